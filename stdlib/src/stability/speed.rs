//! Speed-dependent stability lobes (dissertation §6.1–6.3): tool-point FRFs measured at a few spindle speeds and
//! cutting coefficients measured over speed are interpolated with natural cubic splines onto a fine speed grid
//! (every 5 rpm by default), and at each fine speed `Ω` the ZOA limit is taken *at that speed only*: the lowest of
//! the lobes passing through `Ω`, built from `FRF(Ω)` and the coefficients at `Ω`.

use super::StabilityError;
use super::cutting::{CuttingCoefficients, Milling, MillingDirection};
use super::zoa::{
    FrfSlices, LimitScratch, StabilityLimit, ToolPointFrf, band_top_hz, limit_at_speed_pruned, lobe_count,
    lobes_needed, refine,
};
use num_complex::Complex64;
use rayon::prelude::*;

/// A tool-point FRF pair measured at one spindle speed.
#[derive(Debug, Clone, PartialEq)]
pub struct SpeedFrf {
    /// Spindle speed, rpm.
    pub speed_rpm: f64,
    /// The FRFs at that speed.
    pub frf: ToolPointFrf,
}

/// Cutting coefficients measured over speed, rows `[speed rpm, a, b]` in increasing speed.
#[derive(Debug, Clone, PartialEq)]
pub enum CoefficientTable {
    /// `a = Kt`, `b = Kn`, N/m².
    KtKn(Vec<[f64; 3]>),
    /// `a = Ks` (N/m²), `b = β` (rad): `Kt = Ks sin β`, `Kn = Ks cos β` after interpolation.
    KsBeta(Vec<[f64; 3]>),
}

/// Options of [`speed_dependent_lobes`].
#[derive(Debug, Clone, PartialEq)]
pub struct SpeedDependentOptions {
    /// Speed range, rpm; `None` spans the measured FRF speeds. Speeds ≤ 0 of the grid are skipped.
    pub range_rpm: Option<(f64, f64)>,
    /// Grid step, rpm.
    pub step_rpm: f64,
    /// Number of lobes; `None` takes as many as the FRFs' band needs down to the lowest speed
    /// ([`super::lobes_needed`]).
    pub lobes: Option<usize>,
    /// Extend the end cubics beyond the measured speeds instead of refusing.
    pub allow_extrapolation: bool,
    /// Explicit ascending speeds (rpm) instead of the range and step: the limit at each
    /// speed is computed on its own, so a diagram at the trials' speeds scores them exactly.
    pub speeds_rpm: Option<Vec<f64>>,
    /// The coarsest line spacing the lobes are resolved at, Hz ([`super::zoa::refine`]); `None` takes the grid
    /// as it is.
    pub resolution_hz: Option<f64>,
}

impl Default for SpeedDependentOptions {
    fn default() -> Self {
        SpeedDependentOptions {
            range_rpm: None,
            step_rpm: 5.0,
            lobes: None,
            allow_extrapolation: false,
            speeds_rpm: None,
            resolution_hz: Some(super::zoa::DEFAULT_RESOLUTION_HZ),
        }
    }
}

/// The speed-dependent limit next to the stationary one on the same speeds.
#[derive(Debug, Clone, PartialEq)]
pub struct SpeedDependentLimit {
    /// With the FRF and coefficients interpolated at each speed.
    pub speed_dependent: StabilityLimit,
    /// With the stationary FRF and the coefficients interpolated at each speed.
    pub stationary: StabilityLimit,
    /// The number of lobes solved (the explicit count, or the automatic one).
    pub lobe_count: usize,
    /// The lobes the FRFs' band of significant response needs down to the slowest speed.
    pub lobes_needed: usize,
    /// The highest frequency of significant response over every FRF, Hz.
    pub band_top_hz: f64,
}

/// Natural cubic spline weights: the spline through `(knots[j], y_j)` at `s` is `Σ w_j y_j`.
pub(crate) fn spline_weights(knots: &[f64], s: f64) -> Vec<f64> {
    let k = knots.len();
    if k == 1 {
        return vec![1.0];
    }
    let i = knots.partition_point(|&x| x <= s).clamp(1, k - 1) - 1;
    let h = knots[i + 1] - knots[i];
    let a = (knots[i + 1] - s) / h;
    let b = 1.0 - a;
    let (ca, cb) = ((a * a * a - a) * h * h / 6.0, (b * b * b - b) * h * h / 6.0);
    let mut w = vec![0.0; k];
    w[i] += a;
    w[i + 1] += b;
    if k == 2 {
        return w;
    }
    // Second derivatives M = S y for each unit data vector: solve the tridiagonal system (Thomas).
    let interior = k - 2;
    let (mut sub, mut diag, mut sup) = (vec![0.0; interior], vec![0.0; interior], vec![0.0; interior]);
    for r in 0..interior {
        let (h0, h1) = (knots[r + 1] - knots[r], knots[r + 2] - knots[r + 1]);
        sub[r] = h0;
        diag[r] = 2.0 * (h0 + h1);
        sup[r] = h1;
    }
    let mut rhs = vec![0.0; interior];
    let mut cp = vec![0.0; interior];
    #[allow(clippy::needless_range_loop)]
    for j in 0..k {
        for (r, v) in rhs.iter_mut().enumerate() {
            let (h0, h1) = (knots[r + 1] - knots[r], knots[r + 2] - knots[r + 1]);
            let e = |q: usize| if q == j { 1.0 } else { 0.0 };
            *v = 6.0 * ((e(r + 2) - e(r + 1)) / h1 - (e(r + 1) - e(r)) / h0);
        }
        // Forward sweep.
        cp[0] = sup[0] / diag[0];
        rhs[0] /= diag[0];
        for r in 1..interior {
            let den = diag[r] - sub[r] * cp[r - 1];
            cp[r] = sup[r] / den;
            rhs[r] = (rhs[r] - sub[r] * rhs[r - 1]) / den;
        }
        for r in (0..interior.saturating_sub(1)).rev() {
            rhs[r] -= cp[r] * rhs[r + 1];
        }
        let m_at = |q: usize| if q == 0 || q == k - 1 { 0.0 } else { rhs[q - 1] };
        w[j] += ca * m_at(i) + cb * m_at(i + 1);
    }
    w
}

/// The natural cubic spline's tridiagonal system in the second derivatives at the interior knots
/// (sub-diagonal `h0`, diagonal `2(h0 + h1)`, super-diagonal `h1`), factored once by the Thomas
/// algorithm: `cp` the modified super-diagonal, `den` the pivots.
struct SplineSystem {
    h: Vec<f64>,
    cp: Vec<f64>,
    den: Vec<f64>,
}

impl SplineSystem {
    fn new(knots: &[f64]) -> Self {
        let h: Vec<f64> = knots.windows(2).map(|w| w[1] - w[0]).collect();
        let interior = knots.len().saturating_sub(2);
        let (mut cp, mut den) = (vec![0.0; interior], vec![0.0; interior]);
        for r in 0..interior {
            let (l, d, u) = (h[r], 2.0 * (h[r] + h[r + 1]), h[r + 1]);
            den[r] = if r == 0 { d } else { d - l * cp[r - 1] };
            cp[r] = u / den[r];
        }
        SplineSystem { h, cp, den }
    }

    /// The second derivatives at every knot (zero at the ends) of the splines through `y[knot][line]`,
    /// all lines at once: `O(knots × lines)`.
    fn second_derivatives(&self, y: &[&[Complex64]], lines: usize) -> Vec<Vec<Complex64>> {
        let k = y.len();
        let zero = Complex64::new(0.0, 0.0);
        if k < 3 {
            return vec![vec![zero; lines]; k];
        }
        let h = &self.h;
        let mut m: Vec<Vec<Complex64>> = Vec::with_capacity(k);
        m.push(vec![zero; lines]);
        // Forward sweep: m[r + 1] holds the eliminated right-hand side of interior row r.
        for r in 0..k - 2 {
            let (y0, y1, y2) = (&y[r][..lines], &y[r + 1][..lines], &y[r + 2][..lines]);
            let (g0, g1) = (6.0 / h[r], 6.0 / h[r + 1]);
            let (l, inv) = (if r == 0 { 0.0 } else { h[r] }, 1.0 / self.den[r]);
            let left = &m[r];
            let row: Vec<Complex64> =
                (0..lines).map(|j| ((y2[j] - y1[j]) * g1 - (y1[j] - y0[j]) * g0 - l * left[j]) * inv).collect();
            m.push(row);
        }
        m.push(vec![zero; lines]);
        // Back substitution.
        for r in (0..k - 3).rev() {
            let (head, tail) = m.split_at_mut(r + 2);
            let (row, next) = (&mut head[r + 1], &tail[0]);
            let c = self.cp[r];
            row.iter_mut().zip(next).for_each(|(v, n)| *v -= c * n);
        }
        m
    }
}

/// The FRFs of all measured speeds with their spline second derivatives per line, so that the natural cubic
/// spline at any speed costs four complex multiply-adds per line and series.
struct SplineFrf<'a> {
    knots: &'a [f64],
    /// Per series (xx, yy, xy, yx) and knot: the values and the second derivatives, each per line.
    values: Vec<Vec<&'a [Complex64]>>,
    second: Vec<Vec<Vec<Complex64>>>,
}

#[derive(Default)]
struct SpeedScratch {
    xx: Vec<Complex64>,
    yy: Vec<Complex64>,
    xy: Vec<Complex64>,
    yx: Vec<Complex64>,
    limit: LimitScratch,
}

impl<'a> SplineFrf<'a> {
    fn new(knots: &'a [f64], frfs: &'a [SpeedFrf], with_cross: bool) -> Self {
        let system = SplineSystem::new(knots);
        let mut values: Vec<Vec<&'a [Complex64]>> =
            vec![frfs.iter().map(|f| &f.frf.xx[..]).collect(), frfs.iter().map(|f| &f.frf.yy[..]).collect()];
        if with_cross {
            values.push(frfs.iter().map(|f| f.frf.cross.as_ref().map_or(&[][..], |c| &c.0[..])).collect());
            values.push(frfs.iter().map(|f| f.frf.cross.as_ref().map_or(&[][..], |c| &c.1[..])).collect());
        }
        let lines = frfs[0].frf.freqs_hz.len();
        let second = values.iter().map(|series| system.second_derivatives(series, lines)).collect();
        SplineFrf { knots, values, second }
    }

    /// The spline at speed `s` on the first `lines` lines into the scratch series.
    fn at(&self, s: f64, lines: usize, out: &mut SpeedScratch) {
        let k = self.knots.len();
        let targets = [&mut out.xx, &mut out.yy, &mut out.xy, &mut out.yx];
        if k == 1 {
            for (series, target) in self.values.iter().zip(targets) {
                target.clear();
                target.extend_from_slice(&series[0][..lines]);
            }
            return;
        }
        let knots = self.knots;
        let i = knots.partition_point(|&x| x <= s).clamp(1, k - 1) - 1;
        let h = knots[i + 1] - knots[i];
        let a = (knots[i + 1] - s) / h;
        let b = 1.0 - a;
        let (ca, cb) = ((a * a * a - a) * h * h / 6.0, (b * b * b - b) * h * h / 6.0);
        for ((series, second), target) in self.values.iter().zip(&self.second).zip(targets) {
            target.clear();
            let (y0, y1, m0, m1) = (&series[i][..lines], &series[i + 1][..lines], &second[i], &second[i + 1]);
            target.extend((0..lines).map(|j| a * y0[j] + b * y1[j] + (ca * m0[j] + cb * m1[j])));
        }
    }
}

fn check_knots(what: &'static str, knots: &[f64]) -> Result<(), StabilityError> {
    if knots.is_empty() {
        return Err(StabilityError::InvalidParameter { name: what, value: 0.0, requirement: "at least one speed" });
    }
    if let Some(i) = knots.iter().position(|s| !s.is_finite()) {
        return Err(StabilityError::NonFinite { what, index: i });
    }
    if let Some(i) = knots.windows(2).position(|w| w[1] <= w[0]) {
        return Err(StabilityError::InvalidParameter {
            name: what,
            value: knots[i + 1],
            requirement: "speeds must increase strictly",
        });
    }
    Ok(())
}

fn check_range(what: &'static str, knots: &[f64], s: f64, allow: bool) -> Result<(), StabilityError> {
    let (lo, hi) = (knots[0], knots[knots.len() - 1]);
    if !allow && (s < lo - 1e-9 * hi.abs() || s > hi + 1e-9 * hi.abs()) {
        return Err(StabilityError::Extrapolation { what, speed_rpm: s, lo_rpm: lo, hi_rpm: hi });
    }
    Ok(())
}

fn coefficients_at(table: &CoefficientTable, s: f64, allow: bool) -> Result<CuttingCoefficients, StabilityError> {
    let rows = match table {
        CoefficientTable::KtKn(r) | CoefficientTable::KsBeta(r) => r,
    };
    let knots: Vec<f64> = rows.iter().map(|r| r[0]).collect();
    check_knots("cutting coefficient speeds", &knots)?;
    check_range("cutting coefficient table", &knots, s, allow)?;
    let w = spline_weights(&knots, s);
    let a: f64 = w.iter().zip(rows).map(|(w, r)| w * r[1]).sum();
    let b: f64 = w.iter().zip(rows).map(|(w, r)| w * r[2]).sum();
    match table {
        CoefficientTable::KtKn(_) => CuttingCoefficients::from_kt_kn(a, b),
        CoefficientTable::KsBeta(_) => CuttingCoefficients::from_ks_beta(a, b),
    }
}

/// The tool-point FRF pair and the cutting coefficients at `speed_rpm`, from the same cubic
/// splines in speed as [`speed_dependent_lobes`] (§6.3): what a time-domain simulation of a cut
/// at that speed needs to check the diagram there. Direct terms only.
pub fn conditions_at(
    frfs: &[SpeedFrf],
    coefficients: &CoefficientTable,
    speed_rpm: f64,
    allow_extrapolation: bool,
) -> Result<(ToolPointFrf, CuttingCoefficients), StabilityError> {
    let knots: Vec<f64> = frfs.iter().map(|f| f.speed_rpm).collect();
    check_knots("FRF speeds", &knots)?;
    let grid = &frfs[0].frf.freqs_hz;
    if let Some(f) = frfs.iter().find(|f| f.frf.freqs_hz != *grid) {
        return Err(StabilityError::GridMismatch {
            what: "speed-dependent FRFs",
            detail: format!("the FRF at {} rpm is not on the grid of the FRF at {} rpm", f.speed_rpm, knots[0]),
        });
    }
    check_range("FRF speeds", &knots, speed_rpm, allow_extrapolation)?;
    let coeffs = coefficients_at(coefficients, speed_rpm, allow_extrapolation)?;
    let mut scratch = SpeedScratch::default();
    SplineFrf::new(&knots, frfs, false).at(speed_rpm, grid.len(), &mut scratch);
    Ok((ToolPointFrf::new(grid.clone(), scratch.xx, scratch.yy)?, coeffs))
}

/// Speed-dependent and stationary ZOA limits on the fine speed grid. `frfs` are the FRF pairs at increasing
/// speeds, all on one frequency grid (cross terms used only if every pair has them); `stationary` is the FRF of
/// the stationary limit (e.g. measured at rest), on any grid.
pub fn speed_dependent_lobes(
    frfs: &[SpeedFrf],
    coefficients: &CoefficientTable,
    teeth: usize,
    radial_immersion: f64,
    direction: MillingDirection,
    stationary: &ToolPointFrf,
    options: &SpeedDependentOptions,
) -> Result<SpeedDependentLimit, StabilityError> {
    let knots: Vec<f64> = frfs.iter().map(|f| f.speed_rpm).collect();
    check_knots("FRF speeds", &knots)?;
    for f in frfs {
        f.frf.validate()?;
    }
    stationary.validate()?;
    // FRFs that do not change with speed (one speed measured, or a spindle without a speed law) are one FRF
    // at every speed: it is refined and interpolated once. When it is also the stationary one (a tool measured
    // at rest), the two diagrams are one, computed once.
    let constant = frfs.iter().all(|f| f.frf == frfs[0].frf);
    let one_frf = constant && frfs[0].frf == *stationary;
    let distinct = if constant { &frfs[..1] } else { frfs };
    let refined: Vec<SpeedFrf> = distinct
        .iter()
        .map(|f| SpeedFrf { speed_rpm: f.speed_rpm, frf: refine(&f.frf, options.resolution_hz).into_owned() })
        .collect();
    let frfs = &refined[..];
    let stationary = if one_frf { &frfs[0].frf } else { &*refine(stationary, options.resolution_hz) };
    let grid = &frfs[0].frf.freqs_hz;
    for f in frfs {
        if f.frf.freqs_hz.len() != grid.len()
            || f.frf.freqs_hz.iter().zip(grid).any(|(a, b)| (a - b).abs() > 1e-9 * a.abs().max(b.abs()))
        {
            return Err(StabilityError::GridMismatch {
                what: "speed-dependent FRFs",
                detail: format!("the FRF at {} rpm is not on the grid of the FRF at {} rpm", f.speed_rpm, knots[0]),
            });
        }
    }
    if !(options.step_rpm.is_finite() && options.step_rpm > 0.0) {
        return Err(StabilityError::InvalidParameter {
            name: "speed step",
            value: options.step_rpm,
            requirement: "finite and > 0 rpm",
        });
    }
    let (lo, hi) = options.range_rpm.unwrap_or((knots[0], knots[knots.len() - 1]));
    if !(lo.is_finite() && hi.is_finite() && hi >= lo) {
        return Err(StabilityError::InvalidParameter {
            name: "speed range end",
            value: hi,
            requirement: "finite and not below the start",
        });
    }
    let speeds: Vec<f64> = match &options.speeds_rpm {
        Some(list) => list.iter().copied().filter(|&s| s > 0.0).collect(),
        None => {
            let count = ((hi - lo) / options.step_rpm + 1e-9).floor() as usize + 1;
            (0..count).map(|i| lo + options.step_rpm * i as f64).filter(|&s| s > 0.0).collect()
        }
    };
    // Probe the cutting setup once for its error (teeth, immersion) before the parallel loop.
    Milling::new(
        teeth,
        radial_immersion,
        direction,
        coefficients_at(
            coefficients,
            speeds.first().copied().unwrap_or(lo).max(knots[0]).min(knots[knots.len() - 1]),
            true,
        )?,
    )?;
    let band_top = frfs.iter().map(|f| band_top_hz(&f.frf)).fold(band_top_hz(stationary), f64::max);
    let n_min = speeds.first().copied().unwrap_or(f64::INFINITY);
    let needed = lobes_needed(band_top, teeth, n_min);
    let count = lobe_count(options.lobes, band_top, teeth, n_min)?;
    let with_cross = frfs.iter().all(|f| f.frf.cross.is_some());
    let curves = SplineFrf::new(&knots[..frfs.len()], frfs, with_cross);
    let per_tooth = 60.0 / teeth as f64;
    let rows: Vec<[(f64, f64, Option<usize>); 2]> = speeds
        .par_iter()
        .map_init(SpeedScratch::default, |scratch, &s| {
            check_range("FRF speeds", &knots, s, options.allow_extrapolation)?;
            let coeffs = coefficients_at(coefficients, s, options.allow_extrapolation)?;
            let milling = Milling::new(teeth, radial_immersion, direction, coeffs)?;
            // Lobes k < lobes pass this speed only on lines with f τ ≤ lobes (the phase fraction is below one),
            // so the eigenproblem is solved on those lines and the next one only.
            let tau = per_tooth / s;
            let needed = |freqs: &[f64]| freqs.partition_point(|&f| f * tau <= count as f64 + 1e-6) + 1;
            let lines = needed(grid).min(grid.len());
            curves.at(s, lines, scratch);
            let frf = FrfSlices {
                freqs_hz: &grid[..lines],
                xx: &scratch.xx,
                yy: &scratch.yy,
                cross: with_cross.then_some((&scratch.xy[..], &scratch.yx[..])),
            };
            let dynamic = limit_at_speed_pruned(frf, &milling, count, s, &mut scratch.limit);
            if one_frf {
                return Ok([dynamic, dynamic]);
            }
            let fixed_frf = stationary.slices(needed(&stationary.freqs_hz));
            let fixed = limit_at_speed_pruned(fixed_frf, &milling, count, s, &mut scratch.limit);
            Ok([dynamic, fixed])
        })
        .collect::<Result<_, StabilityError>>()?;
    let build = |which: usize| StabilityLimit {
        speed_rpm: speeds.clone(),
        depth_m: rows.iter().map(|r| r[which].0).collect(),
        chatter_hz: rows.iter().map(|r| r[which].1).collect(),
        lobe: rows.iter().map(|r| r[which].2).collect(),
    };
    Ok(SpeedDependentLimit {
        speed_dependent: build(0),
        stationary: build(1),
        lobe_count: count,
        lobes_needed: needed,
        band_top_hz: band_top,
    })
}

#[cfg(test)]
mod spline_tests {
    use super::*;

    /// The per-line tridiagonal solve gives the same spline as the weights of the natural spline
    /// through unit data (each knot's cardinal spline solved on its own), on uneven knots.
    #[test]
    fn the_frf_spline_equals_the_sum_of_cardinal_splines() {
        let knots = [0.0, 800.0, 1500.0, 4000.0, 4300.0, 9000.0, 12000.0];
        let freqs: Vec<f64> = (1..=5).map(|i| 100.0 * i as f64).collect();
        let series = |q: usize, scale: f64| -> Vec<Complex64> {
            freqs
                .iter()
                .map(|f| Complex64::new((f * 1e-3 + q as f64).sin() * scale, (q as f64 * f * 1e-4).cos()))
                .collect()
        };
        let frfs: Vec<SpeedFrf> = knots
            .iter()
            .enumerate()
            .map(|(q, &s)| SpeedFrf {
                speed_rpm: s,
                frf: ToolPointFrf::new(freqs.clone(), series(q, 1.0), series(q + 3, 0.5)).unwrap(),
            })
            .collect();
        let spline = SplineFrf::new(&knots, &frfs, false);
        let mut out = SpeedScratch::default();
        for s in [0.0, 10.0, 799.0, 1200.0, 4150.0, 8999.0, 11000.0, 12000.0] {
            spline.at(s, freqs.len(), &mut out);
            let w = spline_weights(&knots, s);
            for j in 0..freqs.len() {
                let want_xx: Complex64 = w.iter().zip(&frfs).map(|(w, f)| *w * f.frf.xx[j]).sum();
                let want_yy: Complex64 = w.iter().zip(&frfs).map(|(w, f)| *w * f.frf.yy[j]).sum();
                assert!((out.xx[j] - want_xx).norm() <= 1e-12 * (1.0 + want_xx.norm()), "{s} rpm, line {j}");
                assert!((out.yy[j] - want_yy).norm() <= 1e-12 * (1.0 + want_yy.norm()), "{s} rpm, line {j}");
            }
        }
    }
}
