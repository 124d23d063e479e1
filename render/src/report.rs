//! The run report: one self-contained HTML file from a run folder's manifest and files — the
//! recipe, the graph drawn in-process, every plot inline, the small tables, warnings and the
//! manifest. Nothing in it loads from elsewhere (no scripts, fonts or style sheets), so it
//! opens offline and reads the same in ten years.

use crate::draw;
use indexmap::IndexMap;
use plotters::prelude::*;
use spindlelab_engine::exec::Manifest;
use spindlelab_engine::plot::PlotError;
use std::fmt::Write as _;

/// Tables of at most this many rows are shown in the report; longer ones are listed by name.
const MAX_TABLE_ROWS: usize = 40;

/// Text escaped for HTML.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// A number for a table cell: 4 significant digits, or the text as written.
fn cell(text: &str) -> String {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => {
            let r = spindlelab_domain::round_sig(v, 4);
            if r != 0.0 && !(1e-3..1e6).contains(&r.abs()) { format!("{r:.3e}") } else { format!("{r}") }
        }
        _ => esc(text.trim().trim_matches('"')),
    }
}

/// The step of an instance id (`rig[speed=0 rpm]` → `rig`).
fn step_of(id: &str) -> &str {
    id.split('[').next().unwrap_or(id)
}

/// The steps in manifest order with their kind, instance count and worst status, and the
/// edges between steps with the ports they carry.
#[allow(clippy::type_complexity)]
fn step_graph(m: &Manifest) -> (Vec<(String, String, usize, String)>, Vec<(usize, usize, String)>) {
    let mut steps: IndexMap<String, (String, usize, String)> = IndexMap::new();
    let mut key_step: IndexMap<&str, usize> = IndexMap::new();
    for n in &m.nodes {
        let s = step_of(&n.id).to_string();
        let e = steps.entry(s.clone()).or_insert_with(|| (n.kind.clone(), 0, String::new()));
        e.1 += 1;
        let rank = |st: &str| ["unneeded", "cached", "computed", "skipped", "failed"].iter().position(|x| *x == st);
        if rank(&n.status) > rank(&e.2) {
            e.2 = n.status.clone();
        }
        key_step.insert(n.key.as_str(), steps.get_index_of(&s).expect("inserted"));
    }
    let mut edges: Vec<(usize, usize, String)> = Vec::new();
    for n in &m.nodes {
        let to = steps.get_index_of(step_of(&n.id)).expect("inserted");
        for (port, srcs) in &n.inputs {
            for src in srcs {
                let key = src.split('.').next().unwrap_or(src);
                if let Some(&from) = key_step.get(key)
                    && !edges.iter().any(|(a, b, p)| *a == from && *b == to && p == port)
                {
                    edges.push((from, to, port.clone()));
                }
            }
        }
    }
    (steps.into_iter().map(|(s, (k, c, st))| (s, k, c, st)).collect(), edges)
}

/// The recipe's graph as SVG: steps as boxes in columns by depth, inputs as arrows.
pub fn graph_svg(m: &Manifest) -> Result<String, PlotError> {
    let (steps, edges) = step_graph(m);
    let mut layer = vec![0usize; steps.len()];
    // Manifest order is dependency order: one pass settles every depth.
    for _ in 0..steps.len() {
        let mut changed = false;
        for (a, b, _) in &edges {
            if layer[*b] < layer[*a] + 1 {
                layer[*b] = layer[*a] + 1;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    let columns = layer.iter().max().map_or(0, |m| m + 1);
    let mut row = vec![0usize; steps.len()];
    let mut per_column = vec![0usize; columns];
    for (i, &l) in layer.iter().enumerate() {
        row[i] = per_column[l];
        per_column[l] += 1;
    }
    let rows = per_column.iter().copied().max().unwrap_or(0);
    let (bw, bh, gx, gy, pad) = (180i32, 46i32, 60i32, 22i32, 16i32);
    let width = (pad * 2 + columns as i32 * (bw + gx) - gx).max(200) as u32;
    let height = (pad * 2 + rows as i32 * (bh + gy) - gy).max(60) as u32;
    let at = |i: usize| (pad + layer[i] as i32 * (bw + gx), pad + row[i] as i32 * (bh + gy));
    let mut out = String::new();
    draw::register_font()?;
    {
        let root = SVGBackend::with_string(&mut out, (width, height)).into_drawing_area();
        let e = |x: DrawingAreaErrorKind<_>| PlotError::Draw(format!("{x:?}"));
        root.fill(&WHITE).map_err(e)?;
        for (a, b, _) in &edges {
            let ((xa, ya), (xb, yb)) = (at(*a), at(*b));
            let (x0, y0, x1, y1) = (xa + bw, ya + bh / 2, xb, yb + bh / 2);
            let grey = RGBColor(120, 120, 120);
            root.draw(&PathElement::new(
                vec![(x0, y0), ((x0 + x1) / 2, y0), ((x0 + x1) / 2, y1), (x1 - 6, y1)],
                grey.stroke_width(1),
            ))
            .map_err(e)?;
            root.draw(&Polygon::new(vec![(x1, y1), (x1 - 7, y1 - 4), (x1 - 7, y1 + 4)], grey.filled())).map_err(e)?;
        }
        for (i, (name, kind, count, status)) in steps.iter().enumerate() {
            let (x, y) = at(i);
            let border = match status.as_str() {
                "failed" => RGBColor(214, 39, 40),
                "skipped" => RGBColor(255, 127, 14),
                "cached" => RGBColor(127, 127, 127),
                _ => RGBColor(31, 119, 180),
            };
            root.draw(&Rectangle::new([(x, y), (x + bw, y + bh)], RGBColor(247, 249, 252).filled())).map_err(e)?;
            root.draw(&Rectangle::new([(x, y), (x + bw, y + bh)], border.stroke_width(2))).map_err(e)?;
            let fit = |s: &str, n: usize| {
                if s.chars().count() > n {
                    format!("{}…", s.chars().take(n - 1).collect::<String>())
                } else {
                    s.to_string()
                }
            };
            root.draw(&Text::new(fit(name, 24), (x + 8, y + 8), ("sans-serif", 14).into_font().color(&BLACK)))
                .map_err(e)?;
            let sub = if *count > 1 { format!("{kind} ×{count}") } else { kind.clone() };
            root.draw(&Text::new(
                fit(&sub, 28),
                (x + 8, y + 27),
                ("sans-serif", 12).into_font().color(&RGBColor(90, 90, 90)),
            ))
            .map_err(e)?;
        }
        root.present().map_err(e)?;
    }
    Ok(out)
}

/// A CSV file as an HTML table, if it is small enough to read on a page.
fn csv_table(text: &str) -> Option<String> {
    let lines: Vec<&str> = text.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty()).collect();
    let (header, rows) = lines.split_first()?;
    if rows.len() > MAX_TABLE_ROWS || rows.is_empty() {
        return None;
    }
    let mut s = String::from("<table><thead><tr>");
    for h in header.split(',') {
        let _ = write!(s, "<th>{}</th>", esc(h));
    }
    s.push_str("</tr></thead><tbody>");
    for r in rows {
        s.push_str("<tr>");
        for c in r.split(',') {
            let _ = write!(s, "<td>{}</td>", cell(c));
        }
        s.push_str("</tr>");
    }
    s.push_str("</tbody></table>");
    Some(s)
}

fn base64(bytes: &[u8]) -> String {
    use base64::Engine as _;
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}\
h1{font-size:1.6em}h2{font-size:1.25em;border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:2em}\
table{border-collapse:collapse;font-size:.85em;margin:.5em 0}td,th{border:1px solid #ddd;padding:.2em .5em;text-align:right}\
th{background:#f3f5f8}td:first-child,th:first-child{text-align:left}pre{background:#f7f7f7;padding:1em;overflow:auto;font-size:.85em}\
.warn{color:#8a4b00}.fail{color:#b00020}figure{margin:1em 0}figcaption{font-size:.9em;color:#555}\
.graph{overflow:auto}.graph svg{max-width:none}svg{max-width:100%;height:auto}";

/// A self-contained page with the report's style around `body` (HTML), titled `title`.
pub fn standalone(title: &str, body: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title><style>{STYLE}</style></head><body>\n{body}\n</body></html>\n",
        esc(title)
    )
}

/// An SVG file as a figure the page carries itself (a data URI), with `id` to link to.
pub fn svg_figure(id: &str, caption: &str, svg: &[u8]) -> String {
    format!(
        "<figure id=\"{}\"><img alt=\"{}\" src=\"data:image/svg+xml;base64,{}\"><figcaption>{}</figcaption></figure>",
        esc(id),
        esc(caption),
        base64(svg),
        esc(caption)
    )
}

/// The report of a run: its manifest and its files (name and bytes, as in the folder).
pub fn html(m: &Manifest, recipe_text: Option<&str>, files: &[(String, Vec<u8>)]) -> String {
    let mut s = String::new();
    let _ = write!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{} — spindlelab run report</title><style>{STYLE}</style></head><body>\n",
        esc(&m.recipe_name)
    );
    let _ = writeln!(s, "<h1>{}</h1>", esc(&m.recipe_name));
    let failed = m.nodes.iter().filter(|n| n.status == "failed").count();
    let _ = writeln!(
        s,
        "<p>{} · recipe <code>{}</code> (hash <code>{}</code>) · {} node instance(s): {} computed, {} from cache{} · {:.3} s</p>",
        esc(&m.tool),
        esc(&m.recipe_path),
        esc(&m.recipe_hash[..m.recipe_hash.len().min(16)]),
        m.nodes.len(),
        m.computed,
        m.cache_hits,
        if failed > 0 { format!(", <span class=\"fail\">{failed} failed</span>") } else { String::new() },
        m.seconds
    );
    // Problems first: what failed, what warned, what the run noticed.
    let warnings: Vec<(&str, &str)> =
        m.nodes.iter().flat_map(|n| n.warnings.iter().map(move |w| (n.id.as_str(), w.as_str()))).collect();
    if failed > 0 || !warnings.is_empty() || !m.notes.is_empty() {
        s.push_str("<h2 id=\"warnings\">Failures and warnings</h2>\n<ul>\n");
        for n in m.nodes.iter().filter(|n| n.status == "failed") {
            let _ = writeln!(
                s,
                "<li class=\"fail\"><b>{}</b> failed: {}</li>",
                esc(&n.id),
                esc(n.error.as_deref().unwrap_or(""))
            );
        }
        // One line per step and message, with how many of its instances raised it.
        let mut grouped: IndexMap<(&str, &str), Vec<&str>> = IndexMap::new();
        for (id, w) in &warnings {
            grouped.entry((step_of(id), w)).or_default().push(id);
        }
        for ((step, w), ids) in &grouped {
            let which = if ids.len() == 1 { esc(ids[0]) } else { format!("{} ({} instances)", esc(step), ids.len()) };
            let _ = writeln!(s, "<li class=\"warn\"><b>{which}</b>: {}</li>", esc(w));
        }
        for n in &m.notes {
            let _ = writeln!(s, "<li class=\"warn\">{}</li>", esc(n));
        }
        s.push_str("</ul>\n");
    }
    s.push_str("<h2 id=\"plots\">Plots</h2>\n");
    let mut plots = 0;
    for (name, bytes) in files {
        if name.ends_with(".svg") {
            let text = String::from_utf8_lossy(bytes);
            let _ = writeln!(s, "<figure>{}<figcaption>{}</figcaption></figure>", text.trim(), esc(name));
            plots += 1;
        } else if name.ends_with(".png") {
            let _ = writeln!(
                s,
                "<figure><img alt=\"{0}\" src=\"data:image/png;base64,{1}\"><figcaption>{0}</figcaption></figure>",
                esc(name),
                base64(bytes)
            );
            plots += 1;
        }
    }
    if plots == 0 {
        s.push_str("<p>The recipe asks for no plot (name an output <code>.svg</code> or <code>.png</code>).</p>\n");
    }
    s.push_str("<h2 id=\"numbers\">Tables</h2>\n");
    let mut long = Vec::new();
    for (name, bytes) in files.iter().filter(|(n, _)| n.ends_with(".csv")) {
        match csv_table(&String::from_utf8_lossy(bytes)) {
            Some(t) => {
                let _ = write!(s, "<h3>{}</h3>\n{t}\n", esc(name));
            }
            None => long.push(esc(name)),
        }
    }
    if !long.is_empty() {
        let _ = writeln!(s, "<p>Longer data files, not shown: {}.</p>", long.join(", "));
    }
    s.push_str("<h2 id=\"graph\">Graph</h2>\n");
    match graph_svg(m) {
        Ok(svg) => {
            let _ = writeln!(s, "<div class=\"graph\">{}</div>", svg.trim());
        }
        Err(e) => {
            let _ = writeln!(s, "<p class=\"warn\">The graph could not be drawn: {}</p>", esc(&e.to_string()));
        }
    }
    if let Some(text) = recipe_text {
        let _ = write!(s, "<h2 id=\"recipe\">Recipe</h2>\n<pre>{}</pre>\n", esc(text));
    }
    s.push_str("<h2 id=\"manifest\">Manifest</h2>\n<table><thead><tr><th>instance</th><th>kind</th><th>version</th><th>status</th><th>seconds</th></tr></thead><tbody>\n");
    for n in &m.nodes {
        let _ = writeln!(
            s,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.4}</td></tr>",
            esc(&n.id),
            esc(&n.kind),
            n.version,
            esc(&n.status),
            n.seconds
        );
    }
    s.push_str("</tbody></table>\n<table><thead><tr><th>file</th><th>BLAKE3</th></tr></thead><tbody>\n");
    for (f, h) in &m.files {
        let _ = writeln!(s, "<tr><td>{}</td><td><code>{}</code></td></tr>", esc(f), esc(h));
    }
    s.push_str("</tbody></table>\n</body></html>\n");
    s
}
