//! The example and fixture plugins of `plugins/guest`, built once for tests and benchmarks:
//! `dir()` holds `ID.wasm` and `ID.plugin.json` for each of them.

#![forbid(unsafe_code)]

use std::path::Path;

/// The folder holding the built plugins.
pub fn dir() -> &'static Path {
    Path::new(env!("SPINDLELAB_EXAMPLE_PLUGINS"))
}

/// The manifest of plugin `id` (`chatter-indicator`, `tip-mass`, `hostile`, `legacy`, `bad-effect`).
pub fn manifest(id: &str) -> std::path::PathBuf {
    dir().join(format!("{id}.plugin.json"))
}

/// The cargo target folder the plugins were built in (their dependencies compiled for wasm32).
pub fn target_dir() -> &'static Path {
    Path::new(env!("SPINDLELAB_EXAMPLE_TARGET"))
}
