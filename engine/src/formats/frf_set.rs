//! Measurement sets: every FRF of a UFF or CSV file as one [`FrfSet`], and a set written back as
//! UFF (one dataset 58 per FRF, its nodes and directions in record 6) or CSV (one block of rows
//! per FRF, led by its nodes and directions).
//!
//! A set shares one frequency grid and one unit; a file whose FRFs differ in either is refused
//! at the dataset (UFF line) or block that differs, with what to do instead.

use super::{FileFormat, FormatError, FrfSelect, Loaded, Loc, Notes, csv, uff};
use crate::value::{Frf, FrfDofs, FrfSet, FrfSetError};
use std::fmt::Write as _;
use std::path::Path;

/// The columns a set's CSV file leads each row with (after any sweep columns): the FRF's place in
/// the set (from 1), its direction, and its response and reference node and axis (empty cells for
/// an FRF without them).
pub const SET_COLUMNS: [&str; 6] =
    ["frf", "direction", "response_node", "response_axis", "reference_node", "reference_axis"];

/// What to do when the FRFs of a file do not make one set, for messages.
const GRID_HELP: &str = "a set needs one frequency grid and one unit: read the FRFs one by one with `read.frf` \
                         (`response`, `reference` or `dataset`), or narrow the set with `response`/`reference`";

/// Reads every FRF of a UFF file (datasets 58 of function type 4), or every block of rows of a
/// CSV FRF file, as one set; `select` narrows it by response direction and response and
/// reference node numbers (`dataset` does not apply to a set and is ignored).
pub fn read_frf_set(path: &Path, format: FileFormat, select: &FrfSelect) -> Result<Loaded<FrfSet>, FormatError> {
    let bytes = super::read_bytes(path)?;
    let shown = path.display().to_string();
    let wanted = |f: &Frf| {
        select.direction.as_deref().is_none_or(|d| f.direction.as_deref() == Some(d)) && select.nodes_match(f.dofs)
    };
    match format {
        FileFormat::Uff => {
            let file = uff::parse(&bytes, &shown)?;
            let mut notes = super::skipped_notes(&shown, &file.skipped);
            let mut passed = Notes::new(&shown);
            let mut frfs: Vec<(Frf, usize, String)> = Vec::new();
            for ds in &file.datasets {
                if ds.function_type != uff::FUNCTION_FRF {
                    passed.push(|| {
                        format!(
                            "{shown}: dataset 58 at line {} is {}, not an FRF; skipped",
                            ds.line,
                            uff::function_name(ds.function_type)
                        )
                    });
                    continue;
                }
                let frf = super::checked_frf(ds, &shown)?;
                if wanted(&frf) {
                    frfs.push((frf, ds.line, ds.describe()));
                }
            }
            notes.extend(passed.finish());
            if frfs.is_empty() {
                return Err(nothing(&shown, select, &file.summary()));
            }
            let places: Vec<(usize, String)> = frfs.iter().map(|(_, l, d)| (*l, d.clone())).collect();
            let set = FrfSet::new(frfs.into_iter().map(|(f, _, _)| f).collect())
                .map_err(|e| refused(&shown, &e, |i| Loc::new(&shown, places[i].0, 0), |i| places[i].1.clone()))?;
            Ok(Loaded { value: set, notes })
        }
        FileFormat::Csv => {
            let blocks = csv::read_frf_blocks(&bytes, &shown)?;
            let mut frfs = Vec::new();
            let mut names = Vec::new();
            for b in blocks {
                let name = csv::block_names(std::slice::from_ref(&b)).pop().unwrap_or_default();
                let frf = with_set_columns(b, &shown)?;
                if wanted(&frf) {
                    frfs.push(frf);
                    names.push(if name.is_empty() { "the FRF".to_string() } else { format!("the block {name}") });
                }
            }
            if frfs.is_empty() {
                return Err(nothing(&shown, select, "its blocks"));
            }
            let set =
                FrfSet::new(frfs).map_err(|e| refused(&shown, &e, |_| Loc::new(&shown, 0, 0), |i| names[i].clone()))?;
            Ok(Loaded { value: set, notes: Vec::new() })
        }
    }
}

fn nothing(path: &str, select: &FrfSelect, summary: &str) -> FormatError {
    FormatError::Selection {
        path: path.to_string(),
        message: match select.asked().as_str() {
            "" => format!("no FRF (function type 4) among {summary}"),
            asked => format!("no FRF with {asked} among {summary}"),
        },
    }
}

/// The error of FRFs that do not make a set: at the place of the one that differs.
fn refused(path: &str, e: &FrfSetError, at: impl Fn(usize) -> Loc, name: impl Fn(usize) -> String) -> FormatError {
    match e {
        FrfSetError::Empty => FormatError::Selection { path: path.to_string(), message: e.to_string() },
        FrfSetError::Grid { index, .. } | FrfSetError::Unit { index, .. } => {
            let message = format!("{} does not belong to the set of the first FRF: {e}; {GRID_HELP}", name(*index));
            match at(*index) {
                loc if loc.line > 0 => FormatError::Unsupported { at: loc, message },
                _ => FormatError::Selection { path: path.to_string(), message },
            }
        }
    }
}

/// A CSV block's FRF with its set columns (`frf`, `direction`, nodes and axes) taken in.
fn with_set_columns(b: csv::FrfBlock, path: &str) -> Result<Frf, FormatError> {
    let of = |k: &str| b.coords.iter().find(|(n, _)| n == k).map(|(_, v)| v.trim().to_string());
    let mut frf = b.frf;
    if let Some(d) = of("direction") {
        frf.direction = (!d.is_empty()).then_some(d);
    }
    let point = |node: &str, axis: &str| -> Result<Option<(i64, i32)>, FormatError> {
        match (of(node), of(axis)) {
            (None, None) => Ok(None),
            (Some(n), Some(a)) if n.is_empty() && a.is_empty() => Ok(None),
            (Some(n), Some(a)) => {
                let code =
                    if a == "scalar" { Some(0) } else { Some(uff::direction_code(Some(&a))).filter(|c| *c != 0) };
                match (n.parse::<i64>(), code) {
                    (Ok(n), Some(c)) => Ok(Some((n, c))),
                    _ => Err(FormatError::Selection {
                        path: path.to_string(),
                        message: format!(
                            "columns `{node}`, `{axis}` hold `{}`, `{}`: expected a node number and an axis (x, y, z, rx, ry, rz, scalar)",
                            csv::shown_cell(&n),
                            csv::shown_cell(&a)
                        ),
                    }),
                }
            }
            _ => Err(FormatError::Selection {
                path: path.to_string(),
                message: format!("the file has one of the columns `{node}` and `{axis}` without the other"),
            }),
        }
    };
    match (point("response_node", "response_axis")?, point("reference_node", "reference_axis")?) {
        (Some((rn, rd)), Some((fn_, fd))) => {
            frf.dofs = Some(FrfDofs {
                response_node: rn,
                response_direction: rd,
                reference_node: fn_,
                reference_direction: fd,
            })
        }
        (None, None) => {}
        _ => {
            return Err(FormatError::Selection {
                path: path.to_string(),
                message: "an FRF has a response point without a reference point, or the reverse".into(),
            });
        }
    }
    Ok(frf)
}

/// Writes a set as UFF: one dataset 58 per FRF (see [`uff::write_frf`]), `label` in ID line 2.
pub fn write_uff(out: &mut String, set: &FrfSet, label: &str) {
    for f in &set.frfs {
        uff::write_frf(out, f, label);
    }
}

/// Writes a set as CSV rows: `#` header lines and the column header when `*header_done` is false
/// (`prefix_header` names the sweep columns), then each FRF's rows, each led by `prefix` and the
/// FRF's [`SET_COLUMNS`]. The unit, and the speed and sensor when every FRF has the same, go to
/// the header; coherence is written when every FRF has one.
pub fn csv_rows(out: &mut String, set: &FrfSet, prefix_header: &str, prefix: &str, header_done: &mut bool) {
    let Some(first) = set.frfs.first() else { return };
    let coherence = set.frfs.iter().all(|f| f.coherence.is_some());
    if !*header_done {
        let _ = writeln!(out, "# units: {}", first.unit.symbol);
        if let Some(s) = first.speed
            && set.frfs.iter().all(|f| f.speed == Some(s))
        {
            let _ = writeln!(out, "# speed_rpm: {}", s.rpm_as_written());
        }
        if let Some(s) = &first.sensor
            && set.frfs.iter().all(|f| f.sensor.as_ref() == Some(s))
        {
            let _ = writeln!(out, "# sensor: {s}");
        }
        let coh = if coherence { ",coherence" } else { "" };
        let _ = writeln!(out, "{prefix_header}{},freq_hz,real,imag{coh}", SET_COLUMNS.join(","));
        *header_done = true;
    }
    let mut buf = zmij::Buffer::new();
    for (i, f) in set.frfs.iter().enumerate() {
        let axis = |c: i32| uff::direction_name(c).unwrap_or("scalar");
        let points = match f.dofs {
            Some(d) => format!(
                "{},{},{},{}",
                d.response_node,
                axis(d.response_direction),
                d.reference_node,
                axis(d.reference_direction)
            ),
            None => ",,,".into(),
        };
        let direction = f.direction.as_deref().map(|d| d.replace([',', '"'], ";")).unwrap_or_default();
        let lead = format!("{prefix}{},{direction},{points},", i + 1);
        for (k, (&fr, v)) in f.freq_hz.iter().zip(&f.values).enumerate() {
            out.push_str(&lead);
            out.push_str(buf.format(fr));
            out.push(',');
            out.push_str(buf.format(v.re));
            out.push(',');
            out.push_str(buf.format(v.im));
            if coherence && let Some(c) = &f.coherence {
                out.push(',');
                out.push_str(buf.format(c.get(k).copied().unwrap_or(f64::NAN)));
            }
            out.push('\n');
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::value::UnitLabel;
    use num_complex::Complex64;

    fn frf(k: f64, dofs: Option<FrfDofs>) -> Frf {
        Frf {
            freq_hz: (0..50).map(|i| 2.0 * i as f64).collect(),
            values: (0..50).map(|i| Complex64::new(k * (i as f64 + 0.5).recip(), -k * 1e-3 * i as f64)).collect(),
            coherence: None,
            unit: UnitLabel::new("m/s^2/N"),
            direction: Some("x".into()),
            speed: None,
            sensor: None,
            dofs,
        }
    }

    fn dofs(reference: i64) -> Option<FrfDofs> {
        Some(FrfDofs { response_node: 7, response_direction: 1, reference_node: reference, reference_direction: 2 })
    }

    #[test]
    fn a_set_reads_back_from_its_uff_and_csv_files() {
        let set = FrfSet::new(vec![frf(1.0, dofs(1)), frf(-2.5, dofs(2)), frf(0.3, dofs(3))]).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let mut uff_text = String::new();
        write_uff(&mut uff_text, &set, "");
        let mut csv_text = String::new();
        csv_rows(&mut csv_text, &set, "", "", &mut false);
        let (u, c) = (dir.path().join("s.uff"), dir.path().join("s.csv"));
        std::fs::write(&u, uff_text).unwrap();
        std::fs::write(&c, csv_text).unwrap();
        let from_csv = read_frf_set(&c, FileFormat::Csv, &FrfSelect::default()).unwrap().value;
        assert_eq!(from_csv, set);
        let from_uff = read_frf_set(&u, FileFormat::Uff, &FrfSelect::default()).unwrap().value;
        assert_eq!(from_uff.frfs.len(), 3);
        for (a, b) in from_uff.frfs.iter().zip(&set.frfs) {
            assert_eq!((a.dofs, &a.unit, &a.freq_hz), (b.dofs, &b.unit, &b.freq_hz));
            for (x, y) in a.values.iter().zip(&b.values) {
                assert!((x - y).norm() <= 1e-12 * y.norm().max(1e-300), "{x} {y}");
            }
        }
        // Narrowed by node numbers, from either file.
        let select = FrfSelect { reference: Some(2), ..Default::default() };
        for (p, fmt) in [(&u, FileFormat::Uff), (&c, FileFormat::Csv)] {
            let one = read_frf_set(p, fmt, &select).unwrap().value;
            assert_eq!(one.frfs.len(), 1);
            assert_eq!(one.frfs[0].dofs, dofs(2));
        }
        let none = FrfSelect { reference: Some(9), ..Default::default() };
        let e = read_frf_set(&u, FileFormat::Uff, &none).unwrap_err().to_string();
        assert!(e.contains("no FRF with reference node 9"), "{e}");
    }

    #[test]
    fn frfs_on_different_grids_are_refused_at_the_dataset_that_differs() {
        let mut odd = frf(1.0, dofs(2));
        odd.freq_hz.iter_mut().for_each(|f| *f *= 1.5);
        let mut text = String::new();
        uff::write_frf(&mut text, &frf(1.0, dofs(1)), "");
        uff::write_frf(&mut text, &odd, "");
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("two.uff");
        std::fs::write(&p, &text).unwrap();
        let e = read_frf_set(&p, FileFormat::Uff, &FrfSelect::default()).unwrap_err();
        let line = text.lines().enumerate().filter(|(_, l)| l.trim() == "58").nth(1).unwrap().0 + 1;
        assert_eq!(e.line_column().0, line, "{e}");
        let msg = e.to_string();
        assert!(msg.contains("its line 2 is at 3 Hz, the first FRF's at 2 Hz") && msg.contains("read.frf"), "{msg}");
    }
}
