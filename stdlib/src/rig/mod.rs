//! Virtual test rig: a rotating spindle under impact test (dissertation chapters 2–3),
//! producing the raw channels of one continuous recording together with the truth behind
//! them, so every processing step can be checked against known values.
//!
//! **Channels** (sampled at `sample_rate`, first sample at t = 0): `tach` (V, high with a
//! short low pulse per revolution whose falling edge is exactly θ = 0), `force` (N, the
//! hammer's force sensor), then one channel per probe angle named `a`, `b`, `c`, … in the
//! order given: displacement (m) for capacitance probes, or its exact time derivative
//! (m/s) for a laser vibrometer.
//!
//! **Probe model** (Eq. 3.4 as corrected in the equation notes). With the setup oriented
//! along the struck direction (probe A along it, at machine angle ψ = 0° for x, 90° for y),
//! probe i at angle φ_i from A reads
//! `m_i(t) = R(θ(t−τ) − φ_i) + x(t−τ) cos φ_i + y(t−τ) sin φ_i + noise`,
//! where, in that probe frame, `R(θ)` is the form error seen by probe A, and `x`, `y` are the
//! spindle error motions: synchronous harmonics of θ, a seeded random asynchronous motion
//! (white noise through a 2nd-order Butterworth low-pass, stationary from the first sample)
//! and optional sinusoids. `x` also holds the structural response `u(t)` to the impacts,
//! positive along the force, so `u/F` is the receptance. Machine-frame inputs map to the
//! probe frame by `x_p = X cos ψ + Y sin ψ`, `y_p = −X sin ψ + Y cos ψ`.
//!
//! **Sensor delay**: a phase slope Δθ is a pure delay `τ = −Δθ/2π` (Eq. 2.11) applied
//! exactly to the probe channels only: analytic parts are evaluated at `t − τ`, and the
//! modal states are propagated exactly to the delayed instants.
//!
//! **Structure**: the struck direction's modes at the nominal speed (speed laws of
//! [`RigMode`]). The response is the exact modal response to the noise-free sampled force
//! taken linear between samples (state-transition matrices of each mode), so the sampled
//! `U/F` equals the sampled-data receptance [`RigTruth::sampled_receptance`]; it departs
//! from the continuous receptance by the first-order-hold factor `sinc²(πf/fs)` (plus the
//! tiny aliased terms), under 0.1 % below 1.7 kHz and 0.8 % at 5 kHz at 100 kHz.
//!
//! **Impacts**: impact k has its first contact near `k·impact_interval + impact_offset`,
//! with a seeded uniform jitter, on a grid [`IMPACT_SUBSAMPLES`] times finer than the
//! sampling. Its force is the Hertz hammer model of §2.1 against the struck modes, with a
//! seeded scatter of the release distance, sampled on the record's grid.
//!
//! **Faults**: an impact listed in `double_hits` gets a second hit made as the rebounding
//! hammer striking again: a second §2.1 impact (structure taken at rest for the contact
//! mechanics) with a seeded approach speed of 25–50 % of the first, starting 2–4 ms after
//! the first contact ends. The structural response follows the total force exactly. The
//! recorded force is clipped at ±`force_range` (flat-topped); the structure still feels
//! the true force. Noise is Gaussian per channel kind; ADC quantisation is optional.
//!
//! **Speed**: `Ω(t) = Ω0 (1 + δ Σ w_j sin(2π f_j t + φ_j))` with two seeded slow components
//! (0.05–0.5 Hz, weights summing to 1), and θ(t) its exact integral from a seeded start
//! angle.
//!
//! Random numbers come from separate seeded streams per purpose (plan, force noise, tach
//! noise, each probe's noise, each asynchronous direction), so changing one setting (the
//! delay, the sensor, the probe count) leaves the other signals bit-identical.

mod config;
mod kernels;
mod shaker;

pub use config::{
    Adc, CAPACITANCE_PHASE_SLOPE, Direction, HammerConfig, IMPACT_SPAN, IMPACT_SUBSAMPLES, MAX_DELAY, MAX_PROBES,
    MAX_SAMPLES, ModeAtSpeed, Noise, RigConfig, RigError, RigMode, SensorKind, TachConfig, Tone, Undulation,
    VIBROMETER_PHASE_SLOPE, delay_from_phase_slope, harmonic_slope, harmonic_sum, rpm,
};
pub use shaker::{ShakerConfig, ShakerError, ShakerRecording, shaker};

use crate::impact::{ImpactError, ImpactResult, simulate as impact_simulate, simulate_from_contact};
use kernels::{Chain, cholesky3, sincos_turns, wrap_turns};
use num_complex::Complex64;
use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use std::f64::consts::{PI, TAU};

/// Samples processed together in the probe loop (fits the L1 cache).
const BLOCK: usize = 256;

// Random streams.
const STREAM_PLAN: u64 = 1;
const STREAM_FORCE: u64 = 2;
const STREAM_TACH: u64 = 3;
const STREAM_ASYNC_X: u64 = 4;
const STREAM_ASYNC_Y: u64 = 5;
const STREAM_PROBE: u64 = 16;

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// An independent generator for one purpose of one run.
pub(crate) fn stream(seed: u64, purpose: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(splitmix(splitmix(seed).wrapping_add(purpose)))
}

#[inline(always)]
fn normal(rng: &mut Xoshiro256PlusPlus) -> f64 {
    StandardNormal.sample(rng)
}

#[inline(always)]
fn quantise(v: f64, lsb: f64) -> f64 {
    if lsb > 0.0 { (v / lsb).round() * lsb } else { v }
}

/// One slow component of the speed drift.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriftComponent {
    /// Share of the drift amplitude (the weights sum to 1).
    pub weight: f64,
    /// Frequency, Hz.
    pub freq_hz: f64,
    /// Phase, rad.
    pub phase: f64,
}

/// The spindle rotation: `Ω(t) = Ω0 (1 + δ Σ w_j sin(2π f_j t + φ_j))` and its exact
/// integral `θ(t)`, continuous for any t (also before the record and at delayed instants).
#[derive(Debug, Clone, PartialEq)]
pub struct Rotation {
    /// Nominal speed Ω0, rad/s.
    pub speed: f64,
    /// θ(0), rad, in [0, 2π).
    pub start_angle: f64,
    /// Relative drift amplitude δ.
    pub drift: f64,
    pub components: [DriftComponent; 2],
}

impl Rotation {
    fn draw(speed: f64, drift: f64, rng: &mut Xoshiro256PlusPlus) -> Rotation {
        let start_angle = TAU * rng.random::<f64>();
        let w: f64 = 0.3 + 0.4 * rng.random::<f64>();
        let mut comp = |weight: f64| DriftComponent {
            weight,
            freq_hz: 0.05 + 0.45 * rng.random::<f64>(),
            phase: TAU * rng.random::<f64>(),
        };
        let components = [comp(w), comp(1.0 - w)];
        Rotation { speed, start_angle, drift, components }
    }

    fn rev_rate(&self) -> f64 {
        self.speed / TAU
    }

    /// `∫(Ω/Ω0 − 1) dt` from 0 to t, s.
    fn drift_integral(&self, t: f64) -> f64 {
        self.components
            .iter()
            .map(|c| {
                let w = TAU * c.freq_hz;
                self.drift * c.weight * (c.phase.cos() - (w * t + c.phase).cos()) / w
            })
            .sum()
    }

    /// Revolutions turned since θ = 0 before the record: `θ(t)/2π`, unwrapped.
    pub fn revolutions(&self, t: f64) -> f64 {
        self.start_angle / TAU + self.rev_rate() * (t + self.drift_integral(t))
    }

    /// Spindle angle θ(t), rad, unwrapped.
    pub fn angle(&self, t: f64) -> f64 {
        TAU * self.revolutions(t)
    }

    /// Spindle speed Ω(t), rad/s.
    pub fn speed_at(&self, t: f64) -> f64 {
        let d: f64 = self.components.iter().map(|c| c.weight * (TAU * c.freq_hz * t + c.phase).sin()).sum();
        self.speed * (1.0 + self.drift * d)
    }

    /// The time at which θ = 2π·`revs` (Newton on the exact θ(t)); `None` when not turning.
    pub fn time_of(&self, revs: f64) -> Option<f64> {
        if self.speed <= 0.0 {
            return None;
        }
        let f = self.rev_rate();
        let mut t = (revs - self.start_angle / TAU) / f;
        for _ in 0..50 {
            let step = (self.revolutions(t) - revs) / (f * self.speed_at(t) / self.speed);
            t -= step;
            if step.abs() <= 1e-16 * t.abs().max(1e-3) {
                break;
            }
        }
        Some(t)
    }
}

/// What happened at one impact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImpactTruth {
    pub index: usize,
    /// First contact, s.
    pub time: f64,
    /// First sample at or after the first contact.
    pub sample: usize,
    /// One past the last sample with contact force from this impact (second hit included).
    pub end_sample: usize,
    /// Hammer speed at first contact, m/s.
    pub approach_speed: f64,
    /// Largest contact force of the continuous contact (both hits), N.
    pub peak_force: f64,
    /// Largest noise-free force sample, N.
    pub sampled_peak_force: f64,
    /// Separate contacts, second hit included.
    pub contacts: usize,
    /// More than one contact (a requested second hit, or a rebound of the model itself).
    pub double_hit: bool,
    /// First contact of the requested second hit, s.
    pub second_hit_time: Option<f64>,
    /// The recorded force reached the ADC range.
    pub saturated: bool,
}

/// The known values behind a recording.
#[derive(Debug, Clone, PartialEq)]
pub struct RigTruth {
    pub direction: Direction,
    pub sensor: SensorKind,
    /// Machine angle of probe A, rad.
    pub setup_angle: f64,
    pub rotation: Rotation,
    /// The struck direction's modes at the nominal speed.
    pub modes: Vec<ModeAtSpeed>,
    /// Form error seen by probe A, `R(θ)` of Eq. 3.4.
    pub form: Vec<Undulation>,
    /// Synchronous error motion along probe A, `x(θ)` of Eq. 3.4.
    pub sync_x: Vec<Undulation>,
    /// Synchronous error motion perpendicular to probe A (towards positive probe angles).
    pub sync_y: Vec<Undulation>,
    /// Probe angles from probe A, rad.
    pub probe_angles: Vec<f64>,
    /// Sensor delay of the probe channels, s.
    pub delay: f64,
    pub sample_rate: f64,
    /// Falling tach edges (θ = 0) inside the record, s.
    pub tach_edges: Vec<f64>,
    pub impacts: Vec<ImpactTruth>,
    /// Standard deviation of the white input samples of the asynchronous motion, m.
    pub async_input_std: f64,
}

impl RigTruth {
    /// Receptance of the struck direction at the nominal speed, `Σ 1/(k_j(1 − r_j² + 2iζ_j r_j))`, m/N.
    pub fn receptance(&self, freq_hz: f64) -> Complex64 {
        self.modes.iter().map(|m| m.receptance(freq_hz)).sum()
    }

    /// What the ratio of the DFTs of the sampled response and force equals for a response
    /// to the force taken linear between samples: `Σ_m H(f + m·fs) sinc²(π(f + m·fs)/fs)`.
    pub fn sampled_receptance(&self, freq_hz: f64) -> Complex64 {
        let fs = self.sample_rate;
        let mut sum = Complex64::new(0.0, 0.0);
        for m in -2000i32..=2000 {
            let f = freq_hz + m as f64 * fs;
            let x = PI * f / fs;
            let w = if x == 0.0 { 1.0 } else { (x.sin() / x).powi(2) };
            sum += self.receptance(f) * w;
        }
        sum
    }

    /// Form error `R(θ)` seen by probe A, m.
    pub fn form_error(&self, theta: f64) -> f64 {
        harmonic_sum(&self.form, theta)
    }

    /// Synchronous error motion `(x, y)` in the probe frame, m.
    pub fn sync_motion(&self, theta: f64) -> (f64, f64) {
        (harmonic_sum(&self.sync_x, theta), harmonic_sum(&self.sync_y, theta))
    }

    /// Noise- and response-free reading of probe `i` at spindle angle θ (Eq. 3.4), m.
    pub fn probe_sync_reading(&self, i: usize, theta: f64) -> f64 {
        let phi = self.probe_angles[i];
        let (x, y) = self.sync_motion(theta);
        self.form_error(theta - phi) + x * phi.cos() + y * phi.sin()
    }
}

/// One probe channel.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeChannel {
    /// `a`, `b`, `c`, …
    pub name: String,
    /// Angle from probe A, rad.
    pub angle: f64,
    pub samples: Vec<f64>,
}

/// A simulated recording and its truth.
#[derive(Debug, Clone, PartialEq)]
pub struct RigRecording {
    pub sample_rate: f64,
    /// Tachometer, V.
    pub tach: Vec<f64>,
    /// Hammer force, N.
    pub force: Vec<f64>,
    /// Probe channels in the order of the probe angles (m, or m/s for a vibrometer).
    pub probes: Vec<ProbeChannel>,
    pub truth: RigTruth,
}

impl RigRecording {
    pub fn len(&self) -> usize {
        self.force.len()
    }

    pub fn is_empty(&self) -> bool {
        self.force.is_empty()
    }

    /// A channel by name (`tach`, `force`, `a`, …).
    pub fn channel(&self, name: &str) -> Option<&[f64]> {
        match name {
            "tach" => Some(&self.tach),
            "force" => Some(&self.force),
            _ => self.probes.iter().find(|p| p.name == name).map(|p| p.samples.as_slice()),
        }
    }

    /// Time of sample `n`, s.
    pub fn time(&self, n: usize) -> f64 {
        n as f64 / self.sample_rate
    }
}

/// Name of probe channel `i`: `a`, `b`, … `z`.
pub fn probe_name(i: usize) -> String {
    char::from(b'a' + (i as u8 % 26)).to_string()
}

/// Simulates one run of the rig; the same configuration and seed give identical bits.
pub fn simulate(config: &RigConfig, seed: u64) -> Result<RigRecording, RigError> {
    config.validate()?;
    let fs = config.sample_rate;
    let n = config.samples()?;
    let mut plan = stream(seed, STREAM_PLAN);
    let rotation = Rotation::draw(config.speed, config.speed_drift, &mut plan);

    let (force_true, mut impacts) = impact_forces(config, n, &mut plan)?;
    let (tach, tach_edges) = tach_channel(config, &rotation, n, seed);

    // Force channel: noise, ADC range (clipped, flat-topped), quantisation.
    let mut rng = stream(seed, STREAM_FORCE);
    let range = config.force_range;
    let sigma = config.noise.force;
    let lsb = config.adc.force_lsb;
    let force: Vec<f64> =
        force_true.iter().map(|f| quantise((f + sigma * normal(&mut rng)).clamp(-range, range), lsb)).collect();
    for imp in &mut impacts {
        imp.saturated = force[imp.sample..imp.end_sample].iter().any(|f| f.abs() >= range);
    }

    let frame = ProbeFrame::new(config);
    let modes = config.modes_at_speed();
    let (probes, async_input_std) = probe_channels(config, &frame, &rotation, &modes, &force_true, n, seed);

    let truth = RigTruth {
        direction: config.direction,
        sensor: config.sensor,
        setup_angle: config.direction.setup_angle(),
        rotation,
        modes,
        form: frame.form,
        sync_x: frame.sync_x,
        sync_y: frame.sync_y,
        probe_angles: config.probe_angles.clone(),
        delay: config.delay(),
        sample_rate: fs,
        tach_edges,
        impacts,
        async_input_std,
    };
    Ok(RigRecording { sample_rate: fs, tach, force, probes, truth })
}

/// Runs the §2.1 model with a window long enough to hold the whole contact.
fn hit(setup: &mut crate::impact::ImpactSetup, approach: Option<f64>, index: usize) -> Result<ImpactResult, RigError> {
    let step = 1.0 / setup.sample_rate;
    loop {
        let r = match approach {
            None => impact_simulate(setup),
            Some(v) => simulate_from_contact(setup, v),
        }
        .map_err(|source| RigError::Impact { index, source })?;
        let open = r.contacts.last().is_some_and(|c| c.end >= setup.duration - 2.0 * step);
        if !open {
            return Ok(r);
        }
        if setup.duration >= 0.5 * IMPACT_SPAN {
            return Err(RigError::Impact {
                index,
                source: ImpactError::InvalidParameter {
                    name: "contact",
                    field: "duration",
                    value: setup.duration,
                    requirement: "the contact lasts longer than the time allowed for a pulse: stiffen the tip or lighten the hammer",
                },
            });
        }
        setup.duration *= 2.0;
    }
}

/// Adds a pulse sampled at `IMPACT_SUBSAMPLES × fs` starting at fine index `start` to the
/// record; returns the last record sample it touched with a non-zero value.
fn place(force: &mut [f64], pulse: &[f64], start: i64, peak: &mut f64) -> Option<usize> {
    let o = IMPACT_SUBSAMPLES as i64;
    let first = (o - start.rem_euclid(o)) % o;
    let mut last = None;
    let mut i = first;
    while (i as usize) < pulse.len() {
        let n = (start + i) / o;
        if n >= 0 && (n as usize) < force.len() {
            let v = pulse[i as usize];
            force[n as usize] += v;
            if v != 0.0 {
                last = Some(n as usize);
                *peak = peak.max(force[n as usize]);
            }
        }
        i += o;
    }
    last
}

/// The noise-free force record and the impact truths (saturation filled in later).
fn impact_forces(
    config: &RigConfig,
    n: usize,
    plan: &mut Xoshiro256PlusPlus,
) -> Result<(Vec<f64>, Vec<ImpactTruth>), RigError> {
    let mut force = vec![0.0; n];
    let mut out = Vec::with_capacity(config.impacts);
    if config.impacts == 0 {
        return Ok((force, out));
    }
    let fine_rate = config.sample_rate * IMPACT_SUBSAMPLES as f64;
    let base = config.impact_setup();
    let h = &config.hammer;
    for k in 0..config.impacts {
        // Every draw is made for every impact, so faults on one leave the others unchanged.
        let jitter = config.impact_jitter * (2.0 * plan.random::<f64>() - 1.0);
        let scatter = normal(plan).clamp(-3.0, 3.0);
        let gap = 2.0e-3 + 2.0e-3 * plan.random::<f64>();
        let rebound = 0.25 + 0.25 * plan.random::<f64>();

        let t_nominal = k as f64 * config.impact_interval + config.impact_offset + jitter;
        let start = (t_nominal * fine_rate).round() as i64;
        let mut setup = base.clone();
        setup.release_position = h.contact + (h.release - h.contact) * (1.0 + h.release_scatter * scatter);
        let first = hit(&mut setup, None, k)?;
        let mut peak_sample = 0.0f64;
        let mut last = place(&mut force, &first.force, start, &mut peak_sample);
        let approach_speed = first.contacts.first().map_or(0.0, |c| c.approach_velocity);
        let mut peak = first.peak_force;
        let mut contacts = first.contact_count();
        let mut second_hit_time = None;
        if config.double_hits.contains(&k) {
            let end = first.contacts.last().map_or(0.0, |c| c.end);
            let start2 = start + ((end + gap) * fine_rate).round() as i64;
            let mut setup2 = base.clone();
            let second = hit(&mut setup2, Some(rebound * approach_speed), k)?;
            if let Some(l) = place(&mut force, &second.force, start2, &mut peak_sample) {
                last = Some(last.map_or(l, |p| p.max(l)));
            }
            peak = peak.max(second.peak_force);
            contacts += second.contact_count();
            second_hit_time = Some(start2 as f64 / fine_rate);
        }
        let o = IMPACT_SUBSAMPLES as i64;
        let sample = ((start + o - 1).div_euclid(o)).max(0) as usize;
        out.push(ImpactTruth {
            index: k,
            time: start as f64 / fine_rate,
            sample: sample.min(n),
            end_sample: last.map_or(sample, |l| l + 1).min(n),
            approach_speed,
            peak_force: peak,
            sampled_peak_force: peak_sample,
            contacts,
            double_hit: contacts > 1,
            second_hit_time,
            saturated: false,
        });
    }
    Ok((force, out))
}

/// Tach voltage: a trapezoidal low pulse per revolution with edges centred on θ = 0 and
/// θ = pulse angle, plus noise and quantisation; also the falling-edge times in the record.
fn tach_channel(config: &RigConfig, rot: &Rotation, n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let tc = &config.tach;
    let fs = config.sample_rate;
    let mut v = vec![tc.high; n];
    let mut edges = Vec::new();
    let end = n as f64 / fs;
    if rot.speed > 0.0 {
        let half = 0.5 * tc.edge_time;
        let pulse = tc.pulse_angle / TAU;
        let first = rot.revolutions(-tc.edge_time).floor() as i64 - 1;
        let last = rot.revolutions(end + tc.edge_time).ceil() as i64 + 1;
        for m in first..=last {
            let (Some(tf), Some(tr)) = (rot.time_of(m as f64), rot.time_of(m as f64 + pulse)) else { continue };
            if (0.0..end).contains(&tf) {
                edges.push(tf);
            }
            if tr + half < 0.0 || tf - half > end {
                continue;
            }
            let lo = ((tf - half) * fs).ceil().max(0.0) as usize;
            let hi = (((tr + half) * fs).floor() as i64).min(n as i64 - 1);
            for (k, x) in v.iter_mut().enumerate().take((hi + 1).max(0) as usize).skip(lo) {
                let t = k as f64 / fs;
                let fall = ((t - tf) / tc.edge_time + 0.5).clamp(0.0, 1.0);
                let rise = ((tr - t) / tc.edge_time + 0.5).clamp(0.0, 1.0);
                *x = tc.high - (tc.high - tc.low) * fall.min(rise);
            }
        }
    }
    if config.noise.tach > 0.0 || config.adc.tach_lsb > 0.0 {
        let mut rng = stream(seed, STREAM_TACH);
        let s = config.noise.tach;
        for x in v.iter_mut() {
            *x = quantise(*x + s * normal(&mut rng), config.adc.tach_lsb);
        }
    }
    (v, edges)
}

/// Inputs expressed in the probe frame (probe A along the struck direction).
struct ProbeFrame {
    form: Vec<Undulation>,
    sync_x: Vec<Undulation>,
    sync_y: Vec<Undulation>,
    /// Tones with `direction` meaning the probe-frame axis.
    tones: Vec<Tone>,
    /// Probe-frame asynchronous axes from machine ones: `(source is y, sign)` for x_p and y_p.
    swap: bool,
}

impl ProbeFrame {
    fn new(c: &RigConfig) -> ProbeFrame {
        let psi = c.direction.setup_angle();
        let form =
            c.form.iter().map(|u| Undulation { phase: u.phase + u.upr as f64 * psi, ..*u }).filter(nonzero).collect();
        let flip = |u: &Undulation| Undulation { phase: u.phase + PI, ..*u };
        let (sync_x, sync_y): (Vec<Undulation>, Vec<Undulation>) = match c.direction {
            Direction::X => (c.sync_x.clone(), c.sync_y.clone()),
            Direction::Y => (c.sync_y.clone(), c.sync_x.iter().map(flip).collect()),
        };
        let tones = c
            .async_tones
            .iter()
            .filter(|t| t.amplitude != 0.0)
            .map(|t| match (c.direction, t.direction) {
                (Direction::X, _) => *t,
                (Direction::Y, Direction::Y) => Tone { direction: Direction::X, ..*t },
                (Direction::Y, Direction::X) => Tone { direction: Direction::Y, phase: t.phase + PI, ..*t },
            })
            .collect();
        ProbeFrame {
            form,
            sync_x: sync_x.into_iter().filter(nonzero).collect(),
            sync_y: sync_y.into_iter().filter(nonzero).collect(),
            tones,
            swap: c.direction == Direction::Y,
        }
    }
}

fn nonzero(u: &Undulation) -> bool {
    u.amplitude != 0.0
}

/// Per distinct harmonic order, the complex coefficient `E` of each probe such that the
/// probe's synchronous reading is `Σ_k Re(E_k e^{ikθ})`.
struct Harmonics {
    orders: Vec<u32>,
    /// `[order][probe]`.
    coef: Vec<Vec<Complex64>>,
}

impl Harmonics {
    fn new(frame: &ProbeFrame, angles: &[f64]) -> Harmonics {
        let mut orders: Vec<u32> = frame.form.iter().chain(&frame.sync_x).chain(&frame.sync_y).map(|u| u.upr).collect();
        orders.sort_unstable();
        orders.dedup();
        let mut coef = vec![vec![Complex64::new(0.0, 0.0); angles.len()]; orders.len()];
        let slot = |k: u32| orders.binary_search(&k).unwrap_or(0);
        for (p, &phi) in angles.iter().enumerate() {
            for u in &frame.form {
                let k = u.upr as f64;
                coef[slot(u.upr)][p] += Complex64::from_polar(u.amplitude, -(u.phase + k * phi));
            }
            for u in &frame.sync_x {
                coef[slot(u.upr)][p] += Complex64::from_polar(u.amplitude, -u.phase) * phi.cos();
            }
            for u in &frame.sync_y {
                coef[slot(u.upr)][p] += Complex64::from_polar(u.amplitude, -u.phase) * phi.sin();
            }
        }
        Harmonics { orders, coef }
    }
}

/// The seeded asynchronous random motion along one machine direction: white samples
/// through a 2nd-order Butterworth low-pass, started from its stationary distribution.
struct AsyncMotion {
    chain: Chain,
    rng: Xoshiro256PlusPlus,
    std: f64,
    w: f64,
}

impl AsyncMotion {
    fn new(config: &RigConfig, h: f64, span: f64, seed: u64, purpose: u64) -> Option<AsyncMotion> {
        if config.async_rms <= 0.0 {
            return None;
        }
        let w = TAU * config.async_bandwidth;
        let chain = Chain::new(&[(w, std::f64::consts::FRAC_1_SQRT_2, 1.0)], h, span);
        let p = chain.stationary_covariance();
        let std = config.async_rms / p[0][0].sqrt();
        let l = cholesky3(&p);
        let mut rng = stream(seed, purpose);
        let z = [normal(&mut rng), normal(&mut rng), normal(&mut rng)];
        let x: Vec<f64> = (0..3).map(|i| std * (0..3).map(|j| l[i][j] * z[j]).sum::<f64>()).collect();
        let mut m = AsyncMotion { chain, rng, std, w: x[2] };
        m.chain.set_state(0, x[0], x[1]);
        Some(m)
    }

    /// Output at the delayed instant after the current sample, then advance one sample.
    #[inline(always)]
    fn step(&mut self) -> (f64, f64) {
        let next = self.std * normal(&mut self.rng);
        let out = self.chain.step(self.w, next);
        self.w = next;
        out
    }
}

/// Probe channels (Eq. 3.4 with the delay), block by block.
fn probe_channels(
    config: &RigConfig,
    frame: &ProbeFrame,
    rot: &Rotation,
    modes: &[ModeAtSpeed],
    force: &[f64],
    n: usize,
    seed: u64,
) -> (Vec<ProbeChannel>, f64) {
    let fs = config.sample_rate;
    let h = 1.0 / fs;
    let tau = config.delay();
    let velocity = config.sensor == SensorKind::LaserVibrometer;
    let angles = &config.probe_angles;
    let np = angles.len();

    // τ = shift·h + ε, 0 ≤ ε < h; output n is the chain output at j = n − shift − 1,
    // taken `span = h − ε` after sample j.
    let mut shift = (tau * fs).floor() as i64;
    let mut eps = tau - shift as f64 * h;
    if eps >= h {
        shift += 1;
        eps -= h;
    }
    let eps = eps.max(0.0);
    let span = h - eps;
    let j_start = -((MAX_DELAY * fs).ceil() as i64) - 2;

    let mode_list: Vec<(f64, f64, f64)> =
        modes.iter().map(|m| (TAU * m.freq_hz, m.damping_ratio, m.stiffness)).collect();
    let mut structure = Chain::new(if config.impacts > 0 { &mode_list } else { &[] }, h, span);
    let mut async_x = AsyncMotion::new(config, h, span, seed, STREAM_ASYNC_X);
    let mut async_y = AsyncMotion::new(config, h, span, seed, STREAM_ASYNC_Y);
    let async_std = async_x.as_ref().map_or(0.0, |a| a.std);
    let f_at = |j: i64| if j >= 0 && (j as usize) < n { force[j as usize] } else { 0.0 };
    // Advance the chains to the first output index.
    let mut j = j_start;
    while j < -shift - 1 {
        if !structure.is_empty() {
            structure.step(f_at(j), f_at(j + 1));
        }
        for a in [&mut async_x, &mut async_y].into_iter().flatten() {
            a.step();
        }
        j += 1;
    }

    let harmonics = Harmonics::new(frame, angles);
    let nk = harmonics.orders.len();
    let mut outputs: Vec<Vec<f64>> = (0..np).map(|_| Vec::with_capacity(n)).collect();
    let mut noise: Vec<Xoshiro256PlusPlus> = (0..np).map(|p| stream(seed, STREAM_PROBE + p as u64)).collect();
    let (cos_p, sin_p): (Vec<f64>, Vec<f64>) = angles.iter().map(|a| (a.cos(), a.sin())).unzip();

    // Rotation in turns: revs(n) = r0 + a·n + f_rot·D(t'), t' = n h − τ.
    let f_rot = rot.speed / TAU;
    let r0 = rot.start_angle / TAU - f_rot * tau;
    let a_rev = f_rot * h;
    let drifting = rot.drift > 0.0 && rot.speed > 0.0;
    let drift: Vec<(f64, f64, f64, f64, f64)> = rot
        .components
        .iter()
        .map(|c| {
            let w = TAU * c.freq_hz;
            // (turns per sample, turns at n = 0, K = δ w_j/ω_j, cos φ_j, δ w_j)
            (
                c.freq_hz * h,
                c.phase / TAU - c.freq_hz * tau,
                rot.drift * c.weight / w,
                c.phase.cos(),
                rot.drift * c.weight,
            )
        })
        .collect();

    let mut rev = [0.0; BLOCK];
    let mut omega = [0.0; BLOCK];
    let mut zc = [0.0; BLOCK];
    let mut zs = [0.0; BLOCK];
    let mut ck = [0.0; BLOCK];
    let mut sk = [0.0; BLOCK];
    let mut acc = vec![[0.0; BLOCK]; np];
    let mut xp = [0.0; BLOCK];
    let mut yp = [0.0; BLOCK];

    let mut n0 = 0;
    while n0 < n {
        let len = BLOCK.min(n - n0);
        // 1. Spindle angle (in turns) and speed at the delayed instants.
        for i in 0..len {
            let nn = (n0 + i) as f64;
            let mut d = 0.0;
            let mut rate = 1.0;
            if drifting {
                for &(per, at0, k, cphi, dw) in &drift {
                    let (s, c) = sincos_turns(at0 + per * nn);
                    d += k * (cphi - c);
                    rate += dw * s;
                }
            }
            let r = wrap_turns(r0 + a_rev * nn + f_rot * d);
            rev[i] = r;
            omega[i] = rot.speed * rate;
            let (s, c) = sincos_turns(r);
            zs[i] = s;
            zc[i] = c;
        }
        // 2. Synchronous part: Σ_k Re(E_k z^k) per probe (derivative for a vibrometer).
        for a in acc.iter_mut() {
            a[..len].fill(0.0);
        }
        let mut prev = 0u32;
        for (slot, &k) in harmonics.orders.iter().enumerate() {
            let gap = k - prev;
            if prev > 0 && gap <= 2 {
                for _ in 0..gap {
                    for i in 0..len {
                        let (c, s) = (ck[i] * zc[i] - sk[i] * zs[i], ck[i] * zs[i] + sk[i] * zc[i]);
                        ck[i] = c;
                        sk[i] = s;
                    }
                }
            } else if k == 1 {
                ck[..len].copy_from_slice(&zc[..len]);
                sk[..len].copy_from_slice(&zs[..len]);
            } else {
                let kf = k as f64;
                for i in 0..len {
                    let (s, c) = sincos_turns(kf * rev[i]);
                    ck[i] = c;
                    sk[i] = s;
                }
            }
            prev = k;
            for (p, a) in acc.iter_mut().enumerate() {
                let e = harmonics.coef[slot][p];
                if velocity {
                    // d/dt Re(E z^k) = Ω Re(ik E z^k).
                    let (er, ei) = (-kf64(k) * e.im, kf64(k) * e.re);
                    for i in 0..len {
                        a[i] += omega[i] * (er * ck[i] - ei * sk[i]);
                    }
                } else {
                    for i in 0..len {
                        a[i] += e.re * ck[i] - e.im * sk[i];
                    }
                }
            }
        }
        let _ = nk;
        // 3. Structural response, asynchronous motion and tones in the probe frame.
        for i in 0..len {
            let (mut x, mut y) = (0.0, 0.0);
            if !structure.is_empty() {
                let (q, v) = structure.step(f_at(j), f_at(j + 1));
                x += if velocity { v } else { q };
            }
            if let Some(m) = async_x.as_mut() {
                let (q, v) = m.step();
                let val = if velocity { v } else { q };
                if frame.swap {
                    y -= val;
                } else {
                    x += val;
                }
            }
            if let Some(m) = async_y.as_mut() {
                let (q, v) = m.step();
                let val = if velocity { v } else { q };
                if frame.swap {
                    x += val;
                } else {
                    y += val;
                }
            }
            j += 1;
            xp[i] = x;
            yp[i] = y;
        }
        for t in &frame.tones {
            let per = t.freq_hz * h;
            let at0 = -t.freq_hz * tau - t.phase / TAU;
            let target = if t.direction == Direction::X { &mut xp } else { &mut yp };
            for (i, v) in target.iter_mut().enumerate().take(len) {
                let (s, c) = sincos_turns(at0 + per * (n0 + i) as f64);
                *v += if velocity { -t.amplitude * TAU * t.freq_hz * s } else { t.amplitude * c };
            }
        }
        // 4. Combine, add noise, quantise.
        for p in 0..np {
            let (cp, sp) = (cos_p[p], sin_p[p]);
            let a = &acc[p];
            let out = &mut outputs[p];
            let rng = &mut noise[p];
            let sigma = config.noise.probe;
            let lsb = config.adc.probe_lsb;
            for i in 0..len {
                let mut v = a[i] + cp * xp[i] + sp * yp[i];
                if sigma > 0.0 {
                    v += sigma * normal(rng);
                }
                out.push(quantise(v, lsb));
            }
        }
        n0 += len;
    }
    let probes = outputs
        .into_iter()
        .enumerate()
        .map(|(i, samples)| ProbeChannel { name: probe_name(i), angle: angles[i], samples })
        .collect();
    (probes, async_std)
}

#[inline(always)]
fn kf64(k: u32) -> f64 {
    k as f64
}

#[cfg(test)]
mod tests;
