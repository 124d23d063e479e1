//! The content-addressed cache of node outputs.
//!
//! An entry is written to a temporary file and renamed into place, and carries a checksum of
//! its payload and the key it was written for: an interrupted write, damaged bytes or an entry
//! under the wrong name is never served; the run recomputes it and says so.

use crate::node::Outputs;
use crate::value::Value;
use std::io::Write;
use std::path::PathBuf;

const MAGIC: &[u8; 8] = b"SPLCACH4";

/// A cache entry: a node's outputs and the warnings it raised making them.
pub struct Entry {
    pub outputs: Outputs,
    pub warnings: Vec<String>,
}

/// A directory of cache entries keyed by instance key.
#[derive(Debug, Clone)]
pub struct Cache {
    dir: PathBuf,
}

impl Cache {
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Cache { dir: dir.into() }
    }

    fn path(&self, key: &str) -> PathBuf {
        self.dir.join(&key[..2.min(key.len())]).join(format!("{key}.bin"))
    }

    /// Whether a complete entry exists (checked by reading it: cheap next to recomputing).
    pub fn contains(&self, key: &str) -> bool {
        matches!(self.lookup(key), Lookup::Hit(_))
    }

    /// The outputs stored under `key`, if present and intact.
    pub fn get(&self, key: &str) -> Option<Entry> {
        match self.lookup(key) {
            Lookup::Hit(e) => Some(e),
            _ => None,
        }
    }

    /// The entry under `key`: present and intact, absent, or present but unusable (and why).
    pub fn lookup(&self, key: &str) -> Lookup {
        let Ok(bytes) = std::fs::read(self.path(key)) else { return Lookup::Miss };
        if bytes.len() < 40 || &bytes[..8] != MAGIC {
            return Lookup::Damaged("written by another version or cut short".into());
        }
        let (sum, payload) = bytes[8..].split_at(32);
        if blake3::hash(payload).as_bytes() != sum {
            return Lookup::Damaged("its checksum does not match its contents".into());
        }
        type Stored = (String, Vec<String>, Vec<(String, Value)>);
        let Ok((stored_key, warnings, pairs)) = postcard::from_bytes::<Stored>(payload) else {
            return Lookup::Damaged("its contents cannot be decoded".into());
        };
        if stored_key != key {
            return Lookup::Damaged(format!("it was written for another node (key {stored_key:.12}…)"));
        }
        Lookup::Hit(Entry { outputs: pairs.into_iter().collect(), warnings })
    }

    /// Stores outputs under `key` atomically. The entry is created with the process's umask,
    /// so users who share an output folder share its cache.
    pub fn put(&self, key: &str, outputs: &Outputs, warnings: &[String]) -> std::io::Result<()> {
        static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let path = self.path(key);
        let parent = path.parent().expect("entry has a parent");
        std::fs::create_dir_all(parent)?;
        let pairs: Vec<(&String, &Value)> = outputs.iter().collect();
        let payload = postcard::to_stdvec(&(key, warnings, pairs)).map_err(std::io::Error::other)?;
        let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let tmp = parent.join(format!(".tmp-{}-{n}", std::process::id()));
        let written = (|| {
            let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
            f.write_all(MAGIC)?;
            f.write_all(blake3::hash(&payload).as_bytes())?;
            f.write_all(&payload)?;
            f.sync_data()?;
            std::fs::rename(&tmp, &path)
        })();
        if written.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        written
    }

    /// The cache folder.
    pub fn dir(&self) -> &std::path::Path {
        &self.dir
    }

    /// Every entry file with its key and size in bytes.
    fn entries(&self) -> Vec<(String, PathBuf, u64)> {
        let mut out = Vec::new();
        for sub in std::fs::read_dir(&self.dir).into_iter().flatten().flatten() {
            if !sub.file_type().is_ok_and(|t| t.is_dir()) {
                continue;
            }
            for e in std::fs::read_dir(sub.path()).into_iter().flatten().flatten() {
                let name = e.file_name().to_string_lossy().to_string();
                if let Some(key) = name.strip_suffix(".bin") {
                    let size = e.metadata().map_or(0, |m| m.len());
                    out.push((key.to_string(), e.path(), size));
                }
            }
        }
        out.sort();
        out
    }

    /// Number of entries and their total size in bytes.
    pub fn usage(&self) -> (usize, u64) {
        let e = self.entries();
        (e.len(), e.iter().map(|(_, _, s)| s).sum())
    }

    /// Removes every entry whose key `keep` rejects; returns how many and how many bytes.
    pub fn retain(&self, keep: impl Fn(&str) -> bool) -> (usize, u64) {
        let (mut n, mut bytes) = (0, 0);
        for (key, path, size) in self.entries() {
            if !keep(&key) && std::fs::remove_file(&path).is_ok() {
                n += 1;
                bytes += size;
            }
        }
        for sub in std::fs::read_dir(&self.dir).into_iter().flatten().flatten() {
            let _ = std::fs::remove_dir(sub.path()); // only the emptied ones go
        }
        (n, bytes)
    }
}

/// What [`Cache::lookup`] found.
pub enum Lookup {
    Hit(Entry),
    Miss,
    /// An entry exists but cannot be served; the reason is for the user.
    Damaged(String),
}
