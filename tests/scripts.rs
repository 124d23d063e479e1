//! Runs every recipe in `scripts/` and snapshots a stable summary of its outputs.
//!
//! Numbers are rounded to `summary::SIGNIFICANT_DIGITS` significant digits; timings and
//! paths are left out of the summary, so snapshots change only when results do.

use spindlelab::engine::{self, exec::RunOptions};

#[test]
fn every_recipe_in_scripts() {
    let registry = spindlelab::registry();
    insta::glob!("../scripts", "*.{yaml,rhai}", |path| {
        let compiled = match engine::compile_file(path, &registry) {
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
        summary.push_str(&format!(
            "written: {}\n(numbers to {} significant digits)\n",
            report.written.join(", "),
            spindlelab::summary::SIGNIFICANT_DIGITS
        ));
        insta::assert_snapshot!(summary);
    });
}
