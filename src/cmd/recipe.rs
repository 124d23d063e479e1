//! `check`, `graph`, `plan`, `nodes` and `schema`: what a recipe holds and would do, and the
//! node kinds it can name.

use crate::*;

/// `spindlelab check RECIPE`: compiles the recipe and says what it holds, or reports its problems.
pub(crate) fn cmd_check(
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
pub(crate) fn library_contents(r: &engine::model::Recipe) -> String {
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
pub(crate) fn cmd_graph(
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
pub(crate) fn cmd_plan(
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
pub(crate) fn cmd_nodes(
    kind: Option<String>,
    registry: &mut engine::node::Registry,
    plugins: &mut Plugins,
) -> ExitCode {
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

/// `spindlelab schema`: prints the JSON Schema of the YAML recipe for the kinds in `registry`.
pub(crate) fn cmd_schema(registry: &engine::node::Registry) -> ExitCode {
    outln!("{}", serde_json::to_string_pretty(&engine::schema::recipe_schema(registry)).expect("schema serialises"));
    ExitCode::SUCCESS
}

pub(crate) fn describe_node(spec: &engine::node::NodeSpec, effect: Option<&engine::node::EffectSpec>) -> String {
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
