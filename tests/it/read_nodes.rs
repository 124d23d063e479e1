//! Reader nodes end to end: a recipe names data files relative to its folder, the file's
//! contents key the cache, read problems point into the data file, and what the outputs
//! write the readers read back. The UFF files written by pyuff are read from
//! `../shared/data/uff/` beside the checkout; the tests that need them are skipped without it,
//! except under CI.

use spindlelab::engine::exec::{Outcome, RunOptions};
use spindlelab::engine::formats::{self, FileFormat, FrfSelect};
use spindlelab::engine::spec::ParamValue;
use spindlelab::engine::value::Value;
use spindlelab::engine::{self, Compiled};
use std::path::{Path, PathBuf};

use crate::common::shared;

fn root(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// Our own UFF file `name`.
fn fixture(name: &str) -> PathBuf {
    root("engine/tests/data/uff").join(name)
}

/// pyuff's UFF file `name` in `../shared`, or `None` when it is not there (`what` is skipped).
fn pyuff(name: &str, what: &str) -> Option<PathBuf> {
    shared(&format!("data/uff/{name}"), what)
}

fn compile(path: &Path) -> Compiled {
    engine::compile_file(path, &spindlelab::registry()).unwrap_or_else(|e| panic!("{}", e.render(false)))
}

fn run(c: &Compiled, out: &Path, cache: bool) -> Result<engine::RunReport, engine::RunError> {
    let mut opts = RunOptions::new(out).with_renderer(spindlelab::renderer());
    opts.use_cache = cache;
    engine::run(c, &spindlelab::registry(), &opts, &|_, _| {})
}

fn frf_of(outcome: &Outcome) -> spindlelab::engine::value::Frf {
    match outcome.outputs().expect("ran")["frf"].as_ref() {
        Value::Frf(f) => f.clone(),
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_recipe_reads_a_measured_frf_and_its_outputs_read_back() {
    let what = "the recipe that reads pyuff's files";
    let Some(frf_file) = pyuff("frf_xy_binary.uff", what) else { return };
    let Some(force_file) = pyuff("force_time_ascii.uff", what) else { return };
    // The recipe names the files as they lie beside the checkout; it runs from a temporary
    // folder with their paths written in full.
    let text = std::fs::read_to_string(root("tests/data/read-frf.yaml")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let recipe = dir.path().join("read-frf.yaml");
    let text = text
        .replace("../../../shared/data/uff/frf_xy_binary.uff", &frf_file.display().to_string())
        .replace("../../../shared/data/uff/force_time_ascii.uff", &force_file.display().to_string());
    std::fs::write(&recipe, text).unwrap();
    let c = compile(&recipe);
    let out = tempfile::tempdir().unwrap();
    let report = run(&c, out.path(), false).unwrap_or_else(|e| panic!("{e}"));
    let frf = frf_of(&report.result.outcomes[c.graph.by_step["measured"][0]]);
    let direct =
        formats::read_frf(&frf_file, FileFormat::Uff, &FrfSelect { direction: Some("y".into()), ..Default::default() })
            .unwrap()
            .value;
    assert_eq!(frf, direct);
    assert_eq!(frf.direction.as_deref(), Some("y"));

    let csv = formats::read_frf(&out.path().join("measured.csv"), FileFormat::Csv, &FrfSelect::default()).unwrap();
    assert_eq!(csv.value, frf, "CSV keeps every bit");
    let uff = formats::read_frf(&out.path().join("measured.uff"), FileFormat::Uff, &FrfSelect::default()).unwrap();
    assert_eq!(uff.value.freq_hz, frf.freq_hz);
    for (a, b) in uff.value.values.iter().zip(&frf.values) {
        assert!((a - b).norm() <= 1e-12 * b.norm(), "{a} vs {b}");
    }
    let force = formats::read_time_series(&out.path().join("force.uff"), FileFormat::Uff, None).unwrap().value;
    assert_eq!((force.sample_rate, force.len(), force.channels[0].name.as_str()), (100_000.0, 2048, "impact force"));
}

#[test]
fn the_data_file_content_keys_the_cache_and_a_missing_file_is_reported_where_it_is_named() {
    let Some(ascii) = pyuff("frf_x_ascii.uff", "the cache test on an edited data file") else { return };
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    std::fs::create_dir(&data).unwrap();
    let text = std::fs::read_to_string(ascii).unwrap();
    std::fs::write(data.join("h.uff"), &text).unwrap();
    let recipe = dir.path().join("r.yaml");
    std::fs::write(&recipe, "spindlelab: 1\nsteps:\n  h:\n    kind: read.frf\n    params: { file: data/h.uff }\n")
        .unwrap();
    let out = dir.path().join("out");

    let first = compile(&recipe);
    let ParamValue::File { path, hash } = first.graph.instances[0].params.get("file").unwrap() else { panic!() };
    assert_eq!(path, &data.join("h.uff"));
    assert!(hash.len() == 64 && hash.chars().all(|c| c.is_ascii_hexdigit()), "{hash}");
    let a = run(&first, &out, true).unwrap();
    assert!(matches!(a.result.outcomes[0], Outcome::Computed { .. }));
    let b = run(&compile(&recipe), &out, true).unwrap();
    assert!(matches!(b.result.outcomes[0], Outcome::Cached { .. }), "unchanged file: served from the cache");

    // Edit one value of the data: the key changes and the node reruns with the new number.
    let edited = text.replacen("7.85714285714e-08", "7.85714285715e-08", 1);
    assert_ne!(edited, text);
    std::fs::write(data.join("h.uff"), &edited).unwrap();
    let second = compile(&recipe);
    assert_ne!(second.graph.instances[0].key, first.graph.instances[0].key);
    let c = run(&second, &out, true).unwrap();
    assert!(matches!(c.result.outcomes[0], Outcome::Computed { .. }));
    assert_eq!(frf_of(&c.result.outcomes[0]).values[0].re, 7.85714285715e-08);

    // The same recipe as Rhai resolves the path against its own folder too.
    let rhai = dir.path().join("r.rhai");
    std::fs::write(
        &rhai,
        r#"#{ spindlelab: 1, steps: #{ h: #{ kind: "read.frf", params: #{ file: "data/h.uff" } } } }"#,
    )
    .unwrap();
    assert_eq!(compile(&rhai).graph.instances[0].key, second.graph.instances[0].key);

    std::fs::write(&recipe, "spindlelab: 1\nsteps:\n  h:\n    kind: read.frf\n    params: { file: data/nope.uff }\n")
        .unwrap();
    let e = engine::compile_file(&recipe, &spindlelab::registry()).err().expect("a missing file fails");
    let d = e.diagnostics.iter().next().unwrap();
    let span = d.span.as_ref().unwrap();
    assert_eq!((span.line, span.column), (5, 21), "{}", e.render(false));
    assert!(
        d.message.starts_with("file not found: ")
            && d.message.ends_with("nope.uff (paths are relative to the recipe's folder)"),
        "{}",
        d.message
    );
}

#[test]
fn read_problems_point_into_the_data_file_and_skipped_datasets_warn() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bad.csv"), "# sample_rate: 1000 Hz\nforce\n1.5\nNaN\n").unwrap();
    std::fs::copy(fixture("skip_then_frf.uff"), dir.path().join("skip.uff")).unwrap();
    let recipe = dir.path().join("r.yaml");
    std::fs::write(
        &recipe,
        "spindlelab: 1\nsteps:\n  bad:\n    kind: read.time_series\n    params: { file: bad.csv }\n  \
         skip:\n    kind: read.frf\n    params: { file: skip.uff, format: uff }\n",
    )
    .unwrap();
    let c = compile(&recipe);
    let mut opts = RunOptions::new(dir.path().join("out")).with_renderer(spindlelab::renderer());
    opts.keep_going = true;
    opts.use_cache = false;
    let Err(engine::RunError::NodesFailed { failures, report }) =
        engine::run(&c, &spindlelab::registry(), &opts, &|_, _| {})
    else {
        panic!("the NaN sample must fail the run");
    };
    assert_eq!(failures[0].0, "bad");
    assert!(failures[0].1.starts_with("parameter `file`: "), "{}", failures[0].1);
    assert!(failures[0].1.contains("bad.csv:4:1: `NaN` in channel `force`: NaN samples"), "{}", failures[0].1);
    let Outcome::Computed { warnings, .. } = &report.result.outcomes[c.graph.by_step["skip"][0]] else { panic!() };
    assert_eq!(warnings.len(), 3, "{warnings:?}");
    assert!(warnings[1].contains("dataset 15 at line 11"), "{warnings:?}");
}

#[test]
fn a_uff_output_takes_only_frfs_and_time_series() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = dir.path().join("r.yaml");
    std::fs::write(
        &recipe,
        "spindlelab: 1\nsteps:\n  hit:\n    kind: impact.simulate\n    params: { hammer_mass: 0.01 kg, target_mass: 0.1 kg, \
         target_stiffness: 1e7 N/m, duration: 1 ms }\noutputs:\n  - { from: \"@hit.force\", file: force.uff }\n  \
         - { from: \"@hit.peak_force\", file: peak.uff }\n  - { from: \"@hit.force\", file: force.mat }\n",
    )
    .unwrap();
    let e = engine::compile_file(&recipe, &spindlelab::registry()).err().expect("rejected");
    let messages: Vec<String> =
        e.diagnostics.iter().map(|d| format!("{} | {}", d.message, d.help.clone().unwrap_or_default())).collect();
    assert_eq!(messages.len(), 2, "{messages:?}");
    assert!(
        messages[0].starts_with("a UFF file holds FRFs and time series; `@hit.peak_force` is a scalar"),
        "{messages:?}"
    );
    assert!(
        messages[1].contains("unsupported output format `mat`")
            && messages[1].contains("`.csv`, `.json`, `.uff`, or `.svg` / `.png`"),
        "{messages:?}"
    );
}

#[test]
fn file_parameters_are_documented_in_the_schema() {
    let s = spindlelab::engine::schema::recipe_schema(&spindlelab::registry());
    let read = s["properties"]["steps"]["additionalProperties"]["allOf"]
        .as_array()
        .unwrap()
        .iter()
        .find(|v| v["if"]["properties"]["kind"]["const"] == "read.frf")
        .expect("read.frf variant");
    let file = &read["then"]["properties"]["params"]["properties"]["file"];
    assert_eq!(file["type"], "string");
    assert!(file["description"].as_str().unwrap().contains("recipe's folder"), "{file}");
    let pattern = s["properties"]["outputs"]["items"]["properties"]["file"]["pattern"].as_str().unwrap();
    assert!(pattern.contains("uff"), "{pattern}");
}

/// An FRF saved by a European-locale spreadsheet (byte-order mark, `;` separators, decimal
/// commas, capitalised headers) runs through `read.frf` from the command line and is written
/// back in the plain form, with the same numbers.
#[test]
fn an_frf_saved_by_a_spreadsheet_reads_through_the_binary() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("m.csv"),
        "\u{feff}# units: m/N\r\nFreq_Hz;Real;Imag\r\n100;1,5e-6;-2,25e-7\r\n200;2,5e-6;-3e-7\r\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("r.yaml"),
        "spindlelab: 1\nname: s\nsteps:\n  m:\n    kind: read.frf\n    params: { file: m.csv }\noutputs:\n  - { from: \"@m.frf\", file: plain.csv }\n",
    )
    .unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(["run", "r.yaml", "-o", "o", "-q"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let back = formats::csv::read_frf(&std::fs::read(dir.path().join("o/plain.csv")).unwrap(), "plain.csv").unwrap();
    assert_eq!(back.freq_hz, vec![100.0, 200.0]);
    assert_eq!(back.values[0], spindlelab::stdlib::rcsa::Complex64::new(1.5e-6, -2.25e-7));
}
