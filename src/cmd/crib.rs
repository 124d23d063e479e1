//! `crib`: a tool-crib catalog surveyed on one machine.

use crate::*;

/// What `spindlelab crib` was asked.
pub(crate) struct CribArgs {
    pub(crate) catalog: PathBuf,
    pub(crate) machine: PathBuf,
    pub(crate) machine_name: Option<String>,
    pub(crate) emit: Option<PathBuf>,
    pub(crate) store: StoreArgs,
    pub(crate) work: WorkArgs,
}

/// `spindlelab crib CATALOG --machine LIB`: builds the survey's recipe, and writes it
/// (`--emit`) or runs it, with one table of the best cut of every combination.
pub(crate) fn cmd_crib(args: CribArgs, registry: &engine::node::Registry) -> ExitCode {
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
