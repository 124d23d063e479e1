//! Quantities, lists, ranges and references parse to the documented SI values.

use std::f64::consts::PI;

use spindlelab_grammar::{
    Dimension, DimensionError, Quantity, Reference, Value, looks_like_value, parse_quantity, parse_value,
};

fn q(text: &str) -> Quantity {
    parse_quantity(text).unwrap_or_else(|e| panic!("`{text}` should parse: {e:?}"))
}

fn v(text: &str) -> Value {
    parse_value(text).unwrap_or_else(|e| panic!("`{text}` should parse: {e:?}"))
}

fn assert_close(actual: f64, expected: f64) {
    let tol = 1e-12 * expected.abs();
    assert!((actual - expected).abs() <= tol, "got {actual:e}, expected {expected:e}");
}

#[test]
fn documented_conversions_are_exact() {
    assert_eq!(q("12.7 mm"), Quantity::new(0.0127, Dimension::LENGTH));
    assert_eq!(q("7800 kg/m^3"), Quantity::new(7800.0, Dimension::DENSITY));
    assert_eq!(q("200 GPa"), Quantity::new(2e11, Dimension::PRESSURE));
    assert_eq!(q("76.2 um/tooth"), Quantity::new(7.62e-5, Dimension::LENGTH));
    assert_eq!(q("76.2 µm/tooth"), Quantity::new(7.62e-5, Dimension::LENGTH));
    assert_eq!(q("76.2 μm/tooth"), Quantity::new(7.62e-5, Dimension::LENGTH));
    assert_eq!(q("0.003 in"), Quantity::new(7.62e-5, Dimension::LENGTH));
    assert_eq!(q("25 %"), Quantity::new(0.25, Dimension::DIMENSIONLESS));
    assert_eq!(q("3000 rpm"), Quantity::new(100.0 * PI, Dimension::ROTATIONAL_SPEED));
    assert_eq!(q("250 N*s/m"), Quantity::new(250.0, Dimension::DAMPING));
    assert_eq!(q("1e7 N/m"), Quantity::new(1e7, Dimension::STIFFNESS));
    assert_eq!(q("3e5 N*m/rad"), Quantity::new(3e5, Dimension::ROTATIONAL_STIFFNESS));
    assert_eq!(q("5 ms"), Quantity::new(5e-3, Dimension::TIME));
    assert_eq!(q("100 kHz"), Quantity::new(1e5, Dimension::FREQUENCY));
    assert_eq!(q("2 min"), Quantity::new(120.0, Dimension::TIME));
    assert_eq!(q("5 Ms"), Quantity::new(5e6, Dimension::TIME));
}

#[test]
fn phase_slope_keeps_angle_and_time() {
    let p = q("-13.84 deg/kHz");
    assert_eq!(p.dim, Dimension::PHASE_SLOPE);
    assert_close(p.value, -13.84 * PI / 180.0 / 1000.0);
    assert_ne!(p.dim, Dimension::TIME);
}

#[test]
fn other_conversions() {
    assert_close(q("10 N*m*s/rad").value, 10.0);
    assert_eq!(q("10 N*m*s/rad").dim, Dimension::ROTATIONAL_DAMPING);
    assert_close(q("1 lbf").value, 4.4482216152605);
    assert_close(q("1 psi").value, 6894.757293168);
    assert_close(q("2 ft").value, 0.6096);
    assert_close(q("90 deg").value, PI / 2.0);
    assert_close(q("90°").value, PI / 2.0);
    assert_close(q("1 rev").value, 2.0 * PI);
    assert_close(q("1 h").value, 3600.0);
    assert_close(q("9.81 m/s^2").value, 9.81);
    assert_close(q("-1.5e-3 kN").value, -1.5);
    assert_close(q("+.5 mm").value, 5e-4);
    assert_close(q("5. mm").value, 5e-3);
    assert_close(q("1E3 g").value, 1.0);
}

#[test]
fn plain_numbers_are_dimensionless() {
    assert_eq!(q("0.95"), Quantity::dimensionless(0.95));
    assert_eq!(q("2"), Quantity::dimensionless(2.0));
    assert_eq!(q("1e-3"), Quantity::dimensionless(1e-3));
    assert_eq!(q("  -4  "), Quantity::dimensionless(-4.0));
    assert_eq!(q("3 teeth"), Quantity::dimensionless(3.0));
}

#[test]
fn whitespace_between_number_and_unit_is_optional() {
    assert_eq!(q("12.7mm"), q("12.7 mm"));
    assert_eq!(q("12.7\u{a0}mm"), q("12.7 mm"));
    assert_eq!(q("12.7\u{202f}mm"), q("12.7 mm"));
    assert_eq!(q("1e7N/m"), q("1e7 N/m"));
    assert_eq!(q("25%"), q("25 %"));
}

#[test]
fn dimension_mismatch_names_both() {
    let err: DimensionError = q("12.7 mm").expect(Dimension::FREQUENCY).unwrap_err();
    assert_eq!(err, DimensionError { expected: Dimension::FREQUENCY, found: Dimension::LENGTH });
    let text = err.to_string();
    assert!(text.contains("frequency") && text.contains("length"), "{text}");
    assert_eq!(text, "expected a frequency (1/s), found a length (m)");
    let err = q("3000 rpm").expect(Dimension::FREQUENCY).unwrap_err();
    assert_eq!(err.to_string(), "expected a frequency (1/s), found a rotational speed (rad/s)");
    assert_eq!(q("100 Hz").expect(Dimension::FREQUENCY), Ok(100.0));
}

#[test]
fn range_of_speeds_has_nine_points() {
    let r = v("0..4000 step 500 rpm");
    let Value::Range { start, end, step, dim } = r else { panic!("not a range: {r:?}") };
    assert_eq!(dim, Dimension::ROTATIONAL_SPEED);
    assert_eq!(start, 0.0);
    assert_close(end, 4000.0 * 2.0 * PI / 60.0);
    assert_close(step, 500.0 * 2.0 * PI / 60.0);
    let points = r.points();
    assert_eq!(points.len(), 9);
    assert_eq!(points[8], end);
    for (i, p) in points.iter().enumerate() {
        assert_close(p + 1.0, i as f64 * step + 1.0);
    }
}

#[test]
fn range_end_on_grid_is_inclusive_despite_rounding() {
    let r = v("0.03..0.07 step 0.005 kg");
    let points = r.points();
    assert_eq!(points.len(), 9);
    assert_eq!(points[0], 0.03);
    assert_eq!(points[8], 0.07);
    assert_eq!(r.dimension(), Some(Dimension::MASS));
    assert_eq!(v("0..1 step 0.1").points().len(), 11);
    assert_eq!(v("0..0.3 step 0.1 s").points().len(), 4);
}

#[test]
fn range_end_off_grid_is_excluded() {
    let points = v("0..10 step 3 s").points();
    assert_eq!(points, vec![0.0, 3.0, 6.0, 9.0]);
    assert_eq!(v("5..5 step 1 s").points(), vec![5.0]);
    assert_eq!(v("-2..2 step 2 mm").points(), vec![-0.002, 0.0, 0.002]);
}

#[test]
fn range_units_on_each_bound() {
    let r = v("1 mm..1 cm step 1 mm");
    assert_eq!(r.points().len(), 10);
    assert_eq!(r.dimension(), Some(Dimension::LENGTH));
    let r = v("0 kHz .. 2 kHz step 500 Hz");
    assert_eq!(r.points(), vec![0.0, 500.0, 1000.0, 1500.0, 2000.0]);
    assert!(parse_value("0 mm..10 mm step 1").is_err());
    assert!(parse_value("0 s..10 step 1 mm").is_err());
}

#[test]
fn range_point_limit() {
    assert_eq!(v("0..999999 step 1").points().len(), 1_000_000);
    let err = parse_value("0..1000000 step 1").unwrap_err();
    assert!(err.message.contains("1000000"), "{}", err.message);
}

#[test]
fn lists() {
    let l = v("[1000, 2000, 3000] rpm");
    let Value::List(items) = &l else { panic!("{l:?}") };
    assert_eq!(items.len(), 3);
    assert!(items.iter().all(|q| q.dim == Dimension::ROTATIONAL_SPEED));
    assert_eq!(items[2].value, 100.0 * PI);
    assert_eq!(
        v("[1 mm, 2 mm]"),
        Value::List(vec![Quantity::new(1e-3, Dimension::LENGTH), Quantity::new(2e-3, Dimension::LENGTH)])
    );
    assert_eq!(v("[1,2,3]").points(), vec![1.0, 2.0, 3.0]);
    assert_eq!(v("[ 1 , 2 , ]kg").points(), vec![1.0, 2.0]);
    assert_eq!(v("[1 mm, 2] m").points(), vec![1e-3, 2.0]);
    assert_eq!(v("[0.5]").dimension(), Some(Dimension::DIMENSIONLESS));
    assert!(v("[1, 2] Hz").expect_dim(Dimension::FREQUENCY).is_ok());
    assert!(v("[1, 2] Hz").expect_dim(Dimension::LENGTH).is_err());
}

#[test]
fn references() {
    let r = v("@fit.receptance");
    assert_eq!(r, Value::Reference(Reference { path: vec!["fit".into(), "receptance".into()] }));
    let Value::Reference(r) = r else { unreachable!() };
    assert_eq!(r.to_string(), "@fit.receptance");
    assert_eq!(r.root(), Some("fit"));
    assert_eq!(r.rest(), ["receptance".to_string()]);
    assert_eq!(v("@impact").as_reference().unwrap().path, vec!["impact"]);
    assert_eq!(v("  @materials.steel ").to_string_ref(), "@materials.steel");
    assert_eq!(v("@_a-1.b_2").to_string_ref(), "@_a-1.b_2");
    assert_eq!(v("@a").dimension(), None);
    assert!(v("@a").expect_dim(Dimension::LENGTH).is_ok());
    assert!(v("@a").points().is_empty());
}

trait RefText {
    fn to_string_ref(&self) -> String;
}

impl RefText for Value {
    fn to_string_ref(&self) -> String {
        self.as_reference().map(ToString::to_string).unwrap_or_default()
    }
}

#[test]
fn parse_quantity_rejects_other_values() {
    for text in ["[1, 2] mm", "0..1 step 1 s", "@a"] {
        let err = parse_quantity(text).unwrap_err();
        assert!(err.message.starts_with("expected a single quantity"), "{text}: {}", err.message);
    }
}

#[test]
fn from_str_impls() {
    let a: Value = "12.7 mm".parse().unwrap();
    let b: Quantity = "12.7 mm".parse().unwrap();
    assert_eq!(a, Value::Quantity(b));
    let u: spindlelab_grammar::Unit = "kHz".parse().unwrap();
    assert_eq!(u.scale, 1e3);
}

#[test]
fn looks_like_value_is_cheap_prefix_test() {
    for yes in ["12.7 mm", " -1", "+2", ".5", "[1]", "@fit", "\t0..1 step 1"] {
        assert!(looks_like_value(yes), "{yes:?}");
    }
    for no in ["", "  ", "steel", "mm", "NaN", "inf", "hello world", "(1)"] {
        assert!(!looks_like_value(no), "{no:?}");
    }
}

#[test]
fn display() {
    assert_eq!(q("12.7 mm").to_string(), "0.0127 m");
    assert_eq!(q("0.5").to_string(), "0.5");
    assert_eq!(q("7800 kg/m^3").to_string(), "7800 kg/m^3");
}
