//! A recipe as a workflow another engine schedules: `spindlelab export snakemake` writes a
//! Snakefile whose jobs are the shards of each level of the recipe's graph (each computes its
//! part into a shared cache and leaves a marker file there) and a final job that runs the
//! recipe, finds every result in the cache and commits the outputs. A job of level `L` waits
//! for every job of level `L − 1` through the workflow engine, so no instance runs twice and
//! nothing polls. The same Snakefile runs with the local executor, on a cluster
//! (`--executor cluster-generic`, Slurm, Kubernetes) given a shared folder for the cache.

use crate::codegen::{CodegenError, file_pattern, path_text, python_str};
use crate::engine::Compiled;
use crate::engine::exec::{Shard, shard};
use crate::engine::node::Registry;
use std::path::Path;

/// Where the exported workflow runs things: the command, the recipe, the output folder and
/// the shared cache, each as the jobs will see it (absolute paths on shared storage).
pub struct Places<'a> {
    pub spindlelab: &'a Path,
    pub recipe: &'a Path,
    pub out: &'a Path,
    pub cache: &'a Path,
}

/// The files of an exported workflow: the Snakefile and a profile for the local executor.
pub struct Workflow {
    pub snakefile: String,
    pub profile: String,
    pub levels: usize,
    pub shards: usize,
}

/// The Snakefile of `compiled` split into `shards` shards per level.
pub fn snakemake(
    compiled: &Compiled,
    registry: &Registry,
    places: &Places<'_>,
    shards: usize,
) -> Result<Workflow, CodegenError> {
    let shards = shards.max(1);
    let levels = shard::levels(&compiled.graph, registry);
    let one = Shard { index: 1, count: shards, level: Some(0) };
    let markers = one.marker(places.cache, &compiled.graph);
    let markers = markers.parent().expect("a marker lies in a folder");
    let snakefile = format!(
        r#"# The workflow of the recipe named in RECIPE_NAME, written by `spindlelab export snakemake`.
# {levels} level(s) of its graph, {shards} shard(s) each: each job computes its shard's instances into
# the shared cache and leaves a marker there; `collect` then runs the recipe, which finds every
# result in the cache, and commits the outputs to OUT. Run it with
#   snakemake --profile PROFILE_DIR            (the local executor: ./profile)
# or with a cluster executor (`--executor cluster-generic`, `slurm`, `kubernetes`) when OUT and
# CACHE are on storage every node sees.

RECIPE_NAME = {recipe_name}
SPINDLELAB = {exe}
RECIPE = {recipe}
OUT = {out}
CACHE = {cache}
MARKERS = {markers}
LEVELS = {levels}
SHARDS = {shards}


wildcard_constraints:
    level=r"\d+",
    shard=r"\d+",


def marker(level, shard):
    return f"{{MARKERS}}/level-{{level}}-shard-{{shard}}-of-{{SHARDS}}.done"


def level_done(level):
    return [marker(level, k) for k in range(1, SHARDS + 1)] if level >= 0 else []


rule all:
    input:
        f"{{MARKERS}}/collected",


rule collect:
    input:
        level_done(LEVELS - 1),
    output:
        f"{{MARKERS}}/collected",
    threads: 1
    shell:
        "{{SPINDLELAB:q}} run {{RECIPE:q}} -o {{OUT:q}} --cache {{CACHE:q}} -q && touch {{output:q}}"


rule shard:
    input:
        lambda wc: level_done(int(wc.level) - 1),
    output:
        MARKERS + "/level-{{level}}-shard-{{shard}}-of-" + str(SHARDS) + ".done",
    threads: 1
    resources:
        mem_mb=2000,
    shell:
        "{{SPINDLELAB:q}} run {{RECIPE:q}} -o {{OUT:q}} --cache {{CACHE:q}} --shard {{wildcards.shard}}/{{SHARDS}} --level {{wildcards.level}} -q"
"#,
        recipe_name = python_str(&compiled.recipe.name),
        exe = python_str(path_text("the spindlelab command", places.spindlelab)?),
        recipe = python_str(path_text("the recipe", places.recipe)?),
        out = python_str(path_text("the output folder", places.out)?),
        cache = python_str(path_text("the cache folder", places.cache)?),
        markers = python_str(file_pattern("the cache folder", markers)?),
    );
    Ok(Workflow { snakefile, profile: PROFILE.to_string(), levels, shards })
}

/// The profile of the local executor; it holds no text of the user's.
const PROFILE: &str = "# The local executor: every job a process on this machine.\ncores: all\nprintshellcmds: true\n";

/// A batch of diagnoses as a Snakefile: one job per case (`diagnose --batch CASE --no-summary`,
/// which leaves the case's row beside its diagnosis) and one that gathers the summary
/// (`--summary-only`). A case that fails is a row with its error, so its job still succeeds.
pub fn snakemake_batch(
    spindlelab: &Path,
    pattern: &str,
    cases: &[(std::path::PathBuf, String)],
    out: &Path,
) -> Result<Workflow, CodegenError> {
    let mut list = String::new();
    for (case, name) in cases {
        file_pattern("a case's folder", Path::new(name))?;
        list.push_str(&format!("    {}: {},\n", python_str(name), python_str(path_text("a case", case)?)));
    }
    let snakefile = format!(
        r#"# A batch of diagnoses, written by `spindlelab export snakemake --batch`: one job per case
# (import and diagnose it into OUT/<case>/), then one that gathers OUT/summary.csv and
# summary.md. Run it with `snakemake --profile PROFILE_DIR` or a cluster executor.

SPINDLELAB = {exe}
PATTERN = {pattern}
OUT = {out}
CASES = {{
{list}}}



rule all:
    input:
        f"{{OUT}}/summary.csv",


rule summary:
    input:
        [f"{{OUT}}/{{name}}/row.csv" for name in CASES],
    output:
        f"{{OUT}}/summary.csv",
        f"{{OUT}}/summary.md",
    shell:
        "{{SPINDLELAB:q}} diagnose --batch {{PATTERN:q}} -o {{OUT:q}} --summary-only -q"


rule case:
    output:
        OUT + "/{{name}}/row.csv",
    params:
        case=lambda wc: CASES[wc.name],
    threads: 2
    shell:
        "{{SPINDLELAB:q}} diagnose --batch {{params.case:q}} -o {{OUT:q}} --no-summary -q || test -f {{output:q}}"
"#,
        exe = python_str(path_text("the spindlelab command", spindlelab)?),
        pattern = python_str(pattern),
        out = python_str(file_pattern("the output folder", out)?),
    );
    Ok(Workflow { snakefile, profile: PROFILE.to_string(), levels: 1, shards: cases.len() })
}
