//! Probability of stability: the uncertainty of the tool-point dynamics and of the cutting coefficients carried
//! to the lobes, and updated by cutting trials (the Bayesian stability work of Schmitz's group: Karandikar,
//! Honeycutt, Schmitz & Smith, *Journal of Manufacturing Processes* 2014; Cornelius, Karandikar & Schmitz,
//! *Precision Engineering* 2021).
//!
//! The uncertain parameters `θ` are the specific cutting force `Ks`, the force angle `β` and, for a modal model,
//! each mode's natural frequency, damping ratio and modal stiffness, each with an independent Gaussian prior
//! truncated to its physical range (`f, k > 0`, `ζ ∈ [0, 1)`, `Ks > 0`, `β ∈ (0, π)`). A measured FRF instead
//! carries its own noise line by line: with ordinary coherence `γ²` from `n_d` averages, the normalised random
//! error of the gain and the standard deviation of the phase (rad) are both `ε = √(1 − γ²)/(|γ| √(2 n_d))`
//! (Bendat & Piersol, *Random Data*, 4th ed., Table 9.6), so a sample is `H (1 + ε z₁) e^{i ε z₂}` with
//! independent standard normal `z`.
//!
//! Monte Carlo: each sample's ZOA limit `b_s(n)` ([`zoa_lobes`]) over the speeds; the probability that a cut at
//! `(n, b)` is stable is the (weighted) fraction of samples with `b < b_s(n)`, and the `q` lobe is the
//! `q`-quantile of `b_s(n)`, so a cut below the 5 % lobe is stable with probability ≥ 95 %. Linearised: the
//! limit's standard deviation from central differences of `b(n; θ)` in each parameter, `P = Φ((b(n) − b)/σ_b)`.
//!
//! Trials update the map by importance sampling: sample `s` gets the weight `Π L(trial | b_s(n_trial))` with the
//! probit likelihood of [`TrialLikelihood`] (`P(chatter) = ε + (1 − 2ε) Φ(ln(b/b_lim)/σ)`, a Gaussian CDF of the
//! log margin) and, for a chattering trial with its chatter frequency, a Gaussian of the frequency's error with
//! standard deviation `σ_f`. The posterior map and lobes are the weighted ones; the effective sample size
//! `(Σw)²/Σw²` says how many prior samples carry the posterior.

use super::trials::{Outcome, Trial, TrialLikelihood, normal_cdf};
use super::zoa::{ToolPointFrf, ZoaOptions, zoa_lobes};
use super::{CuttingCoefficients, Milling, ModalModel, Mode, StabilityError};
use num_complex::Complex64;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use std::f64::consts::PI;

/// A Gaussian prior: mean and standard deviation (0: the parameter is known).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gaussian {
    /// Mean.
    pub mean: f64,
    /// Standard deviation, ≥ 0.
    pub sigma: f64,
}

impl Gaussian {
    /// A known value.
    pub fn fixed(mean: f64) -> Gaussian {
        Gaussian { mean, sigma: 0.0 }
    }
}

/// One tool-point mode with uncertain natural frequency (Hz), damping ratio and modal stiffness (N/m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModePrior {
    /// Natural frequency, Hz.
    pub freq_hz: Gaussian,
    /// Viscous damping ratio.
    pub damping_ratio: Gaussian,
    /// Modal stiffness `k = m (2πf)²`, N/m.
    pub stiffness: Gaussian,
}

/// Where the tool-point dynamics and their uncertainty come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Dynamics {
    /// Modes along `x` (feed) and `y` with uncertain parameters; their receptances are evaluated on `freqs_hz`.
    Modes {
        /// Modes along `x`.
        x: Vec<ModePrior>,
        /// Modes along `y`.
        y: Vec<ModePrior>,
        /// Frequency lines of the receptances, Hz ([`modal_grid`]).
        freqs_hz: Vec<f64>,
    },
    /// Measured receptances with the coherence of each line and the number of averages.
    Measured {
        /// The measured tool-point FRFs (no cross terms).
        frf: ToolPointFrf,
        /// Coherence of `frf.xx` per line, in `[0, 1]`.
        coherence_x: Vec<f64>,
        /// Coherence of `frf.yy` per line.
        coherence_y: Vec<f64>,
        /// Number of averages of the estimate, ≥ 1.
        averages: usize,
    },
}

/// A milling cut whose dynamics and cutting coefficients are uncertain.
#[derive(Debug, Clone, PartialEq)]
pub struct UncertainCut {
    /// The tool-point dynamics.
    pub dynamics: Dynamics,
    /// Teeth, immersion and direction; its coefficients are replaced by each sample's `Ks`, `β`.
    pub milling: Milling,
    /// Specific cutting force, N/m².
    pub ks: Gaussian,
    /// Force angle, rad.
    pub beta_rad: Gaussian,
}

/// What a parameter is, for its physical range and its unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Ks,
    Beta,
    Freq,
    Zeta,
    Stiffness,
}

impl Kind {
    fn physical(self, v: f64) -> bool {
        v.is_finite()
            && match self {
                Kind::Ks | Kind::Freq | Kind::Stiffness => v > 0.0,
                Kind::Beta => v > 0.0 && v < PI,
                Kind::Zeta => (0.0..1.0).contains(&v),
            }
    }

    fn unit(self) -> &'static str {
        match self {
            Kind::Ks => "N/m^2",
            Kind::Beta => "rad",
            Kind::Freq => "Hz",
            Kind::Zeta => "",
            Kind::Stiffness => "N/m",
        }
    }
}

/// One uncertain parameter: its name (`Ks`, `beta`, `x1.f`, `y2.stiffness` …), unit and prior.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    /// Name: `Ks`, `beta`, or `<direction><mode number>.<f|zeta|stiffness>`.
    pub name: String,
    /// SI unit.
    pub unit: &'static str,
    /// Prior.
    pub prior: Gaussian,
    kind: Kind,
}

impl UncertainCut {
    /// The parameters in the order of a sample's `θ`: `Ks`, `beta`, then each mode's `f`, `zeta`, `stiffness`,
    /// `x` modes first.
    pub fn parameters(&self) -> Vec<Parameter> {
        let p = |name: String, kind: Kind, prior: Gaussian| Parameter { name, unit: kind.unit(), prior, kind };
        let mut out = vec![p("Ks".into(), Kind::Ks, self.ks), p("beta".into(), Kind::Beta, self.beta_rad)];
        if let Dynamics::Modes { x, y, .. } = &self.dynamics {
            for (dir, modes) in [("x", x), ("y", y)] {
                for (i, m) in modes.iter().enumerate() {
                    out.push(p(format!("{dir}{}.f", i + 1), Kind::Freq, m.freq_hz));
                    out.push(p(format!("{dir}{}.zeta", i + 1), Kind::Zeta, m.damping_ratio));
                    out.push(p(format!("{dir}{}.stiffness", i + 1), Kind::Stiffness, m.stiffness));
                }
            }
        }
        out
    }

    /// Checks the priors (finite, σ ≥ 0, mean in the physical range), the measured FRF's coherence and averages.
    pub fn validate(&self) -> Result<(), StabilityError> {
        for p in self.parameters() {
            if !(p.prior.sigma.is_finite() && p.prior.sigma >= 0.0) {
                return Err(invalid("prior standard deviation", p.prior.sigma, "finite and ≥ 0"));
            }
            if !p.kind.physical(p.prior.mean) {
                return Err(StabilityError::InvalidParameter {
                    name: "prior mean",
                    value: p.prior.mean,
                    requirement: "in the parameter's physical range (f, k, Ks > 0; ζ in [0, 1); β in (0, π))",
                });
            }
        }
        match &self.dynamics {
            Dynamics::Modes { x, y, freqs_hz } => {
                if x.is_empty() && y.is_empty() {
                    return Err(StabilityError::InvalidMode {
                        direction: "x",
                        index: 0,
                        problem: "the model has no modes in x or y; give at least one".into(),
                    });
                }
                if freqs_hz.len() < 2 {
                    return Err(invalid("frequency lines", freqs_hz.len() as f64, "at least 2"));
                }
            }
            Dynamics::Measured { frf, coherence_x, coherence_y, averages } => {
                frf.validate()?;
                for (what, c) in [("coherence of frf_x", coherence_x), ("coherence of frf_y", coherence_y)] {
                    if c.len() != frf.freqs_hz.len() {
                        return Err(StabilityError::GridMismatch {
                            what,
                            detail: format!("{} values for {} lines", c.len(), frf.freqs_hz.len()),
                        });
                    }
                    if let Some(index) = c.iter().position(|g| !(g.is_finite() && (0.0..=1.0).contains(g))) {
                        return Err(StabilityError::NonFinite { what, index });
                    }
                }
                if *averages == 0 {
                    return Err(invalid("averages", 0.0, "at least 1"));
                }
            }
        }
        Ok(())
    }

    /// The nominal parameters (the prior means).
    pub fn nominal(&self) -> Vec<f64> {
        self.parameters().iter().map(|p| p.prior.mean).collect()
    }

    /// The ZOA limit and chatter frequency at `speeds_rpm` for parameters `theta`, with the measured FRF's
    /// noise drawn from `noise` when given (the nominal FRF otherwise).
    pub fn limit(
        &self,
        theta: &[f64],
        speeds_rpm: &[f64],
        noise: Option<&mut rand::rngs::Xoshiro256PlusPlus>,
    ) -> Result<(Vec<f64>, Vec<f64>), StabilityError> {
        let mut milling = self.milling.clone();
        milling.coefficients = CuttingCoefficients::from_ks_beta(theta[0], theta[1])?;
        let frf = match &self.dynamics {
            Dynamics::Modes { x, y, freqs_hz } => {
                let mode = |k: usize| Mode::from_stiffness(theta[k], theta[k + 1], theta[k + 2]);
                let xs = (0..x.len()).map(|i| mode(2 + 3 * i)).collect();
                let ys = (0..y.len()).map(|i| mode(2 + 3 * (x.len() + i))).collect();
                ModalModel::new(xs, ys)?.receptance(freqs_hz)?
            }
            Dynamics::Measured { frf, coherence_x, coherence_y, averages } => match noise {
                None => frf.clone(),
                Some(rng) => noisy(frf, coherence_x, coherence_y, *averages, rng)?,
            },
        };
        // Modal receptances are evaluated on a grid that resolves every mode; a measured FRF is resolved as
        // `stability.lobes` resolves it.
        let resolution_hz = match self.dynamics {
            Dynamics::Modes { .. } => None,
            Dynamics::Measured { .. } => Some(super::zoa::DEFAULT_RESOLUTION_HZ),
        };
        let options = ZoaOptions { lobes: None, speeds_rpm: speeds_rpm.to_vec(), keep_lobes: false, resolution_hz };
        let z = zoa_lobes(&frf, &milling, &options)?;
        Ok((z.limit.depth_m, z.limit.chatter_hz))
    }

    /// One draw of `θ` from the truncated Gaussian priors (a value outside the physical range is drawn again).
    fn draw(&self, params: &[Parameter], rng: &mut rand::rngs::Xoshiro256PlusPlus) -> Result<Vec<f64>, StabilityError> {
        params
            .iter()
            .map(|p| {
                if p.prior.sigma == 0.0 {
                    return Ok(p.prior.mean);
                }
                for _ in 0..MAX_REDRAWS {
                    let z: f64 = StandardNormal.sample(rng);
                    let v = p.prior.mean + p.prior.sigma * z;
                    if p.kind.physical(v) {
                        return Ok(v);
                    }
                }
                Err(StabilityError::InvalidParameter {
                    name: "prior standard deviation",
                    value: p.prior.sigma,
                    requirement: "small enough that the prior puts its mass in the physical range (redraws exhausted)",
                })
            })
            .collect()
    }
}

/// How often a draw outside the physical range is repeated before the prior is called unusable.
const MAX_REDRAWS: usize = 1000;

/// One draw of a measured FRF: each line `H (1 + ε z₁) e^{i ε z₂}` with `ε` = [`random_error`] of its coherence.
pub fn noisy(
    frf: &ToolPointFrf,
    coherence_x: &[f64],
    coherence_y: &[f64],
    averages: usize,
    rng: &mut rand::rngs::Xoshiro256PlusPlus,
) -> Result<ToolPointFrf, StabilityError> {
    let n_d = averages as f64;
    let mut perturb = |h: &[Complex64], c: &[f64]| -> Vec<Complex64> {
        h.iter()
            .zip(c)
            .map(|(&h, &g2)| {
                let e = random_error(g2, n_d);
                let (z1, z2): (f64, f64) = (StandardNormal.sample(rng), StandardNormal.sample(rng));
                h * (1.0 + e * z1) * Complex64::from_polar(1.0, e * z2)
            })
            .collect()
    };
    let xx = perturb(&frf.xx, coherence_x);
    let yy = perturb(&frf.yy, coherence_y);
    ToolPointFrf::new(frf.freqs_hz.clone(), xx, yy)
}

/// Bendat & Piersol's normalised random error of an FRF estimate's gain (and standard deviation of its phase,
/// rad) from coherence `γ²` and `n_d` averages; coherence is floored at 1e-3 so that a line of no coherence
/// gets a large but finite error.
pub fn random_error(coherence: f64, averages: f64) -> f64 {
    let g2 = coherence.clamp(1e-3, 1.0);
    ((1.0 - g2) / (2.0 * averages * g2)).sqrt()
}

fn invalid(name: &'static str, value: f64, requirement: &'static str) -> StabilityError {
    StabilityError::InvalidParameter { name, value, requirement }
}

/// Frequency lines on which uncertain modes are evaluated: from `Δf` to twice the highest natural frequency
/// (and at least the highest plus ten half-power bandwidths) with `Δf` a fifth of the narrowest half-power
/// half-width `ζ f` (between 0.05 and 2 Hz), at most 40,000 lines; the ZOA then resolves every lobe's minimum.
pub fn modal_grid(modes: &[ModePrior]) -> Vec<f64> {
    let f_max = modes.iter().map(|m| m.freq_hz.mean + 3.0 * m.freq_hz.sigma).fold(0.0, f64::max);
    let half = modes.iter().map(|m| (m.damping_ratio.mean * m.freq_hz.mean).max(1e-9)).fold(f64::INFINITY, f64::min);
    let zeta_max = modes.iter().map(|m| m.damping_ratio.mean).fold(0.0, f64::max);
    let top = (2.0 * f_max).max(f_max * (1.0 + 20.0 * zeta_max));
    let mut step = (half / 5.0).clamp(0.05, 2.0);
    if top / step > 40_000.0 {
        step = top / 40_000.0;
    }
    let n = (top / step).ceil() as usize;
    (1..=n).map(|i| i as f64 * step).collect()
}

/// Limits of many samples of an [`UncertainCut`] on one set of speeds.
#[derive(Debug, Clone, PartialEq)]
pub struct Ensemble {
    /// The uncertain parameters.
    pub parameters: Vec<Parameter>,
    /// Speeds, rpm, ascending.
    pub speeds_rpm: Vec<f64>,
    /// `θ` of each sample.
    pub theta: Vec<Vec<f64>>,
    /// Limiting depth of each sample at each speed, m (`+∞`: no lobe limits the cut).
    pub depth_m: Vec<Vec<f64>>,
    /// Chatter frequency of each sample's limiting lobe at each speed, Hz.
    pub chatter_hz: Vec<Vec<f64>>,
    /// The limit with the nominal parameters and the FRF as measured, m.
    pub nominal_depth_m: Vec<f64>,
    /// Its chatter frequency, Hz.
    pub nominal_chatter_hz: Vec<f64>,
}

/// Monte Carlo: `samples` draws of the parameters (and of the measured FRF's noise), each with its ZOA limit on
/// `speeds_rpm`. Sample `i` draws from its own stream of `seed`, so the ensemble is the same on any number of
/// threads.
pub fn sample_ensemble(
    cut: &UncertainCut,
    speeds_rpm: &[f64],
    samples: usize,
    seed: u64,
) -> Result<Ensemble, StabilityError> {
    cut.validate()?;
    if samples == 0 {
        return Err(invalid("samples", 0.0, "at least 1"));
    }
    let parameters = cut.parameters();
    let (nominal_depth_m, nominal_chatter_hz) = cut.limit(&cut.nominal(), speeds_rpm, None)?;
    let measured = matches!(cut.dynamics, Dynamics::Measured { .. });
    let runs: Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> = (0..samples)
        .into_par_iter()
        .map(|i| {
            let mut rng = crate::rig::stream(seed, i as u64);
            let theta = cut.draw(&parameters, &mut rng)?;
            let (d, c) = cut.limit(&theta, speeds_rpm, measured.then_some(&mut rng))?;
            Ok((theta, d, c))
        })
        .collect::<Result<_, StabilityError>>()?;
    let mut e = Ensemble {
        parameters,
        speeds_rpm: speeds_rpm.to_vec(),
        theta: Vec::with_capacity(samples),
        depth_m: Vec::with_capacity(samples),
        chatter_hz: Vec::with_capacity(samples),
        nominal_depth_m,
        nominal_chatter_hz,
    };
    for (t, d, c) in runs {
        e.theta.push(t);
        e.depth_m.push(d);
        e.chatter_hz.push(c);
    }
    Ok(e)
}

impl Ensemble {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.theta.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.theta.is_empty()
    }

    /// Index of `speed` among the speeds, if it is one of them.
    fn speed_index(&self, speed: f64) -> Option<usize> {
        let i = self.speeds_rpm.partition_point(|&s| s < speed);
        (i < self.speeds_rpm.len() && self.speeds_rpm[i] == speed).then_some(i)
    }
}

/// The posterior of an ensemble given trials: normalised importance weights.
#[derive(Debug, Clone, PartialEq)]
pub struct Posterior {
    /// Weight of each sample, summing to 1.
    pub weights: Vec<f64>,
    /// `(Σw)²/Σw²`: how many samples effectively carry the posterior.
    pub effective_samples: f64,
    /// `ln` of the mean likelihood of the trials over the prior samples (the evidence).
    pub log_evidence: f64,
}

/// The trials' likelihood for each sample of `ensemble`, normalised into importance weights. Every trial's speed
/// must be one of the ensemble's speeds (sample the ensemble on the trial speeds too). `chatter_sigma_hz`
/// weighs the chatter frequency of chattering trials that give one; `None` ignores it.
pub fn update(
    ensemble: &Ensemble,
    trials: &[Trial],
    likelihood: &TrialLikelihood,
    chatter_sigma_hz: Option<f64>,
) -> Result<Posterior, StabilityError> {
    if let Some(s) = chatter_sigma_hz
        && !(s.is_finite() && s > 0.0)
    {
        return Err(invalid("chatter frequency σ", s, "finite and > 0 Hz"));
    }
    let at: Vec<usize> = trials
        .iter()
        .enumerate()
        .map(|(index, t)| {
            ensemble.speed_index(t.speed_rpm).ok_or_else(|| StabilityError::InvalidTrial {
                index,
                problem: format!(
                    "{} rpm is not one of the map's speeds; sample the map at the trial speeds",
                    t.speed_rpm
                ),
            })
        })
        .collect::<Result<_, _>>()?;
    let log_l: Vec<f64> = (0..ensemble.len())
        .map(|s| {
            trials
                .iter()
                .zip(&at)
                .map(|(t, &i)| {
                    let mut l = -0.5 * likelihood.deviance(t, ensemble.depth_m[s][i]);
                    if let (Some(sf), Some(f), Outcome::Chatter) = (chatter_sigma_hz, t.chatter_hz, t.outcome) {
                        let r = (f - ensemble.chatter_hz[s][i]) / sf;
                        l += -0.5 * r * r;
                    }
                    l
                })
                .sum()
        })
        .collect();
    let max = log_l.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let raw: Vec<f64> = log_l.iter().map(|l| (l - max).exp()).collect();
    let total: f64 = raw.iter().sum();
    let weights: Vec<f64> = raw.iter().map(|w| w / total).collect();
    let effective_samples = 1.0 / weights.iter().map(|w| w * w).sum::<f64>();
    let log_evidence = max + (total / ensemble.len() as f64).ln();
    Ok(Posterior { weights, effective_samples, log_evidence })
}

/// Weighted mean and standard deviation of each parameter.
pub fn moments(ensemble: &Ensemble, weights: Option<&[f64]>) -> Vec<(f64, f64)> {
    let n = ensemble.len();
    let w = |s: usize| weights.map_or(1.0 / n as f64, |w| w[s]);
    (0..ensemble.parameters.len())
        .map(|k| {
            let mean: f64 = (0..n).map(|s| w(s) * ensemble.theta[s][k]).sum();
            let var: f64 = (0..n).map(|s| w(s) * (ensemble.theta[s][k] - mean).powi(2)).sum();
            (mean, var.max(0.0).sqrt())
        })
        .collect()
}

/// Quantiles of the limit drawn as lobes: 5 %, 50 % and 95 %.
pub const QUANTILES: [f64; 3] = [0.05, 0.5, 0.95];

/// The probability of stability on a speed × depth grid and the quantile lobes.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbabilityMap {
    /// Speeds, rpm.
    pub speeds_rpm: Vec<f64>,
    /// Depths, m.
    pub depths_m: Vec<f64>,
    /// Row-major `[speed][depth]` probability that the cut is stable.
    pub stable: Vec<f64>,
    /// Per speed, the [`QUANTILES`] of the limiting depth, m.
    pub lobes_m: Vec<[f64; 3]>,
    /// Per speed, the chatter frequency of the sample at each quantile, Hz.
    pub chatter_hz: Vec<[f64; 3]>,
}

impl ProbabilityMap {
    /// Probability of stability at speed `i`, depth `j`.
    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.stable[i * self.depths_m.len() + j]
    }
}

/// The map of `ensemble` at the speeds `speed_indices` (indices into its speeds) and `depths_m`, with the prior
/// (equal weights) or posterior `weights`.
pub fn probability_map(
    ensemble: &Ensemble,
    weights: Option<&[f64]>,
    speed_indices: &[usize],
    depths_m: &[f64],
) -> ProbabilityMap {
    let n = ensemble.len();
    let w = |s: usize| weights.map_or(1.0 / n as f64, |w| w[s]);
    let per_speed: Vec<(Vec<f64>, [f64; 3], [f64; 3])> = speed_indices
        .par_iter()
        .map(|&i| {
            let mut order: Vec<usize> = (0..n).collect();
            order.sort_by(|&a, &b| ensemble.depth_m[a][i].total_cmp(&ensemble.depth_m[b][i]).then(a.cmp(&b)));
            let limits: Vec<f64> = order.iter().map(|&s| ensemble.depth_m[s][i]).collect();
            let mut cum = Vec::with_capacity(n);
            let mut acc = 0.0;
            for &s in &order {
                acc += w(s);
                cum.push(acc);
            }
            let total = acc;
            let stable = depths_m
                .iter()
                .map(|&b| {
                    // Samples whose limit is at or below b chatter there.
                    let k = limits.partition_point(|&l| l <= b);
                    let chatter = if k == 0 { 0.0 } else { cum[k - 1] };
                    ((total - chatter) / total).clamp(0.0, 1.0)
                })
                .collect();
            let mut lobes = [0.0; 3];
            let mut chatter = [0.0; 3];
            for (q, (l, c)) in QUANTILES.iter().zip(lobes.iter_mut().zip(chatter.iter_mut())) {
                let k = cum.partition_point(|&c| c < q * total).min(n - 1);
                *l = limits[k];
                *c = ensemble.chatter_hz[order[k]][i];
            }
            (stable, lobes, chatter)
        })
        .collect();
    let mut map = ProbabilityMap {
        speeds_rpm: speed_indices.iter().map(|&i| ensemble.speeds_rpm[i]).collect(),
        depths_m: depths_m.to_vec(),
        stable: Vec::with_capacity(speed_indices.len() * depths_m.len()),
        lobes_m: Vec::with_capacity(speed_indices.len()),
        chatter_hz: Vec::with_capacity(speed_indices.len()),
    };
    for (s, l, c) in per_speed {
        map.stable.extend(s);
        map.lobes_m.push(l);
        map.chatter_hz.push(c);
    }
    map
}

/// The linearised alternative to Monte Carlo: the nominal limit and its standard deviation per speed.
#[derive(Debug, Clone, PartialEq)]
pub struct Linearised {
    /// Speeds, rpm.
    pub speeds_rpm: Vec<f64>,
    /// The nominal limit, m.
    pub depth_m: Vec<f64>,
    /// `σ_b = √Σ (∂b/∂θ_k σ_k)²` by central differences with steps of `σ_k/10`, m.
    pub sigma_m: Vec<f64>,
}

impl Linearised {
    /// The `q` lobe of the Gaussian limit, `b + σ_b Φ⁻¹(q)`.
    pub fn lobe(&self, q: f64) -> Vec<f64> {
        let z = normal_quantile(q);
        self.depth_m.iter().zip(&self.sigma_m).map(|(b, s)| b + z * s).collect()
    }

    /// Probability that a cut at speed `i` and depth `b` is stable, `Φ((b_lim − b)/σ_b)`.
    pub fn stable(&self, i: usize, depth_m: f64) -> f64 {
        let (b, s) = (self.depth_m[i], self.sigma_m[i]);
        if s == 0.0 { f64::from(u8::from(depth_m < b)) } else { normal_cdf((b - depth_m) / s) }
    }
}

/// The limit's standard deviation by first-order propagation of the parameters' σ (the measured FRF's noise is
/// not propagated: it has no few parameters to differentiate).
pub fn linearised(cut: &UncertainCut, speeds_rpm: &[f64]) -> Result<Linearised, StabilityError> {
    cut.validate()?;
    let theta = cut.nominal();
    let (depth_m, _) = cut.limit(&theta, speeds_rpm, None)?;
    let mut var = vec![0.0; speeds_rpm.len()];
    for (k, p) in cut.parameters().iter().enumerate() {
        if p.prior.sigma == 0.0 {
            continue;
        }
        let h = p.prior.sigma / 10.0;
        let (mut up, mut down) = (theta.clone(), theta.clone());
        up[k] += h;
        down[k] -= h;
        if !(p.kind.physical(up[k]) && p.kind.physical(down[k])) {
            return Err(invalid(
                "prior standard deviation",
                p.prior.sigma,
                "at most ten times the distance of the mean to its physical bound",
            ));
        }
        let (bu, _) = cut.limit(&up, speeds_rpm, None)?;
        let (bd, _) = cut.limit(&down, speeds_rpm, None)?;
        for (v, (u, d)) in var.iter_mut().zip(bu.iter().zip(&bd)) {
            let g = (u - d) / (2.0 * h) * p.prior.sigma;
            if g.is_finite() {
                *v += g * g;
            }
        }
    }
    Ok(Linearised { speeds_rpm: speeds_rpm.to_vec(), depth_m, sigma_m: var.iter().map(|v| v.sqrt()).collect() })
}

/// `Φ⁻¹(q)` by Newton's method on [`normal_cdf`] (to 1e-12), for `q` in `(0, 1)`.
pub fn normal_quantile(q: f64) -> f64 {
    let mut x: f64 = 0.0;
    for _ in 0..100 {
        let pdf = (-0.5 * x * x).exp() / (2.0 * PI).sqrt();
        let step = (normal_cdf(x) - q) / pdf.max(1e-300);
        x -= step;
        if step.abs() < 1e-12 {
            break;
        }
    }
    x
}

#[cfg(test)]
mod tests;
