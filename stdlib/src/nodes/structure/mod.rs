//! Structural-model and RCSA node kinds (dissertation §5.1, §5.4): `beam.receptance` (free–free
//! Timoshenko FE model of an assembly), `spindle.receptance` (equivalent fixed-free
//! Euler–Bernoulli spindle modes, Eqs. 5.5–5.12), `beam.substructure` (the FE model reduced to
//! its coupling points, once), `rcsa.couple` (Eqs. 5.3, 5.16–5.17) and `rcsa.decouple` (inverse
//! RCSA, Eq. 5.4).
//!
//! Substructure receptances come from the modal expansion of the FE model: one eigen-solution
//! serves every frequency line, so a line costs a sum over the modes instead of a complex
//! solve of the whole mesh; with all modes kept the expansion equals the direct solve.

mod beam_receptance;
mod campbell;
mod couple;
mod decouple;
mod spindle;
mod substructure;

pub use beam_receptance::BeamReceptance;
pub use campbell::BeamCampbell;
pub use couple::RcsaCouple;
pub use decouple::RcsaDecouple;
pub use spindle::SpindleReceptance;
pub use substructure::BeamSubstructure;

use crate::beam::{self, BeamModel, MeshOptions, ShearCoefficient};
use crate::rcsa::{self, Interface, RcsaError, RcsaOptions, Receptance, ReceptanceFrf, TwoPort};
use spindlelab_domain::Speed;
use spindlelab_engine::model::{Component, Joint, Section};
use spindlelab_engine::node::{NodeContext, NodeError, Outputs, PortSpec};
use spindlelab_engine::spec::{EntityKind, Field, FieldType as T, Params};
use spindlelab_engine::value::{Frf, PortType, ReceptanceSet, UnitLabel, Value};
use spindlelab_grammar::Dimension as D;

// Fields several kinds of this module share, declared once (`node_params!` names them).
pub(super) const ASSEMBLY: Field =
    Field::req("assembly", T::Entity(EntityKind::Assembly), "the sections, from the spindle end to the tip");
pub(super) const SENSOR: Field =
    Field::opt("sensor", T::Entity(EntityKind::Sensor), "a sensor whose `mass` sits on the tip");
pub(super) const MAX_FREQUENCY: Field =
    Field::def("max_frequency", T::Quantity(D::FREQUENCY), "5 kHz", "highest frequency line");
pub(super) const RESOLUTION: Field =
    Field::opt("resolution", T::Quantity(D::FREQUENCY), "line spacing; without it, max_frequency / lines");
pub(super) const LINES: Field = Field::def(
    "lines",
    T::Integer { min: 1, max: 1_000_000 },
    "1000",
    "number of lines (from one spacing up to max_frequency) when no resolution is given",
);
pub(super) const MAX_ELEMENT: Field =
    Field::def("max_element", T::Quantity(D::LENGTH), "2 mm", "longest Timoshenko element of the FE mesh");
pub(super) const SHEAR: Field = Field::def(
    "shear",
    T::Choice(&["cowper", "hutchinson"]),
    "cowper",
    "shear coefficient of the circular sections: Cowper (1966) or Hutchinson (2001)",
);
pub(super) const INTERFACE: Field = Field::def(
    "interface",
    T::Choice(&["rigid", "machine"]),
    "rigid",
    "spindle–holder joint: rigid, or the `holder_interface` of `machine` (Eqs. 5.16–5.17)",
);
pub(super) const MACHINE: Field =
    Field::opt("machine", T::Entity(EntityKind::Machine), "the machine whose `holder_interface` to use");
pub(super) const GRID_MISMATCH: Field = Field::def(
    "grid_mismatch",
    T::Choice(&["refuse", "resample"]),
    "refuse",
    "when `grid` is connected and its lines differ from the receptance input's: refuse, or interpolate the input linearly onto `grid` (no extrapolation)",
);
pub(super) const MAX_CONDITION: Field = Field::def(
    "max_condition",
    RATIO,
    "1e10",
    "largest accepted condition number of a 2x2 inversion (lengths scaled, see docs/structure.md)",
);

const RATIO: T = T::Quantity(D::DIMENSIONLESS);

pub(super) fn grid_port() -> PortSpec {
    PortSpec::new(
        "grid",
        PortType::Frf,
        "an FRF whose frequency lines to use instead of the grid parameters (a 0 Hz line is left out)",
    )
    .optional()
}

/// The FE mesh options from the `max_element` and `shear` parameters.
fn mesh(max_element: f64, shear: &str) -> MeshOptions {
    MeshOptions {
        max_element_length: max_element,
        shear: match shear {
            "hutchinson" => ShearCoefficient::Hutchinson,
            _ => ShearCoefficient::Cowper,
        },
        ..MeshOptions::default()
    }
}

fn check_mesh(p: &Params) -> Result<(), NodeError> {
    super::positive(p, &["max_element", "max_frequency", "resolution", "max_condition"])
}

/// The frequency grid from the `grid` input, else from the grid parameters; positive lines only.
pub(super) fn grid(
    ctx: &NodeContext,
    max_frequency: f64,
    resolution: Option<f64>,
    lines: usize,
) -> Result<Vec<f64>, NodeError> {
    if let Some(l) = ctx.inputs_of("grid").first() {
        let Value::Frf(f) = l.value.as_ref() else {
            return Err(NodeError::input("grid", "expected an FRF"));
        };
        return positive_lines(ctx, "grid", &f.freq_hz);
    }
    let fmax = max_frequency;
    let (df, n) = match resolution {
        Some(df) => (df, (fmax / df * (1.0 + 1e-12)).floor() as usize),
        None => {
            let n = lines.max(1);
            (fmax / n as f64, n)
        }
    };
    if n == 0 {
        return Err(NodeError::param("resolution", format!("{df} Hz is above max_frequency {fmax} Hz: no lines")));
    }
    Ok((1..=n).map(|k| k as f64 * df).collect())
}

/// Checks a grid from an input: finite and ascending; lines at 0 Hz are left out with a warning
/// (a free–free substructure has no static receptance).
fn positive_lines(ctx: &NodeContext, port: &str, f: &[f64]) -> Result<Vec<f64>, NodeError> {
    if let Some(i) = f.iter().position(|v| !v.is_finite() || *v < 0.0) {
        return Err(NodeError::input(
            port,
            format!("frequency line {i} is {} Hz; lines must be finite and >= 0", f[i]),
        ));
    }
    if let Some(i) = (1..f.len()).find(|&i| f[i] <= f[i - 1]) {
        return Err(NodeError::input(
            port,
            format!("frequency lines must ascend; line {i} ({} Hz) follows {} Hz", f[i], f[i - 1]),
        ));
    }
    let kept: Vec<f64> = f.iter().copied().filter(|v| *v > 0.0).collect();
    if kept.len() < f.len() {
        ctx.warn(format!("`{port}`: the 0 Hz line is left out (a free-free substructure has no static receptance)"));
    }
    if kept.is_empty() {
        return Err(NodeError::input(port, "no positive frequency lines"));
    }
    Ok(kept)
}

fn block(m: &beam::Receptance) -> Receptance {
    Receptance::new(m[0][0], m[0][1], m[1][0], m[1][1])
}

pub(super) fn to_frf(s: &ReceptanceSet) -> ReceptanceFrf {
    ReceptanceFrf {
        freqs_hz: s.freq_hz.clone(),
        lines: (0..s.freq_hz.len()).map(|i| Receptance::new(s.h[i], s.l[i], s.n[i], s.p[i])).collect(),
    }
}

pub(super) fn to_set(f: &ReceptanceFrf, direction: Option<String>, speed: Option<Speed>) -> ReceptanceSet {
    ReceptanceSet {
        freq_hz: f.freqs_hz.clone(),
        h: f.lines.iter().map(|r| r.h).collect(),
        l: f.lines.iter().map(|r| r.l).collect(),
        n: f.lines.iter().map(|r| r.n).collect(),
        p: f.lines.iter().map(|r| r.p).collect(),
        direction,
        speed,
    }
}

/// The direct receptance `H` of a set as an FRF (m/N), direction and speed carried.
pub(super) fn h_of(s: &ReceptanceSet) -> Frf {
    Frf {
        freq_hz: s.freq_hz.clone(),
        values: s.h.clone(),
        coherence: None,
        unit: UnitLabel::new("m/N"),
        direction: s.direction.clone(),
        speed: s.speed,
        sensor: None,
        dofs: None,
    }
}

pub(super) fn outputs(items: Vec<(&str, Value)>) -> Outputs {
    items.into_iter().map(|(k, v)| (k.to_string(), v)).collect()
}

/// The sensor's mass (kg) named by the `sensor` parameter, 0 without one.
fn sensor_mass(ctx: &NodeContext, sensor: Option<&str>) -> Result<f64, NodeError> {
    match sensor {
        None => Ok(0.0),
        Some(name) => ctx
            .entities
            .sensors
            .get(name)
            .map(|s| s.mass)
            .ok_or_else(|| NodeError::param("sensor", format!("no sensor `{name}` in the recipe"))),
    }
}

/// The assembly `name`, given as parameter `param`.
fn assembly<'a>(
    ctx: &'a NodeContext,
    param: &str,
    name: &str,
) -> Result<&'a spindlelab_engine::model::Assembly, NodeError> {
    ctx.entities
        .assemblies
        .get(name)
        .ok_or_else(|| NodeError::param(param, format!("no assembly `{name}` in the recipe")))
}

/// A joint entity as a coupling interface. A compliant joint needs both stiffnesses.
fn interface_of(joint: &Joint, param: &str, what: &str) -> Result<Interface, NodeError> {
    match *joint {
        Joint::Rigid => Ok(Interface::Rigid),
        Joint::Compliant { kt, ct, kr, cr } => {
            for (name, v) in [("kt", kt), ("kr", kr)] {
                if !v.is_finite() {
                    return Err(NodeError::param(
                        param,
                        format!(
                            "{what} gives no `{name}`: a compliant joint needs both `kt` and `kr` (or `rigid: true`)"
                        ),
                    ));
                }
            }
            Ok(Interface::diagonal(kt, ct, kr, cr))
        }
    }
}

/// The spindle–holder interface the `interface` parameter asks for.
fn holder_interface(ctx: &NodeContext, interface: &str, machine: Option<&str>) -> Result<Interface, NodeError> {
    if interface != "machine" {
        return Ok(Interface::Rigid);
    }
    let name = machine.ok_or_else(|| {
        NodeError::param("machine", "`interface: machine` needs `machine`, whose `holder_interface` to use")
    })?;
    let m = ctx
        .entities
        .machines
        .get(name)
        .ok_or_else(|| NodeError::param("machine", format!("no machine `{name}` in the recipe")))?;
    interface_of(&m.holder_interface, "machine", &format!("the `holder_interface` of machine `{name}`"))
}

fn check_coupling(p: &Params, interface: &str, machine: Option<&str>) -> Result<(), NodeError> {
    check_mesh(p)?;
    if interface == "machine" && machine.is_none() {
        return Err(NodeError::param(
            "machine",
            "`interface: machine` needs `machine`, whose `holder_interface` to use",
        ));
    }
    Ok(())
}

fn rcsa_options(max_condition: f64) -> RcsaOptions {
    RcsaOptions { max_condition }
}

/// The free–free two-port of `sections` (1 = tip, the last node; 2 = node 0, the spindle end) on
/// `freqs`, by modal expansion; `tip_mass` (kg) sits on the tip.
fn two_port(
    sections: &[Section],
    mesh: &MeshOptions,
    tip_mass: f64,
    freqs: &[f64],
    param: &str,
) -> Result<TwoPort, NodeError> {
    let fe = |e: beam::BeamError| NodeError::param(param, e.to_string());
    let mut model = BeamModel::from_segments(&beam::segments_from_sections(sections), mesh).map_err(fe)?;
    let tip = model.n_nodes() - 1;
    if tip_mass > 0.0 {
        model.add_point_mass(tip, tip_mass, 0.0).map_err(|e| NodeError::param("sensor", e.to_string()))?;
    }
    let modes = model.modes().map_err(fe)?;
    // Kept at tip and spindle end, the shapes are found once for the four blocks (viscous
    // dampers have no modal form: solved per line).
    let reduced = match modes.reduce(&[tip, 0]) {
        Ok(reduced) => Some(reduced),
        Err(beam::BeamError::NotReducible) => None,
        Err(e) => return Err(fe(e)),
    };
    let Some(reduced) = reduced else {
        let r = |a: usize, b: usize| -> Result<Vec<Receptance>, NodeError> {
            Ok(modes.receptance(a, b, freqs).map_err(fe)?.iter().map(block).collect())
        };
        return Ok(TwoPort {
            freqs_hz: freqs.to_vec(),
            r11: r(tip, tip)?,
            r12: r(tip, 0)?,
            r21: r(0, tip)?,
            r22: r(0, 0)?,
        });
    };
    two_port_of(&reduced, freqs).map_err(fe)
}

/// Named free–free parts of an assembly, and the tool joint `[kt, ct, kr, cr]` between two.
type Parts<'a> = (Vec<(&'static str, &'a [Section])>, Option<[f64; 4]>);

/// The free–free parts of an assembly: the whole of it when its `tool_joint` is rigid; otherwise
/// the holder (with the inserted shank) and the protruding tool, with the joint between them.
/// With `split`, a rigidly joined assembly is split too (no joint between the parts), so a
/// joint can be put there later (`substructure.joint`) without reducing the parts again.
fn assembly_parts<'a>(
    a: &'a spindlelab_engine::model::Assembly,
    name: &str,
    split: bool,
) -> Result<Parts<'a>, NodeError> {
    let joint = match a.tool_joint {
        Joint::Rigid if !split => return Ok((vec![("whole", &a.sections[..])], None)),
        joint => joint,
    };
    let split = a.sections.iter().position(|s| s.component == Component::Tool).unwrap_or(a.sections.len());
    let (holder, tool) = a.sections.split_at(split);
    if holder.is_empty() || tool.is_empty() {
        return Err(NodeError::param(
            "assembly",
            format!(
                "assembly `{name}` has a compliant `tool_joint` but no {} sections: the joint sits between the holder (`holder`, `holder+tool`) and the protruding tool (`tool`)",
                if holder.is_empty() { "holder" } else { "`tool`" }
            ),
        ));
    }
    if let Some(s) = tool.iter().find(|s| s.component != Component::Tool) {
        return Err(NodeError::param(
            "assembly",
            format!(
                "assembly `{name}`: section `{}` follows a `tool` section; list the holder sections first, then the protruding tool",
                s.name
            ),
        ));
    }
    // Checks that both stiffnesses are given.
    interface_of(&joint, "assembly", &format!("the `tool_joint` of assembly `{name}`"))?;
    let Joint::Compliant { kt, ct, kr, cr } = joint else {
        return Ok((vec![("holder", holder), ("tool", tool)], None));
    };
    Ok((vec![("holder", holder), ("tool", tool)], Some([kt, ct, kr, cr])))
}

/// The two-port of modes reduced to (tip, spindle end), all four blocks in one modal sum.
fn two_port_of(reduced: &beam::ReducedModes, freqs: &[f64]) -> Result<TwoPort, beam::BeamError> {
    let mut blocks = reduced.blocks(freqs)?.into_iter().map(|b| b.iter().map(block).collect());
    let mut next = || blocks.next().unwrap_or_default();
    Ok(TwoPort { freqs_hz: freqs.to_vec(), r11: next(), r12: next(), r21: next(), r22: next() })
}

/// Two grids agree when they have the same length and every line within 1e-9 relative.
pub(super) fn same_grid(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-9 * x.abs().max(y.abs()))
}

fn describe_grid(f: &[f64]) -> String {
    match (f.first(), f.last()) {
        (Some(a), Some(b)) => format!("{} lines, {a} … {b} Hz", f.len()),
        _ => "no lines".into(),
    }
}

/// Linear interpolation of the complex blocks of `s` onto `target`; refuses to extrapolate.
pub fn resample(s: &ReceptanceSet, target: &[f64]) -> Result<ReceptanceSet, String> {
    let f = &s.freq_hz;
    let (Some(&lo), Some(&hi)) = (f.first(), f.last()) else {
        return Err("it has no lines".into());
    };
    if let Some(i) = (1..f.len()).find(|&i| f[i] <= f[i - 1]) {
        return Err(format!("its lines do not ascend at line {i} ({} Hz)", f[i]));
    }
    let tol = 1e-12 * hi.abs();
    if let Some(x) = target.iter().find(|x| **x < lo - tol || **x > hi + tol) {
        return Err(format!("line {x} Hz lies outside its {lo} … {hi} Hz, and resampling does not extrapolate"));
    }
    let mut out = ReceptanceSet { freq_hz: target.to_vec(), h: vec![], l: vec![], n: vec![], p: vec![], ..s.clone() };
    for &x in target {
        let j = f.partition_point(|v| *v <= x).clamp(1, f.len().max(2) - 1).min(f.len() - 1);
        let (i0, i1) = if f.len() == 1 { (0, 0) } else { (j - 1, j) };
        let w = if i1 == i0 { 0.0 } else { ((x - f[i0]) / (f[i1] - f[i0])).clamp(0.0, 1.0) };
        let lerp = |v: &[rcsa::Complex64]| v[i0] * (1.0 - w) + v[i1] * w;
        out.h.push(lerp(&s.h));
        out.l.push(lerp(&s.l));
        out.n.push(lerp(&s.n));
        out.p.push(lerp(&s.p));
    }
    Ok(out)
}

/// The receptance input of a coupling node on the grid it works on: its own, or the `grid`
/// input's (equal, or resampled when `grid_mismatch: resample`), without a 0 Hz line.
fn input_on_grid(ctx: &NodeContext, port: &str, grid_mismatch: &str) -> Result<ReceptanceSet, NodeError> {
    let Value::ReceptanceSet(s) = ctx.input(port)? else {
        return Err(NodeError::input(port, "expected a 2x2 receptance set"));
    };
    let n = s.freq_hz.len();
    if [s.h.len(), s.l.len(), s.n.len(), s.p.len()].iter().any(|k| *k != n) {
        return Err(NodeError::input(port, format!("the blocks do not have one value per frequency line ({n} lines)")));
    }
    let mut s = s.clone();
    if let Some(l) = ctx.inputs_of("grid").first() {
        let Value::Frf(g) = l.value.as_ref() else {
            return Err(NodeError::input("grid", "expected an FRF"));
        };
        if !same_grid(&s.freq_hz, &g.freq_hz) {
            let first_diff = (s.freq_hz.len() == g.freq_hz.len())
                .then(|| s.freq_hz.iter().zip(&g.freq_hz).position(|(a, b)| a != b))
                .flatten()
                .map(|i| format!(", first difference at line {i}: {} vs {} Hz", s.freq_hz[i], g.freq_hz[i]))
                .unwrap_or_default();
            let both = format!(
                "`{port}` has {} but `grid` has {}{first_diff}",
                describe_grid(&s.freq_hz),
                describe_grid(&g.freq_hz)
            );
            if grid_mismatch != "resample" {
                return Err(NodeError::input(
                    "grid",
                    format!(
                        "frequency grids differ: {both}; give both the same grid, or set `grid_mismatch: resample`"
                    ),
                ));
            }
            s = resample(&s, &g.freq_hz)
                .map_err(|e| NodeError::input("grid", format!("cannot resample `{port}` onto `grid`: {e}")))?;
            ctx.warn(format!("frequency grids differ ({both}): `{port}` linearly interpolated onto `grid`"));
        } else {
            s.freq_hz = g.freq_hz.clone();
        }
    }
    if s.freq_hz.first().is_some_and(|f| *f == 0.0) {
        let keep = |v: &mut Vec<_>| {
            v.remove(0);
        };
        keep(&mut s.h);
        keep(&mut s.l);
        keep(&mut s.n);
        keep(&mut s.p);
        s.freq_hz.remove(0);
        ctx.warn(format!("`{port}`: the 0 Hz line is left out (a free-free substructure has no static receptance)"));
    }
    positive_lines(ctx, port, &s.freq_hz)?;
    Ok(s)
}

/// A coupling failure as a node error on `port`, with what to do about ill-conditioning.
fn rcsa_error(port: &str, e: RcsaError, hint: &str) -> NodeError {
    match e {
        RcsaError::IllConditioned { .. } => NodeError::input(port, format!("{e}; {hint}")),
        other => NodeError::input(port, other.to_string()),
    }
}

/// The kind name of `spindle.receptance`: the spindle model's receptance at the holder base.
pub const SPINDLE_RECEPTANCE: &str = "spindle.receptance";
/// The kind name of `rcsa.couple`: receptance coupling of a substructure to a spindle receptance.
pub const RCSA_COUPLE: &str = "rcsa.couple";
/// The kind name of `beam.substructure`: a tool/holder assembly reduced to its coupling points.
pub const BEAM_SUBSTRUCTURE: &str = "beam.substructure";

#[cfg(test)]
mod tests {
    use super::*;
    use rcsa::Complex64;

    fn set(freq: Vec<f64>, v: impl Fn(f64) -> Complex64) -> ReceptanceSet {
        let h: Vec<Complex64> = freq.iter().map(|f| v(*f)).collect();
        ReceptanceSet {
            l: h.iter().map(|x| x * 2.0).collect(),
            n: h.iter().map(|x| x * 3.0).collect(),
            p: h.iter().map(|x| x * 4.0).collect(),
            h,
            freq_hz: freq,
            direction: Some("x".into()),
            speed: Some(Speed::from_rpm(1000.0)),
        }
    }

    #[test]
    fn resampling_is_exact_for_linear_data_and_refuses_to_extrapolate() {
        let line = |f: f64| Complex64::new(2.0 * f - 1.0, -0.5 * f + 3.0);
        let s = set((0..=10).map(|i| 10.0 * i as f64).collect(), line);
        let target: Vec<f64> = vec![0.0, 3.3, 47.5, 99.9, 100.0];
        let r = resample(&s, &target).unwrap();
        for (f, (h, p)) in target.iter().zip(r.h.iter().zip(&r.p)) {
            assert!((h - line(*f)).norm() < 1e-12, "{f}: {h}");
            assert!((p - line(*f) * 4.0).norm() < 1e-12);
        }
        assert_eq!((r.direction, r.speed), (s.direction.clone(), s.speed));
        let e = resample(&s, &[50.0, 100.5]).unwrap_err();
        assert!(e.contains("100.5") && e.contains("extrapolate"), "{e}");
    }
}
