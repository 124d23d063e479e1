//! §5.2.5: each Eq. 5.8 mode becomes a solid fixed-free Euler–Bernoulli beam with the same first natural
//! frequency (free length by Eq. 5.6) whose tip receptance matches the mode's around resonance.

use super::{Band, Mode};
use crate::eb_modes::{EbError, FIXED_FREE_ROOT_1, FixedFreeBeam};
use argmin::core::{CostFunction, Error as ArgminError, Executor, State};
use argmin::solver::neldermead::NelderMead;
use num_complex::Complex64;
use spindlelab_domain::Material;
use std::f64::consts::{PI, TAU};

/// Closed-form diameter of the beam whose first mode has tip modal mass `M` at `f`: the first cantilever
/// mode's tip modal mass is `ρAL/4`, and with `L = sqrt(c d)` from Eq. 5.6
/// (`c = 1.87510407²/(2πf) · sqrt(E/16ρ)`) this gives `M = (πρ/16) sqrt(c) d^{5/2}`.
pub fn closed_form_diameter(mode: &Mode, material: &Material) -> f64 {
    let c = FIXED_FREE_ROOT_1 * FIXED_FREE_ROOT_1 / (TAU * mode.freq_hz)
        * (material.youngs_modulus / (16.0 * material.density)).sqrt();
    (16.0 * mode.modal_mass / (PI * material.density * c.sqrt())).powf(0.4)
}

/// The beam's `H` against the mode's Eq. 5.8 receptance on the band points: `Σ|H_beam − H_mode| / Σ|H_mode|`,
/// searched over `(ln d, ln η)`.
struct BeamCost<'a> {
    f_hz: f64,
    material: Material,
    w: &'a [f64],
    target: &'a [Complex64],
    scale: f64,
}

impl CostFunction for BeamCost<'_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, p: &Self::Param) -> Result<f64, ArgminError> {
        let Ok(beam) = FixedFreeBeam::equivalent(self.f_hz, p[0].exp(), p[1].exp(), self.material) else {
            return Ok(f64::INFINITY);
        };
        let fast = super::refit::FastH::new(beam);
        let sum: f64 = self.w.iter().zip(self.target).map(|(&w, t)| (fast.h(w.sqrt()) - t).norm_sqr().sqrt()).sum();
        Ok(if sum.is_finite() { sum * self.scale } else { f64::INFINITY })
    }
}

/// Maps `mode` to its equivalent beam (§5.2.5): the closed form ([`closed_form_diameter`], `η = 2ξ`) refined by
/// a two-parameter Nelder–Mead on `points` evenly spaced lines of `band` (at most ±3 half-power widths around
/// the mode), so that the beam's tip `H` matches the mode's Eq. 5.8 FRF. The frequency is kept.
pub fn beam_for_mode(mode: &Mode, band: &Band, material: &Material, points: usize) -> Result<FixedFreeBeam, EbError> {
    let d0 = closed_form_diameter(mode, material);
    let eta0 = 2.0 * mode.damping_ratio;
    let start = FixedFreeBeam::equivalent(mode.freq_hz, d0, eta0, *material)?;
    let reach = 3.0 * mode.damping_ratio * mode.freq_hz;
    let lo = band.lo_hz.max(mode.freq_hz - reach);
    let hi = band.hi_hz.min(mode.freq_hz + reach);
    let n = points.max(8);
    let w: Vec<f64> = (0..n).map(|k| TAU * (lo + (hi - lo) * k as f64 / (n - 1) as f64)).collect();
    let target: Vec<Complex64> = w.iter().map(|&w| mode.receptance(w)).collect();
    let sum: f64 = target.iter().map(|t| t.norm()).sum();
    let cost = BeamCost { f_hz: mode.freq_hz, material: *material, w: &w, target: &target, scale: 1.0 / sum };
    let z0 = vec![d0.ln(), eta0.ln()];
    let simplex = vec![z0.clone(), vec![z0[0] + 0.05, z0[1]], vec![z0[0], z0[1] + 0.1]];
    // Neither step can fail: the tolerance is valid and the cost never errors (a bad point costs ∞); the
    // closed-form beam stands in should that ever change.
    let Ok(solver) = NelderMead::new(simplex).with_sd_tolerance(1e-9) else {
        return Ok(start);
    };
    let best = match Executor::new(cost, solver).configure(|s| s.max_iters(200)).timer(false).run() {
        Ok(res) => res.state().get_best_param().cloned().unwrap_or(z0),
        Err(_) => return Ok(start),
    };
    FixedFreeBeam::equivalent(mode.freq_hz, best[0].exp(), best[1].exp(), *material)
}
