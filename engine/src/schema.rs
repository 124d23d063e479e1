//! JSON Schema of the YAML recipe, generated from the same field tables and node registry
//! the validator uses, so an editor with a YAML language server offers completion and checks.

use crate::model::entity_fields;
use crate::node::Registry;
use crate::spec::{EntityKind, Field, FieldType};
use serde_json::{Map, Value, json};
use spindlelab_grammar::Dimension;

fn field_schema(ty: &FieldType) -> Value {
    match ty {
        FieldType::Quantity(d) if *d == Dimension::DIMENSIONLESS => json!({
            "anyOf": [{"type": "number"}, {"type": "string", "pattern": "^\\s*([-+]?[0-9.]|\\$[A-Za-z_])"}],
        }),
        FieldType::Quantity(d) => json!({
            "type": "string",
            "pattern": "^\\s*([-+]?[0-9.]|\\$[A-Za-z_])",
            "description": format!("{} with a unit, SI {}", d.name().unwrap_or("quantity"), d.si_unit()),
        }),
        FieldType::QuantityList(d) => json!({
            "anyOf": [
                {"type": "string", "description": format!("`a..b step s UNIT`, `[a, b] UNIT` or one value; {}", d.si_unit())},
                {"type": "array", "items": {"type": "string"}},
                {"type": "number"}
            ]
        }),
        FieldType::Integer { min, max } => json!({"type": "integer", "minimum": min, "maximum": max}),
        FieldType::Bool => json!({"type": "boolean"}),
        FieldType::Text => json!({"type": "string"}),
        FieldType::Choice(c) => json!({"enum": c}),
        FieldType::ChoiceList(c) => json!({"type": "array", "items": {"enum": c}}),
        FieldType::Entity(k) => {
            json!({"type": "string", "description": format!("name of a {} declared under `{}`", k.noun(), k.section())})
        }
        FieldType::Object(fields) => object_schema(fields),
        FieldType::ObjectList(fields) => json!({"type": "array", "items": object_schema(fields)}),
        FieldType::MapOf(inner) => json!({"type": "object", "additionalProperties": field_schema(inner)}),
        FieldType::File => {
            json!({"type": "string", "description": "path of a data file, relative to the recipe's folder"})
        }
    }
}

fn object_schema(fields: &[Field]) -> Value {
    let mut props = Map::new();
    let mut required = Vec::new();
    for f in fields {
        let mut s = field_schema(&f.ty);
        if let Some(obj) = s.as_object_mut() {
            let mut desc = f.doc.to_string();
            if let Some(d) = f.default {
                desc.push_str(&format!(" (default {d})"));
            }
            obj.insert("description".into(), desc.into());
        }
        props.insert(f.name.into(), s);
        if f.required {
            required.push(f.name);
        }
    }
    json!({"type": "object", "properties": props, "required": required, "additionalProperties": false})
}

/// The JSON Schema (draft-07) of a recipe for the given registry.
pub fn recipe_schema(registry: &Registry) -> Value {
    let mut step_variants = Vec::new();
    for node in registry.kinds() {
        let spec = node.spec();
        let inputs: Map<String, Value> = spec
            .inputs
            .iter()
            .map(|p| (p.name.to_string(), json!({"type": "string", "pattern": "^@?[A-Za-z_][A-Za-z0-9_-]*\\.[A-Za-z_][A-Za-z0-9_-]*$", "description": format!("{} ({})", p.doc, p.ty)})))
            .collect();
        let params = object_schema(&spec.params);
        let mut params = params;
        // Swept parameters may be absent from `params`.
        params.as_object_mut().expect("object").remove("required");
        step_variants.push(json!({
            "if": {"properties": {"kind": {"const": spec.kind}}},
            "then": {"properties": {
                "params": params,
                "inputs": {"type": "object", "properties": inputs, "additionalProperties": false},
                "sweep": {"type": "object", "propertyNames": {"enum": spec.params.iter().map(|f| f.name).collect::<Vec<_>>()}}
            }}
        }));
    }
    let kinds: Vec<&str> = registry.names().collect();
    let step = json!({
        "type": "object",
        "required": ["kind"],
        "properties": {
            "kind": {"enum": kinds},
            "description": {"type": "string"},
            "params": {"type": "object"},
            "inputs": {"type": "object"},
            "sweep": {"type": "object"}
        },
        "additionalProperties": false,
        "allOf": step_variants
    });
    let mut props = Map::new();
    props.insert("spindlelab".into(), json!({"const": 1, "description": "recipe format version"}));
    props.insert("name".into(), json!({"type": "string"}));
    props.insert("description".into(), json!({"type": "string"}));
    for kind in EntityKind::ALL {
        props.insert(
            kind.section().into(),
            json!({"type": "object", "additionalProperties": object_schema(entity_fields(kind))}),
        );
    }
    props.insert("speeds".into(), field_schema(&FieldType::QuantityList(Dimension::ROTATIONAL_SPEED)));
    props.insert("steps".into(), json!({"type": "object", "additionalProperties": step}));
    props.insert(
        "params".into(),
        json!({"type": "object", "description": "named values (`kt: 2e8 N/m`) used as `$kt`; `--set kt=…` and fits vary them",
            "additionalProperties": {"anyOf": [{"type": "number"}, {"type": "string"}]}}),
    );
    props.insert(
        "measurements".into(),
        json!({"type": "object", "description": "measured FRF files, each set read by a `read.frf` step of its name, one instance per file",
            "additionalProperties": {"anyOf": [{"type": "string"}, {"type": "array", "items": {"type": "string"}},
                {"type": "object", "required": ["files"], "additionalProperties": false, "properties": {
                    "files": {"anyOf": [{"type": "string"}, {"type": "array", "items": {"type": "string"}}],
                        "description": "file names or globs, relative to the recipe's folder"},
                    "format": {"enum": ["auto", "csv", "uff"]},
                    "direction": {"enum": ["x", "y", "z"]},
                    "speed": {"type": "string"},
                    "units": {"type": "string"},
                    "description": {"type": "string"}}}]}}),
    );
    let bound = json!({"anyOf": [{"type": "number"}, {"type": "string"}]});
    props.insert(
        "fit".into(),
        json!({"type": "object", "additionalProperties": false, "required": ["free", "objective"],
        "properties": {
            "free": {"type": "object", "description": "declared parameters the fit moves, with bounds in their unit",
                "additionalProperties": {"type": "object", "required": ["min", "max"], "additionalProperties": false,
                    "properties": {"min": bound, "max": bound, "scale": {"enum": ["linear", "log"]}}}},
            "objective": {"anyOf": [{"type": "string"}, {"type": "array", "items": {"type": "string"}}],
                "description": "outputs (`@step.port`, FRF or scalar) whose sum of squares is minimised"},
            "method": {"enum": ["least-squares", "nelder-mead"]},
            "max_evaluations": {"type": "integer", "minimum": 1, "maximum": 100000},
            "tolerance": {"anyOf": [{"type": "number"}, {"type": "string"}]}
        }}),
    );
    props.insert(
        "outputs".into(),
        json!({"type": "array", "items": {"type": "object", "required": ["from", "file"], "additionalProperties": false,
            "properties": {"from": {"type": "string"}, "file": {"type": "string", "pattern": "\\.(csv|json|uff|svg|png)$"},
                "with": {"oneOf": [{"type": "string"}, {"type": "array", "items": {"type": "string"}}],
                    "description": "values drawn over a plot (`@step.port`)"},
                "plot": {"type": "string", "enum": ["bode", "real-imag", "blocks", "default"],
                    "description": "the plot's view when its type has several"}}}}),
    );
    json!({
        "$schema": "http://json-schema.org/draft-07/schema#",
        "$id": "https://spindlelab.dev/schema/recipe-1.json",
        "title": "spindlelab recipe",
        "type": "object",
        "required": ["spindlelab", "steps"],
        "properties": props,
        "additionalProperties": false
    })
}
