//! Many cases diagnosed in one go (`spindlelab diagnose --batch 'cases/*/case.json' -o DIR`):
//! each case imported to `DIR/<case>/recipe.yaml` and diagnosed into `DIR/<case>/diagnosis`,
//! one after the other (each diagnosis uses every core), and a summary of all of them —
//! verdicts, effects with their parameters, the gap before and after — as `summary.csv`
//! (read back by the project's table reader) and `summary.md`. A case that fails is a row with
//! its error; the others still run.

use super::{Diagnosis, value_pm};
use crate::engine::exec::write::{Row, render};
use crate::engine::model::OutputFormat;
use crate::engine::node::Registry;
use crate::engine::value::{Column, Table, Value};
use crate::import::{Placement, recipe_from_case_at};
use std::path::{Path, PathBuf};

/// One case's line of the summary.
#[derive(Debug, Clone)]
pub struct BatchRow {
    pub case: String,
    pub verdict: String,
    /// The named effects with their fitted parameters (`mass_loading: added_tip_mass = 12.1 ± 0.3 g`).
    pub effects: String,
    /// The largest gap over the measured files, in units of the noise floor, before and after.
    pub gap_before: f64,
    pub gap_after: f64,
    /// Cutting trials the lobes misclassify, before and after (NaN without trials).
    pub misclassified_before: f64,
    pub misclassified_after: f64,
    pub seconds: f64,
    /// Why the case was not diagnosed; empty when it was.
    pub error: String,
}

/// A case's name: its folder (`cases/train_01/case.json` → `train_01`), or the file's stem.
pub fn case_name(case: &Path) -> String {
    let stem = case.file_stem().and_then(|s| s.to_str()).unwrap_or("case");
    match case.parent().and_then(Path::file_name).and_then(|s| s.to_str()) {
        Some(folder) if stem == "case" => folder.to_string(),
        _ => stem.to_string(),
    }
}

/// Imports `case` into `dir/recipe.yaml` and diagnoses it into `dir/diagnosis`.
pub fn diagnose_case(case: &Path, dir: &Path, registry: &Registry) -> Result<Diagnosis, String> {
    let text = crate::engine::formats::read_text_capped(case, crate::engine::formats::MAX_CASE_BYTES)
        .map_err(|e| format!("cannot read {}: {e}", case.display()))?;
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot make {}: {e}", dir.display()))?;
    let case_dir = match case.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let placement = Placement { case_dir: &case_dir, recipe_dir: dir };
    let recipe = recipe_from_case_at(&text, &case.display().to_string(), placement).map_err(|e| e.to_string())?;
    let path = dir.join("recipe.yaml");
    std::fs::write(&path, recipe).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    let d = super::diagnose(&path, registry).map_err(|e| e.to_string())?;
    super::write(&d, &dir.join("diagnosis")).map_err(|e| e.to_string())?;
    Ok(d)
}

/// The summary line of a diagnosis of `case`.
pub fn row(case: &str, d: &Diagnosis) -> BatchRow {
    let worst = |f: fn(&super::GapFile) -> f64| d.gap.files.iter().map(f).fold(f64::NAN, f64::max);
    let effects: Vec<String> = d
        .effects
        .iter()
        .map(|e| {
            // The fitted parameters as diagnosis.md gives them: value ± σ and unit.
            let params: Vec<String> = e
                .uncertainty
                .as_object()
                .into_iter()
                .flatten()
                .map(|(name, p)| {
                    let v = p["value"].as_f64().unwrap_or(f64::NAN);
                    let unit =
                        p["unit"].as_str().filter(|u| !u.is_empty()).map(|u| format!(" {u}")).unwrap_or_default();
                    format!("{name} = {}{unit}", value_pm(v, p["sigma"].as_f64()))
                })
                .collect();
            if params.is_empty() { e.name.to_string() } else { format!("{}: {}", e.name, params.join(", ")) }
        })
        .collect();
    let trials = d.gap.trials.as_ref();
    BatchRow {
        case: case.to_string(),
        verdict: d.verdict.to_string(),
        effects: effects.join("; "),
        gap_before: worst(|f| f.ratio_before),
        gap_after: worst(|f| f.ratio_after),
        misclassified_before: trials.map_or(f64::NAN, |t| t.misclassified_before as f64),
        misclassified_after: trials.map_or(f64::NAN, |t| t.misclassified_after as f64),
        seconds: d.seconds,
        error: String::new(),
    }
}

/// The line of a case that could not be diagnosed.
pub fn failed(case: &str, error: String) -> BatchRow {
    BatchRow {
        case: case.to_string(),
        verdict: "failed".into(),
        effects: String::new(),
        gap_before: f64::NAN,
        gap_after: f64::NAN,
        misclassified_before: f64::NAN,
        misclassified_after: f64::NAN,
        seconds: 0.0,
        error,
    }
}

/// The summary as a table: text columns for the case, verdict, effects and error.
pub fn table(rows: &[BatchRow]) -> Table {
    let text = |f: fn(&BatchRow) -> &str| rows.iter().map(f).collect::<Vec<_>>();
    let num = |f: fn(&BatchRow) -> f64| rows.iter().map(f).collect::<Vec<_>>();
    Table {
        columns: vec![
            Column::text("case", &text(|r| &r.case)),
            Column::text("verdict", &text(|r| &r.verdict)),
            Column::text("effects", &text(|r| &r.effects)),
            Column::new("gap_before", "", num(|r| r.gap_before)),
            Column::new("gap_after", "", num(|r| r.gap_after)),
            Column::new("trials_misclassified_before", "", num(|r| r.misclassified_before)),
            Column::new("trials_misclassified_after", "", num(|r| r.misclassified_after)),
            Column::new("time", "s", num(|r| r.seconds)),
            Column::text("error", &text(|r| &r.error)),
        ],
    }
}

/// `summary.csv`: the table as the project writes tables.
pub fn summary_csv(rows: &[BatchRow]) -> String {
    let value = Value::Table(table(rows));
    render(OutputFormat::Csv, &[Row { label: "", value: &value }])
}

/// The file beside a case's diagnosis that holds its summary row (`DIR/<case>/row.csv`), so
/// the summary can be gathered again without diagnosing (`--summary-only`), as a workflow
/// engine's last job does.
pub const ROW_FILE: &str = "row.csv";

/// The summary rows of a `summary.csv` or `row.csv` as [`summary_csv`] writes them.
pub fn rows_from_csv(bytes: &[u8], path: &str) -> Result<Vec<BatchRow>, String> {
    let blocks = crate::engine::formats::csv::read_tables(bytes, path).map_err(|e| e.to_string())?;
    let mut rows = Vec::new();
    for b in blocks {
        let t = &b.table;
        let col =
            |name: &str| t.columns.iter().find(|c| c.name == name).ok_or_else(|| format!("{path}: no column `{name}`"));
        let word = |name: &str, i: usize| -> Result<String, String> {
            let c = col(name)?;
            Ok(c.values.get(i).and_then(|&v| c.levels.get(v as usize)).cloned().unwrap_or_default())
        };
        let num =
            |name: &str, i: usize| -> Result<f64, String> { Ok(col(name)?.values.get(i).copied().unwrap_or(f64::NAN)) };
        for i in 0..col("case")?.values.len() {
            rows.push(BatchRow {
                case: word("case", i)?,
                verdict: word("verdict", i)?,
                effects: word("effects", i)?,
                gap_before: num("gap_before", i)?,
                gap_after: num("gap_after", i)?,
                misclassified_before: num("trials_misclassified_before", i)?,
                misclassified_after: num("trials_misclassified_after", i)?,
                seconds: num("time", i)?,
                error: word("error", i)?,
            });
        }
    }
    Ok(rows)
}

/// `summary.md`: one line per case, linking its diagnosis.
pub fn summary_md(rows: &[BatchRow]) -> String {
    let mut s = String::from(
        "# Batch diagnosis\n\n| case | verdict | effects | gap before → after (× noise) | trials misclassified | s |\n|---|---|---|---|---|---|\n",
    );
    let n = |v: f64| if v.is_finite() { format!("{}", spindlelab_domain::round_sig(v, 3)) } else { "–".into() };
    for r in rows {
        let what = if r.error.is_empty() {
            r.effects.replace('|', "/")
        } else {
            format!("error: {}", r.error.replace('|', "/"))
        };
        let case =
            if r.error.is_empty() { format!("[{0}]({0}/diagnosis/diagnosis.md)", r.case) } else { r.case.clone() };
        s.push_str(&format!(
            "| {case} | {} | {what} | {} → {} | {} → {} | {:.1} |\n",
            r.verdict,
            n(r.gap_before),
            n(r.gap_after),
            n(r.misclassified_before),
            n(r.misclassified_after),
            r.seconds
        ));
    }
    s
}

/// The page of a batch folder (`spindlelab report DIR`): the summary table, each case linked
/// to its diagnosis below it on the same page, pictures inline.
pub fn report_html(dir: &Path) -> Result<String, super::DiagnoseError> {
    use crate::engine::formats::{MAX_DATA_BYTES, read_capped};
    use pulldown_cmark::{Event, Options, Parser, Tag, html};
    let path = dir.join("summary.md");
    let md = read_capped(&path, MAX_DATA_BYTES)
        .ok()
        .and_then(|b| String::from_utf8(b).ok())
        .ok_or_else(|| super::DiagnoseError::Input(format!("{}: cannot read it as text", path.display())))?;
    let mut cases = Vec::new();
    let events: Vec<Event> = Parser::new_ext(&md, Options::ENABLE_TABLES)
        .map(|ev| match ev {
            // `case/diagnosis/diagnosis.md` → the case's section on this page.
            Event::Start(Tag::Link { link_type, dest_url, title, id })
                if dest_url.ends_with("/diagnosis/diagnosis.md") && !dest_url.starts_with(['.', '/']) =>
            {
                let case = dest_url.trim_end_matches("/diagnosis/diagnosis.md").to_string();
                let anchor = format!("#case-{case}").into();
                cases.push(case);
                Event::Start(Tag::Link { link_type, dest_url: anchor, title, id })
            }
            other => other,
        })
        .collect();
    let mut body = String::new();
    html::push_html(&mut body, events.into_iter());
    for case in cases.iter().filter(|c| !c.contains(['/', '\\']) && *c != "..") {
        let shown = crate::render::report::esc(case);
        body.push_str(&format!("<section id=\"case-{shown}\"><h2>{shown}</h2>\n"));
        match super::report_body(&dir.join(case).join("diagnosis"), &format!("{case}-")) {
            Ok(b) => body.push_str(&b),
            Err(e) => body.push_str(&format!("<p class=\"warn\">{}</p>", crate::render::report::esc(&e.to_string()))),
        }
        body.push_str("</section>\n");
    }
    Ok(crate::render::report::standalone(&format!("batch diagnosis of {}", dir.display()), &body))
}
