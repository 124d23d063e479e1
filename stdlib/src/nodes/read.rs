//! `read.time_series`, `read.frf` and `read.receptance`: measured data from CSV or UFF (dataset
//! 58/58b) files.
//!
//! The file is a parameter: the recipe names it relative to its own folder, and its
//! contents are hashed into the cache key, so editing the data reruns what depends on it.

use spindlelab_domain::Speed;
use spindlelab_engine::formats::{self, FileFormat, FormatError, FrfSelect};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::spec::{Field, FieldType as T, Params};
use spindlelab_engine::value::{PortType, UnitLabel, Value};
use spindlelab_grammar::Dimension as D;
use std::path::Path;

const FORMATS: &[&str] = &["auto", "csv", "uff"];

pub(super) fn file_param() -> Field {
    Field::req("file", T::File, "the data file, relative to the recipe's folder")
}

pub(super) fn format_param() -> Field {
    Field::def(
        "format",
        T::Choice(FORMATS),
        "auto",
        "file layout; `auto` goes by the extension (`.csv`, `.uff`/`.unv`), else by the contents",
    )
}

fn dataset_param(what: &str) -> Field {
    let doc: &'static str = match what {
        "frf" => {
            "which FRF to read, counting from 1: a dataset 58 of a UFF file, or a sweep point of a CSV file a swept output wrote"
        }
        _ => {
            "UFF only: which dataset 58 of the file to read, counting from 1; without it every time response becomes a channel"
        }
    };
    Field::opt("dataset", T::Integer { min: 1, max: 1_000_000 }, doc)
}

/// The file and its layout, as the parameters give them.
fn source(params: &Params, frfs: bool) -> Result<(&Path, FileFormat), NodeError> {
    let path = params.file("file").ok_or_else(|| NodeError::param("file", "missing"))?;
    let format = match params.text("format") {
        Some("csv") => FileFormat::Csv,
        Some("uff") => FileFormat::Uff,
        _ => FileFormat::detect(path).map_err(read_error)?,
    };
    // A CSV file holds one time series or receptance set; a swept FRF file holds sweep points.
    if format == FileFormat::Csv && params.int("dataset").is_some() && !frfs {
        return Err(NodeError::param("dataset", format!("applies to UFF files; {} is CSV", path.display())));
    }
    Ok((path, format))
}

pub(super) fn read_error(e: FormatError) -> NodeError {
    NodeError::param("file", e.to_string())
}

fn dataset(params: &Params) -> Option<usize> {
    params.int("dataset").and_then(|k| usize::try_from(k).ok())
}

/// `read.time_series`: a time series from a CSV or UFF file.
pub struct ReadTimeSeries {
    spec: NodeSpec,
}

impl Default for ReadTimeSeries {
    fn default() -> Self {
        Self::new()
    }
}

impl ReadTimeSeries {
    pub fn new() -> Self {
        ReadTimeSeries {
            spec: NodeSpec {
                kind: "read.time_series",
                version: 1,
                description: "Reads a time series from a CSV file (as outputs write it) or from UFF dataset 58/58b time responses; units to SI.",
                inputs: vec![],
                outputs: vec![PortSpec::new("series", PortType::TimeSeries, "the channels of the file, in SI units")],
                params: vec![file_param(), format_param(), dataset_param("time")],
            },
        }
    }
}

impl Node for ReadTimeSeries {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let (path, format) = source(ctx.params, false)?;
        let loaded = formats::read_time_series(path, format, dataset(ctx.params)).map_err(read_error)?;
        for note in loaded.notes {
            ctx.warn(note);
        }
        Ok([("series".to_string(), Value::TimeSeries(loaded.value))].into_iter().collect())
    }

    /// Raw records are large and as quick to read again from the file as from the cache.
    fn cacheable(&self) -> bool {
        false
    }
}

/// The kind that reads one measured FRF file; measurement sets expand into it.
pub const READ_FRF: &str = "read.frf";

/// `read.frf`: an FRF from a CSV or UFF file.
pub struct ReadFrf {
    spec: NodeSpec,
}

impl Default for ReadFrf {
    fn default() -> Self {
        Self::new()
    }
}

impl ReadFrf {
    pub fn new() -> Self {
        ReadFrf {
            spec: NodeSpec {
                kind: READ_FRF,
                version: 3,
                description: "Reads an FRF from a CSV file (`freq_hz,real,imag[,coherence]`) or a UFF dataset 58/58b (function type 4), with its response and reference nodes and directions; units to SI. Sweep `dataset`, `response` or `reference` to read a measurement set.",
                inputs: vec![],
                outputs: vec![PortSpec::new("frf", PortType::Frf, "the FRF, frequencies in Hz, values in SI units")],
                params: vec![
                    file_param(),
                    format_param(),
                    dataset_param("frf"),
                    Field::opt(
                        "direction",
                        T::Choice(&["x", "y", "z"]),
                        "UFF: take the FRF whose response is in this direction; CSV: the direction of a file without `# direction`",
                    ),
                    Field::opt(
                        "response",
                        T::Integer { min: 0, max: i64::MAX },
                        "take the FRF whose response node number is this (UFF record 6; CSV `# response:`)",
                    ),
                    Field::opt(
                        "reference",
                        T::Integer { min: 0, max: i64::MAX },
                        "take the FRF whose reference (excitation) node number is this",
                    ),
                    Field::opt(
                        "speed",
                        T::Quantity(D::ROTATIONAL_SPEED),
                        "the spindle speed of the measurement: fills a file without one, and must agree with a file that states it",
                    ),
                    Field::opt(
                        "units",
                        T::Text,
                        "the unit of the file's values (`m/N`, `um/N`, `m/s^2/N`): a file without `# units:` is read in it, one whose units are of another kind is refused",
                    ),
                ],
            },
        }
    }
}

impl Node for ReadFrf {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        if let Some(u) = p.text("units") {
            formats::frf_unit(u).map_err(|why| {
                NodeError::param("units", format!("{why}; the values of an FRF are {}", formats::FRF_UNIT_EXPECTED))
            })?;
        }
        super::non_negative(p, &["speed"])
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let (path, format) = source(ctx.params, true)?;
        let select = FrfSelect {
            dataset: dataset(ctx.params),
            direction: ctx.params.text("direction").map(str::to_string),
            response: ctx.params.int("response"),
            reference: ctx.params.int("reference"),
        };
        let loaded = formats::read_frf(path, format, &select).map_err(read_error)?;
        for note in loaded.notes {
            ctx.warn(note);
        }
        let mut frf = loaded.value;
        let shown = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
        if let Some(w) = ctx.params.f64("speed") {
            let rpm = Speed::from_rad_s(w).rpm();
            match frf.speed_rpm {
                Some(s) if (s - rpm).abs() > 1e-6 * rpm.abs().max(1.0) => {
                    return Err(NodeError::param(
                        "speed",
                        format!("{shown} was measured at {s} rpm (its `# speed_rpm`), the recipe says {rpm} rpm"),
                    ));
                }
                Some(_) => {}
                None => frf.speed_rpm = Some(rpm),
            }
        }
        if let Some(u) = ctx.params.text("units") {
            let (scale, want) = formats::frf_unit(u).map_err(|why| NodeError::param("units", why))?;
            // Both labels are SI labels of their kind (`m/N`), or a label kept as written.
            let have = frf.unit.symbol.trim();
            if have.is_empty() {
                frf.values.iter_mut().for_each(|v| *v *= scale);
                frf.unit = UnitLabel::new(want);
            } else if have != want {
                let kind = if formats::is_frf_si_label(have) && formats::is_frf_si_label(&want) {
                    "a different kind of FRF"
                } else {
                    "which cannot be checked against it"
                };
                return Err(NodeError::param(
                    "units",
                    format!(
                        "{shown} holds values in {have} (its `# units:`), the recipe says `{u}`, {kind}; state the file's own units, or convert the file",
                    ),
                ));
            }
        }
        Ok([("frf".to_string(), Value::Frf(frf))].into_iter().collect())
    }
}

/// `read.receptance`: a 2×2 receptance set from a CSV or UFF file.
pub struct ReadReceptance {
    spec: NodeSpec,
}

impl Default for ReadReceptance {
    fn default() -> Self {
        Self::new()
    }
}

impl ReadReceptance {
    pub fn new() -> Self {
        ReadReceptance {
            spec: NodeSpec {
                kind: "read.receptance",
                version: 1,
                description: "Reads a 2x2 receptance set (H, L, N, P) from a CSV file (`freq_hz,h_re,h_im,...,p_im`) or from four UFF datasets 58 told apart by their direction codes; units to SI.",
                inputs: vec![],
                outputs: vec![PortSpec::new("receptance", PortType::ReceptanceSet, "the receptance set, in SI units")],
                params: vec![
                    file_param(),
                    format_param(),
                    Field::opt(
                        "direction",
                        T::Choice(&["x", "y"]),
                        "UFF: the direction to take when the file holds several; CSV: the direction of a file without `# direction`",
                    ),
                ],
            },
        }
    }
}

impl Node for ReadReceptance {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let (path, format) = source(ctx.params, false)?;
        let loaded = formats::read_receptance(path, format, ctx.params.text("direction")).map_err(read_error)?;
        for note in loaded.notes {
            ctx.warn(note);
        }
        Ok([("receptance".to_string(), Value::ReceptanceSet(loaded.value))].into_iter().collect())
    }
}
