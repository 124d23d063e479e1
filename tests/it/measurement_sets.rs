//! Measurement sets: files named once (list or glob) become one `read.frf` per file, and
//! model steps fed by them fan out, each taking its direction and speed from its file.

use crate::common;

use common::{assert_has, rejected, run};
use spindlelab::engine::value::Value;
use spindlelab::stdlib::rcsa::Complex64;
use std::path::Path;

fn rel_l2(a: &[Complex64], b: &[Complex64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y).norm_sqr()).sum();
    let den: f64 = b.iter().map(|y| y.norm_sqr()).sum();
    (num / den).sqrt()
}

/// Validation against the truth simulator: one spindle step, one coupling and one
/// comparison, fanned out over train_02's two files, reproduce the case's baseline gaps
/// (`truth.json`: rel_l2 0.9937 in x, 1.03 in y) and the baseline peaks (1852.5 / 1825 Hz).
#[test]
fn a_measurement_set_fans_the_model_out_per_file() {
    let r = run(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/train-02/measured-set.yaml"));
    let g = &r.compiled.graph;
    assert_eq!(g.by_step["tool_tip"].len(), 2);
    assert_eq!(g.by_step["spindle"].len(), 2);
    assert_eq!(g.by_step["model"].len(), 2);
    let labels: Vec<&str> = g.by_step["model"].iter().map(|&i| g.instances[i].label.as_str()).collect();
    assert_eq!(labels, ["file=frf_x_0rpm.csv", "file=frf_y_0rpm.csv"]);
    let frf =
        |step: &str, k: usize| match r.report.result.outcomes[g.by_step[step][k]].outputs().unwrap()["frf"].as_ref() {
            Value::Frf(f) => f.clone(),
            other => panic!("{:?}", other.port_type()),
        };
    for (k, dir, truth, peak_hz) in [(0, "x", 0.9937, 1852.5), (1, "y", 1.03, 1825.0)] {
        let (model, measured) = (frf("model", k), frf("tool_tip", k));
        assert_eq!(model.direction.as_deref(), Some(dir));
        assert_eq!(model.speed.map(|s| s.rpm_as_written()), Some(0.0));
        let gap = rel_l2(&model.values, &measured.values);
        assert!((gap / truth - 1.0).abs() < 2e-3, "{dir}: rel_l2 {gap} against the truth simulator's {truth}");
        let at = model.values.iter().enumerate().max_by(|a, b| a.1.norm().total_cmp(&b.1.norm())).unwrap().0;
        assert!((model.freq_hz[at] - peak_hz).abs() <= 2.5, "{dir}: peak at {} Hz", model.freq_hz[at]);
    }
}

#[test]
fn bad_measurement_sets_are_named_where_they_are_declared() {
    let text = rejected("measurement-sets.yaml", false);
    assert_has(
        &text,
        &[
            "error: `measured/none_*.csv` matches no file",
            "measurement-sets.yaml:5:21",
            "unknown key `sensr` in measurement set `odd`",
            "measurement-sets.yaml:6:41",
            "measurement set `hit` has the name of a step",
            "nothing was run",
        ],
    );
}

#[test]
fn a_file_that_disagrees_with_the_recipe_is_refused() {
    let text = rejected("measurement-disagrees.yaml", true);
    assert_has(
        &text,
        &[
            "node `accelerance` failed: parameter `units`: frf_x_0rpm.csv holds values in m/N (its `# units:`), the recipe says `m/s^2/N`",
            "measurement-disagrees.yaml:6:3",
            "node `at_speed` failed: parameter `speed`: frf_x_0rpm.csv was measured at 0 rpm (its `# speed_rpm`), the recipe says 12000 rpm",
        ],
    );
}
