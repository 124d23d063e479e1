//! Exhaustive short inputs and odd strings never panic and always yield valid spans.

use spindlelab_grammar::{looks_like_value, parse_quantity, parse_unit, parse_value};

fn check_span(text: &str, e: &spindlelab_grammar::ParseError) {
    let chars = text.chars().count();
    assert!(e.offset + e.len <= chars, "{text:?}: span {}+{} beyond {chars}", e.offset, e.len);
    assert!(!e.message.is_empty(), "{text:?}");
}

/// Runs the value parser only; used for the large exhaustive sweep.
fn check_value(text: &str) {
    match parse_value(text) {
        Ok(v) => assert!(v.points().iter().all(|p| p.is_finite()), "{text:?}"),
        Err(e) => check_span(text, &e),
    }
}

/// Runs every entry point.
fn check(text: &str) {
    check_value(text);
    for e in [parse_quantity(text).err(), parse_unit(text).err()].iter().flatten() {
        check_span(text, e);
    }
    let _ = looks_like_value(text);
}

#[test]
fn all_ascii_strings_up_to_three_chars() {
    let alphabet: Vec<char> = (0x20u8..0x7f).map(char::from).collect();
    let mut buf = String::with_capacity(3);
    for &a in &alphabet {
        buf.clear();
        buf.push(a);
        check(&buf);
        for &b in &alphabet {
            buf.truncate(1);
            buf.push(b);
            check(&buf);
            for &c in &alphabet {
                buf.truncate(2);
                buf.push(c);
                check_value(&buf);
            }
        }
    }
}

#[test]
fn unicode_and_structural_combinations() {
    let pieces = [
        "1", "-", ".", "..", "e", "m", "µ", "μ", "²", "⁻", "°", "·", "/", "*", "^", "(", ")", "[", "]", ",", "@", " ",
        "step", "\u{a0}", "é", "😀", "\n", "NaN", "k",
    ];
    for a in pieces {
        for b in pieces {
            for c in pieces {
                for d in ["", "1", "m", "]", ")"] {
                    check(&format!("{a}{b}{c}{d}"));
                }
            }
        }
    }
}

#[test]
fn odd_strings() {
    let long_list = format!("[{}] mm", vec!["1.5"; 20_000].join(", "));
    let strings = [
        "1e-400 m",
        "1e99999999999999999999 m",
        "1e-99999999999999999999 mm",
        "0..1e308 step 1e-308 m",
        "-1e308..1e308 step 1e308",
        "1 m^-2147483648",
        "1 m^99999999999",
        "1 m¹²³⁴⁵⁶⁷⁸⁹⁰",
        "1 m^127*m^127",
        "1 ((((m))))",
        "@a.b.c.d.e.f",
        "[",
        "]",
        "[[1]]",
        "0..1 step 1 step 1",
        "1 step",
        "1..2 step",
        "\u{feff}1 m",
        &long_list,
    ];
    for s in strings {
        check(s);
    }
    assert_eq!(parse_value(&long_list).unwrap().points().len(), 20_000);
}
