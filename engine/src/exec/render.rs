//! What a run asks of a renderer: a figure drawn as a file, and the run report. The engine
//! decides what a plot shows ([`crate::plot::figure`]); a renderer (the `spindlelab-render`
//! crate) decides how it is drawn, so the engine depends on no drawing library.

use super::Manifest;
use crate::plot::{Figure, PlotError, PlotFormat};

/// The report's file name inside a run folder (`run --report`).
pub const REPORT_FILE: &str = "report.html";

/// Draws figures and writes run reports. A run that asks for a plot or a report needs one
/// ([`crate::exec::RunOptions::renderer`]).
pub trait Renderer: Send + Sync + std::fmt::Debug {
    /// `fig` as the bytes of an SVG or PNG file; the same figure gives the same bytes.
    fn draw(&self, fig: &Figure, format: PlotFormat) -> Result<Vec<u8>, PlotError>;
    /// The self-contained HTML report of a run: its manifest, the recipe's text and the files
    /// written (name and bytes, as in the folder).
    fn report(&self, manifest: &Manifest, recipe_text: Option<&str>, files: &[(String, Vec<u8>)]) -> String;
}
