//! `trials.score`: cutting trials scored against a stability diagram.

use super::{TRIALS_SCORE, outputs, trials_in};
use crate::stability::{self, Outcome, StabilityError, TrialLikelihood, Verdict};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Column, PortType, Scalar, Table, Value};
use spindlelab_grammar::Dimension as D;
use std::path::Path;

node_params! {
    /// Parameters of `trials.score`.
    pub struct TrialsScoreParams<'a> {
        file: req &'a Path = (
            T::File,
            "trials CSV `rpm,depth_mm,outcome[,chatter_freq_hz]`, outcome `stable` or `chatter`",
        ),
        margin: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "0 %",
            "`misfit` also counts right trials closer than this (in ln depth) to the boundary, so a fit centres the boundary between the stable and the chattering cuts",
        ),
        sigma: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "5 %",
            "standard deviation of ln(depth/limit) at the boundary in the trials' likelihood: how sharply the diagram's limit is known",
        ),
        lapse: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "2 %",
            "chance that a trial's outcome is not the diagram's (a mislabelled or disturbed cut): bounds what one trial costs in the likelihood",
        ),
    }
}

/// `trials.score`: cutting trials (speed, depth, stable/chatter) scored against a stability diagram.
pub struct TrialsScore {
    spec: NodeSpec,
}

impl Default for TrialsScore {
    fn default() -> Self {
        Self::new()
    }
}

impl TrialsScore {
    pub fn new() -> Self {
        TrialsScore {
            spec: NodeSpec {
                kind: TRIALS_SCORE,
                version: 2,
                description: "Scores cutting trials (CSV rpm,depth_mm,outcome[,chatter_freq_hz]) against a stability diagram: predicted outcome, right or wrong and distance to the boundary per trial, and the fraction right.",
                inputs: vec![PortSpec::new("lobes", PortType::Lobes, "the diagram: limiting depth over speed")],
                outputs: vec![
                    PortSpec::new(
                        "verdicts",
                        PortType::Table,
                        "per trial: speed (rpm), depth (m), outcome and predicted (0 stable, 1 chatter; −1 outside \
                         the diagram), right (0/1, −1 outside), limit and distance = depth − limit (m; NaN outside)",
                    ),
                    PortSpec::new(
                        "score",
                        PortType::Scalar,
                        "fraction of the trials inside the diagram predicted right",
                    ),
                    PortSpec::new(
                        "misclassified",
                        PortType::Scalar,
                        "number of trials inside the diagram predicted wrong",
                    ),
                    PortSpec::new(
                        "deviance",
                        PortType::Scalar,
                        "−2 ln L of the trials under the probit likelihood: a cut chatters with probability \
                         ε + (1 − 2ε) Φ(ln(depth/limit)/σ); continuous in the diagram, and no trial costs more than \
                         −2 ln ε",
                    ),
                    PortSpec::new(
                        "misfit",
                        PortType::Scalar,
                        "√Σ max(0, margin ∓ ln(depth/limit))² over the trials (− for chatter, + for stable): 0 when \
                         every trial is right by the margin, and continuous in the diagram, so a fit can move a \
                         boundary across the trials",
                    ),
                ],
                params: TrialsScoreParams::fields(),
            },
        }
    }
}

impl Node for TrialsScore {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = TrialsScoreParams::read(params)?;
        let sigma = p.sigma;
        if !(sigma.is_finite() && sigma > 0.0) {
            return Err(NodeError::param("sigma", format!("{} %: give a positive spread, e.g. `5 %`", sigma * 100.0)));
        }
        let lapse = p.lapse;
        if !(0.0..0.5).contains(&lapse) {
            return Err(NodeError::param(
                "lapse",
                format!("{} %: give a rate in [0, 50) %, e.g. `2 %`", lapse * 100.0),
            ));
        }
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = TrialsScoreParams::read(ctx.params)?;
        let Value::Lobes(lobes) = ctx.input("lobes")? else {
            return Err(NodeError::input("lobes", "expected stability lobes"));
        };
        let trials = trials_in(p.file)?;
        let score = stability::score_trials(&lobes.speeds_rpm(), &lobes.depth_limit, &trials).map_err(|e| match e {
            StabilityError::InvalidDiagram { .. } => NodeError::input("lobes", e.to_string()),
            other => NodeError::param("file", other.to_string()),
        })?;
        let outside: Vec<String> = trials
            .iter()
            .zip(&score.verdicts)
            .filter(|(_, v)| matches!(v, Verdict::OutsideDiagram))
            .map(|(t, _)| format!("{} rpm", t.speed_rpm))
            .collect();
        if !outside.is_empty() {
            ctx.warn(format!(
                "{} trial(s) outside the diagram's {}–{} rpm, not scored: {}",
                outside.len(),
                lobes.speed.first().map_or(0.0, |s| s.rpm_as_written()),
                lobes.speed.last().map_or(0.0, |s| s.rpm_as_written()),
                outside.join(", ")
            ));
        }
        let fraction = score.fraction_right.ok_or_else(|| {
            NodeError::param("file", "no trial lies inside the diagram's speed range; nothing to score")
        })?;
        let code = |o: Outcome| if o == Outcome::Chatter { 1.0 } else { 0.0 };
        let mut cols: [Vec<f64>; 7] = Default::default();
        for (t, v) in trials.iter().zip(&score.verdicts) {
            let (predicted, right, limit, distance) = match *v {
                Verdict::OutsideDiagram => (-1.0, -1.0, f64::NAN, f64::NAN),
                Verdict::Scored { limit_m, predicted, right, distance_m, .. } => {
                    (code(predicted), f64::from(u8::from(right)), limit_m, distance_m)
                }
            };
            for (c, v) in
                cols.iter_mut().zip([t.speed_rpm, t.depth_m, code(t.outcome), predicted, right, limit, distance])
            {
                c.push(v);
            }
        }
        let [speed, depth, outcome, predicted, right, limit, distance] = cols;
        let misclassified = right.iter().filter(|r| **r == 0.0).count();
        let margin = p.margin;
        let misfit = (0..speed.len())
            .filter(|&k| right[k] >= 0.0 && limit[k] > 0.0)
            .map(|k| {
                // Positive inside the chatter region for a chattering cut, inside the stable one for a stable cut.
                let side = if outcome[k] == 1.0 { 1.0 } else { -1.0 };
                (margin - side * (depth[k] / limit[k]).ln()).max(0.0).powi(2)
            })
            .sum::<f64>()
            .sqrt();
        let likelihood = TrialLikelihood { sigma: p.sigma, lapse: p.lapse };
        let deviance = likelihood.total_deviance(&trials, &score.verdicts);
        let verdicts = Table {
            columns: vec![
                Column::new("speed", "rpm", speed),
                Column::new("depth", "m", depth),
                Column::new("outcome", "", outcome),
                Column::new("predicted", "", predicted),
                Column::new("right", "", right),
                Column::new("limit", "m", limit),
                Column::new("distance", "m", distance),
            ],
        };
        Ok(outputs(vec![
            ("verdicts", Value::Table(verdicts)),
            ("score", Value::Scalar(Scalar::new(fraction, ""))),
            ("misclassified", Value::Scalar(Scalar::new(misclassified as f64, ""))),
            ("misfit", Value::Scalar(Scalar::new(misfit, ""))),
            ("deviance", Value::Scalar(Scalar::new(deviance, ""))),
        ]))
    }
}
