//! `spindlelab import case.json`: a baseline case (materials, holder–tool sections, spindle
//! modes, sensor, cutting setup and the list of measured files) written as the recipe a
//! person would write for it: entities with units, the measured files as one measurement
//! set, the measured configuration (with the sensor) compared with every file, and the
//! cutting configuration (without it) giving the stability lobes that score the trials.
//!
//! The case format is described with the training data; the recipe it gives compiles on
//! its own (`spindlelab check`), with the data files beside it.

use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt::Write;

/// Why a case file could not be imported.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    #[error("{path}: not a case file: {source}")]
    Json { path: String, source: serde_json::Error },
    #[error("{path}: {message}")]
    Invalid { path: String, message: String },
}

#[derive(Deserialize)]
struct Case {
    case_id: Option<String>,
    materials: BTreeMap<String, CaseMaterial>,
    holder_tool: HolderTool,
    holder_spindle_interface: CaseJoint,
    spindle: CaseSpindle,
    sensor: Option<CaseSensor>,
    cutting: Option<CaseCutting>,
    measurements: Option<CaseMeasurements>,
}

#[derive(Deserialize)]
struct CaseMaterial {
    #[serde(rename = "E_pa")]
    e_pa: f64,
    rho_kg_m3: f64,
    nu: Option<f64>,
    eta: Option<f64>,
}

#[derive(Deserialize)]
struct HolderTool {
    sections: Vec<CaseSection>,
}

#[derive(Deserialize)]
struct CaseSection {
    name: String,
    component: String,
    kind: Option<String>,
    d_out_spindle_end_m: f64,
    d_out_tip_end_m: Option<f64>,
    d_in_m: Option<f64>,
    length_m: f64,
    outer_material: String,
    inner_material: Option<String>,
}

#[derive(Deserialize)]
struct CaseJoint {
    rigid: Option<bool>,
    kt_n_per_m: Option<f64>,
    ct_ns_per_m: Option<f64>,
    kr_nm_per_rad: Option<f64>,
    cr_nms_per_rad: Option<f64>,
}

#[derive(Deserialize)]
struct CaseSpindle {
    material: SpindleMaterial,
    ref_speed_rpm: Option<f64>,
    modes: BTreeMap<String, Vec<CaseMode>>,
}

#[derive(Deserialize)]
struct SpindleMaterial {
    #[serde(rename = "E_pa")]
    e_pa: f64,
    rho_kg_m3: f64,
    nu: Option<f64>,
}

#[derive(Deserialize)]
struct CaseMode {
    f_hz: f64,
    d_m: f64,
    eta: f64,
    kf: Option<f64>,
    keta: Option<f64>,
}

#[derive(Deserialize)]
struct CaseSensor {
    #[serde(rename = "type")]
    kind: String,
    location: Option<String>,
    mass_kg: Option<f64>,
}

#[derive(Deserialize)]
struct CaseCutting {
    teeth: u32,
    radial_immersion: f64,
    milling: String,
    #[serde(rename = "Ks_n_per_m2")]
    ks: f64,
    beta_deg: f64,
    coefficients_calibrated_at_rpm: Option<f64>,
    workpiece_material: Option<String>,
    trial_rpm_range: Option<[f64; 2]>,
}

#[derive(Deserialize)]
struct CaseMeasurements {
    #[serde(default)]
    frf: Vec<CaseFrf>,
    frequency_lines: Option<u32>,
    frequency_step_hz: Option<f64>,
    trials: Option<String>,
}

#[derive(Deserialize)]
struct CaseFrf {
    file: String,
    direction: String,
    speed_rpm: f64,
    units: Option<String>,
}

/// A number as a person writes it: at most 12 significant digits, no binary noise
/// (`0.0635 * 1000` is `63.5`), exponent form only for very large or small magnitudes.
fn num(x: f64) -> String {
    let r: f64 = format!("{x:.11e}").parse().unwrap_or(x);
    if r != 0.0 && (r.abs() >= 1e6 || r.abs() < 1e-3) { format!("{r:e}") } else { format!("{r}") }
}

/// A YAML-safe name: letters, digits, `_` and `-`, starting with a letter or `_`.
fn name(s: &str) -> String {
    let mut out: String = s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' }).collect();
    if !out.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_') {
        out.insert(0, '_');
    }
    out
}

/// Text as a YAML double-quoted scalar.
fn quoted(s: &str) -> String {
    serde_json::to_string(s).expect("a string serialises")
}

/// Writes the recipe for the case in `json` (its file name `path` is for messages).
pub fn recipe_from_case(json: &str, path: &str) -> Result<String, ImportError> {
    let case: Case = serde_json::from_str(json).map_err(|source| ImportError::Json { path: path.into(), source })?;
    let invalid = |message: String| ImportError::Invalid { path: path.into(), message };
    let id = case.case_id.clone().unwrap_or_else(|| "case".into());
    let mut y = String::new();
    let w = &mut y;
    let _ = writeln!(w, "# Baseline model of case {id}, imported from {}.", path.rsplit('/').next().unwrap_or(path));
    let _ = writeln!(w, "# The measured configuration (sensor on the tool) is compared with every measured FRF;");
    let _ = writeln!(w, "# the cutting configuration (no sensor) gives the lobes that score the cutting trials.");
    let _ = writeln!(w, "spindlelab: 1");
    let _ = writeln!(w, "name: {}", name(&id));
    let _ = writeln!(w);

    // Materials of the holder and tool, then the spindle's, under a name of its own.
    let _ = writeln!(w, "materials:");
    for (mname, m) in &case.materials {
        let _ = write!(w, "  {}: {{ E: {} GPa, rho: {} kg/m^3", name(mname), num(m.e_pa / 1e9), num(m.rho_kg_m3));
        if let Some(nu) = m.nu {
            let _ = write!(w, ", nu: {}", num(nu));
        }
        let _ = writeln!(w, ", eta: {} }}", num(m.eta.unwrap_or(0.0)));
    }
    let mut spindle_material = "spindle_steel".to_string();
    while case.materials.contains_key(&spindle_material) {
        spindle_material.push('_');
    }
    let sm = &case.spindle.material;
    let _ = write!(w, "  {spindle_material}: {{ E: {} GPa, rho: {} kg/m^3", num(sm.e_pa / 1e9), num(sm.rho_kg_m3));
    match sm.nu {
        Some(nu) => {
            let _ = writeln!(w, ", nu: {} }}", num(nu));
        }
        None => {
            let _ = writeln!(w, " }}   # no Poisson's ratio: the spindle's beams do not use one");
        }
    }
    let _ = writeln!(w);

    // The machine: spindle modes per direction with their speed laws, and the holder joint.
    let dirs: Vec<&String> = case.spindle.modes.keys().collect();
    let _ = writeln!(w, "machines:");
    let _ = writeln!(w, "  test_spindle:");
    let _ = writeln!(w, "    directions: [{}]", dirs.iter().map(|d| d.as_str()).collect::<Vec<_>>().join(", "));
    let _ = writeln!(w, "    spindle:");
    let _ = writeln!(w, "      material: {spindle_material}");
    let _ = writeln!(w, "      ref_speed: {} rpm", num(case.spindle.ref_speed_rpm.unwrap_or(10_000.0)));
    let _ = writeln!(
        w,
        "      # Equivalent clamped-free Euler–Bernoulli beams, one per mode; f(n) = f (1 + kf (n/ref_speed)^2)."
    );
    let _ = writeln!(w, "      modes:");
    for (dir, modes) in &case.spindle.modes {
        if !matches!(dir.as_str(), "x" | "y") {
            return Err(invalid(format!("spindle modes in direction `{dir}`: the model knows x and y")));
        }
        let _ = writeln!(w, "        {dir}:");
        for m in modes {
            let _ = write!(w, "          - {{ f: {} Hz, d: {} mm, eta: {}", num(m.f_hz), num(m.d_m * 1e3), num(m.eta));
            if let Some(kf) = m.kf.filter(|k| *k != 0.0) {
                let _ = write!(w, ", kf: {}", num(kf));
            }
            if let Some(keta) = m.keta.filter(|k| *k != 0.0) {
                let _ = write!(w, ", keta: {}", num(keta));
            }
            let _ = writeln!(w, " }}");
        }
    }
    let j = &case.holder_spindle_interface;
    match (j.rigid, j.kt_n_per_m, j.ct_ns_per_m, j.kr_nm_per_rad, j.cr_nms_per_rad) {
        (Some(true), ..) => {
            let _ = writeln!(w, "    holder_interface: {{ rigid: true }}");
        }
        (_, Some(kt), ct, Some(kr), cr) => {
            let _ = writeln!(
                w,
                "    holder_interface: {{ kt: {} N/m, ct: {} N*s/m, kr: {} N*m/rad, cr: {} N*m*s/rad }}",
                num(kt),
                num(ct.unwrap_or(0.0)),
                num(kr),
                num(cr.unwrap_or(0.0))
            );
        }
        _ => return Err(invalid("`holder_spindle_interface` is neither rigid nor gives kt and kr".into())),
    }
    let _ = writeln!(w);

    // The holder and tool, from the spindle end to the tip.
    let _ = writeln!(w, "assemblies:");
    let _ = writeln!(w, "  holder_tool:");
    let _ = writeln!(w, "    sections:");
    for s in &case.holder_tool.sections {
        if !case.materials.contains_key(&s.outer_material) {
            return Err(invalid(format!(
                "section `{}` is of material `{}`, which `materials` lacks",
                s.name, s.outer_material
            )));
        }
        let _ = write!(w, "      - {{ name: {}, component: {}", name(&s.name), s.component);
        if let Some(k) = s.kind.as_deref().filter(|k| *k != "plain") {
            let _ = write!(w, ", kind: {k}");
        }
        let _ = write!(w, ", d_out: {} mm", num(s.d_out_spindle_end_m * 1e3));
        if let Some(tip) = s.d_out_tip_end_m.filter(|t| *t != s.d_out_spindle_end_m) {
            let _ = write!(w, ", d_out_tip: {} mm", num(tip * 1e3));
        }
        if let Some(d) = s.d_in_m.filter(|d| *d > 0.0) {
            let _ = write!(w, ", d_in: {} mm", num(d * 1e3));
        }
        let _ = write!(w, ", length: {} mm, outer: {}", num(s.length_m * 1e3), name(&s.outer_material));
        if let Some(inner) = &s.inner_material {
            let _ = write!(w, ", inner: {}", name(inner));
        }
        let _ = writeln!(w, " }}");
    }
    let _ = writeln!(w);

    let sensor = case.sensor.as_ref();
    if let Some(s) = sensor {
        let _ = writeln!(w, "sensors:");
        let _ = write!(w, "  sensor: {{ kind: {}", s.kind);
        if let Some(l) = &s.location {
            let _ = write!(w, ", location: {}", quoted(l));
        }
        let _ = writeln!(w, ", mass: {} g }}", num(s.mass_kg.unwrap_or(0.0) * 1e3));
        let _ = writeln!(w);
    }

    let cutting = case.cutting.as_ref();
    if let Some(c) = cutting {
        let _ = writeln!(w, "cutting:");
        let _ = writeln!(w, "  trials:");
        let _ = writeln!(w, "    teeth: {}", c.teeth);
        let _ = writeln!(w, "    radial_immersion: {}   # radial depth / tool diameter", num(c.radial_immersion));
        let _ = writeln!(w, "    milling: {}", c.milling);
        let _ = writeln!(w, "    Ks: {} MPa", num(c.ks / 1e6));
        let _ = writeln!(w, "    beta: {} deg", num(c.beta_deg));
        if let Some(n) = c.coefficients_calibrated_at_rpm {
            let _ = writeln!(w, "    calibrated_at: {} rpm", num(n));
        }
        if let Some(m) = &c.workpiece_material {
            let _ = writeln!(w, "    workpiece: {}", quoted(m));
        }
        if let Some([a, b]) = c.trial_rpm_range {
            let _ = writeln!(w, "    trial_speeds: [{} rpm, {} rpm]", num(a), num(b));
        }
        let _ = writeln!(w);
    }

    let meas = case.measurements.as_ref();
    let frfs: &[CaseFrf] = meas.map_or(&[], |m| &m.frf);
    if !frfs.is_empty() {
        let _ = writeln!(w, "# Every measured FRF; each file's header gives its direction and speed.");
        let _ = writeln!(w, "measurements:");
        let _ = writeln!(w, "  tool_tip:");
        let _ = writeln!(w, "    files:");
        for f in frfs {
            let _ = writeln!(w, "      - {}   # {}, {} rpm", quoted(&f.file), f.direction, num(f.speed_rpm));
        }
        let units: Vec<&str> = frfs.iter().filter_map(|f| f.units.as_deref()).collect();
        if let Some(u) = units.first().filter(|u| units.iter().all(|v| v == *u)) {
            let _ = writeln!(w, "    units: {u}");
        }
        let _ = writeln!(w);
    }

    let _ = writeln!(w, "steps:");
    let _ = writeln!(w, "  # The holder and tool reduced once to their tip and spindle end.");
    let _ = writeln!(w, "  holder_tool_model:");
    let _ = writeln!(w, "    kind: beam.substructure");
    let _ = writeln!(w, "    params: {{ assembly: holder_tool, max_element: 2 mm }}");
    if !frfs.is_empty() {
        let _ = writeln!(w);
        let _ = writeln!(w, "  # Measured configuration: on each file's lines, direction and speed.");
        let _ = writeln!(w, "  spindle:");
        let _ = writeln!(w, "    kind: spindle.receptance");
        let _ = writeln!(w, "    params: {{ machine: test_spindle }}");
        let _ = writeln!(w, "    inputs: {{ grid: \"@tool_tip.frf\" }}");
        let _ = writeln!(w, "  measured_model:");
        let _ = writeln!(w, "    kind: rcsa.couple");
        if sensor.is_some() {
            let _ = writeln!(
                w,
                "    params: {{ interface: machine, machine: test_spindle, sensor: sensor }}   # the sensor's mass sits on the tool tip"
            );
        } else {
            let _ = writeln!(w, "    params: {{ interface: machine, machine: test_spindle }}");
        }
        let _ =
            writeln!(w, "    inputs: {{ spindle: \"@spindle.receptance\", structure: \"@holder_tool_model.model\" }}");
        let _ =
            writeln!(w, "  # Model against measurement, in units of the measurement's noise (about 1 at the floor).");
        let _ = writeln!(w, "  gap:");
        let _ = writeln!(w, "    kind: frf.gap");
        let _ = writeln!(w, "    inputs: {{ model: \"@measured_model.frf\", measured: \"@tool_tip.frf\" }}");
    }
    if let Some(c) = cutting {
        let mut speeds: Vec<f64> = frfs.iter().map(|f| f.speed_rpm).collect();
        if let Some([a, b]) = c.trial_rpm_range {
            speeds.extend([a, b]);
        }
        speeds.sort_by(f64::total_cmp);
        speeds.dedup();
        let lo = speeds.first().copied().unwrap_or(0.0);
        let hi = speeds.last().copied().unwrap_or(0.0);
        // A round step giving at most 40 speeds, the span widened to whole steps so the
        // ends of the trials' range are on the grid.
        let step = [100.0, 250.0, 500.0, 1000.0, 2000.0, 2500.0, 5000.0, 10_000.0]
            .into_iter()
            .find(|s| (hi - lo) / s <= 40.0)
            .unwrap_or(((hi - lo) / 40.0).ceil());
        let (lo, hi) = ((lo / step).floor() * step, (hi / step).ceil() * step);
        let _ = writeln!(w);
        let _ = writeln!(w, "  # Cutting configuration: no sensor; x and y over the speeds of the trials.");
        let _ = writeln!(w, "  spindle_cutting:");
        let _ = writeln!(w, "    kind: spindle.receptance");
        let _ = writeln!(w, "    params: {{ machine: test_spindle, max_frequency: 10 kHz, resolution: 2.5 Hz }}");
        let _ = writeln!(w, "    sweep:");
        let _ = writeln!(w, "      direction: [x, y]");
        let _ = writeln!(w, "      speed: {}..{} step {} rpm", num(lo), num(hi), num(step));
        let _ = writeln!(w, "  cutting_model:");
        let _ = writeln!(w, "    kind: rcsa.couple");
        let _ = writeln!(w, "    params: {{ interface: machine, machine: test_spindle }}");
        let _ = writeln!(
            w,
            "    inputs: {{ spindle: \"@spindle_cutting.receptance\", structure: \"@holder_tool_model.model\" }}"
        );
        let _ = writeln!(w, "  lobes:");
        let _ = writeln!(w, "    kind: stability.speed_dependent");
        match c.trial_rpm_range {
            Some([a, b]) => {
                let _ = writeln!(w, "    params: {{ cutting: trials, speeds: {}..{} step 5 rpm }}", num(a), num(b));
            }
            None => {
                let _ = writeln!(w, "    params: {{ cutting: trials }}");
            }
        }
        let _ = writeln!(w, "    inputs: {{ frfs: \"@cutting_model.frf\" }}");
        if let Some(t) = meas.and_then(|m| m.trials.as_deref()) {
            let _ = writeln!(w, "  trials:");
            let _ = writeln!(w, "    kind: trials.score");
            let _ = writeln!(w, "    params: {{ file: {} }}", quoted(t));
            let _ = writeln!(w, "    inputs: {{ lobes: \"@lobes.speed_dependent\" }}");
        }
    }
    if let Some(m) = meas {
        let _ = writeln!(w);
        let _ = writeln!(
            w,
            "# {} measured FRFs{}.",
            frfs.len(),
            match (m.frequency_lines, m.frequency_step_hz) {
                (Some(n), Some(df)) => format!(", {n} lines every {} Hz", num(df)),
                _ => String::new(),
            }
        );
    }
    Ok(y)
}

#[cfg(test)]
mod tests {
    use super::num;

    #[test]
    fn numbers_read_as_a_person_writes_them() {
        assert_eq!(num(0.0635 * 1e3), "63.5");
        assert_eq!(num(585e9 / 1e9), "585");
        assert_eq!(num(1.5e8), "1.5e8");
        assert_eq!(num(0.012), "0.012");
        assert_eq!(num(0.0), "0");
        assert_eq!(num(2.1e-3 * 1e3), "2.1");
    }
}
