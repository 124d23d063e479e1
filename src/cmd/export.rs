//! `export snakemake`: a recipe, or a batch of cases, as a workflow another engine schedules.

use crate::*;

/// `spindlelab export snakemake RECIPE -o DIR`: the recipe as a Snakefile of shard jobs per
/// level and a collect job, with a profile for the local executor.
pub(crate) fn cmd_export_snakemake(
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
    let wf = match spindlelab::export::snakemake(&c, registry, &places, shards) {
        Ok(wf) => wf,
        Err(e) => {
            eoutln!("error: {}", esc(e));
            return ExitCode::from(EXIT_BAD_INPUT);
        }
    };
    let snakefile = match write_workflow(dir, &wf.snakefile, &wf.profile) {
        Ok(path) => path,
        Err(code) => return code,
    };
    outln!(
        "wrote {}: {} level(s) × {} shard(s), then collect into {}; run it with `snakemake -s {} --profile {}`",
        esc(snakefile.display()),
        wf.levels,
        wf.shards,
        esc(out_abs.display()),
        esc(snakefile.display()),
        esc(dir.join("profile").display())
    );
    ExitCode::SUCCESS
}

/// `spindlelab export snakemake --batch PATTERN -o DIR`: a batch of diagnoses as a Snakefile,
/// one job per case and one that gathers the summary.
pub(crate) fn cmd_export_batch(pattern: &str, dir: &Path, out: Option<PathBuf>) -> ExitCode {
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
    let wf = match spindlelab::export::snakemake_batch(&exe, &pattern_abs, &cases, &out) {
        Ok(wf) => wf,
        Err(e) => {
            eoutln!("error: {}", esc(e));
            return ExitCode::from(EXIT_BAD_INPUT);
        }
    };
    let snakefile = match write_workflow(dir, &wf.snakefile, &wf.profile) {
        Ok(path) => path,
        Err(code) => return code,
    };
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

/// Writes a workflow's Snakefile and its profile (`profile/config.yaml`) into `dir`, both or
/// neither; the Snakefile's path.
fn write_workflow(dir: &Path, snakefile: &str, profile: &str) -> Result<PathBuf, ExitCode> {
    let (path, profile_path) = (dir.join("Snakefile"), dir.join("profile").join("config.yaml"));
    write_together(&[(Some(&path), Some(snakefile)), (Some(&profile_path), Some(profile))])?;
    Ok(path)
}
