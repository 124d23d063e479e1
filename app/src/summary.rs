//! A stable, human-readable summary of a run: every output of every instance, numbers
//! rounded to a stated number of significant digits, no timings and no paths.

use spindlelab_domain::round_sig;
use spindlelab_engine::diag::{escape_controls, escape_message};
use spindlelab_engine::exec::{Outcome, RunResult};
use spindlelab_engine::value::Value;
use spindlelab_engine::{Compiled, graph::Graph};
use std::fmt::Write as _;

/// Significant digits of every number in a summary.
pub const SIGNIFICANT_DIGITS: i32 = 4;

/// Names and units that came from a data file or a plugin, as the terminal may show them.
fn shown(s: &str) -> std::borrow::Cow<'_, str> {
    escape_controls(s)
}

fn n(x: f64) -> String {
    spindlelab_domain::sig(x, SIGNIFICANT_DIGITS)
}

fn describe(v: &Value) -> String {
    match v {
        Value::Scalar(s) => format!("{} {}", n(s.value), shown(&s.unit.symbol)),
        Value::TimeSeries(ts) => {
            let mut s = format!("time series, {} samples at {} Hz", ts.len(), n(ts.sample_rate));
            for c in &ts.channels {
                let peak = c.samples.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                let rms = (c.samples.iter().map(|x| x * x).sum::<f64>() / c.samples.len().max(1) as f64).sqrt();
                let u = shown(&c.unit.symbol);
                let _ = write!(s, "; {}: peak {} {u}, rms {} {u}", shown(&c.name), n(peak), n(rms));
            }
            s
        }
        Value::Frf(f) => {
            let (imax, vmax) = f
                .values
                .iter()
                .enumerate()
                .map(|(i, v)| (i, v.norm()))
                .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
            let coh = f
                .coherence
                .as_ref()
                .map(|c| format!(", min coherence {}", n(c.iter().copied().fold(1.0, f64::min))))
                .unwrap_or_default();
            format!(
                "FRF, {} lines {}..{} Hz, peak |H| {} {} at {} Hz{coh}",
                f.freq_hz.len(),
                n(*f.freq_hz.first().unwrap_or(&0.0)),
                n(*f.freq_hz.last().unwrap_or(&0.0)),
                n(vmax),
                shown(&f.unit.symbol),
                n(f.freq_hz.get(imax).copied().unwrap_or(0.0))
            )
        }
        Value::Table(t) => {
            let mut s = format!("table, {} rows", t.rows());
            for c in &t.columns {
                let vals: Vec<String> = (0..c.values.len().min(12))
                    .map(|i| c.word(i).map_or_else(|| n(c.values[i]), |w| shown(w).to_string()))
                    .collect();
                let more = if c.values.len() > 12 { ", …" } else { "" };
                let _ = write!(s, "\n      {} [{}]: {}{more}", shown(&c.name), shown(&c.unit.symbol), vals.join(", "));
            }
            s
        }
        Value::ModalModel(m) => format!("modal model, {} modes", m.modes.len()),
        Value::ReceptanceSet(r) => format!("receptance set, {} lines", r.freq_hz.len()),
        Value::BeamModel(b) => format!("beam model, {} sections", b.sections.len()),
        Value::Substructure(s) => {
            let parts: Vec<String> = s
                .parts
                .iter()
                .map(|p| {
                    let first = p.natural_hz.get(p.rigid_modes).map_or(String::from("-"), |f| n(*f));
                    format!("{} ({} modes, first flexible {first} Hz)", shown(&p.name), p.nu.len())
                })
                .collect();
            format!("substructure of `{}`: {}", shown(&s.assembly), parts.join(", "))
        }
        Value::Lobes(l) => format!("lobes, {} speeds", l.speed.len()),
        Value::FrfSet(s) => {
            let f = s.freq_hz();
            format!(
                "FRF set, {} FRFs in {} on {} lines {}..{} Hz",
                s.frfs.len(),
                shown(s.unit()),
                f.len(),
                n(*f.first().unwrap_or(&0.0)),
                n(*f.last().unwrap_or(&0.0))
            )
        }
    }
}

/// The summary of every instance's outputs, in graph order.
pub fn summarize(compiled: &Compiled, result: &RunResult) -> String {
    summarize_graph(&compiled.recipe.name, &compiled.graph, result)
}

fn summarize_graph(name: &str, graph: &Graph, result: &RunResult) -> String {
    let mut out = format!("recipe {}: {} node instance(s)\n", shown(name), graph.instances.len());
    for (inst, outcome) in graph.instances.iter().zip(&result.outcomes) {
        let _ = writeln!(out, "{} ({})", shown(&inst.id), inst.kind);
        match outcome {
            Outcome::Computed { outputs, .. } | Outcome::Cached { outputs, .. } => {
                for (port, v) in outputs.iter() {
                    let _ = writeln!(out, "  {port}: {}", describe(v));
                }
                for w in outcome.warnings() {
                    let _ = writeln!(out, "  warning: {}", shown(w));
                }
            }
            Outcome::Failed(e) => {
                let _ = writeln!(out, "  failed: {}", escape_message(&e.to_string()));
            }
            Outcome::Skipped => {
                let _ = writeln!(out, "  skipped");
            }
            Outcome::Released { .. } => {
                let _ = writeln!(out, "  outputs released once every consumer had run (never cached)");
                for w in outcome.warnings() {
                    let _ = writeln!(out, "  warning: {}", shown(w));
                }
            }
            Outcome::Unneeded { cached, .. } => {
                let how = if *cached { "cached" } else { "not cached" };
                let _ = writeln!(out, "  not loaded ({how}; every consumer came from the cache)");
                for w in outcome.warnings() {
                    let _ = writeln!(out, "  warning: {}", shown(w));
                }
            }
        }
    }
    out
}

/// The fit's outcome as the CLI prints it: each parameter from start to fitted value in the
/// recipe's own unit, with its standard deviation, and the objective before and after.
pub fn fit_summary(r: &crate::fit::FitReport) -> String {
    let mut out = format!(
        "fit ({}): objective {:.4e} -> {:.4e} in {} evaluations, {:.2} s{}\n",
        r.method,
        r.objective_before,
        r.objective_after,
        r.evaluations,
        r.seconds,
        if r.converged { "" } else { " (not converged)" }
    );
    for p in &r.params {
        let sigma = p.sigma.map(|s| format!(" ± {:.2e}", s)).unwrap_or_default();
        let bound = if p.at_bound { "  (at a bound)" } else { "" };
        out.push_str(&format!("  {:<12} {:>11.4e} -> {:>11.4e}{sigma} {}{bound}\n", p.name, p.start, p.value, p.unit));
    }
    out
}

/// A number in engineering notation with an SI prefix on its unit, 4 significant digits:
/// `4.854e-8 m` → `48.54 nm`, `2.6e-6 m/N` → `2.6 µm/N`; units that take no prefix (rpm,
/// deg, none) keep the number as it is.
pub fn eng(v: f64, unit: &str) -> String {
    if !v.is_finite() {
        return if v.is_nan() {
            "—".into()
        } else if v > 0.0 {
            format!("∞ {unit}").trim().into()
        } else {
            format!("−∞ {unit}").trim().into()
        };
    }
    let plain = |v: f64| format!("{} {unit}", round_sig(v, SIGNIFICANT_DIGITS)).trim().to_string();
    if v == 0.0 || unit.is_empty() || ["rpm", "deg", "rad", "%", "dB"].contains(&unit) {
        return plain(v);
    }
    const PREFIXES: [(i32, &str); 7] = [(-9, "n"), (-6, "µ"), (-3, "m"), (0, ""), (3, "k"), (6, "M"), (9, "G")];
    let exp = (v.abs().log10() / 3.0).floor() as i32 * 3;
    let Some((e, p)) = PREFIXES.iter().find(|(e, _)| *e == exp.clamp(-9, 9)) else { return plain(v) };
    // A prefix on a unit that already has one reads badly (`kkg`): mass stays in kg or g.
    if unit == "kg" {
        return if v.abs() < 1.0 { format!("{} g", round_sig(v * 1e3, SIGNIFICANT_DIGITS)) } else { plain(v) };
    }
    format!("{} {p}{unit}", round_sig(v / 10f64.powi(*e), SIGNIFICANT_DIGITS))
}

/// What a port's values come to, in a few words (all sweep points of the step together).
fn headline(values: &[&Value]) -> String {
    let Some(first) = values.first() else { return String::new() };
    let count = values.len();
    let range = |xs: Vec<f64>, unit: &str| -> String {
        let xs: Vec<f64> = xs.into_iter().filter(|x| x.is_finite()).collect();
        let (lo, hi) = xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(*x), b.max(*x)));
        if xs.is_empty() {
            "no finite value".into()
        } else if round_sig(lo, SIGNIFICANT_DIGITS) == round_sig(hi, SIGNIFICANT_DIGITS) {
            eng(lo, unit)
        } else {
            format!("{} … {}", eng(lo, unit), eng(hi, unit))
        }
    };
    match first {
        Value::Scalar(s) => range(
            values.iter().filter_map(|v| if let Value::Scalar(s) = v { Some(s.value) } else { None }).collect(),
            &shown(&s.unit.symbol),
        ),
        Value::Frf(f) => {
            let peaks: Vec<(f64, f64)> = values
                .iter()
                .filter_map(|v| if let Value::Frf(f) = v { Some(f) } else { None })
                .map(|f| {
                    f.values
                        .iter()
                        .zip(&f.freq_hz)
                        .map(|(v, fr)| (v.norm(), *fr))
                        .fold((0.0, 0.0), |a, b| if b.0 > a.0 { b } else { a })
                })
                .collect();
            let top = peaks.iter().fold((0.0, 0.0), |a, b| if b.0 > a.0 { *b } else { a });
            let what = if count > 1 { format!("{count} FRFs, ") } else { String::new() };
            format!("{what}peak |H| {} at {}", eng(top.0, &shown(&f.unit.symbol)), eng(top.1, "Hz"))
        }
        Value::Lobes(_) => {
            let mins: Vec<(f64, f64)> = values
                .iter()
                .filter_map(|v| if let Value::Lobes(l) = v { Some(l) } else { None })
                .flat_map(|l| l.depth_limit.iter().zip(&l.speed).map(|(d, s)| (*d, s.rpm_as_written())))
                .collect();
            let low = mins.iter().fold((f64::INFINITY, 0.0), |a, b| if b.0 < a.0 { *b } else { a });
            let n = mins.len();
            format!(
                "{n} speeds, lowest limit {} mm at {}",
                round_sig(low.0 * 1e3, SIGNIFICANT_DIGITS),
                eng(low.1, "rpm")
            )
        }
        Value::Table(t) if t.rows() == 1 && count == 1 => t
            .columns
            .iter()
            .take(6)
            .map(|c| match c.word(0) {
                Some(w) => format!("{} {}", shown(&c.name), shown(w)),
                None => format!("{} {}", shown(&c.name), eng(c.values[0], &shown(&c.unit.symbol))),
            })
            .collect::<Vec<_>>()
            .join(", "),
        Value::Table(_) => {
            let rows: usize = values.iter().map(|v| if let Value::Table(t) = v { t.rows() } else { 0 }).sum();
            format!("table, {rows} rows")
        }
        Value::TimeSeries(ts) => {
            let secs = ts.len() as f64 / ts.sample_rate;
            let what = if count > 1 { format!("{count} records of ") } else { String::new() };
            format!("{what}{} channel(s), {} at {}", ts.channels.len(), eng(secs, "s"), eng(ts.sample_rate, "Hz"))
        }
        Value::ModalModel(m) if count == 1 => {
            let f: Vec<String> = m.modes.iter().take(6).map(|m| eng(m.freq_hz, "Hz")).collect();
            format!("{} mode(s): {}", m.modes.len(), f.join(", "))
        }
        Value::ModalModel(_) => format!("{count} modal models"),
        other => describe(other),
    }
}

/// The short summary the command line prints by default: per step, the few numbers that
/// matter in engineering notation (`→` marks a step whose values go to a file), and its
/// warnings once each; `-v` prints [`summarize`].
pub fn short(compiled: &Compiled, result: &RunResult) -> String {
    let graph = &compiled.graph;
    let written: Vec<&str> = compiled.recipe.outputs.iter().flat_map(|o| o.steps()).collect();
    let mut out = String::new();
    for (step, ids) in &graph.by_step {
        let kind = &graph.instances[ids[0]].kind;
        let times = if ids.len() > 1 { format!(" ×{}", ids.len()) } else { String::new() };
        let failed = ids.iter().filter(|&&i| matches!(result.outcomes[i], Outcome::Failed(_))).count();
        let mut parts = Vec::new();
        if failed > 0 {
            parts.push(format!("{failed} failed"));
        }
        let outputs: Vec<&spindlelab_engine::exec::Produced> =
            ids.iter().filter_map(|&i| result.outcomes[i].outputs().map(|o| o.as_ref())).collect();
        if let Some(first) = outputs.first() {
            // Ports written to files first, then the rest, three at most.
            let mut ports: Vec<&String> = first.keys().collect();
            let out_ports: Vec<&str> =
                compiled.recipe.outputs.iter().filter(|o| o.from.step == *step).map(|o| o.from.port.as_str()).collect();
            ports.sort_by_key(|p| !out_ports.contains(&p.as_str()));
            for p in ports.into_iter().take(3) {
                let vals: Vec<&Value> = outputs.iter().filter_map(|o| o.get(p.as_str()).map(|v| v.as_ref())).collect();
                parts.push(format!("{p}: {}", headline(&vals)));
            }
        } else if failed == 0 {
            continue;
        }
        let file = if written.contains(&step.as_str()) { " →" } else { "" };
        let _ = writeln!(out, "{step} ({kind}{times}){file} {}", parts.join("; "));
        let mut warnings: Vec<(String, usize)> = Vec::new();
        for &i in ids {
            for w in result.outcomes[i].warnings() {
                match warnings.iter_mut().find(|(x, _)| x == w) {
                    Some((_, n)) => *n += 1,
                    None => warnings.push((w.clone(), 1)),
                }
            }
        }
        for (w, n) in warnings {
            let times = if n > 1 { format!(" (×{n})") } else { String::new() };
            let _ = writeln!(out, "  warning{times}: {}", shown(&w));
        }
    }
    out
}
