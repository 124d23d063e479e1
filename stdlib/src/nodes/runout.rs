//! `runout.remove`: once-per-revolution removal of §3.1.1 on a continuous recording.

use crate::runout::{self, Sampling};
use crate::segment::{self, DetectOptions};
use crate::tach::{self, TachOptions};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Column, PortType, Table, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `runout.remove`.
    pub struct RunoutRemoveParams<'a> {
        channels: def &'a str = (T::Text, "a", "channels to clean, comma-separated"),
        tach_channel: def &'a str = (T::Text, "tach", "tachometer channel (falling edge at θ = 0)"),
        force_channel: def &'a str = (
            T::Text,
            "force",
            "force channel whose impacts are kept out of the average; empty for none",
        ),
        before: def f64 = (
            T::Quantity(D::TIME),
            "5 ms",
            "time before each impact kept out of the average",
        ),
        settle: def f64 = (
            T::Quantity(D::TIME),
            "0.2 s",
            "time after each impact kept out of the average, while the response rings",
        ),
        max_drift: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "2 %",
            "largest speed deviation of one revolution from the mean",
        ),
        samples_per_rev: opt usize = (
            T::Integer { min: 8, max: 1 << 20 },
            "angle grid size (default: fewest samples in a revolution)",
        ),
        stationary: def &'a str = (
            T::Choice(&["error", "pass"]),
            "error",
            "a tachometer without edges: an error, or pass the signal through unchanged with a warning (a spindle at rest has no runout)",
        ),
    }
}

pub struct RunoutRemove {
    spec: NodeSpec,
}

impl Default for RunoutRemove {
    fn default() -> Self {
        Self::new()
    }
}

impl RunoutRemove {
    pub fn new() -> Self {
        RunoutRemove {
            spec: NodeSpec {
                kind: "runout.remove",
                version: 1,
                description: "Removes the once-per-revolution content (form error and synchronous error motion) from response channels: revolutions free of impact response are mapped onto an angle grid through the tachometer, averaged, mapped back and subtracted (§3.1.1).",
                inputs: vec![PortSpec::new(
                    "signal",
                    PortType::TimeSeries,
                    "continuous recording with tachometer, force and response channels",
                )],
                outputs: vec![
                    PortSpec::new(
                        "signal",
                        PortType::TimeSeries,
                        "the recording with the once-per-revolution content removed from the cleaned channels",
                    ),
                    PortSpec::new(
                        "runout",
                        PortType::Table,
                        "the averaged once-per-revolution content per angle and channel",
                    ),
                ],
                params: RunoutRemoveParams::fields(),
            },
        }
    }
}

impl Node for RunoutRemove {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn cacheable(&self) -> bool {
        false
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        super::non_negative(p, &["before", "settle"])?;
        super::positive(p, &["max_drift"])?;
        if RunoutRemoveParams::read(p)?.channels.split(',').all(|s| s.trim().is_empty()) {
            return Err(NodeError::param("channels", "name at least one channel"));
        }
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let Value::TimeSeries(signal) = ctx.input("signal")? else {
            return Err(NodeError::input("signal", "expected a time series"));
        };
        let p = RunoutRemoveParams::read(ctx.params)?;
        let names: Vec<&str> = signal.channels.iter().map(|c| c.name.as_str()).collect();
        let find = |param: &str, name: &str| {
            signal.channels.iter().position(|c| c.name == name).ok_or_else(|| {
                NodeError::param(param, format!("no channel `{name}` in the recording (it has: {})", names.join(", ")))
            })
        };
        let tach_ch = &signal.channels[find("tach_channel", p.tach_channel)?];
        let targets: Vec<usize> = p
            .channels
            .split(',')
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(|name| find("channels", name))
            .collect::<Result<_, _>>()?;
        let fs = signal.sample_rate;
        let opts = TachOptions { max_drift: p.max_drift, ..TachOptions::default() };
        let revs = match tach::decode(&tach_ch.samples, fs, signal.t0, &opts) {
            Ok(r) => r,
            Err(e @ (tach::TachError::Flat { .. } | tach::TachError::TooFewEdges { .. })) if p.stationary == "pass" => {
                ctx.warn(format!("no revolution in `{}` ({e}): the spindle is at rest, nothing removed", tach_ch.name));
                let empty = Table { columns: Vec::new() };
                return Ok([
                    ("signal".to_string(), Value::TimeSeries(signal.clone())),
                    ("runout".to_string(), Value::Table(empty)),
                ]
                .into_iter()
                .collect());
            }
            Err(e) => return Err(NodeError::input("signal", format!("channel `{}`: {e}", tach_ch.name))),
        };
        let edges = revs.edges();
        let mut exclude = Vec::new();
        let force_name = p.force_channel;
        if !force_name.is_empty() {
            let force = &signal.channels[find("force_channel", force_name)?];
            let (before, settle) = (p.before, p.settle);
            match segment::detect(&force.samples, fs, signal.t0, 0, 1, &DetectOptions::default()) {
                Ok(impacts) => exclude.extend(impacts.iter().map(|i| (i.time - before, i.time + settle))),
                Err(segment::SegmentError::NoImpact { .. }) => {}
                Err(e) => return Err(NodeError::input("signal", format!("channel `{force_name}`: {e}"))),
            }
        }
        let sampling = Sampling { rate: fs, t0: signal.t0 };
        let grid = p.samples_per_rev;
        let mut out = signal.clone();
        let mut columns = Vec::new();
        for &c in &targets {
            let ch = &mut out.channels[c];
            let opr = runout::average(&ch.samples, sampling, edges, &exclude, grid)
                .map_err(|e| NodeError::input("signal", format!("channel `{}`: {e}", ch.name)))?;
            opr.subtract(&mut ch.samples, sampling, edges)
                .map_err(|e| NodeError::input("signal", format!("channel `{}`: {e}", ch.name)))?;
            if columns.is_empty() {
                let n = opr.profile.len();
                let angle = (0..n).map(|j| std::f64::consts::TAU * j as f64 / n as f64).collect();
                columns.push(Column::new("angle", "rad", angle));
            }
            if opr.profile.len() == columns[0].values.len() {
                columns.push(Column {
                    name: ch.name.clone(),
                    unit: ch.unit.clone(),
                    values: opr.profile,
                    levels: Vec::new(),
                });
            }
            if opr.revolutions < 3 {
                ctx.warn(format!(
                    "channel `{}`: only {} revolution(s) free of impact response were averaged",
                    ch.name, opr.revolutions
                ));
            }
        }
        Ok([("signal".to_string(), Value::TimeSeries(out)), ("runout".to_string(), Value::Table(Table { columns }))]
            .into_iter()
            .collect())
    }
}
