//! `scripts/tool-crib.rhai` end to end without the cache: 4 holders × 5 end mills × 10
//! stickouts = 200 combinations coupled to one spindle (tool-point FRFs in x and y on 4,800
//! lines), zero-order lobes at 401 speeds and the best cut of each — 802 node instances.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab::engine::{self, exec::RunOptions};
use std::path::Path;

fn bench(c: &mut Criterion) {
    let registry = spindlelab::registry();
    let recipe = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/tool-crib.rhai");
    let compiled = engine::compile_file(&recipe, &registry).unwrap_or_else(|e| panic!("{}", e.render(false)));
    let out = tempfile::tempdir().expect("temporary folder");
    let mut opts = RunOptions::new(out.path()).with_renderer(spindlelab::renderer());
    opts.use_cache = false;
    let mut group = c.benchmark_group("tool_crib");
    group.sample_size(10);
    group.bench_function("tool_crib_200_combinations", |b| {
        b.iter(|| engine::run(&compiled, &registry, &opts, &|_, _| {}).expect("the tool crib runs"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
