//! Raw trees written as YAML text that reads back as the same tree, and the builders of trees
//! that did not come from a text (a generated recipe, a value an edit writes).
//!
//! Small mappings and lists of scalars go on one line (`{ name: flange, d_out: 63 mm }`),
//! everything else in block style; a string is plain only where YAML reads it as that same
//! text, double-quoted and escaped otherwise.

use super::raw::{Key, Raw, RawKind};
use crate::diag::Span;
use std::fmt::Write;
use std::sync::Arc;

/// The widest line a mapping or list is kept on in flow style.
const FLOW_WIDTH: usize = 160;

/// The place of a value built in code: no file line.
fn built() -> Span {
    Span::file_only(Arc::from("(generated)"))
}

impl Raw {
    /// A string value built in code (`80 mm`, `@step.port`, `$name`).
    pub fn text(s: impl Into<String>) -> Raw {
        Raw { span: built(), kind: RawKind::Str(s.into()) }
    }

    /// An integer value built in code.
    pub fn int(i: i64) -> Raw {
        Raw { span: built(), kind: RawKind::Int(i) }
    }

    /// A number built in code.
    pub fn float(x: f64) -> Raw {
        Raw { span: built(), kind: RawKind::Float(x) }
    }

    /// A list built in code.
    pub fn list(items: Vec<Raw>) -> Raw {
        Raw { span: built(), kind: RawKind::Seq(items) }
    }

    /// A mapping built in code, its entries in the order given.
    pub fn mapping<K: Into<String>>(entries: impl IntoIterator<Item = (K, Raw)>) -> Raw {
        let entries = entries.into_iter().map(|(k, v)| (Key { name: k.into(), span: built() }, v)).collect();
        Raw { span: built(), kind: RawKind::Map(entries) }
    }

    /// A reference to a recipe parameter: `$name`.
    pub fn param(name: &str) -> Raw {
        Raw::text(format!("${name}"))
    }

    /// A reference to a step's output: `@step.port`.
    pub fn port(step: &str, port: &str) -> Raw {
        Raw::text(format!("@{step}.{port}"))
    }
}

/// YAML text of a raw tree whose top is a mapping.
pub fn emit(raw: &Raw) -> String {
    let mut out = String::new();
    block(raw, 0, &mut out);
    out
}

/// A value on one line however long, as it follows `key: ` or `- `: a scalar, or a mapping
/// or list of scalars in flow style; `None` for a value that needs lines of its own.
pub fn inline(raw: &Raw) -> Option<String> {
    scalar(raw).or_else(|| flow(raw, 0, usize::MAX))
}

/// Text as a YAML double-quoted scalar that reads back as exactly `s`: the quote, the
/// backslash, every line break and every character YAML does not take raw (control
/// characters, U+FEFF, U+FFFE, U+FFFF) are escaped, and so are the characters that reorder a
/// line on screen, so no string can end its scalar or its line, or change what a reader of
/// the recipe sees around it.
pub fn yaml_quoted(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\0' => out.push_str("\\0"),
            '\t' => out.push_str("\\t"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\u{1b}' => out.push_str("\\e"),
            '\u{85}' => out.push_str("\\N"),
            '\u{2028}' => out.push_str("\\L"),
            '\u{2029}' => out.push_str("\\P"),
            c if (c as u32) < 0x100 && c.is_control() => {
                let _ = write!(out, "\\x{:02X}", c as u32);
            }
            '\u{feff}'
            | '\u{fffe}'
            | '\u{ffff}'
            | '\u{061c}'
            | '\u{200e}'
            | '\u{200f}'
            | '\u{202a}'..='\u{202e}'
            | '\u{2066}'..='\u{2069}' => {
                let _ = write!(out, "\\u{:04X}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// Whether `s` reads back as the same string when written plain: words, quantities
/// (`-0.5 Hz`, `4000..24000 step 50 rpm`) and parameter references (`$kf`); never a
/// keyword, a number or text YAML gives a meaning of its own (`@`, `:`, `#`, brackets).
pub fn plain(s: &str) -> bool {
    let allowed = s
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || matches!(c, ' ' | '_' | '-' | '.' | '+' | '/' | '*' | '^' | '%' | '$'));
    let mut chars = s.chars();
    let starts = match chars.next() {
        Some(c) if c.is_ascii_alphanumeric() || c == '_' || c == '$' => true,
        // A negative quantity: `-` then a digit or a point, never `- ` (a list entry).
        Some('-') => chars.next().is_some_and(|c| c.is_ascii_digit() || c == '.'),
        _ => false,
    };
    let keyword = matches!(
        s.to_ascii_lowercase().as_str(),
        "true" | "false" | "null" | "yes" | "no" | "on" | "off" | "y" | "n" | "inf" | "nan" | "infinity" | "~"
    );
    let number = s.parse::<f64>().is_ok() || s.starts_with("0x") || s.starts_with("0o");
    !s.is_empty() && allowed && starts && !keyword && !number && !s.ends_with(' ') && !s.contains("  ")
}

/// A number as YAML reads it back as the same number: shortest digits, plain decimals where a
/// person writes them (1e-3 to 1e6), a point where the number is whole (`5.0`, not the
/// integer `5`).
fn number(f: f64) -> String {
    if f.is_nan() {
        return ".nan".to_string();
    }
    if f.is_infinite() {
        return (if f > 0.0 { ".inf" } else { "-.inf" }).to_string();
    }
    let text = if f == 0.0 || (1e-3..1e6).contains(&f.abs()) { format!("{f}") } else { format!("{f:e}") };
    if text.contains(['.', 'e']) { text } else { format!("{text}.0") }
}

fn scalar(raw: &Raw) -> Option<String> {
    Some(match &raw.kind {
        RawKind::Null => "~".to_string(),
        RawKind::Bool(b) => b.to_string(),
        RawKind::Int(i) => i.to_string(),
        RawKind::Float(f) => number(*f),
        RawKind::Str(s) if plain(s) => s.clone(),
        RawKind::Str(s) => yaml_quoted(s),
        RawKind::Seq(_) | RawKind::Map(_) => return None,
    })
}

/// A mapping key: plain where it reads back as itself, quoted otherwise. Keys are read as
/// YAML 1.2 reads them, so a direction `y` or `n` stays plain.
pub(super) fn key(name: &str) -> String {
    let word = matches!(name.to_ascii_lowercase().as_str(), "y" | "n" | "yes" | "no" | "on" | "off");
    if (plain(name) || word) && !name.contains(' ') && !name.starts_with('$') {
        name.to_string()
    } else {
        yaml_quoted(name)
    }
}

/// A mapping or list of scalars on one line, if it has only scalars and fits in `width`.
fn flow(raw: &Raw, indent: usize, width: usize) -> Option<String> {
    let text = match &raw.kind {
        RawKind::Map(entries) if !entries.is_empty() => {
            let items: Option<Vec<String>> =
                entries.iter().map(|(k, v)| scalar(v).map(|v| format!("{}: {v}", key(&k.name)))).collect();
            format!("{{ {} }}", items?.join(", "))
        }
        RawKind::Map(_) => "{}".to_string(),
        RawKind::Seq(items) if !items.is_empty() => {
            let items: Option<Vec<String>> = items.iter().map(scalar).collect();
            format!("[{}]", items?.join(", "))
        }
        RawKind::Seq(_) => "[]".to_string(),
        _ => return None,
    };
    (indent + text.len() <= width).then_some(text)
}

fn pad(indent: usize, out: &mut String) {
    out.extend(std::iter::repeat_n(' ', indent));
}

/// Writes the entries of a mapping or the items of a list at `indent`.
pub(super) fn block(raw: &Raw, indent: usize, out: &mut String) {
    match &raw.kind {
        RawKind::Map(entries) => {
            for (k, v) in entries {
                pad(indent, out);
                out.push_str(&key(&k.name));
                out.push(':');
                value(v, indent, out);
            }
        }
        RawKind::Seq(items) => {
            for item in items {
                pad(indent, out);
                out.push('-');
                match (&item.kind, flow(item, indent + 2, FLOW_WIDTH)) {
                    (_, Some(text)) => {
                        out.push(' ');
                        out.push_str(&text);
                        out.push('\n');
                    }
                    (RawKind::Map(_) | RawKind::Seq(_), None) => {
                        out.push('\n');
                        block(item, indent + 2, out);
                    }
                    _ => {
                        out.push(' ');
                        out.push_str(&scalar(item).unwrap_or_default());
                        out.push('\n');
                    }
                }
            }
        }
        _ => {
            pad(indent, out);
            out.push_str(&scalar(raw).unwrap_or_default());
            out.push('\n');
        }
    }
}

/// The value after `key:` at `indent`.
fn value(v: &Raw, indent: usize, out: &mut String) {
    if let Some(s) = scalar(v) {
        out.push(' ');
        out.push_str(&s);
        out.push('\n');
    } else if let Some(text) = flow(v, indent + 2, FLOW_WIDTH) {
        out.push(' ');
        out.push_str(&text);
        out.push('\n');
    } else {
        out.push('\n');
        block(v, indent + 2, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diag::{Diagnostics, SourceFile};

    fn read(text: &str) -> (Raw, String) {
        let f = SourceFile { path: Arc::from("t.yaml"), text: Arc::from(text) };
        let mut d = Diagnostics::new();
        let raw = crate::syntax::load_yaml(&f, &mut d).unwrap_or_else(|| panic!("reads: {text}"));
        let mut c = String::new();
        raw.canonical(&mut c);
        (raw, c)
    }

    #[test]
    fn strings_that_yaml_would_read_otherwise_are_quoted() {
        for s in ["@a.b", "yes", "1e3", "12", "-3", "a: b", "x #y", "", " lead", "[1]", "n", "~", "- a", "-x"] {
            assert!(!plain(s), "{s}");
        }
        for s in ["80 mm", "4000..24000 step 50 rpm", "holder+tool", "50 %", "N*m*s/rad", "kg/m^3", "$kf", "-0.5 Hz"] {
            assert!(plain(s), "{s}");
        }
    }

    #[test]
    fn emitted_text_reads_back_as_the_same_tree() {
        let text = "a: 1\nb: { c: \"@x.y\", d: 80 mm, e: 2.5, f: true, g: $p, h: -2 Hz }\nl:\n  - { n: yes }\n  - [1, 2]\nm:\n  deep:\n    - x\n    - 'y: z'\ny: { n: 1, x: 2 }\n";
        let (raw, want) = read(text);
        let (_, got) = read(&emit(&raw));
        assert_eq!(got, want);
    }

    #[test]
    fn numbers_read_back_as_the_same_numbers() {
        for x in [0.0, -0.0, 5.0, -2.0, 0.05, 1e-3, 9.99e-4, 1e6, 1e10, -2.5e-7, 123456.789, 1.0 / 3.0, f64::MAX, 1e300]
        {
            let raw = Raw::mapping([("x", Raw::float(x))]);
            let (back, _) = read(&emit(&raw));
            match back.get("x").map(|v| &v.kind) {
                Some(RawKind::Float(y)) => assert_eq!(y.to_bits(), x.to_bits(), "{x} → {}", emit(&raw)),
                other => panic!("{x} → {} → {other:?}", emit(&raw)),
            }
        }
    }
}
