//! Once-per-revolution removal of §3.1.1: the artifact's form error and the synchronous
//! error motion repeat every revolution, so their average over revolutions that hold no
//! impact response, mapped back onto time through the tachometer angle and subtracted,
//! leaves the structural response (plus asynchronous motion and noise).
//!
//! Each revolution runs between two tachometer edges (θ = 0); the speed is taken as
//! constant within a revolution, so the angle is linear in time between edges. A
//! revolution is mapped onto a uniform angle grid by linear interpolation between samples
//! (the "piece-wise interpolation" of the text).

use std::f64::consts::TAU;
use thiserror::Error;

/// The averaged once-per-revolution content on a uniform angle grid `θ_j = 2πj/N`.
#[derive(Debug, Clone, PartialEq)]
pub struct OncePerRev {
    /// Mean signal per grid angle.
    pub profile: Vec<f64>,
    /// Revolutions averaged.
    pub revolutions: usize,
}

/// Errors of once-per-revolution removal.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RunoutError {
    #[error("fewer than two tachometer edges: no complete revolution to average")]
    NoRevolution,
    #[error("tachometer edges are not increasing at edge {index}")]
    EdgesNotIncreasing { index: usize },
    #[error(
        "no revolution free of impact response to average ({total} complete revolutions, all within an excluded interval); record more revolutions between impacts or shorten the exclusion"
    )]
    AllExcluded { total: usize },
    #[error("sample {index} is not a finite number")]
    NonFinite { index: usize },
    #[error("the angle grid needs at least 8 points, got {0}")]
    GridTooSmall(usize),
}

/// Time base of a uniformly sampled signal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sampling {
    /// Samples per second.
    pub rate: f64,
    /// Time of the first sample, s.
    pub t0: f64,
}

impl Sampling {
    fn time(&self, n: usize) -> f64 {
        self.t0 + n as f64 / self.rate
    }
    fn position(&self, t: f64) -> f64 {
        (t - self.t0) * self.rate
    }
}

/// Linear interpolation of `x` at fractional sample position `s` (clamped to the ends).
fn at(x: &[f64], s: f64) -> f64 {
    let last = x.len() - 1;
    if s <= 0.0 {
        return x[0];
    }
    let i = s.floor() as usize;
    if i >= last {
        return x[last];
    }
    let w = s - i as f64;
    x[i] + w * (x[i + 1] - x[i])
}

fn check_edges(edges: &[f64]) -> Result<(), RunoutError> {
    if edges.len() < 2 {
        return Err(RunoutError::NoRevolution);
    }
    match edges.windows(2).position(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater)) {
        Some(i) => Err(RunoutError::EdgesNotIncreasing { index: i + 1 }),
        None => Ok(()),
    }
}

/// Averages `signal` over the complete revolutions between `edges` (tachometer θ = 0
/// times, s) that overlap none of the `exclude` intervals (s), on a grid of `grid` angles
/// (default: the fewest samples in any revolution).
pub fn average(
    signal: &[f64],
    sampling: Sampling,
    edges: &[f64],
    exclude: &[(f64, f64)],
    grid: Option<usize>,
) -> Result<OncePerRev, RunoutError> {
    check_edges(edges)?;
    if let Some(index) = signal.iter().position(|v| !v.is_finite()) {
        return Err(RunoutError::NonFinite { index });
    }
    let t_end = sampling.time(signal.len().saturating_sub(1));
    let complete: Vec<(f64, f64)> =
        edges.windows(2).map(|w| (w[0], w[1])).filter(|&(a, b)| a >= sampling.t0 && b <= t_end).collect();
    if complete.is_empty() {
        return Err(RunoutError::NoRevolution);
    }
    let min_samples = complete.iter().map(|(a, b)| ((b - a) * sampling.rate).floor() as usize).min().unwrap_or(0);
    let n = grid.unwrap_or(min_samples);
    if n < 8 {
        return Err(RunoutError::GridTooSmall(n));
    }
    let mut profile = vec![0.0; n];
    let mut used = 0usize;
    for &(a, b) in &complete {
        if exclude.iter().any(|&(lo, hi)| a < hi && b > lo) {
            continue;
        }
        let (s0, ds) = (sampling.position(a), (b - a) * sampling.rate / n as f64);
        for (j, p) in profile.iter_mut().enumerate() {
            *p += at(signal, s0 + j as f64 * ds);
        }
        used += 1;
    }
    if used == 0 {
        return Err(RunoutError::AllExcluded { total: complete.len() });
    }
    let inv = 1.0 / used as f64;
    profile.iter_mut().for_each(|p| *p *= inv);
    Ok(OncePerRev { profile, revolutions: used })
}

/// The angle (rad, in `[0, 2π)`) at time `t`, linear between edges; before the first and
/// after the last edge the neighbouring revolution's period is extended.
pub fn angle_at(edges: &[f64], t: f64) -> f64 {
    let k = edges.partition_point(|&e| e <= t);
    let i = k.saturating_sub(1).min(edges.len() - 2);
    let (a, b) = (edges[i], edges[i + 1]);
    ((t - a) / (b - a) * TAU).rem_euclid(TAU)
}

impl OncePerRev {
    /// The profile at angle `theta` (periodic linear interpolation).
    pub fn at_angle(&self, theta: f64) -> f64 {
        let n = self.profile.len();
        let u = theta.rem_euclid(TAU) / TAU * n as f64;
        let i = (u.floor() as usize).min(n - 1);
        let w = u - i as f64;
        self.profile[i] + w * (self.profile[(i + 1) % n] - self.profile[i])
    }

    /// Subtracts the profile from every sample of `signal`, mapping time to angle through
    /// the tachometer `edges` (§3.1.1: "mapped back to the original time vector").
    pub fn subtract(&self, signal: &mut [f64], sampling: Sampling, edges: &[f64]) -> Result<(), RunoutError> {
        check_edges(edges)?;
        let mut i = 0usize;
        for (n, v) in signal.iter_mut().enumerate() {
            let t = sampling.time(n);
            while i + 2 < edges.len() && t >= edges[i + 1] {
                i += 1;
            }
            let (a, b) = (edges[i], edges[i + 1]);
            *v -= self.at_angle((t - a) / (b - a) * TAU);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FS: f64 = 100.0e3;

    /// Edges of a spindle at `rpm` with a slow 1 % speed wobble, starting at `first`.
    fn edges(rpm: f64, first: f64, until: f64) -> Vec<f64> {
        let mut e = vec![first];
        let mut t = first;
        while t < until {
            let speed = rpm / 60.0 * (1.0 + 0.01 * (0.7 * t).sin());
            t += 1.0 / speed;
            e.push(t);
        }
        e
    }

    /// Runout as a function of angle: a few undulations.
    fn runout(theta: f64) -> f64 {
        1e-6 * theta.cos() + 0.3e-6 * (2.0 * theta + 0.4).sin() + 0.05e-6 * (44.0 * theta).cos()
    }

    #[test]
    fn removes_runout_and_keeps_the_impact_response() {
        let e = edges(1000.0, 0.013, 2.1);
        let s = Sampling { rate: FS, t0: 0.0 };
        let n = 200_000;
        // A decaying 700 Hz response starting at 1.0 s.
        let response =
            |t: f64| if t >= 1.0 { 2e-6 * (-60.0 * (t - 1.0)).exp() * (4398.0 * (t - 1.0)).sin() } else { 0.0 };
        let signal: Vec<f64> = (0..n)
            .map(|k| {
                let t = s.time(k);
                runout(angle_at(&e, t)) + response(t)
            })
            .collect();
        let opr = average(&signal, s, &e, &[(0.995, 1.3)], Some(4096)).unwrap();
        assert!(opr.revolutions > 25, "{}", opr.revolutions);
        for j in (0..4096).step_by(97) {
            let th = TAU * j as f64 / 4096.0;
            assert!((opr.at_angle(th) - runout(th)).abs() < 2e-10, "θ {th}");
        }
        let mut cleaned = signal.clone();
        opr.subtract(&mut cleaned, s, &e).unwrap();
        let worst = (0..n).map(|k| (cleaned[k] - response(s.time(k))).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-9, "residual {worst}");
        // Without the exclusion the impact leaks into the average.
        let leaky = average(&signal, s, &e, &[], Some(4096)).unwrap();
        let err = (0..4096).map(|j| (leaky.profile[j] - opr.profile[j]).abs()).fold(0.0, f64::max);
        assert!(err > 1e-8, "{err}");
    }

    #[test]
    fn bad_input_is_an_error() {
        let s = Sampling { rate: FS, t0: 0.0 };
        let x = vec![0.0; 10_000];
        assert_eq!(average(&x, s, &[0.01], &[], None), Err(RunoutError::NoRevolution));
        assert_eq!(average(&x, s, &[0.01, 0.005], &[], None), Err(RunoutError::EdgesNotIncreasing { index: 1 }));
        assert_eq!(average(&x, s, &[0.01, 0.05], &[(0.0, 1.0)], None), Err(RunoutError::AllExcluded { total: 1 }));
        let mut y = x.clone();
        y[7] = f64::NAN;
        assert_eq!(average(&y, s, &[0.01, 0.05], &[], None), Err(RunoutError::NonFinite { index: 7 }));
        assert_eq!(average(&x, s, &[0.01, 0.01003], &[], None), Err(RunoutError::GridTooSmall(3)));
    }
}
