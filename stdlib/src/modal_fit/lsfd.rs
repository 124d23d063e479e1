//! Least-squares frequency-domain (LSFD) residues: with the poles fixed, the FRF on the fit band is linear in the
//! complex residues and the residual terms,
//! `H(ω) = Σ_r [A_r/(iω − λ_r) + Ā_r/(iω − λ̄_r)] − LR/ω² + UR`,
//! so they follow from one linear least-squares problem (real and imaginary parts stacked, each line weighted by
//! `1/|H|` so that every line counts by its relative error, solved by faer's Householder QR with unit-norm columns).
//! A real (proportionally damped) mode of Eq. 5.8 has `A = 1/(2iMω_d)`; a complex `A` carries the phase of a
//! non-proportionally damped mode, which a real modal mass cannot represent. `LR` is the mass line of modes below
//! the band (`1/M` of a rigid-body-like mode), `UR` the static flexibility `1/K` of modes above it.

use super::{FitError, Mode, Weighting};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Complex residues and residual terms of the LSFD estimate, with the fit's quality.
#[derive(Debug, Clone, PartialEq)]
pub struct ResidueFit {
    /// Residue `A_r` of each mode (same order as the modes), m/(N·s).
    pub residues: Vec<Complex64>,
    /// Lower residual `LR` (the term `−LR/ω²`), m·s⁻²/N; `1/LR` is the mass of the out-of-band low mode, kg.
    pub lower: f64,
    /// Upper residual `UR` (a constant), m/N: the static flexibility of the modes above the band.
    pub upper: f64,
    /// Global relative L2 residual `‖H − H_fit‖/‖H‖` over the lines of the fit band (the peaks dominate it).
    pub relative_residual: f64,
    /// The `1/|H|`-weighted relative error `sqrt(mean |H − H_fit|²/|H|²)` over the same lines (every line
    /// counts by its relative error; the antiresonances dominate it).
    pub weighted_residual: f64,
}

/// The global relative L2 residual and the `1/|H|`-weighted relative error (RMS over lines) of `fit`
/// against `h` (lines where `H = 0` or the fit is not finite are left out of the weighted one).
pub fn residual_measures(h: &[Complex64], fit: &[Complex64]) -> (f64, f64) {
    let (mut num, mut den, mut rel, mut n) = (0.0, 0.0, 0.0, 0usize);
    for (a, b) in h.iter().zip(fit) {
        let d = (a - b).norm_sqr();
        if !d.is_finite() {
            continue;
        }
        num += d;
        den += a.norm_sqr();
        if a.norm_sqr() > 0.0 {
            rel += d / a.norm_sqr();
            n += 1;
        }
    }
    let global = if den > 0.0 { (num / den).sqrt() } else { 0.0 };
    let weighted = if n > 0 { (rel / n as f64).sqrt() } else { 0.0 };
    (global, weighted)
}

/// Pole `λ = −ξω_n + iω_n sqrt(1 − ξ²)` of a mode, rad/s.
pub fn pole(mode: &Mode) -> Complex64 {
    let wn = mode.omega();
    let xi = mode.damping_ratio;
    Complex64::new(-xi * wn, wn * (1.0 - xi * xi).max(0.0).sqrt())
}

/// Residue `1/(2iMω_d)` of the real mode of Eq. 5.8 (its receptance is `A/(iω − λ) + Ā/(iω − λ̄)` exactly).
pub fn real_residue(mode: &Mode) -> Complex64 {
    Complex64::new(0.0, -1.0 / (2.0 * mode.modal_mass * pole(mode).im))
}

/// The mode whose real residue has the modulus of `a`: modal mass `1/(2ω_d|A|)`, so that the peak `|H|` of the
/// mode is kept when a complex residue is reported as an Eq. 5.8 mode.
pub fn mode_of_residue(freq_hz: f64, damping_ratio: f64, a: Complex64) -> Mode {
    let wd = TAU * freq_hz * (1.0 - damping_ratio * damping_ratio).max(0.0).sqrt();
    Mode { freq_hz, damping_ratio, modal_mass: 1.0 / (2.0 * wd * a.norm()) }
}

/// [`mode_of_residue`] with the sign of the modal constant kept: a real residue is
/// `−i/(2Mω_d)`, so the mass is negative where `Im A > 0` (a transfer FRF's mode whose response
/// and reference move in opposite senses).
pub fn signed_mode_of_residue(freq_hz: f64, damping_ratio: f64, a: Complex64) -> Mode {
    let m = mode_of_residue(freq_hz, damping_ratio, a);
    Mode { modal_mass: if a.im > 0.0 { -m.modal_mass } else { m.modal_mass }, ..m }
}

/// `A/(iω − λ) + Ā/(iω − λ̄)` at `w` rad/s.
#[inline]
pub fn pair_h(a: Complex64, lambda: Complex64, w: f64) -> Complex64 {
    let s = Complex64::new(0.0, w);
    a / (s - lambda) + a.conj() / (s - lambda.conj())
}

/// The two real basis functions of a conjugate pair at `w`: `u = φ + ψ`, `v = i(φ − ψ)` with `φ = 1/(iω − λ)`,
/// `ψ = 1/(iω − λ̄)`, so that the pair's receptance is `Re A · u + Im A · v`.
#[inline]
pub(super) fn pair_basis(lambda: Complex64, w: f64) -> (Complex64, Complex64) {
    // φ = 1/(−λr + i(ω − λi)), ψ = 1/(−λr + i(ω + λi)).
    let (lr, li) = (lambda.re, lambda.im);
    let (a, b) = (w - li, w + li);
    let (da, db) = (1.0 / (lr * lr + a * a), 1.0 / (lr * lr + b * b));
    let phi = Complex64::new(-lr * da, -a * da);
    let psi = Complex64::new(-lr * db, -b * db);
    (phi + psi, Complex64::new(psi.im - phi.im, phi.re - psi.re))
}

/// Least-squares solution of the dense `rows × cols` system `a x ≈ y` (column-major `a`) by faer's
/// Householder QR; `None` when a column is (numerically) dependent on the others.
pub(super) fn least_squares(a: &mut [f64], y: &mut [f64], rows: usize, cols: usize) -> Option<Vec<f64>> {
    use faer::linalg::solvers::SolveLstsq;
    // Unit-norm columns first: the residue, 1/ω² and constant columns differ by many orders of magnitude.
    let mut scale = vec![0.0; cols];
    for (c, sc) in scale.iter_mut().enumerate() {
        let n = a[c * rows..(c + 1) * rows].iter().map(|v| v * v).sum::<f64>().sqrt();
        if n == 0.0 || !n.is_finite() {
            return None;
        }
        *sc = 1.0 / n;
        a[c * rows..(c + 1) * rows].iter_mut().for_each(|v| *v /= n);
    }
    let qr = faer::MatRef::from_column_major_slice(a, rows, cols).qr();
    let r = qr.thin_R();
    if (0..cols).any(|k| r[(k, k)].abs() <= 1e-12) {
        return None;
    }
    let mut rhs = faer::Mat::<f64>::from_fn(rows, 1, |i, _| y[i]);
    qr.solve_lstsq_in_place(rhs.as_mut());
    let x: Vec<f64> = (0..cols).map(|k| rhs[(k, 0)] * scale[k]).collect();
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// LSFD residues of `modes` (their poles fixed) and the residual terms on the lines `freqs_hz`, `h` (the fit band;
/// lines at 0 Hz or with `H = 0` are skipped).
pub fn lsfd(freqs_hz: &[f64], h: &[Complex64], modes: &[Mode]) -> Result<ResidueFit, FitError> {
    lsfd_weighted(freqs_hz, h, modes, Weighting::Relative)
}

/// [`lsfd`] with the line weights of `weighting`: `1/|H|` (relative) or none (absolute, the global L2
/// residual).
pub fn lsfd_weighted(
    freqs_hz: &[f64],
    h: &[Complex64],
    modes: &[Mode],
    weighting: Weighting,
) -> Result<ResidueFit, FitError> {
    let lines: Vec<usize> = (0..freqs_hz.len()).filter(|&k| freqs_hz[k] > 0.0 && h[k].norm() > 0.0).collect();
    let p = modes.len();
    let cols = 2 * p + 2;
    let rows = 2 * lines.len();
    if rows < 2 * cols {
        return Err(FitError::TooFewLines { lines: lines.len(), min: cols, place: "for the residues" });
    }
    let poles: Vec<Complex64> = modes.iter().map(pole).collect();
    let mut a = vec![0.0; rows * cols];
    let mut y = vec![0.0; rows];
    for (r, &k) in lines.iter().enumerate() {
        let w = TAU * freqs_hz[k];
        let wt = match weighting {
            Weighting::Relative => 1.0 / h[k].norm(),
            Weighting::Absolute => 1.0,
        };
        let mut put = |c: usize, v: Complex64| {
            a[c * rows + 2 * r] = v.re * wt;
            a[c * rows + 2 * r + 1] = v.im * wt;
        };
        for (m, &lambda) in poles.iter().enumerate() {
            let (u, v) = pair_basis(lambda, w);
            put(2 * m, u);
            put(2 * m + 1, v);
        }
        put(2 * p, Complex64::from(-1.0 / (w * w)));
        put(2 * p + 1, Complex64::from(1.0));
        y[2 * r] = h[k].re * wt;
        y[2 * r + 1] = h[k].im * wt;
    }
    let x = least_squares(&mut a, &mut y, rows, cols).ok_or(FitError::Singular { what: "LSFD residues" })?;
    let residues: Vec<Complex64> = (0..p).map(|m| Complex64::new(x[2 * m], x[2 * m + 1])).collect();
    let (lower, upper) = (x[2 * p], x[2 * p + 1]);
    let fits: Vec<Complex64> = lines
        .iter()
        .map(|&k| {
            let w = TAU * freqs_hz[k];
            residues.iter().zip(&poles).map(|(&a, &l)| pair_h(a, l, w)).sum::<Complex64>() - lower / (w * w) + upper
        })
        .collect();
    let measured: Vec<Complex64> = lines.iter().map(|&k| h[k]).collect();
    let (relative_residual, weighted_residual) = residual_measures(&measured, &fits);
    Ok(ResidueFit { residues, lower, upper, relative_residual, weighted_residual })
}
