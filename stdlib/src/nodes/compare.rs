//! `frf.compare`: an FRF against a reference, judged in the reference's mode bands.

use crate::compare::{self, Region};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Column, PortType, Scalar, Table, Value};
use spindlelab_grammar::Dimension as D;

node_params! {
    /// Parameters of `frf.compare`.
    pub struct FrfCompareParams<'a> {
        region: def &'a str = (
            T::Choice(&["modes", "all"]),
            "modes",
            "judge the half-power band of each reference mode, or every line",
        ),
        min_coherence: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "0.9",
            "lines with lower coherence are not judged",
        ),
    }
}

pub struct FrfCompare {
    spec: NodeSpec,
}

impl Default for FrfCompare {
    fn default() -> Self {
        Self::new()
    }
}

impl FrfCompare {
    pub fn new() -> Self {
        FrfCompare {
            spec: NodeSpec {
                kind: "frf.compare",
                version: 1,
                description: "Compares an FRF with a reference (rig truth, model or another measurement): magnitude ratio and phase error per line, and their worst values in the reference's mode bands where the coherence is high.",
                inputs: vec![
                    PortSpec::new("frf", PortType::Frf, "the FRF under test"),
                    PortSpec::new(
                        "reference",
                        PortType::Frf,
                        "the reference; interpolated onto the FRF's grid if needed",
                    ),
                ],
                outputs: vec![
                    PortSpec::new(
                        "lines",
                        PortType::Table,
                        "per line: frequency, magnitude ratio, phase error, judged (0/1)",
                    ),
                    PortSpec::new("magnitude_error", PortType::Scalar, "largest | |H|/|H_ref| − 1 | over judged lines"),
                    PortSpec::new("phase_error", PortType::Scalar, "largest |arg(H/H_ref)| over judged lines (rad)"),
                ],
                params: FrfCompareParams::fields(),
            },
        }
    }
}

impl Node for FrfCompare {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        let p = FrfCompareParams::read(p)?;
        if !(0.0..=1.0).contains(&p.min_coherence) {
            return Err(NodeError::param("min_coherence", "must lie in [0, 1]"));
        }
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let (Value::Frf(a), Value::Frf(b)) = (ctx.input("frf")?, ctx.input("reference")?) else {
            return Err(NodeError::input("frf", "expected FRFs"));
        };
        super::convert::same_kind(b, "reference", a, "frf")?;
        let p = FrfCompareParams::read(ctx.params)?;
        let region = if p.region == "all" { Region::All } else { Region::Modes };
        let min_coherence = p.min_coherence;
        let c = compare::compare(
            &a.freq_hz,
            &a.values,
            a.coherence.as_deref(),
            &b.freq_hz,
            &b.values,
            region,
            min_coherence,
        )
        .map_err(|e| NodeError::input("frf", e.to_string()))?;
        if c.resampled {
            ctx.warn("the reference is on another frequency grid: interpolated linearly onto the FRF's lines");
        }
        let table = Table {
            columns: vec![
                Column::new("frequency", "Hz", c.freq_hz),
                Column::new("magnitude_ratio", "", c.magnitude_ratio),
                Column::new("phase_error", "rad", c.phase_error),
                Column::new("judged", "", c.judged.iter().map(|&j| if j { 1.0 } else { 0.0 }).collect()),
            ],
        };
        Ok([
            ("lines".to_string(), Value::Table(table)),
            ("magnitude_error".to_string(), Value::Scalar(Scalar::new(c.max_magnitude_error, ""))),
            ("phase_error".to_string(), Value::Scalar(Scalar::new(c.max_phase_error, "rad"))),
        ]
        .into_iter()
        .collect())
    }
}
