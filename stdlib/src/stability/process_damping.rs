//! Process damping at low spindle speed in the zero-order (ZOA) stability limit. Below a few thousand rpm the
//! flank of the tool rubs the wavy surface it cut a tooth period ago, and that indentation damps the vibration:
//! measured limits rise far above the lobes. The linear model of Wu (1989, ASME J. Eng. Ind. 111:37–47) and
//! Chiou & Liang (1998, Int. J. Mach. Tools Manuf. 38:315–327), used by Altintas, Eynian & Onozuka (2008,
//! CIRP Annals 57:371–374), Budak & Tunc (2010, CIRP Annals 59:403–408) and Tyler & Schmitz (2013, J. Manuf.
//! Processes 15:69–76), is a viscous force along the surface normal
//!
//! `F_d = −(C b/V) ṅ`, `C = K_d w²/4`, `V = π D n/60`,
//!
//! with `K_d` the specific indentation force (N/m³), `w` the flank wear land (the flank–surface contact width,
//! m), `b` the axial depth, `V` the cutting speed and `ṅ` the tool velocity along the surface normal (Schmitz &
//! Smith, *Machining Dynamics*, 2nd ed., §4.8, Eq. 4.108: `F_d = C b ṅ/v`). The damping grows with the depth and
//! falls with the speed.
//!
//! **Distribution over the cut.** Each engaged tooth rubs along its own surface normal, the radial direction
//! `r = (sin φ, cos φ)` of the [force convention](super), so tooth `j` adds the force `−(C b/V) r_j r_jᵀ q̇`. The
//! ZOA averages the periodic force matrix over the tooth period; averaged alike, the damping matrix is
//! `D = (C b/V) E` with `E = (N/2π) ∫ r rᵀ dφ` over the engaged arc ([`engagement_matrix`]): `N*⟨r rᵀ⟩`, the mean
//! number of teeth in the cut times the arc average of the normal projector. Schmitz & Smith's Eqs. 4.113–4.116
//! instead put one tooth at the average angle `φ_ave` and keep only the diagonal, `c sin²φ_ave` along x and
//! `c cos²φ_ave` along y: for a four-tooth slot both give `C b/V` along the feed (theirs none along y), but at low
//! immersion, where `N* < 1`, theirs assumes a tooth always in the cut, and in a partial cut their diagonal also
//! damps motion along the mean tangent, which the normal force does not (their whole method is available as
//! [`ProcessDampingFormulation::AverageToothAngle`], below). `E` is in general full (off the slot
//! `⟨sin φ cos φ⟩ ≠ 0`), so the damper is added to the full 2×2 receptance matrix: in parallel at the tool point,
//! `G'⁻¹ = G⁻¹ + iω D`, computed per line as `G' = (I + iω G D)⁻¹ G` (no inverse of `G` needed). A strong damper
//! along the mean normal then mostly locks that direction and leaves the tangential one, so on a tool flexible
//! in both directions the gain at low speed is smaller than on a tool flexible along the normal only.
//!
//! **The fixed point.** `D` depends on the depth, so at each speed `n` the limit is the smallest depth `b` with
//! `b = L(n, b)`, `L(n, b)` the ZOA limit at `n` of the FRF damped by `D(b)`: the first depth, coming up from
//! zero, where a root of the characteristic equation reaches the imaginary axis. Schmitz & Smith (§4.8.2) iterate
//! `b_{k+1} = L(b_k)` from the undamped limit until it settles. Here the residual `h(b) = L(b) − b`
//! (`h(0) = b₀`, the undamped limit) is driven to zero by secant steps from below, with the plain fixed-point
//! step `b + h(b) = L(b)` where the secant slope is not negative, and regula falsi (Illinois) once a step lands
//! past the root (`h < 0`).
//! Where `L` grows with the damping and `h` is convex in `b` (for one mode in the dense-lobe range
//! `L ≈ 2kζ'(1 + ζ')/K` with `ζ'` linear in `b`), every secant step from the left stays left of the smallest
//! root, so the iterates rise monotonically to it and never jump over it; the checks on `h` keep the method
//! safe where that does not hold. When no root exists (the damping grows faster than the depth it must
//! stabilise, at the lowest speeds) the steps run past [`ProcessDampingOptions::max_depth_m`] and the limit is
//! `+∞`: the linear model gives no finite depth there.
//!
//! **The textbook's formulation.** [`ProcessDampingFormulation::AverageToothAngle`] replaces the ZOA and `E` by
//! Tlusty's average-tooth-angle method as Schmitz & Smith use it for process damping (*Machining Dynamics*,
//! §4.8; their converging analysis): one tooth at `φ_ave = (φ_st + φ_ex)/2` stands for the
//! `N* = N(φ_ex − φ_st)/2π` teeth in the cut. That is the midpoint rule for the ZOA's directional factors,
//! `[α] ≈ (φ_ex − φ_st) A(φ_ave)` with `A = −2h/Kt` ([`average_tooth_angle_factors`]), a rank-one matrix
//! `−(2 Ks/Kt)(φ_ex − φ_st) u rᵀ` (`u = (Kn r + Kt t)/Ks` the force direction, `t = (cos φ, −sin φ)`), whose one
//! non-zero eigenvalue turns the ZOA depth `2π/(N Kt Re λ)` into the scalar limit
//! `b_lim = −1/(2 Ks N* Re Φ_or)` of the oriented FRF `Φ_or = rᵀΦu = μ_x Φxx + μ_y Φyy` (plus
//! `r_x u_y Φxy + r_y u_x Φyx` with cross terms), `μ_x = sin(φ_ave + β) sin φ_ave`,
//! `μ_y = cos(φ_ave + β) cos φ_ave` — their `cos(β − (90° − φ_ave)) cos(90° − φ_ave)` and
//! `cos((180° − φ_ave) − β) cos(180° − φ_ave)`. The damping is their diagonal,
//! `D = (C b/V) diag(sin²φ_ave, cos²φ_ave)` ([`average_tooth_angle_damping`]). The lobes, the damper in
//! parallel and the fixed point are the same as above. For a partial cut this scalar method can sit far from the
//! coupled ZOA, whose arc-integrated factors couple x and y and have complex eigenvalues: in the textbook's 50 %
//! up-milling case (`textbook_case.rs`) its lobes' minimum is 2.2 times as deep, and SD and a time-domain model
//! side with the coupled ZOA. It is there to compare with the textbook, not as the better estimate.

use super::StabilityError;
use super::cutting::Milling;
use super::zoa::{
    FrfSlices, LimitScratch, StabilityLimit, ToolPointFrf, ZoaOptions, band_top_hz, limit_at_speed_oriented,
    line_roots_oriented, lobe_count, lobes_needed, refine,
};
use num_complex::Complex64;
use rayon::prelude::*;
use std::f64::consts::{PI, TAU};

#[cfg(test)]
mod tests;

#[cfg(test)]
mod textbook_case;

/// The flank–surface contact of the process damping model: `C = K_d w²/4` with the tool diameter for the cutting
/// speed (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProcessDamping {
    /// Specific indentation force `K_d`, N/m³ (force per indented volume).
    pub indentation_n_per_m3: f64,
    /// Flank wear land `w`: the width of the flank that contacts the wavy surface, m.
    pub wear_land_m: f64,
    /// Tool diameter `D`, m: the cutting speed is `V = π D n/60`.
    pub diameter_m: f64,
}

impl ProcessDamping {
    /// Checked parameters: each finite and positive.
    pub fn new(indentation_n_per_m3: f64, wear_land_m: f64, diameter_m: f64) -> Result<Self, StabilityError> {
        let pd = ProcessDamping { indentation_n_per_m3, wear_land_m, diameter_m };
        pd.validate()?;
        Ok(pd)
    }

    /// Refuses a non-finite or non-positive parameter, naming it.
    pub fn validate(&self) -> Result<(), StabilityError> {
        let check = |name: &'static str, value: f64, requirement: &'static str| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(StabilityError::InvalidParameter { name, value, requirement })
            }
        };
        check(
            "specific indentation force K_d",
            self.indentation_n_per_m3,
            "finite and > 0 N/m³ (steels are of order 10¹³ N/m³, i.e. 10⁴ N/mm³)",
        )?;
        check("wear land w", self.wear_land_m, "finite and > 0 m (a flank contact of tens to hundreds of µm)")?;
        check("tool diameter D", self.diameter_m, "finite and > 0 m")
    }

    /// The process damping coefficient `C = K_d w²/4`, N/m (Chiou & Liang 1998; Tyler & Schmitz 2013).
    pub fn coefficient(&self) -> f64 {
        0.25 * self.indentation_n_per_m3 * self.wear_land_m * self.wear_land_m
    }

    /// Cutting speed `V = π D n/60` at `speed_rpm`, m/s.
    pub fn cutting_speed(&self, speed_rpm: f64) -> f64 {
        PI * self.diameter_m * speed_rpm / 60.0
    }

    /// The viscous damping `c = C b/V` of one flank contact at axial depth `depth_m` and `speed_rpm`, N·s/m.
    pub fn damping(&self, depth_m: f64, speed_rpm: f64) -> f64 {
        self.coefficient() * depth_m / self.cutting_speed(speed_rpm)
    }
}

/// `E = (N/2π) ∫ r rᵀ dφ` over the engaged arc, `r = (sin φ, cos φ)`: the time average of `Σ r_j r_jᵀ` over the
/// engaged teeth, which turns one contact's damping `c` into the cut's damping matrix `c E` in `(x, y)`
/// (module docs). A slot with `N` teeth gives `(N/4) I`.
pub fn engagement_matrix(milling: &Milling) -> [[f64; 2]; 2] {
    let (st, ex) = milling.engagement();
    // Antiderivatives of sin², sin cos and cos².
    let p = |phi: f64| {
        let (s2, c2) = (2.0 * phi).sin_cos();
        [0.5 * phi - 0.25 * s2, -0.25 * c2, 0.5 * phi + 0.25 * s2]
    };
    let (a, b) = (p(st), p(ex));
    let scale = milling.teeth as f64 / TAU;
    let (xx, xy, yy) = (scale * (b[0] - a[0]), scale * (b[1] - a[1]), scale * (b[2] - a[2]));
    [[xx, xy], [xy, yy]]
}

/// Tlusty's average-tooth-angle directional factors (module docs): the arc integral `[α] = ∫ A(φ) dφ` of
/// [`Milling::directional_factors`], `A(φ) = −2 h(φ)/Kt` with `h` the [tooth matrix](Milling::tooth_matrix), taken
/// by the midpoint rule, `(φ_ex − φ_st) A(φ_ave)`. Its non-zero eigenvalue with `[Φ]` is
/// `−(2 Ks/Kt)(φ_ex − φ_st)(μ_x Φxx + μ_y Φyy)` without cross terms.
pub fn average_tooth_angle_factors(milling: &Milling) -> [[f64; 2]; 2] {
    let (st, ex) = milling.engagement();
    let h = milling.tooth_matrix(0.5 * (st + ex));
    let s = -2.0 * (ex - st) / milling.coefficients.kt;
    [[s * h[0][0], s * h[0][1]], [s * h[1][0], s * h[1][1]]]
}

/// The textbook's projection of one flank contact's damping `c` in the average-tooth-angle method (Schmitz &
/// Smith, Eqs. 4.113–4.116): `diag(sin²φ_ave, cos²φ_ave)` in `(x, y)`, their `cos²(90° − φ_ave)` and
/// `cos²(180° − φ_ave)` — one contact always in the cut, no cross term (module docs).
pub fn average_tooth_angle_damping(milling: &Milling) -> [[f64; 2]; 2] {
    let (st, ex) = milling.engagement();
    let (s, c) = (0.5 * (st + ex)).sin_cos();
    [[s * s, 0.0], [0.0, c * c]]
}

/// How the cut enters the zero-order limit with process damping (module docs): the directional factors of the
/// cutting force and the distribution of the flank contact's damping.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ProcessDampingFormulation {
    /// The coupled ZOA (Altintas & Budak 1995): directional factors integrated over the engaged arc
    /// ([`Milling::directional_factors`]), both eigenvalues of the 2×2 problem, and the damping averaged over the
    /// arc, `D = (C b/V) E` ([`engagement_matrix`]).
    #[default]
    ArcAverage,
    /// Tlusty's average tooth angle as Schmitz & Smith apply it to process damping: one tooth at `φ_ave` carries
    /// the `N*` teeth in the cut ([`average_tooth_angle_factors`]), a scalar oriented FRF, and their diagonal
    /// damping `(C b/V) diag(sin²φ_ave, cos²φ_ave)` ([`average_tooth_angle_damping`]). It reproduces the textbook's
    /// converging analysis; it is not the better estimate of the limit (module docs).
    AverageToothAngle,
}

impl ProcessDampingFormulation {
    /// The directional factors `[α]` the lobes are solved with.
    pub fn directional_factors(self, milling: &Milling) -> [[f64; 2]; 2] {
        match self {
            ProcessDampingFormulation::ArcAverage => milling.directional_factors(),
            ProcessDampingFormulation::AverageToothAngle => average_tooth_angle_factors(milling),
        }
    }

    /// The damping matrix of one flank contact's damping `c = 1` N·s/m: the cut's damper is `c` times it.
    pub fn damping_shape(self, milling: &Milling) -> [[f64; 2]; 2] {
        match self {
            ProcessDampingFormulation::ArcAverage => engagement_matrix(milling),
            ProcessDampingFormulation::AverageToothAngle => average_tooth_angle_damping(milling),
        }
    }
}

/// The receptances with a viscous damper `damping` (N·s/m, in `(x, y)`) added in parallel at the tool point:
/// `G'⁻¹ = G⁻¹ + iω D`, i.e. `G' = (I + iω G D)⁻¹ G` per line. Cross terms appear when `D` couples `x` and `y`.
pub fn with_damper(frf: &ToolPointFrf, damping: [[f64; 2]; 2]) -> ToolPointFrf {
    let mut s = DampedLines::default();
    s.fill(frf.slices(usize::MAX), damping);
    let n = frf.freqs_hz.len();
    ToolPointFrf {
        freqs_hz: frf.freqs_hz.clone(),
        xx: s.xx,
        yy: s.yy,
        cross: s.has_cross.then(|| (s.xy[..n].to_vec(), s.yx[..n].to_vec())),
    }
}

/// Receptances of the damped lines, reused across evaluations.
#[derive(Default)]
struct DampedLines {
    xx: Vec<Complex64>,
    yy: Vec<Complex64>,
    xy: Vec<Complex64>,
    yx: Vec<Complex64>,
    has_cross: bool,
    limit: LimitScratch,
}

impl DampedLines {
    /// `G' = (I + iω G D)⁻¹ G` on the lines of `frf`.
    fn fill(&mut self, frf: FrfSlices<'_>, d: [[f64; 2]; 2]) {
        let n = frf.freqs_hz.len();
        let zero = Complex64::new(0.0, 0.0);
        self.has_cross = frf.cross.is_some() || d[0][1] != 0.0 || d[1][0] != 0.0;
        for v in [&mut self.xx, &mut self.yy, &mut self.xy, &mut self.yx] {
            v.clear();
            v.reserve(n);
        }
        for j in 0..n {
            let w = TAU * frf.freqs_hz[j];
            let (a, e) = (frf.xx[j], frf.yy[j]);
            let (b, c) = frf.cross.map_or((zero, zero), |(p, q)| (p[j], q[j]));
            // M = I + iω G D.
            let iw = Complex64::new(0.0, w);
            let m00 = 1.0 + iw * (a * d[0][0] + b * d[1][0]);
            let m01 = iw * (a * d[0][1] + b * d[1][1]);
            let m10 = iw * (c * d[0][0] + e * d[1][0]);
            let m11 = 1.0 + iw * (c * d[0][1] + e * d[1][1]);
            let inv_det = 1.0 / (m00 * m11 - m01 * m10);
            // M⁻¹ G with M⁻¹ = [[m11, −m01], [−m10, m00]]/det.
            self.xx.push((m11 * a - m01 * c) * inv_det);
            self.xy.push((m11 * b - m01 * e) * inv_det);
            self.yx.push((m00 * c - m10 * a) * inv_det);
            self.yy.push((m00 * e - m10 * b) * inv_det);
        }
    }

    fn slices<'a>(&'a self, freqs_hz: &'a [f64]) -> FrfSlices<'a> {
        FrfSlices {
            freqs_hz,
            xx: &self.xx,
            yy: &self.yy,
            cross: self.has_cross.then_some((&self.xy[..], &self.yx[..])),
        }
    }
}

/// Options of the fixed-point search of [`zoa_lobes_with_process_damping`].
#[derive(Debug, Clone, PartialEq)]
pub struct ProcessDampingOptions {
    /// Relative tolerance on the fixed point: the search stops when `|L(b) − b| ≤ tolerance · b`.
    pub tolerance: f64,
    /// The most evaluations of the damped limit `L` per speed; a speed that needs more keeps the last depth
    /// known to lie below the fixed point and is marked not converged.
    pub max_evaluations: usize,
    /// The depth beyond which the search stops and reports `+∞` (no finite limit below it), m.
    pub max_depth_m: f64,
    /// The formulation of the limit, for both the damped and the undamped limit (the coupled ZOA by default).
    pub formulation: ProcessDampingFormulation,
}

impl Default for ProcessDampingOptions {
    fn default() -> Self {
        ProcessDampingOptions {
            tolerance: 1e-6,
            max_evaluations: 60,
            max_depth_m: 1.0,
            formulation: ProcessDampingFormulation::default(),
        }
    }
}

/// The ZOA limit with process damping on a speed grid, and without it for comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct ProcessDampedLimit {
    /// The limit with process damping: the fixed point `b = L(n, b)` at each speed (`+∞` where there is none
    /// below [`ProcessDampingOptions::max_depth_m`] or no lobe passes), with the chatter frequency and lobe of
    /// the damped FRF there.
    pub limit: StabilityLimit,
    /// The limit without process damping at the same speeds: the ZOA envelope of [`super::zoa_lobes`], or with
    /// [`ProcessDampingFormulation::AverageToothAngle`] that formulation's envelope.
    pub without: StabilityLimit,
    /// Evaluations of the damped limit `L` per speed (0 where the undamped limit is already `+∞`).
    pub evaluations: Vec<usize>,
    /// Whether the search met the tolerance (or proved the limit unbounded) at each speed.
    pub converged: Vec<bool>,
    /// Lobes solved (explicit, or as the band needs).
    pub lobe_count: usize,
    /// Lobes the band of significant response needs down to the slowest speed.
    pub lobes_needed: usize,
    /// Highest frequency of significant response, Hz.
    pub band_top_hz: f64,
}

/// One speed's limit: depth, chatter frequency, lobe.
type Limit = (f64, f64, Option<usize>);

/// The result of the fixed-point search at one speed.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Solved {
    limit: Limit,
    evaluations: usize,
    converged: bool,
}

/// The smallest fixed point `b = L(b)` given `L(0) = b0` (module docs): secant steps from below on
/// `h(b) = L(b) − b`, the fixed-point step where the secant slope is not negative, Illinois regula falsi once a
/// step lands past the root, `+∞` once the steps pass `max_depth`.
fn fixed_point(b0: Limit, options: &ProcessDampingOptions, mut eval: impl FnMut(f64) -> Limit) -> Solved {
    let unbounded = |evaluations| Solved { limit: (f64::INFINITY, 0.0, None), evaluations, converged: true };
    if !b0.0.is_finite() {
        return unbounded(0);
    }
    let tol = options.tolerance;
    // The last point known to lie left of the root (h ≥ 0) and what L gave there: the answer if the search
    // runs out of evaluations (L of a point below the fixed point is below it too where L grows with b).
    let mut below = b0;
    let (mut x_prev, mut h_prev) = (0.0, b0.0);
    let mut x = b0.0;
    let mut evaluations = 0;
    let mut bracket = None;
    while evaluations < options.max_evaluations {
        let capped = x >= options.max_depth_m;
        if capped {
            x = options.max_depth_m;
        }
        let l = eval(x);
        evaluations += 1;
        if !l.0.is_finite() {
            // No lobe limits the cut with this much damping, nor with more.
            return unbounded(evaluations);
        }
        let h = l.0 - x;
        if h.abs() <= tol * x {
            return Solved { limit: l, evaluations, converged: true };
        }
        if h < 0.0 {
            bracket = Some(((x_prev, h_prev), (x, h)));
            break;
        }
        below = l;
        if capped {
            return unbounded(evaluations);
        }
        let slope = (h - h_prev) / (x - x_prev);
        let next = if slope < 0.0 { x - h / slope } else { x + h };
        (x_prev, h_prev, x) = (x, h, next);
    }
    let Some((mut lo, mut hi)) = bracket else {
        return Solved { limit: below, evaluations, converged: false };
    };
    // Illinois: regula falsi in [lo, hi] (h(lo) > 0 > h(hi)), halving the value kept at an end that stays twice.
    let mut side = 0i8;
    while evaluations < options.max_evaluations {
        let x = (lo.0 * hi.1 - hi.0 * lo.1) / (hi.1 - lo.1);
        let l = eval(x);
        evaluations += 1;
        if !l.0.is_finite() {
            return unbounded(evaluations);
        }
        let h = l.0 - x;
        if h.abs() <= tol * x || (hi.0 - lo.0) <= tol * x {
            return Solved { limit: l, evaluations, converged: true };
        }
        if h > 0.0 {
            below = l;
            lo = (x, h);
            if side == 1 {
                hi.1 *= 0.5;
            }
            side = 1;
        } else {
            hi = (x, h);
            if side == -1 {
                lo.1 *= 0.5;
            }
            side = -1;
        }
    }
    Solved { limit: below, evaluations, converged: false }
}

/// The ZOA limit with process damping at each speed of `options.speeds_rpm` (the fixed point of the module
/// docs), and the limit without it, in the formulation of `search.formulation`. `options.lobes` and
/// `options.resolution_hz` act as in [`super::zoa_lobes`] (`keep_lobes` is not used: no lobe curves are kept).
pub fn zoa_lobes_with_process_damping(
    frf: &ToolPointFrf,
    milling: &Milling,
    process_damping: &ProcessDamping,
    options: &ZoaOptions,
    search: &ProcessDampingOptions,
) -> Result<ProcessDampedLimit, StabilityError> {
    if !milling.has_equal_pitch() {
        return Err(StabilityError::UnequalPitch);
    }
    frf.validate()?;
    process_damping.validate()?;
    if !(search.tolerance.is_finite() && search.tolerance > 0.0 && search.tolerance < 1.0) {
        return Err(StabilityError::InvalidParameter {
            name: "process damping tolerance",
            value: search.tolerance,
            requirement: "in (0, 1): a relative tolerance on the fixed-point depth",
        });
    }
    if search.max_evaluations == 0 {
        return Err(StabilityError::InvalidParameter {
            name: "process damping evaluations",
            value: 0.0,
            requirement: "at least 1",
        });
    }
    if search.max_depth_m.is_nan() || search.max_depth_m <= 0.0 {
        return Err(StabilityError::InvalidParameter {
            name: "process damping maximum depth",
            value: search.max_depth_m,
            requirement: "> 0 m (+∞ allowed)",
        });
    }
    let grid = &options.speeds_rpm;
    if let Some(i) = grid.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(StabilityError::InvalidParameter {
            name: "speed grid value",
            value: grid[i],
            requirement: "finite and > 0 rpm",
        });
    }
    if let Some(i) = grid.windows(2).position(|w| w[1] <= w[0]) {
        return Err(StabilityError::InvalidParameter {
            name: "speed grid value",
            value: grid[i + 1],
            requirement: "speeds must increase strictly",
        });
    }
    let frf = &*refine(frf, options.resolution_hz);
    let factors = search.formulation.directional_factors(milling);
    let mut roots = Vec::new();
    line_roots_oriented(frf.slices(usize::MAX), &factors, milling, false, &mut roots);
    if roots.iter().all(|r| r.iter().all(Option::is_none)) {
        return Err(StabilityError::NoResonance {
            f_lo: frf.freqs_hz.first().copied().unwrap_or(0.0),
            f_hi: frf.freqs_hz.last().copied().unwrap_or(0.0),
        });
    }
    let band_top = band_top_hz(frf);
    let n_min = grid.first().copied().unwrap_or(f64::INFINITY);
    let needed = lobes_needed(band_top, milling.teeth, n_min);
    let count = lobe_count(options.lobes, band_top, milling.teeth, n_min)?;
    let shape = search.formulation.damping_shape(milling);
    let per_tooth = 60.0 / milling.teeth as f64;
    let freqs = &frf.freqs_hz;
    let rows: Vec<(Limit, Solved)> = grid
        .par_iter()
        .map_init(DampedLines::default, |scratch, &n| {
            // Lobes k < count pass this speed only on lines with f τ ≤ count (the phase fraction is below one),
            // so the eigenproblem is solved on those lines and the next one only.
            let tau = per_tooth / n;
            let lines = (freqs.partition_point(|&f| f * tau <= count as f64 + 1e-6) + 1).min(freqs.len());
            let without = limit_at_speed_oriented(frf.slices(lines), &factors, milling, count, n, &mut scratch.limit);
            let solved = fixed_point(without, search, |depth| {
                let c = process_damping.damping(depth, n);
                let d = [[c * shape[0][0], c * shape[0][1]], [c * shape[1][0], c * shape[1][1]]];
                scratch.fill(frf.slices(lines), d);
                let mut limit = std::mem::take(&mut scratch.limit);
                let l =
                    limit_at_speed_oriented(scratch.slices(&freqs[..lines]), &factors, milling, count, n, &mut limit);
                scratch.limit = limit;
                l
            });
            (without, solved)
        })
        .collect();
    let limit = |pick: &dyn Fn(&(Limit, Solved)) -> Limit| {
        let v: Vec<Limit> = rows.iter().map(pick).collect();
        StabilityLimit {
            speed_rpm: grid.clone(),
            depth_m: v.iter().map(|r| r.0).collect(),
            chatter_hz: v.iter().map(|r| r.1).collect(),
            lobe: v.iter().map(|r| r.2).collect(),
        }
    };
    Ok(ProcessDampedLimit {
        limit: limit(&|r| r.1.limit),
        without: limit(&|r| r.0),
        evaluations: rows.iter().map(|r| r.1.evaluations).collect(),
        converged: rows.iter().map(|r| r.1.converged).collect(),
        lobe_count: count,
        lobes_needed: needed,
        band_top_hz: band_top,
    })
}
