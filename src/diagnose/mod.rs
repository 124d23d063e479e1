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
//!    with 2 n_eff degrees of freedom per file at the floor), plus `2 ln((1−ε)/ε)` per
//!    misclassified trial (trials as Bernoulli outcomes with error rate ε), plus
//!    `k ln n` for k parameters. An effect is named only when it beats the model without it
//!    by [`BIC_STRONG`] and brings every file to the floor; pairs are tried when no single
//!    effect does. What nothing explains is reported as an unexplained discrepancy with
//!    its place, never forced onto a name.
//! 4. **Add** and **show.** The named effects are written into the recipe at their fitted
//!    values (`diagnosed.yaml`), which runs again for the gap after.

pub mod edit;
pub mod effects;
pub mod roles;

use crate::engine::diag::Diagnostics;
use crate::engine::exec::{self, Memo, Outcome, OutputDir, RunOptions};
use crate::engine::node::Registry;
use crate::engine::value::{Table, Value};
use crate::engine::{Compiled, compile_raw};
use crate::fit::{FitReport, FittedParam};
use edit::RecipeText;
use effects::{Effect, Free, Scope};
use rayon::prelude::*;
use roles::Roles;
use serde::Serialize;
use serde_json::{Map, Value as Json};
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// A file disagrees with the model when its ratio² lies this many standard deviations
/// above the floor.
pub const Z_DISCREPANT: f64 = 5.0;
/// "Very strong" evidence on the Kass–Raftery scale: the BIC difference an effect must
/// win by to be named.
pub const BIC_STRONG: f64 = 10.0;
/// Misclassification rate of a right model on trials (a trial near the boundary, a
/// mislabelled cut); sets what one misclassified trial costs.
pub const TRIAL_ERROR_RATE: f64 = 0.02;
/// While a cutting effect is fitted to the trials, trials closer than this (in ln depth)
/// to the boundary count against it, which centres the boundary between the stable and the
/// chattering cuts instead of leaving it at the first point that classifies them all.
pub const TRIAL_MARGIN: f64 = 0.15;
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

/// A model evaluated against the measurements.
#[derive(Debug, Clone, Serialize)]
pub struct Evaluation {
    pub files: Vec<FileGap>,
    /// Trials scored and misclassified, when the recipe scores trials.
    pub trials: Option<(usize, usize)>,
    /// The trials' speeds (rpm), ascending and distinct.
    #[serde(skip)]
    pub trial_speeds_rpm: Vec<f64>,
}

impl Evaluation {
    /// `Σ 2 n_eff ratio²`: −2 ln L of the FRFs up to a constant.
    pub fn deviance(&self) -> f64 {
        self.files.iter().map(|f| 2.0 * f.n_eff * f.ratio * f.ratio).sum()
    }
    fn trial_cost(&self) -> f64 {
        let per = 2.0 * ((1.0 - TRIAL_ERROR_RATE) / TRIAL_ERROR_RATE).ln();
        self.trials.map_or(0.0, |(_, m)| per * m as f64)
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

/// A discrepancy left without a name.
#[derive(Debug, Clone, Serialize)]
pub struct Unexplained {
    pub direction: String,
    pub speed_rpm: f64,
    pub near_hz: f64,
    pub band_hz: [f64; 2],
    pub ratio: f64,
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
    pub recipe: String,
    pub seconds: f64,
    #[serde(skip)]
    pub diagnosed_recipe: String,
}

pub const VERDICT_EFFECTS: &str = "effects";
pub const VERDICT_NONE: &str = "no significant discrepancy";
pub const VERDICT_UNEXPLAINED: &str = "unexplained discrepancy";

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

/// Runs the gaps and the trials of a compiled recipe in memory.
fn evaluate(
    c: &Compiled,
    roles: &Roles,
    registry: &Registry,
    memo: Option<Arc<Memo>>,
) -> Result<(Evaluation, Memo), String> {
    let mut targets: Vec<String> = roles.gaps.iter().map(|g| g.step.clone()).collect();
    targets.extend(roles.trials.clone());
    let opts = RunOptions { use_cache: false, memo, targets: Some(targets), ..RunOptions::new(std::env::temp_dir()) };
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
            let band = match out.get("residual").map(|v| v.as_ref()) {
                Some(Value::Frf(r)) => band_around(&r.freq_hz, &r.values),
                _ => [f64::NAN; 2],
            };
            let label = &c.graph.instances[i].label;
            let file = label
                .split(", ")
                .find_map(|a| a.strip_prefix("file="))
                .map_or_else(|| c.graph.instances[i].id.clone(), str::to_string);
            let direction = match table_value(t, "direction") as i64 {
                0 => "x",
                1 => "y",
                2 => "z",
                _ => "?",
            };
            files.push(FileGap {
                file,
                direction: direction.to_string(),
                speed_rpm: table_value(t, "speed"),
                noise_floor: table_value(t, "noise_floor"),
                rel_l2: table_value(t, "rel_l2"),
                ratio: table_value(t, "ratio"),
                n_eff: table_value(t, "n_eff"),
                max_discrepancy_hz: table_value(t, "max_discrepancy_hz"),
                band_hz: band,
            });
        }
    }
    let mut trials = None;
    let mut trial_speeds = Vec::new();
    if let Some(step) = &roles.trials {
        let i = c.graph.by_step[step][0];
        let out = outputs(i)?;
        if let Some(Value::Table(t)) = out.get("verdicts").map(|v| v.as_ref()) {
            let right = t.columns.iter().find(|c| c.name == "right").map(|c| c.values.clone()).unwrap_or_default();
            let scored = right.iter().filter(|r| **r >= 0.0).count();
            let wrong = right.iter().filter(|r| **r == 0.0).count();
            trials = Some((scored, wrong));
            trial_speeds = t.columns.iter().find(|c| c.name == "speed").map(|c| c.values.clone()).unwrap_or_default();
            trial_speeds.sort_by(f64::total_cmp);
            trial_speeds.dedup();
        }
    }
    Ok((Evaluation { files, trials, trial_speeds_rpm: trial_speeds }, result.memo(&c.graph)))
}

/// The text to evaluate: the stability diagram at the trials' speeds only (each speed's
/// limit is computed on its own, so the trials' verdicts are exactly those of the full
/// diagram, at a fraction of the cost).
fn at_trial_speeds(r: &RecipeText, roles: &Roles, trial_speeds: &[f64]) -> Result<RecipeText, String> {
    let mut r = r.clone();
    if let (Some(lobes), false) = (&roles.lobes, trial_speeds.is_empty()) {
        let speeds: Vec<String> = trial_speeds.iter().map(|s| format!("{s} rpm")).collect();
        r.set_key(&edit::path(&["steps", lobes, "params"]), "speeds", &format!("[{}]", speeds.join(", ")))
            .map_err(|e| e.to_string())?;
    }
    Ok(r)
}

/// The distinct speeds (rpm) of the scored trials, read from the trials file; empty when
/// the recipe scores none or the file cannot be read (the run then says why).
fn trial_speeds(c: &Compiled, roles: &Roles) -> Vec<f64> {
    let Some(file) = roles.trials.as_ref().and_then(|t| c.recipe.step(t)).and_then(|s| s.params.file("file")) else {
        return vec![];
    };
    let Ok(text) = std::fs::read_to_string(file) else { return vec![] };
    let Ok(trials) = crate::stdlib::nodes::parse_trials(&text, &file.display().to_string()) else { return vec![] };
    let mut speeds: Vec<f64> = trials.iter().map(|t| t.speed_rpm).collect();
    speeds.sort_by(f64::total_cmp);
    speeds.dedup();
    speeds
}

/// The fit block for `free`, minimising `objective`.
fn fit_block(free: &[Free], objective: &[String], method: &str, starts: usize) -> String {
    let mut s = String::from("fit:\n  free:\n");
    for f in free {
        let scale = if f.log { ", scale: log" } else { "" };
        s.push_str(&format!("    {}: {{ min: {}, max: {}{scale} }}\n", f.name, f.text(f.min), f.text(f.max)));
    }
    let obj: Vec<String> = objective.iter().map(|o| format!("\"{o}\"")).collect();
    s.push_str(&format!("  objective: [{}]\n  method: {method}\n  starts: {starts}\n", obj.join(", ")));
    s.push_str(&format!("  max_evaluations: {}\n", (100 * free.len()).max(200)));
    s
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
            r.declare_param(&f.name, &f.text(f.start)).map_err(|e| e.to_string())?;
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
            let _ = text.declare_param(n, &f.text(*v));
        }
    }
    let cutting = effects.iter().all(|e| e.scope() == Scope::Cutting);
    let (objective, method) = match (cutting, &ctx.roles.trials) {
        (true, Some(t)) => (vec![format!("@{t}.misfit")], "nelder-mead"),
        _ => (ctx.roles.gaps.iter().map(|g| format!("@{}.residual", g.step)).collect(), "least-squares"),
    };
    let starts = if starts_at.is_empty() { effects.iter().map(|e| e.starts(&mine)).max().unwrap_or(0) } else { 0 };
    let text = match at_trial_speeds(&text, ctx.roles, &ctx.baseline.trial_speeds_rpm) {
        Ok(t) => t,
        Err(e) => {
            c.skipped = Some(e);
            return c;
        }
    };
    let mut fitting = text.clone();
    if cutting && let Some(trials) = &ctx.roles.trials {
        // A margin that centres the boundary between the stable and the chattering cuts.
        let margin = format!("{} %", TRIAL_MARGIN * 100.0);
        if let Err(e) = fitting.set_key(&edit::path(&["steps", trials, "params"]), "margin", &margin) {
            c.skipped = Some(e.to_string());
            return c;
        }
    }
    if let Err(e) = fitting.append(&fit_block(&mine, &objective, method, starts)) {
        c.skipped = Some(e.to_string());
        return c;
    }
    let compiled = match compile_text(&fitting, ctx.path, &[], ctx.registry) {
        Ok(x) => x,
        Err(e) => {
            c.skipped = Some(format!("the augmented recipe does not compile: {e}"));
            return c;
        }
    };
    let report: FitReport = match crate::fit::fit(&compiled, &[], ctx.registry, Some(1)) {
        Ok(r) => r,
        Err(e) => {
            c.skipped = Some(format!("the fit failed: {e}"));
            return c;
        }
    };
    let overrides = report.overrides();
    let after = compile_text(&text, ctx.path, &overrides, ctx.registry)
        .and_then(|x| evaluate(&x, ctx.roles, ctx.registry, Some(Arc::clone(&ctx.memo))).map(|e| e.0));
    let after = match after {
        Ok(a) => a,
        Err(e) => {
            c.skipped = Some(format!("the fitted model cannot be evaluated: {e}"));
            return c;
        }
    };
    let values: Vec<(String, f64)> =
        on_values.iter().cloned().chain(report.params.iter().map(|p| (p.name.clone(), p.value))).collect();
    for e in effects {
        c.params.insert(e.name().to_string(), Json::Object(e.report(&values, ctx.roles, ctx.compiled)));
    }
    // A cutting effect is informed by the trials alone; the rest by the FRFs and trials.
    let k = mine.len() as f64;
    let n = if cutting { after.trials.map_or(2.0, |t| t.0.max(2) as f64) } else { after.observations() };
    c.bic = after.deviance() + after.trial_cost() + k * n.ln();
    let reference_bic = reference.deviance() + reference.trial_cost();
    c.delta_bic = reference_bic - c.bic;
    c.explains = after.at_floor();
    c.ratios_after = after.files.iter().map(|f| f.ratio).collect();
    c.trials_misclassified_after = after.trials.map(|t| t.1);
    c.fitted = report.params;
    c.evaluations = report.evaluations;
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
    let recipe_err = |message: String| DiagnoseError::Recipe { path: shown.clone(), message };
    if path.extension().is_some_and(|e| e == "rhai") {
        return Err(recipe_err(
            "a diagnosis edits the recipe's text; give a YAML recipe (a Rhai script builds its recipe in code)".into(),
        ));
    }
    let text = std::fs::read_to_string(path).map_err(|e| recipe_err(format!("cannot read the recipe: {e}")))?;
    let base = RecipeText::new(&shown, text).map_err(|e| recipe_err(e.to_string()))?;
    let compiled = compile_text(&base, path, &[], registry).map_err(DiagnoseError::Input)?;
    if compiled.recipe.fit.is_some() {
        return Err(recipe_err(
            "the recipe has a `fit:` block; a diagnosis fits its own parameters: remove the block (or run the fitted recipe)".into(),
        ));
    }
    let mut roles = Roles::find(&compiled);
    if roles.gaps.is_empty() {
        return Err(recipe_err(
            "nothing compares a model with a measurement: declare the measured FRFs (`measurements:`) and an `frf.gap` step whose `model` is the prediction (see `spindlelab import`)".into(),
        ));
    }
    // The trials' speeds, so every evaluation computes the lobes there only.
    let trial_speeds = trial_speeds(&compiled, &roles);
    let at_trials = at_trial_speeds(&base, &roles, &trial_speeds).map_err(recipe_err)?;
    let evaluated = compile_text(&at_trials, path, &[], registry)
        .and_then(|c| evaluate(&c, &roles, registry, None))
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
    let mut candidates: Vec<Candidate> = Vec::new();
    let mut named: Vec<&dyn Effect> = Vec::new();
    let mut named_values: Vec<(String, f64)> = Vec::new();
    let mut current = baseline.clone();

    // Structural and measurement effects, when the FRFs disagree.
    if !baseline.at_floor() {
        let singles: Vec<&dyn Effect> =
            lib.iter().map(|e| e.as_ref()).filter(|e| e.scope() != Scope::Cutting).collect();
        let fitted: Vec<Candidate> =
            singles.par_iter().map(|e| try_candidate(&ctx, &[*e], &[], &[], &[], &baseline)).collect();
        let mut ranked: Vec<usize> = (0..fitted.len()).filter(|&i| fitted[i].skipped.is_none()).collect();
        ranked.sort_by(|&a, &b| fitted[a].bic.total_cmp(&fitted[b].bic));
        let best_single = ranked.first().copied().filter(|&i| fitted[i].delta_bic > BIC_STRONG && fitted[i].explains);
        let mut chosen: Option<Candidate> = best_single.map(|i| fitted[i].clone());
        if chosen.is_none() {
            // Pairs of the best three that each explain something.
            let top: Vec<usize> =
                ranked.iter().copied().filter(|&i| fitted[i].delta_bic > BIC_STRONG).take(3).collect();
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
                    let starts: Vec<(String, f64)> =
                        fitted[a].values.iter().chain(&fitted[b].values).cloned().collect();
                    let mut c = try_candidate(&ctx, &[singles[a], singles[b]], &[], &[], &starts, &baseline);
                    // A pair must also beat the best single effect.
                    if c.skipped.is_none() && best_single_bic - c.bic <= BIC_STRONG {
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
            // A pair is kept only if neither of its effects alone, refitted from the pair's
            // values, explains the data as well (a single fit can miss its basin).
            if let Some(pair) = &best_pair {
                let members: Vec<&dyn Effect> =
                    pair.effects.iter().filter_map(|n| singles.iter().copied().find(|e| e.name() == *n)).collect();
                let pruned: Vec<Candidate> =
                    members.par_iter().map(|e| try_candidate(&ctx, &[*e], &[], &[], &pair.values, &baseline)).collect();
                let simpler = pruned
                    .iter()
                    .filter(|c| {
                        c.skipped.is_none() && c.explains && c.delta_bic > BIC_STRONG && c.bic - pair.bic <= BIC_STRONG
                    })
                    .min_by(|a, b| a.bic.total_cmp(&b.bic))
                    .cloned();
                candidates.extend(pruned);
                chosen = simpler.or(best_pair);
            } else {
                chosen = None;
            }
        }
        candidates.splice(0..0, fitted);
        if let Some(ch) = &chosen {
            for name in &ch.effects {
                if let Some(e) = lib.iter().find(|e| e.name() == *name) {
                    named.push(e.as_ref());
                }
            }
            named_values = ch.values.clone();
            current = ch.evaluation.clone().expect("evaluated");
        }
    }

    // Cutting effects, when the trials disagree with the model so far.
    let min_fixed = 3;
    if current.misclassified() >= min_fixed {
        for e in lib.iter().filter(|e| e.scope() == Scope::Cutting) {
            let c = try_candidate(&ctx, &[e.as_ref()], &named, &named_values, &[], &current);
            let fixes = c
                .trials_misclassified_after
                .is_some_and(|m| current.misclassified() - m.min(current.misclassified()) >= min_fixed);
            if c.skipped.is_none() && c.delta_bic > BIC_STRONG && fixes {
                named.push(e.as_ref());
                named_values = c.values.clone();
                candidates.push(c);
                break;
            }
            candidates.push(c);
        }
    }

    // The augmented recipe, run again.
    let (diagnosed, _) = augmented(&ctx, &named, &named_values).map_err(recipe_err)?;
    let after = if named.is_empty() {
        baseline.clone()
    } else {
        at_trial_speeds(&diagnosed, &roles, &baseline.trial_speeds_rpm)
            .and_then(|t| compile_text(&t, path, &[], registry))
            .and_then(|c| evaluate(&c, &roles, registry, Some(Arc::clone(&ctx.memo))).map(|e| e.0))
            .map_err(|e| recipe_err(format!("the diagnosed recipe does not run: {e}")))?
    };

    let unexplained: Vec<Unexplained> = after
        .files
        .iter()
        .filter(|f| f.discrepant())
        .map(|f| Unexplained {
            direction: f.direction.clone(),
            speed_rpm: f.speed_rpm,
            near_hz: f.max_discrepancy_hz,
            band_hz: f.band_hz,
            ratio: f.ratio,
        })
        .collect();
    let trials_unexplained = after.misclassified() >= min_fixed;
    let verdict = if !unexplained.is_empty() || trials_unexplained {
        VERDICT_UNEXPLAINED
    } else if named.is_empty() {
        VERDICT_NONE
    } else {
        VERDICT_EFFECTS
    };
    // Effects are named only when they leave nothing unexplained; otherwise they are
    // evidence among the candidates.
    let effects: Vec<NamedEffect> = if verdict == VERDICT_EFFECTS {
        named
            .iter()
            .map(|e| {
                let c = candidates.iter().rev().find(|c| c.effects.contains(&e.name()) && c.skipped.is_none());
                let uncertainty: Map<String, Json> = c
                    .map(|c| {
                        c.fitted
                            .iter()
                            .map(|p| {
                                (
                                    p.name.clone(),
                                    serde_json::json!({ "value": p.value, "sigma": p.sigma, "unit": p.unit }),
                                )
                            })
                            .collect()
                    })
                    .unwrap_or_default();
                NamedEffect {
                    name: e.name(),
                    params: Json::Object(e.report(&named_values, &roles, &compiled)),
                    uncertainty: Json::Object(uncertainty),
                    evidence: serde_json::json!({
                        "delta_bic": c.map(|c| c.delta_bic),
                        "scope": e.scope(),
                        "description": e.description(),
                    }),
                }
            })
            .collect()
    } else {
        vec![]
    };
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
    let header = diagnosed_header(&named, &named_values, &roles, &compiled, verdict);
    Ok(Diagnosis {
        verdict,
        effects,
        unexplained,
        gap: GapReport { files, trials },
        candidates,
        recipe: shown,
        seconds: t0.elapsed().as_secs_f64(),
        diagnosed_recipe: format!("{header}{}", diagnosed.text),
    })
}

fn diagnosed_header(
    named: &[&dyn Effect],
    values: &[(String, f64)],
    roles: &Roles,
    c: &Compiled,
    verdict: &str,
) -> String {
    let mut s = format!("# Diagnosed by spindlelab: {verdict}.\n");
    for e in named {
        s.push_str(&format!("#   {}: {}\n", e.name(), e.description()));
        let p = Json::Object(e.report(values, roles, c));
        s.push_str(&format!("#     {}\n", readable(&p)));
    }
    if named.is_empty() {
        s.push_str("#   Nothing was added: the recipe below is the input.\n");
    }
    s
}

/// A value as a person reads it: numbers to five significant digits, keys unquoted.
fn readable(v: &Json) -> String {
    match v {
        Json::Number(n) => {
            let x = n.as_f64().unwrap_or(f64::NAN);
            if x == x.trunc() && x.abs() < 1e6 { format!("{x}") } else { format!("{x:.4e}") }
        }
        Json::String(s) => s.clone(),
        Json::Array(a) => format!("[{}]", a.iter().map(readable).collect::<Vec<_>>().join(", ")),
        Json::Object(m) => {
            format!("{{{}}}", m.iter().map(|(k, v)| format!("{k}: {}", readable(v))).collect::<Vec<_>>().join(", "))
        }
        other => other.to_string(),
    }
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
        if let Some(b) = e.evidence["delta_bic"].as_f64() {
            s.push_str(&format!("  - evidence: BIC {b:.1} better than the model without it\n"));
        }
    }
    for u in &d.unexplained {
        s.push_str(&format!(
            "- unexplained in {} at {} rpm near {:.0} Hz (band {:.0}–{:.0} Hz), gap ratio {:.2}\n",
            u.direction, u.speed_rpm, u.near_hz, u.band_hz[0], u.band_hz[1], u.ratio
        ));
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
    staged.commit().map_err(DiagnoseError::Output)
}

/// Evaluates the recipe at `path` as written: every gap step against its measurement and the
/// trials against the lobes at the trials' speeds, with nothing fitted. This is the number a
/// diagnosis starts from, and what a recipe with effects added by hand comes to.
pub fn evaluate_file(path: &Path, registry: &Registry) -> Result<Evaluation, DiagnoseError> {
    let shown = path.display().to_string();
    let err = |message: String| DiagnoseError::Recipe { path: shown.clone(), message };
    let text = std::fs::read_to_string(path).map_err(|e| err(format!("cannot read the recipe: {e}")))?;
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
    let text = std::fs::read_to_string(path).map_err(|e| err(e.to_string()))?;
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
        let free = e.apply(&roles, &compiled, &mut r).map_err(err)?;
        let values = &effects.iter().find(|(n, _)| *n == e.name()).expect("listed").1;
        for (name, v) in values {
            let f = free
                .iter()
                .find(|f| f.name == *name)
                .ok_or_else(|| err(format!("{} has no parameter `{name}`", e.name())))?;
            r.declare_param(name, &f.text(*v)).map_err(|e| err(e.to_string()))?;
        }
    }
    Ok(r.text)
}
