//! The diagnosis on cases it was not developed on: six base structures (the tools, holders
//! and spindles of six training cases), effect strengths drawn across the ranges
//! `docs/diagnosis.md` claims (not at the training values), noise at 1 % and 3 %, single
//! effects, a measurement effect beside a cutting one, resonances outside the library alone
//! and beside an effect, the spindle effects (whirl split and bearing law on the bases
//! measured at speed, a machine resonance on three others), and controls. The measurements are made by a different
//! discretisation than the one diagnosed: the truth's beams are meshed four times finer
//! (0.5 mm elements against 2 mm).
//!
//! Slow (about half a minute of diagnosis per case on one core): run with
//! `cargo test --test it diagnose_out_of_sample -- --ignored --nocapture` for the table.
//!
//! It asks what the diagnosis aims at: identification ≥ 95 % of the cases with an effect, no
//! false alarm on the controls, and the main parameter within 15 % in ≥ 90 % of the effects
//! named. The one miss today carries no evidence: a cutting-coefficient speed law on a base
//! calibrated at 4,000 rpm with trials from 2,000 to 9,000 rpm, where the law moves the limit
//! by less than the 8 % the trials keep from it, so the baseline misclassifies none of the
//! sixty trials and "no significant discrepancy" is the only answer the data allow.

use crate::common;

use common::synthetic::{Case, Effects, score, summarise, training_dir};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// The base structures: each training case's tool, holder, spindle, sensor and cut.
const BASES: [&str; 6] = ["train_01", "train_02", "train_03", "train_04", "train_05", "train_06"];

/// What a draw needs of a base: the nominal diameter of its fluted section (mm), its fastest
/// measured speed and spindle reference speed (rpm), and its highest spindle mode per direction
/// (Hz).
#[derive(Clone)]
struct Base {
    fluted_mm: f64,
    top_rpm: f64,
    ref_rpm: f64,
    spindle_top_hz: Vec<(String, f64)>,
}

/// Speeds the base case measures at, and what a draw needs of it.
fn base_facts(base: &str) -> (usize, Base) {
    let speeds = std::fs::read_dir(training_dir(base))
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.starts_with("frf_x_"))
        .count();
    let case: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(training_dir(base).join("case.json")).unwrap()).unwrap();
    let fluted = case["holder_tool"]["sections"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["kind"] == "fluted")
        .map_or(f64::NAN, |s| s["d_out_spindle_end_m"].as_f64().unwrap() * 1e3);
    let top_rpm = case["measurements"]["frf"]
        .as_array()
        .map_or(0.0, |f| f.iter().filter_map(|f| f["speed_rpm"].as_f64()).fold(0.0, f64::max));
    let spindle = &case["spindle"];
    let spindle_top_hz = spindle["modes"]
        .as_object()
        .unwrap()
        .iter()
        .map(|(d, m)| {
            (d.clone(), m.as_array().unwrap().iter().map(|m| m["f_hz"].as_f64().unwrap()).fold(0.0, f64::max))
        })
        .collect();
    let ref_rpm = spindle["ref_speed_rpm"].as_f64().unwrap_or(10_000.0);
    (speeds, Base { fluted_mm: fluted, top_rpm, ref_rpm, spindle_top_hz })
}

/// One effect drawn at a strength across its documented range.
fn draw(effect: &'static str, rng: &mut ChaCha8Rng, base: &Base) -> (&'static str, Vec<(&'static str, f64)>) {
    let fluted_mm = base.fluted_mm;
    // (n/n_ref) at the fastest measured speed.
    let at_top = base.top_rpm / base.ref_rpm;
    let sign = |rng: &mut ChaCha8Rng| if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let log_uniform = |rng: &mut ChaCha8Rng, lo: f64, hi: f64| (lo.ln() + rng.random::<f64>() * (hi / lo).ln()).exp();
    let params = match effect {
        "sensor_delay" => vec![("sensor_phase_slope", sign(rng) * rng.random_range(4.0..40.0))],
        "mass_loading" => vec![("added_tip_mass", rng.random_range(1.0..15.0))],
        "interface_compliance" => vec![
            ("joint_kt", log_uniform(rng, 5e7, 1e9)),
            ("joint_ct", rng.random_range(100.0..500.0)),
            ("joint_kr", log_uniform(rng, 1e5, 5e6)),
            ("joint_cr", rng.random_range(1.0..10.0)),
        ],
        "flute_reduced_stiffness" => vec![("flute_d_equivalent", fluted_mm * rng.random_range(0.78..0.95))],
        "spindle_speed_stiffening" => {
            vec![("spindle_x0_kf", rng.random_range(0.015..0.05)), ("spindle_y0_kf", rng.random_range(0.01..0.04))]
        }
        // The first mode's gyroscopic coefficient I_p/I_d, of a slender rotor to a stubby one.
        "gyroscopic_mode_split" => vec![("spindle_0_gyro", rng.random_range(0.2..0.6))],
        // The bearings 3–10 % softer at the fastest measured speed.
        "bearing_stiffness_change" => vec![("bearing_kk", -rng.random_range(0.03..0.10) / at_top.powi(2))],
        // A mode of the machine along x or y at 30–85 % of the spindle's highest mode there.
        "machine_resonance" => {
            let (d, top) = base.spindle_top_hz[rng.random_range(0..base.spindle_top_hz.len())].clone();
            let f = top * rng.random_range(0.3..0.85);
            let (k, zeta) = (log_uniform(rng, 1e8, 4e8), rng.random_range(0.02..0.05));
            let names: [&'static str; 3] = match d.as_str() {
                "x" => ["machine_x_f", "machine_x_k", "machine_x_zeta"],
                _ => ["machine_y_f", "machine_y_k", "machine_y_zeta"],
            };
            vec![(names[0], f), (names[1], k), (names[2], zeta)]
        }
        "speed_dependent_cutting_coefficients" => vec![
            ("cutting_ks_change", sign(rng) * rng.random_range(0.15..0.4)),
            ("cutting_beta_change", sign(rng) * rng.random_range(1.0..4.0)),
        ],
        other => panic!("no range for {other}"),
    };
    (effect, params)
}

fn cases() -> Vec<Case> {
    let mut rng = ChaCha8Rng::seed_from_u64(20261127);
    let mut cases = Vec::new();
    let mut seed = 1000;
    let mut push = |name: String, base: &'static str, effects: Effects, sigma: f64, cases: &mut Vec<Case>| {
        seed += 1;
        cases.push(Case { truth_mesh: Some("0.5 mm"), ..Case::new(name, base, effects, sigma, seed) });
    };
    // Three single effects per base, each effect on three bases; the speed law where the
    // base measures at two speeds or more.
    let singles: [[&'static str; 3]; 6] = [
        ["sensor_delay", "spindle_speed_stiffening", "interface_compliance"],
        ["flute_reduced_stiffness", "mass_loading", "speed_dependent_cutting_coefficients"],
        ["spindle_speed_stiffening", "mass_loading", "interface_compliance"],
        ["flute_reduced_stiffness", "sensor_delay", "speed_dependent_cutting_coefficients"],
        ["spindle_speed_stiffening", "sensor_delay", "mass_loading"],
        ["flute_reduced_stiffness", "interface_compliance", "speed_dependent_cutting_coefficients"],
    ];
    for (b, &base) in BASES.iter().enumerate() {
        let (speeds, facts) = base_facts(base);
        for effect in singles[b] {
            assert!(effect != "spindle_speed_stiffening" || speeds >= 2, "{base} measures at one speed");
            let sigma = if rng.random_bool(0.5) { 0.01 } else { 0.03 };
            let e = draw(effect, &mut rng, &facts);
            push(format!("{base} {effect} σ {}%", sigma * 100.0), base, vec![e], sigma, &mut cases);
        }
        // A measurement effect beside a cutting one.
        let measurement = if b % 2 == 0 { "sensor_delay" } else { "mass_loading" };
        let pair =
            vec![draw(measurement, &mut rng, &facts), draw("speed_dependent_cutting_coefficients", &mut rng, &facts)];
        push(format!("{base} {measurement} + cutting σ 2%"), base, pair, 0.02, &mut cases);
        // A control.
        let sigma = if b % 2 == 0 { 0.01 } else { 0.03 };
        push(format!("{base} control σ {}%", sigma * 100.0), base, vec![], sigma, &mut cases);
    }
    // Resonances outside the library: alone, and beside an effect.
    let mut resonance = |name: &str, base: &'static str, effects: Effects, r: (&'static str, f64, f64, f64)| {
        seed += 1;
        cases.push(Case {
            resonance: Some(r),
            truth_mesh: Some("0.5 mm"),
            ..Case::new(name, base, effects, 0.02, seed)
        });
    };
    resonance("train_02 resonance y 5100 Hz", "train_02", vec![], ("y", 5100.0, 1.2e8, 0.04));
    resonance("train_04 resonance x 3300 Hz", "train_04", vec![], ("x", 3300.0, 2e8, 0.06));
    let delay = draw("sensor_delay", &mut rng, &base_facts("train_05").1);
    resonance("train_05 sensor_delay + resonance x 4700 Hz", "train_05", vec![delay], ("x", 4700.0, 1.5e8, 0.05));
    // The spindle effects added later, each on three bases, from a generator of their own so
    // the draws above stay as they were: the speed-dependent ones on the bases measured at
    // speed, the machine's resonance on three others.
    let mut rng = ChaCha8Rng::seed_from_u64(20261128);
    let spindle: [(&'static str, [&'static str; 3]); 3] = [
        ("gyroscopic_mode_split", ["train_01", "train_03", "train_05"]),
        ("bearing_stiffness_change", ["train_01", "train_03", "train_05"]),
        ("machine_resonance", ["train_02", "train_04", "train_06"]),
    ];
    for (effect, bases) in spindle {
        for base in bases {
            let (speeds, facts) = base_facts(base);
            assert!(effect == "machine_resonance" || speeds >= 2, "{base} measures at one speed");
            let sigma = if rng.random_bool(0.5) { 0.01 } else { 0.03 };
            let e = draw(effect, &mut rng, &facts);
            seed += 1;
            cases.push(Case {
                truth_mesh: Some("0.5 mm"),
                ..Case::new(format!("{base} {effect} σ {}%", sigma * 100.0), base, vec![e], sigma, seed)
            });
        }
    }
    cases
}

#[test]
#[ignore = "slow: about forty diagnoses of new cases, several minutes on two cores"]
fn out_of_sample_matrix_meets_the_diagnosis_aims() {
    let only = std::env::var("SPINDLELAB_MATRIX_ONLY").unwrap_or_default();
    let cases: Vec<Case> = cases().into_iter().filter(|c| c.name.contains(&only)).collect();
    assert!(!cases.is_empty(), "SPINDLELAB_MATRIX_ONLY={only:?} matches no case: nothing would be checked");
    let outcomes: Vec<_> = cases.par_iter().map(score).collect();
    let (identified, false_alarms, _) = summarise(&outcomes);
    // The main parameters of the effects the FRFs carry, and of the cutting coefficients'
    // speed law, which the trials carry (a change of Ks and one of β move the boundary alike
    // at most speeds, so the trials fix their effect on the lobes better than their split).
    let errors = |cutting: bool| -> Vec<f64> {
        outcomes
            .iter()
            .flat_map(|o| o.params.iter())
            .filter(|(e, ..)| (*e == "speed_dependent_cutting_coefficients") == cutting)
            .map(|(_, w, g)| (g / w - 1.0).abs())
            .collect()
    };
    let (frf, trials) = (errors(false), errors(true));
    let within = |e: &[f64]| e.iter().filter(|e| **e <= 0.15).count();
    println!(
        "main parameter within 15 %: {} of {} measured by the FRFs, {} of {} by the trials",
        within(&frf),
        frf.len(),
        within(&trials),
        trials.len()
    );
    assert_eq!(false_alarms, 0);
    // A filtered run of controls only has nothing to identify.
    let with_effect = outcomes.iter().filter(|o| o.kind != "control").count();
    assert!(with_effect == 0 || identified >= 0.95, "identification {identified}");
    let (good, all) = (within(&frf) + within(&trials), frf.len() + trials.len());
    assert!(good as f64 >= 0.9 * all as f64, "main parameters within 15 %: {good} of {all}");
}
