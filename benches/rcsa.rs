//! Timing of receptance coupling (§5.1): inverse RCSA of a spindle from an artifact measurement (Eq. 5.4)
//! followed by coupling a tool through a flexible joint (Eqs. 5.3, 5.16–5.17), on 10,000 frequency lines.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_domain::entity::SpindleMode;
use spindlelab_domain::{Material, Speed};
use spindlelab_stdlib::eb_modes::spindle_receptance;
use spindlelab_stdlib::rcsa::{Complex64, Interface, RcsaOptions, Receptance, TwoPort, couple, decouple};
use std::f64::consts::TAU;
use std::hint::black_box;

const LINES: usize = 10_000;

/// Free-free rigid body: `R_PQ = −ω⁻² T_P diag(1/m, 1/j) T_Qᵀ` with tip at `x1`, joint at 0, centre at `xg`.
fn rigid_body(freqs: &[f64], m: f64, j: f64, x1: f64, xg: f64) -> TwoPort {
    let block = |xp: f64, xq: f64, f: f64| {
        let (a, b, s) = (xp - xg, xq - xg, -1.0 / (TAU * f).powi(2));
        Receptance::new(
            Complex64::from(s * (1.0 / m + a * b / j)),
            Complex64::from(s * a / j),
            Complex64::from(s * b / j),
            Complex64::from(s / j),
        )
    };
    TwoPort {
        freqs_hz: freqs.to_vec(),
        r11: freqs.iter().map(|&f| block(x1, x1, f)).collect(),
        r12: freqs.iter().map(|&f| block(x1, 0.0, f)).collect(),
        r21: freqs.iter().map(|&f| block(0.0, x1, f)).collect(),
        r22: freqs.iter().map(|&f| block(0.0, 0.0, f)).collect(),
    }
}

fn bench_rcsa(c: &mut Criterion) {
    let freqs: Vec<f64> = (1..=LINES).map(|i| i as f64).collect();
    let modes = [
        SpindleMode::new(700.0, 0.11, 0.05),
        SpindleMode::new(1900.0, 0.07, 0.04),
        SpindleMode::new(3300.0, 0.05, 0.03),
    ];
    let spindle = spindle_receptance(&modes, &Material::STEEL, Speed::ZERO, Speed::from_rpm(10_000.0), &freqs, None)
        .expect("valid modes");
    let artifact = rigid_body(&freqs, 1.2, 1.5e-3, 0.08, 0.03);
    let tool = rigid_body(&freqs, 0.3, 1e-4, 0.1, 0.04);
    let options = RcsaOptions::default();
    let measured = couple(&artifact, &spindle, &Interface::Rigid, &options).expect("well conditioned");
    let joint = Interface::diagonal(1.5e8, 250.0, 3e5, 4.0);
    c.bench_function("rcsa/decouple+couple/10000", |b| {
        b.iter(|| {
            let sp = decouple(black_box(&artifact), black_box(&measured), &Interface::Rigid, &options).expect("ok");
            couple(black_box(&tool), &sp, &joint, &options).expect("ok")
        })
    });
    c.bench_function("eb_modes/3 modes/10000", |b| {
        b.iter(|| {
            spindle_receptance(
                black_box(&modes),
                &Material::STEEL,
                Speed::ZERO,
                Speed::from_rpm(10_000.0),
                &freqs,
                None,
            )
            .expect("ok")
        })
    });
}

criterion_group!(benches, bench_rcsa);
criterion_main!(benches);
