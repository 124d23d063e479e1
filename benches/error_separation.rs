//! Timing of three-probe error separation (§3.2): 200 revolutions at 1000 rpm sampled at
//! 100 kHz (6,000 samples per revolution, 1.2 M samples per probe), three probes, ten
//! segments; with and without the asynchronous spectrum, and the tachometer decoding.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_stdlib::error_motion::{DEFAULT_ANGLES_DEG, ProbeRecords, SeparationOptions, separate};
use spindlelab_stdlib::tach::{Revolutions, TachOptions, decode};
use std::f64::consts::TAU;
use std::hint::black_box;

const FS: f64 = 100.0e3;
const RPM: f64 = 1000.0;
const REVS: f64 = 201.5;

struct Record {
    tach: Vec<f64>,
    probes: [Vec<f64>; 3],
}

/// Eq. 3.4 with a form of a few undulations (44 UPR included), synchronous and asynchronous
/// motion, a 0.2 % speed ramp and deterministic pseudo-noise.
fn record() -> Record {
    let n = (REVS * 60.0 / RPM * FS) as usize;
    let f0 = RPM / 60.0;
    let duration = n as f64 / FS;
    let angles = DEFAULT_ANGLES_DEG.map(f64::to_radians);
    let mut tach = Vec::with_capacity(n);
    let mut probes = [Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n)];
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    for i in 0..n {
        let t = i as f64 / FS;
        let th = 0.3 + TAU * f0 * (t + 0.5 * 0.002 / duration * t * t);
        let psi = th.rem_euclid(TAU);
        tach.push(if psi < 0.1 { 0.0 } else { 5.0 });
        let x = 30e-9 * (2.0 * th).cos() + 15e-9 * (TAU * 730.0 * t).sin();
        let y = 20e-9 * (3.0 * th).sin() + 25e-9 * (44.0 * th).sin();
        for (p, &phi) in angles.iter().enumerate() {
            let a = th - phi;
            let form = 0.3e-6 * (2.0 * a).cos() + 0.15e-6 * (3.0 * a).sin() + 0.2e-6 * (44.0 * a).cos();
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let noise = 20e-9 * ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
            probes[p].push(form + x * phi.cos() + y * phi.sin() + noise);
        }
    }
    Record { tach, probes }
}

fn bench_separation(c: &mut Criterion) {
    let rec = record();
    let all = decode(&rec.tach, FS, 0.0, &TachOptions::default()).expect("clean tachometer");
    let revs = Revolutions::from_edges(all.edges()[..201].to_vec(), FS).expect("200 revolutions");
    let probes = ProbeRecords { a: &rec.probes[0], b: &rec.probes[1], c: &rec.probes[2], sample_rate: FS, t0: 0.0 };
    let core = SeparationOptions { async_spectrum: false, ..Default::default() };
    let full = SeparationOptions::default();
    c.bench_function("error_separation/200x6000x3", |b| {
        b.iter(|| separate(black_box(&probes), black_box(&revs), black_box(&core)).expect("valid record"))
    });
    c.bench_function("error_separation/200x6000x3+async_spectrum", |b| {
        b.iter(|| separate(black_box(&probes), black_box(&revs), black_box(&full)).expect("valid record"))
    });
    c.bench_function("tach_decode/1.2M", |b| {
        b.iter(|| decode(black_box(&rec.tach), FS, 0.0, &TachOptions::default()).expect("clean tachometer"))
    });
}

criterion_group!(benches, bench_separation);
criterion_main!(benches);
