//! The node trait and the registry of node kinds.
//!
//! A node kind is registered once with its ports, parameters (with units and defaults),
//! version and a one-line description. The compiler, `spindlelab nodes`, the JSON Schema
//! and the docs all read that one registration. Built-in nodes (the `stdlib` crate) and
//! WebAssembly plugins implement the same [`Node`] trait.
//!
//! Contract: a node is a pure function of its parameters and inputs. It must not read
//! files other than those its parameters name, keep state between runs, or depend on the
//! thread it runs on; random parts take a seed parameter. The cache relies on this: the
//! same kind, version, parameters and inputs give the same outputs.

use crate::spec::{Field, Params};
use crate::value::{PortType, Value};
use indexmap::IndexMap;
use spindlelab_domain::entity::Entities;
use std::sync::{Arc, Mutex};

/// A named, typed port of a node.
#[derive(Debug, Clone, Copy)]
pub struct PortSpec {
    pub name: &'static str,
    pub ty: PortType,
    /// Takes every value of a swept upstream step at once, instead of running once per value.
    pub collect: bool,
    pub optional: bool,
    pub doc: &'static str,
}

impl PortSpec {
    pub const fn new(name: &'static str, ty: PortType, doc: &'static str) -> Self {
        PortSpec { name, ty, collect: false, optional: false, doc }
    }
    pub const fn optional(mut self) -> Self {
        self.optional = true;
        self
    }
    pub const fn collecting(mut self) -> Self {
        self.collect = true;
        self
    }
}

/// Everything the engine knows about a node kind before running it.
#[derive(Debug, Clone)]
pub struct NodeSpec {
    /// Dotted kind name used in recipes, e.g. `impact.simulate`.
    pub kind: &'static str,
    /// Bumped whenever the node's numbers change for the same inputs; part of the cache key.
    pub version: u32,
    pub description: &'static str,
    pub inputs: Vec<PortSpec>,
    pub outputs: Vec<PortSpec>,
    pub params: Vec<Field>,
}

impl NodeSpec {
    pub fn input(&self, name: &str) -> Option<&PortSpec> {
        self.inputs.iter().find(|p| p.name == name)
    }
    pub fn output(&self, name: &str) -> Option<&PortSpec> {
        self.outputs.iter().find(|p| p.name == name)
    }
    pub fn param(&self, name: &str) -> Option<&Field> {
        self.params.iter().find(|p| p.name == name)
    }
}

/// One numeric sweep coordinate: parameter name, SI value and SI unit symbol.
#[derive(Debug, Clone, PartialEq)]
pub struct Coord {
    pub name: String,
    pub value: f64,
    pub unit: String,
}

/// One value arriving at an input port, with the sweep label of the instance that made it.
#[derive(Debug, Clone)]
pub struct Labelled {
    /// e.g. `hammer_mass=0.03 kg`; empty when the producer was not swept.
    pub label: String,
    /// The numeric sweep assignments behind the label, in SI.
    pub coords: Vec<Coord>,
    pub value: Arc<Value>,
}

/// What a node sees when it runs.
pub struct NodeContext<'a> {
    /// Instance name, e.g. `hit[hammer_mass=0.03 kg]`, for messages.
    pub instance: &'a str,
    pub params: &'a Params,
    /// Values per input port: one for an ordinary port, all of them for a collecting port.
    pub inputs: &'a IndexMap<String, Vec<Labelled>>,
    /// The entities the step's parameters name, resolved and typed by the compiler.
    pub entities: &'a Entities,
    /// Warnings raised while running (see [`NodeContext::warn`]).
    pub warnings: Mutex<Vec<String>>,
}

impl<'a> NodeContext<'a> {
    pub fn new(
        instance: &'a str,
        params: &'a Params,
        inputs: &'a IndexMap<String, Vec<Labelled>>,
        entities: &'a Entities,
    ) -> Self {
        NodeContext { instance, params, inputs, entities, warnings: Mutex::new(Vec::new()) }
    }

    /// Records a warning that does not stop the node, such as a rejected record: the run
    /// summary and the manifest show it, and a cached result replays it.
    pub fn warn(&self, message: impl Into<String>) {
        self.warnings.lock().unwrap_or_else(|e| e.into_inner()).push(message.into());
    }

    /// The warnings raised so far.
    pub fn take_warnings(&self) -> Vec<String> {
        std::mem::take(&mut *self.warnings.lock().unwrap_or_else(|e| e.into_inner()))
    }

    /// The single value at an ordinary input port.
    pub fn input(&self, port: &str) -> Result<&Value, NodeError> {
        self.inputs
            .get(port)
            .and_then(|v| v.first())
            .map(|l| l.value.as_ref())
            .ok_or_else(|| NodeError::MissingInput { port: port.to_string() })
    }
    /// Every value at a collecting input port.
    pub fn inputs_of(&self, port: &str) -> &[Labelled] {
        self.inputs.get(port).map(Vec::as_slice).unwrap_or(&[])
    }
    /// A required SI parameter (the compiler has checked presence and dimension).
    pub fn f64(&self, name: &str) -> Result<f64, NodeError> {
        self.params
            .f64(name)
            .ok_or_else(|| NodeError::InvalidParam { param: name.to_string(), message: "missing".into() })
    }
}

/// Values produced by one run of a node, by output port name.
pub type Outputs = IndexMap<String, Value>;

/// Why a node could not produce its outputs. The executor adds the node instance.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NodeError {
    #[error("input `{port}` is missing")]
    MissingInput { port: String },
    #[error("input `{port}`: {message}")]
    InvalidInput { port: String, message: String },
    #[error("parameter `{param}`: {message}")]
    InvalidParam { param: String, message: String },
    #[error("{0}")]
    Failed(String),
}

impl NodeError {
    pub fn param(param: &str, message: impl Into<String>) -> Self {
        NodeError::InvalidParam { param: param.to_string(), message: message.into() }
    }
    pub fn input(port: &str, message: impl Into<String>) -> Self {
        NodeError::InvalidInput { port: port.to_string(), message: message.into() }
    }
}

/// A kind of node: its spec and the code that runs it.
pub trait Node: Send + Sync {
    fn spec(&self) -> &NodeSpec;

    /// Checks parameters beyond their types (ranges, combinations) at compile time, so a
    /// recipe with impossible values fails before anything runs. Swept values are checked
    /// per instance when the graph is compiled.
    fn validate(&self, _params: &Params) -> Result<(), NodeError> {
        Ok(())
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError>;

    /// Whether outputs go to the cache. Nodes whose outputs are large and cheap to remake
    /// from their parameters (simulated raw records) say no, so the cache stays small.
    fn cacheable(&self) -> bool {
        true
    }

    /// A digest of the code that runs the kind when it is not built into this program (a
    /// plugin's SHA-256): part of the cache key, so a rebuilt plugin reruns its nodes.
    fn code_digest(&self) -> Option<&str> {
        None
    }

    /// The kind offered as a physical effect the diagnosis may add to a model, if it is one
    /// (kinds from plugins; the built-in effects are transforms of the recipe).
    fn effect(&self) -> Option<&EffectSpec> {
        None
    }
}

/// A node kind offered as a physical effect: it takes the model's FRF at input `frf` and gives
/// the changed FRF at output `frf`; the diagnosis fits `params` within their bounds.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectSpec {
    /// The name a diagnosis reports (`tip_mass`).
    pub name: &'static str,
    pub description: &'static str,
    pub params: Vec<EffectParam>,
}

/// A free parameter of an effect: one of the kind's quantity parameters, in SI.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectParam {
    pub name: &'static str,
    /// The SI unit symbol of its dimension (`kg`; empty for a plain number).
    pub si_unit: &'static str,
    /// Where the effect is absent (the fit's start).
    pub absent: f64,
    pub min: f64,
    pub max: f64,
    pub log: bool,
}

/// The parameters through which a `measurements:` set hands one file to its reader kind, by
/// the names the set uses: the file, and what the recipe states about it.
pub const MEASUREMENT_PARAMS: &[&str] = &["file", "format", "direction", "speed", "units"];

/// Every node kind the engine can compile, by kind name.
#[derive(Default, Clone)]
pub struct Registry {
    kinds: IndexMap<&'static str, Arc<dyn Node>>,
    /// The kind that reads one file of a measurement set (see [`Registry::set_measurement_reader`]).
    measurement_reader: Option<&'static str>,
}

impl Registry {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a node kind from outside the program (a plugin); a kind already registered is
    /// refused with the name, so a plugin cannot replace a built-in kind.
    pub fn try_register(&mut self, node: Arc<dyn Node>) -> Result<(), String> {
        let kind = node.spec().kind;
        if self.kinds.contains_key(kind) {
            return Err(format!("node kind `{kind}` is already registered"));
        }
        self.kinds.insert(kind, node);
        Ok(())
    }

    /// Adds a node kind; a second registration of the same kind name is a programming error.
    pub fn register(&mut self, node: Arc<dyn Node>) {
        let kind = node.spec().kind;
        assert!(!self.kinds.contains_key(kind), "node kind `{kind}` registered twice");
        self.kinds.insert(kind, node);
    }

    pub fn get(&self, kind: &str) -> Option<&Arc<dyn Node>> {
        self.kinds.get(kind)
    }

    /// Names the kind that reads one measured file of a `measurements:` set: the engine
    /// expands each set into a step of this kind swept over its files. The kind must be
    /// registered and take every parameter of [`MEASUREMENT_PARAMS`].
    pub fn set_measurement_reader(&mut self, kind: &str) -> Result<(), String> {
        let Some((&name, node)) = self.kinds.get_key_value(kind) else {
            return Err(format!("the measurement reader `{kind}` is not a registered kind"));
        };
        let missing: Vec<&str> =
            MEASUREMENT_PARAMS.iter().copied().filter(|p| node.spec().param(p).is_none()).collect();
        if !missing.is_empty() {
            return Err(format!("the measurement reader `{kind}` takes no parameter {}", missing.join(", ")));
        }
        self.measurement_reader = Some(name);
        Ok(())
    }

    /// The kind that reads one file of a measurement set, when one is registered.
    pub fn measurement_reader(&self) -> Option<&'static str> {
        self.measurement_reader
    }

    pub fn kinds(&self) -> impl Iterator<Item = &Arc<dyn Node>> {
        self.kinds.values()
    }

    pub fn names(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.kinds.keys().copied()
    }
}
