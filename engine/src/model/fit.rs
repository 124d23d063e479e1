//! The `fit:` block: which parameters a fit may move, within what bounds, against which
//! objective, by which method. The driver that runs it lives with the optimisers; this
//! module only checks what the recipe wrote.

use super::params::Parameter;
use super::{PortRef, Step};
use crate::diag::{Diagnostics, Span};
use crate::node::Registry;
use crate::spec::suggest;
use crate::syntax::{Raw, RawKind};
use crate::value::PortType;
use indexmap::IndexMap;
use spindlelab_grammar::parse_quantity;

const FIT_KEYS: &[&str] = &["free", "objective", "method", "max_evaluations", "tolerance", "starts"];
const FREE_KEYS: &[&str] = &["min", "max", "scale"];

/// How a fit searches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FitMethod {
    /// Levenberg–Marquardt on the residual vector, Jacobian by finite differences.
    LeastSquares,
    /// Nelder–Mead simplex on the sum of squares (argmin).
    NelderMead,
}

/// How a free parameter is scaled for the search.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FitScale {
    Linear,
    /// Searched in its logarithm: stiffnesses and damping spanning decades.
    Log,
}

/// One parameter a fit may move, with bounds in the parameter's own unit.
#[derive(Debug, Clone)]
pub struct FreeParam {
    pub name: String,
    /// Bounds as numbers in the unit the parameter is written in.
    pub min: f64,
    pub max: f64,
    pub scale: FitScale,
    pub span: Span,
}

/// A checked `fit:` block.
#[derive(Debug, Clone)]
pub struct FitSpec {
    pub free: Vec<FreeParam>,
    /// Outputs whose squares are summed: FRFs (real and imaginary parts of every line, such
    /// as `frf.gap`'s weighted residual) or scalars, for every instance of the step.
    pub objective: Vec<PortRef>,
    pub method: FitMethod,
    pub max_evaluations: usize,
    /// Relative decrease of the objective below which the search stops.
    pub tolerance: f64,
    /// Points of the bounds box sampled before the search, which then starts from the best
    /// few (residuals of resonant models have several basins); 0 searches from the start
    /// values only. Default: 16 per free parameter.
    pub starts: usize,
    pub span: Span,
}

/// Checks the `fit:` block against the declared parameters and the steps.
pub fn resolve_fit(
    raw: &Raw,
    params: &IndexMap<String, Parameter>,
    steps: &[Step],
    registry: &Registry,
    diags: &mut Diagnostics,
) -> Option<FitSpec> {
    let Some(entries) = raw.as_map() else {
        diags.error_help(
            Some(&raw.span),
            format!("`fit` must be a mapping, found {}", raw.describe()),
            "write `fit: { free: { kt: { min: 1e7 N/m, max: 1e10 N/m, scale: log } }, objective: [\"@gap.residual\"] }`",
        );
        return None;
    };
    let before = diags.error_count();
    for (k, _) in entries {
        if !FIT_KEYS.contains(&k.name.as_str()) {
            let help = suggest(&k.name, FIT_KEYS.iter().copied())
                .map(|s| format!("did you mean `{s}`?"))
                .unwrap_or_else(|| format!("known keys: {}", FIT_KEYS.join(", ")));
            diags.error_help(Some(&k.span), format!("unknown key `{}` in `fit`", k.name), help);
        }
    }
    let mut free = Vec::new();
    match raw.get("free").map(|f| (f, f.as_map())) {
        Some((_, Some(items))) if !items.is_empty() => {
            for (k, v) in items {
                if let Some(p) = free_param(&k.name, &k.span, v, params, diags) {
                    free.push(p);
                }
            }
        }
        Some((f, _)) => diags.error_help(
            Some(&f.span),
            "`fit.free` must map parameter names to their bounds",
            "e.g. `free: { kt: { min: 1e7 N/m, max: 1e10 N/m, scale: log } }`",
        ),
        None => diags.error_help(
            Some(&raw.span),
            "`fit` names no free parameters",
            "add `free: { NAME: { min: …, max: … } }` for parameters declared under `params:`",
        ),
    }
    let mut objective = Vec::new();
    match raw.get("objective") {
        Some(Raw { kind: RawKind::Seq(items), .. }) if !items.is_empty() => {
            for it in items {
                if let Some(r) = objective_ref(it, steps, registry, diags) {
                    objective.push(r);
                }
            }
        }
        Some(o @ Raw { kind: RawKind::Str(_), .. }) => {
            if let Some(r) = objective_ref(o, steps, registry, diags) {
                objective.push(r);
            }
        }
        Some(o) => diags.error_help(
            Some(&o.span),
            "`fit.objective` must list the outputs to bring to zero",
            "e.g. `objective: [\"@gap_x.residual\", \"@gap_y.residual\"]`",
        ),
        None => diags.error_help(
            Some(&raw.span),
            "`fit` has no `objective`",
            "add `objective: [\"@gap_x.residual\"]` (a frf.gap residual, or any FRF or scalar output)",
        ),
    }
    let method = match raw.get("method") {
        None => FitMethod::LeastSquares,
        Some(m) => match m.as_str() {
            Some("least-squares") => FitMethod::LeastSquares,
            Some("nelder-mead") => FitMethod::NelderMead,
            _ => {
                diags.error_help(
                    Some(&m.span),
                    format!("unknown fit method `{}`", m.scalar_text().unwrap_or_default()),
                    "choose `least-squares` (Levenberg–Marquardt) or `nelder-mead`",
                );
                FitMethod::LeastSquares
            }
        },
    };
    let max_evaluations = match raw.get("max_evaluations") {
        None => 200 * free.len().max(1),
        Some(Raw { kind: RawKind::Int(n), .. }) if (1..=100_000).contains(n) => *n as usize,
        Some(v) => {
            diags.error_help(Some(&v.span), "`max_evaluations` must be a whole number", "between 1 and 100000");
            0
        }
    };
    let tolerance = match raw.get("tolerance") {
        None => 1e-6,
        Some(v) => match v.scalar_text().and_then(|t| parse_quantity(&t).ok()) {
            Some(q) if q.dim.is_dimensionless() && q.value > 0.0 && q.value < 1.0 => q.value,
            _ => {
                diags.error_help(Some(&v.span), "`tolerance` must be a number in (0, 1)", "e.g. `tolerance: 1e-6`");
                1e-6
            }
        },
    };
    let starts = match raw.get("starts") {
        None => 16 * free.len(),
        Some(Raw { kind: RawKind::Int(n), .. }) if (0..=10_000).contains(n) => *n as usize,
        Some(v) => {
            diags.error_help(Some(&v.span), "`starts` must be a whole number", "between 0 (no sampling) and 10000");
            0
        }
    };
    (diags.error_count() == before).then(|| FitSpec {
        free,
        objective,
        method,
        max_evaluations,
        tolerance,
        starts,
        span: raw.span.clone(),
    })
}

fn free_param(
    name: &str,
    span: &Span,
    raw: &Raw,
    params: &IndexMap<String, Parameter>,
    diags: &mut Diagnostics,
) -> Option<FreeParam> {
    let Some(p) = params.get(name) else {
        let msg = format!("`fit.free` names `{name}`, which is not a declared parameter");
        let help = match suggest(name, params.keys().map(String::as_str)) {
            Some(s) => format!("did you mean `{s}`?"),
            None => format!("declare it under `params:` (e.g. `params: {{ {name}: … }}`) and use it as `${name}`"),
        };
        diags.error_help(Some(span), msg, help);
        return None;
    };
    let Some(q) = &p.quantity else {
        diags.error_help(
            Some(span),
            format!("parameter `{name}` is `{}`, not a number, so a fit cannot move it", p.text),
            "fit numeric parameters only",
        );
        return None;
    };
    let Some(items) = raw.as_map() else {
        diags.error_help(
            Some(&raw.span),
            format!("free parameter `{name}` needs bounds"),
            format!("write `{name}: {{ min: …, max: … }}` in the unit of `{}`", p.text),
        );
        return None;
    };
    for (k, _) in items {
        if !FREE_KEYS.contains(&k.name.as_str()) {
            diags.error_help(
                Some(&k.span),
                format!("unknown key `{}` for free parameter `{name}`", k.name),
                "known keys: min, max, scale",
            );
        }
    }
    let bound = |key: &str, diags: &mut Diagnostics| -> Option<f64> {
        let Some(v) = raw.get(key) else {
            diags.error_help(
                Some(&raw.span),
                format!("free parameter `{name}` has no `{key}`: a fit needs both bounds"),
                format!("add `{key}:` in the unit of `{}`", p.text),
            );
            return None;
        };
        match v.scalar_text().map(|t| parse_quantity(&t)) {
            Some(Ok(b)) if b.dim == q.dim && b.value.is_finite() => Some(b.value / q.scale),
            Some(Ok(b)) => {
                diags.error_help(
                    Some(&v.span),
                    format!("`{key}` of `{name}` is in {}, but `{name}` is `{}`", b.dim, p.text),
                    format!("write the bound in `{}`", if q.unit.is_empty() { "a plain number" } else { &q.unit }),
                );
                None
            }
            _ => {
                diags.error_help(
                    Some(&v.span),
                    format!("`{key}` of `{name}` must be a quantity"),
                    format!("e.g. `{key}: {}`", p.text),
                );
                None
            }
        }
    };
    let (min, max) = (bound("min", diags), bound("max", diags));
    let scale = match raw.get("scale") {
        None => FitScale::Linear,
        Some(s) => match s.as_str() {
            Some("linear") => FitScale::Linear,
            Some("log") => FitScale::Log,
            _ => {
                diags.error_help(Some(&s.span), "`scale` is `linear` or `log`", "use `log` for stiffness and damping");
                FitScale::Linear
            }
        },
    };
    let (min, max) = (min?, max?);
    if min >= max {
        diags.error_help(Some(&raw.span), format!("`{name}`: `min` must be below `max`"), "swap the bounds");
        return None;
    }
    if scale == FitScale::Log && min <= 0.0 {
        diags.error_help(
            Some(&raw.span),
            format!("`{name}` is searched on a log scale, so `min` must be positive"),
            "give a positive `min`, or `scale: linear`",
        );
        return None;
    }
    if !(min..=max).contains(&q.number) {
        diags.error_help(
            Some(&p.span),
            format!("the start value of `{name}` ({}) lies outside its fit bounds", p.text),
            "start inside [min, max]",
        );
        return None;
    }
    Some(FreeParam { name: name.to_string(), min, max, scale, span: span.clone() })
}

fn objective_ref(raw: &Raw, steps: &[Step], registry: &Registry, diags: &mut Diagnostics) -> Option<PortRef> {
    let Some(r) = raw.as_str().and_then(PortRef::parse) else {
        diags.error_help(Some(&raw.span), "an objective is a reference to a step output", "write `@step.port`");
        return None;
    };
    let Some(step) = steps.iter().find(|s| s.id == r.step) else {
        let names: Vec<&str> = steps.iter().map(|s| s.id.as_str()).collect();
        let help = suggest(&r.step, names.iter().copied())
            .map(|s| format!("did you mean `@{s}.{}`?", r.port))
            .unwrap_or_else(|| format!("steps: {}", names.join(", ")));
        diags.error_help(Some(&raw.span), format!("the objective names no step `{}`", r.step), help);
        return None;
    };
    let spec = registry.get(&step.kind).expect("checked kind").spec();
    match spec.output(&r.port) {
        Some(p) if matches!(p.ty, PortType::Frf | PortType::Scalar) => Some(r),
        Some(p) => {
            diags.error_help(
                Some(&raw.span),
                format!("`{r}` is a {}; a fit objective sums the squares of FRF lines or scalars", p.ty),
                "name a residual FRF (frf.gap's `residual`) or a scalar output",
            );
            None
        }
        None => {
            let known: Vec<&str> = spec.outputs.iter().map(|p| p.name).collect();
            diags.error_help(
                Some(&raw.span),
                format!("step `{}` has no output `{}`", r.step, r.port),
                format!("its outputs: {}", known.join(", ")),
            );
            None
        }
    }
}
