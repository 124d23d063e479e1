//! Bounded minimisation of a sum of squares, for fitting model parameters to measurements.
//!
//! The search runs in unit coordinates `z ∈ [0, 1]ⁿ` (the caller maps them to parameters,
//! linearly or by logarithm), so one step size and one tolerance suit every parameter.
//! Two methods: Levenberg–Marquardt on the residual vector with a forward-difference
//! Jacobian (few evaluations when the residuals are smooth), and argmin's Nelder–Mead on the
//! sum of squares (no derivatives). Both keep the best point seen, and say whether they
//! converged or ran out of evaluations.

use argmin::core::{CostFunction, Error as ArgminError, Executor, State};
use argmin::solver::neldermead::NelderMead;
use faer::Mat;
use faer::linalg::solvers::DenseSolveCore;
use faer::prelude::Solve;
use std::cell::RefCell;

/// Residuals at a point in unit coordinates, or `None` when the model cannot be evaluated
/// there (the search treats that point as infinitely bad).
pub type Residuals<'a> = dyn FnMut(&[f64]) -> Option<Vec<f64>> + 'a;

/// Limits of a search.
#[derive(Debug, Clone, Copy)]
pub struct SearchOptions {
    /// Model evaluations allowed, Jacobian columns included.
    pub max_evaluations: usize,
    /// Stop when a step lowers the sum of squares by less than this fraction of it.
    pub tolerance: f64,
}

/// Where a search ended.
#[derive(Debug, Clone)]
pub struct SearchResult {
    /// The best point found, in unit coordinates.
    pub z: Vec<f64>,
    /// Its residuals and sum of squares.
    pub residuals: Vec<f64>,
    pub cost: f64,
    /// Sum of squares at the start point.
    pub start_cost: f64,
    pub evaluations: usize,
    /// Whether the stopping rule was met (otherwise the evaluation budget ran out).
    pub converged: bool,
    /// The Jacobian at `z` (rows: residuals, columns: coordinates), when the method has one.
    pub jacobian: Option<Mat<f64>>,
}

fn sum_sq(r: &[f64]) -> f64 {
    r.iter().map(|x| x * x).sum()
}

fn clamp01(z: &mut [f64]) {
    for v in z {
        *v = v.clamp(0.0, 1.0);
    }
}

/// Counts evaluations and remembers the best point.
struct Tracker<'f, 'a> {
    f: &'f mut Residuals<'a>,
    evaluations: usize,
    best: Option<(Vec<f64>, Vec<f64>, f64)>,
}

impl Tracker<'_, '_> {
    fn eval(&mut self, z: &[f64]) -> Option<(Vec<f64>, f64)> {
        self.evaluations += 1;
        let r = (self.f)(z)?;
        let c = sum_sq(&r);
        if !c.is_finite() {
            return None;
        }
        if self.best.as_ref().is_none_or(|b| c < b.2) {
            self.best = Some((z.to_vec(), r.clone(), c));
        }
        Some((r, c))
    }
}

/// Forward-difference step in unit coordinates; the residuals of a model are smooth and
/// computed to near machine precision, so a small step is accurate.
const FD_STEP: f64 = 1e-6;

/// Levenberg–Marquardt (Marquardt's diagonal scaling) within the unit box.
pub fn levenberg_marquardt(f: &mut Residuals<'_>, z0: &[f64], opts: SearchOptions) -> Option<SearchResult> {
    let n = z0.len();
    let mut t = Tracker { f, evaluations: 0, best: None };
    let mut z = z0.to_vec();
    clamp01(&mut z);
    let (mut r, mut cost) = t.eval(&z)?;
    let start_cost = cost;
    let mut lambda = 1e-3;
    let mut converged = false;
    let mut jac: Option<Mat<f64>> = None;
    'outer: while t.evaluations + n < opts.max_evaluations {
        // Jacobian by forward differences, stepping inward at the upper bound.
        let m = r.len();
        let mut j = Mat::<f64>::zeros(m, n);
        for k in 0..n {
            let h = if z[k] + FD_STEP <= 1.0 { FD_STEP } else { -FD_STEP };
            let mut zk = z.clone();
            zk[k] += h;
            let Some((rk, _)) = t.eval(&zk) else { break 'outer };
            if rk.len() != m {
                break 'outer;
            }
            for i in 0..m {
                j[(i, k)] = (rk[i] - r[i]) / h;
            }
        }
        let jtj = j.transpose() * &j;
        let rv = Mat::<f64>::from_fn(m, 1, |i, _| r[i]);
        let mut g = j.transpose() * &rv;
        jac = Some(j);
        // Coordinates on a bound that the descent direction −g pushes outward stay there: the
        // step is solved for the others only (an active set), so a clamped coordinate does not
        // spoil the step of the free ones and the search goes on along the face. (A joint
        // damping on its lower bound otherwise made the joint-and-delay pair of the diagnosis
        // matrix creep to its evaluation budget at twice the noise floor.)
        let pinned: Vec<bool> =
            (0..n).map(|k| (z[k] <= 0.0 && g[(k, 0)] > 0.0) || (z[k] >= 1.0 && g[(k, 0)] < 0.0)).collect();
        for k in (0..n).filter(|&k| pinned[k]) {
            g[(k, 0)] = 0.0;
        }
        loop {
            if t.evaluations >= opts.max_evaluations {
                break 'outer;
            }
            let mut a = jtj.clone();
            for k in 0..n {
                a[(k, k)] += lambda * jtj[(k, k)].max(1e-12);
            }
            for k in (0..n).filter(|&k| pinned[k]) {
                for i in 0..n {
                    a[(k, i)] = 0.0;
                    a[(i, k)] = 0.0;
                }
                a[(k, k)] = 1.0;
            }
            let step = a.partial_piv_lu().solve(-&g);
            let mut zn: Vec<f64> = (0..n).map(|k| z[k] + step[(k, 0)]).collect();
            clamp01(&mut zn);
            let moved: f64 = zn.iter().zip(&z).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            if moved < 1e-12 {
                // Pinned against the bounds or at a stationary point.
                converged = true;
                break 'outer;
            }
            match t.eval(&zn) {
                Some((rn, cn)) if cn < cost => {
                    let gain = (cost - cn) / cost.max(f64::MIN_POSITIVE);
                    z = zn;
                    r = rn;
                    cost = cn;
                    lambda = (lambda / 3.0).max(1e-12);
                    if gain < opts.tolerance {
                        converged = true;
                        break 'outer;
                    }
                    break;
                }
                _ => {
                    lambda *= 4.0;
                    if lambda > 1e12 {
                        converged = true;
                        break 'outer;
                    }
                }
            }
        }
    }
    let evaluations = t.evaluations;
    let (zb, rb, cb) = t.best?;
    // The Jacobian belongs to `z`; the best point is `z` unless a Jacobian column was better.
    let jacobian = if zb == z { jac } else { None };
    Some(SearchResult { z: zb, residuals: rb, cost: cb, start_cost, evaluations, converged, jacobian })
}

struct SimplexCost<'t, 'f, 'a> {
    tracker: &'t RefCell<Tracker<'f, 'a>>,
}

impl CostFunction for SimplexCost<'_, '_, '_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, z: &Vec<f64>) -> Result<f64, ArgminError> {
        // Outside the box the cost grows with the distance, so the simplex turns back.
        let mut zc = z.clone();
        clamp01(&mut zc);
        let outside: f64 = z.iter().zip(&zc).map(|(a, b)| (a - b).abs()).sum();
        let c = self.tracker.borrow_mut().eval(&zc).map_or(f64::INFINITY, |(_, c)| c);
        Ok(if outside > 0.0 { c * (1.0 + outside) + outside } else { c })
    }
}

/// argmin's Nelder–Mead on the sum of squares, from an initial simplex of steps of 0.1.
pub fn nelder_mead(f: &mut Residuals<'_>, z0: &[f64], opts: SearchOptions) -> Option<SearchResult> {
    let n = z0.len();
    let mut z = z0.to_vec();
    clamp01(&mut z);
    let tracker = RefCell::new(Tracker { f, evaluations: 0, best: None });
    let (_, start_cost) = tracker.borrow_mut().eval(&z)?;
    let mut simplex = vec![z.clone()];
    for k in 0..n {
        let mut v = z.clone();
        v[k] += if v[k] + 0.1 <= 1.0 { 0.1 } else { -0.1 };
        simplex.push(v);
    }
    let solver = NelderMead::new(simplex).with_sd_tolerance(opts.tolerance * start_cost.max(1e-300)).ok()?;
    // Each iteration costs one to n + 2 evaluations; the tracker holds the budget too.
    let iters = (opts.max_evaluations / 2).max(1) as u64;
    let res = Executor::new(SimplexCost { tracker: &tracker }, solver)
        .configure(|s| s.max_iters(iters))
        .timer(false)
        .run()
        .ok()?;
    let converged = res.state().get_iter() < iters;
    let t = tracker.into_inner();
    let evaluations = t.evaluations;
    let (z, residuals, cost) = t.best?;
    Some(SearchResult { z, residuals, cost, start_cost, evaluations, converged, jacobian: None })
}

/// The `k`-th point (from 1) of the Halton sequence in `n` dimensions: a deterministic,
/// evenly spread sample of the unit box.
pub fn halton(k: usize, n: usize) -> Vec<f64> {
    const PRIMES: [usize; 16] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53];
    (0..n)
        .map(|d| {
            let b = PRIMES[d % PRIMES.len()];
            let (mut f, mut r, mut i) = (1.0, 0.0, k);
            while i > 0 {
                f /= b as f64;
                r += f * (i % b) as f64;
                i /= b;
            }
            r
        })
        .collect()
}

/// A global search for residuals with several basins (a resonance that must move onto the
/// measured one): the start point and `samples` Halton points of the box are evaluated,
/// then `local` runs from the best `runs` of them, each with an equal share of what is left
/// of the budget, until two runs end on the same minimum. The best end point wins.
pub fn multistart(
    f: &mut Residuals<'_>,
    z0: &[f64],
    samples: usize,
    runs: usize,
    opts: SearchOptions,
    local: fn(&mut Residuals<'_>, &[f64], SearchOptions) -> Option<SearchResult>,
) -> Option<SearchResult> {
    let n = z0.len();
    let mut scored: Vec<(f64, Vec<f64>)> = Vec::with_capacity(samples + 1);
    let mut used = 0usize;
    let mut start_cost = f64::INFINITY;
    for k in 0..=samples {
        let z = if k == 0 { z0.to_vec() } else { halton(k, n) };
        used += 1;
        let c = f(&z).map_or(f64::INFINITY, |r| sum_sq(&r));
        if k == 0 {
            start_cost = c;
        }
        if c.is_finite() {
            scored.push((c, z));
        }
    }
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    let runs = runs.clamp(1, scored.len().max(1));
    let mut best: Option<SearchResult> = None;
    for (i, (_, z)) in scored.iter().take(runs).enumerate() {
        // What an earlier run did not use passes on to the later ones.
        let share = opts.max_evaluations.saturating_sub(used) / (runs - i);
        let Some(mut r) = local(f, z, SearchOptions { max_evaluations: share.max(n + 2), ..opts }) else { continue };
        used += r.evaluations;
        // Two runs from different starts ending on one minimum: that basin is the deepest
        // the samples found, and further runs would only repeat it.
        let agrees = best.as_ref().is_some_and(|b| (r.cost - b.cost).abs() <= 1e-6 * b.cost.max(f64::MIN_POSITIVE));
        if best.as_ref().is_none_or(|b| r.cost < b.cost) {
            r.start_cost = start_cost;
            best = Some(r);
        }
        if agrees {
            break;
        }
    }
    best.map(|mut b| {
        b.evaluations = used;
        b
    })
}

/// Standard deviations of the unit coordinates from the Jacobian at the optimum:
/// `cov = s² (JᵀJ)⁻¹` with `s² = cost / (m − n)`, the residual variance. `None` when `JᵀJ`
/// is singular (a parameter the data do not determine).
pub fn coordinate_sigmas(jacobian: &Mat<f64>, cost: f64) -> Option<Vec<f64>> {
    let (m, n) = (jacobian.nrows(), jacobian.ncols());
    if m <= n {
        return None;
    }
    let jtj = jacobian.transpose() * jacobian;
    let inv = jtj.partial_piv_lu().inverse();
    let s2 = cost / (m - n) as f64;
    (0..n).map(|k| inv[(k, k)]).map(|d| (d.is_finite() && d > 0.0).then(|| (s2 * d).sqrt())).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;

    /// A decaying exponential `a exp(-b t)` sampled at 40 points, parameters mapped from
    /// the unit box: a ∈ [0, 10], b ∈ [0, 5].
    fn exp_residuals(truth: (f64, f64)) -> impl FnMut(&[f64]) -> Option<Vec<f64>> {
        move |z: &[f64]| {
            let (a, b) = (10.0 * z[0], 5.0 * z[1]);
            Some(
                (0..40)
                    .map(|i| {
                        let t = i as f64 * 0.05;
                        a * (-b * t).exp() - truth.0 * (-truth.1 * t).exp()
                    })
                    .collect(),
            )
        }
    }

    #[test]
    fn levenberg_marquardt_recovers_an_exponential() {
        let mut f = exp_residuals((3.0, 1.7));
        let opts = SearchOptions { max_evaluations: 200, tolerance: 1e-12 };
        let r = levenberg_marquardt(&mut f, &[0.5, 0.5], opts).unwrap();
        assert!((10.0 * r.z[0] - 3.0).abs() < 1e-6 && (5.0 * r.z[1] - 1.7).abs() < 1e-6, "{:?}", r.z);
        assert!(r.cost < 1e-12 && r.start_cost > 1.0 && r.evaluations < 200);
    }

    #[test]
    fn nelder_mead_recovers_an_exponential() {
        let mut f = exp_residuals((3.0, 1.7));
        let opts = SearchOptions { max_evaluations: 2000, tolerance: 1e-14 };
        let r = nelder_mead(&mut f, &[0.5, 0.5], opts).unwrap();
        assert!((10.0 * r.z[0] - 3.0).abs() < 1e-3 && (5.0 * r.z[1] - 1.7).abs() < 1e-3, "{:?}", r.z);
    }

    #[test]
    fn bounds_hold_when_the_optimum_lies_outside() {
        // The best fit wants a = 12, beyond the box: the search stops at the bound.
        let mut f = exp_residuals((12.0, 1.0));
        let opts = SearchOptions { max_evaluations: 200, tolerance: 1e-12 };
        let r = levenberg_marquardt(&mut f, &[0.5, 0.5], opts).unwrap();
        assert!(r.z[0] <= 1.0 && r.z[0] > 0.99, "{:?}", r.z);
    }

    #[test]
    fn multistart_leaves_a_local_minimum_that_traps_a_local_search() {
        // A resonance at f0 = 200 + 800 z Hz compared with one at 700 Hz: from z = 0.05 the
        // residual is flat (the peaks do not overlap), so a local search stays put.
        let model = |z: f64, f: f64| 1.0 / Complex64::new(1.0 - (f / (200.0 + 800.0 * z)).powi(2), 0.02 * f / 700.0);
        let mut f = |z: &[f64]| -> Option<Vec<f64>> {
            Some(
                (0..400)
                    .flat_map(|k| {
                        let fr = 100.0 + 2.5 * k as f64;
                        let d = model(z[0], fr) - model(0.625, fr);
                        [d.re, d.im]
                    })
                    .collect(),
            )
        };
        let opts = SearchOptions { max_evaluations: 300, tolerance: 1e-12 };
        let local = levenberg_marquardt(&mut f, &[0.05], opts).unwrap();
        assert!((local.z[0] - 0.625).abs() > 0.05, "the local search should be trapped: {:?}", local.z);
        let global = multistart(&mut f, &[0.05], 20, 3, opts, levenberg_marquardt).unwrap();
        assert!((global.z[0] - 0.625).abs() < 1e-6, "{:?}", global.z);
        assert!(global.evaluations <= 300 + 3 * 3);
    }

    #[test]
    fn sigmas_match_the_linear_regression_formula() {
        // A straight line y = c0 + c1 x with known residuals: the textbook standard errors.
        let xs: Vec<f64> = (0..20).map(|i| i as f64 / 19.0).collect();
        let noise: Vec<f64> =
            (0..20).map(|i| if i % 2 == 0 { 0.01 } else { -0.01 } * (1.0 + i as f64 / 20.0)).collect();
        let j = Mat::<f64>::from_fn(20, 2, |i, k| if k == 0 { 1.0 } else { xs[i] });
        let cost: f64 = noise.iter().map(|e| e * e).sum();
        let s = coordinate_sigmas(&j, cost).unwrap();
        let mean = xs.iter().sum::<f64>() / 20.0;
        let sxx: f64 = xs.iter().map(|x| (x - mean).powi(2)).sum();
        let s2 = cost / 18.0;
        assert!((s[1] - (s2 / sxx).sqrt()).abs() < 1e-12);
        assert!((s[0] - (s2 * (1.0 / 20.0 + mean * mean / sxx)).sqrt()).abs() < 1e-12);
    }
}
