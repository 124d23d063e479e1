//! Raw tree → resolved recipe. Collects every diagnostic; returns a recipe only when there are no errors.

use super::entities::{
    self, Assembly, Component, Cutting, Joint, Machine, Material, Section, Sensor, Spindle, SpindleMode,
};
use super::{
    Binding, FORMAT_VERSION, Output, OutputFormat, PortRef, Recipe, Step, SweepAxis, valid_name, valid_step_name,
};
use crate::diag::{Diagnostics, Span};
use crate::node::{Node, NodeSpec, PortSpec, Registry};
use crate::plot::PlotFormat;
use crate::spec::{self, Ctx, EntityKind, EntityNames, Field, FieldType, ParamValue, Params, suggest};
use crate::syntax::{Key, Raw, RawKind};
use crate::value::PortType;
use indexmap::IndexMap;
use spindlelab_domain::{Speed, SpeedLaw};
use spindlelab_grammar::Dimension;

const TOP_KEYS: &[&str] = &[
    "spindlelab",
    "name",
    "description",
    "materials",
    "machines",
    "assemblies",
    "sensors",
    "cutting",
    "speeds",
    "steps",
    "outputs",
    "params",
    "fit",
    "measurements",
    "plugins",
    "use",
    "exports",
];
const STEP_KEYS: &[&str] = &["kind", "params", "inputs", "sweep", "description", "label"];
const OUTPUT_KEYS: &[&str] = &["from", "file", "with", "plot", "label", "unit"];

/// Files a run writes itself beside its outputs: the manifest, and a fit's report and recipe.
const RESERVED_OUTPUTS: &[&str] = &["manifest.json", "fit.json", "fitted.yaml", "report.html"];

/// Longest name of one file or folder, and of a whole path, that the file systems a run
/// writes to take (bytes).
const MAX_NAME_BYTES: usize = 255;
const MAX_PATH_BYTES: usize = 4096;

/// Why an output file name cannot be written on any common file system, if it cannot: a NUL
/// character, a file or folder name over 255 bytes, a path over 4096 bytes.
fn unwritable_name(name: &str) -> Option<String> {
    if name.contains('\0') {
        return Some("holds a NUL character, which no file name can".into());
    }
    if name.len() > MAX_PATH_BYTES {
        return Some(format!("is {} bytes long, beyond the {MAX_PATH_BYTES} bytes of a path", name.len()));
    }
    let longest = name.split('/').map(str::len).max().unwrap_or(0);
    if longest > MAX_NAME_BYTES {
        return Some(format!("has a part of {longest} bytes, beyond the {MAX_NAME_BYTES} bytes of a file name"));
    }
    None
}

/// A long name cut for a message: its first 60 characters and how long it is.
fn shorten(name: &str) -> String {
    let cut: String = name.chars().take(60).collect();
    if cut.len() < name.len() { format!("{cut}… ({} bytes)", name.len()) } else { cut }
}

fn unknown_keys(raw: &Raw, known: &[&str], what: &str, diags: &mut Diagnostics) {
    if let Some(entries) = raw.as_map() {
        for (k, _) in entries {
            if !known.contains(&k.name.as_str()) {
                let msg = format!("unknown key `{}` in {what}", k.name);
                match suggest(&k.name, known.iter().copied()) {
                    Some(s) => diags.error_help(Some(&k.span), msg, format!("did you mean `{s}`?")),
                    None => diags.error_help(Some(&k.span), msg, format!("known keys: {}", known.join(", "))),
                }
            }
        }
    }
}

/// Resolves a raw recipe against the node registry, with parameters set by `overrides`
/// (`name`, value text) in place of their declared values.
pub fn resolve(
    raw: &Raw,
    overrides: &[(String, String)],
    registry: &Registry,
    diags: &mut Diagnostics,
) -> Option<Recipe> {
    resolve_within(raw, overrides, registry, None, diags)
}

/// [`resolve`] for `--confine`: a data file named outside `confine` (the recipe's folder) is
/// refused by its name, before any byte of it is read or hashed.
pub fn resolve_within(
    raw: &Raw,
    overrides: &[(String, String)],
    registry: &Registry,
    confine: Option<&std::path::Path>,
    diags: &mut Diagnostics,
) -> Option<Recipe> {
    let errors_before = diags.error_count();
    let (substituted, params) = super::params::substitute(raw, overrides, diags);
    let base_dir = std::path::Path::new(&*raw.span.file).parent().map(std::path::Path::to_path_buf);
    let desugared =
        super::measurements::desugar(&substituted, base_dir.as_deref(), registry.measurement_reader(), diags);
    let raw = &desugared;
    let Some(_) = raw.as_map() else {
        diags.error_help(
            Some(&raw.span),
            format!("a recipe must be a mapping, found {}", raw.describe()),
            "start the file with `spindlelab: 1`",
        );
        return None;
    };
    unknown_keys(raw, TOP_KEYS, "the recipe", diags);
    match raw.get("spindlelab") {
        Some(Raw { kind: RawKind::Int(FORMAT_VERSION), .. }) => {}
        Some(v) => diags.error_help(
            Some(&v.span),
            format!("unsupported recipe version `{}`", v.scalar_text().unwrap_or_else(|| v.describe().into())),
            format!("this spindlelab reads `spindlelab: {FORMAT_VERSION}`"),
        ),
        None => {
            diags.error_help(Some(&raw.span), "missing the version key `spindlelab`", "add `spindlelab: 1` at the top")
        }
    }
    let name = match raw.get("name") {
        Some(Raw { kind: RawKind::Str(s), .. }) => s.clone(),
        Some(v) => {
            diags.error(Some(&v.span), "`name` must be text");
            String::new()
        }
        None => raw.span.file.rsplit('/').next().unwrap_or("recipe").trim_end_matches(".yaml").to_string(),
    };
    let description = raw.get("description").and_then(|d| d.as_str()).map(str::to_string);

    // Names first, so entities may refer to each other in any order.
    let mut names = EntityNames::default();
    for kind in EntityKind::ALL {
        let set = names.names.entry(kind).or_default();
        if let Some(section) = raw.get(kind.section()) {
            match section.as_map() {
                Some(entries) => {
                    for (k, _) in entries {
                        if !valid_name(&k.name) {
                            diags.error_help(
                                Some(&k.span),
                                format!("`{}` is not a valid {} name", k.name, kind.noun()),
                                "names start with a letter or `_` and hold letters, digits, `_` and `-`",
                            );
                        }
                        set.insert(k.name.clone());
                    }
                }
                None => diags.error(
                    Some(&section.span),
                    format!("`{}` must be a mapping of names to {}s", kind.section(), kind.noun()),
                ),
            }
        }
    }
    // File parameters are relative to the recipe's folder, for YAML and Rhai recipes alike
    // (the root value's span names the recipe file).
    let recipe_path = std::path::Path::new(&*raw.span.file);
    let ctx = Ctx { entities: &names, base_dir: recipe_path.parent(), confine };
    let mut checked: IndexMap<EntityKind, IndexMap<String, Params>> = IndexMap::new();
    for kind in EntityKind::ALL {
        let out = checked.entry(kind).or_default();
        let Some(entries) = raw.get(kind.section()).and_then(Raw::as_map) else { continue };
        for (k, v) in entries {
            let what = format!("{} `{}`", kind.noun(), k.name);
            if let Some(p) = spec::check_object(v, entities::fields(kind), &what, &ctx, diags) {
                check_entity_rules(kind, &k.name, v, &p, diags);
                out.insert(k.name.clone(), p);
            }
        }
    }
    let materials: IndexMap<String, Material> =
        checked[&EntityKind::Material].iter().map(|(n, p)| (n.clone(), entities::material(p))).collect();

    let speeds = match raw.get("speeds") {
        Some(v) => {
            match spec::check_value(v, &FieldType::QuantityList(Dimension::ROTATIONAL_SPEED), "`speeds`", &ctx, diags) {
                Some(ParamValue::List { values, .. }) => values,
                _ => Vec::new(),
            }
        }
        None => Vec::new(),
    };

    let steps = resolve_steps(raw.get("steps"), &raw.span, registry, &ctx, diags);
    check_poisson(raw, &checked, &materials, &steps, diags);
    let step_names: Vec<String> = raw
        .get("steps")
        .and_then(Raw::as_map)
        .map(|m| m.iter().map(|(k, _)| k.name.clone()).collect())
        .unwrap_or_default();
    let outputs = resolve_outputs(raw.get("outputs"), &steps, &step_names, registry, diags);
    check_exports(raw.get("exports"), &steps, &step_names, registry, diags);
    check_cycles(&steps, diags);
    let fit = raw.get("fit").and_then(|f| super::fit::resolve_fit(f, &params, &steps, registry, diags));

    if diags.error_count() > errors_before {
        return None;
    }
    let mut canonical = String::new();
    raw.canonical(&mut canonical);
    let hash = blake3::hash(canonical.as_bytes()).to_hex()[..16].to_string();
    let entity_digests = entity_digests(&checked);
    let mut entity_origins = IndexMap::new();
    for kind in EntityKind::ALL {
        for (k, _) in raw.get(kind.section()).and_then(Raw::as_map).unwrap_or(&[]) {
            let mut names = Vec::new();
            if let Some(p) = checked[&kind].get(&k.name) {
                p.values.values().for_each(|v| entity_names(v, &mut names));
            }
            let file = k.span.file.split(" (at ").next().unwrap_or(&k.span.file).to_string();
            entity_origins.insert((kind, k.name.clone()), super::EntityOrigin { file, names });
        }
    }
    Some(Recipe {
        name,
        description,
        hash,
        entity_digests,
        entity_origins,
        library: false,
        machines: checked[&EntityKind::Machine]
            .iter()
            .map(|(n, p)| (n.clone(), build_machine(p, &materials)))
            .collect(),
        assemblies: checked[&EntityKind::Assembly]
            .iter()
            .map(|(n, p)| (n.clone(), build_assembly(p, &materials)))
            .collect(),
        sensors: checked[&EntityKind::Sensor].iter().map(|(n, p)| (n.clone(), build_sensor(p))).collect(),
        cutting: checked[&EntityKind::Cutting].iter().map(|(n, p)| (n.clone(), build_cutting(p))).collect(),
        materials,
        speeds,
        steps,
        outputs,
        params,
        fit,
    })
}

/// The entities a checked value names, nested objects included.
fn entity_names(v: &ParamValue, out: &mut Vec<(EntityKind, String)>) {
    match v {
        ParamValue::Entity { kind, name } if !out.iter().any(|(k, n)| k == kind && n == name) => {
            out.push((*kind, name.clone()));
        }
        ParamValue::Object(p) => p.values.values().for_each(|v| entity_names(v, out)),
        ParamValue::Objects(ps) => ps.iter().flat_map(|p| p.values.values()).for_each(|v| entity_names(v, out)),
        ParamValue::Map(m) => m.values().for_each(|v| entity_names(v, out)),
        _ => {}
    }
}

/// The digest of every entity's contents, the entities it names included (an assembly's
/// materials), so a cache key that names an entity changes when its values do.
fn entity_digests(checked: &IndexMap<EntityKind, IndexMap<String, Params>>) -> IndexMap<(EntityKind, String), String> {
    fn digest_of(
        kind: EntityKind,
        name: &str,
        checked: &IndexMap<EntityKind, IndexMap<String, Params>>,
        depth: usize,
    ) -> Option<String> {
        let params = checked.get(&kind)?.get(name)?;
        let mut text = format!("{kind:?}:{name:?}=");
        // Entities name entities of other kinds only (assemblies and machines name
        // materials); the depth bound keeps a malformed recipe from recursing.
        let refs = |k: EntityKind, n: &str| if depth < 4 { digest_of(k, n, checked, depth + 1) } else { None };
        params.canonical_with(&mut text, &refs);
        Some(blake3::hash(text.as_bytes()).to_hex()[..16].to_string())
    }
    let mut out = IndexMap::new();
    for (kind, entries) in checked {
        for name in entries.keys() {
            if let Some(d) = digest_of(*kind, name, checked, 0) {
                out.insert((*kind, name.clone()), d);
            }
        }
    }
    out
}

/// Poisson's ratio may be left out of a material only where nothing uses it: Timoshenko
/// sections need it for the shear modulus, and steps that name a material (contact) too.
fn check_poisson(
    raw: &Raw,
    checked: &IndexMap<EntityKind, IndexMap<String, Params>>,
    materials: &IndexMap<String, Material>,
    steps: &[Step],
    diags: &mut Diagnostics,
) {
    let lacks = |name: &str| materials.get(name).is_some_and(|m| m.poisson.is_nan());
    let at = |name: &str| raw.get("materials").and_then(|m| m.get(name)).map(|v| v.span.clone());
    let mut reported: Vec<String> = Vec::new();
    for (aname, p) in &checked[&EntityKind::Assembly] {
        for s in p.objects("sections").unwrap_or(&[]) {
            for key in ["outer", "inner"] {
                if let Some(m) = s.text(key)
                    && lacks(m)
                    && !reported.iter().any(|r| r == m)
                {
                    reported.push(m.to_string());
                    diags.error_help(
                        at(m).as_ref(),
                        format!("material `{m}` has no `nu`, which the Timoshenko sections of assembly `{aname}` need for their shear stiffness"),
                        "add Poisson's ratio, e.g. `nu: 0.29` for steel",
                    );
                }
            }
        }
    }
    for step in steps {
        for (k, v) in &step.params.values {
            if let ParamValue::Entity { kind: EntityKind::Material, name } = v
                && lacks(name)
            {
                diags.error_help(
                    step.param_spans.get(k).or(at(name).as_ref()),
                    format!("step `{}` uses material `{name}` for contact, and it has no `nu`", step.id),
                    format!("add Poisson's ratio to material `{name}`, e.g. `nu: 0.29` for steel"),
                );
            }
        }
    }
}

/// Rules that cross fields: geometry that cannot exist, coefficient pairs, joints.
fn check_entity_rules(kind: EntityKind, name: &str, raw: &Raw, p: &Params, diags: &mut Diagnostics) {
    match kind {
        EntityKind::Material => {
            for (f, lo, hi) in [("E", 0.0, f64::INFINITY), ("rho", 0.0, f64::INFINITY), ("nu", -1.0, 0.5)] {
                // Poisson's ratio may be left out; what needs it says so.
                if f == "nu" && p.get(f).is_none() {
                    continue;
                }
                let v = p.f64(f).unwrap_or(f64::NAN);
                if !(v > lo && v < hi) {
                    let at = raw.get(f).map(|r| r.span.clone());
                    diags.error(at.as_ref(), format!("material `{name}`: `{f}` = {v} is outside ({lo}, {hi})"));
                }
            }
            // A negative loss factor would make the material give energy back.
            let eta = p.f64("eta").unwrap_or(0.0);
            if !(eta.is_finite() && eta >= 0.0) {
                let at = raw.get("eta").map(|r| r.span.clone());
                diags.error_help(
                    at.as_ref(),
                    format!("material `{name}`: loss factor `eta` = {eta} is negative"),
                    "a loss factor is 0 or more (steel about 0.001–0.02 with its joints)",
                );
            }
        }
        EntityKind::Assembly => {
            for (i, (s, sraw)) in p.objects("sections").unwrap_or(&[]).iter().zip(section_raws(raw)).enumerate() {
                let sname = s.text("name").unwrap_or("?");
                let d_out = s.f64("d_out").unwrap_or(0.0);
                let d_tip = s.f64("d_out_tip").unwrap_or(d_out);
                let d_in = s.f64("d_in").unwrap_or(0.0);
                let len = s.f64("length").unwrap_or(0.0);
                let at = |f: &str| sraw.get(f).map(|r| r.span.clone()).unwrap_or_else(|| sraw.span.clone());
                if len <= 0.0 {
                    diags.error_help(
                        Some(&at("length")),
                        format!("section {} (`{sname}`) of assembly `{name}` has zero or negative length", i + 1),
                        "give the section a positive length or remove it",
                    );
                }
                if d_out <= 0.0 || d_tip <= 0.0 {
                    diags.error(
                        Some(&at("d_out")),
                        format!("section `{sname}` of assembly `{name}`: outer diameter must be positive"),
                    );
                }
                if d_in < 0.0 || d_in >= d_out.min(d_tip) {
                    diags.error_help(
                        Some(&at("d_in")),
                        format!(
                            "section `{sname}` of assembly `{name}`: inner diameter {} mm is not below the outer diameter {} mm",
                            d_in * 1e3,
                            d_out.min(d_tip) * 1e3
                        ),
                        "the bore must be smaller than the outside",
                    );
                }
                if s.get("inner").is_some() && d_in <= 0.0 {
                    diags.error(
                        Some(&at("inner")),
                        format!("section `{sname}` of assembly `{name}` has a core material but no bore (`d_in`)"),
                    );
                }
                if s.get("d_equivalent").is_some() && s.text("kind") != Some("fluted") {
                    diags.error(
                        Some(&at("d_equivalent")),
                        format!("section `{sname}`: `d_equivalent` applies to a fluted section only"),
                    );
                }
            }
        }
        EntityKind::Cutting => {
            let a = p.f64("radial_immersion").unwrap_or(0.0);
            if !(a > 0.0 && a <= 1.0) {
                let at = raw.get("radial_immersion").map(|r| r.span.clone());
                diags.error_help(
                    at.as_ref(),
                    format!("cutting `{name}`: radial immersion {a} is outside (0, 1]"),
                    "write it as a fraction or a percentage, e.g. `25 %`",
                );
            }
            let ks = p.get("Ks").is_some() && p.get("beta").is_some();
            let ktn = p.get("Kt").is_some() && p.get("Kn").is_some();
            if ks == ktn {
                diags.error_help(
                    Some(&raw.span),
                    format!("cutting `{name}` needs exactly one coefficient pair"),
                    "give either `Ks` and `beta`, or `Kt` and `Kn`",
                );
            }
            let law = p.f64("Ks_change").is_some_and(|v| v != 0.0) || p.f64("beta_change").is_some_and(|v| v != 0.0);
            if law && p.get("calibrated_at").is_none() {
                diags.error_help(
                    Some(&raw.span),
                    format!("cutting `{name}` has a speed law (`Ks_change`, `beta_change`) but no `calibrated_at`"),
                    "give the speed the law is about, e.g. `calibrated_at: 12000 rpm`",
                );
            }
            if p.f64("change_per").is_some_and(|v| v.is_nan() || v <= 0.0) {
                let at = raw.get("change_per").map(|r| r.span.clone());
                diags.error_help(
                    at.as_ref(),
                    format!("cutting `{name}`: `change_per` must be a positive speed"),
                    "e.g. `change_per: 10000 rpm`",
                );
            }
        }
        EntityKind::Machine => {
            if let Some(jraw) = raw.get("holder_interface") {
                check_joint(name, jraw, p.object("holder_interface"), diags);
            }
            check_spindle_modes(name, raw, p, diags);
        }
        EntityKind::Sensor => {}
    }
    if kind == EntityKind::Assembly
        && let Some(jraw) = raw.get("tool_joint")
    {
        check_joint(name, jraw, p.object("tool_joint"), diags);
    }
}

/// A spindle mode is an equivalent beam (`d` and `eta`) or stated modally (`stiffness` and
/// `zeta`), one or the other, with a stiffness above 0 and a damping ratio in [0, 1).
fn check_spindle_modes(machine: &str, raw: &Raw, p: &Params, diags: &mut Diagnostics) {
    let (Some(modes), Some(mraw)) =
        (p.object("spindle").and_then(|s| s.get("modes")), raw.get("spindle").and_then(|s| s.get("modes")))
    else {
        return;
    };
    let ParamValue::Map(dirs) = modes else { return };
    for (dir, list) in dirs {
        let ParamValue::Objects(list) = list else { continue };
        let raws: Vec<&Raw> = match mraw.get(dir).map(|r| &r.kind) {
            Some(RawKind::Seq(items)) => items.iter().collect(),
            _ => Vec::new(),
        };
        for (i, m) in list.iter().enumerate() {
            let at = raws.get(i).map(|r| r.span.clone());
            let what = format!("machine `{machine}`: spindle mode {} in {dir}", i + 1);
            let beam = (m.get("d").is_some(), m.get("eta").is_some());
            let modal = (m.get("stiffness").is_some(), m.get("zeta").is_some());
            let help = "give `d` and `eta` (an equivalent beam) or `stiffness` and `zeta` (the mode's k and ζ)";
            match (beam, modal) {
                ((true, true), (false, false)) => {}
                ((false, false), (true, true)) => {
                    let (k, zeta) = (m.f64("stiffness").unwrap_or(f64::NAN), m.f64("zeta").unwrap_or(f64::NAN));
                    if !(k.is_finite() && k > 0.0) {
                        diags.error(at.as_ref(), format!("{what}: `stiffness` = {k} N/m must be above 0"));
                    }
                    if !(zeta.is_finite() && (0.0..1.0).contains(&zeta)) {
                        diags.error_help(
                            at.as_ref(),
                            format!("{what}: damping ratio `zeta` = {zeta} must be in [0, 1)"),
                            "a spindle mode's ζ is about 0.01–0.1 (`zeta: 3 %`)",
                        );
                    }
                }
                ((_, _), (false, false)) | ((false, false), (_, _)) => {
                    diags.error_help(at.as_ref(), format!("{what} is only half stated"), help)
                }
                _ => diags.error_help(at.as_ref(), format!("{what} is stated twice, as a beam and modally"), help),
            }
            if let Some(p) = m.f64("kk_exponent")
                && !(p.is_finite() && (0.5..=10.0).contains(&p))
            {
                diags.error_help(
                    at.as_ref(),
                    format!(
                        "{what}: bearing law exponent `kk_exponent` = {} must be in [0.5, 10]",
                        spindlelab_domain::sig(p, 6)
                    ),
                    "2 is the quadratic law; preloaded angular-contact bearings at high speed take 3–5",
                );
            }
        }
    }
}

fn check_joint(owner: &str, raw: &Raw, p: Option<&Params>, diags: &mut Diagnostics) {
    let Some(p) = p else { return };
    let rigid = p.bool("rigid").unwrap_or(false);
    let has_k = p.get("kt").is_some() || p.get("kr").is_some();
    if rigid && has_k {
        diags.error(Some(&raw.span), format!("joint of `{owner}` is both rigid and has stiffness; keep one"));
    } else if !rigid && (p.get("kt").is_none() || p.get("kr").is_none()) {
        diags.error_help(Some(&raw.span), format!("joint of `{owner}` needs `kt` and `kr`"), "or write `rigid: true`");
    }
}

fn section_raws(raw: &Raw) -> Vec<&Raw> {
    match raw.get("sections").map(|r| &r.kind) {
        Some(RawKind::Seq(items)) => items.iter().collect(),
        _ => Vec::new(),
    }
}

fn material(p: &Params, field: &str, materials: &IndexMap<String, Material>) -> Option<Material> {
    p.text(field).and_then(|n| materials.get(n)).copied()
}

/// Spindle speeds as checked (rad/s).
fn speeds(list: &[f64]) -> Vec<Speed> {
    list.iter().copied().map(Speed::from_rad_s).collect()
}

fn build_machine(p: &Params, materials: &IndexMap<String, Material>) -> Machine {
    let material_of = |s: &Params| material(s, "material", materials).expect("checked material");
    let spindle = p.object("spindle").map(|s| Spindle {
        material: material(s, "material", materials).expect("checked material"),
        ref_speed: Speed::from_rad_s(s.f64("ref_speed").unwrap_or(0.0)),
        modes: match s.get("modes") {
            Some(ParamValue::Map(m)) => m
                .iter()
                .map(|(dir, v)| {
                    let modes = match v {
                        ParamValue::Objects(list) => list
                            .iter()
                            .map(|m| {
                                let freq_hz = m.f64("f").unwrap_or(0.0);
                                let law = SpeedLaw { kf: m.f64("kf").unwrap_or(0.0), kd: m.f64("keta").unwrap_or(0.0) };
                                let mode = match (m.f64("stiffness"), m.f64("zeta")) {
                                    (Some(k), Some(zeta)) => {
                                        SpindleMode::from_modal(freq_hz, k, zeta, &material_of(s), law)
                                    }
                                    _ => SpindleMode {
                                        law,
                                        ..SpindleMode::new(
                                            freq_hz,
                                            m.f64("d").unwrap_or(0.0),
                                            m.f64("eta").unwrap_or(0.0),
                                        )
                                    },
                                };
                                SpindleMode {
                                    stiffness_change: m.f64("kk").unwrap_or(0.0),
                                    stiffness_exponent: m.f64("kk_exponent").unwrap_or(2.0),
                                    gyro: m.f64("gyro").unwrap_or(0.0),
                                    ..mode
                                }
                            })
                            .collect(),
                        _ => Vec::new(),
                    };
                    (dir.clone(), modes)
                })
                .collect(),
            _ => Vec::new(),
        },
    });
    let directions = match p.get("directions") {
        Some(ParamValue::Words(w)) => w.clone(),
        _ => vec!["x".into(), "y".into()],
    };
    Machine {
        directions,
        speeds: p.list("speeds").map(speeds).unwrap_or_default(),
        max_speed: p.f64("max_speed").map(Speed::from_rad_s),
        spindle,
        holder_interface: p.object("holder_interface").map(entities::joint).unwrap_or(Joint::Rigid),
    }
}

fn build_assembly(p: &Params, materials: &IndexMap<String, Material>) -> Assembly {
    let sections = p
        .objects("sections")
        .unwrap_or(&[])
        .iter()
        .map(|s| {
            let d_out = s.f64("d_out").unwrap_or(0.0);
            Section {
                name: s.text("name").unwrap_or_default().to_string(),
                component: match s.text("component") {
                    Some("holder") => Component::Holder,
                    Some("holder+tool") => Component::HolderAndTool,
                    _ => Component::Tool,
                },
                fluted: s.text("kind") == Some("fluted"),
                d_out_spindle_end: d_out,
                d_out_tip_end: s.f64("d_out_tip").unwrap_or(d_out),
                d_in: s.f64("d_in").unwrap_or(0.0),
                length: s.f64("length").unwrap_or(0.0),
                outer: material(s, "outer", materials).expect("checked material"),
                inner: material(s, "inner", materials),
                d_equivalent: s.f64("d_equivalent"),
            }
        })
        .collect();
    Assembly { sections, tool_joint: p.object("tool_joint").map(entities::joint).unwrap_or(Joint::Rigid) }
}

fn build_sensor(p: &Params) -> Sensor {
    Sensor {
        kind: p.text("kind").unwrap_or_default().to_string(),
        phase_slope: p.f64("phase_slope").unwrap_or(0.0),
        mass: p.f64("mass").unwrap_or(0.0),
        location: p.text("location").unwrap_or("tool tip").to_string(),
        noise: p.f64("noise"),
    }
}

fn build_cutting(p: &Params) -> Cutting {
    let (kt, kn) = match (p.f64("Ks"), p.f64("beta")) {
        (Some(ks), Some(beta)) => (ks * beta.sin(), ks * beta.cos()),
        _ => (p.f64("Kt").unwrap_or(0.0), p.f64("Kn").unwrap_or(0.0)),
    };
    Cutting {
        teeth: p.int("teeth").unwrap_or(1) as u32,
        radial_immersion: p.f64("radial_immersion").unwrap_or(0.0),
        up_milling: p.text("milling") == Some("up"),
        kt,
        kn,
        calibrated_at: p.f64("calibrated_at").map(Speed::from_rad_s),
        ks_change: p.f64("Ks_change").unwrap_or(0.0),
        beta_change: p.f64("beta_change").unwrap_or(0.0),
        change_per: Speed::from_rad_s(p.f64("change_per").unwrap_or(f64::NAN)),
        feed_per_tooth: p.f64("feed_per_tooth"),
        workpiece: p.text("workpiece").map(str::to_string),
        trial_speeds: p.list("trial_speeds").map(speeds).unwrap_or_default(),
    }
}

/// Resolves the recipe's `steps` one entry at a time, collecting every diagnostic instead of stopping at the first.
fn resolve_steps(raw: Option<&Raw>, root: &Span, registry: &Registry, ctx: &Ctx, diags: &mut Diagnostics) -> Vec<Step> {
    let Some(entries) = step_entries(raw, root, diags) else { return Vec::new() };
    // Kinds first, so input references can be checked against the producer's ports.
    let kinds = known_step_kinds(entries, registry);
    let mut steps = Vec::new();
    for (key, sraw) in entries {
        // File parameters are relative to the file the step is written in (a recipe run as a
        // step reads its data beside itself).
        let folder = super::source_folder(&key.span.file);
        let step_ctx = Ctx { entities: ctx.entities, base_dir: Some(&folder), confine: ctx.confine };
        if let Some(step) = resolve_step(key, sraw, &kinds, registry, &step_ctx, diags) {
            steps.push(step);
        }
    }
    steps
}

/// The entries of `steps`, reporting a missing or malformed section so the rest of the recipe can still be checked.
fn step_entries<'a>(raw: Option<&'a Raw>, root: &Span, diags: &mut Diagnostics) -> Option<&'a [(Key, Raw)]> {
    let Some(raw) = raw else {
        diags.error_help(Some(root), "the recipe has no `steps`", "add `steps:` with at least one analysis step");
        return None;
    };
    let Some(entries) = raw.as_map() else {
        diags.error(
            Some(&raw.span),
            format!("`steps` must be a mapping of step names to steps, found {}", raw.describe()),
        );
        return None;
    };
    Some(entries)
}

/// Each step's kind when the registry knows it, so references can be checked before their producer is resolved.
fn known_step_kinds<'a>(entries: &'a [(Key, Raw)], registry: &Registry) -> IndexMap<&'a str, Option<&'a str>> {
    entries
        .iter()
        .map(|(k, v)| {
            (k.name.as_str(), v.get("kind").and_then(Raw::as_str).filter(|kind| registry.get(kind).is_some()))
        })
        .collect()
}

/// Resolves one step entry, reporting every problem in it; `None` when it has errors that leave no step to build.
fn resolve_step(
    key: &Key,
    sraw: &Raw,
    kinds: &IndexMap<&str, Option<&str>>,
    registry: &Registry,
    ctx: &Ctx,
    diags: &mut Diagnostics,
) -> Option<Step> {
    let id = key.name.clone();
    let (kind, node) = step_node(key, sraw, registry, diags)?;
    let spec = node.spec();
    let sweep = resolve_sweep(&id, kind, spec, sraw, ctx, diags);
    let empty = Raw { span: key.span.clone(), kind: RawKind::Map(Vec::new()) };
    let praw = sraw.get("params").unwrap_or(&empty);
    let swept = swept_params(sraw);
    let params = check_step_params(&id, kind, spec, praw, &swept, ctx, diags);
    report_set_and_swept(&id, &sweep, params.as_ref(), praw, diags);
    let inputs = resolve_inputs(&id, kind, spec, sraw, kinds, registry, diags);
    report_missing_inputs(key, kind, spec, sraw, diags);
    let param_spans = step_param_spans(praw, sraw);
    // A node's own checks on values (ranges, combinations); swept steps are checked per
    // instance when the graph is built.
    if let Some(p) = params.as_ref().filter(|_| swept.is_empty())
        && let Err(e) = node.validate(p)
    {
        super::report_invalid(diags, (&id, kind, &key.span), "", &e, spec, &param_spans);
    }
    let label = step_label(sraw, diags);
    let params = params?;
    Some(Step { id, kind: kind.to_string(), span: key.span.clone(), params, inputs, sweep, param_spans, label })
}

/// Checks a step's name and shape and looks up its node kind, which everything else in the step is checked against.
fn step_node<'a, 'r>(
    key: &Key,
    sraw: &'a Raw,
    registry: &'r Registry,
    diags: &mut Diagnostics,
) -> Option<(&'a str, &'r dyn Node)> {
    let id = &key.name;
    if !valid_step_name(id) {
        diags.error_help(
            Some(&key.span),
            format!("`{id}` is not a valid step name"),
            "use letters, digits, `_` and `-`, starting with a letter",
        );
    }
    if sraw.as_map().is_none() {
        diags.error(Some(&sraw.span), format!("step `{id}` must be a mapping with `kind`, found {}", sraw.describe()));
        return None;
    }
    unknown_keys(sraw, STEP_KEYS, &format!("step `{id}`"), diags);
    let Some(kind_raw) = sraw.get("kind") else {
        diags.error_help(
            Some(&key.span),
            format!("step `{id}` has no `kind`"),
            "add `kind: …`; `spindlelab nodes` lists the kinds",
        );
        return None;
    };
    let Some(kind) = kind_raw.as_str() else {
        diags.error(Some(&kind_raw.span), format!("`kind` of step `{id}` must be text"));
        return None;
    };
    let Some(node) = registry.get(kind) else {
        let msg = format!("unknown step kind `{kind}`");
        match suggest(kind, registry.names()) {
            Some(s) => diags.error_help(Some(&kind_raw.span), msg, format!("did you mean `{s}`?")),
            None => diags.error_help(Some(&kind_raw.span), msg, "`spindlelab nodes` lists the kinds"),
        }
        return None;
    };
    Some((kind, node.as_ref()))
}

/// A step's `sweep` axes, each naming a parameter and its values; rejected axes are reported and left out.
fn resolve_sweep(
    id: &str,
    kind: &str,
    spec: &NodeSpec,
    sraw: &Raw,
    ctx: &Ctx,
    diags: &mut Diagnostics,
) -> Vec<SweepAxis> {
    let mut sweep = Vec::new();
    if let Some(sw) = sraw.get("sweep") {
        match sw.as_map() {
            Some(axes) => {
                for (pk, pv) in axes {
                    if let Some(axis) = resolve_sweep_axis(id, kind, spec, pk, pv, ctx, diags) {
                        sweep.push(axis);
                    }
                }
            }
            None => diags.error(Some(&sw.span), format!("`sweep` of step `{id}` must map parameter names to values")),
        }
    }
    sweep
}

/// One sweep axis: the swept parameter must exist and its values must be a non-empty list of valid values.
fn resolve_sweep_axis(
    id: &str,
    kind: &str,
    spec: &NodeSpec,
    pk: &Key,
    pv: &Raw,
    ctx: &Ctx,
    diags: &mut Diagnostics,
) -> Option<SweepAxis> {
    let Some(field) = spec.param(&pk.name) else {
        let msg = format!("step `{id}` sweeps `{}`, which is not a parameter of `{kind}`", pk.name);
        match suggest(&pk.name, spec.params.iter().map(|f| f.name)) {
            Some(s) => diags.error_help(Some(&pk.span), msg, format!("did you mean `{s}`?")),
            None => diags.error(Some(&pk.span), msg),
        }
        return None;
    };
    let what = format!("sweep `{}` of step `{id}`", pk.name);
    let unit = match (&field.ty, &pv.kind) {
        (FieldType::Quantity(dim), RawKind::Seq(items)) => {
            items.first().and_then(|it| it.as_str()).and_then(|t| super::written_unit(t, *dim))
        }
        (FieldType::Quantity(dim), _) => pv.as_str().and_then(|t| super::written_unit(t, *dim)),
        _ => None,
    };
    let values = sweep_values(field.ty, pv, &what, ctx, diags)?;
    if values.is_empty() {
        diags.error(Some(&pv.span), format!("{what} has no values"));
        return None;
    }
    Some(SweepAxis { param: pk.name.clone(), values, unit })
}

/// Checks the values of one sweep axis against the parameter's type, so each is a value the parameter takes.
fn sweep_values(ty: FieldType, pv: &Raw, what: &str, ctx: &Ctx, diags: &mut Diagnostics) -> Option<Vec<ParamValue>> {
    match ty {
        FieldType::Quantity(dim) => match spec::check_value(pv, &FieldType::QuantityList(dim), what, ctx, diags) {
            Some(ParamValue::List { values, dim }) => {
                Some(values.into_iter().map(|value| ParamValue::Quantity { value, dim }).collect())
            }
            _ => None,
        },
        ty => match &pv.kind {
            RawKind::Seq(items) => items.iter().map(|it| spec::check_value(it, &ty, what, ctx, diags)).collect(),
            _ => {
                diags.error(Some(&pv.span), format!("{what} must be a list of values"));
                None
            }
        },
    }
}

/// The names a step's `sweep` maps, including rejected axes, whose errors are already reported.
fn swept_params(sraw: &Raw) -> Vec<&str> {
    sraw.get("sweep")
        .and_then(Raw::as_map)
        .map(|m| m.iter().map(|(k, _)| k.name.as_str()).collect())
        .unwrap_or_default()
}

/// Checks a step's `params`; a swept parameter is neither required nor defaulted here, as the sweep supplies it.
fn check_step_params(
    id: &str,
    kind: &str,
    spec: &NodeSpec,
    praw: &Raw,
    swept: &[&str],
    ctx: &Ctx,
    diags: &mut Diagnostics,
) -> Option<Params> {
    let fields: Vec<Field> = spec
        .params
        .iter()
        .map(|f| if swept.contains(&f.name) { Field { required: false, default: None, ..*f } } else { *f })
        .collect();
    spec::check_object(praw, &fields, &format!("params of step `{id}` ({kind})"), ctx, diags)
}

/// Reports each parameter a step both sets and sweeps, since only one of the two can give its value.
fn report_set_and_swept(id: &str, sweep: &[SweepAxis], params: Option<&Params>, praw: &Raw, diags: &mut Diagnostics) {
    for axis in sweep {
        if params.is_some_and(|p| p.get(&axis.param).is_some()) {
            let at = praw.get(&axis.param).map(|r| r.span.clone());
            diags.error_help(
                at.as_ref(),
                format!("step `{id}` both sets and sweeps `{}`", axis.param),
                "keep one of them",
            );
        }
    }
}

/// A step's `inputs` as bindings; each rejected binding is reported and left out.
fn resolve_inputs(
    id: &str,
    kind: &str,
    spec: &NodeSpec,
    sraw: &Raw,
    kinds: &IndexMap<&str, Option<&str>>,
    registry: &Registry,
    diags: &mut Diagnostics,
) -> Vec<Binding> {
    let mut inputs = Vec::new();
    if let Some(iraw) = sraw.get("inputs") {
        match iraw.as_map() {
            Some(bindings) => {
                for (pk, pv) in bindings {
                    let Some(port) = input_port(kind, spec, pk, diags) else { continue };
                    let Some(r) = input_ref(id, pk, pv, diags) else { continue };
                    let Some(out) = producer_output(&r, pv, kinds, registry, diags) else { continue };
                    if out.ty != port.ty {
                        diags.error_help(
                            Some(&pv.span),
                            format!(
                                "type mismatch: input `{}` of step `{id}` takes a {}, but `{r}` is a {}",
                                pk.name, port.ty, out.ty
                            ),
                            format!("connect an output of type {}", port.ty),
                        );
                        continue;
                    }
                    inputs.push(Binding { port: pk.name.clone(), from: r, span: pv.span.clone() });
                }
            }
            None => {
                diags.error(Some(&iraw.span), format!("`inputs` of step `{id}` must map input names to references"))
            }
        }
    }
    inputs
}

/// The input port an `inputs` key names, reporting a name the step's kind does not take.
fn input_port<'s>(kind: &str, spec: &'s NodeSpec, pk: &Key, diags: &mut Diagnostics) -> Option<&'s PortSpec> {
    let Some(port) = spec.input(&pk.name) else {
        let msg = format!("`{kind}` has no input `{}`", pk.name);
        let known: Vec<&str> = spec.inputs.iter().map(|p| p.name).collect();
        match suggest(&pk.name, known.iter().copied()) {
            Some(s) => diags.error_help(Some(&pk.span), msg, format!("did you mean `{s}`?")),
            None => diags.error_help(
                Some(&pk.span),
                msg,
                format!("its inputs: {}", if known.is_empty() { "none".into() } else { known.join(", ") }),
            ),
        }
        return None;
    };
    Some(port)
}

/// Parses the reference an input is bound to, refusing text that is not one and a step's own outputs.
fn input_ref(id: &str, pk: &Key, pv: &Raw, diags: &mut Diagnostics) -> Option<PortRef> {
    let Some(text) = pv.as_str() else {
        diags
            .error(Some(&pv.span), format!("input `{}` of step `{id}` must be a reference like `@step.port`", pk.name));
        return None;
    };
    let Some(r) = PortRef::parse(text) else {
        diags.error_help(
            Some(&pv.span),
            format!("`{text}` is not a reference"),
            "write `@step.port`, e.g. `@hit.force`",
        );
        return None;
    };
    if r.step == id {
        diags.error(Some(&pv.span), format!("step `{id}` takes its own output `{r}` as input: a cycle"));
        return None;
    }
    Some(r)
}

/// The output port a reference points at, reporting a missing step or port; silent when the producer's kind is
/// itself in error.
fn producer_output<'r>(
    r: &PortRef,
    pv: &Raw,
    kinds: &IndexMap<&str, Option<&str>>,
    registry: &'r Registry,
    diags: &mut Diagnostics,
) -> Option<&'r PortSpec> {
    let Some(producer_kind) = kinds.get(r.step.as_str()) else {
        let msg = format!("dangling reference `{r}`: there is no step `{}`", r.step);
        match suggest(&r.step, kinds.keys().copied()) {
            Some(s) => diags.error_help(Some(&pv.span), msg, format!("did you mean `@{s}.{}`?", r.port)),
            None => diags.error_help(
                Some(&pv.span),
                msg,
                format!("steps: {}", kinds.keys().copied().collect::<Vec<_>>().join(", ")),
            ),
        }
        return None;
    };
    let producer_kind = (*producer_kind)?;
    let pspec = registry.get(producer_kind).expect("checked kind").spec();
    let Some(out) = pspec.output(&r.port) else {
        let msg = format!("step `{}` ({producer_kind}) has no output `{}`", r.step, r.port);
        let known: Vec<&str> = pspec.outputs.iter().map(|p| p.name).collect();
        match suggest(&r.port, known.iter().copied()) {
            Some(s) => diags.error_help(Some(&pv.span), msg, format!("did you mean `@{}.{s}`?", r.step)),
            None => diags.error_help(Some(&pv.span), msg, format!("its outputs: {}", known.join(", "))),
        }
        return None;
    };
    Some(out)
}

/// Reports each required input a step leaves unbound, whether or not its `inputs` resolved.
fn report_missing_inputs(key: &Key, kind: &str, spec: &NodeSpec, sraw: &Raw, diags: &mut Diagnostics) {
    let id = &key.name;
    for port in &spec.inputs {
        let given = sraw.get("inputs").and_then(|i| i.get(port.name)).is_some();
        if !port.optional && !given {
            diags.error_help(
                Some(&key.span),
                format!("step `{id}` ({kind}) needs input `{}` ({})", port.name, port.ty),
                format!("add `inputs: {{ {}: \"@step.port\" }}`", port.name),
            );
        }
    }
}

/// Where each parameter of a step is written, set or swept, so later errors can point at it.
fn step_param_spans(praw: &Raw, sraw: &Raw) -> IndexMap<String, Span> {
    let mut param_spans: IndexMap<String, Span> =
        praw.as_map().map(|m| m.iter().map(|(k, v)| (k.name.clone(), v.span.clone())).collect()).unwrap_or_default();
    if let Some(axes) = sraw.get("sweep").and_then(Raw::as_map) {
        param_spans.extend(axes.iter().map(|(k, v)| (k.name.clone(), v.span.clone())));
    }
    param_spans
}

/// A step's `label`, the name its curves get in a plot's legend; a label that is not text is reported and dropped.
fn step_label(sraw: &Raw, diags: &mut Diagnostics) -> Option<String> {
    let l = sraw.get("label")?;
    match l.as_str() {
        Some(t) => Some(t.to_string()),
        None => {
            diags.error_help(
                Some(&l.span),
                format!("`label` must be text, found {}", l.describe()),
                "write the name its curves get in a plot's legend, e.g. `label: measured`",
            );
            None
        }
    }
}

/// Resolves the recipe's `outputs` against the resolved steps, collecting every diagnostic instead of stopping at
/// the first.
fn resolve_outputs(
    raw: Option<&Raw>,
    steps: &[Step],
    step_names: &[String],
    registry: &Registry,
    diags: &mut Diagnostics,
) -> Vec<Output> {
    let Some(raw) = raw else { return Vec::new() };
    let RawKind::Seq(items) = &raw.kind else {
        diags.error_help(
            Some(&raw.span),
            "`outputs` must be a list",
            "write `outputs: [{ from: \"@step.port\", file: name.csv }]`",
        );
        return Vec::new();
    };
    let mut outputs = Vec::new();
    for item in items {
        if let Some(output) = resolve_output(item, &outputs, steps, step_names, registry, diags) {
            outputs.push(output);
        }
    }
    outputs
}

/// Resolves one `outputs` entry against the steps and the outputs before it; `None` once it is found in error.
fn resolve_output(
    item: &Raw,
    outputs: &[Output],
    steps: &[Step],
    step_names: &[String],
    registry: &Registry,
    diags: &mut Diagnostics,
) -> Option<Output> {
    let (from, file, r) = output_source(item, diags)?;
    let (written, fname) = output_file_name(file, diags)?;
    let format = output_format(written, file, diags)?;
    let is_plot = matches!(format, OutputFormat::Plot(_));
    let unit = output_unit(item, format, &fname, diags)?;
    report_plot_only_keys(item, is_plot, &fname, diags);
    let with = plot_overlays(item, is_plot, diags);
    let label = plot_label(item, is_plot, diags)?;
    let plot = plot_view(item, is_plot, diags)?;
    let ty = output_port_type(&r, from, steps, step_names, registry, diags)?;
    check_port_fits_file(&r, ty, file, format, unit.as_ref(), plot.as_ref(), diags)?;
    check_distinct_file(&fname, file, outputs, diags)?;
    check_overlays(&r, &with, steps, step_names, registry, diags)?;
    Some(Output {
        from: r,
        file: fname,
        format,
        with_labels: with.iter().map(|(_, _, l)| l.clone()).collect(),
        with: with.into_iter().map(|(r, _, _)| r).collect(),
        plot: plot.map(|(v, _)| v),
        label,
        unit: unit.map(|(t, _)| t),
        span: item.span.clone(),
    })
}

/// An output's `from` and `file` entries and the reference in `from`, which every later check needs.
fn output_source<'a>(item: &'a Raw, diags: &mut Diagnostics) -> Option<(&'a Raw, &'a Raw, PortRef)> {
    if item.as_map().is_none() {
        diags.error(
            Some(&item.span),
            format!("an output must be a mapping with `from` and `file`, found {}", item.describe()),
        );
        return None;
    }
    unknown_keys(item, OUTPUT_KEYS, "an output", diags);
    let (Some(from), Some(file)) = (item.get("from"), item.get("file")) else {
        diags.error_help(
            Some(&item.span),
            "an output needs `from` and `file`",
            "e.g. `{ from: \"@hit.force\", file: force.csv }`",
        );
        return None;
    };
    let Some(r) = from.as_str().and_then(PortRef::parse) else {
        diags.error_help(Some(&from.span), "`from` must be a reference", "write `@step.port`");
        return None;
    };
    Some((from, file, r))
}

/// The output's file name as written and in its one normal spelling, refusing names that escape the output
/// directory, that no file system takes, or that spindlelab writes itself.
fn output_file_name<'a>(file: &'a Raw, diags: &mut Diagnostics) -> Option<(&'a str, String)> {
    let Some(fname) = file.as_str() else {
        diags.error(Some(&file.span), "`file` must be a file name");
        return None;
    };
    let path = std::path::Path::new(fname);
    if path.is_absolute() || path.components().any(|c| matches!(c, std::path::Component::ParentDir)) || fname.is_empty()
    {
        diags.error_help(
            Some(&file.span),
            format!("output file `{fname}` must stay inside the output directory"),
            "use a relative name without `..`",
        );
        return None;
    }
    // Names no file system takes fail only when the file is written, after the whole
    // computation: refused here instead.
    if let Some(problem) = unwritable_name(fname) {
        diags.error_help(
            Some(&file.span),
            format!("output file `{}` {problem}", shorten(fname)),
            "choose a shorter name without NUL characters",
        );
        return None;
    }
    // One spelling per file: `./t.csv` and `t.csv` are the same file.
    let normal: std::path::PathBuf =
        path.components().filter(|c| matches!(c, std::path::Component::Normal(_))).collect();
    let normal = normal.to_string_lossy().to_string();
    if RESERVED_OUTPUTS.contains(&normal.as_str()) || normal.starts_with(".spindlelab") {
        diags.error_help(
            Some(&file.span),
            format!("`{normal}` is a file spindlelab writes itself"),
            "choose another file name",
        );
        return None;
    }
    Some((fname, normal))
}

/// The output's format, from the extension of the file name as written.
fn output_format(written: &str, file: &Raw, diags: &mut Diagnostics) -> Option<OutputFormat> {
    match std::path::Path::new(written).extension().and_then(|e| e.to_str()) {
        Some("csv") => Some(OutputFormat::Csv),
        Some("json") => Some(OutputFormat::Json),
        Some("uff") => Some(OutputFormat::Uff),
        Some("svg") => Some(OutputFormat::Plot(PlotFormat::Svg)),
        Some("png") => Some(OutputFormat::Plot(PlotFormat::Png)),
        other => {
            diags.error_help(
                Some(&file.span),
                format!("unsupported output format `{}`", other.unwrap_or("")),
                "name the file `.csv`, `.json`, `.uff`, or `.svg` / `.png` for a plot",
            );
            None
        }
    }
}

/// The unit a scalar is written in (`unit: deg/kHz`), as the recipe's people read it; the outer `None` means a
/// rejected `unit`.
fn output_unit(
    item: &Raw,
    format: OutputFormat,
    fname: &str,
    diags: &mut Diagnostics,
) -> Option<Option<(String, Span)>> {
    let Some(u) = item.get("unit") else { return Some(None) };
    if !matches!(format, OutputFormat::Csv | OutputFormat::Json) {
        diags.error_help(
            Some(&u.span),
            format!("`unit` is for a scalar written to `.csv` or `.json`; `{fname}` is not one"),
            "leave `unit` out",
        );
        return None;
    }
    match u.as_str().map(|t| (t, spindlelab_grammar::parse_unit(t))) {
        Some((t, Ok(_))) => Some(Some((t.to_string(), u.span.clone()))),
        Some((t, Err(e))) => {
            diags.error_help(Some(&u.span), format!("`unit: {t}` is not a unit: {e}"), "e.g. `unit: deg/kHz`");
            None
        }
        None => {
            diags.error_help(Some(&u.span), "`unit` takes a unit", "e.g. `unit: deg/kHz`");
            None
        }
    }
}

/// Reports `with`, `plot` and `label` on an output that is not a plot, where they would be silently ignored.
fn report_plot_only_keys(item: &Raw, is_plot: bool, fname: &str, diags: &mut Diagnostics) {
    for key in ["with", "plot", "label"] {
        if let (Some(v), false) = (item.get(key), is_plot) {
            diags.error_help(
                Some(&v.span),
                format!("`{key}` is for plots; `{fname}` is not one"),
                format!("name the file `.svg` or `.png` to plot it, or leave `{key}` out"),
            );
        }
    }
}

/// References drawn over the plot: one `@step.port` or a list of them; rejected entries are reported and left out.
fn plot_overlays(item: &Raw, is_plot: bool, diags: &mut Diagnostics) -> Vec<(PortRef, Span, Option<String>)> {
    let mut with = Vec::new();
    if let Some(w) = item.get("with").filter(|_| is_plot) {
        let items: Vec<&Raw> = match &w.kind {
            RawKind::Seq(items) => items.iter().collect(),
            _ => vec![w],
        };
        for it in items {
            if let Some(overlay) = plot_overlay(it, diags) {
                with.push(overlay);
            }
        }
    }
    with
}

/// One `with` entry: `@step.port`, or `{ from: "@step.port", label: measured }` to name it in the legend.
fn plot_overlay(it: &Raw, diags: &mut Diagnostics) -> Option<(PortRef, Span, Option<String>)> {
    let (reference, label) = match &it.kind {
        RawKind::Map(_) => (it.get("from"), it.get("label")),
        _ => (Some(it), None),
    };
    if let RawKind::Map(entries) = &it.kind
        && let Some((k, _)) = entries.iter().find(|(k, _)| k.name != "from" && k.name != "label")
    {
        diags.error_help(
            Some(&k.span),
            format!("unknown key `{}` in a `with` entry", k.name),
            "a `with` entry takes `from` and `label`",
        );
        return None;
    }
    let label = match label.map(|l| (l.as_str(), &l.span)) {
        Some((Some(t), _)) => Some(t.to_string()),
        Some((None, span)) => {
            diags.error_help(Some(span), "`label` takes text", "e.g. `label: measured`");
            return None;
        }
        None => None,
    };
    match reference.and_then(Raw::as_str).and_then(PortRef::parse) {
        Some(r) => Some((r, it.span.clone(), label)),
        None => {
            diags.error_help(
                Some(&it.span),
                "`with` takes references",
                "write `@step.port`, or `{ from: \"@step.port\", label: measured }`",
            );
            None
        }
    }
}

/// A plot's `label` for its main value; the outer `None` means a label that is not text.
fn plot_label(item: &Raw, is_plot: bool, diags: &mut Diagnostics) -> Option<Option<String>> {
    let Some(v) = item.get("label").filter(|_| is_plot) else { return Some(None) };
    match v.as_str() {
        Some(t) => Some(Some(t.to_string())),
        None => {
            diags.error_help(Some(&v.span), "`label` takes text", "e.g. `label: model`");
            None
        }
    }
}

/// A plot's `plot` view name with where it is written, checked against the port's views later; the outer `None`
/// means a view that is not text.
fn plot_view(item: &Raw, is_plot: bool, diags: &mut Diagnostics) -> Option<Option<(String, Span)>> {
    let Some(v) = item.get("plot").filter(|_| is_plot) else { return Some(None) };
    match v.as_str() {
        Some(t) => Some(Some((t.to_string(), v.span.clone()))),
        None => {
            diags.error_help(Some(&v.span), "`plot` takes the name of a view", "e.g. `plot: real-imag`");
            None
        }
    }
}

/// The type of the step output an output writes, reporting a missing step or port; silent when the step exists
/// but has errors of its own, already reported.
fn output_port_type(
    r: &PortRef,
    from: &Raw,
    steps: &[Step],
    step_names: &[String],
    registry: &Registry,
    diags: &mut Diagnostics,
) -> Option<PortType> {
    let Some(step) = steps.iter().find(|s| s.id == r.step) else {
        if !step_names.contains(&r.step) {
            let msg = format!("dangling reference `{r}`: there is no step `{}`", r.step);
            match suggest(&r.step, step_names.iter().map(String::as_str)) {
                Some(s) => diags.error_help(Some(&from.span), msg, format!("did you mean `@{s}.{}`?", r.port)),
                None => diags.error_help(Some(&from.span), msg, format!("steps: {}", step_names.join(", "))),
            }
        }
        return None;
    };
    let spec = registry.get(&step.kind).expect("checked kind").spec();
    let Some(port) = spec.output(&r.port) else {
        let known: Vec<&str> = spec.outputs.iter().map(|p| p.name).collect();
        let msg = format!("step `{}` has no output `{}`", r.step, r.port);
        match suggest(&r.port, known.iter().copied()) {
            Some(s) => diags.error_help(Some(&from.span), msg, format!("did you mean `@{}.{s}`?", r.step)),
            None => diags.error_help(Some(&from.span), msg, format!("its outputs: {}", known.join(", "))),
        }
        return None;
    };
    Some(port.ty)
}

/// Checks the port's type suits the output: a `unit` only for scalars, UFF only for FRFs and time series, and a
/// plot only for types with a plot and the chosen view.
fn check_port_fits_file(
    r: &PortRef,
    ty: PortType,
    file: &Raw,
    format: OutputFormat,
    unit: Option<&(String, Span)>,
    plot: Option<&(String, Span)>,
    diags: &mut Diagnostics,
) -> Option<()> {
    if let Some((_, span)) = unit
        && ty != PortType::Scalar
    {
        diags.error_help(Some(span), format!("`unit` is for a scalar output; `{r}` is a {ty}"), "leave `unit` out");
        return None;
    }
    if format == OutputFormat::Uff
        && !matches!(ty, PortType::Frf | PortType::TimeSeries | PortType::ReceptanceSet | PortType::FrfSet)
    {
        diags.error_help(
            Some(&file.span),
            format!("a UFF file holds FRFs and time series; `{r}` is a {ty}"),
            "name the file `.csv` or `.json`",
        );
        return None;
    }
    if matches!(format, OutputFormat::Plot(_)) {
        let views = crate::plot::variants(&ty);
        if views.is_empty() {
            diags.error_help(Some(&file.span), format!("a {ty} has no plot"), "name the file `.json` to write it");
            return None;
        }
        if let Some((v, span)) = plot
            && !views.contains(&v.as_str())
        {
            diags.error_help(
                Some(span),
                format!("a {ty} has no view `{v}`"),
                format!("its views: {}", views.join(", ")),
            );
            return None;
        }
    }
    Some(())
}

/// Refuses a file another output already writes, or one inside (or containing) another output's file.
fn check_distinct_file(fname: &str, file: &Raw, outputs: &[Output], diags: &mut Diagnostics) -> Option<()> {
    if outputs.iter().any(|o: &Output| o.file == fname) {
        diags.error(Some(&file.span), format!("two outputs write `{fname}`"));
        return None;
    }
    if let Some(o) = outputs
        .iter()
        .find(|o: &&Output| fname.starts_with(&format!("{}/", o.file)) || o.file.starts_with(&format!("{fname}/")))
    {
        diags.error(
            Some(&file.span),
            format!("`{fname}` and `{}` cannot both be written: one is inside the other", o.file),
        );
        return None;
    }
    Some(())
}

/// Every value drawn over the plot must exist and have a plot of its own kind; all are checked before refusing.
fn check_overlays(
    r: &PortRef,
    with: &[(PortRef, Span, Option<String>)],
    steps: &[Step],
    step_names: &[String],
    registry: &Registry,
    diags: &mut Diagnostics,
) -> Option<()> {
    let mut with_ok = true;
    for (w, span, _) in with {
        let Some(step) = steps.iter().find(|s| s.id == w.step) else {
            if !step_names.contains(&w.step) {
                let msg = format!("dangling reference `{w}`: there is no step `{}`", w.step);
                match suggest(&w.step, step_names.iter().map(String::as_str)) {
                    Some(s) => diags.error_help(Some(span), msg, format!("did you mean `@{s}.{}`?", w.port)),
                    None => diags.error_help(Some(span), msg, format!("steps: {}", step_names.join(", "))),
                }
            }
            with_ok = false;
            continue;
        };
        let spec = registry.get(&step.kind).expect("checked kind").spec();
        let Some(port) = spec.output(&w.port) else {
            let known: Vec<&str> = spec.outputs.iter().map(|p| p.name).collect();
            diags.error_help(
                Some(span),
                format!("step `{}` has no output `{}`", w.step, w.port),
                format!("its outputs: {}", known.join(", ")),
            );
            with_ok = false;
            continue;
        };
        let main_ty = steps
            .iter()
            .find(|s| s.id == r.step)
            .and_then(|s| registry.get(&s.kind))
            .and_then(|n| n.spec().output(&r.port).map(|p| p.ty));
        if let Some(main_ty) = main_ty
            && !crate::plot::accepts(&main_ty, &port.ty)
        {
            diags.error_help(
                Some(span),
                format!("a {} cannot be drawn over a plot of a {main_ty}", port.ty),
                "FRFs take FRFs and modal models, lobes take lobes and trial tables, tables take tables",
            );
            with_ok = false;
        }
    }
    with_ok.then_some(())
}

/// A recipe's `exports` (what it hands back when run as a step) name outputs of its steps.
fn check_exports(
    raw: Option<&Raw>,
    steps: &[Step],
    step_names: &[String],
    registry: &Registry,
    diags: &mut Diagnostics,
) {
    let Some(raw) = raw else { return };
    let Some(entries) = raw.as_map() else {
        diags.error_help(
            Some(&raw.span),
            "`exports` must map names to step outputs",
            "write `exports: { frf: \"@estimate.frf\" }`",
        );
        return;
    };
    for (k, v) in entries {
        if !valid_name(&k.name) {
            diags.error_help(
                Some(&k.span),
                format!("`{}` is not a valid export name", k.name),
                "use letters, digits, `_` and `-`",
            );
        }
        let Some(r) = v.as_str().and_then(PortRef::parse) else {
            diags.error_help(Some(&v.span), format!("export `{}` must be a reference", k.name), "write `@step.port`");
            continue;
        };
        match steps.iter().find(|s| s.id == r.step) {
            Some(step) => {
                let spec = registry.get(&step.kind).expect("checked kind").spec();
                if spec.output(&r.port).is_none() {
                    let known: Vec<&str> = spec.outputs.iter().map(|p| p.name).collect();
                    diags.error_help(
                        Some(&v.span),
                        format!("step `{}` has no output `{}`", r.step, r.port),
                        format!("its outputs: {}", known.join(", ")),
                    );
                }
            }
            None if step_names.contains(&r.step) => {}
            None => diags.error_help(
                Some(&v.span),
                format!("dangling reference `{r}`: there is no step `{}`", r.step),
                format!("steps: {}", step_names.join(", ")),
            ),
        }
    }
}

/// Reports every dependency cycle among steps, naming the steps in it.
fn check_cycles(steps: &[Step], diags: &mut Diagnostics) {
    let index: IndexMap<&str, usize> = steps.iter().enumerate().map(|(i, s)| (s.id.as_str(), i)).collect();
    // 0 = unvisited, 1 = on the stack, 2 = done.
    let mut state = vec![0u8; steps.len()];
    let mut stack: Vec<usize> = Vec::new();
    fn visit(
        i: usize,
        steps: &[Step],
        index: &IndexMap<&str, usize>,
        state: &mut [u8],
        stack: &mut Vec<usize>,
        diags: &mut Diagnostics,
    ) {
        state[i] = 1;
        stack.push(i);
        for b in &steps[i].inputs {
            let Some(&j) = index.get(b.from.step.as_str()) else { continue };
            if state[j] == 1 {
                let pos = stack.iter().position(|&k| k == j).unwrap_or(0);
                let mut names: Vec<&str> = stack[pos..].iter().map(|&k| steps[k].id.as_str()).collect();
                names.push(&steps[j].id);
                diags.error_help(
                    Some(&b.span),
                    format!("cycle between steps: {}", names.join(" → ")),
                    "a step cannot depend on its own output, directly or through others",
                );
            } else if state[j] == 0 {
                visit(j, steps, index, state, stack, diags);
            }
        }
        stack.pop();
        state[i] = 2;
    }
    for i in 0..steps.len() {
        if state[i] == 0 {
            visit(i, steps, &index, &mut state, &mut stack, diags);
        }
    }
}
