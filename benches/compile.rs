//! Compile time of a generated 200-step recipe (parse, resolve, validate and build the
//! graph), and how fast bad recipes are refused: a 50 MB recipe (refused by its size, never
//! parsed) and a Rhai recipe that never ends (stopped by the operation limit).

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use std::fmt::Write as _;
use std::hint::black_box;

/// A recipe with 100 impact simulations, each followed by an FRF estimate (200 steps).
fn recipe_200_steps() -> String {
    let mut s = String::from(
        "spindlelab: 1\nname: bench-200\nmaterials:\n  steel: { E: 200 GPa, rho: 7800 kg/m^3, nu: 0.29 }\nsteps:\n",
    );
    for i in 0..100 {
        let _ = write!(
            s,
            "  hit{i}:\n    kind: impact.simulate\n    params:\n      hammer_mass: {} kg\n      hammer_stiffness: 500 N/m\n      target_mass: 0.1 kg\n      target_stiffness: 5e7 N/m\n      tip_material: steel\n      duration: 5 ms\n",
            0.01 + 0.0005 * i as f64
        );
        let _ = write!(
            s,
            "  frf{i}:\n    kind: frf.estimate\n    params: {{ force_window: 6.5 ms, response_decay: 0.113 s }}\n    inputs: {{ force: \"@hit{i}.force\", response: \"@hit{i}.displacement\" }}\n"
        );
    }
    s.push_str("outputs:\n  - { from: \"@frf0.frf\", file: frf0.csv }\n");
    s
}

fn bench_compile(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("bench-200.yaml");
    std::fs::write(&path, recipe_200_steps()).expect("write recipe");
    let registry = spindlelab::registry();
    c.bench_function("compile/200_steps", |b| {
        b.iter(|| {
            let compiled = spindlelab::engine::compile_file(black_box(&path), &registry).expect("compiles");
            black_box(compiled.graph.instances.len())
        })
    });
}

fn bench_refusals(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temp dir");
    let huge = dir.path().join("huge.yaml");
    let mut text = String::from("spindlelab: 1\nname: huge\nsteps:\n");
    let mut i = 0;
    while text.len() < 50 * 1024 * 1024 {
        let _ = write!(
            text,
            "  hit{i}:\n    kind: impact.simulate\n    params: {{ hammer_mass: 0.01 kg, target_mass: 0.1 kg, target_stiffness: 1e7 N/m }}\n"
        );
        i += 1;
    }
    std::fs::write(&huge, text).expect("write recipe");
    let forever = dir.path().join("forever.rhai");
    std::fs::write(&forever, "let x = 0;\nloop {\n    x += 1;\n}\n").expect("write recipe");
    let registry = spindlelab::registry();
    let mut g = c.benchmark_group("refuse");
    g.sample_size(10);
    for (name, path) in [("50_mb_recipe", &huge), ("endless_rhai", &forever)] {
        g.bench_function(name, |b| {
            b.iter(|| black_box(spindlelab::engine::compile_file(black_box(path), &registry).is_err()))
        });
    }
    g.finish();
}

criterion_group!(benches, bench_compile, bench_refusals);
criterion_main!(benches);
