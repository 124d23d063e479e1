//! Recipe parameters: `$name` takes the declared value, `--set` replaces it, and cache keys
//! follow values, so exactly the steps a parameter (or an entity's contents) reaches rerun.

use spindlelab::engine::{self, Compiled};
use std::path::{Path, PathBuf};
use std::process::Command;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/params").join(name)
}

fn compile(name: &str, set: &[(&str, &str)]) -> Compiled {
    let set: Vec<(String, String)> = set.iter().map(|(a, b)| (a.to_string(), b.to_string())).collect();
    engine::compile_file_with(&data(name), &set, &spindlelab::registry())
        .unwrap_or_else(|e| panic!("{}", e.render(false)))
}

fn key(c: &Compiled, step: &str) -> String {
    c.graph.instances[c.graph.by_step[step][0]].key.clone()
}

#[test]
fn a_parameter_takes_its_declared_value_where_it_is_used() {
    let c = compile("beam.yaml", &[]);
    let a = &c.recipe.assemblies["holder_tool"];
    assert_eq!(a.sections[0].d_in, 0.0127);
    assert_eq!(a.sections[2].d_out_spindle_end, 0.0127);
    assert_eq!(c.recipe.materials["steel"].youngs_modulus, 200e9);
    let q = c.recipe.params["d_shank"].quantity.as_ref().unwrap();
    assert_eq!((q.number, q.unit.as_str()), (12.7, "mm"));
}

#[test]
fn set_reruns_only_the_steps_a_parameter_reaches() {
    let base = compile("beam.yaml", &[]);
    let set = compile("beam.yaml", &[("d_shank", "12mm")]);
    assert_eq!(set.recipe.assemblies["holder_tool"].sections[2].d_out_spindle_end, 0.012);
    assert!(set.recipe.params["d_shank"].overridden);
    assert_ne!(key(&base, "holder_tool_model"), key(&set, "holder_tool_model"));
    assert_eq!(key(&base, "rod_model"), key(&set, "rod_model"));
    assert_ne!(base.recipe.hash, set.recipe.hash);
    // The same value written another way is the same key.
    assert_eq!(
        key(&base, "holder_tool_model"),
        key(&compile("beam.yaml", &[("d_shank", "0.0127 m")]), "holder_tool_model")
    );
}

#[test]
fn an_entity_edit_changes_the_key_of_every_step_that_names_it() {
    // The steel modulus is used by the holder only, through a material the assembly names.
    let base = compile("beam.yaml", &[]);
    let stiffer = compile("beam.yaml", &[("E_steel", "210 GPa")]);
    assert_ne!(key(&base, "holder_tool_model"), key(&stiffer, "holder_tool_model"));
    assert_eq!(key(&base, "rod_model"), key(&stiffer, "rod_model"));
}

fn cli(dir: &Path, args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(args)
        .current_dir(dir)
        .env("NO_COLOR", "1")
        .output()
        .expect("binary runs");
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn bad_parameters_and_fit_blocks_are_named_with_their_place() {
    let (code, err) = cli(&data(""), &["check", "bad.yaml"]);
    assert_eq!(code, 2, "{err}");
    let expect = [
        // A parameter whose unit does not fit the field is reported where it is used.
        ("bad.yaml:10:", "wrong unit for `E` of material `steel`: `2e8 N/m`"),
        ("bad.yaml:15:", "unknown parameter `$diameter`"),
        ("bad.yaml:7:", "parameter `unused` is declared but no value uses it"),
        ("bad.yaml:25:", "free parameter `kt` has no `max`: a fit needs both bounds"),
        ("bad.yaml:26:", "`min` of `ct`"),
        ("bad.yaml:27:", "`fit.free` names `mass`, which is not a declared parameter"),
        ("bad.yaml:28:", "a fit objective sums the squares of FRF lines or scalars"),
    ];
    // Each finding: its message line, then ` --> file:line:column`.
    let lines: Vec<&str> = err.lines().collect();
    let found = |at: &str, what: &str| {
        lines.windows(2).any(|w| w[0].contains(what) && w[1].trim_start().starts_with("-->") && w[1].contains(at))
    };
    for (at, what) in expect {
        assert!(found(at, what), "missing `{what}` at `{at}` in:\n{err}");
    }
    assert_eq!(err.matches("$diameter").count(), 2, "one finding for the unknown parameter:\n{err}");
}

#[test]
fn set_names_a_declared_parameter_in_its_dimension() {
    let (code, err) = cli(&data(""), &["check", "beam.yaml", "--set", "d_shnak=12mm"]);
    assert_eq!(code, 2);
    assert!(err.contains("declares no parameter `d_shnak`") && err.contains("did you mean `d_shank`?"), "{err}");
    let (code, err) = cli(&data(""), &["check", "beam.yaml", "--set", "d_shank=12 GPa"]);
    assert_eq!(code, 2);
    assert!(err.contains("`d_shank` is declared as `12.7 mm`, a length"), "{err}");
    let (code, err) = cli(&data(""), &["check", "beam.yaml", "--set", "d_shank"]);
    assert_eq!(code, 2, "{err}");
    let (code, err) = cli(&data(""), &["check", "beam.yaml", "--set", "d_shank=12 mm"]);
    assert_eq!(code, 0, "{err}");
}
