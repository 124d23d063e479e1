//! Diagnosis: where a model and its measurements disagree, which physical effect the model
//! lacks, the model with that effect added, and the gap before and after.
//!
//! 1. **Locate.** The recipe runs as written; every measured FRF's gap ratio is judged
//!    against its own noise: at the floor `ratio²` is 1 ± 1/√n_eff, so a file disagrees
//!    when `z = (ratio² − 1)√n_eff` exceeds [`Z_DISCREPANT`]. The cutting trials are the
//!    second witness.
//! 2. **Explain.** Every effect of the library ([`effects`]) is added to the recipe as a
//!    transform with bounded parameters and fitted to the measured FRFs by the fit driver.
//! 3. **Select.** Each candidate is scored by BIC: the deviance `Σ 2 n_eff ratio²` (a χ²
//!    with 2 n_eff degrees of freedom per file at the floor), plus the trials' deviance
//!    under the probit likelihood of `trials.score`, plus `k ln n` for k parameters. An
//!    effect is named when it beats the model without it by [`BIC_STRONG`] and brings every
//!    file to the floor; pairs are tried when no single effect does; when none does, one
//!    mode outside the library stands in where the largest discrepancy remains, and an
//!    effect is named beside it when together they explain every file and beat the mode
//!    alone ([`locate_unknown`]).
//!    What nothing explains is reported with its place — files and trials — never forced
//!    onto a name.
//! 4. **Add** and **show.** The named effects are written into the recipe at their fitted
//!    values (`diagnosed.yaml`), which runs again for the gap after.

pub mod batch;
pub mod effects;
pub mod roles;

use crate::engine::diag::Diagnostics;
use crate::engine::exec::{self, Memo, Outcome, OutputDir, RunOptions};
use crate::engine::node::Registry;
use crate::engine::syntax::Raw;
use crate::engine::syntax::edit::{self, RecipeText};
use crate::engine::value::{Table, Value};
use crate::engine::{Compiled, compile_raw};
use crate::fit::{FitReport, FittedParam};
use effects::{Effect, Free, Scope};
use rayon::prelude::*;
use roles::Roles;
use serde::Serialize;
use serde_json::{Map, Value as Json};
use spindlelab_domain::Speed;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// A file disagrees with the model when its ratio² lies this many standard deviations
/// above the floor.
pub const Z_DISCREPANT: f64 = 5.0;
/// "Very strong" evidence on the Kass–Raftery scale: the BIC difference an effect must
/// win by to be named.
pub const BIC_STRONG: f64 = 10.0;
/// The least share of a pair's evidence (its ΔBIC over the model as written) its weaker effect
/// must carry, as the pair's gain over the stronger alone, when the stronger alone already
/// takes the gap to a form misfit: one that adds a sliver there is fitting the stronger
/// one's residual, not naming a cause.
pub const MIN_PAIR_SHARE: f64 = 0.01;
/// A file whose noise floor exceeds this relative level carries no usable signal.
pub const MAX_NOISE_FLOOR: f64 = 0.5;

/// Why a diagnosis could not run; the input is at fault (exit 2) unless it is I/O.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    #[error("{0}")]
    Input(String),
    #[error("{path}: {message}")]
    Recipe { path: String, message: String },
    /// The output folder is busy, holds a planted link, or cannot be written.
    #[error("{0}")]
    Output(exec::CommitError),
}

/// One measured FRF's gap.
#[derive(Debug, Clone, Serialize)]
pub struct FileGap {
    pub file: String,
    pub direction: String,
    pub speed_rpm: f64,
    pub noise_floor: f64,
    pub rel_l2: f64,
    pub ratio: f64,
    pub n_eff: f64,
    pub max_discrepancy_hz: f64,
    /// Where the noise-weighted residual is above half its peak, around the peak (Hz).
    pub band_hz: [f64; 2],
    /// The first and last measured line the gap compares, Hz.
    #[serde(skip)]
    pub span_hz: [f64; 2],
    /// The model and the measured FRF the gap compares, for the pictures.
    #[serde(skip)]
    pub frfs: Option<(Arc<Value>, Arc<Value>)>,
}

impl FileGap {
    /// Standard deviations of ratio² above the floor.
    pub fn z(&self) -> f64 {
        (self.ratio * self.ratio - 1.0) * self.n_eff.sqrt()
    }
    pub fn discrepant(&self) -> bool {
        self.z() > Z_DISCREPANT
    }
}

/// A cutting trial the model's lobes classify wrong.
#[derive(Debug, Clone, Serialize)]
pub struct TrialMiss {
    pub speed_rpm: f64,
    pub depth_mm: f64,
    /// What the cut did: `stable` or `chatter`.
    pub outcome: &'static str,
    /// The diagram's limit at that speed, mm.
    pub limit_mm: f64,
    /// `ln(depth/limit)`: how far the trial lies from the lobe, on the wrong side.
    pub margin: f64,
}

/// A model evaluated against the measurements.
#[derive(Debug, Clone, Serialize)]
pub struct Evaluation {
    pub files: Vec<FileGap>,
    /// Trials scored and misclassified, when the recipe scores trials.
    pub trials: Option<(usize, usize)>,
    /// The trials' speeds (rpm), ascending and distinct.
    #[serde(skip)]
    pub trial_speeds_rpm: Vec<f64>,
    /// The trials the lobes classify wrong, in the file's order.
    #[serde(skip)]
    pub wrong_trials: Vec<TrialMiss>,
    /// `−2 ln L` of the trials under the probit likelihood, when the recipe scores trials.
    pub trial_deviance: Option<f64>,
}

impl Evaluation {
    /// `Σ 2 n_eff ratio²`: −2 ln L of the FRFs up to a constant.
    pub fn deviance(&self) -> f64 {
        self.files.iter().map(|f| 2.0 * f.n_eff * f.ratio * f.ratio).sum()
    }
    /// `−2 ln L` of the trials: the probit likelihood of `trials.score` (a cut chatters with
    /// probability `ε + (1 − 2ε) Φ(ln(depth/limit)/σ)`, σ = 5 %, ε = 2 %).
    fn trial_cost(&self) -> f64 {
        self.trial_deviance.unwrap_or(0.0)
    }
    fn observations(&self) -> f64 {
        let n: f64 = self.files.iter().map(|f| 2.0 * f.n_eff).sum::<f64>() + self.trials.map_or(0.0, |t| t.0 as f64);
        n.max(2.0)
    }
    pub fn at_floor(&self) -> bool {
        self.files.iter().all(|f| !f.discrepant())
    }
    pub fn misclassified(&self) -> usize {
        self.trials.map_or(0, |t| t.1)
    }
}

/// One effect (or pair) fitted and judged.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    pub effects: Vec<&'static str>,
    /// In the vocabulary's names and units, per effect.
    pub params: Map<String, Json>,
    /// The recipe parameters as fitted, with uncertainty.
    pub fitted: Vec<FittedParam>,
    pub bic: f64,
    /// BIC of the model without it minus BIC with it (positive: the effect is better).
    pub delta_bic: f64,
    /// Every file at the noise floor with the effect.
    pub explains: bool,
    pub ratios_after: Vec<f64>,
    pub trials_misclassified_after: Option<usize>,
    pub evaluations: usize,
    pub converged: bool,
    pub seconds: f64,
    /// Why the effect was not fitted (it does not apply to this recipe) or the fit failed.
    pub skipped: Option<String>,
    #[serde(skip)]
    evaluation: Option<Evaluation>,
    #[serde(skip)]
    values: Vec<(String, f64)>,
}

/// A measured FRF the model leaves above its noise floor.
#[derive(Debug, Clone, Serialize)]
pub struct FrfDiscrepancy {
    pub direction: String,
    pub speed_rpm: f64,
    pub near_hz: f64,
    pub band_hz: [f64; 2],
    pub ratio: f64,
    /// One mode along this direction that brings the files to the floor (beside the named
    /// effects), when one does: where the missing resonance is, and how stiff and damped.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resonance: Option<UnknownMode>,
}

/// A mode outside the library that explains what the named effects leave.
#[derive(Debug, Clone, Serialize)]
pub struct UnknownMode {
    pub direction: String,
    pub f_hz: f64,
    pub zeta: f64,
    pub stiffness_n_per_m: f64,
}

/// A discrepancy left without a name: where it is, never forced onto an effect.
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Unexplained {
    /// A measured FRF off the floor: its direction, speed and the band of the largest discrepancy.
    Frf(FrfDiscrepancy),
    /// A cutting trial the diagnosed model still classifies wrong.
    Trial(TrialMiss),
}

impl Unexplained {
    /// The FRF discrepancy, if this is one.
    pub fn frf(&self) -> Option<&FrfDiscrepancy> {
        match self {
            Unexplained::Frf(f) => Some(f),
            Unexplained::Trial(_) => None,
        }
    }
    /// The trial, if this is one.
    pub fn trial(&self) -> Option<&TrialMiss> {
        match self {
            Unexplained::Trial(t) => Some(t),
            Unexplained::Frf(_) => None,
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct NamedEffect {
    pub name: &'static str,
    pub params: Json,
    pub uncertainty: Json,
    pub evidence: Json,
}

#[derive(Debug, Clone, Serialize)]
pub struct GapFile {
    pub file: String,
    pub direction: String,
    pub speed_rpm: f64,
    pub noise_floor: f64,
    pub rel_l2_before: f64,
    pub rel_l2_after: f64,
    pub ratio_before: f64,
    pub ratio_after: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct GapTrials {
    pub n: usize,
    pub misclassified_before: usize,
    pub misclassified_after: usize,
}

#[derive(Debug, Clone, Serialize)]
pub struct GapReport {
    pub files: Vec<GapFile>,
    pub trials: Option<GapTrials>,
}

/// `diagnosis.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    pub verdict: &'static str,
    pub effects: Vec<NamedEffect>,
    pub unexplained: Vec<Unexplained>,
    pub gap: GapReport,
    pub candidates: Vec<Candidate>,
    /// What the search declined to name, and why.
    pub notes: Vec<String>,
    pub recipe: String,
    pub seconds: f64,
    #[serde(skip)]
    pub diagnosed_recipe: String,
    /// What the pictures beside `diagnosis.md` draw.
    #[serde(skip)]
    pub pictures: Pictures,
}

/// One measured file's picture: its name, the measurement, the model before and (when
/// effects were added) after.
#[derive(Debug, Clone)]
pub struct FilePicture {
    pub file: String,
    pub measured: Arc<Value>,
    pub before: Arc<Value>,
    pub after: Option<Arc<Value>>,
}

/// The values behind the diagnosis's pictures.
#[derive(Debug, Clone, Default)]
pub struct Pictures {
    /// Per measured file: the measurement with the model before and after.
    pub files: Vec<FilePicture>,
    /// The full stability diagram before and after, with the trials' verdicts of each.
    pub lobes_before: Option<(Arc<Value>, Arc<Value>)>,
    pub lobes_after: Option<(Arc<Value>, Arc<Value>)>,
}

pub const VERDICT_EFFECTS: &str = "effects";
pub const VERDICT_NONE: &str = "no significant discrepancy";
pub const VERDICT_UNEXPLAINED: &str = "unexplained discrepancy";
/// Named effects explain part of the discrepancy; `unexplained` lists the rest.
pub const VERDICT_PARTIAL: &str = "effects and an unexplained discrepancy";

/// Compiles a recipe text as if it were the file at `path` (data files resolve beside it).
fn compile_text(
    r: &RecipeText,
    path: &Path,
    set: &[(String, String)],
    registry: &Registry,
) -> Result<Compiled, String> {
    compile_raw(path, r.raw.clone(), set, vec![r.source()], registry, Diagnostics::new()).map_err(|e| e.render(false))
}

fn table_value(t: &Table, name: &str) -> f64 {
    t.columns.iter().find(|c| c.name == name).and_then(|c| c.values.first().copied()).unwrap_or(f64::NAN)
}

/// The region around the residual's peak where it stays above half the peak (smoothed).
fn band_around(freq: &[f64], r: &[num_complex::Complex64]) -> [f64; 2] {
    if freq.is_empty() {
        return [f64::NAN; 2];
    }
    let n = r.len();
    let mag: Vec<f64> = (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(2), (k + 3).min(n));
            r[a..b].iter().map(|v| v.norm()).sum::<f64>() / (b - a) as f64
        })
        .collect();
    let k = (0..n).fold(0, |b, k| if mag[k] > mag[b] { k } else { b });
    let half = 0.5 * mag[k];
    let (mut lo, mut hi) = (k, k);
    while lo > 0 && mag[lo - 1] >= half {
        lo -= 1;
    }
    while hi + 1 < n && mag[hi + 1] >= half {
        hi += 1;
    }
    [freq[lo], freq[hi]]
}

/// Where a resonance outside the library would sit: along the direction of the file most
/// off the floor, in a band around its largest discrepancy (the half-peak band of the
/// residual, widened to twice its width or 5 % of its centre either side, within the measured
/// lines). `None` when every file is at the floor.
fn locate_unknown(e: &Evaluation) -> Option<effects::UnknownResonance> {
    let f = e.files.iter().filter(|f| f.discrepant()).max_by(|a, b| a.z().total_cmp(&b.z()))?;
    let [lo, hi] = f.band_hz;
    let [first, last] = f.span_hz;
    if !(lo.is_finite() && hi.is_finite() && first.is_finite() && last.is_finite()) {
        return None;
    }
    let (centre, half) = (0.5 * (lo + hi), (hi - lo).max(0.05 * 0.5 * (lo + hi)));
    let band = [(centre - 2.0 * half).max(first.max(1.0)), (centre + 2.0 * half).min(last)];
    (band[1] > band[0]).then(|| effects::UnknownResonance { direction: f.direction.clone(), band_hz: band })
}

/// Runs the gaps and the trials of a compiled recipe in memory.
fn evaluate(
    c: &Compiled,
    roles: &Roles,
    registry: &Registry,
    memo: Option<Arc<Memo>>,
) -> Result<(Evaluation, Memo), String> {
    let mut targets: Vec<String> = roles.gaps.iter().map(|g| g.step.clone()).collect();
    targets.extend(roles.trials.clone());
    let opts = RunOptions {
        use_cache: false,
        memo,
        targets: Some(targets),
        renderer: Some(crate::renderer()),
        ..RunOptions::new(std::env::temp_dir())
    };
    let result = exec::execute(&c.recipe, &c.graph, registry, &opts, &|_, _| {});
    let outputs = |i: usize| -> Result<&crate::engine::exec::Produced, String> {
        match &result.outcomes[i] {
            Outcome::Failed(e) => Err(format!("`{}` failed: {e}", c.graph.instances[i].id)),
            o => o.outputs().map(|o| o.as_ref()).ok_or_else(|| format!("`{}` did not run", c.graph.instances[i].id)),
        }
    };
    let mut files = Vec::new();
    for g in &roles.gaps {
        for &i in &c.graph.by_step[&g.step] {
            let out = outputs(i)?;
            let Some(Value::Table(t)) = out.get("summary").map(|v| v.as_ref()) else {
                return Err(format!("`{}` gave no summary", c.graph.instances[i].id));
            };
            let (band, span_hz) = match out.get("residual").map(|v| v.as_ref()) {
                Some(Value::Frf(r)) => (
                    band_around(&r.freq_hz, &r.values),
                    [r.freq_hz.first().copied().unwrap_or(f64::NAN), r.freq_hz.last().copied().unwrap_or(f64::NAN)],
                ),
                _ => ([f64::NAN; 2], [f64::NAN; 2]),
            };
            let input = |port: &str| -> Option<Arc<Value>> {
                let (producer, out_port) = c.graph.instances[i].inputs.get(port)?.first()?;
                result.outcomes[*producer].outputs()?.get(out_port).cloned()
            };
            let frfs = input("model").zip(input("measured"));
            let label = &c.graph.instances[i].label;
            let file = label
                .split(", ")
                .find_map(|a| a.strip_prefix("file="))
                .map_or_else(|| c.graph.instances[i].id.clone(), str::to_string);
            let direction = t
                .columns
                .iter()
                .find(|c| c.name == "direction")
                .and_then(|c| c.word(0))
                .filter(|d| !d.is_empty())
                .unwrap_or("?");
            files.push(FileGap {
                file,
                direction: direction.to_string(),
                speed_rpm: table_value(t, "speed"),
                noise_floor: table_value(t, "noise_floor"),
                rel_l2: table_value(t, "rel_l2"),
                ratio: table_value(t, "ratio"),
                n_eff: table_value(t, "n_eff"),
                max_discrepancy_hz: table_value(t, "max_discrepancy"),
                band_hz: band,
                span_hz,
                frfs,
            });
        }
    }
    let mut trials = None;
    let mut trial_speeds = Vec::new();
    let mut wrong_trials = Vec::new();
    let mut trial_deviance = None;
    if let Some(step) = &roles.trials {
        let i = c.graph.by_step[step][0];
        let out = outputs(i)?;
        if let Some(Value::Scalar(d)) = out.get("deviance").map(|v| v.as_ref()) {
            trial_deviance = Some(d.value);
        }
        if let Some(Value::Table(t)) = out.get("verdicts").map(|v| v.as_ref()) {
            let column =
                |name: &str| t.columns.iter().find(|c| c.name == name).map(|c| c.values.clone()).unwrap_or_default();
            let right = column("right");
            let scored = right.iter().filter(|r| **r >= 0.0).count();
            let (speed, depth, outcome, limit) = (column("speed"), column("depth"), column("outcome"), column("limit"));
            for (k, _) in right.iter().enumerate().filter(|(_, r)| **r == 0.0) {
                let at = |v: &[f64]| v.get(k).copied().unwrap_or(f64::NAN);
                wrong_trials.push(TrialMiss {
                    speed_rpm: at(&speed),
                    depth_mm: at(&depth) * 1e3,
                    outcome: if at(&outcome) == 1.0 { "chatter" } else { "stable" },
                    limit_mm: at(&limit) * 1e3,
                    margin: (at(&depth) / at(&limit)).ln(),
                });
            }
            trials = Some((scored, wrong_trials.len()));
            trial_speeds = speed;
            trial_speeds.sort_by(f64::total_cmp);
            trial_speeds.dedup();
        }
    }
    Ok((
        Evaluation { files, trials, trial_speeds_rpm: trial_speeds, wrong_trials, trial_deviance },
        result.memo(&c.graph),
    ))
}

/// The text to evaluate: the stability diagram at the trials' speeds only (each speed's
/// limit is computed on its own, so the trials' verdicts are exactly those of the full
/// diagram, at a fraction of the cost).
fn at_trial_speeds(r: &RecipeText, roles: &Roles, trial_speeds: &[f64]) -> Result<RecipeText, String> {
    let mut r = r.clone();
    if let (Some(lobes), false) = (&roles.lobes, trial_speeds.is_empty()) {
        let speeds = Raw::list(trial_speeds.iter().map(|s| Raw::text(format!("{s} rpm"))).collect());
        r.set_key(&edit::path(&["steps", lobes, "params"]), "speeds", &speeds).map_err(|e| e.to_string())?;
    }
    Ok(r)
}

/// The most speeds a picture's diagram is drawn at, besides the trials' own.
const PICTURE_SPEEDS: usize = 1001;

/// The recipe with its lobes at no more than [`PICTURE_SPEEDS`] of its own speeds, evenly
/// spread over them, and at every trial's speed (so a trial is judged where it was cut): a
/// picture does not need a diagram at every rpm step, and a fine grid over a wide range costs
/// seconds. A recipe with fewer speeds, or one that cannot be edited, is drawn as written.
fn at_picture_speeds(r: &RecipeText, roles: &Roles, c: &Compiled, trial_speeds: &[f64]) -> RecipeText {
    let Some(lobes) = &roles.lobes else { return r.clone() };
    let Some(own) = c.recipe.step(lobes).and_then(|s| s.params.list("speeds")) else { return r.clone() };
    if own.len() <= PICTURE_SPEEDS {
        return r.clone();
    }
    let rpm = |w: f64| Speed::from_rad_s(w).rpm();
    let last = own.len() - 1;
    let mut speeds: Vec<f64> = (0..PICTURE_SPEEDS).map(|i| rpm(own[i * last / (PICTURE_SPEEDS - 1)])).collect();
    speeds.extend(trial_speeds.iter().copied());
    speeds.sort_by(f64::total_cmp);
    speeds.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * b.abs());
    at_trial_speeds(r, roles, &speeds).unwrap_or_else(|_| r.clone())
}

/// The distinct speeds (rpm) of the scored trials, read from the trials file; empty when
/// the recipe scores none or the file cannot be read (the run then says why).
fn trial_speeds(c: &Compiled, roles: &Roles) -> Vec<f64> {
    let Some(file) = roles.trials.as_ref().and_then(|t| c.recipe.step(t)).and_then(|s| s.params.file("file")) else {
        return vec![];
    };
    let Ok(text) = crate::engine::formats::read_text_capped(file, crate::engine::formats::MAX_DATA_BYTES) else {
        return vec![];
    };
    let Ok(trials) = crate::stdlib::nodes::parse_trials(&text, &file.display().to_string()) else { return vec![] };
    let mut speeds: Vec<f64> = trials.iter().map(|t| t.speed_rpm).collect();
    speeds.sort_by(f64::total_cmp);
    speeds.dedup();
    speeds
}

/// The full stability diagram of a recipe text (its own speeds, not the trials') and the
/// trials' verdicts on it, for the pictures; `None` when the recipe scores no trials.
fn diagram(
    r: &RecipeText,
    path: &Path,
    roles: &Roles,
    registry: &Registry,
    memo: Arc<Memo>,
) -> Option<(Arc<Value>, Arc<Value>)> {
    let trials = roles.trials.as_ref()?;
    let c = compile_text(r, path, &[], registry).ok()?;
    let opts = RunOptions {
        use_cache: false,
        memo: Some(memo),
        targets: Some(vec![trials.clone()]),
        renderer: Some(crate::renderer()),
        ..RunOptions::new(std::env::temp_dir())
    };
    let result = exec::execute(&c.recipe, &c.graph, registry, &opts, &|_, _| {});
    let i = *c.graph.by_step.get(trials)?.first()?;
    let verdicts = result.outcomes[i].outputs()?.get("verdicts")?.clone();
    let (producer, port) = c.graph.instances[i].inputs.get("lobes")?.first()?;
    let lobes = result.outcomes[*producer].outputs()?.get(port)?.clone();
    Some((lobes, verdicts))
}

/// The fit block for `free`, minimising `objective`.
fn fit_block(free: &[Free], objective: &[String], method: &str, starts: usize) -> Raw {
    let most = starts + (100 * free.len()).max(200);
    let free = free.iter().map(|f| {
        let mut bounds = vec![("min", f.value(f.min)), ("max", f.value(f.max))];
        if f.log {
            bounds.push(("scale", Raw::text("log")));
        }
        (f.name.clone(), Raw::mapping(bounds))
    });
    Raw::mapping([
        ("free", Raw::mapping(free)),
        ("objective", Raw::list(objective.iter().map(|o| Raw::text(o.as_str())).collect())),
        ("method", Raw::text(method)),
        ("starts", Raw::int(starts as i64)),
        // The sampled starts come on top of what the local searches may take; those stop on
        // convergence, the count only bounds a search that never settles.
        ("max_evaluations", Raw::int(most as i64)),
    ])
}

/// Context shared by every candidate fit.
struct Ctx<'a> {
    path: &'a Path,
    base: &'a RecipeText,
    compiled: &'a Compiled,
    roles: &'a Roles,
    registry: &'a Registry,
    baseline: &'a Evaluation,
    memo: Arc<Memo>,
}

/// Adds `effects` (in library order) to the base text, declaring their parameters at
/// `starts` where given.
fn augmented(ctx: &Ctx, effects: &[&dyn Effect], starts: &[(String, f64)]) -> Result<(RecipeText, Vec<Free>), String> {
    let mut r = ctx.base.clone();
    let mut free = Vec::new();
    for e in effects {
        free.extend(e.apply(ctx.roles, ctx.compiled, &mut r)?);
    }
    for f in free.iter_mut() {
        if let Some((_, v)) = starts.iter().find(|(n, _)| *n == f.name) {
            f.start = v.clamp(f.min, f.max);
            r.declare_param(&f.name, &f.value(f.start)).map_err(|e| e.to_string())?;
        }
    }
    Ok((r, free))
}

/// Fits `effects` to the measurements (the FRF gaps, or the trials for a cutting effect)
/// on top of the model `on`, and judges the result against `reference`.
fn try_candidate(
    ctx: &Ctx,
    effects: &[&dyn Effect],
    on: &[&dyn Effect],
    on_values: &[(String, f64)],
    starts_at: &[(String, f64)],
    reference: &Evaluation,
) -> Candidate {
    let t0 = Instant::now();
    let names: Vec<&'static str> = effects.iter().map(|e| e.name()).collect();
    let mut c = Candidate {
        effects: names,
        params: Map::new(),
        fitted: vec![],
        bic: f64::INFINITY,
        delta_bic: f64::NEG_INFINITY,
        explains: false,
        ratios_after: vec![],
        trials_misclassified_after: None,
        evaluations: 0,
        converged: false,
        seconds: 0.0,
        skipped: None,
        evaluation: None,
        values: vec![],
    };
    let mut all: Vec<&dyn Effect> = on.to_vec();
    all.extend(effects.iter().copied());
    let lib = effects::library(ctx.registry);
    let order = |e: &&dyn Effect| lib.iter().position(|l| l.name() == e.name()).unwrap_or(usize::MAX);
    all.sort_by_key(order);
    let (mut text, free) = match augmented(ctx, &all, starts_at) {
        Ok(v) => v,
        Err(e) => {
            c.skipped = Some(e);
            return c;
        }
    };
    // The model it builds on stays at its values; only this candidate's parameters move.
    let mine: Vec<Free> = free.iter().filter(|f| !on_values.iter().any(|(n, _)| *n == f.name)).cloned().collect();
    for (n, v) in on_values {
        if let Some(f) = free.iter().find(|f| f.name == *n) {
            let _ = text.declare_param(n, &f.value(*v));
        }
    }
    let cutting = effects.iter().all(|e| e.scope() == Scope::Cutting);
    let (objective, method) = match (cutting, &ctx.roles.trials) {
        // The trials' likelihood, which sets the boundary where the stable and the
        // chattering cuts are best told apart.
        (true, Some(t)) => (vec![format!("@{t}.deviance")], "nelder-mead"),
        _ => (ctx.roles.gaps.iter().map(|g| format!("@{}.residual", g.step)).collect(), "least-squares"),
    };
    let text = match at_trial_speeds(&text, ctx.roles, &ctx.baseline.trial_speeds_rpm) {
        Ok(t) => t,
        Err(e) => {
            c.skipped = Some(e);
            return c;
        }
    };
    // A cutting effect is informed by the trials alone; the rest by the FRFs and trials.
    let observations = |after: &Evaluation| {
        if cutting { after.trials.map_or(2.0, |t| t.0.max(2) as f64) } else { after.observations() }
    };
    // The FRF candidates are fitted side by side, one thread each; a cutting effect is fitted
    // alone, after them, and its lobes take every core.
    let threads = if cutting { None } else { Some(1) };
    // Fits the parameters `free` (the rest held where they start) and scores the result.
    let attempt = |free: &[Free]| -> Result<(FitReport, Evaluation, f64), String> {
        let starts = if starts_at.is_empty() { effects.iter().map(|e| e.starts(free)).max().unwrap_or(0) } else { 0 };
        let mut fitting = text.clone();
        fitting.append("fit", &fit_block(free, &objective, method, starts)).map_err(|e| e.to_string())?;
        let compiled = compile_text(&fitting, ctx.path, &[], ctx.registry)
            .map_err(|e| format!("the augmented recipe does not compile: {e}"))?;
        let report =
            crate::fit::fit(&compiled, &[], ctx.registry, threads).map_err(|e| format!("the fit failed: {e}"))?;
        let after = compile_text(&text, ctx.path, &report.overrides(), ctx.registry)
            .and_then(|x| evaluate(&x, ctx.roles, ctx.registry, Some(Arc::clone(&ctx.memo))).map(|e| e.0))
            .map_err(|e| format!("the fitted model cannot be evaluated: {e}"))?;
        let bic = after.deviance() + after.trial_cost() + free.len() as f64 * observations(&after).ln();
        Ok((report, after, bic))
    };
    // The full effect, and each nested form with fewer parameters (the rest held absent),
    // which BIC prefers when the data do not resolve the extra parameters.
    let mut forms = vec![mine.clone()];
    for e in effects {
        for held in e.nested() {
            let form: Vec<Free> = mine.iter().filter(|f| !held.contains(&f.name.as_str())).cloned().collect();
            if !form.is_empty() && form.len() < mine.len() {
                forms.push(form);
            }
        }
    }
    // The full form when the data name it (its parameters are then the unbiased ones);
    // otherwise the form with the lowest BIC, so a law the data support only in its
    // simpler form is still found.
    let reference_bic = reference.deviance() + reference.trial_cost();
    let mut best: Option<(FitReport, Evaluation, f64, Vec<Free>)> = None;
    let mut evaluations = 0;
    for form in forms {
        if best.as_ref().is_some_and(|b| b.3.len() == mine.len() && reference_bic - b.2 > BIC_STRONG) {
            break;
        }
        match attempt(&form) {
            Ok((report, after, bic)) => {
                evaluations += report.evaluations;
                if best.as_ref().is_none_or(|b| bic < b.2) {
                    best = Some((report, after, bic, form));
                }
            }
            Err(e) if best.is_none() => {
                c.skipped = Some(e);
                return c;
            }
            Err(_) => {}
        }
    }
    let Some((report, after, bic, form)) = best else {
        c.skipped = Some("no form of the effect could be fitted".into());
        return c;
    };
    // Parameters a nested form holds stay at their starts (the effect absent).
    let held = mine.iter().filter(|f| !form.iter().any(|g| g.name == f.name)).map(|f| (f.name.clone(), f.start));
    let values: Vec<(String, f64)> =
        on_values.iter().cloned().chain(report.params.iter().map(|p| (p.name.clone(), p.value))).chain(held).collect();
    for e in effects {
        c.params.insert(e.name().to_string(), Json::Object(e.report(&values, ctx.roles, ctx.compiled)));
    }
    c.bic = bic;
    c.delta_bic = reference_bic - c.bic;
    c.explains = after.at_floor();
    c.ratios_after = after.files.iter().map(|f| f.ratio).collect();
    c.trials_misclassified_after = after.trials.map(|t| t.1);
    c.fitted = report.params;
    c.evaluations = evaluations;
    c.converged = report.converged;
    c.seconds = t0.elapsed().as_secs_f64();
    c.evaluation = Some(after);
    c.values = values;
    c
}

/// Diagnoses the recipe at `path`.
pub fn diagnose(path: &Path, registry: &Registry) -> Result<Diagnosis, DiagnoseError> {
    let t0 = Instant::now();
    let shown = path.display().to_string();
    let (base, compiled, mut roles) = load_recipe(path, &shown, registry)?;
    let (baseline, memo) = evaluate_baseline(path, &shown, &base, &compiled, &mut roles, registry)?;
    let ctx = Ctx {
        path,
        base: &base,
        compiled: &compiled,
        roles: &roles,
        registry,
        baseline: &baseline,
        memo: Arc::new(memo),
    };
    let lib = effects::library(registry);
    let search = search_effects(&ctx, &lib);
    let (diagnosed, after) = evaluate_diagnosed(&ctx, &shown, &search)?;
    Ok(assemble_report(&ctx, search, &diagnosed, &after, shown, t0))
}

/// Reads and compiles the recipe at `path` and finds its roles, refusing a recipe a diagnosis
/// cannot edit, fit or judge.
fn load_recipe(path: &Path, shown: &str, registry: &Registry) -> Result<(RecipeText, Compiled, Roles), DiagnoseError> {
    let recipe_err = |message: String| DiagnoseError::Recipe { path: shown.to_string(), message };
    if path.extension().is_some_and(|e| e == "rhai") {
        return Err(recipe_err(
            "a diagnosis edits the recipe's text; give a YAML recipe (a Rhai script builds its recipe in code)".into(),
        ));
    }
    let text = read_recipe_text(path).map_err(|e| recipe_err(format!("cannot read the recipe: {e}")))?;
    let base = RecipeText::new(shown, text).map_err(|e| recipe_err(e.to_string()))?;
    let compiled = compile_text(&base, path, &[], registry).map_err(DiagnoseError::Input)?;
    if compiled.recipe.fit.is_some() {
        return Err(recipe_err(
            "the recipe has a `fit:` block; a diagnosis fits its own parameters: remove the block (or run the fitted recipe)".into(),
        ));
    }
    let roles = Roles::find(&compiled);
    if roles.gaps.is_empty() {
        return Err(recipe_err(
            "nothing compares a model with a measurement: declare the measured FRFs (`measurements:`) and an `frf.gap` step whose `model` is the prediction (see `spindlelab import`)".into(),
        ));
    }
    Ok((base, compiled, roles))
}

/// Evaluates the recipe as written (its lobes at the trials' speeds), refuses it when every
/// measurement is noise, and tells `roles` the measured directions.
fn evaluate_baseline(
    path: &Path,
    shown: &str,
    base: &RecipeText,
    compiled: &Compiled,
    roles: &mut Roles,
    registry: &Registry,
) -> Result<(Evaluation, Memo), DiagnoseError> {
    let recipe_err = |message: String| DiagnoseError::Recipe { path: shown.to_string(), message };
    // The trials' speeds, so every evaluation computes the lobes there only.
    let trial_speeds = trial_speeds(compiled, roles);
    let at_trials = at_trial_speeds(base, roles, &trial_speeds).map_err(recipe_err)?;
    let evaluated = compile_text(&at_trials, path, &[], registry)
        .and_then(|c| evaluate(&c, roles, registry, None))
        .map_err(|e| recipe_err(format!("the model as written does not run: {e}")))?;
    let (mut baseline, memo) = evaluated;
    baseline.trial_speeds_rpm = trial_speeds;
    let noisy: Vec<&FileGap> =
        baseline.files.iter().filter(|f| f.noise_floor.is_nan() || f.noise_floor >= MAX_NOISE_FLOOR).collect();
    if noisy.len() == baseline.files.len() {
        return Err(recipe_err(format!(
            "every measurement is noise (noise floor {} of the signal or more, e.g. `{}` at {:.2}): no discrepancy can be judged",
            MAX_NOISE_FLOOR, noisy[0].file, noisy[0].noise_floor
        )));
    }
    roles.measured(&baseline);
    Ok((baseline, memo))
}

/// A cutting effect is named, and trials listed as unexplained, when at least this many
/// trials are misclassified.
const MIN_FIXED: usize = 3;

/// What the search for effects found: every candidate tried, the effects named with their
/// values, and the mode outside the library that stands in for what they leave.
struct Search<'l> {
    candidates: Vec<Candidate>,
    named: Vec<&'l dyn Effect>,
    named_values: Vec<(String, f64)>,
    unknown_fit: Option<UnknownMode>,
    /// What the search declined to name, and why.
    notes: Vec<String>,
}

/// Searches the library for the effects the model lacks: structural and measurement effects
/// when the FRFs disagree, then cutting effects when the trials still do.
fn search_effects<'l>(ctx: &Ctx, lib: &'l [Box<dyn Effect>]) -> Search<'l> {
    let mut search = Search {
        candidates: Vec::new(),
        named: Vec::new(),
        named_values: Vec::new(),
        unknown_fit: None,
        notes: Vec::new(),
    };
    let mut current = ctx.baseline.clone();
    if !ctx.baseline.at_floor() {
        search_frf_effects(ctx, lib, &mut search, &mut current);
    }
    search_cutting_effects(ctx, lib, &mut search, &current);
    search
}

/// Fits each structural and measurement effect alone, then pairs, then a mode outside the
/// library, and names the effects of the first that explains the FRFs (`current` becomes its
/// evaluation).
fn search_frf_effects<'l>(ctx: &Ctx, lib: &'l [Box<dyn Effect>], search: &mut Search<'l>, current: &mut Evaluation) {
    let singles: Vec<&dyn Effect> = lib.iter().map(|e| e.as_ref()).filter(|e| e.scope() != Scope::Cutting).collect();
    let fitted: Vec<Candidate> =
        singles.par_iter().map(|e| try_candidate(ctx, &[*e], &[], &[], &[], ctx.baseline)).collect();
    let mut ranked: Vec<usize> = (0..fitted.len()).filter(|&i| fitted[i].skipped.is_none()).collect();
    ranked.sort_by(|&a, &b| fitted[a].bic.total_cmp(&fitted[b].bic));
    let best_single = ranked.first().copied().filter(|&i| fitted[i].delta_bic > BIC_STRONG && fitted[i].explains);
    let mut chosen: Option<Candidate> = best_single.map(|i| fitted[i].clone());
    if chosen.is_none() {
        chosen = try_pairs(ctx, &singles, &fitted, &ranked, &mut search.candidates);
    }
    if chosen.is_none() {
        chosen = try_unknown_mode(ctx, &singles, &fitted, &ranked, search);
    }
    if chosen.is_none()
        && let Some(&i) = ranked.first()
        && let Some(note) = form_misfit(ctx.baseline, &fitted[i])
    {
        search.notes.push(note);
        chosen = Some(fitted[i].clone());
    }
    search.candidates.splice(0..0, fitted);
    if let Some(ch) = &chosen {
        for name in &ch.effects {
            if let Some(e) = lib.iter().find(|e| e.name() == *name) {
                search.named.push(e.as_ref());
            }
        }
        search.named_values = ch.values.clone();
        *current = ch.evaluation.clone().expect("evaluated");
    }
}

/// The largest gap ratio after an effect that explains nearly all of the discrepancy but
/// leaves it off the floor: its form, not its presence, is then in doubt.
pub const FORM_MISFIT_MAX_RATIO: f64 = 1.5;
/// The least share of the excess gap (largest ratio over 1) such an effect must remove.
pub const FORM_MISFIT_MIN_SHARE: f64 = 0.9;

/// When no effect, pair or mode outside the library explains the FRFs, the best single effect
/// is still named if its evidence is strong and it brings every file within
/// [`FORM_MISFIT_MAX_RATIO`] of its floor, removing at least [`FORM_MISFIT_MIN_SHARE`] of the
/// excess gap: the note says so with the ratio it leaves, and the files off the floor stay
/// listed as unexplained.
fn form_misfit(baseline: &Evaluation, c: &Candidate) -> Option<String> {
    let before = baseline.files.iter().map(|f| f.ratio).fold(0.0, f64::max);
    let after = c.ratios_after.iter().copied().fold(0.0, f64::max);
    let removed = (before - after) / (before - 1.0);
    (c.skipped.is_none()
        && c.delta_bic > BIC_STRONG
        && after <= FORM_MISFIT_MAX_RATIO
        && removed >= FORM_MISFIT_MIN_SHARE)
        .then(|| {
            format!(
                "`{}` is named with a form misfit: it takes the largest gap ratio from {before:.2} to {after:.2}, {:.0} % of the excess, but not to the noise floor; its form, not its presence, is in doubt",
                c.effects.join(" + "),
                100.0 * removed
            )
        })
}

/// Fits pairs of the three best single effects with strong evidence and returns the best pair
/// that explains the FRFs and beats every single effect, or its simpler member.
fn try_pairs(
    ctx: &Ctx,
    singles: &[&dyn Effect],
    fitted: &[Candidate],
    ranked: &[usize],
    candidates: &mut Vec<Candidate>,
) -> Option<Candidate> {
    // Pairs of the best three that each explain something.
    let top: Vec<usize> = ranked.iter().copied().filter(|&i| fitted[i].delta_bic > BIC_STRONG).take(3).collect();
    let mut pairs = Vec::new();
    for a in 0..top.len() {
        for b in a + 1..top.len() {
            pairs.push((top[a], top[b]));
        }
    }
    let best_single_bic = ranked.first().map_or(f64::INFINITY, |&i| fitted[i].bic);
    let tried: Vec<Candidate> = pairs
        .par_iter()
        .map(|&(a, b)| {
            let starts: Vec<(String, f64)> = fitted[a].values.iter().chain(&fitted[b].values).cloned().collect();
            let mut c = try_candidate(ctx, &[singles[a], singles[b]], &[], &[], &starts, ctx.baseline);
            // A pair must also beat the best single effect; and where its stronger effect alone
            // nearly explains the data (a form misfit), the other must carry a share of the
            // pair's evidence, or it is only fitting the stronger one's residual.
            let (strong, weak_gain) = if fitted[a].bic <= fitted[b].bic {
                (&fitted[a], fitted[a].bic - c.bic)
            } else {
                (&fitted[b], fitted[b].bic - c.bic)
            };
            let sliver = form_misfit(ctx.baseline, strong).is_some() && weak_gain < MIN_PAIR_SHARE * c.delta_bic;
            if c.skipped.is_none() && (best_single_bic - c.bic <= BIC_STRONG || sliver) {
                c.explains = false;
            }
            c
        })
        .collect();
    let best_pair = tried
        .iter()
        .filter(|c| c.skipped.is_none() && c.explains && c.delta_bic > BIC_STRONG)
        .min_by(|a, b| a.bic.total_cmp(&b.bic))
        .cloned();
    candidates.extend(tried);
    Some(pruned_pair(ctx, singles, best_pair?, candidates))
}

/// The pair, unless one of its effects alone, refitted from the pair's values, explains the
/// data as well (a single fit can miss its basin): then the best such effect.
fn pruned_pair(ctx: &Ctx, singles: &[&dyn Effect], pair: Candidate, candidates: &mut Vec<Candidate>) -> Candidate {
    let members: Vec<&dyn Effect> =
        pair.effects.iter().filter_map(|n| singles.iter().copied().find(|e| e.name() == *n)).collect();
    let pruned: Vec<Candidate> =
        members.par_iter().map(|e| try_candidate(ctx, &[*e], &[], &[], &pair.values, ctx.baseline)).collect();
    let simpler = pruned
        .iter()
        .filter(|c| c.skipped.is_none() && c.explains && c.delta_bic > BIC_STRONG && c.bic - pair.bic <= BIC_STRONG)
        .min_by(|a, b| a.bic.total_cmp(&b.bic))
        .cloned();
    candidates.extend(pruned);
    simpler.unwrap_or(pair)
}

/// Fits one mode outside the library where the largest discrepancy remains, alone and beside
/// each strong single effect, and returns the known effect named beside it, if any.
fn try_unknown_mode(
    ctx: &Ctx,
    singles: &[&dyn Effect],
    fitted: &[Candidate],
    ranked: &[usize],
    search: &mut Search<'_>,
) -> Option<Candidate> {
    // Something outside the library: one mode stands in for it where the largest
    // discrepancy remains (after the best effect with strong evidence, else as written),
    // and a known effect is named beside it when the two explain every file and beat
    // that mode alone by ΔBIC > 10.
    let best = ranked.first().filter(|&&i| fitted[i].delta_bic > BIC_STRONG);
    let from = best.and_then(|&i| fitted[i].evaluation.as_ref()).unwrap_or(ctx.baseline);
    let unknown = locate_unknown(from)?;
    let alone = try_candidate(ctx, &[&unknown], &[], &[], &[], ctx.baseline);
    let top: Vec<usize> = ranked.iter().copied().filter(|&i| fitted[i].delta_bic > BIC_STRONG).take(3).collect();
    let beside: Vec<Candidate> = top
        .par_iter()
        .map(|&i| {
            let starts: Vec<(String, f64)> = fitted[i].values.iter().chain(&alone.values).cloned().collect();
            try_candidate(ctx, &[singles[i], &unknown], &[], &[], &starts, ctx.baseline)
        })
        .collect();
    let known = beside
        .iter()
        .filter(|c| c.skipped.is_none() && c.explains)
        .filter(|c| alone.skipped.is_some() || alone.bic - c.bic > BIC_STRONG)
        .min_by(|a, b| a.bic.total_cmp(&b.bic))
        .cloned();
    let located = known.as_ref().or((alone.skipped.is_none() && alone.explains).then_some(&alone));
    if let Some(c) = located {
        let at = |n: &str| c.values.iter().find(|(k, _)| k == n).map_or(f64::NAN, |v| v.1);
        search.unknown_fit = Some(UnknownMode {
            direction: unknown.direction.clone(),
            f_hz: at("unknown_f"),
            zeta: at("unknown_zeta"),
            stiffness_n_per_m: at("unknown_k"),
        });
    }
    search.candidates.push(alone);
    search.candidates.extend(beside);
    known
}

/// Fits each cutting effect on top of the named ones when the trials disagree with the model
/// so far (`current`), and names the first that fixes enough of them — unless the structure
/// itself is still wrong: while a measured FRF stays off its floor, the lobes are wrong for
/// that reason, and a cutting law fitted to the trials would absorb it. It is then fitted and
/// listed among the candidates, and the diagnosis says why it was not named.
fn search_cutting_effects<'l>(ctx: &Ctx, lib: &'l [Box<dyn Effect>], search: &mut Search<'l>, current: &Evaluation) {
    if current.misclassified() < MIN_FIXED {
        return;
    }
    let off_floor = current.files.iter().filter(|f| f.discrepant()).count();
    let open = match (off_floor, &search.unknown_fit) {
        (0, None) => None,
        (0, Some(_)) => Some("a mode outside the library stands in for what the named effects leave".to_string()),
        (n, _) => Some(format!("{n} measured FRF{} off the noise floor", if n == 1 { "" } else { "s" })),
    };
    for e in lib.iter().filter(|e| e.scope() == Scope::Cutting) {
        let c = try_candidate(ctx, &[e.as_ref()], &search.named, &search.named_values, &[], current);
        let fixes = c
            .trials_misclassified_after
            .is_some_and(|m| current.misclassified() - m.min(current.misclassified()) >= MIN_FIXED);
        if c.skipped.is_none()
            && c.delta_bic > BIC_STRONG
            && fixes
            && let Some(open) = &open
        {
            search.notes.push(format!(
                "`{}` would fix the trials but is not named: the library does not explain the measured FRFs ({open}), so the structure, not the cutting law, may be what mispredicts the trials; explain the FRFs first",
                e.name()
            ));
            search.candidates.push(c);
            break;
        }
        if c.skipped.is_none() && c.delta_bic > BIC_STRONG && fixes {
            search.named.push(e.as_ref());
            search.named_values = c.values.clone();
            search.candidates.push(c);
            break;
        }
        search.candidates.push(c);
    }
}

/// The augmented recipe and its evaluation: the named effects written in at their values as
/// `diagnosed.yaml` rounds them, run again (the baseline when nothing was named).
fn evaluate_diagnosed(ctx: &Ctx, shown: &str, search: &Search) -> Result<(RecipeText, Evaluation), DiagnoseError> {
    let recipe_err = |message: String| DiagnoseError::Recipe { path: shown.to_string(), message };
    // The augmented recipe, run again: its values as `diagnosed.yaml` writes them, to the
    // significant digits a fit resolves, so the file reproduces the gap reported after.
    let written: Vec<(String, f64)> = search
        .named_values
        .iter()
        .map(|(n, v)| (n.clone(), spindlelab_domain::round_sig(*v, WRITTEN_DIGITS)))
        .collect();
    let (diagnosed, _) = augmented(ctx, &search.named, &written).map_err(recipe_err)?;
    let after = if search.named.is_empty() {
        ctx.baseline.clone()
    } else {
        at_trial_speeds(&diagnosed, ctx.roles, &ctx.baseline.trial_speeds_rpm)
            .and_then(|t| compile_text(&t, ctx.path, &[], ctx.registry))
            .and_then(|c| evaluate(&c, ctx.roles, ctx.registry, Some(Arc::clone(&ctx.memo))).map(|e| e.0))
            .map_err(|e| recipe_err(format!("the diagnosed recipe does not run: {e}")))?
    };
    Ok((diagnosed, after))
}

/// Assembles the diagnosis: what stays unexplained, the verdict, the named effects, the gap
/// before and after, the pictures and the diagnosed recipe with its header.
fn assemble_report(
    ctx: &Ctx,
    search: Search,
    diagnosed: &RecipeText,
    after: &Evaluation,
    shown: String,
    t0: Instant,
) -> Diagnosis {
    let unexplained = unexplained(after, search.unknown_fit.as_ref());
    let verdict = match (unexplained.is_empty(), search.named.is_empty()) {
        (false, true) => VERDICT_UNEXPLAINED,
        (false, false) => VERDICT_PARTIAL,
        (true, true) => VERDICT_NONE,
        (true, false) => VERDICT_EFFECTS,
    };
    let effects = named_effects(ctx, &search);
    let gap = gap_report(ctx.baseline, after);
    let pictures = picture_values(ctx, diagnosed, after, !search.named.is_empty());
    let header = diagnosed_header(&search.named, &search.named_values, ctx.roles, ctx.compiled, verdict, &effects);
    Diagnosis {
        verdict,
        effects,
        unexplained,
        gap,
        candidates: search.candidates,
        notes: search.notes,
        recipe: shown,
        seconds: t0.elapsed().as_secs_f64(),
        diagnosed_recipe: format!("{header}{}", diagnosed.text),
        pictures,
    }
}

/// What the diagnosed model leaves: every file off the floor (with the unknown mode along its
/// direction), and the trials still wrong when there are enough of them.
fn unexplained(after: &Evaluation, unknown_fit: Option<&UnknownMode>) -> Vec<Unexplained> {
    let mut unexplained: Vec<Unexplained> = after
        .files
        .iter()
        .filter(|f| f.discrepant())
        .map(|f| {
            Unexplained::Frf(FrfDiscrepancy {
                direction: f.direction.clone(),
                speed_rpm: f.speed_rpm,
                near_hz: f.max_discrepancy_hz,
                band_hz: f.band_hz,
                ratio: f.ratio,
                resonance: unknown_fit.cloned().filter(|u| u.direction == f.direction),
            })
        })
        .collect();
    // Trials that stay wrong are listed one by one: where the lobes and the cuts disagree.
    if after.misclassified() >= MIN_FIXED {
        unexplained.extend(after.wrong_trials.iter().cloned().map(Unexplained::Trial));
    }
    unexplained
}

/// The named effects as reported: their parameters, fitted uncertainties and evidence (from
/// the last candidate fitted with each).
fn named_effects(ctx: &Ctx, search: &Search) -> Vec<NamedEffect> {
    search
        .named
        .iter()
        .map(|e| {
            let c = search.candidates.iter().rev().find(|c| c.effects.contains(&e.name()) && c.skipped.is_none());
            let uncertainty: Map<String, Json> = c
                .map(|c| {
                    c.fitted
                        .iter()
                        .map(|p| {
                            let p_json = serde_json::json!({
                                "value": p.value, "sigma": p.sigma, "unit": p.unit, "at_bound": p.at_bound
                            });
                            (p.name.clone(), p_json)
                        })
                        .collect()
                })
                .unwrap_or_default();
            NamedEffect {
                name: e.name(),
                params: Json::Object(e.report(&search.named_values, ctx.roles, ctx.compiled)),
                uncertainty: Json::Object(uncertainty),
                evidence: serde_json::json!({
                    "delta_bic": c.map(|c| c.delta_bic),
                    "scope": e.scope(),
                    "description": e.description(),
                }),
            }
        })
        .collect()
}

/// The gap before and after, per measured file and for the trials.
fn gap_report(baseline: &Evaluation, after: &Evaluation) -> GapReport {
    let files = baseline
        .files
        .iter()
        .zip(&after.files)
        .map(|(b, a)| GapFile {
            file: b.file.clone(),
            direction: b.direction.clone(),
            speed_rpm: b.speed_rpm,
            noise_floor: b.noise_floor,
            rel_l2_before: b.rel_l2,
            rel_l2_after: a.rel_l2,
            ratio_before: b.ratio,
            ratio_after: a.ratio,
        })
        .collect();
    let trials = baseline.trials.map(|(n, m)| GapTrials {
        n,
        misclassified_before: m,
        misclassified_after: after.misclassified(),
    });
    GapReport { files, trials }
}

/// The values behind the pictures: each file's measurement with the model before and (when
/// effects were `added`) after, and the full stability diagrams drawn before and after.
fn picture_values(ctx: &Ctx, diagnosed: &RecipeText, after: &Evaluation, added: bool) -> Pictures {
    let mut pictures = Pictures {
        files: ctx
            .baseline
            .files
            .iter()
            .zip(&after.files)
            .filter_map(|(b, a)| {
                let (model, measured) = b.frfs.clone()?;
                let model_after = if added { a.frfs.as_ref().map(|f| f.0.clone()) } else { None };
                Some(FilePicture { file: b.file.clone(), measured, before: model, after: model_after })
            })
            .collect(),
        ..Pictures::default()
    };
    let drawn = |r: &RecipeText| {
        let r = at_picture_speeds(r, ctx.roles, ctx.compiled, &ctx.baseline.trial_speeds_rpm);
        diagram(&r, ctx.path, ctx.roles, ctx.registry, Arc::clone(&ctx.memo))
    };
    pictures.lobes_before = drawn(ctx.base);
    if added {
        pictures.lobes_after = drawn(diagnosed);
    }
    pictures
}

fn diagnosed_header(
    named: &[&dyn Effect],
    values: &[(String, f64)],
    roles: &Roles,
    c: &Compiled,
    verdict: &str,
    effects: &[NamedEffect],
) -> String {
    let mut s = format!("Diagnosed by spindlelab: {verdict}.\n");
    for e in named {
        s.push_str(&format!("  {}: {}\n", e.name(), e.description()));
        let p = Json::Object(e.report(values, roles, c));
        s.push_str(&format!("    {}\n", readable(&p)));
        if let Some(u) = effects.iter().find(|n| n.name == e.name()).and_then(|n| n.uncertainty.as_object()) {
            for (name, p) in u {
                let unit = p["unit"].as_str().filter(|u| !u.is_empty()).map_or(String::new(), |u| format!(" {u}"));
                let v = value_pm(p["value"].as_f64().unwrap_or(f64::NAN), p["sigma"].as_f64());
                s.push_str(&format!("    fitted {name} = {v}{unit}\n"));
            }
        }
    }
    if named.is_empty() {
        s.push_str("  Nothing was added: the recipe below is the input.\n");
    }
    crate::engine::syntax::emit::comment_lines(s.trim_end_matches('\n'))
}

/// An effect's reported parameters as a person reads them: `name = value unit` with the unit
/// its key names (`equivalent_diameter_m` → `equivalent_diameter = 10.98 mm`, a ratio or a
/// relative change in %), four significant digits, lists of objects one per item.
fn readable(v: &Json) -> String {
    match v {
        Json::Object(m) => m.iter().map(|(k, v)| readable_field(k, v)).collect::<Vec<_>>().join(", "),
        other => readable_value(other),
    }
}

fn readable_value(v: &Json) -> String {
    match v {
        Json::Number(n) => spindlelab_domain::sig(n.as_f64().unwrap_or(f64::NAN), 4),
        Json::String(s) => s.clone(),
        Json::Array(a) => format!("[{}]", a.iter().map(readable_item).collect::<Vec<_>>().join("; ")),
        Json::Object(_) => format!("({})", readable(v)),
        other => other.to_string(),
    }
}

fn readable_item(v: &Json) -> String {
    match v {
        Json::Object(_) => readable(v),
        other => readable_value(other),
    }
}

/// One `key = value unit`, the unit taken from the key's suffix.
fn readable_field(key: &str, v: &Json) -> String {
    const UNITS: [(&str, f64, &str); 11] = [
        ("_per_10000_rpm", 1.0, " per 10000 rpm"),
        ("_hz_per_1000_rpm", 1.0, " Hz per 1000 rpm"),
        ("_deg_per_khz", 1.0, " deg/kHz"),
        ("_nms_per_rad", 1.0, " N·m·s/rad"),
        ("_nm_per_rad", 1.0, " N·m/rad"),
        ("_ns_per_m", 1.0, " N·s/m"),
        ("_n_per_m", 1.0, " N/m"),
        ("_hz", 1.0, " Hz"),
        ("_rpm", 1.0, " rpm"),
        ("_m", 1e3, " mm"),
        ("_s", 1.0, " s"),
    ];
    let Some(x) = v.as_f64() else { return format!("{key} = {}", readable_value(v)) };
    let percent = key.ends_with("_ratio") || key.starts_with("relative_change") || key.contains("relative_change_per");
    for (suffix, scale, unit) in UNITS {
        if let Some(name) = key.strip_suffix(suffix) {
            // `ks_relative_change_per_10000_rpm`: a relative change, in % per 10000 rpm.
            let (x, unit) = if percent { (x * 100.0, format!(" %{unit}")) } else { (x * scale, unit.to_string()) };
            return format!("{name} = {}{unit}", spindlelab_domain::sig(x, 4));
        }
    }
    if percent {
        return format!("{key} = {} %", spindlelab_domain::sig(x * 100.0, 4));
    }
    format!("{key} = {}", spindlelab_domain::sig(x, 4))
}

/// `value ± sigma` with sigma to two significant digits and the value rounded to the same
/// decimal place (`0.012346 ± 0.00056` → `0.01235 ± 0.00056`, `4.0123e8 ± 1.2e7` →
/// `4.01e8 ± 1.2e7`); the value alone to five significant digits without a usable σ.
pub fn value_pm(value: f64, sigma: Option<f64>) -> String {
    let Some(sigma) = sigma.filter(|s| s.is_finite() && *s > 0.0 && value.is_finite()) else {
        return format!("{value:.5}");
    };
    // The decimal place of σ's second significant digit.
    let place = sigma.log10().floor() as i32 - 1;
    if (-9..=0).contains(&place) && value.abs() < 1e6 {
        let decimals = (-place) as usize;
        return format!("{value:.decimals$} ± {sigma:.decimals$}");
    }
    let exponent = if value == 0.0 { place + 1 } else { value.abs().log10().floor() as i32 };
    let digits = (exponent - place).max(0) as usize;
    format!("{value:.digits$e} ± {sigma:.1e}")
}

/// The pictures `write` puts beside `diagnosis.md`, with what each shows.
fn pictures_listed(d: &Diagnosis) -> Vec<(String, String)> {
    let mut v: Vec<(String, String)> = d
        .pictures
        .files
        .iter()
        .map(|p| (picture_name(&p.file), format!("`{}`: measured, model before and after", p.file)))
        .collect();
    if d.pictures.lobes_before.is_some() {
        v.push((
            "lobes.svg".into(),
            "stability lobes before and after, with the trials (misclassified ones ringed)".into(),
        ));
    }
    v
}

/// The readable summary, `diagnosis.md`.
pub fn markdown(d: &Diagnosis) -> String {
    let mut s = format!("# Diagnosis of `{}`\n\n**Verdict: {}.**\n\n", d.recipe, d.verdict);
    for e in &d.effects {
        s.push_str(&format!(
            "- **{}** — {}\n  - parameters: {}\n",
            e.name,
            e.evidence["description"].as_str().unwrap_or(""),
            readable(&e.params)
        ));
        if let Some(u) = e.uncertainty.as_object()
            && !u.is_empty()
        {
            let fitted: Vec<String> = u
                .iter()
                .map(|(name, p)| {
                    let v = p["value"].as_f64().unwrap_or(f64::NAN);
                    let unit = p["unit"].as_str().unwrap_or("");
                    let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
                    let bound = if p["at_bound"].as_bool() == Some(true) {
                        " (at its bound: the data ask for more than this effect can give)"
                    } else {
                        ""
                    };
                    format!("{name} = {}{unit}{bound}", value_pm(v, p["sigma"].as_f64()))
                })
                .collect();
            s.push_str(&format!("  - fitted: {}\n", fitted.join(", ")));
        }
        if let Some(b) = e.evidence["delta_bic"].as_f64() {
            s.push_str(&format!("  - evidence: BIC {b:.1} better than the model without it\n"));
        }
    }
    for u in &d.unexplained {
        match u {
            Unexplained::Frf(u) => {
                s.push_str(&format!(
                    "- unexplained in {} at {} rpm near {:.0} Hz (band {:.0}–{:.0} Hz), gap ratio {:.2}\n",
                    u.direction, u.speed_rpm, u.near_hz, u.band_hz[0], u.band_hz[1], u.ratio
                ));
                if let Some(r) = &u.resonance {
                    s.push_str(&format!(
                        "  - one mode outside the library explains it: {:.0} Hz, ζ {:.3}, k {:.3e} N/m along {}\n",
                        r.f_hz, r.zeta, r.stiffness_n_per_m, r.direction
                    ));
                }
            }
            Unexplained::Trial(t) => s.push_str(&format!(
                "- unexplained trial at {} rpm, {:.3} mm: {} where the lobes give {:.3} mm ({:+.0} % from the limit)\n",
                t.speed_rpm,
                t.depth_mm,
                t.outcome,
                t.limit_mm,
                (t.margin.exp() - 1.0) * 100.0
            )),
        }
    }
    for n in &d.notes {
        s.push_str(&format!("- {n}\n"));
    }
    let drawn = pictures_listed(d);
    if !drawn.is_empty() {
        s.push_str("\n## Pictures\n\n");
        for (name, what) in drawn {
            s.push_str(&format!("- [{what}]({name})\n"));
        }
    }
    s.push_str("\n## Gap per measurement (ratio = rel. L2 / noise floor; about 1 at the floor)\n\n| file | dir | speed (rpm) | noise floor | ratio before | ratio after |\n|---|---|---|---|---|---|\n");
    for f in &d.gap.files {
        s.push_str(&format!(
            "| {} | {} | {} | {:.4} | {:.3} | {:.3} |\n",
            f.file, f.direction, f.speed_rpm, f.noise_floor, f.ratio_before, f.ratio_after
        ));
    }
    if let Some(t) = &d.gap.trials {
        s.push_str(&format!(
            "\nTrials misclassified: {} of {} before, {} after.\n",
            t.misclassified_before, t.n, t.misclassified_after
        ));
    }
    s.push_str("\n## Candidates\n\n| effects | ΔBIC | every file at the floor | ratios after | trials wrong after | evaluations | note |\n|---|---|---|---|---|---|---|\n");
    for c in &d.candidates {
        let ratios: Vec<String> = c.ratios_after.iter().map(|r| format!("{r:.2}")).collect();
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} |\n",
            c.effects.join(" + "),
            if c.delta_bic.is_finite() { format!("{:.1}", c.delta_bic) } else { "—".into() },
            if c.skipped.is_some() {
                "—"
            } else if c.explains {
                "yes"
            } else {
                "no"
            },
            ratios.join(", "),
            c.trials_misclassified_after.map_or("—".into(), |m| m.to_string()),
            c.evaluations,
            c.skipped.as_deref().unwrap_or("")
        ));
    }
    s
}

/// The picture of a measured file: `fit_<file stem>.svg`.
fn picture_name(file: &str) -> String {
    let stem = Path::new(file).file_stem().and_then(|s| s.to_str()).unwrap_or(file);
    let safe: String =
        stem.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect();
    format!("fit_{safe}.svg")
}

/// The pictures beside `diagnosis.md`: per measured file the measurement with the model
/// before and after (magnitude and phase), and the lobes before and after with the trials.
/// A picture that cannot be drawn is left out; the numbers are in `diagnosis.json`.
pub fn pictures(d: &Diagnosis) -> Vec<(String, Vec<u8>)> {
    use crate::engine::plot::{Layer, PlotFormat};
    use crate::render::render;
    let mut out = Vec::new();
    for FilePicture { file, measured, before, after } in &d.pictures.files {
        fn layer<'a>(name: &str, v: &'a Arc<Value>) -> Layer<'a> {
            Layer::new(name, v.as_ref())
        }
        let main = [layer("measured", measured)];
        let mut with = vec![layer("model before", before)];
        if let Some(a) = after {
            with.push(layer("model after", a));
        }
        if let Ok(bytes) = render(PlotFormat::Svg, &format!("{file}: measured and model"), None, &main, &with) {
            out.push((picture_name(file), bytes));
        }
    }
    if let Some((lobes, verdicts)) = &d.pictures.lobes_before {
        let mut main = vec![Layer::new("model before", lobes.as_ref())];
        let mut with = vec![];
        if let Some((after, _)) = &d.pictures.lobes_after {
            main.push(Layer::new("model after", after.as_ref()));
        }
        let trials = d.pictures.lobes_after.as_ref().map_or(verdicts, |(_, v)| v);
        with.push(Layer::new("trials", trials.as_ref()));
        if let Ok(bytes) =
            render(PlotFormat::Svg, "stability lobes before and after, with the trials", None, &main, &with)
        {
            out.push(("lobes.svg".to_string(), bytes));
        }
    }
    out
}

/// The HTML page of a diagnosis folder: `diagnosis.md` with the pictures it links drawn in
/// place of the links (each read through the data-file cap), one self-contained file.
pub fn report_html(dir: &Path) -> Result<String, DiagnoseError> {
    Ok(crate::render::report::standalone(&format!("diagnosis of {}", dir.display()), &report_body(dir, "")?))
}

/// The body of a diagnosis folder's page: `diagnosis.md` as HTML with its pictures inline, each
/// figure's anchor led by `prefix` (so several diagnoses share one page).
pub fn report_body(dir: &Path, prefix: &str) -> Result<String, DiagnoseError> {
    use crate::engine::formats::{MAX_DATA_BYTES, read_capped};
    use pulldown_cmark::{Event, Options, Parser, Tag, TagEnd, html};
    let read = |name: &str| {
        read_capped(&dir.join(name), MAX_DATA_BYTES)
            .map_err(|e| DiagnoseError::Input(format!("{}: {e}", dir.join(name).display())))
    };
    let md = String::from_utf8(read("diagnosis.md")?)
        .map_err(|_| DiagnoseError::Input(format!("{}: not UTF-8 text", dir.join("diagnosis.md").display())))?;
    let mut figures = Vec::new();
    let mut events = Vec::new();
    for ev in Parser::new_ext(&md, Options::ENABLE_TABLES) {
        match ev {
            // A link to a picture of the folder goes to its figure below.
            Event::Start(Tag::Link { link_type, dest_url, title, id })
                if dest_url.ends_with(".svg") && !dest_url.contains(['/', '\\']) && !dest_url.starts_with('.') =>
            {
                let bytes = read(&dest_url)?;
                figures.push(crate::render::report::svg_figure(&format!("{prefix}fig-{dest_url}"), &dest_url, &bytes));
                let dest_url = format!("#{prefix}fig-{dest_url}").into();
                events.push(Event::Start(Tag::Link { link_type, dest_url, title, id }));
            }
            Event::End(TagEnd::Link) => events.push(ev),
            other => events.push(other),
        }
    }
    let mut body = String::new();
    html::push_html(&mut body, events.into_iter());
    for f in figures {
        body.push_str(&f);
        body.push('\n');
    }
    Ok(body)
}

/// Significant digits of a fitted value in `diagnosed.yaml`: far below any fitted σ, so the
/// written recipe reproduces the gap after, and readable where the fit wrote 16.
const WRITTEN_DIGITS: i32 = 6;

/// Writes `diagnosis.json`, `diagnosis.md` and `diagnosed.yaml` into `out`, each whole or
/// not at all.
pub fn write(d: &Diagnosis, out: &Path) -> Result<(), DiagnoseError> {
    // The three files replace the folder's previous diagnosis as one set.
    let dir = OutputDir::open(out).map_err(DiagnoseError::Output)?;
    let mut staged = dir.stage().map_err(DiagnoseError::Output)?;
    let json = serde_json::to_string_pretty(d).expect("diagnosis serialises");
    for (name, text) in
        [("diagnosis.json", json), ("diagnosis.md", markdown(d)), ("diagnosed.yaml", d.diagnosed_recipe.clone())]
    {
        staged.write(name, text.as_bytes()).map_err(DiagnoseError::Output)?;
    }
    for (name, bytes) in pictures(d) {
        staged.write(&name, &bytes).map_err(DiagnoseError::Output)?;
    }
    staged.commit().map_err(DiagnoseError::Output)
}

/// A recipe's text, read as far as a recipe may be long.
fn read_recipe_text(path: &Path) -> std::io::Result<String> {
    crate::engine::formats::read_text_capped(path, crate::engine::syntax::MAX_RECIPE_BYTES)
}

/// Evaluates the recipe at `path` as written: every gap step against its measurement and the
/// trials against the lobes at the trials' speeds, with nothing fitted. This is the number a
/// diagnosis starts from, and what a recipe with effects added by hand comes to.
pub fn evaluate_file(path: &Path, registry: &Registry) -> Result<Evaluation, DiagnoseError> {
    let shown = path.display().to_string();
    let err = |message: String| DiagnoseError::Recipe { path: shown.clone(), message };
    let text = read_recipe_text(path).map_err(|e| err(format!("cannot read the recipe: {e}")))?;
    let base = RecipeText::new(&shown, text).map_err(|e| err(e.to_string()))?;
    let compiled = compile_text(&base, path, &[], registry).map_err(DiagnoseError::Input)?;
    let roles = Roles::find(&compiled);
    let speeds = trial_speeds(&compiled, &roles);
    let at_trials = at_trial_speeds(&base, &roles, &speeds).map_err(err)?;
    let c = compile_text(&at_trials, path, &[], registry).map_err(DiagnoseError::Input)?;
    let (mut evaluation, _) = evaluate(&c, &roles, registry, None).map_err(err)?;
    evaluation.trial_speeds_rpm = speeds;
    Ok(evaluation)
}

/// The recipe at `path` with `effects` added at the given values (recipe parameter names and
/// the units the library writes them in): the forward model of the library, for generating
/// data with a known answer. Effects are applied in library order.
pub fn with_effects(
    path: &Path,
    registry: &Registry,
    effects: &[(&str, Vec<(&str, f64)>)],
) -> Result<String, DiagnoseError> {
    let shown = path.display().to_string();
    let err = |message: String| DiagnoseError::Recipe { path: shown.clone(), message };
    let text = read_recipe_text(path).map_err(|e| err(e.to_string()))?;
    let mut r = RecipeText::new(&shown, text).map_err(|e| err(e.to_string()))?;
    let compiled = compile_text(&r, path, &[], registry).map_err(DiagnoseError::Input)?;
    let mut roles = Roles::find(&compiled);
    let (baseline, _) = evaluate(&compiled, &roles, registry, None).map_err(err)?;
    roles.measured(&baseline);
    let lib = effects::library(registry);
    if let Some((n, _)) = effects.iter().find(|(n, _)| !lib.iter().any(|e| e.name() == *n)) {
        return Err(err(format!("no effect `{n}` in the library")));
    }
    for e in lib.iter().filter(|e| effects.iter().any(|(n, _)| *n == e.name())) {
        let values = &effects.iter().find(|(n, _)| *n == e.name()).expect("listed").1;
        e.place(values, &mut roles);
        let free = e.apply(&roles, &compiled, &mut r).map_err(err)?;
        for (name, v) in values {
            let f = free
                .iter()
                .find(|f| f.name == *name)
                .ok_or_else(|| err(format!("{} has no parameter `{name}`", e.name())))?;
            r.declare_param(name, &f.value(*v)).map_err(|e| err(e.to_string()))?;
        }
    }
    Ok(r.text)
}

#[cfg(test)]
mod tests {
    use super::value_pm;

    /// Rounded to σ: σ to two significant digits, the value to the same place.
    #[test]
    fn fitted_values_are_written_rounded_to_their_sigma() {
        assert_eq!(value_pm(0.012346, Some(0.00056)), "0.01235 ± 0.00056");
        assert_eq!(value_pm(-13.8412, Some(0.231)), "-13.84 ± 0.23");
        assert_eq!(value_pm(4.0123e8, Some(1.2e7)), "4.01e8 ± 1.2e7");
        assert_eq!(value_pm(2.5, Some(3.0)), "2.5 ± 3.0");
        assert_eq!(value_pm(1234.4, Some(56.0)), "1234 ± 56");
        assert_eq!(value_pm(123456.0, Some(1234.0)), "1.235e5 ± 1.2e3");
        assert_eq!(value_pm(7.0, None), "7.00000");
        assert_eq!(value_pm(7.0, Some(f64::NAN)), "7.00000");
    }
}
