//! Joint refit of the equivalent beams against the measured FRF, in the manner of the global iterations of
//! §5.2.4 but on the beam model.
//!
//! The mapping of §5.2.5 matches each beam to its own mode near resonance. A fixed-free beam is not a single
//! mode, though: it carries its higher bending modes (the second at 6.27 f, with the same tip modal mass
//! `ρAL/4`) and an antiresonance above its first mode, so away from its own resonance it departs from the
//! mode's Eq. 5.8 receptance, and the sum of the beams (Eq. 5.7) misses the measured FRF where another beam
//! dominates. Here each beam's `(ln d, ln η, ln f)` is refitted by Nelder–Mead on its band against the
//! measured `H^m` with the other beams' summed tip `H` held (the Eq. 5.9 objective, a sum of complex residual
//! norms), beam after beam, until the summed objective over all bands stops improving.

use super::{Band, EquivalentBeam};
use crate::eb_modes::FixedFreeBeam;
use crate::rcsa::Receptance;
use argmin::core::{CostFunction, Error as ArgminError, Executor, State};
use argmin::solver::neldermead::NelderMead;
use num_complex::Complex64;
use spindlelab_domain::Material;
use std::f64::consts::TAU;

/// Cap on the refit's global iterations (sweeps over all beams).
pub const REFIT_ITERATIONS: usize = 10;
/// Lines per band the refit evaluates its objective on (fewer when the band has fewer or `band_points` is
/// lower); the reported band errors use every line.
pub const REFIT_POINTS: usize = 64;
/// A sweep that lowers the summed objective by less than this fraction ends the refit.
const IMPROVEMENT: f64 = 1e-4;
/// Nelder–Mead iterations per beam and sweep.
const MAX_ITERS: u64 = 150;
/// Below this `|λL|` the closed form cancels; the beam's own series evaluation is used instead.
const SERIES_LIMIT: f64 = 1.0;

/// The tip `H` of one fixed-free beam prepared for many frequencies: with `x = λL = sqrt(ω) q`,
/// `q = L (ρA/EI*)^{1/4}`, Eq. 5.5 reads `H = (L³/EI*) (sin x cosh x − cos x sinh x) / (x³ (1 + cos x cosh x))`.
/// Multiplying through by `2e^{−x}/(1 + e^{−2x})` keeps every term bounded, and `sin x`, `cos x`, `e^{−x}`
/// share two real `sin_cos` and two real `exp`, several times cheaper than the full 2×2 block.
pub(super) struct FastH {
    beam: FixedFreeBeam,
    /// `L³/EI*`, m/N.
    scale: Complex64,
    /// `L (ρA/EI*)^{1/4}` (principal root), s^{1/2}.
    q: Complex64,
    /// `EI*`, N·m².
    ei: Complex64,
}

impl FastH {
    pub(super) fn new(beam: FixedFreeBeam) -> Self {
        let ei = beam.ei_complex();
        let len = beam.length_m;
        let q = (Complex64::from(beam.material.density * beam.area()) / ei).powf(0.25) * len;
        FastH { beam, scale: Complex64::from(len * len * len) / ei, q, ei }
    }

    /// `H` at `sqrt_w = sqrt(ω)`.
    #[inline]
    pub(super) fn h(&self, sqrt_w: f64) -> Complex64 {
        let x = self.q * sqrt_w;
        if x.norm_sqr() < SERIES_LIMIT * SERIES_LIMIT {
            return self.beam.tip_receptance(sqrt_w * sqrt_w).h;
        }
        let (s, c, e, one_e2) = trig_terms(x);
        let num = s * one_e2 - c * (Complex64::from(2.0) - one_e2);
        let den = x * x * x * (e * 2.0 + c * one_e2);
        self.scale * num / den
    }
}

impl FastH {
    /// The full tip block `H, L = N, P` (Eqs. 5.10–5.12) at `sqrt_w = sqrt(ω)`, with the same shared real
    /// trigonometric and exponential terms as [`FastH::h`] (the beam's own evaluation below `|λL| = 1`).
    pub(super) fn block(&self, sqrt_w: f64) -> Receptance {
        let x = self.q * sqrt_w;
        if x.norm_sqr() < SERIES_LIMIT * SERIES_LIMIT {
            return self.beam.tip_receptance(sqrt_w * sqrt_w);
        }
        let (s, c, e, one_e2) = trig_terms(x);
        let inv = one_e2.inv();
        let tanh = (Complex64::from(2.0) - one_e2) * inv;
        let sech = e * 2.0 * inv;
        let lam = x / self.beam.length_m;
        let lam_dn = lam * self.ei * (sech + c);
        let inv1 = lam_dn.inv();
        let inv2 = inv1 / lam;
        let l = s * tanh * inv2;
        Receptance::new((s - c * tanh) * inv2 / lam, l, l, (s + c * tanh) * inv1)
    }
}

/// `sin x`, `cos x`, `e = exp(−x)` and `1 + e²` of a complex `x = λL`, from
/// shared real trigonometric and exponential terms (no complex `sin`/`cos` calls).
#[inline]
fn trig_terms(x: Complex64) -> (Complex64, Complex64, Complex64, Complex64) {
    let (sa, ca) = x.re.sin_cos();
    let (sb, cb) = x.im.sin_cos();
    let (eb, emb) = (x.im.exp(), (-x.im).exp());
    let (chb, shb) = (0.5 * (eb + emb), 0.5 * (eb - emb));
    let s = Complex64::new(sa * chb, ca * shb);
    let c = Complex64::new(ca * chb, -sa * shb);
    let e = Complex64::new(cb, -sb) * (-x.re).exp();
    (s, c, e, Complex64::from(1.0) + e * e)
}

/// One band's data: `sqrt(ω)` of its lines, the measured `H^m` there and `1/Σ|H^m|`.
struct BandData {
    sqrt_w: Vec<f64>,
    hm: Vec<Complex64>,
    scale: f64,
}

/// The Eq. 5.9 objective of one beam on its band with the other beams held, over `(ln d, ln η, ln f)`.
struct BeamRefitCost<'a> {
    data: &'a BandData,
    held: &'a [Complex64],
    material: Material,
    f_lo: f64,
    f_hi: f64,
}

impl BeamRefitCost<'_> {
    fn beam(&self, z: &[f64]) -> Option<FixedFreeBeam> {
        let f = z[2].exp();
        if !(self.f_lo..=self.f_hi).contains(&f) {
            return None;
        }
        FixedFreeBeam::equivalent(f, z[0].exp(), z[1].exp(), self.material).ok()
    }
}

impl CostFunction for BeamRefitCost<'_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, z: &Self::Param) -> Result<f64, ArgminError> {
        let Some(beam) = self.beam(z) else {
            return Ok(f64::INFINITY);
        };
        let fast = FastH::new(beam);
        let mut sum = 0.0;
        for ((&s, hm), held) in self.data.sqrt_w.iter().zip(&self.data.hm).zip(self.held) {
            sum += (hm - held - fast.h(s)).norm_sqr().sqrt();
        }
        let sum = sum * self.data.scale;
        Ok(if sum.is_finite() { sum } else { f64::INFINITY })
    }
}

/// Indices of the lines of `band`: all of them, or, with more than `points`, those nearest to `points` evenly
/// spaced frequencies (as the per-mode fits sample their bands).
pub(super) fn band_lines(freqs: &[f64], band: &Band, points: usize) -> Vec<usize> {
    let a = freqs.partition_point(|&f| f < band.lo_hz);
    let e = freqs.partition_point(|&f| f <= band.hi_hz);
    if e - a <= points {
        return (a..e).collect();
    }
    let mut v: Vec<usize> = (0..points).map(|p| a + (p * (e - a - 1) + (points - 1) / 2) / (points - 1)).collect();
    v.dedup();
    v
}

/// Result of [`refit_beams`]: the beams and the sweeps run.
pub(super) struct Refit {
    pub beams: Vec<EquivalentBeam>,
    pub sweeps: usize,
}

/// Refits `beams` (one per band, same order) jointly against `h` on `freqs`: each beam's `(d, η, f)` on its
/// band's lines (at most `points` and [`REFIT_POINTS`]) with the other beams held, at most [`REFIT_ITERATIONS`] sweeps, keeping the
/// set with the lowest summed objective `Σ_bands Σ|H^m − Σ H_beam| / Σ|H^m|`. A beam's frequency stays inside
/// its band. The result is never worse than the input.
pub(super) fn refit_beams(
    freqs: &[f64],
    h: &[Complex64],
    bands: &[Band],
    beams: &[EquivalentBeam],
    material: &Material,
    points: usize,
) -> Refit {
    let data: Vec<BandData> = bands
        .iter()
        .map(|b| {
            let lines = band_lines(freqs, b, points.min(REFIT_POINTS));
            let hm: Vec<Complex64> = lines.iter().map(|&k| h[k]).collect();
            let sum: f64 = hm.iter().map(|v| v.norm()).sum();
            BandData {
                sqrt_w: lines.iter().map(|&k| (TAU * freqs[k]).sqrt()).collect(),
                hm,
                scale: if sum > 0.0 { 1.0 / sum } else { 1.0 },
            }
        })
        .collect();
    let n = beams.len();
    // contrib[i][j]: beam i's H on band j's lines.
    let on_bands = |beam: FixedFreeBeam| -> Vec<Vec<Complex64>> {
        let fast = FastH::new(beam);
        data.iter().map(|d| d.sqrt_w.iter().map(|&s| fast.h(s)).collect()).collect()
    };
    let mut contrib: Vec<Vec<Vec<Complex64>>> = beams.iter().map(|b| on_bands(b.beam)).collect();
    let total = |contrib: &[Vec<Vec<Complex64>>]| -> f64 {
        data.iter()
            .enumerate()
            .map(|(j, d)| {
                let r: f64 =
                    d.hm.iter()
                        .enumerate()
                        .map(|(k, hm)| {
                            let sum: Complex64 = contrib.iter().map(|c| c[j][k]).sum();
                            (hm - sum).norm_sqr().sqrt()
                        })
                        .sum();
                r * d.scale
            })
            .sum()
    };
    let before = total(&contrib);
    let mut best = (beams.to_vec(), before);
    let mut current = beams.to_vec();
    let mut sweeps = 0;
    let mut held = Vec::new();
    while sweeps < REFIT_ITERATIONS {
        sweeps += 1;
        for j in 0..n {
            let d = &data[j];
            held.clear();
            held.extend(
                (0..d.hm.len()).map(|k| (0..n).filter(|&i| i != j).map(|i| contrib[i][j][k]).sum::<Complex64>()),
            );
            let b = current[j].beam;
            let f0 = current[j].f_hz;
            let cost =
                BeamRefitCost { data: d, held: &held, material: *material, f_lo: bands[j].lo_hz, f_hi: bands[j].hi_hz };
            let z0 = vec![b.d_m.ln(), b.eta.max(1e-12).ln(), f0.ln()];
            let simplex = vec![
                z0.clone(),
                vec![z0[0] + 0.02, z0[1], z0[2]],
                vec![z0[0], z0[1] + 0.05, z0[2]],
                vec![z0[0], z0[1], z0[2] + 0.002],
            ];
            // The tolerance is valid and the cost never errors (a bad point costs ∞); should either step fail,
            // the beam is kept as it is.
            let Ok(solver) = NelderMead::new(simplex).with_sd_tolerance(1e-9) else {
                continue;
            };
            let Ok(res) = Executor::new(cost, solver).configure(|s| s.max_iters(MAX_ITERS)).timer(false).run() else {
                continue;
            };
            let Some(z) = res.state().get_best_param().cloned() else {
                continue;
            };
            let check =
                BeamRefitCost { data: d, held: &held, material: *material, f_lo: bands[j].lo_hz, f_hi: bands[j].hi_hz };
            if let Some(beam) = check.beam(&z) {
                current[j] = EquivalentBeam { f_hz: z[2].exp(), beam };
                contrib[j] = on_bands(beam);
            }
        }
        let t = total(&contrib);
        let improved = t < best.1;
        let enough = best.1 - t > IMPROVEMENT * best.1;
        if improved {
            best = (current.clone(), t);
        }
        if !enough {
            break;
        }
    }
    Refit { beams: best.0, sweeps }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_h_is_the_beams_tip_h() {
        let beam = FixedFreeBeam::equivalent(1100.0, 0.05, 0.06, Material::STEEL).unwrap();
        let fast = FastH::new(beam);
        for f in [1.0, 200.0, 600.0, 1000.0, 1100.0, 1300.0, 3000.0, 6900.0, 20_000.0] {
            let w: f64 = TAU * f;
            let want = beam.tip_receptance(w).h;
            let got = fast.h(w.sqrt());
            assert!((got - want).norm() <= 1e-10 * want.norm(), "{f} Hz: {got} vs {want}");
            let (block, full) = (fast.block(w.sqrt()), beam.tip_receptance(w));
            for (a, b) in [(block.h, full.h), (block.l, full.l), (block.n, full.n), (block.p, full.p)] {
                assert!((a - b).norm() <= 1e-10 * b.norm(), "{f} Hz: {a} vs {b}");
            }
        }
    }
}
