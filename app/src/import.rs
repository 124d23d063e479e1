//! `spindlelab import case.json`: a baseline case (materials, holder–tool sections, spindle
//! modes, sensor, cutting setup and the list of measured files) written as the recipe a
//! person would write for it: entities with units, the measured files as one measurement
//! set, the measured configuration (with the sensor) compared with every file, and the
//! cutting configuration (without it) giving the stability lobes that score the trials.
//!
//! The case format is described with the training data; the recipe it gives compiles on
//! its own (`spindlelab check`) wherever it is written: the case names its data files from
//! its own folder, the recipe names them from the recipe's ([`Placement`]). Its outputs are the
//! gap table, the measured configuration drawn over the measurements and the lobes with the
//! trials, so `run --report` shows the case's results.

use crate::engine::grammar::parse_unit;
use crate::engine::model::entity_fields;
use crate::engine::spec::{EntityKind, FieldType};
use crate::engine::syntax::yaml_quoted;
use serde::Deserialize;
use spindlelab_stdlib::nodes::kinds::{
    BEAM_SUBSTRUCTURE, FRF_GAP, RCSA_COUPLE, SPINDLE_RECEPTANCE, STABILITY_SPEED_DEPENDENT, TRIALS_SCORE,
};
use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::Path;

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

/// A string of the case as a YAML scalar: plain when it is a word that YAML reads as that
/// same text (`steel`, `holder+tool`, `m/N`), double-quoted otherwise.
fn scalar(s: &str) -> String {
    let word = s.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
        && s.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '+' | '/'));
    let keyword = matches!(
        s.to_ascii_lowercase().as_str(),
        "true" | "false" | "null" | "yes" | "no" | "on" | "off" | "y" | "n" | "inf" | "nan" | "infinity"
    );
    if word && !keyword { s.to_string() } else { yaml_quoted(s) }
}

/// A string of the case as a message shows it: quoted and escaped, cut after 60 characters.
fn shown(s: &str) -> String {
    let cut: String = s.chars().take(60).collect();
    let more = if cut.len() < s.len() { format!(" (… {} bytes in all)", s.len()) } else { String::new() };
    format!("{}{more}", yaml_quoted(&cut))
}

/// Whether `s` names an entity as a recipe does: letters, digits, `_` and `-`, starting with
/// a letter or `_`.
fn is_name(s: &str) -> bool {
    s.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
        && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

/// The words a choice field of an entity takes, from the engine's field tables (`path` goes
/// through nested lists of mappings, e.g. `sections`, `component`).
fn choices(kind: EntityKind, path: &[&str]) -> &'static [&'static str] {
    let mut fields = entity_fields(kind);
    for (i, name) in path.iter().enumerate() {
        let Some(f) = fields.iter().find(|f| f.name == *name) else { return &[] };
        match (&f.ty, i + 1 == path.len()) {
            (FieldType::Choice(words), true) => return words,
            (FieldType::ObjectList(inner) | FieldType::Object(inner), false) => fields = inner,
            _ => return &[],
        }
    }
    &[]
}

/// Longest name the recipe writes as a key of a mapping (YAML reads a plain or quoted key of
/// at most 1024 characters on the key's line).
const MAX_KEY_BYTES: usize = 128;

/// Longest file name (one path component) and whole path the systems a recipe runs on take.
const MAX_NAME_BYTES: usize = 255;
const MAX_PATH_BYTES: usize = 4096;

/// Checks every string of the case that the recipe states, so that each reads back as
/// exactly what the case says and means there what it means in the case; the first string
/// that cannot is the error, naming its field.
fn check_strings(case: &Case) -> Result<(), String> {
    // Any string the recipe holds: `$` at its start would make it a parameter reference.
    let text = |field: &str, s: &str| -> Result<(), String> {
        if s.trim_start().starts_with('$') {
            return Err(format!(
                "`{field}` is {}, which begins with `$`: a recipe reads that as a parameter reference; \
                 change it in the case file",
                shown(s)
            ));
        }
        Ok(())
    };
    let word = |field: &str, s: &str, words: &[&str]| -> Result<(), String> {
        if words.contains(&s) {
            return Ok(());
        }
        Err(format!(
            "`{field}` is {}, but a recipe takes one of {}; correct it in the case file",
            shown(s),
            words.join(" | ")
        ))
    };
    let material = |field: &str, s: &str| -> Result<(), String> {
        if !case.materials.contains_key(s) {
            return Err(format!(
                "`{field}` is {}, which `materials` lacks; add it there or correct the name",
                shown(s)
            ));
        }
        Ok(())
    };
    let file = |field: &str, s: &str, glob: bool| -> Result<(), String> {
        text(field, s)?;
        let problem = if s.trim().is_empty() {
            Some("is empty".to_string())
        } else if s.contains('\0') {
            Some("holds a NUL character, which no file name can".into())
        } else if s.len() > MAX_PATH_BYTES {
            Some(format!("is {} bytes long, beyond the {MAX_PATH_BYTES} bytes of a path", s.len()))
        } else if s.split('/').any(|part| part.len() > MAX_NAME_BYTES) {
            Some(format!("has a name longer than the {MAX_NAME_BYTES} bytes a file name can have"))
        } else if std::path::Path::new(s).is_absolute() {
            Some("is an absolute path; a recipe names its data files relative to its own folder".into())
        } else if glob && s.contains(['*', '?', '[']) {
            Some("holds `*`, `?` or `[`, which a measurement set reads as a glob".into())
        } else {
            None
        };
        match problem {
            Some(p) => Err(format!("`{field}` {} {p}; rename the file and the case's entry", shown(s))),
            None => Ok(()),
        }
    };
    if let Some(id) = &case.case_id {
        text("case_id", id)?;
    }
    for m in case.materials.keys() {
        if m.len() > MAX_KEY_BYTES {
            return Err(format!(
                "material {} is {} bytes long; a name that keys a recipe's mapping has at most {MAX_KEY_BYTES}; \
                 shorten it (and its uses) in the case file",
                shown(m),
                m.len()
            ));
        }
        if !is_name(m) {
            return Err(format!(
                "material {} cannot name a recipe's material: names start with a letter or `_` and hold \
                 letters, digits, `_` and `-`; rename it (and its uses) in the case file",
                shown(m)
            ));
        }
    }
    for dir in case.spindle.modes.keys() {
        if !matches!(dir.as_str(), "x" | "y") {
            return Err(format!("spindle modes in direction {}: the model knows x and y", shown(dir)));
        }
    }
    for (i, s) in case.holder_tool.sections.iter().enumerate() {
        let at = |f: &str| format!("holder_tool.sections[{i}].{f}");
        text(&at("name"), &s.name)?;
        word(&at("component"), &s.component, choices(EntityKind::Assembly, &["sections", "component"]))?;
        if let Some(k) = &s.kind {
            word(&at("kind"), k, choices(EntityKind::Assembly, &["sections", "kind"]))?;
        }
        material(&at("outer_material"), &s.outer_material)?;
        if let Some(m) = &s.inner_material {
            material(&at("inner_material"), m)?;
        }
    }
    if let Some(s) = &case.sensor {
        word("sensor.type", &s.kind, choices(EntityKind::Sensor, &["kind"]))?;
        if let Some(l) = &s.location {
            text("sensor.location", l)?;
        }
    }
    if let Some(c) = &case.cutting {
        word("cutting.milling", &c.milling, choices(EntityKind::Cutting, &["milling"]))?;
        if let Some(m) = &c.workpiece_material {
            text("cutting.workpiece_material", m)?;
        }
    }
    if let Some(m) = &case.measurements {
        for (i, f) in m.frf.iter().enumerate() {
            let at = |k: &str| format!("measurements.frf[{i}].{k}");
            file(&at("file"), &f.file, true)?;
            word(&at("direction"), &f.direction, &["x", "y", "z"])?;
            if let Some(u) = &f.units {
                text(&at("units"), u)?;
                if let Err(e) = parse_unit(u) {
                    return Err(format!(
                        "`{}` is {}, which is not a unit ({}); write the unit of the file's values, e.g. `m/N`",
                        at("units"),
                        shown(u),
                        crate::engine::diag::escape_controls(&e.message)
                    ));
                }
            }
        }
        if let Some(t) = &m.trials {
            file("measurements.trials", t, false)?;
        }
    }
    Ok(())
}

/// Where the case and the recipe written from it lie, so the recipe names the case's data
/// files from its own folder (a recipe's file names are relative to the recipe).
#[derive(Debug, Clone, Copy)]
pub struct Placement<'a> {
    /// The folder of the case file: the case names its data files relative to it.
    pub case_dir: &'a Path,
    /// The folder the recipe is written to (the current folder when it is printed).
    pub recipe_dir: &'a Path,
}

impl Placement<'_> {
    /// How the recipe names the case's data file `file`: relative to the recipe's folder, or
    /// absolute when the two folders share nothing but the root. A file that is not beside the
    /// case is written as the case gives it (then the recipe's check names it as missing).
    pub fn data_path(&self, file: &str) -> Result<String, String> {
        let beside_case = self.case_dir.join(file);
        let (Some(dir), Some(name)) = (beside_case.parent(), beside_case.file_name()) else {
            return Ok(file.to_string());
        };
        let (Ok(dir), Some(from)) = (dir.canonicalize(), canonical_to_be(self.recipe_dir)) else {
            return Ok(file.to_string());
        };
        if !dir.join(name).is_file() {
            return Ok(file.to_string());
        }
        let target = dir.join(name);
        let common = from.components().zip(target.components()).take_while(|(a, b)| a == b).count();
        let parts: Vec<std::path::Component<'_>> = if common <= 1 {
            target.components().collect()
        } else {
            let ups = from.components().count() - common;
            std::iter::repeat_n(std::path::Component::ParentDir, ups).chain(target.components().skip(common)).collect()
        };
        let mut written = String::new();
        for (i, c) in parts.iter().enumerate() {
            let text = c.as_os_str().to_str().ok_or_else(|| {
                format!(
                    "the path of `{file}` from the recipe's folder is not UTF-8 text; write the recipe beside the case"
                )
            })?;
            match c {
                std::path::Component::RootDir => written.push('/'),
                _ => {
                    if i > 0 && !written.ends_with('/') {
                        written.push('/');
                    }
                    written.push_str(text);
                }
            }
        }
        if written.contains(['*', '?', '[']) {
            return Err(format!(
                "`{file}` is reached from the recipe's folder as `{written}`, whose `*`, `?` or `[` a measurement \
                 set reads as a glob; write the recipe beside the case, or rename the folders"
            ));
        }
        Ok(written)
    }
}

/// Writes the recipe for the case in `json` (its file name `path` is for messages), naming
/// the data files as the case does (for a recipe written beside the case).
pub fn recipe_from_case(json: &str, path: &str) -> Result<String, ImportError> {
    let parts = import_parts(json, path, None)?;
    Ok(format!("{}{}{}", parts.header, parts.entities, parts.rest))
}

/// The canonical form of a folder that may not exist yet (the recipe's, which the command
/// makes when it writes): its deepest existing ancestor canonicalised, the rest appended.
fn canonical_to_be(dir: &std::path::Path) -> Option<std::path::PathBuf> {
    let abs = std::path::absolute(dir).ok()?;
    let mut missing = Vec::new();
    let mut at = abs.as_path();
    loop {
        if let Ok(c) = at.canonicalize() {
            return Some(missing.iter().rev().fold(c, |path, part| path.join(part)));
        }
        missing.push(at.file_name()?);
        at = at.parent()?;
    }
}

/// [`recipe_from_case`] for a recipe written where `placement` says: its data files named
/// from the recipe's folder.
pub fn recipe_from_case_at(json: &str, path: &str, placement: Placement<'_>) -> Result<String, ImportError> {
    let parts = import_parts(json, path, Some(placement))?;
    Ok(format!("{}{}{}", parts.header, parts.entities, parts.rest))
}

/// The case in `json` as a library of its entities and a short recipe that uses it:
/// `(library, recipe)`. `use_path` is how the recipe names the library (relative to the
/// recipe's folder); like every foreign string it is written as a YAML scalar that reads back
/// exactly. With a `placement`, the recipe names the data files from its own folder.
pub fn library_from_case(
    json: &str,
    path: &str,
    use_path: &str,
    placement: Option<Placement<'_>>,
) -> Result<(String, String), ImportError> {
    let parts = import_parts(json, path, placement)?;
    let file_name = path.rsplit('/').next().unwrap_or(path);
    let library = format!(
        "# Entities of case {}, imported from {}: materials, the spindle, the holder and tool,\n\
         # the sensor and the cutting setup. Recipes take them with `use:`.\nspindlelab: 1\n\n{}",
        scalar(&parts.id),
        scalar(file_name),
        parts.entities
    );
    let recipe = format!(
        "{}# Materials, machine, assemblies, sensor and cutting setup: the case's library.\nuse: [{}]\n\n{}",
        parts.header,
        yaml_quoted(use_path),
        parts.rest
    );
    Ok((library, recipe))
}

/// A recipe written from a case in three parts: the header, the entity sections and the rest
/// (measurements and steps).
struct Parts {
    id: String,
    header: String,
    entities: String,
    rest: String,
}

fn import_parts(json: &str, path: &str, placement: Option<Placement<'_>>) -> Result<Parts, ImportError> {
    let case: Case = serde_json::from_str(json).map_err(|source| ImportError::Json { path: path.into(), source })?;
    let invalid = |message: String| ImportError::Invalid { path: path.into(), message };
    check_strings(&case).map_err(invalid)?;
    let data_path = |file: &str| match placement {
        Some(p) => p.data_path(file).map_err(|m| ImportError::Invalid { path: path.into(), message: m }),
        None => Ok(file.to_string()),
    };
    let id = case.case_id.clone().unwrap_or_else(|| "case".into());
    let header = header_section(&id, path);

    let mut entities = String::new();
    let spindle_material = write_materials(&mut entities, &case);
    write_machines(&mut entities, &case, &spindle_material).map_err(invalid)?;
    write_assemblies(&mut entities, &case.holder_tool);
    if let Some(s) = &case.sensor {
        write_sensors(&mut entities, s);
    }
    if let Some(c) = &case.cutting {
        write_cutting(&mut entities, c);
    }

    let mut rest = String::new();
    let meas = case.measurements.as_ref();
    let frfs: &[CaseFrf] = meas.map_or(&[], |m| &m.frf);
    let trials_file = meas.and_then(|m| m.trials.as_deref());
    write_measurements(&mut rest, frfs, &data_path)?;
    write_steps(&mut rest, &case, frfs, trials_file, &data_path)?;
    let cutting = case.cutting.is_some();
    write_outputs(&mut rest, !frfs.is_empty(), cutting, cutting && trials_file.is_some());
    if let Some(m) = meas {
        write_measurement_note(&mut rest, m);
    }
    Ok(Parts { id, header, entities, rest })
}

/// The recipe's header: comments naming the case and its file, the format version and the name.
fn header_section(id: &str, path: &str) -> String {
    let mut y = String::new();
    let w = &mut y;
    let file_name = path.rsplit('/').next().unwrap_or(path);
    let _ = writeln!(w, "# Baseline model of case {}, imported from {}.", scalar(id), scalar(file_name));
    let _ = writeln!(w, "# The measured configuration (sensor on the tool) is compared with every measured FRF;");
    let _ = writeln!(w, "# the cutting configuration (no sensor) gives the lobes that score the cutting trials.");
    let _ = writeln!(w, "spindlelab: 1");
    let _ = writeln!(w, "name: {}", scalar(id));
    let _ = writeln!(w);
    y
}

/// Writes `materials:` (the holder's and tool's, then the spindle's under a name of its own)
/// and returns that name.
fn write_materials(w: &mut String, case: &Case) -> String {
    let _ = writeln!(w, "materials:");
    for (mname, m) in &case.materials {
        let _ = write!(w, "  {}: {{ E: {} GPa, rho: {} kg/m^3", scalar(mname), num(m.e_pa / 1e9), num(m.rho_kg_m3));
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
    spindle_material
}

/// Writes `machines:`: the spindle's modes per direction, their speed laws and the holder joint.
fn write_machines(w: &mut String, case: &Case, spindle_material: &str) -> Result<(), String> {
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
    write_holder_interface(w, &case.holder_spindle_interface)?;
    let _ = writeln!(w);
    Ok(())
}

/// Writes the machine's `holder_interface`: rigid, or its stiffness and damping; an error when
/// the case gives neither.
fn write_holder_interface(w: &mut String, j: &CaseJoint) -> Result<(), String> {
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
        _ => return Err("`holder_spindle_interface` is neither rigid nor gives kt and kr".into()),
    }
    Ok(())
}

/// Writes `assemblies:`: the holder and tool, section by section from the spindle end to the tip.
fn write_assemblies(w: &mut String, holder_tool: &HolderTool) {
    let _ = writeln!(w, "assemblies:");
    let _ = writeln!(w, "  holder_tool:");
    let _ = writeln!(w, "    sections:");
    for s in &holder_tool.sections {
        let _ = write!(w, "      - {{ name: {}, component: {}", scalar(&s.name), s.component);
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
        let _ = write!(w, ", length: {} mm, outer: {}", num(s.length_m * 1e3), scalar(&s.outer_material));
        if let Some(inner) = &s.inner_material {
            let _ = write!(w, ", inner: {}", scalar(inner));
        }
        let _ = writeln!(w, " }}");
    }
    let _ = writeln!(w);
}

/// Writes `sensors:`: the case's sensor, its kind, location and mass.
fn write_sensors(w: &mut String, s: &CaseSensor) {
    let _ = writeln!(w, "sensors:");
    let _ = write!(w, "  sensor: {{ kind: {}", s.kind);
    if let Some(l) = &s.location {
        let _ = write!(w, ", location: {}", yaml_quoted(l));
    }
    let _ = writeln!(w, ", mass: {} g }}", num(s.mass_kg.unwrap_or(0.0) * 1e3));
    let _ = writeln!(w);
}

/// Writes `cutting:`: the trials' setup (teeth, immersion, coefficients and speed range).
fn write_cutting(w: &mut String, c: &CaseCutting) {
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
        let _ = writeln!(w, "    workpiece: {}", yaml_quoted(m));
    }
    if let Some([a, b]) = c.trial_rpm_range {
        let _ = writeln!(w, "    trial_speeds: [{} rpm, {} rpm]", num(a), num(b));
    }
    let _ = writeln!(w);
}

/// Writes `measurements:`, one set of every measured FRF named from the recipe's folder, when
/// the case has any.
fn write_measurements(
    w: &mut String,
    frfs: &[CaseFrf],
    data_path: &impl Fn(&str) -> Result<String, ImportError>,
) -> Result<(), ImportError> {
    if frfs.is_empty() {
        return Ok(());
    }
    let _ = writeln!(w, "# Every measured FRF; each file's header gives its direction and speed.");
    let _ = writeln!(w, "measurements:");
    let _ = writeln!(w, "  tool_tip:");
    let _ = writeln!(w, "    files:");
    for f in frfs {
        let _ =
            writeln!(w, "      - {}   # {}, {} rpm", yaml_quoted(&data_path(&f.file)?), f.direction, num(f.speed_rpm));
    }
    let units: Vec<&str> = frfs.iter().filter_map(|f| f.units.as_deref()).collect();
    if let Some(u) = units.first().filter(|u| units.iter().all(|v| v == *u)) {
        let _ = writeln!(w, "    units: {}", scalar(u));
    }
    let _ = writeln!(w);
    Ok(())
}

/// Writes `steps:`: the holder and tool model, then the measured and the cutting configurations
/// where the case has them.
fn write_steps(
    w: &mut String,
    case: &Case,
    frfs: &[CaseFrf],
    trials_file: Option<&str>,
    data_path: &impl Fn(&str) -> Result<String, ImportError>,
) -> Result<(), ImportError> {
    let _ = writeln!(w, "steps:");
    let _ = writeln!(w, "  # The holder and tool reduced once to their tip and spindle end.");
    let _ = writeln!(w, "  holder_tool_model:");
    let _ = writeln!(w, "    kind: {BEAM_SUBSTRUCTURE}");
    let _ = writeln!(w, "    params: {{ assembly: holder_tool, max_element: 2 mm }}");
    if !frfs.is_empty() {
        write_measured_steps(w, case.sensor.is_some());
    }
    if let Some(c) = &case.cutting {
        write_cutting_steps(w, c, frfs, trials_file, data_path)?;
    }
    Ok(())
}

/// Writes the measured configuration's steps: the spindle on the files' lines, the coupled
/// model and its gap.
fn write_measured_steps(w: &mut String, with_sensor: bool) {
    let _ = writeln!(w);
    let _ = writeln!(w, "  # Measured configuration: on each file's lines, direction and speed.");
    let _ = writeln!(w, "  spindle:");
    let _ = writeln!(w, "    kind: {SPINDLE_RECEPTANCE}");
    let _ = writeln!(w, "    params: {{ machine: test_spindle }}");
    let _ = writeln!(w, "    inputs: {{ grid: \"@tool_tip.frf\" }}");
    let _ = writeln!(w, "  measured_model:");
    let _ = writeln!(w, "    kind: {RCSA_COUPLE}");
    if with_sensor {
        let _ = writeln!(
            w,
            "    params: {{ interface: machine, machine: test_spindle, sensor: sensor }}   # the sensor's mass sits on the tool tip"
        );
    } else {
        let _ = writeln!(w, "    params: {{ interface: machine, machine: test_spindle }}");
    }
    let _ = writeln!(w, "    inputs: {{ spindle: \"@spindle.receptance\", structure: \"@holder_tool_model.model\" }}");
    let _ = writeln!(w, "  # Model against measurement, in units of the measurement's noise (about 1 at the floor).");
    let _ = writeln!(w, "  gap:");
    let _ = writeln!(w, "    kind: {FRF_GAP}");
    let _ = writeln!(w, "    inputs: {{ model: \"@measured_model.frf\", measured: \"@tool_tip.frf\" }}");
}

/// The speed sweep of the cutting configuration, `(lo, hi, step)` in rpm: over the measured and
/// the trials' speeds.
fn cutting_speed_grid(frfs: &[CaseFrf], c: &CaseCutting) -> (f64, f64, f64) {
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
    (lo, hi, step)
}

/// Writes the cutting configuration's steps: the spindle swept over speed, the coupled model,
/// its lobes and the trials.
fn write_cutting_steps(
    w: &mut String,
    c: &CaseCutting,
    frfs: &[CaseFrf],
    trials_file: Option<&str>,
    data_path: &impl Fn(&str) -> Result<String, ImportError>,
) -> Result<(), ImportError> {
    let (lo, hi, step) = cutting_speed_grid(frfs, c);
    let _ = writeln!(w);
    let _ = writeln!(w, "  # Cutting configuration: no sensor; x and y over the speeds of the trials.");
    let _ = writeln!(w, "  spindle_cutting:");
    let _ = writeln!(w, "    kind: {SPINDLE_RECEPTANCE}");
    let _ = writeln!(w, "    params: {{ machine: test_spindle, max_frequency: 10 kHz, resolution: 2.5 Hz }}");
    let _ = writeln!(w, "    sweep:");
    let _ = writeln!(w, "      direction: [x, y]");
    let _ = writeln!(w, "      speed: {}..{} step {} rpm", num(lo), num(hi), num(step));
    let _ = writeln!(w, "  cutting_model:");
    let _ = writeln!(w, "    kind: {RCSA_COUPLE}");
    let _ = writeln!(w, "    params: {{ interface: machine, machine: test_spindle }}");
    let _ = writeln!(
        w,
        "    inputs: {{ spindle: \"@spindle_cutting.receptance\", structure: \"@holder_tool_model.model\" }}"
    );
    let _ = writeln!(w, "  lobes:");
    let _ = writeln!(w, "    kind: {STABILITY_SPEED_DEPENDENT}");
    match c.trial_rpm_range {
        Some([a, b]) => {
            let _ = writeln!(w, "    params: {{ cutting: trials, speeds: {}..{} step 5 rpm }}", num(a), num(b));
        }
        None => {
            let _ = writeln!(w, "    params: {{ cutting: trials }}");
        }
    }
    let _ = writeln!(w, "    inputs: {{ frfs: \"@cutting_model.frf\" }}");
    if let Some(t) = trials_file {
        let _ = writeln!(w, "  trials:");
        let _ = writeln!(w, "    kind: {TRIALS_SCORE}");
        let _ = writeln!(w, "    params: {{ file: {} }}", yaml_quoted(&data_path(t)?));
        let _ = writeln!(w, "    inputs: {{ lobes: \"@lobes.speed_dependent\" }}");
    }
    Ok(())
}

/// Writes `outputs:`: the gap table and model-over-measurement plots, then the lobes with the
/// trials, as the steps exist.
fn write_outputs(w: &mut String, measured: bool, cutting: bool, trials: bool) {
    if !measured && !cutting {
        return;
    }
    let _ = writeln!(w);
    let _ = writeln!(w, "outputs:");
    if measured {
        let _ = writeln!(
            w,
            "  # The gap per measured file, and the measured configuration over each measurement, one plot per file."
        );
        let _ = writeln!(w, "  - {{ from: \"@gap.summary\", file: gap.csv }}");
        let _ = writeln!(
            w,
            "  - {{ from: \"@measured_model.frf\", label: model, with: [{{ from: \"@tool_tip.frf\", label: measured }}], \
             file: \"model-vs-measured-{{file}}.svg\" }}"
        );
    }
    if cutting {
        if trials {
            let _ =
                writeln!(w, "  # The lobes of the cutting configuration with the trials on them, and the verdicts.");
            let _ = writeln!(
                w,
                "  - {{ from: \"@lobes.speed_dependent\", label: stability limit, with: [{{ from: \"@trials.verdicts\", \
                 label: cutting trials }}], file: lobes.svg }}"
            );
            let _ = writeln!(w, "  - {{ from: \"@trials.verdicts\", file: trial-verdicts.csv }}");
        } else {
            let _ = writeln!(w, "  # The lobes of the cutting configuration.");
            let _ = writeln!(w, "  - {{ from: \"@lobes.speed_dependent\", label: stability limit, file: lobes.svg }}");
        }
        let _ = writeln!(w, "  - {{ from: \"@lobes.table\", file: lobes.csv }}");
    }
}

/// Writes the closing comment: how many FRFs were measured, and on which frequency lines.
fn write_measurement_note(w: &mut String, m: &CaseMeasurements) {
    let _ = writeln!(w);
    let _ = writeln!(
        w,
        "# {} measured FRFs{}.",
        m.frf.len(),
        match (m.frequency_lines, m.frequency_step_hz) {
            (Some(n), Some(df)) => format!(", {n} lines every {} Hz", num(df)),
            _ => String::new(),
        }
    );
}

#[cfg(test)]
mod tests {
    use super::{EntityKind, choices, num, scalar, yaml_quoted};

    #[test]
    fn choice_words_come_from_the_engine_s_field_tables() {
        assert_eq!(choices(EntityKind::Cutting, &["milling"]), &["up", "down"]);
        assert!(choices(EntityKind::Assembly, &["sections", "component"]).contains(&"holder+tool"));
        assert!(choices(EntityKind::Assembly, &["sections", "kind"]).contains(&"plain"));
        assert!(choices(EntityKind::Sensor, &["kind"]).contains(&"accelerometer"));
        assert!(choices(EntityKind::Sensor, &["location"]).is_empty(), "free text has no words");
    }

    #[test]
    fn strings_are_plain_only_where_yaml_reads_them_as_the_same_text() {
        assert_eq!(scalar("holder+tool"), "holder+tool");
        assert_eq!(scalar("m/N"), "m/N");
        for s in ["true", "Null", "y", "a b", "1e3", "", "-x", "a:b", "inf"] {
            assert!(scalar(s).starts_with('"'), "{s}");
        }
        assert_eq!(yaml_quoted("a\"b\\c\n\u{1b}\0\u{7f}\u{2028}\u{feff}é"), r#""a\"b\\c\n\e\0\x7F\L\uFEFFé""#);
    }

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
