//! `table.collect`: gathers a scalar over every point of a sweep into one table, with the
//! sweep coordinates as leading columns.

use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::spec::{Field, FieldType};
use spindlelab_engine::value::{Column, PortType, Table, UnitLabel, Value};

pub struct TableCollect {
    spec: NodeSpec,
}

impl TableCollect {
    pub fn new() -> Self {
        TableCollect {
            spec: NodeSpec {
                kind: "table.collect",
                version: 1,
                description: "Collects a swept scalar into a table: one row per sweep point, sweep values first.",
                inputs: vec![
                    PortSpec::new("values", PortType::Scalar, "the scalar to collect, from a swept step").collecting(),
                ],
                outputs: vec![PortSpec::new(
                    "table",
                    PortType::Table,
                    "sweep coordinates (SI) and the collected value",
                )],
                params: vec![Field::def("name", FieldType::Text, "value", "name of the value column")],
            },
        }
    }
}

impl Default for TableCollect {
    fn default() -> Self {
        Self::new()
    }
}

impl Node for TableCollect {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let items = ctx.inputs_of("values");
        if items.is_empty() {
            return Err(NodeError::input("values", "no values to collect"));
        }
        let axes = &items[0].coords;
        let mut columns: Vec<Column> = axes
            .iter()
            .map(|a| Column { name: a.name.clone(), unit: UnitLabel::new(a.unit.clone()), values: Vec::new() })
            .collect();
        let mut unit = String::new();
        let mut values = Vec::new();
        for item in items {
            let Value::Scalar(s) = item.value.as_ref() else {
                return Err(NodeError::input("values", "expected scalars"));
            };
            if item.coords.len() != axes.len() {
                return Err(NodeError::input("values", "values come from different sweeps"));
            }
            for (col, c) in columns.iter_mut().zip(&item.coords) {
                col.values.push(c.value);
            }
            unit = s.unit.symbol.clone();
            values.push(s.value);
        }
        let name = ctx.params.text("name").unwrap_or("value").to_string();
        columns.push(Column { name, unit: UnitLabel::new(unit), values });
        Ok([("table".to_string(), Value::Table(Table { columns }))].into_iter().collect())
    }
}
