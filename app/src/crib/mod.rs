//! The tool-crib survey: a catalog of holders and end mills (docs/crib.md) turned into the
//! recipe that couples every (holder, tool, stickout) to one machine's spindle, computes its
//! lobes and its best cut, and one table of the best cut of every combination.
//!
//! The recipe is built as a raw tree and written as YAML ([`yaml`]), so what runs is exactly
//! what `--emit` writes and `export snakemake` shards: the emitted text is read back and
//! compiled by the project's own compiler before anything runs.

pub mod catalog;

pub use catalog::{Catalog, Combination};

use crate::engine::diag::{Diagnostics, SourceFile};
use crate::engine::exec::{self, Outcome, RunOptions};
use crate::engine::node::Registry;
use crate::engine::syntax::emit::{Notes, emit_noted};
use crate::engine::syntax::{self, Raw};
use crate::engine::value::{Column, Table, Value};
use crate::engine::{self, CompileError, Compiled, RunError, RunReport};
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

/// The file of the combined table a survey run writes beside the per-tool tables.
pub const SUMMARY_FILE: &str = "crib-summary.csv";

/// Why a survey could not be built or run.
#[derive(Debug, thiserror::Error)]
pub enum CribError {
    /// The catalog (or a library it names) has problems, each at its file, line and column.
    #[error("{}", .diagnostics)]
    Catalog { diagnostics: Diagnostics, sources: Vec<SourceFile> },
    /// The machine file cannot give the machine.
    #[error("{0}")]
    Machine(String),
    /// The generated recipe did not compile: a catalog value the recipe refuses.
    #[error("the survey's recipe does not compile:\n{0}")]
    Compile(CompileError),
    /// A result the survey expected is not there (a node gave no best cut).
    #[error("{0}")]
    Survey(String),
    /// The run failed: nodes that rejected their data, or an output folder that cannot be written.
    #[error("{0}")]
    Run(RunError),
}

impl CribError {
    /// Whether the input is at fault (exit code 2), not the machine.
    pub fn is_bad_input(&self) -> bool {
        match self {
            CribError::Run(RunError::Output(e)) => e.is_bad_input(),
            CribError::Run(RunError::NoRenderer(_)) => false,
            _ => true,
        }
    }

    /// The error as the terminal shows it: diagnostics with the lines they point at.
    pub fn render(&self, color: bool) -> String {
        match self {
            CribError::Catalog { diagnostics, sources } => diagnostics.render(sources, color),
            CribError::Compile(e) => format!("the survey's recipe does not compile:\n{}", e.render(color)),
            CribError::Run(RunError::NodesFailed { failures, .. }) => {
                failures.iter().map(|(id, e)| format!("error: node `{id}` failed: {e}\n")).collect()
            }
            other => format!("error: {other}\n"),
        }
    }
}

/// A catalog as read, with the files it came from (for its diagnostics).
pub struct Loaded {
    pub catalog: Catalog,
    pub path: PathBuf,
    pub sources: Vec<SourceFile>,
}

/// The machine a survey runs on: the library that defines it, and its name there.
#[derive(Debug, Clone)]
pub struct MachineRef {
    pub library: PathBuf,
    pub name: String,
    /// The materials the library brings (its own and those it uses).
    pub materials: Vec<String>,
}

fn catalog_error(diags: Diagnostics, sources: Vec<SourceFile>) -> CribError {
    let mut diagnostics = diags;
    diagnostics.sort();
    CribError::Catalog { diagnostics, sources }
}

/// Reads and checks a catalog file; the materials its sections name must come from the
/// libraries it uses or from the machine's library.
pub fn load(path: &Path, machine: &MachineRef, registry: &Registry) -> Result<Loaded, CribError> {
    let mut diags = Diagnostics::new();
    let loaded = syntax::load_file(path, &mut diags);
    let sources: Vec<SourceFile> = loaded.iter().flat_map(|l| l.sources()).collect();
    let Some(raw) = loaded.and_then(|l| l.raw) else {
        return Err(catalog_error(diags, sources));
    };
    let Some(catalog) = catalog::read(&raw, &mut diags) else {
        return Err(catalog_error(diags, sources));
    };
    let folder = path.parent().unwrap_or(Path::new(""));
    let mut materials = machine.materials.clone();
    for (lib, span) in &catalog.uses {
        match engine::compile_file(&folder.join(lib), registry) {
            Ok(c) if c.recipe.library => materials.extend(c.recipe.materials.keys().cloned()),
            Ok(_) => diags.error_help(
                Some(span),
                format!("`{lib}` is a recipe, not a library"),
                "name a library of materials (`materials:` only)",
            ),
            Err(e) => diags.error_help(
                Some(span),
                format!("the library `{lib}` does not check: {}", e.diagnostics),
                format!("run `spindlelab check {}`", folder.join(lib).display()),
            ),
        }
    }
    for (name, span) in catalog::materials_named(&catalog) {
        if !materials.iter().any(|m| m == name) {
            let hint = crate::engine::spec::suggest(name, materials.iter().map(String::as_str))
                .map(|s| format!("did you mean `{s}`? "))
                .unwrap_or_default();
            diags.error_help(
                Some(span),
                format!("no material `{name}` in the libraries the catalog uses or the machine's"),
                format!("{hint}add a library that defines it to `use:`"),
            );
        }
    }
    if diags.has_errors() {
        return Err(catalog_error(diags, sources));
    }
    Ok(Loaded { catalog, path: path.to_path_buf(), sources })
}

/// The machine `name` of a library (the only one when `name` is not given), with a spindle.
pub fn machine(library: &Path, name: Option<&str>, registry: &Registry) -> Result<MachineRef, CribError> {
    let shown = library.display();
    let c = engine::compile_file(library, registry)
        .map_err(|e| CribError::Machine(format!("the machine file {shown} does not check:\n{}", e.render(false))))?;
    if !c.recipe.library {
        return Err(CribError::Machine(format!(
            "{shown} is a recipe; the survey takes the machine from a library (a file of entity sections, `machines:` and the materials, no steps) that its recipe can `use`"
        )));
    }
    let names: Vec<&String> = c.recipe.machines.keys().collect();
    let chosen = match (name, names.as_slice()) {
        (Some(n), _) if c.recipe.machines.contains_key(n) => n.to_string(),
        (Some(n), _) => {
            return Err(CribError::Machine(format!(
                "{shown} defines no machine `{n}` (it defines {})",
                if names.is_empty() {
                    "none".to_string()
                } else {
                    names.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ")
                }
            )));
        }
        (None, [one]) => one.to_string(),
        (None, []) => return Err(CribError::Machine(format!("{shown} defines no machine"))),
        (None, many) => {
            return Err(CribError::Machine(format!(
                "{shown} defines {} machines ({}): name one with --machine-name",
                many.len(),
                many.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ")
            )));
        }
    };
    let m = &c.recipe.machines[&chosen];
    let both = m
        .spindle
        .as_ref()
        .is_some_and(|s| ["x", "y"].iter().all(|d| s.modes.iter().any(|(m, list)| m == d && !list.is_empty())));
    if !both {
        return Err(CribError::Machine(format!(
            "machine `{chosen}` of {shown} has no spindle modes in x and y: the survey couples its tools to them"
        )));
    }
    Ok(MachineRef {
        library: library.to_path_buf(),
        name: chosen,
        materials: c.recipe.materials.keys().cloned().collect(),
    })
}

/// A survey's recipe as a raw tree, with the combination behind each assembly.
pub struct Survey {
    pub recipe: Raw,
    /// Assembly name → the combination it models.
    pub assemblies: Vec<(String, Combination)>,
    /// Per tool with combinations: the tool's index and its `stability.best` step.
    pub best_steps: Vec<(usize, String)>,
}

/// A length in millimetres as a recipe writes it, to 15 significant digits (`21 mm`).
pub fn mm(v: f64) -> String {
    format!("{} mm", short(v * 1e3))
}

fn short(x: f64) -> String {
    let r: f64 = format!("{x:.14e}").parse().unwrap_or(x);
    format!("{r}")
}

/// The assembly name of a combination: `hsk63_shrink_em12_35mm` (`22p5mm` for 22.5 mm).
pub fn assembly_name(c: &Catalog, k: &Combination) -> String {
    format!("{}_{}_{}mm", c.holders[k.holder].id, c.tools[k.tool].id, short(k.stickout * 1e3).replace('.', "p"))
}

/// One section of an assembly as the recipe writes it.
struct SectionOut<'a> {
    name: &'a str,
    component: &'a str,
    fluted: Option<f64>,
    d_out: f64,
    d_out_tip: Option<f64>,
    d_in: f64,
    length: f64,
    outer: &'a str,
    inner: Option<&'a str>,
}

impl SectionOut<'_> {
    fn raw(&self) -> Raw {
        let mut e = vec![("name", Raw::text(self.name)), ("component", Raw::text(self.component))];
        if self.fluted.is_some() {
            e.push(("kind", Raw::text("fluted")));
        }
        e.push(("d_out", Raw::text(mm(self.d_out))));
        if let Some(t) = self.d_out_tip.filter(|t| (t - self.d_out).abs() > 1e-12) {
            e.push(("d_out_tip", Raw::text(mm(t))));
        }
        if self.d_in > 0.0 {
            e.push(("d_in", Raw::text(mm(self.d_in))));
        }
        e.push(("length", Raw::text(mm(self.length))));
        e.push(("outer", Raw::text(self.outer)));
        if let Some(i) = self.inner {
            e.push(("inner", Raw::text(i)));
        }
        if let Some(d) = self.fluted {
            e.push(("d_equivalent", Raw::text(mm(d))));
        }
        Raw::mapping(e)
    }
}

/// The sections of one combination from the spindle face to the tool tip: the holder's body,
/// its nose (empty bore, then the clamped shank), the free shank and the flutes.
pub fn sections(c: &Catalog, k: &Combination) -> Vec<Raw> {
    let (h, t) = (&c.holders[k.holder], &c.tools[k.tool]);
    let bore = h.bore_for(t.shank).unwrap_or(&h.bores[0]);
    let mut out: Vec<Raw> = h
        .sections
        .iter()
        .map(|b| {
            SectionOut {
                name: &b.name,
                component: "holder",
                fluted: None,
                d_out: b.d_out,
                d_out_tip: b.d_out_tip,
                d_in: b.d_in,
                length: b.length,
                outer: &h.material,
                inner: None,
            }
            .raw()
        })
        .collect();
    // The nose tapers linearly from its body end to its face; the shank fills its last part.
    let nose = h.nose_length();
    let clamped = bore.clamp_length.min(t.overall_length - k.stickout).min(nose);
    let empty = nose - clamped;
    let d_at = |x: f64| bore.d_out + (bore.d_out_tip - bore.d_out) * x / nose;
    if empty > 1e-9 {
        out.push(
            SectionOut {
                name: "nose",
                component: "holder",
                fluted: None,
                d_out: bore.d_out,
                d_out_tip: Some(d_at(empty)),
                d_in: t.shank,
                length: empty,
                outer: &h.material,
                inner: None,
            }
            .raw(),
        );
    }
    out.push(
        SectionOut {
            name: "clamp",
            component: "holder+tool",
            fluted: None,
            d_out: d_at(empty),
            d_out_tip: Some(bore.d_out_tip),
            d_in: t.shank,
            length: clamped,
            outer: &h.material,
            inner: Some(&t.material),
        }
        .raw(),
    );
    let flutes = t.flute_length.min(k.stickout);
    if k.stickout - flutes > 1e-9 {
        out.push(
            SectionOut {
                name: "shank",
                component: "tool",
                fluted: None,
                d_out: t.shank,
                d_out_tip: None,
                d_in: 0.0,
                length: k.stickout - flutes,
                outer: &t.material,
                inner: None,
            }
            .raw(),
        );
    }
    out.push(
        SectionOut {
            name: "flutes",
            component: "tool",
            fluted: Some(t.d_equivalent),
            d_out: t.diameter,
            d_out_tip: None,
            d_in: 0.0,
            length: flutes,
            outer: &t.material,
            inner: None,
        }
        .raw(),
    );
    out
}

/// `to` as a path from the folder `from`: relative when both are under one root, else absolute.
pub fn relative(to: &Path, from: &Path) -> String {
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let (to, from) = (crate::engine::model::normalize(&abs(to)), crate::engine::model::normalize(&abs(from)));
    let (t, f): (Vec<Component>, Vec<Component>) = (to.components().collect(), from.components().collect());
    let common = t.iter().zip(&f).take_while(|(a, b)| a == b).count();
    // Sharing only the root (or nothing): the absolute path says more than a climb to `/`.
    if common <= 1 {
        return t.iter().collect::<PathBuf>().to_string_lossy().replace('\\', "/");
    }
    let mut rel = PathBuf::new();
    for _ in common..f.len() {
        rel.push("..");
    }
    for c in &t[common..] {
        rel.push(c.as_os_str());
    }
    rel.to_string_lossy().replace('\\', "/")
}

/// Builds the survey's recipe for a recipe that will sit in `recipe_dir` (its `use:` paths are
/// relative to it): assemblies per combination, the spindle in x and y, per tool the coupling
/// in x and y swept over its assemblies, the lobes and the best cut, and a table per tool.
pub fn build(loaded: &Loaded, machine: &MachineRef, recipe_dir: &Path) -> Survey {
    let c = &loaded.catalog;
    let folder = loaded.path.parent().unwrap_or(Path::new(""));
    let combos = c.combinations();
    let mut uses: Vec<Raw> = c.uses.iter().map(|(u, _)| Raw::text(relative(&folder.join(u), recipe_dir))).collect();
    uses.push(Raw::text(relative(&machine.library, recipe_dir)));
    let assemblies: Vec<(String, Combination)> = combos.iter().map(|k| (assembly_name(c, k), k.clone())).collect();
    let assembly_tree = Raw::mapping(
        assemblies.iter().map(|(n, k)| (n.clone(), Raw::mapping(vec![("sections", Raw::list(sections(c, k)))]))),
    );
    let mut cutting = Vec::new();
    let m = &machine.name;
    let spindle = |dir: &str| {
        Raw::mapping(vec![
            ("kind", Raw::text("spindle.receptance")),
            (
                "params",
                Raw::mapping(vec![
                    ("machine", Raw::text(m.as_str())),
                    ("direction", Raw::text(dir)),
                    ("max_frequency", Raw::text(c.analysis.max_frequency.as_str())),
                    ("resolution", Raw::text(c.analysis.resolution.as_str())),
                ]),
            ),
        ])
    };
    let mut steps = vec![("spindle_x".to_string(), spindle("x")), ("spindle_y".to_string(), spindle("y"))];
    let mut outputs = Vec::new();
    let mut best_steps = Vec::new();
    for (ti, tool) in c.tools.iter().enumerate() {
        let names: Vec<Raw> =
            assemblies.iter().filter(|(_, k)| k.tool == ti).map(|(n, _)| Raw::text(n.as_str())).collect();
        if names.is_empty() {
            continue;
        }
        let id = &tool.id;
        cutting.push((
            id.clone(),
            Raw::mapping(vec![
                ("teeth", Raw::int(tool.teeth)),
                ("radial_immersion", Raw::text(c.cutting.radial_immersion.as_str())),
                ("milling", Raw::text(c.cutting.milling.as_str())),
                ("Ks", Raw::text(c.cutting.ks.as_str())),
                ("beta", Raw::text(c.cutting.beta.as_str())),
            ]),
        ));
        for dir in ["x", "y"] {
            steps.push((
                format!("tip_{dir}_{id}"),
                Raw::mapping(vec![
                    ("kind", Raw::text("rcsa.couple")),
                    (
                        "params",
                        Raw::mapping(vec![
                            ("interface", Raw::text("machine")),
                            ("machine", Raw::text(m.as_str())),
                            ("max_element", Raw::text(c.analysis.max_element.as_str())),
                        ]),
                    ),
                    ("sweep", Raw::mapping(vec![("assembly", Raw::list(names.clone()))])),
                    ("inputs", Raw::mapping(vec![("spindle", Raw::text(format!("@spindle_{dir}.receptance")))])),
                ]),
            ));
        }
        steps.push((
            format!("lobes_{id}"),
            Raw::mapping(vec![
                ("kind", Raw::text("stability.lobes")),
                (
                    "params",
                    Raw::mapping(vec![
                        ("cutting", Raw::text(id.as_str())),
                        ("speeds", Raw::text(c.cutting.speeds.as_str())),
                    ]),
                ),
                (
                    "inputs",
                    Raw::mapping(vec![
                        ("frf_x", Raw::text(format!("@tip_x_{id}.frf"))),
                        ("frf_y", Raw::text(format!("@tip_y_{id}.frf"))),
                    ]),
                ),
            ]),
        ));
        let best = format!("best_{id}");
        steps.push((
            best.clone(),
            Raw::mapping(vec![
                ("kind", Raw::text("stability.best")),
                ("inputs", Raw::mapping(vec![("lobes", Raw::text(format!("@lobes_{id}.lobes")))])),
            ]),
        ));
        outputs.push(Raw::mapping(vec![
            ("from", Raw::text(format!("@{best}.best"))),
            ("file", Raw::text(format!("best-cuts-{id}.csv"))),
        ]));
        best_steps.push((ti, best));
    }
    let description = if c.description.is_empty() {
        format!("Every holder × tool × stickout of the catalog {} on machine {m}.", loaded.path.display())
    } else {
        c.description.clone()
    };
    let recipe = Raw::mapping(vec![
        ("spindlelab", Raw::int(1)),
        ("name", Raw::text(c.name.as_str())),
        ("description", Raw::text(description)),
        ("use", Raw::list(uses)),
        ("assemblies", assembly_tree),
        ("cutting", Raw::mapping(cutting)),
        ("steps", Raw::mapping(steps)),
        ("outputs", Raw::list(outputs)),
    ]);
    Survey { recipe, assemblies, best_steps }
}

/// The survey's recipe as YAML text, headed by a comment that says where it came from.
pub fn emit(loaded: &Loaded, machine: &MachineRef, survey: &Survey) -> String {
    let head = format!(
        "Generated by `spindlelab crib` from {} on machine `{}` of {}: {} combinations.",
        loaded.path.display(),
        machine.name,
        machine.library.display(),
        survey.assemblies.len()
    );
    let mut notes = Notes::default();
    notes.before(&[], head);
    emit_noted(&survey.recipe, &notes)
}

/// Compiles recipe text as if it were the file `path` (its `use:` paths relative to that
/// folder), through the project's own reader and compiler.
pub fn compile_text(text: &str, path: &Path, registry: &Registry) -> Result<Compiled, CompileError> {
    let file = SourceFile { path: Arc::from(path.display().to_string()), text: Arc::from(text) };
    let mut diags = Diagnostics::new();
    let Some(raw) = syntax::load_yaml(&file, &mut diags) else {
        diags.sort();
        return Err(CompileError { diagnostics: diags, sources: vec![file] });
    };
    engine::compile_raw(path, raw, &[], vec![file], registry, diags)
}

/// A combination and its best cut: depth (m), speed (rpm), chatter frequency (Hz) and the
/// depth stable at every speed (m).
pub type BestRow = (Combination, [f64; 4]);

/// The best cut of each combination as one table: holder, interface, clamping, tool, its
/// diameter and teeth, stickout, then the deepest stable depth, its speed and chatter
/// frequency, the depth stable at every speed, and the depth a user can take there (at most
/// the flute length) with what limits it.
pub fn summary_table(c: &Catalog, rows: &[BestRow]) -> Table {
    let text = |f: &dyn Fn(&Combination) -> String| rows.iter().map(|(k, _)| f(k)).collect::<Vec<String>>();
    let num = |f: &dyn Fn(&BestRow) -> f64| rows.iter().map(f).collect::<Vec<f64>>();
    Table {
        columns: vec![
            Column::text("holder", &text(&|k| c.holders[k.holder].id.clone())),
            Column::text("interface", &text(&|k| c.holders[k.holder].interface.clone())),
            Column::text("clamping", &text(&|k| c.holders[k.holder].clamping.word().to_string())),
            Column::text("tool", &text(&|k| c.tools[k.tool].id.clone())),
            Column::new("diameter", "mm", num(&|(k, _)| c.tools[k.tool].diameter * 1e3)),
            Column::new("teeth", "", num(&|(k, _)| c.tools[k.tool].teeth as f64)),
            Column::new("stickout", "mm", num(&|(k, _)| k.stickout * 1e3)),
            Column::new("depth", "mm", num(&|(_, b)| b[0] * 1e3)),
            Column::new("speed", "rpm", num(&|(_, b)| b[1])),
            Column::new("chatter_frequency", "Hz", num(&|(_, b)| b[2])),
            Column::new("stable_everywhere", "mm", num(&|(_, b)| b[3] * 1e3)),
            // A lobe's peak can stand far above what the tool can cut: the axial depth a
            // user can take is at most the flute length.
            Column::new("usable_depth", "mm", num(&|(k, b)| b[0].min(c.tools[k.tool].flute_length) * 1e3)),
            Column::text(
                "limited_by",
                &rows
                    .iter()
                    .map(|(k, b)| {
                        if b[0] > c.tools[k.tool].flute_length { "flute length" } else { "chatter" }.to_string()
                    })
                    .collect::<Vec<String>>(),
            ),
        ],
    }
}

/// The summary table as CSV, written by the engine's own table writer.
pub fn summary_csv(table: &Table) -> String {
    let value = Value::Table(table.clone());
    exec::write::render(crate::engine::model::OutputFormat::Csv, &[exec::write::Row { label: "", value: &value }])
}

/// The best cut of every combination from a result: the rows in catalog order.
fn best_rows(compiled: &Compiled, survey: &Survey, outcomes: &[Outcome]) -> Result<Vec<BestRow>, String> {
    let mut rows = Vec::with_capacity(survey.assemblies.len());
    for (_, step) in &survey.best_steps {
        let Some(ids) = compiled.graph.by_step.get(step) else { continue };
        for &i in ids {
            let inst = &compiled.graph.instances[i];
            let assembly = inst.assignments.iter().find_map(|(n, v)| match v {
                crate::engine::spec::ParamValue::Entity { name, .. } if n == "assembly" => Some(name.clone()),
                crate::engine::spec::ParamValue::Text(t) if n == "assembly" => Some(t.clone()),
                _ => None,
            });
            let combo = assembly
                .and_then(|a| survey.assemblies.iter().find(|(n, _)| *n == a))
                .map(|(_, k)| k.clone())
                .ok_or_else(|| format!("instance `{}` names no assembly of the survey", inst.id))?;
            let outputs = match &outcomes[i] {
                Outcome::Computed { outputs, .. } | Outcome::Cached { outputs, .. } => outputs,
                _ => return Err(format!("instance `{}` has no result", inst.id)),
            };
            let Some(Value::Table(t)) = outputs.get("best").map(|v| v.as_ref()) else {
                return Err(format!("instance `{}` gave no table", inst.id));
            };
            let col = |name: &str| t.columns.iter().find(|c| c.name == name).and_then(|c| c.values.first().copied());
            let b = [
                col("depth").unwrap_or(f64::NAN),
                col("speed").unwrap_or(f64::NAN),
                col("chatter_frequency").unwrap_or(f64::NAN),
                col("stable_everywhere").unwrap_or(f64::NAN),
            ];
            rows.push((combo, b));
        }
    }
    // Catalog order: holder, tool, stickout.
    rows.sort_by(|(a, _), (b, _)| (a.holder, a.tool).cmp(&(b.holder, b.tool)).then(a.stickout.total_cmp(&b.stickout)));
    Ok(rows)
}

/// Runs a compiled survey: computes every best cut, then commits the per-tool tables and
/// the combined [`SUMMARY_FILE`] as one run (the second pass takes every result from the
/// first, in memory).
pub fn run(
    compiled: &Compiled,
    loaded: &Loaded,
    survey: &Survey,
    registry: &Registry,
    opts: RunOptions,
    progress: &(dyn Fn(usize, &str) + Sync),
) -> Result<Ran, CribError> {
    // As `run` does: a busy folder, or a file of the user's where an output goes, is refused
    // before anything is computed (the lock is taken again by the committing run).
    {
        let dir = exec::OutputDir::open(&opts.out_dir).map_err(|e| CribError::Run(RunError::Output(e)))?;
        let files: Vec<String> = compiled
            .recipe
            .outputs
            .iter()
            .flat_map(|o| compiled.graph.output_files(o).unwrap_or_default().into_iter().map(|(f, _)| f))
            .collect();
        let names = files.iter().map(String::as_str).chain([SUMMARY_FILE, exec::manifest::MANIFEST_FILE]);
        dir.check_outputs(names).map_err(|e| CribError::Run(RunError::Output(e)))?;
    }
    let targets: Vec<String> = survey.best_steps.iter().map(|(_, s)| s.clone()).collect();
    let first = RunOptions {
        targets: Some(targets),
        extra_files: Vec::new(),
        report: false,
        release_consumed: false,
        ..opts.clone_settings()
    };
    let result = exec::execute(&compiled.recipe, &compiled.graph, registry, &first, progress);
    let failures: Vec<(String, String)> =
        result.failures(&compiled.graph).map(|(id, e)| (id.to_string(), e.to_string())).collect();
    let memo = Arc::new(result.memo(&compiled.graph));
    let mut last = opts;
    last.memo = Some(memo);
    if let Some((id, e)) = failures.first() {
        // The committing run reports the failures as `run` does, and keeps what succeeded.
        return match engine::run(compiled, registry, &last, &|_, _| {}) {
            Err(e) => Err(CribError::Run(e)),
            Ok(_) => Err(CribError::Survey(format!("node `{id}` failed: {e}"))),
        };
    }
    let rows = best_rows(compiled, survey, &result.outcomes).map_err(CribError::Survey)?;
    let table = summary_table(&loaded.catalog, &rows);
    last.extra_files.push((SUMMARY_FILE.to_string(), summary_csv(&table)));
    let report = engine::run(compiled, registry, &last, &|_, _| {}).map_err(CribError::Run)?;
    let computed = result.outcomes.iter().filter(|o| matches!(o, Outcome::Computed { .. })).count();
    let seconds = result.seconds + report.result.seconds;
    Ok(Ran { report, table, computed, seconds })
}

/// What a survey run did: the committing run's report, the summary table, and what the
/// first pass computed (the committing run takes it from memory).
pub struct Ran {
    pub report: RunReport,
    pub table: Table,
    /// Node instances computed (the others came from the cache).
    pub computed: usize,
    /// Wall time of both passes, seconds.
    pub seconds: f64,
}

/// The settings of run options without what belongs to one run (its memo, targets, extra files).
trait CloneSettings {
    fn clone_settings(&self) -> RunOptions;
}

impl CloneSettings for RunOptions {
    fn clone_settings(&self) -> RunOptions {
        RunOptions {
            use_cache: self.use_cache,
            keep_going: self.keep_going,
            threads: self.threads,
            release_consumed: self.release_consumed,
            renderer: self.renderer.clone(),
            cache_dir: self.cache_dir.clone(),
            ..RunOptions::new(self.out_dir.clone())
        }
    }
}
