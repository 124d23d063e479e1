//! Measurements as labs have them: measured accelerances of a beam from another lab's files
//! (`../shared/data/measured/` beside the checkout, source and licence in its README; the tests
//! are skipped without it, except under CI), node and direction numbers, FRF kinds and cross
//! FRFs in the modal fit.

use crate::common;

use common::measured::{beam_file, recipe_file, run_recipe};
use common::{Ran, assert_has};
use spindlelab::engine::formats::{self, FileFormat, FrfSelect};
use spindlelab::engine::value::{Frf, FrfDofs, Table};
use std::path::Path;
use std::process::{Command, Output};

/// Runs `recipe` through the binary into `DIR/out`; returns the folder and the process output.
fn run_binary(beam: &Path, recipe: &str) -> (tempfile::TempDir, Output) {
    let (dir, path) = recipe_file(beam, recipe);
    let o = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(["run", "--no-cache", "-o"])
        .arg(dir.path().join("out"))
        .arg(&path)
        .env("NO_COLOR", "1")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stderr).into_owned() + String::from_utf8_lossy(&o.stdout).as_ref();
    assert!(!text.contains("panicked"), "{text}");
    (dir, o)
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned() + String::from_utf8_lossy(&o.stdout).as_ref()
}

fn column<'a>(t: &'a Table, name: &str) -> &'a [f64] {
    &t.columns.iter().find(|c| c.name == name).unwrap_or_else(|| panic!("no column {name}")).values
}

fn warnings(ran: &Ran, step: &str) -> Vec<String> {
    let i = ran.compiled.graph.by_step[step][0];
    ran.report.result.outcomes[i].warnings().to_vec()
}

fn read(path: &Path, select: FrfSelect) -> Frf {
    formats::read_frf(path, FileFormat::Uff, &select).unwrap_or_else(|e| panic!("{e}")).value
}

/// Natural frequencies (Hz) of the three FRFs, each fitted alone by sdypy-EMA 0.x (LSCF poles,
/// `pol_order_high=60`, 10–1000 Hz, `frf_form='accelerance'`, the poles nearest the six peaks of
/// the summed |H|), and the signs of their modal constants (`sign(−Im A)` of `get_constants`):
///
/// ```python
/// import numpy as np, pyuff, sdypy.EMA as EMA
/// d = pyuff.UFF('beam-accelerance.uff').read_sets()
/// freq = d[0]['x']; H = np.array([s['data'] for s in d])
/// for i in range(3):
///     a = EMA.Model(frf=H[i:i+1], freq=freq, lower=10, upper=1000, pol_order_high=60, frf_form='accelerance')
///     a.get_poles(show_progress=False)
///     a.select_closest_poles([52, 142, 279, 460, 687, 959])
///     a.get_constants(whose_poles='own', FRF_ind='all')
///     print(a.nat_freq, np.sign(-a.A.imag))
/// ```
const SDYPY_EMA_HZ: [[f64; 6]; 3] = [
    [51.5117, 142.1760, 278.6616, 460.4034, 687.1688, 958.5439],
    [51.5229, 142.1789, 278.6867, 460.3928, 687.1860, 958.5461],
    [51.5248, 142.1698, 278.6572, 460.3811, 687.1587, 958.5135],
];
const SDYPY_EMA_SIGNS: [[f64; 6]; 3] =
    [[1., -1., 1., -1., 1., -1.], [1., -1., 1., 1., -1., 1.], [1., -1., -1., 1., -1., 1.]];

#[test]
fn default_fit_of_measured_beam_accelerances_matches_sdypy_ema() {
    let Some(beam) = beam_file("the fit of each measured beam accelerance against sdypy-EMA") else { return };
    for (k, reference) in [1, 2, 3].into_iter().enumerate() {
        let (_d, ran) = run_recipe(
            &beam,
            &format!(
                "spindlelab: 1\nname: beam\nsteps:\n  beam:\n    kind: read.frf\n    params: {{ file: BEAM, reference: {reference} }}\n  fit:\n    kind: modal.fit\n    inputs: {{ frf: \"@beam.frf\" }}\n"
            ),
        );
        let t = ran.table("fit", "modal_table");
        let (f, m) = (column(&t, "frequency"), column(&t, "modal_mass"));
        assert_eq!(f.len(), 6, "reference {reference}: {f:?}");
        for j in 0..6 {
            let want = SDYPY_EMA_HZ[k][j];
            assert!(
                (f[j] / want - 1.0).abs() <= 1e-3,
                "reference {reference}: {} Hz against sdypy-EMA's {want} Hz",
                f[j]
            );
            assert_eq!(m[j].signum(), SDYPY_EMA_SIGNS[k][j], "reference {reference}, mode {j}: modal mass {}", m[j]);
        }
        // Half-power widths of 0.02–0.3 Hz on 1 Hz lines: no damping is reported, and the warning says why.
        assert!(column(&t, "damping_ratio").iter().all(|z| z.is_nan()));
        let w = warnings(&ran, "fit").join("\n");
        assert_has(&w, &["below the resolution of the 1.000 Hz lines", "negative modal constants"]);
        if reference == 1 {
            assert_has(&w, &["a driving point by its node numbers (response 1 x, reference 1 x)"]);
        }
        assert!(!w.contains("clips"), "{w}");
        // Both measures of fit quality, in the accelerance the lab measured.
        let q = ran.table("fit", "residual_terms");
        let global = column(&q, "relative_residual")[0];
        assert!(global < 0.1, "reference {reference}: global relative L2 {global}");
        assert!(column(&q, "weighted_residual")[0].is_finite());
    }
}

#[test]
fn read_frf_selects_by_node_numbers_and_writes_them_back_through_the_binary() {
    let Some(beam) = beam_file("the selection of measured FRFs by node numbers") else { return };
    let (dir, o) = run_binary(
        &beam,
        "spindlelab: 1\nname: nodes\nsteps:\n  beam:\n    kind: read.frf\n    params: { file: BEAM, response: 1, reference: 3 }\noutputs:\n  - { from: \"@beam.frf\", file: beam.uff }\n  - { from: \"@beam.frf\", file: beam.csv }\n",
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let want = FrfDofs { response_node: 1, response_direction: 1, reference_node: 3, reference_direction: 1 };
    let original = read(&beam, FrfSelect { dataset: Some(3), ..Default::default() });
    let out = dir.path().join("out");
    let uff = read(&out.join("beam.uff"), FrfSelect::default());
    assert_eq!(uff.dofs, Some(want));
    assert_eq!(uff.unit.symbol, "m/s^2/N");
    for (a, b) in uff.values.iter().zip(&original.values) {
        assert!((a - b).norm() <= 1e-12 * b.norm().max(1e-300), "{a} {b}");
    }
    let csv = formats::read_frf(&out.join("beam.csv"), FileFormat::Csv, &FrfSelect::default()).unwrap().value;
    assert_eq!(csv.dofs, Some(want));
    assert_eq!(csv.values, original.values);
    // A node the file does not hold: exit 2, and the datasets listed with their node numbers.
    let (_d, o) = run_binary(
        &beam,
        "spindlelab: 1\nname: nodes\nsteps:\n  beam:\n    kind: read.frf\n    params: { file: BEAM, reference: 9 }\n",
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert_has(&text(&o), &["no FRF with reference node 9", "response 1 x, reference 3 x (line 1032)"]);
}

#[test]
fn frf_convert_takes_a_measured_accelerance_to_receptance_through_the_binary() {
    let Some(beam) = beam_file("the conversion of a measured accelerance") else { return };
    let (dir, o) = run_binary(
        &beam,
        "spindlelab: 1\nname: convert\nsteps:\n  beam:\n    kind: read.frf\n    params: { file: BEAM, reference: 2 }\n  receptance:\n    kind: frf.convert\n    params: { to: receptance }\n    inputs: { frf: \"@beam.frf\" }\n  back:\n    kind: frf.convert\n    params: { to: accelerance }\n    inputs: { frf: \"@receptance.frf\" }\noutputs:\n  - { from: \"@receptance.frf\", file: receptance.uff }\n  - { from: \"@back.frf\", file: back.uff }\n",
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert_has(&text(&o), &["0 Hz line has no receptance"]);
    let a = read(&beam, FrfSelect { dataset: Some(2), ..Default::default() });
    let out = dir.path().join("out");
    let h = read(&out.join("receptance.uff"), FrfSelect::default());
    assert_eq!(h.unit.symbol, "m/N");
    assert_eq!(h.freq_hz.len(), a.freq_hz.len() - 1);
    assert_eq!(h.freq_hz[0], 1.0);
    // H = A/(iω)² = −A/ω², line by line.
    for ((f, hk), ak) in h.freq_hz.iter().zip(&h.values).zip(&a.values[1..]) {
        let w = std::f64::consts::TAU * f;
        assert!((hk * (-w * w) - ak).norm() <= 1e-11 * ak.norm(), "{f} Hz");
    }
    let back = read(&out.join("back.uff"), FrfSelect::default());
    assert_eq!(back.unit.symbol, "m/s^2/N");
    assert_eq!(back.dofs, a.dofs);
    // Comparing different kinds is refused with the conversion to use.
    let (_d, o) = run_binary(
        &beam,
        "spindlelab: 1\nname: kinds\nsteps:\n  beam:\n    kind: read.frf\n    params: { file: BEAM, reference: 2 }\n  receptance:\n    kind: frf.convert\n    params: { to: receptance }\n    inputs: { frf: \"@beam.frf\" }\n  compare:\n    kind: frf.compare\n    inputs: { frf: \"@receptance.frf\", reference: \"@beam.frf\" }\n",
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert_has(&text(&o), &["FRFs of different kinds cannot be compared", "frf.convert"]);
}
