//! Four frequency lines at a time: receptance blocks as structure-of-arrays lanes, so the 2×2
//! complex algebra of coupling runs in vector registers. Every operation is the scalar one
//! ([`Receptance`]'s and `num_complex`'s, in the same order, no fused multiply-add), so a line
//! gives the same bits whichever path computes it.
//!
//! The four numbers of a lane are a [`Lane`]: an array anywhere ([`PortableIo`]), one AVX
//! register where the CPU has it ([`AvxIo`]: the optimiser pairs array lanes two by two, so
//! only the register type gets four-wide arithmetic). An [`Io`] reads blocks into lanes and
//! writes them back (with AVX, each complex entry of four blocks is two 128-bit loads, two
//! inserts and one unpack pair).
//!
//! Soundness by construction: a lane is made only from its [`Lane::Token`] (the `Io` itself)
//! or from other lanes, and [`AvxIo::detect`] is the only way to an `AvxIo`; so an AVX lane
//! exists only on a CPU with AVX, whoever can name the type.

use super::Receptance;
use num_complex::Complex64;
use std::ops::{Add, Mul, Neg, Sub};

/// Lines per lane group.
pub(super) const LANES: usize = 4;

/// Four f64 with the arithmetic the kernels use.
pub(super) trait Lane:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Neg<Output = Self>
{
    /// What a new lane is made from: the proof that the CPU runs this lane type.
    type Token: Copy;
    fn splat(t: Self::Token, x: f64) -> Self;
    fn from_array(t: Self::Token, a: [f64; LANES]) -> Self;
    fn to_array(self) -> [f64; LANES];
    fn sqrt(self) -> Self;
    /// `1 / self`.
    fn recip(self) -> Self;
    /// Whether every lane has `s > 0`, `bound_sq < limit`, `dd < ∞` and `zero == 0`
    /// (NaN anywhere fails).
    fn all_fine(s: Self, bound_sq: Self, limit: Self, dd: Self, zero: Self) -> bool;
}

/// `[f(0), …, f(LANES − 1)]`.
#[inline(always)]
fn each(f: impl Fn(usize) -> f64) -> [f64; LANES] {
    std::array::from_fn(f)
}

/// Four f64 in an array.
#[derive(Clone, Copy)]
pub(super) struct P4([f64; LANES]);

impl Add for P4 {
    type Output = P4;
    #[inline(always)]
    fn add(self, o: P4) -> P4 {
        P4(each(|l| self.0[l] + o.0[l]))
    }
}

impl Sub for P4 {
    type Output = P4;
    #[inline(always)]
    fn sub(self, o: P4) -> P4 {
        P4(each(|l| self.0[l] - o.0[l]))
    }
}

impl Mul for P4 {
    type Output = P4;
    #[inline(always)]
    fn mul(self, o: P4) -> P4 {
        P4(each(|l| self.0[l] * o.0[l]))
    }
}

impl Neg for P4 {
    type Output = P4;
    #[inline(always)]
    fn neg(self) -> P4 {
        P4(each(|l| -self.0[l]))
    }
}

impl Lane for P4 {
    type Token = PortableIo;
    #[inline(always)]
    fn splat(_: PortableIo, x: f64) -> P4 {
        P4([x; LANES])
    }
    #[inline(always)]
    fn from_array(_: PortableIo, a: [f64; LANES]) -> P4 {
        P4(a)
    }
    #[inline(always)]
    fn to_array(self) -> [f64; LANES] {
        self.0
    }
    #[inline(always)]
    fn sqrt(self) -> P4 {
        P4(each(|l| self.0[l].sqrt()))
    }
    #[inline(always)]
    fn recip(self) -> P4 {
        P4(each(|l| 1.0 / self.0[l]))
    }
    #[inline(always)]
    fn all_fine(s: P4, bound_sq: P4, limit: P4, dd: P4, zero: P4) -> bool {
        (0..LANES)
            .all(|l| (s.0[l] > 0.0) & (bound_sq.0[l] < limit.0[l]) & (dd.0[l] < f64::INFINITY) & (zero.0[l] == 0.0))
    }
}

/// Four complex numbers.
#[derive(Clone, Copy)]
pub(super) struct C4<V> {
    pub(super) re: V,
    pub(super) im: V,
}

impl<V: Lane> C4<V> {
    #[inline(always)]
    pub(super) fn zero(t: V::Token) -> Self {
        C4 { re: V::splat(t, 0.0), im: V::splat(t, 0.0) }
    }

    #[inline(always)]
    fn from_fn(t: V::Token, f: impl Fn(usize) -> Complex64) -> Self {
        C4 { re: V::from_array(t, each(|l| f(l).re)), im: V::from_array(t, each(|l| f(l).im)) }
    }

    #[inline(always)]
    pub(super) fn get(&self, l: usize) -> Complex64 {
        Complex64::new(self.re.to_array()[l], self.im.to_array()[l])
    }

    /// `|z|²` per lane, as `Complex64::norm_sqr`.
    #[inline(always)]
    pub(super) fn norm_sqr(&self) -> V {
        self.re * self.re + self.im * self.im
    }

    /// `z · r` for a real `r` per lane, as `Complex64 * f64`.
    #[inline(always)]
    pub(super) fn scale(&self, r: V) -> Self {
        C4 { re: self.re * r, im: self.im * r }
    }

    /// `conj(z)`.
    #[inline(always)]
    pub(super) fn conj(&self) -> Self {
        C4 { re: self.re, im: -self.im }
    }
}

impl<V: Lane> Add for C4<V> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        C4 { re: self.re + o.re, im: self.im + o.im }
    }
}

impl<V: Lane> Sub for C4<V> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        C4 { re: self.re - o.re, im: self.im - o.im }
    }
}

impl<V: Lane> Neg for C4<V> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        C4 { re: -self.re, im: -self.im }
    }
}

impl<V: Lane> Mul for C4<V> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        C4 { re: self.re * o.re - self.im * o.im, im: self.re * o.im + self.im * o.re }
    }
}

/// Four receptance blocks.
#[derive(Clone, Copy)]
pub(super) struct R4<V> {
    pub(super) h: C4<V>,
    pub(super) l: C4<V>,
    pub(super) n: C4<V>,
    pub(super) p: C4<V>,
}

/// Reads lane groups from blocks and writes them back; it is also the token its lanes are
/// made from.
pub(super) trait Io: Copy {
    /// The lane type.
    type V: Lane<Token = Self>;
    /// Lines `at..at + LANES` of `r`.
    fn load(self, r: &[Receptance], at: usize) -> R4<Self::V>;
    /// Appends the four blocks of `v` to `out`.
    fn store(self, v: &R4<Self::V>, out: &mut Vec<Receptance>);
}

/// Element by element, on any CPU.
#[derive(Clone, Copy)]
pub(super) struct PortableIo;

impl Io for PortableIo {
    type V = P4;

    #[inline(always)]
    fn load(self, r: &[Receptance], at: usize) -> R4<P4> {
        R4::from_blocks(self, &r[at..at + LANES])
    }

    #[inline(always)]
    fn store(self, v: &R4<P4>, out: &mut Vec<Receptance>) {
        for l in 0..LANES {
            out.push(v.get(l));
        }
    }
}

/// With AVX. Only [`AvxIo::detect`] makes one (its field is private to this module), and
/// every constructor of an [`avx::A4`] takes one, so holding either proves the CPU has AVX.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) struct AvxIo(());

#[cfg(target_arch = "x86_64")]
impl AvxIo {
    /// `Some` when the CPU has AVX.
    pub(super) fn detect() -> Option<AvxIo> {
        std::arch::is_x86_feature_detected!("avx").then_some(AvxIo(()))
    }
}

#[cfg(target_arch = "x86_64")]
pub(super) mod avx {
    use super::{C4, Io, LANES, Lane, R4, Receptance};
    use std::arch::x86_64::*;
    use std::ops::{Add, Mul, Neg, Sub};

    /// Four f64 in one AVX register. Its constructors take an [`super::AvxIo`] and its
    /// operations take other `A4`s, so every value descends from an `AvxIo`: the CPU running
    /// its operations has AVX.
    #[derive(Clone, Copy)]
    pub(in super::super) struct A4(__m256d);

    macro_rules! binary {
        ($tr:ident, $f:ident, $intr:ident) => {
            impl $tr for A4 {
                type Output = A4;
                #[inline(always)]
                fn $f(self, o: A4) -> A4 {
                    // SAFETY: an `A4` exists only where the CPU has AVX (type docs).
                    A4(unsafe { $intr(self.0, o.0) })
                }
            }
        };
    }
    binary!(Add, add, _mm256_add_pd);
    binary!(Sub, sub, _mm256_sub_pd);
    binary!(Mul, mul, _mm256_mul_pd);

    impl Neg for A4 {
        type Output = A4;
        #[inline(always)]
        fn neg(self) -> A4 {
            // SAFETY: as above. Flipping the sign bit is what scalar negation does.
            A4(unsafe { _mm256_xor_pd(self.0, _mm256_set1_pd(-0.0)) })
        }
    }

    impl Lane for A4 {
        type Token = super::AvxIo;
        #[inline(always)]
        fn splat(_: super::AvxIo, x: f64) -> A4 {
            // SAFETY: the `AvxIo` proves AVX.
            A4(unsafe { _mm256_set1_pd(x) })
        }
        #[inline(always)]
        fn from_array(_: super::AvxIo, a: [f64; LANES]) -> A4 {
            // SAFETY: the `AvxIo` proves AVX; the array is read unaligned.
            A4(unsafe { _mm256_loadu_pd(a.as_ptr()) })
        }
        #[inline(always)]
        fn to_array(self) -> [f64; LANES] {
            let mut a = [0.0; LANES];
            // SAFETY: as above; the array has room for four f64.
            unsafe { _mm256_storeu_pd(a.as_mut_ptr(), self.0) };
            a
        }
        #[inline(always)]
        fn sqrt(self) -> A4 {
            // SAFETY: as above (correctly rounded, as `f64::sqrt`).
            A4(unsafe { _mm256_sqrt_pd(self.0) })
        }
        #[inline(always)]
        fn recip(self) -> A4 {
            // SAFETY: as above (a true division, as `1.0 / x`).
            A4(unsafe { _mm256_div_pd(_mm256_set1_pd(1.0), self.0) })
        }
        #[inline(always)]
        fn all_fine(s: A4, bound_sq: A4, limit: A4, dd: A4, zero: A4) -> bool {
            // SAFETY: as above. Ordered compares: NaN fails each.
            unsafe {
                let z = _mm256_setzero_pd();
                let ok = _mm256_and_pd(
                    _mm256_and_pd(
                        _mm256_cmp_pd::<_CMP_GT_OQ>(s.0, z),
                        _mm256_cmp_pd::<_CMP_LT_OQ>(bound_sq.0, limit.0),
                    ),
                    _mm256_and_pd(
                        _mm256_cmp_pd::<_CMP_LT_OQ>(dd.0, _mm256_set1_pd(f64::INFINITY)),
                        _mm256_cmp_pd::<_CMP_EQ_OQ>(zero.0, z),
                    ),
                );
                _mm256_movemask_pd(ok) == (1 << LANES) - 1
            }
        }
    }

    /// Entry `c` (0 = h, 1 = l, 2 = n, 3 = p) of the four blocks at `p`.
    #[inline]
    #[target_feature(enable = "avx")]
    unsafe fn load_entry(p: *const f64, c: usize) -> C4<A4> {
        // SAFETY (caller): `p` points at four `#[repr(C)]` blocks of eight f64.
        unsafe {
            let e = p.add(2 * c);
            let x0 = _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(e)), _mm_loadu_pd(e.add(16)), 1);
            let x1 = _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(e.add(8))), _mm_loadu_pd(e.add(24)), 1);
            // x0 = (re0, im0, re2, im2), x1 = (re1, im1, re3, im3).
            C4 { re: A4(_mm256_unpacklo_pd(x0, x1)), im: A4(_mm256_unpackhi_pd(x0, x1)) }
        }
    }

    /// Writes entry `c` of four blocks at `p`.
    #[inline]
    #[target_feature(enable = "avx")]
    unsafe fn store_entry(p: *mut f64, c: usize, v: &C4<A4>) {
        // SAFETY (caller): `p` points at room for four `#[repr(C)]` blocks of eight f64.
        unsafe {
            let (lo, hi) = (_mm256_unpacklo_pd(v.re.0, v.im.0), _mm256_unpackhi_pd(v.re.0, v.im.0));
            let e = p.add(2 * c);
            _mm_storeu_pd(e, _mm256_castpd256_pd128(lo));
            _mm_storeu_pd(e.add(8), _mm256_castpd256_pd128(hi));
            _mm_storeu_pd(e.add(16), _mm256_extractf128_pd(lo, 1));
            _mm_storeu_pd(e.add(24), _mm256_extractf128_pd(hi, 1));
        }
    }

    impl Io for super::AvxIo {
        type V = A4;

        #[inline(always)]
        fn load(self, r: &[Receptance], at: usize) -> R4<A4> {
            let r = &r[at..at + LANES];
            let p = r.as_ptr().cast::<f64>();
            // SAFETY: this `AvxIo` proves AVX; `r` holds four blocks of eight f64
            // (`Receptance` is `#[repr(C)]`).
            unsafe { R4 { h: load_entry(p, 0), l: load_entry(p, 1), n: load_entry(p, 2), p: load_entry(p, 3) } }
        }

        #[inline(always)]
        fn store(self, v: &R4<A4>, out: &mut Vec<Receptance>) {
            let spare = out.spare_capacity_mut();
            assert!(spare.len() >= LANES, "the kernels reserve one block per line");
            let p = spare.as_mut_ptr().cast::<f64>();
            // SAFETY: this `AvxIo` proves AVX; `p` has room for four blocks (checked above),
            // and all their f64 are written before the length grows over them.
            unsafe {
                store_entry(p, 0, &v.h);
                store_entry(p, 1, &v.l);
                store_entry(p, 2, &v.n);
                store_entry(p, 3, &v.p);
                out.set_len(out.len() + LANES);
            }
        }
    }
}

impl<V: Lane> R4<V> {
    /// Four zero blocks.
    #[inline(always)]
    pub(super) fn zero(t: V::Token) -> Self {
        R4 { h: C4::zero(t), l: C4::zero(t), n: C4::zero(t), p: C4::zero(t) }
    }

    /// The first four blocks of `r`, element by element.
    #[inline(always)]
    pub(super) fn from_blocks(t: V::Token, r: &[Receptance]) -> Self {
        R4 {
            h: C4::from_fn(t, |l| r[l].h),
            l: C4::from_fn(t, |l| r[l].l),
            n: C4::from_fn(t, |l| r[l].n),
            p: C4::from_fn(t, |l| r[l].p),
        }
    }

    /// Lane `l` as a block.
    #[inline(always)]
    pub(super) fn get(&self, l: usize) -> Receptance {
        Receptance::new(self.h.get(l), self.l.get(l), self.n.get(l), self.p.get(l))
    }

    /// The inverse of every lane when [`super::try_invert`] accepts every lane (the same test
    /// and the same arithmetic); `None` otherwise. Every lane is computed and the verdicts are
    /// combined at the end, so the work stays in vectors.
    #[inline(always)]
    pub(super) fn try_invert(&self, t: V::Token, half_limit_sq: f64) -> Option<Self> {
        let det = self.h * self.p - self.l * self.n;
        let dd = det.norm_sqr();
        let (hh, pp) = (self.h.norm_sqr(), self.p.norm_sqr());
        let (ll, nn) = (self.l.norm_sqr(), self.n.norm_sqr());
        let s = (hh * pp).sqrt();
        let bound = V::splat(t, 2.0) * s + ll + nn;
        let rn = dd.recip();
        let r = C4 { re: det.re * rn, im: -det.im * rn };
        let inv = R4 { h: self.p * r, l: -self.l * r, n: -self.n * r, p: self.h * r };
        // `x · 0` is 0 for finite `x` and NaN otherwise.
        let o = V::splat(t, 0.0);
        let zero = [inv.h, inv.l, inv.n, inv.p].iter().fold(o, |acc, v| acc + v.re * o + v.im * o);
        V::all_fine(s, bound * bound, V::splat(t, half_limit_sq) * dd, dd, zero).then_some(inv)
    }
}

impl<V: Lane> Add for R4<V> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        R4 { h: self.h + o.h, l: self.l + o.l, n: self.n + o.n, p: self.p + o.p }
    }
}

impl<V: Lane> Sub for R4<V> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        R4 { h: self.h - o.h, l: self.l - o.l, n: self.n - o.n, p: self.p - o.p }
    }
}

impl<V: Lane> Mul for R4<V> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        R4 {
            h: self.h * o.h + self.l * o.n,
            l: self.h * o.l + self.l * o.p,
            n: self.n * o.h + self.p * o.n,
            p: self.n * o.l + self.p * o.p,
        }
    }
}
