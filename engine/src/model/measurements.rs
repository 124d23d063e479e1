//! The `measurements:` section: measured FRF files named once, by list or glob, each with
//! what the recipe states about them (direction, speed, units).
//!
//! A measurement set becomes a step of the same name swept over its files, of the kind the
//! registry names as the measurement reader (the built-in `read.frf`), so
//! `@tool_tip.frf` is every measured FRF and any step fed by it runs once per file (the
//! graph's fan-out). Model steps take direction and speed from the FRF they are fed (a
//! spindle model on `grid: @tool_tip.frf`), which pairs each prediction with its
//! measurement by construction. What a file's header says must agree with what the recipe
//! states; the reader checks that when it reads the file.

use crate::diag::{Diagnostics, Span};
use crate::node::MEASUREMENT_PARAMS;
use crate::spec::suggest;
use crate::syntax::{Key, Raw, RawKind};

const MEASUREMENT_KEYS: &[&str] = &["files", "format", "direction", "speed", "units", "description"];

/// Largest number of files one measurement set may name: a set is a test campaign, not a
/// data lake, and every file becomes a node instance.
pub const MAX_FILES: usize = 10_000;

/// Deepest a `**` in a glob reaches below the folder it starts from.
pub const MAX_GLOB_DEPTH: usize = 8;

/// Most folder entries one glob may look through: a glob names the files of a test campaign,
/// and stops with an error rather than walk a whole disk.
pub const MAX_GLOB_ENTRIES: usize = 100_000;

/// Rewrites `measurements:` into steps of the `reader` kind, appended to `steps:`. `base_dir`
/// is the recipe's folder, against which file names and globs are resolved.
pub fn desugar(raw: &Raw, base_dir: Option<&std::path::Path>, reader: Option<&str>, diags: &mut Diagnostics) -> Raw {
    let Some(section) = raw.get("measurements") else { return raw.clone() };
    let Some(reader) = reader else {
        diags.error_help(
            Some(&section.span),
            "this program has no node kind that reads a measurement set's files",
            "read the files with explicit steps instead of `measurements:`",
        );
        return raw.clone();
    };
    let Some(sets) = section.as_map() else {
        diags.error_help(
            Some(&section.span),
            format!("`measurements` must map set names to files, found {}", section.describe()),
            "write e.g. `measurements: { tool_tip: { files: \"frf_*.csv\" } }`",
        );
        return raw.clone();
    };
    let step_names: Vec<&str> =
        raw.get("steps").and_then(Raw::as_map).unwrap_or(&[]).iter().map(|(k, _)| k.name.as_str()).collect();
    let mut new_steps: Vec<(Key, Raw)> = Vec::new();
    for (name, set) in sets {
        if step_names.contains(&name.name.as_str()) {
            diags.error_help(
                Some(&name.span),
                format!("measurement set `{}` has the name of a step", name.name),
                "a measurement set is read by a step of its own name; rename one of them",
            );
            continue;
        }
        if let Some(step) = measurement_step(name, set, base_dir, reader, diags) {
            new_steps.push((name.clone(), step));
        }
    }
    let mut out = raw.clone();
    if let RawKind::Map(top) = &mut out.kind {
        match top.iter_mut().find(|(k, _)| k.name == "steps") {
            Some((_, Raw { kind: RawKind::Map(steps), .. })) => steps.extend(new_steps),
            Some(_) => {}
            None => top.push((
                Key { name: "steps".into(), span: section.span.clone() },
                Raw { span: section.span.clone(), kind: RawKind::Map(new_steps) },
            )),
        }
    }
    out
}

fn text(s: &str, span: &Span) -> Raw {
    Raw { span: span.clone(), kind: RawKind::Str(s.to_string()) }
}

fn key(s: &str, span: &Span) -> Key {
    Key { name: s.to_string(), span: span.clone() }
}

/// The reader step of one measurement set.
fn measurement_step(
    name: &Key,
    set: &Raw,
    base_dir: Option<&std::path::Path>,
    reader: &str,
    diags: &mut Diagnostics,
) -> Option<Raw> {
    // A bare file name or glob is a set of its own.
    let (files_raw, entries): (&Raw, &[(Key, Raw)]) = match &set.kind {
        RawKind::Str(_) | RawKind::Seq(_) => (set, &[]),
        RawKind::Map(entries) => match set.get("files") {
            Some(f) => (f, entries),
            None => {
                diags.error_help(
                    Some(&set.span),
                    format!("measurement set `{}` names no `files`", name.name),
                    "add `files: \"frf_*.csv\"` (a glob or a list of files, relative to the recipe's folder)",
                );
                return None;
            }
        },
        _ => {
            diags.error_help(
                Some(&set.span),
                format!("measurement set `{}` must be a file, a list of files or a mapping", name.name),
                "write e.g. `tool_tip: { files: \"frf_*.csv\", units: m/N }`",
            );
            return None;
        }
    };
    for (k, _) in entries {
        if !MEASUREMENT_KEYS.contains(&k.name.as_str()) {
            let help = suggest(&k.name, MEASUREMENT_KEYS.iter().copied())
                .map(|s| format!("did you mean `{s}`?"))
                .unwrap_or_else(|| format!("known keys: {}", MEASUREMENT_KEYS.join(", ")));
            diags.error_help(
                Some(&k.span),
                format!("unknown key `{}` in measurement set `{}`", k.name, name.name),
                help,
            );
        }
    }
    let patterns: Vec<&Raw> = match &files_raw.kind {
        RawKind::Str(_) => vec![files_raw],
        RawKind::Seq(items) => items.iter().collect(),
        _ => {
            diags.error(Some(&files_raw.span), "`files` must be a file name, a glob or a list of them");
            return None;
        }
    };
    let mut files: Vec<Raw> = Vec::new();
    for p in patterns {
        let Some(pattern) = p.as_str() else {
            diags.error(Some(&p.span), format!("a file name must be text, found {}", p.describe()));
            continue;
        };
        if !pattern.contains(['*', '?', '[']) {
            // A plain name: the file check (existence, hash) is the resolver's.
            files.push(p.clone());
            continue;
        }
        let glob = match Glob::parse(pattern) {
            Ok(g) => g,
            Err((message, help)) => {
                diags.error_help(Some(&p.span), message, help);
                continue;
            }
        };
        let root = match base_dir {
            Some(b) if !b.as_os_str().is_empty() => b,
            _ => std::path::Path::new("."),
        };
        let mut found = match glob.expand(root) {
            Ok(found) => found,
            Err(Stop::Entries) => {
                diags.error_help(
                    Some(&p.span),
                    format!("`{pattern}` looks through more than {MAX_GLOB_ENTRIES} folder entries"),
                    "name the folder the files are in (`measured/frf_*.csv` rather than `**/frf_*.csv`)",
                );
                continue;
            }
            Err(Stop::Files) => {
                diags.error_help(
                    Some(&p.span),
                    format!("`{pattern}` matches more than {MAX_FILES} files"),
                    "narrow the glob, or split the set",
                );
                continue;
            }
        };
        if found.is_empty() {
            diags.error_help(
                Some(&p.span),
                format!("`{pattern}` matches no file"),
                "globs are relative to the recipe's folder; check the pattern",
            );
            continue;
        }
        found.sort();
        found.dedup();
        files.extend(found.iter().map(|f| text(f, &p.span)));
    }
    if files.is_empty() {
        return None;
    }
    let span = &name.span;
    let mut params: Vec<(Key, Raw)> = Vec::new();
    for &k in MEASUREMENT_PARAMS.iter().filter(|&&k| k != "file") {
        if let Some((key_, v)) = entries.iter().find(|(kk, _)| kk.name == k) {
            params.push((key_.clone(), v.clone()));
        }
    }
    let mut step = vec![(key("kind", span), text(reader, span))];
    if files.len() == 1 {
        params.push((key("file", &files[0].span), files.remove(0)));
    } else {
        let list = Raw { span: files_raw.span.clone(), kind: RawKind::Seq(files) };
        step.push((
            key("sweep", span),
            Raw { span: span.clone(), kind: RawKind::Map(vec![(key("file", span), list)]) },
        ));
    }
    step.push((key("params", span), Raw { span: span.clone(), kind: RawKind::Map(params) }));
    if let Some((k, v)) = entries.iter().find(|(k, _)| k.name == "description") {
        step.push((k.clone(), v.clone()));
    }
    Some(Raw { span: set.span.clone(), kind: RawKind::Map(step) })
}

/// One component of a glob.
enum Part {
    /// A name without wildcards, taken as it is.
    Name(String),
    /// A name with wildcards (`frf_*.csv`), matched against a folder's entries.
    Wild(glob::Pattern),
    /// `**`: any number of folders, up to [`MAX_GLOB_DEPTH`].
    AnyDepth,
}

/// Why a glob's expansion stopped.
#[derive(Debug)]
enum Stop {
    Entries,
    Files,
}

/// A glob of a measurement set, checked before any folder is read: relative to the recipe's
/// folder, without `..`, with at most one `**`.
struct Glob {
    parts: Vec<Part>,
}

impl Glob {
    /// The components of `pattern`, or the message and help of why it is refused.
    fn parse(pattern: &str) -> Result<Glob, (String, String)> {
        use std::path::{Component, Path};
        let refuse = |message: String, help: &str| Err((message, help.to_string()));
        if let Err(e) = glob::Pattern::new(pattern) {
            return refuse(format!("`{pattern}` is not a valid glob: {e}"), "e.g. `frf_*rpm.csv`");
        }
        let path = Path::new(pattern);
        if path.has_root() || path.is_absolute() || pattern.starts_with(['/', '\\']) {
            return refuse(
                format!("`{pattern}` is an absolute glob"),
                "data files are named relative to the recipe's folder: write e.g. `measured/frf_*.csv`",
            );
        }
        let mut parts = Vec::new();
        for c in path.components() {
            match c {
                Component::CurDir => {}
                Component::ParentDir => {
                    return refuse(
                        format!("`{pattern}` leads out of the recipe's folder with `..`"),
                        "a glob looks only below the recipe's folder: move the recipe beside its data, \
                         or name each file outside it without wildcards",
                    );
                }
                Component::Normal(name) => {
                    let name = name.to_string_lossy();
                    if name == "**" {
                        parts.push(Part::AnyDepth);
                    } else if name.contains(['*', '?', '[']) {
                        match glob::Pattern::new(&name) {
                            Ok(p) => parts.push(Part::Wild(p)),
                            Err(e) => {
                                return refuse(format!("`{pattern}` is not a valid glob: {e}"), "e.g. `frf_*rpm.csv`");
                            }
                        }
                    } else {
                        parts.push(Part::Name(name.into_owned()));
                    }
                }
                Component::RootDir | Component::Prefix(_) => {
                    return refuse(
                        format!("`{pattern}` is an absolute glob"),
                        "data files are named relative to the recipe's folder: write e.g. `measured/frf_*.csv`",
                    );
                }
            }
        }
        if parts.iter().filter(|p| matches!(p, Part::AnyDepth)).count() > 1 {
            return refuse(
                format!("`{pattern}` has more than one `**`"),
                "use one `**` at most (e.g. `measured/**/frf_*.csv`), or name the folders",
            );
        }
        Ok(Glob { parts })
    }

    /// The files under `root` the glob matches, as paths relative to `root`. Folders are read
    /// only where a wildcard needs them, `**` follows no symbolic link and reaches
    /// [`MAX_GLOB_DEPTH`] folders down; more than [`MAX_GLOB_ENTRIES`] entries looked at or
    /// [`MAX_FILES`] files found stops the walk.
    fn expand(&self, root: &std::path::Path) -> Result<Vec<String>, Stop> {
        self.expand_within(root, MAX_GLOB_ENTRIES, MAX_FILES)
    }

    /// [`Glob::expand`] with the limits given.
    fn expand_within(&self, root: &std::path::Path, max_entries: usize, max_files: usize) -> Result<Vec<String>, Stop> {
        let mut walk = Walk { entries: 0, max_entries, max_files, found: Vec::new() };
        walk.visit(root, std::path::PathBuf::new(), &self.parts, 0)?;
        Ok(walk.found)
    }
}

/// The state of one glob's walk: entries looked at, files found.
struct Walk {
    entries: usize,
    max_entries: usize,
    max_files: usize,
    found: Vec<String>,
}

impl Walk {
    /// Matches `parts` below `dir` (which is `rel` under the root); `depth` counts the folders
    /// a `**` has gone down.
    fn visit(
        &mut self,
        dir: &std::path::Path,
        rel: std::path::PathBuf,
        parts: &[Part],
        depth: usize,
    ) -> Result<(), Stop> {
        let Some((first, rest)) = parts.split_first() else {
            if dir.is_file() {
                if self.found.len() == self.max_files {
                    return Err(Stop::Files);
                }
                self.found.push(rel.display().to_string());
            }
            return Ok(());
        };
        match first {
            Part::Name(name) => {
                let next = dir.join(name);
                if rest.is_empty() || next.is_dir() {
                    self.visit(&next, rel.join(name), rest, depth)?;
                }
            }
            Part::Wild(pattern) => {
                for (name, _) in self.entries_of(dir)? {
                    let next = dir.join(&name);
                    if pattern.matches(&name) && (rest.is_empty() || next.is_dir()) {
                        self.visit(&next, rel.join(&name), rest, depth)?;
                    }
                }
            }
            Part::AnyDepth => {
                // Zero folders, then one more folder and `**` again.
                self.visit(dir, rel.clone(), rest, depth)?;
                if depth < MAX_GLOB_DEPTH {
                    for (name, is_dir) in self.entries_of(dir)? {
                        if is_dir {
                            self.visit(&dir.join(&name), rel.join(&name), parts, depth + 1)?;
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// The entries of a folder, by name, with whether each is a folder (not following a
    /// symbolic link), counted against [`MAX_GLOB_ENTRIES`]; a folder that cannot be read has
    /// none.
    fn entries_of(&mut self, dir: &std::path::Path) -> Result<Vec<(String, bool)>, Stop> {
        let Ok(read) = std::fs::read_dir(dir) else { return Ok(Vec::new()) };
        let mut out = Vec::new();
        for entry in read {
            self.entries += 1;
            if self.entries > self.max_entries {
                return Err(Stop::Entries);
            }
            let Ok(entry) = entry else { continue };
            let is_dir = entry.file_type().is_ok_and(|t| t.is_dir());
            out.push((entry.file_name().to_string_lossy().into_owned(), is_dir));
        }
        // Names in order, so that which files are found before a limit does not depend on the
        // file system's order.
        out.sort();
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs;

    fn refused(pattern: &str) -> String {
        match Glob::parse(pattern) {
            Ok(_) => panic!("`{pattern}` was accepted"),
            Err((message, help)) => format!("{message} / {help}"),
        }
    }

    #[test]
    fn globs_that_leave_the_recipe_folder_or_repeat_any_depth_are_refused_before_any_walk() {
        assert!(refused("/**/*.csv").contains("is an absolute glob"));
        assert!(refused("/data/*.csv").contains("relative to the recipe's folder"));
        assert!(refused("../../../../../../**/*.csv").contains("leads out of the recipe's folder with `..`"));
        assert!(refused("data/../../x/*.csv").contains("`..`"));
        assert!(refused("a/**/b/**/*.csv").contains("more than one `**`"));
        assert!(refused("a**/*.csv").contains("not a valid glob"));
        assert!(refused("data/[x.csv").contains("not a valid glob"));
        for ok in ["frf_*.csv", "./data/*.csv", "data/**/frf_?.csv", "**/*.csv", "a/[xy]/*.csv"] {
            assert!(Glob::parse(ok).is_ok(), "{ok}");
        }
    }

    #[test]
    fn a_glob_matches_by_component_and_names_files_relative_to_the_root() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        for f in ["data/x/frf_1.csv", "data/y/frf_2.csv", "data/y/other.txt", "data/frf_0.csv", "top.csv"] {
            fs::create_dir_all(root.join(f).parent().unwrap()).unwrap();
            fs::write(root.join(f), "").unwrap();
        }
        let expand = |p: &str| {
            let mut v = Glob::parse(p).unwrap().expand(root).unwrap();
            v.sort();
            v
        };
        assert_eq!(expand("data/*/frf_*.csv"), ["data/x/frf_1.csv", "data/y/frf_2.csv"]);
        assert_eq!(expand("./data/**/frf_*.csv"), ["data/frf_0.csv", "data/x/frf_1.csv", "data/y/frf_2.csv"]);
        assert_eq!(expand("**/*.csv").len(), 4);
        assert_eq!(expand("data/[xy]/*.txt"), ["data/y/other.txt"]);
        assert!(expand("none/*.csv").is_empty());
        assert!(expand("data/*").iter().all(|f| f == "data/frf_0.csv"), "folders are not files");
    }

    #[test]
    fn any_depth_stops_at_its_depth_and_a_walk_at_its_entry_and_file_limits() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        let mut deep = root.to_path_buf();
        for level in 0..=MAX_GLOB_DEPTH + 2 {
            fs::create_dir_all(&deep).unwrap();
            fs::write(deep.join(format!("f{level}.csv")), "").unwrap();
            deep = deep.join("d");
        }
        let found = Glob::parse("**/*.csv").unwrap().expand(root).unwrap();
        assert_eq!(found.len(), MAX_GLOB_DEPTH + 1, "{found:?}");
        // A link back up is not followed by `**`.
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(root, root.join("d").join("up")).unwrap();
            assert_eq!(Glob::parse("**/*.csv").unwrap().expand(root).unwrap().len(), MAX_GLOB_DEPTH + 1);
        }
        let wide = root.join("wide");
        fs::create_dir(&wide).unwrap();
        for i in 0..50 {
            fs::write(wide.join(format!("w{i:02}.csv")), "").unwrap();
        }
        let glob = Glob::parse("wide/*.csv").unwrap();
        assert!(matches!(glob.expand_within(root, 40, 1000), Err(Stop::Entries)));
        assert!(matches!(glob.expand_within(root, 1000, 49), Err(Stop::Files)));
        assert_eq!(glob.expand_within(root, 50, 50).unwrap().len(), 50);
    }
}
