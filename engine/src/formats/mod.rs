//! Data files: time series and FRFs as CSV, and Universal File Format dataset 58 (ASCII and
//! binary 58b), read into and written from the engine's typed values.
//!
//! Readers convert to SI where a unit label says how (`mm` → m) and reject what they cannot
//! read with the file, line and column and what was expected there; `docs/formats.md`
//! describes the layouts as implemented.

pub mod csv;
pub mod frf_set;
pub mod uff;

pub use frf_set::read_frf_set;

use crate::value::{Frf, ReceptanceSet, TimeSeries};
use std::fmt;
use std::path::Path;

/// Where in a data file a problem sits. `line` and `column` are 1-based; 0 when not applicable.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Loc {
    pub path: String,
    pub line: usize,
    pub column: usize,
}

impl Loc {
    pub fn new(path: &str, line: usize, column: usize) -> Self {
        Loc { path: path.to_string(), line, column }
    }
}

impl fmt::Display for Loc {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.line, self.column) {
            (0, _) => write!(f, "{}", self.path),
            (l, 0) => write!(f, "{}:{l}", self.path),
            (l, c) => write!(f, "{}:{l}:{c}", self.path),
        }
    }
}

/// A dataset of a UFF file that the reader does not interpret (for example 15, 55, 151, 164).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Skipped {
    /// Dataset number, e.g. 151.
    pub dataset: u32,
    /// Line of the dataset number.
    pub line: usize,
}

impl fmt::Display for Skipped {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "dataset {} at line {}", self.dataset, self.line)
    }
}

/// Why a data file could not be read or did not hold what was asked for.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    #[error("{path}: cannot read the file: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{at}: the file is empty")]
    Empty { at: Loc },
    #[error("{at}: no sample rate: add a header line `# sample_rate: 100000 Hz`")]
    MissingSampleRate { at: Loc },
    #[error("{at}: expected {expected}, found {found}")]
    Expected { at: Loc, expected: String, found: String },
    #[error("{at}: `{text}` in {what}: NaN samples and infinite values are not accepted")]
    NonFinite { at: Loc, text: String, what: String },
    #[error("{at}: ragged row: {} values, expected {expected} ({columns})", cell_count(*.found))]
    Ragged { at: Loc, found: usize, expected: usize, columns: String },
    #[error("{at}: mismatched channels: {message}")]
    ChannelMismatch { at: Loc, message: String },
    #[error("{at}: truncated binary data: {what} needs {needed} bytes, the file holds {available} more")]
    Truncated { at: Loc, what: String, needed: usize, available: usize },
    #[error("{at}: {message}")]
    Unsupported { at: Loc, message: String },
    #[error("{path}: no dataset 58 or 58b (function data) in the file{}", skipped_list(.skipped))]
    NoSupportedDataset { path: String, skipped: Vec<Skipped> },
    #[error("{path}: {message}")]
    Selection { path: String, message: String },
}

fn skipped_list(skipped: &[Skipped]) -> String {
    if skipped.is_empty() { String::new() } else { format!("; skipped {}", listed(skipped, ", ")) }
}

/// At most this many items of a list are written out in a message or in notes; the rest are
/// counted, so a file of a hundred thousand datasets gives a message of one line.
pub const LISTED: usize = 8;

/// The items joined by `sep`, the first [`LISTED`] written out and the rest counted
/// (`a, b, c, … and 97 more`).
pub(crate) fn listed<T: fmt::Display>(items: impl IntoIterator<Item = T>, sep: &str) -> String {
    let mut out = String::new();
    let mut n = 0usize;
    for item in items {
        if n < LISTED {
            if n > 0 {
                out.push_str(sep);
            }
            out.push_str(&item.to_string());
        }
        n += 1;
    }
    if n > LISTED {
        out.push_str(&format!("{sep}… and {} more", n - LISTED));
    }
    out
}

/// The number of cells found in a row, for a message: a row is counted only up to one cell
/// past [`csv::MAX_COLUMNS`].
fn cell_count(found: usize) -> String {
    if found > csv::MAX_COLUMNS { format!("more than {}", csv::MAX_COLUMNS) } else { found.to_string() }
}

impl FormatError {
    /// Where in the file the problem is, for the errors that have a place.
    fn location(&self) -> Option<&Loc> {
        match self {
            FormatError::Empty { at }
            | FormatError::MissingSampleRate { at }
            | FormatError::Expected { at, .. }
            | FormatError::NonFinite { at, .. }
            | FormatError::Ragged { at, .. }
            | FormatError::ChannelMismatch { at, .. }
            | FormatError::Truncated { at, .. }
            | FormatError::Unsupported { at, .. } => Some(at),
            FormatError::Io { .. } | FormatError::NoSupportedDataset { .. } | FormatError::Selection { .. } => None,
        }
    }

    /// The file the error is about.
    pub fn path(&self) -> &str {
        match self {
            FormatError::Io { path, .. }
            | FormatError::NoSupportedDataset { path, .. }
            | FormatError::Selection { path, .. } => path,
            other => other.location().map_or("", |at| at.path.as_str()),
        }
    }

    /// 1-based line and column of the problem; 0 where it has none.
    pub fn line_column(&self) -> (usize, usize) {
        self.location().map_or((0, 0), |at| (at.line, at.column))
    }
}

/// The layout of a data file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileFormat {
    Csv,
    Uff,
}

impl FileFormat {
    /// The format named by a file's extension (`.csv`, `.txt`; `.uff`, `.unv`, `.uf`), else by its
    /// first non-blank line: a UFF file opens with the delimiter `-1`.
    pub fn detect(path: &Path) -> Result<FileFormat, FormatError> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("csv" | "txt") => return Ok(FileFormat::Csv),
            Some("uff" | "unv" | "uf") => return Ok(FileFormat::Uff),
            _ => {}
        }
        let mut head = Vec::new();
        let opened = std::fs::File::open(path)
            .and_then(|f| std::io::Read::read_to_end(&mut std::io::Read::take(f, 4096), &mut head));
        opened.map_err(|source| FormatError::Io { path: path.display().to_string(), source })?;
        let first = head.split(|b| *b == b'\n').map(|l| l.trim_ascii()).find(|l| !l.is_empty());
        Ok(if first == Some(b"-1".as_slice()) { FileFormat::Uff } else { FileFormat::Csv })
    }
}

/// A value read from a file, with notes on what was passed over (skipped datasets).
#[derive(Debug, Clone, PartialEq)]
pub struct Loaded<T> {
    pub value: T,
    pub notes: Vec<String>,
}

/// The largest data file read (CSV, UFF, trials): a device or a pipe named as a file stops
/// here instead of filling memory.
pub const MAX_DATA_BYTES: u64 = crate::spec::MAX_DATA_BYTES;

/// Reads at most `cap` bytes of any kind of file (a regular file, `/dev/zero`, a pipe); more
/// is an error that says so, never an allocation sized by the file.
pub fn read_capped(path: &Path, cap: u64) -> std::io::Result<Vec<u8>> {
    let meta = std::fs::metadata(path)?;
    let bytes = if meta.is_file() {
        let f = std::fs::File::open(path)?;
        // A regular file's length, to the cap, is read into one allocation.
        let hint = meta.len().min(cap);
        let mut bytes = Vec::with_capacity(usize::try_from(hint).unwrap_or(0).saturating_add(1));
        std::io::Read::read_to_end(&mut std::io::Read::take(f, cap + 1), &mut bytes)?;
        bytes
    } else {
        // A device or a pipe: opened without waiting for a writer, grown as it is read.
        crate::syntax::read_up_to(path, cap)?
    };
    if bytes.len() as u64 > cap {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("the file is larger than the {} MiB limit", cap / (1024 * 1024)),
        ));
    }
    Ok(bytes)
}

/// What is wrong with the frequency `f` of an FRF after the line before it (`None`: the first
/// line), or `None`: frequencies are not negative and rise from line to line.
pub(crate) fn frequency_problem(before: Option<f64>, f: f64) -> Option<&'static str> {
    if f < 0.0 {
        Some("a frequency of at least 0 Hz")
    } else if before.is_some_and(|b| f <= b) {
        Some("a frequency above the one before it (an FRF's frequencies rise, each once)")
    } else {
        None
    }
}

/// The largest case file (`case.json`) read: a case is a page of text that names its data
/// files, as a recipe is.
pub const MAX_CASE_BYTES: u64 = crate::syntax::MAX_RECIPE_BYTES;

/// [`read_capped`] as UTF-8 text; text that is not is an error that says so.
pub fn read_text_capped(path: &Path, cap: u64) -> std::io::Result<String> {
    String::from_utf8(read_capped(path, cap)?)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, format!("not UTF-8 text ({e})")))
}

fn read_bytes(path: &Path) -> Result<Vec<u8>, FormatError> {
    read_capped(path, MAX_DATA_BYTES).map_err(|source| FormatError::Io { path: path.display().to_string(), source })
}

fn skipped_notes(path: &str, skipped: &[Skipped]) -> Vec<String> {
    let mut notes = Notes::new(path);
    for s in skipped {
        notes.push(|| format!("{path}: {s} is not read (only datasets 58 and 58b are)"));
    }
    notes.finish()
}

/// Notes on what a reader passed over, one per item up to [`LISTED`], then one that counts
/// the rest: a file of many skipped datasets does not bury a run's warnings.
pub(crate) struct Notes<'a> {
    path: &'a str,
    notes: Vec<String>,
    more: usize,
}

impl<'a> Notes<'a> {
    pub(crate) fn new(path: &'a str) -> Self {
        Notes { path, notes: Vec::new(), more: 0 }
    }

    /// Adds the note `text` makes, or counts it once [`LISTED`] are kept.
    pub(crate) fn push(&mut self, text: impl FnOnce() -> String) {
        if self.notes.len() < LISTED {
            self.notes.push(text());
        } else {
            self.more += 1;
        }
    }

    pub(crate) fn finish(mut self) -> Vec<String> {
        if self.more > 0 {
            self.notes.push(format!("{}: … and {} more passed over like these", self.path, self.more));
        }
        self.notes
    }
}

/// Reads a time series from a CSV or UFF file. For UFF, `dataset` (1-based, counting the
/// datasets 58 of the file) picks one; without it every time response of the file becomes
/// one channel, which requires them to share sample rate, start time and length.
pub fn read_time_series(
    path: &Path,
    format: FileFormat,
    dataset: Option<usize>,
) -> Result<Loaded<TimeSeries>, FormatError> {
    let bytes = read_bytes(path)?;
    let shown = path.display().to_string();
    match format {
        FileFormat::Csv => Ok(Loaded { value: csv::read_time_series(&bytes, &shown)?, notes: Vec::new() }),
        FileFormat::Uff => {
            let file = uff::parse(&bytes, &shown)?;
            let mut notes = skipped_notes(&shown, &file.skipped);
            if let Some(k) = dataset {
                let ds = pick_of_type(&file, k, &shown, uff::FUNCTION_TIME, "a time response (function type 1)")?;
                return Ok(Loaded { value: ds.to_time_series(&shown)?, notes });
            }
            let mut series: Vec<TimeSeries> = Vec::new();
            let mut passed = Notes::new(&shown);
            for ds in &file.datasets {
                if ds.function_type == uff::FUNCTION_TIME {
                    series.push(ds.to_time_series(&shown)?);
                } else {
                    passed.push(|| {
                        format!(
                            "{shown}: dataset 58 at line {} is {}, not a time response; skipped",
                            ds.line,
                            uff::function_name(ds.function_type)
                        )
                    });
                }
            }
            notes.extend(passed.finish());
            let Some(first) = series.first() else {
                return Err(FormatError::Selection {
                    path: shown,
                    message: format!("no time response (function type 1) among its datasets: {}", file.summary()),
                });
            };
            let (rate, t0, len) = (first.sample_rate, first.t0, first.len());
            let same = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(f64::MIN_POSITIVE);
            if let Some(odd) =
                series.iter().position(|s| !same(s.sample_rate, rate) || !same(s.t0, t0) || s.len() != len)
            {
                return Err(FormatError::Selection {
                    path: shown,
                    message: format!(
                        "its time responses differ in sample rate, start time or length (the first and number {}); \
                         choose one with `dataset`",
                        odd + 1
                    ),
                });
            }
            let mut value = series.remove(0);
            for s in series {
                value.channels.extend(s.channels);
            }
            Ok(Loaded { value, notes })
        }
    }
}

/// Which FRF of a UFF file to take: by position among the datasets 58 (1-based), or by
/// response direction and response and reference node numbers (record 6); with none of them,
/// the file must hold exactly one FRF.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrfSelect {
    pub dataset: Option<usize>,
    pub direction: Option<String>,
    /// Response node number.
    pub response: Option<i64>,
    /// Reference (excitation) node number.
    pub reference: Option<i64>,
}

impl FrfSelect {
    /// Whether the FRF's response and reference nodes are those asked for (an FRF without
    /// node numbers matches no node asked for).
    fn nodes_match(&self, dofs: Option<crate::value::FrfDofs>) -> bool {
        let want = |asked: Option<i64>, have: Option<i64>| asked.is_none_or(|a| have == Some(a));
        want(self.response, dofs.map(|d| d.response_node)) && want(self.reference, dofs.map(|d| d.reference_node))
    }

    /// `response 3, reference 1`, `direction x`, for messages (empty when nothing is asked).
    fn asked(&self) -> String {
        let mut parts = Vec::new();
        if let Some(d) = &self.direction {
            parts.push(format!("direction `{d}`"));
        }
        if let Some(n) = self.response {
            parts.push(format!("response node {n}"));
        }
        if let Some(n) = self.reference {
            parts.push(format!("reference node {n}"));
        }
        parts.join(", ")
    }
}

/// Reads an FRF from a CSV or UFF file.
///
/// For CSV, a `direction` in `select` fills in a file without `# direction` and must agree
/// with one that has it.
pub fn read_frf(path: &Path, format: FileFormat, select: &FrfSelect) -> Result<Loaded<Frf>, FormatError> {
    let bytes = read_bytes(path)?;
    let shown = path.display().to_string();
    match format {
        FileFormat::Csv => {
            let mut blocks = csv::read_frf_blocks(&bytes, &shown)?;
            // A swept file: its `direction` column narrows, `dataset` picks a sweep point.
            if let Some(want) = &select.direction
                && blocks.len() > 1
            {
                blocks.retain(|b| b.frf.direction.as_deref().is_none_or(|d| d == want));
                if blocks.is_empty() {
                    return Err(FormatError::Selection {
                        path: shown,
                        message: format!("no sweep point of the file is in direction `{want}`"),
                    });
                }
            }
            let n = blocks.len();
            let mut frf = match select.dataset {
                Some(k) if k >= 1 && k <= n => blocks.swap_remove(k - 1).frf,
                Some(k) => {
                    return Err(FormatError::Selection {
                        path: shown,
                        message: format!("`dataset: {k}` asked for, the file holds {n} sweep point(s) there"),
                    });
                }
                None if n == 1 => blocks.swap_remove(0).frf,
                None => {
                    return Err(FormatError::Selection {
                        path: shown,
                        message: format!(
                            "the file holds {n} sweep points ({} …); read one with `dataset: K`, counting from 1",
                            csv::block_names(&blocks[..3.min(n)]).join("; ")
                        ),
                    });
                }
            };
            if let Some(want) = &select.direction {
                match &frf.direction {
                    Some(d) if d != want => {
                        return Err(FormatError::Selection {
                            path: shown,
                            message: format!(
                                "the file holds the `{}` direction, `{want}` was asked for",
                                csv::shown_cell(d)
                            ),
                        });
                    }
                    Some(_) => {}
                    None => frf.direction = Some(want.clone()),
                }
            }
            if !select.nodes_match(frf.dofs) {
                return Err(FormatError::Selection {
                    path: shown,
                    message: format!(
                        "{} was asked for, the file holds {}",
                        select.asked(),
                        frf.dofs
                            .map_or("an FRF without node numbers (`# response:`, `# reference:`)".to_string(), |d| d
                                .describe())
                    ),
                });
            }
            Ok(Loaded { value: frf, notes: Vec::new() })
        }
        FileFormat::Uff => {
            let file = uff::parse(&bytes, &shown)?;
            let mut notes = skipped_notes(&shown, &file.skipped);
            if let Some(k) = select.dataset {
                let ds = pick_of_type(&file, k, &shown, uff::FUNCTION_FRF, "an FRF (function type 4)")?;
                let frf = checked_frf(ds, &shown)?;
                if let Some(want) = &select.direction
                    && frf.direction.as_deref() != Some(want.as_str())
                {
                    return Err(FormatError::Selection {
                        path: shown,
                        message: format!(
                            "dataset {k} (line {}) responds in direction {}, `{want}` was asked for",
                            ds.line,
                            frf.direction.as_deref().map_or("none (scalar)".to_string(), |d| format!("`{d}`"))
                        ),
                    });
                }
                if !select.nodes_match(frf.dofs) {
                    return Err(FormatError::Selection {
                        path: shown,
                        message: format!("dataset {k} is {}, {} was asked for", ds.describe(), select.asked()),
                    });
                }
                return Ok(Loaded { value: frf, notes });
            }
            let mut frfs = Vec::new();
            let mut passed = Notes::new(&shown);
            for ds in &file.datasets {
                if ds.function_type != uff::FUNCTION_FRF {
                    passed.push(|| {
                        format!(
                            "{shown}: dataset 58 at line {} is {}, not an FRF; skipped",
                            ds.line,
                            uff::function_name(ds.function_type)
                        )
                    });
                } else if select
                    .direction
                    .as_deref()
                    .is_none_or(|d| uff::direction_name(ds.response.direction) == Some(d))
                    && select.response.is_none_or(|n| ds.response.node == n)
                    && select.reference.is_none_or(|n| ds.reference.node == n)
                {
                    frfs.push(ds);
                }
            }
            notes.extend(passed.finish());
            match frfs.as_slice() {
                [one] => Ok(Loaded { value: checked_frf(one, &shown)?, notes }),
                [] => Err(FormatError::Selection {
                    path: shown,
                    message: match select.asked().as_str() {
                        "" => format!("no FRF (function type 4) among its datasets: {}", file.summary()),
                        asked => format!("no FRF with {asked} among its datasets: {}", file.summary()),
                    },
                }),
                many => Err(FormatError::Selection {
                    path: shown,
                    message: format!(
                        "{} FRFs match ({}); choose one with `response` and `reference` (node numbers), `direction` or `dataset`",
                        many.len(),
                        listed(many.iter().map(|d| d.describe()), ", ")
                    ),
                }),
            }
        }
    }
}

/// Reads a 2×2 receptance set from a CSV file (`freq_hz,h_re,h_im,…,p_im`) or from the four
/// FRF datasets 58 of a UFF file (see [`uff::to_receptance`]). `direction` picks the UFF
/// direction when the file holds several; for CSV it fills in a file without `# direction`
/// and must agree with one that has it.
pub fn read_receptance(
    path: &Path,
    format: FileFormat,
    direction: Option<&str>,
) -> Result<Loaded<ReceptanceSet>, FormatError> {
    let bytes = read_bytes(path)?;
    let shown = path.display().to_string();
    match format {
        FileFormat::Csv => {
            let mut r = csv::read_receptance(&bytes, &shown)?;
            if let Some(want) = direction {
                match &r.direction {
                    Some(d) if d != want => {
                        return Err(FormatError::Selection {
                            path: shown,
                            message: format!(
                                "the file holds the `{}` direction, `{want}` was asked for",
                                csv::shown_cell(d)
                            ),
                        });
                    }
                    Some(_) => {}
                    None => r.direction = Some(want.to_string()),
                }
            }
            Ok(Loaded { value: r, notes: Vec::new() })
        }
        FileFormat::Uff => {
            let file = uff::parse(&bytes, &shown)?;
            let mut notes = skipped_notes(&shown, &file.skipped);
            let (value, more) = uff::to_receptance(&file, &shown, direction)?;
            notes.extend(more);
            Ok(Loaded { value, notes })
        }
    }
}

fn pick<'a>(file: &'a uff::UffFile, k: usize, path: &str) -> Result<&'a uff::Dataset58, FormatError> {
    if k == 0 || k > file.datasets.len() {
        return Err(FormatError::Selection {
            path: path.to_string(),
            message: format!(
                "dataset {k} was asked for; the file holds {} dataset(s) 58, numbered from 1: {}",
                file.datasets.len(),
                file.summary()
            ),
        });
    }
    Ok(&file.datasets[k - 1])
}

/// Dataset `k` (from 1), which must be of function type `function` (`what` names it).
fn pick_of_type<'a>(
    file: &'a uff::UffFile,
    k: usize,
    path: &str,
    function: i32,
    what: &str,
) -> Result<&'a uff::Dataset58, FormatError> {
    let ds = pick(file, k, path)?;
    if ds.function_type != function {
        return Err(FormatError::Selection {
            path: path.to_string(),
            message: format!("dataset {k} (line {}) is {}, not {what}", ds.line, uff::function_name(ds.function_type)),
        });
    }
    Ok(ds)
}

/// The kinds of FRF the readers take, by the dimension of the values (response per force),
/// with the SI label each is given. Nodes that need a receptance check for `m/N`.
const FRF_KINDS: [(spindlelab_grammar::Dimension, &str); 3] = [
    (spindlelab_grammar::Dimension::COMPLIANCE, "m/N"),
    (spindlelab_grammar::Dimension::new(0, -1, 1, 0), "m/s/N"),
    (spindlelab_grammar::Dimension::new(0, -1, 0, 0), "m/s^2/N"),
];

/// What an FRF's unit must be, for messages.
pub const FRF_UNIT_EXPECTED: &str = "a receptance, length per force (`m/N`, `um/N`), or a mobility (`m/s/N`) or \
                                     accelerance (`m/s^2/N`)";

/// An FRF's unit label brought to SI: the factor for its values and the SI label of its kind
/// (`um/N` → 1e-6 and `m/N`; empty for none). A label with a bare `g` (standard gravity as
/// often as grams) is kept as written with factor 1. A label the unit grammar cannot read, or
/// of a dimension no FRF has (`kg`), is refused: `Err` says why, for the caller to place.
pub fn frf_unit(label: &str) -> Result<(f64, String), String> {
    let label = label.trim();
    if label.is_empty() {
        return Ok((1.0, String::new()));
    }
    // A unit is a few symbols; a longer label is neither parsed nor quoted whole.
    const LONGEST: usize = 100;
    let length = label.chars().count();
    if length > LONGEST {
        return Err(format!("a label of {length} characters is not a unit"));
    }
    if has_bare_g(label) {
        return Ok((1.0, label.to_string()));
    }
    let u = spindlelab_grammar::parse_unit(label).map_err(|e| format!("`{label}` is not a unit: {e}"))?;
    match FRF_KINDS.iter().find(|(d, _)| *d == u.dim) {
        Some((_, si)) => Ok((u.scale, si.to_string())),
        None => Err(format!("`{label}` is {}, not the unit of an FRF", u.dim.describe())),
    }
}

/// True for the SI label of a kind of FRF (`m/N`, `m/s/N`, `m/s^2/N`), as [`frf_unit`] gives it.
pub fn is_frf_si_label(label: &str) -> bool {
    FRF_KINDS.iter().any(|(_, si)| *si == label)
}

/// Dataset `ds` as an FRF whose unit (from its ordinate axes) is checked to be one of an FRF
/// where the unit grammar reads it; a label it does not read stays as the file writes it.
fn checked_frf(ds: &uff::Dataset58, path: &str) -> Result<Frf, FormatError> {
    let mut frf = ds.to_frf(path)?;
    let label = frf.unit.symbol.trim();
    if label.is_empty() || has_bare_g(label) || spindlelab_grammar::parse_unit(label).is_err() {
        return Ok(frf);
    }
    match frf_unit(label) {
        Ok((scale, si)) => {
            if scale != 1.0 {
                frf.values.iter_mut().for_each(|v| *v *= scale);
            }
            frf.unit = crate::value::UnitLabel::new(si);
            Ok(frf)
        }
        Err(why) => Err(FormatError::Unsupported {
            at: Loc::new(path, ds.line, 0),
            message: format!("the FRF's values are in {why} (records 9 and 10); expected {FRF_UNIT_EXPECTED}"),
        }),
    }
}

/// True when a unit label has the word `g`, which data files use for standard gravity as
/// often as for grams.
fn has_bare_g(label: &str) -> bool {
    label.split(|c: char| !c.is_alphabetic()).any(|w| w == "g")
}

/// A unit label as found in a file, brought to SI: the factor to multiply values by and the
/// SI symbol. Labels the unit grammar does not read, or whose dimension contradicts `expected`,
/// are kept as written with factor 1, and so is any label with a bare `g`, which data files
/// use for standard gravity as often as for grams.
pub(crate) fn unit_to_si(label: &str, expected: Option<spindlelab_grammar::Dimension>) -> (f64, String) {
    let label = label.trim();
    if label.is_empty() {
        return (1.0, String::new());
    }
    if has_bare_g(label) {
        return (1.0, label.to_string());
    }
    match spindlelab_grammar::parse_unit(label) {
        Ok(u) if expected.is_none_or(|d| d == u.dim) => {
            if u.scale == 1.0 {
                (1.0, label.to_string())
            } else {
                (u.scale, u.dim.si_unit())
            }
        }
        _ => (1.0, label.to_string()),
    }
}

/// Reads a value of type `ty` as a `.json` output writes it: the value's own object (the
/// output writer leaves out the name of its type), non-finite numbers as `"inf"`/`"NaN"`.
pub fn read_json_value(text: &str, ty: crate::value::PortType) -> Result<crate::value::Value, serde_json::Error> {
    let inner: serde_json::Value = serde_json::from_str(text)?;
    // The type's name as the value enum spells its variant (`Lobes`, `Table`, `FrfSet`).
    serde_json::from_value(serde_json::json!({ format!("{ty:?}"): inner }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_labels_come_to_si() {
        assert_eq!(unit_to_si("m/N", None), (1.0, "m/N".to_string()));
        let (s, sym) = unit_to_si("mm", None);
        assert_eq!((s, sym.as_str()), (1e-3, "m"));
        // `g` parses as grams; where an acceleration is expected it stays as written.
        assert_eq!(unit_to_si("g", Some(spindlelab_grammar::Dimension::ACCELERATION)), (1.0, "g".to_string()));
        assert_eq!(unit_to_si("g/N", None), (1.0, "g/N".to_string()));
        assert_eq!(unit_to_si("kg", None), (1.0, "kg".to_string()));
        assert_eq!(unit_to_si("NONE?", None), (1.0, "NONE?".to_string()));
    }

    #[test]
    fn locations_print_as_path_line_column() {
        assert_eq!(Loc::new("a.csv", 3, 7).to_string(), "a.csv:3:7");
        assert_eq!(Loc::new("a.csv", 3, 0).to_string(), "a.csv:3");
        assert_eq!(Loc::new("a.csv", 0, 0).to_string(), "a.csv");
    }

    #[test]
    fn lists_in_messages_show_a_few_items_and_count_the_rest() {
        assert_eq!(listed(["a", "b"], ", "), "a, b");
        assert_eq!(listed(0..LISTED, ","), "0,1,2,3,4,5,6,7");
        assert_eq!(listed(0..100_000, ", "), "0, 1, 2, 3, 4, 5, 6, 7, … and 99992 more");
        let skipped: Vec<Skipped> = (0..100_000).map(|i| Skipped { dataset: 15, line: 3 * i + 2 }).collect();
        let e = FormatError::NoSupportedDataset { path: "big.uff".into(), skipped: skipped.clone() }.to_string();
        assert!(e.ends_with("and 99992 more") && e.len() < 300, "{e}");
        let notes = skipped_notes("big.uff", &skipped);
        assert_eq!(notes.len(), LISTED + 1);
        assert_eq!(notes[LISTED], "big.uff: … and 99992 more passed over like these");
    }

    #[test]
    fn frf_units_of_every_kind_come_to_si_and_others_are_refused() {
        assert_eq!(frf_unit(""), Ok((1.0, String::new())));
        assert_eq!(frf_unit("m/N"), Ok((1.0, "m/N".into())));
        assert_eq!(frf_unit("N^-1*m"), Ok((1.0, "m/N".into())));
        let (s, l) = frf_unit("um/N").unwrap();
        assert!((s - 1e-6).abs() < 1e-20 && l == "m/N");
        assert_eq!(frf_unit("m/s/N").map(|u| u.1), Ok("m/s/N".into()));
        assert_eq!(frf_unit("m/s^2/N").map(|u| u.1), Ok("m/s^2/N".into()));
        assert_eq!(frf_unit("g/N"), Ok((1.0, "g/N".into())));
        assert!(frf_unit("kg").unwrap_err().contains("a mass (kg)"));
        assert!(frf_unit("m").unwrap_err().contains("a length (m)"));
        // Exponents past the grammar's range are an error, never an overflow.
        for u in ["m^999999999999/N", "m^-999999999999/N", "m^127*m^127/N", "m^99999999999999999999999"] {
            assert!(frf_unit(u).is_err(), "{u}");
        }
        assert!(is_frf_si_label("m/N") && !is_frf_si_label("um/N"));
        assert_eq!(frf_unit(&"m".repeat(1_000_000)).unwrap_err(), "a label of 1000000 characters is not a unit");
    }
}
