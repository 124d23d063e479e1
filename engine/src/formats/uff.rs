//! Universal File Format dataset 58: one function (time response, FRF, ...) at a nodal
//! degree of freedom, in ASCII (58) or binary (58b).
//!
//! A dataset is framed by `    -1` lines. Records 1–5 are ID lines, record 6 identifies the
//! function and the response and reference DOFs, record 7 the data form (ordinate type,
//! number of points, abscissa spacing), records 8–11 the abscissa, ordinate numerator,
//! ordinate denominator and Z-axis data characteristics, and record 12 the data. Records 6
//! and 8–11 are read by their published columns (their names and labels may hold spaces);
//! record 7 by its columns where they hold its three integers, else (and the data values) by
//! whitespace, which every writer leaves between real numbers.
//! Other datasets are skipped and listed.

use super::{FormatError, Loc, Skipped, unit_to_si};
use crate::value::{Channel, Frf, FrfDofs, ReceptanceSet, TimeSeries, UnitLabel};
use num_complex::Complex64;
use spindlelab_domain::Speed;
use spindlelab_grammar::Dimension;
use std::fmt::Write as _;

/// Function type of a time response (record 6, field 1).
pub const FUNCTION_TIME: i32 = 1;
/// Function type of a frequency response function.
pub const FUNCTION_FRF: i32 = 4;

/// A short description of a UFF function type, for messages ("an FRF").
pub fn function_name(t: i32) -> &'static str {
    match t {
        0 => "a general function",
        1 => "a time response",
        2 => "an auto spectrum",
        3 => "a cross spectrum",
        4 => "an FRF",
        5 => "a transmissibility",
        6 => "a coherence",
        7 => "an auto correlation",
        8 => "a cross correlation",
        9 => "a power spectral density",
        10 => "an energy spectral density",
        12 => "a spectrum",
        _ => "a function of another type",
    }
}

/// Axis name of a UFF direction code: ±1 x, ±2 y, ±3 z, ±4..±6 rotations; 0 (scalar) has none.
pub fn direction_name(code: i32) -> Option<&'static str> {
    match code.abs() {
        1 => Some("x"),
        2 => Some("y"),
        3 => Some("z"),
        4 => Some("rx"),
        5 => Some("ry"),
        6 => Some("rz"),
        _ => None,
    }
}

/// The positive direction code of an axis name (`x` → 1); 0 for anything else.
pub fn direction_code(name: Option<&str>) -> i32 {
    match name {
        Some("x") => 1,
        Some("y") => 2,
        Some("z") => 3,
        Some("rx") => 4,
        Some("ry") => 5,
        Some("rz") => 6,
        _ => 0,
    }
}

/// Ordinate data type of record 7, field 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OrdinateType {
    RealSingle = 2,
    RealDouble = 4,
    ComplexSingle = 5,
    ComplexDouble = 6,
}

impl OrdinateType {
    fn from_code(code: i64) -> Option<Self> {
        match code {
            2 => Some(OrdinateType::RealSingle),
            4 => Some(OrdinateType::RealDouble),
            5 => Some(OrdinateType::ComplexSingle),
            6 => Some(OrdinateType::ComplexDouble),
            _ => None,
        }
    }
    pub fn is_complex(self) -> bool {
        matches!(self, OrdinateType::ComplexSingle | OrdinateType::ComplexDouble)
    }
    pub fn is_double(self) -> bool {
        matches!(self, OrdinateType::RealDouble | OrdinateType::ComplexDouble)
    }
    fn name(self) -> &'static str {
        match self {
            OrdinateType::RealSingle => "real single",
            OrdinateType::RealDouble => "real double",
            OrdinateType::ComplexSingle => "complex single",
            OrdinateType::ComplexDouble => "complex double",
        }
    }
}

/// A degree of freedom of record 6: entity name, node and direction code.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Dof {
    pub entity: String,
    pub node: i64,
    /// 0 scalar, ±1 x, ±2 y, ±3 z, ±4..±6 rotations about x, y, z.
    pub direction: i32,
}

/// Data characteristics of one axis (records 8–11).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Axis {
    /// Specific data type: 0 unknown, 1 general, 8 displacement, 11 velocity, 12 acceleration,
    /// 13 excitation force, 17 time, 18 frequency, 19 rpm, ...
    pub data_type: i32,
    pub length_exp: i32,
    pub force_exp: i32,
    pub temperature_exp: i32,
    pub label: String,
    pub units: String,
}

/// The abscissa of record 7 (even spacing) or of the data (uneven), in the file's units.
#[derive(Debug, Clone, PartialEq)]
pub enum Abscissa {
    Even { min: f64, step: f64 },
    Uneven(Vec<f64>),
}

/// The ordinate values, in the file's units.
#[derive(Debug, Clone, PartialEq)]
pub enum Ordinate {
    Real(Vec<f64>),
    Complex(Vec<Complex64>),
}

/// One dataset 58 as the file holds it.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset58 {
    /// Line of the dataset number (`58` or `58b`).
    pub line: usize,
    pub binary: bool,
    /// ID lines 1–5 (records 1–5), trimmed.
    pub id: [String; 5],
    pub function_type: i32,
    pub function_id: i64,
    pub version: i64,
    pub load_case: i64,
    pub response: Dof,
    pub reference: Dof,
    pub ordinate_type: OrdinateType,
    pub abscissa: Abscissa,
    pub z_value: f64,
    pub abscissa_axis: Axis,
    pub numerator: Axis,
    pub denominator: Axis,
    pub z_axis: Axis,
    pub ordinate: Ordinate,
}

/// The datasets 58 of a file, and what was skipped.
#[derive(Debug, Clone, PartialEq)]
pub struct UffFile {
    pub datasets: Vec<Dataset58>,
    pub skipped: Vec<Skipped>,
}

impl UffFile {
    /// The datasets 58 as a list for messages: `1: an FRF in x (line 2), ...`.
    /// At most [`super::LISTED`] are written out, the rest counted.
    pub fn summary(&self) -> String {
        super::listed(self.datasets.iter().enumerate().map(|(i, d)| format!("{}: {}", i + 1, d.describe())), ", ")
    }
}

impl Dataset58 {
    /// Number of points.
    pub fn len(&self) -> usize {
        match &self.ordinate {
            Ordinate::Real(v) => v.len(),
            Ordinate::Complex(v) => v.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Abscissa of point `i`, in the file's units.
    pub fn abscissa_at(&self, i: usize) -> f64 {
        match &self.abscissa {
            Abscissa::Even { min, step } => min + i as f64 * step,
            Abscissa::Uneven(x) => x[i],
        }
    }

    /// Ordinate of point `i` (imaginary part 0 for real data), in the file's units.
    pub fn value_at(&self, i: usize) -> Complex64 {
        match &self.ordinate {
            Ordinate::Real(v) => Complex64::new(v[i], 0.0),
            Ordinate::Complex(v) => v[i],
        }
    }

    /// `an FRF in x (line 2)`, for messages; an FRF with node numbers says them too
    /// (`an FRF in x, response 1 x, reference 3 x (line 517)`).
    pub fn describe(&self) -> String {
        if self.function_type == FUNCTION_FRF && (self.response.node != 0 || self.reference.node != 0) {
            let axis = |c: i32| direction_name(c).unwrap_or("scalar");
            return format!(
                "{} in {}, response {} {}, reference {} {} (line {})",
                function_name(self.function_type),
                axis(self.response.direction),
                self.response.node,
                axis(self.response.direction),
                self.reference.node,
                axis(self.reference.direction),
                self.line
            );
        }
        match direction_name(self.response.direction) {
            Some(d) => format!("{} in {d} (line {})", function_name(self.function_type), self.line),
            None => format!("{} (line {})", function_name(self.function_type), self.line),
        }
    }

    fn at(&self, path: &str) -> Loc {
        Loc::new(path, self.line, 0)
    }

    /// The dataset as a one-channel time series (function type 1, real ordinate), in SI.
    ///
    /// The channel is named by ID line 1 (else by the ordinate's data type). An uneven
    /// abscissa must be uniform; the increment is stored with 6–7 digits, so a sample rate
    /// within 1e-6 of a whole number of hertz is taken as that number.
    pub fn to_time_series(&self, path: &str) -> Result<TimeSeries, FormatError> {
        let Ordinate::Real(values) = &self.ordinate else {
            return Err(FormatError::Unsupported {
                at: self.at(path),
                message: format!(
                    "time response with {} ordinates; a time series takes real values (ordinate type 2 or 4)",
                    self.ordinate_type.name()
                ),
            });
        };
        let tscale = axis_scale(&self.abscissa_axis, Dimension::TIME, self.at(path), "time response")?;
        let n = values.len();
        let (t0, dt) = match &self.abscissa {
            Abscissa::Even { min, step } => (*min, *step),
            Abscissa::Uneven(x) => {
                if n < 2 {
                    return Err(FormatError::Unsupported {
                        at: self.at(path),
                        message: "one point with uneven abscissa: the sample rate cannot be told".into(),
                    });
                }
                let dt = (x[n - 1] - x[0]) / (n - 1) as f64;
                if let Some(i) =
                    (0..n).find(|&i| (x[i] - (x[0] + i as f64 * dt)).abs() > 1e-3 * dt.abs() + 1e-5 * x[i].abs())
                {
                    return Err(FormatError::Unsupported {
                        at: self.at(path),
                        message: format!(
                            "time response sampled unevenly (point {} is at {:e}, a constant rate puts it at {:e}); \
                             a time series needs a constant sample rate",
                            i + 1,
                            x[i],
                            x[0] + i as f64 * dt
                        ),
                    });
                }
                (x[0], dt)
            }
        };
        if dt <= 0.0 || !dt.is_finite() {
            return Err(FormatError::Unsupported {
                at: self.at(path),
                message: format!("abscissa increment {dt:e}: a time series needs a positive time step"),
            });
        }
        let mut sample_rate = 1.0 / (dt * tscale);
        let whole = sample_rate.round();
        if (sample_rate - whole).abs() <= 1e-6 * whole {
            sample_rate = whole;
        }
        let (scale, symbol) = axis_unit(&self.numerator);
        let samples = if scale == 1.0 { values.clone() } else { values.iter().map(|v| v * scale).collect() };
        let name = match id_text(&self.id[0]) {
            Some(n) => n.to_string(),
            None => type_name(self.numerator.data_type).unwrap_or("response").to_string(),
        };
        Ok(TimeSeries {
            sample_rate,
            t0: t0 * tscale,
            channels: vec![Channel { name, unit: UnitLabel::new(symbol), samples }],
        })
    }

    /// The dataset as an FRF, in SI: frequencies in Hz, values in numerator/denominator units.
    ///
    /// `direction` is the response axis; values are turned to the positive axes (multiplied
    /// by the signs of the response and reference direction codes). The speed comes from a
    /// Z axis in rpm (data type 19), the sensor from an ID line `sensor: NAME`.
    pub fn to_frf(&self, path: &str) -> Result<Frf, FormatError> {
        let fscale = axis_scale(&self.abscissa_axis, Dimension::FREQUENCY, self.at(path), "FRF")?;
        let (nscale, nsym) = axis_unit(&self.numerator);
        let (dscale, dsym) = axis_unit(&self.denominator);
        let sign = |code: i32| if code < 0 { -1.0 } else { 1.0 };
        let factor = sign(self.response.direction) * sign(self.reference.direction) * nscale / dscale;
        let n = self.len();
        let freq_hz: Vec<f64> = (0..n).map(|i| self.abscissa_at(i) * fscale).collect();
        if let Abscissa::Even { step, .. } = self.abscissa
            && n > 1
            && step.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
        {
            return Err(FormatError::Unsupported {
                at: self.at(path),
                message: format!("abscissa increment {step:e}: an FRF needs a positive frequency step"),
            });
        }
        let mut before = None;
        for (i, &f) in freq_hz.iter().enumerate() {
            if let Some(why) = super::frequency_problem(before, f) {
                return Err(FormatError::Unsupported {
                    at: self.at(path),
                    message: format!("point {} is at {f:?} Hz, where the dataset needs {why}", i + 1),
                });
            }
            before = Some(f);
        }
        let values: Vec<Complex64> = (0..n).map(|i| self.value_at(i) * factor).collect();
        let unit = match (nsym.is_empty(), dsym.is_empty()) {
            (_, true) => nsym,
            (true, false) => format!("1/{dsym}"),
            (false, false) => format!("{nsym}/{dsym}"),
        };
        let rpm = self.z_axis.data_type == 19 || self.z_axis.units.trim().eq_ignore_ascii_case("rpm");
        let sensor = self.id.iter().find_map(|l| {
            let (key, rest) = l.split_once(':')?;
            (key.trim().eq_ignore_ascii_case("sensor") && !rest.trim().is_empty()).then(|| rest.trim().to_string())
        });
        Ok(Frf {
            freq_hz,
            values,
            coherence: None,
            unit: UnitLabel::new(unit),
            direction: direction_name(self.response.direction).map(str::to_string),
            speed: rpm.then(|| Speed::from_rpm(self.z_value)),
            sensor,
            dofs: Some(FrfDofs {
                response_node: self.response.node,
                response_direction: self.response.direction.abs(),
                reference_node: self.reference.node,
                reference_direction: self.reference.direction.abs(),
            }),
        })
    }

    /// An FRF as a dataset: complex double ordinates, even abscissa when the grid is uniform,
    /// `label` (a sweep label) in ID line 2, the sensor in ID line 4, the speed on the Z axis,
    /// the response and reference nodes and directions of the FRF (without them node 1 and the
    /// FRF's direction for both: a direct FRF).
    pub fn from_frf(frf: &Frf, label: &str) -> Dataset58 {
        let dir = direction_code(frf.direction.as_deref());
        let (response, reference) = match frf.dofs {
            Some(d) => (
                Dof { entity: "NONE".into(), node: d.response_node, direction: d.response_direction },
                Dof { entity: "NONE".into(), node: d.reference_node, direction: d.reference_direction },
            ),
            None => (
                Dof { entity: "NONE".into(), node: 1, direction: dir },
                Dof { entity: "NONE".into(), node: 1, direction: dir },
            ),
        };
        let (num, den) = match frf.unit.symbol.rsplit_once('/') {
            Some((n, d)) => (n, d),
            None => (frf.unit.symbol.as_str(), ""),
        };
        let abscissa = even_grid(&frf.freq_hz)
            .map_or_else(|| Abscissa::Uneven(frf.freq_hz.clone()), |(min, step)| Abscissa::Even { min, step });
        let title = frf.direction.as_deref().map_or_else(|| "FRF".to_string(), |d| format!("FRF {d}"));
        Dataset58 {
            line: 0,
            binary: false,
            id: [
                title,
                label.to_string(),
                String::new(),
                frf.sensor.as_deref().map(|s| format!("sensor: {s}")).unwrap_or_default(),
                String::new(),
            ],
            function_type: FUNCTION_FRF,
            function_id: 0,
            version: 0,
            load_case: 0,
            response,
            reference,
            ordinate_type: OrdinateType::ComplexDouble,
            abscissa,
            z_value: frf.speed.map_or(0.0, Speed::rpm_as_written),
            abscissa_axis: axis_for("Hz"),
            numerator: axis_for(num),
            denominator: axis_for(den),
            z_axis: if frf.speed.is_some() { axis_for("rpm") } else { axis_for("") },
            ordinate: Ordinate::Complex(frf.values.clone()),
        }
    }

    /// One channel of a time series as a dataset: real double ordinates, even abscissa from
    /// `t0` in steps of `1/sample_rate`, the channel name in ID line 1 and `label` in ID line 2.
    pub fn from_channel(ts: &TimeSeries, channel: &Channel, label: &str) -> Dataset58 {
        Dataset58 {
            line: 0,
            binary: false,
            id: [channel.name.clone(), label.to_string(), String::new(), String::new(), String::new()],
            function_type: FUNCTION_TIME,
            function_id: 0,
            version: 0,
            load_case: 0,
            response: Dof { entity: "NONE".into(), node: 1, direction: 0 },
            reference: Dof { entity: "NONE".into(), node: 0, direction: 0 },
            ordinate_type: OrdinateType::RealDouble,
            abscissa: Abscissa::Even { min: ts.t0, step: 1.0 / ts.sample_rate },
            z_value: 0.0,
            abscissa_axis: axis_for("s"),
            numerator: axis_for(&channel.unit.symbol),
            denominator: axis_for(""),
            z_axis: axis_for(""),
            ordinate: Ordinate::Real(channel.samples.clone()),
        }
    }
}

/// ID line text, `None` when blank or `NONE`.
fn id_text(s: &str) -> Option<&str> {
    let t = s.trim();
    (!t.is_empty() && t != "NONE").then_some(t)
}

/// Start and step of a uniform grid (to 1e-9 of its span), or `None`.
fn even_grid(x: &[f64]) -> Option<(f64, f64)> {
    match x {
        [] => None,
        [only] => Some((*only, 0.0)),
        [first, .., last] => {
            let step = (last - first) / (x.len() - 1) as f64;
            let tol = 1e-9 * (last.abs().max(first.abs()));
            x.iter().enumerate().all(|(i, v)| (v - (first + i as f64 * step)).abs() <= tol).then_some((*first, step))
        }
    }
}

/// Default SI symbol and dimension of a specific data type (records 8–11, field 1).
fn type_unit(data_type: i32) -> Option<(&'static str, Dimension)> {
    Some(match data_type {
        8 => ("m", Dimension::LENGTH),
        9 | 13 => ("N", Dimension::FORCE),
        11 => ("m/s", Dimension::VELOCITY),
        12 => ("m/s^2", Dimension::ACCELERATION),
        15 => ("Pa", Dimension::PRESSURE),
        16 => ("kg", Dimension::MASS),
        17 => ("s", Dimension::TIME),
        18 => ("Hz", Dimension::FREQUENCY),
        19 => ("rpm", Dimension::ROTATIONAL_SPEED),
        _ => return None,
    })
}

fn type_name(data_type: i32) -> Option<&'static str> {
    Some(match data_type {
        8 => "displacement",
        9 => "reaction force",
        11 => "velocity",
        12 => "acceleration",
        13 => "force",
        15 => "pressure",
        17 => "time",
        18 => "frequency",
        19 => "speed",
        _ => return None,
    })
}

/// An axis's unit in SI: the factor and the symbol. A blank or `NONE` unit label takes the
/// data type's SI unit.
fn axis_unit(axis: &Axis) -> (f64, String) {
    let label = axis.units.trim();
    let known = type_unit(axis.data_type);
    if label.is_empty() || label == "NONE" {
        return (1.0, known.map_or(String::new(), |(s, _)| s.to_string()));
    }
    unit_to_si(label, known.map(|(_, d)| d))
}

/// The factor from the abscissa's unit to SI, checking that it is of the expected dimension.
fn axis_scale(axis: &Axis, dim: Dimension, at: Loc, what: &str) -> Result<f64, FormatError> {
    let label = axis.units.trim();
    if label.is_empty() || label == "NONE" {
        return Ok(1.0);
    }
    match spindlelab_grammar::parse_unit(label) {
        Ok(u) if u.dim == dim => Ok(u.scale),
        Ok(u) => Err(FormatError::Unsupported {
            at,
            message: format!(
                "the abscissa of {what} is in `{label}` ({}); expected {}",
                u.dim.describe(),
                dim.describe()
            ),
        }),
        // A label the unit grammar does not know is taken as SI.
        Err(_) => Ok(1.0),
    }
}

/// Data characteristics written for an SI unit symbol.
fn axis_for(symbol: &str) -> Axis {
    let (data_type, label, exps) = match symbol {
        "" => (0, "NONE", (0, 0, 0)),
        "m" => (8, "Displacement", (1, 0, 0)),
        "N" => (13, "Force", (0, 1, 0)),
        "m/s" => (11, "Velocity", (1, 0, 0)),
        "m/s^2" => (12, "Acceleration", (1, 0, 0)),
        "s" => (17, "Time", (0, 0, 0)),
        "Hz" => (18, "Frequency", (0, 0, 0)),
        "rpm" => (19, "Speed", (0, 0, 0)),
        _ => (1, "NONE", (0, 0, 0)),
    };
    Axis {
        data_type,
        length_exp: exps.0,
        force_exp: exps.1,
        temperature_exp: exps.2,
        label: label.to_string(),
        units: if symbol.is_empty() { "NONE".into() } else { symbol.to_string() },
    }
}

// ---------------------------------------------------------------- reading

/// Lines and raw bytes of a file, with the number of the next line.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: usize,
    path: &'a str,
}

impl<'a> Cursor<'a> {
    fn next_line(&mut self) -> Option<(usize, &'a [u8])> {
        if self.pos >= self.bytes.len() {
            return None;
        }
        let rest = &self.bytes[self.pos..];
        let (text, advance) = match rest.iter().position(|b| *b == b'\n') {
            Some(i) => (&rest[..i], i + 1),
            None => (rest, rest.len()),
        };
        let number = self.line;
        self.pos += advance;
        self.line += 1;
        Some((number, text.strip_suffix(b"\r").unwrap_or(text)))
    }

    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let chunk = self.bytes.get(self.pos..self.pos.checked_add(n)?)?;
        self.pos += n;
        self.line += chunk.iter().filter(|b| **b == b'\n').count();
        Some(chunk)
    }

    fn loc(&self, line: usize, column: usize) -> Loc {
        Loc::new(self.path, line, column)
    }

    fn eof(&self, expected: impl Into<String>) -> FormatError {
        FormatError::Expected {
            at: self.loc(self.line, 0),
            expected: expected.into(),
            found: "the end of the file".into(),
        }
    }

    /// The next line, which must be a record of the dataset (not its end).
    fn record(&mut self, what: &str) -> Result<(usize, &'a [u8]), FormatError> {
        let (n, text) = self.next_line().ok_or_else(|| self.eof(what.to_string()))?;
        if text.trim_ascii() == b"-1" {
            return Err(FormatError::Expected {
                at: self.loc(n, 1),
                expected: what.to_string(),
                found: "`-1`, the end of the dataset".into(),
            });
        }
        Ok((n, text))
    }
}

/// Text of an ID line, entity name, axis label or unit: UTF-8 when the bytes are, else
/// Latin-1 (ISO 8859-1), which older analysers write (`(m/s²)/N` with `²` as the byte 0xB2).
fn decode_text(bytes: &[u8]) -> String {
    match std::str::from_utf8(bytes) {
        Ok(s) => s.to_string(),
        Err(_) => bytes.iter().map(|&b| char::from(b)).collect(),
    }
}

fn shown(text: &[u8]) -> String {
    let s = String::from_utf8_lossy(text);
    let s = s.trim();
    if s.is_empty() {
        "an empty line".into()
    } else if s.chars().count() > 40 {
        format!("`{}…`", s.chars().take(40).collect::<String>())
    } else {
        format!("`{s}`")
    }
}

/// Whitespace-separated tokens of a line with their 1-based columns.
fn tokens(text: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    let mut i = 0;
    std::iter::from_fn(move || {
        while i < text.len() && text[i].is_ascii_whitespace() {
            i += 1;
        }
        if i >= text.len() {
            return None;
        }
        let start = i;
        while i < text.len() && !text[i].is_ascii_whitespace() {
            i += 1;
        }
        Some((start + 1, &text[start..i]))
    })
}

/// A Fortran-written number: `1.5e-3`, `1.5E-03` or `1.5D-03`.
fn fortran_f64(token: &[u8]) -> Option<f64> {
    let s = std::str::from_utf8(token).ok()?;
    s.parse::<f64>().ok().or_else(|| s.replace(['D', 'd'], "e").parse::<f64>().ok())
}

/// One fixed-column record (records 6 and 8–11).
struct Record<'a, 'c> {
    cur: &'c Cursor<'a>,
    line: usize,
    text: &'a [u8],
    name: &'static str,
}

impl Record<'_, '_> {
    /// Columns `col..col+width` (1-based), clipped to the line.
    fn slice(&self, col: usize, width: usize) -> &[u8] {
        let start = (col - 1).min(self.text.len());
        let end = (col - 1 + width).min(self.text.len());
        &self.text[start..end]
    }

    fn int(&self, col: usize, width: usize, field: &str) -> Result<i64, FormatError> {
        let raw = self.slice(col, width).trim_ascii();
        if raw.is_empty() {
            return Ok(0);
        }
        std::str::from_utf8(raw).ok().and_then(|s| s.parse().ok()).ok_or_else(|| FormatError::Expected {
            at: self.cur.loc(self.line, col),
            expected: format!("{field} (an integer in columns {col}–{}) in {}", col + width - 1, self.name),
            found: shown(raw),
        })
    }

    fn int32(&self, col: usize, width: usize, field: &str) -> Result<i32, FormatError> {
        let v = self.int(col, width, field)?;
        i32::try_from(v).map_err(|_| FormatError::Expected {
            at: self.cur.loc(self.line, col),
            expected: format!("{field} (a small integer) in {}", self.name),
            found: format!("`{v}`"),
        })
    }

    fn text(&self, col: usize, width: usize) -> String {
        decode_text(self.slice(col, width)).trim().to_string()
    }
}

fn read_axis(cur: &Cursor, line: usize, text: &[u8], name: &'static str) -> Result<Axis, FormatError> {
    let r = Record { cur, line, text, name };
    Ok(Axis {
        data_type: r.int32(1, 10, "the specific data type")?,
        length_exp: r.int32(11, 5, "the length units exponent")?,
        force_exp: r.int32(16, 5, "the force units exponent")?,
        temperature_exp: r.int32(21, 5, "the temperature units exponent")?,
        label: r.text(27, 20),
        units: r.text(48, 20),
    })
}

/// Parses a UFF file: every dataset 58 and 58b, the others skipped and listed. A file
/// without a dataset 58 is an error that lists what it holds.
pub fn parse(bytes: &[u8], path: &str) -> Result<UffFile, FormatError> {
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Err(FormatError::Empty { at: Loc::new(path, 0, 0) });
    }
    let mut cur = Cursor { bytes, pos: 0, line: 1, path };
    let mut datasets = Vec::new();
    let mut skipped = Vec::new();
    while let Some((n, text)) = cur.next_line() {
        if text.trim_ascii().is_empty() {
            continue;
        }
        if text.trim_ascii() != b"-1" {
            return Err(FormatError::Expected {
                at: cur.loc(n, 1),
                expected: "`    -1`, the delimiter that opens a dataset".into(),
                found: shown(text),
            });
        }
        let (hl, head) = cur.next_line().ok_or_else(|| cur.eof("a dataset number after `-1`"))?;
        let Some((col, first)) = tokens(head).next() else {
            return Err(FormatError::Expected {
                at: cur.loc(hl, 1),
                expected: "a dataset number after `-1` (e.g. `58` or `58b`)".into(),
                found: shown(head),
            });
        };
        let (digits, binary) = match first.last() {
            Some(b'b' | b'B') => (&first[..first.len() - 1], true),
            _ => (first, false),
        };
        let number: u32 =
            std::str::from_utf8(digits).ok().and_then(|s| s.parse().ok()).ok_or_else(|| FormatError::Expected {
                at: cur.loc(hl, col),
                expected: "a dataset number after `-1` (e.g. `58` or `58b`)".into(),
                found: shown(first),
            })?;
        if number == 58 {
            datasets.push(parse58(&mut cur, hl, head, binary)?);
        } else {
            skip_dataset(&mut cur, hl, head, number, binary)?;
            skipped.push(Skipped { dataset: number, line: hl });
        }
    }
    if datasets.is_empty() {
        return Err(FormatError::NoSupportedDataset { path: path.to_string(), skipped });
    }
    Ok(UffFile { datasets, skipped })
}

/// Moves past a dataset that is not read: a binary one by the sizes in its header line,
/// then to its closing `-1`.
fn skip_dataset(cur: &mut Cursor, hl: usize, head: &[u8], number: u32, binary: bool) -> Result<(), FormatError> {
    if binary {
        let fields: Vec<usize> =
            tokens(head).skip(1).take(4).map_while(|(_, t)| std::str::from_utf8(t).ok()?.parse().ok()).collect();
        if let [_, _, lines, nbytes, ..] = fields[..] {
            for _ in 0..lines {
                cur.record(&format!("an ASCII header line of dataset {number}b"))?;
            }
            let available = cur.bytes.len() - cur.pos;
            cur.take(nbytes).ok_or_else(|| FormatError::Truncated {
                at: cur.loc(hl, 0),
                what: format!("dataset {number}b"),
                needed: nbytes,
                available,
            })?;
        }
    }
    loop {
        match cur.next_line() {
            Some((_, t)) if t.trim_ascii() == b"-1" => return Ok(()),
            Some(_) => {}
            None => {
                return Err(FormatError::Expected {
                    at: cur.loc(hl, 0),
                    expected: format!("`-1` closing dataset {number} opened here"),
                    found: "the end of the file".into(),
                });
            }
        }
    }
}

fn parse58(cur: &mut Cursor, hl: usize, head: &[u8], binary: bool) -> Result<Dataset58, FormatError> {
    let layout = if binary { binary_layout(cur, hl, head)? } else { BinaryLayout::default() };
    let kind = if binary { "dataset 58b" } else { "dataset 58" };

    let mut id: [String; 5] = Default::default();
    for (k, slot) in id.iter_mut().enumerate() {
        let (_, text) = cur.record(&format!("ID line {} (record {}) of {kind}", k + 1, k + 1))?;
        *slot = decode_text(text).trim().to_string();
    }

    let (l6, t6) = cur.record(&format!("record 6 (function and DOF identification) of {kind}"))?;
    let r6 = Record { cur, line: l6, text: t6, name: "record 6" };
    let function_type = r6.int32(1, 5, "the function type")?;
    let function_id = r6.int(6, 10, "the function identification number")?;
    let version = r6.int(16, 5, "the version number")?;
    let load_case = r6.int(21, 10, "the load case")?;
    let response = Dof {
        entity: r6.text(32, 10),
        node: r6.int(42, 10, "the response node")?,
        direction: r6.int32(52, 4, "the response direction")?,
    };
    let reference = Dof {
        entity: r6.text(57, 10),
        node: r6.int(67, 10, "the reference node")?,
        direction: r6.int32(77, 4, "the reference direction")?,
    };

    let form = DataForm::read(cur, kind)?;

    let mut axes: [Axis; 4] = Default::default();
    let names = [
        "record 8 (abscissa data characteristics)",
        "record 9 (ordinate numerator data characteristics)",
        "record 10 (ordinate denominator data characteristics)",
        "record 11 (Z-axis data characteristics)",
    ];
    for (axis, name) in axes.iter_mut().zip(names) {
        let (l, t) = cur.record(&format!("{name} of {kind}"))?;
        *axis = read_axis(cur, l, t, name)?;
    }

    let DataForm { ordinate_type, points, even, min, step, z_value, .. } = form;
    let per_point = usize::from(!even) + if ordinate_type.is_complex() { 2 } else { 1 };
    let needed = points.checked_mul(per_point).ok_or_else(|| FormatError::Unsupported {
        at: cur.loc(form.line, form.points_col),
        message: format!("{points} points is more than this reader can hold"),
    })?;
    let values = if binary {
        let BinaryLayout { little_endian, declared_bytes } = layout;
        read_binary(cur, hl, needed, ordinate_type, little_endian, declared_bytes, points, even)?
    } else {
        read_ascii(cur, hl, needed, points)?
    };

    let (abscissa, ys) = if even {
        (Abscissa::Even { min, step }, values)
    } else {
        let x: Vec<f64> = values.iter().step_by(per_point).copied().collect();
        let ys: Vec<f64> = values.chunks_exact(per_point).flat_map(|c| c[1..].iter().copied()).collect();
        (Abscissa::Uneven(x), ys)
    };
    let ordinate = if ordinate_type.is_complex() {
        Ordinate::Complex(ys.chunks_exact(2).map(|c| Complex64::new(c[0], c[1])).collect())
    } else {
        Ordinate::Real(ys)
    };
    let [abscissa_axis, numerator, denominator, z_axis] = axes;
    Ok(Dataset58 {
        line: hl,
        binary,
        id,
        function_type,
        function_id,
        version,
        load_case,
        response,
        reference,
        ordinate_type,
        abscissa,
        z_value,
        abscissa_axis,
        numerator,
        denominator,
        z_axis,
        ordinate,
    })
}

/// The 58b header's layout of the binary data: the byte order (flag 1 little, 2 big endian)
/// and the bytes it declares. The floating-point format must be 2 (IEEE 754); the ASCII
/// lines that follow (11) are not checked.
#[derive(Clone, Copy)]
struct BinaryLayout {
    little_endian: bool,
    declared_bytes: usize,
}

impl Default for BinaryLayout {
    fn default() -> Self {
        BinaryLayout { little_endian: true, declared_bytes: 0 }
    }
}

/// Reads the 58b header line `head` (line `hl`).
fn binary_layout(cur: &Cursor, hl: usize, head: &[u8]) -> Result<BinaryLayout, FormatError> {
    // The fields read; a line of more tokens is not gathered whole.
    let fields: Vec<(usize, &[u8])> = tokens(head).skip(1).take(8).collect();
    let field = |k: usize, what: &str| -> Result<Option<i64>, FormatError> {
        match fields.get(k) {
            None => Ok(None),
            Some((col, t)) => std::str::from_utf8(t).ok().and_then(|s| s.parse().ok()).map(Some).ok_or_else(|| {
                FormatError::Expected {
                    at: cur.loc(hl, *col),
                    expected: format!("{what} in the 58b header line"),
                    found: shown(t),
                }
            }),
        }
    };
    let col = |k: usize| fields.get(k).map_or(0, |f| f.0);
    let little_endian = match field(0, "the byte-order flag")? {
        Some(1) => true,
        Some(2) => false,
        other => {
            return Err(FormatError::Unsupported {
                at: cur.loc(hl, col(0)),
                message: format!(
                    "58b byte-order flag {}: expected 1 (little-endian) or 2 (big-endian)",
                    other.map_or("missing".to_string(), |v| v.to_string())
                ),
            });
        }
    };
    match field(1, "the floating-point format flag")? {
        Some(2) => {}
        other => {
            return Err(FormatError::Unsupported {
                at: cur.loc(hl, col(1)),
                message: format!(
                    "58b floating-point format {}: only 2 (IEEE 754) is read, not 1 (DEC VMS) or 3 (IBM 370)",
                    other.map_or("missing".to_string(), |v| v.to_string())
                ),
            });
        }
    }
    let declared_bytes = field(3, "the number of bytes")?.and_then(|v| usize::try_from(v).ok()).unwrap_or(0);
    Ok(BinaryLayout { little_endian, declared_bytes })
}

/// The fields of record 7 with their 1-based columns. Written to its format (`3I10,3E13.5`),
/// a number of points that fills its ten columns touches the field before it, so the three
/// integers are read by their columns when those hold integers; the rest, and a record
/// written free-form, by whitespace.
fn record7_fields(t7: &[u8]) -> Vec<(usize, &[u8])> {
    let fixed: Option<Vec<(usize, &[u8])>> = (t7.len() >= 30)
        .then(|| {
            (0..3)
                .map(|k| {
                    let field = &t7[10 * k..10 * k + 10];
                    let lead = field.iter().take_while(|b| **b == b' ').count();
                    let digits = field[lead..].trim_ascii_end();
                    let int =
                        std::str::from_utf8(digits).ok().is_some_and(|d| !d.is_empty() && d.parse::<i64>().is_ok());
                    int.then_some((10 * k + lead + 1, digits))
                })
                .collect()
        })
        .flatten();
    match fixed {
        Some(ints) => ints.into_iter().chain(tokens(&t7[30..]).map(|(c, t)| (c + 30, t))).take(8).collect(),
        None => tokens(t7).take(8).collect(),
    }
}

/// Record 7 (data form): the ordinate type, the number of points, an even or uneven
/// abscissa with its minimum and increment, and the Z-axis value.
#[derive(Clone, Copy)]
struct DataForm {
    ordinate_type: OrdinateType,
    points: usize,
    even: bool,
    min: f64,
    step: f64,
    z_value: f64,
    /// The record's line and the column of its number of points, for later errors.
    line: usize,
    points_col: usize,
}

impl DataForm {
    fn read(cur: &mut Cursor, kind: &str) -> Result<DataForm, FormatError> {
        let (l7, t7) = cur.record(&format!("record 7 (data form) of {kind}"))?;
        let fields7 = record7_fields(t7);
        let what7 = ["the ordinate data type", "the number of points", "the abscissa spacing (1 even, 0 uneven)"];
        let mut ints = [0i64; 3];
        for (k, slot) in ints.iter_mut().enumerate() {
            let (col, t) = fields7.get(k).copied().unwrap_or((t7.len() + 1, b""));
            *slot = std::str::from_utf8(t).ok().and_then(|s| s.parse().ok()).ok_or_else(|| FormatError::Expected {
                at: cur.loc(l7, col),
                expected: format!("{} in record 7", what7[k]),
                found: if t.is_empty() { "the end of the line".into() } else { shown(t) },
            })?;
        }
        let mut floats = [0f64; 3];
        let what7f = ["the abscissa minimum", "the abscissa increment", "the Z-axis value"];
        for (k, slot) in floats.iter_mut().enumerate() {
            if let Some((col, t)) = fields7.get(3 + k) {
                *slot = fortran_f64(t).filter(|v| v.is_finite()).ok_or_else(|| FormatError::Expected {
                    at: cur.loc(l7, *col),
                    expected: format!("{} (a finite number) in record 7", what7f[k]),
                    found: shown(t),
                })?;
            }
        }
        let ordinate_type = OrdinateType::from_code(ints[0]).ok_or_else(|| FormatError::Unsupported {
            at: cur.loc(l7, fields7[0].0),
            message: format!(
                "ordinate data type {}: expected 2 (real single), 4 (real double), 5 (complex single) or 6 (complex double)",
                ints[0]
            ),
        })?;
        let points = usize::try_from(ints[1]).ok().filter(|n| *n >= 1).ok_or_else(|| FormatError::Expected {
            at: cur.loc(l7, fields7[1].0),
            expected: "a number of points of at least 1 in record 7".into(),
            found: format!("`{}`", ints[1]),
        })?;
        let even = match ints[2] {
            1 => true,
            0 => false,
            other => {
                return Err(FormatError::Expected {
                    at: cur.loc(l7, fields7[2].0),
                    expected: "abscissa spacing 1 (even) or 0 (uneven) in record 7".into(),
                    found: format!("`{other}`"),
                });
            }
        };
        if even && fields7.len() < 5 {
            return Err(FormatError::Expected {
                at: cur.loc(l7, t7.len() + 1),
                expected: "the abscissa minimum and increment of an even abscissa in record 7".into(),
                found: "the end of the line".into(),
            });
        }
        Ok(DataForm {
            ordinate_type,
            points,
            even,
            min: floats[0],
            step: floats[1],
            z_value: floats[2],
            line: l7,
            points_col: fields7[1].0,
        })
    }
}

/// Record 12 in ASCII: `needed` numbers over as many lines as it takes, then `-1`.
fn read_ascii(cur: &mut Cursor, hl: usize, needed: usize, points: usize) -> Result<Vec<f64>, FormatError> {
    // Reserve only what the rest of the file can hold (a value takes at least two bytes),
    // never what the header claims.
    let mut values = Vec::with_capacity(needed.min((cur.bytes.len() - cur.pos) / 2 + 1));
    loop {
        let Some((n, text)) = cur.next_line() else {
            return Err(FormatError::Expected {
                at: cur.loc(cur.line, 0),
                expected: format!(
                    "{needed} data values ({points} points) and `-1` closing the dataset 58 of line {hl}"
                ),
                found: format!("the end of the file after {} values", values.len()),
            });
        };
        if text.trim_ascii() == b"-1" {
            if values.len() < needed {
                return Err(FormatError::Expected {
                    at: cur.loc(n, 1),
                    expected: format!("{needed} data values ({points} points, as record 7 says)"),
                    found: format!("`-1` after {} values", values.len()),
                });
            }
            return Ok(values);
        }
        for (col, t) in tokens(text) {
            if values.len() == needed {
                return Err(FormatError::Expected {
                    at: cur.loc(n, col),
                    expected: format!("`-1` after {needed} data values ({points} points, as record 7 says)"),
                    found: shown(t),
                });
            }
            match fortran_f64(t) {
                Some(v) if v.is_finite() => values.push(v),
                Some(_) => {
                    return Err(FormatError::NonFinite {
                        at: cur.loc(n, col),
                        text: String::from_utf8_lossy(t).into_owned(),
                        what: format!("the data of the dataset 58 of line {hl}"),
                    });
                }
                None => {
                    return Err(FormatError::Expected {
                        at: cur.loc(n, col),
                        expected: "a number (record 12, data values)".into(),
                        found: shown(t),
                    });
                }
            }
        }
    }
}

/// Record 12 in binary: IEEE values of the ordinate's precision (an uneven abscissa in the
/// same precision, before each ordinate), then `-1`. The size comes from records 7 and 8; the
/// header's byte count is used only to find the closing `-1` when the data are padded.
#[allow(clippy::too_many_arguments)]
fn read_binary(
    cur: &mut Cursor,
    hl: usize,
    needed: usize,
    ty: OrdinateType,
    little_endian: bool,
    declared_bytes: usize,
    points: usize,
    even: bool,
) -> Result<Vec<f64>, FormatError> {
    let width = if ty.is_double() { 8 } else { 4 };
    let start = cur.pos;
    let available = cur.bytes.len() - start;
    let what = format!("dataset 58b ({points} points, {}{})", ty.name(), if even { "" } else { " with abscissa" });
    // A header count the file cannot hold is a truncated file, not an overflow.
    let nbytes = needed.saturating_mul(width);
    let data = cur.take(nbytes).ok_or_else(|| FormatError::Truncated {
        at: cur.loc(hl, 0),
        what: what.clone(),
        needed: nbytes,
        available,
    })?;
    let mut values = Vec::with_capacity(needed);
    for (i, c) in data.chunks_exact(width).enumerate() {
        let v = match (width, little_endian) {
            (8, true) => f64::from_le_bytes(c.try_into().expect("8 bytes")),
            (8, false) => f64::from_be_bytes(c.try_into().expect("8 bytes")),
            (_, true) => f64::from(f32::from_le_bytes(c.try_into().expect("4 bytes"))),
            (_, false) => f64::from(f32::from_be_bytes(c.try_into().expect("4 bytes"))),
        };
        if !v.is_finite() {
            return Err(FormatError::NonFinite {
                at: cur.loc(hl, 0),
                text: v.to_string(),
                what: format!("value {} of the binary data of {what}", i + 1),
            });
        }
        values.push(v);
    }
    // The closing `-1` follows directly or after a line break.
    let closes = |cur: &mut Cursor| -> bool {
        for _ in 0..2 {
            match cur.next_line() {
                Some((_, t)) if t.trim_ascii() == b"-1" => return true,
                Some((_, t)) if t.trim_ascii().is_empty() => continue,
                _ => return false,
            }
        }
        false
    };
    let (pos, line) = (cur.pos, cur.line);
    if closes(cur) {
        return Ok(values);
    }
    if declared_bytes > nbytes && declared_bytes <= available {
        cur.pos = start;
        cur.line = line - data.iter().filter(|b| **b == b'\n').count();
        cur.take(declared_bytes);
        if closes(cur) {
            return Ok(values);
        }
    }
    let after = &cur.bytes[pos..(pos + 24).min(cur.bytes.len())];
    Err(FormatError::Expected {
        at: Loc::new(cur.path, line, 0),
        expected: format!("`-1` closing the {what} of line {hl} after {nbytes} bytes of data"),
        found: if after.is_empty() {
            "the end of the file".into()
        } else {
            format!("{} more bytes", cur.bytes.len() - pos)
        },
    })
}

// ---------------------------------------------------------------- writing

/// Appends `v` in Fortran `E` style: `decimals` digits after the point and an exponent of at
/// least two digits, right-aligned in `width` (0: no field). In a field, a three-digit
/// exponent costs a decimal, so a blank always leads the number. `scratch` is reused.
fn push_e(out: &mut String, scratch: &mut String, v: f64, width: usize, decimals: usize) {
    scratch.clear();
    let _ = write!(scratch, "{v:.decimals$e}");
    let (mantissa, exp) = scratch.split_once('e').expect("exponent");
    let (sign, digits) = match exp.strip_prefix('-') {
        Some(d) => ('-', d),
        None => ('+', exp),
    };
    let len = mantissa.len() + 2 + digits.len().max(2);
    if width > 0 && len >= width && decimals > 0 {
        let fewer = decimals.saturating_sub(len + 1 - width);
        return push_e(out, scratch, v, width, fewer);
    }
    for _ in len..width {
        out.push(' ');
    }
    out.push_str(mantissa);
    out.push('e');
    out.push(sign);
    if digits.len() < 2 {
        out.push('0');
    }
    out.push_str(digits);
}

fn fortran_e(v: f64, decimals: usize) -> String {
    let mut out = String::new();
    push_e(&mut out, &mut String::new(), v, 0, decimals);
    out
}

/// An E13.5 field. A positive value that needs a 7th digit gets it (`E13.6` still leaves a
/// blank before the number), so binary-friendly steps such as 1/102400 s are kept exactly.
fn e13(v: f64) -> String {
    let mut five = String::new();
    push_e(&mut five, &mut String::new(), v, 13, 5);
    if v <= 0.0 || five.trim().parse::<f64>().ok() == Some(v) {
        return five;
    }
    let six = fortran_e(v, 6);
    if six.len() <= 12 { format!("{six:>13}") } else { five }
}

#[cfg(test)]
fn e20(v: f64) -> String {
    let mut out = String::new();
    push_e(&mut out, &mut String::new(), v, 20, 12);
    out
}

fn clip(s: &str, n: usize) -> String {
    s.chars().take(n).collect()
}

fn id_line(s: &str) -> String {
    if s.trim().is_empty() { "NONE".into() } else { clip(s.trim(), 80) }
}

fn axis_record(out: &mut String, a: &Axis) {
    let _ = writeln!(
        out,
        "{:>10}{:>5}{:>5}{:>5} {:<20} {:<20}",
        a.data_type,
        a.length_exp,
        a.force_exp,
        a.temperature_exp,
        clip(if a.label.is_empty() { "NONE" } else { &a.label }, 20),
        clip(if a.units.is_empty() { "NONE" } else { &a.units }, 20)
    );
}

/// Writes a dataset 58 in ASCII with the record layout of the format: ID lines, record 6
/// `2(I5,I10),2(1X,10A1,I10,I4)`, record 7 `3I10,3E13.5`, records 8–11
/// `I10,3I5,2(1X,20A1)`, and data as E13.5 (single precision, abscissa) and E20.12 (double).
pub fn write_dataset(out: &mut String, d: &Dataset58) {
    let _ = writeln!(out, "{:>6}\n{:>6}", -1, 58);
    for l in &d.id {
        let _ = writeln!(out, "{}", id_line(l));
    }
    let _ = writeln!(
        out,
        "{:>5}{:>10}{:>5}{:>10} {:>10}{:>10}{:>4} {:>10}{:>10}{:>4}",
        d.function_type,
        d.function_id,
        d.version,
        d.load_case,
        clip(&d.response.entity, 10),
        d.response.node,
        d.response.direction,
        clip(&d.reference.entity, 10),
        d.reference.node,
        d.reference.direction
    );
    let (even, min, step) = match &d.abscissa {
        Abscissa::Even { min, step } => (true, *min, *step),
        Abscissa::Uneven(_) => (false, 0.0, 0.0),
    };
    let _ = writeln!(
        out,
        "{:>10}{:>10}{:>10}{}{}{}",
        d.ordinate_type as i32,
        d.len(),
        i32::from(even),
        e13(min),
        e13(step),
        e13(d.z_value)
    );
    for a in [&d.abscissa_axis, &d.numerator, &d.denominator, &d.z_axis] {
        axis_record(out, a);
    }
    let double = d.ordinate_type.is_double();
    let complex = d.ordinate_type.is_complex();
    let per_line = match (double, even, complex) {
        (false, _, _) => 6,
        (true, true, _) => 4,
        (true, false, false) => 4,
        (true, false, true) => 3,
    };
    let mut scratch = String::new();
    let mut on_line = 0;
    // One field of record 12: an abscissa (E13.5) or an ordinate (E20.12 double, E13.5 single).
    let mut field = |out: &mut String, v: f64, abscissa: bool| {
        if abscissa {
            out.push_str(&e13(v));
        } else if double {
            push_e(out, &mut scratch, v, 20, 12);
        } else {
            push_e(out, &mut scratch, v, 13, 5);
        }
        on_line += 1;
        if on_line == per_line {
            out.push('\n');
            on_line = 0;
        }
    };
    for i in 0..d.len() {
        if let Abscissa::Uneven(x) = &d.abscissa {
            field(out, x[i], true);
        }
        match &d.ordinate {
            Ordinate::Real(v) => field(out, v[i], false),
            Ordinate::Complex(v) => {
                field(out, v[i].re, false);
                field(out, v[i].im, false);
            }
        }
    }
    if on_line > 0 {
        out.push('\n');
    }
    let _ = writeln!(out, "{:>6}", -1);
}

/// Writes an FRF as one dataset 58 (complex double); `label` goes to ID line 2.
pub fn write_frf(out: &mut String, frf: &Frf, label: &str) {
    write_dataset(out, &Dataset58::from_frf(frf, label));
}

/// Writes a time series as one dataset 58 per channel (real double, even abscissa);
/// `label` goes to ID line 2.
pub fn write_time_series(out: &mut String, ts: &TimeSeries, label: &str) {
    for c in &ts.channels {
        write_dataset(out, &Dataset58::from_channel(ts, c, label));
    }
}

/// The blocks of a receptance set in file order: name, response and reference are rotations,
/// and the unit written (numerator/denominator).
const RECEPTANCE_BLOCKS: [(&str, bool, bool, &str); 4] = [
    ("H", false, false, "m/N"),
    ("L", false, true, "m/N*m"),
    ("N", true, false, "rad/N"),
    ("P", true, true, "rad/N*m"),
];

/// Record 6 direction codes of bending in direction `x` or `y` (the spindle axis is z):
/// translation, and the rotation `θ = d(displacement)/dz` as a signed rotation code. In the
/// x–z plane `θ = θ_y` (code 5); in the y–z plane `θ = −θ_x` (code −4). A set without a
/// direction is written as `x`.
pub fn receptance_codes(direction: Option<&str>) -> (i32, i32) {
    if direction == Some("y") { (2, -4) } else { (1, 5) }
}

/// A record 6 direction code as a receptance coordinate: the bending direction, whether it
/// is the rotation, and the sign that turns a value on the positive axis into the `θ` sense.
fn receptance_dof(code: i32) -> Option<(&'static str, bool, f64)> {
    match code.abs() {
        1 => Some(("x", false, 1.0)),
        2 => Some(("y", false, 1.0)),
        5 => Some(("x", true, 1.0)),
        4 => Some(("y", true, -1.0)),
        _ => None,
    }
}

/// Writes a 2×2 receptance set as four datasets 58 (FRF, complex double), H, L, N, P, told
/// apart by their record 6 direction codes (see [`receptance_codes`]); `label` goes to ID line 2.
pub fn write_receptance(out: &mut String, r: &ReceptanceSet, label: &str) {
    let (t, rot) = receptance_codes(r.direction.as_deref());
    let dir = r.direction.as_deref().unwrap_or("x");
    for ((name, resp_rot, ref_rot, unit), values) in RECEPTANCE_BLOCKS.iter().zip([&r.h, &r.l, &r.n, &r.p]) {
        let frf = Frf {
            freq_hz: r.freq_hz.clone(),
            values: values.clone(),
            coherence: None,
            unit: UnitLabel::new(*unit),
            direction: Some(dir.to_string()),
            speed: r.speed,
            sensor: None,
            dofs: None,
        };
        let mut d = Dataset58::from_frf(&frf, label);
        d.id[0] = format!("receptance {name} {dir}");
        d.response.direction = if *resp_rot { rot } else { t };
        d.reference.direction = if *ref_rot { rot } else { t };
        write_dataset(out, &d);
    }
}

/// The 2×2 receptance set of a file: its FRF datasets whose response and reference codes are
/// a translation or bending rotation of the same direction (see [`receptance_codes`]), one per
/// block. `direction` picks one when the file holds several. Values are turned to the `θ`
/// sense of the project whatever the signs of the codes. Returns notes on datasets passed over.
pub fn to_receptance(
    file: &UffFile,
    path: &str,
    direction: Option<&str>,
) -> Result<(ReceptanceSet, Vec<String>), FormatError> {
    let mut notes = super::Notes::new(path);
    // Per direction found: the dataset of each block.
    let mut found: Vec<(&str, [Option<&Dataset58>; 4])> = Vec::new();
    for ds in &file.datasets {
        let dofs = (receptance_dof(ds.response.direction), receptance_dof(ds.reference.direction));
        let (Some((dir, resp_rot, _)), Some((dir2, ref_rot, _))) = dofs else {
            notes.push(|| {
                format!(
                    "{path}: dataset 58 at line {} ({}) is not a bending receptance; skipped",
                    ds.line,
                    ds.describe()
                )
            });
            continue;
        };
        if ds.function_type != FUNCTION_FRF || dir != dir2 {
            notes.push(|| {
                format!(
                    "{path}: dataset 58 at line {} ({}) is not a bending receptance; skipped",
                    ds.line,
                    ds.describe()
                )
            });
            continue;
        }
        if direction.is_some_and(|d| d != dir) {
            continue;
        }
        let k = 2 * usize::from(resp_rot) + usize::from(ref_rot);
        let slot = match found.iter().position(|(d, _)| *d == dir) {
            Some(i) => i,
            None => {
                found.push((dir, [None; 4]));
                found.len() - 1
            }
        };
        if let Some(first) = found[slot].1[k] {
            return Err(FormatError::Selection {
                path: path.to_string(),
                message: format!(
                    "two {} datasets for direction `{dir}` (lines {} and {}); keep one",
                    RECEPTANCE_BLOCKS[k].0, first.line, ds.line
                ),
            });
        }
        found[slot].1[k] = Some(ds);
    }
    let (dir, blocks) = match found.as_slice() {
        [one] => one,
        [] => {
            return Err(FormatError::Selection {
                path: path.to_string(),
                message: match direction {
                    Some(d) => format!("no receptance datasets in direction `{d}` among: {}", file.summary()),
                    None => format!(
                        "no receptance datasets (FRFs between translation and rotation codes) among: {}",
                        file.summary()
                    ),
                },
            });
        }
        many => {
            let dirs: Vec<&str> = many.iter().map(|(d, _)| *d).collect();
            return Err(FormatError::Selection {
                path: path.to_string(),
                message: format!("receptances in directions {}; choose one with `direction`", dirs.join(", ")),
            });
        }
    };
    let mut values: Vec<Vec<Complex64>> = Vec::with_capacity(4);
    let mut grid: Option<(Vec<f64>, usize)> = None;
    let mut speed = None;
    for (k, ds) in blocks.iter().enumerate() {
        let Some(ds) = ds else {
            return Err(FormatError::Selection {
                path: path.to_string(),
                message: format!(
                    "direction `{dir}` has no {} dataset (response code {}, reference code {}); a receptance set needs H, L, N and P",
                    RECEPTANCE_BLOCKS[k].0,
                    code_of(dir, RECEPTANCE_BLOCKS[k].1),
                    code_of(dir, RECEPTANCE_BLOCKS[k].2)
                ),
            });
        };
        let frf = ds.to_frf(path)?;
        let sign = receptance_dof(ds.response.direction).map_or(1.0, |d| d.2)
            * receptance_dof(ds.reference.direction).map_or(1.0, |d| d.2);
        match &grid {
            None => grid = Some((frf.freq_hz.clone(), ds.line)),
            Some((g, line)) if *g != frf.freq_hz => {
                return Err(FormatError::ChannelMismatch {
                    at: ds.at(path),
                    message: format!(
                        "the {} dataset's {} frequency lines differ from those of the dataset at line {line} ({} lines)",
                        RECEPTANCE_BLOCKS[k].0,
                        frf.freq_hz.len(),
                        g.len()
                    ),
                });
            }
            Some(_) => {}
        }
        speed = speed.or(frf.speed);
        values.push(frf.values.into_iter().map(|v| v * sign).collect());
    }
    let freq_hz = grid.map(|g| g.0).unwrap_or_default();
    let mut it = values.into_iter();
    let mut next = || it.next().unwrap_or_default();
    let (h, l, n, p) = (next(), next(), next(), next());
    Ok((ReceptanceSet { freq_hz, h, l, n, p, direction: Some(dir.to_string()), speed }, notes.finish()))
}

/// The code written for a translation or rotation of direction `dir`.
fn code_of(dir: &str, rotation: bool) -> i32 {
    let (t, r) = receptance_codes(Some(dir));
    if rotation { r } else { t }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_of_100k_skipped_datasets_is_refused_in_one_short_line() {
        let text = "    -1\n    15\n    1 0 0 0\n    -1\n".repeat(100_000);
        let e = parse(text.as_bytes(), "big.uff").unwrap_err().to_string();
        assert!(e.starts_with("big.uff: no dataset 58 or 58b"), "{e}");
        assert!(e.contains("… and 99992 more") && e.len() < 400 && !e.contains('\n'), "{} characters", e.len());
        // A 58b header line of a million tokens is read no further than its fields.
        let head = format!("    -1\n    58b 1 2 11 64 {}\n", "0 ".repeat(1_000_000));
        assert!(parse(head.as_bytes(), "b.uff").is_err());
    }

    #[test]
    fn receptance_set_round_trips_through_four_datasets() {
        for dir in ["x", "y"] {
            let mut r = crate::formats::csv::tests::receptance_set();
            r.direction = Some(dir.into());
            // Record 7 holds the speed (Z value) to 6–7 digits.
            r.speed = Some(Speed::from_rpm(12_000.0));
            r.freq_hz = (1..=r.h.len()).map(|i| i as f64 * 12.5).collect();
            let mut text = String::new();
            write_receptance(&mut text, &r, "speed=3000 rpm");
            let file = parse(text.as_bytes(), "r.uff").unwrap();
            assert_eq!(file.datasets.len(), 4);
            let codes: Vec<(i32, i32)> =
                file.datasets.iter().map(|d| (d.response.direction, d.reference.direction)).collect();
            let (t, q) = receptance_codes(Some(dir));
            assert_eq!(codes, [(t, t), (t, q), (q, t), (q, q)]);
            let (back, notes) = to_receptance(&file, "r.uff", None).unwrap();
            assert!(notes.is_empty(), "{notes:?}");
            assert_eq!(
                (&back.freq_hz, &back.direction, back.speed.map(Speed::rpm_as_written)),
                (&r.freq_hz, &r.direction, r.speed.map(Speed::rpm_as_written))
            );
            for (got, want) in [(&back.h, &r.h), (&back.l, &r.l), (&back.n, &r.n), (&back.p, &r.p)] {
                for (a, b) in got.iter().zip(want.iter()) {
                    assert!((a - b).norm() <= 1e-12 * b.norm(), "{dir}: {a} vs {b}");
                }
            }
        }
    }

    #[test]
    fn receptance_files_missing_a_block_or_ambiguous_are_refused() {
        let mut r = crate::formats::csv::tests::receptance_set();
        r.freq_hz = (1..=r.h.len()).map(|i| i as f64 * 10.0).collect();
        let mut text = String::new();
        write_receptance(&mut text, &r, "");
        // Drop the last dataset (P).
        let cut = text[..text.len() - 8].rfind("    -1\n    58\n").unwrap();
        let file = parse(&text.as_bytes()[..cut], "r.uff").unwrap();
        let e = to_receptance(&file, "r.uff", None).unwrap_err().to_string();
        assert!(e.contains("no P dataset") && e.contains("response code -4"), "{e}");
        let mut both = text.clone();
        write_receptance(&mut both, &ReceptanceSet { direction: Some("x".into()), ..r.clone() }, "");
        let file = parse(both.as_bytes(), "r.uff").unwrap();
        let e = to_receptance(&file, "r.uff", None).unwrap_err().to_string();
        assert!(e.contains("directions y, x") && e.contains("`direction`"), "{e}");
        let (x, _) = to_receptance(&file, "r.uff", Some("x")).unwrap();
        assert_eq!(x.direction.as_deref(), Some("x"));
    }

    fn frf() -> Frf {
        let n = 257;
        Frf {
            freq_hz: (0..n).map(|i| i as f64 * 100_000.0 / 4096.0).collect(),
            values: (0..n)
                .map(|i| {
                    let w = i as f64 / 40.0;
                    Complex64::new(1.0, 0.0) / Complex64::new(1e7 * (1.0 - w * w), 1e6 * w) * (1.0 + 1.0 / 3.0)
                })
                .collect(),
            coherence: None,
            unit: UnitLabel::new("m/N"),
            direction: Some("y".into()),
            speed: Some(Speed::from_rpm(12_000.0)),
            sensor: Some("laser".into()),
            dofs: Some(FrfDofs { response_node: 3, response_direction: 2, reference_node: 1, reference_direction: 2 }),
        }
    }

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * a.abs().max(b.abs()) || a == b
    }

    #[test]
    fn latin1_unit_labels_are_read_and_scaled() {
        // An accelerance in (mm/s²)/N as an analyser writing Latin-1 labels it: `²` is the byte 0xB2.
        let f = Frf { unit: UnitLabel::new("m/s^2/N"), ..frf() };
        let mut text = String::new();
        write_frf(&mut text, &f, "");
        let written = format!("{:<20}", "m/s^2");
        assert!(text.contains(&written), "{text}");
        let mut bytes = text.replacen(&written, &format!("{:<20}", "(mm/s@)"), 1).into_bytes();
        let at = bytes.iter().position(|&b| b == b'@').unwrap();
        bytes[at] = 0xB2;
        let file = parse(&bytes, "latin1.uff").unwrap();
        assert_eq!(file.datasets[0].numerator.units, "(mm/s²)");
        let back = file.datasets[0].to_frf("latin1.uff").unwrap();
        assert_eq!(back.unit.symbol, "m/s^2/N");
        for (a, b) in back.values.iter().zip(&f.values) {
            assert!((a - b * 1e-3).norm() <= 1e-12 * b.norm(), "{a} {b}");
        }
        assert_eq!(back.dofs, f.dofs);
    }

    #[test]
    fn record_7_is_read_by_its_columns_when_a_field_fills_them() {
        let full = b"         61234567890         1  0.00000E+00  1.00000E+00  0.00000E+00";
        let f = record7_fields(full);
        let texts: Vec<&[u8]> = f.iter().map(|(_, t)| *t).collect();
        assert_eq!(texts, [&b"6"[..], b"1234567890", b"1", b"0.00000E+00", b"1.00000E+00", b"0.00000E+00"]);
        assert_eq!(f.iter().map(|(c, _)| *c).collect::<Vec<_>>(), [10, 11, 30, 33, 46, 59]);
        // Free-form, as some writers leave it: by whitespace.
        let free = b"6 4096 1 0.0 2.5 0.0";
        let texts: Vec<&[u8]> = record7_fields(free).iter().map(|(_, t)| *t).collect();
        assert_eq!(texts, [&b"6"[..], b"4096", b"1", b"0.0", b"2.5", b"0.0"]);
    }

    #[test]
    fn frf_round_trips_through_ascii_58() {
        let f = frf();
        let mut text = String::new();
        write_frf(&mut text, &f, "hammer_mass=0.03 kg");
        let file = parse(text.as_bytes(), "f.uff").unwrap();
        assert_eq!(file.datasets.len(), 1);
        let d = &file.datasets[0];
        assert_eq!((d.function_type, d.response.direction, d.ordinate_type), (4, 2, OrdinateType::ComplexDouble));
        assert!(matches!(d.abscissa, Abscissa::Even { .. }));
        assert_eq!(d.id[1], "hammer_mass=0.03 kg");
        let back = d.to_frf("f.uff").unwrap();
        assert_eq!(back.unit, f.unit);
        assert_eq!(
            (back.direction.as_deref(), back.speed.map(Speed::rpm_as_written), back.sensor.as_deref()),
            (Some("y"), Some(12_000.0), Some("laser"))
        );
        assert_eq!(back.values.len(), f.values.len());
        for (a, b) in back.values.iter().zip(&f.values) {
            assert!(close(a.re, b.re, 1e-12) && close(a.im, b.im, 1e-12), "{a} vs {b}");
        }
        // 100000/4096 Hz needs 9 digits; the increment field holds 7.
        for (a, b) in back.freq_hz.iter().zip(&f.freq_hz) {
            assert!((a - b).abs() <= 5e-7 * b.max(1.0), "{a} vs {b}");
        }
    }

    #[test]
    fn time_series_round_trips_through_ascii_58_one_dataset_per_channel() {
        let ts = TimeSeries {
            sample_rate: 102_400.0,
            t0: -0.001,
            channels: vec![
                Channel {
                    name: "force".into(),
                    unit: UnitLabel::new("N"),
                    samples: vec![0.0, 1.0 / 3.0, -2e-300, 4e5],
                },
                Channel {
                    name: "response".into(),
                    unit: UnitLabel::new("m"),
                    samples: vec![1e-9, -2.0 / 7.0, 0.0, 1.5],
                },
            ],
        };
        let mut text = String::new();
        write_time_series(&mut text, &ts, "");
        let file = parse(text.as_bytes(), "t.uff").unwrap();
        assert_eq!(file.datasets.len(), 2);
        for (d, c) in file.datasets.iter().zip(&ts.channels) {
            let back = d.to_time_series("t.uff").unwrap();
            assert_eq!(back.sample_rate, ts.sample_rate);
            assert_eq!(back.t0, ts.t0);
            assert_eq!(back.channels[0].name, c.name);
            assert_eq!(back.channels[0].unit, c.unit);
            for (a, b) in back.channels[0].samples.iter().zip(&c.samples) {
                assert!(close(*a, *b, 1e-12), "{a} vs {b}");
            }
        }
    }

    #[test]
    fn every_ascii_layout_reads_back() {
        // Real and complex, single and double, even and uneven: the writer's line layouts
        // (6E13.5, 4E20.12, 2(E13.5,E20.12), E13.5 2E20.12) all read back.
        let x: Vec<f64> = vec![0.0, 0.5, 1.25, 2.0, 4.0, 8.0, 8.5];
        let re: Vec<f64> = x.iter().map(|v| v * 3.0 - 1.0).collect();
        for ty in [
            OrdinateType::RealSingle,
            OrdinateType::RealDouble,
            OrdinateType::ComplexSingle,
            OrdinateType::ComplexDouble,
        ] {
            for even in [true, false] {
                let mut d = Dataset58::from_frf(&frf(), "");
                d.ordinate_type = ty;
                d.abscissa = if even { Abscissa::Even { min: 1.0, step: 0.25 } } else { Abscissa::Uneven(x.clone()) };
                d.ordinate = if ty.is_complex() {
                    Ordinate::Complex(re.iter().map(|r| Complex64::new(*r, -r / 2.0)).collect())
                } else {
                    Ordinate::Real(re.clone())
                };
                let mut text = String::new();
                write_dataset(&mut text, &d);
                let back = parse(text.as_bytes(), "a.uff").unwrap().datasets.remove(0);
                assert_eq!(back.ordinate, d.ordinate, "{ty:?} even={even}\n{text}");
                assert_eq!(back.abscissa, d.abscissa, "{ty:?} even={even}");
            }
        }
    }

    #[test]
    fn binary_58b_reads_both_byte_orders_and_single_precision() {
        let head = |order: u8, nbytes: usize| {
            [
                "    -1".to_string(),
                format!("    58b{order:>6}     2          11{nbytes:>12}     0     0           0           0"),
                "time".into(),
                "NONE".into(),
                "NONE".into(),
                "NONE".into(),
                "NONE".into(),
                "    1         0    0         0       NONE         1   3       NONE         0   0".into(),
                format!("{:>10}{:>10}{:>10}{}{}{}", 2, 3, 1, e13(0.0), e13(0.5), e13(0.0)),
                "        17    0    0    0 Time                 ms                  ".into(),
                "        13    0    1    0 Force                kN                  ".into(),
                "         0    0    0    0 NONE                 NONE                ".into(),
                "         0    0    0    0 NONE                 NONE                ".into(),
            ]
            .join("\n")
                + "\n"
        };
        let vals = [1.5f32, -2.25, 1e-3];
        for order in [1u8, 2] {
            let mut bytes = head(order, 12).into_bytes();
            for v in vals {
                bytes.extend(if order == 1 { v.to_le_bytes() } else { v.to_be_bytes() });
            }
            bytes.extend(b"\n    -1\n");
            let d = parse(&bytes, "b.uff").unwrap().datasets.remove(0);
            assert!(d.binary);
            assert_eq!(d.ordinate, Ordinate::Real(vals.iter().map(|v| f64::from(*v)).collect()));
            let ts = d.to_time_series("b.uff").unwrap();
            // 0.5 ms steps; kN to N.
            assert_eq!(ts.sample_rate, 2000.0);
            assert_eq!(ts.channels[0].samples[0], 1500.0);
            assert_eq!(ts.channels[0].unit.symbol, "N");
            // Truncated: one value short.
            let mut short = head(order, 12).into_bytes();
            short.extend(&bytes[bytes.len() - 8 - 8..bytes.len() - 8]);
            let e = parse(&short, "b.uff").unwrap_err();
            assert!(matches!(e, FormatError::Truncated { needed: 12, available: 8, .. }), "{e}");
            assert_eq!(e.line_column().0, 2);
        }
    }

    #[test]
    fn other_datasets_are_skipped_and_listed() {
        let mut text = String::from("    -1\n    15\n         1         0         0         0  0.0 0.0 0.0\n    -1\n");
        text.push_str("    -1\n   164\n         1SI - mks (Newton)  2\n  1.0  1.0  1.0\n  273.15\n    -1\n");
        write_frf(&mut text, &frf(), "");
        let file = parse(text.as_bytes(), "s.uff").unwrap();
        assert_eq!(file.skipped, [Skipped { dataset: 15, line: 2 }, Skipped { dataset: 164, line: 6 }]);
        assert_eq!(file.datasets[0].line, 12);
        let only = "    -1\n    15\n         1         0         0         0  0.0 0.0 0.0\n    -1\n";
        let e = parse(only.as_bytes(), "s.uff").unwrap_err();
        assert!(matches!(e, FormatError::NoSupportedDataset { .. }), "{e}");
        assert!(e.to_string().contains("dataset 15 at line 2"), "{e}");
    }

    #[test]
    fn broken_datasets_name_line_and_column() {
        let mut good = String::new();
        write_frf(&mut good, &frf(), "");
        let lines: Vec<&str> = good.lines().collect();
        let with = |k: usize, line: &str| {
            let mut l = lines.clone();
            l[k] = line;
            l.join("\n") + "\n"
        };
        // Record 7 with an unknown ordinate type, at its column.
        let e =
            parse(with(8, "         3       257         1  0.00000e+00  1.00000e+00  0.00000e+00").as_bytes(), "e.uff")
                .unwrap_err();
        assert!(matches!(e, FormatError::Unsupported { .. }), "{e}");
        assert_eq!(e.line_column(), (9, 10));
        // Record 6 with text in the function type.
        let e = parse(
            with(7, "    x         0    0         0       NONE         1   2       NONE         1   2").as_bytes(),
            "e.uff",
        )
        .unwrap_err();
        assert_eq!(e.line_column(), (8, 1));
        assert!(e.to_string().contains("function type"), "{e}");
        // A bad number in the data.
        let bad = lines[14].replacen("e", "x", 1);
        let e = parse(with(14, &bad).as_bytes(), "e.uff").unwrap_err();
        assert_eq!(e.line_column().0, 15);
        assert!(matches!(e, FormatError::Expected { .. }), "{e}");
        // NaN in the data.
        let nan = format!("{:>20}{}", "NaN", &lines[14][20..]);
        let e = parse(with(14, &nan).as_bytes(), "e.uff").unwrap_err();
        assert!(matches!(e, FormatError::NonFinite { .. }), "{e}");
        assert_eq!(e.line_column(), (15, 18));
        // The data stop short.
        let short = lines[..lines.len() - 3].join("\n") + "\n    -1\n";
        let e = parse(short.as_bytes(), "e.uff").unwrap_err();
        assert!(e.to_string().contains("data values"), "{e}");
        // No closing delimiter.
        let open = lines[..lines.len() - 1].join("\n");
        assert!(parse(open.as_bytes(), "e.uff").is_err());
        // Garbage before the first dataset.
        let e = parse(b"hello\n", "e.uff").unwrap_err();
        assert_eq!(e.line_column(), (1, 1));
        assert!(matches!(parse(b"\n\n", "e.uff"), Err(FormatError::Empty { .. })));
    }

    #[test]
    fn negative_direction_codes_turn_values_to_the_positive_axis() {
        let f = frf();
        let mut d = Dataset58::from_frf(&f, "");
        d.response.direction = -2;
        let back = d.to_frf("n.uff").unwrap();
        assert_eq!(back.direction.as_deref(), Some("y"));
        assert_eq!(back.values[3], -f.values[3]);
        d.reference.direction = -2;
        assert_eq!(d.to_frf("n.uff").unwrap().values[3], f.values[3]);
    }

    #[test]
    fn fortran_fields_have_the_published_widths() {
        assert_eq!(e13(1e-5), "  1.00000e-05");
        assert_eq!(e13(-0.001), " -1.00000e-03");
        assert_eq!(e13(1.0 / 102_400.0), " 9.765625e-06");
        assert_eq!(e20(-1.0 / 3.0), " -3.333333333333e-01");
        assert_eq!(e20(-2e-300), " -2.00000000000e-300");
        assert_eq!(e13(-1e-300), " -1.0000e-300");
        assert_eq!(fortran_f64(b"1.5D+02"), Some(150.0));
    }
}
