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
//! below one. Modal velocities are scaled by `1/ω_r` so that the matrices are balanced.

use super::linalg::eigenvalues;
use super::zoa::ToolPointFrf;
use super::{Milling, StabilityError};
use num_complex::Complex64;
use rayon::prelude::*;
use std::f64::consts::TAU;

/// One mode of a tool-point direction: `Φ(ω) = 1/(m (ω_n² − ω² + 2iζω_nω))`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode {
    /// Natural frequency, Hz.
    pub freq_hz: f64,
    /// Viscous damping ratio.
    pub damping_ratio: f64,
    /// Modal mass, kg.
    pub modal_mass_kg: f64,
}

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
                } else if !(m.modal_mass_kg.is_finite() && m.modal_mass_kg > 0.0) {
                    Some(format!("modal mass {} kg must be finite and > 0", m.modal_mass_kg))
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
            modes
                .iter()
                .map(|m| {
                    let wn = TAU * m.freq_hz;
                    Complex64::new(
                        m.modal_mass_kg * (wn * wn - w * w),
                        m.modal_mass_kg * 2.0 * m.damping_ratio * wn * w,
                    )
                    .inv()
                })
                .sum::<Complex64>()
        };
        ToolPointFrf::new(
            freqs_hz.to_vec(),
            freqs_hz.iter().map(|&f| sum(&self.x, f)).collect(),
            freqs_hz.iter().map(|&f| sum(&self.y, f)).collect(),
        )
    }
}

/// Options of the semi-discretization.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SdOptions {
    /// Steps per tooth period `m` (≥ 2).
    pub steps: usize,
    /// Depths scanned from `max/scan` to `max` before bisection in [`sd_depth_limit`].
    pub scan_points: usize,
    /// Bisection stops when the bracket is narrower than this, m.
    pub depth_tolerance_m: f64,
}

impl Default for SdOptions {
    fn default() -> Self {
        SdOptions { steps: 40, scan_points: 40, depth_tolerance_m: 1e-7 }
    }
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
    /// True if a larger scanned depth (≤ the maximum) is stable again: the stable depths at this speed are not
    /// one interval, and `depth_m` is the lower end of the first unstable one.
    pub restabilises: bool,
}

/// Scratch and per-speed data of one semi-discretization.
struct Sd {
    n: usize,
    d: usize,
    nq: usize,
    m: usize,
    dt: f64,
    /// Per mode: `ω_r`, `ζ_r`, `1/(m_r ω_r)`, direction (0 x, 1 y), active-direction column.
    omega: Vec<f64>,
    zeta: Vec<f64>,
    gain: Vec<f64>,
    dir: Vec<usize>,
    qcol: Vec<usize>,
    dirs: Vec<usize>,
    /// Mean `H` per step.
    h: Vec<[[f64; 2]; 2]>,
    // Scratch.
    a: Vec<f64>,
    phi: Vec<f64>,
    f0: Vec<f64>,
    g: Vec<f64>,
    x: Vec<f64>,
    pw: Vec<f64>,
    t1: Vec<f64>,
    ys: Vec<f64>,
    mono: Vec<f64>,
    eig: Vec<(f64, f64)>,
}

impl Sd {
    fn new(model: &ModalModel, milling: &Milling, speed_rpm: f64, steps: usize) -> Result<Self, StabilityError> {
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
                gain.push(1.0 / (mode.modal_mass_kg * w));
                dir.push(dr);
                qcol.push(c);
            }
        }
        let n = omega.len();
        let d = 2 * n;
        let nq = dirs.len();
        let tau = milling.tooth_period(speed_rpm);
        let dt = tau / steps as f64;
        let rate = TAU * speed_rpm / 60.0;
        let h = (0..steps)
            .map(|i| {
                let (ta, tb) = (rate * dt * i as f64, rate * dt * (i + 1) as f64);
                let mut s = milling.force_matrix_integral(ta, tb);
                let scale = 1.0 / (tb - ta);
                s.iter_mut().flatten().for_each(|v| *v *= scale);
                s
            })
            .collect();
        let big = d + nq * steps;
        Ok(Sd {
            n,
            d,
            nq,
            m: steps,
            dt,
            omega,
            zeta,
            gain,
            dir,
            qcol,
            dirs,
            h,
            a: vec![0.0; d * d],
            phi: vec![0.0; d * d],
            f0: vec![0.0; d * d],
            g: vec![0.0; d * d],
            x: vec![0.0; d * d],
            pw: vec![0.0; d * d],
            t1: vec![0.0; d * d],
            ys: vec![0.0; (steps + 1) * d * big],
            mono: vec![0.0; big * big],
            eig: Vec::with_capacity(big),
        })
    }

    /// `Φ`, `F0` and `G = Δt F1` of `A Δt` into `phi`, `f0`, `g` by a Taylor series on `A Δt/2^s` and squaring.
    fn exponentials(&mut self) {
        let d = self.d;
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

    /// Builds the monodromy matrix at depth `depth_m` and returns its dominant multiplier.
    fn point(&mut self, depth_m: f64, speed_rpm: f64) -> Result<SdPoint, StabilityError> {
        let (n, d, nq, m) = (self.n, self.d, self.nq, self.m);
        let big = d + nq * m;
        // Y_0 = [I 0].
        self.ys[..d * big].fill(0.0);
        for r in 0..d {
            self.ys[r * big + r] = 1.0;
        }
        let mut ra = vec![0.0; d * nq];
        let mut rb = vec![0.0; d * nq];
        for i in 0..m {
            let hm = self.h[i];
            // A = A0 + a_p C_i in the scaled state (η, η̇/ω).
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
            self.exponentials();
            // B (d × nq): rows n + r, column c: a_p H[dir r][dirs c]/(m_r ω_r); Ra = (F0 − F1) B, Rb = F1 B.
            let inv_dt = 1.0 / self.dt;
            for row in 0..d {
                for c in 0..nq {
                    let (mut sa, mut sb) = (0.0, 0.0);
                    for r in 0..n {
                        let b = depth_m * self.gain[r] * hm[self.dir[r]][self.dirs[c]];
                        let (f0, f1) = (self.f0[row * d + n + r], self.g[row * d + n + r] * inv_dt);
                        sa += (f0 - f1) * b;
                        sb += f1 * b;
                    }
                    ra[row * nq + c] = sa;
                    rb[row * nq + c] = sb;
                }
            }
            // Y_{i+1} = Φ Y_i + Ra Q(i − m) + Rb Q(i − m + 1).
            let (done, rest) = self.ys.split_at_mut((i + 1) * d * big);
            let yi = &done[i * d * big..];
            let yn = &mut rest[..d * big];
            for row in 0..d {
                let out = &mut yn[row * big..(row + 1) * big];
                out.fill(0.0);
                for k in 0..d {
                    let p = self.phi[row * d + k];
                    if p != 0.0 {
                        for (o, v) in out.iter_mut().zip(&yi[k * big..(k + 1) * big]) {
                            *o += p * v;
                        }
                    }
                }
                // q_{i−m}: slot s = m − i.
                let slot = m - i;
                for c in 0..nq {
                    out[d + (slot - 1) * nq + c] += ra[row * nq + c];
                }
                if i + 1 < m {
                    let slot = m - i - 1;
                    for c in 0..nq {
                        out[d + (slot - 1) * nq + c] += rb[row * nq + c];
                    }
                } else {
                    // q_0 = T y_0: the η columns of the modes of each direction.
                    for r in 0..n {
                        out[r] += rb[row * nq + self.qcol[r]];
                    }
                }
            }
        }
        // Monodromy: rows of y_m, then q_{m−s} = T Y_{m−s} for slots s = 1 … m.
        self.mono.fill(0.0);
        self.mono[..d * big].copy_from_slice(&self.ys[m * d * big..(m + 1) * d * big]);
        for s in 1..=m {
            let y = &self.ys[(m - s) * d * big..(m - s + 1) * d * big];
            for r in 0..n {
                let row = d + (s - 1) * nq + self.qcol[r];
                let src = &y[r * big..(r + 1) * big];
                for (o, v) in self.mono[row * big..(row + 1) * big].iter_mut().zip(src) {
                    *o += v;
                }
            }
        }
        if eigenvalues(&mut self.mono, big, &mut self.eig).is_none() {
            return Err(StabilityError::NoConvergence { size: big, speed_rpm, depth_m });
        }
        let (re, im) =
            self.eig.iter().copied().fold((0.0f64, 0.0f64), |b, e| if e.0.hypot(e.1) > b.0.hypot(b.1) { e } else { b });
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
}

fn identity(a: &mut [f64], d: usize) {
    a.fill(0.0);
    for i in 0..d {
        a[i * d + i] = 1.0;
    }
}

fn matmul(a: &[f64], b: &[f64], c: &mut [f64], d: usize) {
    c.fill(0.0);
    for i in 0..d {
        for k in 0..d {
            let aik = a[i * d + k];
            if aik != 0.0 {
                for j in 0..d {
                    c[i * d + j] += aik * b[k * d + j];
                }
            }
        }
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
    Sd::new(model, milling, speed_rpm, options.steps)?.point(depth_m, speed_rpm)
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
    let rows: Vec<Vec<f64>> = speeds_rpm
        .par_iter()
        .map(|&speed| {
            let mut sd = Sd::new(model, milling, speed, options.steps)?;
            depths_m.iter().map(|&b| sd.point(b, speed).map(|p| p.spectral_radius)).collect()
        })
        .collect::<Result<_, _>>()?;
    Ok(StabilityMap {
        speeds_rpm: speeds_rpm.to_vec(),
        depths_m: depths_m.to_vec(),
        spectral_radius: rows.into_iter().flatten().collect(),
    })
}

/// Limiting depth at one speed: the depths `max/scan … max` are scanned upwards; the first unstable one and the
/// stable one below it are bisected to `depth_tolerance_m`. The lowest loss of stability is returned; at low
/// immersion the stable set in depth can be several intervals (stability returns above a flip lobe), which
/// [`DepthLimit::restabilises`] reports for the scanned depths (use [`sd_stability_map`] for the full picture).
pub fn sd_depth_limit(
    model: &ModalModel,
    milling: &Milling,
    speed_rpm: f64,
    max_depth_m: f64,
    options: &SdOptions,
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
    let mut sd = Sd::new(model, milling, speed_rpm, options.steps)?;
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
            restabilises: false,
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
    Ok(DepthLimit {
        speed_rpm,
        depth_m: 0.5 * (lo + hi),
        multiplier: p_hi.multiplier,
        kind: Some(p_hi.kind),
        restabilises,
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
