//! JSON Schema of the YAML recipe, generated from the same field tables and node registry
//! the validator uses, so an editor with a YAML language server offers completion and checks.

use crate::model::entity_fields;
use crate::node::Registry;
use crate::spec::{EntityKind, Field, FieldType};
use serde_json::{Map, Value, json};
use spindlelab_grammar::Dimension;

/// The units an editor offers for a dimension: the ones recipes and the dissertation write.
/// `spindlelab check` accepts any unit of the right dimension; a schema can only list some.
pub fn units_of(d: Dimension) -> Option<&'static [&'static str]> {
    const TABLE: &[(Dimension, &[&str])] = &[
        (Dimension::LENGTH, &["m", "mm", "um", "µm", "nm", "cm", "in"]),
        (Dimension::MASS, &["kg", "g", "mg"]),
        (Dimension::TIME, &["s", "ms", "us", "µs", "min"]),
        (Dimension::FREQUENCY, &["Hz", "kHz", "MHz"]),
        (Dimension::ROTATIONAL_SPEED, &["rpm", "rad/s"]),
        (Dimension::PRESSURE, &["Pa", "kPa", "MPa", "GPa", "N/m^2", "N/mm^2"]),
        (Dimension::DENSITY, &["kg/m^3", "g/cm^3"]),
        (Dimension::STIFFNESS, &["N/m", "N/mm", "N/um", "N/µm", "kN/mm"]),
        (Dimension::DAMPING, &["N*s/m", "N·s/m", "kg/s"]),
        (Dimension::ROTATIONAL_STIFFNESS, &["N*m/rad", "N·m/rad"]),
        (Dimension::ROTATIONAL_DAMPING, &["N*m*s/rad", "N·m·s/rad"]),
        (Dimension::ANGLE, &["deg", "rad"]),
        (Dimension::PHASE_SLOPE, &["deg/kHz", "deg/Hz", "rad/Hz", "rad/kHz"]),
        (Dimension::FORCE, &["N", "kN"]),
        (Dimension::VELOCITY, &["m/s", "mm/s", "um/s"]),
        (Dimension::ACCELERATION, &["m/s^2", "mm/s^2"]),
    ];
    TABLE.iter().find(|(dim, _)| *dim == d).map(|(_, u)| *u)
}

/// A number (or `$parameter`) followed by one of `units`.
fn quantity_pattern(units: &[&str]) -> String {
    let alternatives: Vec<String> = units
        .iter()
        .map(|u| {
            u.chars().map(|c| if "^*.$/()[]{}+?|\\".contains(c) { format!("\\{c}") } else { c.to_string() }).collect()
        })
        .collect();
    format!(
        "^\\s*(\\$[A-Za-z_][A-Za-z0-9_]*|[-+]?([0-9]+\\.?[0-9]*|\\.[0-9]+)([eE][-+]?[0-9]+)?\\s*({}))\\s*$",
        alternatives.join("|")
    )
}

fn field_schema(ty: &FieldType) -> Value {
    match ty {
        FieldType::Quantity(d) if *d == Dimension::DIMENSIONLESS => json!({
            "anyOf": [{"type": "number"}, {"type": "string", "pattern": "^\\s*([-+]?[0-9.]|\\$[A-Za-z_])"}],
        }),
        FieldType::Quantity(d) => match units_of(*d) {
            Some(units) => json!({
                "type": "string",
                "pattern": quantity_pattern(units),
                "description": format!("{} with a unit: {}", d.name().unwrap_or("quantity"), units.join(", ")),
            }),
            None => json!({
                "type": "string",
                "pattern": "^\\s*([-+]?[0-9.]|\\$[A-Za-z_])",
                "description": format!("{} with a unit, SI {}", d.name().unwrap_or("quantity"), d.si_unit()),
            }),
        },
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
    // A step that runs another recipe: its file, and what it binds by name.
    step_variants.push(json!({
        "if": {"properties": {"kind": {"const": crate::model::RECIPE_KIND}}},
        "then": {"required": ["file"], "properties": {
            "params": {"type": "object", "description": "values of the parameters the recipe declares"},
            "inputs": {"type": "object", "description": "the recipe's declared inputs, each bound to `@step.port`",
                "additionalProperties": {"type": "string"}},
            "sweep": {"type": "object", "description": "parameters of the recipe to sweep: the whole procedure runs per value"}
        }},
        "else": {"properties": {"file": false}}
    }));
    let mut kinds: Vec<&str> = registry.names().collect();
    kinds.push(crate::model::RECIPE_KIND);
    let step = json!({
        "type": "object",
        "required": ["kind"],
        "properties": {
            "kind": {"enum": kinds, "description": "a node kind, or `recipe` to run another recipe as this step"},
            "file": {"type": "string", "description": "`kind: recipe`: the recipe to run, relative to this file"},
            "description": {"type": "string"},
            "label": {"type": "string", "description": "what the step's values are called in a plot's legend"},
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
    props.insert(
        "use".into(),
        json!({"type": "array", "items": {"type": "string", "pattern": "\\.ya?ml$"},
            "description": "library files whose entities (materials, machines, assemblies, sensors, cutting) the recipe takes, relative to it or on $SPINDLELAB_LIBRARY_PATH"}),
    );
    props.insert(
        "inputs".into(),
        json!({"type": "object", "description": "a recipe run as a step: the inputs it takes, name → port type; its steps read them as `@inputs.NAME`",
            "additionalProperties": {"enum": ["time series", "frf", "receptance set", "modal model", "beam model", "substructure", "lobes", "table", "scalar"]}}),
    );
    props.insert(
        "exports".into(),
        json!({"type": "object", "description": "a recipe run as a step: what it hands back, name → `@step.port`",
            "additionalProperties": {"type": "string"}}),
    );
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
    props.insert(
        "plugins".into(),
        json!({"type": "array", "description": "WebAssembly plugins whose node kinds the steps use",
            "items": {"anyOf": [{"type": "string", "description": "plugin id, found on the plugin search path"},
                {"type": "object", "additionalProperties": false, "properties": {
                    "id": {"type": "string"}, "path": {"type": "string", "description": "a `.plugin.json` manifest, relative to the recipe"},
                    "version": {"type": "string"}, "sha256": {"type": "string", "pattern": "^[0-9a-fA-F]{64}$"}}}]}}),
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
                "with": {"oneOf": [{"type": "string"}, {"type": "array", "items": {"oneOf": [{"type": "string"},
                    {"type": "object", "required": ["from"], "additionalProperties": false,
                     "properties": {"from": {"type": "string"}, "label": {"type": "string"}}}]}}],
                    "description": "values drawn over a plot (`@step.port`)"},
                "plot": {"type": "string", "enum": ["bode", "real-imag", "blocks", "spectrum", "default"],
                    "description": "the plot's view when its type has several"},
                "label": {"type": "string", "description": "a plot's name for `from` in its legend and title"},
                "unit": {"type": "string", "description": "the unit a scalar is written in (`deg/kHz`), SI without"}}}}),
    );
    json!({
        "$schema": "http://json-schema.org/draft-07/schema#",
        "$id": "https://spindlelab.dev/schema/recipe-1.json",
        "title": "spindlelab recipe",
        "type": "object",
        "required": ["spindlelab"],
        "properties": props,
        "additionalProperties": false
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every unit the schema offers parses to its dimension, and the pattern takes a value in
    /// one of them (or a `$parameter`) and refuses a value in another dimension's unit.
    #[test]
    fn unit_patterns_take_their_dimension_and_refuse_others() {
        for d in [
            Dimension::LENGTH,
            Dimension::MASS,
            Dimension::TIME,
            Dimension::FREQUENCY,
            Dimension::ROTATIONAL_SPEED,
            Dimension::PRESSURE,
            Dimension::DENSITY,
            Dimension::STIFFNESS,
            Dimension::DAMPING,
            Dimension::ROTATIONAL_STIFFNESS,
            Dimension::ROTATIONAL_DAMPING,
            Dimension::ANGLE,
            Dimension::PHASE_SLOPE,
            Dimension::FORCE,
            Dimension::VELOCITY,
            Dimension::ACCELERATION,
        ] {
            let units = units_of(d).unwrap();
            let re = regex::Regex::new(&quantity_pattern(units)).unwrap();
            for u in units {
                let unit = spindlelab_grammar::parse_unit(u).unwrap_or_else(|e| panic!("`{u}`: {e}"));
                assert_eq!(unit.dim, d, "`{u}`");
                for v in ["12.7", "-3", "1e9", ".5", "2.0E-3"] {
                    let text = format!("{v} {u}");
                    assert!(re.is_match(&text), "`{text}` refused for {}", d.si_unit());
                    assert!(spindlelab_grammar::parse_quantity(&text).is_ok(), "`{text}`");
                }
            }
            assert!(re.is_match("$tip_mass"));
            assert!(!re.is_match("12.7"), "a bare number for {}", d.si_unit());
        }
        let mass = regex::Regex::new(&quantity_pattern(units_of(Dimension::MASS).unwrap())).unwrap();
        assert!(!mass.is_match("0.01 m") && mass.is_match("0.01 kg") && mass.is_match("30 g"));
    }
}
