//! Milling stability (dissertation ch. 6): the zero-order approximation (ZOA) of Altintas & Budak (1995) on
//! measured tool-point FRFs, first-order semi-discretization (SD) of Insperger & Stépán (2002, 2004) on modal
//! models, and the speed-dependent lobes of §6.1–6.3.
//!
//! Force convention (both solvers, [`cutting`]): `x` is the feed direction, `y` is normal to it in the plane of
//! the cut, the tool turns clockwise seen from the spindle, and the tooth angle `φ` is measured clockwise from
//! `+y`, so a tooth sits at `R (sin φ, cos φ)`. The chip thickness is `h = (f + Δx) sin φ + Δy cos φ` with
//! `Δq = q(t) − q(t − τ)` the tool displacement now minus one tooth period ago. The forces on the tool are
//! tangential `Kt a_p h` against the cutting speed and normal `Kn a_p h` pointing from the tooth towards the tool
//! axis (a positive `Kn` pushes the tool away from the work):
//! `Fx = −Ft cos φ − Fn sin φ`, `Fy = Ft sin φ − Fn cos φ` (Altintas, *Manufacturing Automation*, Eq. 3.6), so
//! the regenerative force is `F(t) = −a_p H(t) Δq` with the specific cutting force matrix `H(t)` of
//! [`cutting::Milling::force_matrix`]. Coefficients are `Kt = Ks sin β`, `Kn = Ks cos β`. Up-milling cuts
//! `φ ∈ [0, arccos(1 − 2a_e/D)]`, down-milling `φ ∈ [arccos(2a_e/D − 1), π]`.
//!
//! Variable pitch and helix ([`cutting::Milling::with_pitch`], [`cutting::Milling::with_helix`]): tooth `j`
//! regenerates over its own delay `τ_j = pitch_j/Ω`, `F = −a_p Σ_j H_j(t) [q(t) − q(t − τ_j)]`, and with helical
//! flutes `H` is averaged over the depth of cut; [`sdm`] and the time-domain simulation take both, the ZOA neither
//! ([`pitch`] is the zero-order solution for variable pitch).

pub mod best;
pub mod cutting;
mod linalg;
pub mod pitch;
pub mod process_damping;
pub mod sdm;
pub mod speed;
pub mod trials;
pub mod uncertainty;
pub mod zoa;

#[cfg(test)]
mod tests;

pub use cutting::{CuttingCoefficients, MAX_LAG_PER_SLICE, Milling, MillingDirection};
pub use pitch::{PitchLimit, alternating_pitch, variable_pitch_limits};
pub use process_damping::{
    ProcessDampedLimit, ProcessDamping, ProcessDampingFormulation, ProcessDampingOptions, average_tooth_angle_damping,
    average_tooth_angle_factors, engagement_matrix, with_damper, zoa_lobes_with_process_damping,
};
pub use sdm::{
    AUTO_STEPS_PER_NATURAL_PERIOD, Bifurcation, DepthLimit, ModalModel, Mode, SdOptions, SdPoint, StabilityMap,
    StepCount, sd_depth_limit, sd_depth_limits, sd_spectral_radius, sd_stability_map, sd_steps,
};
pub use speed::{
    CoefficientTable, SpeedDependentLimit, SpeedDependentOptions, SpeedFrf, conditions_at, speed_dependent_lobes,
};
pub use trials::{Outcome, Trial, TrialLikelihood, TrialScore, Verdict, normal_cdf, score_trials};
pub use zoa::{
    Lobe, LobePoint, LobeSet, MAX_LOBES, SIGNIFICANT_RESPONSE, StabilityLimit, ToolPointFrf, ZoaLobes, ZoaOptions,
    band_top_hz, lobes_needed, refine, zoa_lobes,
};

use thiserror::Error;

/// Errors of the stability kernels: each names the offending value and what to change.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum StabilityError {
    /// The tool has no teeth.
    #[error("the tool has 0 teeth; give the number of cutting edges (≥ 1)")]
    NoTeeth,
    /// Radial immersion outside `(0, 1]`.
    #[error(
        "radial immersion a_e/D = {0} is outside (0, 1]; give the radial depth of cut divided by the tool diameter"
    )]
    Immersion(f64),
    /// A limit with one regenerative delay (the tooth period) asked of a cutter whose teeth are unequally spaced.
    #[error(
        "the teeth are unequally spaced, but this limit has one delay, the tooth period; give equal pitch, or use \
         the variable-pitch limit (stability.sd, or the frequency-domain pitch limit) that gives each tooth its own delay"
    )]
    UnequalPitch,
    /// A scalar parameter is out of range.
    #[error("invalid {name} = {value}: {requirement}")]
    InvalidParameter {
        /// Which parameter.
        name: &'static str,
        /// The offending value.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// Two series that must share a grid do not.
    #[error("{what}: {detail}; resample the FRFs onto one frequency grid")]
    GridMismatch {
        /// Which series.
        what: &'static str,
        /// Where they differ.
        detail: String,
    },
    /// A value of a series is not finite.
    #[error("{what} is not finite at index {index}; remove or repair that line")]
    NonFinite {
        /// Which series.
        what: &'static str,
        /// Index of the first bad value.
        index: usize,
    },
    /// No frequency line gives a positive limiting depth.
    #[error(
        "no frequency line between {f_lo} and {f_hi} Hz has Re Λ < 0, so no depth of cut is limited: the band holds \
         no resonance the cut can excite (check the FRF signs and the band)"
    )]
    NoResonance {
        /// Lowest frequency of the grid, Hz.
        f_lo: f64,
        /// Highest frequency of the grid, Hz.
        f_hi: f64,
    },
    /// A modal model entry is out of range.
    #[error("mode {index} along {direction}: {problem}")]
    InvalidMode {
        /// `x` or `y`.
        direction: &'static str,
        /// Index of the mode.
        index: usize,
        /// What is wrong.
        problem: String,
    },
    /// A requested speed lies outside the measured speeds.
    #[error(
        "{what}: {speed_rpm} rpm lies outside the measured speeds {lo_rpm}–{hi_rpm} rpm; narrow the range or allow \
         extrapolation"
    )]
    Extrapolation {
        /// Which table.
        what: &'static str,
        /// The requested speed, rpm.
        speed_rpm: f64,
        /// Lowest measured speed, rpm.
        lo_rpm: f64,
        /// Highest measured speed, rpm.
        hi_rpm: f64,
    },
    /// The lobe count exceeds [`zoa::MAX_LOBES`].
    #[error(
        "{lobes} lobes are needed for the band's response up to {f_max_hz:.0} Hz to reach {n_min_rpm} rpm with \
         {teeth} teeth, more than the {max} a diagram may take; start the speeds higher or give `lobes` explicitly",
        max = zoa::MAX_LOBES
    )]
    TooManyLobes {
        /// The count asked for or needed.
        lobes: usize,
        /// Highest frequency of significant response, Hz.
        f_max_hz: f64,
        /// Slowest speed, rpm.
        n_min_rpm: f64,
        /// Number of teeth.
        teeth: usize,
    },
    /// A stability diagram given for scoring trials is malformed.
    #[error("stability diagram: {detail}; give ascending speeds with one limiting depth (> 0 m or +∞) each")]
    InvalidDiagram {
        /// What is wrong.
        detail: String,
    },
    /// A cutting trial is malformed.
    #[error("trial {index}: {problem}")]
    InvalidTrial {
        /// Index of the trial.
        index: usize,
        /// What is wrong.
        problem: String,
    },
    /// The eigenvalue iteration of a monodromy matrix did not converge.
    #[error("eigenvalues of the {size}×{size} monodromy matrix did not converge at {speed_rpm} rpm, depth {depth_m} m")]
    NoConvergence {
        /// Matrix size.
        size: usize,
        /// Spindle speed, rpm.
        speed_rpm: f64,
        /// Axial depth, m.
        depth_m: f64,
    },
}
