//! spindlelab: spindle-dynamics experiments described once as a recipe and run end to end.
//!
//! This crate is the front: the `spindlelab` binary, the registry of built-in nodes, and the
//! run summary that the CLI prints and the snapshot tests record.

pub mod diagnose;
pub mod fit;
pub mod import;
pub mod plugins;
pub mod summary;

pub use spindlelab_domain as domain;
pub use spindlelab_engine as engine;
pub use spindlelab_stdlib as stdlib;

/// The registry of every built-in node kind.
pub fn registry() -> engine::node::Registry {
    let mut r = engine::node::Registry::new();
    stdlib::register(&mut r);
    r
}
