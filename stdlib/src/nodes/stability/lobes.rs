//! `stability.lobes`: the ZOA stability limit on tool-point FRFs.

use super::{lobes_value, milling_named, outputs, receptance, speeds_rpm, stab_err, warn_lobes_short, warn_unlimited};
use crate::stability::{self, ToolPointFrf, ZoaOptions};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, FieldType as T, Params};
use spindlelab_engine::value::{Column, PortType, Table, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `stability.lobes`.
    pub struct LobesParams<'a> {
        cutting: req &'a str = (
            T::Entity(EntityKind::Cutting),
            "the cut: teeth, radial immersion, up/down, Kt/Kn or Ks/β",
        ),
        speeds: req &'a [f64] = (T::QuantityList(D::ROTATIONAL_SPEED), "spindle speeds, ascending"),
        lobes: opt usize = (
            T::Integer { min: 1, max: stability::MAX_LOBES as i64 },
            "number of lobes k = 0 … lobes − 1; by default as many as reach the FRF band's highest significant \
             response (within 40 dB of its peak) down to the slowest speed: ⌈60 f_max/(N n_min)⌉ + 1",
        ),
        resolution: def f64 = (
            T::Quantity(D::FREQUENCY),
            "1 Hz",
            "coarsest line spacing the lobes are resolved at: FRFs on a coarser grid are interpolated (cubic Hermite of the complex receptance) so a lobe's minimum is not cut off between two lines",
        ),
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
