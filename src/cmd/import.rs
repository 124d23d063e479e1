//! `import`: a case file written as a recipe (and a library).

use crate::*;

/// `spindlelab import CASE`: writes (or prints) the recipe of a baseline case file, and its library if asked.
pub(crate) fn cmd_import(case: &Path, out: Option<PathBuf>, library: Option<PathBuf>) -> ExitCode {
    let shown = case.display().to_string();
    let text = match engine::formats::read_text_capped(case, engine::formats::MAX_CASE_BYTES) {
        Ok(t) => t,
        Err(e) => {
            eoutln!("error: cannot read {}: {e}", esc(&shown));
            return ExitCode::from(EXIT_BAD_INPUT);
        }
    };
    // The recipe names the case's data files from its own folder (the current one when
    // it is printed).
    let recipe_dir = out.as_deref().and_then(Path::parent).unwrap_or(Path::new(""));
    let folder = |p: &'_ Path| if p.as_os_str().is_empty() { Path::new(".").to_path_buf() } else { p.to_path_buf() };
    let (case_dir, recipe_folder) = (folder(case.parent().unwrap_or(Path::new(""))), folder(recipe_dir));
    let placement = spindlelab::import::Placement { case_dir: &case_dir, recipe_dir: &recipe_folder };
    let imported = match &library {
        None => spindlelab::import::recipe_from_case_at(&text, &shown, placement).map(|r| (None, r)),
        Some(lib) => {
            let use_path = relative_to(lib, recipe_dir);
            spindlelab::import::library_from_case(&text, &shown, &use_path, Some(placement)).map(|(l, r)| (Some(l), r))
        }
    };
    let (library_text, recipe) = match imported {
        Ok(r) => r,
        Err(e) => {
            eoutln!("error: {}", esc(&e));
            return ExitCode::from(EXIT_BAD_INPUT);
        }
    };
    let files = [(library.as_ref(), library_text.as_deref()), (out.as_ref(), Some(recipe.as_str()))];
    if let Err(code) = write_together(&files) {
        return code;
    }
    if out.is_none() {
        out!("{recipe}");
    }
    ExitCode::SUCCESS
}
