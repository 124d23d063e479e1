//! Steps 2–4 of §5.2: per-mode Nelder–Mead fits on Eq. 5.13 bands, floating modes (Eqs. 5.14–5.15), global
//! iterations with the other modes held and deletion of modes stuck at their bounds.
//!
//! Bounds are handled as in a bounded simplex search (the `fminsearchbnd` transform): each bounded variable
//! `x ∈ [lo, hi]` is searched as an unbounded `z` with `x = lo + (hi − lo)(1 + sin z)/2`, so every point the
//! simplex visits is feasible and a variable that wants to leave its range settles on the bound, which is
//! what §5.2.4.1 looks for. The variables are the natural frequency (bounded by the mode's band), the damping
//! ratio and the logarithm of the modal mass.

use super::lsfd::{pair_basis, pair_h, pole, real_residue};
use super::pick::{Peak, moving_average};
use super::{Band, FitError, FitOptions, Mode, Residues, mode_bands, mode_h};

/// Modes (by frequency), their residues, their bands, the deleted modes and the global iterations run.
type Identified = (Vec<Mode>, Vec<Complex64>, Vec<Band>, Vec<Mode>, usize);
use argmin::core::{CostFunction, Error as ArgminError, Executor, State};
use argmin::solver::neldermead::NelderMead;
use num_complex::Complex64;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::TAU;
use std::ops::Range;

/// Damping-ratio bounds of every mode.
const XI_BOUNDS: (f64, f64) = (1e-4, 0.3);
/// A fitted mode's mass may move this factor either way from its step-1 estimate.
const MASS_SPAN: f64 = 100.0;
/// A variable within this fraction of its range from a bound is "at the bound" (§5.2.4.1).
const STUCK: f64 = 1e-3;
/// Relative change of the summed objective below which the global iterations have converged.
const CONVERGED: f64 = 1e-7;

/// Box of the search variables `(f Hz, ξ, ln M)`.
#[derive(Debug, Clone, Copy)]
struct Bounds {
    lo: [f64; 3],
    hi: [f64; 3],
}

impl Bounds {
    fn x_at(self, z: &[f64]) -> [f64; 3] {
        std::array::from_fn(|i| self.lo[i] + (self.hi[i] - self.lo[i]) * 0.5 * (1.0 + z[i].sin()))
    }

    fn z_at(self, x: [f64; 3]) -> Vec<f64> {
        (0..3).map(|i| (2.0 * (x[i] - self.lo[i]) / (self.hi[i] - self.lo[i]) - 1.0).clamp(-1.0, 1.0).asin()).collect()
    }

    /// Whether any of the first `dims` variables sits at a bound. A damping ratio at its lower
    /// bound is not, when that bound lies below `xi_resolved`, the damping whose half-power width
    /// `2ξf` is one line: such a mode is sharper than the lines can show, not a spurious one.
    fn stuck(self, x: [f64; 3], dims: usize, xi_resolved: f64) -> bool {
        (0..dims).any(|i| {
            let u = (x[i] - self.lo[i]) / (self.hi[i] - self.lo[i]);
            if i == 1 && u < STUCK && self.lo[1] < xi_resolved {
                return false;
            }
            !(STUCK..=1.0 - STUCK).contains(&u)
        })
    }
}

/// The mode at `x`; `sign` is the sign of its modal constant (−1: a transfer FRF's mode whose
/// response and reference move in opposite senses), the search variable is `ln |M|`.
fn params_of(x: [f64; 3], sign: f64) -> Mode {
    Mode { freq_hz: x[0], damping_ratio: x[1], modal_mass: sign * x[2].exp() }
}

fn x_of(m: &Mode) -> [f64; 3] {
    [m.freq_hz, m.damping_ratio, m.modal_mass.abs().ln()]
}

/// One mode being fitted with its band data.
struct Slot {
    mode: Mode,
    /// Sign of the modal constant (+1 for every mode of a driving point).
    sign: f64,
    /// Residue of the mode's pole pair (complex residues only; the Eq. 5.8 value otherwise).
    residue: Complex64,
    band: Band,
    bounds: Bounds,
    /// Angular frequencies of the band points, rad/s.
    w: Vec<f64>,
    /// Measured (interpolated) receptance at the band points.
    hm: Vec<Complex64>,
    /// The other modes' contribution at the band points (step 4).
    held: Vec<Complex64>,
    /// `1/Σ|H^m|` and `1/Σ|Im H^m|` over the band points: objectives are relative.
    scale: f64,
    scale_im: f64,
    /// `1/sqrt(Σ|H^m|²)` over the band points (the complex-residue objective is a relative L2 residual).
    scale_l2: f64,
}

impl Slot {
    fn new(mode: Mode, band: Band, bounds: Bounds, freqs: &[f64], h: &[Complex64], points: usize) -> Self {
        let a = freqs.partition_point(|&f| f < band.lo_hz);
        let e = freqs.partition_point(|&f| f <= band.hi_hz);
        // Bands with more lines than `points` keep the measured lines nearest to `points` evenly spaced
        // frequencies (interpolating between lines would flatten a sharp resonance and bias its damping up).
        let picks: Vec<usize> = if e - a <= points {
            (a..e).collect()
        } else {
            let mut v: Vec<usize> =
                (0..points).map(|p| a + (p * (e - a - 1) + (points - 1) / 2) / (points - 1)).collect();
            v.dedup();
            v
        };
        let fs: Vec<f64> = picks.iter().map(|&k| freqs[k]).collect();
        let hm: Vec<Complex64> = picks.iter().map(|&k| h[k]).collect();
        let sum: f64 = hm.iter().map(|v| v.norm()).sum();
        let sum_im: f64 = hm.iter().map(|v| v.im.abs()).sum();
        let sum_sq: f64 = hm.iter().map(|v| v.norm_sqr()).sum();
        let n = fs.len();
        Slot {
            mode,
            sign: if mode.modal_mass < 0.0 { -1.0 } else { 1.0 },
            residue: real_residue(&mode),
            band,
            bounds,
            w: fs.iter().map(|f| TAU * f).collect(),
            hm,
            held: vec![Complex64::new(0.0, 0.0); n],
            scale: if sum > 0.0 { 1.0 / sum } else { 1.0 },
            scale_im: if sum_im > 0.0 { 1.0 / sum_im } else { 1.0 },
            scale_l2: if sum_sq > 0.0 { 1.0 / sum_sq.sqrt() } else { 1.0 },
        }
    }
}

/// The objective of one mode: Eq. 5.9 summed over the band points (complex residual norm, with the other
/// modes held), or in step 2 only the imaginary part's residual.
struct ModeCost<'a> {
    w: &'a [f64],
    hm: &'a [Complex64],
    held: &'a [Complex64],
    bounds: Bounds,
    imag_only: bool,
    scale: f64,
    /// Sign of the modal constant.
    sign: f64,
}

impl CostFunction for ModeCost<'_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, z: &Self::Param) -> Result<f64, ArgminError> {
        let x = self.bounds.x_at(z);
        let (wn, xi, m) = (TAU * x[0], x[1], self.sign * x[2].exp());
        let mut sum = 0.0;
        if self.imag_only {
            for (&w, hm) in self.w.iter().zip(self.hm) {
                sum += (hm.im - mode_h(m, wn, xi, w).im).abs();
            }
        } else {
            for ((&w, hm), held) in self.w.iter().zip(self.hm).zip(self.held) {
                // sqrt of the squared modulus: `norm()` goes through `hypot`, several times slower.
                sum += (hm - held - mode_h(m, wn, xi, w)).norm_sqr().sqrt();
            }
        }
        Ok(sum * self.scale)
    }
}

/// The variable-projection objective of one mode with a complex residue: for the pole of `(f, ξ)` the residue
/// `A` minimising `Σ|R − A/(iω − λ) − Ā/(iω − λ̄)|²` on the band (`R = H^m −` the other modes) is a 2×2 linear
/// least-squares problem, so the simplex searches `(f, ξ)` only; the cost is the relative L2 residual.
struct ComplexModeCost<'a> {
    w: &'a [f64],
    /// `H^m` minus the other modes at the band points.
    r: &'a [Complex64],
    /// `Σ|R|²`.
    rr: f64,
    bounds: Bounds,
    /// `1/sqrt(Σ|H^m|²)`.
    scale: f64,
}

impl ComplexModeCost<'_> {
    /// Best residue for the pole at `z` and the squared residual it leaves.
    fn project(&self, z: &[f64]) -> (Complex64, f64) {
        let at = |i: usize| self.bounds.lo[i] + (self.bounds.hi[i] - self.bounds.lo[i]) * 0.5 * (1.0 + z[i].sin());
        let mode = Mode { freq_hz: at(0), damping_ratio: at(1), modal_mass: 1.0 };
        let lambda = pole(&mode);
        let (mut guu, mut guv, mut gvv, mut bu, mut bv) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (&w, r) in self.w.iter().zip(self.r) {
            let (u, v) = pair_basis(lambda, w);
            guu += u.norm_sqr();
            gvv += v.norm_sqr();
            guv += u.re * v.re + u.im * v.im;
            bu += r.re * u.re + r.im * u.im;
            bv += r.re * v.re + r.im * v.im;
        }
        let det = guu * gvv - guv * guv;
        if det.is_nan() || det <= 1e-14 * guu * gvv {
            return (Complex64::new(0.0, 0.0), self.rr);
        }
        let a = (gvv * bu - guv * bv) / det;
        let b = (guu * bv - guv * bu) / det;
        (Complex64::new(a, b), (self.rr - a * bu - b * bv).max(0.0))
    }
}

impl CostFunction for ComplexModeCost<'_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, z: &Self::Param) -> Result<f64, ArgminError> {
        Ok(self.project(z).1.sqrt() * self.scale)
    }
}

/// Runs argmin's Nelder–Mead from `z0` with an initial simplex of axis steps `step`; returns the best point
/// and its cost.
fn nelder_mead<C: CostFunction<Param = Vec<f64>, Output = f64>>(
    cost: C,
    z0: Vec<f64>,
    step: f64,
    max_iters: u64,
    f_hz: f64,
) -> Result<(Vec<f64>, f64), FitError> {
    let mut simplex = vec![z0.clone()];
    for i in 0..z0.len() {
        let mut z = z0.clone();
        z[i] += step;
        simplex.push(z);
    }
    let fail = |e: ArgminError| FitError::Optimiser { f_hz, message: e.to_string() };
    let solver = NelderMead::new(simplex).with_sd_tolerance(1e-7).map_err(fail)?;
    let res = Executor::new(cost, solver).configure(|s| s.max_iters(max_iters)).timer(false).run().map_err(fail)?;
    let state = res.state();

    let best = state.get_best_param().cloned().unwrap_or(z0);
    Ok((best, state.get_best_cost()))
}

/// Step-1 estimate of a mode from its peak: ξ from the half-height width of the smoothed Im(H)
/// (`Δf ≈ 2ξf` for Eq. 5.8), then `M` from the peak `|Im H| = 1/(2ξ M ω²)`.
fn initial_mode(peak: &Peak, smooth: &[f64], offset: usize, freqs: &[f64], band: &Band) -> Mode {
    let i = peak.index - offset;
    let half = 0.5 * peak.im;
    // The peak turned downwards whatever the sign of its modal constant.
    let at = |k: usize| smooth[k] * peak.sign;
    let mut a = i;
    while a > 0 && at(a - 1) < half && freqs[offset + a - 1] >= band.lo_hz {
        a -= 1;
    }
    let mut b = i;
    while b + 1 < smooth.len() && at(b + 1) < half && freqs[offset + b + 1] <= band.hi_hz {
        b += 1;
    }
    let width =
        (freqs[offset + b] - freqs[offset + a]).max(freqs[offset + i.min(smooth.len() - 2) + 1] - freqs[offset + i]);
    let xi = (width / (2.0 * peak.freq_hz)).clamp(0.002, 0.2);
    let w = TAU * peak.freq_hz;
    Mode { freq_hz: peak.freq_hz, damping_ratio: xi, modal_mass: peak.sign / (2.0 * xi * w * w * peak.im.abs()) }
}

fn bounds_for(band: &Band, mass: f64, mass_lo: f64, mass_hi: f64) -> Bounds {
    Bounds {
        lo: [band.lo_hz, XI_BOUNDS.0, (mass * mass_lo).ln()],
        hi: [band.hi_hz, XI_BOUNDS.1, (mass * mass_hi).ln()],
    }
}

/// Floating modes of §5.2.3: counts and ranges by Eqs. 5.14–5.15 around the three deepest peaks, frequencies
/// uniform in `f_k ± 200 Hz`, damping uniform in `[0.005, 0.03]`, masses log-uniform between 1 and 100 times
/// the most flexible mode's (the text's absolute 0–3 kg suits its artifact only).
fn floating(peaks: &[Peak], reference_mass: f64, lo: f64, hi: f64, seed: u64) -> Vec<Mode> {
    let mut order: Vec<&Peak> = peaks.iter().collect();
    order.sort_by(|a, b| a.im.total_cmp(&b.im));
    let im = |k: usize| order.get(k).map_or(0.0, |p| p.im.abs());
    let rat = |k: usize| if im(k) > 0.0 { im(0) / im(k) } else { f64::INFINITY };
    let (rat1, rat2) = (rat(1), rat(2));
    let counts: [usize; 3] = if rat1 > 2.0 && rat2 > 2.0 {
        [30, 18, 12]
    } else if rat1 < 2.0 && rat2 > 2.0 {
        [24, 16, 0]
    } else {
        [20, 0, 0]
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    for (k, &count) in counts.iter().enumerate() {
        // Ranges without a peak give their modes to the deepest peak's range.
        let centre = order.get(k).unwrap_or(&order[0]).freq_hz;
        for _ in 0..count {
            let f = (centre + rng.random_range(-200.0..200.0)).clamp(lo, hi);
            let xi = rng.random_range(0.005..0.03);
            let m = reference_mass * 10f64.powf(rng.random_range(0.0..2.0));
            out.push(Mode { freq_hz: f, damping_ratio: xi, modal_mass: m });
        }
    }
    out
}

/// Steps 2–4: returns the modes (by frequency), their bands, the deleted modes and the iterations run.
pub(super) fn fit_modes(
    freqs: &[f64],
    h: &[Complex64],
    range: Range<usize>,
    peaks: &[Peak],
    opts: &FitOptions,
) -> Result<Identified, FitError> {
    let (lo, hi) = (freqs[range.start], freqs[range.end - 1]);
    let df = (hi - lo) / (range.len() - 1) as f64;
    let centres: Vec<f64> = peaks.iter().map(|p| p.freq_hz).collect();
    let bands = mode_bands(&centres, lo, hi, df);
    let im: Vec<f64> = h[range.clone()].iter().map(|v| v.im).collect();
    let mut smooth = Vec::new();
    moving_average(&im, opts.h_sens, &mut smooth);

    // Step 2: each mode alone on its band, imaginary part only.
    let mut slots = Vec::with_capacity(peaks.len());
    for (peak, band) in peaks.iter().zip(&bands) {
        let m0 = initial_mode(peak, &smooth, range.start, freqs, band);
        let bounds = bounds_for(band, m0.modal_mass.abs(), 1.0 / MASS_SPAN, MASS_SPAN);
        let mut slot = Slot::new(m0, *band, bounds, freqs, h, opts.band_points);
        let cost = ModeCost {
            w: &slot.w,
            hm: &slot.hm,
            held: &slot.held,
            bounds,
            imag_only: true,
            scale: slot.scale_im,
            sign: slot.sign,
        };
        let (z, _) = nelder_mead(cost, bounds.z_at(x_of(&m0)), 0.2, 400, m0.freq_hz)?;
        slot.mode = params_of(bounds.x_at(&z), slot.sign);
        slot.residue = real_residue(&slot.mode);
        slots.push(slot);
    }

    // Step 3: floating modes, each on its own ±200 Hz band.
    if opts.floating_modes {
        let reference = slots
            .iter()
            .zip(peaks)
            .min_by(|a, b| a.1.im.total_cmp(&b.1.im))
            .map_or(1.0, |(s, _)| s.mode.modal_mass.abs());
        for m in floating(peaks, reference, lo, hi, opts.seed) {
            let band = mode_bands(&[m.freq_hz], lo, hi, df)[0];
            let bounds = bounds_for(&band, reference, 0.1, 1e4);
            slots.push(Slot::new(m, band, bounds, freqs, h, opts.band_points));
        }
    }

    // Step 4: global iterations, each mode refitted with the others held (Eq. 5.9).
    let mut deleted = Vec::new();
    let mut deletion_done = opts.delete_after >= opts.iterations;
    let mut previous = f64::INFINITY;
    let mut iterations = 0;
    let dims = if opts.residues == Residues::Complex { 2 } else { 3 };
    let mut current = snapshot(&slots);
    let complex = opts.residues == Residues::Complex;
    while iterations < opts.iterations {
        let mut total = 0.0;
        // With complex residues the modes outside the band enter through the LSFD residual terms of the current
        // poles, held like the other modes.
        let (lower, upper) = if complex {
            let modes: Vec<Mode> = current.iter().map(|c| c.0).collect();
            let r = super::lsfd::lsfd(&freqs[range.clone()], &h[range.clone()], &modes)?;
            (r.lower, r.upper)
        } else {
            (0.0, 0.0)
        };
        for j in 0..slots.len() {
            let slot = &mut slots[j];
            slot.hold_others(j, &current, complex, (lower, upper));
            total += slot.refit(complex, opts.signed)?;
            current[j] = (slot.mode, slot.residue, pole(&slot.mode));
        }
        iterations += 1;
        let converged = (previous - total).abs() <= CONVERGED * total;
        previous = total;
        if !deletion_done && (iterations >= opts.delete_after || converged) {
            deletion_done = true;
            let before = slots.len();
            let (kept, stuck): (Vec<Slot>, Vec<Slot>) =
                slots.drain(..).partition(|s| !s.bounds.stuck(x_of(&s.mode), dims, df / (2.0 * s.mode.freq_hz)));
            deleted.extend(stuck.iter().map(|s| s.mode));
            slots = kept;
            current = snapshot(&slots);
            if slots.len() < before {
                previous = f64::INFINITY;
                continue;
            }
        }
        if converged {
            break;
        }
    }
    if slots.is_empty() {
        return Err(FitError::NothingLeft {
            method: "simplex",
            why: format!("all {} modes ended at their bounds and were deleted", deleted.len()),
        });
    }
    slots.sort_by(|a, b| a.mode.freq_hz.total_cmp(&b.mode.freq_hz));
    let modes = slots.iter().map(|s| s.mode).collect();
    let residues = slots.iter().map(|s| s.residue).collect();
    let bands = slots.iter().map(|s| s.band).collect();
    Ok((modes, residues, bands, deleted, iterations))
}

/// Each slot's mode, residue and pole as they stand.
fn snapshot(slots: &[Slot]) -> Vec<(Mode, Complex64, Complex64)> {
    slots.iter().map(|s| (s.mode, s.residue, pole(&s.mode))).collect()
}

impl Slot {
    /// Sets the receptance the other modes give on this slot's lines (`current` without mode `j`):
    /// with complex residues their pole pairs and the LSFD residual terms `(lower, upper)`, else
    /// their real modes.
    fn hold_others(
        &mut self,
        j: usize,
        current: &[(Mode, Complex64, Complex64)],
        complex: bool,
        residuals: (f64, f64),
    ) {
        let (lower, upper) = residuals;
        for (held, &w) in self.held.iter_mut().zip(&self.w) {
            *held = if complex {
                current
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| *i != j)
                    .map(|(_, (_, a, l))| pair_h(*a, *l, w))
                    .sum::<Complex64>()
                    - lower / (w * w)
                    + upper
            } else {
                current
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| *i != j)
                    .map(|(_, (m, _, _))| mode_h(m.modal_mass, TAU * m.freq_hz, m.damping_ratio, w))
                    .sum()
            };
        }
    }

    /// Refits this slot's mode against the measurement less the held modes (Eq. 5.9): frequency and
    /// damping by the simplex with the complex residue projected out, or the real mode's three
    /// parameters. Returns the cost reached.
    fn refit(&mut self, complex: bool, signed: bool) -> Result<f64, FitError> {
        if complex {
            let r: Vec<Complex64> = self.hm.iter().zip(&self.held).map(|(a, b)| a - b).collect();
            let rr = r.iter().map(|v| v.norm_sqr()).sum();
            let cost = ComplexModeCost { w: &self.w, r: &r, rr, bounds: self.bounds, scale: self.scale_l2 };
            let z0 = self.bounds.z_at(x_of(&self.mode))[..2].to_vec();
            let (z, c) = nelder_mead(cost, z0, 0.05, 200, self.mode.freq_hz)?;
            let cost = ComplexModeCost { w: &self.w, r: &r, rr, bounds: self.bounds, scale: self.scale_l2 };
            let (a, _) = cost.project(&z);
            let x = self.bounds.x_at(&[z[0], z[1], 0.0]);
            self.mode = if signed {
                super::lsfd::signed_mode_of_residue(x[0], x[1], a)
            } else {
                super::lsfd::mode_of_residue(x[0], x[1], a)
            };
            self.residue = a;
            Ok(c)
        } else {
            let cost = ModeCost {
                w: &self.w,
                hm: &self.hm,
                held: &self.held,
                bounds: self.bounds,
                imag_only: false,
                scale: self.scale,
                sign: self.sign,
            };
            let (z, c) = nelder_mead(cost, self.bounds.z_at(x_of(&self.mode)), 0.05, 200, self.mode.freq_hz)?;
            self.mode = params_of(self.bounds.x_at(&z), self.sign);
            self.residue = real_residue(&self.mode);
            Ok(c)
        }
    }
}
