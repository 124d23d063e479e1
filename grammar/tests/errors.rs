//! Malformed input is rejected with a located message, never a panic.

use spindlelab_grammar::{ParseError, parse_quantity, parse_unit, parse_value};

fn err(text: &str) -> ParseError {
    match parse_value(text) {
        Ok(v) => panic!("`{text}` should fail, got {v:?}"),
        Err(e) => e,
    }
}

#[test]
fn empty_and_blank() {
    for text in ["", "   ", "\t\n"] {
        let e = err(text);
        assert_eq!(e.offset, 0);
        assert!(e.message.contains("empty"), "{}", e.message);
    }
}

#[test]
fn unknown_unit_with_suggestion() {
    let e = err("12.7 mmm");
    assert_eq!(e.message, "unknown unit `mmm`");
    assert_eq!(e.help.as_deref(), Some("did you mean `mm`?"));
    assert_eq!((e.offset, e.len), (5, 3));
    assert_eq!(err("12 khz").help.as_deref(), Some("did you mean `kHz`?"));
    assert_eq!(err("5 rmp").help.as_deref(), Some("did you mean `rpm`?"));
    assert_eq!(err("1 mpa").help.as_deref(), Some("did you mean `mPa` or `MPa`?"));
    assert_eq!(err("1 xyzzy").help, None);
}

#[test]
fn unit_without_number() {
    let e = err("mm");
    assert_eq!(e.offset, 0);
    assert!(e.message.starts_with("expected a number"), "{}", e.message);
    assert!(e.help.is_some());
}

#[test]
fn unfinished_range() {
    let e = err("1..");
    assert_eq!(e.offset, 3);
    assert!(e.message.starts_with("expected a number"), "{}", e.message);
    let e = err("0..10 rpm");
    assert!(e.message.contains("`step`"), "{}", e.message);
}

#[test]
fn zero_and_negative_steps() {
    let e = err("0..10 step 0 s");
    assert_eq!(e.message, "range step must be positive");
    assert_eq!((e.offset, e.len), (11, 3));
    let e = err("0..10 step -1 s");
    assert_eq!(e.message, "range step must be positive");
    assert!(e.help.is_some());
    let e = err("10..0 step 1 s");
    assert_eq!(e.message, "range end is below its start");
    assert_eq!(e.offset, 4);
    let e = err("0..10 step 1e-6 m");
    assert!(e.message.contains("points"), "{}", e.message);
}

#[test]
fn unclosed_list() {
    let e = err("[1, 2");
    assert_eq!(e.offset, 5);
    assert!(e.message.contains("`]`"), "{}", e.message);
    let e = err("[1 2]");
    assert_eq!(e.offset, 3);
    let e = err("[]");
    assert!(e.message.contains("at least one"), "{}", e.message);
    let e = err("[1 mm, 2]");
    assert_eq!(e.offset, 7);
    assert!(e.message.contains("length") && e.message.contains("dimensionless"), "{}", e.message);
}

#[test]
fn bad_references() {
    let e = err("@");
    assert_eq!(e.offset, 1);
    assert!(e.message.contains("name"), "{}", e.message);
    let e = err("@1abc");
    assert_eq!((e.offset, e.len), (1, 1));
    assert!(e.message.contains("name"), "{}", e.message);
    assert_eq!(err("@a.").offset, 3);
    assert_eq!(err("@a..b").offset, 3);
    assert_eq!(err("@a b").offset, 3);
}

#[test]
fn non_finite_numbers() {
    for text in ["NaN mm", "nan", "inf Hz", "-inf", "+Infinity s", "[1, inf] m", "0..inf step 1 s"] {
        let e = err(text);
        assert!(e.message.contains("non-finite"), "{text}: {}", e.message);
    }
    let e = err("inf Hz");
    assert_eq!((e.offset, e.len), (0, 3));
}

#[test]
fn overflow() {
    let e = err("1e400 m");
    assert!(e.message.contains("out of range"), "{}", e.message);
    assert_eq!((e.offset, e.len), (0, 5));
    let e = err("1e308 GPa");
    assert!(e.message.contains("out of range"), "{}", e.message);
    assert!(parse_value("1e400 pm").is_err());
    assert!(parse_value("1 m^24").is_ok());
    assert!(parse_value("1 Tm^24").is_ok());
    assert!(parse_value("1 Tm^24*Tm^2").is_err());
    assert!(parse_unit("Tm^24*Tm^2").is_err());
}

#[test]
fn decibels_are_rejected() {
    let e = err("-3 dB");
    assert!(e.message.contains("decibel"), "{}", e.message);
    assert_eq!((e.offset, e.len), (3, 2));
}

#[test]
fn trailing_garbage() {
    let e = err("12.7 mm N");
    assert_eq!(e.offset, 8);
    assert!(e.help.as_deref().is_some_and(|h| h.contains('*')));
    assert_eq!(err("1 2").offset, 2);
    assert_eq!(err("1.5.3").offset, 3);
    assert_eq!(err("1 m^").offset, 4);
    assert_eq!(err("1 (m").offset, 4);
    assert_eq!(err("1 m*").offset, 4);
}

#[test]
fn offsets_count_characters_not_bytes() {
    let e = err("1 µm/µmm");
    assert_eq!((e.offset, e.len), (5, 3));
    assert_eq!(e.help.as_deref(), Some("did you mean `mm`?"));
}

#[test]
fn deep_nesting_is_refused() {
    let text = format!("1 {}m{}", "(".repeat(1000), ")".repeat(1000));
    assert!(parse_value(&text).is_err());
    let text = format!("1 {}m{}", "(".repeat(10), ")".repeat(10));
    assert!(parse_value(&text).is_ok());
    assert!(parse_unit(&"(".repeat(100_000)).is_err());
}

#[test]
fn render_points_at_the_span() {
    let e = err("12.7 mmm");
    assert_eq!(e.render("12.7 mmm"), "error: unknown unit `mmm`\n  12.7 mmm\n       ^^^\n  help: did you mean `mm`?");
    assert_eq!(e.to_string(), "unknown unit `mmm`");
}

#[test]
fn quantity_errors_propagate() {
    assert_eq!(parse_quantity("12.7 mmm").unwrap_err(), err("12.7 mmm"));
}
