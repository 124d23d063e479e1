//! What a run promises when it is killed, run twice at once, or handed a hostile recipe or
//! data file (docs/guarantees.md), each reproduced through the binary.

use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::Duration;

use crate::common::binary::{bin, no_panic, run_in, text};
use crate::common::shared;

/// A small recipe with a sweep: a few files, a few hundred milliseconds.
fn write_recipe(dir: &Path, name: &str, hammer_stiffness: &str) -> PathBuf {
    let path = dir.join("r.yaml");
    std::fs::write(
        &path,
        format!(
            r#"spindlelab: 1
name: "{name}"
steps:
  hit:
    kind: impact.simulate
    params:
      hammer_stiffness: {hammer_stiffness}
      target_mass: 0.1 kg
      target_stiffness: 5e7 N/m
    sweep:
      hammer_mass: 0.03..0.07 step 0.01 kg
  impulse:
    kind: table.collect
    inputs: {{ values: "@hit.impulse_time" }}
outputs:
  - {{ from: "@impulse.table", file: impulse.csv }}
  - {{ from: "@hit.force", file: sub/force.csv }}
"#
        ),
    )
    .unwrap();
    path
}

/// Every entry under `dir` (following nothing), relative, sorted.
pub(crate) fn tree(dir: &Path) -> Vec<String> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) {
        for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
            let p = e.path();
            out.push(p.strip_prefix(root).unwrap().display().to_string());
            if e.file_type().is_ok_and(|t| t.is_dir()) {
                walk(root, &p, out);
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out.sort();
    out
}

/// The folder as a reader sees it: the manifest, and every file it lists with the hash it
/// states; no other visible file.
fn assert_one_complete_run(out: &Path) {
    let Ok(text) = std::fs::read_to_string(out.join("manifest.json")) else {
        // Before the first commit there is no run at all, and no visible output either.
        let visible: Vec<String> = tree(out).into_iter().filter(|p| !p.starts_with('.')).collect();
        assert!(visible.iter().all(|p| std::fs::metadata(out.join(p)).is_err() || out.join(p).is_dir()), "{visible:?}");
        return;
    };
    let m: serde_json::Value = serde_json::from_str(&text).expect("the manifest is whole");
    let files = m["files"].as_object().expect("the manifest lists its files");
    for (rel, hash) in files {
        let bytes = std::fs::read(out.join(rel)).unwrap_or_else(|e| panic!("{rel} listed but unreadable: {e}"));
        assert_eq!(blake3::hash(&bytes).to_hex().as_str(), hash.as_str().unwrap(), "{rel} is not the run's file");
    }
    for rel in tree(out) {
        let p = out.join(&rel);
        if rel.starts_with('.') || p.is_dir() || rel == "manifest.json" {
            continue;
        }
        if std::fs::metadata(&p).is_ok() {
            assert!(files.contains_key(&rel), "`{rel}` is visible but not part of the committed run");
        }
    }
}

#[test]
fn a_recipe_name_cannot_lead_the_default_folder_out_of_out() {
    for name in ["..", "../../x", "/elsewhere/x", "a/../../b"] {
        let tmp = tempfile::tempdir().unwrap();
        let work = tmp.path().join("work");
        std::fs::create_dir_all(&work).unwrap();
        write_recipe(&work, name, "500 N/m");
        let o = run_in(&work, &["run", "r.yaml", "-q"]);
        no_panic(&o);
        assert!(o.status.success(), "{}", text(&o));
        // Everything is under work/out/<one folder>.
        let top: Vec<String> =
            std::fs::read_dir(tmp.path()).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into()).collect();
        assert_eq!(top, ["work"], "name {name:?} wrote beside the working folder");
        let inside: Vec<String> =
            std::fs::read_dir(&work).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into()).collect();
        let mut inside = inside;
        inside.sort();
        assert_eq!(inside, ["out", "r.yaml"], "name {name:?}");
        let folders: Vec<PathBuf> = std::fs::read_dir(work.join("out")).unwrap().map(|e| e.unwrap().path()).collect();
        assert_eq!(folders.len(), 1);
        assert!(folders[0].join("impulse.csv").is_file(), "name {name:?}: {folders:?}");
    }
}

#[test]
fn a_planted_link_in_the_output_folder_is_not_written_through() {
    let tmp = tempfile::tempdir().unwrap();
    let elsewhere = tempfile::tempdir().unwrap();
    let recipe = write_recipe(tmp.path(), "r", "500 N/m");
    let out = tmp.path().join("o");
    std::fs::create_dir_all(&out).unwrap();
    std::os::unix::fs::symlink(elsewhere.path(), out.join("sub")).unwrap();
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o", "-q"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("symbolic link"), "{}", text(&o));
    assert_eq!(std::fs::read_dir(elsewhere.path()).unwrap().count(), 0, "wrote through the link");

    // A linked cache folder is refused too.
    let out2 = tmp.path().join("o2");
    std::fs::create_dir_all(&out2).unwrap();
    std::os::unix::fs::symlink(elsewhere.path(), out2.join(".spindlelab-cache")).unwrap();
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o2", "-q"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert_eq!(std::fs::read_dir(elsewhere.path()).unwrap().count(), 0, "wrote through the cache link");
}

#[test]
fn outputs_that_name_one_file_twice_or_the_manifest_are_refused_at_compile_time() {
    let tmp = tempfile::tempdir().unwrap();
    let base = std::fs::read_to_string(write_recipe(tmp.path(), "r", "500 N/m")).unwrap();
    let head = &base[..base.find("outputs:").unwrap()];
    for (outputs, says) in [
        (
            "  - { from: \"@impulse.table\", file: t.csv }\n  - { from: \"@impulse.table\", file: ./t.csv }\n",
            "two outputs write `t.csv`",
        ),
        (
            "  - { from: \"@impulse.table\", file: manifest.json }\n",
            "`manifest.json` is a file spindlelab writes itself",
        ),
        (
            "  - { from: \"@impulse.table\", file: t.csv }\n  - { from: \"@hit.force\", file: t.csv/f.csv }\n",
            "one is inside the other",
        ),
    ] {
        std::fs::write(tmp.path().join("bad.yaml"), format!("{head}outputs:\n{outputs}")).unwrap();
        let o = run_in(tmp.path(), &["check", "bad.yaml"]);
        no_panic(&o);
        assert_eq!(o.status.code(), Some(2), "{}", text(&o));
        assert!(text(&o).contains(says), "expected `{says}`:\n{}", text(&o));
        assert!(text(&o).contains("bad.yaml:"), "no location:\n{}", text(&o));
    }
}

#[test]
fn a_second_run_into_a_busy_folder_is_refused_and_the_first_completes() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = write_recipe(tmp.path(), "r", "500 N/m");
    let out = tmp.path().join("o");
    // Hold the folder's lock as a running run does.
    std::fs::create_dir_all(out.join(".spindlelab")).unwrap();
    let lock = std::fs::File::create(out.join(".spindlelab/lock")).unwrap();
    lock.lock().unwrap();
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o", "-q"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("in use by another run"), "{}", text(&o));
    assert!(!out.join("manifest.json").exists());
    drop(lock);
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o", "-q"]);
    assert!(o.status.success(), "{}", text(&o));
    assert_one_complete_run(&out);
}

#[test]
fn concurrent_runs_into_one_folder_never_mix() {
    let tmp = tempfile::tempdir().unwrap();
    let a = write_recipe(tmp.path(), "r", "500 N/m");
    let b_dir = tmp.path().join("b");
    std::fs::create_dir_all(&b_dir).unwrap();
    let b = write_recipe(&b_dir, "r", "900 N/m");
    for _ in 0..4 {
        let spawn = |r: &Path| {
            bin()
                .args(["run", r.to_str().unwrap(), "-o", "o", "-q", "--no-cache"])
                .current_dir(tmp.path())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        };
        let (pa, pb) = (spawn(&a), spawn(&b));
        let (oa, ob) = (pa.wait_with_output().unwrap(), pb.wait_with_output().unwrap());
        no_panic(&oa);
        no_panic(&ob);
        // Each either ran whole or was refused; at least one ran.
        for o in [&oa, &ob] {
            assert!(o.status.success() || o.status.code() == Some(2), "{}", text(o));
        }
        assert!(oa.status.success() || ob.status.success());
        assert_one_complete_run(&tmp.path().join("o"));
    }
}

#[test]
fn a_run_killed_at_any_moment_leaves_one_complete_run() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = write_recipe(tmp.path(), "r", "500 N/m");
    let out = tmp.path().join("o");
    // Deterministic spread of kill times over a run's whole length (build to commit).
    let mut survived_commit = 0;
    for (i, ms) in [0u64, 3, 7, 12, 20, 30, 45, 60, 90, 130, 200, 300].iter().enumerate() {
        let mut args = vec!["run", recipe.to_str().unwrap(), "-o", "o", "-q"];
        if i % 2 == 0 {
            args.push("--no-cache");
        }
        // Now and then a cache entry is a pipe or a link to a device, as damage can leave it.
        let entry = tree(&out.join(".spindlelab-cache")).into_iter().find(|p| p.ends_with(".bin"));
        if let Some(entry) = entry.filter(|_| i % 3 != 0) {
            let entry = out.join(".spindlelab-cache").join(entry);
            std::fs::remove_file(&entry).unwrap();
            if i % 3 == 1 {
                let c = std::ffi::CString::new(entry.as_os_str().as_encoded_bytes()).unwrap();
                // SAFETY: a valid NUL-terminated path; mkfifo only creates the node.
                assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
            } else {
                std::os::unix::fs::symlink("/dev/zero", &entry).unwrap();
            }
        }
        let mut child = bin().args(&args).current_dir(tmp.path()).stderr(Stdio::null()).spawn().unwrap();
        std::thread::sleep(Duration::from_millis(*ms));
        let _ = child.kill(); // SIGKILL
        let status = child.wait().unwrap();
        if status.success() {
            survived_commit += 1;
        }
        assert_one_complete_run(&out);
    }
    // A rerun cleans what the killed ones left and commits a whole run; no pipe or link is
    // left standing as an entry.
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o", "-q"]);
    assert!(o.status.success(), "{}", text(&o));
    for e in tree(&out.join(".spindlelab-cache")).into_iter().filter(|p| p.ends_with(".bin")) {
        let m = std::fs::symlink_metadata(out.join(".spindlelab-cache").join(&e)).unwrap();
        assert!(m.is_file(), "{e} is not a regular entry after the rerun");
    }
    assert_one_complete_run(&out);
    let runs = std::fs::read_dir(out.join(".spindlelab/runs")).unwrap().count();
    assert!(runs <= 2, "{runs} run folders left (current and previous expected)");
    let tmp_files: Vec<String> =
        tree(&out.join(".spindlelab-cache")).into_iter().filter(|p| p.contains(".tmp")).collect();
    assert!(tmp_files.is_empty(), "{tmp_files:?}");
    assert!(tree(&out).iter().all(|p| !p.contains(".staging")));
    let _ = survived_commit;
}

#[test]
fn a_failed_rerun_leaves_no_earlier_output_standing_unmarked() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("m.csv"), "# units: m/N\nfreq_hz,real,imag\n100,1e-6,-1e-6\n200,2e-6,-3e-6\n")
        .unwrap();
    std::fs::write(
        tmp.path().join("r.yaml"),
        "spindlelab: 1\nname: f\nsteps:\n  m:\n    kind: read.frf\n    params: { file: m.csv }\noutputs:\n  - { from: \"@m.frf\", file: copy.csv }\n",
    )
    .unwrap();
    let o = run_in(tmp.path(), &["run", "r.yaml", "-o", "o", "-q"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(tmp.path().join("o/copy.csv").is_file());
    // The data file goes bad: the rerun compiles, runs and fails in the node.
    std::fs::write(tmp.path().join("m.csv"), "# units: m/N\nfreq_hz,real,imag\n100,abc,-1e-6\n").unwrap();
    let o = run_in(tmp.path(), &["run", "r.yaml", "-o", "o", "-q"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(!tmp.path().join("o/copy.csv").exists(), "a stale output stands beside the failed run");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("o/manifest.json")).unwrap()).unwrap();
    assert!(m["nodes"].as_array().unwrap().iter().any(|n| n["status"] == "failed"), "{m}");
    assert_one_complete_run(&tmp.path().join("o"));
    // The previous run's files are kept until the next run.
    assert!(tmp.path().join("o/.spindlelab/previous/copy.csv").is_file());
}

#[test]
fn a_swapped_or_damaged_cache_entry_is_recomputed_and_said() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = write_recipe(tmp.path(), "r", "500 N/m");
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o", "-q"]);
    assert!(o.status.success(), "{}", text(&o));
    let first: Vec<(String, Vec<u8>)> = ["impulse.csv", "sub/force.csv"]
        .iter()
        .map(|f| (f.to_string(), std::fs::read(tmp.path().join("o").join(f)).unwrap()))
        .collect();
    let mut entries: Vec<PathBuf> = tree(&tmp.path().join("o/.spindlelab-cache"))
        .into_iter()
        .filter(|p| p.ends_with(".bin"))
        .map(|p| tmp.path().join("o/.spindlelab-cache").join(p))
        .collect();
    entries.sort();
    assert!(entries.len() >= 3);
    // Swap two entries, damage a third.
    let (a, b) = (std::fs::read(&entries[0]).unwrap(), std::fs::read(&entries[1]).unwrap());
    std::fs::write(&entries[0], &b).unwrap();
    std::fs::write(&entries[1], &a).unwrap();
    let mut c = std::fs::read(&entries[2]).unwrap();
    let last = c.len() - 1;
    c[last] ^= 0xff;
    std::fs::write(&entries[2], &c).unwrap();
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o"]);
    assert!(o.status.success(), "{}", text(&o));
    let said = String::from_utf8_lossy(&o.stderr);
    assert_eq!(said.matches("was not used").count(), 3, "{said}");
    assert!(said.contains("written for another node") && said.contains("checksum"), "{said}");
    for (f, bytes) in first {
        assert_eq!(std::fs::read(tmp.path().join("o").join(&f)).unwrap(), bytes, "{f} differs after the swap");
    }
}

#[test]
fn cache_entries_follow_the_umask_and_the_cache_command_sees_and_bounds_them() {
    use std::os::unix::fs::PermissionsExt;
    let tmp = tempfile::tempdir().unwrap();
    let recipe = write_recipe(tmp.path(), "r", "500 N/m");
    assert!(run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "out/r", "-q"]).status.success());
    let entry = tree(&tmp.path().join("out/r/.spindlelab-cache")).into_iter().find(|p| p.ends_with(".bin")).unwrap();
    let mode = std::fs::metadata(tmp.path().join("out/r/.spindlelab-cache").join(entry)).unwrap().permissions().mode();
    assert_ne!(mode & 0o077, 0, "entry mode {mode:o} ignores the umask (0600)");

    let du = |cwd: &Path| String::from_utf8_lossy(&run_in(cwd, &["cache", "du"]).stdout).to_string();
    let before = du(tmp.path());
    assert!(before.contains("out/r:") && before.contains("entries"), "{before}");
    // A changed parameter leaves entries the latest runs no longer use... after two more runs.
    for k in ["600 N/m", "700 N/m"] {
        std::fs::write(&recipe, std::fs::read_to_string(&recipe).unwrap().replace("500 N/m", k).replace("600 N/m", k))
            .unwrap();
        assert!(run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "out/r", "-q"]).status.success());
    }
    let gc = run_in(tmp.path(), &["cache", "gc"]);
    assert!(gc.status.success(), "{}", text(&gc));
    let said = String::from_utf8_lossy(&gc.stdout);
    assert!(said.contains("removed") && !said.contains("removed 0 entries"), "{said}");
    // What the latest run used stays: a rerun computes nothing.
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "out/r"]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("0 computed"), "{}", text(&o));
    let clean = run_in(tmp.path(), &["cache", "clean", "out/r"]);
    assert!(clean.status.success());
    assert!(du(tmp.path()).contains("0 entries"));
}

#[test]
fn output_into_a_closed_pipe_ends_quietly() {
    for args in [&["nodes"][..], &["schema"][..]] {
        let mut child = bin().args(args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
        drop(child.stdout.take()); // the reader goes away at once, as `| head -0` would
        let o = child.wait_with_output().unwrap();
        no_panic(&o);
        assert!(!String::from_utf8_lossy(&o.stderr).contains("panicked"));
    }
}

#[test]
fn thread_counts_are_clamped_and_said() {
    let tmp = tempfile::tempdir().unwrap();
    let recipe = write_recipe(tmp.path(), "r", "500 N/m");
    let o = run_in(tmp.path(), &["run", recipe.to_str().unwrap(), "-o", "o", "-j", "100000", "-q"]);
    no_panic(&o);
    assert!(o.status.success(), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("-j 100000 is outside"), "{}", text(&o));
}

#[test]
fn device_files_and_pipes_are_read_up_to_the_cap_only() {
    let tmp = tempfile::tempdir().unwrap();
    let o = run_in(tmp.path(), &["check", "/dev/zero"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("byte limit"), "{}", text(&o));
    // A data file that is a device: the node says so, the run does not fill memory.
    std::fs::write(
        tmp.path().join("r.yaml"),
        "spindlelab: 1\nname: dev\nsteps:\n  m:\n    kind: read.frf\n    params: { file: /dev/zero }\n",
    )
    .unwrap();
    let o = run_in(tmp.path(), &["run", "r.yaml", "-o", "o", "-q"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
}

#[test]
fn sweep_products_beyond_the_cap_are_refused_with_their_size() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("r.yaml"),
        r#"spindlelab: 1
name: big
steps:
  hit:
    kind: impact.simulate
    params: { target_mass: 0.1 kg, target_stiffness: 5e7 N/m }
    sweep:
      hammer_mass: 0.01..10.01 step 0.0001 kg
      hammer_stiffness: 100..100100 step 1 N/m
"#,
    )
    .unwrap();
    let o = run_in(tmp.path(), &["check", "r.yaml"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("10000200001 node instances"), "{}", text(&o));
    assert!(text(&o).contains("r.yaml:"), "{}", text(&o));
}

#[test]
fn uff_headers_that_claim_more_points_than_the_file_holds_are_errors() {
    let tmp = tempfile::tempdir().unwrap();
    // A dataset 58 (ASCII) claiming 99,999,999,999 points, and a 58b whose point count times
    // 24 bytes (complex doubles with an abscissa) overflows.
    let header = |kind: &str, points: &str, even: u8| {
        let id = if kind == "58b" {
            "    58b     1     2          11        8008     0     0           0           0".to_string()
        } else {
            "    58".to_string()
        };
        format!(
            "    -1\n{id}\nFRF x direct\nspindle test\nfixture\n\n\n    4         0    0         0       tool         1   1       tool         1   1\n         6 {points}         {even}  0.00000e+00  1.00000e+00  0.00000e+00\n        18    0    0    0 NONE                 Hz\n         8    0    0    0 NONE                 m\n        13    0    0    0 NONE                 N\n         0    0    0    0 NONE                 NONE\n  1.0 2.0\n    -1\n"
        )
    };
    for (kind, points, even) in [("58", "99999999999", 1), ("58b", "3074457345618258603", 0)] {
        std::fs::write(tmp.path().join("big.uff"), header(kind, points, even)).unwrap();
        std::fs::write(
            tmp.path().join("r.yaml"),
            "spindlelab: 1\nname: u\nsteps:\n  m:\n    kind: read.frf\n    params: { file: big.uff }\n",
        )
        .unwrap();
        let o = run_in(tmp.path(), &["run", "r.yaml", "-o", "o", "-q"]);
        no_panic(&o);
        assert_eq!(o.status.code(), Some(2), "{kind}: {}", text(&o));
        assert!(text(&o).contains("big.uff"), "{kind}: {}", text(&o));
    }
}

#[test]
fn an_implausible_quantity_is_warned_about_with_the_likely_unit() {
    let tmp = tempfile::tempdir().unwrap();
    let study =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/impact-study.yaml")).unwrap();
    let line = study.lines().position(|l| l.contains("tip_radius:")).expect("the study sets a tip radius") + 1;
    let bad: String = study
        .lines()
        .map(|l| {
            if l.contains("tip_radius:") {
                format!("{}tip_radius: 6.35 m", &l[..l.find("tip_radius").unwrap()])
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(tmp.path().join("r.yaml"), bad).unwrap();
    let o = run_in(tmp.path(), &["check", "r.yaml"]);
    no_panic(&o);
    assert!(o.status.success(), "a warning, not an error: {}", text(&o));
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(said.contains(&format!("r.yaml:{line}:")), "{said}");
    assert!(said.contains("`6.35 m` for `tip_radius` is outside the usual range"), "{said}");
    assert!(said.contains("did you mean `6.35 mm`?"), "{said}");
}

#[test]
fn a_data_file_that_is_not_csv_never_has_its_lines_quoted() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("secret.csv"), "root:x:0:0:root:/root:/bin/bash\n").unwrap();
    std::fs::write(
        tmp.path().join("r.yaml"),
        "spindlelab: 1\nname: s\nsteps:\n  m:\n    kind: read.frf\n    params: { file: secret.csv }\n",
    )
    .unwrap();
    let o = run_in(tmp.path(), &["run", "r.yaml", "-o", "o", "-q"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let said = text(&o);
    assert!(said.contains("secret.csv:1"), "{said}");
    assert!(!said.contains("root:x"), "a line of the file was quoted: {said}");
    // A file named anywhere is read (and still never quoted); `--confine` refuses names
    // outside the recipe's folder when the recipe is loaded, before anything is read.
    std::fs::write(tmp.path().join("elsewhere.csv"), "root:x:0:0:root:/root:/bin/bash\n").unwrap();
    let absolute = tmp.path().join("elsewhere.csv").display().to_string();
    let sub = tmp.path().join("sub");
    std::fs::create_dir_all(&sub).unwrap();
    for (dir, file) in [(tmp.path(), absolute.as_str()), (sub.as_path(), "../elsewhere.csv")] {
        std::fs::write(
            dir.join("r.yaml"),
            format!("spindlelab: 1\nname: s\nsteps:\n  m:\n    kind: read.frf\n    params: {{ file: \"{file}\" }}\n"),
        )
        .unwrap();
        let o = run_in(dir, &["run", "r.yaml", "-o", "o", "-q"]);
        no_panic(&o);
        assert_eq!(o.status.code(), Some(2), "{file}: {}", text(&o));
        assert!(text(&o).contains("elsewhere.csv:1") && !text(&o).contains("root:x"), "{file}: {}", text(&o));
        let o = run_in(dir, &["check", "r.yaml", "--confine"]);
        no_panic(&o);
        assert_eq!(o.status.code(), Some(2), "{file}: {}", text(&o));
        assert!(text(&o).contains("outside the recipe's folder") && text(&o).contains("r.yaml:6:"), "{}", text(&o));
        let o = run_in(dir, &["run", "r.yaml", "-o", "o", "--confine"]);
        assert_eq!(o.status.code(), Some(2), "{file}: {}", text(&o));
        assert!(!text(&o).contains("elsewhere.csv:1"), "read before refusing: {}", text(&o));
    }
}

#[test]
fn the_manifest_records_every_data_file_with_its_hash() {
    let Some(frf) = shared("data/uff/frf_xy_binary.uff", "the manifest test of a data file") else { return };
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("r.yaml"),
        format!(
            "spindlelab: 1\nname: s\nsteps:\n  m:\n    kind: read.frf\n    params: {{ file: \"{}\", direction: y }}\noutputs:\n  - {{ from: \"@m.frf\", file: m.csv }}\n",
            frf.display()
        ),
    )
    .unwrap();
    let o = run_in(tmp.path(), &["run", "r.yaml", "-o", "o", "-q"]);
    assert!(o.status.success(), "{}", text(&o));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("o/manifest.json")).unwrap()).unwrap();
    let hash = blake3::hash(&std::fs::read(&frf).unwrap()).to_hex().to_string();
    assert_eq!(m["data_files"][frf.display().to_string()].as_str(), Some(hash.as_str()), "{m}");
}
