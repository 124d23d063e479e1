//! Text written into code another program runs. An exported Snakefile is Python that every
//! node of a cluster loads, even under `snakemake -n`, and its file names are Snakemake
//! patterns: a recipe's name, a path or a case's name reaches it only through these escapers,
//! never raw, so no string of the user's can end a literal, a comment or a line, or change the
//! file's encoding; a path Snakemake reads as a file pattern is refused if it could hold a
//! wildcard. Shell lines are fixed templates that take values only through Snakemake's own
//! quoting (`{NAME:q}`).

use std::path::Path;

/// Why a value cannot be written into generated code.
#[derive(Debug, thiserror::Error)]
pub enum CodegenError {
    #[error(
        "{what} `{shown}` is not valid UTF-8, so a workflow cannot name it exactly; rename it, or run the recipe without exporting it"
    )]
    NotUtf8 { what: &'static str, shown: String },
    #[error(
        "{what} `{shown}` holds {held}, which a workflow's file names cannot: Snakemake reads a brace as a wildcard (doubling does not escape it there) and warns of line breaks; give a folder without them"
    )]
    NotAFilePattern { what: &'static str, shown: String, held: &'static str },
}

/// A Python string literal that evaluates to exactly `s`. It is ASCII only: a quote, a
/// backslash, every control character (line ends included) and every character outside ASCII
/// is an escape, so the literal cannot end early, break its line, or make a line Python reads
/// as an encoding declaration.
pub fn python_str(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '"' => out.push_str("\\\""),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            ' '..='~' => out.push(c),
            c if (c as u32) <= 0xff => out.push_str(&format!("\\x{:02x}", c as u32)),
            c if (c as u32) <= 0xffff => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push_str(&format!("\\U{:08x}", c as u32)),
        }
    }
    out.push('"');
    out
}

/// The text of `path`, which Snakemake matches as a file pattern (a rule's input or output):
/// refused when it holds a brace (a wildcard to Snakemake, whatever is done to it) or a
/// control character.
pub fn file_pattern<'a>(what: &'static str, path: &'a Path) -> Result<&'a str, CodegenError> {
    let text = path_text(what, path)?;
    let held = if text.contains(['{', '}']) {
        Some("a brace")
    } else if text.chars().any(char::is_control) {
        Some("a control character (a line break, a tab)")
    } else {
        None
    };
    match held {
        Some(held) => Err(CodegenError::NotAFilePattern { what, shown: text.escape_debug().to_string(), held }),
        None => Ok(text),
    }
}

/// The text of `path`, which generated code names exactly or not at all.
pub fn path_text<'a>(what: &'static str, path: &'a Path) -> Result<&'a str, CodegenError> {
    path.to_str().ok_or_else(|| CodegenError::NotUtf8 { what, shown: path.display().to_string() })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What Python would make of the literal, by its escapes (the subset `python_str` writes).
    fn unescape(lit: &str) -> String {
        let inner = &lit[1..lit.len() - 1];
        let mut out = String::new();
        let mut chars = inner.chars();
        while let Some(c) = chars.next() {
            if c != '\\' {
                out.push(c);
                continue;
            }
            let hex = |n: usize, chars: &mut std::str::Chars<'_>| {
                let h: String = chars.take(n).collect();
                char::from_u32(u32::from_str_radix(&h, 16).unwrap()).unwrap()
            };
            match chars.next().unwrap() {
                'n' => out.push('\n'),
                'r' => out.push('\r'),
                't' => out.push('\t'),
                'x' => out.push(hex(2, &mut chars)),
                'u' => out.push(hex(4, &mut chars)),
                'U' => out.push(hex(8, &mut chars)),
                c => out.push(c),
            }
        }
        out
    }

    #[test]
    fn literals_are_one_ascii_line_that_reads_back_exactly() {
        for s in [
            "plain",
            "a\nimport os\nos.system('x')",
            "q\"uote'",
            "back\\slash\\",
            "{wildcard} }{",
            "# not a comment",
            "cr\rlf\r\n",
            "nul\0bel\x07del\x7f",
            "ünïcødé \u{2028} \u{85} 🦀",
            "coding: utf-7 +AAo-",
        ] {
            let lit = python_str(s);
            assert!(lit.is_ascii() && !lit.contains(['\n', '\r']), "{lit}");
            assert!(lit.chars().all(|c| (' '..='~').contains(&c)), "{lit}");
            assert_eq!(unescape(&lit), s);
            // Inside, every quote is escaped: the literal ends only at its last character.
            let inner = &lit[1..lit.len() - 1];
            let bare_quote = inner
                .char_indices()
                .any(|(i, c)| c == '"' && inner[..i].chars().rev().take_while(|&b| b == '\\').count() % 2 == 0);
            assert!(!bare_quote, "{lit}");
        }
    }

    #[test]
    fn file_patterns_hold_no_brace_and_no_control_character() {
        for bad in ["/a/{x}/b", "/a/}", "/a\nb", "/a\tb"] {
            let bad = bad.replace("\\n", "\n").replace("\\t", "\t");
            assert!(file_pattern("f", Path::new(&bad)).is_err(), "{bad:?}");
        }
        assert_eq!(file_pattern("f", Path::new("/a \"q\" #h \\b")).unwrap(), "/a \"q\" #h \\b");
    }
}
