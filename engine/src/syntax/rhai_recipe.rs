//! Rhai recipes: a script that builds the same raw recipe a YAML file would, with loops and functions.
//!
//! The script runs at compile time in a sandbox: bounded operations, call depth, string,
//! array and map sizes; no file, network or module access; `print` and `debug` are muted.
//! Its result (an object map) becomes the raw tree, so caching keys on what it built.

use super::raw::{Key, Raw, RawKind};
use crate::diag::{Diagnostic, Diagnostics, SourceFile, Span};
use rhai::{Dynamic, Engine, EvalAltResult, Position};
use std::sync::Arc;

/// Resource limits for a Rhai recipe or a Rhai step expression.
#[derive(Debug, Clone)]
pub struct RhaiLimits {
    pub max_operations: u64,
    pub max_call_levels: usize,
    pub max_string_size: usize,
    pub max_array_size: usize,
    pub max_map_size: usize,
    pub max_expr_depth: usize,
}

impl Default for RhaiLimits {
    fn default() -> Self {
        RhaiLimits {
            max_operations: 5_000_000,
            max_call_levels: 64,
            max_string_size: 64 * 1024,
            max_array_size: 100_000,
            max_map_size: 10_000,
            max_expr_depth: 128,
        }
    }
}

/// A Rhai engine with the sandbox limits set, no module loading and muted output.
pub fn sandboxed_engine(limits: &RhaiLimits) -> Engine {
    let mut engine = Engine::new();
    engine.set_max_operations(limits.max_operations);
    engine.set_max_call_levels(limits.max_call_levels);
    engine.set_max_string_size(limits.max_string_size);
    engine.set_max_array_size(limits.max_array_size);
    engine.set_max_map_size(limits.max_map_size);
    engine.set_max_expr_depths(limits.max_expr_depth, limits.max_expr_depth);
    engine.set_module_resolver(rhai::module_resolvers::DummyModuleResolver::new());
    engine.disable_symbol("eval");
    engine.on_print(|_| {});
    engine.on_debug(|_, _, _| {});
    // `q(12.7, "mm")` writes the quantity text a YAML recipe would hold.
    engine.register_fn("q", |v: f64, unit: &str| format!("{} {unit}", fmt_num(v)));
    engine.register_fn("q", |v: i64, unit: &str| format!("{v} {unit}"));
    engine.register_fn("sweep", |a: f64, b: f64, step: f64, unit: &str| {
        format!("{}..{} step {} {unit}", fmt_num(a), fmt_num(b), fmt_num(step))
    });
    engine
}

fn fmt_num(v: f64) -> String {
    // Shortest text that reads back as the same number.
    format!("{v:?}")
}

fn position_span(file: &Arc<str>, pos: Position) -> Span {
    match (pos.line(), pos.position()) {
        (Some(line), col) => {
            Span { file: file.clone(), line: line as u32, column: col.unwrap_or(1) as u32, bytes: None }
        }
        _ => Span::file_only(file.clone()),
    }
}

/// Runs a `.rhai` recipe and converts the object map it returns into the raw tree.
pub fn load_rhai(file: &SourceFile, limits: &RhaiLimits, diags: &mut Diagnostics) -> Option<Raw> {
    let engine = sandboxed_engine(limits);
    let result: Result<Dynamic, Box<EvalAltResult>> = engine.eval(&file.text);
    match result {
        Ok(value) => {
            let root = Span::file_only(file.path.clone());
            if !value.is_map() {
                diags.push(
                    Diagnostic::error(
                        Some(root),
                        format!("a Rhai recipe must end with an object map, found {}", value.type_name()),
                    )
                    .with_help("end the script with `#{ spindlelab: 1, steps: #{ ... } }`"),
                );
                return None;
            }
            Some(to_raw(&file.path, "", value))
        }
        Err(e) => {
            let span = position_span(&file.path, e.position());
            let help = match *e {
                EvalAltResult::ErrorTooManyOperations(_) => {
                    "the script ran past its operation limit: a loop that never ends, or a sweep too large for a recipe"
                }
                EvalAltResult::ErrorStackOverflow(_) => "the script recursed too deep",
                EvalAltResult::ErrorDataTooLarge(..) => "a string, array or map in the script grew past its limit",
                EvalAltResult::ErrorModuleNotFound(..) => "Rhai recipes cannot import modules or read files",
                _ => "fix the script; it runs at compile time and must return the recipe as an object map",
            };
            let msg = e.to_string();
            let msg = match msg.rfind(" (line ") {
                Some(i) if msg.ends_with(')') => msg[..i].to_string(),
                _ => msg,
            };
            diags.push(Diagnostic::error(Some(span), format!("Rhai recipe failed: {msg}")).with_help(help));
            None
        }
    }
}

/// Converts a Rhai value into the raw tree. Values built by a script have no line, so
/// their span names the file and the key path is kept in the message context.
fn to_raw(file: &Arc<str>, path: &str, value: Dynamic) -> Raw {
    let span =
        Span::file_only(Arc::from(if path.is_empty() { file.to_string() } else { format!("{file} (at {path})") }));
    let kind = if value.is_unit() {
        RawKind::Null
    } else if let Some(b) = value.clone().try_cast::<bool>() {
        RawKind::Bool(b)
    } else if let Some(i) = value.clone().try_cast::<i64>() {
        RawKind::Int(i)
    } else if let Some(f) = value.clone().try_cast::<f64>() {
        RawKind::Float(f)
    } else if value.is_string() {
        RawKind::Str(value.into_string().unwrap_or_default())
    } else if value.is_array() {
        let arr = value.into_array().unwrap_or_default();
        RawKind::Seq(arr.into_iter().enumerate().map(|(i, v)| to_raw(file, &format!("{path}[{i}]"), v)).collect())
    } else if value.is_map() {
        let map = value.cast::<rhai::Map>();
        RawKind::Map(
            map.into_iter()
                .map(|(k, v)| {
                    let child = if path.is_empty() { k.to_string() } else { format!("{path}.{k}") };
                    let raw = to_raw(file, &child, v);
                    (Key { name: k.to_string(), span: raw.span.clone() }, raw)
                })
                .collect(),
        )
    } else {
        RawKind::Str(value.to_string())
    };
    Raw { span, kind }
}
