//! The run manifest (JSON beside the outputs) and the dry-run plan that reads it.
//!
//! The manifest records, per instance, the key, version, parameter digests and input keys,
//! so the next `plan` can say why an instance would run: new, new version, a changed
//! parameter or a changed input.

use super::{Cache, Outcome, RunResult};
use crate::graph::Graph;
use crate::model::Recipe;
use crate::node::Registry;
use indexmap::IndexMap;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One instance in the manifest.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ManifestNode {
    pub id: String,
    pub kind: String,
    pub version: u32,
    pub key: String,
    /// `computed`, `cached`, `failed`, `skipped` (an input failed) or `unneeded` (not
    /// cached, and every consumer came from the cache).
    pub status: String,
    pub seconds: f64,
    pub params: IndexMap<String, String>,
    pub inputs: IndexMap<String, Vec<String>>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub error: Option<String>,
    /// Warnings the node raised, such as rejected records.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub warnings: Vec<String>,
}

/// What a run did, written as `manifest.json` in the output directory.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Manifest {
    pub tool: String,
    pub recipe_name: String,
    pub recipe_hash: String,
    pub recipe_path: String,
    /// The recipe as run (the script, for a Rhai recipe), so the folder explains itself.
    #[serde(default)]
    pub recipe_text: String,
    pub seconds: f64,
    pub cache_hits: usize,
    pub computed: usize,
    pub nodes: Vec<ManifestNode>,
    pub outputs: Vec<String>,
    /// Every file of the run but this manifest, relative to the output folder, with its
    /// BLAKE3 hash (hex).
    #[serde(default)]
    pub files: IndexMap<String, String>,
    /// Every data file the recipe read, as named (resolved against the recipe's folder), with
    /// the BLAKE3 hash of what was read.
    #[serde(default, skip_serializing_if = "IndexMap::is_empty")]
    pub data_files: IndexMap<String, String>,
    /// Every file the recipe took something from besides itself (the libraries it uses, the
    /// recipes it runs as steps, the modules a Rhai recipe imports), as shown, with the BLAKE3
    /// hash of what was read.
    #[serde(default, skip_serializing_if = "IndexMap::is_empty")]
    pub recipe_files: IndexMap<String, String>,
    /// The digest of every entity (`assemblies.artifact`), so the next plan can say which
    /// entity changed, and in which file.
    #[serde(default, skip_serializing_if = "IndexMap::is_empty")]
    pub entities: IndexMap<String, String>,
    /// What the run noticed about itself (cache entries it could not use and recomputed).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// Swept outputs written with `--keep-going` without some of their sweep points: per file,
    /// the points missing and why. The files mark the same points (`# missing:` in CSV).
    #[serde(default, skip_serializing_if = "IndexMap::is_empty")]
    pub partial: IndexMap<String, Vec<MissingPoint>>,
}

/// A sweep point an output file lacks because its instance failed or did not run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MissingPoint {
    /// The sweep label as the recipe wrote it, e.g. `speed=3000 rpm`.
    pub label: String,
    /// The instance that would have made it.
    pub instance: String,
    /// `failed: …` with the node's error, or `not run: its input `…` failed`.
    pub reason: String,
}

pub const MANIFEST_FILE: &str = "manifest.json";

fn input_keys(graph: &Graph, i: usize) -> IndexMap<String, Vec<String>> {
    graph.instances[i]
        .inputs
        .iter()
        .map(|(p, srcs)| (p.clone(), srcs.iter().map(|(s, o)| format!("{}.{o}", graph.instances[*s].key)).collect()))
        .collect()
}

impl Manifest {
    pub fn build(
        recipe: &Recipe,
        recipe_path: &str,
        graph: &Graph,
        result: &RunResult,
        outputs: Vec<String>,
    ) -> Manifest {
        let nodes: Vec<ManifestNode> = graph
            .instances
            .iter()
            .enumerate()
            .map(|(i, inst)| {
                let (status, seconds, error) = match &result.outcomes[i] {
                    Outcome::Computed { seconds, .. } | Outcome::Released { seconds, .. } => {
                        ("computed", *seconds, None)
                    }
                    Outcome::Cached { .. } => ("cached", 0.0, None),
                    Outcome::Failed(e) => ("failed", 0.0, Some(e.to_string())),
                    Outcome::Skipped => ("skipped", 0.0, None),
                    Outcome::Unneeded { cached: true, .. } => ("cached", 0.0, None),
                    Outcome::Unneeded { cached: false, .. } => ("unneeded", 0.0, None),
                };
                ManifestNode {
                    id: inst.id.clone(),
                    kind: inst.kind.clone(),
                    version: inst.version,
                    key: inst.key.clone(),
                    status: status.into(),
                    seconds,
                    params: inst.param_digests.clone(),
                    inputs: input_keys(graph, i),
                    error,
                    warnings: result.outcomes[i].warnings().to_vec(),
                }
            })
            .collect();
        Manifest {
            tool: format!("spindlelab {}", env!("CARGO_PKG_VERSION")),
            recipe_name: recipe.name.clone(),
            recipe_hash: recipe.hash.clone(),
            recipe_path: recipe_path.to_string(),
            recipe_text: String::new(),
            seconds: result.seconds,
            cache_hits: nodes.iter().filter(|n| n.status == "cached").count(),
            computed: nodes.iter().filter(|n| n.status == "computed").count(),
            nodes,
            outputs,
            files: IndexMap::new(),
            data_files: recipe
                .data_files()
                .into_iter()
                .map(|f| (f.path.display().to_string(), f.hash.to_string()))
                .collect(),
            recipe_files: IndexMap::new(),
            entities: recipe
                .entity_digests
                .iter()
                .map(|((kind, name), d)| (Recipe::entity_label(*kind, name), d.clone()))
                .collect(),
            notes: result.notes.clone(),
            partial: IndexMap::new(),
        }
    }

    /// The manifest of the run committed in the output folder `out_dir` (or of the run folder
    /// `out_dir` itself); `None` when there is none or it cannot be read.
    pub fn read(out_dir: &Path) -> Option<Manifest> {
        // Through the committed run's own folder: the visible name is a link, and a pipe or
        // a link planted as the manifest is not read, a huge one not whole.
        let committed = out_dir.join(super::commit::META_DIR).join("current");
        let dir = if committed.is_dir() { committed } else { out_dir.to_path_buf() };
        let bytes = super::files::read_regular(&dir.join(MANIFEST_FILE), 1 << 30).ok()?;
        serde_json::from_slice(&bytes).ok()
    }
}

/// Why an instance would run, or that it comes from the cache.
#[derive(Debug, Clone, PartialEq)]
pub enum PlanReason {
    Cached,
    New,
    NewVersion {
        from: u32,
        to: u32,
    },
    ChangedParams(Vec<String>),
    /// Changed parameters naming entities whose contents changed, with the files they are
    /// defined in (a library the recipe uses, or the recipe itself).
    ChangedIn {
        params: Vec<String>,
        files: Vec<String>,
    },
    ChangedInputs(Vec<String>),
    /// The previous run did not finish it, or the cache was cleared or bypassed.
    NotInCache,
    /// Not cached, but every consumer is, and no output file reads it.
    NotNeeded,
    /// Never cached (large outputs that are cheaper to remake), and needed: by the output file
    /// or the uncached instance named.
    Uncacheable {
        needed_by: String,
    },
}

impl std::fmt::Display for PlanReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PlanReason::Cached => write!(f, "from cache"),
            PlanReason::New => write!(f, "run: new node"),
            PlanReason::NewVersion { from, to } => write!(f, "run: node version {from} → {to}"),
            PlanReason::ChangedParams(p) => write!(
                f,
                "run: changed parameter {}",
                p.iter().map(|s| format!("`{s}`")).collect::<Vec<_>>().join(", ")
            ),
            PlanReason::ChangedIn { params, files } => write!(
                f,
                "run: changed parameter {} (changed in {})",
                params.iter().map(|s| format!("`{s}`")).collect::<Vec<_>>().join(", "),
                files.join(", ")
            ),
            PlanReason::ChangedInputs(p) => {
                write!(f, "run: changed input {}", p.iter().map(|s| format!("`{s}`")).collect::<Vec<_>>().join(", "))
            }
            PlanReason::NotInCache => write!(f, "run: not in cache"),
            PlanReason::NotNeeded => write!(f, "skip: every consumer comes from the cache"),
            PlanReason::Uncacheable { needed_by } => {
                write!(f, "run: never cached (large outputs, cheap to remake), and {needed_by} needs it")
            }
        }
    }
}

/// One line of a plan.
#[derive(Debug, Clone)]
pub struct PlanEntry {
    pub id: String,
    pub kind: String,
    pub reason: PlanReason,
}

/// What makes the uncached instance `i` run: an output file that reads its step, else the
/// first consumer that runs too.
fn needed_by(recipe: &Recipe, graph: &Graph, i: usize, needed: &[bool], cached: &[bool]) -> String {
    let step = graph.instances[i].step.as_str();
    if let Some(out) = recipe.outputs.iter().find(|o| o.steps().any(|s| s == step)) {
        return format!("the output `{}`", out.file);
    }
    graph
        .instances
        .iter()
        .enumerate()
        .skip(i + 1)
        .find(|(j, inst)| needed[*j] && !cached[*j] && inst.deps().any(|d| d == i))
        .map_or_else(|| "the run (nothing consumes it)".to_string(), |(_, inst)| format!("`{}`", inst.id))
}

fn prev_entities(m: Option<&Manifest>) -> IndexMap<String, String> {
    m.map(|m| m.entities.clone()).unwrap_or_default()
}

/// The files in which the entities named by `inst`'s changed parameters changed: an entity
/// whose digest differs from the previous run's, and which names no entity that changed
/// (an assembly is not what changed when only its material did).
fn changed_in(
    recipe: &Recipe,
    inst: &crate::graph::Instance,
    changed: &[String],
    prev: &IndexMap<String, String>,
) -> Vec<String> {
    use crate::spec::{EntityKind, ParamValue};
    fn named(v: &ParamValue, out: &mut Vec<(EntityKind, String)>) {
        match v {
            ParamValue::Entity { kind, name } => out.push((*kind, name.clone())),
            ParamValue::Object(p) => p.values.values().for_each(|v| named(v, out)),
            ParamValue::Objects(ps) => ps.iter().flat_map(|p| p.values.values()).for_each(|v| named(v, out)),
            ParamValue::Map(m) => m.values().for_each(|v| named(v, out)),
            _ => {}
        }
    }
    if prev.is_empty() {
        return Vec::new();
    }
    let differs = |k: EntityKind, n: &str| {
        let now = recipe.entity_digest(k, n);
        now.is_some() && prev.get(&Recipe::entity_label(k, n)) != now.as_ref()
    };
    let mut files: Vec<String> = Vec::new();
    for p in changed {
        let mut direct = Vec::new();
        if let Some(v) = inst.params.values.get(p) {
            named(v, &mut direct);
        }
        for (k, n) in direct {
            for (ek, en) in recipe.entity_closure(k, &n) {
                let own_change = differs(ek, &en)
                    && recipe
                        .entity_origins
                        .get(&(ek, en.clone()))
                        .is_none_or(|o| !o.names.iter().any(|(nk, nn)| differs(*nk, nn)));
                if own_change
                    && let Some(o) = recipe.entity_origins.get(&(ek, en.clone()))
                    && !files.contains(&o.file)
                {
                    files.push(o.file.clone());
                }
            }
        }
    }
    files
}

/// Says, without running anything, which instances would run and why.
pub fn plan(
    recipe: &Recipe,
    graph: &Graph,
    registry: &Registry,
    out_dir: &Path,
    cache: Option<&Cache>,
) -> Vec<PlanEntry> {
    let previous = Manifest::read(out_dir);
    let cacheable: Vec<bool> =
        graph.instances.iter().map(|inst| registry.get(&inst.kind).is_none_or(|node| node.cacheable())).collect();
    let cached: Vec<bool> = graph
        .instances
        .iter()
        .zip(&cacheable)
        .map(|(inst, &c)| c && cache.is_some_and(|cache| cache.contains(&inst.key)))
        .collect();
    // Without a cache every instance runs.
    let needed = if cache.is_some() { super::needed(recipe, graph, &cached) } else { vec![true; cached.len()] };
    graph
        .instances
        .iter()
        .enumerate()
        .map(|(i, inst)| {
            let reason = if cached[i] {
                PlanReason::Cached
            } else if !needed[i] {
                PlanReason::NotNeeded
            } else if !cacheable[i] {
                PlanReason::Uncacheable { needed_by: needed_by(recipe, graph, i, &needed, &cached) }
            } else {
                match previous.as_ref().and_then(|m| m.nodes.iter().find(|n| n.id == inst.id)) {
                    None => PlanReason::New,
                    Some(prev) if prev.version != inst.version => {
                        PlanReason::NewVersion { from: prev.version, to: inst.version }
                    }
                    Some(prev) => {
                        let mut changed: Vec<String> = inst
                            .param_digests
                            .iter()
                            .filter(|(k, d)| prev.params.get(*k) != Some(*d))
                            .map(|(k, _)| k.clone())
                            .collect();
                        changed.extend(prev.params.keys().filter(|k| !inst.param_digests.contains_key(*k)).cloned());
                        let files = changed_in(recipe, inst, &changed, &prev_entities(previous.as_ref()));
                        if !changed.is_empty() && !files.is_empty() {
                            PlanReason::ChangedIn { params: changed, files }
                        } else if !changed.is_empty() {
                            PlanReason::ChangedParams(changed)
                        } else {
                            let now = input_keys(graph, i);
                            let ports: Vec<String> = now
                                .iter()
                                .filter(|(p, keys)| prev.inputs.get(*p) != Some(*keys))
                                .map(|(p, _)| p.clone())
                                .collect();
                            if ports.is_empty() { PlanReason::NotInCache } else { PlanReason::ChangedInputs(ports) }
                        }
                    }
                }
            };
            PlanEntry { id: inst.id.clone(), kind: inst.kind.clone(), reason }
        })
        .collect()
}
