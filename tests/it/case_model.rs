//! A recipe can say everything a training `case.json` says: the resolved recipe of
//! `tests/data/train-07-case.yaml` holds the same numbers as `tests/data/train_07-case.json`.

use crate::common;

use serde_json::Value as Json;
use std::path::Path;

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * b.abs().max(1e-30)
}

#[test]
fn train_07_baseline_round_trips_through_a_recipe() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let case: Json = serde_json::from_str(&std::fs::read_to_string(dir.join("train_07-case.json")).unwrap()).unwrap();
    let compiled = spindlelab::engine::compile_file(&dir.join("train-07-case.yaml"), &spindlelab::registry())
        .unwrap_or_else(|e| panic!("{}", e.render(false)));
    let r = &compiled.recipe;
    let f = |v: &Json| v.as_f64().unwrap();

    common::case::assert_baseline_matches(
        r,
        &case,
        &common::case::CaseNames {
            assembly: "artifact_in_holder",
            machine: "test_spindle",
            sensor: "accel",
            cutting: "trials",
        },
    );

    // The measurement list: each FRF file read by a step, with its direction, speed and grid.
    let out = tempfile::tempdir().unwrap();
    let mut opts = spindlelab::engine::exec::RunOptions::new(out.path()).with_renderer(spindlelab::renderer());
    opts.use_cache = false;
    let report = spindlelab::engine::run(&compiled, &spindlelab::registry(), &opts, &|_, _| {})
        .unwrap_or_else(|e| panic!("{e}"));
    let m = &case["measurements"];
    for (k, meas) in m["frf"].as_array().unwrap().iter().enumerate() {
        let step = format!("measured_{}", meas["direction"].as_str().unwrap());
        let i = compiled.graph.by_step[&step][0];
        let spindlelab::engine::value::Value::Frf(frf) = report.result.outcomes[i].outputs().unwrap()["frf"].as_ref()
        else {
            panic!("{step} is not an FRF");
        };
        let path = compiled.graph.instances[i].params.file("file").unwrap();
        assert!(path.ends_with(meas["file"].as_str().unwrap()), "measurement {k}: {}", path.display());
        assert_eq!(frf.direction.as_deref(), meas["direction"].as_str());
        assert_eq!(frf.speed.map(|s| s.rpm_as_written()), Some(f(&meas["speed_rpm"])));
        assert_eq!(frf.unit.symbol, meas["units"].as_str().unwrap());
        assert_eq!(frf.freq_hz.len() as f64, f(&m["frequency_lines"]));
        assert!(close(frf.freq_hz[1] - frf.freq_hz[0], f(&m["frequency_step_hz"])));
    }
}
