//! `stability.best`: the best cut of a stability diagram, as one row a sweep collects.

use super::outputs;
use crate::stability::best::best_cut;
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::spec::Params;
use spindlelab_engine::value::{Column, PortType, Table, Value};

/// `stability.best`: the deepest stable cut of a diagram and its speed, and the depth stable
/// at every speed of it.
pub struct StabilityBest {
    spec: NodeSpec,
}

impl Default for StabilityBest {
    fn default() -> Self {
        Self::new()
    }
}

impl StabilityBest {
    pub fn new() -> Self {
        StabilityBest {
            spec: NodeSpec {
                kind: "stability.best",
                version: 1,
                description: "The best cut of a stability diagram: the largest limiting depth over its speeds (the top of the highest lobe) with its speed and chatter frequency, and the depth stable at every speed.",
                inputs: vec![PortSpec::new("lobes", PortType::Lobes, "a stability diagram")],
                outputs: vec![PortSpec::new(
                    "best",
                    PortType::Table,
                    "one row: depth (m, the largest limit), speed (rpm, where it is reached), chatter_frequency (Hz), \
                     stable_everywhere (m, the smallest limit)",
                )],
                params: Vec::new(),
            },
        }
    }
}

impl Node for StabilityBest {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, _params: &Params) -> Result<(), NodeError> {
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let Value::Lobes(lobes) = ctx.input("lobes")? else {
            return Err(NodeError::input("lobes", "expected stability lobes"));
        };
        let b = best_cut(lobes)
            .ok_or_else(|| NodeError::input("lobes", "the diagram has no speed with a valid limiting depth"))?;
        let best = Table {
            columns: vec![
                Column::new("depth", "m", vec![b.depth_m]),
                Column::new("speed", "rpm", vec![b.speed_rpm]),
                Column::new("chatter_frequency", "Hz", vec![b.chatter_hz]),
                Column::new("stable_everywhere", "m", vec![b.stable_everywhere_m]),
            ],
        };
        Ok(outputs(vec![("best", Value::Table(best))]))
    }
}
