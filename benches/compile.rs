//! Compile time of a generated 200-step recipe: parse, resolve, validate and build the graph.

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

criterion_group!(benches, bench_compile);
criterion_main!(benches);
