//! Every unit symbol and prefix converts to the right SI scale and dimension.

use std::f64::consts::PI;

use spindlelab_grammar::{Dimension, Unit, parse_unit};

fn assert_close(actual: f64, expected: f64, what: &str) {
    let tol = 1e-12 * expected.abs().max(f64::MIN_POSITIVE);
    assert!((actual - expected).abs() <= tol, "{what}: got {actual:e}, expected {expected:e}");
}

fn unit(text: &str) -> Unit {
    parse_unit(text).unwrap_or_else(|e| panic!("`{text}` should parse: {e:?}"))
}

#[test]
fn every_base_symbol() {
    let table: &[(&str, f64, Dimension)] = &[
        ("m", 1.0, Dimension::LENGTH),
        ("g", 1e-3, Dimension::MASS),
        ("kg", 1.0, Dimension::MASS),
        ("s", 1.0, Dimension::TIME),
        ("min", 60.0, Dimension::TIME),
        ("h", 3600.0, Dimension::TIME),
        ("Hz", 1.0, Dimension::FREQUENCY),
        ("rpm", 2.0 * PI / 60.0, Dimension::ROTATIONAL_SPEED),
        ("rps", 2.0 * PI, Dimension::ROTATIONAL_SPEED),
        ("rev", 2.0 * PI, Dimension::ANGLE),
        ("rad", 1.0, Dimension::ANGLE),
        ("deg", PI / 180.0, Dimension::ANGLE),
        ("°", PI / 180.0, Dimension::ANGLE),
        ("N", 1.0, Dimension::FORCE),
        ("Pa", 1.0, Dimension::PRESSURE),
        ("J", 1.0, Dimension::ENERGY),
        ("W", 1.0, Dimension::POWER),
        ("in", 0.0254, Dimension::LENGTH),
        ("ft", 0.3048, Dimension::LENGTH),
        ("lb", 0.45359237, Dimension::MASS),
        ("lbf", 4.4482216152605, Dimension::FORCE),
        ("psi", 6894.757293168, Dimension::PRESSURE),
        ("ksi", 6894757.293168, Dimension::PRESSURE),
        ("%", 0.01, Dimension::DIMENSIONLESS),
        ("tooth", 1.0, Dimension::DIMENSIONLESS),
        ("teeth", 1.0, Dimension::DIMENSIONLESS),
        ("flute", 1.0, Dimension::DIMENSIONLESS),
        ("flutes", 1.0, Dimension::DIMENSIONLESS),
    ];
    for (text, scale, dim) in table {
        let u = unit(text);
        assert_eq!(u.dim, *dim, "dimension of `{text}`");
        assert_close(u.scale, *scale, text);
    }
}

#[test]
fn every_prefix_on_every_prefixable_symbol() {
    let prefixes: &[(&str, f64)] = &[
        ("p", 1e-12),
        ("n", 1e-9),
        ("u", 1e-6),
        ("µ", 1e-6),
        ("μ", 1e-6),
        ("m", 1e-3),
        ("k", 1e3),
        ("M", 1e6),
        ("G", 1e9),
        ("T", 1e12),
    ];
    let symbols: &[(&str, f64, Dimension)] = &[
        ("m", 1.0, Dimension::LENGTH),
        ("g", 1e-3, Dimension::MASS),
        ("s", 1.0, Dimension::TIME),
        ("Hz", 1.0, Dimension::FREQUENCY),
        ("rad", 1.0, Dimension::ANGLE),
        ("N", 1.0, Dimension::FORCE),
        ("Pa", 1.0, Dimension::PRESSURE),
        ("J", 1.0, Dimension::ENERGY),
        ("W", 1.0, Dimension::POWER),
    ];
    for (p, pf) in prefixes {
        for (s, sf, dim) in symbols {
            let text = format!("{p}{s}");
            let u = unit(&text);
            assert_eq!(u.dim, *dim, "dimension of `{text}`");
            assert_close(u.scale, pf * sf, &text);
        }
    }
    assert_close(unit("cm").scale, 1e-2, "cm");
    assert_close(unit("dm").scale, 1e-1, "dm");
}

#[test]
fn centi_and_deci_only_apply_to_the_metre() {
    for text in ["cs", "cg", "dN", "dPa", "cHz", "ds"] {
        assert!(parse_unit(text).is_err(), "`{text}` should be rejected");
    }
}

#[test]
fn prefixes_do_not_apply_to_non_si_symbols() {
    for text in ["krpm", "mdeg", "kin", "mft", "klbf", "Mpsi", "m%", "ktooth", "kmin", "mh"] {
        assert!(parse_unit(text).is_err(), "`{text}` should be rejected");
    }
}

#[test]
fn whole_symbols_win_over_prefix_splits() {
    assert_eq!(unit("min"), Unit { scale: 60.0, dim: Dimension::TIME });
    assert_eq!(unit("mm").dim, Dimension::LENGTH);
    assert_eq!(unit("ms").dim, Dimension::TIME);
    assert_close(unit("ms").scale, 1e-3, "ms");
    assert_close(unit("Ms").scale, 1e6, "Ms");
    assert_eq!(unit("psi").dim, Dimension::PRESSURE);
    assert_close(unit("ps").scale, 1e-12, "ps");
    assert_eq!(unit("kg"), Unit { scale: 1.0, dim: Dimension::MASS });
}

#[test]
fn compound_units() {
    assert_eq!(unit("kg/m^3").dim, Dimension::DENSITY);
    assert_eq!(unit("kg/m³").dim, Dimension::DENSITY);
    assert_eq!(unit("N/m").dim, Dimension::STIFFNESS);
    assert_eq!(unit("N*s/m").dim, Dimension::DAMPING);
    assert_eq!(unit("N·s/m").dim, Dimension::DAMPING);
    assert_eq!(unit("N * s / m").dim, Dimension::DAMPING);
    assert_eq!(unit("N*m/rad").dim, Dimension::ROTATIONAL_STIFFNESS);
    assert_eq!(unit("N*m*s/rad").dim, Dimension::ROTATIONAL_DAMPING);
    assert_eq!(unit("deg/kHz").dim, Dimension::PHASE_SLOPE);
    assert_eq!(unit("m/s^2").dim, Dimension::ACCELERATION);
    assert_eq!(unit("m/s²").dim, Dimension::ACCELERATION);
    assert_eq!(unit("m*s^-2").dim, Dimension::ACCELERATION);
    assert_eq!(unit("m*s⁻²").dim, Dimension::ACCELERATION);
    assert_eq!(unit("1/s").dim, Dimension::FREQUENCY);
    assert_eq!(unit("rad/s").dim, Dimension::ROTATIONAL_SPEED);
    assert_eq!(unit("mm^2").dim, Dimension::AREA);
    assert_close(unit("mm^2").scale, 1e-6, "mm^2");
    assert_close(unit("cm^3").scale, 1e-6, "cm^3");
    assert_eq!(unit("um/tooth").dim, Dimension::LENGTH);
    assert_eq!(unit("1").dim, Dimension::DIMENSIONLESS);
    assert_eq!(unit("m^0").dim, Dimension::DIMENSIONLESS);
}

#[test]
fn division_is_left_associative() {
    let a = unit("N/m/s");
    let b = unit("N/(m*s)");
    assert_eq!(a.dim, b.dim);
    assert_eq!(a.dim, Dimension::FORCE / Dimension::LENGTH / Dimension::TIME);
    assert_eq!(unit("kg/(m*s^2)").dim, Dimension::PRESSURE);
    assert_close(unit("kN/mm").scale, 1e6, "kN/mm");
    assert_close(unit("(mm)^2").scale, 1e-6, "(mm)^2");
}

#[test]
fn every_named_si_unit_round_trips() {
    let names = [
        "dimensionless",
        "length",
        "mass",
        "time",
        "angle",
        "frequency",
        "rotational speed",
        "force",
        "pressure",
        "density",
        "stiffness",
        "damping",
        "rotational stiffness",
        "rotational damping",
        "phase slope",
        "velocity",
        "acceleration",
        "area",
        "volume",
        "moment",
        "power",
        "compliance",
        "rotational acceleration",
    ];
    for name in names {
        let dim = Dimension::from_name(name).unwrap();
        assert_eq!(dim.name(), Some(name));
        let u = unit(&dim.si_unit());
        assert_eq!(u.dim, dim, "{name}: {}", dim.si_unit());
        assert_eq!(u.scale, 1.0, "{name}");
    }
}

#[test]
fn unnamed_si_units_round_trip() {
    for l in -3..=3 {
        for m in -2..=2 {
            for t in -3..=3 {
                for a in -1..=1 {
                    let dim = Dimension::new(l, m, t, a);
                    let u = unit(&dim.si_unit());
                    assert_eq!(u.dim, dim, "{}", dim.si_unit());
                    assert_eq!(u.scale, 1.0, "{}", dim.si_unit());
                }
            }
        }
    }
}

#[test]
fn unit_errors() {
    assert!(parse_unit("").is_err());
    assert!(parse_unit("m^99").is_err());
    assert!(parse_unit("m/").is_err());
    let e = parse_unit("Hzz").unwrap_err();
    assert_eq!(e.message, "unknown unit `Hzz`");
    assert_eq!(e.help.as_deref(), Some("did you mean `Hz`?"));
    let e = parse_unit("dB").unwrap_err();
    assert!(e.message.contains("decibel"), "{}", e.message);
    assert!(parse_unit("dB/Hz").is_err());
}
