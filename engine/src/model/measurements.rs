//! The `measurements:` section: measured FRF files named once, by list or glob, each with
//! what the recipe states about them (direction, speed, units).
//!
//! A measurement set becomes a `read.frf` step of the same name swept over its files, so
//! `@tool_tip.frf` is every measured FRF and any step fed by it runs once per file (the
//! graph's fan-out). Model steps take direction and speed from the FRF they are fed (a
//! spindle model on `grid: @tool_tip.frf`), which pairs each prediction with its
//! measurement by construction. What a file's header says must agree with what the recipe
//! states; `read.frf` checks that when it reads the file.

use crate::diag::{Diagnostics, Span};
use crate::spec::suggest;
use crate::syntax::{Key, Raw, RawKind};

const MEASUREMENT_KEYS: &[&str] = &["files", "format", "direction", "speed", "units", "description"];

/// Largest number of files one measurement set may name: a set is a test campaign, not a
/// data lake, and every file becomes a node instance.
pub const MAX_FILES: usize = 10_000;

/// Rewrites `measurements:` into `read.frf` steps, appended to `steps:`. `base_dir` is the
/// recipe's folder, against which file names and globs are resolved.
pub fn desugar(raw: &Raw, base_dir: Option<&std::path::Path>, diags: &mut Diagnostics) -> Raw {
    let Some(section) = raw.get("measurements") else { return raw.clone() };
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
        if let Some(step) = measurement_step(name, set, base_dir, diags) {
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

/// The `read.frf` step of one measurement set.
fn measurement_step(name: &Key, set: &Raw, base_dir: Option<&std::path::Path>, diags: &mut Diagnostics) -> Option<Raw> {
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
        let full = match base_dir {
            Some(b) if !b.as_os_str().is_empty() => b.join(pattern).display().to_string(),
            _ => pattern.to_string(),
        };
        let matched = match glob::glob(&full) {
            Ok(paths) => paths,
            Err(e) => {
                diags.error_help(Some(&p.span), format!("`{pattern}` is not a valid glob: {e}"), "e.g. `frf_*rpm.csv`");
                continue;
            }
        };
        let mut found: Vec<String> = Vec::new();
        for m in matched.flatten() {
            if !m.is_file() {
                continue;
            }
            // Back to a name relative to the recipe's folder, as the recipe would write it.
            let rel = match base_dir {
                Some(b) if !b.as_os_str().is_empty() => m.strip_prefix(b).unwrap_or(&m).to_path_buf(),
                _ => m.clone(),
            };
            found.push(rel.display().to_string());
            if found.len() > MAX_FILES {
                break;
            }
        }
        if found.len() > MAX_FILES {
            diags.error_help(
                Some(&p.span),
                format!("`{pattern}` matches more than {MAX_FILES} files"),
                "narrow the glob, or split the set",
            );
            continue;
        }
        if found.is_empty() {
            diags.error_help(
                Some(&p.span),
                format!("`{pattern}` matches no file"),
                "globs are relative to the recipe's folder; check the pattern",
            );
            continue;
        }
        found.sort();
        files.extend(found.iter().map(|f| text(f, &p.span)));
    }
    if files.is_empty() {
        return None;
    }
    let span = &name.span;
    let mut params: Vec<(Key, Raw)> = Vec::new();
    for k in ["format", "direction", "speed", "units"] {
        if let Some((key_, v)) = entries.iter().find(|(kk, _)| kk.name == k) {
            params.push((key_.clone(), v.clone()));
        }
    }
    let mut step = vec![(key("kind", span), text("read.frf", span))];
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
