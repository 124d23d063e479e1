//! Timing of the virtual rig (dissertation chapters 2–3): one recording of 20 impacts ×
//! 65,536 samples at 100 kHz with tach, force and three capacitance probes, every source on.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_stdlib::rig::{RigConfig, simulate};
use std::hint::black_box;

fn bench_rig(c: &mut Criterion) {
    let config = RigConfig::default();
    assert_eq!(config.impacts, 20);
    assert_eq!(config.samples().expect("valid config"), 20 * 65_536);
    let mut group = c.benchmark_group("rig");
    group.sample_size(20);
    group.bench_function("simulate/20x65536x3", |b| {
        b.iter(|| simulate(black_box(&config), black_box(7)).expect("valid config"))
    });
    group.finish();
}

criterion_group!(benches, bench_rig);
criterion_main!(benches);
