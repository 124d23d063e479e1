//! The `beam.campbell` node kind: whirl frequencies of a spinning free–free assembly.

use super::{assembly, check_mesh, mesh, outputs, sensor_mass};
use crate::beam::{self, BeamModel};
use spindlelab_domain::Speed;

use super::{ASSEMBLY, MAX_ELEMENT, SENSOR, SHEAR};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Column, PortType, Table, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `beam.campbell`.
    pub struct BeamCampbellParams<'a> {
        assembly: req &'a str = ASSEMBLY,
        sensor: opt &'a str = SENSOR,
        speeds: req &'a [f64] = (T::QuantityList(D::ROTATIONAL_SPEED), "spin speeds, e.g. `0..30000 step 5000 rpm`"),
        max_frequency: def f64 = (T::Quantity(D::FREQUENCY), "20 kHz", "highest whirl frequency listed"),
        max_element: def f64 = MAX_ELEMENT,
        shear: def &'a str = SHEAR,
    }
}

/// `beam.campbell`: forward and backward whirl frequencies of a spinning free–free assembly.
pub struct BeamCampbell {
    spec: NodeSpec,
}

impl Default for BeamCampbell {
    fn default() -> Self {
        Self::new()
    }
}

impl BeamCampbell {
    pub fn new() -> Self {
        BeamCampbell {
            spec: NodeSpec {
                kind: "beam.campbell",
                version: 1,
                description: "Campbell table of a spinning free-free Timoshenko assembly: forward and backward whirl frequencies per speed, with the gyroscopic matrices of Nelson's rotating elements.",
                inputs: vec![],
                outputs: vec![PortSpec::new(
                    "whirl",
                    PortType::Table,
                    "one row per speed and whirl: speed (rpm), frequency (Hz), whirl (+1 forward, −1 backward)",
                )],
                params: BeamCampbellParams::fields(),
            },
        }
    }
}

impl Node for BeamCampbell {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        check_mesh(p)
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = BeamCampbellParams::read(ctx.params)?;
        let a = assembly(ctx, "assembly", p.assembly)?;
        let fe = |e: beam::BeamError| NodeError::param("assembly", e.to_string());
        let mut model =
            BeamModel::from_segments(&beam::segments_from_sections(&a.sections), &mesh(p.max_element, p.shear))
                .map_err(fe)?;
        let m = sensor_mass(ctx, p.sensor)?;
        if m > 0.0 {
            let tip = model.n_nodes() - 1;
            model.add_point_mass(tip, m, 0.0).map_err(|e| NodeError::param("sensor", e.to_string()))?;
        }
        let speeds = p.speeds.to_vec();
        let top = p.max_frequency;
        let whirls = beam::spinning::SpinningModel::new(model).campbell(&speeds).map_err(fe)?;
        // One row per whirl: forward (+1) orbits turn with the spin, backward (−1) against it.
        let mut cols: [Vec<f64>; 3] = Default::default();
        for w in &whirls {
            let rows = w.forward.iter().map(|f| (*f, 1.0)).chain(w.backward.iter().map(|f| (*f, -1.0)));
            let mut rows: Vec<(f64, f64)> = rows.filter(|(f, _)| *f <= top).collect();
            rows.sort_by(|a, b| a.0.total_cmp(&b.0).then(b.1.total_cmp(&a.1)));
            for (f, sense) in rows {
                cols[0].push(Speed::from_rad_s(w.speed).rpm());
                cols[1].push(f);
                cols[2].push(sense);
            }
        }
        let [speed, frequency, sense] = cols;
        let table = Table {
            columns: vec![
                Column::new("speed", "rpm", speed),
                Column::new("frequency", "Hz", frequency),
                Column::new("whirl", "", sense),
            ],
        };
        Ok(outputs(vec![("whirl", Value::Table(table))]))
    }
}
