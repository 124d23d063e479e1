//! `frf.gap`: a model's FRF against a measured one, in units of the measurement's noise.

use crate::gap::{self, NoiseModel};
use spindlelab_domain::Speed;
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Column, Frf, PortType, Scalar, Table, UnitLabel, Value};
use spindlelab_grammar::Dimension as D;

/// The kind name of `frf.gap`: the gap between a model FRF and a measured one.
pub const FRF_GAP: &str = "frf.gap";

node_params! {
    /// Parameters of `frf.gap`.
    pub struct GapParams<'a> {
        band: opt &'a [f64] = (T::QuantityList(D::FREQUENCY), "[low, high] Hz to compare (default: every measured line the model covers)"),
        noise: def &'a str = (
            T::Choice(&["coherence", "h1", "declared"]),
            "coherence",
            "where the noise of each line comes from: the coherence as the virtual rig writes it (σ² = |H|²(1/γ − 1)/20); an analyser's H1 estimate over `averages` averages with γ² its ordinary coherence (σ² = |H|²(1 − γ²)/(nγ²)); or `sigma_rel`, `floor_rel` and `rolloff`",
        ),
        averages: opt usize = (
            T::Integer { min: 1, max: 1_000_000 },
            "`noise: h1`: the number of impacts or blocks averaged into the measured FRF",
        ),
        sigma_rel: opt f64 = (T::Quantity(D::DIMENSIONLESS), "declared noise: relative noise of each line (e.g. 1.5 %)"),
        floor_rel: opt f64 = (T::Quantity(D::DIMENSIONLESS), "declared noise: absolute floor as a fraction of max|H|"),
        rolloff: opt f64 = (
            T::Quantity(D::FREQUENCY),
            "declared noise: the floor rises as √(1 + (f/rolloff)⁴) beyond the excitation's roll-off",
        ),
        bands: def usize = (T::Integer { min: 1, max: 1000 }, "10", "number of equal-width bands in the `bands` table"),
    }
}

pub struct FrfGap {
    spec: NodeSpec,
}

impl Default for FrfGap {
    fn default() -> Self {
        Self::new()
    }
}

impl FrfGap {
    pub fn new() -> Self {
        FrfGap {
            spec: NodeSpec {
                kind: FRF_GAP,
                version: 3,
                description: "The gap between a model FRF and a measured one: relative complex L2, the noise floor (from the coherence or a declared noise model) and their ratio (about 1 for a model that explains the data), peak-frequency error, where the discrepancy is largest, a per-band table, and the noise-weighted residual a fit minimises.",
                inputs: vec![
                    PortSpec::new(
                        "model",
                        PortType::Frf,
                        "the prediction, on the measured lines (connect the measurement as the model's `grid`)",
                    ),
                    PortSpec::new(
                        "measured",
                        PortType::Frf,
                        "the measurement, with coherence unless the noise is declared",
                    ),
                ],
                outputs: vec![
                    PortSpec::new("ratio", PortType::Scalar, "rel_l2 / noise_floor: about 1 at the noise floor"),
                    PortSpec::new(
                        "summary",
                        PortType::Table,
                        "one row: rel_l2, noise_floor, ratio, peak_model, peak_measured (Hz), peak_freq_error, max_discrepancy (Hz), max_discrepancy_rel, lines, n_eff (effective independent lines: at the floor ratio² is 1 ± 1/√n_eff), speed (rpm), direction (text: x, y, z; empty when unknown)",
                    ),
                    PortSpec::new("bands", PortType::Table, "per band: lo, hi (Hz), rel_l2, noise_floor, ratio, lines"),
                    PortSpec::new(
                        "residual",
                        PortType::Frf,
                        "(H_model − H_meas)/(noise_floor·‖H_meas‖) on the compared lines: Σ|r|² = ratio², the objective of a fit",
                    ),
                ],
                params: GapParams::fields(),
            },
        }
    }
}

fn declared(p: &GapParams) -> Result<Option<NoiseModel>, NodeError> {
    match p.noise {
        "h1" => {
            let n = p.averages.ok_or_else(|| {
                NodeError::param(
                    "averages",
                    "`noise: h1` needs `averages`: how many impacts or blocks the FRF averages",
                )
            })?;
            Ok(Some(NoiseModel::H1 { averages: n as f64 }))
        }
        "declared" => {
            let need = |name: &str, v: Option<f64>| {
                v.ok_or_else(|| {
                    NodeError::param(name, "`noise: declared` needs `sigma_rel`, `floor_rel` and `rolloff`")
                })
            };
            let (sigma_rel, floor_rel, rolloff_hz) =
                (need("sigma_rel", p.sigma_rel)?, need("floor_rel", p.floor_rel)?, need("rolloff", p.rolloff)?);
            Ok(Some(NoiseModel::Declared { sigma_rel, floor_rel, rolloff_hz }))
        }
        _ => Ok(None),
    }
}

impl Node for FrfGap {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = GapParams::read(params)?;
        declared(&p)?;
        super::non_negative(params, &["sigma_rel", "floor_rel"])?;
        super::positive(params, &["rolloff"])?;
        if let Some(b) = p.band
            && (b.len() != 2 || b[0] >= b[1])
        {
            return Err(NodeError::param("band", "give `[low, high]` with low below high"));
        }
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let (Value::Frf(model), Value::Frf(meas)) = (ctx.input("model")?, ctx.input("measured")?) else {
            return Err(NodeError::input("model", "expected FRFs"));
        };
        super::convert::same_kind(meas, "measured", model, "model")?;
        let p = GapParams::read(ctx.params)?;
        let noise = declared(&p)?.unwrap_or(NoiseModel::Coherence);
        let (lo, hi) = match p.band {
            Some([a, b]) => (*a, *b),
            _ => (f64::NEG_INFINITY, f64::INFINITY),
        };
        let (m_lo, m_hi) = match (model.freq_hz.first(), model.freq_hz.last()) {
            (Some(a), Some(b)) => (*a, *b),
            _ => return Err(NodeError::input("model", "the model has no lines")),
        };
        // Pair each measured line in the band with the model's line at the same frequency.
        let (mut f, mut hm, mut hx, mut coh) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let (mut outside, mut bad) = (0usize, 0usize);
        let mut j = 0usize;
        for (k, (&fk, &h)) in meas.freq_hz.iter().zip(&meas.values).enumerate() {
            if fk < lo || fk > hi {
                continue;
            }
            let tol = 1e-9 * fk.abs().max(1.0);
            if fk < m_lo - tol || fk > m_hi + tol {
                outside += 1;
                continue;
            }
            let c = meas.coherence.as_ref().map(|c| c[k]);
            // A line of zero coherence (or one rounded to zero) has no noise estimate.
            if !(h.re.is_finite() && h.im.is_finite()) || c.is_some_and(|c| !(c.is_finite() && c > 0.0)) {
                bad += 1;
                continue;
            }
            while j + 1 < model.freq_hz.len() && model.freq_hz[j] < fk - tol {
                j += 1;
            }
            if (model.freq_hz[j] - fk).abs() > tol {
                return Err(NodeError::input(
                    "model",
                    format!(
                        "the model has no line at {fk} Hz, where the measurement has one (nearest {} Hz): evaluate the model on the measured lines by connecting the measurement as its `grid`",
                        model.freq_hz[j]
                    ),
                ));
            }
            let v = model.values[j];
            if !(v.re.is_finite() && v.im.is_finite()) {
                return Err(NodeError::input("model", format!("the model is not finite at {fk} Hz")));
            }
            f.push(fk);
            hm.push(v);
            hx.push(h);
            if let Some(c) = c {
                coh.push(c);
            }
        }
        if bad > 0 {
            ctx.warn(format!(
                "{bad} measured line(s) are not finite (NaN or infinite) or have zero coherence, and were left out"
            ));
        }
        if f.is_empty() {
            return Err(NodeError::input(
                "measured",
                format!(
                    "no measured line lies in the model's range {m_lo}..{m_hi} Hz{}",
                    if lo.is_finite() { format!(" and the band {lo}..{hi} Hz") } else { String::new() }
                ),
            ));
        }
        if outside > 0 {
            ctx.warn(format!(
                "the model covers {m_lo}..{m_hi} Hz; {outside} measured line(s) outside it were left out, {} compared",
                f.len()
            ));
        }
        let bands = p.bands;
        let coherence = meas.coherence.as_ref().map(|_| coh.as_slice());
        let g =
            gap::gap(&f, &hm, &hx, coherence, noise, bands).map_err(|e| NodeError::input("measured", e.to_string()))?;
        let direction = meas.direction.as_deref().or(model.direction.as_deref()).unwrap_or("");
        let speed = meas.speed.or(model.speed).map_or(f64::NAN, Speed::rpm_as_written);
        let one = |name: &str, unit: &str, v: f64| Column::new(name, unit, vec![v]);
        let summary = Table {
            columns: vec![
                one("rel_l2", "", g.rel_l2),
                one("noise_floor", "", g.noise_floor),
                one("ratio", "", g.ratio),
                one("peak_model", "Hz", g.peak_hz_model),
                one("peak_measured", "Hz", g.peak_hz_measured),
                one("peak_freq_error", "", g.peak_freq_error),
                one("max_discrepancy", "Hz", g.max_discrepancy_hz),
                one("max_discrepancy_rel", "", g.max_discrepancy_rel),
                one("lines", "", g.freq_hz.len() as f64),
                one("n_eff", "", g.n_eff),
                one("speed", "rpm", speed),
                Column::text("direction", &[direction]),
            ],
        };
        let col = |name: &str, unit: &str, get: &dyn Fn(&gap::BandGap) -> f64| {
            Column::new(name, unit, g.bands.iter().map(get).collect())
        };
        let band_table = Table {
            columns: vec![
                col("lo", "Hz", &|b| b.lo_hz),
                col("hi", "Hz", &|b| b.hi_hz),
                col("rel_l2", "", &|b| b.rel_l2),
                col("noise_floor", "", &|b| b.noise_floor),
                col("ratio", "", &|b| b.ratio),
                col("lines", "", &|b| b.lines as f64),
            ],
        };
        let residual = Frf {
            freq_hz: g.freq_hz.clone(),
            values: g.residual.clone(),
            coherence: None,
            unit: UnitLabel::new(""),
            direction: meas.direction.clone(),
            speed: meas.speed,
            sensor: meas.sensor.clone(),
            dofs: meas.dofs,
        };
        Ok([
            ("ratio".to_string(), Value::Scalar(Scalar::new(g.ratio, ""))),
            ("summary".to_string(), Value::Table(summary)),
            ("bands".to_string(), Value::Table(band_table)),
            ("residual".to_string(), Value::Frf(residual)),
        ]
        .into_iter()
        .collect())
    }
}
