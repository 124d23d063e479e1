//! Numeric building blocks of the virtual rig: a branch-free sine/cosine of an angle in
//! turns, the matrix exponential that discretises a mode exactly, and the modal chain that
//! returns the exact response to a piecewise-linear input at delayed instants.

use std::f64::consts::FRAC_PI_2;

/// `1.5·2^52`: adding and subtracting it rounds a double of magnitude below `2^51` to the
/// nearest integer with plain arithmetic (vectorisable, unlike `f64::round`).
const ROUND_MAGIC: f64 = 6_755_399_441_055_744.0;

// Minimax kernels of sin and cos on [−π/4, π/4] (the fdlibm/musl `__sin`/`__cos` coefficients).
const S1: f64 = -1.666_666_666_666_663_2e-1;
const S2: f64 = 8.333_333_333_322_49e-3;
const S3: f64 = -1.984_126_982_985_795e-4;
const S4: f64 = 2.755_731_370_707_006_8e-6;
const S5: f64 = -2.505_076_025_340_686_3e-8;
const S6: f64 = 1.589_690_995_211_55e-10;
const C1: f64 = 4.166_666_666_666_66e-2;
const C2: f64 = -1.388_888_888_887_411e-3;
const C3: f64 = 2.480_158_728_947_673e-5;
const C4: f64 = -2.755_731_435_139_066_3e-7;
const C5: f64 = 2.087_572_321_298_175e-9;
const C6: f64 = -1.135_964_755_778_819_5e-11;

/// `(sin 2πx, cos 2πx)` for an angle `x` in turns (|x| < 2^51), to a few units in the last
/// place: the integer part of `x` is dropped exactly, the rest is evaluated at a quarter of
/// the angle with the minimax kernels and doubled twice. No branches, so loops over it
/// vectorise.
#[inline(always)]
pub(crate) fn sincos_turns(x: f64) -> (f64, f64) {
    let u = x - ((x + ROUND_MAGIC) - ROUND_MAGIC);
    let y = u * FRAC_PI_2;
    let y2 = y * y;
    let s = y + y * y2 * (S1 + y2 * (S2 + y2 * (S3 + y2 * (S4 + y2 * (S5 + y2 * S6)))));
    let c = 1.0 - 0.5 * y2 + y2 * y2 * (C1 + y2 * (C2 + y2 * (C3 + y2 * (C4 + y2 * (C5 + y2 * C6)))));
    let (s1, c1) = (2.0 * s * c, (c - s) * (c + s));
    (2.0 * s1 * c1, (c1 - s1) * (c1 + s1))
}

/// Fractional part of `x` in `[−0.5, 0.5]` (the nearest-integer remainder), exact.
#[inline(always)]
pub(crate) fn wrap_turns(x: f64) -> f64 {
    x - ((x + ROUND_MAGIC) - ROUND_MAGIC)
}

// fdlibm `__ieee754_log` constants.
const LN2_HI: f64 = 6.931_471_803_691_238e-1;
const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
const LG1: f64 = 6.666_666_666_666_735e-1;
const LG2: f64 = 3.999_999_999_940_942e-1;
const LG3: f64 = 2.857_142_874_366_239e-1;
const LG4: f64 = 2.222_219_843_214_978_4e-1;
const LG5: f64 = 1.818_357_216_161_805e-1;
const LG6: f64 = 1.531_383_769_920_937_3e-1;
const LG7: f64 = 1.479_819_860_511_658_6e-1;
/// Bits of 1.0.
const ONE_BITS: u64 = 0x3FF0_0000_0000_0000;
/// `2^52`: adding its bit pattern's integer to it turns a small integer into a double.
const TWO_52: f64 = 4_503_599_627_370_496.0;

/// Natural logarithm of a positive normal double, branch-free (fdlibm's reduction to
/// `[√2/2, √2]` and its degree-14 kernel; within an ulp or two).
#[inline(always)]
pub(crate) fn ln_positive(x: f64) -> f64 {
    let bits = x.to_bits();
    let exp = bits >> 52;
    let m = f64::from_bits((bits & 0x000F_FFFF_FFFF_FFFF) | ONE_BITS);
    let big = m > std::f64::consts::SQRT_2;
    let m = if big { 0.5 * m } else { m };
    let k = (f64::from_bits(0x4330_0000_0000_0000 | exp) - TWO_52) - 1023.0 + if big { 1.0 } else { 0.0 };
    let f = m - 1.0;
    let s = f / (2.0 + f);
    let z = s * s;
    let w = z * z;
    let t1 = w * (LG2 + w * (LG4 + w * LG6));
    let t2 = z * (LG1 + w * (LG3 + w * (LG5 + w * LG7)));
    let r = t2 + t1;
    let hfsq = 0.5 * f * f;
    k * LN2_HI - ((hfsq - (s * (hfsq + r) + k * LN2_LO)) - f)
}

/// Normals made per refill (a multiple of 8: four lanes, two normals per pair of draws).
const NORMAL_BATCH: usize = 512;

/// Seeded standard normal numbers, fast: four interleaved xoshiro256++ generators whose
/// lane-wise update vectorises, and the Box–Muller transform `√(−2 ln u1)·(cos, sin)(2π u2)`
/// evaluated in batches with the branch-free kernels above. The same seed gives the same
/// numbers with or without AVX2 (no fused multiply-add is used).
pub(crate) struct NormalSource {
    /// `s[word][lane]`.
    s: [[u64; 4]; 4],
    buf: Vec<f64>,
    pos: usize,
    avx2: bool,
}

impl NormalSource {
    pub(crate) fn new(seed: u64) -> NormalSource {
        let mut z = seed;
        let mut next = || {
            z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut x = z;
            x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            x ^ (x >> 31)
        };
        let mut s = [[0u64; 4]; 4];
        for lane in 0..4 {
            for word in s.iter_mut() {
                word[lane] = next();
            }
        }
        #[cfg(target_arch = "x86_64")]
        let avx2 = std::arch::is_x86_feature_detected!("avx2");
        #[cfg(not(target_arch = "x86_64"))]
        let avx2 = false;
        NormalSource { s, buf: vec![0.0; NORMAL_BATCH], pos: NORMAL_BATCH, avx2 }
    }

    /// Eight draws: two steps of the four lanes (state words held in locals, lane loops that
    /// vectorise).
    #[inline(always)]
    fn next8(&mut self) -> ([u64; 4], [u64; 4]) {
        let [mut s0, mut s1, mut s2, mut s3] = self.s;
        let mut out = [[0u64; 4]; 2];
        for o in out.iter_mut() {
            for l in 0..4 {
                let sum = s0[l].wrapping_add(s3[l]);
                o[l] = sum.rotate_left(23).wrapping_add(s0[l]);
                let t = s1[l] << 17;
                s2[l] ^= s0[l];
                s3[l] ^= s1[l];
                s1[l] ^= s2[l];
                s0[l] ^= s3[l];
                s2[l] ^= t;
                s3[l] = s3[l].rotate_right(19);
            }
        }
        self.s = [s0, s1, s2, s3];
        (out[0], out[1])
    }

    #[inline(always)]
    fn refill_body(&mut self) {
        let mut buf = std::mem::take(&mut self.buf);
        for chunk in buf.chunks_exact_mut(8) {
            let (a, b) = self.next8();
            for l in 0..4 {
                // u1 in (0, 1], u2 in [0, 1), 52 random bits each.
                let u1 = 2.0 - f64::from_bits((a[l] >> 12) | ONE_BITS);
                let u2 = f64::from_bits((b[l] >> 12) | ONE_BITS) - 1.0;
                let r = (-2.0 * ln_positive(u1)).sqrt();
                let (s, c) = sincos_turns(u2);
                chunk[l] = r * c;
                chunk[4 + l] = r * s;
            }
        }
        self.buf = buf;
        self.pos = 0;
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn refill_avx2(&mut self) {
        self.refill_body()
    }

    #[inline(never)]
    fn refill(&mut self) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: AVX2 support was detected when the source was made.
            unsafe { self.refill_avx2() };
            return;
        }
        self.refill_body()
    }

    /// The next standard normal number.
    #[inline(always)]
    pub(crate) fn next(&mut self) -> f64 {
        if self.pos == NORMAL_BATCH {
            self.refill();
        }
        let v = self.buf[self.pos];
        self.pos += 1;
        v
    }
}

type M4 = [[f64; 4]; 4];

fn mul4(a: &M4, b: &M4) -> M4 {
    let mut c = [[0.0; 4]; 4];
    for i in 0..4 {
        for k in 0..4 {
            let aik = a[i][k];
            for j in 0..4 {
                c[i][j] += aik * b[k][j];
            }
        }
    }
    c
}

/// Matrix exponential of a 4×4 matrix by scaling and squaring with a Taylor series
/// (norm scaled below 1/4, 20 terms: converged to round-off).
fn expm4(a: &M4) -> M4 {
    let norm = a.iter().map(|r| r.iter().map(|x| x.abs()).sum::<f64>()).fold(0.0, f64::max);
    let squarings = if norm > 0.25 { (norm / 0.25).log2().ceil() as i32 } else { 0 };
    let scale = 0.5f64.powi(squarings);
    let mut b = *a;
    for row in b.iter_mut() {
        for x in row.iter_mut() {
            *x *= scale;
        }
    }
    // Horner: I + b(I + b/2(I + b/3(...))).
    let mut e = identity4();
    for n in (1..=20).rev() {
        let mut t = mul4(&b, &e);
        for row in t.iter_mut() {
            for x in row.iter_mut() {
                *x /= n as f64;
            }
        }
        for (i, row) in t.iter_mut().enumerate() {
            row[i] += 1.0;
        }
        e = t;
    }
    for _ in 0..squarings {
        e = mul4(&e, &e);
    }
    e
}

fn identity4() -> M4 {
    let mut m = [[0.0; 4]; 4];
    for (i, row) in m.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    m
}

/// One exact step of a mode over `span` for an input that is linear over the full sample
/// interval `h`: `x(span) = Φ x0 + a·F0 + b·F1` with `F0`, `F1` the input at the interval's
/// two ends. The state is `(q, q̇/ω)`, scaled so the step matrices stay well conditioned.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Step {
    phi: [[f64; 2]; 2],
    a: [f64; 2],
    b: [f64; 2],
}

impl Step {
    /// Exact step of `q̈ + 2ζω q̇ + ω² q = (ω²/k) F` over `span` with `F` linear over `h`,
    /// from the exponential of the augmented system `(q, q̇/ω, F, dF/dt)`.
    pub(crate) fn new(omega: f64, zeta: f64, stiffness: f64, h: f64, span: f64) -> Step {
        let m: M4 = [
            [0.0, omega * span, 0.0, 0.0],
            [-omega * span, -2.0 * zeta * omega * span, omega / stiffness * span, 0.0],
            [0.0, 0.0, 0.0, span],
            [0.0, 0.0, 0.0, 0.0],
        ];
        let e = expm4(&m);
        // x(span) = E[..2][..2] x0 + E[..2][2] F0 + E[..2][3] (F1 − F0)/h.
        Step {
            phi: [[e[0][0], e[0][1]], [e[1][0], e[1][1]]],
            a: [e[0][2] - e[0][3] / h, e[1][2] - e[1][3] / h],
            b: [e[0][3] / h, e[1][3] / h],
        }
    }

    #[inline(always)]
    fn apply(&self, x: [f64; 2], f0: f64, f1: f64) -> [f64; 2] {
        // The input terms first: they do not wait for the state.
        [
            (self.a[0] * f0 + self.b[0] * f1) + (self.phi[0][0] * x[0] + self.phi[0][1] * x[1]),
            (self.a[1] * f0 + self.b[1] * f1) + (self.phi[1][0] * x[0] + self.phi[1][1] * x[1]),
        ]
    }
}

/// One mode of a [`Chain`]: the full-interval step, the fractional step to the delayed
/// instant, the scale from the state's second component back to a velocity, and for runs
/// without input the output row of `frac·Φ^i` for `i < BLOCK` and `Φ^BLOCK`.
#[derive(Debug, Clone)]
struct Section {
    full: Step,
    frac: Step,
    omega: f64,
    free_out: Vec<[f64; 2]>,
    free_end: [[f64; 2]; 2],
}

fn mul2(a: &[[f64; 2]; 2], b: &[[f64; 2]; 2]) -> [[f64; 2]; 2] {
    [
        [a[0][0] * b[0][0] + a[0][1] * b[1][0], a[0][0] * b[0][1] + a[0][1] * b[1][1]],
        [a[1][0] * b[0][0] + a[1][1] * b[1][0], a[1][0] * b[0][1] + a[1][1] * b[1][1]],
    ]
}

impl Section {
    fn new(w: f64, z: f64, k: f64, h: f64, span: f64, row: usize) -> Section {
        let full = Step::new(w, z, k, h, h);
        let frac = Step::new(w, z, k, h, span);
        let scale = if row == 0 { 1.0 } else { w };
        let mut power = [[1.0, 0.0], [0.0, 1.0]];
        let mut free_out = Vec::with_capacity(BLOCK);
        for _ in 0..BLOCK {
            let m = mul2(&frac.phi, &power);
            free_out.push([m[row][0] * scale, m[row][1] * scale]);
            power = mul2(&full.phi, &power);
        }
        Section { full, frac, omega: w, free_out, free_end: power }
    }
}

/// Samples per block of the rig's probe synthesis.
pub(crate) const BLOCK: usize = 256;

/// Modes driven by one sampled input that is linear between samples. Each call of
/// [`Chain::step`] with the inputs `F_j`, `F_{j+1}` returns the summed displacement (or
/// velocity) at `t_j + span` (the delayed output instant) and advances every mode from
/// `t_j` to `t_{j+1}`; both are exact for the piecewise-linear input.
#[derive(Debug, Clone)]
pub(crate) struct Chain {
    sections: Vec<Section>,
    states: Vec<[f64; 2]>,
    /// Row of the fractional step that gives the output: 0 displacement, 1 velocity.
    row: usize,
}

impl Chain {
    /// Modes `(ω rad/s, ζ, k N/m)` sampled every `h` s, with outputs `span ∈ (0, h]` after
    /// each sample instant: displacements, or velocities when `velocity` is set.
    pub(crate) fn new(modes: &[(f64, f64, f64)], h: f64, span: f64, velocity: bool) -> Chain {
        let row = usize::from(velocity);
        let sections: Vec<Section> = modes.iter().map(|&(w, z, k)| Section::new(w, z, k, h, span, row)).collect();
        let states = vec![[0.0; 2]; sections.len()];
        Chain { sections, states, row }
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.sections.is_empty()
    }

    /// Sets the state of mode `i` to displacement `q` and scaled velocity `q̇/ω`.
    pub(crate) fn set_state(&mut self, i: usize, q: f64, v_scaled: f64) {
        self.states[i] = [q, v_scaled];
    }

    /// Output at `t_j + span`, then advance to `t_{j+1}`.
    #[inline(always)]
    pub(crate) fn step(&mut self, f0: f64, f1: f64) -> f64 {
        let r = self.row;
        let mut out = 0.0;
        for (s, x) in self.sections.iter().zip(self.states.iter_mut()) {
            let p = &s.frac;
            let d = (p.a[r] * f0 + p.b[r] * f1) + (p.phi[r][0] * x[0] + p.phi[r][1] * x[1]);
            out += if r == 0 { d } else { d * s.omega };
            *x = s.full.apply(*x, f0, f1);
        }
        out
    }

    /// The next [`BLOCK`] outputs with no input (exact: `frac·Φ^i` applied to the state),
    /// written to `out`; advances the states by the block.
    #[inline(always)]
    pub(crate) fn free_block(&mut self, out: &mut [f64; BLOCK]) {
        out.fill(0.0);
        for (s, x) in self.sections.iter().zip(self.states.iter_mut()) {
            let (x0, x1) = (x[0], x[1]);
            for (o, c) in out.iter_mut().zip(&s.free_out) {
                *o += c[0] * x0 + c[1] * x1;
            }
            let e = &s.free_end;
            *x = [e[0][0] * x0 + e[0][1] * x1, e[1][0] * x0 + e[1][1] * x1];
        }
    }

    /// Stationary covariance of `(q, q̇/ω, F_j)` of a single-mode chain driven by independent
    /// unit-variance input samples (discrete Lyapunov equation by doubling), the sampled
    /// process the asynchronous error motion is made of.
    pub(crate) fn stationary_covariance(&self) -> [[f64; 3]; 3] {
        let s = &self.sections[0].full;
        // z_{j+1} = A z_j + g w_{j+1}, z = (q, v, w).
        let mut a = [[s.phi[0][0], s.phi[0][1], s.a[0]], [s.phi[1][0], s.phi[1][1], s.a[1]], [0.0, 0.0, 0.0]];
        let g = [s.b[0], s.b[1], 1.0];
        let mut p = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                p[i][j] = g[i] * g[j];
            }
        }
        for _ in 0..64 {
            // P ← P + A P Aᵀ, A ← A².
            let ap = mul3(&a, &p);
            let apat = mul3_t(&ap, &a);
            let mut change = 0.0f64;
            for i in 0..3 {
                for j in 0..3 {
                    p[i][j] += apat[i][j];
                    change = change.max(apat[i][j].abs());
                }
            }
            a = mul3(&a, &a);
            if change <= 1e-18 * p[0][0].abs().max(f64::MIN_POSITIVE) {
                break;
            }
        }
        p
    }
}

fn mul3(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for k in 0..3 {
            for j in 0..3 {
                c[i][j] += a[i][k] * b[k][j];
            }
        }
    }
    c
}

/// `a bᵀ`.
fn mul3_t(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..3 {
                c[i][j] += a[i][k] * b[j][k];
            }
        }
    }
    c
}

/// Lower Cholesky factor of a symmetric positive semi-definite 3×3 matrix (non-positive
/// pivots, from round-off, give a zero column).
pub(crate) fn cholesky3(p: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut l = [[0.0; 3]; 3];
    for j in 0..3 {
        let d = p[j][j] - (0..j).map(|k| l[j][k] * l[j][k]).sum::<f64>();
        if d <= 0.0 {
            continue;
        }
        let ljj = d.sqrt();
        l[j][j] = ljj;
        for i in j + 1..3 {
            l[i][j] = (p[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>()) / ljj;
        }
    }
    l
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    #[test]
    fn sincos_turns_matches_libm() {
        let mut worst = 0.0f64;
        let mut norm = 0.0f64;
        for i in 0..200_000 {
            let x = (i as f64 - 100_000.0) * 0.012_345_678_9 + 1e-3 * (i as f64).sin();
            let (s, c) = sincos_turns(x);
            let a = TAU * wrap_turns(x);
            worst = worst.max((s - a.sin()).abs()).max((c - a.cos()).abs());
            norm = norm.max((s * s + c * c - 1.0).abs());
        }
        assert!(worst < 2e-15 && norm < 4e-15, "worst error {worst}, norm {norm}");
        // Exact quadrant points.
        assert_eq!(sincos_turns(0.0), (0.0, 1.0));
        assert!((sincos_turns(0.25).0 - 1.0).abs() < 1e-15 && sincos_turns(0.25).1.abs() < 1e-15);
        assert!((sincos_turns(-1e6 + 0.5).1 + 1.0).abs() < 1e-15);
    }

    #[test]
    fn ln_matches_libm() {
        let mut worst = 0.0f64;
        for i in 1..200_000u64 {
            let x = f64::from_bits(0x3CB0_0000_0000_0000 + i * 0x0000_3A5F_27C1_9D3B);
            if !(x > 0.0 && x <= 1.0) {
                continue;
            }
            let rel = (ln_positive(x) - x.ln()).abs() / x.ln().abs().max(1e-300);
            worst = worst.max(rel);
        }
        assert!(worst < 4e-16, "{worst}");
        assert_eq!(ln_positive(1.0), 0.0);
        assert!((ln_positive(2.0f64.powi(-52)) + 52.0 * std::f64::consts::LN_2).abs() < 1e-13);
    }

    #[test]
    fn normal_source_is_standard_normal() {
        let mut g = NormalSource::new(42);
        let n = 2_000_000;
        let x: Vec<f64> = (0..n).map(|_| g.next()).collect();
        let nf = n as f64;
        let mean = x.iter().sum::<f64>() / nf;
        let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / nf;
        let skew = x.iter().map(|v| (v - mean).powi(3)).sum::<f64>() / nf / var.powf(1.5);
        let kurt = x.iter().map(|v| (v - mean).powi(4)).sum::<f64>() / nf / (var * var);
        assert!(mean.abs() < 4.0 / nf.sqrt(), "mean {mean}");
        assert!((var - 1.0).abs() < 4.0 * (2.0 / nf).sqrt(), "var {var}");
        assert!(skew.abs() < 4.0 * (6.0 / nf).sqrt(), "skew {skew}");
        assert!((kurt - 3.0).abs() < 4.0 * (24.0 / nf).sqrt(), "kurtosis {kurt}");
        // Cumulative frequencies at a few points against Φ (erf by its series).
        for (z, phi) in
            [(-3.0, 0.001_349_898), (-1.5, 0.066_807_201), (0.0, 0.5), (0.7, 0.758_036_348), (2.5, 0.993_790_335)]
        {
            let p = x.iter().filter(|v| **v < z).count() as f64 / nf;
            let sd = (phi * (1.0 - phi) / nf).sqrt();
            assert!((p - phi).abs() < 4.5 * sd, "P(x < {z}) = {p}, expected {phi}");
        }
        // Consecutive values (across lanes and the two Box–Muller outputs) are uncorrelated.
        for lag in [1, 4, 8] {
            let c = x.windows(lag + 1).map(|w| w[0] * w[lag]).sum::<f64>() / nf;
            assert!(c.abs() < 4.0 / nf.sqrt(), "lag {lag}: {c}");
        }
        // Seeds: same numbers again, different for another seed.
        let mut a = NormalSource::new(7);
        let mut b = NormalSource::new(7);
        let mut c = NormalSource::new(8);
        let va: Vec<u64> = (0..1000).map(|_| a.next().to_bits()).collect();
        let vb: Vec<u64> = (0..1000).map(|_| b.next().to_bits()).collect();
        let vc: Vec<u64> = (0..1000).map(|_| c.next().to_bits()).collect();
        assert_eq!(va, vb);
        assert_ne!(va, vc);
        // The vectorised and the plain refill agree bit for bit.
        let mut plain = NormalSource::new(9);
        plain.avx2 = false;
        let mut fast = NormalSource::new(9);
        for _ in 0..5000 {
            assert_eq!(plain.next().to_bits(), fast.next().to_bits());
        }
    }

    #[test]
    fn expm_matches_closed_form_oscillator() {
        // Free undamped oscillator: exp([[0, w],[−w, 0]] t) is a rotation by w t.
        let (w, t) = (2.0e4, 3.3e-3);
        let m = [[0.0, w * t, 0.0, 0.0], [-w * t, 0.0, 0.0, 0.0], [0.0; 4], [0.0; 4]];
        let e = expm4(&m);
        assert!((e[0][0] - (w * t).cos()).abs() < 1e-12);
        assert!((e[0][1] - (w * t).sin()).abs() < 1e-12);
        assert!((e[1][0] + (w * t).sin()).abs() < 1e-12);
        assert!((e[2][2] - 1.0).abs() < 1e-15 && e[3][3] == 1.0);
    }

    #[test]
    fn step_gives_static_deflection_and_free_decay() {
        let (w, z, k, h) = (TAU * 700.0, 0.03, 2.0e7, 1.0e-5);
        let s = Step::new(w, z, k, h, h);
        // A constant force held for a long time settles at F/k.
        let mut x = [0.0, 0.0];
        for _ in 0..200_000 {
            x = s.apply(x, 1.0e3, 1.0e3);
        }
        assert!((x[0] - 1.0e3 / k).abs() < 1e-12 * 1.0e3 / k, "{}", x[0]);
        // Free decay from q0 after n steps matches the closed-form damped response.
        let mut x = [1.0, 0.0];
        let n = 137;
        for _ in 0..n {
            x = s.apply(x, 0.0, 0.0);
        }
        let t = n as f64 * h;
        let wd = w * (1.0 - z * z).sqrt();
        let q = (-z * w * t).exp() * ((wd * t).cos() + z * w / wd * (wd * t).sin());
        assert!((x[0] - q).abs() < 1e-13, "{} vs {q}", x[0]);
    }
}
