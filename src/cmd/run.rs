//! `run`: a recipe compiled, fitted if it asks, run, and its outputs written; or one shard of
//! its graph computed into the cache.

use crate::*;

/// The arguments of `spindlelab run`, as the command line gave them.
pub(crate) struct RunArgs {
    pub(crate) recipe: PathBuf,
    pub(crate) store: StoreArgs,
    pub(crate) work: WorkArgs,
    pub(crate) keep_going: bool,
    pub(crate) verbose: bool,
    pub(crate) set: Vec<(String, String)>,
    pub(crate) no_fit: bool,
    pub(crate) report: bool,
}

/// `spindlelab run RECIPE --shard K/N [--level L]`: computes one shard of the graph into the
/// cache, writes no outputs, and leaves a marker in the cache folder listing what it computed.
pub(crate) fn cmd_run_shard(
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
    // A shard's work is the cache entries it leaves: one it could not store fails it, with no
    // marker, so the collect step does not take it for done.
    let cache_dir = opts.cache().dir().to_path_buf();
    if engine::exec::files::is_link(&cache_dir) {
        let e = engine::exec::shard::MarkerError::CacheLink(cache_dir);
        eoutln!("error: {}", esc(&e));
        return ExitCode::from(EXIT_BAD_INPUT);
    }
    if let Some((inst, why)) =
        c.graph.instances.iter().zip(&result.outcomes).find_map(|(inst, o)| o.not_cached().map(|w| (inst, w)))
    {
        eoutln!(
            "error: the result of `{}` could not be stored in the cache ({}); the shard wrote no marker: free space or fix the cache folder's permissions and run the shard again",
            esc(&inst.id),
            esc(why)
        );
        return ExitCode::from(EXIT_FAILURE);
    }
    let record = serde_json::json!({
        "recipe": c.recipe.name,
        "shard": format!("{}/{}", shard.index, shard.count),
        "level": shard.level,
        "computed": computed,
        "from_cache": cached,
    });
    let text = serde_json::to_string_pretty(&record).expect("a marker serialises") + "\n";
    let marker = match shard.write_marker(opts.cache().dir(), &c.graph, &text) {
        Ok(path) => path,
        Err(e) => {
            eoutln!("error: {}", esc(&e));
            return ExitCode::from(if e.is_bad_input() { EXIT_BAD_INPUT } else { EXIT_FAILURE });
        }
    };
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

/// `spindlelab run RECIPE`: compiles the recipe, fits it if it asks, runs it and writes its outputs.
pub(crate) fn cmd_run(args: RunArgs, registry: &mut engine::node::Registry, plugins: &mut Plugins) -> ExitCode {
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
pub(crate) fn refuse_library(c: &Compiled, recipe: &Path) -> ExitCode {
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
pub(crate) fn fit_recipe(
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
pub(crate) fn progress_bar(len: u64, quiet: bool) -> ProgressBar {
    if std::io::stderr().is_terminal() && !quiet {
        let b = ProgressBar::new(len);
        b.set_style(ProgressStyle::with_template("{bar:30} {pos}/{len} {wide_msg}").expect("template"));
        b
    } else {
        ProgressBar::hidden()
    }
}

/// Where a failed node instance comes from in the recipe (`\n --> span (step `id`)`), or nothing if unknown.
pub(crate) fn failed_step(c: &Compiled, id: &str) -> String {
    c.graph
        .instances
        .iter()
        .find(|i| i.id == id)
        .and_then(|i| c.recipe.step(&i.step))
        .map(|s| format!("\n --> {} (step `{}`)", esc(&s.span), s.id))
        .unwrap_or_default()
}

/// What a run with failed nodes wrote: nothing (and why), or its files and those lacking failed sweep points.
pub(crate) fn failed_outputs(r: &engine::RunReport, keep_going: bool) -> String {
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
pub(crate) fn relative_to(path: &Path, dir: &Path) -> String {
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let (p, d) = (abs(path), abs(if dir.as_os_str().is_empty() { Path::new(".") } else { dir }));
    let norm =
        |p: PathBuf| -> PathBuf { p.components().filter(|c| !matches!(c, std::path::Component::CurDir)).collect() };
    match norm(p.clone()).strip_prefix(norm(d)) {
        Ok(rel) => rel.display().to_string(),
        Err(_) => p.display().to_string(),
    }
}
