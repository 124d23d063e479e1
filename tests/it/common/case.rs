//! A baseline case (`case.json` of the training data) against the recipe that states it.

use serde_json::Value as Json;
use spindlelab::engine::model::{Component, Joint, Recipe};
use std::f64::consts::PI;

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * b.abs().max(1e-30)
}

/// The entity names the recipe uses for the case's parts.
pub struct CaseNames<'a> {
    pub assembly: &'a str,
    pub machine: &'a str,
    pub sensor: &'a str,
    pub cutting: &'a str,
}

/// Every number of the case's materials, sections, joint, spindle modes, sensor and cutting
/// setup equals the resolved recipe's (SI, to 1e-12).
pub fn assert_baseline_matches(r: &Recipe, case: &Json, names: &CaseNames) {
    let f = |v: &Json| v.as_f64().unwrap();
    for (name, m) in case["materials"].as_object().unwrap() {
        let got = r.materials[name.as_str()];
        assert!(close(got.youngs_modulus, f(&m["E_pa"])), "{name} E");
        assert!(close(got.density, f(&m["rho_kg_m3"])), "{name} rho");
        assert!(close(got.poisson, f(&m["nu"])) && close(got.loss_factor, f(&m["eta"])), "{name}");
    }

    let sections = case["holder_tool"]["sections"].as_array().unwrap();
    let asm = &r.assemblies[names.assembly];
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

    let machine = &r.machines[names.machine];
    let joint = &case["holder_spindle_interface"];
    match machine.holder_interface {
        Joint::Compliant { kt, ct, kr, cr } => {
            assert!(close(kt, f(&joint["kt_n_per_m"])) && close(ct, f(&joint["ct_ns_per_m"])));
            assert!(close(kr, f(&joint["kr_nm_per_rad"])) && close(cr, f(&joint["cr_nms_per_rad"])));
        }
        Joint::Rigid => assert_eq!(joint["rigid"].as_bool(), Some(true), "joint should be compliant"),
    }
    let spindle = machine.spindle.as_ref().unwrap();
    assert!(close(spindle.ref_speed.rpm(), f(&case["spindle"]["ref_speed_rpm"])));
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
            assert_eq!((m.law.kf, m.law.kd), (f(&w["kf"]), f(&w["keta"])));
        }
    }

    let sensor = &r.sensors[names.sensor];
    assert_eq!(sensor.kind, case["sensor"]["type"].as_str().unwrap());
    assert!(close(sensor.mass, f(&case["sensor"]["mass_kg"])));

    let cut = &r.cutting[names.cutting];
    let c = &case["cutting"];
    let beta = f(&c["beta_deg"]).to_radians();
    assert_eq!(cut.teeth as f64, f(&c["teeth"]));
    assert!(close(cut.radial_immersion, f(&c["radial_immersion"])));
    assert_eq!(cut.up_milling, c["milling"] == "up");
    assert!(close(cut.kt, f(&c["Ks_n_per_m2"]) * beta.sin()) && close(cut.kn, f(&c["Ks_n_per_m2"]) * beta.cos()));
    assert!(close(cut.calibrated_at.unwrap().rpm(), f(&c["coefficients_calibrated_at_rpm"])));
    let range: Vec<f64> = c["trial_rpm_range"].as_array().unwrap().iter().map(|v| f(v) * 2.0 * PI / 60.0).collect();
    assert!(cut.trial_speeds.iter().zip(&range).all(|(a, b)| close(a.rad_s(), *b)));
}
