//! The `rcsa.couple` node kind: tool-tip receptances of an assembly coupled to a spindle.

use super::{
    RCSA_COUPLE, assembly, assembly_parts, check_coupling, h_of, holder_interface, input_on_grid, mesh, outputs,
    rcsa_error, rcsa_options, sensor_mass, to_frf, to_set, two_port, two_port_of,
};
use crate::beam;
use crate::rcsa::{self, Interface, TwoPort};

use super::{GRID_MISMATCH, INTERFACE, MACHINE, MAX_CONDITION, MAX_ELEMENT, SHEAR};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, FieldType as T, Params};
use spindlelab_engine::value::{PortType, SubstructurePart, Value};
use std::sync::{Arc, Mutex};

node_params! {
    /// Parameters of `rcsa.couple`.
    pub struct RcsaCoupleParams<'a> {
        assembly: opt &'a str = (
            T::Entity(EntityKind::Assembly),
            "holder and tool sections, meshed here; its `tool_joint` is used (or connect `structure`)",
        ),
        sensor: opt &'a str = (T::Entity(EntityKind::Sensor), "a sensor whose `mass` sits on the tool tip"),
        interface: def &'a str = INTERFACE,
        machine: opt &'a str = MACHINE,
        grid_mismatch: def &'a str = GRID_MISMATCH,
        max_condition: def f64 = MAX_CONDITION,
        max_element: def f64 = MAX_ELEMENT,
        shear: def &'a str = SHEAR,
    }
}

/// `rcsa.couple`: tool-tip receptances of an assembly on a spindle (Eqs. 5.3, 5.16–5.17).
pub struct RcsaCouple {
    spec: NodeSpec,
}

impl Default for RcsaCouple {
    fn default() -> Self {
        Self::new()
    }
}

impl RcsaCouple {
    pub fn new() -> Self {
        RcsaCouple {
            spec: NodeSpec {
                kind: RCSA_COUPLE,
                version: 2,
                description: "RCSA: couples a free-free FE assembly to the spindle receptances at its base, G11 = R11 - R12 (R22 + K^-1 + B)^-1 R21 (Eqs. 5.3, 5.16-5.17); a compliant tool_joint makes it spindle-holder-tool.",
                inputs: vec![
                    PortSpec::new("spindle", PortType::ReceptanceSet, "spindle receptances B at the holder base"),
                    PortSpec::new(
                        "structure",
                        PortType::Substructure,
                        "the holder and tool, reduced once by beam.substructure (instead of `assembly`)",
                    )
                    .optional(),
                    PortSpec::new(
                        "grid",
                        PortType::Frf,
                        "an FRF whose frequency lines the result is to have (see `grid_mismatch`)",
                    )
                    .optional(),
                ],
                outputs: vec![
                    PortSpec::new("tip", PortType::ReceptanceSet, "2x2 receptances at the tool tip"),
                    PortSpec::new("frf", PortType::Frf, "tool-tip H (m/N), direction and speed of the spindle input"),
                ],
                params: RcsaCoupleParams::fields(),
            },
        }
    }
}

impl Node for RcsaCouple {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = RcsaCoupleParams::read(params)?;
        check_coupling(params, p.interface, p.machine)
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = RcsaCoupleParams::read(ctx.params)?;
        let spindle = input_on_grid(ctx, "spindle", p.grid_mismatch)?;
        let interface = holder_interface(ctx, p.interface, p.machine)?;
        let tip_mass = sensor_mass(ctx, p.sensor)?;
        let freqs = spindle.freq_hz.clone();
        let base = to_frf(&spindle);
        let opts = rcsa_options(p.max_condition);
        let hint = "the spindle receptance and the assembly's joint receptance cancel there; check the spindle model and the joint";
        let (ports, tool_joint) = match ctx.inputs_of("structure").first().map(|l| l.value.as_ref()) {
            Some(Value::Substructure(s)) => {
                let ports = s.parts.iter().map(|part| cached_two_port(part, &freqs)).collect::<Result<Vec<_>, _>>()?;
                (ports, s.tool_joint)
            }
            Some(other) => {
                return Err(NodeError::input(
                    "structure",
                    format!("expected a substructure, got {}", other.port_type()),
                ));
            }
            None => {
                let name = p.assembly.ok_or_else(|| {
                    NodeError::param(
                        "assembly",
                        "rcsa.couple needs `assembly`, or a substructure connected to `structure`",
                    )
                })?;
                let a = assembly(ctx, "assembly", name)?;
                let (parts, joint) = assembly_parts(a, name, false)?;
                let mesh = mesh(p.max_element, p.shear);
                let ports = parts
                    .iter()
                    .map(|(_, sections)| two_port(sections, &mesh, 0.0, &freqs, "assembly").map(Arc::new))
                    .collect::<Result<Vec<_>, _>>()?;
                (ports, joint)
            }
        };
        let mut g = match (&ports[..], tool_joint) {
            ([whole], _) => {
                rcsa::couple(whole, &base, &interface, &opts).map_err(|e| rcsa_error("spindle", e, hint))?
            }
            ([holder, tool], joint) => {
                let at_tool = match joint {
                    Some([kt, ct, kr, cr]) => Interface::diagonal(kt, ct, kr, cr),
                    None => Interface::Rigid,
                };
                rcsa::couple_chain(&base, &[(&**holder, interface), (&**tool, at_tool)], &opts)
                    .map_err(|e| rcsa_error("spindle", e, hint))?
            }
            _ => return Err(NodeError::input("structure", "a substructure has one part, or two (holder and tool)")),
        };
        if tip_mass > 0.0 {
            g = rcsa::with_point_mass(&g, tip_mass).map_err(|e| {
                rcsa_error("sensor", e, "the sensor mass resonates with the structure exactly on a line")
            })?;
        }
        let set = to_set(&g, spindle.direction.clone(), spindle.speed_rpm);
        let frf = h_of(&set);
        Ok(outputs(vec![("tip", Value::ReceptanceSet(set)), ("frf", Value::Frf(frf))]))
    }
}

/// A substructure part's two-port on `freqs` (1 = tip, 2 = spindle end).
fn part_two_port(part: &SubstructurePart, freqs: &[f64]) -> Result<TwoPort, NodeError> {
    let reduced = beam::ReducedModes {
        sigma: part.shift,
        rigid: part.rigid_modes,
        nu: part.nu.clone(),
        shapes: part.shapes.to_vec(),
        natural_hz: part.natural_hz.clone(),
    };
    two_port_of(&reduced, freqs).map_err(|e| NodeError::input("structure", format!("part `{}`: {e}", part.name)))
}

/// Two-ports already evaluated, by part and grid: a fit or a diagnosis couples the same
/// parts on the same lines hundreds of times while only a joint or the spindle changes, and
/// summing the parts' modes is most of a coupling's cost. A hit is checked against the full
/// part and grid, so it is exactly the value the sum would give.
fn cached_two_port(part: &SubstructurePart, freqs: &[f64]) -> Result<Arc<TwoPort>, NodeError> {
    type Entry = (SubstructurePart, Arc<TwoPort>);
    /// Enough for the parts of a few assemblies on a few grids (each about 1 MB).
    const KEEP: usize = 12;
    static CACHE: Mutex<Vec<Entry>> = Mutex::new(Vec::new());
    let hit = |c: &[Entry]| c.iter().find(|(p, t)| p == part && t.freqs_hz == freqs).map(|(_, t)| Arc::clone(t));
    if let Some(t) = hit(&CACHE.lock().unwrap_or_else(|e| e.into_inner())) {
        return Ok(t);
    }
    let t = Arc::new(part_two_port(part, freqs)?);
    let mut c = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    if c.len() >= KEEP {
        c.remove(0);
    }
    c.push((part.clone(), Arc::clone(&t)));
    Ok(t)
}
