//! Unit symbols, SI prefixes and the conversion factor of a unit expression.

use std::f64::consts::PI;

use crate::Dimension;

/// A unit: a value written in it is `value * scale` in SI, with dimension `dim`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unit {
    /// Factor from this unit to the SI unit of `dim`.
    pub scale: f64,
    /// Dimension of quantities measured in this unit.
    pub dim: Dimension,
}

impl Unit {
    /// The unit of a plain number: scale 1, dimensionless.
    pub const ONE: Unit = Unit { scale: 1.0, dim: Dimension::DIMENSIONLESS };

    /// Converts a value written in this unit to SI.
    pub fn to_si(&self, value: f64) -> f64 {
        value * self.scale
    }
}

/// A unit scale kept as `factor * 10^pow10` so decimal prefixes convert without rounding.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Scale {
    pub factor: f64,
    pub pow10: i32,
    pub dim: Dimension,
}

impl Scale {
    pub const ONE: Scale = Scale { factor: 1.0, pow10: 0, dim: Dimension::DIMENSIONLESS };

    pub fn mul(self, rhs: Scale) -> Option<Scale> {
        Some(Scale {
            factor: finite(self.factor * rhs.factor)?,
            pow10: self.pow10.checked_add(rhs.pow10)?,
            dim: self.dim.checked_mul(rhs.dim)?,
        })
    }

    pub fn div(self, rhs: Scale) -> Option<Scale> {
        self.mul(rhs.powi(-1)?)
    }

    pub fn powi(self, n: i32) -> Option<Scale> {
        Some(Scale {
            factor: finite(self.factor.powi(n))?,
            pow10: self.pow10.checked_mul(n)?,
            dim: self.dim.checked_powi(n)?,
        })
    }

    /// The combined scale as one number, if it is finite and non-zero.
    pub fn to_unit(self) -> Option<Unit> {
        let scale = finite(self.factor * pow10(self.pow10))?;
        Some(Unit { scale, dim: self.dim })
    }

    /// Converts the decimal text `number` (already validated as finite) to SI.
    ///
    /// The decimal exponent of the unit is folded into the number's own exponent before
    /// parsing, so `76.2 um` gives the double nearest to 7.62e-5 rather than `76.2 * 1e-6`.
    pub fn convert(self, number: &str, raw: f64) -> f64 {
        let shifted = if self.pow10 == 0 {
            Some(raw)
        } else {
            let (mantissa, exp) = match number.find(['e', 'E']) {
                Some(i) => (&number[..i], number[i + 1..].parse::<i64>().ok()),
                None => (number, Some(0)),
            };
            exp.and_then(|e| e.checked_add(i64::from(self.pow10)))
                .and_then(|e| format!("{mantissa}e{e}").parse::<f64>().ok())
        };
        match shifted {
            Some(v) => v * self.factor,
            None => raw * self.factor * pow10(self.pow10),
        }
    }
}

fn finite(x: f64) -> Option<f64> {
    (x.is_finite() && x != 0.0).then_some(x)
}

/// Correctly rounded `10^n`.
fn pow10(n: i32) -> f64 {
    format!("1e{n}").parse().unwrap_or(f64::NAN)
}

/// One unit symbol: name, factor, decimal exponent, dimension, and whether SI prefixes apply.
struct Symbol {
    sym: &'static str,
    factor: f64,
    pow10: i32,
    dim: Dimension,
    prefixable: bool,
}

const fn sym(sym: &'static str, factor: f64, pow10: i32, dim: Dimension, prefixable: bool) -> Symbol {
    Symbol { sym, factor, pow10, dim, prefixable }
}

const D: Dimension = Dimension::DIMENSIONLESS;

/// Every unit symbol, matched whole before any prefix is stripped (so `min` is minutes).
const SYMBOLS: &[Symbol] = &[
    sym("m", 1.0, 0, Dimension::LENGTH, true),
    sym("kg", 1.0, 0, Dimension::MASS, false),
    sym("g", 1.0, -3, Dimension::MASS, true),
    sym("s", 1.0, 0, Dimension::TIME, true),
    sym("min", 60.0, 0, Dimension::TIME, false),
    sym("h", 3600.0, 0, Dimension::TIME, false),
    sym("Hz", 1.0, 0, Dimension::FREQUENCY, true),
    sym("rpm", 2.0 * PI / 60.0, 0, Dimension::ROTATIONAL_SPEED, false),
    sym("rps", 2.0 * PI, 0, Dimension::ROTATIONAL_SPEED, false),
    sym("rev", 2.0 * PI, 0, Dimension::ANGLE, false),
    sym("rad", 1.0, 0, Dimension::ANGLE, true),
    sym("deg", PI / 180.0, 0, Dimension::ANGLE, false),
    sym("°", PI / 180.0, 0, Dimension::ANGLE, false),
    sym("N", 1.0, 0, Dimension::FORCE, true),
    sym("Pa", 1.0, 0, Dimension::PRESSURE, true),
    sym("J", 1.0, 0, Dimension::ENERGY, true),
    sym("W", 1.0, 0, Dimension::POWER, true),
    sym("in", 254.0, -4, Dimension::LENGTH, false),
    sym("ft", 3048.0, -4, Dimension::LENGTH, false),
    sym("lb", 45359237.0, -8, Dimension::MASS, false),
    sym("lbf", 4.4482216152605, 0, Dimension::FORCE, false),
    sym("psi", 6894.757293168, 0, Dimension::PRESSURE, false),
    sym("ksi", 6894.757293168, 3, Dimension::PRESSURE, false),
    sym("%", 1.0, -2, D, false),
    sym("tooth", 1.0, 0, D, false),
    sym("teeth", 1.0, 0, D, false),
    sym("flute", 1.0, 0, D, false),
    sym("flutes", 1.0, 0, D, false),
];

/// SI prefixes with their decimal exponents; `c` and `d` apply to the metre only.
const PREFIXES: &[(&str, i32)] = &[
    ("p", -12),
    ("n", -9),
    ("u", -6),
    ("µ", -6),
    ("μ", -6),
    ("m", -3),
    ("c", -2),
    ("d", -1),
    ("k", 3),
    ("M", 6),
    ("G", 9),
    ("T", 12),
];

/// Why a unit symbol was not accepted.
pub(crate) enum SymbolError {
    /// Not a known symbol; carries suggestions.
    Unknown(Vec<String>),
    /// A known notation that is deliberately unsupported, with an explanation.
    Unsupported(String, String),
}

/// Resolves one unit symbol: a whole symbol first, then prefix + prefixable symbol.
pub(crate) fn lookup_symbol(text: &str) -> Result<Scale, SymbolError> {
    if let Some(s) = SYMBOLS.iter().find(|s| s.sym == text) {
        return Ok(Scale { factor: s.factor, pow10: s.pow10, dim: s.dim });
    }
    for (prefix, p) in PREFIXES {
        let Some(rest) = text.strip_prefix(prefix) else {
            continue;
        };
        if (*prefix == "c" || *prefix == "d") && rest != "m" {
            continue;
        }
        if let Some(s) = SYMBOLS.iter().find(|s| s.prefixable && s.sym == rest) {
            return Ok(Scale { factor: s.factor, pow10: s.pow10 + p, dim: s.dim });
        }
    }
    if text.starts_with("dB") {
        return Err(SymbolError::Unsupported(
            format!("decibels (`{text}`) are not a unit here"),
            "give the linear ratio as a plain number, e.g. `0.5`".to_string(),
        ));
    }
    if matches!(text, "K" | "°C" | "°F" | "C" | "F") {
        return Err(SymbolError::Unsupported(
            format!("`{text}` is not supported; temperatures are not recipe quantities"),
            "remove the unit or use a supported one".to_string(),
        ));
    }
    Err(SymbolError::Unknown(suggest(text)))
}

/// All spellings a user may mean, for suggestions (ASCII prefixes only).
fn candidates() -> Vec<String> {
    let mut out: Vec<String> = SYMBOLS.iter().map(|s| s.sym.to_string()).collect();
    for (prefix, _) in PREFIXES.iter().filter(|(p, _)| p.is_ascii()) {
        for s in SYMBOLS.iter().filter(|s| s.prefixable) {
            if (*prefix == "c" || *prefix == "d") && s.sym != "m" {
                continue;
            }
            out.push(format!("{prefix}{}", s.sym));
        }
    }
    out
}

/// Closest known symbols: exact case-insensitive matches, else those within a small edit distance.
fn suggest(text: &str) -> Vec<String> {
    let all = candidates();
    let lower = text.to_lowercase();
    let same_case: Vec<String> = all.iter().filter(|c| c.to_lowercase() == lower).cloned().collect();
    if !same_case.is_empty() {
        return same_case;
    }
    let len = text.chars().count();
    let max = if len <= 2 { 1 } else { 2 };
    let scored: Vec<(usize, &String)> = all.iter().map(|c| (levenshtein(text, c), c)).collect();
    let Some(best) = scored.iter().map(|(d, _)| *d).min().filter(|d| *d <= max && *d < len) else {
        return Vec::new();
    };
    scored.into_iter().filter(|(d, _)| *d == best).map(|(_, c)| c.clone()).take(3).collect()
}

/// Edit distance between two strings in characters, counting an adjacent swap as one edit.
pub(crate) fn levenshtein(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let w = b.len() + 1;
    let mut d = vec![0usize; (a.len() + 1) * w];
    for (i, row) in d.chunks_mut(w).enumerate() {
        row[0] = i;
    }
    for (j, cell) in d.iter_mut().take(w).enumerate() {
        *cell = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut best = (d[(i - 1) * w + j] + 1).min(d[i * w + j - 1] + 1).min(d[(i - 1) * w + j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                best = best.min(d[(i - 2) * w + j - 2] + 1);
            }
            d[i * w + j] = best;
        }
    }
    d[a.len() * w + b.len()]
}
