//! Milling stability nodes (dissertation ch. 6): `stability.lobes` (ZOA on tool-point FRFs), `stability.sd`
//! (semi-discretization on modal models), `stability.speed_dependent` (§6.1–6.3), `chatter.detect` (§6.4,
//! Eq. 5.1 of ch. 6) and `trials.score` (cutting trials against a diagram).
//!
//! The cut comes from a recipe `cutting` entity (teeth, radial immersion, up/down, `Kt = Ks sin β`,
//! `Kn = Ks cos β`); `x` is the feed direction (force convention in [`crate::stability`]).

mod best;
mod chatter;
mod lobes;
mod modal_model;
mod probability;
mod sd;
mod speed_dependent;
mod trials;

pub use best::StabilityBest;
pub use chatter::ChatterDetect;
pub use lobes::StabilityLobes;
pub use modal_model::ModalModelNode;
pub use probability::StabilityProbability;
pub use sd::StabilitySd;
pub use speed_dependent::StabilitySpeedDependent;
pub use trials::TrialsScore;

// The kinds' `super::positive` and `super::non_negative` are the checks of `nodes`.
use super::{non_negative, positive};
use crate::stability::{
    self, CoefficientTable, CuttingCoefficients, Milling, MillingDirection, Outcome, ProcessDamping, StabilityError,
    StabilityLimit, ToolPointFrf, Trial,
};
use spindlelab_domain::Speed;
use spindlelab_engine::node::{NodeContext, NodeError, Outputs};
use spindlelab_engine::spec::{EntityKind, Field, FieldType as T, Params};
use spindlelab_engine::value::{Frf, Lobes, ModalModel, Value};
use spindlelab_grammar::Dimension as D;
use std::path::Path;

// Fields several kinds of this module share, declared once (`node_params!` names them).
pub(super) const CUTTING: Field =
    Field::req("cutting", T::Entity(EntityKind::Cutting), "the cut: teeth, radial immersion, up/down, Kt/Kn or Ks/β");
pub(super) const SPEEDS: Field =
    Field::req("speeds", T::QuantityList(D::ROTATIONAL_SPEED), "spindle speeds, ascending");
pub(super) const LOBES: Field = Field::opt(
    "lobes",
    T::Integer { min: 1, max: stability::MAX_LOBES as i64 },
    "number of lobes k = 0 … lobes − 1; by default as many as reach the FRF band's highest significant response (within 40 dB of its peak) down to the slowest speed: ⌈60 f_max/(N n_min)⌉ + 1",
);
pub(super) const RESOLUTION: Field = Field::def(
    "resolution",
    T::Quantity(D::FREQUENCY),
    "1 Hz",
    "coarsest line spacing the lobes are resolved at: FRFs on a coarser grid are interpolated (cubic Hermite of the complex receptance) so a lobe's minimum is not cut off between two lines",
);

/// Tooth pitch of `stability.sd` and `milling.simulate`.
pub(super) const PITCH: Field = Field::opt(
    "pitch",
    T::QuantityList(D::ANGLE),
    "variable (unequal) tooth pitch: one angle per tooth, summing to 360°, each the angle from a tooth forward to the next one (the tooth that passed the same angle just before it, so tooth j regenerates over pitch_j/Ω), e.g. `[80 deg, 100 deg, 80 deg, 100 deg]` (default: equally spaced, 360°/N)",
);
/// Helix angle of `stability.sd` and `milling.simulate`.
pub(super) const HELIX: Field = Field::opt(
    "helix",
    T::Quantity(D::ANGLE),
    "helix angle η of the flutes, below 90°, with `diameter`: the edge at height z above the tip lags it by 2 z tan η/D, and the force is averaged over the depth (default 0°: straight teeth)",
);
/// Tool diameter for the helix lag.
pub(super) const DIAMETER: Field = Field::opt(
    "diameter",
    T::Quantity(D::LENGTH),
    "tool diameter D, for the helix lag 2 z tan η/D (needed with `helix`)",
);

/// The dimension of the specific indentation force `K_d`: force per volume, N/m³.
pub(crate) const FORCE_PER_VOLUME: D = D::new(-2, 1, -2, 0);

/// The fields of `process_damping` (`stability.lobes`, `milling.simulate`): the flank contact of the process damping model of
/// [`crate::stability::process_damping`], all three together.
pub(crate) const PROCESS_DAMPING: &[Field] = &[
    Field::req(
        "indentation",
        T::Quantity(FORCE_PER_VOLUME),
        "specific indentation force K_d (force per indented volume), e.g. `30000 N/mm^3`; steels: of order 10⁴ N/mm³",
    ),
    Field::req(
        "wear_land",
        T::Quantity(D::LENGTH),
        "flank wear land w: the width of the flank that rubs the wavy surface, e.g. `0.05 mm`",
    ),
    Field::req("diameter", T::Quantity(D::LENGTH), "tool diameter D, for the cutting speed V = π D n/60"),
];

/// The `process_damping` object as the kernel's contact (errors name the parameter and the field).
pub(crate) fn process_damping(p: &Params) -> Result<ProcessDamping, NodeError> {
    let field = |name: &str| {
        p.f64(name).ok_or_else(|| {
            NodeError::param(
                "process_damping",
                format!("`{name}` is missing: give `indentation`, `wear_land` and `diameter` together"),
            )
        })
    };
    let (kd, w, d) = (field("indentation")?, field("wear_land")?, field("diameter")?);
    for (name, v) in [("indentation", kd), ("wear_land", w), ("diameter", d)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(NodeError::param("process_damping", format!("`{name}` must be positive, got {v}")));
        }
    }
    ProcessDamping::new(kd, w, d).map_err(|e| NodeError::param("process_damping", e.to_string()))
}

/// `mill` with the tool geometry of a node's `pitch` (rad, one per tooth), `helix` (rad) and `diameter` (m)
/// parameters; errors name the parameter.
pub(super) fn with_geometry(
    mill: Milling,
    pitch: Option<&[f64]>,
    helix: Option<f64>,
    diameter: Option<f64>,
) -> Result<Milling, NodeError> {
    let mut mill = mill;
    if let Some(p) = pitch {
        let teeth = mill.teeth;
        mill = mill
            .with_pitch(p.to_vec())
            .map_err(|e| NodeError::param("pitch", format!("{e} (the cutting setup has {teeth} teeth)")))?;
    }
    if let Some(h) = helix.filter(|h| *h != 0.0) {
        let d = diameter.ok_or_else(|| {
            NodeError::param(
                "diameter",
                "give the tool diameter with `helix` (e.g. `diameter: 12 mm`): the helix lag is 2 z tan η/D",
            )
        })?;
        mill = mill.with_helix(h, d).map_err(|e| NodeError::param("helix", e.to_string()))?;
    }
    Ok(mill)
}

/// The kind name of `stability.speed_dependent`: lobes from tool-point FRFs that change with speed.
pub const STABILITY_SPEED_DEPENDENT: &str = "stability.speed_dependent";
/// The kind name of `trials.score`: cutting trials scored against lobes.
pub const TRIALS_SCORE: &str = "trials.score";

/// A speed parameter (rad/s) in rpm as the recipe wrote it.
pub(super) fn to_rpm(w: f64) -> f64 {
    Speed::from_rad_s(w).rpm_as_written()
}

/// Warns when an explicit `lobes` leaves part of the FRF band unreached at the slowest speed.
fn warn_lobes_short(ctx: &NodeContext, count: usize, needed: usize, band_top_hz: f64, teeth: usize, n_min_rpm: f64) {
    if count < needed {
        let reached = count as f64 * teeth as f64 * n_min_rpm / 60.0;
        ctx.warn(format!(
            "`lobes: {count}` reaches chatter frequencies up to {reached:.0} Hz at {n_min_rpm} rpm, but the FRFs \
             respond significantly up to {band_top_hz:.0} Hz, which needs {needed} lobes there: the limit may be \
             too high at the low speeds (drop `lobes` for the automatic count)"
        ));
    }
}

/// The cutting entity a node's `cutting` parameter names, as the kernels' [`Milling`] (its constant
/// coefficients).
pub(super) fn milling(ctx: &NodeContext) -> Result<Milling, NodeError> {
    let name = ctx.params.text("cutting").ok_or_else(|| NodeError::param("cutting", "missing"))?;
    milling_named(ctx, name)
}

/// The cutting entity `name` of the recipe, as the kernels' [`Milling`] (its constant coefficients).
fn milling_named(ctx: &NodeContext, name: &str) -> Result<Milling, NodeError> {
    let c = ctx
        .entities
        .cutting
        .get(name)
        .ok_or_else(|| NodeError::param("cutting", format!("no cutting setup `{name}` in the recipe")))?;
    let direction = if c.up_milling { MillingDirection::Up } else { MillingDirection::Down };
    let coefficients = CuttingCoefficients::from_kt_kn(c.kt, c.kn)
        .map_err(|e| NodeError::param("cutting", format!("cutting setup `{name}`: {e}")))?;
    Milling::new(c.teeth as usize, c.radial_immersion, direction, coefficients)
        .map_err(|e| NodeError::param("cutting", format!("cutting setup `{name}`: {e}")))
}

/// The `speeds` parameter (rad/s, a list or a range as checked) in rpm.
fn speed_list(speeds: &[f64]) -> Vec<f64> {
    speeds.iter().map(|&w| to_rpm(w)).collect()
}

/// The `speeds` list in rpm, ascending and positive.
fn speeds_rpm(speeds: &[f64]) -> Result<Vec<f64>, NodeError> {
    let rpm: Vec<f64> = speed_list(speeds);
    if rpm.is_empty() {
        return Err(NodeError::param("speeds", "give at least one spindle speed, e.g. `1000..20000 step 10 rpm`"));
    }
    if let Some(s) = rpm.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
        return Err(NodeError::param("speeds", format!("{s} rpm: every speed must be positive")));
    }
    if rpm.windows(2).any(|w| w[1] <= w[0]) {
        return Err(NodeError::param("speeds", "the speeds must increase, e.g. `1000..20000 step 10 rpm`"));
    }
    Ok(rpm)
}

/// A tool-point receptance input, checked to be in m/N.
fn receptance<'a>(ctx: &'a NodeContext, port: &str) -> Result<&'a Frf, NodeError> {
    let Value::Frf(f) = ctx.input(port)? else {
        return Err(NodeError::input(port, "expected an FRF"));
    };
    check_unit(f, port)?;
    Ok(f)
}

fn check_unit(f: &Frf, port: &str) -> Result<(), NodeError> {
    if !f.unit.symbol.is_empty() && f.unit.symbol != "m/N" {
        return Err(NodeError::input(
            port,
            format!("unit `{}`: stability needs tool-point receptances in m/N", f.unit.symbol),
        ));
    }
    Ok(())
}

/// Maps a kernel error to the port or parameter it is about.
fn stab_err(e: StabilityError, frf_port: &str) -> NodeError {
    match &e {
        StabilityError::NoTeeth | StabilityError::Immersion(_) => NodeError::param("cutting", e.to_string()),
        StabilityError::GridMismatch { .. }
        | StabilityError::NonFinite { .. }
        | StabilityError::NoResonance { .. }
        | StabilityError::InvalidMode { .. } => NodeError::input(frf_port, e.to_string()),
        StabilityError::TooManyLobes { .. } => NodeError::param("lobes", e.to_string()),
        StabilityError::UnequalPitch => NodeError::param("pitch", e.to_string()),
        _ => NodeError::Failed(e.to_string()),
    }
}

fn lobes_value(l: &StabilityLimit) -> Lobes {
    Lobes::from_rpm(&l.speed_rpm, l.depth_m.clone(), l.chatter_hz.clone())
}

/// Warns about the speeds where no lobe of the band limits the cut (depth `+∞`: no limit found, not a promise).
fn warn_unlimited(ctx: &NodeContext, what: &str, l: &StabilityLimit) {
    let open: Vec<f64> = l.speed_rpm.iter().zip(&l.depth_m).filter(|(_, d)| d.is_infinite()).map(|(s, _)| *s).collect();
    if let (Some(first), Some(last)) = (open.first(), open.last()) {
        ctx.warn(format!(
            "{what}: no lobe limits the cut at {} of {} speeds ({first}–{last} rpm); their limit is +∞ (raise `lobes` \
             or widen the FRF band)",
            open.len(),
            l.speed_rpm.len()
        ));
    }
}

fn outputs(items: Vec<(&str, Value)>) -> Outputs {
    items.into_iter().map(|(k, v)| (k.to_string(), v)).collect()
}

pub(super) fn modal(ctx: &NodeContext, port: &str) -> Result<Vec<stability::Mode>, NodeError> {
    let Value::ModalModel(ModalModel { modes }) = ctx.input(port)? else {
        return Err(NodeError::input(port, "expected a modal model"));
    };
    Ok(modes.clone())
}

pub(super) const COEFFICIENT_ROW: &[Field] = &[
    Field::req("speed", T::Quantity(D::ROTATIONAL_SPEED), "spindle speed of the measurement"),
    Field::opt("Ks", T::Quantity(D::PRESSURE), "specific cutting force (with beta)"),
    Field::opt("beta", T::Quantity(D::ANGLE), "force angle: Kt = Ks sin β, Kn = Ks cos β"),
    Field::opt("Kt", T::Quantity(D::PRESSURE), "tangential coefficient (with Kn)"),
    Field::opt("Kn", T::Quantity(D::PRESSURE), "normal coefficient (with Kt)"),
];

/// The cutting coefficients over speed of a node's `coefficients` parameter (see [`coefficients_over_speed`]).
pub(super) fn coefficient_table(
    p: &Params,
    mill: &Milling,
    law: Option<&spindlelab_engine::model::Cutting>,
    span: (f64, f64),
) -> Result<CoefficientTable, NodeError> {
    coefficients_over_speed(p.objects("coefficients"), mill, law, span)
}

/// The cutting coefficients over speed: the `coefficients` rows, else the cutting setup's speed law or its
/// constant coefficients over `span` (rpm).
fn coefficients_over_speed(
    rows: Option<&[Params]>,
    mill: &Milling,
    law: Option<&spindlelab_engine::model::Cutting>,
    span: (f64, f64),
) -> Result<CoefficientTable, NodeError> {
    let Some(rows) = rows else {
        let c = mill.coefficients;
        let (lo, hi) = (span.0.min(0.0) - 1.0, span.1.max(span.0) + 1.0);
        // The cutting setup's linear speed law, sampled at knots a cubic reproduces exactly.
        if let Some(cut) = law.filter(|c| c.ks_change != 0.0 || c.beta_change != 0.0) {
            let (Some(reference), per) =
                (cut.calibrated_at.map(Speed::rpm_as_written), cut.change_per.rpm_as_written())
            else {
                return Err(NodeError::param("cutting", "a speed law needs `calibrated_at`"));
            };
            let (ks, beta) = (c.kt.hypot(c.kn), c.kt.atan2(c.kn));
            let rows: Vec<[f64; 3]> = (0..4)
                .map(|i| {
                    let n = lo + (hi - lo) * i as f64 / 3.0;
                    let t = (n - reference) / per;
                    [n, ks * (1.0 + cut.ks_change * t), beta + cut.beta_change * t]
                })
                .collect();
            let physical = |r: &[f64; 3]| r[1] > 0.0 && r[2] > 0.0 && r[2] < std::f64::consts::PI;
            if !rows.iter().all(physical) {
                return Err(NodeError::param(
                    "cutting",
                    format!("the speed law gives Ks ≤ 0 or β outside (0, 180°) within {lo:.0}–{hi:.0} rpm"),
                ));
            }
            return Ok(CoefficientTable::KsBeta(rows));
        }
        // Constant coefficients: a flat spline through two knots covering every speed.
        return Ok(CoefficientTable::KtKn(vec![[lo, c.kt, c.kn], [hi, c.kt, c.kn]]));
    };
    if rows.is_empty() {
        return Err(NodeError::param("coefficients", "the table is empty; give rows or leave it out"));
    }
    let pair = |r: &Params| match (r.f64("Ks"), r.f64("beta"), r.f64("Kt"), r.f64("Kn")) {
        (Some(a), Some(b), None, None) => Some((true, a, b)),
        (None, None, Some(a), Some(b)) => Some((false, a, b)),
        _ => None,
    };
    let mut out = Vec::with_capacity(rows.len());
    let mut ks_beta = None;
    for (i, r) in rows.iter().enumerate() {
        let Some((is_ks, a, b)) = pair(r) else {
            return Err(NodeError::param(
                "coefficients",
                format!("row {}: give exactly one pair, `Ks` with `beta` or `Kt` with `Kn`", i + 1),
            ));
        };
        if *ks_beta.get_or_insert(is_ks) != is_ks {
            return Err(NodeError::param(
                "coefficients",
                "mixes Ks/beta rows with Kt/Kn rows; use one pair throughout",
            ));
        }
        out.push([to_rpm(r.f64("speed").unwrap_or(0.0)), a, b]);
    }
    if let Some(i) = out.windows(2).position(|w| w[1][0] <= w[0][0]) {
        return Err(NodeError::param(
            "coefficients",
            format!("row {}: speed {} rpm does not increase on the row before; sort the rows", i + 2, out[i + 1][0]),
        ));
    }
    Ok(if ks_beta == Some(true) { CoefficientTable::KsBeta(out) } else { CoefficientTable::KtKn(out) })
}

/// Groups the collected FRFs by speed into x/y pairs, ascending in speed.
pub(super) fn pairs(ctx: &NodeContext) -> Result<Vec<(f64, ToolPointFrf)>, NodeError> {
    let items = ctx.inputs_of("frfs");
    if items.is_empty() {
        return Err(NodeError::input("frfs", "no FRFs arrived; feed tool-point FRFs at several speeds"));
    }
    let mut by_speed: Vec<(f64, Option<&Frf>, Option<&Frf>)> = Vec::new();
    for it in items {
        let Value::Frf(f) = it.value.as_ref() else {
            return Err(NodeError::input("frfs", "expected FRFs"));
        };
        check_unit(f, "frfs")?;
        // The FRF's own speed, else the `speed` sweep coordinate of the step that made it (a record at rest
        // carries no tachometer speed).
        let coord = it
            .coords
            .iter()
            .find(|c| c.name == "speed" && c.unit == D::ROTATIONAL_SPEED.si_unit())
            .map(|c| to_rpm(c.value));
        let speed = f.speed.map(Speed::rpm_as_written).or(coord).ok_or_else(|| {
            NodeError::input(
                "frfs",
                format!(
                    "the FRF `{}` carries no speed_rpm and no speed sweep coordinate; give FRFs made at a known speed",
                    it.label
                ),
            )
        })?;
        let slot = match by_speed.iter().position(|(s, _, _)| (s - speed).abs() <= 1e-6 * speed.abs().max(1.0)) {
            Some(i) => i,
            None => {
                by_speed.push((speed, None, None));
                by_speed.len() - 1
            }
        };
        let entry = &mut by_speed[slot];
        // The FRF's own direction, else the `direction` the upstream sweep assigned (its label).
        let swept = it.label.split(", ").find_map(|a| a.strip_prefix("direction="));
        let place = match f.direction.as_deref().or(swept) {
            Some("x") => &mut entry.1,
            Some("y") => &mut entry.2,
            other => {
                return Err(NodeError::input(
                    "frfs",
                    format!(
                        "the FRF `{}` has direction {other:?}; each must be `x` or `y` (its own, or swept as `direction`)",
                        it.label
                    ),
                ));
            }
        };
        if place.replace(f).is_some() {
            return Err(NodeError::input(
                "frfs",
                format!(
                    "two FRFs along one direction at {speed} rpm (the second is `{}`); give one per direction and speed",
                    it.label
                ),
            ));
        }
    }
    by_speed.sort_by(|a, b| a.0.total_cmp(&b.0));
    by_speed
        .into_iter()
        .map(|(s, x, y)| match (x, y) {
            (Some(x), Some(y)) => ToolPointFrf::from_pair(&x.freq_hz, x.values.clone(), &y.freq_hz, y.values.clone())
                .map(|f| (s, f))
                .map_err(|e| NodeError::input("frfs", format!("at {s} rpm: {e}"))),
            _ => Err(NodeError::input(
                "frfs",
                format!(
                    "at {s} rpm only the {} FRF arrived; each speed needs both x and y",
                    if x.is_some() { "x" } else { "y" }
                ),
            )),
        })
        .collect()
}

/// The trials of the node's `file` parameter.
pub(super) fn read_trials(ctx: &NodeContext) -> Result<Vec<Trial>, NodeError> {
    let path = ctx.params.file("file").ok_or_else(|| NodeError::param("file", "missing"))?;
    trials_in(path)
}

/// The trials of the CSV file at `path` (errors name the `file` parameter).
fn trials_in(path: &Path) -> Result<Vec<Trial>, NodeError> {
    let bytes = spindlelab_engine::formats::read_capped(path, spindlelab_engine::formats::MAX_DATA_BYTES)
        .map_err(|e| NodeError::param("file", format!("cannot read {}: {e}", path.display())))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| NodeError::param("file", format!("{} is not UTF-8 text", path.display())))?;
    parse_trials(&text, &path.display().to_string())
}

/// Parses the trials CSV: a header row naming the columns, then one trial per row; `#` lines are comments.
pub fn parse_trials(text: &str, path: &str) -> Result<Vec<Trial>, NodeError> {
    let bad = |line: usize, what: String| NodeError::param("file", format!("{path}:{line}: {what}"));
    let mut rows = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((hl, header)) = rows.next() else {
        return Err(NodeError::param(
            "file",
            format!("{path}: no trials; write `rpm,depth_mm,outcome` and one row per cut"),
        ));
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let col = |n: &str| names.iter().position(|h| h.eq_ignore_ascii_case(n));
    let (Some(ci_rpm), Some(ci_depth), Some(ci_out)) = (col("rpm"), col("depth_mm"), col("outcome")) else {
        return Err(bad(hl + 1, format!("header `{header}` must name the columns rpm, depth_mm and outcome")));
    };
    let ci_freq = col("chatter_freq_hz");
    let mut trials = Vec::new();
    for (i, line) in rows {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let cell = |c: usize| cells.get(c).copied().unwrap_or("");
        let number = |c: usize, what: &str| -> Result<f64, NodeError> {
            cell(c)
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(i + 1, format!("{what} `{}` is not a finite number", cell(c))))
        };
        let rpm = number(ci_rpm, "rpm")?;
        let depth_mm = number(ci_depth, "depth_mm")?;
        if rpm <= 0.0 || depth_mm <= 0.0 {
            return Err(bad(i + 1, "speed and depth must be positive".into()));
        }
        let outcome = match cell(ci_out).to_ascii_lowercase().as_str() {
            "stable" => Outcome::Stable,
            "chatter" => Outcome::Chatter,
            other => return Err(bad(i + 1, format!("outcome `{other}` must be `stable` or `chatter`"))),
        };
        let chatter_hz = match ci_freq.map(cell) {
            None | Some("") => None,
            Some(_) => Some(number(ci_freq.unwrap_or(0), "chatter_freq_hz")?),
        };
        trials.push(Trial { speed_rpm: rpm, depth_m: depth_mm * 1e-3, outcome, chatter_hz });
    }
    if trials.is_empty() {
        return Err(NodeError::param("file", format!("{path}: the header is there but no trial follows")));
    }
    Ok(trials)
}
