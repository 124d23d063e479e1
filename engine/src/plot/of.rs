//! The default figure of each value type, in the units a person reads: rpm, mm, µm/N, Hz, deg.

use super::PlotError;
use super::figure::{Axis, Figure, Panel, Series, Style, sweep_color, sweep_labelled};
use crate::value::{Frf, Lobes, ModalModel, Table, TimeSeries, Value};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// One value to draw with its legend name and, when its step is swept, its first numeric
/// sweep coordinate as written in the recipe (`speed=1500 rpm` → `("speed [rpm]", 1500)`).
pub struct Layer<'a> {
    pub name: String,
    pub value: &'a Value,
    pub coord: Option<(String, f64)>,
}

/// The figure of `main` (one value, or one per sweep point) with the `with` values drawn over
/// it. `variant` picks another view of the same type (`real-imag` for FRFs).
pub fn figure(title: &str, variant: Option<&str>, main: &[Layer], with: &[Layer]) -> Result<Figure, PlotError> {
    let Some(first) = main.first() else {
        return Err(PlotError::Empty);
    };
    let panels = match first.value {
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

/// Views a port type can be drawn in; the first is the default.
pub fn variants(ty: &crate::value::PortType) -> &'static [&'static str] {
    use crate::value::PortType as P;
    match ty {
        P::Frf => &["bode", "real-imag"],
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
        P::Frf | P::ReceptanceSet => matches!(with, P::Frf | P::ReceptanceSet | P::ModalModel),
        P::Lobes => matches!(with, P::Lobes | P::Table),
        P::Table => matches!(with, P::Table),
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
        "rad/s" => (60.0 / TAU, "rpm".into()),
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

/// Magnitude (log) and phase, or real and imaginary parts, of the H block of every FRF and
/// receptance set; coherence beneath when any has it; modes of `with` modal models marked.
fn frf(main: &[Layer], with: &[Layer], real_imag: bool) -> Result<Vec<Panel>, PlotError> {
    let layers: Vec<&Layer> =
        main.iter().chain(with.iter().filter(|l| !matches!(l.value, Value::ModalModel(_)))).collect();
    let unit = blocks(main[0].value).first().map(|b| b.3.clone()).unwrap_or_default();
    let (scale, shown) = receptance_unit(&unit);
    let f_axis = || Axis::linear("frequency [Hz]");
    let (mut top, mut bottom) = if real_imag {
        (
            Panel::new(f_axis(), Axis::linear(format!("real [{shown}]"))),
            Panel::new(f_axis(), Axis::linear(format!("imaginary [{shown}]"))),
        )
    } else {
        (Panel::new(f_axis(), Axis::log(format!("|H| [{shown}]"))), Panel::new(f_axis(), Axis::linear("phase [deg]")))
    };
    top.weight = 3;
    bottom.weight = 2;
    let mut coherence = Panel::new(f_axis(), Axis::linear("coherence").fixed(0.0, 1.05));
    for (i, l) in layers.iter().enumerate() {
        let Some((_, freq, h, u, coh)) = blocks(l.value).into_iter().next() else {
            return Err(PlotError::Mixed(format!("`{}` is not an FRF", l.name)));
        };
        if u != unit {
            return Err(PlotError::Mixed(format!("`{}` is in {u}, the plot in {unit}", l.name)));
        }
        // The sweep of `main` on a ramp when long; `with` values in palette colours after it.
        let color = if i < main.len() { sweep_color(i, main.len()) } else { (i - main.len() + 1).into() };
        let named = layers.len() > 1 && (i >= main.len() || sweep_labelled(i, main.len()));
        let name = if named { l.name.clone() } else { String::new() };
        type Points = Vec<(f64, f64)>;
        let (a, b): (Points, Points) = if real_imag {
            freq.iter().zip(&h).map(|(f, v)| ((*f, v.re * scale), (*f, v.im * scale))).unzip()
        } else {
            freq.iter().zip(&h).map(|(f, v)| ((*f, v.norm() * scale), (*f, v.arg().to_degrees()))).unzip()
        };
        top.series.push(Series::new(name.clone(), a, Style::Line, color));
        bottom.series.push(Series::new("", b, Style::Line, color));
        if let Some(c) = coh {
            coherence.series.push(Series::new("", freq.iter().copied().zip(c).collect(), Style::Line, color));
        }
    }
    let markers = mode_markers(with);
    top.series.extend(markers.iter().cloned());
    let mut panels = vec![top, bottom];
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
            let label = if k == 0 && n > 1 && sweep_labelled(i, n) { l.name.clone() } else { String::new() };
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
            let name = if main.len() > 1 && sweep_labelled(i, main.len()) { l.name.clone() } else { String::new() };
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
            let name = if main.len() > 1 && sweep_labelled(i, main.len()) { l.name.clone() } else { String::new() };
            panels[k].1.series.push(Series::new(name, pts, Style::Line, sweep_color(i, main.len())));
        }
    }
    Ok(panels.into_iter().map(|(_, p)| p).collect())
}

/// Depth limit (mm) over speed (rpm) for every diagram, trials as ○ stable and × chatter,
/// and beneath, the chatter frequency of each diagram with the trials' observed ones.
fn lobes(main: &[Layer], with: &[Layer]) -> Result<Vec<Panel>, PlotError> {
    let mut depth = Panel::new(Axis::linear("spindle speed [rpm]"), Axis::linear("depth limit [mm]"));
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
                let d = lobes.speed_rpm.iter().zip(&lobes.depth_limit).map(|(s, b)| (*s, b * 1e3)).collect();
                depth.series.push(Series::new(l.name.clone(), d, style.clone(), color));
                let c = lobes.speed_rpm.iter().zip(&lobes.chatter_hz).map(|(s, f)| (*s, *f)).collect();
                chatter.series.push(Series::new(l.name.clone(), c, Style::Dots, color));
                color += 1;
            }
            Value::Table(t) => {
                // Trials of one reference (several tables when its step is swept) as one set.
                let base = l.name.split(" [").next().unwrap_or(&l.name).to_string();
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
        let pick = |chatter: bool| -> Vec<(f64, f64)> {
            rows.iter().filter(|r| (r[2] == 1.0) == chatter).map(|r| (r[0], r[1] * 1e3)).collect()
        };
        depth.series.push(Series::new(format!("{name}: stable"), pick(false), Style::Circles, 2));
        depth.series.push(Series::new(format!("{name}: chatter"), pick(true), Style::Crosses, 3));
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
/// right 1/0 (−1 where not scored)]`: the outcome from `outcome`, else from `simulated` or
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
            .map(|i| [speed[i], depth[i], chatter[i], freq.map_or(0.0, |f| f[i]), right.map_or(-1.0, |r| r[i])])
            .collect(),
    )
}

fn col<'a>(t: &'a Table, name: &str) -> Option<&'a [f64]> {
    t.columns.iter().find(|c| c.name == name).map(|c| c.values.as_slice())
}

/// Tables by what their columns hold: a form or motion per angle as a polar plot (µm), a
/// spectrum per undulation per revolution, a Campbell table; any other as its columns over
/// the first, one panel per unit.
fn table(main: &[Layer], with: &[Layer]) -> Result<Vec<Panel>, PlotError> {
    let mut tables: Vec<(&str, &Table)> = Vec::new();
    for l in main.iter().chain(with) {
        match l.value {
            Value::Table(t) => tables.push((l.name.as_str(), t)),
            other => return Err(PlotError::Mixed(format!("`{}` is a {}, not a table", l.name, other.port_type()))),
        }
    }
    let many = tables.len() > 1;
    let t = tables[0].1;
    if col(t, "angle").is_some() {
        return Ok(vec![polar(&tables)]);
    }
    if let (Some(speed), Some(freq), Some(whirl), false) = (col(t, "speed"), col(t, "frequency"), col(t, "whirl"), many)
    {
        return Ok(vec![campbell(speed, freq, whirl)]);
    }
    let mut panels: Vec<(String, Panel)> = Vec::new();
    let mut color = 0;
    for (name, t) in &tables {
        let Some(x) = t.columns.first() else { return Err(PlotError::Empty) };
        let (xs, xu) = signal_unit(&x.unit.symbol);
        let x_label = if xu.is_empty() { x.name.clone() } else { format!("{} [{xu}]", x.name) };
        for c in t.columns.iter().skip(1) {
            let (s, u) = signal_unit(&c.unit.symbol);
            let k = match panels.iter().position(|(unit, _)| *unit == u) {
                Some(k) => k,
                None => {
                    let y = if u.is_empty() { "value".to_string() } else { format!("[{u}]") };
                    panels.push((u.clone(), Panel::new(Axis::linear(x_label.clone()), Axis::linear(y))));
                    panels.len() - 1
                }
            };
            let pts = x.values.iter().zip(&c.values).map(|(a, b)| (a * xs, b * s)).collect();
            let style = Style::Line;
            let label = if many { format!("{name}: {}", c.name) } else { c.name.clone() };
            panels[k].1.series.push(Series::new(label, pts, style, color));
            color += 1;
        }
    }
    Ok(panels.into_iter().map(|(_, p)| p).collect())
}

/// Form or error motion around the circle: each radial column as `r0 + e(θ)` in x–y (µm), the
/// ±3σ band of a form where the table gives its bounds, and the reference circle `r0`.
fn polar(tables: &[(&str, &Table)]) -> Panel {
    let is_radial = |c: &&crate::value::Column| {
        c.unit.symbol == "m" && !c.name.contains("sigma") && !c.name.ends_with("lower") && !c.name.ends_with("upper")
    };
    let peak = tables
        .iter()
        .flat_map(|(_, t)| t.columns.iter().filter(|c| c.unit.symbol == "m").flat_map(|c| c.values.iter()))
        .fold(0.0f64, |a, v| a.max(v.abs() * 1e6));
    // The reference circle: twice the largest excursion, so the shape reads at a glance.
    let r0 = 2.0 * peak.max(1e-3);
    let mut p = Panel::new(Axis::linear("x [µm]"), Axis::linear("y [µm]"));
    p.equal_aspect = true;
    p.weight = 4;
    let circle: Vec<(f64, f64)> =
        (0..=180).map(|k| (TAU * k as f64 / 180.0).sin_cos()).map(|(s, c)| (r0 * c, r0 * s)).collect();
    p.series.push(Series::new(
        format!("reference circle, r0 = {} µm", crate::round_sig(r0, 2)),
        circle,
        Style::Dashed,
        7,
    ));
    let mut color = 0;
    for (name, t) in tables {
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
        let prefix = if tables.len() > 1 { format!("{name}: ") } else { String::new() };
        if let (Some(lo), Some(hi)) = (col(t, "form_lower"), col(t, "form_upper")) {
            p.series.push(Series::new(format!("{prefix}form ±3σ"), around(lo), Style::Band(around(hi)), color));
        }
        for c in t.columns.iter().filter(is_radial) {
            p.series.push(Series::new(format!("{prefix}{}", c.name), around(&c.values), Style::Line, color));
            color += 1;
        }
    }
    p
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
        let x = match &l.coord {
            Some((label, x)) => {
                x_label = label.clone();
                *x
            }
            None => i as f64 + 1.0,
        };
        pts.push((x, s.value * scale));
    }
    let y = if unit.is_empty() { "value".to_string() } else { format!("value [{unit}]") };
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
            speed_rpm: None,
            sensor: None,
            dofs: None,
        }));
    }
    let layers: Vec<Layer> =
        main.iter().zip(&frfs).map(|(l, v)| Layer { name: l.name.clone(), value: v, coord: None }).collect();
    let markers: Vec<Layer> =
        main.iter().map(|l| Layer { name: l.name.clone(), value: l.value, coord: None }).collect();
    frf(&layers, &markers, false)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::value::{Channel, Column, PortType, Table, UnitLabel};

    fn layer(v: &Value) -> Layer<'_> {
        Layer { name: "t".into(), value: v, coord: None }
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

    /// The same figure gives the same bytes (SVG and PNG), and the PNG decodes to the size drawn.
    #[test]
    fn plots_are_the_same_bytes_every_time_and_the_png_decodes() {
        let l = Value::Lobes(crate::value::Lobes {
            speed_rpm: vec![1000.0, 2000.0, 3000.0],
            depth_limit: vec![1e-3, f64::INFINITY, 2e-3],
            chatter_hz: vec![900.0, f64::NAN, 950.0],
        });
        let fig = figure("lobes", None, &[layer(&l)], &[]).unwrap();
        assert_eq!(super::super::draw::svg(&fig).unwrap(), super::super::draw::svg(&fig).unwrap());
        let png = super::super::draw::png(&fig).unwrap();
        assert_eq!(png, super::super::draw::png(&fig).unwrap());
        let decoder = png::Decoder::new(std::io::Cursor::new(&png));
        let reader = decoder.read_info().unwrap();
        let info = reader.info();
        assert_eq!((info.width, info.height), (super::super::draw::WIDTH, super::super::draw::height(&fig)));
    }
}
