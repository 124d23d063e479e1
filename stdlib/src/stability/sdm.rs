//! First-order semi-discretization of the milling equation (Insperger & Stépán 2002, IJNME 55:503–518;
//! 2004, IJNME 61:117–141; first-order delay interpolation after Insperger, Stépán & Turi 2008, JSV 313:334–341).
//!
//! Each direction is a sum of modes with unit mode shape at the tool point, `q = (x, y)`, and the tool obeys
//! `M q̈ + C q̇ + K q = −a_p H(t) [q(t) − q(t − τ)]` with `H(t)` from [`Milling::force_matrix`]. The tooth period
//! `τ = 60/(N n)` is split into `m` steps; on step `i` the coefficient matrix is replaced by its mean (exact
//! integral of `H` over the step, screen function included) and the delayed position by the linear interpolant
//! between `q_{i−m}` and `q_{i−m+1}`. Solving each step exactly gives
//! `y_{i+1} = Φ_i y_i + (F0_i − F1_i) B_i q_{i−m} + F1_i B_i q_{i−m+1}` with `Φ_i = e^{A_i Δt}`,
//! `F0 = ∫₀^Δt e^{A(Δt−s)} ds`, `F1 = ∫₀^Δt e^{A(Δt−s)} s/Δt ds`; the product over one period is the monodromy
//! matrix acting on `(y_0, q_{−1}, …, q_{−m})`, and the cut is asymptotically stable iff its spectral radius is
//! below one. Modal velocities are scaled by `1/ω_r` so that the matrices are balanced. The dominant multiplier
//! comes from an Arnoldi iteration on the step-by-step operator (the matrix is never formed), accepted on a Ritz
//! residual below 1e-11 relative, with the dense QR eigen-solve of the formed matrix as fallback.
//!
//! Variable pitch and helix (Insperger & Stépán 2004; Sims, Mann & Huyanan 2008, JSV 317:664–686): with unequal
//! pitch tooth `j` regenerates over its own delay `τ_j = pitch_j/Ω` ([`Milling::tooth_delay`]), the equation
//! becomes `M q̈ + C q̇ + K q = −a_p Σ_j H_j(t) [q(t) − q(t − τ_j)]` and its period is the spindle revolution. The
//! revolution is then split into `N m` steps of the same length as for equal pitch; each step's delayed term is
//! split per tooth (teeth of equal pitch together), tooth `j`'s delayed position interpolated linearly between
//! the recorded positions around `t − τ_j` (`τ_j/Δt` need not be an integer: the ends of the step fall between
//! grid points, each end interpolated between its two neighbours), and the state holds the positions back to the
//! longest delay. Equal pitch keeps the single delay and the tooth period (the same numbers as before). With a
//! helix the step means come from the depth-averaged force matrix ([`Milling::force_matrix_integral_at`], exact
//! along the flute), which depends on the depth, so they are rebuilt at every depth.

use super::linalg::{eigenvalues, hessenberg_eigenvalues};
use super::zoa::ToolPointFrf;
use super::{Milling, StabilityError};
use num_complex::Complex64;
use rayon::prelude::*;
use std::f64::consts::TAU;

/// The mode type of every kernel: natural frequency (Hz), damping ratio and modal mass (kg), receptance Eq. 5.8.
pub use spindlelab_domain::value::Mode;

/// Modes of the tool point along `x` (feed) and `y`; a direction without modes is rigid.
#[derive(Debug, Clone, PartialEq)]
pub struct ModalModel {
    /// Modes along `x`.
    pub x: Vec<Mode>,
    /// Modes along `y`.
    pub y: Vec<Mode>,
}

impl ModalModel {
    /// Checks every mode (positive frequency and mass, damping in `[0, 1)`) and that there is at least one.
    pub fn new(x: Vec<Mode>, y: Vec<Mode>) -> Result<Self, StabilityError> {
        for (direction, modes) in [("x", &x), ("y", &y)] {
            for (index, m) in modes.iter().enumerate() {
                let problem = if !(m.freq_hz.is_finite() && m.freq_hz > 0.0) {
                    Some(format!("natural frequency {} Hz must be finite and > 0", m.freq_hz))
                } else if !(m.damping_ratio.is_finite() && (0.0..1.0).contains(&m.damping_ratio)) {
                    Some(format!("damping ratio {} must be in [0, 1)", m.damping_ratio))
                } else if !(m.modal_mass.is_finite() && m.modal_mass > 0.0) {
                    Some(format!("modal mass {} kg must be finite and > 0", m.modal_mass))
                } else {
                    None
                };
                if let Some(problem) = problem {
                    return Err(StabilityError::InvalidMode { direction, index, problem });
                }
            }
        }
        if x.is_empty() && y.is_empty() {
            return Err(StabilityError::InvalidMode {
                direction: "x",
                index: 0,
                problem: "the model has no modes in x or y; give at least one".into(),
            });
        }
        Ok(ModalModel { x, y })
    }

    /// Tool-point receptances of the model on `freqs_hz` (no cross terms), for the ZOA.
    pub fn receptance(&self, freqs_hz: &[f64]) -> Result<ToolPointFrf, StabilityError> {
        let sum = |modes: &[Mode], f: f64| {
            let w = TAU * f;
            modes.iter().map(|m| m.receptance(w)).sum::<Complex64>()
        };
        ToolPointFrf::new(
            freqs_hz.to_vec(),
            freqs_hz.iter().map(|&f| sum(&self.x, f)).collect(),
            freqs_hz.iter().map(|&f| sum(&self.y, f)).collect(),
        )
    }
}

/// How many time steps a tooth period is split into.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepCount {
    /// Exactly this many steps per tooth period (≥ 2).
    Fixed(usize),
    /// Chosen per speed by [`sd_steps`]: enough steps that the step is at most `1/per_natural_period` of the
    /// shortest natural period of the model, never fewer than `min` nor more than `max`.
    Auto {
        /// Steps per shortest natural period.
        per_natural_period: f64,
        /// Floor on the steps per tooth period.
        min: usize,
        /// Cap on the steps per tooth period.
        max: usize,
    },
}

impl StepCount {
    /// The default automatic rule: at least [`AUTO_STEPS_PER_NATURAL_PERIOD`] steps per shortest natural period,
    /// 40 to 1000 steps per tooth period.
    pub const AUTO: StepCount =
        StepCount::Auto { per_natural_period: AUTO_STEPS_PER_NATURAL_PERIOD, min: 40, max: 1000 };
}

/// Steps per shortest natural period of [`StepCount::AUTO`]. First-order SD converges about quadratically in the
/// step, and at low speeds (several natural periods per tooth period) the error at a given `Δt/T_n` grows: on the
/// Insperger–Stépán slotting benchmark at 7,000 rpm (four natural periods per tooth period) 10, 20, 30, 40 and 60
/// steps per natural period (m = 40 … 240) put the limit 19 %, 3.8 %, 1.6 %, 0.9 % and 0.4 % above the converged
/// one; 50 keeps it below 1 % with margin.
pub const AUTO_STEPS_PER_NATURAL_PERIOD: f64 = 50.0;

/// Options of the semi-discretization.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SdOptions {
    /// Steps per tooth period `m`: fixed, or chosen per speed from the modes.
    pub steps: StepCount,
    /// Depths scanned from `max/scan` to `max` before bisection in [`sd_depth_limit`].
    pub scan_points: usize,
    /// Bisection stops when the bracket is narrower than this, m.
    pub depth_tolerance_m: f64,
}

impl Default for SdOptions {
    fn default() -> Self {
        SdOptions { steps: StepCount::AUTO, scan_points: 40, depth_tolerance_m: 1e-7 }
    }
}

impl SdOptions {
    /// The default options with exactly `m` steps per tooth period.
    pub fn fixed(m: usize) -> Self {
        SdOptions { steps: StepCount::Fixed(m), ..SdOptions::default() }
    }
}

/// Steps per tooth period at `speed_rpm`: the fixed count, or for [`StepCount::Auto`]
/// `clamp(⌈q τ/T_min⌉, min, max)` with the tooth period `τ = 60/(N n)` and the shortest natural period `T_min`
/// of the model's modes, so that the step `Δt = τ/m` stays a small fraction of every mode's period.
pub fn sd_steps(
    model: &ModalModel,
    milling: &Milling,
    speed_rpm: f64,
    count: StepCount,
) -> Result<usize, StabilityError> {
    let (q, min, max) = match count {
        StepCount::Fixed(m) => return Ok(m),
        StepCount::Auto { per_natural_period, min, max } => (per_natural_period, min, max),
    };
    if !(q.is_finite() && q > 0.0) || min < 2 || max < min {
        return Err(StabilityError::InvalidParameter {
            name: "automatic steps (per natural period, min, max)",
            value: q,
            requirement: "per natural period finite and > 0, 2 ≤ min ≤ max",
        });
    }
    if !(speed_rpm.is_finite() && speed_rpm > 0.0) {
        return Err(StabilityError::InvalidParameter {
            name: "spindle speed",
            value: speed_rpm,
            requirement: "finite and > 0 rpm",
        });
    }
    let f_max = model.x.iter().chain(&model.y).map(|m| m.freq_hz).fold(0.0, f64::max);
    let wanted = (q * milling.tooth_period(speed_rpm) * f_max).ceil();
    Ok(if wanted.is_finite() { (wanted as usize).clamp(min, max) } else { max })
}

/// How the dominant Floquet multiplier leaves the unit circle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bifurcation {
    /// A complex pair (secondary Hopf / Neimark–Sacker): quasi-periodic chatter.
    Hopf,
    /// A real multiplier through −1: period-doubling chatter at half the tooth frequency.
    Flip,
    /// A real multiplier through +1.
    Fold,
}

/// Spectral radius and dominant multiplier at one `(speed, depth)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SdPoint {
    /// Largest modulus of the monodromy eigenvalues; stable iff < 1.
    pub spectral_radius: f64,
    /// The eigenvalue of largest modulus (the one with positive imaginary part for a pair).
    pub multiplier: Complex64,
    /// Type of the dominant multiplier.
    pub kind: Bifurcation,
}

/// Spectral radii on a speed × depth grid.
#[derive(Debug, Clone, PartialEq)]
pub struct StabilityMap {
    /// Speeds, rpm.
    pub speeds_rpm: Vec<f64>,
    /// Depths, m.
    pub depths_m: Vec<f64>,
    /// Row-major `[speed][depth]` spectral radii.
    pub spectral_radius: Vec<f64>,
    /// Steps per tooth period used at each speed.
    pub steps: Vec<usize>,
}

impl StabilityMap {
    /// Spectral radius at speed index `i`, depth index `j`.
    pub fn radius(&self, i: usize, j: usize) -> f64 {
        self.spectral_radius[i * self.depths_m.len() + j]
    }

    /// True where the cut is stable.
    pub fn is_stable(&self, i: usize, j: usize) -> bool {
        self.radius(i, j) < 1.0
    }
}

/// Per-speed result of [`sd_depth_limit`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthLimit {
    /// Speed, rpm.
    pub speed_rpm: f64,
    /// The smallest depth at which the cut loses stability (bisected), m; `+∞` if stable up to the maximum.
    pub depth_m: f64,
    /// Dominant multiplier just above `depth_m`.
    pub multiplier: Complex64,
    /// Its type.
    pub kind: Option<Bifurcation>,
    /// Chatter frequency at the limit, Hz (0 where there is none): of the frequencies
    /// `±arg μ/(2πτ) + k/τ` the multiplier `μ` leaves open, the one at which the tool moves most in
    /// its Floquet solution (see [`Sd::chatter_frequency`]), the frequency a time-domain
    /// simulation or a microphone hears; `|arg μ|/(2πτ)` alone is that frequency folded into
    /// `[0, f_tooth/2]`.
    pub chatter_hz: f64,
    /// True if a larger scanned depth (≤ the maximum) is stable again: the stable depths at this speed are not
    /// one interval, and `depth_m` is the lower end of the first unstable one.
    pub restabilises: bool,
    /// Steps per tooth period used (per mean tooth period for unequal pitch, whose revolution takes `N` times as
    /// many).
    pub steps: usize,
}

/// One regenerative delay of the discretized equation, `τ = (lag + frac) Δt`: over step `i` the delayed
/// position runs from `q(t_i − τ)` to `q(t_{i+1} − τ)`, each interpolated linearly between the recorded
/// positions around it (`q_{i−lag}` and `q_{i−lag+1}` exactly when `frac = 0`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Delay {
    lag: usize,
    frac: f64,
}

/// The step operators of one period at one depth:
/// `y_{i+1} = Φ_i y_i + Σ_g (Ra_ig q(t_i − τ_g) + Rb_ig q(t_{i+1} − τ_g))`.
struct Steps {
    n: usize,
    d: usize,
    nq: usize,
    /// Steps per period (the tooth period for equal pitch, the revolution otherwise).
    m: usize,
    /// Recorded positions the state holds, `q_{−1} … q_{−hist}` (`m` for equal pitch).
    hist: usize,
    /// Active-direction column of each mode (`q = T y` sums the modal displacements of a direction).
    qcol: Vec<usize>,
    /// Steps with no tooth in the cut: `Φ_i = e^{A0 Δt}` and no delayed term.
    free: Vec<bool>,
    /// The delays (one for equal pitch).
    delays: Vec<Delay>,
    /// Whether delay `g` acts on step `i` (some tooth of that delay is in the cut), `m × delays`.
    active: Vec<bool>,
    /// `Φ_i`, `m × d × d`.
    phis: Vec<f64>,
    /// `Ra_ig = (F0 − F1) B_ig` and `Rb_ig = F1 B_ig`, `m × delays × d × nq` each.
    ra: Vec<f64>,
    rb: Vec<f64>,
}

/// Scratch of [`Steps::apply`].
struct ApplyScratch {
    hist: Vec<f64>,
    y: Vec<f64>,
    y2: Vec<f64>,
    qa: Vec<f64>,
    qb: Vec<f64>,
}

impl Steps {
    /// Order of the monodromy matrix: the state `y_0` and the delayed positions `q_{−1} … q_{−hist}`.
    fn size(&self) -> usize {
        self.d + self.nq * self.hist
    }

    /// `out = M z` for the monodromy matrix `M` without forming it: `z = (y_0, q_{−1}, …, q_{−L})`,
    /// `out = (y_m, q_{m−1}, …, q_{m−L})` with `L` = [`Steps::hist`], the positions `q_i = T y_i` recorded as the
    /// period is stepped through (left in the scratch's `hist`, `q_t` at `(t + L) nq` for `t = −L … m − 1`).
    fn apply(&self, z: &[f64], out: &mut [f64], s: &mut ApplyScratch) {
        let (n, d, nq, m, l) = (self.n, self.d, self.nq, self.m, self.hist);
        let groups = self.delays.len();
        for slot in 1..=l {
            s.hist[(l - slot) * nq..(l - slot + 1) * nq].copy_from_slice(&z[d + (slot - 1) * nq..d + slot * nq]);
        }
        s.y.copy_from_slice(&z[..d]);
        for i in 0..m {
            let qi = &mut s.hist[(i + l) * nq..(i + l + 1) * nq];
            qi.fill(0.0);
            for r in 0..n {
                qi[self.qcol[r]] += s.y[r];
            }
            let phi = &self.phis[i * d * d..(i + 1) * d * d];
            for (row, o) in s.y2.iter_mut().enumerate() {
                *o = phi[row * d..(row + 1) * d].iter().zip(&s.y).map(|(p, v)| p * v).sum();
            }
            if !self.free[i] {
                for (g, delay) in self.delays.iter().enumerate() {
                    let at = i * groups + g;
                    if !self.active[at] {
                        continue;
                    }
                    // q_{i−lag} sits at (i − lag + l) nq.
                    let base = i + l - delay.lag;
                    let (ra, rb) = (&self.ra[at * d * nq..(at + 1) * d * nq], &self.rb[at * d * nq..(at + 1) * d * nq]);
                    if delay.frac == 0.0 {
                        let (qa, qb) = (&s.hist[base * nq..(base + 1) * nq], &s.hist[(base + 1) * nq..(base + 2) * nq]);
                        for (row, o) in s.y2.iter_mut().enumerate() {
                            for c in 0..nq {
                                *o += ra[row * nq + c] * qa[c] + rb[row * nq + c] * qb[c];
                            }
                        }
                    } else {
                        let f = delay.frac;
                        for c in 0..nq {
                            let (q0, q1, q2) =
                                (s.hist[(base - 1) * nq + c], s.hist[base * nq + c], s.hist[(base + 1) * nq + c]);
                            s.qa[c] = f * q0 + (1.0 - f) * q1;
                            s.qb[c] = f * q1 + (1.0 - f) * q2;
                        }
                        for (row, o) in s.y2.iter_mut().enumerate() {
                            for c in 0..nq {
                                *o += ra[row * nq + c] * s.qa[c] + rb[row * nq + c] * s.qb[c];
                            }
                        }
                    }
                }
            }
            std::mem::swap(&mut s.y, &mut s.y2);
        }
        out[..d].copy_from_slice(&s.y);
        for slot in 1..=l {
            out[d + (slot - 1) * nq..d + slot * nq]
                .copy_from_slice(&s.hist[(m + l - slot) * nq..(m + l - slot + 1) * nq]);
        }
    }
}

/// Largest Krylov dimension before falling back to the dense eigen-solve.
const KRYLOV_MAX: usize = 60;
/// Krylov dimensions at which the dominant Ritz pair is tested.
const KRYLOV_CHECKS: [usize; 7] = [12, 18, 24, 32, 40, 50, 60];
/// Monodromy matrices up to this order are solved densely.
const DENSE_MAX: usize = 32;
/// Largest monodromy order whose eigenvector is found densely (inverse iteration) when the Krylov iteration
/// gives none.
const DENSE_VECTOR_MAX: usize = 600;
/// Accepted relative residual `‖M x − θ x‖/|θ|` of the dominant Ritz pair.
const RITZ_TOLERANCE: f64 = 1e-11;

/// Scratch of the Arnoldi iteration.
struct Krylov {
    /// Orthonormal basis, one vector of the monodromy order per row.
    v: Vec<f64>,
    /// Hessenberg matrix `(KRYLOV_MAX + 1) × KRYLOV_MAX`, row-major.
    h: Vec<f64>,
    w: Vec<f64>,
    coef: Vec<f64>,
    hk: Vec<f64>,
    ritz: Vec<(f64, f64)>,
    lu: Vec<Complex64>,
    x: Vec<Complex64>,
    /// Krylov dimension and `‖H‖` of the last accepted Ritz pair (for its vector).
    accepted: usize,
    hnorm: f64,
}

/// Scratch and per-speed data of one semi-discretization.
struct Sd {
    /// Skip the Krylov iteration (to check it against the dense solve).
    dense_only: bool,
    /// The period is the revolution with one delay per pitch (else the tooth period with one delay).
    multi: bool,
    /// The cut (the step means are rebuilt per depth with a helix).
    milling: Milling,
    /// Spindle speed, rad/s.
    rate: f64,
    /// Delay group of each tooth.
    group: Vec<usize>,
    dt: f64,
    /// Per mode: `ω_r`, `ζ_r`, `1/(m_r ω_r)`, direction (0 x, 1 y).
    omega: Vec<f64>,
    zeta: Vec<f64>,
    gain: Vec<f64>,
    dir: Vec<usize>,
    dirs: Vec<usize>,
    /// Mean `H` per step and delay group, `m × delays`.
    h: Vec<[[f64; 2]; 2]>,
    /// Mean `H` per step, all teeth.
    h_total: Vec<[[f64; 2]; 2]>,
    /// `e^{A0 Δt}`, the step with no tooth in the cut.
    phi0: Vec<f64>,
    steps: Steps,
    apply: ApplyScratch,
    krylov: Krylov,
    // Exponential scratch.
    a: Vec<f64>,
    phi: Vec<f64>,
    f0: Vec<f64>,
    g: Vec<f64>,
    x: Vec<f64>,
    pw: Vec<f64>,
    t1: Vec<f64>,
    // Dense fallback.
    mono: Vec<f64>,
    col: Vec<f64>,
    eig: Vec<(f64, f64)>,
}

impl Sd {
    /// The semi-discretization at `speed_rpm` with `steps` per tooth period; `multi` forces the revolution and
    /// one delay per pitch even for equal pitch (unequal pitch always takes it).
    fn new(
        model: &ModalModel,
        milling: &Milling,
        speed_rpm: f64,
        steps: usize,
        multi: bool,
    ) -> Result<Self, StabilityError> {
        if !(speed_rpm.is_finite() && speed_rpm > 0.0) {
            return Err(StabilityError::InvalidParameter {
                name: "spindle speed",
                value: speed_rpm,
                requirement: "finite and > 0 rpm",
            });
        }
        if steps < 2 {
            return Err(StabilityError::InvalidParameter {
                name: "steps per tooth period",
                value: steps as f64,
                requirement: "≥ 2 (40 is a good default)",
            });
        }
        let mut dirs = Vec::new();
        if !model.x.is_empty() {
            dirs.push(0);
        }
        if !model.y.is_empty() {
            dirs.push(1);
        }
        let (mut omega, mut zeta, mut gain, mut dir, mut qcol) = (vec![], vec![], vec![], vec![], vec![]);
        for (c, &dr) in dirs.iter().enumerate() {
            for mode in if dr == 0 { &model.x } else { &model.y } {
                let w = TAU * mode.freq_hz;
                omega.push(w);
                zeta.push(mode.damping_ratio);
                gain.push(1.0 / (mode.modal_mass * w));
                dir.push(dr);
                qcol.push(c);
            }
        }
        let n = omega.len();
        let d = 2 * n;
        let nq = dirs.len();
        let multi = multi || !milling.has_equal_pitch();
        let tau = milling.tooth_period(speed_rpm);
        let dt = tau / steps as f64;
        let rate = TAU * speed_rpm / 60.0;
        // Equal pitch: one delay of m steps over the tooth period. Otherwise the revolution of N m steps and one
        // delay per distinct pitch angle, τ_j/Δt = pitch_j N m/2π steps (an integer within 1e-9 is taken as one).
        let (m, delays, group) = if multi {
            let m = steps * milling.teeth;
            let mut delays: Vec<Delay> = Vec::new();
            let mut group = Vec::with_capacity(milling.teeth);
            for j in 0..milling.teeth {
                let r = milling.pitch_angle(j) * m as f64 / TAU;
                let near = r.round();
                let (lag, frac) = if (r - near).abs() <= 1e-9 * r {
                    (near as usize, 0.0)
                } else {
                    (r.floor() as usize, r - r.floor())
                };
                if lag < 1 {
                    return Err(StabilityError::InvalidParameter {
                        name: "steps per tooth period",
                        value: steps as f64,
                        requirement: "enough that the narrowest pitch spans at least one step",
                    });
                }
                let delay = Delay { lag, frac };
                group.push(delays.iter().position(|&g| g == delay).unwrap_or_else(|| {
                    delays.push(delay);
                    delays.len() - 1
                }));
            }
            (m, delays, group)
        } else {
            (steps, vec![Delay { lag: steps, frac: 0.0 }], vec![0; milling.teeth])
        };
        let hist = delays.iter().map(|g| g.lag + usize::from(g.frac > 0.0)).max().unwrap_or(m);
        let groups = delays.len();
        let big = d + nq * hist;
        let mut sd = Sd {
            dense_only: false,
            multi,
            milling: milling.clone(),
            rate,
            group,
            dt,
            omega,
            zeta,
            gain,
            dir,
            dirs,
            h: vec![[[0.0; 2]; 2]; m * groups],
            h_total: vec![[[0.0; 2]; 2]; m],
            phi0: vec![0.0; d * d],
            steps: Steps {
                n,
                d,
                nq,
                m,
                hist,
                qcol,
                free: vec![false; m],
                delays,
                active: vec![false; m * groups],
                phis: vec![0.0; m * d * d],
                ra: vec![0.0; m * groups * d * nq],
                rb: vec![0.0; m * groups * d * nq],
            },
            apply: ApplyScratch {
                hist: vec![0.0; (m + hist) * nq],
                y: vec![0.0; d],
                y2: vec![0.0; d],
                qa: vec![0.0; nq],
                qb: vec![0.0; nq],
            },
            krylov: Krylov {
                v: vec![0.0; (KRYLOV_MAX + 1) * big],
                h: vec![0.0; (KRYLOV_MAX + 1) * KRYLOV_MAX],
                w: vec![0.0; big],
                coef: vec![0.0; KRYLOV_MAX + 1],
                hk: vec![0.0; KRYLOV_MAX * KRYLOV_MAX],
                ritz: Vec::with_capacity(KRYLOV_MAX),
                lu: vec![Complex64::new(0.0, 0.0); KRYLOV_MAX * KRYLOV_MAX],
                x: vec![Complex64::new(0.0, 0.0); KRYLOV_MAX],
                accepted: 0,
                hnorm: 0.0,
            },
            a: vec![0.0; d * d],
            phi: vec![0.0; d * d],
            f0: vec![0.0; d * d],
            g: vec![0.0; d * d],
            x: vec![0.0; d * d],
            pw: vec![0.0; d * d],
            t1: vec![0.0; d * d],
            mono: Vec::new(),
            col: vec![0.0; big],
            eig: Vec::with_capacity(big),
        };
        sd.fill_h(0.0);
        // Free steps do not depend on the depth: e^{A0 Δt} once per speed.
        sd.fill_a(0.0, &[[0.0; 2]; 2]);
        sd.exponentials();
        sd.phi0.copy_from_slice(&sd.phi);
        for i in 0..m {
            if sd.steps.free[i] {
                sd.steps.phis[i * d * d..(i + 1) * d * d].copy_from_slice(&sd.phi0);
            }
        }
        Ok(sd)
    }

    /// The step means of `H` per delay group and in total at depth `depth_m` (the depth matters with a helix
    /// only), and which steps are free of the cut.
    fn fill_h(&mut self, depth_m: f64) {
        let (m, groups) = (self.steps.m, self.steps.delays.len());
        let (rate, dt) = (self.rate, self.dt);
        for i in 0..m {
            let (ta, tb) = (rate * dt * i as f64, rate * dt * (i + 1) as f64);
            let scale = 1.0 / (tb - ta);
            let hs = &mut self.h[i * groups..(i + 1) * groups];
            if self.multi {
                hs.iter_mut().for_each(|h| *h = [[0.0; 2]; 2]);
                for j in 0..self.milling.teeth {
                    let t = self.milling.tooth_force_integral(j, ta, tb, depth_m);
                    let h = &mut hs[self.group[j]];
                    for r in 0..2 {
                        for c in 0..2 {
                            h[r][c] += t[r][c] * scale;
                        }
                    }
                }
                let mut total = [[0.0; 2]; 2];
                for h in hs.iter() {
                    for r in 0..2 {
                        for c in 0..2 {
                            total[r][c] += h[r][c];
                        }
                    }
                }
                self.h_total[i] = total;
            } else {
                let mut s = self.milling.force_matrix_integral_at(ta, tb, depth_m);
                s.iter_mut().flatten().for_each(|v| *v *= scale);
                hs[0] = s;
                self.h_total[i] = s;
            }
            for (g, h) in hs.iter().enumerate() {
                self.steps.active[i * groups + g] = !h.iter().flatten().all(|v| *v == 0.0);
            }
            self.steps.free[i] = self.h_total[i].iter().flatten().all(|v| *v == 0.0)
                && !self.steps.active[i * groups..(i + 1) * groups].iter().any(|&a| a);
        }
    }

    /// `A = A0 + a_p C` in the scaled state `(η, η̇/ω)` with the mean force matrix `hm` of a step.
    fn fill_a(&mut self, depth_m: f64, hm: &[[f64; 2]; 2]) {
        let (n, d) = (self.steps.n, self.steps.d);
        self.a.fill(0.0);
        for r in 0..n {
            let (w, z) = (self.omega[r], self.zeta[r]);
            self.a[r * d + n + r] = w;
            self.a[(n + r) * d + r] = -w;
            self.a[(n + r) * d + n + r] = -2.0 * z * w;
            for s in 0..n {
                self.a[(n + r) * d + s] -= depth_m * self.gain[r] * hm[self.dir[r]][self.dir[s]];
            }
        }
    }

    /// `Φ`, `F0` and `G = Δt F1` of `A Δt` into `phi`, `f0`, `g` by a Taylor series on `A Δt/2^s` and squaring.
    fn exponentials(&mut self) {
        let d = self.steps.d;
        let norm = (0..d).map(|c| (0..d).map(|r| self.a[r * d + c].abs()).sum::<f64>()).fold(0.0, f64::max) * self.dt;
        let mut s = 0;
        while norm / f64::from(1u32 << s.min(30)) > 0.5 && s < 60 {
            s += 1;
        }
        let h = self.dt / 2f64.powi(s);
        for (x, a) in self.x.iter_mut().zip(&self.a) {
            *x = a * h;
        }
        // Power term X^k/k! in pw; Φ += pw, F0 += h pw/(k+1), G += h² pw/((k+1)(k+2)).
        identity(&mut self.pw, d);
        identity(&mut self.phi, d);
        self.f0.iter_mut().zip(&self.pw).for_each(|(f, p)| *f = h * p);
        self.g.iter_mut().zip(&self.pw).for_each(|(f, p)| *f = 0.5 * h * h * p);
        for k in 1..40 {
            matmul(&self.x, &self.pw, &mut self.t1, d);
            let inv_k = 1.0 / k as f64;
            let (c0, c1) = (h / (k + 1) as f64, h * h / ((k + 1) * (k + 2)) as f64);
            let mut size = 0.0f64;
            for i in 0..d * d {
                let p = self.t1[i] * inv_k;
                self.pw[i] = p;
                self.phi[i] += p;
                self.f0[i] += c0 * p;
                self.g[i] += c1 * p;
                size = size.max(p.abs());
            }
            if size < 1e-18 {
                break;
            }
        }
        let mut hh = h;
        for _ in 0..s {
            // G ← Φ G + G + h F0 ; F0 ← Φ F0 + F0 ; Φ ← Φ².
            matmul(&self.phi, &self.g, &mut self.t1, d);
            for i in 0..d * d {
                self.g[i] += self.t1[i] + hh * self.f0[i];
            }
            matmul(&self.phi, &self.f0, &mut self.t1, d);
            for i in 0..d * d {
                self.f0[i] += self.t1[i];
            }
            matmul(&self.phi, &self.phi, &mut self.t1, d);
            self.phi.copy_from_slice(&self.t1);
            hh *= 2.0;
        }
    }

    /// The step operators at depth `depth_m` (free steps were set once per speed; with a helix the step means
    /// and the free steps are rebuilt for the depth first).
    fn set_depth(&mut self, depth_m: f64) {
        let (n, d, nq) = (self.steps.n, self.steps.d, self.steps.nq);
        let groups = self.steps.delays.len();
        let inv_dt = 1.0 / self.dt;
        let rebuilt = self.milling.has_helix();
        if rebuilt {
            self.fill_h(depth_m);
        }
        for i in 0..self.steps.m {
            if self.steps.free[i] {
                if rebuilt {
                    self.steps.phis[i * d * d..(i + 1) * d * d].copy_from_slice(&self.phi0);
                }
                continue;
            }
            let hm = self.h_total[i];
            self.fill_a(depth_m, &hm);
            self.exponentials();
            self.steps.phis[i * d * d..(i + 1) * d * d].copy_from_slice(&self.phi);
            for g in 0..groups {
                let at = i * groups + g;
                if !self.steps.active[at] {
                    continue;
                }
                let hg = self.h[at];
                // B (d × nq): rows n + r, column c: a_p H_g[dir r][dirs c]/(m_r ω_r); Ra = (F0 − F1) B, Rb = F1 B.
                let (ra, rb) = (&mut self.steps.ra[at * d * nq..(at + 1) * d * nq], &mut self.steps.rb[at * d * nq..]);
                for row in 0..d {
                    for c in 0..nq {
                        let (mut sa, mut sb) = (0.0, 0.0);
                        for r in 0..n {
                            let b = depth_m * self.gain[r] * hg[self.dir[r]][self.dirs[c]];
                            let (f0, f1) = (self.f0[row * d + n + r], self.g[row * d + n + r] * inv_dt);
                            sa += (f0 - f1) * b;
                            sb += f1 * b;
                        }
                        ra[row * nq + c] = sa;
                        rb[row * nq + c] = sb;
                    }
                }
            }
        }
    }

    /// Dominant monodromy eigenvalue `(re, im)` at the current depth: Arnoldi iteration on the step operator
    /// (the monodromy spectrum of a delay equation clusters at zero, so the outermost multipliers converge within
    /// a few dozen vectors), accepted when the dominant Ritz pair's residual is below [`RITZ_TOLERANCE`];
    /// otherwise, and for small matrices, the dense QR eigen-solve of the formed matrix.
    fn dominant(&mut self, depth_m: f64, speed_rpm: f64) -> Result<(f64, f64), StabilityError> {
        let big = self.steps.size();
        if big > DENSE_MAX
            && !self.dense_only
            && let Some(mu) = self.arnoldi(big)
        {
            return Ok(mu);
        }
        self.mono.resize(big * big, 0.0);
        for j in 0..big {
            self.col.fill(0.0);
            self.col[j] = 1.0;
            self.steps.apply(&self.col, &mut self.krylov.w, &mut self.apply);
            for (r, v) in self.krylov.w.iter().enumerate() {
                self.mono[r * big + j] = *v;
            }
        }
        if eigenvalues(&mut self.mono, big, &mut self.eig).is_none() {
            return Err(StabilityError::NoConvergence { size: big, speed_rpm, depth_m });
        }
        Ok(largest(&self.eig))
    }

    fn arnoldi(&mut self, big: usize) -> Option<(f64, f64)> {
        let kmax = KRYLOV_MAX.min(big - 1);
        let Krylov { v, h, w, coef, hk, ritz, lu, x, accepted, hnorm: accepted_hnorm } = &mut self.krylov;
        *accepted = 0;
        h.fill(0.0);
        // A fixed, generic start vector (no zero components, not aligned with any structure).
        for (i, e) in v[..big].iter_mut().enumerate() {
            *e = 1.0 + 0.5 * ((i as f64) * 0.754_877_666).fract();
        }
        let norm = v[..big].iter().map(|e| e * e).sum::<f64>().sqrt();
        v[..big].iter_mut().for_each(|e| *e /= norm);
        let mut hnorm = 0.0f64;
        for j in 0..kmax {
            self.steps.apply(&v[j * big..(j + 1) * big], w, &mut self.apply);
            // Classical Gram–Schmidt, twice.
            for _ in 0..2 {
                for (i, c) in coef[..=j].iter_mut().enumerate() {
                    *c = v[i * big..(i + 1) * big].iter().zip(w.iter()).map(|(a, b)| a * b).sum();
                }
                for (i, c) in coef[..=j].iter().enumerate() {
                    h[i * KRYLOV_MAX + j] += c;
                    for (wv, vv) in w.iter_mut().zip(&v[i * big..(i + 1) * big]) {
                        *wv -= c * vv;
                    }
                }
            }
            let beta = w.iter().map(|e| e * e).sum::<f64>().sqrt();
            h[(j + 1) * KRYLOV_MAX + j] = beta;
            hnorm = hnorm.max((0..=j + 1).map(|i| h[i * KRYLOV_MAX + j].abs()).sum());
            let k = j + 1;
            let breakdown = beta <= 1e-14 * hnorm;
            if breakdown || KRYLOV_CHECKS.contains(&k) || k == kmax {
                for r in 0..k {
                    hk[r * k..(r + 1) * k].copy_from_slice(&h[r * KRYLOV_MAX..r * KRYLOV_MAX + k]);
                }
                hessenberg_eigenvalues(&mut hk[..k * k], k, ritz)?;
                let (re, im) = largest(ritz);
                if breakdown {
                    *accepted = k;
                    *accepted_hnorm = hnorm;
                    return Some((re, im));
                }
                let theta = Complex64::new(re, im);
                let residual = beta * ritz_last_component(h, k, theta, hnorm, lu, x);
                if residual <= RITZ_TOLERANCE * theta.norm() {
                    *accepted = k;
                    *accepted_hnorm = hnorm;
                    return Some((re, im));
                }
            }
            if breakdown {
                return None;
            }
            for (o, e) in v[(j + 1) * big..(j + 2) * big].iter_mut().zip(w.iter()) {
                *o = e / beta;
            }
        }
        None
    }

    /// Builds the step operators at depth `depth_m` and returns the dominant multiplier.
    fn point(&mut self, depth_m: f64, speed_rpm: f64) -> Result<SdPoint, StabilityError> {
        self.set_depth(depth_m);
        let (re, im) = self.dominant(depth_m, speed_rpm)?;
        let multiplier = Complex64::new(re, im.abs());
        let kind = if im != 0.0 {
            Bifurcation::Hopf
        } else if re < 0.0 {
            Bifurcation::Flip
        } else {
            Bifurcation::Fold
        };
        Ok(SdPoint { spectral_radius: multiplier.norm(), multiplier, kind })
    }

    /// The chatter frequency of the multiplier `mu` of the step operators at the current depth, Hz.
    ///
    /// The multiplier fixes the chatter frequency only modulo the tooth frequency: the Floquet solution is
    /// `q(t) = e^{λt} p(t)` with `e^{λτ} = μ` and `p` τ-periodic, so it holds the frequencies
    /// `arg μ/(2πτ) + k/τ` (and their negatives) at once, with the amplitudes of the Fourier series of `p`. The
    /// one with the largest amplitude is what the tool does, what a time-domain simulation finds and what the
    /// zero-order approximation predicts (its `ω_c`, Altintas & Budak 1995). The solution over one period comes
    /// from the step recurrence with the delayed positions `q_{i−m} = q_i/μ` (an eigenvector `z` of the
    /// monodromy matrix has `M z = μ z`): on each step `(I − Rb_i T/μ) y_{i+1} = (Φ_i + Ra_i T/μ) y_i`, so
    /// `y_0` is the null vector of `P(μ) − μ I` with `P(μ)` the product of those step maps (found by inverse
    /// iteration). `p_i = q_i μ^{−i/m}` is then transformed over the `m` steps; the x and y amplitudes of each
    /// harmonic are added, as `|A| = |A_x| + |A_y|` of §6.4 adds the spectra of a cut. `None` if the solve
    /// breaks down.
    fn chatter_frequency(&self, mu: Complex64) -> Option<f64> {
        let (n, d, nq, m) = (self.steps.n, self.steps.d, self.steps.nq, self.steps.m);
        if !(mu.norm() > 0.0 && mu.is_finite()) {
            return None;
        }
        let zero = Complex64::new(0.0, 0.0);
        let inv_mu = 1.0 / mu;
        // Step maps P_i (d × d, row-major), and their product P = P_{m−1} ⋯ P_0.
        let mut maps = vec![zero; m * d * d];
        let mut product = vec![zero; d * d];
        for i in 0..d {
            product[i * d + i] = Complex64::new(1.0, 0.0);
        }
        let mut lhs = vec![zero; d * d];
        let mut rhs = vec![zero; d * d];
        let mut next = vec![zero; d * d];
        for i in 0..m {
            let phi = &self.steps.phis[i * d * d..(i + 1) * d * d];
            for (r, c) in rhs.iter_mut().zip(phi) {
                *r = Complex64::new(*c, 0.0);
            }
            lhs.fill(zero);
            for r in 0..d {
                lhs[r * d + r] = Complex64::new(1.0, 0.0);
            }
            if !self.steps.free[i] {
                let (ra, rb) =
                    (&self.steps.ra[i * d * nq..(i + 1) * d * nq], &self.steps.rb[i * d * nq..(i + 1) * d * nq]);
                // R T: column r of T is the unit vector of mode r's direction (r < n), zero for velocities.
                for row in 0..d {
                    for r in 0..n {
                        let c = self.steps.qcol[r];
                        rhs[row * d + r] += ra[row * nq + c] * inv_mu;
                        lhs[row * d + r] -= rb[row * nq + c] * inv_mu;
                    }
                }
            }
            let map = &mut maps[i * d * d..(i + 1) * d * d];
            map.copy_from_slice(&rhs);
            solve_in_place(&mut lhs, map, d)?;
            cmatmul(map, &product, &mut next, d);
            std::mem::swap(&mut product, &mut next);
        }
        // y_0: the null vector of P − μ I, by two steps of inverse iteration.
        for r in 0..d {
            product[r * d + r] -= mu;
        }
        let scale = product.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let mut y = vec![Complex64::new(1.0, 0.0); d];
        for _ in 0..2 {
            let mut a = product.clone();
            let mut b = y.clone();
            solve_regularised(&mut a, &mut b, d, scale)?;
            let norm = b.iter().map(|v| v.norm_sqr()).sum::<f64>().sqrt();
            if !(norm.is_finite() && norm > 0.0) {
                return None;
            }
            y = b.into_iter().map(|v| v / norm).collect();
        }
        // Positions over one period, the e^{λt} growth taken out: p_i = q_i μ^{−i/m}.
        let step = (-mu.ln() / m as f64).exp();
        let mut growth = Complex64::new(1.0, 0.0);
        let mut p = vec![zero; m * nq];
        let mut y_next = vec![zero; d];
        for i in 0..m {
            for r in 0..n {
                p[i * nq + self.steps.qcol[r]] += y[r] * growth;
            }
            let map = &maps[i * d * d..(i + 1) * d * d];
            for (row, o) in y_next.iter_mut().enumerate() {
                *o = map[row * d..(row + 1) * d].iter().zip(&y).map(|(a, b)| a * b).sum();
            }
            std::mem::swap(&mut y, &mut y_next);
            growth *= step;
        }
        // Harmonic k of p (k from −m/2 to m/2) is at arg μ/(2πτ) + k/τ.
        let tau = self.dt * m as f64;
        let base = mu.arg() / (TAU * tau);
        let mut best = (f64::NEG_INFINITY, 0.0);
        for k in 0..m {
            let signed = if k <= m / 2 { k as f64 } else { k as f64 - m as f64 };
            let w = Complex64::from_polar(1.0, -TAU * k as f64 / m as f64);
            let mut amplitude = 0.0;
            for c in 0..nq {
                let mut acc = zero;
                let mut rot = Complex64::new(1.0, 0.0);
                for i in 0..m {
                    acc += p[i * nq + c] * rot;
                    rot *= w;
                }
                amplitude += acc.norm();
            }
            if amplitude > best.0 {
                best = (amplitude, (base + signed / tau).abs());
            }
        }
        best.0.is_finite().then_some(best.1)
    }

    /// The dominant eigenpair `(μ, z)` of the monodromy matrix at the current depth: the Ritz pair of the Arnoldi
    /// iteration, or for small matrices (and when it does not converge, up to [`DENSE_VECTOR_MAX`]) `μ` from the
    /// dense eigen-solve and `z` by inverse iteration on the formed matrix. `None` if neither gives one.
    fn eigenpair(&mut self) -> Option<(Complex64, Vec<Complex64>)> {
        let big = self.steps.size();
        let zero = Complex64::new(0.0, 0.0);
        if big > DENSE_MAX
            && let Some((re, im)) = self.arnoldi(big)
        {
            let k = self.krylov.accepted;
            let theta = Complex64::new(re, im);
            let Krylov { v, h, lu, x, hnorm, .. } = &mut self.krylov;
            ritz_last_component(h, k, theta, *hnorm, lu, x);
            let mut z = vec![zero; big];
            for (i, xi) in x[..k].iter().enumerate() {
                for (o, e) in z.iter_mut().zip(&v[i * big..(i + 1) * big]) {
                    *o += xi * e;
                }
            }
            return Some((theta, z));
        }
        if big > DENSE_VECTOR_MAX {
            return None;
        }
        self.mono.resize(big * big, 0.0);
        for j in 0..big {
            self.col.fill(0.0);
            self.col[j] = 1.0;
            self.steps.apply(&self.col, &mut self.krylov.w, &mut self.apply);
            for (r, v) in self.krylov.w.iter().enumerate() {
                self.mono[r * big + j] = *v;
            }
        }
        let formed: Vec<Complex64> = self.mono.iter().map(|&v| Complex64::new(v, 0.0)).collect();
        eigenvalues(&mut self.mono, big, &mut self.eig)?;
        let (re, im) = largest(&self.eig);
        let mu = Complex64::new(re, im);
        let scale = formed.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let mut z = vec![Complex64::new(1.0, 0.0); big];
        for _ in 0..2 {
            let mut a = formed.clone();
            for r in 0..big {
                a[r * big + r] -= mu;
            }
            solve_regularised(&mut a, &mut z, big, scale)?;
            let norm = z.iter().map(|v| v.norm_sqr()).sum::<f64>().sqrt();
            if !(norm.is_finite() && norm > 0.0) {
                return None;
            }
            z.iter_mut().for_each(|v| *v /= norm);
        }
        Some((mu, z))
    }

    /// The chatter frequency at the current depth for the revolution-periodic (multi-delay) equation, Hz: as
    /// [`Sd::chatter_frequency`] but from the monodromy eigenvector, which holds the history over the longest
    /// delay; one revolution is stepped from it, the growth `μ^{i/m}` taken out, and of the harmonics
    /// `arg μ/(2πT) + k/T` (`T` the revolution) the one with the largest x plus y amplitude is returned. `None`
    /// if no eigenvector is found.
    fn chatter_frequency_multi(&mut self) -> Option<f64> {
        let (mu, z) = self.eigenpair()?;
        if !(mu.norm() > 0.0 && mu.is_finite()) {
            return None;
        }
        let (nq, m, l) = (self.steps.nq, self.steps.m, self.steps.hist);
        let big = self.steps.size();
        let zero = Complex64::new(0.0, 0.0);
        let mut q = vec![zero; m * nq];
        let mut part = vec![0.0; big];
        let mut out = vec![0.0; big];
        for imaginary in [false, true] {
            for (p, v) in part.iter_mut().zip(&z) {
                *p = if imaginary { v.im } else { v.re };
            }
            self.steps.apply(&part, &mut out, &mut self.apply);
            let unit = if imaginary { Complex64::new(0.0, 1.0) } else { Complex64::new(1.0, 0.0) };
            for (o, h) in q.iter_mut().zip(&self.apply.hist[l * nq..(l + m) * nq]) {
                *o += unit * h;
            }
        }
        let step = (-mu.ln() / m as f64).exp();
        let mut growth = Complex64::new(1.0, 0.0);
        for i in 0..m {
            for c in 0..nq {
                q[i * nq + c] *= growth;
            }
            growth *= step;
        }
        let fft = rustfft::FftPlanner::new().plan_fft_forward(m);
        let mut amplitude = vec![0.0; m];
        let mut buf = vec![zero; m];
        for c in 0..nq {
            for i in 0..m {
                buf[i] = q[i * nq + c];
            }
            fft.process(&mut buf);
            for (a, b) in amplitude.iter_mut().zip(&buf) {
                *a += b.norm();
            }
        }
        let period = self.dt * m as f64;
        let base = mu.arg() / (TAU * period);
        let (k, best) =
            amplitude.iter().enumerate().fold((0, f64::NEG_INFINITY), |b, (k, &a)| if a > b.1 { (k, a) } else { b });
        let signed = if k <= m / 2 { k as f64 } else { k as f64 - m as f64 };
        best.is_finite().then_some((base + signed / period).abs())
    }
}

/// Solves `A X = B` in place for `X` (`A` d × d, `B` d × d, row-major) by Gaussian elimination with partial
/// pivoting; `None` if `A` is singular.
fn solve_in_place(a: &mut [Complex64], b: &mut [Complex64], d: usize) -> Option<()> {
    for c in 0..d {
        let pivot = (c..d).max_by(|&i, &j| a[i * d + c].norm().total_cmp(&a[j * d + c].norm()))?;
        if a[pivot * d + c].norm() == 0.0 || !a[pivot * d + c].is_finite() {
            return None;
        }
        if pivot != c {
            for j in 0..d {
                a.swap(c * d + j, pivot * d + j);
                b.swap(c * d + j, pivot * d + j);
            }
        }
        let inv = 1.0 / a[c * d + c];
        for r in (c + 1)..d {
            let l = a[r * d + c] * inv;
            if l == Complex64::new(0.0, 0.0) {
                continue;
            }
            for j in c..d {
                let u = a[c * d + j];
                a[r * d + j] -= l * u;
            }
            for j in 0..d {
                let u = b[c * d + j];
                b[r * d + j] -= l * u;
            }
        }
    }
    for c in (0..d).rev() {
        let inv = 1.0 / a[c * d + c];
        for j in 0..d {
            let mut s = b[c * d + j];
            for k in (c + 1)..d {
                s -= a[c * d + k] * b[k * d + j];
            }
            b[c * d + j] = s * inv;
        }
    }
    Some(())
}

/// Solves the nearly singular `A x = b` of inverse iteration (`A` d × d row-major, `b` of length d) in place,
/// pivots smaller than `ε·scale` replaced by that size so the solve returns the null direction, hugely amplified.
fn solve_regularised(a: &mut [Complex64], b: &mut [Complex64], d: usize, scale: f64) -> Option<()> {
    let tiny = f64::EPSILON * scale.max(f64::MIN_POSITIVE);
    for c in 0..d {
        let pivot = (c..d).max_by(|&i, &j| a[i * d + c].norm().total_cmp(&a[j * d + c].norm()))?;
        if pivot != c {
            for j in 0..d {
                a.swap(c * d + j, pivot * d + j);
            }
            b.swap(c, pivot);
        }
        if a[c * d + c].norm() < tiny {
            a[c * d + c] = Complex64::new(tiny, 0.0);
        }
        let inv = 1.0 / a[c * d + c];
        for r in (c + 1)..d {
            let l = a[r * d + c] * inv;
            for j in c..d {
                let u = a[c * d + j];
                a[r * d + j] -= l * u;
            }
            let u = b[c];
            b[r] -= l * u;
        }
    }
    for c in (0..d).rev() {
        let mut s = b[c];
        for k in (c + 1)..d {
            s -= a[c * d + k] * b[k];
        }
        b[c] = s / a[c * d + c];
    }
    b.iter().all(|v| v.is_finite()).then_some(())
}

/// `c = a b` for row-major complex `d × d` matrices.
fn cmatmul(a: &[Complex64], b: &[Complex64], c: &mut [Complex64], d: usize) {
    c.fill(Complex64::new(0.0, 0.0));
    for i in 0..d {
        for k in 0..d {
            let aik = a[i * d + k];
            for j in 0..d {
                c[i * d + j] += aik * b[k * d + j];
            }
        }
    }
}

/// The eigenvalue of largest modulus (the first of equal ones).
fn largest(eig: &[(f64, f64)]) -> (f64, f64) {
    eig.iter().copied().fold((0.0f64, 0.0f64), |b, e| if e.0.hypot(e.1) > b.0.hypot(b.1) { e } else { b })
}

/// `|s_k|/‖s‖` for the eigenvector `s` of the leading `k × k` block of the Hessenberg matrix `h` (row stride
/// [`KRYLOV_MAX`]) at its eigenvalue `θ`, by two steps of inverse iteration; times `h_{k+1,k}` it is the residual
/// norm of the Ritz pair.
fn ritz_last_component(
    h: &[f64],
    k: usize,
    theta: Complex64,
    hnorm: f64,
    lu: &mut [Complex64],
    x: &mut [Complex64],
) -> f64 {
    let tiny = f64::EPSILON * hnorm.max(f64::MIN_POSITIVE);
    for r in 0..k {
        for c in 0..k {
            let e = if c + 1 >= r { h[r * KRYLOV_MAX + c] } else { 0.0 };
            lu[r * k + c] = Complex64::new(e, 0.0) - if r == c { theta } else { Complex64::new(0.0, 0.0) };
        }
    }
    // LU of the Hessenberg matrix with partial pivoting between adjacent rows; the multiplier of row c + 1 is
    // kept in its sub-diagonal slot.
    let mut swapped = [false; KRYLOV_MAX];
    for c in 0..k {
        if c + 1 < k && lu[(c + 1) * k + c].norm() > lu[c * k + c].norm() {
            for j in c..k {
                lu.swap(c * k + j, (c + 1) * k + j);
            }
            swapped[c] = true;
        }
        if lu[c * k + c].norm() < tiny {
            lu[c * k + c] = Complex64::new(tiny, 0.0);
        }
        if c + 1 < k {
            let l = lu[(c + 1) * k + c] / lu[c * k + c];
            for j in (c + 1)..k {
                let u = lu[c * k + j];
                lu[(c + 1) * k + j] -= l * u;
            }
            lu[(c + 1) * k + c] = l;
        }
    }
    x[..k].fill(Complex64::new(1.0, 0.0));
    for _ in 0..2 {
        for c in 0..k.saturating_sub(1) {
            if swapped[c] {
                x.swap(c, c + 1);
            }
            let l = lu[(c + 1) * k + c];
            let xc = x[c];
            x[c + 1] -= l * xc;
        }
        for r in (0..k).rev() {
            let mut s = x[r];
            for j in (r + 1)..k {
                s -= lu[r * k + j] * x[j];
            }
            x[r] = s / lu[r * k + r];
        }
        let norm = x[..k].iter().map(|e| e.norm_sqr()).sum::<f64>().sqrt();
        if !(norm.is_finite() && norm > 0.0) {
            return f64::INFINITY;
        }
        x[..k].iter_mut().for_each(|e| *e /= norm);
    }
    x[k - 1].norm()
}

fn identity(a: &mut [f64], d: usize) {
    a.fill(0.0);
    for i in 0..d {
        a[i * d + i] = 1.0;
    }
}

/// `c = a b` for row-major `d × d` matrices (unrolled for the common small orders).
fn matmul(a: &[f64], b: &[f64], c: &mut [f64], d: usize) {
    match d {
        2 => matmul_n::<2>(a, b, c),
        4 => matmul_n::<4>(a, b, c),
        6 => matmul_n::<6>(a, b, c),
        8 => matmul_n::<8>(a, b, c),
        _ => {
            c.fill(0.0);
            for i in 0..d {
                for k in 0..d {
                    let aik = a[i * d + k];
                    for j in 0..d {
                        c[i * d + j] += aik * b[k * d + j];
                    }
                }
            }
        }
    }
}

fn matmul_n<const D: usize>(a: &[f64], b: &[f64], c: &mut [f64]) {
    let (a, b, c) = (&a[..D * D], &b[..D * D], &mut c[..D * D]);
    for i in 0..D {
        let mut row = [0.0; D];
        for k in 0..D {
            let aik = a[i * D + k];
            for j in 0..D {
                row[j] += aik * b[k * D + j];
            }
        }
        c[i * D..(i + 1) * D].copy_from_slice(&row);
    }
}

fn check_depth(depth_m: f64) -> Result<(), StabilityError> {
    if depth_m.is_finite() && depth_m >= 0.0 {
        Ok(())
    } else {
        Err(StabilityError::InvalidParameter { name: "axial depth", value: depth_m, requirement: "finite and ≥ 0 m" })
    }
}

/// Spectral radius of the monodromy matrix (and its dominant multiplier) at `speed_rpm`, `depth_m`.
pub fn sd_spectral_radius(
    model: &ModalModel,
    milling: &Milling,
    speed_rpm: f64,
    depth_m: f64,
    options: &SdOptions,
) -> Result<SdPoint, StabilityError> {
    check_depth(depth_m)?;
    let m = sd_steps(model, milling, speed_rpm, options.steps)?;
    Sd::new(model, milling, speed_rpm, m, false)?.point(depth_m, speed_rpm)
}

/// [`sd_spectral_radius`] by the dense eigen-solve of the formed monodromy matrix only.
#[cfg(test)]
pub(crate) fn sd_spectral_radius_dense(
    model: &ModalModel,
    milling: &Milling,
    speed_rpm: f64,
    depth_m: f64,
    options: &SdOptions,
) -> Result<SdPoint, StabilityError> {
    let mut sd = Sd::new(model, milling, speed_rpm, sd_steps(model, milling, speed_rpm, options.steps)?, false)?;
    sd.dense_only = true;
    sd.point(depth_m, speed_rpm)
}

/// Spectral radii on `speeds_rpm × depths_m`, in parallel over speeds (each speed's row is computed by one
/// thread, so the numbers do not depend on the thread count).
pub fn sd_stability_map(
    model: &ModalModel,
    milling: &Milling,
    speeds_rpm: &[f64],
    depths_m: &[f64],
    options: &SdOptions,
) -> Result<StabilityMap, StabilityError> {
    for &b in depths_m {
        check_depth(b)?;
    }
    let rows: Vec<(usize, Vec<f64>)> = speeds_rpm
        .par_iter()
        .map(|&speed| {
            let m = sd_steps(model, milling, speed, options.steps)?;
            let mut sd = Sd::new(model, milling, speed, m, false)?;
            let row: Result<Vec<f64>, _> =
                depths_m.iter().map(|&b| sd.point(b, speed).map(|p| p.spectral_radius)).collect();
            row.map(|r| (m, r))
        })
        .collect::<Result<_, _>>()?;
    Ok(StabilityMap {
        speeds_rpm: speeds_rpm.to_vec(),
        depths_m: depths_m.to_vec(),
        steps: rows.iter().map(|r| r.0).collect(),
        spectral_radius: rows.into_iter().flat_map(|r| r.1).collect(),
    })
}

/// Limiting depth at one speed: the depths `max/scan … max` are scanned upwards; the first unstable one and the
/// stable one below it are bisected to `depth_tolerance_m`. The lowest loss of stability is returned; at low
/// immersion the stable set in depth can be several intervals (stability returns above a flip lobe), which
/// [`DepthLimit::restabilises`] reports for the scanned depths (use [`sd_stability_map`] for the full picture).
///
/// With unequal pitch the multiplier is that of the revolution map (its Hopf/flip/fold kind too), and the
/// chatter frequency comes from the Floquet solution over the revolution.
pub fn sd_depth_limit(
    model: &ModalModel,
    milling: &Milling,
    speed_rpm: f64,
    max_depth_m: f64,
    options: &SdOptions,
) -> Result<DepthLimit, StabilityError> {
    depth_limit(model, milling, speed_rpm, max_depth_m, options, false)
}

/// [`sd_depth_limit`] through the revolution-periodic multi-delay discretization even for equal pitch (to check
/// it against the single-delay one).
#[cfg(test)]
pub(crate) fn sd_depth_limit_multi_delay(
    model: &ModalModel,
    milling: &Milling,
    speed_rpm: f64,
    max_depth_m: f64,
    options: &SdOptions,
) -> Result<DepthLimit, StabilityError> {
    depth_limit(model, milling, speed_rpm, max_depth_m, options, true)
}

fn depth_limit(
    model: &ModalModel,
    milling: &Milling,
    speed_rpm: f64,
    max_depth_m: f64,
    options: &SdOptions,
    multi: bool,
) -> Result<DepthLimit, StabilityError> {
    if !(max_depth_m.is_finite() && max_depth_m > 0.0) {
        return Err(StabilityError::InvalidParameter {
            name: "maximum depth",
            value: max_depth_m,
            requirement: "finite and > 0 m",
        });
    }
    if options.scan_points == 0 || options.depth_tolerance_m.is_nan() || options.depth_tolerance_m <= 0.0 {
        return Err(StabilityError::InvalidParameter {
            name: "scan points / depth tolerance",
            value: options.depth_tolerance_m,
            requirement: "at least one scan point and a tolerance > 0 m",
        });
    }
    let steps = sd_steps(model, milling, speed_rpm, options.steps)?;
    let mut sd = Sd::new(model, milling, speed_rpm, steps, multi)?;
    let scan = options.scan_points;
    let mut first = None;
    for i in 1..=scan {
        let b = max_depth_m * i as f64 / scan as f64;
        let p = sd.point(b, speed_rpm)?;
        if p.spectral_radius >= 1.0 {
            first = Some((i, b, p));
            break;
        }
    }
    let Some((i_unstable, mut hi, mut p_hi)) = first else {
        return Ok(DepthLimit {
            speed_rpm,
            depth_m: f64::INFINITY,
            multiplier: Complex64::new(0.0, 0.0),
            kind: None,
            chatter_hz: 0.0,
            restabilises: false,
            steps,
        });
    };
    let mut lo = max_depth_m * (i_unstable - 1) as f64 / scan as f64;
    while hi - lo > options.depth_tolerance_m {
        let mid = 0.5 * (lo + hi);
        let p = sd.point(mid, speed_rpm)?;
        if p.spectral_radius >= 1.0 {
            hi = mid;
            p_hi = p;
        } else {
            lo = mid;
        }
    }
    let mut restabilises = false;
    for i in (i_unstable + 1)..=scan {
        if sd.point(max_depth_m * i as f64 / scan as f64, speed_rpm)?.spectral_radius < 1.0 {
            restabilises = true;
            break;
        }
    }
    sd.set_depth(hi);
    let chatter_hz = if sd.multi {
        let revolution = 60.0 / speed_rpm;
        sd.chatter_frequency_multi().unwrap_or(p_hi.multiplier.arg().abs() / (TAU * revolution))
    } else {
        let tau = milling.tooth_period(speed_rpm);
        sd.chatter_frequency(p_hi.multiplier).unwrap_or(p_hi.multiplier.arg().abs() / (TAU * tau))
    };
    Ok(DepthLimit {
        speed_rpm,
        depth_m: 0.5 * (lo + hi),
        multiplier: p_hi.multiplier,
        kind: Some(p_hi.kind),
        chatter_hz,
        restabilises,
        steps,
    })
}

/// [`sd_depth_limit`] at every speed, in parallel over speeds (thread-count independent).
pub fn sd_depth_limits(
    model: &ModalModel,
    milling: &Milling,
    speeds_rpm: &[f64],
    max_depth_m: f64,
    options: &SdOptions,
) -> Result<Vec<DepthLimit>, StabilityError> {
    speeds_rpm.par_iter().map(|&s| sd_depth_limit(model, milling, s, max_depth_m, options)).collect()
}
