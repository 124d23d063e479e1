//! `frf.convert`: receptance ↔ mobility ↔ accelerance, and the check that two FRFs compared
//! are of one kind.
//!
//! A harmonic displacement `x e^{iωt}` has the velocity `iωx` and the acceleration `−ω²x`, so
//! the three kinds of FRF of one structure differ by powers of `iω`: mobility `Y = iωH`,
//! accelerance `A = −ω²H` (Ewins, *Modal testing*, §2.4). Going down in order divides by `iω`,
//! which the 0 Hz line does not allow: it is dropped, or kept as NaN.

use num_complex::Complex64;
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::FieldType as T;
use spindlelab_engine::value::{Frf, FrfKind, PortType, UnitLabel, Value};
use std::f64::consts::TAU;

/// What happens to a 0 Hz line that a conversion would divide by zero.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ZeroLine {
    /// Left out of the converted FRF.
    Drop,
    /// Kept, its value NaN (nodes that compare FRFs pass over NaN lines).
    Nan,
}

/// The kind of an FRF, or an error on `port` that says how to state it.
pub(crate) fn kind_of(frf: &Frf, port: &str) -> Result<FrfKind, NodeError> {
    frf.kind().ok_or_else(|| {
        let label = frf.unit.symbol.trim();
        let have = if label.is_empty() { "no unit".to_string() } else { format!("the unit `{label}`") };
        NodeError::input(
            port,
            format!(
                "the FRF has {have}, so its kind (receptance m/N, mobility m/s/N, accelerance m/s^2/N) is unknown; \
                 state it with `units:` on `read.frf` or the measurement set"
            ),
        )
    })
}

/// `frf` brought to `to` (values times `(iω)^(to − from)`; coherence kept), with the 0 Hz line
/// handled by `zero` when the conversion divides. Returns the FRF and whether a 0 Hz line was
/// dropped or set to NaN.
pub(crate) fn convert(frf: &Frf, from: FrfKind, to: FrfKind, zero: ZeroLine) -> (Frf, bool) {
    let power = to.order() - from.order();
    let mut out = Frf {
        freq_hz: Vec::with_capacity(frf.freq_hz.len()),
        values: Vec::with_capacity(frf.values.len()),
        coherence: frf.coherence.as_ref().map(|_| Vec::with_capacity(frf.freq_hz.len())),
        unit: UnitLabel::new(to.label()),
        direction: frf.direction.clone(),
        speed: frf.speed,
        sensor: frf.sensor.clone(),
        dofs: frf.dofs,
    };
    let mut touched = false;
    for (k, (&f, &v)) in frf.freq_hz.iter().zip(&frf.values).enumerate() {
        let s = Complex64::new(0.0, TAU * f);
        let value = if power < 0 && f == 0.0 {
            touched = true;
            if zero == ZeroLine::Drop {
                continue;
            }
            Complex64::new(f64::NAN, f64::NAN)
        } else {
            v * s.powi(power)
        };
        out.freq_hz.push(f);
        out.values.push(value);
        if let (Some(c), Some(src)) = (out.coherence.as_mut(), frf.coherence.as_ref()) {
            c.push(src[k]);
        }
    }
    (out, touched)
}

/// Refuses to compare FRFs of different kinds (a receptance with an accelerance differs by
/// `−ω²`, not by a modelling error); FRFs whose units are unknown or not SI labels are compared
/// only when the labels agree or one is empty.
pub(crate) fn same_kind(a: &Frf, a_port: &str, b: &Frf, b_port: &str) -> Result<(), NodeError> {
    let (la, lb) = (a.unit.symbol.trim(), b.unit.symbol.trim());
    if la.is_empty() || lb.is_empty() || la == lb {
        return Ok(());
    }
    let name = |f: &Frf, l: &str| match f.kind() {
        Some(k) => format!("a {} ({l})", k.name()),
        None => format!("an FRF in `{l}`"),
    };
    Err(NodeError::input(
        b_port,
        format!(
            "`{a_port}` is {} but `{b_port}` is {}: FRFs of different kinds cannot be compared; convert one with `frf.convert` (`to: {}`)",
            name(a, la),
            name(b, lb),
            a.kind().map_or("receptance", |k| k.name())
        ),
    ))
}

node_params! {
    /// Parameters of `frf.convert`.
    pub struct FrfConvertParams<'a> {
        to: req &'a str = (T::Choice(&["receptance", "mobility", "accelerance"]), "the kind to convert to"),
        zero_line: def &'a str = (
            T::Choice(&["drop", "nan"]),
            "drop",
            "a 0 Hz line divided by iω: left out (`drop`) or kept as NaN (`nan`), which comparisons pass over",
        ),
    }
}

pub struct FrfConvert {
    spec: NodeSpec,
}

impl Default for FrfConvert {
    fn default() -> Self {
        Self::new()
    }
}

impl FrfConvert {
    pub fn new() -> Self {
        FrfConvert {
            spec: NodeSpec {
                kind: "frf.convert",
                version: 1,
                description: "Converts an FRF between receptance (m/N), mobility (m/s/N) and accelerance (m/s^2/N): values times powers of iω (mobility iωH, accelerance −ω²H); a 0 Hz line that a conversion would divide by zero is dropped or kept as NaN.",
                inputs: vec![PortSpec::new(
                    "frf",
                    PortType::Frf,
                    "an FRF whose unit says its kind (m/N, m/s/N, m/s^2/N)",
                )],
                outputs: vec![PortSpec::new("frf", PortType::Frf, "the FRF in the kind asked for")],
                params: FrfConvertParams::fields(),
            },
        }
    }
}

impl Node for FrfConvert {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let Value::Frf(frf) = ctx.input("frf")? else {
            return Err(NodeError::input("frf", "expected an FRF"));
        };
        let from = kind_of(frf, "frf")?;
        let p = FrfConvertParams::read(ctx.params)?;
        let to = match p.to {
            "mobility" => FrfKind::Mobility,
            "accelerance" => FrfKind::Accelerance,
            _ => FrfKind::Receptance,
        };
        let zero = if p.zero_line == "nan" { ZeroLine::Nan } else { ZeroLine::Drop };
        let (out, touched) = convert(frf, from, to, zero);
        if touched {
            ctx.warn(match zero {
                ZeroLine::Drop => format!("the 0 Hz line has no {} (a division by iω there): dropped", to.name()),
                ZeroLine::Nan => format!("the 0 Hz line has no {} (a division by iω there): kept as NaN", to.name()),
            });
        }
        Ok([("frf".to_string(), Value::Frf(out))].into_iter().collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frf(unit: &str) -> Frf {
        Frf {
            freq_hz: vec![0.0, 10.0, 20.0],
            values: vec![Complex64::new(1.0, 0.0), Complex64::new(2.0, -1.0), Complex64::new(0.5, 0.25)],
            coherence: Some(vec![0.5, 0.9, 1.0]),
            unit: UnitLabel::new(unit),
            direction: Some("x".into()),
            speed: None,
            sensor: None,
            dofs: None,
        }
    }

    #[test]
    fn mobility_is_i_omega_times_receptance_and_accelerance_minus_omega_squared() {
        let h = frf("m/N");
        let (y, touched) = convert(&h, FrfKind::Receptance, FrfKind::Mobility, ZeroLine::Drop);
        assert!(!touched);
        assert_eq!(y.unit.symbol, "m/s/N");
        let w = TAU * 10.0;
        assert!((y.values[1] - Complex64::new(0.0, w) * h.values[1]).norm() < 1e-12);
        let (a, _) = convert(&h, FrfKind::Receptance, FrfKind::Accelerance, ZeroLine::Drop);
        assert!((a.values[1] + w * w * h.values[1]).norm() < 1e-9);
        // And back: the 0 Hz line cannot be divided, the others return to the receptance.
        let (back, touched) = convert(&a, FrfKind::Accelerance, FrfKind::Receptance, ZeroLine::Drop);
        assert!(touched);
        assert_eq!(back.freq_hz, vec![10.0, 20.0]);
        assert_eq!(back.coherence, Some(vec![0.9, 1.0]));
        for (b, o) in back.values.iter().zip(&h.values[1..]) {
            assert!((b - o).norm() < 1e-12 * o.norm());
        }
        let (nan, _) = convert(&a, FrfKind::Accelerance, FrfKind::Receptance, ZeroLine::Nan);
        assert_eq!(nan.freq_hz.len(), 3);
        assert!(nan.values[0].re.is_nan());
    }

    #[test]
    fn different_kinds_are_refused_with_the_conversion_to_use() {
        let e = same_kind(&frf("m/N"), "model", &frf("m/s^2/N"), "measured").unwrap_err().to_string();
        assert!(e.contains("receptance") && e.contains("accelerance") && e.contains("frf.convert"), "{e}");
        assert!(same_kind(&frf("m/N"), "a", &frf(""), "b").is_ok());
    }
}
