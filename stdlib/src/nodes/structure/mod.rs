//! Structural-model and RCSA node kinds (dissertation §5.1, §5.4): `beam.receptance` (free–free
//! Timoshenko FE model of an assembly), `spindle.receptance` (equivalent fixed-free
//! Euler–Bernoulli spindle modes, Eqs. 5.5–5.12), `beam.substructure` (the FE model reduced to
//! its coupling points, once), `rcsa.couple` (Eqs. 5.3, 5.16–5.17) and `rcsa.decouple` (inverse
//! RCSA, Eq. 5.4).
//!
//! Substructure receptances come from the modal expansion of the FE model: one eigen-solution
//! serves every frequency line, so a line costs a sum over the modes instead of a complex
//! solve of the whole mesh; with all modes kept the expansion equals the direct solve.

use crate::beam::{self, BeamModel, MeshOptions, ShearCoefficient};
use crate::eb_modes;
use crate::rcsa::{self, Interface, RcsaError, RcsaOptions, Receptance, ReceptanceFrf, TwoPort};
use spindlelab_domain::Speed;
use spindlelab_engine::model::{Component, Joint, Section};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, FieldType as T, Params};
use spindlelab_engine::value::{
    Column, Frf, PortType, ReceptanceSet, Substructure, SubstructurePart, Table, UnitLabel, Value,
};
use spindlelab_grammar::Dimension as D;
use std::sync::{Arc, Mutex};

const RATIO: T = T::Quantity(D::DIMENSIONLESS);

fn grid_port() -> PortSpec {
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
fn grid(ctx: &NodeContext, max_frequency: f64, resolution: Option<f64>, lines: usize) -> Result<Vec<f64>, NodeError> {
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

pub(super) fn to_set(f: &ReceptanceFrf, direction: Option<String>, speed_rpm: Option<f64>) -> ReceptanceSet {
    ReceptanceSet {
        freq_hz: f.freqs_hz.clone(),
        h: f.lines.iter().map(|r| r.h).collect(),
        l: f.lines.iter().map(|r| r.l).collect(),
        n: f.lines.iter().map(|r| r.n).collect(),
        p: f.lines.iter().map(|r| r.p).collect(),
        direction,
        speed_rpm,
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
        speed_rpm: s.speed_rpm,
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

/// A part's FE model reduced to its tip and spindle end (a [`SubstructurePart`]).
fn reduce_part(name: &str, sections: &[Section], mesh: &MeshOptions) -> Result<SubstructurePart, NodeError> {
    let fe = |e: beam::BeamError| NodeError::param("assembly", e.to_string());
    let model = BeamModel::from_segments(&beam::segments_from_sections(sections), mesh).map_err(fe)?;
    let tip = model.n_nodes() - 1;
    let reduced = model.modes().map_err(fe)?.reduce(&[tip, 0]).map_err(fe)?;
    let mut shapes = reduced.shapes.into_iter();
    let mut next = || shapes.next().unwrap_or_default();
    Ok(SubstructurePart {
        name: name.to_string(),
        length: sections.iter().map(|s| s.length).sum(),
        shift: reduced.sigma,
        rigid_modes: reduced.rigid,
        natural_hz: reduced.natural_hz,
        nu: reduced.nu,
        shapes: [next(), next(), next(), next()],
    })
}

/// A substructure part's two-port on `freqs` (1 = tip, 2 = spindle end).
fn part_two_port(part: &SubstructurePart, freqs: &[f64]) -> Result<TwoPort, NodeError> {
    let reduced = beam::ReducedModes {
        sigma: part.shift,
        rigid: part.rigid_modes,
        nu: part.nu.clone(),
        shapes: part.shapes.to_vec(),
        natural_hz: part.natural_hz.clone(),
    };
    two_port_of(&reduced, freqs).map_err(|e| NodeError::input("structure", format!("part `{}`: {e}", part.name)))
}

/// The two-port of modes reduced to (tip, spindle end), all four blocks in one modal sum.
fn two_port_of(reduced: &beam::ReducedModes, freqs: &[f64]) -> Result<TwoPort, beam::BeamError> {
    let mut blocks = reduced.blocks(freqs)?.into_iter().map(|b| b.iter().map(block).collect());
    let mut next = || blocks.next().unwrap_or_default();
    Ok(TwoPort { freqs_hz: freqs.to_vec(), r11: next(), r12: next(), r21: next(), r22: next() })
}

/// Two-ports already evaluated, by part and grid: a fit or a diagnosis couples the same
/// parts on the same lines hundreds of times while only a joint or the spindle changes, and
/// summing the parts' modes is most of a coupling's cost. A hit is checked against the full
/// part and grid, so it is exactly the value the sum would give.
fn cached_two_port(part: &SubstructurePart, freqs: &[f64]) -> Result<Arc<TwoPort>, NodeError> {
    type Entry = (SubstructurePart, Arc<TwoPort>);
    /// Enough for the parts of a few assemblies on a few grids (each about 1 MB).
    const KEEP: usize = 12;
    static CACHE: Mutex<Vec<Entry>> = Mutex::new(Vec::new());
    let hit = |c: &[Entry]| c.iter().find(|(p, t)| p == part && t.freqs_hz == freqs).map(|(_, t)| Arc::clone(t));
    if let Some(t) = hit(&CACHE.lock().unwrap_or_else(|e| e.into_inner())) {
        return Ok(t);
    }
    let t = Arc::new(part_two_port(part, freqs)?);
    let mut c = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    if c.len() >= KEEP {
        c.remove(0);
    }
    c.push((part.clone(), Arc::clone(&t)));
    Ok(t)
}

/// Two grids agree when they have the same length and every line within 1e-9 relative.
fn same_grid(a: &[f64], b: &[f64]) -> bool {
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

// ------------------------------------------------------------------ beam.receptance

/// The kind name of `spindle.receptance`: the spindle model's receptance at the holder base.
pub const SPINDLE_RECEPTANCE: &str = "spindle.receptance";
/// The kind name of `rcsa.couple`: receptance coupling of a substructure to a spindle receptance.
pub const RCSA_COUPLE: &str = "rcsa.couple";
/// The kind name of `beam.substructure`: a tool/holder assembly reduced to its coupling points.
pub const BEAM_SUBSTRUCTURE: &str = "beam.substructure";

node_params! {
    /// Parameters of `beam.receptance`.
    pub struct BeamReceptanceParams<'a> {
        assembly: req &'a str = (T::Entity(EntityKind::Assembly), "the sections, from the spindle end to the tip"),
        sensor: opt &'a str = (T::Entity(EntityKind::Sensor), "a sensor whose `mass` sits on the tip"),
        spin: opt f64 = (
            T::Quantity(D::ROTATIONAL_SPEED),
            "spin the assembly at this speed: gyroscopic (Nelson) elements couple the two planes; `tip` is then the in-plane block",
        ),
        max_frequency: def f64 = (T::Quantity(D::FREQUENCY), "5 kHz", "highest frequency line"),
        resolution: opt f64 = (T::Quantity(D::FREQUENCY), "line spacing; without it, max_frequency / lines"),
        lines: def usize = (
            T::Integer { min: 1, max: 1_000_000 },
            "1000",
            "number of lines (from one spacing up to max_frequency) when no resolution is given",
        ),
        max_element: def f64 = (T::Quantity(D::LENGTH), "2 mm", "longest Timoshenko element of the FE mesh"),
        shear: def &'a str = (
            T::Choice(&["cowper", "hutchinson"]),
            "cowper",
            "shear coefficient of the circular sections: Cowper (1966) or Hutchinson (2001)",
        ),
    }
}

/// `beam.receptance`: tip receptances of a free–free assembly (§5.4).
pub struct BeamReceptance {
    spec: NodeSpec,
}

impl Default for BeamReceptance {
    fn default() -> Self {
        Self::new()
    }
}

impl BeamReceptance {
    pub fn new() -> Self {
        BeamReceptance {
            spec: NodeSpec {
                kind: "beam.receptance",
                version: 2,
                description: "Free-free Timoshenko FE model of an assembly (§5.4, Table 5.1 sections) and its tip receptances H, L, N, P (Eq. 5.2) by modal expansion.",
                inputs: vec![grid_port()],
                outputs: vec![
                    PortSpec::new("tip", PortType::ReceptanceSet, "direct 2x2 receptances at the tip"),
                    PortSpec::new("frf", PortType::Frf, "the tip's H = y/F (m/N)"),
                    PortSpec::new(
                        "modes",
                        PortType::Table,
                        "free-free natural frequencies (rigid-body modes left out) up to the grid's highest line",
                    ),
                ],
                params: BeamReceptanceParams::fields(),
            },
        }
    }
}

impl Node for BeamReceptance {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        check_mesh(p)
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = BeamReceptanceParams::read(ctx.params)?;
        let freqs = grid(ctx, p.max_frequency, p.resolution, p.lines)?;
        let a = assembly(ctx, "assembly", p.assembly)?;
        let fe = |e: beam::BeamError| NodeError::param("assembly", e.to_string());
        let mut model =
            BeamModel::from_segments(&beam::segments_from_sections(&a.sections), &mesh(p.max_element, p.shear))
                .map_err(fe)?;
        let tip = model.n_nodes() - 1;
        let m = sensor_mass(ctx, p.sensor)?;
        if m > 0.0 {
            model.add_point_mass(tip, m, 0.0).map_err(|e| NodeError::param("sensor", e.to_string()))?;
        }
        if !matches!(a.tool_joint, Joint::Rigid) {
            ctx.warn("the assembly's `tool_joint` is not modelled here (one continuous beam); rcsa.couple models it");
        }
        let modes = model.modes().map_err(fe)?;
        let spin = p.spin.filter(|w| *w != 0.0);
        let lines: Vec<Receptance> = match spin {
            None => modes.receptance(tip, tip, &freqs).map_err(fe)?.iter().map(block).collect(),
            Some(w) => {
                let spinning = beam::spinning::SpinningModel::new(model.clone());
                let blocks = spinning.receptance(tip, tip, w, &freqs).map_err(fe)?;
                blocks.iter().map(|b| Receptance::new(b[0][0], b[0][1], b[1][0], b[1][1])).collect()
            }
        };
        let speed_rpm = spin.map(|w| Speed::from_rad_s(w).rpm());
        let set = to_set(&ReceptanceFrf { freqs_hz: freqs.clone(), lines }, None, speed_rpm);
        let top = freqs.last().copied().unwrap_or(0.0);
        let nat: Vec<f64> =
            modes.natural_frequencies().into_iter().skip(modes.rigid_modes()).take_while(|f| *f <= top).collect();
        let table = Table {
            columns: vec![
                Column::new("mode", "", (1..=nat.len()).map(|k| k as f64).collect()),
                Column::new("frequency", "Hz", nat),
            ],
        };
        let frf = h_of(&set);
        Ok(outputs(vec![("tip", Value::ReceptanceSet(set)), ("frf", Value::Frf(frf)), ("modes", Value::Table(table))]))
    }
}

// ------------------------------------------------------------------ spindle.receptance

node_params! {
    /// Parameters of `spindle.receptance`.
    pub struct SpindleReceptanceParams<'a> {
        machine: req &'a str = (T::Entity(EntityKind::Machine), "a machine with a `spindle` model"),
        direction: opt &'a str = (
            T::Choice(&["x", "y"]),
            "which direction's modes; default: the `grid` FRF's direction, else x",
        ),
        speed: opt f64 = (
            T::Quantity(D::ROTATIONAL_SPEED),
            "spindle speed for the speed laws; default: the `grid` FRF's speed, else 0 rpm",
        ),
        max_frequency: def f64 = (T::Quantity(D::FREQUENCY), "5 kHz", "highest frequency line"),
        resolution: opt f64 = (T::Quantity(D::FREQUENCY), "line spacing; without it, max_frequency / lines"),
        lines: def usize = (
            T::Integer { min: 1, max: 1_000_000 },
            "1000",
            "number of lines (from one spacing up to max_frequency) when no resolution is given",
        ),
    }
}

/// `spindle.receptance`: the spindle-machine receptance at the holder base from equivalent modes.
pub struct SpindleReceptance {
    spec: NodeSpec,
}

impl Default for SpindleReceptance {
    fn default() -> Self {
        Self::new()
    }
}

impl SpindleReceptance {
    pub fn new() -> Self {
        SpindleReceptance {
            spec: NodeSpec {
                kind: SPINDLE_RECEPTANCE,
                version: 2,
                description: "Spindle-machine receptances at the holder base as the sum of equivalent fixed-free Euler-Bernoulli modes (Eqs. 5.5-5.7, 5.10-5.12) at a speed.",
                inputs: vec![grid_port()],
                outputs: vec![
                    PortSpec::new("receptance", PortType::ReceptanceSet, "2x2 receptances at the holder base"),
                    PortSpec::new("frf", PortType::Frf, "its H = y/F (m/N)"),
                ],
                params: SpindleReceptanceParams::fields(),
            },
        }
    }
}

impl Node for SpindleReceptance {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        super::positive(p, &["max_frequency", "resolution"])?;
        super::non_negative(p, &["speed"])
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = SpindleReceptanceParams::read(ctx.params)?;
        let name = p.machine;
        let machine = ctx
            .entities
            .machines
            .get(name)
            .ok_or_else(|| NodeError::param("machine", format!("no machine `{name}` in the recipe")))?;
        let Some(spindle) = &machine.spindle else {
            return Err(NodeError::param(
                "machine",
                format!(
                    "machine `{name}` has no spindle model: add `spindle: {{material, modes: {{x: [{{f, d, eta}}]}}}}`"
                ),
            ));
        };
        // Direction and speed default to those of the measurement the model is evaluated
        // for, so one step serves every file of a measurement set.
        let measured = match ctx.inputs_of("grid").first().map(|l| l.value.as_ref()) {
            Some(Value::Frf(f)) => Some(f),
            _ => None,
        };
        let dir = p.direction.or_else(|| measured.and_then(|f| f.direction.as_deref())).unwrap_or("x");
        let Some((_, modes)) = spindle.modes.iter().find(|(d, _)| d == dir) else {
            let have: Vec<&str> = spindle.modes.iter().map(|(d, _)| d.as_str()).collect();
            return Err(NodeError::param(
                "direction",
                format!(
                    "machine `{name}` has no spindle modes in direction `{dir}`; it has: {}",
                    if have.is_empty() { "none".to_string() } else { have.join(", ") }
                ),
            ));
        };
        if modes.is_empty() {
            return Err(NodeError::param("machine", format!("machine `{name}` lists no spindle modes for `{dir}`")));
        }
        let freqs = grid(ctx, p.max_frequency, p.resolution, p.lines)?;
        // The measured FRF's speed as its file wrote it (rpm), so the label is the file's.
        let (speed, speed_rpm) = match (p.speed, measured.and_then(|f| f.speed_rpm)) {
            (Some(w), _) => (Speed::from_rad_s(w), Speed::from_rad_s(w).rpm()),
            (None, Some(s)) => (Speed::from_rpm(s), s),
            (None, None) => (Speed::ZERO, 0.0),
        };
        let r = eb_modes::spindle_receptance(modes, &spindle.material, speed, spindle.ref_speed, &freqs)
            .map_err(|e| NodeError::param("machine", format!("spindle of machine `{name}`, direction {dir}: {e}")))?;
        let set = to_set(&r, Some(dir.to_string()), Some(speed_rpm));
        let frf = h_of(&set);
        Ok(outputs(vec![("receptance", Value::ReceptanceSet(set)), ("frf", Value::Frf(frf))]))
    }
}

// ------------------------------------------------------------------ rcsa.couple

node_params! {
    /// Parameters of `rcsa.couple`.
    pub struct RcsaCoupleParams<'a> {
        assembly: opt &'a str = (
            T::Entity(EntityKind::Assembly),
            "holder and tool sections, meshed here; its `tool_joint` is used (or connect `structure`)",
        ),
        sensor: opt &'a str = (T::Entity(EntityKind::Sensor), "a sensor whose `mass` sits on the tool tip"),
        interface: def &'a str = (
            T::Choice(&["rigid", "machine"]),
            "rigid",
            "spindle–holder joint: rigid, or the `holder_interface` of `machine` (Eqs. 5.16–5.17)",
        ),
        machine: opt &'a str = (T::Entity(EntityKind::Machine), "the machine whose `holder_interface` to use"),
        grid_mismatch: def &'a str = (
            T::Choice(&["refuse", "resample"]),
            "refuse",
            "when `grid` is connected and its lines differ from the receptance input's: refuse, or interpolate the input linearly onto `grid` (no extrapolation)",
        ),
        max_condition: def f64 = (
            RATIO,
            "1e10",
            "largest accepted condition number of a 2x2 inversion (lengths scaled, see docs/structure.md)",
        ),
        max_element: def f64 = (T::Quantity(D::LENGTH), "2 mm", "longest Timoshenko element of the FE mesh"),
        shear: def &'a str = (
            T::Choice(&["cowper", "hutchinson"]),
            "cowper",
            "shear coefficient of the circular sections: Cowper (1966) or Hutchinson (2001)",
        ),
    }
}

/// `rcsa.couple`: tool-tip receptances of an assembly on a spindle (Eqs. 5.3, 5.16–5.17).
pub struct RcsaCouple {
    spec: NodeSpec,
}

impl Default for RcsaCouple {
    fn default() -> Self {
        Self::new()
    }
}

impl RcsaCouple {
    pub fn new() -> Self {
        RcsaCouple {
            spec: NodeSpec {
                kind: RCSA_COUPLE,
                version: 2,
                description: "RCSA: couples a free-free FE assembly to the spindle receptances at its base, G11 = R11 - R12 (R22 + K^-1 + B)^-1 R21 (Eqs. 5.3, 5.16-5.17); a compliant tool_joint makes it spindle-holder-tool.",
                inputs: vec![
                    PortSpec::new("spindle", PortType::ReceptanceSet, "spindle receptances B at the holder base"),
                    PortSpec::new(
                        "structure",
                        PortType::Substructure,
                        "the holder and tool, reduced once by beam.substructure (instead of `assembly`)",
                    )
                    .optional(),
                    PortSpec::new(
                        "grid",
                        PortType::Frf,
                        "an FRF whose frequency lines the result is to have (see `grid_mismatch`)",
                    )
                    .optional(),
                ],
                outputs: vec![
                    PortSpec::new("tip", PortType::ReceptanceSet, "2x2 receptances at the tool tip"),
                    PortSpec::new("frf", PortType::Frf, "tool-tip H (m/N), direction and speed of the spindle input"),
                ],
                params: RcsaCoupleParams::fields(),
            },
        }
    }
}

impl Node for RcsaCouple {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = RcsaCoupleParams::read(params)?;
        check_coupling(params, p.interface, p.machine)
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = RcsaCoupleParams::read(ctx.params)?;
        let spindle = input_on_grid(ctx, "spindle", p.grid_mismatch)?;
        let interface = holder_interface(ctx, p.interface, p.machine)?;
        let tip_mass = sensor_mass(ctx, p.sensor)?;
        let freqs = spindle.freq_hz.clone();
        let base = to_frf(&spindle);
        let opts = rcsa_options(p.max_condition);
        let hint = "the spindle receptance and the assembly's joint receptance cancel there; check the spindle model and the joint";
        let (ports, tool_joint) = match ctx.inputs_of("structure").first().map(|l| l.value.as_ref()) {
            Some(Value::Substructure(s)) => {
                let ports = s.parts.iter().map(|part| cached_two_port(part, &freqs)).collect::<Result<Vec<_>, _>>()?;
                (ports, s.tool_joint)
            }
            Some(other) => {
                return Err(NodeError::input(
                    "structure",
                    format!("expected a substructure, got {}", other.port_type()),
                ));
            }
            None => {
                let name = p.assembly.ok_or_else(|| {
                    NodeError::param(
                        "assembly",
                        "rcsa.couple needs `assembly`, or a substructure connected to `structure`",
                    )
                })?;
                let a = assembly(ctx, "assembly", name)?;
                let (parts, joint) = assembly_parts(a, name, false)?;
                let mesh = mesh(p.max_element, p.shear);
                let ports = parts
                    .iter()
                    .map(|(_, sections)| two_port(sections, &mesh, 0.0, &freqs, "assembly").map(Arc::new))
                    .collect::<Result<Vec<_>, _>>()?;
                (ports, joint)
            }
        };
        let mut g = match (&ports[..], tool_joint) {
            ([whole], _) => {
                rcsa::couple(whole, &base, &interface, &opts).map_err(|e| rcsa_error("spindle", e, hint))?
            }
            ([holder, tool], joint) => {
                let at_tool = match joint {
                    Some([kt, ct, kr, cr]) => Interface::diagonal(kt, ct, kr, cr),
                    None => Interface::Rigid,
                };
                rcsa::couple_chain(&base, &[(&**holder, interface), (&**tool, at_tool)], &opts)
                    .map_err(|e| rcsa_error("spindle", e, hint))?
            }
            _ => return Err(NodeError::input("structure", "a substructure has one part, or two (holder and tool)")),
        };
        if tip_mass > 0.0 {
            g = rcsa::with_point_mass(&g, tip_mass).map_err(|e| {
                rcsa_error("sensor", e, "the sensor mass resonates with the structure exactly on a line")
            })?;
        }
        let set = to_set(&g, spindle.direction.clone(), spindle.speed_rpm);
        let frf = h_of(&set);
        Ok(outputs(vec![("tip", Value::ReceptanceSet(set)), ("frf", Value::Frf(frf))]))
    }
}

// ------------------------------------------------------------------ beam.substructure

node_params! {
    /// Parameters of `beam.substructure`.
    pub struct BeamSubstructureParams<'a> {
        assembly: req &'a str = (
            T::Entity(EntityKind::Assembly),
            "holder and tool sections; a compliant `tool_joint` splits it into holder and tool",
        ),
        split: def &'a str = (
            T::Choice(&["auto", "holder_face"]),
            "auto",
            "`holder_face`: reduce holder and tool separately even with a rigid tool joint, so `substructure.joint` can put a joint there; `auto`: split only at a compliant `tool_joint`",
        ),
        max_element: def f64 = (T::Quantity(D::LENGTH), "2 mm", "longest Timoshenko element of the FE mesh"),
        shear: def &'a str = (
            T::Choice(&["cowper", "hutchinson"]),
            "cowper",
            "shear coefficient of the circular sections: Cowper (1966) or Hutchinson (2001)",
        ),
    }
}

/// `beam.substructure`: an assembly's free–free FE model reduced once to its tip and spindle end.
pub struct BeamSubstructure {
    spec: NodeSpec,
}

impl Default for BeamSubstructure {
    fn default() -> Self {
        Self::new()
    }
}

impl BeamSubstructure {
    pub fn new() -> Self {
        BeamSubstructure {
            spec: NodeSpec {
                kind: BEAM_SUBSTRUCTURE,
                version: 2,
                description: "Free-free Timoshenko FE model of an assembly (§5.4) with structural damping, reduced to its tip and spindle end: every complex mode, computed once and coupled by rcsa.couple at every speed, direction and joint setting.",
                inputs: vec![],
                outputs: vec![PortSpec::new(
                    "model",
                    PortType::Substructure,
                    "the holder and tool as complex modes at tip and spindle end",
                )],
                params: BeamSubstructureParams::fields(),
            },
        }
    }
}

impl Node for BeamSubstructure {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        check_mesh(p)
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = BeamSubstructureParams::read(ctx.params)?;
        let name = p.assembly;
        let a = assembly(ctx, "assembly", name)?;
        let (parts, tool_joint) = assembly_parts(a, name, p.split == "holder_face")?;
        let mesh = mesh(p.max_element, p.shear);
        let parts =
            parts.iter().map(|(part, sections)| reduce_part(part, sections, &mesh)).collect::<Result<Vec<_>, _>>()?;
        let model = Substructure { assembly: name.to_string(), parts, tool_joint };
        Ok(outputs(vec![("model", Value::Substructure(model))]))
    }
}

// ------------------------------------------------------------------ rcsa.decouple

node_params! {
    /// Parameters of `rcsa.decouple`.
    pub struct RcsaDecoupleParams<'a> {
        artifact: req &'a str = (T::Entity(EntityKind::Assembly), "the artifact beyond the flange, as one body"),
        sensor: opt &'a str = (
            T::Entity(EntityKind::Sensor),
            "a sensor whose `mass` sat on the tip when G11 was measured",
        ),
        interface: def &'a str = (
            T::Choice(&["rigid", "machine"]),
            "rigid",
            "spindle–holder joint: rigid, or the `holder_interface` of `machine` (Eqs. 5.16–5.17)",
        ),
        machine: opt &'a str = (T::Entity(EntityKind::Machine), "the machine whose `holder_interface` to use"),
        grid_mismatch: def &'a str = (
            T::Choice(&["refuse", "resample"]),
            "refuse",
            "when `grid` is connected and its lines differ from the receptance input's: refuse, or interpolate the input linearly onto `grid` (no extrapolation)",
        ),
        max_condition: def f64 = (
            RATIO,
            "1e10",
            "largest accepted condition number of a 2x2 inversion (lengths scaled, see docs/structure.md)",
        ),
        max_element: def f64 = (T::Quantity(D::LENGTH), "2 mm", "longest Timoshenko element of the FE mesh"),
        shear: def &'a str = (
            T::Choice(&["cowper", "hutchinson"]),
            "cowper",
            "shear coefficient of the circular sections: Cowper (1966) or Hutchinson (2001)",
        ),
    }
}

/// `rcsa.decouple`: spindle receptances from an artifact's tip receptances (inverse RCSA, Eq. 5.4).
pub struct RcsaDecouple {
    spec: NodeSpec,
}

impl Default for RcsaDecouple {
    fn default() -> Self {
        Self::new()
    }
}

impl RcsaDecouple {
    pub fn new() -> Self {
        RcsaDecouple {
            spec: NodeSpec {
                kind: "rcsa.decouple",
                version: 1,
                description: "Inverse RCSA: the spindle receptances at the holder base from the artifact-tip receptances G11, R2b2b = R2a1 (R11 - G11)^-1 R12a - R2a2a - K^-1 (Eq. 5.4 as corrected, with Eqs. 5.16-5.17).",
                inputs: vec![
                    PortSpec::new(
                        "assembly_tip",
                        PortType::ReceptanceSet,
                        "2x2 receptances G11 at the artifact tip on the spindle (e.g. from a fit)",
                    ),
                    PortSpec::new(
                        "grid",
                        PortType::Frf,
                        "an FRF whose frequency lines the result is to have (see `grid_mismatch`)",
                    )
                    .optional(),
                ],
                outputs: vec![PortSpec::new(
                    "spindle",
                    PortType::ReceptanceSet,
                    "spindle receptances at the holder base, direction and speed of the input",
                )],
                params: RcsaDecoupleParams::fields(),
            },
        }
    }
}

impl Node for RcsaDecouple {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        let p = RcsaDecoupleParams::read(params)?;
        check_coupling(params, p.interface, p.machine)
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = RcsaDecoupleParams::read(ctx.params)?;
        let g11 = input_on_grid(ctx, "assembly_tip", p.grid_mismatch)?;
        let a = assembly(ctx, "artifact", p.artifact)?;
        if !matches!(a.tool_joint, Joint::Rigid) {
            ctx.warn("the artifact's `tool_joint` is not used: the artifact is decoupled as one body");
        }
        let interface = holder_interface(ctx, p.interface, p.machine)?;
        let tip_mass = sensor_mass(ctx, p.sensor)?;
        let freqs = g11.freq_hz.clone();
        let art = two_port(&a.sections, &mesh(p.max_element, p.shear), tip_mass, &freqs, "artifact")?;
        let hint = "there the artifact's own tip receptance R11 equals G11 (R11 - G11 is singular, e.g. G11 of the free artifact or lines where a measured G11 is noise), so the spindle is not determined: leave those lines out of the grid or fit G11 first";
        let b = rcsa::decouple(&art, &to_frf(&g11), &interface, &rcsa_options(p.max_condition))
            .map_err(|e| rcsa_error("assembly_tip", e, hint))?;
        let set = to_set(&b, g11.direction.clone(), g11.speed_rpm);
        Ok(outputs(vec![("spindle", Value::ReceptanceSet(set))]))
    }
}

// ------------------------------------------------------------------ beam.campbell

node_params! {
    /// Parameters of `beam.campbell`.
    pub struct BeamCampbellParams<'a> {
        assembly: req &'a str = (T::Entity(EntityKind::Assembly), "the sections, from the spindle end to the tip"),
        sensor: opt &'a str = (T::Entity(EntityKind::Sensor), "a sensor whose `mass` sits on the tip"),
        speeds: req &'a [f64] = (T::QuantityList(D::ROTATIONAL_SPEED), "spin speeds, e.g. `0..30000 step 5000 rpm`"),
        max_frequency: def f64 = (T::Quantity(D::FREQUENCY), "20 kHz", "highest whirl frequency listed"),
        max_element: def f64 = (T::Quantity(D::LENGTH), "2 mm", "longest Timoshenko element of the FE mesh"),
        shear: def &'a str = (
            T::Choice(&["cowper", "hutchinson"]),
            "cowper",
            "shear coefficient of the circular sections: Cowper (1966) or Hutchinson (2001)",
        ),
    }
}

/// `beam.campbell`: forward and backward whirl frequencies of a spinning free–free assembly.
pub struct BeamCampbell {
    spec: NodeSpec,
}

impl Default for BeamCampbell {
    fn default() -> Self {
        Self::new()
    }
}

impl BeamCampbell {
    pub fn new() -> Self {
        BeamCampbell {
            spec: NodeSpec {
                kind: "beam.campbell",
                version: 1,
                description: "Campbell table of a spinning free-free Timoshenko assembly: forward and backward whirl frequencies per speed, with the gyroscopic matrices of Nelson's rotating elements.",
                inputs: vec![],
                outputs: vec![PortSpec::new(
                    "whirl",
                    PortType::Table,
                    "one row per speed and whirl: speed (rpm), frequency (Hz), whirl (+1 forward, −1 backward)",
                )],
                params: BeamCampbellParams::fields(),
            },
        }
    }
}

impl Node for BeamCampbell {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, p: &Params) -> Result<(), NodeError> {
        check_mesh(p)
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = BeamCampbellParams::read(ctx.params)?;
        let a = assembly(ctx, "assembly", p.assembly)?;
        let fe = |e: beam::BeamError| NodeError::param("assembly", e.to_string());
        let mut model =
            BeamModel::from_segments(&beam::segments_from_sections(&a.sections), &mesh(p.max_element, p.shear))
                .map_err(fe)?;
        let m = sensor_mass(ctx, p.sensor)?;
        if m > 0.0 {
            let tip = model.n_nodes() - 1;
            model.add_point_mass(tip, m, 0.0).map_err(|e| NodeError::param("sensor", e.to_string()))?;
        }
        let speeds = p.speeds.to_vec();
        let top = p.max_frequency;
        let whirls = beam::spinning::SpinningModel::new(model).campbell(&speeds).map_err(fe)?;
        // One row per whirl: forward (+1) orbits turn with the spin, backward (−1) against it.
        let mut cols: [Vec<f64>; 3] = Default::default();
        for w in &whirls {
            let rows = w.forward.iter().map(|f| (*f, 1.0)).chain(w.backward.iter().map(|f| (*f, -1.0)));
            let mut rows: Vec<(f64, f64)> = rows.filter(|(f, _)| *f <= top).collect();
            rows.sort_by(|a, b| a.0.total_cmp(&b.0).then(b.1.total_cmp(&a.1)));
            for (f, sense) in rows {
                cols[0].push(Speed::from_rad_s(w.speed).rpm());
                cols[1].push(f);
                cols[2].push(sense);
            }
        }
        let [speed, frequency, sense] = cols;
        let table = Table {
            columns: vec![
                Column::new("speed", "rpm", speed),
                Column::new("frequency", "Hz", frequency),
                Column::new("whirl", "", sense),
            ],
        };
        Ok(outputs(vec![("whirl", Value::Table(table))]))
    }
}

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
            speed_rpm: Some(1000.0),
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
        assert_eq!((r.direction, r.speed_rpm), (s.direction.clone(), s.speed_rpm));
        let e = resample(&s, &[50.0, 100.5]).unwrap_err();
        assert!(e.contains("100.5") && e.contains("extrapolate"), "{e}");
    }
}
