//! Validation of the diagnosis on data it did not make: the labelled development cases of an
//! independent simulator (`../shared/data/dev-cases/`: its own beam elements, spindle, rotor
//! and bearing physics, noise and stability code). A handful run in the default tier; all 24
//! in the slow tier, scored per category with every miss in the denominator. The slow test
//! holds today's rates as floors (a regression guard on independent data, printed as a table);
//! the acceptance targets of the diagnosis (≥ 95 % identified) are not met yet, and the table
//! says where.
//!
//! Without `../shared` (a checkout alone) the tests say so and pass, except under CI (`CI` set),
//! where its absence fails them.

use serde_json::Value as Json;
use spindlelab::diagnose::Diagnosis;
use std::path::{Path, PathBuf};

/// The development cases beside the checkout, or `None` (said) when they are not there.
fn cases() -> Option<PathBuf> {
    let index = crate::common::shared("data/dev-cases/index.json", "the validation on independent cases")?;
    index.parent().map(Path::to_path_buf)
}

/// One case diagnosed and scored against its label.
struct Scored {
    case: String,
    category: String,
    /// The library effects the truth holds, and those the diagnosis named.
    truth: Vec<String>,
    named: Vec<String>,
    verdict: &'static str,
    /// Per effect named rightly: its main parameter, truth and diagnosed.
    params: Vec<(String, f64, f64)>,
    /// The largest file's gap ratio before and after.
    gap: (f64, f64),
    /// Whether a measured FRF stays unexplained after the diagnosis.
    frf_open: bool,
}

impl Scored {
    fn found(&self) -> usize {
        self.truth.iter().filter(|t| self.named.contains(t)).count()
    }
    fn false_effects(&self) -> usize {
        self.named.iter().filter(|n| !self.truth.contains(n)).count()
    }
}

fn diagnose(dir: &Path, case: &str) -> Scored {
    let truth: Json =
        serde_json::from_str(&std::fs::read_to_string(dir.join(case).join("truth.json")).unwrap()).unwrap();
    let out = tempfile::tempdir().unwrap();
    let d: Diagnosis = spindlelab::diagnose::batch::diagnose_case(
        &dir.join(case).join("case.json"),
        out.path(),
        &spindlelab::registry(),
    )
    .unwrap_or_else(|e| panic!("{case}: {e}"));
    let expected: Vec<String> = truth["expected_answer"]["effects"]
        .as_array()
        .map(|a| a.iter().filter_map(|v| v.as_str().map(str::to_string)).collect())
        .unwrap_or_default();
    let named: Vec<String> = d.effects.iter().map(|e| e.name.to_string()).collect();
    let mut params = Vec::new();
    for e in truth["effects"].as_array().into_iter().flatten() {
        let name = e["name"].as_str().unwrap_or_default();
        if let Some(ours) = d.effects.iter().find(|n| n.name == name)
            && let Some((t, g)) = main_param(name, &e["params"], &ours.params)
        {
            params.push((name.to_string(), t, g));
        }
    }
    let gap = d.gap.files.iter().fold((0.0f64, 0.0f64), |(b, a), f| (b.max(f.ratio_before), a.max(f.ratio_after)));
    Scored {
        case: case.to_string(),
        category: truth["category"].as_str().unwrap_or_default().to_string(),
        truth: expected,
        named,
        verdict: d.verdict,
        params,
        gap,
        frf_open: d.unexplained.iter().any(|u| matches!(u, spindlelab::diagnose::Unexplained::Frf(_))),
    }
}

/// An effect's main parameter as the independent simulator states it and as the diagnosis
/// reports it.
fn main_param(effect: &str, truth: &Json, ours: &Json) -> Option<(f64, f64)> {
    let pair = |t: &str, o: &str| Some((truth[t].as_f64()?, ours[o].as_f64()?));
    match effect {
        "sensor_delay" => pair("phase_slope_deg_per_khz", "phase_slope_deg_per_khz"),
        "mass_loading" => pair("added_mass_kg", "added_mass_kg"),
        "interface_compliance" => pair("kt_n_per_m", "kt_n_per_m"),
        "bearing_stiffness_change" => {
            pair("relative_change_at_fastest_measured", "relative_change_at_fastest_measured")
        }
        "flute_reduced_stiffness" => pair("equivalent_diameter_m", "equivalent_diameter_m"),
        "speed_dependent_cutting_coefficients" => {
            pair("ks_relative_change_per_10000_rpm", "ks_relative_change_per_10000_rpm")
        }
        "gyroscopic_mode_split" => {
            let t = truth["modes"].as_array()?.iter().find(|m| m["mode_index"] == 0)?["gyro_ratio"].as_f64()?;
            let o = ours["modes"].as_array()?.iter().find(|m| m["mode_index"] == 0)?["gyro_ratio"].as_f64()?;
            Some((t, o))
        }
        "spindle_speed_stiffening" => {
            let c = truth["changes"].as_array()?.first()?;
            let o = ours["changes"]
                .as_array()?
                .iter()
                .find(|m| m["direction"] == c["direction"] && m["mode_index"] == c["mode_index"])?;
            Some((c["delta_kf"].as_f64()?, o["delta_kf"].as_f64()?))
        }
        _ => None,
    }
}

/// A control, a sensor delay, an interface joint and a cutting law, each answered as its label
/// says, with the main parameter within 15 % and every file brought to the floor.
#[test]
fn a_handful_of_independent_cases_are_answered_as_labelled() {
    let Some(dir) = cases() else { return };
    for case in ["dev_09", "dev_10", "dev_06", "dev_23"] {
        let s = diagnose(&dir, case);
        assert_eq!(s.named, s.truth, "{case}: named {:?}, the label {:?} ({})", s.named, s.truth, s.verdict);
        for (effect, t, g) in &s.params {
            assert!(((g - t) / t).abs() < 0.15, "{case}: {effect} {g} against {t}");
        }
        if s.category != "none" && s.truth.iter().all(|t| t != "speed_dependent_cutting_coefficients") {
            assert!(s.gap.1 < 1.3, "{case}: the largest gap after is {:.2} of the floor", s.gap.1);
        }
    }
}

/// All 24 cases, scored per category with misses counted: library effects identified, false
/// effects named, the main parameter's error, controls and effects outside the library. The
/// floors are today's results on this independent set (see the table the test prints); the
/// targets it does not reach yet are in the note of the diagnosis issue.
#[test]
#[ignore = "slow: twenty-four diagnoses of independent cases, about six minutes on two cores"]
fn every_independent_case_scored_per_category_holds_todays_rates() {
    let Some(dir) = cases() else { return };
    let index: Json = serde_json::from_str(&std::fs::read_to_string(dir.join("index.json")).unwrap()).unwrap();
    let ids: Vec<String> =
        index.as_array().unwrap().iter().map(|c| c["case_id"].as_str().unwrap().to_string()).collect();
    let scored: Vec<Scored> = ids.iter().map(|c| diagnose(&dir, c)).collect();
    eprintln!("| case | category | truth | named | verdict | gap before → after | main parameter |");
    for s in &scored {
        let params: Vec<String> =
            s.params.iter().map(|(e, t, g)| format!("{e} {g:.4} vs {t:.4} ({:+.1} %)", 100.0 * (g - t) / t)).collect();
        eprintln!(
            "| {} | {} | {} | {} | {} | {:.2} → {:.2} | {} |",
            s.case,
            s.category,
            s.truth.join(" + "),
            s.named.join(" + "),
            s.verdict,
            s.gap.0,
            s.gap.1,
            params.join("; ")
        );
    }
    let of = |cat: &str| scored.iter().filter(|s| s.category == cat).collect::<Vec<_>>();
    let (single, combined, none, outside) = (of("single"), of("combined"), of("none"), of("unmodelled"));
    let effects =
        |v: &[&Scored]| (v.iter().map(|s| s.found()).sum::<usize>(), v.iter().map(|s| s.truth.len()).sum::<usize>());
    let falses = |v: &[&Scored]| v.iter().map(|s| s.false_effects()).sum::<usize>();
    let (found_single, all_single) = effects(&single);
    let (found_combined, all_combined) = effects(&combined);
    let params: Vec<f64> = scored.iter().flat_map(|s| s.params.iter().map(|(_, t, g)| ((g - t) / t).abs())).collect();
    let within = params.iter().filter(|e| **e < 0.15).count();
    eprintln!(
        "single effects identified {found_single}/{all_single}, false effects {}; combined {found_combined}/{all_combined}, false {}; controls with an effect named {}/{}; outside the library with an effect named {}/{}; main parameter within 15 %: {within}/{}",
        falses(&single),
        falses(&combined),
        none.iter().filter(|s| !s.named.is_empty()).count(),
        none.len(),
        outside.iter().filter(|s| !s.named.is_empty()).count(),
        outside.len(),
        params.len()
    );
    assert_eq!((single.len(), combined.len(), none.len(), outside.len()), (15, 4, 3, 2), "the set's categories");
    // Controls: nothing named, nothing unexplained.
    for s in &none {
        assert!(
            s.named.is_empty() && s.verdict == "no significant discrepancy",
            "{}: {:?} {}",
            s.case,
            s.named,
            s.verdict
        );
    }
    // Floors at today's results on this set.
    assert!(found_single >= 11, "single effects identified {found_single}/{all_single}");
    assert_eq!(falses(&single), 0, "false effects beside single ones");
    assert!(found_combined >= 2, "effects of combinations identified {found_combined}/{all_combined}");
    assert!(falses(&combined) <= 1, "false effects beside combined ones: {}", falses(&combined));
    assert!(outside.iter().all(|s| s.named.is_empty()), "a library effect named outside the library");
    // No trial-only effect beside an FRF the diagnosis leaves unexplained.
    for s in &scored {
        assert!(
            !(s.frf_open && s.named.iter().any(|n| n == "speed_dependent_cutting_coefficients")),
            "{}: the cutting law named while an FRF stays unexplained ({:?})",
            s.case,
            s.named
        );
    }
    assert!(within + 2 >= params.len(), "main parameters within 15 %: {within}/{}", params.len());
}
