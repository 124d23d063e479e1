//! What one recipe scalar means once parsed: a quantity, a list, a range or a reference.

use std::fmt;

use crate::{Dimension, DimensionError};

/// Largest number of points a range may expand to.
pub const MAX_RANGE_POINTS: usize = 1_000_000;

/// Relative tolerance (in steps) within which a range end counts as lying on the grid.
pub const RANGE_END_TOLERANCE: f64 = 1e-9;

/// A number in SI units together with its dimension.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantity {
    /// Magnitude in the SI unit of `dim`.
    pub value: f64,
    /// Physical dimension of the value.
    pub dim: Dimension,
}

impl Quantity {
    /// Builds a quantity from an SI value and its dimension.
    pub const fn new(value: f64, dim: Dimension) -> Self {
        Quantity { value, dim }
    }

    /// A dimensionless number.
    pub const fn dimensionless(value: f64) -> Self {
        Quantity { value, dim: Dimension::DIMENSIONLESS }
    }

    /// Returns the SI value if the quantity has dimension `dim`, so callers can type-check fields.
    pub fn expect(&self, dim: Dimension) -> Result<f64, DimensionError> {
        if self.dim == dim { Ok(self.value) } else { Err(DimensionError { expected: dim, found: self.dim }) }
    }
}

impl fmt::Display for Quantity {
    /// Writes the SI value followed by its SI unit, e.g. `0.0127 m`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.dim.is_dimensionless() { write!(f, "{}", self.value) } else { write!(f, "{} {}", self.value, self.dim) }
    }
}

/// A reference to another part of the recipe, such as `@fit.receptance` or `@impact`.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Reference {
    /// Name segments; the first names a step or table, the rest a port or entry.
    pub path: Vec<String>,
}

impl Reference {
    /// The first segment (a step or table name), if any.
    pub fn root(&self) -> Option<&str> {
        self.path.first().map(String::as_str)
    }

    /// The segments after the first, e.g. `["receptance"]` for `@fit.receptance`.
    pub fn rest(&self) -> &[String] {
        self.path.get(1..).unwrap_or(&[])
    }
}

impl fmt::Display for Reference {
    /// Writes the reference as it is spelled in a recipe, e.g. `@fit.receptance`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "@{}", self.path.join("."))
    }
}

/// What one recipe scalar string means, with all numbers already in SI.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// A single number, e.g. `12.7 mm` or `0.95`.
    Quantity(Quantity),
    /// Several numbers of one dimension, e.g. `[1000, 2000, 3000] rpm`.
    List(Vec<Quantity>),
    /// An evenly spaced grid `start..end step step`; the end is included when it lies on the grid.
    Range {
        /// First point (SI).
        start: f64,
        /// Last point allowed (SI).
        end: f64,
        /// Spacing (SI), positive.
        step: f64,
        /// Dimension shared by all points.
        dim: Dimension,
    },
    /// A reference such as `@fit.receptance`.
    Reference(Reference),
}

impl Value {
    /// Dimension of the numbers in the value; `None` for a reference or an empty list.
    pub fn dimension(&self) -> Option<Dimension> {
        match self {
            Value::Quantity(q) => Some(q.dim),
            Value::List(items) => items.first().map(|q| q.dim),
            Value::Range { dim, .. } => Some(*dim),
            Value::Reference(_) => None,
        }
    }

    /// Checks that every number in the value has dimension `dim`; references always pass.
    pub fn expect_dim(&self, dim: Dimension) -> Result<(), DimensionError> {
        let found = match self {
            Value::Quantity(q) => Some(q.dim),
            Value::List(items) => items.iter().map(|q| q.dim).find(|d| *d != dim),
            Value::Range { dim, .. } => Some(*dim),
            Value::Reference(_) => None,
        };
        match found {
            Some(found) if found != dim => Err(DimensionError { expected: dim, found }),
            _ => Ok(()),
        }
    }

    /// The single quantity, if this is one.
    pub fn as_quantity(&self) -> Option<&Quantity> {
        match self {
            Value::Quantity(q) => Some(q),
            _ => None,
        }
    }

    /// The reference, if this is one.
    pub fn as_reference(&self) -> Option<&Reference> {
        match self {
            Value::Reference(r) => Some(r),
            _ => None,
        }
    }

    /// The SI numbers the value stands for: one for a quantity, each item of a list, every
    /// grid point of a range, none for a reference.
    pub fn points(&self) -> Vec<f64> {
        match self {
            Value::Quantity(q) => vec![q.value],
            Value::List(items) => items.iter().map(|q| q.value).collect(),
            Value::Range { start, end, step, .. } => range_points(*start, *end, *step),
            Value::Reference(_) => Vec::new(),
        }
    }

    /// Short noun for messages: "a quantity", "a list", "a range" or "a reference".
    pub fn kind(&self) -> &'static str {
        match self {
            Value::Quantity(_) => "a quantity",
            Value::List(_) => "a list",
            Value::Range { .. } => "a range",
            Value::Reference(_) => "a reference",
        }
    }
}

/// Number of grid points of `start..end step step`, or `None` if the range is invalid
/// (non-finite, non-positive step, end below start) or exceeds [`MAX_RANGE_POINTS`].
pub fn range_len(start: f64, end: f64, step: f64) -> Option<usize> {
    if !(start.is_finite() && end.is_finite() && step.is_finite()) || step <= 0.0 || end < start {
        return None;
    }
    let intervals = ((end - start) / step + RANGE_END_TOLERANCE).floor();
    if !intervals.is_finite() || intervals >= MAX_RANGE_POINTS as f64 {
        return None;
    }
    Some(intervals as usize + 1)
}

/// Grid points `start, start + step, ...` up to `end`, including `end` when it lies on the
/// grid within `1e-9 * step`; empty when the range is invalid.
pub fn range_points(start: f64, end: f64, step: f64) -> Vec<f64> {
    let Some(n) = range_len(start, end, step) else {
        return Vec::new();
    };
    (0..n)
        .map(|i| {
            let x = start + i as f64 * step;
            if (x - end).abs() <= RANGE_END_TOLERANCE * step { end } else { x }
        })
        .collect()
}
