//! `modal.fit`: equivalent modes and fixed-free Euler–Bernoulli beams of a direct tip FRF (§5.2, Eqs. 5.7–5.12),
//! and the modes of a transfer FRF (signed modal constants, no beams).

use super::convert::{self, ZeroLine};
use crate::modal_fit::{self, FitError, FitOptions, Method, ModalFit, Residues, Weighting};
use spindlelab_domain::Material;
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, FieldType as T, Params};
use spindlelab_engine::value::{Column, Frf, FrfKind, ModalModel, Mode, PortType, ReceptanceSet, Table, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `modal.fit`.
    pub struct ModalFitParams<'a> {
        method: def &'a str = (
            T::Choice(&["simplex", "lscf"]),
            "simplex",
            "§5.2 simplex procedure or least-squares complex frequency-domain fit",
        ),
        min_frequency: def f64 = (T::Quantity(D::FREQUENCY), "0 Hz", "lower end of the fit band"),
        max_frequency: opt f64 = (T::Quantity(D::FREQUENCY), "upper end of the fit band (default: the last line)"),
        h_sens: def usize = (
            T::Integer { min: 1, max: 10_000 },
            "5",
            "moving-average width on Im(H) for peak picking, points (§5.2.1)",
        ),
        v_sens: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "0.1 %",
            "peak cut-off as a fraction of the largest |Im H| (§5.2.1)",
        ),
        prominence: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "3",
            "least prominence of the smoothed |H| at a picked peak, dB (0: off); rejects noise minima of Im H where the FRF is flat",
        ),
        residues: def &'a str = (
            T::Choice(&["real", "complex"]),
            "real",
            "real modal masses (Eq. 5.8) or complex residues with lower and upper residual terms (LSFD), for non-proportional damping",
        ),
        iterations: def usize = (T::Integer { min: 1, max: 1000 }, "20", "global iterations of step 4 (§5.2.4)"),
        delete_after: def usize = (
            T::Integer { min: 1, max: 1000 },
            "14",
            "delete modes stuck at their bounds after this many iterations (§5.2.4.1)",
        ),
        floating_modes: def bool = (T::Bool, "false", "add the random floating modes of §5.2.3"),
        seed: def u64 = (T::Integer { min: 0, max: i64::MAX }, "0", "seed of the floating modes"),
        band_points: def usize = (
            T::Integer { min: 8, max: 100_000 },
            "200",
            "lines each mode band is sampled to for its fit",
        ),
        material: opt &'a str = (
            T::Entity(EntityKind::Material),
            "material of the equivalent beams (default steel, E 200 GPa, ρ 7800 kg/m³)",
        ),
        beam_refit: def bool = (
            T::Bool,
            "true",
            "refit the mapped beams jointly so that their sum reproduces the measured FRF (false: the plain per-mode mapping of §5.2.5)",
        ),
        driving_point: opt bool = (
            T::Bool,
            "whether response and reference are the same point and direction (default: from the FRF's node and direction numbers, else unknown); a driving point's modal masses must be positive (modes that come out negative are rejected), a transfer FRF's modal constants carry signs",
        ),
        weighting: def &'a str = (
            T::Choice(&["relative", "absolute"]),
            "relative",
            "line weights of the LSCF and LSFD least squares: 1/|H| (every line by its relative error) or none (the global L2 distance, which the peaks dominate)",
        ),
        order: opt usize = (
            T::Integer { min: 4, max: 200 },
            "LSCF model order (number of poles; default four per picked peak, at least 8, raised to six and eight while fewer poles than peaks are stable)",
        ),
    }
}

pub struct ModalFitNode {
    spec: NodeSpec,
}

impl Default for ModalFitNode {
    fn default() -> Self {
        Self::new()
    }
}

impl ModalFitNode {
    pub fn new() -> Self {
        ModalFitNode {
            spec: NodeSpec {
                kind: "modal.fit",
                version: 2,
                description: "Modes of an FRF (§5.2 simplex, or LSCF); of a direct tip FRF mapped to fixed-free Euler–Bernoulli beams (§5.2.5) with the fitted FRF (Eq. 5.7) and tip receptances G11 (Eqs. 5.10–5.12). A transfer FRF's modal constants may be negative (then no beams). Receptance, mobility or accelerance: fitted as a receptance.",
                inputs: vec![PortSpec::new(
                    "frf",
                    PortType::Frf,
                    "the FRF: receptance (m/N), mobility (m/s/N) or accelerance (m/s^2/N), a driving point or a transfer FRF",
                )],
                outputs: vec![
                    PortSpec::new("modes", PortType::ModalModel, "identified modes (Eq. 5.8)"),
                    PortSpec::new(
                        "modal_table",
                        PortType::Table,
                        "frequency, damping ratio, modal mass and stiffness per mode",
                    ),
                    PortSpec::new(
                        "beams",
                        PortType::Table,
                        "equivalent beam per mode: frequency, diameter, loss factor, free length",
                    ),
                    PortSpec::new(
                        "fitted",
                        PortType::Frf,
                        "sum of the beams' tip H (Eq. 5.7), or the modal model where there are no beams, on the fit's grid (the input's without a 0 Hz line a conversion drops), in the input's kind",
                    ),
                    PortSpec::new(
                        "tip",
                        PortType::ReceptanceSet,
                        "sum of the beams' tip blocks H, L, N, P (Eqs. 5.10–5.12)",
                    ),
                    PortSpec::new(
                        "band_errors",
                        PortType::Table,
                        "relative residual per mode band, of the modes, of the beams and of the beams before the joint refit",
                    ),
                    PortSpec::new(
                        "residues",
                        PortType::Table,
                        "per mode: frequency, damping ratio and complex residue A (H = Σ A/(iω − λ) + conj)",
                    ),
                    PortSpec::new(
                        "residual_terms",
                        PortType::Table,
                        "one row: lower residual LR (term −LR/ω²), its mass 1/LR, upper residual UR, the global relative L2 residual ‖H − H_fit‖/‖H‖ and the 1/|H|-weighted relative error (RMS of |H − H_fit|/|H|) of the modal model on the fit band",
                    ),
                ],
                params: ModalFitParams::fields(),
            },
        }
    }
}

fn err(e: FitError) -> NodeError {
    match e {
        FitError::InvalidOption { name, .. } => NodeError::param(name, e.to_string()),
        FitError::NoModes { .. } => NodeError::param("v_sens", e.to_string()),
        FitError::TooFewLines { place: "in the fit band", .. } => NodeError::param("min_frequency", e.to_string()),
        FitError::LengthMismatch { .. }
        | FitError::TooFewLines { .. }
        | FitError::NonIncreasing { .. }
        | FitError::NonFinite { .. }
        | FitError::NoPeaks { .. } => NodeError::input("frf", e.to_string()),
        other => NodeError::Failed(other.to_string()),
    }
}

fn table(columns: Vec<Column>) -> Value {
    Value::Table(Table { columns })
}

impl Node for ModalFitNode {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = ModalFitParams::read(params)?;
        super::non_negative(params, &["min_frequency", "prominence"])?;
        super::positive(params, &["max_frequency", "v_sens"])?;
        let v = p.v_sens;
        if v > 1.0 {
            return Err(NodeError::param("v_sens", format!("must be at most 100 %, got {v}")));
        }
        let lo = p.min_frequency;
        if let Some(hi) = p.max_frequency
            && hi <= lo
        {
            return Err(NodeError::param("max_frequency", format!("{hi} Hz is not above min_frequency {lo} Hz")));
        }
        if p.order.is_some_and(|n| n % 2 != 0) {
            return Err(NodeError::param("order", "must be even: poles come in conjugate pairs"));
        }
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let Value::Frf(frf) = ctx.input("frf")? else {
            return Err(NodeError::input("frf", "expected an FRF"));
        };
        // A file without units is taken as a receptance, as before kinds were told apart.
        let kind = if frf.unit.symbol.trim().is_empty() { FrfKind::Receptance } else { convert::kind_of(frf, "frf")? };
        let (receptance, dropped) = convert::convert(frf, kind, FrfKind::Receptance, ZeroLine::Drop);
        if dropped {
            ctx.warn(format!(
                "the {}'s 0 Hz line has no receptance (a division by iω there): left out of the fit",
                kind.name()
            ));
        }
        let labelled = frf.dofs.map(|d| d.driving_point());
        let p = ModalFitParams::read(ctx.params)?;
        let stated = p.driving_point;
        let material = match p.material {
            Some(name) => {
                let m = ctx
                    .entities
                    .materials
                    .get(name)
                    .ok_or_else(|| NodeError::param("material", format!("no material `{name}` in the recipe")))?;
                *m
            }
            None => Material::STEEL,
        };
        if !(material.youngs_modulus.is_finite()
            && material.youngs_modulus > 0.0
            && material.density.is_finite()
            && material.density > 0.0)
        {
            return Err(NodeError::param("material", "the material needs a positive `E` and `rho`"));
        }
        let method = match p.method {
            "lscf" => Method::Lscf { order: p.order },
            _ => Method::Simplex,
        };
        let opts = FitOptions {
            method,
            min_frequency_hz: p.min_frequency,
            max_frequency_hz: p.max_frequency.unwrap_or(f64::INFINITY),
            h_sens: p.h_sens,
            v_sens: p.v_sens,
            prominence_db: p.prominence,
            residues: match p.residues {
                "complex" => Residues::Complex,
                _ => Residues::Real,
            },
            iterations: p.iterations,
            delete_after: p.delete_after,
            floating_modes: p.floating_modes,
            seed: p.seed,
            band_points: p.band_points,
            material,
            beam_refit: p.beam_refit,
            // Only a driving point stated as one is held to positive modal masses; node numbers may be
            // placeholders, so a driving point by its numbers alone is checked after the fit instead.
            signed: stated != Some(true),
            kind_order: kind.order(),
            weighting: match p.weighting {
                "absolute" => Weighting::Absolute,
                _ => Weighting::Relative,
            },
        };
        let fit = modal_fit::fit(&receptance.freq_hz, &receptance.values, &opts).map_err(err)?;
        report(ctx, &fit, method, &receptance.freq_hz);
        let negative: Vec<String> =
            fit.modes.iter().filter(|m| m.modal_mass < 0.0).map(|m| format!("{:.1} Hz", m.freq_hz)).collect();
        if stated.is_none()
            && labelled == Some(true)
            && !negative.is_empty()
            && let Some(d) = frf.dofs
        {
            ctx.warn(format!(
                "the FRF is a driving point by its node numbers ({}), but the mode(s) at {} have negative modal constants, which a driving point cannot have: check the file's node numbers, or state `driving_point: false` (a transfer FRF) or `true` (to reject those modes)",
                d.describe(),
                negative.join(", ")
            ));
        }
        if !negative.is_empty() {
            ctx.warn(format!(
                "mode(s) at {} have negative modal constants (a transfer FRF): no equivalent beams, `fitted` is the modal model and the tip blocks L, N, P are NaN",
                negative.join(", ")
            ));
        }
        Ok(outputs(&receptance, kind, fit))
    }
}

fn report(ctx: &NodeContext, fit: &ModalFit, method: Method, freqs_hz: &[f64]) {
    if !fit.deleted.is_empty() {
        let what = match method {
            Method::Simplex => "deleted at their bounds (§5.2.4.1)",
            Method::Lscf { .. } => "rejected (negative modal mass of a driving point, or below v_sens)",
        };
        let list: Vec<String> = fit.deleted.iter().map(|m| format!("{:.1} Hz", m.freq_hz)).collect();
        ctx.warn(format!("{} mode(s) {what}: {}", fit.deleted.len(), list.join(", ")));
    }
    let clipped: Vec<String> = fit
        .bands
        .iter()
        .zip(&fit.modes)
        .filter(|(b, _)| b.clipped)
        .map(|(_, m)| format!("{:.1} Hz", m.freq_hz))
        .collect();
    if !clipped.is_empty() {
        ctx.warn(format!("the fit band clips the band of the mode(s) at {}", clipped.join(", ")));
    }
    let unresolved = modal_fit::unresolved_damping(&fit.modes, freqs_hz);
    if !unresolved.is_empty() {
        let df = modal_fit::line_spacing(freqs_hz);
        let list: Vec<String> = unresolved.iter().map(|&i| format!("{:.1} Hz", fit.modes[i].freq_hz)).collect();
        ctx.warn(format!(
            "the damping of the mode(s) at {} is below the resolution of the {df:.3} Hz lines (half-power width 2ζf under one line): the table gives NaN; the model keeps the fitted value, an upper bound at best (measure with finer lines, a longer record, to know it)",
            list.join(", ")
        ));
    }
}

fn outputs(frf: &Frf, kind: FrfKind, fit: ModalFit) -> Outputs {
    let modes = ModalModel { modes: fit.modes.clone() };
    let col = |f: &dyn Fn(&Mode) -> f64| fit.modes.iter().map(f).collect::<Vec<f64>>();
    let unresolved = modal_fit::unresolved_damping(&fit.modes, &frf.freq_hz);
    let damping: Vec<f64> = fit
        .modes
        .iter()
        .enumerate()
        .map(|(i, m)| if unresolved.contains(&i) { f64::NAN } else { m.damping_ratio })
        .collect();
    let modal_table = table(vec![
        Column::new("frequency", "Hz", col(&|m| m.freq_hz)),
        Column::new("damping_ratio", "", damping),
        Column::new("modal_mass", "kg", col(&|m| m.modal_mass)),
        Column::new("stiffness", "N/m", col(&|m| m.stiffness())),
    ]);
    let beams = table(vec![
        Column::new("frequency", "Hz", fit.beams.iter().map(|b| b.f_hz).collect()),
        Column::new("diameter", "m", fit.beams.iter().map(|b| b.beam.d_m).collect()),
        Column::new("eta", "", fit.beams.iter().map(|b| b.beam.eta).collect()),
        Column::new("length", "m", fit.beams.iter().map(|b| b.beam.length_m).collect()),
    ]);
    let e = &fit.band_errors;
    let band_errors = table(vec![
        Column::new("frequency", "Hz", e.iter().map(|b| b.f_hz).collect()),
        Column::new("band_low", "Hz", e.iter().map(|b| b.lo_hz).collect()),
        Column::new("band_high", "Hz", e.iter().map(|b| b.hi_hz).collect()),
        Column::new("modal_error", "", e.iter().map(|b| b.modal).collect()),
        Column::new("beam_error", "", e.iter().map(|b| b.beam).collect()),
        Column::new("mapped_beam_error", "", e.iter().map(|b| b.mapped).collect()),
    ]);
    let r = &fit.residue_fit;
    let residues = table(vec![
        Column::new("frequency", "Hz", col(&|m| m.freq_hz)),
        Column::new("damping_ratio", "", col(&|m| m.damping_ratio)),
        Column::new("residue_re", "m/(N s)", r.residues.iter().map(|a| a.re).collect()),
        Column::new("residue_im", "m/(N s)", r.residues.iter().map(|a| a.im).collect()),
    ]);
    let residual_terms = table(vec![
        Column::new("lower_residual", "m/(N s^2)", vec![r.lower]),
        Column::new("lower_mass", "kg", vec![if r.lower != 0.0 { 1.0 / r.lower } else { f64::INFINITY }]),
        Column::new("upper_residual", "m/N", vec![r.upper]),
        Column::new("relative_residual", "", vec![r.relative_residual]),
        Column::new("weighted_residual", "", vec![r.weighted_residual]),
    ]);
    let receptance = Frf {
        freq_hz: frf.freq_hz.clone(),
        values: fit.fitted,
        coherence: None,
        unit: frf.unit.clone(),
        direction: frf.direction.clone(),
        speed: frf.speed,
        sensor: frf.sensor.clone(),
        dofs: frf.dofs,
    };
    let (fitted, _) = convert::convert(&receptance, FrfKind::Receptance, kind, ZeroLine::Drop);
    let lines = &fit.tip.lines;
    let tip = ReceptanceSet {
        freq_hz: fit.tip.freqs_hz.clone(),
        h: lines.iter().map(|r| r.h).collect(),
        l: lines.iter().map(|r| r.l).collect(),
        n: lines.iter().map(|r| r.n).collect(),
        p: lines.iter().map(|r| r.p).collect(),
        direction: frf.direction.clone(),
        speed: frf.speed,
    };
    [
        ("modes", Value::ModalModel(modes)),
        ("modal_table", modal_table),
        ("beams", beams),
        ("fitted", Value::Frf(fitted)),
        ("tip", Value::ReceptanceSet(tip)),
        ("band_errors", band_errors),
        ("residues", residues),
        ("residual_terms", residual_terms),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nodes::test_support::{empty_recipe, params};
    use spindlelab_engine::node::Labelled;
    use spindlelab_engine::value::UnitLabel;
    use std::f64::consts::TAU;
    use std::sync::Arc;

    #[test]
    fn node_fits_two_modes_and_keeps_direction_and_speed() {
        let node = ModalFitNode::new();
        let modes = [
            Mode { freq_hz: 800.0, damping_ratio: 0.03, modal_mass: 0.5 },
            Mode { freq_hz: 2100.0, damping_ratio: 0.02, modal_mass: 0.3 },
        ];
        let freq_hz: Vec<f64> = (1..=1000).map(|k| 3.0 * k as f64).collect();
        let values = freq_hz.iter().map(|&f| modes.iter().map(|m| m.receptance(TAU * f)).sum()).collect();
        let frf = Frf {
            freq_hz,
            values,
            coherence: None,
            unit: UnitLabel::new("m/N"),
            direction: Some("x".into()),
            speed: Some(spindlelab_domain::Speed::from_rpm(3000.0)),
            sensor: None,
            dofs: None,
        };
        let inputs = [(
            "frf".to_string(),
            vec![Labelled { label: "frf".into(), coords: Vec::new(), value: Arc::new(Value::Frf(frf)) }],
        )]
        .into_iter()
        .collect();
        let recipe = empty_recipe();
        for method in ["simplex", "lscf"] {
            let p = params(&node, &format!("method: {method}\nv_sens: 10 %"));
            node.validate(&p).unwrap();
            let out = node.run(&NodeContext::new("fit", &p, &inputs, &recipe.entities_named_by(&p))).unwrap();
            let Value::ModalModel(m) = &out["modes"] else { panic!("modes") };
            assert_eq!(m.modes.len(), 2, "{method}");
            for (got, want) in m.modes.iter().zip(&modes) {
                assert!((got.freq_hz / want.freq_hz - 1.0).abs() < 1e-3, "{method}: {got:?}");
                assert!((got.damping_ratio / want.damping_ratio - 1.0).abs() < 0.01, "{method}: {got:?}");
            }
            let (Value::Frf(fitted), Value::ReceptanceSet(tip)) = (&out["fitted"], &out["tip"]) else { panic!() };
            assert_eq!(fitted.direction.as_deref(), Some("x"));
            assert_eq!(tip.direction.as_deref(), Some("x"));
            let rpm = |s: Option<spindlelab_domain::Speed>| s.map(|s| s.rpm_as_written());
            assert_eq!((rpm(fitted.speed), rpm(tip.speed)), (Some(3000.0), Some(3000.0)));
            assert_eq!(fitted.values, tip.h);
            let Value::Table(beams) = &out["beams"] else { panic!() };
            assert_eq!(beams.rows(), 2);
        }
        let odd = params(&node, "order: 9");
        assert!(matches!(node.validate(&odd), Err(NodeError::InvalidParam { .. })));
        let hi = params(&node, "v_sens: 150 %");
        assert!(matches!(node.validate(&hi), Err(NodeError::InvalidParam { .. })));
    }
}
