//! The raw recipe tree: YAML-shaped values, each with the place it came from.

use crate::diag::Span;

/// A mapping key with its location.
#[derive(Debug, Clone, PartialEq)]
pub struct Key {
    pub name: String,
    pub span: Span,
}

/// One value of a raw recipe and where it sits in the text.
#[derive(Debug, Clone, PartialEq)]
pub struct Raw {
    pub span: Span,
    pub kind: RawKind,
}

/// The shape of a raw value, as YAML (or a Rhai object map) gives it.
#[derive(Debug, Clone, PartialEq)]
pub enum RawKind {
    Null,
    Bool(bool),
    Int(i64),
    Float(f64),
    Str(String),
    Seq(Vec<Raw>),
    Map(Vec<(Key, Raw)>),
}

impl Raw {
    /// What kind of value this is, for messages ("expected a mapping, found a list").
    pub fn describe(&self) -> &'static str {
        match &self.kind {
            RawKind::Null => "nothing (null)",
            RawKind::Bool(_) => "a boolean",
            RawKind::Int(_) => "an integer",
            RawKind::Float(_) => "a number",
            RawKind::Str(_) => "a string",
            RawKind::Seq(_) => "a list",
            RawKind::Map(_) => "a mapping",
        }
    }

    pub fn as_map(&self) -> Option<&[(Key, Raw)]> {
        match &self.kind {
            RawKind::Map(m) => Some(m),
            _ => None,
        }
    }

    pub fn as_str(&self) -> Option<&str> {
        match &self.kind {
            RawKind::Str(s) => Some(s),
            _ => None,
        }
    }

    /// Looks a key up in a mapping.
    pub fn get(&self, key: &str) -> Option<&Raw> {
        self.as_map()?.iter().find(|(k, _)| k.name == key).map(|(_, v)| v)
    }

    /// The scalar as text, as a user would have typed it (numbers included).
    pub fn scalar_text(&self) -> Option<String> {
        match &self.kind {
            RawKind::Str(s) => Some(s.clone()),
            RawKind::Int(i) => Some(i.to_string()),
            RawKind::Float(f) => Some(f.to_string()),
            RawKind::Bool(b) => Some(b.to_string()),
            _ => None,
        }
    }

    /// A canonical text form, independent of location: the recipe hash and cache keys use it.
    pub fn canonical(&self, out: &mut String) {
        match &self.kind {
            RawKind::Null => out.push('~'),
            RawKind::Bool(b) => out.push_str(if *b { "true" } else { "false" }),
            RawKind::Int(i) => out.push_str(&i.to_string()),
            RawKind::Float(f) => out.push_str(&format!("{:?}", f)),
            RawKind::Str(s) => out.push_str(&format!("{s:?}")),
            RawKind::Seq(items) => {
                out.push('[');
                for (i, it) in items.iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    it.canonical(out);
                }
                out.push(']');
            }
            RawKind::Map(entries) => {
                out.push('{');
                for (i, (k, v)) in entries.iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    out.push_str(&format!("{:?}:", k.name));
                    v.canonical(out);
                }
                out.push('}');
            }
        }
    }
}

/// One step of a path into the raw tree: a mapping key or a list index.
#[derive(Debug, Clone, PartialEq)]
pub enum Seg {
    Key(String),
    Index(usize),
}

/// A path such as `["machines", "m", "spindle", "modes", "x", 0]`: a part that reads as a
/// number is a list index.
pub fn path(parts: &[&str]) -> Vec<Seg> {
    parts.iter().map(|p| p.parse::<usize>().map(Seg::Index).unwrap_or_else(|_| Seg::Key(p.to_string()))).collect()
}
