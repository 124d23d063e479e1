//! `scripts/rotor-spindle.yaml` end to end without the cache: the rotor spindle's Campbell table
//! (21 speeds), its nose receptance at five speeds in x and y (2,500 lines, banded solves of
//! 52 dof), the spinning tool holder coupled in whirl coordinates, and the speed-dependent lobes
//! at 1,501 speeds — 22 node instances.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab::engine::{self, exec::RunOptions};
use std::path::Path;

fn bench(c: &mut Criterion) {
    let registry = spindlelab::registry();
    let recipe = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/rotor-spindle.yaml");
    let compiled = engine::compile_file(&recipe, &registry).unwrap_or_else(|e| panic!("{}", e.render(false)));
    let out = tempfile::tempdir().expect("temporary folder");
    let mut opts = RunOptions::new(out.path()).with_renderer(spindlelab::renderer());
    opts.use_cache = false;
    let mut group = c.benchmark_group("rotor");
    group.sample_size(10);
    group.bench_function("rotor_spindle_recipe", |b| {
        b.iter(|| engine::run(&compiled, &registry, &opts, &|_, _| {}).expect("the rotor spindle runs"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
