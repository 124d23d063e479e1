//! Raw trees written as YAML text that reads back as the same tree, and the builders of trees
//! that did not come from a text (a generated recipe, a value an edit writes).
//!
//! Small mappings and lists of scalars go on one line (`{ name: flange, d_out: 63 mm }`),
//! everything else in block style; a string is plain only where YAML reads it as that same
//! text, double-quoted and escaped otherwise.

use super::raw::{Key, Raw, RawKind, Seg, path};
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

    /// A yes/no value built in code.
    pub fn bool(b: bool) -> Raw {
        Raw { span: built(), kind: RawKind::Bool(b) }
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
            c => escaped(c, &mut out),
        }
    }
    out.push('"');
    out
}

/// `c` as YAML text shows it, in a double-quoted scalar or a comment: a control character
/// (`\x1B`), a byte-order mark, a noncharacter or a character that reorders a line on screen
/// (`\u202E`) escaped, anything else as itself.
fn escaped(c: char, out: &mut String) {
    match c {
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
        // `y` and `n` are words to YAML 1.2 (and to PyYAML): directions stay plain.
        RawKind::Str(s) if plain(s) || matches!(s.as_str(), "y" | "n") => s.clone(),
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

/// The comments and blank lines of a document written from a tree built in code (an imported
/// case, a generated survey): comment lines before an entry, a remark after it on its line, a
/// blank line before it, and closing comments. Each names its entry by its path from the top
/// ([`path`]); a mapping or list with a note inside is written in block style, so no note is
/// lost in a one-line value.
#[derive(Debug, Clone, Default)]
pub struct Notes {
    before: Vec<(Vec<Seg>, String)>,
    after: Vec<(Vec<Seg>, String)>,
    blank: Vec<Vec<Seg>>,
    end: Vec<String>,
}

impl Notes {
    /// A comment on the lines before the entry at `at` (the document's top for `&[]`).
    pub fn before(&mut self, at: &[&str], comment: impl Into<String>) -> &mut Self {
        self.before.push((path(at), comment.into()));
        self
    }

    /// A remark after the entry at `at`, on its line.
    pub fn after(&mut self, at: &[&str], remark: impl Into<String>) -> &mut Self {
        self.after.push((path(at), remark.into()));
        self
    }

    /// A blank line before the entry at `at` (and its comments).
    pub fn blank(&mut self, at: &[&str]) -> &mut Self {
        self.blank.push(path(at));
        self
    }

    /// A comment closing the document, after a blank line.
    pub fn end(&mut self, comment: impl Into<String>) -> &mut Self {
        self.end.push(comment.into());
        self
    }

    /// Whether a note names an entry inside the value at `p`.
    fn inside(&self, p: &[Seg]) -> bool {
        let below = |q: &Vec<Seg>| q.len() > p.len() && q.starts_with(p);
        self.before.iter().any(|(q, _)| below(q))
            || self.after.iter().any(|(q, _)| below(q))
            || self.blank.iter().any(below)
    }
}

/// The line breaks of YAML 1.1 and 1.2: each ends a comment.
const LINE_BREAKS: [char; 5] = ['\n', '\r', '\u{85}', '\u{2028}', '\u{2029}'];

/// `text` as comment lines at `indent`: a line break in it starts another comment line, so no
/// comment can end early and put its rest into the document; the characters YAML does not
/// take in a comment, and those that reorder a line on screen, are written escaped (`\x1B`).
fn comment(text: &str, indent: usize, out: &mut String) {
    for line in text.split(LINE_BREAKS) {
        pad(indent, out);
        out.push('#');
        if !line.is_empty() {
            out.push(' ');
            for c in line.chars() {
                match c {
                    '\t' => out.push(c),
                    c => escaped(c, out),
                }
            }
        }
        out.push('\n');
    }
}

/// `text` as comment lines at the top of a document, one per line of `text` (see [`Notes::before`]).
pub fn comment_lines(text: &str) -> String {
    let mut out = String::new();
    comment(text, 0, &mut out);
    out
}

/// YAML text of a raw tree whose top is a mapping, with the comments and blank lines of
/// `notes`: reads back as the same tree as [`emit`]'s text does.
pub fn emit_noted(raw: &Raw, notes: &Notes) -> String {
    let mut out = String::new();
    for (_, c) in notes.before.iter().filter(|(q, _)| q.is_empty()) {
        comment(c, 0, &mut out);
    }
    Writer { notes, out: &mut out }.block(raw, 0, &mut Vec::new());
    if !notes.end.is_empty() {
        out.push('\n');
        for c in &notes.end {
            comment(c, 0, &mut out);
        }
    }
    out
}

/// Writes the entries of a mapping or the items of a list at `indent`.
pub(super) fn block(raw: &Raw, indent: usize, out: &mut String) {
    Writer { notes: &Notes::default(), out }.block(raw, indent, &mut Vec::new());
}

/// Writes a tree in block style, with its notes.
struct Writer<'a> {
    notes: &'a Notes,
    out: &'a mut String,
}

impl Writer<'_> {
    /// The blank line and comments before the entry at `at`.
    fn lead(&mut self, at: &[Seg], indent: usize) {
        if self.notes.blank.iter().any(|q| q == at) {
            self.out.push('\n');
        }
        for (_, c) in self.notes.before.iter().filter(|(q, _)| q == at) {
            comment(c, indent, self.out);
        }
    }

    /// Ends the line of the entry at `at`, with its remark.
    fn end_line(&mut self, at: &[Seg]) {
        for (_, r) in self.notes.after.iter().filter(|(q, _)| q == at) {
            self.out.push_str("   # ");
            let mut line = String::new();
            comment(&r.replace(LINE_BREAKS, " "), 0, &mut line);
            self.out.push_str(line.strip_prefix("# ").unwrap_or_default().trim_end_matches('\n'));
        }
        self.out.push('\n');
    }

    /// `raw` on one line as it follows `key: ` or `- ` at `indent`, unless a note lies inside it.
    fn one_line(&self, raw: &Raw, indent: usize, at: &[Seg]) -> Option<String> {
        scalar(raw).or_else(|| if self.notes.inside(at) { None } else { flow(raw, indent, FLOW_WIDTH) })
    }

    /// Whether the list item `item` at `at` is a mapping in lines of its own whose first entry
    /// can share the line of its `-`: nothing is noted on the item or before that entry.
    fn compact(&self, item: &Raw, indent: usize, at: &[Seg]) -> bool {
        let RawKind::Map(entries) = &item.kind else { return false };
        let Some((first, _)) = entries.first() else { return false };
        let mut first_at = at.to_vec();
        first_at.push(Seg::Key(first.name.clone()));
        let noted = |p: &[Seg]| {
            self.notes.after.iter().any(|(q, _)| q == p)
                || self.notes.before.iter().any(|(q, _)| q == first_at.as_slice())
                || self.notes.blank.contains(&first_at)
        };
        self.one_line(item, indent + 2, at).is_none() && !noted(at)
    }

    /// Writes the entries of a mapping or the items of a list at `indent`; `at` is its path.
    fn block(&mut self, raw: &Raw, indent: usize, at: &mut Vec<Seg>) {
        match &raw.kind {
            RawKind::Map(entries) => {
                for (k, v) in entries {
                    at.push(Seg::Key(k.name.clone()));
                    self.lead(at, indent);
                    pad(indent, self.out);
                    self.out.push_str(&key(&k.name));
                    self.out.push(':');
                    self.value(v, indent, at);
                    at.pop();
                }
            }
            RawKind::Seq(items) => {
                for (i, item) in items.iter().enumerate() {
                    at.push(Seg::Index(i));
                    self.lead(at, indent);
                    pad(indent, self.out);
                    self.out.push('-');
                    if self.compact(item, indent, at) {
                        // `- key: value`, the mapping's other entries below it.
                        self.out.push(' ');
                        let start = self.out.len();
                        self.block(item, indent + 2, at);
                        self.out.replace_range(start..start + indent + 2, "");
                    } else {
                        self.value(item, indent, at);
                    }
                    at.pop();
                }
            }
            _ => {
                pad(indent, self.out);
                self.out.push_str(&scalar(raw).unwrap_or_default());
                self.out.push('\n');
            }
        }
    }

    /// The value after `key:` or `-` at `indent`: on the line, or in lines of its own below.
    fn value(&mut self, v: &Raw, indent: usize, at: &mut Vec<Seg>) {
        match self.one_line(v, indent + 2, at) {
            Some(text) => {
                self.out.push(' ');
                self.out.push_str(&text);
                self.end_line(at);
            }
            None => {
                self.end_line(at);
                self.block(v, indent + 2, at);
            }
        }
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

    #[test]
    fn notes_become_comments_and_blank_lines_and_the_tree_reads_back_the_same() {
        let raw = Raw::mapping([
            ("spindlelab", Raw::int(1)),
            ("cutting", Raw::mapping([("teeth", Raw::int(4)), ("ae", Raw::float(0.5))])),
            ("files", Raw::list(vec![Raw::text("a.csv"), Raw::text("b c.csv")])),
            ("steps", Raw::mapping([("s", Raw::mapping([("kind", Raw::text("frf.gap"))]))])),
        ]);
        let mut notes = Notes::default();
        notes
            .before(&[], "Top.\nSecond line: # stays a comment")
            .blank(&["cutting"])
            .after(&["cutting", "ae"], "radial depth\nnot a key: 1")
            .after(&["files", "1"], "y, 0 rpm")
            .before(&["steps", "s"], "The step.")
            .end("The end.");
        let text = emit_noted(&raw, &notes);
        let want = "# Top.\n# Second line: # stays a comment\nspindlelab: 1\n\ncutting:\n  teeth: 4\n  ae: 0.5   # radial depth not a key: 1\n\
                    files:\n  - a.csv\n  - b c.csv   # y, 0 rpm\nsteps:\n  # The step.\n  s: { kind: frf.gap }\n\n# The end.\n";
        assert_eq!(text, want);
        assert_eq!(read(&text).1, read(&emit(&raw)).1);
        // Without notes inside, the small mapping and list go on one line.
        assert!(emit(&raw).contains("cutting: { teeth: 4, ae: 0.5 }\nfiles: [a.csv, b c.csv]\n"), "{}", emit(&raw));
    }

    #[test]
    fn a_list_item_that_needs_lines_starts_on_the_line_of_its_dash() {
        let with = Raw::list(vec![Raw::mapping([("from", Raw::port("t", "frf")), ("label", Raw::text("measured"))])]);
        let item = Raw::mapping([("from", Raw::port("m", "frf")), ("with", with), ("file", Raw::text("a.svg"))]);
        let raw = Raw::mapping([("outputs", Raw::list(vec![item.clone(), item]))]);
        let text = emit(&raw);
        let one = "  - from: \"@m.frf\"\n    with:\n      - { from: \"@t.frf\", label: measured }\n    file: a.svg\n";
        assert_eq!(text, format!("outputs:\n{one}{one}"));
        assert_eq!(read(&text).1, read(&emit_noted(&raw, &Notes::default())).1);
        // A comment before the item's first entry keeps the item's own line.
        let mut notes = Notes::default();
        notes.before(&["outputs", "1", "from"], "The model.");
        let text = emit_noted(&raw, &notes);
        assert!(text.contains("  -\n    # The model.\n    from: \"@m.frf\"\n"), "{text}");
        assert_eq!(read(&text).1, read(&emit(&raw)).1);
    }

    #[test]
    fn no_comment_text_can_leave_its_comment_or_hide_what_follows() {
        let raw = Raw::mapping([("a", Raw::int(1))]);
        let mut notes = Notes::default();
        let hostile = "x\u{2028}b: 2\rc: 3\u{1b}[2J\u{202e}\u{7f}";
        notes.before(&[], hostile).after(&["a"], hostile).end(hostile);
        let text = emit_noted(&raw, &notes);
        assert_eq!(read(&text).1, read("a: 1\n").1, "{text}");
        assert!(!text.chars().any(|c| c.is_control() && c != '\n' || c == '\u{202e}'), "{text:?}");
        assert!(text.contains("a: 1   # x b: 2 c: 3\\x1B[2J\\u202E\\x7F\n"), "{text}");
        assert_eq!(comment_lines("one\ntwo"), "# one\n# two\n");
    }
}
