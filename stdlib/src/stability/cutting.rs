//! Cutting setup: teeth, radial immersion, milling direction and cutting force coefficients, with the
//! directional factors shared by the ZOA and the semi-discretization (convention in the [module docs](super)).

use super::StabilityError;
use std::f64::consts::{PI, TAU};

/// Up- or down-milling (conventional or climb).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MillingDirection {
    /// The tooth enters at zero chip thickness: `φ ∈ [0, arccos(1 − 2a_e/D)]`.
    Up,
    /// The tooth leaves at zero chip thickness: `φ ∈ [arccos(2a_e/D − 1), π]`.
    Down,
}

/// Linear cutting force coefficients (force per chip area), N/m².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CuttingCoefficients {
    /// Tangential coefficient `Kt`, N/m².
    pub kt: f64,
    /// Normal (radial) coefficient `Kn`, N/m².
    pub kn: f64,
}

impl CuttingCoefficients {
    /// From `Kt` and `Kn` directly; `Kt` must be positive and `Kn` finite.
    pub fn from_kt_kn(kt: f64, kn: f64) -> Result<Self, StabilityError> {
        if !(kt.is_finite() && kt > 0.0) {
            return Err(StabilityError::InvalidParameter {
                name: "Kt", value: kt, requirement: "finite and > 0 N/m²"
            });
        }
        if !kn.is_finite() {
            return Err(StabilityError::InvalidParameter { name: "Kn", value: kn, requirement: "finite (N/m²)" });
        }
        Ok(CuttingCoefficients { kt, kn })
    }

    /// From the specific cutting force `Ks` (N/m²) and the force angle `β` (rad) of the dissertation (§6.1):
    /// `Kt = Ks sin β`, `Kn = Ks cos β`.
    pub fn from_ks_beta(ks: f64, beta_rad: f64) -> Result<Self, StabilityError> {
        if !(ks.is_finite() && ks > 0.0) {
            return Err(StabilityError::InvalidParameter {
                name: "Ks", value: ks, requirement: "finite and > 0 N/m²"
            });
        }
        if !(beta_rad.is_finite() && beta_rad > 0.0 && beta_rad < PI) {
            return Err(StabilityError::InvalidParameter {
                name: "β",
                value: beta_rad,
                requirement: "in (0, π) rad so that Kt = Ks sin β > 0",
            });
        }
        Self::from_kt_kn(ks * beta_rad.sin(), ks * beta_rad.cos())
    }

    /// `Kr = Kn / Kt`.
    pub fn kr(&self) -> f64 {
        self.kn / self.kt
    }
}

/// A milling cut: teeth (equally spaced, no helix), radial immersion `a_e/D`, direction and coefficients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Milling {
    /// Number of teeth `N`.
    pub teeth: usize,
    /// Radial immersion `a_e/D` in `(0, 1]`.
    pub radial_immersion: f64,
    /// Up- or down-milling.
    pub direction: MillingDirection,
    /// Cutting force coefficients.
    pub coefficients: CuttingCoefficients,
}

impl Milling {
    /// Checks the teeth and the immersion.
    pub fn new(
        teeth: usize,
        radial_immersion: f64,
        direction: MillingDirection,
        coefficients: CuttingCoefficients,
    ) -> Result<Self, StabilityError> {
        if teeth == 0 {
            return Err(StabilityError::NoTeeth);
        }
        if !(radial_immersion.is_finite() && radial_immersion > 0.0 && radial_immersion <= 1.0) {
            return Err(StabilityError::Immersion(radial_immersion));
        }
        Ok(Milling { teeth, radial_immersion, direction, coefficients })
    }

    /// Entry and exit angles `(φ_st, φ_ex)`, rad, measured clockwise from `+y`.
    pub fn engagement(&self) -> (f64, f64) {
        let a = self.radial_immersion;
        match self.direction {
            MillingDirection::Up => (0.0, (1.0 - 2.0 * a).clamp(-1.0, 1.0).acos()),
            MillingDirection::Down => ((2.0 * a - 1.0).clamp(-1.0, 1.0).acos(), PI),
        }
    }

    /// Tooth passing period `τ = 60/(N n)`, s, at `n` rpm.
    pub fn tooth_period(&self, speed_rpm: f64) -> f64 {
        60.0 / (self.teeth as f64 * speed_rpm)
    }

    /// Specific cutting force matrix of one engaged tooth at angle `φ`: `h(φ) = (Kt t + Kn r) rᵀ` with
    /// `t = (cos φ, −sin φ)`, `r = (sin φ, cos φ)`, so that its force is `−a_p h(φ) Δq`.
    pub fn tooth_matrix(&self, phi: f64) -> [[f64; 2]; 2] {
        let (s, c) = phi.sin_cos();
        let CuttingCoefficients { kt, kn } = self.coefficients;
        let (gx, gy) = (kt * c + kn * s, -kt * s + kn * c);
        [[gx * s, gx * c], [gy * s, gy * c]]
    }

    /// `H(t)` at rotation angle `θ = Ωt` of tooth 0: the sum of [`Milling::tooth_matrix`] over the engaged teeth
    /// (tooth `j` at `θ + 2πj/N`), zero outside the cut (screen function).
    pub fn force_matrix(&self, theta: f64) -> [[f64; 2]; 2] {
        let (st, ex) = self.engagement();
        let mut h = [[0.0; 2]; 2];
        for j in 0..self.teeth {
            let phi = (theta + TAU * j as f64 / self.teeth as f64).rem_euclid(TAU);
            if phi >= st && phi <= ex {
                add(&mut h, &self.tooth_matrix(phi));
            }
        }
        h
    }

    /// `∫ H dθ` over `θ ∈ [θa, θb]` (exact, engaged arcs only), so that the mean of `H(t)` over a time step is
    /// `force_matrix_integral(Ωt_i, Ωt_{i+1}) / (Ω Δt)`.
    pub fn force_matrix_integral(&self, theta_a: f64, theta_b: f64) -> [[f64; 2]; 2] {
        let (st, ex) = self.engagement();
        let mut h = [[0.0; 2]; 2];
        for j in 0..self.teeth {
            let offset = TAU * j as f64 / self.teeth as f64;
            let (a, b) = (theta_a + offset, theta_b + offset);
            let first = ((a - ex) / TAU).floor() as i64;
            let last = ((b - st) / TAU).ceil() as i64;
            for l in first..=last {
                let base = TAU * l as f64;
                let lo = a.max(st + base);
                let hi = b.min(ex + base);
                if hi > lo {
                    let (p, q) = (primitive(&self.coefficients, lo - base), primitive(&self.coefficients, hi - base));
                    for r in 0..2 {
                        for c in 0..2 {
                            h[r][c] += q[r][c] - p[r][c];
                        }
                    }
                }
            }
        }
        h
    }

    /// Altintas's directional factors `[α]` (*Manufacturing Automation*, Eq. 3.17): the integral over the
    /// engaged arc of `A(φ) = −2 h(φ)/Kt`, so that the time-averaged `H` is `H0 = −(N Kt/4π) [α]`.
    pub fn directional_factors(&self) -> [[f64; 2]; 2] {
        let (st, ex) = self.engagement();
        let (p, q) = (primitive(&self.coefficients, st), primitive(&self.coefficients, ex));
        let s = -2.0 / self.coefficients.kt;
        [[s * (q[0][0] - p[0][0]), s * (q[0][1] - p[0][1])], [s * (q[1][0] - p[1][0]), s * (q[1][1] - p[1][1])]]
    }
}

/// Antiderivative in `φ` of [`Milling::tooth_matrix`].
fn primitive(k: &CuttingCoefficients, phi: f64) -> [[f64; 2]; 2] {
    let (s2, c2) = (2.0 * phi).sin_cos();
    let (kt, kn) = (k.kt, k.kn);
    [
        [-0.25 * kt * c2 + 0.5 * kn * (phi - 0.5 * s2), 0.5 * kt * (phi + 0.5 * s2) - 0.25 * kn * c2],
        [-0.5 * kt * (phi - 0.5 * s2) - 0.25 * kn * c2, 0.25 * kt * c2 + 0.5 * kn * (phi + 0.5 * s2)],
    ]
}

fn add(a: &mut [[f64; 2]; 2], b: &[[f64; 2]; 2]) {
    for r in 0..2 {
        for c in 0..2 {
            a[r][c] += b[r][c];
        }
    }
}
