//! Model transforms: cheap changes of an already computed value, so that a fit or a
//! diagnosis that varies one effect recomputes only the transform, never the structure.
//!
//! - `substructure.joint`: a joint between holder and tool, given as numbers;
//! - `receptance.tip_mass`: a translational point mass on the tip (a sensor);
//! - `frf.phase_slope`: a phase proportional to frequency (a sensor's delay);
//! - `frf.add_mode`: one more mode added to an FRF (a resonance the model lacks).

use super::structure::{h_of, outputs, to_frf, to_set};
use crate::rcsa;
use num_complex::Complex64;
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{Field, FieldType as T, Params};
use spindlelab_engine::value::{Frf, Mode, PortType, Substructure, Value};
use spindlelab_grammar::Dimension as D;
use std::f64::consts::TAU;

fn spec(
    kind: &'static str,
    description: &'static str,
    inputs: Vec<PortSpec>,
    outputs: Vec<PortSpec>,
    params: Vec<Field>,
) -> NodeSpec {
    NodeSpec { kind, version: 1, description, inputs, outputs, params }
}

// ------------------------------------------------------------------ substructure.joint

/// The kind name of `substructure.joint`: a compliant joint at a substructure's holder face.
pub const SUBSTRUCTURE_JOINT: &str = "substructure.joint";
/// The kind name of `receptance.tip_mass`: a point mass at a receptance's tip.
pub const RECEPTANCE_TIP_MASS: &str = "receptance.tip_mass";
/// The kind name of `frf.phase_slope`: a phase lag linear in frequency.
pub const FRF_PHASE_SLOPE: &str = "frf.phase_slope";
/// The kind name of `frf.add_mode`: one mode added to an FRF.
pub const FRF_ADD_MODE: &str = "frf.add_mode";

node_params! {
    /// Parameters of `substructure.joint`.
    pub struct SubstructureJointParams<'a> {
        kt: req f64 = (T::Quantity(D::STIFFNESS), "translational stiffness"),
        ct: def f64 = (T::Quantity(D::DAMPING), "0 N*s/m", "translational damping"),
        kr: req f64 = (T::Quantity(D::ROTATIONAL_STIFFNESS), "rotational stiffness"),
        cr: def f64 = (T::Quantity(D::ROTATIONAL_DAMPING), "0 N*m*s/rad", "rotational damping"),
    }
}

/// `substructure.joint`: puts a joint `diag(kt + iωct, kr + iωcr)` between the holder and
/// the tool of a substructure reduced in two parts.
pub struct SubstructureJoint {
    spec: NodeSpec,
}

impl Default for SubstructureJoint {
    fn default() -> Self {
        Self::new()
    }
}

impl SubstructureJoint {
    pub fn new() -> Self {
        SubstructureJoint {
            spec: spec(
                SUBSTRUCTURE_JOINT,
                "Puts a tool–holder joint K = diag(kt + iω ct, kr + iω cr) between the holder and the tool of a two-part substructure (beam.substructure with a compliant tool_joint or `split: holder_face`), replacing any joint there; the parts' modes are reused.",
                vec![PortSpec::new("structure", PortType::Substructure, "holder and tool, reduced in two parts")],
                vec![PortSpec::new("structure", PortType::Substructure, "the same parts with the joint")],
                SubstructureJointParams::fields(),
            ),
        }
    }
}

impl Node for SubstructureJoint {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        super::positive(p, &["kt", "kr"])?;
        super::non_negative(p, &["ct", "cr"])
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let Value::Substructure(s) = ctx.input("structure")? else {
            return Err(NodeError::input("structure", "expected a substructure"));
        };
        if s.parts.len() != 2 {
            return Err(NodeError::input(
                "structure",
                format!(
                    "substructure `{}` is one part; reduce it with `split: holder_face` so a joint can sit between holder and tool",
                    s.assembly
                ),
            ));
        }
        let p = SubstructureJointParams::read(ctx.params)?;
        let joint = [p.kt, p.ct, p.kr, p.cr];
        let out = Substructure { assembly: s.assembly.clone(), parts: s.parts.clone(), tool_joint: Some(joint) };
        Ok(outputs(vec![("structure", Value::Substructure(out))]))
    }
}

// ------------------------------------------------------------------ receptance.tip_mass

node_params! {
    /// Parameters of `receptance.tip_mass`.
    pub struct ReceptanceTipMassParams<'a> {
        mass: req f64 = (T::Quantity(D::MASS), "the mass on the tip (negative removes one)"),
    }
}

/// `receptance.tip_mass`: `G' = G (I − ω² diag(m, 0) G)⁻¹`, a translational mass on the tip.
pub struct ReceptanceTipMass {
    spec: NodeSpec,
}

impl Default for ReceptanceTipMass {
    fn default() -> Self {
        Self::new()
    }
}

impl ReceptanceTipMass {
    pub fn new() -> Self {
        ReceptanceTipMass {
            spec: spec(
                RECEPTANCE_TIP_MASS,
                "Adds a translational point mass (a sensor, no rotary inertia) to tip receptances: G' = G (I - w^2 diag(m, 0) G)^-1; the measured configuration from the cutting one.",
                vec![PortSpec::new("tip", PortType::ReceptanceSet, "2x2 tip receptances")],
                vec![
                    PortSpec::new("tip", PortType::ReceptanceSet, "with the mass"),
                    PortSpec::new("frf", PortType::Frf, "its H (m/N)"),
                ],
                ReceptanceTipMassParams::fields(),
            ),
        }
    }
}

impl Node for ReceptanceTipMass {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let Value::ReceptanceSet(set) = ctx.input("tip")? else {
            return Err(NodeError::input("tip", "expected a receptance set"));
        };
        let mass = ReceptanceTipMassParams::read(ctx.params)?.mass;
        let g = rcsa::with_point_mass(&to_frf(set), mass).map_err(|e| {
            NodeError::param("mass", format!("{e}: the mass resonates with the structure exactly on a line"))
        })?;
        let out = to_set(&g, set.direction.clone(), set.speed);
        let frf = h_of(&out);
        Ok(outputs(vec![("tip", Value::ReceptanceSet(out)), ("frf", Value::Frf(frf))]))
    }
}

// ------------------------------------------------------------------ frf.phase_slope

node_params! {
    /// Parameters of `frf.phase_slope`.
    pub struct FrfPhaseSlopeParams<'a> {
        slope: req f64 = (T::Quantity(D::PHASE_SLOPE), "phase per frequency, e.g. -13.84 deg/kHz"),
    }
}

/// `frf.phase_slope`: `H' = H exp(i s f)`, a phase linear in frequency (a sensor's delay).
pub struct FrfPhaseSlope {
    spec: NodeSpec,
}

impl Default for FrfPhaseSlope {
    fn default() -> Self {
        Self::new()
    }
}

impl FrfPhaseSlope {
    pub fn new() -> Self {
        FrfPhaseSlope {
            spec: spec(
                FRF_PHASE_SLOPE,
                "Adds a phase linear in frequency, H' = H exp(i s f): a sensor's delay or filter lag (-13.84 deg/kHz for a capacitance gauge, §2.3).",
                vec![PortSpec::new("frf", PortType::Frf, "the FRF")],
                vec![PortSpec::new("frf", PortType::Frf, "with the phase slope")],
                FrfPhaseSlopeParams::fields(),
            ),
        }
    }
}

impl Node for FrfPhaseSlope {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let Value::Frf(frf) = ctx.input("frf")? else {
            return Err(NodeError::input("frf", "expected an FRF"));
        };
        // The slope is stored in rad/Hz (rad·s).
        let slope = FrfPhaseSlopeParams::read(ctx.params)?.slope;
        let mut out = frf.clone();
        for (v, f) in out.values.iter_mut().zip(&frf.freq_hz) {
            *v *= Complex64::from_polar(1.0, slope * f);
        }
        Ok(outputs(vec![("frf", Value::Frf(out))]))
    }
}

// ------------------------------------------------------------------ frf.add_mode

node_params! {
    /// Parameters of `frf.add_mode`.
    pub struct FrfAddModeParams<'a> {
        f: req f64 = (T::Quantity(D::FREQUENCY), "natural frequency"),
        zeta: req f64 = (T::Quantity(D::DIMENSIONLESS), "damping ratio"),
        stiffness: req f64 = (
            T::Quantity(D::STIFFNESS),
            "modal stiffness k (its static compliance is 1/k)",
        ),
        direction: opt &'a str = (
            T::Choice(&["x", "y", "z"]),
            "add the mode only to FRFs along this direction (others pass unchanged): a resonance of one direction in a sweep over both",
        ),
    }
}

/// `frf.add_mode`: `H' = H + 1/(k(1 − (f/fn)² + 2iζ f/fn))`, one more mode.
pub struct FrfAddMode {
    spec: NodeSpec,
}

impl Default for FrfAddMode {
    fn default() -> Self {
        Self::new()
    }
}

impl FrfAddMode {
    pub fn new() -> Self {
        FrfAddMode {
            spec: spec(
                FRF_ADD_MODE,
                "Adds one mode to an FRF, H' = H + 1/(k (1 - (f/fn)^2 + 2i zeta f/fn)): a resonance the model lacks, such as a sensor mount's.",
                vec![PortSpec::new("frf", PortType::Frf, "the FRF (m/N)")],
                vec![PortSpec::new("frf", PortType::Frf, "with the mode")],
                FrfAddModeParams::fields(),
            ),
        }
    }
}

impl Node for FrfAddMode {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        super::positive(p, &["f", "stiffness"])?;
        super::non_negative(p, &["zeta"])
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let Value::Frf(frf) = ctx.input("frf")? else {
            return Err(NodeError::input("frf", "expected an FRF"));
        };
        let p = FrfAddModeParams::read(ctx.params)?;
        if let Some(only) = p.direction {
            match frf.direction.as_deref() {
                Some(d) if d == only => {}
                Some(_) => return Ok(outputs(vec![("frf", Value::Frf(frf.clone()))])),
                None => {
                    return Err(NodeError::input(
                        "frf",
                        format!("the FRF states no direction, so `direction: {only}` cannot pick it"),
                    ));
                }
            }
        }
        let mode = Mode::from_stiffness(p.f, p.zeta, p.stiffness);
        let mut out: Frf = frf.clone();
        for (v, f) in out.values.iter_mut().zip(&frf.freq_hz) {
            *v += mode.receptance(TAU * f);
        }
        Ok(outputs(vec![("frf", Value::Frf(out))]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nodes::test_support::{empty_recipe, params};
    use indexmap::IndexMap;
    use spindlelab_engine::node::Labelled;
    use spindlelab_engine::value::{ReceptanceSet, UnitLabel};
    use std::sync::Arc;

    fn input(port: &str, v: Value) -> IndexMap<String, Vec<Labelled>> {
        let mut m = IndexMap::new();
        m.insert(port.to_string(), vec![Labelled { label: String::new(), coords: Vec::new(), value: Arc::new(v) }]);
        m
    }

    fn frf(values: Vec<Complex64>, freq: Vec<f64>) -> Frf {
        Frf {
            freq_hz: freq,
            values,
            coherence: None,
            unit: UnitLabel::new("m/N"),
            direction: None,
            speed: None,
            sensor: None,
            dofs: None,
        }
    }

    #[test]
    fn a_tip_mass_on_a_spring_gives_the_spring_mass_receptance() {
        // A massless tip on a spring k (h = 1/k, no rotation) with a mass m: 1/(k − ω²m).
        let (k, m) = (1e7, 0.5);
        let freq: Vec<f64> = (1..200).map(|i| i as f64 * 5.0).collect();
        let n = freq.len();
        let zero = vec![Complex64::new(0.0, 0.0); n];
        let set = ReceptanceSet {
            freq_hz: freq.clone(),
            h: vec![Complex64::new(1.0 / k, 0.0); n],
            l: zero.clone(),
            n: zero.clone(),
            p: vec![Complex64::new(1e-6, 0.0); n],
            direction: Some("x".into()),
            speed: Some(spindlelab_domain::Speed::from_rpm(0.0)),
        };
        let node = ReceptanceTipMass::new();
        let p = params(&node, "mass: 500 g");
        let inputs = input("tip", Value::ReceptanceSet(set));
        let recipe = empty_recipe();
        let out = node.run(&NodeContext::new("t", &p, &inputs, &recipe.entities_named_by(&p))).unwrap();
        let Value::Frf(h) = &out["frf"] else { panic!() };
        for (f, v) in freq.iter().zip(&h.values) {
            let w = TAU * f;
            let want = 1.0 / (k - w * w * m);
            assert!((v.re - want).abs() <= 1e-9 * want.abs() && v.im.abs() < 1e-20, "{f} Hz");
        }
        assert_eq!(h.direction.as_deref(), Some("x"));
    }

    #[test]
    fn a_phase_slope_turns_the_phase_linearly() {
        let freq: Vec<f64> = (0..100).map(|i| i as f64 * 40.0).collect();
        let values = vec![Complex64::new(2e-7, -1e-7); freq.len()];
        let node = FrfPhaseSlope::new();
        let p = params(&node, "slope: -13.84 deg/kHz");
        let inputs = input("frf", Value::Frf(frf(values.clone(), freq.clone())));
        let recipe = empty_recipe();
        let out = node.run(&NodeContext::new("t", &p, &inputs, &recipe.entities_named_by(&p))).unwrap();
        let Value::Frf(h) = &out["frf"] else { panic!() };
        for ((f, a), b) in freq.iter().zip(&values).zip(&h.values) {
            let turn = (b / a).arg();
            let want = (-13.84 * f / 1000.0_f64).to_radians();
            let d = (turn - want + std::f64::consts::PI).rem_euclid(TAU) - std::f64::consts::PI;
            assert!(d.abs() < 1e-12 && (b.norm() / a.norm() - 1.0).abs() < 1e-12, "{f} Hz");
        }
    }

    #[test]
    fn an_added_mode_is_the_sdof_receptance() {
        let freq: Vec<f64> = (1..1000).map(|i| i as f64 * 10.0).collect();
        let node = FrfAddMode::new();
        let p = params(&node, "{f: 4650 Hz, zeta: 0.02, stiffness: 5e8 N/m}");
        let inputs = input("frf", Value::Frf(frf(vec![Complex64::new(0.0, 0.0); freq.len()], freq.clone())));
        let recipe = empty_recipe();
        let out = node.run(&NodeContext::new("t", &p, &inputs, &recipe.entities_named_by(&p))).unwrap();
        let Value::Frf(h) = &out["frf"] else { panic!() };
        for (f, v) in freq.iter().zip(&h.values) {
            let r = f / 4650.0;
            let want = 1.0 / (5e8 * Complex64::new(1.0 - r * r, 2.0 * 0.02 * r));
            assert!((v - want).norm() <= 1e-12 * want.norm(), "{f} Hz");
        }
    }
}
