//! The content-addressed cache of node outputs.
//!
//! An entry is written to a temporary file and renamed into place, and carries a checksum of
//! its payload: an interrupted write never leaves an entry that a later run would serve.

use crate::node::Outputs;
use crate::value::Value;
use std::io::Write;
use std::path::PathBuf;

const MAGIC: &[u8; 8] = b"SPLCACH3";

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
        self.get(key).is_some()
    }

    /// The outputs stored under `key`, if present and intact.
    pub fn get(&self, key: &str) -> Option<Entry> {
        let bytes = std::fs::read(self.path(key)).ok()?;
        if bytes.len() < 40 || &bytes[..8] != MAGIC {
            return None;
        }
        let (sum, payload) = bytes[8..].split_at(32);
        if blake3::hash(payload).as_bytes() != sum {
            return None;
        }
        let (warnings, pairs): (Vec<String>, Vec<(String, Value)>) = postcard::from_bytes(payload).ok()?;
        Some(Entry { outputs: pairs.into_iter().collect(), warnings })
    }

    /// Stores outputs under `key` atomically.
    pub fn put(&self, key: &str, outputs: &Outputs, warnings: &[String]) -> std::io::Result<()> {
        let path = self.path(key);
        let parent = path.parent().expect("entry has a parent");
        std::fs::create_dir_all(parent)?;
        let pairs: Vec<(&String, &Value)> = outputs.iter().collect();
        let payload = postcard::to_stdvec(&(warnings, pairs)).map_err(std::io::Error::other)?;
        let mut tmp = tempfile::NamedTempFile::new_in(parent)?;
        tmp.write_all(MAGIC)?;
        tmp.write_all(blake3::hash(&payload).as_bytes())?;
        tmp.write_all(&payload)?;
        tmp.as_file().sync_data()?;
        tmp.persist(&path).map_err(|e| e.error)?;
        Ok(())
    }
}
