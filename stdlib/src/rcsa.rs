//! Receptance coupling substructure analysis (RCSA), dissertation §5.1.
//!
//! Receptances are 2×2 complex blocks `R = [[H, L], [N, P]]` per frequency line, with `H = y/F`, `L = y/M`,
//! `N = θ/F`, `P = θ/M` (`θ = dy/dx`, force along `+y`, moment in the `θ` sense). A substructure with two
//! coupling points carries the blocks `R11`, `R12`, `R21`, `R22` (1 = free end, 2 = joint). Coupling at point 2
//! to a base with joint receptance `B` (Eq. 5.3, with the interface compliance of Eqs. 5.16–5.17):
//! `G11 = R11 − R12 (R22 + K⁻¹ + B)⁻¹ R21`, `K = k + iωc`; inverse RCSA (Eq. 5.4):
//! `B = R21 (R11 − G11)⁻¹ R12 − R22 − K⁻¹`. Every 2×2 inversion is checked: its condition number (after a
//! length scaling that makes translation and rotation terms commensurate) must stay below a limit, and the
//! frequencies where it does not are reported as an error, never returned as NaN.

/// The complex scalar of every receptance entry.
pub use num_complex::Complex64;
use std::f64::consts::TAU;
use std::ops::{Add, Mul, Neg, Sub};
use thiserror::Error;

mod lanes;
use lanes::{C4, Io, LANES, Lane, PortableIo, R4};

/// A 2×2 complex receptance block `[[h, l], [n, p]]`, laid out as eight f64 in that order
/// (the coupling kernels read four blocks at a time with vector loads).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct Receptance {
    /// Displacement per force, m/N.
    pub h: Complex64,
    /// Displacement per moment, 1/N.
    pub l: Complex64,
    /// Rotation per force, 1/N.
    pub n: Complex64,
    /// Rotation per moment, rad/(N m).
    pub p: Complex64,
}

impl Receptance {
    /// The zero block.
    pub const ZERO: Receptance = Receptance {
        h: Complex64::new(0.0, 0.0),
        l: Complex64::new(0.0, 0.0),
        n: Complex64::new(0.0, 0.0),
        p: Complex64::new(0.0, 0.0),
    };
    /// The identity.
    pub const IDENTITY: Receptance = Receptance {
        h: Complex64::new(1.0, 0.0),
        l: Complex64::new(0.0, 0.0),
        n: Complex64::new(0.0, 0.0),
        p: Complex64::new(1.0, 0.0),
    };

    /// Builds `[[h, l], [n, p]]`.
    pub const fn new(h: Complex64, l: Complex64, n: Complex64, p: Complex64) -> Self {
        Receptance { h, l, n, p }
    }

    /// A diagonal block `diag(a, b)`.
    pub fn diag(a: Complex64, b: Complex64) -> Self {
        Receptance::new(a, Complex64::from(0.0), Complex64::from(0.0), b)
    }

    /// Determinant `hp − ln`.
    pub fn det(&self) -> Complex64 {
        self.h * self.p - self.l * self.n
    }

    /// Largest modulus of the four entries.
    pub fn max_norm(&self) -> f64 {
        self.h.norm().max(self.l.norm()).max(self.n.norm()).max(self.p.norm())
    }

    /// The same block seen from a mirrored axis (`x → −x`): rotation and moment change sign, so `L` and `N`
    /// do. Used when a substructure's own axis points the other way along the assembly.
    pub fn mirrored(&self) -> Self {
        Receptance::new(self.h, -self.l, -self.n, self.p)
    }

    /// 2-norm condition number after scaling lengths by `c = sqrt(|h|/|p|)` (so that a cantilever's
    /// `H ≈ L² P` does not count as ill-conditioning). Infinite when singular.
    pub fn condition(&self) -> f64 {
        self.condition_with(self.det())
    }

    /// [`Receptance::condition`] with the determinant already at hand. With `c² = |h|/|p|` the scaled block has
    /// `|h'| = |p'| = |p|`, `|l'| = |l|/c`, `|n'| = |n|/c`, `|det'| = |det|/c²`; the 2-norm condition of a 2×2
    /// block is `(F² + sqrt(F⁴ − 4|det|²)) / (2|det|)` with `F` the Frobenius norm.
    fn condition_with(&self, det: Complex64) -> f64 {
        let (ah, ap) = (self.h.norm_sqr().sqrt(), self.p.norm_sqr().sqrt());
        let off = self.l.norm_sqr() + self.n.norm_sqr();
        let (f2, det) = if ah > 0.0 && ap > 0.0 {
            let r = ap / ah;
            (2.0 * ap * ap + off * r, det.norm_sqr().sqrt() * r)
        } else {
            (ah * ah + ap * ap + off, det.norm_sqr().sqrt())
        };
        if det.is_nan() || det <= 0.0 || !f2.is_finite() || !det.is_finite() {
            return f64::INFINITY;
        }
        let disc = (f2 * f2 - 4.0 * det * det).max(0.0).sqrt();
        (f2 + disc) / (2.0 * det)
    }

    /// True when every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.h.is_finite() && self.l.is_finite() && self.n.is_finite() && self.p.is_finite()
    }

    /// Closed-form inverse with its condition number; `None` when singular or not finite.
    pub fn inverse(&self) -> Option<(Receptance, f64)> {
        let det = self.det();
        let cond = self.condition_with(det);
        if !cond.is_finite() {
            return None;
        }
        let r = det.inv();
        Some((Receptance::new(self.p * r, -self.l * r, -self.n * r, self.h * r), cond))
    }
}

impl Add for Receptance {
    type Output = Receptance;
    #[inline]
    fn add(self, o: Receptance) -> Receptance {
        Receptance::new(self.h + o.h, self.l + o.l, self.n + o.n, self.p + o.p)
    }
}

impl Sub for Receptance {
    type Output = Receptance;
    #[inline]
    fn sub(self, o: Receptance) -> Receptance {
        Receptance::new(self.h - o.h, self.l - o.l, self.n - o.n, self.p - o.p)
    }
}

impl Neg for Receptance {
    type Output = Receptance;
    #[inline]
    fn neg(self) -> Receptance {
        Receptance::new(-self.h, -self.l, -self.n, -self.p)
    }
}

impl Mul for Receptance {
    type Output = Receptance;
    #[inline]
    fn mul(self, o: Receptance) -> Receptance {
        Receptance::new(
            self.h * o.h + self.l * o.n,
            self.h * o.l + self.l * o.p,
            self.n * o.h + self.p * o.n,
            self.n * o.l + self.p * o.p,
        )
    }
}

impl Mul<Complex64> for Receptance {
    type Output = Receptance;
    #[inline]
    fn mul(self, s: Complex64) -> Receptance {
        Receptance::new(self.h * s, self.l * s, self.n * s, self.p * s)
    }
}

/// One-point receptances on a frequency grid (e.g. a spindle's `R2b2b` or an assembly's `G11`).
#[derive(Debug, Clone, PartialEq)]
pub struct ReceptanceFrf {
    /// Frequency lines, Hz.
    pub freqs_hz: Vec<f64>,
    /// One block per line.
    pub lines: Vec<Receptance>,
}

/// Receptances of a substructure with a free end (1) and a joint (2) on a frequency grid.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoPort {
    /// Frequency lines, Hz.
    pub freqs_hz: Vec<f64>,
    /// `R11`, direct at the free end.
    pub r11: Vec<Receptance>,
    /// `R12`, free-end response to a joint load.
    pub r12: Vec<Receptance>,
    /// `R21`, joint response to a free-end load.
    pub r21: Vec<Receptance>,
    /// `R22`, direct at the joint.
    pub r22: Vec<Receptance>,
}

/// Joint between two substructures (Eqs. 5.16–5.17).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Interface {
    /// Rigid: `K⁻¹ = 0`.
    Rigid,
    /// Flexible: `K(ω) = k + iωc` with 2×2 real stiffness (N/m, N, N m/rad) and damping (N s/m, N s,
    /// N m s/rad) over (translation, rotation).
    Flexible {
        /// Stiffness `[[k_tt, k_tr], [k_rt, k_rr]]`.
        k: [[f64; 2]; 2],
        /// Viscous damping `[[c_tt, c_tr], [c_rt, c_rr]]`.
        c: [[f64; 2]; 2],
    },
}

impl Interface {
    /// A diagonal joint `diag(kt + iω ct, kr + iω cr)`.
    pub fn diagonal(kt: f64, ct: f64, kr: f64, cr: f64) -> Self {
        Interface::Flexible { k: [[kt, 0.0], [0.0, kr]], c: [[ct, 0.0], [0.0, cr]] }
    }

    /// `K(ω) = k + iωc` at `freq_hz`, or `None` for a rigid joint.
    pub fn stiffness(&self, freq_hz: f64) -> Option<Receptance> {
        match self {
            Interface::Rigid => None,
            Interface::Flexible { k, c } => {
                let w = TAU * freq_hz;
                let e = |i: usize, j: usize| Complex64::new(k[i][j], w * c[i][j]);
                Some(Receptance::new(e(0, 0), e(0, 1), e(1, 0), e(1, 1)))
            }
        }
    }
}

/// Options of the coupling kernels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RcsaOptions {
    /// Largest accepted condition number of a 2×2 inversion (scaled, see [`Receptance::condition`]).
    pub max_condition: f64,
}

impl Default for RcsaOptions {
    /// `max_condition = 1e10`, leaving about six significant digits in double precision.
    fn default() -> Self {
        RcsaOptions { max_condition: 1e10 }
    }
}

/// Errors of receptance coupling.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RcsaError {
    /// Two inputs are not on the same frequency grid.
    #[error(
        "frequency grids differ: {a} has {a_len} lines ({a_first} … {a_last} Hz), {b} has {b_len} lines \
         ({b_first} … {b_last} Hz){}; resample both onto one grid first",
        first_diff.map(|(i, fa, fb)| format!(", first difference at line {i}: {fa} vs {fb} Hz")).unwrap_or_default()
    )]
    GridMismatch {
        /// Name of the first input.
        a: &'static str,
        /// Name of the second input.
        b: &'static str,
        /// Line counts.
        a_len: usize,
        /// Line counts.
        b_len: usize,
        /// First / last frequency of `a`, Hz.
        a_first: f64,
        /// Last frequency of `a`, Hz.
        a_last: f64,
        /// First frequency of `b`, Hz.
        b_first: f64,
        /// Last frequency of `b`, Hz.
        b_last: f64,
        /// First differing line (index, a, b) when the lengths agree.
        first_diff: Option<(usize, f64, f64)>,
    },
    /// A block list does not have one entry per frequency line.
    #[error("{what} has {found} blocks for {expected} frequency lines")]
    LengthMismatch {
        /// Which block list.
        what: &'static str,
        /// Number of lines.
        expected: usize,
        /// Number of blocks.
        found: usize,
    },
    /// A 2×2 inversion is singular or too ill-conditioned at some lines.
    #[error(
        "{operation}: ill-conditioned at {} of the lines (worst condition {worst_condition:e} at {worst_freq_hz} Hz, \
         limit {limit:e}); first affected frequencies {:?} Hz",
        freqs_hz.len(), &freqs_hz[..freqs_hz.len().min(8)]
    )]
    IllConditioned {
        /// Which inversion (`(R22 + K⁻¹ + B)`, `(R11 − G11)`, `K`).
        operation: &'static str,
        /// Every affected frequency, Hz.
        freqs_hz: Vec<f64>,
        /// Largest condition number met (infinite when singular).
        worst_condition: f64,
        /// Where it occurs, Hz.
        worst_freq_hz: f64,
        /// The accepted limit.
        limit: f64,
    },
}

/// A translational point mass `m` (kg, no rotary inertia) added at the point of a driving-point
/// receptance G: `G' = G (I − ω² diag(m, 0) G)⁻¹`. It equals meshing the mass into the FE model,
/// so one coupled structure serves both the measured configuration (sensor on the tip) and the
/// cutting one (no sensor).
pub fn with_point_mass(g: &ReceptanceFrf, mass: f64) -> Result<ReceptanceFrf, RcsaError> {
    let mut lines = Vec::with_capacity(g.lines.len());
    let mut bad = Vec::new();
    for (&f, r) in g.freqs_hz.iter().zip(&g.lines) {
        let w2m = (std::f64::consts::TAU * f).powi(2) * mass;
        // (I − ω²DG) = [[a, −ω²m l], [0, 1]], a = 1 − ω²m h; its inverse is [[1/a, ω²m l/a], [0, 1]].
        let a = Complex64::new(1.0, 0.0) - r.h * w2m;
        if a.norm() == 0.0 || !a.is_finite() {
            bad.push(f);
            lines.push(*r);
            continue;
        }
        let inv = Receptance::new(1.0 / a, r.l * w2m / a, Complex64::new(0.0, 0.0), Complex64::new(1.0, 0.0));
        lines.push(*r * inv);
    }
    if let Some(&worst_freq_hz) = bad.first() {
        return Err(RcsaError::IllConditioned {
            operation: "(I − ω² m G) of the point mass",
            freqs_hz: bad,
            worst_condition: f64::INFINITY,
            worst_freq_hz,
            limit: f64::INFINITY,
        });
    }
    Ok(ReceptanceFrf { freqs_hz: g.freqs_hz.clone(), lines })
}

fn check_grid(a: &'static str, fa: &[f64], b: &'static str, fb: &[f64]) -> Result<(), RcsaError> {
    if fa == fb {
        return Ok(());
    }
    let first_diff = if fa.len() == fb.len() {
        fa.iter().zip(fb).enumerate().find(|(_, (x, y))| x != y).map(|(i, (x, y))| (i, *x, *y))
    } else {
        None
    };
    let ends = |f: &[f64]| (f.first().copied().unwrap_or(f64::NAN), f.last().copied().unwrap_or(f64::NAN));
    let ((a_first, a_last), (b_first, b_last)) = (ends(fa), ends(fb));
    Err(RcsaError::GridMismatch {
        a,
        b,
        a_len: fa.len(),
        b_len: fb.len(),
        a_first,
        a_last,
        b_first,
        b_last,
        first_diff,
    })
}

fn check_len(what: &'static str, v: &[Receptance], expected: usize) -> Result<(), RcsaError> {
    if v.len() == expected { Ok(()) } else { Err(RcsaError::LengthMismatch { what, expected, found: v.len() }) }
}

impl TwoPort {
    fn check(&self) -> Result<(), RcsaError> {
        let n = self.freqs_hz.len();
        check_len("R11", &self.r11, n)?;
        check_len("R12", &self.r12, n)?;
        check_len("R21", &self.r21, n)?;
        check_len("R22", &self.r22, n)
    }

    /// A substructure whose free end and joint are the same point (e.g. a one-point body): all four blocks
    /// equal `r`.
    pub fn single_point(frf: &ReceptanceFrf) -> TwoPort {
        TwoPort {
            freqs_hz: frf.freqs_hz.clone(),
            r11: frf.lines.clone(),
            r12: frf.lines.clone(),
            r21: frf.lines.clone(),
            r22: frf.lines.clone(),
        }
    }
}

/// Collects ill-conditioned lines while a kernel runs.
struct Diagnostics {
    operation: &'static str,
    limit: f64,
    freqs: Vec<f64>,
    worst: (f64, f64),
}

impl Diagnostics {
    fn new(operation: &'static str, limit: f64) -> Self {
        Diagnostics { operation, limit, freqs: Vec::new(), worst: (0.0, f64::NAN) }
    }

    /// Inverts `m` at `freq`, recording the line if singular or beyond the limit (zero is returned then).
    fn invert(&mut self, m: Receptance, freq: f64) -> Receptance {
        let (inv, cond) = m.inverse().unwrap_or((Receptance::ZERO, f64::INFINITY));
        if cond > self.limit || !inv.is_finite() {
            self.freqs.push(freq);
            if cond > self.worst.0 {
                self.worst = (cond, freq);
            }
            return Receptance::ZERO;
        }
        inv
    }

    /// [`Diagnostics::invert`] kept out of line: the kernels take it only for lines [`try_invert`] turns away.
    #[cold]
    #[inline(never)]
    fn invert_cold(&mut self, m: Receptance, freq: f64) -> Receptance {
        self.invert(m, freq)
    }

    fn finish(self) -> Result<(), RcsaError> {
        if self.freqs.is_empty() {
            Ok(())
        } else {
            Err(RcsaError::IllConditioned {
                operation: self.operation,
                freqs_hz: self.freqs,
                worst_condition: self.worst.0,
                worst_freq_hz: self.worst.1,
                limit: self.limit,
            })
        }
    }
}

/// The hot-path inversion of the coupling kernels: `m⁻¹` when a bound on its scaled condition number shows it
/// is well inside `limit`, `None` otherwise (the caller then takes [`Diagnostics::invert`], which decides with
/// the exact [`Receptance::condition`] and records the line).
///
/// With `c² = |h|/|p|` the scaled Frobenius norm and determinant of [`Receptance::condition_with`] give
/// `cond ≤ F²/|det'| = (2|h||p| + |l|² + |n|²)/|det|` (and `cond ≥` half of it), so the test
/// `(2 sqrt(|h|²|p|²) + |l|² + |n|²)² < (limit/2)² |det|²` needs one square root and no division, and a line it
/// accepts is one the exact check accepts too; lines it turns away (near the limit, singular, zero diagonal,
/// not finite) are decided by the exact check.
#[inline(always)]
fn try_invert(m: &Receptance, half_limit_sq: f64) -> Option<Receptance> {
    let det = m.det();
    let dd = det.norm_sqr();
    let s = (m.h.norm_sqr() * m.p.norm_sqr()).sqrt();
    let bound = 2.0 * s + m.l.norm_sqr() + m.n.norm_sqr();
    // Written so that NaN anywhere fails the test.
    if !(s > 0.0 && bound * bound < half_limit_sq * dd && dd < f64::INFINITY) {
        return None;
    }
    let rn = 1.0 / dd;
    let r = Complex64::new(det.re * rn, -det.im * rn);
    let inv = Receptance::new(m.p * r, -m.l * r, -m.n * r, m.h * r);
    // `x · 0` is 0 for finite `x` and NaN otherwise, so the sum is 0 exactly when every entry is finite.
    let z = [inv.h, inv.l, inv.n, inv.p].iter().fold(0.0, |acc, v| acc + v.re * 0.0 + v.im * 0.0);
    if z == 0.0 { Some(inv) } else { None }
}

/// `(limit/2)²` for [`try_invert`].
fn half_limit_sq(limit: f64) -> f64 {
    let half = 0.5 * limit;
    half * half
}

/// Per-line interface compliance `K⁻¹` of a flexible joint, prepared once per call.
#[derive(Clone, Copy)]
enum Compliance {
    /// Diagonal `k` and `c`: `K⁻¹ = diag(1/(k_tt + iωc_tt), 1/(k_rr + iωc_rr))`.
    Diagonal { kt: f64, ct: f64, kr: f64, cr: f64 },
    /// Full 2×2 `K = k + iωc`, inverted per line.
    Full { k: [[f64; 2]; 2], c: [[f64; 2]; 2] },
}

impl Compliance {
    /// `None` for a rigid joint (`K⁻¹ = 0`, no inversion at all).
    fn new(interface: &Interface) -> Option<Self> {
        match *interface {
            Interface::Rigid => None,
            Interface::Flexible { k, c } => {
                if k[0][1] == 0.0 && k[1][0] == 0.0 && c[0][1] == 0.0 && c[1][0] == 0.0 {
                    Some(Compliance::Diagonal { kt: k[0][0], ct: c[0][0], kr: k[1][1], cr: c[1][1] })
                } else {
                    Some(Compliance::Full { k, c })
                }
            }
        }
    }

    /// `K⁻¹` at `freq`. A diagonal `K` has scaled condition number 1 (up to rounding), so with nonzero, finite
    /// entries whose product stays in range it is inverted entry by entry when `limit > 4`; every other line
    /// (and a full `K`) goes through the checks of [`try_invert`] and, failing those, [`Diagnostics::invert`].
    #[inline(always)]
    fn at(&self, freq: f64, half_limit_sq: f64, diag: &mut Diagnostics) -> Receptance {
        let w = TAU * freq;
        match *self {
            Compliance::Diagonal { kt, ct, kr, cr } => {
                let (a, b) = (Complex64::new(kt, w * ct), Complex64::new(kr, w * cr));
                let (aa, bb) = (a.norm_sqr(), b.norm_sqr());
                let q = aa * bb;
                if half_limit_sq > 4.0 && q > 1e-300 && q < 1e300 {
                    let (ra, rb) = (1.0 / aa, 1.0 / bb);
                    let zero = Complex64::new(0.0, 0.0);
                    Receptance::new(
                        Complex64::new(a.re * ra, -a.im * ra),
                        zero,
                        zero,
                        Complex64::new(b.re * rb, -b.im * rb),
                    )
                } else {
                    diag.invert_cold(Receptance::diag(a, b), freq)
                }
            }
            Compliance::Full { k, c } => {
                let e = |i: usize, j: usize| Complex64::new(k[i][j], w * c[i][j]);
                let m = Receptance::new(e(0, 0), e(0, 1), e(1, 0), e(1, 1));
                try_invert(&m, half_limit_sq).unwrap_or_else(|| diag.invert_cold(m, freq))
            }
        }
    }
}

/// Which loop [`Kernel::run`] runs.
#[derive(Clone, Copy)]
enum Direction {
    /// [`Kernel::couple`].
    Couple,
    /// [`Kernel::decouple`].
    Decouple,
}

/// The per-line loops of [`couple`] and [`decouple`], [`LANES`] lines at a time where every
/// inversion in the group passes [`try_invert`]'s test, line by line otherwise (the same
/// arithmetic either way, so the path taken does not change a bit).
struct Kernel<'a> {
    lim: f64,
    kdiag: &'a mut Diagnostics,
    diag: &'a mut Diagnostics,
    out: &'a mut Vec<Receptance>,
}

impl Kernel<'_> {
    /// [`Kernel::couple`] (or [`Kernel::decouple`], `lines` then being G11) compiled
    /// for AVX when the CPU has it (four-lane vectors).
    fn run(&mut self, a: &TwoPort, lines: &[Receptance], comp: Option<Compliance>, direction: Direction) {
        #[inline(always)]
        fn body<I: Io>(
            k: &mut Kernel,
            io: I,
            a: &TwoPort,
            lines: &[Receptance],
            comp: Option<Compliance>,
            direction: Direction,
        ) {
            match direction {
                Direction::Couple => k.couple(io, a, lines, comp),
                Direction::Decouple => k.decouple(io, a, lines, comp),
            }
        }
        // `body` compiled with the given target features, and called.
        #[cfg(target_arch = "x86_64")]
        macro_rules! compiled_for {
            ($features:literal, $k:expr, $io:expr) => {{
                #[target_feature(enable = $features)]
                fn compiled(
                    k: &mut Kernel,
                    io: lanes::AvxIo,
                    a: &TwoPort,
                    lines: &[Receptance],
                    comp: Option<Compliance>,
                    direction: Direction,
                ) {
                    body(k, io, a, lines, comp, direction)
                }
                // SAFETY: the caller checked that the CPU has these features.
                unsafe { compiled($k, $io, a, lines, comp, direction) }
            }};
        }
        #[cfg(target_arch = "x86_64")]
        if let Some(io) = lanes::AvxIo::detect() {
            // With AVX-512's 32 vector registers the four-line blocks of a product stay in
            // registers (AVX's 16 spill them to the stack); the vectors stay 256 bits wide.
            if std::arch::is_x86_feature_detected!("avx512f") && std::arch::is_x86_feature_detected!("avx512vl") {
                return compiled_for!("avx,avx512f,avx512vl", self, io);
            }
            return compiled_for!("avx", self, io);
        }
        body(self, PortableIo, a, lines, comp, direction)
    }

    /// `K⁻¹` of lines `i..i + LANES` (zero for a rigid joint): a diagonal joint in lanes
    /// (the arithmetic of [`Compliance::at`]), line by line when a lane needs its checks.
    #[inline(always)]
    fn compliance<V: Lane>(&mut self, t: V::Token, comp: Option<Compliance>, f: &[f64], i: usize) -> R4<V> {
        match comp {
            None => R4::zero(t),
            Some(Compliance::Diagonal { kt, ct, kr, cr }) if self.lim > 4.0 => {
                let w = V::splat(t, TAU) * V::from_array(t, std::array::from_fn(|l| f[i + l]));
                let a = C4 { re: V::splat(t, kt), im: w * V::splat(t, ct) };
                let b = C4 { re: V::splat(t, kr), im: w * V::splat(t, cr) };
                let (aa, bb) = (a.norm_sqr(), b.norm_sqr());
                let q = (aa * bb).to_array();
                if q.iter().all(|&q| (q > 1e-300) & (q < 1e300)) {
                    let zero = C4::zero(t);
                    return R4 { h: a.conj().scale(aa.recip()), l: zero, n: zero, p: b.conj().scale(bb.recip()) };
                }
                self.compliance_lines(t, comp, f, i)
            }
            Some(_) => self.compliance_lines(t, comp, f, i),
        }
    }

    /// [`Kernel::compliance`] line by line.
    #[cold]
    #[inline(never)]
    fn compliance_lines<V: Lane>(&mut self, t: V::Token, comp: Option<Compliance>, f: &[f64], i: usize) -> R4<V> {
        let mut k = [Receptance::ZERO; LANES];
        if let Some(c) = comp {
            for (l, k) in k.iter_mut().enumerate() {
                *k = c.at(f[i + l], self.lim, self.kdiag);
            }
        }
        R4::from_blocks(t, &k)
    }

    /// `m⁻¹` by the scalar path, recording a line it turns away.
    #[inline(always)]
    fn invert(&mut self, m: Receptance, freq: f64) -> Receptance {
        try_invert(&m, self.lim).unwrap_or_else(|| self.diag.invert_cold(m, freq))
    }

    /// `G11 = R11 − R12 (R22 [+ K⁻¹] + B)⁻¹ R21` on every line.
    #[inline(always)]
    fn couple<I: Io>(&mut self, io: I, a: &TwoPort, b: &[Receptance], comp: Option<Compliance>) {
        let (f, r11, r12, r21, r22) = (&a.freqs_hz, &a.r11, &a.r12, &a.r21, &a.r22);
        let n = f.len();
        let whole = n - n % LANES;
        for i in (0..whole).step_by(LANES) {
            let k: R4<I::V> = self.compliance(io, comp, f, i);
            let m = match comp {
                Some(_) => (io.load(r22, i) + k) + io.load(b, i),
                None => io.load(r22, i) + io.load(b, i),
            };
            if let Some(x) = m.try_invert(io, self.lim) {
                io.store(&(io.load(r11, i) - (io.load(r12, i) * x) * io.load(r21, i)), self.out);
            } else {
                for l in 0..LANES {
                    let x = self.invert(m.get(l), f[i + l]);
                    self.out.push(r11[i + l] - r12[i + l] * x * r21[i + l]);
                }
            }
        }
        for i in whole..n {
            let m = match comp {
                Some(c) => r22[i] + c.at(f[i], self.lim, self.kdiag) + b[i],
                None => r22[i] + b[i],
            };
            let x = self.invert(m, f[i]);
            self.out.push(r11[i] - r12[i] * x * r21[i]);
        }
    }

    /// `B = R21 (R11 − G11)⁻¹ R12 − R22 [− K⁻¹]` on every line.
    #[inline(always)]
    fn decouple<I: Io>(&mut self, io: I, a: &TwoPort, g: &[Receptance], comp: Option<Compliance>) {
        let (f, r11, r12, r21, r22) = (&a.freqs_hz, &a.r11, &a.r12, &a.r21, &a.r22);
        let n = f.len();
        let whole = n - n % LANES;
        for i in (0..whole).step_by(LANES) {
            let k: R4<I::V> = self.compliance(io, comp, f, i);
            let m = io.load(r11, i) - io.load(g, i);
            if let Some(x) = m.try_invert(io, self.lim) {
                let v = (io.load(r21, i) * x) * io.load(r12, i) - io.load(r22, i);
                match comp {
                    Some(_) => io.store(&(v - k), self.out),
                    None => io.store(&v, self.out),
                }
            } else {
                for l in 0..LANES {
                    let x = self.invert(m.get(l), f[i + l]);
                    let v = r21[i + l] * x * r12[i + l] - r22[i + l];
                    self.out.push(if comp.is_some() { v - k.get(l) } else { v });
                }
            }
        }
        for i in whole..n {
            let k = comp.map(|c| c.at(f[i], self.lim, self.kdiag));
            let x = self.invert(r11[i] - g[i], f[i]);
            let v = r21[i] * x * r12[i] - r22[i];
            self.out.push(k.map_or(v, |k| v - k));
        }
    }
}

/// Couples substructure `a` at its joint to a base with joint receptance `base` through `interface`, and
/// returns the assembly's free-end receptance (Eqs. 5.3, 5.16–5.17):
/// `G11 = R11 − R12 (R22 + K⁻¹ + B)⁻¹ R21`.
pub fn couple(
    a: &TwoPort,
    base: &ReceptanceFrf,
    interface: &Interface,
    options: &RcsaOptions,
) -> Result<ReceptanceFrf, RcsaError> {
    a.check()?;
    check_len("base", &base.lines, base.freqs_hz.len())?;
    check_grid("substructure", &a.freqs_hz, "base", &base.freqs_hz)?;
    let mut kdiag = Diagnostics::new("interface stiffness K", options.max_condition);
    let mut diag = Diagnostics::new("(R22 + K^-1 + B)", options.max_condition);
    let lim = half_limit_sq(options.max_condition);
    let n = a.freqs_hz.len();
    let mut lines = Vec::with_capacity(n);
    let comp = Compliance::new(interface);
    let mut kernel = Kernel { lim, kdiag: &mut kdiag, diag: &mut diag, out: &mut lines };
    kernel.run(a, &base.lines, comp, Direction::Couple);
    kdiag.finish()?;
    diag.finish()?;
    Ok(ReceptanceFrf { freqs_hz: a.freqs_hz.clone(), lines })
}

/// Inverse RCSA (Eq. 5.4 with the interface of Eqs. 5.16–5.17): the base's joint receptance from the
/// assembly's free-end receptance `g11` and the substructure `a`:
/// `B = R21 (R11 − G11)⁻¹ R12 − R22 − K⁻¹`.
pub fn decouple(
    a: &TwoPort,
    g11: &ReceptanceFrf,
    interface: &Interface,
    options: &RcsaOptions,
) -> Result<ReceptanceFrf, RcsaError> {
    a.check()?;
    check_len("G11", &g11.lines, g11.freqs_hz.len())?;
    check_grid("substructure", &a.freqs_hz, "assembly G11", &g11.freqs_hz)?;
    let mut kdiag = Diagnostics::new("interface stiffness K", options.max_condition);
    let mut diag = Diagnostics::new("(R11 - G11)", options.max_condition);
    let lim = half_limit_sq(options.max_condition);
    let n = a.freqs_hz.len();
    let mut lines = Vec::with_capacity(n);
    let comp = Compliance::new(interface);
    let mut kernel = Kernel { lim, kdiag: &mut kdiag, diag: &mut diag, out: &mut lines };
    kernel.run(a, &g11.lines, comp, Direction::Decouple);
    kdiag.finish()?;
    diag.finish()?;
    Ok(ReceptanceFrf { freqs_hz: a.freqs_hz.clone(), lines })
}

/// The in-plane and cross-plane blocks `(P, Q)` of a spinning structure with isotropic
/// supports, whose 4×4 receptance is `[[P, Q], [−Q, P]]`: one [`ReceptanceFrf`] each.
pub type Spinning = (ReceptanceFrf, ReceptanceFrf);

/// Line by line `P + s·i·Q` (`s = ±1`): the forward (`s = −1`) or backward (`s = +1`) whirl
/// block of a spinning structure from its in-plane and cross-plane blocks.
fn whirl_lines(p: &[Receptance], q: &[Receptance], s: f64) -> Vec<Receptance> {
    let iq = Complex64::new(0.0, s);
    p.iter()
        .zip(q)
        .map(|(p, q)| Receptance::new(p.h + iq * q.h, p.l + iq * q.l, p.n + iq * q.n, p.p + iq * q.p))
        .collect()
}

/// RCSA of a spinning substructure on a spinning base (a rotor model of a spindle), both with
/// isotropic supports and an isotropic joint: in the whirl coordinates `u± = q_y ± i q_z` the
/// two bending planes decouple, so Eq. 5.3 holds in each, `G± = R11± − R12± (R22± + K⁻¹ +
/// B±)⁻¹ R21±`, with `B∓ = P ∓ iQ` of the base. The substructure comes as its forward and
/// backward two-ports; the result is the free end's `(P, Q)`: `P = (G₊ + G₋)/2`, `Q = i(G₊ −
/// G₋)/2`. A `tip_mass` (kg, no polar inertia) acts alike in both coordinates.
pub fn couple_spinning(
    forward: &TwoPort,
    backward: &TwoPort,
    base: &Spinning,
    interface: &Interface,
    tip_mass: f64,
    options: &RcsaOptions,
) -> Result<Spinning, RcsaError> {
    let (p, q) = base;
    check_len("base Q", &q.lines, p.lines.len())?;
    check_grid("base P", &p.freqs_hz, "base Q", &q.freqs_hz)?;
    let whirl = |a: &TwoPort, s: f64| -> Result<ReceptanceFrf, RcsaError> {
        let b = ReceptanceFrf { freqs_hz: p.freqs_hz.clone(), lines: whirl_lines(&p.lines, &q.lines, s) };
        let g = couple(a, &b, interface, options)?;
        if tip_mass > 0.0 { with_point_mass(&g, tip_mass) } else { Ok(g) }
    };
    let (gf, gb) = (whirl(forward, -1.0)?, whirl(backward, 1.0)?);
    let half = Complex64::new(0.5, 0.0);
    let half_i = Complex64::new(0.0, 0.5);
    let comb = |c: Complex64, sign: f64| {
        gf.lines
            .iter()
            .zip(&gb.lines)
            .map(|(f, b)| {
                let m = |x: Complex64, y: Complex64| c * (x + sign * y);
                Receptance::new(m(f.h, b.h), m(f.l, b.l), m(f.n, b.n), m(f.p, b.p))
            })
            .collect::<Vec<_>>()
    };
    Ok((
        ReceptanceFrf { freqs_hz: gf.freqs_hz.clone(), lines: comb(half, 1.0) },
        ReceptanceFrf { freqs_hz: gf.freqs_hz.clone(), lines: comb(half_i, -1.0) },
    ))
}

/// A chain assembled outward from a base (e.g. spindle → holder → tool): each stage is a substructure and
/// the joint between it and everything assembled so far. Returns the free-end receptance of the last stage.
pub fn couple_chain(
    base: &ReceptanceFrf,
    stages: &[(&TwoPort, Interface)],
    options: &RcsaOptions,
) -> Result<ReceptanceFrf, RcsaError> {
    let mut acc = base.clone();
    for (sub, interface) in stages {
        acc = couple(sub, &acc, interface, options)?;
    }
    Ok(acc)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sign convention shared by the beam model and the coupling, proven as the equation
    /// notes ask: two free–free Timoshenko FE beams coupled rigidly by RCSA give the tip
    /// receptances of one FE model of the whole assembly.
    #[test]
    fn two_fe_beams_coupled_equal_one_fe_model_of_the_assembly() {
        use crate::beam::{BeamModel, BeamSegment, CrossSection, MeshOptions};
        use spindlelab_domain::Material as Fe;
        let holder = BeamSegment::uniform(CrossSection::solid(0.05, Fe::STEEL), 0.06);
        let tool = BeamSegment::uniform(CrossSection::solid(0.0127, Fe::CARBIDE), 0.07);
        let mesh = MeshOptions::default();
        let base = BeamModel::from_segments(&[holder], &mesh).unwrap();
        let part = BeamModel::from_segments(&[tool], &mesh).unwrap();
        let whole = BeamModel::from_segments(&[holder, tool], &mesh).unwrap();
        let freqs: Vec<f64> = (1..=400).map(|k| 25.0 * k as f64).collect();
        let conv = |v: Vec<crate::beam::Receptance>| -> Vec<Receptance> {
            v.into_iter().map(|m| Receptance { h: m[0][0], l: m[0][1], n: m[1][0], p: m[1][1] }).collect()
        };
        let (pm, bm, wm) = (part.modes().unwrap(), base.modes().unwrap(), whole.modes().unwrap());
        let (tip, joint) = (part.n_nodes() - 1, 0);
        let r = |resp, exc| conv(pm.receptance(resp, exc, &freqs).unwrap());
        let two = TwoPort {
            freqs_hz: freqs.clone(),
            r11: r(tip, tip),
            r12: r(tip, joint),
            r21: r(joint, tip),
            r22: r(joint, joint),
        };
        let end = base.n_nodes() - 1;
        let base_frf = ReceptanceFrf { freqs_hz: freqs.clone(), lines: conv(bm.receptance(end, end, &freqs).unwrap()) };
        let coupled = couple(&two, &base_frf, &Interface::Rigid, &RcsaOptions::default()).unwrap();
        let last = whole.n_nodes() - 1;
        let monolithic = conv(wm.receptance(last, last, &freqs).unwrap());
        for (k, (g, w)) in coupled.lines.iter().zip(&monolithic).enumerate() {
            for (name, a, b) in [("H", g.h, w.h), ("L", g.l, w.l), ("N", g.n, w.n), ("P", g.p, w.p)] {
                assert!((a - b).norm() <= 1e-6 * b.norm(), "{name} at {} Hz: {a} vs {b}", freqs[k]);
            }
        }
    }
    use crate::eb_modes::{FixedFreeBeam, spindle_receptance};
    use spindlelab_domain::entity::SpindleMode;
    use spindlelab_domain::{Material, Speed};

    /// Free-free rigid body (mass `m`, inertia `j` about its centre of mass) with free end 1 at `x1` and joint
    /// 2 at `x2`, centre of mass at `xg`: `R_PQ = −ω⁻² T_P diag(1/m, 1/j) T_Qᵀ`, `T_P = [[1, x_P − x_G], [0, 1]]`.
    fn rigid_body(freqs: &[f64], m: f64, j: f64, x1: f64, x2: f64, xg: f64) -> TwoPort {
        let block = |xp: f64, xq: f64, w: f64| {
            let (a, b) = (xp - xg, xq - xg);
            let s = -1.0 / (w * w);
            // T_P diag(1/m, 1/j) T_Qᵀ = [[1/m + a b / j, a / j], [b / j, 1 / j]]
            Receptance::new(
                Complex64::from(s * (1.0 / m + a * b / j)),
                Complex64::from(s * a / j),
                Complex64::from(s * b / j),
                Complex64::from(s / j),
            )
        };
        let ws: Vec<f64> = freqs.iter().map(|f| TAU * f).collect();
        TwoPort {
            freqs_hz: freqs.to_vec(),
            r11: ws.iter().map(|&w| block(x1, x1, w)).collect(),
            r12: ws.iter().map(|&w| block(x1, x2, w)).collect(),
            r21: ws.iter().map(|&w| block(x2, x1, w)).collect(),
            r22: ws.iter().map(|&w| block(x2, x2, w)).collect(),
        }
    }

    fn beam_frf(beam: &FixedFreeBeam, freqs: &[f64]) -> ReceptanceFrf {
        ReceptanceFrf { freqs_hz: freqs.to_vec(), lines: freqs.iter().map(|f| beam.tip_receptance(TAU * f)).collect() }
    }

    /// Golden-section maximum of `g(f)` on `[lo, hi]`.
    fn peak(lo: f64, hi: f64, g: impl Fn(f64) -> f64) -> f64 {
        let r = 0.5 * (5f64.sqrt() - 1.0);
        let (mut a, mut b) = (lo, hi);
        for _ in 0..200 {
            let (c, d) = (b - r * (b - a), a + r * (b - a));
            if g(c) > g(d) {
                b = d;
            } else {
                a = c;
            }
        }
        0.5 * (a + b)
    }

    /// Bisection root of `g` on `[lo, hi]` (sign change required).
    fn root(mut lo: f64, mut hi: f64, g: impl Fn(f64) -> f64) -> f64 {
        let glo = g(lo);
        assert!(glo * g(hi) < 0.0);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if (g(mid) > 0.0) == (glo > 0.0) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    #[test]
    fn inverse_and_condition_are_correct() {
        let m = Receptance::new(
            Complex64::new(2.0, 1.0),
            Complex64::new(0.5, -0.3),
            Complex64::new(-0.2, 0.7),
            Complex64::new(1.5, 0.1),
        );
        let (inv, cond) = m.inverse().unwrap();
        assert!((m * inv - Receptance::IDENTITY).max_norm() < 1e-15);
        assert!((1.0..10.0).contains(&cond));
        let sing =
            Receptance::new(Complex64::from(1.0), Complex64::from(2.0), Complex64::from(2.0), Complex64::from(4.0));
        assert!(sing.inverse().is_none());
        // Scaling lengths does not change the condition: H = c² h, L = N = c l.
        let c = 1e-3;
        let scaled = Receptance::new(m.h * (c * c), m.l * c, m.n * c, m.p);
        assert!((scaled.condition() / m.condition() - 1.0).abs() < 1e-9);
    }

    /// Two clamped-free beams joined at their free ends form a clamped-clamped beam of the summed length,
    /// whose first mode satisfies `cos x cosh x = 1`, `x = 4.730040745`, for any joint position. The second
    /// beam's axis points the other way, so it enters mirrored (the sign of L and N is thus tested).
    #[test]
    fn two_cantilevers_join_into_a_clamped_clamped_beam() {
        let mat = Material::STEEL;
        let (l1, l2, d) = (0.35, 0.2, 0.03);
        let eta = 1e-6;
        let a = FixedFreeBeam::new(l1, d, eta, mat).unwrap();
        let b = FixedFreeBeam::new(l2, d, eta, mat).unwrap();
        let total = l1 + l2;
        let f_cc = 4.730_040_744_862_704f64.powi(2) / (TAU * total * total)
            * (mat.youngs_modulus * a.second_moment() / (mat.density * a.area())).sqrt();
        let g = |f: f64| {
            let grid = [f];
            let sub = TwoPort::single_point(&beam_frf(&a, &grid));
            let mut base = beam_frf(&b, &grid);
            base.lines[0] = base.lines[0].mirrored();
            couple(&sub, &base, &Interface::Rigid, &RcsaOptions::default()).unwrap().lines[0].h.norm()
        };
        let fp = peak(0.8 * f_cc, 1.2 * f_cc, g);
        assert!((fp / f_cc - 1.0).abs() < 1e-6, "peak {fp}, clamped-clamped {f_cc}");
        // Without the mirror the joint would see a wrong rotation coupling and the peak moves.
        let g_wrong = |f: f64| {
            let grid = [f];
            let sub = TwoPort::single_point(&beam_frf(&a, &grid));
            couple(&sub, &beam_frf(&b, &grid), &Interface::Rigid, &RcsaOptions::default()).unwrap().lines[0].h.norm()
        };
        let fw = peak(0.8 * f_cc, 1.2 * f_cc, g_wrong);
        assert!((fw / f_cc - 1.0).abs() > 1e-3);
    }

    /// A cantilever carrying a rigid tip body of mass `M` and inertia `J` (a two-port body at one point):
    /// `1 + cos x cosh x + μx(cos x sinh x − sin x cosh x) − j x³(sin x cosh x + cos x sinh x)
    ///  + μ j x⁴ (1 − cos x cosh x) = 0`, `μ = M/(ρAL)`, `j = J/(ρAL³)`.
    #[test]
    fn cantilever_with_tip_body_matches_frequency_equation() {
        let mat = Material::STEEL;
        let beam = FixedFreeBeam::new(0.25, 0.04, 1e-7, mat).unwrap();
        let mbeam = mat.density * beam.area() * beam.length_m;
        let (mu, jr) = (0.8, 0.05);
        let (m, j) = (mu * mbeam, jr * mbeam * beam.length_m.powi(2));
        let freq_eq = |x: f64| {
            let (s, c, sh, ch) = (x.sin(), x.cos(), x.sinh(), x.cosh());
            1.0 + c * ch + mu * x * (c * sh - s * ch) - jr * x.powi(3) * (s * ch + c * sh)
                + mu * jr * x.powi(4) * (1.0 - c * ch)
        };
        let x1 = root(0.3, 1.875, freq_eq);
        let f1 = x1 * x1 / (TAU * beam.length_m.powi(2))
            * (mat.youngs_modulus * beam.second_moment() / (mat.density * beam.area())).sqrt();
        let g = |f: f64| {
            let grid = [f];
            let body = rigid_body(&grid, m, j, 0.0, 0.0, 0.0);
            couple(&body, &beam_frf(&beam, &grid), &Interface::Rigid, &RcsaOptions::default()).unwrap().lines[0]
                .h
                .norm()
        };
        let fp = peak(0.7 * f1, 1.3 * f1, g);
        assert!((fp / f1 - 1.0).abs() < 1e-6, "peak {fp}, frequency equation {f1}");
    }

    fn spindle(freqs: &[f64]) -> ReceptanceFrf {
        let modes = [SpindleMode::new(700.0, 0.11, 0.05), SpindleMode::new(1900.0, 0.07, 0.04)];
        spindle_receptance(&modes, &Material::STEEL, Speed::ZERO, Speed::from_rpm(10000.0), freqs, None).unwrap()
    }

    /// The four-line kernels give every line the bits of the scalar formulas, on groups that
    /// pass the fast inversion test and on groups with a line it turns away (condition 5.8,
    /// limit 8), with a remainder, rigid and through a joint.
    #[test]
    fn lane_and_line_coupling_are_bit_identical() {
        let n = 4 * 25 + 3;
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut block = |scale: f64| {
            let mut c = || Complex64::new(scale * rnd(), scale * rnd());
            Receptance::new(c(), c(), c(), c())
        };
        let freqs: Vec<f64> = (1..=n).map(|k| 10.0 * k as f64).collect();
        let lines = |f: &mut dyn FnMut() -> Receptance| -> Vec<Receptance> { (0..n).map(|_| f()).collect() };
        let two = TwoPort {
            freqs_hz: freqs.clone(),
            r11: lines(&mut || block(1.0)),
            r12: lines(&mut || block(1.0)),
            r21: lines(&mut || block(1.0)),
            r22: lines(&mut || block(0.05)),
        };
        // Base: near the identity, except two lines where R22 + B is [[1, 2], [0, 1]].
        let mut base =
            ReceptanceFrf { freqs_hz: freqs.clone(), lines: lines(&mut || block(0.05) + Receptance::IDENTITY) };
        let hard = Receptance::new(1.0.into(), 2.0.into(), 0.0.into(), 1.0.into());
        for i in [9, n - 2] {
            base.lines[i] = hard - two.r22[i];
        }
        let options = RcsaOptions { max_condition: 8.0 };
        let lim = half_limit_sq(options.max_condition);
        for interface in [Interface::Rigid, Interface::diagonal(1e3, 0.1, 2e3, 0.2)] {
            let comp = Compliance::new(&interface);
            let mut d = Diagnostics::new("", options.max_condition);
            let kinv = |f: f64, d: &mut Diagnostics| comp.map(|c| c.at(f, lim, d));
            let invert =
                |m: Receptance, f: f64, d: &mut Diagnostics| try_invert(&m, lim).unwrap_or_else(|| d.invert(m, f));
            let coupled = couple(&two, &base, &interface, &options).unwrap();
            // R11 − G11 = R12 X R21 of random blocks: far from the identity, so the default limit.
            let wide = RcsaOptions::default();
            let decoupled = decouple(&two, &coupled, &interface, &wide).unwrap();
            let lim2 = half_limit_sq(wide.max_condition);
            let mut d2 = Diagnostics::new("", wide.max_condition);
            for (i, &f) in freqs.iter().enumerate() {
                let k = kinv(f, &mut d);
                let m = match k {
                    Some(k) => two.r22[i] + k + base.lines[i],
                    None => two.r22[i] + base.lines[i],
                };
                let want = two.r11[i] - two.r12[i] * invert(m, f, &mut d) * two.r21[i];
                let got = coupled.lines[i];
                let bits = |r: &Receptance| [r.h, r.l, r.n, r.p].map(|z| (z.re.to_bits(), z.im.to_bits()));
                assert_eq!(bits(&got), bits(&want), "couple, line {i}");
                let m = two.r11[i] - coupled.lines[i];
                let x = try_invert(&m, lim2).unwrap_or_else(|| d2.invert(m, f));
                let v = two.r21[i] * x * two.r12[i] - two.r22[i];
                let want = k.map_or(v, |k| v - k);
                assert_eq!(bits(&decoupled.lines[i]), bits(&want), "decouple, line {i}");
            }
            assert!(d.freqs.is_empty() && d2.freqs.is_empty());
            // The portable lanes (what a CPU without AVX runs) give the same bits too.
            let portable = |direction: Direction, lines: &[Receptance], options: &RcsaOptions| {
                let mut kd = Diagnostics::new("", options.max_condition);
                let mut dg = Diagnostics::new("", options.max_condition);
                let mut out = Vec::with_capacity(n);
                let lim = half_limit_sq(options.max_condition);
                let mut k = Kernel { lim, kdiag: &mut kd, diag: &mut dg, out: &mut out };
                match direction {
                    Direction::Couple => k.couple(PortableIo, &two, lines, comp),
                    Direction::Decouple => k.decouple(PortableIo, &two, lines, comp),
                }
                out
            };
            let all_bits = |v: &[Receptance]| -> Vec<u64> {
                v.iter().flat_map(|r| [r.h, r.l, r.n, r.p]).flat_map(|z| [z.re.to_bits(), z.im.to_bits()]).collect()
            };
            assert_eq!(all_bits(&portable(Direction::Couple, &base.lines, &options)), all_bits(&coupled.lines));
            assert_eq!(all_bits(&portable(Direction::Decouple, &coupled.lines, &wide)), all_bits(&decoupled.lines));
        }
    }

    #[test]
    fn couple_then_decouple_recovers_the_spindle() {
        let freqs: Vec<f64> = (1..=2000).map(|i| 2.5 * i as f64).collect();
        let sp = spindle(&freqs);
        // A 1.2 kg artifact, tip 80 mm from the flange, centre of mass 30 mm out.
        let art = rigid_body(&freqs, 1.2, 1.5e-3, 0.08, 0.0, 0.03);
        for interface in [Interface::Rigid, Interface::diagonal(2e8, 300.0, 4e6, 5.0)] {
            let g = couple(&art, &sp, &interface, &RcsaOptions::default()).unwrap();
            let back = decouple(&art, &g, &interface, &RcsaOptions::default()).unwrap();
            for (got, want) in back.lines.iter().zip(&sp.lines) {
                assert!((*got - *want).max_norm() <= 1e-8 * want.max_norm(), "{got:?} vs {want:?}");
            }
        }
    }

    #[test]
    fn stiff_interface_tends_to_rigid_and_soft_one_lowers_the_first_mode() {
        let freqs: Vec<f64> = (1..=4000).map(|i| 0.5 * i as f64).collect();
        let sp = spindle(&freqs);
        let art = rigid_body(&freqs, 1.2, 1.5e-3, 0.08, 0.0, 0.03);
        let opts = RcsaOptions::default();
        let rigid = couple(&art, &sp, &Interface::Rigid, &opts).unwrap();
        let stiff = couple(&art, &sp, &Interface::diagonal(1e20, 0.0, 1e18, 0.0), &opts).unwrap();
        for (a, b) in stiff.lines.iter().zip(&rigid.lines) {
            assert!((*a - *b).max_norm() <= 1e-8 * b.max_norm());
        }
        let first_peak = |g: &ReceptanceFrf| {
            let i = (1..g.lines.len() - 1)
                .find(|&i| {
                    g.lines[i].h.norm() > g.lines[i - 1].h.norm() && g.lines[i].h.norm() >= g.lines[i + 1].h.norm()
                })
                .unwrap();
            g.freqs_hz[i]
        };
        let soft = couple(&art, &sp, &Interface::diagonal(2e7, 0.0, 3e5, 0.0), &opts).unwrap();
        assert!(first_peak(&soft) < 0.95 * first_peak(&rigid), "{} vs {}", first_peak(&soft), first_peak(&rigid));
    }

    #[test]
    fn chain_of_three_equals_stepwise_coupling() {
        let freqs: Vec<f64> = (1..=500).map(|i| 10.0 * i as f64).collect();
        let sp = spindle(&freqs);
        let holder = rigid_body(&freqs, 1.0, 1e-3, 0.07, 0.0, 0.03);
        let tool = rigid_body(&freqs, 0.1, 2e-5, 0.05, 0.0, 0.025);
        let joint = Interface::diagonal(1.5e8, 250.0, 3e5, 4.0);
        let opts = RcsaOptions::default();
        let chain = couple_chain(&sp, &[(&holder, Interface::Rigid), (&tool, joint)], &opts).unwrap();
        let step = couple(&tool, &couple(&holder, &sp, &Interface::Rigid, &opts).unwrap(), &joint, &opts).unwrap();
        assert_eq!(chain, step);
        // Two rigid bodies joined rigidly are one rigid body: mass 1.1 kg, and the holder-tool chain with a
        // rigid joint equals a single body with the combined inertia about the combined centre of mass.
        let rigid_chain = couple_chain(&sp, &[(&holder, Interface::Rigid), (&tool, Interface::Rigid)], &opts).unwrap();
        // Tool frame: joint at 0 (holder tip, 0.07 from flange), tip at 0.05; in flange frame tip at 0.12.
        let (m1, j1, g1): (f64, f64, f64) = (1.0, 1e-3, 0.03);
        let (m2, j2, g2): (f64, f64, f64) = (0.1, 2e-5, 0.07 + 0.025);
        let m = m1 + m2;
        let g = (m1 * g1 + m2 * g2) / m;
        let j = j1 + m1 * (g1 - g).powi(2) + j2 + m2 * (g2 - g).powi(2);
        let one = couple(&rigid_body(&freqs, m, j, 0.12, 0.0, g), &sp, &Interface::Rigid, &opts).unwrap();
        // Rigid-body receptances (∝ 1/ω²) exceed the assembly's by ~1e7 at 10 Hz, so the subtraction in
        // Eq. 5.3 loses about seven digits there.
        for ((a, b), f) in rigid_chain.lines.iter().zip(&one.lines).zip(&freqs) {
            assert!((*a - *b).max_norm() <= 1e-7 * b.max_norm(), "{f} Hz: {a:?} vs {b:?}");
        }
    }

    /// A rigid body on a spring-damper joint to rigid ground (`B = 0`) is the single-degree-of-freedom
    /// system of Eq. 5.8 in each coordinate: `H = 1/(K − Mω² + iωC)`, `K = M(2πf_n)²`, `C = 2ξ sqrt(MK)`,
    /// and `P = 1/(k_r − Jω² + iωc_r)`.
    #[test]
    fn body_on_flexible_joint_to_ground_is_a_single_dof_oscillator() {
        let (m, jm, fnat, xi) = (0.4, 2e-4, 1500.0, 0.03);
        let k = m * (TAU * fnat).powi(2);
        let c = 2.0 * xi * (m * k).sqrt();
        let (kr, cr) = (5e4, 0.7);
        let freqs: Vec<f64> = (1..=300).map(|i| 10.0 * i as f64).collect();
        let body = rigid_body(&freqs, m, jm, 0.0, 0.0, 0.0);
        let ground = ReceptanceFrf { freqs_hz: freqs.clone(), lines: vec![Receptance::ZERO; freqs.len()] };
        let g = couple(&body, &ground, &Interface::diagonal(k, c, kr, cr), &RcsaOptions::default()).unwrap();
        for (line, &f) in g.lines.iter().zip(&freqs) {
            let w = TAU * f;
            let h = Complex64::from(1.0) / Complex64::new(k - m * w * w, w * c);
            let p = Complex64::from(1.0) / Complex64::new(kr - jm * w * w, w * cr);
            assert!((line.h - h).norm() <= 1e-9 * h.norm(), "{f} Hz: {} vs {h}", line.h);
            assert!((line.p - p).norm() <= 1e-9 * p.norm());
            assert!(line.l.norm() <= 1e-9 * (h.norm() * p.norm()).sqrt());
        }
        // The peak sits at the damped-oscillator resonance.
        let i = (0..g.lines.len()).max_by(|&a, &b| g.lines[a].h.norm().total_cmp(&g.lines[b].h.norm())).unwrap();
        assert_eq!(freqs[i], fnat);
    }

    #[test]
    fn mismatched_grids_and_singular_inversions_are_reported() {
        let f1: Vec<f64> = (1..=10).map(|i| i as f64).collect();
        let mut f2 = f1.clone();
        f2[3] = 4.5;
        let art = rigid_body(&f1, 1.0, 1e-3, 0.1, 0.0, 0.05);
        let err = couple(&art, &spindle(&f2), &Interface::Rigid, &RcsaOptions::default()).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("substructure") && msg.contains("base") && msg.contains("line 3"), "{msg}");
        // Decoupling with G11 = R11 makes (R11 − G11) singular on every line.
        let g = ReceptanceFrf { freqs_hz: f1.clone(), lines: art.r11.clone() };
        match decouple(&art, &g, &Interface::Rigid, &RcsaOptions::default()) {
            Err(RcsaError::IllConditioned { freqs_hz, worst_condition, .. }) => {
                assert_eq!(freqs_hz, f1);
                assert!(worst_condition.is_infinite());
            }
            other => panic!("expected IllConditioned, got {other:?}"),
        }
        // A joint with no rotational stiffness is a hinge: K is singular.
        let hinge = Interface::diagonal(1e8, 0.0, 0.0, 0.0);
        assert!(matches!(
            couple(&art, &spindle(&f1), &hinge, &RcsaOptions::default()),
            Err(RcsaError::IllConditioned { .. })
        ));
    }
}
