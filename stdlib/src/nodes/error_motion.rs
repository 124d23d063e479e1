//! `tach.decode`, `errors.separate` and `ldv.integrate`: revolutions from the tachometer
//! (§3.1.1), three-probe error separation (§3.2, Eqs. 3.4–3.15) and displacement from laser
//! vibrometer velocity (§3.2.1).

use crate::error_motion::{
    LdvError, ProbeRecords, Separation, SeparationError, SeparationOptions, integrate_velocity, separate,
};
use crate::tach::{Revolutions, TachError, TachOptions, decode};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Channel, Column, PortType, Scalar, Table, TimeSeries, UnitLabel, Value};
use spindlelab_grammar::Dimension as D;
use std::f64::consts::TAU;

/// The tachometer fields the three kinds share: the `threshold` and `max_drift` of
/// `tach.decode`, which `errors.separate` (both) and `ldv.integrate` (`max_drift`) repeat.
const THRESHOLD_DOC: &str =
    "falling-edge threshold in the channel's units (V); default midway between the low and high levels";
const MAX_DRIFT_DEFAULT: &str = "2 %";
const MAX_DRIFT_DOC: &str = "largest accepted deviation of one revolution's speed from the mean";

node_params! {
    /// Parameters of `tach.decode`.
    pub struct TachDecodeParams<'a> {
        channel: def &'a str = (T::Text, "tach", "name of the tachometer channel (V)"),
        threshold: opt f64 = (T::Quantity(D::DIMENSIONLESS), THRESHOLD_DOC),
        max_drift: def f64 = (T::Quantity(D::DIMENSIONLESS), MAX_DRIFT_DEFAULT, MAX_DRIFT_DOC),
    }
}

fn tach_options(threshold: Option<f64>, max_drift: f64) -> TachOptions {
    TachOptions { threshold, max_drift, ..TachOptions::default() }
}

fn validate_max_drift(d: f64) -> Result<(), NodeError> {
    if d.is_nan() || d <= 0.0 {
        return Err(NodeError::param("max_drift", format!("must be positive, got {d}")));
    }
    Ok(())
}

fn tach_err(e: TachError) -> NodeError {
    match e {
        TachError::InvalidOption { name: "threshold", .. } => NodeError::param("threshold", e.to_string()),
        TachError::InvalidOption { name: "max_drift", .. } | TachError::Drift { .. } => {
            NodeError::input("signal", format!("{e} (raise `max_drift` if the drift is real)"))
        }
        _ => NodeError::input("signal", e.to_string()),
    }
}

fn time_series<'a>(ctx: &'a NodeContext) -> Result<&'a TimeSeries, NodeError> {
    match ctx.input("signal")? {
        Value::TimeSeries(ts) => Ok(ts),
        other => Err(NodeError::input("signal", format!("expected a time series, got a {}", other.port_type()))),
    }
}

fn channel<'a>(ts: &'a TimeSeries, name: &str, param: &str) -> Result<&'a Channel, NodeError> {
    ts.channel(name).ok_or_else(|| {
        let names: Vec<&str> = ts.channels.iter().map(|c| c.name.as_str()).collect();
        NodeError::param(param, format!("the signal has no channel `{name}` (channels: {})", names.join(", ")))
    })
}

/// Revolutions from the tachometer channel `name`, which the parameter `param` names.
fn decode_tach(ts: &TimeSeries, name: &str, param: &str, opts: &TachOptions) -> Result<Revolutions, NodeError> {
    let tach = channel(ts, name, param)?;
    decode(&tach.samples, ts.sample_rate, ts.t0, opts).map_err(tach_err)
}

/// `tach.decode`: falling edges of the tachometer → revolution table and mean speed.
pub struct TachDecode {
    spec: NodeSpec,
}

impl Default for TachDecode {
    fn default() -> Self {
        Self::new()
    }
}

impl TachDecode {
    pub fn new() -> Self {
        TachDecode {
            spec: NodeSpec {
                kind: "tach.decode",
                version: 1,
                description: "Revolutions from the once-per-revolution tachometer: sub-sample falling edges (θ = 0, §3.1.1), speed per revolution and mean speed.",
                inputs: vec![PortSpec::new(
                    "signal",
                    PortType::TimeSeries,
                    "record holding the tachometer channel (V)",
                )],
                outputs: vec![
                    PortSpec::new(
                        "revolutions",
                        PortType::Table,
                        "index, start time (s) and speed (rpm) of each complete revolution",
                    ),
                    PortSpec::new("speed", PortType::Scalar, "mean spindle speed (rad/s)"),
                ],
                params: TachDecodeParams::fields(),
            },
        }
    }
}

impl Node for TachDecode {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        validate_max_drift(TachDecodeParams::read(p)?.max_drift)
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let ts = time_series(ctx)?;
        let p = TachDecodeParams::read(ctx.params)?;
        let revs = decode_tach(ts, p.channel, "channel", &tach_options(p.threshold, p.max_drift))?;
        let n = revs.count();
        let table = Table {
            columns: vec![
                Column::new("index", "", (0..n).map(|r| r as f64).collect()),
                Column::new("start", "s", (0..n).map(|r| revs.start(r)).collect()),
                Column::new("speed", "rpm", (0..n).map(|r| revs.speed_rpm(r)).collect()),
            ],
        };
        Ok([
            ("revolutions".to_string(), Value::Table(table)),
            ("speed".to_string(), Value::Scalar(Scalar::new(revs.mean_speed(), "rad/s"))),
        ]
        .into_iter()
        .collect())
    }
}

node_params! {
    /// Parameters of `errors.separate`.
    pub struct ErrorsSeparateParams<'a> {
        tach: def &'a str = (T::Text, "tach", "name of the tachometer channel (V)"),
        probe_a: def &'a str = (T::Text, "a", "channel of probe A (at the first angle, 0)"),
        probe_b: def &'a str = (T::Text, "b", "channel of probe B (at σ)"),
        probe_c: def &'a str = (T::Text, "c", "channel of probe C (at ρ)"),
        angles: def &'a [f64] = (
            T::QuantityList(D::ANGLE),
            "[0, 99.84, 202.5] deg",
            "probe angles A, B (σ), C (ρ); A at 0",
        ),
        sensor: def &'a str = (
            T::Choice(&["displacement", "velocity"]),
            "displacement",
            "velocity probes (laser vibrometer) are integrated first (§3.2.1)",
        ),
        segments: def usize = (
            T::Integer { min: 2, max: 100_000 },
            "10",
            "segments of revolutions for the uncertainty of §3.2.2.1",
        ),
        samples_per_rev: opt usize = (
            T::Integer { min: 8, max: 100_000_000 },
            "angle grid size (even); default the fewest samples in a revolution, rounded down to an FFT-friendly even number",
        ),
        allow_unrecoverable: def bool = (
            T::Bool,
            "false",
            "accept probe angles that cannot separate low harmonics (they are zeroed)",
        ),
        required_upr: def usize = (
            T::Integer { min: 2, max: 1_000_000 },
            "100",
            "harmonics 2..=this must be separable by the probe angles",
        ),
        gain_tolerance: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "0.01",
            "harmonics with α_k² + β_k² below this are not divided by (Eq. 3.12)",
        ),
        phase_slope: def f64 = (
            T::Quantity(D::PHASE_SLOPE),
            "0 deg/kHz",
            "phase slope of the probe chain (Eq. 2.11); its delay is taken out of the angle mapping",
        ),
        async_max_frequency: opt f64 = (
            T::Quantity(D::FREQUENCY),
            "keep asynchronous spectrum lines up to this frequency",
        ),
        threshold: opt f64 = (T::Quantity(D::DIMENSIONLESS), THRESHOLD_DOC),
        max_drift: def f64 = (T::Quantity(D::DIMENSIONLESS), MAX_DRIFT_DEFAULT, MAX_DRIFT_DOC),
    }
}

/// `errors.separate`: three-probe error separation.
pub struct ErrorsSeparate {
    spec: NodeSpec,
}

impl Default for ErrorsSeparate {
    fn default() -> Self {
        Self::new()
    }
}

impl ErrorsSeparate {
    pub fn new() -> Self {
        ErrorsSeparate {
            spec: NodeSpec {
                kind: "errors.separate",
                version: 2,
                description: "Three-probe error separation (§3.2, Eqs. 3.4–3.15): artifact form, synchronous and asynchronous spindle error motions, spectra and segment uncertainty (§3.2.2).",
                inputs: vec![PortSpec::new(
                    "signal",
                    PortType::TimeSeries,
                    "record with the tachometer (V) and three probe channels (m, or m/s with `sensor: velocity`)",
                )],
                outputs: vec![
                    PortSpec::new(
                        "form",
                        PortType::Table,
                        "artifact form error per angle with the segment σ and the ±3σ band",
                    ),
                    PortSpec::new(
                        "motion",
                        PortType::Table,
                        "synchronous x, y, r and asynchronous σ per angle, with the segment σ of synchronous x and y",
                    ),
                    PortSpec::new(
                        "spectrum",
                        PortType::Table,
                        "synchronous amplitudes and form amplitude per undulation per revolution",
                    ),
                    PortSpec::new(
                        "async_spectrum",
                        PortType::Table,
                        "amplitude spectrum of the asynchronous x and y (Hz)",
                    ),
                    PortSpec::new("summary", PortType::Table, "one row of figures of merit"),
                ],
                params: ErrorsSeparateParams::fields(),
            },
        }
    }
}

fn separation_err(e: SeparationError) -> NodeError {
    match e {
        SeparationError::InvalidSegments { .. } => NodeError::param("segments", e.to_string()),
        SeparationError::InvalidSamplesPerRev { .. } => NodeError::param("samples_per_rev", e.to_string()),
        SeparationError::DegenerateAngles { .. } => NodeError::param("angles", e.to_string()),
        SeparationError::Unrecoverable { .. } => {
            NodeError::param("angles", format!("{e} (`allow_unrecoverable: true`)"))
        }
        SeparationError::InvalidOption { name: "gain_tolerance", .. } => {
            NodeError::param("gain_tolerance", e.to_string())
        }
        _ => NodeError::input("signal", e.to_string()),
    }
}

fn ldv_err(e: LdvError, channel: &str) -> NodeError {
    NodeError::input("signal", format!("channel `{channel}`: {e}"))
}

fn angles_of(angles: &[f64]) -> Result<[f64; 3], NodeError> {
    match *angles {
        [a, b, c] => Ok([a, b, c]),
        _ => Err(NodeError::param("angles", format!("three angles (A, B, C) are needed, got {}", angles.len()))),
    }
}

impl Node for ErrorsSeparate {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        let p = ErrorsSeparateParams::read(p)?;
        validate_max_drift(p.max_drift)?;
        let angles = angles_of(p.angles)?;
        if angles[0].abs() > 1e-12 {
            return Err(NodeError::param("angles", "probe A must be at 0: angles count from probe A"));
        }
        if let Some(n) = p.samples_per_rev
            && n % 2 == 1
        {
            return Err(NodeError::param("samples_per_rev", format!("must be even, got {n}")));
        }
        let t = p.gain_tolerance;
        if t.is_nan() || t < 0.0 {
            return Err(NodeError::param("gain_tolerance", format!("must not be negative, got {t}")));
        }
        if let Some(f) = p.async_max_frequency
            && (f.is_nan() || f <= 0.0)
        {
            return Err(NodeError::param("async_max_frequency", format!("must be positive, got {f}")));
        }
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let ts = time_series(ctx)?;
        let p = ErrorsSeparateParams::read(ctx.params)?;
        let mut revs = decode_tach(ts, p.tach, "tach", &tach_options(p.threshold, p.max_drift))?;
        // A probe chain that lags by τ shows at t the surface that passed at t − τ: the
        // probes' revolutions start τ after the tachometer's edges (Eq. 2.11's slope −2πτ).
        let slope = p.phase_slope;
        if slope != 0.0 {
            let tau = -slope / std::f64::consts::TAU;
            let last = ts.t0 + (ts.len().saturating_sub(1)) as f64 / ts.sample_rate;
            let shifted: Vec<f64> = revs.edges().iter().map(|e| e + tau).filter(|&e| e >= ts.t0 && e <= last).collect();
            revs = crate::tach::Revolutions::from_edges(shifted, revs.sample_rate())
                .map_err(|e| NodeError::param("phase_slope", e.to_string()))?;
        }
        let velocity = p.sensor == "velocity";
        let mut records: Vec<Vec<f64>> = Vec::with_capacity(3);
        let mut borrowed: Vec<&[f64]> = Vec::with_capacity(3);
        for (param, name) in [("probe_a", p.probe_a), ("probe_b", p.probe_b), ("probe_c", p.probe_c)] {
            let ch = channel(ts, name, param)?;
            match (velocity, ch.unit.symbol.as_str()) {
                (false, "m/s") => {
                    return Err(NodeError::param(
                        "sensor",
                        format!("channel `{}` holds velocity (m/s): set `sensor: velocity`", ch.name),
                    ));
                }
                (true, "m") => {
                    return Err(NodeError::param(
                        "sensor",
                        format!("channel `{}` holds displacement (m): set `sensor: displacement`", ch.name),
                    ));
                }
                _ => {}
            }
            if velocity {
                let hz = revs.mean_speed_rpm() / 60.0;
                records.push(integrate_velocity(&ch.samples, ts.sample_rate, hz).map_err(|e| ldv_err(e, &ch.name))?);
            } else {
                borrowed.push(&ch.samples);
            }
        }
        if velocity {
            borrowed = records.iter().map(Vec::as_slice).collect();
        }
        let angles = angles_of(p.angles)?;
        let opts = SeparationOptions {
            angles,
            samples_per_rev: p.samples_per_rev,
            segments: p.segments,
            gain_tolerance: p.gain_tolerance,
            required_harmonics: p.required_upr,
            allow_unrecoverable: p.allow_unrecoverable,
            async_spectrum: true,
        };
        let probes =
            ProbeRecords { a: borrowed[0], b: borrowed[1], c: borrowed[2], sample_rate: ts.sample_rate, t0: ts.t0 };
        let sep = separate(&probes, &revs, &opts).map_err(separation_err)?;
        warn(ctx, &sep, angles);
        Ok(outputs(&sep, p.async_max_frequency))
    }
}

fn warn(ctx: &NodeContext, sep: &Separation, angles: [f64; 3]) {
    if !sep.unrecoverable.is_empty() {
        const SHOWN: usize = 12;
        let list: Vec<String> = sep.unrecoverable.iter().take(SHOWN).map(usize::to_string).collect();
        let more = sep.unrecoverable.len().saturating_sub(SHOWN);
        let more = if more > 0 { format!(" and {more} more") } else { String::new() };
        let deg = angles.map(f64::to_degrees);
        ctx.warn(format!(
            "harmonic(s) {}{more} UPR cannot be separated with probes at {:.2}°, {:.2}°, {:.2}°: they are left out of the form (and stay in x)",
            list.join(", "),
            deg[0],
            deg[1],
            deg[2]
        ));
    }
    if sep.nyquist_exceeded {
        ctx.warn(format!(
            "the angle grid ({} points) resolves {} UPR but the sampling only {:.1} UPR (Eq. 3.15): content above it is not measured",
            sep.samples_per_rev,
            sep.samples_per_rev / 2,
            sep.nyquist_upr
        ));
    }
}

fn outputs(sep: &Separation, async_max: Option<f64>) -> Outputs {
    let st = &sep.segments;
    let band = |k: f64| st.form_mean.iter().zip(&st.form_sigma).map(|(m, s)| m + k * s).collect::<Vec<f64>>();
    let form = Table {
        columns: vec![
            Column::new("angle", "rad", sep.angle.clone()),
            Column::new("form", "m", sep.form.clone()),
            Column::new("form_sigma", "m", st.form_sigma.clone()),
            Column::new("form_lower", "m", band(-3.0)),
            Column::new("form_upper", "m", band(3.0)),
        ],
    };
    let motion = Table {
        columns: vec![
            Column::new("angle", "rad", sep.angle.clone()),
            Column::new("sync_x", "m", sep.sync_x.clone()),
            Column::new("sync_y", "m", sep.sync_y.clone()),
            Column::new("sync_r", "m", sep.sync_r.clone()),
            Column::new("async_sigma_x", "m", sep.async_sigma_x.clone()),
            Column::new("async_sigma_y", "m", sep.async_sigma_y.clone()),
            Column::new("async_sigma_r", "m", sep.async_sigma_r.clone()),
            Column::new("seg_sigma_x", "m", st.x_sigma.clone()),
            Column::new("seg_sigma_y", "m", st.y_sigma.clone()),
        ],
    };
    let sp = &sep.sync_spectrum;
    let spectrum = Table {
        columns: vec![
            Column::new("upr", "", (0..sp.x.len()).map(|k| k as f64).collect()),
            Column::new("sync_x", "m", sp.x.clone()),
            Column::new("sync_y", "m", sp.y.clone()),
            Column::new("sync_r", "m", sp.r.clone()),
            Column::new("form", "m", sp.form.clone()),
        ],
    };
    let (freq, ax, ay) = match &sep.async_spectrum {
        Some(a) => {
            let keep = async_max.map_or(a.freq_hz.len(), |f| a.freq_hz.iter().take_while(|v| **v <= f).count());
            (a.freq_hz[..keep].to_vec(), a.x[..keep].to_vec(), a.y[..keep].to_vec())
        }
        None => (Vec::new(), Vec::new(), Vec::new()),
    };
    let async_spectrum =
        Table { columns: vec![Column::new("freq", "Hz", freq), Column::new("x", "m", ax), Column::new("y", "m", ay)] };
    let one = |v: f64| vec![v];
    let summary = Table {
        columns: vec![
            Column::new("measured_speed", "rpm", one(sep.mean_speed_rpm)),
            Column::new("revolutions", "", one(sep.revolutions as f64)),
            Column::new("samples_per_rev", "", one(sep.samples_per_rev as f64)),
            Column::new("nyquist_upr", "", one(sep.nyquist_upr)),
            Column::new("form_ptv", "m", one(sep.ptv.form)),
            Column::new("sync_x_ptv", "m", one(sep.ptv.x)),
            Column::new("sync_y_ptv", "m", one(sep.ptv.y)),
            Column::new("sync_r_ptv", "m", one(sep.ptv.r)),
            Column::new("async_x", "m", one(sep.async_value_x)),
            Column::new("async_y", "m", one(sep.async_value_y)),
            Column::new("form_sigma_mean", "m", one(st.form_sigma_mean)),
            Column::new("sync_x_sigma_mean", "m", one(st.x_sigma_mean)),
            Column::new("sync_y_sigma_mean", "m", one(st.y_sigma_mean)),
            Column::new("unrecoverable", "", one(sep.unrecoverable.len() as f64)),
        ],
    };
    [
        ("form".to_string(), Value::Table(form)),
        ("motion".to_string(), Value::Table(motion)),
        ("spectrum".to_string(), Value::Table(spectrum)),
        ("async_spectrum".to_string(), Value::Table(async_spectrum)),
        ("summary".to_string(), Value::Table(summary)),
    ]
    .into_iter()
    .collect()
}

node_params! {
    /// Parameters of `ldv.integrate`.
    pub struct LdvIntegrateParams<'a> {
        channels: opt &'a str = (
            T::Text,
            "comma-separated channels to integrate; default every channel but the tachometer",
        ),
        tach: def &'a str = (T::Text, "tach", "name of the tachometer channel (V)"),
        spindle_speed: opt f64 = (
            T::Quantity(D::ROTATIONAL_SPEED),
            "spindle speed for the high-pass cutoff; default the tachometer's mean speed",
        ),
        max_drift: def f64 = (T::Quantity(D::DIMENSIONLESS), MAX_DRIFT_DEFAULT, MAX_DRIFT_DOC),
    }
}

/// `ldv.integrate`: laser-vibrometer velocity → displacement (§3.2.1).
pub struct LdvIntegrate {
    spec: NodeSpec,
}

impl Default for LdvIntegrate {
    fn default() -> Self {
        Self::new()
    }
}

impl LdvIntegrate {
    pub fn new() -> Self {
        LdvIntegrate {
            spec: NodeSpec {
                kind: "ldv.integrate",
                version: 1,
                description: "Velocity to displacement (§3.2.1): cumulative trapezoid, then a zero-phase 3rd-order Butterworth high-pass at half the spindle frequency.",
                inputs: vec![PortSpec::new(
                    "signal",
                    PortType::TimeSeries,
                    "velocity channels (m/s), with the tachometer unless `spindle_speed` is given",
                )],
                outputs: vec![PortSpec::new(
                    "signal",
                    PortType::TimeSeries,
                    "the integrated channels (m); other channels pass through unchanged",
                )],
                params: LdvIntegrateParams::fields(),
            },
        }
    }
}

impl Node for LdvIntegrate {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        let p = LdvIntegrateParams::read(p)?;
        validate_max_drift(p.max_drift)?;
        if let Some(w) = p.spindle_speed
            && (w.is_nan() || w <= 0.0)
        {
            return Err(NodeError::param("spindle_speed", format!("must be positive, got {w}")));
        }
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let ts = time_series(ctx)?;
        let p = LdvIntegrateParams::read(ctx.params)?;
        let tach = p.tach;
        let spindle_hz = match p.spindle_speed {
            Some(w) => w / TAU,
            None => decode_tach(ts, tach, "tach", &tach_options(None, p.max_drift))?.mean_speed_rpm() / 60.0,
        };
        let wanted: Vec<String> = match p.channels {
            Some(list) => {
                let names: Vec<String> =
                    list.split(',').map(str::trim).filter(|s| !s.is_empty()).map(str::to_string).collect();
                for n in &names {
                    channel(ts, n, "channels")?;
                }
                names
            }
            None => ts.channels.iter().filter(|c| c.name != tach).map(|c| c.name.clone()).collect(),
        };
        if wanted.is_empty() {
            return Err(NodeError::param("channels", "no channel to integrate"));
        }
        let mut out =
            TimeSeries { sample_rate: ts.sample_rate, t0: ts.t0, channels: Vec::with_capacity(ts.channels.len()) };
        for ch in &ts.channels {
            if wanted.contains(&ch.name) {
                let samples =
                    integrate_velocity(&ch.samples, ts.sample_rate, spindle_hz).map_err(|e| ldv_err(e, &ch.name))?;
                out.channels.push(Channel { name: ch.name.clone(), unit: UnitLabel::new("m"), samples });
            } else {
                out.channels.push(ch.clone());
            }
        }
        Ok([("signal".to_string(), Value::TimeSeries(out))].into_iter().collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_motion::rig::Rig;
    use crate::nodes::test_support::empty_recipe as recipe;
    use indexmap::IndexMap;
    use spindlelab_engine::diag::{Diagnostics, Span};
    use spindlelab_engine::node::Labelled;
    use spindlelab_engine::spec::{Ctx, EntityNames, ParamValue, check_value};
    use spindlelab_engine::syntax::{Raw, RawKind};
    use std::sync::Arc;

    /// Parameters as the compiler would give them: defaults, then `set` (recipe text).
    fn params(spec: &NodeSpec, set: &[(&str, &str)]) -> Params {
        let names = EntityNames::default();
        let ctx = Ctx { entities: &names, base_dir: None, confine: None };
        let mut values = IndexMap::new();
        for f in &spec.params {
            let text = set.iter().find(|(k, _)| *k == f.name).map(|(_, v)| *v).or(f.default);
            let Some(text) = text else { continue };
            let kind = match f.ty {
                T::Bool => RawKind::Bool(text == "true"),
                _ => RawKind::Str(text.to_string()),
            };
            let raw = Raw { span: Span::file_only("<test>".into()), kind };
            let mut diags = Diagnostics::new();
            let v: ParamValue = check_value(&raw, &f.ty, f.name, &ctx, &mut diags).unwrap_or_else(|| panic!("{diags}"));
            values.insert(f.name.to_string(), v);
        }
        Params { values }
    }

    /// Runs `node` on `signal` with parameters `set`; the outputs and the warnings.
    fn run_node(
        node: &dyn Node,
        signal: TimeSeries,
        set: &[(&str, &str)],
    ) -> (Result<Outputs, NodeError>, Vec<String>) {
        let p = params(node.spec(), set);
        node.validate(&p).expect("valid parameters");
        let mut inputs = IndexMap::new();
        inputs.insert(
            "signal".to_string(),
            vec![Labelled { label: String::new(), coords: Vec::new(), value: Arc::new(Value::TimeSeries(signal)) }],
        );
        let r = recipe();
        let entities = r.entities_named_by(&p);
        let ctx = NodeContext::new("test", &p, &inputs, &entities);
        let out = node.run(&ctx);
        (out, ctx.take_warnings())
    }

    fn record(rig: &Rig) -> TimeSeries {
        let s = rig.generate();
        let unit = if rig.velocity { "m/s" } else { "m" };
        let ch = |name: &str, unit: &str, samples: Vec<f64>| Channel {
            name: name.into(),
            unit: UnitLabel::new(unit),
            samples,
        };
        TimeSeries {
            sample_rate: rig.fs,
            t0: 0.0,
            channels: vec![ch("tach", "V", s.tach), ch("a", unit, s.a), ch("b", unit, s.b), ch("c", unit, s.c)],
        }
    }

    fn table<'a>(out: &'a Outputs, port: &str) -> &'a Table {
        match &out[port] {
            Value::Table(t) => t,
            other => panic!("{port}: {other:?}"),
        }
    }

    fn column<'a>(t: &'a Table, name: &str) -> &'a Column {
        t.columns.iter().find(|c| c.name == name).unwrap_or_else(|| panic!("no column {name}"))
    }

    fn rig() -> Rig {
        let mut rig = Rig::new(3000.0, 20);
        rig.form = vec![(2, 0.3e-6, 0.1e-6), (5, -0.1e-6, 0.05e-6), (44, 0.1e-6, -0.2e-6)];
        rig.y = vec![(44, 0.0, 25e-9)];
        rig
    }

    #[test]
    fn tach_decode_gives_revolutions_and_mean_speed() {
        let rig = rig();
        let (out, warnings) = run_node(&TachDecode::new(), record(&rig), &[]);
        let out = out.unwrap();
        assert!(warnings.is_empty());
        let t = table(&out, "revolutions");
        assert_eq!(t.rows(), 20);
        assert_eq!(column(t, "start").unit.symbol, "s");
        assert!(column(t, "speed").values.iter().all(|v| (v - 3000.0).abs() < 1e-3));
        let Value::Scalar(speed) = &out["speed"] else { panic!() };
        assert!((speed.value - 3000.0 * TAU / 60.0).abs() < 1e-4 && speed.unit.symbol == "rad/s");
        let (err, _) = run_node(&TachDecode::new(), record(&rig), &[("channel", "index")]);
        assert!(matches!(err, Err(NodeError::InvalidParam { ref param, .. }) if param == "channel"), "{err:?}");
    }

    #[test]
    fn errors_separate_outputs_form_motion_spectra_and_summary() {
        let rig = rig();
        let (out, warnings) = run_node(&ErrorsSeparate::new(), record(&rig), &[("segments", "4")]);
        let out = out.unwrap();
        let form = table(&out, "form");
        let n = form.rows();
        assert!(n > 1900 && n.is_multiple_of(2));
        assert_eq!(column(form, "angle").unit.symbol, "rad");
        let angle = &column(form, "angle").values;
        let err = column(form, "form")
            .values
            .iter()
            .zip(angle)
            .map(|(r, &t)| (r - rig.expected_form(t)).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-9, "form error {err}");
        let lower = &column(form, "form_lower").values;
        let upper = &column(form, "form_upper").values;
        assert!(lower.iter().zip(upper).all(|(l, u)| l <= u));
        let spectrum = table(&out, "spectrum");
        assert!((column(spectrum, "sync_y").values[44] - 25e-9).abs() < 1e-9);
        assert_eq!(column(spectrum, "upr").values[44], 44.0);
        let summary = table(&out, "summary");
        assert_eq!(summary.rows(), 1);
        assert!((column(summary, "measured_speed").values[0] - 3000.0).abs() < 1e-3);
        assert!((column(summary, "nyquist_upr").values[0] - 1000.0).abs() < 1e-3);
        let motion = table(&out, "motion");
        assert_eq!(motion.rows(), n);
        assert!(column(motion, "async_sigma_x").values.iter().all(|v| *v < 1e-9));
        let asy = table(&out, "async_spectrum");
        assert_eq!(column(asy, "freq").unit.symbol, "Hz");
        // The default angles lose 255 and 257 UPR (among others): a warning names them.
        assert!(warnings.iter().any(|w| w.contains("255, 257")), "{warnings:?}");
        let (trimmed, _) =
            run_node(&ErrorsSeparate::new(), record(&rig), &[("segments", "4"), ("async_max_frequency", "1 kHz")]);
        let trimmed = trimmed.unwrap();
        assert!(column(table(&trimmed, "async_spectrum"), "freq").values.iter().all(|f| *f <= 1000.0));
    }

    #[test]
    fn errors_separate_rejects_angles_that_lose_low_harmonics() {
        let mut rig = rig();
        rig.angles = [0.0, 90f64.to_radians(), 180f64.to_radians()];
        rig.revs = 6;
        let set = [("angles", "[0, 90, 180] deg"), ("segments", "2")];
        let (err, _) = run_node(&ErrorsSeparate::new(), record(&rig), &set);
        let Err(NodeError::InvalidParam { param, message }) = err else { panic!("{err:?}") };
        assert_eq!(param, "angles");
        assert!(message.contains("[3, 5, 7") && message.contains("allow_unrecoverable"), "{message}");
        let allowed = [("angles", "[0, 90, 180] deg"), ("segments", "2"), ("allow_unrecoverable", "true")];
        let (out, warnings) = run_node(&ErrorsSeparate::new(), record(&rig), &allowed);
        assert!(out.is_ok());
        assert!(warnings.iter().any(|w| w.contains("3, 5, 7") && w.contains("90.00°")), "{warnings:?}");
    }

    #[test]
    fn velocity_sensor_and_ldv_integrate() {
        let mut rig = rig();
        rig.velocity = true;
        let signal = record(&rig);
        // Velocity channels with the displacement setting are refused with a hint.
        let (err, _) = run_node(&ErrorsSeparate::new(), signal.clone(), &[("segments", "4")]);
        assert!(matches!(err, Err(NodeError::InvalidParam { ref param, .. }) if param == "sensor"), "{err:?}");
        let (out, _) = run_node(&ErrorsSeparate::new(), signal.clone(), &[("segments", "4"), ("sensor", "velocity")]);
        let out = out.unwrap();
        let form = table(&out, "form");
        let angle = &column(form, "angle").values;
        let (mut e2, mut t2) = (0.0, 0.0);
        for (r, &t) in column(form, "form").values.iter().zip(angle) {
            e2 += (r - rig.expected_form(t)).powi(2);
            t2 += rig.expected_form(t).powi(2);
        }
        assert!((e2 / t2).sqrt() < 0.005, "relative form error {}", (e2 / t2).sqrt());

        // ldv.integrate: displacement channels in metres, the tachometer passed through.
        let (out, _) = run_node(&LdvIntegrate::new(), signal.clone(), &[]);
        let Value::TimeSeries(ts) = &out.unwrap()["signal"] else { panic!() };
        assert_eq!(ts.channels.len(), 4);
        assert_eq!(ts.channel("a").unwrap().unit.symbol, "m");
        assert_eq!(ts.channel("tach").unwrap(), signal.channel("tach").unwrap());
        // Probe A reads R(θ) + x with x = 0 here: its displacement is the form along θ(t).
        let a = &ts.channel("a").unwrap().samples;
        let (mut e2, mut t2) = (0.0, 0.0);
        for (i, v) in a.iter().enumerate() {
            let truth = crate::error_motion::rig::series(&rig.form, rig.theta(i as f64 / rig.fs).0);
            e2 += (v - truth).powi(2);
            t2 += truth * truth;
        }
        assert!((e2 / t2).sqrt() < 0.01, "relative error {}", (e2 / t2).sqrt());
        let (out, _) =
            run_node(&LdvIntegrate::new(), signal.clone(), &[("channels", "b"), ("spindle_speed", "3000 rpm")]);
        let Value::TimeSeries(ts) = &out.unwrap()["signal"] else { panic!() };
        assert_eq!(ts.channel("b").unwrap().unit.symbol, "m");
        assert_eq!(ts.channel("a").unwrap().unit.symbol, "m/s");
        let (err, _) = run_node(&LdvIntegrate::new(), signal, &[("channels", "z")]);
        assert!(matches!(err, Err(NodeError::InvalidParam { ref param, .. }) if param == "channels"));
    }

    #[test]
    fn node_specs_have_valid_defaults() {
        for node in [&TachDecode::new() as &dyn Node, &ErrorsSeparate::new(), &LdvIntegrate::new()] {
            spindlelab_engine::spec::check_defaults(&node.spec().params).unwrap();
            node.validate(&params(node.spec(), &[])).unwrap();
        }
        let p = params(ErrorsSeparate::new().spec(), &[("angles", "[0, 90] deg")]);
        assert!(ErrorsSeparate::new().validate(&p).is_err());
        let p = params(ErrorsSeparate::new().spec(), &[("samples_per_rev", "1001")]);
        assert!(ErrorsSeparate::new().validate(&p).is_err());
    }
}
