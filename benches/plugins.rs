//! WebAssembly plugin costs: the overhead of one call of a no-op plugin node (fresh store,
//! instantiation, arguments in and out), the same computation natively and in a plugin
//! (mean removal, Hann window and FFT of 65,536 samples: `spectrum.amplitude` of the
//! example plugin against the same steps compiled into this program), and the cold start
//! of a plugin whose compiled form is cached (manifest, hash, deserialise, checks, describe).

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use indexmap::IndexMap;
use realfft::RealFftPlanner;
use spindlelab::engine::model::Recipe;
use spindlelab::engine::node::{Labelled, Node, NodeContext};
use spindlelab::engine::spec::Params;
use spindlelab::engine::value::{Channel, Scalar, TimeSeries, UnitLabel, Value};
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

/// The Hann window `0.5 − 0.5 cos(2πi/n)` of length n, with one cosine per quarter period
/// (cos(π ∓ x) = −cos x, cos(2π − x) = cos x) when 4 divides n.
fn hann(n: usize) -> Vec<f64> {
    let step = std::f64::consts::TAU / n as f64;
    if !n.is_multiple_of(4) {
        return (0..n).map(|i| 0.5 - 0.5 * (step * i as f64).cos()).collect();
    }
    let q = n / 4;
    let c: Vec<f64> = (0..=q).map(|i| (step * i as f64).cos()).collect();
    (0..n)
        .map(|i| {
            let cos = match i / q {
                0 => c[i],
                1 => -c[2 * q - i],
                2 => -c[i - 2 * q],
                _ => c[4 * q - i],
            };
            0.5 - 0.5 * cos
        })
        .collect()
}

/// The example plugin's spectrum, natively: mean removed, Hann window, real-input FFT,
/// one-sided amplitude.
fn native_spectrum(samples: &[f64], planner: &mut RealFftPlanner<f64>) -> Vec<f64> {
    let n = samples.len();
    let mean = samples.iter().sum::<f64>() / n as f64;
    let mut buf: Vec<f64> = samples.iter().zip(hann(n)).map(|(s, w)| (s - mean) * w).collect();
    let fft = planner.plan_fft_forward(n);
    let mut spectrum = fft.make_output_vec();
    fft.process(&mut buf, &mut spectrum).expect("lengths match the plan");
    let gain = 4.0 / n as f64;
    let mut a: Vec<f64> = spectrum.iter().map(|c| gain * c.norm()).collect();
    a[0] *= 0.5;
    a
}

fn bench(c: &mut Criterion) {
    let cache = tempfile::tempdir().expect("temp dir");
    let host = Host::new(Policy::default(), Some(cache.path().to_path_buf())).expect("host");
    let recipe = Recipe::default();
    let params = Params::default();

    let noop = node(&host, "hostile", "fixture.noop");
    let one = inputs("x", Value::Scalar(Scalar::new(1.5, "m")));
    c.bench_function("plugins/noop_call", |b| {
        b.iter(|| {
            let ctx = NodeContext::new("noop", &params, &one, &recipe);
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
    let spectrum = node(&host, "chatter-indicator", "spectrum.amplitude");
    let signal = inputs("signal", series);
    // The two agree before they are timed.
    let ctx = NodeContext::new("spectrum", &params, &signal, &recipe);
    let Value::Table(t) = spectrum.run(&ctx).expect("runs").swap_remove("spectrum").expect("spectrum") else {
        panic!("not a table")
    };
    let native = native_spectrum(&samples, &mut RealFftPlanner::new());
    let worst = t.columns[1].values.iter().zip(&native).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(worst < 1e-9, "plugin and native spectra differ by {worst}");
    c.bench_function("plugins/spectrum_65536_plugin", |b| {
        b.iter(|| {
            let ctx = NodeContext::new("spectrum", &params, &signal, &recipe);
            black_box(spectrum.run(&ctx).expect("runs"))
        })
    });
    c.bench_function("plugins/spectrum_65536_native", |b| {
        // A planner per call, as the plugin makes one per call.
        b.iter(|| black_box(native_spectrum(black_box(&samples), &mut RealFftPlanner::new())))
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
