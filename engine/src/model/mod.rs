//! Model: the resolved, typed recipe, built from the raw tree with every problem reported.
//!
//! Second recipe stage: units are SI, names resolve to entities, steps name registered
//! node kinds with checked parameters, and inputs name existing step outputs.

mod entities;
mod fit;
mod measurements;
mod params;
mod plugins;
mod resolve;
mod reuse;

pub use crate::spec::normalize;
pub use crate::spec::within;
pub use entities::{
    Assembly, Component, Cutting, Entities, Joint, Machine, Material, Section, Sensor, Spindle, SpindleMode,
    fields as entity_fields,
};
pub use fit::{FitMethod, FitScale, FitSpec, FreeParam};
pub use params::{ParamQuantity, Parameter, command_line_span};
pub use plugins::{PluginRef, plugin_refs};
pub use resolve::{resolve, resolve_within};
pub(crate) use reuse::source_folder;
pub use reuse::{Expanded, INPUTS, RECIPE_KIND, expand, expand_within, is_library, library_search_path};

use crate::diag::Span;
use crate::spec::{EntityKind, ParamValue, Params};
use indexmap::IndexMap;

/// The most steps a recipe may have once the recipes it runs as steps are inlined: as many as
/// the node instances it may expand to (each step is at least one), checked before inlining.
pub const MAX_STEPS: usize = 50_000;

/// The recipe format version this engine reads.
pub const FORMAT_VERSION: i64 = 1;

/// A resolved recipe: entities, steps and outputs, all checked.
#[derive(Debug, Clone, Default)]
pub struct Recipe {
    pub name: String,
    pub description: Option<String>,
    /// Hash of the recipe's meaning (not its layout or comments): blake3 of the canonical raw tree.
    pub hash: String,
    /// Digest of each entity's contents (see [`Recipe::entity_digest`]).
    pub entity_digests: IndexMap<(EntityKind, String), String>,
    /// Where each entity is defined (the recipe, or a file it uses) and the entities it names,
    /// so a plan can say in which file a changed entity changed.
    pub entity_origins: IndexMap<(EntityKind, String), EntityOrigin>,
    /// The file holds entities only (a library checked on its own): nothing to run.
    pub library: bool,
    pub materials: IndexMap<String, Material>,
    pub machines: IndexMap<String, Machine>,
    pub assemblies: IndexMap<String, Assembly>,
    pub sensors: IndexMap<String, Sensor>,
    pub cutting: IndexMap<String, Cutting>,
    /// Recipe-wide spindle speeds (rad/s), when given.
    pub speeds: Vec<f64>,
    pub steps: Vec<Step>,
    pub outputs: Vec<Output>,
    /// Declared parameters (`params:`) with the values in force.
    pub params: IndexMap<String, Parameter>,
    /// The `fit:` block, when the recipe has one.
    pub fit: Option<FitSpec>,
}

/// Where an entity is defined and which entities it names.
#[derive(Debug, Clone, Default)]
pub struct EntityOrigin {
    /// The file, as shown in messages.
    pub file: String,
    pub names: Vec<(EntityKind, String)>,
}

/// A data file a recipe reads: where it was named and what was read.
#[derive(Debug, Clone)]
pub struct DataFile<'a> {
    /// The step and parameter naming it.
    pub step: &'a str,
    pub param: &'a str,
    /// Where the parameter was written.
    pub span: Option<&'a Span>,
    pub path: &'a std::path::Path,
    /// BLAKE3 of its contents when the recipe was loaded.
    pub hash: &'a str,
}

impl Recipe {
    pub fn step(&self, id: &str) -> Option<&Step> {
        self.steps.iter().find(|s| s.id == id)
    }

    /// Every data file the steps read (parameters, nested objects and sweep values), in
    /// recipe order.
    pub fn data_files(&self) -> Vec<DataFile<'_>> {
        fn walk<'a>(step: &'a Step, param: &'a str, v: &'a ParamValue, out: &mut Vec<DataFile<'a>>) {
            match v {
                ParamValue::File { path, hash } => {
                    out.push(DataFile { step: &step.id, param, span: step.param_spans.get(param), path, hash })
                }
                ParamValue::Object(p) => p.values.values().for_each(|v| walk(step, param, v, out)),
                ParamValue::Objects(ps) => {
                    ps.iter().flat_map(|p| p.values.values()).for_each(|v| walk(step, param, v, out))
                }
                ParamValue::Map(m) => m.values().for_each(|v| walk(step, param, v, out)),
                _ => {}
            }
        }
        let mut out = Vec::new();
        for step in &self.steps {
            for (name, v) in &step.params.values {
                walk(step, name, v, &mut out);
            }
            for axis in &step.sweep {
                axis.values.iter().for_each(|v| walk(step, &axis.param, v, &mut out));
            }
        }
        out
    }

    /// The digest of an entity's contents (and of the entities it names): cache keys carry
    /// it beside the entity's name, so editing a material reruns the steps that use it.
    pub fn entity_digest(&self, kind: EntityKind, name: &str) -> Option<String> {
        self.entity_digests.get(&(kind, name.to_string())).cloned()
    }

    /// The entities `params` name (in objects and lists too), typed: what the node of a step
    /// with these parameters sees of the recipe.
    pub fn entities_named_by(&self, params: &Params) -> Entities {
        let mut out = Entities::default();
        self.collect_entities(params, &mut out);
        out
    }

    fn collect_entities(&self, params: &Params, out: &mut Entities) {
        for v in params.values.values() {
            match v {
                ParamValue::Entity { kind, name } => {
                    let n = name.clone();
                    match kind {
                        EntityKind::Material => {
                            self.materials.get(name).map(|e| out.materials.insert(n, *e));
                        }
                        EntityKind::Machine => {
                            self.machines.get(name).map(|e| out.machines.insert(n, e.clone()));
                        }
                        EntityKind::Assembly => {
                            self.assemblies.get(name).map(|e| out.assemblies.insert(n, e.clone()));
                        }
                        EntityKind::Sensor => {
                            self.sensors.get(name).map(|e| out.sensors.insert(n, e.clone()));
                        }
                        EntityKind::Cutting => {
                            self.cutting.get(name).map(|e| out.cutting.insert(n, e.clone()));
                        }
                    }
                }
                ParamValue::Object(p) => self.collect_entities(p, out),
                ParamValue::Objects(list) => list.iter().for_each(|p| self.collect_entities(p, out)),
                _ => {}
            }
        }
    }

    /// `materials.steel`: how the manifest names an entity.
    pub fn entity_label(kind: EntityKind, name: &str) -> String {
        format!("{}.{name}", kind.section())
    }

    /// The entity and every entity it names, directly or through others.
    pub fn entity_closure(&self, kind: EntityKind, name: &str) -> Vec<(EntityKind, String)> {
        let mut out: Vec<(EntityKind, String)> = vec![(kind, name.to_string())];
        let mut i = 0;
        while i < out.len() {
            if let Some(o) = self.entity_origins.get(&out[i]) {
                for n in &o.names {
                    if !out.contains(n) {
                        out.push(n.clone());
                    }
                }
            }
            i += 1;
        }
        out
    }
}

/// `step.port`: an output of a step.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct PortRef {
    pub step: String,
    pub port: String,
}

impl PortRef {
    /// Parses `@step.port` (the `@` may be left out where only a reference makes sense).
    pub fn parse(text: &str) -> Option<PortRef> {
        let t = text.trim().strip_prefix('@').unwrap_or(text.trim());
        let (step, port) = t.rsplit_once('.')?;
        (valid_step_name(step) && valid_name(port)).then(|| PortRef { step: step.to_string(), port: port.to_string() })
    }
}

/// A name of an entity, step or port: a letter or `_`, then letters, digits, `_` and `-`.
pub(crate) fn valid_name(s: &str) -> bool {
    let mut chars = s.chars();
    matches!(chars.next(), Some(c) if c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

/// A step name: a name, or names joined by `/` for the steps of a recipe run as a step
/// (`tap/segment`); a file's own step names cannot hold `/` (see `reuse`).
pub(crate) fn valid_step_name(s: &str) -> bool {
    s.split('/').all(valid_name)
}

impl std::fmt::Display for PortRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "@{}.{}", self.step, self.port)
    }
}

/// An input port bound to an upstream output.
#[derive(Debug, Clone)]
pub struct Binding {
    pub port: String,
    pub from: PortRef,
    pub span: Span,
}

/// One parameter a step fans out over, with the values in SI.
#[derive(Debug, Clone)]
pub struct SweepAxis {
    pub param: String,
    pub values: Vec<ParamValue>,
    /// The unit the recipe wrote the values in and its factor to SI (`rpm`, 2π/60), so labels
    /// and file columns show them as written; `None` for text and plain numbers.
    pub unit: Option<(String, f64)>,
}

impl SweepAxis {
    /// A value of the axis as the recipe wrote it (`1500 rpm`, `2 mm`, `x`).
    pub fn show(&self, v: &ParamValue) -> String {
        match (v, &self.unit) {
            (ParamValue::Quantity { value, .. }, Some((unit, scale))) => {
                format!("{} {unit}", spindlelab_domain::sig(value / scale, 6))
            }
            _ => v.display(),
        }
    }
}

/// The unit a sweep's text ends in (`0..4000 step 500 rpm`, `[1, 4] mm`, `1000 rpm`), when it
/// measures `dim`: its symbol and factor to SI.
pub(crate) fn written_unit(text: &str, dim: spindlelab_grammar::Dimension) -> Option<(String, f64)> {
    let text = text.trim();
    let end = text.rfind(|c: char| c.is_ascii_digit() || c == ']' || c == '.')?;
    let symbol = text[end + 1..].trim();
    if symbol.is_empty() {
        return None;
    }
    let unit = spindlelab_grammar::parse_unit(symbol).ok()?;
    (unit.dim == dim && unit.scale.is_finite() && unit.scale > 0.0).then(|| (symbol.to_string(), unit.scale))
}

/// An analysis step: a node kind with parameters, inputs and optional sweeps.
#[derive(Debug, Clone)]
pub struct Step {
    pub id: String,
    pub kind: String,
    pub span: Span,
    pub params: Params,
    pub inputs: Vec<Binding>,
    /// Sweep axes; several axes form their product.
    pub sweep: Vec<SweepAxis>,
    /// Where each parameter (or sweep axis) was written, for messages about its value.
    pub param_spans: IndexMap<String, Span>,
    /// What its values are called in a plot's legend (`measured`, `model`); the step's id when
    /// not given.
    pub label: Option<String>,
}

/// The file format of an output, from its extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputFormat {
    Csv,
    Json,
    /// Universal File Format dataset 58 (ASCII): FRFs and time series only.
    Uff,
    /// A plot of the value (`crate::plot`), as SVG or PNG.
    Plot(crate::plot::PlotFormat),
}

/// A step output written to a file in the output directory.
#[derive(Debug, Clone)]
pub struct Output {
    pub from: PortRef,
    /// File name relative to the output directory.
    pub file: String,
    pub format: OutputFormat,
    /// A plot's other values, drawn over `from` (the stationary lobes and the trials over the
    /// speed-dependent lobes, a measured FRF over a fitted one).
    pub with: Vec<PortRef>,
    /// The legend name of each `with` value (`{ from: …, label: … }`), where one is given.
    pub with_labels: Vec<Option<String>>,
    /// A plot's view when its type has several (`real-imag` for an FRF).
    pub plot: Option<String>,
    /// A plot's name for `from` in its legend and title, over the step's own `label`.
    pub label: Option<String>,
    /// The unit a scalar output is written in, as the recipe wrote it (`deg/kHz`); SI without.
    pub unit: Option<String>,
    pub span: Span,
}

impl Output {
    /// The steps whose values the file holds.
    pub fn steps(&self) -> impl Iterator<Item = &str> {
        std::iter::once(self.from.step.as_str()).chain(self.with.iter().map(|r| r.step.as_str()))
    }

    /// The sweep coordinates the file name splits the output by, one file per value:
    /// `model-vs-measured-{file}.svg` gives `["file"]`; empty for one file.
    pub fn split_by(&self) -> Vec<&str> {
        let mut out = Vec::new();
        let mut rest = self.file.as_str();
        while let Some(open) = rest.find('{') {
            let Some(close) = rest[open..].find('}') else { break };
            out.push(&rest[open + 1..open + close]);
            rest = &rest[open + close + 1..];
        }
        out
    }
}

/// Reports a node's rejection of a step's parameter values at the parameter's place.
/// `at` names the sweep point (empty for an unswept step).
pub(crate) fn report_invalid(
    diags: &mut crate::diag::Diagnostics,
    step: (&str, &str, &Span),
    at: &str,
    error: &crate::node::NodeError,
    spec: &crate::node::NodeSpec,
    param_spans: &IndexMap<String, Span>,
) {
    let (id, kind, step_span) = step;
    let which = if at.is_empty() { String::new() } else { format!(" at {at}") };
    let (span, help) = match error {
        crate::node::NodeError::InvalidParam { param, .. } => (
            param_spans.get(param).unwrap_or(step_span),
            spec.param(param).map(|f| format!("`{param}`: {} — {}", f.ty.describe(), f.doc)),
        ),
        _ => (step_span, None),
    };
    diags.error_help(
        Some(span),
        format!("step `{id}` ({kind}){which}: {error}"),
        help.unwrap_or_else(|| "check the step's parameters".into()),
    );
}

/// A recipe name as a folder name: letters, digits, `-`, `_` and inner dots kept, anything
/// else (a `/`, a space) made `-`, leading dots and dashes dropped, so the default output folder
/// `out/<slug>` can never lead out of `out/`.
pub fn slug(name: &str) -> String {
    let s: String =
        name.chars().map(|c| if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') { c } else { '-' }).collect();
    let s = s.trim_start_matches(['.', '-']).trim_end_matches('.');
    if s.is_empty() { "recipe".to_string() } else { s.chars().take(100).collect() }
}

#[cfg(test)]
mod slug_tests {
    #[test]
    fn a_name_becomes_a_plain_folder_name() {
        use super::slug;
        assert_eq!(slug("impact-study"), "impact-study");
        assert_eq!(slug(".."), "recipe");
        assert_eq!(slug("../../x"), "x");
        assert_eq!(slug("/elsewhere/x"), "elsewhere-x");
        assert_eq!(slug("my run 2"), "my-run-2");
        assert_eq!(slug("a..b"), "a..b");
    }
}
