//! Variable (unequal) pitch in the frequency domain: the zero-order stability limit of a cutter whose teeth have
//! unequal delays (Altintas, Engin & Budak 1999, J. Manuf. Sci. Eng. 121:173–178) and the alternating-pitch
//! design rule after Budak (2003, J. Manuf. Sci. Eng. 125:29–38).
//!
//! Tooth `j` regenerates over its own delay `τ_j = pitch_j/Ω` ([`Milling::tooth_delay`]). Averaged over the
//! revolution (the zero-order approximation), every tooth contributes the same matrix `H0_t = (1/2π) ∫ h(φ) dφ`
//! over the engaged arc, `H0_t = −(Kt/4π) [α]` with Altintas's directional factors (the helix does not change
//! this average), so a vibration `q e^{iωt}` of the tool point with FRF matrix `Φ(iω)` gives the dynamic force
//! `F = −a_p Σ_j H0_t (1 − e^{−iωτ_j}) Φ F`. The characteristic equation is
//! `det[I + a_p S(ω) H0_t Φ(iω)] = 0` with `S(ω) = Σ_j (1 − e^{−iωτ_j})`: for each eigenvalue `λ` of `H0_t Φ`,
//! `a_p = −1/(S λ)`, and a chatter frequency is where this is real and positive. For equal pitch
//! `S = N (1 − e^{−iωτ})` and the limit is the ZOA of Altintas & Budak (1995); for unequal pitch `S` depends on
//! the speed through every `τ_j`, there is no closed-form lobe, and the limit at a speed is the smallest positive
//! real root over the chatter frequencies, found here by sweeping the FRF's lines.
//!
//! Like the ZOA it neglects the harmonics of the cutting forces (here at the spindle frequency, as the teeth
//! differ): good in slotting and at half immersion, not at low immersion, where [`super::sd_depth_limit`] (which
//! handles variable pitch in the time domain) is the method to use.

use super::zoa::ToolPointFrf;
use super::{Milling, StabilityError};
use num_complex::Complex64;
use std::f64::consts::{PI, TAU};

/// Largest phase step `ω τ_max` of the regenerative factor `S(ω)` between two samples of the sweep, rad: between
/// FRF lines farther apart the eigenvalues are interpolated linearly and `S` evaluated exactly.
const MAX_PHASE_STEP: f64 = 0.05;

/// The limit of a variable-pitch cutter at one speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PitchLimit {
    /// Spindle speed, rpm.
    pub speed_rpm: f64,
    /// Smallest positive real root `a_p = −1/(S λ)` over the chatter frequencies, m; `+∞` if there is none.
    pub depth_m: f64,
    /// Chatter frequency of that root, Hz (0 where there is none).
    pub chatter_hz: f64,
}

/// Zero-order stability limit of a (possibly) variable-pitch cutter at each of `speeds_rpm` from the tool-point
/// FRFs (Altintas, Engin & Budak 1999): see the [module docs](self). The FRF lines should resolve the modes; `S`
/// is evaluated exactly between them (eigenvalues interpolated linearly) so that its phase moves at most 0.05 rad
/// per sample. The cut's pitch and delays come from `milling`; its helix does not enter the averaged matrix.
pub fn variable_pitch_limits(
    frf: &ToolPointFrf,
    milling: &Milling,
    speeds_rpm: &[f64],
) -> Result<Vec<PitchLimit>, StabilityError> {
    frf.validate()?;
    if let Some(&s) = speeds_rpm.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
        return Err(StabilityError::InvalidParameter {
            name: "spindle speed",
            value: s,
            requirement: "finite and > 0 rpm",
        });
    }
    let lambdas = eigenvalue_branches(frf, milling);
    Ok(speeds_rpm.iter().map(|&n| limit_at(&frf.freqs_hz, &lambdas, milling, n)).collect())
}

/// Per FRF line the two eigenvalues of `H0_t Φ(iω)`, branches followed by nearest matching from line to line.
fn eigenvalue_branches(frf: &ToolPointFrf, milling: &Milling) -> Vec<[Complex64; 2]> {
    let alpha = milling.directional_factors();
    let scale = -milling.coefficients.kt / (4.0 * PI);
    let h0 = [[scale * alpha[0][0], scale * alpha[0][1]], [scale * alpha[1][0], scale * alpha[1][1]]];
    let zero = Complex64::new(0.0, 0.0);
    let mut prev: Option<[Complex64; 2]> = None;
    (0..frf.freqs_hz.len())
        .map(|k| {
            let (xy, yx) = frf.cross.as_ref().map_or((zero, zero), |(p, q)| (p[k], q[k]));
            let g = [[frf.xx[k], xy], [yx, frf.yy[k]]];
            let m = |r: usize, c: usize| h0[r][0] * g[0][c] + h0[r][1] * g[1][c];
            let (m00, m01, m10, m11) = (m(0, 0), m(0, 1), m(1, 0), m(1, 1));
            let half_tr = 0.5 * (m00 + m11);
            let disc = (half_tr * half_tr - (m00 * m11 - m01 * m10)).sqrt();
            let mut lam = [half_tr + disc, half_tr - disc];
            if let Some(p) = prev
                && (lam[0] - p[0]).norm() + (lam[1] - p[1]).norm() > (lam[0] - p[1]).norm() + (lam[1] - p[0]).norm()
            {
                lam.swap(0, 1);
            }
            prev = Some(lam);
            lam
        })
        .collect()
}

/// The smallest positive root at `speed_rpm`: where `Im(S λ)` changes sign along a branch and `Re(S λ) < 0`,
/// `a_p = −1/Re(S λ)` at the crossing (linear interpolation between samples).
fn limit_at(freqs_hz: &[f64], lambdas: &[[Complex64; 2]], milling: &Milling, speed_rpm: f64) -> PitchLimit {
    let delays: Vec<f64> = (0..milling.teeth).map(|j| milling.tooth_delay(j, speed_rpm)).collect();
    let tau_max = delays.iter().cloned().fold(0.0, f64::max);
    let s_of = |w: f64| -> Complex64 {
        delays.iter().map(|&t| Complex64::new(1.0, 0.0) - Complex64::from_polar(1.0, -w * t)).sum()
    };
    let mut best = PitchLimit { speed_rpm, depth_m: f64::INFINITY, chatter_hz: 0.0 };
    let mut consider = |f0: f64, w0: Complex64, f1: f64, w1: Complex64| {
        if (w0.im > 0.0) == (w1.im > 0.0) && w1.im != 0.0 {
            return;
        }
        let u = if w0.im == w1.im { 0.0 } else { w0.im / (w0.im - w1.im) };
        let re = w0.re + u * (w1.re - w0.re);
        let depth = -1.0 / re;
        if re < 0.0 && depth.is_finite() && depth < best.depth_m {
            best.depth_m = depth;
            best.chatter_hz = f0 + u * (f1 - f0);
        }
    };
    // The last FRF line (frequency, eigenvalues) and the last sample of the sweep (frequency, S λ).
    let mut line: Option<(f64, [Complex64; 2])> = None;
    let mut last: Option<(f64, [Complex64; 2])> = None;
    for (&f, lam) in freqs_hz.iter().zip(lambdas) {
        if f <= 0.0 || !(lam[0].is_finite() && lam[1].is_finite()) {
            (line, last) = (None, None);
            continue;
        }
        let (fp, lp, samples) = match line {
            Some((fp, lp)) => (fp, lp, ((TAU * (f - fp) * tau_max / MAX_PHASE_STEP).ceil() as usize).clamp(1, 100_000)),
            None => (f, *lam, 1),
        };
        for i in 1..=samples {
            let u = i as f64 / samples as f64;
            let fi = fp + u * (f - fp);
            let s = s_of(TAU * fi);
            let wi = [s * (lp[0] + u * (lam[0] - lp[0])), s * (lp[1] + u * (lam[1] - lp[1]))];
            if let Some((fl, wl)) = last {
                for b in 0..2 {
                    consider(fl, wl[b], fi, wi[b]);
                }
            }
            last = Some((fi, wi));
        }
        line = Some((f, *lam));
    }
    best
}

/// Alternating pitch tuned to a chatter frequency after Budak (2003, J. Manuf. Sci. Eng. 125:29–38, Part I):
/// the pitch variation `ΔP` is chosen so that the regenerative phases of neighbouring teeth differ by `π` at the
/// chatter frequency `ω_c`, `ω_c ΔP/Ω = π`, i.e. `ΔP = π Ω/ω_c`. With the pitches alternating
/// `p̄ − ΔP/2, p̄ + ΔP/2, …` (`p̄ = 2π/N`, `N` even) the regenerative factor of the
/// [characteristic equation](self) is `S(ω) = N [1 − e^{−iω p̄/Ω} cos(ω ΔP/2Ω)]`, and at `ω_c` the cosine
/// vanishes: the delayed terms of neighbouring teeth cancel and `S(ω_c) = N` whatever the speed, so the cut cannot
/// regenerate at `ω_c`. (Budak states the rule for a linear pitch variation; this is its alternating-pitch form,
/// derived from the same phase condition.) Returns the `N` pitch angles, rad, for [`Milling::with_pitch`].
pub fn alternating_pitch(teeth: usize, speed_rpm: f64, chatter_hz: f64) -> Result<Vec<f64>, StabilityError> {
    if teeth < 2 || !teeth.is_multiple_of(2) {
        return Err(StabilityError::InvalidParameter {
            name: "teeth of an alternating-pitch cutter",
            value: teeth as f64,
            requirement: "an even number ≥ 2 (the pitch alternates between two angles)",
        });
    }
    if !(speed_rpm.is_finite() && speed_rpm > 0.0) {
        return Err(StabilityError::InvalidParameter {
            name: "spindle speed",
            value: speed_rpm,
            requirement: "finite and > 0 rpm",
        });
    }
    if !(chatter_hz.is_finite() && chatter_hz > 0.0) {
        return Err(StabilityError::InvalidParameter {
            name: "chatter frequency (Hz)",
            value: chatter_hz,
            requirement: "finite and > 0 Hz",
        });
    }
    let mean = TAU / teeth as f64;
    let variation = PI * (TAU * speed_rpm / 60.0) / (TAU * chatter_hz);
    if variation >= mean {
        return Err(StabilityError::InvalidParameter {
            name: "pitch variation ΔP = π Ω/ω_c (rad)",
            value: variation,
            requirement: "below the mean pitch 2π/N: the chatter frequency is too low for this speed and tooth count",
        });
    }
    Ok((0..teeth).map(|j| if j % 2 == 0 { mean - 0.5 * variation } else { mean + 0.5 * variation }).collect())
}
