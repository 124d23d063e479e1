//! The fit driver: moves a recipe's free parameters (its `fit:` block) to minimise the sum
//! of squares of its objective outputs.
//!
//! Each evaluation substitutes the trial values into the loaded recipe, recompiles it (no
//! file is read again but the data files' hashes) and runs only the steps the objective
//! needs, in memory. Instances whose cache key the trial values do not reach are taken from
//! the start point's results, so a fit of a joint stiffness recomputes the coupling and the
//! gap, never the holder–tool modes. Nothing is written until the caller runs the fitted
//! recipe.

use crate::engine::exec::{self, Memo, Outcome, RunOptions};
use crate::engine::model::{FitMethod, FitScale, FreeParam};
use crate::engine::node::Registry;
use crate::engine::value::Value;
use crate::engine::{Compiled, compile_raw, diag::Diagnostics};
use crate::stdlib::optimize::{self, SearchOptions, SearchResult};
use serde::Serialize;
use std::sync::Arc;
use std::time::Instant;

/// One fitted parameter, in the unit the recipe writes it in.
#[derive(Debug, Clone, Serialize)]
pub struct FittedParam {
    pub name: String,
    pub unit: String,
    pub start: f64,
    pub value: f64,
    /// One standard deviation from the Jacobian and the residual variance, when the method
    /// gives a Jacobian and the data determine the parameter.
    pub sigma: Option<f64>,
    pub min: f64,
    pub max: f64,
    /// Whether the value sits on a bound (the data want it further).
    pub at_bound: bool,
}

/// What a fit did.
#[derive(Debug, Clone, Serialize)]
pub struct FitReport {
    pub method: &'static str,
    pub params: Vec<FittedParam>,
    /// Sum of squares of the objective outputs at the start and at the end.
    pub objective_before: f64,
    pub objective_after: f64,
    pub evaluations: usize,
    pub converged: bool,
    /// Residuals summed (FRF lines count twice: real and imaginary part).
    pub residuals: usize,
    pub seconds: f64,
    /// Why the last failed evaluation failed, if any did.
    pub last_failure: Option<String>,
}

impl FitReport {
    /// `(name, value text)` pairs that set the fitted values (`--set` form).
    pub fn overrides(&self) -> Vec<(String, String)> {
        self.params
            .iter()
            .map(|p| {
                let text =
                    if p.unit.is_empty() { format!("{:e}", p.value) } else { format!("{:e} {}", p.value, p.unit) };
                (p.name.clone(), text)
            })
            .collect()
    }
}

/// Why a fit could not run.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    #[error("the recipe has no `fit:` block")]
    NoFit,
    #[error("the model cannot be evaluated at the start values: {0}")]
    Start(String),
}

/// Maps unit coordinates to parameter numbers and back. The number is clamped into
/// `[min, max]`: `exp(ln min + 1·(ln max − ln min))` rounds to an ulp past the bound
/// (1e6 → 999999.9999999995, 1e3 → 999.9999999999998), which the recompile would refuse
/// as outside the bounds, failing every evaluation on that face of the box.
fn to_number(p: &FreeParam, z: f64) -> f64 {
    let x = match p.scale {
        FitScale::Linear => p.min + z * (p.max - p.min),
        FitScale::Log => (p.min.ln() + z * (p.max.ln() - p.min.ln())).exp(),
    };
    if z <= 0.0 {
        p.min
    } else if z >= 1.0 {
        p.max
    } else {
        x.clamp(p.min, p.max)
    }
}

fn to_unit(p: &FreeParam, x: f64) -> f64 {
    match p.scale {
        FitScale::Linear => (x - p.min) / (p.max - p.min),
        FitScale::Log => (x.ln() - p.min.ln()) / (p.max.ln() - p.min.ln()),
    }
}

/// The objective outputs of a finished evaluation as one residual vector, in step and
/// sweep order: an FRF gives the real and imaginary part of every line, a scalar itself.
fn residuals(compiled: &Compiled, outcomes: &[Outcome]) -> Result<Vec<f64>, String> {
    let fit = compiled.recipe.fit.as_ref().expect("fit");
    let mut r = Vec::new();
    for port in &fit.objective {
        for &i in &compiled.graph.by_step[&port.step] {
            let inst = &compiled.graph.instances[i];
            let outputs = match &outcomes[i] {
                Outcome::Failed(e) => return Err(format!("`{}` failed: {e}", inst.id)),
                o => o.outputs().ok_or_else(|| format!("`{}` did not run", inst.id))?,
            };
            match outputs.get(&port.port).map(|v| v.as_ref()) {
                Some(Value::Frf(f)) => r.extend(f.values.iter().flat_map(|c| [c.re, c.im])),
                Some(Value::Scalar(s)) => r.push(s.value),
                _ => return Err(format!("`{}` produced no `{}`", inst.id, port.port)),
            }
        }
    }
    Ok(r)
}

/// Runs the recipe's fit. `overrides` are the command line's `--set` values (a free
/// parameter set there starts the fit from that value).
pub fn fit(
    compiled: &Compiled,
    overrides: &[(String, String)],
    registry: &Registry,
    threads: Option<usize>,
) -> Result<FitReport, FitError> {
    let start_time = Instant::now();
    let spec = compiled.recipe.fit.as_ref().ok_or(FitError::NoFit)?;
    let free = &spec.free;
    let quantities: Vec<_> =
        free.iter().map(|p| compiled.recipe.params[&p.name].quantity.clone().expect("checked numeric")).collect();
    let fixed: Vec<(String, String)> =
        overrides.iter().filter(|(n, _)| !free.iter().any(|p| &p.name == n)).cloned().collect();
    let targets: Vec<String> = spec.objective.iter().map(|p| p.step.clone()).collect();
    let base_memo: std::cell::RefCell<Option<Arc<Memo>>> = std::cell::RefCell::new(None);
    let last_failure: std::cell::RefCell<Option<String>> = std::cell::RefCell::new(None);

    let mut evaluate = |z: &[f64]| -> Option<Vec<f64>> {
        let mut set = fixed.clone();
        for ((p, q), &zk) in free.iter().zip(&quantities).zip(z) {
            set.push((p.name.clone(), q.text_for(to_number(p, zk))));
        }
        let trial = match compile_raw(
            &compiled.path,
            compiled.raw.clone(),
            &set,
            compiled.sources.clone(),
            registry,
            Diagnostics::new(),
        ) {
            Ok(c) => c,
            Err(e) => {
                *last_failure.borrow_mut() = Some(e.to_string());
                return None;
            }
        };
        let opts = RunOptions {
            use_cache: false,
            threads,
            memo: base_memo.borrow().clone(),
            targets: Some(targets.clone()),
            renderer: Some(crate::renderer()),
            ..RunOptions::new(std::env::temp_dir())
        };
        let result = exec::execute(&trial.recipe, &trial.graph, registry, &opts, &|_, _| {});
        // The first evaluation (the start point) seeds the memo every later one reads.
        if base_memo.borrow().is_none() {
            *base_memo.borrow_mut() = Some(Arc::new(result.memo(&trial.graph)));
        }
        match residuals(&trial, &result.outcomes) {
            Ok(r) if r.iter().all(|v| v.is_finite()) => Some(r),
            Ok(_) => {
                *last_failure.borrow_mut() = Some("the objective is not finite".into());
                None
            }
            Err(e) => {
                *last_failure.borrow_mut() = Some(e);
                None
            }
        }
    };

    let z0: Vec<f64> = free.iter().zip(&quantities).map(|(p, q)| to_unit(p, q.number)).collect();
    if evaluate(&z0).is_none() {
        return Err(FitError::Start(last_failure.borrow().clone().unwrap_or_default()));
    }
    let opts =
        SearchOptions { max_evaluations: spec.max_evaluations.saturating_sub(1).max(1), tolerance: spec.tolerance };
    let local = match spec.method {
        FitMethod::LeastSquares => optimize::levenberg_marquardt,
        FitMethod::NelderMead => optimize::nelder_mead,
    };
    let result: Option<SearchResult> = if spec.starts == 0 {
        local(&mut evaluate, &z0, opts)
    } else {
        optimize::multistart(&mut evaluate, &z0, spec.starts, 3, opts, local)
    };
    let result = result.ok_or_else(|| FitError::Start(last_failure.borrow().clone().unwrap_or_default()))?;
    let sigmas = result.jacobian.as_ref().and_then(|j| optimize::coordinate_sigmas(j, result.cost));
    let params = free
        .iter()
        .zip(&quantities)
        .enumerate()
        .map(|(k, (p, q))| {
            let value = to_number(p, result.z[k]);
            // dx/dz times the coordinate's deviation.
            let slope = match p.scale {
                FitScale::Linear => p.max - p.min,
                FitScale::Log => value * (p.max.ln() - p.min.ln()),
            };
            FittedParam {
                name: p.name.clone(),
                unit: q.unit.clone(),
                start: q.number,
                value,
                sigma: sigmas.as_ref().and_then(|s| s.get(k).copied()).map(|s| s * slope),
                min: p.min,
                max: p.max,
                at_bound: result.z[k] <= 1e-9 || result.z[k] >= 1.0 - 1e-9,
            }
        })
        .collect();
    Ok(FitReport {
        method: match spec.method {
            FitMethod::LeastSquares => "least-squares",
            FitMethod::NelderMead => "nelder-mead",
        },
        params,
        objective_before: result.start_cost,
        objective_after: result.cost,
        evaluations: result.evaluations + 1,
        converged: result.converged,
        residuals: result.residuals.len(),
        seconds: start_time.elapsed().as_secs_f64(),
        last_failure: last_failure.into_inner(),
    })
}

/// The recipe text with each fitted parameter's declared value replaced, so it diffs
/// against the input line by line. `None` for a recipe whose declarations have no place in
/// the text (a Rhai script); its fitted values are in the fit report.
pub fn fitted_recipe(compiled: &Compiled, report: &FitReport) -> Option<String> {
    let text = compiled.sources.first()?.text.clone();
    let mut edits: Vec<(usize, usize, String)> = Vec::new();
    for (name, value) in report.overrides() {
        let p = compiled.recipe.params.get(&name)?;
        let (a, b) = p.span.bytes?;
        let old = text.get(a..b)?;
        let quote = old.chars().next().filter(|c| *c == '"' || *c == '\'');
        let new = match quote {
            Some(q) => format!("{q}{value}{q}"),
            None => value,
        };
        edits.push((a, b, new));
    }
    edits.sort_by_key(|e| std::cmp::Reverse(e.0));
    let mut out = text.to_string();
    for (a, b, new) in edits {
        out.replace_range(a..b, &new);
    }
    let lines: Vec<String> = report
        .params
        .iter()
        .map(|p| {
            let sigma = p.sigma.map(|s| format!(" ± {s:.3e}")).unwrap_or_default();
            format!("#   {} = {:.6e}{sigma} {} (start {:e})", p.name, p.value, p.unit, p.start)
        })
        .collect();
    Some(format!(
        "# Fitted by spindlelab ({}, {} evaluations, objective {:.6e} -> {:.6e}):\n{}\n# Place it beside {} to run it; its data files are named relative to that folder.\n{out}",
        report.method,
        report.evaluations,
        report.objective_before,
        report.objective_after,
        lines.join("\n"),
        compiled.path.display()
    ))
}

/// Writes `fit.json` (the report) and `fitted.yaml` (the recipe with the fitted values)
/// into the output directory, each written whole or not at all.
/// The fit's report (`fit.json`) and written-back recipe (`fitted.yaml`), as files of the run
/// that uses the fitted values (committed with its outputs).
pub fn fit_files(compiled: &Compiled, report: &FitReport) -> Vec<(String, String)> {
    let mut files =
        vec![(FIT_REPORT_FILE.to_string(), serde_json::to_string_pretty(report).expect("report serialises"))];
    if let Some(text) = fitted_recipe(compiled, report) {
        files.push((FITTED_RECIPE_FILE.to_string(), text));
    }
    files
}

/// File names of a fit's report and written-back recipe in the output directory.
pub const FIT_REPORT_FILE: &str = "fit.json";
pub const FITTED_RECIPE_FILE: &str = "fitted.yaml";
