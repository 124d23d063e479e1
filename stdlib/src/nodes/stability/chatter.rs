//! `chatter.detect`: stable or chatter from the vibration records of one cut.

use super::outputs;
use crate::chatter::{self, ChatterError, ChatterKind, ChatterOptions, Record};
use spindlelab_domain::Speed;
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Channel, Column, PortType, Table, TimeSeries, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `chatter.detect`.
    pub struct ChatterDetectParams<'a> {
        x_channel: def &'a str = (T::Text, "ax", "channel along x"),
        y_channel: def &'a str = (T::Text, "ay", "channel along y"),
        speed: req f64 = (T::Quantity(D::ROTATIONAL_SPEED), "spindle speed of the cut"),
        teeth: req usize = (T::Integer { min: 1, max: 64 }, "number of teeth"),
        threshold: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "0.2",
            "chatter when the largest unnotched peak exceeds this fraction of the largest tooth harmonic",
        ),
        max_frequency: opt f64 = (T::Quantity(D::FREQUENCY), "search peaks up to here (default Nyquist)"),
    }
}

/// `chatter.detect`: stable or chatter from the x and y vibration records of one cut (§6.4, `|A| = |A_x| + |A_y|`).
pub struct ChatterDetect {
    spec: NodeSpec,
}

impl Default for ChatterDetect {
    fn default() -> Self {
        Self::new()
    }
}

impl ChatterDetect {
    pub fn new() -> Self {
        ChatterDetect {
            spec: NodeSpec {
                kind: "chatter.detect",
                version: 1,
                description: "Chatter or stable from the x and y vibration records of one cut (§6.4): |A(f)| = |A_x| + |A_y|, tooth-passing and runout harmonics notched, the largest remaining peak against the largest tooth harmonic.",
                inputs: vec![PortSpec::new("signal", PortType::TimeSeries, "the cut's records, e.g. accelerations")],
                outputs: vec![
                    PortSpec::new(
                        "result",
                        PortType::Table,
                        "one row: chatter (0/1), chatter_frequency (Hz, 0 if stable), ratio, kind (0 none, \
                         1 quasi-periodic, 2 period doubling), tooth_frequency (Hz), peak_frequency (Hz)",
                    ),
                    PortSpec::new("spectrum", PortType::Table, "frequency (Hz), amplitude |A|, notched (0/1)"),
                ],
                params: ChatterDetectParams::fields(),
            },
        }
    }
}

impl Node for ChatterDetect {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        super::positive(params, &["speed", "threshold", "max_frequency"])
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = ChatterDetectParams::read(ctx.params)?;
        let Value::TimeSeries(ts) = ctx.input("signal")? else {
            return Err(NodeError::input("signal", "expected a time series"));
        };
        let channel = |param: &str, name: &str| {
            ts.channel(name).ok_or_else(|| {
                let have: Vec<&str> = ts.channels.iter().map(|c| c.name.as_str()).collect();
                NodeError::param(param, format!("no channel `{name}` in the signal; it has: {}", have.join(", ")))
            })
        };
        let (x, y) = (channel("x_channel", p.x_channel)?, channel("y_channel", p.y_channel)?);
        let opts = ChatterOptions { threshold: p.threshold, max_freq_hz: p.max_frequency, ..ChatterOptions::default() };
        fn rec<'a>(ts: &'a TimeSeries, c: &'a Channel) -> Record<'a> {
            Record { sample_rate_hz: ts.sample_rate, samples: &c.samples }
        }
        let r = chatter::detect_chatter(rec(ts, x), rec(ts, y), Speed::from_rad_s(p.speed).rpm(), p.teeth, &opts)
            .map_err(|e| match e {
                ChatterError::InvalidOption { .. } => NodeError::param("threshold", e.to_string()),
                ChatterError::NoTeeth | ChatterError::InvalidSpeed(_) | ChatterError::ToothAboveNyquist { .. } => {
                    NodeError::param("speed", e.to_string())
                }
                other => NodeError::input("signal", other.to_string()),
            })?;
        let kind = match r.kind {
            None => 0.0,
            Some(ChatterKind::QuasiPeriodic) => 1.0,
            Some(ChatterKind::PeriodDoubling) => 2.0,
        };
        let result = Table {
            columns: vec![
                Column::new("chatter", "", vec![f64::from(u8::from(r.chatter))]),
                Column::new("chatter_frequency", "Hz", vec![r.chatter_hz.unwrap_or(0.0)]),
                Column::new("ratio", "", vec![r.ratio]),
                Column::new("kind", "", vec![kind]),
                Column::new("tooth_frequency", "Hz", vec![r.tooth_hz]),
                Column::new("peak_frequency", "Hz", vec![r.peak_hz]),
            ],
        };
        let spectrum = Table {
            columns: vec![
                Column::new("frequency", "Hz", r.freqs_hz),
                Column::new("amplitude", "", r.amplitude),
                Column::new("notched", "", r.notched.iter().map(|&n| f64::from(u8::from(n))).collect()),
            ],
        };
        Ok(outputs(vec![("result", Value::Table(result)), ("spectrum", Value::Table(spectrum))]))
    }
}
