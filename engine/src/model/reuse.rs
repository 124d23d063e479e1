//! Reuse across files: `use:` takes entities from library files, and a step of `kind: recipe`
//! runs another recipe's steps, inlined under the step's name (`tap/segment`).
//!
//! Both are expanded on the raw tree before it is resolved, so what they bring is checked,
//! keyed and cached exactly like what a recipe writes itself, and every value keeps the place
//! it was written: an error in a library points into the library.
//!
//! ```yaml
//! use: [lib/shop.yaml, lib/holders.yaml]        # materials, machines, assemblies, sensors, cutting
//! steps:
//!   tap:
//!     kind: recipe
//!     file: procedures/tap-test.yaml             # declares `params`, `inputs` and `exports`
//!     params: { impacts: 10 }
//!     sweep: { speed: 0..4000 step 1000 rpm }    # sweeps the whole procedure
//!   fit: { kind: modal.fit, inputs: { frf: "@tap.frf" } }   # an export of the procedure
//! ```
//!
//! One name means one entity: the same name defined in two files is an error naming both (a
//! file reached twice, through two libraries, is taken once).

use super::measurements;
use super::params::ParamQuantity;
use crate::diag::{Diagnostics, SourceFile, Span};
use crate::node::Registry;
use crate::spec::{EntityKind, normalize, suggest};
use crate::syntax::{self, Key, Raw, RawKind};
use crate::value::PortType;
use indexmap::IndexMap;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The step kind that runs another recipe as a step.
pub const RECIPE_KIND: &str = "recipe";

/// How a sub-recipe's steps name its declared inputs: `"@inputs.frf"`.
pub const INPUTS: &str = "inputs";

/// Keys a library may hold besides its entity sections.
const LIBRARY_KEYS: &[&str] = &["spindlelab", "name", "description", "use"];

/// Keys of a step that runs a recipe.
const RECIPE_STEP_KEYS: &[&str] = &["kind", "file", "params", "inputs", "sweep", "description"];

/// Keys a recipe run as a step may not have, and why: they belong to the recipe that runs it.
const NOT_IN_A_STEP: &[(&str, &str)] = &[
    ("fit", "a fit moves the parameters of the recipe that is run; fit the recipe that uses this one"),
    ("plugins", "name the plugins in the recipe that uses this one"),
    ("speeds", "give the speeds as a parameter of a step"),
];

/// Deepest nesting of libraries and sub-recipes: deeper is a mistake, not a design.
const MAX_DEPTH: usize = 16;

/// The raw tree with every `use` and `kind: recipe` step expanded.
pub struct Expanded {
    pub raw: Raw,
    /// The file holds entities only: a library, checked on its own.
    pub library: bool,
}

/// The folders a library or sub-recipe named by a bare relative path is looked for in when it
/// is not beside the file naming it: `$SPINDLELAB_LIBRARY_PATH`, then
/// `~/.local/share/spindlelab/library`.
pub fn library_search_path() -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> =
        std::env::var_os("SPINDLELAB_LIBRARY_PATH").map(|p| std::env::split_paths(&p).collect()).unwrap_or_default();
    let data = std::env::var_os("XDG_DATA_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/share")));
    if let Some(d) = data {
        dirs.push(d.join("spindlelab/library"));
    }
    dirs.retain(|d| !d.as_os_str().is_empty());
    dirs
}

/// The folder of the file a value was written in: file parameters and the files a recipe uses
/// are relative to it (a Rhai recipe's values carry ` (at key.path)` after the file name).
pub(crate) fn source_folder(file: &str) -> PathBuf {
    let file = match file.find(" (at ") {
        Some(i) if file.ends_with(')') => &file[..i],
        _ => file,
    };
    Path::new(file).parent().map(Path::to_path_buf).unwrap_or_default()
}

/// The file a span is in, without the key path a Rhai recipe adds.
fn file_of(span: &Span) -> &str {
    match span.file.find(" (at ") {
        Some(i) if span.file.ends_with(')') => &span.file[..i],
        _ => &span.file,
    }
}

/// Whether a raw tree is a library: entity sections (or `use`) and no steps.
pub fn is_library(raw: &Raw) -> bool {
    raw.as_map().is_some()
        && raw.get("steps").is_none()
        && raw.get("measurements").is_none()
        && (raw.get("use").is_some() || EntityKind::ALL.iter().any(|k| raw.get(k.section()).is_some()))
}

/// Expands `use:` and `kind: recipe` steps, reading the files they name, pushing each into
/// `sources` (so diagnostics quote them and the manifest lists them) and every problem into
/// `diags`. A tree without either comes back as it was.
pub fn expand(raw: Raw, registry: &Registry, sources: &mut Vec<SourceFile>, diags: &mut Diagnostics) -> Expanded {
    expand_within(raw, registry, None, sources, diags)
}

/// [`expand`] for `--confine`: a library or recipe named outside `confine` (the recipe's
/// folder) is refused by its name, before any byte of it is read.
pub fn expand_within(
    raw: Raw,
    registry: &Registry,
    confine: Option<&Path>,
    sources: &mut Vec<SourceFile>,
    diags: &mut Diagnostics,
) -> Expanded {
    if raw.as_map().is_none() {
        return Expanded { raw, library: false };
    }
    let library = is_library(&raw);
    let needs = library || raw.get("use").is_some() || raw.get(INPUTS).is_some() || has_recipe_steps(&raw);
    if !needs {
        check_step_names(&raw, diags);
        return Expanded { raw, library };
    }
    let root_file: Arc<str> = Arc::from(file_of(&raw.span));
    let mut ex = Expander {
        registry,
        confine,
        search: library_search_path(),
        sources,
        diags,
        files: HashMap::new(),
        libraries: HashMap::new(),
        stack: vec![(canonical(Path::new(&*root_file)), root_file.clone())],
    };
    let mut tree = raw;
    if let Some(inputs) = tree.get(INPUTS) {
        ex.diags.error_help(
            Some(&inputs.span),
            "this recipe declares `inputs`, so it runs as a step of another recipe, which binds them",
            "use it from a recipe: `kind: recipe`, `file: …`, `inputs: { name: \"@step.port\" }`",
        );
    }
    if library {
        ex.check_library_keys(&tree);
        ex.merge_uses(&mut tree, 0);
        let span = tree.span.clone();
        if let RawKind::Map(top) = &mut tree.kind {
            if !top.iter().any(|(k, _)| k.name == "spindlelab") {
                top.insert(0, (key("spindlelab", &span), Raw { span: span.clone(), kind: RawKind::Int(1) }));
            }
            top.push((key("steps", &span), Raw { span, kind: RawKind::Map(Vec::new()) }));
        }
        return Expanded { raw: tree, library };
    }
    ex.merge_uses(&mut tree, 0);
    // The recipes run as steps may run others, each more than once: the size is counted from
    // the files before any is inlined, so a fan-out is refused at its size, not built.
    let size = ex.quietly(|ex| ex.expanded_size(&tree, 0, &mut HashMap::new()));
    if size > super::MAX_STEPS as u64 {
        let span = tree.get("steps").map_or_else(|| tree.span.clone(), |s| s.span.clone());
        ex.diags.error_help(
            Some(&span),
            format!(
                "the recipes this recipe runs as steps would make it {size} steps, over the limit of {}",
                super::MAX_STEPS
            ),
            "run fewer recipes per recipe, or sweep a parameter instead of repeating a step",
        );
        return Expanded { raw: tree, library };
    }
    ex.expand_steps(&mut tree, 0);
    Expanded { raw: tree, library }
}

fn has_recipe_steps(raw: &Raw) -> bool {
    raw.get("steps")
        .and_then(Raw::as_map)
        .is_some_and(|m| m.iter().any(|(_, s)| s.get("kind").and_then(Raw::as_str) == Some(RECIPE_KIND)))
}

/// A step name written in a file may not hold `/`: it separates a sub-recipe's steps from the
/// step that runs it. Steps inlined from another file carry that file's places and are not
/// this file's to check.
fn check_step_names(raw: &Raw, diags: &mut Diagnostics) {
    let own = file_of(&raw.span);
    for (k, _) in raw.get("steps").and_then(Raw::as_map).unwrap_or(&[]) {
        if k.name.contains('/') && file_of(&k.span) == own {
            diags.error_help(
                Some(&k.span),
                format!(
                    "step name `{}` holds `/`, which separates a sub-recipe's steps from the step that runs it",
                    k.name
                ),
                "use letters, digits, `_` and `-`",
            );
        }
    }
}

fn key(name: &str, span: &Span) -> Key {
    Key { name: name.to_string(), span: span.clone() }
}

fn canonical(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| normalize(path))
}

fn map_mut(raw: &mut Raw) -> Option<&mut Vec<(Key, Raw)>> {
    match &mut raw.kind {
        RawKind::Map(m) => Some(m),
        _ => None,
    }
}

fn get_mut<'a>(raw: &'a mut Raw, name: &str) -> Option<&'a mut Raw> {
    map_mut(raw)?.iter_mut().find(|(k, _)| k.name == name).map(|(_, v)| v)
}

fn remove(raw: &mut Raw, name: &str) -> Option<(Key, Raw)> {
    let m = map_mut(raw)?;
    let i = m.iter().position(|(k, _)| k.name == name)?;
    Some(m.remove(i))
}

/// The parameter a scalar names, when it is `$name`.
fn dollar(raw: &Raw) -> Option<&str> {
    raw.as_str()?.trim().strip_prefix('$')
}

/// Every `$name` in a tree, with its place.
fn dollars<'a>(raw: &'a Raw, out: &mut Vec<(&'a str, &'a Span)>) {
    if let Some(name) = dollar(raw) {
        out.push((name, &raw.span));
        return;
    }
    match &raw.kind {
        RawKind::Seq(items) => items.iter().for_each(|i| dollars(i, out)),
        RawKind::Map(entries) => entries.iter().for_each(|(_, v)| dollars(v, out)),
        _ => {}
    }
}

/// `@step.port` split, for a step name that may hold `/`.
fn split_ref(text: &str) -> Option<(&str, &str)> {
    let t = text.trim().strip_prefix('@').unwrap_or(text.trim());
    let (step, port) = t.rsplit_once('.')?;
    (!step.is_empty() && !port.is_empty()).then_some((step, port))
}

/// Applies `f` to every reference of a tree: step inputs, outputs (`from`, `with`), the fit's
/// objective and a recipe's exports.
fn for_each_ref(tree: &mut Raw, f: &mut dyn FnMut(&mut Raw)) {
    // A reference, a list of them, or `{ from: reference, … }` entries of a plot's `with`.
    let visit = |v: &mut Raw, f: &mut dyn FnMut(&mut Raw)| match &mut v.kind {
        RawKind::Str(_) => f(v),
        RawKind::Seq(items) => {
            for i in items.iter_mut() {
                match i.kind {
                    RawKind::Str(_) => f(i),
                    RawKind::Map(_) => {
                        if let Some(from) = get_mut(i, "from").filter(|r| matches!(r.kind, RawKind::Str(_))) {
                            f(from)
                        }
                    }
                    _ => {}
                }
            }
        }
        _ => {}
    };
    if let Some(steps) = get_mut(tree, "steps").and_then(map_mut) {
        for (_, step) in steps.iter_mut() {
            if let Some(inputs) = get_mut(step, "inputs").and_then(map_mut) {
                inputs.iter_mut().for_each(|(_, v)| visit(v, f));
            }
        }
    }
    if let Some(RawKind::Seq(outs)) = get_mut(tree, "outputs").map(|o| &mut o.kind) {
        for out in outs.iter_mut() {
            for k in ["from", "with"] {
                if let Some(v) = get_mut(out, k) {
                    visit(v, f);
                }
            }
        }
    }
    if let Some(obj) = get_mut(tree, "fit").and_then(|fit| get_mut(fit, "objective")) {
        visit(obj, f);
    }
    if let Some(exports) = get_mut(tree, "exports").and_then(map_mut) {
        exports.iter_mut().for_each(|(_, v)| visit(v, f));
    }
}

/// A port type as a sub-recipe declares it (`frf`, `time series`, `modal_model`).
fn port_type(text: &str) -> Option<PortType> {
    let norm = |s: &str| s.chars().filter(|c| c.is_ascii_alphanumeric()).collect::<String>().to_ascii_lowercase();
    let want = norm(text);
    [
        PortType::TimeSeries,
        PortType::Frf,
        PortType::ReceptanceSet,
        PortType::ModalModel,
        PortType::BeamModel,
        PortType::Substructure,
        PortType::Lobes,
        PortType::Table,
        PortType::Scalar,
        PortType::FrfSet,
    ]
    .into_iter()
    .find(|t| {
        let n = norm(t.name());
        n == want || n.strip_prefix("2x2") == Some(want.as_str())
    })
}

/// A recipe step inlined: its steps under the prefix, and its exports as references to them.
type Inlined = (Vec<(Key, Raw)>, IndexMap<String, String>);

/// The recipe a `kind: recipe` step runs, as read.
struct SubRecipe {
    /// Its canonical path, and its name as messages show it.
    canon: PathBuf,
    shown: Arc<str>,
    /// Its file as the step names it, and where.
    written: String,
    span: Span,
    tree: Raw,
    /// The names of its own steps, before any expansion.
    own_steps: Vec<String>,
}

/// What a recipe run as a step declares.
struct Declared {
    /// Parameters, with their defaults.
    params: IndexMap<String, Raw>,
    /// Inputs, with their port types (`None`: not a port type; reported).
    inputs: IndexMap<String, (Span, Option<PortType>)>,
}

/// What the step that runs a recipe gives it.
struct Given {
    /// Parameters set, and swept (with the place they are swept at).
    bound: IndexMap<String, Raw>,
    swept: IndexMap<String, (Span, Raw)>,
    /// Inputs bound to references.
    bindings: IndexMap<String, Raw>,
}

struct Expander<'a> {
    registry: &'a Registry,
    /// `--confine`: the folder every file read must lie in, by name.
    confine: Option<&'a Path>,
    search: Vec<PathBuf>,
    sources: &'a mut Vec<SourceFile>,
    diags: &'a mut Diagnostics,
    /// Files read, by canonical path: the name shown and the tree (`None`: it did not load).
    files: HashMap<PathBuf, (Arc<str>, Option<Raw>)>,
    /// Libraries expanded and checked, by canonical path (`None`: they have errors).
    libraries: HashMap<PathBuf, Option<Raw>>,
    /// The files being expanded, outermost first: one of them reached again is a cycle.
    stack: Vec<(PathBuf, Arc<str>)>,
}

impl Expander<'_> {
    /// Runs `f` with its diagnostics set aside: for looking ahead at files that the expansion
    /// proper reports on.
    fn quietly<T>(&mut self, f: impl FnOnce(&mut Self) -> T) -> T {
        let kept = std::mem::take(self.diags);
        let out = f(self);
        *self.diags = kept;
        out
    }

    /// How many steps `tree` has once its recipes run as steps are inlined (saturating), read
    /// from the files without inlining them; `memo` holds each file's count by canonical path.
    /// A step that cannot be followed (a missing file, a cycle, too deep) counts as one: the
    /// expansion reports it.
    fn expanded_size(&mut self, tree: &Raw, depth: usize, memo: &mut HashMap<PathBuf, u64>) -> u64 {
        let Some(steps) = tree.get("steps").and_then(Raw::as_map) else { return 0 };
        let mut n: u64 = 0;
        for (_, step) in steps {
            let file = step.get("file").filter(|_| step.get("kind").and_then(Raw::as_str) == Some(RECIPE_KIND));
            let found = file.filter(|_| depth < MAX_DEPTH).and_then(|f| Some((f.as_str()?, &f.span)));
            let Some(path) = found.and_then(|(written, span)| self.locate(written, span, "recipe")) else {
                n = n.saturating_add(1);
                continue;
            };
            let canon = canonical(&path);
            let k = match memo.get(&canon) {
                Some(&k) => k,
                None => {
                    memo.insert(canon.clone(), 1); // a cycle counts once
                    let mut scratch = Diagnostics::new();
                    let sub = syntax::load_file(&path, &mut scratch).and_then(|l| l.raw);
                    let k = sub.map_or(1, |sub| self.expanded_size(&sub, depth + 1, memo));
                    memo.insert(canon, k);
                    k
                }
            };
            n = n.saturating_add(k);
        }
        n
    }

    /// The file `written` names from the file `from`: beside it, else on the search path.
    fn locate(&mut self, written: &str, from: &Span, what: &str) -> Option<PathBuf> {
        let found = self.find_file(written, from, what)?;
        match self.confine {
            Some(root) if !super::within(root, &found) => {
                self.diags.error_help(
                    Some(from),
                    format!("{what} `{written}` lies outside the recipe's folder, which --confine refuses"),
                    "copy it beside the recipe, or run without --confine",
                );
                None
            }
            _ => Some(found),
        }
    }

    /// The file `written` names from the file `from`, wherever it is.
    fn find_file(&mut self, written: &str, from: &Span, what: &str) -> Option<PathBuf> {
        let base = source_folder(&from.file);
        let p = Path::new(written);
        let beside = normalize(&base.join(p));
        if p.is_absolute() || beside.is_file() {
            if beside.is_file() {
                return Some(beside);
            }
        } else if !written.starts_with("./")
            && !written.starts_with("../")
            && let Some(found) = self.search.iter().map(|d| d.join(p)).find(|f| f.is_file())
        {
            return Some(found);
        }
        let looked: Vec<String> =
            std::iter::once(if base.as_os_str().is_empty() { ".".to_string() } else { base.display().to_string() })
                .chain(self.search.iter().filter(|_| !p.is_absolute()).map(|d| d.display().to_string()))
                .collect();
        let msg = if beside.exists() {
            format!("{what} `{written}` is not a file")
        } else {
            format!("{what} `{written}` not found (looked in {})", looked.join(", "))
        };
        self.diags.error_help(
            Some(from),
            msg,
            "name it relative to this file's folder, or put it on $SPINDLELAB_LIBRARY_PATH",
        );
        None
    }

    /// Reads and parses a file once; later calls get the same tree.
    fn load(&mut self, path: &Path) -> (PathBuf, Arc<str>, Option<Raw>) {
        let canon = canonical(path);
        if let Some((shown, raw)) = self.files.get(&canon) {
            return (canon, shown.clone(), raw.clone());
        }
        let loaded = syntax::load_file(path, self.diags);
        let shown: Arc<str> = Arc::from(path.display().to_string());
        let raw = match loaded {
            Some(l) => {
                self.sources.extend(l.sources());
                l.raw
            }
            None => None,
        };
        self.files.insert(canon.clone(), (shown.clone(), raw.clone()));
        (canon, shown, raw)
    }

    /// The chain of files that leads back to `canon`, for a cycle's message; `None` when
    /// `canon` is not being expanded.
    fn cycle(&self, canon: &Path, shown: &str) -> Option<String> {
        let i = self.stack.iter().position(|(p, _)| p == canon)?;
        let mut names: Vec<&str> = self.stack[i..].iter().map(|(_, s)| &**s).collect();
        names.push(shown);
        Some(names.join(" → "))
    }

    /// Refuses what a library may not hold: steps and the rest of a recipe, and `$name`.
    fn check_library_keys(&mut self, tree: &Raw) {
        let file = file_of(&tree.span).to_string();
        for (k, v) in tree.as_map().unwrap_or(&[]) {
            let entity = EntityKind::ALL.iter().any(|e| e.section() == k.name);
            if !entity && !LIBRARY_KEYS.contains(&k.name.as_str()) {
                let sections: Vec<&str> = EntityKind::ALL.iter().map(|e| e.section()).collect();
                self.diags.error_help(
                    Some(&k.span),
                    format!(
                        "`{}` in a library: {file} is used for its entities ({}), and a library holds nothing else",
                        k.name,
                        sections.join(", ")
                    ),
                    if k.name == "steps" {
                        "move the steps to a recipe that `use`s this file, or run this file as a step (`kind: recipe`)"
                    } else {
                        "move it to the recipe that uses this library"
                    },
                );
            }
            if entity {
                let mut found = Vec::new();
                dollars(v, &mut found);
                for (name, span) in found {
                    self.diags.error_help(
                        Some(span),
                        format!("`${name}` in a library: a library declares no parameters"),
                        "write the value, or define this entity in the recipe that declares the parameter",
                    );
                }
            }
        }
    }

    /// Expands a tree's `use:` list into its entity sections and removes it. A name defined in
    /// two files is an error naming both; a file reached twice is taken once.
    fn merge_uses(&mut self, tree: &mut Raw, depth: usize) -> bool {
        let Some((_, list)) = remove(tree, "use") else { return true };
        let items: Vec<Raw> = match list.kind {
            RawKind::Seq(items) => items,
            RawKind::Str(_) => vec![list],
            _ => {
                self.diags.error_help(
                    Some(&list.span),
                    format!("`use` must be a list of library files, found {}", list.describe()),
                    "write `use: [lib/shop.yaml, lib/holders.yaml]`",
                );
                return false;
            }
        };
        let mut ok = true;
        let mut libs: Vec<(Span, Raw)> = Vec::new();
        for item in items {
            let Some(written) = item.as_str() else {
                self.diags.error_help(
                    Some(&item.span),
                    format!("a `use` entry is a file name, found {}", item.describe()),
                    "write `use: [lib/holders.yaml]`",
                );
                ok = false;
                continue;
            };
            if !(written.ends_with(".yaml") || written.ends_with(".yml")) {
                self.diags.error_help(
                    Some(&item.span),
                    format!("`{written}` is not a YAML file; a library is one"),
                    "name a `.yaml` file holding materials, machines, assemblies, sensors or cutting setups",
                );
                ok = false;
                continue;
            }
            match self.library(written, &item.span, depth) {
                Some(lib) => libs.push((item.span.clone(), lib)),
                None => ok = false,
            }
        }
        for (via, lib) in &libs {
            self.merge_entities(tree, lib, via);
        }
        ok
    }

    /// A used library, expanded (its own `use` included) and checked on its own; `None` when
    /// it cannot be used (each problem reported, and one at the `use` entry).
    fn library(&mut self, written: &str, entry: &Span, depth: usize) -> Option<Raw> {
        let path = self.locate(written, entry, "library")?;
        let canon = canonical(&path);
        let shown_now = path.display().to_string();
        if let Some(chain) = self.cycle(&canon, &shown_now) {
            self.diags.error_help(
                Some(entry),
                format!("`{written}` uses itself: {chain}"),
                "a library may use others, but not one that leads back to it",
            );
            return None;
        }
        if depth >= MAX_DEPTH {
            self.diags.error(Some(entry), format!("libraries nest deeper than {MAX_DEPTH} files here"));
            return None;
        }
        if let Some(done) = self.libraries.get(&canon) {
            if done.is_none() {
                self.diags
                    .error(Some(entry), format!("cannot use `{written}`: it has errors (reported at their places)"));
            }
            return done.clone();
        }
        let errors = self.diags.error_count();
        let (canon, shown, raw) = self.load(&path);
        let result = raw.and_then(|mut tree| {
            if tree.as_map().is_none() {
                self.diags.error(Some(&tree.span), format!("a library must be a mapping, found {}", tree.describe()));
                return None;
            }
            self.check_library_keys(&tree);
            if let Some(v) = tree.get("spindlelab")
                && !matches!(v.kind, RawKind::Int(super::FORMAT_VERSION))
            {
                self.diags.error_help(
                    Some(&v.span),
                    "unsupported library version",
                    format!("this spindlelab reads `spindlelab: {}`", super::FORMAT_VERSION),
                );
            }
            self.stack.push((canon.clone(), shown.clone()));
            let used = self.merge_uses(&mut tree, depth + 1);
            self.stack.pop();
            if !used || self.diags.error_count() > errors {
                return None;
            }
            // On its own: every name it uses must be its own or a library's it uses.
            let mut alone = tree.clone();
            let span = alone.span.clone();
            if let Some(m) = map_mut(&mut alone) {
                m.retain(|(k, _)| k.name != "spindlelab");
                m.insert(0, (key("spindlelab", &span), Raw { span: span.clone(), kind: RawKind::Int(1) }));
                m.push((key("steps", &span), Raw { span, kind: RawKind::Map(Vec::new()) }));
            }
            super::resolve::resolve(&alone, &[], self.registry, self.diags);
            (self.diags.error_count() == errors).then_some(tree)
        });
        if result.is_none() && self.diags.error_count() > errors {
            self.diags.error_help(
                Some(entry),
                format!("cannot use `{written}`: it has errors (reported at their places in {shown})"),
                "fix the library; `spindlelab check` on it reports them alone",
            );
        }
        self.libraries.insert(canon, result.clone());
        result
    }

    /// Adds the entities of `from` to `tree`'s sections; `via` is where `tree` takes them
    /// (its `use` entry, or the step that runs a sub-recipe).
    fn merge_entities(&mut self, tree: &mut Raw, from: &Raw, via: &Span) {
        let own = file_of(&tree.span).to_string();
        for kind in EntityKind::ALL {
            let Some(entries) = from.get(kind.section()).and_then(Raw::as_map) else { continue };
            if entries.is_empty() {
                continue;
            }
            let Some(top) = map_mut(tree) else { return };
            if !top.iter().any(|(k, _)| k.name == kind.section()) {
                top.push((key(kind.section(), via), Raw { span: via.clone(), kind: RawKind::Map(Vec::new()) }));
            }
            let section = get_mut(tree, kind.section()).expect("just made");
            let Some(have) = map_mut(section) else { continue };
            for (k, v) in entries {
                match have.iter().find(|(h, _)| h.name == k.name) {
                    // The same file reached twice: the same entity.
                    Some((h, _)) if h.span.file == k.span.file => {}
                    Some((h, _)) => {
                        let (at, msg) = if file_of(&h.span) == own {
                            (
                                h.span.clone(),
                                format!(
                                    "{} `{}` is defined here and in {}:{}",
                                    kind.noun(),
                                    k.name,
                                    file_of(&k.span),
                                    k.span.line
                                ),
                            )
                        } else {
                            (
                                via.clone(),
                                format!(
                                    "{} `{}` is defined in both {}:{} and {}:{}",
                                    kind.noun(),
                                    k.name,
                                    file_of(&h.span),
                                    h.span.line,
                                    file_of(&k.span),
                                    k.span.line
                                ),
                            )
                        };
                        self.diags.error_help(
                            Some(&at),
                            msg,
                            "one name means one entity across a recipe and the files it uses: rename one, or delete the copy",
                        );
                    }
                    None => have.push((k.clone(), v.clone())),
                }
            }
        }
    }

    /// Inlines every `kind: recipe` step of `tree` and rewrites the references to them.
    fn expand_steps(&mut self, tree: &mut Raw, depth: usize) {
        check_step_names(tree, self.diags);
        if !has_recipe_steps(tree) {
            return;
        }
        let Some(steps) = get_mut(tree, "steps").and_then(map_mut).map(std::mem::take) else { return };
        let mut out: Vec<(Key, Raw)> = Vec::new();
        // Per recipe step: its exports (name → reference to an inlined step), or `None` when
        // it could not be expanded (references to it are then not reported again).
        let mut exports: IndexMap<String, Option<IndexMap<String, String>>> = IndexMap::new();
        for (k, step) in steps {
            if step.get("kind").and_then(Raw::as_str) != Some(RECIPE_KIND) {
                out.push((k, step));
                continue;
            }
            match self.inline(&k, &step, tree, depth) {
                Some((inlined, ex)) => {
                    out.extend(inlined);
                    exports.insert(k.name.clone(), Some(ex));
                }
                None => {
                    exports.insert(k.name.clone(), None);
                }
            }
        }
        if let Some(slot) = get_mut(tree, "steps") {
            slot.kind = RawKind::Map(out);
        }
        let diags = &mut *self.diags;
        for_each_ref(tree, &mut |v: &mut Raw| {
            let Some(text) = v.as_str() else { return };
            let Some((step, port)) = split_ref(text) else { return };
            let Some(ex) = exports.get(step) else { return };
            let Some(ex) = ex else { return };
            match ex.get(port) {
                Some(target) => v.kind = RawKind::Str(target.clone()),
                None => {
                    let known: Vec<&str> = ex.keys().map(String::as_str).collect();
                    let msg = format!("step `{step}` runs a recipe that exports no `{port}`");
                    match suggest(port, known.iter().copied()) {
                        Some(s) => diags.error_help(Some(&v.span), msg, format!("did you mean `@{step}.{s}`?")),
                        None => diags.error_help(
                            Some(&v.span),
                            msg,
                            if known.is_empty() {
                                "it exports nothing: add `exports: { name: \"@step.port\" }` to it".to_string()
                            } else {
                                format!("its exports: {}", known.join(", "))
                            },
                        ),
                    }
                }
            }
        });
    }

    /// One `kind: recipe` step: the steps of the recipe it runs, prefixed with its name, and
    /// its exports as references to them. The recipe's entities are merged into `parent`.
    fn inline(&mut self, k: &Key, step: &Raw, parent: &mut Raw, depth: usize) -> Option<Inlined> {
        let name = &k.name;
        let errors = self.diags.error_count();
        self.check_recipe_step_keys(name, step);
        let mut sub = self.open_sub_recipe(k, step, depth)?;
        let declared = self.declarations(&sub);
        let given = self.given(k, step, &sub, &declared);
        self.pass_parameters(name, &mut sub, &declared, &given);
        self.refuse_parameters_in_entities(&sub.tree);
        if self.diags.error_count() > errors {
            return None;
        }
        self.expand_under_prefix(name, &mut sub, depth);
        let out = self.wire_inputs(name, &mut sub, &declared, &given);
        let exports = self.exports(name, &sub);
        self.merge_entities(parent, &sub.tree, &sub.span);
        (self.diags.error_count() == errors).then_some((out, exports))
    }

    /// Reports keys a `kind: recipe` step does not take.
    fn check_recipe_step_keys(&mut self, name: &str, step: &Raw) {
        for (sk, _) in step.as_map().unwrap_or(&[]) {
            if !RECIPE_STEP_KEYS.contains(&sk.name.as_str()) {
                let msg = format!("unknown key `{}` in step `{name}` (kind: recipe)", sk.name);
                match suggest(&sk.name, RECIPE_STEP_KEYS.iter().copied()) {
                    Some(s) => self.diags.error_help(Some(&sk.span), msg, format!("did you mean `{s}`?")),
                    None => self.diags.error_help(
                        Some(&sk.span),
                        msg,
                        format!("known keys: {}", RECIPE_STEP_KEYS.join(", ")),
                    ),
                }
            }
        }
    }

    /// The recipe a step runs, read and checked: it exists, is not already running, has steps
    /// and nothing a recipe run as a step cannot have; its measurement sets expanded.
    fn open_sub_recipe(&mut self, k: &Key, step: &Raw, depth: usize) -> Option<SubRecipe> {
        let name = &k.name;
        let Some(file_raw) = step.get("file") else {
            self.diags.error_help(
                Some(&k.span),
                format!("step `{name}` runs a recipe but names no `file`"),
                "add `file: procedures/tap-test.yaml` (relative to this file)",
            );
            return None;
        };
        let Some(written) = file_raw.as_str() else {
            self.diags.error(Some(&file_raw.span), format!("`file` of step `{name}` must be a file name"));
            return None;
        };
        let path = self.locate(written, &file_raw.span, "recipe")?;
        let canon = canonical(&path);
        if let Some(chain) = self.cycle(&canon, &path.display().to_string()) {
            self.diags.error_help(
                Some(&file_raw.span),
                format!("step `{name}` runs a recipe that runs itself: {chain}"),
                "a recipe run as a step cannot lead back to the recipe that runs it",
            );
            return None;
        }
        if depth >= MAX_DEPTH {
            self.diags.error(Some(&file_raw.span), format!("recipes run as steps nest deeper than {MAX_DEPTH} here"));
            return None;
        }
        let (canon, shown, raw) = self.load(&path);
        let Some(mut sub) = raw else {
            self.diags.error_help(
                Some(&file_raw.span),
                format!("step `{name}` cannot run `{written}`: it has errors (reported at their places)"),
                "fix that recipe; `spindlelab check` reports its problems",
            );
            return None;
        };
        if sub.as_map().is_none() || sub.get("steps").is_none() {
            self.diags.error_help(
                Some(&file_raw.span),
                format!("`{written}` has no steps to run"),
                if is_library(&sub) {
                    "it is a library: take its entities with `use:` at the top of the recipe"
                } else {
                    "a recipe run as a step declares `steps` (and `exports` for what it hands back)"
                },
            );
            return None;
        }
        for (bad, why) in NOT_IN_A_STEP {
            if let Some((bk, _)) = sub.as_map().unwrap_or(&[]).iter().find(|(sk, _)| sk.name == *bad) {
                self.diags.error_help(Some(&bk.span), format!("`{bad}` in a recipe run as a step (by `{name}`)"), *why);
            }
        }
        // Measurement sets are read relative to the sub-recipe's own folder.
        let base = source_folder(&shown);
        sub = measurements::desugar(&sub, Some(&base), self.registry.measurement_reader(), self.diags);
        let own_steps: Vec<String> =
            sub.get("steps").and_then(Raw::as_map).unwrap_or(&[]).iter().map(|(s, _)| s.name.clone()).collect();

        Some(SubRecipe {
            canon,
            shown,
            written: written.to_string(),
            span: file_raw.span.clone(),
            tree: sub,
            own_steps,
        })
    }

    /// What the recipe declares: its parameters with their defaults and its inputs with their
    /// port types.
    fn declarations(&mut self, sub: &SubRecipe) -> Declared {
        let SubRecipe { tree: sub, own_steps, .. } = sub;
        // Declarations: parameters with their defaults, inputs with their types, exports.
        let declared: IndexMap<String, Raw> = sub
            .get("params")
            .and_then(Raw::as_map)
            .unwrap_or(&[])
            .iter()
            .map(|(pk, pv)| (pk.name.clone(), pv.clone()))
            .collect();
        let mut inputs: IndexMap<String, (Span, Option<PortType>)> = IndexMap::new();
        if let Some(d) = sub.get(INPUTS) {
            match d.as_map() {
                Some(entries) => {
                    for (ik, iv) in entries {
                        let ty = iv.as_str().and_then(port_type);
                        if ty.is_none() {
                            self.diags.error_help(
                                Some(&iv.span),
                                format!("input `{}` needs a port type", ik.name),
                                "one of: time series, frf, receptance set, modal model, beam model, substructure, lobes, table, scalar",
                            );
                        }
                        if own_steps.iter().any(|s| s == INPUTS) {
                            self.diags
                                .error(Some(&ik.span), "a recipe with `inputs` cannot also have a step named `inputs`");
                        }
                        inputs.insert(ik.name.clone(), (ik.span.clone(), ty));
                    }
                }
                None => self.diags.error_help(
                    Some(&d.span),
                    "`inputs` must map input names to port types",
                    "write `inputs: { frf: frf }`",
                ),
            }
        }

        Declared { params: declared, inputs }
    }

    /// What the running step gives the recipe: parameters set and swept, and inputs bound,
    /// each to something the recipe declares.
    fn given(&mut self, k: &Key, step: &Raw, sub: &SubRecipe, declared: &Declared) -> Given {
        let name = &k.name;
        let written = &sub.written;
        let Declared { params: declared, inputs } = declared;
        // The step's bindings, each to something declared.
        let mut bound: IndexMap<String, Raw> = IndexMap::new();
        let mut swept: IndexMap<String, (Span, Raw)> = IndexMap::new();
        for (section, sweep) in [("params", false), ("sweep", true)] {
            let Some(given) = step.get(section) else { continue };
            let Some(entries) = given.as_map() else {
                self.diags.error(
                    Some(&given.span),
                    format!("`{section}` of step `{name}` must map parameter names to values"),
                );
                continue;
            };
            for (pk, pv) in entries {
                let Some(default) = declared.get(&pk.name) else {
                    let msg =
                        format!("step `{name}` sets `{}`, which {written} does not declare under `params`", pk.name);
                    match suggest(&pk.name, declared.keys().map(String::as_str)) {
                        Some(s) => self.diags.error_help(Some(&pk.span), msg, format!("did you mean `{s}`?")),
                        None if declared.is_empty() => {
                            self.diags.error_help(Some(&pk.span), msg, "it declares no parameters")
                        }
                        None => self.diags.error_help(
                            Some(&pk.span),
                            msg,
                            format!("its parameters: {}", declared.keys().cloned().collect::<Vec<_>>().join(", ")),
                        ),
                    }
                    continue;
                };
                if bound.contains_key(&pk.name) || swept.contains_key(&pk.name) {
                    self.diags.error_help(
                        Some(&pk.span),
                        format!("step `{name}` both sets and sweeps `{}`", pk.name),
                        "keep one of them",
                    );
                    continue;
                }
                if sweep {
                    swept.insert(pk.name.clone(), (pk.span.clone(), pv.clone()));
                    continue;
                }
                // A quantity must keep the dimension its declaration has.
                if let (Some(d), Some(v)) = (default.scalar_text(), pv.scalar_text())
                    && let (Some(dq), Some(vq)) = (ParamQuantity::parse(&d), ParamQuantity::parse(&v))
                    && dq.dim != vq.dim
                {
                    self.diags.error_help(
                        Some(&pv.span),
                        format!(
                            "`{}` of {written} is declared as `{d}`, a {}; `{v}` is a {}",
                            pk.name,
                            dq.dim.name().unwrap_or("quantity"),
                            vq.dim.name().unwrap_or("quantity")
                        ),
                        format!("give a value in the unit of `{d}`"),
                    );
                    continue;
                }
                bound.insert(pk.name.clone(), pv.clone());
            }
        }
        let mut bindings: IndexMap<String, Raw> = IndexMap::new();
        if let Some(given) = step.get("inputs") {
            match given.as_map() {
                Some(entries) => {
                    for (ik, iv) in entries {
                        if !inputs.contains_key(&ik.name) {
                            let msg = format!(
                                "step `{name}` binds `{}`, which {written} does not declare under `inputs`",
                                ik.name
                            );
                            match suggest(&ik.name, inputs.keys().map(String::as_str)) {
                                Some(s) => self.diags.error_help(Some(&ik.span), msg, format!("did you mean `{s}`?")),
                                None => self.diags.error_help(
                                    Some(&ik.span),
                                    msg,
                                    if inputs.is_empty() {
                                        "it declares no inputs".to_string()
                                    } else {
                                        format!("its inputs: {}", inputs.keys().cloned().collect::<Vec<_>>().join(", "))
                                    },
                                ),
                            }
                            continue;
                        }
                        bindings.insert(ik.name.clone(), iv.clone());
                    }
                }
                None => self
                    .diags
                    .error(Some(&given.span), format!("`inputs` of step `{name}` must map input names to references")),
            }
        }
        for (input, (_, ty)) in inputs {
            if !bindings.contains_key(input) {
                self.diags.error_help(
                    Some(&k.span),
                    format!(
                        "step `{name}` runs {written}, which needs input `{input}`{}",
                        ty.map(|t| format!(" ({t})")).unwrap_or_default()
                    ),
                    format!("add `inputs: {{ {input}: \"@step.port\" }}`"),
                );
            }
        }

        Given { bound, swept, bindings }
    }

    /// The parameters into the recipe's steps: `$name` replaced by the value given (or the
    /// default); a swept one becomes a sweep of each step that takes it as a whole parameter.
    fn pass_parameters(&mut self, name: &str, sub: &mut SubRecipe, declared: &Declared, given: &Given) {
        let (written, shown) = (&sub.written, &sub.shown);
        let (declared, Given { bound, swept, .. }) = (&declared.params, given);
        if let Some(steps) = get_mut(&mut sub.tree, "steps").and_then(map_mut) {
            let mut swept_used: Vec<&str> = Vec::new();
            for (sk, s) in steps.iter_mut() {
                let Some(fields) = map_mut(s) else { continue };
                // (place in the running step's sweep, parameter, values)
                let mut moved: Vec<(usize, Key, Raw)> = Vec::new();
                for (fk, fv) in fields.iter_mut() {
                    if fk.name == "params"
                        && let Some(params) = map_mut(fv)
                    {
                        params.retain(|(pk, pv)| match dollar(pv).and_then(|p| swept.get_full(p)) {
                            Some((at, p, (_, values))) => {
                                swept_used.push(p.as_str());
                                moved.push((at, pk.clone(), values.clone()));
                                false
                            }
                            None => true,
                        });
                    }
                    let diags = &mut *self.diags;
                    substitute(fv, bound, declared, swept, &sk.name, shown, diags);
                }
                if moved.is_empty() {
                    continue;
                }
                let span = sk.span.clone();
                if !fields.iter().any(|(f, _)| f.name == "sweep") {
                    fields.push((key("sweep", &span), Raw { span: span.clone(), kind: RawKind::Map(Vec::new()) }));
                }
                let sweep = fields.iter_mut().find(|(f, _)| f.name == "sweep").map(|(_, v)| v).expect("just made");
                let Some(axes) = map_mut(sweep) else { continue };
                // In the order the running step sweeps them, as its labels show them.
                moved.sort_by_key(|(at, ..)| *at);
                for (_, mk, mv) in moved {
                    if axes.iter().any(|(a, _)| a.name == mk.name) {
                        self.diags.error_help(
                            Some(&mk.span),
                            format!("step `{}` sweeps `{}` itself, and `{name}` sweeps it too", sk.name, mk.name),
                            "sweep it in one place",
                        );
                        continue;
                    }
                    axes.push((mk, mv));
                }
            }
            for (p, (span, _)) in swept {
                if !swept_used.contains(&p.as_str()) {
                    self.diags.error_help(
                        Some(span),
                        format!("step `{name}` sweeps `{p}`, which no step of {written} takes as a whole parameter (`{p}: ${p}`)"),
                        "sweep a parameter that a step of the recipe uses as its own value",
                    );
                }
            }
        }
    }

    /// Reports `$name` in the recipe's entities: they are shared with the recipe that runs it.
    fn refuse_parameters_in_entities(&mut self, sub: &Raw) {
        for kind in EntityKind::ALL {
            if let Some(section) = sub.get(kind.section()) {
                let mut found = Vec::new();
                dollars(section, &mut found);
                for (p, span) in found {
                    self.diags.error_help(
                        Some(span),
                        format!("`${p}` in an entity of a recipe run as a step: its entities are shared with the recipe that runs it"),
                        "pass the value to a step parameter instead, or write it out",
                    );
                }
            }
        }
    }

    /// Expands the recipe's own libraries and the recipes it runs, and points its references
    /// to its steps under the prefix `name/`.
    fn expand_under_prefix(&mut self, name: &str, sub: &mut SubRecipe, depth: usize) {
        let (canon, shown, sub) = (sub.canon.clone(), sub.shown.clone(), &mut sub.tree);
        self.stack.push((canon, shown.clone()));
        self.merge_uses(sub, depth + 1);
        self.expand_steps(sub, depth + 1);
        self.stack.pop();
        let sub_steps: Vec<String> =
            sub.get("steps").and_then(Raw::as_map).unwrap_or(&[]).iter().map(|(s, _)| s.name.clone()).collect();
        for_each_ref(sub, &mut |v: &mut Raw| {
            if let Some((s, port)) = v.as_str().and_then(split_ref)
                && sub_steps.iter().any(|n| n == s)
            {
                v.kind = RawKind::Str(format!("@{name}/{s}.{port}"));
            }
        });
    }

    /// The recipe's steps under the prefix, each `@inputs.x` replaced by the step's binding
    /// after checking it against the port that takes it.
    fn wire_inputs(&mut self, name: &str, sub: &mut SubRecipe, declared: &Declared, given: &Given) -> Vec<(Key, Raw)> {
        let written = &sub.written;
        let (inputs, bindings) = (&declared.inputs, &given.bindings);
        let registry = self.registry;
        let mut out: Vec<(Key, Raw)> = Vec::new();
        let (_, steps) = remove(&mut sub.tree, "steps").expect("checked above");
        for (sk, mut s) in match steps.kind {
            RawKind::Map(m) => m,
            _ => Vec::new(),
        } {
            let kind = s.get("kind").and_then(Raw::as_str).map(str::to_string);
            if let Some(ins) = get_mut(&mut s, "inputs").and_then(map_mut) {
                for (port, v) in ins.iter_mut() {
                    let Some((INPUTS, input)) = v.as_str().and_then(split_ref) else { continue };
                    let input = input.to_string();
                    let Some((_, declared_ty)) = inputs.get(&input) else {
                        self.diags.error_help(
                            Some(&v.span),
                            format!("`@inputs.{input}`: {written} declares no input `{input}`"),
                            "declare it under `inputs:` with its port type",
                        );
                        continue;
                    };
                    let takes = kind
                        .as_deref()
                        .and_then(|k| registry.get(k))
                        .and_then(|n| n.spec().input(&port.name).map(|p| p.ty));
                    if let (Some(want), Some(takes)) = (declared_ty, takes)
                        && *want != takes
                    {
                        self.diags.error_help(
                            Some(&v.span),
                            format!(
                                "input `{input}` is declared a {want}, but `{}` of step `{}` takes a {takes}",
                                port.name, sk.name
                            ),
                            format!("declare `{input}: {takes}`"),
                        );
                        continue;
                    }
                    if let Some(b) = bindings.get(&input) {
                        *v = b.clone();
                    }
                }
            }
            let mut nk = sk.clone();
            nk.name = format!("{name}/{}", sk.name);
            out.push((nk, s));
        }
        out
    }

    /// The recipe's exports: names for outputs of its steps (already under the prefix).
    fn exports(&mut self, name: &str, sub: &SubRecipe) -> IndexMap<String, String> {
        let SubRecipe { tree: sub, written, own_steps, .. } = sub;
        let mut exports: IndexMap<String, String> = IndexMap::new();
        if let Some(ex) = sub.get("exports") {
            match ex.as_map() {
                Some(entries) => {
                    for (ek, ev) in entries {
                        match ev.as_str().and_then(split_ref) {
                            Some((s, _)) if s.starts_with(&format!("{name}/")) => {
                                exports.insert(ek.name.clone(), ev.as_str().unwrap_or_default().to_string());
                            }
                            // A step of its own that could not be expanded: reported where it is.
                            Some((s, _)) if own_steps.iter().any(|o| o == s) => {}
                            Some((s, _)) => self.diags.error_help(
                                Some(&ev.span),
                                format!("export `{}` names `{s}`, which is not a step of {written}", ek.name),
                                format!("its steps: {}", own_steps.join(", ")),
                            ),
                            None => self.diags.error_help(
                                Some(&ev.span),
                                format!("export `{}` must be a reference", ek.name),
                                "write `name: \"@step.port\"`",
                            ),
                        }
                    }
                }
                None => self.diags.error_help(
                    Some(&ex.span),
                    "`exports` must map names to step outputs",
                    "write `exports: { frf: \"@estimate.frf\" }`",
                ),
            }
        }
        exports
    }
}

/// Replaces every `$name` in `raw` by the value the step binds (or the declared default);
/// a swept parameter is only taken whole (moved to a sweep before this runs).
fn substitute(
    raw: &mut Raw,
    bound: &IndexMap<String, Raw>,
    declared: &IndexMap<String, Raw>,
    swept: &IndexMap<String, (Span, Raw)>,
    step: &str,
    file: &str,
    diags: &mut Diagnostics,
) {
    if let Some(p) = dollar(raw).map(str::to_string) {
        if swept.contains_key(&p) {
            diags.error_help(
                Some(&raw.span),
                format!("`${p}` is swept by the step that runs {file}, but step `{step}` uses it inside a value"),
                format!("a swept parameter must be a whole step parameter: `name: ${p}`"),
            );
        } else if let Some(v) = bound.get(&p).or(declared.get(&p)) {
            *raw = v.clone();
        } else {
            let help = match suggest(&p, declared.keys().map(String::as_str)) {
                Some(s) => format!("did you mean `${s}`?"),
                None => format!("declare it under `params:` in {file}"),
            };
            diags.error_help(Some(&raw.span), format!("unknown parameter `${p}`"), help);
        }
        return;
    }
    match &mut raw.kind {
        RawKind::Seq(items) => items.iter_mut().for_each(|i| substitute(i, bound, declared, swept, step, file, diags)),
        RawKind::Map(entries) => {
            entries.iter_mut().for_each(|(_, v)| substitute(v, bound, declared, swept, step, file, diags))
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rhai_value_is_in_the_folder_of_its_script() {
        assert_eq!(source_folder("scripts/x.rhai (at steps.hit.params)"), PathBuf::from("scripts"));
        assert_eq!(source_folder("scripts/lib/a.yaml"), PathBuf::from("scripts/lib"));
        assert_eq!(source_folder("a.yaml"), PathBuf::from(""));
    }

    #[test]
    fn paths_are_normalised_by_name() {
        assert_eq!(normalize(Path::new("a/./b/../c.yaml")), PathBuf::from("a/c.yaml"));
        assert_eq!(normalize(Path::new("../x.yaml")), PathBuf::from("../x.yaml"));
    }

    #[test]
    fn port_types_read_as_written() {
        assert_eq!(port_type("frf"), Some(PortType::Frf));
        assert_eq!(port_type("time series"), Some(PortType::TimeSeries));
        assert_eq!(port_type("receptance_set"), Some(PortType::ReceptanceSet));
        assert_eq!(port_type("2x2 receptance set"), Some(PortType::ReceptanceSet));
        assert_eq!(port_type("frf_set"), Some(PortType::FrfSet));
        assert_eq!(port_type("frff"), None);
    }
}
