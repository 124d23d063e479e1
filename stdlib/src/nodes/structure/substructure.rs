//! The `beam.substructure` node kind: an assembly's FE model reduced once to its coupling points.

use super::{BEAM_SUBSTRUCTURE, assembly, assembly_parts, check_mesh, mesh, outputs};
use crate::beam::{self, BeamModel, MeshOptions};
use spindlelab_engine::model::Section;

use super::{MAX_ELEMENT, SHEAR};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, FieldType as T, Params};
use spindlelab_engine::value::{PortType, Substructure, SubstructurePart, Value};

node_params! {
    /// Parameters of `beam.substructure`.
    pub struct BeamSubstructureParams<'a> {
        assembly: req &'a str = (
            T::Entity(EntityKind::Assembly),
            "holder and tool sections; a compliant `tool_joint` splits it into holder and tool",
        ),
        split: def &'a str = (
            T::Choice(&["auto", "holder_face"]),
            "auto",
            "`holder_face`: reduce holder and tool separately even with a rigid tool joint, so `substructure.joint` can put a joint there; `auto`: split only at a compliant `tool_joint`",
        ),
        max_element: def f64 = MAX_ELEMENT,
        shear: def &'a str = SHEAR,
    }
}

/// `beam.substructure`: an assembly's free–free FE model reduced once to its tip and spindle end.
pub struct BeamSubstructure {
    spec: NodeSpec,
}

impl Default for BeamSubstructure {
    fn default() -> Self {
        Self::new()
    }
}

impl BeamSubstructure {
    pub fn new() -> Self {
        BeamSubstructure {
            spec: NodeSpec {
                kind: BEAM_SUBSTRUCTURE,
                version: 2,
                description: "Free-free Timoshenko FE model of an assembly (§5.4) with structural damping, reduced to its tip and spindle end: every complex mode, computed once and coupled by rcsa.couple at every speed, direction and joint setting.",
                inputs: vec![],
                outputs: vec![PortSpec::new(
                    "model",
                    PortType::Substructure,
                    "the holder and tool as complex modes at tip and spindle end",
                )],
                params: BeamSubstructureParams::fields(),
            },
        }
    }
}

impl Node for BeamSubstructure {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        check_mesh(p)
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = BeamSubstructureParams::read(ctx.params)?;
        let name = p.assembly;
        let a = assembly(ctx, "assembly", name)?;
        let (parts, tool_joint) = assembly_parts(a, name, p.split == "holder_face")?;
        let mesh = mesh(p.max_element, p.shear);
        let parts =
            parts.iter().map(|(part, sections)| reduce_part(part, sections, &mesh)).collect::<Result<Vec<_>, _>>()?;
        let model = Substructure { assembly: name.to_string(), parts, tool_joint };
        Ok(outputs(vec![("model", Value::Substructure(model))]))
    }
}

/// A part's FE model reduced to its tip and spindle end (a [`SubstructurePart`]).
fn reduce_part(name: &str, sections: &[Section], mesh: &MeshOptions) -> Result<SubstructurePart, NodeError> {
    let fe = |e: beam::BeamError| NodeError::param("assembly", e.to_string());
    let model = BeamModel::from_segments(&beam::segments_from_sections(sections), mesh).map_err(fe)?;
    let tip = model.n_nodes() - 1;
    let reduced = model.modes().map_err(fe)?.reduce(&[tip, 0]).map_err(fe)?;
    let mut shapes = reduced.shapes.into_iter();
    let mut next = || shapes.next().unwrap_or_default();
    Ok(SubstructurePart {
        name: name.to_string(),
        length: sections.iter().map(|s| s.length).sum(),
        shift: reduced.sigma,
        rigid_modes: reduced.rigid,
        natural_hz: reduced.natural_hz,
        nu: reduced.nu,
        shapes: [next(), next(), next(), next()],
    })
}
