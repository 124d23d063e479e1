//! The command line at its edges: standard output that cannot be written, output file names
//! no file system takes, and foreign text (a recipe's keys, a data file's cells) that must
//! not drive the terminal. Each through the binary.

use std::path::Path;
use std::process::Stdio;

use crate::common::binary::{bin, no_panic, run_in, text};

/// No character of the output may drive a terminal: no control character but the line break.
fn no_raw_controls(s: &str) {
    assert!(!s.chars().any(|c| c.is_control() && c != '\n'), "a control character reaches the terminal: {s:?}");
    assert!(!s.contains('\u{202e}'), "a line-reordering character reaches the terminal: {s:?}");
}

/// A small recipe of one step and one output, written as `r.yaml` in `dir`.
fn small_recipe(dir: &Path) -> std::path::PathBuf {
    let path = dir.join("r.yaml");
    std::fs::write(
        &path,
        "spindlelab: 1\nname: small\nsteps:\n  one: { kind: rhai.eval, params: { expr: \"1.5\" } }\n\
         outputs:\n  - { from: \"@one.value\", file: one.json }\n",
    )
    .unwrap();
    path
}

/// Whether `/dev/full` (a device whose writes fail as on a full disk) exists. Linux always
/// has it, so there a missing one fails the test rather than letting it pass unrun.
fn has_dev_full() -> bool {
    let there = Path::new("/dev/full").exists();
    assert!(there || !cfg!(target_os = "linux"), "/dev/full is missing on Linux: the full-disk checks cannot run");
    if !there {
        eprintln!("not run: this system has no /dev/full");
    }
    there
}

#[test]
fn a_full_standard_output_ends_the_command_with_one_line_and_exit_code_1() {
    if !has_dev_full() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let recipe = small_recipe(tmp.path());
    let recipe = recipe.to_str().unwrap();
    let case = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/train_07-case.json");
    let commands: [&[&str]; 8] = [
        &["--help"],
        &["--version"],
        &["nodes"],
        &["schema"],
        &["check", recipe],
        &["run", recipe, "-o", "out", "--no-cache"],
        &["plan", recipe, "-o", "out"],
        &["import", case.to_str().unwrap()],
    ];
    for args in commands {
        let full = std::fs::File::create("/dev/full").unwrap();
        let o = bin().args(args).current_dir(tmp.path()).stdout(full).stderr(Stdio::piped()).output().unwrap();
        no_panic(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(err.lines().count(), 1, "{args:?}: one line: {err}");
        assert!(err.starts_with("error: cannot write to standard output: "), "{args:?}: {err}");
    }
    // The run itself was complete: only its summary could not be printed.
    assert!(tmp.path().join("out/one.json").is_file());
}

#[test]
fn a_full_standard_error_never_panics_and_the_exit_code_still_tells() {
    if !has_dev_full() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let recipe = small_recipe(tmp.path());
    std::fs::write(tmp.path().join("bad.yaml"), "spindlelab: 1\nname: bad\nsteps:\n  a: { kind: no.such }\n").unwrap();
    for (args, code) in [
        (vec!["run", recipe.to_str().unwrap(), "-o", "out", "--no-cache", "-q"], 0),
        (vec!["run", recipe.to_str().unwrap(), "-o", "out", "--no-cache"], 1),
        (vec!["check", "bad.yaml"], 2),
        (vec!["run", "bad.yaml"], 2),
    ] {
        let full = || std::fs::File::create("/dev/full").unwrap();
        let o = bin().args(&args).current_dir(tmp.path()).stdout(full()).stderr(full()).output().unwrap();
        assert_eq!(o.status.code(), Some(code), "{args:?}");
    }
}

#[test]
fn output_names_no_file_system_takes_are_refused_at_their_place_before_anything_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let long_part = "x".repeat(256);
    let long_path = format!("{}/f.csv", vec!["d".repeat(200); 21].join("/"));
    for (name, says) in [
        ("\"a\\0b.json\"".to_string(), "holds a NUL character"),
        (format!("{long_part}.json"), "has a part of 261 bytes, beyond the 255 bytes of a file name"),
        (long_path.clone(), &*format!("is {} bytes long, beyond the 4096 bytes of a path", long_path.len())),
    ] {
        let recipe = format!(
            "spindlelab: 1\nname: names\nsteps:\n  one: {{ kind: rhai.eval, params: {{ expr: \"1.5\" }} }}\n\
             outputs:\n  - {{ from: \"@one.value\", file: {name} }}\n"
        );
        let column = recipe.lines().nth(5).unwrap().find(name.as_str()).unwrap() + 1;
        std::fs::write(tmp.path().join("r.yaml"), &recipe).unwrap();
        for args in [&["check", "r.yaml"][..], &["run", "r.yaml", "-q"]] {
            let o = run_in(tmp.path(), args);
            no_panic(&o);
            assert_eq!(o.status.code(), Some(2), "{}", text(&o));
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(err.contains(says), "{says}: {err}");
            assert!(err.contains(&format!("r.yaml:6:{column}")), "the name's place: {err}");
            assert!(err.contains("nothing was run"), "{err}");
            no_raw_controls(&err);
        }
        assert!(!tmp.path().join("out").exists(), "nothing ran");
    }
}

#[test]
fn a_recipe_s_keys_and_values_reach_the_terminal_escaped() {
    let tmp = tempfile::tempdir().unwrap();
    // A key and a value that try to clear the line, recolour the terminal and start lines of
    // their own; YAML's escapes put them into the recipe.
    std::fs::write(
        tmp.path().join("r.yaml"),
        "spindlelab: 1\nname: hostile\n\"x\\e[2K\\r\\nerror: forged key\": 1\nsteps:\n  one:\n    kind: \"a\\e]0;owned\\a\\nok: forged kind\"\n",
    )
    .unwrap();
    let o = run_in(tmp.path(), &["check", "r.yaml"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    no_raw_controls(&err);
    assert!(err.contains("unknown key `x\\x1b[2K\\r\\nerror: forged key`"), "{err}");
    assert!(err.contains("a\\x1b]0;owned\\x07\\nok: forged kind"), "{err}");
    assert!(!err.lines().any(|l| l.starts_with("error: forged") || l.starts_with("ok: forged")), "{err}");

    // A raw escape character in the file: whether YAML refuses it or the key is unknown, the
    // quoted line and the message show it escaped.
    std::fs::write(tmp.path().join("raw.yaml"), "spindlelab: 1\nname: raw\n\"raw \u{1b}[31m red\": 1\n").unwrap();
    let o = run_in(tmp.path(), &["check", "raw.yaml"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    no_raw_controls(&err);
    assert!(err.contains("raw.yaml:3:6"), "{err}");
}

#[test]
fn a_data_file_s_text_reaches_the_terminal_escaped() {
    let tmp = tempfile::tempdir().unwrap();
    // The unit of a column, quoted by the reader's error, holds escape sequences and a line
    // break that would print a line of its own.
    std::fs::write(
        tmp.path().join("frf.csv"),
        "# units: freq_hz=Hz, real=m\u{1b}[2K\r\u{1b}[32m\u{2028}/N\nfreq_hz,real,imag\n1,2,3\n2,3,4\n",
    )
    .unwrap();
    std::fs::write(
        tmp.path().join("r.yaml"),
        "spindlelab: 1\nname: data\nsteps:\n  m: { kind: read.frf, params: { file: frf.csv } }\n\
         outputs:\n  - { from: \"@m.frf\", file: m.csv }\n",
    )
    .unwrap();
    let o = run_in(tmp.path(), &["run", "r.yaml", "-o", "out", "--no-cache"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    no_raw_controls(&err);
    assert!(err.contains("node `m` failed"), "{err}");
    assert!(err.contains("real=m\\x1b[2K\\r\\x1b[32m\\u{2028}/N"), "the cell is quoted escaped: {err}");
}

#[test]
fn a_plugin_pin_that_yaml_reads_as_a_number_asks_for_quotes() {
    let tmp = tempfile::tempdir().unwrap();
    for (pin, says) in [
        ("0".repeat(64), "is read as the number 0, not as text"),
        ("1234".to_string(), "is read as the number 1234"),
        ("\"abc\"".to_string(), "must be 64 hexadecimal digits, found 3 characters"),
    ] {
        std::fs::write(
            tmp.path().join("r.yaml"),
            format!("spindlelab: 1\nname: pins\nplugins:\n  - {{ path: p.plugin.json, sha256: {pin} }}\nsteps: {{}}\n"),
        )
        .unwrap();
        let o = run_in(tmp.path(), &["check", "r.yaml"]);
        no_panic(&o);
        assert_eq!(o.status.code(), Some(2), "{}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(says) && err.contains("r.yaml:4:"), "{pin}: {err}");
    }
    std::fs::write(
        tmp.path().join("r.yaml"),
        "spindlelab: 1\nname: pins\nplugins:\n  - { path: p.plugin.json, version: 1.0 }\nsteps: {}\n",
    )
    .unwrap();
    let o = run_in(tmp.path(), &["check", "r.yaml"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("quote it: `version: \"…\"`"), "{}", text(&o));
}

/// After a complete run, `plan` counts as "to run" only what a rerun would compute: the
/// uncached recording an output file reads, not the recordings every consumer of which is
/// cached (listed as not needed).
#[test]
fn plan_after_a_full_run_counts_only_what_would_run() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let recipe = dir.path().join("phase-lag.yaml");
    std::fs::copy(root.join("scripts/phase-lag.yaml"), &recipe).unwrap();
    let run = run_in(dir.path(), &["run", "phase-lag.yaml", "-o", "out", "-q"]);
    assert!(run.status.success(), "{}", text(&run));
    let plan = run_in(dir.path(), &["plan", "phase-lag.yaml", "-o", "out"]);
    assert!(plan.status.success(), "{}", text(&plan));
    let out = String::from_utf8_lossy(&plan.stdout);
    let lines: Vec<&str> = out.lines().collect();
    let last = lines.last().unwrap();
    let would_run = lines.iter().filter(|l| l.contains(" run: ")).count();
    let not_needed = lines.iter().filter(|l| l.contains(" skip: ")).count();
    assert!(would_run >= 1 && not_needed >= 10, "{out}");
    assert!(last.starts_with(&format!("{would_run} to run, ")), "{out}");
    assert!(last.contains(&format!(", {not_needed} not needed")), "{out}");
}
