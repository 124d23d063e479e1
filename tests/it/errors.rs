//! Bad input through the binary's boundary: every class of mistake a recipe can hold must
//! end with exit code 2, no panic, a message that says where and what (and what to do
//! instead, where there is something to suggest), and nothing written.
//!
//! Fixtures live in `tests/bad/`; the binary runs with that directory as its working
//! directory so messages name files as `units.yaml`, not by an absolute path. Inputs that
//! cannot sit in the repository (non-UTF-8 bytes, a 50 MB file) are made at test time.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Exit code of the CLI for bad input.
const EXIT_BAD_INPUT: i32 = 2;

fn bad_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join("bad")
}

/// What one run of the binary did.
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
        .output()
        .expect("the spindlelab binary starts");
    Outcome {
        code: out.status.code(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// Exit 2, no panic, something said on stderr.
fn assert_rejected(o: &Outcome) {
    assert!(!o.stderr.contains("panicked"), "the binary panicked:\n{}", o.stderr);
    assert_eq!(o.code, Some(EXIT_BAD_INPUT), "exit code\nstdout:\n{}\nstderr:\n{}", o.stdout, o.stderr);
    assert!(o.stderr.contains("error"), "no error on stderr:\n{}", o.stderr);
}

/// Every entry under `dir`, relative to it, sorted.
fn entries(dir: &Path) -> Vec<String> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) {
        let Ok(rd) = std::fs::read_dir(dir) else { return };
        for e in rd.flatten() {
            let p = e.path();
            out.push(p.strip_prefix(root).unwrap().display().to_string());
            if p.is_dir() {
                walk(root, &p, out);
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out.sort();
    out
}

/// Everything under `tmp`, the parent of the output directory `out`, except an empty `out`.
fn written(tmp: &Path, out: &Path) -> Vec<String> {
    let mut found = entries(tmp);
    if out.is_dir() && entries(out).is_empty() {
        found.retain(|e| Path::new(e) != out.strip_prefix(tmp).unwrap());
    }
    found
}

/// The output directory is absent or empty, and nothing appeared next to it either.
fn assert_nothing_written(tmp: &Path, out: &Path) {
    let found = written(tmp, out);
    assert!(found.is_empty(), "files written: {found:?}");
}

/// Replaces the temporary directories in a message by stable placeholders.
fn redact(text: &str, dirs: &[(&Path, &str)]) -> String {
    let mut s = text.to_string();
    for (dir, placeholder) in dirs {
        s = s.replace(&dir.display().to_string(), placeholder);
    }
    s
}

/// `spindlelab run FILE -o OUT` from `cwd`, where `FILE` must not compile: checks the
/// contract for compile errors and returns stderr with the temporary paths redacted.
fn reject_in(cwd: &Path, file: &str) -> String {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = spindlelab(cwd, [OsStr::new("run"), OsStr::new(file), OsStr::new("-o"), out.as_os_str()]);
    assert_rejected(&o);
    assert!(o.stdout.is_empty(), "stdout of a rejected recipe:\n{}", o.stdout);
    assert!(o.stderr.contains(file), "stderr does not name `{file}`:\n{}", o.stderr);
    assert!(o.stderr.contains("nothing was run"), "no summary line:\n{}", o.stderr);
    assert_nothing_written(tmp.path(), &out);
    redact(&o.stderr, &[(tmp.path(), "[OUT]"), (cwd, "[CWD]")])
}

/// [`reject_in`] for a fixture of `tests/bad/`.
fn reject(file: &str) -> String {
    assert!(bad_dir().join(file).is_file(), "missing fixture {file}");
    reject_in(&bad_dir(), file)
}

/// Number of diagnostics rendered as errors.
fn error_count(stderr: &str) -> usize {
    stderr.lines().filter(|l| l.starts_with("error: ") || l.contains(": error: ")).count()
}

/// `file:line:column` of every diagnostic, in the order printed (quoted `--> ` form or the
/// bracketed form used when no line can be quoted).
fn locations(stderr: &str, file: &str) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    for line in stderr.lines() {
        let Some(i) = line.find(&format!("{file}:")) else { continue };
        let rest = &line[i + file.len() + 1..];
        let mut parts = rest.split(|c: char| !c.is_ascii_digit()).filter(|p| !p.is_empty());
        if let (Some(l), Some(c)) = (parts.next(), parts.next()) {
            out.push((l.parse().unwrap(), c.parse().unwrap()));
        }
    }
    out
}

fn assert_has(stderr: &str, needles: &[&str]) {
    for n in needles {
        assert!(stderr.contains(n), "stderr lacks {n:?}:\n{stderr}");
    }
}

fn assert_at(stderr: &str, file: &str, line: u32, column: u32) {
    assert!(
        locations(stderr, file).contains(&(line, column)),
        "stderr has no diagnostic at {file}:{line}:{column}:\n{stderr}"
    );
}

// ---------------------------------------------------------------------------------------
// Positive controls: the harness does see success and written files.

/// A small, valid recipe that writes one file when run.
const GOOD_RECIPE: &str = "\
spindlelab: 1
name: good
steps:
  hit:
    kind: impact.simulate
    params: { hammer_mass: 0.01 kg, target_mass: 0.1 kg, target_stiffness: 1e7 N/m, duration: 1 ms }
  ratio:
    kind: rhai.eval
    params: { expr: \"x * 2.0\" }
    inputs: { x: \"@hit.peak_force\" }
outputs:
  - { from: \"@ratio.value\", file: ratio.csv }
";

#[test]
fn control_a_good_recipe_checks_runs_and_writes() {
    let src = tempfile::tempdir().unwrap();
    std::fs::write(src.path().join("good.yaml"), GOOD_RECIPE).unwrap();
    let check = spindlelab(src.path(), ["check", "good.yaml"]);
    assert_eq!(check.code, Some(0), "{}", check.stderr);
    assert!(check.stdout.contains("good.yaml: ok"), "{}", check.stdout);

    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let run = spindlelab(src.path(), [OsStr::new("run"), OsStr::new("good.yaml"), OsStr::new("-o"), out.as_os_str()]);
    assert_eq!(run.code, Some(0), "{}", run.stderr);
    assert!(out.join("ratio.csv").is_file(), "written: {:?}", entries(&out));
    // The check every bad-input test relies on does notice files.
    assert!(written(tmp.path(), &out).contains(&"out/ratio.csv".to_string()), "{:?}", written(tmp.path(), &out));
}

#[test]
fn control_impact_study_checks() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let o = spindlelab(root, ["check", "scripts/impact-study.yaml"]);
    assert!(!o.stderr.contains("panicked"), "the binary panicked:\n{}", o.stderr);
    assert_eq!(o.code, Some(0), "stderr:\n{}", o.stderr);
    assert!(o.stdout.contains("scripts/impact-study.yaml: ok"), "{}", o.stdout);
}

// ---------------------------------------------------------------------------------------
// 1. Unknown names, each with a did-you-mean.

#[test]
fn unknown_keys_and_kind_suggest_the_right_name() {
    let e = reject("unknown-names.yaml");
    assert_has(
        &e,
        &[
            "unknown key `materails` in the recipe",
            "did you mean `materials`?",
            "unknown key `parms` in step `hit`",
            "did you mean `params`?",
            "unknown key `hammer_mas`",
            "did you mean `hammer_mass`?",
            "unknown step kind `frf.estimat`",
            "did you mean `frf.estimate`?",
        ],
    );
    let f = "unknown-names.yaml";
    assert_at(&e, f, 3, 1);
    assert_at(&e, f, 9, 5);
    assert_at(&e, f, 12, 7);
    assert_at(&e, f, 17, 11);
    insta::assert_snapshot!("unknown_names", e);
}

// ---------------------------------------------------------------------------------------
// 2. Units: wrong dimension, none at all, not a unit.

#[test]
fn wrong_missing_and_unknown_units() {
    let e = reject("units.yaml");
    let f = "units.yaml";
    // A length where a stiffness goes: both dimensions named.
    assert_has(&e, &["`12 mm`", "stiffness", "length", "N/m"]);
    assert_at(&e, f, 9, 25);
    // A bare number where a mass goes: asks for a unit.
    assert_has(&e, &["`0.01`", "expected a mass", "write the number with a unit of mass, e.g. `0.01 kg`"]);
    assert_at(&e, f, 16, 20);
    // Not a unit at all: the closest one suggested.
    assert_has(&e, &["unknown unit `mmm`", "did you mean `mm`?"]);
    assert_at(&e, f, 26, 22);
    assert_eq!(error_count(&e), 3, "{e}");
    insta::assert_snapshot!("units", e);
}

// ---------------------------------------------------------------------------------------
// 3. References: dangling, to a missing port, of the wrong type.

#[test]
fn dangling_misspelt_and_mistyped_references() {
    let e = reject("references.yaml");
    let f = "references.yaml";
    assert_has(&e, &["dangling reference `@hitt.force`", "did you mean `@hit.force`?"]);
    assert_at(&e, f, 16, 14);
    assert_has(&e, &["dangling reference `@nosuch.displacement`: there is no step `nosuch`"]);
    assert_at(&e, f, 17, 17);
    assert_has(&e, &["has no output `forse`", "did you mean `@hit.force`?"]);
    assert_at(&e, f, 23, 14);
    assert_has(
        &e,
        &["type mismatch", "input `force` of step `wrong_type` takes a time series", "`@hit.peak_force` is a scalar"],
    );
    assert_at(&e, f, 30, 14);
    assert_eq!(error_count(&e), 4, "{e}");
    insta::assert_snapshot!("references", e);
}

// ---------------------------------------------------------------------------------------
// 4. Cycles.

#[test]
fn cycles_are_reported_with_their_steps() {
    let e = reject("cycle.yaml");
    // The three-step cycle is reported once, naming every step on it.
    let cycle_lines: Vec<&str> = e.lines().filter(|l| l.contains("cycle between steps")).collect();
    assert_eq!(cycle_lines.len(), 1, "{e}");
    for step in ["a", "b", "c"] {
        assert!(cycle_lines[0].contains(&format!("{step} → ")), "`{step}` missing from {:?}", cycle_lines[0]);
    }
    assert_has(&e, &["step `self_loop` takes its own output `@self_loop.value` as input"]);
    assert_at(&e, "cycle.yaml", 23, 18);
    assert_eq!(error_count(&e), 2, "{e}");
    insta::assert_snapshot!("cycle", e);
}

// ---------------------------------------------------------------------------------------
// 5. Every diagnostic at once, top to bottom.

#[test]
fn all_errors_are_reported_at_once_in_line_order() {
    let e = reject("many-errors.yaml");
    let f = "many-errors.yaml";
    // Seven mistakes on seven lines; the file puts them where they are found out of order
    // (outputs first, the version and an unknown key last).
    assert_eq!(error_count(&e), 7, "{e}");
    assert_has(&e, &["7 errors found; nothing was run."]);
    let lines: Vec<u32> = locations(&e, f).into_iter().map(|(l, _)| l).collect();
    assert_eq!(lines, [3, 8, 11, 16, 18, 20, 21], "{e}");
    assert_has(
        &e,
        &[
            "unsupported output format `txt`",
            "expected a mass",
            "unknown unit `mmm`",
            "did you mean `force_window`?",
            "did you mean `@hit.force`?",
            "unsupported recipe version `2`",
            "unknown key `extra_key` in the recipe",
        ],
    );
    insta::assert_snapshot!("many_errors", e);
}

// ---------------------------------------------------------------------------------------
// 6. Files that are not a recipe.

#[test]
fn empty_file() {
    let e = reject("empty.yaml");
    assert_has(&e, &["a recipe must be a mapping", "start the file with `spindlelab: 1`"]);
    insta::assert_snapshot!("empty", e);
}

#[test]
fn a_list_is_not_a_recipe() {
    let e = reject("list.yaml");
    assert_has(&e, &["a recipe must be a mapping, found a list", "start the file with `spindlelab: 1`"]);
    assert_at(&e, "list.yaml", 1, 1);
    insta::assert_snapshot!("list", e);
}

#[test]
fn a_scalar_is_not_a_recipe() {
    let e = reject("scalar.yaml");
    assert_has(&e, &["a recipe must be a mapping, found a string", "start the file with `spindlelab: 1`"]);
    assert_at(&e, "scalar.yaml", 1, 1);
    insta::assert_snapshot!("scalar", e);
}

#[test]
fn missing_version() {
    let e = reject("no-version.yaml");
    assert_has(&e, &["missing the version key `spindlelab`", "add `spindlelab: 1`"]);
    assert_eq!(error_count(&e), 1, "{e}");
    insta::assert_snapshot!("no_version", e);
}

#[test]
fn unsupported_version() {
    let e = reject("version-2.yaml");
    assert_has(&e, &["unsupported recipe version `2`", "`spindlelab: 1`"]);
    assert_at(&e, "version-2.yaml", 1, 13);
    assert_eq!(error_count(&e), 1, "{e}");
    insta::assert_snapshot!("version_2", e);
}

#[test]
fn no_steps() {
    let e = reject("no-steps.yaml");
    assert_has(&e, &["the recipe has no `steps`", "add `steps:`"]);
    assert_eq!(error_count(&e), 1, "{e}");
    insta::assert_snapshot!("no_steps", e);
}

// ---------------------------------------------------------------------------------------
// 7. YAML syntax.

#[test]
fn invalid_yaml_syntax_has_a_location() {
    let e = reject("flow-mapping.yaml");
    assert_has(&e, &["invalid YAML", "flow mapping"]);
    assert_eq!(locations(&e, "flow-mapping.yaml").len(), 1, "no line:column:\n{e}");
    assert_eq!(error_count(&e), 1, "{e}");
    insta::assert_snapshot!("flow_mapping", e);
}

// ---------------------------------------------------------------------------------------
// 8. Not UTF-8.

#[test]
fn non_utf8_file_names_the_place() {
    let dir = tempfile::tempdir().unwrap();
    // "café" in Latin-1 on line 3: the 0xff byte is the sixth character of that line.
    let mut bytes = b"spindlelab: 1\nname: latin1\n# caf".to_vec();
    bytes.push(0xff);
    bytes.extend_from_slice(b"\nsteps: {}\n");
    std::fs::write(dir.path().join("latin1.yaml"), &bytes).unwrap();
    let e = reject_in(dir.path(), "latin1.yaml");
    assert_has(&e, &["not valid UTF-8", "save the file as UTF-8"]);
    assert_at(&e, "latin1.yaml", 3, 6);
    assert_eq!(error_count(&e), 1, "{e}");
    insta::assert_snapshot!("non_utf8", e);
}

// ---------------------------------------------------------------------------------------
// 9. Too big to be a recipe.

#[test]
fn a_50_mb_file_is_refused_before_parsing() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::with_capacity(50 * 1024 * 1024 + 4096);
    text.push_str("spindlelab: 1\nname: huge\nsteps:\n");
    let mut i = 0;
    while text.len() < 50 * 1024 * 1024 {
        text.push_str(&format!(
            "  hit{i}:\n    kind: impact.simulate\n    params: {{ hammer_mass: 0.01 kg, target_mass: 0.1 kg, target_stiffness: 1e7 N/m }}\n"
        ));
        i += 1;
    }
    std::fs::write(dir.path().join("huge.yaml"), &text).unwrap();
    drop(text);
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = spindlelab(dir.path(), [OsStr::new("run"), OsStr::new("huge.yaml"), OsStr::new("-o"), out.as_os_str()]);
    assert_rejected(&o);
    assert_nothing_written(tmp.path(), &out);
    let e = redact(&o.stderr, &[(tmp.path(), "[OUT]"), (dir.path(), "[CWD]")]);
    assert_has(&e, &["huge.yaml", "byte limit", "keep measured data in CSV"]);
    assert_eq!(error_count(&e), 1, "{e}");
    insta::assert_snapshot!("too_big", e);
}

// ---------------------------------------------------------------------------------------
// 10. Rhai recipes that misbehave.

#[test]
fn rhai_recipe_that_never_ends_hits_the_operation_limit() {
    // How fast the limit stops it is measured in `benches/compile.rs`, not asserted here.
    let e = reject("forever.rhai");
    assert_has(&e, &["Rhai recipe failed", "Too many operations", "operation limit"]);
    assert_at(&e, "forever.rhai", 4, 5);
    insta::assert_snapshot!("rhai_forever", e);
}

#[test]
fn rhai_recipe_cannot_import() {
    let e = reject("import.rhai");
    // A module is looked for in the recipe's own folder only.
    assert_has(&e, &["cannot import `x`", "there is no `x.rhai` in the recipe's folder", "by a relative path"]);
    assert_at(&e, "import.rhai", 1, 8);
    insta::assert_snapshot!("rhai_import", e);
}

#[test]
fn rhai_recipe_must_return_a_map() {
    let e = reject("not-a-map.rhai");
    assert_has(&e, &["must end with an object map, found array", "#{ spindlelab: 1"]);
    insta::assert_snapshot!("rhai_not_a_map", e);
}

// ---------------------------------------------------------------------------------------
// 11. Numbers that are not numbers, sweeps that are not sweeps.

#[test]
fn non_finite_numbers_and_degenerate_sweeps() {
    let e = reject("nonfinite.yaml");
    let f = "nonfinite.yaml";
    assert_has(&e, &["non-finite number `NaN`", "`hammer_mass` of params of step `nan_mass`"]);
    assert_at(&e, f, 8, 20);
    assert_has(&e, &["non-finite number `inf`", "`target_stiffness` of params of step `inf_stiffness`"]);
    assert_at(&e, f, 17, 25);
    assert_has(&e, &["range step must be positive", "sweep `tip_radius` of step `zero_step`"]);
    assert_at(&e, f, 26, 29);
    assert_has(&e, &["sweep `release` of step `empty_sweep`", "empty"]);
    assert_at(&e, f, 35, 16);
    assert_eq!(error_count(&e), 4, "{e}");
    insta::assert_snapshot!("nonfinite", e);
}

#[test]
fn a_bad_sweep_is_one_error_not_two() {
    let e = reject("bad-sweep-of-required-param.yaml");
    assert_has(&e, &["range step must be positive"]);
    assert!(!e.contains("missing `hammer_mass`"), "the sweep gives `hammer_mass`:\n{e}");
    assert_eq!(error_count(&e), 1, "{e}");
    insta::assert_snapshot!("bad_sweep_of_required_param", e);
}

// ---------------------------------------------------------------------------------------
// 12. Physically impossible parameters, caught by the node before anything runs.

#[test]
fn impossible_parameters_are_rejected_at_compile_time() {
    let e = reject("impossible.yaml");
    // Released behind the target's contact point: the hammer starts inside the target.
    assert_has(&e, &["step `behind_target`", "`release`", "contact"]);
    // A negative mass.
    assert_has(&e, &["step `negative_mass`", "`hammer_mass`", "positive"]);
    let lines: Vec<u32> = locations(&e, "impossible.yaml").into_iter().map(|(l, _)| l).collect();
    assert_eq!(lines.len(), 2, "each error needs a location:\n{e}");
    assert_eq!(error_count(&e), 2, "{e}");
    insta::assert_snapshot!("impossible", e);
}

// ---------------------------------------------------------------------------------------
// 13. A node that fails while running.

#[test]
fn run_time_failures_name_the_instance_and_write_no_outputs() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = spindlelab(
        &bad_dir(),
        [OsStr::new("run"), OsStr::new("runtime-failure.yaml"), OsStr::new("-o"), out.as_os_str()],
    );
    assert_rejected(&o);
    let e = redact(&o.stderr, &[(tmp.path(), "[OUT]"), (&bad_dir(), "[CWD]")]);
    assert_has(
        &e,
        &[
            "node `mismatched_frf[hammer_mass=0.01 kg]` failed",
            "node `mismatched_frf[hammer_mass=0.02 kg]` failed",
            "2 force channel(s) but 1 response channel(s)",
            "node `ratio[hammer_mass=0.01 kg]` failed",
            "`x / 0.0` gave inf",
            "no outputs written",
        ],
    );
    assert_eq!(error_count(&e), 4, "{e}");
    // The run record and the cache stay, by design; no declared output, no staging left over.
    let written = entries(&out);
    for file in ["force.csv", "frf.csv", "mismatched-frf.csv", "ratio.csv"] {
        assert!(!out.join(file).exists(), "{file} written: {written:?}");
    }
    assert!(
        written.iter().all(|p| p == "manifest.json" || p.starts_with(".spindlelab")),
        "unexpected files: {written:?}"
    );
    insta::assert_snapshot!("runtime_failure", e);
}

// ---------------------------------------------------------------------------------------
// 14. Output files.

#[test]
fn output_files_must_stay_inside_be_supported_and_distinct() {
    let e = reject("outputs.yaml");
    let f = "outputs.yaml";
    assert_has(&e, &["output file `../escape.csv` must stay inside the output directory"]);
    assert_at(&e, f, 14, 33);
    assert_has(&e, &["output file `/tmp/absolute.csv` must stay inside the output directory"]);
    assert_at(&e, f, 15, 33);
    assert_has(&e, &["unsupported output format `txt`", "name the file `.csv`, `.json`, `.uff`, or `.svg` / `.png`"]);
    assert_at(&e, f, 16, 33);
    assert_has(&e, &["two outputs write `force.csv`"]);
    assert_at(&e, f, 18, 40);
    assert_eq!(error_count(&e), 4, "{e}");
    // Nothing escaped either: `reject` found the folder that holds the output folder (where
    // `../escape.csv` would land) empty.
    insta::assert_snapshot!("outputs", e);
}

#[test]
fn plot_outputs_that_cannot_be_drawn_are_refused_at_their_place() {
    let e = reject("plots.yaml");
    let f = "plots.yaml";
    assert_has(&e, &["a time series has no view `real-imag`", "its views: default"]);
    assert_at(&e, f, 27, 33);
    assert_has(&e, &["a substructure has no plot", "name the file `.json` to write it"]);
    assert_at(&e, f, 28, 36);
    assert_has(&e, &["`with` is for plots; `force.csv` is not one"]);
    assert_at(&e, f, 29, 33);
    assert_has(&e, &["dangling reference `@hti.displacement`: there is no step `hti`"]);
    assert_at(&e, f, 30, 34);
    assert_has(&e, &["a time series cannot be drawn over a plot of a time series"]);
    assert_at(&e, f, 31, 33);
    assert_eq!(error_count(&e), 5, "{e}");
}

#[test]
fn an_output_from_a_step_with_bad_params_is_not_dangling() {
    let e = reject("output-from-bad-step.yaml");
    assert_has(&e, &["expected a mass"]);
    assert!(!e.contains("there is no step `hit`"), "step `hit` exists:\n{e}");
    assert_eq!(error_count(&e), 1, "{e}");
    insta::assert_snapshot!("output_from_bad_step", e);
}

// ---------------------------------------------------------------------------------------
// 15. `nodes` with a misspelt kind.

#[test]
fn nodes_with_an_unknown_kind_suggests_one() {
    let o = spindlelab(&bad_dir(), ["nodes", "frf.estimat"]);
    assert_rejected(&o);
    assert!(o.stdout.is_empty(), "{}", o.stdout);
    assert_has(&o.stderr, &["unknown node kind `frf.estimat`", "did you mean `frf.estimate`?"]);
    insta::assert_snapshot!("nodes_unknown_kind", o.stderr);
}

#[test]
fn bad_measurement_data_is_named_per_channel_record_and_value() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = spindlelab(
        &bad_dir(),
        [
            OsStr::new("run"),
            OsStr::new("measurement-failures.yaml"),
            OsStr::new("--keep-going"),
            OsStr::new("-o"),
            out.as_os_str(),
        ],
    );
    assert_rejected(&o);
    let e = redact(&o.stderr, &[(tmp.path(), "[OUT]"), (&bad_dir(), "[CWD]")]);
    assert_has(
        &e,
        &[
            // Speed drift beyond tolerance, naming the revolution and the speeds.
            "node `runout` failed: input `signal`: channel `tach`: revolution 0 runs at",
            "(tolerance 2.00 %)",
            // Every record rejected, each with its reason.
            "0 of 3 impacts usable",
            "impact 2 at 0.2504 s rejected: double hit: a second pulse of 25 % of the peak",
            "impact 3 at 0.4483 s rejected: saturated force",
            // A tachometer without edges.
            "the tachometer signal is flat",
            // Probe angles that lose harmonics, with what to do.
            "harmonic(s) [3, 5, 7",
            "`allow_unrecoverable: true`",
            // Mismatched sample rates.
            "sample rate 50000 Hz differs from the force's 100000 Hz",
        ],
    );
    assert_eq!(error_count(&e), 6, "{e}");
    assert!(!o.stderr.contains("NaN"), "{e}");
}

/// The YAML reader's own wording (`set DuplicateKeyPolicy in Options`, `budget breached:
/// Depth { depth: 65 }`) is translated into the recipe's terms, and a loss factor below zero
/// is refused at load with the material's name, not as a dump of a kernel struct at run time.
#[test]
fn library_messages_are_said_in_the_recipes_terms() {
    let e = reject("duplicate-key.yaml");
    assert_has(&e, &["the key `name` appears twice in one mapping", "keep one of them"]);
    assert_at(&e, "duplicate-key.yaml", 4, 1);
    assert!(!e.contains("DuplicateKeyPolicy") && !e.contains("quote values"), "{e}");
    let e = reject("deep.yaml");
    assert_has(&e, &["the YAML nests 65 levels deep, more than a recipe may"]);
    assert!(!e.contains("budget breached") && !e.contains("Depth {"), "{e}");
    let e = reject("frf-trigger.yaml");
    assert_has(&e, &["`trigger: level` needs a `trigger_level`", "used only with `trigger: level`"]);
    assert_eq!(error_count(&e), 2, "{e}");
    let e = reject("negative-eta.yaml");
    assert_has(&e, &["material `steel`: loss factor `eta` = -0.01 is negative", "a loss factor is 0 or more"]);
    assert_at(&e, "negative-eta.yaml", 5, 57);
    assert!(!e.contains("youngs_modulus"), "{e}");
}
