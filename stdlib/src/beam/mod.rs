//! Timoshenko beam finite elements for free–free tool/holder/artifact assemblies
//! (dissertation Chapter 5: §5.1 receptances, §5.4 and Table 5.1 section models).
//!
//! Conventions: planar bending, transverse displacement y (m) and rotation θ = dy/dx (rad);
//! force along +y, moment positive in the θ sense. Receptances `H = y/F`, `L = y/M`,
//! `N = θ/F`, `P = θ/M` (Eq. 5.2). Node 0 is the spindle end, the last node the tip. With
//! these signs a fixed-free cantilever's tip has static `H = L³/3EI`, `L = N = L²/2EI`,
//! `P = L/EI`, all positive.
//!
//! [`section`] computes EI, κGA, ρA, ρI of circular/hollow/composite sections,
//! [`element`] the 4×4 Timoshenko matrices, [`model`] the assembly (point masses, springs
//! with dampers) and the receptances by direct solve or modal expansion, [`spinning`] the
//! speed-dependent model of both planes with gyroscopic coupling (§5.4 rotor, Nelson 1980),
//! [`equivalent`] the equivalent diameter of a fluted tool (§5.3), and [`table`] the Table 5.1
//! reference geometries.

mod csym;
pub mod element;
pub mod equivalent;
mod jacobi;
pub(crate) mod linalg;
pub mod model;
pub mod section;
pub mod spinning;
pub mod table;

#[cfg(test)]
mod tests;

pub use equivalent::{FlutedTool, equivalent_diameter};
pub use model::{BeamModel, DampingForm, EigenSolver, MeshOptions, ModalModel, NodeSpring, Receptance, ReducedModes};
pub use section::{BeamSegment, CrossSection, SectionProperties, ShearCoefficient};
pub use spinning::{SpinningModel, SpinningReceptance, Whirl};

use spindlelab_domain::entity::{Material, Section};
use thiserror::Error;

/// Errors of the beam model.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum BeamError {
    /// A diameter is not positive/finite or the bore is not smaller than the outer diameter.
    #[error("bad section geometry: outer diameter {d_out} m, bore {d_in} m (need 0 <= d_in < d_out)")]
    BadGeometry { d_out: f64, d_in: f64 },
    /// A material property is out of range.
    #[error("bad {what} material {material:?}: need E > 0, rho > 0, -1 < nu < 0.5, eta >= 0")]
    BadMaterial { what: &'static str, material: Material },
    /// A segment's properties could not be computed.
    #[error("segment {segment}: {source}")]
    Segment { segment: usize, source: Box<BeamError> },
    /// A segment length is not positive.
    #[error("segment {segment} has length {length} m; it must be positive")]
    BadLength { segment: usize, length: f64 },
    /// No segments were given.
    #[error("the beam has no segments")]
    NoSegments,
    /// The element length limit is not positive.
    #[error("maximum element length {0} m must be positive")]
    BadElementLength(f64),
    /// The mesh would exceed [`model::MAX_ELEMENTS`] elements.
    #[error("the mesh needs {elements} elements, more than {limit}; use a longer maximum element length")]
    TooManyElements { elements: f64, limit: usize },
    /// A node index is out of range.
    #[error("node {node} does not exist; the model has {nodes} nodes (0 = spindle end)")]
    NoSuchNode { node: usize, nodes: usize },
    /// A point mass or rotary inertia is negative or not finite.
    #[error("bad point mass at node {node}: mass {mass} kg, rotary inertia {rotary_inertia} kg m^2")]
    BadPointMass { node: usize, mass: f64, rotary_inertia: f64 },
    /// A spring or damper value is negative or not finite.
    #[error("bad spring at node {node}: {spring:?}; values must be finite and >= 0")]
    BadSpring { node: usize, spring: NodeSpring },
    /// A frequency is negative or not finite.
    #[error("frequency {0} Hz must be finite and >= 0")]
    BadFrequency(f64),
    /// A spin speed is not finite.
    #[error("spin speed {0} rad/s must be finite")]
    BadSpeed(f64),
    /// The dynamic stiffness is singular at a frequency (e.g. 0 Hz on a free–free beam).
    #[error("dynamic stiffness is singular at {0} Hz (a free-free beam has no static receptance)")]
    Singular(f64),
    /// A fluted tool's dimensions are not positive, or the equivalent cylinder (fluted length
    /// plus half the diameter) is not shorter than the tool.
    #[error("bad fluted tool {tool:?}: need positive sizes and fluted length + diameter/2 < overall length")]
    BadFlutedTool { tool: FlutedTool },
    /// No equivalent diameter in the searched range reaches the target frequency.
    #[error(
        "first bending frequency {target} Hz is out of reach: equivalent diameters {d_min} m to {d_max} m give \
         {lowest} Hz to {highest} Hz; check the frequency and the tool's dimensions and material"
    )]
    EquivalentOutOfReach { target: f64, lowest: f64, highest: f64, d_min: f64, d_max: f64 },
    /// The mass matrix is not positive definite.
    #[error("mass matrix is not positive definite")]
    MassNotDefinite,
    /// The structurally damped model has (nearly) repeated complex modes, so it has no modal
    /// form; the direct solve (`receptance_direct`) still applies.
    #[error("the damped model has nearly repeated complex modes and no modal form; use the direct solve")]
    DefectiveDamping,
    /// Viscous dampers make the modal form frequency dependent, so it cannot be reduced to
    /// coupling points.
    #[error(
        "node dampers make the model's damping frequency dependent; it has no reduced modal form (remove the dampers, or couple the full model)"
    )]
    NotReducible,
    /// The eigen-solver did not converge (a matrix with non-finite entries).
    #[error("the eigen-solver did not converge")]
    NoConvergence,
}

/// Converts recipe sections (Table 5.1, lengths in m) into beam segments. A fluted section
/// with an equivalent diameter (Fig. 5.16) is modelled as a solid cylinder of that diameter;
/// an inner material is kept only where there is a bore (`d_in > 0`).
pub fn segments_from_sections(sections: &[Section]) -> Vec<BeamSegment> {
    sections
        .iter()
        .map(|s| {
            let (d0, d1) = match (s.fluted, s.d_equivalent) {
                (true, Some(d)) => (d, d),
                _ => (s.d_out_spindle_end, s.d_out_tip_end),
            };
            BeamSegment {
                d_out_start: d0,
                d_out_end: d1,
                d_in: s.d_in,
                length: s.length,
                outer: s.outer,
                inner: if s.d_in > 0.0 { s.inner } else { None },
            }
        })
        .collect()
}
