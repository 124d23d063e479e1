//! The output folder is the user's too: what a run refuses to replace, the links and special
//! files it does not follow or wait on (docs/guarantees.md), each through the binary.

#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_spindlelab"));
    c.env("NO_COLOR", "1").env_remove("RUST_BACKTRACE");
    c
}

/// Runs the binary, failing the test (not hanging it) if it has not ended within a minute.
fn run_in(cwd: &Path, args: &[&str]) -> Output {
    let mut child = bin()
        .args(args)
        .current_dir(cwd)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary starts");
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            panic!("`spindlelab {}` hung", args.join(" "));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn text(o: &Output) -> String {
    format!("stdout:\n{}\nstderr:\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn no_panic(o: &Output) {
    let t = text(o);
    assert!(!t.contains("panicked"), "the binary panicked:\n{t}");
    assert_ne!(o.status.code(), Some(101), "{t}");
}

fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path; mkfifo only creates the node.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo {}", path.display());
}

/// A small swept recipe whose outputs are `outputs` (YAML list items).
fn write_recipe(dir: &Path, outputs: &[(&str, &str)]) -> PathBuf {
    let path = dir.join("r.yaml");
    let mut text = String::from(
        r#"spindlelab: 1
name: "edges"
steps:
  hit:
    kind: impact.simulate
    params:
      hammer_stiffness: 500 N/m
      target_mass: 0.1 kg
      target_stiffness: 5e7 N/m
    sweep:
      hammer_mass: 0.03..0.05 step 0.01 kg
  impulse:
    kind: table.collect
    inputs: { values: "@hit.impulse_time" }
outputs:
"#,
    );
    for (from, file) in outputs {
        text.push_str(&format!("  - {{ from: \"{from}\", file: \"{file}\" }}\n"));
    }
    std::fs::write(&path, text).unwrap();
    path
}

/// The cache entry of the first instance of `step` in the last run of the output folder
/// `out` (by the key its manifest records): the consumer's entry, which a rerun needs.
fn entry_of(out: &Path, step: &str) -> PathBuf {
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    let node = m["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["id"].as_str().is_some_and(|id| id == step || id.starts_with(&format!("{step}["))))
        .unwrap_or_else(|| panic!("no instance of `{step}` in the manifest"));
    let key = node["key"].as_str().unwrap();
    out.join(".spindlelab-cache").join(&key[..2]).join(format!("{key}.bin"))
}

fn entries(cache: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for sub in std::fs::read_dir(cache).unwrap().flatten() {
        if sub.file_type().unwrap().is_dir() {
            for e in std::fs::read_dir(sub.path()).unwrap().flatten() {
                if e.file_name().to_string_lossy().ends_with(".bin") {
                    out.push(e.path());
                }
            }
        }
    }
    out.sort();
    out
}

#[test]
fn a_users_file_named_like_an_output_is_refused_before_computing_and_kept() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = write_recipe(tmp.path(), &[("@impulse.table", "impulse.csv"), ("@hit.force", "sub/force.csv")]);
    let out = tmp.path().join("o");
    std::fs::create_dir_all(out.join("empty")).unwrap();
    std::fs::write(out.join("impulse.csv"), b"the user's own data\n").unwrap();
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(said.contains("impulse.csv") && said.contains("did not write"), "{said}");
    assert!(!said.contains("computed"), "refused before computing: {said}");
    assert_eq!(std::fs::read(out.join("impulse.csv")).unwrap(), b"the user's own data\n");
    assert!(!out.join(".spindlelab/current").exists(), "nothing committed");

    // Moved away, the run goes through; the user's empty folder outlives it and a rerun.
    std::fs::rename(out.join("impulse.csv"), tmp.path().join("mine.csv")).unwrap();
    for _ in 0..2 {
        let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o", "-q"]);
        assert!(o.status.success(), "{}", text(&o));
    }
    std::fs::write(
        &recipe,
        std::fs::read_to_string(&recipe)
            .unwrap()
            .replace("  - { from: \"@hit.force\", file: \"sub/force.csv\" }\n", ""),
    )
    .unwrap();
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o", "-q"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(out.join("empty").is_dir(), "the user's empty folder was removed");
    assert!(std::fs::symlink_metadata(out.join("sub")).is_err(), "the run's own folder link goes with its files");
}

#[test]
fn a_name_turns_from_file_to_folder_between_runs_and_back() {
    let tmp = tempfile::tempdir().unwrap();
    let cases: [&[(&str, &str)]; 3] =
        [&[("@impulse.table", "t.csv")], &[("@impulse.table", "t.csv/x.csv")], &[("@impulse.table", "t.csv")]];
    for (i, outputs) in cases.into_iter().enumerate() {
        let recipe = write_recipe(tmp.path(), outputs);
        let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o", "-q"]);
        no_panic(&o);
        assert!(o.status.success(), "run {i}: {}", text(&o));
        let file = tmp.path().join("o").join(outputs[0].1);
        assert!(std::fs::read_to_string(&file).unwrap().contains("hammer_mass_kg"), "run {i}: {}", file.display());
    }
}

#[test]
fn a_linked_cache_folder_or_lock_is_not_written_through() {
    let tmp = tempfile::tempdir().unwrap();
    let elsewhere = tempfile::tempdir().unwrap();
    let recipe = write_recipe(tmp.path(), &[("@impulse.table", "impulse.csv")]);
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o", "-q"]);
    assert!(o.status.success(), "{}", text(&o));
    let cache = tmp.path().join("o/.spindlelab-cache");
    let before = entries(&cache).len();
    // A cache subfolder replaced by a link to another folder: the one of the table's entry,
    // which the rerun needs (an entry no output needs is not recomputed).
    let sub = entry_of(&tmp.path().join("o"), "impulse").parent().unwrap().to_path_buf();
    std::fs::remove_dir_all(&sub).unwrap();
    std::os::unix::fs::symlink(elsewhere.path(), &sub).unwrap();
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o"]);
    no_panic(&o);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("symbolic link"), "the repair is said: {}", text(&o));
    assert_eq!(std::fs::read_dir(elsewhere.path()).unwrap().count(), 0, "entries written through the link");
    assert_eq!(entries(&cache).len(), before, "the entries are back in the cache");
    let du = run_in(tmp.path(), &["cache", "du", "o"]);
    assert!(String::from_utf8_lossy(&du.stdout).contains(&format!("{before} entries")), "{}", text(&du));

    // A link at the lock: refused, and nothing is created where it points.
    let lock = tmp.path().join("o/.spindlelab/lock");
    std::fs::remove_file(&lock).unwrap();
    std::os::unix::fs::symlink(elsewhere.path().join("planted"), &lock).unwrap();
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o", "-q"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("lock") && text(&o).contains("symbolic link"), "{}", text(&o));
    assert!(!elsewhere.path().join("planted").exists());
}

#[test]
fn pipes_and_devices_in_the_cache_are_recomputed_not_waited_on() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = write_recipe(tmp.path(), &[("@impulse.table", "impulse.csv")]);
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o", "-q"]);
    assert!(o.status.success(), "{}", text(&o));
    let first = std::fs::read(tmp.path().join("o/impulse.csv")).unwrap();
    // The table's entry and one of its inputs', both needed by the rerun.
    let all = [entry_of(&tmp.path().join("o"), "impulse"), entry_of(&tmp.path().join("o"), "hit")];
    std::fs::remove_file(&all[0]).unwrap();
    mkfifo(&all[0]);
    std::fs::remove_file(&all[1]).unwrap();
    std::os::unix::fs::symlink("/dev/zero", &all[1]).unwrap();
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o"]);
    no_panic(&o);
    assert!(o.status.success(), "{}", text(&o));
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(said.matches("was not used").count() >= 1, "{said}");
    assert_eq!(std::fs::read(tmp.path().join("o/impulse.csv")).unwrap(), first);
    // Both are ordinary entries again.
    for e in &all[..2] {
        assert!(std::fs::symlink_metadata(e).unwrap().is_file(), "{} not replaced", e.display());
    }
}

#[test]
fn a_pipe_named_as_a_plugin_or_its_component_is_refused_not_waited_on() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    mkfifo(&dir.join("c.wasm"));
    std::fs::write(
        dir.join("p.plugin.json"),
        format!(r#"{{"id":"p","version":"0.1.0","interface":"0.2.0","wasm":"c.wasm","sha256":"{}"}}"#, "0".repeat(64)),
    )
    .unwrap();
    mkfifo(&dir.join("q.plugin.json"));
    for manifest in ["p.plugin.json", "q.plugin.json"] {
        std::fs::write(
            dir.join("r.yaml"),
            format!("spindlelab: 1\nname: pipes\nplugins:\n  - {{ path: {manifest} }}\nsteps: {{}}\n"),
        )
        .unwrap();
        let o = run_in(dir, &["check", "r.yaml"]);
        no_panic(&o);
        assert_eq!(o.status.code(), Some(2), "{manifest}: {}", text(&o));
        assert!(text(&o).contains("not a regular file"), "{manifest}: {}", text(&o));
    }
}

/// `scripts/rotating-frf.yaml` as `r.yaml` in `dir`, with the libraries and the procedure it uses.
fn copy_rotating_frf(dir: &Path) {
    let scripts = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts");
    std::fs::copy(scripts.join("rotating-frf.yaml"), dir.join("r.yaml")).unwrap();
    for folder in ["lib", "procedures"] {
        std::fs::create_dir_all(dir.join(folder)).unwrap();
        for e in std::fs::read_dir(scripts.join(folder)).unwrap().flatten() {
            std::fs::copy(e.path(), dir.join(folder).join(e.file_name())).unwrap();
        }
    }
}

#[test]
fn plan_says_why_a_rerun_remakes_an_uncached_intermediate() {
    let tmp = tempfile::tempdir().unwrap();
    copy_rotating_frf(tmp.path());
    let o = run_in(tmp.path(), &["run", "r.yaml", "-o", "o", "-q"]);
    assert!(o.status.success(), "{}", text(&o));
    let o = run_in(tmp.path(), &["plan", "r.yaml", "-o", "o"]);
    assert!(o.status.success(), "{}", text(&o));
    let plan = String::from_utf8_lossy(&o.stdout);
    // The impact table is written to a file from the uncached segmenter: it and what feeds it
    // run again, and the plan names the file and the chain; the FRFs come from the cache.
    let line =
        |id: &str| plan.lines().find(|l| l.starts_with(id)).unwrap_or_else(|| panic!("{id}: {plan}")).to_string();
    assert!(line("records[").contains("the output `impacts.csv` needs it"), "{plan}");
    assert!(line("runout[").contains("`records["), "{plan}");
    assert!(line("frf[").contains("from cache"), "{plan}");
}

/// Peak resident memory of one run of the binary, in KiB (from the kernel's account of the
/// child, not sampled).
fn peak_kib(cwd: &Path, args: &[&str]) -> i64 {
    // Reaped by `wait4` below, which also reports its peak memory.
    #[allow(clippy::zombie_processes)]
    let child = bin().args(args).current_dir(cwd).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
    let mut status = 0;
    // SAFETY: a zeroed rusage is a valid value for wait4 to fill in.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: waits for our own child, with valid pointers to locals.
    let pid = unsafe { libc::wait4(child.id() as libc::pid_t, &mut status, 0, &mut usage) };
    assert_eq!(pid, child.id() as libc::pid_t);
    assert!(libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0, "`spindlelab {}` failed", args.join(" "));
    usage.ru_maxrss
}

#[test]
fn threads_beyond_the_cores_do_not_multiply_the_memory_of_large_intermediates() {
    let tmp = tempfile::tempdir().unwrap();
    copy_rotating_frf(tmp.path());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let at = |j: usize| {
        peak_kib(tmp.path(), &["run", "r.yaml", "-o", &format!("o{j}"), "-q", "--no-cache", "-j", &j.to_string()])
    };
    let (few, many) = (at(cores), at(8 * cores));
    // Eighteen raw recordings: before the bound, eight times the threads held about twice the memory.
    assert!((many as f64) < 1.3 * few as f64, "-j {cores}: {few} KiB, -j {}: {many} KiB", 8 * cores);
}

#[test]
fn a_full_disk_fails_the_run_cleanly_and_leaves_the_previous_run_whole() {
    use std::os::unix::process::CommandExt;
    let tmp = tempfile::tempdir().unwrap();
    let recipe = write_recipe(tmp.path(), &[("@impulse.table", "impulse.csv"), ("@hit.force", "sub/force.csv")]);
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o", "-q"]);
    assert!(o.status.success(), "{}", text(&o));
    let before: Vec<Vec<u8>> =
        ["impulse.csv", "sub/force.csv"].iter().map(|f| std::fs::read(tmp.path().join("o").join(f)).unwrap()).collect();
    std::fs::write(&recipe, std::fs::read_to_string(&recipe).unwrap().replace("500 N/m", "800 N/m")).unwrap();
    for limit in [0u64, 512, 4096] {
        // Every file the run writes stops at `limit` bytes, as on a full disk (EFBIG; the
        // signal that would kill the process is ignored, as a full disk sends none).
        let mut cmd = bin();
        cmd.args(["run", recipe.to_str().unwrap(), "-o", "o"]).current_dir(tmp.path());
        // SAFETY: only async-signal-safe calls between fork and exec.
        unsafe {
            cmd.pre_exec(move || {
                libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
                let lim = libc::rlimit { rlim_cur: limit, rlim_max: libc::RLIM_INFINITY };
                if libc::setrlimit(libc::RLIMIT_FSIZE, &lim) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
        let o = cmd.output().unwrap();
        no_panic(&o);
        assert_eq!(o.status.code(), Some(1), "limit {limit}: {}", text(&o));
        assert!(String::from_utf8_lossy(&o.stderr).contains("error"), "limit {limit}: {}", text(&o));
        for (f, bytes) in ["impulse.csv", "sub/force.csv"].iter().zip(&before) {
            assert_eq!(&std::fs::read(tmp.path().join("o").join(f)).unwrap(), bytes, "limit {limit}: {f} changed");
        }
    }
    // With room again the run completes, and no half-written cache entry is served.
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(!text(&o).contains("was not used"), "{}", text(&o));
    assert_ne!(std::fs::read(tmp.path().join("o/impulse.csv")).unwrap(), before[0]);
}

/// With `--keep-going`, a swept output keeps the sweep points that succeeded and marks the one
/// that failed, in the file (`# missing:` in CSV, a `missing` item in JSON) and the manifest;
/// an unswept output of the failed step is not written.
#[test]
fn keep_going_writes_the_sweep_points_that_succeeded_and_marks_the_failed_one() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("r.yaml"),
        r#"spindlelab: 1
name: partial
steps:
  divisor:
    kind: rhai.eval
    sweep: { expr: ["1.0", "0.0", "4.0"] }
  ratio:
    kind: rhai.eval
    params: { expr: "2.0 / x", unit: m }
    inputs: { x: "@divisor.value" }
  scaled:
    kind: rhai.eval
    params: { expr: "x * 1000.0", unit: mm }
    inputs: { x: "@ratio.value" }
  first:
    kind: rhai.eval
    params: { expr: "1.0 / 0.0" }
outputs:
  - { from: "@ratio.value", file: ratio.csv }
  - { from: "@scaled.value", file: scaled.csv }
  - { from: "@ratio.value", file: ratio.json }
  - { from: "@first.value", file: first.csv }
"#,
    )
    .unwrap();
    let o = run_in(dir.path(), &["run", "--no-cache", "-o", "out", "r.yaml"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let out = dir.path().join("out");
    assert!(!out.join("ratio.csv").exists(), "without --keep-going nothing is written: {}", text(&o));

    let o = run_in(dir.path(), &["run", "--no-cache", "--keep-going", "-o", "out", "r.yaml"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "the run still fails: {}", text(&o));
    let said = text(&o);
    assert!(said.contains("ratio.csv (without 1 sweep point(s))"), "{said}");
    assert!(!out.join("first.csv").exists(), "an unswept output of a failed step is not written");

    // The CSV: the two good points read back through the table reader, the failed one listed.
    let bytes = std::fs::read(out.join("ratio.csv")).unwrap();
    let missing = spindlelab::engine::formats::csv::missing_points(&bytes);
    assert_eq!(missing.len(), 1, "{}", String::from_utf8_lossy(&bytes));
    assert!(missing[0].starts_with("expr=0.0 (failed: "), "{missing:?}");
    assert!(missing[0].contains("gave inf"), "{missing:?}");
    let downstream = spindlelab::engine::formats::csv::missing_points(&std::fs::read(out.join("scaled.csv")).unwrap());
    assert_eq!(downstream, ["expr=0.0 (not run: its input `ratio[expr=0.0]` failed)"]);
    let blocks = spindlelab::engine::formats::csv::read_tables(&bytes, "ratio.csv").unwrap();
    let got: Vec<(String, f64)> =
        blocks.iter().map(|b| (b.coords[0].1.clone(), b.table.columns[0].values[0])).collect();
    assert_eq!(got, [("1.0".to_string(), 2.0), ("4.0".to_string(), 0.5)]);

    // The JSON: the values, and an item saying which point is missing and why.
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("ratio.json")).unwrap()).unwrap();
    let items = json.as_array().unwrap();
    assert_eq!(items.len(), 3);
    assert_eq!(items.iter().filter(|i| i.get("value").is_some()).count(), 2);
    let gone = items.iter().find(|i| i.get("missing").is_some()).unwrap();
    assert_eq!(gone["label"], "expr=0.0");

    // The manifest: both partial files, the point, the instance and the reason.
    let m: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    for file in ["ratio.csv", "ratio.json"] {
        let p = &m["partial"][file][0];
        assert_eq!(p["label"], "expr=0.0", "{m:#}");
        assert_eq!(p["instance"], "ratio[expr=0.0]");
        assert!(p["reason"].as_str().unwrap().starts_with("failed: "), "{p}");
    }
    assert!(m["partial"].get("first.csv").is_none());
}
