//! `stability.speed_dependent`: lobes from tool-point FRFs that change with speed.

use super::{
    COEFFICIENT_ROW, STABILITY_SPEED_DEPENDENT, coefficients_over_speed, lobes_value, milling_named, outputs, pairs,
    speed_list, stab_err, to_rpm, warn_lobes_short, warn_unlimited,
};
use super::{CUTTING, LOBES, RESOLUTION};
use crate::stability::{self, SpeedDependentOptions, SpeedFrf, StabilityError};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType as T, Params};
use spindlelab_engine::value::{Column, PortType, Table, Value};
use spindlelab_grammar::Dimension as D;

/// `stability.speed_dependent`: lobes from tool-point FRFs measured (or predicted) at discrete speeds, spline-
/// interpolated in speed, with the ZOA limit at each speed taken from the FRF at that speed (§6.3), next to the
/// stationary limit of one fixed FRF.
pub struct StabilitySpeedDependent {
    spec: NodeSpec,
}

impl Default for StabilitySpeedDependent {
    fn default() -> Self {
        Self::new()
    }
}

node_params! {
    /// Parameters of `stability.speed_dependent`.
    pub struct SpeedDependentParams<'a> {
        cutting: req &'a str = CUTTING,
        coefficients: opt &'a [Params] = (
            T::ObjectList(COEFFICIENT_ROW),
            "cutting coefficients over speed, rows {speed, Ks, beta} or {speed, Kt, Kn}, cubic in speed \
             (default: the cutting setup's constant coefficients)",
        ),
        speeds: opt &'a [f64] = (
            T::QuantityList(D::ROTATIONAL_SPEED),
            "speeds: an evenly spaced grid, e.g. `1000..4000 step 5 rpm`, or an ascending list (the trials' speeds) (default: the measured span every 5 rpm)",
        ),
        stationary_speed: def f64 = (
            T::Quantity(D::ROTATIONAL_SPEED),
            "0 rpm",
            "speed of the FRFs used for the stationary diagram",
        ),
        extrapolate: def bool = (
            T::Bool,
            "false",
            "extend the end cubics beyond the measured speeds instead of refusing",
        ),
        lobes: opt usize = LOBES,
        resolution: def f64 = RESOLUTION,
    }
}

impl StabilitySpeedDependent {
    pub fn new() -> Self {
        StabilitySpeedDependent {
            spec: NodeSpec {
                kind: STABILITY_SPEED_DEPENDENT,
                version: 1,
                description: "Speed-dependent stability lobes (§6.1–6.3): tool-point FRFs at discrete speeds and cutting coefficients over speed, cubic-spline interpolated; at each speed the ZOA limit of the FRF at that speed, next to the stationary limit of one fixed FRF.",
                inputs: vec![
                    PortSpec::new(
                        "frfs",
                        PortType::Frf,
                        "tool-point receptances (m/N) at several speeds, x and y, as their direction and speed_rpm say",
                    )
                    .collecting(),
                ],
                outputs: vec![
                    PortSpec::new("speed_dependent", PortType::Lobes, "limit with the FRF interpolated at each speed"),
                    PortSpec::new("stationary", PortType::Lobes, "limit with the FRF at stationary_speed throughout"),
                    PortSpec::new(
                        "table",
                        PortType::Table,
                        "speed (rpm); depth_speed_dependent and depth_stationary (m); their chatter frequencies \
                         (Hz); ratio of the two depths",
                    ),
                ],
                params: SpeedDependentParams::fields(),
            },
        }
    }
}

/// The speed grid as (first, last, step) rpm, from an evenly spaced list.
fn grid(speeds: Option<&[f64]>) -> Result<Option<(f64, f64, f64)>, NodeError> {
    let Some(rpm) = speeds.map(speed_list) else {
        return Ok(None);
    };
    if rpm.is_empty() {
        return Err(NodeError::param("speeds", "give an evenly spaced ascending grid, e.g. `1000..4000 step 5 rpm`"));
    }
    let (lo, hi) = (rpm[0], rpm[rpm.len() - 1]);
    if rpm.len() == 1 {
        return Ok(Some((lo, hi, 5.0)));
    }
    let step = rpm[1] - rpm[0];
    if step.is_nan() || step <= 0.0 || rpm.windows(2).any(|w| ((w[1] - w[0]) - step).abs() > 1e-6 * step.max(1.0)) {
        // An explicit ascending list (the speeds of the trials, say): the step is NaN.
        if rpm.iter().all(|s| s.is_finite()) && rpm.windows(2).all(|w| w[1] > w[0]) {
            return Ok(Some((lo, hi, f64::NAN)));
        }
        return Err(NodeError::param(
            "speeds",
            "give an ascending list or an evenly spaced grid, e.g. `1000..4000 step 5 rpm`",
        ));
    }
    Ok(Some((lo, hi, step)))
}

impl Node for StabilitySpeedDependent {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = SpeedDependentParams::read(params)?;
        super::non_negative(params, &["stationary_speed"])?;
        super::positive(params, &["resolution"])?;
        grid(p.speeds).map(|_| ())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = SpeedDependentParams::read(ctx.params)?;
        let mill = milling_named(ctx, p.cutting)?;
        let measured = pairs(ctx)?;
        let stationary_rpm = to_rpm(p.stationary_speed);
        let stationary = measured
            .iter()
            .find(|(s, _)| (s - stationary_rpm).abs() <= 1e-6 * s.abs().max(1.0))
            .map(|(_, f)| f.clone())
            .ok_or_else(|| {
                let have: Vec<String> = measured.iter().map(|(s, _)| format!("{s}")).collect();
                NodeError::param(
                    "stationary_speed",
                    format!("no FRFs at {stationary_rpm} rpm; the FRFs are at {} rpm", have.join(", ")),
                )
            })?;
        let span = (measured[0].0, measured[measured.len() - 1].0);
        let range = grid(p.speeds)?;
        let options = SpeedDependentOptions {
            range_rpm: range.map(|(lo, hi, _)| (lo, hi)),
            step_rpm: range.map_or(5.0, |r| if r.2.is_nan() { 5.0 } else { r.2 }),
            lobes: p.lobes,
            allow_extrapolation: p.extrapolate,
            speeds_rpm: range.filter(|r| r.2.is_nan()).and_then(|_| p.speeds.map(speed_list)),
            resolution_hz: Some(p.resolution),
        };
        let law = ctx.entities.cutting.get(p.cutting);
        let span = range.map_or(span, |(lo, hi, _)| (lo.min(span.0), hi.max(span.1)));
        let coeffs = coefficients_over_speed(p.coefficients, &mill, law, span)?;
        let frfs: Vec<SpeedFrf> = measured.into_iter().map(|(speed_rpm, frf)| SpeedFrf { speed_rpm, frf }).collect();
        let limits = stability::speed_dependent_lobes(
            &frfs,
            &coeffs,
            mill.teeth,
            mill.radial_immersion,
            mill.direction,
            &stationary,
            &options,
        )
        .map_err(|e| match e {
            StabilityError::Extrapolation { what: "cutting coefficient table", .. } => NodeError::param(
                "coefficients",
                format!("{e} (`speeds` narrower than the table, or `extrapolate: true`)"),
            ),
            StabilityError::Extrapolation { .. } => {
                NodeError::param("speeds", format!("{e} (`extrapolate: true` extends the end cubics)"))
            }
            StabilityError::InvalidParameter { name: "cutting coefficient speeds", .. } => {
                NodeError::param("coefficients", e.to_string())
            }
            other => stab_err(other, "frfs"),
        })?;
        let (sd, st) = (&limits.speed_dependent, &limits.stationary);
        if sd.speed_rpm.is_empty() {
            return Err(NodeError::param("speeds", "the grid holds no speed above 0 rpm"));
        }
        warn_lobes_short(ctx, limits.lobe_count, limits.lobes_needed, limits.band_top_hz, mill.teeth, sd.speed_rpm[0]);
        warn_unlimited(ctx, "speed-dependent", sd);
        warn_unlimited(ctx, "stationary", st);
        let table = Table {
            columns: vec![
                Column::new("speed", "rpm", sd.speed_rpm.clone()),
                Column::new("depth_speed_dependent", "m", sd.depth_m.clone()),
                Column::new("depth_stationary", "m", st.depth_m.clone()),
                Column::new("chatter_speed_dependent", "Hz", sd.chatter_hz.clone()),
                Column::new("chatter_stationary", "Hz", st.chatter_hz.clone()),
                Column::new("depth_ratio", "", sd.depth_m.iter().zip(&st.depth_m).map(|(a, b)| a / b).collect()),
            ],
        };
        Ok(outputs(vec![
            ("speed_dependent", Value::Lobes(lobes_value(sd))),
            ("stationary", Value::Lobes(lobes_value(st))),
            ("table", Value::Table(table)),
        ]))
    }
}
