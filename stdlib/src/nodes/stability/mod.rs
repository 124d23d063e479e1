//! Milling stability nodes (dissertation ch. 6): `stability.lobes` (ZOA on tool-point FRFs), `stability.sd`
//! (semi-discretization on modal models), `stability.speed_dependent` (§6.1–6.3), `chatter.detect` (§6.4,
//! Eq. 5.1 of ch. 6) and `trials.score` (cutting trials against a diagram).
//!
//! The cut comes from a recipe `cutting` entity (teeth, radial immersion, up/down, `Kt = Ks sin β`,
//! `Kn = Ks cos β`); `x` is the feed direction (force convention in [`crate::stability`]).

use crate::chatter::{self, ChatterError, ChatterKind, ChatterOptions, Record};
use crate::stability::{
    self, Bifurcation, CoefficientTable, CuttingCoefficients, Milling, MillingDirection, Outcome, SdOptions,
    SpeedDependentOptions, SpeedFrf, StabilityError, StabilityLimit, StepCount, ToolPointFrf, Trial, TrialLikelihood,
    Verdict, ZoaOptions,
};
use spindlelab_domain::Speed;
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, Field, FieldType as T, Params};
use spindlelab_engine::value::{Channel, Column, Frf, Lobes, ModalModel, PortType, Scalar, Table, TimeSeries, Value};
use spindlelab_grammar::Dimension as D;
use std::path::Path;

/// A speed parameter (rad/s) in rpm as the recipe wrote it.
pub(super) fn to_rpm(w: f64) -> f64 {
    Speed::from_rad_s(w).rpm_as_written()
}

/// The `cutting` field the kinds here and in `milling.rs` declare (their tables are checked against it in
/// tests).
#[cfg_attr(not(test), allow(dead_code))]
pub(super) fn cutting_param() -> Field {
    Field::req("cutting", T::Entity(EntityKind::Cutting), "the cut: teeth, radial immersion, up/down, Kt/Kn or Ks/β")
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
        _ => NodeError::Failed(e.to_string()),
    }
}

fn lobes_value(l: &StabilityLimit) -> Lobes {
    Lobes { speed_rpm: l.speed_rpm.clone(), depth_limit: l.depth_m.clone(), chatter_hz: l.chatter_hz.clone() }
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

// ------------------------------------------------------------------ stability.lobes

/// The kind name of `stability.speed_dependent`: lobes from tool-point FRFs that change with speed.
pub const STABILITY_SPEED_DEPENDENT: &str = "stability.speed_dependent";
/// The kind name of `trials.score`: cutting trials scored against lobes.
pub const TRIALS_SCORE: &str = "trials.score";

node_params! {
    /// Parameters of `stability.lobes`.
    pub struct LobesParams<'a> {
        cutting: req &'a str = (
            T::Entity(EntityKind::Cutting),
            "the cut: teeth, radial immersion, up/down, Kt/Kn or Ks/β",
        ),
        speeds: req &'a [f64] = (T::QuantityList(D::ROTATIONAL_SPEED), "spindle speeds, ascending"),
        lobes: opt usize = (
            T::Integer { min: 1, max: stability::MAX_LOBES as i64 },
            "number of lobes k = 0 … lobes − 1; by default as many as reach the FRF band's highest significant \
             response (within 40 dB of its peak) down to the slowest speed: ⌈60 f_max/(N n_min)⌉ + 1",
        ),
        resolution: def f64 = (
            T::Quantity(D::FREQUENCY),
            "1 Hz",
            "coarsest line spacing the lobes are resolved at: FRFs on a coarser grid are interpolated (cubic Hermite of the complex receptance) so a lobe's minimum is not cut off between two lines",
        ),
    }
}

/// `stability.lobes`: the ZOA stability limit (Altintas & Budak 1995) from tool-point FRFs in x and y.
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
                description: "Stability lobes by the zero-order approximation (Altintas & Budak 1995) from tool-point FRFs in x (feed) and y: limiting depth and chatter frequency over speed.",
                inputs: vec![
                    PortSpec::new("frf_x", PortType::Frf, "tool-point receptance along x, the feed direction (m/N)"),
                    PortSpec::new("frf_y", PortType::Frf, "tool-point receptance along y, on the grid of frf_x (m/N)"),
                ],
                outputs: vec![
                    PortSpec::new("lobes", PortType::Lobes, "lowest lobe through each speed: depth (m), chatter (Hz)"),
                    PortSpec::new(
                        "table",
                        PortType::Table,
                        "speed (rpm), depth_limit (m), chatter_frequency (Hz), lobe k (−1 where none limits)",
                    ),
                ],
                params: LobesParams::fields(),
            },
        }
    }
}

impl Node for StabilityLobes {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = LobesParams::read(params)?;
        super::positive(params, &["resolution"])?;
        speeds_rpm(p.speeds).map(|_| ())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = LobesParams::read(ctx.params)?;
        let (fx, fy) = (receptance(ctx, "frf_x")?, receptance(ctx, "frf_y")?);
        let mill = milling_named(ctx, p.cutting)?;
        let frf = ToolPointFrf::from_pair(&fx.freq_hz, fx.values.clone(), &fy.freq_hz, fy.values.clone())
            .map_err(|e| stab_err(e, "frf_y"))?;
        let opts = ZoaOptions {
            lobes: p.lobes,
            speeds_rpm: speeds_rpm(p.speeds)?,
            keep_lobes: false,
            resolution_hz: Some(p.resolution),
        };
        let z = stability::zoa_lobes(&frf, &mill, &opts).map_err(|e| stab_err(e, "frf_x"))?;
        warn_lobes_short(ctx, z.lobe_count, z.lobes_needed, z.band_top_hz, mill.teeth, opts.speeds_rpm[0]);
        warn_unlimited(ctx, "lobes", &z.limit);
        let l = &z.limit;
        let table = Table {
            columns: vec![
                Column::new("speed", "rpm", l.speed_rpm.clone()),
                Column::new("depth_limit", "m", l.depth_m.clone()),
                Column::new("chatter_frequency", "Hz", l.chatter_hz.clone()),
                Column::new("lobe", "", l.lobe.iter().map(|k| k.map_or(-1.0, |k| k as f64)).collect()),
            ],
        };
        Ok(outputs(vec![("lobes", Value::Lobes(lobes_value(l))), ("table", Value::Table(table))]))
    }
}

// ------------------------------------------------------------------ stability.sd

node_params! {
    /// Parameters of `stability.sd`.
    pub struct SdParams<'a> {
        cutting: req &'a str = (
            T::Entity(EntityKind::Cutting),
            "the cut: teeth, radial immersion, up/down, Kt/Kn or Ks/β",
        ),
        speeds: req &'a [f64] = (T::QuantityList(D::ROTATIONAL_SPEED), "spindle speeds, ascending"),
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
    }
}

/// `stability.sd`: the limiting depth per speed by first-order semi-discretization (Insperger & Stépán 2002,
/// 2004) of the tool-point modal models.
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
                version: 3,
                description: "Limiting depth per speed by first-order semi-discretization (Insperger & Stépán) of tool-point modal models in x (feed) and y, with the kind of chatter (Hopf or flip); spectral radii on a speed × depth grid.",
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
                        "speed (rpm), depth_limit (m), chatter_frequency (Hz), kind (0 none, 1 Hopf, 2 flip, 3 fold), \
                         restabilises (1 if a larger scanned depth is stable again), steps (per tooth period used)",
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

pub(super) fn modal(ctx: &NodeContext, port: &str) -> Result<Vec<stability::Mode>, NodeError> {
    let Value::ModalModel(ModalModel { modes }) = ctx.input(port)? else {
        return Err(NodeError::input(port, "expected a modal model"));
    };
    Ok(modes.clone())
}

impl Node for StabilitySd {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = SdParams::read(params)?;
        super::positive(params, &["max_depth", "tolerance"])?;
        speeds_rpm(p.speeds).map(|_| ())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = SdParams::read(ctx.params)?;
        let model = stability::ModalModel::new(modal(ctx, "modes_x")?, modal(ctx, "modes_y")?)
            .map_err(|e| stab_err(e, "modes_x"))?;
        if model.x.is_empty() && model.y.is_empty() {
            return Err(NodeError::input("modes_x", "neither modes_x nor modes_y holds a mode: nothing can chatter"));
        }
        let mill = milling_named(ctx, p.cutting)?;
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
            None => 0.0,
            Some(Bifurcation::Hopf) => 1.0,
            Some(Bifurcation::Flip) => 2.0,
            Some(Bifurcation::Fold) => 3.0,
        };
        let depth: Vec<f64> = limits.iter().map(|d| d.depth_m).collect();
        let table = Table {
            columns: vec![
                Column::new("speed", "rpm", speeds.clone()),
                Column::new("depth_limit", "m", depth.clone()),
                Column::new("chatter_frequency", "Hz", chatter.clone()),
                Column::new("kind", "", limits.iter().map(kind).collect()),
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
        let lobes = Lobes { speed_rpm: speeds, depth_limit: depth, chatter_hz: chatter };
        Ok(outputs(vec![("lobes", Value::Lobes(lobes)), ("table", Value::Table(table)), ("map", Value::Table(map))]))
    }
}

// ------------------------------------------------------------------ modal.model

/// `modal.model`: tool-point modes stated in the recipe, per direction, as the modal models `stability.sd`
/// takes (no FRF file or fit needed for a textbook case).
pub struct ModalModelNode {
    spec: NodeSpec,
}

impl Default for ModalModelNode {
    fn default() -> Self {
        Self::new()
    }
}

const MODE_ROW: &[Field] = &[
    Field::req("frequency", T::Quantity(D::FREQUENCY), "natural frequency"),
    Field::req("damping", T::Quantity(D::DIMENSIONLESS), "viscous damping ratio ζ, in [0, 1)"),
    Field::opt("mass", T::Quantity(D::MASS), "modal mass (or give stiffness)"),
    Field::opt("stiffness", T::Quantity(D::STIFFNESS), "modal stiffness k = m (2πf)² (or give mass)"),
];

node_params! {
    /// Parameters of `modal.model`.
    pub struct ModalModelParams<'a> {
        x: opt &'a [Params] = (
            T::ObjectList(MODE_ROW),
            "modes along x, rows {frequency, damping, mass} or {frequency, damping, stiffness} (none: \
             rigid)",
        ),
        y: opt &'a [Params] = (T::ObjectList(MODE_ROW), "modes along y, rows as for x (none: rigid)"),
    }
}

impl ModalModelNode {
    pub fn new() -> Self {
        ModalModelNode {
            spec: NodeSpec {
                kind: "modal.model",
                version: 1,
                description: "Tool-point modes stated directly, per direction: natural frequency, damping ratio and modal mass or modal stiffness of each mode (receptance Eq. 5.8); the modal models x (feed) and y for stability.sd.",
                inputs: vec![],
                outputs: vec![
                    PortSpec::new("modes_x", PortType::ModalModel, "modes along x, the feed direction"),
                    PortSpec::new("modes_y", PortType::ModalModel, "modes along y"),
                ],
                params: ModalModelParams::fields(),
            },
        }
    }
}

/// The modes of the `x` and `y` parameters, checked: each row gives a mass or a stiffness (not both, positive),
/// and [`stability::ModalModel::new`] checks frequency, damping and mass.
fn stated_modes(p: &ModalModelParams) -> Result<stability::ModalModel, NodeError> {
    let mut dirs: [Vec<stability::Mode>; 2] = Default::default();
    for ((dir, rows), modes) in [("x", p.x), ("y", p.y)].into_iter().zip(dirs.iter_mut()) {
        for (index, r) in rows.unwrap_or_default().iter().enumerate() {
            let bad = |what: String| NodeError::param(dir, format!("mode {index} along {dir}: {what}"));
            let (f, zeta) = (r.f64("frequency").unwrap_or(f64::NAN), r.f64("damping").unwrap_or(f64::NAN));
            let mode = match (r.f64("mass"), r.f64("stiffness")) {
                (Some(m), None) => stability::Mode { freq_hz: f, damping_ratio: zeta, modal_mass: m },
                (None, Some(k)) if !(k.is_finite() && k > 0.0) => {
                    return Err(bad(format!("modal stiffness {k} N/m must be finite and > 0")));
                }
                (None, Some(k)) => stability::Mode::from_stiffness(f, zeta, k),
                (Some(_), Some(_)) => return Err(bad("give the modal mass or the modal stiffness, not both".into())),
                (None, None) => {
                    return Err(bad("give its modal mass (`mass`) or modal stiffness (`stiffness`)".into()));
                }
            };
            modes.push(mode);
        }
    }
    let [x, y] = dirs;
    stability::ModalModel::new(x, y).map_err(|e| match &e {
        StabilityError::InvalidMode { direction, .. } => NodeError::param(direction, e.to_string()),
        _ => NodeError::param("x", e.to_string()),
    })
}

impl Node for ModalModelNode {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        stated_modes(&ModalModelParams::read(params)?).map(|_| ())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let model = stated_modes(&ModalModelParams::read(ctx.params)?)?;
        Ok(outputs(vec![
            ("modes_x", Value::ModalModel(ModalModel { modes: model.x })),
            ("modes_y", Value::ModalModel(ModalModel { modes: model.y })),
        ]))
    }
}

// ------------------------------------------------------------------ stability.speed_dependent

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

pub(super) const COEFFICIENT_ROW: &[Field] = &[
    Field::req("speed", T::Quantity(D::ROTATIONAL_SPEED), "spindle speed of the measurement"),
    Field::opt("Ks", T::Quantity(D::PRESSURE), "specific cutting force (with beta)"),
    Field::opt("beta", T::Quantity(D::ANGLE), "force angle: Kt = Ks sin β, Kn = Ks cos β"),
    Field::opt("Kt", T::Quantity(D::PRESSURE), "tangential coefficient (with Kn)"),
    Field::opt("Kn", T::Quantity(D::PRESSURE), "normal coefficient (with Kt)"),
];

node_params! {
    /// Parameters of `stability.speed_dependent`.
    pub struct SpeedDependentParams<'a> {
        cutting: req &'a str = (
            T::Entity(EntityKind::Cutting),
            "the cut: teeth, radial immersion, up/down, Kt/Kn or Ks/β",
        ),
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
        lobes: opt usize = (
            T::Integer { min: 1, max: stability::MAX_LOBES as i64 },
            "number of lobes k = 0 … lobes − 1; by default as many as reach the FRF band's highest significant \
             response (within 40 dB of its peak) down to the slowest speed: ⌈60 f_max/(N n_min)⌉ + 1",
        ),
        resolution: def f64 = (
            T::Quantity(D::FREQUENCY),
            "1 Hz",
            "coarsest line spacing the lobes are resolved at: FRFs on a coarser grid are interpolated (cubic Hermite of the complex receptance) so a lobe's minimum is not cut off between two lines",
        ),
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
        let speed = f.speed_rpm.or(coord).ok_or_else(|| {
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

// ------------------------------------------------------------------ chatter.detect

node_params! {
    /// Parameters of `chatter.detect`.
    pub struct ChatterDetectParams<'a> {
        x_channel: def &'a str = (T::Text, "ax", "channel along x"),
        y_channel: def &'a str = (T::Text, "ay", "channel along y"),
        speed: req f64 = (T::Quantity(D::ROTATIONAL_SPEED), "spindle speed of the cut"),
        teeth: req usize = (T::Integer { min: 1, max: 64 }, "number of teeth"),
        threshold: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "0.2",
            "chatter when the largest unnotched peak exceeds this fraction of the largest tooth harmonic",
        ),
        max_frequency: opt f64 = (T::Quantity(D::FREQUENCY), "search peaks up to here (default Nyquist)"),
    }
}

/// `chatter.detect`: stable or chatter from the x and y vibration records of one cut (§6.4, `|A| = |A_x| + |A_y|`).
pub struct ChatterDetect {
    spec: NodeSpec,
}

impl Default for ChatterDetect {
    fn default() -> Self {
        Self::new()
    }
}

impl ChatterDetect {
    pub fn new() -> Self {
        ChatterDetect {
            spec: NodeSpec {
                kind: "chatter.detect",
                version: 1,
                description: "Chatter or stable from the x and y vibration records of one cut (§6.4): |A(f)| = |A_x| + |A_y|, tooth-passing and runout harmonics notched, the largest remaining peak against the largest tooth harmonic.",
                inputs: vec![PortSpec::new("signal", PortType::TimeSeries, "the cut's records, e.g. accelerations")],
                outputs: vec![
                    PortSpec::new(
                        "result",
                        PortType::Table,
                        "one row: chatter (0/1), chatter_frequency (Hz, 0 if stable), ratio, kind (0 none, \
                         1 quasi-periodic, 2 period doubling), tooth_frequency (Hz), peak_frequency (Hz)",
                    ),
                    PortSpec::new("spectrum", PortType::Table, "frequency (Hz), amplitude |A|, notched (0/1)"),
                ],
                params: ChatterDetectParams::fields(),
            },
        }
    }
}

impl Node for ChatterDetect {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        super::positive(params, &["speed", "threshold", "max_frequency"])
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = ChatterDetectParams::read(ctx.params)?;
        let Value::TimeSeries(ts) = ctx.input("signal")? else {
            return Err(NodeError::input("signal", "expected a time series"));
        };
        let channel = |param: &str, name: &str| {
            ts.channel(name).ok_or_else(|| {
                let have: Vec<&str> = ts.channels.iter().map(|c| c.name.as_str()).collect();
                NodeError::param(param, format!("no channel `{name}` in the signal; it has: {}", have.join(", ")))
            })
        };
        let (x, y) = (channel("x_channel", p.x_channel)?, channel("y_channel", p.y_channel)?);
        let opts = ChatterOptions { threshold: p.threshold, max_freq_hz: p.max_frequency, ..ChatterOptions::default() };
        fn rec<'a>(ts: &'a TimeSeries, c: &'a Channel) -> Record<'a> {
            Record { sample_rate_hz: ts.sample_rate, samples: &c.samples }
        }
        let r = chatter::detect_chatter(rec(ts, x), rec(ts, y), Speed::from_rad_s(p.speed).rpm(), p.teeth, &opts)
            .map_err(|e| match e {
                ChatterError::InvalidOption { .. } => NodeError::param("threshold", e.to_string()),
                ChatterError::NoTeeth | ChatterError::InvalidSpeed(_) | ChatterError::ToothAboveNyquist { .. } => {
                    NodeError::param("speed", e.to_string())
                }
                other => NodeError::input("signal", other.to_string()),
            })?;
        let kind = match r.kind {
            None => 0.0,
            Some(ChatterKind::QuasiPeriodic) => 1.0,
            Some(ChatterKind::PeriodDoubling) => 2.0,
        };
        let result = Table {
            columns: vec![
                Column::new("chatter", "", vec![f64::from(u8::from(r.chatter))]),
                Column::new("chatter_frequency", "Hz", vec![r.chatter_hz.unwrap_or(0.0)]),
                Column::new("ratio", "", vec![r.ratio]),
                Column::new("kind", "", vec![kind]),
                Column::new("tooth_frequency", "Hz", vec![r.tooth_hz]),
                Column::new("peak_frequency", "Hz", vec![r.peak_hz]),
            ],
        };
        let spectrum = Table {
            columns: vec![
                Column::new("frequency", "Hz", r.freqs_hz),
                Column::new("amplitude", "", r.amplitude),
                Column::new("notched", "", r.notched.iter().map(|&n| f64::from(u8::from(n))).collect()),
            ],
        };
        Ok(outputs(vec![("result", Value::Table(result)), ("spectrum", Value::Table(spectrum))]))
    }
}

// ------------------------------------------------------------------ trials.score

node_params! {
    /// Parameters of `trials.score`.
    pub struct TrialsScoreParams<'a> {
        file: req &'a Path = (
            T::File,
            "trials CSV `rpm,depth_mm,outcome[,chatter_freq_hz]`, outcome `stable` or `chatter`",
        ),
        margin: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "0 %",
            "`misfit` also counts right trials closer than this (in ln depth) to the boundary, so a fit centres the boundary between the stable and the chattering cuts",
        ),
        sigma: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "5 %",
            "standard deviation of ln(depth/limit) at the boundary in the trials' likelihood: how sharply the diagram's limit is known",
        ),
        lapse: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "2 %",
            "chance that a trial's outcome is not the diagram's (a mislabelled or disturbed cut): bounds what one trial costs in the likelihood",
        ),
    }
}

/// `trials.score`: cutting trials (speed, depth, stable/chatter) scored against a stability diagram.
pub struct TrialsScore {
    spec: NodeSpec,
}

impl Default for TrialsScore {
    fn default() -> Self {
        Self::new()
    }
}

impl TrialsScore {
    pub fn new() -> Self {
        TrialsScore {
            spec: NodeSpec {
                kind: TRIALS_SCORE,
                version: 2,
                description: "Scores cutting trials (CSV rpm,depth_mm,outcome[,chatter_freq_hz]) against a stability diagram: predicted outcome, right or wrong and distance to the boundary per trial, and the fraction right.",
                inputs: vec![PortSpec::new("lobes", PortType::Lobes, "the diagram: limiting depth over speed")],
                outputs: vec![
                    PortSpec::new(
                        "verdicts",
                        PortType::Table,
                        "per trial: speed (rpm), depth (m), outcome and predicted (0 stable, 1 chatter; −1 outside \
                         the diagram), right (0/1, −1 outside), limit and distance = depth − limit (m; NaN outside)",
                    ),
                    PortSpec::new(
                        "score",
                        PortType::Scalar,
                        "fraction of the trials inside the diagram predicted right",
                    ),
                    PortSpec::new(
                        "misclassified",
                        PortType::Scalar,
                        "number of trials inside the diagram predicted wrong",
                    ),
                    PortSpec::new(
                        "deviance",
                        PortType::Scalar,
                        "−2 ln L of the trials under the probit likelihood: a cut chatters with probability \
                         ε + (1 − 2ε) Φ(ln(depth/limit)/σ); continuous in the diagram, and no trial costs more than \
                         −2 ln ε",
                    ),
                    PortSpec::new(
                        "misfit",
                        PortType::Scalar,
                        "√Σ max(0, margin ∓ ln(depth/limit))² over the trials (− for chatter, + for stable): 0 when \
                         every trial is right by the margin, and continuous in the diagram, so a fit can move a \
                         boundary across the trials",
                    ),
                ],
                params: TrialsScoreParams::fields(),
            },
        }
    }
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

impl Node for TrialsScore {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = TrialsScoreParams::read(params)?;
        let sigma = p.sigma;
        if !(sigma.is_finite() && sigma > 0.0) {
            return Err(NodeError::param("sigma", format!("{} %: give a positive spread, e.g. `5 %`", sigma * 100.0)));
        }
        let lapse = p.lapse;
        if !(0.0..0.5).contains(&lapse) {
            return Err(NodeError::param(
                "lapse",
                format!("{} %: give a rate in [0, 50) %, e.g. `2 %`", lapse * 100.0),
            ));
        }
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = TrialsScoreParams::read(ctx.params)?;
        let Value::Lobes(lobes) = ctx.input("lobes")? else {
            return Err(NodeError::input("lobes", "expected stability lobes"));
        };
        let trials = trials_in(p.file)?;
        let score = stability::score_trials(&lobes.speed_rpm, &lobes.depth_limit, &trials).map_err(|e| match e {
            StabilityError::InvalidDiagram { .. } => NodeError::input("lobes", e.to_string()),
            other => NodeError::param("file", other.to_string()),
        })?;
        let outside: Vec<String> = trials
            .iter()
            .zip(&score.verdicts)
            .filter(|(_, v)| matches!(v, Verdict::OutsideDiagram))
            .map(|(t, _)| format!("{} rpm", t.speed_rpm))
            .collect();
        if !outside.is_empty() {
            ctx.warn(format!(
                "{} trial(s) outside the diagram's {}–{} rpm, not scored: {}",
                outside.len(),
                lobes.speed_rpm.first().copied().unwrap_or(0.0),
                lobes.speed_rpm.last().copied().unwrap_or(0.0),
                outside.join(", ")
            ));
        }
        let fraction = score.fraction_right.ok_or_else(|| {
            NodeError::param("file", "no trial lies inside the diagram's speed range; nothing to score")
        })?;
        let code = |o: Outcome| if o == Outcome::Chatter { 1.0 } else { 0.0 };
        let mut cols: [Vec<f64>; 7] = Default::default();
        for (t, v) in trials.iter().zip(&score.verdicts) {
            let (predicted, right, limit, distance) = match *v {
                Verdict::OutsideDiagram => (-1.0, -1.0, f64::NAN, f64::NAN),
                Verdict::Scored { limit_m, predicted, right, distance_m, .. } => {
                    (code(predicted), f64::from(u8::from(right)), limit_m, distance_m)
                }
            };
            for (c, v) in
                cols.iter_mut().zip([t.speed_rpm, t.depth_m, code(t.outcome), predicted, right, limit, distance])
            {
                c.push(v);
            }
        }
        let [speed, depth, outcome, predicted, right, limit, distance] = cols;
        let misclassified = right.iter().filter(|r| **r == 0.0).count();
        let margin = p.margin;
        let misfit = (0..speed.len())
            .filter(|&k| right[k] >= 0.0 && limit[k] > 0.0)
            .map(|k| {
                // Positive inside the chatter region for a chattering cut, inside the stable one for a stable cut.
                let side = if outcome[k] == 1.0 { 1.0 } else { -1.0 };
                (margin - side * (depth[k] / limit[k]).ln()).max(0.0).powi(2)
            })
            .sum::<f64>()
            .sqrt();
        let likelihood = TrialLikelihood { sigma: p.sigma, lapse: p.lapse };
        let deviance = likelihood.total_deviance(&trials, &score.verdicts);
        let verdicts = Table {
            columns: vec![
                Column::new("speed", "rpm", speed),
                Column::new("depth", "m", depth),
                Column::new("outcome", "", outcome),
                Column::new("predicted", "", predicted),
                Column::new("right", "", right),
                Column::new("limit", "m", limit),
                Column::new("distance", "m", distance),
            ],
        };
        Ok(outputs(vec![
            ("verdicts", Value::Table(verdicts)),
            ("score", Value::Scalar(Scalar::new(fraction, ""))),
            ("misclassified", Value::Scalar(Scalar::new(misclassified as f64, ""))),
            ("misfit", Value::Scalar(Scalar::new(misfit, ""))),
            ("deviance", Value::Scalar(Scalar::new(deviance, ""))),
        ]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fields written out in several kinds' tables stay the same field for field: `cutting` is the shared
    /// [`cutting_param`], `lobes` and `resolution` are those of `stability.lobes`.
    #[test]
    fn the_repeated_fields_agree() {
        let field = |fields: Vec<Field>, name: &str| {
            format!("{:?}", fields.into_iter().find(|f| f.name == name).expect("declared"))
        };
        let shared = format!("{:?}", cutting_param());
        for fields in [LobesParams::fields(), SdParams::fields(), SpeedDependentParams::fields()] {
            assert_eq!(field(fields, "cutting"), shared);
        }
        for name in ["lobes", "resolution"] {
            assert_eq!(field(SpeedDependentParams::fields(), name), field(LobesParams::fields(), name));
        }
    }
}
