//! The `spindlelab` command: check, plan, draw and run recipes; list node kinds; print the schema.

use clap::{Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use spindlelab::engine::exec::{RunOptions, plan};
use spindlelab::engine::{self, CompileError, Compiled, RunError};
use spindlelab::plugins::Plugins;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

/// mimalloc keeps freed memory for reuse: glibc's allocator returns large blocks (a sweep's
/// records, a coupling's 10,000 lines) to the system on every free and faults them in again.
#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Exit code for bad input: a recipe with errors, or a node that rejected its data.
const EXIT_BAD_INPUT: u8 = 2;
/// Exit code for a failure of the machine (a file that cannot be written).
const EXIT_FAILURE: u8 = 1;

/// Set once writing to standard output has failed (a full disk behind `>`): the failure is
/// said once, and the command ends with [`EXIT_FAILURE`].
static STDOUT_FAILED: AtomicBool = AtomicBool::new(false);

/// Writes `text` to standard output, flushed. A write that fails is said once on stderr and
/// sets the exit code, instead of a panic; a closed pipe has ended the process before (by
/// its signal), as it should.
fn emit(text: &str) {
    use std::io::Write;
    if STDOUT_FAILED.load(Ordering::Relaxed) {
        return;
    }
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        STDOUT_FAILED.store(true, Ordering::Relaxed);
        let _ = writeln!(std::io::stderr(), "error: cannot write to standard output: {e}");
    }
}

/// `print!` through [`emit`].
macro_rules! out {
    ($($arg:tt)*) => { emit(&format!($($arg)*)) };
}

/// `eprint!` that never panics: with standard error gone (closed, or a full disk) there is
/// nowhere left to say anything, and the exit code still tells.
macro_rules! eout {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stderr(), $($arg)*);
    }};
}

/// `eprintln!` that never panics (see [`eout!`]).
macro_rules! eoutln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

/// `println!` through [`emit`].
macro_rules! outln {
    ($($arg:tt)*) => { emit(&format!("{}\n", format_args!($($arg)*))) };
}

/// A document of many lines that quotes foreign words (a graph, a diagnosis): every control
/// character but its line breaks escaped.
fn esc_lines(text: &str) -> String {
    text.split('\n').map(engine::diag::escape_controls).collect::<Vec<_>>().join("\n")
}

/// Text that may hold foreign words (a recipe's, a data file's, a plugin's) as the terminal
/// may show it: control characters escaped, the lines of a node error's notes kept.
fn esc(text: impl std::fmt::Display) -> String {
    engine::diag::escape_message(&text.to_string()).into_owned()
}

#[derive(Parser)]
#[command(
    name = "spindlelab",
    version,
    about = "Spindle-dynamics experiments as recipes: compiled to a typed dataflow graph and run end to end."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// A plugin to load (its `.plugin.json` manifest), or a folder to search for the
    /// plugins a recipe names (repeatable). `$SPINDLELAB_PLUGIN_PATH` and the user plugin
    /// folder are searched after these.
    #[arg(long = "plugin", global = true, value_name = "FILE|DIR")]
    plugin: Vec<PathBuf>,
    /// Refuse data files named outside the recipe's folder (an absolute path, or `..`), for
    /// recipes from elsewhere. Without it a data file is read wherever it is named, and the
    /// manifest records each with its hash.
    #[arg(long, global = true)]
    confine: bool,
}

/// `--confine`, set once from the command line before any recipe is compiled.
static CONFINE: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

#[derive(Subcommand)]
enum Command {
    /// Compile and run a recipe, writing its outputs and a run manifest.
    Run {
        /// Recipe file (`.yaml` or `.rhai`).
        recipe: PathBuf,
        /// Output directory (default: `out/<recipe name>`).
        #[arg(short, long)]
        out: Option<PathBuf>,
        /// Keep running independent nodes after one fails, and write the outputs that succeeded.
        #[arg(long)]
        keep_going: bool,
        /// Neither read nor write the cache.
        #[arg(long)]
        no_cache: bool,
        /// Worker threads (default: one per core). Results do not depend on it.
        #[arg(long, short = 'j')]
        threads: Option<usize>,
        /// Print nothing but errors.
        #[arg(long, short)]
        quiet: bool,
        /// Print every output of every node instance, not just the short summary.
        #[arg(long, short, conflicts_with = "quiet")]
        verbose: bool,
        /// Set a declared parameter, e.g. `--set kt=3e8N/m` (repeatable).
        #[arg(long = "set", value_name = "NAME=VALUE", value_parser = parse_set)]
        set: Vec<(String, String)>,
        /// Run the recipe as written, without its `fit:` block.
        #[arg(long)]
        no_fit: bool,
        /// Also write `report.html`: the recipe, its graph, every plot, the small tables,
        /// warnings and the manifest in one self-contained file.
        #[arg(long)]
        report: bool,
    },
    /// Write the HTML report of a finished run (or a diagnosis) from its output folder.
    Report {
        /// The run's output folder (it holds `manifest.json`), or a diagnosis folder.
        run_dir: PathBuf,
        /// Where to write the report (default: `<folder>.report.html` beside the folder).
        #[arg(short, long)]
        out: Option<PathBuf>,
    },
    /// Check a recipe: report every problem, run nothing.
    Check {
        /// Recipe file (`.yaml` or `.rhai`).
        recipe: PathBuf,
        /// Set a declared parameter, e.g. `--set kt=3e8N/m` (repeatable).
        #[arg(long = "set", value_name = "NAME=VALUE", value_parser = parse_set)]
        set: Vec<(String, String)>,
    },
    /// Dry run: which nodes would run and why, and which come from the cache.
    Plan {
        /// Recipe file (`.yaml` or `.rhai`).
        recipe: PathBuf,
        /// Output directory whose cache and manifest to compare with (default: `out/<recipe name>`).
        #[arg(short, long)]
        out: Option<PathBuf>,
        /// Plan as if the cache were empty.
        #[arg(long)]
        no_cache: bool,
        /// Set a declared parameter, e.g. `--set kt=3e8N/m` (repeatable).
        #[arg(long = "set", value_name = "NAME=VALUE", value_parser = parse_set)]
        set: Vec<(String, String)>,
    },
    /// Draw the compiled graph (Graphviz DOT or Mermaid).
    Graph {
        /// Recipe file (`.yaml` or `.rhai`).
        recipe: PathBuf,
        /// Output format.
        #[arg(long, short, value_enum, default_value_t = GraphFormat::Dot)]
        format: GraphFormat,
    },
    /// List every node kind with its ports, parameters, units and description.
    Nodes {
        /// Show one kind only.
        kind: Option<String>,
    },
    /// Print the JSON Schema of the YAML recipe (for editors with a YAML language server).
    Schema,
    /// See and bound the cache of output folders: `du`, `gc`, `clean`.
    Cache {
        #[command(subcommand)]
        action: CacheAction,
    },
    /// Make, build and check WebAssembly plugins (third-party node kinds).
    Plugin {
        #[command(subcommand)]
        action: PluginAction,
    },
    /// Write the recipe of a baseline case file (`case.json`): entities, the measured files
    /// as a measurement set, the measured and the cutting configuration.
    Import {
        /// The case file.
        case: PathBuf,
        /// Where to write the recipe (default: print it); it names the case's data files from
        /// its own folder (from the current folder when printed).
        #[arg(short, long)]
        out: Option<PathBuf>,
        /// Write the case's entities (materials, spindle, holder and tool, sensor, cutting
        /// setup) to this library file, and a recipe that takes them with `use:`.
        #[arg(long, value_name = "FILE")]
        library: Option<PathBuf>,
    },
    /// Find where the recipe's model and its measurements disagree, name the missing physical
    /// effect, add it and show the gap shrink: writes `diagnosis.json`, `diagnosis.md` and
    /// `diagnosed.yaml`.
    Diagnose {
        /// A YAML recipe that declares its measurements and compares them (`frf.gap`).
        recipe: PathBuf,
        /// Output directory (default: `out/<recipe name>/diagnosis`).
        #[arg(short, long)]
        out: Option<PathBuf>,
        /// Print nothing but errors.
        #[arg(short, long)]
        quiet: bool,
    },
}

#[derive(Subcommand)]
enum CacheAction {
    /// Show the size of each output folder's cache.
    Du {
        /// Output folders (default: every folder under `out/`).
        folders: Vec<PathBuf>,
    },
    /// Remove the entries that neither the latest run of the folder nor the one before used.
    Gc {
        /// Output folders (default: every folder under `out/`).
        folders: Vec<PathBuf>,
    },
    /// Remove the whole cache of each folder (the outputs stay).
    Clean {
        /// Output folders (default: every folder under `out/`).
        folders: Vec<PathBuf>,
    },
}

#[derive(Subcommand)]
enum PluginAction {
    /// Check a plugin without running a recipe: manifest, hash, imports, interface version,
    /// its description of its node kinds; lists the kinds.
    Check {
        /// The plugin's manifest (`NAME.plugin.json`).
        manifest: PathBuf,
    },
    /// Create a plugin crate from the template: one node kind, ready to build.
    New {
        /// Plugin id (letters, digits, `-`); the crate's name.
        name: String,
        /// Where to create the crate (default: `./NAME`).
        #[arg(short, long)]
        dir: Option<PathBuf>,
    },
    /// Build a plugin crate for wasm32-unknown-unknown and pack it: the component and its
    /// manifest with the SHA-256.
    Build {
        /// The plugin crate's folder (it holds `Cargo.toml`).
        crate_dir: PathBuf,
        /// Where to put the plugin (default: the user plugin folder, so recipes find it by id).
        #[arg(short, long)]
        out: Option<PathBuf>,
        /// Cargo's target folder for the build (default: `target` in the crate's folder).
        #[arg(long)]
        target_dir: Option<PathBuf>,
    },
    /// List the plugins on the search path and their node kinds.
    List,
}

#[derive(Clone, Copy, ValueEnum)]
enum GraphFormat {
    Dot,
    Mermaid,
}

fn color() -> bool {
    std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none()
}

/// `NAME=VALUE` of `--set`.
fn parse_set(text: &str) -> Result<(String, String), String> {
    match text.split_once('=') {
        Some((n, v)) if !n.trim().is_empty() && !v.trim().is_empty() => {
            Ok((n.trim().to_string(), v.trim().to_string()))
        }
        _ => Err(format!("`{text}` is not NAME=VALUE (e.g. `kt=3e8N/m`)")),
    }
}

fn compile(path: &Path, registry: &mut engine::node::Registry, plugins: &mut Plugins) -> Result<Compiled, ExitCode> {
    compile_with(path, &[], registry, plugins)
}

/// Compiles a recipe, loading the plugins it names into `registry` first.
fn compile_with(
    path: &Path,
    set: &[(String, String)],
    registry: &mut engine::node::Registry,
    plugins: &mut Plugins,
) -> Result<Compiled, ExitCode> {
    let compiled = spindlelab::plugins::compile_file(path, set, registry, plugins)
        .and_then(|c| if CONFINE.load(Ordering::Relaxed) { engine::check_confined(&c).map(|()| c) } else { Ok(c) });
    match compiled {
        Ok(c) => {
            if !c.warnings.is_empty() {
                eout!("{}", c.warnings.render(&c.sources, color()));
            }
            Ok(c)
        }
        Err(CompileError { diagnostics, sources }) => {
            eout!("{}", diagnostics.render(&sources, color()));
            Err(ExitCode::from(EXIT_BAD_INPUT))
        }
    }
}

fn default_out(c: &Compiled) -> PathBuf {
    PathBuf::from("out").join(engine::model::slug(&c.recipe.name))
}

/// The most worker threads a run starts, whatever `-j` asks: more than a few per core only
/// costs memory (each thread reserves a stack).
fn clamp_threads(asked: Option<usize>) -> Option<usize> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let most = (8 * cores).min(256);
    asked.map(|n| {
        let used = n.clamp(1, most);
        if used != n {
            eoutln!("warning: -j {n} is outside 1..={most} for this machine's {cores} core(s); using {used}");
        }
        used
    })
}

fn main() -> ExitCode {
    // Output into a closed pipe (`spindlelab nodes | head -1`) ends the process quietly, as
    // for any Unix filter, instead of a panic in `println!`.
    #[cfg(unix)]
    // SAFETY: restoring the default action of one signal before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        // `--help` and `--version` go to standard output like any other output of ours, so a
        // full disk behind `>` is said; usage errors go to stderr with clap's exit code (2).
        Err(e) if !e.use_stderr() && !std::io::stdout().is_terminal() => {
            out!("{}", e.render());
            return if STDOUT_FAILED.load(Ordering::Relaxed) {
                ExitCode::from(EXIT_FAILURE)
            } else {
                ExitCode::SUCCESS
            };
        }
        Err(e) => e.exit(),
    };
    CONFINE.store(cli.confine, Ordering::Relaxed);
    let code = command(cli);
    if STDOUT_FAILED.load(Ordering::Relaxed) { ExitCode::from(EXIT_FAILURE) } else { code }
}

/// Runs one command of the command line.
fn command(cli: Cli) -> ExitCode {
    let mut registry = spindlelab::registry();
    let mut plugins = Plugins::new(&cli.plugin);
    match cli.command {
        Command::Check { recipe, set } => match compile_with(&recipe, &set, &mut registry, &mut plugins) {
            Ok(c) if c.recipe.library => {
                let r = &c.recipe;
                let counts: Vec<String> = [
                    (r.materials.len(), "material", "materials"),
                    (r.machines.len(), "machine", "machines"),
                    (r.assemblies.len(), "assembly", "assemblies"),
                    (r.sensors.len(), "sensor", "sensors"),
                    (r.cutting.len(), "cutting setup", "cutting setups"),
                ]
                .iter()
                .filter(|(n, ..)| *n > 0)
                .map(|(n, one, many)| format!("{n} {}", if *n == 1 { one } else { many }))
                .collect();
                outln!(
                    "{}: ok — library of {}",
                    recipe.display(),
                    if counts.is_empty() { "nothing".into() } else { counts.join(", ") }
                );
                ExitCode::SUCCESS
            }
            Ok(c) => {
                outln!(
                    "{}: ok — {} steps, {} node instances, {} outputs",
                    recipe.display(),
                    c.recipe.steps.len(),
                    c.graph.instances.len(),
                    c.recipe.outputs.len()
                );
                ExitCode::SUCCESS
            }
            Err(code) => code,
        },
        Command::Graph { recipe, format } => match compile(&recipe, &mut registry, &mut plugins) {
            Ok(c) => {
                let text = match format {
                    GraphFormat::Dot => engine::graph::to_dot(&c.graph),
                    GraphFormat::Mermaid => engine::graph::to_mermaid(&c.graph),
                };
                out!("{}", esc_lines(&text));
                ExitCode::SUCCESS
            }
            Err(code) => code,
        },
        Command::Plan { recipe, out, no_cache, set } => {
            match compile_with(&recipe, &set, &mut registry, &mut plugins) {
                Ok(c) => {
                    let out = out.unwrap_or_else(|| default_out(&c));
                    let opts = RunOptions::new(&out);
                    let cache = (!no_cache).then(|| opts.cache());
                    let entries = plan(&c.recipe, &c.graph, &registry, &out, cache.as_ref());
                    let width = entries.iter().map(|e| e.id.len()).max().unwrap_or(0);
                    for e in &entries {
                        outln!("{:width$}  {:18}  {}", esc(&e.id), e.kind, esc(&e.reason));
                    }
                    use engine::exec::PlanReason;
                    let count = |r: fn(&PlanReason) -> bool| entries.iter().filter(|e| r(&e.reason)).count();
                    let cached = count(|r| *r == PlanReason::Cached);
                    let skipped = count(|r| *r == PlanReason::NotNeeded);
                    let skip = if skipped > 0 { format!(", {skipped} not needed") } else { String::new() };
                    outln!(
                        "{} to run, {} from cache{skip} (output directory {})",
                        entries.len() - cached - skipped,
                        cached,
                        out.display()
                    );
                    ExitCode::SUCCESS
                }
                Err(code) => code,
            }
        }
        Command::Nodes { kind } => {
            if let Err(e) = plugins.load_always(&mut registry) {
                eoutln!("error: {}", esc(&e));
                return ExitCode::from(EXIT_BAD_INPUT);
            }
            for (manifest, e) in plugins.load_search_path(&mut registry).1 {
                eoutln!("warning: {}: {}", esc(manifest.display()), esc(&e));
            }
            let mut any = false;
            for node in registry.kinds() {
                let spec = node.spec();
                if kind.as_deref().is_some_and(|k| k != spec.kind) {
                    continue;
                }
                any = true;
                out!("{}", describe_node(spec, node.effect()));
            }
            if !any {
                let k = kind.unwrap_or_default();
                let hint = engine::spec::suggest(&k, registry.names())
                    .map(|s| format!(" (did you mean `{s}`?)"))
                    .unwrap_or_default();
                eoutln!("error: unknown node kind `{}`{hint}", esc(&k));
                return ExitCode::from(EXIT_BAD_INPUT);
            }
            ExitCode::SUCCESS
        }
        Command::Diagnose { recipe, out, quiet } => {
            // Loads the plugins the recipe names, so the diagnosis compiles it with them.
            let compiled = match compile(&recipe, &mut registry, &mut plugins) {
                Ok(c) => c,
                Err(code) => return code,
            };
            let d = match spindlelab::diagnose::diagnose(&recipe, &registry) {
                Ok(d) => d,
                Err(spindlelab::diagnose::DiagnoseError::Output(e)) if !e.is_bad_input() => {
                    eoutln!("error: {}", esc(&e));
                    return ExitCode::from(EXIT_FAILURE);
                }
                Err(e) => {
                    eoutln!("error: {}", esc(&e));
                    return ExitCode::from(EXIT_BAD_INPUT);
                }
            };
            // Beside the run's outputs: `out/<recipe name>/diagnosis`, as `run` names its folder.
            let out = out.unwrap_or_else(|| default_out(&compiled).join("diagnosis"));
            if let Err(e) = spindlelab::diagnose::write(&d, &out) {
                eoutln!("error: {}", esc(&e));
                let bad = matches!(&e, spindlelab::diagnose::DiagnoseError::Output(c) if c.is_bad_input());
                return ExitCode::from(if bad { EXIT_BAD_INPUT } else { EXIT_FAILURE });
            }
            if !quiet {
                out!("{}", esc_lines(&spindlelab::diagnose::markdown(&d)));
                outln!(
                    "\nwrote diagnosis.json, diagnosis.md and diagnosed.yaml to {} in {:.1} s",
                    out.display(),
                    d.seconds
                );
            }
            ExitCode::SUCCESS
        }
        Command::Import { case, out, library } => {
            let shown = case.display().to_string();
            let text = match std::fs::read_to_string(&case) {
                Ok(t) => t,
                Err(e) => {
                    eoutln!("error: cannot read {}: {e}", esc(&shown));
                    return ExitCode::from(EXIT_BAD_INPUT);
                }
            };
            // The recipe names the case's data files from its own folder (the current one when
            // it is printed).
            let recipe_dir = out.as_deref().and_then(Path::parent).unwrap_or(Path::new(""));
            let folder =
                |p: &'_ Path| if p.as_os_str().is_empty() { Path::new(".").to_path_buf() } else { p.to_path_buf() };
            let (case_dir, recipe_folder) = (folder(case.parent().unwrap_or(Path::new(""))), folder(recipe_dir));
            let placement = spindlelab::import::Placement { case_dir: &case_dir, recipe_dir: &recipe_folder };
            let imported = match &library {
                None => spindlelab::import::recipe_from_case_at(&text, &shown, placement).map(|r| (None, r)),
                Some(lib) => {
                    let use_path = relative_to(lib, recipe_dir);
                    spindlelab::import::library_from_case(&text, &shown, &use_path, Some(placement))
                        .map(|(l, r)| (Some(l), r))
                }
            };
            let (library_text, recipe) = match imported {
                Ok(r) => r,
                Err(e) => {
                    eoutln!("error: {}", esc(&e));
                    return ExitCode::from(EXIT_BAD_INPUT);
                }
            };
            // Each file is written whole to a temporary name first, and both are renamed into
            // place only when both are written; a folder named that does not exist yet is made.
            let stage = |path: &Path, text: &str| {
                let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
                std::fs::create_dir_all(dir).and_then(|()| tempfile::NamedTempFile::new_in(dir)).and_then(|mut tmp| {
                    std::io::Write::write_all(&mut tmp, text.as_bytes())?;
                    Ok(tmp)
                })
            };
            let mut staged = Vec::new();
            for (path, text) in [(library.as_ref(), library_text.as_deref()), (out.as_ref(), Some(recipe.as_str()))] {
                let (Some(path), Some(text)) = (path, text) else { continue };
                match stage(path, text) {
                    Ok(tmp) => staged.push((path.clone(), tmp)),
                    Err(e) => {
                        eoutln!("error: cannot write {}: {e}", path.display());
                        return ExitCode::from(EXIT_FAILURE);
                    }
                }
            }
            for (path, tmp) in staged {
                if let Err(e) = tmp.persist(&path) {
                    eoutln!("error: cannot write {}: {}", path.display(), e.error);
                    return ExitCode::from(EXIT_FAILURE);
                }
            }
            if out.is_none() {
                out!("{recipe}");
            }
            ExitCode::SUCCESS
        }
        Command::Cache { action } => cache_command(action),
        Command::Plugin { action } => plugin_command(action, &mut plugins),
        Command::Schema => {
            outln!(
                "{}",
                serde_json::to_string_pretty(&engine::schema::recipe_schema(&registry)).expect("schema serialises")
            );
            ExitCode::SUCCESS
        }
        Command::Report { run_dir, out } => report_command(&run_dir, out),
        Command::Run { recipe, out, keep_going, no_cache, threads, quiet, verbose, set, no_fit, report } => {
            let threads = clamp_threads(threads);
            let mut c = match compile_with(&recipe, &set, &mut registry, &mut plugins) {
                Ok(c) if c.recipe.library => {
                    let mut d = engine::diag::Diagnostics::new();
                    d.error_help(
                        Some(&c.raw.span),
                        "the recipe has no `steps`: it holds entities only, which makes it a library, and a library has nothing to run",
                        format!(
                            "add `steps:` with at least one analysis step, or take its entities into a recipe with `use: [{}]`",
                            recipe.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
                        ),
                    );
                    eout!("{}", d.render(&c.sources, color()));
                    return ExitCode::from(EXIT_BAD_INPUT);
                }
                Ok(c) => c,
                Err(code) => return code,
            };
            let out = out.unwrap_or_else(|| default_out(&c));
            let mut fitted = None;
            if c.recipe.fit.is_some() && !no_fit {
                let report = match spindlelab::fit::fit(&c, &set, &registry, threads) {
                    Ok(r) => r,
                    Err(e) => {
                        eoutln!("error: fit: {}", esc(&e));
                        return ExitCode::from(EXIT_BAD_INPUT);
                    }
                };
                if !quiet {
                    out!("{}", spindlelab::summary::fit_summary(&report));
                }
                // The run that writes the outputs is the recipe with the fitted values.
                let mut with_fit: Vec<(String, String)> =
                    set.iter().filter(|(n, _)| !report.params.iter().any(|p| &p.name == n)).cloned().collect();
                with_fit.extend(report.overrides());
                c = match compile_with(&recipe, &with_fit, &mut registry, &mut plugins) {
                    Ok(c) => c,
                    Err(code) => return code,
                };
                fitted = Some(report);
            }
            let opts = RunOptions {
                use_cache: !no_cache,
                keep_going,
                threads,
                release_consumed: true,
                extra_files: fitted.as_ref().map(|r| spindlelab::fit::fit_files(&c, r)).unwrap_or_default(),
                report,
                renderer: Some(spindlelab::renderer()),
                ..RunOptions::new(out.clone())
            };
            let bar = if std::io::stderr().is_terminal() && !quiet {
                let b = ProgressBar::new(c.graph.instances.len() as u64);
                b.set_style(ProgressStyle::with_template("{bar:30} {pos}/{len} {wide_msg}").expect("template"));
                b
            } else {
                ProgressBar::hidden()
            };
            let progress = |_: usize, id: &str| {
                bar.inc(1);
                bar.set_message(esc(id));
            };
            let outcome = engine::run(&c, &registry, &opts, &progress);
            bar.finish_and_clear();
            let notes = match &outcome {
                Ok(r) => &r.manifest.notes[..],
                Err(RunError::NodesFailed { report, .. }) => &report.manifest.notes[..],
                Err(_) => &[],
            };
            for n in notes {
                eoutln!("warning: {}", esc(n));
            }
            if let Some(report) = fitted.as_ref().filter(|r| !r.converged) {
                eoutln!(
                    "warning: the fit did not converge in {} evaluations; the outputs use its best point (raise `max_evaluations` or narrow the bounds)",
                    report.evaluations
                );
            }
            match outcome {
                Ok(report) => {
                    if verbose {
                        out!("{}", spindlelab::summary::summarize(&c, &report.result));
                    } else if !quiet {
                        out!("{}", spindlelab::summary::short(&c, &report.result));
                    }
                    if !quiet {
                        outln!(
                            "{} computed, {} from cache in {:.3} s; wrote {} file(s) and manifest.json to {}",
                            report.manifest.computed,
                            report.manifest.cache_hits,
                            report.result.seconds,
                            report.written.len(),
                            out.display()
                        );
                    }
                    ExitCode::SUCCESS
                }
                Err(RunError::NodesFailed { failures, report }) => {
                    for (id, e) in &failures {
                        let at = c
                            .graph
                            .instances
                            .iter()
                            .find(|i| &i.id == id)
                            .and_then(|i| c.recipe.step(&i.step))
                            .map(|s| format!("\n --> {} (step `{}`)", esc(&s.span), s.id))
                            .unwrap_or_default();
                        eoutln!("error: node `{}` failed: {}{at}", esc(id), esc(e));
                    }
                    {
                        let r = report;
                        eoutln!(
                            "{} instance(s) computed and cached; {}",
                            r.manifest.computed,
                            if r.written.is_empty() && keep_going {
                                "every output depended on the failures, so none was written".to_string()
                            } else if r.written.is_empty() {
                                "no outputs written (use --keep-going to write those that succeeded)".to_string()
                            } else if r.manifest.partial.is_empty() {
                                format!("wrote {} file(s) that did not depend on the failure", r.written.len())
                            } else {
                                let partial: Vec<String> = r
                                    .manifest
                                    .partial
                                    .iter()
                                    .map(|(file, m)| format!("{} (without {} sweep point(s))", esc(file), m.len()))
                                    .collect();
                                format!(
                                    "wrote {} file(s); {} lack the failed sweep points, which they and manifest.json list",
                                    r.written.len(),
                                    partial.join(", ")
                                )
                            }
                        );
                    }
                    ExitCode::from(EXIT_BAD_INPUT)
                }
                Err(RunError::Output(e)) => {
                    eoutln!("error: {}", esc(&e));
                    ExitCode::from(if e.is_bad_input() { EXIT_BAD_INPUT } else { EXIT_FAILURE })
                }
                Err(e @ RunError::NoRenderer(_)) => {
                    eoutln!("error: {}", esc(&e));
                    ExitCode::from(EXIT_FAILURE)
                }
            }
        }
    }
}

/// How a file at `path` is named from the folder `dir`: relative when it lies in or below
/// it (both taken from the current folder), else its absolute path.
fn relative_to(path: &Path, dir: &Path) -> String {
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let (p, d) = (abs(path), abs(if dir.as_os_str().is_empty() { Path::new(".") } else { dir }));
    let norm =
        |p: PathBuf| -> PathBuf { p.components().filter(|c| !matches!(c, std::path::Component::CurDir)).collect() };
    match norm(p.clone()).strip_prefix(norm(d)) {
        Ok(rel) => rel.display().to_string(),
        Err(_) => p.display().to_string(),
    }
}

/// `spindlelab report RUN_DIR`: the HTML report of a finished run, from its manifest and the
/// files the manifest lists (each read through the data-file cap).
fn report_command(run_dir: &Path, out: Option<PathBuf>) -> ExitCode {
    let target_for = |out: Option<PathBuf>| out.unwrap_or_else(|| report_beside(run_dir));
    // A diagnosis folder: its page and pictures.
    if run_dir.join("diagnosis.md").is_file() && run_dir.join("diagnosis.json").is_file() {
        return match spindlelab::diagnose::report_html(run_dir) {
            Ok(html) => write_report(&target_for(out), html),
            Err(e) => {
                eoutln!("error: {}; rerun `spindlelab diagnose` into that folder", esc(&e));
                ExitCode::from(EXIT_BAD_INPUT)
            }
        };
    }
    let Some(manifest) = engine::exec::Manifest::read(run_dir) else {
        eoutln!(
            "error: {} holds no readable manifest.json; give the output folder of a run (`spindlelab run` writes it) or of a diagnosis (`spindlelab diagnose`)",
            run_dir.display()
        );
        return ExitCode::from(EXIT_BAD_INPUT);
    };
    let mut files = Vec::new();
    for name in manifest.files.keys() {
        if name == engine::render::REPORT_FILE || name.starts_with('.') || name.contains("..") {
            continue;
        }
        match engine::formats::read_capped(&run_dir.join(name), engine::formats::MAX_DATA_BYTES) {
            Ok(bytes) => files.push((name.clone(), bytes)),
            Err(e) => {
                eoutln!(
                    "error: {}: {e}; the folder no longer matches its manifest (rerun the recipe)",
                    run_dir.join(name).display()
                );
                return ExitCode::from(EXIT_BAD_INPUT);
            }
        }
    }
    let text = (!manifest.recipe_text.is_empty()).then_some(manifest.recipe_text.as_str());
    let html = spindlelab::render::report::html(&manifest, text, &files);
    write_report(&target_for(out), html)
}

/// Where `report DIR` writes by default: `DIR.report.html` beside the folder, as a plain path
/// (`out/x` gives `out/x.report.html`); a folder named `.` or `..` is resolved first.
fn report_beside(run_dir: &Path) -> PathBuf {
    let dir = match run_dir.file_name() {
        Some(_) => Some(run_dir.to_path_buf()),
        None => run_dir.canonicalize().ok(),
    };
    match dir.as_deref().and_then(|d| Some((d.parent()?, d.file_name()?))) {
        Some((parent, name)) => parent.join(format!("{}.report.html", name.to_string_lossy())),
        None => run_dir.join("..").join("run.report.html"),
    }
}

/// Writes a report page whole (a temporary file renamed into place).
fn write_report(target: &Path, html: String) -> ExitCode {
    let tmp = target.with_extension("html.tmp");
    if let Err(e) = std::fs::write(&tmp, html).and_then(|_| std::fs::rename(&tmp, target)) {
        let _ = std::fs::remove_file(&tmp);
        eoutln!("error: cannot write {}: {e}", target.display());
        return ExitCode::from(EXIT_FAILURE);
    }
    outln!("wrote {}", target.display());
    ExitCode::SUCCESS
}

/// The output folders a `cache` command acts on: those named, or every folder under `out/`
/// that has a cache.
fn cache_folders(named: Vec<PathBuf>) -> Vec<PathBuf> {
    if !named.is_empty() {
        return named;
    }
    let mut found: Vec<PathBuf> = std::fs::read_dir("out")
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| engine::exec::cache_dir(p).is_dir())
        .collect();
    found.sort();
    found
}

fn human_bytes(b: u64) -> String {
    match b {
        b if b >= 1 << 30 => format!("{:.1} GiB", b as f64 / (1u64 << 30) as f64),
        b if b >= 1 << 20 => format!("{:.1} MiB", b as f64 / (1u64 << 20) as f64),
        b if b >= 1 << 10 => format!("{:.1} KiB", b as f64 / 1024.0),
        b => format!("{b} B"),
    }
}

fn cache_command(action: CacheAction) -> ExitCode {
    use engine::exec::{Cache, Manifest, OutputDir, commit::META_DIR};
    let (folders, verb) = match action {
        CacheAction::Du { folders } => (cache_folders(folders), "du"),
        CacheAction::Gc { folders } => (cache_folders(folders), "gc"),
        CacheAction::Clean { folders } => (cache_folders(folders), "clean"),
    };
    let mut code = ExitCode::SUCCESS;
    for folder in folders {
        let cache = Cache::new(engine::exec::cache_dir(&folder));
        if !cache.dir().is_dir() {
            outln!("{}: no cache", folder.display());
            continue;
        }
        if verb == "du" {
            let (n, bytes) = cache.usage();
            outln!("{}: {n} entries, {}", folder.display(), human_bytes(bytes));
            continue;
        }
        // Changing the cache needs the folder: not while a run uses it.
        let _held = match OutputDir::open(&folder) {
            Ok(d) => d,
            Err(e) => {
                eoutln!("error: {}", esc(&e));
                code = ExitCode::from(if e.is_bad_input() { EXIT_BAD_INPUT } else { EXIT_FAILURE });
                continue;
            }
        };
        let (n, bytes) = if verb == "clean" {
            cache.retain(|_| false)
        } else {
            let meta = folder.join(META_DIR);
            let keep: std::collections::HashSet<String> = ["current", "previous"]
                .iter()
                .filter_map(|run| Manifest::read(&meta.join(run)))
                .flat_map(|m| m.nodes.into_iter().map(|n| n.key))
                .collect();
            cache.retain(|k| keep.contains(k))
        };
        outln!("{}: removed {n} entries, {}", folder.display(), human_bytes(bytes));
    }
    code
}

fn describe_node(spec: &engine::node::NodeSpec, effect: Option<&engine::node::EffectSpec>) -> String {
    let mut s = format!("{} (version {})\n  {}\n", spec.kind, spec.version, esc(spec.description));
    if !spec.inputs.is_empty() {
        s.push_str("  inputs:\n");
        for p in &spec.inputs {
            let flags = match (p.optional, p.collect) {
                (true, true) => " (optional, collects a sweep)",
                (true, false) => " (optional)",
                (false, true) => " (collects a sweep)",
                _ => "",
            };
            s.push_str(&format!("    {:16} {}{flags} — {}\n", p.name, p.ty, esc(p.doc)));
        }
    }
    s.push_str("  outputs:\n");
    for p in &spec.outputs {
        s.push_str(&format!("    {:16} {} — {}\n", p.name, p.ty, esc(p.doc)));
    }
    if !spec.params.is_empty() {
        s.push_str("  params:\n");
        for f in &spec.params {
            let req = if f.required {
                "required".to_string()
            } else {
                f.default.map(|d| format!("default {}", esc(d))).unwrap_or_else(|| "optional".into())
            };
            s.push_str(&format!("    {:16} {} ({req}) — {}\n", f.name, esc(f.ty.describe()), esc(f.doc)));
        }
    }
    if let Some(e) = effect {
        s.push_str(&format!("  effect for the diagnosis: {} — {}\n", e.name, esc(e.description)));
        for p in &e.params {
            let scale = if p.log { ", log scale" } else { "" };
            s.push_str(&format!(
                "    {:16} absent at {:e} {u}, fitted within {:e} … {:e} {u}{scale}\n",
                p.name,
                p.absent,
                p.min,
                p.max,
                u = p.si_unit
            ));
        }
    }
    s.push('\n');
    s
}

fn plugin_command(action: PluginAction, plugins: &mut Plugins) -> ExitCode {
    use spindlelab::engine::node::Registry;
    let describe_plugin = |p: &spindlelab_plugin_host::Plugin| {
        outln!(
            "{} {} — {} (interface {}, sha256 {})",
            esc(&p.manifest.id),
            esc(&p.manifest.version),
            esc(p.manifest_path.display()),
            esc(&p.manifest.interface),
            esc(p.manifest.sha256.get(..16).unwrap_or(&p.manifest.sha256))
        );
        outln!(
            "  limits: {} MiB memory, {:.1e} fuel, {} numbers out per call",
            p.limits.memory >> 20,
            p.limits.fuel as f64,
            p.limits.output_values
        );
        for n in &p.nodes {
            let spec = engine::node::Node::spec(n.as_ref());
            outln!("  {} v{}: {}", spec.kind, spec.version, esc(spec.description));
            if let Some(e) = engine::node::Node::effect(n.as_ref()) {
                outln!("    effect for the diagnosis: {}", e.name);
            }
        }
    };
    match action {
        PluginAction::Check { manifest } => {
            // A registry of its own: a plugin that names a built-in kind is a problem to report.
            let mut registry = spindlelab::registry();
            match plugins.load(&manifest, &Default::default(), &mut registry) {
                Ok(p) => {
                    describe_plugin(&p);
                    outln!("{}: ok", manifest.display());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eoutln!("error: {}", esc(&e));
                    ExitCode::from(EXIT_BAD_INPUT)
                }
            }
        }
        PluginAction::New { name, dir } => {
            let dir = dir.unwrap_or_else(|| PathBuf::from(&name));
            match spindlelab::plugins::new_plugin(&name, &dir) {
                Ok(files) => {
                    for f in files {
                        outln!("wrote {}", f.display());
                    }
                    outln!(
                        "next: `rustup target add wasm32-unknown-unknown` once, then `spindlelab plugin build {}`",
                        dir.display()
                    );
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eoutln!("error: {}", esc(&e));
                    ExitCode::from(EXIT_BAD_INPUT)
                }
            }
        }
        PluginAction::Build { crate_dir, out, target_dir } => {
            let Some(out) = out.or_else(spindlelab::plugins::user_plugin_dir) else {
                eoutln!("error: no user plugin folder (HOME is not set); give one with --out");
                return ExitCode::from(EXIT_BAD_INPUT);
            };
            let cargo = std::env::var_os("CARGO").map(PathBuf::from).unwrap_or_else(|| PathBuf::from("cargo"));
            let target = target_dir.unwrap_or_else(|| crate_dir.join("target"));
            match spindlelab_plugin_pack::build(&cargo, &crate_dir, &target, &out, false) {
                Ok(packed) => {
                    let mut registry = Registry::new();
                    match plugins.load(&packed.manifest_path, &Default::default(), &mut registry) {
                        Ok(p) => describe_plugin(&p),
                        Err(e) => {
                            eoutln!("error: the plugin was built but does not load: {}", esc(&e));
                            return ExitCode::from(EXIT_BAD_INPUT);
                        }
                    }
                    outln!("wrote {}", packed.manifest_path.display());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eoutln!("error: {}", esc(&e));
                    ExitCode::from(EXIT_BAD_INPUT)
                }
            }
        }
        PluginAction::List => {
            let mut registry = spindlelab::registry();
            let (ok, failed) = plugins.load_search_path(&mut registry);
            for p in &ok {
                describe_plugin(p);
            }
            for (m, e) in &failed {
                eoutln!("warning: {}: {}", esc(m.display()), esc(e));
            }
            if ok.is_empty() && failed.is_empty() {
                let dirs: Vec<String> = plugins.search.iter().map(|d| d.display().to_string()).collect();
                outln!("no plugins in {}", dirs.join(", "));
            }
            ExitCode::SUCCESS
        }
    }
}
