use super::*;
use crate::stability::{MillingDirection, Outcome, Trial};
use rand::SeedableRng;

/// Two modes per direction near the lab tool of the ZOA validation (1243/1747 Hz), Ks 2160 MPa, β 68°, 4 teeth,
/// 50 % down-milling; σ: 1 % on f, 10 % on ζ, 5 % on k, 5 % on Ks, 2° on β.
fn cut(scale_sigma: f64) -> UncertainCut {
    let mode = |f: f64, zeta: f64, k: f64| ModePrior {
        freq_hz: Gaussian { mean: f, sigma: 0.01 * f * scale_sigma },
        damping_ratio: Gaussian { mean: zeta, sigma: 0.1 * zeta * scale_sigma },
        stiffness: Gaussian { mean: k, sigma: 0.05 * k * scale_sigma },
    };
    let x = vec![mode(1243.0, 0.03, 3.6e7), mode(1747.0, 0.025, 6.0e7)];
    let y = vec![mode(1260.0, 0.03, 3.9e7), mode(1780.0, 0.025, 6.5e7)];
    let freqs_hz = modal_grid(&[x.clone(), y.clone()].concat());
    let milling = Milling::new(
        4,
        0.5,
        MillingDirection::Down,
        CuttingCoefficients::from_ks_beta(2160e6, 68f64.to_radians()).unwrap(),
    )
    .unwrap();
    UncertainCut {
        dynamics: Dynamics::Modes { x, y, freqs_hz },
        milling,
        ks: Gaussian { mean: 2160e6, sigma: 0.05 * 2160e6 * scale_sigma },
        beta_rad: Gaussian { mean: 68f64.to_radians(), sigma: 2f64.to_radians() * scale_sigma },
    }
}

fn speeds() -> Vec<f64> {
    (0..=100).map(|i| 8000.0 + 120.0 * i as f64).collect()
}

/// The ranks between which the median of `n` samples lies with 99 % confidence (order statistics of a
/// binomial(n, ½), normal approximation).
fn median_ranks(n: usize) -> (usize, usize) {
    let half = 2.576 * (n as f64).sqrt() / 2.0;
    let mid = n as f64 / 2.0;
    ((mid - half).floor().max(0.0) as usize, ((mid + half).ceil() as usize).min(n - 1))
}

/// Where every sample is limited by the same lobe as the nominal model (its chatter frequency within 5 % of
/// the nominal one for ≥ 95 % of the samples), the median limit is the nominal limit within the 99 % interval
/// of the median. At a cusp, where samples switch between two lobes, the median of their minimum lies below
/// the minimum of their medians: a real bias of the nominal lobe, not sampling error.
#[test]
fn the_50_percent_lobe_is_the_nominal_lobe_within_the_sampling_error() {
    let speeds = speeds();
    let e = sample_ensemble(&cut(1.0), &speeds, 300, 7).unwrap();
    let (lo, hi) = median_ranks(e.len());
    let (mut off_cusp, mut inside, mut median_low_at_cusps) = (0, 0, 0);
    for i in 0..speeds.len() {
        let mut at: Vec<f64> = e.depth_m.iter().map(|d| d[i]).collect();
        at.sort_by(f64::total_cmp);
        let f0 = e.nominal_chatter_hz[i];
        let same_lobe = e.chatter_hz.iter().filter(|c| (c[i] - f0).abs() <= 0.05 * f0).count();
        if same_lobe * 100 >= e.len() * 95 {
            off_cusp += 1;
            if at[lo] <= e.nominal_depth_m[i] && e.nominal_depth_m[i] <= at[hi] {
                inside += 1;
            }
        } else if at[e.len() / 2] <= e.nominal_depth_m[i] {
            median_low_at_cusps += 1;
        }
    }
    let cusps = speeds.len() - off_cusp;
    assert!(off_cusp * 2 >= speeds.len(), "only {off_cusp} of {} speeds away from cusps", speeds.len());
    assert!(inside * 100 >= off_cusp * 95, "nominal inside the median's interval at {inside} of {off_cusp} speeds");
    assert!(
        median_low_at_cusps * 10 >= cusps * 8,
        "median below nominal at {median_low_at_cusps} of {cusps} cusp speeds"
    );
    let all: Vec<usize> = (0..speeds.len()).collect();
    let map = probability_map(&e, None, &all, &[1e-4]);
    for (i, l) in map.lobes_m.iter().enumerate() {
        assert!(l[0] <= l[1] && l[1] <= l[2], "quantiles out of order at {} rpm", speeds[i]);
    }
}

#[test]
fn monte_carlo_and_the_linearised_limit_agree_where_the_limit_is_smooth() {
    let speeds = speeds();
    let c = cut(1.0);
    let e = sample_ensemble(&c, &speeds, 400, 11).unwrap();
    let lin = linearised(&c, &speeds).unwrap();
    let all: Vec<usize> = (0..speeds.len()).collect();
    let map = probability_map(&e, None, &all, &[]);
    let (p05, p95) = (lin.lobe(0.05), lin.lobe(0.95));
    // Compare the 5–95 % spread: within 25 % of the Monte Carlo spread at most speeds (the linearisation misses
    // the switch between lobes at the cusps and the skew of b ∝ 1/Ks).
    let mut close = 0;
    for i in 0..speeds.len() {
        let mc = map.lobes_m[i][2] - map.lobes_m[i][0];
        let li = p95[i] - p05[i];
        if (mc - li).abs() <= 0.25 * mc {
            close += 1;
        }
    }
    assert!(close * 4 >= speeds.len() * 3, "spreads agree at {close} of {} speeds", speeds.len());
}

#[test]
fn the_map_is_a_probability_falling_with_depth_and_is_the_same_on_any_thread_count() {
    let speeds: Vec<f64> = (0..=20).map(|i| 9000.0 + 200.0 * i as f64).collect();
    let depths: Vec<f64> = (1..=40).map(|j| j as f64 * 0.25e-3).collect();
    let all: Vec<usize> = (0..speeds.len()).collect();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let e = sample_ensemble(&cut(1.0), &speeds, 60, 3).unwrap();
            probability_map(&e, None, &all, &depths)
        })
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one, two);
    for (i, speed) in speeds.iter().enumerate() {
        for j in 1..depths.len() {
            assert!((0.0..=1.0).contains(&one.at(i, j)));
            assert!(one.at(i, j) <= one.at(i, j - 1), "not falling with depth at {speed} rpm");
        }
    }
}

#[test]
fn known_parameters_give_the_nominal_lobe_at_every_quantile() {
    let speeds = speeds();
    let e = sample_ensemble(&cut(0.0), &speeds, 5, 1).unwrap();
    let all: Vec<usize> = (0..speeds.len()).collect();
    let map = probability_map(&e, None, &all, &[]);
    for (l, b) in map.lobes_m.iter().zip(&e.nominal_depth_m) {
        assert_eq!(l, &[*b; 3]);
    }
}

/// Bendat & Piersol's ε for γ² = 0.9 and 10 averages is √(0.1/18) = 0.0745; the drawn FRFs scatter by it.
#[test]
fn measured_frf_noise_scatters_by_the_coherence_error() {
    assert!((random_error(0.9, 10.0) - (0.1f64 / 18.0).sqrt()).abs() < 1e-15);
    assert_eq!(random_error(1.0, 4.0), 0.0);
    let freqs = vec![100.0, 200.0];
    let h = vec![Complex64::new(1e-6, -2e-6); 2];
    let frf = ToolPointFrf::new(freqs, h.clone(), h).unwrap();
    let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(5);
    let n = 4000;
    let (mut s1, mut s2) = (0.0, 0.0);
    for _ in 0..n {
        let d = noisy(&frf, &[0.9, 1.0], &[0.9, 1.0], 10, &mut rng).unwrap();
        assert_eq!(d.xx[1], frf.xx[1], "a line of coherence 1 has no noise");
        let r = d.xx[0].norm() / frf.xx[0].norm() - 1.0;
        s1 += r;
        s2 += r * r;
    }
    let sd = (s2 / n as f64 - (s1 / n as f64).powi(2)).sqrt();
    let eps = random_error(0.9, 10.0);
    assert!((sd / eps - 1.0).abs() < 0.06, "gain scatter {sd} vs ε {eps}");
}

/// Trials drawn from a truth whose Ks lies 1.5 prior σ above the prior mean: the posterior mean of Ks moves to
/// the truth and its σ shrinks as trials accumulate.
#[test]
fn the_posterior_concentrates_on_the_true_coefficients() {
    let mut prior = cut(0.0);
    prior.ks = Gaussian { mean: 2000e6, sigma: 200e6 };
    prior.beta_rad = Gaussian { mean: 68f64.to_radians(), sigma: 2f64.to_radians() };
    let (ks_true, beta_true) = (2300e6, 69.5f64.to_radians());
    let speeds: Vec<f64> = (0..=40).map(|i| 8000.0 + 300.0 * i as f64).collect();
    let mut truth = prior.clone();
    truth.ks = Gaussian::fixed(ks_true);
    truth.beta_rad = Gaussian::fixed(beta_true);
    let (b_true, _) = truth.limit(&truth.nominal(), &speeds, None).unwrap();
    // Trials at every speed, depths spread evenly over ±40 % of the true limit; outcome by the truth.
    let trials: Vec<Trial> = (0..80)
        .map(|k| {
            let i = (k * 7) % speeds.len();
            let ratio = 0.6 + 0.8 * ((k * 37) % 80) as f64 / 79.0;
            let depth = ratio * b_true[i];
            let outcome = if depth < b_true[i] { Outcome::Stable } else { Outcome::Chatter };
            Trial { speed_rpm: speeds[i], depth_m: depth, outcome, chatter_hz: None }
        })
        .collect();
    let e = sample_ensemble(&prior, &speeds, 1500, 42).unwrap();
    let lik = TrialLikelihood::default();
    let mut last_sigma = 200e6;
    let mut last_error = f64::INFINITY;
    for n in [5, 20, 80] {
        let post = update(&e, &trials[..n], &lik, None).unwrap();
        let m = moments(&e, Some(&post.weights));
        let (mean, sd) = m[0];
        assert!(sd < last_sigma, "{n} trials: σ(Ks) {sd} did not shrink from {last_sigma}");
        assert!(post.effective_samples >= 5.0, "{n} trials: {} effective samples", post.effective_samples);
        last_sigma = sd;
        last_error = (mean - ks_true).abs();
    }
    assert!(last_error < 0.03 * ks_true, "Ks posterior mean off the truth by {last_error}");
    assert!(last_sigma < 0.25 * 200e6, "σ(Ks) {last_sigma} after 80 trials");
}

#[test]
fn a_trial_off_the_map_speeds_is_refused_by_its_index() {
    let speeds = vec![9000.0, 10000.0];
    let e = sample_ensemble(&cut(1.0), &speeds, 4, 1).unwrap();
    let t = Trial { speed_rpm: 9500.0, depth_m: 1e-3, outcome: Outcome::Stable, chatter_hz: None };
    let err = update(&e, &[t], &TrialLikelihood::default(), None).unwrap_err();
    assert!(matches!(err, StabilityError::InvalidTrial { index: 0, .. }), "{err}");
}

#[test]
fn the_linearised_quantile_inverts_the_normal_cdf() {
    for q in [0.05, 0.5, 0.95, 0.999] {
        assert!((normal_cdf(normal_quantile(q)) - q).abs() < 1e-12);
    }
    assert!((normal_quantile(0.95) - 1.644_853_626_951_472_2).abs() < 1e-9);
}
