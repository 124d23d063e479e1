//! Cross-section properties of circular, hollow, composite and tapered beam sections
//! (dissertation §5.4, Table 5.1/5.2).
//!
//! A section is an outer tube of one material (outer diameter `d_out`, bore `d_in`) with an
//! optional inner core of another material filling the bore (Table 5.1, `M_in`). Composite
//! rule: the bending stiffness, mass and rotary inertia per length are summed over the two
//! parts. A filled bore makes the section geometrically solid, so its shear stiffness is the
//! solid-circle coefficient, taken at the shear-stiffness weighted Poisson's ratio, times the
//! summed `G·A` of the parts: `κGA = κ_solid(ν̄) (G_o A_o + G_c A_c)`,
//! `ν̄ = Σ ν_i G_i A_i / Σ G_i A_i`. A core of the tube's own material therefore gives exactly
//! the solid section, and an empty bore the hollow-circle coefficient. The loss factor of the
//! section is the bending-stiffness weighted mean of the materials' loss factors (exact when
//! both materials share one loss factor, as in Table 5.2).

use super::BeamError;
use spindlelab_domain::Material;
use std::f64::consts::PI;

/// The checks a Timoshenko section makes of a material: E and ρ positive, ν in (−1, ½), η ≥ 0.
fn validate(m: &Material, what: &'static str) -> Result<(), BeamError> {
    let ok = m.youngs_modulus.is_finite()
        && m.youngs_modulus > 0.0
        && m.density.is_finite()
        && m.density > 0.0
        && m.poisson.is_finite()
        && m.poisson > -1.0
        && m.poisson < 0.5
        && m.loss_factor.is_finite()
        && m.loss_factor >= 0.0;
    if ok { Ok(()) } else { Err(BeamError::BadMaterial { what, material: *m }) }
}

/// Shear coefficient model for circular sections (solid, hollow and, through the composite
/// rule of the module docs, filled). Both forms give κ for a hollow circle of bore ratio
/// `m = d_in / d_out`; Cowper's is the default. Hutchinson's is the larger of the two (3.2 %
/// for a solid carbide section, ν = 0.22), so it makes a shear-dominated mode stiffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ShearCoefficient {
    /// Cowper (1966) hollow circle:
    /// `κ = 6(1+ν)(1+m²)² / ((7+6ν)(1+m²)² + (20+12ν)m²)`; solid `6(1+ν)/(7+6ν)`, thin tube
    /// `2(1+ν)/(4+3ν)`.
    #[default]
    Cowper,
    /// Hutchinson (2001, J. Appl. Mech. 68:87–92) hollow circle, outer radius a, inner b:
    /// `κ = 6(a²+b²)²(1+ν)² / (7a⁴+34a²b²+7b⁴ + ν(12a⁴+48a²b²+12b⁴) + ν²(4a⁴+16a²b²+4b⁴))`
    /// (identical to Stephen and Levinson's); solid `6(1+ν)²/(7+12ν+4ν²)`, thin tube
    /// `(1+ν)/(2+ν)`.
    Hutchinson,
}

impl ShearCoefficient {
    /// κ of a hollow circle with bore ratio `m = d_in / d_out` (0 for a solid circle).
    pub fn hollow_circle(self, poisson: f64, m: f64) -> f64 {
        let m2 = m * m;
        match self {
            ShearCoefficient::Cowper => {
                let s = (1.0 + m2).powi(2);
                6.0 * (1.0 + poisson) * s / ((7.0 + 6.0 * poisson) * s + (20.0 + 12.0 * poisson) * m2)
            }
            ShearCoefficient::Hutchinson => {
                // With a = 1, b = m: (a⁴ + b⁴) and a²b² terms of the published form.
                let (q, p) = (1.0 + m2 * m2, m2);
                let nu = poisson;
                let den = 7.0 * q + 34.0 * p + nu * (12.0 * q + 48.0 * p) + nu * nu * (4.0 * q + 16.0 * p);
                6.0 * (1.0 + m2).powi(2) * (1.0 + nu).powi(2) / den
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
    pub outer: Material,
    /// Material filling the bore, if any.
    pub inner: Option<Material>,
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
    pub fn solid(d: f64, material: Material) -> CrossSection {
        CrossSection { d_out: d, d_in: 0.0, outer: material, inner: None }
    }

    /// EI, κGA, ρA, ρI and η of the section with the composite rule of the module docs.
    pub fn properties(&self, shear: ShearCoefficient) -> Result<SectionProperties, BeamError> {
        let geometry_ok = self.d_out.is_finite() && self.d_out > 0.0 && self.d_in.is_finite() && self.d_in >= 0.0;
        if !geometry_ok || self.d_in >= self.d_out {
            return Err(BeamError::BadGeometry { d_out: self.d_out, d_in: self.d_in });
        }
        validate(&self.outer, "outer")?;
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
            validate(&c, "inner")?;
            let (a_c, i_c) = ring(self.d_in, 0.0);
            let ei_c = c.youngs_modulus * i_c;
            p.ei += ei_c;
            let (ga_o, ga_c) = (o.shear_modulus() * a_o, c.shear_modulus() * a_c);
            let nu = (o.poisson * ga_o + c.poisson * ga_c) / (ga_o + ga_c);
            p.ga_s = shear.hollow_circle(nu, 0.0) * (ga_o + ga_c);
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
    pub outer: Material,
    /// Core material filling the bore, if any.
    pub inner: Option<Material>,
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

    /// Cross-sections at the spindle end and the tip end, with the diameters exactly as given.
    pub fn end_sections(&self) -> [CrossSection; 2] {
        [self.d_out_start, self.d_out_end].map(|d_out| CrossSection { d_out, ..self.section_at(0.0) })
    }

    /// Whether the outer diameter changes over the segment.
    pub fn is_tapered(&self) -> bool {
        self.d_out_start != self.d_out_end
    }

    /// The segment cut into `pieces` equal lengths, the taper continued piece to piece; with
    /// one element per piece this meshes a segment into exactly `pieces` elements.
    pub fn split(&self, pieces: usize) -> Vec<BeamSegment> {
        let pieces = pieces.max(1);
        (0..pieces)
            .map(|k| {
                let (a, b) = (k as f64 / pieces as f64, (k + 1) as f64 / pieces as f64);
                BeamSegment {
                    d_out_start: self.section_at(a).d_out,
                    d_out_end: self.section_at(b).d_out,
                    length: self.length / pieces as f64,
                    ..*self
                }
            })
            .collect()
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

    /// Hutchinson's published form in the radii themselves (not the bore ratio).
    fn hutchinson_radii(nu: f64, a: f64, b: f64) -> f64 {
        let (a2, b2) = (a * a, b * b);
        let (a4, b4, ab) = (a2 * a2, b2 * b2, a2 * b2);
        let den = 7.0 * a4
            + 34.0 * ab
            + 7.0 * b4
            + nu * (12.0 * a4 + 48.0 * ab + 12.0 * b4)
            + nu * nu * (4.0 * a4 + 16.0 * ab + 4.0 * b4);
        6.0 * (a2 + b2).powi(2) * (1.0 + nu).powi(2) / den
    }

    #[test]
    fn hutchinson_hollow_circle_limits_and_equivalent_forms() {
        let h = ShearCoefficient::Hutchinson;
        for nu in [0.0f64, 0.22, 0.29, 0.3, 0.45] {
            // Solid limit b → 0.
            let solid = 6.0 * (1.0 + nu).powi(2) / (7.0 + 12.0 * nu + 4.0 * nu * nu);
            assert!((h.hollow_circle(nu, 0.0) - solid).abs() < 1e-15);
            assert!((h.hollow_circle(nu, 1e-6) - solid).abs() < 1e-10);
            // Thin-walled limit b → a: (1+ν)/(2+ν).
            let thin = (1.0 + nu) / (2.0 + nu);
            assert!((h.hollow_circle(nu, 1.0 - 1e-9) - thin).abs() < 1e-8);
            for m in [0.1, 0.3, 0.4529, 0.7, 0.95] {
                let k = h.hollow_circle(nu, m);
                // Scale invariance: the radii form with a = 6.35 mm gives the same κ.
                let a = 6.35e-3;
                assert!((k - hutchinson_radii(nu, a, m * a)).abs() < 1e-14, "nu {nu} m {m}");
                // Stephen–Levinson's grouping of the same expression.
                let s = (1.0 + m * m).powi(2);
                let stephen = 6.0 * (1.0 + nu).powi(2) * s
                    / ((7.0 + 12.0 * nu + 4.0 * nu * nu) * s + 4.0 * (5.0 + 6.0 * nu + 2.0 * nu * nu) * m * m);
                assert!((k - stephen).abs() < 1e-14);
                // Hutchinson's κ exceeds Cowper's for every ν ≥ 0 and bore ratio.
                let c = ShearCoefficient::Cowper.hollow_circle(nu, m);
                assert!(nu == 0.0 && (k - c).abs() < 1e-12 || k > c, "nu {nu} m {m}: {k} vs {c}");
            }
        }
        // Carbide (ν = 0.22): 0.908152 against Cowper's 0.879808, 3.22 % larger.
        let (k, c) = (h.hollow_circle(0.22, 0.0), ShearCoefficient::Cowper.hollow_circle(0.22, 0.0));
        assert!((k - 0.908_151_643).abs() < 1e-9 && (c - 0.879_807_692).abs() < 1e-9);
        assert!((k / c - 1.032_216).abs() < 1e-6);
    }

    #[test]
    fn filled_bore_takes_the_solid_circle_coefficient() {
        let (d_out, d_in) = (28.04e-3, 12.7e-3);
        for shear in [ShearCoefficient::Cowper, ShearCoefficient::Hutchinson] {
            // A core of the tube's own material is the solid section, shear included.
            let same = CrossSection { d_out, d_in, outer: Material::STEEL, inner: Some(Material::STEEL) };
            let solid = CrossSection::solid(d_out, Material::STEEL).properties(shear).unwrap();
            let p = same.properties(shear).unwrap();
            assert!((p.ga_s - solid.ga_s).abs() < 1e-12 * solid.ga_s, "{shear:?}");
            // Steel on carbide: κ(ν̄) of the solid circle times the summed G·A.
            let (st, cb) = (Material::STEEL, Material::CARBIDE);
            let s = CrossSection { d_out, d_in, outer: st, inner: Some(cb) };
            let a_o = PI / 4.0 * (d_out * d_out - d_in * d_in);
            let a_c = PI / 4.0 * d_in * d_in;
            let (ga_o, ga_c) = (st.shear_modulus() * a_o, cb.shear_modulus() * a_c);
            let nu = (0.29 * ga_o + 0.22 * ga_c) / (ga_o + ga_c);
            assert!(nu > 0.22 && nu < 0.29);
            let expected = shear.hollow_circle(nu, 0.0) * (ga_o + ga_c);
            let got = s.properties(shear).unwrap().ga_s;
            assert!((got - expected).abs() < 1e-12 * expected, "{shear:?}: {got} vs {expected}");
            // An empty bore keeps the hollow-circle coefficient.
            let tube = CrossSection { d_out, d_in, outer: st, inner: None }.properties(shear).unwrap();
            let k = shear.hollow_circle(0.29, d_in / d_out);
            assert!((tube.ga_s - k * ga_o).abs() < 1e-12 * tube.ga_s);
        }
    }

    #[test]
    fn composite_section_sums_bending_stiffness_and_mass() {
        let (d_out, d_in) = (28.04e-3, 12.7e-3);
        let s = CrossSection { d_out, d_in, outer: Material::STEEL, inner: Some(Material::CARBIDE) };
        let p = s.properties(ShearCoefficient::Cowper).unwrap();
        let ei = 200e9 * PI * (d_out.powi(4) - d_in.powi(4)) / 64.0 + 550e9 * PI * d_in.powi(4) / 64.0;
        let rho_a = 7800.0 * PI * (d_out.powi(2) - d_in.powi(2)) / 4.0 + 15000.0 * PI * d_in.powi(2) / 4.0;
        assert!((p.ei - ei).abs() < 1e-12 * ei);
        assert!((p.rho_a - rho_a).abs() < 1e-12 * rho_a);
        assert!((p.eta - 0.0015).abs() < 1e-15);
        // A core of the same material gives the solid section.
        let same = CrossSection { inner: Some(Material::STEEL), outer: Material::STEEL, d_out, d_in };
        let solid = CrossSection::solid(d_out, Material::STEEL).properties(ShearCoefficient::Cowper).unwrap();
        let p2 = same.properties(ShearCoefficient::Cowper).unwrap();
        assert!((p2.ei - solid.ei).abs() < 1e-12 * solid.ei);
        assert!((p2.rho_i - solid.rho_i).abs() < 1e-12 * solid.rho_i);
    }

    #[test]
    fn bad_geometry_and_material_are_rejected() {
        let s = CrossSection { d_out: 0.01, d_in: 0.02, outer: Material::STEEL, inner: None };
        assert!(matches!(s.properties(ShearCoefficient::Cowper), Err(BeamError::BadGeometry { .. })));
        let mut m = Material::STEEL;
        m.poisson = 0.7;
        let s = CrossSection::solid(0.01, m);
        assert!(matches!(s.properties(ShearCoefficient::Cowper), Err(BeamError::BadMaterial { .. })));
    }
}
