//! Small things a new user meets first, through the binary: a speed written `1/min` as drawings
//! and machine controls write it, the unit suggested for a bare cutting coefficient, where
//! `diagnose` writes by default, and the path `report` prints.

use std::path::Path;
use std::process::Command;

fn spindlelab(cwd: &Path, args: &[&str]) -> (Option<i32>, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(args)
        .current_dir(cwd)
        .env("NO_COLOR", "1")
        .output()
        .unwrap();
    let (out, err) = (String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned());
    assert!(!err.contains("panicked"), "{err}");
    (o.status.code(), out, err)
}

fn recipe(speeds: &str, ks: &str) -> String {
    format!(
        "spindlelab: 1
name: speeds
cutting:
  c: {{ teeth: 4, radial_immersion: 25 %, milling: up, Ks: {ks}, beta: 68 deg }}
steps:
  tool:
    kind: modal.model
    params:
      x: [{{ f: 600 Hz, zeta: 0.04, mass: 0.4 kg }}]
      y: [{{ f: 650 Hz, zeta: 0.03, mass: 0.3 kg }}]
  sd:
    kind: stability.sd
    params: {{ cutting: c, speeds: \"{speeds}\", max_depth: 20 mm }}
    inputs: {{ modes_x: \"@tool.modes_x\", modes_y: \"@tool.modes_y\" }}
outputs:
  - {{ from: \"@sd.table\", file: sd.csv }}
"
    )
}

/// `1/min` (and `min^-1`) is a spindle speed in revolutions per minute: the same numbers as rpm,
/// as a list and as a range.
#[test]
fn one_per_minute_is_a_spindle_speed() {
    let dir = tempfile::tempdir().unwrap();
    let mut written = Vec::new();
    for (i, speeds) in [
        "[6000, 9000, 12000] rpm",
        "[6000, 9000, 12000] 1/min",
        "6000..12000 step 3000 1/min",
        "[6000, 9000, 12000] min^-1",
    ]
    .into_iter()
    .enumerate()
    {
        let path = dir.path().join(format!("r{i}.yaml"));
        std::fs::write(&path, recipe(speeds, "800 N/mm^2")).unwrap();
        let out = dir.path().join(format!("out{i}"));
        let (code, stdout, err) =
            spindlelab(dir.path(), &["run", path.to_str().unwrap(), "-o", out.to_str().unwrap(), "--no-cache"]);
        assert_eq!(code, Some(0), "{speeds}: {err}{stdout}");
        written.push(std::fs::read_to_string(out.join("sd.csv")).unwrap());
    }
    assert!(written[0].contains("\n6000.0,") && written[0].contains("\n12000.0,"), "{}", written[0]);
    for w in &written[1..] {
        assert_eq!(w, &written[0]);
    }
}

/// A bare number for a cutting coefficient is refused (exit 2) with the unit such numbers are
/// written in, N/mm²; a bare Young's modulus still gets GPa.
#[test]
fn a_bare_cutting_coefficient_is_asked_for_in_newtons_per_square_millimetre() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ks.yaml");
    std::fs::write(&path, recipe("[6000] rpm", "800")).unwrap();
    let (code, _, err) = spindlelab(dir.path(), &["check", "ks.yaml"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("ks.yaml:4:") && err.contains("e.g. `800 N/mm^2`") && !err.contains("GPa"), "{err}");
    std::fs::write(
        &path,
        recipe("[6000] rpm", "800 N/mm^2") + "materials:\n  steel: { E: 200, rho: 7850 kg/m^3, nu: 0.29, eta: 0 }\n",
    )
    .unwrap();
    let (code, _, err) = spindlelab(dir.path(), &["check", "ks.yaml"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("e.g. `200 GPa`"), "{err}");
}

/// `report out/x` writes `out/x.report.html` and says so in those words (no `out/x/../`).
#[test]
fn report_prints_a_plain_path_beside_the_folder() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("r.yaml"), recipe("[6000] rpm", "800 N/mm^2")).unwrap();
    let (code, _, err) = spindlelab(dir.path(), &["run", "r.yaml", "-o", "out/x", "-q"]);
    assert_eq!(code, Some(0), "{err}");
    let (code, out, err) = spindlelab(dir.path(), &["report", "out/x"]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(out.trim(), "wrote out/x.report.html");
    assert!(dir.path().join("out/x.report.html").is_file());
    let (code, out, err) = spindlelab(&dir.path().join("out/x"), &["report", "."]);
    assert_eq!(code, Some(0), "{err}");
    let canonical = dir.path().canonicalize().unwrap().join("out/x.report.html");
    assert_eq!(out.trim(), format!("wrote {}", canonical.display()));
}

/// `diagnose` writes beside the run's outputs, `out/<recipe name>/diagnosis`, whatever the file
/// is called (here `my-recipe.yaml` for the case `train_02`).
#[test]
fn diagnose_writes_under_the_recipe_name_like_run() {
    let dir = tempfile::tempdir().unwrap();
    let case = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/train-02");
    for f in ["case.json", "frf_x_0rpm.csv", "frf_y_0rpm.csv", "trials.csv"] {
        std::fs::copy(case.join(f), dir.path().join(f)).unwrap();
    }
    let (code, _, err) = spindlelab(dir.path(), &["import", "case.json", "-o", "my-recipe.yaml"]);
    assert_eq!(code, Some(0), "{err}");
    let (code, out, err) = spindlelab(dir.path(), &["diagnose", "my-recipe.yaml"]);
    assert_eq!(code, Some(0), "{err}{out}");
    let folder = dir.path().join("out/train_02/diagnosis");
    assert!(folder.join("diagnosis.md").is_file(), "{out}");
    assert!(!dir.path().join("out/my-recipe").exists());
    assert!(out.contains("to out/train_02/diagnosis"), "{out}");
}

/// A scalar output written in the unit the output names (`unit: deg/kHz`), read back through
/// the scalar reader in that unit; a unit of another quantity is reported and that file alone
/// is not written; a unit that is none, or one on a plot or a table, is refused at its place
/// (exit 2).
#[test]
fn a_scalar_output_is_written_in_the_unit_it_names() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = |outputs: &str| {
        format!(
            "spindlelab: 1
name: slope
steps:
  slope:
    kind: rhai.eval
    params: {{ expr: \"-13.84 * 3.141592653589793 / 180.0 / 1000.0\", unit: \"rad*s\" }}
outputs:
{outputs}"
        )
    };
    std::fs::write(
        dir.path().join("r.yaml"),
        recipe(
            "  - { from: \"@slope.value\", file: slope.csv, unit: deg/kHz }
  - { from: \"@slope.value\", file: slope.json, unit: deg/kHz }
  - { from: \"@slope.value\", file: si.csv }
  - { from: \"@slope.value\", file: wrong.csv, unit: mm }
",
        ),
    )
    .unwrap();
    let (code, _, err) = spindlelab(dir.path(), &["run", "r.yaml", "-o", "out", "-q"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("wrong.csv: not written: the value is in rad*s, which `mm` does not measure"), "{err}");
    assert!(!dir.path().join("out/wrong.csv").exists());
    let csv = std::fs::read(dir.path().join("out/slope.csv")).unwrap();
    let back = spindlelab::engine::formats::csv::read_scalars(&csv, "slope.csv").unwrap();
    assert_eq!(back[0].2, "deg/kHz");
    assert!((back[0].1 + 13.84).abs() < 1e-12, "{}", back[0].1);
    assert!(String::from_utf8_lossy(&csv).contains("value_deg_per_kHz"));
    let si = std::fs::read(dir.path().join("out/si.csv")).unwrap();
    let back = spindlelab::engine::formats::csv::read_scalars(&si, "si.csv").unwrap();
    assert_eq!(back[0].2, "rad*s");
    let json = std::fs::read_to_string(dir.path().join("out/slope.json")).unwrap();
    let j: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert!((j["value"].as_f64().unwrap() + 13.84).abs() < 1e-12 && json.contains("deg/kHz"), "{json}");

    // A table of the slope: its columns carry their own units, so `unit` is refused there.
    let table = "  table:\n    kind: table.collect\n    inputs: { values: \"@slope.value\" }\noutputs:\n";
    for (outputs, said) in [
        ("  - { from: \"@slope.value\", file: a.csv, unit: furlongs }\n", "bad.yaml:8:48"),
        (
            "  - { from: \"@slope.value\", file: a.svg, unit: deg/kHz }\n",
            "is for a scalar written to `.csv` or `.json`",
        ),
        (
            "  - { from: \"@table.table\", file: t.csv, unit: deg/kHz }\n",
            "`unit` is for a scalar output; `@table.table` is a table",
        ),
    ] {
        let text = recipe(outputs);
        let text = if outputs.contains("@table") { text.replace("outputs:\n", table) } else { text };
        std::fs::write(dir.path().join("bad.yaml"), text).unwrap();
        let (code, _, err) = spindlelab(dir.path(), &["run", "bad.yaml", "-o", "bad", "-q"]);
        assert_eq!(code, Some(2), "{err}");
        assert!(err.contains(said), "{err}");
        assert!(!dir.path().join("bad").exists());
    }
}
