//! `spindlelab import` through the binary, as a lab uses it: the case and its measurements in
//! one folder, the recipe written into another, run from a third. The recipe names the data
//! from its own folder and asks for the case's results (the gap table, the model over the
//! measurements, the lobes with the trials), so `run --report` shows them.

use spindlelab::engine::formats::csv::read_tables;
use std::path::{Path, PathBuf};
use std::process::Command;

fn case_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/train-02")
}

/// Runs the binary in `cwd`; exit code, stdout, stderr.
fn spindlelab(cwd: &Path, args: &[&str]) -> (Option<i32>, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(args)
        .current_dir(cwd)
        .env("NO_COLOR", "1")
        .output()
        .unwrap();
    (o.status.code(), String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
}

/// A lab's folders: `data/` with the case and its files, `recipes/`, and `work/` to run from.
fn lab() -> tempfile::TempDir {
    let root = tempfile::tempdir().unwrap();
    for d in ["data", "recipes", "work"] {
        std::fs::create_dir(root.path().join(d)).unwrap();
    }
    for f in ["case.json", "frf_x_0rpm.csv", "frf_y_0rpm.csv", "trials.csv"] {
        std::fs::copy(case_dir().join(f), root.path().join("data").join(f)).unwrap();
    }
    root
}

#[test]
fn a_recipe_imported_into_another_folder_runs_from_a_third_and_writes_the_case_s_results() {
    let root = lab();
    let work = root.path().join("work");
    let (code, _, err) = spindlelab(&work, &["import", "../data/case.json", "-o", "../recipes/train-02.yaml"]);
    assert_eq!(code, Some(0), "{err}");
    let text = std::fs::read_to_string(root.path().join("recipes/train-02.yaml")).unwrap();
    // The data are named from the recipe's folder.
    for file in ["\"../data/frf_x_0rpm.csv\"", "\"../data/frf_y_0rpm.csv\"", "{ file: \"../data/trials.csv\" }"] {
        assert!(text.contains(file), "{file} not in:\n{text}");
    }
    assert!(text.contains("\noutputs:\n"), "{text}");

    let (code, out, err) = spindlelab(&work, &["run", "../recipes/train-02.yaml", "--report"]);
    assert_eq!(code, Some(0), "{err}{out}");
    assert!(!format!("{out}{err}").contains("asks for no plot"), "{out}{err}");
    let dir = work.join("out/train_02");
    for f in [
        "gap.csv",
        "model-vs-measured-frf_x_0rpm.svg",
        "model-vs-measured-frf_y_0rpm.svg",
        "lobes.svg",
        "trial-verdicts.csv",
        "lobes.csv",
        "report.html",
    ] {
        assert!(dir.join(f).is_file(), "{f} not written to {}:\n{out}", dir.display());
    }

    // Each file reads back through the project's readers.
    let read = |f: &str| std::fs::read(dir.join(f)).unwrap();
    let gap = read_tables(&read("gap.csv"), "gap.csv").unwrap();
    assert_eq!(gap.len(), 2, "one gap row block per measured file");
    for block in &gap {
        let ratio = block.table.columns.iter().find(|c| c.name == "ratio").expect("a ratio column");
        // The baseline misses the interface compliance the case hides: far above the noise floor.
        assert!(ratio.values[0] > 10.0, "{:?}: {:?}", block.coords, ratio.values);
    }
    let verdicts = read_tables(&read("trial-verdicts.csv"), "trial-verdicts.csv").unwrap();
    assert_eq!(verdicts[0].table.columns[0].values.len(), 39, "every trial of the case");
    let lobes = read_tables(&read("lobes.csv"), "lobes.csv").unwrap();
    let limit = lobes[0].table.columns.iter().find(|c| c.name == "depth_speed_dependent").expect("the limit");
    assert!(limit.values.len() > 100 && limit.values.iter().all(|d| *d > 0.0), "{:?}", &limit.values[..3]);
    for svg in ["model-vs-measured-frf_x_0rpm.svg", "model-vs-measured-frf_y_0rpm.svg", "lobes.svg"] {
        let text = String::from_utf8(read(svg)).unwrap();
        assert!(text.contains("<svg") && text.contains("</svg>"), "{svg}");
    }
    // One plot per measured file: the model and the measurement of that file only.
    let x = String::from_utf8(read("model-vs-measured-frf_x_0rpm.svg")).unwrap();
    assert!(x.contains("frf_x_0rpm") && !x.contains("frf_y_0rpm"), "the x plot draws the y file");
    let report = String::from_utf8(read("report.html")).unwrap();
    assert!(report.contains("model-vs-measured") && report.contains("lobes.svg"), "the report shows the plots");
}

/// Printed, the recipe names the data from the current folder (where `> recipe.yaml` puts it);
/// a file that is not beside the case is written as the case gives it.
#[test]
fn a_printed_recipe_names_the_data_from_the_current_folder() {
    let root = lab();
    let (code, out, err) = spindlelab(&root.path().join("work"), &["import", "../data/case.json"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("- \"../data/frf_x_0rpm.csv\""), "{out}");
    let (code, out, err) = spindlelab(root.path(), &["import", "data/case.json"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("- data/frf_x_0rpm.csv"), "{out}");
    std::fs::remove_file(root.path().join("data/trials.csv")).unwrap();
    let (code, out, err) = spindlelab(root.path(), &["import", "data/case.json"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("{ file: trials.csv }"), "{out}");
}

/// With `--library`, the short recipe names both the library and the data from its own folder,
/// and checks from anywhere.
#[test]
fn a_recipe_and_its_library_written_elsewhere_check_from_anywhere() {
    let root = lab();
    let work = root.path().join("work");
    let args = ["import", "../data/case.json", "-o", "../recipes/short.yaml", "--library", "../recipes/lib/case.yaml"];
    std::fs::create_dir(root.path().join("recipes/lib")).unwrap();
    let (code, _, err) = spindlelab(&work, &args);
    assert_eq!(code, Some(0), "{err}");
    let text = std::fs::read_to_string(root.path().join("recipes/short.yaml")).unwrap();
    assert!(text.contains("use: [lib/case.yaml]") && text.contains("- \"../data/frf_y_0rpm.csv\""), "{text}");
    let (code, out, err) = spindlelab(&work, &["check", "../recipes/short.yaml"]);
    assert_eq!(code, Some(0), "{err}{out}");
}

/// `import -o` into a folder that does not exist yet makes it, as `run -o` does, and the
/// recipe written there runs.
#[test]
fn import_makes_the_folder_it_is_told_to_write_into() {
    let root = lab();
    let work = root.path().join("work");
    let (code, _, err) = spindlelab(&work, &["import", "../data/case.json", "-o", "../recipes/new/deeper/r.yaml"]);
    assert_eq!(code, Some(0), "{err}");
    let recipe = root.path().join("recipes/new/deeper/r.yaml");
    let text = std::fs::read_to_string(&recipe).unwrap();
    assert!(text.contains("\"../../../data/frf_x_0rpm.csv\""), "{text}");
    let (code, _, err) = spindlelab(&work, &["check", "../recipes/new/deeper/r.yaml"]);
    assert_eq!(code, Some(0), "{err}");
}
