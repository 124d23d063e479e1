//! A recipe can say everything a training `case.json` says: the resolved recipe of
//! `tests/data/train-07-case.yaml` holds the same numbers as `tests/data/train_07-case.json`.

use serde_json::Value as Json;
use spindlelab::engine::model::{Component, Joint};
use std::f64::consts::PI;
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

    for (name, m) in case["materials"].as_object().unwrap() {
        let got = r.materials[name.as_str()];
        assert!(close(got.youngs_modulus, f(&m["E_pa"])), "{name} E");
        assert!(close(got.density, f(&m["rho_kg_m3"])), "{name} rho");
        assert!(close(got.poisson, f(&m["nu"])) && close(got.loss_factor, f(&m["eta"])), "{name}");
    }

    let sections = case["holder_tool"]["sections"].as_array().unwrap();
    let asm = &r.assemblies["artifact_in_holder"];
    assert_eq!(asm.sections.len(), sections.len());
    for (got, want) in asm.sections.iter().zip(sections) {
        assert_eq!(got.name, want["name"].as_str().unwrap());
        let component = match want["component"].as_str().unwrap() {
            "holder" => Component::Holder,
            "holder+tool" => Component::HolderAndTool,
            _ => Component::Tool,
        };
        assert_eq!(got.component, component);
        assert_eq!(got.fluted, want["kind"] == "fluted");
        assert!(close(got.d_out_spindle_end, f(&want["d_out_spindle_end_m"])), "{}", got.name);
        assert!(close(got.d_out_tip_end, f(&want["d_out_tip_end_m"])), "{}", got.name);
        assert!(got.d_in == f(&want["d_in_m"]) || close(got.d_in, f(&want["d_in_m"])), "{}", got.name);
        assert!(close(got.length, f(&want["length_m"])), "{}", got.name);
        let outer = &case["materials"][want["outer_material"].as_str().unwrap()];
        assert!(close(got.outer.youngs_modulus, f(&outer["E_pa"])));
        match want["inner_material"].as_str() {
            Some(m) => assert!(close(got.inner.unwrap().youngs_modulus, f(&case["materials"][m]["E_pa"]))),
            None => assert!(got.inner.is_none()),
        }
    }

    let machine = &r.machines["test_spindle"];
    let joint = &case["holder_spindle_interface"];
    match machine.holder_interface {
        Joint::Compliant { kt, ct, kr, cr } => {
            assert!(close(kt, f(&joint["kt_n_per_m"])) && close(ct, f(&joint["ct_ns_per_m"])));
            assert!(close(kr, f(&joint["kr_nm_per_rad"])) && close(cr, f(&joint["cr_nms_per_rad"])));
        }
        Joint::Rigid => panic!("joint should be compliant"),
    }
    let spindle = machine.spindle.as_ref().unwrap();
    assert!(close(spindle.ref_speed, f(&case["spindle"]["ref_speed_rpm"]) * 2.0 * PI / 60.0));
    assert!(close(spindle.material.youngs_modulus, f(&case["spindle"]["material"]["E_pa"])));
    for (dir, modes) in &spindle.modes {
        let want = case["spindle"]["modes"][dir.as_str()].as_array().unwrap();
        assert_eq!(modes.len(), want.len());
        for (m, w) in modes.iter().zip(want) {
            assert!(
                close(m.freq_hz, f(&w["f_hz"]))
                    && close(m.diameter, f(&w["d_m"]))
                    && close(m.loss_factor, f(&w["eta"]))
            );
            assert_eq!((m.kf, m.keta), (f(&w["kf"]), f(&w["keta"])));
        }
    }

    let sensor = &r.sensors["accel"];
    assert_eq!(sensor.kind, case["sensor"]["type"].as_str().unwrap());
    assert!(close(sensor.mass, f(&case["sensor"]["mass_kg"])));

    let cut = &r.cutting["trials"];
    let c = &case["cutting"];
    let beta = f(&c["beta_deg"]).to_radians();
    assert_eq!(cut.teeth as f64, f(&c["teeth"]));
    assert!(close(cut.radial_immersion, f(&c["radial_immersion"])));
    assert!(!cut.up_milling);
    assert!(close(cut.kt, f(&c["Ks_n_per_m2"]) * beta.sin()) && close(cut.kn, f(&c["Ks_n_per_m2"]) * beta.cos()));
    assert!(close(cut.calibrated_at.unwrap(), f(&c["coefficients_calibrated_at_rpm"]) * 2.0 * PI / 60.0));
    let range: Vec<f64> = c["trial_rpm_range"].as_array().unwrap().iter().map(|v| f(v) * 2.0 * PI / 60.0).collect();
    assert!(cut.trial_speeds.iter().zip(&range).all(|(a, b)| close(*a, *b)));

    // The measurement list: each FRF file read by a step, with its direction, speed and grid.
    let out = tempfile::tempdir().unwrap();
    let mut opts = spindlelab::engine::exec::RunOptions::new(out.path());
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
        assert_eq!(frf.speed_rpm, Some(f(&meas["speed_rpm"])));
        assert_eq!(frf.unit.symbol, meas["units"].as_str().unwrap());
        assert_eq!(frf.freq_hz.len() as f64, f(&m["frequency_lines"]));
        assert!(close(frf.freq_hz[1] - frf.freq_hz[0], f(&m["frequency_step_hz"])));
    }
}
