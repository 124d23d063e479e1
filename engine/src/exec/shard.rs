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

/// Why a shard's marker could not be written; the entries the shard computed stay cached.
#[derive(Debug, thiserror::Error)]
pub enum MarkerError {
    /// A link stands where the cache keeps its markers (`CACHE/shards`, a graph's folder, the
    /// marker itself): nothing is written where it leads.
    #[error(
        "`{0}` is a symbolic link where the cache keeps its shard markers; spindlelab does not write through links in its cache, and wrote nothing where it leads: remove the link and run the shard again (what it computed is cached)"
    )]
    Link(PathBuf),
    /// The output folder's own cache is a link: nothing was stored through it, entries included.
    #[error(
        "`{0}`, the output folder's cache, is a symbolic link; spindlelab never writes through it, so this shard stored nothing: remove the link (or name a shared cache with --cache) and run the shard again"
    )]
    CacheLink(PathBuf),
    /// A file, a pipe or a device stands where the cache keeps a folder of markers, or a
    /// folder, a pipe or a device where the marker goes.
    #[error(
        "`{0}` stands where the cache keeps its shard markers and is not what spindlelab puts there; move it away and run the shard again (what it computed is cached)"
    )]
    InTheWay(PathBuf),
    #[error("cannot write the shard marker `{path}`: {source}")]
    Io { path: PathBuf, source: std::io::Error },
}

impl MarkerError {
    /// Whether the error is the user's to fix (something planted in the cache) rather than a
    /// failure of the machine.
    pub fn is_bad_input(&self) -> bool {
        !matches!(self, MarkerError::Io { .. })
    }
}

impl Shard {
    /// Writes `text` as this shard's marker ([`Shard::marker`]) under `cache_dir`, and returns
    /// its path. The cache folder itself is made if missing (a cache the user names is resolved
    /// before, see [`super::RunOptions::cache`], so a link there is the output folder's own
    /// cache replaced, and refused); the folders inside it (`shards`,
    /// the graph's digest) are made, and the marker written, without following a link: a link
    /// or anything else standing there is refused, never written through. The marker is written
    /// whole to a fresh name beside it and renamed into place.
    pub fn write_marker(&self, cache_dir: &Path, graph: &Graph, text: &str) -> Result<PathBuf, MarkerError> {
        use std::io::Write;
        static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let path = self.marker(cache_dir, graph);
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| MarkerError::Io { path, source }
        };
        if super::files::is_link(cache_dir) {
            return Err(MarkerError::CacheLink(cache_dir.to_path_buf()));
        }
        std::fs::create_dir_all(cache_dir).map_err(io(cache_dir))?;
        let mut dir = cache_dir.to_path_buf();
        let inner = path.parent().and_then(|p| p.strip_prefix(cache_dir).ok()).unwrap_or(Path::new(""));
        for part in inner.components() {
            dir.push(part);
            match std::fs::symlink_metadata(&dir) {
                Ok(m) if m.file_type().is_symlink() => return Err(MarkerError::Link(dir)),
                Ok(m) if m.is_dir() => {}
                Ok(_) => return Err(MarkerError::InTheWay(dir)),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => match std::fs::create_dir(&dir) {
                    Err(e) if e.kind() != std::io::ErrorKind::AlreadyExists => return Err(io(&dir)(e)),
                    _ if super::files::is_link(&dir) => return Err(MarkerError::Link(dir)),
                    _ => {}
                },
                Err(e) => return Err(io(&dir)(e)),
            }
        }
        match std::fs::symlink_metadata(&path) {
            Ok(m) if m.file_type().is_symlink() => return Err(MarkerError::Link(path)),
            Ok(m) if !m.is_file() => return Err(MarkerError::InTheWay(path)),
            _ => {}
        }
        let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let tmp = dir.join(format!(".tmp-{}-{n}", std::process::id()));
        let written = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .and_then(|mut f| f.write_all(text.as_bytes()))
            .and_then(|()| std::fs::rename(&tmp, &path));
        if let Err(e) = written {
            let _ = std::fs::remove_file(&tmp);
            return Err(io(&path)(e));
        }
        Ok(path)
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
