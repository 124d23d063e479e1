//! A stable, human-readable summary of a run: every output of every instance, numbers
//! rounded to a stated number of significant digits, no timings and no paths.

use spindlelab_engine::exec::{Outcome, RunResult};
use spindlelab_engine::round_sig;
use spindlelab_engine::value::Value;
use spindlelab_engine::{Compiled, graph::Graph};
use std::fmt::Write as _;

/// Significant digits of every number in a summary.
pub const SIGNIFICANT_DIGITS: i32 = 4;

fn n(x: f64) -> String {
    format!("{}", round_sig(x, SIGNIFICANT_DIGITS))
}

fn describe(v: &Value) -> String {
    match v {
        Value::Scalar(s) => format!("{} {}", n(s.value), s.unit.symbol),
        Value::TimeSeries(ts) => {
            let mut s = format!("time series, {} samples at {} Hz", ts.len(), n(ts.sample_rate));
            for c in &ts.channels {
                let peak = c.samples.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                let rms = (c.samples.iter().map(|x| x * x).sum::<f64>() / c.samples.len().max(1) as f64).sqrt();
                let _ = write!(s, "; {}: peak {} {}, rms {} {}", c.name, n(peak), c.unit.symbol, n(rms), c.unit.symbol);
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
                f.unit.symbol,
                n(f.freq_hz.get(imax).copied().unwrap_or(0.0))
            )
        }
        Value::Table(t) => {
            let mut s = format!("table, {} rows", t.rows());
            for c in &t.columns {
                let vals: Vec<String> = c.values.iter().take(12).map(|x| n(*x)).collect();
                let more = if c.values.len() > 12 { ", …" } else { "" };
                let _ = write!(s, "\n      {} [{}]: {}{more}", c.name, c.unit.symbol, vals.join(", "));
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
                    format!("{} ({} modes, first flexible {first} Hz)", p.name, p.nu.len())
                })
                .collect();
            format!("substructure of `{}`: {}", s.assembly, parts.join(", "))
        }
        Value::Lobes(l) => format!("lobes, {} speeds", l.speed_rpm.len()),
    }
}

/// The summary of every instance's outputs, in graph order.
pub fn summarize(compiled: &Compiled, result: &RunResult) -> String {
    summarize_graph(&compiled.recipe.name, &compiled.graph, result)
}

fn summarize_graph(name: &str, graph: &Graph, result: &RunResult) -> String {
    let mut out = format!("recipe {name}: {} node instance(s)\n", graph.instances.len());
    for (inst, outcome) in graph.instances.iter().zip(&result.outcomes) {
        let _ = writeln!(out, "{} ({})", inst.id, inst.kind);
        match outcome {
            Outcome::Computed { outputs, .. } | Outcome::Cached { outputs, .. } => {
                for (port, v) in outputs.iter() {
                    let _ = writeln!(out, "  {port}: {}", describe(v));
                }
                for w in outcome.warnings() {
                    let _ = writeln!(out, "  warning: {w}");
                }
            }
            Outcome::Failed(e) => {
                let _ = writeln!(out, "  failed: {e}");
            }
            Outcome::Skipped => {
                let _ = writeln!(out, "  skipped");
            }
            Outcome::Released { .. } => {
                let _ = writeln!(out, "  outputs released once every consumer had run (never cached)");
                for w in outcome.warnings() {
                    let _ = writeln!(out, "  warning: {w}");
                }
            }
            Outcome::Unneeded { cached } => {
                let how = if *cached { "cached" } else { "not cached" };
                let _ = writeln!(out, "  not loaded ({how}; every consumer came from the cache)");
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
