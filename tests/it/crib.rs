//! The tool-crib catalog and `spindlelab crib` (docs/crib.md): the shipped catalog reads and
//! pairs ≥ 200 combinations; the emitted recipe compiles and its assemblies are the catalog's
//! geometry; one combination's tool-point FRF equals the same combination written by hand;
//! bad catalogs are refused at their file, line and column with exit code 2.

use crate::common::binary::{run_in, text};
use spindlelab::crib::{self, Loaded, MachineRef};
use spindlelab::engine::{self, domain::entity::Component, exec, exec::RunOptions, value::Value};
use std::path::{Path, PathBuf};

fn scripts() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts")
}

fn catalog_path() -> PathBuf {
    scripts().join("catalog/tool-crib.yaml")
}

fn machine_path() -> PathBuf {
    scripts().join("lib/mill.yaml")
}

fn shipped() -> (MachineRef, Loaded) {
    let registry = spindlelab::registry();
    let machine = crib::machine(&machine_path(), None, &registry).unwrap_or_else(|e| panic!("{}", e.render(false)));
    let loaded = crib::load(&catalog_path(), &machine, &registry).unwrap_or_else(|e| panic!("{}", e.render(false)));
    (machine, loaded)
}

/// The survey's recipe emitted into `dir` and compiled from the file, as `run` would.
fn emitted(dir: &Path) -> (crib::Survey, Loaded, engine::Compiled) {
    let (machine, loaded) = shipped();
    let survey = crib::build(&loaded, &machine, dir);
    let path = dir.join("survey.yaml");
    std::fs::write(&path, crib::emit(&loaded, &machine, &survey)).unwrap();
    let compiled = engine::compile_file(&path, &spindlelab::registry())
        .unwrap_or_else(|e| panic!("the emitted recipe does not compile:\n{}", e.render(false)));
    (survey, loaded, compiled)
}

#[test]
fn the_shipped_catalog_reads_and_pairs_at_least_200_combinations() {
    let (machine, loaded) = shipped();
    assert_eq!(machine.name, "mill");
    let c = &loaded.catalog;
    assert_eq!((c.holders.len(), c.tools.len()), (7, 6));
    let combos = c.combinations();
    assert_eq!(combos.len(), 4 * 6 * 9, "HSK-A63 holders × end mills × stickouts");
    // Only the machine's interface; every holder and tool states its source.
    assert!(combos.iter().all(|k| c.holders[k.holder].interface == "HSK-A63"));
    assert!(c.holders.iter().all(|h| !h.source.is_empty()) && c.tools.iter().all(|t| t.source.contains("DIN 6527")));
    // Quantities are SI: the ER32 chuck takes 2–20 mm shanks; 86 % of 12 mm.
    let er32 = c.holders.iter().find(|h| h.id == "hsk63_er32_100").unwrap();
    assert_eq!((er32.bores[0].d_min, er32.bores[0].d_max), (0.002, 0.02));
    let em12 = c.tools.iter().find(|t| t.id == "em12").unwrap();
    assert!((em12.d_equivalent - 0.01032).abs() < 1e-15);
    assert_eq!(em12.stickout.len(), 9);
}

#[test]
fn the_emitted_recipe_compiles_and_holds_the_catalog_geometry() {
    let dir = tempfile::tempdir().unwrap();
    let (survey, loaded, compiled) = emitted(dir.path());
    let c = &loaded.catalog;
    assert_eq!(compiled.recipe.assemblies.len(), survey.assemblies.len());
    // Per tool: two couplings, lobes and best; and the two spindle steps.
    assert_eq!(compiled.recipe.steps.len(), 2 + 4 * 6);
    assert_eq!(compiled.graph.instances.len(), 2 + 4 * 216);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1e-3);
    for (name, k) in &survey.assemblies {
        let (h, t) = (&c.holders[k.holder], &c.tools[k.tool]);
        let bore = h.bore_for(t.shank).unwrap();
        let sections = &compiled.recipe.assemblies[name].sections;
        let length =
            |f: &dyn Fn(&Component) -> bool| sections.iter().filter(|s| f(&s.component)).map(|s| s.length).sum::<f64>();
        // The holder reaches the gauge length, the tool sticks out by the stickout.
        assert!(close(length(&|c| *c != Component::Tool), h.gauge_length), "{name}");
        assert!(close(length(&|c| *c == Component::Tool), k.stickout), "{name}");
        // The body as written, then a nose from its diameter at the body to its face's.
        for (s, b) in sections.iter().zip(&h.sections) {
            assert!(close(s.d_out_spindle_end, b.d_out) && close(s.length, b.length), "{name}: {}", s.name);
        }
        let nose: Vec<_> = sections[h.sections.len()..].iter().filter(|s| s.component != Component::Tool).collect();
        assert!(close(nose[0].d_out_spindle_end, bore.d_out), "{name}");
        assert!(close(nose.last().unwrap().d_out_tip_end, bore.d_out_tip), "{name}");
        assert!(nose.iter().all(|s| close(s.d_in, t.shank)), "{name}");
        // The shank is clamped as deep as the holder and the tool's length allow.
        let clamp = nose.last().unwrap();
        assert_eq!(clamp.component, Component::HolderAndTool);
        assert!(close(clamp.length, bore.clamp_length.min(t.overall_length - k.stickout)), "{name}");
        assert!(clamp.inner.is_some());
        // The flutes: the tool's diameter, its equivalent diameter, its flute length.
        let flutes = sections.last().unwrap();
        assert!(flutes.fluted && close(flutes.d_out_spindle_end, t.diameter));
        assert!(close(flutes.d_equivalent.unwrap(), t.d_equivalent));
        assert!(close(flutes.length, t.flute_length.min(k.stickout)), "{name}");
    }
}

#[test]
fn emitting_twice_gives_the_same_text() {
    let (machine, loaded) = shipped();
    let dir = tempfile::tempdir().unwrap();
    let a = crib::emit(&loaded, &machine, &crib::build(&loaded, &machine, dir.path()));
    let b = crib::emit(&loaded, &machine, &crib::build(&loaded, &machine, dir.path()));
    assert_eq!(a, b);
}

/// The ER32 chuck with the 12 mm end mill at 41 mm, written by hand from the catalog: a 26 mm
/// flange of 63 mm, a 74 mm nose of 50 mm whose last 40 mm hold the shank, 15 mm of free
/// shank and 26 mm of flutes (equivalent diameter 86 % of 12 mm).
const BY_HAND: &str = r#"
spindlelab: 1
name: by-hand
use: [LIB/materials.yaml, LIB/mill.yaml]
assemblies:
  hand:
    sections:
      - { name: flange, component: holder, d_out: 63 mm, length: 26 mm, outer: steel }
      - { name: nose, component: holder, d_out: 50 mm, d_in: 12 mm, length: 34 mm, outer: steel }
      - { name: clamp, component: holder+tool, d_out: 50 mm, d_in: 12 mm, length: 40 mm, outer: steel, inner: carbide }
      - { name: shank, component: tool, d_out: 12 mm, length: 15 mm, outer: carbide }
      - { name: flutes, component: tool, kind: fluted, d_out: 12 mm, d_equivalent: 10.32 mm, length: 26 mm, outer: carbide }
steps:
  spindle: { kind: spindle.receptance, params: { machine: mill, direction: x, max_frequency: 12 kHz, resolution: 2.5 Hz } }
  tip:
    kind: rcsa.couple
    params: { interface: machine, machine: mill, max_element: 4 mm, assembly: hand }
    inputs: { spindle: "@spindle.receptance" }
"#;

#[test]
fn a_combination_s_tool_point_frf_equals_the_same_written_by_hand() {
    let dir = tempfile::tempdir().unwrap();
    let (_, _, compiled) = emitted(dir.path());
    let registry = spindlelab::registry();
    let mut opts = RunOptions::new(dir.path().join("out"));
    opts.use_cache = false;
    opts.targets = Some(vec!["tip_x_em12".into()]);
    let result = exec::execute(&compiled.recipe, &compiled.graph, &registry, &opts, &|_, _| {});
    let i = compiled.graph.by_step["tip_x_em12"]
        .iter()
        .copied()
        .find(|&i| compiled.graph.instances[i].label.contains("hsk63_er32_100_em12_41mm"))
        .expect("the combination is in the survey");
    let frf = |v: &Value| match v {
        Value::Frf(f) => f.clone(),
        other => panic!("{:?}", other.port_type()),
    };
    let survey = frf(&result.outcomes[i].outputs().expect("coupled")["frf"]);

    let hand = dir.path().join("by-hand.yaml");
    std::fs::write(&hand, BY_HAND.replace("LIB", &scripts().join("lib").display().to_string())).unwrap();
    let ran = crate::common::run(&hand);
    let by_hand = frf(&ran.value("tip", "frf"));
    assert_eq!(survey.freq_hz, by_hand.freq_hz);
    let peak = by_hand.values.iter().map(|v| v.norm()).fold(0.0, f64::max);
    let worst = survey.values.iter().zip(&by_hand.values).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(worst <= 1e-9 * peak, "largest difference {worst:e} of a {peak:e} m/N peak");
}

/// The shipped catalog with `edit` applied, beside the libraries it names (by absolute path).
fn bad_catalog(dir: &Path, edit: impl Fn(String) -> String) -> (PathBuf, String) {
    let text = std::fs::read_to_string(catalog_path()).unwrap();
    let lib = scripts().join("lib/materials.yaml");
    let text = edit(text.replace("use: [../lib/materials.yaml]", &format!("use: [\"{}\"]", lib.display())));
    let path = dir.join("bad.yaml");
    std::fs::write(&path, &text).unwrap();
    (path, text)
}

/// The 1-based line of the first line of `text` that contains `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap_or_else(|| panic!("no `{needle}`")) + 1
}

/// Runs `crib` on a bad catalog; it must fail with exit code 2 naming `file:line:` and `message`.
fn refused(edit: impl Fn(String) -> String, marker: &str, message: &str) {
    let dir = tempfile::tempdir().unwrap();
    let (path, written) = bad_catalog(dir.path(), edit);
    let machine = machine_path();
    let o = run_in(dir.path(), &["crib", path.to_str().unwrap(), "--machine", machine.to_str().unwrap(), "-o", "out"]);
    crate::common::binary::no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let stderr = String::from_utf8_lossy(&o.stderr);
    let at = format!("{}:{}:", path.display(), line_of(&written, marker));
    assert!(stderr.contains(&at), "expected `{at}` in:\n{stderr}");
    assert!(stderr.contains(message), "expected `{message}` in:\n{stderr}");
    assert!(!dir.path().join("out").exists(), "nothing is written for a bad catalog");
}

#[test]
fn an_unknown_field_is_refused_where_it_is() {
    refused(
        |t| t.replacen("    teeth: 3\n", "    teeth: 3\n    colour: red\n", 1),
        "colour: red",
        "unknown field `colour`",
    );
}

#[test]
fn a_quantity_without_unit_is_refused_where_it_is() {
    refused(|t| t.replacen("gauge_length: 80 mm", "gauge_length: 80", 1), "gauge_length: 80", "has no unit");
}

#[test]
fn an_empty_stickout_range_is_refused_where_it_is() {
    refused(
        |t| t.replacen("stickout: 35..59 step 3 mm", "stickout: 59..35 step 3 mm", 1),
        "stickout: 59..35",
        "is empty",
    );
}

#[test]
fn a_shank_too_big_for_the_holder_is_refused_where_it_is_named() {
    // The HSK-E40 chuck's bores end at 12 mm; pairing it with the 20 mm end mill is refused.
    refused(
        |t| t.replacen("    interface: HSK-E40\n", "    interface: HSK-E40\n    tools: [em06, em20]\n", 1),
        "tools: [em06, em20]",
        "too big for its bore",
    );
}

#[test]
fn emit_writes_a_recipe_that_checks_and_a_machine_recipe_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (catalog, machine) = (catalog_path(), machine_path());
    let o = run_in(
        dir.path(),
        &["crib", catalog.to_str().unwrap(), "--machine", machine.to_str().unwrap(), "--emit", "survey.yaml"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("216 combinations"), "{}", text(&o));
    let o = run_in(dir.path(), &["check", "survey.yaml"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(!dir.path().join("out").exists(), "--emit runs nothing");
    // A recipe is not a library of machines.
    let recipe = scripts().join("rcsa-tool-point.yaml");
    let o = run_in(dir.path(), &["crib", catalog.to_str().unwrap(), "--machine", recipe.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("is a recipe"), "{}", text(&o));
}

#[test]
fn the_survey_runs_and_writes_one_table_of_the_best_cuts() {
    let dir = tempfile::tempdir().unwrap();
    let (catalog, machine) = (catalog_path(), machine_path());
    let o =
        run_in(dir.path(), &["crib", catalog.to_str().unwrap(), "--machine", machine.to_str().unwrap(), "-o", "out"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let csv = std::fs::read(dir.path().join("out").join(crib::SUMMARY_FILE)).unwrap();
    let blocks = engine::formats::csv::read_tables(&csv, crib::SUMMARY_FILE).unwrap();
    let table = &blocks[0].table;
    let col = |n: &str| table.columns.iter().find(|c| c.name == n).unwrap_or_else(|| panic!("no column {n}"));
    assert_eq!(col("depth").values.len(), 216);
    // Every combination has a stable depth and a speed in the surveyed range.
    assert!(col("depth").values.iter().all(|d| *d > 0.0 && d.is_finite()));
    assert!(col("speed").values.iter().all(|s| (4000.0..=24000.0).contains(s)));
    // The deepest stable cut is at least the depth stable at every speed; rows in catalog
    // order, stickouts rising within each holder and tool.
    let (depth, everywhere) = (&col("depth").values, &col("stable_everywhere").values);
    let (holder, tool, stick) = (col("holder"), col("tool"), &col("stickout").values);
    assert!(depth.iter().zip(everywhere).all(|(d, e)| d >= e && *e > 0.0));
    // The usable depth is the lobe's, cut at the flute length (DIN 6527 K: 13 mm for 6 mm).
    let (usable, limited) = (&col("usable_depth").values, col("limited_by"));
    for r in 0..216 {
        assert!(usable[r] <= depth[r] && usable[r] <= 38.0, "row {r}");
        let by_flutes = usable[r] < depth[r];
        assert_eq!(limited.word(r), Some(if by_flutes { "flute length" } else { "chatter" }), "row {r}");
    }
    let first_6mm = (0..216).find(|&r| tool.word(r) == Some("em06")).unwrap();
    assert!(usable[first_6mm] <= 13.0);
    for r in 1..216 {
        if holder.values[r] == holder.values[r - 1] && tool.values[r] == tool.values[r - 1] {
            assert!(stick[r] > stick[r - 1], "row {r}");
        }
    }
    assert_eq!(holder.word(0), Some("hsk63_shrink_80"));
    // The per-tool tables are written too.
    assert!(dir.path().join("out/best-cuts-em12.csv").is_file());
}
