//! `modal.fit_set`: the modes of a measurement set, one set of poles shared by its FRFs
//! (poly-reference LSCF with its stabilisation diagram) and residues per FRF (LSFD); see
//! [`crate::modal_fit::fit_set`].

use super::convert;
use crate::modal_fit::{self, FitError, SetFit, SetOptions, Stability, Targets, Weighting, signed_mode_of_residue};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Column, Frf, FrfDofs, FrfKind, FrfSet, ModalModel, Mode, PortType, Table, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `modal.fit_set`.
    pub struct ModalFitSetParams<'a> {
        min_frequency: def f64 = (T::Quantity(D::FREQUENCY), "0 Hz", "lower end of the fit band"),
        max_frequency: opt f64 = (T::Quantity(D::FREQUENCY), "upper end of the fit band (default: the last line)"),
        modes: opt usize = (
            T::Integer { min: 1, max: 200 },
            "how many modes to keep: the most prominent peaks of the summed |H| that have a stable pole (default: every peak at least `prominence` prominent that has one)",
        ),
        frequencies: opt &'a [f64] = (
            T::QuantityList(D::FREQUENCY),
            "approximate natural frequencies to take the poles at, instead of the peaks of the summed |H|",
        ),
        prominence: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "6",
            "least prominence of a peak of the summed |H| over the higher of its flanking minima, dB",
        ),
        max_order: def usize = (
            T::Integer { min: 4, max: 300 },
            "120",
            "highest model order of the stabilisation diagram: poles of the common denominator, conjugates counted (even; sdypy-EMA's pol_order_high is half of it)",
        ),
        stable_frequency: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "1 %",
            "a pole is stable in frequency when the previous order has one this close (relative)",
        ),
        stable_damping: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "5 %",
            "and stable in damping when that pole's damping ratio is this close too (relative)",
        ),
        weighting: def &'a str = (
            T::Choice(&["absolute", "relative"]),
            "absolute",
            "line weights of the LSCF and LSFD least squares: none, each FRF scaled to unit RMS (the peaks lead; the global L2 distance) or 1/|H| (every line by its relative error)",
        ),
        point: opt usize = (
            T::Integer { min: 1, max: 1_000_000 },
            "which FRF of the set (its place, from 1) the `modes` output describes (default: the first driving point by its node numbers, else the first FRF)",
        ),
    }
}

pub struct ModalFitSetNode {
    spec: NodeSpec,
}

impl Default for ModalFitSetNode {
    fn default() -> Self {
        Self::new()
    }
}

impl ModalFitSetNode {
    pub fn new() -> Self {
        ModalFitSetNode {
            spec: NodeSpec {
                kind: "modal.fit_set",
                version: 1,
                description: "Modes of a measurement set fitted together: one set of poles for every FRF from the poly-reference LSCF (common denominator, stabilisation diagram over model orders), the poles stable in frequency and damping nearest the peaks of the summed |H| (or given frequencies), then residues per FRF with complex lower and upper residual terms (LSFD) in the kind measured. Receptance, mobility or accelerance.",
                inputs: vec![PortSpec::new(
                    "set",
                    PortType::FrfSet,
                    "the FRFs of one structure on one grid: receptance (m/N), mobility (m/s/N) or accelerance (m/s^2/N)",
                )],
                outputs: vec![
                    PortSpec::new(
                        "modal_table",
                        PortType::Table,
                        "per mode: natural frequency, damping ratio and decay rate σ (NaN where the lines cannot resolve the damping), the model order it was taken from and the peak it was selected for",
                    ),
                    PortSpec::new(
                        "residues",
                        PortType::Table,
                        "per FRF and mode: the FRF's place in the set (from 1) and its response and reference node (NaN without) and direction (`x`, `-y`; empty without), the mode, its frequency, the complex residue A (H = Σ A/(iω − λ) + conj, as a receptance) and the signed modal mass 1/(2ω_d|A|)",
                    ),
                    PortSpec::new(
                        "stabilisation",
                        PortType::Table,
                        "every physical pole of every model order: order, frequency, damping ratio, whether it is stable in frequency and in damping against the previous order, and whether it was selected",
                    ),
                    PortSpec::new(
                        "residual_terms",
                        PortType::Table,
                        "per FRF: its place and nodes, the complex lower residual LR (term −LR/ω²) and upper residual UR of the receptance, the global relative L2 residual ‖H − H_fit‖/‖H‖ and the 1/|H|-weighted relative error of the FRF",
                    ),
                    PortSpec::new(
                        "quality",
                        PortType::Table,
                        "one row for the whole set: the global relative L2 residual, the 1/|H|-weighted relative error, the modes kept and the model orders computed",
                    ),
                    PortSpec::new(
                        "fitted",
                        PortType::FrfSet,
                        "the modal model of each FRF on the lines of the fit band, in the set's kind",
                    ),
                    PortSpec::new(
                        "modes",
                        PortType::ModalModel,
                        "the modes as the FRF `point` sees them (Eq. 5.8: frequency, damping ratio, signed modal mass 1/(2ω_d|A|)), for the nodes that take a modal model",
                    ),
                ],
                params: ModalFitSetParams::fields(),
            },
        }
    }
}

fn err(e: FitError) -> NodeError {
    match e {
        FitError::InvalidOption { name, .. } => NodeError::param(name, e.to_string()),
        FitError::TooFewLines { place: "in the fit band", .. } => NodeError::param("min_frequency", e.to_string()),
        FitError::NothingLeft { why, .. } => NodeError::Failed(format!(
            "no mode found: {why}; check the band (`min_frequency`, `max_frequency`), `modes`, `frequencies` or `prominence`, or raise `max_order`"
        )),
        FitError::LengthMismatch { .. }
        | FitError::TooFewLines { .. }
        | FitError::NonIncreasing { .. }
        | FitError::NonFinite { .. } => NodeError::input("set", e.to_string()),
        other => NodeError::Failed(other.to_string()),
    }
}

fn table(columns: Vec<Column>) -> Value {
    Value::Table(Table { columns })
}

impl Node for ModalFitSetNode {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = ModalFitSetParams::read(params)?;
        super::non_negative(params, &["min_frequency", "prominence"])?;
        super::positive(params, &["max_frequency", "stable_frequency", "stable_damping"])?;
        let lo = p.min_frequency;
        if let Some(hi) = p.max_frequency
            && hi <= lo
        {
            return Err(NodeError::param("max_frequency", format!("{hi} Hz is not above min_frequency {lo} Hz")));
        }
        if p.max_order % 2 != 0 {
            return Err(NodeError::param("max_order", "must be even: poles come in conjugate pairs"));
        }
        let v = p.stable_frequency;
        if v >= 1.0 {
            return Err(NodeError::param("stable_frequency", format!("must be below 100 %, got {v}")));
        }
        if p.modes.is_some() && p.frequencies.is_some() {
            return Err(NodeError::param(
                "frequencies",
                "give either `modes` (how many peaks) or `frequencies` (where), not both",
            ));
        }
        if let Some(f) = p.frequencies
            && let Some(v) = f.iter().find(|v| !(v.is_finite() && **v > 0.0))
        {
            return Err(NodeError::param("frequencies", format!("must be positive, got {v} Hz")));
        }
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let Value::FrfSet(set) = ctx.input("set")? else {
            return Err(NodeError::input("set", "expected an FRF set"));
        };
        let Some(first) = set.frfs.first() else {
            return Err(NodeError::input("set", "the set holds no FRF"));
        };
        // A file without units is taken as a receptance, as `modal.fit` does.
        let kind =
            if first.unit.symbol.trim().is_empty() { FrfKind::Receptance } else { convert::kind_of(first, "set")? };
        let p = ModalFitSetParams::read(ctx.params)?;
        let point = match p.point {
            Some(k) => {
                if k == 0 || k > set.frfs.len() {
                    return Err(NodeError::param(
                        "point",
                        format!("FRF {k} was asked for; the set holds {} FRF(s), numbered from 1", set.frfs.len()),
                    ));
                }
                k - 1
            }
            None => set.frfs.iter().position(|f| f.dofs.is_some_and(|d| d.driving_point())).unwrap_or(0),
        };
        let targets = match p.frequencies {
            Some(f) => Targets::Frequencies(f.to_vec()),
            None => Targets::Peaks { count: p.modes.map(|n| n.max(1)), prominence_db: p.prominence },
        };
        let opts = SetOptions {
            min_frequency_hz: p.min_frequency,
            max_frequency_hz: p.max_frequency.unwrap_or(f64::INFINITY),
            max_order: p.max_order,
            weighting: match p.weighting {
                "relative" => Weighting::Relative,
                _ => Weighting::Absolute,
            },
            kind_order: kind.order(),
            stable_frequency: p.stable_frequency,
            stable_damping: p.stable_damping,
            targets,
        };
        let values: Vec<&[num_complex::Complex64]> = set.frfs.iter().map(|f| f.values.as_slice()).collect();
        let fit = modal_fit::fit_set(set.freq_hz(), &values, &opts).map_err(err)?;
        report(ctx, set, &fit, &opts);
        Ok(outputs(set, &fit, point))
    }
}

/// The fit's modes as Eq. 5.8 modes (unit mass), for the damping-resolution check.
fn modes(fit: &SetFit) -> Vec<Mode> {
    fit.poles.iter().map(|p| Mode { freq_hz: p.f_hz, damping_ratio: p.xi, modal_mass: 1.0 }).collect()
}

fn report(ctx: &NodeContext, set: &FrfSet, fit: &SetFit, opts: &SetOptions) {
    let hz = |f: &[f64]| f.iter().map(|v| format!("{v:.1} Hz")).collect::<Vec<_>>().join(", ");
    if !fit.unmatched_hz.is_empty() {
        let asked = match &opts.targets {
            Targets::Peaks { count: Some(n), .. } if fit.poles.len() < *n => {
                format!("{n} mode(s) were asked for, {} found; ", fit.poles.len())
            }
            _ => String::new(),
        };
        ctx.warn(format!(
            "{asked}no pole stable in frequency ({} %) and damping ({} %) near {} up to order {}: raise `max_order`, widen `stable_frequency`/`stable_damping`, or leave the frequency out",
            100.0 * opts.stable_frequency,
            100.0 * opts.stable_damping,
            hz(&fit.unmatched_hz),
            opts.max_order
        ));
    }
    let wanted = opts.max_order / 2;
    if fit.orders.len() < wanted {
        ctx.warn(format!(
            "{} of the {wanted} model orders up to {} have singular normal equations and are left out of the diagram (the highest solved is {}): a band narrow against its upper frequency leaves the high orders undetermined; widen the band or lower `max_order`",
            wanted - fit.orders.len(),
            opts.max_order,
            fit.orders.last().copied().unwrap_or(0)
        ));
    }
    let grid = set.freq_hz();
    let band: Vec<f64> = fit.lines.iter().map(|&k| grid[k]).collect();
    let modes = modes(fit);
    let unresolved = modal_fit::unresolved_damping(&modes, &band);
    if !unresolved.is_empty() {
        let df = modal_fit::line_spacing(&band);
        let list: Vec<f64> = unresolved.iter().map(|&i| modes[i].freq_hz).collect();
        ctx.warn(format!(
            "the damping of the mode(s) at {} is below the resolution of the {df:.3} Hz lines (half-power width 2ζf under one line): the table gives NaN (measure with finer lines, a longer record, to know it)",
            hz(&list)
        ));
    }
    // A driving point (by its node numbers) has positive modal constants only.
    for (o, f) in set.frfs.iter().enumerate() {
        let Some(d) = f.dofs.filter(|d| d.driving_point()) else { continue };
        let negative: Vec<f64> = fit.residues[o]
            .iter()
            .zip(&modes)
            .filter(|(a, m)| signed_mode_of_residue(m.freq_hz, m.damping_ratio, **a).modal_mass < 0.0)
            .map(|(_, m)| m.freq_hz)
            .collect();
        if !negative.is_empty() {
            ctx.warn(format!(
                "FRF {} is a driving point by its node numbers ({}), but the mode(s) at {} have negative modal constants, which a driving point cannot have: check the file's node numbers",
                o + 1,
                d.describe(),
                hz(&negative)
            ));
        }
    }
}

/// Where an FRF sits in the set: its place (from 1), and its response and reference node
/// and direction when the file numbers them.
struct Place {
    frf: f64,
    nodes: [f64; 2],
    directions: [String; 2],
}

fn place(o: usize, f: &Frf) -> Place {
    match f.dofs {
        Some(d) => Place {
            frf: (o + 1) as f64,
            nodes: [d.response_node as f64, d.reference_node as f64],
            directions: [FrfDofs::axis_word(d.response_direction), FrfDofs::axis_word(d.reference_direction)],
        },
        None => Place { frf: (o + 1) as f64, nodes: [f64::NAN; 2], directions: [String::new(), String::new()] },
    }
}

/// The place columns: `frf`, `response_node`, `response_direction` (a word: `x`, `-y`),
/// `reference_node`, `reference_direction`.
fn place_columns(rows: &[Place]) -> Vec<Column> {
    let words = |i: usize| rows.iter().map(|r| r.directions[i].as_str()).collect::<Vec<_>>();
    vec![
        Column::new("frf", "", rows.iter().map(|r| r.frf).collect()),
        Column::new("response_node", "", rows.iter().map(|r| r.nodes[0]).collect()),
        Column::text("response_direction", &words(0)),
        Column::new("reference_node", "", rows.iter().map(|r| r.nodes[1]).collect()),
        Column::text("reference_direction", &words(1)),
    ]
}

fn outputs(set: &FrfSet, fit: &SetFit, point: usize) -> Outputs {
    let grid = set.freq_hz();
    let band: Vec<f64> = fit.lines.iter().map(|&k| grid[k]).collect();
    let modes = modes(fit);
    let unresolved = modal_fit::unresolved_damping(&modes, &band);
    let resolved = |i: usize, v: f64| if unresolved.contains(&i) { f64::NAN } else { v };
    let modal_table = table(vec![
        Column::new("frequency", "Hz", fit.poles.iter().map(|p| p.f_hz).collect()),
        Column::new("damping_ratio", "", fit.poles.iter().enumerate().map(|(i, p)| resolved(i, p.xi)).collect()),
        Column::new("sigma", "1/s", fit.poles.iter().enumerate().map(|(i, p)| resolved(i, -p.lambda.re)).collect()),
        Column::new("order", "", fit.poles.iter().map(|p| p.order as f64).collect()),
        Column::new("target", "Hz", fit.poles.iter().map(|p| p.target_hz).collect()),
    ]);
    let mut places = Vec::new();
    let (mut mode, mut freq, mut re, mut im, mut mass) = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (o, f) in set.frfs.iter().enumerate() {
        for (r, (a, m)) in fit.residues[o].iter().zip(&modes).enumerate() {
            places.push(place(o, f));
            mode.push((r + 1) as f64);
            freq.push(m.freq_hz);
            re.push(a.re);
            im.push(a.im);
            mass.push(signed_mode_of_residue(m.freq_hz, m.damping_ratio, *a).modal_mass);
        }
    }
    let mut residues = place_columns(&places);
    residues.extend([
        Column::new("mode", "", mode),
        Column::new("frequency", "Hz", freq),
        Column::new("residue_re", "m/(N s)", re),
        Column::new("residue_im", "m/(N s)", im),
        Column::new("modal_mass", "kg", mass),
    ]);
    let selected: Vec<(usize, f64)> = fit.poles.iter().map(|p| (p.order, p.f_hz)).collect();
    let d = &fit.diagram;
    let stabilisation = table(vec![
        Column::new("order", "", d.iter().map(|p| p.order as f64).collect()),
        Column::new("frequency", "Hz", d.iter().map(|p| p.f_hz).collect()),
        Column::new("damping_ratio", "", d.iter().map(|p| p.xi).collect()),
        Column::new(
            "stable_frequency",
            "",
            d.iter().map(|p| f64::from(u8::from(p.stability >= Stability::Frequency))).collect(),
        ),
        Column::new(
            "stable_damping",
            "",
            d.iter().map(|p| f64::from(u8::from(p.stability == Stability::Damping))).collect(),
        ),
        Column::new(
            "selected",
            "",
            d.iter().map(|p| f64::from(u8::from(selected.contains(&(p.order, p.f_hz))))).collect(),
        ),
    ]);
    let places: Vec<Place> = set.frfs.iter().enumerate().map(|(o, f)| place(o, f)).collect();
    let mut terms = place_columns(&places);
    terms.extend([
        Column::new("lower_residual_re", "m/(N s^2)", fit.lower.iter().map(|v| v.re).collect()),
        Column::new("lower_residual_im", "m/(N s^2)", fit.lower.iter().map(|v| v.im).collect()),
        Column::new("upper_residual_re", "m/N", fit.upper.iter().map(|v| v.re).collect()),
        Column::new("upper_residual_im", "m/N", fit.upper.iter().map(|v| v.im).collect()),
        Column::new("relative_residual", "", fit.relative_residual.clone()),
        Column::new("weighted_residual", "", fit.weighted_residual.clone()),
    ]);
    let quality = table(vec![
        Column::new("relative_residual", "", vec![fit.global_relative_residual]),
        Column::new("weighted_residual", "", vec![fit.global_weighted_residual]),
        Column::new("modes", "", vec![fit.poles.len() as f64]),
        Column::new("orders", "", vec![fit.orders.len() as f64]),
    ]);
    let point_modes: Vec<Mode> = fit.residues[point]
        .iter()
        .zip(&modes)
        .map(|(a, m)| signed_mode_of_residue(m.freq_hz, m.damping_ratio, *a))
        .collect();
    let fitted = FrfSet {
        frfs: set
            .frfs
            .iter()
            .zip(&fit.fitted)
            .map(|(f, v)| Frf {
                freq_hz: band.clone(),
                values: v.clone(),
                coherence: None,
                unit: f.unit.clone(),
                direction: f.direction.clone(),
                speed: f.speed,
                sensor: f.sensor.clone(),
                dofs: f.dofs,
            })
            .collect(),
    };
    [
        ("modal_table", modal_table),
        ("residues", table(residues)),
        ("stabilisation", stabilisation),
        ("residual_terms", table(terms)),
        ("quality", quality),
        ("fitted", Value::FrfSet(fitted)),
        ("modes", Value::ModalModel(ModalModel { modes: point_modes })),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nodes::test_support::{empty_recipe, params};
    use num_complex::Complex64;
    use spindlelab_engine::node::Labelled;
    use spindlelab_engine::value::{FrfDofs, UnitLabel};
    use std::sync::Arc;

    /// Two receptances of a 2-mode structure (points 1 and 2, reference 1): the node keeps both
    /// modes, signs its modal masses per FRF and refuses what it cannot fit.
    #[test]
    fn node_fits_a_two_point_set_and_signs_the_cross_frf() {
        let node = ModalFitSetNode::new();
        let modes = [(300.0, 0.01), (780.0, 0.015)];
        let shapes = [[1.0, 1.0], [0.8, -0.6]];
        let freq_hz: Vec<f64> = (0..=2000).map(|k| 0.5 * k as f64).collect();
        let frf = |o: usize| Frf {
            freq_hz: freq_hz.clone(),
            values: freq_hz
                .iter()
                .map(|&f| {
                    modes
                        .iter()
                        .zip(shapes[o].iter().zip(&shapes[0]))
                        .map(|(&(fr, z), (a, b))| Mode { freq_hz: fr, damping_ratio: z, modal_mass: 1.0 / (a * b) })
                        .map(|m| m.receptance(std::f64::consts::TAU * f))
                        .sum::<Complex64>()
                })
                .collect(),
            coherence: None,
            unit: UnitLabel::new("m/N"),
            direction: Some("x".into()),
            speed: None,
            sensor: None,
            dofs: Some(FrfDofs {
                response_node: o as i64 + 1,
                response_direction: 1,
                reference_node: 1,
                reference_direction: 1,
            }),
        };
        let set = FrfSet::new(vec![frf(0), frf(1)]).unwrap();
        let inputs = [(
            "set".to_string(),
            vec![Labelled { label: "set".into(), coords: Vec::new(), value: Arc::new(Value::FrfSet(set)) }],
        )]
        .into_iter()
        .collect();
        let recipe = empty_recipe();
        let p = params(&node, "min_frequency: 20 Hz\nmax_order: 30");
        node.validate(&p).unwrap();
        let out = node.run(&NodeContext::new("fit", &p, &inputs, &recipe.entities_named_by(&p))).unwrap();
        let Value::Table(t) = &out["modal_table"] else { panic!() };
        let f = &t.columns[0].values;
        assert_eq!(f.len(), 2, "{f:?}");
        assert!((f[0] / 300.0 - 1.0).abs() < 1e-6 && (f[1] / 780.0 - 1.0).abs() < 1e-6, "{f:?}");
        let Value::Table(r) = &out["residues"] else { panic!() };
        let mass = &r.columns.iter().find(|c| c.name == "modal_mass").unwrap().values;
        // FRF 1 (driving point): both masses 1; FRF 2: 1/0.8, and −1/0.6 at the second mode.
        let want = [1.0, 1.0, 1.0 / 0.8, -1.0 / 0.6];
        for (m, w) in mass.iter().zip(want) {
            assert!((m / w - 1.0).abs() < 1e-4, "{mass:?}");
        }
        // The modal model of the driving point (FRF 1 by its nodes), and of FRF 2 when asked.
        let Value::ModalModel(m) = &out["modes"] else { panic!() };
        assert!(m.modes.iter().all(|m| (m.modal_mass - 1.0).abs() < 1e-4), "{m:?}");
        let second = params(&node, "min_frequency: 20 Hz\nmax_order: 30\npoint: 2");
        let out2 = node.run(&NodeContext::new("fit", &second, &inputs, &recipe.entities_named_by(&second))).unwrap();
        let Value::ModalModel(m) = &out2["modes"] else { panic!() };
        assert!((m.modes[1].modal_mass * 0.6 + 1.0).abs() < 1e-4, "{m:?}");
        let third = params(&node, "point: 3");
        assert!(matches!(
            node.run(&NodeContext::new("fit", &third, &inputs, &recipe.entities_named_by(&third))),
            Err(NodeError::InvalidParam { .. })
        ));
        let Value::FrfSet(fitted) = &out["fitted"] else { panic!() };
        assert_eq!(fitted.frfs[1].dofs.map(|d| d.response_node), Some(2));
        let both = params(&node, "modes: 2\nfrequencies: [300 Hz, 780 Hz]");
        assert!(matches!(node.validate(&both), Err(NodeError::InvalidParam { .. })));
        let odd = params(&node, "max_order: 31");
        assert!(matches!(node.validate(&odd), Err(NodeError::InvalidParam { .. })));
    }
}
