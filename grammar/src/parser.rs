//! Turns the pest parse tree of a recipe scalar into SI values with dimensions.

use pest::Parser;
use pest::error::{ErrorVariant, InputLocation};
use pest::iterators::Pair;

use crate::unit::{Scale, SymbolError, lookup_symbol};
use crate::value::{MAX_RANGE_POINTS, range_len};
use crate::{ParseError, Quantity, Reference, Unit, Value};

#[derive(pest_derive::Parser)]
#[grammar = "quantity.pest"]
struct QuantityParser;

/// Deepest parenthesis nesting accepted in a unit expression.
const MAX_NESTING: usize = 16;

/// Largest absolute unit exponent accepted, e.g. the `3` in `m^3`.
const MAX_EXPONENT: i32 = 24;

/// Parses one recipe scalar: a quantity, a list, a range or a reference, in SI units.
pub fn parse_value(text: &str) -> Result<Value, ParseError> {
    let cx = Cx { text };
    cx.precheck()?;
    let mut pairs = QuantityParser::parse(Rule::value_input, text).map_err(|e| cx.pest_error(&e))?;
    let Some(pair) = pairs.next() else {
        return Err(cx.error_at(0, "expected a value"));
    };
    match pair.as_rule() {
        Rule::reference => Ok(Value::Reference(cx.reference(pair))),
        Rule::list => cx.list(pair),
        Rule::range => cx.range(pair),
        Rule::quantity => {
            let item = pair.into_inner().next().ok_or_else(|| cx.error_at(0, "expected a number"))?;
            let item = cx.item(item)?;
            Ok(Value::Quantity(cx.quantity(&item, None)?))
        }
        _ => Err(cx.error_at(0, "expected a value")),
    }
}

/// Parses text that must be a single quantity such as `12.7 mm` or `0.95`.
pub fn parse_quantity(text: &str) -> Result<Quantity, ParseError> {
    match parse_value(text)? {
        Value::Quantity(q) => Ok(q),
        other => {
            let start = text.chars().take_while(|c| c.is_whitespace()).count();
            let len = text.trim().chars().count();
            Err(ParseError::new(start, len, format!("expected a single quantity, found {}", other.kind()))
                .with_help("write one number with its unit, e.g. `12.7 mm`"))
        }
    }
}

/// Parses a unit expression such as `N*s/m`, `kg/m^3`, `deg/kHz` or `1/s`.
pub fn parse_unit(text: &str) -> Result<Unit, ParseError> {
    let cx = Cx { text };
    cx.precheck()?;
    let mut pairs = QuantityParser::parse(Rule::unit_input, text).map_err(|e| cx.pest_error(&e))?;
    let Some(pair) = pairs.next() else {
        return Err(cx.error_at(0, "expected a unit"));
    };
    let span = pair.as_span();
    let scale = match pair.as_rule() {
        Rule::unit => cx.unit(pair)?,
        _ => Scale::ONE,
    };
    scale.to_unit().ok_or_else(|| cx.error(span, "unit scale is out of range"))
}

/// Cheap test whether a scalar is meant as a value: after leading whitespace it starts with
/// a digit, a sign, `.`, `[` or `@`.
pub fn looks_like_value(text: &str) -> bool {
    text.trim_start().starts_with(|c: char| c.is_ascii_digit() || matches!(c, '+' | '-' | '.' | '[' | '@'))
}

/// A parsed list item or range bound before unit defaults are applied.
struct Item<'a> {
    pair: Pair<'a, Rule>,
    number: &'a str,
    raw: f64,
    unit: Option<Scale>,
}

/// Parsing context: the original text, for converting byte positions to character columns.
struct Cx<'a> {
    text: &'a str,
}

impl<'a> Cx<'a> {
    fn col(&self, byte: usize) -> usize {
        self.text.get(..byte).map_or(0, |s| s.chars().count())
    }

    fn error(&self, span: pest::Span<'_>, message: impl Into<String>) -> ParseError {
        let offset = self.col(span.start());
        ParseError::new(offset, span.as_str().chars().count(), message)
    }

    fn error_at(&self, byte: usize, message: impl Into<String>) -> ParseError {
        let len = usize::from(self.text.get(byte..).is_some_and(|s| !s.is_empty()));
        ParseError::new(self.col(byte), len, message)
    }

    /// Rejects empty input and runaway parenthesis nesting before running the grammar.
    fn precheck(&self) -> Result<(), ParseError> {
        if self.text.trim().is_empty() {
            return Err(ParseError::new(0, 0, "expected a value, found an empty string")
                .with_help("write a number with a unit, e.g. `12.7 mm`"));
        }
        let mut depth = 0usize;
        for (i, c) in self.text.char_indices() {
            match c {
                '(' => depth += 1,
                ')' => depth = depth.saturating_sub(1),
                _ => {}
            }
            if depth > MAX_NESTING {
                return Err(self.error_at(i, "too many nested parentheses in unit"));
            }
        }
        Ok(())
    }

    /// Converts a grammar failure into a message naming what was expected.
    fn pest_error(&self, e: &pest::error::Error<Rule>) -> ParseError {
        let pos = match e.location {
            InputLocation::Pos(p) => p,
            InputLocation::Span((s, _)) => s,
        };
        let positives: Vec<Rule> = match &e.variant {
            ErrorVariant::ParsingError { positives, .. } => positives.clone(),
            ErrorVariant::CustomError { .. } => Vec::new(),
        };
        let rest = self.text.get(pos..).unwrap_or("");
        let at_start = self.text.get(..pos).is_some_and(|s| s.trim().is_empty());
        let wants = |r: Rule| positives.contains(&r);
        let structural = [Rule::comma, Rule::close, Rule::dots, Rule::step_kw, Rule::name, Rule::number, Rule::rparen];
        let mut expected: Vec<&str> = Vec::new();
        for rule in &positives {
            let word = match rule {
                Rule::number | Rule::nonfinite | Rule::item | Rule::quantity | Rule::range => "a number",
                Rule::reference | Rule::name => "a name",
                Rule::list | Rule::open => "`[`",
                Rule::comma => "`,`",
                Rule::close => "`]`",
                Rule::dots if wants(Rule::EOI) => continue,
                Rule::dots => "`..`",
                Rule::step_kw => "`step`",
                Rule::unit | Rule::unit_factor | Rule::unit_symbol | Rule::one => {
                    if positives.iter().any(|r| structural.contains(r)) {
                        continue;
                    }
                    "a unit"
                }
                Rule::exponent | Rule::superscript => {
                    if positives.iter().any(|r| structural.contains(r)) || wants(Rule::EOI) {
                        continue;
                    }
                    "an integer exponent"
                }
                Rule::mul | Rule::div => {
                    if positives.iter().any(|r| structural.contains(r)) || wants(Rule::EOI) {
                        continue;
                    }
                    if *rule == Rule::mul { "`*`" } else { "`/`" }
                }
                Rule::rparen => "`)`",
                Rule::EOI => "end of input",
                _ => continue,
            };
            if !expected.contains(&word) {
                expected.push(word);
            }
        }
        if at_start {
            expected = vec!["a number"];
        }
        let message = match expected.as_slice() {
            [] => "unexpected input".to_string(),
            [one] => format!("expected {one}"),
            [init @ .., last] => format!("expected {} or {last}", init.join(", ")),
        };
        let found = rest.chars().next();
        let message = match found {
            Some(c) => format!("{message}, found `{c}`"),
            None => format!("{message}, found end of input"),
        };
        let mut err = self.error_at(pos, message);
        if at_start && rest.starts_with(|c: char| c.is_alphabetic() || c == '%' || c == '°' || c == 'µ') {
            err = err.with_help(if rest.trim_start().to_ascii_lowercase().starts_with(['n', 'i']) {
                "numbers must be finite decimals such as `12.7` or `1e-3`"
            } else {
                "write the number before its unit, e.g. `12.7 mm`; references start with `@`"
            });
        } else if wants(Rule::name) {
            err = err.with_help("names start with a letter or `_` and contain letters, digits, `_` or `-`");
        } else if wants(Rule::step_kw) {
            err = err.with_help("write ranges as `start..end step size unit`, e.g. `0..4000 step 500 rpm`");
        } else if wants(Rule::EOI)
            && found.is_some_and(|c| c.is_alphabetic())
            && !self.text.trim_start().starts_with('@')
        {
            err = err.with_help("combine units with `*` or `/`, e.g. `N*s/m`");
        }
        err
    }

    fn reference(&self, pair: Pair<'a, Rule>) -> Reference {
        Reference { path: pair.into_inner().map(|p| p.as_str().to_string()).collect() }
    }

    fn item(&self, pair: Pair<'a, Rule>) -> Result<Item<'a>, ParseError> {
        let whole = pair.clone();
        let mut inner = pair.into_inner();
        let Some(num) = inner.next() else {
            return Err(self.error(whole.as_span(), "expected a number"));
        };
        let number = num.as_str();
        if num.as_rule() == Rule::nonfinite {
            return Err(self
                .error(num.as_span(), format!("non-finite number `{number}` is not allowed"))
                .with_help("write a finite decimal number such as `12.7` or `1e-3`"));
        }
        let raw: f64 = number.parse().map_err(|_| self.error(num.as_span(), format!("invalid number `{number}`")))?;
        if !raw.is_finite() {
            return Err(self.error(num.as_span(), format!("number `{number}` is out of range")));
        }
        let unit = inner.next().map(|u| self.unit(u)).transpose()?;
        Ok(Item { pair: whole, number, raw, unit })
    }

    /// Converts an item to SI using its own unit, else `default`, else no unit.
    fn quantity(&self, item: &Item<'a>, default: Option<Scale>) -> Result<Quantity, ParseError> {
        let scale = item.unit.or(default).unwrap_or(Scale::ONE);
        let value = scale.convert(item.number, item.raw);
        if !value.is_finite() {
            return Err(
                self.error(item.pair.as_span(), format!("`{}` is out of range in SI units", item.pair.as_str()))
            );
        }
        Ok(Quantity { value, dim: scale.dim })
    }

    fn list(&self, pair: Pair<'a, Rule>) -> Result<Value, ParseError> {
        let span = pair.as_span();
        let mut items = Vec::new();
        let mut trailing = None;
        for p in pair.into_inner() {
            match p.as_rule() {
                Rule::item => items.push(self.item(p)?),
                Rule::unit => trailing = Some(self.unit(p)?),
                _ => {}
            }
        }
        if items.is_empty() {
            return Err(self.error(span, "a list needs at least one item"));
        }
        let mut out: Vec<Quantity> = Vec::with_capacity(items.len());
        for item in &items {
            let q = self.quantity(item, trailing)?;
            if let Some(first) = out.first().filter(|f| f.dim != q.dim) {
                return Err(self
                    .error(
                        item.pair.as_span(),
                        format!(
                            "list items differ in dimension: this is {}, the first is {}",
                            q.dim.describe(),
                            first.dim.describe()
                        ),
                    )
                    .with_help("give every item the same kind of unit, or one unit after `]`"));
            }
            out.push(q);
        }
        Ok(Value::List(out))
    }

    fn range(&self, pair: Pair<'a, Rule>) -> Result<Value, ParseError> {
        let span = pair.as_span();
        let items: Vec<Item<'a>> =
            pair.into_inner().filter(|p| p.as_rule() == Rule::item).map(|p| self.item(p)).collect::<Result<_, _>>()?;
        let [start, end, step] = items.as_slice() else {
            return Err(self.error(span, "expected `start..end step size`"));
        };
        // Bounds without a unit take the step's unit: `0..4000 step 500 rpm`.
        let default = step.unit;
        let qs = [self.quantity(start, default)?, self.quantity(end, default)?, self.quantity(step, default)?];
        let dim = qs[2].dim;
        for (q, item) in qs.iter().zip([start, end]) {
            if q.dim != dim {
                return Err(self
                    .error(
                        item.pair.as_span(),
                        format!(
                            "range bounds differ in dimension: this is {}, the step is {}",
                            q.dim.describe(),
                            dim.describe()
                        ),
                    )
                    .with_help("use one kind of unit for start, end and step"));
            }
        }
        let [start_v, end_v, step_v] = [qs[0].value, qs[1].value, qs[2].value];
        if step_v <= 0.0 {
            let mut err = self.error(step.pair.as_span(), "range step must be positive");
            if step_v < 0.0 {
                err = err.with_help("write ranges in increasing order with a positive step, e.g. `0..10 step 1 s`");
            }
            return Err(err);
        }
        if end_v < start_v {
            return Err(self
                .error(end.pair.as_span(), "range end is below its start")
                .with_help("write ranges in increasing order, e.g. `0..10 step 1 s`"));
        }
        if range_len(start_v, end_v, step_v).is_none() {
            return Err(self
                .error(span, format!("range has more than {MAX_RANGE_POINTS} points"))
                .with_help("use a larger step or a shorter range"));
        }
        Ok(Value::Range { start: start_v, end: end_v, step: step_v, dim })
    }

    /// Evaluates a unit expression left to right: `N/m/s` is `N/(m*s)`.
    fn unit(&self, pair: Pair<'a, Rule>) -> Result<Scale, ParseError> {
        let span = pair.as_span();
        let mut acc = Scale::ONE;
        let mut divide = false;
        for p in pair.into_inner() {
            match p.as_rule() {
                Rule::mul => divide = false,
                Rule::div => divide = true,
                Rule::unit_factor => {
                    let f = self.factor(p)?;
                    let next = if divide { acc.div(f) } else { acc.mul(f) };
                    acc = next.ok_or_else(|| self.error(span, "unit is out of range"))?;
                }
                _ => {}
            }
        }
        Ok(acc)
    }

    fn factor(&self, pair: Pair<'a, Rule>) -> Result<Scale, ParseError> {
        let span = pair.as_span();
        let mut base = Scale::ONE;
        for p in pair.into_inner() {
            match p.as_rule() {
                Rule::unit_symbol => base = self.symbol(&p)?,
                Rule::unit => base = self.unit(p)?,
                Rule::exponent | Rule::superscript => {
                    let n = if p.as_rule() == Rule::exponent {
                        p.as_str().parse::<i32>().ok()
                    } else {
                        superscript(p.as_str())
                    };
                    let n = n.filter(|n| n.unsigned_abs() <= MAX_EXPONENT.unsigned_abs()).ok_or_else(|| {
                        self.error(
                            p.as_span(),
                            format!("unit exponent must be between -{MAX_EXPONENT} and {MAX_EXPONENT}"),
                        )
                    })?;
                    base = base.powi(n).ok_or_else(|| self.error(span, "unit is out of range"))?;
                }
                _ => {}
            }
        }
        Ok(base)
    }

    fn symbol(&self, pair: &Pair<'a, Rule>) -> Result<Scale, ParseError> {
        let text = pair.as_str();
        lookup_symbol(text).map_err(|e| match e {
            SymbolError::Unknown(suggestions) => {
                let err = self.error(pair.as_span(), format!("unknown unit `{text}`"));
                match suggestions.as_slice() {
                    [] => err,
                    [one] => err.with_help(format!("did you mean `{one}`?")),
                    [init @ .., last] => {
                        let init: Vec<String> = init.iter().map(|s| format!("`{s}`")).collect();
                        err.with_help(format!("did you mean {} or `{last}`?", init.join(", ")))
                    }
                }
            }
            SymbolError::Unsupported(message, help) => self.error(pair.as_span(), message).with_help(help),
        })
    }
}

/// Value of a superscript integer such as `²` or `⁻¹`.
fn superscript(text: &str) -> Option<i32> {
    let mut sign = 1;
    let mut value: i32 = 0;
    for c in text.chars() {
        let digit = match c {
            '⁻' => {
                sign = -1;
                continue;
            }
            '⁺' => continue,
            '⁰' => 0,
            '¹' => 1,
            '²' => 2,
            '³' => 3,
            '⁴'..='⁹' => c as i32 - '⁴' as i32 + 4,
            _ => return None,
        };
        value = value.checked_mul(10)?.checked_add(digit)?;
    }
    Some(sign * value)
}

impl std::str::FromStr for Value {
    type Err = ParseError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        parse_value(s)
    }
}

impl std::str::FromStr for Quantity {
    type Err = ParseError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        parse_quantity(s)
    }
}

impl std::str::FromStr for Unit {
    type Err = ParseError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        parse_unit(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Dimension;

    #[test]
    fn superscripts() {
        assert_eq!(superscript("²"), Some(2));
        assert_eq!(superscript("⁻¹"), Some(-1));
        assert_eq!(superscript("¹²"), Some(12));
        assert_eq!(superscript("⁹"), Some(9));
    }

    #[test]
    fn range_takes_the_step_dimension() {
        let v = parse_value("0..1 step 0.5 s").unwrap();
        assert_eq!(v.dimension(), Some(Dimension::TIME));
    }
}
