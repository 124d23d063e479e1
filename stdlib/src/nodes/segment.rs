//! `impact.segment`: one record per accepted impact from a continuous recording (§3.1.3),
//! rejecting double hits and clipped force pulses with a warning that names each.

use crate::segment::{self, DetectOptions, SegmentError};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Channel, Column, PortType, Table, TimeSeries, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `impact.segment`.
    pub struct ImpactSegmentParams<'a> {
        force_channel: def &'a str = (T::Text, "force", "channel holding the force"),
        response_channel: def &'a str = (T::Text, "a", "channel holding the response"),
        record_length: def usize = (T::Integer { min: 64, max: 1 << 24 }, "65536", "samples per record"),
        pre_trigger: def f64 = (T::Quantity(D::TIME), "0.5 ms", "time kept before each force peak"),
        trigger_level: opt f64 = (
            T::Quantity(D::FORCE),
            "force that starts an impact (default 10 % of the largest)",
        ),
        double_hit_ratio: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "5 %",
            "a second pulse above this fraction of the peak is a double hit",
        ),
        double_hit_window: def f64 = (
            T::Quantity(D::TIME),
            "6.5 ms",
            "time after the peak in which a second pulse is a double hit",
        ),
        dead_time: def f64 = (T::Quantity(D::TIME), "50 ms", "shortest time between two impacts"),
        full_scale: opt f64 = (
            T::Quantity(D::FORCE),
            "range of the force channel; a pulse reaching it is clipped",
        ),
        min_records: def usize = (T::Integer { min: 1, max: 100_000 }, "1", "fewest accepted impacts"),
    }
}

pub struct ImpactSegment {
    spec: NodeSpec,
}

impl Default for ImpactSegment {
    fn default() -> Self {
        Self::new()
    }
}

impl ImpactSegment {
    pub fn new() -> Self {
        ImpactSegment {
            spec: NodeSpec {
                kind: "impact.segment",
                version: 1,
                description: "Finds the impacts in a continuous recording, rejects double hits and saturated force pulses, and cuts one record per accepted impact aligned on its force peak (§3.1.3).",
                inputs: vec![PortSpec::new(
                    "signal",
                    PortType::TimeSeries,
                    "continuous recording with force and response channels",
                )],
                outputs: vec![
                    PortSpec::new("force", PortType::TimeSeries, "force records (N), one channel per accepted impact"),
                    PortSpec::new(
                        "response",
                        PortType::TimeSeries,
                        "response records, one channel per accepted impact",
                    ),
                    PortSpec::new(
                        "impacts",
                        PortType::Table,
                        "every impact found: time, peak force, rejection code (0 used, 1 double hit, 2 saturated, 3 truncated)",
                    ),
                ],
                params: ImpactSegmentParams::fields(),
            },
        }
    }
}

fn options(p: &ImpactSegmentParams) -> DetectOptions {
    DetectOptions {
        trigger_level: p.trigger_level,
        double_hit_ratio: p.double_hit_ratio,
        double_hit_window: p.double_hit_window,
        dead_time: p.dead_time,
        full_scale: p.full_scale,
        ..DetectOptions::default()
    }
}

impl Node for ImpactSegment {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    /// Records are large and cut in milliseconds: not worth the cache's disk.
    fn cacheable(&self) -> bool {
        false
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        let r = ImpactSegmentParams::read(p)?.double_hit_ratio;
        if !(r > 0.0 && r < 1.0) {
            return Err(NodeError::param("double_hit_ratio", format!("must lie between 0 and 100 %, got {r}")));
        }
        super::positive(p, &["trigger_level", "full_scale", "double_hit_window", "dead_time"])?;
        super::non_negative(p, &["pre_trigger"])
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let Value::TimeSeries(signal) = ctx.input("signal")? else {
            return Err(NodeError::input("signal", "expected a time series"));
        };
        let p = ImpactSegmentParams::read(ctx.params)?;
        let channel = |param: &str, name: &str| -> Result<&Channel, NodeError> {
            signal.channel(name).ok_or_else(|| {
                let names: Vec<&str> = signal.channels.iter().map(|c| c.name.as_str()).collect();
                NodeError::param(param, format!("no channel `{name}` in the recording (it has: {})", names.join(", ")))
            })
        };
        let force = channel("force_channel", p.force_channel)?;
        let response = channel("response_channel", p.response_channel)?;
        let fs = signal.sample_rate;
        let len = p.record_length;
        let pre = (p.pre_trigger * fs).round() as usize;
        if pre >= len {
            return Err(NodeError::param(
                "pre_trigger",
                format!("{pre} samples is not shorter than the record ({len})"),
            ));
        }
        let impacts = segment::detect(&force.samples, fs, signal.t0, pre, len, &options(&p)).map_err(|e| match e {
            SegmentError::InvalidOption { field, .. } => NodeError::param(field, e.to_string()),
            other => NodeError::input("signal", format!("channel `{}`: {other}", force.name)),
        })?;
        if let Some(i) = response.samples.iter().position(|v| !v.is_finite()) {
            return Err(NodeError::input(
                "signal",
                format!("channel `{}`: sample {i} is not a finite number", response.name),
            ));
        }
        for (k, imp) in impacts.iter().enumerate() {
            if let Some(r) = imp.rejection {
                ctx.warn(format!("impact {} at {:.4} s rejected: {r}", k + 1, imp.time));
            }
        }
        let accepted = impacts.iter().filter(|i| i.rejection.is_none()).count();
        let min = p.min_records;
        if accepted < min {
            return Err(NodeError::input(
                "signal",
                format!(
                    "{accepted} of {} impacts usable, fewer than min_records = {min}; see the warnings for why each was rejected",
                    impacts.len()
                ),
            ));
        }
        let records = |ch: &Channel| TimeSeries {
            sample_rate: fs,
            t0: -(pre as f64) / fs,
            channels: segment::cut(&ch.samples, &impacts, pre, len)
                .into_iter()
                .enumerate()
                .map(|(k, samples)| Channel { name: format!("impact_{}", k + 1), unit: ch.unit.clone(), samples })
                .collect(),
        };
        let table = Table {
            columns: vec![
                Column::new("impact", "", (1..=impacts.len()).map(|k| k as f64).collect()),
                Column::new("time", "s", impacts.iter().map(|i| i.time).collect()),
                Column::new("peak_force", "N", impacts.iter().map(|i| i.peak).collect()),
                Column::new(
                    "rejection",
                    "",
                    impacts.iter().map(|i| i.rejection.map_or(0.0, |r| r.code() as f64)).collect(),
                ),
            ],
        };
        Ok([
            ("force".to_string(), Value::TimeSeries(records(force))),
            ("response".to_string(), Value::TimeSeries(records(response))),
            ("impacts".to_string(), Value::Table(table)),
        ]
        .into_iter()
        .collect())
    }
}
