//! The `beam.receptance` node kind: tip receptances of a free–free assembly.

use super::{assembly, block, check_mesh, grid, grid_port, h_of, mesh, outputs, sensor_mass, to_set};
use crate::beam::{self, BeamModel};
use crate::rcsa::{Receptance, ReceptanceFrf};
use spindlelab_domain::Speed;
use spindlelab_engine::model::Joint;

use super::{ASSEMBLY, LINES, MAX_ELEMENT, MAX_FREQUENCY, RESOLUTION, SENSOR, SHEAR};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Column, PortType, Table, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `beam.receptance`.
    pub struct BeamReceptanceParams<'a> {
        assembly: req &'a str = ASSEMBLY,
        sensor: opt &'a str = SENSOR,
        spin: opt f64 = (
            T::Quantity(D::ROTATIONAL_SPEED),
            "spin the assembly at this speed: gyroscopic (Nelson) elements couple the two planes; `tip` is then the in-plane block",
        ),
        max_frequency: def f64 = MAX_FREQUENCY,
        resolution: opt f64 = RESOLUTION,
        lines: def usize = LINES,
        max_element: def f64 = MAX_ELEMENT,
        shear: def &'a str = SHEAR,
    }
}

/// `beam.receptance`: tip receptances of a free–free assembly (§5.4).
pub struct BeamReceptance {
    spec: NodeSpec,
}

impl Default for BeamReceptance {
    fn default() -> Self {
        Self::new()
    }
}

impl BeamReceptance {
    pub fn new() -> Self {
        BeamReceptance {
            spec: NodeSpec {
                kind: "beam.receptance",
                version: 2,
                description: "Free-free Timoshenko FE model of an assembly (§5.4, Table 5.1 sections) and its tip receptances H, L, N, P (Eq. 5.2) by modal expansion.",
                inputs: vec![grid_port()],
                outputs: vec![
                    PortSpec::new("tip", PortType::ReceptanceSet, "direct 2x2 receptances at the tip"),
                    PortSpec::new("frf", PortType::Frf, "the tip's H = y/F (m/N)"),
                    PortSpec::new(
                        "modes",
                        PortType::Table,
                        "free-free natural frequencies (rigid-body modes left out) up to the grid's highest line",
                    ),
                ],
                params: BeamReceptanceParams::fields(),
            },
        }
    }
}

impl Node for BeamReceptance {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        check_mesh(p)
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = BeamReceptanceParams::read(ctx.params)?;
        let freqs = grid(ctx, p.max_frequency, p.resolution, p.lines)?;
        let a = assembly(ctx, "assembly", p.assembly)?;
        let fe = |e: beam::BeamError| NodeError::param("assembly", e.to_string());
        let mut model =
            BeamModel::from_segments(&beam::segments_from_sections(&a.sections), &mesh(p.max_element, p.shear))
                .map_err(fe)?;
        let tip = model.n_nodes() - 1;
        let m = sensor_mass(ctx, p.sensor)?;
        if m > 0.0 {
            model.add_point_mass(tip, m, 0.0).map_err(|e| NodeError::param("sensor", e.to_string()))?;
        }
        if !matches!(a.tool_joint, Joint::Rigid) {
            ctx.warn("the assembly's `tool_joint` is not modelled here (one continuous beam); rcsa.couple models it");
        }
        let modes = model.modes().map_err(fe)?;
        let spin = p.spin.filter(|w| *w != 0.0);
        let lines: Vec<Receptance> = match spin {
            None => modes.receptance(tip, tip, &freqs).map_err(fe)?.iter().map(block).collect(),
            Some(w) => {
                let spinning = beam::spinning::SpinningModel::new(model.clone());
                let blocks = spinning.receptance(tip, tip, w, &freqs).map_err(fe)?;
                blocks.iter().map(|b| Receptance::new(b[0][0], b[0][1], b[1][0], b[1][1])).collect()
            }
        };
        let set = to_set(&ReceptanceFrf { freqs_hz: freqs.clone(), lines }, None, spin.map(Speed::from_rad_s));
        let top = freqs.last().copied().unwrap_or(0.0);
        let nat: Vec<f64> =
            modes.natural_frequencies().into_iter().skip(modes.rigid_modes()).take_while(|f| *f <= top).collect();
        let table = Table {
            columns: vec![
                Column::new("mode", "", (1..=nat.len()).map(|k| k as f64).collect()),
                Column::new("frequency", "Hz", nat),
            ],
        };
        let frf = h_of(&set);
        Ok(outputs(vec![("tip", Value::ReceptanceSet(set)), ("frf", Value::Frf(frf)), ("modes", Value::Table(table))]))
    }
}
