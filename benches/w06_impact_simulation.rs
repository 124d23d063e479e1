//! W6 of the peer workloads (`bench-peers/README.md`): a 0.01 kg hammer on 100 N/m released at
//! +10 mm strikes a target whose surface sits at −3 mm, through Hertz contact of steel spheres
//! 6.35 mm / 1 mm with Lankarani–Nikravesh damping (e = 0.95); forward Euler at dt = 1e-8 s for
//! every one of the 500,000 steps (5 ms) from first contact. Targets: the 0.1 kg / 1e7 N/m SDOF,
//! and the peer's 10-mode target (f = 1592…17500 Hz, m = 0.1…2.5 kg, ζ = 0.01). Our step is the
//! semi-implicit Euler of Eq. 2.7 (velocity first), the peer's the explicit one: the same work per step.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_domain::Mode;
use spindlelab_stdlib::impact::{Hammer, ImpactSetup, ModalTarget, first_contact, simulate_from_contact};
use std::f64::consts::TAU;
use std::hint::black_box;

fn setup(target: ModalTarget) -> ImpactSetup {
    let mut s = ImpactSetup::new(Hammer { mass: 0.01, stiffness: 100.0, damping: 0.0 }, target);
    s.dt = 1.0e-8;
    s.duration = 5.0e-3;
    // Every step integrated, also after the hammer leaves (the peer's loop does not skip free flight).
    s.exact_free_flight = false;
    s
}

fn ten_modes() -> ModalTarget {
    let f = [1592.0, 3100.0, 4700.0, 6200.0, 7900.0, 9400.0, 11200.0, 13000.0, 15300.0, 17500.0];
    let m = [0.1, 0.3, 0.5, 0.4, 0.8, 1.0, 1.2, 1.5, 2.0, 2.5];
    let modes = (0..10)
        .map(|r| {
            let w = TAU * f[r];
            Mode::from_mass_stiffness_damping(m[r], m[r] * w * w, 2.0 * 0.01 * m[r] * w)
        })
        .collect();
    ModalTarget { modes }
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("w06_impact_simulation");
    for (name, s) in [
        ("sdof_500000_steps", setup(ModalTarget::single(0.1, 1.0e7, 0.0))),
        ("ten_modes_500000_steps", setup(ten_modes())),
    ] {
        let speed = -first_contact(&s).expect("hammer reaches the target").hammer_velocity;
        group.bench_function(name, |b| {
            b.iter(|| simulate_from_contact(black_box(&s), black_box(speed)).expect("valid setup"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
