//! Spindle error motions by three-probe error separation (dissertation §3.2, Eqs. 3.4–3.15)
//! and displacement from laser-vibrometer velocity (§3.2.1).
//!
//! Probe `i` at angle `φ_i` around the spindle axis (A at 0, B at σ, C at ρ) reads
//! `m_i(θ) = R(θ − φ_i) + x(θ) cos φ_i + y(θ) sin φ_i` (Eq. 3.4 corrected): the artifact's
//! out-of-roundness `R` plus the projection of the error motions `x`, `y`. The weighted sum
//! `M = m_A + a m_B + b m_C` (Eq. 3.5) with `a`, `b` of Eq. 3.8 cancels `x` and `y`, so `M`
//! holds the form alone, filtered harmonic by harmonic with the gain
//! `T_k = 1 + a e^{−ikσ} + b e^{−ikρ} = α_k − iβ_k` (Eq. 3.12 with `α_k = 1 + a cos kσ + b cos kρ`,
//! `β_k = a sin kσ + b sin kρ`). Dividing the FFT of the revolution-averaged `M` by `T_k`
//! recovers `R` (Eq. 3.9), except at harmonics where `α_k² + β_k²` is too small to divide by:
//! those are reported and set to zero, together with 0 and 1 UPR (the mean radius and the
//! centring, inseparable from a probe offset and an eccentric mounting). Then
//! `x = m_A − R` (Eq. 3.13, sign corrected) and `y` follows from probes B and C by least
//! squares on `m_i − R(θ − φ_i) = x cos φ_i + y sin φ_i`, where the shifted form is
//! evaluated exactly from its Fourier series. The rotating-sensitive motion is
//! `r = x cos θ + y sin θ` (Eq. 3.14).
//!
//! Every complete revolution (between two tachometer edges) is mapped onto the angle grid
//! `θ_j = 2πj/N` by linear interpolation in time, the speed being constant within a
//! revolution (§3.1.1). One pass over the revolutions accumulates everything the results
//! need: per-segment sums of the three probes (the synchronous motion and form of each
//! segment and of the whole record are linear in them), and per-angle second moments and
//! extremes of the per-revolution motions (their asynchronous part is the deviation from
//! the mean, where the form cancels). The asynchronous record itself is kept only for its
//! spectrum.

use crate::filter::{FilterError, Sos};
use crate::tach::Revolutions;
use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use std::f64::consts::{SQRT_2, TAU};
use std::sync::Arc;
use thiserror::Error;

/// Probe angles of the dissertation's setup (A, B = σ, C = ρ), degrees.
pub const DEFAULT_ANGLES_DEG: [f64; 3] = [0.0, 99.84, 202.5];

/// The three displacement records, sampled together with the tachometer.
#[derive(Debug, Clone, Copy)]
pub struct ProbeRecords<'a> {
    /// Probe A (at angle 0), m.
    pub a: &'a [f64],
    /// Probe B (at σ), m.
    pub b: &'a [f64],
    /// Probe C (at ρ), m.
    pub c: &'a [f64],
    /// Samples per second, Hz.
    pub sample_rate: f64,
    /// Time of the first sample, s (the time base of the tachometer edges).
    pub t0: f64,
}

/// Options of [`separate`].
#[derive(Debug, Clone, PartialEq)]
pub struct SeparationOptions {
    /// Probe angles A, B, C in rad; A must be 0 (angles count from probe A).
    pub angles: [f64; 3],
    /// Angle grid size N; `None` takes the smallest whole number of samples in any
    /// revolution, rounded down to an even number with no prime factor above 7 (so the
    /// Fourier transforms stay fast; at most a few per cent fewer points). Must be even and
    /// at least 8.
    pub samples_per_rev: Option<usize>,
    /// Number of segments the revolutions are split into for the uncertainty estimate of
    /// §3.2.2.1 (at least 2, at most the number of revolutions).
    pub segments: usize,
    /// Harmonics with `α_k² + β_k²` below this are not divided by (unrecoverable).
    pub gain_tolerance: f64,
    /// Harmonics `2..=required_harmonics` must be recoverable, else the probe angles are
    /// rejected (unless `allow_unrecoverable`).
    pub required_harmonics: usize,
    /// Accept probe angles that leave low harmonics unrecoverable; they are zeroed and listed.
    pub allow_unrecoverable: bool,
    /// Compute the spectrum of the asynchronous motion (keeps the asynchronous record).
    pub async_spectrum: bool,
}

impl Default for SeparationOptions {
    /// The dissertation's probe angles, 10 segments, tolerance 0.01 (noise amplified at most
    /// tenfold), harmonics up to 100 UPR required, asynchronous spectrum on.
    fn default() -> Self {
        SeparationOptions {
            angles: DEFAULT_ANGLES_DEG.map(f64::to_radians),
            samples_per_rev: None,
            segments: 10,
            gain_tolerance: 1e-2,
            required_harmonics: 100,
            allow_unrecoverable: false,
            async_spectrum: true,
        }
    }
}

/// Errors of error separation.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SeparationError {
    /// The probe records differ in length.
    #[error(
        "probe `{probe}` has {len} samples but probe `a` has {expected}: the three probes must be sampled together"
    )]
    LengthMismatch {
        /// The probe that differs.
        probe: &'static str,
        /// Its length.
        len: usize,
        /// Length of probe A.
        expected: usize,
    },
    /// Probes and tachometer were sampled at different rates.
    #[error(
        "the probes are sampled at {probes} Hz but the tachometer at {tach} Hz: decode the tachometer of the same record"
    )]
    SampleRateMismatch {
        /// Probe sample rate, Hz.
        probes: f64,
        /// Tachometer sample rate, Hz.
        tach: f64,
    },
    /// A sample used by the separation is NaN or infinite.
    #[error("probe `{probe}` sample {index} is not finite ({value})")]
    NonFinite {
        /// Probe name.
        probe: &'static str,
        /// Sample index.
        index: usize,
        /// The value.
        value: f64,
    },
    /// Fewer than two complete revolutions.
    #[error(
        "{found} complete revolution(s) in the record; at least 2 are needed to separate synchronous from asynchronous motion"
    )]
    TooFewRevolutions {
        /// Complete revolutions available.
        found: usize,
    },
    /// A revolution lies (partly) outside the probe record.
    #[error(
        "revolution {revolution} ({start} s to {end} s) is not inside the probe record ({record_start} s to {record_end} s): the tachometer belongs to another record"
    )]
    OutsideRecord {
        /// Revolution index.
        revolution: usize,
        /// Its start, s.
        start: f64,
        /// Its end, s.
        end: f64,
        /// First probe sample time, s.
        record_start: f64,
        /// Last probe sample time, s.
        record_end: f64,
    },
    /// Not between 2 and the number of revolutions segments.
    #[error("{segments} segment(s) for {revolutions} revolutions: use between 2 and {revolutions} segments")]
    InvalidSegments {
        /// Requested segments.
        segments: usize,
        /// Complete revolutions.
        revolutions: usize,
    },
    /// The angle grid size is unusable.
    #[error("samples_per_rev = {n}: {reason}")]
    InvalidSamplesPerRev {
        /// Requested or derived grid size.
        n: usize,
        /// Why it cannot be used.
        reason: &'static str,
    },
    /// The probe angles cannot cancel the error motions.
    #[error("probe angles {angles_deg:?} deg: {reason}")]
    DegenerateAngles {
        /// Angles of A, B, C, degrees.
        angles_deg: [f64; 3],
        /// What is wrong.
        reason: &'static str,
    },
    /// Low harmonics cannot be separated with these probe angles.
    #[error(
        "harmonic(s) {harmonics:?} UPR cannot be separated with probes at {angles_deg:?} deg (α_k² + β_k² below {tolerance}): move probe B or C, or allow unrecoverable harmonics to have them zeroed"
    )]
    Unrecoverable {
        /// The unrecoverable harmonics up to the required order.
        harmonics: Vec<usize>,
        /// Angles of A, B, C, degrees.
        angles_deg: [f64; 3],
        /// The gain tolerance.
        tolerance: f64,
    },
    /// An option is out of range.
    #[error("invalid {name} = {value}: {requirement}")]
    InvalidOption {
        /// Option name.
        name: &'static str,
        /// Offending value.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
}

/// `a` and `b` of Eq. 3.8, which cancel `x` and `y` in `M = m_A + a m_B + b m_C` for probes
/// at 0, σ and ρ (rad); `None` when B and C lie on one line through the axis.
pub fn combination_coefficients(sigma: f64, rho: f64) -> Option<(f64, f64)> {
    let d = (sigma - rho).sin();
    if d.abs() < 1e-9 {
        return None;
    }
    Some((rho.sin() / d, -sigma.sin() / d))
}

/// `(α_k, β_k)` of Eq. 3.12 for harmonic `k` with probes at 0, σ, ρ (rad).
pub fn harmonic_gain(k: usize, sigma: f64, rho: f64) -> (f64, f64) {
    let Some((a, b)) = combination_coefficients(sigma, rho) else { return (f64::NAN, f64::NAN) };
    let kf = k as f64;
    (1.0 + a * (kf * sigma).cos() + b * (kf * rho).cos(), a * (kf * sigma).sin() + b * (kf * rho).sin())
}

/// Harmonics `2..=max_k` whose `α_k² + β_k²` is below `tolerance` for probes at 0, σ, ρ.
pub fn unrecoverable_harmonics(sigma: f64, rho: f64, max_k: usize, tolerance: f64) -> Vec<usize> {
    (2..=max_k)
        .filter(|&k| {
            let (al, be) = harmonic_gain(k, sigma, rho);
            let g = al * al + be * be;
            g.is_nan() || g < tolerance
        })
        .collect()
}

/// Peak-to-valley values (max − min), m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeakToValley {
    /// Artifact form error.
    pub form: f64,
    /// Synchronous motion, fixed-sensitive x.
    pub x: f64,
    /// Synchronous motion, fixed-sensitive y.
    pub y: f64,
    /// Synchronous motion, rotating-sensitive (Eq. 3.14).
    pub r: f64,
}

/// Amplitudes per harmonic `k = 0..=N/2` (undulations per revolution), m.
#[derive(Debug, Clone, PartialEq)]
pub struct SyncSpectrum {
    /// Synchronous x.
    pub x: Vec<f64>,
    /// Synchronous y.
    pub y: Vec<f64>,
    /// Synchronous rotating-sensitive r.
    pub r: Vec<f64>,
    /// Form error (zero at 0, 1 UPR and at unrecoverable harmonics).
    pub form: Vec<f64>,
}

/// Single-sided amplitude spectrum of the asynchronous motion in time order.
#[derive(Debug, Clone, PartialEq)]
pub struct AsyncSpectrum {
    /// Line frequencies, Hz (spacing 1 / record duration).
    pub freq_hz: Vec<f64>,
    /// Amplitude of asynchronous x per line, m.
    pub x: Vec<f64>,
    /// Amplitude of asynchronous y per line, m.
    pub y: Vec<f64>,
}

/// Form and synchronous motion of each segment and their spread per angle (§3.2.2.1).
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentStats {
    /// Revolutions in each segment.
    pub revolutions: Vec<usize>,
    /// Form per segment, on the angle grid, m.
    pub form: Vec<Vec<f64>>,
    /// Synchronous x per segment, m.
    pub x: Vec<Vec<f64>>,
    /// Synchronous y per segment, m.
    pub y: Vec<Vec<f64>>,
    /// Mean form over segments per angle, m.
    pub form_mean: Vec<f64>,
    /// Standard deviation of the form over segments per angle, m.
    pub form_sigma: Vec<f64>,
    /// Mean synchronous x over segments per angle, m.
    pub x_mean: Vec<f64>,
    /// Standard deviation of synchronous x over segments per angle, m.
    pub x_sigma: Vec<f64>,
    /// Mean synchronous y over segments per angle, m.
    pub y_mean: Vec<f64>,
    /// Standard deviation of synchronous y over segments per angle, m.
    pub y_sigma: Vec<f64>,
    /// Mean over angles of `form_sigma` (6.3 nm in the dissertation), m.
    pub form_sigma_mean: f64,
    /// Mean over angles of `x_sigma` (63 nm in the dissertation, its measuring direction), m.
    pub x_sigma_mean: f64,
    /// Mean over angles of `y_sigma`, m.
    pub y_sigma_mean: f64,
}

/// Results of [`separate`]: arrays on the angle grid `θ_j = 2πj/N` unless noted.
#[derive(Debug, Clone, PartialEq)]
pub struct Separation {
    /// Grid size N (samples per revolution).
    pub samples_per_rev: usize,
    /// Complete revolutions used.
    pub revolutions: usize,
    /// Mean spindle speed, rpm.
    pub mean_speed_rpm: f64,
    /// `a`, `b` of Eq. 3.8.
    pub coefficients: (f64, f64),
    /// Grid angles θ_j, rad.
    pub angle: Vec<f64>,
    /// Artifact form error R(θ) (Eq. 3.9), m.
    pub form: Vec<f64>,
    /// Fourier coefficients `(A_k, B_k)` of `R = Σ A_k cos kθ + B_k sin kθ`, k = 0..=N/2, m.
    pub form_harmonics: Vec<(f64, f64)>,
    /// Synchronous x (mean over revolutions of `m_A − R`, mean over angle removed), m.
    pub sync_x: Vec<f64>,
    /// Synchronous y, m.
    pub sync_y: Vec<f64>,
    /// Synchronous rotating-sensitive motion `x cos θ + y sin θ` (Eq. 3.14), m.
    pub sync_r: Vec<f64>,
    /// Standard deviation over revolutions of the asynchronous x per angle, m.
    pub async_sigma_x: Vec<f64>,
    /// Same for y, m.
    pub async_sigma_y: Vec<f64>,
    /// Same for r, m.
    pub async_sigma_r: Vec<f64>,
    /// Asynchronous error motion value of x: the largest spread (max − min over
    /// revolutions) at any angle, m.
    pub async_value_x: f64,
    /// Same for y, m.
    pub async_value_y: f64,
    /// Peak-to-valley values.
    pub ptv: PeakToValley,
    /// Synchronous spectra in UPR.
    pub sync_spectrum: SyncSpectrum,
    /// Asynchronous spectrum in Hz, when requested.
    pub async_spectrum: Option<AsyncSpectrum>,
    /// Nyquist limit in UPR, `30·SR/Ω` (Eq. 3.15).
    pub nyquist_upr: f64,
    /// The grid resolves harmonics (up to N/2) above the Nyquist limit of the sampling.
    pub nyquist_exceeded: bool,
    /// Harmonics (2 ≤ k < N/2) not divided by and zeroed in the form, ascending.
    pub unrecoverable: Vec<usize>,
    /// Segment statistics.
    pub segments: SegmentStats,
}

/// Probe geometry: the Eq. 3.8 weights and the least-squares weights for y.
struct Geometry {
    sigma: f64,
    rho: f64,
    a: f64,
    b: f64,
    /// `y = ky·(m_A, m_B, m_C)` minus the form terms (least squares over B and C given x = m_A).
    ky: [f64; 3],
    /// sin σ, sin ρ, `sin σ cos σ + sin ρ cos ρ` and the least-squares denominator `sin²σ + sin²ρ`.
    sb: f64,
    sc: f64,
    s_dot_c: f64,
    d: f64,
}

impl Geometry {
    fn new(angles: [f64; 3]) -> Result<Geometry, SeparationError> {
        let angles_deg = angles.map(f64::to_degrees);
        if angles.iter().any(|a| !a.is_finite()) {
            return Err(SeparationError::DegenerateAngles { angles_deg, reason: "angles must be finite" });
        }
        if angles[0].abs() > 1e-12 {
            return Err(SeparationError::DegenerateAngles {
                angles_deg,
                reason: "probe A must be at 0 (angles count from probe A)",
            });
        }
        let (sigma, rho) = (angles[1], angles[2]);
        let (a, b) = combination_coefficients(sigma, rho).ok_or(SeparationError::DegenerateAngles {
            angles_deg,
            reason: "probes B and C lie on one line through the axis (sin(σ − ρ) = 0), so x and y cannot be cancelled",
        })?;
        let (sb, sc, cb, cc) = (sigma.sin(), rho.sin(), sigma.cos(), rho.cos());
        let d = sb * sb + sc * sc;
        let s_dot_c = sb * cb + sc * cc;
        Ok(Geometry { sigma, rho, a, b, ky: [-s_dot_c / d, sb / d, sc / d], sb, sc, s_dot_c, d })
    }
}

/// `e^{−ikφ}` for k = 0..=kmax by rotation, recomputed exactly every 64 steps.
fn phasors(phi: f64, kmax: usize) -> Vec<Complex64> {
    let rot = Complex64::from_polar(1.0, -phi);
    let mut out = Vec::with_capacity(kmax + 1);
    let mut z = Complex64::new(1.0, 0.0);
    for k in 0..=kmax {
        if k % 64 == 0 {
            z = Complex64::from_polar(1.0, -phi * k as f64);
        }
        out.push(z);
        z *= rot;
    }
    out
}

/// Form and synchronous motion of one set of revolution-averaged probe signals.
struct SetResult {
    form: Vec<f64>,
    /// FFT of the form, k = 0..=N/2.
    form_hat: Vec<Complex64>,
    x: Vec<f64>,
    y: Vec<f64>,
}

/// Revolution-averaged (offset) probe signals A, B, C on the grid.
#[derive(Clone)]
struct Means {
    a: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
}

impl Means {
    fn zeros(n: usize) -> Means {
        Means { a: vec![0.0; n], b: vec![0.0; n], c: vec![0.0; n] }
    }
}

thread_local! {
    /// FFT plans (twiddle tables) are kept per thread for the grid sizes met so far.
    static PLANNER: std::cell::RefCell<FftPlanner<f64>> = std::cell::RefCell::new(FftPlanner::new());
}

/// FFT plans and the per-harmonic factors shared by every averaged set.
struct Spectral {
    n: usize,
    fwd: Arc<dyn Fft<f64>>,
    inv: Arc<dyn Fft<f64>>,
    buf: Vec<Complex64>,
    spec: Vec<Complex64>,
    scratch: Vec<Complex64>,
    /// `1/T_k` where recoverable (2 ≤ k < N/2), else 0; `T_k = 1 + a e^{−ikσ} + b e^{−ikρ}`.
    inv_t: Vec<Complex64>,
    /// Spectrum of the form terms of y per unit form harmonic:
    /// `Ry = [s_B R(θ−σ) + s_C R(θ−ρ) − (s_B c_B + s_C c_C) R(θ)] / D`.
    yk: Vec<Complex64>,
    /// Harmonics 2 ≤ k < N/2 with `|T_k|² < tolerance`.
    unrecoverable: Vec<usize>,
}

impl Spectral {
    fn new(n: usize, geo: &Geometry, tolerance: f64) -> Spectral {
        let (fwd, inv) = PLANNER.with(|p| {
            let mut p = p.borrow_mut();
            (p.plan_fft_forward(n), p.plan_fft_inverse(n))
        });
        let scratch_len = fwd.get_inplace_scratch_len().max(inv.get_inplace_scratch_len());
        let half = n / 2;
        let (es, er) = (phasors(geo.sigma, half), phasors(geo.rho, half));
        let mut inv_t = Vec::with_capacity(half + 1);
        let mut yk = Vec::with_capacity(half + 1);
        let mut unrecoverable = Vec::new();
        for k in 0..=half {
            let t = 1.0 + es[k] * geo.a + er[k] * geo.b;
            let usable = (2..half).contains(&k) && t.norm_sqr() >= tolerance;
            if (2..half).contains(&k) && !usable {
                unrecoverable.push(k);
            }
            inv_t.push(if usable { 1.0 / t } else { Complex64::new(0.0, 0.0) });
            yk.push((es[k] * geo.sb + er[k] * geo.sc - geo.s_dot_c) / geo.d);
        }
        Spectral {
            n,
            fwd,
            inv,
            buf: vec![Complex64::new(0.0, 0.0); n],
            spec: vec![Complex64::new(0.0, 0.0); n],
            scratch: vec![Complex64::new(0.0, 0.0); scratch_len],
            inv_t,
            yk,
            unrecoverable,
        }
    }

    /// Eqs. 3.5–3.13 on one or two sets of averaged probe signals (each offset by a
    /// constant, which only moves the mean that is removed). Two sets share one forward
    /// transform: `M₁ + i M₂`.
    fn solve(&mut self, geo: &Geometry, m1: &Means, m2: Option<&Means>) -> (SetResult, Option<SetResult>) {
        let n = self.n;
        let combined = |m: &Means, j: usize| m.a[j] + geo.a * m.b[j] + geo.b * m.c[j];
        for (j, z) in self.spec.iter_mut().enumerate() {
            *z = Complex64::new(combined(m1, j), m2.map_or(0.0, |m| combined(m, j)));
        }
        self.fwd.process_with_scratch(&mut self.spec, &mut self.scratch);
        let half = n / 2;
        let (mut h1, mut h2) = (Vec::with_capacity(half + 1), Vec::with_capacity(half + 1));
        for k in 0..=half {
            let zk = self.spec[k];
            let zc = self.spec[(n - k) % n].conj();
            h1.push((zk + zc) * 0.5 * self.inv_t[k]);
            h2.push((zk - zc) * Complex64::new(0.0, -0.5) * self.inv_t[k]);
        }
        let first = self.finish(geo, m1, h1);
        let second = m2.map(|m| self.finish(geo, m, h2));
        (first, second)
    }

    /// Form, x and y of one set from its form spectrum (k = 0..=N/2).
    fn finish(&mut self, geo: &Geometry, m: &Means, form_hat: Vec<Complex64>) -> SetResult {
        let n = self.n;
        // R and the form part of y share one inverse transform: R + i·Ry, both real.
        self.buf.fill(Complex64::new(0.0, 0.0));
        let i = Complex64::new(0.0, 1.0);
        for (k, (&r, &yk)) in form_hat.iter().zip(&self.yk).enumerate().take(n / 2).skip(1) {
            let ry = r * yk;
            self.buf[k] = r + i * ry;
            self.buf[n - k] = r.conj() + i * ry.conj();
        }
        self.inv.process_with_scratch(&mut self.buf, &mut self.scratch);
        let scale = 1.0 / n as f64;
        let [ka, kb, kc] = geo.ky;
        let mut form = Vec::with_capacity(n);
        let mut x = Vec::with_capacity(n);
        let mut y = Vec::with_capacity(n);
        for (j, z) in self.buf.iter().enumerate() {
            let r = z.re * scale;
            form.push(r);
            x.push(m.a[j] - r);
            y.push(ka * m.a[j] + kb * m.b[j] + kc * m.c[j] - z.im * scale);
        }
        remove_mean(&mut x);
        remove_mean(&mut y);
        SetResult { form, form_hat, x, y }
    }

    /// Single-sided amplitudes (k = 0..=N/2) of two real signals with one transform.
    fn amplitudes2(&mut self, u: &[f64], v: &[f64]) -> (Vec<f64>, Vec<f64>) {
        for (j, z) in self.buf.iter_mut().enumerate() {
            *z = Complex64::new(u[j], v[j]);
        }
        self.fwd.process_with_scratch(&mut self.buf, &mut self.scratch);
        split_amplitudes(&self.buf)
    }
}

/// Amplitude spectra of the real and imaginary parts of a packed complex signal from its FFT `z`.
fn split_amplitudes(z: &[Complex64]) -> (Vec<f64>, Vec<f64>) {
    let n = z.len();
    let half = n / 2;
    let mut ax = Vec::with_capacity(half + 1);
    let mut ay = Vec::with_capacity(half + 1);
    for k in 0..=half {
        let zk = z[k];
        let zc = z[(n - k) % n].conj();
        let xk = (zk + zc) * 0.5;
        let yk = (zk - zc) * Complex64::new(0.0, -0.5);
        let s = if k == 0 || 2 * k == n { 1.0 } else { 2.0 } / n as f64;
        ax.push(s * xk.norm_sqr().sqrt());
        ay.push(s * yk.norm_sqr().sqrt());
    }
    (ax, ay)
}

fn remove_mean(v: &mut [f64]) {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    v.iter_mut().for_each(|x| *x -= m);
}

fn ptv(v: &[f64]) -> f64 {
    let (lo, hi) = v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| (l.min(x), h.max(x)));
    hi - lo
}

/// The largest even number `≤ m` whose prime factors are 2, 3, 5 and 7 (0 below 2). Such
/// grid sizes transform several times faster than sizes with a large prime factor, and lie
/// within a few per cent of `m`.
fn fft_friendly_floor(m: usize) -> usize {
    let smooth = |mut v: usize| {
        for p in [2, 3, 5, 7] {
            while v.is_multiple_of(p) {
                v /= p;
            }
        }
        v == 1
    };
    (1..=m / 2).rev().map(|h| 2 * h).find(|&v| smooth(v)).unwrap_or(0)
}

/// Mean and sample standard deviation per angle over the rows of `sets`.
fn mean_sigma(sets: &[Vec<f64>]) -> (Vec<f64>, Vec<f64>) {
    let n = sets[0].len();
    let s = sets.len() as f64;
    let mut mean = vec![0.0; n];
    for set in sets {
        mean.iter_mut().zip(set).for_each(|(m, v)| *m += v / s);
    }
    let mut sigma = vec![0.0; n];
    for set in sets {
        sigma.iter_mut().zip(set.iter().zip(&mean)).for_each(|(q, (v, m))| *q += (v - m) * (v - m));
    }
    sigma.iter_mut().for_each(|q| *q = (*q / (s - 1.0)).sqrt());
    (mean, sigma)
}

/// Separates artifact form and spindle error motions from three probe records and the
/// revolutions of their tachometer (Eqs. 3.4–3.15); see the module documentation.
///
/// Samples outside the complete revolutions are not used. A non-finite sample that enters
/// the interpolation is an error naming it. Linear interpolation attenuates harmonic `k` by
/// about `(2πk/n)²/12` for `n` samples per revolution (0.03 % for 44 UPR at 6000 samples).
pub fn separate(
    probes: &ProbeRecords<'_>,
    revs: &Revolutions,
    opts: &SeparationOptions,
) -> Result<Separation, SeparationError> {
    let geo = Geometry::new(opts.angles)?;
    let n = checked_grid(probes, revs, opts)?;
    let n_rev = revs.count();

    // Which harmonics can be divided by.
    let low = unrecoverable_harmonics(geo.sigma, geo.rho, opts.required_harmonics, opts.gain_tolerance);
    if !low.is_empty() && !opts.allow_unrecoverable {
        return Err(SeparationError::Unrecoverable {
            harmonics: low,
            angles_deg: opts.angles.map(f64::to_degrees),
            tolerance: opts.gain_tolerance,
        });
    }
    let mut spec = Spectral::new(n, &geo, opts.gain_tolerance);
    let Pass { mut acc, mean, all, sets } = averaged_pass(probes, revs, opts, n, &geo, &mut spec)?;

    let angle: Vec<f64> = (0..n).map(|j| TAU * j as f64 / n as f64).collect();
    let turn = phasors(-TAU / n as f64, n - 1);
    let (cos_t, sin_t): (Vec<f64>, Vec<f64>) = turn.iter().map(|z| (z.re, z.im)).unzip();
    let sync_r: Vec<f64> = (0..n).map(|j| all.x[j] * cos_t[j] + all.y[j] * sin_t[j]).collect();

    // Asynchronous spread per angle: deviations from the mean, where the form cancels.
    let [ka, kb, kc] = geo.ky;
    let mqy: Vec<f64> = (0..n).map(|j| ka * mean.a[j] + kb * mean.b[j] + kc * mean.c[j]).collect();
    let spread = AsyncSpread::new(&acc, &mean.a, &mqy, &cos_t, &sin_t, n_rev);

    // Spectra.
    let (sx, sy) = spec.amplitudes2(&all.x, &all.y);
    let (sr, _) = spec.amplitudes2(&sync_r, &all.form);
    let scale = 2.0 / n as f64;
    let form_amp: Vec<f64> = all.form_hat.iter().map(|h| scale * h.norm_sqr().sqrt()).collect();
    let form_harmonics: Vec<(f64, f64)> = all.form_hat.iter().map(|h| (scale * h.re, -scale * h.im)).collect();
    let async_spectrum = opts.async_spectrum.then(|| acc.async_spectrum(&mean.a, &mqy, n, n_rev, revs.mean_period()));

    let mean_speed_rpm = revs.mean_speed_rpm();
    let nyquist_upr = 30.0 * probes.sample_rate / mean_speed_rpm;
    Ok(Separation {
        samples_per_rev: n,
        revolutions: n_rev,
        mean_speed_rpm,
        coefficients: (geo.a, geo.b),
        ptv: PeakToValley { form: ptv(&all.form), x: ptv(&all.x), y: ptv(&all.y), r: ptv(&sync_r) },
        angle,
        form: all.form,
        form_harmonics,
        sync_spectrum: SyncSpectrum { x: sx, y: sy, r: sr, form: form_amp },
        sync_x: all.x,
        sync_y: all.y,
        sync_r,
        async_sigma_x: spread.sigma_x,
        async_sigma_y: spread.sigma_y,
        async_sigma_r: spread.sigma_r,
        async_value_x: spread.value_x,
        async_value_y: spread.value_y,
        async_spectrum,
        nyquist_upr,
        nyquist_exceeded: (n / 2) as f64 > nyquist_upr,
        unrecoverable: std::mem::take(&mut spec.unrecoverable),
        segments: sets.stats(),
    })
}

/// Position of time `t` in fractional samples of the probe records.
fn sample_position(probes: &ProbeRecords<'_>, t: f64) -> f64 {
    (t - probes.t0) * probes.sample_rate
}

/// Checks the records, the revolutions and the options against each other and returns the
/// angle grid's size: the option's, or the largest FFT-friendly even size that every
/// revolution's samples fill.
fn checked_grid(
    probes: &ProbeRecords<'_>,
    revs: &Revolutions,
    opts: &SeparationOptions,
) -> Result<usize, SeparationError> {
    if !(opts.gain_tolerance.is_finite() && opts.gain_tolerance >= 0.0) {
        return Err(SeparationError::InvalidOption {
            name: "gain_tolerance",
            value: opts.gain_tolerance,
            requirement: "must be a finite number ≥ 0",
        });
    }
    let len = probes.a.len();
    for (probe, rec) in [("b", probes.b), ("c", probes.c)] {
        if rec.len() != len {
            return Err(SeparationError::LengthMismatch { probe, len: rec.len(), expected: len });
        }
    }
    let fs = probes.sample_rate;
    if !(fs.is_finite() && fs > 0.0) {
        return Err(SeparationError::InvalidOption {
            name: "sample_rate",
            value: fs,
            requirement: "must be positive and finite",
        });
    }
    if (revs.sample_rate() - fs).abs() > 1e-9 * fs {
        return Err(SeparationError::SampleRateMismatch { probes: fs, tach: revs.sample_rate() });
    }
    let n_rev = revs.count();
    if n_rev < 2 {
        return Err(SeparationError::TooFewRevolutions { found: n_rev });
    }
    if opts.segments < 2 || opts.segments > n_rev {
        return Err(SeparationError::InvalidSegments { segments: opts.segments, revolutions: n_rev });
    }
    let edges = revs.edges();
    let record_end = probes.t0 + len.saturating_sub(1) as f64 / fs;
    for r in [0, n_rev - 1] {
        let (p0, p1) = (sample_position(probes, edges[r]), sample_position(probes, edges[r + 1]));
        if p0 < -1e-9 || p1 > len as f64 - 1.0 + 1e-9 || len < 2 {
            return Err(SeparationError::OutsideRecord {
                revolution: r,
                start: edges[r],
                end: edges[r + 1],
                record_start: probes.t0,
                record_end,
            });
        }
    }
    let min_samples = (0..n_rev).map(|r| (revs.period(r) * fs).floor() as usize).min().unwrap_or(0);
    let n = match opts.samples_per_rev {
        Some(n) if n % 2 == 1 => {
            return Err(SeparationError::InvalidSamplesPerRev { n, reason: "must be even" });
        }
        Some(n) => n,
        None => fft_friendly_floor(min_samples),
    };
    if n < 8 {
        return Err(SeparationError::InvalidSamplesPerRev {
            n,
            reason: "at least 8 points per revolution are needed (raise the sample rate or lower the speed)",
        });
    }
    Ok(n)
}

/// What the pass over the records leaves: the per-angle accumulators, the mean over every
/// revolution, its form and motion, and each segment's.
struct Pass {
    acc: Accumulators,
    mean: Means,
    all: SetResult,
    sets: SegmentSets,
}

/// One pass over the records, segment by segment; segments are solved in pairs as they
/// complete, and the whole record (with the last segment when their number is odd) at the end.
fn averaged_pass(
    probes: &ProbeRecords<'_>,
    revs: &Revolutions,
    opts: &SeparationOptions,
    n: usize,
    geo: &Geometry,
    spec: &mut Spectral,
) -> Result<Pass, SeparationError> {
    let n_rev = revs.count();
    let n_seg = opts.segments;
    let edges = revs.edges();
    let pos = |t: f64| sample_position(probes, t);
    let first = pos(edges[0]).max(0.0) as usize;
    let offsets = [probes.a[first], probes.b[first], probes.c[first]];
    let mut acc = Accumulators::new(n, if opts.async_spectrum { n_rev } else { 0 });
    let mut total = Means::zeros(n);
    let mut sets = SegmentSets::with_capacity(n_seg);
    let mut place = Vec::new();
    let mut pending: Option<Means> = None;
    for s in 0..n_seg {
        let (r0, r1) = (s * n_rev / n_seg, (s + 1) * n_rev / n_seg);
        place.clear();
        place.extend((r0..r1).map(|r| {
            let p0 = pos(edges[r]).max(0.0);
            (p0, (pos(edges[r + 1]) - p0) / n as f64)
        }));
        acc.segment(probes, offsets, &place, r0, geo.ky);
        let sums = &acc.seg;
        let inv_count = 1.0 / (r1 - r0) as f64;
        let mut mean = Means::zeros(n);
        for (t, (m, v)) in [
            (&mut total.a, (&mut mean.a, &sums.a)),
            (&mut total.b, (&mut mean.b, &sums.b)),
            (&mut total.c, (&mut mean.c, &sums.c)),
        ] {
            for j in 0..n {
                t[j] += v[j];
                m[j] = v[j] * inv_count;
            }
        }
        sets.revolutions.push(r1 - r0);
        match pending.take() {
            None => pending = Some(mean),
            Some(prev) => {
                let (r_prev, r_this) = spec.solve(geo, &prev, Some(&mean));
                sets.keep(r_prev);
                sets.keep(r_this.expect("second set solved"));
            }
        }
    }

    // A non-finite sample that entered the interpolation has spread into the sums.
    if total.a.iter().chain(&total.b).chain(&total.c).any(|v| !v.is_finite()) {
        let to = (pos(edges[n_rev]).ceil() as usize).min(probes.a.len() - 1);
        return Err(first_non_finite(probes, first, to));
    }

    let nf = n_rev as f64;
    let mean = Means {
        a: total.a.iter().map(|t| t / nf).collect(),
        b: total.b.iter().map(|t| t / nf).collect(),
        c: total.c.iter().map(|t| t / nf).collect(),
    };
    let (all, last) = spec.solve(geo, &mean, pending.as_ref());
    if let Some(res) = last {
        sets.keep(res);
    }
    Ok(Pass { acc, mean, all, sets })
}

/// Each segment's form and synchronous motion, in segment order.
struct SegmentSets {
    revolutions: Vec<usize>,
    form: Vec<Vec<f64>>,
    x: Vec<Vec<f64>>,
    y: Vec<Vec<f64>>,
}

impl SegmentSets {
    fn with_capacity(n: usize) -> Self {
        SegmentSets {
            revolutions: Vec::with_capacity(n),
            form: Vec::with_capacity(n),
            x: Vec::with_capacity(n),
            y: Vec::with_capacity(n),
        }
    }

    fn keep(&mut self, res: SetResult) {
        self.form.push(res.form);
        self.x.push(res.x);
        self.y.push(res.y);
    }

    /// Their mean and spread per angle (§3.2.2.1).
    fn stats(self) -> SegmentStats {
        let (form_mean, form_sigma) = mean_sigma(&self.form);
        let (x_mean, x_sigma) = mean_sigma(&self.x);
        let (y_mean, y_sigma) = mean_sigma(&self.y);
        let avg = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        SegmentStats {
            revolutions: self.revolutions,
            form_sigma_mean: avg(&form_sigma),
            x_sigma_mean: avg(&x_sigma),
            y_sigma_mean: avg(&y_sigma),
            form: self.form,
            x: self.x,
            y: self.y,
            form_mean,
            form_sigma,
            x_mean,
            x_sigma,
            y_mean,
            y_sigma,
        }
    }
}

/// Asynchronous error motion: its standard deviation per angle in x, y and along the
/// rotating sensitive direction, and its value (the widest band of the revolutions), m.
struct AsyncSpread {
    sigma_x: Vec<f64>,
    sigma_y: Vec<f64>,
    sigma_r: Vec<f64>,
    value_x: f64,
    value_y: f64,
}

impl AsyncSpread {
    /// From the accumulated squares and extremes about the mean `mqx = m_A`, `mqy = ky·m`,
    /// where the form cancels.
    fn new(acc: &Accumulators, mqx: &[f64], mqy: &[f64], cos_t: &[f64], sin_t: &[f64], n_rev: usize) -> Self {
        let nf = n_rev as f64;
        let var = |sq: f64, m: f64| ((sq - nf * m * m) / (nf - 1.0)).max(0.0);
        let n = mqx.len();
        let mut sigma_x = Vec::with_capacity(n);
        let mut sigma_y = Vec::with_capacity(n);
        let mut sigma_r = Vec::with_capacity(n);
        for j in 0..n {
            let vx = var(acc.sq_x[j], mqx[j]);
            let vy = var(acc.sq_y[j], mqy[j]);
            let cxy = (acc.sxy[j] - nf * mqx[j] * mqy[j]) / (nf - 1.0);
            let (c, s) = (cos_t[j], sin_t[j]);
            sigma_x.push(vx.sqrt());
            sigma_y.push(vy.sqrt());
            sigma_r.push((c * c * vx + s * s * vy + 2.0 * c * s * cxy).max(0.0).sqrt());
        }
        let widest = |lo: &[f64], hi: &[f64]| lo.iter().zip(hi).map(|(l, h)| h - l).fold(0.0, f64::max);
        AsyncSpread {
            sigma_x,
            sigma_y,
            sigma_r,
            value_x: widest(&acc.min_x, &acc.max_x),
            value_y: widest(&acc.min_y, &acc.max_y),
        }
    }
}

/// Angle-block length of the pass. Revolutions are visited one after the other (long
/// sequential runs over the probe records keep the hardware prefetcher ahead), each in
/// blocks whose interpolated values stay in the L1 cache until they are accumulated.
const BLOCK: usize = 512;

/// Everything accumulated in the pass over the revolutions.
struct Accumulators {
    n: usize,
    /// Sums over the current segment of the offset probe values A, B, C.
    seg: Means,
    /// Per angle: Σ qx², Σ qy², Σ qx·qy with qx = m_A, qy = ky·m (the per-revolution x and
    /// y up to terms that are the same in every revolution).
    sq_x: Vec<f64>,
    sq_y: Vec<f64>,
    sxy: Vec<f64>,
    min_x: Vec<f64>,
    max_x: Vec<f64>,
    min_y: Vec<f64>,
    max_y: Vec<f64>,
    /// qx, qy per revolution in time order (only for the asynchronous spectrum).
    rec_x: Vec<f64>,
    rec_y: Vec<f64>,
    /// Interpolated A, B, C of the current revolution and block.
    va: Vec<f64>,
    vb: Vec<f64>,
    vc: Vec<f64>,
    /// Same for the second revolution of a pair.
    wa: Vec<f64>,
    wb: Vec<f64>,
    wc: Vec<f64>,
    /// 0, 1, 2, … as f64 (the position within an interpolation run).
    ramp: Vec<f64>,
}

impl Accumulators {
    fn new(n: usize, keep_revs: usize) -> Self {
        let block = BLOCK.min(n);
        Accumulators {
            n,
            seg: Means::zeros(n),
            sq_x: vec![0.0; n],
            sq_y: vec![0.0; n],
            sxy: vec![0.0; n],
            min_x: vec![f64::INFINITY; n],
            max_x: vec![f64::NEG_INFINITY; n],
            min_y: vec![f64::INFINITY; n],
            max_y: vec![f64::NEG_INFINITY; n],
            rec_x: vec![0.0; n * keep_revs],
            rec_y: vec![0.0; n * keep_revs],
            va: vec![0.0; block],
            vb: vec![0.0; block],
            vc: vec![0.0; block],
            wa: vec![0.0; block],
            wb: vec![0.0; block],
            wc: vec![0.0; block],
            ramp: (0..block).map(|q| q as f64).collect(),
        }
    }

    /// Accumulates the revolutions of one segment, given as `(p0, step)`: grid point `j` of a
    /// revolution sits at sample position `p0 + j·step`. `r0` is the first revolution's index.
    /// Revolutions are taken two at a time, so each accumulator is loaded and stored once per pair.
    fn segment(&mut self, probes: &ProbeRecords<'_>, offsets: [f64; 3], place: &[(f64, f64)], r0: usize, ky: [f64; 3]) {
        let n = self.n;
        self.seg.a.fill(0.0);
        self.seg.b.fill(0.0);
        self.seg.c.fill(0.0);
        let [ka, kb, kc] = ky;
        let keep = !self.rec_x.is_empty();
        let mut q = 0;
        while q < place.len() {
            let pair = q + 1 < place.len();
            for jb in (0..n).step_by(BLOCK) {
                let len = BLOCK.min(n - jb);
                let r = jb..jb + len;
                let (p0, step) = place[q];
                let (va, vb, vc) = (&mut self.va[..len], &mut self.vb[..len], &mut self.vc[..len]);
                interpolate3(probes, offsets, p0 + jb as f64 * step, step, &self.ramp, [&mut *va, &mut *vb, &mut *vc]);
                let (wa, wb, wc) = (&mut self.wa[..len], &mut self.wb[..len], &mut self.wc[..len]);
                if pair {
                    let (p0, step) = place[q + 1];
                    interpolate3(
                        probes,
                        offsets,
                        p0 + jb as f64 * step,
                        step,
                        &self.ramp,
                        [&mut *wa, &mut *wb, &mut *wc],
                    );
                }
                let (sa, sb, sc) = (&mut self.seg.a[r.clone()], &mut self.seg.b[r.clone()], &mut self.seg.c[r.clone()]);
                let sq_x = &mut self.sq_x[r.clone()];
                let sq_y = &mut self.sq_y[r.clone()];
                let sxy = &mut self.sxy[r.clone()];
                let min_x = &mut self.min_x[r.clone()];
                let max_x = &mut self.max_x[r.clone()];
                let min_y = &mut self.min_y[r.clone()];
                let max_y = &mut self.max_y[r];
                if pair {
                    for j in 0..len {
                        let (xa, xb, xc) = (va[j], vb[j], vc[j]);
                        let (ya, yb, yc) = (wa[j], wb[j], wc[j]);
                        sa[j] += xa + ya;
                        sb[j] += xb + yb;
                        sc[j] += xc + yc;
                        let qx = ka * xa + kb * xb + kc * xc;
                        let qw = ka * ya + kb * yb + kc * yc;
                        sq_x[j] += xa * xa + ya * ya;
                        sq_y[j] += qx * qx + qw * qw;
                        sxy[j] += xa * qx + ya * qw;
                        let (lo, hi) = if xa < ya { (xa, ya) } else { (ya, xa) };
                        min_x[j] = if lo < min_x[j] { lo } else { min_x[j] };
                        max_x[j] = if hi > max_x[j] { hi } else { max_x[j] };
                        let (lo, hi) = if qx < qw { (qx, qw) } else { (qw, qx) };
                        min_y[j] = if lo < min_y[j] { lo } else { min_y[j] };
                        max_y[j] = if hi > max_y[j] { hi } else { max_y[j] };
                    }
                } else {
                    for j in 0..len {
                        let (xa, xb, xc) = (va[j], vb[j], vc[j]);
                        sa[j] += xa;
                        sb[j] += xb;
                        sc[j] += xc;
                        let qy = ka * xa + kb * xb + kc * xc;
                        sq_x[j] += xa * xa;
                        sq_y[j] += qy * qy;
                        sxy[j] += xa * qy;
                        min_x[j] = if xa < min_x[j] { xa } else { min_x[j] };
                        max_x[j] = if xa > max_x[j] { xa } else { max_x[j] };
                        min_y[j] = if qy < min_y[j] { qy } else { min_y[j] };
                        max_y[j] = if qy > max_y[j] { qy } else { max_y[j] };
                    }
                }
                if keep {
                    let revs: &[[&[f64]; 3]] = if pair { &[[va, vb, vc], [wa, wb, wc]] } else { &[[va, vb, vc]] };
                    for (g, [a, b, c]) in revs.iter().enumerate() {
                        let at = (r0 + q + g) * n + jb;
                        let (rx, ry) = (&mut self.rec_x[at..at + len], &mut self.rec_y[at..at + len]);
                        for j in 0..len {
                            rx[j] = a[j];
                            ry[j] = ka * a[j] + kb * b[j] + kc * c[j];
                        }
                    }
                }
            }
            q += if pair { 2 } else { 1 };
        }
    }

    /// Spectrum of the asynchronous x and y in time order (sample spacing mean period / N).
    fn async_spectrum(&mut self, mqx: &[f64], mqy: &[f64], n: usize, n_rev: usize, mean_period: f64) -> AsyncSpectrum {
        let total = n * n_rev;
        let mut z: Vec<Complex64> = Vec::with_capacity(total);
        for (rx, ry) in self.rec_x.chunks_exact(n).zip(self.rec_y.chunks_exact(n)) {
            z.extend((0..n).map(|j| Complex64::new(rx[j] - mqx[j], ry[j] - mqy[j])));
        }
        let fft = FftPlanner::new().plan_fft_forward(total);
        fft.process(&mut z);
        let (x, y) = split_amplitudes(&z);
        let df = 1.0 / (n_rev as f64 * mean_period);
        AsyncSpectrum { freq_hz: (0..x.len()).map(|k| k as f64 * df).collect(), x, y }
    }
}

/// Linear interpolation of the three probes (minus their offsets) at sample positions
/// `p + j·step`, j = 0..len. Between two carries of the fraction the sample index advances by
/// the whole part of the step, so each run is a plain strided loop (contiguous for step < 2)
/// that the compiler vectorizes.
fn interpolate3(probes: &ProbeRecords<'_>, offsets: [f64; 3], p: f64, step: f64, ramp: &[f64], out: [&mut [f64]; 3]) {
    let [va, vb, vc] = out;
    let len = va.len();
    let [oa, ob, oc] = offsets;
    let whole = step.floor();
    let (si, sf) = (whole as usize, step - whole);
    let start = p.floor();
    let (mut i, mut f) = (start as usize, p - start);
    let last = (p + (len - 1) as f64 * step).floor() as usize + 1;
    let (a, b, c) = (&probes.a[..=last], &probes.b[..=last], &probes.c[..=last]);
    if sf > 0.125 {
        // Short runs (a grid finer than the sampling, or a step far from whole): per point.
        for j in 0..len {
            let pj = p + ramp[j] * step;
            let i = pj as usize;
            let f = pj - i as f64;
            va[j] = a[i] + f * (a[i + 1] - a[i]) - oa;
            vb[j] = b[i] + f * (b[i + 1] - b[i]) - ob;
            vc[j] = c[i] + f * (c[i + 1] - c[i]) - oc;
        }
        return;
    }
    let mut j = 0;
    while j < len {
        // Points before the fraction carries: the smallest m with f + m·sf ≥ 1.
        let run = if sf > 0.0 {
            let t = (1.0 - f) / sf;
            let m = t as usize;
            (if (m as f64) < t { m + 1 } else { m }).clamp(1, len - j)
        } else {
            len - j
        };
        let (oa_, ob_, oc_) = (&mut va[j..j + run], &mut vb[j..j + run], &mut vc[j..j + run]);
        let ramp = &ramp[..run];
        if si == 1 {
            let (a0, a1) = (&a[i..i + run], &a[i + 1..i + 1 + run]);
            let (b0, b1) = (&b[i..i + run], &b[i + 1..i + 1 + run]);
            let (c0, c1) = (&c[i..i + run], &c[i + 1..i + 1 + run]);
            for q in 0..run {
                let ff = f + ramp[q] * sf;
                oa_[q] = a0[q] + ff * (a1[q] - a0[q]) - oa;
                ob_[q] = b0[q] + ff * (b1[q] - b0[q]) - ob;
                oc_[q] = c0[q] + ff * (c1[q] - c0[q]) - oc;
            }
        } else {
            for q in 0..run {
                let ff = f + ramp[q] * sf;
                let ii = i + q * si;
                oa_[q] = a[ii] + ff * (a[ii + 1] - a[ii]) - oa;
                ob_[q] = b[ii] + ff * (b[ii + 1] - b[ii]) - ob;
                oc_[q] = c[ii] + ff * (c[ii + 1] - c[ii]) - oc;
            }
        }
        j += run;
        i += run * si;
        f += run as f64 * sf;
        if f >= 1.0 {
            f -= 1.0;
            i += 1;
        }
    }
}

/// The first non-finite sample of the probes within `from..=to`.
fn first_non_finite(probes: &ProbeRecords<'_>, from: usize, to: usize) -> SeparationError {
    for (probe, rec) in [("a", probes.a), ("b", probes.b), ("c", probes.c)] {
        if let Some(i) = rec[from..=to].iter().position(|v| !v.is_finite()) {
            return SeparationError::NonFinite { probe, index: from + i, value: rec[from + i] };
        }
    }
    // Unreachable for finite inputs: the sums are finite then.
    SeparationError::NonFinite { probe: "a", index: from, value: f64::NAN }
}

/// Errors of [`integrate_velocity`].
#[derive(Debug, Clone, PartialEq, Error)]
pub enum LdvError {
    /// A velocity sample is NaN or infinite.
    #[error("velocity sample {index} is not finite ({value})")]
    NonFinite {
        /// Sample index.
        index: usize,
        /// The value.
        value: f64,
    },
    /// Fewer than two samples.
    #[error("the velocity record has {len} sample(s); at least 2 are needed")]
    TooShort {
        /// Number of samples.
        len: usize,
    },
    /// The spindle frequency is not positive.
    #[error("spindle frequency {hz} Hz must be positive")]
    InvalidSpindleSpeed {
        /// The offending frequency, Hz.
        hz: f64,
    },
    /// The high-pass filter cannot be designed (cutoff at or above Nyquist).
    #[error("high-pass at half the spindle frequency: {0}")]
    Filter(#[from] FilterError),
}

/// Order of the LDV high-pass filter (§3.2.1).
pub const LDV_HIGHPASS_ORDER: u32 = 3;

/// Displacement (m) from laser-vibrometer velocity `v` (m/s) sampled at `sample_rate` (Hz),
/// as in §3.2.1: cumulative trapezoidal integration (MATLAB's `cumtrapz`), then a 3rd-order
/// Butterworth high-pass at half the spindle frequency `spindle_hz` to remove the
/// integration drift.
///
/// The high-pass runs forward and backward (zero phase) so the displacement keeps its angular
/// alignment with the tachometer: a causal filter would shift the once-per-revolution content
/// by tens of degrees. Its per-pass cutoff is lowered by `(√2 − 1)^(1/6)` so that the two passes
/// together are 3 dB down at half the spindle frequency (the once-per-revolution content then
/// keeps 99.4 % of its amplitude). Before filtering, the least-squares line is removed and
/// the record is extended at each end by up to three revolutions of its own periodic
/// continuation (the samples one whole number of revolutions away, interpolated): the
/// synchronous content continues seamlessly, so the filter's start-up transient stays small.
/// Records shorter than one revolution fall back to odd reflection.
pub fn integrate_velocity(v: &[f64], sample_rate: f64, spindle_hz: f64) -> Result<Vec<f64>, LdvError> {
    let n = v.len();
    if n < 2 {
        return Err(LdvError::TooShort { len: n });
    }
    if let Some(index) = v.iter().position(|x| !x.is_finite()) {
        return Err(LdvError::NonFinite { index, value: v[index] });
    }
    if !(spindle_hz.is_finite() && spindle_hz > 0.0) {
        return Err(LdvError::InvalidSpindleSpeed { hz: spindle_hz });
    }
    let cutoff = 0.5 * spindle_hz * (SQRT_2 - 1.0).powf(1.0 / (2.0 * LDV_HIGHPASS_ORDER as f64));
    let hp = Sos::butter_highpass(LDV_HIGHPASS_ORDER, cutoff, sample_rate)?;
    let h = 0.5 / sample_rate;
    let mut d = Vec::with_capacity(n);
    let mut acc = 0.0;
    d.push(0.0);
    for w in v.windows(2) {
        acc += h * (w[0] + w[1]);
        d.push(acc);
    }
    detrend(&mut d);
    let period = sample_rate / spindle_hz;
    let revs = ((n - 1) as f64 / period).floor().min(3.0);
    if revs < 1.0 {
        return Ok(hp.filtfilt(&d));
    }
    let shift = revs * period;
    let pad = shift.floor() as usize;
    let at = |p: f64| {
        let i = (p.floor() as usize).min(n - 2);
        let f = p - i as f64;
        d[i] + f * (d[i + 1] - d[i])
    };
    let mut ext = Vec::with_capacity(n + 2 * pad);
    ext.extend((1..=pad).rev().map(|i| at(shift - i as f64)));
    ext.extend_from_slice(&d);
    ext.extend((1..=pad).map(|i| at((n - 1 + i) as f64 - shift)));
    let mut y = hp.filtfilt_padded(&ext, 0);
    y.drain(..pad);
    y.truncate(n);
    Ok(y)
}

/// Removes the least-squares straight line from `d`.
fn detrend(d: &mut [f64]) {
    let n = d.len() as f64;
    let tm = (n - 1.0) / 2.0;
    let mean = d.iter().sum::<f64>() / n;
    let (mut stt, mut sty) = (0.0, 0.0);
    for (i, &y) in d.iter().enumerate() {
        let t = i as f64 - tm;
        stt += t * t;
        sty += t * (y - mean);
    }
    let slope = if stt > 0.0 { sty / stt } else { 0.0 };
    d.iter_mut().enumerate().for_each(|(i, y)| *y -= mean + slope * (i as f64 - tm));
}

#[cfg(test)]
pub(crate) mod rig {
    //! Synthetic probe and tachometer records built from Eq. 3.4 with a known form and motion.

    use crate::tach::synth::tach_level;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};
    use std::f64::consts::TAU;

    /// `(k, A_k, B_k)`: `A_k cos kθ + B_k sin kθ`.
    pub type Harmonics = Vec<(usize, f64, f64)>;

    pub fn series(h: &[(usize, f64, f64)], theta: f64) -> f64 {
        h.iter().map(|&(k, a, b)| a * (k as f64 * theta).cos() + b * (k as f64 * theta).sin()).sum()
    }

    #[derive(Clone)]
    pub struct Rig {
        pub fs: f64,
        pub rpm: f64,
        /// Relative speed change over the record (linear ramp).
        pub drift: f64,
        pub revs: usize,
        pub phase0: f64,
        pub angles: [f64; 3],
        pub form: Harmonics,
        pub x: Harmonics,
        pub y: Harmonics,
        /// Asynchronous sinusoids `(Hz, amplitude)` in x and y.
        pub async_x: Option<(f64, f64)>,
        pub async_y: Option<(f64, f64)>,
        pub noise: f64,
        pub seed: u64,
        /// Probes give velocity (m/s) instead of displacement.
        pub velocity: bool,
    }

    pub struct Signals {
        pub tach: Vec<f64>,
        pub a: Vec<f64>,
        pub b: Vec<f64>,
        pub c: Vec<f64>,
    }

    impl Rig {
        pub fn new(rpm: f64, revs: usize) -> Rig {
            Rig {
                fs: 100_000.0,
                rpm,
                drift: 0.0,
                revs,
                phase0: 0.3,
                angles: super::DEFAULT_ANGLES_DEG.map(f64::to_radians),
                form: Vec::new(),
                x: Vec::new(),
                y: Vec::new(),
                async_x: None,
                async_y: None,
                noise: 0.0,
                seed: 1,
                velocity: false,
            }
        }

        pub fn duration(&self) -> f64 {
            (self.revs as f64 + 1.0) * 60.0 / self.rpm
        }

        /// Spindle angle and its rate at time `t`.
        pub fn theta(&self, t: f64) -> (f64, f64) {
            let f0 = self.rpm / 60.0;
            let ramp = self.drift / self.duration();
            (self.phase0 + TAU * f0 * (t + 0.5 * ramp * t * t), TAU * f0 * (1.0 + ramp * t))
        }

        /// Motion (x, y) and its time derivative at time `t`.
        fn motion(&self, t: f64) -> [(f64, f64); 2] {
            let (th, w) = self.theta(t);
            let d = |h: &[(usize, f64, f64)]| -> (f64, f64) {
                let v = series(h, th);
                let dv: f64 = h
                    .iter()
                    .map(|&(k, a, b)| k as f64 * w * (-a * (k as f64 * th).sin() + b * (k as f64 * th).cos()))
                    .sum();
                (v, dv)
            };
            let asy = |o: Option<(f64, f64)>| -> (f64, f64) {
                o.map_or((0.0, 0.0), |(f, amp)| {
                    let ph = TAU * f * t + 0.7;
                    (amp * ph.sin(), amp * TAU * f * ph.cos())
                })
            };
            let (x, dx) = d(&self.x);
            let (ax, dax) = asy(self.async_x);
            let (y, dy) = d(&self.y);
            let (ay, day) = asy(self.async_y);
            [(x + ax, dx + dax), (y + ay, dy + day)]
        }

        pub fn generate(&self) -> Signals {
            let n = (self.duration() * self.fs) as usize;
            let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
            let normal = Normal::new(0.0, self.noise.max(1e-300)).unwrap();
            let delta = TAU * self.rpm / 60.0 * 2.0 / self.fs;
            let mut s = Signals {
                tach: Vec::with_capacity(n),
                a: Vec::with_capacity(n),
                b: Vec::with_capacity(n),
                c: Vec::with_capacity(n),
            };
            for i in 0..n {
                let t = i as f64 / self.fs;
                let (th, w) = self.theta(t);
                s.tach.push(tach_level(th, 0.1, delta));
                let [(x, dx), (y, dy)] = self.motion(t);
                for (p, &phi) in self.angles.iter().enumerate() {
                    let arg = th - phi;
                    let v = if self.velocity {
                        let dr: f64 = self
                            .form
                            .iter()
                            .map(|&(k, a, b)| k as f64 * w * (-a * (k as f64 * arg).sin() + b * (k as f64 * arg).cos()))
                            .sum();
                        dr + dx * phi.cos() + dy * phi.sin()
                    } else {
                        series(&self.form, arg) + x * phi.cos() + y * phi.sin()
                    };
                    let e = if self.noise > 0.0 { normal.sample(&mut rng) } else { 0.0 };
                    [&mut s.a, &mut s.b, &mut s.c][p].push(v + e);
                }
            }
            s
        }

        /// Expected synchronous x and y on the grid: the motion plus the 1-UPR form term,
        /// which is indistinguishable from centring, with the mean removed.
        pub fn expected_sync(&self, theta: f64) -> (f64, f64) {
            let (a1, b1) = self.form.iter().find(|h| h.0 == 1).map_or((0.0, 0.0), |h| (h.1, h.2));
            (
                series(&self.x, theta) + a1 * theta.cos() + b1 * theta.sin(),
                series(&self.y, theta) + a1 * theta.sin() - b1 * theta.cos(),
            )
        }

        /// Expected form on the grid: harmonics 2 and up.
        pub fn expected_form(&self, theta: f64) -> f64 {
            let h: Vec<(usize, f64, f64)> = self.form.iter().copied().filter(|h| h.0 >= 2).collect();
            series(&h, theta)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::rig::{Rig, Signals, series};
    use super::*;
    use crate::tach::{TachOptions, decode};

    fn run(rig: &Rig, opts: &SeparationOptions) -> (Signals, Result<Separation, SeparationError>) {
        let s = rig.generate();
        let revs = decode(&s.tach, rig.fs, 0.0, &TachOptions::default()).unwrap();
        let probes = ProbeRecords { a: &s.a, b: &s.b, c: &s.c, sample_rate: rig.fs, t0: 0.0 };
        let out = separate(&probes, &revs, opts);
        (s, out)
    }

    fn rms(v: impl Iterator<Item = f64>) -> f64 {
        let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
        (s / n as f64).sqrt()
    }

    fn max_abs(v: impl Iterator<Item = f64>) -> f64 {
        v.fold(0.0, |m, x| m.max(x.abs()))
    }

    /// About 1 µm of form with 0 and 1 UPR terms, synchronous motion with 44 UPR in y.
    fn reference_rig(revs: usize) -> Rig {
        let mut rig = Rig::new(3000.0, revs);
        rig.drift = 0.002;
        rig.form = vec![
            (0, 2.0e-6, 0.0),
            (1, 0.8e-6, -0.5e-6),
            (2, 0.3e-6, 0.2e-6),
            (3, -0.15e-6, 0.1e-6),
            (5, 0.05e-6, -0.12e-6),
            (12, 0.04e-6, 0.03e-6),
            (44, 0.1e-6, -0.2e-6),
        ];
        rig.x = vec![(2, 30e-9, 10e-9), (7, -8e-9, 5e-9)];
        rig.y = vec![(3, 20e-9, -15e-9), (44, 0.0, 25e-9)];
        rig
    }

    #[test]
    fn combination_cancels_motion_and_gain_matches_eq_3_12() {
        let (sigma, rho) = (99.84f64.to_radians(), 202.5f64.to_radians());
        let (a, b) = combination_coefficients(sigma, rho).unwrap();
        // Eq. 3.7 corrected: the x and y coefficients vanish.
        assert!((1.0 + a * sigma.cos() + b * rho.cos()).abs() < 1e-12);
        assert!((a * sigma.sin() + b * rho.sin()).abs() < 1e-12);
        // Eq. 3.10/3.12 corrected: R = A cos kθ + B sin kθ gives M = F cos kθ + G sin kθ with
        // F = αA − βB and G = βA + αB.
        let (ak, bk) = (0.7, -0.4);
        for k in [2usize, 5, 44, 255] {
            let (al, be) = harmonic_gain(k, sigma, rho);
            let r = |t: f64| ak * (k as f64 * t).cos() + bk * (k as f64 * t).sin();
            for t in [0.1, 1.3, 2.9, 4.4] {
                let m = r(t) + a * r(t - sigma) + b * r(t - rho);
                let (f, g) = (al * ak - be * bk, be * ak + al * bk);
                let expect = f * (k as f64 * t).cos() + g * (k as f64 * t).sin();
                assert!((m - expect).abs() < 1e-12, "k {k}: {m} vs {expect}");
            }
        }
        // 0°/90°/180°: probe B gets no weight and every odd harmonic is lost.
        let odd = unrecoverable_harmonics(90f64.to_radians(), 180f64.to_radians(), 9, 1e-6);
        assert_eq!(odd, vec![3, 5, 7, 9]);
        assert!(combination_coefficients(90f64.to_radians(), 270f64.to_radians()).is_none());
    }

    #[test]
    fn fourier_sign_convention_recovers_sine_and_cosine_terms() {
        // Pure sin 5θ and cos 7θ form: a sign slip in the FFT's sine coefficients or in the
        // probe shifts would flip B_5 or leak form into the motion.
        let mut rig = Rig::new(3000.0, 10);
        rig.form = vec![(5, 0.0, 0.5e-6), (7, 0.2e-6, 0.0)];
        let opts = SeparationOptions { segments: 2, ..Default::default() };
        let (_, sep) = run(&rig, &opts);
        let sep = sep.unwrap();
        let (a5, b5) = sep.form_harmonics[5];
        let (a7, b7) = sep.form_harmonics[7];
        // Linear interpolation between samples attenuates harmonic k by about (2πk/n)²/12
        // (n samples per revolution): 2·10⁻⁵ here.
        assert!(a5.abs() < 1e-11 && (b5 - 0.5e-6).abs() < 2e-11, "k=5: ({a5}, {b5})");
        assert!((a7 - 0.2e-6).abs() < 2e-11 && b7.abs() < 1e-11, "k=7: ({a7}, {b7})");
        let err = max_abs(sep.angle.iter().zip(&sep.form).map(|(&t, &r)| r - rig.expected_form(t)));
        assert!(err < 5e-11, "form error {err}");
        let (mx, my) = (max_abs(sep.sync_x.iter().copied()), max_abs(sep.sync_y.iter().copied()));
        // Only the interpolation residual (10⁻⁴ of the form) is left; a sign slip would leave
        // a fraction of the 0.5 µm.
        assert!(mx < 5e-11 && my < 5e-11, "form leaks into the motion: {mx} {my}");
        assert!((sep.sync_spectrum.form[5] - 0.5e-6).abs() < 2e-11);
    }

    #[test]
    fn noise_free_form_and_synchronous_motion_are_recovered() {
        let rig = reference_rig(20);
        let (_, sep) = run(&rig, &SeparationOptions { segments: 4, ..Default::default() });
        let sep = sep.unwrap();
        assert!(sep.revolutions >= 20);
        assert_eq!(sep.samples_per_rev % 2, 0);
        let form_err = rms(sep.angle.iter().zip(&sep.form).map(|(&t, &r)| r - rig.expected_form(t)));
        assert!(form_err < 5e-9, "form rms error {form_err}");
        assert!(form_err < 1e-9, "form rms error {form_err} (expected well below the 5 nm goal)");
        let (mut ex, mut ey) = (Vec::new(), Vec::new());
        for &t in &sep.angle {
            let (x, y) = rig.expected_sync(t);
            ex.push(x);
            ey.push(y);
        }
        remove_mean(&mut ex);
        remove_mean(&mut ey);
        let xerr = rms(sep.sync_x.iter().zip(&ex).map(|(a, b)| a - b));
        let yerr = rms(sep.sync_y.iter().zip(&ey).map(|(a, b)| a - b));
        assert!(xerr < 2e-9 && yerr < 2e-9, "sync errors x {xerr}, y {yerr}");
        // r = x cos θ + y sin θ; the centring term becomes a constant in r.
        for j in (0..sep.samples_per_rev).step_by(97) {
            let t = sep.angle[j];
            let r = sep.sync_x[j] * t.cos() + sep.sync_y[j] * t.sin();
            assert!((r - sep.sync_r[j]).abs() < 1e-15);
        }
        assert!(
            (sep.ptv.form - ptv(&sep.angle.iter().map(|&t| rig.expected_form(t)).collect::<Vec<_>>())).abs() < 2e-9
        );
        assert!((sep.ptv.x - ptv(&ex)).abs() < 2e-9 && (sep.ptv.y - ptv(&ey)).abs() < 2e-9);
        // Spectrum: 44 UPR in y with 25 nm, in the form with |0.1 − 0.2i| µm; nothing at 45.
        assert!((sep.sync_spectrum.y[44] - 25e-9).abs() < 0.5e-9, "{}", sep.sync_spectrum.y[44]);
        assert!((sep.sync_spectrum.form[44] - (0.1e-6f64).hypot(0.2e-6)).abs() < 1e-9);
        assert!(sep.sync_spectrum.y[45] < 0.2e-9 && sep.sync_spectrum.form[1] == 0.0);
        assert!((sep.sync_spectrum.x[1] - (0.8e-6f64).hypot(0.5e-6)).abs() < 2e-9, "centring in x");
        // No asynchronous motion: the spread over revolutions is at the level of the drift.
        assert!(sep.async_value_x < 2e-9 && max_abs(sep.async_sigma_y.iter().copied()) < 1e-9);
        assert!(sep.unrecoverable.contains(&255) && sep.unrecoverable.contains(&257));
        assert_eq!(sep.form_harmonics[255], (0.0, 0.0));
        assert!((sep.nyquist_upr - 1000.0 / (1.0 + 0.001)).abs() < 1.0 && !sep.nyquist_exceeded);
    }

    #[test]
    fn asynchronous_motion_is_measured_per_angle_and_in_frequency() {
        let mut rig = reference_rig(40);
        rig.drift = 0.0;
        let (ax, ay) = (15e-9, 10e-9);
        rig.async_x = Some((2197.3, ax));
        rig.async_y = Some((1234.5, ay));
        let (_, sep) = run(&rig, &SeparationOptions::default());
        let sep = sep.unwrap();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let (sx, sy) = (mean(&sep.async_sigma_x), mean(&sep.async_sigma_y));
        assert!((sx / (ax / SQRT_2) - 1.0).abs() < 0.05, "σx {sx}");
        assert!((sy / (ay / SQRT_2) - 1.0).abs() < 0.05, "σy {sy}");
        // Rotating-sensitive σ² = cos²θ σx² + sin²θ σy² for uncorrelated x and y.
        let j = sep.samples_per_rev / 8;
        let t = sep.angle[j];
        let pred =
            (t.cos().powi(2) * sep.async_sigma_x[j].powi(2) + t.sin().powi(2) * sep.async_sigma_y[j].powi(2)).sqrt();
        assert!((sep.async_sigma_r[j] / pred - 1.0).abs() < 0.3);
        assert!(sep.async_value_x > 1.7 * ax && sep.async_value_x <= 2.0 * ax + 1e-12, "{}", sep.async_value_x);
        assert!(sep.async_value_y > 1.7 * ay && sep.async_value_y <= 2.0 * ay + 1e-12);
        let spec = sep.async_spectrum.as_ref().unwrap();
        let peak = |v: &[f64]| v.iter().enumerate().fold((0, 0.0), |b, (i, &a)| if a > b.1 { (i, a) } else { b });
        let (ix, px) = peak(&spec.x);
        let (iy, py) = peak(&spec.y);
        let df = spec.freq_hz[1];
        assert!((spec.freq_hz[ix] - 2197.3).abs() <= df, "x peak at {} Hz", spec.freq_hz[ix]);
        assert!((spec.freq_hz[iy] - 1234.5).abs() <= df, "y peak at {} Hz", spec.freq_hz[iy]);
        assert!(px > 0.6 * ax && px < 1.05 * ax && py > 0.6 * ay && py < 1.05 * ay, "{px} {py}");
        assert!(spec.x[iy] < 0.05 * ax, "y motion leaks into x");
        // The form is untouched (x and y cancel in M), the synchronous motion nearly so.
        let form_err = rms(sep.angle.iter().zip(&sep.form).map(|(&t, &r)| r - rig.expected_form(t)));
        assert!(form_err < 1e-9, "{form_err}");
    }

    #[test]
    fn noisy_truth_lies_inside_the_three_sigma_segment_band() {
        let mut rig = reference_rig(200);
        rig.noise = 20e-9;
        rig.async_x = Some((2197.3, 15e-9));
        let (_, sep) = run(&rig, &SeparationOptions::default());
        let sep = sep.unwrap();
        let st = &sep.segments;
        assert_eq!(st.revolutions.len(), 10);
        assert!(st.revolutions.iter().all(|&c| c == sep.revolutions / 10 || c == sep.revolutions / 10 + 1));
        let mut ex: Vec<f64> = sep.angle.iter().map(|&t| rig.expected_sync(t).0).collect();
        remove_mean(&mut ex);
        for (j, &truth_x) in ex.iter().enumerate() {
            let truth_form = rig.expected_form(sep.angle[j]);
            assert!(
                (truth_form - st.form_mean[j]).abs() <= 3.0 * st.form_sigma[j],
                "form at {j}: truth {truth_form}, mean {}, σ {}",
                st.form_mean[j],
                st.form_sigma[j]
            );
            assert!((truth_x - st.x_mean[j]).abs() <= 3.0 * st.x_sigma[j], "x at {j}");
        }
        // The band is informative: a few nm against a micrometre of form.
        assert!(st.form_sigma_mean > 1e-9 && st.form_sigma_mean < 15e-9, "form σ {}", st.form_sigma_mean);
        assert!(st.x_sigma_mean > 1e-9 && st.x_sigma_mean < 20e-9, "x σ {}", st.x_sigma_mean);
        // Whole-record estimates are √10 better than a segment's.
        let form_err = rms(sep.angle.iter().zip(&sep.form).map(|(&t, &r)| r - rig.expected_form(t)));
        assert!(form_err < st.form_sigma_mean, "{form_err}");
        // Asynchronous σ: probe noise (interpolated) and the 15 nm sinusoid.
        let sx = sep.async_sigma_x.iter().sum::<f64>() / sep.samples_per_rev as f64;
        assert!(sx > 15e-9 / SQRT_2 && sx < 25e-9, "{sx}");
    }

    #[test]
    fn unrecoverable_harmonics_are_reported_not_divided_by() {
        // Probes at 0°, 90°, 180°: every odd harmonic has α_k² + β_k² = 0.
        let mut rig = Rig::new(3000.0, 8);
        rig.angles = [0.0, 90f64.to_radians(), 180f64.to_radians()];
        rig.form = vec![(2, 0.3e-6, 0.1e-6), (3, 0.2e-6, -0.1e-6), (4, -0.1e-6, 0.05e-6), (44, 0.1e-6, 0.0)];
        rig.y = vec![(2, 10e-9, 0.0)];
        let mut opts = SeparationOptions { angles: rig.angles, segments: 2, ..Default::default() };
        let (_, err) = run(&rig, &opts);
        let err = err.unwrap_err();
        let SeparationError::Unrecoverable { harmonics, .. } = &err else { panic!("{err}") };
        assert_eq!(harmonics[..3], [3, 5, 7]);
        let msg = err.to_string();
        assert!(msg.contains("[3, 5, 7") && msg.contains("90") && msg.contains("180"), "{msg}");
        opts.allow_unrecoverable = true;
        let (_, sep) = run(&rig, &opts);
        let sep = sep.unwrap();
        let half = sep.samples_per_rev / 2;
        assert_eq!(sep.unrecoverable, (3..half).step_by(2).collect::<Vec<_>>());
        assert!(sep.form.iter().all(|v| v.is_finite()));
        assert_eq!(sep.form_harmonics[3], (0.0, 0.0));
        for (k, a, b) in [(2usize, 0.3e-6f64, 0.1e-6f64), (4, -0.1e-6, 0.05e-6), (44, 0.1e-6, 0.0)] {
            let (ra, rb) = sep.form_harmonics[k];
            // Within the linear-interpolation error of the largest harmonic (44 UPR, 0.1 µm):
            // about (2πk/n)²/8 of it, spread over sidebands.
            let tol = 1e-12 + (TAU * 44.0 / 2000.0).powi(2) / 8.0 * 0.1e-6;
            assert!((ra - a).abs() < tol && (rb - b).abs() < tol, "k {k}: ({ra}, {rb})");
        }
        // The lost 3-UPR form stays in x (probe A sees it), as the only place it can go.
        assert!((sep.sync_spectrum.x[3] - (0.2e-6f64).hypot(0.1e-6)).abs() < 1e-10);
    }

    #[test]
    fn grid_size_and_nyquist_limit() {
        // 4857 rpm at 100 kHz: 1235.3 samples per revolution → N = 1200, the largest even
        // number ≤ 1235 without prime factors above 7.
        assert_eq!(fft_friendly_floor(1235), 1200);
        assert_eq!(fft_friendly_floor(6000), 6000);
        assert_eq!(fft_friendly_floor(5999), 5880);
        assert_eq!(fft_friendly_floor(9), 8);
        let rig = Rig::new(4857.0, 6);
        let opts = SeparationOptions { segments: 2, ..Default::default() };
        let (s, sep) = run(&rig, &opts);
        let sep = sep.unwrap();
        assert_eq!(sep.samples_per_rev, 1200);
        assert!((sep.nyquist_upr - 30.0 * 100_000.0 / 4857.0).abs() < 1e-6);
        assert!(!sep.nyquist_exceeded);
        let revs = decode(&s.tach, rig.fs, 0.0, &TachOptions::default()).unwrap();
        let probes = ProbeRecords { a: &s.a, b: &s.b, c: &s.c, sample_rate: rig.fs, t0: 0.0 };
        let over =
            separate(&probes, &revs, &SeparationOptions { samples_per_rev: Some(2000), ..opts.clone() }).unwrap();
        assert!(over.nyquist_exceeded && over.samples_per_rev == 2000);
        // Any even grid size is accepted when asked for.
        let plain =
            separate(&probes, &revs, &SeparationOptions { samples_per_rev: Some(1234), ..opts.clone() }).unwrap();
        assert_eq!(plain.samples_per_rev, 1234);
        let odd = separate(&probes, &revs, &SeparationOptions { samples_per_rev: Some(1001), ..opts.clone() });
        assert!(matches!(odd, Err(SeparationError::InvalidSamplesPerRev { n: 1001, .. })));
        let no_async = separate(&probes, &revs, &SeparationOptions { async_spectrum: false, ..opts }).unwrap();
        assert!(no_async.async_spectrum.is_none() && no_async.form == sep.form);
    }

    #[test]
    fn bad_inputs_are_errors_with_context() {
        let mut rig = Rig::new(3000.0, 6);
        rig.form = vec![(3, 0.1e-6, 0.0)];
        let s = rig.generate();
        let revs = decode(&s.tach, rig.fs, 0.0, &TachOptions::default()).unwrap();
        let opts = SeparationOptions { segments: 2, ..Default::default() };
        fn ok<'a>(a: &'a [f64], b: &'a [f64], c: &'a [f64]) -> ProbeRecords<'a> {
            ProbeRecords { a, b, c, sample_rate: 100_000.0, t0: 0.0 }
        }
        let short = &s.c[..s.c.len() - 1];
        assert!(matches!(
            separate(&ok(&s.a, &s.b, short), &revs, &opts),
            Err(SeparationError::LengthMismatch { probe: "c", .. })
        ));
        let mut b = s.b.clone();
        b[5000] = f64::NAN;
        assert_eq!(
            separate(&ok(&s.a, &b, &s.c), &revs, &opts).unwrap_err().to_string(),
            "probe `b` sample 5000 is not finite (NaN)"
        );
        let mut other_rate = ok(&s.a, &s.b, &s.c);
        other_rate.sample_rate = 50_000.0;
        assert!(matches!(separate(&other_rate, &revs, &opts), Err(SeparationError::SampleRateMismatch { .. })));
        let one = crate::tach::Revolutions::from_edges(revs.edges()[..2].to_vec(), rig.fs).unwrap();
        assert!(matches!(
            separate(&ok(&s.a, &s.b, &s.c), &one, &opts),
            Err(SeparationError::TooFewRevolutions { found: 1 })
        ));
        let many = SeparationOptions { segments: 10, ..Default::default() };
        let e = separate(&ok(&s.a, &s.b, &s.c), &revs, &many).unwrap_err();
        assert!(matches!(e, SeparationError::InvalidSegments { segments: 10, .. }), "{e}");
        let tilted = SeparationOptions { angles: [0.1, 1.7, 3.5], ..opts.clone() };
        assert!(matches!(
            separate(&ok(&s.a, &s.b, &s.c), &revs, &tilted),
            Err(SeparationError::DegenerateAngles { .. })
        ));
        let line = SeparationOptions { angles: [0.0, 90f64.to_radians(), 270f64.to_radians()], ..opts.clone() };
        assert!(matches!(separate(&ok(&s.a, &s.b, &s.c), &revs, &line), Err(SeparationError::DegenerateAngles { .. })));
        let late = crate::tach::Revolutions::from_edges(vec![0.01, 0.03, 0.05, 10.0], rig.fs).unwrap();
        assert!(matches!(
            separate(&ok(&s.a, &s.b, &s.c), &late, &opts),
            Err(SeparationError::OutsideRecord { revolution: 2, .. })
        ));
    }

    #[test]
    fn ldv_integration_recovers_spindle_harmonics() {
        // Displacement with 1–5 UPR at 50 Hz: integrate the analytic velocity.
        let (fs, f) = (20_000.0, 50.0);
        let h: Vec<(usize, f64, f64)> =
            vec![(1, 1.0e-6, 0.3e-6), (2, -0.5e-6, 0.2e-6), (3, 0.3e-6, 0.0), (4, 0.0, -0.2e-6), (5, 0.1e-6, 0.1e-6)];
        let n = (2.0 * fs) as usize;
        let th = |i: usize| TAU * f * i as f64 / fs;
        let x: Vec<f64> = (0..n).map(|i| 3e-6 + series(&h, th(i))).collect();
        let v: Vec<f64> = (0..n)
            .map(|i| {
                h.iter()
                    .map(|&(k, a, b)| {
                        let w = TAU * f * k as f64;
                        w * (-a * (k as f64 * th(i)).sin() + b * (k as f64 * th(i)).cos())
                    })
                    .sum()
            })
            .collect();
        // A velocity offset (integration drift) must not matter either.
        let v: Vec<f64> = v.iter().map(|x| x + 2e-5).collect();
        let d = integrate_velocity(&v, fs, f).unwrap();
        let mut truth = x.clone();
        remove_mean(&mut truth);
        let scale = rms(truth.iter().copied());
        let err = rms((0..n).map(|i| d[i] - truth[i]));
        assert!(err < 0.01 * scale, "relative rms error {}", err / scale);
        let inner = 1000..n - 1000;
        // Zero phase: the 1-UPR component keeps its angle.
        let c1 = inner.clone().map(|i| Complex64::from_polar(d[i], -th(i))).sum::<Complex64>();
        let t1 = inner.clone().map(|i| Complex64::from_polar(truth[i], -th(i))).sum::<Complex64>();
        assert!((c1 / t1).arg().abs() < 1e-3 && ((c1 / t1).norm() - 1.0).abs() < 0.01, "{}", c1 / t1);
        assert!(matches!(integrate_velocity(&v, fs, 0.0), Err(LdvError::InvalidSpindleSpeed { .. })));
        assert!(matches!(integrate_velocity(&v, fs, 25_000.0), Err(LdvError::Filter(_))));
        let mut bad = v.clone();
        bad[7] = f64::INFINITY;
        assert!(matches!(integrate_velocity(&bad, fs, f), Err(LdvError::NonFinite { index: 7, .. })));
    }

    #[test]
    fn velocity_probes_separate_like_displacement_probes() {
        let mut rig = reference_rig(20);
        rig.drift = 0.0;
        rig.velocity = true;
        let s = rig.generate();
        let revs = decode(&s.tach, rig.fs, 0.0, &TachOptions::default()).unwrap();
        let hz = revs.mean_speed_rpm() / 60.0;
        let a = integrate_velocity(&s.a, rig.fs, hz).unwrap();
        let b = integrate_velocity(&s.b, rig.fs, hz).unwrap();
        let c = integrate_velocity(&s.c, rig.fs, hz).unwrap();
        let probes = ProbeRecords { a: &a, b: &b, c: &c, sample_rate: rig.fs, t0: 0.0 };
        let sep = separate(&probes, &revs, &SeparationOptions { segments: 4, ..Default::default() }).unwrap();
        let form_err = rms(sep.angle.iter().zip(&sep.form).map(|(&t, &r)| r - rig.expected_form(t)));
        let form_rms = rms(sep.angle.iter().map(|&t| rig.expected_form(t)));
        assert!(form_err < 0.005 * form_rms, "form error {form_err} of {form_rms}");
    }
}
