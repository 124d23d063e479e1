//! The host's binding of interface `spindlelab:plugin@0.2.0` (frozen in
//! `plugins/wit/since_v0.2.0`). Its `types` and `node` are those of 0.1.0, so the values are
//! 0.1.0's Rust types (wasmtime checks component types by structure) and one set of
//! conversions serves both; 0.2.0 adds `effects`.

wasmtime::component::bindgen!({
    path: "../wit/since_v0.2.0",
    world: "plugin",
    with: {
        "spindlelab:plugin/types@0.2.0": crate::v0_1_0::spindlelab::plugin::types,
    },
});

pub use exports::spindlelab::plugin::effects::Effect;
#[cfg(test)]
pub use exports::spindlelab::plugin::effects::FreeParam;
