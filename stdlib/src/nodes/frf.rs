//! `frf.estimate`: FRF and coherence from impact records (§3.1.2–3.1.5, Eqs. 3.1–3.3), measured
//! from the levels the channels show at rest ([`crate::frf::IMPACT_ONSET_FRACTION`]).

use crate::frf::{Averaging, DecayStart, FrfError, FrfEstimator, FrfOptions, ImpactRecord, Trigger, Windows};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::spec::{Field, FieldType as T, Params};
use spindlelab_engine::value::{Frf, PortType, UnitLabel, Value};
use spindlelab_grammar::Dimension as D;

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
                params: vec![
                    Field::def("windows", T::Bool, "true", "apply the §3.1.2 windows"),
                    Field::def("force_window", T::Quantity(D::TIME), "6.5 ms", "rectangular force window length"),
                    Field::def(
                        "response_decay",
                        T::Quantity(D::TIME),
                        "0.113 s",
                        "time constant of the exponential response window",
                    ),
                    Field::def(
                        "decay_from",
                        T::Choice(&["force-window-end", "frame-start"]),
                        "force-window-end",
                        "where the response window starts to decay (§3.1.2: at the force window's end)",
                    ),
                    Field::def(
                        "trigger",
                        T::Choice(&["force-peak", "record-start", "level"]),
                        "force-peak",
                        "where each analysis frame starts: before the force peak, at the record start, or before the first sample above `trigger_level`",
                    ),
                    Field::opt(
                        "trigger_level",
                        T::Quantity(D::FORCE),
                        "force that triggers the frame (with `trigger: level`)",
                    ),
                    Field::def(
                        "pre_trigger",
                        T::Quantity(D::TIME),
                        "0.5 ms",
                        "time kept before the force peak or the trigger sample",
                    ),
                    Field::def(
                        "averaging",
                        T::Choice(&["h1", "h2", "time-synchronous"]),
                        "h1",
                        "H1 or H2 spectral averaging, or impact-synchronous time averaging (§3.1.3)",
                    ),
                    Field::def(
                        "response",
                        T::Choice(&["displacement", "velocity"]),
                        "displacement",
                        "velocity responses become receptance by Eq. 3.3",
                    ),
                    Field::opt("max_frequency", T::Quantity(D::FREQUENCY), "keep lines up to this frequency"),
                ],
            },
        }
    }
}

fn options(p: &Params) -> FrfOptions {
    let windows = if p.bool("windows").unwrap_or(true) {
        Windows {
            force_window: p.f64("force_window").unwrap_or(6.5e-3),
            response_decay: p.f64("response_decay").unwrap_or(0.113),
            decay_from: match p.text("decay_from") {
                Some("frame-start") => DecayStart::FrameStart,
                _ => DecayStart::ForceWindowEnd,
            },
        }
    } else {
        Windows::NONE
    };
    let pre_trigger = p.f64("pre_trigger").unwrap_or(0.5e-3);
    let trigger = match p.text("trigger") {
        Some("record-start") => Trigger::RecordStart,
        Some("level") => Trigger::level(p.f64("trigger_level").unwrap_or(f64::NAN), pre_trigger),
        _ => Trigger::ForcePeak { pre_trigger },
    };
    let averaging = match p.text("averaging") {
        Some("time-synchronous") => Averaging::TimeSynchronous,
        Some("h2") => Averaging::H2,
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
        match (p.text("trigger"), p.f64("trigger_level")) {
            (Some("level"), None) => {
                Err(NodeError::param("trigger_level", "`trigger: level` needs a `trigger_level` (a force, e.g. 20 N)"))
            }
            (Some("level"), Some(_)) | (_, None) => Ok(()),
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
        let mut est = FrfEstimator::new(force.len(), force.sample_rate).map_err(err)?;
        // One thread inside the node: the executor runs nodes in parallel, and a fixed
        // summation order keeps the numbers identical whatever the machine.
        est.set_threads(1);
        let mut e = est.estimate(&records, &options(ctx.params)).map_err(err)?;
        if ctx.params.text("response") == Some("velocity") {
            e = e.to_receptance().map_err(err)?;
        }
        let keep = match ctx.params.f64("max_frequency") {
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
            speed_rpm: None,
            sensor: None,
            dofs: None,
        };
        Ok([("frf".to_string(), Value::Frf(frf))].into_iter().collect())
    }
}
