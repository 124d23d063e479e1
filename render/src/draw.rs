//! A [`Figure`] drawn by plotters, as SVG text or PNG bytes. Text is laid out with the bundled
//! DejaVu Sans, so the bytes depend on the figure only (no system fonts, no timestamps).

use plotters::coord::Shift;
use plotters::prelude::*;
use spindlelab_engine::plot::PlotError;
use spindlelab_engine::plot::figure::{Color as Shade, ColorBar, Figure, Panel, Series, Style};
use std::sync::OnceLock;

/// DejaVu Sans, cut to Latin, Greek and the symbols plots use (`assets/DejaVuSans-LICENSE.txt`).
const FONT: &[u8] = include_bytes!("../assets/DejaVuSans-subset.ttf");
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
        // Line art: the adaptive filter and full compression make files a fraction the size.
        enc.set_compression(png::Compression::Best);
        enc.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
        let mut writer = enc.write_header().map_err(err)?;
        writer.write_image_data(&rgb).map_err(err)?;
    }
    Ok(bytes)
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, fig: &Figure) -> Result<(), PlotError> {
    root.fill(&WHITE).map_err(err)?;
    // A long title (a diagram's cut) in a smaller font, so it fits the width.
    let size = (1.75 * (WIDTH - 30) as f64 / fig.title.chars().count().max(1) as f64).clamp(12.0, 20.0);
    let area = root.titled(&fig.title, (FAMILY, size)).map_err(err)?;
    let total: u32 = fig.panels.iter().map(|p| p.weight.max(1)).sum();
    // Every panel keeps the legend column when one has a legend, so their axes line up.
    let legend_column = fig.panels.iter().any(|p| p.color_bar.is_some() || p.series.iter().any(|s| !s.name.is_empty()));
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
        panel(&this, p, legend_column)?;
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

/// The points as runs of finite, plottable points inside the axes' ranges (a gap where a value
/// is not, so a line never leaves its panel).
fn runs(points: &[(f64, f64)], p: &Panel, xr: (f64, f64), yr: (f64, f64)) -> Vec<Vec<(f64, f64)>> {
    let inside = |v: f64, (lo, hi): (f64, f64)| {
        let tol = 1e-9 * (hi - lo).abs();
        v >= lo - tol && v <= hi + tol
    };
    let mut out: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
    for &(x, y) in points {
        match (mapped(x, p.x.log), mapped(y, p.y.log)) {
            (Some(x), Some(y)) if inside(x, xr) && inside(y, yr) => out.last_mut().expect("one run").push((x, y)),
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

fn panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel, legend_column: bool) -> Result<(), PlotError> {
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
    if let (Some(lo), false) = (p.y.start, p.y.log) {
        yr.0 = lo;
        yr.1 = yr.1.max(lo + f64::EPSILON);
    }
    if p.equal_aspect {
        let half = 0.5 * (xr.1 - xr.0).max(yr.1 - yr.0);
        let (cx, cy) = (0.5 * (xr.0 + xr.1), 0.5 * (yr.0 + yr.1));
        xr = (cx - half, cx + half);
        yr = (cy - half, cy + half);
    }
    // The legend in a column of its own beside the chart, never over the data.
    let named: Vec<&Series> = p.series.iter().filter(|s| !s.name.is_empty()).collect();
    let (area, legend_area) = if !legend_column {
        (area.clone(), None)
    } else {
        let (w, _) = area.dim_in_pixel();
        let (chart, legend) = area.split_horizontally(w.saturating_sub(LEGEND_WIDTH) as i32);
        (chart, Some(legend))
    };
    let area = if p.equal_aspect {
        // A square plotting region in the middle of the panel: the chart's margins (12 each
        // side) and label areas (72 left, 42 below) taken off first.
        let (w, h) = area.dim_in_pixel();
        let (pw, ph) = (w as i32 - 96, h as i32 - 66);
        if pw > ph {
            let m = (pw - ph) / 2;
            area.margin(0, 0, m, m)
        } else {
            let m = (ph - pw) / 2;
            area.margin(m, m, 0, 0)
        }
    } else {
        area
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
    for s in &p.series {
        let color = rgb(s.color);
        match &s.style {
            Style::Line | Style::Dashed => {
                for run in runs(&s.points, p, xr, yr) {
                    if s.style == Style::Dashed {
                        chart.draw_series(DashedLineSeries::new(run, 7, 4, color.stroke_width(2))).map_err(err)?;
                    } else {
                        chart.draw_series(LineSeries::new(run, color.stroke_width(2))).map_err(err)?;
                    }
                }
            }
            Style::Circles | Style::Crosses | Style::Squares | Style::Dots => {
                let pts: Vec<(f64, f64)> = runs(&s.points, p, xr, yr).concat();
                let style = color.stroke_width(2);
                match s.style {
                    Style::Circles => chart.draw_series(pts.iter().map(|&q| Circle::new(q, 5, style))).map_err(err)?,
                    Style::Crosses => chart.draw_series(pts.iter().map(|&q| Cross::new(q, 5, style))).map_err(err)?,
                    Style::Squares => chart
                        .draw_series(
                            pts.iter().map(|&q| EmptyElement::at(q) + Rectangle::new([(-4, -4), (4, 4)], style)),
                        )
                        .map_err(err)?,
                    _ => {
                        let r = if pts.len() > 200 { 2 } else { 4 };
                        chart.draw_series(pts.iter().map(|&q| Circle::new(q, r, color.filled()))).map_err(err)?
                    }
                };
            }
            Style::Band(upper) => {
                let lower: Vec<(f64, f64)> = runs(&s.points, p, xr, yr).concat();
                let mut top: Vec<(f64, f64)> = runs(upper, p, xr, yr).concat();
                top.reverse();
                let polygon: Vec<(f64, f64)> = lower.into_iter().chain(top).collect();
                chart.draw_series(std::iter::once(Polygon::new(polygon, color.mix(0.25).filled()))).map_err(err)?;
            }
            Style::Stems => {
                let base = if p.y.log { yr.0 } else { 0.0f64.clamp(yr.0, yr.1) };
                let stems = runs(&s.points, p, xr, yr)
                    .concat()
                    .into_iter()
                    .map(|(x, y)| PathElement::new(vec![(x, base), (x, y)], color.stroke_width(2)));
                chart.draw_series(stems).map_err(err)?;
            }
            Style::VLines => {
                let lines = s
                    .points
                    .iter()
                    .filter_map(|&(x, _)| mapped(x, p.x.log))
                    .filter(|x| (xr.0..=xr.1).contains(x))
                    .map(|x| PathElement::new(vec![(x, yr.0), (x, yr.1)], color.mix(0.6).stroke_width(1)));
                chart.draw_series(lines).map_err(err)?;
            }
        }
    }
    if let Some(legend_area) = legend_area {
        legend(&legend_area, &named, p.color_bar.as_ref())?;
    }
    Ok(())
}

/// Width of the legend column beside a chart, pixels.
const LEGEND_WIDTH: u32 = 230;
const LEGEND_LINE: i32 = 17;
/// Characters of a legend line that fit the column at the legend's font size.
const LEGEND_CHARS: usize = 27;

/// A series' sample in the legend, centred vertically on `y` from `x` to `x + 22`.
fn glyph<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    style: &Style,
    color: RGBColor,
    (x, y): (i32, i32),
) -> Result<(), PlotError> {
    let pen = color.stroke_width(2);
    match style {
        Style::Circles => area.draw(&Circle::new((x + 11, y), 5, pen)),
        Style::Crosses => area.draw(&Cross::new((x + 11, y), 5, pen)),
        Style::Squares => area.draw(&Rectangle::new([(x + 7, y - 4), (x + 15, y + 4)], pen)),
        Style::Dots => area.draw(&Circle::new((x + 11, y), 4, color.filled())),
        Style::Band(_) => area.draw(&Rectangle::new([(x, y - 5), (x + 22, y + 5)], color.mix(0.25).filled())),
        Style::Dashed => {
            area.draw(&PathElement::new(vec![(x, y), (x + 8, y)], pen)).map_err(err)?;
            area.draw(&PathElement::new(vec![(x + 13, y), (x + 22, y)], pen))
        }
        Style::VLines => {
            area.draw(&PathElement::new(vec![(x + 11, y - 6), (x + 11, y + 6)], color.mix(0.6).stroke_width(1)))
        }
        Style::Line => area.draw(&PathElement::new(vec![(x, y), (x + 22, y)], pen)),
        Style::Stems => area.draw(&PathElement::new(vec![(x + 11, y + 6), (x + 11, y - 6)], pen)),
    }
    .map_err(err)
}

/// A legend name in lines of at most [`LEGEND_CHARS`] characters, broken at spaces (two lines
/// at most, the second cut with `…`).
fn legend_lines(name: &str) -> Vec<String> {
    let mut lines: Vec<String> = vec![String::new()];
    for word in name.split(' ') {
        let line = lines.last_mut().expect("one line");
        if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > LEGEND_CHARS {
            lines.push(String::new());
        }
        let line = lines.last_mut().expect("one line");
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    if lines.len() > 2 {
        let rest = lines.split_off(1).join(" ");
        lines.push(rest);
    }
    for l in &mut lines {
        if l.chars().count() > LEGEND_CHARS {
            *l = l.chars().take(LEGEND_CHARS - 1).collect::<String>() + "…";
        }
    }
    lines
}

/// The legend column: each named series' sample and name, as many as fit (then how many do
/// not), and the colour bar of a long sweep.
fn legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    named: &[&Series],
    bar: Option<&ColorBar>,
) -> Result<(), PlotError> {
    let (_, h) = area.dim_in_pixel();
    let h = h as i32;
    let font = (FAMILY, 13).into_font().color(&BLACK);
    let bar_height = if bar.is_some() { 3 * LEGEND_LINE + 8 } else { 0 };
    let mut y = 22;
    for (k, s) in named.iter().enumerate() {
        let lines = legend_lines(&s.name);
        let need = LEGEND_LINE * lines.len() as i32;
        if y + need + bar_height > h - 8 {
            let more = named.len() - k;
            area.draw(&Text::new(format!("… and {more} more"), (38, y - 7), font.clone())).map_err(err)?;
            y += LEGEND_LINE;
            break;
        }
        glyph(area, &s.style, rgb(s.color), (8, y))?;
        for (i, line) in lines.iter().enumerate() {
            area.draw(&Text::new(line.clone(), (38, y - 7 + LEGEND_LINE * i as i32), font.clone())).map_err(err)?;
        }
        y += need;
    }
    if let Some(bar) = bar {
        y += 6;
        area.draw(&Text::new(bar.label.clone(), (8, y - 7), font.clone())).map_err(err)?;
        y += LEGEND_LINE - 4;
        let width = LEGEND_WIDTH as i32 - 40;
        for i in 0..width {
            let c = rgb(Shade::Ramp(i as f64 / (width - 1) as f64));
            area.draw(&Rectangle::new([(8 + i, y), (9 + i, y + 12)], c.filled())).map_err(err)?;
        }
        y += 16;
        area.draw(&Text::new(tick(bar.from), (8, y), font.clone())).map_err(err)?;
        let to = tick(bar.to);
        let x = 8 + width - 7 * to.chars().count() as i32;
        area.draw(&Text::new(to, (x.max(60), y), font)).map_err(err)?;
    }
    Ok(())
}
