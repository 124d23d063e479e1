//! A [`Figure`] drawn by plotters, as SVG text or PNG bytes. Text is laid out with the bundled
//! DejaVu Sans, so the bytes depend on the figure only (no system fonts, no timestamps).

use super::PlotError;
use super::figure::{Color as Shade, Figure, Panel, Style};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::sync::OnceLock;

/// DejaVu Sans, cut to Latin, Greek and the symbols plots use (`assets/DejaVuSans-LICENSE.txt`).
const FONT: &[u8] = include_bytes!("../../assets/DejaVuSans-subset.ttf");
const FAMILY: &str = "sans-serif";

/// Width of every plot, pixels; the height follows from the panels.
pub const WIDTH: u32 = 900;
const PANEL_HEIGHT: u32 = 320;
const TITLE_HEIGHT: u32 = 40;

/// A palette that stays apart in print and for the common colour-vision deficiencies (Tableau 10).
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Viridis at eight stops, interpolated: a ramp that reads in order in grey as in colour.
const RAMP: [(u8, u8, u8); 8] = [
    (68, 1, 84),
    (70, 50, 127),
    (54, 92, 141),
    (39, 127, 142),
    (31, 161, 135),
    (74, 194, 109),
    (159, 218, 58),
    (253, 231, 37),
];

fn rgb(c: Shade) -> RGBColor {
    match c {
        Shade::Palette(i) => PALETTE[i % PALETTE.len()],
        Shade::Ramp(t) => {
            let x = t.clamp(0.0, 1.0) * (RAMP.len() - 1) as f64;
            let k = (x.floor() as usize).min(RAMP.len() - 2);
            let f = x - k as f64;
            let mix = |a: u8, b: u8| (a as f64 + f * (b as f64 - a as f64)).round() as u8;
            let (a, b) = (RAMP[k], RAMP[k + 1]);
            RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
        }
    }
}

/// Makes the bundled font the plots' `sans-serif` (once per process).
pub fn register_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok { Ok(()) } else { Err(PlotError::Draw("the bundled font could not be loaded".into())) }
}

fn err<E: std::fmt::Debug>(e: E) -> PlotError {
    PlotError::Draw(format!("{e:?}"))
}

/// Total height of a figure, pixels.
pub fn height(fig: &Figure) -> u32 {
    TITLE_HEIGHT + fig.panels.iter().map(|p| PANEL_HEIGHT * p.weight.max(1) / 2 + PANEL_HEIGHT / 2).sum::<u32>()
}

/// The figure as SVG text.
pub fn svg(fig: &Figure) -> Result<String, PlotError> {
    register_font()?;
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (WIDTH, height(fig))).into_drawing_area();
        draw(&root, fig)?;
        root.present().map_err(err)?;
    }
    Ok(out)
}

/// The figure as PNG bytes.
pub fn png(fig: &Figure) -> Result<Vec<u8>, PlotError> {
    register_font()?;
    let (w, h) = (WIDTH, height(fig));
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        draw(&root, fig)?;
        root.present().map_err(err)?;
    }
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().map_err(err)?;
        writer.write_image_data(&rgb).map_err(err)?;
    }
    Ok(bytes)
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, fig: &Figure) -> Result<(), PlotError> {
    root.fill(&WHITE).map_err(err)?;
    let area = root.titled(&fig.title, (FAMILY, 20)).map_err(err)?;
    let total: u32 = fig.panels.iter().map(|p| p.weight.max(1)).sum();
    let (_, h) = area.dim_in_pixel();
    let mut rest = area;
    let mut used = 0u32;
    for (i, p) in fig.panels.iter().enumerate() {
        let this = if i + 1 == fig.panels.len() {
            rest.clone()
        } else {
            used += p.weight.max(1);
            let at = (h as u64 * used as u64 / total as u64) as i32
                - (h as u64 * (used - p.weight.max(1)) as u64 / total as u64) as i32;
            let (top, bottom) = rest.split_vertically(at);
            rest = bottom;
            top
        };
        panel(&this, p)?;
    }
    Ok(())
}

/// The value as plotted on an axis: its log10 on a log axis (non-positive values dropped).
fn mapped(v: f64, log: bool) -> Option<f64> {
    match (log, v.is_finite()) {
        (_, false) => None,
        (true, _) if v <= 0.0 => None,
        (true, _) => Some(v.log10()),
        (false, _) => Some(v),
    }
}

/// The points as runs of finite, plottable points (a gap where a value is not).
fn runs(points: &[(f64, f64)], p: &Panel) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
    for &(x, y) in points {
        match (mapped(x, p.x.log), mapped(y, p.y.log)) {
            (Some(x), Some(y)) => out.last_mut().expect("one run").push((x, y)),
            _ if out.last().is_some_and(|r| !r.is_empty()) => out.push(Vec::new()),
            _ => {}
        }
    }
    out.retain(|r| !r.is_empty());
    out
}

fn range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !(lo.is_finite() && hi.is_finite()) {
        return (0.0, 1.0);
    }
    if log {
        let (a, b) = (lo.floor(), hi.ceil());
        return if b > a { (a, b) } else { (a - 1.0, a + 1.0) };
    }
    if hi - lo <= f64::EPSILON * hi.abs().max(lo.abs()).max(1e-300) {
        let d = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
        return (lo - d, hi + d);
    }
    let pad = 0.04 * (hi - lo);
    (lo - pad, hi + pad)
}

/// A tick label: plain for ordinary magnitudes, scientific beyond.
fn tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.1e}");
    }
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.to_string() }
}

/// A decade label on a log axis (integer exponents only).
fn decade(v: f64) -> String {
    if (v - v.round()).abs() > 1e-9 {
        return String::new();
    }
    tick(10f64.powi(v.round() as i32))
}

fn panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Result<(), PlotError> {
    let xs = p.series.iter().flat_map(|s| {
        let band = match &s.style {
            Style::Band(upper) => upper.clone(),
            _ => vec![],
        };
        s.points.iter().chain(band.iter()).filter_map(|&(x, _)| mapped(x, p.x.log)).collect::<Vec<_>>()
    });
    let mut xr = range(xs, p.x.log);
    let ys = p.series.iter().filter(|s| s.style != Style::VLines).flat_map(|s| {
        let band = match &s.style {
            Style::Band(upper) => upper.clone(),
            _ => vec![],
        };
        s.points.iter().chain(band.iter()).filter_map(|&(_, y)| mapped(y, p.y.log)).collect::<Vec<_>>()
    });
    let mut yr = range(ys, p.y.log);
    if let Some(r) = p.x.fixed {
        xr = r;
    }
    if let Some(r) = p.y.fixed {
        yr = r;
    }
    if p.equal_aspect {
        let half = 0.5 * (xr.1 - xr.0).max(yr.1 - yr.0);
        let (cx, cy) = (0.5 * (xr.0 + xr.1), 0.5 * (yr.0 + yr.1));
        xr = (cx - half, cx + half);
        yr = (cy - half, cy + half);
    }
    let area = if p.equal_aspect {
        // A square plotting region in the middle of the panel.
        let (w, h) = area.dim_in_pixel();
        let side = h.min(w);
        let margin = (w.saturating_sub(side + 60)) / 2;
        area.margin(0, 0, margin as i32, margin as i32)
    } else {
        area.clone()
    };
    let mut chart = ChartBuilder::on(&area)
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(72)
        .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
        .map_err(err)?;
    let fx = |v: &f64| if p.x.log { decade(*v) } else { tick(*v) };
    let fy = |v: &f64| if p.y.log { decade(*v) } else { tick(*v) };
    let label_font = (FAMILY, 14);
    chart
        .configure_mesh()
        .x_desc(p.x.label.as_str())
        .y_desc(p.y.label.as_str())
        .x_labels(if p.x.log { (xr.1 - xr.0) as usize + 1 } else { 9 })
        .y_labels(if p.y.log { (yr.1 - yr.0) as usize + 1 } else { 6 })
        .x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .label_style(label_font)
        .axis_desc_style((FAMILY, 15))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(205, 205, 205))
        .draw()
        .map_err(err)?;
    let mut labelled = false;
    for s in &p.series {
        let color = rgb(s.color);
        match &s.style {
            Style::Line | Style::Dashed => {
                for run in runs(&s.points, p) {
                    if s.style == Style::Dashed {
                        chart.draw_series(DashedLineSeries::new(run, 6, 4, color.stroke_width(1))).map_err(err)?;
                    } else {
                        chart.draw_series(LineSeries::new(run, color.stroke_width(2))).map_err(err)?;
                    }
                }
            }
            Style::Circles | Style::Crosses | Style::Dots => {
                let pts: Vec<(f64, f64)> = runs(&s.points, p).concat();
                let style = color.stroke_width(2);
                match s.style {
                    Style::Circles => chart.draw_series(pts.iter().map(|&q| Circle::new(q, 5, style))).map_err(err)?,
                    Style::Crosses => chart.draw_series(pts.iter().map(|&q| Cross::new(q, 5, style))).map_err(err)?,
                    _ => {
                        let r = if pts.len() > 200 { 2 } else { 4 };
                        chart.draw_series(pts.iter().map(|&q| Circle::new(q, r, color.filled()))).map_err(err)?
                    }
                };
            }
            Style::Band(upper) => {
                let lower: Vec<(f64, f64)> = runs(&s.points, p).concat();
                let mut top: Vec<(f64, f64)> = runs(upper, p).concat();
                top.reverse();
                let polygon: Vec<(f64, f64)> = lower.into_iter().chain(top).collect();
                chart.draw_series(std::iter::once(Polygon::new(polygon, color.mix(0.25).filled()))).map_err(err)?;
            }
            Style::VLines => {
                let lines = s
                    .points
                    .iter()
                    .filter_map(|&(x, _)| mapped(x, p.x.log))
                    .map(|x| PathElement::new(vec![(x, yr.0), (x, yr.1)], color.mix(0.6).stroke_width(1)));
                chart.draw_series(lines).map_err(err)?;
            }
        }
        if !s.name.is_empty() {
            labelled = true;
            let legend = s.style.clone();
            chart
                .draw_series(std::iter::empty::<PathElement<(f64, f64)>>())
                .map_err(err)?
                .label(s.name.as_str())
                .legend(move |(x, y)| -> DynElement<'static, DB, (i32, i32)> {
                    match legend {
                        Style::Circles => Circle::new((x + 10, y), 5, color.stroke_width(2)).into_dyn(),
                        Style::Crosses => Cross::new((x + 10, y), 5, color.stroke_width(2)).into_dyn(),
                        Style::Dots => Circle::new((x + 10, y), 4, color.filled()).into_dyn(),
                        Style::Band(_) => {
                            Rectangle::new([(x, y - 5), (x + 20, y + 5)], color.mix(0.25).filled()).into_dyn()
                        }
                        _ => PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)).into_dyn(),
                    }
                });
        }
    }
    if labelled {
        chart
            .configure_series_labels()
            .label_font((FAMILY, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(180, 180, 180))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(err)?;
    }
    Ok(())
}
