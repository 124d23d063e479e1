//! Graph drawings: Graphviz DOT and Mermaid, with swept steps drawn as clusters.

use super::Graph;

fn esc(s: &str) -> String {
    s.replace('\\', "\\\\").replace('"', "\\\"")
}

/// The steps of a graph grouped by the recipe run as a step they belong to (`tap/segment`
/// under `tap`), in order of first appearance.
#[derive(Default)]
struct Group<'a> {
    steps: Vec<&'a str>,
    children: Vec<(&'a str, Group<'a>)>,
}

fn groups(g: &Graph) -> Group<'_> {
    let mut root = Group::default();
    for step in g.by_step.keys() {
        let mut at = &mut root;
        let parts: Vec<&str> = step.split('/').collect();
        for i in 0..parts.len() - 1 {
            let prefix = &step[..parts[..=i].iter().map(|p| p.len() + 1).sum::<usize>() - 1];
            let pos = match at.children.iter().position(|(p, _)| p == &prefix) {
                Some(pos) => pos,
                None => {
                    at.children.push((prefix, Group::default()));
                    at.children.len() - 1
                }
            };
            at = &mut at.children[pos].1;
        }
        at.steps.push(step);
    }
    root
}

fn dot_group(g: &Graph, group: &Group, indent: &str, out: &mut String) {
    for step in &group.steps {
        let ids = &g.by_step[*step];
        let kind = ids.first().map(|&i| g.instances[i].kind.as_str()).unwrap_or("");
        if ids.len() > 1 {
            out.push_str(&format!(
                "{indent}subgraph \"cluster_{}\" {{\n{indent}  label=\"{} ({kind}) × {}\";\n",
                esc(step),
                esc(step),
                ids.len()
            ));
            for &i in ids {
                out.push_str(&format!("{indent}  n{i} [label=\"{}\"];\n", esc(&g.instances[i].label)));
            }
            out.push_str(&format!("{indent}}}\n"));
        } else if let Some(&i) = ids.first() {
            out.push_str(&format!("{indent}n{i} [label=\"{}\\n{kind}\"];\n", esc(step)));
        }
    }
    for (prefix, child) in &group.children {
        out.push_str(&format!(
            "{indent}subgraph \"cluster_{}/\" {{\n{indent}  label=\"{} (recipe)\";\n{indent}  style=rounded;\n",
            esc(prefix),
            esc(prefix)
        ));
        dot_group(g, child, &format!("{indent}  "), out);
        out.push_str(&format!("{indent}}}\n"));
    }
}

/// Graphviz DOT: one box per instance, swept steps grouped, the steps of a recipe run as a
/// step in a cluster of their own, edges labelled with ports.
pub fn to_dot(g: &Graph) -> String {
    let mut out = String::from("digraph recipe {\n  rankdir=LR;\n  node [shape=box, fontname=\"Helvetica\"];\n");
    dot_group(g, &groups(g), "  ", &mut out);
    for (j, inst) in g.instances.iter().enumerate() {
        for (port, srcs) in &inst.inputs {
            for (i, out_port) in srcs {
                out.push_str(&format!("  n{i} -> n{j} [label=\"{} → {}\"];\n", esc(out_port), esc(port)));
            }
        }
    }
    out.push_str("}\n");
    out
}

fn mermaid_group(g: &Graph, group: &Group, indent: &str, out: &mut String) {
    let q = |s: &str| s.replace('"', "'");
    // Mermaid ids take no `/`.
    let id = |s: &str| s.replace('/', "__");
    for step in &group.steps {
        let ids = &g.by_step[*step];
        let kind = ids.first().map(|&i| g.instances[i].kind.as_str()).unwrap_or("");
        if ids.len() > 1 {
            out.push_str(&format!("{indent}subgraph {}[\"{} ({kind}) × {}\"]\n", id(step), q(step), ids.len()));
            for &i in ids {
                out.push_str(&format!("{indent}  n{i}[\"{}\"]\n", q(&g.instances[i].label)));
            }
            out.push_str(&format!("{indent}end\n"));
        } else if let Some(&i) = ids.first() {
            out.push_str(&format!("{indent}n{i}[\"{}<br/>{kind}\"]\n", q(step)));
        }
    }
    for (prefix, child) in &group.children {
        out.push_str(&format!("{indent}subgraph {}__recipe[\"{} (recipe)\"]\n", id(prefix), q(prefix)));
        mermaid_group(g, child, &format!("{indent}  "), out);
        out.push_str(&format!("{indent}end\n"));
    }
}

/// Mermaid flowchart of the same graph.
pub fn to_mermaid(g: &Graph) -> String {
    let mut out = String::from("flowchart LR\n");
    let q = |s: &str| s.replace('"', "'");
    mermaid_group(g, &groups(g), "  ", &mut out);
    for (j, inst) in g.instances.iter().enumerate() {
        for (port, srcs) in &inst.inputs {
            for (i, out_port) in srcs {
                out.push_str(&format!("  n{i} -->|{} → {}| n{j}\n", q(out_port), q(port)));
            }
        }
    }
    out
}
