//! Timing of the §2.1 impact simulation from first contact (dt = 1e-8 s over 5 ms).

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_stdlib::impact::{
    Hammer, ImpactSetup, ModalTarget, Table21Target, first_contact, simulate_from_contact, table_2_1_target,
};
use std::hint::black_box;

fn setup(target: ModalTarget) -> ImpactSetup {
    let mut s = ImpactSetup::new(Hammer { mass: 0.01, stiffness: 100.0, damping: 0.0 }, target);
    s.dt = 1.0e-8;
    s.duration = 5.0e-3;
    s.sample_rate = 100.0e3;
    s
}

fn bench_impact(c: &mut Criterion) {
    let one_mode = setup(ModalTarget::single(0.1, 1.0e7, 0.0));
    let table = setup(table_2_1_target(Table21Target::Target1));
    for (name, s) in [("impact/one_mode_5ms_dt1e-8", one_mode), ("impact/table2_1_target1_5ms_dt1e-8", table)] {
        let speed = -first_contact(&s).expect("hammer reaches the target").hammer_velocity;
        c.bench_function(name, |b| {
            b.iter(|| simulate_from_contact(black_box(&s), black_box(speed)).expect("valid setup"))
        });
    }
}

criterion_group!(benches, bench_impact);
criterion_main!(benches);
