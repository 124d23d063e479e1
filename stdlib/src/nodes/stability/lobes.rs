//! `stability.lobes`: the ZOA stability limit on tool-point FRFs, optionally with process damping at low speed.

use super::{CUTTING, LOBES, PROCESS_DAMPING, RESOLUTION, SPEEDS, process_damping};
use super::{
    lobes_value, milling_named, outputs, receptance, speeds_rpm, stab_err, warn_lobes_short, warn_unlimited,
    with_geometry,
};
use crate::stability::{
    self, ProcessDampingFormulation, ProcessDampingOptions, StabilityLimit, ToolPointFrf, ZoaOptions,
};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Column, PortType, Table, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `stability.lobes`.
    pub struct LobesParams<'a> {
        cutting: req &'a str = CUTTING,
        speeds: req &'a [f64] = SPEEDS,
        lobes: opt usize = LOBES,
        resolution: def f64 = RESOLUTION,
        pitch: opt &'a [f64] = (
            T::QuantityList(D::ANGLE),
            "tooth pitch, one angle per tooth: only equal pitch is accepted here (the ZOA has one delay); unequal pitch is refused, stability.sd gives each tooth its own delay",
        ),
        process_damping: opt &'a Params = (
            T::Object(PROCESS_DAMPING),
            "process damping at low speed (Tyler & Schmitz 2013): `{ indentation, wear_land, diameter }`; the flank rubbing the wavy surface adds the damping C b/V along the surface normal, C = K_d w²/4, V = π D n/60, and the limit becomes the fixed point b = b_lim(C b/V) at each speed; the table then also gives the limit without it"
        ),
        process_damping_formulation: opt &'a str = (
            T::Choice(&["arc_average", "average_tooth_angle"]),
            "with `process_damping`: `arc_average` (the default) is the coupled ZOA with the damping averaged over the engaged arc; `average_tooth_angle` is Tlusty's average tooth angle with diagonal damping, as the Schmitz & Smith textbook's converging analysis applies it (about twice the coupled limit for a half-immersion cut: docs/stability.md)"
        ),
    }
}

/// `stability.lobes`: the ZOA stability limit (Altintas & Budak 1995) from tool-point FRFs in x and y.
///
/// Equally spaced teeth only: a `pitch` that is not equal is refused (use `stability.sd`). There is no helix
/// parameter: the ZOA uses the force averaged over the revolution, which the helix does not change, so its limit
/// is the straight tooth's (`stability.sd` takes the helix).
pub struct StabilityLobes {
    spec: NodeSpec,
}

impl Default for StabilityLobes {
    fn default() -> Self {
        Self::new()
    }
}

impl StabilityLobes {
    pub fn new() -> Self {
        StabilityLobes {
            spec: NodeSpec {
                kind: "stability.lobes",
                version: 1,
                description: "Stability lobes by the zero-order approximation (Altintas & Budak 1995) from tool-point FRFs in x (feed) and y: limiting depth and chatter frequency over speed, optionally with process damping at low speed.",
                inputs: vec![
                    PortSpec::new("frf_x", PortType::Frf, "tool-point receptance along x, the feed direction (m/N)"),
                    PortSpec::new("frf_y", PortType::Frf, "tool-point receptance along y, on the grid of frf_x (m/N)"),
                ],
                outputs: vec![
                    PortSpec::new("lobes", PortType::Lobes, "lowest lobe through each speed: depth (m), chatter (Hz)"),
                    PortSpec::new(
                        "table",
                        PortType::Table,
                        "speed (rpm), depth_limit (m), chatter_frequency (Hz), lobe k (−1 where none limits); with process_damping also depth_limit_without_process_damping (m)",
                    ),
                ],
                params: LobesParams::fields(),
            },
        }
    }
}

/// The refusal of unequal pitch: the ZOA has one delay, the tooth period.
fn unequal_pitch() -> NodeError {
    NodeError::param(
        "pitch",
        "stability.lobes (the zero-order approximation) assumes equally spaced teeth, one regenerative delay; for \
         unequal pitch use stability.sd, whose semi-discretization gives every tooth its own delay",
    )
}

/// `a–b rpm`, or `a rpm` for one speed.
fn span(speeds: &[f64]) -> String {
    match (speeds.first(), speeds.last()) {
        (Some(a), Some(b)) if a != b => format!("{a}–{b} rpm"),
        (Some(a), _) => format!("{a} rpm"),
        _ => String::new(),
    }
}

/// Warns about the speeds where process damping leaves no finite limit, and where the search did not converge.
fn warn_process_damping(ctx: &NodeContext, with: &StabilityLimit, without: &StabilityLimit, converged: &[bool]) {
    let open: Vec<f64> = with
        .speed_rpm
        .iter()
        .zip(with.depth_m.iter().zip(&without.depth_m))
        .filter(|(_, (d, w))| d.is_infinite() && w.is_finite())
        .map(|(s, _)| *s)
        .collect();
    if !open.is_empty() {
        ctx.warn(format!(
            "process damping: at {} of {} speeds ({}) the damping grows with the depth faster than \
             the depth it must stabilise, so the linear model gives no finite limit below {} m (+∞); the real limit \
             there is set by what it leaves out (tool length, power, nonlinear contact)",
            open.len(),
            with.speed_rpm.len(),
            span(&open),
            ProcessDampingOptions::default().max_depth_m
        ));
    }
    let slow: Vec<f64> = with.speed_rpm.iter().zip(converged).filter(|(_, c)| !**c).map(|(s, _)| *s).collect();
    if !slow.is_empty() {
        ctx.warn(format!(
            "process damping: the fixed point was not reached at {} speeds ({}); their limit is the last depth found \
             below it",
            slow.len(),
            span(&slow)
        ));
    }
}

impl Node for StabilityLobes {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = LobesParams::read(params)?;
        super::positive(params, &["resolution"])?;
        if let Some(pitch) = p.pitch
            && pitch.iter().any(|a| (a - pitch[0]).abs() > 1e-9)
        {
            return Err(unequal_pitch());
        }
        if let Some(pd) = p.process_damping {
            process_damping(pd)?;
        }
        if p.process_damping.is_none() && p.process_damping_formulation.is_some() {
            return Err(NodeError::param(
                "process_damping_formulation",
                "is given without `process_damping`: give the flank contact too, or leave the formulation out",
            ));
        }
        speeds_rpm(p.speeds).map(|_| ())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = LobesParams::read(ctx.params)?;
        let (fx, fy) = (receptance(ctx, "frf_x")?, receptance(ctx, "frf_y")?);
        let mill = with_geometry(milling_named(ctx, p.cutting)?, p.pitch, None, None)?;
        if !mill.has_equal_pitch() {
            return Err(unequal_pitch());
        }
        let frf = ToolPointFrf::from_pair(&fx.freq_hz, fx.values.clone(), &fy.freq_hz, fy.values.clone())
            .map_err(|e| stab_err(e, "frf_y"))?;
        let opts = ZoaOptions {
            lobes: p.lobes,
            speeds_rpm: speeds_rpm(p.speeds)?,
            keep_lobes: false,
            resolution_hz: Some(p.resolution),
        };
        if let Some(pd) = p.process_damping {
            let pd = process_damping(pd)?;
            let formulation = match p.process_damping_formulation {
                Some("average_tooth_angle") => ProcessDampingFormulation::AverageToothAngle,
                _ => ProcessDampingFormulation::ArcAverage,
            };
            let pd_opts = ProcessDampingOptions { formulation, ..ProcessDampingOptions::default() };
            let r = stability::zoa_lobes_with_process_damping(&frf, &mill, &pd, &opts, &pd_opts)
                .map_err(|e| stab_err(e, "frf_x"))?;
            warn_lobes_short(ctx, r.lobe_count, r.lobes_needed, r.band_top_hz, mill.teeth, opts.speeds_rpm[0]);
            warn_unlimited(ctx, "lobes without process damping", &r.without);
            warn_process_damping(ctx, &r.limit, &r.without, &r.converged);
            let mut table = limit_table(&r.limit);
            table.columns.push(Column::new("depth_limit_without_process_damping", "m", r.without.depth_m.clone()));
            return Ok(outputs(vec![("lobes", Value::Lobes(lobes_value(&r.limit))), ("table", Value::Table(table))]));
        }
        let z = stability::zoa_lobes(&frf, &mill, &opts).map_err(|e| stab_err(e, "frf_x"))?;
        warn_lobes_short(ctx, z.lobe_count, z.lobes_needed, z.band_top_hz, mill.teeth, opts.speeds_rpm[0]);
        warn_unlimited(ctx, "lobes", &z.limit);
        let l = &z.limit;
        Ok(outputs(vec![("lobes", Value::Lobes(lobes_value(l))), ("table", Value::Table(limit_table(l)))]))
    }
}

/// The table of a limit: speed, depth, chatter frequency and lobe number (−1 where none limits).
fn limit_table(l: &StabilityLimit) -> Table {
    Table {
        columns: vec![
            Column::new("speed", "rpm", l.speed_rpm.clone()),
            Column::new("depth_limit", "m", l.depth_m.clone()),
            Column::new("chatter_frequency", "Hz", l.chatter_hz.clone()),
            Column::new("lobe", "", l.lobe.iter().map(|k| k.map_or(-1.0, |k| k as f64)).collect()),
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stability::Milling;
    use indexmap::IndexMap;
    use num_complex::Complex64;
    use spindlelab_engine::model::Recipe;
    use spindlelab_engine::node::Labelled;
    use spindlelab_engine::value::{Frf, UnitLabel};
    use std::sync::Arc;

    const PD: &str = "process_damping: { indentation: 30000 N/mm^3, wear_land: 0.05 mm, diameter: 10 mm }";

    /// The recipe of a four-tooth slot with `lobes_params` for the `stability.lobes` step, resolved.
    fn recipe(lobes_params: &str) -> Result<Recipe, String> {
        let text = format!(
            "spindlelab: 1\ncutting:\n  \
             slot: {{ teeth: 4, radial_immersion: 100 %, milling: down, Kt: 600 MPa, Kn: 200 MPa }}\nsteps:\n  \
             modes: {{ kind: modal.model, params: {{ x: [{{ f: 1 kHz, zeta: 0.02, stiffness: 2e7 N/m }}] }} }}\n  \
             frf:\n    kind: modal.frf\n    params: {{ max_frequency: 3 kHz }}\n    \
             inputs: {{ modes_x: \"@modes.modes_x\", modes_y: \"@modes.modes_y\" }}\n  \
             lobes:\n    kind: stability.lobes\n    params: {{ {lobes_params} }}\n    \
             inputs: {{ frf_x: \"@frf.frf_x\", frf_y: \"@frf.frf_y\" }}\n"
        );
        crate::nodes::test_support::resolve_text(&text)
    }

    fn frf(freqs: &[f64], values: Vec<Complex64>, direction: &str) -> Arc<Value> {
        Arc::new(Value::Frf(Frf {
            freq_hz: freqs.to_vec(),
            values,
            coherence: None,
            unit: UnitLabel::new("m/N"),
            direction: Some(direction.into()),
            speed: None,
            sensor: None,
            dofs: None,
        }))
    }

    /// Runs the step `lobes` of the recipe on one mode along x (1 kHz, ζ = 0.02, 20 N/µm), y rigid.
    fn run(lobes_params: &str) -> (Table, Vec<String>, ToolPointFrf, Params) {
        let r = recipe(lobes_params).unwrap();
        let params = r.step("lobes").unwrap().params.clone();
        let entities = r.entities_named_by(&params);
        let freqs: Vec<f64> = (1..=6000).map(|i| 0.5 * i as f64).collect();
        let x: Vec<Complex64> =
            freqs.iter().map(|f| 1.0 / (2e7 * Complex64::new(1.0 - (f / 1e3).powi(2), 0.04 * f / 1e3))).collect();
        let y = vec![Complex64::new(0.0, 0.0); freqs.len()];
        let tool = ToolPointFrf::new(freqs.clone(), x.clone(), y.clone()).unwrap();
        let mut inputs: IndexMap<String, Vec<Labelled>> = IndexMap::new();
        for (port, v) in [("frf_x", frf(&freqs, x, "x")), ("frf_y", frf(&freqs, y, "y"))] {
            inputs.insert(port.into(), vec![Labelled { label: String::new(), coords: vec![], value: v }]);
        }
        let node = StabilityLobes::new();
        node.validate(&params).unwrap();
        let ctx = NodeContext::new("lobes", &params, &inputs, &entities);
        let out = node.run(&ctx).unwrap();
        let Value::Table(t) = out["table"].clone() else { panic!("no table") };
        let Value::Lobes(l) = &out["lobes"] else { panic!("no lobes") };
        assert_eq!(l.depth_limit, t.columns[1].values);
        (t, ctx.take_warnings(), tool, params)
    }

    fn names(t: &Table) -> Vec<(&str, &str)> {
        t.columns.iter().map(|c| (c.name.as_str(), c.unit.symbol.as_str())).collect()
    }

    /// Without `process_damping` the table keeps its four columns and the kernel's numbers; with it the limit is the
    /// kernel's fixed point, above the undamped limit, which the fifth column gives. `30000 N/mm^3` is read in SI.
    #[test]
    fn process_damping_adds_the_fixed_point_limit_and_keeps_the_plain_table() {
        let speeds = "speeds: \"[1000, 2000, 3000, 6000] rpm\"";
        let (plain, _, tool, _) = run(&format!("cutting: slot, {speeds}"));
        let four = [("speed", "rpm"), ("depth_limit", "m"), ("chatter_frequency", "Hz"), ("lobe", "")];
        assert_eq!(names(&plain), four);
        let mill = Milling::new(
            4,
            1.0,
            stability::MillingDirection::Down,
            stability::CuttingCoefficients::from_kt_kn(6e8, 2e8).unwrap(),
        )
        .unwrap();
        let opts = ZoaOptions {
            lobes: None,
            speeds_rpm: vec![1000.0, 2000.0, 3000.0, 6000.0],
            keep_lobes: false,
            ..ZoaOptions::default()
        };
        let z = stability::zoa_lobes(&tool, &mill, &opts).unwrap();
        assert_eq!(plain.columns[1].values, z.limit.depth_m);

        let (damped, warnings, _, params) = run(&format!("cutting: slot, {speeds}, {PD}"));
        let pd = params.object("process_damping").unwrap();
        assert!((pd.f64("indentation").unwrap() / 3e13 - 1.0).abs() < 1e-12);
        assert!((pd.f64("wear_land").unwrap() / 5e-5 - 1.0).abs() < 1e-12);
        let mut five = four.to_vec();
        five.push(("depth_limit_without_process_damping", "m"));
        assert_eq!(names(&damped), five);
        let contact = crate::stability::ProcessDamping::new(3e13, 5e-5, 0.01).unwrap();
        let k = stability::zoa_lobes_with_process_damping(&tool, &mill, &contact, &opts, &Default::default()).unwrap();
        assert_eq!(damped.columns[1].values, k.limit.depth_m);
        assert_eq!(damped.columns[2].values, k.limit.chatter_hz);
        for (a, b) in damped.columns[4].values.iter().zip(&z.limit.depth_m) {
            assert!((a - b).abs() <= 1e-9 * b, "{a} vs {b}");
        }
        for (a, b) in damped.columns[1].values.iter().zip(&damped.columns[4].values) {
            assert!(a >= b, "{a} below {b}");
        }
        assert!(damped.columns[1].values[1] > 2.0 * damped.columns[4].values[1]);
        // At 1000 rpm the damping outgrows the depth: no finite limit, and a warning says so.
        assert!(damped.columns[1].values[0].is_infinite());
        assert!(
            warnings.iter().any(|w| w.contains("process damping") && w.contains("at 1 of 4 speeds (1000 rpm)")),
            "{warnings:?}"
        );
    }

    /// The three fields go together: a missing one is named by the recipe check, and the node refuses a value
    /// out of range with the parameter's name.
    #[test]
    fn process_damping_fields_are_checked() {
        let with = |pd: &str| recipe(&format!("cutting: slot, speeds: 2000 rpm, process_damping: {{ {pd} }}"));
        let e = with("indentation: 30000 N/mm^3, wear_land: 0.05 mm").unwrap_err();
        assert!(e.contains("diameter"), "{e}");
        let e = with("indentation: 30 MPa, wear_land: 0.05 mm, diameter: 10 mm").unwrap_err();
        assert!(e.contains("indentation"), "{e}");
        let e = with("indentation: 30000 N/mm^3, wear_land: 0 mm, diameter: 10 mm").unwrap_err();
        assert!(e.contains("process_damping") && e.contains("`wear_land` must be positive"), "{e}");
        let e =
            recipe("cutting: slot, speeds: 2000 rpm, process_damping_formulation: average_tooth_angle").unwrap_err();
        assert!(e.contains("process_damping_formulation") && e.contains("without `process_damping`"), "{e}");
    }
}
