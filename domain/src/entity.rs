//! The entities a recipe names, typed and in SI: materials, machines with their spindle
//! models, tool/holder assemblies of Timoshenko sections, sensors and cutting setups.
//!
//! The engine builds them from checked recipe fields; the kernels take them as they are.

use crate::speed::{Speed, SpeedLaw};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Elastic, inertial and damping properties of an isotropic material (SI): the one material
/// of the recipe, the Timoshenko sections and the equivalent Euler–Bernoulli spindle beams.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// Young's modulus E, Pa.
    pub youngs_modulus: f64,
    /// Density ρ, kg/m³.
    pub density: f64,
    /// Poisson's ratio ν (NaN where a recipe leaves it out: Euler–Bernoulli beams do without).
    pub poisson: f64,
    /// Structural loss factor η (complex modulus E(1 + iη)).
    pub loss_factor: f64,
}

impl Material {
    /// Steel of Table 5.2: 200 GPa, ν 0.29, 7800 kg/m³, η 0.0015.
    pub const STEEL: Material = Material { youngs_modulus: 200e9, density: 7800.0, poisson: 0.29, loss_factor: 0.0015 };
    /// Carbide of Table 5.2: 550 GPa, ν 0.22, 15000 kg/m³, η 0.0015.
    pub const CARBIDE: Material =
        Material { youngs_modulus: 550e9, density: 15000.0, poisson: 0.22, loss_factor: 0.0015 };

    /// Shear modulus G = E / (2(1 + ν)).
    pub fn shear_modulus(&self) -> f64 {
        self.youngs_modulus / (2.0 * (1.0 + self.poisson))
    }
}

/// Which part of the assembly a section belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Component {
    Holder,
    HolderAndTool,
    Tool,
}

/// One Timoshenko section of a tool/holder assembly, lengths in metres.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Section {
    pub name: String,
    pub component: Component,
    pub fluted: bool,
    pub d_out_spindle_end: f64,
    pub d_out_tip_end: f64,
    pub d_in: f64,
    pub length: f64,
    pub outer: Material,
    pub inner: Option<Material>,
    pub d_equivalent: Option<f64>,
}

/// A joint between substructures: rigid, or stiffness and damping per direction.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Joint {
    Rigid,
    Compliant { kt: f64, ct: f64, kr: f64, cr: f64 },
}

/// One equivalent fixed-free Euler–Bernoulli spindle mode (§5.2) with its speed law: the
/// natural frequency and loss factor change with speed, the diameter does not.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpindleMode {
    /// Natural frequency at rest, Hz.
    pub freq_hz: f64,
    /// Diameter of the equivalent beam, m.
    pub diameter: f64,
    /// Structural loss factor at rest.
    pub loss_factor: f64,
    /// Frequency and loss factor over speed (`kf`, `keta` in a recipe).
    pub law: SpeedLaw,
    /// Relative change of the mode's bearing stiffness at the reference speed (`kk`):
    /// `k(n) = k (1 + kk (n/n_ref)²)` at the mode's mass, so the frequency moves with `√k` and
    /// the modal flexibility with `1/k`; zero for bearings that keep their stiffness.
    pub stiffness_change: f64,
    /// Exponent `p` of the bearing law `k(n) = k (1 + kk (n/n_ref)^p)` (`kk_exponent`): 2 for
    /// the quadratic law; a preloaded angular-contact bearing softens faster at high speed,
    /// as its balls' centrifugal load turns the contact angles (Jones–Harris), so a law
    /// fitted over three speeds or more may take a larger one.
    pub stiffness_exponent: f64,
    /// Gyroscopic coefficient of the rotor in this mode (`gyro`): its polar over its diametral
    /// moment of inertia, `g = I_p/I_d` (0 for a mode without gyroscopic coupling, 2 for a thin
    /// disk). At spin `Ω` the mode whirls forward and backward at `ω (√(1+e²) ± e)`, `e =
    /// gΩ/(2ω)` (see [`whirl_frequency`]); the two whirls decouple for the whole spinning
    /// assembly, so a coupling takes each whirl whole and averages the results.
    pub gyro: f64,
}

/// A whirl of a spinning, isotropic rotor: in the coordinates `x ± i y` its bending planes
/// decouple, and each mode whirls forward (with the spin, its frequency rising) or backward.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Whirl {
    Forward,
    Backward,
}

/// The frequency (Hz) of a mode at rest frequency `freq_hz` with gyroscopic coefficient `gyro`
/// whirling `whirl` at spin `n`: the roots of `ω² ∓ gΩω − ω_n² = 0`, the isotropic two-plane
/// mode `m(ẍ + ω_n² x) + gmΩ ẏ = 0`, `m(ÿ + ω_n² y) − gmΩ ẋ = 0` in whirl coordinates, which
/// are `ω_n (√(1+e²) ± e)` with `e = gΩ/(2ω_n)`.
pub fn whirl_frequency(freq_hz: f64, gyro: f64, n: Speed, whirl: Whirl) -> f64 {
    let e = gyro * n.rad_s() / (2.0 * std::f64::consts::TAU * freq_hz);
    let root = e.hypot(1.0);
    match whirl {
        Whirl::Forward => freq_hz * (root + e),
        Whirl::Backward => freq_hz * (root - e),
    }
}

impl SpindleMode {
    /// A mode that does not change with speed.
    pub fn new(freq_hz: f64, diameter: f64, loss_factor: f64) -> SpindleMode {
        SpindleMode {
            freq_hz,
            diameter,
            loss_factor,
            law: SpeedLaw::NONE,
            stiffness_change: 0.0,
            stiffness_exponent: 2.0,
            gyro: 0.0,
        }
    }

    /// A mode stated modally, as the equivalent beam the spindle model uses: the solid
    /// fixed-free Euler–Bernoulli beam of `material` whose first mode has natural frequency
    /// `freq_hz` and modal stiffness `stiffness` at its free end (N/m), with the loss factor
    /// `2 zeta` that gives a viscous damping ratio `zeta` its resonant peak.
    ///
    /// With the first mode normalised to 1 at the tip, its modal mass is ρAL/4, so
    /// `k = ω² ρ (π d²/4) L / 4`, and `ω = (β₁L)² (d/4) √(E/ρ) / L²` (`I/A = d²/16`); the two
    /// give `L⁵ = k (β₁L)⁴ E / (π ρ² ω⁴)` and `d = 4 ω L² / ((β₁L)² √(E/ρ))`. The beam's higher
    /// modes (from 6.27 f) add about 3 % to its static compliance, as a real spindle's do.
    pub fn from_modal(freq_hz: f64, stiffness: f64, zeta: f64, material: &Material, law: SpeedLaw) -> SpindleMode {
        let b4 = FIXED_FREE_FIRST_ROOT.powi(4);
        let w = std::f64::consts::TAU * freq_hz;
        let (e, rho) = (material.youngs_modulus, material.density);
        let length = (stiffness * b4 * e / (std::f64::consts::PI * rho * rho * w.powi(4))).powf(0.2);
        let diameter = 4.0 * w * length * length / (FIXED_FREE_FIRST_ROOT.powi(2) * (e / rho).sqrt());
        SpindleMode {
            freq_hz,
            diameter,
            loss_factor: 2.0 * zeta,
            law,
            stiffness_change: 0.0,
            stiffness_exponent: 2.0,
            gyro: 0.0,
        }
    }

    /// Natural frequency (Hz) and loss factor at speed `n`, by the law about `reference`.
    pub fn at_speed(&self, n: Speed, reference: Speed) -> (f64, f64) {
        (self.law.frequency(self.freq_hz, n, reference), self.law.damping(self.loss_factor, n, reference))
    }

    /// The equivalent beam the mode is at speed `n`, `(frequency Hz, diameter m, loss factor)`:
    /// the speed law's frequency and loss factor, then the bearing stiffness change at the
    /// mode's mass, `1 + kk (n/n_ref)^p`. A beam keeps its modal mass when its frequency moves by a factor `r` and its
    /// stiffness by `r²` if its diameter moves by `r^⅕` (from [`SpindleMode::from_modal`]:
    /// `d ∝ ω L²`, `L⁵ ∝ k/ω⁴`).
    pub fn beam_at(&self, n: Speed, reference: Speed) -> (f64, f64, f64) {
        let (f, eta) = self.at_speed(n, reference);
        let ratio = SpeedLaw::ratio_squared(n, reference);
        let stiffness = 1.0
            + self.stiffness_change
                * if self.stiffness_exponent == 2.0 { ratio } else { ratio.powf(0.5 * self.stiffness_exponent) };
        (f * stiffness.sqrt(), self.diameter * stiffness.powf(0.1), eta)
    }

    /// The frequency (Hz) of the mode whirling `whirl` at speed `n` ([`whirl_frequency`] of its
    /// frequency there); its frequency there when it has no gyroscopic coefficient or at rest.
    pub fn whirl_at(&self, n: Speed, reference: Speed, whirl: Whirl) -> f64 {
        let (f, _, _) = self.beam_at(n, reference);
        if self.gyro == 0.0 || n.is_rest() { f } else { whirl_frequency(f, self.gyro, n, whirl) }
    }
}

/// β₁L of the first mode of a fixed-free Euler–Bernoulli beam: the first root of
/// `1 + cos x cosh x = 0`.
pub const FIXED_FREE_FIRST_ROOT: f64 = 1.875_104_068_711_961;

/// The spindle-machine receptance at the holder base as equivalent modes per direction.
#[derive(Debug, Clone, PartialEq)]
pub struct Spindle {
    pub material: Material,
    /// Reference speed of the speed law.
    pub ref_speed: Speed,
    pub modes: Vec<(String, Vec<SpindleMode>)>,
}

/// A machine: directions, speeds, spindle model and holder joint.
#[derive(Debug, Clone, PartialEq)]
pub struct Machine {
    pub directions: Vec<String>,
    /// Spindle speeds of interest.
    pub speeds: Vec<Speed>,
    pub max_speed: Option<Speed>,
    pub spindle: Option<Spindle>,
    pub holder_interface: Joint,
}

/// A tool/holder assembly of sections from the spindle end to the tip.
#[derive(Debug, Clone, PartialEq)]
pub struct Assembly {
    pub sections: Vec<Section>,
    pub tool_joint: Joint,
}

/// A response sensor and what it does to a measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct Sensor {
    pub kind: String,
    /// Phase slope of the chain (rad per Hz, i.e. seconds × 2π); Eq. 2.11.
    pub phase_slope: f64,
    pub mass: f64,
    pub location: String,
    pub noise: Option<f64>,
}

/// A milling setup, with coefficients in the tangential/normal convention `Kt = Ks sin β`, `Kn = Ks cos β`.
#[derive(Debug, Clone, PartialEq)]
pub struct Cutting {
    pub teeth: u32,
    pub radial_immersion: f64,
    pub up_milling: bool,
    pub kt: f64,
    pub kn: f64,
    pub calibrated_at: Option<Speed>,
    /// Linear speed law about `calibrated_at`: relative change of Ks and change of β (rad)
    /// per `change_per` of speed; zero for speed-independent coefficients.
    pub ks_change: f64,
    pub beta_change: f64,
    pub change_per: Speed,
    pub feed_per_tooth: Option<f64>,
    pub workpiece: Option<String>,
    pub trial_speeds: Vec<Speed>,
}

/// The entities one step names through its parameters (in objects and lists too), resolved
/// by the compiler: what a node sees of the recipe. A node cannot reach an entity its step
/// does not name, so its cache key (which holds the digests of the entities named) covers
/// everything it reads.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Entities {
    pub materials: BTreeMap<String, Material>,
    pub machines: BTreeMap<String, Machine>,
    pub assemblies: BTreeMap<String, Assembly>,
    pub sensors: BTreeMap<String, Sensor>,
    pub cutting: BTreeMap<String, Cutting>,
}
