//! The floors of ARCHITECTURE.md, checked on the sources: which crate may depend on which,
//! and that a crate without unsafe code keeps `#![forbid(unsafe_code)]` at its root.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The workspace's crates: name, folder, and the workspace crates it may depend on.
const CRATES: &[(&str, &str, &[&str])] = &[
    ("spindlelab-grammar", "grammar", &[]),
    ("spindlelab-domain", "domain", &[]),
    ("spindlelab-engine", "engine", &["spindlelab-grammar", "spindlelab-domain"]),
    ("spindlelab-render", "render", &["spindlelab-engine", "spindlelab-domain"]),
    ("spindlelab-stdlib", "stdlib", &["spindlelab-engine", "spindlelab-grammar", "spindlelab-domain"]),
    (
        "spindlelab-app",
        "app",
        &["spindlelab-engine", "spindlelab-render", "spindlelab-stdlib", "spindlelab-domain", "spindlelab-plugin-host"],
    ),
    ("spindlelab-plugin-pack", "plugins/pack", &[]),
    ("spindlelab-plugin-host", "plugins/host", &["spindlelab-engine", "spindlelab-plugin-pack"]),
    ("spindlelab-plugin-examples", "plugins/examples", &["spindlelab-plugin-pack"]),
];

/// Presentation sits above the engine: the engine decides what a plot shows and a renderer
/// (`spindlelab-render`) draws it, so no drawing library is among the engine's dependencies.
#[test]
fn the_engine_draws_nothing_itself() {
    let manifest = std::fs::read_to_string(root().join("engine/Cargo.toml")).unwrap();
    for lib in ["plotters", "png", "base64"] {
        assert!(
            !manifest.lines().any(|l| l.trim_start().starts_with(&format!("{lib} "))),
            "the engine depends on {lib}; drawing belongs in spindlelab-render"
        );
    }
    let render = std::fs::read_to_string(root().join("render/Cargo.toml")).unwrap();
    assert!(render.lines().any(|l| l.starts_with("plotters ")), "render/Cargo.toml draws with plotters");
}

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

/// The code lines of a source file: comments and the unit tests at its end left out.
fn code_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    let code = text.split("#[cfg(test)]").next().unwrap_or("");
    code.lines().enumerate().filter(|(_, l)| !l.trim_start().starts_with("//")).map(|(n, l)| (n + 1, l))
}

/// The physics kernels (every stdlib module but the node adapters in `nodes/` and the
/// registry in `lib.rs`) speak the domain floor only: no kernel imports the engine, so a
/// kernel can be used, tested and benchmarked without the recipe model.
#[test]
fn no_kernel_imports_the_engine() {
    let src = root().join("stdlib/src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.retain(|f| !f.starts_with(src.join("nodes")) && *f != src.join("lib.rs"));
    assert!(files.len() > 40, "{} kernel files", files.len());
    let mut found = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        // Unit tests included: a kernel's tests need no engine either.
        for (n, line) in text.lines().enumerate() {
            if !line.trim_start().starts_with("//") && line.contains("spindlelab_engine") {
                found.push(format!("{}:{}: {}", f.strip_prefix(root()).unwrap().display(), n + 1, line.trim()));
            }
        }
    }
    assert!(found.is_empty(), "kernels import the engine:\n{}", found.join("\n"));
}

/// The sources of the floors and the kernels: domain, grammar, engine and stdlib without its
/// node adapters (a node is a kind, not a concept). The application's JSON shapes of the
/// files it reads and writes (a case, a diagnosis report) are edges and not scanned.
fn crate_sources() -> Vec<PathBuf> {
    let mut files = Vec::new();
    for dir in ["domain", "grammar", "engine", "stdlib"] {
        rust_files(&root().join(dir).join("src"), &mut files);
    }
    let nodes = root().join("stdlib/src/nodes");
    // A module's unit tests in a file of their own (`mod tests;`) are not its code.
    files.retain(|f| !f.starts_with(&nodes) && f.file_name().is_none_or(|n| n != "tests.rs"));
    files
}

/// One concept, one type: a mode is `domain::Mode` (an equivalent spindle beam mode and a
/// rig mode with its speed law are built on it), a material is `domain::Material`, a
/// spindle speed is `domain::Speed`, and the speed law of a mode is written once, in
/// `domain::SpeedLaw`.
#[test]
fn one_mode_one_material_one_speed_one_speed_law() {
    let mut modes = Vec::new();
    let mut materials = Vec::new();
    let mut speeds = Vec::new();
    let mut laws = Vec::new();
    for f in crate_sources() {
        let text = std::fs::read_to_string(&f).unwrap();
        let at = |n: usize| format!("{}:{n}", f.strip_prefix(root()).unwrap().display());
        for (n, line) in code_lines(&text) {
            let Some(rest) = line
                .split("struct ")
                .nth(1)
                .filter(|_| line.trim_start().starts_with("pub") || line.trim_start().starts_with("struct"))
            else {
                // The speed law applied outside its one home: a law's coefficient scaling
                // something.
                if (line.contains(".kf *") || line.contains(".kd *") || line.contains(".keta *"))
                    && !f.ends_with("domain/src/speed.rs")
                {
                    laws.push(at(n));
                }
                continue;
            };
            let name: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            if name.ends_with("Mode") {
                modes.push((name.clone(), at(n)));
            }
            if name.ends_with("Material") {
                materials.push((name.clone(), at(n)));
            }
            if name == "Speed" || name.ends_with("Speed") {
                speeds.push((name, at(n)));
            }
        }
    }
    fn names(v: &[(String, String)]) -> Vec<&str> {
        v.iter().map(|(n, _)| n.as_str()).collect()
    }
    let mut mode_names = names(&modes);
    mode_names.sort_unstable();
    assert_eq!(mode_names, ["Mode", "RigMode", "SpindleMode"], "{modes:?}");
    assert!(modes.iter().any(|(n, at)| n == "Mode" && at.starts_with("domain/")), "{modes:?}");
    assert_eq!(names(&materials), ["Material"], "{materials:?}");
    assert!(materials[0].1.starts_with("domain/"), "{materials:?}");
    assert_eq!(names(&speeds), ["Speed"], "{speeds:?}");
    assert!(speeds[0].1.starts_with("domain/"), "{speeds:?}");
    assert!(laws.is_empty(), "the speed law is written outside domain::SpeedLaw at {laws:?}");
    // And that law is where the check looks for it.
    let law = std::fs::read_to_string(root().join("domain/src/speed.rs")).unwrap();
    assert!(law.contains("pub struct SpeedLaw") && law.contains("self.kf * Self::ratio_squared"));
    // The values that cross node boundaries carry a speed as a `Speed`, never as a number in
    // one unit or another (the files they are written to say rpm).
    let values = std::fs::read_to_string(root().join("domain/src/value.rs")).unwrap();
    let numeric: Vec<(usize, &str)> = code_lines(&values)
        .filter(|(_, l)| {
            let l = l.trim_start();
            l.starts_with("pub ") && !l.starts_with("pub fn") && l.contains("speed") && l.contains("f64")
        })
        .collect();
    assert!(numeric.is_empty(), "value fields hold a speed as a number: {numeric:?}");
    assert!(values.contains("pub speed: Option<Speed>") && values.contains("pub speed: Vec<Speed>"));
}

/// The modules a module of `dir` names among its siblings (`crate::x` at the crate's root,
/// `super::x` one level down), in its code lines.
fn sibling_imports(dir: &Path, prefix: &str) -> Vec<(String, String)> {
    let mut files = Vec::new();
    rust_files(dir, &mut files);
    let mut edges = Vec::new();
    for f in files {
        let rel = f.strip_prefix(dir).unwrap();
        let module = rel.iter().next().unwrap().to_string_lossy().trim_end_matches(".rs").to_string();
        // The root names every module it declares; `super::` from a file one folder down is
        // its own module's root.
        if module == "lib" || module == "mod" {
            continue;
        }
        let pat = if rel.components().count() > 1 && prefix == "super::" { "super::super::" } else { prefix };
        let text = std::fs::read_to_string(&f).unwrap();
        for (_, line) in code_lines(&text) {
            for (i, _) in line.match_indices(pat) {
                let name: String =
                    line[i + pat.len()..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
                if !name.is_empty() && name != module {
                    edges.push((module.clone(), name));
                }
            }
        }
    }
    edges.sort();
    edges.dedup();
    edges
}

/// A cycle among `edges`, if there is one.
fn cycle(edges: &[(String, String)]) -> Option<Vec<String>> {
    fn visit(
        n: &str,
        edges: &[(String, String)],
        path: &mut Vec<String>,
        done: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        if let Some(i) = path.iter().position(|p| p == n) {
            let mut c = path[i..].to_vec();
            c.push(n.to_string());
            return Some(c);
        }
        if done.iter().any(|d| d == n) {
            return None;
        }
        path.push(n.to_string());
        for (_, to) in edges.iter().filter(|(from, _)| from == n) {
            if let Some(c) = visit(to, edges, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.push(n.to_string());
        None
    }
    let mut done = Vec::new();
    edges.iter().find_map(|(from, _)| visit(from, edges, &mut Vec::new(), &mut done))
}

/// The engine's stages import one way (syntax → model → graph → execution): no two of its
/// modules, and no two of the model's, import each other, directly or round a circle.
#[test]
fn the_engine_modules_import_without_circles() {
    let engine = sibling_imports(&root().join("engine/src"), "crate::");
    assert!(engine.iter().any(|(a, b)| a == "graph" && b == "model"), "{engine:?}");
    assert_eq!(cycle(&engine), None, "engine modules: {engine:?}");
    let model = sibling_imports(&root().join("engine/src/model"), "super::");
    assert!(model.iter().any(|(a, b)| a == "resolve" && b == "fit"), "{model:?}");
    assert_eq!(cycle(&model), None, "model modules: {model:?}");
    // The check sees a circle where there is one.
    let circle = [("a", "b"), ("b", "c"), ("c", "a")].map(|(a, b)| (a.to_string(), b.to_string()));
    assert_eq!(cycle(&circle).map(|c| c.len()), Some(4));
}
