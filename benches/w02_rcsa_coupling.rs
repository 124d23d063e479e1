//! W2 of the peer workloads (`bench-peers/README.md`): the W1 tool-holder (modal receptances of
//! its 52-element mesh, one loss factor 0.0015) coupled to a spindle whose free-end receptance is
//! the sum of eight clamped-free steel Euler–Bernoulli beams (f1 = 500…5000 Hz, d = 110…70 mm,
//! η = 0.05…0.02), on 10,000 lines `linspace(1 Hz, 10 kHz)`. Timed: the coupling only, rigid and
//! through a joint `diag(2e8 N/m, 1e6 N·m/rad)`. The peer's joint loss is hysteretic
//! (`1 + 0.05i`); our interface takes viscous damping, so the joint here has `c = 0.05 k/ω` at
//! 1 kHz: the same arithmetic per line, slightly different flexible-joint values.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_domain::entity::SpindleMode;
use spindlelab_domain::{Material, Speed};
use spindlelab_stdlib::beam::table::{tool_holder_sections, w01_segments};
use spindlelab_stdlib::beam::{BeamModel, MeshOptions};
use spindlelab_stdlib::eb_modes::spindle_receptance;
use spindlelab_stdlib::rcsa::{Interface, RcsaOptions, Receptance, TwoPort, couple};
use std::f64::consts::TAU;
use std::hint::black_box;

fn holder(freqs: &[f64]) -> TwoPort {
    let mesh = MeshOptions { max_element_length: 1.0, min_taper_elements: 1, ..MeshOptions::default() };
    let model = BeamModel::from_segments(&w01_segments(&tool_holder_sections()), &mesh).expect("valid sections");
    let modes = model.modes().expect("modes");
    let tip = model.n_nodes() - 1;
    let r = |a: usize, b: usize| -> Vec<Receptance> {
        modes
            .receptance(a, b, freqs)
            .expect("receptance")
            .iter()
            .map(|m| Receptance::new(m[0][0], m[0][1], m[1][0], m[1][1]))
            .collect()
    };
    TwoPort { freqs_hz: freqs.to_vec(), r11: r(tip, tip), r12: r(tip, 0), r21: r(0, tip), r22: r(0, 0) }
}

fn bench(c: &mut Criterion) {
    let freqs: Vec<f64> = (0..10_000).map(|k| 1.0 + 9999.0 * k as f64 / 9999.0).collect();
    let holder = holder(&freqs);
    let f1 = [500.0, 900.0, 1300.0, 1900.0, 2500.0, 3200.0, 4100.0, 5000.0];
    let d = [0.110, 0.100, 0.095, 0.090, 0.085, 0.080, 0.075, 0.070];
    let eta = [0.05, 0.045, 0.04, 0.035, 0.03, 0.025, 0.022, 0.02];
    let modes: Vec<SpindleMode> = (0..8).map(|i| SpindleMode::new(f1[i], d[i], eta[i])).collect();
    let spindle = spindle_receptance(&modes, &Material::STEEL, Speed::ZERO, Speed::from_rpm(10_000.0), &freqs, None)
        .expect("valid modes");
    let w_ref = TAU * 1000.0;
    let joint = Interface::diagonal(2e8, 0.05 * 2e8 / w_ref, 1e6, 0.05 * 1e6 / w_ref);
    let options = RcsaOptions::default();
    let mut group = c.benchmark_group("w02_rcsa_coupling");
    group.bench_function("rigid_and_flexible_10000_lines", |b| {
        b.iter(|| {
            let rigid = couple(black_box(&holder), black_box(&spindle), &Interface::Rigid, &options).expect("ok");
            let flexible = couple(black_box(&holder), black_box(&spindle), &joint, &options).expect("ok");
            (rigid, flexible)
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
