//! Typed edits of a YAML recipe that keep everything else byte for byte (comments, layout,
//! quoting), so an edited recipe diffs against its input only where it was edited.
//!
//! An edit names its place by a path into the raw tree (each value knows its byte range) and
//! its new value as a raw tree ([`Raw::text`], [`Raw::mapping`], [`Raw::param`], …), which
//! [`super::emit`] writes as YAML. The text is parsed again after each edit, so the next edit
//! sees the new text and no edit can leave text that does not read.

use super::emit::{self, inline};
use super::raw::{Raw, RawKind};
pub use super::raw::{Seg, path};
use super::yaml::load_yaml;
use crate::diag::{Diagnostics, SourceFile};
use std::sync::Arc;

/// Why an edit could not be made.
#[derive(Debug, Clone, thiserror::Error)]
pub enum EditError {
    #[error("the recipe has no `{0}`")]
    Missing(String),
    #[error("`{0}` has no place in the text (a recipe made by a script cannot be edited)")]
    NoPlace(String),
    #[error("the value for `{0}` does not fit on one line; give it as a mapping or list of scalars")]
    NotInline(String),
    #[error("the edited recipe does not parse: {0}")]
    Parse(String),
}

/// A recipe's text and its parse.
#[derive(Debug, Clone)]
pub struct RecipeText {
    pub file: Arc<str>,
    pub text: String,
    pub raw: Raw,
}

fn show(p: &[Seg]) -> String {
    p.iter()
        .map(|s| match s {
            Seg::Key(k) => k.clone(),
            Seg::Index(i) => i.to_string(),
        })
        .collect::<Vec<_>>()
        .join(".")
}

/// `value` on one line, or why not.
fn one_line(p: &[Seg], value: &Raw) -> Result<String, EditError> {
    inline(value).ok_or_else(|| EditError::NotInline(show(p)))
}

impl RecipeText {
    /// Parses `text` (named `file` in messages).
    pub fn new(file: &str, text: String) -> Result<Self, EditError> {
        let file: Arc<str> = Arc::from(file);
        let raw = parse(&file, &text)?;
        Ok(RecipeText { file, text, raw })
    }

    pub fn source(&self) -> SourceFile {
        SourceFile { path: self.file.clone(), text: Arc::from(self.text.as_str()) }
    }

    /// The value at `p`.
    pub fn get(&self, p: &[Seg]) -> Option<&Raw> {
        let mut at = &self.raw;
        for s in p {
            at = match (s, &at.kind) {
                (Seg::Key(k), RawKind::Map(m)) => &m.iter().find(|(key, _)| &key.name == k)?.1,
                (Seg::Index(i), RawKind::Seq(v)) => v.get(*i)?,
                _ => return None,
            };
        }
        Some(at)
    }

    /// Byte offset and indentation of the first key of the mapping at `p`, and whether the
    /// mapping is written in flow style (`{ a: 1 }`).
    fn first_key(&self, p: &[Seg]) -> Result<(usize, usize, bool), EditError> {
        let map = self.get(p).ok_or_else(|| EditError::Missing(show(p)))?;
        let RawKind::Map(entries) = &map.kind else { return Err(EditError::Missing(show(p))) };
        let (key, _) = entries.first().ok_or_else(|| EditError::NoPlace(show(p)))?;
        let (at, _) = key.span.bytes.ok_or_else(|| EditError::NoPlace(show(p)))?;
        // A quoted key starts at its quote.
        let before = self.text[..at].trim_end_matches([' ', '\t']);
        let flow = before.ends_with('{') || before.ends_with(',');
        let line_start = self.text[..at].rfind('\n').map_or(0, |i| i + 1);
        let indent = self.text[line_start..at].chars().count();
        Ok((at, indent, flow))
    }

    /// Replaces the bytes `range` with `new` and parses the result.
    fn splice(&mut self, range: std::ops::Range<usize>, new: &str) -> Result<(), EditError> {
        let mut text = self.text.clone();
        text.replace_range(range, new);
        self.raw = parse(&self.file, &text)?;
        self.text = text;
        Ok(())
    }

    /// Adds `key: value` to the mapping at `p`, as its first entry (so a block mapping's
    /// indentation and a flow mapping's braces need no searching for an end).
    pub fn insert_key(&mut self, p: &[Seg], key: &str, value: &Raw) -> Result<(), EditError> {
        let (at, indent, flow) = self.first_key(p)?;
        let key = emit::key(key);
        let value = one_line(p, value)?;
        let insert = if flow { format!("{key}: {value}, ") } else { format!("{key}: {value}\n{}", " ".repeat(indent)) };
        self.splice(at..at, &insert)
    }

    /// Sets `key` in the mapping at `p`: replaces its value when present, adds it otherwise.
    pub fn set_key(&mut self, p: &[Seg], key: &str, value: &Raw) -> Result<(), EditError> {
        let mut full = p.to_vec();
        full.push(Seg::Key(key.to_string()));
        if self.get(&full).is_some() { self.replace(&full, value) } else { self.insert_key(p, key, value) }
    }

    /// Replaces the value at `p`, written on one line, with `value`.
    pub fn replace(&mut self, p: &[Seg], value: &Raw) -> Result<(), EditError> {
        let v = self.get(p).ok_or_else(|| EditError::Missing(show(p)))?;
        let (a, b) = v.span.bytes.ok_or_else(|| EditError::NoPlace(show(p)))?;
        if self.text[a..b].contains('\n') {
            return Err(EditError::NoPlace(show(p)));
        }
        let new = one_line(p, value)?;
        self.splice(a..b, &new)
    }

    /// Adds `item` as the last entry of the block sequence at `p`, on a line of its own at the
    /// entries' indentation.
    pub fn push_item(&mut self, p: &[Seg], item: &Raw) -> Result<(), EditError> {
        let seq = self.get(p).ok_or_else(|| EditError::Missing(show(p)))?;
        let RawKind::Seq(items) = &seq.kind else { return Err(EditError::Missing(show(p))) };
        let last = items.last().ok_or_else(|| EditError::NoPlace(show(p)))?;
        let (at, end) = last.span.bytes.ok_or_else(|| EditError::NoPlace(show(p)))?;
        let line_start = self.text[..at].rfind('\n').map_or(0, |i| i + 1);
        let lead = &self.text[line_start..at];
        // A block entry: its line reads `<indent>- ` up to the value.
        let Some(dash) = lead.find('-').filter(|&i| lead[..i].trim().is_empty() && lead[i + 1..].trim().is_empty())
        else {
            return Err(EditError::NoPlace(show(p)));
        };
        let indent = " ".repeat(lead[..dash].chars().count());
        let item = one_line(p, item)?;
        let line_end = self.text[end..].find('\n').map_or(self.text.len(), |i| end + i);
        self.splice(line_end..line_end, &format!("\n{indent}- {item}"))
    }

    /// Inserts the step `name: step` in the `steps:` block before step `before`, at its
    /// indentation, under the comment lines of `comment`.
    pub fn insert_step_before(&mut self, before: &str, comment: &str, name: &str, step: &Raw) -> Result<(), EditError> {
        let p = path(&["steps", before]);
        let key = self
            .get(&path(&["steps"]))
            .and_then(|s| s.as_map())
            .and_then(|m| m.iter().find(|(k, _)| k.name == before))
            .map(|(k, _)| k.span.clone())
            .ok_or_else(|| EditError::Missing(show(&p)))?;
        let (at, _) = key.bytes.ok_or_else(|| EditError::NoPlace(show(&p)))?;
        let line_start = self.text[..at].rfind('\n').map_or(0, |i| i + 1);
        let indent = self.text[line_start..at].chars().count();
        let mut insert = String::new();
        for line in comment.lines() {
            insert.push_str(&format!("# {line}\n{}", " ".repeat(indent)));
        }
        let mut entry = String::new();
        emit::block(&Raw::mapping([(name, step.clone())]), indent, &mut entry);
        // The first line goes where the key `before` stood, after its indentation.
        insert.push_str(&entry[indent..]);
        insert.push_str(&" ".repeat(indent));
        self.splice(at..at, &insert)
    }

    /// Declares (or re-declares) a recipe parameter `name: value` in the top-level `params:`.
    pub fn declare_param(&mut self, name: &str, value: &Raw) -> Result<(), EditError> {
        if self.get(&path(&["params"])).is_some_and(|p| p.as_map().is_some_and(|m| !m.is_empty())) {
            return self.set_key(&path(&["params"]), name, value);
        }
        if self.get(&path(&["params"])).is_some() {
            return Err(EditError::NoPlace("params".into()));
        }
        // No `params:` yet: open one before `steps:`.
        let key = self
            .raw
            .as_map()
            .and_then(|m| m.iter().find(|(k, _)| k.name == "steps"))
            .map(|(k, _)| k.span.clone())
            .ok_or_else(|| EditError::Missing("steps".into()))?;
        let (at, _) = key.bytes.ok_or_else(|| EditError::NoPlace("steps".into()))?;
        let mut block = String::from("params:\n");
        emit::block(&Raw::mapping([(name, value.clone())]), 2, &mut block);
        block.push('\n');
        self.splice(at..at, &block)
    }

    /// Adds `key: value` at the end of the recipe (a `fit:` block, say), in block style.
    pub fn append(&mut self, key: &str, value: &Raw) -> Result<(), EditError> {
        if self.get(&path(&[key])).is_some() {
            return Err(EditError::NoPlace(format!("{key} (already there)")));
        }
        let mut add = String::new();
        if !self.text.ends_with('\n') {
            add.push('\n');
        }
        emit::block(&Raw::mapping([(key, value.clone())]), 0, &mut add);
        let end = self.text.len();
        self.splice(end..end, &add)
    }
}

fn parse(file: &Arc<str>, text: &str) -> Result<Raw, EditError> {
    let mut diags = Diagnostics::new();
    let src = SourceFile { path: file.clone(), text: Arc::from(text) };
    load_yaml(&src, &mut diags)
        .ok_or_else(|| EditError::Parse(diags.iter().map(|d| d.message.clone()).collect::<Vec<_>>().join("; ")))
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "spindlelab: 1\nname: t\nmachines:\n  m:\n    modes:\n      x:\n        - { f: 820 Hz, d: 125 mm }   # first\nsteps:\n  a:\n    kind: k\n    params: { p: 1 }\n  b:\n    kind: k\n    inputs: { x: \"@a.out\" }\n";

    #[test]
    fn edits_touch_only_their_place() {
        let mut r = RecipeText::new("t.yaml", TEXT.to_string()).unwrap();
        r.insert_key(&path(&["machines", "m", "modes", "x", "0"]), "kf", &Raw::param("kf")).unwrap();
        r.replace(&path(&["steps", "b", "inputs", "x"]), &Raw::port("c", "out")).unwrap();
        let step = Raw::mapping([("kind", Raw::text("k2")), ("inputs", Raw::mapping([("y", Raw::port("a", "out"))]))]);
        r.insert_step_before("b", "new", "c", &step).unwrap();
        r.insert_key(&path(&["steps", "a"]), "note", &Raw::text("here")).unwrap();
        let mode = Raw::mapping([("f", Raw::param("f")), ("zeta", Raw::float(0.1))]);
        r.push_item(&path(&["machines", "m", "modes", "x"]), &mode).unwrap();
        r.declare_param("kf", &Raw::float(0.0)).unwrap();
        let want = "spindlelab: 1\nname: t\nmachines:\n  m:\n    modes:\n      x:\n        - { kf: $kf, f: 820 Hz, d: 125 mm }   # first\n        - { f: $f, zeta: 0.1 }\nparams:\n  kf: 0.0\n\nsteps:\n  a:\n    note: here\n    kind: k\n    params: { p: 1 }\n  # new\n  c:\n    kind: k2\n    inputs: { y: \"@a.out\" }\n  b:\n    kind: k\n    inputs: { x: \"@c.out\" }\n";
        assert_eq!(r.text, want);
        r.declare_param("kf", &Raw::float(0.5)).unwrap();
        assert!(r.text.contains("params:\n  kf: 0.5\n"), "{}", r.text);
        r.declare_param("other", &Raw::text("1 g")).unwrap();
        assert!(r.text.contains("params:\n  other: 1 g\n  kf: 0.5\n"), "{}", r.text);
        let fit = Raw::mapping([("free", Raw::mapping([("kf", Raw::mapping([("min", Raw::float(-1.0))]))]))]);
        r.append("fit", &fit).unwrap();
        assert!(r.text.ends_with("\nfit:\n  free:\n    kf: { min: -1.0 }\n"), "{}", r.text);
        assert!(matches!(r.append("fit", &fit), Err(EditError::NoPlace(_))));
    }

    #[test]
    fn a_value_that_needs_lines_of_its_own_is_refused_where_one_line_is_kept() {
        let mut r = RecipeText::new("t.yaml", TEXT.to_string()).unwrap();
        let nested = Raw::mapping([("a", Raw::mapping([("b", Raw::int(1))]))]);
        let err = r.set_key(&path(&["steps", "a", "params"]), "p", &nested).unwrap_err();
        assert!(matches!(err, EditError::NotInline(_)), "{err}");
        assert_eq!(r.text, TEXT, "nothing changed");
        assert!(matches!(r.replace(&path(&["steps", "z"]), &Raw::int(1)), Err(EditError::Missing(_))));
    }
}
