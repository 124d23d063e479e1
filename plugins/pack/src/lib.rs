//! What a plugin is on disk: a WebAssembly component (`NAME.wasm`) beside its manifest
//! (`NAME.plugin.json`), and how one is made from a plugin crate.
//!
//! The manifest names the plugin, its version, the interface version it was built for, the
//! component file and its SHA-256, and the limits it asks for; the host checks the hash
//! before it compiles anything and clamps the limits to its own policy. Packing turns the
//! core module a `wasm32-unknown-unknown` build makes into a component (the interface types
//! travel in the module's custom section, put there by the SDK's bindings).

#![forbid(unsafe_code)]

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The interface versions this crate knows, newest last.
pub const INTERFACE_VERSIONS: &[&str] = &["0.1.0", "0.2.0"];

/// Largest manifest read, bytes.
pub const MAX_MANIFEST_BYTES: u64 = 64 * 1024;

/// File name suffix of a manifest.
pub const MANIFEST_SUFFIX: &str = ".plugin.json";

/// A plugin's manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// The plugin's id (its crate name), as recipes name it.
    pub id: String,
    /// Its semantic version.
    pub version: String,
    /// The `spindlelab:plugin` interface version it was built for.
    pub interface: String,
    /// The component file, relative to the manifest's folder (a plain file name).
    pub wasm: String,
    /// SHA-256 of the component file, lowercase hex.
    pub sha256: String,
    /// Limits the plugin asks for; the host clamps them to its policy.
    #[serde(default)]
    pub limits: RequestedLimits,
}

/// Limits a plugin asks for (each clamped by the host; absent means the host's default).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RequestedLimits {
    /// Linear memory per call, MiB.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub memory_mib: Option<u64>,
    /// Work per call, in fuel units (about one per WebAssembly instruction).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fuel: Option<u64>,
    /// Numbers in all outputs of one call.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_values: Option<u64>,
}

/// Why a plugin could not be read or made.
#[derive(Debug, thiserror::Error)]
pub enum PackError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}: not a plugin manifest: {message}")]
    Manifest { path: PathBuf, message: String },
    #[error("{path}: the manifest is {size} bytes; a manifest is at most {MAX_MANIFEST_BYTES} bytes")]
    ManifestTooLarge { path: PathBuf, size: u64 },
    #[error("{0} is not a WebAssembly core module with spindlelab plugin bindings: {1}")]
    Componentize(PathBuf, String),
    #[error("building {crate_dir}: {message}")]
    Build { crate_dir: PathBuf, message: String },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> PackError + '_ {
    move |source| PackError::Io { path: path.to_path_buf(), source }
}

/// SHA-256 of `bytes`, lowercase hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    let digest = Sha256::digest(bytes);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

impl Manifest {
    /// Reads a manifest, refusing files larger than [`MAX_MANIFEST_BYTES`] and component
    /// paths that leave the manifest's folder.
    pub fn read(path: &Path) -> Result<Manifest, PackError> {
        use std::io::Read;
        // A pipe or a device named as the manifest would be waited on or read forever.
        if std::fs::metadata(path).is_ok_and(|m| !m.is_file()) {
            return Err(io(path)(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "not a regular file (a pipe, a device or a folder)",
            )));
        }
        let file = std::fs::File::open(path).map_err(io(path))?;
        let mut text = String::new();
        file.take(MAX_MANIFEST_BYTES + 1).read_to_string(&mut text).map_err(io(path))?;
        if text.len() as u64 > MAX_MANIFEST_BYTES {
            return Err(PackError::ManifestTooLarge { path: path.to_path_buf(), size: text.len() as u64 });
        }
        let m: Manifest = serde_json::from_str(&text)
            .map_err(|e| PackError::Manifest { path: path.to_path_buf(), message: e.to_string() })?;
        let bad = |message: String| Err(PackError::Manifest { path: path.to_path_buf(), message });
        if m.wasm.is_empty() || m.wasm.contains(['/', '\\']) || m.wasm.starts_with('.') {
            return bad(format!("`wasm` is `{}`; give the component's file name in the manifest's folder", m.wasm));
        }
        if m.sha256.len() != 64 || !m.sha256.bytes().all(|b| b.is_ascii_hexdigit()) {
            return bad(format!("`sha256` is `{}`; give the 64 hex digits of the component's SHA-256", m.sha256));
        }
        if m.id.is_empty() || !m.id.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_') {
            return bad(format!("`id` is `{}`; use letters, digits, `-` and `_`", m.id));
        }
        Ok(m)
    }

    /// Writes the manifest as pretty JSON.
    pub fn write(&self, path: &Path) -> Result<(), PackError> {
        let text = serde_json::to_string_pretty(self).expect("a manifest serialises") + "\n";
        std::fs::write(path, text).map_err(io(path))
    }

    /// The component file beside the manifest at `manifest_path`.
    pub fn wasm_path(&self, manifest_path: &Path) -> PathBuf {
        manifest_path.parent().unwrap_or(Path::new(".")).join(&self.wasm)
    }
}

/// Makes a component from a core module built with the SDK.
pub fn componentize(core: &[u8], name: &Path) -> Result<Vec<u8>, PackError> {
    wit_component::ComponentEncoder::default()
        .module(core)
        .and_then(|e| e.validate(true).encode())
        .map_err(|e| PackError::Componentize(name.to_path_buf(), format!("{e:#}")))
}

/// The interface version whose `node` the component exports (the newest, if several).
pub fn interface_of(component: &[u8]) -> Option<String> {
    let mut found = None;
    for payload in wasmparser::Parser::new(0).parse_all(component) {
        let Ok(wasmparser::Payload::ComponentExportSection(exports)) = payload else { continue };
        for export in exports.into_iter().flatten() {
            // The name with its version suffix appended, when the encoder split them.
            let n = export.name;
            let name = match (n.implements, n.version_suffix) {
                (None, Some(suffix)) => format!("{}{suffix}", n.name),
                _ => n.name.to_string(),
            };
            if let Some(v) = name.strip_prefix("spindlelab:plugin/node@")
                && let Some(i) = INTERFACE_VERSIONS.iter().position(|k| *k == v)
            {
                found = found.max(Some(i));
            }
        }
    }
    found.map(|i| INTERFACE_VERSIONS[i].to_string())
}

/// A plugin written by [`pack`] or [`build`].
#[derive(Debug, Clone)]
pub struct Packed {
    pub manifest: Manifest,
    pub manifest_path: PathBuf,
}

/// Packs the core module `core_wasm` as plugin `id` `version` into `out_dir`: the component
/// `ID.wasm` and the manifest `ID.plugin.json`.
pub fn pack(core_wasm: &Path, id: &str, version: &str, out_dir: &Path) -> Result<Packed, PackError> {
    let core = std::fs::read(core_wasm).map_err(io(core_wasm))?;
    let component = componentize(&core, core_wasm)?;
    std::fs::create_dir_all(out_dir).map_err(io(out_dir))?;
    let wasm = format!("{id}.wasm");
    let wasm_path = out_dir.join(&wasm);
    std::fs::write(&wasm_path, &component).map_err(io(&wasm_path))?;
    let manifest = Manifest {
        id: id.to_string(),
        version: version.to_string(),
        interface: interface_of(&component).ok_or_else(|| {
            PackError::Componentize(
                core_wasm.to_path_buf(),
                format!(
                    "it exports no `spindlelab:plugin/node` of a known version ({})",
                    INTERFACE_VERSIONS.join(", ")
                ),
            )
        })?,
        wasm,
        sha256: sha256_hex(&component),
        limits: RequestedLimits::default(),
    };
    let manifest_path = out_dir.join(format!("{id}{MANIFEST_SUFFIX}"));
    manifest.write(&manifest_path)?;
    Ok(Packed { manifest, manifest_path })
}

/// The name and version of the package whose `Cargo.toml` is in `crate_dir`.
fn package_of(cargo: &Path, crate_dir: &Path) -> Result<(String, String), PackError> {
    let fail = |message: String| PackError::Build { crate_dir: crate_dir.to_path_buf(), message };
    let out = clean_cargo(cargo)
        .args(["metadata", "--no-deps", "--format-version", "1", "--manifest-path"])
        .arg(crate_dir.join("Cargo.toml"))
        .output()
        .map_err(|e| fail(format!("cannot run cargo: {e}")))?;
    if !out.status.success() {
        return Err(fail(String::from_utf8_lossy(&out.stderr).into_owned()));
    }
    let meta: serde_json::Value =
        serde_json::from_slice(&out.stdout).map_err(|e| fail(format!("cargo metadata: {e}")))?;
    let want = crate_dir.join("Cargo.toml").canonicalize().map_err(io(crate_dir))?;
    let pkg = meta["packages"]
        .as_array()
        .into_iter()
        .flatten()
        .find(|p| p["manifest_path"].as_str().and_then(|m| Path::new(m).canonicalize().ok()).as_ref() == Some(&want))
        .ok_or_else(|| fail("no package in its Cargo.toml".into()))?;
    let field = |k: &str| pkg[k].as_str().map(str::to_string).ok_or_else(|| fail(format!("package has no {k}")));
    Ok((field("name")?, field("version")?))
}

/// `cargo` without the variables a calling cargo sets for its own build (a build script's
/// target, flags and jobserver), so a nested build is an ordinary one.
fn clean_cargo(cargo: &Path) -> Command {
    let mut cmd = Command::new(cargo);
    for (k, _) in std::env::vars_os() {
        let k = k.to_string_lossy().into_owned();
        let keep = k == "CARGO_HOME" || k == "CARGO_NET_OFFLINE" || k.starts_with("CARGO_REGISTRIES_");
        if (k.starts_with("CARGO_") && !keep)
            || matches!(
                k.as_str(),
                "RUSTFLAGS" | "RUSTC_WRAPPER" | "RUSTC_WORKSPACE_WRAPPER" | "RUSTDOCFLAGS" | "RUSTC"
            )
        {
            cmd.env_remove(&k);
        }
    }
    cmd
}

/// Builds the plugin crate in `crate_dir` for `wasm32-unknown-unknown` (release, its own
/// lock file, `target_dir`) and packs it into `out_dir`. With `locked`, the crate's lock file
/// must already pin every dependency (`cargo --locked`).
pub fn build(
    cargo: &Path,
    crate_dir: &Path,
    target_dir: &Path,
    out_dir: &Path,
    locked: bool,
) -> Result<Packed, PackError> {
    let fail = |message: String| PackError::Build { crate_dir: crate_dir.to_path_buf(), message };
    let crate_dir = &crate_dir.canonicalize().map_err(io(crate_dir))?;
    let target_dir = &std::path::absolute(target_dir).map_err(io(target_dir))?;
    let (name, version) = package_of(cargo, crate_dir)?;
    let mut cmd = clean_cargo(cargo);
    // From the crate's folder, so its `.cargo/config.toml` (target features) applies.
    cmd.current_dir(crate_dir);
    cmd.args(["build", "--release", "--target", "wasm32-unknown-unknown", "--manifest-path"])
        .arg(crate_dir.join("Cargo.toml"));
    if locked {
        cmd.arg("--locked");
    }
    let status =
        cmd.arg("--target-dir").arg(target_dir).status().map_err(|e| fail(format!("cannot run cargo: {e}")))?;
    if !status.success() {
        return Err(fail(format!(
            "cargo build failed ({status}); if it says the target is missing, run `rustup target add wasm32-unknown-unknown`"
        )));
    }
    let core = target_dir.join("wasm32-unknown-unknown/release").join(format!("{}.wasm", name.replace('-', "_")));
    pack(&core, &name, &version, out_dir)
}
