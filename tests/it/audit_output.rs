//! The hostile audit of the output folder and the cache (issue 52), each finding reproduced
//! through the binary: names of the user's that look like the tool's, a kill at every step of
//! a commit, a shared cache given as a link, shard markers and cache entries behind planted
//! links or padding, files where the tool keeps its folders, and warnings of cached runs
//! (docs/guarantees.md).

#![cfg(unix)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use crate::common::binary::{bin, no_panic, run_in, text};

/// A small swept recipe (five simulated impacts, a collected table): `stiffness` changes the
/// numbers, `outputs` (YAML list items) the files.
fn write_recipe(dir: &Path, file: &str, stiffness: &str, outputs: &[(&str, &str)]) -> PathBuf {
    let path = dir.join(file);
    let mut text = format!(
        r#"spindlelab: 1
name: "audit"
steps:
  hit:
    kind: impact.simulate
    params:
      hammer_stiffness: {stiffness}
      target_mass: 0.1 kg
      target_stiffness: 5e7 N/m
    sweep:
      hammer_mass: 0.03..0.07 step 0.01 kg
  impulse:
    kind: table.collect
    inputs: {{ values: "@hit.impulse_time" }}
outputs:
"#
    );
    for (from, file) in outputs {
        text.push_str(&format!("  - {{ from: \"{from}\", file: {file} }}\n"));
    }
    std::fs::write(&path, text).unwrap();
    path
}

/// The first variant: `a-only.csv` is a file the second does not write.
fn recipe_a(dir: &Path) -> PathBuf {
    let outputs =
        [("@impulse.table", "impulse.csv"), ("@hit.force", "sub/force.csv"), ("@impulse.table", "a-only.csv")];
    write_recipe(dir, "a.yaml", "500 N/m", &outputs)
}

/// The second variant: other numbers in `impulse.csv`, and files the first does not write.
fn recipe_b(dir: &Path) -> PathBuf {
    let outputs = [("@impulse.table", "impulse.csv"), ("@hit.force", "sub/again.csv"), ("@impulse.table", "other.csv")];
    write_recipe(dir, "b.yaml", "900 N/m", &outputs)
}

fn ok(cwd: &Path, args: &[&str]) -> Output {
    let o = run_in(cwd, args);
    no_panic(&o);
    assert!(o.status.success(), "spindlelab {args:?}:\n{}", text(&o));
    o
}

/// Refused as the user's to fix: exit code 2, no panic; returns what was said.
fn refused(cwd: &Path, args: &[&str]) -> String {
    let o = run_in(cwd, args);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "spindlelab {args:?}:\n{}", text(&o));
    text(&o)
}

fn manifest(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap()
}

/// The files a manifest lists, with their hashes.
fn files_of(m: &serde_json::Value) -> BTreeMap<String, String> {
    let files = m["files"].as_object().expect("the manifest lists its files");
    files.iter().map(|(k, v)| (k.clone(), v.as_str().unwrap().to_string())).collect()
}

/// Every name under `dir` outside the tool's own folders (`.spindlelab`, `.spindlelab-cache`),
/// relative, sorted, following no link.
fn visible(dir: &Path) -> Vec<String> {
    let own = |rel: &String| {
        let top = Path::new(rel).components().next().map(|c| c.as_os_str().to_owned());
        top.is_some_and(|t| t == ".spindlelab" || t == ".spindlelab-cache")
    };
    crate::guarantees::tree(dir).into_iter().filter(|rel| !own(rel)).collect()
}

/// The names a set of files stands for: the files and the folders on their paths.
fn names_of<'a>(files: impl IntoIterator<Item = &'a String>) -> Vec<String> {
    let mut names = Vec::new();
    for f in files {
        let mut at = PathBuf::new();
        for c in Path::new(f).components() {
            at.push(c);
            names.push(at.display().to_string());
        }
    }
    names.sort();
    names.dedup();
    names
}

fn blake3_of(path: &Path) -> Option<String> {
    std::fs::read(path).ok().map(|b| blake3::hash(&b).to_hex().to_string())
}

/// Item 3: a folder of the user's named like the staging folders of an older layout, and files
/// of the user's named like the temporary links an earlier commit made beside its outputs
/// (`.link-<pid>`, for a range of process ids the run is about to get), outlive the run.
#[test]
fn names_of_the_users_that_look_like_the_tools_temporaries_are_left_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = recipe_a(tmp.path());
    let out = tmp.path().join("o");
    std::fs::create_dir_all(out.join(".staging-notes")).unwrap();
    std::fs::write(out.join(".staging-notes/keep.txt"), b"mine").unwrap();
    let mut hit = false;
    for _ in 0..5 {
        // The next process ids: plant the user's `.link-<pid>` for each, then start the run.
        let probe = Command::new("true").spawn().unwrap();
        let next = probe.id() + 1;
        let mut probe = probe;
        probe.wait().unwrap();
        let planted: Vec<u32> = (next..next + 400).collect();
        for pid in &planted {
            std::fs::write(out.join(format!(".link-{pid}")), b"the user's").unwrap();
        }
        let child = bin()
            .args(["run", recipe.to_str().unwrap(), "-o", "o", "-q", "--no-cache"])
            .current_dir(tmp.path())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let pid = child.id();
        let o = child.wait_with_output().unwrap();
        no_panic(&o);
        assert!(o.status.success(), "{}", text(&o));
        for p in &planted {
            let name = out.join(format!(".link-{p}"));
            assert_eq!(
                std::fs::read(&name).ok().as_deref(),
                Some(&b"the user's"[..]),
                "{} was touched",
                name.display()
            );
        }
        if planted.contains(&pid) {
            hit = true;
            break;
        }
    }
    assert!(hit, "the run never got one of the planted process ids");
    assert_eq!(std::fs::read(out.join(".staging-notes/keep.txt")).unwrap(), b"mine");
    assert!(std::fs::read_to_string(out.join("impulse.csv")).is_ok());
}

/// Item 4: the second of two runs (other numbers, other files) killed right after each step of
/// its commit ([`spindlelab::engine::exec::commit::FAULT_COMMIT_STEP`]): the folder shows one
/// complete run (every readable file is the old run's or the new run's, as the visible
/// manifest says, never a file of the other), no name outside `.spindlelab` but the two runs'
/// own, and the next run leaves exactly its own files (no link of the killed state, no
/// temporary link in `.spindlelab/tmp`).
#[test]
fn a_commit_killed_after_each_of_its_steps_leaves_one_complete_run_and_the_next_run_cleans_up() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (recipe_a(tmp.path()), recipe_b(tmp.path()));
    let cache = tmp.path().join("cache");
    let run = |out: &Path, recipe: &Path, step: Option<usize>| -> Output {
        let mut c = Command::new("sh");
        // No core file for the abort the hook asks for, whatever the machine's limit.
        c.args(["-c", "ulimit -c 0; exec \"$0\" \"$@\"", env!("CARGO_BIN_EXE_spindlelab")])
            .args(["run", recipe.to_str().unwrap(), "-o", out.to_str().unwrap(), "-q", "--cache"])
            .arg(&cache)
            .env("NO_COLOR", "1")
            .env_remove("RUST_BACKTRACE")
            .env_remove("SPINDLELAB_FAULT_COMMIT_STEP");
        if let Some(n) = step {
            c.env("SPINDLELAB_FAULT_COMMIT_STEP", n.to_string());
        }
        let o = c.output().unwrap();
        no_panic(&o);
        o
    };
    let mut sets: Vec<BTreeMap<String, String>> = Vec::new();
    let mut killed = 0;
    for step in 1.. {
        let out = tmp.path().join(format!("o{step}"));
        let first = run(&out, &a, None);
        assert!(first.status.success(), "{}", text(&first));
        let set_a = files_of(&manifest(&out));
        let second = run(&out, &b, Some(step));
        if second.status.success() {
            break; // past the last step: the commit ran whole
        }
        assert_eq!(second.status.code(), None, "step {step}: not killed by the hook:\n{}", text(&second));
        killed += 1;
        // One complete run: the visible manifest's files, each with its hash, and nothing else readable.
        let m = manifest(&out);
        let set = files_of(&m);
        for (rel, hash) in &set {
            assert_eq!(blake3_of(&out.join(rel)).as_ref(), Some(hash), "step {step}: `{rel}` is not the run's file");
        }
        let b_files = ["impulse.csv".to_string(), "sub/again.csv".into(), "other.csv".into(), "manifest.json".into()];
        let known = names_of(set_a.keys().chain(&b_files));
        for rel in visible(&out) {
            if rel != "manifest.json" && std::fs::metadata(out.join(&rel)).is_ok_and(|m| m.is_file()) {
                assert!(set.contains_key(&rel), "step {step}: `{rel}` is readable but not part of the visible run");
            }
            assert!(known.contains(&rel), "step {step}: `{rel}` is visible and is no output of either run");
        }
        if !sets.contains(&set) {
            sets.push(set);
        }
        // The next run leaves exactly its own files.
        let next = run(&out, &a, None);
        assert!(next.status.success(), "{}", text(&next));
        let set = files_of(&manifest(&out));
        assert_eq!(set.keys().collect::<Vec<_>>(), set_a.keys().collect::<Vec<_>>());
        let names = names_of(set.keys().chain(["manifest.json".to_string()].iter()));
        for rel in visible(&out) {
            assert!(names.contains(&rel), "step {step}: the next run left `{rel}`");
            assert!(std::fs::metadata(out.join(&rel)).is_ok(), "step {step}: the next run left `{rel}` dangling");
        }
        for (rel, hash) in &set {
            assert_eq!(blake3_of(&out.join(rel)).as_ref(), Some(hash), "step {step}: `{rel}`");
        }
        let leftovers: Vec<_> = std::fs::read_dir(out.join(".spindlelab/tmp")).unwrap().flatten().collect();
        assert!(leftovers.is_empty(), "step {step}: {leftovers:?} left in .spindlelab/tmp");
    }
    // Two links made and renamed for `other.csv`, then `previous` and `current`, the sync, the
    // stale `a-only.csv` removed and the old runs: nine steps.
    assert!(killed >= 9, "only {killed} steps were killed");
    assert_eq!(sets.len(), 2, "both the old and the new run were seen: {sets:?}");
}

/// Item 5: a shared cache given as a link (as on clusters) is the folder it leads to: a shard
/// computes into it, and the plain run afterwards finds everything there.
#[test]
fn a_shared_cache_given_as_a_link_is_filled_by_a_shard_and_found_by_the_run() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = recipe_a(tmp.path());
    let real = tmp.path().join("shared");
    std::fs::create_dir_all(&real).unwrap();
    std::os::unix::fs::symlink(&real, tmp.path().join("cache")).unwrap();
    let r = recipe.to_str().unwrap();
    let o = ok(tmp.path(), &["run", r, "-o", "o", "--cache", "cache", "--shard", "1/1"]);
    let said = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(said.contains("computed"), "{said}");
    assert!(std::fs::read_dir(real.join("shards")).unwrap().count() == 1, "the marker is in the shared folder");
    ok(tmp.path(), &["run", r, "-o", "o", "--cache", "cache", "-q"]);
    let m = manifest(&tmp.path().join("o"));
    assert_eq!(m["computed"], 0, "the run recomputed what the shard computed: {m}");
    assert!(m["cache_hits"].as_u64().unwrap() > 0, "{m}");
    // An output folder given as a link is the user's path too.
    std::fs::create_dir_all(tmp.path().join("real-out")).unwrap();
    std::os::unix::fs::symlink(tmp.path().join("real-out"), tmp.path().join("linked-out")).unwrap();
    ok(tmp.path(), &["run", r, "-o", "linked-out", "--cache", "cache", "-q"]);
    assert!(tmp.path().join("real-out/impulse.csv").is_file());
}

/// Item 6: links planted where the cache keeps its shard markers (`CACHE/shards`, the graph's
/// folder in it, the default cache's `shards`) are not written through: the shard is refused
/// with the link's path, and nothing appears where they lead.
#[test]
fn shard_markers_are_not_written_through_planted_links() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = recipe_a(tmp.path());
    let r = recipe.to_str().unwrap();
    let elsewhere = tempfile::tempdir().unwrap();
    let empty = |p: &Path| std::fs::read_dir(p).unwrap().count() == 0;

    // `CACHE/shards` a link.
    let cache = tmp.path().join("c1");
    std::fs::create_dir_all(&cache).unwrap();
    std::os::unix::fs::symlink(elsewhere.path(), cache.join("shards")).unwrap();
    let said = refused(tmp.path(), &["run", r, "--cache", "c1", "--shard", "1/1", "-q"]);
    assert!(said.contains("c1/shards`") && said.contains("symbolic link"), "{said}");
    assert!(empty(elsewhere.path()), "wrote through CACHE/shards");

    // `CACHE/shards/<digest>` a link: the digest is the folder a first shard made.
    let cache = tmp.path().join("c2");
    ok(tmp.path(), &["run", r, "--cache", "c2", "--shard", "1/1", "-q"]);
    let digest = std::fs::read_dir(cache.join("shards")).unwrap().flatten().next().unwrap().path();
    std::fs::remove_dir_all(&digest).unwrap();
    std::os::unix::fs::symlink(elsewhere.path(), &digest).unwrap();
    let said = refused(tmp.path(), &["run", r, "--cache", "c2", "--shard", "1/1", "-q"]);
    assert!(said.contains(&format!("{}`", digest.file_name().unwrap().to_string_lossy())), "{said}");
    assert!(empty(elsewhere.path()), "wrote through CACHE/shards/<digest>");

    // The output folder's own cache: its `shards` a link.
    let own = tmp.path().join("o/.spindlelab-cache");
    std::fs::create_dir_all(&own).unwrap();
    std::os::unix::fs::symlink(elsewhere.path(), own.join("shards")).unwrap();
    let said = refused(tmp.path(), &["run", r, "-o", "o", "--shard", "1/1", "-q"]);
    assert!(said.contains(".spindlelab-cache/shards`"), "{said}");
    assert!(empty(elsewhere.path()), "wrote through OUT/.spindlelab-cache/shards");

    // The output folder's own cache a link: a shard stores nothing through it and says so.
    std::fs::create_dir_all(tmp.path().join("o2")).unwrap();
    std::os::unix::fs::symlink(elsewhere.path(), tmp.path().join("o2/.spindlelab-cache")).unwrap();
    let said = refused(tmp.path(), &["run", r, "-o", "o2", "--shard", "1/1", "-q"]);
    assert!(said.contains("o2/.spindlelab-cache`") && said.contains("symbolic link"), "{said}");
    assert!(empty(elsewhere.path()), "wrote through OUT/.spindlelab-cache");
}

/// A shard whose results cannot be stored (a file stands at every folder the cache would put
/// an entry in) fails with exit 1 and writes no marker; a plain run in the same state runs,
/// and its manifest says what it could not cache.
#[test]
fn a_shard_that_cannot_store_its_results_fails_without_a_marker() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = recipe_a(tmp.path());
    let r = recipe.to_str().unwrap();
    let cache = tmp.path().join("c");
    std::fs::create_dir_all(&cache).unwrap();
    for i in 0..256 {
        std::fs::write(cache.join(format!("{i:02x}")), "in the way").unwrap();
    }
    let o = run_in(tmp.path(), &["run", r, "--cache", "c", "--shard", "1/1", "-q"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("could not be stored in the cache"), "{}", text(&o));
    assert!(!cache.join("shards").exists(), "a marker was written for a shard that stored nothing");
    ok(tmp.path(), &["run", r, "-o", "o", "--cache", "c", "-q"]);
    let m = std::fs::read_to_string(tmp.path().join("o/manifest.json")).unwrap();
    assert!(m.contains("could not be stored in the cache"), "{m}");
}

/// Runs the binary and returns its output with its peak resident memory in bytes (from
/// `wait4`, this child's own).
#[allow(clippy::zombie_processes, reason = "the child is reaped by wait4, which also gives its rusage")]
fn run_measured(cwd: &Path, args: &[&str]) -> (Output, u64) {
    let dir = tempfile::tempdir().unwrap();
    let (so, se) = (dir.path().join("stdout"), dir.path().join("stderr"));
    let child = bin()
        .args(args)
        .current_dir(cwd)
        .stdout(std::fs::File::create(&so).unwrap())
        .stderr(std::fs::File::create(&se).unwrap())
        .spawn()
        .unwrap();
    let mut status = 0;
    // SAFETY: an all-zero rusage is a valid value for wait4 to fill.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: waits for our own child by its pid; status and usage are valid for writes.
    let pid = unsafe { libc::wait4(child.id() as libc::pid_t, &mut status, 0, &mut usage) };
    assert_eq!(pid, child.id() as libc::pid_t);
    let code = if libc::WIFEXITED(status) { libc::WEXITSTATUS(status) } else { 128 + libc::WTERMSIG(status) };
    let o = Output {
        status: std::os::unix::process::ExitStatusExt::from_raw(code << 8),
        stdout: std::fs::read(&so).unwrap(),
        stderr: std::fs::read(&se).unwrap(),
    };
    (o, usage.ru_maxrss as u64 * 1024)
}

/// Item 7: a cache entry padded to 1 GiB behind a valid header (a sparse file, so the test is
/// cheap) is damage found from its length: recomputed and said, and its padding never read
/// (the run's peak memory stays far below the gigabyte reading it would take).
#[test]
fn a_cache_entry_padded_behind_its_header_is_recomputed_without_being_read() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = recipe_a(tmp.path());
    let r = recipe.to_str().unwrap();
    ok(tmp.path(), &["run", r, "-o", "o", "-q"]);
    let m = manifest(&tmp.path().join("o"));
    let node = m["nodes"].as_array().unwrap().iter().find(|n| n["id"] == "impulse").unwrap();
    let key = node["key"].as_str().unwrap();
    let entry = tmp.path().join("o/.spindlelab-cache").join(&key[..2]).join(format!("{key}.bin"));
    std::fs::OpenOptions::new().write(true).open(&entry).unwrap().set_len(1 << 30).unwrap();
    let (o, peak) = run_measured(tmp.path(), &["run", r, "-o", "o"]);
    no_panic(&o);
    assert!(o.status.success(), "{}", text(&o));
    let said = text(&o);
    assert!(said.contains("`impulse` was not used") && said.contains("the rest was not read"), "{said}");
    let m = manifest(&tmp.path().join("o"));
    let node = m["nodes"].as_array().unwrap().iter().find(|n| n["id"] == "impulse").unwrap();
    assert_eq!(node["status"], "computed", "the padded entry is recomputed: {m}");
    assert!(peak < 256 << 20, "the run peaked at {} MiB: the padding was read", peak >> 20);
    assert!(std::fs::metadata(&entry).unwrap().len() < 1 << 20, "the entry is written again");
}

/// Items 12a and 12b: a file standing where the tool keeps its runs, or named by `-o`, refuses
/// the run with exit code 2, naming that file and what to do; the file is left as it was.
#[test]
fn a_file_where_the_tool_keeps_its_runs_or_named_by_o_is_refused_with_its_path() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = recipe_a(tmp.path());
    let r = recipe.to_str().unwrap();
    std::fs::create_dir_all(tmp.path().join("o/.spindlelab")).unwrap();
    std::fs::write(tmp.path().join("o/.spindlelab/runs"), b"mine").unwrap();
    let said = refused(tmp.path(), &["run", r, "-o", "o", "-q"]);
    assert!(said.contains("`o/.spindlelab/runs` is a file where spindlelab keeps"), "{said}");
    assert!(said.contains("move it away"), "{said}");
    assert_eq!(std::fs::read(tmp.path().join("o/.spindlelab/runs")).unwrap(), b"mine");

    std::fs::write(tmp.path().join("notes.txt"), b"mine").unwrap();
    let said = refused(tmp.path(), &["run", r, "-o", "notes.txt", "-q"]);
    assert!(said.contains("`notes.txt` is not a folder") && said.contains("-o"), "{said}");
    let said = refused(tmp.path(), &["run", r, "-o", "notes.txt/deeper", "-q"]);
    assert!(said.contains("`notes.txt` is not a folder"), "{said}");
    assert_eq!(std::fs::read(tmp.path().join("notes.txt")).unwrap(), b"mine");
}

/// Item 13b: a run whose every result comes from the cache records in its manifest the
/// warnings the fresh run recorded, node by node, including those of nodes it did not load.
#[test]
fn a_cached_run_records_the_warnings_of_a_fresh_one() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = tmp.path().join("w.yaml");
    std::fs::write(
        &recipe,
        r#"spindlelab: 1
name: warned
steps:
  hit:
    kind: impact.simulate
    params:
      hammer_stiffness: 500 N/m
      target_mass: 0.1 kg
      target_stiffness: 5e7 N/m
      target_damping: 50 N*s/m
      duration: 5 ms
      pre_trigger: 0.5 ms
      hammer_mass: 0.04 kg
  frf:
    kind: frf.estimate
    params: { windows: false, trigger: record-start }
    inputs: { force: "@hit.force", response: "@hit.displacement" }
  mobility:
    kind: frf.convert
    params: { to: mobility }
    inputs: { frf: "@frf.frf" }
  back:
    kind: frf.convert
    params: { to: receptance }
    inputs: { frf: "@mobility.frf" }
  again:
    kind: frf.convert
    params: { to: receptance }
    inputs: { frf: "@back.frf" }
outputs:
  - { from: "@again.frf", file: again.csv }
"#,
    )
    .unwrap();
    let r = recipe.to_str().unwrap();
    let warnings = |m: &serde_json::Value| -> BTreeMap<String, serde_json::Value> {
        m["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|n| (n["id"].as_str().unwrap().to_string(), n["warnings"].clone()))
            .collect()
    };
    ok(tmp.path(), &["run", r, "-o", "o", "-q"]);
    let fresh = manifest(&tmp.path().join("o"));
    assert!(
        fresh["nodes"].as_array().unwrap().iter().any(|n| n["id"] == "back" && n["warnings"].is_array()),
        "{fresh}"
    );
    ok(tmp.path(), &["run", r, "-o", "o", "-q"]);
    let cached = manifest(&tmp.path().join("o"));
    assert_eq!(cached["computed"], 0, "{cached}");
    assert_eq!(warnings(&cached), warnings(&fresh));
}

/// Item 13c: an empty folder at a cache entry's name is removed and the entry written (said
/// once, then served); a folder holding files there, or a file where the cache keeps a folder
/// of entries, is left as it is and every run says how to fix it.
#[test]
fn what_stands_in_the_way_of_a_cache_entry_is_repaired_or_said_how_to_fix() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = recipe_a(tmp.path());
    let r = recipe.to_str().unwrap();
    ok(tmp.path(), &["run", r, "-o", "o", "-q"]);
    let m = manifest(&tmp.path().join("o"));
    let key = |id: &str| {
        let n = m["nodes"].as_array().unwrap().iter().find(|n| n["id"] == id).unwrap();
        n["key"].as_str().unwrap().to_string()
    };
    let cache = tmp.path().join("o/.spindlelab-cache");
    let entry = |k: &str| cache.join(&k[..2]).join(format!("{k}.bin"));

    // An empty folder: repaired by the next run, served by the one after.
    let k = key("impulse");
    std::fs::remove_file(entry(&k)).unwrap();
    std::fs::create_dir(entry(&k)).unwrap();
    let o = ok(tmp.path(), &["run", r, "-o", "o", "-q"]);
    assert!(text(&o).contains("an empty folder stands at its name; it is removed"), "{}", text(&o));
    assert!(entry(&k).is_file(), "the entry is written in place of the empty folder");
    let o = ok(tmp.path(), &["run", r, "-o", "o", "-q"]);
    assert!(!text(&o).contains("cache entry"), "{}", text(&o));
    assert_eq!(manifest(&tmp.path().join("o"))["computed"], 0);

    // A folder holding files: kept, and said how to fix.
    std::fs::remove_file(entry(&k)).unwrap();
    std::fs::create_dir(entry(&k)).unwrap();
    std::fs::write(entry(&k).join("x"), b"someone's").unwrap();
    for _ in 0..2 {
        let o = ok(tmp.path(), &["run", r, "-o", "o", "-q"]);
        assert!(
            text(&o).contains("a folder holding files stands at its name") && text(&o).contains("rm -r"),
            "{}",
            text(&o)
        );
    }
    assert_eq!(std::fs::read(entry(&k).join("x")).unwrap(), b"someone's");
    std::fs::remove_dir_all(entry(&k)).unwrap();

    // A file where a folder of entries goes: kept, and said how to fix.
    let sub = entry(&k).parent().unwrap().to_path_buf();
    std::fs::remove_dir_all(&sub).unwrap();
    std::fs::write(&sub, b"someone's").unwrap();
    let o = ok(tmp.path(), &["run", r, "-o", "o", "-q"]);
    assert!(text(&o).contains("is a file where the cache keeps a folder of entries"), "{}", text(&o));
    assert_eq!(std::fs::read(&sub).unwrap(), b"someone's");
}
