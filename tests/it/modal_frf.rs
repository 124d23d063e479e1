//! `modal.frf` through the binary: a tool stated as modes feeds `stability.lobes`, which takes
//! FRFs only, and the receptance it writes reads back as the closed form of each mode.

use spindlelab::engine::formats::csv::read_frf_blocks;
use std::f64::consts::TAU;
use std::process::Command;

const RECIPE: &str = "spindlelab: 1
name: modal-tool
cutting:
  quarter_up:
    teeth: 4
    radial_immersion: 25 %
    milling: up
    Kt: 600 MPa
    Kn: 200 MPa
steps:
  tool:
    kind: modal.model
    params:
      x: [{ f: 600 Hz, zeta: 0.04, mass: 0.4 kg }]
      y: [{ f: 650 Hz, zeta: 0.03, stiffness: 5e6 N/m }]
  tool_frf:
    kind: modal.frf
    params: { max_frequency: 2 kHz, resolution: 0.5 Hz }
    inputs: { modes_x: \"@tool.modes_x\", modes_y: \"@tool.modes_y\" }
  lobes:
    kind: stability.lobes
    params: { cutting: quarter_up, speeds: 5000..15000 step 100 rpm }
    inputs: { frf_x: \"@tool_frf.frf_x\", frf_y: \"@tool_frf.frf_y\" }
outputs:
  - { from: \"@tool_frf.frf_x\", file: frf_x.csv }
  - { from: \"@tool_frf.frf_y\", file: frf_y.csv }
  - { from: \"@lobes.lobes\", file: lobes.csv }
";

/// Validation against the closed form of one mode: `|H(ω_n)| = 1/(2kζ)` and `H(0) = 1/k`, as written
/// to CSV and read back; the lobes of the modes are computed (the node took the FRFs).
#[test]
fn modes_become_receptances_the_zoa_lobes_take() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = dir.path().join("modal-tool.yaml");
    std::fs::write(&recipe, RECIPE).unwrap();
    let out_dir = dir.path().join("out");
    let run = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(["run".as_ref(), recipe.as_os_str(), "-o".as_ref(), out_dir.as_os_str()])
        .env("NO_COLOR", "1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{}{stdout}", String::from_utf8_lossy(&run.stderr));
    assert!(stdout.contains("lobes (stability.lobes)"), "{stdout}");

    let k_x = 0.4 * (TAU * 600.0f64).powi(2);
    for (file, f_n, zeta, k, direction) in [("frf_x.csv", 600.0, 0.04, k_x, "x"), ("frf_y.csv", 650.0, 0.03, 5e6, "y")]
    {
        let path = out_dir.join(file);
        let blocks = read_frf_blocks(&std::fs::read(&path).unwrap(), file).unwrap();
        assert_eq!(blocks.len(), 1);
        let h = &blocks[0].frf;
        assert_eq!(h.unit.symbol, "m/N", "{file}");
        assert_eq!(h.direction.as_deref(), Some(direction), "{file}");
        assert_eq!(h.freq_hz.len(), 4001, "{file}: 0 to 2 kHz every 0.5 Hz");
        let at = |f: f64| h.values[h.freq_hz.iter().position(|x| *x == f).unwrap()];
        assert!((at(0.0).norm() * k - 1.0).abs() < 1e-12, "{file}: H(0) {} vs 1/k {}", at(0.0), 1.0 / k);
        let peak = at(f_n).norm();
        assert!(
            (peak * 2.0 * k * zeta - 1.0).abs() < 1e-12,
            "{file}: |H(ω_n)| {peak} vs 1/(2kζ) {}",
            1.0 / (2.0 * k * zeta)
        );
    }
    let lobes = std::fs::read_to_string(out_dir.join("lobes.csv")).unwrap();
    assert!(lobes.lines().filter(|l| !l.starts_with('#')).count() > 100, "{lobes}");
}

/// A mode is `{f, zeta, …}` wherever a recipe states one; a recipe written with the old
/// names is told which to write, at the key.
#[test]
fn a_mode_written_with_the_old_names_is_told_the_one_name() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = dir.path().join("old.yaml");
    std::fs::write(
        &recipe,
        "spindlelab: 1\nname: old\nsteps:\n  tool:\n    kind: modal.model\n    params:\n      x: [{ frequency: 600 Hz, damping: 0.04, mass: 0.4 kg }]\n",
    )
    .unwrap();
    let e = spindlelab::engine::compile_file(&recipe, &spindlelab::registry()).err().expect("old names are refused");
    let shown = e.render(false);
    for needle in ["old.yaml:7:13", "unknown key `frequency`", "write `f`", "unknown key `damping`", "write `zeta`"] {
        assert!(shown.contains(needle), "{needle} not in:\n{shown}");
    }
}
