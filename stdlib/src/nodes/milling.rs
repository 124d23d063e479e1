//! `milling.simulate`: the time-domain milling simulation ([`crate::milling`]) as a node.

use super::stability::{cutting_param, milling, modal};
use crate::milling::{MillingSimulation, simulate};
use crate::stability;
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::spec::{Field, FieldType as T};
use spindlelab_engine::value::{Channel, Column, PortType, Scalar, Table, TimeSeries, UnitLabel, Value};
use spindlelab_grammar::Dimension as D;
use std::f64::consts::TAU;

pub struct MillingSimulate {
    spec: NodeSpec,
}

impl Default for MillingSimulate {
    fn default() -> Self {
        Self::new()
    }
}

impl MillingSimulate {
    pub fn new() -> Self {
        MillingSimulate {
            spec: NodeSpec {
                kind: "milling.simulate",
                version: 1,
                description: "Time-domain milling simulation (Schmitz & Smith): regenerative chip thickness by the tooth path, \
                              straight teeth with the lobes' force model, tool-point modes in x (feed) and y advanced exactly \
                              per step, optional runout; stable or chatter by once-per-period sampling, the chatter \
                              frequency and the surface location error. Sweep speed and depth for a stability map.",
                inputs: vec![
                    PortSpec::new("modes_x", PortType::ModalModel, "tool-point modes along x, the feed direction"),
                    PortSpec::new("modes_y", PortType::ModalModel, "tool-point modes along y"),
                ],
                outputs: vec![
                    PortSpec::new(
                        "signals",
                        PortType::TimeSeries,
                        "force_x, force_y (N, on the tool) and x, y (m, tool displacement) at every step",
                    ),
                    PortSpec::new(
                        "samples",
                        PortType::TimeSeries,
                        "x and y once per tooth period (once per revolution with runout): still in a stable cut",
                    ),
                    PortSpec::new(
                        "summary",
                        PortType::Table,
                        "speed (rpm), depth (m), stable (1 or 0), chatter_metric (sample spread over motion spread, to 0.001), \
                         chatter_frequency (Hz, 0 when stable), surface_location_error (m), steps (per tooth period)",
                    ),
                    PortSpec::new(
                        "surface_location_error",
                        PortType::Scalar,
                        "y of the tool as a tooth passes the finished wall, steady state (m; + towards +y)",
                    ),
                ],
                params: vec![
                    cutting_param(),
                    Field::req("speed", T::Quantity(D::ROTATIONAL_SPEED), "spindle speed"),
                    Field::req("depth", T::Quantity(D::LENGTH), "axial depth of cut"),
                    Field::opt(
                        "feed_per_tooth",
                        T::Quantity(D::LENGTH),
                        "feed per tooth (default: the cutting setup's `feed_per_tooth`)",
                    ),
                    Field::def("revolutions", T::Integer { min: 2, max: 100_000 }, "100", "length of the simulation"),
                    Field::opt(
                        "steps_per_tooth",
                        T::Integer { min: 8, max: 100_000 },
                        "time steps per tooth period (default: at least 100 and 20 per period of the highest mode)",
                    ),
                    Field::opt(
                        "runout",
                        T::QuantityList(D::LENGTH),
                        "radial runout of each tooth, one value per tooth (e.g. `[10, 0, 0, 0] um`)",
                    ),
                ],
            },
        }
    }
}

impl Node for MillingSimulate {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = ctx.params;
        let modes = stability::ModalModel::new(modal(ctx, "modes_x")?, modal(ctx, "modes_y")?)
            .map_err(|e| NodeError::input("modes_x", e.to_string()))?;
        let speed_rpm = ctx.f64("speed")? * 60.0 / TAU;
        let sim = MillingSimulation {
            cut: milling(ctx)?,
            depth: ctx.f64("depth")?,
            feed_per_tooth: feed_per_tooth(ctx)?,
            speed_rpm,
            modes,
            runout: p
                .list("runout")
                .map(<[f64]>::to_vec)
                .or_else(|| p.f64("runout").map(|r| vec![r]))
                .unwrap_or_default(),
            revolutions: p.int("revolutions").unwrap_or(100) as usize,
            steps_per_tooth: p.int("steps_per_tooth").map(|s| s as usize),
        };
        let r = simulate(&sim).map_err(|e| match e {
            crate::milling::MillingError::Runout { .. } => NodeError::param("runout", e.to_string()),
            other => NodeError::Failed(other.to_string()),
        })?;
        let channel = |name: &str, unit: &str, samples: Vec<f64>| Channel {
            name: name.into(),
            unit: UnitLabel::new(unit),
            samples,
        };
        let signals = TimeSeries {
            sample_rate: 1.0 / r.dt,
            t0: 0.0,
            channels: vec![
                channel("force_x", "N", r.force_x),
                channel("force_y", "N", r.force_y),
                channel("x", "m", r.disp_x),
                channel("y", "m", r.disp_y),
            ],
        };
        let samples = TimeSeries {
            sample_rate: 1.0 / r.sample_period,
            t0: r.sample_period - r.dt,
            channels: vec![channel("x", "m", r.samples_x), channel("y", "m", r.samples_y)],
        };
        if !r.stable {
            ctx.warn(format!(
                "chatter at {speed_rpm:.0} rpm and {:.3} mm: once-per-period samples spread {:.2} of the motion",
                sim.depth * 1e3,
                r.chatter_metric
            ));
        }
        let summary = Table {
            columns: vec![
                Column::new("speed", "rpm", vec![speed_rpm]),
                Column::new("depth", "m", vec![sim.depth]),
                Column::new("stable", "", vec![if r.stable { 1.0 } else { 0.0 }]),
                // A ratio of order 1 in chatter: three decimals say all there is; below that a
                // stable cut shows only roundoff and leftover transient.
                Column::new("chatter_metric", "", vec![(r.chatter_metric * 1e3).round() / 1e3]),
                Column::new("chatter_frequency", "Hz", vec![r.chatter_frequency_hz.unwrap_or(0.0)]),
                Column::new("surface_location_error", "m", vec![r.surface_location_error]),
                Column::new("steps", "", vec![r.steps_per_tooth as f64]),
            ],
        };
        let mut out = Outputs::new();
        out.insert("signals".into(), Value::TimeSeries(signals));
        out.insert("samples".into(), Value::TimeSeries(samples));
        out.insert("summary".into(), Value::Table(summary));
        out.insert(
            "surface_location_error".into(),
            Value::Scalar(Scalar { value: r.surface_location_error, unit: UnitLabel::new("m") }),
        );
        Ok(out)
    }
}

/// The feed per tooth: the node's parameter, else the cutting setup's.
fn feed_per_tooth(ctx: &NodeContext) -> Result<f64, NodeError> {
    if let Some(f) = ctx.params.f64("feed_per_tooth") {
        return Ok(f);
    }
    let name = ctx.params.text("cutting").unwrap_or_default();
    ctx.recipe.cutting.get(name).and_then(|c| c.feed_per_tooth).ok_or_else(|| {
        NodeError::param(
            "feed_per_tooth",
            format!("give `feed_per_tooth`, here or in the cutting setup `{name}` (e.g. `feed_per_tooth: 0.05 mm`)"),
        )
    })
}
