//! `plugin`: third-party node kinds checked, listed and installed.

use crate::*;

pub(crate) fn plugin_command(action: PluginAction, plugins: &mut Plugins) -> ExitCode {
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
