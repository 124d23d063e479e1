//! Runs every recipe in `scripts/` and snapshots a stable summary of its outputs, and holds
//! every plot against a reviewed reference image (`tests/figures/`).
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
    insta::glob!("../../scripts", "*.{yaml,rhai}", |path| {
        let mut registry = spindlelab::registry();
        let compiled = match spindlelab::plugins::compile_file(path, &[], &mut registry, &mut plugins) {
            Ok(c) => c,
            Err(e) => panic!("{} does not compile:\n{}", path.display(), e.render(false)),
        };
        let out = tempfile::tempdir().expect("temp dir");
        let mut opts = RunOptions::new(out.path()).with_renderer(spindlelab::renderer());
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
        // Every plot, drawn as PNG, against its reviewed reference image.
        for o in &compiled.recipe.outputs {
            if let Some(png) = engine::plot_of_output(
                &compiled,
                &report.result,
                o,
                engine::plot::PlotFormat::Png,
                &spindlelab::render::Plotters,
            ) {
                let png = png.unwrap_or_else(|e| panic!("{}: {}: {e}", path.display(), o.file));
                check_figure(path, &o.file, &png);
            }
        }
    });
}

/// Compares a plot with `tests/figures/RECIPE/FILE.png`, the image a person reviewed: the
/// same size, and at most 0.5 % of the pixels off by more than a faint shade (so a change of
/// font hinting passes and a moved curve, axis or legend fails). With
/// `SPINDLELAB_UPDATE_FIGURES=1` the references are rewritten for review instead; a failing
/// figure is saved beside the test's temporary files to look at.
fn check_figure(recipe: &std::path::Path, file: &str, png: &[u8]) {
    let stem = recipe.file_stem().unwrap().to_string_lossy().to_string();
    let name = std::path::Path::new(file).with_extension("png");
    let reference = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/figures").join(&stem).join(&name);
    if std::env::var_os("SPINDLELAB_UPDATE_FIGURES").is_some() {
        std::fs::create_dir_all(reference.parent().unwrap()).unwrap();
        std::fs::write(&reference, png).unwrap();
        return;
    }
    let actual = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("figures").join(&stem).join(&name);
    let keep = || {
        std::fs::create_dir_all(actual.parent().unwrap()).unwrap();
        std::fs::write(&actual, png).unwrap();
    };
    let Ok(want) = std::fs::read(&reference) else {
        keep();
        panic!(
            "{stem}: no reference image {}; review {} and run with SPINDLELAB_UPDATE_FIGURES=1 to keep it",
            reference.display(),
            actual.display()
        );
    };
    let (a, b) = (pixels(png), pixels(&want));
    if a.0 != b.0 {
        keep();
        panic!("{stem}/{file}: {:?} pixels, the reference {:?}; see {}", a.0, b.0, actual.display());
    }
    let off =
        a.1.chunks(3).zip(b.1.chunks(3)).filter(|(p, q)| p.iter().zip(*q).any(|(x, y)| x.abs_diff(*y) > 48)).count();
    let fraction = off as f64 / (a.0.0 * a.0.1) as f64;
    if fraction > 0.005 {
        keep();
        panic!(
            "{stem}/{file}: {:.2} % of the pixels differ from the reference; see {} against {}",
            100.0 * fraction,
            actual.display(),
            reference.display()
        );
    }
}

/// A PNG's size and RGB bytes.
fn pixels(png: &[u8]) -> ((u32, u32), Vec<u8>) {
    let mut reader = png::Decoder::new(std::io::Cursor::new(png)).read_info().expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("a PNG frame");
    assert_eq!(info.color_type, png::ColorType::Rgb, "plots are RGB");
    buf.truncate(info.buffer_size());
    ((info.width, info.height), buf)
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
