//! Timing of the Timoshenko beam receptances (§5.1, §5.4): Table 5.1 tool-holder (112 dof),
//! tip receptance block over 10,000 frequency lines by modal expansion, the direct (banded)
//! solve, and the spinning model's receptance and Campbell table.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_stdlib::beam::{
    BeamModel, MeshOptions, SpinningModel, segments_from_sections, table::tool_holder_sections,
};
use std::hint::black_box;

fn bench_beam(c: &mut Criterion) {
    let model = BeamModel::from_segments(&segments_from_sections(&tool_holder_sections()), &MeshOptions::default())
        .expect("valid sections");
    let freqs: Vec<f64> = (1..=10_000).map(|k| k as f64 * 2.0).collect();
    let modes = model.modes().expect("positive definite mass");
    let tip = model.n_nodes() - 1;
    c.bench_function("beam/modes_tool_holder", |b| b.iter(|| black_box(&model).modes().expect("modes")));
    c.bench_function("beam/modal_10000_lines", |b| {
        b.iter(|| modes.receptance(black_box(tip), black_box(tip), black_box(&freqs)).expect("receptance"))
    });
    let lines: Vec<f64> = (1..=1000).map(|k| k as f64 * 20.0).collect();
    c.bench_function("beam/direct_1000_lines", |b| {
        b.iter(|| model.receptance_direct(black_box(tip), black_box(0), black_box(&lines)).expect("receptance"))
    });
    let spinning = SpinningModel::new(model.clone());
    c.bench_function("beam/spinning_1000_lines", |b| {
        b.iter(|| spinning.receptance(black_box(tip), black_box(tip), 2000.0, black_box(&lines)).expect("receptance"))
    });
    let mut group = c.benchmark_group("beam_campbell");
    group.sample_size(10);
    group.bench_function("beam/campbell_1_speed", |b| {
        b.iter(|| spinning.campbell(black_box(&[2000.0])).expect("whirl"))
    });
    group.finish();
}

criterion_group!(benches, bench_beam);
criterion_main!(benches);
