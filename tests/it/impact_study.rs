//! §2.1.3 at the settings of `scripts/mdof-hammer-mass.rhai`: on both Table 2.1 targets a
//! heavier hammer gives a longer first contact and excites a narrower band. The 50 ms record
//! catches a light hammer's return hits; those are flagged as a double hit, as a lab rejects
//! one, and the first contact is reported beside the whole train.

use crate::common::run;
use std::path::Path;

#[test]
fn the_hammer_mass_study_shows_the_trends_of_2_1_3_on_the_first_contact() {
    let ran = run(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/mdof-hammer-mass.rhai"));
    for target in 1..=2 {
        let at = |mass: usize, port: &str| ran.scalar(&format!("hit_t{target}_m{mass}"), port).value;
        let masses = [0.001, 0.01, 0.1];
        let times: Vec<f64> = (0..3).map(|m| at(m, "first_impulse_time")).collect();
        let bands: Vec<f64> = (0..3).map(|m| at(m, "first_excited_bandwidth")).collect();
        for m in 1..3 {
            assert!(
                times[m] > times[m - 1],
                "target {target}: the {} kg hammer's first contact {} s is not longer than the {} kg hammer's {} s",
                masses[m],
                times[m],
                masses[m - 1],
                times[m - 1]
            );
            assert!(
                bands[m] < bands[m - 1],
                "target {target}: the {} kg hammer excites {} Hz, not less than the {} kg hammer's {} Hz",
                masses[m],
                bands[m],
                masses[m - 1],
                bands[m - 1]
            );
        }
        // A first contact lasts well under a millisecond, and excites kilohertz.
        assert!(times.iter().all(|t| *t > 0.0 && *t < 1e-3), "target {target}: {times:?}");
        assert!(bands.iter().all(|b| *b > 1e3), "target {target}: {bands:?}");
        // Where the record holds more than one contact, the step says it is a double hit.
        for m in 0..3 {
            let step = format!("hit_t{target}_m{m}");
            let i = ran.compiled.graph.by_step[&step][0];
            let said = ran.report.result.outcomes[i].warnings().join("\n");
            let contacts = at(m, "contacts");
            assert_eq!(contacts > 1.0, said.contains("double hit"), "{step}: {contacts} contacts; {said}");
            if contacts > 1.0 {
                assert!(at(m, "impulse_time") > at(m, "first_impulse_time"), "{step}");
            }
        }
    }
}
