//! Reuse across files through the binary: entity libraries (`use:`), recipes run as steps
//! (`kind: recipe`), Rhai modules, and what the manifest and the plan say of the files used.
//!
//! Fixtures live in `tests/data/reuse/`; the binary runs there, so messages name files as
//! the user would (`bad/broken.yaml:6:…`).

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

const EXIT_BAD_INPUT: i32 = 2;

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/reuse")
}

struct Outcome {
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

fn spindlelab<I, S>(cwd: &Path, args: I) -> Outcome
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let out = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(args)
        .current_dir(cwd)
        .env("NO_COLOR", "1")
        .env_remove("RUST_BACKTRACE")
        .env_remove("SPINDLELAB_LIBRARY_PATH")
        .output()
        .expect("the spindlelab binary starts");
    Outcome {
        code: out.status.code(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// Exit 2, no panic, and every `needle` in the error output.
fn assert_rejected(o: &Outcome, needles: &[&str]) {
    assert!(!o.stderr.contains("panicked"), "the binary panicked:\n{}", o.stderr);
    assert_eq!(o.code, Some(EXIT_BAD_INPUT), "exit code\nstdout:\n{}\nstderr:\n{}", o.stdout, o.stderr);
    for n in needles {
        assert!(o.stderr.contains(n), "`{n}` not in:\n{}", o.stderr);
    }
}

fn assert_ok(o: &Outcome) {
    assert_eq!(o.code, Some(0), "stdout:\n{}\nstderr:\n{}", o.stdout, o.stderr);
}

/// A copy of the fixture folder, to edit and run in.
fn copy_fixtures() -> tempfile::TempDir {
    fn copy(from: &Path, to: &Path) {
        std::fs::create_dir_all(to).unwrap();
        for e in std::fs::read_dir(from).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                copy(&p, &to.join(e.file_name()));
            } else {
                std::fs::copy(&p, to.join(e.file_name())).unwrap();
            }
        }
    }
    let dir = tempfile::tempdir().unwrap();
    copy(&data(), dir.path());
    dir
}

fn manifest(out: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(out.join("manifest.json")).expect("manifest written");
    serde_json::from_str(&text).unwrap()
}

#[test]
fn a_recipe_takes_its_entities_from_libraries_and_the_manifest_lists_them() {
    let dir = copy_fixtures();
    let o = spindlelab(dir.path(), ["run", "holders-study.yaml", "-o", "out", "-q"]);
    assert_ok(&o);
    let m = manifest(&dir.path().join("out"));
    let mut files: Vec<&str> = m["recipe_files"].as_object().unwrap().keys().map(String::as_str).collect();
    files.sort();
    assert_eq!(files, ["lib/holders.yaml", "lib/shop.yaml"], "the shop's library is listed once");
    let hash = blake3::hash(&std::fs::read(dir.path().join("lib/holders.yaml")).unwrap()).to_hex().to_string();
    assert_eq!(m["recipe_files"]["lib/holders.yaml"], hash.as_str());
    assert!(m["entities"]["assemblies.tool_holder"].is_string(), "{}", m["entities"]);
}

#[test]
fn editing_a_library_entity_reruns_only_the_nodes_that_use_it() {
    let dir = copy_fixtures();
    assert_ok(&spindlelab(dir.path(), ["run", "holders-study.yaml", "-o", "out", "-q"]));
    let lib = dir.path().join("lib/holders.yaml");
    let text = std::fs::read_to_string(&lib).unwrap();
    std::fs::write(&lib, text.replace("length: 15.88 mm, outer: carbide", "length: 20 mm, outer: carbide")).unwrap();

    let plan = spindlelab(dir.path(), ["plan", "holders-study.yaml", "-o", "out"]);
    assert_ok(&plan);
    let line = |id: &str| plan.stdout.lines().find(|l| l.starts_with(&format!("{id} "))).unwrap_or("").to_string();
    assert!(
        line("holder_model").contains("changed parameter `assembly` (changed in lib/holders.yaml)"),
        "{}",
        plan.stdout
    );
    for id in ["artifact_model", "hit", "impulse"] {
        assert!(line(id).contains("from cache"), "{id}:\n{}", plan.stdout);
    }
    assert!(plan.stdout.contains("1 to run, 3 from cache"), "{}", plan.stdout);

    assert_ok(&spindlelab(dir.path(), ["run", "holders-study.yaml", "-o", "out", "-q"]));
    let m = manifest(&dir.path().join("out"));
    let computed: Vec<&str> = m["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|n| n["status"] == "computed")
        .map(|n| n["id"].as_str().unwrap())
        .collect();
    assert_eq!(computed, ["holder_model"]);
    assert_eq!(m["computed"], 1);
    assert_eq!(m["cache_hits"], 3);

    // A material of the shop's library reaches both assemblies, and says where it changed.
    let shop = dir.path().join("lib/shop.yaml");
    let text = std::fs::read_to_string(&shop).unwrap();
    std::fs::write(&shop, text.replace("E: 200 GPa", "E: 205 GPa")).unwrap();
    let plan = spindlelab(dir.path(), ["plan", "holders-study.yaml", "-o", "out"]);
    assert_ok(&plan);
    for id in ["artifact_model", "holder_model"] {
        let l = plan.stdout.lines().find(|l| l.starts_with(id)).unwrap();
        assert!(l.contains("(changed in lib/shop.yaml)"), "{l}");
    }
    assert!(plan.stdout.contains("2 to run, 2 from cache"), "{}", plan.stdout);
}

#[test]
fn an_error_in_a_library_points_into_it_and_at_the_use_entry() {
    let o = spindlelab(&data(), ["check", "bad/uses-broken.yaml"]);
    assert_rejected(
        &o,
        &["bad/broken.yaml:6:", "zero or negative length", "bad/uses-broken.yaml:3:7", "cannot use `broken.yaml`"],
    );
    let o = spindlelab(&data(), ["check", "bad/uses-not-yaml.yaml"]);
    assert_rejected(&o, &["bad/not-yaml.yaml:", "invalid YAML", "bad/uses-not-yaml.yaml:3:7"]);
}

#[test]
fn a_name_defined_in_two_files_is_an_error_naming_both() {
    let o = spindlelab(&data(), ["check", "bad/clash-libraries.yaml"]);
    assert_rejected(
        &o,
        &["material `steel` is defined in both lib/shop.yaml:6 and bad/other-shop.yaml:3", "rename one"],
    );
    let o = spindlelab(&data(), ["check", "bad/clash-own.yaml"]);
    assert_rejected(&o, &["bad/clash-own.yaml:5:3", "material `steel` is defined here and in lib/shop.yaml:6"]);
}

#[test]
fn a_library_holds_entities_only_and_cannot_use_itself() {
    let o = spindlelab(&data(), ["check", "bad/uses-with-steps.yaml"]);
    assert_rejected(&o, &["bad/with-steps.yaml:3:1", "`steps` in a library", "cannot use `with-steps.yaml`"]);
    let o = spindlelab(&data(), ["check", "bad/uses-cycle.yaml"]);
    assert_rejected(&o, &["uses itself", "bad/cycle-a.yaml → bad/cycle-b.yaml → bad/cycle-a.yaml"]);
    let o = spindlelab(&data(), ["check", "bad/uses-missing.yaml"]);
    assert_rejected(&o, &["bad/uses-missing.yaml:3:7", "library `lib/nowhere.yaml` not found"]);
}

#[test]
fn check_validates_a_library_on_its_own_and_run_refuses_one() {
    let o = spindlelab(&data(), ["check", "lib/holders.yaml"]);
    assert_ok(&o);
    assert!(o.stdout.contains("lib/holders.yaml: ok — library of 2 materials, 2 assemblies"), "{}", o.stdout);
    let o = spindlelab(&data(), ["check", "bad/broken.yaml"]);
    assert_rejected(&o, &["bad/broken.yaml:6:"]);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = spindlelab(&data(), [OsStr::new("run"), OsStr::new("lib/shop.yaml"), OsStr::new("-o"), out.as_os_str()]);
    assert_rejected(&o, &["makes it a library", "nothing was run"]);
    assert!(!out.exists(), "nothing is written for a library");
}

#[test]
fn a_recipe_step_swept_over_two_values_runs_the_whole_procedure_per_value() {
    let dir = copy_fixtures();
    let o = spindlelab(dir.path(), ["plan", "sweep-tap.yaml", "-o", "out"]);
    assert_ok(&o);
    for id in [
        "tap/hit[hammer_mass=0.02 kg]",
        "tap/hit[hammer_mass=0.04 kg]",
        "tap/frf[hammer_mass=0.02 kg]",
        "tap/frf[hammer_mass=0.04 kg]",
        "impulse ",
    ] {
        assert!(o.stdout.contains(id), "{id} not planned:\n{}", o.stdout);
    }
    assert!(o.stdout.contains("5 to run"), "{}", o.stdout);
    let graph = spindlelab(dir.path(), ["graph", "sweep-tap.yaml"]);
    assert_ok(&graph);
    assert!(graph.stdout.contains("subgraph \"cluster_tap/\""), "{}", graph.stdout);
    assert!(graph.stdout.contains("label=\"tap (recipe)\""), "{}", graph.stdout);

    // The same numbers as the procedure's steps written out in the recipe.
    assert_ok(&spindlelab(dir.path(), ["run", "sweep-tap.yaml", "-o", "sub", "-q"]));
    assert_ok(&spindlelab(dir.path(), ["run", "flat-tap.yaml", "-o", "flat", "-q"]));
    for f in ["frf.csv", "impulse.csv"] {
        let a = std::fs::read(dir.path().join("sub").join(f)).unwrap();
        let b = std::fs::read(dir.path().join("flat").join(f)).unwrap();
        assert_eq!(a, b, "{f} differs between the recipe step and the steps written out");
    }
    let m = manifest(&dir.path().join("sub"));
    assert!(m["recipe_files"]["procedures/tap.yaml"].is_string(), "{}", m["recipe_files"]);
    // Run on its own, the procedure writes its own outputs.
    assert_ok(&spindlelab(dir.path(), ["run", "procedures/tap.yaml", "-o", "alone", "-q"]));
    assert!(dir.path().join("alone/frf.csv").is_file());
}

#[test]
fn a_recipe_step_binds_the_inputs_it_declares_and_types_are_checked() {
    let o = spindlelab(&data(), ["check", "bound-inputs.yaml"]);
    assert_ok(&o);
    assert!(o.stdout.contains("2 steps"), "{}", o.stdout);
    let o = spindlelab(&data(), ["check", "bad/wrong-input-type.yaml"]);
    assert_rejected(&o, &["type mismatch", "`@hit.impulse_time` is a scalar", "bad/wrong-input-type.yaml:10:"]);
    let o = spindlelab(&data(), ["check", "procedures/estimate.yaml"]);
    assert_rejected(&o, &["declares `inputs`", "runs as a step of another recipe"]);
    let o = spindlelab(&data(), ["check", "bad/unknown-export.yaml"]);
    assert_rejected(&o, &["bad/unknown-export.yaml:9:", "exports no `impulses`", "did you mean `@tap.impulse`?"]);
    let o = spindlelab(&data(), ["check", "bad/self-step.yaml"]);
    assert_rejected(&o, &["runs itself", "bad/self-step.yaml → bad/self-step.yaml"]);
}

#[test]
fn a_rhai_recipe_imports_a_module_from_its_folder_and_nothing_else() {
    let o = spindlelab(&data(), ["check", "rhai/modular.rhai"]);
    assert_ok(&o);
    assert!(o.stdout.contains("2 steps"), "{}", o.stdout);
    let o = spindlelab(&data(), ["check", "rhai/climbs-out.rhai"]);
    assert_rejected(
        &o,
        &["rhai/climbs-out.rhai:1:", "cannot import `../lib/shop`", "leads out of the recipe's folder"],
    );
    let o = spindlelab(&data(), ["check", "rhai/absolute.rhai"]);
    assert_rejected(&o, &["cannot import `/etc/passwd`", "an absolute path"]);
}

#[test]
fn the_manifest_lists_a_rhai_recipes_modules() {
    let dir = copy_fixtures();
    assert_ok(&spindlelab(dir.path(), ["run", "rhai/modular.rhai", "-o", "out", "-q"]));
    let m = manifest(&dir.path().join("out"));
    assert!(m["recipe_files"]["rhai/helpers/steps.rhai"].is_string(), "{}", m["recipe_files"]);
}

#[test]
fn a_library_is_found_on_the_library_path() {
    let dir = copy_fixtures();
    std::fs::write(
        dir.path().join("far.yaml"),
        "spindlelab: 1\nuse: [shop.yaml]\nsteps:\n  m:\n    kind: impact.simulate\n    params: { hammer_mass: 0.02 kg, hammer_stiffness: 500 N/m, target_mass: 0.1 kg, target_stiffness: 5e7 N/m, tip_material: steel }\n",
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(["check", "far.yaml"])
        .current_dir(dir.path())
        .env("NO_COLOR", "1")
        .env("SPINDLELAB_LIBRARY_PATH", dir.path().join("lib"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn every_library_and_procedure_of_the_examples_checks_on_its_own() {
    let scripts = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts");
    let registry = spindlelab::registry();
    for (folder, library) in [("lib", true), ("procedures", false)] {
        let mut seen = 0;
        for e in std::fs::read_dir(scripts.join(folder)).unwrap().flatten() {
            let path = e.path();
            let c = spindlelab::engine::compile_file(&path, &registry)
                .unwrap_or_else(|e| panic!("{} does not check:\n{}", path.display(), e.render(false)));
            assert_eq!(c.recipe.library, library, "{}", path.display());
            seen += 1;
        }
        assert!(seen > 0, "scripts/{folder} is empty");
    }
    // The examples that use them list them in their manifests' files.
    let c = spindlelab::engine::compile_file(&scripts.join("rcsa-tool-point.yaml"), &registry).unwrap();
    let used: Vec<String> = c.used_files().keys().cloned().collect();
    for f in ["lib/materials.yaml", "lib/sensors.yaml", "lib/table-5.1.yaml", "procedures/test-spindle.yaml"] {
        assert!(used.iter().any(|u| u.ends_with(f)), "{f} not in {used:?}");
    }
}

/// The worked example of docs/recipe-format.md (*Reuse*), written out file by file as its
/// blocks name them, checks: the libraries on their own, the recipes with them.
#[test]
fn the_worked_example_in_the_recipe_format_checks() {
    let doc = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/recipe-format.md")).unwrap();
    let section = doc.split("\n## Reuse\n").nth(1).expect("a Reuse section").split("\n## ").next().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for block in section.split("```yaml\n").skip(1) {
        let text = block.split("```").next().unwrap();
        let name = text.lines().next().and_then(|l| l.strip_prefix("# ")).unwrap();
        let name = name.split([':', ' ']).next().unwrap();
        let path = dir.path().join(name);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, text).unwrap();
        files.push(name.to_string());
    }
    assert_eq!(files, ["lib/shop.yaml", "lib/holders.yaml", "study.yaml", "procedures/tap.yaml", "tap-study.yaml"]);
    for f in &files {
        let o = spindlelab(dir.path(), ["check", f]);
        assert_ok(&o);
    }
    let o = spindlelab(dir.path(), ["check", "lib/holders.yaml"]);
    assert!(o.stdout.contains("ok — library of 2 materials, 1 assembly"), "{}", o.stdout);
    let o = spindlelab(dir.path(), ["plan", "tap-study.yaml", "-o", "out"]);
    assert!(o.stdout.contains("tap/hit[hammer_mass=0.04 kg]"), "{}", o.stdout);
}

#[test]
fn confine_refuses_a_library_from_outside_the_recipes_folder() {
    assert_ok(&spindlelab(&data(), ["check", "bad/climbs-out.yaml"]));
    let o = spindlelab(&data(), ["--confine", "check", "bad/climbs-out.yaml"]);
    assert_rejected(&o, &["library `../lib/shop.yaml` lies outside the recipe's folder", "--confine"]);
    assert_ok(&spindlelab(&data(), ["--confine", "check", "holders-study.yaml"]));
}
