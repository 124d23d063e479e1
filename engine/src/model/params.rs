//! Recipe parameters: `params: { kt: 2e8 N/m }` at the top, `$kt` wherever a value goes.
//!
//! Parameters are substituted into the raw tree before it is resolved, so a `$kt` is checked
//! exactly as the value written in its place would be (its unit against the field), and the
//! cache key of every step follows the value: a step whose entity or parameter uses `$kt`
//! reruns when `kt` changes, and only such steps do. The command line (`--set kt=3e8N/m`)
//! and a fit replace a parameter's value the same way.

use crate::diag::{Diagnostic, Diagnostics, Span};
use crate::spec::suggest;
use crate::syntax::{Raw, RawKind};
use indexmap::IndexMap;
use spindlelab_grammar::{Dimension, parse_quantity, parse_unit};

/// Top-level sections a `$name` is not substituted in: the declarations themselves and the
/// fit block, which names parameters without `$`.
const NOT_SUBSTITUTED: &[&str] = &["params", "fit"];

/// One declared parameter and its value in this compilation.
#[derive(Debug, Clone)]
pub struct Parameter {
    pub name: String,
    /// The value as written (in the recipe, or by `--set`), e.g. `2e8 N/m`.
    pub text: String,
    /// Where it is declared in the recipe.
    pub span: Span,
    /// When the value is a single quantity: its number in the unit written, the unit text
    /// and the SI value with its dimension.
    pub quantity: Option<ParamQuantity>,
    /// Whether the command line (or a fit) set the value.
    pub overridden: bool,
}

/// A parameter's value as a number in the unit the recipe writes it in.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamQuantity {
    /// The number as written, e.g. `2e8` in `2e8 N/m`.
    pub number: f64,
    /// The unit as written (`N/m`; empty for a plain number).
    pub unit: String,
    /// SI value of one unit (`number * scale` is the SI value).
    pub scale: f64,
    pub dim: Dimension,
}

impl ParamQuantity {
    /// Splits `2e8 N/m` into its number and unit; `None` when the text is not one quantity.
    pub fn parse(text: &str) -> Option<ParamQuantity> {
        let text = text.trim();
        let q = parse_quantity(text).ok()?;
        // The longest prefix that reads as a number is the number; the rest is the unit.
        let (number, rest) = (1..=text.len())
            .rev()
            .filter(|&k| text.is_char_boundary(k))
            .find_map(|k| text[..k].parse::<f64>().ok().map(|n| (n, text[k..].trim())))?;
        let scale = if rest.is_empty() { 1.0 } else { parse_unit(rest).ok()?.scale };
        Some(ParamQuantity { number, unit: rest.to_string(), scale, dim: q.dim })
    }

    /// The value in SI.
    pub fn si(&self) -> f64 {
        self.number * self.scale
    }

    /// Text for a number in this parameter's unit, exact on reading back.
    pub fn text_for(&self, number: f64) -> String {
        if self.unit.is_empty() { format!("{number:e}") } else { format!("{number:e} {}", self.unit) }
    }
}

/// Where a value set from outside the recipe file comes from.
pub fn command_line_span() -> Span {
    Span::file_only(std::sync::Arc::from("--set"))
}

/// Substitutes parameters into the raw tree. `overrides` are `(name, value text)` pairs
/// from the command line or a fit; each must name a declared parameter and keep its
/// dimension. Returns the tree with every `$name` replaced and the parameter table.
pub fn substitute(
    raw: &Raw,
    overrides: &[(String, String)],
    diags: &mut Diagnostics,
) -> (Raw, IndexMap<String, Parameter>) {
    let mut table: IndexMap<String, Parameter> = IndexMap::new();
    let mut values: IndexMap<String, Raw> = IndexMap::new();
    let mut tree = raw.clone();
    if let Some(section) = raw.get("params") {
        match section.as_map() {
            Some(entries) => {
                for (k, v) in entries {
                    let text = match v.scalar_text() {
                        Some(t) if !matches!(v.kind, RawKind::Bool(_)) => t,
                        _ => {
                            diags.error_help(
                                Some(&v.span),
                                format!(
                                    "parameter `{}` must be a number with its unit or a text, found {}",
                                    k.name,
                                    v.describe()
                                ),
                                "write e.g. `kt: 2e8 N/m`",
                            );
                            continue;
                        }
                    };
                    if text.trim_start().starts_with('$') {
                        diags.error_help(
                            Some(&v.span),
                            format!("parameter `{}` refers to another parameter", k.name),
                            "give every parameter its own value",
                        );
                        continue;
                    }
                    table.insert(
                        k.name.clone(),
                        Parameter {
                            name: k.name.clone(),
                            quantity: ParamQuantity::parse(&text),
                            text,
                            span: v.span.clone(),
                            overridden: false,
                        },
                    );
                    values.insert(k.name.clone(), v.clone());
                }
            }
            None => diags.error_help(
                Some(&section.span),
                format!("`params` must be a mapping of names to values, found {}", section.describe()),
                "write e.g. `params: { kt: 2e8 N/m }`",
            ),
        }
    }
    for (name, text) in overrides {
        let Some(p) = table.get_mut(name) else {
            let msg = format!("`--set {name}=…`: the recipe declares no parameter `{name}`");
            let help = match suggest(name, table.keys().map(String::as_str)) {
                Some(s) => format!("did you mean `{s}`?"),
                None if table.is_empty() => "declare it under `params:` at the top of the recipe".into(),
                None => format!("declared parameters: {}", table.keys().cloned().collect::<Vec<_>>().join(", ")),
            };
            diags.push(Diagnostic::error(Some(command_line_span()), msg).with_help(help));
            continue;
        };
        let q = ParamQuantity::parse(text);
        if let (Some(old), new) = (&p.quantity, &q)
            && new.as_ref().is_none_or(|n| n.dim != old.dim)
        {
            diags.push(
                Diagnostic::error(
                    Some(command_line_span()),
                    format!(
                        "`--set {name}={text}`: `{name}` is declared as `{}`, a {}",
                        p.text,
                        old.dim.name().unwrap_or("quantity")
                    ),
                )
                .with_help(format!("give a value in the same unit, e.g. `{name}={}`", p.text.replace(' ', ""))),
            );
            continue;
        }
        p.text = text.clone();
        p.quantity = q;
        p.overridden = true;
        let v = values.get_mut(name).expect("declared");
        v.kind = RawKind::Str(text.clone());
    }
    // The declarations carry the values in force, so the recipe hash follows them.
    if let RawKind::Map(top) = &mut tree.kind {
        for (k, v) in top.iter_mut() {
            if k.name == "params"
                && let RawKind::Map(entries) = &mut v.kind
            {
                for (pk, pv) in entries.iter_mut() {
                    if let Some(val) = values.get(&pk.name) {
                        pv.kind = val.kind.clone();
                    }
                }
            }
        }
    }
    let mut used: IndexMap<String, bool> = table.keys().map(|k| (k.clone(), false)).collect();
    if let RawKind::Map(top) = &mut tree.kind {
        for (k, v) in top.iter_mut() {
            if !NOT_SUBSTITUTED.contains(&k.name.as_str()) {
                replace(v, &values, &mut used, diags);
            }
        }
    }
    for (name, was_used) in &used {
        if !was_used {
            let p = &table[name];
            diags.push(
                Diagnostic::warning(
                    Some(p.span.clone()),
                    format!("parameter `{name}` is declared but no value uses it"),
                )
                .with_help(format!("write `${name}` where the value goes, or remove it")),
            );
        }
    }
    (tree, table)
}

/// The parameter a scalar refers to, when it is `$name`.
fn reference(raw: &Raw) -> Option<&str> {
    let s = raw.as_str()?.trim();
    s.strip_prefix('$')
}

fn replace(raw: &mut Raw, values: &IndexMap<String, Raw>, used: &mut IndexMap<String, bool>, diags: &mut Diagnostics) {
    if let Some(name) = reference(raw).map(str::to_string) {
        let name = name.as_str();
        match values.get(name) {
            Some(v) => {
                // The use site keeps its place, so a unit that does not fit the field is
                // reported where `$name` is written.
                raw.kind = v.kind.clone();
                if let Some(u) = used.get_mut(name) {
                    *u = true;
                }
            }
            None => {
                let msg = format!("unknown parameter `${name}`");
                let help = match suggest(name, values.keys().map(String::as_str)) {
                    Some(s) => format!("did you mean `${s}`?"),
                    None => format!("declare it under `params:` at the top, e.g. `params: {{ {name}: … }}`"),
                };
                diags.error_help(Some(&raw.span), msg, help);
            }
        }
        return;
    }
    match &mut raw.kind {
        RawKind::Seq(items) => {
            for it in items {
                replace(it, values, used, diags);
            }
        }
        RawKind::Map(entries) => {
            for (_, v) in entries.iter_mut() {
                replace(v, values, used, diags);
            }
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quantity_splits_into_number_and_unit() {
        let q = ParamQuantity::parse("2e8 N/m").unwrap();
        assert_eq!((q.number, q.unit.as_str(), q.scale), (2e8, "N/m", 1.0));
        assert_eq!(q.dim, Dimension::STIFFNESS);
        let q = ParamQuantity::parse("12.7 mm").unwrap();
        assert_eq!(q.number, 12.7);
        assert!((q.si() - 0.0127).abs() < 1e-15);
        assert_eq!(ParamQuantity::parse("3e8N/m").unwrap().unit, "N/m");
        assert_eq!(ParamQuantity::parse("0.25").unwrap().unit, "");
        assert!(ParamQuantity::parse("carbide").is_none());
        let q = ParamQuantity::parse("250 N*s/m").unwrap();
        assert_eq!(q.text_for(1.5e2), "1.5e2 N*s/m");
        assert_eq!(ParamQuantity::parse(&q.text_for(1.234_567_890_123e2)).unwrap().number, 1.234_567_890_123e2);
    }
}
