//! Inputs shared by the modal-fit benches: a modal receptance with seeded complex noise.

use spindlelab_engine::value::Mode;
use spindlelab_stdlib::rcsa::Complex64;
use std::f64::consts::TAU;

/// SplitMix64 step: a small deterministic generator, uniform in [0, 1).
fn next(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
}

/// Standard normal pair by Box–Muller.
fn gauss(state: &mut u64) -> (f64, f64) {
    let (u, v) = (next(state).max(1e-300), next(state));
    let r = (-2.0 * u.ln()).sqrt();
    (r * (TAU * v).cos(), r * (TAU * v).sin())
}

/// `Σ` of the modes' receptances on `freqs` (Hz) with complex noise `0.02|H|(n1 + i n2)/√2`, the
/// normals drawn from a SplitMix64 stream seeded with `seed`.
pub fn noisy_frf(modes: &[Mode], freqs: &[f64], seed: u64) -> Vec<Complex64> {
    let mut state = seed;
    freqs
        .iter()
        .map(|&f| {
            let v: Complex64 = modes.iter().map(|m| m.receptance(TAU * f)).sum();
            let (a, b) = gauss(&mut state);
            v + Complex64::new(a, b) * (0.02 * v.norm() / std::f64::consts::SQRT_2)
        })
        .collect()
}
