//! What a plot shows, independent of how it is drawn: panels stacked top to bottom, each with
//! two axes in display units and a list of series.

/// A figure: a title and panels stacked top to bottom that share nothing but the width.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    pub title: String,
    pub panels: Vec<Panel>,
}

/// One chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    pub x: Axis,
    pub y: Axis,
    pub series: Vec<Series>,
    /// Same scale on both axes (a polar plot drawn in x–y).
    pub equal_aspect: bool,
    /// Relative height among the figure's panels.
    pub weight: u32,
    /// A colour bar in the legend for a long sweep drawn on the ramp: what the colour means.
    pub color_bar: Option<ColorBar>,
}

/// What the ramp colours of a long sweep stand for: the coordinate and its first and last
/// values as written (`speed [rpm]`, 0 → 4000).
#[derive(Debug, Clone, PartialEq)]
pub struct ColorBar {
    pub label: String,
    pub from: f64,
    pub to: f64,
}

/// An axis: its label (with the unit shown) and whether it is logarithmic.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    pub label: String,
    pub log: bool,
    /// A fixed range instead of the data's (coherence from 0 to 1).
    pub fixed: Option<(f64, f64)>,
    /// A fixed start with the data's end (a depth from 0).
    pub start: Option<f64>,
}

impl Axis {
    pub fn linear(label: impl Into<String>) -> Axis {
        Axis { label: label.into(), log: false, fixed: None, start: None }
    }
    pub fn log(label: impl Into<String>) -> Axis {
        Axis { label: label.into(), log: true, fixed: None, start: None }
    }
    pub fn fixed(mut self, lo: f64, hi: f64) -> Axis {
        self.fixed = Some((lo, hi));
        self
    }
    /// A linear axis that starts at zero whatever the data.
    pub fn from_zero(mut self) -> Axis {
        self.start = Some(0.0);
        self
    }
}

/// How a series is drawn.
#[derive(Debug, Clone, PartialEq)]
pub enum Style {
    Line,
    /// A dashed line: a reference (the stationary diagram, the 1× line), or the second of two
    /// kinds drawn together (a measurement over a model).
    Dashed,
    /// Open circles (stable trials).
    Circles,
    /// Crosses (chattering trials).
    Crosses,
    /// Open squares (trials that no diagram scores: outside its speeds).
    Squares,
    /// Filled dots (modes).
    Dots,
    /// A shaded band between the series' points (lower) and these (upper), same x.
    Band(Vec<(f64, f64)>),
    /// Vertical lines at the points' x (mode markers).
    VLines,
    /// A vertical line from the axis to each point (the harmonics of a spectrum).
    Stems,
}

/// A named set of points in display units.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    pub style: Style,
    pub color: Color,
}

/// A series' colour: a palette entry (series that belong together share one), or a place on
/// a sequential ramp from 0 to 1 (the points of a sweep, in order).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Color {
    Palette(usize),
    Ramp(f64),
}

impl From<usize> for Color {
    fn from(i: usize) -> Color {
        Color::Palette(i)
    }
}

impl Series {
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>, style: Style, color: impl Into<Color>) -> Series {
        Series { name: name.into(), points, style, color: color.into() }
    }
}

/// The colour of the `i`-th of `n` sweep points: palette entries for a few, a ramp for many.
pub fn sweep_color(i: usize, n: usize) -> Color {
    if n <= 10 { Color::Palette(i) } else { Color::Ramp(i as f64 / (n - 1) as f64) }
}

/// Whether the `i`-th of `n` sweep points gets a legend entry: all of a few, about eight
/// evenly spread (first and last included) of many.
pub fn sweep_labelled(i: usize, n: usize) -> bool {
    n <= 10 || i == n - 1 || i.is_multiple_of(n.div_ceil(8))
}

impl Panel {
    pub fn new(x: Axis, y: Axis) -> Panel {
        Panel { x, y, series: Vec::new(), equal_aspect: false, weight: 1, color_bar: None }
    }
}
