//! `stability.sd`: the limiting depth per speed by semi-discretization of modal models.

use super::{CUTTING, SPEEDS};
use super::{milling_named, modal, outputs, speeds_rpm, stab_err};
use crate::stability::{self, Bifurcation, SdOptions, StepCount};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Column, Lobes, PortType, Table, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `stability.sd`.
    pub struct SdParams<'a> {
        cutting: req &'a str = CUTTING,
        speeds: req &'a [f64] = SPEEDS,
        max_depth: req f64 = (T::Quantity(D::LENGTH), "largest axial depth scanned"),
        steps: opt usize = (
            T::Integer { min: 2, max: 2000 },
            "time steps per tooth period (default: per speed, at least 50 per shortest natural period, \
             40 to 1000)",
        ),
        scan_points: def usize = (
            T::Integer { min: 2, max: 1000 },
            "40",
            "depths scanned from max_depth/scan_points to max_depth before bisection",
        ),
        tolerance: def f64 = (T::Quantity(D::LENGTH), "0.1 um", "bisection stops below this bracket"),
        map_depths: def usize = (
            T::Integer { min: 0, max: 1000 },
            "0",
            "depths of the map, evenly from max_depth/map_depths to max_depth (0: no map rows)",
        ),
    }
}

/// `stability.sd`: the limiting depth per speed by first-order semi-discretization (Insperger & Stépán 2002,
/// 2004) of the tool-point modal models.
pub struct StabilitySd {
    spec: NodeSpec,
}

impl Default for StabilitySd {
    fn default() -> Self {
        Self::new()
    }
}

impl StabilitySd {
    pub fn new() -> Self {
        StabilitySd {
            spec: NodeSpec {
                kind: "stability.sd",
                // 3: the chatter frequency is the physical one (the harmonic of the Floquet solution with the
                // largest amplitude), no longer |arg μ|/2π × the tooth frequency folded into [0, f_tooth/2].
                // 4: the table's `kind` is a word (none, Hopf, flip, fold), not a code.
                version: 4,
                description: "Limiting depth per speed by first-order semi-discretization (Insperger & Stépán) of tool-point modal models in x (feed) and y, with the kind of chatter (Hopf or flip); spectral radii on a speed × depth grid.",
                inputs: vec![
                    PortSpec::new("modes_x", PortType::ModalModel, "tool-point modes along x, the feed direction"),
                    PortSpec::new("modes_y", PortType::ModalModel, "tool-point modes along y"),
                ],
                outputs: vec![
                    PortSpec::new(
                        "lobes",
                        PortType::Lobes,
                        "lowest unstable depth per speed (m; +∞ if stable up to max_depth) and the chatter frequency \
                         (Hz): of the frequencies ±arg μ/(2πτ) + k/τ the dominant multiplier μ allows, the one the \
                         tool vibrates at most, as a time-domain simulation and the ZOA find it",
                    ),
                    PortSpec::new(
                        "table",
                        PortType::Table,
                        "speed (rpm), depth_limit (m), chatter_frequency (Hz), kind (the bifurcation at the limit, as a word: none, Hopf, flip or fold), \
                         restabilises (1 if a larger scanned depth is stable again), steps (per tooth period used)",
                    ),
                    PortSpec::new(
                        "map",
                        PortType::Table,
                        "speed (rpm), depth (m), spectral_radius (stable below 1) on speeds × map_depths",
                    ),
                ],
                params: SdParams::fields(),
            },
        }
    }
}

impl Node for StabilitySd {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = SdParams::read(params)?;
        super::positive(params, &["max_depth", "tolerance"])?;
        speeds_rpm(p.speeds).map(|_| ())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = SdParams::read(ctx.params)?;
        let model = stability::ModalModel::new(modal(ctx, "modes_x")?, modal(ctx, "modes_y")?)
            .map_err(|e| stab_err(e, "modes_x"))?;
        if model.x.is_empty() && model.y.is_empty() {
            return Err(NodeError::input("modes_x", "neither modes_x nor modes_y holds a mode: nothing can chatter"));
        }
        let mill = milling_named(ctx, p.cutting)?;
        let speeds = speeds_rpm(p.speeds)?;
        let max_depth = p.max_depth;
        let opts = SdOptions {
            steps: p.steps.map_or(StepCount::AUTO, StepCount::Fixed),
            scan_points: p.scan_points,
            depth_tolerance_m: p.tolerance,
        };
        let limits =
            stability::sd_depth_limits(&model, &mill, &speeds, max_depth, &opts).map_err(|e| stab_err(e, "modes_x"))?;
        let chatter: Vec<f64> = limits.iter().map(|d| if d.kind.is_some() { d.chatter_hz } else { 0.0 }).collect();
        let unlimited = limits.iter().filter(|d| d.depth_m.is_infinite()).count();
        if unlimited > 0 {
            ctx.warn(format!(
                "{unlimited} of {} speeds are stable up to max_depth {max_depth} m; their limit is +∞",
                limits.len()
            ));
        }
        let kind = |d: &stability::DepthLimit| match d.kind {
            None => "none",
            Some(Bifurcation::Hopf) => "Hopf",
            Some(Bifurcation::Flip) => "flip",
            Some(Bifurcation::Fold) => "fold",
        };
        let kinds: Vec<&str> = limits.iter().map(kind).collect();
        let depth: Vec<f64> = limits.iter().map(|d| d.depth_m).collect();
        let table = Table {
            columns: vec![
                Column::new("speed", "rpm", speeds.clone()),
                Column::new("depth_limit", "m", depth.clone()),
                Column::new("chatter_frequency", "Hz", chatter.clone()),
                Column::text("kind", &kinds),
                Column::new("restabilises", "", limits.iter().map(|d| f64::from(u8::from(d.restabilises))).collect()),
                Column::new("steps", "", limits.iter().map(|d| d.steps as f64).collect()),
            ],
        };
        let n = p.map_depths;
        let depths: Vec<f64> = (1..=n).map(|i| max_depth * i as f64 / n as f64).collect();
        let (mut ms, mut md, mut mr) = (Vec::new(), Vec::new(), Vec::new());
        if n > 0 {
            let map = stability::sd_stability_map(&model, &mill, &speeds, &depths, &opts)
                .map_err(|e| stab_err(e, "modes_x"))?;
            for (i, s) in map.speeds_rpm.iter().enumerate() {
                for (j, b) in map.depths_m.iter().enumerate() {
                    ms.push(*s);
                    md.push(*b);
                    mr.push(map.radius(i, j));
                }
            }
        }
        let map = Table {
            columns: vec![
                Column::new("speed", "rpm", ms),
                Column::new("depth", "m", md),
                Column::new("spectral_radius", "", mr),
            ],
        };
        let lobes = Lobes { speed_rpm: speeds, depth_limit: depth, chatter_hz: chatter };
        Ok(outputs(vec![("lobes", Value::Lobes(lobes)), ("table", Value::Table(table)), ("map", Value::Table(map))]))
    }
}
