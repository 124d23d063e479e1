//! The measured beam accelerances of another lab, written into recipes and run
//! (`measured_sets.rs` fits each FRF alone, `measured_set_fit.rs` the three together). The file
//! is not in the repository: it is read from `../shared/data/measured/beam-accelerance/` beside
//! the checkout (source and licence in the README there); without it the tests that need it
//! say so and pass, except under CI (`CI` set), where its absence fails them.

use super::{Ran, run_at, shared};
use std::path::{Path, PathBuf};

/// The measured file, or `None` when `../shared` does not hold it (`what` is then skipped).
pub fn beam_file(what: &str) -> Option<PathBuf> {
    shared("data/measured/beam-accelerance/beam-accelerance.uff", what)
}

/// Writes `recipe` (with `BEAM` standing for the measured file `beam`) into a temporary folder.
pub fn recipe_file(beam: &Path, recipe: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let text = recipe.replace("BEAM", &beam.display().to_string());
    let path = dir.path().join("recipe.yaml");
    std::fs::write(&path, text).unwrap();
    (dir, path)
}

/// Runs `recipe` in the library (no cache).
pub fn run_recipe(beam: &Path, recipe: &str) -> (tempfile::TempDir, Ran) {
    let (dir, path) = recipe_file(beam, recipe);
    let ran = run_at(&path, &dir.path().join("out"));
    (dir, ran)
}
