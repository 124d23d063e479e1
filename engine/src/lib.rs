//! spindlelab engine: a recipe goes from text to a raw tree ([`syntax`]), to a resolved,
//! typed recipe ([`model`]), to an instance graph ([`graph`]), and is run by [`exec`].
//!
//! The facade here is what the CLI and tests use: [`compile_file`] collects every
//! diagnostic before anything runs; [`run`] executes and writes outputs atomically.

// Tests make pipes (mkfifo) to check that they are never waited on; the engine itself holds
// no unsafe code.
#![cfg_attr(not(test), forbid(unsafe_code))]

pub mod diag;
pub mod exec;
pub mod formats;
pub mod graph;
pub mod model;
pub mod node;
pub mod node_params;
pub mod plot;
pub use exec::render;
pub mod schema;
pub mod spec;
pub mod syntax;

pub use spindlelab_domain as domain;
pub use spindlelab_domain::value;
pub use spindlelab_grammar as grammar;

use diag::{Diagnostics, SourceFile};
use exec::{Outcome, RunOptions, RunResult};
use graph::Graph;
use model::Recipe;
use node::Registry;
use std::path::{Path, PathBuf};

/// A recipe that compiled: the resolved recipe, its graph and the sources it came from.
pub struct Compiled {
    pub path: PathBuf,
    /// The tree as loaded, before parameters were substituted: a fit recompiles from it.
    pub raw: syntax::Raw,
    pub recipe: Recipe,
    pub graph: Graph,
    pub sources: Vec<SourceFile>,
    /// Warnings found while compiling.
    pub warnings: Diagnostics,
}

impl Compiled {
    /// Every file the recipe took something from besides itself (libraries, recipes run as
    /// steps, Rhai modules), as shown, with the BLAKE3 hash of what was read.
    pub fn used_files(&self) -> indexmap::IndexMap<String, String> {
        self.sources
            .iter()
            .skip(1)
            .map(|s| (s.path.to_string(), blake3::hash(s.text.as_bytes()).to_hex().to_string()))
            .collect()
    }
}

/// A recipe that did not compile, with every diagnostic found.
#[derive(Debug)]
pub struct CompileError {
    pub diagnostics: Diagnostics,
    pub sources: Vec<SourceFile>,
}

impl CompileError {
    pub fn render(&self, color: bool) -> String {
        self.diagnostics.render(&self.sources, color)
    }
}

impl std::fmt::Display for CompileError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.diagnostics)
    }
}

impl std::error::Error for CompileError {}

/// Loads, resolves and compiles a recipe file, reporting every problem at once.
pub fn compile_file(path: &Path, registry: &Registry) -> Result<Compiled, CompileError> {
    compile_file_with(path, &[], registry)
}

/// [`compile_file`] with parameters set from outside (`--set kt=3e8N/m`): `(name, value text)`.
pub fn compile_file_with(
    path: &Path,
    overrides: &[(String, String)],
    registry: &Registry,
) -> Result<Compiled, CompileError> {
    let mut diags = Diagnostics::new();
    let loaded = syntax::load_file(path, &mut diags);
    let sources: Vec<SourceFile> = loaded.iter().flat_map(|l| l.sources()).collect();
    let raw = loaded.and_then(|l| l.raw);
    match raw {
        Some(raw) => compile_raw(path, raw, overrides, sources, registry, diags),
        None => {
            diags.sort();
            Err(CompileError { diagnostics: diags, sources })
        }
    }
}

/// Resolves and compiles a loaded raw tree with parameter overrides. The libraries it uses
/// and the recipes it runs as steps are read and expanded first (their files added to
/// `sources`); the tree kept in [`Compiled::raw`] is the expanded one, so a fit, which calls
/// this once per evaluation, reads no file again.
pub fn compile_raw(
    path: &Path,
    raw: syntax::Raw,
    overrides: &[(String, String)],
    sources: Vec<SourceFile>,
    registry: &Registry,
    diags: Diagnostics,
) -> Result<Compiled, CompileError> {
    compile_raw_within(path, raw, overrides, sources, registry, diags, Reach::Anywhere)
}

/// Which files a recipe may read besides itself: its libraries, the recipes it runs as steps
/// and its data files. (A Rhai recipe's modules are always its own folder's.)
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Reach {
    /// Wherever they are named; the manifest records each data file with its hash.
    #[default]
    Anywhere,
    /// `--confine`, for recipes from elsewhere: only files inside the recipe's folder, judged
    /// by name (absolute, or climbing out with `..`, is outside) before a byte of them is read,
    /// so a refused file is never quoted.
    RecipeFolder,
}

/// [`compile_raw`] with the files the recipe may read limited by `reach`.
pub fn compile_raw_within(
    path: &Path,
    raw: syntax::Raw,
    overrides: &[(String, String)],
    mut sources: Vec<SourceFile>,
    registry: &Registry,
    mut diags: Diagnostics,
    reach: Reach,
) -> Result<Compiled, CompileError> {
    let folder = path.parent().unwrap_or(Path::new(""));
    let confine = (reach == Reach::RecipeFolder).then_some(folder);
    let expanded = model::expand_within(raw, registry, confine, &mut sources, &mut diags);
    let (raw, library) = (expanded.raw, expanded.library);
    if diags.has_errors() {
        diags.sort();
        return Err(CompileError { diagnostics: diags, sources });
    }
    let recipe = model::resolve_within(&raw, overrides, registry, confine, &mut diags).map(|mut r| {
        r.library = library;
        r
    });
    let graph = recipe.as_ref().filter(|_| !diags.has_errors()).map(|r| graph::compile(r, registry, &mut diags));
    diags.sort();
    match (recipe, graph) {
        (Some(recipe), Some(graph)) if !diags.has_errors() => {
            Ok(Compiled { path: path.to_path_buf(), raw, recipe, graph, sources, warnings: diags })
        }
        _ => Err(CompileError { diagnostics: diags, sources }),
    }
}

/// Why a run did not complete.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// Some instances failed; the report says what the others did and what was written.
    #[error("{} node instance(s) failed", .failures.len())]
    NodesFailed { failures: Vec<(String, String)>, report: Box<RunReport> },
    /// The output folder is busy, holds a link that leads elsewhere, or cannot be written.
    #[error("{0}")]
    Output(exec::CommitError),
    /// The recipe asks for a plot or a report and the run was given no renderer to draw it:
    /// a caller's mistake (the command always gives one), found before anything runs.
    #[error("`{0}` asks for a drawing and this run has no renderer: set `RunOptions::renderer`")]
    NoRenderer(String),
}

/// Everything a run produced.
#[derive(Debug)]
pub struct RunReport {
    pub result: RunResult,
    pub manifest: exec::Manifest,
    /// Output files written (relative to the output directory).
    pub written: Vec<String>,
}

/// Runs a compiled recipe and writes its outputs and manifest into `opts.out_dir`.
///
/// The run holds the output folder's lock throughout; its files and manifest go into a fresh
/// run folder that replaces the previous run as one ([`exec::commit`]). With `keep_going`,
/// outputs are written even if some instances failed, a swept one without its failed sweep
/// points (the file and the manifest's `partial` list them); a failed run otherwise commits
/// only its manifest, so no earlier output stands beside it unmarked. The cache keeps every
/// computed instance either way.
pub fn run(
    compiled: &Compiled,
    registry: &Registry,
    opts: &RunOptions,
    progress: &(dyn Fn(usize, &str) + Sync),
) -> Result<RunReport, RunError> {
    let dir = exec::OutputDir::open(&opts.out_dir).map_err(RunError::Output)?;
    // A file of the user's where an output goes is refused before anything is computed.
    let files: Vec<(&model::Output, String, Vec<usize>)> = compiled
        .recipe
        .outputs
        .iter()
        .flat_map(|o| {
            let files = compiled.graph.output_files(o).unwrap_or_default();
            files.into_iter().map(move |(file, ids)| (o, file, ids))
        })
        .collect();
    let names = files.iter().map(|(_, f, _)| f.as_str());
    let names = names.chain(opts.extra_files.iter().map(|(rel, _)| rel.as_str()));
    let names = names.chain([exec::manifest::MANIFEST_FILE]);
    let names = names.chain(opts.report.then_some(render::REPORT_FILE));
    dir.check_outputs(names).map_err(RunError::Output)?;
    let renderer = opts.renderer.as_deref();
    if renderer.is_none()
        && let Some(asks) = compiled
            .recipe
            .outputs
            .iter()
            .find(|o| matches!(o.format, model::OutputFormat::Plot(_)))
            .map(|o| o.file.as_str())
            .or(opts.report.then_some(render::REPORT_FILE))
    {
        return Err(RunError::NoRenderer(asks.to_string()));
    }
    let result = exec::execute(&compiled.recipe, &compiled.graph, registry, opts, progress);
    let failures: Vec<(String, String)> =
        result.failures(&compiled.graph).map(|(id, e)| (id.to_string(), e.to_string())).collect();
    let complete = failures.is_empty() && result.outcomes.iter().all(|o| !matches!(o, Outcome::Skipped));
    let mut staged = dir.stage().map_err(RunError::Output)?;
    let mut written = Vec::new();
    let mut plot_notes = Vec::new();
    let mut partial = indexmap::IndexMap::new();
    let mut contents: Vec<(String, Vec<u8>)> = Vec::new();
    for (out, file, ids) in files.iter().filter(|_| complete || opts.keep_going) {
        let mut rows = Vec::new();
        let mut missing = Vec::new();
        for &i in ids {
            let inst = &compiled.graph.instances[i];
            match result.outcomes[i].outputs().and_then(|o| o.get(&out.from.port)) {
                Some(value) => rows.push(exec::write::Row { label: &inst.label, value }),
                None => missing.push(exec::manifest::MissingPoint {
                    label: inst.label.clone(),
                    instance: inst.id.clone(),
                    reason: missing_reason(&compiled.graph, &result, i),
                }),
            }
        }
        // A swept output keeps the sweep points that succeeded and marks the others; an output
        // with nothing to show, or an unswept one that failed, is not written.
        if rows.is_empty() || (!missing.is_empty() && ids.len() == 1) {
            continue;
        }
        // Scalars in the unit the output asks for.
        let converted: Vec<value::Value>;
        if let Some(unit) = &out.unit {
            match rows.iter().map(|r| in_unit(r.value, unit)).collect::<Result<Vec<_>, _>>() {
                Ok(v) => converted = v,
                Err(message) => {
                    plot_notes.push(format!("{file}: not written: {message}"));
                    continue;
                }
            }
            for (r, v) in rows.iter_mut().zip(&converted) {
                r.value = v;
            }
        }
        let bytes = match out.format {
            model::OutputFormat::Plot(format) => match renderer
                .ok_or_else(|| "no renderer was given to this run".to_string())
                .and_then(|r| plot_output(compiled, &result, out, (file, ids), format, &rows, r))
            {
                Ok(bytes) => bytes,
                Err(message) => {
                    plot_notes.push(format!("{file}: not drawn: {message}"));
                    continue;
                }
            },
            format => exec::write::render_partial(format, &rows, &missing).into_bytes(),
        };
        staged.write(file, &bytes).map_err(RunError::Output)?;
        written.push(file.clone());
        if !missing.is_empty() {
            partial.insert(file.clone(), missing);
        }
        if opts.report {
            contents.push((file.clone(), bytes));
        }
    }
    for (rel, text) in &opts.extra_files {
        staged.write(rel, text.as_bytes()).map_err(RunError::Output)?;
    }
    let mut manifest = exec::Manifest::build(
        &compiled.recipe,
        &compiled.path.display().to_string(),
        &compiled.graph,
        &result,
        written.clone(),
    );
    manifest.notes.extend(dir.notes().iter().cloned());
    manifest.notes.extend(plot_notes);
    manifest.partial = partial;
    manifest.recipe_text = compiled.sources.first().map(|s| s.text.to_string()).unwrap_or_default();
    manifest.recipe_files = compiled.used_files();
    manifest.files = staged.files().iter().cloned().collect();
    if let (true, Some(renderer)) = (opts.report, renderer) {
        let html = renderer.report(&manifest, Some(&manifest.recipe_text), &contents);
        staged.write(render::REPORT_FILE, html.as_bytes()).map_err(RunError::Output)?;
        written.push(render::REPORT_FILE.to_string());
        manifest.files = staged.files().iter().cloned().collect();
    }
    let json = serde_json::to_string_pretty(&manifest).expect("manifest serialises");
    staged.write(exec::manifest::MANIFEST_FILE, json.as_bytes()).map_err(RunError::Output)?;
    staged.commit().map_err(RunError::Output)?;
    let report = RunReport { result, manifest, written };
    if failures.is_empty() { Ok(report) } else { Err(RunError::NodesFailed { failures, report: Box::new(report) }) }
}

/// Why instance `i` has no value: its own error, or the failed instance upstream that kept it
/// from running.
/// A scalar in `unit` as the recipe wrote it (`deg/kHz`): its SI value over the unit's scale,
/// when the two measure the same quantity.
fn in_unit(v: &value::Value, unit: &str) -> Result<value::Value, String> {
    use spindlelab_grammar::{Unit, parse_unit};
    let value::Value::Scalar(s) = v else {
        return Err(format!("`unit` is for a scalar; this is a {}", v.port_type()));
    };
    let to = parse_unit(unit).map_err(|e| format!("`{unit}` is not a unit: {e}"))?;
    let from = match s.unit.symbol.as_str() {
        "" => Unit::ONE,
        symbol => parse_unit(symbol).map_err(|_| format!("the value's unit `{symbol}` cannot be converted"))?,
    };
    if from.dim != to.dim {
        let held =
            if s.unit.symbol.is_empty() { "a plain number".to_string() } else { format!("in {}", s.unit.symbol) };
        return Err(format!("the value is {held}, which `{unit}` does not measure"));
    }
    Ok(value::Value::Scalar(value::Scalar::new(s.value * from.scale / to.scale, unit)))
}

fn missing_reason(graph: &graph::Graph, result: &RunResult, i: usize) -> String {
    match &result.outcomes[i] {
        Outcome::Failed(e) => format!("failed: {e}"),
        Outcome::Skipped => {
            let mut stack = vec![i];
            let mut seen = std::collections::HashSet::new();
            while let Some(j) = stack.pop() {
                if !seen.insert(j) {
                    continue;
                }
                if matches!(result.outcomes[j], Outcome::Failed(_)) {
                    return format!("not run: its input `{}` failed", graph.instances[j].id);
                }
                stack.extend(graph.instances[j].deps());
            }
            "not run: the run stopped before it".to_string()
        }
        _ => "no value on this port".to_string(),
    }
}

/// The plot an output names, drawn from a finished run in `format` (a figure test draws every
/// example's plots as PNG); `None` when the output is not a plot or its step has no values.
pub fn plot_of_output(
    compiled: &Compiled,
    result: &RunResult,
    out: &model::Output,
    format: plot::PlotFormat,
    renderer: &dyn render::Renderer,
) -> Option<Result<Vec<u8>, String>> {
    if !matches!(out.format, model::OutputFormat::Plot(_)) {
        return None;
    }
    let ids = &compiled.graph.by_step[&out.from.step];
    let rows: Vec<exec::write::Row> = ids
        .iter()
        .filter_map(|&i| {
            let value = result.outcomes[i].outputs()?.get(&out.from.port)?;
            Some(exec::write::Row { label: &compiled.graph.instances[i].label, value })
        })
        .collect();
    (!rows.is_empty()).then(|| plot_output(compiled, result, out, (&out.file, ids), format, &rows, renderer))
}

/// An output's plot: the rows of its own port, each `with` reference's values over them, each
/// named by the output's or step's `label` (else its step) and its sweep point.
fn plot_output(
    compiled: &Compiled,
    result: &RunResult,
    out: &model::Output,
    (file, ids): (&str, &[usize]),
    format: plot::PlotFormat,
    rows: &[exec::write::Row],
    renderer: &dyn render::Renderer,
) -> Result<Vec<u8>, String> {
    let name = |r: &model::PortRef| {
        compiled.recipe.step(&r.step).and_then(|s| s.label.clone()).unwrap_or_else(|| default_label(r))
    };
    let main_name = out.label.clone().unwrap_or_else(|| name(&out.from));
    let main: Vec<plot::Layer> = rows.iter().map(|r| plot::Layer::swept(main_name.clone(), r.value, r.label)).collect();
    let mut with = Vec::new();
    // A file of one sweep point (`{file}` in its name) draws the values of that point: each
    // `with` instance that agrees with it on the coordinates the name splits by.
    let point: Vec<(&str, &str)> = match ids.first() {
        Some(&i) if file != out.file => {
            let axes = out.split_by();
            graph::coordinates(&compiled.graph.instances[i].label)
                .into_iter()
                .filter(|(n, _)| axes.contains(n))
                .collect()
        }
        _ => Vec::new(),
    };
    for (w, label) in out.with.iter().zip(&out.with_labels) {
        for &i in &compiled.graph.by_step[&w.step] {
            let inst = &compiled.graph.instances[i];
            let coords = graph::coordinates(&inst.label);
            if point.iter().any(|(n, v)| coords.iter().any(|(m, u)| m == n && u != v)) {
                continue;
            }
            let value = result.outcomes[i]
                .outputs()
                .and_then(|o| o.get(&w.port))
                .ok_or_else(|| format!("`{}` did not run", inst.id))?;
            with.push(plot::Layer::swept(label.clone().unwrap_or_else(|| name(w)), value, &inst.label));
        }
    }
    let mut title = format!("{}: {main_name}", compiled.recipe.name);
    if !point.is_empty() {
        let at: Vec<String> = point.iter().map(|(n, v)| format!("{n} {v}")).collect();
        title = format!("{title}, {}", at.join(", "));
    }
    if let Some(cut) = cut_of(compiled, &out.from.step) {
        title = format!("{title} ({cut})");
    }
    let fig = plot::figure(&title, out.plot.as_deref(), &main, &with).map_err(|e| e.to_string())?;
    renderer.draw(&fig, format).map_err(|e| e.to_string())
}

/// A reference's legend name without a `label`: its step, and its port unless that is the
/// value's plain name (`corrected`, `rig truth frf`, `trials verdicts`).
fn default_label(r: &model::PortRef) -> String {
    const PLAIN: &[&str] = &["frf", "value", "lobes", "table", "signal", "model", "set", "receptance"];
    let words = |s: &str| s.replace(['_', '-'], " ");
    if PLAIN.contains(&r.port.as_str()) { words(&r.step) } else { format!("{} {}", words(&r.step), words(&r.port)) }
}

/// The cut a step's stability diagram is for, in the units a shop uses: `4 teeth, 50 %
/// immersion, down milling, Ks 800 N/mm², β 68°`; `None` when the step names no cutting setup.
fn cut_of(compiled: &Compiled, step: &str) -> Option<String> {
    let name = compiled.recipe.step(step)?.params.text("cutting")?;
    let c = compiled.recipe.cutting.get(name)?;
    let ks = c.kt.hypot(c.kn);
    let beta = c.kt.atan2(c.kn).to_degrees();
    Some(format!(
        "{} teeth, {} % immersion, {} milling, Ks {} N/mm², β {}°",
        c.teeth,
        spindlelab_domain::round_sig(100.0 * c.radial_immersion, 3),
        if c.up_milling { "up" } else { "down" },
        spindlelab_domain::round_sig(ks / 1e6, 4),
        spindlelab_domain::round_sig(beta, 3)
    ))
}
