//! A full diagnosis over the whole effect library, from the recipe `spindlelab import`
//! writes, for every training case: a sensor delay, a tool–holder joint (two FRFs, 39
//! trials), spindle stiffening with speed (eight FRFs at four speeds), a tip mass, fluted
//! stiffness, speed-dependent cutting coefficients, no effect, and a resonance outside the
//! library.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use std::path::Path;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let registry = spindlelab::registry();
    let mut group = c.benchmark_group("diagnose");
    group.sample_size(10).measurement_time(Duration::from_secs(60));
    let only = std::env::var("SPINDLELAB_BENCH_CASES").unwrap_or_default();
    let all = ["train_01", "train_02", "train_03", "train_04", "train_05", "train_06", "train_07", "train_08"];
    let chosen: Vec<&str> =
        all.into_iter().filter(|case| only.is_empty() || only.split(',').any(|c| c == *case)).collect();
    assert!(!chosen.is_empty(), "SPINDLELAB_BENCH_CASES={only:?} names no training case (train_01 … train_08)");
    for case in chosen {
        let from = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/training").join(case);
        let dir = tempfile::tempdir().expect("temporary folder");
        for entry in std::fs::read_dir(&from).expect("case folder") {
            let p = entry.expect("entry").path();
            if p.extension().is_some_and(|e| e == "csv") {
                std::fs::copy(&p, dir.path().join(p.file_name().expect("name"))).expect("copy");
            }
        }
        let json = std::fs::read_to_string(from.join("case.json")).expect("case");
        let recipe = spindlelab::import::recipe_from_case(&json, "case.json").expect("import");
        let path = dir.path().join("recipe.yaml");
        std::fs::write(&path, recipe).expect("write");
        group.bench_function(case, |b| b.iter(|| spindlelab::diagnose::diagnose(&path, &registry).expect("diagnosis")));
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
