//! The raw tree of a generated recipe as YAML text that reads back as the same tree: small
//! mappings of scalars on one line (`{ name: flange, d_out: 63 mm }`), everything else in
//! block style, a string plain only where YAML reads it as that same text.

use crate::engine::syntax::{Raw, RawKind};
use crate::import::yaml_quoted;

/// The widest line a mapping is kept on in flow style.
const FLOW_WIDTH: usize = 160;

/// YAML text of a raw tree whose top is a mapping.
pub fn emit(raw: &Raw) -> String {
    let mut out = String::new();
    block(raw, 0, &mut out);
    out
}

/// Whether `s` reads back as the same string when written plain.
fn plain(s: &str) -> bool {
    let allowed = s
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || matches!(c, ' ' | '_' | '-' | '.' | '+' | '/' | '*' | '^' | '%'));
    let starts = s.starts_with(|c: char| c.is_ascii_alphanumeric() || c == '_');
    let keyword = matches!(
        s.to_ascii_lowercase().as_str(),
        "true" | "false" | "null" | "yes" | "no" | "on" | "off" | "y" | "n" | "inf" | "nan" | "infinity" | "~"
    );
    let number = s.parse::<f64>().is_ok() || s.starts_with("0x") || s.starts_with("0o");
    !s.is_empty() && allowed && starts && !keyword && !number && !s.ends_with(' ') && !s.contains("  ")
}

fn scalar(raw: &Raw) -> Option<String> {
    Some(match &raw.kind {
        RawKind::Null => "~".to_string(),
        RawKind::Bool(b) => b.to_string(),
        RawKind::Int(i) => i.to_string(),
        RawKind::Float(f) if f.is_finite() => format!("{f:?}"),
        RawKind::Float(f) if f.is_nan() => ".nan".to_string(),
        RawKind::Float(f) => (if *f > 0.0 { ".inf" } else { "-.inf" }).to_string(),
        RawKind::Str(s) if plain(s) => s.clone(),
        RawKind::Str(s) => yaml_quoted(s),
        RawKind::Seq(_) | RawKind::Map(_) => return None,
    })
}

fn key(name: &str) -> String {
    if plain(name) && !name.contains(' ') { name.to_string() } else { yaml_quoted(name) }
}

/// A mapping or list of scalars on one line, if it has only scalars and fits.
fn flow(raw: &Raw, indent: usize) -> Option<String> {
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
    (indent + text.len() <= FLOW_WIDTH).then_some(text)
}

fn pad(indent: usize, out: &mut String) {
    out.extend(std::iter::repeat_n(' ', indent));
}

/// Writes the entries of a mapping or the items of a list at `indent`.
fn block(raw: &Raw, indent: usize, out: &mut String) {
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
                match (&item.kind, flow(item, indent + 2)) {
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
    } else if let Some(text) = flow(v, indent + 2) {
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
    use crate::engine::diag::{Diagnostics, SourceFile};
    use std::sync::Arc;

    #[test]
    fn strings_that_yaml_would_read_otherwise_are_quoted() {
        for s in ["@a.b", "yes", "1e3", "12", "a: b", "x #y", "", " lead", "[1]", "n", "~"] {
            assert!(!plain(s), "{s}");
        }
        for s in ["80 mm", "4000..24000 step 50 rpm", "holder+tool", "50 %", "N*m*s/rad", "kg/m^3"] {
            assert!(plain(s), "{s}");
        }
    }

    #[test]
    fn emitted_text_reads_back_as_the_same_tree() {
        let text = "a: 1\nb: { c: \"@x.y\", d: 80 mm, e: 2.5, f: true }\nl:\n  - { n: yes }\n  - [1, 2]\nm:\n  deep:\n    - x\n    - 'y: z'\n";
        let read = |t: &str| {
            let f = SourceFile { path: Arc::from("t.yaml"), text: Arc::from(t) };
            let mut d = Diagnostics::new();
            let raw = crate::engine::syntax::load_yaml(&f, &mut d).expect("reads");
            let mut c = String::new();
            raw.canonical(&mut c);
            (raw, c)
        };
        let (raw, want) = read(text);
        let (_, got) = read(&emit(&raw));
        assert_eq!(got, want);
    }
}
