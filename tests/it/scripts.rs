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
/// same size, and at most [`DATA_PIXELS_OFF`] of its drawn pixels (those not background in
/// either image: curves, markers, axes, text) off by more than a faint shade, so a change of
/// font hinting passes and an erased or moved curve, axis or legend fails. With
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
    let fraction = drawn_pixels_off(&a.1, &b.1);
    if fraction > DATA_PIXELS_OFF {
        keep();
        panic!(
            "{stem}/{file}: {:.2} % of the drawn pixels differ from the reference; see {} against {}",
            100.0 * fraction,
            actual.display(),
            reference.display()
        );
    }
}

/// The share of drawn pixels two renderings may differ in: text rasterised a shade apart at a
/// few edges, not a curve (a curve is several per cent of what is drawn).
const DATA_PIXELS_OFF: f64 = 0.01;

/// The background of a plot: white, and anything within a faint shade of it.
fn is_background(p: &[u8]) -> bool {
    p.iter().all(|&c| c >= 250)
}

/// The share of the pixels drawn in either RGB image (not background) that differ by more than
/// a faint shade in some channel.
fn drawn_pixels_off(a: &[u8], b: &[u8]) -> f64 {
    let (mut drawn, mut off) = (0usize, 0usize);
    for (p, q) in a.chunks(3).zip(b.chunks(3)) {
        if is_background(p) && is_background(q) {
            continue;
        }
        drawn += 1;
        if p.iter().zip(q).any(|(x, y)| x.abs_diff(*y) > 48) {
            off += 1;
        }
    }
    if drawn == 0 { 0.0 } else { off as f64 / drawn as f64 }
}

/// The comparison sees a curve: in every reference figure, erasing the pixels of its most
/// common curve colour, or moving them three pixels up and right, differs by more than the allowance;
/// the figure against itself differs by nothing.
#[test]
fn the_figure_check_fails_when_a_curve_is_erased_or_moved() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/figures");
    let mut checked = 0;
    for recipe in std::fs::read_dir(&root).unwrap().flatten() {
        for figure in std::fs::read_dir(recipe.path()).unwrap().flatten() {
            let ((w, h), px) = pixels(&std::fs::read(figure.path()).unwrap());
            let (w, h) = (w as usize, h as usize);
            // A curve's colour: the most common saturated colour (not a grey of text or axes).
            let mut counts = std::collections::HashMap::new();
            for p in px.chunks(3) {
                let (lo, hi) = (p.iter().min().unwrap(), p.iter().max().unwrap());
                if hi - lo > 60 {
                    *counts.entry([p[0], p[1], p[2]]).or_insert(0usize) += 1;
                }
            }
            let Some((&colour, _)) = counts.iter().max_by_key(|(c, n)| (**n, **c)) else { continue };
            let name = figure.path().display().to_string();
            assert_eq!(drawn_pixels_off(&px, &px), 0.0, "{name}");
            let is_curve = |i: usize| px[3 * i..3 * i + 3] == colour;
            let mut erased = px.clone();
            let mut moved = px.clone();
            for i in 0..w * h {
                if is_curve(i) {
                    erased[3 * i..3 * i + 3].copy_from_slice(&[255, 255, 255]);
                    moved[3 * i..3 * i + 3].copy_from_slice(&[255, 255, 255]);
                }
            }
            // Three pixels up and three to the right: a curve of any slope, or a bar, moves.
            for i in (3 * w)..w * h {
                if is_curve(i) && i % w + 3 < w {
                    let to = i - 3 * w + 3;
                    moved[3 * to..3 * to + 3].copy_from_slice(&colour);
                }
            }
            for (what, image) in [("erased", &erased), ("moved", &moved)] {
                let off = drawn_pixels_off(image, &px);
                assert!(
                    off > DATA_PIXELS_OFF,
                    "{name}: its curve {what}, {:.2} % of the drawn pixels differ",
                    100.0 * off
                );
            }
            checked += 1;
        }
    }
    assert!(checked >= 20, "{checked} figures");
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
