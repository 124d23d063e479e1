//! `spindlelab import case.json`: the recipe written for a baseline case states the case's
//! numbers exactly, compiles beside the case's data, and reproduces the truth simulator's
//! baseline (FRF gaps and misclassified trials from `truth.json`).

use crate::common;

use serde_json::Value as Json;
use spindlelab::engine::exec::RunOptions;
use spindlelab::engine::value::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data")
}

/// Imports `case` with the binary into a fresh folder holding `files` from `from`.
fn import(case: &Path, from: &Path, files: &[&str]) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    for f in files {
        std::fs::copy(from.join(f), dir.path().join(f)).unwrap();
    }
    let recipe = dir.path().join("recipe.yaml");
    let out = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(["import".as_ref(), case.as_os_str(), "-o".as_ref(), recipe.as_os_str()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    (dir, recipe)
}

fn compile(recipe: &Path) -> spindlelab::engine::Compiled {
    spindlelab::engine::compile_file(recipe, &spindlelab::registry()).unwrap_or_else(|e| panic!("{}", e.render(false)))
}

#[test]
fn an_imported_case_states_every_number_of_the_case() {
    let case_path = data().join("train_07-case.json");
    let case: Json = serde_json::from_str(&std::fs::read_to_string(&case_path).unwrap()).unwrap();
    let (_dir, recipe) =
        import(&case_path, &data().join("train-07"), &["frf_x_0rpm.csv", "frf_y_0rpm.csv", "trials.csv"]);
    let text = std::fs::read_to_string(&recipe).unwrap();
    assert!(text.starts_with("# Baseline model of case train_07"), "a recipe a person reads:\n{text}");
    let c = compile(&recipe);
    let names = common::case::CaseNames {
        assembly: "holder_tool",
        machine: "test_spindle",
        sensor: "sensor",
        cutting: "trials",
    };
    common::case::assert_baseline_matches(&c.recipe, &case, &names);
    // The spindle material has no Poisson's ratio in the case, and needs none.
    assert!(c.recipe.materials["spindle_steel"].poisson.is_nan());
}

/// Validation against the truth simulator on train_02: the imported baseline misclassifies
/// 16 of the 39 trials (`truth.json`: misclassified_before) and its measured configuration
/// is 0.9937 / 1.03 (rel_l2) from the two FRFs.
#[test]
fn an_imported_case_reproduces_the_truth_simulators_baseline() {
    let dir = data().join("train-02");
    let (tmp, recipe) = import(&dir.join("case.json"), &dir, &["frf_x_0rpm.csv", "frf_y_0rpm.csv", "trials.csv"]);
    let c = compile(&recipe);
    let registry = spindlelab::registry();
    let mut opts = RunOptions::new(tmp.path().join("out")).with_renderer(spindlelab::renderer());
    opts.use_cache = false;
    let report = spindlelab::engine::run(&c, &registry, &opts, &|_, _| {}).unwrap_or_else(|e| panic!("{e}"));
    let truth: Json = serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    let out = |step: &str, k: usize, port: &str| {
        report.result.outcomes[c.graph.by_step[step][k]].outputs().unwrap()[port].clone()
    };
    let Value::Scalar(score) = out("trials", 0, "score").as_ref().clone() else { panic!() };
    let n = truth["gap"]["trials"]["n"].as_f64().unwrap();
    let wrong = truth["gap"]["trials"]["misclassified_before"].as_f64().unwrap();
    assert!(((1.0 - score.value) * n - wrong).abs() < 1e-9, "score {}", score.value);
    for (k, file) in truth["gap"]["frf_files"].as_array().unwrap().iter().enumerate() {
        let (Value::Frf(model), Value::Frf(measured)) =
            (out("measured_model", k, "frf").as_ref().clone(), out("tool_tip", k, "frf").as_ref().clone())
        else {
            panic!()
        };
        assert_eq!(model.direction.as_deref(), file["direction"].as_str());
        let num: f64 = model.values.iter().zip(&measured.values).map(|(a, b)| (a - b).norm_sqr()).sum();
        let den: f64 = measured.values.iter().map(|b| b.norm_sqr()).sum();
        let want = file["rel_l2_before"].as_f64().unwrap();
        assert!(((num / den).sqrt() / want - 1.0).abs() < 2e-3, "{k}: {} vs {want}", (num / den).sqrt());
    }
}

#[test]
fn a_file_that_is_not_a_case_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("case.json");
    std::fs::write(&bad, r#"{"materials": {}, "holder_tool": {"sections": []}}"#).unwrap();
    let out =
        Command::new(env!("CARGO_BIN_EXE_spindlelab")).args(["import".as_ref(), bad.as_os_str()]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("case.json: not a case file: missing field `holder_spindle_interface`"), "{err}");
}

#[test]
fn poisson_s_ratio_is_asked_for_where_a_timoshenko_section_needs_it() {
    let text = common::rejected("no-poisson.yaml", false);
    common::assert_has(
        &text,
        &[
            "material `steel` has no `nu`, which the Timoshenko sections of assembly `rod` need for their shear stiffness",
            "no-poisson.yaml:5:10",
            "add Poisson's ratio, e.g. `nu: 0.29` for steel",
        ],
    );
}

/// Strings that try to change the structure of the recipe they are written into (line
/// breaks, quotes, YAML's indicators and tags, a parameter reference) or the terminal of
/// whoever reads a message quoting them.
fn hostile_strings() -> Vec<String> {
    let mut s: Vec<String> = [
        "x\noutputs:\n  - { from: \"@gap.gap\", file: stolen.csv }",
        "x\"\noutputs: []\n# ",
        "x'\n  extra: 1",
        "it's \"quoted\"",
        "a # comment",
        "key: value",
        "{ a: 1 }",
        "[a, b]",
        "&anchor x",
        "*alias",
        "!!binary aGk=",
        "%YAML 1.2",
        "@gap.gap",
        "$kt",
        "tab\there",
        "nul\0byte",
        "ünïcödé ✓ 中文 🚀",
        "\u{1b}[31mred\u{1b}[0m\u{1b}]0;title\u{7}",
        "\r\nkey: v",
        "\u{85}\u{2028}\u{2029}\u{feff}\u{202e}\u{7f}\u{9b}",
        "",
        "  spaced  ",
        "true",
        "null",
        "~",
        "123",
        "-",
        "---\n...",
        "back\\slash \\n \\",
        "| >",
        "- item",
        "? q",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    s.push("x".repeat(5000));
    s
}

/// Every string of a case file, by JSON pointer: the map keys that name things (materials,
/// spindle directions) as `…/{key}` entries, and every string value.
fn string_fields(v: &Json, at: &str, out: &mut Vec<String>) {
    match v {
        Json::String(_) => out.push(at.to_string()),
        Json::Array(items) => {
            for (i, it) in items.iter().enumerate() {
                string_fields(it, &format!("{at}/{i}"), out);
            }
        }
        Json::Object(m) => {
            for (k, it) in m {
                if at == "/materials" || at == "/spindle/modes" {
                    out.push(format!("{at}/{{{k}}}"));
                }
                string_fields(it, &format!("{at}/{k}"), out);
            }
        }
        _ => {}
    }
}

/// Where the recipe states a string field of the case (a path of keys and list indices), or
/// `None` for a string the recipe does not carry (a note of the case, or a value it only
/// checks). `{new}` stands for the string itself, where it is a key.
fn stated_at(field: &str) -> Option<Vec<String>> {
    let p: Vec<&str> = field.trim_start_matches('/').split('/').collect();
    let v = |xs: &[&str]| Some(xs.iter().map(|s| s.to_string()).collect());
    match p[..] {
        ["case_id"] => v(&["name"]),
        ["materials", _] => v(&["materials", "{new}"]),
        ["holder_tool", "sections", i, f] => {
            let key = match f {
                "outer_material" => "outer",
                "inner_material" => "inner",
                "name" | "component" | "kind" => f,
                _ => return None,
            };
            v(&["assemblies", "holder_tool", "sections", i, key])
        }
        ["sensor", "type"] => v(&["sensors", "sensor", "kind"]),
        ["sensor", "location"] => v(&["sensors", "sensor", "location"]),
        ["cutting", "milling"] => v(&["cutting", "trials", "milling"]),
        ["cutting", "workpiece_material"] => v(&["cutting", "trials", "workpiece"]),
        ["measurements", "frf", i, "file"] => v(&["measurements", "tool_tip", "files", i]),
        ["measurements", "frf", _, "units"] => v(&["measurements", "tool_tip", "units"]),
        ["measurements", "trials"] => v(&["steps", "trials", "params", "file"]),
        _ => None,
    }
}

/// The case with `field` set to `s`: a key renamed (and every use of the old name with it),
/// or a value replaced; the FRF units all at once, since the recipe states them once.
fn with_field(case: &Json, field: &str, s: &str) -> Json {
    let mut c = case.clone();
    if let Some((map, key)) = field.rsplit_once("/{") {
        let key = key.trim_end_matches('}');
        let m = c.pointer_mut(map).and_then(Json::as_object_mut).unwrap();
        let v = m.remove(key).unwrap();
        m.insert(s.to_string(), v);
        if map == "/materials" {
            for sec in c["holder_tool"]["sections"].as_array_mut().unwrap() {
                for k in ["outer_material", "inner_material"] {
                    if sec[k] == Json::String(key.into()) {
                        sec[k] = Json::String(s.into());
                    }
                }
            }
        }
        return c;
    }
    if field.starts_with("/measurements/frf/") && field.ends_with("/units") {
        for f in c["measurements"]["frf"].as_array_mut().unwrap() {
            f["units"] = Json::String(s.into());
        }
        return c;
    }
    *c.pointer_mut(field).unwrap() = Json::String(s.into());
    c
}

fn raw_at<'a>(
    raw: &'a spindlelab::engine::syntax::Raw,
    path: &[String],
) -> Option<&'a spindlelab::engine::syntax::Raw> {
    use spindlelab::engine::syntax::RawKind;
    path.iter().try_fold(raw, |r, k| match &r.kind {
        RawKind::Map(m) => m.iter().find(|(key, _)| &key.name == k).map(|(_, v)| v),
        RawKind::Seq(items) => items.get(k.parse::<usize>().ok()?),
        _ => None,
    })
}

/// Every key and list index of a raw tree, as paths: the recipe's structure without its values.
fn shape(raw: &spindlelab::engine::syntax::Raw, at: &str, out: &mut Vec<String>) {
    use spindlelab::engine::syntax::RawKind;
    match &raw.kind {
        RawKind::Map(m) => {
            for (k, v) in m {
                let p = format!("{at}/{}", k.name);
                out.push(p.clone());
                shape(v, &p, out);
            }
        }
        RawKind::Seq(items) => {
            for (i, v) in items.iter().enumerate() {
                let p = format!("{at}/{i}");
                out.push(p.clone());
                shape(v, &p, out);
            }
        }
        _ => {}
    }
}

fn parse_yaml(path: &Path, what: &str) -> spindlelab::engine::syntax::Raw {
    use spindlelab::engine::diag::{Diagnostics, SourceFile};
    let text = std::fs::read_to_string(path).unwrap();
    let file = SourceFile { path: path.display().to_string().into(), text: text.into() };
    let mut d = Diagnostics::new();
    spindlelab::engine::syntax::load_yaml(&file, &mut d)
        .unwrap_or_else(|| panic!("{what}: not YAML: {d}\n{}", file.text))
}

/// For every string field of a case and every hostile string, the import either refuses
/// the case with an error that names the field (escaped, on one line) or writes a recipe
/// that compiles, states the string exactly where it belongs and has the shape of the
/// recipe of the unaltered case: no key, output or step more or less.
#[test]
fn no_string_of_a_case_can_change_the_structure_of_its_recipe() {
    let case_path = data().join("train_07-case.json");
    let case: Json = serde_json::from_str(&std::fs::read_to_string(&case_path).unwrap()).unwrap();
    let files = ["frf_x_0rpm.csv", "frf_y_0rpm.csv", "trials.csv"];
    let registry = spindlelab::registry();
    let mut fields = Vec::new();
    string_fields(&case, "", &mut fields);
    assert!(fields.len() >= 35, "the case holds its strings: {fields:?}");

    let base_dir = tempfile::tempdir().unwrap();
    for f in files {
        std::fs::copy(data().join("train-07").join(f), base_dir.path().join(f)).unwrap();
    }
    let base_text = spindlelab::import::recipe_from_case(&case.to_string(), "case.json").unwrap();
    std::fs::write(base_dir.path().join("recipe.yaml"), &base_text).unwrap();
    let base_raw = parse_yaml(&base_dir.path().join("recipe.yaml"), "the case");
    let base = compile(&base_dir.path().join("recipe.yaml"));
    let base_steps: Vec<String> = base.recipe.steps.iter().map(|s| s.id.clone()).collect();
    let outputs = |c: &spindlelab::engine::Compiled| -> Vec<(String, String)> {
        c.recipe.outputs.iter().map(|o| (o.from.step.clone(), o.file.clone())).collect()
    };
    let base_outputs = outputs(&base);
    assert_eq!(base_outputs.len(), 5, "gap table, model over measurement, lobes with trials, verdicts, lobes table");
    let mut base_shape = Vec::new();
    shape(&base_raw, "", &mut base_shape);

    let (mut accepted, mut refused) = (0, 0);
    for field in &fields {
        let original = match field.rsplit_once("/{") {
            Some((_, k)) => k.trim_end_matches('}').to_string(),
            None => case.pointer(field).and_then(Json::as_str).unwrap().to_string(),
        };
        for s in hostile_strings() {
            let what = format!("{field} = {s:?}");
            let dir = tempfile::tempdir().unwrap();
            for f in files {
                std::fs::copy(data().join("train-07").join(f), dir.path().join(f)).unwrap();
            }
            // A data file under the hostile name, where a file system takes it.
            if original.ends_with(".csv") && !s.contains('/') && !s.contains('\0') && !s.trim().is_empty() {
                let _ = std::fs::copy(data().join("train-07").join(&original), dir.path().join(&s));
            }
            let json = with_field(&case, field, &s).to_string();
            let text = match spindlelab::import::recipe_from_case(&json, "case.json") {
                Err(e) => {
                    let m = e.to_string();
                    assert!(!m.chars().any(char::is_control), "{what}: the message quotes it raw: {m:?}");
                    assert!(m.starts_with("case.json: "), "{what}: {m}");
                    let name = field.rsplit('/').find(|p| p.parse::<usize>().is_err()).unwrap();
                    let name = if name.starts_with('{') { field.split('/').nth(1).unwrap() } else { name };
                    let name = match name {
                        "materials" => "material",
                        "modes" => "spindle modes",
                        "type" => "sensor.type",
                        n => n,
                    };
                    assert!(m.contains(name), "{what}: the message names the field (`{name}`): {m}");
                    refused += 1;
                    continue;
                }
                Ok(t) => t,
            };
            accepted += 1;
            let recipe = dir.path().join("recipe.yaml");
            std::fs::write(&recipe, &text).unwrap();
            let raw = parse_yaml(&recipe, &what);
            let mut got_shape = Vec::new();
            shape(&raw, "", &mut got_shape);
            match stated_at(field) {
                Some(path) => {
                    let path: Vec<String> =
                        path.into_iter().map(|p| if p == "{new}" { s.clone() } else { p }).collect();
                    let v = raw_at(&raw, &path).unwrap_or_else(|| panic!("{what}: nothing at {path:?}:\n{text}"));
                    if path.last().is_none_or(|p| p != &s) {
                        assert_eq!(v.as_str(), Some(s.as_str()), "{what}: the recipe states another value:\n{text}");
                    }
                    let mut renamed: Vec<String> = base_shape
                        .iter()
                        .map(|p| match p.strip_prefix(&format!("/materials/{original}")) {
                            Some(rest) if field.starts_with("/materials/") => format!("/materials/{s}{rest}"),
                            _ => p.clone(),
                        })
                        .collect();
                    renamed.sort();
                    got_shape.sort();
                    assert_eq!(got_shape, renamed, "{what}: the recipe's shape changed:\n{text}");
                }
                None => assert_eq!(text, base_text, "{what}: a string the recipe does not state changed it"),
            }
            let c = spindlelab::engine::compile_file(&recipe, &registry)
                .unwrap_or_else(|e| panic!("{what}: the recipe does not compile:\n{}\n{text}", e.render(false)));
            assert_eq!(outputs(&c), base_outputs, "{what}: the outputs changed");
            let steps: Vec<String> = c.recipe.steps.iter().map(|s| s.id.clone()).collect();
            assert_eq!(steps, base_steps, "{what}");
        }
    }
    // Free text (the case's name, a section's name, the sensor's place, the workpiece) takes
    // any string but a `$` reference, so both outcomes are exercised.
    assert!(accepted > 100 && refused > 100, "{accepted} accepted, {refused} refused");
}

/// Runs the binary with `args` in `dir`; exit code, stdout, stderr.
fn spindlelab_in(dir: &Path, args: &[&str]) -> (Option<i32>, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(args)
        .current_dir(dir)
        .env("NO_COLOR", "1")
        .env_remove("RUST_BACKTRACE")
        .output()
        .unwrap();
    (o.status.code(), String::from_utf8_lossy(&o.stdout).into(), String::from_utf8_lossy(&o.stderr).into())
}

/// Through the command line: a case name that breaks lines to add an output gives a recipe
/// that `check` passes with only the import's own outputs, and a value the recipe cannot take (with escape
/// sequences and a line break in it) is refused with exit code 2 on one escaped line.
#[test]
fn the_import_command_writes_hostile_names_as_text_and_refuses_what_a_recipe_cannot_take() {
    let case_path = data().join("train_07-case.json");
    let case: Json = serde_json::from_str(&std::fs::read_to_string(&case_path).unwrap()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for f in ["frf_x_0rpm.csv", "frf_y_0rpm.csv", "trials.csv"] {
        std::fs::copy(data().join("train-07").join(f), dir.path().join(f)).unwrap();
    }
    let id = "train_07\noutputs:\n  - { from: \"@gap.gap\", file: stolen.csv }";
    std::fs::write(dir.path().join("case.json"), with_field(&case, "/case_id", id).to_string()).unwrap();
    let (code, _, err) = spindlelab_in(dir.path(), &["import", "case.json", "-o", "recipe.yaml"]);
    assert_eq!(code, Some(0), "{err}");
    let (code, out, err) = spindlelab_in(dir.path(), &["check", "recipe.yaml"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains(", 5 outputs"), "{out}");
    let c = compile(&dir.path().join("recipe.yaml"));
    assert_eq!(c.recipe.name, id);

    let milling = "\u{1b}[2K\rdown\nerror: forged";
    std::fs::write(dir.path().join("bad.json"), with_field(&case, "/cutting/milling", milling).to_string()).unwrap();
    let (code, out, err) = spindlelab_in(dir.path(), &["import", "bad.json"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(out.is_empty(), "{out}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(!err.trim_end().chars().any(char::is_control), "{err:?}");
    assert!(
        err.contains(
            "bad.json: `cutting.milling` is \"\\e[2K\\rdown\\nerror: forged\", but a recipe takes one of up | down"
        ),
        "{err}"
    );

    // A speed no spindle has is refused by its field, the number short.
    let mut fast = case.clone();
    *fast.pointer_mut("/measurements/frf/0/speed_rpm").unwrap() = serde_json::json!(-1e308);
    std::fs::write(dir.path().join("fast.json"), fast.to_string()).unwrap();
    let (code, _, err) = spindlelab_in(dir.path(), &["import", "fast.json"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("`measurements.frf[0].speed_rpm` is -1e308 rpm"), "{err}");
    assert!(err.len() < 300, "{err}");

    // Files in two units are not one measurement set: refused, not read in the first's unit.
    let mut mixed = case.clone();
    *mixed.pointer_mut("/measurements/frf/1/units").unwrap() = serde_json::json!("m/s^2/N");
    std::fs::write(dir.path().join("mixed.json"), mixed.to_string()).unwrap();
    let (code, _, err) = spindlelab_in(dir.path(), &["import", "mixed.json"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("`measurements.frf[1].units` is \"m/s^2/N\" where `measurements.frf[0].units` is \"m/N\""),
        "{err}"
    );
}

/// `--library` writes the case's entities to a library and a recipe that uses it: the two
/// compile to the same entities and the same graph, key for key, as the one-file recipe,
/// whatever the library's name holds (quotes, `#`, spaces).
#[test]
fn an_imported_case_as_a_library_and_a_recipe_compiles_to_the_same_graph() {
    let dir = tempfile::tempdir().unwrap();
    for f in ["frf_x_0rpm.csv", "frf_y_0rpm.csv", "trials.csv"] {
        std::fs::copy(data().join("train-07").join(f), dir.path().join(f)).unwrap();
    }
    std::fs::copy(data().join("train_07-case.json"), dir.path().join("case.json")).unwrap();
    std::fs::create_dir(dir.path().join("lib")).unwrap();
    let lib = "lib/it's \"train\" #7.yaml";
    let (code, _, err) = spindlelab_in(dir.path(), &["import", "case.json", "-o", "split.yaml", "--library", lib]);
    assert_eq!(code, Some(0), "{err}");
    let (code, _, err) = spindlelab_in(dir.path(), &["import", "case.json", "-o", "whole.yaml"]);
    assert_eq!(code, Some(0), "{err}");
    let library = std::fs::read_to_string(dir.path().join(lib)).unwrap();
    assert!(library.contains("assemblies:") && !library.contains("steps:"), "{library}");
    let (code, out, err) = spindlelab_in(dir.path(), &["check", lib]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("ok — library of"), "{out}");
    let split = compile(&dir.path().join("split.yaml"));
    let whole = compile(&dir.path().join("whole.yaml"));
    assert_eq!(split.recipe.entity_digests, whole.recipe.entity_digests);
    let keys = |c: &spindlelab::engine::Compiled| -> Vec<(String, String)> {
        c.graph.instances.iter().map(|i| (i.id.clone(), i.key.clone())).collect()
    };
    assert_eq!(keys(&split), keys(&whole));
    assert!(split.used_files().keys().any(|f| f.ends_with("#7.yaml")), "{:?}", split.used_files());
}
