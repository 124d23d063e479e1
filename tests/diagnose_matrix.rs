//! A synthetic test matrix for the diagnosis: measurements generated from the project's own
//! models with a known effect added (each effect at two strengths and two noise levels,
//! pairs of effects, no-effect controls, and a resonance outside the library), with the
//! noise model of the training cases, then diagnosed from the baseline recipe.
//!
//! Run with `--nocapture` for the table of every case; the test holds the identification
//! rate (≥ 95 %) and the false alarms on the controls (none).

use num_complex::Complex64;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use spindlelab::diagnose::{self, VERDICT_EFFECTS, VERDICT_NONE, VERDICT_UNEXPLAINED};
use spindlelab::engine::exec::{self, Outcome, RunOptions};
use spindlelab::engine::value::Value;
use std::f64::consts::TAU;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The base case: two directions at 0 and 12000 rpm, a fluted tool, a capacitance probe.
const BASE: &str = "train_01";

fn base_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/training").join(BASE)
}

/// Effects by name, each with its recipe parameters' values.
type Effects = Vec<(&'static str, Vec<(&'static str, f64)>)>;

/// One case of the matrix.
struct Case {
    name: String,
    effects: Effects,
    /// `(direction, f Hz, k N/m, η)`: a resonance outside the library added to that direction.
    resonance: Option<(&'static str, f64, f64, f64)>,
    sigma_rel: f64,
    seed: u64,
}

/// Writes the measured files of `case` into `dir` (beside the baseline recipe).
fn generate(dir: &Path, case: &Case) {
    let registry = spindlelab::registry();
    let recipe = dir.join("recipe.yaml");
    let truth = diagnose::with_effects(&recipe, &registry, &case.effects).unwrap_or_else(|e| panic!("{e}"));
    let truth_path = dir.join("truth.yaml");
    std::fs::write(&truth_path, &truth).unwrap();
    let c = spindlelab::engine::compile_file(&truth_path, &registry).unwrap_or_else(|e| panic!("{}", e.render(false)));
    std::fs::remove_file(&truth_path).unwrap();
    let roles = diagnose::roles::Roles::find(&c);
    let model_step = roles.gaps[0].model.step.clone();
    let lobes_step = roles.lobes.clone().unwrap();
    let opts = RunOptions {
        use_cache: false,
        targets: Some(vec![model_step.clone(), lobes_step.clone()]),
        ..RunOptions::new(std::env::temp_dir())
    };
    let result = exec::execute(&c.recipe, &c.graph, &registry, &opts, &|_, _| {});
    let out = |i: usize| match &result.outcomes[i] {
        Outcome::Failed(e) => panic!("{}: {e}", c.graph.instances[i].id),
        o => o.outputs().unwrap().clone(),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(case.seed);
    let (floor, f_exc) = (1e-3, 7000.0);
    for &i in &c.graph.by_step[&model_step] {
        let label = &c.graph.instances[i].label;
        let file = label.split(", ").find_map(|a| a.strip_prefix("file=")).unwrap().to_string();
        let Value::Frf(h) = out(i)["frf"].as_ref().clone() else { panic!() };
        let dir_name = h.direction.clone().unwrap();
        let mut values = h.values.clone();
        if let Some((d, fr, k, eta)) = case.resonance
            && d == dir_name
        {
            for (v, f) in values.iter_mut().zip(&h.freq_hz) {
                let r = f / fr;
                *v += 1.0 / (k * Complex64::new(1.0 - r * r, eta));
            }
        }
        let peak = values.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let mut text = format!(
            "# synthetic: {}\n# units: m/N\n# direction: {dir_name}\n# speed_rpm: {}\nfreq_hz,real,imag,coherence\n",
            case.name,
            h.speed_rpm.unwrap()
        );
        for (v, f) in values.iter().zip(&h.freq_hz) {
            let mut normal = || -> Complex64 {
                let (a, b): (f64, f64) = (rng.sample(StandardNormal), rng.sample(StandardNormal));
                Complex64::new(a, b) * std::f64::consts::FRAC_1_SQRT_2
            };
            let abs = floor * peak * (1.0 + (f / f_exc).powi(4)).sqrt();
            let meas = v * (1.0 + normal() * case.sigma_rel) + normal() * abs;
            let var = case.sigma_rel.powi(2) * v.norm_sqr() + abs * abs;
            // The training cases' indicator, on the measured magnitude.
            let coherence = 1.0 / (1.0 + 20.0 * var / meas.norm_sqr());
            let _ = writeln!(text, "{f:.2},{:.6e},{:.6e},{coherence:.6}", meas.re, meas.im);
        }
        std::fs::write(dir.join(&file), text).unwrap();
    }
    // Sixty trials at random speeds of the diagram, 8–25 % in depth from the true limit (the
    // training cases keep them at least 8 % away).
    let Value::Lobes(l) = out(c.graph.by_step[&lobes_step][0])["speed_dependent"].as_ref().clone() else { panic!() };
    let mut text = String::from("# synthetic trials\nrpm,depth_mm,outcome,chatter_freq_hz\n");
    for _ in 0..60 {
        let k = rng.random_range(0..l.speed_rpm.len());
        let chatter = rng.random_bool(0.5);
        let away: f64 = rng.random_range(0.08..0.25);
        let depth = l.depth_limit[k] * if chatter { (away).exp() } else { (-away).exp() };
        let _ = writeln!(text, "{},{:.5},{},", l.speed_rpm[k], depth * 1e3, if chatter { "chatter" } else { "stable" });
    }
    std::fs::write(dir.join("trials.csv"), text).unwrap();
    let _ = TAU;
}

/// What a diagnosis of a case came to.
struct Outcome_ {
    name: String,
    kind: &'static str,
    right: bool,
    verdict: &'static str,
    named: Vec<&'static str>,
    param_error: Option<f64>,
    seconds: f64,
}

/// The main parameter of an effect, as the truth wrote it and as the diagnosis reports it.
fn main_param(effect: &str, truth: &[(&str, f64)], d: &diagnose::Diagnosis) -> Option<f64> {
    let p = &d.effects.iter().find(|e| e.name == effect)?.params;
    let t = |n: &str| truth.iter().find(|(k, _)| *k == n).map(|v| v.1);
    let (want, got) = match effect {
        "sensor_delay" => (t("sensor_phase_slope")?, p["phase_slope_deg_per_khz"].as_f64()?),
        "mass_loading" => (t("added_tip_mass")? * 1e-3, p["added_mass_kg"].as_f64()?),
        "interface_compliance" => (t("joint_kt")?, p["kt_n_per_m"].as_f64()?),
        "flute_reduced_stiffness" => (t("flute_d_equivalent")? * 1e-3, p["equivalent_diameter_m"].as_f64()?),
        "spindle_speed_stiffening" => {
            let c = p["changes"].as_array()?.iter().find(|c| c["direction"] == "x" && c["mode_index"] == 0)?;
            (t("spindle_x0_kf")?, c["delta_kf"].as_f64()?)
        }
        "speed_dependent_cutting_coefficients" => {
            (t("cutting_ks_change")?, p["ks_relative_change_per_10000_rpm"].as_f64()?)
        }
        _ => return None,
    };
    Some((got / want - 1.0).abs())
}

fn run(case: &Case) -> Outcome_ {
    let dir = tempfile::tempdir().unwrap();
    for entry in std::fs::read_dir(base_dir()).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "csv") {
            std::fs::copy(&p, dir.path().join(p.file_name().unwrap())).unwrap();
        }
    }
    let json = std::fs::read_to_string(base_dir().join("case.json")).unwrap();
    let recipe = spindlelab::import::recipe_from_case(&json, "case.json").unwrap();
    std::fs::write(dir.path().join("recipe.yaml"), recipe).unwrap();
    generate(dir.path(), case);
    if let Ok(keep) = std::env::var("SPINDLELAB_MATRIX_KEEP") {
        let to = Path::new(&keep).join(case.name.replace([' ', '#', '%', '+'], "_"));
        std::fs::create_dir_all(&to).unwrap();
        for entry in std::fs::read_dir(dir.path()).unwrap() {
            let p = entry.unwrap().path();
            std::fs::copy(&p, to.join(p.file_name().unwrap())).unwrap();
        }
    }
    let d = diagnose::diagnose(&dir.path().join("recipe.yaml"), &spindlelab::registry())
        .unwrap_or_else(|e| panic!("{}: {e}", case.name));
    let named: Vec<&'static str> = d.effects.iter().map(|e| e.name).collect();
    let (kind, right) = if let Some((dir_name, fr, _, _)) = case.resonance {
        let located = d
            .unexplained
            .iter()
            .filter_map(|u| u.frf())
            .any(|u| u.direction == dir_name && (u.near_hz - fr).abs() <= 0.1 * fr);
        ("out of library", d.verdict == VERDICT_UNEXPLAINED && located)
    } else if case.effects.is_empty() {
        ("control", d.verdict == VERDICT_NONE)
    } else {
        let mut want: Vec<&str> = case.effects.iter().map(|e| e.0).collect();
        let mut got = named.clone();
        want.sort();
        got.sort();
        (if case.effects.len() == 1 { "single" } else { "pair" }, d.verdict == VERDICT_EFFECTS && want == got)
    };
    let param_error = case
        .effects
        .iter()
        .filter_map(|(e, v)| main_param(e, v, &d))
        .fold(None, |a: Option<f64>, b| Some(a.map_or(b, |a| a.max(b))));
    Outcome_ { name: case.name.clone(), kind, right, verdict: d.verdict, named, param_error, seconds: d.seconds }
}

fn matrix() -> Vec<Case> {
    let mut cases = Vec::new();
    let mut seed = 1;
    let mut add = |name: String, effects: Effects, resonance, sigma_rel| {
        seed += 1;
        cases.push(Case { name, effects, resonance, sigma_rel, seed });
    };
    type Strengths<'a> = Vec<Vec<(&'a str, f64)>>;
    let singles: Vec<(&str, Strengths)> = vec![
        ("sensor_delay", vec![vec![("sensor_phase_slope", -8.0)], vec![("sensor_phase_slope", -20.0)]]),
        ("mass_loading", vec![vec![("added_tip_mass", 2.0)], vec![("added_tip_mass", 8.0)]]),
        (
            "interface_compliance",
            vec![
                vec![("joint_kt", 4e8), ("joint_ct", 300.0), ("joint_kr", 1e6), ("joint_cr", 5.0)],
                vec![("joint_kt", 1e8), ("joint_ct", 200.0), ("joint_kr", 2e5), ("joint_cr", 3.0)],
            ],
        ),
        ("flute_reduced_stiffness", vec![vec![("flute_d_equivalent", 11.5)], vec![("flute_d_equivalent", 10.5)]]),
        (
            "spindle_speed_stiffening",
            vec![
                vec![("spindle_x0_kf", 0.02), ("spindle_y0_kf", 0.015)],
                vec![("spindle_x0_kf", 0.04), ("spindle_x1_kf", 0.02), ("spindle_y0_kf", 0.03)],
            ],
        ),
        (
            "speed_dependent_cutting_coefficients",
            vec![
                vec![("cutting_ks_change", -0.3), ("cutting_beta_change", 2.0)],
                vec![("cutting_ks_change", 0.35), ("cutting_beta_change", -3.0)],
            ],
        ),
    ];
    // The weaker strength at the lower noise and the stronger at the higher, and the
    // weaker again at the higher noise for the effects whose signature is the smallest.
    for (effect, strengths) in &singles {
        let mut runs = vec![(0, 0.01), (1, 0.03)];
        if ["sensor_delay", "spindle_speed_stiffening"].contains(effect) {
            runs.push((0, 0.03));
        }
        for (i, sigma) in runs {
            add(format!("{effect} #{} σ {}%", i + 1, sigma * 100.0), vec![(effect, strengths[i].clone())], None, sigma);
        }
    }
    let pairs: Vec<Effects> = vec![
        vec![("sensor_delay", vec![("sensor_phase_slope", -14.0)]), ("mass_loading", vec![("added_tip_mass", 5.0)])],
        vec![
            (
                "interface_compliance",
                vec![("joint_kt", 2e8), ("joint_ct", 250.0), ("joint_kr", 4e5), ("joint_cr", 4.0)],
            ),
            ("sensor_delay", vec![("sensor_phase_slope", -10.0)]),
        ],
        vec![
            ("flute_reduced_stiffness", vec![("flute_d_equivalent", 11.0)]),
            ("speed_dependent_cutting_coefficients", vec![("cutting_ks_change", -0.2), ("cutting_beta_change", 2.0)]),
        ],
    ];
    for p in pairs {
        let name = p.iter().map(|e| e.0).collect::<Vec<_>>().join(" + ");
        add(name, p, None, 0.02);
    }
    // Controls are cheap (nothing to fit when nothing disagrees): several noise draws.
    for sigma in [0.01, 0.01, 0.02, 0.02, 0.03, 0.03] {
        add(format!("control σ {}%", sigma * 100.0), vec![], None, sigma);
    }
    add("probe-mount resonance x 4200 Hz".into(), vec![], Some(("x", 4200.0, 1.5e8, 0.05)), 0.02);
    add("probe-mount resonance y 6300 Hz".into(), vec![], Some(("y", 6300.0, 1e8, 0.04)), 0.02);
    cases
}

#[test]
fn the_synthetic_matrix_is_identified_without_false_alarms() {
    let only = std::env::var("SPINDLELAB_MATRIX_ONLY").unwrap_or_default();
    let cases: Vec<Case> = matrix().into_iter().filter(|c| c.name.contains(&only)).collect();
    let outcomes: Vec<Outcome_> = cases.par_iter().map(run).collect();
    println!(
        "| case | kind | verdict | named | right | main parameter error | seconds |\n|---|---|---|---|---|---|---|"
    );
    for o in &outcomes {
        println!(
            "| {} | {} | {} | {} | {} | {} | {:.1} |",
            o.name,
            o.kind,
            o.verdict,
            o.named.join(" + "),
            if o.right { "yes" } else { "NO" },
            o.param_error.map_or("—".into(), |e| format!("{:.1} %", e * 100.0)),
            o.seconds
        );
    }
    let with_effect: Vec<&Outcome_> = outcomes.iter().filter(|o| o.kind != "control").collect();
    let identified = with_effect.iter().filter(|o| o.right).count() as f64 / with_effect.len() as f64;
    let false_alarms = outcomes.iter().filter(|o| o.kind == "control" && !o.right).count();
    let errors: Vec<f64> = outcomes.iter().filter(|o| o.right).filter_map(|o| o.param_error).collect();
    let median = {
        let mut e = errors.clone();
        e.sort_by(f64::total_cmp);
        e.get(e.len() / 2).copied().unwrap_or(f64::NAN)
    };
    println!(
        "identification {:.1} % of {}, false alarms {} of {} controls, main-parameter error median {:.1} %, max {:.1} %",
        identified * 100.0,
        with_effect.len(),
        false_alarms,
        outcomes.len() - with_effect.len(),
        median * 100.0,
        errors.iter().fold(0.0f64, |a, b| a.max(*b)) * 100.0
    );
    assert_eq!(false_alarms, 0);
    assert!(with_effect.is_empty() || identified >= 0.95, "identification {identified}");
}
