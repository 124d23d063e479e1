//! Rhai recipes: a script that builds the same raw recipe a YAML file would, with loops and functions.
//!
//! The script runs at compile time in a sandbox: bounded operations, call depth, string,
//! array and map sizes; no file or network access; `print` and `debug` are muted. It may
//! `import` `.rhai` files from its own folder and the folders below it ([`RecipeModules`]),
//! under the same limits. Its result (an object map) becomes the raw tree, so caching keys on
//! what it built.

use super::raw::{Key, Raw, RawKind};
use crate::diag::{Diagnostic, Diagnostics, SourceFile, Span};
use rhai::{Dynamic, Engine, EvalAltResult, Position};
use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};
use std::rc::Rc;
use std::sync::{Arc, Mutex};

/// Resource limits for a Rhai recipe or a Rhai step expression.
#[derive(Debug, Clone)]
pub struct RhaiLimits {
    pub max_operations: u64,
    pub max_call_levels: usize,
    pub max_string_size: usize,
    pub max_array_size: usize,
    pub max_map_size: usize,
    pub max_expr_depth: usize,
    /// Wall-clock time a script may run. Operations are counted, but some (cloning a value
    /// nested thousands deep) cost more the larger the script's data grows; this bounds them.
    pub max_time: std::time::Duration,
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
            max_time: std::time::Duration::from_secs(5),
        }
    }
}

/// A Rhai engine with the sandbox limits set, no module loading and muted output (a recipe's
/// engine is given [`RecipeModules`] in place of the resolver that refuses every import).
pub fn sandboxed_engine(limits: &RhaiLimits) -> Engine {
    let mut engine = Engine::new();
    engine.set_max_operations(limits.max_operations);
    engine.set_max_call_levels(limits.max_call_levels);
    engine.set_max_string_size(limits.max_string_size);
    engine.set_max_array_size(limits.max_array_size);
    engine.set_max_map_size(limits.max_map_size);
    engine.set_max_expr_depths(limits.max_expr_depth, limits.max_expr_depth);
    engine.set_module_resolver(rhai::module_resolvers::DummyModuleResolver::new());
    // The clock is read every 1024 operations; a run's first reading starts its clock (the
    // count starts again at each run, so a reading not above the last one is a new run).
    let budget = limits.max_time;
    let clock = Mutex::new((0u64, std::time::Instant::now()));
    engine.on_progress(move |ops| {
        if ops % 1024 != 0 {
            return None;
        }
        let mut c = clock.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if ops <= c.0 {
            c.1 = std::time::Instant::now();
        }
        c.0 = ops;
        (c.1.elapsed() > budget).then(|| Dynamic::from(TIME_LIMIT))
    });
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

/// The token a script stopped by its time limit ends with.
const TIME_LIMIT: &str = "time limit";

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

/// The modules a Rhai recipe may import: `.rhai` files in its own folder and the folders
/// below it, named by a relative path without `..` (`import "lib/helpers" as h;`). Anything
/// else (an absolute path, a URL, a folder, a link that leads out of the folder) is refused.
/// A module runs once, in the importing script's engine, under the same limits.
pub struct RecipeModules {
    /// The recipe's folder as the user named it (for messages) and as the system resolves it.
    shown_root: PathBuf,
    root: Option<PathBuf>,
    state: Mutex<ModuleState>,
}

/// The most imports a recipe's script and its modules run (a module imported again counts
/// again) and how deep modules may import modules: a module's index holds every function of
/// the modules below it, so a lattice of imports grows with the number of paths through it.
const MAX_IMPORTS: usize = 64;
const MAX_MODULE_DEPTH: usize = 6;

#[derive(Default)]
struct ModuleState {
    /// Imports run so far, cached or not.
    imports: usize,
    /// Modules evaluated, by relative path, so a module imported twice runs once.
    done: HashMap<PathBuf, rhai::Shared<rhai::Module>>,
    /// Modules being evaluated: importing one of them again is a cycle.
    running: Vec<PathBuf>,
    /// Every module file read, as diagnostics quote it and the manifest lists it.
    files: Vec<SourceFile>,
    /// Why an import was refused, by the path as written.
    refused: Vec<(String, String)>,
    /// The shown path of each module by the path as written, for errors inside it.
    shown: HashMap<String, Arc<str>>,
}

impl RecipeModules {
    /// The resolver of a recipe at `recipe` (its path as shown).
    pub fn new(recipe: &Path) -> RecipeModules {
        let shown_root = recipe.parent().map(Path::to_path_buf).unwrap_or_default();
        let root =
            std::fs::canonicalize(if shown_root.as_os_str().is_empty() { Path::new(".") } else { &shown_root }).ok();
        RecipeModules { shown_root, root, state: Mutex::new(ModuleState::default()) }
    }

    fn state(&self) -> std::sync::MutexGuard<'_, ModuleState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The module file `written` names, or why it is refused.
    fn locate(&self, written: &str) -> Result<(PathBuf, PathBuf), String> {
        if written.trim().is_empty() {
            return Err("an empty module path".into());
        }
        if written.contains("://") {
            return Err("a module is a file beside the recipe, not an address".into());
        }
        let mut rel = PathBuf::new();
        for c in Path::new(written).components() {
            match c {
                Component::Normal(p) => rel.push(p),
                Component::CurDir => {}
                Component::ParentDir => return Err("`..` leads out of the recipe's folder".into()),
                Component::RootDir | Component::Prefix(_) => {
                    return Err("an absolute path; name modules relative to the recipe's folder".into());
                }
            }
        }
        match rel.extension().and_then(|e| e.to_str()) {
            None => {
                rel.set_extension("rhai");
            }
            Some("rhai") => {}
            Some(other) => return Err(format!("a module is a `.rhai` file, not `.{other}`")),
        }
        let root = self.root.as_ref().ok_or("the recipe's folder cannot be read")?;
        let path = root.join(&rel);
        let real = std::fs::canonicalize(&path)
            .map_err(|_| format!("there is no `{}` in the recipe's folder", rel.display()))?;
        if !real.starts_with(root) {
            return Err("a link that leads out of the recipe's folder".into());
        }
        if !real.is_file() {
            return Err(format!("`{}` is not a file", rel.display()));
        }
        Ok((rel, real))
    }

    /// The module files read while the script ran.
    pub fn files(&self) -> Vec<SourceFile> {
        self.state().files.clone()
    }

    fn refusal(&self, written: &str) -> Option<String> {
        self.state().refused.iter().find(|(w, _)| w == written).map(|(_, r)| r.clone())
    }

    fn shown(&self, written: &str) -> Option<Arc<str>> {
        self.state().shown.get(written).cloned()
    }
}

impl rhai::ModuleResolver for RecipeModules {
    fn resolve(
        &self,
        engine: &Engine,
        _source: Option<&str>,
        path: &str,
        pos: Position,
    ) -> Result<rhai::Shared<rhai::Module>, Box<EvalAltResult>> {
        let refuse = |why: String| {
            self.state().refused.push((path.to_string(), why));
            Box::new(EvalAltResult::ErrorModuleNotFound(path.to_string(), pos))
        };
        let (rel, real) = self.locate(path).map_err(refuse)?;
        {
            let mut st = self.state();
            st.imports += 1;
            if st.imports > MAX_IMPORTS {
                drop(st);
                return Err(refuse(format!(
                    "the script runs more than {MAX_IMPORTS} imports; import each module once, where it is used"
                )));
            }
            if st.running.len() >= MAX_MODULE_DEPTH {
                drop(st);
                return Err(refuse(format!("modules import modules more than {MAX_MODULE_DEPTH} deep here")));
            }
            if let Some(m) = st.done.get(&rel) {
                return Ok(m.clone());
            }
            if st.running.contains(&rel) {
                drop(st);
                return Err(refuse(format!("`{}` imports itself (through the modules it imports)", rel.display())));
            }
        }
        let text = match super::read_recipe_bytes(&real) {
            Ok(bytes) => String::from_utf8(bytes).map_err(|_| refuse("the module is not valid UTF-8".into()))?,
            Err(super::RecipeRead::TooLarge) => {
                return Err(refuse(format!(
                    "the module is over the {} byte limit of a recipe",
                    super::MAX_RECIPE_BYTES
                )));
            }
            Err(super::RecipeRead::Io(e)) => return Err(refuse(format!("cannot read it: {e}"))),
        };
        let shown: Arc<str> = Arc::from(self.shown_root.join(&rel).display().to_string());
        {
            let mut st = self.state();
            st.shown.insert(path.to_string(), shown.clone());
            st.files.push(SourceFile { path: shown, text: Arc::from(text.as_str()) });
            st.running.push(rel.clone());
        }
        let result = engine
            .compile(&text)
            .map_err(|e| Box::new(EvalAltResult::ErrorInModule(path.to_string(), e.into(), pos)))
            .and_then(|mut ast| {
                ast.set_source(path);
                rhai::Module::eval_ast_as_new(rhai::Scope::new(), &ast, engine)
                    .map_err(|e| Box::new(EvalAltResult::ErrorInModule(path.to_string(), e, pos)))
            });
        let mut st = self.state();
        st.running.retain(|r| r != &rel);
        let module: rhai::Shared<rhai::Module> = result?.into();
        st.done.insert(rel, module.clone());
        Ok(module)
    }
}

/// Runs a `.rhai` recipe and converts the object map it returns into the raw tree.
pub fn load_rhai(file: &SourceFile, limits: &RhaiLimits, diags: &mut Diagnostics) -> Option<Raw> {
    load_rhai_with_modules(file, limits, diags).0
}

/// [`load_rhai`], also returning the module files the script imported.
pub fn load_rhai_with_modules(
    file: &SourceFile,
    limits: &RhaiLimits,
    diags: &mut Diagnostics,
) -> (Option<Raw>, Vec<SourceFile>) {
    // A script can build values nested as deep as its operations allow (closures that capture
    // closures, arrays in arrays), which are dropped, and converted, by recursion: it runs on a
    // thread of its own with a deep stack (address space; pages are touched only as used).
    let run = || {
        let mut found = Diagnostics::new();
        let mut engine = sandboxed_engine(limits);
        let modules = Rc::new(RecipeModules::new(Path::new(&*file.path)));
        engine.set_module_resolver(SharedResolver(modules.clone()));
        let raw = eval_recipe(&engine, &modules, file, &mut found);
        drop(engine);
        (raw, modules.files(), found)
    };
    let ran = std::thread::scope(|s| {
        std::thread::Builder::new()
            .name("rhai recipe".into())
            .stack_size(SCRIPT_STACK)
            .spawn_scoped(s, run)
            .map(|h| h.join())
    });
    match ran {
        Ok(Ok((raw, files, found))) => {
            diags.extend(found);
            (raw, files)
        }
        Ok(Err(panic)) => std::panic::resume_unwind(panic),
        // No thread to be had (a limit on threads or memory): the script is not run.
        Err(_) => {
            diags.push(
                Diagnostic::error(
                    Some(Span::file_only(file.path.clone())),
                    "the Rhai recipe could not be run: no thread for it",
                )
                .with_help("raise the process's thread or memory limit"),
            );
            (None, Vec::new())
        }
    }
}

/// The stack of the thread a Rhai recipe runs on.
const SCRIPT_STACK: usize = 1 << 30;

/// The resolver behind an `Rc`, so its files can be read after the engine is done.
struct SharedResolver(Rc<RecipeModules>);

impl rhai::ModuleResolver for SharedResolver {
    fn resolve(
        &self,
        engine: &Engine,
        source: Option<&str>,
        path: &str,
        pos: Position,
    ) -> Result<rhai::Shared<rhai::Module>, Box<EvalAltResult>> {
        self.0.resolve(engine, source, path, pos)
    }
}

fn eval_recipe(engine: &Engine, modules: &RecipeModules, file: &SourceFile, diags: &mut Diagnostics) -> Option<Raw> {
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
            if nests_deeper(&value, MAX_NESTING) {
                diags.push(
                    Diagnostic::error(
                        Some(root),
                        format!(
                            "the recipe the script built nests deeper than {MAX_NESTING} levels of maps and arrays"
                        ),
                    )
                    .with_help("a recipe is a few levels deep: build its lists flat"),
                );
                return None;
            }
            Some(to_raw(&file.path, "", value))
        }
        Err(e) => {
            // An error inside an imported module is shown where it is in the module.
            let (e, span) = match *e {
                EvalAltResult::ErrorModuleNotFound(written, pos) if modules.refusal(&written).is_some() => {
                    let why = modules.refusal(&written).unwrap_or_default();
                    diags.push(
                        Diagnostic::error(
                            Some(position_span(&file.path, pos)),
                            format!("Rhai recipe cannot import `{written}`: {why}"),
                        )
                        .with_help(IMPORT_HELP),
                    );
                    return None;
                }
                EvalAltResult::ErrorInModule(written, inner, pos) => {
                    // Down the chain of modules to the one where it failed, keeping the place
                    // of the import that reached it.
                    let (mut written, mut inner, mut span) = (written, inner, position_span(&file.path, pos));
                    while let EvalAltResult::ErrorInModule(next, deeper, at) = *inner {
                        if let Some(shown) = modules.shown(&written) {
                            span = position_span(&shown, at);
                        }
                        (written, inner) = (next, deeper);
                    }
                    if let EvalAltResult::ErrorModuleNotFound(refused, at) = &*inner
                        && let Some(why) = modules.refusal(refused)
                    {
                        let place = modules.shown(&written).map_or(span, |shown| position_span(&shown, *at));
                        diags.push(
                            Diagnostic::error(Some(place), format!("Rhai recipe cannot import `{refused}`: {why}"))
                                .with_help(IMPORT_HELP),
                        );
                        return None;
                    }
                    let span = match modules.shown(&written) {
                        Some(shown) if inner.position().line().is_some() => position_span(&shown, inner.position()),
                        _ => span,
                    };
                    (inner, span)
                }
                other => {
                    let span = position_span(&file.path, other.position());
                    (Box::new(other), span)
                }
            };
            let help = match *e {
                EvalAltResult::ErrorTooManyOperations(_) => {
                    "the script ran past its operation limit: a loop that never ends, or a sweep too large for a recipe"
                }
                EvalAltResult::ErrorStackOverflow(_) => "the script recursed too deep",
                EvalAltResult::ErrorTerminated(..) => {
                    "the script ran past its time limit: a recipe builds its steps in well under a second; build its lists flat, not nested"
                }
                EvalAltResult::ErrorDataTooLarge(..) => "a string, array or map in the script grew past its limit",
                EvalAltResult::ErrorModuleNotFound(..) => IMPORT_HELP,
                _ => "fix the script; it runs at compile time and must return the recipe as an object map",
            };
            let msg = match *e {
                EvalAltResult::ErrorTerminated(..) => {
                    format!("ran longer than {} s and was stopped", RhaiLimits::default().max_time.as_secs())
                }
                _ => e.to_string(),
            };
            let msg = match msg.rfind(" (line ") {
                Some(i) if msg.ends_with(')') => msg[..i].to_string(),
                _ => msg,
            };
            diags.push(Diagnostic::error(Some(span), format!("Rhai recipe failed: {msg}")).with_help(help));
            None
        }
    }
}

/// The deepest a recipe built by a script may nest maps and arrays (a YAML recipe's parser
/// has a limit of its own).
const MAX_NESTING: usize = 64;

/// Whether `value` nests maps and arrays deeper than `max`, walked without recursion.
fn nests_deeper(value: &Dynamic, max: usize) -> bool {
    let mut stack: Vec<(Dynamic, usize)> = vec![(value.clone(), 0)];
    while let Some((v, depth)) = stack.pop() {
        if depth > max {
            return true;
        }
        if v.is_array() {
            if let Ok(a) = v.into_array() {
                stack.extend(a.into_iter().map(|x| (x, depth + 1)));
            }
        } else if v.is_map()
            && let Some(m) = v.try_cast::<rhai::Map>()
        {
            stack.extend(m.into_values().map(|x| (x, depth + 1)));
        }
    }
    false
}

/// What a refused or missing import should be instead.
const IMPORT_HELP: &str = "a Rhai recipe imports `.rhai` files from its own folder and the folders below it, by a relative path without `..`: `import \"helpers\" as h;`";

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
