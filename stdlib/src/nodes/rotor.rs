//! `rotor.campbell`: whirl frequencies of a spindle modelled as a rotor (Timoshenko shaft sections with
//! gyroscopics, disks, bearings) over spin speed, from [`crate::rotor`].

use crate::rotor::{Bearing, Disk, Rotor, ShaftSection, Whirl};
use spindlelab_domain::Speed;
use spindlelab_domain::entity::Material;
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, Field, FieldType as T, Params};
use spindlelab_engine::value::{Column, PortType, Table, Value};
use spindlelab_grammar::Dimension as D;

const SECTION: &[Field] = &[
    Field::req("length", T::Quantity(D::LENGTH), "length of the section"),
    Field::req("outer_diameter", T::Quantity(D::LENGTH), "outer diameter"),
    Field::def("inner_diameter", T::Quantity(D::LENGTH), "0 mm", "bore (0: solid)"),
    Field::def(
        "elements",
        T::Integer { min: 1, max: 1000 },
        "1",
        "equal Timoshenko elements the section is split into",
    ),
    Field::req("material", T::Entity(EntityKind::Material), "material: E, rho and nu (G = E/2(1 + nu))"),
];

const DISK: &[Field] = &[
    Field::req("node", T::Integer { min: 0, max: 100_000 }, "node it sits on (0 at the first section's start)"),
    Field::req("width", T::Quantity(D::LENGTH), "axial width"),
    Field::def("inner_diameter", T::Quantity(D::LENGTH), "0 mm", "bore"),
    Field::req("outer_diameter", T::Quantity(D::LENGTH), "outer diameter"),
    Field::req("material", T::Entity(EntityKind::Material), "material (its density)"),
];

const BEARING: &[Field] = &[
    Field::req("node", T::Integer { min: 0, max: 100_000 }, "node it supports"),
    Field::req("kxx", T::Quantity(D::STIFFNESS), "radial stiffness along x"),
    Field::req("kyy", T::Quantity(D::STIFFNESS), "radial stiffness along y"),
    Field::def("cxx", T::Quantity(D::DAMPING), "0 N*s/m", "damping along x"),
    Field::def("cyy", T::Quantity(D::DAMPING), "0 N*s/m", "damping along y"),
];

node_params! {
    /// Parameters of `rotor.campbell`.
    pub struct RotorCampbellParams<'a> {
        sections: req &'a [Params] = (
            T::ObjectList(SECTION),
            "shaft sections from the first node on, rows {length, outer_diameter, inner_diameter, elements, material}",
        ),
        disks: opt &'a [Params] = (
            T::ObjectList(DISK),
            "rigid disks (rotor, pulley, drawbar, holder mass), rows {node, width, outer_diameter, inner_diameter, material}",
        ),
        bearings: req &'a [Params] = (
            T::ObjectList(BEARING),
            "bearings as grounded springs and dampers, rows {node, kxx, kyy, cxx, cyy}",
        ),
        speeds: req &'a [f64] = (T::QuantityList(D::ROTATIONAL_SPEED), "spin speeds, e.g. `0..30000 step 1000 rpm`"),
        modes: def usize = (T::Integer { min: 1, max: 200 }, "6", "lowest modes listed per speed"),
    }
}

/// `rotor.campbell`: the Campbell table of a rotor model of a spindle.
pub struct RotorCampbell {
    spec: NodeSpec,
}

impl Default for RotorCampbell {
    fn default() -> Self {
        Self::new()
    }
}

impl RotorCampbell {
    pub fn new() -> Self {
        RotorCampbell {
            spec: NodeSpec {
                kind: "rotor.campbell",
                version: 1,
                description: "Campbell table of a spindle as a rotor (Friswell et al., Dynamics of Rotating Machines, ch. 5): Timoshenko shaft sections with gyroscopic matrices, rigid disks and bearings; forward and backward whirl frequencies and damping per spin speed.",
                inputs: vec![],
                outputs: vec![PortSpec::new(
                    "whirl",
                    PortType::Table,
                    "one row per speed and mode: speed (rpm), frequency (Hz, damped), whirl (+1 forward, −1 backward, 0 mixed or a straight orbit), damping_ratio",
                )],
                params: RotorCampbellParams::fields(),
            },
        }
    }
}

fn material(ctx: &NodeContext, param: &str, row: &Params, index: usize) -> Result<Material, NodeError> {
    let name = row.text("material").unwrap_or("");
    ctx.entities.materials.get(name).copied().ok_or_else(|| {
        NodeError::param(
            param,
            format!("row {index}: no material `{name}` in the recipe; declare it under `materials`"),
        )
    })
}

fn rotor(ctx: &NodeContext, p: &RotorCampbellParams) -> Result<Rotor, NodeError> {
    let num = |r: &Params, n: &str| r.f64(n).unwrap_or(f64::NAN);
    let node = |r: &Params| r.int("node").unwrap_or(-1).max(0) as usize;
    let mut sections = Vec::new();
    for (i, r) in p.sections.iter().enumerate() {
        let m = material(ctx, "sections", r, i)?;
        if !(m.poisson.is_finite() && m.poisson > -1.0 && m.poisson < 0.5) {
            return Err(NodeError::param(
                "sections",
                format!("row {i}: the material needs Poisson's ratio `nu` for the Timoshenko shear modulus"),
            ));
        }
        sections.push(ShaftSection {
            length_m: num(r, "length"),
            inner_diameter_m: num(r, "inner_diameter"),
            outer_diameter_m: num(r, "outer_diameter"),
            elements: r.int("elements").unwrap_or(1).max(1) as usize,
            material: m,
        });
    }
    let mut disks = Vec::new();
    for (i, r) in p.disks.unwrap_or_default().iter().enumerate() {
        let m = material(ctx, "disks", r, i)?;
        disks.push(Disk::from_geometry(
            node(r),
            m.density,
            num(r, "width"),
            num(r, "inner_diameter"),
            num(r, "outer_diameter"),
        ));
    }
    let bearings = p
        .bearings
        .iter()
        .map(|r| Bearing::new(node(r), num(r, "kxx"), num(r, "kyy"), num(r, "cxx"), num(r, "cyy")))
        .collect();
    let rotor = Rotor { sections, disks, bearings };
    rotor.validate().map_err(|e| NodeError::param("sections", e.to_string()))?;
    Ok(rotor)
}

impl Node for RotorCampbell {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = RotorCampbellParams::read(ctx.params)?;
        let rotor = rotor(ctx, &p)?;
        let rows = rotor.campbell(p.speeds, p.modes).map_err(|e| NodeError::Failed(e.to_string()))?;
        let mut cols: [Vec<f64>; 4] = Default::default();
        for row in &rows {
            for m in &row.modes {
                cols[0].push(Speed::from_rad_s(row.speed_rad_s).rpm_as_written());
                cols[1].push(m.freq_hz());
                cols[2].push(match m.whirl {
                    Whirl::Forward => 1.0,
                    Whirl::Backward => -1.0,
                    Whirl::Mixed => 0.0,
                });
                // An undamped rotor's ratios are the eigen-solver's rounding (±1e-9): zero.
                cols[3].push(if m.damping_ratio.abs() < 1e-6 { 0.0 } else { m.damping_ratio });
            }
        }
        let [speed, frequency, whirl, zeta] = cols;
        let table = Table {
            columns: vec![
                Column::new("speed", "rpm", speed),
                Column::new("frequency", "Hz", frequency),
                Column::new("whirl", "", whirl),
                Column::new("damping_ratio", "", zeta),
            ],
        };
        Ok([("whirl".to_string(), Value::Table(table))].into_iter().collect())
    }
}
