//! Plugins for a run: the `plugins:` of a recipe and the `--plugin` of the command line,
//! loaded by the plugin host into the registry before the recipe's steps are resolved.

use crate::engine::diag::{Diagnostics, SourceFile};
use crate::engine::model::{PluginRef, plugin_refs};
use crate::engine::node::{Node, Registry};
use crate::engine::{self, CompileError, Compiled, syntax};
use spindlelab_plugin_host::{self as host, Expect, Host, Plugin, Policy};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The plugin host of one command, created when a first plugin is needed, and what it loaded.
pub struct Plugins {
    host: Option<Host>,
    policy: Policy,
    cache_dir: Option<PathBuf>,
    /// Folders searched for a plugin named by id, in order.
    pub search: Vec<PathBuf>,
    /// Manifests to load whatever the recipe says.
    pub always: Vec<PathBuf>,
    /// Each plugin loaded, by its manifest's path: a later recipe of the same command (a
    /// fit, a test over many recipes) registers it again without loading it again.
    loaded: HashMap<PathBuf, Arc<Plugin>>,
}

/// What `spindlelab plugin build` and a missing plugin's message suggest.
pub const BUILD_HINT: &str =
    "build it with `spindlelab plugin build <its crate folder>`, or name its manifest with `--plugin FILE`";

impl Plugins {
    /// Plugins from `--plugin` arguments (manifests are loaded, folders searched first) and
    /// the user's plugin folders.
    pub fn new(args: &[PathBuf]) -> Plugins {
        let (dirs, files): (Vec<PathBuf>, Vec<PathBuf>) = args.iter().cloned().partition(|p| p.is_dir());
        let mut search = dirs;
        search.extend(host::default_search_path());
        Plugins {
            host: None,
            policy: Policy::default(),
            cache_dir: host::default_cache_dir(),
            search,
            always: files,
            loaded: HashMap::new(),
        }
    }

    /// Only these folders, the given policy and cache: for tests and benchmarks.
    pub fn with(search: Vec<PathBuf>, policy: Policy, cache_dir: Option<PathBuf>) -> Plugins {
        Plugins { host: None, policy, cache_dir, search, always: Vec::new(), loaded: HashMap::new() }
    }

    fn host(&mut self) -> Result<&Host, String> {
        if self.host.is_none() {
            self.host = Some(Host::new(self.policy, self.cache_dir.clone())?);
        }
        Ok(self.host.as_ref().expect("just made"))
    }

    /// Loads the plugin at `manifest` (once per command) and registers its kinds in
    /// `registry`. Another build of a plugin whose kinds are registered already is refused.
    pub fn load(&mut self, manifest: &Path, expect: &Expect, registry: &mut Registry) -> Result<Arc<Plugin>, String> {
        let plugin = match self.loaded.get(manifest) {
            Some(p) => {
                host::check_pins(&p.manifest, expect).map_err(|e| e.to_string())?;
                p.clone()
            }
            None => {
                let p = Arc::new(self.host()?.load(manifest, expect).map_err(|e| e.to_string())?);
                self.loaded.insert(manifest.to_path_buf(), p.clone());
                p
            }
        };
        for node in &plugin.nodes {
            let kind = node.spec().kind;
            if let Some(present) = registry.get(kind) {
                if present.code_digest() == Some(plugin.manifest.sha256.as_str()) {
                    continue;
                }
                return Err(match present.code_digest() {
                    Some(_) => format!(
                        "plugin `{}` ({}): node kind `{kind}` is provided by another plugin build already loaded; name one",
                        plugin.manifest.id,
                        manifest.display()
                    ),
                    None => format!(
                        "plugin `{}`: node kind `{kind}` is built in; a plugin cannot replace it",
                        plugin.manifest.id
                    ),
                });
            }
            let node: Arc<dyn Node> = node.clone();
            registry.try_register(node).map_err(|e| format!("plugin `{}`: {e}", plugin.manifest.id))?;
        }
        Ok(plugin)
    }

    /// Loads the `--plugin` manifests.
    pub fn load_always(&mut self, registry: &mut Registry) -> Result<(), String> {
        for m in self.always.clone() {
            self.load(&m, &Expect::default(), registry)?;
        }
        Ok(())
    }

    /// Loads what a recipe's `plugins:` names, each problem a diagnostic at its entry.
    pub fn load_refs(&mut self, refs: &[PluginRef], registry: &mut Registry, diags: &mut Diagnostics) {
        for r in refs {
            let manifest = match (&r.path, &r.id) {
                (Some(p), _) => Some(p.clone()),
                (None, Some(id)) => host::find(id, &self.search),
                (None, None) => None,
            };
            let Some(manifest) = manifest else {
                let places: Vec<String> = self.search.iter().map(|d| d.display().to_string()).collect();
                diags.error_help(
                    Some(&r.span),
                    format!(
                        "plugin `{}` is not in the plugin folders ({})",
                        r.name(),
                        if places.is_empty() { "none".into() } else { places.join(", ") }
                    ),
                    BUILD_HINT,
                );
                continue;
            };
            let expect = Expect { version: r.version.clone(), sha256: r.sha256.clone() };
            match self.load(&manifest, &expect, registry) {
                Ok(p) if r.id.as_ref().is_some_and(|id| *id != p.manifest.id) => {
                    diags.error(
                        Some(&r.span),
                        format!("{} holds plugin `{}`, not `{}`", manifest.display(), p.manifest.id, r.name()),
                    );
                }
                Ok(_) => {}
                Err(e) => diags.error(Some(&r.span), e),
            }
        }
    }
}

/// Loads a recipe file, its plugins into `registry`, and compiles it (every problem at once).
pub fn compile_file(
    path: &Path,
    set: &[(String, String)],
    registry: &mut Registry,
    plugins: &mut Plugins,
) -> Result<Compiled, CompileError> {
    compile_file_within(path, set, registry, plugins, engine::Reach::Anywhere)
}

/// [`compile_file`] reading only the files `reach` allows (`--confine`).
pub fn compile_file_within(
    path: &Path,
    set: &[(String, String)],
    registry: &mut Registry,
    plugins: &mut Plugins,
    reach: engine::Reach,
) -> Result<Compiled, CompileError> {
    let mut diags = Diagnostics::new();
    let loaded = syntax::load_file(path, &mut diags);
    let sources: Vec<SourceFile> = loaded.iter().flat_map(|l| l.sources()).collect();
    let Some(raw) = loaded.and_then(|l| l.raw) else {
        diags.sort();
        return Err(CompileError { diagnostics: diags, sources });
    };
    if let Err(e) = plugins.load_always(registry) {
        diags.error(None, e);
    }
    let refs = plugin_refs(&raw, &mut diags);
    plugins.load_refs(&refs, registry, &mut diags);
    engine::compile_raw_within(path, raw, set, sources, registry, diags, reach)
}

impl Plugins {
    /// Every manifest in the search folders, in folder order then by name.
    pub fn manifests(&self) -> Vec<PathBuf> {
        let mut all = Vec::new();
        for dir in &self.search {
            let Ok(entries) = std::fs::read_dir(dir) else { continue };
            let mut found: Vec<PathBuf> = entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.to_string_lossy().ends_with(host::pack::MANIFEST_SUFFIX))
                .collect();
            found.sort();
            all.extend(found);
        }
        all
    }

    /// Loads every plugin on the search path (an id found twice: the first), returning the
    /// plugins loaded and the problems of those that would not load.
    pub fn load_search_path(&mut self, registry: &mut Registry) -> (Vec<Arc<Plugin>>, Vec<(PathBuf, String)>) {
        let (mut ok, mut failed) = (Vec::new(), Vec::new());
        let mut ids = std::collections::HashSet::new();
        for m in self.manifests() {
            match self.load(&m, &Expect::default(), registry) {
                Ok(p) if ids.insert(p.manifest.id.clone()) => ok.push(p),
                Ok(_) => {}
                Err(e) => failed.push((m, e)),
            }
        }
        (ok, failed)
    }
}

/// The SDK and the interface, as `spindlelab plugin new` writes them beside a new plugin.
mod template {
    pub const SDK_LIB: &str = include_str!("../../plugins/guest/sdk/src/lib.rs");
    pub const SDK_TRIG: &str = include_str!("../../plugins/guest/sdk/src/trig.rs");
    pub const WIT: &str = include_str!("../../plugins/wit/since_v0.2.0/plugin.wit");
    pub const SDK_WIT_PATH: &str = "../../wit/since_v0.2.0";
    pub const WIT_0_1_0: &str = include_str!("../../plugins/wit/since_v0.1.0/plugin.wit");
    pub const SDK_WIT_PATH_0_1_0: &str = "../../wit/since_v0.1.0";
    /// The build settings every plugin crate wants: WebAssembly SIMD, 8 MiB of initial memory,
    /// vectorised loops unrolled for the host's work bound.
    pub const CARGO_CONFIG: &str = include_str!("../../plugins/guest/.cargo/config.toml");
}

/// Creates a plugin crate named `name` in `dir`: one node kind, the SDK and the interface
/// beside it, so it builds with nothing but a Rust toolchain and the wasm32 target.
pub fn new_plugin(name: &str, dir: &Path) -> Result<Vec<PathBuf>, String> {
    if name.is_empty() || !name.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-') {
        return Err(format!("`{name}` is not a plugin id: use lowercase letters, digits and `-`"));
    }
    if dir.exists() && std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?.next().is_some() {
        return Err(format!("{} exists and is not empty; choose another folder with --dir", dir.display()));
    }
    let module = name.replace('-', "_");
    let sdk_lib =
        template::SDK_LIB.replace(template::SDK_WIT_PATH, "wit").replace(template::SDK_WIT_PATH_0_1_0, "wit-0.1.0");
    let files: Vec<(&str, String)> = vec![
        (
            "Cargo.toml",
            format!(
                "[package]\nname = \"{name}\"\nversion = \"0.1.0\"\nedition = \"2024\"\npublish = false\n\n[lib]\ncrate-type = [\"cdylib\"]\n\n\
                 [dependencies]\nspindlelab-plugin-sdk = {{ path = \"sdk\" }}\n\n[workspace]\n\n[profile.release]\nopt-level = 3\nlto = true\n\
                 codegen-units = 1\npanic = \"abort\"\nstrip = true\n"
            ),
        ),
        (
            "src/lib.rs",
            format!(
                "//! Plugin `{name}`: node kinds for spindlelab recipes.\n\nuse spindlelab_plugin_sdk::*;\n\n\
                 /// Multiplies every value of an FRF by `gain`.\nfn scale(call: &Call) -> Result<Outputs, String> {{\n    \
                 let frf = call.frf(\"frf\")?;\n    let gain = call.number(\"gain\")?;\n    \
                 let re = frf.re.iter().map(|v| v * gain).collect();\n    let im = frf.im.iter().map(|v| v * gain).collect();\n    \
                 Ok(Outputs::new().frf(\"frf\", Frf {{ re, im, ..frf.clone() }}))\n}}\n\n\
                 plugin! {{\n    NodeKind::new(\"{module}.scale\", \"Multiplies an FRF by a gain.\", scale)\n        \
                 .input(Port::new(\"frf\", PortType::Frf, \"the FRF\"))\n        \
                 .output(Port::new(\"frf\", PortType::Frf, \"gain × FRF\"))\n        \
                 .param(Param::quantity(\"gain\", \"\", \"the factor\").default(\"1\")),\n}}\n"
            ),
        ),
        (
            "sdk/Cargo.toml",
            "[package]\nname = \"spindlelab-plugin-sdk\"\nversion = \"0.1.0\"\nedition = \"2024\"\npublish = false\n\n[dependencies]\n\
             wit-bindgen = { version = \"0.61.1\", default-features = false, features = [\"macros\", \"realloc\", \"std\"] }\n\
             dlmalloc = { version = \"0.2.14\", default-features = false, optional = true }\n\
             libm = { version = \"0.2.16\", optional = true }\n\n\
             [features]\ndefault = [\"allocator\", \"paired-trig\"]\n# The SDK's global allocator (it starts in the initial memory); turn it off to set another.\n\
             allocator = [\"dep:dlmalloc\"]\n# `sin` and `cos` that share one argument reduction between an angle's cosine and sine.\n\
             paired-trig = [\"dep:libm\"]\n# Build against interface 0.1.0 (no effects), for hosts that run nothing newer.\ninterface-0-1-0 = []\n"
                .into(),
        ),
        ("sdk/src/lib.rs", sdk_lib),
        ("sdk/src/trig.rs", template::SDK_TRIG.into()),
        ("sdk/wit/plugin.wit", template::WIT.into()),
        ("sdk/wit-0.1.0/plugin.wit", template::WIT_0_1_0.into()),
        (".gitignore", "/target\n".into()),
        (".cargo/config.toml", template::CARGO_CONFIG.into()),
    ];
    let mut written = Vec::new();
    for (rel, text) in files {
        let path = dir.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| format!("{}: {e}", parent.display()))?;
        }
        std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
        written.push(path);
    }
    Ok(written)
}

/// Where `spindlelab plugin build` puts a plugin by default: the first user plugin folder.
pub fn user_plugin_dir() -> Option<PathBuf> {
    host::default_search_path().pop()
}
