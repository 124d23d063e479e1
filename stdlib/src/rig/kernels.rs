//! Numeric building blocks of the virtual rig: a branch-free sine/cosine of an angle in
//! turns, the matrix exponential that discretises a mode exactly, and the modal chain that
//! returns the exact response to a piecewise-linear input at delayed instants.

use std::f64::consts::FRAC_PI_2;

/// `1.5·2^52`: adding and subtracting it rounds a double of magnitude below `2^51` to the
/// nearest integer with plain arithmetic (vectorisable, unlike `f64::round`).
const ROUND_MAGIC: f64 = 6_755_399_441_055_744.0;

// Minimax kernels of sin and cos on [−π/4, π/4] (the fdlibm/musl `__sin`/`__cos` coefficients).
const S1: f64 = -1.666_666_666_666_663_243_48e-1;
const S2: f64 = 8.333_333_333_322_489_461_24e-3;
const S3: f64 = -1.984_126_982_985_794_931_34e-4;
const S4: f64 = 2.755_731_370_707_006_767_89e-6;
const S5: f64 = -2.505_076_025_340_686_342_35e-8;
const S6: f64 = 1.589_690_995_211_550_102_21e-10;
const C1: f64 = 4.166_666_666_666_660_190_37e-2;
const C2: f64 = -1.388_888_888_887_410_957_49e-3;
const C3: f64 = 2.480_158_728_947_672_941_78e-5;
const C4: f64 = -2.755_731_435_139_066_330_35e-7;
const C5: f64 = 2.087_572_321_298_174_827_90e-9;
const C6: f64 = -1.135_964_755_778_819_482_65e-11;

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
        [
            self.phi[0][0] * x[0] + self.phi[0][1] * x[1] + self.a[0] * f0 + self.b[0] * f1,
            self.phi[1][0] * x[0] + self.phi[1][1] * x[1] + self.a[1] * f0 + self.b[1] * f1,
        ]
    }
}

/// One mode of a [`Chain`]: the full-interval step, the fractional step to the delayed
/// instant, and the scale from the state's second component back to a velocity.
#[derive(Debug, Clone, Copy)]
struct Section {
    full: Step,
    frac: Step,
    omega: f64,
}

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
        let sections: Vec<Section> = modes
            .iter()
            .map(|&(w, z, k)| Section { full: Step::new(w, z, k, h, h), frac: Step::new(w, z, k, h, span), omega: w })
            .collect();
        let states = vec![[0.0; 2]; sections.len()];
        Chain { sections, states, row: usize::from(velocity) }
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
            let d = p.phi[r][0] * x[0] + p.phi[r][1] * x[1] + p.a[r] * f0 + p.b[r] * f1;
            out += if r == 0 { d } else { d * s.omega };
            *x = s.full.apply(*x, f0, f1);
        }
        out
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
