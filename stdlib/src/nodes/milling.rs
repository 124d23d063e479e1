//! `milling.simulate`: the time-domain milling simulation ([`crate::milling`]) as a node.

use super::stability::{
    COEFFICIENT_ROW, CUTTING, DIAMETER, HELIX, PITCH, PROCESS_DAMPING, coefficient_table, milling, modal, pairs,
    process_damping, read_trials, with_geometry,
};
use crate::milling::{MillingSimulation, simulate};
use crate::stability::{self, SpeedFrf, Trial};
use spindlelab_domain::Speed;
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Channel, Column, PortType, Scalar, Table, TimeSeries, UnitLabel, Value};
use spindlelab_grammar::Dimension as D;
use std::path::Path;

node_params! {
    /// Parameters of `milling.simulate`.
    pub struct MillingSimulateParams<'a> {
        cutting: req &'a str = CUTTING,
        speed: req f64 = (T::Quantity(D::ROTATIONAL_SPEED), "spindle speed"),
        depth: req f64 = (T::Quantity(D::LENGTH), "axial depth of cut"),
        feed_per_tooth: opt f64 = (
            T::Quantity(D::LENGTH),
            "feed per tooth (default: the cutting setup's `feed_per_tooth`)",
        ),
        revolutions: def usize = (T::Integer { min: 2, max: 100_000 }, "100", "length of the simulation"),
        steps_per_tooth: opt usize = (
            T::Integer { min: 8, max: 100_000 },
            "time steps per tooth period (default: at least 100 and 20 per period of the highest mode)",
        ),
        runout: opt &'a [f64] = (
            T::QuantityList(D::LENGTH),
            "radial runout of each tooth, one value per tooth (e.g. `[10, 0, 0, 0] um`)",
        ),
        pitch: opt &'a [f64] = PITCH,
        helix: opt f64 = HELIX,
        diameter: opt f64 = DIAMETER,
        process_damping: opt &'a Params = (
            T::Object(PROCESS_DAMPING),
            "process damping at low speed (Tyler & Schmitz 2013): `{ indentation, wear_land, diameter }`; every tooth \
             (every helix slice) in the cut adds the viscous force −(C a/V)(r·v) r of its flank rubbing the wavy \
             surface, along its surface normal r, C = K_d w²/4, V = π D n/60, a its axial length, v the tool velocity: \
             the model of stability.lobes' `process_damping`",
        ),
    }
}

pub struct MillingSimulate {
    spec: NodeSpec,
}

impl Default for MillingSimulate {
    fn default() -> Self {
        Self::new()
    }
}

impl MillingSimulate {
    pub fn new() -> Self {
        MillingSimulate {
            spec: NodeSpec {
                kind: "milling.simulate",
                version: 1,
                description: "Time-domain milling simulation (Schmitz & Smith): regenerative chip thickness by the tooth path, \
                              teeth with the lobes' force model, tool-point modes in x (feed) and y advanced exactly \
                              per step, optional runout, variable pitch (each tooth at its angle, cutting the feed of its \
                              pitch) and helix (axial slices at most 1° of lag apart, each on its own tooth path), optional \
                              process damping at low speed (the flank's viscous force along each cutting edge's normal); stable \
                              or chatter by once-per-period sampling, the chatter frequency and the surface location error. \
                              Sweep speed and depth for a stability map.",
                inputs: vec![
                    PortSpec::new("modes_x", PortType::ModalModel, "tool-point modes along x, the feed direction"),
                    PortSpec::new("modes_y", PortType::ModalModel, "tool-point modes along y"),
                ],
                outputs: vec![
                    PortSpec::new(
                        "signals",
                        PortType::TimeSeries,
                        "force_x, force_y (N, on the tool) and x, y (m, tool displacement) at every step",
                    ),
                    PortSpec::new(
                        "samples",
                        PortType::TimeSeries,
                        "x and y once per tooth period (with unequal pitch once per period of the pitch pattern, once per \
                         revolution with runout): still in a stable cut",
                    ),
                    PortSpec::new(
                        "summary",
                        PortType::Table,
                        "speed (rpm), depth (m), stable (1 or 0), chatter_metric (sample spread over motion spread, to 0.001), \
                         chatter_frequency (Hz, 0 when stable), surface_location_error (m), steps (per tooth period)",
                    ),
                    PortSpec::new(
                        "surface_location_error",
                        PortType::Scalar,
                        "y of the tool as a tooth passes the finished wall, steady state (m; + towards +y)",
                    ),
                ],
                params: MillingSimulateParams::fields(),
            },
        }
    }
}

impl Node for MillingSimulate {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = MillingSimulateParams::read(params)?;
        if let Some(pd) = p.process_damping {
            process_damping(pd)?;
        }
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = MillingSimulateParams::read(ctx.params)?;
        let modes = stability::ModalModel::new(modal(ctx, "modes_x")?, modal(ctx, "modes_y")?)
            .map_err(|e| NodeError::input("modes_x", e.to_string()))?;
        let speed_rpm = Speed::from_rad_s(p.speed).rpm();
        let sim = MillingSimulation {
            cut: with_geometry(milling(ctx)?, p.pitch, p.helix, p.diameter)?,
            depth: p.depth,
            feed_per_tooth: feed_per_tooth(ctx, p.feed_per_tooth, p.cutting)?,
            speed_rpm,
            modes,
            runout: p.runout.map(<[f64]>::to_vec).unwrap_or_default(),
            revolutions: p.revolutions,
            steps_per_tooth: p.steps_per_tooth,
            process_damping: p.process_damping.map(process_damping).transpose()?,
        };
        let r = simulate(&sim).map_err(|e| match e {
            crate::milling::MillingError::Runout { .. } => NodeError::param("runout", e.to_string()),
            other => NodeError::Failed(other.to_string()),
        })?;
        let channel = |name: &str, unit: &str, samples: Vec<f64>| Channel {
            name: name.into(),
            unit: UnitLabel::new(unit),
            samples,
        };
        let signals = TimeSeries {
            sample_rate: 1.0 / r.dt,
            t0: 0.0,
            channels: vec![
                channel("force_x", "N", r.force_x),
                channel("force_y", "N", r.force_y),
                channel("x", "m", r.disp_x),
                channel("y", "m", r.disp_y),
            ],
        };
        let samples = TimeSeries {
            sample_rate: 1.0 / r.sample_period,
            t0: r.sample_period - r.dt,
            channels: vec![channel("x", "m", r.samples_x), channel("y", "m", r.samples_y)],
        };
        if !r.stable {
            ctx.warn(format!(
                "chatter at {speed_rpm:.0} rpm and {:.3} mm: once-per-period samples spread {:.2} of the motion",
                sim.depth * 1e3,
                r.chatter_metric
            ));
        }
        let summary = Table {
            columns: vec![
                Column::new("speed", "rpm", vec![speed_rpm]),
                Column::new("depth", "m", vec![sim.depth]),
                Column::new("stable", "", vec![if r.stable { 1.0 } else { 0.0 }]),
                // A ratio of order 1 in chatter: three decimals say all there is; below that a
                // stable cut shows only roundoff and leftover transient.
                Column::new("chatter_metric", "", vec![(r.chatter_metric * 1e3).round() / 1e3]),
                Column::new("chatter_frequency", "Hz", vec![r.chatter_frequency_hz.unwrap_or(0.0)]),
                Column::new("surface_location_error", "m", vec![r.surface_location_error]),
                Column::new("steps", "", vec![r.steps_per_tooth as f64]),
            ],
        };
        let mut out = Outputs::new();
        out.insert("signals".into(), Value::TimeSeries(signals));
        out.insert("samples".into(), Value::TimeSeries(samples));
        out.insert("summary".into(), Value::Table(summary));
        out.insert(
            "surface_location_error".into(),
            Value::Scalar(Scalar { value: r.surface_location_error, unit: UnitLabel::new("m") }),
        );
        Ok(out)
    }
}

/// The feed per tooth: the node's parameter `given`, else that of the cutting setup `name`.
fn feed_per_tooth(ctx: &NodeContext, given: Option<f64>, name: &str) -> Result<f64, NodeError> {
    if let Some(f) = given {
        return Ok(f);
    }
    ctx.entities.cutting.get(name).and_then(|c| c.feed_per_tooth).ok_or_else(|| {
        NodeError::param(
            "feed_per_tooth",
            format!("give `feed_per_tooth`, here or in the cutting setup `{name}` (e.g. `feed_per_tooth: 0.05 mm`)"),
        )
    })
}

// ------------------------------------------------------------------ trials.simulate

/// `trials.simulate`: each cutting trial of a file simulated in the time domain on tool-point
/// dynamics interpolated at its speed, as the independent check of a speed-dependent diagram
/// (§6.4): the FRFs and coefficients are the same splines in speed as `stability.speed_dependent`
/// uses, the modes in x and y are fitted to the FRFs at the trial's speed (§5.2), and
/// `milling.simulate` gives the verdict.
pub struct TrialsSimulate {
    spec: NodeSpec,
}

impl Default for TrialsSimulate {
    fn default() -> Self {
        Self::new()
    }
}

impl TrialsSimulate {
    pub fn new() -> Self {
        TrialsSimulate {
            spec: NodeSpec {
                kind: "trials.simulate",
                version: 1,
                description: "Cutting trials (CSV rpm,depth_mm,outcome) simulated in the time domain: tool-point FRFs and \
                              cutting coefficients spline-interpolated at each trial's speed as stability.speed_dependent \
                              does, modes fitted in x and y (§5.2), then milling.simulate at the trial's depth; the \
                              simulated verdict next to the recorded one.",
                inputs: vec![
                    PortSpec::new(
                        "frfs",
                        PortType::Frf,
                        "tool-point receptances (m/N) at several speeds, x and y, as their direction and speed_rpm say",
                    )
                    .collecting(),
                ],
                outputs: vec![
                    PortSpec::new(
                        "verdicts",
                        PortType::Table,
                        "per trial: speed (rpm), depth (m), outcome (recorded) and simulated (0 stable, 1 chatter; \
                         −1 outside the FRFs' speeds), agrees (0/1, −1 outside), chatter_metric, chatter_frequency (Hz, 0 when stable), modes_x and modes_y \
                         (modes fitted)",
                    ),
                    PortSpec::new(
                        "agreement",
                        PortType::Scalar,
                        "fraction of the simulated trials whose recorded outcome the simulation gives",
                    ),
                ],
                params: TrialsSimulateParams::fields(),
            },
        }
    }
}

node_params! {
    /// Parameters of `trials.simulate`.
    pub struct TrialsSimulateParams<'a> {
        cutting: req &'a str = CUTTING,
        file: req &'a Path = (T::File, "trials CSV `rpm,depth_mm,outcome[,chatter_freq_hz]`"),
        coefficients: opt &'a [Params] = (
            T::ObjectList(COEFFICIENT_ROW),
            "cutting coefficients over speed, rows {speed, Ks, beta} or {speed, Kt, Kn}, cubic in speed \
             (default: the cutting setup's)",
        ),
        min_frequency: def f64 = (T::Quantity(D::FREQUENCY), "100 Hz", "lower end of the modal fit"),
        max_frequency: opt f64 = (
            T::Quantity(D::FREQUENCY),
            "upper end of the modal fit (default: the FRFs' last line)",
        ),
        feed_per_tooth: opt f64 = (
            T::Quantity(D::LENGTH),
            "feed per tooth (default: the cutting setup's `feed_per_tooth`)",
        ),
        revolutions: def usize = (
            T::Integer { min: 2, max: 100_000 },
            "100",
            "length of each simulated cut",
        ),
        extrapolate: def bool = (
            T::Bool,
            "false",
            "extend the end cubics beyond the measured speeds instead of refusing",
        ),
    }
}

/// One trial's simulation.
struct Simulated {
    stable: bool,
    metric: f64,
    chatter_hz: f64,
    modes: [usize; 2],
}

impl Node for TrialsSimulate {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        use crate::modal_fit::{self, FitOptions};
        use rayon::prelude::*;
        let p = TrialsSimulateParams::read(ctx.params)?;
        let mill = milling(ctx)?;
        let frfs: Vec<SpeedFrf> = pairs(ctx)?.into_iter().map(|(speed_rpm, frf)| SpeedFrf { speed_rpm, frf }).collect();
        let trials = read_trials(ctx)?;
        let span = (frfs[0].speed_rpm, frfs[frfs.len() - 1].speed_rpm);
        let (lo, hi) = trials.iter().fold(span, |(a, b), t| (a.min(t.speed_rpm), b.max(t.speed_rpm)));
        let law = ctx.entities.cutting.get(p.cutting);
        // The shared readers take the raw parameters: `coefficients` here, `file` in `read_trials`.
        let coeffs = coefficient_table(ctx.params, &mill, law, (lo, hi))?;
        let feed = feed_per_tooth(ctx, p.feed_per_tooth, p.cutting)?;
        let allow = p.extrapolate;
        let fit = FitOptions {
            min_frequency_hz: p.min_frequency,
            max_frequency_hz: p.max_frequency.unwrap_or(f64::INFINITY),
            beam_refit: false,
            ..FitOptions::default()
        };
        let revolutions = p.revolutions;
        let one = |t: &Trial| -> Result<Option<Simulated>, NodeError> {
            if !allow && (t.speed_rpm < span.0 || t.speed_rpm > span.1) {
                return Ok(None);
            }
            let at = format!("the trial at {} rpm, {} mm", t.speed_rpm, t.depth_m * 1e3);
            let (frf, c) = stability::conditions_at(&frfs, &coeffs, t.speed_rpm, allow)
                .map_err(|e| NodeError::input("frfs", format!("{at}: {e} (`extrapolate: true` extends the cubics)")))?;
            let modes = |h: &[num_complex::Complex64], d: &str| {
                modal_fit::fit(&frf.freqs_hz, h, &fit)
                    .map(|f| f.modes)
                    .map_err(|e| NodeError::input("frfs", format!("{at}: fitting the {d} modes: {e}")))
            };
            let (mx, my) = (modes(&frf.xx, "x")?, modes(&frf.yy, "y")?);
            let counts = [mx.len(), my.len()];
            let sim = MillingSimulation {
                cut: {
                    let mut m = mill.clone();
                    m.coefficients = c;
                    m
                },
                depth: t.depth_m,
                feed_per_tooth: feed,
                speed_rpm: t.speed_rpm,
                modes: stability::ModalModel::new(mx, my)
                    .map_err(|e| NodeError::input("frfs", format!("{at}: {e}")))?,
                runout: vec![],
                revolutions,
                steps_per_tooth: None,
                process_damping: None,
            };
            let r = simulate(&sim).map_err(|e| NodeError::Failed(format!("{at}: {e}")))?;
            Ok(Some(Simulated {
                stable: r.stable,
                metric: r.chatter_metric,
                chatter_hz: r.chatter_frequency_hz.unwrap_or(0.0),
                modes: counts,
            }))
        };
        let sims: Vec<Option<Simulated>> = trials.par_iter().map(one).collect::<Result<_, _>>()?;
        let outside: Vec<String> = trials
            .iter()
            .zip(&sims)
            .filter(|(_, s)| s.is_none())
            .map(|(t, _)| format!("{} rpm", t.speed_rpm))
            .collect();
        if outside.len() == trials.len() {
            return Err(NodeError::param(
                "file",
                format!("no trial lies within the FRFs' {:.0}–{:.0} rpm; nothing to simulate", span.0, span.1),
            ));
        }
        if !outside.is_empty() {
            ctx.warn(format!(
                "{} trial(s) outside the FRFs' {:.0}–{:.0} rpm, not simulated: {}",
                outside.len(),
                span.0,
                span.1,
                outside.join(", ")
            ));
        }
        let code = |chatter: bool| if chatter { 1.0 } else { 0.0 };
        let recorded: Vec<f64> = trials.iter().map(|t| code(t.outcome == stability::Outcome::Chatter)).collect();
        let simulated: Vec<f64> = sims.iter().map(|s| s.as_ref().map_or(-1.0, |s| code(!s.stable))).collect();
        let agrees: Vec<f64> =
            recorded.iter().zip(&simulated).map(|(a, b)| if *b < 0.0 { -1.0 } else { code(a == b) }).collect();
        let scored = agrees.iter().filter(|a| **a >= 0.0).count();
        let agreement = agrees.iter().filter(|a| **a > 0.0).count() as f64 / scored as f64;
        let col =
            |f: &dyn Fn(&Simulated) -> f64| sims.iter().map(|s| s.as_ref().map_or(f64::NAN, f)).collect::<Vec<_>>();
        let verdicts = Table {
            columns: vec![
                Column::new("speed", "rpm", trials.iter().map(|t| t.speed_rpm).collect()),
                Column::new("depth", "m", trials.iter().map(|t| t.depth_m).collect()),
                Column::new("outcome", "", recorded),
                Column::new("simulated", "", simulated),
                Column::new("agrees", "", agrees),
                Column::new("chatter_metric", "", col(&|s| (s.metric * 1e3).round() / 1e3)),
                Column::new("chatter_frequency", "Hz", col(&|s| s.chatter_hz)),
                Column::new("modes_x", "", col(&|s| s.modes[0] as f64)),
                Column::new("modes_y", "", col(&|s| s.modes[1] as f64)),
            ],
        };
        let mut out = Outputs::new();
        out.insert("verdicts".into(), Value::Table(verdicts));
        out.insert("agreement".into(), Value::Scalar(Scalar { value: agreement, unit: UnitLabel::new("") }));
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::milling::MillingResult;
    use indexmap::IndexMap;
    use spindlelab_engine::model::Recipe;
    use spindlelab_engine::node::Labelled;
    use spindlelab_engine::value::ModalModel;
    use std::sync::Arc;

    const PD: &str = "process_damping: { indentation: 30000 N/mm^3, wear_land: 0.1 mm, diameter: 10 mm }";

    /// The recipe of a four-tooth slot with `params` for the `cut` step (`milling.simulate`), resolved.
    fn recipe(params: &str) -> Result<Recipe, String> {
        let text = format!(
            "spindlelab: 1\ncutting:\n  \
             slot: {{ teeth: 4, radial_immersion: 100 %, milling: down, Kt: 600 MPa, Kn: 200 MPa, \
             feed_per_tooth: 0.1 mm }}\nsteps:\n  \
             modes: {{ kind: modal.model, params: {{ x: [{{ f: 1 kHz, zeta: 0.025, stiffness: 2e7 N/m }}] }} }}\n  \
             cut:\n    kind: milling.simulate\n    params: {{ {params} }}\n    \
             inputs: {{ modes_x: \"@modes.modes_x\", modes_y: \"@modes.modes_y\" }}\n"
        );
        crate::nodes::test_support::resolve_text(&text)
    }

    /// The tool: one mode along x (1 kHz, ζ = 0.025, 20 N/µm), one along y (1080 Hz, ζ = 0.02, 24 N/µm).
    fn modes() -> (Vec<stability::Mode>, Vec<stability::Mode>) {
        (
            vec![stability::Mode::from_stiffness(1000.0, 0.025, 2e7)],
            vec![stability::Mode::from_stiffness(1080.0, 0.02, 2.4e7)],
        )
    }

    /// Runs the step `cut` of the recipe on [`modes`]: its summary, its signals and its parameters.
    fn run(params: &str) -> (Table, TimeSeries, Params) {
        let r = recipe(params).unwrap();
        let params = r.step("cut").unwrap().params.clone();
        let entities = r.entities_named_by(&params);
        let (x, y) = modes();
        let mut inputs: IndexMap<String, Vec<Labelled>> = IndexMap::new();
        for (port, m) in [("modes_x", x), ("modes_y", y)] {
            let value = Arc::new(Value::ModalModel(ModalModel { modes: m }));
            inputs.insert(port.into(), vec![Labelled { label: String::new(), coords: vec![], value }]);
        }
        let node = MillingSimulate::new();
        node.validate(&params).unwrap();
        let ctx = NodeContext::new("cut", &params, &inputs, &entities);
        let out = node.run(&ctx).unwrap();
        let Value::Table(t) = out["summary"].clone() else { panic!("no summary") };
        let Value::TimeSeries(s) = out["signals"].clone() else { panic!("no signals") };
        (t, s, params)
    }

    /// The kernel's run of the same slot at 1500 rpm and `depth`, with `process_damping`.
    fn kernel(depth: f64, process_damping: Option<crate::stability::ProcessDamping>) -> MillingResult {
        let (x, y) = modes();
        let sim = MillingSimulation {
            cut: stability::Milling::new(
                4,
                1.0,
                stability::MillingDirection::Down,
                stability::CuttingCoefficients::from_kt_kn(6e8, 2e8).unwrap(),
            )
            .unwrap(),
            depth,
            feed_per_tooth: 1e-4,
            speed_rpm: 1500.0,
            modes: stability::ModalModel::new(x, y).unwrap(),
            runout: vec![5e-6, 0.0, 0.0, 0.0],
            revolutions: 100,
            steps_per_tooth: None,
            process_damping,
        };
        simulate(&sim).unwrap()
    }

    /// `process_damping` reaches the kernel in SI (`30000 N/mm^3` is 3·10¹³ N/m³): at 1500 rpm a 2 mm slot, above
    /// the undamped limit (1.6 mm) and below the limit with process damping (2.5 mm), chatters without it and
    /// is stable with it, with the kernel's numbers.
    #[test]
    fn process_damping_reaches_the_simulation() {
        let base = "cutting: slot, speed: 1500 rpm, depth: 2 mm, runout: \"[5, 0, 0, 0] um\"";
        let (plain, plain_signals, _) = run(base);
        let (damped, damped_signals, params) = run(&format!("{base}, {PD}"));
        let pd = params.object("process_damping").unwrap();
        assert!((pd.f64("indentation").unwrap() / 3e13 - 1.0).abs() < 1e-12);
        assert!((pd.f64("wear_land").unwrap() / 1e-4 - 1.0).abs() < 1e-12);
        assert!((pd.f64("diameter").unwrap() / 1e-2 - 1.0).abs() < 1e-12);
        let stable = |t: &Table| t.columns.iter().find(|c| c.name == "stable").unwrap().values[0];
        assert_eq!(stable(&plain), 0.0);
        assert_eq!(stable(&damped), 1.0);
        let depth = params.f64("depth").unwrap();
        let contact = crate::stability::ProcessDamping::new(3e13, 1e-4, 0.01).unwrap();
        for (signals, r) in [(&plain_signals, kernel(depth, None)), (&damped_signals, kernel(depth, Some(contact)))] {
            assert_eq!(signals.channels[0].samples, r.force_x);
            assert_eq!(signals.channels[3].samples, r.disp_y);
        }
    }

    /// The three fields go together, and a value out of range is refused naming the parameter.
    #[test]
    fn process_damping_fields_are_checked() {
        let with =
            |pd: &str| recipe(&format!("cutting: slot, speed: 1500 rpm, depth: 2 mm, process_damping: {{ {pd} }}"));
        let e = with("indentation: 30000 N/mm^3, wear_land: 0.1 mm").unwrap_err();
        assert!(e.contains("diameter"), "{e}");
        let e = with("indentation: 30 MPa, wear_land: 0.1 mm, diameter: 10 mm").unwrap_err();
        assert!(e.contains("indentation"), "{e}");
        let e = with("indentation: 30000 N/mm^3, wear_land: 0 mm, diameter: 10 mm").unwrap_err();
        assert!(e.contains("process_damping") && e.contains("`wear_land` must be positive"), "{e}");
    }
}
