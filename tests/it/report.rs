//! The HTML run report: `run --report` and `spindlelab report RUN_DIR` give one self-contained
//! file with every plot, the graph, the recipe, the warnings and the manifest; it loads in a
//! headless Chromium without a console error when the machine has one.

use std::path::{Path, PathBuf};
use std::process::Command;

fn spindlelab(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_spindlelab")).args(args).output().expect("binary runs")
}

fn recipe() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/speed-dependent-sld.yaml")
}

/// Runs the example recipe with `--report` into a fresh folder.
fn reported() -> (tempfile::TempDir, PathBuf, String) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = spindlelab(&[
        "run".as_ref(),
        recipe().as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
        "--report".as_ref(),
        "-q".as_ref(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = std::fs::read_to_string(out.join("report.html")).expect("report written");
    (dir, out, html)
}

#[test]
fn the_report_holds_every_plot_the_graph_the_recipe_and_the_manifest_and_nothing_from_elsewhere() {
    let (_dir, out, html) = reported();
    assert!(html.starts_with("<!DOCTYPE html>") && html.trim_end().ends_with("</html>"));
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    // Every plot the run wrote, inline, and the graph.
    let plots: Vec<&str> = manifest["outputs"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|f| f.as_str())
        .filter(|f| f.ends_with(".svg"))
        .collect();
    assert_eq!(plots, ["lobes.svg", "tool-tip.svg"]);
    for p in &plots {
        let svg = std::fs::read_to_string(out.join(p)).unwrap();
        assert!(html.contains(svg.trim()), "{p} is not inline in the report");
        assert!(html.contains(&format!("<figcaption>{p}</figcaption>")), "{p}");
    }
    assert_eq!(html.matches("<svg").count(), plots.len() + 1, "the plots and the graph");
    // The graph names every step; the recipe and the manifest are there.
    for step in ["rig", "records", "holder_tool", "tool_tip", "sld", "truth_trials"] {
        assert!(html.contains(&format!("\n{step}\n</text>")), "step `{step}` not in the graph");
    }
    assert!(html.contains("name: speed-dependent-sld"), "the recipe text");
    assert!(html.contains("<td>sld</td><td>stability.speed_dependent</td>"), "the manifest's nodes");
    assert!(html.contains("trial-score.csv</td><td><code>"), "the manifest's files with their hashes");
    // The warnings of the run, and the small tables read back.
    assert!(html.contains("not scored: 4200 rpm"), "warnings");
    assert!(html.contains("<h3>trial-score.csv</h3>"), "small tables");
    // Self-contained: nothing loads from elsewhere.
    for outside in ["<script", "<link", "@import", "url(", "src=\"http", "href=\"http", "src=\"//", "xlink:href=\"http"]
    {
        assert!(!html.contains(outside), "the report refers outside itself: {outside}");
    }
}

#[test]
fn report_of_a_run_folder_writes_the_same_sections_and_refuses_a_folder_without_a_run() {
    let (dir, out, from_run) = reported();
    let target = dir.path().join("again.html");
    let o = spindlelab(&["report".as_ref(), out.as_os_str(), "-o".as_ref(), target.as_os_str()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let again = std::fs::read_to_string(&target).unwrap();
    // The same report, but for the file list: the folder now holds report.html too.
    let head = |s: &str| s.split("<h2 id=\"manifest\">").next().unwrap().to_string();
    assert_eq!(head(&again), head(&from_run));
    assert!(again.contains("<td>report.html</td>"));
    // The default place is beside the folder.
    let o = spindlelab(&["report".as_ref(), out.as_os_str()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(dir.path().join("out.report.html").is_file());
    // A folder without a run.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let o = spindlelab(&["report".as_ref(), empty.as_os_str()]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("holds no readable manifest.json") && e.contains("give the output folder of a run"), "{e}");
}

/// Loads the report in headless Chromium (Debian's `chromium`) as a reader would see it: every
/// figure decoded (its natural size above zero, checked by a script added to a copy of the
/// page, which writes what it found into the page), a screenshot that is not blank where the
/// figures are, and no console error. Without a browser it says so and passes, except where
/// `SPINDLELAB_REQUIRE_BROWSER` is set (CI installs Chromium and sets it), so there a missing
/// browser fails the test. A copy with one figure's data broken must fail the same checks.
#[test]
fn the_report_loads_in_a_headless_browser_with_every_figure_shown() {
    let Some(browser) = ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .find(|b| Command::new(b).arg("--version").output().is_ok_and(|o| o.status.success()))
    else {
        assert!(
            std::env::var_os("SPINDLELAB_REQUIRE_BROWSER").is_none(),
            "SPINDLELAB_REQUIRE_BROWSER is set and no Chromium runs here: install Debian's `chromium`"
        );
        eprintln!("no Chromium on this machine: the browser check is skipped");
        return;
    };
    let (dir, out, html) = reported();
    let figures = html.matches("<figure").count();
    assert!(figures >= 2, "{figures} figures in the report");
    // Counts the figures the browser shows (an image decoded to a natural size above zero, an
    // inline drawing laid out with a size and something in it) and writes the count where
    // --dump-dom shows it.
    let check = r#"<script>
window.addEventListener("load", () => {
  const figs = [...document.querySelectorAll("figure")];
  const shown = figs.filter(f => {
    const img = f.querySelector("img");
    if (img) return img.complete && img.naturalWidth > 0 && img.naturalHeight > 0;
    const svg = f.querySelector("svg");
    if (!svg) return false;
    const r = svg.getBoundingClientRect();
    return r.width > 0 && r.height > 0 && svg.childElementCount > 0;
  }).length;
  const p = document.createElement("p");
  p.id = "figure-check";
  p.textContent = `figures shown: ${shown} of ${figs.length}`;
  document.body.prepend(p);
});
</script>"#;
    let load = |name: &str, page: &str| {
        let path = out.join(name);
        std::fs::write(&path, page.replace("</body>", &format!("{check}</body>"))).unwrap();
        let url = format!("file://{}", path.canonicalize().unwrap().display());
        let shot = dir.path().join(format!("{name}.png"));
        let run = |extra: &[&str]| {
            Command::new(browser)
                .args(["--headless", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr", "--v=0"])
                .args(["--hide-scrollbars", "--window-size=1000,2400", "--virtual-time-budget=5000"])
                .arg(format!("--user-data-dir={}", dir.path().join("profile").display()))
                .args(extra)
                .arg(&url)
                .output()
                .expect("browser runs")
        };
        let o = run(&["--dump-dom"]);
        let dom = String::from_utf8_lossy(&o.stdout).to_string();
        let mut log = String::from_utf8_lossy(&o.stderr).to_string();
        let s = run(&[&format!("--screenshot={}", shot.display())]);
        log.push_str(&String::from_utf8_lossy(&s.stderr));
        (dom, log, std::fs::read(&shot).unwrap_or_default())
    };
    let (dom, log, shot) = load("checked.html", &html);
    let console: Vec<&str> = log
        .lines()
        .filter(|l| l.contains("CONSOLE") || l.contains("Uncaught") || l.contains("ERR_FILE_NOT_FOUND"))
        .collect();
    assert!(console.is_empty(), "console errors:\n{}", console.join("\n"));
    assert!(dom.contains(&format!("figures shown: {figures} of {figures}")), "not every figure decoded:\n{log}");
    // The screenshot: a page, not a blank, with the first figure's colours on it.
    let mut reader = png::Decoder::new(std::io::Cursor::new(&shot)).read_info().expect("a screenshot");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("a frame");
    let channels = info.color_type.samples();
    let drawn = buf[..info.buffer_size()].chunks(channels).filter(|p| p[..3].iter().any(|&c| c < 200)).count();
    let share = drawn as f64 / (info.width * info.height) as f64;
    assert!(share > 0.02, "the screenshot is nearly blank: {:.2} % drawn", 100.0 * share);
    // One figure broken (an image's data, or an inline drawing emptied to no size): the check
    // sees it.
    let broken = match html.find("base64,") {
        Some(at) => format!("{}!!!!{}", &html[..at + 7], &html[at + 11..]),
        None => html.replacen("<svg", "<svg style=\"display:none\"", 1),
    };
    let (dom, _, _) = load("broken.html", &broken);
    assert!(dom.contains(&format!("figures shown: {} of {figures}", figures - 1)), "a broken figure went unseen");
}
