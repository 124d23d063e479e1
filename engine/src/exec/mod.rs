//! Execution: instances run in dependency waves, each wave in parallel on rayon, with a
//! content-addressed cache. Nodes are pure and results are gathered in instance order, so
//! the numbers are identical whatever the thread count.

mod cache;
pub mod commit;
pub mod files;
pub mod manifest;
pub mod render;
pub mod shard;
pub mod write;

pub use cache::{Cache, Lookup};
pub use commit::{CommitError, OutputDir};
pub use manifest::{Manifest, ManifestNode, PlanEntry, PlanReason, plan};
pub use shard::Shard;

use crate::graph::Graph;
use crate::model::Recipe;
use crate::node::{Labelled, NodeContext, NodeError, Outputs, Registry};
use indexmap::IndexMap;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// How to run a compiled recipe.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Where outputs, the manifest and (by default) the cache go.
    pub out_dir: PathBuf,
    /// Read and write the cache; off with `--no-cache`.
    pub use_cache: bool,
    /// Keep running independent instances after one fails.
    pub keep_going: bool,
    /// Worker threads; `None` uses rayon's default.
    pub threads: Option<usize>,
    /// Drop the outputs of uncached instances (raw recordings) once every consumer has
    /// run and no output file reads them, to bound memory; the result then shows them as
    /// released.
    pub release_consumed: bool,
    /// Outputs already computed in this process, by cache key: instances found here are
    /// not run again (a fit re-evaluates only what its parameters reach).
    pub memo: Option<Arc<Memo>>,
    /// Settle only these steps and what they need, instead of every output and leaf.
    pub targets: Option<Vec<String>>,
    /// Further files of the run (relative path, text), committed with its outputs: a fit's
    /// report and fitted recipe.
    pub extra_files: Vec<(String, String)>,
    /// Write the HTML run report (`report.html`) with the outputs.
    pub report: bool,
    /// Draws the plots and the report; a run that asks for either needs one.
    pub renderer: Option<Arc<dyn crate::render::Renderer>>,
    /// The cache folder when it is not the output folder's own (`--cache DIR`,
    /// `SPINDLELAB_CACHE`): one that runs, shards and machines share.
    pub cache_dir: Option<PathBuf>,
    /// Settle only this shard's instances and what they need ([`shard`]).
    pub shard: Option<Shard>,
}

/// Outputs and warnings of computed instances, by cache key, kept in memory.
pub type Memo = std::collections::HashMap<String, (Arc<Produced>, Vec<String>)>;

impl RunOptions {
    pub fn new(out_dir: impl Into<PathBuf>) -> Self {
        RunOptions {
            out_dir: out_dir.into(),
            use_cache: true,
            keep_going: false,
            threads: None,
            release_consumed: false,
            memo: None,
            targets: None,
            extra_files: Vec::new(),
            report: false,
            renderer: None,
            cache_dir: None,
            shard: None,
        }
    }

    /// These options with `renderer` to draw plots and the report.
    pub fn with_renderer(mut self, renderer: Arc<dyn crate::render::Renderer>) -> Self {
        self.renderer = Some(renderer);
        self
    }

    /// The cache directory for this output directory.
    ///
    /// A cache folder the user names (`--cache DIR`) is the user's path, resolved as the
    /// system does: given as a link (a shared cache on a cluster often is), it is the folder
    /// the link leads to. The output folder's own cache is never reached through a link.
    pub fn cache(&self) -> Cache {
        match &self.cache_dir {
            Some(dir) => Cache::new(std::fs::canonicalize(dir).unwrap_or_else(|_| dir.clone())),
            None => Cache::new(cache_dir(&self.out_dir)),
        }
    }
}

/// Where the cache of an output directory lives.
pub fn cache_dir(out_dir: &Path) -> PathBuf {
    out_dir.join(".spindlelab-cache")
}

/// A finished instance's outputs, each shared so consumers read it without copying.
pub type Produced = IndexMap<String, Arc<crate::value::Value>>;

fn share(outputs: Outputs) -> Arc<Produced> {
    Arc::new(outputs.into_iter().map(|(k, v)| (k, Arc::new(v))).collect())
}

/// What happened to one instance.
#[derive(Debug, Clone)]
pub enum Outcome {
    Computed {
        outputs: Arc<Produced>,
        seconds: f64,
        /// Warnings the node raised (rejected records and the like).
        warnings: Vec<String>,
    },
    Cached {
        outputs: Arc<Produced>,
        warnings: Vec<String>,
    },
    Failed(NodeError),
    /// Not run because an input failed (or the run stopped).
    Skipped,
    /// Not run or loaded: no output file reads it and every consumer came from the cache.
    /// `cached` says whether a valid cache entry exists for it; `warnings` are those its entry
    /// holds, so a cached run records what a fresh one does.
    Unneeded {
        cached: bool,
        warnings: Vec<String>,
    },
    /// Computed, used by every consumer, then dropped (see [`RunOptions::release_consumed`]).
    Released {
        seconds: f64,
        warnings: Vec<String>,
    },
}

/// The start of the warning a result that could not be stored in the cache carries.
pub const NOT_CACHED: &str = "the result could not be stored in the cache: ";

impl Outcome {
    pub fn outputs(&self) -> Option<&Arc<Produced>> {
        match self {
            Outcome::Computed { outputs, .. } | Outcome::Cached { outputs, .. } => Some(outputs),
            _ => None,
        }
    }

    /// Why a result computed in this run could not be stored in the cache, if it could not.
    pub fn not_cached(&self) -> Option<&str> {
        match self {
            Outcome::Computed { warnings, .. } | Outcome::Released { warnings, .. } => {
                warnings.iter().find_map(|w| w.strip_prefix(NOT_CACHED))
            }
            _ => None,
        }
    }

    /// Warnings raised by the node, replayed from the cache when it was not rerun.
    pub fn warnings(&self) -> &[String] {
        match self {
            Outcome::Computed { warnings, .. }
            | Outcome::Cached { warnings, .. }
            | Outcome::Released { warnings, .. }
            | Outcome::Unneeded { warnings, .. } => warnings,
            _ => &[],
        }
    }
}

/// The result of executing a graph: one outcome per instance, in instance order.
#[derive(Debug, Clone)]
pub struct RunResult {
    pub outcomes: Vec<Outcome>,
    pub seconds: f64,
    /// What the run noticed about itself: cache entries it could not use and recomputed.
    pub notes: Vec<String>,
}

impl RunResult {
    /// What this run computed, by cache key, for a later run in the same process to reuse
    /// (`RunOptions::memo`): a fit's start point seeds every later evaluation.
    pub fn memo(&self, graph: &Graph) -> Memo {
        graph
            .instances
            .iter()
            .zip(&self.outcomes)
            .filter_map(|(inst, o)| match o {
                Outcome::Computed { outputs, warnings, .. } => {
                    Some((inst.key.clone(), (Arc::clone(outputs), warnings.clone())))
                }
                _ => None,
            })
            .collect()
    }

    pub fn failures<'g>(&'g self, graph: &'g Graph) -> impl Iterator<Item = (&'g str, &'g NodeError)> {
        self.outcomes.iter().zip(&graph.instances).filter_map(|(o, i)| match o {
            Outcome::Failed(e) => Some((i.id.as_str(), e)),
            _ => None,
        })
    }
}

/// Runs every instance of the graph. `progress` is called after each instance finishes.
pub fn execute(
    recipe: &Recipe,
    graph: &Graph,
    registry: &Registry,
    opts: &RunOptions,
    progress: &(dyn Fn(usize, &str) + Sync),
) -> RunResult {
    let start = Instant::now();
    let pool = {
        let mut b = rayon::ThreadPoolBuilder::new();
        if let Some(n) = opts.threads {
            b = b.num_threads(n.clamp(1, 256));
        }
        // Threads the system refuses (a memory limit) leave one worker: same numbers, slower.
        b.build()
            .or_else(|_| rayon::ThreadPoolBuilder::new().num_threads(1).build())
            .expect("a one-thread pool can always be built")
    };
    let cache = opts.use_cache.then(|| opts.cache());
    let n = graph.instances.len();
    let mut outcomes: Vec<Option<Outcome>> = vec![None; n];
    let mut notes = Vec::new();
    if cache.is_some() || opts.memo.is_some() || opts.targets.is_some() || opts.shard.is_some() {
        settle_known(recipe, graph, registry, cache.as_ref(), opts, &mut outcomes, &mut notes);
    }
    let mut stop = false;
    let mut done_count = 0usize;
    // Instances whose outputs must stay: read by output files, or never cached.
    let mut keep = vec![false; n];
    for step in recipe.outputs.iter().flat_map(|o| o.steps()) {
        for &i in graph.by_step.get(step).into_iter().flatten() {
            keep[i] = true;
        }
    }
    for (i, o) in outcomes.iter().enumerate() {
        if o.is_some() {
            progress(i, &graph.instances[i].id);
            done_count += 1;
        }
    }
    // Depth of each instance (longest chain of inputs above it), for the memory-bounded order.
    let mut depth = vec![0usize; n];
    for i in 0..n {
        depth[i] = graph.instances[i].deps().map(|d| depth[d] + 1).max().unwrap_or(0);
    }
    let width = pool.current_num_threads().max(1);
    // Large intermediates in flight: one chain per thread, but no more than the machine has
    // cores, so threads beyond the cores (`-j 16` on two) do not multiply the memory they hold.
    let heavy_width = width.min(std::thread::available_parallelism().map_or(1, |n| n.get()));
    let mut failed_steps: std::collections::HashSet<String> = std::collections::HashSet::new();
    while outcomes.iter().any(Option::is_none) {
        // The next wave: every instance whose inputs are all settled.
        let mut wave: Vec<usize> = (0..n)
            .filter(|&i| outcomes[i].is_none() && graph.instances[i].deps().all(|d| outcomes[d].is_some()))
            .collect();
        if opts.release_consumed {
            // Producers of large uncached intermediates (raw records) start at most one per
            // thread and core, deepest first, so a sweep's recordings are consumed and released chain by
            // chain instead of all being alive at once; everything else runs as soon as it is
            // ready. The order changes when an instance runs, never what it computes.
            wave.sort_by_key(|&i| (std::cmp::Reverse(depth[i]), i));
            let mut heavy = 0;
            wave.retain(|&i| {
                let cacheable = registry.get(&graph.instances[i].kind).is_none_or(|node| node.cacheable());
                heavy += usize::from(!cacheable);
                cacheable || heavy <= heavy_width
            });
            wave.sort_unstable();
        }
        assert!(!wave.is_empty(), "graph has no ready instance; compile guarantees a DAG");
        let results: Vec<(usize, Outcome)> = pool.install(|| {
            wave.par_iter()
                .map(|&i| {
                    let inst = &graph.instances[i];
                    // After a failure the run stops, but the failed step's other instances still
                    // run, so every failing sweep point is reported at once.
                    let stopped = stop && !failed_steps.contains(&inst.step);
                    let blocked =
                        stopped || inst.deps().any(|d| outcomes[d].as_ref().and_then(Outcome::outputs).is_none());
                    let outcome =
                        if blocked { Outcome::Skipped } else { run_one(graph, registry, cache.as_ref(), &outcomes, i) };
                    progress(i, &inst.id);
                    (i, outcome)
                })
                .collect()
        });
        for (i, o) in results {
            if matches!(o, Outcome::Failed(_)) && !opts.keep_going {
                stop = true;
                failed_steps.insert(graph.instances[i].step.clone());
            }
            done_count += 1;
            outcomes[i] = Some(o);
        }
        if opts.release_consumed {
            release(graph, registry, &keep, &mut outcomes);
        }
    }
    debug_assert_eq!(done_count, n);
    RunResult {
        outcomes: outcomes.into_iter().map(|o| o.expect("settled")).collect(),
        seconds: start.elapsed().as_secs_f64(),
        notes,
    }
}

/// Which instances a run must settle, given which have a cache entry: those an output file
/// reads, those nothing consumes, and the inputs of every needed instance that is not cached.
pub fn needed(recipe: &Recipe, graph: &Graph, cached: &[bool]) -> Vec<bool> {
    needed_for(recipe, graph, cached, None)
}

/// [`needed`], or with `targets`, only the instances of those steps and what they need.
pub fn needed_for(recipe: &Recipe, graph: &Graph, cached: &[bool], targets: Option<&[String]>) -> Vec<bool> {
    let n = graph.instances.len();
    let mut needed = vec![false; n];
    let mut consumed = vec![false; n];
    for inst in &graph.instances {
        for d in inst.deps() {
            consumed[d] = true;
        }
    }
    let roots: Vec<&str> = match targets {
        Some(t) => t.iter().map(String::as_str).collect(),
        None => recipe.outputs.iter().flat_map(|o| o.steps()).collect(),
    };
    for step in roots {
        for &i in graph.by_step.get(step).into_iter().flatten() {
            needed[i] = true;
        }
    }
    // Without targets, the leaves are needed too: nothing consumes them, so nothing else asks.
    if targets.is_none() {
        for (need, consumed) in needed.iter_mut().zip(&consumed) {
            *need |= !consumed;
        }
    }
    needed_from(graph, cached, needed)
}

/// The instances `roots` need: themselves, and the inputs of every needed one not cached.
fn needed_from(graph: &Graph, cached: &[bool], mut needed: Vec<bool>) -> Vec<bool> {
    // Instances are in topological order: consumers come after their inputs.
    for i in (0..graph.instances.len()).rev() {
        if needed[i] && !cached[i] {
            for d in graph.instances[i].deps() {
                needed[d] = true;
            }
        }
    }
    needed
}

/// Reads the cache entry of every cacheable instance and settles what need not run: needed
/// instances with an entry are loaded from it, the others are marked unneeded. So a rerun
/// does not remake large uncached intermediates (simulated raw records) whose consumers
/// all come from the cache.
/// Drops the outputs of uncached computed instances whose consumers have all settled.
fn release(graph: &Graph, registry: &Registry, keep: &[bool], outcomes: &mut [Option<Outcome>]) {
    let n = graph.instances.len();
    let mut pending = vec![false; n];
    let mut consumed = vec![false; n];
    for (i, inst) in graph.instances.iter().enumerate() {
        for d in inst.deps() {
            consumed[d] = true;
            if outcomes[i].is_none() {
                pending[d] = true;
            }
        }
    }
    for i in 0..n {
        if keep[i] || pending[i] || !consumed[i] {
            continue;
        }
        if registry.get(&graph.instances[i].kind).is_some_and(|node| node.cacheable()) {
            continue;
        }
        if let Some(Outcome::Computed { seconds, warnings, .. }) = &outcomes[i] {
            outcomes[i] = Some(Outcome::Released { seconds: *seconds, warnings: warnings.clone() });
        }
    }
}

fn settle_known(
    recipe: &Recipe,
    graph: &Graph,
    registry: &Registry,
    cache: Option<&Cache>,
    opts: &RunOptions,
    outcomes: &mut [Option<Outcome>],
    notes: &mut Vec<String>,
) {
    let n = graph.instances.len();
    let mut entries: Vec<Option<(Arc<Produced>, Vec<String>)>> = graph
        .instances
        .iter()
        .map(|inst| {
            if let Some(hit) = opts.memo.as_ref().and_then(|m| m.get(&inst.key)) {
                return Some(hit.clone());
            }
            let node = registry.get(&inst.kind).expect("compiled kind");
            let cache = cache.filter(|_| node.cacheable())?;
            match cache.lookup(&inst.key) {
                cache::Lookup::Hit(e) => Some((share(e.outputs), e.warnings)),
                cache::Lookup::Miss => None,
                cache::Lookup::Damaged(why) => {
                    notes.push(format!("the cache entry of `{}` was not used ({why}); it is recomputed", inst.id));
                    None
                }
            }
        })
        .collect();
    let cached: Vec<bool> = entries.iter().map(Option::is_some).collect();
    let needed = match &opts.shard {
        Some(s) => needed_from(graph, &cached, shard::roots(graph, registry, s)),
        None => needed_for(recipe, graph, &cached, opts.targets.as_deref()),
    };
    for i in 0..n {
        match (needed[i], entries[i].take()) {
            (true, Some((outputs, warnings))) => outcomes[i] = Some(Outcome::Cached { outputs, warnings }),
            (false, e) => {
                let cached = e.is_some();
                let warnings = e.map(|(_, w)| w).unwrap_or_default();
                outcomes[i] = Some(Outcome::Unneeded { cached, warnings });
            }
            (true, None) => {}
        }
    }
}

/// A failed node's warnings often say why it failed (every record rejected, say): they go
/// into its error message, one note per line.
fn with_warnings(e: NodeError, warnings: Vec<String>) -> NodeError {
    if warnings.is_empty() {
        return e;
    }
    let notes: String = warnings.iter().map(|w| format!("\n  note: {w}")).collect();
    match e {
        NodeError::InvalidInput { port, message } => {
            NodeError::InvalidInput { port, message: message + notes.as_str() }
        }
        NodeError::InvalidParam { param, message } => {
            NodeError::InvalidParam { param, message: message + notes.as_str() }
        }
        NodeError::Failed(message) => NodeError::Failed(message + notes.as_str()),
        NodeError::MissingInput { port } => NodeError::Failed(format!("{}{notes}", NodeError::MissingInput { port })),
    }
}

fn run_one(
    graph: &Graph,
    registry: &Registry,
    cache: Option<&Cache>,
    outcomes: &[Option<Outcome>],
    i: usize,
) -> Outcome {
    let inst = &graph.instances[i];
    let node = registry.get(&inst.kind).expect("compiled kind");
    // Cache hits were settled before the waves; what reaches here runs.
    let cache = cache.filter(|_| node.cacheable());
    let mut inputs: IndexMap<String, Vec<Labelled>> = IndexMap::new();
    for (port, srcs) in &inst.inputs {
        let mut vals = Vec::new();
        for (src, out_port) in srcs {
            let outputs = outcomes[*src].as_ref().and_then(Outcome::outputs).expect("dependency finished");
            let Some(v) = outputs.get(out_port) else {
                return Outcome::Failed(NodeError::input(
                    port,
                    format!("`{}` produced no `{out_port}`", graph.instances[*src].id),
                ));
            };
            let coords = graph.instances[*src]
                .assignments
                .iter()
                .filter_map(|(k, v)| match v {
                    crate::spec::ParamValue::Quantity { value, dim } => {
                        let unit = if *dim == spindlelab_grammar::Dimension::DIMENSIONLESS {
                            String::new()
                        } else {
                            dim.si_unit()
                        };
                        Some(crate::node::Coord { name: k.clone(), value: *value, unit })
                    }
                    crate::spec::ParamValue::Int(i) => {
                        Some(crate::node::Coord { name: k.clone(), value: *i as f64, unit: String::new() })
                    }
                    _ => None,
                })
                .collect();
            vals.push(Labelled { label: graph.instances[*src].label.clone(), coords, value: Arc::clone(v) });
        }
        inputs.insert(port.clone(), vals);
    }
    let ctx = NodeContext::new(&inst.id, &inst.params, &inputs, &inst.entities);
    let t = Instant::now();
    // A panic in a node is a bug in that node; contain it and report it as that node's failure.
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| node.run(&ctx)));
    let seconds = t.elapsed().as_secs_f64();
    match result {
        Ok(Ok(outputs)) => {
            let spec = node.spec();
            for p in &spec.outputs {
                match outputs.get(p.name) {
                    Some(v) if v.port_type() == p.ty => {}
                    Some(v) => {
                        return Outcome::Failed(NodeError::Failed(format!(
                            "output `{}` is a {} but the node declares {}",
                            p.name,
                            v.port_type(),
                            p.ty
                        )));
                    }
                    None if p.optional => {}
                    None => {
                        return Outcome::Failed(NodeError::Failed(format!(
                            "declared output `{}` was not produced",
                            p.name
                        )));
                    }
                }
            }
            let mut warnings = ctx.take_warnings();
            if let Some(c) = cache
                && let Err(e) = c.put(&inst.key, &outputs, &warnings)
            {
                // A cache that cannot be written costs speed next time, not correctness now;
                // the run says so (and a shard, whose work is to fill the cache, fails on it).
                warnings.push(format!("{NOT_CACHED}{e}"));
            }
            Outcome::Computed { outputs: share(outputs), seconds, warnings }
        }
        Ok(Err(e)) => Outcome::Failed(with_warnings(e, ctx.take_warnings())),
        Err(panic) => {
            let msg = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Outcome::Failed(NodeError::Failed(format!("internal error in node: {msg}")))
        }
    }
}
