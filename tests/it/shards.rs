//! Sharded runs: shards of each graph level computed by separate processes into one cache,
//! then a plain run that finds everything there and commits the outputs. Checked by hand
//! (one process per shard, in level order) in the default tier, and through Snakemake's local
//! and cluster-generic executors in the slow tier.

use crate::common::binary::{bin, text};
use serde_json::Value as Json;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A small swept recipe of two levels (simulated impacts, then their FRFs and a collected table).
fn recipe(dir: &Path) -> PathBuf {
    let r = dir.join("noisy-sweep.yaml");
    std::fs::copy(root().join("tests/data/noisy-sweep.yaml"), &r).unwrap();
    r
}

fn ok(args: &[&str], cwd: &Path) -> String {
    let o = bin().args(args).current_dir(cwd).output().expect("the binary starts");
    assert!(o.status.success(), "spindlelab {args:?}:\n{}", text(&o));
    String::from_utf8_lossy(&o.stdout).to_string()
}

/// The files a run committed, by name, without the manifest (it records times and paths).
fn committed(out: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(out)
        .unwrap()
        .flatten()
        .filter(|e| !e.file_name().to_string_lossy().starts_with('.'))
        .filter(|e| e.file_name() != "manifest.json")
        .map(|e| (e.file_name().to_string_lossy().to_string(), std::fs::read(e.path()).unwrap()))
        .collect()
}

fn manifest(out: &Path) -> Json {
    serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap()
}

/// The markers the shard jobs left, read as JSON.
fn markers(cache: &Path) -> Vec<Json> {
    let mut found = Vec::new();
    for d in std::fs::read_dir(cache.join("shards")).unwrap().flatten() {
        for m in std::fs::read_dir(d.path()).unwrap().flatten() {
            if m.file_name().to_string_lossy().ends_with(".done") {
                found.push(serde_json::from_str(&std::fs::read_to_string(m.path()).unwrap()).unwrap());
            }
        }
    }
    found
}

fn computed(markers: &[Json]) -> Vec<String> {
    let mut ids: Vec<String> = markers
        .iter()
        .flat_map(|m| m["computed"].as_array().unwrap().iter().map(|v| v.as_str().unwrap().to_string()))
        .collect();
    ids.sort();
    ids
}

/// The one-process run's committed files and its instance count, for comparison.
fn one_process(dir: &Path, recipe: &Path) -> (BTreeMap<String, Vec<u8>>, usize) {
    let out = dir.join("one");
    ok(&["run", recipe.to_str().unwrap(), "-o", out.to_str().unwrap(), "-q"], dir);
    let m = manifest(&out);
    (committed(&out), m["nodes"].as_array().unwrap().len())
}

fn levels_of(snakefile: &str) -> usize {
    snakefile.lines().find_map(|l| l.strip_prefix("LEVELS = ")).unwrap().trim().parse().unwrap()
}

#[test]
fn shards_run_level_by_level_compute_each_instance_once_and_commit_the_same_files() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = recipe(dir.path());
    let (want, instances) = one_process(dir.path(), &recipe);
    let (out, cache, wf) = (dir.path().join("out"), dir.path().join("cache"), dir.path().join("wf"));
    let r = recipe.to_str().unwrap();
    let (o, c) = (out.to_str().unwrap(), cache.to_str().unwrap());
    ok(&["export", "snakemake", r, "-o", wf.to_str().unwrap(), "--out", o, "--cache", c, "--shards", "3"], dir.path());
    let levels = levels_of(&std::fs::read_to_string(wf.join("Snakefile")).unwrap());
    assert!(levels >= 2, "{levels} levels");
    for level in 0..levels {
        for k in 1..=3 {
            ok(
                &["run", r, "-o", o, "--cache", c, "--shard", &format!("{k}/3"), "--level", &level.to_string(), "-q"],
                dir.path(),
            );
        }
    }
    let m = markers(&cache);
    assert_eq!(m.len(), 3 * levels, "a marker per shard and level");
    let ids = computed(&m);
    let mut unique = ids.clone();
    unique.dedup();
    assert_eq!(ids, unique, "an instance computed by two shards");
    assert_eq!(ids.len(), instances, "every instance computed once: {ids:?}");
    // The plain run afterwards computes nothing and commits the one-process run's files.
    ok(&["run", r, "-o", o, "--cache", c, "-q"], dir.path());
    let after = manifest(&out);
    assert_eq!(after["computed"], 0, "{after}");
    assert_eq!(committed(&out), want);

    // A shard killed before it left its marker runs again from the cache: nothing recomputed.
    let marker = std::fs::read_dir(cache.join("shards"))
        .unwrap()
        .flatten()
        .next()
        .unwrap()
        .path()
        .join("level-1-shard-2-of-3.done");
    std::fs::remove_file(&marker).unwrap();
    ok(&["run", r, "-o", o, "--cache", c, "--shard", "2/3", "--level", "1", "-q"], dir.path());
    let again: Json = serde_json::from_str(&std::fs::read_to_string(&marker).unwrap()).unwrap();
    assert_eq!(again["computed"].as_array().unwrap().len(), 0, "{again}");
}

#[test]
fn a_shard_is_refused_when_it_is_not_k_of_n() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = recipe(dir.path());
    let o = bin().args(["run", recipe.to_str().unwrap(), "--shard", "4/3"]).current_dir(dir.path()).output().unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("`4/3` is not a shard"), "{}", text(&o));
}

/// Snakemake on PATH (or `SPINDLELAB_SNAKEMAKE`); without it the test says so and passes,
/// except where `SPINDLELAB_REQUIRE_SNAKEMAKE` is set (CI installs it), where it fails.
pub(crate) fn snakemake() -> Option<String> {
    let exe = std::env::var("SPINDLELAB_SNAKEMAKE").unwrap_or_else(|_| "snakemake".into());
    if Command::new(&exe).arg("--version").output().is_ok_and(|o| o.status.success()) {
        return Some(exe);
    }
    assert!(
        std::env::var_os("SPINDLELAB_REQUIRE_SNAKEMAKE").is_none(),
        "SPINDLELAB_REQUIRE_SNAKEMAKE is set and `{exe}` does not run: pip install snakemake snakemake-executor-plugin-cluster-generic"
    );
    eprintln!("no Snakemake on this machine: the workflow check is skipped");
    None
}

/// The tool-crib example (200 holder × tool × stickout combinations) beside the library it uses.
fn tool_crib(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir.join("lib")).unwrap();
    std::fs::copy(root().join("scripts/lib/materials.yaml"), dir.join("lib/materials.yaml")).unwrap();
    let r = dir.join("tool-crib.rhai");
    std::fs::copy(root().join("scripts/tool-crib.rhai"), &r).unwrap();
    r
}

/// The exported tool crib run by Snakemake, with the local executor (3 shards per level) and
/// with cluster-generic (2, each job submitted as a separate process): the committed files are
/// the one-process run's, byte for byte, and no instance is computed twice.
#[test]
#[ignore = "slow: runs Snakemake twice (about a minute)"]
fn the_exported_workflow_runs_in_snakemake_locally_and_as_cluster_jobs() {
    let Some(snakemake) = snakemake() else { return };
    let dir = tempfile::tempdir().unwrap();
    let recipe = tool_crib(dir.path());
    let (want, instances) = one_process(dir.path(), &recipe);
    assert_eq!(want.len(), 5, "a best-cut table per end mill");
    for (name, shards, executor) in [
        ("local", "3", &[][..]),
        ("cluster", "2", &["--executor", "cluster-generic", "--cluster-generic-submit-cmd", "bash", "--jobs", "4"][..]),
    ] {
        let (out, cache, wf) = (
            dir.path().join(format!("out-{name}")),
            dir.path().join(format!("cache-{name}")),
            dir.path().join(format!("wf-{name}")),
        );
        ok(
            &[
                "export",
                "snakemake",
                recipe.to_str().unwrap(),
                "-o",
                wf.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--cache",
                cache.to_str().unwrap(),
                "--shards",
                shards,
            ],
            dir.path(),
        );
        let o = Command::new(&snakemake)
            .arg("-s")
            .arg(wf.join("Snakefile"))
            .arg("--profile")
            .arg(wf.join("profile"))
            .args(["--cores", "2"])
            .args(executor)
            .current_dir(&wf)
            .env(
                "PATH",
                format!(
                    "{}:{}",
                    Path::new(env!("CARGO_BIN_EXE_spindlelab")).parent().unwrap().display(),
                    std::env::var("PATH").unwrap_or_default()
                ),
            )
            .output()
            .unwrap();
        assert!(o.status.success(), "{name}: {}", text(&o));
        let ids = computed(&markers(&cache));
        let mut unique = ids.clone();
        unique.dedup();
        assert_eq!((ids.len(), unique.len()), (instances, instances), "{name}: {ids:?}");
        assert_eq!(manifest(&out)["computed"], 0, "{name}");
        assert_eq!(committed(&out), want, "{name}");
    }
}

/// `cache du|gc|clean --cache DIR` work on a shared cache: gc keeps what a named output
/// folder's last runs used, and `--max-size` bounds it to the entries written last.
#[test]
fn a_shared_cache_is_measured_and_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = recipe(dir.path());
    let (r, cache) = (recipe.to_str().unwrap(), dir.path().join("cache"));
    let c = cache.to_str().unwrap();
    ok(&["run", r, "-o", "a", "--cache", c, "-q"], dir.path());
    let entries = |du: &str| -> usize { du.split(": ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap() };
    let before = entries(&ok(&["cache", "du", "--cache", c], dir.path()));
    assert!(before >= 7, "{before}");
    assert!(!dir.path().join("a/.spindlelab-cache").exists(), "the run used the folder's own cache");
    // `plan` reads the same cache: nothing to run.
    let plan = ok(&["plan", r, "-o", "a", "--cache", c], dir.path());
    assert!(plan.lines().last().unwrap().starts_with("0 to run, "), "{plan}");
    // What folder `a` used stays; a size of nothing leaves nothing.
    ok(&["cache", "gc", "--cache", c, "a"], dir.path());
    assert_eq!(entries(&ok(&["cache", "du", "--cache", c], dir.path())), before);
    let o = bin().args(["cache", "gc", "--cache", c]).current_dir(dir.path()).output().unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    ok(&["cache", "gc", "--cache", c, "--max-size", "0"], dir.path());
    assert_eq!(entries(&ok(&["cache", "du", "--cache", c], dir.path())), 0);
}

/// A batch of diagnoses exported to Snakemake (one job per case, then the summary) gives the
/// summary the one-process batch gives, but for the times; a broken case is a row there too.
#[test]
#[ignore = "slow: Snakemake over two diagnoses"]
fn an_exported_batch_of_diagnoses_gives_the_one_process_summary() {
    let Some(snakemake) = snakemake() else { return };
    let dir = tempfile::tempdir().unwrap();
    for case in ["train_01", "train_04"] {
        let to = dir.path().join("cases").join(case);
        std::fs::create_dir_all(&to).unwrap();
        for e in std::fs::read_dir(root().join("tests/data/training").join(case)).unwrap().flatten() {
            if e.file_name() != "truth.json" {
                std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
            }
        }
    }
    std::fs::create_dir_all(dir.path().join("cases/broken")).unwrap();
    std::fs::write(dir.path().join("cases/broken/case.json"), "{ not json").unwrap();
    let o = bin()
        .args(["diagnose", "--batch", "cases/*/case.json", "-o", "one", "-q"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    ok(&["export", "snakemake", "--batch", "cases/*/case.json", "-o", "wf", "--out", "flow"], dir.path());
    let o = Command::new(&snakemake)
        .args(["-s", "wf/Snakefile", "--profile", "wf/profile", "--cores", "2"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let rows = |folder: &str| {
        let bytes = std::fs::read(dir.path().join(folder).join("summary.csv")).unwrap();
        let mut r = spindlelab::diagnose::batch::rows_from_csv(&bytes, "summary.csv").unwrap();
        // The workflow names the cases by absolute paths; the times differ.
        for row in &mut r {
            row.seconds = 0.0;
            if let Some(at) = row.error.find("cases/") {
                row.error = row.error[at..].to_string();
            }
        }
        format!("{r:?}")
    };
    assert_eq!(rows("flow"), rows("one"));
    assert!(rows("flow").contains("train_04") && rows("flow").contains("broken"));
}

/// The new command-line inputs refuse what they cannot use, with exit 2 and what to write: a
/// size that is not one, a batch pattern that matches nothing, a workflow of no shards.
#[test]
fn bad_scale_out_inputs_are_refused_with_what_to_write() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = recipe(dir.path());
    let r = recipe.to_str().unwrap();
    for (args, says) in [
        (vec!["cache", "gc", "--cache", "c", "--max-size", "10XB"], "is not a size"),
        (vec!["cache", "gc", "--max-size", "1GB"], "name it with --cache DIR"),
        (vec!["diagnose", "--batch", "nothing/*/case.json", "-o", "b"], "matches no case file"),
        (vec!["diagnose", "--batch", "[", "-o", "b"], "is not a file pattern"),
        (vec!["export", "snakemake", r, "-o", "wf", "--shards", "0"], "at least one shard"),
        (vec!["run", r, "--shard", "1/2", "--no-cache"], "writes no outputs"),
    ] {
        let o = bin().args(&args).current_dir(dir.path()).output().unwrap();
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o));
        assert!(String::from_utf8_lossy(&o.stderr).contains(says), "{args:?}: {}", text(&o));
        assert!(!dir.path().join("wf").exists() && !dir.path().join("b").exists(), "{args:?} wrote something");
    }
}
