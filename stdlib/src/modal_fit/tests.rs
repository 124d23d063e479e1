use super::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Ten Eq. 5.8 modes between 250 and 4800 Hz with imaginary peaks within a factor of four of each other.
fn ten_modes() -> Vec<Mode> {
    let f = [250.0, 620.0, 1050.0, 1500.0, 1980.0, 2450.0, 3000.0, 3550.0, 4150.0, 4800.0];
    let xi = [0.03, 0.02, 0.025, 0.015, 0.02, 0.03, 0.018, 0.022, 0.025, 0.02];
    let peak = [1.0, 0.6, 0.8, 0.5, 0.7, 0.4, 0.6, 0.5, 0.3, 0.4];
    (0..10)
        .map(|i| {
            let w = TAU * f[i];
            let m = 1.0 / (2.0 * xi[i] * w * w * peak[i] * 1e-6);
            Mode { freq_hz: f[i], damping_ratio: xi[i], modal_mass: m }
        })
        .collect()
}

/// 4,000 lines at 1.5 Hz, the sum of `modes` plus complex Gaussian noise of `noise` · |H| per line.
fn synthetic(modes: &[Mode], noise: f64, seed: u64) -> (Vec<f64>, Vec<Complex64>) {
    let freqs: Vec<f64> = (1..=4000).map(|k| 1.5 * k as f64).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let h = freqs
        .iter()
        .map(|&f| {
            let v: Complex64 = modes.iter().map(|m| m.receptance(TAU * f)).sum();
            let (a, b): (f64, f64) = (StandardNormal.sample(&mut rng), StandardNormal.sample(&mut rng));
            v + Complex64::new(a, b) * (noise * v.norm() / std::f64::consts::SQRT_2)
        })
        .collect();
    (freqs, h)
}

/// Worst relative frequency, damping and mass errors of `got` against `want` (matched by order).
fn worst(got: &[Mode], want: &[Mode]) -> (f64, f64, f64) {
    assert_eq!(got.len(), want.len(), "modes found: {:?}", got.iter().map(|m| m.freq_hz).collect::<Vec<_>>());
    got.iter().zip(want).fold((0.0_f64, 0.0_f64, 0.0_f64), |(a, b, c), (g, w)| {
        (
            a.max((g.freq_hz / w.freq_hz - 1.0).abs()),
            b.max((g.damping_ratio / w.damping_ratio - 1.0).abs()),
            c.max((g.modal_mass / w.modal_mass - 1.0).abs()),
        )
    })
}

fn opts(method: Method) -> FitOptions {
    FitOptions { method, h_sens: 9, v_sens: 0.1, ..FitOptions::default() }
}

#[test]
fn simplex_recovers_ten_noisy_modes() {
    let truth = ten_modes();
    let (freqs, h) = synthetic(&truth, 0.02, 7);
    let fit = fit(&freqs, &h, &opts(Method::Simplex)).unwrap();
    let (ef, ex, em) = worst(&fit.modes, &truth);
    println!("simplex worst errors: f {ef:.2e}, xi {ex:.2e}, M {em:.2e}; iterations {}", fit.iterations);
    assert!(ef < 0.01 && ex < 0.015, "f {ef}, xi {ex}");
    assert!(em < 0.05, "mass {em}");
    for e in &fit.band_errors {
        // 2 % noise: the residual of a correct fit is ~2 % · E|N(0,1)|/√2·√2 ≈ 1.8 %. Each beam also carries its
        // higher bending modes (the second at 6.27 f, with the same tip modal mass ρAL/4): the 250 Hz beam's
        // second mode at 1567 Hz adds ~6 % in the 1500 Hz band, a limit of the one-beam-per-mode model.
        assert!(e.modal < 0.025 && e.beam < 0.1, "band error at {} Hz: {e:?}", e.f_hz);
    }
}

#[test]
fn lscf_recovers_ten_noisy_modes() {
    let truth = ten_modes();
    let (freqs, h) = synthetic(&truth, 0.02, 7);
    let fit = fit(&freqs, &h, &opts(Method::Lscf { order: None })).unwrap();
    let (ef, ex, em) = worst(&fit.modes, &truth);
    println!("lscf worst errors: f {ef:.2e}, xi {ex:.2e}, M {em:.2e}; rejected {}", fit.deleted.len());
    assert!(ef < 0.01 && ex < 0.015, "f {ef}, xi {ex}");
    assert!(em < 0.05, "mass {em}");
}

#[test]
fn picking_finds_the_peaks_and_honours_v_sens() {
    let truth = ten_modes();
    let (freqs, h) = synthetic(&truth, 0.0, 1);
    let all = pick_modes(&freqs, &h, 0..freqs.len(), 1, 0.05, 1.0).unwrap();
    assert_eq!(all.len(), 10);
    for (p, m) in all.iter().zip(&truth) {
        // The Im peak of Eq. 5.8 sits at f·(1 + O(ξ²)); the grid step is 1.5 Hz.
        assert!((p.freq_hz - m.freq_hz).abs() <= 1.5 + 2.0 * m.damping_ratio.powi(2) * m.freq_hz, "{p:?}");
    }
    // Peaks are 1.0, 0.6, 0.8, 0.5, 0.7, 0.4, 0.6, 0.5, 0.3, 0.4 µm/N: a 55 % cut-off keeps five.
    let strong = pick_modes(&freqs, &h, 0..freqs.len(), 1, 0.55, 1.0).unwrap();
    let kept: Vec<f64> = strong.iter().map(|p| (p.freq_hz / 10.0).round() * 10.0).collect();
    assert_eq!(kept, [250.0, 620.0, 1050.0, 1980.0, 3000.0]);
    // Noise makes spurious minima without smoothing; H_sens = 9 with a 10 % cut-off leaves the ten modes.
    let (freqs, noisy) = synthetic(&truth, 0.02, 3);
    assert!(pick_modes(&freqs, &noisy, 0..freqs.len(), 1, 0.05, 1.0).unwrap().len() > 10);
    let picked = pick_modes(&freqs, &noisy, 0..freqs.len(), 9, 0.1, 1.0).unwrap();
    assert_eq!(picked.len(), 10);
    for (p, m) in picked.iter().zip(&truth) {
        assert!((p.freq_hz / m.freq_hz - 1.0).abs() < 0.005, "{p:?}");
    }
}

#[test]
fn moving_average_matches_direct_sums() {
    let x: Vec<f64> = (0..20).map(|i| ((i * 7) % 5) as f64 - 1.5).collect();
    let mut out = Vec::new();
    for width in [1, 2, 3, 6] {
        moving_average(&x, width, &mut out);
        let before = (width - 1) / 2;
        for (i, got) in out.iter().enumerate() {
            let a = i.saturating_sub(before);
            let b = (i + width - before).min(x.len());
            let want = x[a..b].iter().sum::<f64>() / (b - a) as f64;
            assert!((got - want).abs() < 1e-12);
        }
    }
}

#[test]
fn no_mode_above_v_sens_is_an_error() {
    // A mode below the band dominates Im(H) at the band's lower edge; the one mode inside is 200 times weaker.
    let big = Mode { freq_hz: 300.0, damping_ratio: 0.05, modal_mass: 0.5 };
    let w = TAU * 2000.0;
    // Its Im peak is 1 % of the big mode's |Im H| at 400 Hz, under the default 5 % cut-off.
    let edge = big.receptance(TAU * 400.0).im.abs();
    let small = Mode { freq_hz: 2000.0, damping_ratio: 0.02, modal_mass: 1.0 / (0.04 * w * w * 0.01 * edge) };
    let (freqs, h) = synthetic(&[big, small], 0.0, 1);
    // The v_sens cut-off alone (the weak mode is too faint in |H| for the prominence check).
    let o = FitOptions { min_frequency_hz: 400.0, v_sens: 0.05, prominence_db: 0.0, ..FitOptions::default() };
    match fit(&freqs, &h, &o) {
        Err(FitError::NoModes { largest, cutoff, deepest, .. }) => {
            assert!((cutoff / largest - 0.05).abs() < 1e-12 && deepest < cutoff);
            let msg = fit(&freqs, &h, &o).unwrap_err().to_string();
            assert!(msg.contains("lower v_sens"), "{msg}");
        }
        Err(other) => panic!("expected NoModes, got {other}"),
        Ok(fit) => panic!("expected NoModes, got {} modes", fit.modes.len()),
    }
    // Lowering v_sens picks it.
    let start = freqs.partition_point(|&f| f < 400.0);
    let picked = pick_modes(&freqs, &h, start..freqs.len(), 5, 1e-3, 1.0).unwrap();
    assert_eq!(picked.len(), 1);
    assert!((picked[0].freq_hz / 2000.0 - 1.0).abs() < 1e-3);
    // A positive imaginary part (wrong sign convention) has no negative peak at all.
    let flipped: Vec<Complex64> = h.iter().map(|v| v.conj()).collect();
    assert!(matches!(super::fit(&freqs, &flipped, &FitOptions::default()), Err(FitError::NoPeaks { .. })));
}

#[test]
fn bad_grids_are_errors() {
    let (freqs, h) = synthetic(&ten_modes()[..2], 0.0, 1);
    let o = FitOptions::default();
    let mut f = freqs.clone();
    f[10] = f[9];
    assert!(matches!(fit(&f, &h, &o), Err(FitError::NonIncreasing { index: 10, .. })));
    f[10] = f64::NAN;
    assert!(matches!(fit(&f, &h, &o), Err(FitError::NonFinite { what: "frequency", index: 10, .. })));
    let mut v = h.clone();
    v[5].im = f64::INFINITY;
    assert!(matches!(fit(&freqs, &v, &o), Err(FitError::NonFinite { what: "FRF value", index: 5, .. })));
    assert!(matches!(fit(&freqs[..5], &h[..5], &o), Err(FitError::TooFewLines { lines: 5, .. })));
    assert!(matches!(fit(&freqs, &h[1..], &o), Err(FitError::LengthMismatch { .. })));
    let narrow = FitOptions { min_frequency_hz: 1000.0, max_frequency_hz: 1006.0, ..o };
    assert!(matches!(fit(&freqs, &h, &narrow), Err(FitError::TooFewLines { place: "in the fit band", .. })));
    let bad = FitOptions { v_sens: 1.5, ..o };
    assert!(matches!(fit(&freqs, &h, &bad), Err(FitError::InvalidOption { name: "v_sens", .. })));
}

#[test]
fn bands_follow_eq_5_13() {
    // Well spread modes: ±200 Hz (constraint b); the first is limited by 0.4·f (a) and then by c.
    let b = mode_bands(&[300.0, 1500.0, 1700.0, 5000.0], 0.0, 6000.0, 1.0);
    assert_eq!((b[0].lo_hz, b[0].hi_hz), (180.0, 500.0)); // 0.4·300 = 120 below, 200 above
    assert_eq!((b[1].lo_hz, b[1].hi_hz), (1300.0, 1580.0)); // 0.4·200 = 80 above, 200 below (ratio 2.5)
    assert_eq!((b[2].lo_hz, b[2].hi_hz), (1620.0, 1900.0));
    assert!(!b[3].clipped);
    // Ratio cap: 150 Hz below and 40 Hz above becomes 120 / 40.
    let b = mode_bands(&[375.0, 475.0], 0.0, 6000.0, 1.0);
    assert_eq!((b[0].lo_hz, b[0].hi_hz), (375.0 - 120.0, 415.0));
    // The fit band clips and says so.
    let b = mode_bands(&[5950.0], 0.0, 6000.0, 1.0);
    assert!(b[0].clipped && b[0].hi_hz == 6000.0 && (b[0].lo_hz - 5800.0).abs() < 1e-9);
}

#[test]
fn equivalent_beam_matches_the_mode_near_resonance() {
    let mat = Material::STEEL;
    for mode in [
        Mode { freq_hz: 900.0, damping_ratio: 0.03, modal_mass: 0.8 },
        Mode { freq_hz: 3200.0, damping_ratio: 0.015, modal_mass: 0.2 },
    ] {
        let band = Band { lo_hz: mode.freq_hz - 200.0, hi_hz: mode.freq_hz + 200.0, clipped: false };
        let beam = beam_for_mode(&mode, &band, &mat, 32).unwrap();
        // The closed form is the start: the first mode's tip modal mass is ρAL/4.
        let d0 = closed_form_diameter(&mode, &mat);
        let b0 = FixedFreeBeam::equivalent(mode.freq_hz, d0, 0.0, mat).unwrap();
        assert!((mat.density * b0.area() * b0.length_m / 4.0 / mode.modal_mass - 1.0).abs() < 1e-12);
        assert!((beam.d_m / d0 - 1.0).abs() < 0.05 && (beam.eta / (2.0 * mode.damping_ratio) - 1.0).abs() < 0.05);
        // Within ±2 half-power widths the beam's H is the mode's to 1.5 % of the peak.
        let peak = mode.receptance(TAU * mode.freq_hz).norm();
        let reach = 2.0 * mode.damping_ratio * mode.freq_hz;
        for k in 0..=40 {
            let f = mode.freq_hz - reach + 2.0 * reach * k as f64 / 40.0;
            let e = (beam.tip_receptance(TAU * f).h - mode.receptance(TAU * f)).norm() / peak;
            assert!(e < 0.015, "{} Hz: {e}", f);
        }
    }
}

#[test]
fn tip_block_is_the_fitted_frf_with_positive_static_limits() {
    let truth = ten_modes();
    let (freqs, h) = synthetic(&truth[..3], 0.0, 1);
    let o = FitOptions { max_frequency_hz: 1500.0, ..opts(Method::Simplex) };
    let fit = fit(&freqs, &h, &o).unwrap();
    assert_eq!(fit.modes.len(), 3);
    for (k, r) in fit.tip.lines.iter().enumerate() {
        assert_eq!(r.h, fit.fitted[k]);
        assert_eq!(r.l, r.n); // Eq. 5.10
    }
    // Static limits (first line, 1.5 Hz, far below the modes): Σ L³/3EI, Σ L²/2EI, Σ L/EI, all positive.
    let zero = Complex64::new(0.0, 0.0);
    let (mut h0, mut l0, mut p0) = (zero, zero, zero);
    for b in &fit.beams {
        let ei = b.beam.ei_complex();
        let len = b.beam.length_m;
        h0 += len.powi(3) / (3.0 * ei);
        l0 += len * len / (2.0 * ei);
        p0 += len / ei;
    }
    let r0 = fit.tip.lines[0];
    assert!(r0.h.re > 0.0 && r0.l.re > 0.0 && r0.p.re > 0.0);
    let rel = |a: Complex64, b: Complex64| (a - b).norm() / b.norm();
    assert!(rel(r0.h, h0) < 1e-3 && rel(r0.l, l0) < 1e-3 && rel(r0.p, p0) < 1e-3);
    // The modes reproduce the noise-free FRF in every band; the beams to within the ~3 % their higher modes add
    // away from resonance (a cantilever's first mode carries 97 % of its static flexibility L³/3EI).
    for e in &fit.band_errors {
        assert!(e.modal < 2e-3 && e.beam < 0.04, "{e:?}");
    }
}

#[test]
fn floating_modes_are_seeded_and_deleted_when_useless() {
    let truth = ten_modes();
    let (freqs, h) = synthetic(&truth[..3], 0.01, 5);
    let o = FitOptions { max_frequency_hz: 1500.0, floating_modes: true, seed: 11, ..opts(Method::Simplex) };
    let a = fit(&freqs, &h, &o).unwrap();
    let b = fit(&freqs, &h, &o).unwrap();
    assert_eq!(a, b);
    // Twenty to sixty floating modes went in; those that ended at a bound were deleted.
    assert!(!a.deleted.is_empty());
    for e in &a.band_errors {
        assert!(e.modal < 0.02, "{e:?}");
    }
}

/// Three modes like an artifact's direct FRF: 696, 1093 and 2369 Hz, ζ ≈ 3 %, 1.0, 0.87 and 0.30 kg.
fn artifact_modes() -> Vec<Mode> {
    vec![
        Mode { freq_hz: 696.0, damping_ratio: 0.03, modal_mass: 1.0 },
        Mode { freq_hz: 1093.0, damping_ratio: 0.028, modal_mass: 0.87 },
        Mode { freq_hz: 2369.0, damping_ratio: 0.032, modal_mass: 0.30 },
    ]
}

#[test]
fn beam_refit_brings_the_summed_beams_towards_the_noise() {
    // 2 % noise: a correct model leaves ~1.8 % per band (see `simplex_recovers_ten_noisy_modes`).
    // (case, bound on the refit's worst band, bound the plain mapping's worst band exceeds)
    for (name, truth, refit_bound, plain_floor) in
        [("artifact", artifact_modes(), 0.03, 0.0), ("ten modes", ten_modes(), 0.06, 0.075)]
    {
        let (freqs, h) = synthetic(&truth, 0.02, 7);
        let refit = fit(&freqs, &h, &opts(Method::Simplex)).unwrap();
        let plain = fit(&freqs, &h, &FitOptions { beam_refit: false, ..opts(Method::Simplex) }).unwrap();
        assert_eq!(refit.modes, plain.modes);
        assert_eq!(plain.refit_sweeps, 0);
        assert!((1..=REFIT_ITERATIONS).contains(&refit.refit_sweeps));
        let worst = |f: &ModalFit| f.band_errors.iter().map(|e| e.beam).fold(0.0, f64::max);
        let total = |f: &ModalFit| f.band_errors.iter().map(|e| e.beam).sum::<f64>();
        for (a, b) in refit.band_errors.iter().zip(&plain.band_errors) {
            println!("{name} {:.0} Hz: modal {:.4} mapped {:.4} refit {:.4}", a.f_hz, a.modal, a.mapped, a.beam);
            // The refit reports the plain mapping's error as `mapped`.
            assert!((a.mapped / b.beam - 1.0).abs() < 1e-12 && b.mapped == b.beam);
        }
        let (wr, wp) = (worst(&refit), worst(&plain));
        println!("{name}: {} sweeps; worst band plain {wp:.4}, refit {wr:.4}", refit.refit_sweeps);
        assert!(wr < refit_bound && wp > plain_floor && wr <= wp + 0.002, "{name}: refit {wr}, plain {wp}");
        // Where the mapping is already at the noise the refit only trades noise; elsewhere it lowers the sum.
        assert!(plain_floor == 0.0 || total(&refit) < total(&plain), "{name}");
        // The tip block still carries the fitted FRF, with L = N.
        for (k, r) in refit.tip.lines.iter().enumerate() {
            assert!(r.h == refit.fitted[k] && r.l == r.n);
        }
        let r0 = refit.tip.lines[0];
        assert!(r0.h.re > 0.0 && r0.l.re > 0.0 && r0.p.re > 0.0);
    }
}

/// The artifact's three modes with complex residues: each Eq. 5.8 residue `1/(2iMω_d)` turned by a phase, as
/// non-proportional damping does (a real modal mass cannot carry it).
fn complex_artifact() -> Vec<(Mode, Complex64)> {
    artifact_modes()
        .into_iter()
        .zip([0.2, -0.15, 0.25])
        .map(|(m, phase)| (m, real_residue(&m) * Complex64::from_polar(1.0, phase)))
        .collect()
}

/// 3,000 lines at 1 Hz of `Σ A/(iω − λ) + conj`, plus `upper − lower/ω²`, with complex Gaussian noise of
/// `noise · |H|` per line.
fn synthetic_residues(
    modes: &[(Mode, Complex64)],
    lower: f64,
    upper: f64,
    noise: f64,
    seed: u64,
) -> (Vec<f64>, Vec<Complex64>) {
    let freqs: Vec<f64> = (1..=3000).map(|k| k as f64).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let h = freqs
        .iter()
        .map(|&f| {
            let w = TAU * f;
            let v: Complex64 =
                modes.iter().map(|(m, a)| pair_h(*a, pole(m), w)).sum::<Complex64>() - lower / (w * w) + upper;
            let (a, b): (f64, f64) = (StandardNormal.sample(&mut rng), StandardNormal.sample(&mut rng));
            v + Complex64::new(a, b) * (noise * v.norm() / std::f64::consts::SQRT_2)
        })
        .collect();
    (freqs, h)
}

#[test]
fn complex_residues_fit_non_proportional_modes_to_the_noise() {
    let truth = complex_artifact();
    let (freqs, h) = synthetic_residues(&truth, 0.0, 0.0, 0.01, 13);
    let want: Vec<Mode> = truth.iter().map(|(m, _)| *m).collect();
    let xi_err = |fit: &ModalFit| worst(&fit.modes, &want).1;
    for method in [Method::Simplex, Method::Lscf { order: None }] {
        let base = FitOptions { method, max_frequency_hz: 3000.0, beam_refit: false, ..FitOptions::default() };
        let complex = fit(&freqs, &h, &FitOptions { residues: Residues::Complex, ..base }).unwrap();
        let real = fit(&freqs, &h, &base).unwrap();
        let (ec, er) = (xi_err(&complex), xi_err(&real));
        let (rc, rr) = (complex.residue_fit.relative_residual, real.residue_fit.relative_residual);
        println!("{method:?}: ξ error complex {ec:.4}, real {er:.4}; residual complex {rc:.4}, real {rr:.4}");
        assert!(ec <= 0.01, "{method:?}: complex residues leave a ξ error of {ec}");
        // 1 % noise of |H| leaves a relative L2 residual of 1 %: the complex model sits at the noise floor.
        assert!((rc - 0.01).abs() < 0.001, "{method:?}: residual {rc}");
        // The residues themselves: within 3 % (modulus) and 2° of the truth.
        for (a, (_, t)) in complex.residue_fit.residues.iter().zip(&truth) {
            assert!((a.norm() / t.norm() - 1.0).abs() < 0.03 && (a / t).arg().abs() < 0.035, "{a} vs {t}");
        }
        // Real modal masses cannot carry the phase: the fit is visibly worse.
        assert!(rr > 1.5 * rc, "{method:?}: real-residue residual {rr} vs {rc}");
        if method == Method::Simplex {
            assert!(er > 2.0 * ec.max(0.005), "{method:?}: real-residue ξ error {er} vs {ec}");
        }
    }
}

#[test]
fn residual_terms_recover_out_of_band_modes() {
    // In-band modes between 300 and 3000 Hz; a mode at 30 Hz acts on the band as its mass line −1/(Mω²), one at
    // 30 kHz as its static flexibility 1/K (both to (30/300)² = 1 % at the band's near edge).
    let low = Mode { freq_hz: 30.0, damping_ratio: 0.02, modal_mass: 2.0 };
    let high = Mode { freq_hz: 30_000.0, damping_ratio: 0.02, modal_mass: 1.4e-3 };
    let mut modes = complex_artifact();
    modes.push((low, real_residue(&low)));
    modes.push((high, real_residue(&high)));
    let (freqs, h) = synthetic_residues(&modes, 0.0, 0.0, 0.0, 1);
    let o =
        FitOptions { min_frequency_hz: 300.0, residues: Residues::Complex, beam_refit: false, ..FitOptions::default() };
    let fit = fit(&freqs, &h, &o).unwrap();
    assert_eq!(fit.modes.len(), 3);
    let r = &fit.residue_fit;
    println!(
        "LR·M {}, UR·K {}, residual {}",
        r.lower * low.modal_mass,
        r.upper * high.stiffness(),
        r.relative_residual
    );
    assert!(
        (r.lower * low.modal_mass - 1.0).abs() < 0.02,
        "lower residual {} vs 1/M {}",
        r.lower,
        1.0 / low.modal_mass
    );
    assert!(
        (r.upper * high.stiffness() - 1.0).abs() < 0.02,
        "upper residual {} vs 1/K {}",
        r.upper,
        1.0 / high.stiffness()
    );
    // What remains is the residual terms' own approximation (the next terms are (30/300)² and (3000/30000)², 1 %
    // at the band's edges); real modes without residual terms leave the out-of-band modes' whole contribution.
    let real = super::fit(&freqs, &h, &FitOptions { residues: Residues::Real, ..o }).unwrap();
    let rr = real.residue_fit.relative_residual;
    println!("residual with residual terms {}, real modes without {rr}", r.relative_residual);
    assert!(r.relative_residual < 0.01 && rr > 3.0 * r.relative_residual, "{} vs {rr}", r.relative_residual);
}

/// The W3 peer workload: ten modes, f = 310..3900 Hz, ζ 1–3 %, m 0.5–1.6 kg, 4,000 lines at 1.25 Hz, 2 % noise.
fn w03() -> (Vec<Mode>, Vec<f64>, Vec<Complex64>) {
    let f = [310.0, 620.0, 980.0, 1350.0, 1720.0, 2150.0, 2600.0, 3050.0, 3500.0, 3900.0];
    let z = [0.020, 0.015, 0.030, 0.010, 0.025, 0.012, 0.020, 0.018, 0.022, 0.015];
    let m = [0.5, 0.8, 0.6, 1.2, 0.9, 1.5, 1.0, 1.3, 1.1, 1.6];
    let truth: Vec<Mode> = (0..10).map(|i| Mode { freq_hz: f[i], damping_ratio: z[i], modal_mass: m[i] }).collect();
    let freqs: Vec<f64> = (1..=4000).map(|k| 1.25 * k as f64).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let h = freqs
        .iter()
        .map(|&fq| {
            let v: Complex64 = truth.iter().map(|m| m.receptance(TAU * fq)).sum();
            let (a, b): (f64, f64) = (StandardNormal.sample(&mut rng), StandardNormal.sample(&mut rng));
            v + Complex64::new(a, b) * (0.02 * v.norm() / std::f64::consts::SQRT_2)
        })
        .collect();
    (truth, freqs, h)
}

#[test]
fn w03_ten_modes_over_four_decades_found_with_default_settings() {
    // The modes' Im peaks span 13 µm/N to 35 nm/N (0.26 %): the default cut-off and the |H| prominence check must
    // find all ten and no noise minimum. The peers report max f errors of 2e-4 and 5e-4 and ζ errors of 1.3 %
    // (Nelder–Mead) and 7.9 % (LSCF/LSFD) on this workload.
    let (truth, freqs, h) = w03();
    for method in [Method::Simplex, Method::Lscf { order: None }] {
        let fit = fit(&freqs, &h, &FitOptions { method, beam_refit: false, ..FitOptions::default() }).unwrap();
        let (ef, ez, _) = worst(&fit.modes, &truth);
        println!("{method:?}: max f error {ef:.2e}, max ζ error {ez:.2e}");
        assert!(ef < 1e-3, "{method:?}: f error {ef}");
        let bound = if method == Method::Simplex { 0.015 } else { 0.02 };
        assert!(ez <= bound, "{method:?}: ζ error {ez}");
    }
}
