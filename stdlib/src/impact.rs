//! Hammer–target impact simulation with Hertz contact and hysteresis damping, dissertation
//! §2.1 (Eqs. 2.2–2.7).
//!
//! Conventions (SI units throughout). Positions are along one axis. The hammer spring rests
//! at `x_h = 0` and the hammer is released at `release_position` (X_hi, +10 mm in the
//! dissertation, from rest). The target rests at `x_t = 0` and its contact surface sits at
//! `contact_position + x_t` (X_t0 = −3 mm). The hammer therefore travels in −x, and the
//! penetration is `δ = (X_t0 + x_t) − x_h`; `δ > 0` means contact. At contact the hammer
//! spring force `−K_h x_h` is positive, i.e. it pulls the hammer away from the target, as
//! required by §2.1. The contact force `F_c ≥ 0` pushes the hammer in +x and the target in
//! −x (Eq. 2.2).
//!
//! The target is a set of independent modes in modal coordinates (Table 2.1): every mode
//! carries the full contact force (unit mode shape at the impact point) and the physical
//! displacement at the impact point is the sum of the modal displacements. A single-DOF
//! target is one mode.
//!
//! Integration. Release to first contact is solved in closed form (the target is at rest
//! and the hammer is a free linear oscillator). Contact phases are integrated with the
//! semi-implicit Euler scheme of Eq. 2.7 at the fine step `dt`. Between contacts both bodies
//! are linear and, when [`ImpactSetup::exact_free_flight`] is set, they are advanced with the
//! exact state-transition matrices; a cubic Hermite bound on the gap over each sub-step
//! detects any possible re-contact (double hit), in which case the output interval is
//! redone with the fine integrator. Setting the flag to `false` steps the whole record with
//! Eq. 2.7, exactly as in the dissertation.
//!
//! Output records are point samples at `sample_rate` (an integer number of fine steps per
//! output interval; `dt` is reduced slightly when needed to make it so). The force record is
//! the contact force magnitude and the target record is positive along the impact
//! direction, so the pair feeds the FRF estimate of Eq. 3.1 directly.

use crate::signal::amplitude_at;
use num_complex::Complex64;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use spindlelab_domain::Mode;
use std::f64::consts::{PI, TAU};
use thiserror::Error;

/// Upper bound on the number of fine integration steps a setup may request
/// (`duration × sample_rate × steps per sample`).
pub const MAX_FINE_STEPS: f64 = 1.0e9;

/// Young's modulus of steel used in the dissertation example, Pa.
pub const STEEL_YOUNGS_MODULUS: f64 = 200.0e9;
/// Poisson's ratio of steel used in the dissertation example.
pub const STEEL_POISSON: f64 = 0.29;

/// Sampling interval of the finely sampled force used for the excited bandwidth, s
/// (10 MHz: far above any bandwidth of interest, yet cheap to transform).
const SPECTRAL_SAMPLE_INTERVAL: f64 = 1.0e-7;
/// −10 dB amplitude ratio that defines the excited bandwidth (§2.1).
const BANDWIDTH_RATIO: f64 = 0.316_227_766_016_837_94;
/// Smallest frequency scan step, as a fraction `1/(n T)` of the force record span `T`,
/// when locating the −10 dB point; a dip narrower than this could go unseen.
const BANDWIDTH_MIN_STEP_PER_SPAN: f64 = 256.0;
/// Cap on frequency scan steps for the excited bandwidth search.
const BANDWIDTH_MAX_SCAN: usize = 200_000;
/// Largest `(ω_n + c/m)·dt` accepted for the fine integration of Eq. 2.7 (stable below 2;
/// 0.1 keeps the linear dynamics accurate to a fraction of a percent).
const MAX_RATE_TIMES_DT: f64 = 0.1;
/// Largest `ω·h` allowed for a free-flight sub-step, which keeps the cubic Hermite
/// re-contact test accurate.
const FREE_FLIGHT_MAX_PHASE: f64 = 0.5;

/// Elastic sphere at one side of the contact; Eq. 2.5–2.6 need its radius, Young's modulus
/// and Poisson's ratio. A radius of `f64::INFINITY` models a flat (sphere–plane contact).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Radius, m (> 0, may be infinite for a flat).
    pub radius: f64,
    /// Young's modulus, Pa.
    pub youngs_modulus: f64,
    /// Poisson's ratio.
    pub poisson: f64,
}

impl Sphere {
    /// A steel sphere with the material constants of the §2.1 example.
    pub fn steel(radius: f64) -> Self {
        Sphere { radius, youngs_modulus: STEEL_YOUNGS_MODULUS, poisson: STEEL_POISSON }
    }

    /// Material compliance `k_i = (1 − ν_i²)/E_i` of Eq. 2.6.
    pub fn compliance(&self) -> f64 {
        (1.0 - self.poisson * self.poisson) / self.youngs_modulus
    }

    fn validate(&self, which: &'static str) -> Result<(), ImpactError> {
        positive_or_inf(which, "radius", self.radius)?;
        positive(which, "youngs_modulus", self.youngs_modulus)?;
        if !(self.poisson > -1.0 && self.poisson < 0.5) {
            return Err(ImpactError::InvalidParameter {
                name: which,
                field: "poisson",
                value: self.poisson,
                requirement: "must lie in (-1, 0.5)",
            });
        }
        Ok(())
    }
}

/// Hammer-tip/target contact pair with the coefficient of restitution of the hysteresis
/// term in Eq. 2.4.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Sphere on the hammer side.
    pub hammer_tip: Sphere,
    /// Sphere on the target side.
    pub target: Sphere,
    /// Coefficient of restitution `e`, in (0, 1].
    pub restitution: f64,
}

impl Contact {
    /// Steel spheres of radii 6.35 mm and 1 mm with `e = 0.95`, the contact used throughout
    /// dissertation §2.1.
    pub fn dissertation_steel() -> Self {
        Contact { hammer_tip: Sphere::steel(6.35e-3), target: Sphere::steel(1.0e-3), restitution: 0.95 }
    }

    /// Hertz stiffness `K = 4/(3(k1+k2)) · sqrt(r1 r2/(r1+r2))` of Eq. 2.5, in N/m^1.5.
    /// The effective radius is written `1/(1/r1 + 1/r2)` so that a flat (`r = ∞`) works.
    pub fn stiffness(&self) -> f64 {
        let r_eff = 1.0 / (1.0 / self.hammer_tip.radius + 1.0 / self.target.radius);
        4.0 / (3.0 * (self.hammer_tip.compliance() + self.target.compliance())) * r_eff.sqrt()
    }

    fn validate(&self) -> Result<(), ImpactError> {
        self.hammer_tip.validate("contact.hammer_tip")?;
        self.target.validate("contact.target")?;
        if !(self.restitution > 0.0 && self.restitution <= 1.0) {
            return Err(ImpactError::InvalidParameter {
                name: "contact",
                field: "restitution",
                value: self.restitution,
                requirement: "must lie in (0, 1]",
            });
        }
        if !(self.hammer_tip.radius.is_finite() || self.target.radius.is_finite()) {
            return Err(ImpactError::InvalidParameter {
                name: "contact",
                field: "radius",
                value: f64::INFINITY,
                requirement: "at least one sphere must have a finite radius",
            });
        }
        Ok(())
    }
}

/// Lumped hammer of Eq. 2.2: mass `M_h`, spring `K_h` (rest at `x_h = 0`) and viscous
/// damping `C_h`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hammer {
    /// Mass, kg (> 0).
    pub mass: f64,
    /// Spring constant, N/m (≥ 0; 0 is a free hammer).
    pub stiffness: f64,
    /// Viscous damping, N·s/m (≥ 0).
    pub damping: f64,
}

/// Target described by independent modes in modal space (Table 2.1); the impact-point
/// displacement is the sum of the modal displacements.
#[derive(Debug, Clone, PartialEq)]
pub struct ModalTarget {
    /// Modes in modal coordinates (unit mode shape at the impact point), each of modal
    /// mass m > 0, stiffness k ≥ 0 and viscous damping c ≥ 0; at least one.
    pub modes: Vec<Mode>,
}

impl ModalTarget {
    /// Single-degree-of-freedom target.
    pub fn single(mass: f64, stiffness: f64, damping: f64) -> Self {
        ModalTarget { modes: vec![Mode::from_mass_stiffness_damping(mass, stiffness, damping)] }
    }

    /// A target of modes given by modal mass (kg), stiffness (N/m) and viscous damping
    /// (N·s/m), each checked before it becomes a [`Mode`] so an error names the value given.
    pub fn from_mass_stiffness_damping(rows: &[(f64, f64, f64)]) -> Result<Self, ImpactError> {
        for &(m, k, c) in rows {
            positive("target mode", "mass", m)?;
            non_negative("target mode", "stiffness", k)?;
            non_negative("target mode", "damping", c)?;
            if k == 0.0 && c > 0.0 {
                return Err(ImpactError::InvalidParameter {
                    name: "target mode",
                    field: "stiffness",
                    value: k,
                    requirement: "must be positive for a damped mode",
                });
            }
        }
        Ok(ModalTarget { modes: rows.iter().map(|&(m, k, c)| Mode::from_mass_stiffness_damping(m, k, c)).collect() })
    }

    /// Mode with the lowest undamped natural frequency, used for the response magnitude.
    pub fn fundamental(&self) -> Option<&Mode> {
        self.modes.iter().min_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz))
    }
}

/// The two 10-mode targets of dissertation Table 2.1.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Table21Target {
    /// Target 1.
    Target1,
    /// Target 2.
    Target2,
}

/// Modal parameters of Table 2.1 (mass kg, stiffness ×1e6 N/m, damping ×1e3 N·s/m) for the
/// requested multi-degree-of-freedom target of §2.1.3.
pub fn table_2_1_target(which: Table21Target) -> ModalTarget {
    const TARGET_1: [(f64, f64, f64); 10] = [
        (2.56, 76.90, 1.11),
        (1.94, 78.96, 1.04),
        (6.25, 69.35, 7.50),
        (125.99, 813.04, 27.07),
        (14.97, 234.46, 9.09),
        (125.80, 547.60, 39.60),
        (1.32, 278.99, 3.85),
        (2.13, 1016.30, 3.82),
        (19.26, 2177.73, 55.61),
        (3.97, 4781.16, 7.29),
    ];
    const TARGET_2: [(f64, f64, f64); 10] = [
        (0.06, 11.90, 0.08),
        (0.60, 30.71, 0.41),
        (4.31, 157.60, 1.35),
        (0.54, 36.40, 0.59),
        (7.10, 103.74, 3.90),
        (0.27, 101.09, 0.29),
        (0.17, 149.96, 0.23),
        (0.22, 328.74, 0.21),
        (1.05, 342.52, 1.39),
        (0.54, 1488.68, 0.99),
    ];
    let rows = match which {
        Table21Target::Target1 => &TARGET_1,
        Table21Target::Target2 => &TARGET_2,
    };
    ModalTarget {
        modes: rows.iter().map(|&(m, k, c)| Mode::from_mass_stiffness_damping(m, k * 1.0e6, c * 1.0e3)).collect(),
    }
}

/// Gaussian sensor noise added to the target displacement record (§2.1.3 uses 25 nm);
/// the seed makes it reproducible.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorNoise {
    /// Standard deviation, m (≥ 0).
    pub std_dev: f64,
    /// Seed of the ChaCha8 generator.
    pub seed: u64,
}

/// Complete description of one simulated impact (§2.1).
#[derive(Debug, Clone, PartialEq)]
pub struct ImpactSetup {
    /// Hammer dynamics.
    pub hammer: Hammer,
    /// Target modes.
    pub target: ModalTarget,
    /// Contact geometry and restitution.
    pub contact: Contact,
    /// Hammer position at release, X_hi, m (must lie on the +x side of `contact_position`).
    pub release_position: f64,
    /// Hammer velocity at release, m/s (0 in the dissertation).
    pub release_velocity: f64,
    /// Target contact surface at rest, X_t0, m.
    pub contact_position: f64,
    /// Requested fine integration step of Eq. 2.7, s (reduced to fit an integer number of
    /// steps per output sample).
    pub dt: f64,
    /// Record length after first contact, s.
    pub duration: f64,
    /// Record length kept before first contact, s (rounded to whole samples).
    pub pre_trigger: f64,
    /// Output sampling rate, Hz.
    pub sample_rate: f64,
    /// Optional sensor noise on the target displacement.
    pub noise: Option<SensorNoise>,
    /// Advance non-contact phases with exact linear propagation (see module docs).
    pub exact_free_flight: bool,
}

impl ImpactSetup {
    /// Setup with the §2.1 geometry (release 10 mm, contact −3 mm), the steel contact,
    /// `dt = 1e-8 s`, a 10 ms record sampled at 100 kHz, no noise.
    pub fn new(hammer: Hammer, target: ModalTarget) -> Self {
        ImpactSetup {
            hammer,
            target,
            contact: Contact::dissertation_steel(),
            release_position: 10.0e-3,
            release_velocity: 0.0,
            contact_position: -3.0e-3,
            dt: 1.0e-8,
            duration: 10.0e-3,
            pre_trigger: 0.0,
            sample_rate: 100.0e3,
            noise: None,
            exact_free_flight: true,
        }
    }

    /// The worked example of §2.1: `M_h = 0.01 kg`, `K_h = 100 N/m`, `M_t = 0.1 kg`,
    /// `K_t = 1e7 N/m`, no damping.
    pub fn dissertation_example() -> Self {
        ImpactSetup::new(Hammer { mass: 0.01, stiffness: 100.0, damping: 0.0 }, ModalTarget::single(0.1, 1.0e7, 0.0))
    }

    fn validate(&self) -> Result<(), ImpactError> {
        positive("hammer", "mass", self.hammer.mass)?;
        non_negative("hammer", "stiffness", self.hammer.stiffness)?;
        non_negative("hammer", "damping", self.hammer.damping)?;
        if self.target.modes.is_empty() {
            return Err(ImpactError::EmptyTarget);
        }
        for mode in &self.target.modes {
            positive("target mode", "mass", mode.modal_mass)?;
            non_negative("target mode", "stiffness", mode.stiffness())?;
            non_negative("target mode", "damping", mode.damping())?;
        }
        self.contact.validate()?;
        finite("setup", "release_position", self.release_position)?;
        finite("setup", "release_velocity", self.release_velocity)?;
        finite("setup", "contact_position", self.contact_position)?;
        if self.release_position <= self.contact_position {
            return Err(ImpactError::InvalidParameter {
                name: "setup",
                field: "release_position",
                value: self.release_position,
                requirement: "must be greater than contact_position (no initial penetration)",
            });
        }
        positive("setup", "dt", self.dt)?;
        // Eq. 2.7 must resolve every linear time scale (stability needs ω·dt < 2).
        let rates = std::iter::once(Body::new(self.hammer.mass, self.hammer.stiffness, self.hammer.damping))
            .chain(self.target.modes.iter().map(|m| Body::new(m.modal_mass, m.stiffness(), m.damping())))
            .map(|b| b.rate);
        for rate in rates {
            if rate * self.dt > MAX_RATE_TIMES_DT {
                return Err(ImpactError::InvalidParameter {
                    name: "setup",
                    field: "dt",
                    value: self.dt,
                    requirement: "too coarse for the fastest hammer or target mode (need (ω_n + c/m)·dt ≤ 0.1)",
                });
            }
        }
        positive("setup", "duration", self.duration)?;
        non_negative("setup", "pre_trigger", self.pre_trigger)?;
        positive("setup", "sample_rate", self.sample_rate)?;
        if let Some(noise) = &self.noise {
            non_negative("noise", "std_dev", noise.std_dev)?;
        }
        let steps = self.duration * self.sample_rate * (1.0 / (self.sample_rate * self.dt)).ceil();
        if steps.is_nan() || steps > MAX_FINE_STEPS {
            return Err(ImpactError::TooManySteps { steps, limit: MAX_FINE_STEPS });
        }
        let samples = (self.duration + self.pre_trigger) * self.sample_rate;
        if samples.is_nan() || samples > MAX_FINE_STEPS {
            return Err(ImpactError::TooManySteps { steps: samples, limit: MAX_FINE_STEPS });
        }
        Ok(())
    }
}

/// Errors of the impact simulation.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ImpactError {
    /// A parameter is out of range or not finite.
    #[error("invalid {name}.{field} = {value}: {requirement}")]
    InvalidParameter {
        /// Which part of the setup.
        name: &'static str,
        /// Which field.
        field: &'static str,
        /// Offending value.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// The target has no modes.
    #[error("the target has no modes")]
    EmptyTarget,
    /// The hammer never reaches the target surface from its release state.
    #[error("the hammer never reaches the target surface")]
    NoContact,
    /// The requested record needs more fine steps than allowed.
    #[error("the setup needs {steps:e} fine steps, more than the limit {limit:e}")]
    TooManySteps {
        /// Requested steps.
        steps: f64,
        /// Limit ([`MAX_FINE_STEPS`]).
        limit: f64,
    },
}

/// First contact of the released hammer with the resting target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FirstContact {
    /// Time from release to first contact, s.
    pub time: f64,
    /// Hammer velocity at first contact, m/s (negative: towards the target).
    pub hammer_velocity: f64,
}

/// One continuous contact episode (`δ > 0`), with boundary times interpolated between
/// fine steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactEvent {
    /// Start, s after first contact.
    pub start: f64,
    /// End, s after first contact (record end if still in contact).
    pub end: f64,
    /// Penetration rate `δ̇` at the start, the `V_i` of Eq. 2.4, m/s (> 0).
    pub approach_velocity: f64,
    /// Penetration rate `δ̇` at separation, m/s (≤ 0; NaN if the record ends in contact).
    pub separation_velocity: f64,
    /// Largest contact force, N.
    pub peak_force: f64,
    /// Time integral of the contact force, N·s.
    pub impulse: f64,
}

/// Output of [`simulate`]: sampled records plus the §2.1 figures of merit.
#[derive(Debug, Clone, PartialEq)]
pub struct ImpactResult {
    /// Output sampling rate, Hz.
    pub sample_rate: f64,
    /// Fine integration step actually used, s.
    pub dt: f64,
    /// Time from release to first contact, s (None when started at contact).
    pub release_to_contact: Option<f64>,
    /// Index of the first-contact sample in the records (time zero).
    pub first_contact_index: usize,
    /// Contact force, N (point samples).
    pub force: Vec<f64>,
    /// Target displacement at the impact point from its rest position, m, positive along
    /// the impact direction (the direction of the contact force on the target, −x), so that
    /// `target_displacement / force` spectra give the target receptance with its usual sign
    /// (Eq. 3.1). Includes sensor noise if requested.
    pub target_displacement: Vec<f64>,
    /// Hammer position `x_h` from its spring rest position, m.
    pub hammer_displacement: Vec<f64>,
    /// Contact episodes in time order (more than one means a multiple hit).
    pub contacts: Vec<ContactEvent>,
    /// Time from first contact to last contact, s (§2.1 (ii)): with a double hit it spans
    /// the hits, as §2.1.1's jump with hammer mass shows.
    pub impulse_time: f64,
    /// Duration of the first contact alone, s: the impulse a lab keeps when it rejects the
    /// later hits (§2.1.3 compares hammer masses by it).
    pub first_impulse_time: f64,
    /// Frequency where the force spectrum, normalised to its DC value (the impulse), first
    /// falls below −10 dB, Hz (§2.1 (i)). Evaluated on the contact force sampled every
    /// 0.1 µs during the fine integration (exact single-frequency transforms, no FFT grid);
    /// 5 MHz if it never falls that low.
    pub excited_bandwidth: f64,
    /// The same of the first contact's force alone, Hz.
    pub first_excited_bandwidth: f64,
    /// Frequency at which the response magnitude is evaluated: the lowest undamped natural
    /// frequency of the target, Hz.
    pub response_frequency: f64,
    /// Single-sided amplitude spectrum of the noise-free target displacement from first
    /// contact to record end at `response_frequency`, m (§2.1 (iii)).
    pub response_magnitude: f64,
    /// Largest contact force, N.
    pub peak_force: f64,
    /// Fine integration steps actually taken.
    pub fine_steps: u64,
}

impl ImpactResult {
    /// Number of separate contact episodes.
    pub fn contact_count(&self) -> usize {
        self.contacts.len()
    }

    /// Time of sample `index` relative to first contact, s.
    pub fn time(&self, index: usize) -> f64 {
        (index as f64 - self.first_contact_index as f64) / self.sample_rate
    }
}

/// Hysteretic Hertz contact force of Eq. 2.4, `K δ^1.5 (1 + 3(1−e²)/4 · δ̇/V_i)`, zero when
/// `δ ≤ 0` and clipped at zero so the contact never pulls.
pub fn contact_force(
    stiffness: f64,
    restitution: f64,
    penetration: f64,
    penetration_rate: f64,
    approach_velocity: f64,
) -> f64 {
    if penetration <= 0.0 {
        return 0.0;
    }
    let hysteresis = 0.75 * (1.0 - restitution * restitution);
    let f = stiffness * penetration * penetration.sqrt() * (1.0 + hysteresis * penetration_rate / approach_velocity);
    f.max(0.0)
}

/// Simulates the impact of §2.1 from hammer release: closed-form approach, then
/// [`simulate_from_contact`] with the approach velocity found.
pub fn simulate(setup: &ImpactSetup) -> Result<ImpactResult, ImpactError> {
    let fc = first_contact(setup)?;
    run(setup, -fc.hammer_velocity, Some(fc.time), true)
}

/// Simulates the impact starting at first contact, with the hammer touching the resting
/// target at speed `approach_speed` (m/s, > 0, towards the target); the release fields of
/// the setup are ignored. This is the kernel timed by the impact benchmarks.
pub fn simulate_from_contact(setup: &ImpactSetup, approach_speed: f64) -> Result<ImpactResult, ImpactError> {
    setup.validate()?;
    positive("simulate_from_contact", "approach_speed", approach_speed)?;
    run(setup, approach_speed, None, true)
}

/// [`simulate`] (from release), or [`simulate_from_contact`] when `approach_speed` is given,
/// without the excited-bandwidth search (left NaN): for callers that need only the force
/// and response records, since that search dominates the cost of a short impact.
pub fn simulate_records(setup: &ImpactSetup, approach_speed: Option<f64>) -> Result<ImpactResult, ImpactError> {
    match approach_speed {
        None => {
            let fc = first_contact(setup)?;
            run(setup, -fc.hammer_velocity, Some(fc.time), false)
        }
        Some(v) => {
            setup.validate()?;
            positive("simulate_from_contact", "approach_speed", v)?;
            run(setup, v, None, false)
        }
    }
}

/// Time and hammer velocity at first contact, solved in closed form from the free linear
/// hammer motion (the target is at rest until then, Eq. 2.2 with `F_c = 0`).
pub fn first_contact(setup: &ImpactSetup) -> Result<FirstContact, ImpactError> {
    setup.validate()?;
    let h = &setup.hammer;
    let body = Body::new(h.mass, h.stiffness, h.damping);
    let x0 = setup.release_position;
    let v0 = setup.release_velocity;
    let level = setup.contact_position;
    let x_at = |t: f64| body.transition(t).apply(x0, v0).0;

    // Times where the hammer velocity vanishes split [0, ∞) into monotone pieces.
    let alpha = body.alpha;
    let wn2 = body.wn2;
    let b2 = wn2 - alpha * alpha;
    let p = alpha * v0 + wn2 * x0; // v(t) ∝ v0·C(t) − p·S(t)
    let mut knots: Vec<f64> = vec![0.0];
    let mut oscillatory_horizon = None;
    if b2 > 0.0 {
        let b = b2.sqrt();
        let phi = p.atan2(b * v0);
        let mut theta = (0.5 * PI - phi).rem_euclid(PI);
        while theta <= TAU * (1.0 + 1e-12) {
            if theta > 0.0 {
                knots.push(theta / b);
            }
            theta += PI;
        }
        oscillatory_horizon = Some(TAU / b);
    } else if b2 < 0.0 {
        let g = (-b2).sqrt();
        if p != 0.0 {
            let r = g * v0 / p;
            if r > 0.0 && r < 1.0 {
                knots.push(r.atanh() / g);
            }
        }
    } else if p != 0.0 && v0 / p > 0.0 {
        knots.push(v0 / p);
    }

    // Find the first monotone piece whose end reaches the contact level.
    let mut bracket = None;
    for pair in knots.windows(2) {
        if x_at(pair[1]) <= level {
            bracket = Some((pair[0], pair[1]));
            break;
        }
    }
    if bracket.is_none() && oscillatory_horizon.is_none() {
        // Non-oscillatory: after the last knot the motion is monotone towards its limit.
        let limit = if wn2 > 0.0 {
            0.0
        } else if alpha > 0.0 {
            x0 + v0 / (2.0 * alpha)
        } else if v0 < 0.0 {
            f64::NEG_INFINITY
        } else {
            f64::INFINITY
        };
        if limit < level {
            let lo = *knots.last().unwrap_or(&0.0);
            let mut hi = lo.max(1e-9) * 2.0;
            let mut found = false;
            for _ in 0..2000 {
                if x_at(hi) <= level {
                    found = true;
                    break;
                }
                hi *= 2.0;
                if !hi.is_finite() {
                    break;
                }
            }
            if found {
                bracket = Some((lo, hi));
            }
        }
    }
    let (mut lo, mut hi) = bracket.ok_or(ImpactError::NoContact)?;
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if x_at(mid) <= level {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let (_, v) = body.transition(hi).apply(x0, v0);
    // A grazing approach (zero normal speed) is no impact.
    if v.is_nan() || v >= -1e-12 {
        return Err(ImpactError::NoContact);
    }
    Ok(FirstContact { time: hi, hammer_velocity: v })
}

/// Single-frequency excited bandwidth of a finely sampled force: the first frequency where
/// `|F(f)|/|F(0)|` falls below −10 dB (§2.1 (i)). `samples` holds `(step index, force)` at
/// a uniform interval `interval`; missing indices are zero force.
fn excited_bandwidth(samples: &[(u64, f64)], interval: f64) -> f64 {
    let f0: f64 = samples.iter().map(|s| s.1).sum();
    if samples.is_empty() || f0 <= 0.0 {
        return 0.0;
    }
    let ratio = |freq: f64| -> f64 {
        let w = -TAU * freq * interval;
        let rot = Complex64::from_polar(1.0, w);
        let mut acc = Complex64::new(0.0, 0.0);
        let mut phasor = Complex64::new(1.0, 0.0);
        let mut last: Option<u64> = None;
        let mut since_seed = 0usize;
        for &(j, f) in samples {
            match last {
                Some(prev) if j == prev + 1 && since_seed < 256 => {
                    phasor *= rot;
                    since_seed += 1;
                }
                _ => {
                    phasor = Complex64::from_polar(1.0, w * j as f64);
                    since_seed = 0;
                }
            }
            last = Some(j);
            acc += phasor * f;
        }
        acc.norm() / f0
    };
    let span = ((samples[samples.len() - 1].0 - samples[0].0) as f64 * interval).max(interval);
    let nyquist = 0.5 / interval;
    // For a non-negative force supported on a span T, |F(f)|/F(0) is Lipschitz in f with
    // constant πT, so no crossing of the threshold can lie closer than (r − r_10dB)/(πT):
    // step by that distance, never less than 1/(BANDWIDTH_MIN_STEP_PER_SPAN·T).
    let lipschitz = PI * span;
    let min_step = 1.0 / (BANDWIDTH_MIN_STEP_PER_SPAN * span);
    let mut f_prev = 0.0;
    let mut r = 1.0;
    for _ in 0..BANDWIDTH_MAX_SCAN {
        let f = f_prev + ((r - BANDWIDTH_RATIO) / lipschitz).max(min_step);
        if f > nyquist {
            break;
        }
        r = ratio(f);
        if r < BANDWIDTH_RATIO {
            let (mut lo, mut hi) = (f_prev, f);
            while hi - lo > 1e-9 * hi {
                let mid = 0.5 * (lo + hi);
                if ratio(mid) < BANDWIDTH_RATIO {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            return 0.5 * (lo + hi);
        }
        f_prev = f;
    }
    nyquist
}

/// Linear body `m ẍ + c ẋ + k x = F` with derived constants.
#[derive(Debug, Clone, Copy)]
struct Body {
    alpha: f64,
    wn2: f64,
    /// Upper bound on the rates of the free motion, `sqrt(k/m) + c/m`.
    rate: f64,
    stiff: bool,
}

impl Body {
    fn new(mass: f64, stiffness: f64, damping: f64) -> Self {
        let wn2 = stiffness / mass;
        Body { alpha: damping / (2.0 * mass), wn2, rate: wn2.sqrt() + damping / mass, stiff: stiffness > 0.0 }
    }

    /// Exact free-response state-transition matrix over time `h` (any sign).
    fn transition(&self, h: f64) -> Transition {
        let a = self.alpha;
        let b2 = self.wn2 - a * a;
        let (ec, es) = if b2 > 0.0 {
            let b = b2.sqrt();
            let e = (-a * h).exp();
            let (s, c) = (b * h).sin_cos();
            (e * c, e * s / b)
        } else if b2 < 0.0 {
            let g = (-b2).sqrt();
            let gh = g * h;
            if gh.abs() < 20.0 {
                let e = (-a * h).exp();
                (e * gh.cosh(), e * gh.sinh() / g)
            } else {
                let ep = ((g - a) * h).exp();
                let em = (-(g + a) * h).exp();
                (0.5 * (ep + em), 0.5 * (ep - em) / g)
            }
        } else {
            let e = (-a * h).exp();
            (e, e * h)
        };
        Transition { xx: ec + a * es, xv: es, vx: -self.wn2 * es, vv: ec - a * es }
    }

    /// Bound on the fourth time derivative of the free response from state `(x, v)`.
    fn fourth_derivative_bound(&self, x: f64, v: f64) -> f64 {
        let r = self.rate;
        let r3 = r * r * r;
        let xs = if self.stiff { r * r3 * x.abs() } else { 0.0 };
        xs + r3 * v.abs()
    }
}

#[derive(Debug, Clone, Copy)]
struct Transition {
    xx: f64,
    xv: f64,
    vx: f64,
    vv: f64,
}

impl Transition {
    #[inline]
    fn apply(&self, x: f64, v: f64) -> (f64, f64) {
        (self.xx * x + self.xv * v, self.vx * x + self.vv * v)
    }
}

/// Largest value on `[0, 1]` of the cubic Hermite interpolant with end values `p0`, `p1`
/// and end slopes (already scaled by the interval) `m0`, `m1`.
fn hermite_max(p0: f64, m0: f64, p1: f64, m1: f64) -> f64 {
    let eval = |t: f64| {
        let t2 = t * t;
        let t3 = t2 * t;
        (2.0 * t3 - 3.0 * t2 + 1.0) * p0 + (t3 - 2.0 * t2 + t) * m0 + (-2.0 * t3 + 3.0 * t2) * p1 + (t3 - t2) * m1
    };
    let mut best = p0.max(p1);
    let a = 6.0 * p0 + 3.0 * m0 - 6.0 * p1 + 3.0 * m1;
    let b = -6.0 * p0 - 4.0 * m0 + 6.0 * p1 - 2.0 * m1;
    let c = m0;
    let mut consider = |t: f64| {
        if t > 0.0 && t < 1.0 {
            best = best.max(eval(t));
        }
    };
    if a.abs() < 1e-300 {
        if b != 0.0 {
            consider(-c / b);
        }
    } else {
        let disc = b * b - 4.0 * a * c;
        if disc >= 0.0 {
            let sq = disc.sqrt();
            let qq = -0.5 * (b + b.signum() * sq);
            if qq != 0.0 {
                consider(qq / a);
                consider(c / qq);
            } else {
                consider(0.0);
            }
        }
    }
    best
}

/// Bodies stepped side by side: the hammer and the target's modes are stored in groups of
/// this many lanes (the last group padded with bodies that stay at rest), so a step's
/// arithmetic runs in vector registers and its sums are taken in one fixed order.
const LANES: usize = 4;
type Lane = [f64; LANES];

/// One semi-implicit Euler step of Eq. 2.7 for a linear body `m ẍ + c ẋ + k x = −F`,
/// written as a map of the previous state:
/// `v' = (1 − c dt/m) v − (k dt/m) x − (dt/m) F` and
/// `x' = x + dt v' = (1 − k dt²/m) x + dt (1 − c dt/m) v − (dt²/m) F`.
/// It is Eq. 2.7 in exact arithmetic; written this way the new position no longer waits
/// for the new velocity, so each step's dependent chain is one multiply and one add.
#[derive(Debug, Clone, Copy)]
struct EulerMap {
    vv: f64,
    vx: f64,
    vf: f64,
    xx: f64,
    xv: f64,
    xf: f64,
}

impl EulerMap {
    /// Map of a body of mass `m`, damping `c` and stiffness `k` over the step `dt`.
    fn new(m: f64, c: f64, k: f64, dt: f64) -> Self {
        let vv = 1.0 - c * dt / m;
        let vx = k * dt / m;
        let vf = -dt / m;
        EulerMap { vv, vx, vf, xx: 1.0 - vx * dt, xv: dt * vv, xf: vf * dt }
    }

    /// A padding lane: stays at rest whatever the force.
    const REST: EulerMap = EulerMap { vv: 1.0, vx: 0.0, vf: 0.0, xx: 1.0, xv: 0.0, xf: 0.0 };

    /// One step from `(x, v)` under force `f`; `CONTACT = false` means `f = 0`.
    #[inline(always)]
    fn step<const CONTACT: bool>(&self, x: f64, v: f64, f: f64) -> (f64, f64) {
        let v1 = self.vv * v - self.vx * x;
        let x1 = self.xx * x + self.xv * v;
        if CONTACT { (x1 + self.xf * f, v1 + self.vf * f) } else { (x1, v1) }
    }
}

/// The maps of one group of [`LANES`] modes, field by field.
#[derive(Debug, Clone, Copy)]
struct GroupMap {
    vv: Lane,
    vx: Lane,
    vf: Lane,
    xx: Lane,
    xv: Lane,
    xf: Lane,
}

/// Every moving body as lanes: lane 0 is the hammer with its coordinates sign-flipped
/// (`y = −x_h`), lanes 1… the target's modes. Every lane then obeys `m ÿ + c ẏ + k y = −F`
/// (Eq. 2.2: the contact force pushes the hammer in +x and the target in −x), and the
/// penetration is the plain sum `δ = Σ y + X_t0` of Eq. 2.2's gap.
#[derive(Debug, Clone, Default)]
struct Bodies {
    maps: Vec<GroupMap>,
    /// Displacements and velocities (padding lanes stay zero).
    q: Vec<Lane>,
    u: Vec<Lane>,
    /// Number of real bodies (the hammer and the modes).
    bodies: usize,
}

impl Bodies {
    /// Lanes of the bodies with `maps` (the hammer's first), at rest.
    fn new(maps: &[EulerMap]) -> Self {
        let groups = maps.len().div_ceil(LANES).max(1);
        let group = |g: usize| {
            let at = |l: usize| maps.get(g * LANES + l).copied().unwrap_or(EulerMap::REST);
            let field = |get: fn(&EulerMap) -> f64| -> Lane { std::array::from_fn(|l| get(&at(l))) };
            GroupMap {
                vv: field(|m| m.vv),
                vx: field(|m| m.vx),
                vf: field(|m| m.vf),
                xx: field(|m| m.xx),
                xv: field(|m| m.xv),
                xf: field(|m| m.xf),
            }
        };
        Bodies {
            maps: (0..groups).map(group).collect(),
            q: vec![[0.0; LANES]; groups],
            u: vec![[0.0; LANES]; groups],
            bodies: maps.len(),
        }
    }

    /// `(Σ y, Σ ẏ)` over every body, in the same order as the integrator's own sums.
    fn sums(&self) -> (f64, f64) {
        lane_sums(&self.q, &self.u)
    }

    /// Hammer position `x_h` and velocity.
    fn hammer(&self) -> (f64, f64) {
        (-self.q[0][0], -self.u[0][0])
    }

    /// Target displacement at the impact point, `Σ q` over the modes (lane 0 left out).
    fn target(&self) -> f64 {
        let mut sq = [0.0; LANES];
        for (g, q) in self.q.iter().enumerate() {
            for l in 0..LANES {
                sq[l] += if g == 0 && l == 0 { 0.0 } else { q[l] };
            }
        }
        lane_sum(&sq)
    }
}

/// `(Σ q, Σ u)` over lane groups: lane-wise over the groups, then across the lanes.
#[inline(always)]
fn lane_sums(q: &[Lane], u: &[Lane]) -> (f64, f64) {
    let (mut sq, mut su) = ([0.0; LANES], [0.0; LANES]);
    for (q, u) in q.iter().zip(u) {
        for l in 0..LANES {
            sq[l] += q[l];
            su[l] += u[l];
        }
    }
    (lane_sum(&sq), lane_sum(&su))
}

/// One step of every body under force `f` (`CONTACT = false`: no force); the sums of the new
/// state are [`lane_sums`]'s.
#[inline(always)]
fn step_bodies<const CONTACT: bool>(maps: &[GroupMap], q: &mut [Lane], u: &mut [Lane], f: f64) {
    for ((m, q), u) in maps.iter().zip(q.iter_mut()).zip(u.iter_mut()) {
        for l in 0..LANES {
            let map = EulerMap { vv: m.vv[l], vx: m.vx[l], vf: m.vf[l], xx: m.xx[l], xv: m.xv[l], xf: m.xf[l] };
            (q[l], u[l]) = map.step::<CONTACT>(q[l], u[l], f);
        }
    }
}

/// Pairwise sum of one lane group, `(a₀ + a₁) + (a₂ + a₃)`.
#[inline(always)]
fn lane_sum(a: &Lane) -> f64 {
    (a[0] + a[1]) + (a[2] + a[3])
}

/// Integrator state and bookkeeping for one run from first contact.
struct Sim {
    // Constants.
    dt: f64,
    contact_k: f64,
    hysteresis: f64,
    x_t0: f64,
    spectral_stride: u64,
    // State: the hammer and the target's modes.
    bodies: Bodies,
    // Current penetration and rate for the current state.
    delta: f64,
    delta_rate: f64,
    step: u64,
    in_contact: bool,
    hyst_over_vi: f64,
    contacts: Vec<ContactEvent>,
    spectral: Vec<(u64, f64)>,
    fine_steps: u64,
}

impl Sim {
    /// Penetration `δ = (X_t0 + x_t) − x_h` (Eq. 2.2's gap) and its rate from the state.
    fn refresh_gap(&mut self) {
        let (sq, su) = self.bodies.sums();
        self.delta = sq + self.x_t0;
        self.delta_rate = su;
    }

    #[inline]
    fn force_now(&self) -> f64 {
        if self.in_contact && self.delta > 0.0 {
            let d = self.delta;
            (self.contact_k * d * d.sqrt() * (1.0 + self.hyst_over_vi * self.delta_rate)).max(0.0)
        } else {
            0.0
        }
    }

    /// `n` semi-implicit Euler steps of Eq. 2.7 with the contact force of Eq. 2.4, run as
    /// alternating contact and free stretches (a free step has no force to evaluate).
    fn fine_steps(&mut self, n: usize) {
        let mut done = 0;
        while done < n {
            done += if self.in_contact { self.stretch::<true>(n - done) } else { self.stretch::<false>(n - done) };
        }
        self.fine_steps += n as u64;
    }

    /// Up to `n` steps in the current contact state (`CONTACT` tells which), stopping after
    /// the step where it changes; returns the steps taken. Up to three lane groups (the hammer
    /// and eleven modes) are held in registers for the whole stretch.
    fn stretch<const CONTACT: bool>(&mut self, n: usize) -> usize {
        match self.bodies.q.len() {
            1 => self.stretch_dispatch::<CONTACT, 1>(n),
            2 => self.stretch_dispatch::<CONTACT, 2>(n),
            3 => self.stretch_dispatch::<CONTACT, 3>(n),
            _ => self.stretch_dispatch::<CONTACT, 0>(n),
        }
    }

    /// Runs [`Sim::stretch_in`] compiled for AVX2 where the CPU has it.
    fn stretch_dispatch<const CONTACT: bool, const G: usize>(&mut self, n: usize) -> usize {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { self.stretch_avx2::<CONTACT, G>(n) };
        }
        self.stretch_in::<CONTACT, G>(n)
    }

    /// [`Sim::stretch_in`] for AVX2: the same operations in the same order, no fused
    /// multiply-add, so the same bits.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn stretch_avx2<const CONTACT: bool, const G: usize>(&mut self, n: usize) -> usize {
        self.stretch_in::<CONTACT, G>(n)
    }

    /// The stretch with the bodies' maps and state moved out of `self`: into local arrays of
    /// `G` lane groups when `G > 0` (kept in registers), else used in place.
    #[inline(always)]
    fn stretch_in<const CONTACT: bool, const G: usize>(&mut self, n: usize) -> usize {
        let mut bodies = std::mem::take(&mut self.bodies);
        let taken = if G > 0 {
            let maps: [GroupMap; G] = std::array::from_fn(|g| bodies.maps[g]);
            let mut q: [Lane; G] = std::array::from_fn(|g| bodies.q[g]);
            let mut u: [Lane; G] = std::array::from_fn(|g| bodies.u[g]);
            let taken = self.steps::<CONTACT>(&maps, &mut q, &mut u, n);
            bodies.q.copy_from_slice(&q);
            bodies.u.copy_from_slice(&u);
            taken
        } else {
            self.steps::<CONTACT>(&bodies.maps, &mut bodies.q, &mut bodies.u, n)
        };
        self.bodies = bodies;
        taken
    }

    #[inline(always)]
    fn steps<const CONTACT: bool>(&mut self, maps: &[GroupMap], q: &mut [Lane], u: &mut [Lane], n: usize) -> usize {
        let dt = self.dt;
        let k = self.contact_k;
        let hyst_over_vi = self.hyst_over_vi;
        let stride = self.spectral_stride;
        let gap_offset = self.x_t0;
        let (mut delta, mut rate) = (self.delta, self.delta_rate);
        // Running peak and impulse of the open contact event.
        let (mut peak, mut impulse) = match self.contacts.last() {
            Some(ev) if CONTACT => (ev.peak_force, ev.impulse),
            _ => (0.0, 0.0),
        };
        // Steps until the next spectral sample (taken when the step is a multiple of stride).
        let mut countdown = (stride - self.step % stride) % stride;
        let mut taken = 0;
        let mut changed = false;
        while taken < n {
            // Contact force at the current state (Eq. 2.4).
            let f = if CONTACT { (k * delta * delta.sqrt() * (1.0 + hyst_over_vi * rate)).max(0.0) } else { 0.0 };
            if CONTACT {
                if countdown == 0 {
                    if f > 0.0 {
                        self.spectral.push(((self.step + taken as u64) / stride, f));
                    }
                    countdown = stride;
                }
                countdown -= 1;
                impulse += f * dt;
                peak = peak.max(f);
            }
            // Eq. 2.3 accelerations and the Eq. 2.7 update, as maps of the previous state.
            step_bodies::<CONTACT>(maps, q, u, f);
            let (sq, su) = lane_sums(q, u);
            let new_delta = sq + gap_offset;
            let new_rate = su;
            taken += 1;
            if (new_delta > 0.0) != CONTACT {
                self.mark_change(self.step + taken as u64, delta, new_delta, new_rate, peak, impulse);
                changed = true;
            }
            delta = new_delta;
            rate = new_rate;
            if changed {
                break;
            }
        }
        if CONTACT
            && !changed
            && let Some(ev) = self.contacts.last_mut()
        {
            ev.peak_force = peak;
            ev.impulse = impulse;
        }
        self.delta = delta;
        self.delta_rate = rate;
        self.step += taken as u64;
        taken
    }

    /// Records a change of contact state during the step that ends at `step`: an onset
    /// (`δ` crosses zero upwards; `V_i` is the penetration rate now) or a separation (the
    /// open event's end by linear interpolation, its peak and impulse).
    #[cold]
    fn mark_change(&mut self, step: u64, delta: f64, new_delta: f64, new_rate: f64, peak: f64, impulse: f64) {
        let dt = self.dt;
        if new_delta > 0.0 {
            let t1 = step as f64 * dt;
            let frac = new_delta / (new_delta - delta);
            let v_i = new_rate.max(f64::MIN_POSITIVE);
            self.in_contact = true;
            self.hyst_over_vi = self.hysteresis / v_i;
            self.contacts.push(ContactEvent {
                start: t1 - frac * dt,
                end: f64::NAN,
                approach_velocity: v_i,
                separation_velocity: f64::NAN,
                peak_force: 0.0,
                impulse: 0.0,
            });
        } else {
            let t0 = (step - 1) as f64 * dt;
            let frac = delta / (delta - new_delta);
            self.in_contact = false;
            if let Some(ev) = self.contacts.last_mut() {
                ev.end = t0 + frac * dt;
                ev.separation_velocity = new_rate;
                ev.peak_force = peak;
                ev.impulse = impulse;
            }
        }
    }
}

/// Free-flight propagators for one sub-step.
struct FreeFlight {
    substeps: usize,
    h: f64,
    /// The hammer and the target's modes, in the order of [`Bodies`]' lanes.
    bodies: Vec<Body>,
    transitions: Vec<Transition>,
}

impl FreeFlight {
    /// Advances one output interval exactly unless the gap may close; returns false (state
    /// untouched) when the interval must be integrated with contact.
    fn try_advance(&self, sim: &mut Sim, save_q: &mut [Lane], save_u: &mut [Lane]) -> bool {
        if sim.in_contact || sim.delta > 0.0 {
            return false;
        }
        save_q.copy_from_slice(&sim.bodies.q);
        save_u.copy_from_slice(&sim.bodies.u);
        let h = self.h;
        let h4 = h * h * h * h / 384.0;
        let mut g_a = sim.delta;
        let mut d_a = sim.delta_rate;
        let n = sim.bodies.bodies;
        for _ in 0..self.substeps {
            // A linear map: the hammer's sign-flipped lane moves as the hammer does.
            let q = &mut sim.bodies.q.as_flattened_mut()[..n];
            let u = &mut sim.bodies.u.as_flattened_mut()[..n];
            let mut bound = 0.0;
            for j in 0..n {
                bound += self.bodies[j].fourth_derivative_bound(q[j], u[j]);
                (q[j], u[j]) = self.transitions[j].apply(q[j], u[j]);
            }
            let (sq, su) = sim.bodies.sums();
            let g_b = sq + sim.x_t0;
            let d_b = su;
            let peak = hermite_max(g_a, d_a * h, g_b, d_b * h);
            if peak + 2.0 * h4 * bound >= 0.0 {
                sim.bodies.q.copy_from_slice(save_q);
                sim.bodies.u.copy_from_slice(save_u);
                sim.refresh_gap();
                return false;
            }
            g_a = g_b;
            d_a = d_b;
        }
        sim.delta = g_a;
        sim.delta_rate = d_a;
        true
    }
}

fn run(
    setup: &ImpactSetup,
    approach_speed: f64,
    release_to_contact: Option<f64>,
    bandwidth: bool,
) -> Result<ImpactResult, ImpactError> {
    let fs = setup.sample_rate;
    let ts = 1.0 / fs;
    let n_sub = ((ts / setup.dt) * (1.0 - 1e-12)).ceil().max(1.0) as usize;
    let dt = ts / n_sub as f64;
    let n_pre = (setup.pre_trigger * fs).round() as usize;
    let n_post = ((setup.duration * fs).round() as usize).max(1);
    let x_t0 = setup.contact_position;
    let hm = &setup.hammer;
    let modes = &setup.target.modes;

    let spectral_stride = ((SPECTRAL_SAMPLE_INTERVAL / dt).round() as u64).max(1);
    let mut sim = Sim {
        dt,
        contact_k: setup.contact.stiffness(),
        hysteresis: 0.75 * (1.0 - setup.contact.restitution * setup.contact.restitution),
        x_t0,
        spectral_stride,
        bodies: Bodies::new(
            &std::iter::once((hm.mass, hm.damping, hm.stiffness))
                .chain(modes.iter().map(|m| (m.modal_mass, m.damping(), m.stiffness())))
                .map(|(m, c, k)| EulerMap::new(m, c, k, dt))
                .collect::<Vec<_>>(),
        ),
        delta: 0.0,
        delta_rate: approach_speed,
        step: 0,
        in_contact: false,
        hyst_over_vi: 0.0,
        contacts: Vec::new(),
        spectral: Vec::with_capacity(4096),
        fine_steps: 0,
    };

    let hammer_body = Body::new(hm.mass, hm.stiffness, hm.damping);
    let mode_bodies: Vec<Body> = modes.iter().map(|m| Body::new(m.modal_mass, m.stiffness(), m.damping())).collect();
    let max_rate = mode_bodies.iter().map(|b| b.rate).fold(hammer_body.rate, f64::max);
    let substeps = ((ts * max_rate / FREE_FLIGHT_MAX_PHASE).ceil() as usize).max(1);
    let h = ts / substeps as f64;
    let bodies: Vec<Body> = std::iter::once(hammer_body).chain(mode_bodies).collect();
    let free = FreeFlight { substeps, h, transitions: bodies.iter().map(|b| b.transition(h)).collect(), bodies };
    // The hammer touches the resting target: `x_h = X_t0`, moving at the approach speed.
    sim.bodies.q[0][0] = -x_t0;
    sim.bodies.u[0][0] = approach_speed;
    let mut save_q = sim.bodies.q.clone();
    let mut save_u = sim.bodies.u.clone();

    let total = n_pre + n_post;
    let mut force = Vec::with_capacity(total);
    let mut target = Vec::with_capacity(total);
    let mut hammer = Vec::with_capacity(total);

    // Before first contact: target at rest, hammer on its free trajectory (held at the
    // release position before release, when that is known).
    for k in 0..n_pre {
        let t = (k as f64 - n_pre as f64) * ts;
        let xh = match release_to_contact {
            Some(tc) if t + tc <= 0.0 => setup.release_position,
            _ => hammer_body.transition(t).apply(x_t0, -approach_speed).0,
        };
        force.push(0.0);
        target.push(0.0);
        hammer.push(xh);
    }

    for k in 0..n_post {
        force.push(sim.force_now());
        target.push(-sim.bodies.target());
        hammer.push(sim.bodies.hammer().0);
        if k + 1 == n_post {
            break;
        }
        let advanced = setup.exact_free_flight && free.try_advance(&mut sim, &mut save_q, &mut save_u);
        if advanced {
            sim.step += n_sub as u64;
        } else {
            sim.fine_steps(n_sub);
        }
    }

    let record_end = (n_post - 1) as f64 * ts;
    if let (true, Some(ev)) = (sim.in_contact, sim.contacts.last_mut()) {
        ev.end = record_end;
    }
    let contacts = sim.contacts;
    let impulse_time = match (contacts.first(), contacts.last()) {
        (Some(a), Some(b)) => b.end - a.start,
        _ => 0.0,
    };
    let peak_force = contacts.iter().map(|c| c.peak_force).fold(0.0, f64::max);
    let excited_bandwidth =
        if bandwidth { excited_bandwidth(&sim.spectral, spectral_stride as f64 * dt) } else { f64::NAN };
    let first_impulse_time = contacts.first().map_or(0.0, |c| c.end - c.start);
    // The first contact's samples: the first run of consecutive sample indices (between
    // contacts the force is zero and no sample is kept).
    let first_len = sim.spectral.windows(2).position(|w| w[1].0 != w[0].0 + 1).map_or(sim.spectral.len(), |i| i + 1);
    let first_excited_bandwidth = if bandwidth && first_len < sim.spectral.len() {
        self::excited_bandwidth(&sim.spectral[..first_len], spectral_stride as f64 * dt)
    } else {
        excited_bandwidth
    };

    let response_frequency = setup.target.fundamental().map(|m| m.freq_hz).unwrap_or(0.0);
    let response_magnitude = amplitude_at(&target[n_pre..], fs, response_frequency);

    if let Some(noise) = setup.noise.filter(|n| n.std_dev > 0.0) {
        let normal = Normal::new(0.0, noise.std_dev).map_err(|_| ImpactError::InvalidParameter {
            name: "noise",
            field: "std_dev",
            value: noise.std_dev,
            requirement: "must be finite and non-negative",
        })?;
        let mut rng = ChaCha8Rng::seed_from_u64(noise.seed);
        for x in target.iter_mut() {
            *x += normal.sample(&mut rng);
        }
    }

    Ok(ImpactResult {
        sample_rate: fs,
        dt,
        release_to_contact,
        first_contact_index: n_pre,
        force,
        target_displacement: target,
        hammer_displacement: hammer,
        contacts,
        impulse_time,
        first_impulse_time,
        excited_bandwidth,
        first_excited_bandwidth,
        response_frequency,
        response_magnitude,
        peak_force,
        fine_steps: sim.fine_steps,
    })
}

fn finite(name: &'static str, field: &'static str, value: f64) -> Result<(), ImpactError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(ImpactError::InvalidParameter { name, field, value, requirement: "must be finite" })
    }
}

fn positive(name: &'static str, field: &'static str, value: f64) -> Result<(), ImpactError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ImpactError::InvalidParameter { name, field, value, requirement: "must be finite and positive" })
    }
}

fn positive_or_inf(name: &'static str, field: &'static str, value: f64) -> Result<(), ImpactError> {
    if value > 0.0 {
        Ok(())
    } else {
        Err(ImpactError::InvalidParameter { name, field, value, requirement: "must be positive" })
    }
}

fn non_negative(name: &'static str, field: &'static str, value: f64) -> Result<(), ImpactError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(ImpactError::InvalidParameter { name, field, value, requirement: "must be finite and non-negative" })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `2 ∫₀¹ (1 − u^{5/2})^{-1/2} du = (4/5) B(2/5, 1/2)`: Hertz contact time over `δ_max/v`.
    const HERTZ_TIME_FACTOR: f64 = 2.943_27;

    fn free_pair(mh: f64, mt: f64, speed: f64, restitution: f64) -> ImpactSetup {
        let mut s =
            ImpactSetup::new(Hammer { mass: mh, stiffness: 0.0, damping: 0.0 }, ModalTarget::single(mt, 0.0, 0.0));
        s.contact.restitution = restitution;
        s.release_position = s.contact_position + 1.0e-4;
        s.release_velocity = -speed;
        s.duration = 0.3e-3;
        s.sample_rate = 1.0e6;
        s
    }

    fn sweep_setup(mh: f64) -> ImpactSetup {
        let mut s =
            ImpactSetup::new(Hammer { mass: mh, stiffness: 500.0, damping: 0.0 }, ModalTarget::single(0.1, 5.0e7, 0.0));
        s.duration = 2.0e-3;
        s
    }

    #[test]
    fn hertz_stiffness_eq_2_5() {
        let c = Contact::dissertation_steel();
        let k1 = (1.0 - 0.29f64.powi(2)) / 200.0e9;
        let r = 6.35e-3 * 1.0e-3 / (6.35e-3 + 1.0e-3);
        let expected = 4.0 / (3.0 * 2.0 * k1) * f64::sqrt(r);
        assert!((c.stiffness() - expected).abs() < 1e-12 * expected);
        // Swapping the spheres changes nothing; a flat equals a sphere of infinite radius.
        let swapped = Contact { hammer_tip: c.target, target: c.hammer_tip, ..c };
        assert!((swapped.stiffness() - c.stiffness()).abs() < 1e-9 * expected);
        let flat = Contact { target: Sphere::steel(f64::INFINITY), ..c };
        let expected_flat = 4.0 / (3.0 * 2.0 * k1) * f64::sqrt(6.35e-3);
        assert!((flat.stiffness() - expected_flat).abs() < 1e-9 * expected_flat);
    }

    #[test]
    fn contact_force_eq_2_4_is_hysteretic_and_never_pulls() {
        let (k, e, vi) = (4.0e9, 0.8, 1.0);
        let d: f64 = 2.0e-6;
        let elastic = k * d.powf(1.5);
        let loading = contact_force(k, e, d, vi, vi);
        let unloading = contact_force(k, e, d, -vi, vi);
        assert!((loading - elastic * (1.0 + 0.75 * (1.0 - e * e))).abs() < 1e-9 * elastic);
        assert!(unloading < elastic && unloading > 0.0);
        assert_eq!(contact_force(k, e, -1e-9, 1.0, 1.0), 0.0);
        assert_eq!(contact_force(k, 0.01, d, -1.0e3, 1.0), 0.0);
    }

    #[test]
    fn first_contact_matches_harmonic_motion() {
        let s = ImpactSetup::dissertation_example();
        let fc = first_contact(&s).unwrap();
        let w = (100.0f64 / 0.01).sqrt();
        let t = (s.contact_position / s.release_position).acos() / w;
        let v = -w * (s.release_position.powi(2) - s.contact_position.powi(2)).sqrt();
        assert!((fc.time - t).abs() < 1e-12, "{} vs {t}", fc.time);
        assert!((fc.hammer_velocity - v).abs() < 1e-9 * v.abs());

        // Light damping still reaches the target, a little later and slower.
        let mut damped = s.clone();
        damped.hammer.damping = 0.05;
        let fd = first_contact(&damped).unwrap();
        assert!(fd.time > fc.time && fd.hammer_velocity > v && fd.hammer_velocity < 0.0);
        let body = Body::new(0.01, 100.0, 0.05);
        let (x, _) = body.transition(fd.time).apply(s.release_position, 0.0);
        assert!((x - s.contact_position).abs() < 1e-15);

        // Overdamped hammer creeps to its rest position and never reaches −3 mm.
        let mut over = s.clone();
        over.hammer.damping = 10.0;
        assert_eq!(first_contact(&over), Err(ImpactError::NoContact));
    }

    #[test]
    fn hertz_free_sphere_contact_time_and_peak_force() {
        for &(mh, mt, v) in &[(0.01, 0.1, 1.0), (0.05, 0.2, 0.3)] {
            let s = free_pair(mh, mt, v, 1.0);
            let r = simulate(&s).unwrap();
            assert_eq!(r.contact_count(), 1);
            let k = s.contact.stiffness();
            let m_star = mh * mt / (mh + mt);
            let delta_max = (1.25 * m_star * v * v / k).powf(0.4);
            let t_hertz = HERTZ_TIME_FACTOR * delta_max / v;
            let f_max = k.powf(0.4) * (1.25 * m_star * v * v).powf(0.6);
            let t = r.impulse_time;
            assert!((t / t_hertz - 1.0).abs() < 0.005, "T {t} vs {t_hertz}");
            assert!((r.peak_force / f_max - 1.0).abs() < 0.005, "F {} vs {f_max}", r.peak_force);
            // Equivalent form (m*²/(K² v))^(1/5) carries the factor 2.9432·(5/4)^(2/5).
            let alt = HERTZ_TIME_FACTOR * 1.25f64.powf(0.4) * (m_star * m_star / (k * k * v)).powf(0.2);
            assert!((alt / t_hertz - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn elastic_impact_conserves_energy_and_momentum() {
        let (mh, mt, v) = (0.01, 0.1, 1.0);
        let r = simulate(&free_pair(mh, mt, v, 1.0)).unwrap();
        let c = r.contacts[0];
        let m_star = mh * mt / (mh + mt);
        let before = 0.5 * m_star * c.approach_velocity.powi(2);
        let after = 0.5 * m_star * c.separation_velocity.powi(2);
        assert!((after / before - 1.0).abs() < 1e-3, "{after} vs {before}");
        assert!((c.approach_velocity - v).abs() < 1e-6);
        // Free bodies after the impact: total momentum equals the hammer's initial momentum.
        let n = r.target_displacement.len();
        // The target record is positive along the impact direction (−x).
        let vt = -(r.target_displacement[n - 1] - r.target_displacement[n - 2]) * r.sample_rate;
        let vh = (r.hammer_displacement[n - 1] - r.hammer_displacement[n - 2]) * r.sample_rate;
        let p = mh * vh + mt * vt;
        assert!((p - mh * (-v)).abs() < 1e-6 * mh * v, "momentum {p}");
        // Elastic collision of free bodies: v_t = −2 m_h v/(m_h + m_t).
        assert!((vt + 2.0 * mh * v / (mh + mt)).abs() < 1e-3 * v);
    }

    #[test]
    fn hysteresis_gives_requested_restitution() {
        let r = simulate(&free_pair(0.01, 0.1, 1.0, 0.95)).unwrap();
        let c = r.contacts[0];
        let e_eff = -c.separation_velocity / c.approach_velocity;
        assert!((e_eff / 0.95 - 1.0).abs() < 0.02, "effective restitution {e_eff}");
        // A lower restitution loses more energy.
        let r2 = simulate(&free_pair(0.01, 0.1, 1.0, 0.8)).unwrap();
        let e2 = -r2.contacts[0].separation_velocity / r2.contacts[0].approach_velocity;
        assert!(e2 < e_eff - 0.1, "e=0.8 gives {e2}");
    }

    #[test]
    fn dissertation_example_figures_of_merit() {
        let mut s = ImpactSetup::dissertation_example();
        s.pre_trigger = 0.1e-3;
        let r = simulate(&s).unwrap();
        assert_eq!(r.first_contact_index, 10);
        assert_eq!(r.contact_count(), 1);
        assert!(r.impulse_time > 0.05e-3 && r.impulse_time < 0.2e-3, "{}", r.impulse_time);
        // The bandwidth by its definition, computed here independently: a dense scan of the
        // recorded force's spectrum for the first drop below −10 dB.
        let f0: f64 = r.force.iter().sum();
        let ratio = |f: f64| {
            let w = -TAU * f / r.sample_rate;
            let acc: Complex64 = r.force.iter().enumerate().map(|(k, &x)| Complex64::from_polar(x, w * k as f64)).sum();
            acc.norm() / f0
        };
        let dense = (1..200_000).map(|i| i as f64 * 1.0).find(|&f| ratio(f) < BANDWIDTH_RATIO).expect("a −10 dB point");
        // The recorded force has about ten samples per pulse at 100 kHz; the kernel scans the
        // finer integration steps, so the two sums differ by the coarser one's quadrature (0.5 %).
        assert!(
            (r.excited_bandwidth / dense - 1.0).abs() < 1e-2,
            "{} Hz vs dense scan {dense} Hz",
            r.excited_bandwidth
        );
        assert!(r.response_magnitude > 0.0 && r.response_magnitude.is_finite());
        assert!((r.response_frequency - (1.0e7f64 / 0.1).sqrt() / TAU).abs() < 1e-9);
        assert!(r.peak_force > 0.0 && r.force.iter().all(|f| *f >= 0.0));
        assert_eq!(r.force.len(), 1010);
        // The target was at rest before contact; afterwards it rings at its natural
        // frequency with the response magnitude as amplitude (no damping).
        assert!(r.target_displacement[..10].iter().all(|x| *x == 0.0));
        let tail_peak = r.target_displacement[500..].iter().fold(0.0f64, |a, x| a.max(x.abs()));
        assert!((tail_peak / r.response_magnitude - 1.0).abs() < 0.05);
        // The impulse is the momentum handed to the target plus the hammer rebound.
        let total: f64 = r.contacts.iter().map(|c| c.impulse).sum();
        let sampled: f64 = r.force.iter().sum::<f64>() / r.sample_rate;
        assert!((sampled / total - 1.0).abs() < 0.05);
        // Hammer rebounds: it moves back towards +x after the impact.
        let n = r.hammer_displacement.len();
        assert!(r.hammer_displacement[n - 1] > r.hammer_displacement[n - 2]);
    }

    #[test]
    fn hammer_mass_sweep_shows_impulse_time_jump() {
        let masses: Vec<f64> = (0..=16).map(|i| 0.03 + 0.0025 * i as f64).collect();
        let times: Vec<f64> = masses.iter().map(|&mh| simulate(&sweep_setup(mh)).unwrap().impulse_time).collect();
        let at = |mh: f64| times[masses.iter().position(|m| (m - mh).abs() < 1e-9).unwrap()];
        assert!(at(0.03) < 0.17e-3, "impulse(0.03) = {}", at(0.03));
        assert!(at(0.07) > 0.22e-3, "impulse(0.07) = {}", at(0.07));
        // The largest jump between neighbouring masses lies between 0.04 and 0.06 kg.
        let (i, jump) = times.windows(2).map(|w| w[1] - w[0]).enumerate().max_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
        assert!(jump > 0.05e-3, "largest jump {jump}");
        assert!(masses[i] >= 0.04 && masses[i + 1] <= 0.06, "jump at {}", masses[i]);
        // Longer contact narrows the excited bandwidth.
        let bw_light = simulate(&sweep_setup(0.03)).unwrap().excited_bandwidth;
        let bw_heavy = simulate(&sweep_setup(0.07)).unwrap().excited_bandwidth;
        assert!(bw_heavy < bw_light);
    }

    #[test]
    fn table_2_1_targets_run() {
        let t1 = table_2_1_target(Table21Target::Target1);
        let t2 = table_2_1_target(Table21Target::Target2);
        assert_eq!(t1.modes.len(), 10);
        assert_eq!(t2.modes.len(), 10);
        let mkc = |m: &Mode| [m.modal_mass, m.stiffness(), m.damping()];
        let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).all(|(x, y)| (x / y - 1.0).abs() < 1e-14);
        assert!(close(mkc(&t1.modes[3]), [125.99, 813.04e6, 27.07e3]), "{:?}", t1.modes[3]);
        assert!(close(mkc(&t2.modes[9]), [0.54, 1488.68e6, 0.99e3]), "{:?}", t2.modes[9]);
        // Lowest natural frequencies: mode 6 of target 1 (332 Hz), mode 5 of target 2 (608 Hz).
        for (target, lowest) in [(t1, 5), (t2, 4)] {
            let f_low = target.modes[lowest].freq_hz;
            let mut previous: Option<(f64, f64)> = None;
            for mh in [0.001, 0.01, 0.1] {
                let mut s = ImpactSetup::new(Hammer { mass: mh, stiffness: 100.0, damping: 0.0 }, target.clone());
                s.noise = Some(SensorNoise { std_dev: 25.0e-9, seed: 7 });
                let r = simulate(&s).unwrap();
                assert!((r.response_frequency - f_low).abs() < 1e-9);
                assert!(r.impulse_time > 0.0 && r.impulse_time < 1.0e-3, "{}", r.impulse_time);
                assert!(r.excited_bandwidth.is_finite() && r.excited_bandwidth > 0.0);
                assert!(r.response_magnitude.is_finite() && r.response_magnitude > 0.0);
                assert!(r.target_displacement.iter().all(|x| x.is_finite()));
                // A heavier hammer stays longer in contact and excites a narrower band.
                if let Some((t_prev, bw_prev)) = previous {
                    assert!(r.impulse_time > t_prev, "{mh} kg: impulse {} s not above {t_prev} s", r.impulse_time);
                    assert!(
                        r.excited_bandwidth < bw_prev,
                        "{mh} kg: band {} Hz not below {bw_prev} Hz",
                        r.excited_bandwidth
                    );
                }
                previous = Some((r.impulse_time, r.excited_bandwidth));
            }
        }
    }

    #[test]
    fn noise_is_deterministic_per_seed() {
        let mut s = ImpactSetup::dissertation_example();
        s.duration = 2.0e-3;
        s.noise = Some(SensorNoise { std_dev: 25.0e-9, seed: 42 });
        let a = simulate(&s).unwrap();
        let b = simulate(&s).unwrap();
        let bits = |r: &ImpactResult| r.target_displacement.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a), bits(&b));
        s.noise = Some(SensorNoise { std_dev: 25.0e-9, seed: 43 });
        let c = simulate(&s).unwrap();
        assert_ne!(bits(&a), bits(&c));
        // The noise has the requested spread and leaves the force untouched.
        s.noise = None;
        let clean = simulate(&s).unwrap();
        let diff: Vec<f64> = a.target_displacement.iter().zip(&clean.target_displacement).map(|(x, y)| x - y).collect();
        let sd = (diff.iter().map(|d| d * d).sum::<f64>() / diff.len() as f64).sqrt();
        assert!((sd / 25.0e-9 - 1.0).abs() < 0.15, "noise sd {sd}");
        assert_eq!(a.force, clean.force);
    }

    #[test]
    fn exact_free_flight_matches_fine_stepping() {
        // Single hit, and a stiff hammer that swings back for a second hit.
        let mut single = ImpactSetup::dissertation_example();
        single.duration = 3.0e-3;
        let m = single.target.modes[0];
        single.target.modes[0] = Mode::from_mass_stiffness_damping(m.modal_mass, m.stiffness(), 20.0);
        let mut double = sweep_setup(0.03);
        double.hammer.stiffness = 3.0e5;
        double.release_position = 0.2e-3;
        double.contact_position = -0.1e-3;
        double.duration = 3.0e-3;
        for (case, setup) in [("single", single), ("double", double)] {
            let mut fine = setup.clone();
            fine.exact_free_flight = false;
            let a = simulate(&setup).unwrap();
            let b = simulate(&fine).unwrap();
            assert!(a.fine_steps < b.fine_steps, "{case}");
            assert_eq!(a.contact_count(), b.contact_count(), "{case}");
            if case == "double" {
                assert!(a.contact_count() >= 2, "expected a second hit");
            }
            for (ca, cb) in a.contacts.iter().zip(&b.contacts) {
                assert!((ca.start - cb.start).abs() < 1e-7, "{case}: {} vs {}", ca.start, cb.start);
                assert!((ca.end - cb.end).abs() < 1e-7, "{case}");
                assert!((ca.peak_force / cb.peak_force - 1.0).abs() < 1e-3, "{case}");
            }
            let scale = b.target_displacement.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            for (x, y) in a.target_displacement.iter().zip(&b.target_displacement) {
                assert!((x - y).abs() < 1e-3 * scale, "{case}: {x} vs {y}");
            }
            assert!((a.impulse_time - b.impulse_time).abs() < 1e-7);
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let base = ImpactSetup::dissertation_example();
        let mut cases: Vec<ImpactSetup> = Vec::new();
        let mut s = base.clone();
        s.hammer.mass = 0.0;
        cases.push(s);
        let mut s = base.clone();
        s.target.modes[0].modal_mass = -1.0;
        cases.push(s);
        let mut s = base.clone();
        s.dt = 0.0;
        cases.push(s);
        let mut s = base.clone();
        s.dt = f64::NAN;
        cases.push(s);
        let mut s = base.clone();
        s.hammer.stiffness = f64::NAN;
        cases.push(s);
        let mut s = base.clone();
        s.contact.restitution = 1.5;
        cases.push(s);
        let mut s = base.clone();
        s.release_position = -5.0e-3;
        cases.push(s);
        let mut s = base.clone();
        s.sample_rate = f64::INFINITY;
        cases.push(s);
        let mut s = base.clone();
        s.target.modes.clear();
        cases.push(s);
        let mut s = base.clone();
        s.dt = 1.0e-4; // coarser than the 1.6 kHz target allows
        s.sample_rate = 1.0e3;
        cases.push(s);
        let mut s = base.clone();
        s.noise = Some(SensorNoise { std_dev: -1.0, seed: 0 });
        cases.push(s);
        for (i, s) in cases.iter().enumerate() {
            assert!(
                matches!(simulate(s), Err(ImpactError::InvalidParameter { .. } | ImpactError::EmptyTarget)),
                "case {i}"
            );
        }
        // Released closer to the hammer rest than the contact point: never reaches it.
        let mut s = base.clone();
        s.release_position = 2.0e-3;
        assert_eq!(simulate(&s).unwrap_err(), ImpactError::NoContact);
        // A free hammer released from rest never moves.
        let mut s = base.clone();
        s.hammer.stiffness = 0.0;
        assert_eq!(simulate(&s).unwrap_err(), ImpactError::NoContact);
        // Step cap.
        let mut s = base.clone();
        s.duration = 20.0;
        assert!(matches!(simulate(&s), Err(ImpactError::TooManySteps { .. })));
        assert!(matches!(simulate_from_contact(&base, 0.0), Err(ImpactError::InvalidParameter { .. })));
    }

    #[test]
    fn from_contact_equals_full_run() {
        let s = ImpactSetup::dissertation_example();
        let full = simulate(&s).unwrap();
        let v = -first_contact(&s).unwrap().hammer_velocity;
        let part = simulate_from_contact(&s, v).unwrap();
        assert_eq!(full.force, part.force);
        assert_eq!(full.target_displacement, part.target_displacement);
        assert_eq!(part.release_to_contact, None);
    }
}
