//! Diagnosis cases with a known answer: a baseline recipe imported from a training case's
//! structure, measurements generated from that recipe with effects added (and optionally a
//! resonance outside the library, a finer mesh than the one diagnosed, mislabelled cuts),
//! with the training cases' noise model, and cutting trials placed off the true lobes.

use num_complex::Complex64;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use spindlelab::diagnose::{self, Diagnosis, roles::Roles};
use spindlelab::engine::exec::{self, Outcome, RunOptions};
use spindlelab::engine::syntax::{Raw, RecipeText, edit};
use spindlelab::engine::value::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Effects by name, each with its recipe parameters' values.
pub type Effects = Vec<(&'static str, Vec<(&'static str, f64)>)>;

/// One case.
pub struct Case {
    pub name: String,
    /// The training case whose structure (`case.json`) is the baseline.
    pub base: &'static str,
    pub effects: Effects,
    /// `(direction, f Hz, k N/m, η)`: a resonance outside the library added to that direction.
    pub resonance: Option<(&'static str, f64, f64, f64)>,
    pub sigma_rel: f64,
    pub seed: u64,
    /// Cuts recorded with the wrong outcome far from the boundary, at speeds spread over the
    /// diagram: what no effect of the library can explain.
    pub mislabelled: usize,
    /// The truth's longest beam element (`max_element`), when it is to differ from the
    /// diagnosed model's: data made by another discretisation than the one fitted.
    pub truth_mesh: Option<&'static str>,
}

impl Case {
    pub fn new(name: impl Into<String>, base: &'static str, effects: Effects, sigma_rel: f64, seed: u64) -> Case {
        Case { name: name.into(), base, effects, resonance: None, sigma_rel, seed, mislabelled: 0, truth_mesh: None }
    }
}

pub fn training_dir(case: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/training").join(case)
}

/// Writes the measured files of `case` into `dir` (beside the baseline recipe).
fn generate(dir: &Path, case: &Case) {
    let registry = spindlelab::registry();
    let recipe = dir.join("recipe.yaml");
    let mut truth = diagnose::with_effects(&recipe, &registry, &case.effects).unwrap_or_else(|e| panic!("{e}"));
    let truth_path = dir.join("truth.yaml");
    if let Some(mesh) = case.truth_mesh {
        std::fs::write(&truth_path, &truth).unwrap();
        let c =
            spindlelab::engine::compile_file(&truth_path, &registry).unwrap_or_else(|e| panic!("{}", e.render(false)));
        let mut r = RecipeText::new("truth.yaml", truth).unwrap();
        let beams: Vec<&str> =
            c.recipe.steps.iter().filter(|s| s.kind == "beam.substructure").map(|s| s.id.as_str()).collect();
        assert!(!beams.is_empty(), "{}: no beam.substructure step to mesh finer", case.name);
        for sub in beams {
            r.set_key(&edit::path(&["steps", sub, "params"]), "max_element", &Raw::text(mesh)).unwrap();
        }
        truth = r.text;
    }
    std::fs::write(&truth_path, &truth).unwrap();
    let c = spindlelab::engine::compile_file(&truth_path, &registry).unwrap_or_else(|e| panic!("{}", e.render(false)));
    std::fs::remove_file(&truth_path).unwrap();
    let roles = Roles::find(&c);
    let model_step = roles.gaps[0].model.step.clone();
    let lobes_step = roles.lobes.clone().unwrap();
    let opts = RunOptions {
        use_cache: false,
        targets: Some(vec![model_step.clone(), lobes_step.clone()]),
        renderer: Some(spindlelab::renderer()),
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
            h.speed.map(|s| s.rpm_as_written()).unwrap()
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
        let k = rng.random_range(0..l.speed.len());
        let chatter = rng.random_bool(0.5);
        let away: f64 = rng.random_range(0.08..0.25);
        let depth = l.depth_limit[k] * if chatter { away.exp() } else { (-away).exp() };
        let _ =
            writeln!(text, "{},{:.5},{},", l.speeds_rpm()[k], depth * 1e3, if chatter { "chatter" } else { "stable" });
    }
    // Mislabelled cuts, alternately: chatter recorded at half the limit, stable at twice it.
    for j in 0..case.mislabelled {
        let k = (j + 1) * l.speed.len() / (case.mislabelled + 1);
        let chatter = j % 2 == 0;
        let depth = l.depth_limit[k] * if chatter { 0.5 } else { 2.0 };
        let _ =
            writeln!(text, "{},{:.5},{},", l.speeds_rpm()[k], depth * 1e3, if chatter { "chatter" } else { "stable" });
    }
    std::fs::write(dir.join("trials.csv"), text).unwrap();
}

/// Imports the case's base structure, generates its measurements beside it and diagnoses it.
/// `SPINDLELAB_MATRIX_KEEP=DIR` keeps each case's files under `DIR/<name>`.
pub fn diagnose_case(case: &Case) -> Diagnosis {
    let base = training_dir(case.base);
    let dir = tempfile::tempdir().unwrap();
    for entry in std::fs::read_dir(&base).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "csv") {
            std::fs::copy(&p, dir.path().join(p.file_name().unwrap())).unwrap();
        }
    }
    let json = std::fs::read_to_string(base.join("case.json")).unwrap();
    let recipe = spindlelab::import::recipe_from_case(&json, "case.json").unwrap();
    std::fs::write(dir.path().join("recipe.yaml"), recipe).unwrap();
    generate(dir.path(), case);
    if let Ok(keep) = std::env::var("SPINDLELAB_MATRIX_KEEP") {
        let to = Path::new(&keep).join(case.name.replace([' ', '#', '%', '+', '/'], "_"));
        std::fs::create_dir_all(&to).unwrap();
        for entry in std::fs::read_dir(dir.path()).unwrap() {
            let p = entry.unwrap().path();
            std::fs::copy(&p, to.join(p.file_name().unwrap())).unwrap();
        }
    }
    diagnose::diagnose(&dir.path().join("recipe.yaml"), &spindlelab::registry())
        .unwrap_or_else(|e| panic!("{}: {e}", case.name))
}

/// The main parameter of an effect, as the truth wrote it and as the diagnosis reports it.
pub fn main_param(effect: &str, truth: &[(&str, f64)], d: &Diagnosis) -> Option<(f64, f64)> {
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
        "bearing_stiffness_change" => (t("bearing_kk")?, p["relative_change_at_reference"].as_f64()?),
        "gyroscopic_mode_split" => {
            let m = p["modes"].as_array()?.iter().find(|m| m["mode_index"] == 0)?;
            (t("spindle_0_gyro")?, m["gyro_ratio"].as_f64()?)
        }
        "machine_resonance" => {
            let (name, k) = truth.iter().find(|(k, _)| k.starts_with("machine_") && k.ends_with("_k"))?;
            // The direction must be the truth's as well.
            let d = name.trim_start_matches("machine_").trim_end_matches("_k");
            if p["direction"] != d {
                return None;
            }
            (*k, p["stiffness_n_per_m"].as_f64()?)
        }
        "speed_dependent_cutting_coefficients" => {
            (t("cutting_ks_change")?, p["ks_relative_change_per_10000_rpm"].as_f64()?)
        }
        _ => return None,
    };
    Some((want, got))
}

/// What a diagnosis of a case came to.
pub struct Scored {
    pub name: String,
    pub kind: &'static str,
    pub right: bool,
    pub verdict: &'static str,
    pub named: Vec<&'static str>,
    pub param_error: Option<f64>,
    /// Each effect's main parameter: name, truth, diagnosed.
    pub params: Vec<(&'static str, f64, f64)>,
    pub seconds: f64,
}

/// Diagnoses `case` and judges the answer: an out-of-library resonance must be located (and
/// any effect beside it named), a control must show nothing, effects must be named exactly.
pub fn score(case: &Case) -> Scored {
    let d = diagnose_case(case);
    let named: Vec<&'static str> = d.effects.iter().map(|e| e.name).collect();
    let mut want: Vec<&str> = case.effects.iter().map(|e| e.0).collect();
    let mut got = named.clone();
    want.sort();
    got.sort();
    let (kind, right) = if let Some((dir_name, fr, _, _)) = case.resonance {
        let located = d
            .unexplained
            .iter()
            .filter_map(|u| u.frf())
            .any(|u| u.direction == dir_name && (u.near_hz - fr).abs() <= 0.1 * fr);
        let verdict = if want.is_empty() { diagnose::VERDICT_UNEXPLAINED } else { diagnose::VERDICT_PARTIAL };
        ("out of library", d.verdict == verdict && located && want == got)
    } else if case.effects.is_empty() {
        ("control", d.verdict == diagnose::VERDICT_NONE)
    } else {
        (if case.effects.len() == 1 { "single" } else { "pair" }, d.verdict == diagnose::VERDICT_EFFECTS && want == got)
    };
    let params: Vec<(&'static str, f64, f64)> =
        case.effects.iter().filter_map(|(e, v)| main_param(e, v, &d).map(|(w, g)| (*e, w, g))).collect();
    let param_error = params
        .iter()
        .map(|(_, w, g)| (g / w - 1.0).abs())
        .fold(None, |a: Option<f64>, b| Some(a.map_or(b, |a| a.max(b))));
    Scored { name: case.name.clone(), kind, right, verdict: d.verdict, named, param_error, params, seconds: d.seconds }
}

/// Prints the table of outcomes and returns (identification rate over the cases with an
/// effect, false alarms on the controls, main-parameter errors of the right answers).
pub fn summarise(outcomes: &[Scored]) -> (f64, usize, Vec<f64>) {
    println!(
        "| case | kind | verdict | named | right | main parameters (truth → diagnosed) | worst error | seconds |\n|---|---|---|---|---|---|---|---|"
    );
    for o in outcomes {
        let params: Vec<String> = o.params.iter().map(|(e, w, g)| format!("{e} {w:.4} → {g:.4}")).collect();
        println!(
            "| {} | {} | {} | {} | {} | {} | {} | {:.1} |",
            o.name,
            o.kind,
            o.verdict,
            o.named.join(" + "),
            if o.right { "yes" } else { "NO" },
            params.join("; "),
            o.param_error.map_or("—".into(), |e| format!("{:.1} %", e * 100.0)),
            o.seconds
        );
    }
    let with_effect: Vec<&Scored> = outcomes.iter().filter(|o| o.kind != "control").collect();
    let identified = with_effect.iter().filter(|o| o.right).count() as f64 / with_effect.len().max(1) as f64;
    let false_alarms = outcomes.iter().filter(|o| o.kind == "control" && !o.right).count();
    let mut errors: Vec<f64> = outcomes.iter().filter(|o| o.right).filter_map(|o| o.param_error).collect();
    errors.sort_by(f64::total_cmp);
    let pct =
        |q: f64| errors.get(((errors.len() as f64 - 1.0) * q).round() as usize).copied().unwrap_or(f64::NAN) * 100.0;
    println!(
        "identification {:.1} % of {}, false alarms {} of {} controls, main-parameter error median {:.1} %, p90 {:.1} %, max {:.1} %",
        identified * 100.0,
        with_effect.len(),
        false_alarms,
        outcomes.len() - with_effect.len(),
        pct(0.5),
        pct(0.9),
        pct(1.0)
    );
    (identified, false_alarms, errors)
}
