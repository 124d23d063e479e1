//! An output folder whose readers always see one complete run.
//!
//! Layout of an output folder `OUT`:
//!
//! ```text
//! OUT/.spindlelab/lock            held (exclusive) by the run that writes OUT
//! OUT/.spindlelab/runs/run-XXXX/  one folder per run: its files and manifest.json
//! OUT/.spindlelab/current         symbolic link → runs/run-XXXX, the committed run
//! OUT/.spindlelab/previous        symbolic link → the run before it, kept until the next run
//! OUT/.spindlelab/tmp/            links being made, renamed into place by the commit
//! OUT/<file>                      symbolic link → .spindlelab/current/<file>
//! OUT/<folder>                    symbolic link → .spindlelab/current/<folder> (outputs in it)
//! OUT/.spindlelab-cache/          the cache (see [`super::Cache`])
//! ```
//!
//! A run writes every file into a fresh run folder, then switches `current` by renaming a new
//! link over it: that rename is the single commit point, so a run killed at any moment leaves
//! the previous run whole, and a reader never sees files of two runs. An output in a folder is
//! reached through one link for the folder's topmost part that is not the user's, so a name
//! can turn from a file into a folder between runs and back, still in the one switch. A file
//! the new run does not write disappears with the switch (its link dangles and is removed).
//!
//! The folder is the user's too: a file or folder spindlelab did not make is never replaced
//! or removed (the run is refused before it computes, naming it), and a run folder in which
//! the user left or changed a file is kept when it ages out. The run before the committed one
//! is kept until the next run; older run folders, links a killed run left in
//! `.spindlelab/tmp`, the tool's links that no longer lead to a file of the committed run and
//! the cache's temporary files are removed when the next run takes the lock. Every link the
//! commit puts in the folder is made under a fresh name inside `.spindlelab/tmp` and renamed
//! into place, so no temporary name of the tool's is ever visible beside the user's files and
//! no name the tool did not make is removed. The lock, the manifest and cache entries are
//! opened without following links (see [`super::files`]).
//!
//! [`FAULT_COMMIT_STEP`] is a test hook: it makes the process abort right after a given step
//! of the commit, so that every moment of it can be killed deterministically.

use super::Cache;
use super::files::{self, Refused};
use std::fs::File;
use std::io::Write;
use std::path::{Component, Path, PathBuf};

/// The folder inside an output folder that holds runs, the lock and the `current` link.
pub const META_DIR: &str = ".spindlelab";
const RUNS: &str = "runs";
const CURRENT: &str = "current";
const PREVIOUS: &str = "previous";
const LOCK: &str = "lock";
/// Where a commit makes its links before renaming them into place (inside [`META_DIR`]).
const TMP: &str = "tmp";
/// The prefix of a link made beside its place when `.spindlelab/tmp` is on another file system
/// than the place (a rename cannot cross): unmistakably the tool's, and removed by the next run.
const NEAR_PREFIX: &str = ".spindlelab-link-";

/// The environment variable that makes a run abort right after step `N` (1-based) of its
/// commit: a link made, a link renamed into place, the folder synced, a stale link removed, old
/// runs removed. A test hook only (`tests/it/audit_output.rs` kills every step with it); a
/// value that is not a number is ignored.
pub const FAULT_COMMIT_STEP: &str = "SPINDLELAB_FAULT_COMMIT_STEP";

/// Why an output folder could not be opened or a run not committed.
#[derive(Debug, thiserror::Error)]
pub enum CommitError {
    #[error(
        "the output folder `{0}` is in use by another run; wait for it to finish, or give this run another folder with -o"
    )]
    Busy(PathBuf),
    #[error(
        "`{0}` is a symbolic link inside the output folder; spindlelab never writes through links it did not make (remove it, or choose another output folder)"
    )]
    ForeignLink(PathBuf),
    #[error(
        "`{path}` is a {what} spindlelab did not write, standing where this run puts an output; it is never replaced: move it away, rename the output, or give this run another folder with -o"
    )]
    NotOurs { path: PathBuf, what: &'static str },
    #[error(
        "`{0}` is not a regular file (a pipe, a device or a folder); remove it, or give this run another folder with -o"
    )]
    Special(PathBuf),
    /// The output folder the user named, or a folder on its path, is a file (or a link to
    /// nothing): there is no folder to write into, and nothing of it is replaced.
    #[error(
        "`{0}` is not a folder (a file, or a link that leads nowhere), so the outputs cannot go into it; give this run a folder with -o, or move the file away"
    )]
    NotAFolder(PathBuf),
    /// Something stands where spindlelab keeps its own folders in the output folder (a file at
    /// `OUT/.spindlelab/runs`): it is left as it is, and the run is refused.
    #[error(
        "`{path}` is a {what} where spindlelab keeps {purpose}; it is left as it is: move it away (or remove it if it is not yours) and run again"
    )]
    InTheWay { path: PathBuf, what: &'static str, purpose: &'static str },
    #[error("`{path}`: {source}")]
    Io { path: PathBuf, source: std::io::Error },
}

impl CommitError {
    /// Whether the error is the user's to fix (a busy folder, a planted link) rather than a
    /// failure of the machine.
    pub fn is_bad_input(&self) -> bool {
        !matches!(self, CommitError::Io { .. })
    }
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> CommitError + '_ {
    move |source| CommitError::Io { path: path.to_path_buf(), source }
}

/// An output folder held by this process until dropped.
#[derive(Debug)]
pub struct OutputDir {
    root: PathBuf,
    meta: PathBuf,
    _lock: File,
    /// What opening found and repaired or kept (links in the cache, run folders holding the
    /// user's files), for the run's manifest.
    notes: Vec<String>,
}

impl OutputDir {
    /// Creates `root` if needed, takes its lock (refusing if another run holds it) and removes
    /// what killed runs left behind.
    pub fn open(root: &Path) -> Result<OutputDir, CommitError> {
        user_folder(root)?;
        let meta = root.join(META_DIR);
        refuse_link(&super::cache_dir(root))?;
        own_folder(&meta, "its runs, its lock and the links to the committed run")?;
        own_folder(&meta.join(RUNS), "the folders of its runs")?;
        own_folder(&meta.join(TMP), "the links a commit makes before putting them in place")?;
        let lock_path = meta.join(LOCK);
        let lock = match files::open_regular(&lock_path, File::options().create(true).truncate(false).write(true)) {
            Ok(f) => f,
            Err(Refused::Link) => return Err(CommitError::ForeignLink(lock_path)),
            Err(Refused::Special) => return Err(CommitError::Special(lock_path)),
            Err(e) => return Err(io(&lock_path)(std::io::Error::other(e.to_string()))),
        };
        match lock.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => return Err(CommitError::Busy(root.to_path_buf())),
            Err(std::fs::TryLockError::Error(e)) => return Err(io(&lock_path)(e)),
        }
        let mut dir = OutputDir { root: root.to_path_buf(), meta, _lock: lock, notes: Vec::new() };
        dir.notes = dir.clean_leftovers();
        Ok(dir)
    }

    /// What opening the folder repaired or kept, one sentence each.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// Checks, before anything is computed, that every output (`rel`, relative to the folder)
    /// can be put in place without replacing a file, a folder or a link that is not the tool's.
    pub fn check_outputs<'a>(&self, rels: impl IntoIterator<Item = &'a str>) -> Result<(), CommitError> {
        for rel in rels {
            place(&self.root, rel)?;
        }
        Ok(())
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The cache of this output folder.
    pub fn cache(&self) -> Cache {
        Cache::new(super::cache_dir(&self.root))
    }

    /// A fresh run folder to write into.
    pub fn stage(&self) -> Result<Staged<'_>, CommitError> {
        let runs = self.meta.join(RUNS);
        let run = tempfile::Builder::new().prefix("run-").tempdir_in(&runs).map_err(io(&runs))?.keep();
        Ok(Staged { dir: self, run, files: Vec::new() })
    }

    fn link_target(&self, name: &str) -> Option<PathBuf> {
        std::fs::read_link(self.meta.join(name)).ok()
    }

    /// Removes run folders other than the current and the previous one, except those holding
    /// a file the run did not write or that changed since (the user's, through the links);
    /// returns a note for each kept.
    fn remove_old_runs(&self) -> Vec<String> {
        let keep: Vec<PathBuf> = [CURRENT, PREVIOUS].iter().filter_map(|n| self.link_target(n)).collect();
        let mut notes = Vec::new();
        if let Ok(rd) = std::fs::read_dir(self.meta.join(RUNS)) {
            for e in rd.flatten() {
                let rel = Path::new(RUNS).join(e.file_name());
                if keep.contains(&rel) {
                    continue;
                }
                let foreign = users_files(&e.path());
                if foreign.is_empty() {
                    let _ = std::fs::remove_dir_all(e.path());
                } else {
                    let shown: Vec<&str> = foreign.iter().take(5).map(String::as_str).collect();
                    let more =
                        if foreign.len() > 5 { format!(" and {} more", foreign.len() - 5) } else { String::new() };
                    notes.push(format!(
                        "`{}` was kept: it holds files the run did not write or that were changed after it ({}{more}); move them out and remove the folder",
                        e.path().display(),
                        shown.join(", ")
                    ));
                }
            }
        }
        notes
    }

    /// Removes what killed runs left: run folders other than the current and previous one,
    /// links in `.spindlelab/tmp` (and the `.tmp*` links of older versions beside `current`),
    /// the tool's links that lead to no file of the committed run, temporary files of
    /// interrupted cache writes and links in the cache. Nothing outside the tool's own folders
    /// is removed unless it is a link the tool made (see [`remove_stale_links`]); a name that
    /// merely looks like the tool's (`OUT/.staging-x`, `OUT/.link-1`) is the user's.
    fn clean_leftovers(&self) -> Vec<String> {
        let mut notes = self.remove_old_runs();
        for dir in [self.meta.clone(), self.meta.join(TMP)] {
            for e in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
                let leftover = dir != self.meta || e.file_name().to_string_lossy().starts_with(".tmp");
                if leftover && e.file_type().is_ok_and(|t| t.is_symlink()) {
                    let _ = std::fs::remove_file(e.path());
                }
            }
        }
        remove_stale_links(&self.root, &self.root, 0, &mut Steps::none());
        notes.extend(self.cache().remove_links());
        if let Ok(rd) = std::fs::read_dir(super::cache_dir(&self.root)) {
            for sub in rd.flatten().filter(|e| e.file_type().is_ok_and(|t| t.is_dir())) {
                for e in std::fs::read_dir(sub.path()).into_iter().flatten().flatten() {
                    if e.file_name().to_string_lossy().starts_with(".tmp") {
                        let _ = std::fs::remove_file(e.path());
                    }
                }
            }
        }
        notes
    }
}

/// The files in a run folder that its manifest does not list with their current contents:
/// written or changed by someone else through the links. A folder without a manifest was
/// never committed, so nobody could reach it; it holds nothing of the user's.
fn users_files(run: &Path) -> Vec<String> {
    let Ok(bytes) = files::read_regular(&run.join(super::manifest::MANIFEST_FILE), 1 << 30) else {
        return Vec::new();
    };
    let Ok(manifest) = serde_json::from_slice::<super::Manifest>(&bytes) else {
        return Vec::new();
    };
    let mut found = Vec::new();
    let mut stack = vec![run.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
            let Ok(ft) = e.file_type() else { continue };
            let path = e.path();
            if ft.is_dir() {
                stack.push(path);
                continue;
            }
            if !ft.is_file() {
                continue; // a link or a pipe holds no data of anyone's
            }
            let rel = path.strip_prefix(run).unwrap_or(&path).to_string_lossy().replace('\\', "/");
            if rel == super::manifest::MANIFEST_FILE {
                continue;
            }
            let same = manifest.files.get(&rel).is_some_and(|want| {
                files::read_regular(&path, 1 << 30).is_ok_and(|b| blake3::hash(&b).to_hex().as_str() == want)
            });
            if !same {
                found.push(rel);
            }
        }
    }
    found.sort();
    found
}

fn refuse_link(path: &Path) -> Result<(), CommitError> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => Err(CommitError::ForeignLink(path.to_path_buf())),
        _ => Ok(()),
    }
}

/// Makes the output folder the user named (and the folders on its path) unless it is a folder
/// already; the user's path is followed as the system does, links included. A file, or a link
/// to nothing, at that path or on it is refused, naming it.
fn user_folder(root: &Path) -> Result<(), CommitError> {
    if std::fs::metadata(root).is_ok_and(|m| m.is_dir()) {
        return Ok(());
    }
    std::fs::create_dir_all(root).map_err(|e| {
        // The first part of the path that stands but is not a folder is the one to name.
        let mut at = PathBuf::new();
        for c in root.components() {
            at.push(c);
            let stands = std::fs::symlink_metadata(&at).is_ok();
            if stands && !std::fs::metadata(&at).is_ok_and(|m| m.is_dir()) {
                return CommitError::NotAFolder(at);
            }
        }
        io(root)(e)
    })
}

/// Makes one of the tool's own folders inside the output folder (`.spindlelab`, its `runs`),
/// never through a link, and refuses, naming it, what else stands at its name.
fn own_folder(path: &Path, purpose: &'static str) -> Result<(), CommitError> {
    for _ in 0..2 {
        match std::fs::symlink_metadata(path) {
            Ok(m) if m.file_type().is_symlink() => return Err(CommitError::ForeignLink(path.to_path_buf())),
            Ok(m) if m.is_dir() => return Ok(()),
            Ok(m) => {
                let what = if m.is_file() { "file" } else { "pipe, device or socket" };
                return Err(CommitError::InTheWay { path: path.to_path_buf(), what, purpose });
            }
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(io(path)(e)),
            Err(_) => match std::fs::create_dir(path) {
                // Made by another run in between: looked at again.
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
                made => return made.map_err(io(path)),
            },
        }
    }
    Err(io(path)(std::io::Error::other("it appeared and disappeared while the run opened the folder")))
}

/// Checks that `rel` is a plain relative path that stays inside the folder.
pub fn is_confined(rel: &str) -> bool {
    let p = Path::new(rel);
    !rel.is_empty() && p.components().all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
}

/// A run being written; nothing of it is visible until [`Staged::commit`].
#[derive(Debug)]
pub struct Staged<'a> {
    dir: &'a OutputDir,
    run: PathBuf,
    /// Files written, relative to the output folder, with their BLAKE3 hashes.
    files: Vec<(String, String)>,
}

impl Staged<'_> {
    /// Writes one file of the run (`rel` relative to the output folder).
    pub fn write(&mut self, rel: &str, bytes: &[u8]) -> Result<(), CommitError> {
        debug_assert!(is_confined(rel), "output paths are checked when the recipe is compiled");
        let path = self.run.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(io(parent))?;
        }
        let mut f = File::create(&path).map_err(io(&path))?;
        f.write_all(bytes).map_err(io(&path))?;
        f.sync_data().map_err(io(&path))?;
        self.files.retain(|(r, _)| r != rel);
        self.files.push((rel.to_string(), blake3::hash(bytes).to_hex().to_string()));
        Ok(())
    }

    /// The files written so far with their hashes.
    pub fn files(&self) -> &[(String, String)] {
        &self.files
    }

    /// Makes this run the folder's run: links every file, then switches `current` in one rename
    /// and removes the links of files the run did not write.
    ///
    /// Each link is made under a fresh name in `.spindlelab/tmp` and renamed into place: a kill
    /// at any step leaves either the previous run (the new run's own names dangle, so they read
    /// as absent) or this one (the previous run's names dangle until the next run removes them),
    /// and no temporary name outside `.spindlelab`.
    pub fn commit(self) -> Result<(), CommitError> {
        let mut steps = Steps::from_env();
        let root = &self.dir.root;
        let meta = &self.dir.meta;
        for (rel, _) in &self.files {
            if let Some((at, prefix)) = place(root, rel)? {
                self.dir.put_link(&link_text(&prefix), &at, &mut steps)?;
            }
        }
        let run_rel = Path::new(RUNS).join(self.run.file_name().unwrap_or_default());
        let old = self.dir.link_target(CURRENT);
        // `previous` first: a kill before the switch then leaves both naming the committed run,
        // and the one before it ages out as it would have after this commit.
        if let Some(old) = old.filter(|o| *o != run_rel) {
            let _ = self.dir.put_link(&old, &meta.join(PREVIOUS), &mut steps);
        }
        // The commit point.
        self.dir.put_link(&run_rel, &meta.join(CURRENT), &mut steps)?;
        if let Ok(d) = File::open(meta) {
            let _ = d.sync_all();
        }
        steps.done();
        remove_stale_links(root, root, 0, &mut steps);
        let _ = self.dir.remove_old_runs();
        steps.done();
        Ok(())
    }
}

impl OutputDir {
    /// Puts a link reading `text` at `at` (replacing the tool's link there, if any): made under
    /// a fresh name in `.spindlelab/tmp` and renamed into place. Should the rename cross file
    /// systems (a folder of the user's mounted inside the output folder), the link is made
    /// under a fresh [`NEAR_PREFIX`] name beside its place instead; either way only a name this
    /// call created is ever removed.
    fn put_link(&self, text: &Path, at: &Path, steps: &mut Steps) -> Result<(), CommitError> {
        let tmp = fresh_link(text, &self.meta.join(TMP), "link-")?;
        steps.done();
        let tmp = match std::fs::rename(&tmp, at) {
            Ok(()) => None,
            Err(e) if e.kind() == std::io::ErrorKind::CrossesDevices => {
                let _ = std::fs::remove_file(&tmp);
                let near = fresh_link(text, at.parent().unwrap_or(&self.root), NEAR_PREFIX)?;
                steps.done();
                std::fs::rename(&near, at).err().map(|e| (near, e))
            }
            Err(e) => Some((tmp, e)),
        };
        if let Some((made, e)) = tmp {
            let _ = std::fs::remove_file(&made);
            return Err(io(at)(e));
        }
        steps.done();
        Ok(())
    }
}

/// Makes a link reading `text` under a name in `dir` that did not exist (`prefix`, the process
/// id and a counter; `symlink` never replaces a name, so a taken one is skipped) and returns it.
fn fresh_link(text: &Path, dir: &Path, prefix: &str) -> Result<PathBuf, CommitError> {
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    loop {
        let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let path = dir.join(format!("{prefix}{}-{n}", std::process::id()));
        match symlink(text, &path) {
            Ok(()) => return Ok(path),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && n < u64::MAX => continue,
            Err(e) => return Err(io(dir)(e)),
        }
    }
}

/// The steps of a commit, counted so that [`FAULT_COMMIT_STEP`] can abort the process right
/// after one of them.
struct Steps {
    done: usize,
    abort_after: Option<usize>,
}

impl Steps {
    /// Counting against the hook of the environment, if set.
    fn from_env() -> Steps {
        let abort_after = std::env::var(FAULT_COMMIT_STEP).ok().and_then(|v| v.trim().parse().ok());
        Steps { done: 0, abort_after }
    }

    /// Counting only (outside a commit).
    fn none() -> Steps {
        Steps { done: 0, abort_after: None }
    }

    /// One more step is done; aborts the process if the hook asks for this one.
    fn done(&mut self) {
        self.done += 1;
        if self.abort_after == Some(self.done) {
            std::process::abort();
        }
    }
}

/// The link text for `rel` placed in the output folder: up to the folder, then through
/// `current`.
fn link_text(rel: &str) -> PathBuf {
    let depth = Path::new(rel).components().filter(|c| matches!(c, Component::Normal(_))).count() - 1;
    let mut t = PathBuf::new();
    for _ in 0..depth {
        t.push("..");
    }
    t.join(META_DIR).join(CURRENT).join(rel)
}

/// Where the output `rel` needs a link so that it is reached through `current`: `None` when a
/// link of the tool's already reaches it, else the place and the part of `rel` it stands
/// for (the topmost part that is absent or a link of the tool's). Passes through folders the
/// user made, never through a link it did not make, and never replaces the user's file or
/// folder.
fn place(root: &Path, rel: &str) -> Result<Option<(PathBuf, String)>, CommitError> {
    let mut at = root.to_path_buf();
    let mut prefix = PathBuf::new();
    let parts: Vec<_> = Path::new(rel).components().filter(|c| matches!(c, Component::Normal(_))).collect();
    for (i, c) in parts.iter().enumerate() {
        at.push(c);
        prefix.push(c);
        let last = i + 1 == parts.len();
        let prefix_text = prefix.to_string_lossy().replace('\\', "/");
        match std::fs::symlink_metadata(&at) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Some((at, prefix_text))),
            Err(e) => return Err(io(&at)(e)),
            Ok(m) if m.file_type().is_symlink() => {
                if std::fs::read_link(&at).ok().as_deref() == Some(link_text(&prefix_text).as_path()) {
                    return Ok(None);
                }
                if is_ours(&at) {
                    return Ok(Some((at, prefix_text)));
                }
                return Err(CommitError::ForeignLink(at));
            }
            Ok(m) if m.is_dir() && !last => {}
            Ok(m) if m.is_dir() => return Err(CommitError::NotOurs { path: at, what: "folder" }),
            Ok(m) if m.is_file() => return Err(CommitError::NotOurs { path: at, what: "file" }),
            Ok(_) => return Err(CommitError::Special(at)),
        }
    }
    Ok(None)
}

/// Whether a link points through some output folder's `current` (ours to replace).
fn is_ours(path: &Path) -> bool {
    std::fs::read_link(path).is_ok_and(|t| {
        let s = t.to_string_lossy();
        s.contains(&format!("{META_DIR}/{CURRENT}/")) && !t.is_absolute()
    })
}

/// Removes the tool's links whose file the committed run does not have (they dangle), and
/// links a commit made beside their place ([`NEAR_PREFIX`]) and never renamed. A link is the
/// tool's when it reads exactly what the tool writes at its place (up to the output folder,
/// then through `current`), so a link of the user's is never removed. Does not descend into
/// nested output folders (those with their own `.spindlelab`), and removes no folder: the ones
/// on an output's path are the user's.
fn remove_stale_links(root: &Path, dir: &Path, depth: usize, steps: &mut Steps) {
    if depth > 32 {
        return;
    }
    let Ok(rd) = std::fs::read_dir(dir) else { return };
    for e in rd.flatten() {
        let name = e.file_name();
        if name == META_DIR || name == ".spindlelab-cache" {
            continue;
        }
        let path = e.path();
        let Ok(ft) = e.file_type() else { continue };
        if ft.is_symlink() {
            let rel = path.strip_prefix(root).unwrap_or(&path).to_string_lossy().replace('\\', "/");
            let exact = std::fs::read_link(&path).ok().as_deref() == Some(link_text(&rel).as_path());
            let dangling = std::fs::metadata(&path).is_err();
            let near = name.to_string_lossy().starts_with(NEAR_PREFIX) && is_ours(&path);
            if (exact && dangling) || near {
                let _ = std::fs::remove_file(&path);
                steps.done();
            }
        } else if ft.is_dir() && !path.join(META_DIR).exists() {
            remove_stale_links(root, &path, depth + 1, steps);
        }
    }
}

#[cfg(unix)]
fn symlink(target: &Path, link: &Path) -> std::io::Result<()> {
    std::os::unix::fs::symlink(target, link)
}

#[cfg(not(unix))]
fn symlink(_target: &Path, _link: &Path) -> std::io::Result<()> {
    Err(std::io::Error::other("output folders need symbolic links (a Unix-like system)"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(p: &Path) -> Option<String> {
        std::fs::read_to_string(p).ok()
    }

    #[test]
    fn a_commit_replaces_the_whole_set_and_drops_files_the_new_run_did_not_write() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path().join("r");
        {
            let d = OutputDir::open(&root).unwrap();
            let mut s = d.stage().unwrap();
            s.write("a.csv", b"1").unwrap();
            s.write("sub/b.csv", b"2").unwrap();
            // Nothing is visible before the commit.
            assert_eq!(read(&root.join("a.csv")), None);
            s.commit().unwrap();
        }
        assert_eq!(read(&root.join("a.csv")).as_deref(), Some("1"));
        assert_eq!(read(&root.join("sub/b.csv")).as_deref(), Some("2"));
        {
            let d = OutputDir::open(&root).unwrap();
            let mut s = d.stage().unwrap();
            s.write("a.csv", b"3").unwrap();
            s.commit().unwrap();
        }
        assert_eq!(read(&root.join("a.csv")).as_deref(), Some("3"));
        assert!(std::fs::symlink_metadata(root.join("sub/b.csv")).is_err(), "stale file removed");
        assert!(!root.join("sub").exists(), "emptied folder removed");
        // Current and previous runs are kept; a third run removes the first.
        {
            let d = OutputDir::open(&root).unwrap();
            d.stage().unwrap().commit().unwrap();
        }
        let d = OutputDir::open(&root).unwrap();
        assert_eq!(std::fs::read_dir(root.join(META_DIR).join(RUNS)).unwrap().count(), 2);
        drop(d);
    }

    #[test]
    fn a_second_writer_is_refused_while_the_first_holds_the_folder() {
        let tmp = tempfile::tempdir().unwrap();
        let first = OutputDir::open(tmp.path()).unwrap();
        assert!(matches!(OutputDir::open(tmp.path()), Err(CommitError::Busy(_))));
        drop(first);
        OutputDir::open(tmp.path()).unwrap();
    }

    #[test]
    fn a_planted_link_is_never_written_through() {
        let tmp = tempfile::tempdir().unwrap();
        let elsewhere = tempfile::tempdir().unwrap();
        let root = tmp.path().join("r");
        std::fs::create_dir_all(&root).unwrap();
        symlink(elsewhere.path(), &root.join("sub")).unwrap();
        let d = OutputDir::open(&root).unwrap();
        let mut s = d.stage().unwrap();
        s.write("sub/x.csv", b"1").unwrap();
        assert!(matches!(s.commit(), Err(CommitError::ForeignLink(_))));
        assert_eq!(std::fs::read_dir(elsewhere.path()).unwrap().count(), 0);
    }

    #[test]
    fn a_linked_cache_folder_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let elsewhere = tempfile::tempdir().unwrap();
        symlink(elsewhere.path(), &tmp.path().join(".spindlelab-cache")).unwrap();
        assert!(matches!(OutputDir::open(tmp.path()), Err(CommitError::ForeignLink(_))));
    }

    fn run(root: &Path, files: &[(&str, &[u8])]) -> Result<(), CommitError> {
        let d = OutputDir::open(root)?;
        d.check_outputs(files.iter().map(|(r, _)| *r))?;
        let mut s = d.stage()?;
        for (rel, bytes) in files {
            s.write(rel, bytes)?;
        }
        s.commit()
    }

    #[test]
    fn a_users_file_or_folder_named_like_an_output_is_refused_and_left_alone() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path();
        std::fs::write(root.join("t.csv"), b"the user's data").unwrap();
        std::fs::create_dir_all(root.join("f.csv")).unwrap();
        for rel in ["t.csv", "f.csv", "t.csv/x.csv"] {
            let e = run(root, &[(rel, b"1")]).unwrap_err();
            assert!(matches!(e, CommitError::NotOurs { .. }), "{rel}: {e}");
            assert!(e.is_bad_input() && e.to_string().contains("did not write"), "{e}");
        }
        assert_eq!(read(&root.join("t.csv")).as_deref(), Some("the user's data"));
        assert!(root.join("f.csv").is_dir() && !std::fs::symlink_metadata(root.join("f.csv")).unwrap().is_symlink());
        // Refused at commit too, when the file appears while the run computes.
        let d = OutputDir::open(root).unwrap();
        let mut s = d.stage().unwrap();
        s.write("late.csv", b"1").unwrap();
        std::fs::write(root.join("late.csv"), b"appeared").unwrap();
        assert!(matches!(s.commit(), Err(CommitError::NotOurs { .. })));
        assert_eq!(read(&root.join("late.csv")).as_deref(), Some("appeared"));
    }

    #[test]
    fn the_users_empty_folders_outlive_every_run() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path();
        std::fs::create_dir_all(root.join("empty/deeper")).unwrap();
        std::fs::create_dir_all(root.join("sub")).unwrap();
        run(root, &[("sub/a.csv", b"1"), ("b.csv", b"2")]).unwrap();
        // The user's folder holds the run's file through a link inside it.
        assert_eq!(read(&root.join("sub/a.csv")).as_deref(), Some("1"));
        assert!(!std::fs::symlink_metadata(root.join("sub")).unwrap().is_symlink());
        run(root, &[("b.csv", b"3")]).unwrap();
        assert!(std::fs::symlink_metadata(root.join("sub/a.csv")).is_err(), "the stale link goes");
        assert!(root.join("sub").is_dir() && root.join("empty/deeper").is_dir(), "the user's folders stay");
    }

    #[test]
    fn a_name_turns_from_file_to_folder_and_back_between_runs() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path();
        run(root, &[("t.csv", b"file")]).unwrap();
        assert_eq!(read(&root.join("t.csv")).as_deref(), Some("file"));
        run(root, &[("t.csv/x.csv", b"inside")]).unwrap();
        assert_eq!(read(&root.join("t.csv/x.csv")).as_deref(), Some("inside"));
        run(root, &[("t.csv", b"file again"), ("d/e/f.csv", b"deep")]).unwrap();
        assert_eq!(read(&root.join("t.csv")).as_deref(), Some("file again"));
        assert_eq!(read(&root.join("d/e/f.csv")).as_deref(), Some("deep"));
        run(root, &[("d/e.csv", b"shallow")]).unwrap();
        assert_eq!(read(&root.join("d/e.csv")).as_deref(), Some("shallow"));
        assert!(std::fs::symlink_metadata(root.join("t.csv")).is_err());
    }

    #[test]
    fn a_run_folder_holding_the_users_files_is_kept_and_said() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path();
        let manifest = |n: &str| {
            let m = format!(
                r#"{{"tool":"t","recipe_name":"r","recipe_hash":"h","recipe_path":"p","seconds":0,"cache_hits":0,"computed":0,"nodes":[],"outputs":[],"files":{{"sub/a.csv":"{}"}}}}"#,
                blake3::hash(n.as_bytes()).to_hex()
            );
            m.into_bytes()
        };
        run(root, &[("sub/a.csv", b"1"), ("manifest.json", &manifest("1"))]).unwrap();
        // The user saves a note into the output's folder and edits the output in place.
        std::fs::write(root.join("sub/note.txt"), b"mine").unwrap();
        run(root, &[("sub/a.csv", b"2"), ("manifest.json", &manifest("2"))]).unwrap();
        run(root, &[("sub/a.csv", b"3"), ("manifest.json", &manifest("3"))]).unwrap();
        let d = OutputDir::open(root).unwrap();
        let note = d.notes().iter().find(|n| n.contains("note.txt")).expect("the kept run is said");
        assert!(note.contains("was kept"), "{note}");
        let runs = std::fs::read_dir(root.join(META_DIR).join(RUNS)).unwrap().count();
        assert_eq!(runs, 3, "current, previous and the run holding the note");
        // An untouched run ages out as before.
        drop(d);
        run(root, &[("sub/a.csv", b"4"), ("manifest.json", &manifest("4"))]).unwrap();
        assert_eq!(std::fs::read_dir(root.join(META_DIR).join(RUNS)).unwrap().count(), 3);
    }

    #[cfg(unix)]
    #[test]
    fn a_linked_or_special_lock_is_refused_and_nothing_is_created_where_it_points() {
        let tmp = tempfile::tempdir().unwrap();
        let elsewhere = tempfile::tempdir().unwrap();
        let root = tmp.path().join("r");
        std::fs::create_dir_all(root.join(META_DIR)).unwrap();
        let target = elsewhere.path().join("created");
        symlink(&target, &root.join(META_DIR).join(LOCK)).unwrap();
        assert!(matches!(OutputDir::open(&root), Err(CommitError::ForeignLink(_))));
        assert!(!target.exists());
        std::fs::remove_file(root.join(META_DIR).join(LOCK)).unwrap();
        let c = std::ffi::CString::new(root.join(META_DIR).join(LOCK).as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        assert!(matches!(OutputDir::open(&root), Err(CommitError::Special(_))));
    }

    #[cfg(unix)]
    #[test]
    fn links_in_the_cache_are_removed_not_followed_and_said() {
        use crate::node::Outputs;
        let tmp = tempfile::tempdir().unwrap();
        let elsewhere = tempfile::tempdir().unwrap();
        let root = tmp.path();
        let key = "ab".repeat(32);
        let cache_dir = super::super::cache_dir(root);
        std::fs::create_dir_all(&cache_dir).unwrap();
        symlink(elsewhere.path(), &cache_dir.join("ab")).unwrap();
        let cache = Cache::new(&cache_dir);
        assert!(matches!(cache.lookup(&key), super::super::Lookup::Damaged(_)));
        let d = OutputDir::open(root).unwrap();
        assert!(d.notes().iter().any(|n| n.contains("symbolic link")), "{:?}", d.notes());
        d.cache().put(&key, &Outputs::new(), &[]).unwrap();
        assert_eq!(std::fs::read_dir(elsewhere.path()).unwrap().count(), 0, "wrote through the link");
        assert!(d.cache().contains(&key));
        assert_eq!(d.cache().usage().0, 1);
        // An entry that is a link to a device, or a pipe, is damage: never read, never waited on.
        let entry = cache_dir.join("ab").join(format!("{key}.bin"));
        std::fs::remove_file(&entry).unwrap();
        symlink(Path::new("/dev/zero"), &entry).unwrap();
        assert!(matches!(cache.lookup(&key), super::super::Lookup::Damaged(m) if m.contains("link")));
        std::fs::remove_file(&entry).unwrap();
        let c = std::ffi::CString::new(entry.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        assert!(matches!(cache.lookup(&key), super::super::Lookup::Damaged(m) if m.contains("regular")));
        // A put replaces the pipe by an entry.
        d.cache().put(&key, &Outputs::new(), &[]).unwrap();
        assert!(cache.contains(&key));
    }

    #[test]
    fn an_entry_whose_length_disagrees_with_its_header_is_damage() {
        use crate::node::Outputs;
        let tmp = tempfile::tempdir().unwrap();
        let cache = Cache::new(tmp.path());
        let key = "cd".repeat(32);
        cache.put(&key, &Outputs::new(), &["w".into()]).unwrap();
        let entry = tmp.path().join("cd").join(format!("{key}.bin"));
        let mut bytes = std::fs::read(&entry).unwrap();
        bytes.extend_from_slice(&[0; 16]);
        std::fs::write(&entry, &bytes).unwrap();
        assert!(matches!(cache.lookup(&key), super::super::Lookup::Damaged(m) if m.contains("declares")));
    }

    #[cfg(unix)]
    #[test]
    fn only_the_tools_own_links_are_removed_as_stale() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path();
        run(root, &[("a.csv", b"1")]).unwrap();
        // The user's dangling links: one to nowhere, one reading like the tool's link of
        // another name.
        symlink(Path::new("nowhere"), &root.join("mine")).unwrap();
        symlink(&link_text("gone.csv"), &root.join("other.csv")).unwrap();
        run(root, &[("c.csv", b"2")]).unwrap();
        assert!(std::fs::symlink_metadata(root.join("a.csv")).is_err(), "the tool's stale link goes");
        for kept in ["mine", "other.csv"] {
            assert!(std::fs::symlink_metadata(root.join(kept)).is_ok(), "the user's `{kept}` was removed");
        }
        let tmp_links = std::fs::read_dir(root.join(META_DIR).join(TMP)).unwrap().count();
        assert_eq!(tmp_links, 0, "a commit leaves nothing in .spindlelab/tmp");
    }

    #[test]
    fn confined_paths() {
        assert!(is_confined("a.csv") && is_confined("sub/a.csv") && is_confined("./a.csv"));
        assert!(!is_confined("../a.csv") && !is_confined("/etc/x") && !is_confined("a/../../b") && !is_confined(""));
    }
}
