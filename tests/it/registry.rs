//! The node registry and the entity tables are self-consistent: every default parses,
//! the schema is produced from them, and `nodes` documents every kind.

use spindlelab::engine::{model, schema, spec};

#[test]
fn every_default_is_a_valid_value_of_its_field() {
    let registry = spindlelab::registry();
    for node in registry.kinds() {
        let s = node.spec();
        spec::check_defaults(&s.params).unwrap_or_else(|e| panic!("{}: {e}", s.kind));
        assert!(!s.description.is_empty() && s.version >= 1, "{}", s.kind);
    }
    for kind in spec::EntityKind::ALL {
        spec::check_defaults(model::entity_fields(kind)).unwrap_or_else(|e| panic!("{kind:?}: {e}"));
    }
}

#[test]
fn schema_lists_every_node_kind_and_entity_section() {
    let registry = spindlelab::registry();
    let s = schema::recipe_schema(&registry);
    let kinds = s["properties"]["steps"]["additionalProperties"]["properties"]["kind"]["enum"].as_array().unwrap();
    // Every node kind, and `recipe` for a step that runs another recipe.
    assert_eq!(kinds.len(), registry.kinds().count() + 1);
    assert!(kinds.iter().any(|k| k == "recipe"));
    for key in ["use", "inputs", "exports"] {
        assert!(s["properties"][key].is_object(), "{key}");
    }
    for section in ["materials", "machines", "assemblies", "sensors", "cutting"] {
        assert!(s["properties"][section].is_object(), "{section}");
    }
    let impact = s["properties"]["steps"]["additionalProperties"]["allOf"]
        .as_array()
        .unwrap()
        .iter()
        .find(|v| v["if"]["properties"]["kind"]["const"] == "impact.simulate")
        .expect("impact.simulate variant");
    assert!(impact["then"]["properties"]["params"]["properties"]["hammer_mass"].is_object());
}
