//! `modal.model`: tool-point modes stated in the recipe.

use super::outputs;
use crate::stability::{self, StabilityError};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{Field, FieldType as T, Params};
use spindlelab_engine::value::{ModalModel, PortType, Value};
use spindlelab_grammar::Dimension as D;

/// `modal.model`: tool-point modes stated in the recipe, per direction, as the modal models `stability.sd`
/// takes (no FRF file or fit needed for a textbook case).
pub struct ModalModelNode {
    spec: NodeSpec,
}

impl Default for ModalModelNode {
    fn default() -> Self {
        Self::new()
    }
}

const MODE_ROW: &[Field] = &[
    Field::req("f", T::Quantity(D::FREQUENCY), "natural frequency"),
    Field::req("zeta", T::Quantity(D::DIMENSIONLESS), "viscous damping ratio ζ, in [0, 1)"),
    Field::opt("mass", T::Quantity(D::MASS), "modal mass (or give stiffness)"),
    Field::opt("stiffness", T::Quantity(D::STIFFNESS), "modal stiffness k = m (2πf)² (or give mass)"),
];

node_params! {
    /// Parameters of `modal.model`.
    pub struct ModalModelParams<'a> {
        x: opt &'a [Params] = (
            T::ObjectList(MODE_ROW),
            "modes along x, rows {f, zeta, mass} or {f, zeta, stiffness} (none: rigid)",
        ),
        y: opt &'a [Params] = (T::ObjectList(MODE_ROW), "modes along y, rows as for x (none: rigid)"),
    }
}

impl ModalModelNode {
    pub fn new() -> Self {
        ModalModelNode {
            spec: NodeSpec {
                kind: "modal.model",
                // 2: a mode's rows are {f, zeta, …}, the names every mode has.
                version: 2,
                description: "Tool-point modes stated directly, per direction: natural frequency, damping ratio and modal mass or modal stiffness of each mode (receptance Eq. 5.8); the modal models x (feed) and y for stability.sd.",
                inputs: vec![],
                outputs: vec![
                    PortSpec::new("modes_x", PortType::ModalModel, "modes along x, the feed direction"),
                    PortSpec::new("modes_y", PortType::ModalModel, "modes along y"),
                ],
                params: ModalModelParams::fields(),
            },
        }
    }
}

/// The modes of the `x` and `y` parameters, checked: each row gives a mass or a stiffness (not both, positive),
/// and [`stability::ModalModel::new`] checks frequency, damping ratio and mass.
fn stated_modes(p: &ModalModelParams) -> Result<stability::ModalModel, NodeError> {
    let mut dirs: [Vec<stability::Mode>; 2] = Default::default();
    for ((dir, rows), modes) in [("x", p.x), ("y", p.y)].into_iter().zip(dirs.iter_mut()) {
        for (index, r) in rows.unwrap_or_default().iter().enumerate() {
            let bad = |what: String| NodeError::param(dir, format!("mode {index} along {dir}: {what}"));
            let (f, zeta) = (r.f64("f").unwrap_or(f64::NAN), r.f64("zeta").unwrap_or(f64::NAN));
            let mode = match (r.f64("mass"), r.f64("stiffness")) {
                (Some(m), None) => stability::Mode { freq_hz: f, damping_ratio: zeta, modal_mass: m },
                (None, Some(k)) if !(k.is_finite() && k > 0.0) => {
                    return Err(bad(format!("modal stiffness {k} N/m must be finite and > 0")));
                }
                (None, Some(k)) => stability::Mode::from_stiffness(f, zeta, k),
                (Some(_), Some(_)) => return Err(bad("give the modal mass or the modal stiffness, not both".into())),
                (None, None) => {
                    return Err(bad("give its modal mass (`mass`) or modal stiffness (`stiffness`)".into()));
                }
            };
            modes.push(mode);
        }
    }
    let [x, y] = dirs;
    stability::ModalModel::new(x, y).map_err(|e| match &e {
        StabilityError::InvalidMode { direction, .. } => NodeError::param(direction, e.to_string()),
        _ => NodeError::param("x", e.to_string()),
    })
}

impl Node for ModalModelNode {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        stated_modes(&ModalModelParams::read(params)?).map(|_| ())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let model = stated_modes(&ModalModelParams::read(ctx.params)?)?;
        Ok(outputs(vec![
            ("modes_x", Value::ModalModel(ModalModel { modes: model.x })),
            ("modes_y", Value::ModalModel(ModalModel { modes: model.y })),
        ]))
    }
}
