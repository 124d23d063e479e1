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

mod cmd;
use cmd::{cache::*, crib::*, diagnose::*, export::*, import::*, plugin::*, recipe::*, report::*, run::*};

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

/// Where a run writes its outputs and which cache it reads and fills; `run`, `plan` and
/// `crib` take them alike.
#[derive(clap::Args)]
struct StoreArgs {
    /// Output directory (default: `out/<name of the recipe or catalog>`).
    #[arg(short, long)]
    out: Option<PathBuf>,
    /// Neither read nor write the cache (`plan`: plan as if it were empty).
    #[arg(long)]
    no_cache: bool,
    /// The cache folder (default: the output folder's own), e.g. on storage that several
    /// machines share.
    #[arg(long, env = "SPINDLELAB_CACHE", value_name = "DIR")]
    cache: Option<PathBuf>,
}

/// How a run works through its graph, and how much it says.
#[derive(clap::Args)]
struct WorkArgs {
    /// Worker threads (default: one per core). Results do not depend on it.
    #[arg(long, short = 'j')]
    threads: Option<usize>,
    /// Print nothing but errors.
    #[arg(long, short)]
    quiet: bool,
}

/// `--confine`, set once from the command line before any recipe is compiled.
static CONFINE: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

#[derive(Subcommand)]
enum Command {
    /// Compile and run a recipe, writing its outputs and a run manifest.
    Run {
        /// Recipe file (`.yaml` or `.rhai`).
        recipe: PathBuf,
        #[command(flatten)]
        store: StoreArgs,
        #[command(flatten)]
        work: WorkArgs,
        /// Keep running independent nodes after one fails, and write the outputs that succeeded.
        #[arg(long)]
        keep_going: bool,
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
        /// Compute only shard K of N of the graph's cacheable instances into the cache, and
        /// write no outputs; a run without `--shard` afterwards commits them
        /// (docs/scale-out.md).
        #[arg(long, value_name = "K/N")]
        shard: Option<String>,
        /// With `--shard`: only the instances of this level of the graph (the length of their
        /// longest chain of inputs), so the shards of each level need only those before.
        #[arg(long, requires = "shard")]
        level: Option<usize>,
    },
    /// Write a workflow that another engine schedules (Snakemake): shards of each level of the
    /// graph as jobs, then one that commits the outputs.
    Export {
        #[command(subcommand)]
        to: ExportTo,
    },
    /// Survey a tool-crib catalog on one machine: every (holder, tool, stickout) coupled to
    /// its spindle, its lobes and best cut, and one table of them all (docs/crib.md).
    Crib {
        /// The catalog file (`.yaml`).
        catalog: PathBuf,
        /// The library that defines the machine (`machines:`), e.g. `scripts/lib/mill.yaml`.
        #[arg(long, value_name = "LIBRARY")]
        machine: PathBuf,
        /// The machine's name in that library, when it defines more than one.
        #[arg(long, value_name = "NAME")]
        machine_name: Option<String>,
        /// Write the survey's recipe to this file and run nothing (to run, plan or export it).
        #[arg(long, value_name = "RECIPE")]
        emit: Option<PathBuf>,
        #[command(flatten)]
        store: StoreArgs,
        #[command(flatten)]
        work: WorkArgs,
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
        #[command(flatten)]
        store: StoreArgs,
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
        #[arg(required_unless_present = "batch", conflicts_with = "batch")]
        recipe: Option<PathBuf>,
        /// Diagnose every case file the pattern matches (`'cases/*/case.json'`, quoted): each
        /// imported and diagnosed into `OUT/<case>/`, with `summary.csv` and `summary.md`.
        #[arg(long, value_name = "PATTERN")]
        batch: Option<String>,
        /// With `--batch`: diagnose the cases and write no summary (a workflow's case jobs).
        #[arg(long, requires = "batch", conflicts_with = "summary_only")]
        no_summary: bool,
        /// With `--batch`: diagnose nothing; gather the rows the cases' diagnoses left
        /// (`OUT/<case>/row.csv`) into the summary (a workflow's last job).
        #[arg(long, requires = "batch")]
        summary_only: bool,
        /// Output directory (default: `out/<recipe name>/diagnosis`; with `--batch`, `out/batch`).
        #[arg(short, long)]
        out: Option<PathBuf>,
        /// Print nothing but errors.
        #[arg(short, long)]
        quiet: bool,
    },
}

#[derive(Subcommand)]
enum ExportTo {
    /// A Snakefile and a profile for the local executor (docs/scale-out.md).
    Snakemake {
        /// Recipe file (`.yaml` or `.rhai`).
        #[arg(required_unless_present = "batch", conflicts_with = "batch")]
        recipe: Option<PathBuf>,
        /// Instead of a recipe, a batch of diagnoses (`'cases/*/case.json'`): one job per case
        /// (`diagnose --batch CASE --no-summary`), then one that gathers the summary.
        #[arg(long, value_name = "PATTERN")]
        batch: Option<String>,
        /// The folder to write the Snakefile and `profile/` into.
        #[arg(short = 'o', long = "dir")]
        dir: PathBuf,
        /// The output folder the workflow commits to (default: `out/<recipe name>`).
        #[arg(long)]
        out: Option<PathBuf>,
        /// The cache the jobs share (default: the output folder's own).
        #[arg(long, env = "SPINDLELAB_CACHE", value_name = "DIR")]
        cache: Option<PathBuf>,
        /// Shards per level of the graph: jobs that run at once.
        #[arg(long, default_value_t = 4)]
        shards: usize,
    },
}

#[derive(Subcommand)]
enum CacheAction {
    /// Show the size of each output folder's cache (or of the shared one, `--cache`).
    Du {
        /// Output folders (default: every folder under `out/`).
        folders: Vec<PathBuf>,
        /// A cache folder of its own that runs share (`run --cache`), instead of the folders'.
        #[arg(long, env = "SPINDLELAB_CACHE", value_name = "DIR")]
        cache: Option<PathBuf>,
    },
    /// Remove the entries that neither the latest run of the folder nor the one before used;
    /// on a shared cache (`--cache`), those that no named folder's last two runs used, and with
    /// `--max-size` the oldest entries beyond the size.
    Gc {
        /// Output folders (default: every folder under `out/`; with `--cache`, none).
        folders: Vec<PathBuf>,
        /// A cache folder of its own that runs share (`run --cache`), instead of the folders'.
        #[arg(long, env = "SPINDLELAB_CACHE", value_name = "DIR")]
        cache: Option<PathBuf>,
        /// Keep at most this much of the cache, the entries written last (`500MB`, `20GB`).
        #[arg(long, value_name = "SIZE", value_parser = parse_size)]
        max_size: Option<u64>,
    },
    /// Remove the whole cache of each folder (the outputs stay), or the shared one.
    Clean {
        /// Output folders (default: every folder under `out/`).
        folders: Vec<PathBuf>,
        /// A cache folder of its own that runs share (`run --cache`), instead of the folders'.
        #[arg(long, env = "SPINDLELAB_CACHE", value_name = "DIR")]
        cache: Option<PathBuf>,
    },
}

/// A size as `--max-size` takes it: bytes, or with kB, MB, GB, TB (powers of 1000).
fn parse_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let scale = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "kb" | "k" => 1e3,
        "mb" | "m" => 1e6,
        "gb" | "g" => 1e9,
        "tb" | "t" => 1e12,
        _ => return Err(format!("`{text}` is not a size: write e.g. `500MB` or `20GB`")),
    };
    match number.parse::<f64>() {
        Ok(n) if n.is_finite() && n >= 0.0 => Ok((n * scale) as u64),
        _ => Err(format!("`{text}` is not a size: write e.g. `500MB` or `20GB`")),
    }
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
    let reach = if CONFINE.load(Ordering::Relaxed) { engine::Reach::RecipeFolder } else { engine::Reach::Anywhere };
    let compiled = spindlelab::plugins::compile_file_within(path, set, registry, plugins, reach);
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
        Command::Check { recipe, set } => cmd_check(&recipe, &set, &mut registry, &mut plugins),
        Command::Graph { recipe, format } => cmd_graph(&recipe, format, &mut registry, &mut plugins),
        Command::Plan { recipe, store, set } => cmd_plan(&recipe, store, &set, &mut registry, &mut plugins),
        Command::Nodes { kind } => cmd_nodes(kind, &mut registry, &mut plugins),
        Command::Diagnose { recipe: Some(recipe), out, quiet, .. } => {
            cmd_diagnose(&recipe, out, quiet, &mut registry, &mut plugins)
        }
        Command::Diagnose { batch, out, quiet, no_summary, summary_only, .. } => {
            let mode = BatchMode { summary: !no_summary, diagnose: !summary_only };
            cmd_diagnose_batch(batch.as_deref().unwrap_or_default(), out, quiet, mode, &registry)
        }
        Command::Crib { catalog, machine, machine_name, emit, store, work } => {
            cmd_crib(CribArgs { catalog, machine, machine_name, emit, store, work }, &registry)
        }
        Command::Import { case, out, library } => cmd_import(&case, out, library),
        Command::Cache { action } => cache_command(action),
        Command::Plugin { action } => plugin_command(action, &mut plugins),
        Command::Schema => cmd_schema(&registry),
        Command::Report { run_dir, out } => report_command(&run_dir, out),
        Command::Run { recipe, store, work, keep_going, verbose, set, no_fit, report, shard, level } => {
            let args = RunArgs { recipe, store, work, keep_going, verbose, set, no_fit, report };
            match shard {
                Some(shard) => cmd_run_shard(args, &shard, level, &mut registry, &mut plugins),
                None => cmd_run(args, &mut registry, &mut plugins),
            }
        }
        Command::Export { to: ExportTo::Snakemake { recipe: Some(recipe), dir, out, cache, shards, .. } } => {
            cmd_export_snakemake(&recipe, &dir, out, cache, shards, &mut registry, &mut plugins)
        }
        Command::Export { to: ExportTo::Snakemake { batch, dir, out, .. } } => {
            cmd_export_batch(batch.as_deref().unwrap_or_default(), &dir, out)
        }
    }
}

/// Writes the files given both a path and a text, all or none: each whole to a temporary name first,
/// all renamed into place only when all are written; a folder named that does not exist yet is made.
fn write_together(files: &[(Option<&PathBuf>, Option<&str>)]) -> Result<(), ExitCode> {
    let mut staged = Vec::new();
    for &(path, text) in files {
        let (Some(path), Some(text)) = (path, text) else { continue };
        match stage_file(path, text) {
            Ok(tmp) => staged.push((path.clone(), tmp)),
            Err(e) => {
                eoutln!("error: cannot write {}: {e}", path.display());
                return Err(ExitCode::from(EXIT_FAILURE));
            }
        }
    }
    for (path, tmp) in staged {
        if let Err(e) = tmp.persist(&path) {
            eoutln!("error: cannot write {}: {}", path.display(), e.error);
            return Err(ExitCode::from(EXIT_FAILURE));
        }
    }
    Ok(())
}

/// Writes `text` whole to a temporary file in the folder of `path` (made if missing), to be renamed into place.
fn stage_file(path: &Path, text: &str) -> std::io::Result<tempfile::NamedTempFile> {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).and_then(|()| tempfile::NamedTempFile::new_in(dir)).and_then(|mut tmp| {
        std::io::Write::write_all(&mut tmp, text.as_bytes())?;
        Ok(tmp)
    })
}
