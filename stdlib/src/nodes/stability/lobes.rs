//! `stability.lobes`: the ZOA stability limit on tool-point FRFs.

use super::{CUTTING, LOBES, RESOLUTION, SPEEDS};
use super::{lobes_value, milling_named, outputs, receptance, speeds_rpm, stab_err, warn_lobes_short, warn_unlimited};
use crate::stability::{self, ToolPointFrf, ZoaOptions};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::Params;
use spindlelab_engine::value::{Column, PortType, Table, Value};

node_params! {
    /// Parameters of `stability.lobes`.
    pub struct LobesParams<'a> {
        cutting: req &'a str = CUTTING,
        speeds: req &'a [f64] = SPEEDS,
        lobes: opt usize = LOBES,
        resolution: def f64 = RESOLUTION,
    }
}

/// `stability.lobes`: the ZOA stability limit (Altintas & Budak 1995) from tool-point FRFs in x and y.
pub struct StabilityLobes {
    spec: NodeSpec,
}

impl Default for StabilityLobes {
    fn default() -> Self {
        Self::new()
    }
}

impl StabilityLobes {
    pub fn new() -> Self {
        StabilityLobes {
            spec: NodeSpec {
                kind: "stability.lobes",
                version: 1,
                description: "Stability lobes by the zero-order approximation (Altintas & Budak 1995) from tool-point FRFs in x (feed) and y: limiting depth and chatter frequency over speed.",
                inputs: vec![
                    PortSpec::new("frf_x", PortType::Frf, "tool-point receptance along x, the feed direction (m/N)"),
                    PortSpec::new("frf_y", PortType::Frf, "tool-point receptance along y, on the grid of frf_x (m/N)"),
                ],
                outputs: vec![
                    PortSpec::new("lobes", PortType::Lobes, "lowest lobe through each speed: depth (m), chatter (Hz)"),
                    PortSpec::new(
                        "table",
                        PortType::Table,
                        "speed (rpm), depth_limit (m), chatter_frequency (Hz), lobe k (−1 where none limits)",
                    ),
                ],
                params: LobesParams::fields(),
            },
        }
    }
}

impl Node for StabilityLobes {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = LobesParams::read(params)?;
        super::positive(params, &["resolution"])?;
        speeds_rpm(p.speeds).map(|_| ())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = LobesParams::read(ctx.params)?;
        let (fx, fy) = (receptance(ctx, "frf_x")?, receptance(ctx, "frf_y")?);
        let mill = milling_named(ctx, p.cutting)?;
        let frf = ToolPointFrf::from_pair(&fx.freq_hz, fx.values.clone(), &fy.freq_hz, fy.values.clone())
            .map_err(|e| stab_err(e, "frf_y"))?;
        let opts = ZoaOptions {
            lobes: p.lobes,
            speeds_rpm: speeds_rpm(p.speeds)?,
            keep_lobes: false,
            resolution_hz: Some(p.resolution),
        };
        let z = stability::zoa_lobes(&frf, &mill, &opts).map_err(|e| stab_err(e, "frf_x"))?;
        warn_lobes_short(ctx, z.lobe_count, z.lobes_needed, z.band_top_hz, mill.teeth, opts.speeds_rpm[0]);
        warn_unlimited(ctx, "lobes", &z.limit);
        let l = &z.limit;
        let table = Table {
            columns: vec![
                Column::new("speed", "rpm", l.speed_rpm.clone()),
                Column::new("depth_limit", "m", l.depth_m.clone()),
                Column::new("chatter_frequency", "Hz", l.chatter_hz.clone()),
                Column::new("lobe", "", l.lobe.iter().map(|k| k.map_or(-1.0, |k| k as f64)).collect()),
            ],
        };
        Ok(outputs(vec![("lobes", Value::Lobes(lobes_value(l))), ("table", Value::Table(table))]))
    }
}
