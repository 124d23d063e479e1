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

/// `spindlelab check RECIPE`: compiles the recipe and says what it holds, or reports its problems.
fn cmd_check(
    recipe: &Path,
    set: &[(String, String)],
    registry: &mut engine::node::Registry,
    plugins: &mut Plugins,
) -> ExitCode {
    match compile_with(recipe, set, registry, plugins) {
        Ok(c) if c.recipe.library => {
            outln!("{}: ok — library of {}", recipe.display(), library_contents(&c.recipe));
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
    }
}

/// What a library holds, counted by kind of entity (`2 materials, 1 sensor`), or `nothing`.
fn library_contents(r: &engine::model::Recipe) -> String {
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
    if counts.is_empty() { "nothing".into() } else { counts.join(", ") }
}

/// `spindlelab graph RECIPE`: prints the compiled graph as Graphviz DOT or Mermaid.
fn cmd_graph(
    recipe: &Path,
    format: GraphFormat,
    registry: &mut engine::node::Registry,
    plugins: &mut Plugins,
) -> ExitCode {
    match compile(recipe, registry, plugins) {
        Ok(c) => {
            let text = match format {
                GraphFormat::Dot => engine::graph::to_dot(&c.graph),
                GraphFormat::Mermaid => engine::graph::to_mermaid(&c.graph),
            };
            out!("{}", esc_lines(&text));
            ExitCode::SUCCESS
        }
        Err(code) => code,
    }
}

/// `spindlelab plan RECIPE`: lists which nodes a run would compute, which come from the cache, and why.
fn cmd_plan(
    recipe: &Path,
    StoreArgs { out, no_cache, cache: cache_dir }: StoreArgs,
    set: &[(String, String)],
    registry: &mut engine::node::Registry,
    plugins: &mut Plugins,
) -> ExitCode {
    match compile_with(recipe, set, registry, plugins) {
        Ok(c) => {
            let out = out.unwrap_or_else(|| default_out(&c));
            let opts = RunOptions { cache_dir, ..RunOptions::new(&out) };
            let cache = (!no_cache).then(|| opts.cache());
            let entries = plan(&c.recipe, &c.graph, registry, &out, cache.as_ref());
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

/// `spindlelab nodes [KIND]`: describes every node kind (built-in and from plugins), or the one named.
fn cmd_nodes(kind: Option<String>, registry: &mut engine::node::Registry, plugins: &mut Plugins) -> ExitCode {
    if let Err(e) = plugins.load_always(registry) {
        eoutln!("error: {}", esc(&e));
        return ExitCode::from(EXIT_BAD_INPUT);
    }
    for (manifest, e) in plugins.load_search_path(registry).1 {
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
        let hint =
            engine::spec::suggest(&k, registry.names()).map(|s| format!(" (did you mean `{s}`?)")).unwrap_or_default();
        eoutln!("error: unknown node kind `{}`{hint}", esc(&k));
        return ExitCode::from(EXIT_BAD_INPUT);
    }
    ExitCode::SUCCESS
}

/// `spindlelab diagnose RECIPE`: finds the missing physical effect and writes the diagnosis folder.
fn cmd_diagnose(
    recipe: &Path,
    out: Option<PathBuf>,
    quiet: bool,
    registry: &mut engine::node::Registry,
    plugins: &mut Plugins,
) -> ExitCode {
    // Loads the plugins the recipe names, so the diagnosis compiles it with them.
    let compiled = match compile(recipe, registry, plugins) {
        Ok(c) => c,
        Err(code) => return code,
    };
    let d = match spindlelab::diagnose::diagnose(recipe, registry) {
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
        outln!("\nwrote diagnosis.json, diagnosis.md and diagnosed.yaml to {} in {:.1} s", out.display(), d.seconds);
    }
    ExitCode::SUCCESS
}

/// `spindlelab diagnose --batch PATTERN`: every case the pattern matches imported and
/// diagnosed into a folder of its own, one after the other, with a summary of all of them.
/// What `diagnose --batch` does: diagnose the cases, write the summary, or both.
#[derive(Clone, Copy)]
struct BatchMode {
    diagnose: bool,
    summary: bool,
}

/// The case files `pattern` matches, each with its folder name under the batch's output
/// (a name two cases share gets `_2`, `_3`, …, in the pattern's order).
fn batch_cases(pattern: &str) -> Result<Vec<(PathBuf, String)>, ExitCode> {
    use spindlelab::diagnose::batch;
    let cases: Vec<PathBuf> = match glob::glob(pattern) {
        Ok(paths) => paths.filter_map(Result::ok).filter(|p| p.is_file()).collect(),
        Err(e) => {
            eoutln!("error: `{}` is not a file pattern: {e}", esc(pattern));
            return Err(ExitCode::from(EXIT_BAD_INPUT));
        }
    };
    if cases.is_empty() {
        eoutln!(
            "error: `{}` matches no case file (quote the pattern so the shell leaves it: 'cases/*/case.json')",
            esc(pattern)
        );
        return Err(ExitCode::from(EXIT_BAD_INPUT));
    }
    let mut names = std::collections::HashSet::new();
    Ok(cases
        .into_iter()
        .map(|case| {
            let mut name = batch::case_name(&case);
            for k in 2.. {
                if names.insert(name.clone()) {
                    break;
                }
                name = format!("{}_{k}", batch::case_name(&case));
            }
            (case, name)
        })
        .collect())
}

fn cmd_diagnose_batch(
    pattern: &str,
    out: Option<PathBuf>,
    quiet: bool,
    mode: BatchMode,
    registry: &engine::node::Registry,
) -> ExitCode {
    use spindlelab::diagnose::batch;
    let cases = match batch_cases(pattern) {
        Ok(c) => c,
        Err(code) => return code,
    };
    let out = out.unwrap_or_else(|| PathBuf::from("out/batch"));
    let mut rows = Vec::new();
    for (case, name) in &cases {
        let row_file = out.join(name).join(batch::ROW_FILE);
        if !mode.diagnose {
            // The row the case's diagnosis left; a case not diagnosed yet is a failed row.
            let read = std::fs::read(&row_file).map_err(|e| e.to_string());
            let row = read.and_then(|b| batch::rows_from_csv(&b, &row_file.display().to_string()));
            match row {
                Ok(r) if r.len() == 1 => rows.extend(r),
                Ok(_) => rows.push(batch::failed(name, format!("{} holds no single row", row_file.display()))),
                Err(e) => rows.push(batch::failed(name, format!("not diagnosed: {e}"))),
            }
            continue;
        }
        let row = match batch::diagnose_case(case, &out.join(name), registry) {
            Ok(d) => batch::row(name, &d),
            Err(e) => batch::failed(name, e),
        };
        let text = batch::summary_csv(std::slice::from_ref(&row));
        if let Err(code) = write_together(&[(Some(&row_file), Some(text.as_str()))]) {
            return code;
        }
        if !quiet {
            let what = if row.error.is_empty() {
                format!("{} {}", row.verdict, row.effects)
            } else {
                format!("failed: {}", row.error)
            };
            outln!("{}: {} ({:.1} s)", esc(name), esc(what.trim()), row.seconds);
        }
        rows.push(row);
    }
    let failed = rows.iter().filter(|r| !r.error.is_empty()).count();
    if mode.summary {
        let (csv, md) = (out.join("summary.csv"), out.join("summary.md"));
        let (csv_text, md_text) = (batch::summary_csv(&rows), batch::summary_md(&rows));
        if let Err(code) = write_together(&[(Some(&csv), Some(csv_text.as_str())), (Some(&md), Some(md_text.as_str()))])
        {
            return code;
        }
        if !quiet {
            outln!("wrote {} and summary.md: {} case(s), {failed} failed", esc(csv.display()), rows.len());
        }
    }
    // Gathering the summary succeeds whatever the cases did: their rows say it.
    if failed > 0 && mode.diagnose { ExitCode::from(EXIT_FAILURE) } else { ExitCode::SUCCESS }
}

/// What `spindlelab crib` was asked.
struct CribArgs {
    catalog: PathBuf,
    machine: PathBuf,
    machine_name: Option<String>,
    emit: Option<PathBuf>,
    store: StoreArgs,
    work: WorkArgs,
}

/// `spindlelab crib CATALOG --machine LIB`: builds the survey's recipe, and writes it
/// (`--emit`) or runs it, with one table of the best cut of every combination.
fn cmd_crib(args: CribArgs, registry: &engine::node::Registry) -> ExitCode {
    use spindlelab::crib;
    let fail = |e: crib::CribError| {
        eout!("{}", e.render(color()));
        ExitCode::from(if e.is_bad_input() { EXIT_BAD_INPUT } else { EXIT_FAILURE })
    };
    let machine = match crib::machine(&args.machine, args.machine_name.as_deref(), registry) {
        Ok(m) => m,
        Err(e) => return fail(e),
    };
    let loaded = match crib::load(&args.catalog, &machine, registry) {
        Ok(l) => l,
        Err(e) => return fail(e),
    };
    // The recipe sits where it is emitted, or (never written) beside the catalog.
    let recipe_path = args.emit.clone().unwrap_or_else(|| {
        let stem = args.catalog.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        args.catalog.with_file_name(format!("{stem}.recipe.yaml"))
    });
    let recipe_dir = recipe_path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let survey = crib::build(&loaded, &machine, recipe_dir);
    let text = crib::emit(&loaded, &machine, &survey);
    let compiled = match crib::compile_text(&text, &recipe_path, registry) {
        Ok(c) => c,
        Err(e) => return fail(crib::CribError::Compile(e)),
    };
    if let Some(emit) = &args.emit {
        if let Err(code) = write_together(&[(Some(emit), Some(text.as_str()))]) {
            return code;
        }
        if !args.work.quiet {
            outln!(
                "wrote {}: {} combinations, {} node instances; run it with `spindlelab run {}`",
                esc(emit.display()),
                survey.assemblies.len(),
                compiled.graph.instances.len(),
                esc(emit.display())
            );
        }
        return ExitCode::SUCCESS;
    }
    let out = args.store.out.unwrap_or_else(|| default_out(&compiled));
    let opts = RunOptions {
        use_cache: !args.store.no_cache,
        threads: clamp_threads(args.work.threads),
        release_consumed: true,
        renderer: Some(spindlelab::renderer()),
        cache_dir: args.store.cache,
        ..RunOptions::new(out.clone())
    };
    let bar = progress_bar(compiled.graph.instances.len() as u64, args.work.quiet);
    let progress = |_: usize, id: &str| {
        bar.inc(1);
        bar.set_message(esc(id));
    };
    let outcome = crib::run(&compiled, &loaded, &survey, registry, opts, &progress);
    bar.finish_and_clear();
    match outcome {
        Ok(ran) => {
            if !args.work.quiet {
                let instances = compiled.graph.instances.len();
                outln!(
                    "{} combinations on machine `{}`: {} of {instances} node instances computed, the others from the cache, in {:.3} s; wrote {}, {} per-tool table(s) and manifest.json to {}",
                    survey.assemblies.len(),
                    esc(&machine.name),
                    ran.computed,
                    ran.seconds,
                    crib::SUMMARY_FILE,
                    ran.report.written.len(),
                    esc(out.display())
                );
            }
            ExitCode::SUCCESS
        }
        Err(e) => fail(e),
    }
}

/// `spindlelab import CASE`: writes (or prints) the recipe of a baseline case file, and its library if asked.
fn cmd_import(case: &Path, out: Option<PathBuf>, library: Option<PathBuf>) -> ExitCode {
    let shown = case.display().to_string();
    let text = match std::fs::read_to_string(case) {
        Ok(t) => t,
        Err(e) => {
            eoutln!("error: cannot read {}: {e}", esc(&shown));
            return ExitCode::from(EXIT_BAD_INPUT);
        }
    };
    // The recipe names the case's data files from its own folder (the current one when
    // it is printed).
    let recipe_dir = out.as_deref().and_then(Path::parent).unwrap_or(Path::new(""));
    let folder = |p: &'_ Path| if p.as_os_str().is_empty() { Path::new(".").to_path_buf() } else { p.to_path_buf() };
    let (case_dir, recipe_folder) = (folder(case.parent().unwrap_or(Path::new(""))), folder(recipe_dir));
    let placement = spindlelab::import::Placement { case_dir: &case_dir, recipe_dir: &recipe_folder };
    let imported = match &library {
        None => spindlelab::import::recipe_from_case_at(&text, &shown, placement).map(|r| (None, r)),
        Some(lib) => {
            let use_path = relative_to(lib, recipe_dir);
            spindlelab::import::library_from_case(&text, &shown, &use_path, Some(placement)).map(|(l, r)| (Some(l), r))
        }
    };
    let (library_text, recipe) = match imported {
        Ok(r) => r,
        Err(e) => {
            eoutln!("error: {}", esc(&e));
            return ExitCode::from(EXIT_BAD_INPUT);
        }
    };
    let files = [(library.as_ref(), library_text.as_deref()), (out.as_ref(), Some(recipe.as_str()))];
    if let Err(code) = write_together(&files) {
        return code;
    }
    if out.is_none() {
        out!("{recipe}");
    }
    ExitCode::SUCCESS
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

/// `spindlelab schema`: prints the JSON Schema of the YAML recipe for the kinds in `registry`.
fn cmd_schema(registry: &engine::node::Registry) -> ExitCode {
    outln!("{}", serde_json::to_string_pretty(&engine::schema::recipe_schema(registry)).expect("schema serialises"));
    ExitCode::SUCCESS
}

/// The arguments of `spindlelab run`, as the command line gave them.
struct RunArgs {
    recipe: PathBuf,
    store: StoreArgs,
    work: WorkArgs,
    keep_going: bool,
    verbose: bool,
    set: Vec<(String, String)>,
    no_fit: bool,
    report: bool,
}

/// `spindlelab run RECIPE --shard K/N [--level L]`: computes one shard of the graph into the
/// cache, writes no outputs, and leaves a marker in the cache folder listing what it computed.
fn cmd_run_shard(
    args: RunArgs,
    shard: &str,
    level: Option<usize>,
    registry: &mut engine::node::Registry,
    plugins: &mut Plugins,
) -> ExitCode {
    let mut shard = match engine::exec::Shard::parse(shard) {
        Ok(s) => s,
        Err(e) => {
            eoutln!("error: {}", esc(&e));
            return ExitCode::from(EXIT_BAD_INPUT);
        }
    };
    shard.level = level;
    if args.store.no_cache || args.report || args.keep_going {
        eoutln!(
            "error: a shard computes into the cache and writes no outputs: leave out --no-cache, --report and --keep-going"
        );
        return ExitCode::from(EXIT_BAD_INPUT);
    }
    let c = match compile_with(&args.recipe, &args.set, registry, plugins) {
        Ok(c) if c.recipe.library => return refuse_library(&c, &args.recipe),
        Ok(c) => c,
        Err(code) => return code,
    };
    if c.recipe.fit.is_some() && !args.no_fit {
        eoutln!(
            "error: {} has a `fit:` block, whose evaluations run in one process: shard it with --no-fit, or run the fitted recipe",
            esc(args.recipe.display())
        );
        return ExitCode::from(EXIT_BAD_INPUT);
    }
    let out = args.store.out.clone().unwrap_or_else(|| default_out(&c));
    let opts = RunOptions {
        threads: clamp_threads(args.work.threads),
        cache_dir: args.store.cache.clone(),
        shard: Some(shard),
        ..RunOptions::new(out)
    };
    let bar = progress_bar(c.graph.instances.len() as u64, args.work.quiet);
    let progress = |_: usize, id: &str| {
        bar.inc(1);
        bar.set_message(esc(id));
    };
    let result = engine::exec::execute(&c.recipe, &c.graph, registry, &opts, &progress);
    bar.finish_and_clear();
    for n in &result.notes {
        eoutln!("warning: {}", esc(n));
    }
    let failures: Vec<(&str, String)> = result.failures(&c.graph).map(|(id, e)| (id, e.to_string())).collect();
    if !failures.is_empty() {
        for (id, e) in &failures {
            eoutln!("error: {}: {}", esc(id), esc(e));
        }
        return ExitCode::from(EXIT_FAILURE);
    }
    let computed: Vec<&str> = c
        .graph
        .instances
        .iter()
        .zip(&result.outcomes)
        .filter(|(inst, o)| {
            matches!(o, engine::exec::Outcome::Computed { .. } | engine::exec::Outcome::Released { .. })
                && registry.get(&inst.kind).is_some_and(|n| n.cacheable())
        })
        .map(|(inst, _)| inst.id.as_str())
        .collect();
    let cached = result.outcomes.iter().filter(|o| matches!(o, engine::exec::Outcome::Cached { .. })).count();
    let marker = shard.marker(opts.cache().dir(), &c.graph);
    let record = serde_json::json!({
        "recipe": c.recipe.name,
        "shard": format!("{}/{}", shard.index, shard.count),
        "level": shard.level,
        "computed": computed,
        "from_cache": cached,
    });
    let text = serde_json::to_string_pretty(&record).expect("a marker serialises") + "\n";
    if let Err(code) = write_together(&[(Some(&marker), Some(text.as_str()))]) {
        return code;
    }
    if !args.work.quiet {
        let level = shard.level.map(|l| format!(", level {l}")).unwrap_or_default();
        outln!(
            "shard {}/{}{level}: {} computed, {} from cache; marker {}",
            shard.index,
            shard.count,
            computed.len(),
            cached,
            esc(marker.display())
        );
    }
    ExitCode::SUCCESS
}

/// `spindlelab export snakemake RECIPE -o DIR`: the recipe as a Snakefile of shard jobs per
/// level and a collect job, with a profile for the local executor.
fn cmd_export_snakemake(
    recipe: &Path,
    dir: &Path,
    out: Option<PathBuf>,
    cache: Option<PathBuf>,
    shards: usize,
    registry: &mut engine::node::Registry,
    plugins: &mut Plugins,
) -> ExitCode {
    if shards == 0 {
        eoutln!("error: --shards 0: a workflow needs at least one shard per level");
        return ExitCode::from(EXIT_BAD_INPUT);
    }
    let c = match compile_with(recipe, &[], registry, plugins) {
        Ok(c) if c.recipe.library => return refuse_library(&c, recipe),
        Ok(c) => c,
        Err(code) => return code,
    };
    let out = out.unwrap_or_else(|| default_out(&c));
    let cache = cache.unwrap_or_else(|| engine::exec::cache_dir(&out));
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let exe = std::env::current_exe().unwrap_or_else(|_| PathBuf::from("spindlelab"));
    let (recipe_abs, out_abs, cache_abs) = (abs(recipe), abs(&out), abs(&cache));
    let places = spindlelab::export::Places { spindlelab: &exe, recipe: &recipe_abs, out: &out_abs, cache: &cache_abs };
    let wf = spindlelab::export::snakemake(&c, registry, &places, shards);
    let (snakefile, profile) = (dir.join("Snakefile"), dir.join("profile").join("config.yaml"));
    if let Err(code) =
        write_together(&[(Some(&snakefile), Some(wf.snakefile.as_str())), (Some(&profile), Some(wf.profile.as_str()))])
    {
        return code;
    }
    outln!(
        "wrote {}: {} level(s) × {} shard(s), then collect into {}; run it with `snakemake -s {} --profile {}`",
        esc(dir.join("Snakefile").display()),
        wf.levels,
        wf.shards,
        esc(out_abs.display()),
        esc(dir.join("Snakefile").display()),
        esc(dir.join("profile").display())
    );
    ExitCode::SUCCESS
}

/// `spindlelab export snakemake --batch PATTERN -o DIR`: a batch of diagnoses as a Snakefile,
/// one job per case and one that gathers the summary.
fn cmd_export_batch(pattern: &str, dir: &Path, out: Option<PathBuf>) -> ExitCode {
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let pattern_abs = if Path::new(pattern).is_absolute() {
        pattern.to_string()
    } else {
        abs(Path::new(".")).join(pattern).display().to_string()
    };
    let cases = match batch_cases(&pattern_abs) {
        Ok(c) => c,
        Err(code) => return code,
    };
    if let Some((case, name)) = cases.iter().find(|(c, n)| spindlelab::diagnose::batch::case_name(c) != *n) {
        eoutln!(
            "error: {} would be named `{}` like another case; a workflow names each case's folder by it alone: give the cases distinct folders",
            esc(case.display()),
            esc(name)
        );
        return ExitCode::from(EXIT_BAD_INPUT);
    }
    let out = abs(&out.unwrap_or_else(|| PathBuf::from("out/batch")));
    let exe = std::env::current_exe().unwrap_or_else(|_| PathBuf::from("spindlelab"));
    let wf = spindlelab::export::snakemake_batch(&exe, &pattern_abs, &cases, &out);
    let (snakefile, profile) = (dir.join("Snakefile"), dir.join("profile").join("config.yaml"));
    if let Err(code) =
        write_together(&[(Some(&snakefile), Some(wf.snakefile.as_str())), (Some(&profile), Some(wf.profile.as_str()))])
    {
        return code;
    }
    outln!(
        "wrote {}: {} case job(s), then the summary into {}; run it with `snakemake -s {} --profile {}`",
        esc(snakefile.display()),
        cases.len(),
        esc(out.display()),
        esc(snakefile.display()),
        esc(dir.join("profile").display())
    );
    ExitCode::SUCCESS
}

/// `spindlelab run RECIPE`: compiles the recipe, fits it if it asks, runs it and writes its outputs.
fn cmd_run(args: RunArgs, registry: &mut engine::node::Registry, plugins: &mut Plugins) -> ExitCode {
    let RunArgs {
        recipe,
        store: StoreArgs { out, no_cache, cache },
        work: WorkArgs { threads, quiet },
        keep_going,
        verbose,
        set,
        no_fit,
        report,
    } = args;
    let threads = clamp_threads(threads);
    let mut c = match compile_with(&recipe, &set, registry, plugins) {
        Ok(c) if c.recipe.library => return refuse_library(&c, &recipe),
        Ok(c) => c,
        Err(code) => return code,
    };
    let out = out.unwrap_or_else(|| default_out(&c));
    let mut fitted = None;
    if c.recipe.fit.is_some() && !no_fit {
        let (refit, report) = match fit_recipe(&c, &recipe, &set, threads, quiet, registry, plugins) {
            Ok(r) => r,
            Err(code) => return code,
        };
        c = refit;
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
        cache_dir: cache,
        ..RunOptions::new(out.clone())
    };
    let bar = progress_bar(c.graph.instances.len() as u64, quiet);
    let progress = |_: usize, id: &str| {
        bar.inc(1);
        bar.set_message(esc(id));
    };
    let outcome = engine::run(&c, registry, &opts, &progress);
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
                eoutln!("error: node `{}` failed: {}{}", esc(id), esc(e), failed_step(&c, id));
            }
            eoutln!(
                "{} instance(s) computed and cached; {}",
                report.manifest.computed,
                failed_outputs(&report, keep_going)
            );
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

/// Refuses to run a library (a recipe without steps), saying how to use its entities instead.
fn refuse_library(c: &Compiled, recipe: &Path) -> ExitCode {
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
    ExitCode::from(EXIT_BAD_INPUT)
}

/// Runs the recipe's fit and compiles the recipe again with the fitted values (the run that writes the outputs).
fn fit_recipe(
    c: &Compiled,
    recipe: &Path,
    set: &[(String, String)],
    threads: Option<usize>,
    quiet: bool,
    registry: &mut engine::node::Registry,
    plugins: &mut Plugins,
) -> Result<(Compiled, spindlelab::fit::FitReport), ExitCode> {
    let report = match spindlelab::fit::fit(c, set, registry, threads) {
        Ok(r) => r,
        Err(e) => {
            eoutln!("error: fit: {}", esc(&e));
            return Err(ExitCode::from(EXIT_BAD_INPUT));
        }
    };
    if !quiet {
        out!("{}", spindlelab::summary::fit_summary(&report));
    }
    // The run that writes the outputs is the recipe with the fitted values.
    let mut with_fit: Vec<(String, String)> =
        set.iter().filter(|(n, _)| !report.params.iter().any(|p| &p.name == n)).cloned().collect();
    with_fit.extend(report.overrides());
    let c = compile_with(recipe, &with_fit, registry, plugins)?;
    Ok((c, report))
}

/// The progress bar of a run on standard error: shown on a terminal unless `quiet`, else hidden.
fn progress_bar(len: u64, quiet: bool) -> ProgressBar {
    if std::io::stderr().is_terminal() && !quiet {
        let b = ProgressBar::new(len);
        b.set_style(ProgressStyle::with_template("{bar:30} {pos}/{len} {wide_msg}").expect("template"));
        b
    } else {
        ProgressBar::hidden()
    }
}

/// Where a failed node instance comes from in the recipe (`\n --> span (step `id`)`), or nothing if unknown.
fn failed_step(c: &Compiled, id: &str) -> String {
    c.graph
        .instances
        .iter()
        .find(|i| i.id == id)
        .and_then(|i| c.recipe.step(&i.step))
        .map(|s| format!("\n --> {} (step `{}`)", esc(&s.span), s.id))
        .unwrap_or_default()
}

/// What a run with failed nodes wrote: nothing (and why), or its files and those lacking failed sweep points.
fn failed_outputs(r: &engine::RunReport, keep_going: bool) -> String {
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
    // A batch of diagnoses: the summary, and each case's diagnosis on the same page.
    if run_dir.join("summary.md").is_file() && run_dir.join("summary.csv").is_file() {
        return match spindlelab::diagnose::batch::report_html(run_dir) {
            Ok(html) => write_report(&target_for(out), html),
            Err(e) => {
                eoutln!("error: {}; rerun `spindlelab diagnose --batch` into that folder", esc(&e));
                ExitCode::from(EXIT_BAD_INPUT)
            }
        };
    }
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
        CacheAction::Du { cache: Some(dir), .. } => return shared_cache_command(&dir, "du", &[], None),
        CacheAction::Gc { cache: Some(dir), folders, max_size } => {
            return shared_cache_command(&dir, "gc", &folders, max_size);
        }
        CacheAction::Clean { cache: Some(dir), .. } => return shared_cache_command(&dir, "clean", &[], None),
        CacheAction::Du { folders, .. } => (cache_folders(folders), "du"),
        CacheAction::Gc { max_size: Some(_), .. } => {
            eoutln!("error: --max-size bounds a shared cache: name it with --cache DIR");
            return ExitCode::from(EXIT_BAD_INPUT);
        }
        CacheAction::Gc { folders, .. } => (cache_folders(folders), "gc"),
        CacheAction::Clean { folders, .. } => (cache_folders(folders), "clean"),
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

/// `cache du|gc|clean --cache DIR`: the same on a cache folder that runs and machines share.
/// Nothing is locked (entries are written by rename and checked on read); `gc` keeps what the
/// latest two runs of each named output folder used and, with `max_size`, the entries written
/// last that fit.
fn shared_cache_command(dir: &Path, verb: &str, folders: &[PathBuf], max_size: Option<u64>) -> ExitCode {
    use engine::exec::{Cache, Manifest, commit::META_DIR};
    let cache = Cache::new(dir);
    if !dir.is_dir() {
        outln!("{}: no cache", esc(dir.display()));
        return ExitCode::SUCCESS;
    }
    let (n, bytes) = match verb {
        "du" => {
            let (n, bytes) = cache.usage();
            outln!("{}: {n} entries, {}", esc(dir.display()), human_bytes(bytes));
            return ExitCode::SUCCESS;
        }
        "clean" => cache.retain(|_| false),
        _ => {
            if folders.is_empty() && max_size.is_none() {
                eoutln!(
                    "error: gc of a shared cache keeps what named output folders used, or what fits a size: name folders, or give --max-size"
                );
                return ExitCode::from(EXIT_BAD_INPUT);
            }
            let (mut n, mut bytes) = (0, 0);
            if !folders.is_empty() {
                let keep: std::collections::HashSet<String> = folders
                    .iter()
                    .flat_map(|f| ["current", "previous"].map(|run| f.join(META_DIR).join(run)))
                    .filter_map(|m| Manifest::read(&m))
                    .flat_map(|m| m.nodes.into_iter().map(|n| n.key))
                    .collect();
                (n, bytes) = cache.retain(|k| keep.contains(k));
            }
            if let Some(max) = max_size {
                let (m, b) = cache.within(max);
                (n, bytes) = (n + m, bytes + b);
            }
            (n, bytes)
        }
    };
    outln!("{}: removed {n} entries, {}", esc(dir.display()), human_bytes(bytes));
    ExitCode::SUCCESS
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
