//! Typed values that cross node boundaries, and the port types that name them.
//!
//! Small structs with their units in the field docs (SI throughout), never loose vectors:
//! the compiler checks that a port of one type only feeds a port of the same type.

use crate::speed::Speed;
use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use std::fmt;

/// The type of a port, checked at compile time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PortType {
    TimeSeries,
    Frf,
    ReceptanceSet,
    ModalModel,
    BeamModel,
    Substructure,
    Lobes,
    Table,
    Scalar,
    FrfSet,
}

impl PortType {
    pub fn name(self) -> &'static str {
        match self {
            PortType::TimeSeries => "time series",
            PortType::Frf => "FRF",
            PortType::ReceptanceSet => "2x2 receptance set",
            PortType::ModalModel => "modal model",
            PortType::BeamModel => "beam model",
            PortType::Substructure => "substructure",
            PortType::Lobes => "stability lobes",
            PortType::Table => "table",
            PortType::Scalar => "scalar",
            PortType::FrfSet => "FRF set",
        }
    }
}

impl fmt::Display for PortType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A physical unit as stored with data: the dimension plus the symbol shown at the edges.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UnitLabel {
    /// SI symbol of the stored values, e.g. `m`, `N`, `m/N`.
    pub symbol: String,
}

impl UnitLabel {
    pub fn new(symbol: impl Into<String>) -> Self {
        UnitLabel { symbol: symbol.into() }
    }
}

/// One or more channels sampled at a constant rate, in SI units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TimeSeries {
    /// Samples per second (Hz).
    pub sample_rate: f64,
    /// Time of the first sample (s).
    pub t0: f64,
    pub channels: Vec<Channel>,
}

/// A named channel of a [`TimeSeries`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Channel {
    pub name: String,
    pub unit: UnitLabel,
    pub samples: Vec<f64>,
}

impl TimeSeries {
    pub fn len(&self) -> usize {
        self.channels.first().map_or(0, |c| c.samples.len())
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn channel(&self, name: &str) -> Option<&Channel> {
        self.channels.iter().find(|c| c.name == name)
    }
}

/// A frequency response function on a frequency grid (Hz), complex values in `unit` (e.g. m/N).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Frf {
    pub freq_hz: Vec<f64>,
    pub values: Vec<Complex64>,
    /// Ordinary coherence per line (0..1), when the estimate has one.
    pub coherence: Option<Vec<f64>>,
    pub unit: UnitLabel,
    /// Measurement direction (`x`, `y`), when known.
    pub direction: Option<String>,
    /// Spindle speed at which it was measured or predicted (written as `speed_rpm`).
    #[serde(rename = "speed_rpm")]
    pub speed: Option<Speed>,
    /// Name of the sensor that measured the response, when known.
    #[serde(default)]
    pub sensor: Option<String>,
    /// Response and reference node and direction of a measured FRF (UFF 58 record 6), when known.
    #[serde(default)]
    pub dofs: Option<FrfDofs>,
}

/// Where an FRF was measured: the response point and the reference (excitation) point, each a
/// node number and a direction code as UFF dataset 58 record 6 numbers them (1 x, 2 y, 3 z, 4–6
/// rotations about x, y, z). Codes are stored positive: the values are already turned to the
/// positive axes when they are read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct FrfDofs {
    pub response_node: i64,
    pub response_direction: i32,
    pub reference_node: i64,
    pub reference_direction: i32,
}

impl FrfDofs {
    /// True when response and reference are the same node and direction (a driving-point FRF,
    /// whose modal constants are all positive).
    pub fn driving_point(&self) -> bool {
        self.response_node == self.reference_node && self.response_direction == self.reference_direction
    }

    /// A UFF direction code as a word: `x`, `-y`, `rz`, `scalar`.
    pub fn axis_word(code: i32) -> String {
        let axis = match code.abs() {
            1 => "x",
            2 => "y",
            3 => "z",
            4 => "rx",
            5 => "ry",
            6 => "rz",
            _ => return "scalar".into(),
        };
        if code < 0 { format!("-{axis}") } else { axis.into() }
    }

    /// `response 3 x, reference 1 x`, for messages.
    pub fn describe(&self) -> String {
        let axis = |c: i32| match c {
            1 => "x",
            2 => "y",
            3 => "z",
            4 => "rx",
            5 => "ry",
            6 => "rz",
            _ => "scalar",
        };
        format!(
            "response {} {}, reference {} {}",
            self.response_node,
            axis(self.response_direction),
            self.reference_node,
            axis(self.reference_direction)
        )
    }
}

/// The kind of an FRF by its SI unit label: what response per force it holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrfKind {
    /// Displacement per force, m/N.
    Receptance,
    /// Velocity per force, m/s/N.
    Mobility,
    /// Acceleration per force, m/s²/N.
    Accelerance,
}

impl FrfKind {
    /// The kind of an SI label (`m/N`, `m/s/N`, `m/s^2/N`); `None` for another label or none.
    pub fn of_label(label: &str) -> Option<FrfKind> {
        match label.trim() {
            "m/N" => Some(FrfKind::Receptance),
            "m/s/N" => Some(FrfKind::Mobility),
            "m/s^2/N" => Some(FrfKind::Accelerance),
            _ => None,
        }
    }

    /// The SI label of the kind.
    pub fn label(self) -> &'static str {
        match self {
            FrfKind::Receptance => "m/N",
            FrfKind::Mobility => "m/s/N",
            FrfKind::Accelerance => "m/s^2/N",
        }
    }

    /// The kind's name, for messages.
    pub fn name(self) -> &'static str {
        match self {
            FrfKind::Receptance => "receptance",
            FrfKind::Mobility => "mobility",
            FrfKind::Accelerance => "accelerance",
        }
    }

    /// Powers of `iω` that take a receptance to this kind: 0, 1, 2 (velocity `iωx`,
    /// acceleration `−ω²x`).
    pub fn order(self) -> i32 {
        match self {
            FrfKind::Receptance => 0,
            FrfKind::Mobility => 1,
            FrfKind::Accelerance => 2,
        }
    }
}

impl Frf {
    /// The FRF's kind by its unit label, when it is an SI label of one.
    pub fn kind(&self) -> Option<FrfKind> {
        FrfKind::of_label(&self.unit.symbol)
    }
}

/// A measurement set: the FRFs of one structure (one per response and reference point, as a
/// modal test gives them) on one common frequency grid and in one unit, each with its response
/// and reference nodes and directions. Fitted together, they share their poles
/// (`modal.fit_set`); written, each FRF is one UFF dataset 58 or one block of CSV rows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrfSet {
    /// The FRFs, in the order they were read; every one on the same `freq_hz` and `unit`.
    pub frfs: Vec<Frf>,
}

/// Frequency lines of two FRFs of a set agree when within this relative distance (a grid
/// written with 6–7 digits reads back a few ulps off).
pub const SET_GRID_TOLERANCE: f64 = 1e-9;

/// Whether two frequency lines agree within [`SET_GRID_TOLERANCE`] (a NaN agrees with nothing).
fn same_line(a: f64, b: f64) -> bool {
    (a - b).abs() <= SET_GRID_TOLERANCE * a.abs().max(b.abs())
}

/// Why FRFs do not make a set.
#[derive(Debug, Clone, PartialEq)]
pub enum FrfSetError {
    /// No FRF at all.
    Empty,
    /// FRF `index` (from 0) has another number of lines, or a line elsewhere, than the first.
    Grid { index: usize, why: String },
    /// FRF `index` (from 0) is in another unit than the first.
    Unit { index: usize, unit: String, first: String },
}

impl fmt::Display for FrfSetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrfSetError::Empty => f.write_str("a set needs at least one FRF"),
            FrfSetError::Grid { why, .. } => f.write_str(why),
            FrfSetError::Unit { unit, first, .. } => {
                write!(f, "its values are in `{unit}`, the first FRF's in `{first}`")
            }
        }
    }
}

impl FrfSet {
    /// The set of `frfs`, checked: at least one, every one on the first one's lines (within
    /// [`SET_GRID_TOLERANCE`]) and in its unit.
    pub fn new(frfs: Vec<Frf>) -> Result<FrfSet, FrfSetError> {
        let Some(first) = frfs.first() else {
            return Err(FrfSetError::Empty);
        };
        for (index, f) in frfs.iter().enumerate().skip(1) {
            if f.freq_hz.len() != first.freq_hz.len() {
                return Err(FrfSetError::Grid {
                    index,
                    why: format!("it has {} lines, the first FRF {}", f.freq_hz.len(), first.freq_hz.len()),
                });
            }
            if let Some(k) = f.freq_hz.iter().zip(&first.freq_hz).position(|(&a, &b)| !same_line(a, b)) {
                return Err(FrfSetError::Grid {
                    index,
                    why: format!(
                        "its line {} is at {} Hz, the first FRF's at {} Hz",
                        k + 1,
                        f.freq_hz[k],
                        first.freq_hz[k]
                    ),
                });
            }
            if f.unit.symbol.trim() != first.unit.symbol.trim() {
                return Err(FrfSetError::Unit { index, unit: f.unit.symbol.clone(), first: first.unit.symbol.clone() });
            }
        }
        Ok(FrfSet { frfs })
    }

    /// The common frequency grid, Hz (the first FRF's).
    pub fn freq_hz(&self) -> &[f64] {
        self.frfs.first().map_or(&[], |f| f.freq_hz.as_slice())
    }

    /// The common unit label.
    pub fn unit(&self) -> &str {
        self.frfs.first().map_or("", |f| f.unit.symbol.as_str())
    }

    /// How FRF `i` (from 0) is named in legends and messages: by its nodes and directions
    /// (`response 1 x / reference 3 x`), else by its place in the set (`FRF 2`).
    pub fn name(&self, i: usize) -> String {
        match self.frfs.get(i).and_then(|f| f.dofs) {
            Some(d) => d.describe().replacen(", reference", " / reference", 1),
            None => format!("FRF {}", i + 1),
        }
    }
}

/// The 2x2 receptance blocks `[[h, l], [n, p]]` (displacement and rotation per force and moment) on a grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReceptanceSet {
    pub freq_hz: Vec<f64>,
    /// Displacement per force (m/N).
    pub h: Vec<Complex64>,
    /// Displacement per moment (m/(N m)).
    pub l: Vec<Complex64>,
    /// Rotation per force (rad/N).
    pub n: Vec<Complex64>,
    /// Rotation per moment (rad/(N m)).
    pub p: Vec<Complex64>,
    /// Direction (`x`, `y`) the blocks describe, when known.
    #[serde(default)]
    pub direction: Option<String>,
    /// Spindle speed they hold at, when known (written as `speed_rpm`).
    #[serde(default, rename = "speed_rpm")]
    pub speed: Option<Speed>,
}

/// Modal parameters of a structure at one point and direction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModalModel {
    pub modes: Vec<Mode>,
}

/// One mode of a structure at one point and direction: natural frequency (Hz), viscous
/// damping ratio and modal mass (kg). The one mode type of every kernel (modal fit, stability,
/// spindle models): its receptance is Eq. 5.8, `1/(m(ω_n² − ω² + 2iζω_nω))`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Mode {
    pub freq_hz: f64,
    pub damping_ratio: f64,
    pub modal_mass: f64,
}

impl Mode {
    /// The mode with modal stiffness `k` (N/m) instead of a modal mass: `m = k/(2πf)²`.
    pub fn from_stiffness(freq_hz: f64, damping_ratio: f64, stiffness: f64) -> Mode {
        let wn = std::f64::consts::TAU * freq_hz;
        Mode { freq_hz, damping_ratio, modal_mass: stiffness / (wn * wn) }
    }

    /// The mode of modal mass `m` (kg), stiffness `k` (N/m) and viscous damping `c` (N·s/m):
    /// `f = √(k/m)/2π`, `ζ = c/(2√(km))` (zero when undamped, so a free rigid-body mode,
    /// `k = 0`, is `f = 0` with its mass).
    pub fn from_mass_stiffness_damping(m: f64, k: f64, c: f64) -> Mode {
        let damping_ratio = if c == 0.0 { 0.0 } else { c / (2.0 * (k * m).sqrt()) };
        Mode { freq_hz: (k / m).sqrt() / std::f64::consts::TAU, damping_ratio, modal_mass: m }
    }

    /// Viscous modal damping `c = 2ζ m ω_n`, N·s/m.
    pub fn damping(&self) -> f64 {
        2.0 * self.damping_ratio * self.modal_mass * self.omega()
    }

    /// Natural angular frequency `2πf`, rad/s.
    pub fn omega(&self) -> f64 {
        std::f64::consts::TAU * self.freq_hz
    }

    /// Modal stiffness `m(2πf)²`, N/m.
    pub fn stiffness(&self) -> f64 {
        let wn = self.omega();
        self.modal_mass * wn * wn
    }

    /// Receptance at `omega` (rad/s), Eq. 5.8: `1/(m(ω_n² − ω² + 2iζω_nω))`, m/N.
    #[inline]
    pub fn receptance(&self, omega: f64) -> Complex64 {
        let wn = self.omega();
        let re = self.modal_mass * (wn * wn - omega * omega);
        let im = 2.0 * self.damping_ratio * self.modal_mass * wn * omega;
        let inv = 1.0 / (re * re + im * im);
        Complex64::new(re * inv, -im * inv)
    }
}

/// A free–free beam assembly: Timoshenko sections from the spindle end to the tip.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BeamModel {
    pub sections: Vec<crate::entity::Section>,
}

/// A free–free substructure (a holder with its tool) reduced to its two coupling points, the
/// tip and the spindle end: every complex mode of its FE model with the shapes kept at those
/// points. Receptances between them are exact on any frequency grid, so the substructure is
/// built once and coupled at every speed, direction or joint setting.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Substructure {
    /// The assembly it was built from.
    pub assembly: String,
    /// One part when the tool joint is rigid; otherwise the holder (with the inserted shank),
    /// then the protruding tool, joined by `tool_joint`.
    pub parts: Vec<SubstructurePart>,
    /// The tool joint between the parts: `[kt N/m, ct N·s/m, kr N·m/rad, cr N·m·s/rad]`.
    pub tool_joint: Option<[f64; 4]>,
}

/// One free–free part of a [`Substructure`], in the modal form `Σ_r u_r u_rᵀ/(1 − sν_r)`,
/// `s = σ + ω²` (the shift σ is the part's own).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SubstructurePart {
    /// `whole`, `holder` or `tool`.
    pub name: String,
    /// Length from the spindle end to the tip, m.
    pub length: f64,
    /// The shift σ, rad²/s².
    pub shift: f64,
    /// Number of rigid-body modes (the first ones).
    pub rigid_modes: usize,
    /// Natural frequencies, Hz, ascending: of the undamped modes, or with structural damping
    /// of the complex modes (`√Re λ*`, `λ* = ω²(1 + iη)`).
    pub natural_hz: Vec<f64>,
    /// Complex `ν_r` of every mode.
    pub nu: Vec<Complex64>,
    /// Mode shapes at tip y, tip θ, spindle-end y, spindle-end θ: one value per mode each.
    pub shapes: [Vec<Complex64>; 4],
}

/// A stability lobe diagram: limiting depth of cut (m) over spindle speed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Lobes {
    /// The speeds, ascending (written as `speed_rpm`).
    #[serde(rename = "speed_rpm")]
    pub speed: Vec<Speed>,
    /// Limiting depth (m); `+∞` where no lobe limits the cut at that speed.
    #[serde(with = "nonfinite::seq")]
    pub depth_limit: Vec<f64>,
    /// Chatter frequency (Hz) of the lobe that sets the limit at each speed.
    #[serde(with = "nonfinite::seq")]
    pub chatter_hz: Vec<f64>,
}

impl Lobes {
    /// A diagram over speeds given in rpm.
    pub fn from_rpm(speed_rpm: &[f64], depth_limit: Vec<f64>, chatter_hz: Vec<f64>) -> Lobes {
        Lobes { speed: speed_rpm.iter().map(|&n| Speed::from_rpm(n)).collect(), depth_limit, chatter_hz }
    }

    /// The speeds in rpm, as written ([`Speed::rpm_as_written`]).
    pub fn speeds_rpm(&self) -> Vec<f64> {
        self.speed.iter().map(|s| s.rpm_as_written()).collect()
    }
}

/// A table of named columns with units, e.g. figures of merit over a sweep: numbers, or
/// words (a direction, a node's label) where a column names things.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Table {
    pub columns: Vec<Column>,
}

/// One column of a [`Table`]. A text column holds each row as an index into `levels` (as
/// a categorical does), so every column stays a vector of numbers for the nodes and plots
/// that compute with them, and is written and read as the words.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Column {
    pub name: String,
    pub unit: UnitLabel,
    #[serde(with = "nonfinite::seq")]
    pub values: Vec<f64>,
    /// The words of a text column, indexed by `values`; empty for a numeric column. Always
    /// serialised (the cache's binary form has no optional fields).
    #[serde(default)]
    pub levels: Vec<String>,
}

impl Column {
    pub fn new(name: impl Into<String>, unit: &str, values: Vec<f64>) -> Self {
        Column { name: name.into(), unit: UnitLabel::new(unit), values, levels: Vec::new() }
    }

    /// A text column of `cells`, its levels in order of first appearance.
    pub fn text<S: AsRef<str>>(name: impl Into<String>, cells: &[S]) -> Self {
        let mut levels: Vec<String> = Vec::new();
        let values = cells
            .iter()
            .map(|c| {
                let c = c.as_ref();
                let i = levels.iter().position(|l| l == c).unwrap_or_else(|| {
                    levels.push(c.to_string());
                    levels.len() - 1
                });
                i as f64
            })
            .collect();
        Column { name: name.into(), unit: UnitLabel::new(""), values, levels }
    }

    pub fn is_text(&self) -> bool {
        !self.levels.is_empty()
    }

    /// Row `i` of a text column as its word (`None` for a numeric column or an index
    /// outside the levels).
    pub fn word(&self, i: usize) -> Option<&str> {
        let v = *self.values.get(i)?;
        if !self.is_text() || v.is_nan() || v < 0.0 || v.fract() != 0.0 {
            return None;
        }
        self.levels.get(v as usize).map(String::as_str)
    }
}

impl Table {
    pub fn rows(&self) -> usize {
        self.columns.first().map_or(0, |c| c.values.len())
    }
}

/// A single number with its unit (SI).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scalar {
    #[serde(with = "nonfinite")]
    pub value: f64,
    pub unit: UnitLabel,
}

impl Scalar {
    pub fn new(value: f64, unit: &str) -> Self {
        Scalar { value, unit: UnitLabel::new(unit) }
    }
}

/// Any value a port can carry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Value {
    TimeSeries(TimeSeries),
    Frf(Frf),
    ReceptanceSet(ReceptanceSet),
    ModalModel(ModalModel),
    BeamModel(BeamModel),
    Substructure(Substructure),
    Lobes(Lobes),
    Table(Table),
    Scalar(Scalar),
    /// Appended last: the cache codec numbers variants by position.
    FrfSet(FrfSet),
}

impl Value {
    pub fn port_type(&self) -> PortType {
        match self {
            Value::TimeSeries(_) => PortType::TimeSeries,
            Value::Frf(_) => PortType::Frf,
            Value::ReceptanceSet(_) => PortType::ReceptanceSet,
            Value::ModalModel(_) => PortType::ModalModel,
            Value::BeamModel(_) => PortType::BeamModel,
            Value::Substructure(_) => PortType::Substructure,
            Value::Lobes(_) => PortType::Lobes,
            Value::Table(_) => PortType::Table,
            Value::Scalar(_) => PortType::Scalar,
            Value::FrfSet(_) => PortType::FrfSet,
        }
    }
}

/// Numbers that may be infinite or NaN (a lobe that limits nothing, a trial outside a diagram).
/// JSON has no such numbers and would write `null`, which says nothing and does not read back:
/// text formats get the strings `"inf"`, `"-inf"` and `"NaN"` and read them (and `null`, as
/// NaN) back; binary formats (the cache) keep the `f64`.
pub mod nonfinite {
    use serde::de::{self, Deserializer, SeqAccess, Visitor};
    use serde::ser::{SerializeSeq, Serializer};
    use std::fmt;

    fn text(v: f64) -> Option<&'static str> {
        if v.is_nan() {
            Some("NaN")
        } else if v == f64::INFINITY {
            Some("inf")
        } else if v == f64::NEG_INFINITY {
            Some("-inf")
        } else {
            None
        }
    }

    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        match text(*v) {
            Some(t) if s.is_human_readable() => s.serialize_str(t),
            _ => s.serialize_f64(*v),
        }
    }

    struct Number;

    impl<'de> Visitor<'de> for Number {
        type Value = f64;
        fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
            f.write_str("a number, or \"inf\", \"-inf\" or \"NaN\"")
        }
        fn visit_f64<E: de::Error>(self, v: f64) -> Result<f64, E> {
            Ok(v)
        }
        fn visit_i64<E: de::Error>(self, v: i64) -> Result<f64, E> {
            Ok(v as f64)
        }
        fn visit_u64<E: de::Error>(self, v: u64) -> Result<f64, E> {
            Ok(v as f64)
        }
        fn visit_unit<E: de::Error>(self) -> Result<f64, E> {
            Ok(f64::NAN)
        }
        fn visit_str<E: de::Error>(self, v: &str) -> Result<f64, E> {
            match v {
                "inf" | "+inf" | "Infinity" => Ok(f64::INFINITY),
                "-inf" | "-Infinity" => Ok(f64::NEG_INFINITY),
                "NaN" | "nan" => Ok(f64::NAN),
                other => Err(E::invalid_value(de::Unexpected::Str(other), &self)),
            }
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        if d.is_human_readable() { d.deserialize_any(Number) } else { d.deserialize_f64(Number) }
    }

    /// The same for a list of numbers.
    pub mod seq {
        use super::*;

        struct One(f64);

        impl serde::Serialize for One {
            fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                super::serialize(&self.0, s)
            }
        }

        impl<'de> serde::Deserialize<'de> for One {
            fn deserialize<D: Deserializer<'de>>(d: D) -> Result<One, D::Error> {
                super::deserialize(d).map(One)
            }
        }

        pub fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
            let mut seq = s.serialize_seq(Some(v.len()))?;
            for x in v {
                seq.serialize_element(&One(*x))?;
            }
            seq.end()
        }

        struct Many;

        impl<'de> Visitor<'de> for Many {
            type Value = Vec<f64>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a list of numbers")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut a: A) -> Result<Vec<f64>, A::Error> {
                // Never reserve from a length the input states.
                let mut out = Vec::new();
                while let Some(One(v)) = a.next_element()? {
                    out.push(v);
                }
                Ok(out)
            }
        }

        pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
            d.deserialize_seq(Many)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Mode;

    #[test]
    fn mode_receptance_has_its_static_and_resonant_closed_forms() {
        let m = Mode::from_stiffness(820.0, 0.03, 2e7);
        assert!((m.stiffness() / 2e7 - 1.0).abs() < 1e-14);
        let h0 = m.receptance(0.0);
        assert!((h0.re * 2e7 - 1.0).abs() < 1e-14 && h0.im == 0.0);
        // At resonance the response is purely imaginary, −1/(2ζk).
        let hr = m.receptance(m.omega());
        assert!(hr.re.abs() < 1e-12 * hr.im.abs());
        assert!((hr.im * 2.0 * 0.03 * 2e7 + 1.0).abs() < 1e-12);
    }

    #[test]
    fn mass_stiffness_and_damping_round_trip() {
        let m = Mode::from_mass_stiffness_damping(0.4, 3e7, 120.0);
        assert!((m.stiffness() / 3e7 - 1.0).abs() < 1e-14 && (m.damping() / 120.0 - 1.0).abs() < 1e-14);
        assert!((m.freq_hz - (3e7f64 / 0.4).sqrt() / std::f64::consts::TAU).abs() < 1e-12);
        let rigid = Mode::from_mass_stiffness_damping(2.0, 0.0, 0.0);
        assert_eq!((rigid.freq_hz, rigid.damping_ratio, rigid.modal_mass, rigid.stiffness()), (0.0, 0.0, 2.0, 0.0));
    }
}
