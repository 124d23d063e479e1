//! `modal.frf`: the receptance of a modal model on a stated frequency grid, so a tool point a
//! user has as modes (from `modal.model`, a modal fit or a handbook) feeds the nodes that take
//! FRFs: the zero-order lobes (`stability.lobes`), the speed-dependent lobes, comparisons and
//! plots.
//!
//! Each mode contributes Eq. 5.8, `H(ω) = 1/(m(ω_n² − ω² + 2iζω_nω))`, and a direction's
//! receptance is the sum over its modes (unit mode shape at the point, no cross terms).

use crate::stability;
use num_complex::Complex64;
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Frf, ModalModel, Mode, PortType, UnitLabel, Value};
use spindlelab_grammar::Dimension as D;
use std::f64::consts::TAU;

/// Most lines one FRF of this node may have (10 kHz at 0.01 Hz): a grid is stated by the
/// recipe, and memory is not sized by a typo in it.
pub const MAX_LINES: usize = 1_000_001;

node_params! {
    /// Parameters of `modal.frf`.
    pub struct ModalFrfParams<'a> {
        min_frequency: def f64 = (T::Quantity(D::FREQUENCY), "0 Hz", "first line of the grid"),
        max_frequency: req f64 = (
            T::Quantity(D::FREQUENCY),
            "last line of the grid (at most; the grid steps by `resolution` from `min_frequency`)",
        ),
        resolution: def f64 = (T::Quantity(D::FREQUENCY), "1 Hz", "line spacing"),
    }
}

/// `modal.frf`: modal models along x and y → their receptances on `min_frequency ..
/// max_frequency` every `resolution`.
pub struct ModalFrf {
    spec: NodeSpec,
}

impl Default for ModalFrf {
    fn default() -> Self {
        Self::new()
    }
}

impl ModalFrf {
    pub fn new() -> Self {
        ModalFrf {
            spec: NodeSpec {
                kind: "modal.frf",
                version: 1,
                description: "The receptance (m/N) of modal models on a stated band and resolution, per direction as the model has them: each mode contributes Eq. 5.8, 1/(m(ω_n² − ω² + 2iζω_nω)), so modes (modal.model, a modal fit) feed the nodes that take FRFs, such as stability.lobes.",
                inputs: vec![
                    PortSpec::new("modes_x", PortType::ModalModel, "modes along x, the feed direction").optional(),
                    PortSpec::new("modes_y", PortType::ModalModel, "modes along y").optional(),
                ],
                outputs: vec![
                    PortSpec::new("frf_x", PortType::Frf, "receptance along x (m/N), when modes_x is connected")
                        .optional(),
                    PortSpec::new("frf_y", PortType::Frf, "receptance along y (m/N), when modes_y is connected")
                        .optional(),
                ],
                params: ModalFrfParams::fields(),
            },
        }
    }
}

/// The grid of the parameters, Hz: `min, min + Δf, …` up to `max` (within a millionth of a line).
fn grid(p: &Params) -> Result<Vec<f64>, NodeError> {
    let ModalFrfParams { min_frequency: lo, max_frequency: hi, resolution: df, .. } = ModalFrfParams::read(p)?;
    if !(lo.is_finite() && lo >= 0.0) {
        return Err(NodeError::param("min_frequency", format!("{lo} Hz: give a frequency of 0 Hz or more")));
    }
    if !(hi.is_finite() && hi > lo) {
        return Err(NodeError::param(
            "max_frequency",
            format!("{hi} Hz must lie above min_frequency ({lo} Hz), e.g. `max_frequency: 5 kHz`"),
        ));
    }
    if !(df.is_finite() && df > 0.0) {
        return Err(NodeError::param("resolution", format!("{df} Hz: give a positive line spacing, e.g. `1 Hz`")));
    }
    let steps = ((hi - lo) / df + 1e-6).floor();
    if steps + 1.0 > MAX_LINES as f64 {
        return Err(NodeError::param(
            "resolution",
            format!(
                "{df} Hz from {lo} to {hi} Hz makes {} lines, more than the {MAX_LINES} an FRF here may have; \
                 coarsen the resolution or narrow the band",
                steps + 1.0
            ),
        ));
    }
    Ok((0..=steps as usize).map(|i| lo + i as f64 * df).collect())
}

/// The receptance of `modes` on `freqs_hz`, m/N: the sum of Eq. 5.8 over the modes.
pub fn receptance(modes: &[Mode], freqs_hz: &[f64]) -> Vec<Complex64> {
    freqs_hz.iter().map(|&f| modes.iter().map(|m| m.receptance(TAU * f)).sum()).collect()
}

impl Node for ModalFrf {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        grid(p).map(|_| ())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let freqs = grid(ctx.params)?;
        let mut out = Outputs::new();
        for (port, output, direction) in [("modes_x", "frf_x", "x"), ("modes_y", "frf_y", "y")] {
            let value = match ctx.input(port) {
                Ok(v) => v,
                Err(NodeError::MissingInput { .. }) => continue,
                Err(e) => return Err(e),
            };
            let Value::ModalModel(ModalModel { modes }) = value else {
                return Err(NodeError::input(port, "expected a modal model"));
            };
            // The same checks as every modal kernel: positive frequency and mass, damping in [0, 1).
            let (x, y) = if direction == "x" { (modes.clone(), vec![]) } else { (vec![], modes.clone()) };
            if !modes.is_empty() {
                stability::ModalModel::new(x, y).map_err(|e| NodeError::input(port, e.to_string()))?;
            } else {
                ctx.warn(format!("`{port}` holds no mode: the {direction} direction is rigid, its receptance zero"));
            }
            let frf = Frf {
                freq_hz: freqs.clone(),
                values: receptance(modes, &freqs),
                coherence: None,
                unit: UnitLabel::new("m/N"),
                direction: Some(direction.to_string()),
                speed: None,
                sensor: None,
                dofs: None,
            };
            out.insert(output.to_string(), Value::Frf(frf));
        }
        if out.is_empty() {
            return Err(NodeError::input(
                "modes_x",
                "connect `modes_x` or `modes_y` (or both), e.g. `modes_x: \"@tool.modes_x\"`",
            ));
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nodes::test_support::{empty_recipe, params};
    use indexmap::IndexMap;
    use spindlelab_engine::node::Labelled;
    use std::sync::Arc;

    fn run(yaml: &str, inputs: &[(&str, Vec<Mode>)]) -> Result<(Outputs, Vec<String>), NodeError> {
        let node = ModalFrf::new();
        let p = params(&node, yaml);
        node.validate(&p)?;
        let mut map: IndexMap<String, Vec<Labelled>> = IndexMap::new();
        for (port, modes) in inputs {
            let value = Arc::new(Value::ModalModel(ModalModel { modes: modes.clone() }));
            map.insert(port.to_string(), vec![Labelled { label: String::new(), coords: vec![], value }]);
        }
        let recipe = empty_recipe();
        let entities = recipe.entities_named_by(&p);
        let ctx = NodeContext::new("frf", &p, &map, &entities);
        let out = node.run(&ctx)?;
        Ok((out, ctx.take_warnings()))
    }

    fn frf(out: &Outputs, port: &str) -> Frf {
        match &out[port] {
            Value::Frf(f) => f.clone(),
            other => panic!("{port} is {:?}", other.port_type()),
        }
    }

    /// Validation against the closed form of one mode: |H(ω_n)| = 1/(2kζ), H(0) = 1/k, and the
    /// phase −90° at ω_n.
    #[test]
    fn one_mode_gives_the_closed_form_receptance() {
        let (f_n, zeta, k) = (600.0, 0.04, 2.0e7);
        let mode = Mode::from_stiffness(f_n, zeta, k);
        let (out, warnings) = run("{ max_frequency: 2 kHz, resolution: 0.5 Hz }", &[("modes_x", vec![mode])]).unwrap();
        assert!(warnings.is_empty(), "{warnings:?}");
        assert!(!out.contains_key("frf_y"), "no modes_y, no frf_y");
        let h = frf(&out, "frf_x");
        assert_eq!(h.freq_hz.len(), 4001);
        assert_eq!((h.freq_hz[0], h.freq_hz[4000]), (0.0, 2000.0));
        assert_eq!(h.unit.symbol, "m/N");
        assert_eq!(h.direction.as_deref(), Some("x"));
        let at = |f: f64| h.values[(f / 0.5).round() as usize];
        assert!((at(0.0).re * k - 1.0).abs() < 1e-12 && at(0.0).im == 0.0, "{}", at(0.0));
        let peak = at(f_n);
        assert!(
            (peak.norm() * 2.0 * k * zeta - 1.0).abs() < 1e-12,
            "|H(ω_n)| {} vs {}",
            peak.norm(),
            1.0 / (2.0 * k * zeta)
        );
        assert!((peak.arg().to_degrees() + 90.0).abs() < 1e-9, "{}°", peak.arg().to_degrees());
    }

    /// Two modes along y add; a direction with an empty model is rigid (zero, warned); the grid
    /// starts where it is told.
    #[test]
    fn modes_add_per_direction_and_an_empty_model_is_rigid() {
        let a = Mode { freq_hz: 650.0, damping_ratio: 0.03, modal_mass: 0.3 };
        let b = Mode { freq_hz: 1400.0, damping_ratio: 0.02, modal_mass: 0.5 };
        let (out, warnings) = run(
            "{ min_frequency: 100 Hz, max_frequency: 2 kHz, resolution: 10 Hz }",
            &[("modes_x", vec![]), ("modes_y", vec![a, b])],
        )
        .unwrap();
        let (x, y) = (frf(&out, "frf_x"), frf(&out, "frf_y"));
        assert_eq!(y.freq_hz.first(), Some(&100.0));
        assert_eq!(y.freq_hz.len(), 191);
        assert!(x.values.iter().all(|v| *v == Complex64::new(0.0, 0.0)));
        assert!(warnings.iter().any(|w| w.contains("rigid")), "{warnings:?}");
        for (f, v) in y.freq_hz.iter().zip(&y.values) {
            let w = TAU * f;
            assert!((v - (a.receptance(w) + b.receptance(w))).norm() <= 1e-15 * v.norm());
        }
    }

    #[test]
    fn bad_grids_and_modes_are_named() {
        let mode = Mode { freq_hz: 600.0, damping_ratio: 0.04, modal_mass: 0.4 };
        let m = || vec![("modes_x", vec![mode])];
        let err = |yaml: &str| run(yaml, &m()).unwrap_err().to_string();
        assert!(err("{ max_frequency: 0 Hz }").contains("max_frequency"));
        assert!(err("{ max_frequency: 1 kHz, min_frequency: 2 kHz }").contains("above min_frequency"));
        assert!(err("{ max_frequency: 1 MHz, resolution: 0.001 Hz }").contains("coarsen the resolution"));
        let bad = Mode { damping_ratio: 1.5, ..mode };
        let e = run("{ max_frequency: 1 kHz }", &[("modes_y", vec![bad])]).unwrap_err().to_string();
        assert!(e.contains("modes_y") && e.contains("damping ratio 1.5"), "{e}");
        let none = run("{ max_frequency: 1 kHz }", &[]).unwrap_err().to_string();
        assert!(none.contains("connect `modes_x` or `modes_y`"), "{none}");
    }
}
