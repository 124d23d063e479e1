//! One model evaluation of a training case: `tests/data/train-02/model.yaml` run end to end
//! without the cache (both measured FRFs read, the baseline and jointed holder–tool each
//! reduced once to a substructure with two loss factors, spindle x and y, five couplings on
//! 4,000 lines).

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab::engine::{self, exec::RunOptions};
use std::path::Path;

fn bench(c: &mut Criterion) {
    let registry = spindlelab::registry();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/train-02/model.yaml");
    let compiled = engine::compile_file(&path, &registry).unwrap_or_else(|e| panic!("{}", e.render(false)));
    let out = tempfile::tempdir().expect("temporary folder");
    let mut opts = RunOptions::new(out.path());
    opts.use_cache = false;
    let mut group = c.benchmark_group("training_case");
    group.sample_size(20);
    group.bench_function("train_02_model_evaluation", |b| {
        b.iter(|| engine::run(&compiled, &registry, &opts, &|_, _| {}).expect("run"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
