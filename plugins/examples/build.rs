//! Builds every plugin crate of `plugins/guest` for wasm32-unknown-unknown and packs each
//! into `$OUT_DIR/plugins` (component + manifest), once per change of their sources.

use std::path::{Path, PathBuf};

const CRATES: &[&str] =
    &["examples/chatter-indicator", "examples/tip-mass", "fixtures/hostile", "fixtures/legacy", "fixtures/bad-effect"];

fn main() {
    let guest = Path::new(env!("CARGO_MANIFEST_DIR")).join("../guest");
    let wit = Path::new(env!("CARGO_MANIFEST_DIR")).join("../wit");
    for p in ["sdk", "examples", "fixtures", "Cargo.toml", "Cargo.lock"] {
        println!("cargo:rerun-if-changed={}", guest.join(p).display());
    }
    println!("cargo:rerun-if-changed={}", wit.display());
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let cargo = PathBuf::from(std::env::var_os("CARGO").expect("cargo sets CARGO"));
    let target_dir = out.join("target");
    let plugins = out.join("plugins");
    for krate in CRATES {
        if let Err(e) = spindlelab_plugin_pack::build(&cargo, &guest.join(krate), &target_dir, &plugins, true) {
            panic!("{e}");
        }
    }
    println!("cargo:rustc-env=SPINDLELAB_EXAMPLE_PLUGINS={}", plugins.display());
    println!("cargo:rustc-env=SPINDLELAB_EXAMPLE_TARGET={}", target_dir.display());
}
