//! CSV time series and FRFs, as the output writer produces them.
//!
//! Time series: `# sample_rate: 100000 Hz`, `# t0: -0.001 s`, `# units: force=N, ...`, a row
//! of channel names, then one column per channel. FRF: `# units`, `# direction`,
//! `# speed_rpm`, `# sensor`, then `freq_hz,real,imag[,coherence]`. 2×2 receptance set:
//! `# units`, `# direction`, `# speed_rpm`, then `freq_hz,h_re,h_im,l_re,l_im,n_re,n_im,p_re,p_im`.
//! Numbers are written as the shortest text that reads back as the same double (zmij's
//! Schubfach; `NaN`, `inf` as Rust writes them), so a round trip is exact.

use super::{FormatError, Loc, unit_to_si};
use crate::value::{Channel, Frf, Lobes, ReceptanceSet, Table, TimeSeries, UnitLabel};
use num_complex::Complex64;
use spindlelab_domain::Speed;
use spindlelab_grammar::{self as grammar, Dimension};
use std::borrow::Cow;
use std::collections::HashMap;
use std::fmt::Write as _;

/// Appends `,` (unless `first`) and the shortest round-trip text of each of `values`.
fn push_nums(out: &mut String, buf: &mut zmij::Buffer, values: &[f64], first: bool) {
    for (k, &v) in values.iter().enumerate() {
        if k > 0 || !first {
            out.push(',');
        }
        out.push_str(buf.format(v));
    }
}

/// Writes a time series: the `#` header lines and the column header when `*header_done` is
/// false, then one row per sample. `prefix_header` and `prefix` lead the header and each row
/// (the sweep columns of a swept output; empty otherwise).
pub(crate) fn time_series_rows(
    out: &mut String,
    ts: &TimeSeries,
    prefix_header: &str,
    prefix: &str,
    header_done: &mut bool,
) {
    if !*header_done {
        let _ = writeln!(out, "# sample_rate: {} Hz", ts.sample_rate);
        let _ = writeln!(out, "# t0: {} s", ts.t0);
        let units: Vec<String> = ts.channels.iter().map(|c| format!("{}={}", c.name, c.unit.symbol)).collect();
        let _ = writeln!(out, "# units: {}", units.join(", "));
        let names: Vec<&str> = ts.channels.iter().map(|c| c.name.as_str()).collect();
        let _ = writeln!(out, "{prefix_header}{}", names.join(","));
        *header_done = true;
    }
    let mut buf = zmij::Buffer::new();
    for i in 0..ts.len() {
        out.push_str(prefix);
        for (k, c) in ts.channels.iter().enumerate() {
            push_nums(out, &mut buf, &[c.samples[i]], k == 0);
        }
        out.push('\n');
    }
}

/// Writes an FRF: `#` header lines and the column header when `*header_done` is false, then
/// one row per frequency line, each led by `prefix`.
pub(crate) fn frf_rows(out: &mut String, f: &Frf, prefix_header: &str, prefix: &str, header_done: &mut bool) {
    if !*header_done {
        let _ = writeln!(out, "# units: {}", f.unit.symbol);
        if let Some(d) = &f.direction {
            let _ = writeln!(out, "# direction: {d}");
        }
        if let Some(s) = f.speed {
            let _ = writeln!(out, "# speed_rpm: {}", s.rpm_as_written());
        }
        if let Some(s) = &f.sensor {
            let _ = writeln!(out, "# sensor: {s}");
        }
        // One FRF's points; a swept file's blocks may differ in them, so it leaves them to UFF.
        if let Some(d) = f.dofs
            && prefix_header.is_empty()
        {
            let axis = |c: i32| super::uff::direction_name(c).unwrap_or("scalar");
            let _ = writeln!(out, "# response: {} {}", d.response_node, axis(d.response_direction));
            let _ = writeln!(out, "# reference: {} {}", d.reference_node, axis(d.reference_direction));
        }
        let coh = if f.coherence.is_some() { ",coherence" } else { "" };
        let _ = writeln!(out, "{prefix_header}freq_hz,real,imag{coh}");
        *header_done = true;
    }
    let mut buf = zmij::Buffer::new();
    for (i, (&fr, v)) in f.freq_hz.iter().zip(&f.values).enumerate() {
        out.push_str(prefix);
        push_nums(out, &mut buf, &[fr, v.re, v.im], true);
        if let Some(c) = &f.coherence {
            push_nums(out, &mut buf, &[c[i]], false);
        }
        out.push('\n');
    }
}

/// The blocks of a receptance set, their column stems, SI unit symbols as written, and dimensions.
const BLOCKS: [(&str, &str, Dimension); 4] = [
    ("h", "m/N", Dimension::new(0, -1, 2, 0)),
    ("l", "m/(N*m)", Dimension::new(-1, -1, 2, 0)),
    ("n", "rad/N", Dimension::new(-1, -1, 2, 1)),
    ("p", "rad/(N*m)", Dimension::new(-2, -1, 2, 1)),
];

/// The header row of a receptance set.
const RECEPTANCE_HEADER: &str = "freq_hz,h_re,h_im,l_re,l_im,n_re,n_im,p_re,p_im";

/// Writes a 2×2 receptance set: `#` header lines and the column header when `*header_done`
/// is false, then one row per frequency line, each led by `prefix`.
pub(crate) fn receptance_rows(
    out: &mut String,
    r: &ReceptanceSet,
    prefix_header: &str,
    prefix: &str,
    header_done: &mut bool,
) {
    if !*header_done {
        let units: Vec<String> = BLOCKS.iter().map(|(n, u, _)| format!("{n}={u}")).collect();
        let _ = writeln!(out, "# units: {}", units.join(", "));
        if let Some(d) = &r.direction {
            let _ = writeln!(out, "# direction: {d}");
        }
        if let Some(s) = r.speed {
            let _ = writeln!(out, "# speed_rpm: {}", s.rpm_as_written());
        }
        let _ = writeln!(out, "{prefix_header}{RECEPTANCE_HEADER}");
        *header_done = true;
    }
    let mut buf = zmij::Buffer::new();
    for i in 0..r.freq_hz.len() {
        out.push_str(prefix);
        let (h, l, n, p) = (r.h[i], r.l[i], r.n[i], r.p[i]);
        push_nums(out, &mut buf, &[r.freq_hz[i], h.re, h.im, l.re, l.im, n.re, n.im, p.re, p.im], true);
        out.push('\n');
    }
}

/// Column header of a stability diagram.
pub const LOBES_HEADER: &str = "speed_rpm,depth_limit_m,chatter_hz";

/// Rows `speed_rpm,depth_limit_m,chatter_hz` of a stability diagram; a speed no lobe limits has depth `inf`.
pub(crate) fn lobes_rows(out: &mut String, l: &Lobes, prefix_header: &str, prefix: &str, header_done: &mut bool) {
    if !*header_done {
        let _ = writeln!(out, "# units: speed_rpm=rpm, depth_limit_m=m, chatter_hz=Hz");
        let _ = writeln!(out, "{prefix_header}{LOBES_HEADER}");
        *header_done = true;
    }
    let mut buf = zmij::Buffer::new();
    for i in 0..l.speed.len() {
        out.push_str(prefix);
        push_nums(out, &mut buf, &[l.speed[i].rpm_as_written(), l.depth_limit[i], l.chatter_hz[i]], true);
        out.push('\n');
    }
}

/// A stability diagram as CSV text.
pub fn write_lobes(l: &Lobes) -> String {
    let mut out = String::new();
    lobes_rows(&mut out, l, "", "", &mut false);
    out
}

/// A 2×2 receptance set as CSV text.
pub fn write_receptance(r: &ReceptanceSet) -> String {
    let mut out = String::new();
    receptance_rows(&mut out, r, "", "", &mut false);
    out
}

/// A time series as CSV text.
pub fn write_time_series(ts: &TimeSeries) -> String {
    let mut out = String::new();
    time_series_rows(&mut out, ts, "", "", &mut false);
    out
}

/// An FRF as CSV text.
pub fn write_frf(f: &Frf) -> String {
    let mut out = String::new();
    frf_rows(&mut out, f, "", "", &mut false);
    out
}

/// Most columns a CSV header row may name: the channels of a time series, the columns of a
/// table. Each column becomes a vector in memory, so a wider header is refused before
/// anything is allocated for it; a wider recording is split into files of fewer channels.
pub const MAX_COLUMNS: usize = 4096;

/// Most sweep-coordinate columns that may lead the columns of an FRF or table file (a swept
/// output writes one per swept parameter).
pub const MAX_SWEEP_COLUMNS: usize = 64;

/// Most sweep points (runs of rows with the same sweep coordinates) one FRF or table file may
/// hold: as many as a recipe's graph may have node instances.
pub const MAX_SWEEP_POINTS: usize = crate::graph::MAX_INSTANCES;

/// A `# key: value` line, with the 1-based line number and the column of the value.
struct Meta<'a> {
    key: &'a str,
    value: &'a str,
    line: usize,
    column: usize,
}

/// A `channel=unit` entry of `# units`, with the column where it starts.
type UnitEntry<'a> = (&'a str, &'a str, usize);

/// The `# key: value` line `raw` (line number `line`), or `None` for any other line. Only
/// `# word: …` lines are header lines; any other `#` line is a comment.
fn meta_line(raw: &str, line: usize) -> Option<Meta<'_>> {
    let trimmed = raw.trim();
    let (key, value) = trimmed.strip_prefix('#')?.split_once(':')?;
    let key = key.trim();
    if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return None;
    }
    let lead = raw.len() - raw.trim_start().len();
    let value_start = lead + trimmed.len() - value.trim_start().len();
    Some(Meta { key, value: value.trim(), line, column: raw[..value_start].chars().count() + 1 })
}

/// The lines of `text` from byte `from`, numbered from `first`, without their line ends
/// (`\n` or `\r\n`).
fn numbered(text: &str, from: usize, first: usize) -> impl Iterator<Item = (usize, &str)> {
    text[from..].split_inclusive('\n').zip(first..).map(|(piece, n)| (n, without_end(piece)))
}

/// A line without its line end (`\n` or `\r\n`).
fn without_end(piece: &str) -> &str {
    match piece.strip_suffix('\n') {
        Some(l) => l.strip_suffix('\r').unwrap_or(l),
        None => piece,
    }
}

/// True for a line that is neither blank nor a `#` line: the header row or a data row.
fn is_data(raw: &str) -> bool {
    let t = raw.trim();
    !t.is_empty() && !t.starts_with('#')
}

/// How much of what spreadsheets do to a CSV file a reader undoes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Forms {
    /// The plain form only (what outputs write).
    Plain,
    /// A byte-order mark, and `;` separators with decimal commas.
    Spreadsheet,
    /// As `Spreadsheet`, and a capitalised header row of fixed names (`Freq_Hz,Real,Imag`).
    SpreadsheetHeader,
}

/// A CSV file as the readers walk it: the text (after a byte-order mark), the column header
/// row and where the data rows start. `#` lines and rows are read from the text as they are
/// needed, never gathered, so a file is held in memory once, with what is read from it.
///
/// A spreadsheet's form is undone line by line: `;` separators with decimal commas
/// (`1,5;2,0` in European locales) become `1.5,2.0`, a capitalised header row of fixed names
/// is lowercased. Every change keeps each character in its place, so lines and columns in
/// messages still point into the file as written.
struct Sheet<'a> {
    text: &'a str,
    header: Option<(usize, Cow<'a, str>)>,
    /// The number of cells of the header row as written.
    header_width: usize,
    /// Byte offset of the line after the header row.
    rows_at: usize,
    semicolons: bool,
}

impl<'a> Sheet<'a> {
    fn open(bytes: &'a [u8], path: &str, forms: Forms) -> Result<Self, FormatError> {
        let body = match forms {
            Forms::Plain => bytes,
            _ => bytes.strip_prefix(b"\xef\xbb\xbf".as_slice()).unwrap_or(bytes),
        };
        let text = as_text(body, path)?;
        if text.trim().is_empty() {
            return Err(FormatError::Empty { at: Loc::new(path, 0, 0) });
        }
        let mut rows_at = 0;
        let mut header = None;
        for (piece, n) in text.split_inclusive('\n').zip(1..) {
            rows_at += piece.len();
            if is_data(piece) {
                header = Some((n, without_end(piece)));
                break;
            }
        }
        // Names and labels travel into output headers, legends and messages: none longer than
        // a label can be, whatever the file says.
        // A list (`# units:`, `# text:`) is bounded entry by entry, other values whole.
        let long_meta = numbered(text, 0, 1).filter_map(|(n, raw)| meta_line(raw, n)).find_map(|m| {
            let pieces: Vec<&str> =
                if matches!(m.key, "units" | "text") { m.value.split(',').collect() } else { vec![m.value] };
            let mut at = 0;
            pieces.into_iter().find_map(|piece| {
                let found = (piece.len() > MAX_LABEL_BYTES).then(|| {
                    (
                        m.line,
                        m.column + m.value[..at].chars().count(),
                        piece.len(),
                        "a name or value in a `# key:` line",
                    )
                });
                at += piece.len() + 1;
                found
            })
        });
        let long_name = header.as_ref().and_then(|&(n, raw)| {
            let mut at = 0;
            raw.split([',', ';']).find_map(|cell| {
                let found = (cell.len() > MAX_LABEL_BYTES).then_some(at);
                at += cell.len() + 1;
                found.map(|at| (n, column_of(raw, at), cell.len(), "a column name"))
            })
        });
        if let Some((n, column, len, what)) = long_meta.or(long_name) {
            return Err(FormatError::Expected {
                at: Loc::new(path, n, column),
                expected: format!("{what} of at most {MAX_LABEL_BYTES} bytes"),
                found: format!("{len} bytes"),
            });
        }
        let Some((line, raw)) = header else {
            return Ok(Sheet { text, header: None, header_width: 0, rows_at: text.len(), semicolons: false });
        };
        let semicolons = forms != Forms::Plain && raw.contains(';') && !raw.contains(',');
        let lower = forms == Forms::SpreadsheetHeader && raw.bytes().any(|b| b.is_ascii_uppercase());
        let sep = if semicolons { b';' } else { b',' };
        let header_width = raw.bytes().filter(|b| *b == sep).count() + 1;
        Ok(Sheet { text, header: Some((line, rewrite(raw, semicolons, lower))), header_width, rows_at, semicolons })
    }

    /// The `# key: value` lines, wherever they are in the file.
    fn meta(&self) -> impl Iterator<Item = Meta<'a>> + use<'a> {
        numbered(self.text, 0, 1).filter_map(|(n, raw)| meta_line(raw, n))
    }

    /// The data rows after the header row, with their line numbers.
    fn rows(&self) -> impl Iterator<Item = (usize, Cow<'a, str>)> + use<'a> {
        let first = self.header.as_ref().map_or(1, |(l, _)| l + 1);
        let semicolons = self.semicolons;
        numbered(self.text, self.rows_at, first)
            .filter(|(_, raw)| is_data(raw))
            .map(move |(n, raw)| (n, rewrite(raw, semicolons, false)))
    }

    /// The number of the file's last line.
    fn last_line(&self) -> usize {
        numbered(self.text, 0, 1).count()
    }

    /// How many rows of at least `row_bytes` bytes each (with its line end) the text after
    /// the header row can hold, and no more than it has lines: a capacity the file's length
    /// vouches for.
    fn row_bound(&self, row_bytes: usize) -> usize {
        let rest = &self.text.as_bytes()[self.rows_at..];
        let lines = rest.iter().filter(|b| **b == b'\n').count() + 1;
        lines.min(rest.len() / row_bytes.max(1) + 1)
    }
}

/// The longest name or label a file may give (a channel name, a `# direction:`): it is written
/// into output headers, plot legends and messages.
pub const MAX_LABEL_BYTES: usize = 4096;

/// Cells of a line beyond which no reader looks: the widest header read, and one more to see
/// that a line is wider.
const CELLS_LOOKED_AT: usize = MAX_SWEEP_COLUMNS + MAX_COLUMNS + 2;

/// A line with a spreadsheet's form undone: with `semicolons`, `;` made `,` and `,` made `.`;
/// with `lower`, ASCII letters lowercased. Borrowed when nothing changes; a rewritten line
/// ends after [`CELLS_LOOKED_AT`] cells, so a line of millions of cells is not copied whole.
fn rewrite(raw: &str, semicolons: bool, lower: bool) -> Cow<'_, str> {
    if !semicolons && !lower {
        return Cow::Borrowed(raw);
    }
    let sep = if semicolons { b';' } else { b',' };
    let cut = raw.bytes().enumerate().filter(|(_, b)| *b == sep).nth(CELLS_LOOKED_AT).map_or(raw.len(), |(i, _)| i);
    Cow::Owned(
        raw[..cut]
            .chars()
            .map(|c| match c {
                ',' if semicolons => '.',
                ';' if semicolons => ',',
                c if lower => c.to_ascii_lowercase(),
                c => c,
            })
            .collect(),
    )
}

fn as_text<'a>(bytes: &'a [u8], path: &str) -> Result<&'a str, FormatError> {
    match std::str::from_utf8(bytes) {
        Ok(t) => Ok(t),
        Err(e) => {
            let before = &bytes[..e.valid_up_to()];
            let line = before.iter().filter(|b| **b == b'\n').count() + 1;
            let line_start = before.iter().rposition(|b| *b == b'\n').map_or(0, |p| p + 1);
            let column = String::from_utf8_lossy(&before[line_start..]).chars().count() + 1;
            Err(FormatError::Expected {
                at: Loc::new(path, line, column),
                expected: "UTF-8 text".into(),
                found: format!("the byte 0x{:02x}", bytes[e.valid_up_to()]),
            })
        }
    }
}

/// The cells of a header row, trimmed, at most `max` of them; a wider row is an error that
/// counts its cells (`width`, as written) and says what to do (`what` names the columns,
/// `help` the remedy).
fn header_cells<'h>(
    (line, raw): (usize, &'h str),
    width: usize,
    path: &str,
    max: usize,
    what: &str,
    help: &str,
) -> Result<Vec<(usize, &'h str)>, FormatError> {
    let mut out = Vec::new();
    for (at, cell) in cells(raw) {
        if out.len() == max {
            return Err(FormatError::Unsupported {
                at: Loc::new(path, line, column_of(raw, at)),
                message: format!("the header row has {width} columns; at most {max} {what} are read: {help}"),
            });
        }
        out.push((at, cell));
    }
    Ok(out)
}

fn column_of(line: &str, byte: usize) -> usize {
    line[..byte].chars().count() + 1
}

/// The cells of a row with the byte offset where each (trimmed) cell starts.
fn cells(line: &str) -> impl Iterator<Item = (usize, &str)> {
    let mut start = 0;
    line.split(',').map(move |cell| {
        let lead = cell.len() - cell.trim_start().len();
        let at = start + lead;
        start += cell.len() + 1;
        (at, cell.trim())
    })
}

/// Parses one data row of exactly `names.len()` numeric cells into `row` (a ragged row is an
/// error naming the line and the expected `columns`).
fn fixed_row(
    row: &mut [f64],
    names: &[&str],
    columns: &str,
    path: &str,
    line: usize,
    raw: &str,
) -> Result<(), FormatError> {
    fixed_row_after(row, names, columns, path, line, raw, 0)
}

/// [`fixed_row`] after `skip` leading cells (a swept file's sweep coordinates), which are
/// not numbers of the row; columns in messages still count from the start of the line.
fn fixed_row_after(
    row: &mut [f64],
    names: &[&str],
    columns: &str,
    path: &str,
    line: usize,
    raw: &str,
    skip: usize,
) -> Result<(), FormatError> {
    let mut k = 0;
    // A row is counted no further than one cell past the widest header read.
    for (at, cell) in cells(raw).skip(skip).take(MAX_COLUMNS + 1) {
        if k < names.len() {
            row[k] = number(cell, path, line, raw, at, || format!("column `{}`", names[k]))?;
        }
        k += 1;
    }
    if k != names.len() {
        return Err(FormatError::Ragged {
            at: Loc::new(path, line, 0),
            found: k,
            expected: names.len(),
            columns: columns.into(),
        });
    }
    Ok(())
}

/// The number in a cell; `what` names its column for an error (built only then).
fn number(
    text: &str,
    path: &str,
    line: usize,
    raw: &str,
    at: usize,
    what: impl Fn() -> String,
) -> Result<f64, FormatError> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(FormatError::NonFinite {
            at: Loc::new(path, line, column_of(raw, at)),
            text: shown_cell(text),
            what: what(),
        }),
        Err(_) => Err(FormatError::Expected {
            at: Loc::new(path, line, column_of(raw, at)),
            expected: format!("a number in {}", what()),
            found: if text.is_empty() { "an empty cell".into() } else { format!("`{}`", shown_cell(text)) },
        }),
    }
}

/// A header value: a number with an optional unit of `dim` (a plain number is taken as SI).
fn quantity(m: &Meta, dim: Dimension, example: &str, path: &str) -> Result<f64, FormatError> {
    let err = |found: String| FormatError::Expected {
        at: Loc::new(path, m.line, m.column),
        expected: format!("a number with a unit of {} (e.g. `{example}`) after `# {}:`", dim.describe(), m.key),
        found,
    };
    let (num, unit) = match m.value.split_once(char::is_whitespace) {
        Some((n, u)) => (n, u.trim()),
        None => (m.value, ""),
    };
    let v: f64 = num.parse().map_err(|_| err(format!("`{}`", shown_cell(m.value))))?;
    if !v.is_finite() {
        return Err(FormatError::NonFinite {
            at: Loc::new(path, m.line, m.column),
            text: shown_cell(num),
            what: format!("`# {}`", m.key),
        });
    }
    if unit.is_empty() {
        return Ok(v);
    }
    match grammar::parse_unit(unit) {
        Ok(u) if u.dim == dim => Ok(if u.scale == 1.0 { v } else { v * u.scale }),
        _ => Err(err(format!("`{}`", shown_cell(m.value)))),
    }
}

/// Reads a time series written as [`write_time_series`] writes it. Header lines may come in
/// any order and other `#` lines are comments; the sample rate is required, `t0` defaults
/// to 0 and a channel missing from `# units` has no unit. Units are brought to SI.
pub fn read_time_series(bytes: &[u8], path: &str) -> Result<TimeSeries, FormatError> {
    let sheet = Sheet::open(bytes, path, Forms::Spreadsheet)?;
    let mut sample_rate = None;
    let mut t0 = 0.0;
    // The `# units` line and its `(channel, unit, column)` entries.
    let mut units: Option<(Meta, Vec<UnitEntry>)> = None;
    for m in sheet.meta() {
        match m.key {
            "sample_rate" => {
                let fs = quantity(&m, Dimension::FREQUENCY, "100000 Hz", path)?;
                if fs <= 0.0 {
                    return Err(FormatError::Expected {
                        at: Loc::new(path, m.line, m.column),
                        expected: "a positive sample rate".into(),
                        found: format!("`{}`", shown_cell(m.value)),
                    });
                }
                sample_rate = Some(fs);
            }
            "t0" => t0 = quantity(&m, Dimension::TIME, "-0.001 s", path)?,
            "units" => {
                let list = unit_entries(&m, path)?;
                units = Some((m, list));
            }
            _ => {}
        }
    }
    let Some((hline, hraw)) = &sheet.header else {
        return Err(FormatError::Expected {
            at: Loc::new(path, sheet.last_line(), 0),
            expected: "a row of channel names".into(),
            found: "only `#` lines".into(),
        });
    };
    let hline = *hline;
    let Some(sample_rate) = sample_rate else {
        return Err(FormatError::MissingSampleRate { at: Loc::new(path, 0, 0) });
    };
    let header = header_cells(
        (hline, hraw),
        sheet.header_width,
        path,
        MAX_COLUMNS,
        "channels",
        "split the recording into files of fewer channels, or keep the channels the recipe reads",
    )?;
    // Names by position, and positions by name: each name is looked up once.
    let mut names: Vec<&str> = Vec::with_capacity(header.len());
    let mut index: HashMap<&str, usize> = HashMap::with_capacity(header.len());
    for (at, cell) in header {
        let name = cell.trim_matches('"');
        if name.is_empty() {
            return Err(FormatError::Expected {
                at: Loc::new(path, hline, column_of(hraw, at)),
                expected: "a channel name".into(),
                found: "an empty cell".into(),
            });
        }
        // A name travels into output headers, plot legends and messages: a control character
        // (a tab, an escape) would break the files written from it or drive a terminal.
        if let Some(c) = name.chars().find(|c| c.is_control()) {
            return Err(FormatError::Expected {
                at: Loc::new(path, hline, column_of(hraw, at)),
                expected: "a channel name of printable characters".into(),
                found: format!("the control character {}", c.escape_unicode()),
            });
        }
        if index.insert(name, names.len()).is_some() {
            return Err(FormatError::ChannelMismatch {
                at: Loc::new(path, hline, column_of(hraw, at)),
                message: format!("channel `{name}` appears twice in the header row"),
            });
        }
        names.push(name);
    }
    let mut unit_of: Vec<&str> = vec![""; names.len()];
    if let Some((m, list)) = &units {
        for &(name, unit, col) in list {
            match index.get(name) {
                Some(&k) => unit_of[k] = unit,
                None => {
                    return Err(FormatError::ChannelMismatch {
                        at: Loc::new(path, m.line, col),
                        message: format!(
                            "`# units` names channel `{name}`, which the header row (line {hline}) does not have: {}",
                            super::listed(&names, ", ")
                        ),
                    });
                }
            }
        }
        if list.len() != names.len() {
            return Err(FormatError::ChannelMismatch {
                at: Loc::new(path, m.line, m.column),
                message: format!(
                    "`# units` gives {} channel(s), the header row (line {hline}) has {}: {}",
                    list.len(),
                    names.len(),
                    super::listed(&names, ", ")
                ),
            });
        }
    }
    let mut rows = sheet.rows().peekable();
    if rows.peek().is_none() {
        return Err(FormatError::Expected {
            at: Loc::new(path, sheet.last_line() + 1, 0),
            expected: "rows of samples after the channel names".into(),
            found: "the end of the file".into(),
        });
    }
    // A row of n channels takes at least 2n bytes (`1,` per cell, a line end for the last).
    let capacity = sheet.row_bound(2 * names.len());
    let mut samples: Vec<Vec<f64>> = (0..names.len()).map(|_| Vec::with_capacity(capacity)).collect();
    for (line, raw) in rows {
        let mut n = 0;
        for (at, cell) in cells(&raw).take(MAX_COLUMNS + 1) {
            if n < names.len() {
                samples[n].push(number(cell, path, line, &raw, at, || format!("channel `{}`", names[n]))?);
            }
            n += 1;
        }
        if n != names.len() {
            return Err(FormatError::Ragged {
                at: Loc::new(path, line, 0),
                found: n,
                expected: names.len(),
                columns: format!("one per channel: {}", super::listed(&names, ", ")),
            });
        }
    }
    let channels = names
        .into_iter()
        .zip(unit_of)
        .zip(samples)
        .map(|((name, unit), mut samples)| {
            let (scale, symbol) = unit_to_si(unit, None);
            if scale != 1.0 {
                samples.iter_mut().for_each(|v| *v *= scale);
            }
            Channel { name: name.to_string(), unit: UnitLabel::new(symbol), samples }
        })
        .collect();
    Ok(TimeSeries { sample_rate, t0, channels })
}

/// The `channel=unit` entries of a `# units:` line, each with the column where it starts; at
/// most [`MAX_COLUMNS`] of them.
fn unit_entries<'a>(m: &Meta<'a>, path: &str) -> Result<Vec<UnitEntry<'a>>, FormatError> {
    let mut list = Vec::new();
    // Characters before the current item, counted as the items pass: linear in the line.
    let mut chars_before = 0;
    for item in m.value.split(',') {
        let col = m.column + chars_before + (item.len() - item.trim_start().len());
        chars_before += item.chars().count() + 1;
        let item = item.trim();
        if item.is_empty() {
            continue;
        }
        let at = Loc::new(path, m.line, col);
        if list.len() == MAX_COLUMNS {
            return Err(FormatError::Unsupported {
                at,
                message: format!(
                    "`# units` lists more than {MAX_COLUMNS} channels, the most a time series is read with: \
                     split the recording into files of fewer channels"
                ),
            });
        }
        let Some((name, unit)) = item.split_once('=') else {
            return Err(FormatError::Expected {
                at,
                expected: "`channel=unit` in `# units:`".into(),
                found: format!("`{}`", shown_cell(item)),
            });
        };
        list.push((name.trim(), unit.trim(), col));
    }
    Ok(list)
}

/// A cell's text for a message, cut to 80 characters.
pub(crate) fn shown_cell(text: &str) -> String {
    let mut chars = text.chars();
    let head: String = chars.by_ref().take(80).collect();
    if chars.next().is_some() { format!("{head}…") } else { head }
}

/// One sweep point of a swept FRF file (as a swept output writes it): the sweep coordinates
/// as written (`("speed_rpm", "1500")`, `("direction", "x")`) and its FRF.
#[derive(Debug, Clone, PartialEq)]
pub struct FrfBlock {
    pub coords: Vec<(String, String)>,
    pub frf: Frf,
}

/// Reads an FRF file: `freq_hz,real,imag[,coherence]`, led by sweep-coordinate columns when a
/// swept output wrote it. Each run of rows with the same coordinates is one block; a
/// `direction` or `speed_rpm` coordinate gives the block's direction or speed.
pub fn read_frf_blocks(bytes: &[u8], path: &str) -> Result<Vec<FrfBlock>, FormatError> {
    let sheet = Sheet::open(bytes, path, Forms::SpreadsheetHeader)?;
    let mut unit = (1.0, String::new());
    let mut direction = None;
    let mut speed = None;
    let mut sensor = None;
    let (mut response, mut reference) = (None, None);
    let mut point_line = None;
    for m in sheet.meta() {
        match m.key {
            "units" => unit = frf_unit(&m, path)?,
            "direction" if !m.value.is_empty() => direction = Some(m.value.to_string()),
            "sensor" if !m.value.is_empty() => sensor = Some(m.value.to_string()),
            "speed_rpm" => speed = Some(speed_rpm(&m, path)?),
            "response" => {
                response = Some(node_point(&m, path)?);
                point_line = Some(m.line);
            }
            "reference" => {
                reference = Some(node_point(&m, path)?);
                point_line = Some(m.line);
            }
            _ => {}
        }
    }
    let dofs = match (response, reference) {
        (Some((rn, rd)), Some((fn_, fd))) => Some(crate::value::FrfDofs {
            response_node: rn,
            response_direction: rd,
            reference_node: fn_,
            reference_direction: fd,
        }),
        (None, None) => None,
        _ => {
            return Err(FormatError::Expected {
                at: Loc::new(path, point_line.unwrap_or(0), 1),
                expected: "both `# response: NODE AXIS` and `# reference: NODE AXIS`".into(),
                found: "only one of them".into(),
            });
        }
    };
    let Some((hline, hraw)) = &sheet.header else {
        return Err(FormatError::Expected {
            at: Loc::new(path, sheet.last_line(), 0),
            expected: "the header row `freq_hz,real,imag[,coherence]`".into(),
            found: "only `#` lines".into(),
        });
    };
    let hline = *hline;
    let help = format!(
        "an FRF file has the columns `freq_hz,real,imag[,coherence]`, after at most {MAX_SWEEP_COLUMNS} sweep columns"
    );
    let header: Vec<&str> =
        header_cells((hline, hraw), sheet.header_width, path, MAX_SWEEP_COLUMNS + 4, "columns", &help)?
            .into_iter()
            .map(|(_, c)| c)
            .collect();
    let lead = header.iter().position(|h| *h == "freq_hz").unwrap_or(0);
    let with_coherence = match &header[lead..] {
        ["freq_hz", "real", "imag"] => false,
        ["freq_hz", "real", "imag", "coherence"] => true,
        _ => {
            return Err(FormatError::Expected {
                at: Loc::new(path, hline, 1),
                expected: "the header row `freq_hz,real,imag` or `freq_hz,real,imag,coherence` (after sweep columns in a swept file)".into(),
                found: shown_header(hraw),
            });
        }
    };
    let mut rows = sheet.rows().peekable();
    if rows.peek().is_none() {
        return Err(FormatError::Expected {
            at: Loc::new(path, sheet.last_line() + 1, 0),
            expected: "rows of `freq_hz,real,imag` values after the header row".into(),
            found: "the end of the file".into(),
        });
    }
    let names: &[&str] =
        if with_coherence { &["freq_hz", "real", "imag", "coherence"] } else { &["freq_hz", "real", "imag"] };
    let columns = names.join(",");
    let (scale, symbol) = unit;
    // A file of one FRF (no sweep columns) reserves its rows, as many as its length can hold
    // (`1,2,3` and a line end per row); a swept file's blocks grow as they are read.
    let capacity = if lead == 0 { sheet.row_bound(2 * names.len()) } else { 0 };
    let mut blocks: Vec<FrfBlock> = Vec::new();
    let mut row = [0.0; 4];
    for (line, raw) in rows {
        fixed_row_after(&mut row, names, &columns, path, line, &raw, lead)?;
        let same = blocks.last().is_some_and(|b| {
            b.coords.iter().zip(cells(&raw)).all(|((_, v), (_, c))| c.trim_matches('"') == v.as_str())
        });
        if !same {
            if blocks.len() == MAX_SWEEP_POINTS {
                return Err(FormatError::Unsupported {
                    at: Loc::new(path, line, 1),
                    message: format!(
                        "more than {MAX_SWEEP_POINTS} sweep points (runs of rows with the same sweep columns); \
                         split the file"
                    ),
                });
            }
            let coords: Vec<(String, String)> = header[..lead]
                .iter()
                .zip(cells(&raw))
                .map(|(h, (_, c))| (h.to_string(), c.trim_matches('"').to_string()))
                .collect();
            let of = |key: &str| coords.iter().find(|(k, _)| k == key).map(|(_, v)| v.clone());
            let block_speed = match of("speed_rpm") {
                Some(v) => Some(
                    v.parse::<f64>()
                        .ok()
                        .filter(|s| s.is_finite())
                        .ok_or_else(|| FormatError::Expected {
                            at: Loc::new(path, line, 1),
                            expected: "a finite speed in rpm in column `speed_rpm`".into(),
                            found: format!("`{}`", shown_cell(&v)),
                        })
                        .map(Speed::from_rpm)?,
                ),
                None => speed,
            };
            let reserve = if blocks.is_empty() { capacity } else { 0 };
            blocks.push(FrfBlock {
                frf: Frf {
                    freq_hz: Vec::with_capacity(reserve),
                    values: Vec::with_capacity(reserve),
                    coherence: with_coherence.then(|| Vec::with_capacity(reserve)),
                    unit: UnitLabel::new(symbol.clone()),
                    direction: of("direction").or_else(|| direction.clone()),
                    speed: block_speed,
                    sensor: sensor.clone(),
                    dofs,
                },
                coords,
            });
        }
        let f = &mut blocks.last_mut().expect("pushed").frf;
        if let Some(why) = super::frequency_problem(f.freq_hz.last().copied(), row[0]) {
            return Err(FormatError::Expected {
                at: Loc::new(path, line, 1 + lead),
                expected: why.into(),
                found: format!("{:?} Hz", row[0]),
            });
        }
        if with_coherence && !(0.0..=1.0).contains(&row[3]) {
            return Err(FormatError::Expected {
                at: Loc::new(path, line, 4 + lead),
                expected: "a coherence between 0 and 1".into(),
                found: format!("{:?}", row[3]),
            });
        }
        f.freq_hz.push(row[0]);
        f.values.push(Complex64::new(row[1], row[2]) * scale);
        if let Some(c) = f.coherence.as_mut() {
            c.push(row[3]);
        }
    }
    Ok(blocks)
}

/// The unit of an FRF file's values from its `# units:` line: the factor to SI and the SI
/// label (see [`super::frf_unit`]); a unit of another dimension is an error at its column.
fn frf_unit(m: &Meta, path: &str) -> Result<(f64, String), FormatError> {
    super::frf_unit(m.value).map_err(|why| FormatError::Unsupported {
        at: Loc::new(path, m.line, m.column),
        message: format!("`# units:` {why}; the values of an FRF are {}", super::FRF_UNIT_EXPECTED),
    })
}

/// Reads an FRF file that holds one FRF (see [`read_frf_blocks`] for swept files).
pub fn read_frf(bytes: &[u8], path: &str) -> Result<Frf, FormatError> {
    let mut blocks = read_frf_blocks(bytes, path)?;
    if blocks.len() > 1 {
        return Err(FormatError::Selection {
            path: path.to_string(),
            message: format!(
                "the file holds {} sweep points ({} …); read one with `dataset: K`, counting from 1",
                blocks.len(),
                block_names(&blocks[..blocks.len().min(3)]).join("; ")
            ),
        });
    }
    Ok(blocks.pop().expect("at least one row").frf)
}

/// Sweep coordinates as written: `(column, value)` pairs.
pub type Coords = Vec<(String, String)>;

/// The sweep points a partial output lacks, as its `# missing:` lines give them (label and
/// reason), in file order: a swept output written with `--keep-going` after some of its
/// instances failed.
pub fn missing_points(bytes: &[u8]) -> Vec<String> {
    let text = String::from_utf8_lossy(bytes);
    numbered(&text, 0, 1)
        .filter_map(|(n, raw)| meta_line(raw, n).filter(|m| m.key == "missing").map(|m| m.value.to_string()))
        .collect()
}

/// One sweep point of a numeric table file: the sweep coordinates as written, then the
/// table's own columns.
#[derive(Debug, Clone, PartialEq)]
pub struct TableBlock {
    pub coords: Vec<(String, String)>,
    pub table: Table,
}

/// Reads a table as a table output writes it: `# units: name=unit, …`, a header whose last
/// columns are the table's (led by sweep columns in a swept file), numeric rows (`NaN`,
/// `inf` allowed: a trial outside a diagram, a lobe that limits nothing), words in the
/// columns `# text:` names. Without a units line every column is the table's, with no unit.
pub fn read_tables(bytes: &[u8], path: &str) -> Result<Vec<TableBlock>, FormatError> {
    let sheet = Sheet::open(bytes, path, Forms::Plain)?;
    let mut units: Vec<(&str, &str)> = Vec::new();
    for m in sheet.meta().filter(|m| m.key == "units") {
        for pair in m.value.split(", ").filter(|p| !p.is_empty()) {
            let Some((name, unit)) = pair.split_once('=') else {
                return Err(FormatError::Expected {
                    at: Loc::new(path, m.line, m.column),
                    expected: "`name=unit` pairs after `# units:`".into(),
                    found: format!("`{}`", shown_cell(pair)),
                });
            };
            if units.len() == MAX_COLUMNS {
                return Err(FormatError::Unsupported {
                    at: Loc::new(path, m.line, m.column),
                    message: format!("`# units:` names more than {MAX_COLUMNS} columns, the most a table is read with"),
                });
            }
            units.push((name.trim(), unit.trim()));
        }
    }
    let Some((hline, hraw)) = &sheet.header else {
        return Err(FormatError::Expected {
            at: Loc::new(path, sheet.last_line(), 0),
            expected: "a header row of column names".into(),
            found: "only `#` lines".into(),
        });
    };
    let hline = *hline;
    let header: Vec<&str> = header_cells(
        (hline, hraw),
        sheet.header_width,
        path,
        MAX_COLUMNS + MAX_SWEEP_COLUMNS,
        "columns",
        "split the table into files of fewer columns",
    )?
    .into_iter()
    .map(|(_, c)| c)
    .collect();
    if units.is_empty() {
        units = header.iter().map(|h| (*h, "")).collect();
    }
    let Some(lead) = header.len().checked_sub(units.len()) else {
        return Err(FormatError::Expected {
            at: Loc::new(path, hline, 1),
            expected: format!("at least the {} columns the `# units:` line names", units.len()),
            found: shown_header(hraw),
        });
    };
    if lead > MAX_SWEEP_COLUMNS {
        return Err(FormatError::Unsupported {
            at: Loc::new(path, hline, 1),
            message: format!(
                "{lead} sweep columns lead the table's own; at most {MAX_SWEEP_COLUMNS} are read: \
                 name every column of the table in `# units:`"
            ),
        });
    }
    let names: Vec<&str> = units.iter().map(|(n, _)| *n).collect();
    // Text columns, as `# text:` names them: their cells are words, not numbers.
    let mut text = vec![false; names.len()];
    for m in sheet.meta().filter(|m| m.key == "text") {
        for name in m.value.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            let Some(k) = names.iter().position(|n| *n == name) else {
                return Err(FormatError::Expected {
                    at: Loc::new(path, m.line, m.column),
                    expected: "the names of columns `# units:` lists after `# text:`".into(),
                    found: format!("`{}`", shown_cell(name)),
                });
            };
            text[k] = true;
        }
    }
    let columns = super::listed(&header[lead..], ",");
    let mut blocks: Vec<TableBlock> = Vec::new();
    let mut row = vec![0.0; names.len()];
    let mut words: Vec<String> = vec![String::new(); names.len()];
    for (line, raw) in sheet.rows() {
        // Cells of the table itself; non-finite numbers are values here.
        let mut k = 0;
        for (_, cell) in cells(&raw).skip(lead).take(MAX_COLUMNS + 1) {
            if k < names.len() && text[k] {
                words[k].clear();
                words[k].push_str(cell);
            } else if k < names.len() {
                row[k] = cell.parse::<f64>().map_err(|_| FormatError::Expected {
                    at: Loc::new(path, line, 0),
                    expected: format!("a number in column `{}`", names[k]),
                    found: if cell.is_empty() { "an empty cell".into() } else { format!("`{}`", shown_cell(cell)) },
                })?;
            }
            k += 1;
        }
        if k != names.len() {
            return Err(FormatError::Ragged { at: Loc::new(path, line, 0), found: k, expected: names.len(), columns });
        }
        let same = blocks.last().is_some_and(|b| {
            b.coords.iter().zip(cells(&raw)).all(|((_, v), (_, c))| c.trim_matches('"') == v.as_str())
        });
        if !same {
            if blocks.len() == MAX_SWEEP_POINTS {
                return Err(FormatError::Unsupported {
                    at: Loc::new(path, line, 1),
                    message: format!(
                        "more than {MAX_SWEEP_POINTS} sweep points (runs of rows with the same sweep columns); \
                         split the file"
                    ),
                });
            }
            let coords: Vec<(String, String)> = header[..lead]
                .iter()
                .zip(cells(&raw))
                .map(|(h, (_, c))| (h.to_string(), c.trim_matches('"').to_string()))
                .collect();
            let table =
                Table { columns: units.iter().map(|&(n, u)| crate::value::Column::new(n, u, Vec::new())).collect() };
            blocks.push(TableBlock { coords, table });
        }
        let t = &mut blocks.last_mut().expect("pushed").table;
        for (k, c) in t.columns.iter_mut().enumerate() {
            if text[k] {
                let i = c.levels.iter().position(|l| *l == words[k]).unwrap_or_else(|| {
                    c.levels.push(words[k].clone());
                    c.levels.len() - 1
                });
                c.values.push(i as f64);
            } else {
                c.values.push(row[k]);
            }
        }
    }
    Ok(blocks)
}

/// Reads lobes as a lobes output writes them (`speed_rpm,depth_limit_m,chatter_hz`, led by
/// sweep columns in a swept file), one per sweep point.
pub fn read_lobes(bytes: &[u8], path: &str) -> Result<Vec<(Coords, Lobes)>, FormatError> {
    let blocks = read_tables(bytes, path)?;
    blocks
        .into_iter()
        .map(|b| {
            let names: Vec<&str> = b.table.columns.iter().map(|c| c.name.as_str()).collect();
            let n = names.len();
            if n < 3 || names[n - 3..] != ["speed_rpm", "depth_limit_m", "chatter_hz"] {
                return Err(FormatError::Expected {
                    at: Loc::new(path, 0, 0),
                    expected: format!("the header `{LOBES_HEADER}`"),
                    found: format!("`{}`", super::listed(&names, ",")),
                });
            }
            let col = |i: usize| b.table.columns[n - 3 + i].values.clone();
            // Columns before the lobes' own are sweep coordinates of an older layout.
            Ok((
                b.coords,
                Lobes {
                    speed: col(0).into_iter().map(Speed::from_rpm).collect(),
                    depth_limit: col(1),
                    chatter_hz: col(2),
                },
            ))
        })
        .collect()
}

/// Reads scalars as a scalar output writes them (`value_UNIT`, one row per sweep point):
/// each with its sweep coordinates and its unit.
pub fn read_scalars(bytes: &[u8], path: &str) -> Result<Vec<(Coords, f64, String)>, FormatError> {
    let mut out = Vec::new();
    for b in read_tables(bytes, path)? {
        let [c] = b.table.columns.as_slice() else {
            return Err(FormatError::Expected {
                at: Loc::new(path, 0, 0),
                expected: "one `value_UNIT` column".into(),
                found: format!("{} columns", b.table.columns.len()),
            });
        };
        for v in &c.values {
            out.push((b.coords.clone(), *v, c.unit.symbol.clone()));
        }
    }
    Ok(out)
}

/// Each block's coordinates as `name=value, …`.
pub fn block_names(blocks: &[FrfBlock]) -> Vec<String> {
    blocks
        .iter()
        .map(|b| super::listed(b.coords.iter().map(|(k, v)| format!("{}={}", shown_cell(k), shown_cell(v))), ", "))
        .collect()
}

/// A `# speed_rpm:` value.
/// A `# response:` or `# reference:` line: a node number and an axis (`3 x`; `x`, `y`, `z`,
/// `rx`, `ry`, `rz`, `scalar`), as the UFF direction code.
fn node_point(m: &Meta, path: &str) -> Result<(i64, i32), FormatError> {
    let mut parts = m.value.split_whitespace();
    let node = parts.next().and_then(|t| t.parse::<i64>().ok());
    let axis = parts.next().and_then(|t| match t {
        "scalar" => Some(0),
        t => Some(super::uff::direction_code(Some(t))).filter(|c| *c != 0),
    });
    match (node, axis, parts.next()) {
        (Some(n), Some(a), None) => Ok((n, a)),
        _ => Err(FormatError::Expected {
            at: Loc::new(path, m.line, m.column),
            expected: format!("a node number and an axis after `# {}:` (`3 x`; axes x, y, z, rx, ry, rz)", m.key),
            found: format!("`{}`", shown_cell(m.value)),
        }),
    }
}

fn speed_rpm(m: &Meta, path: &str) -> Result<Speed, FormatError> {
    let text = m.value.strip_suffix("rpm").unwrap_or(m.value).trim();
    let at = Loc::new(path, m.line, m.column);
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(Speed::from_rpm(v)),
        Ok(_) => Err(FormatError::NonFinite { at, text: shown_cell(text), what: "`# speed_rpm`".into() }),
        Err(_) => Err(FormatError::Expected {
            at,
            expected: "a speed in rpm after `# speed_rpm:`".into(),
            found: format!("`{}`", shown_cell(m.value)),
        }),
    }
}

/// The factors that bring each block of a receptance set to SI, from a `# units:` line
/// (`h=m/N, l=m/(N*m), n=rad/N, p=rad/(N*m)`; blocks left out are taken as SI).
fn receptance_units(m: &Meta, path: &str) -> Result<[f64; 4], FormatError> {
    let mut scale = [1.0; 4];
    // Characters before the current item, counted as the items pass: linear in the line.
    let mut chars_before = 0;
    for item in m.value.split(',') {
        let col = m.column + chars_before + (item.len() - item.trim_start().len());
        chars_before += item.chars().count() + 1;
        let item = item.trim();
        if item.is_empty() {
            continue;
        }
        let at = Loc::new(path, m.line, col);
        let expected = "`block=unit` with block h, l, n or p in `# units:` (e.g. `h=m/N`)";
        let found = || format!("`{}`", shown_cell(item));
        let Some((name, unit)) = item.split_once('=') else {
            return Err(FormatError::Expected { at, expected: expected.into(), found: found() });
        };
        let (name, unit) = (name.trim(), unit.trim());
        let Some(k) = BLOCKS.iter().position(|(n, _, _)| *n == name) else {
            return Err(FormatError::Expected { at, expected: expected.into(), found: found() });
        };
        let (_, si, dim) = BLOCKS[k];
        if unit == si || unit.is_empty() {
            continue;
        }
        scale[k] = match grammar::parse_unit(unit) {
            Ok(u) if u.dim == dim => u.scale,
            _ => {
                return Err(FormatError::Expected {
                    at,
                    expected: format!("a unit of {} for `{name}` (e.g. `{si}`)", dim.describe()),
                    found: format!("`{}`", shown_cell(unit)),
                });
            }
        };
    }
    Ok(scale)
}

/// Reads a 2×2 receptance set written as [`write_receptance`] writes it: header row
/// `freq_hz,h_re,h_im,l_re,l_im,n_re,n_im,p_re,p_im`; `# units`, `# direction` and
/// `# speed_rpm` are optional and in any order. Units are brought to SI.
pub fn read_receptance(bytes: &[u8], path: &str) -> Result<ReceptanceSet, FormatError> {
    let sheet = Sheet::open(bytes, path, Forms::SpreadsheetHeader)?;
    let mut scale = [1.0; 4];
    let mut direction = None;
    let mut speed = None;
    for m in sheet.meta() {
        match m.key {
            "units" => scale = receptance_units(&m, path)?,
            "direction" if !m.value.is_empty() => direction = Some(m.value.to_string()),
            "speed_rpm" => speed = Some(speed_rpm(&m, path)?),
            _ => {}
        }
    }
    let Some((hline, hraw)) = &sheet.header else {
        return Err(FormatError::Expected {
            at: Loc::new(path, sheet.last_line(), 0),
            expected: format!("the header row `{RECEPTANCE_HEADER}`"),
            found: "only `#` lines".into(),
        });
    };
    let names: Vec<&str> = RECEPTANCE_HEADER.split(',').collect();
    // Compared cell by cell, so a row of any width is looked at no further than it differs.
    let same = cells(hraw).map(|(_, c)| c).take(names.len() + 1).eq(names.iter().copied());
    if !same {
        return Err(FormatError::Expected {
            at: Loc::new(path, *hline, 1),
            expected: format!("the header row `{RECEPTANCE_HEADER}`"),
            found: shown_header(hraw),
        });
    }
    let mut rows = sheet.rows().peekable();
    if rows.peek().is_none() {
        return Err(FormatError::Expected {
            at: Loc::new(path, sheet.last_line() + 1, 0),
            expected: "rows of values after the header row".into(),
            found: "the end of the file".into(),
        });
    }
    // As many rows as the file's length can hold, of nine cells and a line end each.
    let n = sheet.row_bound(2 * names.len());
    let mut r = ReceptanceSet {
        freq_hz: Vec::with_capacity(n),
        h: Vec::with_capacity(n),
        l: Vec::with_capacity(n),
        n: Vec::with_capacity(n),
        p: Vec::with_capacity(n),
        direction,
        speed,
    };
    let mut row = [0.0; 9];
    for (line, raw) in rows {
        fixed_row(&mut row, &names, RECEPTANCE_HEADER, path, line, &raw)?;
        r.freq_hz.push(row[0]);
        r.h.push(Complex64::new(row[1], row[2]) * scale[0]);
        r.l.push(Complex64::new(row[3], row[4]) * scale[1]);
        r.n.push(Complex64::new(row[5], row[6]) * scale[2]);
        r.p.push(Complex64::new(row[7], row[8]) * scale[3]);
    }
    Ok(r)
}

/// A header row as an error shows it: quoted only when it looks like a CSV header (cells of
/// names), so a file that is not a data file at all (a password file named by mistake or on
/// purpose) never has its contents printed.
fn shown_header(raw: &str) -> String {
    let t = raw.trim();
    let names = t.contains(',')
        && t.split(',').all(|c| {
            let c = c.trim().trim_matches('"');
            !c.is_empty()
                && c.chars().all(|ch| ch.is_alphanumeric() || matches!(ch, '_' | ' ' | '-' | '.' | '(' | ')' | '/'))
        });
    if names {
        format!("`{}`", t.chars().take(120).collect::<String>())
    } else {
        format!("a line of {} characters that is not a CSV header row", t.chars().count())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn receptance_set() -> ReceptanceSet {
        let n = 60;
        let c = |i: usize, a: f64, b: f64| Complex64::new(a / (i as f64 + 3.0), -b * (i as f64).sqrt() / 7.0);
        ReceptanceSet {
            freq_hz: (1..=n).map(|i| i as f64 * 24.414_062_5).collect(),
            h: (0..n).map(|i| c(i, 1e-7, 3e-8)).collect(),
            l: (0..n).map(|i| c(i, 1e-6, -2e-7)).collect(),
            n: (0..n).map(|i| c(i, -1e-6, 2e-7)).collect(),
            p: (0..n).map(|i| c(i, 1e-5, 1e-6)).collect(),
            direction: Some("y".into()),
            speed: Some(Speed::from_rpm(12_345.678_9)),
        }
    }

    #[test]
    fn receptance_set_round_trips_bit_for_bit() {
        let r = receptance_set();
        let text = write_receptance(&r);
        assert!(text.contains("# units: h=m/N, l=m/(N*m), n=rad/N, p=rad/(N*m)\n"), "{text}");
        assert_eq!(read_receptance(text.as_bytes(), "r.csv").unwrap(), r);
        let bare = ReceptanceSet { direction: None, speed: None, ..r };
        assert_eq!(read_receptance(write_receptance(&bare).as_bytes(), "r.csv").unwrap(), bare);
    }

    #[test]
    fn receptance_units_come_to_si_and_bad_files_name_the_place() {
        let text = "# units: h=um/N\nfreq_hz,h_re,h_im,l_re,l_im,n_re,n_im,p_re,p_im\n10,2,-4,1,0,1,0,1,0\n";
        let r = read_receptance(text.as_bytes(), "r.csv").unwrap();
        assert_eq!(r.h[0], Complex64::new(2e-6, -4e-6));
        assert_eq!(r.l[0], Complex64::new(1.0, 0.0));
        let e = read_receptance(
            b"# units: h=N\nfreq_hz,h_re,h_im,l_re,l_im,n_re,n_im,p_re,p_im\n1,0,0,0,0,0,0,0,0\n",
            "r.csv",
        )
        .unwrap_err();
        assert_eq!(e.line_column(), (1, 10), "{e}");
        let e = read_receptance(b"freq_hz,real,imag\n1,2,3\n", "r.csv").unwrap_err();
        assert_eq!(e.line_column(), (1, 1), "{e}");
        let e = read_receptance(b"freq_hz,h_re,h_im,l_re,l_im,n_re,n_im,p_re,p_im\n1,0,0,0,0,0,0,0\n", "r.csv")
            .unwrap_err();
        assert!(matches!(e, FormatError::Ragged { found: 8, expected: 9, .. }), "{e}");
        let e = read_receptance(b"freq_hz,h_re,h_im,l_re,l_im,n_re,n_im,p_re,p_im\n1,0,0,0,inf,0,0,0,0\n", "r.csv")
            .unwrap_err();
        assert!(matches!(e, FormatError::NonFinite { .. }), "{e}");
        assert_eq!(e.line_column(), (2, 9));
    }

    fn series() -> TimeSeries {
        // Values chosen to need all 17 digits: a lossy writer would not read back bit for bit.
        let force: Vec<f64> = (0..50).map(|i| (i as f64 * 0.37).sin() * 123.456_789_012_345_67 + 1e-300).collect();
        let resp: Vec<f64> = (0..50).map(|i| -(i as f64 / 7.0).exp() * 1.234_567_890_123_456_7e-7).collect();
        TimeSeries {
            sample_rate: 102_400.0 / 3.0,
            t0: -0.001 / 3.0,
            channels: vec![
                Channel { name: "force".into(), unit: UnitLabel::new("N"), samples: force },
                Channel { name: "response".into(), unit: UnitLabel::new("m"), samples: resp },
            ],
        }
    }

    #[test]
    fn time_series_round_trips_bit_for_bit() {
        let ts = series();
        let text = write_time_series(&ts);
        assert!(text.starts_with("# sample_rate: "), "{text}");
        let back = read_time_series(text.as_bytes(), "t.csv").unwrap();
        assert_eq!(back.sample_rate.to_bits(), ts.sample_rate.to_bits());
        assert_eq!(back.t0.to_bits(), ts.t0.to_bits());
        assert_eq!(back, ts);
    }

    #[test]
    fn time_series_header_lines_in_any_order_with_comments_and_units_to_si() {
        let text = "# measured on rig 2\n# units: f=kN, x=mm\n# t0: 2 ms\n#\n# sample_rate: 10 kHz\nf,x\n1,2\n3,4\n";
        let ts = read_time_series(text.as_bytes(), "t.csv").unwrap();
        assert_eq!(ts.sample_rate, 10_000.0);
        assert_eq!(ts.t0, 0.002);
        assert_eq!(ts.channels[0].unit.symbol, "N");
        assert_eq!(ts.channels[0].samples, [1000.0, 3000.0]);
        assert_eq!(ts.channels[1].unit.symbol, "m");
        assert_eq!(ts.channels[1].samples, [0.002, 0.004]);
    }

    #[test]
    fn frf_round_trips_bit_for_bit_with_all_header_fields() {
        let n = 40;
        let frf = Frf {
            freq_hz: (0..n).map(|i| i as f64 * 24.414_062_5).collect(),
            values: (0..n).map(|i| Complex64::new(1.0 / (i as f64 + 3.0), -(i as f64).sqrt() * 1e-7 / 3.0)).collect(),
            coherence: Some((0..n).map(|i| 1.0 - 1.0 / (i as f64 + 7.0)).collect()),
            unit: UnitLabel::new("m/N"),
            direction: Some("y".into()),
            speed: Some(Speed::from_rpm(12_345.678_9)),
            sensor: Some("laser 1".into()),
            dofs: None,
        };
        let back = read_frf(write_frf(&frf).as_bytes(), "f.csv").unwrap();
        assert_eq!(back, frf);
        let bare = Frf { coherence: None, direction: None, speed: None, sensor: None, ..frf };
        assert_eq!(read_frf(write_frf(&bare).as_bytes(), "f.csv").unwrap(), bare);
    }

    fn err(text: &str) -> FormatError {
        read_time_series(text.as_bytes(), "bad.csv").unwrap_err()
    }

    #[test]
    fn bad_time_series_files_name_the_place() {
        assert!(matches!(err(""), FormatError::Empty { .. }));
        assert!(matches!(err(" \n\n"), FormatError::Empty { .. }));
        let e = err("# t0: 0 s\na,b\n1,2\n");
        assert!(matches!(e, FormatError::MissingSampleRate { .. }), "{e}");
        assert!(e.to_string().contains("sample_rate"), "{e}");

        let e = err("# sample_rate: 1000 Hz\na,b\n1,2\n3\n");
        assert!(matches!(e, FormatError::Ragged { found: 1, expected: 2, .. }), "{e}");
        assert_eq!(e.line_column(), (4, 0));

        let e = err("# sample_rate: 1000 Hz\na,b\n1,2\n3, 4x\n");
        assert!(matches!(e, FormatError::Expected { .. }), "{e}");
        assert_eq!(e.line_column(), (4, 4));
        assert!(e.to_string().starts_with("bad.csv:4:4: expected a number in channel `b`"), "{e}");

        let e = err("# sample_rate: 1000 Hz\na,b\n1,2\n3,NaN\n");
        assert!(matches!(e, FormatError::NonFinite { .. }), "{e}");
        assert_eq!(e.line_column(), (4, 3));
        assert!(e.to_string().contains("NaN samples"), "{e}");
        assert!(matches!(err("# sample_rate: 1000 Hz\na\ninf\n"), FormatError::NonFinite { .. }));

        let e = err("# sample_rate: 1000 Hz\n# units: a=N, b=m, c=m\na,b\n1,2\n");
        assert!(matches!(e, FormatError::ChannelMismatch { .. }), "{e}");
        assert_eq!(e.line_column().0, 2);
        let e = err("# sample_rate: 1000 Hz\n# units: a=N\na,b\n1,2\n");
        assert!(matches!(e, FormatError::ChannelMismatch { .. }), "{e}");

        let e = err("# sample_rate: 1000 m\na\n1\n");
        assert!(matches!(e, FormatError::Expected { .. }), "{e}");
        assert_eq!(e.line_column(), (1, 16));
        let e = err("# sample_rate: 1000 Hz\na,b\n");
        assert!(e.to_string().contains("rows of samples"), "{e}");
        assert!(matches!(
            read_time_series(b"# sample_rate: 1 Hz\na\n\xff\n", "x.csv"),
            Err(FormatError::Expected { .. })
        ));
    }

    #[test]
    fn bad_frf_files_name_the_place() {
        let e = read_frf(b"# units: m/N\nfreq,re,im\n1,2,3\n", "f.csv").unwrap_err();
        assert_eq!(e.line_column(), (2, 1));
        let e = read_frf(b"freq_hz,real,imag\n1,2,3\n2,nan,3\n", "f.csv").unwrap_err();
        assert!(matches!(e, FormatError::NonFinite { .. }), "{e}");
        assert_eq!(e.line_column(), (3, 3));
        let e = read_frf(b"freq_hz,real,imag,coherence\n1,2,3\n", "f.csv").unwrap_err();
        assert!(matches!(e, FormatError::Ragged { found: 3, expected: 4, .. }), "{e}");
        let e = read_frf(b"# speed_rpm: fast\nfreq_hz,real,imag\n1,2,3\n", "f.csv").unwrap_err();
        assert_eq!(e.line_column(), (1, 14));
    }

    /// The same FRF as a spreadsheet saves it: with a byte-order mark, with `;` and decimal
    /// commas, with capitalised headers; each reads as the plain file does, and an error still
    /// points at the line and column of the file as written.
    #[test]
    fn spreadsheet_forms_of_an_frf_read_as_the_plain_file() {
        let plain =
            read_frf(b"# units: m/N\nfreq_hz,real,imag\n100,1.5e-6,-2.25e-7\n200,2.5e-6,-3e-7\n", "p.csv").unwrap();
        for text in [
            "\u{feff}# units: m/N\nfreq_hz,real,imag\n100,1.5e-6,-2.25e-7\n200,2.5e-6,-3e-7\n",
            "# units: m/N\nfreq_hz;real;imag\n100;1,5e-6;-2,25e-7\n200;2,5e-6;-3e-7\n",
            "\u{feff}Freq_Hz,Real,Imag\r\n100,1.5e-6,-2.25e-7\r\n200,2.5e-6,-3e-7\r\n",
        ] {
            let f = read_frf(text.as_bytes(), "s.csv").unwrap_or_else(|e| panic!("{text:?}: {e}"));
            assert_eq!(
                (f.freq_hz.clone(), f.values.clone()),
                (plain.freq_hz.clone(), plain.values.clone()),
                "{text:?}"
            );
        }
        let e = read_frf("freq_hz;real;imag\n100;1,5e-6;x\n".as_bytes(), "s.csv").unwrap_err();
        assert_eq!(e.line_column(), (2, 12), "{e}");
    }

    /// A header of `n` channels `c0,c1,…` with `rows` rows of ones.
    fn wide(n: usize, rows: usize) -> String {
        let names: Vec<String> = (0..n).map(|i| format!("c{i}")).collect();
        let mut text = format!("# sample_rate: 1 kHz\n{}\n", names.join(","));
        for _ in 0..rows {
            text.push_str(&vec!["1"; n].join(","));
            text.push('\n');
        }
        text
    }

    #[test]
    fn a_header_of_200k_channels_is_refused_with_its_line_and_count() {
        let e = read_time_series(wide(200_000, 0).as_bytes(), "w.csv").unwrap_err();
        let text = e.to_string();
        assert!(matches!(e, FormatError::Unsupported { .. }), "{text}");
        assert_eq!(e.line_column().0, 2, "{text}");
        assert!(text.contains("200000 columns") && text.contains("at most 4096 channels"), "{text}");
        assert!(text.contains("split the recording"), "{text}");
        assert!(text.len() < 400, "{} characters", text.len());
    }

    #[test]
    fn a_header_of_4096_channels_is_read_and_a_name_repeated_last_is_found() {
        let ts = read_time_series(wide(MAX_COLUMNS, 3).as_bytes(), "w.csv").unwrap();
        assert_eq!((ts.channels.len(), ts.len()), (MAX_COLUMNS, 3));
        assert_eq!(ts.channels[MAX_COLUMNS - 1].name, format!("c{}", MAX_COLUMNS - 1));
        let mut names: Vec<String> = (0..MAX_COLUMNS - 1).map(|i| format!("c{i}")).collect();
        names.push("c7".into());
        let text = format!("# sample_rate: 1 kHz\n{}\n{}\n", names.join(","), vec!["1"; MAX_COLUMNS].join(","));
        let e = read_time_series(text.as_bytes(), "w.csv").unwrap_err();
        assert!(e.to_string().contains("channel `c7` appears twice"), "{e}");
        assert_eq!(e.line_column().0, 2);
    }

    #[test]
    fn messages_list_a_few_channels_and_count_the_rest() {
        let mut text = wide(1000, 0);
        text.push_str("1,2\n");
        let e = read_time_series(text.as_bytes(), "w.csv").unwrap_err().to_string();
        assert!(e.contains("ragged row: 2 values, expected 1000") && e.contains("and 992 more"), "{e}");
        assert!(e.len() < 300, "{e}");
        let e =
            read_time_series(b"# sample_rate: 1 Hz\n# units: x=m\na,b,c,d,e,f,g,h,i,j\n1,1,1,1,1,1,1,1,1,1\n", "u.csv")
                .unwrap_err()
                .to_string();
        assert!(e.contains("does not have: a, b, c, d, e, f, g, h, … and 2 more"), "{e}");
    }

    #[test]
    fn a_units_line_of_more_entries_than_channels_can_have_is_refused_at_its_line() {
        let units: Vec<String> = (0..MAX_COLUMNS + 1).map(|i| format!("c{i}=m")).collect();
        let text = format!("# units: {}\n# sample_rate: 1 Hz\na\n1\n", units.join(", "));
        let e = read_time_series(text.as_bytes(), "u.csv").unwrap_err();
        assert!(matches!(e, FormatError::Unsupported { .. }), "{e}");
        assert_eq!(e.line_column().0, 1);
        assert!(e.to_string().contains("more than 4096 channels"), "{e}");
    }

    #[test]
    fn a_row_of_a_million_cells_is_ragged_and_counted_no_further_than_the_cap() {
        let mut text = String::from("freq_hz,real,imag\n");
        text.push_str(&vec!["1"; 1_000_000].join(","));
        let e = read_frf(text.as_bytes(), "f.csv").unwrap_err();
        assert!(matches!(e, FormatError::Ragged { .. }), "{e}");
        assert!(e.to_string().contains("ragged row: more than 4096 values, expected 3"), "{e}");
        // The same through a time series, and as a spreadsheet writes it (`;`, decimal commas).
        let mut text = String::from("# sample_rate: 1 Hz\na;b\n");
        text.push_str(&vec!["1,5"; 1_000_000].join(";"));
        let e = read_time_series(text.as_bytes(), "t.csv").unwrap_err();
        assert!(e.to_string().contains("ragged row: more than 4096 values, expected 2"), "{e}");
    }

    #[test]
    fn a_one_line_file_of_a_million_cells_is_refused_by_its_header_in_every_form() {
        for cell in ["a", "A"] {
            for sep in [",", ";"] {
                let text = vec![cell; 1_000_000].join(sep);
                let e = read_frf(text.as_bytes(), "one.csv").unwrap_err();
                assert!(matches!(e, FormatError::Unsupported { .. }), "{cell}{sep}: {e}");
                assert!(e.to_string().contains("the header row has 1000000 columns"), "{cell}{sep}: {e}");
                assert_eq!(e.line_column().0, 1);
                let e = read_time_series(format!("# sample_rate: 1 Hz\n{text}").as_bytes(), "one.csv").unwrap_err();
                assert!(e.to_string().contains("the header row has 1000000 columns"), "{cell}{sep}: {e}");
                // Tables are read in the plain form only, where `;` is part of a name.
                if sep == "," {
                    let e = read_tables(text.as_bytes(), "one.csv").unwrap_err();
                    assert!(e.to_string().contains("the header row has 1000000 columns"), "{cell}{sep}: {e}");
                }
                assert!(read_receptance(text.as_bytes(), "one.csv").is_err());
            }
        }
    }

    #[test]
    fn sweep_points_beyond_the_cap_are_refused_at_the_first_row_past_it() {
        let mut text = String::from("speed_rpm,freq_hz,real,imag\n");
        for i in 0..=MAX_SWEEP_POINTS {
            text.push_str(&format!("{i},1,2,3\n"));
        }
        let e = read_frf_blocks(text.as_bytes(), "s.csv").unwrap_err();
        assert_eq!(e.line_column().0, MAX_SWEEP_POINTS + 2, "{e}");
        assert!(e.to_string().contains("more than 50000 sweep points"), "{e}");
        let mut text = String::from("# units: value_m=m\nk,value_m\n");
        for i in 0..=MAX_SWEEP_POINTS {
            text.push_str(&format!("{i},1\n"));
        }
        let e = read_tables(text.as_bytes(), "s.csv").unwrap_err();
        assert!(e.to_string().contains("more than 50000 sweep points"), "{e}");
    }

    #[test]
    fn frf_units_are_checked_for_the_dimension_of_an_frf() {
        let read = |unit: &str| read_frf(format!("# units: {unit}\nfreq_hz,real,imag\n1,2,3\n").as_bytes(), "f.csv");
        let f = read("um/N").unwrap();
        assert_eq!((f.unit.symbol.as_str(), f.values[0]), ("m/N", Complex64::new(2e-6, 3e-6)));
        assert_eq!(read("m/s^2/N").unwrap().unit.symbol, "m/s^2/N");
        assert_eq!(read("mm/s/N").unwrap().unit.symbol, "m/s/N");
        assert_eq!(read("g/N").unwrap().unit.symbol, "g/N");
        for (unit, why) in [
            ("kg", "`kg` is a mass (kg), not the unit of an FRF"),
            ("N/m", "is a stiffness"),
            ("m^999999999999/N", "`m^999999999999/N` is not a unit"),
            ("m/N/N", "not the unit of an FRF"),
            ("bananas", "is not a unit"),
        ] {
            let e = read(unit).unwrap_err();
            let text = e.to_string();
            assert_eq!(e.line_column(), (1, 10), "{text}");
            assert!(text.contains(why) && text.contains("a receptance, length per force (`m/N`"), "{text}");
        }
    }

    #[test]
    fn a_channel_name_with_a_control_character_is_refused_at_its_place() {
        let e = read_time_series("# sample_rate: 1000 Hz\nforce,acc\u{1b}[2J\n1,2\n".as_bytes(), "t.csv").unwrap_err();
        let said = e.to_string();
        assert!(said.contains("t.csv:2:7") && said.contains("\\u{1b}"), "{said}");
    }

    #[test]
    fn long_cells_are_cut_in_messages() {
        let long = "x".repeat(100_000);
        let e = read_frf(format!("freq_hz,real,imag\n1,2,{long}\n").as_bytes(), "f.csv").unwrap_err().to_string();
        assert!(e.len() < 300 && e.contains("xxx…"), "{}", e.len());
        let e = read_time_series(format!("# sample_rate: {long}\na\n1\n").as_bytes(), "t.csv").unwrap_err();
        assert!(e.to_string().len() < 300, "{}", e.to_string().len());
        let e = read_frf(format!("freq_hz,real,imag\n1,2,1e{}\n", "9".repeat(100_000)).as_bytes(), "f.csv");
        assert!(e.unwrap_err().to_string().len() < 300);
    }

    #[test]
    fn row_capacity_is_what_the_file_length_can_hold() {
        // A header of 4096 channels before a million one-cell rows: the rows the file can hold
        // at 2 bytes per cell, not a million per channel.
        let mut text = wide(MAX_COLUMNS, 0);
        text.push_str(&"1\n".repeat(1_000_000));
        let sheet = Sheet::open(text.as_bytes(), "w.csv", Forms::Spreadsheet).unwrap();
        let bound = sheet.row_bound(2 * MAX_COLUMNS);
        assert!(bound <= 2_000_000 / (2 * MAX_COLUMNS) + 1, "{bound}");
        assert!(matches!(read_time_series(text.as_bytes(), "w.csv"), Err(FormatError::Ragged { found: 1, .. })));
        let plain = Sheet::open(b"a\n1\n2\n3", "p.csv", Forms::Plain).unwrap();
        assert_eq!(plain.row_bound(2), 3);
    }
}
