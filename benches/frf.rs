//! Timing of FRF estimation (§3.1.2–3.1.4): 20 impacts of 65,536 samples with windows,
//! H1 averaging and coherence.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_stdlib::frf::{FrfEstimator, FrfOptions, ImpactRecord};
use spindlelab_stdlib::impact::{Hammer, ImpactSetup, ModalTarget, SensorNoise, simulate};
use std::hint::black_box;

const LEN: usize = 65_536;
const FS: f64 = 100.0e3;

fn bench_frf(c: &mut Criterion) {
    let records: Vec<(Vec<f64>, Vec<f64>)> = (0..20u64)
        .map(|seed| {
            let mut s = ImpactSetup::new(
                Hammer { mass: 0.05, stiffness: 0.0, damping: 0.0 },
                ModalTarget::single(0.1, 5.0e7, 90.0),
            );
            s.release_position = s.contact_position + 1.0e-3;
            s.release_velocity = -0.5;
            s.pre_trigger = 1.0e-3;
            s.duration = (LEN - 100) as f64 / FS;
            s.sample_rate = FS;
            s.noise = Some(SensorNoise { std_dev: 25.0e-9, seed });
            let r = simulate(&s).expect("valid setup");
            (r.force, r.target_displacement)
        })
        .collect();
    let views: Vec<ImpactRecord<'_>> = records.iter().map(|(f, x)| ImpactRecord { force: f, response: x }).collect();
    let mut estimator = FrfEstimator::new(LEN, FS).expect("valid length");
    let options = FrfOptions::default();
    c.bench_function("frf/20x65536", |b| {
        b.iter(|| estimator.estimate(black_box(&views), black_box(&options)).expect("valid records"))
    });
}

criterion_group!(benches, bench_frf);
criterion_main!(benches);
