//! The `rcsa.decouple` node kind: spindle receptances from an artifact's tip receptances (inverse RCSA).

use super::{
    assembly, check_coupling, holder_interface, input_on_grid, mesh, outputs, rcsa_error, rcsa_options, sensor_mass,
    to_frf, to_set, two_port,
};
use crate::rcsa;
use spindlelab_engine::model::Joint;

use super::{GRID_MISMATCH, INTERFACE, MACHINE, MAX_CONDITION, MAX_ELEMENT, SHEAR};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, FieldType as T, Params};
use spindlelab_engine::value::{PortType, Value};

node_params! {
    /// Parameters of `rcsa.decouple`.
    pub struct RcsaDecoupleParams<'a> {
        artifact: req &'a str = (T::Entity(EntityKind::Assembly), "the artifact beyond the flange, as one body"),
        sensor: opt &'a str = (
            T::Entity(EntityKind::Sensor),
            "a sensor whose `mass` sat on the tip when G11 was measured",
        ),
        interface: def &'a str = INTERFACE,
        machine: opt &'a str = MACHINE,
        grid_mismatch: def &'a str = GRID_MISMATCH,
        max_condition: def f64 = MAX_CONDITION,
        max_element: def f64 = MAX_ELEMENT,
        shear: def &'a str = SHEAR,
    }
}

/// `rcsa.decouple`: spindle receptances from an artifact's tip receptances (inverse RCSA, Eq. 5.4).
pub struct RcsaDecouple {
    spec: NodeSpec,
}

impl Default for RcsaDecouple {
    fn default() -> Self {
        Self::new()
    }
}

impl RcsaDecouple {
    pub fn new() -> Self {
        RcsaDecouple {
            spec: NodeSpec {
                kind: "rcsa.decouple",
                version: 1,
                description: "Inverse RCSA: the spindle receptances at the holder base from the artifact-tip receptances G11, R2b2b = R2a1 (R11 - G11)^-1 R12a - R2a2a - K^-1 (Eq. 5.4 as corrected, with Eqs. 5.16-5.17).",
                inputs: vec![
                    PortSpec::new(
                        "assembly_tip",
                        PortType::ReceptanceSet,
                        "2x2 receptances G11 at the artifact tip on the spindle (e.g. from a fit)",
                    ),
                    PortSpec::new(
                        "grid",
                        PortType::Frf,
                        "an FRF whose frequency lines the result is to have (see `grid_mismatch`)",
                    )
                    .optional(),
                ],
                outputs: vec![PortSpec::new(
                    "spindle",
                    PortType::ReceptanceSet,
                    "spindle receptances at the holder base, direction and speed of the input",
                )],
                params: RcsaDecoupleParams::fields(),
            },
        }
    }
}

impl Node for RcsaDecouple {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = RcsaDecoupleParams::read(params)?;
        check_coupling(params, p.interface, p.machine)
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = RcsaDecoupleParams::read(ctx.params)?;
        let g11 = input_on_grid(ctx, "assembly_tip", p.grid_mismatch)?;
        let a = assembly(ctx, "artifact", p.artifact)?;
        if !matches!(a.tool_joint, Joint::Rigid) {
            ctx.warn("the artifact's `tool_joint` is not used: the artifact is decoupled as one body");
        }
        let interface = holder_interface(ctx, p.interface, p.machine)?;
        let tip_mass = sensor_mass(ctx, p.sensor)?;
        let freqs = g11.freq_hz.clone();
        let art = two_port(&a.sections, &mesh(p.max_element, p.shear), tip_mass, &freqs, "artifact")?;
        let hint = "there the artifact's own tip receptance R11 equals G11 (R11 - G11 is singular, e.g. G11 of the free artifact or lines where a measured G11 is noise), so the spindle is not determined: leave those lines out of the grid or fit G11 first";
        let b = rcsa::decouple(&art, &to_frf(&g11), &interface, &rcsa_options(p.max_condition))
            .map_err(|e| rcsa_error("assembly_tip", e, hint))?;
        let set = to_set(&b, g11.direction.clone(), g11.speed);
        Ok(outputs(vec![("spindle", Value::ReceptanceSet(set))]))
    }
}
