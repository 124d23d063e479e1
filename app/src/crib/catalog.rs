//! The tool-crib catalog file: holders and end mills with their geometry, read from YAML into
//! typed values in SI, every problem reported at its file, line and column.
//!
//! The file is read through the engine's YAML front end, so every value keeps its place, and
//! every quantity goes through the recipe grammar (`63 mm`, `800 MPa`, `21..45 step 3 mm`).

use crate::engine::diag::{Diagnostics, Span};
use crate::engine::grammar::{self, Dimension};
use crate::engine::spec::suggest;
use crate::engine::syntax::{Key, Raw, RawKind};

/// The version of the catalog format this reader takes (`spindlelab_catalog: 1`).
pub const FORMAT_VERSION: i64 = 1;

/// A catalog: what it is, where its materials come from, the cutting conditions, the holders
/// and tools, and which of them a survey takes.
#[derive(Debug, Clone)]
pub struct Catalog {
    pub name: String,
    pub description: String,
    /// Libraries the sections' materials come from, as written (relative to the catalog).
    pub uses: Vec<(String, Span)>,
    /// The holder interfaces a survey takes (the machine's); empty: every holder.
    pub interfaces: Vec<String>,
    pub cutting: CuttingBlock,
    pub analysis: Analysis,
    pub holders: Vec<Holder>,
    pub tools: Vec<Tool>,
}

/// Cutting conditions every combination is judged at; the texts are passed to the recipe as
/// written, after their dimension was checked.
#[derive(Debug, Clone)]
pub struct CuttingBlock {
    pub ks: String,
    pub beta: String,
    pub radial_immersion: String,
    pub milling: String,
    pub speeds: String,
}

/// The grids of the survey: the receptances' band and line spacing, the beam's element length.
#[derive(Debug, Clone)]
pub struct Analysis {
    pub max_frequency: String,
    pub resolution: String,
    pub max_element: String,
}

/// How a holder grips the shank.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Clamping {
    ShrinkFit,
    Collet,
    Hydraulic,
    Weldon,
}

impl Clamping {
    pub const WORDS: &'static [&'static str] = &["shrink_fit", "collet", "hydraulic", "weldon"];

    fn from_word(w: &str) -> Option<Clamping> {
        Some(match w {
            "shrink_fit" => Clamping::ShrinkFit,
            "collet" => Clamping::Collet,
            "hydraulic" => Clamping::Hydraulic,
            "weldon" => Clamping::Weldon,
            _ => return None,
        })
    }

    pub fn word(self) -> &'static str {
        match self {
            Clamping::ShrinkFit => "shrink_fit",
            Clamping::Collet => "collet",
            Clamping::Hydraulic => "hydraulic",
            Clamping::Weldon => "weldon",
        }
    }
}

/// One section of a holder's body between the spindle face and its nose (SI).
#[derive(Debug, Clone)]
pub struct BodySection {
    pub name: String,
    pub d_out: f64,
    pub d_out_tip: Option<f64>,
    pub d_in: f64,
    pub length: f64,
}

/// The nose of a holder for a range of shank diameters: its outer diameters at the body and at
/// the face, and how deep a shank goes in (SI).
#[derive(Debug, Clone)]
pub struct Bore {
    pub d_min: f64,
    pub d_max: f64,
    pub d_out: f64,
    pub d_out_tip: f64,
    pub clamp_length: f64,
    pub span: Span,
}

/// A tool holder: its interface, clamping, body sections from the spindle face, and the nose
/// per bore up to the gauge length.
#[derive(Debug, Clone)]
pub struct Holder {
    pub id: String,
    pub interface: String,
    pub clamping: Clamping,
    pub material: String,
    pub gauge_length: f64,
    pub sections: Vec<BodySection>,
    pub bores: Vec<Bore>,
    /// The tools it is paired with when named (each checked to fit); otherwise every tool
    /// whose shank one of its bores takes.
    pub tools: Option<Vec<(String, Span)>>,
    pub source: String,
    pub span: Span,
    pub material_span: Span,
}

impl Holder {
    /// The length of the nose: the gauge length less the body sections.
    pub fn nose_length(&self) -> f64 {
        self.gauge_length - self.sections.iter().map(|s| s.length).sum::<f64>()
    }

    /// The bore that takes a shank of diameter `d`, if any.
    pub fn bore_for(&self, d: f64) -> Option<&Bore> {
        let tol = 1e-9;
        self.bores.iter().find(|b| d >= b.d_min - tol && d <= b.d_max + tol)
    }
}

/// An end mill (SI); `stickout` holds every stickout a survey takes, from the holder's face
/// to the tip.
#[derive(Debug, Clone)]
pub struct Tool {
    pub id: String,
    pub diameter: f64,
    pub teeth: i64,
    pub flute_length: f64,
    pub overall_length: f64,
    pub shank: f64,
    pub d_equivalent: f64,
    pub material: String,
    pub stickout: Vec<f64>,
    pub source: String,
    pub span: Span,
    pub material_span: Span,
}

/// One survey point: a holder, the tool in it and its stickout.
#[derive(Debug, Clone)]
pub struct Combination {
    pub holder: usize,
    pub tool: usize,
    pub stickout: f64,
}

impl Catalog {
    /// Every (holder, tool, stickout) the survey takes, holder by holder, tool by tool.
    pub fn combinations(&self) -> Vec<Combination> {
        let mut out = Vec::new();
        for (h, holder) in self.holders.iter().enumerate() {
            if !self.interfaces.is_empty() && !self.interfaces.contains(&holder.interface) {
                continue;
            }
            for (t, tool) in self.tools.iter().enumerate() {
                let named = match &holder.tools {
                    Some(list) => list.iter().any(|(id, _)| *id == tool.id),
                    None => holder.bore_for(tool.shank).is_some(),
                };
                if named {
                    out.extend(tool.stickout.iter().map(|&s| Combination { holder: h, tool: t, stickout: s }));
                }
            }
        }
        out
    }
}

/// The least shank left in a holder, in shank diameters: a stickout that leaves less is refused.
pub const MIN_CLAMPED_DIAMETERS: f64 = 2.0;

/// A mapping being read: its entries, which of them were used, and what it is called in
/// messages.
struct Obj<'a> {
    raw: &'a Raw,
    entries: &'a [(Key, Raw)],
    what: String,
}

impl<'a> Obj<'a> {
    /// Opens `raw` as a mapping with the keys `allowed`; an unknown key is an error at the key.
    fn open(raw: &'a Raw, what: &str, allowed: &[&str], diags: &mut Diagnostics) -> Option<Obj<'a>> {
        let Some(entries) = raw.as_map() else {
            diags.error_help(
                Some(&raw.span),
                format!("{what} must be a mapping, found {}", raw.describe()),
                "write `key: value` lines or `{ key: value, … }`",
            );
            return None;
        };
        for (k, _) in entries {
            if !allowed.contains(&k.name.as_str()) {
                let hint = suggest(&k.name, allowed.iter().copied())
                    .map(|s| format!("did you mean `{s}`? "))
                    .unwrap_or_default();
                diags.error_help(
                    Some(&k.span),
                    format!("{what}: unknown field `{}`", k.name),
                    format!("{hint}the fields are {}", allowed.join(", ")),
                );
            }
        }
        Some(Obj { raw, entries, what: what.to_string() })
    }

    fn get(&self, key: &str) -> Option<&'a Raw> {
        self.entries.iter().find(|(k, _)| k.name == key).map(|(_, v)| v)
    }

    fn missing(&self, key: &str, example: &str, diags: &mut Diagnostics) {
        diags.error_help(
            Some(&self.raw.span),
            format!("{}: `{key}` is missing", self.what),
            format!("add it, e.g. `{key}: {example}`"),
        );
    }

    /// A required text field.
    fn text(&self, key: &str, example: &str, diags: &mut Diagnostics) -> Option<(String, Span)> {
        match self.get(key) {
            None => {
                self.missing(key, example, diags);
                None
            }
            Some(r) => match &r.kind {
                RawKind::Str(s) if !s.trim().is_empty() => Some((s.clone(), r.span.clone())),
                _ => {
                    diags.error_help(
                        Some(&r.span),
                        format!("{}: `{key}` must be text, found {}", self.what, r.describe()),
                        format!("e.g. `{key}: {example}`"),
                    );
                    None
                }
            },
        }
    }

    /// An optional text field (a default when absent).
    fn text_or(&self, key: &str, default: &str, diags: &mut Diagnostics) -> Option<String> {
        match self.get(key) {
            None => Some(default.to_string()),
            Some(_) => self.text(key, default, diags).map(|(s, _)| s),
        }
    }

    /// A required quantity of dimension `dim`, in SI.
    fn quantity(&self, key: &str, dim: Dimension, example: &str, diags: &mut Diagnostics) -> Option<f64> {
        match self.get(key) {
            None => {
                self.missing(key, example, diags);
                None
            }
            Some(r) => quantity(r, &format!("{}: `{key}`", self.what), dim, example, diags),
        }
    }

    /// An optional quantity.
    fn opt_quantity(&self, key: &str, dim: Dimension, example: &str, diags: &mut Diagnostics) -> Option<Option<f64>> {
        match self.get(key) {
            None => Some(None),
            Some(r) => quantity(r, &format!("{}: `{key}`", self.what), dim, example, diags).map(Some),
        }
    }

    /// A quantity passed on as written, once its dimension is checked.
    fn quantity_text(&self, key: &str, dim: Dimension, example: &str, diags: &mut Diagnostics) -> Option<String> {
        let r = self.get(key);
        self.quantity(key, dim, example, diags)?;
        r.and_then(Raw::scalar_text)
    }
}

/// A quantity of dimension `dim` from a scalar, in SI; a bare number where a dimension is
/// expected is an error that asks for the unit.
fn quantity(r: &Raw, what: &str, dim: Dimension, example: &str, diags: &mut Diagnostics) -> Option<f64> {
    let text = match &r.kind {
        RawKind::Str(s) => s.clone(),
        RawKind::Int(_) | RawKind::Float(_) => r.scalar_text().unwrap_or_default(),
        _ => {
            diags.error_help(
                Some(&r.span),
                format!("{what} must be a quantity, found {}", r.describe()),
                format!("write it with its unit, e.g. `{example}`"),
            );
            return None;
        }
    };
    let q = match grammar::parse_quantity(&text) {
        Ok(q) => q,
        Err(e) => {
            diags.error_help(
                Some(&r.span),
                format!("{what}: `{text}` is not a quantity: {e}"),
                format!("write a number and its unit, e.g. `{example}`"),
            );
            return None;
        }
    };
    if q.dim.is_dimensionless() && !dim.is_dimensionless() {
        diags.error_help(
            Some(&r.span),
            format!("{what}: `{text}` has no unit, and {} is expected", dim.describe()),
            format!("write it with its unit, e.g. `{example}`"),
        );
        return None;
    }
    match q.expect(dim) {
        Ok(v) if v.is_finite() => Some(v),
        Ok(_) => {
            diags.error(Some(&r.span), format!("{what}: `{text}` is not a finite number"));
            None
        }
        Err(e) => {
            diags.error_help(Some(&r.span), format!("{what}: `{text}`: {e}"), format!("e.g. `{example}`"));
            None
        }
    }
}

/// Whether `s` names an entity as a recipe does: letters, digits, `_` and `-`, starting with
/// a letter.
fn is_id(s: &str) -> bool {
    s.starts_with(|c: char| c.is_ascii_alphabetic())
        && s.len() <= 40
        && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

fn id(obj: &Obj, what: &str, diags: &mut Diagnostics) -> Option<(String, Span)> {
    let (id, span) = obj.text("id", "hsk63_shrink", diags)?;
    if !is_id(&id) {
        diags.error_help(
            Some(&span),
            format!("{what} id `{id}` is not a name"),
            "use letters, digits, `_` and `-`, starting with a letter, at most 40 characters",
        );
        return None;
    }
    Some((id, span))
}

fn positive(v: Option<f64>, span: &Span, what: &str, diags: &mut Diagnostics) -> Option<f64> {
    let v = v?;
    if v > 0.0 {
        Some(v)
    } else {
        diags.error(Some(span), format!("{what} must be above 0, found {v}"));
        None
    }
}

fn list<'a>(raw: Option<&'a Raw>, what: &str, diags: &mut Diagnostics) -> Vec<&'a Raw> {
    match raw.map(|r| (r, &r.kind)) {
        None => Vec::new(),
        Some((_, RawKind::Seq(items))) => items.iter().collect(),
        Some((r, _)) => {
            diags.error_help(
                Some(&r.span),
                format!("{what} must be a list, found {}", r.describe()),
                "write one `- item` per line",
            );
            Vec::new()
        }
    }
}

const TOP: &[&str] =
    &["spindlelab_catalog", "name", "description", "use", "filters", "cutting", "analysis", "holders", "tools"];
const FILTERS: &[&str] = &["interfaces"];
const CUTTING: &[&str] = &["Ks", "beta", "radial_immersion", "milling", "speeds"];
const ANALYSIS: &[&str] = &["max_frequency", "resolution", "max_element"];
const HOLDER: &[&str] =
    &["id", "interface", "clamping", "material", "gauge_length", "sections", "bores", "tools", "source"];
const SECTION: &[&str] = &["name", "d_out", "d_out_tip", "d_in", "length"];
const BORE: &[&str] = &["d", "d_min", "d_max", "d_out", "d_out_tip", "clamp_length"];
const TOOL: &[&str] = &[
    "id",
    "diameter",
    "teeth",
    "flute_length",
    "overall_length",
    "shank",
    "d_equivalent",
    "material",
    "stickout",
    "source",
];

/// Reads a catalog from its raw tree; every problem is pushed to `diags`, and `None` is
/// returned when there was any.
pub fn read(raw: &Raw, diags: &mut Diagnostics) -> Option<Catalog> {
    let before = diags.error_count();
    let top = Obj::open(raw, "the catalog", TOP, diags)?;
    match top.get("spindlelab_catalog") {
        Some(Raw { kind: RawKind::Int(FORMAT_VERSION), .. }) => {}
        Some(r) => diags.error_help(
            Some(&r.span),
            format!("`spindlelab_catalog` is {}, and this reader takes version {FORMAT_VERSION}", r.describe()),
            format!("write `spindlelab_catalog: {FORMAT_VERSION}`"),
        ),
        None => diags.error_help(
            Some(&raw.span),
            "this is not a tool-crib catalog: `spindlelab_catalog` is missing",
            format!("a catalog starts with `spindlelab_catalog: {FORMAT_VERSION}` (docs/crib.md)"),
        ),
    }
    let name = top.text("name", "tool-crib", diags).map(|(s, _)| s).unwrap_or_default();
    let description = top.text_or("description", "", diags).unwrap_or_default();
    let uses = list(top.get("use"), "`use`", diags)
        .into_iter()
        .filter_map(|r| match &r.kind {
            RawKind::Str(s) => Some((s.clone(), r.span.clone())),
            _ => {
                diags.error(Some(&r.span), format!("`use`: a library is named by its path, found {}", r.describe()));
                None
            }
        })
        .collect();
    let interfaces = match top.get("filters") {
        None => Vec::new(),
        Some(f) => Obj::open(f, "`filters`", FILTERS, diags)
            .map(|o| {
                list(o.get("interfaces"), "`filters.interfaces`", diags)
                    .into_iter()
                    .filter_map(|r| r.as_str().map(str::to_string))
                    .collect()
            })
            .unwrap_or_default(),
    };
    let cutting = top.get("cutting").and_then(|c| read_cutting(c, diags));
    if top.get("cutting").is_none() {
        top.missing("cutting", "{ Ks: 800 MPa, beta: 68 deg, … }", diags);
    }
    let analysis = match top.get("analysis") {
        Some(a) => read_analysis(a, diags),
        None => {
            Some(Analysis { max_frequency: "12 kHz".into(), resolution: "2.5 Hz".into(), max_element: "4 mm".into() })
        }
    };
    let holders: Vec<Holder> = list(top.get("holders"), "`holders`", diags)
        .into_iter()
        .enumerate()
        .filter_map(|(i, r)| read_holder(r, i, diags))
        .collect();
    let tools: Vec<Tool> = list(top.get("tools"), "`tools`", diags)
        .into_iter()
        .enumerate()
        .filter_map(|(i, r)| read_tool(r, i, diags))
        .collect();
    if top.get("holders").is_none() {
        top.missing("holders", "[ … ]", diags);
    }
    if top.get("tools").is_none() {
        top.missing("tools", "[ … ]", diags);
    }
    unique(holders.iter().map(|h| (&h.id, &h.span)), "holder", diags);
    unique(tools.iter().map(|t| (&t.id, &t.span)), "tool", diags);
    check_pairs(&holders, &tools, diags);
    if diags.error_count() > before {
        return None;
    }
    let catalog =
        Catalog { name, description, uses, interfaces, cutting: cutting?, analysis: analysis?, holders, tools };
    if catalog.combinations().is_empty() {
        diags.error_help(
            Some(&raw.span),
            "the catalog pairs no holder with any tool",
            "give each holder a bore that takes a tool's shank, and check `filters.interfaces`",
        );
        return None;
    }
    Some(catalog)
}

fn unique<'a>(ids: impl Iterator<Item = (&'a String, &'a Span)>, what: &str, diags: &mut Diagnostics) {
    let mut seen: Vec<&String> = Vec::new();
    for (id, span) in ids {
        if seen.contains(&id) {
            diags.error_help(Some(span), format!("{what} `{id}` is listed twice"), "give each one an id of its own");
        }
        seen.push(id);
    }
}

fn read_cutting(raw: &Raw, diags: &mut Diagnostics) -> Option<CuttingBlock> {
    let o = Obj::open(raw, "`cutting`", CUTTING, diags)?;
    let ks = o.quantity_text("Ks", Dimension::PRESSURE, "800 MPa", diags);
    let beta = o.quantity_text("beta", Dimension::ANGLE, "68 deg", diags);
    let radial_immersion = o.quantity_text("radial_immersion", Dimension::DIMENSIONLESS, "50 %", diags);
    let milling = o.text("milling", "down", diags).and_then(|(m, span)| {
        if m == "up" || m == "down" {
            Some(m)
        } else {
            diags.error_help(Some(&span), format!("`cutting`: `milling` is `{m}`"), "write `up` or `down`");
            None
        }
    });
    let speeds =
        o.text("speeds", "4000..24000 step 50 rpm", diags).and_then(|(s, span)| match grammar::parse_value(&s) {
            Ok(v @ grammar::Value::Range { .. }) if v.expect_dim(Dimension::ROTATIONAL_SPEED).is_ok() => {
                if v.points().is_empty() {
                    diags.error_help(
                        Some(&span),
                        format!("`cutting`: `speeds` `{s}` holds no speed"),
                        "start below its end",
                    );
                    return None;
                }
                Some(s)
            }
            _ => {
                diags.error_help(
                    Some(&span),
                    format!("`cutting`: `speeds` `{s}` is not a range of spindle speeds"),
                    "e.g. `4000..24000 step 50 rpm`",
                );
                None
            }
        });
    Some(CuttingBlock { ks: ks?, beta: beta?, radial_immersion: radial_immersion?, milling: milling?, speeds: speeds? })
}

fn read_analysis(raw: &Raw, diags: &mut Diagnostics) -> Option<Analysis> {
    let o = Obj::open(raw, "`analysis`", ANALYSIS, diags)?;
    let text = |key: &str, dim, default: &str, diags: &mut Diagnostics| match o.get(key) {
        None => Some(default.to_string()),
        Some(_) => o.quantity_text(key, dim, default, diags),
    };
    let max_frequency = text("max_frequency", Dimension::FREQUENCY, "12 kHz", diags);
    let resolution = text("resolution", Dimension::FREQUENCY, "2.5 Hz", diags);
    let max_element = text("max_element", Dimension::LENGTH, "4 mm", diags);
    Some(Analysis { max_frequency: max_frequency?, resolution: resolution?, max_element: max_element? })
}

fn read_holder(raw: &Raw, index: usize, diags: &mut Diagnostics) -> Option<Holder> {
    let o = Obj::open(raw, &format!("holder {}", index + 1), HOLDER, diags)?;
    let (id, _) = id(&o, "holder", diags)?;
    let o = Obj { what: format!("holder `{id}`"), ..o };
    let interface = o.text("interface", "HSK-A63", diags).map(|(s, _)| s);
    let clamping = o.text("clamping", "shrink_fit", diags).and_then(|(w, span)| {
        let c = Clamping::from_word(&w);
        if c.is_none() {
            diags.error_help(
                Some(&span),
                format!("holder `{id}`: clamping `{w}` is not known"),
                format!("write one of {}", Clamping::WORDS.join(", ")),
            );
        }
        c
    });
    let material = o.text("material", "steel", diags);
    let gauge_length = positive(
        o.quantity("gauge_length", Dimension::LENGTH, "80 mm", diags),
        &raw.span,
        &format!("holder `{id}`: `gauge_length`"),
        diags,
    );
    let source = o.text("source", "ISO 12164-1 (interface); body assumed", diags).map(|(s, _)| s);
    let sections: Vec<Option<BodySection>> = list(o.get("sections"), &format!("holder `{id}`: `sections`"), diags)
        .into_iter()
        .enumerate()
        .map(|(i, r)| read_section(r, &format!("holder `{id}`: section {}", i + 1), diags))
        .collect();
    if o.get("sections").is_none() {
        o.missing("sections", "[{ name: flange, d_out: 63 mm, length: 26 mm }]", diags);
    }
    let bores: Vec<Option<Bore>> = list(o.get("bores"), &format!("holder `{id}`: `bores`"), diags)
        .into_iter()
        .enumerate()
        .map(|(i, r)| read_bore(r, &format!("holder `{id}`: bore {}", i + 1), diags))
        .collect();
    if bores.is_empty() {
        o.missing("bores", "[{ d: 12 mm, d_out: 32 mm, d_out_tip: 24 mm, clamp_length: 47 mm }]", diags);
    }
    let tools = o.get("tools").map(|t| {
        list(Some(t), &format!("holder `{id}`: `tools`"), diags)
            .into_iter()
            .filter_map(|r| r.as_str().map(|s| (s.to_string(), r.span.clone())))
            .collect()
    });
    let sections: Option<Vec<BodySection>> = sections.into_iter().collect();
    let bores: Option<Vec<Bore>> = bores.into_iter().collect();
    let holder = Holder {
        id: id.clone(),
        interface: interface?,
        clamping: clamping?,
        material_span: material.as_ref()?.1.clone(),
        material: material?.0,
        gauge_length: gauge_length?,
        sections: sections?,
        bores: bores?,
        tools,
        source: source?,
        span: raw.span.clone(),
    };
    let nose = holder.nose_length();
    if nose <= 0.0 {
        diags.error_help(
            Some(&raw.span),
            format!(
                "holder `{id}`: its body sections are {:.3} mm long, as long as its gauge length {:.3} mm or longer",
                (holder.gauge_length - nose) * 1e3,
                holder.gauge_length * 1e3
            ),
            "the nose (gauge length less the body sections) holds the shank: shorten the body",
        );
        return None;
    }
    for b in &holder.bores {
        if b.clamp_length > nose + 1e-12 {
            diags.error_help(
                Some(&b.span),
                format!(
                    "holder `{id}`: `clamp_length` {:.3} mm is longer than the nose, {:.3} mm (gauge length less the body)",
                    b.clamp_length * 1e3,
                    nose * 1e3
                ),
                "shorten the clamped length or the body sections",
            );
            return None;
        }
    }
    Some(holder)
}

fn read_section(raw: &Raw, what: &str, diags: &mut Diagnostics) -> Option<BodySection> {
    let o = Obj::open(raw, what, SECTION, diags)?;
    let name = o.text("name", "flange", diags).map(|(s, _)| s);
    let d_out = positive(o.quantity("d_out", Dimension::LENGTH, "63 mm", diags), &raw.span, what, diags);
    let d_out_tip = o.opt_quantity("d_out_tip", Dimension::LENGTH, "50 mm", diags);
    let d_in = o.opt_quantity("d_in", Dimension::LENGTH, "10 mm", diags).map(|d| d.unwrap_or(0.0));
    let length = positive(o.quantity("length", Dimension::LENGTH, "26 mm", diags), &raw.span, what, diags);
    let s = BodySection { name: name?, d_out: d_out?, d_out_tip: d_out_tip?, d_in: d_in?, length: length? };
    if s.d_in >= s.d_out.min(s.d_out_tip.unwrap_or(s.d_out)) {
        diags.error(Some(&raw.span), format!("{what}: the bore `d_in` is not smaller than the outer diameter"));
        return None;
    }
    Some(s)
}

fn read_bore(raw: &Raw, what: &str, diags: &mut Diagnostics) -> Option<Bore> {
    let o = Obj::open(raw, what, BORE, diags)?;
    let (d_min, d_max) = match (o.get("d"), o.get("d_min"), o.get("d_max")) {
        (Some(_), None, None) => {
            let d = o.quantity("d", Dimension::LENGTH, "12 mm", diags);
            (d, d)
        }
        (None, Some(_), Some(_)) => (
            o.quantity("d_min", Dimension::LENGTH, "2 mm", diags),
            o.quantity("d_max", Dimension::LENGTH, "20 mm", diags),
        ),
        _ => {
            diags.error_help(
                Some(&raw.span),
                format!("{what}: give the shank diameter it takes as `d`, or a range as `d_min` and `d_max`"),
                "`d: 12 mm` for a fixed bore (shrink-fit, hydraulic), `d_min: 2 mm, d_max: 20 mm` for a collet",
            );
            return None;
        }
    };
    let d_out = o.quantity("d_out", Dimension::LENGTH, "32 mm", diags);
    let d_out_tip = o.opt_quantity("d_out_tip", Dimension::LENGTH, "24 mm", diags);
    let clamp_length = o.quantity("clamp_length", Dimension::LENGTH, "47 mm", diags);
    let (d_min, d_max, d_out, d_out_tip, clamp_length) = (d_min?, d_max?, d_out?, d_out_tip?, clamp_length?);
    let d_out_tip = d_out_tip.unwrap_or(d_out);
    if !(d_min > 0.0 && d_max >= d_min && d_out.min(d_out_tip) > d_max && clamp_length > 0.0) {
        diags.error_help(
            Some(&raw.span),
            format!("{what}: the dimensions do not make a nose around a bore"),
            "0 < d_min ≤ d_max < d_out and d_out_tip, and clamp_length above 0",
        );
        return None;
    }
    Some(Bore { d_min, d_max, d_out, d_out_tip, clamp_length, span: raw.span.clone() })
}

fn read_tool(raw: &Raw, index: usize, diags: &mut Diagnostics) -> Option<Tool> {
    let o = Obj::open(raw, &format!("tool {}", index + 1), TOOL, diags)?;
    let (id, _) = id(&o, "tool", diags)?;
    let o = Obj { what: format!("tool `{id}`"), ..o };
    let what = |f: &str| format!("tool `{id}`: `{f}`");
    let diameter =
        positive(o.quantity("diameter", Dimension::LENGTH, "12 mm", diags), &raw.span, &what("diameter"), diags);
    let teeth = match o.get("teeth") {
        Some(Raw { kind: RawKind::Int(n), .. }) if (1..=64).contains(n) => Some(*n),
        Some(r) => {
            diags.error_help(
                Some(&r.span),
                format!("tool `{id}`: `teeth` must be a whole number from 1 to 64"),
                "e.g. `teeth: 4`",
            );
            None
        }
        None => {
            o.missing("teeth", "4", diags);
            None
        }
    };
    let flute_length = positive(
        o.quantity("flute_length", Dimension::LENGTH, "26 mm", diags),
        &raw.span,
        &what("flute_length"),
        diags,
    );
    let overall_length = positive(
        o.quantity("overall_length", Dimension::LENGTH, "83 mm", diags),
        &raw.span,
        &what("overall_length"),
        diags,
    );
    let shank = positive(o.quantity("shank", Dimension::LENGTH, "12 mm", diags), &raw.span, &what("shank"), diags);
    let material = o.text("material", "carbide", diags);
    let source = o.text("source", "DIN 6527 K", diags).map(|(s, _)| s);
    // The equivalent diameter of the fluted part: a length, or a fraction of the diameter.
    let d_equivalent = match o.get("d_equivalent") {
        None => {
            o.missing("d_equivalent", "86 %", diags);
            None
        }
        Some(r) => {
            let text = r.scalar_text().unwrap_or_default();
            match grammar::parse_quantity(&text) {
                Ok(q) if q.dim == Dimension::LENGTH => Some(q.value),
                Ok(q) if q.dim.is_dimensionless() && q.value > 0.0 && q.value <= 1.0 => diameter.map(|d| q.value * d),
                _ => {
                    diags.error_help(
                        Some(&r.span),
                        format!(
                            "tool `{id}`: `d_equivalent` `{text}` is neither a length nor a fraction of the diameter"
                        ),
                        "write a length (`10.3 mm`) or a fraction in (0, 1] (`86 %`)",
                    );
                    None
                }
            }
        }
    };
    let stickout = match o.get("stickout") {
        None => {
            o.missing("stickout", "36..60 step 3 mm", diags);
            None
        }
        Some(r) => stickouts(r, &id, diags),
    };
    let tool = Tool {
        id: id.clone(),
        diameter: diameter?,
        teeth: teeth?,
        flute_length: flute_length?,
        overall_length: overall_length?,
        shank: shank?,
        d_equivalent: d_equivalent?,
        material_span: material.as_ref()?.1.clone(),
        material: material?.0,
        stickout: stickout?,
        source: source?,
        span: raw.span.clone(),
    };
    let at = o.get("stickout").map_or(&raw.span, |r| &r.span);
    if tool.flute_length > tool.overall_length || tool.d_equivalent > tool.diameter {
        diags.error_help(
            Some(&raw.span),
            format!(
                "tool `{id}`: its flutes are longer than the tool, or its equivalent diameter larger than its diameter"
            ),
            "flute_length ≤ overall_length and d_equivalent ≤ diameter",
        );
        return None;
    }
    let longest = tool.stickout.iter().copied().fold(f64::MIN, f64::max);
    let left = tool.overall_length - longest;
    if left < MIN_CLAMPED_DIAMETERS * tool.shank - 1e-12 {
        diags.error_help(
            Some(at),
            format!(
                "tool `{id}`: a stickout of {} mm leaves {} mm of its {} mm length in the holder, less than {MIN_CLAMPED_DIAMETERS} shank diameters",
                mm(longest),
                mm(left),
                mm(tool.overall_length)
            ),
            format!("end the stickout range at {} mm or less", mm(tool.overall_length - MIN_CLAMPED_DIAMETERS * tool.shank)),
        );
        return None;
    }
    Some(tool)
}

/// Millimetres for a message, to the micrometre.
fn mm(v: f64) -> String {
    let r = (v * 1e6).round() / 1e3;
    format!("{r}")
}

/// The stickouts of a tool: a range (`21..45 step 3 mm`), a list (`[30, 40] mm`) or one length.
fn stickouts(r: &Raw, id: &str, diags: &mut Diagnostics) -> Option<Vec<f64>> {
    let text = r.scalar_text().unwrap_or_default();
    let example = "36..60 step 3 mm";
    let value = match grammar::parse_value(&text) {
        Ok(v) => v,
        Err(e) if e.to_string().contains("below its start") => {
            diags.error_help(
                Some(&r.span),
                format!("tool `{id}`: the stickout range `{text}` is empty: its end is below its start"),
                "a range runs from its start up to its end: write the shorter stickout first",
            );
            return None;
        }
        Err(e) => {
            diags.error_help(
                Some(&r.span),
                format!("tool `{id}`: `stickout` `{text}` is not a length, list or range: {e}"),
                format!("e.g. `{example}`"),
            );
            return None;
        }
    };
    if value.dimension().is_some_and(|d| d.is_dimensionless()) {
        diags.error_help(
            Some(&r.span),
            format!("tool `{id}`: `stickout` `{text}` has no unit, and a length is expected"),
            format!("write it with its unit, e.g. `{example}`"),
        );
        return None;
    }
    if let Err(e) = value.expect_dim(Dimension::LENGTH) {
        diags.error_help(Some(&r.span), format!("tool `{id}`: `stickout` `{text}`: {e}"), format!("e.g. `{example}`"));
        return None;
    }
    let points = value.points();
    if points.is_empty() {
        diags.error_help(
            Some(&r.span),
            format!("tool `{id}`: the stickout range `{text}` is empty"),
            "a range runs from its start up to its end: write the shorter stickout first",
        );
        return None;
    }
    if points.len() > 200 {
        diags.error_help(
            Some(&r.span),
            format!("tool `{id}`: `stickout` `{text}` holds {} stickouts", points.len()),
            "at most 200 per tool: take a coarser step",
        );
        return None;
    }
    if points.iter().any(|&p| p <= 0.0) {
        diags.error(Some(&r.span), format!("tool `{id}`: every stickout must be above 0"));
        return None;
    }
    Some(points)
}

/// A holder that names a tool must take its shank; a name must be a tool of the catalog.
fn check_pairs(holders: &[Holder], tools: &[Tool], diags: &mut Diagnostics) {
    for h in holders {
        for (name, span) in h.tools.iter().flatten() {
            let Some(t) = tools.iter().find(|t| t.id == *name) else {
                let hint = suggest(name, tools.iter().map(|t| t.id.as_str()))
                    .map(|s| format!("did you mean `{s}`?"))
                    .unwrap_or_else(|| "name a tool of `tools`".into());
                diags.error_help(Some(span), format!("holder `{}`: no tool `{name}` in the catalog", h.id), hint);
                continue;
            };
            if h.bore_for(t.shank).is_none() {
                let takes: Vec<String> = h
                    .bores
                    .iter()
                    .map(|b| if b.d_min == b.d_max { mm(b.d_min) } else { format!("{}–{}", mm(b.d_min), mm(b.d_max)) })
                    .collect();
                let bigger = h.bores.iter().all(|b| t.shank > b.d_max);
                diags.error_help(
                    Some(span),
                    format!(
                        "holder `{}` takes shanks of {} mm; tool `{name}` has a {} mm shank{}",
                        h.id,
                        takes.join(", "),
                        mm(t.shank),
                        if bigger { ", too big for its bore" } else { " that no bore fits" }
                    ),
                    "pair it with a holder whose bore takes its shank, or add that bore to the holder",
                );
            }
        }
    }
}

/// The materials the catalog's sections and tools name, each with where it is named.
pub fn materials_named(c: &Catalog) -> Vec<(&str, &Span)> {
    c.holders
        .iter()
        .map(|h| (h.material.as_str(), &h.material_span))
        .chain(c.tools.iter().map(|t| (t.material.as_str(), &t.material_span)))
        .collect()
}
