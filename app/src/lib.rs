//! spindlelab's application layer, under the command line: the registry of built-in nodes,
//! the plugins a recipe names, the fit driver, the case importer, the diagnosis, and the run
//! summary the command prints and the snapshot tests record.

#![forbid(unsafe_code)]

pub mod codegen;
pub mod crib;
pub mod diagnose;
pub mod export;
pub mod fit;
pub mod import;
pub mod plugins;
pub mod summary;

pub use spindlelab_domain as domain;
pub use spindlelab_engine as engine;
pub use spindlelab_render as render;
pub use spindlelab_render::renderer;
pub use spindlelab_stdlib as stdlib;

/// The registry of every built-in node kind.
pub fn registry() -> engine::node::Registry {
    let mut r = engine::node::Registry::new();
    stdlib::register(&mut r);
    r
}
