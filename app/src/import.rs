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
use crate::engine::syntax::emit::{Notes, emit_noted, inline};
use crate::engine::syntax::{Raw, yaml_quoted};
use serde::Deserialize;
use spindlelab_stdlib::nodes::kinds::{
    BEAM_SUBSTRUCTURE, FRF_GAP, RCSA_COUPLE, SPINDLE_RECEPTANCE, STABILITY_SPEED_DEPENDENT, TRIALS_SCORE,
};
use std::collections::BTreeMap;
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

/// The fastest spindle speed a case may state: beyond any machine tool's spindle.
const MAX_SPEED_RPM: f64 = 1e6;

/// Checks every spindle speed of the case: finite, not negative, below [`MAX_SPEED_RPM`]; the
/// first that is not is the error, naming its field.
fn check_speeds(case: &Case) -> Result<(), String> {
    let mut speeds: Vec<(String, f64)> = Vec::new();
    if let Some(m) = &case.measurements {
        speeds.extend(m.frf.iter().enumerate().map(|(i, f)| (format!("measurements.frf[{i}].speed_rpm"), f.speed_rpm)));
    }
    speeds.extend(case.spindle.ref_speed_rpm.map(|v| ("spindle.ref_speed_rpm".to_string(), v)));
    if let Some(c) = &case.cutting {
        speeds.extend(
            c.coefficients_calibrated_at_rpm.map(|v| ("cutting.coefficients_calibrated_at_rpm".to_string(), v)),
        );
        if let Some([a, b]) = c.trial_rpm_range {
            speeds
                .extend([("cutting.trial_rpm_range[0]".to_string(), a), ("cutting.trial_rpm_range[1]".to_string(), b)]);
        }
    }
    match speeds.into_iter().find(|(_, v)| !(0.0..=MAX_SPEED_RPM).contains(v)) {
        Some((field, v)) => Err(format!(
            "`{field}` is {} rpm; a spindle speed is between 0 and {} rpm: correct it in the case file",
            spindlelab_domain::sig(v, 6),
            spindlelab_domain::sig(MAX_SPEED_RPM, 6)
        )),
        None => Ok(()),
    }
}

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
    Ok(import_parts(json, path, None)?.recipe())
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
    Ok(import_parts(json, path, Some(placement))?.recipe())
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
    let mut notes = parts.notes.clone();
    notes.before(
        &[],
        format!(
            "Entities of case {}, imported from {}: materials, the spindle, the holder and tool,\n\
             the sensor and the cutting setup. Recipes take them with `use:`.",
            shown_word(&parts.id),
            shown_word(&parts.file_name)
        ),
    );
    let mut top = vec![("spindlelab".to_string(), Raw::int(1))];
    top.extend(separated(&parts.entities, &mut notes));
    let library = emit_noted(&Raw::mapping(top), &notes);

    let mut notes = parts.notes.clone();
    parts.head(&mut notes);
    let mut top = parts.title();
    let uses = vec![("use".to_string(), Raw::list(vec![Raw::text(use_path)]))];
    notes.before(&["use"], "Materials, machine, assemblies, sensor and cutting setup: the case's library.");
    top.extend(separated(&uses, &mut notes));
    top.extend(separated(&parts.rest, &mut notes));
    let recipe = emit_noted(&Raw::mapping(top), &notes);
    Ok((library, recipe))
}

/// A recipe written from a case: its entity sections, the rest (measurements, steps and
/// outputs) and the comments of both.
struct Parts {
    id: String,
    file_name: String,
    entities: Vec<(String, Raw)>,
    rest: Vec<(String, Raw)>,
    notes: Notes,
    /// The recipe's closing comment: how many FRFs were measured, on which lines.
    closing: Option<String>,
}

impl Parts {
    /// The format version and the recipe's name.
    fn title(&self) -> Vec<(String, Raw)> {
        vec![("spindlelab".to_string(), Raw::int(1)), ("name".to_string(), Raw::text(&self.id))]
    }

    /// The recipe's opening and closing comments: the case and its file, what the recipe
    /// compares, and the measurements.
    fn head(&self, notes: &mut Notes) {
        if let Some(c) = &self.closing {
            notes.end(c);
        }
        notes.before(
            &[],
            format!(
                "Baseline model of case {}, imported from {}.\n\
                 The measured configuration (sensor on the tool) is compared with every measured FRF;\n\
                 the cutting configuration (no sensor) gives the lobes that score the cutting trials.",
                shown_word(&self.id),
                shown_word(&self.file_name)
            ),
        );
    }

    /// The whole recipe: entities and steps in one file.
    fn recipe(&self) -> String {
        let mut notes = self.notes.clone();
        self.head(&mut notes);
        let mut top = self.title();
        top.extend(separated(&self.entities, &mut notes));
        top.extend(separated(&self.rest, &mut notes));
        emit_noted(&Raw::mapping(top), &notes)
    }
}

/// `sections`, each after a blank line.
fn separated(sections: &[(String, Raw)], notes: &mut Notes) -> Vec<(String, Raw)> {
    for (key, _) in sections {
        notes.blank(&[key]);
    }
    sections.to_vec()
}

/// A string as a comment quotes it: as the recipe would write it.
fn shown_word(s: &str) -> String {
    inline(&Raw::text(s)).unwrap_or_default()
}

/// A number as a person writes it (see [`num`]): whole numbers as integers.
fn number(x: f64) -> Raw {
    let r: f64 = num(x).parse().unwrap_or(x);
    if r.fract() == 0.0 && r.abs() < 1e15 { Raw::int(r as i64) } else { Raw::float(r) }
}

/// A quantity with its unit, `x` already in that unit: `63.5 mm`.
fn quantity(x: f64, unit: &str) -> Raw {
    Raw::text(format!("{} {unit}", num(x)))
}

/// A one-line mapping of the entries given, in order.
fn map<const N: usize>(entries: [(&str, Raw); N]) -> Raw {
    Raw::mapping(entries)
}

fn import_parts(json: &str, path: &str, placement: Option<Placement<'_>>) -> Result<Parts, ImportError> {
    let case: Case = serde_json::from_str(json).map_err(|source| ImportError::Json { path: path.into(), source })?;
    let invalid = |message: String| ImportError::Invalid { path: path.into(), message };
    check_strings(&case).map_err(invalid)?;
    check_speeds(&case).map_err(invalid)?;
    let data_path = |file: &str| match placement {
        Some(p) => p.data_path(file).map_err(|m| ImportError::Invalid { path: path.into(), message: m }),
        None => Ok(file.to_string()),
    };
    let id = case.case_id.clone().unwrap_or_else(|| "case".into());
    let file_name = path.rsplit('/').next().unwrap_or(path).to_string();
    let mut notes = Notes::default();

    let (materials, spindle_material) = materials(&case, &mut notes);
    let mut entities = vec![("materials".to_string(), materials)];
    entities.push(("machines".into(), machines(&case, &spindle_material, &mut notes).map_err(invalid)?));
    entities.push(("assemblies".into(), assemblies(&case.holder_tool)));
    if let Some(s) = &case.sensor {
        entities.push(("sensors".into(), sensors(s)));
    }
    if let Some(c) = &case.cutting {
        entities.push(("cutting".into(), cutting(c, &mut notes)));
    }

    let mut rest = Vec::new();
    let meas = case.measurements.as_ref();
    let frfs: &[CaseFrf] = meas.map_or(&[], |m| &m.frf);
    let trials_file = meas.and_then(|m| m.trials.as_deref());
    if !frfs.is_empty() {
        rest.push(("measurements".to_string(), measurements(path, frfs, &data_path, &mut notes)?));
    }
    rest.push(("steps".into(), steps(&case, frfs, trials_file, &data_path, &mut notes)?));
    let cutting = case.cutting.is_some();
    if let Some(o) = outputs(!frfs.is_empty(), cutting, cutting && trials_file.is_some(), &mut notes) {
        rest.push(("outputs".into(), o));
    }
    let closing = meas.map(|m| {
        format!(
            "{} measured FRFs{}.",
            m.frf.len(),
            match (m.frequency_lines, m.frequency_step_hz) {
                (Some(n), Some(df)) => format!(", {n} lines every {} Hz", num(df)),
                _ => String::new(),
            }
        )
    });
    Ok(Parts { id, file_name, entities, rest, notes, closing })
}

/// `materials:` (the holder's and tool's, then the spindle's under a name of its own), and
/// that name.
fn materials(case: &Case, notes: &mut Notes) -> (Raw, String) {
    let mut entries = Vec::new();
    for (name, m) in &case.materials {
        let mut fields = vec![("E", quantity(m.e_pa / 1e9, "GPa")), ("rho", quantity(m.rho_kg_m3, "kg/m^3"))];
        if let Some(nu) = m.nu {
            fields.push(("nu", number(nu)));
        }
        fields.push(("eta", number(m.eta.unwrap_or(0.0))));
        entries.push((name.clone(), Raw::mapping(fields)));
    }
    let mut spindle_material = "spindle_steel".to_string();
    while case.materials.contains_key(&spindle_material) {
        spindle_material.push('_');
    }
    let sm = &case.spindle.material;
    let mut fields = vec![("E", quantity(sm.e_pa / 1e9, "GPa")), ("rho", quantity(sm.rho_kg_m3, "kg/m^3"))];
    match sm.nu {
        Some(nu) => fields.push(("nu", number(nu))),
        None => {
            notes.after(&["materials", &spindle_material], "no Poisson's ratio: the spindle's beams do not use one");
        }
    }
    entries.push((spindle_material.clone(), Raw::mapping(fields)));
    (Raw::mapping(entries), spindle_material)
}

/// `machines:`: the spindle's modes per direction, their speed laws and the holder joint.
fn machines(case: &Case, spindle_material: &str, notes: &mut Notes) -> Result<Raw, String> {
    let directions = case.spindle.modes.keys().map(Raw::text).collect();
    let modes = case.spindle.modes.iter().map(|(dir, modes)| {
        let modes = modes.iter().map(|m| {
            let mut fields =
                vec![("f", quantity(m.f_hz, "Hz")), ("d", quantity(m.d_m * 1e3, "mm")), ("eta", number(m.eta))];
            if let Some(kf) = m.kf.filter(|k| *k != 0.0) {
                fields.push(("kf", number(kf)));
            }
            if let Some(keta) = m.keta.filter(|k| *k != 0.0) {
                fields.push(("keta", number(keta)));
            }
            Raw::mapping(fields)
        });
        (dir.clone(), Raw::list(modes.collect()))
    });
    notes.before(
        &["machines", "test_spindle", "spindle", "modes"],
        "Equivalent clamped-free Euler–Bernoulli beams, one per mode; f(n) = f (1 + kf (n/ref_speed)^2).",
    );
    let spindle = map([
        ("material", Raw::text(spindle_material)),
        ("ref_speed", quantity(case.spindle.ref_speed_rpm.unwrap_or(10_000.0), "rpm")),
        ("modes", Raw::mapping(modes)),
    ]);
    let machine = map([
        ("directions", Raw::list(directions)),
        ("spindle", spindle),
        ("holder_interface", holder_interface(&case.holder_spindle_interface)?),
    ]);
    Ok(map([("test_spindle", machine)]))
}

/// The machine's `holder_interface`: rigid, or its stiffness and damping; an error when the
/// case gives neither.
fn holder_interface(j: &CaseJoint) -> Result<Raw, String> {
    match (j.rigid, j.kt_n_per_m, j.ct_ns_per_m, j.kr_nm_per_rad, j.cr_nms_per_rad) {
        (Some(true), ..) => Ok(map([("rigid", Raw::bool(true))])),
        (_, Some(kt), ct, Some(kr), cr) => Ok(map([
            ("kt", quantity(kt, "N/m")),
            ("ct", quantity(ct.unwrap_or(0.0), "N*s/m")),
            ("kr", quantity(kr, "N*m/rad")),
            ("cr", quantity(cr.unwrap_or(0.0), "N*m*s/rad")),
        ])),
        _ => Err("`holder_spindle_interface` is neither rigid nor gives kt and kr".into()),
    }
}

/// `assemblies:`: the holder and tool, section by section from the spindle end to the tip.
fn assemblies(holder_tool: &HolderTool) -> Raw {
    let sections = holder_tool.sections.iter().map(|s| {
        let mut fields = vec![("name", Raw::text(&s.name)), ("component", Raw::text(&s.component))];
        if let Some(k) = s.kind.as_deref().filter(|k| *k != "plain") {
            fields.push(("kind", Raw::text(k)));
        }
        fields.push(("d_out", quantity(s.d_out_spindle_end_m * 1e3, "mm")));
        if let Some(tip) = s.d_out_tip_end_m.filter(|t| *t != s.d_out_spindle_end_m) {
            fields.push(("d_out_tip", quantity(tip * 1e3, "mm")));
        }
        if let Some(d) = s.d_in_m.filter(|d| *d > 0.0) {
            fields.push(("d_in", quantity(d * 1e3, "mm")));
        }
        fields.push(("length", quantity(s.length_m * 1e3, "mm")));
        fields.push(("outer", Raw::text(&s.outer_material)));
        if let Some(inner) = &s.inner_material {
            fields.push(("inner", Raw::text(inner)));
        }
        Raw::mapping(fields)
    });
    map([("holder_tool", map([("sections", Raw::list(sections.collect()))]))])
}

/// `sensors:`: the case's sensor, its kind, location and mass.
fn sensors(s: &CaseSensor) -> Raw {
    let mut fields = vec![("kind", Raw::text(&s.kind))];
    if let Some(l) = &s.location {
        fields.push(("location", Raw::text(l)));
    }
    fields.push(("mass", quantity(s.mass_kg.unwrap_or(0.0) * 1e3, "g")));
    map([("sensor", Raw::mapping(fields))])
}

/// `cutting:`: the trials' setup (teeth, immersion, coefficients and speed range).
fn cutting(c: &CaseCutting, notes: &mut Notes) -> Raw {
    let mut fields = vec![
        ("teeth", Raw::int(i64::from(c.teeth))),
        ("radial_immersion", number(c.radial_immersion)),
        ("milling", Raw::text(&c.milling)),
        ("Ks", quantity(c.ks / 1e6, "MPa")),
        ("beta", quantity(c.beta_deg, "deg")),
    ];
    notes.after(&["cutting", "trials", "radial_immersion"], "radial depth / tool diameter");
    if let Some(n) = c.coefficients_calibrated_at_rpm {
        fields.push(("calibrated_at", quantity(n, "rpm")));
    }
    if let Some(m) = &c.workpiece_material {
        fields.push(("workpiece", Raw::text(m)));
    }
    if let Some([a, b]) = c.trial_rpm_range {
        fields.push(("trial_speeds", Raw::list(vec![quantity(a, "rpm"), quantity(b, "rpm")])));
    }
    map([("trials", Raw::mapping(fields))])
}

/// `measurements:`, one set of every measured FRF named from the recipe's folder.
fn measurements(
    path: &str,
    frfs: &[CaseFrf],
    data_path: &impl Fn(&str) -> Result<String, ImportError>,
    notes: &mut Notes,
) -> Result<Raw, ImportError> {
    notes.before(&["measurements"], "Every measured FRF; each file's header gives its direction and speed.");
    let mut files = Vec::new();
    for (i, f) in frfs.iter().enumerate() {
        files.push(Raw::text(data_path(&f.file)?));
        let at = i.to_string();
        notes.after(&["measurements", "tool_tip", "files", &at], format!("{}, {} rpm", f.direction, num(f.speed_rpm)));
    }
    let mut set = vec![("files", Raw::list(files))];
    let units: Vec<(usize, &str)> =
        frfs.iter().enumerate().filter_map(|(i, f)| Some((i, f.units.as_deref()?))).collect();
    if let Some(&(i, other)) = units.iter().find(|(_, u)| *u != units[0].1) {
        return Err(ImportError::Invalid {
            path: path.into(),
            message: format!(
                "`measurements.frf[{i}].units` is {} where `measurements.frf[{}].units` is {}: a recipe reads the measured FRFs as one set, in one unit; convert the files to one unit and correct the case",
                shown(other),
                units[0].0,
                shown(units[0].1)
            ),
        });
    }
    if let Some(&(_, u)) = units.first() {
        set.push(("units", Raw::text(u)));
    }
    Ok(map([("tool_tip", Raw::mapping(set))]))
}

/// A step: its kind, parameters and inputs (each left out when empty), and its sweep.
fn step(kind: &str, params: Vec<(&str, Raw)>, inputs: Vec<(&str, Raw)>, sweep: Option<Raw>) -> Raw {
    let mut fields = vec![("kind", Raw::text(kind))];
    if !params.is_empty() {
        fields.push(("params", Raw::mapping(params)));
    }
    if !inputs.is_empty() {
        fields.push(("inputs", Raw::mapping(inputs)));
    }
    if let Some(s) = sweep {
        fields.push(("sweep", s));
    }
    Raw::mapping(fields)
}

/// `steps:`: the holder and tool model, then the measured and the cutting configurations where
/// the case has them.
fn steps(
    case: &Case,
    frfs: &[CaseFrf],
    trials_file: Option<&str>,
    data_path: &impl Fn(&str) -> Result<String, ImportError>,
    notes: &mut Notes,
) -> Result<Raw, ImportError> {
    notes.before(&["steps", "holder_tool_model"], "The holder and tool reduced once to their tip and spindle end.");
    let mut steps = vec![(
        "holder_tool_model",
        step(
            BEAM_SUBSTRUCTURE,
            vec![("assembly", Raw::text("holder_tool")), ("max_element", Raw::text("2 mm"))],
            vec![],
            None,
        ),
    )];
    if !frfs.is_empty() {
        steps.extend(measured_steps(case.sensor.is_some(), notes));
    }
    if let Some(c) = &case.cutting {
        steps.extend(cutting_steps(c, frfs, trials_file, data_path, notes)?);
    }
    Ok(Raw::mapping(steps))
}

/// The measured configuration's steps: the spindle on the files' lines, the coupled model and
/// its gap.
fn measured_steps(with_sensor: bool, notes: &mut Notes) -> Vec<(&'static str, Raw)> {
    notes
        .blank(&["steps", "spindle"])
        .before(&["steps", "spindle"], "Measured configuration: on each file's lines, direction and speed.");
    let spindle = step(
        SPINDLE_RECEPTANCE,
        vec![("machine", Raw::text("test_spindle"))],
        vec![("grid", Raw::port("tool_tip", "frf"))],
        None,
    );
    let mut params = vec![("interface", Raw::text("machine")), ("machine", Raw::text("test_spindle"))];
    if with_sensor {
        params.push(("sensor", Raw::text("sensor")));
        notes.after(&["steps", "measured_model", "params"], "the sensor's mass sits on the tool tip");
    }
    let model = step(
        RCSA_COUPLE,
        params,
        vec![("spindle", Raw::port("spindle", "receptance")), ("structure", Raw::port("holder_tool_model", "model"))],
        None,
    );
    notes.before(
        &["steps", "gap"],
        "Model against measurement, in units of the measurement's noise (about 1 at the floor).",
    );
    let gap = step(
        FRF_GAP,
        vec![],
        vec![("model", Raw::port("measured_model", "frf")), ("measured", Raw::port("tool_tip", "frf"))],
        None,
    );
    vec![("spindle", spindle), ("measured_model", model), ("gap", gap)]
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

/// The cutting configuration's steps: the spindle swept over speed, the coupled model, its
/// lobes and the trials.
fn cutting_steps(
    c: &CaseCutting,
    frfs: &[CaseFrf],
    trials_file: Option<&str>,
    data_path: &impl Fn(&str) -> Result<String, ImportError>,
    notes: &mut Notes,
) -> Result<Vec<(&'static str, Raw)>, ImportError> {
    let (lo, hi, step_rpm) = cutting_speed_grid(frfs, c);
    notes.blank(&["steps", "spindle_cutting"]).before(
        &["steps", "spindle_cutting"],
        "Cutting configuration: no sensor; x and y over the speeds of the trials.",
    );
    let sweep = map([
        ("direction", Raw::list(vec![Raw::text("x"), Raw::text("y")])),
        ("speed", Raw::text(format!("{}..{} step {} rpm", num(lo), num(hi), num(step_rpm)))),
    ]);
    let spindle = step(
        SPINDLE_RECEPTANCE,
        vec![
            ("machine", Raw::text("test_spindle")),
            ("max_frequency", Raw::text("10 kHz")),
            ("resolution", Raw::text("2.5 Hz")),
        ],
        vec![],
        Some(sweep),
    );
    let model = step(
        RCSA_COUPLE,
        vec![("interface", Raw::text("machine")), ("machine", Raw::text("test_spindle"))],
        vec![
            ("spindle", Raw::port("spindle_cutting", "receptance")),
            ("structure", Raw::port("holder_tool_model", "model")),
        ],
        None,
    );
    let mut params = vec![("cutting", Raw::text("trials"))];
    if let Some([a, b]) = c.trial_rpm_range {
        params.push(("speeds", Raw::text(format!("{}..{} step 5 rpm", num(a), num(b)))));
    }
    let lobes = step(STABILITY_SPEED_DEPENDENT, params, vec![("frfs", Raw::port("cutting_model", "frf"))], None);
    let mut steps = vec![("spindle_cutting", spindle), ("cutting_model", model), ("lobes", lobes)];
    if let Some(t) = trials_file {
        let trials = step(
            TRIALS_SCORE,
            vec![("file", Raw::text(data_path(t)?))],
            vec![("lobes", Raw::port("lobes", "speed_dependent"))],
            None,
        );
        steps.push(("trials", trials));
    }
    Ok(steps)
}

/// An output: a port written to `file`, with a label and the ports drawn with it.
fn output(from: Raw, label: Option<&str>, with: Option<(Raw, &str)>, file: &str) -> Raw {
    let mut fields = vec![("from", from)];
    if let Some(l) = label {
        fields.push(("label", Raw::text(l)));
    }
    if let Some((w, l)) = with {
        fields.push(("with", Raw::list(vec![map([("from", w), ("label", Raw::text(l))])])));
    }
    fields.push(("file", Raw::text(file)));
    Raw::mapping(fields)
}

/// `outputs:`: the gap table and model-over-measurement plots, then the lobes with the trials,
/// as the steps exist; `None` without either.
fn outputs(measured: bool, cutting: bool, trials: bool, notes: &mut Notes) -> Option<Raw> {
    let mut outputs = Vec::new();
    if measured {
        notes.before(
            &["outputs", "0"],
            "The gap per measured file, and the measured configuration over each measurement, one plot per file.",
        );
        outputs.push(output(Raw::port("gap", "summary"), None, None, "gap.csv"));
        outputs.push(output(
            Raw::port("measured_model", "frf"),
            Some("model"),
            Some((Raw::port("tool_tip", "frf"), "measured")),
            "model-vs-measured-{file}.svg",
        ));
    }
    if cutting {
        let at = outputs.len().to_string();
        let lobes = Raw::port("lobes", "speed_dependent");
        if trials {
            notes.before(
                &["outputs", &at],
                "The lobes of the cutting configuration with the trials on them, and the verdicts.",
            );
            let verdicts = Raw::port("trials", "verdicts");
            outputs.push(output(
                lobes,
                Some("stability limit"),
                Some((verdicts.clone(), "cutting trials")),
                "lobes.svg",
            ));
            outputs.push(output(verdicts, None, None, "trial-verdicts.csv"));
        } else {
            notes.before(&["outputs", &at], "The lobes of the cutting configuration.");
            outputs.push(output(lobes, Some("stability limit"), None, "lobes.svg"));
        }
        outputs.push(output(Raw::port("lobes", "table"), None, None, "lobes.csv"));
    }
    (!outputs.is_empty()).then(|| Raw::list(outputs))
}

#[cfg(test)]
mod tests {
    use super::{EntityKind, choices, num};

    #[test]
    fn choice_words_come_from_the_engine_s_field_tables() {
        assert_eq!(choices(EntityKind::Cutting, &["milling"]), &["up", "down"]);
        assert!(choices(EntityKind::Assembly, &["sections", "component"]).contains(&"holder+tool"));
        assert!(choices(EntityKind::Assembly, &["sections", "kind"]).contains(&"plain"));
        assert!(choices(EntityKind::Sensor, &["kind"]).contains(&"accelerometer"));
        assert!(choices(EntityKind::Sensor, &["location"]).is_empty(), "free text has no words");
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
