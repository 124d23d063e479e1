//! `spindlelab crib` on the shipped catalog (`scripts/catalog/tool-crib.yaml` on
//! `scripts/lib/mill.yaml`) without the cache: 4 HSK-A63 holders × 6 end mills × 9 stickouts =
//! 216 combinations, from reading the catalog to the committed summary table, as the command
//! does it.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab::crib;
use spindlelab::engine::exec::RunOptions;
use std::path::Path;

fn bench(c: &mut Criterion) {
    let registry = spindlelab::registry();
    let scripts = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts");
    let (catalog, library) = (scripts.join("catalog/tool-crib.yaml"), scripts.join("lib/mill.yaml"));
    let out = tempfile::tempdir().expect("temporary folder");
    let mut group = c.benchmark_group("crib");
    group.sample_size(10);
    group.bench_function("crib_216_combinations", |b| {
        b.iter(|| {
            let machine = crib::machine(&library, None, &registry).unwrap_or_else(|e| panic!("{}", e.render(false)));
            let loaded = crib::load(&catalog, &machine, &registry).unwrap_or_else(|e| panic!("{}", e.render(false)));
            let recipe = catalog.with_file_name("tool-crib.recipe.yaml");
            let survey = crib::build(&loaded, &machine, recipe.parent().expect("a folder"));
            let text = crib::emit(&loaded, &machine, &survey);
            let compiled =
                crib::compile_text(&text, &recipe, &registry).unwrap_or_else(|e| panic!("{}", e.render(false)));
            let mut opts = RunOptions::new(out.path()).with_renderer(spindlelab::renderer());
            opts.use_cache = false;
            let ran = crib::run(&compiled, &loaded, &survey, &registry, opts, &|_, _| {})
                .unwrap_or_else(|e| panic!("{}", e.render(false)));
            assert_eq!(ran.table.rows(), 216);
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
