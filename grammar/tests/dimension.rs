//! Dimension names, SI units, descriptions and arithmetic.

use spindlelab_grammar::{Dimension, DimensionError};

#[test]
fn names_and_units() {
    let table = [
        (Dimension::LENGTH, "length", "m"),
        (Dimension::MASS, "mass", "kg"),
        (Dimension::TIME, "time", "s"),
        (Dimension::ANGLE, "angle", "rad"),
        (Dimension::FREQUENCY, "frequency", "1/s"),
        (Dimension::ROTATIONAL_SPEED, "rotational speed", "rad/s"),
        (Dimension::FORCE, "force", "N"),
        (Dimension::PRESSURE, "pressure", "Pa"),
        (Dimension::SPECIFIC_FORCE, "pressure", "Pa"),
        (Dimension::DENSITY, "density", "kg/m^3"),
        (Dimension::STIFFNESS, "stiffness", "N/m"),
        (Dimension::DAMPING, "damping", "N*s/m"),
        (Dimension::ROTATIONAL_STIFFNESS, "rotational stiffness", "N*m/rad"),
        (Dimension::ROTATIONAL_DAMPING, "rotational damping", "N*m*s/rad"),
        (Dimension::PHASE_SLOPE, "phase slope", "rad*s"),
        (Dimension::VELOCITY, "velocity", "m/s"),
        (Dimension::ACCELERATION, "acceleration", "m/s^2"),
        (Dimension::AREA, "area", "m^2"),
        (Dimension::ENERGY, "moment", "N*m"),
        (Dimension::MOMENT, "moment", "N*m"),
        (Dimension::DIMENSIONLESS, "dimensionless", "1"),
    ];
    for (dim, name, si) in table {
        assert_eq!(dim.name(), Some(name));
        assert_eq!(dim.si_unit(), si);
        assert_eq!(dim.to_string(), si);
    }
}

#[test]
fn from_name_accepts_spellings_and_aliases() {
    assert_eq!(Dimension::from_name("rotational_speed"), Some(Dimension::ROTATIONAL_SPEED));
    assert_eq!(Dimension::from_name("Rotational Speed"), Some(Dimension::ROTATIONAL_SPEED));
    assert_eq!(Dimension::from_name("phase-slope"), Some(Dimension::PHASE_SLOPE));
    assert_eq!(Dimension::from_name("energy"), Some(Dimension::ENERGY));
    assert_eq!(Dimension::from_name("torque"), Some(Dimension::MOMENT));
    assert_eq!(Dimension::from_name("specific_force"), Some(Dimension::SPECIFIC_FORCE));
    assert_eq!(Dimension::from_name("nonsense"), None);
    assert_eq!(Dimension::from_name(""), None);
}

#[test]
fn descriptions() {
    assert_eq!(Dimension::LENGTH.describe(), "a length (m)");
    assert_eq!(Dimension::ANGLE.describe(), "an angle (rad)");
    assert_eq!(Dimension::ACCELERATION.describe(), "an acceleration (m/s^2)");
    assert_eq!(Dimension::DIMENSIONLESS.describe(), "a dimensionless number");
    let odd = Dimension::new(1, 1, -3, 0) / Dimension::new(0, 0, 0, 0) * Dimension::new(0, 0, 1, 0);
    assert_eq!(odd, Dimension::FORCE);
    let unnamed = Dimension::new(1, 1, -4, 0);
    assert_eq!(unnamed.name(), None);
    assert_eq!(unnamed.describe(), "a quantity of dimension kg*m/s^4");
    assert_eq!(Dimension::new(-1, 1, -1, 2).si_unit(), "kg*rad^2/(m*s)");
    assert_eq!(Dimension::new(0, 0, -2, 0).si_unit(), "1/s^2");
}

#[test]
fn arithmetic() {
    assert_eq!(Dimension::FORCE / Dimension::AREA, Dimension::PRESSURE);
    assert_eq!(Dimension::FORCE * Dimension::TIME / Dimension::LENGTH, Dimension::DAMPING);
    assert_eq!(Dimension::ANGLE / Dimension::FREQUENCY, Dimension::PHASE_SLOPE);
    assert_eq!(Dimension::ANGLE * Dimension::FREQUENCY, Dimension::ROTATIONAL_SPEED);
    assert_eq!(Dimension::LENGTH.powi(3), Dimension::LENGTH * Dimension::AREA);
    assert_eq!(Dimension::STIFFNESS.recip(), Dimension::COMPLIANCE);
    assert_eq!(Dimension::LENGTH.checked_powi(200), None);
    assert_eq!(Dimension::LENGTH.powi(200).length, i8::MAX);
    assert_eq!(Dimension::new(100, 0, 0, 0).checked_mul(Dimension::new(100, 0, 0, 0)), None);
    assert_eq!(Dimension::LENGTH.checked_div(Dimension::TIME), Some(Dimension::VELOCITY));
    assert_ne!(Dimension::ROTATIONAL_SPEED, Dimension::FREQUENCY);
    assert_ne!(Dimension::PHASE_SLOPE, Dimension::TIME);
}

#[test]
fn dimension_error_display() {
    let e = DimensionError { expected: Dimension::FREQUENCY, found: Dimension::LENGTH };
    assert_eq!(e.to_string(), "expected a frequency (1/s), found a length (m)");
    let e = DimensionError { expected: Dimension::STIFFNESS, found: Dimension::new(1, 1, -4, 0) };
    assert_eq!(e.to_string(), "expected a stiffness (N/m), found a quantity of dimension kg*m/s^4");
}

#[test]
fn usable_as_hash_key() {
    let mut set = std::collections::HashSet::new();
    set.insert(Dimension::ENERGY);
    assert!(set.contains(&Dimension::MOMENT));
}
