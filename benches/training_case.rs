//! Training case train_02 (`tests/data/train-02/`), run without the cache:
//! - `train_02_model_evaluation`: `model.yaml` end to end (both measured FRFs read, the
//!   baseline and jointed holder–tool each reduced once to a substructure with two loss
//!   factors, spindle x and y, five couplings on 4,000 lines);
//! - `train_02_measured_set`: one model evaluation as a fit or a diagnosis makes it — the
//!   measurement set, one substructure, spindle and coupling fanned out over x and y;
//! - `train_02_nominal_recipe`: the whole recipe `spindlelab import` writes for the case
//!   (measured configuration, cutting configuration over 25 speeds × 2 directions,
//!   speed-dependent lobes, 39 trials scored).

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab::engine::{self, exec::RunOptions};
use std::path::Path;

fn bench(c: &mut Criterion) {
    let registry = spindlelab::registry();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/train-02");
    let out = tempfile::tempdir().expect("temporary folder");
    let mut opts = RunOptions::new(out.path()).with_renderer(spindlelab::renderer());
    opts.use_cache = false;
    let compile = |path: &Path| engine::compile_file(path, &registry).unwrap_or_else(|e| panic!("{}", e.render(false)));

    // The imported recipe, written beside copies of the case's data.
    let imported = tempfile::tempdir().expect("temporary folder");
    for f in ["frf_x_0rpm.csv", "frf_y_0rpm.csv", "trials.csv"] {
        std::fs::copy(dir.join(f), imported.path().join(f)).expect("copy");
    }
    let case = std::fs::read_to_string(dir.join("case.json")).expect("case");
    let recipe = spindlelab::import::recipe_from_case(&case, "case.json").expect("import");
    std::fs::write(imported.path().join("recipe.yaml"), recipe).expect("write");

    let mut group = c.benchmark_group("training_case");
    group.sample_size(20);
    for (id, path) in [
        ("train_02_model_evaluation", dir.join("model.yaml")),
        ("train_02_measured_set", dir.join("measured-set.yaml")),
        ("train_02_nominal_recipe", imported.path().join("recipe.yaml")),
    ] {
        let compiled = compile(&path);
        group.bench_function(id, |b| b.iter(|| engine::run(&compiled, &registry, &opts, &|_, _| {}).expect("run")));
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
