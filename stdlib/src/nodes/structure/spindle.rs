//! The `spindle.receptance` node kind: spindle receptances at the holder base from equivalent modes.

use super::{SPINDLE_RECEPTANCE, grid, grid_port, h_of, outputs, to_set};
use crate::eb_modes;
use crate::rcsa::ReceptanceFrf;
use spindlelab_domain::Speed;

use super::{LINES, MAX_FREQUENCY, RESOLUTION};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, FieldType as T, Params};
use spindlelab_engine::value::{PortType, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `spindle.receptance`.
    pub struct SpindleReceptanceParams<'a> {
        machine: req &'a str = (T::Entity(EntityKind::Machine), "a machine with a `spindle` model"),
        direction: opt &'a str = (
            T::Choice(&["x", "y"]),
            "which direction's modes; default: the `grid` FRF's direction, else x",
        ),
        speed: opt f64 = (
            T::Quantity(D::ROTATIONAL_SPEED),
            "spindle speed for the speed laws; default: the `grid` FRF's speed, else 0 rpm",
        ),
        max_frequency: def f64 = MAX_FREQUENCY,
        resolution: opt f64 = RESOLUTION,
        lines: def usize = LINES,
    }
}

/// `spindle.receptance`: the spindle-machine receptance at the holder base from equivalent modes.
pub struct SpindleReceptance {
    spec: NodeSpec,
}

impl Default for SpindleReceptance {
    fn default() -> Self {
        Self::new()
    }
}

impl SpindleReceptance {
    pub fn new() -> Self {
        SpindleReceptance {
            spec: NodeSpec {
                kind: SPINDLE_RECEPTANCE,
                version: 3,
                description: "Spindle-machine receptances at the holder base as the sum of equivalent fixed-free Euler-Bernoulli modes (Eqs. 5.5-5.7, 5.10-5.12) at a speed. Modes with a gyroscopic coefficient (`gyro`) whirl forward and backward at speed; wire `cross` into rcsa.couple's `spindle_cross` so the assembly is coupled in each whirl.",
                inputs: vec![grid_port()],
                outputs: vec![
                    PortSpec::new(
                        "receptance",
                        PortType::ReceptanceSet,
                        "2x2 receptances at the holder base (in-plane block P, the mean of the two whirls)",
                    ),
                    PortSpec::new(
                        "cross",
                        PortType::ReceptanceSet,
                        "cross-plane block Q of the gyroscopic coupling, i(F - B)/2 of the forward and backward whirls (zero without one), for rcsa.couple's `spindle_cross`",
                    ),
                    PortSpec::new("frf", PortType::Frf, "its H = y/F (m/N)"),
                ],
                params: SpindleReceptanceParams::fields(),
            },
        }
    }
}

impl Node for SpindleReceptance {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        super::super::positive(p, &["max_frequency", "resolution"])?;
        super::super::non_negative(p, &["speed"])
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = SpindleReceptanceParams::read(ctx.params)?;
        let name = p.machine;
        let machine = ctx
            .entities
            .machines
            .get(name)
            .ok_or_else(|| NodeError::param("machine", format!("no machine `{name}` in the recipe")))?;
        let Some(spindle) = &machine.spindle else {
            return Err(NodeError::param(
                "machine",
                format!(
                    "machine `{name}` has no spindle model: add `spindle: {{material, modes: {{x: [{{f, d, eta}}]}}}}`"
                ),
            ));
        };
        // Direction and speed default to those of the measurement the model is evaluated
        // for, so one step serves every file of a measurement set.
        let measured = match ctx.inputs_of("grid").first().map(|l| l.value.as_ref()) {
            Some(Value::Frf(f)) => Some(f),
            _ => None,
        };
        let dir = p.direction.or_else(|| measured.and_then(|f| f.direction.as_deref())).unwrap_or("x");
        let Some((_, modes)) = spindle.modes.iter().find(|(d, _)| d == dir) else {
            let have: Vec<&str> = spindle.modes.iter().map(|(d, _)| d.as_str()).collect();
            return Err(NodeError::param(
                "direction",
                format!(
                    "machine `{name}` has no spindle modes in direction `{dir}`; it has: {}",
                    if have.is_empty() { "none".to_string() } else { have.join(", ") }
                ),
            ));
        };
        if modes.is_empty() {
            return Err(NodeError::param("machine", format!("machine `{name}` lists no spindle modes for `{dir}`")));
        }
        let freqs = grid(ctx, p.max_frequency, p.resolution, p.lines)?;
        // The measured FRF's speed where the step gives none.
        let speed = p.speed.map(Speed::from_rad_s).or(measured.and_then(|f| f.speed)).unwrap_or(Speed::ZERO);
        let err = |e: eb_modes::EbError| {
            NodeError::param("machine", format!("spindle of machine `{name}`, direction {dir}: {e}"))
        };
        // With gyroscopic coupling at speed, each mode and the same mode across (y for x) are
        // one rotor mode in two planes: the in-plane block P and the cross-plane block Q.
        let (p_block, q_block) = if modes.iter().any(|m| m.gyro != 0.0) && !speed.is_rest() {
            let across = if dir == "x" { "y" } else { "x" };
            let partner = spindle.modes.iter().find(|(d, _)| d == across).map_or(&modes[..], |(_, m)| &m[..]);
            eb_modes::spindle_gyroscopic(modes, partner, &spindle.material, speed, spindle.ref_speed, &freqs)
                .map_err(err)?
        } else {
            let p = eb_modes::spindle_receptance(modes, &spindle.material, speed, spindle.ref_speed, &freqs, None)
                .map_err(err)?;
            let zero =
                ReceptanceFrf { freqs_hz: freqs.clone(), lines: vec![crate::rcsa::Receptance::ZERO; freqs.len()] };
            (p, zero)
        };
        let set = to_set(&p_block, Some(dir.to_string()), Some(speed));
        let cross = to_set(&q_block, Some(dir.to_string()), Some(speed));
        let frf = h_of(&set);
        Ok(outputs(vec![
            ("receptance", Value::ReceptanceSet(set)),
            ("cross", Value::ReceptanceSet(cross)),
            ("frf", Value::Frf(frf)),
        ]))
    }
}
