//! The spectrum's computation, in a file of its own so the plugins benchmark compiles the
//! same code natively as the plugin's built-in twin.

use realfft::{FftError, RealFftPlanner};

/// The record less its `mean`, under the Hann window `0.5 − 0.5 cos(2πi/n)`.
///
/// The cosines come from two short tables by angle addition,
/// cos((kB + j)θ) = cos(kBθ) cos(jθ) − sin(kBθ) sin(jθ) with blocks of B = 256: about 2n/B
/// sines and cosines instead of n, each value within a few ulp of the direct one.
fn windowed(samples: &[f64], mean: f64) -> Vec<f64> {
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

/// Hann-windowed amplitudes of the record less its `mean` (lines 0..=n/2), scaled so a
/// sinusoid of amplitude `a` on a line reads `a`. A real-input transform: half the work and
/// half the plan of a complex one; the amplitudes take the place of the windowed record.
pub fn amplitudes(samples: &[f64], mean: f64, planner: &mut RealFftPlanner<f64>) -> Result<Vec<f64>, FftError> {
    let n = samples.len();
    let mut buf = windowed(samples, mean);
    let fft = planner.plan_fft_forward(n);
    let mut spectrum = fft.make_output_vec();
    fft.process(&mut buf, &mut spectrum)?;
    // The Hann window sums to n/2: gain 2/(n/2) for a one-sided amplitude.
    let gain = 4.0 / n as f64;
    buf.truncate(spectrum.len());
    for (a, c) in buf.iter_mut().zip(&spectrum) {
        *a = gain * c.norm();
    }
    buf[0] *= 0.5;
    buf.shrink_to_fit();
    Ok(buf)
}
