//! Cross-section properties of circular, hollow, composite and tapered beam sections
//! (dissertation §5.4, Table 5.1/5.2).
//!
//! A section is an outer tube of one material (outer diameter `d_out`, bore `d_in`) with an
//! optional inner core of another material filling the bore (Table 5.1, `M_in`). Composite
//! rule: the bending stiffness, shear stiffness, mass and rotary inertia per length are
//! summed over the two parts, each part taking its own shear coefficient (Cowper's hollow
//! circle for the tube, Cowper's solid circle for the core). The loss factor of the section
//! is the bending-stiffness weighted mean of the materials' loss factors (exact when both
//! materials share one loss factor, as in Table 5.2).

use super::BeamError;
use std::f64::consts::PI;

/// Elastic, inertial and damping properties of a material (SI).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamMaterial {
    /// Young's modulus E, Pa.
    pub youngs_modulus: f64,
    /// Density ρ, kg/m³.
    pub density: f64,
    /// Poisson's ratio ν.
    pub poisson: f64,
    /// Structural loss factor η (complex modulus E(1 + iη)).
    pub loss_factor: f64,
}

impl BeamMaterial {
    /// Steel of Table 5.2: 200 GPa, ν 0.29, 7800 kg/m³, η 0.0015.
    pub const STEEL: BeamMaterial =
        BeamMaterial { youngs_modulus: 200e9, density: 7800.0, poisson: 0.29, loss_factor: 0.0015 };
    /// Carbide of Table 5.2: 550 GPa, ν 0.22, 15000 kg/m³, η 0.0015.
    pub const CARBIDE: BeamMaterial =
        BeamMaterial { youngs_modulus: 550e9, density: 15000.0, poisson: 0.22, loss_factor: 0.0015 };

    /// Shear modulus G = E / (2(1 + ν)).
    pub fn shear_modulus(&self) -> f64 {
        self.youngs_modulus / (2.0 * (1.0 + self.poisson))
    }

    fn validate(&self, what: &'static str) -> Result<(), BeamError> {
        let ok = self.youngs_modulus.is_finite()
            && self.youngs_modulus > 0.0
            && self.density.is_finite()
            && self.density > 0.0
            && self.poisson.is_finite()
            && self.poisson > -1.0
            && self.poisson < 0.5
            && self.loss_factor.is_finite()
            && self.loss_factor >= 0.0;
        if ok { Ok(()) } else { Err(BeamError::BadMaterial { what, material: *self }) }
    }
}

/// Shear coefficient model for circular sections. Only Cowper's form is provided: Hutchinson's
/// (2001) hollow-circle coefficient is not offered because its exact expression could not be
/// verified here (his solid-circle value is 6(1+ν)²/(7+12ν+4ν²)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ShearCoefficient {
    /// Cowper (1966) hollow circle:
    /// `κ = 6(1+ν)(1+m²)² / ((7+6ν)(1+m²)² + (20+12ν)m²)`, m = d_in/d_out.
    #[default]
    Cowper,
}

impl ShearCoefficient {
    /// κ of a hollow circle with bore ratio `m = d_in / d_out` (0 for a solid circle).
    pub fn hollow_circle(self, poisson: f64, m: f64) -> f64 {
        match self {
            ShearCoefficient::Cowper => {
                let s = (1.0 + m * m).powi(2);
                6.0 * (1.0 + poisson) * s / ((7.0 + 6.0 * poisson) * s + (20.0 + 12.0 * poisson) * m * m)
            }
        }
    }
}

/// Uniform circular cross-section: a tube of `outer` material, optionally filled with a core
/// of `inner` material (diameters in m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrossSection {
    /// Outer diameter, m.
    pub d_out: f64,
    /// Bore (inner) diameter, m; 0 for a solid section.
    pub d_in: f64,
    /// Material of the tube.
    pub outer: BeamMaterial,
    /// Material filling the bore, if any.
    pub inner: Option<BeamMaterial>,
}

/// Per-length properties of a cross-section used by the Timoshenko element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SectionProperties {
    /// Bending stiffness EI, N·m².
    pub ei: f64,
    /// Shear stiffness κGA, N.
    pub ga_s: f64,
    /// Mass per length ρA, kg/m.
    pub rho_a: f64,
    /// Rotary inertia per length ρI, kg·m.
    pub rho_i: f64,
    /// Loss factor η of the section (EI-weighted over materials).
    pub eta: f64,
}

/// Area and second moment of area of a circular ring between diameters `d_in` and `d_out`.
fn ring(d_out: f64, d_in: f64) -> (f64, f64) {
    let a = PI / 4.0 * (d_out * d_out - d_in * d_in);
    let i = PI / 64.0 * (d_out.powi(4) - d_in.powi(4));
    (a, i)
}

impl CrossSection {
    /// Solid circular section.
    pub fn solid(d: f64, material: BeamMaterial) -> CrossSection {
        CrossSection { d_out: d, d_in: 0.0, outer: material, inner: None }
    }

    /// EI, κGA, ρA, ρI and η of the section with the composite rule of the module docs.
    pub fn properties(&self, shear: ShearCoefficient) -> Result<SectionProperties, BeamError> {
        let geometry_ok = self.d_out.is_finite() && self.d_out > 0.0 && self.d_in.is_finite() && self.d_in >= 0.0;
        if !geometry_ok || self.d_in >= self.d_out {
            return Err(BeamError::BadGeometry { d_out: self.d_out, d_in: self.d_in });
        }
        self.outer.validate("outer")?;
        let (a_o, i_o) = ring(self.d_out, self.d_in);
        let o = self.outer;
        let kappa_o = shear.hollow_circle(o.poisson, self.d_in / self.d_out);
        let mut p = SectionProperties {
            ei: o.youngs_modulus * i_o,
            ga_s: kappa_o * o.shear_modulus() * a_o,
            rho_a: o.density * a_o,
            rho_i: o.density * i_o,
            eta: 0.0,
        };
        let mut eta_ei = o.loss_factor * p.ei;
        if let (Some(c), true) = (self.inner, self.d_in > 0.0) {
            c.validate("inner")?;
            let (a_c, i_c) = ring(self.d_in, 0.0);
            let ei_c = c.youngs_modulus * i_c;
            p.ei += ei_c;
            p.ga_s += shear.hollow_circle(c.poisson, 0.0) * c.shear_modulus() * a_c;
            p.rho_a += c.density * a_c;
            p.rho_i += c.density * i_c;
            eta_ei += c.loss_factor * ei_c;
        }
        p.eta = eta_ei / p.ei;
        Ok(p)
    }
}

/// A length of beam whose outer diameter varies linearly from the spindle end to the tip end
/// (a uniform section when both are equal).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamSegment {
    /// Outer diameter at the spindle end, m.
    pub d_out_start: f64,
    /// Outer diameter at the tip end, m.
    pub d_out_end: f64,
    /// Bore diameter, m (0 for solid).
    pub d_in: f64,
    /// Length, m.
    pub length: f64,
    /// Tube material.
    pub outer: BeamMaterial,
    /// Core material filling the bore, if any.
    pub inner: Option<BeamMaterial>,
}

impl BeamSegment {
    /// Uniform segment of a cross-section.
    pub fn uniform(section: CrossSection, length: f64) -> BeamSegment {
        BeamSegment {
            d_out_start: section.d_out,
            d_out_end: section.d_out,
            d_in: section.d_in,
            length,
            outer: section.outer,
            inner: section.inner,
        }
    }

    /// Cross-section at fraction `s` ∈ [0, 1] of the length from the spindle end (linear taper).
    pub fn section_at(&self, s: f64) -> CrossSection {
        CrossSection {
            d_out: self.d_out_start + s * (self.d_out_end - self.d_out_start),
            d_in: self.d_in,
            outer: self.outer,
            inner: self.inner,
        }
    }

    /// Whether the outer diameter changes over the segment.
    pub fn is_tapered(&self) -> bool {
        self.d_out_start != self.d_out_end
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cowper_solid_circle_matches_closed_form() {
        for nu in [0.0, 0.22, 0.29, 0.3, 0.45] {
            let k = ShearCoefficient::Cowper.hollow_circle(nu, 0.0);
            assert!((k - 6.0 * (1.0 + nu) / (7.0 + 6.0 * nu)).abs() < 1e-15);
        }
        // Thin-walled tube limit m → 1: κ → 2(1+ν)/(4+3ν) (Cowper's thin ring).
        let nu = 0.3;
        let k = ShearCoefficient::Cowper.hollow_circle(nu, 1.0 - 1e-9);
        assert!((k - 2.0 * (1.0 + nu) / (4.0 + 3.0 * nu)).abs() < 1e-8, "{k}");
    }

    #[test]
    fn composite_section_sums_bending_stiffness_and_mass() {
        let (d_out, d_in) = (28.04e-3, 12.7e-3);
        let s = CrossSection { d_out, d_in, outer: BeamMaterial::STEEL, inner: Some(BeamMaterial::CARBIDE) };
        let p = s.properties(ShearCoefficient::Cowper).unwrap();
        let ei = 200e9 * PI * (d_out.powi(4) - d_in.powi(4)) / 64.0 + 550e9 * PI * d_in.powi(4) / 64.0;
        let rho_a = 7800.0 * PI * (d_out.powi(2) - d_in.powi(2)) / 4.0 + 15000.0 * PI * d_in.powi(2) / 4.0;
        assert!((p.ei - ei).abs() < 1e-12 * ei);
        assert!((p.rho_a - rho_a).abs() < 1e-12 * rho_a);
        assert!((p.eta - 0.0015).abs() < 1e-15);
        // A core of the same material gives the solid section.
        let same = CrossSection { inner: Some(BeamMaterial::STEEL), outer: BeamMaterial::STEEL, d_out, d_in };
        let solid = CrossSection::solid(d_out, BeamMaterial::STEEL).properties(ShearCoefficient::Cowper).unwrap();
        let p2 = same.properties(ShearCoefficient::Cowper).unwrap();
        assert!((p2.ei - solid.ei).abs() < 1e-12 * solid.ei);
        assert!((p2.rho_i - solid.rho_i).abs() < 1e-12 * solid.rho_i);
    }

    #[test]
    fn bad_geometry_and_material_are_rejected() {
        let s = CrossSection { d_out: 0.01, d_in: 0.02, outer: BeamMaterial::STEEL, inner: None };
        assert!(matches!(s.properties(ShearCoefficient::Cowper), Err(BeamError::BadGeometry { .. })));
        let mut m = BeamMaterial::STEEL;
        m.poisson = 0.7;
        let s = CrossSection::solid(0.01, m);
        assert!(matches!(s.properties(ShearCoefficient::Cowper), Err(BeamError::BadMaterial { .. })));
    }
}
