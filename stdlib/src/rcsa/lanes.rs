//! Four frequency lines at a time: receptance blocks as structure-of-arrays lanes, so the 2×2
//! complex algebra of coupling runs in vector registers. Every operation is the scalar one
//! ([`Receptance`]'s and `num_complex`'s, in the same order, no fused multiply-add), so a line
//! gives the same bits whichever path computes it.

use super::Receptance;
use num_complex::Complex64;
use std::ops::{Add, Mul, Neg, Sub};

/// Lines per lane group.
pub(super) const LANES: usize = 4;

/// Four complex numbers.
#[derive(Clone, Copy)]
pub(super) struct C4 {
    re: [f64; LANES],
    im: [f64; LANES],
}

impl C4 {
    #[inline(always)]
    fn from_fn(f: impl Fn(usize) -> Complex64) -> C4 {
        let mut z = C4 { re: [0.0; LANES], im: [0.0; LANES] };
        for l in 0..LANES {
            let v = f(l);
            z.re[l] = v.re;
            z.im[l] = v.im;
        }
        z
    }

    /// `C4` with lanes `re[l] + i im[l]` computed by `f(l) = (re, im)`.
    #[inline(always)]
    fn lanes(f: impl Fn(usize) -> (f64, f64)) -> C4 {
        let mut z = C4 { re: [0.0; LANES], im: [0.0; LANES] };
        for l in 0..LANES {
            let (re, im) = f(l);
            z.re[l] = re;
            z.im[l] = im;
        }
        z
    }

    #[inline(always)]
    fn get(&self, l: usize) -> Complex64 {
        Complex64::new(self.re[l], self.im[l])
    }

    /// `|z|²` per lane, as `Complex64::norm_sqr`.
    #[inline(always)]
    fn norm_sqr(&self) -> [f64; LANES] {
        let mut v = [0.0; LANES];
        for (l, v) in v.iter_mut().enumerate() {
            *v = self.re[l] * self.re[l] + self.im[l] * self.im[l];
        }
        v
    }
}

impl Add for C4 {
    type Output = C4;
    #[inline(always)]
    fn add(self, o: C4) -> C4 {
        C4::lanes(|l| (self.re[l] + o.re[l], self.im[l] + o.im[l]))
    }
}

impl Sub for C4 {
    type Output = C4;
    #[inline(always)]
    fn sub(self, o: C4) -> C4 {
        C4::lanes(|l| (self.re[l] - o.re[l], self.im[l] - o.im[l]))
    }
}

impl Neg for C4 {
    type Output = C4;
    #[inline(always)]
    fn neg(self) -> C4 {
        C4::lanes(|l| (-self.re[l], -self.im[l]))
    }
}

impl Mul for C4 {
    type Output = C4;
    #[inline(always)]
    fn mul(self, o: C4) -> C4 {
        C4::lanes(|l| (self.re[l] * o.re[l] - self.im[l] * o.im[l], self.re[l] * o.im[l] + self.im[l] * o.re[l]))
    }
}

/// Four receptance blocks.
#[derive(Clone, Copy)]
pub(super) struct R4 {
    h: C4,
    l: C4,
    n: C4,
    p: C4,
}

impl R4 {
    /// Lines `at..at + LANES` of `r`.
    #[inline(always)]
    pub(super) fn load(r: &[Receptance], at: usize) -> R4 {
        let r = &r[at..at + LANES];
        R4 {
            h: C4::from_fn(|l| r[l].h),
            l: C4::from_fn(|l| r[l].l),
            n: C4::from_fn(|l| r[l].n),
            p: C4::from_fn(|l| r[l].p),
        }
    }

    /// The blocks of an array.
    #[inline(always)]
    pub(super) fn from_blocks(r: &[Receptance; LANES]) -> R4 {
        R4::load(r, 0)
    }

    /// Lane `l` as a block.
    #[inline(always)]
    pub(super) fn get(&self, l: usize) -> Receptance {
        Receptance::new(self.h.get(l), self.l.get(l), self.n.get(l), self.p.get(l))
    }

    /// Appends the four blocks to `out`.
    #[inline(always)]
    pub(super) fn store(&self, out: &mut Vec<Receptance>) {
        for l in 0..LANES {
            out.push(self.get(l));
        }
    }

    /// The inverse of every lane when [`super::try_invert`] accepts every lane (the same test
    /// and the same arithmetic); `None` otherwise.
    #[inline(always)]
    pub(super) fn try_invert(&self, half_limit_sq: f64) -> Option<R4> {
        let det = self.h * self.p - self.l * self.n;
        let dd = det.norm_sqr();
        let (hh, pp) = (self.h.norm_sqr(), self.p.norm_sqr());
        let (ll, nn) = (self.l.norm_sqr(), self.n.norm_sqr());
        let mut bad = 0;
        for l in 0..LANES {
            let s = (hh[l] * pp[l]).sqrt();
            let bound = 2.0 * s + ll[l] + nn[l];
            let fine = (s > 0.0) & (bound * bound < half_limit_sq * dd[l]) & (dd[l] < f64::INFINITY);
            bad += usize::from(!fine);
        }
        if bad != 0 {
            return None;
        }
        let r = C4::lanes(|l| {
            let rn = 1.0 / dd[l];
            (det.re[l] * rn, -det.im[l] * rn)
        });
        let inv = R4 { h: self.p * r, l: -self.l * r, n: -self.n * r, p: self.h * r };
        for l in 0..LANES {
            let z = [inv.h, inv.l, inv.n, inv.p].iter().fold(0.0, |acc, v| acc + v.re[l] * 0.0 + v.im[l] * 0.0);
            bad += usize::from(z != 0.0);
        }
        (bad == 0).then_some(inv)
    }
}

impl Add for R4 {
    type Output = R4;
    #[inline(always)]
    fn add(self, o: R4) -> R4 {
        R4 { h: self.h + o.h, l: self.l + o.l, n: self.n + o.n, p: self.p + o.p }
    }
}

impl Sub for R4 {
    type Output = R4;
    #[inline(always)]
    fn sub(self, o: R4) -> R4 {
        R4 { h: self.h - o.h, l: self.l - o.l, n: self.n - o.n, p: self.p - o.p }
    }
}

impl Mul for R4 {
    type Output = R4;
    #[inline(always)]
    fn mul(self, o: R4) -> R4 {
        R4 {
            h: self.h * o.h + self.l * o.n,
            l: self.h * o.l + self.l * o.p,
            n: self.n * o.h + self.p * o.n,
            p: self.n * o.l + self.p * o.p,
        }
    }
}
