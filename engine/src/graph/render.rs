//! Graph drawings: Graphviz DOT and Mermaid, with swept steps drawn as clusters.

use super::Graph;

fn esc(s: &str) -> String {
    s.replace('\\', "\\\\").replace('"', "\\\"")
}

/// Graphviz DOT: one box per instance, swept steps grouped, edges labelled with ports.
pub fn to_dot(g: &Graph) -> String {
    let mut out = String::from("digraph recipe {\n  rankdir=LR;\n  node [shape=box, fontname=\"Helvetica\"];\n");
    for (step, ids) in &g.by_step {
        let kind = ids.first().map(|&i| g.instances[i].kind.as_str()).unwrap_or("");
        if ids.len() > 1 {
            out.push_str(&format!(
                "  subgraph \"cluster_{}\" {{\n    label=\"{} ({kind}) × {}\";\n",
                esc(step),
                esc(step),
                ids.len()
            ));
            for &i in ids {
                out.push_str(&format!("    n{i} [label=\"{}\"];\n", esc(&g.instances[i].label)));
            }
            out.push_str("  }\n");
        } else if let Some(&i) = ids.first() {
            out.push_str(&format!("  n{i} [label=\"{}\\n{kind}\"];\n", esc(step)));
        }
    }
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

/// Mermaid flowchart of the same graph.
pub fn to_mermaid(g: &Graph) -> String {
    let mut out = String::from("flowchart LR\n");
    let q = |s: &str| s.replace('"', "'");
    for (step, ids) in &g.by_step {
        let kind = ids.first().map(|&i| g.instances[i].kind.as_str()).unwrap_or("");
        if ids.len() > 1 {
            out.push_str(&format!("  subgraph {step}[\"{} ({kind}) × {}\"]\n", q(step), ids.len()));
            for &i in ids {
                out.push_str(&format!("    n{i}[\"{}\"]\n", q(&g.instances[i].label)));
            }
            out.push_str("  end\n");
        } else if let Some(&i) = ids.first() {
            out.push_str(&format!("  n{i}[\"{}<br/>{kind}\"]\n", q(step)));
        }
    }
    for (j, inst) in g.instances.iter().enumerate() {
        for (port, srcs) in &inst.inputs {
            for (i, out_port) in srcs {
                out.push_str(&format!("  n{i} -->|{} → {}| n{j}\n", q(out_port), q(port)));
            }
        }
    }
    out
}
