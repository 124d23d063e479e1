//! A plugin's node kinds as engine nodes: described once at load, each call in a fresh,
//! bounded store.

use crate::lend;
use crate::v0_1_0::{self as v1, NamedParam, ParamType, ParamValue};
use crate::v0_2_0 as v2;
use crate::{Limits, LoadError, Manifest};
use spindlelab_engine::diag::escape_controls;
use spindlelab_engine::grammar::{self, Dimension};
use spindlelab_engine::model::Entities;
use spindlelab_engine::node::{EffectParam, EffectSpec, Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::spec::{EntityKind, Field, FieldType, ParamValue as P, Params};
use spindlelab_engine::value::Value;
use std::sync::Arc;
use wasmtime::component::{self, ComponentExportIndex, InstancePre};
use wasmtime::{Engine, ResourceLimiter, Store, Trap};

/// A counting semaphore over the host's instance slots.
pub(crate) struct Slots {
    free: std::sync::Mutex<usize>,
    freed: std::sync::Condvar,
}

impl Slots {
    pub fn new(n: usize) -> Slots {
        Slots { free: std::sync::Mutex::new(n), freed: std::sync::Condvar::new() }
    }
    fn take(&self) -> SlotGuard<'_> {
        let mut free = self.free.lock().unwrap_or_else(|e| e.into_inner());
        while *free == 0 {
            free = self.freed.wait(free).unwrap_or_else(|e| e.into_inner());
        }
        *free -= 1;
        SlotGuard(self)
    }
}

struct SlotGuard<'a>(&'a Slots);

impl Drop for SlotGuard<'_> {
    fn drop(&mut self) {
        *self.0.free.lock().unwrap_or_else(|e| e.into_inner()) += 1;
        self.0.freed.notify_one();
    }
}

/// The pre-instantiated component, bound by its interface version, and where its `run` is.
pub(crate) struct Pre {
    bound: Bound,
    /// `run` of the interface `node`, called with the inputs lent (`lend`), not through the
    /// bindings.
    run: ComponentExportIndex,
}

enum Bound {
    V0_1_0(v1::PluginPre<State>),
    V0_2_0(v2::PluginPre<State>),
}

impl Pre {
    pub fn new(pre: InstancePre<State>, interface: &str) -> wasmtime::Result<Pre> {
        let node = pre.component().get_export_index(None, format!("spindlelab:plugin/node@{interface}"));
        let run = pre
            .component()
            .get_export_index(node.as_ref(), "run")
            .ok_or_else(|| wasmtime::format_err!("no function `run` in interface `node`"))?;
        let bound = match interface {
            "0.1.0" => Bound::V0_1_0(v1::PluginPre::new(pre)?),
            _ => Bound::V0_2_0(v2::PluginPre::new(pre)?),
        };
        Ok(Pre { bound, run })
    }

    fn instance_pre(&self) -> &InstancePre<State> {
        match &self.bound {
            Bound::V0_1_0(p) => p.instance_pre(),
            Bound::V0_2_0(p) => p.instance_pre(),
        }
    }
}

/// What one plugin's calls share: the engine, the pre-instantiated component, its limits.
pub(crate) struct Runtime {
    pub engine: Engine,
    pub slots: Arc<Slots>,
    pub pre: Pre,
    pub limits: Limits,
    pub id: String,
    pub version: String,
    pub sha256: String,
}

/// The store's data of one call: the memory limiter and what it refused.
pub(crate) struct State {
    memory_cap: usize,
    refused: Option<usize>,
}

impl ResourceLimiter for State {
    fn memory_growing(&mut self, _current: usize, desired: usize, _maximum: Option<usize>) -> wasmtime::Result<bool> {
        if desired > self.memory_cap {
            self.refused = Some(desired);
            return Err(wasmtime::format_err!("memory limit"));
        }
        Ok(true)
    }
    fn table_growing(&mut self, _current: usize, desired: usize, _maximum: Option<usize>) -> wasmtime::Result<bool> {
        Ok(desired <= 1 << 20)
    }
    fn instances(&self) -> usize {
        16
    }
    fn memories(&self) -> usize {
        4
    }
    fn tables(&self) -> usize {
        16
    }
}

/// An instance of the component, by interface version.
enum Instance {
    V0_1_0(v1::Plugin),
    V0_2_0(v2::Plugin),
}

/// Why a call failed, for the node's error.
enum CallError {
    OutOfFuel,
    Memory(usize),
    Trap(String),
    Plugin(String),
}

impl Runtime {
    /// A fresh store with this plugin's limits.
    fn store(&self) -> Store<State> {
        let mut store = Store::new(&self.engine, State { memory_cap: self.limits.memory as usize, refused: None });
        store.limiter(|s| s as &mut dyn ResourceLimiter);
        store.set_fuel(self.limits.fuel).expect("fuel is enabled");
        store
    }

    fn classify(&self, store: &Store<State>, e: wasmtime::Error) -> CallError {
        if let Some(bytes) = store.data().refused {
            return CallError::Memory(bytes);
        }
        match e.downcast_ref::<Trap>() {
            Some(Trap::OutOfFuel) => CallError::OutOfFuel,
            Some(Trap::UnreachableCodeReached) => {
                CallError::Trap("it trapped (a panic in the plugin, or an `unreachable` instruction)".into())
            }
            Some(t) => CallError::Trap(format!("it trapped: {t}")),
            None => CallError::Trap(format!("{e:#}")),
        }
    }

    /// Runs `f` on a fresh instance in a fresh store; the store (and its instance's slot) is
    /// dropped before the slot is given back.
    fn call<T>(
        &self,
        f: impl FnOnce(&mut Store<State>, component::Instance) -> wasmtime::Result<T>,
    ) -> Result<T, CallError> {
        let _slot = self.slots.take();
        let mut store = self.store();
        match self.pre.instance_pre().instantiate(&mut store).and_then(|i| f(&mut store, i)) {
            Ok(v) => Ok(v),
            Err(e) => Err(self.classify(&store, e)),
        }
    }

    /// Runs `f` on a fresh instance through the bindings of its interface version.
    fn call_bound<T>(
        &self,
        f: impl FnOnce(&mut Store<State>, Instance) -> wasmtime::Result<T>,
    ) -> Result<T, CallError> {
        self.call(|store, i| {
            let bound = match self.pre.bound {
                Bound::V0_1_0(_) => Instance::V0_1_0(v1::Plugin::new(&mut *store, &i)?),
                Bound::V0_2_0(_) => Instance::V0_2_0(v2::Plugin::new(&mut *store, &i)?),
            };
            f(store, bound)
        })
    }

    fn describe(&self) -> Result<v1::PluginInfo, CallError> {
        self.call_bound(|store, i| match i {
            Instance::V0_1_0(p) => p.spindlelab_plugin_node().call_describe(store),
            Instance::V0_2_0(p) => p.spindlelab_plugin_node().call_describe(store),
        })
    }

    /// The effects the plugin offers (none before interface 0.2.0).
    fn effects(&self) -> Result<Vec<v2::Effect>, CallError> {
        match self.pre.bound {
            Bound::V0_1_0(_) => Ok(Vec::new()),
            Bound::V0_2_0(_) => self.call_bound(|store, i| match i {
                Instance::V0_2_0(p) => p.spindlelab_plugin_effects().call_effects(store),
                Instance::V0_1_0(_) => Ok(Vec::new()),
            }),
        }
    }

    fn run(&self, kind: &str, params: &[NamedParam], inputs: &[lend::Input]) -> Result<v1::Outcome, CallError> {
        type Run<'a> = (&'a str, &'a [NamedParam], &'a [lend::Input<'a>]);
        let result = self.call(|store, i| {
            let run = i
                .get_func(&mut *store, self.pre.run)
                .ok_or_else(|| wasmtime::format_err!("no function `run`"))?
                .typed::<Run, (Result<v1::Outcome, String>,)>(&*store)?;
            Ok(run.call(store, (kind, params, inputs))?.0)
        })?;
        result.map_err(|m| CallError::Plugin(guest_text(&m)))
    }

    fn explain(&self, e: CallError) -> String {
        match e {
            CallError::OutOfFuel => format!(
                "it ran out of its work bound ({} fuel units, about as many instructions) and was stopped; if the \
                 input is that large, ask for more fuel in its manifest's `limits`",
                self.limits.fuel
            ),
            CallError::Memory(bytes) => format!(
                "it asked for {} MiB of memory, beyond its cap of {} MiB, and was stopped",
                bytes >> 20,
                self.limits.memory >> 20
            ),
            CallError::Trap(m) | CallError::Plugin(m) => m,
        }
    }
}

/// Leaks a plugin's text for the engine's `'static` node descriptions: a plugin is
/// described once per process, so this is bounded by the plugins loaded.
fn leak(s: String) -> &'static str {
    Box::leak(s.into_boxed_str())
}

/// A plugin's words (its error, a warning, a description) as the host passes them on: at
/// most [`MAX_TEXT`] characters, control characters escaped (`\x1b`, `\n`), so a plugin can
/// neither drive the terminal nor print a line that looks like the program's own.
fn guest_text(s: &str) -> String {
    let cut: String = s.chars().take(MAX_TEXT).collect();
    let more = if cut.len() < s.len() { "…" } else { "" };
    format!("{}{more}", escape_controls(&cut))
}

/// What a number that is not finite is, for a message.
fn not_finite(x: f64) -> &'static str {
    if x.is_nan() {
        "NaN"
    } else if x > 0.0 {
        "+inf"
    } else {
        "-inf"
    }
}

/// Where the first number of a plugin's output that is not finite sits, and what it is
/// (`sample 7 of channel `ax` is NaN`), or `None` when every number is finite. Lobes may
/// hold `+inf` as their documented "no limit at this speed" (and any chatter frequency there).
pub(crate) fn first_non_finite(v: &Value) -> Option<String> {
    let first = |xs: &[f64]| xs.iter().position(|x| !x.is_finite()).map(|i| (i, not_finite(xs[i])));
    match v {
        Value::Scalar(s) => first(&[s.value]).map(|(_, w)| format!("the value is {w}")),
        Value::TimeSeries(t) => first(&[t.sample_rate])
            .map(|(_, w)| format!("the sample rate is {w}"))
            .or_else(|| first(&[t.t0]).map(|(_, w)| format!("the start time is {w}")))
            .or_else(|| {
                t.channels.iter().find_map(|c| {
                    first(&c.samples).map(|(i, w)| format!("sample {i} of channel `{}` is {w}", guest_text(&c.name)))
                })
            }),
        Value::Frf(f) => {
            let re: Vec<f64> = f.values.iter().map(|v| v.re).collect();
            let im: Vec<f64> = f.values.iter().map(|v| v.im).collect();
            let lines = [("frequency", &f.freq_hz[..]), ("real part", &re[..]), ("imaginary part", &im[..])];
            let coherence = f.coherence.as_deref().map(|c| ("coherence", c));
            lines
                .into_iter()
                .chain(coherence)
                .filter_map(|(what, xs)| first(xs).map(|(i, w)| (i, format!("the {what} at line {i} is {w}"))))
                .min_by_key(|(i, _)| *i)
                .map(|(_, m)| m)
                .or_else(|| f.speed.and_then(|s| first(&[s.rpm()])).map(|(_, w)| format!("the speed is {w}")))
        }
        Value::ModalModel(m) => m.modes.iter().enumerate().find_map(|(i, mode)| {
            [("frequency", mode.freq_hz), ("damping ratio", mode.damping_ratio), ("modal mass", mode.modal_mass)]
                .into_iter()
                .find(|(_, x)| !x.is_finite())
                .map(|(what, x)| format!("the {what} of mode {i} is {}", not_finite(x)))
        }),
        Value::Lobes(l) => (0..l.speed.len()).find_map(|i| {
            let (speed, depth, chatter) = (l.speed[i].rpm(), l.depth_limit[i], l.chatter_hz[i]);
            if !speed.is_finite() {
                Some(format!("the speed at point {i} is {}", not_finite(speed)))
            } else if !depth.is_finite() && depth != f64::INFINITY {
                Some(format!("the depth limit at point {i} is {}", not_finite(depth)))
            } else if !chatter.is_finite() && depth != f64::INFINITY {
                Some(format!("the chatter frequency at point {i} (a finite limit) is {}", not_finite(chatter)))
            } else {
                None
            }
        }),
        Value::Table(t) => t
            .columns
            .iter()
            .find_map(|c| first(&c.values).map(|(i, w)| format!("row {i} of column `{}` is {w}", guest_text(&c.name)))),
        // Kinds a plugin cannot return.
        Value::ReceptanceSet(_) | Value::BeamModel(_) | Value::Substructure(_) | Value::FrfSet(_) => None,
    }
}

/// The first name or unit of a plugin's output that holds a control character (they go
/// into files' headers and onto the terminal), or `None`.
pub(crate) fn label_with_control(v: &Value) -> Option<String> {
    let bad = |what: &str, s: &str| s.chars().any(char::is_control).then(|| format!("{what} {}", guest_text(s)));
    match v {
        Value::Scalar(s) => bad("the unit", &s.unit.symbol),
        Value::TimeSeries(t) => {
            t.channels.iter().find_map(|c| bad("the channel name", &c.name).or_else(|| bad("the unit", &c.unit.symbol)))
        }
        Value::Frf(f) => bad("the unit", &f.unit.symbol)
            .or_else(|| f.direction.as_deref().and_then(|d| bad("the direction", d)))
            .or_else(|| f.sensor.as_deref().and_then(|d| bad("the sensor", d))),
        Value::Table(t) => {
            t.columns.iter().find_map(|c| bad("the column name", &c.name).or_else(|| bad("the unit", &c.unit.symbol)))
        }
        _ => None,
    }
}

const MAX_KINDS: usize = 256;
const MAX_PORTS: usize = 64;
const MAX_PARAMS: usize = 128;
const MAX_TEXT: usize = 4096;

/// Asks the plugin to describe itself and checks what it says.
pub(crate) fn describe(rt: &Arc<Runtime>, manifest: &Manifest) -> Result<Vec<Arc<PluginNode>>, LoadError> {
    let id = manifest.id.clone();
    let bad = |message: String| LoadError::BadDescription { id: id.clone(), message };
    let info = rt.describe().map_err(|e| LoadError::Describe { id: id.clone(), message: rt.explain(e) })?;
    if info.name != manifest.id || info.version != manifest.version {
        return Err(bad(format!(
            "it calls itself `{}` {} but its manifest says `{}` {}; rebuild it with `spindlelab plugin build`",
            guest_text(&info.name),
            guest_text(&info.version),
            guest_text(&manifest.id),
            guest_text(&manifest.version)
        )));
    }
    if info.nodes.is_empty() || info.nodes.len() > MAX_KINDS {
        return Err(bad(format!("it describes {} node kinds; a plugin provides 1 to {MAX_KINDS}", info.nodes.len())));
    }
    let mut effects = rt.effects().map_err(|e| LoadError::Describe { id: id.clone(), message: rt.explain(e) })?;
    if effects.len() > MAX_KINDS {
        return Err(bad(format!("it offers {} effects; at most {MAX_KINDS}", effects.len())));
    }
    let mut seen = std::collections::HashSet::new();
    let mut nodes = Vec::new();
    for k in info.nodes {
        let kind = k.kind.clone();
        let bad_kind = |m: String| bad(format!("node kind `{}`: {m}", guest_text(&kind)));
        let dotted = kind.split('.').count() >= 2
            && kind
                .split('.')
                .all(|p| !p.is_empty() && p.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_'));
        if !dotted || kind.len() > 64 {
            return Err(bad_kind("a kind is dotted lowercase words, e.g. `chatter.indicator`".into()));
        }
        if !seen.insert(kind.clone()) {
            return Err(bad_kind("described twice".into()));
        }
        if k.inputs.len() > MAX_PORTS || k.outputs.len() > MAX_PORTS || k.params.len() > MAX_PARAMS {
            return Err(bad_kind(format!("at most {MAX_PORTS} ports each way and {MAX_PARAMS} parameters")));
        }
        if k.outputs.is_empty() {
            return Err(bad_kind("it has no outputs".into()));
        }
        let texts = std::iter::once(&k.description)
            .chain(k.inputs.iter().chain(&k.outputs).flat_map(|p| [&p.name, &p.doc]))
            .chain(k.params.iter().flat_map(|p| [&p.name, &p.doc]));
        if texts.clone().any(|t| t.len() > MAX_TEXT) {
            return Err(bad_kind(format!("a name or description is longer than {MAX_TEXT} bytes")));
        }
        let ident =
            |n: &str| !n.is_empty() && n.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_');
        let mut names = std::collections::HashSet::new();
        for n in k.inputs.iter().map(|p| &p.name).chain(k.params.iter().map(|p| &p.name)) {
            if !ident(n) || !names.insert(n.clone()) {
                return Err(bad_kind(format!(
                    "`{}` is not a unique lowercase name (letters, digits, `_`)",
                    guest_text(n)
                )));
            }
        }
        let mut outs = std::collections::HashSet::new();
        for n in k.outputs.iter().map(|p| &p.name) {
            if !ident(n) || !outs.insert(n.clone()) {
                return Err(bad_kind(format!("output `{}` is not a unique lowercase name", guest_text(n))));
            }
        }
        let port = |p: &v1::Port| {
            let mut s = PortSpec::new(leak(p.name.clone()), v1::port_type(p.ty), leak(guest_text(&p.doc)));
            s.optional = p.optional;
            s
        };
        let mut params = Vec::new();
        for p in &k.params {
            let ty = match &p.ty {
                ParamType::Quantity(u) => FieldType::Quantity(si_dimension(u).map_err(&bad_kind)?),
                ParamType::QuantityList(u) => FieldType::QuantityList(si_dimension(u).map_err(&bad_kind)?),
                ParamType::Integer((min, max)) if min <= max => FieldType::Integer { min: *min, max: *max },
                ParamType::Integer(_) => return Err(bad_kind(format!("parameter `{}`: empty integer range", p.name))),
                ParamType::Boolean => FieldType::Bool,
                ParamType::Text => FieldType::Text,
                ParamType::Choice(words) if !words.is_empty() => FieldType::Choice(Box::leak(
                    words.iter().map(|w| leak(w.clone())).collect::<Vec<_>>().into_boxed_slice(),
                )),
                ParamType::Choice(_) => return Err(bad_kind(format!("parameter `{}`: a choice of no words", p.name))),
                ParamType::Material => FieldType::Entity(EntityKind::Material),
                ParamType::Sensor => FieldType::Entity(EntityKind::Sensor),
            };
            params.push(Field {
                name: leak(p.name.clone()),
                ty,
                required: p.required && p.default.is_none(),
                default: p.default.clone().map(leak),
                doc: leak(guest_text(&p.doc)),
            });
        }
        spindlelab_engine::spec::check_defaults(&params).map_err(&bad_kind)?;
        let spec = NodeSpec {
            kind: leak(kind.clone()),
            version: k.version,
            description: leak(guest_text(&k.description)),
            inputs: k.inputs.iter().map(port).collect(),
            outputs: k.outputs.iter().map(port).collect(),
            params,
        };
        let effect = match effects.iter().position(|e| e.kind == kind) {
            Some(i) => {
                Some(effect_spec(effects.swap_remove(i), &spec).map_err(|m| bad_kind(format!("as an effect: {m}")))?)
            }
            None => None,
        };
        nodes.push(Arc::new(PluginNode { spec, rt: rt.clone(), effect }));
    }
    if let Some(e) = effects.first() {
        return Err(bad(format!(
            "it offers `{}` as an effect, but describes no such node kind (or offers it twice)",
            guest_text(&e.kind)
        )));
    }
    Ok(nodes)
}

/// Checks an effect a plugin offers against its kind: FRF in and out at `frf`, free
/// parameters that are quantity parameters of the kind, bounds that hold the absent value.
fn effect_spec(e: v2::Effect, spec: &NodeSpec) -> Result<EffectSpec, String> {
    let frf =
        |ports: &[PortSpec]| ports.iter().any(|p| p.name == "frf" && p.ty == spindlelab_engine::value::PortType::Frf);
    if !frf(&spec.inputs) || !frf(&spec.outputs) {
        return Err("an effect takes an FRF at input `frf` and gives one at output `frf`".into());
    }
    let required: Vec<&str> = spec.inputs.iter().filter(|p| !p.optional && p.name != "frf").map(|p| p.name).collect();
    if let Some(p) = required.first() {
        return Err(format!("an effect's only required input is `frf`, but `{p}` is required too"));
    }
    let name_ok = !e.name.is_empty()
        && e.name.len() <= 64
        && e.name.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_');
    if !name_ok {
        return Err(format!("name `{}` is not lowercase words joined by `_`", guest_text(&e.name)));
    }
    if e.description.len() > MAX_TEXT {
        return Err(format!("the description is longer than {MAX_TEXT} bytes"));
    }
    if e.params.is_empty() || e.params.len() > 8 {
        return Err(format!("it frees {} parameters; an effect frees 1 to 8", e.params.len()));
    }
    let mut params: Vec<EffectParam> = Vec::new();
    for p in e.params {
        let field = spec
            .params
            .iter()
            .find(|f| f.name == p.name)
            .ok_or_else(|| format!("parameter `{}` is not a parameter of the kind", guest_text(&p.name)))?;
        let FieldType::Quantity(dim) = &field.ty else {
            return Err(format!("parameter `{}` is not a quantity", p.name));
        };
        if params.iter().any(|q| q.name == p.name) {
            return Err(format!("parameter `{}` is freed twice", p.name));
        }
        let finite = p.absent.is_finite() && p.min.is_finite() && p.max.is_finite();
        if !finite || p.min >= p.max || p.absent < p.min || p.absent > p.max {
            return Err(format!(
                "parameter `{}`: bounds [{}, {}] must be finite, increasing and hold the absent value {}",
                p.name, p.min, p.max, p.absent
            ));
        }
        if p.log && p.min <= 0.0 && p.max >= 0.0 {
            return Err(format!("parameter `{}`: a logarithmic search needs bounds of one sign, not zero", p.name));
        }
        params.push(EffectParam {
            name: field.name,
            si_unit: if *dim == Dimension::DIMENSIONLESS { "" } else { leak(dim.si_unit()) },
            absent: p.absent,
            min: p.min,
            max: p.max,
            log: p.log,
        });
    }
    Ok(EffectSpec { name: leak(e.name), description: leak(guest_text(&e.description)), params })
}

/// The dimension of an SI unit symbol a plugin declares (`kg`, `N/m`, `rad/s`; empty: none).
fn si_dimension(unit: &str) -> Result<Dimension, String> {
    if unit.trim().is_empty() {
        return Ok(Dimension::DIMENSIONLESS);
    }
    let u =
        grammar::parse_unit(unit).map_err(|e| format!("unit `{}`: {}", guest_text(unit), guest_text(&e.message)))?;
    if (u.scale - 1.0).abs() > 1e-12 {
        return Err(format!(
            "unit `{unit}` is not SI (1 {unit} = {} {}); plugins receive SI, declare `{}`",
            u.scale,
            u.dim.si_unit(),
            u.dim.si_unit()
        ));
    }
    Ok(u.dim)
}

/// One node kind of a plugin.
pub struct PluginNode {
    spec: NodeSpec,
    rt: Arc<Runtime>,
    effect: Option<EffectSpec>,
}

impl PluginNode {
    /// The plugin that provides it: id, version, SHA-256.
    pub fn plugin(&self) -> (&str, &str, &str) {
        (&self.rt.id, &self.rt.version, &self.rt.sha256)
    }

    fn fail(&self, cause: impl std::fmt::Display) -> NodeError {
        NodeError::Failed(format!("plugin `{}` {}, node `{}`: {cause}", self.rt.id, self.rt.version, self.spec.kind))
    }
}

fn param_value(v: &P, entities: &Entities) -> Option<ParamValue> {
    Some(match v {
        P::Entity { kind: EntityKind::Material, name } => {
            let m = entities.materials.get(name)?;
            ParamValue::Material(v1::Material {
                name: name.clone(),
                youngs_modulus: m.youngs_modulus,
                density: m.density,
                poisson: m.poisson,
                loss_factor: m.loss_factor,
            })
        }
        P::Entity { kind: EntityKind::Sensor, name } => {
            let s = entities.sensors.get(name)?;
            ParamValue::Sensor(v1::Sensor {
                name: name.clone(),
                kind: s.kind.clone(),
                phase_slope: s.phase_slope,
                mass: s.mass,
                location: s.location.clone(),
            })
        }
        P::Quantity { value, .. } => ParamValue::Number(*value),
        P::List { values, .. } => ParamValue::Numbers(values.clone()),
        P::Int(i) => ParamValue::Integer(*i),
        P::Bool(b) => ParamValue::Boolean(*b),
        P::Text(t) => ParamValue::Text(t.clone()),
        _ => return None,
    })
}

/// The parameters as the interface passes them (SI), in the kind's order; a material or
/// sensor by its properties, the only entity data a plugin sees.
fn params_of(spec: &NodeSpec, params: &Params, entities: &Entities) -> Vec<NamedParam> {
    spec.params
        .iter()
        .filter_map(|f| {
            let value = param_value(params.get(f.name)?, entities)?;
            Some(NamedParam { name: f.name.to_string(), value })
        })
        .collect()
}

impl Node for PluginNode {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn effect(&self) -> Option<&EffectSpec> {
        self.effect.as_ref()
    }

    fn code_digest(&self) -> Option<&str> {
        Some(&self.rt.sha256)
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let params = params_of(&self.spec, ctx.params, ctx.entities);
        let mut inputs = Vec::new();
        for port in &self.spec.inputs {
            for l in ctx.inputs_of(port.name) {
                let value = lend::value(&l.value).ok_or_else(|| {
                    NodeError::input(port.name, format!("a {} cannot cross to a plugin", l.value.port_type()))
                })?;
                inputs.push(lend::Input { port: port.name, label: &l.label, value });
            }
        }
        let outcome = self.rt.run(self.spec.kind, &params, &inputs).map_err(|e| self.fail(self.rt.explain(e)))?;
        let total: u64 = outcome.outputs.iter().map(|o| v1::numbers_in(&o.value)).sum();
        if total > self.rt.limits.output_values {
            return Err(self.fail(format!(
                "it returned {total} numbers, beyond its bound of {}; ask for more in its manifest's `limits`",
                self.rt.limits.output_values
            )));
        }
        for w in outcome.warnings.into_iter().take(100) {
            ctx.warn(guest_text(&w));
        }
        let mut out = Outputs::new();
        for o in outcome.outputs {
            let Some(port) = self.spec.output(&o.port) else {
                return Err(self.fail(format!("it returned an output `{}` it does not declare", guest_text(&o.port))));
            };
            let value =
                v1::from_wit(o.value).map_err(|m| self.fail(format!("output `{}`: {}", o.port, guest_text(&m))))?;
            if value.port_type() != port.ty {
                return Err(self.fail(format!(
                    "output `{}` is declared a {} but it returned a {}",
                    o.port,
                    port.ty,
                    value.port_type()
                )));
            }
            if let Some(at) = first_non_finite(&value) {
                return Err(self.fail(format!(
                    "output `{}`: {at}; a plugin's outputs must be finite numbers (fix the plugin, or the input \
                     that leads it there)",
                    o.port
                )));
            }
            if let Some(label) = label_with_control(&value) {
                return Err(self.fail(format!("output `{}`: {label} holds a control character", o.port)));
            }
            if out.insert(o.port.clone(), value).is_some() {
                return Err(self.fail(format!("it returned output `{}` twice", o.port)));
            }
        }
        if let Some(missing) = self.spec.outputs.iter().find(|p| !out.contains_key(p.name)) {
            return Err(self.fail(format!("it returned no `{}`", missing.name)));
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use spindlelab_engine::value::{PortType, UnitLabel};

    fn kind(inputs: &[(&'static str, PortType, bool)]) -> NodeSpec {
        let kg = grammar::parse_unit("kg").unwrap().dim;
        NodeSpec {
            kind: "effect.test",
            version: 1,
            description: "",
            inputs: inputs
                .iter()
                .map(|&(n, t, optional)| {
                    let mut p = PortSpec::new(n, t, "");
                    p.optional = optional;
                    p
                })
                .collect(),
            outputs: vec![PortSpec::new("frf", PortType::Frf, "")],
            params: vec![Field::opt("mass", FieldType::Quantity(kg), ""), Field::opt("label", FieldType::Text, "")],
        }
    }

    fn effect(params: Vec<(&str, f64, f64, f64, bool)>) -> v2::Effect {
        v2::Effect {
            kind: "effect.test".into(),
            name: "test_mass".into(),
            description: "a mass".into(),
            params: params
                .into_iter()
                .map(|(name, absent, min, max, log)| v2::FreeParam { name: name.into(), absent, min, max, log })
                .collect(),
        }
    }

    #[test]
    fn the_first_number_of_an_output_that_is_not_finite_is_named_by_its_place() {
        use num_complex::Complex64;
        use spindlelab_engine::value::{Channel, Column, Frf, Lobes, ModalModel, Mode, Scalar, Table, TimeSeries};
        let at = |v: Value| first_non_finite(&v);
        assert_eq!(at(Value::Scalar(Scalar::new(1.0, "m"))), None);
        assert_eq!(at(Value::Scalar(Scalar::new(f64::NAN, "m"))).as_deref(), Some("the value is NaN"));
        let table = Table {
            columns: vec![Column::new("a", "", vec![1.0, 2.0]), Column::new("b\u{1b}", "", vec![0.0, f64::INFINITY])],
        };
        assert_eq!(at(Value::Table(table)).as_deref(), Some("row 1 of column `b\\x1b` is +inf"));
        let mut frf = Frf {
            freq_hz: vec![0.0, 1.0, 2.0],
            values: vec![Complex64::new(1.0, 0.0); 3],
            coherence: Some(vec![1.0, f64::NAN, 1.0]),
            unit: UnitLabel::new("m/N"),
            direction: None,
            speed: None,
            sensor: None,
            dofs: None,
        };
        frf.values[2].im = f64::NEG_INFINITY;
        assert_eq!(at(Value::Frf(frf.clone())).as_deref(), Some("the coherence at line 1 is NaN"));
        frf.coherence = None;
        assert_eq!(at(Value::Frf(frf.clone())).as_deref(), Some("the imaginary part at line 2 is -inf"));
        frf.values[2].im = 0.0;
        frf.speed = Some(spindlelab_engine::domain::Speed::from_rpm(f64::NAN));
        assert_eq!(at(Value::Frf(frf)).as_deref(), Some("the speed is NaN"));
        let series = TimeSeries {
            sample_rate: 100.0,
            t0: 0.0,
            channels: vec![Channel { name: "ax".into(), unit: UnitLabel::new(""), samples: vec![0.0, f64::NAN] }],
        };
        assert_eq!(at(Value::TimeSeries(series)).as_deref(), Some("sample 1 of channel `ax` is NaN"));
        let modes = ModalModel { modes: vec![Mode { freq_hz: 100.0, damping_ratio: f64::NAN, modal_mass: 1.0 }] };
        assert_eq!(at(Value::ModalModel(modes)).as_deref(), Some("the damping ratio of mode 0 is NaN"));
        // `+inf` is a lobe diagram's "no limit"; its chatter frequency there means nothing.
        let lobes = |depth: f64, chatter: f64| {
            Value::Lobes(Lobes::from_rpm(&[1000.0, 2000.0], vec![1e-3, depth], vec![500.0, chatter]))
        };
        assert_eq!(at(lobes(f64::INFINITY, f64::NAN)), None);
        assert_eq!(at(lobes(f64::NAN, 500.0)).as_deref(), Some("the depth limit at point 1 is NaN"));
        assert_eq!(
            at(lobes(2e-3, f64::INFINITY)).as_deref(),
            Some("the chatter frequency at point 1 (a finite limit) is +inf")
        );
    }

    #[test]
    fn a_plugin_s_words_reach_messages_escaped_and_bounded() {
        assert_eq!(guest_text("plain"), "plain");
        assert_eq!(guest_text("\u{1b}[2Kok\nerror: x"), "\\x1b[2Kok\\nerror: x");
        assert_eq!(guest_text(&"é".repeat(MAX_TEXT + 10)).chars().count(), MAX_TEXT + 1);
        let series = Value::Scalar(spindlelab_engine::value::Scalar::new(1.0, "m\n"));
        assert_eq!(label_with_control(&series).as_deref(), Some("the unit m\\n"));
    }

    #[test]
    fn an_effect_declaration_is_checked_against_its_kind() {
        let frf_in = kind(&[("frf", PortType::Frf, false)]);
        let ok = effect_spec(effect(vec![("mass", 0.0, -0.05, 0.1, false)]), &frf_in).unwrap();
        assert_eq!((ok.name, ok.params[0].name, ok.params[0].si_unit), ("test_mass", "mass", "kg"));
        let refused = |e: v2::Effect, spec: &NodeSpec, says: &str| {
            let m = effect_spec(e, spec).unwrap_err();
            assert!(m.contains(says), "`{m}` should say `{says}`");
        };
        refused(effect(vec![("mass", 0.0, -0.05, 0.1, false)]), &kind(&[("x", PortType::Frf, false)]), "input `frf`");
        refused(
            effect(vec![("mass", 0.0, -0.05, 0.1, false)]),
            &kind(&[("frf", PortType::Frf, false), ("other", PortType::Scalar, false)]),
            "`other` is required",
        );
        refused(effect(vec![("stiffness", 0.0, 0.0, 1.0, false)]), &frf_in, "not a parameter of the kind");
        refused(effect(vec![("label", 0.0, 0.0, 1.0, false)]), &frf_in, "not a quantity");
        refused(effect(vec![("mass", 0.2, -0.05, 0.1, false)]), &frf_in, "hold the absent value");
        refused(effect(vec![("mass", 0.0, f64::NEG_INFINITY, 0.1, false)]), &frf_in, "finite");
        refused(effect(vec![("mass", 0.0, -0.05, 0.1, true)]), &frf_in, "logarithmic");
        refused(effect(vec![("mass", 0.0, -0.05, 0.1, false), ("mass", 0.0, -0.05, 0.1, false)]), &frf_in, "twice");
        refused(effect(vec![]), &frf_in, "frees 0 parameters");
        let mut bad_name = effect(vec![("mass", 0.0, -0.05, 0.1, false)]);
        bad_name.name = "Tip Mass".into();
        refused(bad_name, &frf_in, "lowercase words");
    }
}
