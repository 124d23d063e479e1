//! Plots of port values, for outputs named `.svg` or `.png` and for the run report. A value
//! becomes a [`Figure`] by the default view of its type ([`of`]), in the units a person reads,
//! and plotters draws the figure with a bundled font, so the bytes depend on the values only.

pub mod draw;
pub mod figure;
pub mod of;
pub mod sets;

pub use figure::{Axis, Figure, Panel, Series, Style};
pub use of::{Layer, accepts, figure, variants};

/// Why a value could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("nothing to draw")]
    Empty,
    #[error("a {0} has no plot; write it as `.json`")]
    NoPlot(String),
    #[error("{0}")]
    Mixed(String),
    #[error("drawing failed: {0}")]
    Draw(String),
}

/// A plot file's format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlotFormat {
    Svg,
    Png,
}

/// The figure of `main` with `with` drawn over it, as the bytes of an SVG or PNG file.
pub fn render(
    format: PlotFormat,
    title: &str,
    variant: Option<&str>,
    main: &[Layer],
    with: &[Layer],
) -> Result<Vec<u8>, PlotError> {
    let fig = figure(title, variant, main, with)?;
    match format {
        PlotFormat::Svg => draw::svg(&fig).map(String::into_bytes),
        PlotFormat::Png => draw::png(&fig),
    }
}
