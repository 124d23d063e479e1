//! Graph: the resolved recipe compiled to node instances in dependency order.
//!
//! A swept step becomes one instance per sweep value; a step fed by a swept step runs once
//! per upstream value (fan-out), unless its port collects, in which case it receives the
//! whole collection. Every instance carries its content-addressed cache key, computed from
//! kind, version, parameters and the keys of its inputs, so a plan needs no execution.

mod render;

pub use render::{to_dot, to_mermaid};

use crate::diag::Diagnostics;
use crate::model::{Entities, Recipe, Step};
use crate::node::Registry;
use crate::spec::{ParamValue, Params};
use indexmap::IndexMap;
use std::sync::Arc;

/// One run of a node: a step, or one point of a swept step.
#[derive(Debug, Clone)]
pub struct Instance {
    /// Unique name: the step id, plus the sweep label in brackets when swept.
    pub id: String,
    pub step: String,
    pub kind: String,
    pub version: u32,
    /// Sweep assignments that made this instance, e.g. `hammer_mass=0.03 kg`.
    pub label: String,
    /// The sweep assignments behind the label (upstream ones first), in SI.
    pub assignments: Vec<(String, ParamValue)>,
    pub params: Params,
    /// Per input port: the producing instances and their output port.
    pub inputs: IndexMap<String, Vec<(usize, String)>>,
    /// Content-addressed cache key (hex).
    pub key: String,
    /// Digest of each parameter, so a plan can say which one changed.
    pub param_digests: IndexMap<String, String>,
    /// The entities the parameters name, resolved: all the node sees of the recipe.
    pub entities: Arc<Entities>,
}

impl Instance {
    /// Instances this one waits for.
    pub fn deps(&self) -> impl Iterator<Item = usize> + '_ {
        self.inputs.values().flatten().map(|(i, _)| *i)
    }
}

/// The most node instances a recipe may expand to (sweeps and their products); each costs a
/// few kilobytes before it runs, and far fewer suffice for any study we know of.
pub const MAX_INSTANCES: usize = crate::model::MAX_STEPS;

/// The compiled graph: instances in a topological order.
#[derive(Debug, Clone)]
pub struct Graph {
    pub instances: Vec<Instance>,
    /// Instances of each step, in sweep order.
    pub by_step: IndexMap<String, Vec<usize>>,
}

/// The sweep coordinates of an instance label (`file=frf_x.csv, speed=6000 rpm`), as written.
pub fn coordinates(label: &str) -> Vec<(&str, &str)> {
    label.split(", ").filter_map(|part| part.split_once('=')).map(|(n, v)| (n.trim(), v.trim())).collect()
}

/// A coordinate's value as part of a file name: a data file by its stem, a quantity without
/// its space (`6000rpm`), and anything a file name should not hold as `_`.
fn file_part(axis: &str, value: &str) -> String {
    let value = if axis == "file" {
        std::path::Path::new(value).file_stem().and_then(|s| s.to_str()).unwrap_or(value)
    } else {
        value
    };
    value
        .chars()
        .filter(|c| !c.is_whitespace())
        .map(|c| if c.is_alphanumeric() || matches!(c, '.' | '-' | '_') { c } else { '_' })
        .collect()
}

impl Graph {
    /// The files an output writes, each with the instances of its `from` step it holds: one
    /// file for an output named plainly, one per value of the coordinates its name splits by
    /// (`model-vs-measured-{file}.svg`), in sweep order. An error names a coordinate that
    /// is not a sweep of the step.
    pub fn output_files(&self, out: &crate::model::Output) -> Result<Vec<(String, Vec<usize>)>, String> {
        let ids = self.by_step.get(&out.from.step).cloned().unwrap_or_default();
        let axes = out.split_by();
        if axes.is_empty() {
            return Ok(vec![(out.file.clone(), ids)]);
        }
        let mut files: IndexMap<String, Vec<usize>> = IndexMap::new();
        for &i in &ids {
            let coords = coordinates(&self.instances[i].label);
            let mut name = out.file.clone();
            for axis in &axes {
                let Some((_, v)) = coords.iter().find(|(n, _)| n == axis) else {
                    let sweeps: Vec<&str> = coords.iter().map(|(n, _)| *n).collect();
                    return Err(if sweeps.is_empty() {
                        format!(
                            "`{{{axis}}}` in `{}` names a sweep, and step `{}` is not swept",
                            out.file, out.from.step
                        )
                    } else {
                        format!(
                            "`{{{axis}}}` in `{}` names no sweep of step `{}`; its sweeps: {}",
                            out.file,
                            out.from.step,
                            sweeps.join(", ")
                        )
                    });
                };
                name = name.replacen(&format!("{{{axis}}}"), &file_part(axis, v), 1);
            }
            files.entry(name).or_default().push(i);
        }
        Ok(files.into_iter().collect())
    }
}

fn digest(text: &str) -> String {
    blake3::hash(text.as_bytes()).to_hex()[..16].to_string()
}

/// Steps in dependency order, ties broken by recipe order so the result is deterministic.
fn step_order(recipe: &Recipe) -> Vec<&Step> {
    let mut done: Vec<bool> = vec![false; recipe.steps.len()];
    let mut order = Vec::with_capacity(recipe.steps.len());
    while order.len() < recipe.steps.len() {
        let before = order.len();
        for (i, s) in recipe.steps.iter().enumerate() {
            if done[i] {
                continue;
            }
            let ready =
                s.inputs.iter().all(|b| recipe.steps.iter().position(|t| t.id == b.from.step).is_none_or(|j| done[j]));
            if ready {
                done[i] = true;
                order.push(s);
            }
        }
        assert!(order.len() > before, "cycle slipped past the resolver");
    }
    order
}

/// The product of sweep axes as (label, assignments) pairs.
fn sweep_points(step: &Step) -> Vec<(String, Vec<(String, ParamValue)>)> {
    let mut points: Vec<(String, Vec<(String, ParamValue)>)> = vec![(String::new(), Vec::new())];
    for axis in &step.sweep {
        let mut next = Vec::with_capacity(points.len() * axis.values.len());
        for (label, assigned) in &points {
            for v in &axis.values {
                let l = format!("{}={}", axis.param, axis.show(v));
                let label = if label.is_empty() { l } else { format!("{label}, {l}") };
                let mut a = assigned.clone();
                a.push((axis.param.clone(), v.clone()));
                next.push((label, a));
            }
        }
        points = next;
    }
    points
}

/// Compiles a resolved recipe into its instance graph.
///
/// Each instance's parameters go through the node's own checks; failures are pushed as
/// diagnostics at the step, naming the instance and the value.
pub fn compile(recipe: &Recipe, registry: &Registry, diags: &mut Diagnostics) -> Graph {
    let mut instances: Vec<Instance> = Vec::new();
    let mut by_step: IndexMap<String, Vec<usize>> = IndexMap::new();
    for step in step_order(recipe) {
        let node = registry.get(&step.kind).expect("resolved kind");
        let spec = node.spec();
        // Upstream families: producers whose instances this step maps over (zipped when their labels agree).
        let mut families: Vec<Vec<usize>> = Vec::new();
        let mut family_of_binding: Vec<Option<usize>> = Vec::new();
        for b in &step.inputs {
            let collect = spec.input(&b.port).is_some_and(|p| p.collect);
            let producers = &by_step[&b.from.step];
            if collect || producers.len() == 1 {
                family_of_binding.push(None);
                continue;
            }
            let labels: Vec<&str> = producers.iter().map(|&i| instances[i].label.as_str()).collect();
            let found =
                families.iter().position(|f| f.iter().map(|&i| instances[i].label.as_str()).eq(labels.iter().copied()));
            let idx = found.unwrap_or_else(|| {
                families.push(producers.clone());
                families.len() - 1
            });
            family_of_binding.push(Some(idx));
        }
        // The step's instance count before anything is built: a product of large sweeps is
        // refused with the size it would have had, not discovered by running out of memory.
        let upstream = families.iter().fold(1usize, |n, f| n.saturating_mul(f.len()));
        let own = step.sweep.iter().fold(1usize, |n, a| n.saturating_mul(a.values.len()));
        let would_be = instances.len().saturating_add(upstream.saturating_mul(own));
        if would_be > MAX_INSTANCES {
            let sizes: Vec<String> = families
                .iter()
                .map(|f| format!("{} upstream", f.len()))
                .chain(step.sweep.iter().map(|a| format!("{} `{}`", a.values.len(), a.param)))
                .collect();
            diags.push(
                crate::diag::Diagnostic::error(
                    Some(step.span.clone()),
                    format!(
                        "step `{}` would make the recipe {} node instances ({}), over the limit of {MAX_INSTANCES}",
                        step.id,
                        if would_be == usize::MAX { "more than 10^19".to_string() } else { would_be.to_string() },
                        sizes.join(" × ")
                    ),
                )
                .with_help("sweep fewer points (a coarser `step`), or split the study into several recipes"),
            );
            break;
        }
        // Upstream combinations (product over families), then own sweep points.
        let mut combos: Vec<Vec<usize>> = vec![Vec::new()];
        for fam in &families {
            combos = combos.iter().flat_map(|c| (0..fam.len()).map(move |k| [c.clone(), vec![k]].concat())).collect();
        }
        let points = sweep_points(step);
        let mut ids = Vec::new();
        for combo in &combos {
            let up_label: Vec<String> =
                combo.iter().enumerate().map(|(f, &k)| instances[families[f][k]].label.clone()).collect();
            let up_assigned: Vec<(String, ParamValue)> =
                combo.iter().enumerate().flat_map(|(f, &k)| instances[families[f][k]].assignments.clone()).collect();
            for (own_label, assigned) in &points {
                let mut label_parts: Vec<&str> =
                    up_label.iter().map(String::as_str).filter(|l| !l.is_empty()).collect();
                if !own_label.is_empty() {
                    label_parts.push(own_label);
                }
                let label = label_parts.join(", ");
                let mut params = step.params.clone();
                for (name, v) in assigned {
                    params.values.insert(name.clone(), v.clone());
                }
                // Declaration order, so the key does not depend on sweep placement.
                let mut ordered = Params::default();
                for f in &spec.params {
                    if let Some(v) = params.values.get(f.name) {
                        ordered.values.insert(f.name.to_string(), v.clone());
                    }
                }
                let params = ordered;
                let mut inputs: IndexMap<String, Vec<(usize, String)>> = IndexMap::new();
                for (b, fam) in step.inputs.iter().zip(&family_of_binding) {
                    let producers = &by_step[&b.from.step];
                    let chosen: Vec<usize> = match fam {
                        // Zipped families agree label by label, so the same position of this
                        // binding's own producers is the instance that matches.
                        Some(f) => vec![producers[combo[*f]]],
                        None => producers.clone(),
                    };
                    inputs.insert(b.port.clone(), chosen.into_iter().map(|i| (i, b.from.port.clone())).collect());
                }
                let param_digests: IndexMap<String, String> = params
                    .values
                    .iter()
                    .map(|(k, v)| {
                        let mut s = String::new();
                        v.canonical_with(&mut s, &|k, n| recipe.entity_digest(k, n));
                        (k.clone(), digest(&s))
                    })
                    .collect();
                let mut key_text = format!("{}@{}\n", step.kind, spec.version);
                if let Some(code) = node.code_digest() {
                    key_text.push_str(&format!("code {code}\n"));
                }
                for (k, d) in &param_digests {
                    key_text.push_str(&format!("p {k}={d}\n"));
                }
                for (port, srcs) in &inputs {
                    for (i, out) in srcs {
                        key_text.push_str(&format!("i {port}<-{}.{out}\n", instances[*i].key));
                    }
                }
                let id = if label.is_empty() { step.id.clone() } else { format!("{}[{label}]", step.id) };
                // Unswept steps were checked by the resolver already.
                let checked = if step.sweep.is_empty() { Ok(()) } else { node.validate(&params) };
                if let Err(e) = checked {
                    crate::model::report_invalid(
                        diags,
                        (&step.id, &step.kind, &step.span),
                        &label,
                        &e,
                        spec,
                        &step.param_spans,
                    );
                }
                ids.push(instances.len());
                let entities = Arc::new(recipe.entities_named_by(&params));
                instances.push(Instance {
                    id,
                    step: step.id.clone(),
                    kind: step.kind.clone(),
                    version: spec.version,
                    label,
                    assignments: up_assigned.iter().cloned().chain(assigned.iter().cloned()).collect(),
                    params,
                    inputs,
                    key: blake3::hash(key_text.as_bytes()).to_hex().to_string(),
                    param_digests,
                    entities,
                });
            }
        }
        by_step.insert(step.id.clone(), ids);
    }
    // Keep recipe order for display while instances stay topologically ordered.
    let graph = Graph { instances, by_step };
    // A file name that splits an output by sweep coordinates names sweeps of its step.
    for out in recipe.outputs.iter().filter(|o| graph.by_step.contains_key(&o.from.step)) {
        if let Err(e) = graph.output_files(out) {
            diags.error_help(
                Some(&out.span),
                e,
                "name a sweep of the step in braces (`frf-{speed}.csv`: one file per speed), or leave the braces out",
            );
        }
    }
    graph
}
