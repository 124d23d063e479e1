//! `rig.simulate` and `rig.shaker`: the virtual test rig (dissertation chapters 2–3) as
//! recipe nodes, producing raw channels together with the truth behind them.

use crate::impact::{STEEL_POISSON, STEEL_YOUNGS_MODULUS, Sphere};
use crate::rig::{
    Direction, RigConfig, RigError, RigMode, RigRecording, SensorKind, ShakerConfig, ShakerError, Tone, Undulation,
    shaker, simulate,
};
use spindlelab_domain::{Speed, SpeedLaw};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, Field, FieldType as T, Params};
use spindlelab_engine::value::{Channel, Column, Frf, PortType, Table, TimeSeries, UnitLabel, Value};
use spindlelab_grammar::Dimension as D;
use std::f64::consts::TAU;

const RATIO: T = T::Quantity(D::DIMENSIONLESS);

const MODE: &[Field] = &[
    Field::req("f", T::Quantity(D::FREQUENCY), "natural frequency at rest"),
    Field::req("zeta", RATIO, "viscous damping ratio at rest, in [0, 1)"),
    Field::req("stiffness", T::Quantity(D::STIFFNESS), "modal stiffness (receptance 1/(k(1 − r² + 2iζr)))"),
    Field::def("kf", RATIO, "0", "speed law: f(n) = f (1 + kf (n/ref_speed)^2)"),
    Field::def("kzeta", RATIO, "0", "speed law: zeta(n) = zeta (1 + kzeta (n/ref_speed)^2)"),
];

const UNDULATION: &[Field] = &[
    Field::req("upr", T::Integer { min: 1, max: 1_000_000 }, "undulations per revolution"),
    Field::req("amplitude", T::Quantity(D::LENGTH), "amplitude of amplitude·cos(upr·θ − phase)"),
    Field::def("phase", T::Quantity(D::ANGLE), "0 deg", "phase of amplitude·cos(upr·θ − phase)"),
];

const TONE: &[Field] = &[
    Field::opt("frequency", T::Quantity(D::FREQUENCY), "frequency of the non-synchronous motion"),
    Field::opt(
        "per_rev",
        RATIO,
        "frequency as a multiple of the nominal spindle frequency, not a whole number (a bearing's ball-pass order, say); instead of `frequency`",
    ),
    Field::req("amplitude", T::Quantity(D::LENGTH), "amplitude of amplitude·cos(2π f t − phase)"),
    Field::def("phase", T::Quantity(D::ANGLE), "0 deg", "phase"),
    Field::def("direction", T::Choice(&["x", "y"]), "x", "machine direction it acts along"),
];

const SENSORS: &[&str] = &["capacitance_probe", "laser_vibrometer"];

/// The asynchronous tones; a tone given `per_rev` runs at that multiple of the nominal
/// spindle frequency (`speed` in rad/s), so it follows the speed like a bearing order (and
/// is absent when the spindle is at rest).
fn tones(list: Option<&[Params]>, speed: f64) -> Result<Vec<Tone>, NodeError> {
    let spindle_hz = speed / std::f64::consts::TAU;
    list.unwrap_or(&[])
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let freq_hz = match (t.f64("frequency"), t.f64("per_rev")) {
                (Some(f), None) => f,
                (None, Some(order)) => order * spindle_hz,
                _ => {
                    return Err(NodeError::param(
                        "async_tones",
                        format!("tone {}: give exactly one of `frequency` and `per_rev`", i + 1),
                    ));
                }
            };
            Ok(Tone {
                freq_hz,
                amplitude: t.f64("amplitude").unwrap_or(f64::NAN),
                phase: t.f64("phase").unwrap_or(0.0),
                direction: direction(t.text("direction")),
            })
        })
        .filter(|t| !matches!(t, Ok(Tone { freq_hz, .. }) if *freq_hz == 0.0 && speed == 0.0))
        .collect()
}

node_params! {
    /// Parameters of `rig.simulate`.
    pub struct RigSimulateParams<'a> {
        sample_rate: def f64 = (T::Quantity(D::FREQUENCY), "100 kHz", "sampling rate of every channel"),
        speed: def f64 = (T::Quantity(D::ROTATIONAL_SPEED), "1000 rpm", "nominal spindle speed"),
        ref_speed: def f64 = (T::Quantity(D::ROTATIONAL_SPEED), "10000 rpm", "reference speed of the mode speed laws"),
        speed_drift: def f64 = (RATIO, "0.001", "relative amplitude of the slow seeded speed drift"),
        direction: def &'a str = (
            T::Choice(&["x", "y"]),
            "x",
            "struck direction; the probe setup is oriented along it (probe A along it)",
        ),
        impacts: def usize = (
            T::Integer { min: 0, max: 10_000 },
            "20",
            "number of impacts (0: an error-motion run sized by `duration` or `revolutions`)",
        ),
        impact_interval: def f64 = (
            T::Quantity(D::TIME),
            "0.65536 s",
            "time between impacts; the record is impacts × interval long",
        ),
        impact_offset: def f64 = (
            T::Quantity(D::TIME),
            "50 ms",
            "nominal time of each impact after the start of its interval",
        ),
        impact_jitter: def f64 = (T::Quantity(D::TIME), "2 ms", "largest seeded impact timing deviation"),
        duration: opt f64 = (T::Quantity(D::TIME), "record length (overrides impacts × interval)"),
        revolutions: opt f64 = (RATIO, "record length in revolutions (overrides impacts × interval)"),
        modes_x: opt &'a [Params] = (T::ObjectList(MODE), "modes along machine x (default: 700, 1100, 2400 Hz)"),
        modes_y: opt &'a [Params] = (T::ObjectList(MODE), "modes along machine y (default: 720, 1150, 2350 Hz)"),
        form: opt &'a [Params] = (
            T::ObjectList(UNDULATION),
            "artifact form error read by a probe along +x (default: 2, 3, 5, 8, 13 UPR; [] for none)",
        ),
        sync_x: opt &'a [Params] = (
            T::ObjectList(UNDULATION),
            "synchronous error motion along machine x (default: 1, 2, 44 UPR)",
        ),
        sync_y: opt &'a [Params] = (
            T::ObjectList(UNDULATION),
            "synchronous error motion along machine y (default: 1, 3, 44 UPR)",
        ),
        async_rms: def f64 = (
            T::Quantity(D::LENGTH),
            "20 nm",
            "RMS of the random asynchronous error motion per direction",
        ),
        async_bandwidth: def f64 = (
            T::Quantity(D::FREQUENCY),
            "1 kHz",
            "corner of the 2nd-order low-pass shaping the random asynchronous motion",
        ),
        async_tones: opt &'a [Params] = (T::ObjectList(TONE), "non-synchronous sinusoidal error motions"),
        probes: def &'a [f64] = (
            T::QuantityList(D::ANGLE),
            "[0, 99.84, 202.5] deg",
            "probe angles from probe A (Eq. 3.4), one channel each",
        ),
        sensor: def &'a str = (T::Choice(SENSORS), "capacitance_probe", "displacement probes or vibrometer"),
        phase_slope: opt f64 = (
            T::Quantity(D::PHASE_SLOPE),
            "amplifier phase slope, a pure delay on the probes (default −13.84 deg/kHz, −10.27 for a vibrometer)",
        ),
        force_noise: def f64 = (T::Quantity(D::FORCE), "0.05 N", "force sensor noise (std)"),
        probe_noise: def f64 = (T::Quantity(D::LENGTH), "5 nm", "capacitance probe noise (std)"),
        velocity_noise: def f64 = (T::Quantity(D::VELOCITY), "20 um/s", "vibrometer noise (std)"),
        tach_noise: def f64 = (RATIO, "0.01", "tachometer noise (std), V"),
        force_lsb: opt f64 = (T::Quantity(D::FORCE), "force ADC step (quantisation)"),
        probe_lsb: opt f64 = (T::Quantity(D::LENGTH), "capacitance probe ADC step"),
        velocity_lsb: opt f64 = (T::Quantity(D::VELOCITY), "vibrometer ADC step"),
        tach_lsb: opt f64 = (RATIO, "tachometer ADC step, V"),
        tach_pulse: def f64 = (T::Quantity(D::ANGLE), "10 deg", "angular width of the tach low pulse"),
        tach_edge: def f64 = (T::Quantity(D::TIME), "30 us", "duration of each tach edge"),
        double_hits: opt &'a [f64] = (
            T::QuantityList(D::DIMENSIONLESS),
            "impact indices (from 0) that get a second hit 2–4 ms after the first",
        ),
        force_range: opt f64 = (T::Quantity(D::FORCE), "force ADC range: larger forces are clipped"),
        hammer_mass: def f64 = (T::Quantity(D::MASS), "0.01 kg", "hammer mass (Setup 2, §2.2.2)"),
        hammer_stiffness: def f64 = (T::Quantity(D::STIFFNESS), "623 N/m", "hammer spring (flexure)"),
        hammer_damping: def f64 = (T::Quantity(D::DAMPING), "0 N*s/m", "hammer damping"),
        tip_radius: def f64 = (T::Quantity(D::LENGTH), "6.35 mm", "hammer tip sphere radius"),
        target_radius: def f64 = (T::Quantity(D::LENGTH), "12.7 mm", "artifact surface radius"),
        tip_material: opt &'a str = (T::Entity(EntityKind::Material), "tip material (default steel)"),
        target_material: opt &'a str = (T::Entity(EntityKind::Material), "artifact material (default steel)"),
        restitution: def f64 = (RATIO, "0.95", "coefficient of restitution of Eq. 2.4"),
        release: def f64 = (T::Quantity(D::LENGTH), "6 mm", "hammer release position X_hi"),
        contact: def f64 = (T::Quantity(D::LENGTH), "-3 mm", "artifact contact point X_t0"),
        release_scatter: def f64 = (RATIO, "0.02", "relative scatter of the release distance"),
        dt: def f64 = (T::Quantity(D::TIME), "1e-7 s", "integration step of Eq. 2.7 during contact"),
        seed: def u64 = (T::Integer { min: 0, max: i64::MAX }, "0", "seed of every random part"),
        record_length: def usize = (
            T::Integer { min: 16, max: 1 << 24 },
            "65536",
            "FFT length whose grid `truth_frf` uses",
        ),
        max_frequency: def f64 = (T::Quantity(D::FREQUENCY), "5 kHz", "highest line of `truth_frf`"),
    }
}

pub struct RigSimulate {
    spec: NodeSpec,
}

impl Default for RigSimulate {
    fn default() -> Self {
        Self::new()
    }
}

impl RigSimulate {
    pub fn new() -> Self {
        RigSimulate {
            spec: NodeSpec {
                kind: "rig.simulate",
                version: 1,
                description: "Virtual rig: a rotating spindle under impact test (§2.1–2.3, Eq. 3.4) as one raw recording (tach, force, probes) with its truth.",
                inputs: vec![
                    PortSpec::new(
                        "modes_x",
                        PortType::ModalModel,
                        "modes along x (f, ζ, modal mass m; stiffness m(2πf)²) replacing the `modes_x` parameter; taken as already at the rig's speed, so no speed law applies",
                    )
                    .optional(),
                    PortSpec::new(
                        "modes_y",
                        PortType::ModalModel,
                        "modes along y replacing the `modes_y` parameter; as `modes_x`",
                    )
                    .optional(),
                ],
                outputs: vec![
                    PortSpec::new(
                        "record",
                        PortType::TimeSeries,
                        "channels tach (V), force (N) and one per probe a, b, c, … (m, or m/s for a vibrometer)",
                    ),
                    PortSpec::new(
                        "truth_frf",
                        PortType::Frf,
                        "struck direction's receptance at this speed on the FFT grid of `record_length` (m/N)",
                    ),
                    PortSpec::new(
                        "truth_form",
                        PortType::Table,
                        "form error seen by probe A, R(θ) of Eq. 3.4: angle (rad), form (m), 3600 points",
                    ),
                    PortSpec::new(
                        "truth_motion",
                        PortType::Table,
                        "synchronous error motion in the probe frame: angle (rad), x along probe A, y (m)",
                    ),
                    PortSpec::new(
                        "impacts",
                        PortType::Table,
                        "per impact: index, time (s), peak_force (N), double_hit and saturated (0/1)",
                    ),
                ],
                params: RigSimulateParams::fields(),
            },
        }
    }
}

fn undulations(list: &[Params]) -> Vec<Undulation> {
    list.iter()
        .map(|u| Undulation {
            upr: u.int("upr").unwrap_or(1).clamp(0, u32::MAX as i64) as u32,
            amplitude: u.f64("amplitude").unwrap_or(f64::NAN),
            phase: u.f64("phase").unwrap_or(0.0),
        })
        .collect()
}

fn modes(list: &[Params]) -> Vec<RigMode> {
    list.iter()
        .map(|m| RigMode {
            law: SpeedLaw { kf: m.f64("kf").unwrap_or(0.0), kd: m.f64("kzeta").unwrap_or(0.0) },
            ..RigMode::new(
                m.f64("f").unwrap_or(f64::NAN),
                m.f64("zeta").unwrap_or(f64::NAN),
                m.f64("stiffness").unwrap_or(f64::NAN),
            )
        })
        .collect()
}

/// The modes at a connected `ModalModel` port, as rig modes without speed laws (the model is
/// already at its speed): stiffness `m (2π f)²` (Eq. 5.8 in modal form). Warns when the
/// parameter of the same name is given too, since the port wins.
fn modal_input(ctx: &NodeContext, port: &str, param_given: bool) -> Result<Option<Vec<RigMode>>, NodeError> {
    let Some(l) = ctx.inputs_of(port).first() else {
        return Ok(None);
    };
    let Value::ModalModel(m) = l.value.as_ref() else {
        return Err(NodeError::input(port, "expected a modal model"));
    };
    if m.modes.is_empty() {
        return Err(NodeError::input(port, "the modal model has no modes"));
    }
    for (i, mode) in m.modes.iter().enumerate() {
        let ok = mode.freq_hz.is_finite()
            && mode.freq_hz > 0.0
            && mode.modal_mass.is_finite()
            && mode.modal_mass > 0.0
            && (0.0..1.0).contains(&mode.damping_ratio);
        if !ok {
            return Err(NodeError::input(
                port,
                format!(
                    "mode {}: f {} Hz, ζ {}, modal mass {} kg; need f > 0, 0 <= ζ < 1, mass > 0",
                    i + 1,
                    mode.freq_hz,
                    mode.damping_ratio,
                    mode.modal_mass
                ),
            ));
        }
    }
    if param_given {
        ctx.warn(format!("both the `{port}` input and the `{port}` parameter are given; the input is used"));
    }
    Ok(Some(m.modes.iter().map(|&mode| RigMode { at_rest: mode, law: SpeedLaw::NONE }).collect()))
}

fn direction(word: Option<&str>) -> Direction {
    if word == Some("y") { Direction::Y } else { Direction::X }
}

/// The kernel configuration from the node parameters (materials from the recipe when given).
fn config_from(p: &Params, recipe: Option<&spindlelab_engine::model::Entities>) -> Result<RigConfig, NodeError> {
    let d = RigConfig::default();
    let p = RigSimulateParams::read(p)?;
    let sensor =
        if p.sensor == "laser_vibrometer" { SensorKind::LaserVibrometer } else { SensorKind::CapacitanceProbe };
    let velocity = sensor == SensorKind::LaserVibrometer;
    let material = |name: Option<&str>| -> (f64, f64) {
        match (name, recipe) {
            (Some(m), Some(r)) => r
                .materials
                .get(m)
                .map(|m| (m.youngs_modulus, m.poisson))
                .unwrap_or((STEEL_YOUNGS_MODULUS, STEEL_POISSON)),
            _ => (STEEL_YOUNGS_MODULUS, STEEL_POISSON),
        }
    };
    let (e1, nu1) = material(p.tip_material);
    let (e2, nu2) = material(p.target_material);
    let mut double_hits = Vec::new();
    for &v in p.double_hits.unwrap_or(&[]) {
        if !(v >= 0.0 && v.fract() == 0.0 && v < 1e9) {
            return Err(NodeError::param("double_hits", format!("{v} is not an impact index (a whole number from 0)")));
        }
        double_hits.push(v as usize);
    }
    let mut c = RigConfig {
        sample_rate: p.sample_rate,
        speed: p.speed,
        ref_speed: p.ref_speed,
        speed_drift: p.speed_drift,
        direction: direction(Some(p.direction)),
        impacts: p.impacts,
        impact_interval: p.impact_interval,
        impact_offset: p.impact_offset,
        impact_jitter: p.impact_jitter,
        duration: p.duration,
        revolutions: p.revolutions,
        modes_x: p.modes_x.map_or(d.modes_x, modes),
        modes_y: p.modes_y.map_or(d.modes_y, modes),
        form: p.form.map_or(d.form, undulations),
        sync_x: p.sync_x.map_or(d.sync_x, undulations),
        sync_y: p.sync_y.map_or(d.sync_y, undulations),
        async_rms: p.async_rms,
        async_bandwidth: p.async_bandwidth,
        async_tones: tones(p.async_tones, p.speed)?,
        probe_angles: p.probes.to_vec(),
        sensor,
        phase_slope: p.phase_slope.unwrap_or(sensor.default_phase_slope()),
        double_hits,
        force_range: p.force_range.unwrap_or(f64::INFINITY),
        ..d
    };
    c.noise.force = p.force_noise;
    c.noise.probe = if velocity { p.velocity_noise } else { p.probe_noise };
    c.noise.tach = p.tach_noise;
    c.adc.force_lsb = p.force_lsb.unwrap_or(0.0);
    c.adc.probe_lsb = if velocity { p.velocity_lsb.unwrap_or(0.0) } else { p.probe_lsb.unwrap_or(0.0) };
    c.adc.tach_lsb = p.tach_lsb.unwrap_or(0.0);
    c.tach.pulse_angle = p.tach_pulse;
    c.tach.edge_time = p.tach_edge;
    let h = &mut c.hammer;
    h.mass = p.hammer_mass;
    h.stiffness = p.hammer_stiffness;
    h.damping = p.hammer_damping;
    h.tip = Sphere { radius: p.tip_radius, youngs_modulus: e1, poisson: nu1 };
    h.target = Sphere { radius: p.target_radius, youngs_modulus: e2, poisson: nu2 };
    h.restitution = p.restitution;
    h.release = p.release;
    h.contact = p.contact;
    h.release_scatter = p.release_scatter;
    h.dt = p.dt;
    Ok(c)
}

/// The recipe parameter behind a kernel field path (`modes_x[1].freq_hz` → `modes_x`).
fn param_of(field: &str, velocity: bool) -> String {
    let head = field.split(['[', '.']).next().unwrap_or(field);
    let rest = field.split_once('.').map(|(_, r)| r).unwrap_or("");
    match (head, rest) {
        ("probe_angles", _) => "probes".into(),
        ("noise", "probe") if velocity => "velocity_noise".into(),
        ("noise", r) => format!("{r}_noise"),
        ("adc", "probe_lsb") if velocity => "velocity_lsb".into(),
        ("adc", r) => r.to_string(),
        ("tach", "pulse_angle") => "tach_pulse".into(),
        ("tach", "edge_time") => "tach_edge".into(),
        ("hammer", "release_scatter") => "release_scatter".into(),
        ("hammer", r) => format!("hammer_{r}"),
        (h, _) => h.to_string(),
    }
}

/// Maps a hammer-model error to the recipe parameter a user would change.
fn hammer_param(e: &crate::impact::ImpactError) -> &'static str {
    use crate::impact::ImpactError as E;
    match e {
        E::InvalidParameter { name, field, .. } => match (*name, *field) {
            ("hammer", "mass") => "hammer_mass",
            ("hammer", "stiffness") => "hammer_stiffness",
            ("hammer", "damping") => "hammer_damping",
            ("contact", "restitution") => "restitution",
            ("contact.hammer_tip", _) => "tip_radius",
            ("contact.target", _) => "target_radius",
            ("setup", "release_position") => "release",
            ("setup", "contact_position") => "contact",
            ("setup", "dt") => "dt",
            _ => "hammer_mass",
        },
        E::NoContact => "release",
        E::TooManySteps { .. } => "dt",
        E::EmptyTarget => "modes_x",
    }
}

fn rig_error(e: RigError, velocity: bool) -> NodeError {
    match &e {
        RigError::InvalidParameter { field, .. }
        | RigError::AboveNyquist { field, .. }
        | RigError::Length { field, .. } => NodeError::param(&param_of(field, velocity), e.to_string()),
        RigError::NoProbes => NodeError::param("probes", e.to_string()),
        RigError::Hammer(inner) | RigError::Impact { source: inner, .. } => {
            NodeError::param(hammer_param(inner), e.to_string())
        }
    }
}

/// The record as a time series, moving the channel buffers.
fn record(r: RigRecording, unit: &str) -> (TimeSeries, crate::rig::RigTruth) {
    let mut channels = vec![
        Channel { name: "tach".into(), unit: UnitLabel::new("V"), samples: r.tach },
        Channel { name: "force".into(), unit: UnitLabel::new("N"), samples: r.force },
    ];
    channels.extend(r.probes.into_iter().map(|p| Channel {
        name: p.name,
        unit: UnitLabel::new(unit),
        samples: p.samples,
    }));
    (TimeSeries { sample_rate: r.sample_rate, t0: 0.0, channels }, r.truth)
}

impl Node for RigSimulate {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        let c = config_from(p, None)?;
        c.validate().map_err(|e| rig_error(e, c.sensor == SensorKind::LaserVibrometer))?;
        let fmax = RigSimulateParams::read(p)?.max_frequency;
        if !(fmax > 0.0 && fmax <= 0.5 * c.sample_rate) {
            return Err(NodeError::param(
                "max_frequency",
                format!("{fmax} Hz must lie in (0, {}] Hz (the Nyquist frequency)", 0.5 * c.sample_rate),
            ));
        }
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = RigSimulateParams::read(ctx.params)?;
        let mut c = config_from(ctx.params, Some(ctx.entities))?;
        for (port, target, given) in
            [("modes_x", &mut c.modes_x, p.modes_x.is_some()), ("modes_y", &mut c.modes_y, p.modes_y.is_some())]
        {
            if let Some(modes) = modal_input(ctx, port, given)? {
                *target = modes;
            }
        }
        let seed = p.seed;
        let r = simulate(&c, seed).map_err(|e| rig_error(e, c.sensor == SensorKind::LaserVibrometer))?;
        let (series, truth) = record(r, c.sensor.unit());

        let len = p.record_length.max(1);
        let fmax = p.max_frequency;
        let df = c.sample_rate / len as f64;
        let lines = ((fmax / df).floor() as usize).min(len / 2);
        let freq_hz: Vec<f64> = (0..=lines).map(|k| k as f64 * df).collect();
        let frf = Frf {
            values: freq_hz.iter().map(|f| truth.receptance(*f)).collect(),
            freq_hz,
            coherence: None,
            unit: UnitLabel::new("m/N"),
            direction: Some(c.direction.name().into()),
            speed: Some(Speed::from_rad_s(c.speed)),
            sensor: Some("rig truth".into()),
            dofs: None,
        };

        const GRID: usize = 3600;
        let angle: Vec<f64> = (0..GRID).map(|i| TAU * i as f64 / GRID as f64).collect();
        let form = Table {
            columns: vec![
                Column::new("angle", "rad", angle.clone()),
                Column::new("form", "m", angle.iter().map(|t| truth.form_error(*t)).collect()),
            ],
        };
        let (mx, my): (Vec<f64>, Vec<f64>) = angle.iter().map(|t| truth.sync_motion(*t)).unzip();
        let motion = Table {
            columns: vec![Column::new("angle", "rad", angle), Column::new("x", "m", mx), Column::new("y", "m", my)],
        };
        let imp = &truth.impacts;
        let impacts = Table {
            columns: vec![
                Column::new("index", "", imp.iter().map(|i| i.index as f64).collect()),
                Column::new("time", "s", imp.iter().map(|i| i.time).collect()),
                Column::new("peak_force", "N", imp.iter().map(|i| i.peak_force).collect()),
                Column::new("double_hit", "", imp.iter().map(|i| f64::from(u8::from(i.double_hit))).collect()),
                Column::new("saturated", "", imp.iter().map(|i| f64::from(u8::from(i.saturated))).collect()),
            ],
        };
        for i in imp.iter().filter(|i| i.saturated) {
            ctx.warn(format!("impact {} at {:.4} s saturates the force range", i.index, i.time));
        }
        let mut out = Outputs::new();
        out.insert("record".into(), Value::TimeSeries(series));
        out.insert("truth_frf".into(), Value::Frf(frf));
        out.insert("truth_form".into(), Value::Table(form));
        out.insert("truth_motion".into(), Value::Table(motion));
        out.insert("impacts".into(), Value::Table(impacts));
        Ok(out)
    }

    fn cacheable(&self) -> bool {
        false
    }
}

node_params! {
    /// Parameters of `rig.shaker`.
    pub struct RigShakerParams<'a> {
        frequency: def f64 = (T::Quantity(D::FREQUENCY), "1 kHz", "drive frequency"),
        amplitude: def f64 = (T::Quantity(D::LENGTH), "1 um", "displacement amplitude"),
        sensor: def &'a str = (T::Choice(SENSORS), "capacitance_probe", "chain under test"),
        phase_slope: opt f64 = (
            T::Quantity(D::PHASE_SLOPE),
            "phase slope of the chain (default −13.84 deg/kHz, −10.27 for a vibrometer)",
        ),
        accel_noise: def f64 = (T::Quantity(D::ACCELERATION), "0.01 m/s^2", "accelerometer noise (std)"),
        probe_noise: def f64 = (T::Quantity(D::LENGTH), "1 nm", "capacitance probe noise (std)"),
        velocity_noise: def f64 = (T::Quantity(D::VELOCITY), "10 um/s", "vibrometer noise (std)"),
        duration: def f64 = (T::Quantity(D::TIME), "0.1 s", "record length"),
        sample_rate: def f64 = (T::Quantity(D::FREQUENCY), "100 kHz", "sampling rate"),
        seed: def u64 = (T::Integer { min: 0, max: i64::MAX }, "0", "seed of the noise and start phase"),
    }
}

pub struct RigShaker {
    spec: NodeSpec,
}

impl Default for RigShaker {
    fn default() -> Self {
        Self::new()
    }
}

impl RigShaker {
    pub fn new() -> Self {
        RigShaker {
            spec: NodeSpec {
                kind: "rig.shaker",
                version: 1,
                description: "Shaker phase-lag test of §2.3.1: accelerometer and delayed probe channel on a sinusoidally driven target (Eqs. 2.8–2.9).",
                inputs: vec![],
                outputs: vec![PortSpec::new(
                    "record",
                    PortType::TimeSeries,
                    "channels accel (m/s², no delay) and sensor (m, or m/s for a vibrometer, delayed by the phase slope)",
                )],
                params: RigShakerParams::fields(),
            },
        }
    }
}

fn shaker_config(p: &RigShakerParams) -> ShakerConfig {
    let sensor =
        if p.sensor == "laser_vibrometer" { SensorKind::LaserVibrometer } else { SensorKind::CapacitanceProbe };
    let sensor_noise = match sensor {
        SensorKind::LaserVibrometer => p.velocity_noise,
        SensorKind::CapacitanceProbe => p.probe_noise,
    };
    ShakerConfig {
        sample_rate: p.sample_rate,
        frequency: p.frequency,
        amplitude: p.amplitude,
        sensor,
        phase_slope: p.phase_slope.unwrap_or(sensor.default_phase_slope()),
        accel_noise: p.accel_noise,
        sensor_noise,
        duration: p.duration,
    }
}

fn shaker_error(e: ShakerError, sensor: SensorKind) -> NodeError {
    let ShakerError::InvalidParameter { field, .. } = &e;
    let param = match *field {
        "sensor_noise" if sensor == SensorKind::LaserVibrometer => "velocity_noise",
        "sensor_noise" => "probe_noise",
        f => f,
    };
    NodeError::param(param, e.to_string())
}

impl Node for RigShaker {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        let c = shaker_config(&RigShakerParams::read(p)?);
        c.validate().map_err(|e| shaker_error(e, c.sensor))
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = RigShakerParams::read(ctx.params)?;
        let c = shaker_config(&p);
        let seed = p.seed;
        let r = shaker(&c, seed).map_err(|e| shaker_error(e, c.sensor))?;
        let series = TimeSeries {
            sample_rate: r.sample_rate,
            t0: 0.0,
            channels: vec![
                Channel { name: "accel".into(), unit: UnitLabel::new("m/s^2"), samples: r.accel },
                Channel { name: "sensor".into(), unit: UnitLabel::new(c.sensor.unit()), samples: r.sensor },
            ],
        };
        Ok([("record".to_string(), Value::TimeSeries(series))].into_iter().collect())
    }

    fn cacheable(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nodes::test_support::{empty_recipe as recipe, params};
    use crate::signal::dtft_at;

    fn run(node: &dyn Node, p: &Params) -> Result<Outputs, NodeError> {
        let r = recipe();
        let inputs = Default::default();
        node.run(&NodeContext::new("test", p, &inputs, &r.entities_named_by(p)))
    }

    fn param_error(node: &dyn Node, yaml: &str) -> String {
        match node.validate(&params(node, yaml)) {
            Err(NodeError::InvalidParam { param, .. }) => param,
            other => panic!("{yaml}: {other:?}"),
        }
    }

    /// A modal model at the `modes_y` port replaces the parameter: the truth FRF is
    /// `Σ 1/(m_r(ω_r² − ω² + 2iζ_r ω_r ω))`, computed here independently of the rig kernel.
    #[test]
    fn modal_model_input_sets_the_truth_frf() {
        use spindlelab_engine::node::Labelled;
        use spindlelab_engine::value::{ModalModel, Mode};
        use std::sync::Arc;
        let node = RigSimulate::new();
        let model = ModalModel {
            modes: vec![
                Mode { freq_hz: 812.0, damping_ratio: 0.031, modal_mass: 0.42 },
                Mode { freq_hz: 2170.0, damping_ratio: 0.018, modal_mass: 1.3 },
            ],
        };
        let p = params(
            &node,
            "{direction: y, speed: 6000 rpm, impacts: 1, duration: 0.2 s, probes: [0 deg], modes_y: [{f: 500 Hz, zeta: 0.02, stiffness: 1e7 N/m, kf: 0.3}]}",
        );
        let r = recipe();
        let mut inputs = indexmap::IndexMap::new();
        inputs.insert(
            "modes_y".to_string(),
            vec![Labelled { label: String::new(), coords: vec![], value: Arc::new(Value::ModalModel(model.clone())) }],
        );
        let entities = r.entities_named_by(&p);
        let ctx = NodeContext::new("test", &p, &inputs, &entities);
        let out = node.run(&ctx).unwrap();
        let Value::Frf(frf) = &out["truth_frf"] else { panic!("frf") };
        assert_eq!(frf.direction.as_deref(), Some("y"));
        for (f, h) in frf.freq_hz.iter().zip(&frf.values) {
            let w = TAU * f;
            let want: num_complex::Complex64 = model
                .modes
                .iter()
                .map(|m| {
                    let wn = TAU * m.freq_hz;
                    1.0 / (m.modal_mass * num_complex::Complex64::new(wn * wn - w * w, 2.0 * m.damping_ratio * wn * w))
                })
                .sum();
            assert!((h - want).norm() <= 1e-12 * want.norm(), "{f} Hz: {h} vs {want}");
        }
        let warnings = ctx.take_warnings();
        assert!(warnings.iter().any(|w| w.contains("`modes_y` input and the `modes_y` parameter")), "{warnings:?}");
    }

    #[test]
    fn node_defaults_are_the_kernel_defaults() {
        let node = RigSimulate::new();
        let mut c = config_from(&params(&node, "{}"), None).unwrap();
        let d = RigConfig::default();
        // Unit conversions may differ from the kernel's constants in the last bit.
        for (a, b) in c.probe_angles.iter().zip(&d.probe_angles) {
            assert!((a - b).abs() < 1e-15);
        }
        for (a, b) in [(c.speed, d.speed), (c.ref_speed, d.ref_speed), (c.phase_slope, d.phase_slope)] {
            assert!((a / b - 1.0).abs() < 1e-15, "{a} vs {b}");
        }
        assert!((c.tach.pulse_angle - d.tach.pulse_angle).abs() < 1e-15);
        (c.probe_angles, c.speed, c.ref_speed, c.phase_slope) =
            (d.probe_angles.clone(), d.speed, d.ref_speed, d.phase_slope);
        c.tach.pulse_angle = d.tach.pulse_angle;
        assert_eq!(c, d);
        assert!(!node.cacheable() && !RigShaker::new().cacheable());
    }

    #[test]
    fn simulate_node_outputs_the_record_and_its_truth() {
        let node = RigSimulate::new();
        let p =
            params(&node, "{impacts: 2, impact_interval: 0.2 s, record_length: 4096, max_frequency: 2 kHz, seed: 3}");
        node.validate(&p).unwrap();
        let out = run(&node, &p).unwrap();
        let Value::TimeSeries(rec) = &out["record"] else { panic!("record") };
        let names: Vec<&str> = rec.channels.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["tach", "force", "a", "b", "c"]);
        let units: Vec<&str> = rec.channels.iter().map(|c| c.unit.symbol.as_str()).collect();
        assert_eq!(units, ["V", "N", "m", "m", "m"]);
        assert_eq!(rec.len(), 40_000);
        assert_eq!((rec.sample_rate, rec.t0), (100.0e3, 0.0));
        // The same numbers as the kernel with the same configuration and seed.
        let c = config_from(&p, None).unwrap();
        let k = simulate(&c, 3).unwrap();
        assert_eq!(rec.channel("force").unwrap().samples, k.force);
        assert_eq!(rec.channel("b").unwrap().samples, k.probes[1].samples);

        let Value::Frf(frf) = &out["truth_frf"] else { panic!("frf") };
        let df = 100.0e3 / 4096.0;
        assert_eq!(frf.freq_hz.len(), 82);
        assert_eq!(frf.freq_hz[81], 81.0 * df);
        assert_eq!((frf.unit.symbol.as_str(), frf.direction.as_deref()), ("m/N", Some("x")));
        assert!((frf.speed.unwrap().rpm() - 1000.0).abs() < 1e-9);
        let modes = c.modes_at_speed();
        let h: num_complex::Complex64 =
            modes.iter().map(|m| m.receptance(std::f64::consts::TAU * frf.freq_hz[29])).sum();
        assert_eq!(frf.values[29], h);
        // Static compliance: Σ 1/k.
        let static_h: f64 = modes.iter().map(|m| 1.0 / m.stiffness()).sum();
        assert!((frf.values[0].re - static_h).abs() < 1e-20 && frf.values[0].im == 0.0);

        let Value::Table(form) = &out["truth_form"] else { panic!("form") };
        assert_eq!(form.rows(), 3600);
        assert_eq!(form.columns[1].values[900], k.truth.form_error(form.columns[0].values[900]));
        let Value::Table(motion) = &out["truth_motion"] else { panic!("motion") };
        let names: Vec<&str> = motion.columns.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["angle", "x", "y"]);
        let Value::Table(imp) = &out["impacts"] else { panic!("impacts") };
        assert_eq!(imp.rows(), 2);
        let names: Vec<&str> = imp.columns.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["index", "time", "peak_force", "double_hit", "saturated"]);
        assert_eq!(imp.columns[1].values[1], k.truth.impacts[1].time);
    }

    #[test]
    fn sensor_direction_and_faults_reach_the_kernel() {
        let node = RigSimulate::new();
        let p = params(
            &node,
            "{impacts: 3, impact_interval: 0.1 s, sensor: laser_vibrometer, direction: y, double_hits: [1], \
             force_range: 50 N, speed: 2400 rpm, probes: [0 deg, 90 deg]}",
        );
        let c = config_from(&p, None).unwrap();
        assert_eq!(c.sensor, SensorKind::LaserVibrometer);
        assert!((c.phase_slope / crate::rig::VIBROMETER_PHASE_SLOPE - 1.0).abs() < 1e-15);
        assert_eq!(c.noise.probe, 20.0e-6);
        let out = run(&node, &p).unwrap();
        let Value::TimeSeries(rec) = &out["record"] else { panic!() };
        assert_eq!(rec.channels.len(), 4);
        assert_eq!(rec.channels[2].unit.symbol, "m/s");
        let Value::Frf(frf) = &out["truth_frf"] else { panic!() };
        assert_eq!(frf.direction.as_deref(), Some("y"));
        let Value::Table(imp) = &out["impacts"] else { panic!() };
        assert_eq!(imp.columns[3].values, [0.0, 1.0, 0.0]);
        assert!(imp.columns[4].values.iter().all(|s| *s == 1.0), "50 N saturates every hit");
    }

    #[test]
    fn bad_parameters_name_the_recipe_parameter() {
        let node = RigSimulate::new();
        let cases = [
            ("{modes_x: [{f: 700 Hz, zeta: 1.2, stiffness: 2e7 N/m}]}", "modes_x"),
            ("{double_hits: [25]}", "double_hits"),
            ("{double_hits: [1.5]}", "double_hits"),
            ("{force_noise: -1 N}", "force_noise"),
            ("{sensor: laser_vibrometer, velocity_noise: -1 m/s}", "velocity_noise"),
            ("{speed: 30000 rpm, form: [], sync_x: [], sync_y: []}", "tach_pulse"),
            ("{hammer_mass: 0 kg}", "hammer_mass"),
            ("{release: -5 mm}", "release"),
            ("{impacts: 0}", "duration"),
            ("{max_frequency: 60 kHz}", "max_frequency"),
            ("{sync_x: [{upr: 5000, amplitude: 1 nm}]}", "sync_x"),
            ("{phase_slope: -5000 deg/kHz}", "phase_slope"),
            ("{impact_offset: 0.7 s}", "impact_offset"),
        ];
        for (yaml, param) in cases {
            assert_eq!(param_error(&node, yaml), param, "{yaml}");
        }
    }

    #[test]
    fn shaker_node_delays_the_sensor_only() {
        let node = RigShaker::new();
        let p = params(&node, "{frequency: 2 kHz, accel_noise: 0 m/s^2, probe_noise: 0 m, seed: 4}");
        node.validate(&p).unwrap();
        let out = run(&node, &p).unwrap();
        let Value::TimeSeries(rec) = &out["record"] else { panic!() };
        let names: Vec<&str> = rec.channels.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["accel", "sensor"]);
        assert_eq!(rec.len(), 10_000);
        let a = dtft_at(&rec.channels[0].samples, rec.sample_rate, 2000.0);
        let x = dtft_at(&rec.channels[1].samples, rec.sample_rate, 2000.0);
        let lag = ((x / a).arg().to_degrees() + 180.0 + 540.0).rem_euclid(360.0) - 180.0;
        assert!((lag + 2.0 * 13.84).abs() < 1e-9, "{lag}");
        assert_eq!(param_error(&node, "{frequency: 60 kHz}"), "frequency");
        assert_eq!(param_error(&node, "{sensor: laser_vibrometer, velocity_noise: -1 m/s}"), "velocity_noise");
    }
}
