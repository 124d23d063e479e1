//! An output folder whose readers always see one complete run.
//!
//! Layout of an output folder `OUT`:
//!
//! ```text
//! OUT/.spindlelab/lock            held (exclusive) by the run that writes OUT
//! OUT/.spindlelab/runs/run-XXXX/  one folder per run: its files and manifest.json
//! OUT/.spindlelab/current         symbolic link → runs/run-XXXX, the committed run
//! OUT/<file>                      symbolic link → .spindlelab/current/<file>
//! OUT/.spindlelab-cache/          the cache (see [`super::Cache`])
//! ```
//!
//! A run writes every file into a fresh run folder, then switches `current` by renaming a new
//! link over it: that rename is the single commit point, so a run killed at any moment leaves
//! the previous run whole, and a reader never sees files of two runs. A file the new run does
//! not write disappears with the switch (its link dangles and is removed). The run before the
//! committed one is kept until the next run; older run folders, staging folders of killed
//! runs and the cache's temporary files are removed when the next run takes the lock.

use super::Cache;
use std::fs::File;
use std::io::Write;
use std::path::{Component, Path, PathBuf};

/// The folder inside an output folder that holds runs, the lock and the `current` link.
pub const META_DIR: &str = ".spindlelab";
const RUNS: &str = "runs";
const CURRENT: &str = "current";
const PREVIOUS: &str = "previous";
const LOCK: &str = "lock";

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
}

impl OutputDir {
    /// Creates `root` if needed, takes its lock (refusing if another run holds it) and removes
    /// what killed runs left behind.
    pub fn open(root: &Path) -> Result<OutputDir, CommitError> {
        std::fs::create_dir_all(root).map_err(io(root))?;
        let meta = root.join(META_DIR);
        refuse_link(&meta)?;
        refuse_link(&super::cache_dir(root))?;
        std::fs::create_dir_all(meta.join(RUNS)).map_err(io(&meta))?;
        refuse_link(&meta.join(RUNS))?;
        let lock_path = meta.join(LOCK);
        let lock = File::options().create(true).truncate(false).write(true).open(&lock_path).map_err(io(&lock_path))?;
        match lock.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => return Err(CommitError::Busy(root.to_path_buf())),
            Err(std::fs::TryLockError::Error(e)) => return Err(io(&lock_path)(e)),
        }
        let dir = OutputDir { root: root.to_path_buf(), meta, _lock: lock };
        dir.clean_leftovers();
        Ok(dir)
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

    /// Removes run folders other than the current and the previous one.
    fn remove_old_runs(&self) {
        let keep: Vec<PathBuf> = [CURRENT, PREVIOUS].iter().filter_map(|n| self.link_target(n)).collect();
        if let Ok(rd) = std::fs::read_dir(self.meta.join(RUNS)) {
            for e in rd.flatten() {
                let rel = Path::new(RUNS).join(e.file_name());
                if !keep.contains(&rel) {
                    let _ = std::fs::remove_dir_all(e.path());
                }
            }
        }
    }

    /// Removes run folders other than the current and previous one, staging folders of the
    /// older layout and temporary files of interrupted cache writes.
    fn clean_leftovers(&self) {
        self.remove_old_runs();
        if let Ok(rd) = std::fs::read_dir(&self.meta) {
            for e in rd.flatten() {
                if e.file_name().to_string_lossy().starts_with(".tmp") {
                    let _ = std::fs::remove_file(e.path());
                }
            }
        }
        if let Ok(rd) = std::fs::read_dir(&self.root) {
            for e in rd.flatten() {
                if e.file_name().to_string_lossy().starts_with(".staging-") {
                    let _ = std::fs::remove_dir_all(e.path());
                }
            }
        }
        if let Ok(rd) = std::fs::read_dir(super::cache_dir(&self.root)) {
            for sub in rd.flatten().filter(|e| e.file_type().is_ok_and(|t| t.is_dir())) {
                for e in std::fs::read_dir(sub.path()).into_iter().flatten().flatten() {
                    if e.file_name().to_string_lossy().starts_with(".tmp") {
                        let _ = std::fs::remove_file(e.path());
                    }
                }
            }
        }
    }
}

fn refuse_link(path: &Path) -> Result<(), CommitError> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => Err(CommitError::ForeignLink(path.to_path_buf())),
        _ => Ok(()),
    }
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
    pub fn commit(self) -> Result<(), CommitError> {
        let root = &self.dir.root;
        let meta = &self.dir.meta;
        for (rel, _) in &self.files {
            link_file(root, rel)?;
        }
        let run_rel = Path::new(RUNS).join(self.run.file_name().unwrap_or_default());
        let old = self.dir.link_target(CURRENT);
        switch_link(meta, CURRENT, &run_rel)?;
        if let Some(old) = old.filter(|o| *o != run_rel) {
            let _ = switch_link(meta, PREVIOUS, &old);
        }
        if let Ok(d) = File::open(meta) {
            let _ = d.sync_all();
        }
        remove_dangling_links(root, 0);
        self.dir.remove_old_runs();
        Ok(())
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

/// Creates (or keeps) `root/rel` as a link through `current`, refusing to pass through any
/// link on the way: a planted link could lead out of the folder.
fn link_file(root: &Path, rel: &str) -> Result<(), CommitError> {
    let mut at = root.to_path_buf();
    let parts: Vec<_> = Path::new(rel).components().filter(|c| matches!(c, Component::Normal(_))).collect();
    for (i, c) in parts.iter().enumerate() {
        at.push(c);
        let last = i + 1 == parts.len();
        match std::fs::symlink_metadata(&at) {
            Ok(m) if m.file_type().is_symlink() => {
                if last && std::fs::read_link(&at).ok().as_deref() == Some(link_text(rel).as_path()) {
                    return Ok(());
                }
                if !last || !is_ours(&at) {
                    return Err(CommitError::ForeignLink(at));
                }
            }
            Ok(m) if !last && m.is_dir() => continue,
            Ok(_) if !last => return Err(CommitError::ForeignLink(at)),
            Ok(m) if m.is_dir() => return Err(CommitError::ForeignLink(at)),
            Ok(_) => {} // a plain file of the older layout: replaced by the link below
            Err(_) if !last => {
                std::fs::create_dir(&at).map_err(io(&at))?;
                continue;
            }
            Err(_) => {}
        }
        if last {
            let parent = at.parent().unwrap_or(root);
            let tmp = parent.join(format!(".link-{}", std::process::id()));
            let _ = std::fs::remove_file(&tmp);
            symlink(&link_text(rel), &tmp).map_err(io(&tmp))?;
            std::fs::rename(&tmp, &at).map_err(io(&at))?;
        }
    }
    Ok(())
}

/// Whether a link points through some output folder's `current` (ours to replace).
fn is_ours(path: &Path) -> bool {
    std::fs::read_link(path).is_ok_and(|t| {
        let s = t.to_string_lossy();
        s.contains(&format!("{META_DIR}/{CURRENT}/")) && !t.is_absolute()
    })
}

fn switch_link(meta: &Path, name: &str, target: &Path) -> Result<(), CommitError> {
    let tmp = meta.join(format!(".tmp-{name}-{}", std::process::id()));
    let _ = std::fs::remove_file(&tmp);
    symlink(target, &tmp).map_err(io(&tmp))?;
    std::fs::rename(&tmp, meta.join(name)).map_err(io(meta))
}

/// Removes links through `current` whose file the committed run does not have. Does not
/// descend into nested output folders (those with their own `.spindlelab`).
fn remove_dangling_links(dir: &Path, depth: usize) {
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
            if is_ours(&path) && std::fs::metadata(&path).is_err() {
                let _ = std::fs::remove_file(&path);
            }
        } else if ft.is_dir() && !path.join(META_DIR).exists() {
            remove_dangling_links(&path, depth + 1);
            // A folder left empty by removed links goes too.
            let _ = std::fs::remove_dir(&path);
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

    #[test]
    fn confined_paths() {
        assert!(is_confined("a.csv") && is_confined("sub/a.csv") && is_confined("./a.csv"));
        assert!(!is_confined("../a.csv") && !is_confined("/etc/x") && !is_confined("a/../../b") && !is_confined(""));
    }
}
