//! The recipe's `plugins:` list: which plugins its steps need, by file or by id.
//!
//! ```yaml
//! plugins:
//!   - chatter-indicator                       # by id, found on the plugin search path
//!   - { id: tip-mass, version: 0.1.0 }        # pinned to a version
//!   - { path: vendor/fit.plugin.json, sha256: 3f5c… }   # a manifest beside the recipe, pinned to a hash
//! ```
//!
//! The engine only reads the list; loading is the plugin host's, before the steps are
//! resolved, so plugin kinds type-check like built-in ones.

use crate::diag::{Diagnostics, Span};
use crate::syntax::{Raw, RawKind};
use std::path::PathBuf;

const KEYS: &[&str] = &["id", "path", "version", "sha256"];

/// One entry of `plugins:`.
#[derive(Debug, Clone, PartialEq)]
pub struct PluginRef {
    /// A manifest named by path (relative paths are taken from the recipe's folder).
    pub path: Option<PathBuf>,
    /// A plugin named by id, found on the search path.
    pub id: Option<String>,
    pub version: Option<String>,
    pub sha256: Option<String>,
    pub span: Span,
}

impl PluginRef {
    /// How the entry names its plugin, for messages.
    pub fn name(&self) -> String {
        match (&self.id, &self.path) {
            (Some(id), _) => id.clone(),
            (None, Some(p)) => p.display().to_string(),
            (None, None) => "?".into(),
        }
    }
}

/// Reads `plugins:` from a loaded recipe, reporting a malformed entry at its place.
pub fn plugin_refs(raw: &Raw, diags: &mut Diagnostics) -> Vec<PluginRef> {
    let Some(list) = raw.get("plugins") else { return Vec::new() };
    let base = std::path::Path::new(&*raw.span.file).parent().map(std::path::Path::to_path_buf).unwrap_or_default();
    let RawKind::Seq(items) = &list.kind else {
        diags.error_help(
            Some(&list.span),
            format!("`plugins` must be a list, found {}", list.describe()),
            "write `plugins: [chatter-indicator, { path: vendor/x.plugin.json }]`",
        );
        return Vec::new();
    };
    let mut refs = Vec::new();
    for item in items {
        let mut r = PluginRef { path: None, id: None, version: None, sha256: None, span: item.span.clone() };
        match &item.kind {
            RawKind::Str(id) => r.id = Some(id.clone()),
            RawKind::Map(entries) => {
                for (k, v) in entries {
                    let Some(text) = v.scalar_text() else {
                        diags.error(
                            Some(&v.span),
                            format!("`{}` of a plugin must be text, found {}", k.name, v.describe()),
                        );
                        continue;
                    };
                    // YAML reads a hash of digits or a version like `1.0` as a number, and
                    // its text is then lost: ask for quotes instead of comparing the number.
                    if matches!(k.name.as_str(), "sha256" | "version") && !matches!(v.kind, RawKind::Str(_)) {
                        diags.error_help(
                            Some(&v.span),
                            format!("`{}` of a plugin is read as the number {text}, not as text", k.name),
                            format!("quote it: `{}: \"…\"`", k.name),
                        );
                        continue;
                    }
                    if k.name == "sha256" && !(text.len() == 64 && text.bytes().all(|b| b.is_ascii_hexdigit())) {
                        diags.error_help(
                            Some(&v.span),
                            format!(
                                "`sha256` of a plugin must be 64 hexadecimal digits, found {} characters",
                                text.chars().count()
                            ),
                            "copy the `sha256` of its manifest, or `spindlelab plugin list` shows it",
                        );
                        continue;
                    }
                    match k.name.as_str() {
                        "id" => r.id = Some(text),
                        "path" => r.path = Some(base.join(text)),
                        "version" => r.version = Some(text),
                        "sha256" => r.sha256 = Some(text),
                        other => {
                            let msg = format!("unknown key `{other}` in a plugin entry");
                            diags.error_help(Some(&k.span), msg, format!("known keys: {}", KEYS.join(", ")));
                        }
                    }
                }
                if r.id.is_some() == r.path.is_some() {
                    diags.error_help(
                        Some(&item.span),
                        "a plugin entry names its plugin by `id` or by `path`, not both or neither",
                        "write `{ id: tip-mass }` or `{ path: vendor/tip-mass.plugin.json }`",
                    );
                    continue;
                }
            }
            _ => {
                diags.error_help(
                    Some(&item.span),
                    format!("a plugin entry is an id or a mapping, found {}", item.describe()),
                    "write `- tip-mass` or `- { id: tip-mass, version: 0.1.0 }`",
                );
                continue;
            }
        }
        refs.push(r);
    }
    refs
}
