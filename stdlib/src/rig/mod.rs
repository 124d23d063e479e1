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
//! seeded scatter of the release distance, sampled on the record's grid. Each hit is
//! modelled for [`PULSE_WINDOW`] after first contact (its contact must end within it;
//! a later swing of the hammer back onto the artifact is not modelled: the hammer is
//! caught, as in §2.2).
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
//! delay, the sensor, the probe count) leaves the other signals bit-identical. The bulk
//! normals are Box–Muller on four interleaved xoshiro256++ generators; the hot loops are
//! also compiled for AVX2 and chosen at run time, with bit-identical results.

mod config;
mod kernels;
mod shaker;

pub use config::{
    Adc, CAPACITANCE_PHASE_SLOPE, Direction, HammerConfig, IMPACT_SPAN, IMPACT_SUBSAMPLES, MAX_DELAY, MAX_PROBES,
    MAX_SAMPLES, Noise, PULSE_WINDOW, RigConfig, RigError, RigMode, SensorKind, TachConfig, Tone, Undulation,
    VIBROMETER_PHASE_SLOPE, delay_from_phase_slope, harmonic_slope, harmonic_sum, rpm,
};
pub use shaker::{ShakerConfig, ShakerError, ShakerRecording, shaker};

use crate::impact::{ImpactError, ImpactResult, simulate_records};
use kernels::{BLOCK, Chain, NormalSource, cholesky3, sincos_turns, wrap_turns};
use num_complex::Complex64;
use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use spindlelab_domain::Mode;
use std::f64::consts::{PI, TAU};

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

/// A fast normal source for one bulk purpose of one run.
pub(crate) fn normals(seed: u64, purpose: u64) -> NormalSource {
    NormalSource::new(splitmix(splitmix(seed).wrapping_add(purpose)))
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
    pub modes: Vec<Mode>,
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
        self.modes.iter().map(|m| m.receptance(TAU * freq_hz)).sum()
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

    let (segments, mut impacts) = impact_forces(config, n, &mut plan)?;
    let (tach, tach_edges) = tach_channel(config, &rotation, n, seed);

    // Force channel: noise, the impacts, ADC range (clipped, flat-topped), quantisation.
    let mut force = vec![0.0; n];
    if config.noise.force > 0.0 {
        let mut rng = normals(seed, STREAM_FORCE);
        let sigma = config.noise.force;
        for f in force.iter_mut() {
            *f = sigma * rng.next();
        }
    }
    for seg in &segments {
        for (f, v) in force[seg.start..seg.end()].iter_mut().zip(&seg.values) {
            *f += v;
        }
    }
    let range = config.force_range;
    if range.is_finite() || config.adc.force_lsb > 0.0 {
        for f in force.iter_mut() {
            *f = quantise(f.clamp(-range, range), config.adc.force_lsb);
        }
    }
    for imp in &mut impacts {
        imp.saturated = force[imp.sample..imp.end_sample].iter().any(|f| f.abs() >= range);
    }

    let frame = ProbeFrame::new(config);
    let modes = config.modes_at_speed();
    let (probes, async_input_std) = probe_channels(config, &frame, &rotation, &modes, &segments, n, seed);

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

/// Runs the §2.1 model over its pulse window; a contact still open at the window's end is
/// an error (such a hammer cannot be told apart from a press).
fn hit(setup: &crate::impact::ImpactSetup, approach: Option<f64>, index: usize) -> Result<ImpactResult, RigError> {
    let r = simulate_records(setup, approach).map_err(|source| RigError::Impact { index, source })?;
    let step = 1.0 / setup.sample_rate;
    if r.contacts.last().is_some_and(|c| c.end >= setup.duration - 2.0 * step) {
        return Err(RigError::Impact {
            index,
            source: ImpactError::InvalidParameter {
                name: "contact",
                field: "duration",
                value: setup.duration,
                requirement: "is shorter than the contact: stiffen the tip or lighten the hammer",
            },
        });
    }
    Ok(r)
}

/// The noise-free force of one impact on the record's samples `start..start + values.len()`.
#[derive(Debug, Clone)]
struct Segment {
    start: usize,
    values: Vec<f64>,
}

impl Segment {
    fn end(&self) -> usize {
        self.start + self.values.len()
    }
}

/// Samples a pulse given at `IMPACT_SUBSAMPLES × fs` from fine index `start` onto the
/// record's grid: `(record sample, value)` pairs.
fn on_grid(pulse: &[f64], start: i64) -> impl Iterator<Item = (i64, f64)> + '_ {
    let o = IMPACT_SUBSAMPLES as i64;
    let first = (o - start.rem_euclid(o)) % o;
    (first..pulse.len() as i64).step_by(o as usize).map(move |i| ((start + i) / o, pulse[i as usize]))
}

/// The noise-free force of every impact (one segment each) and the impact truths
/// (saturation filled in later).
fn impact_forces(
    config: &RigConfig,
    n: usize,
    plan: &mut Xoshiro256PlusPlus,
) -> Result<(Vec<Segment>, Vec<ImpactTruth>), RigError> {
    let mut segments = Vec::with_capacity(config.impacts);
    let mut out = Vec::with_capacity(config.impacts);
    if config.impacts == 0 {
        return Ok((segments, out));
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
        let first = hit(&setup, None, k)?;
        let approach_speed = first.contacts.first().map_or(0.0, |c| c.approach_velocity);
        let mut pulses = vec![(start, first.force)];
        let mut peak = first.peak_force;
        let mut contacts = first.contacts.len();
        let mut second_hit_time = None;
        if config.double_hits.contains(&k) {
            let end = first.contacts.last().map_or(0.0, |c| c.end);
            let start2 = start + ((end + gap) * fine_rate).round() as i64;
            let second = hit(&base, Some(rebound * approach_speed), k)?;
            peak = peak.max(second.peak_force);
            contacts += second.contacts.len();
            second_hit_time = Some(start2 as f64 / fine_rate);
            pulses.push((start2, second.force));
        }
        // One segment from the first sample at or after contact to the last non-zero one.
        let o = IMPACT_SUBSAMPLES as i64;
        let first_sample = start.div_euclid(o) + i64::from(start.rem_euclid(o) != 0);
        let last = pulses
            .iter()
            .flat_map(|(s, p)| on_grid(p, *s))
            .filter(|(_, v)| *v != 0.0)
            .map(|(m, _)| m)
            .max()
            .unwrap_or(first_sample - 1);
        let lo = first_sample.clamp(0, n as i64) as usize;
        let hi = (last + 1).clamp(lo as i64, n as i64) as usize;
        let mut values = vec![0.0; hi - lo];
        for (s, p) in &pulses {
            for (m, v) in on_grid(p, *s) {
                if m >= lo as i64 && m < hi as i64 {
                    values[m as usize - lo] += v;
                }
            }
        }
        let sampled_peak_force = values.iter().copied().fold(0.0, f64::max);
        out.push(ImpactTruth {
            index: k,
            time: start as f64 / fine_rate,
            sample: lo,
            end_sample: hi,
            approach_speed,
            peak_force: peak,
            sampled_peak_force,
            contacts,
            double_hit: contacts > 1,
            second_hit_time,
            saturated: false,
        });
        segments.push(Segment { start: lo, values });
    }
    Ok((segments, out))
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
        let mut rng = normals(seed, STREAM_TACH);
        let s = config.noise.tach;
        for x in v.iter_mut() {
            *x = quantise(*x + s * rng.next(), config.adc.tach_lsb);
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

/// Per distinct harmonic order, the coefficient `E` of each probe such that the probe's
/// synchronous reading is `Σ_k Re(E_k e^{ikθ})` (for a vibrometer, `D_k = ik·E_k`, to be
/// multiplied by Ω), and how each power `e^{ikθ}` is obtained from earlier ones.
struct Harmonics {
    orders: Vec<u32>,
    /// `[order][probe]`: `(Re, Im)` of `E_k` (or `D_k`).
    coef: Vec<Vec<(f64, f64)>>,
    plan: Vec<Power>,
}

/// How `e^{ikθ}` of one order is computed: `e^{iθ}` itself, the product of two earlier
/// powers (`None` is `e^{iθ}`), or directly from the angle.
#[derive(Debug, Clone, Copy)]
enum Power {
    Base,
    Product(Option<usize>, Option<usize>),
    Direct,
}

impl Harmonics {
    fn new(frame: &ProbeFrame, angles: &[f64], velocity: bool) -> Harmonics {
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
        let coef = coef
            .iter()
            .zip(&orders)
            .map(|(row, &k)| {
                row.iter()
                    .map(|e| {
                        // d/dt Re(E e^{ikθ}) = Ω Re(ik E e^{ikθ}).
                        let e = if velocity { Complex64::new(0.0, k as f64) * e } else { *e };
                        (e.re, e.im)
                    })
                    .collect()
            })
            .collect();
        let mut plan = Vec::with_capacity(orders.len());
        for (s, &k) in orders.iter().enumerate() {
            // Sources: e^{iθ} (order 1) and every earlier slot.
            let known = |o: u32| -> Option<Option<usize>> {
                if o == 1 { Some(None) } else { orders[..s].binary_search(&o).ok().map(Some) }
            };
            let step = if k == 1 {
                Power::Base
            } else {
                (1..=k / 2).rev().find_map(|a| Some(Power::Product(known(a)?, known(k - a)?))).unwrap_or(Power::Direct)
            };
            plan.push(step);
        }
        Harmonics { orders, coef, plan }
    }
}

/// The seeded asynchronous random motion along one machine direction: white samples
/// through a 2nd-order Butterworth low-pass, started from its stationary distribution.
struct AsyncMotion {
    chain: Chain,
    rng: NormalSource,
    std: f64,
    w: f64,
}

impl AsyncMotion {
    fn new(config: &RigConfig, h: f64, span: f64, seed: u64, purpose: u64) -> Option<AsyncMotion> {
        if config.async_rms <= 0.0 {
            return None;
        }
        let w = TAU * config.async_bandwidth;
        let velocity = config.sensor == SensorKind::LaserVibrometer;
        let chain = Chain::new(&[(w, std::f64::consts::FRAC_1_SQRT_2, 1.0)], h, span, velocity);
        let p = chain.stationary_covariance();
        let std = config.async_rms / p[0][0].sqrt();
        let l = cholesky3(&p);
        let mut rng = normals(seed, purpose);
        let z = [rng.next(), rng.next(), rng.next()];
        let x: Vec<f64> = (0..3).map(|i| std * (0..3).map(|j| l[i][j] * z[j]).sum::<f64>()).collect();
        let mut m = AsyncMotion { chain, rng, std, w: x[2] };
        m.chain.set_state(0, x[0], x[1]);
        Some(m)
    }

    /// Output at the delayed instant after the current sample, then advance one sample.
    #[inline(always)]
    fn step(&mut self) -> f64 {
        let next = self.std * self.rng.next();
        let out = self.chain.step(self.w, next);
        self.w = next;
        out
    }
}

/// `e^{2πi·per·i}` for `i` in `0..BLOCK`: the in-block rotation of a fixed-frequency phasor.
struct PhasorTable {
    c: [f64; BLOCK],
    s: [f64; BLOCK],
}

impl PhasorTable {
    fn new(per: f64) -> PhasorTable {
        let mut t = PhasorTable { c: [0.0; BLOCK], s: [0.0; BLOCK] };
        for i in 0..BLOCK {
            let (s, c) = sincos_turns(per * i as f64);
            t.c[i] = c;
            t.s[i] = s;
        }
        t
    }
}

/// A fixed-frequency term evaluated per block as an exact phasor at the block start times
/// the in-block rotation: `(sin, cos)(2π(at0 + per·n))`.
struct Periodic {
    per: f64,
    at0: f64,
    table: PhasorTable,
}

impl Periodic {
    fn new(per: f64, at0: f64) -> Periodic {
        Periodic { per, at0, table: PhasorTable::new(per) }
    }

    /// Phasor at the block start `n0`.
    #[inline(always)]
    fn start(&self, n0: f64) -> (f64, f64) {
        sincos_turns(self.at0 + self.per * n0)
    }
}

/// Probe-channel synthesis (Eq. 3.4 with the delay), block by block.
struct ProbeSynth<'a> {
    velocity: bool,
    n: usize,
    speed: f64,
    f_rot: f64,
    r0: f64,
    a_rev: f64,
    /// Drift components: phasor, `K = δw/ω`, `cos φ`, `δw`.
    drift: Vec<(Periodic, f64, f64, f64)>,
    harmonics: Harmonics,
    /// Tones: phasor, amplitude (or its derivative factor), along probe-frame x.
    tones: Vec<(Periodic, f64, bool)>,
    structure: Chain,
    async_x: Option<AsyncMotion>,
    async_y: Option<AsyncMotion>,
    swap: bool,
    force: &'a [Segment],
    cursor: usize,
    j: i64,
    cos_p: Vec<f64>,
    sin_p: Vec<f64>,
    sigma: f64,
    lsb: f64,
    noise: Vec<NormalSource>,
    rev: [f64; BLOCK],
    omega: [f64; BLOCK],
    d: [f64; BLOCK],
    zc: [f64; BLOCK],
    zs: [f64; BLOCK],
    pc: Vec<[f64; BLOCK]>,
    ps: Vec<[f64; BLOCK]>,
    acc: Vec<[f64; BLOCK]>,
    xp: [f64; BLOCK],
    yp: [f64; BLOCK],
}

impl<'a> ProbeSynth<'a> {
    #[allow(clippy::too_many_arguments)]
    fn new(
        config: &RigConfig,
        frame: &ProbeFrame,
        rot: &Rotation,
        modes: &[Mode],
        force: &'a [Segment],
        n: usize,
        seed: u64,
    ) -> ProbeSynth<'a> {
        let fs = config.sample_rate;
        let h = 1.0 / fs;
        let tau = config.delay();
        let velocity = config.sensor == SensorKind::LaserVibrometer;
        let angles = &config.probe_angles;

        // τ = shift·h + ε, 0 ≤ ε < h; output n is the chain output at j = n − shift − 1,
        // taken `span = h − ε` after sample j.
        let mut shift = (tau * fs).floor() as i64;
        let mut eps = tau - shift as f64 * h;
        if eps >= h {
            shift += 1;
            eps -= h;
        }
        let span = h - eps.max(0.0);
        let j_start = -((MAX_DELAY * fs).ceil() as i64) - 2;

        let mode_list: Vec<(f64, f64, f64)> =
            modes.iter().map(|m| (m.omega(), m.damping_ratio, m.stiffness())).collect();
        let structure = Chain::new(if config.impacts > 0 { &mode_list } else { &[] }, h, span, velocity);
        let async_x = AsyncMotion::new(config, h, span, seed, STREAM_ASYNC_X);
        let async_y = AsyncMotion::new(config, h, span, seed, STREAM_ASYNC_Y);

        // Rotation in turns: revs(n) = r0 + a·n + f_rot·D(t'), t' = n h − τ.
        let f_rot = rot.speed / TAU;
        let drift = if rot.drift > 0.0 && rot.speed > 0.0 {
            rot.components
                .iter()
                .map(|c| {
                    let w = TAU * c.freq_hz;
                    let p = Periodic::new(c.freq_hz * h, c.phase / TAU - c.freq_hz * tau);
                    (p, rot.drift * c.weight / w, c.phase.cos(), rot.drift * c.weight)
                })
                .collect()
        } else {
            Vec::new()
        };
        let tones = frame
            .tones
            .iter()
            .map(|t| {
                let p = Periodic::new(t.freq_hz * h, -t.freq_hz * tau - t.phase / TAU);
                let scale = if velocity { -t.amplitude * TAU * t.freq_hz } else { t.amplitude };
                (p, scale, t.direction == Direction::X)
            })
            .collect();
        let harmonics = Harmonics::new(frame, angles, velocity);
        let nk = harmonics.orders.len();
        let np = angles.len();
        let mut synth = ProbeSynth {
            velocity,
            n,
            speed: rot.speed,
            f_rot,
            r0: rot.start_angle / TAU - f_rot * tau,
            a_rev: f_rot * h,
            drift,
            harmonics,
            tones,
            structure,
            async_x,
            async_y,
            swap: frame.swap,
            force,
            cursor: 0,
            j: j_start,
            cos_p: angles.iter().map(|a| a.cos()).collect(),
            sin_p: angles.iter().map(|a| a.sin()).collect(),
            sigma: config.noise.probe,
            lsb: config.adc.probe_lsb,
            noise: (0..np).map(|p| normals(seed, STREAM_PROBE + p as u64)).collect(),
            rev: [0.0; BLOCK],
            omega: [0.0; BLOCK],
            d: [0.0; BLOCK],
            zc: [0.0; BLOCK],
            zs: [0.0; BLOCK],
            pc: vec![[0.0; BLOCK]; nk],
            ps: vec![[0.0; BLOCK]; nk],
            acc: vec![[0.0; BLOCK]; np],
            xp: [0.0; BLOCK],
            yp: [0.0; BLOCK],
        };
        // Advance the chains to the first output index.
        while synth.j < -shift - 1 {
            synth.chain_step();
        }
        synth
    }

    /// The noise-free force at sample `j`; calls come with non-decreasing `j`.
    #[inline(always)]
    fn force_at(&mut self, j: i64) -> f64 {
        if j < 0 {
            return 0.0;
        }
        let j = j as usize;
        while self.cursor < self.force.len() && self.force[self.cursor].end() <= j {
            self.cursor += 1;
        }
        match self.force.get(self.cursor) {
            Some(seg) if j >= seg.start => seg.values[j - seg.start],
            _ => 0.0,
        }
    }

    /// Structural response plus asynchronous random motion in the probe frame at the next
    /// output instant; advances every chain one sample.
    #[inline(always)]
    fn chain_step(&mut self) -> (f64, f64) {
        let (mut x, mut y) = (0.0, 0.0);
        if !self.structure.is_empty() {
            let (f0, f1) = (self.force_at(self.j), self.force_at(self.j + 1));
            x += self.structure.step(f0, f1);
        }
        if let Some(m) = self.async_x.as_mut() {
            let v = m.step();
            if self.swap {
                y -= v;
            } else {
                x += v;
            }
        }
        if let Some(m) = self.async_y.as_mut() {
            let v = m.step();
            if self.swap {
                x += v;
            } else {
                y += v;
            }
        }
        self.j += 1;
        (x, y)
    }

    /// Whether the force is zero at every sample `j0..=j1`.
    #[inline(always)]
    fn force_free(&mut self, j0: i64, j1: i64) -> bool {
        let j0 = j0.max(0) as usize;
        while self.cursor < self.force.len() && self.force[self.cursor].end() <= j0 {
            self.cursor += 1;
        }
        self.force.get(self.cursor).is_none_or(|seg| (seg.start as i64) > j1)
    }

    /// The next `len` chain outputs into `xp`, `yp` (probe frame), one loop per chain.
    #[inline(always)]
    fn chains(&mut self, len: usize) {
        let j0 = self.j;
        if self.structure.is_empty() {
            self.xp[..len].fill(0.0);
        } else if len == BLOCK && self.force_free(j0, j0 + len as i64) {
            self.structure.free_block(&mut self.xp);
        } else {
            for i in 0..len {
                let j = j0 + i as i64;
                let (f0, f1) = (self.force_at(j), self.force_at(j + 1));
                self.xp[i] = self.structure.step(f0, f1);
            }
        }
        self.yp[..len].fill(0.0);
        let (to_x, to_y) = if self.swap { (&mut self.yp, &mut self.xp) } else { (&mut self.xp, &mut self.yp) };
        let sign = if self.swap { -1.0 } else { 1.0 };
        match (self.async_x.as_mut(), self.async_y.as_mut()) {
            // Both chains in one loop, so their recurrences overlap.
            (Some(mx), Some(my)) => {
                for i in 0..len {
                    to_x[i] += sign * mx.step();
                    to_y[i] += my.step();
                }
            }
            (Some(mx), None) => {
                for v in to_x[..len].iter_mut() {
                    *v += sign * mx.step();
                }
            }
            (None, Some(my)) => {
                for v in to_y[..len].iter_mut() {
                    *v += my.step();
                }
            }
            (None, None) => {}
        }
        self.j += len as i64;
    }

    /// Samples `n0..n0 + len` of every probe. The loops run over several block arrays in
    /// lockstep, indexed, so that they vectorise.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)]
    fn block(&mut self, n0: usize, len: usize, out: &mut [Vec<f64>]) {
        let nf = n0 as f64;
        // 1. Spindle angle (in turns) and speed at the delayed instants.
        let rate = &mut self.omega;
        rate[..len].fill(1.0);
        self.d[..len].fill(0.0);
        for (p, k, cphi, dw) in &self.drift {
            let (s0, c0) = p.start(nf);
            let (tc, ts) = (&p.table.c, &p.table.s);
            for i in 0..len {
                let c = c0 * tc[i] - s0 * ts[i];
                let s = s0 * tc[i] + c0 * ts[i];
                self.d[i] += k * (cphi - c);
                rate[i] += dw * s;
            }
        }
        for i in 0..len {
            let r = wrap_turns(self.r0 + self.a_rev * (nf + i as f64) + self.f_rot * self.d[i]);
            self.rev[i] = r;
            let (s, c) = sincos_turns(r);
            self.zs[i] = s;
            self.zc[i] = c;
            rate[i] *= self.speed;
        }
        // 2. Synchronous part: Σ_k Re(E_k e^{ikθ}) per probe.
        for a in self.acc.iter_mut() {
            a[..len].fill(0.0);
        }
        for slot in 0..self.harmonics.orders.len() {
            let (before, rest) = self.pc.split_at_mut(slot);
            let (sbefore, srest) = self.ps.split_at_mut(slot);
            let (pc, ps) = (&mut rest[0], &mut srest[0]);
            match self.harmonics.plan[slot] {
                Power::Base => {
                    pc[..len].copy_from_slice(&self.zc[..len]);
                    ps[..len].copy_from_slice(&self.zs[..len]);
                }
                Power::Product(a, b) => {
                    let (ac, as_) = a.map_or((&self.zc, &self.zs), |a| (&before[a], &sbefore[a]));
                    let (bc, bs) = b.map_or((&self.zc, &self.zs), |b| (&before[b], &sbefore[b]));
                    for i in 0..len {
                        pc[i] = ac[i] * bc[i] - as_[i] * bs[i];
                        ps[i] = ac[i] * bs[i] + as_[i] * bc[i];
                    }
                }
                Power::Direct => {
                    let k = self.harmonics.orders[slot] as f64;
                    for i in 0..len {
                        let (s, c) = sincos_turns(k * self.rev[i]);
                        pc[i] = c;
                        ps[i] = s;
                    }
                }
            }
            for (a, &(er, ei)) in self.acc.iter_mut().zip(&self.harmonics.coef[slot]) {
                for i in 0..len {
                    a[i] += er * pc[i] - ei * ps[i];
                }
            }
        }
        if self.velocity {
            for a in self.acc.iter_mut() {
                for i in 0..len {
                    a[i] *= rate[i];
                }
            }
        }
        // 3. Structural response and asynchronous motion, then tones, in the probe frame.
        self.chains(len);
        for (p, scale, along_x) in &self.tones {
            let (s0, c0) = p.start(nf);
            let (tc, ts) = (&p.table.c, &p.table.s);
            let target = if *along_x { &mut self.xp } else { &mut self.yp };
            if self.velocity {
                for i in 0..len {
                    target[i] += scale * (s0 * tc[i] + c0 * ts[i]);
                }
            } else {
                for i in 0..len {
                    target[i] += scale * (c0 * tc[i] - s0 * ts[i]);
                }
            }
        }
        // 4. Combine, add noise, quantise.
        for (p, o) in out.iter_mut().enumerate() {
            let (cp, sp) = (self.cos_p[p], self.sin_p[p]);
            let a = &self.acc[p];
            let start = o.len();
            o.extend((0..len).map(|i| a[i] + cp * self.xp[i] + sp * self.yp[i]));
            if self.sigma > 0.0 {
                let rng = &mut self.noise[p];
                for v in o[start..].iter_mut() {
                    *v += self.sigma * rng.next();
                }
            }
            if self.lsb > 0.0 {
                for v in o[start..].iter_mut() {
                    *v = quantise(*v, self.lsb);
                }
            }
        }
    }

    #[inline(always)]
    fn fill(&mut self, out: &mut [Vec<f64>]) {
        let mut n0 = 0;
        while n0 < self.n {
            let len = BLOCK.min(self.n - n0);
            self.block(n0, len, out);
            n0 += len;
        }
    }

    /// The same arithmetic compiled for 256-bit vectors (no fused multiply-add, so the
    /// results are bit-identical to [`ProbeSynth::fill`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn fill_avx2(&mut self, out: &mut [Vec<f64>]) {
        self.fill(out)
    }

    fn run(&mut self, out: &mut [Vec<f64>]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            unsafe { self.fill_avx2(out) };
            return;
        }
        self.fill(out)
    }
}

/// Probe channels (Eq. 3.4 with the delay) and the input level of the asynchronous motion.
fn probe_channels(
    config: &RigConfig,
    frame: &ProbeFrame,
    rot: &Rotation,
    modes: &[Mode],
    force: &[Segment],
    n: usize,
    seed: u64,
) -> (Vec<ProbeChannel>, f64) {
    let mut synth = ProbeSynth::new(config, frame, rot, modes, force, n, seed);
    let async_std = synth.async_x.as_ref().map_or(0.0, |a| a.std);
    let angles = &config.probe_angles;
    let mut outputs: Vec<Vec<f64>> = (0..angles.len()).map(|_| Vec::with_capacity(n)).collect();
    synth.run(&mut outputs);
    let probes = outputs
        .into_iter()
        .enumerate()
        .map(|(i, samples)| ProbeChannel { name: probe_name(i), angle: angles[i], samples })
        .collect();
    (probes, async_std)
}

#[cfg(test)]
mod tests;
