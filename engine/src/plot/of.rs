//! The default figure of each value type, in the units a person reads: rpm, mm, µm/N, Hz, deg.

use super::PlotError;
use super::figure::{Axis, Color, ColorBar, Figure, Panel, Series, Style, sweep_color, sweep_labelled};
use crate::value::{Frf, Lobes, ModalModel, Table, TimeSeries, Value};
use num_complex::Complex64;
use spindlelab_domain::Speed;
use std::f64::consts::TAU;

/// One value to draw: what it is called, and the sweep point that made it.
pub struct Layer<'a> {
    /// Its name in the legend: the output's or step's `label`, else the step.
    pub name: String,
    pub value: &'a Value,
    /// The sweep point as the recipe wrote it, `[("speed", "1500 rpm"), ("direction", "x")]`;
    /// empty when its step is not swept.
    pub sweep: Vec<(String, String)>,
}

impl<'a> Layer<'a> {
    /// An unswept value.
    pub fn new(name: impl Into<String>, value: &'a Value) -> Layer<'a> {
        Layer { name: name.into(), value, sweep: Vec::new() }
    }

    /// A value of a swept step, with its sweep label (`speed=1500 rpm, direction=x`).
    pub fn swept(name: impl Into<String>, value: &'a Value, label: &str) -> Layer<'a> {
        let sweep = label
            .split(", ")
            .filter_map(|part| part.split_once('='))
            .map(|(n, v)| (n.trim().to_string(), v.trim().to_string()))
            .collect();
        Layer { name: name.into(), value, sweep }
    }

    /// The direction of an FRF: its own, or the sweep's `direction`.
    fn direction(&self) -> Option<String> {
        let own = match self.value {
            Value::Frf(f) => f.direction.clone(),
            _ => None,
        };
        own.or_else(|| self.sweep.iter().find(|(n, _)| n == "direction").map(|(_, v)| v.clone()))
    }

    /// The first numeric sweep coordinate as written: `speed=1500 rpm` → `("speed [rpm]", 1500)`.
    fn coord(&self) -> Option<(String, f64)> {
        self.sweep.iter().find_map(|(name, v)| {
            let mut words = v.split_whitespace();
            let x: f64 = words.next()?.parse().ok()?;
            let unit: Vec<&str> = words.collect();
            let name = name.replace('_', " ");
            Some((if unit.is_empty() { name } else { format!("{name} [{}]", unit.join(" ")) }, x))
        })
    }

    /// The sweep point in words, without its direction when `no_direction` (the panel says
    /// it): `1500 rpm, x`; a plain number keeps its name (`dataset 2`).
    fn words(&self, no_direction: bool) -> String {
        let parts: Vec<String> = self
            .sweep
            .iter()
            .filter(|(n, _)| !(no_direction && n == "direction"))
            .map(|(n, v)| {
                let mut w = v.split_whitespace();
                match (w.next().map(|x| x.parse::<f64>().is_ok()), w.next()) {
                    (Some(true), Some(_)) => v.clone(),
                    (Some(true), None) => format!("{} {v}", n.replace('_', " ")),
                    _ => v.clone(),
                }
            })
            .collect();
        parts.join(", ")
    }
}

/// The figure of `main` (one value, or one per sweep point) with the `with` values drawn over
/// it. `variant` picks another view of the same type (`real-imag` for FRFs).
pub fn figure(title: &str, variant: Option<&str>, main: &[Layer], with: &[Layer]) -> Result<Figure, PlotError> {
    let Some(first) = main.first() else {
        return Err(PlotError::Empty);
    };
    // An FRF set is drawn as its FRFs, one curve each named by its nodes.
    if !matches!(first.value, Value::Table(_)) && main.iter().chain(with).any(|l| matches!(l.value, Value::FrfSet(_))) {
        let (owned_main, owned_with) = (set_members(main, false), set_members(with, true));
        let (m, w) = (unpacked(main, &owned_main), unpacked(with, &owned_with));
        return figure(title, variant, &m, &w);
    }
    let panels = match first.value {
        Value::Table(t) if main.len() == 1 && super::sets::is_stabilisation(t) => {
            let behind: Vec<&Value> = with.iter().map(|l| l.value).collect();
            super::sets::stabilisation(t, &behind)?
        }
        Value::Frf(_) | Value::ReceptanceSet(_) if variant == Some("blocks") => receptance_blocks(main, with)?,
        Value::Frf(_) | Value::ReceptanceSet(_) => frf(main, with, variant == Some("real-imag"))?,
        Value::TimeSeries(_) if variant == Some("spectrum") => spectrum(main)?,
        Value::TimeSeries(_) => time_series(main)?,
        Value::Lobes(_) => lobes(main, with)?,
        Value::Table(_) => table(main, with)?,
        Value::Scalar(_) => scalar(main)?,
        Value::ModalModel(_) => modal(main)?,
        other => return Err(PlotError::NoPlot(other.port_type().to_string())),
    };
    Ok(Figure { title: title.to_string(), panels })
}

/// The FRFs of each FRF set among `layers` with their legend names (nothing for other values):
/// a swept set's FRFs are prefixed by the sweep point, a set drawn `over` another by its name.
fn set_members(layers: &[Layer], over: bool) -> Vec<Vec<(String, Value)>> {
    layers
        .iter()
        .map(|l| match l.value {
            Value::FrfSet(_) => {
                let words = l.words(false);
                let prefix = if words.is_empty() && over { l.name.clone() } else { words };
                super::sets::members(l.value, &prefix)
            }
            _ => Vec::new(),
        })
        .collect()
}

/// `layers` with each FRF set replaced by its FRFs (`owned`, from [`set_members`]).
fn unpacked<'a>(layers: &[Layer<'a>], owned: &'a [Vec<(String, Value)>]) -> Vec<Layer<'a>> {
    let mut out = Vec::new();
    for (l, o) in layers.iter().zip(owned) {
        if matches!(l.value, Value::FrfSet(_)) {
            out.extend(o.iter().map(|(n, v)| Layer::new(n.clone(), v)));
        } else {
            out.push(Layer { name: l.name.clone(), value: l.value, sweep: l.sweep.clone() });
        }
    }
    out
}

/// Views a port type can be drawn in; the first is the default.
pub fn variants(ty: &crate::value::PortType) -> &'static [&'static str] {
    use crate::value::PortType as P;
    match ty {
        P::Frf | P::FrfSet => &["bode", "real-imag"],
        P::ReceptanceSet => &["bode", "real-imag", "blocks"],
        P::TimeSeries => &["default", "spectrum"],
        P::Lobes | P::Table | P::Scalar | P::ModalModel => &["default"],
        _ => &[],
    }
}

/// Whether a value of type `with` can be drawn over a plot of `main`.
pub fn accepts(main: &crate::value::PortType, with: &crate::value::PortType) -> bool {
    use crate::value::PortType as P;
    match main {
        P::Frf | P::ReceptanceSet | P::FrfSet => {
            matches!(with, P::Frf | P::ReceptanceSet | P::ModalModel | P::FrfSet)
        }
        P::Lobes => matches!(with, P::Lobes | P::Table),
        // A stabilisation diagram takes the FRFs it was fitted to behind it.
        P::Table => matches!(with, P::Table | P::Frf | P::FrfSet),
        _ => false,
    }
}

/// A receptance's display scale and unit: m/N as µm/N and so on.
fn receptance_unit(symbol: &str) -> (f64, String) {
    match symbol {
        "m/N" => (1e6, "µm/N".into()),
        "rad/N" => (1e6, "µrad/N".into()),
        "m/(N*m)" | "m/(N m)" | "m/(N·m)" => (1e6, "µm/(N·m)".into()),
        "rad/(N*m)" | "rad/(N m)" | "rad/(N·m)" => (1e6, "µrad/(N·m)".into()),
        "" => (1.0, "—".into()),
        s => (1.0, s.to_string()),
    }
}

/// A signal's display scale and unit: displacements in µm, times in ms, the rest as stored.
fn signal_unit(symbol: &str) -> (f64, String) {
    match symbol {
        "m" => (1e6, "µm".into()),
        "m/s" => (1e3, "mm/s".into()),
        "s" => (1e3, "ms".into()),
        "rad/s" => (Speed::from_rad_s(1.0).rpm(), "rpm".into()),
        "" => (1.0, String::new()),
        s => (1.0, s.to_string()),
    }
}

/// One block of a receptance: its name, lines (Hz), values, unit and coherence if measured.
type Block = (&'static str, Vec<f64>, Vec<Complex64>, String, Option<Vec<f64>>);

/// The blocks of one layer: an FRF is one block `H`, a receptance set four.
fn blocks(v: &Value) -> Vec<Block> {
    match v {
        Value::Frf(f) => vec![("H", f.freq_hz.clone(), f.values.clone(), f.unit.symbol.clone(), f.coherence.clone())],
        Value::ReceptanceSet(r) => vec![
            ("H", r.freq_hz.clone(), r.h.clone(), "m/N".into(), None),
            ("L", r.freq_hz.clone(), r.l.clone(), "m/(N*m)".into(), None),
            ("N", r.freq_hz.clone(), r.n.clone(), "rad/N".into(), None),
            ("P", r.freq_hz.clone(), r.p.clone(), "rad/(N*m)".into(), None),
        ],
        _ => vec![],
    }
}

/// A layer's legend entry among `n` values of one output: its sweep point in words when it
/// has one and there are several, else its name.
fn legend_name(l: &Layer, n: usize) -> String {
    let words = l.words(false);
    if n > 1 && !words.is_empty() { words } else { l.name.clone() }
}

/// Mode frequencies of the `with` modal models, as vertical markers.
fn mode_markers(with: &[Layer]) -> Vec<Series> {
    let models: Vec<&Layer> = with.iter().filter(|l| matches!(l.value, Value::ModalModel(_))).collect();
    models
        .iter()
        .enumerate()
        .filter_map(|(i, l)| match l.value {
            Value::ModalModel(m) => Some(Series::new(
                if i == 0 { format!("modes ({})", l.name) } else { String::new() },
                m.modes.iter().map(|m| (m.freq_hz, 0.0)).collect(),
                Style::VLines,
                7,
            )),
            _ => None,
        })
        .collect()
}

/// The phase of `h` over `freq` in degrees, in the turn centred on its circular mean (a
/// receptance near 0° stays near 0°, one that lags by 250° stays at −250°), with a gap (a NaN
/// point) wherever it wraps, so a line never jumps across the plot. Unwrapping along
/// frequency would be the other way, but it drifts by whole turns on measured noise.
fn phase_points(freq: &[f64], h: &[Complex64]) -> Vec<(f64, f64)> {
    let valid = |v: &Complex64| v.norm() > 0.0 && v.is_finite();
    let centre = h.iter().filter(|v| valid(v)).map(|v| v / v.norm()).sum::<Complex64>().arg();
    let mut out = Vec::with_capacity(h.len() + 8);
    let mut prev: Option<f64> = None;
    for (f, v) in freq.iter().zip(h) {
        if !valid(v) {
            out.push((*f, f64::NAN));
            prev = None;
            continue;
        }
        // In (centre − π, centre + π].
        let mut a = v.arg();
        a -= TAU * ((a - centre) / TAU).round();
        if a <= centre - std::f64::consts::PI {
            a += TAU;
        }
        if prev.is_some_and(|p| (a - p).abs() > std::f64::consts::PI) {
            out.push((*f, f64::NAN));
        }
        out.push((*f, a.to_degrees()));
        prev = Some(a);
    }
    out
}

/// The colour of the `i`-th of `n` sweep points: along the ramp, in order, when the sweep has a
/// numeric coordinate (a speed reads from dark to light); palette entries for a few unordered
/// ones (files, directions).
fn shade(layers: &[&Layer], i: usize) -> Color {
    let n = layers.len();
    if n > 1 && layers.iter().all(|l| l.coord().is_some()) {
        Color::Ramp(i as f64 / (n - 1) as f64)
    } else {
        sweep_color(i, n)
    }
}

/// The colour bar of a long sweep drawn on the ramp: its first coordinate from the first to
/// the last layer.
fn color_bar(layers: &[&Layer]) -> Option<ColorBar> {
    let (label, from) = layers.first()?.coord()?;
    let (_, to) = layers.last()?.coord()?;
    Some(ColorBar { label, from, to })
}

/// Magnitude (log) and phase, or real and imaginary parts, of the H block of every FRF and
/// receptance set; coherence beneath when any has it; modes of `with` modal models marked.
///
/// One pair of panels per direction when the values hold more than one. Within a panel the
/// sweep of `main` is coloured in order (palette for a few points, a ramp with a colour bar
/// for many); a `with` value of the same sweep point takes its colour, dashed (a measurement
/// over a model), any other a palette colour of its own.
fn frf(main: &[Layer], with: &[Layer], real_imag: bool) -> Result<Vec<Panel>, PlotError> {
    let overlays: Vec<&Layer> = with.iter().filter(|l| !matches!(l.value, Value::ModalModel(_))).collect();
    let unit = blocks(main[0].value).first().map(|b| b.3.clone()).unwrap_or_default();
    let (scale, shown) = receptance_unit(&unit);
    for l in main.iter().chain(overlays.iter().copied()) {
        match blocks(l.value).first() {
            None => return Err(PlotError::Mixed(format!("`{}` is not an FRF", l.name))),
            Some(b) if b.3 != unit => {
                return Err(PlotError::Mixed(format!("`{}` is in {}, the plot in {unit}", l.name, b.3)));
            }
            Some(_) => {}
        }
    }
    let mut directions: Vec<String> = Vec::new();
    for d in main.iter().chain(overlays.iter().copied()).filter_map(Layer::direction) {
        if !directions.contains(&d) {
            directions.push(d);
        }
    }
    let split = directions.len() > 1;
    let groups: Vec<Option<String>> = if split { directions.into_iter().map(Some).collect() } else { vec![None] };
    let in_group = |l: &Layer, g: &Option<String>| g.is_none() || l.direction().is_none() || l.direction() == *g;
    let f_axis = || Axis::linear("frequency [Hz]");
    let mut panels = Vec::new();
    let mut coherence = Panel::new(f_axis(), Axis::linear("coherence").fixed(0.0, 1.05));
    for g in &groups {
        let dir = g.as_ref().map(|d| format!(" {d}")).unwrap_or_default();
        let (mut top, mut bottom) = if real_imag {
            (
                Panel::new(f_axis(), Axis::linear(format!("real{dir} [{shown}]"))),
                Panel::new(f_axis(), Axis::linear(format!("imaginary{dir} [{shown}]"))),
            )
        } else {
            (
                Panel::new(f_axis(), Axis::log(format!("|H|{dir} [{shown}]"))),
                Panel::new(f_axis(), Axis::linear(format!("phase{dir} [deg]"))),
            )
        };
        top.weight = 3;
        bottom.weight = 2;
        let members: Vec<&Layer> = main.iter().filter(|l| in_group(l, g)).collect();
        let n = members.len();
        let ramp = n > 10;
        if ramp {
            top.color_bar = color_bar(&members);
        }
        let others: Vec<&Layer> = overlays.iter().copied().filter(|l| in_group(l, g)).collect();
        // Names: the sweep point in words; the value's name too when others share the plot.
        let prefix = |l: &Layer| if others.is_empty() { String::new() } else { format!("{}, ", l.name) };
        let mut curves: Vec<(&Layer, Color, Style, String)> = Vec::new();
        for (i, l) in members.iter().enumerate() {
            let words = l.words(split);
            let name = match (n, ramp) {
                (1, _) if others.is_empty() => String::new(),
                (1, _) => l.name.clone(),
                (_, true) if others.is_empty() => String::new(),
                (_, true) if i == 0 => l.name.clone(),
                (_, true) => String::new(),
                _ if words.is_empty() => l.name.clone(),
                _ => format!("{}{words}", prefix(l)),
            };
            curves.push((l, shade(&members, i), Style::Line, name));
        }
        let on_ramp = n > 1 && members.iter().all(|l| l.coord().is_some());
        let mut next = if ramp || on_ramp { 0 } else { n };
        for l in &others {
            let words = l.words(split);
            let twin = (!l.sweep.is_empty()).then(|| members.iter().position(|m| m.words(split) == words)).flatten();
            match twin {
                Some(i) => {
                    let name = if ramp { String::new() } else { format!("{}, {words}", l.name) };
                    curves.push((l, shade(&members, i), Style::Dashed, name));
                }
                None => {
                    let name = if words.is_empty() { l.name.clone() } else { format!("{}, {words}", l.name) };
                    curves.push((l, Color::Palette(next), Style::Line, name));
                    next += 1;
                }
            }
        }
        // With a ramp the dashed twins need one legend entry saying what dashed means.
        if ramp && curves.iter().any(|c| c.2 == Style::Dashed) {
            let name = others.first().map(|l| l.name.clone()).unwrap_or_default();
            top.series.push(Series::new(name, Vec::new(), Style::Dashed, Color::Palette(7)));
        }
        for (l, color, style, name) in curves {
            let Some((_, freq, h, _, coh)) = blocks(l.value).into_iter().next() else { continue };
            type Points = Vec<(f64, f64)>;
            let (a, b): (Points, Points) = if real_imag {
                freq.iter().zip(&h).map(|(f, v)| ((*f, v.re * scale), (*f, v.im * scale))).unzip()
            } else {
                let magnitude = freq.iter().zip(&h).map(|(f, v)| (*f, v.norm() * scale)).collect();
                let phase = phase_points(&freq, &h);
                (magnitude, phase)
            };
            top.series.push(Series::new(name, a, style.clone(), color));
            bottom.series.push(Series::new("", b, style.clone(), color));
            if let Some(c) = coh
                && (g.is_none() || l.direction() == *g || (l.direction().is_none() && g == &groups[0]))
            {
                coherence.series.push(Series::new("", freq.iter().copied().zip(c).collect(), style, color));
            }
        }
        top.series.extend(mode_markers(with));
        panels.push(top);
        panels.push(bottom);
    }
    if !coherence.series.is_empty() {
        panels.push(coherence);
    }
    Ok(panels)
}

/// |H|, |L|, |N| and |P| of receptance sets (an FRF gives |H| only).
fn receptance_blocks(main: &[Layer], with: &[Layer]) -> Result<Vec<Panel>, PlotError> {
    let mut panels: Vec<Panel> = Vec::new();
    for (i, l) in main.iter().chain(with).enumerate() {
        for (k, (name, freq, h, unit, _)) in blocks(l.value).into_iter().enumerate() {
            let (scale, shown) = receptance_unit(&unit);
            if panels.len() <= k {
                panels.push(Panel::new(Axis::linear("frequency [Hz]"), Axis::log(format!("|{name}| [{shown}]"))));
            }
            let n = main.len() + with.len();
            let label =
                if k == 0 && n > 1 && sweep_labelled(i, n) { legend_name(l, main.len()) } else { String::new() };
            let pts = freq.iter().zip(&h).map(|(f, v)| (*f, v.norm() * scale)).collect();
            panels[k].series.push(Series::new(label, pts, Style::Line, sweep_color(i, n)));
        }
    }
    Ok(panels)
}

/// One panel per channel name, every sweep point overlaid, time in ms.
fn time_series(main: &[Layer]) -> Result<Vec<Panel>, PlotError> {
    let mut panels: Vec<(String, Panel)> = Vec::new();
    for (i, l) in main.iter().enumerate() {
        let Value::TimeSeries(ts) = l.value else {
            return Err(PlotError::Mixed(format!("`{}` is not a time series", l.name)));
        };
        let ts: &TimeSeries = ts;
        for c in &ts.channels {
            let (scale, unit) = signal_unit(&c.unit.symbol);
            let k = match panels.iter().position(|(n, _)| *n == c.name) {
                Some(k) => k,
                None => {
                    let y = if unit.is_empty() { c.name.clone() } else { format!("{} [{unit}]", c.name) };
                    panels.push((c.name.clone(), Panel::new(Axis::linear("time [ms]"), Axis::linear(y))));
                    panels.len() - 1
                }
            };
            // At most 20,000 points a line: every k-th sample, with the extremes of its stretch.
            let n = c.samples.len();
            let stride = n.div_ceil(10_000).max(1);
            let mut pts = Vec::with_capacity(2 * n / stride + 2);
            for (j, chunk) in c.samples.chunks(stride).enumerate() {
                let t = |o: usize| 1e3 * (ts.t0 + (j * stride + o) as f64 / ts.sample_rate);
                let (lo, hi) = chunk.iter().enumerate().fold((0, 0), |(a, b), (o, v)| {
                    (if *v < chunk[a] { o } else { a }, if *v > chunk[b] { o } else { b })
                });
                for o in if lo <= hi { [lo, hi] } else { [hi, lo] } {
                    pts.push((t(o), chunk[o] * scale));
                }
            }
            pts.dedup();
            let name = if main.len() > 1 && sweep_labelled(i, main.len()) {
                legend_name(l, main.len())
            } else {
                String::new()
            };
            panels[k].1.series.push(Series::new(name, pts, Style::Line, sweep_color(i, main.len())));
        }
    }
    Ok(panels.into_iter().map(|(_, p)| p).collect())
}

/// The amplitude spectrum of each channel (one-sided, `2|X|/N`, log), one panel per channel:
/// how wide a band an impact excites, where a signal's energy sits.
fn spectrum(main: &[Layer]) -> Result<Vec<Panel>, PlotError> {
    let mut panels: Vec<(String, Panel)> = Vec::new();
    let mut planner = rustfft::FftPlanner::<f64>::new();
    for (i, l) in main.iter().enumerate() {
        let Value::TimeSeries(ts) = l.value else {
            return Err(PlotError::Mixed(format!("`{}` is not a time series", l.name)));
        };
        for c in &ts.channels {
            let n = c.samples.len();
            if n < 4 {
                continue;
            }
            let (scale, unit) = signal_unit(&c.unit.symbol);
            let fft = planner.plan_fft_forward(n);
            let mut buf: Vec<Complex64> = c.samples.iter().map(|x| Complex64::new(*x, 0.0)).collect();
            fft.process(&mut buf);
            let df = ts.sample_rate / n as f64;
            // At most 5,000 points: the largest line of each stretch, so peaks stay.
            let lines = n / 2;
            let stride = lines.div_ceil(5000).max(1);
            let pts: Vec<(f64, f64)> = (1..lines)
                .collect::<Vec<_>>()
                .chunks(stride)
                .map(|k| {
                    let best = *k.iter().max_by(|a, b| buf[**a].norm().total_cmp(&buf[**b].norm())).expect("non-empty");
                    (best as f64 * df, 2.0 * buf[best].norm() / n as f64 * scale)
                })
                .collect();
            let k = match panels.iter().position(|(name, _)| *name == c.name) {
                Some(k) => k,
                None => {
                    let y = if unit.is_empty() { format!("|{}|", c.name) } else { format!("|{}| [{unit}]", c.name) };
                    panels.push((c.name.clone(), Panel::new(Axis::linear("frequency [Hz]"), Axis::log(y))));
                    panels.len() - 1
                }
            };
            let name = if main.len() > 1 && sweep_labelled(i, main.len()) {
                legend_name(l, main.len())
            } else {
                String::new()
            };
            panels[k].1.series.push(Series::new(name, pts, Style::Line, sweep_color(i, main.len())));
        }
    }
    Ok(panels.into_iter().map(|(_, p)| p).collect())
}

/// The most speeds a stability diagram may have to be drawn as points on its line.
const FEW_SPEEDS: usize = 40;

/// Depth limit (mm) over speed (rpm) for every diagram, trials as ○ stable and × chatter,
/// and beneath, the chatter frequency of each diagram with the trials' observed ones.
fn lobes(main: &[Layer], with: &[Layer]) -> Result<Vec<Panel>, PlotError> {
    let mut depth = Panel::new(Axis::linear("spindle speed [rpm]"), Axis::linear("depth limit [mm]").from_zero());
    depth.weight = 3;
    let mut chatter = Panel::new(Axis::linear("spindle speed [rpm]"), Axis::linear("chatter frequency [Hz]"));
    chatter.weight = 2;
    let mut color = 0;
    let mut trials: Vec<(String, Vec<[f64; 5]>)> = Vec::new();
    for (k, l) in main.iter().chain(with).enumerate() {
        match l.value {
            Value::Lobes(lobes) => {
                let lobes: &Lobes = lobes;
                let style = if k < main.len() { Style::Line } else { Style::Dashed };
                let name = if l.sweep.is_empty() { l.name.clone() } else { format!("{}, {}", l.name, l.words(false)) };
                let d: Vec<(f64, f64)> =
                    lobes.speed.iter().zip(&lobes.depth_limit).map(|(s, b)| (s.rpm_as_written(), b * 1e3)).collect();
                // A diagram at a few speeds is its points, not the straight lines between them
                // (a lobe's cusps fall between): the points are drawn, unnamed, on the line.
                let few = d.len() <= FEW_SPEEDS;
                let points = few.then(|| d.clone());
                depth.series.push(Series::new(name.clone(), d, style.clone(), color));
                if let Some(points) = points {
                    depth.series.push(Series::new("", points, Style::Dots, color));
                }
                let c = lobes.speed.iter().zip(&lobes.chatter_hz).map(|(s, f)| (s.rpm_as_written(), *f)).collect();
                chatter.series.push(Series::new(name, c, Style::Dots, color));
                color += 1;
            }
            Value::Table(t) => {
                // Trials of one reference (several tables when its step is swept) as one set.
                let base = l.name.clone();
                let Some(rows) = trial_rows(t) else {
                    return Err(PlotError::Mixed(format!(
                        "`{}` has no speed, depth and outcome (or stable) columns to draw as trials",
                        l.name
                    )));
                };
                match trials.iter_mut().find(|(n, _)| *n == base) {
                    Some((_, all)) => all.extend(rows),
                    None => trials.push((base, rows)),
                }
            }
            other => {
                return Err(PlotError::Mixed(format!(
                    "`{}` is a {}; lobes take other lobes and trial tables",
                    l.name,
                    other.port_type()
                )));
            }
        }
    }
    for (name, rows) in trials {
        // Trials a diagram scored (or no score at all) by outcome; those outside every
        // diagram's speeds, which none scored, apart.
        let unscored = |r: &[f64; 5]| r[4] == -1.0;
        let pick = |chatter: bool| -> Vec<(f64, f64)> {
            rows.iter().filter(|r| !unscored(r) && (r[2] == 1.0) == chatter).map(|r| (r[0], r[1] * 1e3)).collect()
        };
        let (stable, chattered) = (pick(false), pick(true));
        if !stable.is_empty() {
            depth.series.push(Series::new(format!("{name}: stable"), stable, Style::Circles, 2));
        }
        if !chattered.is_empty() {
            depth.series.push(Series::new(format!("{name}: chatter"), chattered, Style::Crosses, 3));
        }
        let outside: Vec<(f64, f64)> = rows.iter().filter(|r| unscored(r)).map(|r| (r[0], r[1] * 1e3)).collect();
        if !outside.is_empty() {
            depth.series.push(Series::new(format!("{name}: not scored (outside)"), outside, Style::Squares, 7));
        }
        // Scored trials the diagram classifies wrong, ringed.
        let wrong: Vec<(f64, f64)> = rows.iter().filter(|r| r[4] == 0.0).map(|r| (r[0], r[1] * 1e3)).collect();
        if !wrong.is_empty() {
            depth.series.push(Series::new(format!("{name}: misclassified"), wrong, Style::Circles, 4));
        }
        let observed: Vec<(f64, f64)> = rows.iter().filter(|r| r[3] > 0.0).map(|r| (r[0], r[3])).collect();
        if !observed.is_empty() {
            chatter.series.push(Series::new(format!("{name}: observed"), observed, Style::Crosses, 3));
        }
    }
    Ok(vec![depth, chatter])
}

/// A trial table's rows as `[speed rpm, depth m, chatter 0/1, chatter frequency Hz or 0,
/// right 1/0 (−1 where not scored, NaN without a score)]`: the outcome from `outcome`, else from `simulated` or
/// `stable`; rows with no outcome (−1, outside a diagram) are kept by what was recorded.
fn trial_rows(t: &Table) -> Option<Vec<[f64; 5]>> {
    let (speed, depth) = (col(t, "speed")?, col(t, "depth")?);
    let chatter: Vec<f64> = match (col(t, "outcome"), col(t, "stable")) {
        (Some(o), _) => o.to_vec(),
        (None, Some(s)) => s.iter().map(|v| 1.0 - v).collect(),
        _ => return None,
    };
    let freq = col(t, "chatter_frequency").or_else(|| col(t, "chatter_freq"));
    let right = col(t, "right");
    Some(
        (0..speed.len())
            .map(|i| [speed[i], depth[i], chatter[i], freq.map_or(0.0, |f| f[i]), right.map_or(f64::NAN, |r| r[i])])
            .collect(),
    )
}

fn col<'a>(t: &'a Table, name: &str) -> Option<&'a [f64]> {
    t.columns.iter().find(|c| c.name == name).map(|c| c.values.as_slice())
}

/// Tables by what their columns hold: a form or motion per angle as a polar plot (µm), a
/// spectrum per undulation per revolution, a Campbell table; any other as its columns over
/// the first, one panel per unit (one per column when the table is swept, coloured by its
/// sweep point).
fn table(main: &[Layer], with: &[Layer]) -> Result<Vec<Panel>, PlotError> {
    let mut layers: Vec<(&Layer, &Table)> = Vec::new();
    for l in main.iter().chain(with) {
        match l.value {
            Value::Table(t) => layers.push((l, t)),
            other => return Err(PlotError::Mixed(format!("`{}` is a {}, not a table", l.name, other.port_type()))),
        }
    }
    let many = layers.len() > 1;
    let t = layers[0].1;
    if col(t, "angle").is_some() {
        return Ok(polar(&layers));
    }
    if let (Some(speed), Some(freq), Some(whirl), false) = (col(t, "speed"), col(t, "frequency"), col(t, "whirl"), many)
    {
        return Ok(vec![campbell(speed, freq, whirl)]);
    }
    if t.columns.first().is_some_and(|c| c.name == "upr") {
        return Ok(upr_spectrum(&layers));
    }
    let mut panels: Vec<(String, Panel)> = Vec::new();
    let n = layers.len();
    let all: Vec<&Layer> = layers.iter().map(|(l, _)| *l).collect();
    let mut color = 0;
    for (i, (l, t)) in layers.iter().enumerate() {
        let Some(x) = t.columns.first() else { return Err(PlotError::Empty) };
        let (xs, xu) = signal_unit(&x.unit.symbol);
        let x_label = if xu.is_empty() { x.name.clone() } else { format!("{} [{xu}]", x.name) };
        // Text columns name rows; they are not drawn.
        for c in t.columns.iter().skip(1).filter(|c| !c.is_text()) {
            let (s, u) = signal_unit(&c.unit.symbol);
            let key = if many { c.name.clone() } else { u.clone() };
            let k = match panels.iter().position(|(key_, _)| *key_ == key) {
                Some(k) => k,
                None => {
                    let y = match (many, u.is_empty()) {
                        (true, true) => c.name.replace('_', " "),
                        (true, false) => format!("{} [{u}]", c.name.replace('_', " ")),
                        (false, true) => "value".to_string(),
                        (false, false) => format!("[{u}]"),
                    };
                    let mut p = Panel::new(Axis::linear(x_label.clone()), Axis::linear(y));
                    if many && n > 10 {
                        p.color_bar = color_bar(&layers.iter().map(|(l, _)| *l).collect::<Vec<_>>());
                    }
                    panels.push((key, p));
                    panels.len() - 1
                }
            };
            let pts = x.values.iter().zip(&c.values).map(|(a, b)| (a * xs, b * s)).collect();
            let (label, shade) = if many {
                let named = k == 0 && sweep_labelled(i, n) && n <= 10;
                (if named { legend_name(l, n) } else { String::new() }, shade(&all, i))
            } else {
                color += 1;
                (c.name.clone(), Color::Palette(color - 1))
            };
            panels[k].1.series.push(Series::new(label, pts, Style::Line, shade));
        }
    }
    Ok(panels.into_iter().map(|(_, p)| p).collect())
}

/// Amplitudes per undulation per revolution (error motions, forms), one panel per quantity,
/// the sweep points side by side at each harmonic: to the highest harmonic that carries at
/// least 1 % of the largest amplitude, not to the end of the table.
fn upr_spectrum(layers: &[(&Layer, &Table)]) -> Vec<Panel> {
    let n = layers.len();
    let peak = layers
        .iter()
        .flat_map(|(_, t)| t.columns.iter().skip(1).flat_map(|c| c.values.iter()))
        .fold(0.0f64, |a, v| if v.is_finite() { a.max(v.abs()) } else { a });
    let mut top = 0.0f64;
    for (_, t) in layers {
        let Some(upr) = col(t, "upr") else { continue };
        for c in t.columns.iter().skip(1) {
            for (u, v) in upr.iter().zip(&c.values) {
                if v.abs() >= 0.01 * peak && *u > top {
                    top = *u;
                }
            }
        }
    }
    let end = (top * 1.1 + 1.0).max(10.0).ceil();
    let all: Vec<&Layer> = layers.iter().map(|(l, _)| *l).collect();
    let mut panels: Vec<(String, Panel)> = Vec::new();
    for (i, (l, t)) in layers.iter().enumerate() {
        let Some(upr) = col(t, "upr") else { continue };
        for c in t.columns.iter().skip(1) {
            let (scale, unit) = signal_unit(&c.unit.symbol);
            let k = match panels.iter().position(|(name, _)| *name == c.name) {
                Some(k) => k,
                None => {
                    let what = c.name.replace('_', " ");
                    let y = if unit.is_empty() {
                        format!("{what} amplitude")
                    } else {
                        format!("{what} amplitude [{unit}]")
                    };
                    let mut p = Panel::new(
                        Axis::linear("undulations per revolution [UPR]").fixed(-0.5, end + 0.5),
                        Axis::linear(y).from_zero(),
                    );
                    if n > 10 {
                        p.color_bar = color_bar(&layers.iter().map(|(l, _)| *l).collect::<Vec<_>>());
                    }
                    panels.push((c.name.clone(), p));
                    panels.len() - 1
                }
            };
            // Side by side within ±0.35 UPR of the harmonic.
            let shift = if n > 1 { 0.7 * (i as f64 / (n - 1) as f64 - 0.5) } else { 0.0 };
            let pts = upr
                .iter()
                .zip(&c.values)
                .filter(|(u, _)| **u <= end)
                .map(|(u, v)| (u + shift, v.abs() * scale))
                .collect();
            let named = k == 0 && n > 1 && n <= 10 && sweep_labelled(i, n);
            let name = if named { legend_name(l, n) } else { String::new() };
            panels[k].1.series.push(Series::new(name, pts, Style::Stems, shade(&all, i)));
        }
    }
    panels.into_iter().map(|(_, p)| p).collect()
}

/// Form or error motion around the circle: each radial quantity as `r0 + e(θ)` in x–y (µm),
/// the ±3σ band of a form where the table gives its bounds, and the reference circle `r0`.
/// A swept table gets one polar panel per quantity, its sweep points coloured in order.
fn polar(layers: &[(&Layer, &Table)]) -> Vec<Panel> {
    let is_radial = |c: &&crate::value::Column| {
        c.unit.symbol == "m" && !c.name.contains("sigma") && !c.name.ends_with("lower") && !c.name.ends_with("upper")
    };
    let peak = layers
        .iter()
        .flat_map(|(_, t)| t.columns.iter().filter(|c| c.unit.symbol == "m").flat_map(|c| c.values.iter()))
        .fold(0.0f64, |a, v| a.max(v.abs() * 1e6));
    // The reference circle: twice the largest excursion, so the shape reads at a glance.
    let r0 = 2.0 * peak.max(1e-3);
    let n = layers.len();
    let all: Vec<&Layer> = layers.iter().map(|(l, _)| *l).collect();
    let new_panel = |what: &str| {
        let mut p = Panel::new(Axis::linear(format!("{what}x [µm]")), Axis::linear(format!("{what}y [µm]")));
        p.equal_aspect = true;
        p.weight = 4;
        let circle: Vec<(f64, f64)> =
            (0..=180).map(|k| (TAU * k as f64 / 180.0).sin_cos()).map(|(s, c)| (r0 * c, r0 * s)).collect();
        p.series.push(Series::new(
            format!("reference circle, r0 = {} µm", spindlelab_domain::round_sig(r0, 2)),
            circle,
            Style::Dashed,
            7,
        ));
        if n > 10 {
            p.color_bar = color_bar(&layers.iter().map(|(l, _)| *l).collect::<Vec<_>>());
        }
        p
    };
    let mut panels: Vec<(String, Panel)> = Vec::new();
    for (i, (l, t)) in layers.iter().enumerate() {
        let Some(angle) = col(t, "angle") else { continue };
        let around = |e: &[f64]| -> Vec<(f64, f64)> {
            let mut pts: Vec<(f64, f64)> = angle
                .iter()
                .zip(e)
                .map(|(a, v)| {
                    let r = r0 + v * 1e6;
                    (r * a.cos(), r * a.sin())
                })
                .collect();
            if let Some(&p) = pts.first() {
                pts.push(p);
            }
            pts
        };
        let radial: Vec<&crate::value::Column> = t.columns.iter().filter(is_radial).collect();
        for (j, c) in radial.iter().enumerate() {
            // One panel for an unswept table's quantities; one per quantity when swept.
            let key = if n > 1 { c.name.clone() } else { String::new() };
            let k = match panels.iter().position(|(key_, _)| *key_ == key) {
                Some(k) => k,
                None => {
                    let what = if n > 1 { format!("{}: ", c.name.replace('_', " ")) } else { String::new() };
                    panels.push((key.clone(), new_panel(&what)));
                    panels.len() - 1
                }
            };
            let (name, color) = if n > 1 {
                let named = n <= 10 && sweep_labelled(i, n);
                (if named { legend_name(l, n) } else { String::new() }, shade(&all, i))
            } else {
                (c.name.replace('_', " "), Color::Palette(j))
            };
            if c.name == "form"
                && let (Some(lo), Some(hi)) = (col(t, "form_lower"), col(t, "form_upper"))
            {
                let band = if n > 1 { String::new() } else { "form ±3σ".to_string() };
                panels[k].1.series.push(Series::new(band, around(lo), Style::Band(around(hi)), color));
            }
            panels[k].1.series.push(Series::new(name, around(&c.values), Style::Line, color));
        }
    }
    panels.into_iter().map(|(_, p)| p).collect()
}

/// Whirl frequencies over speed: forward and backward modes as lines by rank, and the 1×
/// line where a whirl crosses the rotation.
fn campbell(speed: &[f64], freq: &[f64], whirl: &[f64]) -> Panel {
    let mut p = Panel::new(Axis::linear("spindle speed [rpm]"), Axis::linear("whirl frequency [Hz]"));
    p.weight = 3;
    let mut speeds: Vec<f64> = speed.to_vec();
    speeds.sort_by(f64::total_cmp);
    speeds.dedup();
    for (dir, name, color) in [(1.0, "forward", 0usize), (-1.0, "backward", 1)] {
        let per_speed: Vec<Vec<f64>> = speeds
            .iter()
            .map(|s| {
                let mut f: Vec<f64> =
                    (0..speed.len()).filter(|&i| speed[i] == *s && whirl[i] == dir).map(|i| freq[i]).collect();
                f.sort_by(f64::total_cmp);
                f
            })
            .collect();
        let ranks = per_speed.iter().map(Vec::len).max().unwrap_or(0);
        for k in 0..ranks {
            let pts = speeds.iter().zip(&per_speed).filter_map(|(s, f)| f.get(k).map(|v| (*s, *v))).collect();
            p.series.push(Series::new(if k == 0 { name } else { "" }, pts, Style::Line, color));
        }
    }
    // Modes without one whirl sense (straight orbits at rest on anisotropic bearings, or nodes
    // whirling both ways) as points.
    let mixed: Vec<(f64, f64)> = (0..speed.len()).filter(|&i| whirl[i] == 0.0).map(|i| (speed[i], freq[i])).collect();
    if !mixed.is_empty() {
        p.series.push(Series::new("no single whirl sense", mixed, Style::Dots, 2));
    }
    let top = freq.iter().copied().fold(0.0, f64::max);
    let one: Vec<(f64, f64)> = speeds.iter().map(|s| (*s, s / 60.0)).filter(|(_, f)| *f <= top).collect();
    p.series.push(Series::new("1× rotation", one, Style::Dashed, 7));
    p
}

/// A scalar over its sweep coordinate (or its sweep points in order).
fn scalar(main: &[Layer]) -> Result<Vec<Panel>, PlotError> {
    let mut pts = Vec::new();
    let mut unit = String::new();
    let mut x_label = "sweep point".to_string();
    for (i, l) in main.iter().enumerate() {
        let Value::Scalar(s) = l.value else { return Err(PlotError::Mixed(format!("`{}` is not a scalar", l.name))) };
        let (scale, u) = signal_unit(&s.unit.symbol);
        unit = u;
        let x = match l.coord() {
            Some((label, x)) => {
                x_label = label;
                x
            }
            None => i as f64 + 1.0,
        };
        pts.push((x, s.value * scale));
    }
    // The value's name on its axis: `impulse duration [ms]`.
    let name = &main[0].name;
    let y = if unit.is_empty() { name.clone() } else { format!("{name} [{unit}]") };
    let mut p = Panel::new(Axis::linear(x_label), Axis::linear(y));
    p.series.push(Series::new("", pts.clone(), Style::Line, 0));
    p.series.push(Series::new("", pts, Style::Dots, 0));
    Ok(vec![p])
}

/// The receptance of a modal model (Eq. 5.8), magnitude and phase, to 1.5 times its top mode.
fn modal(main: &[Layer]) -> Result<Vec<Panel>, PlotError> {
    let mut frfs = Vec::new();
    for l in main {
        let Value::ModalModel(m) = l.value else {
            return Err(PlotError::Mixed(format!("`{}` is not a modal model", l.name)));
        };
        let m: &ModalModel = m;
        let top = m.modes.iter().map(|m| m.freq_hz).fold(0.0, f64::max).max(1.0) * 1.5;
        let freq_hz: Vec<f64> = (1..=2000).map(|k| top * k as f64 / 2000.0).collect();
        let values = freq_hz.iter().map(|f| m.modes.iter().map(|m| m.receptance(TAU * f)).sum()).collect();
        frfs.push(Value::Frf(Frf {
            freq_hz,
            values,
            coherence: None,
            unit: crate::value::UnitLabel::new("m/N"),
            direction: None,
            speed: None,
            sensor: None,
            dofs: None,
        }));
    }
    let layers: Vec<Layer> =
        main.iter().zip(&frfs).map(|(l, v)| Layer { name: l.name.clone(), value: v, sweep: l.sweep.clone() }).collect();
    let markers: Vec<Layer> = main.iter().map(|l| Layer::new(l.name.clone(), l.value)).collect();
    frf(&layers, &markers, false)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::value::{Channel, Column, PortType, Table, UnitLabel};
    use num_complex::Complex64;

    fn layer(v: &Value) -> Layer<'_> {
        Layer::new("t", v)
    }

    /// A sine of 1 mm at 250 Hz: its spectrum peaks at 250 Hz at 1000 µm, the unit shown.
    #[test]
    fn a_spectrum_puts_a_sine_at_its_frequency_and_amplitude() {
        let fs = 10_000.0;
        let ts = Value::TimeSeries(TimeSeries {
            sample_rate: fs,
            t0: 0.0,
            channels: vec![Channel {
                name: "x".into(),
                unit: UnitLabel::new("m"),
                samples: (0..10_000).map(|i| 1e-3 * (std::f64::consts::TAU * 250.0 * i as f64 / fs).sin()).collect(),
            }],
        });
        let fig = figure("s", Some("spectrum"), &[layer(&ts)], &[]).unwrap();
        let pts = &fig.panels[0].series[0].points;
        let peak = pts.iter().fold((0.0, 0.0), |a, p| if p.1 > a.1 { *p } else { a });
        assert_eq!(fig.panels[0].y.label, "|x| [µm]");
        assert!((peak.0 - 250.0).abs() < 1e-9 && (peak.1 - 1000.0).abs() < 1e-6, "{peak:?}");
    }

    /// A Campbell table: a forward and a backward whirl line per rank and the 1× line, in rpm and Hz.
    #[test]
    fn a_campbell_table_draws_forward_and_backward_whirl_by_rank() {
        let speeds = [0.0, 0.0, 10_000.0, 10_000.0, 20_000.0, 20_000.0];
        let t = Value::Table(Table {
            columns: vec![
                Column::new("speed", "rpm", speeds.to_vec()),
                Column::new("frequency", "Hz", vec![500.0, 500.0, 520.0, 480.0, 540.0, 460.0]),
                Column::new("whirl", "", vec![1.0, -1.0, 1.0, -1.0, 1.0, -1.0]),
            ],
        });
        let fig = figure("c", None, &[layer(&t)], &[]).unwrap();
        let names: Vec<&str> = fig.panels[0].series.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["forward", "backward", "1× rotation"]);
        assert_eq!(fig.panels[0].series[0].points, [(0.0, 500.0), (10_000.0, 520.0), (20_000.0, 540.0)]);
        assert_eq!(fig.panels[0].x.label, "spindle speed [rpm]");
        assert!(variants(&PortType::Table).contains(&"default"));
    }

    fn frf_of(direction: Option<&str>, values: Vec<Complex64>, freq_hz: Vec<f64>) -> Value {
        Value::Frf(Frf {
            freq_hz,
            values,
            coherence: None,
            unit: UnitLabel::new("m/N"),
            direction: direction.map(str::to_string),
            speed: None,
            sensor: None,
            dofs: None,
        })
    }

    /// A pure delay of 1 ms over 0–5 kHz turns five times: the drawn phase stays within one
    /// turn, breaks where it wraps (never a line across the plot), and a receptance that
    /// lags a little stays just below 0°.
    #[test]
    fn phase_breaks_where_it_wraps_and_stays_in_the_turn_of_its_mean() {
        let f: Vec<f64> = (0..=500).map(|k| 10.0 * k as f64).collect();
        let h = f.iter().map(|f| Complex64::from_polar(1e-6, -TAU * f * 1e-3)).collect();
        let fig = figure("d", None, &[layer(&frf_of(None, h, f.clone()))], &[]).unwrap();
        let phase: Vec<f64> = fig.panels[1].series[0].points.iter().map(|p| p.1).collect();
        let gaps = phase.iter().filter(|p| p.is_nan()).count();
        assert_eq!(gaps, 5, "{phase:?}");
        assert!(phase.windows(2).all(|w| w[0].is_nan() || w[1].is_nan() || (w[1] - w[0]).abs() < 180.0));
        let spread = phase.iter().filter(|p| !p.is_nan()).fold((f64::MAX, f64::MIN), |a, p| (a.0.min(*p), a.1.max(*p)));
        assert!(spread.1 - spread.0 <= 360.0, "{spread:?}");
        let lag = f.iter().map(|f| Complex64::from_polar(1e-6, -0.01 * (f / 5000.0))).collect();
        let fig = figure("d", None, &[layer(&frf_of(None, lag, f))], &[]).unwrap();
        assert!(fig.panels[1].series[0].points.iter().all(|p| p.1 <= 0.0 && p.1 > -1.0));
    }

    /// FRFs in x and y get a pair of panels each, named by direction; a `with` value of the
    /// same sweep point takes the colour of its twin and is dashed.
    #[test]
    fn a_set_in_two_directions_gets_panels_per_direction_and_twins_share_a_colour() {
        let f = vec![100.0, 200.0, 300.0];
        let h = vec![Complex64::new(1e-7, -1e-7); 3];
        let (x1, y1) = (frf_of(Some("x"), h.clone(), f.clone()), frf_of(Some("y"), h.clone(), f.clone()));
        let (x2, y2) = (frf_of(Some("x"), h.clone(), f.clone()), frf_of(Some("y"), h, f));
        let main = [
            Layer::swept("model", &x1, "speed=0 rpm, direction=x"),
            Layer::swept("model", &y1, "speed=0 rpm, direction=y"),
        ];
        let with = [
            Layer::swept("measured", &x2, "speed=0 rpm, direction=x"),
            Layer::swept("measured", &y2, "speed=0 rpm, direction=y"),
        ];
        let fig = figure("t", None, &main, &with).unwrap();
        let labels: Vec<&str> = fig.panels.iter().map(|p| p.y.label.as_str()).collect();
        assert_eq!(labels, ["|H| x [µm/N]", "phase x [deg]", "|H| y [µm/N]", "phase y [deg]"]);
        let top = &fig.panels[0].series;
        assert_eq!(top.len(), 2, "{top:?}");
        assert_eq!((top[0].style.clone(), top[1].style.clone()), (Style::Line, Style::Dashed));
        assert_eq!(top[0].color, top[1].color);
        assert_eq!((top[0].name.as_str(), top[1].name.as_str()), ("model", "measured, 0 rpm"));
    }

    /// Depth from zero; trials outside every diagram's speeds apart from the scored ones.
    #[test]
    fn lobes_start_at_zero_depth_and_unscored_trials_are_drawn_apart() {
        let l = Value::Lobes(crate::value::Lobes {
            speed: vec![1000.0, 2000.0].into_iter().map(Speed::from_rpm).collect(),
            depth_limit: vec![2e-3, 3e-3],
            chatter_hz: vec![900.0, 950.0],
        });
        let trials = Value::Table(Table {
            columns: vec![
                Column::new("speed", "rpm", vec![1500.0, 1500.0, 2500.0]),
                Column::new("depth", "m", vec![1e-3, 4e-3, 1e-3]),
                Column::new("outcome", "", vec![0.0, 1.0, 0.0]),
                Column::new("right", "", vec![1.0, 1.0, -1.0]),
            ],
        });
        let fig = figure("l", None, &[layer(&l)], &[Layer::new("trials", &trials)]).unwrap();
        assert_eq!(fig.panels[0].y.start, Some(0.0));
        let by_name = |n: &str| fig.panels[0].series.iter().find(|s| s.name == n).map(|s| s.points.clone());
        assert_eq!(by_name("trials: stable"), Some(vec![(1500.0, 1.0)]));
        assert_eq!(by_name("trials: chatter"), Some(vec![(1500.0, 4.0)]));
        assert_eq!(by_name("trials: not scored (outside)"), Some(vec![(2500.0, 1.0)]));
    }

    /// A diagram at a few speeds shows its points on its line, without a second legend entry;
    /// a dense one is its line alone.
    #[test]
    fn a_diagram_at_a_few_speeds_shows_its_points() {
        let lobes = |n: usize| {
            Value::Lobes(crate::value::Lobes {
                speed: (0..n).map(|i| Speed::from_rpm(1000.0 + 100.0 * i as f64)).collect(),
                depth_limit: vec![2e-3; n],
                chatter_hz: vec![900.0; n],
            })
        };
        let (few, many) = (lobes(5), lobes(FEW_SPEEDS + 1));
        let series = |v: &Value| figure("l", None, &[layer(v)], &[]).unwrap().panels[0].series.clone();
        let s = series(&few);
        assert_eq!(s.len(), 2, "{s:?}");
        assert_eq!((s[0].style.clone(), s[1].style.clone()), (Style::Line, Style::Dots));
        assert_eq!((s[1].name.as_str(), s[1].color, s[1].points.len()), ("", s[0].color, 5));
        assert_eq!(series(&many).len(), 1);
    }
}
