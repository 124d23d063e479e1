//! The plugin host: third-party node kinds as WebAssembly components, run sandboxed.
//!
//! Loading a plugin ([`Host::load`]) reads its manifest, checks the component's SHA-256
//! against it before anything is compiled, compiles the component (or takes the compiled
//! form from the cache), refuses a component that imports anything (no WASI: no files,
//! network, clock or environment) or exports another interface version, pre-instantiates
//! it and asks it to describe itself. Its node kinds become [`PluginNode`]s, which
//! implement the engine's `Node` trait like every built-in kind, so recipes type-check
//! them the same way.
//!
//! Every call runs in a fresh store from the pre-instantiated component (an instance that
//! trapped is never reused), with a memory cap, a fuel bound on the work (deterministic:
//! the same call stops at the same point on any machine) and a bound on the numbers it
//! returns; the limits are the manifest's requests clamped to the host's [`Policy`].

mod lend;
mod node;
mod v0_1_0;
mod v0_2_0;

pub use node::PluginNode;
pub use spindlelab_plugin_pack::{self as pack, Manifest, RequestedLimits};

use spindlelab_plugin_pack::{INTERFACE_VERSIONS, PackError, sha256_hex};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use wasmtime::component::{Component, Linker, types::ComponentItem};
use wasmtime::{Config, Engine};

/// The interface versions this host runs.
pub const SUPPORTED_INTERFACES: &[&str] = &["0.1.0", "0.2.0"];

/// Largest component file read, bytes.
pub const MAX_COMPONENT_BYTES: u64 = 64 << 20;

/// The host's bounds on what a plugin may use per call.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Policy {
    /// Memory per call when the manifest asks for none, bytes.
    pub memory_default: u64,
    /// Most memory per call a manifest may ask for, bytes.
    pub memory_max: u64,
    /// Fuel per call when the manifest asks for none (about one unit per instruction).
    pub fuel_default: u64,
    pub fuel_max: u64,
    /// Numbers in all outputs of one call when the manifest asks for none.
    pub output_default: u64,
    pub output_max: u64,
}

impl Default for Policy {
    /// 256 MiB (at most 1 GiB), 10¹⁰ fuel (a few seconds; at most 10¹¹), 16 Mi numbers out
    /// (at most 64 Mi).
    fn default() -> Self {
        Policy {
            memory_default: 256 << 20,
            memory_max: 1 << 30,
            fuel_default: 10_000_000_000,
            fuel_max: 100_000_000_000,
            output_default: 16 << 20,
            output_max: 64 << 20,
        }
    }
}

/// The limits one plugin runs under: its manifest's requests clamped to the policy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    pub memory: u64,
    pub fuel: u64,
    pub output_values: u64,
}

impl Policy {
    pub fn limits(&self, requested: &RequestedLimits) -> Limits {
        Limits {
            memory: requested
                .memory_mib
                .map_or(self.memory_default, |m| m.saturating_mul(1 << 20).min(self.memory_max)),
            fuel: requested.fuel.map_or(self.fuel_default, |f| f.min(self.fuel_max)),
            output_values: requested.output_values.map_or(self.output_default, |n| n.min(self.output_max)),
        }
    }
}

/// Why a plugin could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error(transparent)]
    Pack(#[from] PackError),
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}: the component is {size} bytes; a plugin is at most {MAX_COMPONENT_BYTES} bytes")]
    TooLarge { path: PathBuf, size: u64 },
    #[error(
        "{path}: SHA-256 is {actual} but the manifest says {expected}; the file was changed or damaged after it was \
         packed: rebuild it with `spindlelab plugin build`, or fix the manifest if you trust the file"
    )]
    HashMismatch { path: PathBuf, expected: String, actual: String },
    #[error("plugin `{id}`: {expected} was asked for, but its {what} is {actual}")]
    Pinned { id: String, what: &'static str, expected: String, actual: String },
    #[error(
        "plugin `{id}` {version} is built for interface spindlelab:plugin@{interface}; this host runs {}: rebuild it \
         against a supported SDK",
        SUPPORTED_INTERFACES.join(", ")
    )]
    Interface { id: String, version: String, interface: String },
    #[error("{path}: not a valid WebAssembly component: {message}")]
    Invalid { path: PathBuf, message: String },
    #[error(
        "plugin `{id}` imports `{import}`; a plugin may import nothing (no WASI: files, network, clock, environment): \
         build it for wasm32-unknown-unknown with the spindlelab SDK"
    )]
    Imports { id: String, import: String },
    #[error("plugin `{id}` does not export `spindlelab:plugin/node@{interface}`, which its manifest names{found}")]
    NoExport { id: String, interface: String, found: String },
    #[error("plugin `{id}`: describing itself failed: {message}")]
    Describe { id: String, message: String },
    #[error("plugin `{id}`: {message}")]
    BadDescription { id: String, message: String },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> LoadError + '_ {
    move |source| LoadError::Io { path: path.to_path_buf(), source }
}

/// Instances that may run at once in one host (the slots of its instance pool); a call
/// beyond them waits for a slot.
pub const CONCURRENT_CALLS: u32 = 32;

/// Bytes of a slot's linear memory kept mapped between calls (reset, not returned to the
/// system) when the kernel reports which pages a call touched (no-op call 21.8 → 12.0 µs, a
/// 65,536-sample spectrum 6.0 → 4.2 ms). Guard pages stay: explicit bounds checks instead
/// made the no-op call faster still (8.4 µs) but computing calls 5–8 % slower.
const KEEP_RESIDENT: usize = 8 << 20;
/// Without that report every kept byte is reset by `memset` per call: keep little.
const KEEP_RESIDENT_MEMSET: usize = 128 << 10;

/// The wasmtime engine with the sandbox's settings, and where compiled components are cached.
pub struct Host {
    engine: Engine,
    policy: Policy,
    cache_dir: Option<PathBuf>,
    slots: Arc<node::Slots>,
}

/// The address space this process may map (`ulimit -v`, in bytes), if it is limited.
fn address_space_limit() -> Option<u64> {
    #[cfg(unix)]
    {
        let mut limit = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
        // SAFETY: getrlimit writes the one struct it is given.
        let ok = unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut limit) } == 0;
        if ok && limit.rlim_cur != libc::RLIM_INFINITY {
            return Some(limit.rlim_cur);
        }
    }
    None
}

/// What to load and what to expect of it.
#[derive(Debug, Clone, Default)]
pub struct Expect {
    /// The version the recipe pins, if any.
    pub version: Option<String>,
    /// The SHA-256 the recipe pins, if any.
    pub sha256: Option<String>,
}

/// A loaded plugin: its manifest, the limits it runs under and its node kinds.
pub struct Plugin {
    pub manifest: Manifest,
    pub manifest_path: PathBuf,
    pub limits: Limits,
    pub nodes: Vec<Arc<PluginNode>>,
    /// Whether the compiled component came from the cache.
    pub from_cache: bool,
}

impl Host {
    /// A host with `policy`, caching compiled components in `cache_dir` (none: compile
    /// every time).
    pub fn new(policy: Policy, cache_dir: Option<PathBuf>) -> Result<Host, String> {
        let mut config = Config::new();
        config.consume_fuel(true);
        config.cranelift_opt_level(wasmtime::OptLevel::Speed);
        // Cranelift inlines small functions into their callers: a plugin's calls into the
        // math functions of its standard library (compiled apart from it, so never inlined by
        // its own compiler) then lose their call overhead and the fuel accounting at each
        // function entry. About 10 % off a call of the example spectrum; compiling takes about
        // twice as long and five times the memory (the example: 1.9 s, 520 MB peak), once per
        // plugin version (the compiled form is cached).
        config.compiler_inlining(wasmtime::Inlining::Yes);
        config.wasm_component_model(true);
        let engine = match address_space_limit() {
            None => Engine::new(&Self::pooled(config.clone(), &policy)),
            Some(_) => Err(wasmtime::Error::msg("the address space is limited")),
        }
        .or_else(|_| {
            // Under `ulimit -v` a pool's reservations (hundreds of GiB of address space, never
            // touched) cannot be made: each call's memory is then mapped when it is made, as
            // large as it grows, with explicit bounds checks.
            config.memory_reservation(0).memory_guard_size(0).memory_reservation_for_growth(1 << 20);
            config.allocation_strategy(wasmtime::InstanceAllocationStrategy::OnDemand);
            Engine::new(&config)
        })
        .map_err(|e| match address_space_limit() {
            Some(limit) => format!(
                "cannot start the WebAssembly engine under an address-space limit of {} MiB (`ulimit -v`): {e}; raise the limit, or run without plugins",
                limit >> 20
            ),
            None => format!("cannot start the WebAssembly engine: {e}"),
        })?;
        Ok(Host { engine, policy, cache_dir, slots: Arc::new(node::Slots::new(CONCURRENT_CALLS as usize)) })
    }

    /// `config` with a pool of instance slots: the layout when the address space is not limited.
    fn pooled(mut config: Config, policy: &Policy) -> Config {
        // A pool of instance slots, each with room for the largest memory the policy allows:
        // a fresh instance per call then costs microseconds (its memory slot is reset, not
        // mapped anew). The limiter still caps each call at its own plugin's limit.
        let keep_resident = if wasmtime::PoolingAllocationConfig::is_pagemap_scan_available() {
            KEEP_RESIDENT
        } else {
            KEEP_RESIDENT_MEMSET
        };
        let mut pool = wasmtime::PoolingAllocationConfig::new();
        pool.total_component_instances(CONCURRENT_CALLS)
            .total_core_instances(4 * CONCURRENT_CALLS)
            .total_memories(4 * CONCURRENT_CALLS)
            .total_tables(4 * CONCURRENT_CALLS)
            .max_memory_size(policy.memory_max.max(policy.memory_default) as usize)
            // Reset a slot's pages in place up to KEEP_RESIDENT and return the rest to the
            // system in batches; where the kernel can say which pages a call touched
            // (PAGEMAP_SCAN, Linux 6.7), only those are reset, and they stay mapped: a call
            // then pays neither the page faults of fresh memory nor a reset of untouched pages.
            .linear_memory_keep_resident(keep_resident)
            .table_keep_resident(16 << 10)
            .pagemap_scan(wasmtime::Enabled::Auto)
            .decommit_batch_size(16);
        config.allocation_strategy(wasmtime::InstanceAllocationStrategy::Pooling(pool));
        config
    }

    pub fn policy(&self) -> &Policy {
        &self.policy
    }

    /// Loads the plugin whose manifest is at `manifest_path` (checks in the module docs).
    pub fn load(&self, manifest_path: &Path, expect: &Expect) -> Result<Plugin, LoadError> {
        let manifest = Manifest::read(manifest_path)?;
        check_pins(&manifest, &Expect { version: expect.version.clone(), sha256: None })?;
        if !SUPPORTED_INTERFACES.contains(&manifest.interface.as_str()) {
            return Err(LoadError::Interface {
                id: manifest.id,
                version: manifest.version,
                interface: manifest.interface,
            });
        }
        debug_assert!(INTERFACE_VERSIONS.iter().all(|v| SUPPORTED_INTERFACES.contains(v)));
        let wasm_path = manifest.wasm_path(manifest_path);
        let bytes = read_capped(&wasm_path)?;
        let actual = sha256_hex(&bytes);
        if !actual.eq_ignore_ascii_case(&manifest.sha256) {
            return Err(LoadError::HashMismatch { path: wasm_path, expected: manifest.sha256, actual });
        }
        check_pins(&manifest, expect)?;
        let (component, from_cache) = self.compile(&bytes, &actual, &wasm_path)?;
        self.check_world(&component, &manifest)?;
        let limits = self.policy.limits(&manifest.limits);
        let linker: Linker<node::State> = Linker::new(&self.engine);
        let pre = linker
            .instantiate_pre(&component)
            .map_err(|e| LoadError::Invalid { path: wasm_path.clone(), message: format!("{e:#}") })?;
        let pre = node::Pre::new(pre, &manifest.interface)
            .map_err(|e| LoadError::Invalid { path: wasm_path.clone(), message: format!("{e:#}") })?;
        let runtime = Arc::new(node::Runtime {
            engine: self.engine.clone(),
            slots: self.slots.clone(),
            pre,
            limits,
            id: manifest.id.clone(),
            version: manifest.version.clone(),
            sha256: actual,
        });
        let nodes = node::describe(&runtime, &manifest)?;
        Ok(Plugin { manifest, manifest_path: manifest_path.to_path_buf(), limits, nodes, from_cache })
    }

    /// The component compiled from `bytes`, from the cache when it holds it.
    fn compile(&self, bytes: &[u8], sha: &str, path: &Path) -> Result<(Component, bool), LoadError> {
        let cached = self.cache_dir.as_ref().map(|dir| {
            use std::hash::{Hash, Hasher};
            let mut h = std::collections::hash_map::DefaultHasher::new();
            self.engine.precompile_compatibility_hash().hash(&mut h);
            dir.join(format!("{sha}-{:016x}.cwasm", h.finish()))
        });
        if let Some(file) = &cached
            && let Ok(data) = spindlelab_engine::exec::files::read_regular_via_links(file, 4 * MAX_COMPONENT_BYTES)
            && data.len() > 64
        {
            // The file holds the checksum of the compiled bytes, then the bytes: a damaged or
            // truncated entry is recompiled, never loaded.
            let (sum, body) = data.split_at(64);
            if sum == cache_checksum(body).as_bytes() {
                // SAFETY: the bytes are what `Component::serialize` wrote into the user's own
                // cache folder for this engine (the name carries the engine's compatibility
                // hash) and their checksum matches.
                if let Ok(c) = unsafe { Component::deserialize(&self.engine, body) } {
                    return Ok((c, true));
                }
            }
        }
        let component = Component::new(&self.engine, bytes)
            .map_err(|e| LoadError::Invalid { path: path.to_path_buf(), message: format!("{e:#}") })?;
        if let Some(file) = &cached
            && let Ok(body) = component.serialize()
        {
            // Best effort: a cache that cannot be written only costs the next start its time.
            let _ = write_atomically(file, &body);
        }
        Ok((component, false))
    }

    /// Refuses imports and other interface versions.
    fn check_world(&self, component: &Component, manifest: &Manifest) -> Result<(), LoadError> {
        let ty = component.component_type();
        // The one import allowed: the interface's own type definitions (no functions).
        let own_types = |name: &str, item: &ComponentItem| {
            name.strip_prefix("spindlelab:plugin/types@").is_some_and(|v| SUPPORTED_INTERFACES.contains(&v))
                && match item {
                    ComponentItem::ComponentInstance(i) => {
                        i.exports(&self.engine).all(|(_, e)| matches!(e.ty, ComponentItem::Type(_)))
                    }
                    _ => false,
                }
        };
        if let Some((name, _)) = ty.imports(&self.engine).find(|(name, item)| !own_types(name, &item.ty)) {
            return Err(LoadError::Imports { id: manifest.id.clone(), import: name.to_string() });
        }
        let mut others = Vec::new();
        let mut found = false;
        for (name, item) in ty.exports(&self.engine) {
            if let Some(version) = name.strip_prefix("spindlelab:plugin/node@") {
                if version == manifest.interface && matches!(item.ty, ComponentItem::ComponentInstance(_)) {
                    found = true;
                } else {
                    others.push(version.to_string());
                }
            }
        }
        if found {
            return Ok(());
        }
        if let Some(v) = others.first().filter(|v| !SUPPORTED_INTERFACES.contains(&v.as_str())) {
            return Err(LoadError::Interface {
                id: manifest.id.clone(),
                version: manifest.version.clone(),
                interface: v.clone(),
            });
        }
        Err(LoadError::NoExport {
            id: manifest.id.clone(),
            interface: manifest.interface.clone(),
            found: others
                .first()
                .map(|v| format!(" (it exports `node@{v}`: repack it with `spindlelab plugin build`)"))
                .unwrap_or_default(),
        })
    }
}

/// Whether a manifest (whose hash has been checked against its component) meets the version
/// and SHA-256 a recipe pins.
pub fn check_pins(manifest: &Manifest, expect: &Expect) -> Result<(), LoadError> {
    if let Some(v) = &expect.version
        && v != &manifest.version
    {
        return Err(LoadError::Pinned {
            id: manifest.id.clone(),
            what: "version",
            expected: format!("version {v}"),
            actual: manifest.version.clone(),
        });
    }
    if let Some(pin) = &expect.sha256
        && !pin.eq_ignore_ascii_case(&manifest.sha256)
    {
        return Err(LoadError::Pinned {
            id: manifest.id.clone(),
            what: "SHA-256",
            expected: format!("SHA-256 {pin}"),
            actual: manifest.sha256.to_ascii_lowercase(),
        });
    }
    Ok(())
}

/// Reads a component through the cap; a pipe or a device named as one is refused, never
/// waited on.
fn read_capped(path: &Path) -> Result<Vec<u8>, LoadError> {
    use spindlelab_engine::exec::files::{Refused, read_regular_via_links};
    match read_regular_via_links(path, MAX_COMPONENT_BYTES) {
        Ok(bytes) => Ok(bytes),
        Err(Refused::TooLarge(_)) => Err(LoadError::TooLarge {
            path: path.to_path_buf(),
            size: std::fs::metadata(path).map_or(MAX_COMPONENT_BYTES + 1, |m| m.len()),
        }),
        Err(Refused::Io(e)) => Err(io(path)(e)),
        Err(e) => Err(io(path)(std::io::Error::new(std::io::ErrorKind::InvalidInput, e.to_string()))),
    }
}

/// The checksum a cache entry carries of its compiled bytes: BLAKE3, in hex. It guards
/// against damage, not against whoever can write the user's own cache folder, and runs at
/// several times SHA-256's speed: most of a cached plugin's start was hashing its 3 MB.
fn cache_checksum(body: &[u8]) -> String {
    blake3::hash(body).to_hex().to_string()
}

fn write_atomically(file: &Path, body: &[u8]) -> std::io::Result<()> {
    let dir = file.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)?;
    let mut data = cache_checksum(body).into_bytes();
    data.extend_from_slice(body);
    let tmp =
        dir.join(format!(".{}.{}.tmp", file.file_name().and_then(|n| n.to_str()).unwrap_or("c"), std::process::id()));
    std::fs::write(&tmp, &data)?;
    std::fs::rename(&tmp, file)
}

/// Where compiled plugins are cached for this user: `$SPINDLELAB_PLUGIN_CACHE`, else
/// `$XDG_CACHE_HOME/spindlelab/plugins`, else `~/.cache/spindlelab/plugins`.
pub fn default_cache_dir() -> Option<PathBuf> {
    if let Some(d) = std::env::var_os("SPINDLELAB_PLUGIN_CACHE") {
        return Some(PathBuf::from(d));
    }
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("spindlelab/plugins"))
}

/// The folders searched for a plugin named by id: `$SPINDLELAB_PLUGIN_PATH` (separated like
/// `PATH`), then `$XDG_DATA_HOME/spindlelab/plugins` (else `~/.local/share/spindlelab/plugins`).
pub fn default_search_path() -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> =
        std::env::var_os("SPINDLELAB_PLUGIN_PATH").map(|p| std::env::split_paths(&p).collect()).unwrap_or_default();
    let data = std::env::var_os("XDG_DATA_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/share")));
    if let Some(d) = data {
        dirs.push(d.join("spindlelab/plugins"));
    }
    dirs
}

/// The manifest of plugin `id` in the first of `dirs` that holds `ID.plugin.json`.
pub fn find(id: &str, dirs: &[PathBuf]) -> Option<PathBuf> {
    dirs.iter().map(|d| d.join(format!("{id}{}", pack::MANIFEST_SUFFIX))).find(|p| p.is_file())
}
