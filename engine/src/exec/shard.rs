//! Shards: a graph's cacheable instances split into `N` parts by their cache keys, so several
//! processes (or a workflow engine's jobs on many machines) compute one part each into a
//! shared cache, and a plain run afterwards finds every result there and commits the outputs.
//!
//! The partition depends on the keys only, never on thread count or order. A shard may be
//! narrowed to one level of the graph (the instances whose longest chain of inputs has that
//! length): a job of level `L` then needs only results of lower levels, which the jobs it waits
//! for have cached, so no instance is computed twice.

use crate::graph::Graph;
use crate::node::Registry;
use std::path::{Path, PathBuf};

/// Part `index` of `count` (1-based), optionally of one level of the graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
    pub level: Option<usize>,
}

impl Shard {
    /// `K/N` as the command line writes it.
    pub fn parse(text: &str) -> Result<Shard, String> {
        let bad = || format!("`{text}` is not a shard: write K/N with 1 ≤ K ≤ N, e.g. `--shard 2/4`");
        let (k, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count) =
            (k.trim().parse::<usize>().map_err(|_| bad())?, n.trim().parse::<usize>().map_err(|_| bad())?);
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count, level: None })
    }

    /// Whether the instance with cache key `key` at `depth` belongs to this shard.
    pub fn holds(&self, key: &str, depth: usize) -> bool {
        bucket(key, self.count) == self.index && self.level.is_none_or(|l| l == depth)
    }

    /// The file a finished shard job leaves in the cache folder, for a workflow engine to wait
    /// on: named by the graph's digest, so a changed recipe waits on new ones.
    pub fn marker(&self, cache_dir: &Path, graph: &Graph) -> PathBuf {
        let level = self.level.map(|l| format!("level-{l}-")).unwrap_or_default();
        cache_dir
            .join("shards")
            .join(graph_digest(graph))
            .join(format!("{level}shard-{}-of-{}.done", self.index, self.count))
    }
}

/// The shard (1-based) of `count` a cache key falls into: its first 64 bits modulo `count`.
pub fn bucket(key: &str, count: usize) -> usize {
    let head = key.get(..16).and_then(|h| u64::from_str_radix(h, 16).ok()).unwrap_or(0);
    (head % count.max(1) as u64) as usize + 1
}

/// Each instance's level: the length of its longest chain of inputs.
pub fn depths(graph: &Graph) -> Vec<usize> {
    let mut depth = vec![0usize; graph.instances.len()];
    for i in 0..graph.instances.len() {
        depth[i] = graph.instances[i].deps().map(|d| depth[d] + 1).max().unwrap_or(0);
    }
    depth
}

/// The number of levels that hold cacheable instances (0 for a graph of none).
pub fn levels(graph: &Graph, registry: &Registry) -> usize {
    let depth = depths(graph);
    graph
        .instances
        .iter()
        .zip(&depth)
        .filter(|(inst, _)| registry.get(&inst.kind).is_some_and(|n| n.cacheable()))
        .map(|(_, d)| d + 1)
        .max()
        .unwrap_or(0)
}

/// The instances a shard settles itself: its cacheable ones. What they need comes from the
/// cache, or is computed when it is never cached (cheap to remake by design).
pub fn roots(graph: &Graph, registry: &Registry, shard: &Shard) -> Vec<bool> {
    let depth = depths(graph);
    graph
        .instances
        .iter()
        .zip(&depth)
        .map(|(inst, &d)| registry.get(&inst.kind).is_some_and(|n| n.cacheable()) && shard.holds(&inst.key, d))
        .collect()
}

/// A digest of every instance key: the identity of a compiled graph.
pub fn graph_digest(graph: &Graph) -> String {
    let mut h = blake3::Hasher::new();
    for inst in &graph.instances {
        h.update(inst.key.as_bytes());
        h.update(b"\n");
    }
    h.finalize().to_hex()[..16].to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shard_is_written_k_of_n() {
        assert_eq!(Shard::parse("2/4"), Ok(Shard { index: 2, count: 4, level: None }));
        for bad in ["0/4", "5/4", "2", "a/b", "2/0", ""] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
    }

    /// Every key falls into exactly one of the shards, and the split is even enough to share
    /// work: 1,000 keys over 4 shards put between 200 and 300 into each.
    #[test]
    fn keys_fall_into_one_shard_each_and_spread() {
        let keys: Vec<String> =
            (0..1000).map(|i| blake3::hash(format!("{i}").as_bytes()).to_hex().to_string()).collect();
        let mut counts = [0usize; 4];
        for k in &keys {
            let hits: Vec<usize> = (1..=4).filter(|&s| Shard { index: s, count: 4, level: None }.holds(k, 0)).collect();
            assert_eq!(hits.len(), 1, "{k}");
            counts[hits[0] - 1] += 1;
        }
        assert!(counts.iter().all(|&c| (200..=300).contains(&c)), "{counts:?}");
    }
}
