//! The `rcsa.couple` node kind: tool-tip receptances of an assembly coupled to a spindle.

use super::{
    RCSA_COUPLE, assembly, assembly_parts, check_coupling, h_of, holder_interface, input_on_grid, mesh, outputs,
    rcsa_error, rcsa_options, sensor_mass, to_frf, to_set, two_port, two_port_of,
};
use crate::beam;
use crate::rcsa::{self, Complex64, Interface, Receptance, TwoPort};
use spindlelab_domain::Speed;
use spindlelab_engine::model::Joint;

use super::{GRID_MISMATCH, INTERFACE, MACHINE, MAX_CONDITION, MAX_ELEMENT, SHEAR};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, FieldType as T, Params};
use spindlelab_engine::value::{PortType, ReceptanceSet, SubstructurePart, Value};
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
                    PortSpec::new(
                        "spindle_cross",
                        PortType::ReceptanceSet,
                        "the cross-plane block Q of a spinning spindle (rotor.receptance's or spindle.receptance's `cross`): the assembly is coupled in the forward and backward whirl coordinates and the two averaged; an `assembly` meshed here also spins at the spindle's speed, a `structure` does not",
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
        if !ctx.inputs_of("spindle_cross").is_empty() {
            let cross = input_on_grid(ctx, "spindle_cross", p.grid_mismatch)?;
            check_same_spindle(&spindle, &cross)?;
            if ctx.inputs_of("structure").is_empty() {
                return couple_spinning(ctx, &p, spindle, cross, interface, tip_mass);
            }
            // No cross-plane block (at rest, or no gyroscopic mode): both whirls are the spindle.
            let zero = Complex64::new(0.0, 0.0);
            if [&cross.h, &cross.l, &cross.n, &cross.p].iter().all(|v| v.iter().all(|c| *c == zero)) {
                let g = couple_still(ctx, &p, &to_frf(&spindle), interface, tip_mass)?;
                let set = to_set(&g, spindle.direction.clone(), spindle.speed);
                let frf = h_of(&set);
                return Ok(outputs(vec![("tip", Value::ReceptanceSet(set)), ("frf", Value::Frf(frf))]));
            }
            // A structure that does not spin on a spindle that whirls: in the whirl coordinates
            // the planes decouple, so the structure is coupled to the forward whirl F = P − iQ
            // and to the backward whirl B = P + iQ, and the tip's in-plane block is the mean.
            let (base, q) = (to_frf(&spindle), to_frf(&cross));
            let whirl = |s: f64| rcsa::ReceptanceFrf {
                freqs_hz: base.freqs_hz.clone(),
                lines: base.lines.iter().zip(&q.lines).map(|(p, q)| *p + *q * Complex64::new(0.0, s)).collect(),
            };
            let (gf, gb) = (
                couple_still(ctx, &p, &whirl(-1.0), interface, tip_mass)?,
                couple_still(ctx, &p, &whirl(1.0), interface, tip_mass)?,
            );
            let half = Complex64::new(0.5, 0.0);
            let g = rcsa::ReceptanceFrf {
                freqs_hz: gf.freqs_hz.clone(),
                lines: gf.lines.iter().zip(&gb.lines).map(|(f, b)| (*f + *b) * half).collect(),
            };
            let set = to_set(&g, spindle.direction.clone(), spindle.speed);
            let frf = h_of(&set);
            return Ok(outputs(vec![("tip", Value::ReceptanceSet(set)), ("frf", Value::Frf(frf))]));
        }
        let g = couple_still(ctx, &p, &to_frf(&spindle), interface, tip_mass)?;
        let set = to_set(&g, spindle.direction.clone(), spindle.speed);
        let frf = h_of(&set);
        Ok(outputs(vec![("tip", Value::ReceptanceSet(set)), ("frf", Value::Frf(frf))]))
    }
}

/// The tip receptance of the structure on `structure` (or the `assembly` meshed here, not
/// spinning) coupled to the spindle receptance `base` through `interface`, with the sensor's
/// `tip_mass` on it.
fn couple_still(
    ctx: &NodeContext,
    p: &RcsaCoupleParams,
    base: &rcsa::ReceptanceFrf,
    interface: Interface,
    tip_mass: f64,
) -> Result<rcsa::ReceptanceFrf, NodeError> {
    let freqs = base.freqs_hz.clone();
    let opts = rcsa_options(p.max_condition);
    let hint = "the spindle receptance and the assembly's joint receptance cancel there; check the spindle model and the joint";
    let (ports, tool_joint) = match ctx.inputs_of("structure").first().map(|l| l.value.as_ref()) {
        Some(Value::Substructure(s)) => {
            let ports = s.parts.iter().map(|part| cached_two_port(part, &freqs)).collect::<Result<Vec<_>, _>>()?;
            (ports, s.tool_joint)
        }
        Some(other) => {
            return Err(NodeError::input("structure", format!("expected a substructure, got {}", other.port_type())));
        }
        None => {
            let name = p.assembly.ok_or_else(|| {
                NodeError::param("assembly", "rcsa.couple needs `assembly`, or a substructure connected to `structure`")
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
        ([whole], _) => rcsa::couple(whole, base, &interface, &opts).map_err(|e| rcsa_error("spindle", e, hint))?,
        ([holder, tool], joint) => {
            let at_tool = match joint {
                Some([kt, ct, kr, cr]) => Interface::diagonal(kt, ct, kr, cr),
                None => Interface::Rigid,
            };
            rcsa::couple_chain(base, &[(&**holder, interface), (&**tool, at_tool)], &opts)
                .map_err(|e| rcsa_error("spindle", e, hint))?
        }
        _ => return Err(NodeError::input("structure", "a substructure has one part, or two (holder and tool)")),
    };
    if tip_mass > 0.0 {
        g = rcsa::with_point_mass(&g, tip_mass)
            .map_err(|e| rcsa_error("sensor", e, "the sensor mass resonates with the structure exactly on a line"))?;
    }
    Ok(g)
}

/// Refuses a cross-plane block that is not of the same spindle step as the in-plane one.
fn check_same_spindle(spindle: &ReceptanceSet, cross: &ReceptanceSet) -> Result<(), NodeError> {
    if spindle.speed.unwrap_or(Speed::ZERO) != cross.speed.unwrap_or(Speed::ZERO)
        || !super::same_grid(&spindle.freq_hz, &cross.freq_hz)
    {
        return Err(NodeError::input(
            "spindle_cross",
            format!(
                "`spindle` and `spindle_cross` must come from one rotor.receptance or spindle.receptance step (same speed and lines); got {} and {}",
                spindle.speed.unwrap_or(Speed::ZERO),
                cross.speed.unwrap_or(Speed::ZERO)
            ),
        ));
    }
    Ok(())
}

/// `rcsa.couple` on a spinning spindle: the assembly meshed, spinning at the spindle's speed, and
/// coupled to the spindle's in-plane and cross-plane blocks in whirl coordinates
/// ([`rcsa::couple_spinning`]).
fn couple_spinning(
    ctx: &NodeContext,
    p: &RcsaCoupleParams,
    spindle: ReceptanceSet,
    cross: ReceptanceSet,
    interface: Interface,
    tip_mass: f64,
) -> Result<Outputs, NodeError> {
    let name = p
        .assembly
        .ok_or_else(|| NodeError::param("assembly", "a spinning coupling needs `assembly`, the holder and tool"))?;
    let a = assembly(ctx, "assembly", name)?;
    if !matches!(a.tool_joint, Joint::Rigid) {
        return Err(NodeError::param(
            "assembly",
            format!(
                "assembly `{name}` has a compliant `tool_joint`; on a spinning spindle only a rigid tool joint is modelled"
            ),
        ));
    }
    let fe = |e: beam::BeamError| NodeError::param("assembly", e.to_string());
    let model =
        beam::BeamModel::from_segments(&beam::segments_from_sections(&a.sections), &mesh(p.max_element, p.shear))
            .map_err(fe)?;
    let tip = model.n_nodes() - 1;
    let spinning = beam::SpinningModel::new(model);
    let freqs = spindle.freq_hz.clone();
    let speed = spindle.speed.unwrap_or(Speed::ZERO);
    let two_port = |forward: bool| -> Result<TwoPort, NodeError> {
        let lines = spinning.whirl_blocks(&[tip, 0], speed.rad_s(), forward, &freqs).map_err(fe)?;
        let pick =
            |k: usize| lines.iter().map(|b| Receptance::new(b[k][0][0], b[k][0][1], b[k][1][0], b[k][1][1])).collect();
        Ok(TwoPort { freqs_hz: freqs.clone(), r11: pick(0), r12: pick(1), r21: pick(2), r22: pick(3) })
    };
    let base = (to_frf(&spindle), to_frf(&cross));
    let hint =
        "the spindle and the spinning assembly cancel there in one whirl direction; check the rotor and the joint";
    let (g, _) = rcsa::couple_spinning(
        &two_port(true)?,
        &two_port(false)?,
        &base,
        &interface,
        tip_mass,
        &rcsa_options(p.max_condition),
    )
    .map_err(|e| rcsa_error("spindle", e, hint))?;
    let set = to_set(&g, spindle.direction.clone(), spindle.speed);
    let frf = h_of(&set);
    Ok(outputs(vec![("tip", Value::ReceptanceSet(set)), ("frf", Value::Frf(frf))]))
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
