//! The chatter frequency `stability.sd` reports, through the binary, against two methods that
//! share no code with the semi-discretization: the zero-order approximation (`stability.lobes` on
//! the tool's receptance from `modal.frf`) and the time-domain simulation (`milling.simulate`)
//! just above the limit. The tool of `scripts/milling-simulation.yaml` (600 Hz in x, 650 Hz in y),
//! cut at 25 % up-milling with 4 teeth: the multiplier alone gives 171.7 Hz at 6000 rpm, folded
//! into [0, f_tooth/2] = [0, 200 Hz], where the simulation chatters at about 630 Hz.

use spindlelab::engine::formats::csv::read_tables;
use spindlelab::engine::value::Table;
use std::path::Path;
use std::process::Command;

const HEAD: &str = "spindlelab: 1
name: chatter-frequency
cutting:
  quarter_up:
    teeth: 4
    radial_immersion: 25 %
    milling: up
    Kt: 600 MPa
    Kn: 200 MPa
    feed_per_tooth: 0.05 mm
steps:
  tool:
    kind: modal.model
    params:
      x: [{ f: 600 Hz, zeta: 0.04, mass: 0.4 kg }]
      y: [{ f: 650 Hz, zeta: 0.03, mass: 0.3 kg }]
";

const SPEEDS: [f64; 2] = [6000.0, 12_000.0];

fn run(dir: &Path, name: &str, recipe: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, recipe).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(["run".as_ref(), path.as_os_str(), "-o".as_ref(), dir.join("out").join(name).as_os_str()])
        .env("NO_COLOR", "1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{name}: {}{stdout}", String::from_utf8_lossy(&out.stderr));
    stdout
}

/// The tables of an output CSV, read back with the project's reader.
fn tables(dir: &Path, recipe: &str, file: &str) -> Vec<Table> {
    let path = dir.join("out").join(recipe).join(file);
    let bytes = std::fs::read(&path).unwrap();
    read_tables(&bytes, &path.display().to_string()).unwrap().into_iter().map(|b| b.table).collect()
}

fn column(t: &Table, name: &str) -> Vec<f64> {
    t.columns.iter().find(|c| c.name == name).unwrap_or_else(|| panic!("no column `{name}`")).values.clone()
}

/// Validation: at each speed the SD chatter frequency is within 3 % of the ZOA's and within 2 % of
/// the strongest non-harmonic frequency the time-domain simulation finds 5 % above the SD limit.
#[test]
fn sd_reports_the_chatter_frequency_the_simulation_and_the_zoa_find() {
    let dir = tempfile::tempdir().unwrap();
    let speeds = "\"[6000, 12000] rpm\"";
    let stability = format!(
        "{HEAD}  sd:
    kind: stability.sd
    params: {{ cutting: quarter_up, speeds: {speeds}, max_depth: 20 mm }}
    inputs: {{ modes_x: \"@tool.modes_x\", modes_y: \"@tool.modes_y\" }}
  tool_frf:
    kind: modal.frf
    params: {{ max_frequency: 3 kHz, resolution: 0.25 Hz }}
    inputs: {{ modes_x: \"@tool.modes_x\", modes_y: \"@tool.modes_y\" }}
  zoa:
    kind: stability.lobes
    params: {{ cutting: quarter_up, speeds: {speeds} }}
    inputs: {{ frf_x: \"@tool_frf.frf_x\", frf_y: \"@tool_frf.frf_y\" }}
outputs:
  - {{ from: \"@sd.table\", file: sd.csv }}
  - {{ from: \"@zoa.table\", file: zoa.csv }}
"
    );
    run(dir.path(), "stability.yaml", &stability);
    let sd = &tables(dir.path(), "stability.yaml", "sd.csv")[0];
    let zoa = &tables(dir.path(), "stability.yaml", "zoa.csv")[0];
    assert_eq!(column(sd, "speed"), SPEEDS);
    let (limits, sd_hz, zoa_hz) =
        (column(sd, "depth_limit"), column(sd, "chatter_frequency"), column(zoa, "chatter_frequency"));

    for (i, speed) in SPEEDS.iter().enumerate() {
        let tooth_hz = speed * 4.0 / 60.0;
        assert!(sd_hz[i] > tooth_hz / 2.0, "{speed} rpm: {} Hz is folded into [0, f_tooth/2]", sd_hz[i]);
        assert!((sd_hz[i] / zoa_hz[i] - 1.0).abs() < 0.03, "{speed} rpm: SD {} Hz vs ZOA {} Hz", sd_hz[i], zoa_hz[i]);

        let depth_mm = 1.05 * limits[i] * 1e3;
        let cut = format!(
            "{HEAD}  cut:
    kind: milling.simulate
    params: {{ cutting: quarter_up, revolutions: 300, speed: {speed} rpm, depth: {depth_mm} mm }}
    inputs: {{ modes_x: \"@tool.modes_x\", modes_y: \"@tool.modes_y\" }}
outputs:
  - {{ from: \"@cut.summary\", file: cut.csv }}
"
        );
        let name = format!("cut-{speed}.yaml");
        run(dir.path(), &name, &cut);
        let summary = &tables(dir.path(), &name, "cut.csv")[0];
        assert_eq!(column(summary, "stable"), [0.0], "{speed} rpm: stable 5 % above the SD limit");
        let heard = column(summary, "chatter_frequency")[0];
        assert!((sd_hz[i] / heard - 1.0).abs() < 0.02, "{speed} rpm: SD {} Hz vs simulation {heard} Hz", sd_hz[i]);
    }
}
