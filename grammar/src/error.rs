//! Errors reported while parsing values and checking their dimensions.

use crate::Dimension;

/// A syntax or unit error at a character span of the parsed text, with an optional hint.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct ParseError {
    /// Character column (0-based) where the problem starts within the parsed text.
    pub offset: usize,
    /// Length of the offending span in characters (0 for a position).
    pub len: usize,
    /// What went wrong, e.g. "unknown unit `mmm`".
    pub message: String,
    /// A suggestion such as "did you mean `mm`?".
    pub help: Option<String>,
}

impl ParseError {
    /// Builds an error at a character span without a hint.
    pub fn new(offset: usize, len: usize, message: impl Into<String>) -> Self {
        ParseError { offset, len, message: message.into(), help: None }
    }

    /// Attaches a hint to the error.
    pub fn with_help(mut self, help: impl Into<String>) -> Self {
        self.help = Some(help.into());
        self
    }

    /// Renders the error under the source line with carets, for terminal output.
    pub fn render(&self, source: &str) -> String {
        let line: String = source.chars().map(|c| if c == '\n' || c == '\r' { ' ' } else { c }).collect();
        let mut out =
            format!("error: {}\n  {line}\n  {}{}", self.message, " ".repeat(self.offset), "^".repeat(self.len.max(1)));
        if let Some(help) = &self.help {
            out.push_str("\n  help: ");
            out.push_str(help);
        }
        out
    }
}

/// A value had a different dimension from the one the recipe expects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("expected {}, found {}", .expected.describe(), .found.describe())]
pub struct DimensionError {
    /// The dimension the recipe field requires.
    pub expected: Dimension,
    /// The dimension the value actually has.
    pub found: Dimension,
}
