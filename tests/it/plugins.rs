//! WebAssembly plugins end to end: the example plugins against analytic results, the
//! faulty and hostile fixtures against the sandbox, load-time checks, the compiled-component
//! cache and the command line. The plugins are built once, by `spindlelab-plugin-examples`.

use num_complex::Complex64;
use spindlelab::engine::exec::{Outcome, RunOptions};
use spindlelab::engine::value::{Channel, Frf, TimeSeries, UnitLabel, Value};
use spindlelab::engine::{self, Compiled, RunError, formats::csv};
use spindlelab::plugins::{self, Plugins};
use spindlelab_plugin_host::{Expect, Host, LoadError, Policy};
use std::path::{Path, PathBuf};
use std::process::Command;

fn examples() -> PathBuf {
    spindlelab_plugin_examples::dir().to_path_buf()
}

/// Plugins from the example folder only, compiled components cached in `cache`.
fn plugins_in(cache: &Path) -> Plugins {
    Plugins::with(vec![examples()], Policy::default(), Some(cache.to_path_buf()))
}

/// The compiled-component cache the tests share (each plugin is compiled once per run).
fn shared_cache() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("plugin-cache")
}

fn compile(path: &Path, plugins: &mut Plugins) -> (Compiled, engine::node::Registry) {
    let mut registry = spindlelab::registry();
    match plugins::compile_file(path, &[], &mut registry, plugins) {
        Ok(c) => (c, registry),
        Err(e) => panic!("{} does not compile:\n{}", path.display(), e.render(false)),
    }
}

/// Runs a recipe without the cache; every instance's outcome by id.
fn run(path: &Path, plugins: &mut Plugins) -> Vec<(String, Outcome)> {
    let (c, registry) = compile(path, plugins);
    let out = tempfile::tempdir().unwrap();
    let mut opts = RunOptions::new(out.path()).with_renderer(spindlelab::renderer());
    opts.use_cache = false;
    opts.keep_going = true;
    let result = match engine::run(&c, &registry, &opts, &|_, _| {}) {
        Ok(r) => r.result,
        Err(RunError::NodesFailed { report, .. }) => report.result,
        Err(e) => panic!("{e}"),
    };
    c.graph.instances.iter().map(|i| i.id.clone()).zip(result.outcomes).collect()
}

fn value<'a>(outcomes: &'a [(String, Outcome)], id: &str, port: &str) -> &'a Value {
    let (_, o) = outcomes.iter().find(|(i, _)| i == id).unwrap_or_else(|| panic!("no instance {id}"));
    match o.outputs() {
        Some(out) => out.get(port).unwrap_or_else(|| panic!("{id} has no {port}")),
        None => panic!("{id} did not run: {o:?}"),
    }
}

fn failure(outcomes: &[(String, Outcome)], id: &str) -> String {
    match &outcomes.iter().find(|(i, _)| i == id).expect("instance").1 {
        Outcome::Failed(e) => e.to_string(),
        o => panic!("{id} should have failed: {o:?}"),
    }
}

/// Receptance of a single degree of freedom, m/N.
fn sdof(m: f64, k: f64, c: f64, f: f64) -> Complex64 {
    let w = std::f64::consts::TAU * f;
    Complex64::new(1.0, 0.0) / Complex64::new(k - w * w * m, w * c)
}

#[test]
fn tip_mass_gives_the_receptance_of_the_structure_with_the_added_mass() {
    // Validation: H of m, k, c with the plugin's 20 g added (the recipe's accelerometer, the
    // entity passed to the plugin by value) is H of m + 20 g, k, c (closed form).
    let dir = tempfile::tempdir().unwrap();
    let (m, k, c, added) = (0.1, 1e7, 12.0, 0.02);
    let freq_hz: Vec<f64> = (0..=800).map(|i| 5.0 * i as f64).collect();
    let frf = Frf {
        values: freq_hz.iter().map(|&f| sdof(m, k, c, f)).collect(),
        freq_hz: freq_hz.clone(),
        coherence: None,
        unit: UnitLabel::new("m/N"),
        direction: Some("x".into()),
        speed: None,
        sensor: None,
        dofs: None,
    };
    std::fs::write(dir.path().join("sdof.csv"), csv::write_frf(&frf)).unwrap();
    let recipe = dir.path().join("tip-mass.yaml");
    std::fs::write(
        &recipe,
        "spindlelab: 1\nname: tip-mass-check\nplugins: [tip-mass]\n\
         sensors:\n  accel: { kind: accelerometer, mass: 20 g, location: tip }\nsteps:\n  \
         measured: { kind: read.frf, params: { file: sdof.csv } }\n  \
         loaded: { kind: effect.tip_mass, params: { sensor: accel }, inputs: { frf: \"@measured.frf\" } }\n  \
         removed: { kind: effect.tip_mass, params: { mass: -20 g }, inputs: { frf: \"@loaded.frf\" } }\n",
    )
    .unwrap();
    let outcomes = run(&recipe, &mut plugins_in(&shared_cache()));
    let Value::Frf(loaded) = value(&outcomes, "loaded", "frf") else { panic!("not an FRF") };
    let mut worst: f64 = 0.0;
    for (f, h) in loaded.freq_hz.iter().zip(&loaded.values) {
        let want = sdof(m + added, k, c, *f);
        worst = worst.max((h - want).norm() / want.norm());
    }
    assert!(worst < 1e-6, "largest relative difference from the closed form {worst:e}");
    assert_eq!(loaded.direction.as_deref(), Some("x"), "the FRF keeps its direction");
    // Removing the mass again gives the structure back; the plugin warns that it removes mass.
    let Value::Frf(back) = value(&outcomes, "removed", "frf") else { panic!("not an FRF") };
    for (h, f) in back.values.iter().zip(&freq_hz) {
        let want = sdof(m, k, c, *f);
        assert!((h - want).norm() / want.norm() < 1e-6);
    }
    let removed = &outcomes.iter().find(|(i, _)| i == "removed").unwrap().1;
    assert!(removed.warnings().iter().any(|w| w.contains("negative mass (-20 g)")), "{:?}", removed.warnings());
}

#[test]
fn chatter_energy_ratio_is_the_share_of_non_synchronous_energy_of_a_known_signal() {
    // Validation: rotation harmonics of amplitudes 3, 2, 1 at 100, 200, 400 Hz (6000 rpm) and a
    // chatter tone of amplitude 1.5 at 537 Hz, each on a spectral line: the Hann window
    // spreads each tone alike, so the share is 1.5²/(3² + 2² + 1² + 1.5²) exactly.
    let dir = tempfile::tempdir().unwrap();
    let (fs, n) = (8192.0, 8192usize);
    let tones = [(100.0, 3.0), (200.0, 2.0), (400.0, 1.0), (537.0, 1.5)];
    let samples: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 / fs;
            0.25 + tones.iter().map(|(f, a)| a * (std::f64::consts::TAU * f * t + 0.3 * f / 100.0).sin()).sum::<f64>()
        })
        .collect();
    let series = TimeSeries {
        sample_rate: fs,
        t0: 0.0,
        channels: vec![Channel { name: "ax".into(), unit: UnitLabel::new("m/s^2"), samples }],
    };
    std::fs::write(dir.path().join("cut.csv"), csv::write_time_series(&series)).unwrap();
    let recipe = dir.path().join("chatter.yaml");
    std::fs::write(
        &recipe,
        "spindlelab: 1\nname: chatter-check\nplugins: [chatter-indicator]\nsteps:\n  \
         cut: { kind: read.time_series, params: { file: cut.csv } }\n  \
         ratio: { kind: chatter.energy_ratio, params: { spindle_speed: 6000 rpm }, inputs: { signal: \"@cut.series\" } }\n  \
         spectrum: { kind: spectrum.amplitude, inputs: { signal: \"@cut.series\" } }\n",
    )
    .unwrap();
    let outcomes = run(&recipe, &mut plugins_in(&shared_cache()));
    let Value::Scalar(ratio) = value(&outcomes, "ratio", "ratio") else { panic!() };
    let want = 1.5f64.powi(2) / (9.0 + 4.0 + 1.0 + 2.25);
    assert!((ratio.value - want).abs() < 1e-9, "ratio {} against {want}", ratio.value);
    let Value::Scalar(f) = value(&outcomes, "ratio", "chatter_frequency") else { panic!() };
    assert_eq!(f.value, 537.0);
    assert_eq!(f.unit.symbol, "Hz");
    // The spectrum reads each tone's amplitude on its line, in the channel's unit.
    let Value::Table(t) = value(&outcomes, "spectrum", "spectrum") else { panic!() };
    assert_eq!(t.columns[1].unit.symbol, "m/s^2");
    for (fr, a) in tones {
        let line = fr as usize; // 1 Hz lines
        assert_eq!(t.columns[0].values[line], fr);
        assert!((t.columns[1].values[line] - a).abs() < 1e-9, "{fr} Hz reads {}", t.columns[1].values[line]);
    }
    assert!((t.columns[1].values[0] - 0.0).abs() < 1e-9, "the mean is removed");
}

#[test]
fn the_example_recipe_s_chatter_indicator_agrees_with_the_simulation_s_verdicts() {
    // The plugin's spectral share against milling.simulate's own once-per-period verdict
    // (another criterion, other code): low where the cut is stable, high where it chatters.
    let outcomes = run(Path::new("scripts/plugin-nodes.yaml"), &mut plugins_in(&shared_cache()));
    for depth in ["1 mm", "4 mm"] {
        let Value::Table(summary) = value(&outcomes, &format!("cut[depth={depth}]"), "summary") else { panic!() };
        let stable = summary.columns.iter().find(|c| c.name == "stable").unwrap().values[0] == 1.0;
        let Value::Scalar(r) = value(&outcomes, &format!("indicator[depth={depth}]"), "ratio") else { panic!() };
        if stable {
            assert!(r.value < 0.05, "{depth}: stable but {} of the energy is not synchronous", r.value);
        } else {
            assert!(r.value > 0.5, "{depth}: chatter but only {} of the energy is not synchronous", r.value);
        }
    }
    // The 20 g sensor lowers the target's resonance from sqrt(k/m) to sqrt(k/(m + 20 g)).
    let peak = |v: &Value| {
        let Value::Frf(f) = v else { panic!() };
        let i = (0..f.values.len()).max_by(|&a, &b| f.values[a].norm().total_cmp(&f.values[b].norm())).unwrap();
        f.freq_hz[i]
    };
    let (bare, loaded) = (peak(value(&outcomes, "frf", "frf")), peak(value(&outcomes, "with_sensor", "frf")));
    let fk = |m: f64| (1e7f64 / m).sqrt() / std::f64::consts::TAU;
    assert!((bare - fk(0.1)).abs() < 25.0, "bare peak {bare} Hz");
    assert!((loaded - fk(0.12)).abs() < 25.0, "loaded peak {loaded} Hz");
}

#[test]
fn hostile_plugins_fail_alone_with_clear_errors_within_their_bounds() {
    let cache = tempfile::tempdir().unwrap();
    // Tight bounds so the spinning and growing nodes stop quickly.
    let policy =
        Policy { fuel_default: 300_000_000, memory_default: 160 << 20, output_default: 4 << 20, ..Policy::default() };
    let mut plugins = Plugins::with(vec![examples()], policy, Some(cache.path().to_path_buf()));
    let outcomes = run(Path::new("tests/data/plugins/hostile.yaml"), &mut plugins);
    let Value::Scalar(y) = value(&outcomes, "after", "y") else { panic!() };
    assert_eq!(y.value, 1.5, "a working plugin node after the failures still runs");
    let expect = [
        ("spin", "ran out of its work bound (300000000 fuel units"),
        ("grow", "beyond its cap of 160 MiB"),
        ("huge", "returned 12000000 numbers, beyond its bound of 4194304"),
        ("wrong_type", "output `y` is declared a table but it returned a scalar"),
        ("undeclared", "returned an output `z` it does not declare"),
        ("trap", "it trapped (a panic in the plugin, or an `unreachable` instruction)"),
        ("panic", "it trapped (a panic in the plugin"),
        ("open_file", "could not open /etc/passwd: operation not supported"),
    ];
    for (id, text) in expect {
        let e = failure(&outcomes, id);
        assert!(e.contains(text), "{id}: {e}");
        assert!(e.contains(&format!("plugin `hostile` 0.1.0, node `fixture.{id}`")), "{id} names plugin and node: {e}");
    }
}

/// A recipe of the `hostile` fixture plugin: one input value, then `steps` (`name: kind`).
fn hostile_recipe(dir: &Path, steps: &[(&str, &str)]) -> PathBuf {
    let mut text = String::from(
        "spindlelab: 1\nname: hostile-edges\nplugins: [hostile]\nsteps:\n  one: { kind: rhai.eval, params: { expr: \"1.5\" } }\n",
    );
    for (name, kind) in steps {
        text.push_str(&format!("  {name}: {{ kind: {kind}, inputs: {{ x: \"@one.value\" }} }}\n"));
    }
    let path = dir.join("hostile-edges.yaml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_plugin_output_that_is_not_a_finite_number_is_refused_with_its_place() {
    let dir = tempfile::tempdir().unwrap();
    let mut plugins = plugins_in(&shared_cache());
    let recipe =
        hostile_recipe(dir.path(), &[("nan", "fixture.nan"), ("inf", "fixture.inf"), ("fine", "fixture.noop")]);
    let outcomes = run(&recipe, &mut plugins);
    let e = failure(&outcomes, "nan");
    assert!(
        e.contains("plugin `hostile` 0.1.0, node `fixture.nan`: output `y`: row 3 of column `v` is NaN; a plugin's outputs must be finite"),
        "{e}"
    );
    let e = failure(&outcomes, "inf");
    assert!(e.contains("node `fixture.inf`: output `y`: the value is -inf"), "{e}");
    let Value::Scalar(y) = value(&outcomes, "fine", "y") else { panic!() };
    assert_eq!(y.value, 1.5, "the other nodes run");
}

/// Whether a control character (but the line break) or a line-reordering one is in `s`.
fn has_raw_controls(s: &str) -> bool {
    s.chars().any(|c| (c.is_control() && c != '\n') || c == '\u{202e}')
}

#[test]
fn a_plugin_s_error_and_warnings_reach_the_terminal_escaped() {
    let home = tempfile::tempdir().unwrap();
    let dir = examples();
    let plugin_dir = dir.to_str().unwrap();

    let recipe = hostile_recipe(home.path(), &[("forge", "fixture.forge")]);
    let (code, out, err) =
        spindlelab(&["run", recipe.to_str().unwrap(), "--plugin", plugin_dir, "--no-cache"], home.path());
    assert_eq!(code, 2, "{err}");
    assert!(!has_raw_controls(&out) && !has_raw_controls(&err), "{out:?}\n{err:?}");
    assert!(
        err.contains(
            "node `fixture.forge`: \\x1b[2K\\r\\x1b[32mfine\\x1b[0m\\nerror: forged line\\x1b]0;owned\\x07\\u{202e}"
        ),
        "{err}"
    );
    assert!(!err.lines().any(|l| l.starts_with("error: forged")), "{err}");

    let recipe = hostile_recipe(home.path(), &[("warns", "fixture.forge_warning")]);
    let (code, out, err) =
        spindlelab(&["run", recipe.to_str().unwrap(), "--plugin", plugin_dir, "--no-cache"], home.path());
    assert_eq!(code, 0, "{err}");
    assert!(!has_raw_controls(&out) && !has_raw_controls(&err), "{out:?}\n{err:?}");
    assert!(out.contains("warning: \\x1b[2K\\rwarning line\\nok: forged by a warning"), "{out}");
    assert!(!out.lines().any(|l| l.starts_with("ok: forged")), "{out}");
}

/// Writes `component` and a manifest with its true hash into `dir` as plugin `id`.
fn write_plugin(dir: &Path, id: &str, component: &[u8], interface: &str) -> PathBuf {
    std::fs::write(dir.join(format!("{id}.wasm")), component).unwrap();
    let m = spindlelab_plugin_host::Manifest {
        id: id.into(),
        version: "0.1.0".into(),
        interface: interface.into(),
        wasm: format!("{id}.wasm"),
        sha256: spindlelab_plugin_host::pack::sha256_hex(component),
        limits: Default::default(),
    };
    let path = dir.join(format!("{id}.plugin.json"));
    m.write(&path).unwrap();
    path
}

fn load(manifest: &Path, expect: Expect) -> Result<spindlelab_plugin_host::Plugin, LoadError> {
    Host::new(Policy::default(), None).unwrap().load(manifest, &expect)
}

#[test]
fn faulty_plugin_files_are_refused_before_anything_runs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let wat = |name: &str| wat::parse_file(Path::new("tests/data/plugins").join(name)).unwrap();
    let err = |r: Result<spindlelab_plugin_host::Plugin, LoadError>| match r {
        Ok(_) => panic!("loaded"),
        Err(e) => e.to_string(),
    };

    let e = err(load(&write_plugin(d, "wasi", &wat("wasi-import.wat"), "0.1.0"), Expect::default()));
    assert!(e.contains("imports `wasi:filesystem/types@0.2.0`; a plugin may import nothing"), "{e}");
    let e = err(load(&write_plugin(d, "later", &wat("interface-0.9.0.wat"), "0.1.0"), Expect::default()));
    assert!(e.contains("built for interface spindlelab:plugin@0.9.0; this host runs 0.1.0, 0.2.0"), "{e}");
    let e = err(load(&write_plugin(d, "claims", &wat("interface-0.9.0.wat"), "0.9.0"), Expect::default()));
    assert!(e.contains("built for interface spindlelab:plugin@0.9.0"), "{e}");
    // A 0.2.0 component whose manifest says 0.1.0.
    let tip = std::fs::read(spindlelab_plugin_examples::manifest("tip-mass").with_file_name("tip-mass.wasm")).unwrap();
    let e = err(load(&write_plugin(d, "older", &tip, "0.1.0"), Expect::default()));
    assert!(
        e.contains("does not export `spindlelab:plugin/node@0.1.0`, which its manifest names (it exports `node@0.2.0`"),
        "{e}"
    );
    let e = err(load(&write_plugin(d, "corrupt", b"\0asm\x0d\0\x01\0garbage", "0.1.0"), Expect::default()));
    assert!(e.contains("not a valid WebAssembly component"), "{e}");

    // A component changed after packing: its hash no longer matches the manifest's.
    let good = spindlelab_plugin_examples::manifest("tip-mass");
    let mut bytes = std::fs::read(good.with_file_name("tip-mass.wasm")).unwrap();
    let manifest = write_plugin(d, "tip-mass", &bytes, "0.1.0");
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(d.join("tip-mass.wasm"), &bytes).unwrap();
    let e = err(load(&manifest, Expect::default()));
    assert!(e.contains("SHA-256 is") && e.contains("but the manifest says"), "{e}");

    // Pins the recipe sets.
    let e = err(load(&good, Expect { version: Some("0.2.0".into()), sha256: None }));
    assert!(e.contains("version 0.2.0 was asked for, but its version is 0.1.0"), "{e}");
    let e = err(load(&good, Expect { version: None, sha256: Some("0".repeat(64)) }));
    assert!(e.contains("SHA-256 0000"), "{e}");

    // Manifests that point outside their folder or are not manifests.
    let outside = d.join("outside.plugin.json");
    std::fs::write(&outside, r#"{"id":"x","version":"1","interface":"0.1.0","wasm":"../x.wasm","sha256":"00"}"#)
        .unwrap();
    assert!(err(load(&outside, Expect::default())).contains("give the component's file name in the manifest's folder"));
    let big = d.join("big.plugin.json");
    std::fs::write(&big, vec![b' '; 100_000]).unwrap();
    assert!(err(load(&big, Expect::default())).contains("a manifest is at most 65536 bytes"));
}

#[test]
fn a_compiled_plugin_is_cached_and_a_damaged_cache_entry_is_compiled_again() {
    let cache = tempfile::tempdir().unwrap();
    let host = Host::new(Policy::default(), Some(cache.path().to_path_buf())).unwrap();
    let manifest = spindlelab_plugin_examples::manifest("chatter-indicator");
    assert!(!host.load(&manifest, &Expect::default()).unwrap().from_cache);
    assert!(host.load(&manifest, &Expect::default()).unwrap().from_cache);
    for entry in std::fs::read_dir(cache.path()).unwrap() {
        let path = entry.unwrap().path();
        let mut bytes = std::fs::read(&path).unwrap();
        let mid = bytes.len() / 2;
        bytes[mid] ^= 0xff;
        std::fs::write(&path, bytes).unwrap();
    }
    let again = host.load(&manifest, &Expect::default()).unwrap();
    assert!(!again.from_cache, "a damaged entry is never loaded");
    assert_eq!(again.nodes.len(), 2);
}

#[test]
fn plugin_outputs_are_cached_under_the_plugin_s_hash() {
    let out = tempfile::tempdir().unwrap();
    let mut plugins = plugins_in(&shared_cache());
    let (c, registry) = compile(Path::new("scripts/plugin-nodes.yaml"), &mut plugins);
    let node = registry.get("effect.tip_mass").unwrap();
    let sha = node.code_digest().expect("a plugin node has a code digest");
    assert_eq!(sha.len(), 64);
    let opts = RunOptions::new(out.path()).with_renderer(spindlelab::renderer());
    engine::run(&c, &registry, &opts, &|_, _| {}).unwrap();
    let second = engine::run(&c, &registry, &opts, &|_, _| {}).unwrap();
    let i = c.graph.instances.iter().position(|i| i.id == "with_sensor").unwrap();
    assert!(matches!(second.result.outcomes[i], Outcome::Cached { .. } | Outcome::Unneeded { cached: true, .. }));
}

#[test]
fn bad_plugin_entries_are_reported_at_their_line_and_column() {
    let mut plugins = plugins_in(&shared_cache());
    let mut registry = spindlelab::registry();
    let path = Path::new("tests/data/plugins/bad-refs.yaml");
    let e = match plugins::compile_file(path, &[], &mut registry, &mut plugins) {
        Ok(_) => panic!("compiled"),
        Err(e) => e.render(false),
    };
    for needle in [
        "bad-refs.yaml:5:5",
        "plugin `no-such-plugin` is not in the plugin folders",
        "bad-refs.yaml:6:5",
        "version 9.9.9 was asked for, but its version is 0.1.0",
        "bad-refs.yaml:7:5",
        "by `id` or by `path`, not both or neither",
        "bad-refs.yaml:8:5",
        "missing.plugin.json",
        "bad-refs.yaml:9:5",
        "a plugin entry is an id or a mapping, found an integer",
        "unknown key `colour` in a plugin entry",
    ] {
        assert!(e.contains(needle), "missing `{needle}` in:\n{e}");
    }
}

fn spindlelab(args: &[&str], home: &Path) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(args)
        .env("HOME", home)
        .env_remove("XDG_DATA_HOME")
        .env_remove("XDG_CACHE_HOME")
        .env_remove("SPINDLELAB_PLUGIN_PATH")
        .env_remove("SPINDLELAB_PLUGIN_CACHE")
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

#[test]
fn command_line_checks_plugins_lists_their_nodes_and_runs_recipes_with_them() {
    let home = tempfile::tempdir().unwrap();
    let manifest = spindlelab_plugin_examples::manifest("tip-mass");
    let (code, out, err) = spindlelab(&["plugin", "check", manifest.to_str().unwrap()], home.path());
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("tip-mass 0.1.0") && out.contains("effect.tip_mass v1") && out.contains("256 MiB memory"),
        "{out}"
    );
    assert!(out.contains("effect for the diagnosis: tip_mass"), "{out}");

    let dir = examples();
    let (code, out, _) = spindlelab(&["nodes", "effect.tip_mass", "--plugin", dir.to_str().unwrap()], home.path());
    assert_eq!(code, 0);
    assert!(out.contains("effect.tip_mass") && out.contains("mass"), "{out}");

    let out_dir = home.path().join("run");
    let (code, _, err) = spindlelab(
        &["run", "scripts/plugin-nodes.yaml", "-q", "--plugin", dir.to_str().unwrap(), "-o", out_dir.to_str().unwrap()],
        home.path(),
    );
    assert_eq!(code, 0, "{err}");
    assert!(out_dir.join("chatter-energy-ratio.csv").is_file());

    // Without the plugin folder the recipe names a plugin that is not there: exit 2, at its line.
    let (code, _, err) = spindlelab(&["check", "scripts/plugin-nodes.yaml"], home.path());
    assert_eq!(code, 2);
    let text = std::fs::read_to_string("scripts/plugin-nodes.yaml").unwrap();
    let line = 1 + text.lines().position(|l| l.contains("id: tip-mass")).unwrap();
    assert!(
        err.contains(&format!("plugin-nodes.yaml:{line}:5"))
            && err.contains("plugin `tip-mass` is not in the plugin folders"),
        "{err}"
    );

    let bad = home.path().join("bad.plugin.json");
    std::fs::write(&bad, "{}").unwrap();
    let (code, _, err) = spindlelab(&["plugin", "check", bad.to_str().unwrap()], home.path());
    assert_eq!(code, 2);
    assert!(err.contains("not a plugin manifest"), "{err}");

    // An effect declaration the host refuses, through the binary: exit 2 with the cause.
    let bad_effect = spindlelab_plugin_examples::manifest("bad-effect");
    let (code, _, err) = spindlelab(&["plugin", "check", bad_effect.to_str().unwrap()], home.path());
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("plugin `bad-effect`")
            && err.contains("fixture.bad_effect")
            && err.contains("must be finite, increasing and hold the absent value 0.2"),
        "{err}"
    );
}

#[test]
fn a_new_plugin_from_the_template_builds_loads_and_runs() {
    let home = tempfile::tempdir().unwrap();
    let crate_dir = home.path().join("my-gain");
    let (code, out, err) = spindlelab(&["plugin", "new", "my-gain", "--dir", crate_dir.to_str().unwrap()], home.path());
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("plugin build"), "{out}");
    // Built into the user plugin folder, where a recipe finds it by id.
    // The examples' target folder already holds the SDK's dependencies.
    let target = spindlelab_plugin_examples::target_dir();
    let (code, out, err) = spindlelab(
        &["plugin", "build", crate_dir.to_str().unwrap(), "--target-dir", target.to_str().unwrap()],
        home.path(),
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("my_gain.scale v1"), "{out}");
    assert!(home.path().join(".local/share/spindlelab/plugins/my-gain.plugin.json").is_file());
    let (code, out, _) = spindlelab(&["plugin", "list"], home.path());
    assert_eq!(code, 0);
    assert!(out.contains("my-gain 0.1.0"), "{out}");
}

/// A folder with `bare.csv`, the FRF of an SDOF (0.1 kg, 1e7 N/m, damping `c` N·s/m, closed
/// form, coherence 0.999), and `measured.csv`, the same with 20 g more mass.
fn bare_and_20_g_heavier(c: f64) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let (m, k) = (0.1, 1e7);
    let freq_hz: Vec<f64> = (40..=600).map(|i| 5.0 * i as f64).collect();
    let frf = |mass: f64| Frf {
        values: freq_hz.iter().map(|&f| sdof(mass, k, c, f)).collect(),
        freq_hz: freq_hz.clone(),
        coherence: Some(vec![0.999; freq_hz.len()]),
        unit: UnitLabel::new("m/N"),
        direction: Some("x".into()),
        speed: None,
        sensor: None,
        dofs: None,
    };
    std::fs::write(dir.path().join("bare.csv"), csv::write_frf(&frf(m))).unwrap();
    std::fs::write(dir.path().join("measured.csv"), csv::write_frf(&frf(m + 0.02))).unwrap();
    dir
}

#[test]
fn the_fit_driver_finds_the_mass_a_plugin_effect_adds() {
    // A plugin effect is a transform of the model like a built-in one: with the measured FRF
    // that of m + 20 g (closed form, coherence 0.999) and the model the bare structure through
    // `effect.tip_mass`, the least-squares fit of the effect's mass finds the 20 g.
    let dir = bare_and_20_g_heavier(12.0);
    let recipe = dir.path().join("fit.yaml");
    std::fs::write(
        &recipe,
        "spindlelab: 1\nname: fit-tip-mass\nplugins: [tip-mass]\nparams: { added: 5 g }\nsteps:\n  \
         bare: { kind: read.frf, params: { file: bare.csv } }\n  \
         measured: { kind: read.frf, params: { file: measured.csv } }\n  \
         model: { kind: effect.tip_mass, params: { mass: $added }, inputs: { frf: \"@bare.frf\" } }\n  \
         gap: { kind: frf.gap, inputs: { model: \"@model.frf\", measured: \"@measured.frf\" } }\n\
         fit:\n  free:\n    added: { min: 0 g, max: 60 g }\n  objective: [\"@gap.residual\"]\n  method: least-squares\n",
    )
    .unwrap();
    let (c, registry) = compile(&recipe, &mut plugins_in(&shared_cache()));
    let report = spindlelab::fit::fit(&c, &[], &registry, Some(1)).expect("fit runs");
    let added = &report.params[0];
    assert_eq!(added.unit, "g", "the fit reports the unit the recipe writes");
    assert!((added.value - 20.0).abs() < 0.02, "fitted {} g, truth 20 g", added.value);
    assert!(report.objective_after < 1e-6 * report.objective_before, "{report:?}");
}

#[test]
fn the_diagnosis_names_a_plugin_effect_and_fits_it() {
    // The model is the bare structure; the measurement carries 20 g more at the measured point
    // (closed form). No built-in effect acts on a model read from a file but the sensor's
    // delay, so the diagnosis must take `tip_mass` from the plugin, fit it within the
    // plugin's bounds and find the 20 g; the recipe it writes runs the plugin's node.
    // ζ = 0.6 %: the 20 g moves the resonance 72 Hz, about four half-power bandwidths, so the
    // fit must sample the plugin's bounds rather than descend from the absent value.
    let dir = bare_and_20_g_heavier(12.0);
    let recipe = dir.path().join("diagnose.yaml");
    std::fs::write(
        &recipe,
        "spindlelab: 1\nname: diagnose-tip-mass\nplugins: [tip-mass]\nsteps:\n  \
         bare: { kind: read.frf, params: { file: bare.csv } }\n  \
         measured: { kind: read.frf, params: { file: measured.csv } }\n  \
         gap: { kind: frf.gap, inputs: { model: \"@bare.frf\", measured: \"@measured.frf\" } }\n",
    )
    .unwrap();
    let (_, registry) = compile(&recipe, &mut plugins_in(&shared_cache()));
    let d = spindlelab::diagnose::diagnose(&recipe, &registry).expect("the diagnosis runs");
    let names: Vec<&str> = d.effects.iter().map(|e| e.name).collect();
    assert_eq!(names, ["tip_mass"], "{}", spindlelab::diagnose::markdown(&d));
    let mass = d.effects[0].params["mass_kg"].as_f64().unwrap();
    assert!((mass - 0.02).abs() < 2e-5, "fitted {mass} kg, truth 0.02 kg");
    assert!(
        d.candidates.iter().any(|c| c.effects == ["sensor_delay"] && !c.explains),
        "the delay cannot explain a mass"
    );
    assert!(d.diagnosed_recipe.contains("kind: effect.tip_mass"), "{}", d.diagnosed_recipe);
}

#[test]
fn a_plugin_built_for_interface_0_1_0_still_runs() {
    let host = Host::new(Policy::default(), None).unwrap();
    let p = host.load(&spindlelab_plugin_examples::manifest("legacy"), &Expect::default()).expect("0.1.0 loads");
    assert_eq!(p.manifest.interface, "0.1.0");
    let dir = tempfile::tempdir().unwrap();
    let recipe = dir.path().join("legacy.yaml");
    std::fs::write(
        &recipe,
        "spindlelab: 1\nname: legacy\nplugins: [legacy]\nsteps:\n  \
         x: { kind: rhai.eval, params: { expr: \"0.002\", unit: m } }\n  \
         y: { kind: legacy.scale, inputs: { x: \"@x.value\" } }\n",
    )
    .unwrap();
    let out = run(&recipe, &mut plugins_in(&shared_cache()));
    match value(&out, "y", "y") {
        Value::Scalar(s) => assert!((s.value - 6e-3).abs() < 1e-15 && s.unit.symbol == "m", "{s:?}"),
        v => panic!("{v:?}"),
    }
    assert!(p.nodes.iter().all(|n| spindlelab::engine::node::Node::effect(n.as_ref()).is_none()));
}

#[test]
fn no_call_sees_anything_of_an_earlier_one() {
    // Instance slots are recycled and keep touched pages mapped between calls: each call must
    // still start from the component's initial memory. `fixture.remember` counts its calls
    // in its data and marks a page it grows; a fresh instance reports 1. Calls of another
    // kind and another plugin in between recycle the same slots.
    use spindlelab::engine::node::{Labelled, Node, NodeContext};
    use spindlelab::engine::value::Scalar;
    let host = Host::new(Policy::default(), None).unwrap();
    let load = |id: &str| host.load(&spindlelab_plugin_examples::manifest(id), &Expect::default()).unwrap();
    let (hostile, tip) = (load("hostile"), load("tip-mass"));
    let kind =
        |p: &spindlelab_plugin_host::Plugin, k: &str| p.nodes.iter().find(|n| n.spec().kind == k).unwrap().clone();
    let (remember, noop, tip_mass) =
        (kind(&hostile, "fixture.remember"), kind(&hostile, "fixture.noop"), kind(&tip, "effect.tip_mass"));
    let input = |port: &str, value: Value| -> indexmap::IndexMap<String, Vec<Labelled>> {
        [(port.to_string(), vec![Labelled { label: String::new(), coords: vec![], value: std::sync::Arc::new(value) }])]
            .into_iter()
            .collect()
    };
    let x = input("x", Value::Scalar(Scalar::new(1.0, "m")));
    let frf = input(
        "frf",
        Value::Frf(Frf {
            freq_hz: vec![100.0; 50_000],
            values: vec![Complex64::new(1e-6, -1e-6); 50_000],
            coherence: None,
            unit: UnitLabel::new("m/N"),
            direction: None,
            speed: None,
            sensor: None,
            dofs: None,
        }),
    );
    let recipe = spindlelab::engine::model::Recipe::default();
    let params = spindlelab::engine::spec::Params::default();
    let mut mass = spindlelab::engine::spec::Params::default();
    let kg = spindlelab::engine::grammar::parse_unit("kg").unwrap().dim;
    mass.values.insert("mass".into(), spindlelab::engine::spec::ParamValue::Quantity { value: 0.01, dim: kg });
    for i in 0..40 {
        let out =
            remember.run(&NodeContext::new("remember", &params, &x, &recipe.entities_named_by(&params))).expect("runs");
        let Value::Scalar(y) = &out["y"] else { panic!() };
        assert_eq!(y.value, 1.0, "call {i} saw an earlier call (1000: its page, > 1: its data)");
        match i % 3 {
            0 => drop(
                noop.run(&NodeContext::new("noop", &params, &x, &recipe.entities_named_by(&params))).expect("runs"),
            ),
            1 => drop(
                tip_mass.run(&NodeContext::new("tip", &mass, &frf, &recipe.entities_named_by(&mass))).expect("runs"),
            ),
            _ => {}
        }
    }
}

#[test]
fn the_spectrum_plugin_names_a_sample_that_is_not_a_number_and_a_sum_that_overflows() {
    // The mean's pass checks the samples: a NaN or an infinity is named by its position; finite
    // samples whose sum overflows are named as such (no sample is at fault).
    use indexmap::IndexMap;
    use spindlelab::engine::model::Recipe;
    use spindlelab::engine::node::{Labelled, Node, NodeContext, NodeError};
    use spindlelab::engine::spec::Params;
    use std::sync::Arc;
    let host = Host::new(Policy::default(), Some(shared_cache())).unwrap();
    let plugin = host.load(&spindlelab_plugin_examples::manifest("chatter-indicator"), &Expect::default()).unwrap();
    let node = plugin.nodes.iter().find(|n| n.spec().kind == "spectrum.amplitude").unwrap();
    let message = |samples: Vec<f64>| {
        let series = TimeSeries {
            sample_rate: 1000.0,
            t0: 0.0,
            channels: vec![Channel { name: "ax".into(), unit: UnitLabel::new("m/s^2"), samples }],
        };
        let signal = Labelled { label: String::new(), coords: vec![], value: Arc::new(Value::TimeSeries(series)) };
        let inputs: IndexMap<String, Vec<Labelled>> = [("signal".to_string(), vec![signal])].into_iter().collect();
        let (params, recipe) = (Params::default(), Recipe::default());
        match node.run(&NodeContext::new("spectrum", &params, &inputs, &recipe.entities_named_by(&params))) {
            Err(NodeError::Failed(m)) => m,
            other => panic!("not refused: {other:?}"),
        }
    };
    let mut samples = vec![1.0; 64];
    samples[7] = f64::NAN;
    let m = message(samples.clone());
    assert!(m.contains("sample 7 of channel `ax` is not a finite number"), "{m}");
    samples[7] = 1.0;
    samples[40] = f64::NEG_INFINITY;
    assert!(message(samples).contains("sample 40 of channel `ax`"));
    let m = message(vec![1.5e308; 64]);
    assert!(m.contains("too large to sum"), "{m}");
}

/// The SDK's paired `sin` and `cos`, compiled natively.
#[path = "../../plugins/guest/sdk/src/trig.rs"]
mod trig;

/// The plugin SDK's `sin` and `cos` (one argument reduction for an angle's cosine and sine)
/// give libm's own values bit for bit, in any order of calls: on FFT twiddle angles taken as
/// the planners take them (cosine, then sine), on angles whose reduction takes each of
/// libm's paths (up to 1e300, the large-argument one), on the special values; and every
/// value is within 1 ulp of the host's C library (an implementation of its own).
#[test]
fn the_sdk_s_paired_sine_and_cosine_are_libm_s_bit_for_bit() {
    let mut pair = trig::Pair::new();
    let mut check = |x: f64, cos_first: bool| {
        let (s, c) = if cos_first {
            let c = pair.cos(x);
            (pair.sin(x), c)
        } else {
            let s = pair.sin(x);
            (s, pair.cos(x))
        };
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        assert!(same(s, libm::sin(x)) && same(c, libm::cos(x)), "x = {x:e}: ({s:e}, {c:e})");
        // A repeated angle is answered from memory, with the same value.
        assert!(same(pair.sin(x), s) && same(pair.cos(x), c));
        if x.is_finite() {
            let ulp = |v: f64| v.abs().next_up() - v.abs();
            assert!((s - x.sin()).abs() <= ulp(x.sin()) && (c - x.cos()).abs() <= ulp(x.cos()), "x = {x:e}");
        }
    };
    for n in [16_usize, 1000, 4096, 65_536] {
        for k in 0..n {
            check(-std::f64::consts::TAU / n as f64 * k as f64, true);
        }
    }
    let mut x = 1.0e-12_f64;
    while x < 1.0e300 {
        for v in [x, -x, x * 1.000_000_7, std::f64::consts::FRAC_PI_4 * x] {
            check(v, v.to_bits() % 2 == 0);
        }
        x *= 1.37;
    }
    for v in [0.0, -0.0, 1e-320, f64::MIN_POSITIVE, f64::MAX, f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
        check(v, true);
        check(v, false);
    }
}
