//! Plots of port values, for outputs named `.svg` or `.png` and for the run report. A value
//! becomes a [`Figure`] by the default view of its type ([`of`]), in the units a person reads;
//! a [`crate::render::Renderer`] draws the figure.

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
