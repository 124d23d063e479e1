//! Physical dimensions as integer exponents over length, mass, time and angle.

use std::fmt;
use std::ops::{Div, Mul};

/// Exponents of the base quantities length (m), mass (kg), time (s) and angle (rad).
///
/// Angle is a base of its own so that a rotational speed (rad/s) is distinct from a
/// frequency (1/s) and an angle per frequency is a phase slope rather than a time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, PartialOrd, Ord)]
pub struct Dimension {
    /// Exponent of length (m).
    pub length: i8,
    /// Exponent of mass (kg).
    pub mass: i8,
    /// Exponent of time (s).
    pub time: i8,
    /// Exponent of angle (rad).
    pub angle: i8,
}

/// A named dimension: the constant, its name and its readable SI unit.
struct Named {
    dim: Dimension,
    name: &'static str,
    si: &'static str,
}

const fn named(dim: Dimension, name: &'static str, si: &'static str) -> Named {
    Named { dim, name, si }
}

/// Named dimensions in lookup order; the first entry with a given dimension wins.
const NAMED: &[Named] = &[
    named(Dimension::DIMENSIONLESS, "dimensionless", "1"),
    named(Dimension::LENGTH, "length", "m"),
    named(Dimension::MASS, "mass", "kg"),
    named(Dimension::TIME, "time", "s"),
    named(Dimension::ANGLE, "angle", "rad"),
    named(Dimension::FREQUENCY, "frequency", "1/s"),
    named(Dimension::ROTATIONAL_SPEED, "rotational speed", "rad/s"),
    named(Dimension::FORCE, "force", "N"),
    named(Dimension::PRESSURE, "pressure", "Pa"),
    named(Dimension::DENSITY, "density", "kg/m^3"),
    named(Dimension::STIFFNESS, "stiffness", "N/m"),
    named(Dimension::DAMPING, "damping", "N*s/m"),
    named(Dimension::ROTATIONAL_STIFFNESS, "rotational stiffness", "N*m/rad"),
    named(Dimension::ROTATIONAL_DAMPING, "rotational damping", "N*m*s/rad"),
    named(Dimension::PHASE_SLOPE, "phase slope", "rad*s"),
    named(Dimension::VELOCITY, "velocity", "m/s"),
    named(Dimension::ACCELERATION, "acceleration", "m/s^2"),
    named(Dimension::AREA, "area", "m^2"),
    named(Dimension::VOLUME, "volume", "m^3"),
    named(Dimension::MOMENT, "moment", "N*m"),
    named(Dimension::POWER, "power", "W"),
    named(Dimension::COMPLIANCE, "compliance", "m/N"),
    named(Dimension::ROTATIONAL_ACCELERATION, "rotational acceleration", "rad/s^2"),
];

/// Extra names accepted by [`Dimension::from_name`] for dimensions that share exponents.
const ALIASES: &[(&str, Dimension)] = &[
    ("energy", Dimension::ENERGY),
    ("torque", Dimension::MOMENT),
    ("specific force", Dimension::SPECIFIC_FORCE),
    ("stress", Dimension::PRESSURE),
    ("angular velocity", Dimension::ROTATIONAL_SPEED),
    ("angular speed", Dimension::ROTATIONAL_SPEED),
    ("receptance", Dimension::COMPLIANCE),
    ("speed", Dimension::VELOCITY),
];

impl Dimension {
    /// Builds a dimension from exponents of length, mass, time and angle.
    pub const fn new(length: i8, mass: i8, time: i8, angle: i8) -> Self {
        Dimension { length, mass, time, angle }
    }

    /// A pure number (all exponents zero).
    pub const DIMENSIONLESS: Dimension = Dimension::new(0, 0, 0, 0);
    /// Length, m.
    pub const LENGTH: Dimension = Dimension::new(1, 0, 0, 0);
    /// Mass, kg.
    pub const MASS: Dimension = Dimension::new(0, 1, 0, 0);
    /// Time, s.
    pub const TIME: Dimension = Dimension::new(0, 0, 1, 0);
    /// Plane angle, rad.
    pub const ANGLE: Dimension = Dimension::new(0, 0, 0, 1);
    /// Frequency, 1/s (Hz).
    pub const FREQUENCY: Dimension = Dimension::new(0, 0, -1, 0);
    /// Rotational speed, rad/s (rpm converts to this).
    pub const ROTATIONAL_SPEED: Dimension = Dimension::new(0, 0, -1, 1);
    /// Force, N = kg*m/s^2.
    pub const FORCE: Dimension = Dimension::new(1, 1, -2, 0);
    /// Pressure or stress, Pa = N/m^2.
    pub const PRESSURE: Dimension = Dimension::new(-1, 1, -2, 0);
    /// Specific cutting force (cutting coefficient Ks), N/m^2; same exponents as pressure.
    pub const SPECIFIC_FORCE: Dimension = Dimension::PRESSURE;
    /// Density, kg/m^3.
    pub const DENSITY: Dimension = Dimension::new(-3, 1, 0, 0);
    /// Translational stiffness, N/m.
    pub const STIFFNESS: Dimension = Dimension::new(0, 1, -2, 0);
    /// Translational viscous damping, N*s/m.
    pub const DAMPING: Dimension = Dimension::new(0, 1, -1, 0);
    /// Rotational stiffness, N*m/rad.
    pub const ROTATIONAL_STIFFNESS: Dimension = Dimension::new(2, 1, -2, -1);
    /// Rotational viscous damping, N*m*s/rad.
    pub const ROTATIONAL_DAMPING: Dimension = Dimension::new(2, 1, -1, -1);
    /// Angle per frequency, rad*s (e.g. `deg/kHz`).
    pub const PHASE_SLOPE: Dimension = Dimension::new(0, 0, 1, 1);
    /// Velocity, m/s.
    pub const VELOCITY: Dimension = Dimension::new(1, 0, -1, 0);
    /// Acceleration, m/s^2.
    pub const ACCELERATION: Dimension = Dimension::new(1, 0, -2, 0);
    /// Area, m^2.
    pub const AREA: Dimension = Dimension::new(2, 0, 0, 0);
    /// Volume, m^3.
    pub const VOLUME: Dimension = Dimension::new(3, 0, 0, 0);
    /// Energy, J = N*m; same exponents as [`Dimension::MOMENT`].
    pub const ENERGY: Dimension = Dimension::new(2, 1, -2, 0);
    /// Moment or torque, N*m.
    pub const MOMENT: Dimension = Dimension::ENERGY;
    /// Torque, N*m; an alias of [`Dimension::MOMENT`].
    pub const TORQUE: Dimension = Dimension::MOMENT;
    /// Power, W = J/s.
    pub const POWER: Dimension = Dimension::new(2, 1, -3, 0);
    /// Compliance (receptance magnitude), m/N.
    pub const COMPLIANCE: Dimension = Dimension::new(0, -1, 2, 0);
    /// Rotational acceleration, rad/s^2.
    pub const ROTATIONAL_ACCELERATION: Dimension = Dimension::new(0, 0, -2, 1);

    fn named(&self) -> Option<&'static Named> {
        NAMED.iter().find(|n| n.dim == *self)
    }

    /// Human name of a well-known dimension such as `"length"` or `"rotational speed"`.
    ///
    /// Energy and moment share exponents; that dimension is called `"moment"`, and
    /// specific force is called `"pressure"`.
    pub fn name(&self) -> Option<&'static str> {
        self.named().map(|n| n.name)
    }

    /// Looks a dimension up by name, accepting spaces, `_` or `-` between words and any case.
    pub fn from_name(name: &str) -> Option<Dimension> {
        let normalised: String =
            name.trim().chars().map(|c| if c == '_' || c == '-' { ' ' } else { c.to_ascii_lowercase() }).collect();
        let normalised = normalised.split_whitespace().collect::<Vec<_>>().join(" ");
        NAMED
            .iter()
            .find(|n| n.name == normalised)
            .map(|n| n.dim)
            .or_else(|| ALIASES.iter().find(|(a, _)| *a == normalised).map(|(_, d)| *d))
    }

    /// SI unit of this dimension, readable for named ones (`"N*s/m"`) and built from the
    /// base units otherwise (`"kg*m/s^3"`); the result is accepted by [`crate::parse_unit`].
    pub fn si_unit(&self) -> String {
        if let Some(n) = self.named() {
            return n.si.to_string();
        }
        let bases = [("kg", self.mass), ("m", self.length), ("s", self.time), ("rad", self.angle)];
        let factor = |sym: &str, exp: i8| {
            let exp = exp.unsigned_abs();
            if exp == 1 { sym.to_string() } else { format!("{sym}^{exp}") }
        };
        let num: Vec<String> = bases.iter().filter(|(_, e)| *e > 0).map(|(s, e)| factor(s, *e)).collect();
        let den: Vec<String> = bases.iter().filter(|(_, e)| *e < 0).map(|(s, e)| factor(s, *e)).collect();
        let num = if num.is_empty() { "1".to_string() } else { num.join("*") };
        match den.len() {
            0 => num,
            1 => format!("{num}/{}", den[0]),
            _ => format!("{num}/({})", den.join("*")),
        }
    }

    /// Phrase for messages: `"a length (m)"`, `"a dimensionless number"`, or
    /// `"a quantity of dimension kg*m/s^3"` when the dimension has no name.
    pub fn describe(&self) -> String {
        if self.is_dimensionless() {
            return "a dimensionless number".to_string();
        }
        match self.named() {
            Some(n) => {
                let article = if n.name.starts_with(['a', 'e', 'i', 'o', 'u']) { "an" } else { "a" };
                format!("{article} {} ({})", n.name, n.si)
            }
            None => format!("a quantity of dimension {}", self.si_unit()),
        }
    }

    /// True when every exponent is zero.
    pub fn is_dimensionless(&self) -> bool {
        *self == Dimension::DIMENSIONLESS
    }

    /// Product of two dimensions, or `None` if an exponent leaves the `i8` range.
    pub fn checked_mul(self, rhs: Dimension) -> Option<Dimension> {
        Some(Dimension {
            length: self.length.checked_add(rhs.length)?,
            mass: self.mass.checked_add(rhs.mass)?,
            time: self.time.checked_add(rhs.time)?,
            angle: self.angle.checked_add(rhs.angle)?,
        })
    }

    /// Quotient of two dimensions, or `None` if an exponent leaves the `i8` range.
    pub fn checked_div(self, rhs: Dimension) -> Option<Dimension> {
        self.checked_mul(rhs.checked_powi(-1)?)
    }

    /// Integer power of a dimension, or `None` if an exponent leaves the `i8` range.
    pub fn checked_powi(self, n: i32) -> Option<Dimension> {
        let p = |e: i8| i8::try_from(i32::from(e).checked_mul(n)?).ok();
        Some(Dimension { length: p(self.length)?, mass: p(self.mass)?, time: p(self.time)?, angle: p(self.angle)? })
    }

    /// Integer power of a dimension; exponents saturate at the `i8` limits.
    pub fn powi(self, n: i32) -> Dimension {
        let p = |e: i8| i32::from(e).saturating_mul(n).clamp(i8::MIN.into(), i8::MAX.into()) as i8;
        Dimension { length: p(self.length), mass: p(self.mass), time: p(self.time), angle: p(self.angle) }
    }

    /// Reciprocal dimension (all exponents negated, saturating).
    pub fn recip(self) -> Dimension {
        self.powi(-1)
    }
}

impl Mul for Dimension {
    type Output = Dimension;
    /// Adds exponents; saturates at the `i8` limits (use [`Dimension::checked_mul`] to detect that).
    fn mul(self, rhs: Dimension) -> Dimension {
        Dimension {
            length: self.length.saturating_add(rhs.length),
            mass: self.mass.saturating_add(rhs.mass),
            time: self.time.saturating_add(rhs.time),
            angle: self.angle.saturating_add(rhs.angle),
        }
    }
}

impl Div for Dimension {
    type Output = Dimension;
    /// Subtracts exponents; saturates at the `i8` limits (use [`Dimension::checked_div`] to detect that).
    fn div(self, rhs: Dimension) -> Dimension {
        Dimension {
            length: self.length.saturating_sub(rhs.length),
            mass: self.mass.saturating_sub(rhs.mass),
            time: self.time.saturating_sub(rhs.time),
            angle: self.angle.saturating_sub(rhs.angle),
        }
    }
}

impl fmt::Display for Dimension {
    /// Writes the SI unit, e.g. `kg/m^3`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.si_unit())
    }
}
