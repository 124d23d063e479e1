//! The measured beam accelerances of `tests/data/measured/` (source and licence in its
//! README), written into recipes and run.

use super::{Ran, run_at};
use std::path::{Path, PathBuf};

/// A file of `tests/data/measured/`.
pub fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/measured").join(name)
}

/// Writes `recipe` (with `BEAM` standing for the measured file) into a temporary folder.
pub fn recipe_file(recipe: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let text = recipe.replace("BEAM", &data("beam-accelerance.uff").display().to_string());
    let path = dir.path().join("recipe.yaml");
    std::fs::write(&path, text).unwrap();
    (dir, path)
}

/// Runs `recipe` in the library (no cache).
pub fn run_recipe(recipe: &str) -> (tempfile::TempDir, Ran) {
    let (dir, path) = recipe_file(recipe);
    let ran = run_at(&path, &dir.path().join("out"));
    (dir, ran)
}
