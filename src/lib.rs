//! spindlelab: spindle-dynamics experiments described once as a recipe and run end to end.
//!
//! This package is the `spindlelab` command (`src/main.rs`); as a library it is the
//! application layer ([`spindlelab_app`]) under one name, as the command and the tests use it.

#![forbid(unsafe_code)]

pub use spindlelab_app::*;
