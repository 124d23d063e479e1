//! The content-addressed cache of node outputs.
//!
//! An entry is written to a temporary file and renamed into place, and carries its payload's
//! length, a checksum of it and the key it was written for: an interrupted write, damaged
//! bytes or an entry under the wrong name is never served; the run recomputes it and says so.
//! An entry is opened without following links or waiting on pipes, and read only as far as
//! its declared length (and [`MAX_ENTRY_BYTES`]) allows. The checksum detects damage, not a
//! local user who can write the folder and recompute it.

use super::files::{self, Refused};
use crate::node::Outputs;
use crate::value::Value;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 8] = b"SPLCACH8";
/// Magic, payload length (u64, little endian), BLAKE3 of the payload.
const HEADER: usize = 8 + 8 + 32;

/// The largest entry written or read; larger outputs are recomputed on every run instead.
pub const MAX_ENTRY_BYTES: u64 = 1 << 30;

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
    ///
    /// Only the header and the payload length it declares are read: a file longer than that
    /// (padded to a gigabyte behind a valid header) is damage, found from its length alone.
    pub fn lookup(&self, key: &str) -> Lookup {
        let path = self.path(key);
        let parent = path.parent().expect("entry has a parent");
        match std::fs::symlink_metadata(parent) {
            Ok(m) if m.file_type().is_symlink() => return Lookup::Damaged("its folder is a symbolic link".into()),
            Ok(m) if !m.is_dir() => {
                return Lookup::Damaged(format!(
                    "`{}` is a file where the cache keeps a folder of entries, so nothing under it can be stored; spindlelab does not remove it: move it away or remove it (`rm '{}'`)",
                    parent.display(),
                    parent.display()
                ));
            }
            _ => {}
        }
        let mut f = match files::open_regular(&path, std::fs::OpenOptions::new().read(true)) {
            Ok(f) => f,
            Err(Refused::Missing) => return Lookup::Miss,
            Err(Refused::Special) if path.is_dir() => return Lookup::Damaged(folder_at_entry(&path)),
            Err(e) => return Lookup::Damaged(e.to_string()),
        };
        let len = match f.metadata() {
            Ok(m) => m.len(),
            Err(e) => return Lookup::Damaged(e.to_string()),
        };
        let mut header = [0u8; HEADER];
        if len < HEADER as u64 || f.read_exact(&mut header).is_err() || &header[..8] != MAGIC {
            return Lookup::Damaged("written by another version or cut short".into());
        }
        let declared = u64::from_le_bytes(header[8..16].try_into().expect("eight bytes"));
        if declared > MAX_ENTRY_BYTES {
            return Lookup::Damaged(format!("its header declares {declared} bytes, more than an entry may hold"));
        }
        let held = len - HEADER as u64;
        if held > declared {
            return Lookup::Damaged(format!(
                "the file holds {held} bytes where its header declares {declared}; the rest was not read"
            ));
        }
        let mut payload = Vec::new();
        if (&mut f).take(declared).read_to_end(&mut payload).is_err() || (payload.len() as u64) < declared {
            return Lookup::Damaged(format!("it holds {} bytes where its header declares {declared}", payload.len()));
        }
        if blake3::hash(&payload).as_bytes() != &header[16..HEADER] {
            return Lookup::Damaged("its checksum does not match its contents".into());
        }
        type Stored = (String, Vec<String>, Vec<(String, Value)>);
        let Ok((stored_key, warnings, pairs)) = postcard::from_bytes::<Stored>(&payload) else {
            return Lookup::Damaged("its contents cannot be decoded".into());
        };
        if stored_key != key {
            return Lookup::Damaged(format!("it was written for another node (key {stored_key:.12}…)"));
        }
        Lookup::Hit(Entry { outputs: pairs.into_iter().collect(), warnings })
    }

    /// Stores outputs under `key` atomically. The entry is created with the process's umask,
    /// so users who share an output folder share its cache. A link standing in place of the
    /// entry's folder is removed (never written through), and so is an empty folder standing
    /// at the entry's name (it holds nothing of anyone's); a folder holding files is left and
    /// the entry not stored ([`Cache::lookup`] says how to fix it). An entry over
    /// [`MAX_ENTRY_BYTES`] is not stored.
    pub fn put(&self, key: &str, outputs: &Outputs, warnings: &[String]) -> std::io::Result<()> {
        static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let path = self.path(key);
        let parent = path.parent().expect("entry has a parent");
        if files::is_link(&self.dir) {
            return Err(std::io::Error::other("the cache folder is a symbolic link"));
        }
        if files::is_link(parent) {
            std::fs::remove_file(parent)?;
        }
        std::fs::create_dir_all(parent)?;
        let pairs: Vec<(&String, &Value)> = outputs.iter().collect();
        let payload = postcard::to_stdvec(&(key, warnings, pairs)).map_err(std::io::Error::other)?;
        if payload.len() as u64 > MAX_ENTRY_BYTES {
            return Err(std::io::Error::other("the outputs are larger than a cache entry may be"));
        }
        let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let tmp = parent.join(format!(".tmp-{}-{n}", std::process::id()));
        let written = (|| {
            let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
            f.write_all(MAGIC)?;
            f.write_all(&(payload.len() as u64).to_le_bytes())?;
            f.write_all(blake3::hash(&payload).as_bytes())?;
            f.write_all(&payload)?;
            // No fsync: an entry torn by a power cut fails its length or checksum and is
            // recomputed, and a sweep of 50,000 small entries is not 50,000 disk flushes.
            if path.is_dir() && !files::is_link(&path) {
                std::fs::remove_dir(&path)?; // only an empty one goes
            }
            std::fs::rename(&tmp, &path)
        })();
        if written.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        written
    }

    /// Removes links standing in the cache in place of its folders or entries (they would lead
    /// reads and writes elsewhere); returns a note per link for the run to report.
    pub fn remove_links(&self) -> Vec<String> {
        let mut notes = Vec::new();
        let mut unlink = |p: &Path| {
            let target = std::fs::read_link(p).map(|t| t.display().to_string()).unwrap_or_default();
            if std::fs::remove_file(p).is_ok() {
                notes.push(format!(
                    "the cache held a symbolic link `{}` → `{target}`; it was removed (not followed) and what it stood for is recomputed",
                    p.display()
                ));
            }
        };
        for sub in std::fs::read_dir(&self.dir).into_iter().flatten().flatten() {
            let Ok(ft) = sub.file_type() else { continue };
            if ft.is_symlink() {
                unlink(&sub.path());
            } else if ft.is_dir() {
                for e in std::fs::read_dir(sub.path()).into_iter().flatten().flatten() {
                    if e.file_type().is_ok_and(|t| t.is_symlink()) {
                        unlink(&e.path());
                    }
                }
            }
        }
        notes
    }

    /// The cache folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Every entry file with its key and size in bytes (links are not entries).
    fn entries(&self) -> Vec<(String, PathBuf, u64)> {
        let mut out = Vec::new();
        for sub in std::fs::read_dir(&self.dir).into_iter().flatten().flatten() {
            if !sub.file_type().is_ok_and(|t| t.is_dir()) {
                continue;
            }
            for e in std::fs::read_dir(sub.path()).into_iter().flatten().flatten() {
                let name = e.file_name().to_string_lossy().to_string();
                if let Some(key) = name.strip_suffix(".bin")
                    && e.file_type().is_ok_and(|t| t.is_file())
                {
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

impl Cache {
    /// Bounds the cache to `max_bytes`: the entries written last are kept while they fit, the
    /// older ones removed (ties by key, so the choice does not depend on listing order); returns
    /// how many and how many bytes went. Works on a cache others use at the same time: an entry
    /// removed under a running job is a miss there, and recomputed.
    pub fn within(&self, max_bytes: u64) -> (usize, u64) {
        let mut entries: Vec<(std::time::SystemTime, String, u64)> = self
            .entries()
            .into_iter()
            .map(|(key, path, size)| {
                let at = std::fs::metadata(&path).and_then(|m| m.modified()).unwrap_or(std::time::UNIX_EPOCH);
                (at, key, size)
            })
            .collect();
        entries.sort_by(|a, b| b.0.cmp(&a.0).then_with(|| a.1.cmp(&b.1)));
        let mut total = 0u64;
        let keep: std::collections::HashSet<String> = entries
            .into_iter()
            .take_while(|(_, _, size)| {
                total += size;
                total <= max_bytes
            })
            .map(|(_, key, _)| key)
            .collect();
        self.retain(|k| keep.contains(k))
    }
}

/// Why a folder standing at an entry's name cannot be used, and what will be done or is to do.
fn folder_at_entry(path: &Path) -> String {
    let empty = std::fs::read_dir(path).is_ok_and(|mut rd| rd.next().is_none());
    if empty {
        "an empty folder stands at its name; it is removed and the entry written in its place".into()
    } else {
        format!(
            "a folder holding files stands at its name, so the entry cannot be stored; spindlelab does not remove it: move what it holds elsewhere and remove it (`rm -r '{}'`)",
            path.display()
        )
    }
}

/// What [`Cache::lookup`] found.
pub enum Lookup {
    Hit(Entry),
    Miss,
    /// An entry exists but cannot be served; the reason is for the user.
    Damaged(String),
}
