//! A measurement set fitted as one: the three measured beam accelerances of
//! `../shared/data/measured/` beside the checkout (source and licence in its README; the tests
//! are skipped without it, except under CI) read as one FRF set, their poles shared
//! (`modal.fit_set`), validated against sdypy-EMA's joint fit; the set written as UFF and CSV and
//! read back with its node numbers; FRFs on different grids refused.

use crate::common;

use common::measured::{beam_file, recipe_file, run_recipe};
use common::{Ran, assert_has, run_at};
use spindlelab::engine::formats::{self, FileFormat, FrfSelect};
use spindlelab::engine::value::{Frf, FrfDofs, FrfSet, Table, UnitLabel, Value};
use std::path::Path;
use std::process::{Command, Output};

/// Runs the recipe file `path` through the binary into `out`.
fn run_binary(path: &Path, out: &Path) -> Output {
    let o = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(["run", "--no-cache", "-o"])
        .arg(out)
        .arg(path)
        .env("NO_COLOR", "1")
        .output()
        .unwrap();
    assert!(!text(&o).contains("panicked"), "{}", text(&o));
    o
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned() + String::from_utf8_lossy(&o.stdout).as_ref()
}

fn column<'a>(t: &'a Table, name: &str) -> &'a [f64] {
    &t.columns.iter().find(|c| c.name == name).unwrap_or_else(|| panic!("no column {name}")).values
}

fn warnings(ran: &Ran, step: &str) -> String {
    let i = ran.compiled.graph.by_step[step][0];
    ran.report.result.outcomes[i].warnings().join("\n")
}

/// Natural frequencies (Hz) of the three FRFs fitted together by sdypy-EMA 0.31 (pyuff 2.5):
/// one LSCF common denominator over the three FRFs (`pol_order_high=60`, 10–1000 Hz),
/// the poles nearest six approximate frequencies, LSFD residues per FRF in accelerance form; the
/// signs of the modal constants (`sign(−Im A)`), and the global relative L2 residual
/// `‖H − H_rec‖/‖H‖` of the reconstruction over the three FRFs on the LSFD lines (10–998 Hz):
///
/// ```python
/// import numpy as np, pyuff, sdypy.EMA as EMA
/// d = pyuff.UFF('beam-accelerance.uff').read_sets()
/// freq = d[0]['x']; H = np.array([s['data'] for s in d])
/// a = EMA.Model(frf=H, freq=freq, lower=10, upper=1000, pol_order_high=60, frf_form='accelerance')
/// a.get_poles(show_progress=False)
/// a.select_closest_poles([52, 142, 279, 460, 687, 959])
/// H_rec, A = a.get_constants(whose_poles='own', FRF_ind='all')
/// print(a.nat_freq, np.sign(-A.imag))
/// band = slice(10, 999)
/// print(np.linalg.norm(H[:, band] - H_rec[:, band]) / np.linalg.norm(H[:, band]))
/// ```
const SDYPY_EMA_JOINT_HZ: [f64; 6] = [51.5172, 142.1765, 278.6626, 460.3949, 687.1659, 958.5330];
const SDYPY_EMA_JOINT_SIGNS: [[f64; 6]; 3] =
    [[1., -1., 1., -1., 1., -1.], [1., -1., 1., 1., -1., 1.], [1., -1., -1., 1., -1., 1.]];
const SDYPY_EMA_JOINT_RESIDUAL: f64 = 0.032534;

/// The same band and highest order as sdypy-EMA (`upper=1000` keeps the lines below 1000 Hz;
/// `pol_order_high=60` reaches 120 poles); `POLES` picks the poles: nearest given frequencies,
/// or (empty) nearest the peaks of the summed |H|.
const JOINT: &str = "spindlelab: 1\nname: beam-set\nsteps:\n  beam:\n    kind: read.frf_set\n    params: { file: BEAM }\n  fit:\n    kind: modal.fit_set\n    params: { min_frequency: 10 Hz, max_frequency: 999 Hz, max_order: 120POLES }\n    inputs: { set: \"@beam.set\" }\n";

#[test]
fn joint_fit_of_three_measured_beam_accelerances_matches_sdypy_ema() {
    let Some(beam) = beam_file("the joint fit of the measured beam accelerances against sdypy-EMA") else { return };
    let given = ", frequencies: [52 Hz, 142 Hz, 279 Hz, 460 Hz, 687 Hz, 959 Hz]";
    for poles in [given, ""] {
        let (_d, ran) = run_recipe(&beam, &JOINT.replace("POLES", poles));
        let t = ran.table("fit", "modal_table");
        let f = column(&t, "frequency");
        assert_eq!(f.len(), 6, "{poles:?}: {f:?}");
        for (got, want) in f.iter().zip(SDYPY_EMA_JOINT_HZ) {
            assert!((got / want - 1.0).abs() <= 1e-3, "{poles:?}: {got} Hz against sdypy-EMA's {want} Hz");
        }
        // One row per FRF and mode, the FRF's nodes beside it; modal constants signed as sdypy-EMA's.
        let r = ran.table("fit", "residues");
        let (frf, mass) = (column(&r, "frf"), column(&r, "modal_mass"));
        assert_eq!(frf.len(), 18);
        assert_eq!(column(&r, "reference_node"), [[1.0; 6], [2.0; 6], [3.0; 6]].concat());
        assert!(column(&r, "response_node").iter().all(|&n| n == 1.0));
        for (k, m) in mass.iter().enumerate() {
            assert_eq!(m.signum(), SDYPY_EMA_JOINT_SIGNS[k / 6][k % 6], "FRF {}, mode {}: {m}", k / 6 + 1, k % 6 + 1);
        }
        // The LSFD on the shared poles reproduces the lines at least as closely as sdypy-EMA's.
        let q = ran.table("fit", "quality");
        let global = column(&q, "relative_residual")[0];
        assert!(global <= SDYPY_EMA_JOINT_RESIDUAL, "{poles:?}: global relative L2 {global}");
        // 0.02–0.3 Hz half-power widths on 1 Hz lines: no damping in the table, and the warning says why.
        assert!(column(&t, "damping_ratio").iter().all(|z| z.is_nan()));
        let w = warnings(&ran, "fit");
        assert_has(&w, &["below the resolution of the 1.000 Hz lines"]);
        // FRF 1 is labelled a driving point (response and reference node 1 in x), which its signs deny.
        assert_has(&w, &["FRF 1 is a driving point by its node numbers (response 1 x, reference 1 x)"]);
        // The diagram: every order up to 120, the six selected poles among its stable ones.
        let s = ran.table("fit", "stabilisation");
        let (order, selected, stable) = (column(&s, "order"), column(&s, "selected"), column(&s, "stable_damping"));
        assert_eq!(order.iter().copied().fold(0.0, f64::max), 120.0);
        assert_eq!(selected.iter().filter(|&&v| v == 1.0).count(), 6);
        assert!(selected.iter().zip(stable).all(|(s, d)| *s == 0.0 || *d == 1.0));
    }
}

/// Two FRFs of a set on its own nodes, for the binary tests.
fn small_set(shift: f64) -> Vec<Frf> {
    (1..=2)
        .map(|k| Frf {
            freq_hz: (0..64).map(|i| (1.0 + if k == 2 { shift } else { 0.0 }) * i as f64).collect(),
            values: (0..64)
                .map(|i| num_complex::Complex64::new(k as f64 / (1.0 + i as f64), -0.01 * i as f64))
                .collect(),
            coherence: None,
            unit: UnitLabel::new("m/s^2/N"),
            direction: Some("y".into()),
            speed: None,
            sensor: None,
            dofs: Some(FrfDofs {
                response_node: 11,
                response_direction: 2,
                reference_node: 20 + k,
                reference_direction: 3,
            }),
        })
        .collect()
}

#[test]
fn a_set_output_reads_back_from_uff_and_csv_with_its_node_numbers_through_the_binary() {
    let Some(beam) = beam_file("the measured set written and read back") else { return };
    let (dir, path) = recipe_file(
        &beam,
        "spindlelab: 1\nname: set\nsteps:\n  beam:\n    kind: read.frf_set\n    params: { file: BEAM, response: 1 }\n  fit:\n    kind: modal.fit_set\n    params: { min_frequency: 10 Hz, max_frequency: 999 Hz, modes: 6 }\n    inputs: { set: \"@beam.set\" }\noutputs:\n  - { from: \"@beam.set\", file: set.uff }\n  - { from: \"@beam.set\", file: set.csv }\n  - { from: \"@fit.fitted\", file: fitted.uff }\n  - { from: \"@fit.stabilisation\", file: stabilisation.csv }\n  - { from: \"@fit.stabilisation\", with: \"@beam.set\", file: stabilisation.svg }\n  - { from: \"@beam.set\", with: \"@fit.fitted\", file: set.svg }\n",
    );
    let out = dir.path().join("out");
    let o = run_binary(&path, &out);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let original = formats::read_frf_set(&beam, FileFormat::Uff, &FrfSelect::default()).unwrap().value;
    let read = |name: &str, format| -> FrfSet {
        formats::read_frf_set(&out.join(name), format, &FrfSelect::default()).unwrap_or_else(|e| panic!("{e}")).value
    };
    let uff = read("set.uff", FileFormat::Uff);
    let csv = read("set.csv", FileFormat::Csv);
    assert_eq!(csv, original, "CSV keeps every double");
    assert_eq!(uff.frfs.len(), 3);
    for (a, b) in uff.frfs.iter().zip(&original.frfs) {
        assert_eq!((a.dofs, &a.unit, &a.freq_hz, &a.direction), (b.dofs, &b.unit, &b.freq_hz, &b.direction));
        for (x, y) in a.values.iter().zip(&b.values) {
            assert!((x - y).norm() <= 1e-12 * y.norm().max(1e-300), "{x} {y}");
        }
    }
    let want: Vec<i64> = vec![1, 2, 3];
    let fitted = read("fitted.uff", FileFormat::Uff);
    assert_eq!(fitted.frfs.iter().map(|f| f.dofs.unwrap().reference_node).collect::<Vec<_>>(), want);
    assert_eq!(fitted.freq_hz().first(), Some(&10.0));
    // One FRF of the set by its nodes, as `read.frf` takes it from the set's file.
    let one = formats::read_frf(
        &out.join("set.uff"),
        FileFormat::Uff,
        &FrfSelect { reference: Some(2), ..Default::default() },
    )
    .unwrap()
    .value;
    assert_eq!(one.values.len(), original.frfs[1].values.len());
    let s = std::fs::read_to_string(out.join("stabilisation.csv")).unwrap();
    assert!(s.contains("order,frequency_Hz,damping_ratio,stable_frequency,stable_damping,selected"), "{s:.300}");
    // The diagram over the summed |H|, and the set drawn one curve per FRF named by its nodes.
    let svg = std::fs::read_to_string(out.join("stabilisation.svg")).unwrap();
    assert_has(&svg, &["model order", "stable in f and ζ", "Σ|H| (log scale)", "selected"]);
    let svg = std::fs::read_to_string(out.join("set.svg")).unwrap();
    assert_has(&svg, &["response 1 x / reference 2", "fit fitted: response 1 x /", "reference 3 x"]);
}

#[test]
fn frfs_on_different_grids_are_refused_as_a_set_with_the_dataset_and_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let mut uff = String::new();
    for f in small_set(0.5) {
        formats::uff::write_frf(&mut uff, &f, "");
    }
    std::fs::write(dir.path().join("two.uff"), &uff).unwrap();
    let path = dir.path().join("recipe.yaml");
    std::fs::write(
        &path,
        "spindlelab: 1\nname: grids\nsteps:\n  taps:\n    kind: read.frf_set\n    params: { file: two.uff }\n",
    )
    .unwrap();
    let o = run_binary(&path, &dir.path().join("out"));
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let second = uff.lines().enumerate().filter(|(_, l)| l.trim() == "58").nth(1).unwrap().0 + 1;
    assert_has(
        &text(&o),
        &[
            &format!("two.uff:{second}"),
            "response 11 y, reference 22 z",
            "its line 2 is at 1.5 Hz, the first FRF's at 1 Hz",
            "read the FRFs one by one with `read.frf`",
        ],
    );
    // Narrowed to one reference node, the same file is a set of one.
    std::fs::write(
        &path,
        "spindlelab: 1\nname: grids\nsteps:\n  taps:\n    kind: read.frf_set\n    params: { file: two.uff, reference: 22 }\n",
    )
    .unwrap();
    let ran = run_at(&path, &dir.path().join("out2"));
    let Value::FrfSet(set) = ran.value("taps", "set").as_ref().clone() else { panic!("not a set") };
    assert_eq!(set.frfs.len(), 1);
    assert_eq!(set.name(0), "response 11 y / reference 22 z");
}
