//! `rhai.eval`: a short Rhai expression over scalar inputs, for the arithmetic a recipe needs
//! between physics steps (a ratio, a unit change, a margin).

use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{FieldType, Params};
use spindlelab_engine::syntax::rhai::{self, Scope};
use spindlelab_engine::syntax::{RhaiLimits, sandboxed_engine};
use spindlelab_engine::value::{PortType, Scalar, Value};

node_params! {
    /// Parameters of `rhai.eval`.
    pub struct RhaiEvalParams<'a> {
        expr: req &'a str = (FieldType::Text, "Rhai expression, e.g. `x / y * 1000.0`"),
        unit: def &'a str = (FieldType::Text, "", "unit label of the result (SI symbol)"),
    }
}

pub struct RhaiEval {
    spec: NodeSpec,
}

impl RhaiEval {
    pub fn new() -> Self {
        RhaiEval {
            spec: NodeSpec {
                kind: "rhai.eval",
                version: 1,
                description: "Evaluates a sandboxed Rhai expression over scalar inputs x, y, z (SI values).",
                inputs: vec![
                    PortSpec::new("x", PortType::Scalar, "bound to `x`").optional(),
                    PortSpec::new("y", PortType::Scalar, "bound to `y`").optional(),
                    PortSpec::new("z", PortType::Scalar, "bound to `z`").optional(),
                ],
                outputs: vec![PortSpec::new("value", PortType::Scalar, "the expression's value")],
                params: RhaiEvalParams::fields(),
            },
        }
    }
}

impl Default for RhaiEval {
    fn default() -> Self {
        Self::new()
    }
}

fn limits() -> RhaiLimits {
    RhaiLimits { max_operations: 1_000_000, ..RhaiLimits::default() }
}

impl Node for RhaiEval {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let expr = RhaiEvalParams::read(params)?.expr;
        sandboxed_engine(&limits())
            .compile_expression(expr)
            .map(|_| ())
            .map_err(|e| NodeError::param("expr", format!("`{expr}` is not a Rhai expression: {e}")))
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = RhaiEvalParams::read(ctx.params)?;
        let engine = sandboxed_engine(&limits());
        let mut scope = Scope::new();
        for var in ["x", "y", "z"] {
            if let Ok(Value::Scalar(s)) = ctx.input(var) {
                scope.push(var, s.value);
            }
        }
        let expr = p.expr;
        let result: rhai::Dynamic = engine
            .eval_expression_with_scope(&mut scope, expr)
            .map_err(|e| NodeError::param("expr", format!("`{expr}` failed: {e}")))?;
        let value = if let Some(f) = result.clone().try_cast::<f64>() {
            f
        } else if let Some(i) = result.clone().try_cast::<i64>() {
            i as f64
        } else {
            return Err(NodeError::param("expr", format!("`{expr}` gave {}, not a number", result.type_name())));
        };
        if !value.is_finite() {
            return Err(NodeError::param("expr", format!("`{expr}` gave {value}")));
        }
        let unit = p.unit;
        Ok([("value".to_string(), Value::Scalar(Scalar::new(value, unit)))].into_iter().collect())
    }
}
