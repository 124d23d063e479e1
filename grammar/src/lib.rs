//! Quantity grammar of spindlelab recipes: numbers with units, ranges, lists and references.
//!
//! Every dimensioned number in a recipe is a string such as `12.7 mm`, `-13.84 deg/kHz`,
//! `0..4000 step 500 rpm`, `[1000, 2000] rpm` or `@fit.receptance`. This crate parses those
//! strings, converts numbers to SI and tracks their [`Dimension`] so that a length given
//! where a frequency is expected is reported naming both.
//!
//! ```
//! use spindlelab_grammar::{parse_value, Dimension, Value};
//!
//! let Value::Quantity(q) = parse_value("200 GPa").unwrap() else { panic!() };
//! assert_eq!(q.expect(Dimension::PRESSURE), Ok(2e11));
//! let err = q.expect(Dimension::FREQUENCY).unwrap_err();
//! assert_eq!(err.to_string(), "expected a frequency (1/s), found a pressure (Pa)");
//! ```

#![forbid(unsafe_code)]

mod dimension;
mod error;
mod parser;
mod unit;
mod value;

pub use dimension::Dimension;
pub use error::{DimensionError, ParseError};
pub use parser::{looks_like_value, parse_quantity, parse_unit, parse_value};
pub use unit::Unit;
pub use value::{MAX_RANGE_POINTS, Quantity, RANGE_END_TOLERANCE, Reference, Value, range_len, range_points};
