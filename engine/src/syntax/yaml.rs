//! YAML recipes, read with serde-saphyr into the raw tree.
//!
//! serde-saphyr is serde-based, maintained and panic-free, keeps the line and column of
//! every value (`Spanned`), and enforces budgets against alias bombs and runaway inputs.

use super::raw::{Key, Raw, RawKind};
use crate::diag::{Diagnostic, Diagnostics, SourceFile, Span};
use serde::de::{self, Deserialize, Deserializer, MapAccess, SeqAccess, Visitor};
use serde_saphyr::Spanned;
use std::fmt;
use std::sync::Arc;

/// A YAML node as serde sees it; converted to [`Raw`] once its span is known.
enum Node {
    Null,
    Bool(bool),
    Int(i64),
    Float(f64),
    Str(String),
    Seq(Vec<Spanned<Node>>),
    Map(Vec<(Spanned<String>, Spanned<Node>)>),
}

impl<'de> Deserialize<'de> for Node {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(NodeVisitor)
    }
}

struct NodeVisitor;

impl<'de> Visitor<'de> for NodeVisitor {
    type Value = Node;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a YAML value")
    }
    fn visit_unit<E>(self) -> Result<Node, E> {
        Ok(Node::Null)
    }
    fn visit_none<E>(self) -> Result<Node, E> {
        Ok(Node::Null)
    }
    fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<Node, D::Error> {
        Node::deserialize(d)
    }
    fn visit_bool<E>(self, v: bool) -> Result<Node, E> {
        Ok(Node::Bool(v))
    }
    fn visit_i64<E>(self, v: i64) -> Result<Node, E> {
        Ok(Node::Int(v))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Node, E> {
        i64::try_from(v).map(Node::Int).map_err(|_| E::custom("integer too large"))
    }
    fn visit_f64<E>(self, v: f64) -> Result<Node, E> {
        Ok(Node::Float(v))
    }
    fn visit_str<E>(self, v: &str) -> Result<Node, E> {
        Ok(Node::Str(v.to_string()))
    }
    fn visit_string<E>(self, v: String) -> Result<Node, E> {
        Ok(Node::Str(v))
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Node, A::Error> {
        let mut items = Vec::new();
        while let Some(item) = seq.next_element::<Spanned<Node>>()? {
            items.push(item);
        }
        Ok(Node::Seq(items))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Node, A::Error> {
        let mut entries = Vec::new();
        while let Some(k) = map.next_key::<Spanned<String>>()? {
            let v = map.next_value::<Spanned<Node>>()?;
            entries.push((k, v));
        }
        Ok(Node::Map(entries))
    }
}

fn span_of(file: &Arc<str>, loc: &serde_saphyr::Location) -> Span {
    let s = loc.span();
    let bytes = s.byte_offset().map(|o| {
        let len = s.byte_len().unwrap_or(0);
        (o as usize, (o + len) as usize)
    });
    Span { file: file.clone(), line: loc.line() as u32, column: loc.column() as u32, bytes }
}

fn convert(file: &Arc<str>, node: Spanned<Node>) -> Raw {
    let span = span_of(file, &node.referenced);
    let kind = match node.value {
        Node::Null => RawKind::Null,
        Node::Bool(b) => RawKind::Bool(b),
        Node::Int(i) => RawKind::Int(i),
        Node::Float(f) => RawKind::Float(f),
        Node::Str(s) => RawKind::Str(s),
        Node::Seq(items) => RawKind::Seq(items.into_iter().map(|n| convert(file, n)).collect()),
        Node::Map(entries) => RawKind::Map(
            entries
                .into_iter()
                .map(|(k, v)| {
                    let key = Key { name: k.value, span: span_of(file, &k.referenced) };
                    (key, convert(file, v))
                })
                .collect(),
        ),
    };
    Raw { span, kind }
}

/// The parser's message in the recipe's terms, and what to do: the parser's own wording names
/// its internals (`budget breached: Depth { depth: 65 }`, `set DuplicateKeyPolicy`).
fn yaml_message(msg: &str) -> (String, String) {
    if let Some(rest) = msg.strip_prefix("duplicate mapping key: ") {
        let key = rest.split(", set ").next().unwrap_or(rest).trim();
        return (
            format!("the key `{key}` appears twice in one mapping"),
            "keep one of them: YAML would otherwise take the later one silently".into(),
        );
    }
    if let Some(rest) = msg.strip_prefix("budget breached: ") {
        let what = rest.split([' ', '{']).next().unwrap_or(rest);
        let limit = rest.split(|c: char| !c.is_ascii_digit()).find(|t| !t.is_empty());
        let text = match (what, limit) {
            ("Depth", Some(n)) => format!("the YAML nests {n} levels deep, more than a recipe may"),
            ("Aliases" | "AliasExpansion" | "Anchors", _) => {
                "the YAML's anchors and aliases expand beyond a recipe's size".into()
            }
            (w, _) => format!("the YAML exceeds the reader's limit on {}", w.to_lowercase()),
        };
        return (text, "a recipe is a few levels of mappings and lists; generated or hostile input is refused".into());
    }
    let quoting = [
        "mapping values",
        "did not find expected",
        "unexpected character",
        "found character",
        "could not find expected",
    ]
    .iter()
    .any(|p| msg.contains(p));
    let help = if quoting {
        "quote values that contain `:` or start with `@`, `[`, `{` or `*`"
    } else {
        "a recipe is a YAML mapping of keys to values; check the syntax at the marked place"
    };
    (msg.to_string(), help.into())
}

/// Parses YAML text into the raw tree; a syntax error becomes one diagnostic with its location.
pub fn load_yaml(file: &SourceFile, diags: &mut Diagnostics) -> Option<Raw> {
    let options = serde_saphyr::options! {
        with_snippet: false,
        // `y` and `n` are directions here, not YAML 1.1 booleans.
        strict_booleans: true,
    };
    match serde_saphyr::from_str_with_options::<Spanned<Node>>(&file.text, options) {
        Ok(node) => Some(convert(&file.path, node)),
        Err(e) => {
            let span =
                e.location().map(|l| span_of(&file.path, &l)).unwrap_or_else(|| Span::file_only(file.path.clone()));
            let msg = e.to_string();
            let msg = msg.lines().next().unwrap_or("invalid YAML");
            // The location is shown with the quoted line; keep the sentence free of it.
            let msg = msg.split(" at line ").next().unwrap_or(msg).to_string();
            let (msg, help) = yaml_message(&msg);
            diags.push(Diagnostic::error(Some(span), format!("invalid YAML: {msg}")).with_help(help));
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(text: &str) -> (Option<Raw>, Diagnostics) {
        let file = SourceFile { path: Arc::from("t.yaml"), text: Arc::from(text) };
        let mut d = Diagnostics::new();
        (load_yaml(&file, &mut d), d)
    }

    #[test]
    fn every_value_keeps_its_line_and_column() {
        let (raw, d) = load("spindlelab: 1\nsteps:\n  hit:\n    kind: impact.simulate\n");
        assert!(d.is_empty());
        let raw = raw.unwrap();
        let kind = raw.get("steps").unwrap().get("hit").unwrap().get("kind").unwrap();
        assert_eq!((kind.span.line, kind.span.column), (4, 11));
        assert_eq!(kind.as_str(), Some("impact.simulate"));
        let (start, end) = kind.span.bytes.unwrap();
        assert_eq!(&"spindlelab: 1\nsteps:\n  hit:\n    kind: impact.simulate\n"[start..end], "impact.simulate");
    }

    #[test]
    fn y_and_n_are_words_not_booleans() {
        let (raw, _) = load("directions: [x, y, n]\n");
        let dirs = raw.unwrap();
        let RawKind::Seq(items) = &dirs.get("directions").unwrap().kind else { panic!() };
        assert!(items.iter().all(|i| matches!(i.kind, RawKind::Str(_))));
    }

    #[test]
    fn duplicate_keys_are_an_error_with_a_place() {
        let (raw, d) = load("a: 1\na: 2\n");
        assert!(raw.is_none());
        let diag = d.iter().next().unwrap();
        assert_eq!(diag.span.as_ref().unwrap().line, 2, "{diag}");
    }
}
