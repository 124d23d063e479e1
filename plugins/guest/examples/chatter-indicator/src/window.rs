//! The Hann window of the spectrum, in a file of its own so the plugins benchmark compiles the
//! same code natively as the plugin's twin.

/// The record less its `mean`, under the Hann window `0.5 − 0.5 cos(2πi/n)`.
///
/// The cosines come from two short tables by angle addition,
/// cos((kB + j)θ) = cos(kBθ) cos(jθ) − sin(kBθ) sin(jθ) with blocks of B = 256: about 2n/B
/// sines and cosines instead of n, each value within a few ulp of the direct one.
pub fn windowed(samples: &[f64], mean: f64) -> Vec<f64> {
    const B: usize = 256;
    let n = samples.len();
    let theta = std::f64::consts::TAU / n as f64;
    let fine: Vec<(f64, f64)> = (0..B.min(n)).map(|j| (theta * j as f64).sin_cos()).collect();
    let mut buf = Vec::with_capacity(n);
    for (k, block) in samples.chunks(B).enumerate() {
        let (s, c) = (theta * (k * B) as f64).sin_cos();
        buf.extend(block.iter().zip(&fine).map(|(x, (sj, cj))| (x - mean) * (0.5 - 0.5 * (c * cj - s * sj))));
    }
    buf
}
