//! Spindle speed: one type, rad/s inside, rpm at the edges; and the one speed law of a
//! spindle mode.

use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;
use std::fmt;

/// A spindle speed. Held in rad/s (SI, as the grammar converts every recipe quantity); built
/// from and shown in rpm, the unit recipes, tables and figures write.
///
/// Serialized as rpm where people read it (JSON output files: the number as written,
/// [`Speed::rpm_as_written`]) and as the exact rad/s where only the program does (the
/// binary cache), so a cached value is bit for bit the computed one.
#[derive(Debug, Clone, Copy, Default, PartialEq, PartialOrd)]
pub struct Speed(f64);

impl Serialize for Speed {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if s.is_human_readable() { s.serialize_f64(self.rpm_as_written()) } else { s.serialize_f64(self.0) }
    }
}

impl<'de> Deserialize<'de> for Speed {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Speed, D::Error> {
        let human = d.is_human_readable();
        let v = f64::deserialize(d)?;
        Ok(if human { Speed::from_rpm(v) } else { Speed(v) })
    }
}

impl Speed {
    /// At rest.
    pub const ZERO: Speed = Speed(0.0);

    /// A speed in rad/s, as a recipe's quantities arrive.
    pub const fn from_rad_s(omega: f64) -> Speed {
        Speed(omega)
    }

    /// A speed in revolutions per minute.
    pub fn from_rpm(rpm: f64) -> Speed {
        Speed(rpm * TAU / 60.0)
    }

    /// The speed in rad/s.
    pub const fn rad_s(self) -> f64 {
        self.0
    }

    /// The speed in revolutions per minute.
    pub fn rpm(self) -> f64 {
        self.0 * 60.0 / TAU
    }

    /// The speed in rpm rounded to 1e-6 rpm: a speed a recipe or file wrote in rpm reads back
    /// as written (`1500 rpm` is 1500, not 1500.0000000000002), for labels, tables and keys.
    pub fn rpm_as_written(self) -> f64 {
        (self.rpm() * 1e6).round() / 1e6
    }

    /// Revolutions per second, Hz: the spindle's rotation frequency.
    pub fn rev_per_s(self) -> f64 {
        self.0 / TAU
    }

    /// Whether the spindle stands still.
    pub fn is_rest(self) -> bool {
        self.0 == 0.0
    }
}

impl fmt::Display for Speed {
    /// In rpm to six significant digits: `12000 rpm`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} rpm", crate::sig(self.rpm(), 6))
    }
}

/// How a spindle mode changes with speed `n` about a reference speed `n_ref`:
/// `f(n) = f₀ (1 + kf (n/n_ref)²)` and the damping (a loss factor or a damping ratio, whichever
/// the mode carries) `d(n) = d₀ (1 + kd (n/n_ref)²)`. Stiffness, mass and diameter do not
/// change. The one law of the recipe's spindle modes, the virtual rig and the equivalent
/// Euler–Bernoulli spindle.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct SpeedLaw {
    /// Relative change of the natural frequency at the reference speed.
    pub kf: f64,
    /// Relative change of the damping at the reference speed.
    pub kd: f64,
}

impl SpeedLaw {
    /// No change with speed.
    pub const NONE: SpeedLaw = SpeedLaw { kf: 0.0, kd: 0.0 };

    /// `(n/n_ref)²`; zero at rest whatever the reference (a mode at rest is the mode as
    /// written, even where no reference speed is given).
    pub fn ratio_squared(n: Speed, reference: Speed) -> f64 {
        if n.is_rest() { 0.0 } else { (n.rad_s() / reference.rad_s()).powi(2) }
    }

    /// The natural frequency at `n` of a mode at `freq` at rest.
    pub fn frequency(&self, freq: f64, n: Speed, reference: Speed) -> f64 {
        freq * (1.0 + self.kf * Self::ratio_squared(n, reference))
    }

    /// The damping at `n` of a mode with damping `damping` at rest.
    pub fn damping(&self, damping: f64, n: Speed, reference: Speed) -> f64 {
        damping * (1.0 + self.kd * Self::ratio_squared(n, reference))
    }

    /// Whether the mode changes with speed at all.
    pub fn is_none(&self) -> bool {
        self.kf == 0.0 && self.kd == 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speed_round_trips_through_rpm_and_shows_rpm() {
        let s = Speed::from_rpm(12_000.0);
        assert!((s.rad_s() - 12_000.0 * TAU / 60.0).abs() < 1e-12);
        assert!((s.rpm() - 12_000.0).abs() < 1e-9);
        assert_eq!((s.rev_per_s() * 1e6).round(), 200e6);
        assert_eq!(s.to_string(), "12000 rpm");
        assert_eq!(Speed::ZERO.to_string(), "0 rpm");
    }

    #[test]
    fn people_read_rpm_and_the_cache_keeps_the_bits() {
        let s = Speed::from_rad_s(1_234.567_890_123_4);
        let json = serde_json::to_string(&s).unwrap();
        assert_eq!(json, format!("{}", s.rpm_as_written()));
        let back: Speed = serde_json::from_str("1500").unwrap();
        assert_eq!(back, Speed::from_rpm(1500.0));
        assert_eq!(back.rpm_as_written(), 1500.0);
        let bytes = postcard::to_stdvec(&s).unwrap();
        assert_eq!(postcard::from_bytes::<Speed>(&bytes).unwrap().rad_s().to_bits(), s.rad_s().to_bits());
    }

    #[test]
    fn the_speed_law_is_quadratic_and_the_mode_at_rest_is_as_written() {
        let law = SpeedLaw { kf: -0.04, kd: 0.5 };
        let r = Speed::from_rpm(10_000.0);
        assert_eq!(law.frequency(800.0, Speed::ZERO, r), 800.0);
        // At rest with no reference speed: still the mode as written, not 0/0.
        assert_eq!(law.frequency(800.0, Speed::ZERO, Speed::ZERO), 800.0);
        assert!((law.frequency(800.0, r, r) - 768.0).abs() < 1e-12);
        assert!((law.frequency(800.0, Speed::from_rpm(5_000.0), r) - 792.0).abs() < 1e-12);
        assert!((law.damping(0.02, Speed::from_rpm(20_000.0), r) - 0.06).abs() < 1e-15);
    }
}
