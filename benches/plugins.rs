//! WebAssembly plugin costs: the overhead of one call of a no-op plugin node (fresh store,
//! instantiation, arguments in and out), the same computation natively and in a plugin
//! (mean removal, Hann window and FFT of 65,536 samples: `spectrum.amplitude` of the
//! example plugin against the same node kind built into this program, and its steps
//! alone; the ratio of plugin to built-in is also printed from alternating calls), and the
//! cold start of a plugin whose compiled form is cached (manifest, hash, deserialise,
//! checks, describe).

#[path = "common/alloc.rs"]
mod alloc;
/// The plugin's own spectrum code (window, transform, amplitudes), compiled natively.
#[path = "../plugins/guest/examples/chatter-indicator/src/spectrum.rs"]
mod spectrum;

use criterion::{Criterion, criterion_group, criterion_main};
use indexmap::IndexMap;
use realfft::RealFftPlanner;
use spindlelab::engine::model::Recipe;
use spindlelab::engine::node::{Labelled, Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab::engine::spec::Params;
use spindlelab::engine::value::{Channel, Column, PortType, Scalar, Table, TimeSeries, UnitLabel, Value};
use spindlelab_plugin_host::{Expect, Host, Policy};
use std::hint::black_box;
use std::sync::Arc;

fn node(host: &Host, plugin: &str, kind: &str) -> Arc<dyn Node> {
    let p = host.load(&spindlelab_plugin_examples::manifest(plugin), &Expect::default()).expect("example plugin loads");
    p.nodes.into_iter().find(|n| n.spec().kind == kind).expect("kind")
}

fn inputs(port: &str, value: Value) -> IndexMap<String, Vec<Labelled>> {
    [(port.to_string(), vec![Labelled { label: String::new(), coords: vec![], value: Arc::new(value) }])]
        .into_iter()
        .collect()
}

/// The plugin's `spectrum.amplitude` as a built-in node: the same checks of its input, the
/// same steps, the same table out, run through the engine's `Node` interface as the plugin's
/// node is.
struct BuiltinSpectrum(NodeSpec);

impl BuiltinSpectrum {
    fn new() -> Self {
        BuiltinSpectrum(NodeSpec {
            kind: "spectrum.amplitude",
            version: 1,
            description: "amplitude spectrum of the first channel",
            inputs: vec![PortSpec::new("signal", PortType::TimeSeries, "the record")],
            outputs: vec![PortSpec::new("spectrum", PortType::Table, "freq_hz and amplitude")],
            params: vec![],
        })
    }
}

impl Node for BuiltinSpectrum {
    fn spec(&self) -> &NodeSpec {
        &self.0
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let Value::TimeSeries(series) = ctx.input("signal")? else {
            return Err(NodeError::input("signal", "not a time series"));
        };
        let ch = series.channels.first().ok_or_else(|| NodeError::input("signal", "no channels"))?;
        if ch.samples.len() < 16 {
            return Err(NodeError::input("signal", "give at least 16 samples"));
        }
        let mean = ch.samples.iter().sum::<f64>() / ch.samples.len() as f64;
        if !mean.is_finite() {
            return Err(NodeError::input("signal", "a sample is not a finite number, or their sum overflows"));
        }
        if !(series.sample_rate.is_finite() && series.sample_rate > 0.0) {
            return Err(NodeError::input("signal", "the sample rate must be finite and > 0"));
        }
        let amplitude = spectrum::amplitudes(&ch.samples, mean, &mut RealFftPlanner::new())
            .map_err(|e| NodeError::Failed(format!("the transform failed: {e}")))?;
        let df = series.sample_rate / ch.samples.len() as f64;
        let freq = (0..amplitude.len()).map(|i| i as f64 * df).collect();
        let table = Table {
            columns: vec![Column::new("freq_hz", "Hz", freq), Column::new("amplitude", &ch.unit.symbol, amplitude)],
        };
        Ok([("spectrum".to_string(), Value::Table(table))].into_iter().collect())
    }
}

/// Alternating calls of the plugin and the built-in node timed for the ratio of the two.
const PAIRS: usize = 300;

fn bench(c: &mut Criterion) {
    let cache = tempfile::tempdir().expect("temp dir");
    let host = Host::new(Policy::default(), Some(cache.path().to_path_buf())).expect("host");
    let recipe = Recipe::default();
    let params = Params::default();

    let noop = node(&host, "hostile", "fixture.noop");
    let one = inputs("x", Value::Scalar(Scalar::new(1.5, "m")));
    c.bench_function("plugins/noop_call", |b| {
        b.iter(|| {
            let entities = recipe.entities_named_by(&params);
            let ctx = NodeContext::new("noop", &params, &one, &entities);
            black_box(noop.run(&ctx).expect("runs"))
        })
    });

    let n = 65_536;
    let samples: Vec<f64> = (0..n).map(|i| (i as f64 * 0.01).sin() + 0.3 * (i as f64 * 0.37).cos()).collect();
    let series = Value::TimeSeries(TimeSeries {
        sample_rate: 10_000.0,
        t0: 0.0,
        channels: vec![Channel { name: "a".into(), unit: UnitLabel::new("m/s^2"), samples: samples.clone() }],
    });
    let plugin = node(&host, "chatter-indicator", "spectrum.amplitude");
    let signal = inputs("signal", series);
    let builtin = BuiltinSpectrum::new();
    let table = |node: &dyn Node| {
        let entities = recipe.entities_named_by(&params);
        let ctx = NodeContext::new("spectrum", &params, &signal, &entities);
        match node.run(&ctx).expect("runs").swap_remove("spectrum") {
            Some(Value::Table(t)) => t,
            _ => panic!("no spectrum table"),
        }
    };
    // The two agree before they are timed.
    let (plugin_table, builtin_table) = (table(plugin.as_ref()), table(&builtin));
    assert_eq!(plugin_table.columns[0], builtin_table.columns[0], "frequencies");
    let worst = (plugin_table.columns[1].values.iter().zip(&builtin_table.columns[1].values))
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "plugin and built-in spectra differ by {worst}");
    // The target is a ratio, and this machine's speed drifts between criterion's runs of
    // the two: time them in alternation too, and report the paired ratios.
    let time = |node: &dyn Node| {
        let entities = recipe.entities_named_by(&params);
        let ctx = NodeContext::new("spectrum", &params, &signal, &entities);
        let start = std::time::Instant::now();
        black_box(node.run(&ctx).expect("runs"));
        start.elapsed().as_secs_f64()
    };
    for _ in 0..10 {
        time(plugin.as_ref());
        time(&builtin);
    }
    let mut ratios: Vec<f64> = (0..PAIRS).map(|_| time(plugin.as_ref()) / time(&builtin)).collect();
    ratios.sort_by(f64::total_cmp);
    let at = |q: f64| ratios[((PAIRS - 1) as f64 * q).round() as usize];
    println!(
        "plugins/spectrum_65536 plugin ÷ built-in, {PAIRS} interleaved pairs: median {:.3} (p10 {:.3}, p90 {:.3})",
        at(0.5),
        at(0.1),
        at(0.9)
    );
    c.bench_function("plugins/spectrum_65536_plugin", |b| {
        b.iter(|| {
            let entities = recipe.entities_named_by(&params);
            let ctx = NodeContext::new("spectrum", &params, &signal, &entities);
            black_box(plugin.run(&ctx).expect("runs"))
        })
    });
    // The same node kind built in: the target is the plugin within 2× of this.
    c.bench_function("plugins/spectrum_65536_native", |b| {
        b.iter(|| {
            let entities = recipe.entities_named_by(&params);
            let ctx = NodeContext::new("spectrum", &params, &signal, &entities);
            black_box(builtin.run(&ctx).expect("runs"))
        })
    });
    // The steps alone, without the node's checks and table (a planner per call, as the
    // plugin makes one per call).
    c.bench_function("plugins/spectrum_65536_steps", |b| {
        b.iter(|| {
            let mean = samples.iter().sum::<f64>() / samples.len() as f64;
            black_box(spectrum::amplitudes(black_box(&samples), mean, &mut RealFftPlanner::new()))
        })
    });

    let manifest = spindlelab_plugin_examples::manifest("chatter-indicator");
    host.load(&manifest, &Expect::default()).expect("fills the cache");
    c.bench_function("plugins/cold_start_cached", |b| {
        b.iter(|| {
            let host = Host::new(Policy::default(), Some(cache.path().to_path_buf())).expect("host");
            let p = host.load(&manifest, &Expect::default()).expect("loads");
            assert!(p.from_cache);
            black_box(p.nodes.len())
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).without_plots();
    targets = bench
}
criterion_main!(benches);
