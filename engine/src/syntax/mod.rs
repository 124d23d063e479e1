//! Syntax: recipe text (YAML or a Rhai script) to a raw tree that keeps every value's location.
//!
//! This is the first of the two recipe stages: close to the text, no meaning yet.
//! [`crate::model`] turns the raw tree into a resolved, typed recipe.

pub mod edit;
pub mod emit;
mod raw;
mod rhai_recipe;
mod yaml;

pub use edit::RecipeText;
pub use emit::{emit, yaml_quoted};
pub use raw::{Key, Raw, RawKind};
/// The Rhai crate, so nodes that evaluate expressions use the same version and sandbox.
pub use rhai;
pub use rhai_recipe::{RecipeModules, RhaiLimits, load_rhai, load_rhai_with_modules, sandboxed_engine};
pub use yaml::load_yaml;

use crate::diag::{Diagnostic, Diagnostics, SourceFile, Span};
use std::path::Path;
use std::sync::Arc;

/// The largest recipe file read, in bytes: a recipe is a page of text, not a data set.
pub const MAX_RECIPE_BYTES: u64 = 4 * 1024 * 1024;

/// A recipe file read from disk and parsed into its raw tree.
pub struct LoadedSource {
    pub file: SourceFile,
    pub raw: Option<Raw>,
    /// The modules a Rhai recipe imported, in the order read.
    pub modules: Vec<SourceFile>,
}

impl LoadedSource {
    /// The recipe file and every module it imported, as diagnostics quote them.
    pub fn sources(&self) -> Vec<SourceFile> {
        std::iter::once(self.file.clone()).chain(self.modules.iter().cloned()).collect()
    }
}

enum RecipeRead {
    TooLarge,
    Io(std::io::Error),
}

/// The bytes of a recipe, at most [`MAX_RECIPE_BYTES`] of them, from any kind of file.
fn read_recipe_bytes(path: &Path) -> Result<Vec<u8>, RecipeRead> {
    let bytes = read_up_to(path, MAX_RECIPE_BYTES).map_err(RecipeRead::Io)?;
    if bytes.len() as u64 > MAX_RECIPE_BYTES { Err(RecipeRead::TooLarge) } else { Ok(bytes) }
}

/// At most `cap + 1` bytes of any kind of file the user names. It is opened without waiting
/// for a writer (`O_NONBLOCK`): a pipe nobody writes reads as empty at once, one being written
/// (`<(…)`) is read as its data comes, `/dev/zero` as far as the cap.
pub fn read_up_to(path: &Path, cap: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let mut o = std::fs::OpenOptions::new();
    o.read(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::custom_flags(&mut o, libc::O_NONBLOCK);
    let mut f = o.open(path)?.take(cap + 1);
    let mut bytes = Vec::new();
    let mut chunk = [0u8; 64 * 1024];
    loop {
        match f.read(&mut chunk) {
            Ok(0) => return Ok(bytes),
            Ok(n) => bytes.extend_from_slice(&chunk[..n]),
            // A pipe whose writer has not written yet.
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                std::thread::sleep(std::time::Duration::from_millis(5));
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
}

/// Reads a recipe file (`.yaml`, `.yml` or `.rhai`) and parses it, pushing every problem found.
pub fn load_file(path: &Path, diags: &mut Diagnostics) -> Option<LoadedSource> {
    let shown: Arc<str> = Arc::from(path.display().to_string());
    let span = Span::file_only(shown.clone());
    // Read at most one byte past the cap, whatever the file is (`/dev/zero`, a pipe).
    if std::fs::metadata(path).is_ok_and(|m| m.is_dir()) {
        diags.push(
            Diagnostic::error(Some(span), "cannot read the recipe: it is a folder").with_help("name a recipe file"),
        );
        return None;
    }
    let bytes = match read_recipe_bytes(path) {
        Ok(b) => b,
        Err(RecipeRead::TooLarge) => {
            let size = match std::fs::metadata(path) {
                Ok(m) if m.is_file() => format!("{} bytes", m.len()),
                _ => "longer than that".to_string(),
            };
            diags.push(
                Diagnostic::error(
                    Some(span),
                    format!("the recipe is {size}, over the {MAX_RECIPE_BYTES} byte limit for a recipe"),
                )
                .with_help("keep measured data in CSV or UFF files and name them in the recipe"),
            );
            return None;
        }
        Err(RecipeRead::Io(e)) => {
            diags.push(
                Diagnostic::error(Some(span), format!("cannot read the recipe: {e}")).with_help("check the path"),
            );
            return None;
        }
    };
    let text = match String::from_utf8(bytes) {
        Ok(t) => t,
        Err(e) => {
            let valid = e.utf8_error().valid_up_to();
            let prefix = String::from_utf8_lossy(&e.as_bytes()[..valid]).to_string();
            let line = prefix.matches('\n').count() as u32 + 1;
            let column = prefix.rsplit('\n').next().map(|l| l.chars().count()).unwrap_or(0) as u32 + 1;
            diags.push(
                Diagnostic::error(
                    Some(Span { file: shown, line, column, bytes: None }),
                    format!("the recipe is not valid UTF-8 (byte {valid})"),
                )
                .with_help("save the file as UTF-8"),
            );
            return None;
        }
    };
    let file = SourceFile { path: shown, text: Arc::from(text) };
    let is_rhai = path.extension().is_some_and(|e| e == "rhai");
    let (raw, modules) = if is_rhai {
        load_rhai_with_modules(&file, &RhaiLimits::default(), diags)
    } else {
        (load_yaml(&file, diags), Vec::new())
    };
    Some(LoadedSource { file, raw, modules })
}
