//! Engine behaviour through its public boundary: determinism across thread counts, the
//! cache and the plan, fan-out of sweeps, and atomic outputs.

use spindlelab::engine::exec::{Outcome, PlanReason, RunOptions, plan};
use spindlelab::engine::{self, Compiled};
use std::path::{Path, PathBuf};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)
}

fn compile(path: &Path) -> Compiled {
    engine::compile_file(path, &spindlelab::registry()).unwrap_or_else(|e| panic!("{}", e.render(false)))
}

fn run(c: &Compiled, out: &Path, threads: usize, cache: bool) -> engine::RunReport {
    let mut opts = RunOptions::new(out).with_renderer(spindlelab::renderer());
    opts.threads = Some(threads);
    opts.use_cache = cache;
    engine::run(c, &spindlelab::registry(), &opts, &|_, _| {}).unwrap_or_else(|e| panic!("{e}"))
}

fn outputs(r: &engine::RunReport) -> Vec<String> {
    r.result.outcomes.iter().map(|o| format!("{:?}", o.outputs().expect("every instance ran").as_ref())).collect()
}

#[test]
fn same_numbers_on_one_thread_and_on_four() {
    let c = compile(&data("noisy-sweep.yaml"));
    let a = tempfile::tempdir().unwrap();
    let b = tempfile::tempdir().unwrap();
    let one = run(&c, a.path(), 1, false);
    let four = run(&c, b.path(), 4, false);
    assert_eq!(outputs(&one), outputs(&four));
    for f in ["frf.csv", "impulse.csv"] {
        assert_eq!(std::fs::read(a.path().join(f)).unwrap(), std::fs::read(b.path().join(f)).unwrap(), "{f}");
    }
}

#[test]
fn sweep_fans_out_downstream_and_collects_where_asked() {
    let c = compile(&data("noisy-sweep.yaml"));
    let ids: Vec<&str> = c.graph.instances.iter().map(|i| i.id.as_str()).collect();
    assert_eq!(
        ids,
        [
            "hit[hammer_mass=0.02 kg]",
            "hit[hammer_mass=0.04 kg]",
            "hit[hammer_mass=0.06 kg]",
            "frf[hammer_mass=0.02 kg]",
            "frf[hammer_mass=0.04 kg]",
            "frf[hammer_mass=0.06 kg]",
            "impulse"
        ]
    );
    assert_eq!(c.graph.instances[6].inputs["values"].len(), 3);
    let dot = engine::graph::to_dot(&c.graph);
    assert!(dot.contains("cluster_hit"), "{dot}");
    let mermaid = engine::graph::to_mermaid(&c.graph);
    assert!(mermaid.contains("subgraph hit"), "{mermaid}");
}

#[test]
fn second_run_comes_from_the_cache_and_a_changed_parameter_reruns_only_its_cone() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = dir.path().join("r.yaml");
    let text = std::fs::read_to_string(data("noisy-sweep.yaml")).unwrap();
    std::fs::write(&recipe, &text).unwrap();
    let out = dir.path().join("out");
    let c = compile(&recipe);
    let first = run(&c, &out, 2, true);
    assert_eq!(first.manifest.computed, 7);
    let first_files: Vec<Vec<u8>> =
        ["frf.csv", "impulse.csv"].iter().map(|f| std::fs::read(out.join(f)).unwrap()).collect();
    let second = run(&c, &out, 2, true);
    assert_eq!(second.manifest.cache_hits, 7);
    assert_eq!(second.manifest.computed, 0);
    // What the output files read comes from the cache; the upstream `hit` instances, whose
    // consumers are all cached, are not even loaded.
    for (inst, o) in c.graph.instances.iter().zip(&second.result.outcomes) {
        match inst.step.as_str() {
            "hit" => assert!(matches!(o, Outcome::Unneeded { cached: true, .. }), "{}: {o:?}", inst.id),
            _ => assert!(matches!(o, Outcome::Cached { .. }), "{}: {o:?}", inst.id),
        }
    }
    let second_files: Vec<Vec<u8>> =
        ["frf.csv", "impulse.csv"].iter().map(|f| std::fs::read(out.join(f)).unwrap()).collect();
    assert_eq!(first_files, second_files);

    // Change one parameter of `frf`: `hit` stays cached, `frf` and nothing else reruns.
    std::fs::write(
        &recipe,
        text.replace("windows: false, trigger: record-start", "windows: false, trigger: force-peak"),
    )
    .unwrap();
    let c2 = compile(&recipe);
    let cache = RunOptions::new(&out).cache();
    let p = plan(&c2.recipe, &c2.graph, &spindlelab::registry(), &out, Some(&cache));
    for e in &p {
        match e.id.split('[').next().unwrap() {
            "frf" => assert_eq!(e.reason, PlanReason::ChangedParams(vec!["trigger".into()]), "{}", e.id),
            _ => assert_eq!(e.reason, PlanReason::Cached, "{}", e.id),
        }
    }
    let third = run(&c2, &out, 2, true);
    assert_eq!((third.manifest.computed, third.manifest.cache_hits), (3, 4));

    // Change the upstream seed: every `hit` shows a changed parameter, its consumers a changed input.
    let text2 = text.replace("windows: false, trigger: record-start", "windows: false, trigger: force-peak");
    std::fs::write(&recipe, text2.replace("seed: 11", "seed: 12")).unwrap();
    let c3 = compile(&recipe);
    for e in plan(&c3.recipe, &c3.graph, &spindlelab::registry(), &out, Some(&cache)) {
        match e.id.split('[').next().unwrap() {
            "hit" => assert_eq!(e.reason, PlanReason::ChangedParams(vec!["seed".into()])),
            "frf" => assert_eq!(e.reason, PlanReason::ChangedInputs(vec!["force".into(), "response".into()])),
            _ => assert_eq!(e.reason, PlanReason::ChangedInputs(vec!["values".into()])),
        }
    }
}

#[test]
fn a_damaged_cache_entry_is_recomputed_not_served() {
    let dir = tempfile::tempdir().unwrap();
    let c = compile(&data("noisy-sweep.yaml"));
    let first = run(&c, dir.path(), 1, true);
    // Truncate every entry, as an interrupted write would leave it without the rename.
    let cache_dir = engine::exec::cache_dir(dir.path());
    let mut damaged = 0;
    for sub in std::fs::read_dir(&cache_dir).unwrap() {
        for entry in std::fs::read_dir(sub.unwrap().path()).unwrap() {
            let p = entry.unwrap().path();
            let bytes = std::fs::read(&p).unwrap();
            std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
            damaged += 1;
        }
    }
    assert_eq!(damaged, 7);
    let second = run(&c, dir.path(), 1, true);
    assert_eq!(second.manifest.computed, 7, "damaged entries must not be served");
    assert_eq!(outputs(&first), outputs(&second));
}

#[test]
fn no_cache_neither_reads_nor_writes() {
    let dir = tempfile::tempdir().unwrap();
    let c = compile(&data("noisy-sweep.yaml"));
    run(&c, dir.path(), 1, false);
    assert!(!engine::exec::cache_dir(dir.path()).exists());
    let r = run(&c, dir.path(), 1, false);
    assert_eq!(r.manifest.computed, 7);
    assert!(r.result.outcomes.iter().all(|o| matches!(o, Outcome::Computed { .. })));
}

#[test]
fn manifest_records_the_recipe_hash_tool_version_and_every_instance() {
    let dir = tempfile::tempdir().unwrap();
    let c = compile(&data("noisy-sweep.yaml"));
    run(&c, dir.path(), 2, true);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("manifest.json")).unwrap()).unwrap();
    assert_eq!(m["recipe_hash"], c.recipe.hash.as_str());
    assert!(m["tool"].as_str().unwrap().starts_with("spindlelab "));
    assert_eq!(m["nodes"].as_array().unwrap().len(), 7);
    assert!(m["nodes"][0]["seconds"].as_f64().is_some());
    // No staging directory is left behind.
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(".staging"))
        .collect();
    assert!(leftovers.is_empty());
}

#[test]
fn the_recipe_hash_ignores_layout_and_comments() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.yaml");
    let b = dir.path().join("b.yaml");
    let text = std::fs::read_to_string(data("noisy-sweep.yaml")).unwrap();
    std::fs::write(&a, &text).unwrap();
    std::fs::write(
        &b,
        format!("# another comment\n\n{}", text.replace("hammer_stiffness: 500 N/m", "hammer_stiffness:   500 N/m")),
    )
    .unwrap();
    assert_eq!(compile(&a).recipe.hash, compile(&b).recipe.hash);
}

#[test]
fn rhai_and_yaml_recipes_that_say_the_same_compile_to_the_same_graph() {
    let dir = tempfile::tempdir().unwrap();
    let rhai = dir.path().join("same.rhai");
    std::fs::write(
        &rhai,
        r#"
        let masses = [0.02, 0.04, 0.06];
        #{
            spindlelab: 1,
            name: "noisy-sweep",
            steps: #{
                hit: #{
                    kind: "impact.simulate",
                    params: #{ hammer_stiffness: "500 N/m", target_mass: "0.1 kg", target_stiffness: "5e7 N/m",
                               target_damping: "50 N*s/m", duration: "5 ms", pre_trigger: "0.5 ms",
                               noise: "25 nm", impacts: 3, seed: 11 },
                    sweep: #{ hammer_mass: masses.map(|m| q(m, "kg")) }
                },
                frf: #{ kind: "frf.estimate", params: #{ windows: false, trigger: "record-start" },
                        inputs: #{ force: "@hit.force", response: "@hit.displacement" } },
                impulse: #{ kind: "table.collect", inputs: #{ values: "@hit.impulse_time" } },
            },
            outputs: [ #{ from: "@frf.frf", file: "frf.csv" }, #{ from: "@impulse.table", file: "impulse.csv" } ]
        }
        "#,
    )
    .unwrap();
    let from_rhai = compile(&rhai);
    let from_yaml = compile(&data("noisy-sweep.yaml"));
    // Rhai object maps keep keys sorted, so independent steps may come in another order.
    let keys = |c: &Compiled| {
        let mut k = c.graph.instances.iter().map(|i| (i.id.clone(), i.key.clone())).collect::<Vec<_>>();
        k.sort();
        k
    };
    assert_eq!(keys(&from_rhai), keys(&from_yaml));
}

#[test]
fn a_failure_writes_nothing_but_keeps_what_was_computed_and_keep_going_writes_the_rest() {
    let c = compile(&data("one-step-fails.yaml"));
    let registry = spindlelab::registry();
    let dir = tempfile::tempdir().unwrap();
    let opts = RunOptions::new(dir.path()).with_renderer(spindlelab::renderer());
    let Err(engine::RunError::NodesFailed { failures, report }) = engine::run(&c, &registry, &opts, &|_, _| {}) else {
        panic!("the run should fail");
    };
    assert_eq!(failures.len(), 1);
    assert_eq!(failures[0].0, "ratio");
    assert!(failures[0].1.contains("x / 0.0"), "{}", failures[0].1);
    assert!(report.written.is_empty());
    assert!(!dir.path().join("impulse.csv").exists() && !dir.path().join("ratio.csv").exists());
    assert_eq!(report.manifest.computed, 1, "the successful instance is kept in the cache");

    let mut opts = RunOptions::new(dir.path()).with_renderer(spindlelab::renderer());
    opts.keep_going = true;
    let Err(engine::RunError::NodesFailed { report, .. }) = engine::run(&c, &registry, &opts, &|_, _| {}) else {
        panic!("the run should still fail");
    };
    assert_eq!(report.written, ["impulse.csv"]);
    assert_eq!(report.manifest.cache_hits, 1);
    assert!(dir.path().join("impulse.csv").exists() && !dir.path().join("ratio.csv").exists());
}

#[test]
fn a_rerun_does_not_remake_uncached_recordings_whose_consumers_are_cached() {
    let dir = tempfile::tempdir().unwrap();
    let c = compile(&data("uncached-upstream.yaml"));
    let first = run(&c, dir.path(), 2, true);
    assert_eq!(first.manifest.computed, 3);
    let frf = std::fs::read(dir.path().join("frf.csv")).unwrap();
    let cache = RunOptions::new(dir.path()).cache();
    for e in plan(&c.recipe, &c.graph, &spindlelab::registry(), dir.path(), Some(&cache)) {
        let want = if e.id == "frf" { PlanReason::Cached } else { PlanReason::NotNeeded };
        assert_eq!(e.reason, want, "{}", e.id);
    }
    let second = run(&c, dir.path(), 2, true);
    assert_eq!(second.manifest.computed, 0, "nothing reruns");
    for (inst, o) in c.graph.instances.iter().zip(&second.result.outcomes) {
        match inst.step.as_str() {
            "frf" => assert!(matches!(o, Outcome::Cached { .. }), "{o:?}"),
            _ => assert!(matches!(o, Outcome::Unneeded { cached: false, .. }), "{}: {o:?}", inst.id),
        }
    }
    assert_eq!(std::fs::read(dir.path().join("frf.csv")).unwrap(), frf);
    // Without its cache entry the FRF needs its inputs again, and they are remade.
    std::fs::remove_dir_all(dir.path().join(".spindlelab-cache")).unwrap();
    let third = run(&c, dir.path(), 2, true);
    assert_eq!(third.manifest.computed, 3);
    assert_eq!(std::fs::read(dir.path().join("frf.csv")).unwrap(), frf);
}

#[test]
fn released_recordings_free_memory_without_changing_results() {
    let c = compile(&data("uncached-upstream.yaml"));
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let kept = run(&c, a.path(), 2, false);
    let mut opts = RunOptions::new(b.path()).with_renderer(spindlelab::renderer());
    opts.use_cache = false;
    opts.release_consumed = true;
    let released = engine::run(&c, &spindlelab::registry(), &opts, &|_, _| {}).unwrap_or_else(|e| panic!("{e}"));
    for (inst, o) in c.graph.instances.iter().zip(&released.result.outcomes) {
        match inst.step.as_str() {
            "frf" => assert!(matches!(o, Outcome::Computed { .. }), "{o:?}"),
            _ => assert!(matches!(o, Outcome::Released { .. }), "{}: {o:?}", inst.id),
        }
    }
    assert_eq!(released.manifest.computed, 3);
    assert_eq!(std::fs::read(a.path().join("frf.csv")).unwrap(), std::fs::read(b.path().join("frf.csv")).unwrap());
    assert!(kept.result.outcomes.iter().all(|o| matches!(o, Outcome::Computed { .. })));
}

#[test]
fn zipped_sweeps_feed_each_port_from_its_own_step() {
    let c = compile(&data("zipped-inputs.yaml"));
    let g = &c.graph;
    let ids = &g.by_step["compare"];
    assert_eq!(ids.len(), 2, "the two sweeps zip instead of forming a product");
    for &i in ids {
        let inst = &g.instances[i];
        for (port, step) in [("frf", "a"), ("reference", "b")] {
            let (src, _) = &inst.inputs[port][0];
            let producer = &g.instances[*src];
            assert_eq!(producer.step, step, "{}: port {port} fed by {}", inst.id, producer.id);
            assert_eq!(producer.label, inst.label);
        }
    }
}

/// A run that asks for a plot needs a renderer to draw it: without one it stops before
/// anything is computed, names the file that asked, and leaves the output folder as it was.
#[test]
fn a_plot_without_a_renderer_is_refused_before_anything_runs() {
    let c = compile(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/phase-lag.yaml"));
    let out = tempfile::tempdir().unwrap();
    let opts = RunOptions::new(out.path());
    match engine::run(&c, &spindlelab::registry(), &opts, &|_, _| {}) {
        Err(e @ engine::RunError::NoRenderer(_)) => {
            let file = c.recipe.outputs.iter().find(|o| o.file.ends_with(".svg") || o.file.ends_with(".png"));
            assert!(e.to_string().contains(&file.unwrap().file), "{e}");
        }
        other => panic!("expected NoRenderer, got {:?}", other.map(|r| r.written)),
    }
    let left: Vec<_> = std::fs::read_dir(out.path()).unwrap().flatten().map(|e| e.file_name()).collect();
    assert!(left.iter().all(|n| n.to_string_lossy().starts_with('.')), "{left:?}");
}

/// A file name with a sweep coordinate in braces writes one file per value, each holding that
/// point's values only and reading back as one block; a coordinate the step does not sweep is
/// an error at the output before anything runs.
#[test]
fn an_output_named_by_a_sweep_coordinate_writes_one_file_per_point() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(data("noisy-sweep.yaml")).unwrap();
    let split = text.replace("file: frf.csv", "file: \"frf-{hammer_mass}.csv\"");
    let recipe = dir.path().join("split.yaml");
    std::fs::write(&recipe, &split).unwrap();
    let c = compile(&recipe);
    let report = run(&c, &dir.path().join("out"), 2, false);
    for mass in ["0.02kg", "0.04kg", "0.06kg"] {
        let file = format!("frf-{mass}.csv");
        assert!(report.written.contains(&file), "{file} not in {:?}", report.written);
        let bytes = std::fs::read(dir.path().join("out").join(&file)).unwrap();
        let frfs = engine::formats::csv::read_frf_blocks(&bytes, &file).unwrap();
        assert_eq!(frfs.len(), 1, "{file}: one sweep point");
    }
    assert!(!report.written.contains(&"frf.csv".to_string()));

    let bad = dir.path().join("bad.yaml");
    std::fs::write(&bad, text.replace("file: frf.csv", "file: \"frf-{speed}.csv\"")).unwrap();
    let e = engine::compile_file(&bad, &spindlelab::registry()).err().expect("an unknown coordinate is refused");
    let shown = e.render(false);
    assert!(
        shown.contains("`{speed}` in `frf-{speed}.csv` names no sweep of step `frf`; its sweeps: hammer_mass"),
        "{shown}"
    );
    assert!(shown.contains("bad.yaml:"), "{shown}");
}
