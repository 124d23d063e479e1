//! Cutting trials against a stability diagram (dissertation §6.4, Fig. 6.9): each trial (speed, depth, observed
//! outcome) is classified by the limiting depth linearly interpolated at its speed, predicted stable strictly
//! below the limit and chatter at or above it (the SD criterion "stable iff spectral radius < 1" likewise
//! counts the boundary as unstable), and scored against what was observed.

use super::StabilityError;

/// What a trial cut showed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// No chatter.
    Stable,
    /// Chatter.
    Chatter,
}

/// One cutting trial.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trial {
    /// Spindle speed, rpm.
    pub speed_rpm: f64,
    /// Axial depth of cut, m.
    pub depth_m: f64,
    /// Observed outcome.
    pub outcome: Outcome,
    /// Observed chatter frequency, Hz, if measured.
    pub chatter_hz: Option<f64>,
}

/// The verdict on one trial.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Verdict {
    /// The trial's speed lies outside the diagram's speed range: not scored.
    OutsideDiagram,
    /// Inside the range: the prediction and the distance to the boundary.
    Scored {
        /// Limiting depth interpolated at the trial's speed, m (`+∞` where the diagram has no limit).
        limit_m: f64,
        /// Predicted outcome.
        predicted: Outcome,
        /// Prediction equals observation.
        right: bool,
        /// `depth − limit`, m: negative below the boundary (stable side), positive above.
        distance_m: f64,
        /// `depth/limit − 1`: the distance relative to the limit.
        distance_relative: f64,
    },
}

/// Trials scored against a diagram.
#[derive(Debug, Clone, PartialEq)]
pub struct TrialScore {
    /// One verdict per trial, in input order.
    pub verdicts: Vec<Verdict>,
    /// Trials predicted right.
    pub right: usize,
    /// Trials predicted wrong.
    pub wrong: usize,
    /// Trials outside the diagram's speed range.
    pub outside: usize,
    /// `right / (right + wrong)`; `None` if no trial lies inside the diagram.
    pub fraction_right: Option<f64>,
}

/// How likely a diagram makes each trial's outcome: a cut at depth `b` where the diagram's limit is `b_lim`
/// chatters with probability `ε + (1 − 2ε) Φ(ln(b/b_lim)/σ)`, a probit in the log depth ratio (the likelihood
/// of the Bayesian stability work of Schmitz's group: Karandikar, Schmitz et al., *Precision Engineering*, 2014)
/// mixed with a lapse rate `ε` (a mislabelled or disturbed cut), so no single trial costs more than `−2 ln ε`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrialLikelihood {
    /// Standard deviation of `ln(b/b_lim)` at the boundary: how sharply the diagram's boundary is known.
    pub sigma: f64,
    /// Lapse rate `ε`, in `[0, ½)`.
    pub lapse: f64,
}

impl Default for TrialLikelihood {
    /// σ = 0.05 (a limit known to about 5 %), ε = 2 %.
    fn default() -> Self {
        TrialLikelihood { sigma: 0.05, lapse: 0.02 }
    }
}

/// The standard normal distribution function, `Φ(x) = ½ erfc(−x/√2)`.
pub fn normal_cdf(x: f64) -> f64 {
    0.5 * libm::erfc(-x / std::f64::consts::SQRT_2)
}

impl TrialLikelihood {
    /// Probability that a cut at `depth_m` chatters where the limit is `limit_m` (`+∞`: no limit found).
    pub fn chatter_probability(&self, depth_m: f64, limit_m: f64) -> f64 {
        let x = (depth_m / limit_m).ln() / self.sigma;
        let p = if x.is_nan() { 0.5 } else { normal_cdf(x) };
        self.lapse + (1.0 - 2.0 * self.lapse) * p
    }

    /// `−2 ln p` of what the trial showed, given the limit at its speed.
    pub fn deviance(&self, trial: &Trial, limit_m: f64) -> f64 {
        let p = self.chatter_probability(trial.depth_m, limit_m);
        let p = if trial.outcome == Outcome::Chatter { p } else { 1.0 - p };
        -2.0 * p.max(f64::MIN_POSITIVE).ln()
    }

    /// `−2 ln L` of the scored trials (those outside the diagram do not count).
    pub fn total_deviance(&self, trials: &[Trial], verdicts: &[Verdict]) -> f64 {
        trials
            .iter()
            .zip(verdicts)
            .filter_map(|(t, v)| match *v {
                Verdict::Scored { limit_m, .. } => Some(self.deviance(t, limit_m)),
                Verdict::OutsideDiagram => None,
            })
            .sum()
    }
}

/// Limiting depth at `speed` by linear interpolation of the diagram (`None` outside its range). Between a finite
/// and an infinite limit (a speed where no lobe was found) the limit is infinite.
fn limit_at(speeds: &[f64], limits: &[f64], speed: f64) -> Option<f64> {
    let (lo, hi) = (speeds[0], speeds[speeds.len() - 1]);
    if !(speed >= lo && speed <= hi) {
        return None;
    }
    let i = speeds.partition_point(|&s| s < speed);
    if speeds[i] == speed {
        return Some(limits[i]);
    }
    let (s0, s1, a0, a1) = (speeds[i - 1], speeds[i], limits[i - 1], limits[i]);
    if a0.is_infinite() || a1.is_infinite() {
        return Some(f64::INFINITY);
    }
    Some(a0 + (speed - s0) / (s1 - s0) * (a1 - a0))
}

/// Scores `trials` against the diagram `(speeds_rpm, limits_m)`: speeds strictly ascending, limiting depths
/// `> 0` (`+∞` allowed where no lobe limits the cut), as [`super::StabilityLimit`] or the SD limits give it.
pub fn score_trials(speeds_rpm: &[f64], limits_m: &[f64], trials: &[Trial]) -> Result<TrialScore, StabilityError> {
    let bad = |detail: String| Err(StabilityError::InvalidDiagram { detail });
    if speeds_rpm.is_empty() {
        return bad("the diagram has no speeds".into());
    }
    if speeds_rpm.len() != limits_m.len() {
        return bad(format!("{} speeds but {} limiting depths", speeds_rpm.len(), limits_m.len()));
    }
    if let Some(i) = speeds_rpm.iter().position(|s| !s.is_finite()) {
        return bad(format!("speed {i} is {}", speeds_rpm[i]));
    }
    if let Some(i) = speeds_rpm.windows(2).position(|w| w[1] <= w[0]) {
        return bad(format!("speeds do not increase strictly at index {} ({} rpm)", i + 1, speeds_rpm[i + 1]));
    }
    if let Some(i) = limits_m.iter().position(|a| a.is_nan() || *a <= 0.0) {
        return bad(format!("limiting depth {i} is {} m (must be > 0 or +∞)", limits_m[i]));
    }
    let mut verdicts = Vec::with_capacity(trials.len());
    let (mut right, mut wrong, mut outside) = (0, 0, 0);
    for (index, t) in trials.iter().enumerate() {
        if !(t.speed_rpm.is_finite() && t.speed_rpm > 0.0) {
            return Err(StabilityError::InvalidTrial {
                index,
                problem: format!("speed {} rpm must be finite and > 0", t.speed_rpm),
            });
        }
        if !(t.depth_m.is_finite() && t.depth_m >= 0.0) {
            return Err(StabilityError::InvalidTrial {
                index,
                problem: format!("depth {} m must be finite and ≥ 0", t.depth_m),
            });
        }
        let Some(limit_m) = limit_at(speeds_rpm, limits_m, t.speed_rpm) else {
            outside += 1;
            verdicts.push(Verdict::OutsideDiagram);
            continue;
        };
        let predicted = if t.depth_m < limit_m { Outcome::Stable } else { Outcome::Chatter };
        let ok = predicted == t.outcome;
        if ok {
            right += 1;
        } else {
            wrong += 1;
        }
        verdicts.push(Verdict::Scored {
            limit_m,
            predicted,
            right: ok,
            distance_m: t.depth_m - limit_m,
            distance_relative: t.depth_m / limit_m - 1.0,
        });
    }
    let fraction_right = (right + wrong > 0).then(|| right as f64 / (right + wrong) as f64);
    Ok(TrialScore { verdicts, right, wrong, outside, fraction_right })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The probit's known values: on the boundary one half; one σ into the chatter side `Φ(1)` = 0.841345;
    /// a stable cut deep on the chatter side costs no more than `−2 ln ε`; `+∞` limit: stable but for the lapse.
    #[test]
    fn the_trial_likelihood_is_a_probit_in_the_log_depth_ratio_with_a_lapse() {
        let l = TrialLikelihood { sigma: 0.1, lapse: 0.0 };
        assert!((l.chatter_probability(1e-3, 1e-3) - 0.5).abs() < 1e-15);
        assert!((l.chatter_probability(1e-3 * 0.1f64.exp(), 1e-3) - 0.841_344_746_068_543).abs() < 1e-12);
        assert!((normal_cdf(-1.959_963_984_540_054) - 0.025).abs() < 1e-12);
        let l = TrialLikelihood::default();
        let stable_deep = Trial { speed_rpm: 1000.0, depth_m: 10e-3, outcome: Outcome::Stable, chatter_hz: None };
        let cost = l.deviance(&stable_deep, 1e-3);
        assert!(cost <= -2.0 * 0.02f64.ln() + 1e-12 && cost > -2.0 * 0.021f64.ln(), "{cost}");
        assert!((l.chatter_probability(1e-3, f64::INFINITY) - 0.02).abs() < 1e-15);
        // Right trials cost less the farther they lie from the boundary.
        let right = |d: f64| l.deviance(&Trial { depth_m: d, ..stable_deep }, 1e-3);
        assert!(right(0.5e-3) < right(0.9e-3) && right(0.9e-3) < right(1.1e-3));
    }

    /// A V-shaped lobe: 2 mm at 1000 rpm down to 1 mm at 2000 rpm and up to 4 mm at 3000 rpm, no limit (+∞)
    /// at 4000 rpm.
    fn diagram() -> (Vec<f64>, Vec<f64>) {
        (vec![1000.0, 2000.0, 3000.0, 4000.0], vec![2e-3, 1e-3, 4e-3, f64::INFINITY])
    }

    fn trial(speed_rpm: f64, depth_m: f64, outcome: Outcome) -> Trial {
        Trial { speed_rpm, depth_m, outcome, chatter_hz: None }
    }

    /// Known answers: at 1500 rpm the limit is 1.5 mm, at 2500 rpm 2.5 mm, at 2000 rpm exactly 1 mm (a trial on
    /// the boundary is predicted chatter), between 3000 and 4000 rpm unlimited; trials at 500 and 4500 rpm are
    /// reported outside, not dropped.
    #[test]
    fn trials_are_classified_against_the_interpolated_limit() {
        let (s, a) = diagram();
        let trials = [
            trial(1500.0, 1.2e-3, Outcome::Stable),  // right, 0.3 mm below, −20 %
            trial(1500.0, 1.8e-3, Outcome::Stable),  // wrong, 0.3 mm above, +20 %
            trial(2500.0, 3.0e-3, Outcome::Chatter), // right, 0.5 mm above, +20 %
            trial(2000.0, 1.0e-3, Outcome::Chatter), // right: on the boundary
            trial(3500.0, 9.0e-3, Outcome::Chatter), // wrong: no limit there
            trial(500.0, 1e-3, Outcome::Stable),     // outside
            Trial { speed_rpm: 4500.0, depth_m: 1e-3, outcome: Outcome::Chatter, chatter_hz: Some(812.0) },
        ];
        let score = score_trials(&s, &a, &trials).unwrap();
        assert_eq!((score.right, score.wrong, score.outside), (3, 2, 2));
        assert_eq!(score.fraction_right, Some(0.6));
        assert_eq!(score.verdicts.len(), trials.len());
        let expect = [
            (1.5e-3, Outcome::Stable, true, -0.3e-3, -0.2),
            (1.5e-3, Outcome::Chatter, false, 0.3e-3, 0.2),
            (2.5e-3, Outcome::Chatter, true, 0.5e-3, 0.2),
            (1.0e-3, Outcome::Chatter, true, 0.0, 0.0),
        ];
        for (v, (lim, pred, ok, dist, rel)) in score.verdicts.iter().zip(expect) {
            let Verdict::Scored { limit_m, predicted, right, distance_m, distance_relative } = *v else {
                panic!("{v:?}")
            };
            assert!((limit_m - lim).abs() < 1e-15, "{v:?}");
            assert_eq!((predicted, right), (pred, ok), "{v:?}");
            assert!((distance_m - dist).abs() < 1e-15 && (distance_relative - rel).abs() < 1e-12, "{v:?}");
        }
        let Verdict::Scored { limit_m, predicted, right, distance_relative, .. } = score.verdicts[4] else { panic!() };
        assert!(limit_m.is_infinite() && predicted == Outcome::Stable && !right && distance_relative == -1.0);
        assert_eq!(score.verdicts[5], Verdict::OutsideDiagram);
        assert_eq!(score.verdicts[6], Verdict::OutsideDiagram);
        // The diagram's end speeds are inside.
        let ends = score_trials(&s, &a, &[trial(1000.0, 1e-3, Outcome::Stable), trial(4000.0, 1.0, Outcome::Stable)]);
        assert_eq!(ends.unwrap().right, 2);
        // Only trials outside: nothing to score.
        let none = score_trials(&s, &a, &[trial(100.0, 1e-3, Outcome::Stable)]).unwrap();
        assert_eq!((none.outside, none.fraction_right), (1, None));
    }

    #[test]
    fn bad_diagrams_and_trials_are_refused() {
        let (s, a) = diagram();
        let t = [trial(1500.0, 1e-3, Outcome::Stable)];
        assert!(matches!(score_trials(&[], &[], &t), Err(StabilityError::InvalidDiagram { .. })));
        assert!(matches!(score_trials(&s, &a[..3], &t), Err(StabilityError::InvalidDiagram { .. })));
        let e = score_trials(&[1000.0, 1000.0], &[1e-3, 1e-3], &t).unwrap_err();
        assert!(e.to_string().contains("index 1"), "{e}");
        assert!(matches!(score_trials(&s, &[1e-3, 0.0, 1e-3, 1e-3], &t), Err(StabilityError::InvalidDiagram { .. })));
        assert!(matches!(
            score_trials(&s, &[1e-3, f64::NAN, 1e-3, 1e-3], &t),
            Err(StabilityError::InvalidDiagram { .. })
        ));
        let e = score_trials(&s, &a, &[t[0], trial(1500.0, -1e-3, Outcome::Stable)]).unwrap_err();
        assert!(matches!(e, StabilityError::InvalidTrial { index: 1, .. }), "{e}");
        let e = score_trials(&s, &a, &[trial(f64::NAN, 1e-3, Outcome::Stable)]).unwrap_err();
        assert!(matches!(e, StabilityError::InvalidTrial { index: 0, .. }), "{e}");
    }
}
