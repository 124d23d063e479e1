//! `table.collect`: gathers a scalar over every point of a sweep into one table, with the
//! sweep coordinates as leading columns in the units the recipe wrote them.

use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::FieldType;
use spindlelab_engine::value::{Column, PortType, Table, UnitLabel, Value};

node_params! {
    /// Parameters of `table.collect`.
    pub struct TableCollectParams<'a> {
        name: def &'a str = (FieldType::Text, "value", "name of the value column"),
    }
}

pub struct TableCollect {
    spec: NodeSpec,
}

impl TableCollect {
    pub fn new() -> Self {
        TableCollect {
            spec: NodeSpec {
                kind: "table.collect",
                version: 2,
                description: "Collects a swept scalar into a table: one row per sweep point, sweep values first.",
                inputs: vec![
                    PortSpec::new("values", PortType::Scalar, "the scalar to collect, from a swept step").collecting(),
                ],
                outputs: vec![PortSpec::new(
                    "table",
                    PortType::Table,
                    "sweep coordinates (SI) and the collected value",
                )],
                params: TableCollectParams::fields(),
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
        let p = TableCollectParams::read(ctx.params)?;
        let items = ctx.inputs_of("values");
        if items.is_empty() {
            return Err(NodeError::input("values", "no values to collect"));
        }
        let axes = &items[0].coords;
        let mut columns: Vec<Column> = axes
            .iter()
            .map(|a| Column {
                name: a.name.clone(),
                unit: UnitLabel::new(a.unit.clone()),
                values: Vec::new(),
                levels: Vec::new(),
            })
            .collect();
        // Each axis in the unit the recipe wrote it (`6000 rpm`, `1 mm`) where every sweep point
        // writes it in the same unit; in SI otherwise.
        let points: Vec<Vec<(String, f64, String)>> = items.iter().map(|i| written(&i.label)).collect();
        let as_written: Vec<Option<String>> = axes
            .iter()
            .map(|a| {
                let units: Vec<Option<&str>> = points
                    .iter()
                    .map(|w| w.iter().find(|(n, _, u)| *n == a.name && !u.is_empty()).map(|(_, _, u)| u.as_str()))
                    .collect();
                let first = units.first().copied().flatten()?;
                units.iter().all(|u| *u == Some(first)).then(|| first.to_string())
            })
            .collect();
        for (col, unit) in columns.iter_mut().zip(&as_written) {
            if let Some(u) = unit {
                col.unit = UnitLabel::new(u.clone());
            }
        }
        let mut unit = String::new();
        let mut values = Vec::new();
        for item in items {
            let Value::Scalar(s) = item.value.as_ref() else {
                return Err(NodeError::input("values", "expected scalars"));
            };
            if item.coords.len() != axes.len() {
                return Err(NodeError::input("values", "values come from different sweeps"));
            }
            let w = written(&item.label);
            for ((col, c), unit) in columns.iter_mut().zip(&item.coords).zip(&as_written) {
                let v = match unit {
                    Some(_) => w.iter().find(|(n, _, _)| *n == c.name).map_or(c.value, |(_, v, _)| *v),
                    None => c.value,
                };
                col.values.push(v);
            }
            unit = s.unit.symbol.clone();
            values.push(s.value);
        }
        let name = p.name.to_string();
        columns.push(Column { name, unit: UnitLabel::new(unit), values, levels: Vec::new() });
        Ok([("table".to_string(), Value::Table(Table { columns }))].into_iter().collect())
    }
}

/// The numeric sweep coordinates of a label as the recipe wrote them: `speed=6000 rpm,
/// depth=1 mm` → `[("speed", 6000, "rpm"), ("depth", 1, "mm")]`.
fn written(label: &str) -> Vec<(String, f64, String)> {
    label
        .split(", ")
        .filter_map(|part| {
            let (name, value) = part.split_once('=')?;
            let mut words = value.split_whitespace();
            let v: f64 = words.next()?.parse().ok()?;
            Some((name.to_string(), v, words.collect::<Vec<_>>().join(" ")))
        })
        .collect()
}
