//! The `rotor.*` node kinds, a spindle modelled as a rotor (Timoshenko shaft sections with
//! gyroscopics, disks, bearings; [`crate::rotor`]): `rotor.campbell`, its whirl frequencies over
//! spin speed, and `rotor.receptance`, its receptance at the spindle nose at one speed, which
//! `rcsa.couple` takes like a spindle receptance.

use super::structure::{LINES, MAX_FREQUENCY, RESOLUTION, grid, grid_port, h_of, outputs};
use crate::rcsa::{Receptance, ReceptanceFrf};
use crate::rotor::{Bearing, Disk, Rotor, ShaftSection, Whirl};
use spindlelab_domain::Speed;
use spindlelab_domain::entity::Material;
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, Field, FieldType as T, Params};
use spindlelab_engine::value::{Column, PortType, ReceptanceSet, Table, Value};
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
    Field::def(
        "speed_coefficient",
        T::Quantity(D::DIMENSIONLESS),
        "0",
        "relative change of the stiffness at ref_speed, k (1 + speed_coefficient (n/ref_speed)^2); negative for the centrifugal softening of ball bearings",
    ),
    Field::def("ref_speed", T::Quantity(D::ROTATIONAL_SPEED), "10000 rpm", "reference speed of speed_coefficient"),
];

/// The rotor, as both node kinds take it.
const SECTIONS: Field = Field::req(
    "sections",
    T::ObjectList(SECTION),
    "shaft sections from the rear end (node 0) to the nose (the last node), rows {length, outer_diameter, inner_diameter, elements, material}",
);
const DISKS: Field = Field::opt(
    "disks",
    T::ObjectList(DISK),
    "rigid disks (motor rotor, pulley, drawbar), rows {node, width, outer_diameter, inner_diameter, material}",
);
const BEARINGS: Field = Field::req(
    "bearings",
    T::ObjectList(BEARING),
    "bearings as grounded springs and dampers, rows {node, kxx, kyy, cxx, cyy, speed_coefficient, ref_speed}",
);

node_params! {
    /// Parameters of `rotor.campbell`.
    pub struct RotorCampbellParams<'a> {
        sections: req &'a [Params] = SECTIONS,
        disks: opt &'a [Params] = DISKS,
        bearings: req &'a [Params] = BEARINGS,
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
                    "one row per speed and mode: speed (rpm), frequency (Hz, damped), whirl (+1 forward, −1 backward, 0 at rest, mixed or a straight orbit), damping_ratio",
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

/// The rotor's shaft, disks and bearings as a recipe gives them.
struct RotorRows<'a> {
    sections: &'a [Params],
    disks: Option<&'a [Params]>,
    bearings: &'a [Params],
}

fn rotor(ctx: &NodeContext, p: &RotorRows) -> Result<Rotor, NodeError> {
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
        .map(|r| Bearing {
            speed_coefficient: num(r, "speed_coefficient"),
            ref_speed_rad_s: num(r, "ref_speed"),
            ..Bearing::new(node(r), num(r, "kxx"), num(r, "kyy"), num(r, "cxx"), num(r, "cyy"))
        })
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
        let rotor = rotor(ctx, &RotorRows { sections: p.sections, disks: p.disks, bearings: p.bearings })?;
        let rows = rotor.campbell(p.speeds, p.modes).map_err(|e| NodeError::Failed(e.to_string()))?;
        let mut cols: [Vec<f64>; 4] = Default::default();
        for row in &rows {
            for m in &row.modes {
                cols[0].push(Speed::from_rad_s(row.speed_rad_s).rpm_as_written());
                cols[1].push(m.freq_hz());
                // At rest there is no spin for an orbit to follow or oppose: an isotropic rotor's
                // pair is one frequency whose eigenvectors' orbits are arbitrary.
                cols[2].push(match m.whirl {
                    _ if row.speed_rad_s == 0.0 => 0.0,
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

node_params! {
    /// Parameters of `rotor.receptance`.
    pub struct RotorReceptanceParams<'a> {
        sections: req &'a [Params] = SECTIONS,
        disks: opt &'a [Params] = DISKS,
        bearings: req &'a [Params] = BEARINGS,
        node: opt usize = (
            T::Integer { min: 0, max: 100_000 },
            "node whose receptance to give (default: the last, the spindle nose)",
        ),
        direction: def &'a str = (T::Choice(&["x", "y"]), "x", "bending plane of the direct block"),
        speed: def f64 = (T::Quantity(D::ROTATIONAL_SPEED), "0 rpm", "spin speed"),
        max_frequency: def f64 = MAX_FREQUENCY,
        resolution: opt f64 = RESOLUTION,
        lines: def usize = LINES,
    }
}

/// `rotor.receptance`: the receptance of a rotor model of a spindle at its nose.
pub struct RotorReceptance {
    spec: NodeSpec,
}

impl Default for RotorReceptance {
    fn default() -> Self {
        Self::new()
    }
}

impl RotorReceptance {
    pub fn new() -> Self {
        RotorReceptance {
            spec: NodeSpec {
                kind: "rotor.receptance",
                version: 1,
                description: "Receptance at the nose of a spindle modelled as a rotor (Friswell et al., Dynamics of Rotating Machines, ch. 5-6) at one spin speed, by direct solution of (K + iw(C + WG) - w^2 M) X = F: the in-plane 2x2 block for rcsa.couple's `spindle` and the cross-plane block the spin adds, for its `spindle_cross`.",
                inputs: vec![grid_port()],
                outputs: vec![
                    PortSpec::new(
                        "receptance",
                        PortType::ReceptanceSet,
                        "2x2 in-plane receptances (displacement and slope per force and moment) at the node",
                    ),
                    PortSpec::new(
                        "cross",
                        PortType::ReceptanceSet,
                        "2x2 cross-plane block Q of the isotropic form [[P, Q], [-Q, P]]: x-plane response to y-plane load (zero at rest)",
                    ),
                    PortSpec::new("frf", PortType::Frf, "the in-plane H = displacement/force (m/N)"),
                ],
                params: RotorReceptanceParams::fields(),
            },
        }
    }
}

/// A bearing whose x and y coefficients differ, if any: the cross block then is not that of an
/// isotropic rotor.
fn anisotropic(rotor: &Rotor) -> Option<usize> {
    let differs = |a: f64, b: f64| (a - b).abs() > 1e-9 * a.abs().max(b.abs());
    rotor
        .bearings
        .iter()
        .find(|b| differs(b.kxx, b.kyy) || differs(b.cxx, b.cyy) || b.kxy != 0.0 || b.kyx != 0.0)
        .map(|b| b.node)
}

impl Node for RotorReceptance {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        super::positive(p, &["max_frequency", "resolution"])?;
        super::non_negative(p, &["speed"])
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = RotorReceptanceParams::read(ctx.params)?;
        let rotor = rotor(ctx, &RotorRows { sections: p.sections, disks: p.disks, bearings: p.bearings })?;
        let last = rotor.n_nodes() - 1;
        let node = p.node.unwrap_or(last);
        if node > last {
            return Err(NodeError::param(
                "node",
                format!("node {node} does not exist; the rotor has nodes 0..={last}"),
            ));
        }
        if let Some(b) = anisotropic(&rotor) {
            ctx.warn(format!(
                "the bearing at node {b} differs along x and y: the in-plane block is exact, the cross block is that of an isotropic rotor only"
            ));
        }
        let freqs = grid(ctx, p.max_frequency, p.resolution, p.lines)?;
        let speed = Speed::from_rad_s(p.speed);
        let blocks = rotor
            .assemble()
            .and_then(|m| m.point_receptance(node, &freqs, speed.rad_s()))
            .map_err(|e| NodeError::param("sections", e.to_string()))?;
        // x: rows/columns 0..2 of [x, β, y, −α]; y: 2..4. Q is the x-plane response to a y-plane
        // load, or minus the y-plane response to an x-plane load.
        let (d, other, sign) = if p.direction == "y" { (2, 0, -1.0) } else { (0, 2, 1.0) };
        let pick = |r: usize, c: usize, s: f64| ReceptanceFrf {
            freqs_hz: freqs.clone(),
            lines: blocks
                .iter()
                .map(|b| Receptance::new(s * b[r][c], s * b[r][c + 1], s * b[r + 1][c], s * b[r + 1][c + 1]))
                .collect(),
        };
        let set = |f: &ReceptanceFrf| -> ReceptanceSet {
            super::structure::to_set(f, Some(p.direction.to_string()), Some(speed))
        };
        let direct = set(&pick(d, d, 1.0));
        let cross = set(&pick(d, other, sign));
        let frf = h_of(&direct);
        Ok(outputs(vec![
            ("receptance", Value::ReceptanceSet(direct)),
            ("cross", Value::ReceptanceSet(cross)),
            ("frf", Value::Frf(frf)),
        ]))
    }
}
