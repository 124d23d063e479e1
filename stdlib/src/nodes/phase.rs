//! `phase.correct` (Eqs. 2.11–2.12) and `phase.measure` (Eq. 2.8, §2.3.1).

use crate::phase::{self, PhaseError, SensorKind};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, FieldType as T, Params};
use spindlelab_engine::value::{Column, PortType, Scalar, Table, Value};
use spindlelab_grammar::Dimension as D;

/// Degrees per kilohertz in rad/Hz, for messages.
const DEG_PER_KHZ: f64 = std::f64::consts::PI / 180.0 / 1000.0;

node_params! {
    /// Parameters of `phase.correct`.
    pub struct PhaseCorrectParams<'a> {
        slope: opt f64 = (T::Quantity(D::PHASE_SLOPE), "phase slope Δθ, e.g. -13.84 deg/kHz"),
        sensor: opt &'a str = (T::Entity(EntityKind::Sensor), "a sensor whose `phase_slope` to use"),
    }
}

pub struct PhaseCorrect {
    spec: NodeSpec,
}

impl Default for PhaseCorrect {
    fn default() -> Self {
        Self::new()
    }
}

impl PhaseCorrect {
    pub fn new() -> Self {
        PhaseCorrect {
            spec: NodeSpec {
                kind: "phase.correct",
                version: 1,
                description: "Removes a sensor chain's linear phase lag from an FRF, φ_cor = φ_meas − Δθ·f with the magnitude kept (Eqs. 2.11–2.12).",
                inputs: vec![
                    PortSpec::new("frf", PortType::Frf, "measured FRF"),
                    PortSpec::new("slope", PortType::Scalar, "measured phase slope (from phase.measure)").optional(),
                ],
                outputs: vec![PortSpec::new("frf", PortType::Frf, "corrected FRF")],
                params: PhaseCorrectParams::fields(),
            },
        }
    }
}

impl Node for PhaseCorrect {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        let p = PhaseCorrectParams::read(p)?;
        if p.slope.is_some() && p.sensor.is_some() {
            return Err(NodeError::param("slope", "give either `slope` or `sensor`, not both"));
        }
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let Value::Frf(frf) = ctx.input("frf")? else {
            return Err(NodeError::input("frf", "expected an FRF"));
        };
        let p = PhaseCorrectParams::read(ctx.params)?;
        let slope = if let Some(Value::Scalar(s)) = ctx.inputs_of("slope").first().map(|l| l.value.as_ref()) {
            if s.unit.symbol != "rad*s" && s.unit.symbol != "rad/Hz" {
                return Err(NodeError::input(
                    "slope",
                    format!("expected a phase slope in rad/Hz, got `{}`", s.unit.symbol),
                ));
            }
            s.value
        } else if let Some(v) = p.slope {
            v
        } else if let Some(name) = p.sensor {
            ctx.entities
                .sensors
                .get(name)
                .map(|s| s.phase_slope)
                .ok_or_else(|| NodeError::param("sensor", format!("no sensor `{name}` in the recipe")))?
        } else {
            return Err(NodeError::param(
                "slope",
                "no phase slope: connect `slope` to a phase.measure step, or set `slope` or `sensor`",
            ));
        };
        let mut out = frf.clone();
        phase::correct(&out.freq_hz, &mut out.values, slope).map_err(|e| NodeError::param("slope", e.to_string()))?;
        Ok([("frf".to_string(), Value::Frf(out))].into_iter().collect())
    }
}

node_params! {
    /// Parameters of `phase.measure`.
    pub struct PhaseMeasureParams<'a> {
        accel_channel: def &'a str = (T::Text, "accel", "accelerometer channel"),
        sensor_channel: def &'a str = (T::Text, "sensor", "channel of the sensor under test"),
        sensor: def &'a str = (
            T::Choice(&["displacement", "velocity"]),
            "displacement",
            "what the sensor measures",
        ),
        bandwidth: def f64 = (
            T::Quantity(D::FREQUENCY),
            "100 Hz",
            "width of the band-pass around the drive frequency",
        ),
        order: def usize = (T::Integer { min: 1, max: 8 }, "3", "Butterworth order of the band-pass"),
    }
}

pub struct PhaseMeasure {
    spec: NodeSpec,
}

impl Default for PhaseMeasure {
    fn default() -> Self {
        Self::new()
    }
}

impl PhaseMeasure {
    pub fn new() -> Self {
        PhaseMeasure {
            spec: NodeSpec {
                kind: "phase.measure",
                version: 1,
                description: "Phase lag of a sensor chain against an accelerometer on a shaker, per drive frequency (Eq. 2.8 after a band-pass around it), and its slope over frequency (§2.3.1).",
                inputs: vec![
                    PortSpec::new(
                        "records",
                        PortType::TimeSeries,
                        "shaker records with accelerometer and sensor channels, one per drive frequency",
                    )
                    .collecting(),
                ],
                outputs: vec![
                    PortSpec::new("slope", PortType::Scalar, "phase slope Δθ (rad/Hz) of a line through the origin"),
                    PortSpec::new(
                        "phase",
                        PortType::Table,
                        "drive frequency, measured phase lag, and the line's residual",
                    ),
                ],
                params: PhaseMeasureParams::fields(),
            },
        }
    }
}

impl Node for PhaseMeasure {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        if PhaseMeasureParams::read(p)?.bandwidth <= 0.0 {
            return Err(NodeError::param("bandwidth", "must be positive"));
        }
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = PhaseMeasureParams::read(ctx.params)?;
        let kind = match p.sensor {
            "velocity" => SensorKind::Velocity,
            _ => SensorKind::Displacement,
        };
        let (bandwidth, order) = (p.bandwidth, p.order);
        let (accel_name, sensor_name) = (p.accel_channel, p.sensor_channel);
        let mut points = Vec::new();
        for item in ctx.inputs_of("records") {
            let Value::TimeSeries(ts) = item.value.as_ref() else {
                return Err(NodeError::input("records", "expected time series"));
            };
            let what = if item.label.is_empty() { "record".to_string() } else { format!("record {}", item.label) };
            let get = |name: &str, param: &str| {
                ts.channel(name).ok_or_else(|| NodeError::param(param, format!("{what} has no channel `{name}`")))
            };
            let (a, x) = (get(accel_name, "accel_channel")?, get(sensor_name, "sensor_channel")?);
            let m = crate::phase::measure_record(&a.samples, &x.samples, ts.sample_rate, bandwidth, order, kind)
                .map_err(|e| NodeError::input("records", format!("{what}: {e}")))?;
            points.push(m);
        }
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (slope, rms) =
            phase::fit_slope(&points).map_err(|e: PhaseError| NodeError::input("records", e.to_string()))?;
        if rms > 2.0f64.to_radians() {
            ctx.warn(format!(
                "phase lag departs from a line through the origin by {:.2}° RMS (slope {:.3} deg/kHz): check for structural modes in the band",
                rms.to_degrees(),
                slope / DEG_PER_KHZ
            ));
        }
        let table = Table {
            columns: vec![
                Column::new("frequency", "Hz", points.iter().map(|p| p.0).collect()),
                Column::new("phase_lag", "rad", points.iter().map(|p| p.1).collect()),
                Column::new("residual", "rad", points.iter().map(|p| p.1 - slope * p.0).collect()),
            ],
        };
        Ok([
            ("slope".to_string(), Value::Scalar(Scalar::new(slope, "rad*s"))),
            ("phase".to_string(), Value::Table(table)),
        ]
        .into_iter()
        .collect())
    }
}
