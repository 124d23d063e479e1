//! Configuration of the virtual rig: structure, rotation, artifact, error motions, probes,
//! hammer and faults, with the dissertation's values as defaults, and its validation.

use crate::impact::{Contact, ImpactError, ImpactSetup, ModalTarget, Sphere, first_contact};
use spindlelab_domain::{Mode, Speed, SpeedLaw};
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use thiserror::Error;

/// Phase slope of the capacitance-gauge chain measured in §2.3.1, −13.84 deg/kHz, in SI
/// (rad per Hz, i.e. rad·s).
pub const CAPACITANCE_PHASE_SLOPE: f64 = -13.84 * PI / 180.0 / 1000.0;
/// Phase slope of the laser-vibrometer chain measured in §2.3.1, −10.27 deg/kHz, in SI (rad·s).
pub const VIBROMETER_PHASE_SLOPE: f64 = -10.27 * PI / 180.0 / 1000.0;
/// Largest sensor delay accepted, s (a phase slope of ±3600 deg/kHz).
pub const MAX_DELAY: f64 = 10.0e-3;
/// Largest record accepted, samples per channel.
pub const MAX_SAMPLES: usize = 50_000_000;
/// Largest number of probes (channels are named `a`..`z`).
pub const MAX_PROBES: usize = 26;
/// Impact times are placed on a grid this many times finer than the sampling interval.
pub const IMPACT_SUBSAMPLES: u32 = 16;
/// Record length of the §2.1 model for each hit, s: a contact must end within it.
pub const PULSE_WINDOW: f64 = 3.0e-3;
/// Time after a first contact kept free for the pulse and a possible second hit, s
/// (checked against `impact_offset` and `impact_interval`).
pub const IMPACT_SPAN: f64 = 12.0e-3;

/// The time delay of a chain whose phase falls linearly with frequency at `slope` (rad per
/// Hz, SI): `τ = −slope/2π` s, i.e. `τ = −Δθ/(360·1000)` s for Δθ in deg/kHz (Eq. 2.11).
pub fn delay_from_phase_slope(slope: f64) -> f64 {
    -slope / TAU
}

/// A machine direction: the struck direction, and the axis an error motion or tone acts along.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Direction {
    #[default]
    X,
    Y,
}

impl Direction {
    pub fn name(self) -> &'static str {
        match self {
            Direction::X => "x",
            Direction::Y => "y",
        }
    }

    /// Machine angle of probe A when the setup is oriented along this direction, rad.
    pub fn setup_angle(self) -> f64 {
        match self {
            Direction::X => 0.0,
            Direction::Y => FRAC_PI_2,
        }
    }
}

/// The motion sensor behind the probe channels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SensorKind {
    /// Capacitance gauges: displacement, m.
    #[default]
    CapacitanceProbe,
    /// Laser Doppler vibrometer: velocity, m/s (the exact time derivative of the displacement).
    LaserVibrometer,
}

impl SensorKind {
    /// The dissertation's measured phase slope of this chain (§2.3.1), rad·s.
    pub fn default_phase_slope(self) -> f64 {
        match self {
            SensorKind::CapacitanceProbe => CAPACITANCE_PHASE_SLOPE,
            SensorKind::LaserVibrometer => VIBROMETER_PHASE_SLOPE,
        }
    }

    /// SI unit of the probe channels.
    pub fn unit(self) -> &'static str {
        match self {
            SensorKind::CapacitanceProbe => "m",
            SensorKind::LaserVibrometer => "m/s",
        }
    }
}

/// One structural mode at the impact point with its speed law (the law of the recipe's
/// spindle modes, applied to the damping ratio): `f(n) = f0 (1 + kf (n/n_ref)²)`,
/// `ζ(n) = ζ0 (1 + kd (n/n_ref)²)`; the modal stiffness does not change with speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigMode {
    /// The mode at rest.
    pub at_rest: Mode,
    /// How its frequency and damping ratio change with speed.
    pub law: SpeedLaw,
}

impl RigMode {
    /// A mode of natural frequency (Hz), damping ratio and modal stiffness (N/m) that does not
    /// change with speed.
    pub fn new(freq_hz: f64, damping_ratio: f64, stiffness: f64) -> Self {
        RigMode { at_rest: Mode::from_stiffness(freq_hz, damping_ratio, stiffness), law: SpeedLaw::NONE }
    }

    /// The mode at spindle speed `speed`, by its law about `reference`, with its stiffness.
    pub fn at_speed(&self, speed: Speed, reference: Speed) -> Mode {
        let m = &self.at_rest;
        Mode::from_stiffness(
            self.law.frequency(m.freq_hz, speed, reference),
            self.law.damping(m.damping_ratio, speed, reference),
            m.stiffness(),
        )
    }
}

/// One harmonic of a function of the spindle angle: `amplitude · cos(upr·θ − phase)`, so
/// that in Eq. 3.9's form `A_k = amplitude·cos(phase)`, `B_k = amplitude·sin(phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Undulation {
    /// Undulations per revolution (≥ 1).
    pub upr: u32,
    /// Amplitude, m (≥ 0).
    pub amplitude: f64,
    /// Phase, rad.
    pub phase: f64,
}

impl Undulation {
    pub const fn new(upr: u32, amplitude: f64, phase: f64) -> Self {
        Undulation { upr, amplitude, phase }
    }
}

/// `Σ amplitude·cos(upr·θ − phase)` (Eq. 3.9 with the corrected sine term).
pub fn harmonic_sum(terms: &[Undulation], theta: f64) -> f64 {
    terms.iter().map(|u| u.amplitude * (u.upr as f64 * theta - u.phase).cos()).sum()
}

/// `d/dθ` of [`harmonic_sum`].
pub fn harmonic_slope(terms: &[Undulation], theta: f64) -> f64 {
    terms.iter().map(|u| -u.amplitude * u.upr as f64 * (u.upr as f64 * theta - u.phase).sin()).sum()
}

/// A non-synchronous sinusoidal error motion `amplitude · cos(2π f t − phase)` along a
/// machine direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tone {
    /// Frequency, Hz (> 0).
    pub freq_hz: f64,
    /// Amplitude, m.
    pub amplitude: f64,
    /// Phase, rad.
    pub phase: f64,
    pub direction: Direction,
}

/// The impact hammer and its contact with the artifact, for the Hertz impact model of §2.1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HammerConfig {
    /// Hammer mass, kg.
    pub mass: f64,
    /// Hammer spring, N/m.
    pub stiffness: f64,
    /// Hammer viscous damping, N·s/m.
    pub damping: f64,
    /// Hammer tip sphere.
    pub tip: Sphere,
    /// Artifact surface as a sphere.
    pub target: Sphere,
    /// Coefficient of restitution of Eq. 2.4.
    pub restitution: f64,
    /// Hammer position at release, m (X_hi of §2.1).
    pub release: f64,
    /// Artifact contact point, m (X_t0 of §2.1).
    pub contact: f64,
    /// Relative standard deviation of the release distance `release − contact` from hit to
    /// hit (clipped at 3σ).
    pub release_scatter: f64,
    /// Fine integration step of Eq. 2.7, s (1e-7 s resolves a 0.4 ms contact in thousands
    /// of steps).
    pub dt: f64,
}

impl Default for HammerConfig {
    /// The low-mass hammer of Setup 2 (§2.2.2, built for a wide excited bandwidth): 0.01 kg
    /// on a 623 N/m flexure, a 6.35 mm steel tip on the steel artifact (taken as a 12.7 mm
    /// sphere), released 6 mm out with the contact at −3 mm: a hard hit of about 0.05 ms and 900 N.
    fn default() -> Self {
        HammerConfig {
            mass: 0.01,
            stiffness: 623.0,
            damping: 0.0,
            tip: Sphere::steel(6.35e-3),
            target: Sphere::steel(12.7e-3),
            restitution: 0.95,
            release: 6.0e-3,
            contact: -3.0e-3,
            release_scatter: 0.02,
            dt: 1.0e-7,
        }
    }
}

/// Gaussian sensor noise, standard deviations in each channel's unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// Force channel, N.
    pub force: f64,
    /// Probe channels, m (capacitance probes) or m/s (vibrometer).
    pub probe: f64,
    /// Tachometer, V.
    pub tach: f64,
}

/// Optional ADC quantisation: the step (LSB) of each channel kind, 0 for none.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Adc {
    /// N.
    pub force_lsb: f64,
    /// m or m/s.
    pub probe_lsb: f64,
    /// V.
    pub tach_lsb: f64,
}

/// Laser tachometer: high level, a low pulse once per revolution starting at θ = 0, and
/// linear edges centred on their instants (so the mid-level crossing is the exact instant).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TachConfig {
    /// High level, V.
    pub high: f64,
    /// Low level, V.
    pub low: f64,
    /// Angular width of the low pulse, rad.
    pub pulse_angle: f64,
    /// Duration of each edge (10–90 % is 80 % of it), s. With two or more sampling
    /// intervals, linear interpolation of the mid-level crossing is exact.
    pub edge_time: f64,
}

impl Default for TachConfig {
    fn default() -> Self {
        TachConfig { high: 5.0, low: 0.0, pulse_angle: 10.0f64.to_radians(), edge_time: 30.0e-6 }
    }
}

/// Everything the virtual rig needs for one run. SI units: s, Hz, rad, rad/s, m, N.
#[derive(Debug, Clone, PartialEq)]
pub struct RigConfig {
    /// Sampling rate of every channel, Hz.
    pub sample_rate: f64,
    /// Nominal spindle speed, rad/s (0 is a stationary test).
    pub speed: f64,
    /// Reference speed of the mode speed laws, rad/s.
    pub ref_speed: f64,
    /// Relative amplitude of the slow seeded speed drift (0.001 = 0.1 %).
    pub speed_drift: f64,
    /// Struck direction; the probe setup is oriented along it (probe A along it).
    pub direction: Direction,
    /// Number of impacts (0: an error-motion run; `duration` or `revolutions` sets the length).
    pub impacts: usize,
    /// Time between nominal impacts, s; the record is `impacts × impact_interval` long unless
    /// `duration` or `revolutions` is given.
    pub impact_interval: f64,
    /// Nominal time of each impact after the start of its interval, s.
    pub impact_offset: f64,
    /// Largest seeded deviation of an impact from its nominal time (uniform), s.
    pub impact_jitter: f64,
    /// Record length, s (overrides the impact-based length).
    pub duration: Option<f64>,
    /// Record length in nominal revolutions (overrides the impact-based length).
    pub revolutions: Option<f64>,
    /// Modes of the structure along machine x.
    pub modes_x: Vec<RigMode>,
    /// Modes of the structure along machine y.
    pub modes_y: Vec<RigMode>,
    /// Artifact form error as read by a probe along machine +x, a function of the spindle angle.
    pub form: Vec<Undulation>,
    /// Synchronous error motion along machine x.
    pub sync_x: Vec<Undulation>,
    /// Synchronous error motion along machine y.
    pub sync_y: Vec<Undulation>,
    /// RMS of the random asynchronous error motion per direction, m.
    pub async_rms: f64,
    /// Corner frequency of the random asynchronous motion (2nd-order Butterworth low-pass), Hz.
    pub async_bandwidth: f64,
    /// Non-synchronous sinusoids.
    pub async_tones: Vec<Tone>,
    /// Probe angles from probe A, rad (Eq. 3.4: 0, σ, ρ).
    pub probe_angles: Vec<f64>,
    pub sensor: SensorKind,
    /// Phase slope of the probe amplifier chain, rad·s (rad per Hz); a pure delay of
    /// [`delay_from_phase_slope`] on the probe channels only.
    pub phase_slope: f64,
    pub noise: Noise,
    pub adc: Adc,
    pub tach: TachConfig,
    pub hammer: HammerConfig,
    /// Impact indices that get a second hit (see [`crate::rig`] docs).
    pub double_hits: Vec<usize>,
    /// Force ADC range, N: the recorded force is clipped to ±range (INFINITY: no clipping).
    pub force_range: f64,
}

/// Rotational speed from rpm, rad/s.
pub fn rpm(n: f64) -> f64 {
    Speed::from_rpm(n).rad_s()
}

impl Default for RigConfig {
    /// A realistic spindle at 1000 rpm with dissertation settings: 100 kHz, probes at 0°,
    /// 99.84°, 202.5°, capacitance gauges with −13.84 deg/kHz, 20 impacts of 65,536 samples.
    fn default() -> Self {
        let mode = |f, z, k, kf, kd| RigMode { law: SpeedLaw { kf, kd }, ..RigMode::new(f, z, k) };
        RigConfig {
            sample_rate: 100.0e3,
            speed: rpm(1000.0),
            ref_speed: rpm(10_000.0),
            speed_drift: 1.0e-3,
            direction: Direction::X,
            impacts: 20,
            impact_interval: 0.655_36,
            impact_offset: 0.05,
            impact_jitter: 2.0e-3,
            duration: None,
            revolutions: None,
            modes_x: vec![
                mode(700.0, 0.03, 2.0e7, -0.02, 0.1),
                mode(1100.0, 0.04, 3.0e7, -0.03, 0.05),
                mode(2400.0, 0.025, 5.0e7, -0.05, 0.1),
            ],
            modes_y: vec![
                mode(720.0, 0.032, 2.2e7, -0.02, 0.1),
                mode(1150.0, 0.04, 2.8e7, -0.03, 0.05),
                mode(2350.0, 0.028, 4.5e7, -0.05, 0.1),
            ],
            form: vec![
                Undulation::new(2, 0.8e-6, 0.4),
                Undulation::new(3, 0.5e-6, 1.9),
                Undulation::new(5, 0.2e-6, -0.7),
                Undulation::new(8, 0.1e-6, 2.5),
                Undulation::new(13, 0.05e-6, 0.3),
            ],
            sync_x: vec![
                Undulation::new(1, 1.0e-6, 0.2),
                Undulation::new(2, 0.15e-6, -1.1),
                Undulation::new(44, 0.03e-6, 0.8),
            ],
            sync_y: vec![
                Undulation::new(1, 1.0e-6, 0.2 + FRAC_PI_2),
                Undulation::new(3, 0.1e-6, 2.0),
                Undulation::new(44, 0.05e-6, -0.4),
            ],
            async_rms: 20.0e-9,
            async_bandwidth: 1.0e3,
            async_tones: Vec::new(),
            probe_angles: vec![0.0, 99.84f64.to_radians(), 202.5f64.to_radians()],
            sensor: SensorKind::CapacitanceProbe,
            phase_slope: CAPACITANCE_PHASE_SLOPE,
            noise: Noise { force: 0.05, probe: 5.0e-9, tach: 0.01 },
            adc: Adc::default(),
            tach: TachConfig::default(),
            hammer: HammerConfig::default(),
            double_hits: Vec::new(),
            force_range: f64::INFINITY,
        }
    }
}

/// Why a rig configuration cannot be simulated; `field` names the [`RigConfig`] field
/// (dotted for nested ones, with a list index where one applies).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RigError {
    #[error("`{field}` = {value}: {requirement}")]
    InvalidParameter { field: String, value: f64, requirement: String },
    #[error(
        "`{field}`: {frequency} Hz is at or above the Nyquist frequency {nyquist} Hz; raise `sample_rate` or lower it"
    )]
    AboveNyquist { field: String, frequency: f64, nyquist: f64 },
    #[error("`probe_angles` is empty: give at least one probe angle")]
    NoProbes,
    #[error("`{field}`: {message}")]
    Length { field: String, message: String },
    #[error("`hammer`: {0}")]
    Hammer(ImpactError),
    #[error("impact {index}: {source}")]
    Impact { index: usize, source: ImpactError },
}

fn bad(field: impl Into<String>, value: f64, requirement: impl Into<String>) -> RigError {
    RigError::InvalidParameter { field: field.into(), value, requirement: requirement.into() }
}

fn finite(field: &str, v: f64) -> Result<(), RigError> {
    if v.is_finite() { Ok(()) } else { Err(bad(field, v, "must be finite")) }
}

fn positive(field: &str, v: f64) -> Result<(), RigError> {
    if v.is_finite() && v > 0.0 { Ok(()) } else { Err(bad(field, v, "must be finite and positive")) }
}

fn non_negative(field: &str, v: f64) -> Result<(), RigError> {
    if v.is_finite() && v >= 0.0 { Ok(()) } else { Err(bad(field, v, "must be finite and non-negative")) }
}

impl RigConfig {
    /// Sensor delay of the probe channels, s.
    pub fn delay(&self) -> f64 {
        delay_from_phase_slope(self.phase_slope)
    }

    /// The struck direction's modes.
    pub fn struck_modes(&self) -> &[RigMode] {
        match self.direction {
            Direction::X => &self.modes_x,
            Direction::Y => &self.modes_y,
        }
    }

    /// The struck direction's modes at the nominal speed.
    pub fn modes_at_speed(&self) -> Vec<Mode> {
        let (n, reference) = (Speed::from_rad_s(self.speed), Speed::from_rad_s(self.ref_speed));
        self.struck_modes().iter().map(|m| m.at_speed(n, reference)).collect()
    }

    /// Record length in samples.
    pub fn samples(&self) -> Result<usize, RigError> {
        let fs = self.sample_rate;
        let (field, seconds) = match (self.duration, self.revolutions) {
            (Some(_), Some(_)) => {
                return Err(RigError::Length {
                    field: "duration".into(),
                    message: "give `duration` or `revolutions`, not both".into(),
                });
            }
            (Some(d), None) => {
                positive("duration", d)?;
                ("duration", d)
            }
            (None, Some(r)) => {
                positive("revolutions", r)?;
                if self.speed <= 0.0 {
                    return Err(RigError::Length {
                        field: "revolutions".into(),
                        message: "the spindle does not turn (speed 0): give `duration` instead".into(),
                    });
                }
                ("revolutions", r * TAU / self.speed)
            }
            (None, None) if self.impacts > 0 => ("impact_interval", self.impacts as f64 * self.impact_interval),
            (None, None) => {
                return Err(RigError::Length {
                    field: "duration".into(),
                    message: "a run without impacts needs `duration` or `revolutions`".into(),
                });
            }
        };
        let n = (seconds * fs).round();
        if n.is_nan() || n < 2.0 {
            return Err(RigError::Length { field: field.into(), message: format!("{n} samples: need at least 2") });
        }
        if n > MAX_SAMPLES as f64 {
            return Err(RigError::Length {
                field: field.into(),
                message: format!("{n:e} samples per channel, more than the limit {MAX_SAMPLES}"),
            });
        }
        Ok(n as usize)
    }

    /// The §2.1 impact setup for this hammer against the struck direction's modes at speed,
    /// sampled `IMPACT_SUBSAMPLES` times faster than the record.
    pub(crate) fn impact_setup(&self) -> ImpactSetup {
        let h = &self.hammer;
        let modes = self.modes_at_speed();
        let mut s = ImpactSetup::new(
            crate::impact::Hammer { mass: h.mass, stiffness: h.stiffness, damping: h.damping },
            ModalTarget { modes },
        );
        s.contact = Contact { hammer_tip: h.tip, target: h.target, restitution: h.restitution };
        s.release_position = h.release;
        s.contact_position = h.contact;
        s.dt = h.dt;
        s.sample_rate = self.sample_rate * IMPACT_SUBSAMPLES as f64;
        s.duration = PULSE_WINDOW;
        s
    }

    /// Checks every field; the error names the field and what it must satisfy.
    pub fn validate(&self) -> Result<(), RigError> {
        positive("sample_rate", self.sample_rate)?;
        let nyquist = 0.5 * self.sample_rate;
        non_negative("speed", self.speed)?;
        positive("ref_speed", self.ref_speed)?;
        if !(self.speed_drift.is_finite() && (0.0..0.1).contains(&self.speed_drift)) {
            return Err(bad("speed_drift", self.speed_drift, "must lie in [0, 0.1)"));
        }
        let record = self.samples()? as f64 / self.sample_rate;
        self.validate_modes(nyquist)?;
        self.validate_error_motions(nyquist)?;
        self.validate_sensors()?;
        self.validate_tach()?;
        self.validate_impacts(record)?;
        if self.force_range.is_nan() || self.force_range <= 0.0 {
            return Err(bad("force_range", self.force_range, "must be positive (INFINITY for no clipping)"));
        }
        Ok(())
    }

    /// The modes at rest and at speed: positive, underdamped and below Nyquist.
    fn validate_modes(&self, nyquist: f64) -> Result<(), RigError> {
        for (name, modes) in [("modes_x", &self.modes_x), ("modes_y", &self.modes_y)] {
            for (i, m) in modes.iter().enumerate() {
                let f = |field: &str| format!("{name}[{i}].{field}");
                let (rest, law) = (&m.at_rest, &m.law);
                positive(&f("freq_hz"), rest.freq_hz)?;
                positive(&f("stiffness"), rest.stiffness())?;
                finite(&f("kf"), law.kf)?;
                finite(&f("kzeta"), law.kd)?;
                if !(rest.damping_ratio.is_finite() && (0.0..1.0).contains(&rest.damping_ratio)) {
                    return Err(bad(f("damping_ratio"), rest.damping_ratio, "must lie in [0, 1) (underdamped)"));
                }
                let s = m.at_speed(Speed::from_rad_s(self.speed), Speed::from_rad_s(self.ref_speed));
                if s.freq_hz.is_nan() || s.freq_hz <= 0.0 {
                    return Err(bad(
                        f("kf"),
                        law.kf,
                        format!("gives a natural frequency of {} Hz at speed", s.freq_hz),
                    ));
                }
                if !(s.damping_ratio.is_finite() && (0.0..1.0).contains(&s.damping_ratio)) {
                    return Err(bad(
                        f("kzeta"),
                        law.kd,
                        format!("gives a damping ratio of {} at speed, outside [0, 1)", s.damping_ratio),
                    ));
                }
                if s.freq_hz >= nyquist {
                    return Err(RigError::AboveNyquist { field: f("freq_hz"), frequency: s.freq_hz, nyquist });
                }
            }
        }
        Ok(())
    }

    /// The artifact form, the synchronous and the asynchronous error motions: every harmonic and
    /// tone below Nyquist, the harmonics at the fastest drifting speed (Eq. 3.15).
    fn validate_error_motions(&self, nyquist: f64) -> Result<(), RigError> {
        let f_rot_max = self.speed * (1.0 + self.speed_drift) / TAU;
        for (name, terms) in [("form", &self.form), ("sync_x", &self.sync_x), ("sync_y", &self.sync_y)] {
            for (i, u) in terms.iter().enumerate() {
                if u.upr == 0 {
                    return Err(bad(format!("{name}[{i}].upr"), 0.0, "must be at least 1"));
                }
                non_negative(&format!("{name}[{i}].amplitude"), u.amplitude)?;
                finite(&format!("{name}[{i}].phase"), u.phase)?;
                let f = u.upr as f64 * f_rot_max;
                if f >= nyquist {
                    return Err(RigError::AboveNyquist { field: format!("{name}[{i}].upr"), frequency: f, nyquist });
                }
            }
        }
        non_negative("async_rms", self.async_rms)?;
        positive("async_bandwidth", self.async_bandwidth)?;
        if self.async_rms > 0.0 && self.async_bandwidth >= nyquist {
            return Err(RigError::AboveNyquist {
                field: "async_bandwidth".into(),
                frequency: self.async_bandwidth,
                nyquist,
            });
        }
        for (i, t) in self.async_tones.iter().enumerate() {
            positive(&format!("async_tones[{i}].freq_hz"), t.freq_hz)?;
            non_negative(&format!("async_tones[{i}].amplitude"), t.amplitude)?;
            finite(&format!("async_tones[{i}].phase"), t.phase)?;
            if t.freq_hz >= nyquist {
                return Err(RigError::AboveNyquist {
                    field: format!("async_tones[{i}].freq_hz"),
                    frequency: t.freq_hz,
                    nyquist,
                });
            }
        }
        Ok(())
    }

    /// The probes, the sensor's phase lag, the noise and the converters.
    fn validate_sensors(&self) -> Result<(), RigError> {
        if self.probe_angles.is_empty() {
            return Err(RigError::NoProbes);
        }
        if self.probe_angles.len() > MAX_PROBES {
            return Err(bad("probe_angles", self.probe_angles.len() as f64, format!("at most {MAX_PROBES} probes")));
        }
        for (i, a) in self.probe_angles.iter().enumerate() {
            finite(&format!("probe_angles[{i}]"), *a)?;
        }
        finite("phase_slope", self.phase_slope)?;
        if self.delay().abs() > MAX_DELAY {
            return Err(bad(
                "phase_slope",
                self.phase_slope,
                format!("is a delay of {} s, more than {MAX_DELAY} s", self.delay()),
            ));
        }
        non_negative("noise.force", self.noise.force)?;
        non_negative("noise.probe", self.noise.probe)?;
        non_negative("noise.tach", self.noise.tach)?;
        non_negative("adc.force_lsb", self.adc.force_lsb)?;
        non_negative("adc.probe_lsb", self.adc.probe_lsb)?;
        non_negative("adc.tach_lsb", self.adc.tach_lsb)?;
        Ok(())
    }

    /// The tachometer's levels and a pulse long enough for its edges at the fastest speed.
    fn validate_tach(&self) -> Result<(), RigError> {
        finite("tach.high", self.tach.high)?;
        finite("tach.low", self.tach.low)?;
        positive("tach.edge_time", self.tach.edge_time)?;
        if !(self.tach.pulse_angle > 0.0 && self.tach.pulse_angle < PI) {
            return Err(bad("tach.pulse_angle", self.tach.pulse_angle, "must lie in (0, π) rad"));
        }
        if self.speed > 0.0 {
            let pulse = self.tach.pulse_angle / (self.speed * (1.0 + self.speed_drift));
            if pulse < 2.0 * self.tach.edge_time {
                return Err(bad(
                    "tach.pulse_angle",
                    self.tach.pulse_angle,
                    format!(
                        "lasts {pulse:e} s at this speed, less than two edge times ({} s): widen the pulse or shorten the edges",
                        2.0 * self.tach.edge_time
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The impacts: their spacing, every one inside the record, a hammer that meets the struck
    /// direction's modes, and double hits that name impacts.
    fn validate_impacts(&self, record: f64) -> Result<(), RigError> {
        if self.impacts > 0 {
            positive("impact_interval", self.impact_interval)?;
            non_negative("impact_jitter", self.impact_jitter)?;
            non_negative("impact_offset", self.impact_offset)?;
            if self.impact_offset < self.impact_jitter {
                return Err(bad("impact_offset", self.impact_offset, "must be at least `impact_jitter`"));
            }
            if self.impact_offset + self.impact_jitter + IMPACT_SPAN > self.impact_interval {
                return Err(bad(
                    "impact_offset",
                    self.impact_offset,
                    format!(
                        "plus `impact_jitter` and {IMPACT_SPAN} s for the pulse must fit in `impact_interval` ({} s)",
                        self.impact_interval
                    ),
                ));
            }
            let last = (self.impacts - 1) as f64 * self.impact_interval + self.impact_offset + self.impact_jitter;
            if last + IMPACT_SPAN > record {
                return Err(RigError::Length {
                    field: if self.duration.is_some() { "duration" } else { "revolutions" }.into(),
                    message: format!("the record ({record} s) ends before the last impact at {last} s is over"),
                });
            }
            if self.struck_modes().is_empty() {
                return Err(bad(
                    format!("modes_{}", self.direction.name()),
                    0.0,
                    "the struck direction needs at least one mode",
                ));
            }
            if !(self.hammer.release_scatter.is_finite() && (0.0..0.3).contains(&self.hammer.release_scatter)) {
                return Err(bad("hammer.release_scatter", self.hammer.release_scatter, "must lie in [0, 0.3)"));
            }
            first_contact(&self.impact_setup()).map_err(RigError::Hammer)?;
        }
        for &i in &self.double_hits {
            if i >= self.impacts {
                return Err(bad(
                    "double_hits",
                    i as f64,
                    format!("is not an impact index (0..{} for {} impacts)", self.impacts, self.impacts),
                ));
            }
        }
        Ok(())
    }
}
