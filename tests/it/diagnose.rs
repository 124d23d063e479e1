//! Diagnosis against the truth simulator's labelled cases (`tests/data/training/`, made by a
//! separate program; the answers are read from each case's `truth.json` and nowhere else),
//! and the command line around it.

use serde_json::Value as Json;
use spindlelab::diagnose::{self, Diagnosis, VERDICT_EFFECTS, VERDICT_NONE, VERDICT_UNEXPLAINED};
use std::path::{Path, PathBuf};
use std::process::Command;

fn training(case: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/training").join(case)
}

/// The case imported into a fresh folder beside copies of its data files.
fn imported(case: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    for entry in std::fs::read_dir(training(case)).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "csv") {
            std::fs::copy(&p, dir.path().join(p.file_name().unwrap())).unwrap();
        }
    }
    let json = std::fs::read_to_string(training(case).join("case.json")).unwrap();
    let recipe = spindlelab::import::recipe_from_case(&json, "case.json").unwrap();
    let path = dir.path().join("recipe.yaml");
    std::fs::write(&path, recipe).unwrap();
    (dir, path)
}

fn truth(case: &str) -> Json {
    serde_json::from_str(&std::fs::read_to_string(training(case).join("truth.json")).unwrap()).unwrap()
}

/// Relative error of every nonzero number the truth states for an effect, matched by key
/// (and, for lists of changes, by their direction and mode index).
fn param_errors(want: &Json, got: &Json, at: &str, out: &mut Vec<(String, f64, f64)>) {
    match (want, got) {
        (Json::Number(w), Json::Number(g)) => {
            let (w, g) = (w.as_f64().unwrap(), g.as_f64().unwrap());
            if w != 0.0 {
                out.push((at.to_string(), w, g));
            }
        }
        (Json::Object(w), Json::Object(g)) => {
            for (k, wv) in w {
                if let Some(gv) = g.get(k) {
                    param_errors(wv, gv, &format!("{at}.{k}"), out);
                }
            }
        }
        (Json::Array(w), Json::Array(g)) => {
            for (i, wv) in w.iter().enumerate() {
                let same = |gv: &&Json| ["direction", "mode_index"].iter().all(|k| wv.get(k) == gv.get(k));
                let gv = if wv.get("direction").is_some() { g.iter().find(same) } else { g.get(i) };
                if let Some(gv) = gv {
                    param_errors(wv, gv, &format!("{at}[{i}]"), out);
                }
            }
        }
        _ => {}
    }
}

/// Checks a diagnosis against the case's truth: the answer, the parameters within 15 %,
/// the FRFs at the noise floor after (ratio ≤ 1.2) and the trials as the truth has them.
fn check(case: &str, d: &Diagnosis) {
    let t = truth(case);
    let expected = &t["expected_answer"];
    let want: Vec<&str> = expected["effects"].as_array().unwrap().iter().map(|e| e.as_str().unwrap()).collect();
    let got: Vec<&str> = d.effects.iter().map(|e| e.name).collect();
    let summary = diagnose::markdown(d);
    match expected["statement"].as_str() {
        Some(s) if s.starts_with(VERDICT_UNEXPLAINED) => {
            assert_eq!(d.verdict, VERDICT_UNEXPLAINED, "{summary}");
            let (dir, near) = (expected["direction"].as_str().unwrap(), expected["near_hz"].as_f64().unwrap());
            assert!(
                d.unexplained
                    .iter()
                    .filter_map(|u| u.frf())
                    .any(|u| u.direction == dir && (u.near_hz - near).abs() <= 0.1 * near),
                "{summary}"
            );
            return;
        }
        Some(s) if s.starts_with(VERDICT_NONE) => assert_eq!(d.verdict, VERDICT_NONE, "{summary}"),
        _ => {
            assert_eq!(d.verdict, VERDICT_EFFECTS, "{summary}");
            let (mut a, mut b) = (want.clone(), got.clone());
            a.sort();
            b.sort();
            assert_eq!(a, b, "{summary}");
        }
    }
    for e in t["effects"].as_array().unwrap() {
        let name = e["name"].as_str().unwrap();
        let mine = &d.effects.iter().find(|x| x.name == name).unwrap().params;
        let mut errors = Vec::new();
        param_errors(&e["params"], mine, name, &mut errors);
        assert!(!errors.is_empty(), "{name}: no parameter compared\n{summary}");
        for (at, w, g) in errors {
            assert!((g / w - 1.0).abs() <= 0.15, "{at}: {g} against the truth's {w}\n{summary}");
        }
    }
    for f in &d.gap.files {
        assert!(f.ratio_after <= 1.2, "{}: gap ratio after {}\n{summary}", f.file, f.ratio_after);
    }
    let trials = d.gap.trials.as_ref().unwrap();
    assert_eq!(trials.n, t["gap"]["trials"]["n"].as_u64().unwrap() as usize);
    assert_eq!(
        trials.misclassified_after,
        t["gap"]["trials"]["misclassified_after"].as_u64().unwrap() as usize,
        "{summary}"
    );
}

fn run_case(case: &str) {
    let (_dir, recipe) = imported(case);
    let d = diagnose::diagnose(&recipe, &spindlelab::registry()).unwrap_or_else(|e| panic!("{e}"));
    check(case, &d);
}

#[test]
fn train_01_sensor_delay() {
    run_case("train_01");
}

#[test]
fn train_02_interface_compliance() {
    run_case("train_02");
}

#[test]
fn train_03_spindle_speed_stiffening() {
    run_case("train_03");
}

#[test]
fn train_04_mass_loading() {
    run_case("train_04");
}

#[test]
fn train_05_flute_reduced_stiffness() {
    run_case("train_05");
}

#[test]
fn train_06_speed_dependent_cutting_coefficients() {
    run_case("train_06");
}

#[test]
fn train_07_no_effect() {
    run_case("train_07");
}

#[test]
fn train_08_unmodelled_resonance() {
    run_case("train_08");
}

/// The spindle effects as the forward model writes them: the bearing law and the whirl
/// split leave the FRFs at rest as they were and change those at speed; the machine's
/// resonance changes every FRF of its direction and none of the other.
#[test]
fn the_spindle_effects_act_where_their_physics_does() {
    let (dir, recipe) = imported("train_01");
    let registry = spindlelab::registry();
    let ratios = |effects: &[(&str, Vec<(&str, f64)>)]| -> Vec<(String, f64)> {
        let text = diagnose::with_effects(&recipe, &registry, effects).unwrap_or_else(|e| panic!("{e}"));
        let path = dir.path().join("with_effect.yaml");
        std::fs::write(&path, text).unwrap();
        let e = diagnose::evaluate_file(&path, &registry).unwrap_or_else(|e| panic!("{e}"));
        e.files.iter().map(|f| (format!("{} {}", f.direction, f.speed_rpm), f.ratio)).collect()
    };
    let base = ratios(&[]);
    let changed = |with: &[(String, f64)]| -> Vec<String> {
        let mut v: Vec<String> =
            base.iter().zip(with).filter(|(a, b)| (a.1 - b.1).abs() > 1e-9 * a.1).map(|(a, _)| a.0.clone()).collect();
        v.sort();
        v
    };
    let at_speed = ["x 12000", "y 12000"];
    assert_eq!(changed(&ratios(&[("bearing_stiffness_change", vec![("bearing_kk", -0.05)])])), at_speed);
    assert_eq!(changed(&ratios(&[("gyroscopic_mode_split", vec![("spindle_0_gyro", 0.3)])])), at_speed);
    let machine =
        ratios(&[("machine_resonance", vec![("machine_y_f", 1200.0), ("machine_y_k", 2e8), ("machine_y_zeta", 0.03)])]);
    assert_eq!(changed(&machine), ["y 0", "y 12000"]);
}

fn spindlelab(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_spindlelab")).args(args).env("NO_COLOR", "1").output().unwrap()
}

/// The command writes its three files and its pictures; `report` makes the folder a page;
/// `diagnosed.yaml` differs from the input only by added lines (the effect, its parameters and
/// a header), and runs to the noise floor.
#[test]
fn the_command_writes_a_diagnosed_recipe_that_runs_at_the_floor() {
    let (dir, recipe) = imported("train_04");
    let out = dir.path().join("diag");
    let o = spindlelab(&["diagnose".as_ref(), recipe.as_os_str(), "-o".as_ref(), out.as_os_str(), "-q".as_ref()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json: Json = serde_json::from_str(&std::fs::read_to_string(out.join("diagnosis.json")).unwrap()).unwrap();
    assert_eq!(json["verdict"], "effects");
    assert_eq!(json["effects"][0]["name"], "mass_loading");
    for key in ["effects", "unexplained", "gap", "candidates"] {
        assert!(json.get(key).is_some(), "{key}");
    }
    let md = std::fs::read_to_string(out.join("diagnosis.md")).unwrap();
    assert!(md.contains("mass_loading"));
    // The fitted mass as value ± σ, rounded to σ, here and in the diagnosed recipe's header.
    let fitted = md.lines().find(|l| l.contains("fitted: added_tip_mass = ")).unwrap_or_else(|| panic!("{md}"));
    assert!(fitted.contains(" ± ") && fitted.ends_with(" g"), "{fitted}");
    // The pictures: per measured file and the lobes, linked from the page, each an SVG that
    // names what it draws.
    for (picture, needles) in [
        ("fit_frf_x_0rpm.svg", &["measured", "model before", "model after"][..]),
        ("fit_frf_y_0rpm.svg", &["measured", "model before", "model after"]),
        ("lobes.svg", &["model before", "model after", "trials: stable"]),
    ] {
        assert!(md.contains(&format!("]({picture})")), "{picture} not linked\n{md}");
        let svg = std::fs::read_to_string(out.join(picture)).unwrap();
        assert!(svg.starts_with("<svg") || svg.starts_with("<?xml"), "{picture}");
        for n in needles {
            assert!(svg.contains(n), "{picture} lacks `{n}`");
        }
    }
    // `report` makes the folder one page with the pictures in it.
    let page = dir.path().join("diag.html");
    let o = spindlelab(&["report".as_ref(), out.as_os_str(), "-o".as_ref(), page.as_os_str()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = std::fs::read_to_string(&page).unwrap();
    assert_eq!(html.matches("<figure id=\"fig-").count(), 3, "{html}");
    assert!(html.contains("href=\"#fig-lobes.svg\"") && html.contains("<table>"));
    let input = std::fs::read_to_string(&recipe).unwrap();
    let diagnosed = std::fs::read_to_string(out.join("diagnosed.yaml")).unwrap();
    // The fitted value is written to six significant digits, not the sixteen of a double.
    let mass = diagnosed
        .lines()
        .find(|l| l.trim_start().starts_with("added_tip_mass:"))
        .unwrap_or_else(|| panic!("{diagnosed}"));
    let number = mass.split(':').nth(1).unwrap().split_whitespace().next().unwrap();
    let digits = number.split(['e', 'E']).next().unwrap().chars().filter(char::is_ascii_digit).collect::<String>();
    assert!(digits.trim_start_matches('0').len() <= 6, "{mass}");
    // Every input line is kept, in order, but for a reference rewired through the effect's
    // step; the rest is added.
    let refs = |l: &str| -> String {
        l.split('"').enumerate().map(|(i, p)| if i % 2 == 1 && p.starts_with('@') { "@" } else { p }).collect()
    };
    let mut lines = diagnosed.lines();
    let mut rewired = 0;
    for l in input.lines() {
        let d = lines
            .find(|d| refs(d) == refs(l))
            .unwrap_or_else(|| panic!("input line `{l}` is missing from diagnosed.yaml"));
        rewired += usize::from(d != l);
    }
    assert_eq!(rewired, 1, "only the gap's model input is rewired");
    // Placed beside the data, it runs, and both FRFs sit at the floor.
    let placed = dir.path().join("diagnosed.yaml");
    std::fs::write(&placed, &diagnosed).unwrap();
    let run_out = dir.path().join("run");
    let o = spindlelab(&["run".as_ref(), placed.as_os_str(), "-o".as_ref(), run_out.as_os_str(), "-v".as_ref()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    let ratios: Vec<f64> =
        text.lines().filter_map(|l| l.trim().strip_prefix("ratio: ")).map(|v| v.trim().parse().unwrap()).collect();
    assert_eq!(ratios.len(), 2, "{text}");
    assert!(ratios.iter().all(|r| *r <= 1.2), "{ratios:?}");
}

#[test]
fn a_recipe_without_measurements_is_refused_with_what_to_add() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = dir.path().join("r.yaml");
    std::fs::write(
        &recipe,
        "spindlelab: 1\nname: r\nsteps:\n  hit:\n    kind: impact.simulate\n    params: { hammer_mass: 0.05 kg, hammer_stiffness: 500 N/m, target_mass: 0.1 kg, target_stiffness: 5e7 N/m }\n",
    )
    .unwrap();
    let o = spindlelab(&["diagnose".as_ref(), recipe.as_os_str(), "-o".as_ref(), dir.path().join("o").as_os_str()]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("nothing compares a model with a measurement") && err.contains("frf.gap"), "{err}");
    assert!(!dir.path().join("o").exists(), "nothing is written for a refused recipe");
}

/// A measurement that is noise only (coherence near zero everywhere) supports no claim.
#[test]
fn a_measurement_that_is_all_noise_is_refused() {
    let (dir, recipe) = imported("train_04");
    for f in ["frf_x_0rpm.csv", "frf_y_0rpm.csv"] {
        let p = dir.path().join(f);
        let text = std::fs::read_to_string(&p).unwrap();
        let noisy: Vec<String> = text
            .lines()
            .map(|l| {
                if l.starts_with('#') || l.starts_with("freq") {
                    return l.to_string();
                }
                let mut c: Vec<&str> = l.split(',').collect();
                c[3] = "0.001";
                c.join(",")
            })
            .collect();
        std::fs::write(&p, noisy.join("\n")).unwrap();
    }
    let o = spindlelab(&["diagnose".as_ref(), recipe.as_os_str(), "-o".as_ref(), dir.path().join("o").as_os_str()]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stdout));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("every measurement is noise"), "{err}");
}

/// A recipe that fits its own parameters is refused: the diagnosis fits the effects' ones.
#[test]
fn a_recipe_with_a_fit_block_is_refused() {
    let recipe = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/train-02/joint-fit.yaml");
    let dir = tempfile::tempdir().unwrap();
    let o = spindlelab(&["diagnose".as_ref(), recipe.as_os_str(), "-o".as_ref(), dir.path().join("o").as_os_str()]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("joint-fit.yaml") && err.contains("`fit:` block"), "{err}");
    assert!(!dir.path().join("o").exists());
}

/// `diagnose --batch` diagnoses every case a pattern matches, each into a folder of its own,
/// and writes a summary that reads back through the table reader; a broken case is a row with
/// its error (exit 1) and the others are still diagnosed.
#[test]
fn a_batch_diagnoses_every_case_and_summarises_them() {
    let dir = tempfile::tempdir().unwrap();
    for case in ["train_01", "train_04"] {
        let to = dir.path().join("cases").join(case);
        std::fs::create_dir_all(&to).unwrap();
        for e in std::fs::read_dir(training(case)).unwrap().flatten() {
            let name = e.file_name();
            if name != "truth.json" {
                std::fs::copy(e.path(), to.join(name)).unwrap();
            }
        }
    }
    std::fs::create_dir_all(dir.path().join("cases/broken")).unwrap();
    std::fs::write(dir.path().join("cases/broken/case.json"), "{ not json").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(["diagnose", "--batch", "cases/*/case.json", "-o", "batch"])
        .current_dir(dir.path())
        .env("NO_COLOR", "1")
        .output()
        .unwrap();
    let shown = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert_eq!(o.status.code(), Some(1), "one case is broken:\n{shown}");
    let out = dir.path().join("batch");
    let csv = std::fs::read(out.join("summary.csv")).unwrap();
    let blocks = spindlelab::engine::formats::csv::read_tables(&csv, "summary.csv").unwrap();
    let t = &blocks[0].table;
    let col = |name: &str| t.columns.iter().find(|c| c.name == name).unwrap_or_else(|| panic!("no {name}"));
    let words = |name: &str| -> Vec<String> {
        let c = col(name);
        c.values.iter().map(|&v| c.levels[v as usize].clone()).collect()
    };
    assert_eq!(words("case"), ["broken", "train_01", "train_04"]);
    assert_eq!(words("verdict")[0], "failed");
    assert!(!words("error")[0].is_empty());
    for (i, case) in [(1, "train_01"), (2, "train_04")] {
        assert_eq!(words("verdict")[i], "effects", "{case}:\n{shown}");
        assert!(col("gap_after").values[i] < col("gap_before").values[i], "{case}: the gap shrinks");
        assert!(out.join(case).join("diagnosis/diagnosis.md").is_file());
        assert!(out.join(case).join("recipe.yaml").is_file());
    }
    assert!(words("effects")[2].contains("mass_loading"), "{:?}", words("effects"));
    let md = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(md.contains("[train_04](train_04/diagnosis/diagnosis.md)"), "{md}");
    // `report` makes the batch one page: the summary, each case's diagnosis and its pictures.
    let page = dir.path().join("batch.html");
    let o = spindlelab(&["report".as_ref(), out.as_os_str(), "-o".as_ref(), page.as_os_str()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = std::fs::read_to_string(&page).unwrap();
    for needle in ["href=\"#case-train_01\"", "<section id=\"case-train_04\">", "id=\"train_04-fig-lobes.svg\""] {
        assert!(html.contains(needle), "{needle} not in the page");
    }
}
