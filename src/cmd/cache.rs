//! `cache du | gc | clean`: the cache of output folders seen and bounded.

use crate::*;

/// The output folders a `cache` command acts on: those named, or every folder under `out/`
/// that has a cache.
pub(crate) fn cache_folders(named: Vec<PathBuf>) -> Vec<PathBuf> {
    if !named.is_empty() {
        return named;
    }
    let mut found: Vec<PathBuf> = std::fs::read_dir("out")
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| engine::exec::cache_dir(p).is_dir())
        .collect();
    found.sort();
    found
}

pub(crate) fn human_bytes(b: u64) -> String {
    match b {
        b if b >= 1 << 30 => format!("{:.1} GiB", b as f64 / (1u64 << 30) as f64),
        b if b >= 1 << 20 => format!("{:.1} MiB", b as f64 / (1u64 << 20) as f64),
        b if b >= 1 << 10 => format!("{:.1} KiB", b as f64 / 1024.0),
        b => format!("{b} B"),
    }
}

pub(crate) fn cache_command(action: CacheAction) -> ExitCode {
    use engine::exec::{Cache, Manifest, OutputDir, commit::META_DIR};
    let (folders, verb) = match action {
        CacheAction::Du { cache: Some(dir), .. } => return shared_cache_command(&dir, "du", &[], None),
        CacheAction::Gc { cache: Some(dir), folders, max_size } => {
            return shared_cache_command(&dir, "gc", &folders, max_size);
        }
        CacheAction::Clean { cache: Some(dir), .. } => return shared_cache_command(&dir, "clean", &[], None),
        CacheAction::Du { folders, .. } => (cache_folders(folders), "du"),
        CacheAction::Gc { max_size: Some(_), .. } => {
            eoutln!("error: --max-size bounds a shared cache: name it with --cache DIR");
            return ExitCode::from(EXIT_BAD_INPUT);
        }
        CacheAction::Gc { folders, .. } => (cache_folders(folders), "gc"),
        CacheAction::Clean { folders, .. } => (cache_folders(folders), "clean"),
    };
    let mut code = ExitCode::SUCCESS;
    for folder in folders {
        let cache = Cache::new(engine::exec::cache_dir(&folder));
        // The output folder's own cache is the tool's: a link there is never followed, not even
        // to measure what it leads to.
        if std::fs::symlink_metadata(cache.dir()).is_ok_and(|m| m.file_type().is_symlink()) {
            eoutln!(
                "error: `{}` is a symbolic link inside the output folder; spindlelab never follows links it did not make (remove it, or name a shared cache with --cache DIR)",
                esc(cache.dir().display())
            );
            code = ExitCode::from(EXIT_BAD_INPUT);
            continue;
        }
        if !cache.dir().is_dir() {
            outln!("{}: no cache", folder.display());
            continue;
        }
        if verb == "du" {
            let (n, bytes) = cache.usage();
            outln!("{}: {n} entries, {}", folder.display(), human_bytes(bytes));
            continue;
        }
        // Changing the cache needs the folder: not while a run uses it.
        let _held = match OutputDir::open(&folder) {
            Ok(d) => d,
            Err(e) => {
                eoutln!("error: {}", esc(&e));
                code = ExitCode::from(if e.is_bad_input() { EXIT_BAD_INPUT } else { EXIT_FAILURE });
                continue;
            }
        };
        let (n, bytes) = if verb == "clean" {
            cache.retain(|_| false)
        } else {
            let meta = folder.join(META_DIR);
            let keep: std::collections::HashSet<String> = ["current", "previous"]
                .iter()
                .filter_map(|run| Manifest::read(&meta.join(run)))
                .flat_map(|m| m.nodes.into_iter().map(|n| n.key))
                .collect();
            cache.retain(|k| keep.contains(k))
        };
        outln!("{}: removed {n} entries, {}", folder.display(), human_bytes(bytes));
    }
    code
}

/// `cache du|gc|clean --cache DIR`: the same on a cache folder that runs and machines share.
/// Nothing is locked (entries are written by rename and checked on read); `gc` keeps what the
/// latest two runs of each named output folder used and, with `max_size`, the entries written
/// last that fit.
pub(crate) fn shared_cache_command(dir: &Path, verb: &str, folders: &[PathBuf], max_size: Option<u64>) -> ExitCode {
    use engine::exec::{Cache, Manifest, commit::META_DIR};
    let cache = Cache::new(dir);
    if !dir.is_dir() {
        outln!("{}: no cache", esc(dir.display()));
        return ExitCode::SUCCESS;
    }
    let (n, bytes) = match verb {
        "du" => {
            let (n, bytes) = cache.usage();
            outln!("{}: {n} entries, {}", esc(dir.display()), human_bytes(bytes));
            return ExitCode::SUCCESS;
        }
        "clean" => cache.retain(|_| false),
        _ => {
            if folders.is_empty() && max_size.is_none() {
                eoutln!(
                    "error: gc of a shared cache keeps what named output folders used, or what fits a size: name folders, or give --max-size"
                );
                return ExitCode::from(EXIT_BAD_INPUT);
            }
            let (mut n, mut bytes) = (0, 0);
            if !folders.is_empty() {
                let keep: std::collections::HashSet<String> = folders
                    .iter()
                    .flat_map(|f| ["current", "previous"].map(|run| f.join(META_DIR).join(run)))
                    .filter_map(|m| Manifest::read(&m))
                    .flat_map(|m| m.nodes.into_iter().map(|n| n.key))
                    .collect();
                (n, bytes) = cache.retain(|k| keep.contains(k));
            }
            if let Some(max) = max_size {
                let (m, b) = cache.within(max);
                (n, bytes) = (n + m, bytes + b);
            }
            (n, bytes)
        }
    };
    outln!("{}: removed {n} entries, {}", esc(dir.display()), human_bytes(bytes));
    ExitCode::SUCCESS
}
