//! `stability.sd`: the limiting depth per speed by semi-discretization of modal models.

use super::{CUTTING, DIAMETER, HELIX, PITCH, SPEEDS};
use super::{milling_named, modal, outputs, speeds_rpm, stab_err, with_geometry};
use crate::stability::{self, Bifurcation, SdOptions, StepCount};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Column, Lobes, PortType, Table, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `stability.sd`.
    pub struct SdParams<'a> {
        cutting: req &'a str = CUTTING,
        speeds: req &'a [f64] = SPEEDS,
        max_depth: req f64 = (T::Quantity(D::LENGTH), "largest axial depth scanned"),
        steps: opt usize = (
            T::Integer { min: 2, max: 2000 },
            "time steps per tooth period (default: per speed, at least 50 per shortest natural period, \
             40 to 1000)",
        ),
        scan_points: def usize = (
            T::Integer { min: 2, max: 1000 },
            "40",
            "depths scanned from max_depth/scan_points to max_depth before bisection",
        ),
        tolerance: def f64 = (T::Quantity(D::LENGTH), "0.1 um", "bisection stops below this bracket"),
        map_depths: def usize = (
            T::Integer { min: 0, max: 1000 },
            "0",
            "depths of the map, evenly from max_depth/map_depths to max_depth (0: no map rows)",
        ),
        pitch: opt &'a [f64] = PITCH,
        helix: opt f64 = HELIX,
        diameter: opt f64 = DIAMETER,
    }
}

/// `stability.sd`: the limiting depth per speed by first-order semi-discretization (Insperger & Stépán 2002,
/// 2004) of the tool-point modal models; with `pitch` the multi-delay semi-discretization over the revolution
/// (Sims, Mann & Huyanan 2008), with `helix` the force averaged over the depth.
pub struct StabilitySd {
    spec: NodeSpec,
}

impl Default for StabilitySd {
    fn default() -> Self {
        Self::new()
    }
}

impl StabilitySd {
    pub fn new() -> Self {
        StabilitySd {
            spec: NodeSpec {
                kind: "stability.sd",
                // 3: the chatter frequency is the physical one (the harmonic of the Floquet solution with the
                // largest amplitude), no longer |arg μ|/2π × the tooth frequency folded into [0, f_tooth/2].
                // 4: the table's `kind` is a word (none, Hopf, flip, fold), not a code.
                version: 4,
                description: "Limiting depth per speed by first-order semi-discretization (Insperger & Stépán) of tool-point modal models in x (feed) and y, with the kind of chatter (Hopf or flip); spectral radii on a speed × depth grid. Variable tooth pitch (one delay per tooth over the revolution) and helical flutes (force averaged over the depth) optional.",
                inputs: vec![
                    PortSpec::new("modes_x", PortType::ModalModel, "tool-point modes along x, the feed direction"),
                    PortSpec::new("modes_y", PortType::ModalModel, "tool-point modes along y"),
                ],
                outputs: vec![
                    PortSpec::new(
                        "lobes",
                        PortType::Lobes,
                        "lowest unstable depth per speed (m; +∞ if stable up to max_depth) and the chatter frequency \
                         (Hz): of the frequencies ±arg μ/(2πτ) + k/τ the dominant multiplier μ allows, the one the \
                         tool vibrates at most, as a time-domain simulation and the ZOA find it",
                    ),
                    PortSpec::new(
                        "table",
                        PortType::Table,
                        "speed (rpm), depth_limit (m), chatter_frequency (Hz), kind (the bifurcation at the limit, as a word: none, Hopf, flip or fold; \
                         of the revolution map with unequal pitch), restabilises (1 if a larger scanned depth is stable again), steps (per \
                         (mean) tooth period used)",
                    ),
                    PortSpec::new(
                        "map",
                        PortType::Table,
                        "speed (rpm), depth (m), spectral_radius (stable below 1) on speeds × map_depths",
                    ),
                ],
                params: SdParams::fields(),
            },
        }
    }
}

impl Node for StabilitySd {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = SdParams::read(params)?;
        super::positive(params, &["max_depth", "tolerance", "diameter"])?;
        if p.helix.is_some_and(|h| h != 0.0) && p.diameter.is_none() {
            return Err(NodeError::param("diameter", "give the tool diameter with `helix` (e.g. `diameter: 12 mm`)"));
        }
        speeds_rpm(p.speeds).map(|_| ())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = SdParams::read(ctx.params)?;
        let model = stability::ModalModel::new(modal(ctx, "modes_x")?, modal(ctx, "modes_y")?)
            .map_err(|e| stab_err(e, "modes_x"))?;
        if model.x.is_empty() && model.y.is_empty() {
            return Err(NodeError::input("modes_x", "neither modes_x nor modes_y holds a mode: nothing can chatter"));
        }
        let mill = with_geometry(milling_named(ctx, p.cutting)?, p.pitch, p.helix, p.diameter)?;
        let speeds = speeds_rpm(p.speeds)?;
        let max_depth = p.max_depth;
        let opts = SdOptions {
            steps: p.steps.map_or(StepCount::AUTO, StepCount::Fixed),
            scan_points: p.scan_points,
            depth_tolerance_m: p.tolerance,
        };
        let limits =
            stability::sd_depth_limits(&model, &mill, &speeds, max_depth, &opts).map_err(|e| stab_err(e, "modes_x"))?;
        let chatter: Vec<f64> = limits.iter().map(|d| if d.kind.is_some() { d.chatter_hz } else { 0.0 }).collect();
        let unlimited = limits.iter().filter(|d| d.depth_m.is_infinite()).count();
        if unlimited > 0 {
            ctx.warn(format!(
                "{unlimited} of {} speeds are stable up to max_depth {max_depth} m; their limit is +∞",
                limits.len()
            ));
        }
        let kind = |d: &stability::DepthLimit| match d.kind {
            None => "none",
            Some(Bifurcation::Hopf) => "Hopf",
            Some(Bifurcation::Flip) => "flip",
            Some(Bifurcation::Fold) => "fold",
        };
        let kinds: Vec<&str> = limits.iter().map(kind).collect();
        let depth: Vec<f64> = limits.iter().map(|d| d.depth_m).collect();
        let table = Table {
            columns: vec![
                Column::new("speed", "rpm", speeds.clone()),
                Column::new("depth_limit", "m", depth.clone()),
                Column::new("chatter_frequency", "Hz", chatter.clone()),
                Column::text("kind", &kinds),
                Column::new("restabilises", "", limits.iter().map(|d| f64::from(u8::from(d.restabilises))).collect()),
                Column::new("steps", "", limits.iter().map(|d| d.steps as f64).collect()),
            ],
        };
        let n = p.map_depths;
        let depths: Vec<f64> = (1..=n).map(|i| max_depth * i as f64 / n as f64).collect();
        let (mut ms, mut md, mut mr) = (Vec::new(), Vec::new(), Vec::new());
        if n > 0 {
            let map = stability::sd_stability_map(&model, &mill, &speeds, &depths, &opts)
                .map_err(|e| stab_err(e, "modes_x"))?;
            for (i, s) in map.speeds_rpm.iter().enumerate() {
                for (j, b) in map.depths_m.iter().enumerate() {
                    ms.push(*s);
                    md.push(*b);
                    mr.push(map.radius(i, j));
                }
            }
        }
        let map = Table {
            columns: vec![
                Column::new("speed", "rpm", ms),
                Column::new("depth", "m", md),
                Column::new("spectral_radius", "", mr),
            ],
        };
        let lobes = Lobes::from_rpm(&speeds, depth, chatter);
        Ok(outputs(vec![("lobes", Value::Lobes(lobes)), ("table", Value::Table(table)), ("map", Value::Table(map))]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stability::{CuttingCoefficients, Milling, MillingDirection, Mode};
    use indexmap::IndexMap;
    use spindlelab_engine::model::Recipe;
    use spindlelab_engine::node::Labelled;
    use spindlelab_engine::value::ModalModel;
    use std::sync::Arc;

    /// A four-flute slot and the step `step` of kind `kind` with `params`, resolved; `stability.lobes` gets the
    /// FRFs of the modes, every other kind the modes.
    fn recipe(kind: &str, params: &str) -> Result<Recipe, String> {
        let inputs = if kind == "stability.lobes" {
            "{ frf_x: \"@frf.frf_x\", frf_y: \"@frf.frf_y\" }"
        } else {
            "{ modes_x: \"@modes.modes_x\", modes_y: \"@modes.modes_y\" }"
        };
        let text = format!(
            "spindlelab: 1\ncutting:\n  slot: {{ teeth: 4, radial_immersion: 100 %, milling: down, Kt: 600 MPa, Kn: 200 MPa }}\n\
             steps:\n  modes: {{ kind: modal.model, params: {{ x: [{{ f: 1 kHz, zeta: 0.02, stiffness: 2e7 N/m }}] }} }}\n  \
             frf: {{ kind: modal.frf, inputs: {{ modes_x: \"@modes.modes_x\", modes_y: \"@modes.modes_y\" }}, params: {{ max_frequency: 3 kHz }} }}\n  \
             step:\n    kind: {kind}\n    params: {{ {params} }}\n    inputs: {inputs}\n"
        );
        crate::nodes::test_support::resolve_text(&text)
    }

    fn modes() -> (Vec<Mode>, Vec<Mode>) {
        (
            vec![Mode { freq_hz: 600.0, damping_ratio: 0.04, modal_mass: 0.4 }],
            vec![Mode { freq_hz: 650.0, damping_ratio: 0.03, modal_mass: 0.3 }],
        )
    }

    /// Runs `stability.sd` with `params` on the modes of [`modes`]: the table.
    fn run(params: &str) -> Result<Table, NodeError> {
        let r = recipe("stability.sd", params).map_err(NodeError::Failed)?;
        let params = r.step("step").unwrap().params.clone();
        let entities = r.entities_named_by(&params);
        let (x, y) = modes();
        let mut inputs: IndexMap<String, Vec<Labelled>> = IndexMap::new();
        for (port, m) in [("modes_x", x), ("modes_y", y)] {
            let value = Arc::new(Value::ModalModel(ModalModel { modes: m }));
            inputs.insert(port.into(), vec![Labelled { label: String::new(), coords: vec![], value }]);
        }
        let node = StabilitySd::new();
        node.validate(&params)?;
        let ctx = NodeContext::new("step", &params, &inputs, &entities);
        let out = node.run(&ctx)?;
        let Value::Table(t) = &out["table"] else { panic!("no table") };
        Ok(t.clone())
    }

    /// `pitch` (deg) and `helix` with `diameter` reach the kernel: the node's limits are the kernel's on the same
    /// tool; a pitch of the wrong count, a helix without diameter and an unequal pitch on `stability.lobes` are
    /// refused with the parameter named.
    #[test]
    fn pitch_and_helix_reach_the_semi_discretization() {
        let base = "cutting: slot, speeds: [6000 rpm, 9000 rpm], max_depth: 5 mm, steps: 40";
        let t =
            run(&format!("{base}, pitch: [70 deg, 110 deg, 70 deg, 110 deg], helix: 30 deg, diameter: 12 mm")).unwrap();
        let mill = Milling::new(4, 1.0, MillingDirection::Down, CuttingCoefficients::from_kt_kn(6e8, 2e8).unwrap())
            .unwrap()
            .with_pitch_deg(&[70.0, 110.0, 70.0, 110.0])
            .unwrap()
            .with_helix(30f64.to_radians(), 0.012)
            .unwrap();
        let (x, y) = modes();
        let model = stability::ModalModel::new(x, y).unwrap();
        let opts = SdOptions { steps: StepCount::Fixed(40), scan_points: 40, depth_tolerance_m: 1e-7 };
        let kernel = stability::sd_depth_limits(&model, &mill, &[6000.0, 9000.0], 5e-3, &opts).unwrap();
        for (a, k) in t.columns[1].values.iter().zip(&kernel) {
            assert!((a / k.depth_m - 1.0).abs() < 1e-12, "{a} vs {}", k.depth_m);
        }
        let plain = run(base).unwrap();
        assert_ne!(plain.columns[1].values, t.columns[1].values);

        let e = run(&format!("{base}, pitch: [90 deg, 90 deg, 180 deg]")).unwrap_err().to_string();
        assert!(e.contains("pitch") && e.contains("4 teeth"), "{e}");
        let e = run(&format!("{base}, helix: 30 deg")).unwrap_err().to_string();
        assert!(e.contains("diameter"), "{e}");
        let e = run(&format!("{base}, helix: 95 deg, diameter: 12 mm")).unwrap_err().to_string();
        assert!(e.contains("helix"), "{e}");

        let e =
            recipe("stability.lobes", "cutting: slot, speeds: [6000 rpm], pitch: [70 deg, 110 deg, 70 deg, 110 deg]")
                .unwrap_err();
        assert!(e.contains("pitch") && e.contains("use stability.sd"), "{e}");
        let r = recipe("stability.lobes", "cutting: slot, speeds: [6000 rpm], pitch: [90 deg, 90 deg, 90 deg, 90 deg]")
            .unwrap();
        super::super::StabilityLobes::new().validate(&r.step("step").unwrap().params).unwrap();
    }
}
