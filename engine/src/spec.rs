//! Field specifications: the one description of what a recipe entity or a node parameter accepts.
//!
//! The validator, the JSON Schema, `spindlelab nodes` and the docs all read these tables,
//! so what the engine accepts and what it documents cannot drift apart.

use crate::diag::{Diagnostic, Diagnostics, Span};
use crate::syntax::{Raw, RawKind};
use indexmap::IndexMap;
use spindlelab_domain::Speed;
use spindlelab_grammar::{self as grammar, Dimension};
use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

/// The kinds of named entity a recipe declares and steps refer to by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum EntityKind {
    Material,
    Machine,
    Assembly,
    Sensor,
    Cutting,
}

impl EntityKind {
    pub const ALL: [EntityKind; 5] =
        [EntityKind::Material, EntityKind::Machine, EntityKind::Assembly, EntityKind::Sensor, EntityKind::Cutting];

    /// The recipe's top-level key that holds entities of this kind.
    pub fn section(self) -> &'static str {
        match self {
            EntityKind::Material => "materials",
            EntityKind::Machine => "machines",
            EntityKind::Assembly => "assemblies",
            EntityKind::Sensor => "sensors",
            EntityKind::Cutting => "cutting",
        }
    }

    pub fn noun(self) -> &'static str {
        match self {
            EntityKind::Material => "material",
            EntityKind::Machine => "machine",
            EntityKind::Assembly => "assembly",
            EntityKind::Sensor => "sensor",
            EntityKind::Cutting => "cutting setup",
        }
    }
}

/// What one field accepts.
#[derive(Debug, Clone, Copy)]
pub enum FieldType {
    /// One number with a unit of this dimension (`12.7 mm`); a plain number when dimensionless.
    Quantity(Dimension),
    /// A list, a range or a single quantity of this dimension (`0..4000 step 500 rpm`).
    QuantityList(Dimension),
    /// A whole number within bounds.
    Integer {
        min: i64,
        max: i64,
    },
    Bool,
    Text,
    /// One of a fixed set of words.
    Choice(&'static [&'static str]),
    /// A list of words from a fixed set.
    ChoiceList(&'static [&'static str]),
    /// The name of an entity declared in the recipe.
    Entity(EntityKind),
    /// A nested mapping with its own fields.
    Object(&'static [Field]),
    /// A list of nested mappings.
    ObjectList(&'static [Field]),
    /// A mapping from free names (for example directions `x`, `y`) to values of one type.
    MapOf(&'static FieldType),
    /// The path of a data file, relative to the recipe's folder. It must exist when the
    /// recipe is loaded; its contents are hashed into the cache key, so editing it reruns
    /// the steps that read it.
    File,
}

impl FieldType {
    /// A short human description, used in messages and `spindlelab nodes`.
    pub fn describe(&self) -> String {
        match self {
            FieldType::Quantity(d) if *d == Dimension::DIMENSIONLESS => "number".into(),
            FieldType::Quantity(d) => format!("{} [{}]", dim_name(*d), shown_unit(*d)),
            FieldType::QuantityList(d) => format!("list or range of {} [{}]", dim_name(*d), shown_unit(*d)),
            FieldType::Integer { min, max } => format!("integer {min}..={max}"),
            FieldType::Bool => "true/false".into(),
            FieldType::Text => "text".into(),
            FieldType::Choice(c) => format!("one of {}", c.join(" | ")),
            FieldType::ChoiceList(c) => format!("list of {}", c.join(" | ")),
            FieldType::Entity(k) => format!("name of a {} in `{}`", k.noun(), k.section()),
            FieldType::Object(_) => "mapping".into(),
            FieldType::ObjectList(_) => "list of mappings".into(),
            FieldType::MapOf(t) => format!("mapping of name to {}", t.describe()),
            FieldType::File => "path of a data file, relative to the recipe's folder".into(),
        }
    }
}

fn dim_name(d: Dimension) -> String {
    d.name().map(str::to_string).unwrap_or_else(|| format!("quantity of dimension {}", d.si_unit()))
}

/// One field of an entity or node parameter list.
#[derive(Debug, Clone, Copy)]
pub struct Field {
    pub name: &'static str,
    pub ty: FieldType,
    pub required: bool,
    /// The default, written as a recipe would write it (`"6.5 ms"`); parsed like user input.
    pub default: Option<&'static str>,
    pub doc: &'static str,
}

impl Field {
    pub const fn req(name: &'static str, ty: FieldType, doc: &'static str) -> Field {
        Field { name, ty, required: true, default: None, doc }
    }
    pub const fn opt(name: &'static str, ty: FieldType, doc: &'static str) -> Field {
        Field { name, ty, required: false, default: None, doc }
    }
    pub const fn def(name: &'static str, ty: FieldType, default: &'static str, doc: &'static str) -> Field {
        Field { name, ty, required: false, default: Some(default), doc }
    }
}

/// A checked value, in SI.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamValue {
    Quantity {
        value: f64,
        dim: Dimension,
    },
    List {
        values: Vec<f64>,
        dim: Dimension,
    },
    Int(i64),
    Bool(bool),
    Text(String),
    Words(Vec<String>),
    Entity {
        kind: EntityKind,
        name: String,
    },
    Object(Params),
    Objects(Vec<Params>),
    Map(IndexMap<String, ParamValue>),
    /// A data file: its path (the recipe's folder joined with what the recipe wrote) and
    /// the blake3 hash of its contents when the recipe was loaded.
    File {
        path: PathBuf,
        hash: String,
    },
}

impl ParamValue {
    /// Location-free text of the value; cache keys and the recipe hash are built on it.
    pub fn canonical(&self, out: &mut String) {
        self.canonical_with(out, &|_, _| None);
    }

    /// [`ParamValue::canonical`], with each named entity followed by what `entity` says of
    /// it (the digest of its contents, for cache keys that follow an entity's values).
    pub fn canonical_with(&self, out: &mut String, entity: &dyn Fn(EntityKind, &str) -> Option<String>) {
        match self {
            ParamValue::Quantity { value, dim } => {
                let _ = write!(out, "{:016x}{dim:?}", value.to_bits());
            }
            ParamValue::List { values, dim } => {
                out.push('[');
                for v in values {
                    let _ = write!(out, "{:016x},", v.to_bits());
                }
                let _ = write!(out, "]{dim:?}");
            }
            ParamValue::Int(i) => {
                let _ = write!(out, "i{i}");
            }
            ParamValue::Bool(b) => {
                let _ = write!(out, "b{b}");
            }
            ParamValue::Text(t) => {
                let _ = write!(out, "{t:?}");
            }
            ParamValue::Words(w) => {
                let _ = write!(out, "{w:?}");
            }
            ParamValue::Entity { kind, name } => {
                let _ = write!(out, "{kind:?}:{name:?}");
                if let Some(d) = entity(*kind, name) {
                    let _ = write!(out, "#{d}");
                }
            }
            ParamValue::Object(p) => p.canonical_with(out, entity),
            ParamValue::Objects(list) => {
                out.push('[');
                for p in list {
                    p.canonical_with(out, entity);
                    out.push(',');
                }
                out.push(']');
            }
            ParamValue::Map(m) => {
                out.push('{');
                for (k, v) in m {
                    let _ = write!(out, "{k:?}=");
                    v.canonical_with(out, entity);
                    out.push(';');
                }
                out.push('}');
            }
            // The contents, not the place: moving a file keeps the key, editing it changes it.
            ParamValue::File { hash, .. } => {
                let _ = write!(out, "file:{hash}");
            }
        }
    }

    /// The value as a recipe would write it, for messages, plans and the graph.
    pub fn display(&self) -> String {
        match self {
            ParamValue::Quantity { value, dim } => fmt_quantity(*value, *dim),
            ParamValue::List { values, dim } => {
                let items: Vec<String> = values.iter().map(|v| fmt_quantity(*v, *dim)).collect();
                format!("[{}]", items.join(", "))
            }
            ParamValue::Int(i) => i.to_string(),
            ParamValue::Bool(b) => b.to_string(),
            ParamValue::Text(t) => t.clone(),
            ParamValue::Words(w) => format!("[{}]", w.join(", ")),
            ParamValue::Entity { name, .. } => name.clone(),
            ParamValue::Object(_) => "{…}".into(),
            ParamValue::Objects(l) => format!("[{} items]", l.len()),
            ParamValue::Map(m) => format!("{{{} keys}}", m.len()),
            // The file's name: sweep labels over measured files stay short.
            ParamValue::File { path, .. } => {
                path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned())
            }
        }
    }
}

/// Formats an SI value with its SI unit, to 6 significant digits; a rotational speed is
/// shown in rpm, the unit every spindle speed is written in, and a frequency in Hz.
pub fn fmt_quantity(value: f64, dim: Dimension) -> String {
    if dim == Dimension::ROTATIONAL_SPEED {
        return Speed::from_rad_s(value).to_string();
    }
    if dim == Dimension::FREQUENCY {
        return format!("{} Hz", spindlelab_domain::sig(value, 6));
    }
    let num = spindlelab_domain::sig(value, 6);
    if dim == Dimension::DIMENSIONLESS { num } else { format!("{num} {}", dim.si_unit()) }
}

/// Checked fields of one entity or node, in declaration order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Params {
    pub values: IndexMap<String, ParamValue>,
}

impl Params {
    pub fn get(&self, name: &str) -> Option<&ParamValue> {
        self.values.get(name)
    }
    /// An SI number; `None` when absent or not a quantity.
    pub fn f64(&self, name: &str) -> Option<f64> {
        match self.values.get(name)? {
            ParamValue::Quantity { value, .. } => Some(*value),
            ParamValue::Int(i) => Some(*i as f64),
            _ => None,
        }
    }
    pub fn list(&self, name: &str) -> Option<&[f64]> {
        match self.values.get(name)? {
            ParamValue::List { values, .. } => Some(values),
            _ => None,
        }
    }
    pub fn int(&self, name: &str) -> Option<i64> {
        match self.values.get(name)? {
            ParamValue::Int(i) => Some(*i),
            _ => None,
        }
    }
    pub fn bool(&self, name: &str) -> Option<bool> {
        match self.values.get(name)? {
            ParamValue::Bool(b) => Some(*b),
            _ => None,
        }
    }
    /// Text, a choice word or an entity name.
    pub fn text(&self, name: &str) -> Option<&str> {
        match self.values.get(name)? {
            ParamValue::Text(t) => Some(t),
            ParamValue::Entity { name, .. } => Some(name),
            _ => None,
        }
    }
    /// The path of a file parameter, resolved against the recipe's folder.
    pub fn file(&self, name: &str) -> Option<&Path> {
        match self.values.get(name)? {
            ParamValue::File { path, .. } => Some(path),
            _ => None,
        }
    }
    pub fn object(&self, name: &str) -> Option<&Params> {
        match self.values.get(name)? {
            ParamValue::Object(p) => Some(p),
            _ => None,
        }
    }
    pub fn objects(&self, name: &str) -> Option<&[Params]> {
        match self.values.get(name)? {
            ParamValue::Objects(p) => Some(p),
            _ => None,
        }
    }
    pub fn canonical(&self, out: &mut String) {
        self.canonical_with(out, &|_, _| None);
    }

    /// [`Params::canonical`] with entity digests (see [`ParamValue::canonical_with`]).
    pub fn canonical_with(&self, out: &mut String, entity: &dyn Fn(EntityKind, &str) -> Option<String>) {
        out.push('{');
        for (k, v) in &self.values {
            let _ = write!(out, "{k:?}=");
            v.canonical_with(out, entity);
            out.push(';');
        }
        out.push('}');
    }
}

/// The names each entity kind declares, so references can be checked and misspellings suggested.
#[derive(Debug, Clone, Default)]
pub struct EntityNames {
    pub names: IndexMap<EntityKind, BTreeSet<String>>,
}

impl EntityNames {
    pub fn contains(&self, kind: EntityKind, name: &str) -> bool {
        self.names.get(&kind).is_some_and(|s| s.contains(name))
    }
    pub fn of(&self, kind: EntityKind) -> impl Iterator<Item = &str> {
        self.names.get(&kind).into_iter().flat_map(|s| s.iter().map(String::as_str))
    }
}

/// The closest candidate to a misspelt word, when it is close enough to be a likely intent.
pub fn suggest<'a>(word: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<String> {
    let mut best: Option<(f64, &str)> = None;
    for c in candidates {
        // Jaro–Winkler ranks; a small edit distance also counts for short names (`hot` → `hit`).
        let edits = strsim::levenshtein(word, c);
        let close = edits <= (c.chars().count() / 3).max(1);
        let score = strsim::jaro_winkler(word, c) + if close { 1.0 } else { 0.0 };
        if score > best.map_or(0.0, |b| b.0) {
            best = Some((score, c));
        }
    }
    best.filter(|(s, _)| *s >= 0.8).map(|(_, c)| c.to_string())
}

/// Where a value is being checked, for messages: `steps.hit.params.hammer_mass`.
pub struct Ctx<'a> {
    pub entities: &'a EntityNames,
    /// The folder of the recipe file, against which file parameters are resolved.
    pub base_dir: Option<&'a Path>,
    /// `--confine`: the folder every file parameter must lie in, by name.
    pub confine: Option<&'a Path>,
}

/// Keys a mode once had and the one name each has now (`f` a natural frequency, `zeta` a
/// viscous damping ratio, `eta` a loss factor, `damping` only a viscous coefficient in N·s/m),
/// so an old recipe is told what to write.
const RENAMED: &[(&str, &str, &str)] = &[
    ("frequency", "f", "a mode's natural frequency is `f` everywhere"),
    ("damping", "zeta", "a mode's viscous damping ratio is `zeta` everywhere (`damping` is a coefficient in N*s/m)"),
];

/// Checks a raw mapping against a field table, pushing every problem; unknown keys, missing
/// fields and wrong values are all reported, not only the first.
pub fn check_object(raw: &Raw, fields: &[Field], what: &str, ctx: &Ctx, diags: &mut Diagnostics) -> Option<Params> {
    let Some(entries) = raw.as_map() else {
        diags.error(Some(&raw.span), format!("{what} must be a mapping, found {}", raw.describe()));
        return None;
    };
    let mut ok = true;
    let mut values = IndexMap::new();
    let mut suggested: Vec<String> = Vec::new();
    for (key, _) in entries {
        if !fields.iter().any(|f| f.name == key.name) {
            ok = false;
            let known: Vec<&str> = fields.iter().map(|f| f.name).collect();
            let msg = format!("unknown key `{}` in {what}", key.name);
            let renamed = RENAMED.iter().find(|(old, new, _)| *old == key.name && known.contains(new));
            if let Some((_, new, why)) = renamed {
                diags.error_help(Some(&key.span), msg, format!("write `{new}`: {why}"));
                suggested.push(new.to_string());
                continue;
            }
            match suggest(&key.name, known.iter().copied()) {
                Some(s) => {
                    diags.error_help(Some(&key.span), msg, format!("did you mean `{s}`?"));
                    suggested.push(s);
                }
                None => diags.error_help(Some(&key.span), msg, format!("known keys: {}", known.join(", "))),
            }
        }
    }
    for field in fields {
        match entries.iter().find(|(k, _)| k.name == field.name) {
            Some((_, v)) => match check_value(v, &field.ty, &format!("`{}` of {what}", field.name), ctx, diags) {
                Some(pv) => {
                    if let ParamValue::Quantity { value, dim } = &pv {
                        check_plausible(field.name, *value, *dim, v, diags);
                    }
                    values.insert(field.name.to_string(), pv);
                }
                None => ok = false,
            },
            None => {
                if let Some(def) = field.default {
                    let raw_def = default_raw(def, &field.ty);
                    let mut scratch = Diagnostics::new();
                    let pv = check_value(&raw_def, &field.ty, field.name, ctx, &mut scratch);
                    debug_assert!(pv.is_some(), "bad default for {}: {scratch}", field.name);
                    if let Some(pv) = pv {
                        values.insert(field.name.to_string(), pv);
                    }
                } else if field.required && suggested.iter().any(|s| s == field.name) {
                    // Already reported as a misspelling of this field.
                    ok = false;
                } else if field.required {
                    ok = false;
                    diags.error_help(
                        Some(&raw.span),
                        format!("missing `{}` in {what}", field.name),
                        format!("add `{}: …` ({}): {}", field.name, field.ty.describe(), field.doc),
                    );
                }
            }
        }
    }
    ok.then_some(Params { values })
}

/// A field default, written as recipe text, as the raw value the validator reads.
fn default_raw(def: &str, ty: &FieldType) -> Raw {
    let span = Span::file_only("<default>".into());
    let kind = match ty {
        FieldType::Bool => RawKind::Bool(def == "true"),
        FieldType::ChoiceList(_) => RawKind::Seq(
            def.trim_matches(|c| c == '[' || c == ']')
                .split(',')
                .map(|w| Raw { span: span.clone(), kind: RawKind::Str(w.trim().to_string()) })
                .collect(),
        ),
        _ => RawKind::Str(def.to_string()),
    };
    Raw { span, kind }
}

/// Checks that every default in a field table is valid for its field; a registry test calls it.
pub fn check_defaults(fields: &[Field]) -> Result<(), String> {
    let names = EntityNames::default();
    let ctx = Ctx { entities: &names, base_dir: None, confine: None };
    for f in fields {
        if let Some(def) = f.default {
            let mut d = Diagnostics::new();
            if check_value(&default_raw(def, &f.ty), &f.ty, f.name, &ctx, &mut d).is_none() {
                return Err(format!("default `{def}` of `{}` is invalid: {d}", f.name));
            }
        }
        match f.ty {
            FieldType::Object(inner) | FieldType::ObjectList(inner) => check_defaults(inner)?,
            _ => {}
        }
    }
    Ok(())
}

fn parse_scalar(raw: &Raw, what: &str, diags: &mut Diagnostics) -> Option<(String, grammar::Value)> {
    let text = raw.scalar_text()?;
    match grammar::parse_value(&text) {
        Ok(v) => Some((text, v)),
        Err(e) => {
            let span = raw.span.narrow(&text, e.offset, e.len);
            let msg = format!("{} in {what}: `{text}`", e.message);
            match e.help {
                Some(h) => diags.error_help(Some(&span), msg, h),
                None => diags.error(Some(&span), msg),
            }
            None
        }
    }
}

fn dim_error(raw: &Raw, text: &str, expected: Dimension, found: Dimension, what: &str, diags: &mut Diagnostics) {
    let err = grammar::DimensionError { expected, found };
    let help = if found == Dimension::DIMENSIONLESS {
        let unit = field_name(what).map_or(example_unit(expected), |name| unit_for_number(name, expected, text));
        format!("write the number with a unit of {}, e.g. `{text} {unit}`", dim_name(expected))
    } else {
        format!("use a unit of {} such as `{}`", dim_name(expected), example_unit(expected))
    };
    diags.error_help(Some(&raw.span), format!("wrong unit for {what}: `{text}`: {err}"), help);
}

/// The field a description such as ``"`Ks` of cutting `al`"`` names: its first backquoted word.
fn field_name(what: &str) -> Option<&str> {
    what.strip_prefix('`').and_then(|rest| rest.split('`').next())
}

/// The unit to suggest for a bare number given to field `name`: the first of the dimension's
/// usual units that puts the number where such a field usually lies, else the dimension's
/// example unit. A cutting coefficient (`Ks`, `Kt`, `Kn`, …) is a pressure of hundreds to
/// thousands of N/mm²: `Ks: 800` means `800 N/mm^2`, never 800 GPa.
fn unit_for_number(name: &str, dim: Dimension, text: &str) -> &'static str {
    if dim == Dimension::PRESSURE && is_cutting_coefficient(name) {
        return "N/mm^2";
    }
    let number = text.trim().parse::<f64>().ok();
    let fits = |unit: &'static str, factor: f64| -> Option<&'static str> {
        number
            .is_some_and(|x| plausible_range(name, dim).is_some_and(|(lo, hi)| (lo..=hi).contains(&(x * factor).abs())))
            .then_some(unit)
    };
    let choices: &[(&'static str, f64)] = match dim {
        d if d == Dimension::PRESSURE => &[("GPa", 1e9), ("MPa", 1e6)],
        d if d == Dimension::LENGTH => &[("mm", 1e-3), ("m", 1.0)],
        _ => &[],
    };
    choices.iter().find_map(|(unit, factor)| fits(unit, *factor)).unwrap_or(example_unit(dim))
}

/// Whether `name` is a specific cutting force coefficient (`Ks`, `Kt`, `Kn`, `Kr`, `Ktc`, …): a `K`
/// and at most three more letters, as the milling literature writes them.
fn is_cutting_coefficient(name: &str) -> bool {
    let mut chars = name.chars();
    chars.next().is_some_and(|c| c == 'K' || c == 'k')
        && name.len() <= 4
        && chars.all(|c| c.is_ascii_alphabetic())
        && name.len() >= 2
}

/// Spellings of the unit *per minute*, a rotational speed in revolutions per minute as drawings
/// and machine controls write it (`12000 1/min`), which the grammar reads as a frequency.
const PER_MINUTE: &[&str] = &["1/min", "/min", "min^-1"];

/// `q` as a quantity of dimension `dim`: itself when it has that dimension, a count per minute
/// taken as revolutions per minute where a rotational speed is expected (`1000 1/min` is
/// `1000 rpm`), else `None`.
fn as_dimension(q: grammar::Quantity, dim: Dimension, text: &str) -> Option<grammar::Quantity> {
    if q.dim == dim {
        return Some(q);
    }
    let unit: String = text.chars().filter(|c| !c.is_whitespace()).collect();
    let per_minute = PER_MINUTE.iter().any(|u| unit.ends_with(u));
    (dim == Dimension::ROTATIONAL_SPEED && q.dim == Dimension::FREQUENCY && per_minute)
        .then_some(grammar::Quantity { value: q.value * std::f64::consts::TAU, dim })
}

/// The unit a description shows: the one recipes write (`rpm`, `mm`), else SI.
fn shown_unit(d: Dimension) -> String {
    match example_unit(d) {
        "an SI unit" => d.si_unit(),
        u => u.to_string(),
    }
}

fn example_unit(d: Dimension) -> &'static str {
    const EXAMPLES: &[(Dimension, &str)] = &[
        (Dimension::LENGTH, "mm"),
        (Dimension::MASS, "kg"),
        (Dimension::TIME, "ms"),
        (Dimension::FREQUENCY, "Hz"),
        (Dimension::ROTATIONAL_SPEED, "rpm"),
        (Dimension::PRESSURE, "GPa"),
        (Dimension::DENSITY, "kg/m^3"),
        (Dimension::STIFFNESS, "N/m"),
        (Dimension::DAMPING, "N*s/m"),
        (Dimension::ANGLE, "deg"),
        (Dimension::PHASE_SLOPE, "deg/kHz"),
        (Dimension::FORCE, "N"),
    ];
    EXAMPLES.iter().find(|(d2, _)| *d2 == d).map_or("an SI unit", |(_, u)| u)
}

/// One quantity of dimension `dim`: a number (dimensionless only) or a value with its unit.
fn check_quantity(
    raw: &Raw,
    dim: &Dimension,
    ty: &FieldType,
    what: &str,
    diags: &mut Diagnostics,
) -> Option<ParamValue> {
    if let RawKind::Int(_) | RawKind::Float(_) = raw.kind {
        let v = match raw.kind {
            RawKind::Int(i) => i as f64,
            RawKind::Float(f) => f,
            _ => unreachable!(),
        };
        if *dim != Dimension::DIMENSIONLESS {
            dim_error(raw, &raw.scalar_text().unwrap_or_default(), *dim, Dimension::DIMENSIONLESS, what, diags);
            return None;
        }
        if !v.is_finite() {
            diags.error(Some(&raw.span), format!("{what} must be a finite number"));
            return None;
        }
        return Some(ParamValue::Quantity { value: v, dim: *dim });
    }
    if !matches!(raw.kind, RawKind::Str(_)) {
        diags.error(Some(&raw.span), format!("{what} must be {}, found {}", ty.describe(), raw.describe()));
        return None;
    }
    let (text, v) = parse_scalar(raw, what, diags)?;
    match v {
        grammar::Value::Quantity(q) => {
            let Some(q) = as_dimension(q, *dim, &text) else {
                dim_error(raw, &text, *dim, q.dim, what, diags);
                return None;
            };
            Some(ParamValue::Quantity { value: q.value, dim: q.dim })
        }
        _ => {
            diags.error_help(
                Some(&raw.span),
                format!("{what} takes one value, found `{text}`"),
                "a list, a range or a reference is not accepted here; sweep over values with `sweep:`",
            );
            None
        }
    }
}

/// A list of quantities of dimension `dim`: a YAML list, a number, or a value, list or range
/// with its unit (`[80, 100] deg`, `0..1 step 0.1 mm`).
fn check_quantity_list(
    raw: &Raw,
    dim: &Dimension,
    ty: &FieldType,
    what: &str,
    ctx: &Ctx,
    diags: &mut Diagnostics,
) -> Option<ParamValue> {
    let mut values = Vec::new();
    let mut push =
        |raw: &Raw, q: grammar::Quantity, text: &str, diags: &mut Diagnostics| match as_dimension(q, *dim, text) {
            Some(q) => {
                values.push(q.value);
                true
            }
            None => {
                dim_error(raw, text, *dim, q.dim, what, diags);
                false
            }
        };
    match &raw.kind {
        RawKind::Seq(items) => {
            let mut ok = true;
            for item in items {
                match check_value(item, &FieldType::Quantity(*dim), what, ctx, diags) {
                    Some(ParamValue::Quantity { value, dim }) => {
                        push(item, grammar::Quantity { value, dim }, "", diags);
                    }
                    _ => ok = false,
                }
            }
            if items.is_empty() {
                diags.error(Some(&raw.span), format!("{what} is an empty list"));
                return None;
            }
            ok.then_some(())?;
        }
        RawKind::Int(_) | RawKind::Float(_) => {
            let pv = check_value(raw, &FieldType::Quantity(*dim), what, ctx, diags)?;
            if let ParamValue::Quantity { value, .. } = pv {
                values.push(value);
            }
        }
        RawKind::Str(_) => {
            let (text, v) = parse_scalar(raw, what, diags)?;
            match v {
                grammar::Value::Quantity(q) => {
                    push(raw, q, &text, diags).then_some(())?;
                }
                grammar::Value::List(qs) => {
                    for q in qs {
                        push(raw, q, &text, diags).then_some(())?;
                    }
                }
                grammar::Value::Range { .. } => {
                    let (rdim, pts) = match &v {
                        grammar::Value::Range { dim, .. } => (*dim, v.points()),
                        _ => unreachable!(),
                    };
                    for p in pts {
                        push(raw, grammar::Quantity { value: p, dim: rdim }, &text, diags).then_some(())?;
                    }
                }
                grammar::Value::Reference(_) => {
                    diags.error(Some(&raw.span), format!("{what} takes values, not a reference: `{text}`"));
                    return None;
                }
            }
        }
        _ => {
            diags.error(Some(&raw.span), format!("{what} must be {}, found {}", ty.describe(), raw.describe()));
            return None;
        }
    }
    Some(ParamValue::List { values, dim: *dim })
}

/// Checks one raw value against a field type.
pub fn check_value(raw: &Raw, ty: &FieldType, what: &str, ctx: &Ctx, diags: &mut Diagnostics) -> Option<ParamValue> {
    // A `$name` left after substitution names no parameter; that has been reported.
    if raw.as_str().is_some_and(|s| s.trim_start().starts_with('$')) {
        return None;
    }
    match ty {
        FieldType::Quantity(dim) => check_quantity(raw, dim, ty, what, diags),
        FieldType::QuantityList(dim) => check_quantity_list(raw, dim, ty, what, ctx, diags),
        FieldType::Integer { min, max } => {
            let v = match &raw.kind {
                RawKind::Int(i) => Some(*i),
                RawKind::Float(f) if f.fract() == 0.0 && f.is_finite() => Some(*f as i64),
                RawKind::Str(s) => s.trim().parse::<i64>().ok(),
                _ => None,
            };
            match v {
                Some(i) if i >= *min && i <= *max => Some(ParamValue::Int(i)),
                Some(i) => {
                    diags.error(Some(&raw.span), format!("{what} is {i}, outside {min}..={max}"));
                    None
                }
                None => {
                    diags.error(Some(&raw.span), format!("{what} must be a whole number, found {}", raw.describe()));
                    None
                }
            }
        }
        FieldType::Bool => match raw.kind {
            RawKind::Bool(b) => Some(ParamValue::Bool(b)),
            _ => {
                diags.error(Some(&raw.span), format!("{what} must be true or false, found {}", raw.describe()));
                None
            }
        },
        FieldType::Text => match &raw.kind {
            RawKind::Str(s) => Some(ParamValue::Text(s.clone())),
            _ => {
                diags.error(Some(&raw.span), format!("{what} must be text, found {}", raw.describe()));
                None
            }
        },
        FieldType::Choice(choices) => check_word(raw, choices, what, diags).map(ParamValue::Text),
        FieldType::ChoiceList(choices) => {
            let RawKind::Seq(items) = &raw.kind else {
                diags.error(Some(&raw.span), format!("{what} must be a list of {}", choices.join(" | ")));
                return None;
            };
            let words: Vec<Option<String>> = items.iter().map(|it| check_word(it, choices, what, diags)).collect();
            words.into_iter().collect::<Option<Vec<_>>>().map(ParamValue::Words)
        }
        FieldType::Entity(kind) => {
            let RawKind::Str(name) = &raw.kind else {
                diags.error(Some(&raw.span), format!("{what} must name a {}, found {}", kind.noun(), raw.describe()));
                return None;
            };
            if ctx.entities.contains(*kind, name) {
                Some(ParamValue::Entity { kind: *kind, name: name.clone() })
            } else {
                let msg = format!("unknown {} `{name}` in {what}", kind.noun());
                match suggest(name, ctx.entities.of(*kind)) {
                    Some(s) => diags.error_help(Some(&raw.span), msg, format!("did you mean `{s}`?")),
                    None => {
                        let known: Vec<&str> = ctx.entities.of(*kind).collect();
                        let help = if known.is_empty() {
                            format!("declare it under `{}:`", kind.section())
                        } else {
                            format!("declared {}: {}", kind.section(), known.join(", "))
                        };
                        diags.error_help(Some(&raw.span), msg, help)
                    }
                }
                None
            }
        }
        FieldType::Object(fields) => check_object(raw, fields, what, ctx, diags).map(ParamValue::Object),
        FieldType::ObjectList(fields) => {
            let RawKind::Seq(items) = &raw.kind else {
                diags.error(Some(&raw.span), format!("{what} must be a list, found {}", raw.describe()));
                return None;
            };
            let checked: Vec<Option<Params>> = items
                .iter()
                .enumerate()
                .map(|(i, it)| check_object(it, fields, &format!("item {} of {what}", i + 1), ctx, diags))
                .collect();
            checked.into_iter().collect::<Option<Vec<_>>>().map(ParamValue::Objects)
        }
        FieldType::File => check_file(raw, what, ctx, diags),
        FieldType::MapOf(inner) => {
            let Some(entries) = raw.as_map() else {
                diags.error(Some(&raw.span), format!("{what} must be a mapping, found {}", raw.describe()));
                return None;
            };
            let mut out = IndexMap::new();
            let mut ok = true;
            for (k, v) in entries {
                match check_value(v, inner, &format!("`{}` of {what}", k.name), ctx, diags) {
                    Some(pv) => {
                        out.insert(k.name.clone(), pv);
                    }
                    None => ok = false,
                }
            }
            ok.then_some(ParamValue::Map(out))
        }
    }
}

/// `a/./b/../c` as `a/c`, by name (a leading `..` is kept).
pub fn normalize(path: &Path) -> PathBuf {
    let mut out: Vec<Component> = Vec::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if matches!(out.last(), Some(Component::Normal(_))) => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out.iter().collect()
}

/// Whether `path` lies inside `folder` by name (`--confine`): relative to it, with no `..`
/// that climbs out and no root. Judged on the names alone, before anything is opened.
pub fn within(folder: &Path, path: &Path) -> bool {
    normalize(path)
        .strip_prefix(normalize(folder))
        .is_ok_and(|rel| rel.components().all(|c| matches!(c, Component::Normal(_) | Component::CurDir)))
}

/// The largest data file read (CSV, UFF, trials) or hashed for a cache key: a device or a pipe
/// named as a file stops here instead of filling memory.
pub const MAX_DATA_BYTES: u64 = 512 * 1024 * 1024;

/// Resolves a file parameter against the recipe's folder, checks that it is a readable file
/// and hashes its contents.
fn check_file(raw: &Raw, what: &str, ctx: &Ctx, diags: &mut Diagnostics) -> Option<ParamValue> {
    let RawKind::Str(written) = &raw.kind else {
        diags.error(Some(&raw.span), format!("{what} must be a file path, found {}", raw.describe()));
        return None;
    };
    if written.trim().is_empty() {
        diags.error(Some(&raw.span), format!("{what} is an empty file path"));
        return None;
    }
    // A relative name is the recipe's folder's; an absolute one is read where it is. Either
    // way the manifest records the file and its hash; `--confine` refuses names outside the
    // recipe's folder.
    let path = match ctx.base_dir {
        Some(base) => base.join(written),
        None => PathBuf::from(written),
    };
    if let Some(root) = ctx.confine
        && !within(root, &path)
    {
        diags.error_help(
            Some(&raw.span),
            format!("{what}: `{}` lies outside the recipe's folder, which --confine refuses", path.display()),
            "copy the file beside the recipe, or run without --confine",
        );
        return None;
    }
    let folder = match ctx.base_dir {
        Some(b) if !b.as_os_str().is_empty() => format!("`{}`", b.display()),
        _ => "the current folder".to_string(),
    };
    if !path.exists() {
        diags.error_help(
            Some(&raw.span),
            format!("file not found: {} (paths are relative to the recipe's folder)", path.display()),
            format!("the recipe's folder is {folder}"),
        );
        return None;
    }
    if !path.is_file() {
        diags.error(Some(&raw.span), format!("{what}: {} is not a file", path.display()));
        return None;
    }
    let mut hasher = blake3::Hasher::new();
    // Hashed as far as a reader would read it: a device or a pipe named as a file stops at the cap.
    let cap = MAX_DATA_BYTES;
    let hashed = std::fs::File::open(&path).and_then(|f| {
        let mut capped = std::io::Read::take(f, cap + 1);
        std::io::copy(&mut capped, &mut hasher)
    });
    match hashed {
        Ok(n) if n > cap => {
            diags.error_help(
                Some(&raw.span),
                format!("{what}: {} is larger than the {} MiB limit of a data file", path.display(), cap >> 20),
                "name a data file (CSV or UFF), not a device or an archive",
            );
            return None;
        }
        Ok(_) => {}
        Err(e) => {
            diags.error(Some(&raw.span), format!("cannot read {}: {e}", path.display()));
            return None;
        }
    }
    Some(ParamValue::File { path, hash: hasher.finalize().to_hex().to_string() })
}

fn check_word(raw: &Raw, choices: &[&str], what: &str, diags: &mut Diagnostics) -> Option<String> {
    let Some(word) = raw.scalar_text() else {
        diags.error(Some(&raw.span), format!("{what} must be one of {}", choices.join(" | ")));
        return None;
    };
    if choices.contains(&word.as_str()) {
        return Some(word);
    }
    let msg = format!("`{word}` is not a valid {what}");
    match suggest(&word, choices.iter().copied()) {
        Some(s) => diags.error_help(Some(&raw.span), msg, format!("did you mean `{s}`?")),
        None => diags.error_help(Some(&raw.span), msg, format!("use one of {}", choices.join(" | "))),
    }
    None
}

/// The range a quantity usually falls in (SI), by the parameter's name where the name says
/// more than its dimension does (a radius, a loss factor), else by its dimension. Outside it
/// the value is kept but warned about: `6.35 m` meant as `6.35 mm` gives a hammer tip the size
/// of a room and a meganewton peak force, without any error.
pub fn plausible_range(name: &str, dim: Dimension) -> Option<(f64, f64)> {
    let n = name.to_ascii_lowercase();
    let section = ["radius", "diameter", "d_out", "d_in", "d_eq", "length", "overhang", "stickout"];
    match dim {
        d if d == Dimension::LENGTH && section.iter().any(|k| n.contains(k)) => Some((1e-5, 2.0)),
        d if d == Dimension::LENGTH => Some((1e-12, 20.0)),
        d if d == Dimension::MASS => Some((1e-7, 1e4)),
        d if d == Dimension::DENSITY => Some((100.0, 3e4)),
        d if d == Dimension::PRESSURE && (n == "e" || n.contains("modulus")) => Some((1e8, 2e12)),
        d if d == Dimension::PRESSURE => Some((1e4, 2e12)),
        d if d == Dimension::STIFFNESS => Some((1e-3, 1e18)),
        d if d == Dimension::FREQUENCY => Some((1e-3, 1e7)),
        d if d == Dimension::ROTATIONAL_SPEED => Some((1e-3, 1e5)),
        d if d == Dimension::TIME => Some((1e-10, 1e5)),
        d if d == Dimension::DIMENSIONLESS && (n == "eta" || n.starts_with("loss")) => Some((0.0, 1.0)),
        d if d == Dimension::DIMENSIONLESS && (n == "nu" || n == "poisson") => Some((0.0, 0.5)),
        _ => None,
    }
}

/// Warns when a quantity lies outside [`plausible_range`], naming the unit that would put it
/// inside when there is one (`mm` for a length given in `m`).
fn check_plausible(name: &str, value: f64, dim: Dimension, raw: &Raw, diags: &mut Diagnostics) {
    let Some((lo, hi)) = plausible_range(name, dim) else { return };
    if value == 0.0 || (lo..=hi).contains(&value.abs()) {
        return;
    }
    let text = raw.scalar_text().unwrap_or_default();
    let number = text.split_whitespace().next().unwrap_or("");
    let alternatives: &[(&str, f64)] = match dim {
        d if d == Dimension::LENGTH => &[("mm", 1e-3), ("µm", 1e-6), ("m", 1.0)],
        d if d == Dimension::MASS => &[("g", 1e-3), ("kg", 1.0)],
        d if d == Dimension::PRESSURE => &[("GPa", 1e9), ("MPa", 1e6), ("N/mm^2", 1e6)],
        d if d == Dimension::FREQUENCY => &[("Hz", 1.0), ("kHz", 1e3)],
        d if d == Dimension::ROTATIONAL_SPEED => &[("rpm", Speed::from_rpm(1.0).rad_s())],
        d if d == Dimension::TIME => &[("ms", 1e-3), ("s", 1.0)],
        _ => &[],
    };
    let shown = number.parse::<f64>().ok();
    let hint = alternatives.iter().find(|(_, f)| shown.is_some_and(|x| (lo..=hi).contains(&(x * f).abs())));
    let range = match dim {
        d if d == Dimension::DIMENSIONLESS => format!("{lo} to {hi}"),
        _ => format!("{lo:e} to {hi:e} {}", dim.si_unit()),
    };
    let mut d = Diagnostic::warning(
        Some(raw.span.clone()),
        format!("`{text}` for `{name}` is outside the usual range ({range}); it is used as written"),
    );
    if let Some((unit, _)) = hint {
        d = d.with_help(format!("did you mean `{number} {unit}`?"));
    }
    diags.push(d);
}
