//! `report`: the HTML report of a finished run or diagnosis.

use crate::*;

/// `spindlelab report RUN_DIR`: the HTML report of a finished run, from its manifest and the
/// files the manifest lists (each read through the data-file cap).
pub(crate) fn report_command(run_dir: &Path, out: Option<PathBuf>) -> ExitCode {
    let target_for = |out: Option<PathBuf>| out.unwrap_or_else(|| report_beside(run_dir));
    // A batch of diagnoses: the summary, and each case's diagnosis on the same page.
    if run_dir.join("summary.md").is_file() && run_dir.join("summary.csv").is_file() {
        return match spindlelab::diagnose::batch::report_html(run_dir) {
            Ok(html) => write_report(&target_for(out), html),
            Err(e) => {
                eoutln!("error: {}; rerun `spindlelab diagnose --batch` into that folder", esc(&e));
                ExitCode::from(EXIT_BAD_INPUT)
            }
        };
    }
    // A diagnosis folder: its page and pictures.
    if run_dir.join("diagnosis.md").is_file() && run_dir.join("diagnosis.json").is_file() {
        return match spindlelab::diagnose::report_html(run_dir) {
            Ok(html) => write_report(&target_for(out), html),
            Err(e) => {
                eoutln!("error: {}; rerun `spindlelab diagnose` into that folder", esc(&e));
                ExitCode::from(EXIT_BAD_INPUT)
            }
        };
    }
    let Some(manifest) = engine::exec::Manifest::read(run_dir) else {
        eoutln!(
            "error: {} holds no readable manifest.json; give the output folder of a run (`spindlelab run` writes it) or of a diagnosis (`spindlelab diagnose`)",
            run_dir.display()
        );
        return ExitCode::from(EXIT_BAD_INPUT);
    };
    let mut files = Vec::new();
    for name in manifest.files.keys() {
        if name == engine::render::REPORT_FILE || name.starts_with('.') || name.contains("..") {
            continue;
        }
        match engine::formats::read_capped(&run_dir.join(name), engine::formats::MAX_DATA_BYTES) {
            Ok(bytes) => files.push((name.clone(), bytes)),
            Err(e) => {
                eoutln!(
                    "error: {}: {e}; the folder no longer matches its manifest (rerun the recipe)",
                    run_dir.join(name).display()
                );
                return ExitCode::from(EXIT_BAD_INPUT);
            }
        }
    }
    let text = (!manifest.recipe_text.is_empty()).then_some(manifest.recipe_text.as_str());
    let html = spindlelab::render::report::html(&manifest, text, &files);
    write_report(&target_for(out), html)
}

/// Where `report DIR` writes by default: `DIR.report.html` beside the folder, as a plain path
/// (`out/x` gives `out/x.report.html`); a folder named `.` or `..` is resolved first.
pub(crate) fn report_beside(run_dir: &Path) -> PathBuf {
    let dir = match run_dir.file_name() {
        Some(_) => Some(run_dir.to_path_buf()),
        None => run_dir.canonicalize().ok(),
    };
    match dir.as_deref().and_then(|d| Some((d.parent()?, d.file_name()?))) {
        Some((parent, name)) => parent.join(format!("{}.report.html", name.to_string_lossy())),
        None => run_dir.join("..").join("run.report.html"),
    }
}

/// Writes a report page whole (a temporary file renamed into place).
pub(crate) fn write_report(target: &Path, html: String) -> ExitCode {
    let tmp = target.with_extension("html.tmp");
    if let Err(e) = std::fs::write(&tmp, html).and_then(|_| std::fs::rename(&tmp, target)) {
        let _ = std::fs::remove_file(&tmp);
        eoutln!("error: cannot write {}: {e}", target.display());
        return ExitCode::from(EXIT_FAILURE);
    }
    outln!("wrote {}", target.display());
    ExitCode::SUCCESS
}
