//! Least-squares complex frequency-domain (LSCF) identification, the standard alternative to §5.2's simplex.
//!
//! The FRF on the fit band is modelled as a common-denominator rational fraction in `z = e^{iωΔt}`
//! (`Δt = 1/(2 f_max)`), `H ≈ Σ b_j z^j / Σ a_j z^j` with real coefficients, weighted by `1/|H|` (relative
//! errors). The numerator is eliminated from the linearised least-squares problem (reduced normal equations
//! `M = 2(T − Sᵀ R⁻¹ S)`, `a_n = 1`), the denominator's roots give the poles `λ = ln z / Δt`, and poles that
//! reappear at the next model order within 1 % in frequency and 20 % in damping are kept (stabilisation).
//! Residues then follow by linear least squares with a lower (`−1/ω²`) and an upper (constant) residual term;
//! a real mode's residue is `R = 1/(2iMω_d)`, which gives its modal mass.

use super::pick::Peak;
use super::{FitError, Mode, Weighting, im_peak};
use num_complex::Complex64;
use std::f64::consts::TAU;
use std::ops::Range;

/// Largest damping ratio accepted as a physical pole.
const MAX_XI: f64 = 0.3;

/// Gaussian elimination with partial pivoting: solves `A X = B` in place (`a` is `n×n` row-major, `b` is `n×k`
/// row-major). `None` when a pivot vanishes relative to the matrix's scale.
pub(super) fn solve(a: &mut [f64], b: &mut [f64], n: usize, k: usize) -> Option<()> {
    let scale = a.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    if scale == 0.0 || !scale.is_finite() {
        return None;
    }
    for col in 0..n {
        let piv = (col..n).max_by(|&i, &j| a[i * n + col].abs().total_cmp(&a[j * n + col].abs()))?;
        if a[piv * n + col].abs() <= 1e-15 * scale {
            return None;
        }
        if piv != col {
            for c in 0..n {
                a.swap(piv * n + c, col * n + c);
            }
            for c in 0..k {
                b.swap(piv * k + c, col * k + c);
            }
        }
        let d = a[col * n + col];
        for r in col + 1..n {
            let f = a[r * n + col] / d;
            if f == 0.0 {
                continue;
            }
            for c in col..n {
                a[r * n + c] -= f * a[col * n + c];
            }
            for c in 0..k {
                b[r * k + c] -= f * b[col * k + c];
            }
        }
    }
    for col in (0..n).rev() {
        let d = a[col * n + col];
        for c in 0..k {
            let mut v = b[col * k + c];
            for j in col + 1..n {
                v -= a[col * n + j] * b[j * k + c];
            }
            b[col * k + c] = v / d;
        }
    }
    b.iter().all(|v| v.is_finite()).then_some(())
}

/// Roots of the real polynomial `Σ c_j z^j` (`c[n] ≠ 0`) by the Aberth–Ehrlich iteration.
pub(super) fn roots(c: &[f64]) -> Vec<Complex64> {
    let n = c.len() - 1;
    let lead = c[n];
    let mono: Vec<f64> = c.iter().map(|v| v / lead).collect();
    let eval = |z: Complex64| {
        let mut p = Complex64::from(mono[n]);
        let mut dp = Complex64::from(0.0);
        for j in (0..n).rev() {
            dp = dp * z + p;
            p = p * z + mono[j];
        }
        (p, dp)
    };
    // Roots of an LSCF denominator lie near the unit circle; start on a slightly smaller, rotated circle.
    let mut z: Vec<Complex64> =
        (0..n).map(|k| Complex64::from_polar(0.95, TAU * (k as f64 + 0.3) / n as f64 + 0.1)).collect();
    for _ in 0..500 {
        let mut moved = 0.0_f64;
        for k in 0..n {
            let (p, dp) = eval(z[k]);
            if p.norm() == 0.0 {
                continue;
            }
            let ratio = p / dp;
            let s: Complex64 = (0..n).filter(|&j| j != k).map(|j| (z[k] - z[j]).inv()).sum();
            let step = ratio / (Complex64::from(1.0) - ratio * s);
            if step.re.is_finite() && step.im.is_finite() {
                z[k] -= step;
                moved = moved.max(step.norm() / z[k].norm().max(1e-300));
            }
        }
        if moved < 1e-13 {
            break;
        }
    }
    z
}

/// A physical pole: natural frequency (Hz), damping ratio and `λ`.
#[derive(Debug, Clone, Copy)]
struct Pole {
    f_hz: f64,
    xi: f64,
    lambda: Complex64,
}

/// Lines used by the estimate, with `H` scaled by `h0` so the normal equations stay well scaled.
struct Data {
    w: Vec<f64>,
    h: Vec<Complex64>,
    z: Vec<Complex64>,
    dt: f64,
    h0: f64,
    lo: f64,
    hi: f64,
    /// `1/|H|` line weights (relative errors), or none.
    relative: bool,
}

fn data(freqs: &[f64], h: &[Complex64], range: Range<usize>, weighting: Weighting) -> Data {
    let idx: Vec<usize> = range.filter(|&k| freqs[k] > 0.0 && h[k].norm() > 0.0).collect();
    let hi = freqs[*idx.last().unwrap_or(&0)];
    let lo = freqs[*idx.first().unwrap_or(&0)];
    let dt = 1.0 / (2.0 * hi);
    let h0 = (idx.iter().map(|&k| h[k].norm_sqr()).sum::<f64>() / idx.len().max(1) as f64).sqrt();
    Data {
        w: idx.iter().map(|&k| TAU * freqs[k]).collect(),
        h: idx.iter().map(|&k| h[k] / h0).collect(),
        z: idx.iter().map(|&k| Complex64::from_polar(1.0, TAU * freqs[k] * dt)).collect(),
        dt,
        h0,
        lo,
        hi,
        relative: weighting == Weighting::Relative,
    }
}

/// Denominator coefficients `a_0..a_n` (`a_n = 1`) of the order-`n` model for the line weights `g` (the square
/// of the extra weight on top of `1/|H|`).
fn denominator(d: &Data, n: usize, g: &[f64]) -> Result<Vec<f64>, FitError> {
    let m = n + 1;
    // Toeplitz sequences: r_q = Re Σ w² z^q, t_q = Re Σ w²|H|² z^q (= Σ cos qθ with w = 1/|H|),
    // s±_q = Σ −w² H z^{±q}.
    let mut r = vec![0.0; m];
    let mut t = vec![0.0; m];
    let mut sp = vec![Complex64::from(0.0); m];
    let mut sm = vec![Complex64::from(0.0); m];
    for ((&z, &h), &g) in d.z.iter().zip(&d.h).zip(g) {
        let w2 = if d.relative { g / h.norm_sqr() } else { g };
        let mut zq = Complex64::from(1.0);
        for q in 0..m {
            r[q] += w2 * zq.re;
            t[q] += w2 * h.norm_sqr() * zq.re;
            sp[q] -= w2 * h * zq;
            sm[q] -= w2 * h * zq.conj();
            zq *= z;
        }
    }
    let s_at = |i: usize, j: usize| if j >= i { sp[j - i].re } else { sm[i - j].re };
    let mut rr = vec![0.0; m * m];
    let mut x = vec![0.0; m * m];
    for i in 0..m {
        for j in 0..m {
            rr[i * m + j] = r[i.abs_diff(j)];
            x[i * m + j] = s_at(i, j);
        }
    }
    let s = x.clone();
    solve(&mut rr, &mut x, m, m).ok_or(FitError::Singular { what: "numerator elimination" })?;
    // M = T − Sᵀ R⁻¹ S; solve M[..n, ..n] a = −M[..n, n].
    let mut mm = vec![0.0; m * m];
    for i in 0..m {
        for j in 0..m {
            let mut v = t[i.abs_diff(j)];
            for k in 0..m {
                v -= s[k * m + i] * x[k * m + j];
            }
            mm[i * m + j] = v;
        }
    }
    let mut a = vec![0.0; n * n];
    let mut rhs = vec![0.0; n];
    for i in 0..n {
        for j in 0..n {
            a[i * n + j] = mm[i * m + j];
        }
        rhs[i] = -mm[i * m + n];
    }
    solve(&mut a, &mut rhs, n, 1).ok_or(FitError::Singular { what: "denominator" })?;
    rhs.push(1.0);
    Ok(rhs)
}

/// Sanathanan–Koerner passes: each re-weights the linearised problem by `1/|D(z)|²` of the previous pass,
/// which removes the bias of the linearisation (it weights lines near poles too heavily).
const SK_PASSES: usize = 4;

/// Physical poles of the order-`n` LSCF model.
fn poles(d: &Data, n: usize) -> Result<Vec<Pole>, FitError> {
    let mut g = vec![1.0; d.z.len()];
    let mut a = denominator(d, n, &g)?;
    for _ in 0..SK_PASSES {
        for (gk, &z) in g.iter_mut().zip(&d.z) {
            let den = a.iter().rev().fold(Complex64::from(0.0), |acc, &c| acc * z + c);
            *gk = 1.0 / den.norm_sqr().max(1e-300);
        }
        // Keep the weights' scale near one.
        let mean = g.iter().sum::<f64>() / g.len() as f64;
        g.iter_mut().for_each(|v| *v /= mean);
        a = denominator(d, n, &g)?;
    }
    let out = roots(&a)
        .into_iter()
        .filter_map(|zr| {
            let lambda = zr.ln() / d.dt;
            let wn = lambda.norm();
            let f_hz = wn / TAU;
            let xi = -lambda.re / wn;
            (lambda.im > 0.0 && xi > 0.0 && xi < MAX_XI && f_hz >= d.lo && f_hz <= d.hi).then_some(Pole {
                f_hz,
                xi,
                lambda,
            })
        })
        .collect();
    Ok(out)
}

/// Residues of `poles` (with their conjugates) and the lower/upper residual terms by weighted linear least
/// squares; returns the residues in the FRF's units.
fn residues(d: &Data, poles: &[Pole]) -> Result<Vec<Complex64>, FitError> {
    let p = poles.len();
    let cols = 2 * p + 2;
    let mut ata = vec![0.0; cols * cols];
    let mut aty = vec![0.0; cols];
    let mut row = vec![Complex64::from(0.0); cols];
    for ((&w, &h), _) in d.w.iter().zip(&d.h).zip(&d.z) {
        let wt = if d.relative { 1.0 / h.norm() } else { 1.0 };
        let s = Complex64::new(0.0, w);
        for (k, pole) in poles.iter().enumerate() {
            let a = (s - pole.lambda).inv();
            let b = (s - pole.lambda.conj()).inv();
            row[2 * k] = (a + b) * wt;
            row[2 * k + 1] = Complex64::new(0.0, 1.0) * (a - b) * wt;
        }
        row[2 * p] = Complex64::from(-wt / (w * w));
        row[2 * p + 1] = Complex64::from(wt);
        let y = h * wt;
        for i in 0..cols {
            for j in i..cols {
                ata[i * cols + j] += row[i].re * row[j].re + row[i].im * row[j].im;
            }
            aty[i] += row[i].re * y.re + row[i].im * y.im;
        }
    }
    for i in 0..cols {
        for j in 0..i {
            ata[i * cols + j] = ata[j * cols + i];
        }
    }
    // Column scaling to unit diagonal before the solve.
    let sc: Vec<f64> = (0..cols).map(|i| 1.0 / ata[i * cols + i].sqrt().max(1e-300)).collect();
    for i in 0..cols {
        for j in 0..cols {
            ata[i * cols + j] *= sc[i] * sc[j];
        }
        aty[i] *= sc[i];
    }
    solve(&mut ata, &mut aty, cols, 1).ok_or(FitError::Singular { what: "residues" })?;
    Ok((0..p).map(|k| Complex64::new(aty[2 * k] * sc[2 * k], aty[2 * k + 1] * sc[2 * k + 1]) * d.h0).collect())
}

/// LSCF modes on the fit band: returns the kept modes (by frequency), the rejected ones (negative mass or
/// below the `v_sens` cut-off) and the number of model orders evaluated.
#[allow(clippy::too_many_arguments)]
pub(super) fn fit_modes(
    freqs: &[f64],
    h: &[Complex64],
    range: Range<usize>,
    peaks: &[Peak],
    order: Option<usize>,
    v_sens: f64,
    complex: bool,
    signed: bool,
    weighting: Weighting,
) -> Result<(Vec<Mode>, Vec<Mode>, usize), FitError> {
    let d = data(freqs, h, range, weighting);
    // With no order given, four poles per picked peak (at least 8); when fewer poles than peaks are stable
    // (noise or close modes), six and then eight per peak. Orders noise-free data cannot support (singular
    // normal equations) are skipped.
    let candidates: Vec<usize> = match order {
        Some(n) => vec![n & !1],
        None => [4, 6, 8].iter().map(|k| (k * peaks.len()).clamp(8, 200) & !1).collect(),
    };
    let mut best: Option<(usize, Vec<Pole>)> = None;
    let mut last_err = None;
    let mut tried = 0;
    for &n in &candidates {
        tried += 1;
        let pair = poles(&d, n).and_then(|a| Ok((a, poles(&d, n + 2)?)));
        let (a, b) = match pair {
            Ok(ab) => ab,
            Err(e @ FitError::Singular { .. }) if order.is_none() => {
                last_err = Some(e);
                continue;
            }
            Err(e) => return Err(e),
        };
        let stable: Vec<Pole> = a
            .into_iter()
            .filter(|p| b.iter().any(|q| (q.f_hz - p.f_hz).abs() <= 0.01 * p.f_hz && (q.xi - p.xi).abs() <= 0.2 * p.xi))
            .collect();
        let enough = stable.len() >= peaks.len();
        if best.as_ref().is_none_or(|(_, s)| stable.len() > s.len()) {
            best = Some((n, stable));
        }
        if enough {
            break;
        }
    }
    let Some((n, stable)) = best else {
        return Err(last_err.unwrap_or(FitError::Singular { what: "denominator" }));
    };
    if stable.is_empty() {
        return Err(FitError::NothingLeft {
            method: "lscf",
            why: format!("no pole is stable between orders {n} and {}", n + 2),
        });
    }
    let res = residues(&d, &stable)?;
    let mut kept = Vec::new();
    let mut rejected = Vec::new();
    for (pole, r) in stable.iter().zip(&res) {
        // R = 1/(2 i M ω_d) = −i/(2 M ω_d): M from the imaginary part; a complex residue keeps its modulus.
        let mode = if complex && signed {
            super::lsfd::signed_mode_of_residue(pole.f_hz, pole.xi, *r)
        } else if complex {
            super::lsfd::mode_of_residue(pole.f_hz, pole.xi, *r)
        } else {
            let mass = -1.0 / (2.0 * pole.lambda.im * r.im);
            Mode { freq_hz: pole.f_hz, damping_ratio: pole.xi, modal_mass: mass }
        };
        let mass = mode.modal_mass;
        // A transfer FRF's modal constants carry signs; only a driving point's must be positive.
        if mass.is_finite() && mass != 0.0 && (signed || mass > 0.0) { kept.push(mode) } else { rejected.push(mode) }
    }
    let largest = kept.iter().fold(0.0_f64, |m, q| m.max(im_peak(q).abs()));
    let (keep, drop): (Vec<Mode>, Vec<Mode>) = kept.into_iter().partition(|q| im_peak(q).abs() >= v_sens * largest);
    rejected.extend(drop);
    if keep.is_empty() {
        return Err(FitError::NothingLeft {
            method: "lscf",
            why: "every stable pole has a negative modal mass".into(),
        });
    }
    let mut keep = keep;
    keep.sort_by(|x, y| x.freq_hz.total_cmp(&y.freq_hz));
    Ok((keep, rejected, tried + 1))
}
