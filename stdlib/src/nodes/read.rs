//! `read.time_series`, `read.frf` and `read.receptance`: measured data from CSV or UFF (dataset
//! 58/58b) files.
//!
//! The file is a parameter: the recipe names it relative to its own folder, and its
//! contents are hashed into the cache key, so editing the data reruns what depends on it.

use spindlelab_domain::Speed;
use spindlelab_engine::formats::{self, FileFormat, FormatError, FrfSelect};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{PortType, UnitLabel, Value};
use spindlelab_grammar::Dimension as D;
use std::path::Path;

pub(super) const FORMATS: &[&str] = &["auto", "csv", "uff"];

/// The doc of the `file` parameter every reader has.
pub(super) const FILE_DOC: &str = "the data file, relative to the recipe's folder";

/// The default and the doc of the `format` parameter every reader has.
pub(super) const FORMAT_DEFAULT: &str = "auto";
pub(super) const FORMAT_DOC: &str =
    "file layout; `auto` goes by the extension (`.csv`, `.uff`/`.unv`), else by the contents";

/// The range of the `dataset` parameter, and its doc for FRFs and for time series.
const DATASET: T = T::Integer { min: 1, max: 1_000_000 };
const DATASET_FRF_DOC: &str = "which FRF to read, counting from 1: a dataset 58 of a UFF file, or a sweep point of a CSV file a swept output wrote";
const DATASET_TIME_DOC: &str =
    "UFF only: which dataset 58 of the file to read, counting from 1; without it every time response becomes a channel";

/// The layout of `path` as the `format` parameter gives it.
pub(super) fn file_format(path: &Path, format: &str) -> Result<FileFormat, NodeError> {
    Ok(match format {
        "csv" => FileFormat::Csv,
        "uff" => FileFormat::Uff,
        _ => FileFormat::detect(path).map_err(read_error)?,
    })
}

/// The layout of the file, checked against `dataset` where the file holds no datasets.
fn source(path: &Path, format: &str, dataset: Option<usize>, frfs: bool) -> Result<FileFormat, NodeError> {
    let format = file_format(path, format)?;
    // A CSV file holds one time series or receptance set; a swept FRF file holds sweep points.
    if format == FileFormat::Csv && dataset.is_some() && !frfs {
        return Err(NodeError::param("dataset", format!("applies to UFF files; {} is CSV", path.display())));
    }
    Ok(format)
}

pub(super) fn read_error(e: FormatError) -> NodeError {
    NodeError::param("file", e.to_string())
}

node_params! {
    /// Parameters of `read.time_series`.
    pub struct ReadTimeSeriesParams<'a> {
        file: req &'a Path = (T::File, FILE_DOC),
        format: def &'a str = (T::Choice(FORMATS), FORMAT_DEFAULT, FORMAT_DOC),
        dataset: opt usize = (DATASET, DATASET_TIME_DOC),
    }
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
                params: ReadTimeSeriesParams::fields(),
            },
        }
    }
}

impl Node for ReadTimeSeries {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = ReadTimeSeriesParams::read(ctx.params)?;
        let format = source(p.file, p.format, p.dataset, false)?;
        let loaded = formats::read_time_series(p.file, format, p.dataset).map_err(read_error)?;
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

node_params! {
    /// Parameters of `read.frf`.
    pub struct ReadFrfParams<'a> {
        file: req &'a Path = (T::File, FILE_DOC),
        format: def &'a str = (T::Choice(FORMATS), FORMAT_DEFAULT, FORMAT_DOC),
        dataset: opt usize = (DATASET, DATASET_FRF_DOC),
        direction: opt &'a str = (
            T::Choice(&["x", "y", "z"]),
            "UFF: take the FRF whose response is in this direction; CSV: the direction of a file without `# direction`",
        ),
        response: opt i64 = (
            T::Integer { min: 0, max: i64::MAX },
            "take the FRF whose response node number is this (UFF record 6; CSV `# response:`)",
        ),
        reference: opt i64 = (
            T::Integer { min: 0, max: i64::MAX },
            "take the FRF whose reference (excitation) node number is this",
        ),
        speed: opt f64 = (
            T::Quantity(D::ROTATIONAL_SPEED),
            "the spindle speed of the measurement: fills a file without one, and must agree with a file that states it",
        ),
        units: opt &'a str = (
            T::Text,
            "the unit of the file's values (`m/N`, `um/N`, `m/s^2/N`): a file without `# units:` is read in it, one whose units are of another kind is refused",
        ),
    }
}

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
                params: ReadFrfParams::fields(),
            },
        }
    }
}

impl Node for ReadFrf {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = ReadFrfParams::read(params)?;
        if let Some(u) = p.units {
            formats::frf_unit(u).map_err(|why| {
                NodeError::param("units", format!("{why}; the values of an FRF are {}", formats::FRF_UNIT_EXPECTED))
            })?;
        }
        super::non_negative(params, &["speed"])
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = ReadFrfParams::read(ctx.params)?;
        let path = p.file;
        let format = source(path, p.format, p.dataset, true)?;
        let select = FrfSelect {
            dataset: p.dataset,
            direction: p.direction.map(str::to_string),
            response: p.response,
            reference: p.reference,
        };
        let loaded = formats::read_frf(path, format, &select).map_err(read_error)?;
        for note in loaded.notes {
            ctx.warn(note);
        }
        let mut frf = loaded.value;
        let shown = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
        if let Some(w) = p.speed {
            let rpm = Speed::from_rad_s(w).rpm();
            match frf.speed.map(Speed::rpm_as_written) {
                Some(s) if (s - rpm).abs() > 1e-6 * rpm.abs().max(1.0) => {
                    return Err(NodeError::param(
                        "speed",
                        format!("{shown} was measured at {s} rpm (its `# speed_rpm`), the recipe says {rpm} rpm"),
                    ));
                }
                Some(_) => {}
                None => frf.speed = Some(Speed::from_rad_s(w)),
            }
        }
        if let Some(u) = p.units {
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

node_params! {
    /// Parameters of `read.receptance`.
    pub struct ReadReceptanceParams<'a> {
        file: req &'a Path = (T::File, FILE_DOC),
        format: def &'a str = (T::Choice(FORMATS), FORMAT_DEFAULT, FORMAT_DOC),
        direction: opt &'a str = (
            T::Choice(&["x", "y"]),
            "UFF: the direction to take when the file holds several; CSV: the direction of a file without `# direction`",
        ),
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
                params: ReadReceptanceParams::fields(),
            },
        }
    }
}

impl Node for ReadReceptance {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = ReadReceptanceParams::read(ctx.params)?;
        let format = source(p.file, p.format, None, false)?;
        let loaded = formats::read_receptance(p.file, format, p.direction).map_err(read_error)?;
        for note in loaded.notes {
            ctx.warn(note);
        }
        Ok([("receptance".to_string(), Value::ReceptanceSet(loaded.value))].into_iter().collect())
    }
}
