//! Finite-element rotor model of a spindle: a spinning Timoshenko shaft with rigid disks on
//! grounded bearings, for whirl frequencies (Campbell tables), whirl directions and
//! speed-dependent receptances (Friswell, Penny, Garvey & Lees, *Dynamics of Rotating
//! Machines*, Cambridge 2010, ch. 5; the conventions are those of the ROSS rotordynamics
//! library, which reproduces the book's examples).
//!
//! Coordinates: the shaft axis is z, the spin Ω (rad/s) is about +z. Each node has four
//! degrees of freedom `[x, y, α, β]`: translations x and y, α the rotation about x
//! (α = −dy/dz) and β the rotation about y (β = dx/dz), the `[u, v, θ, ψ]` of Friswell et
//! al. ch. 5. Equations of motion (shaft, disks and bearings assembled, Friswell et al. ch. 5):
//!
//! `M q̈ + (C + Ω G) q̇ + K q = f`,
//!
//! with M the consistent mass including rotary inertia, K the shear-deformable (Timoshenko)
//! stiffness, C the bearing dampers and G the skew-symmetric gyroscopic matrix of the shaft's
//! and disks' polar inertia. The shaft element (the Timoshenko element of Friswell et al.
//! ch. 5 with shear and rotary inertia; Przemieniecki's shear-deformable beam) is the planar
//! element of [`crate::beam::element`] used in both bending planes, with the shear coefficient
//! of Cowper (1966) from ν = E/2G − 1, as ROSS computes it. Disks are rigid; bearings are
//! linear springs and dampers between the translations and ground, possibly cross-coupled.
//! Equation numbers of the book are not quoted: the matrices were checked against ROSS's
//! implementation (`ross/shaft_element.py`, `disk_element.py`) and its tests
//! (`test_rotor_assembly.py`: `test_campbell`, `test_kappa_rotor3`, `test_kappa_mode_rotor3`
//! for Friswell et al. Example 5.9.1), which `tests.rs` reproduces to about 1e-6.
//!
//! Modes come from the first-order (state-space) eigenproblem, Friswell et al. ch. 3:
//! `A = [[0, I], [−M⁻¹K, −M⁻¹C(Ω)]]`, solved densely (faer). The whirl of a mode at a node is
//! the sense of the elliptical orbit of `(x, y)`: forward when it turns with the spin (x → y),
//! backward against it; `kappa` = ± minor/major axis, as ROSS's `kappa`.
//!
//! Torsion is a separate, uncoupled model ([`Rotor::torsional_frequencies`]; ROSS's 6-dof
//! nodes carry it in the same matrices, hence its torsional mode at 650.4 rad/s among the
//! whirls of `rotor4`). Not modelled: axial dofs, tapered sections, shaft internal
//! (rotating) damping, speed-dependent bearing coefficients, the loss factor of the material.
//!
//! The nodes `rotor.campbell` and `rotor.receptance` expose the model; the receptance at the
//! nose ([`RotorWhirll::point_receptance`]) feeds RCSA with a spinning holder
//! ([`crate::rcsa::couple_spinning`]). Friswell et al. Example 5.8.1 (ROSS `example_1.ipynb`)
//! is not a test because that notebook prints only convergence plots, no frequencies.

use crate::beam::element;
use crate::beam::section::SectionProperties;
use num_complex::Complex64;
use spindlelab_domain::entity::Material;
use std::f64::consts::{PI, TAU};
use thiserror::Error;

#[cfg(test)]
mod tests;

/// Degrees of freedom per node: `[x, y, α, β]`.
pub const DOF_PER_NODE: usize = 4;

/// Errors of the rotor model; each names the offending value.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RotorError {
    /// The rotor has no shaft sections.
    #[error("the rotor has no shaft sections")]
    NoSections,
    /// A section's length is not positive and finite.
    #[error("section {section}: length {length} m must be positive and finite")]
    BadLength { section: usize, length: f64 },
    /// A section's diameters are not `0 <= inner < outer`.
    #[error("section {section}: outer diameter {outer} m, inner {inner} m (need 0 <= inner < outer)")]
    BadDiameters { section: usize, inner: f64, outer: f64 },
    /// A section is split into zero elements.
    #[error("section {section} has 0 elements; it needs at least one")]
    NoElements { section: usize },
    /// A section's material is out of range.
    #[error("section {section}: bad material {material:?} (need E > 0, rho > 0, -1 < nu < 0.5)")]
    BadMaterial { section: usize, material: Material },
    /// A disk or bearing sits on a node that does not exist.
    #[error("{what} at node {node}: the rotor has nodes 0..={last}")]
    NoSuchNode { what: &'static str, node: usize, last: usize },
    /// A disk's mass or an inertia is negative or not finite.
    #[error("disk at node {node}: mass {mass} kg, Ip {polar} kg m^2, Id {diametral} kg m^2 must be finite and >= 0")]
    BadDisk { node: usize, mass: f64, polar: f64, diametral: f64 },
    /// A bearing coefficient is not finite, or a direct coefficient is negative.
    #[error("bearing at node {node}: {name} = {value} (need finite, direct terms >= 0)")]
    BadBearing { node: usize, name: &'static str, value: f64 },
    /// A spin speed is not finite.
    #[error("spin speed {0} rad/s must be finite")]
    BadSpeed(f64),
    /// A bearing's speed law makes its stiffness negative at a speed.
    #[error(
        "bearing at node {node}: its speed law gives a negative stiffness at {speed_rad_s} rad/s (factor {factor}); lower the softening or the speed"
    )]
    SoftenedBearing { node: usize, speed_rad_s: f64, factor: f64 },
    /// A frequency is negative or not finite.
    #[error("frequency {0} Hz must be finite and >= 0")]
    BadFrequency(f64),
    /// The mass matrix is singular (e.g. a massless shaft).
    #[error("the mass matrix is singular")]
    SingularMass,
    /// The dynamic stiffness is singular at a frequency (an undamped resonance, or 0 Hz
    /// without bearings).
    #[error("the dynamic stiffness is singular at {0} Hz")]
    Singular(f64),
    /// The eigen-solver failed (non-finite entries).
    #[error("the eigen-solver did not converge")]
    NoConvergence,
}

/// A uniform shaft section split into equal Timoshenko elements.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShaftSection {
    /// Length, m.
    pub length_m: f64,
    /// Bore diameter (0 for a solid shaft), m.
    pub inner_diameter_m: f64,
    /// Outer diameter, m.
    pub outer_diameter_m: f64,
    /// Number of equal elements.
    pub elements: usize,
    /// Material: E, ρ and ν (G = E / 2(1 + ν)); the loss factor is not used.
    pub material: Material,
}

/// A rigid disk on the axis (Friswell et al. ch. 5): mass, diametral and polar inertia.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disk {
    /// Node index.
    pub node: usize,
    /// Mass, kg.
    pub mass_kg: f64,
    /// Polar moment of inertia Ip about the spin axis, kg·m².
    pub polar_inertia: f64,
    /// Diametral moment of inertia Id about a transverse axis through its centre, kg·m².
    pub diametral_inertia: f64,
}

impl Disk {
    /// Disk of a uniform annulus: `m = ρπw(do² − di²)/4`, `Ip = m(do² + di²)/8`,
    /// `Id = Ip/2 + m w²/12` (as ROSS's `DiskElement.from_geometry`).
    pub fn from_geometry(node: usize, rho: f64, width: f64, inner_d: f64, outer_d: f64) -> Disk {
        let mass_kg = rho * PI * width * (outer_d * outer_d - inner_d * inner_d) / 4.0;
        let polar_inertia = mass_kg * (outer_d * outer_d + inner_d * inner_d) / 8.0;
        let diametral_inertia = polar_inertia / 2.0 + mass_kg * width * width / 12.0;
        Disk { node, mass_kg, polar_inertia, diametral_inertia }
    }
}

/// Linear bearing between a node's translations and ground: force `−[k]·[x, y] − [c]·[ẋ, ẏ]`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Bearing {
    /// Node index.
    pub node: usize,
    /// Direct stiffness in x, N/m.
    pub kxx: f64,
    /// Direct stiffness in y, N/m.
    pub kyy: f64,
    /// Cross-coupled stiffness (force in x per y displacement), N/m.
    pub kxy: f64,
    /// Cross-coupled stiffness (force in y per x displacement), N/m.
    pub kyx: f64,
    /// Direct damping in x, N·s/m.
    pub cxx: f64,
    /// Direct damping in y, N·s/m.
    pub cyy: f64,
    /// Relative change of the stiffness at `ref_speed_rad_s`: every stiffness of the bearing
    /// is `k (1 + speed_coefficient (Ω/Ω_ref)²)` at spin speed Ω, the quadratic law of the
    /// centrifugal load on the rolling elements (negative: softening). 0: constant.
    pub speed_coefficient: f64,
    /// Reference speed Ω_ref of the law, rad/s.
    pub ref_speed_rad_s: f64,
}

impl Bearing {
    /// Bearing with direct coefficients only.
    pub fn new(node: usize, kxx: f64, kyy: f64, cxx: f64, cyy: f64) -> Bearing {
        Bearing { node, kxx, kyy, cxx, cyy, ..Bearing::default() }
    }
}

/// A rotor: shaft sections end to end (node 0 at the start of the first), disks and bearings.
#[derive(Debug, Clone, PartialEq)]
pub struct Rotor {
    /// Shaft sections, in order along the axis.
    pub sections: Vec<ShaftSection>,
    /// Rigid disks.
    pub disks: Vec<Disk>,
    /// Bearings.
    pub bearings: Vec<Bearing>,
}

/// Direction of a degree of freedom at a node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Translation x (force Fx).
    X,
    /// Translation y (force Fy).
    Y,
    /// Rotation α about x (moment Mx).
    Alpha,
    /// Rotation β about y (moment My).
    Beta,
}

impl Direction {
    fn offset(self) -> usize {
        match self {
            Direction::X => 0,
            Direction::Y => 1,
            Direction::Alpha => 2,
            Direction::Beta => 3,
        }
    }
}

/// Whirl direction of a mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Whirl {
    /// Every node orbits in the sense of the spin (or on a line, with some forward).
    Forward,
    /// Every node orbits against the spin (or on a line, with some backward).
    Backward,
    /// Some nodes forward, some backward — or all orbits straight lines (at rest, anisotropic
    /// bearings), where the sense is undefined.
    Mixed,
}

/// One whirl of the rotor at a spin speed: an eigen-solution of the gyroscopic system (damped and undamped
/// frequency, damping, whirl sense and the orbit ratio at each node), not a modal triple of a tool point.
#[derive(Debug, Clone, PartialEq)]
pub struct RotorWhirl {
    /// Undamped natural frequency |λ|, rad/s.
    pub wn_rad_s: f64,
    /// Damped natural frequency Im λ, rad/s.
    pub wd_rad_s: f64,
    /// Damping ratio −Re λ / |λ|.
    pub damping_ratio: f64,
    /// Whirl direction over all nodes.
    pub whirl: Whirl,
    /// Signed ellipticity of the orbit of each node: minor/major axis, positive forward
    /// (ROSS's `kappa`); 0 for a straight-line orbit or a node at rest.
    pub kappa: Vec<f64>,
}

impl RotorWhirl {
    /// Damped natural frequency, Hz.
    pub fn freq_hz(&self) -> f64 {
        self.wd_rad_s / TAU
    }
}

/// Modes at one speed of a Campbell table.
#[derive(Debug, Clone, PartialEq)]
pub struct CampbellRow {
    /// Spin speed, rad/s.
    pub speed_rad_s: f64,
    /// The lowest modes, ascending in damped frequency.
    pub modes: Vec<RotorWhirl>,
}

/// Orbits with |kappa| below this are straight lines (no whirl sense).
const LINE_KAPPA: f64 = 1e-6;

/// The assembled rotor: M, K, C and G (row-major, 4 dof per node).
#[derive(Debug, Clone, PartialEq)]
pub struct RotorWhirll {
    n_nodes: usize,
    nodes_z: Vec<f64>,
    m: Vec<f64>,
    k: Vec<f64>,
    c: Vec<f64>,
    g: Vec<f64>,
    /// Bearing stiffness per Ω² (the speed laws' `k c / Ω_ref²`): K(Ω) = K + Ω² K₂.
    k2: Vec<f64>,
    /// Each speed-dependent bearing's node and its coefficient per Ω², for the check that
    /// its stiffness stays positive.
    laws: Vec<(usize, f64)>,
}

/// Cowper's (1966) shear coefficient of a hollow circle, `r = di/do`, as used by ROSS.
fn cowper(nu: f64, r: f64) -> f64 {
    let r2 = r * r;
    let r12 = (1.0 + r2) * (1.0 + r2);
    6.0 * r12 * (1.0 + nu) / (r12 * (7.0 + 6.0 * nu) + r2 * (20.0 + 12.0 * nu))
}

fn finite_nonneg(v: f64) -> bool {
    v.is_finite() && v >= 0.0
}

impl Rotor {
    /// Number of nodes (elements + 1).
    pub fn n_nodes(&self) -> usize {
        self.sections.iter().map(|s| s.elements).sum::<usize>() + 1
    }

    /// Checks the rotor's data.
    pub fn validate(&self) -> Result<(), RotorError> {
        if self.sections.is_empty() {
            return Err(RotorError::NoSections);
        }
        for (i, s) in self.sections.iter().enumerate() {
            if !(s.length_m.is_finite() && s.length_m > 0.0) {
                return Err(RotorError::BadLength { section: i, length: s.length_m });
            }
            let (di, d) = (s.inner_diameter_m, s.outer_diameter_m);
            if !(di.is_finite() && d.is_finite() && di >= 0.0 && di < d) {
                return Err(RotorError::BadDiameters { section: i, inner: di, outer: d });
            }
            if s.elements == 0 {
                return Err(RotorError::NoElements { section: i });
            }
            let mat = s.material;
            let ok = mat.youngs_modulus.is_finite()
                && mat.youngs_modulus > 0.0
                && mat.density.is_finite()
                && mat.density > 0.0
                && mat.poisson > -1.0
                && mat.poisson < 0.5;
            if !ok {
                return Err(RotorError::BadMaterial { section: i, material: mat });
            }
        }
        let last = self.n_nodes() - 1;
        for d in &self.disks {
            if d.node > last {
                return Err(RotorError::NoSuchNode { what: "disk", node: d.node, last });
            }
            if !(finite_nonneg(d.mass_kg) && finite_nonneg(d.polar_inertia) && finite_nonneg(d.diametral_inertia)) {
                return Err(RotorError::BadDisk {
                    node: d.node,
                    mass: d.mass_kg,
                    polar: d.polar_inertia,
                    diametral: d.diametral_inertia,
                });
            }
        }
        for b in &self.bearings {
            if b.node > last {
                return Err(RotorError::NoSuchNode { what: "bearing", node: b.node, last });
            }
            for (name, value, direct) in [
                ("kxx", b.kxx, true),
                ("kyy", b.kyy, true),
                ("cxx", b.cxx, true),
                ("cyy", b.cyy, true),
                ("kxy", b.kxy, false),
                ("kyx", b.kyx, false),
            ] {
                if !value.is_finite() || (direct && value < 0.0) {
                    return Err(RotorError::BadBearing { node: b.node, name, value });
                }
            }
            if !b.speed_coefficient.is_finite() {
                return Err(RotorError::BadBearing {
                    node: b.node,
                    name: "speed_coefficient",
                    value: b.speed_coefficient,
                });
            }
            if b.speed_coefficient != 0.0 && !(b.ref_speed_rad_s.is_finite() && b.ref_speed_rad_s > 0.0) {
                return Err(RotorError::BadBearing { node: b.node, name: "ref_speed", value: b.ref_speed_rad_s });
            }
        }
        Ok(())
    }

    /// Validates and assembles M, K, C and G.
    pub fn assemble(&self) -> Result<RotorWhirll, RotorError> {
        self.validate()?;
        let nn = self.n_nodes();
        let n = DOF_PER_NODE * nn;
        let mut model = RotorWhirll {
            n_nodes: nn,
            nodes_z: Vec::with_capacity(nn),
            m: vec![0.0; n * n],
            k: vec![0.0; n * n],
            c: vec![0.0; n * n],
            g: vec![0.0; n * n],
            k2: vec![0.0; n * n],
            laws: Vec::new(),
        };
        model.nodes_z.push(0.0);
        let mut node = 0;
        let mut z = 0.0;
        for s in &self.sections {
            let (d, di) = (s.outer_diameter_m, s.inner_diameter_m);
            let area = PI * (d * d - di * di) / 4.0;
            let inertia = PI * (d.powi(4) - di.powi(4)) / 64.0;
            let mat = s.material;
            let kappa = cowper(mat.poisson, di / d);
            let props = SectionProperties {
                ei: mat.youngs_modulus * inertia,
                ga_s: kappa * mat.shear_modulus() * area,
                rho_a: mat.density * area,
                rho_i: mat.density * inertia,
                eta: 0.0,
            };
            // Polar rotary inertia ρIp = 2ρI for the gyroscopic matrix (Friswell et al. ch. 5).
            let polar = SectionProperties { rho_i: 2.0 * props.rho_i, ..props };
            let le = s.length_m / s.elements as f64;
            let (ke, me, re) =
                (element::stiffness(&props, le), element::mass(&props, le), element::rotary_mass(&polar, le));
            for _ in 0..s.elements {
                model.add_element(node, &ke, &me, &re);
                node += 1;
                z += le;
                model.nodes_z.push(z);
            }
        }
        for d in &self.disks {
            let b = DOF_PER_NODE * d.node;
            model.m[b * n + b] += d.mass_kg;
            model.m[(b + 1) * n + b + 1] += d.mass_kg;
            model.m[(b + 2) * n + b + 2] += d.diametral_inertia;
            model.m[(b + 3) * n + b + 3] += d.diametral_inertia;
            // Friswell et al. ch. 5 (ROSS `DiskElement.G`): the spin couples α̇ into the β equation and back.
            model.g[(b + 2) * n + b + 3] += d.polar_inertia;
            model.g[(b + 3) * n + b + 2] -= d.polar_inertia;
        }
        for br in &self.bearings {
            let b = DOF_PER_NODE * br.node;
            model.k[b * n + b] += br.kxx;
            model.k[b * n + b + 1] += br.kxy;
            model.k[(b + 1) * n + b] += br.kyx;
            model.k[(b + 1) * n + b + 1] += br.kyy;
            model.c[b * n + b] += br.cxx;
            model.c[(b + 1) * n + b + 1] += br.cyy;
            if br.speed_coefficient != 0.0 {
                let per = br.speed_coefficient / (br.ref_speed_rad_s * br.ref_speed_rad_s);
                model.k2[b * n + b] += per * br.kxx;
                model.k2[b * n + b + 1] += per * br.kxy;
                model.k2[(b + 1) * n + b] += per * br.kyx;
                model.k2[(b + 1) * n + b + 1] += per * br.kyy;
                model.laws.push((br.node, per));
            }
        }
        Ok(model)
    }

    /// Modes at a spin speed (rad/s), ascending in damped frequency; see [`RotorWhirll::modes_at`].
    pub fn modes_at(&self, speed_rad_s: f64) -> Result<Vec<RotorWhirl>, RotorError> {
        self.assemble()?.modes_at(speed_rad_s)
    }

    /// Campbell table; see [`RotorWhirll::campbell`].
    pub fn campbell(&self, speeds_rad_s: &[f64], n_modes: usize) -> Result<Vec<CampbellRow>, RotorError> {
        self.assemble()?.campbell(speeds_rad_s, n_modes)
    }

    /// Torsional natural frequencies, rad/s, ascending, the rigid rotation (bearings do not
    /// restrain torsion) left out. A separate uncoupled model of the shaft's twist: two-node
    /// elements with stiffness `GJ/L [[1, −1], [−1, 1]]` and consistent inertia
    /// `ρJL/6 [[2, 1], [1, 2]]`, J = π(do⁴ − di⁴)/32, disks adding their polar inertia (as
    /// ROSS's 6-dof elements; lateral–torsional coupling is zero for a straight rotor).
    pub fn torsional_frequencies(&self) -> Result<Vec<f64>, RotorError> {
        self.validate()?;
        let n = self.n_nodes();
        let (mut k, mut m) = (vec![0.0; n * n], vec![0.0; n * n]);
        let mut node = 0;
        for s in &self.sections {
            let (d, di) = (s.outer_diameter_m, s.inner_diameter_m);
            let j = PI * (d.powi(4) - di.powi(4)) / 32.0;
            let le = s.length_m / s.elements as f64;
            let (kt, mt) = (s.material.shear_modulus() * j / le, s.material.density * j * le / 6.0);
            for _ in 0..s.elements {
                for (a, b, sk, sm) in [(0, 0, 1.0, 2.0), (0, 1, -1.0, 1.0), (1, 0, -1.0, 1.0), (1, 1, 1.0, 2.0)] {
                    k[(node + a) * n + node + b] += sk * kt;
                    m[(node + a) * n + node + b] += sm * mt;
                }
                node += 1;
            }
        }
        for d in &self.disks {
            m[d.node * n + d.node] += d.polar_inertia;
        }
        let mut a: Vec<Complex64> = m.iter().map(|&v| Complex64::new(v, 0.0)).collect();
        let mut b: Vec<Complex64> = k.iter().map(|&v| Complex64::new(v, 0.0)).collect();
        if !solve(&mut a, n, &mut b, n) {
            return Err(RotorError::SingularMass);
        }
        let mat = faer::Mat::<faer::c64>::from_fn(n, n, |i, j| faer::c64::new(b[i * n + j].re, b[i * n + j].im));
        let evd = mat.eigen().map_err(|_| RotorError::NoConvergence)?;
        let s = evd.S().column_vector();
        let mut w2: Vec<f64> = (0..n).map(|i| s[i].re).collect();
        let top = w2.iter().fold(0.0, |acc: f64, v| acc.max(v.abs()));
        w2.retain(|&v| v > 1e-10 * top);
        let mut w: Vec<f64> = w2.into_iter().map(f64::sqrt).collect();
        w.sort_by(f64::total_cmp);
        Ok(w)
    }

    /// Receptance at a node; see [`RotorWhirll::receptance`].
    pub fn receptance(
        &self,
        node: usize,
        direction_in: Direction,
        direction_out: Direction,
        freqs_hz: &[f64],
        speed_rad_s: f64,
    ) -> Result<Vec<Complex64>, RotorError> {
        self.assemble()?.receptance(node, direction_in, node, direction_out, freqs_hz, speed_rad_s)
    }
}

impl RotorWhirll {
    /// The stiffness matrix at spin speed Ω (rad/s), the bearings' speed laws applied.
    fn stiffness_at(&self, speed_rad_s: f64) -> Result<std::borrow::Cow<'_, [f64]>, RotorError> {
        if self.laws.is_empty() {
            return Ok(std::borrow::Cow::Borrowed(&self.k));
        }
        let w2 = speed_rad_s * speed_rad_s;
        if let Some(&(node, per)) = self.laws.iter().find(|(_, per)| 1.0 + per * w2 < 0.0) {
            return Err(RotorError::SoftenedBearing { node, speed_rad_s, factor: 1.0 + per * w2 });
        }
        Ok(std::borrow::Cow::Owned(self.k.iter().zip(&self.k2).map(|(k, k2)| k + w2 * k2).collect()))
    }

    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.n_nodes
    }

    /// Number of degrees of freedom (4 per node).
    pub fn n_dof(&self) -> usize {
        DOF_PER_NODE * self.n_nodes
    }

    /// Axial positions of the nodes, m (node 0 at 0).
    pub fn node_positions(&self) -> &[f64] {
        &self.nodes_z
    }

    /// Mass matrix, row-major.
    pub fn mass(&self) -> &[f64] {
        &self.m
    }

    /// Stiffness matrix at rest, row-major (the bearings' speed laws not applied).
    pub fn stiffness(&self) -> &[f64] {
        &self.k
    }

    /// Bearing damping matrix, row-major.
    pub fn damping(&self) -> &[f64] {
        &self.c
    }

    /// Gyroscopic matrix G (skew-symmetric; the damping at speed Ω is C + ΩG), row-major.
    pub fn gyroscopic(&self) -> &[f64] {
        &self.g
    }

    /// Adds one shaft element between `node` and `node + 1` from the planar matrices
    /// (`[w1, θ1, w2, θ2]`, θ = dw/dz). The x–z plane uses them as they are (β = dx/dz);
    /// the y–z plane with α = −dy/dz flips the sign of the rotations. The gyroscopic coupling
    /// of the polar rotary-inertia matrix R: `G[y-plane, x-plane] = −S R`,
    /// `G[x-plane, y-plane] = R S`, S = diag(1, −1, 1, −1); the signs agree with a disk's
    /// `G[α][β] = +Ip` and reproduce ROSS's whirl frequencies and kappas.
    fn add_element(&mut self, node: usize, ke: &element::Mat4, me: &element::Mat4, re: &element::Mat4) {
        let n = self.n_dof();
        let a = DOF_PER_NODE * node;
        let b = a + DOF_PER_NODE;
        let xp = [a, a + 3, b, b + 3];
        let yp = [a + 1, a + 2, b + 1, b + 2];
        let s = [1.0, -1.0, 1.0, -1.0];
        for i in 0..4 {
            for j in 0..4 {
                self.k[xp[i] * n + xp[j]] += ke[i][j];
                self.m[xp[i] * n + xp[j]] += me[i][j];
                self.k[yp[i] * n + yp[j]] += s[i] * s[j] * ke[i][j];
                self.m[yp[i] * n + yp[j]] += s[i] * s[j] * me[i][j];
                self.g[yp[i] * n + xp[j]] -= s[i] * re[i][j];
                self.g[xp[i] * n + yp[j]] += re[i][j] * s[j];
            }
        }
    }

    /// Modes at spin speed Ω (rad/s) from the state-space eigenproblem (Friswell et al.
    /// ch. 3): the eigenvalues λ with Im λ > 0, ascending in Im λ (overdamped real
    /// roots are left out). Whirl and kappa from the translations of the eigenvector.
    pub fn modes_at(&self, speed_rad_s: f64) -> Result<Vec<RotorWhirl>, RotorError> {
        if !speed_rad_s.is_finite() {
            return Err(RotorError::BadSpeed(speed_rad_s));
        }
        let n = self.n_dof();
        let k = self.stiffness_at(speed_rad_s)?;
        // M⁻¹ [K, C + ΩG] by one solve with 2n right-hand sides.
        let mut a: Vec<Complex64> = self.m.iter().map(|&v| Complex64::new(v, 0.0)).collect();
        let mut rhs = vec![Complex64::new(0.0, 0.0); n * 2 * n];
        for i in 0..n {
            for j in 0..n {
                rhs[i * 2 * n + j] = Complex64::new(k[i * n + j], 0.0);
                rhs[i * 2 * n + n + j] = Complex64::new(self.c[i * n + j] + speed_rad_s * self.g[i * n + j], 0.0);
            }
        }
        if !solve(&mut a, n, &mut rhs, 2 * n) {
            return Err(RotorError::SingularMass);
        }
        let big = 2 * n;
        let state = faer::Mat::<faer::c64>::from_fn(big, big, |i, j| {
            if i < n {
                if j == n + i { faer::c64::new(1.0, 0.0) } else { faer::c64::new(0.0, 0.0) }
            } else {
                let v = -rhs[(i - n) * 2 * n + j];
                faer::c64::new(v.re, v.im)
            }
        });
        if state.col_iter().any(|c| c.iter().any(|v| !v.re.is_finite())) {
            return Err(RotorError::NoConvergence);
        }
        let evd = state.eigen().map_err(|_| RotorError::NoConvergence)?;
        let (u, s) = (evd.U(), evd.S().column_vector());
        let scale = (0..big).map(|i| s[i].norm()).fold(0.0, f64::max);
        let mut modes = Vec::new();
        for c in 0..big {
            let lambda = Complex64::new(s[c].re, s[c].im);
            if lambda.im <= 1e-9 * scale.max(1.0) {
                continue;
            }
            let wn = lambda.norm();
            let kappa: Vec<f64> = (0..self.n_nodes)
                .map(|node| {
                    let x = Complex64::new(u[(DOF_PER_NODE * node, c)].re, u[(DOF_PER_NODE * node, c)].im);
                    let y = Complex64::new(u[(DOF_PER_NODE * node + 1, c)].re, u[(DOF_PER_NODE * node + 1, c)].im);
                    orbit_kappa(x, y)
                })
                .collect();
            modes.push(RotorWhirl {
                wn_rad_s: wn,
                wd_rad_s: lambda.im,
                damping_ratio: -lambda.re / wn,
                whirl: whirl_of(&kappa),
                kappa,
            });
        }
        modes.sort_by(|p, q| p.wd_rad_s.total_cmp(&q.wd_rad_s));
        Ok(modes)
    }

    /// Campbell table: the lowest `n_modes` modes at each speed (rad/s).
    pub fn campbell(&self, speeds_rad_s: &[f64], n_modes: usize) -> Result<Vec<CampbellRow>, RotorError> {
        speeds_rad_s
            .iter()
            .map(|&speed| {
                let mut modes = self.modes_at(speed)?;
                modes.truncate(n_modes);
                Ok(CampbellRow { speed_rad_s: speed, modes })
            })
            .collect()
    }

    /// Receptance `X_out / F_in` (m/N, rad/(N·m), …) between dof `direction_out` at
    /// `node_out` and a unit harmonic load in `direction_in` at `node_in`, at each frequency
    /// (Hz) and spin speed Ω (rad/s), by direct solution of
    /// `(K + iω(C + ΩG) − ω²M) X = F` (the forced response of Friswell et al. ch. 6).
    pub fn receptance(
        &self,
        node_in: usize,
        direction_in: Direction,
        node_out: usize,
        direction_out: Direction,
        freqs_hz: &[f64],
        speed_rad_s: f64,
    ) -> Result<Vec<Complex64>, RotorError> {
        let last = self.n_nodes - 1;
        for node in [node_in, node_out] {
            if node > last {
                return Err(RotorError::NoSuchNode { what: "receptance", node, last });
            }
        }
        if !speed_rad_s.is_finite() {
            return Err(RotorError::BadSpeed(speed_rad_s));
        }
        let n = self.n_dof();
        let k = self.stiffness_at(speed_rad_s)?;
        let (din, dout) =
            (DOF_PER_NODE * node_in + direction_in.offset(), DOF_PER_NODE * node_out + direction_out.offset());
        let mut a = vec![Complex64::new(0.0, 0.0); n * n];
        let mut b = vec![Complex64::new(0.0, 0.0); n];
        let mut out = Vec::with_capacity(freqs_hz.len());
        for &f in freqs_hz {
            if !finite_nonneg(f) {
                return Err(RotorError::BadFrequency(f));
            }
            let w = TAU * f;
            for (idx, z) in a.iter_mut().enumerate() {
                *z = Complex64::new(k[idx] - w * w * self.m[idx], w * (self.c[idx] + speed_rad_s * self.g[idx]));
            }
            b.fill(Complex64::new(0.0, 0.0));
            b[din] = Complex64::new(1.0, 0.0);
            if !solve(&mut a, n, &mut b, 1) {
                return Err(RotorError::Singular(f));
            }
            out.push(b[dout]);
        }
        Ok(out)
    }
}

impl RotorWhirll {
    /// The 4×4 receptance block at `node` in the planar convention of the holder and tool
    /// models ([`crate::beam::SpinningReceptance`]), with the shaft axis z as their beam
    /// axis: rows the response `[x, β, y, −α]` (each plane's displacement and its slope),
    /// columns the excitation `[Fx, Mβ, Fy, −Mα]` (force and the moment conjugate to that
    /// slope). Spin about +z turns x toward y as the beam's spin turns y toward z, so with
    /// isotropic bearings the block has the form `[[P, Q], [−Q, P]]` and couples to a
    /// spinning holder in forward and backward whirl coordinates. Banded solves, four
    /// right-hand sides per line.
    pub fn point_receptance(
        &self,
        node: usize,
        freqs_hz: &[f64],
        speed_rad_s: f64,
    ) -> Result<Vec<crate::beam::SpinningReceptance>, RotorError> {
        let last = self.n_nodes - 1;
        if node > last {
            return Err(RotorError::NoSuchNode { what: "receptance", node, last });
        }
        if !speed_rad_s.is_finite() {
            return Err(RotorError::BadSpeed(speed_rad_s));
        }
        let n = self.n_dof();
        let k = self.stiffness_at(speed_rad_s)?;
        let band = crate::beam::linalg::bandwidth(&[&k, &self.m, &self.c, &self.g], n);
        let base = DOF_PER_NODE * node;
        // Planar order [x, β, y, −α] → rotor dofs, with the sign of each.
        let dofs = [(base, 1.0), (base + 3, 1.0), (base + 1, 1.0), (base + 2, -1.0)];
        let zero = Complex64::new(0.0, 0.0);
        let mut a = vec![zero; n * n];
        let mut b = vec![zero; n * 4];
        let mut out = Vec::with_capacity(freqs_hz.len());
        for &f in freqs_hz {
            if !finite_nonneg(f) {
                return Err(RotorError::BadFrequency(f));
            }
            let w = TAU * f;
            for i in 0..n {
                for j in i.saturating_sub(band)..(i + 2 * band + 1).min(n) {
                    let idx = i * n + j;
                    a[idx] =
                        Complex64::new(k[idx] - w * w * self.m[idx], w * (self.c[idx] + speed_rad_s * self.g[idx]));
                }
            }
            b.fill(zero);
            for (col, &(dof, sign)) in dofs.iter().enumerate() {
                b[dof * 4 + col] = Complex64::new(sign, 0.0);
            }
            if !crate::beam::linalg::complex_solve_banded(&mut a, n, band, &mut b, 4) {
                return Err(RotorError::Singular(f));
            }
            let mut block = [[zero; 4]; 4];
            for (row, &(dof, sign)) in dofs.iter().enumerate() {
                for (col, v) in block[row].iter_mut().enumerate() {
                    *v = sign * b[dof * 4 + col];
                }
            }
            out.push(block);
        }
        Ok(out)
    }
}

/// Signed ellipticity (minor/major, positive when the orbit turns from x toward y) of the
/// orbit `x(t) = Re(X e^{iωt})`, `y(t) = Re(Y e^{iωt})`, ω > 0. The semi-axes a ≥ b obey
/// `a² + b² = |X|² + |Y|²` and `ab = |Im(X Ȳ)|`; the sense is that of `Im(X Ȳ)`.
fn orbit_kappa(x: Complex64, y: Complex64) -> f64 {
    let sum = x.norm_sqr() + y.norm_sqr();
    if sum == 0.0 {
        return 0.0;
    }
    let area = (x * y.conj()).im;
    // a² and b² are the roots of t² − sum·t + area² = 0.
    let disc = (sum * sum - 4.0 * area * area).max(0.0).sqrt();
    let a2 = 0.5 * (sum + disc);
    let b2 = (area * area / a2).max(0.0);
    let k = (b2 / a2).sqrt();
    if area >= 0.0 { k } else { -k }
}

/// Whirl of a mode from its nodes' kappas (straight-line orbits and nodes at rest do not vote).
fn whirl_of(kappa: &[f64]) -> Whirl {
    let fwd = kappa.iter().any(|&k| k > LINE_KAPPA);
    let bwd = kappa.iter().any(|&k| k < -LINE_KAPPA);
    match (fwd, bwd) {
        (true, false) => Whirl::Forward,
        (false, true) => Whirl::Backward,
        _ => Whirl::Mixed,
    }
}

/// Solves `a x = b` in place (`a` n×n row-major, destroyed; `b` n×r row-major, overwritten with
/// x) by Gaussian elimination with partial pivoting. False on a zero or non-finite pivot.
fn solve(a: &mut [Complex64], n: usize, b: &mut [Complex64], r: usize) -> bool {
    for col in 0..n {
        let p = (col..n).max_by(|&i, &j| a[i * n + col].norm().total_cmp(&a[j * n + col].norm())).unwrap_or(col);
        let piv = a[p * n + col];
        if !(piv.norm() > 0.0 && piv.norm().is_finite()) {
            return false;
        }
        if p != col {
            for j in 0..n {
                a.swap(p * n + j, col * n + j);
            }
            for j in 0..r {
                b.swap(p * r + j, col * r + j);
            }
        }
        let inv = 1.0 / piv;
        for i in col + 1..n {
            let f = a[i * n + col] * inv;
            if f == Complex64::new(0.0, 0.0) {
                continue;
            }
            for j in col..n {
                let v = a[col * n + j];
                a[i * n + j] -= f * v;
            }
            for j in 0..r {
                let v = b[col * r + j];
                b[i * r + j] -= f * v;
            }
        }
    }
    for col in (0..n).rev() {
        let inv = 1.0 / a[col * n + col];
        for j in 0..r {
            let mut v = b[col * r + j];
            for k in col + 1..n {
                v -= a[col * n + k] * b[k * r + j];
            }
            b[col * r + j] = v * inv;
        }
    }
    true
}
