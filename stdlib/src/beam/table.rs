//! Reference geometries of dissertation Table 5.1 (sections in mm there, metres here) with the
//! Table 5.2 materials, and the §5.3 fluted end mill: one copy for tests, benches and examples.

use super::{BeamSegment, segments_from_sections};
use spindlelab_domain::entity::{Component, Material, Section};

/// Steel of Table 5.2 as a recipe material.
pub const STEEL: Material = Material { youngs_modulus: 200e9, density: 7800.0, poisson: 0.29, loss_factor: 0.0015 };
/// Carbide of Table 5.2 as a recipe material.
pub const CARBIDE: Material = Material { youngs_modulus: 550e9, density: 15000.0, poisson: 0.22, loss_factor: 0.0015 };

/// Equivalent diameter of the fluted section of the §5.3 end mill, as printed (m).
pub const FLUTED_EQUIVALENT_DIAMETER: f64 = 10.99e-3;

/// The Table 5.1 tool-holder: six steel holder sections (carbide core in section 6) and two
/// solid carbide tool sections, the last one fluted and modelled by its equivalent diameter.
pub fn tool_holder_sections() -> Vec<Section> {
    const D_S: [f64; 8] = [44.46, 31.76, 31.76, 31.08, 30.98, 28.04, 12.70, 10.99];
    const D_T: [f64; 8] = [44.46, 31.76, 31.08, 30.98, 28.04, 24.20, 12.70, 10.99];
    const D_IN: [f64; 8] = [9.00, 9.00, 9.00, 13.56, 12.70, 12.70, 0.00, 0.00];
    const LEN: [f64; 8] = [15.88, 1.56, 4.24, 6.90, 13.05, 25.05, 19.05, 15.88];
    (0..8)
        .map(|i| Section {
            name: format!("s{}", i + 1),
            component: if i < 6 { Component::Holder } else { Component::Tool },
            fluted: i == 7,
            d_out_spindle_end: D_S[i] * 1e-3,
            d_out_tip_end: D_T[i] * 1e-3,
            d_in: D_IN[i] * 1e-3,
            length: LEN[i] * 1e-3,
            outer: if i < 6 { STEEL } else { CARBIDE },
            // M_in: carbide in sections 6, 7 and 8 (7 and 8 are solid, d_in = 0).
            inner: if i >= 5 { Some(CARBIDE) } else { None },
            d_equivalent: if i == 7 { Some(FLUTED_EQUIVALENT_DIAMETER) } else { None },
        })
        .collect()
}

/// Element length the peer benchmark W1 meshes to, m.
const W1_ELEMENT: f64 = 2e-3;

/// Sections meshed as the W1 reference model meshes them: each in `max(1, round(L / 2 mm))`
/// equal pieces with the taper continued, to be meshed one element per piece
/// (`MeshOptions { max_element_length: 1.0, min_taper_elements: 1, .. }`). The Table 5.1
/// tool-holder gives 52 elements, 106 dof.
pub fn w01_segments(sections: &[Section]) -> Vec<BeamSegment> {
    segments_from_sections(sections)
        .iter()
        .flat_map(|s| s.split(((s.length / W1_ELEMENT).round() as usize).max(1)))
        .collect()
}
