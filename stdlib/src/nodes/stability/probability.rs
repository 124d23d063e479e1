//! `stability.probability`: the probability that a cut is stable over speed and depth, from the uncertainty of
//! the tool-point dynamics and of the cutting coefficients, updated by cutting trials.

use super::{CUTTING, SPEEDS};
use super::{milling_named, outputs, receptance, speeds_rpm, stab_err, trials_in};
use crate::stability::uncertainty::{
    self, Dynamics, Ensemble, Gaussian, ModePrior, QUANTILES, UncertainCut, modal_grid,
};
use crate::stability::{ToolPointFrf, TrialLikelihood};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{Field, FieldType as T, Params};
use spindlelab_engine::value::{Column, Lobes, ModalModel, PortType, Scalar, Table, Value};
use spindlelab_grammar::Dimension as D;
use std::path::Path;

/// The kind name of `stability.probability`.
pub const STABILITY_PROBABILITY: &str = "stability.probability";

const SIGMA_ROW: &[Field] = &[
    Field::req("f", T::Quantity(D::FREQUENCY), "standard deviation of the natural frequency"),
    Field::req("zeta", T::Quantity(D::DIMENSIONLESS), "standard deviation of the damping ratio"),
    Field::req("stiffness", T::Quantity(D::STIFFNESS), "standard deviation of the modal stiffness"),
];

node_params! {
    /// Parameters of `stability.probability`.
    pub struct ProbabilityParams<'a> {
        cutting: req &'a str = CUTTING,
        speeds: req &'a [f64] = SPEEDS,
        max_depth: req f64 = (T::Quantity(D::LENGTH), "deepest cut of the map"),
        depths: def usize = (
            T::Integer { min: 1, max: 2000 },
            "100",
            "depths of the map, evenly from max_depth/depths to max_depth",
        ),
        samples: def usize = (
            T::Integer { min: 10, max: 100_000 },
            "500",
            "Monte Carlo samples of the uncertain parameters (and of the measured FRFs' noise)",
        ),
        seed: def u64 = (T::Integer { min: 0, max: i64::MAX }, "0", "seed of the samples"),
        Ks_sigma: def f64 = (T::Quantity(D::PRESSURE), "0 MPa", "standard deviation of the cutting setup's Ks"),
        beta_sigma: def f64 = (T::Quantity(D::ANGLE), "0 deg", "standard deviation of the cutting setup's β"),
        f_sigma: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "0 %",
            "relative standard deviation of every mode's natural frequency (modes inputs; sigma_x/sigma_y override)",
        ),
        zeta_sigma: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "0 %",
            "relative standard deviation of every mode's damping ratio",
        ),
        stiffness_sigma: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "0 %",
            "relative standard deviation of every mode's modal stiffness",
        ),
        sigma_x: opt &'a [Params] = (
            T::ObjectList(SIGMA_ROW),
            "per mode along x, rows {f, zeta, stiffness} of absolute standard deviations (as a fit reports them), one per mode of modes_x",
        ),
        sigma_y: opt &'a [Params] = (T::ObjectList(SIGMA_ROW), "per mode along y, rows as for sigma_x"),
        averages: def usize = (
            T::Integer { min: 1, max: 100_000 },
            "1",
            "averages behind the measured FRFs' coherence (frf inputs): each line's random error is √(1 − γ²)/(|γ|√(2 n_d))",
        ),
        trials: opt &'a Path = (
            T::File,
            "cutting trials CSV `rpm,depth_mm,outcome[,chatter_freq_hz]` that update the map (importance sampling)",
        ),
        sigma: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "5 %",
            "standard deviation of ln(depth/limit) at the boundary in the trials' likelihood",
        ),
        lapse: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "2 %",
            "chance that a trial's outcome is not the limit's (a mislabelled or disturbed cut)",
        ),
        chatter_sigma: opt f64 = (
            T::Quantity(D::FREQUENCY),
            "standard deviation of a chattering trial's chatter frequency about the sample's (none: frequencies not used)",
        ),
    }
}

/// `stability.probability`: Monte Carlo of the ZOA limit over the uncertain parameters, the probability of
/// stability on a speed × depth grid, the 5/50/95 % lobes, and the posterior given trials.
pub struct StabilityProbability {
    spec: NodeSpec,
}

impl Default for StabilityProbability {
    fn default() -> Self {
        Self::new()
    }
}

impl StabilityProbability {
    pub fn new() -> Self {
        let lobe = |name: &'static str, doc: &'static str| PortSpec::new(name, PortType::Lobes, doc);
        StabilityProbability {
            spec: NodeSpec {
                kind: STABILITY_PROBABILITY,
                version: 1,
                description: "Probability of stability over speed and depth (ZOA, Monte Carlo over Gaussian priors on Ks, β and each mode's f, ζ, k, or over a measured FRF's coherence noise), its 5/50/95 % lobes beside the linearised ones, and the posterior given cutting trials (importance sampling with the probit likelihood of trials.score).",
                inputs: vec![
                    PortSpec::new("modes_x", PortType::ModalModel, "nominal tool-point modes along x (feed)")
                        .optional(),
                    PortSpec::new("modes_y", PortType::ModalModel, "nominal tool-point modes along y").optional(),
                    PortSpec::new(
                        "frf_x",
                        PortType::Frf,
                        "measured tool-point receptance along x with its coherence (instead of modes)",
                    )
                    .optional(),
                    PortSpec::new("frf_y", PortType::Frf, "measured tool-point receptance along y with its coherence")
                        .optional(),
                ],
                outputs: vec![
                    lobe("nominal", "the limit of the nominal parameters (and the FRFs as measured)"),
                    lobe("p05", "5 % lobe: a cut below it is stable with probability ≥ 95 % (posterior with trials)"),
                    lobe("p50", "50 % lobe: the median limit (posterior with trials)"),
                    lobe("p95", "95 % lobe: a cut above it chatters with probability ≥ 95 % (posterior with trials)"),
                    PortSpec::new(
                        "lobes",
                        PortType::Table,
                        "speed (rpm), nominal, prior p05/p50/p95, linearised p05/p95, and with trials posterior \
                         p05/p50/p95 (m), nominal chatter_frequency (Hz) and the median lobe's chatter frequency (Hz)",
                    ),
                    PortSpec::new(
                        "map",
                        PortType::Table,
                        "speed (rpm), depth (m), probability of stability (prior; posterior with trials), \
                         chatter_frequency (Hz, the median lobe's at that speed)",
                    ),
                    PortSpec::new(
                        "parameters",
                        PortType::Table,
                        "per uncertain parameter (name, SI unit): prior mean and σ, posterior mean and σ",
                    ),
                    PortSpec::new(
                        "effective_samples",
                        PortType::Scalar,
                        "(Σw)²/Σw² of the posterior weights (the samples without trials)",
                    ),
                ],
                params: ProbabilityParams::fields(),
            },
        }
    }
}

fn connected(ctx: &NodeContext, port: &str) -> bool {
    ctx.input(port).is_ok()
}

/// Nominal modes with their priors: relative σ for all, or a row per mode.
fn uncertain_modes(
    modes: &[crate::stability::Mode],
    rows: Option<&[Params]>,
    rel: [f64; 3],
    param: &str,
) -> Result<Vec<ModePrior>, NodeError> {
    if let Some(rows) = rows
        && rows.len() != modes.len()
    {
        return Err(NodeError::param(
            param,
            format!("{} rows for {} modes: give one row {{f, zeta, stiffness}} per mode", rows.len(), modes.len()),
        ));
    }
    Ok(modes
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let k = m.modal_mass * (std::f64::consts::TAU * m.freq_hz).powi(2);
            let s = match rows {
                Some(r) => [
                    r[i].f64("f").unwrap_or(0.0),
                    r[i].f64("zeta").unwrap_or(0.0),
                    r[i].f64("stiffness").unwrap_or(0.0),
                ],
                None => [rel[0] * m.freq_hz, rel[1] * m.damping_ratio, rel[2] * k],
            };
            ModePrior {
                freq_hz: Gaussian { mean: m.freq_hz, sigma: s[0] },
                damping_ratio: Gaussian { mean: m.damping_ratio, sigma: s[1] },
                stiffness: Gaussian { mean: k, sigma: s[2] },
            }
        })
        .collect())
}

fn dynamics(ctx: &NodeContext, p: &ProbabilityParams) -> Result<Dynamics, NodeError> {
    let modal = connected(ctx, "modes_x") || connected(ctx, "modes_y");
    let measured = connected(ctx, "frf_x") || connected(ctx, "frf_y");
    match (modal, measured) {
        (true, true) => {
            Err(NodeError::input("frf_x", "give modes (modes_x, modes_y) or measured FRFs (frf_x, frf_y), not both"))
        }
        (false, false) => Err(NodeError::input("modes_x", "connect modes_x and modes_y, or frf_x and frf_y")),
        (true, false) => {
            let get = |port: &str| -> Result<Vec<crate::stability::Mode>, NodeError> {
                match ctx.input(port) {
                    Ok(Value::ModalModel(ModalModel { modes })) => Ok(modes.clone()),
                    Ok(_) => Err(NodeError::input(port, "expected a modal model")),
                    Err(_) => Ok(Vec::new()),
                }
            };
            let rel = [p.f_sigma, p.zeta_sigma, p.stiffness_sigma];
            let x = uncertain_modes(&get("modes_x")?, p.sigma_x, rel, "sigma_x")?;
            let y = uncertain_modes(&get("modes_y")?, p.sigma_y, rel, "sigma_y")?;
            let all: Vec<ModePrior> = x.iter().chain(&y).copied().collect();
            if all.is_empty() {
                return Err(NodeError::input(
                    "modes_x",
                    "neither modes_x nor modes_y holds a mode: nothing can chatter",
                ));
            }
            Ok(Dynamics::Modes { freqs_hz: modal_grid(&all), x, y })
        }
        (false, true) => {
            let (fx, fy) = (receptance(ctx, "frf_x")?, receptance(ctx, "frf_y")?);
            let frf = ToolPointFrf::from_pair(&fx.freq_hz, fx.values.clone(), &fy.freq_hz, fy.values.clone())
                .map_err(|e| stab_err(e, "frf_y"))?;
            let coherence = |port: &str, f: &spindlelab_engine::value::Frf| -> Result<Vec<f64>, NodeError> {
                f.coherence.clone().ok_or_else(|| {
                    NodeError::input(
                        port,
                        "this FRF has no coherence, so its noise is unknown: estimate it from impacts \
                         (frf.estimate) or give modes with σ instead",
                    )
                })
            };
            let (cx, cy) = (coherence("frf_x", fx)?, coherence("frf_y", fy)?);
            if cx.len() != frf.freqs_hz.len() || cy.len() != frf.freqs_hz.len() {
                return Err(NodeError::input("frf_y", "frf_x and frf_y must share one frequency grid"));
            }
            Ok(Dynamics::Measured { frf, coherence_x: cx, coherence_y: cy, averages: p.averages })
        }
    }
}

impl Node for StabilityProbability {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = ProbabilityParams::read(params)?;
        super::positive(params, &["max_depth", "sigma"])?;
        super::non_negative(params, &["Ks_sigma", "beta_sigma", "f_sigma", "zeta_sigma", "stiffness_sigma"])?;
        if !(0.0..0.5).contains(&p.lapse) {
            return Err(NodeError::param(
                "lapse",
                format!("{} %: give a rate in [0, 50) %, e.g. `2 %`", p.lapse * 100.0),
            ));
        }
        if p.chatter_sigma.is_some() {
            super::positive(params, &["chatter_sigma"])?;
        }
        speeds_rpm(p.speeds).map(|_| ())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = ProbabilityParams::read(ctx.params)?;
        let milling = milling_named(ctx, p.cutting)?;
        let (kt, kn) = (milling.coefficients.kt, milling.coefficients.kn);
        let cut = UncertainCut {
            dynamics: dynamics(ctx, &p)?,
            milling,
            ks: Gaussian { mean: kt.hypot(kn), sigma: p.Ks_sigma },
            beta_rad: Gaussian { mean: kt.atan2(kn), sigma: p.beta_sigma },
        };
        let port = if matches!(cut.dynamics, Dynamics::Modes { .. }) { "modes_x" } else { "frf_x" };
        let speeds = speeds_rpm(p.speeds)?;
        let trials = p.trials.map(trials_in).transpose()?.unwrap_or_default();
        // The samples are evaluated at the map's speeds and at the trials' speeds.
        let mut all: Vec<f64> = speeds.iter().copied().chain(trials.iter().map(|t| t.speed_rpm)).collect();
        all.sort_by(f64::total_cmp);
        all.dedup();
        let grid: Vec<usize> = speeds.iter().map(|s| all.partition_point(|a| a < s)).collect();
        let ens = uncertainty::sample_ensemble(&cut, &all, p.samples, p.seed).map_err(|e| stab_err(e, port))?;
        let lin = uncertainty::linearised(&cut, &speeds).map_err(|e| stab_err(e, port))?;
        let depths: Vec<f64> = (1..=p.depths).map(|j| p.max_depth * j as f64 / p.depths as f64).collect();
        let prior = uncertainty::probability_map(&ens, None, &grid, &depths);
        let posterior = if trials.is_empty() {
            None
        } else {
            let lik = TrialLikelihood { sigma: p.sigma, lapse: p.lapse };
            let post = uncertainty::update(&ens, &trials, &lik, p.chatter_sigma).map_err(|e| match e {
                crate::stability::StabilityError::InvalidTrial { .. } => NodeError::param("trials", e.to_string()),
                e => stab_err(e, port),
            })?;
            if post.effective_samples < 20.0 {
                ctx.warn(format!(
                    "the trials leave {:.1} effective samples of {}: the posterior rests on few samples; raise \
                     `samples` or widen the priors",
                    post.effective_samples, p.samples
                ));
            }
            let map = uncertainty::probability_map(&ens, Some(&post.weights), &grid, &depths);
            Some((post, map))
        };
        let shown = posterior.as_ref().map_or(&prior, |(_, m)| m);
        let nominal: Vec<f64> = grid.iter().map(|&i| ens.nominal_depth_m[i]).collect();
        let nominal_chatter: Vec<f64> = grid.iter().map(|&i| ens.nominal_chatter_hz[i]).collect();
        let quantile =
            |m: &uncertainty::ProbabilityMap, q: usize| -> Vec<f64> { m.lobes_m.iter().map(|l| l[q]).collect() };
        let chatter =
            |m: &uncertainty::ProbabilityMap, q: usize| -> Vec<f64> { m.chatter_hz.iter().map(|l| l[q]).collect() };
        let lobes_of = |q: usize| Lobes::from_rpm(&speeds, quantile(shown, q), chatter(shown, q));
        let mut columns =
            vec![Column::new("speed", "rpm", speeds.clone()), Column::new("nominal", "m", nominal.clone())];
        for (q, name) in QUANTILES.iter().enumerate().map(|(k, _)| k).zip(["prior_p05", "prior_p50", "prior_p95"]) {
            columns.push(Column::new(name, "m", quantile(&prior, q)));
        }
        columns.push(Column::new("linearised_p05", "m", lin.lobe(0.05)));
        columns.push(Column::new("linearised_p95", "m", lin.lobe(0.95)));
        if let Some((_, m)) = &posterior {
            for (q, name) in [(0, "posterior_p05"), (1, "posterior_p50"), (2, "posterior_p95")] {
                columns.push(Column::new(name, "m", quantile(m, q)));
            }
        }
        columns.push(Column::new("chatter_frequency", "Hz", nominal_chatter.clone()));
        columns.push(Column::new("median_chatter_frequency", "Hz", chatter(shown, 1)));
        let (mut ms, mut md, mut mp, mut mc) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (i, s) in speeds.iter().enumerate() {
            for (j, b) in depths.iter().enumerate() {
                ms.push(*s);
                md.push(*b);
                mp.push(prior.at(i, j));
                mc.push(shown.chatter_hz[i][1]);
            }
        }
        let mut map_columns =
            vec![Column::new("speed", "rpm", ms), Column::new("depth", "m", md), Column::new("probability", "", mp)];
        if let Some((_, m)) = &posterior {
            let post: Vec<f64> = (0..speeds.len())
                .flat_map(|i| (0..depths.len()).map(move |j| (i, j)))
                .map(|(i, j)| m.at(i, j))
                .collect();
            map_columns.push(Column::new("posterior_probability", "", post));
        }
        map_columns.push(Column::new("chatter_frequency", "Hz", mc));
        let parameters = parameter_table(&ens, posterior.as_ref().map(|(p, _)| p.weights.as_slice()));
        let effective = posterior.as_ref().map_or(p.samples as f64, |(post, _)| post.effective_samples);
        Ok(outputs(vec![
            ("nominal", Value::Lobes(Lobes::from_rpm(&speeds, nominal, nominal_chatter))),
            ("p05", Value::Lobes(lobes_of(0))),
            ("p50", Value::Lobes(lobes_of(1))),
            ("p95", Value::Lobes(lobes_of(2))),
            ("lobes", Value::Table(Table { columns })),
            ("map", Value::Table(Table { columns: map_columns })),
            ("parameters", Value::Table(parameters)),
            ("effective_samples", Value::Scalar(Scalar::new(effective, ""))),
        ]))
    }
}

/// Prior and posterior moments of each uncertain parameter.
fn parameter_table(ens: &Ensemble, weights: Option<&[f64]>) -> Table {
    let prior: Vec<Gaussian> = ens.parameters.iter().map(|p| p.prior).collect();
    let post = uncertainty::moments(ens, weights);
    let names: Vec<&str> = ens.parameters.iter().map(|p| p.name.as_str()).collect();
    let units: Vec<&str> = ens.parameters.iter().map(|p| if p.unit.is_empty() { "1" } else { p.unit }).collect();
    Table {
        columns: vec![
            Column::text("name", &names),
            Column::text("unit", &units),
            Column::new("prior_mean", "", prior.iter().map(|g| g.mean).collect()),
            Column::new("prior_sigma", "", prior.iter().map(|g| g.sigma).collect()),
            Column::new("posterior_mean", "", post.iter().map(|m| m.0).collect()),
            Column::new("posterior_sigma", "", post.iter().map(|m| m.1).collect()),
        ],
    }
}
