//! Equivalent diameter of a fluted end mill (dissertation §5.3, Fig. 5.16): the fluted part
//! plus half the tool diameter is replaced by a solid cylinder whose diameter makes the
//! free–free Timoshenko model of the whole tool reproduce a known first bending frequency
//! (from a solid model or a measurement).

use super::BeamError;
use super::model::{BeamModel, MeshOptions};
use super::section::{BeamSegment, CrossSection};
use spindlelab_domain::Material;

/// A solid tool of one material: a cylindrical shank of the tool diameter and, at the tip, the
/// cylinder standing for the fluted part (lengths and diameters in m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlutedTool {
    /// Tool (shank) diameter, m.
    pub diameter: f64,
    /// Overall length, m.
    pub overall_length: f64,
    /// Fluted length, m.
    pub fluted_length: f64,
    /// Tool material.
    pub material: Material,
}

/// Smallest equivalent diameter searched, as a fraction of the tool diameter. The flutes of an
/// end mill leave a core of roughly half to two thirds of the diameter, and the equivalent
/// cylinder is stiffer than the core, so a quarter is well below any real tool.
pub const MIN_DIAMETER_FRACTION: f64 = 0.25;

/// Grid of trial diameters that brackets the root before it is refined.
const SCAN_POINTS: usize = 16;

impl FlutedTool {
    /// Length of the equivalent cylinder: fluted length plus half the tool diameter (§5.3).
    pub fn equivalent_length(&self) -> f64 {
        self.fluted_length + 0.5 * self.diameter
    }

    fn validate(&self) -> Result<(), BeamError> {
        let vals = [self.diameter, self.overall_length, self.fluted_length];
        if vals.iter().any(|v| !(v.is_finite() && *v > 0.0)) || self.equivalent_length() >= self.overall_length {
            return Err(BeamError::BadFlutedTool { tool: *self });
        }
        Ok(())
    }

    /// Shank (spindle end) and equivalent cylinder of diameter `d_equivalent` (tip end).
    pub fn segments(&self, d_equivalent: f64) -> [BeamSegment; 2] {
        let le = self.equivalent_length();
        [
            BeamSegment::uniform(CrossSection::solid(self.diameter, self.material), self.overall_length - le),
            BeamSegment::uniform(CrossSection::solid(d_equivalent, self.material), le),
        ]
    }

    /// First free–free bending frequency (Hz) of the tool with an equivalent diameter.
    pub fn first_bending_frequency(&self, d_equivalent: f64, mesh: &MeshOptions) -> Result<f64, BeamError> {
        self.validate()?;
        first_bending(&self.segments(d_equivalent), mesh)
    }
}

/// First elastic natural frequency (Hz) of a free–free beam.
fn first_bending(segments: &[BeamSegment], mesh: &MeshOptions) -> Result<f64, BeamError> {
    let modes = BeamModel::from_segments(segments, mesh)?.modes()?;
    Ok(modes.natural_frequencies()[modes.rigid_modes()])
}

/// Diameter of the equivalent cylinder (m) whose free–free model of the whole tool has the
/// first bending frequency `first_bending_hz` (§5.3). The search covers
/// [`MIN_DIAMETER_FRACTION`] of the tool diameter up to the tool diameter itself (flutes only
/// remove material); if several diameters match, the largest is returned.
pub fn equivalent_diameter(tool: &FlutedTool, first_bending_hz: f64, mesh: &MeshOptions) -> Result<f64, BeamError> {
    tool.validate()?;
    if !(first_bending_hz.is_finite() && first_bending_hz > 0.0) {
        return Err(BeamError::BadFrequency(first_bending_hz));
    }
    let (d_min, d_max) = (MIN_DIAMETER_FRACTION * tool.diameter, tool.diameter);
    let g = |d: f64| -> Result<f64, BeamError> { Ok(tool.first_bending_frequency(d, mesh)? - first_bending_hz) };
    // Scan from the largest diameter down for the first sign change.
    let mut hi = (d_max, g(d_max)?);
    if hi.1 == 0.0 {
        return Ok(d_max);
    }
    let (mut lowest, mut highest) = (hi.1, hi.1);
    for k in 1..SCAN_POINTS {
        let d = d_max - (d_max - d_min) * k as f64 / (SCAN_POINTS - 1) as f64;
        let lo = (d, g(d)?);
        lowest = lowest.min(lo.1);
        highest = highest.max(lo.1);
        if lo.1 == 0.0 {
            return Ok(d);
        }
        if lo.1.signum() != hi.1.signum() {
            return refine(&g, lo, hi);
        }
        hi = lo;
    }
    Err(BeamError::EquivalentOutOfReach {
        target: first_bending_hz,
        lowest: first_bending_hz + lowest,
        highest: first_bending_hz + highest,
        d_min,
        d_max,
    })
}

/// Illinois regula falsi on a sign-changing bracket `(d, g(d))`, to 1e-12 of the diameter.
fn refine(g: &impl Fn(f64) -> Result<f64, BeamError>, a: (f64, f64), b: (f64, f64)) -> Result<f64, BeamError> {
    let (mut a, mut b) = (a, b);
    let mut side = 0i8;
    for _ in 0..100 {
        let d = (a.0 * b.1 - b.0 * a.1) / (b.1 - a.1);
        if (b.0 - a.0).abs() <= 1e-12 * b.0.abs().max(a.0.abs()) {
            return Ok(d);
        }
        let gd = g(d)?;
        if gd == 0.0 {
            return Ok(d);
        }
        if gd.signum() == b.1.signum() {
            b = (d, gd);
            if side == 1 {
                a.1 *= 0.5;
            }
            side = 1;
        } else {
            a = (d, gd);
            if side == -1 {
                b.1 *= 0.5;
            }
            side = -1;
        }
    }
    Ok(0.5 * (a.0 + b.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::beam::ShearCoefficient;

    /// §5.3: 12.7 mm solid carbide end mill, 76.2 mm long, 25.4 mm fluted.
    fn tool() -> FlutedTool {
        FlutedTool { diameter: 12.7e-3, overall_length: 76.2e-3, fluted_length: 25.4e-3, material: Material::CARBIDE }
    }

    #[test]
    fn section_5_3_tool_gives_the_published_equivalent_diameter() {
        // ANSYS first free–free bending mode 10610.9 Hz → 10.98 mm in the text, printed to
        // 0.01 mm. This model gives 10.9771 mm (2 mm elements; 10.9785 mm converged at 0.5 mm):
        // within the half unit (5 µm) of the printed value.
        let t = tool();
        assert!((t.equivalent_length() - 31.75e-3).abs() < 1e-15);
        let mesh = MeshOptions::default();
        let d = equivalent_diameter(&t, 10610.9, &mesh).unwrap();
        assert!((d - 10.98e-3).abs() < 5e-6, "{d}");
        // Round trip: the tool built with the found diameter has the target frequency.
        let f = first_bending(&t.segments(d), &mesh).unwrap();
        assert!((f - 10610.9).abs() < 1e-8 * 10610.9, "{f}");
        // Hutchinson's larger κ stiffens the tool, so a slimmer cylinder matches: 10.956 mm.
        let hutchinson = MeshOptions { shear: ShearCoefficient::Hutchinson, ..mesh };
        let dh = equivalent_diameter(&t, 10610.9, &hutchinson).unwrap();
        assert!(dh < d && d - dh > 10e-6 && d - dh < 40e-6, "{dh} vs {d}");
    }

    #[test]
    fn solid_blank_frequency_gives_the_tool_diameter() {
        // A target equal to the unfluted blank's frequency is met by the full diameter, and a
        // frequency in between by a diameter in between.
        let t = tool();
        let mesh = MeshOptions { max_element_length: 4e-3, ..MeshOptions::default() };
        let blank = t.first_bending_frequency(t.diameter, &mesh).unwrap();
        let d = equivalent_diameter(&t, blank, &mesh).unwrap();
        assert!((d - t.diameter).abs() < 1e-12, "{d}");
        let half = t.first_bending_frequency(0.6 * t.diameter, &mesh).unwrap();
        let d = equivalent_diameter(&t, half, &mesh).unwrap();
        assert!((d - 0.6 * t.diameter).abs() < 1e-9 * t.diameter, "{d}");
    }

    #[test]
    fn unreachable_frequencies_and_bad_tools_are_rejected() {
        let t = tool();
        let mesh = MeshOptions { max_element_length: 4e-3, ..MeshOptions::default() };
        // Above the solid blank (flutes cannot stiffen a tool) or below a quarter-diameter tip.
        for target in [12_000.0, 2_000.0] {
            match equivalent_diameter(&t, target, &mesh) {
                Err(BeamError::EquivalentOutOfReach { target: tg, lowest, highest, d_min, d_max }) => {
                    assert_eq!(tg, target);
                    assert!(lowest > 2_000.0 && highest < 12_000.0 && lowest < highest, "{lowest} {highest}");
                    assert!((d_min - 0.25 * t.diameter).abs() < 1e-15 && d_max == t.diameter);
                }
                other => panic!("{target} Hz: {other:?}"),
            }
        }
        for target in [f64::NAN, -5.0, 0.0, f64::INFINITY] {
            assert!(matches!(equivalent_diameter(&t, target, &mesh), Err(BeamError::BadFrequency(_))));
        }
        let too_long = FlutedTool { fluted_length: 70e-3, ..t };
        let zero = FlutedTool { diameter: 0.0, ..t };
        let nan = FlutedTool { overall_length: f64::NAN, ..t };
        for bad in [too_long, zero, nan] {
            assert!(matches!(equivalent_diameter(&bad, 10610.9, &mesh), Err(BeamError::BadFlutedTool { .. })));
        }
    }
}
