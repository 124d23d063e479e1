//! Runs every recipe in `scripts/` and snapshots a stable summary of its outputs.
//!
//! Numbers are rounded to `summary::SIGNIFICANT_DIGITS` significant digits; timings and
//! paths are left out of the summary, so snapshots change only when results do.

use spindlelab::engine::{self, exec::RunOptions};

#[test]
fn every_recipe_in_scripts() {
    // The example plugins the recipes name, built once for the tests.
    let mut plugins = spindlelab::plugins::Plugins::with(
        vec![spindlelab_plugin_examples::dir().to_path_buf()],
        Default::default(),
        Some(std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("plugin-cache")),
    );
    insta::glob!("../scripts", "*.{yaml,rhai}", |path| {
        let mut registry = spindlelab::registry();
        let compiled = match spindlelab::plugins::compile_file(path, &[], &mut registry, &mut plugins) {
            Ok(c) => c,
            Err(e) => panic!("{} does not compile:\n{}", path.display(), e.render(false)),
        };
        let out = tempfile::tempdir().expect("temp dir");
        let mut opts = RunOptions::new(out.path());
        opts.use_cache = false;
        let report = match engine::run(&compiled, &registry, &opts, &|_, _| {}) {
            Ok(r) => r,
            Err(e) => panic!("{} failed: {e}", path.display()),
        };
        let mut summary = spindlelab::summary::summarize(&compiled, &report.result);
        for file in report.written.iter().filter(|f| f.ends_with(".svg")) {
            let svg = std::fs::read_to_string(out.path().join(file)).expect("plot written");
            summary.push_str(&svg_outline(file, &svg));
        }
        summary.push_str(&format!(
            "written: {}\n(numbers to {} significant digits)\n",
            report.written.join(", "),
            spindlelab::summary::SIGNIFICANT_DIGITS
        ));
        insta::assert_snapshot!(summary);
        // What `spindlelab run` prints by default.
        insta::assert_snapshot!("short", spindlelab::summary::short(&compiled, &report.result));
    });
}

/// A plot in a normalised form: how many of each drawing element, and every text it shows
/// (title, axis labels, ticks, legend), so a snapshot shows what changed without the geometry.
fn svg_outline(file: &str, svg: &str) -> String {
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"), "{file} is not an SVG document");
    let mut counts = std::collections::BTreeMap::new();
    for tag in ["polyline", "circle", "line", "polygon", "rect", "text"] {
        counts.insert(tag, svg.matches(&format!("<{tag} ")).count() + svg.matches(&format!("<{tag}>")).count());
    }
    let texts: Vec<&str> = svg
        .split("<text")
        .skip(1)
        .filter_map(|t| t.split_once('>').and_then(|(_, rest)| rest.split_once("</text>")).map(|(text, _)| text.trim()))
        .collect();
    let counts: Vec<String> = counts.iter().map(|(t, n)| format!("{n} {t}")).collect();
    format!("plot {file}: {}\n  texts: {}\n", counts.join(", "), texts.join(" | "))
}
