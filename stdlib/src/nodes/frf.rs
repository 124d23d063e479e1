//! `frf.estimate`: FRF and coherence from impact records (§3.1.2–3.1.5, Eqs. 3.1–3.3), measured
//! from the levels the channels show at rest ([`crate::frf::IMPACT_ONSET_FRACTION`]).

use crate::frf::{Averaging, DecayStart, FrfError, FrfEstimator, FrfOptions, ImpactRecord, Trigger, Windows};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Frf, PortType, UnitLabel, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `frf.estimate`.
    pub struct FrfEstimateParams<'a> {
        windows: def bool = (T::Bool, "true", "apply the §3.1.2 windows"),
        force_window: def f64 = (T::Quantity(D::TIME), "6.5 ms", "rectangular force window length"),
        response_decay: def f64 = (
            T::Quantity(D::TIME),
            "0.113 s",
            "time constant of the exponential response window",
        ),
        decay_from: def &'a str = (
            T::Choice(&["force-window-end", "frame-start"]),
            "force-window-end",
            "where the response window starts to decay (§3.1.2: at the force window's end)",
        ),
        trigger: def &'a str = (
            T::Choice(&["force-peak", "record-start", "level"]),
            "force-peak",
            "where each analysis frame starts: before the force peak, at the record start, or before the first sample above `trigger_level`",
        ),
        trigger_level: opt f64 = (
            T::Quantity(D::FORCE),
            "force that triggers the frame (with `trigger: level`)",
        ),
        pre_trigger: def f64 = (
            T::Quantity(D::TIME),
            "0.5 ms",
            "time kept before the force peak or the trigger sample",
        ),
        averaging: def &'a str = (
            T::Choice(&["h1", "h2", "time-synchronous"]),
            "h1",
            "H1 or H2 spectral averaging, or impact-synchronous time averaging (§3.1.3)",
        ),
        response: def &'a str = (
            T::Choice(&["displacement", "velocity"]),
            "displacement",
            "velocity responses become receptance by Eq. 3.3",
        ),
        max_frequency: opt f64 = (T::Quantity(D::FREQUENCY), "keep lines up to this frequency"),
    }
}

pub struct FrfEstimate {
    spec: NodeSpec,
}

impl Default for FrfEstimate {
    fn default() -> Self {
        Self::new()
    }
}

impl FrfEstimate {
    pub fn new() -> Self {
        FrfEstimate {
            spec: NodeSpec {
                kind: "frf.estimate",
                // 2: the levels at rest (a probe's standoff, an amplifier offset) are taken out
                // of each record before the windows, so they no longer read as a 0 Hz peak.
                version: 2,
                description: "H = X/F with a rectangular force window and an exponential response window (§3.1.2), averaged over records, with coherence (Eqs. 3.1–3.2); each record's force and response are measured from their levels at rest (before the impact, and the response's second half), so a probe's standoff is no 0 Hz response.",
                inputs: vec![
                    PortSpec::new("force", PortType::TimeSeries, "force records (N), one channel per impact"),
                    PortSpec::new(
                        "response",
                        PortType::TimeSeries,
                        "response records, one channel per impact (m, or m/s with `response: velocity`)",
                    ),
                ],
                outputs: vec![PortSpec::new("frf", PortType::Frf, "receptance (m/N) with coherence")],
                params: FrfEstimateParams::fields(),
            },
        }
    }
}

fn options(p: &FrfEstimateParams) -> FrfOptions {
    let windows = if p.windows {
        Windows {
            force_window: p.force_window,
            response_decay: p.response_decay,
            decay_from: match p.decay_from {
                "frame-start" => DecayStart::FrameStart,
                _ => DecayStart::ForceWindowEnd,
            },
        }
    } else {
        Windows::NONE
    };
    let pre_trigger = p.pre_trigger;
    let trigger = match p.trigger {
        "record-start" => Trigger::RecordStart,
        "level" => Trigger::level(p.trigger_level.unwrap_or(f64::NAN), pre_trigger),
        _ => Trigger::ForcePeak { pre_trigger },
    };
    let averaging = match p.averaging {
        "time-synchronous" => Averaging::TimeSynchronous,
        "h2" => Averaging::H2,
        _ => Averaging::H1,
    };
    FrfOptions { windows, trigger, averaging, time_averaged: false }
}

fn err(e: FrfError) -> NodeError {
    match e {
        FrfError::InvalidParameter { field, .. } => NodeError::param(field, e.to_string()),
        FrfError::NonFinite { .. }
        | FrfError::TooShort { .. }
        | FrfError::ChannelLengthMismatch { .. }
        | FrfError::RecordLengthMismatch { .. } => NodeError::input("response", e.to_string()),
        FrfError::NoRecords | FrfError::NoTrigger { .. } => NodeError::input("force", e.to_string()),
        other => NodeError::Failed(other.to_string()),
    }
}

impl Node for FrfEstimate {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        super::positive(p, &["force_window", "response_decay", "max_frequency"])?;
        super::non_negative(p, &["pre_trigger"])?;
        let p = FrfEstimateParams::read(p)?;
        match (p.trigger, p.trigger_level) {
            ("level", None) => {
                Err(NodeError::param("trigger_level", "`trigger: level` needs a `trigger_level` (a force, e.g. 20 N)"))
            }
            ("level", Some(_)) | (_, None) => Ok(()),
            (_, Some(_)) => Err(NodeError::param(
                "trigger_level",
                "a trigger level is used only with `trigger: level`; set that or drop the level",
            )),
        }
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let (Value::TimeSeries(force), Value::TimeSeries(response)) = (ctx.input("force")?, ctx.input("response")?)
        else {
            return Err(NodeError::input("force", "expected time series"));
        };
        if force.channels.is_empty() || force.is_empty() {
            return Err(NodeError::input("force", "the force record is empty"));
        }
        if (force.sample_rate - response.sample_rate).abs() > 1e-9 * force.sample_rate {
            return Err(NodeError::input(
                "response",
                format!("sample rate {} Hz differs from the force's {} Hz", response.sample_rate, force.sample_rate),
            ));
        }
        if force.channels.len() != response.channels.len() {
            return Err(NodeError::input(
                "response",
                format!(
                    "{} force channel(s) but {} response channel(s): one of each per impact",
                    force.channels.len(),
                    response.channels.len()
                ),
            ));
        }
        let records: Vec<ImpactRecord> = force
            .channels
            .iter()
            .zip(&response.channels)
            .map(|(f, r)| ImpactRecord { force: &f.samples, response: &r.samples })
            .collect();
        let p = FrfEstimateParams::read(ctx.params)?;
        let mut est = FrfEstimator::new(force.len(), force.sample_rate).map_err(err)?;
        // One thread inside the node: the executor runs nodes in parallel, and a fixed
        // summation order keeps the numbers identical whatever the machine.
        est.set_threads(1);
        let mut e = est.estimate(&records, &options(&p)).map_err(err)?;
        if p.response == "velocity" {
            e = e.to_receptance().map_err(err)?;
        }
        let keep = match p.max_frequency {
            Some(fmax) => e.freq.iter().take_while(|f| **f <= fmax).count(),
            None => e.freq.len(),
        };
        let unit = if force.channels[0].unit.symbol == "N" { "m/N" } else { "" };
        let frf = Frf {
            freq_hz: e.freq[..keep].to_vec(),
            values: e.h[..keep].to_vec(),
            coherence: Some(e.coherence[..keep].to_vec()),
            unit: UnitLabel::new(unit),
            direction: None,
            speed: None,
            sensor: None,
            dofs: None,
        };
        Ok([("frf".to_string(), Value::Frf(frf))].into_iter().collect())
    }
}
