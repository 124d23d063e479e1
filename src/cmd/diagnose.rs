//! `diagnose`: one recipe against its measurements, or a batch of cases.

use crate::*;

/// `spindlelab diagnose RECIPE`: finds the missing physical effect and writes the diagnosis folder.
pub(crate) fn cmd_diagnose(
    recipe: &Path,
    out: Option<PathBuf>,
    quiet: bool,
    registry: &mut engine::node::Registry,
    plugins: &mut Plugins,
) -> ExitCode {
    // Loads the plugins the recipe names, so the diagnosis compiles it with them.
    let compiled = match compile(recipe, registry, plugins) {
        Ok(c) => c,
        Err(code) => return code,
    };
    let d = match spindlelab::diagnose::diagnose(recipe, registry) {
        Ok(d) => d,
        Err(spindlelab::diagnose::DiagnoseError::Output(e)) if !e.is_bad_input() => {
            eoutln!("error: {}", esc(&e));
            return ExitCode::from(EXIT_FAILURE);
        }
        Err(e) => {
            eoutln!("error: {}", esc(&e));
            return ExitCode::from(EXIT_BAD_INPUT);
        }
    };
    // Beside the run's outputs: `out/<recipe name>/diagnosis`, as `run` names its folder.
    let out = out.unwrap_or_else(|| default_out(&compiled).join("diagnosis"));
    if let Err(e) = spindlelab::diagnose::write(&d, &out) {
        eoutln!("error: {}", esc(&e));
        let bad = matches!(&e, spindlelab::diagnose::DiagnoseError::Output(c) if c.is_bad_input());
        return ExitCode::from(if bad { EXIT_BAD_INPUT } else { EXIT_FAILURE });
    }
    if !quiet {
        out!("{}", esc_lines(&spindlelab::diagnose::markdown(&d)));
        outln!("\nwrote diagnosis.json, diagnosis.md and diagnosed.yaml to {} in {:.1} s", out.display(), d.seconds);
    }
    ExitCode::SUCCESS
}

/// `spindlelab diagnose --batch PATTERN`: every case the pattern matches imported and
/// diagnosed into a folder of its own, one after the other, with a summary of all of them.
/// What `diagnose --batch` does: diagnose the cases, write the summary, or both.
#[derive(Clone, Copy)]
pub(crate) struct BatchMode {
    pub(crate) diagnose: bool,
    pub(crate) summary: bool,
}

/// The case files `pattern` matches, each with its folder name under the batch's output
/// (a name two cases share gets `_2`, `_3`, …, in the pattern's order).
pub(crate) fn batch_cases(pattern: &str) -> Result<Vec<(PathBuf, String)>, ExitCode> {
    use spindlelab::diagnose::batch;
    let cases: Vec<PathBuf> = match glob::glob(pattern) {
        Ok(paths) => paths.filter_map(Result::ok).filter(|p| p.is_file()).collect(),
        Err(e) => {
            eoutln!("error: `{}` is not a file pattern: {e}", esc(pattern));
            return Err(ExitCode::from(EXIT_BAD_INPUT));
        }
    };
    if cases.is_empty() {
        eoutln!(
            "error: `{}` matches no case file (quote the pattern so the shell leaves it: 'cases/*/case.json')",
            esc(pattern)
        );
        return Err(ExitCode::from(EXIT_BAD_INPUT));
    }
    let mut names = std::collections::HashSet::new();
    Ok(cases
        .into_iter()
        .map(|case| {
            let mut name = batch::case_name(&case);
            for k in 2.. {
                if names.insert(name.clone()) {
                    break;
                }
                name = format!("{}_{k}", batch::case_name(&case));
            }
            (case, name)
        })
        .collect())
}

pub(crate) fn cmd_diagnose_batch(
    pattern: &str,
    out: Option<PathBuf>,
    quiet: bool,
    mode: BatchMode,
    registry: &engine::node::Registry,
) -> ExitCode {
    use spindlelab::diagnose::batch;
    let cases = match batch_cases(pattern) {
        Ok(c) => c,
        Err(code) => return code,
    };
    let out = out.unwrap_or_else(|| PathBuf::from("out/batch"));
    let mut rows = Vec::new();
    for (case, name) in &cases {
        let row_file = out.join(name).join(batch::ROW_FILE);
        if !mode.diagnose {
            // The row the case's diagnosis left; a case not diagnosed yet is a failed row.
            let read = std::fs::read(&row_file).map_err(|e| e.to_string());
            let row = read.and_then(|b| batch::rows_from_csv(&b, &row_file.display().to_string()));
            match row {
                Ok(r) if r.len() == 1 => rows.extend(r),
                Ok(_) => rows.push(batch::failed(name, format!("{} holds no single row", row_file.display()))),
                Err(e) => rows.push(batch::failed(name, format!("not diagnosed: {e}"))),
            }
            continue;
        }
        let row = match batch::diagnose_case(case, &out.join(name), registry) {
            Ok(d) => batch::row(name, &d),
            Err(e) => batch::failed(name, e),
        };
        let text = batch::summary_csv(std::slice::from_ref(&row));
        if let Err(code) = write_together(&[(Some(&row_file), Some(text.as_str()))]) {
            return code;
        }
        if !quiet {
            let what = if row.error.is_empty() {
                format!("{} {}", row.verdict, row.effects)
            } else {
                format!("failed: {}", row.error)
            };
            outln!("{}: {} ({:.1} s)", esc(name), esc(what.trim()), row.seconds);
        }
        rows.push(row);
    }
    let failed = rows.iter().filter(|r| !r.error.is_empty()).count();
    if mode.summary {
        let (csv, md) = (out.join("summary.csv"), out.join("summary.md"));
        let (csv_text, md_text) = (batch::summary_csv(&rows), batch::summary_md(&rows));
        if let Err(code) = write_together(&[(Some(&csv), Some(csv_text.as_str())), (Some(&md), Some(md_text.as_str()))])
        {
            return code;
        }
        if !quiet {
            outln!("wrote {} and summary.md: {} case(s), {failed} failed", esc(csv.display()), rows.len());
        }
    }
    // Gathering the summary succeeds whatever the cases did: their rows say it.
    if failed > 0 && mode.diagnose { ExitCode::from(EXIT_FAILURE) } else { ExitCode::SUCCESS }
}
