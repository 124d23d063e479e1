//! The floors of ARCHITECTURE.md, checked on the sources: which crate may depend on which,
//! and that a crate without unsafe code keeps `#![forbid(unsafe_code)]` at its root.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The workspace's crates: name, folder, and the workspace crates it may depend on.
const CRATES: &[(&str, &str, &[&str])] = &[
    ("spindlelab-grammar", "grammar", &[]),
    ("spindlelab-engine", "engine", &["spindlelab-grammar"]),
    ("spindlelab-stdlib", "stdlib", &["spindlelab-engine", "spindlelab-grammar"]),
    ("spindlelab-plugin-pack", "plugins/pack", &[]),
    ("spindlelab-plugin-host", "plugins/host", &["spindlelab-engine", "spindlelab-plugin-pack"]),
    ("spindlelab-plugin-examples", "plugins/examples", &["spindlelab-plugin-pack"]),
];

/// The names of the workspace crates a `Cargo.toml` lists in its normal dependencies.
fn workspace_dependencies(manifest: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut in_deps = false;
    for line in manifest.lines() {
        let t = line.trim();
        if t.starts_with('[') {
            in_deps = t == "[dependencies]" || (t.starts_with("[target.") && t.ends_with(".dependencies]"));
            continue;
        }
        if in_deps && let Some((name, _)) = t.split_once('=') {
            let name = name.trim();
            if name.starts_with("spindlelab-") {
                out.push(name.to_string());
            }
        }
    }
    out
}

#[test]
fn each_crate_depends_only_on_the_floors_below_it() {
    for (name, dir, allowed) in CRATES {
        let manifest = std::fs::read_to_string(root().join(dir).join("Cargo.toml")).unwrap();
        assert!(manifest.contains(&format!("name = \"{name}\"")), "{dir}/Cargo.toml is not {name}");
        for dep in workspace_dependencies(&manifest) {
            assert!(allowed.contains(&dep.as_str()), "{name} depends on {dep}; it may depend on {allowed:?} only");
        }
    }
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// Whether any source of the crate uses `unsafe` (a block, a function or an impl).
fn uses_unsafe(src: &Path) -> bool {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    files.iter().any(|f| {
        let text = std::fs::read_to_string(f).unwrap();
        text.lines().filter(|l| !l.trim_start().starts_with("//")).any(|l| {
            l.contains("unsafe {")
                || l.contains("unsafe fn")
                || l.contains("unsafe impl")
                || l.contains("unsafe extern")
        })
    })
}

#[test]
fn crates_without_unsafe_code_forbid_it() {
    let mut checked = 0;
    for (name, dir, _) in CRATES.iter().chain([&("spindlelab", ".", &[][..])]) {
        let src = root().join(dir).join("src");
        let lib = std::fs::read_to_string(src.join("lib.rs")).unwrap();
        if uses_unsafe(&src) {
            continue;
        }
        checked += 1;
        assert!(
            lib.lines().any(|l| l.trim() == "#![forbid(unsafe_code)]"),
            "{name} holds no unsafe code but its lib.rs does not say `#![forbid(unsafe_code)]`"
        );
    }
    assert!(checked >= 3, "only {checked} crates checked");
    // The engine's own code is held to it; only its tests make pipes through libc.
    let engine = std::fs::read_to_string(root().join("engine/src/lib.rs")).unwrap();
    assert!(engine.contains("#![cfg_attr(not(test), forbid(unsafe_code))]"), "the engine lost its forbid");
}

/// The engine compiles and runs any registry's kinds: none of the built-in kind names appears
/// in its code as a string (the measurement reader, say, is the one the registry names).
/// Comments and the engine's own unit tests, which register kinds of their own, are not code
/// the engine runs.
#[test]
fn the_engine_names_no_built_in_node_kind() {
    let kinds: Vec<String> = spindlelab::registry().names().map(|k| format!("\"{k}\"")).collect();
    assert!(kinds.len() > 30, "{kinds:?}");
    let mut files = Vec::new();
    rust_files(&root().join("engine/src"), &mut files);
    let mut found = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        // Unit tests sit at the end of a file, after `#[cfg(test)]`.
        let code = text.split("#[cfg(test)]").next().unwrap_or("");
        for (n, line) in code.lines().enumerate() {
            if line.trim_start().starts_with("//") {
                continue;
            }
            for k in kinds.iter().filter(|k| line.contains(k.as_str())) {
                found.push(format!("{}:{}: {k}", f.strip_prefix(root()).unwrap().display(), n + 1));
            }
        }
    }
    assert!(found.is_empty(), "the engine names built-in kinds:\n{}", found.join("\n"));
}
