//! Cutting setup: teeth, radial immersion, milling direction and cutting force coefficients, with the
//! directional factors shared by the ZOA and the semi-discretization (convention in the [module docs](super)),
//! and the tool geometry: unequal (variable) tooth pitch and helical teeth.

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

/// Below this helix lag `ψ(a_p)` (rad) over the depth the helix average is taken as the straight tooth shifted by
/// `ψ/2` (the closed form divides by `ψ` and loses digits; the shift is exact to `O(ψ²)` where `H` is smooth).
const HELIX_LAG_EXACT_MIN: f64 = 1e-6;

/// Pitch angles within this of `2π/N` (rad) are equal pitch: the tool is stored as equally spaced.
const EQUAL_PITCH_TOLERANCE: f64 = 1e-9;

/// Largest helix lag per axial slice of the time-domain simulation ([`Milling::helix_slices`]), rad (1°).
pub const MAX_LAG_PER_SLICE: f64 = PI / 180.0;

/// A milling cut: teeth, radial immersion `a_e/D`, direction and coefficients, with the tool's geometry: the
/// pitch angles between the teeth (equal by default) and the helix angle with the tool diameter (straight teeth
/// by default).
///
/// Tooth `j` sits at `θ + θ_j` with `θ = Ωt` the rotation of tooth 0 and `θ_j = pitch_0 + … + pitch_{j−1}`
/// ([`Milling::tooth_offset`]): `pitch_j` is the angle from tooth `j` forward to tooth `j + 1` (mod N), the
/// tooth that passed the same angle `τ_j = pitch_j/Ω` earlier, so `τ_j` is tooth `j`'s regenerative delay. With
/// a helix angle `η` the edge at height `z` above the tool tip lags the tip by `ψ(z) = 2 z tan η/D`; over an
/// axial depth `a_p` the force matrix is the average over `z ∈ [0, a_p]` of the straight-tooth matrix at the
/// lagged angles, so the regenerative force stays `−a_p H̄(t) Δq` (Altintas, *Manufacturing Automation*, §3.3).
#[derive(Debug, Clone, PartialEq)]
pub struct Milling {
    /// Number of teeth `N`.
    pub teeth: usize,
    /// Radial immersion `a_e/D` in `(0, 1]`.
    pub radial_immersion: f64,
    /// Up- or down-milling.
    pub direction: MillingDirection,
    /// Cutting force coefficients.
    pub coefficients: CuttingCoefficients,
    /// Pitch angles (rad, summing to 2π), `None` for equal spacing.
    pitch: Option<Vec<f64>>,
    /// Helix angle `η`, rad (0: straight teeth).
    helix: f64,
    /// Tool diameter, m (0 without a helix).
    diameter: f64,
}

impl Milling {
    /// Checks the teeth and the immersion; equally spaced straight teeth.
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
        Ok(Milling { teeth, radial_immersion, direction, coefficients, pitch: None, helix: 0.0, diameter: 0.0 })
    }

    /// The same cut with the pitch angles `pitch` (rad): one per tooth, each finite and positive, summing to `2π`
    /// (within 1e-6 relative; they are scaled to sum to exactly `2π`). `pitch[j]` is the angle from tooth `j`
    /// forward to tooth `j + 1` (see [`Milling`]). Angles all within 1e-9 rad of `2π/N` are equal pitch.
    pub fn with_pitch(mut self, pitch: Vec<f64>) -> Result<Self, StabilityError> {
        if pitch.len() != self.teeth {
            return Err(StabilityError::InvalidParameter {
                name: "number of pitch angles",
                value: pitch.len() as f64,
                requirement: "one pitch angle per tooth (the angle from each tooth to the next)",
            });
        }
        if let Some(&p) = pitch.iter().find(|p| !(p.is_finite() && **p > 0.0 && **p <= TAU * (1.0 + 1e-6))) {
            return Err(StabilityError::InvalidParameter {
                name: "pitch angle (rad)",
                value: p,
                requirement: "finite, > 0 and ≤ 2π",
            });
        }
        let sum: f64 = pitch.iter().sum();
        if (sum - TAU).abs() > 1e-6 * TAU {
            return Err(StabilityError::InvalidParameter {
                name: "sum of the pitch angles (rad)",
                value: sum,
                requirement: "2π (360°): the pitch angles go once round the tool",
            });
        }
        let equal = TAU / self.teeth as f64;
        self.pitch = if pitch.iter().all(|p| (p - equal).abs() <= EQUAL_PITCH_TOLERANCE) {
            None
        } else {
            Some(pitch.iter().map(|p| p * (TAU / sum)).collect())
        };
        Ok(self)
    }

    /// [`Milling::with_pitch`] with the angles in degrees (summing to 360°).
    pub fn with_pitch_deg(self, pitch_deg: &[f64]) -> Result<Self, StabilityError> {
        self.with_pitch(pitch_deg.iter().map(|p| p.to_radians()).collect())
    }

    /// The same cut with helical teeth: helix angle `helix_rad` in `[0, π/2)` (0: straight teeth) on a tool of
    /// diameter `diameter_m` (finite, > 0), which sets the lag `ψ(z) = 2 z tan η/D` of the edge at height `z`.
    pub fn with_helix(mut self, helix_rad: f64, diameter_m: f64) -> Result<Self, StabilityError> {
        if !(helix_rad.is_finite() && (0.0..0.5 * PI).contains(&helix_rad)) {
            return Err(StabilityError::InvalidParameter {
                name: "helix angle (rad)",
                value: helix_rad,
                requirement: "in [0, π/2) (0° to below 90°)",
            });
        }
        if !(diameter_m.is_finite() && diameter_m > 0.0) {
            return Err(StabilityError::InvalidParameter {
                name: "tool diameter (m)",
                value: diameter_m,
                requirement: "finite and > 0 m (the helix lag is 2 z tan η/D)",
            });
        }
        self.helix = helix_rad;
        self.diameter = diameter_m;
        Ok(self)
    }

    /// True if the teeth are equally spaced (the default).
    pub fn has_equal_pitch(&self) -> bool {
        self.pitch.is_none()
    }

    /// The pitch angles, rad: `pitch[j]` from tooth `j` forward to tooth `j + 1` (all `2π/N` for equal pitch).
    pub fn pitch_angles(&self) -> Vec<f64> {
        match &self.pitch {
            Some(p) => p.clone(),
            None => vec![TAU / self.teeth as f64; self.teeth],
        }
    }

    /// Pitch angle of tooth `j` (its delay is this over `Ω`), rad.
    pub fn pitch_angle(&self, j: usize) -> f64 {
        match &self.pitch {
            Some(p) => p[j % self.teeth],
            None => TAU / self.teeth as f64,
        }
    }

    /// Angle of tooth `j` ahead of tooth 0, `θ_j = pitch_0 + … + pitch_{j−1}` (`2πj/N` for equal pitch), rad.
    pub fn tooth_offset(&self, j: usize) -> f64 {
        match &self.pitch {
            Some(p) => p[..j.min(self.teeth)].iter().sum(),
            None => TAU * j as f64 / self.teeth as f64,
        }
    }

    /// Helix angle, rad (0 for straight teeth).
    pub fn helix(&self) -> f64 {
        self.helix
    }

    /// Tool diameter, m, if a helix was given.
    pub fn diameter(&self) -> Option<f64> {
        (self.diameter > 0.0).then_some(self.diameter)
    }

    /// True if the teeth are helical (helix angle > 0).
    pub fn has_helix(&self) -> bool {
        self.helix > 0.0
    }

    /// Lag `ψ(a_p) = 2 a_p tan η/D` of the edge at the top of the cut behind the tool tip, rad (0 for straight
    /// teeth).
    pub fn helix_lag(&self, depth_m: f64) -> f64 {
        if self.helix > 0.0 { 2.0 * depth_m * self.helix.tan() / self.diameter } else { 0.0 }
    }

    /// Axial slices of the time-domain simulation at depth `depth_m`: enough that the helix lag across one slice
    /// is at most [`MAX_LAG_PER_SLICE`] (1°), at least 1 (straight teeth), at most 3600.
    pub fn helix_slices(&self, depth_m: f64) -> usize {
        let lag = self.helix_lag(depth_m);
        if lag > 0.0 && lag.is_finite() { ((lag / MAX_LAG_PER_SLICE).ceil() as usize).clamp(1, 3600) } else { 1 }
    }

    /// Entry and exit angles `(φ_st, φ_ex)`, rad, measured clockwise from `+y`.
    pub fn engagement(&self) -> (f64, f64) {
        let a = self.radial_immersion;
        match self.direction {
            MillingDirection::Up => (0.0, (1.0 - 2.0 * a).clamp(-1.0, 1.0).acos()),
            MillingDirection::Down => ((2.0 * a - 1.0).clamp(-1.0, 1.0).acos(), PI),
        }
    }

    /// Mean tooth passing period `τ = 60/(N n)`, s, at `n` rpm (the delay of every tooth for equal pitch).
    pub fn tooth_period(&self, speed_rpm: f64) -> f64 {
        60.0 / (self.teeth as f64 * speed_rpm)
    }

    /// Regenerative delay of tooth `j`, `τ_j = pitch_j/Ω`, s, at `n` rpm.
    pub fn tooth_delay(&self, j: usize, speed_rpm: f64) -> f64 {
        self.pitch_angle(j) / (TAU * speed_rpm / 60.0)
    }

    /// Specific cutting force matrix of one engaged tooth at angle `φ`: `h(φ) = (Kt t + Kn r) rᵀ` with
    /// `t = (cos φ, −sin φ)`, `r = (sin φ, cos φ)`, so that its force is `−a_p h(φ) Δq`.
    pub fn tooth_matrix(&self, phi: f64) -> [[f64; 2]; 2] {
        let (s, c) = phi.sin_cos();
        let CuttingCoefficients { kt, kn } = self.coefficients;
        let (gx, gy) = (kt * c + kn * s, -kt * s + kn * c);
        [[gx * s, gx * c], [gy * s, gy * c]]
    }

    /// `H(t)` of straight teeth at rotation angle `θ = Ωt` of tooth 0: the sum of [`Milling::tooth_matrix`] over
    /// the engaged teeth (tooth `j` at `θ + θ_j`), zero outside the cut (screen function). The helix is not
    /// applied: this is the limit of a vanishing depth; [`Milling::force_matrix_at`] averages over the depth.
    pub fn force_matrix(&self, theta: f64) -> [[f64; 2]; 2] {
        let (st, ex) = self.engagement();
        let mut h = [[0.0; 2]; 2];
        for j in 0..self.teeth {
            let phi = (theta + self.tooth_offset(j)).rem_euclid(TAU);
            if phi >= st && phi <= ex {
                add(&mut h, &self.tooth_matrix(phi));
            }
        }
        h
    }

    /// `H̄(t)` at axial depth `depth_m`: [`Milling::force_matrix`] averaged over the height `z ∈ [0, a_p]` of the
    /// cut, each height at its lagged angle `θ − ψ(z)`; exactly (the limit of infinitely many axial slices)
    /// `H̄(θ) = ∫_{θ−ψ}^{θ} H/ψ` with `ψ = ψ(a_p)`. Equal to [`Milling::force_matrix`] for straight teeth.
    pub fn force_matrix_at(&self, theta: f64, depth_m: f64) -> [[f64; 2]; 2] {
        let lag = self.helix_lag(depth_m);
        if lag == 0.0 {
            return self.force_matrix(theta);
        }
        if lag < HELIX_LAG_EXACT_MIN {
            return self.force_matrix(theta - 0.5 * lag);
        }
        let mut h = self.force_matrix_integral(theta - lag, theta);
        h.iter_mut().flatten().for_each(|v| *v /= lag);
        h
    }

    /// `∫ H dθ` over `θ ∈ [θa, θb]` (exact, engaged arcs only) for straight teeth, so that the mean of `H(t)` over
    /// a time step is `force_matrix_integral(Ωt_i, Ωt_{i+1}) / (Ω Δt)`.
    pub fn force_matrix_integral(&self, theta_a: f64, theta_b: f64) -> [[f64; 2]; 2] {
        let mut h = [[0.0; 2]; 2];
        for j in 0..self.teeth {
            self.tooth_integral(self.tooth_offset(j), theta_a, theta_b, &mut h);
        }
        h
    }

    /// `∫ H̄ dθ` over `θ ∈ [θa, θb]` at axial depth `depth_m`, the helix average of
    /// [`Milling::force_matrix_at`] included (exact); equal to [`Milling::force_matrix_integral`] for straight
    /// teeth.
    pub fn force_matrix_integral_at(&self, theta_a: f64, theta_b: f64, depth_m: f64) -> [[f64; 2]; 2] {
        let lag = self.helix_lag(depth_m);
        if lag == 0.0 {
            return self.force_matrix_integral(theta_a, theta_b);
        }
        let mut h = [[0.0; 2]; 2];
        for j in 0..self.teeth {
            self.helix_tooth_integral(self.tooth_offset(j), theta_a, theta_b, lag, &mut h);
        }
        h
    }

    /// Tooth `j`'s share of [`Milling::force_matrix_integral_at`]: `∫ H̄_j dθ` over `[θa, θb]` at depth
    /// `depth_m`, the tooth at `θ + θ_j`. The semi-discretization of variable pitch needs each tooth apart, as
    /// each has its own delay.
    pub fn tooth_force_integral(&self, j: usize, theta_a: f64, theta_b: f64, depth_m: f64) -> [[f64; 2]; 2] {
        let mut h = [[0.0; 2]; 2];
        let lag = self.helix_lag(depth_m);
        if lag == 0.0 {
            self.tooth_integral(self.tooth_offset(j), theta_a, theta_b, &mut h);
        } else {
            self.helix_tooth_integral(self.tooth_offset(j), theta_a, theta_b, lag, &mut h);
        }
        h
    }

    /// Adds `∫ h(θ + offset) dθ` over the engaged parts of `[θa, θb]` to `h`.
    fn tooth_integral(&self, offset: f64, theta_a: f64, theta_b: f64, h: &mut [[f64; 2]; 2]) {
        let (st, ex) = self.engagement();
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

    /// Adds `s ∫ (u − u0) h(u + offset) du` over the engaged parts of `[ua, ub]` to `h`.
    fn tooth_moment(&self, offset: f64, ua: f64, ub: f64, u0: f64, s: f64, h: &mut [[f64; 2]; 2]) {
        let (st, ex) = self.engagement();
        let (a, b) = (ua + offset, ub + offset);
        let first = ((a - ex) / TAU).floor() as i64;
        let last = ((b - st) / TAU).ceil() as i64;
        for l in first..=last {
            let base = TAU * l as f64;
            let lo = a.max(st + base);
            let hi = b.min(ex + base);
            if hi > lo {
                // In the arc's own angle φ = u + offset − base, u − u0 = φ − z with z = u0 + offset − base.
                let z = u0 + offset - base;
                let k = &self.coefficients;
                let (plo, phi) = (primitive(k, lo - base), primitive(k, hi - base));
                let (qlo, qhi) = (second_primitive(k, lo - base), second_primitive(k, hi - base));
                let (wlo, whi) = (lo - base - z, hi - base - z);
                for r in 0..2 {
                    for c in 0..2 {
                        h[r][c] += s * ((whi * phi[r][c] - qhi[r][c]) - (wlo * plo[r][c] - qlo[r][c]));
                    }
                }
            }
        }
    }

    /// Adds the helix-averaged `∫_{θa}^{θb} (1/ψ) ∫_{θ−ψ}^{θ} h(u + offset) du dθ = (1/ψ) ∫ w(u) h(u + offset) du`
    /// to `h`, `w(u) = |[θa, θb] ∩ [u, u + ψ]|` the trapezoid that rises with slope 1 from `θa − ψ`, is flat at
    /// `min(ψ, θb − θa)` and falls with slope 1 to `θb`.
    fn helix_tooth_integral(&self, offset: f64, theta_a: f64, theta_b: f64, lag: f64, h: &mut [[f64; 2]; 2]) {
        if lag < HELIX_LAG_EXACT_MIN {
            self.tooth_integral(offset, theta_a - 0.5 * lag, theta_b - 0.5 * lag, h);
            return;
        }
        let (c1, c2) = ((theta_b - lag).min(theta_a), (theta_b - lag).max(theta_a));
        let mut acc = [[0.0; 2]; 2];
        self.tooth_moment(offset, theta_a - lag, c1, theta_a - lag, 1.0, &mut acc);
        let mut mid = [[0.0; 2]; 2];
        self.tooth_integral(offset, c1, c2, &mut mid);
        let level = lag.min(theta_b - theta_a);
        self.tooth_moment(offset, c2, theta_b, theta_b, -1.0, &mut acc);
        for r in 0..2 {
            for c in 0..2 {
                h[r][c] += (acc[r][c] + level * mid[r][c]) / lag;
            }
        }
    }

    /// Altintas's directional factors `[α]` (*Manufacturing Automation*, Eq. 3.17): the integral over the
    /// engaged arc of `A(φ) = −2 h(φ)/Kt`, so that the time-averaged `H` is `H0 = −(N Kt/4π) [α]`. The pitch and
    /// the helix do not change this average.
    pub fn directional_factors(&self) -> [[f64; 2]; 2] {
        let (st, ex) = self.engagement();
        let (p, q) = (primitive(&self.coefficients, st), primitive(&self.coefficients, ex));
        let s = -2.0 / self.coefficients.kt;
        [[s * (q[0][0] - p[0][0]), s * (q[0][1] - p[0][1])], [s * (q[1][0] - p[1][0]), s * (q[1][1] - p[1][1])]]
    }
}

/// Antiderivative in `φ` of [`primitive`] (second antiderivative of [`Milling::tooth_matrix`]).
fn second_primitive(k: &CuttingCoefficients, phi: f64) -> [[f64; 2]; 2] {
    let (s2, c2) = (2.0 * phi).sin_cos();
    let (kt, kn) = (k.kt, k.kn);
    let half_sq = 0.5 * phi * phi;
    [
        [-0.125 * kt * s2 + 0.5 * kn * (half_sq + 0.25 * c2), 0.5 * kt * (half_sq - 0.25 * c2) - 0.125 * kn * s2],
        [-0.5 * kt * (half_sq + 0.25 * c2) - 0.125 * kn * s2, 0.125 * kt * s2 + 0.5 * kn * (half_sq - 0.25 * c2)],
    ]
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
