//! Write spindlelab node kinds as plain Rust functions over typed values; [`plugin!`]
//! turns them into a WebAssembly component with the `spindlelab:plugin@0.2.0` interface
//! (feature `interface-0-1-0`: the older 0.1.0, which has no effects).
//!
//! ```ignore
//! use spindlelab_plugin_sdk::*;
//!
//! fn double(call: &Call) -> Result<Outputs, String> {
//!     let x = call.scalar("x")?;
//!     Ok(Outputs::new().scalar("y", x.value * call.number("gain")?, &x.unit))
//! }
//!
//! plugin! {
//!     NodeKind::new("demo.double", "Multiplies a scalar by a gain.", double)
//!         .input(Port::new("x", PortType::Scalar, "the number"))
//!         .output(Port::new("y", PortType::Scalar, "gain × x"))
//!         .param(Param::quantity("gain", "", "the factor").default("2")),
//! }
//! ```
//!
//! A plugin is a pure function of its parameters and inputs: every call runs in a fresh
//! instance with no files, network, clock or environment; quantities arrive in SI.

/// The plugin's heap: dlmalloc, as the standard library's, in a version that takes the free
/// tail of the initial linear memory (`__heap_base` to `__heap_end`) before it grows the
/// memory. A plugin linked with room to spare (the template's `--initial-memory`, 8 MiB)
/// then serves most calls without `memory.grow`, and the host need not change the page
/// protection of its memory slot on each call: the no-op call costs half as much.
#[cfg(all(feature = "allocator", target_arch = "wasm32", not(target_feature = "atomics")))]
mod heap {
    use core::alloc::{GlobalAlloc, Layout};
    use core::ptr::addr_of_mut;

    /// One heap: a plugin instance runs on one thread.
    static mut HEAP: dlmalloc::Dlmalloc = dlmalloc::Dlmalloc::new();

    /// dlmalloc's natural alignment on wasm32 (two words).
    const NATURAL: usize = 2 * core::mem::size_of::<usize>();

    pub struct Heap;

    // SAFETY: each method hands its layout to dlmalloc as its contract asks; wasm32 without
    // the atomics feature (this module's condition) has one thread, so the heap is never used
    // concurrently.
    unsafe impl GlobalAlloc for Heap {
        unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
            unsafe { (*addr_of_mut!(HEAP)).malloc(layout.size(), layout.align()) }
        }

        unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
            unsafe { (*addr_of_mut!(HEAP)).calloc(layout.size(), layout.align()) }
        }

        unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
            unsafe { (*addr_of_mut!(HEAP)).free(ptr, layout.size(), layout.align()) }
        }

        /// Shrinks an over-aligned block in place (dlmalloc splits the chunk and the address,
        /// so its alignment, stays); dlmalloc's own `realloc` copies it to a new block. A
        /// boxed slice of SIMD vectors made from a longer vector is one (rustfft's twiddles).
        unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
            let heap = unsafe { &mut *addr_of_mut!(HEAP) };
            if layout.align() > NATURAL && new_size <= layout.size() {
                let shrunk = unsafe { heap.c_realloc(ptr, new_size) };
                if (shrunk as usize).is_multiple_of(layout.align()) {
                    return shrunk;
                }
                // Moved off its alignment (dlmalloc does not, when shrinking): realign.
                let aligned = unsafe { heap.malloc(new_size, layout.align()) };
                if !aligned.is_null() {
                    unsafe {
                        core::ptr::copy_nonoverlapping(shrunk, aligned, new_size);
                        heap.c_free(shrunk);
                    }
                }
                return aligned;
            }
            unsafe { heap.realloc(ptr, layout.size(), layout.align(), new_size) }
        }
    }

    #[global_allocator]
    static ALLOCATOR: Heap = Heap;
}

#[cfg(feature = "paired-trig")]
pub mod trig;

/// The plugin's `sin` and `cos`, in place of the standard library's: the same libm values,
/// with one argument reduction for the cosine and sine of an angle taken one after the
/// other ([`trig::Pair`]). The twiddle factors of an FFT plan are taken so: a 65,536-sample
/// real transform takes about 49,000 pairs, and the example spectrum's call is about 5 %
/// faster. They are exported from the core module, as a symbol that replaces the standard
/// library's must be; the component does not export them.
#[cfg(all(feature = "paired-trig", target_arch = "wasm32", not(target_feature = "atomics")))]
mod trig_symbols {
    use core::ptr::addr_of_mut;

    static mut PAIR: crate::trig::Pair = crate::trig::Pair::new();

    // SAFETY (both): wasm32 without the atomics feature (this module's condition) has one
    // thread, and nothing else names PAIR, so no two references to it are ever alive.
    #[unsafe(no_mangle)]
    extern "C" fn sin(x: f64) -> f64 {
        unsafe { (*addr_of_mut!(PAIR)).sin(x) }
    }

    #[unsafe(no_mangle)]
    extern "C" fn cos(x: f64) -> f64 {
        unsafe { (*addr_of_mut!(PAIR)).cos(x) }
    }
}

#[cfg(not(feature = "interface-0-1-0"))]
#[doc(hidden)]
pub mod bindings {
    wit_bindgen::generate!({
        path: "../../wit/since_v0.2.0",
        world: "plugin",
        pub_export_macro: true,
        export_macro_name: "export_plugin",
        default_bindings_module: "spindlelab_plugin_sdk::bindings",
    });
}

#[cfg(feature = "interface-0-1-0")]
#[doc(hidden)]
pub mod bindings {
    wit_bindgen::generate!({
        path: "../../wit/since_v0.1.0",
        world: "plugin",
        pub_export_macro: true,
        export_macro_name: "export_plugin",
        default_bindings_module: "spindlelab_plugin_sdk::bindings",
    });
}

use bindings::spindlelab::plugin::types as wit;
pub use wit::{
    Channel, Column, Frf, Lobes, Material, ModalModel, Mode, PortType, Scalar, Sensor, Table, TimeSeries, Value,
};

/// The interface version this SDK builds against.
#[cfg(not(feature = "interface-0-1-0"))]
pub const INTERFACE_VERSION: &str = "0.2.0";
#[cfg(feature = "interface-0-1-0")]
pub const INTERFACE_VERSION: &str = "0.1.0";

/// A node kind offered as a physical effect the diagnosis may add to a model that disagrees
/// with its measurements (interface 0.2.0 and later). The kind takes the model's FRF at
/// input `frf` and gives the changed FRF at output `frf`; the diagnosis fits the freed
/// quantity parameters within their bounds, in SI.
#[cfg_attr(feature = "interface-0-1-0", allow(dead_code))]
pub struct Effect {
    name: String,
    description: String,
    params: Vec<(String, f64, f64, f64, bool)>,
}

impl Effect {
    /// An effect reported as `name` (lowercase words joined by `_`, e.g. `tip_mass`).
    pub fn new(name: &str, description: &str) -> Effect {
        Effect { name: name.into(), description: description.into(), params: Vec::new() }
    }
    /// Frees quantity parameter `name`: absent at `absent` (where the fit starts), bounded
    /// by `min` and `max` (SI).
    pub fn free(mut self, name: &str, absent: f64, min: f64, max: f64) -> Effect {
        self.params.push((name.into(), absent, min, max, false));
        self
    }
    /// As [`Effect::free`], searched on a logarithmic scale (bounds of one sign).
    pub fn free_log(mut self, name: &str, absent: f64, min: f64, max: f64) -> Effect {
        self.params.push((name.into(), absent, min, max, true));
        self
    }
}

/// A port of a node kind.
pub struct Port(wit::Port);

impl Port {
    pub fn new(name: &str, ty: PortType, doc: &str) -> Port {
        Port(wit::Port { name: name.into(), ty, doc: doc.into(), optional: false })
    }
    /// An input the recipe may leave unconnected.
    pub fn optional(mut self) -> Port {
        self.0.optional = true;
        self
    }
}

/// A parameter of a node kind.
pub struct Param(wit::Param);

impl Param {
    fn new(name: &str, ty: wit::ParamType, doc: &str) -> Param {
        Param(wit::Param { name: name.into(), ty, required: true, default: None, doc: doc.into() })
    }
    /// A number of the dimension of `si_unit` (`"kg"`, `"N/m"`, `"rad/s"`; `""` for a plain
    /// number). The recipe writes any unit of that dimension; the node receives SI.
    pub fn quantity(name: &str, si_unit: &str, doc: &str) -> Param {
        Param::new(name, wit::ParamType::Quantity(si_unit.into()), doc)
    }
    /// A list or range of numbers of the dimension of `si_unit`.
    pub fn quantity_list(name: &str, si_unit: &str, doc: &str) -> Param {
        Param::new(name, wit::ParamType::QuantityList(si_unit.into()), doc)
    }
    pub fn integer(name: &str, min: i64, max: i64, doc: &str) -> Param {
        Param::new(name, wit::ParamType::Integer((min, max)), doc)
    }
    pub fn boolean(name: &str, doc: &str) -> Param {
        Param::new(name, wit::ParamType::Boolean, doc)
    }
    pub fn text(name: &str, doc: &str) -> Param {
        Param::new(name, wit::ParamType::Text, doc)
    }
    pub fn choice(name: &str, words: &[&str], doc: &str) -> Param {
        Param::new(name, wit::ParamType::Choice(words.iter().map(|w| w.to_string()).collect()), doc)
    }
    /// The name of a material of the recipe (`materials:`); the node receives its properties.
    pub fn material(name: &str, doc: &str) -> Param {
        Param::new(name, wit::ParamType::Material, doc)
    }
    /// The name of a sensor of the recipe (`sensors:`); the node receives its properties.
    pub fn sensor(name: &str, doc: &str) -> Param {
        Param::new(name, wit::ParamType::Sensor, doc)
    }
    /// The value used when the recipe gives none, written as a recipe would (`"0.5 g"`).
    pub fn default(mut self, text: &str) -> Param {
        self.0.default = Some(text.into());
        self.0.required = false;
        self
    }
    /// A parameter the recipe may leave out (the node sees none).
    pub fn optional(mut self) -> Param {
        self.0.required = false;
        self
    }
}

/// The code of a node kind: a plain function of the call.
pub type RunFn = fn(&Call) -> Result<Outputs, String>;

/// A node kind the plugin provides: its description. [`plugin!`] sends each call of the
/// kind to the function named in [`NodeKind::new`].
pub struct NodeKind {
    kind: wit::NodeKind,
    effect: Option<Effect>,
}

impl NodeKind {
    /// A kind named `kind` (dotted, e.g. `chatter.indicator`), version 1, run by `run`.
    pub fn new(kind: &str, description: &str, run: RunFn) -> NodeKind {
        let _ = run;
        NodeKind {
            kind: wit::NodeKind {
                kind: kind.into(),
                version: 1,
                description: description.into(),
                inputs: Vec::new(),
                outputs: Vec::new(),
                params: Vec::new(),
            },
            effect: None,
        }
    }
    /// Offers the kind as a physical effect for the diagnosis (see [`Effect`]).
    pub fn effect(mut self, effect: Effect) -> NodeKind {
        self.effect = Some(effect);
        self
    }
    /// Bump whenever the node's numbers change for the same inputs (it is part of the cache key).
    pub fn version(mut self, version: u32) -> NodeKind {
        self.kind.version = version;
        self
    }
    pub fn input(mut self, port: Port) -> NodeKind {
        self.kind.inputs.push(port.0);
        self
    }
    pub fn output(mut self, port: Port) -> NodeKind {
        self.kind.outputs.push(port.0);
        self
    }
    pub fn param(mut self, param: Param) -> NodeKind {
        self.kind.params.push(param.0);
        self
    }
}

/// What one run of a node sees: its parameters (SI) and its input values.
pub struct Call {
    params: Vec<wit::NamedParam>,
    inputs: Vec<wit::Input>,
    warnings: std::cell::RefCell<Vec<String>>,
}

impl Call {
    fn param(&self, name: &str) -> Option<&wit::ParamValue> {
        self.params.iter().find(|p| p.name == name).map(|p| &p.value)
    }
    fn missing(name: &str) -> String {
        format!("parameter `{name}` is missing")
    }
    /// A quantity parameter, in SI.
    pub fn number(&self, name: &str) -> Result<f64, String> {
        match self.param(name) {
            Some(wit::ParamValue::Number(v)) => Ok(*v),
            Some(_) => Err(format!("parameter `{name}` is not a number")),
            None => Err(Self::missing(name)),
        }
    }
    /// A quantity parameter the recipe may leave out.
    pub fn number_opt(&self, name: &str) -> Option<f64> {
        self.number(name).ok()
    }
    /// A list parameter, in SI.
    pub fn numbers(&self, name: &str) -> Result<&[f64], String> {
        match self.param(name) {
            Some(wit::ParamValue::Numbers(v)) => Ok(v),
            Some(_) => Err(format!("parameter `{name}` is not a list")),
            None => Err(Self::missing(name)),
        }
    }
    pub fn integer(&self, name: &str) -> Result<i64, String> {
        match self.param(name) {
            Some(wit::ParamValue::Integer(v)) => Ok(*v),
            Some(_) => Err(format!("parameter `{name}` is not an integer")),
            None => Err(Self::missing(name)),
        }
    }
    pub fn boolean(&self, name: &str) -> Result<bool, String> {
        match self.param(name) {
            Some(wit::ParamValue::Boolean(v)) => Ok(*v),
            Some(_) => Err(format!("parameter `{name}` is not true/false")),
            None => Err(Self::missing(name)),
        }
    }
    /// A text or choice parameter.
    pub fn text(&self, name: &str) -> Result<&str, String> {
        match self.param(name) {
            Some(wit::ParamValue::Text(v)) => Ok(v),
            Some(_) => Err(format!("parameter `{name}` is not text")),
            None => Err(Self::missing(name)),
        }
    }
    pub fn text_opt(&self, name: &str) -> Option<&str> {
        self.text(name).ok()
    }
    /// A material parameter's properties.
    pub fn material(&self, name: &str) -> Result<&Material, String> {
        match self.param(name) {
            Some(wit::ParamValue::Material(m)) => Ok(m),
            Some(_) => Err(format!("parameter `{name}` is not a material")),
            None => Err(Self::missing(name)),
        }
    }
    /// A sensor parameter's properties, when the recipe gave one.
    pub fn sensor(&self, name: &str) -> Option<&Sensor> {
        match self.param(name) {
            Some(wit::ParamValue::Sensor(s)) => Some(s),
            _ => None,
        }
    }

    /// Every value at an input port with its sweep label, in sweep order.
    pub fn inputs(&self, port: &str) -> impl Iterator<Item = (&str, &Value)> {
        self.inputs.iter().filter(move |i| i.port == port).map(|i| (i.label.as_str(), &i.value))
    }
    /// The value at an input port.
    pub fn value(&self, port: &str) -> Result<&Value, String> {
        self.inputs(port).next().map(|(_, v)| v).ok_or_else(|| format!("input `{port}` is missing"))
    }
    pub fn time_series(&self, port: &str) -> Result<&TimeSeries, String> {
        match self.value(port)? {
            Value::TimeSeries(v) => Ok(v),
            _ => Err(format!("input `{port}` is not a time series")),
        }
    }
    pub fn frf(&self, port: &str) -> Result<&Frf, String> {
        match self.value(port)? {
            Value::Frf(v) => Ok(v),
            _ => Err(format!("input `{port}` is not an FRF")),
        }
    }
    pub fn modal_model(&self, port: &str) -> Result<&ModalModel, String> {
        match self.value(port)? {
            Value::ModalModel(v) => Ok(v),
            _ => Err(format!("input `{port}` is not a modal model")),
        }
    }
    pub fn lobes(&self, port: &str) -> Result<&Lobes, String> {
        match self.value(port)? {
            Value::Lobes(v) => Ok(v),
            _ => Err(format!("input `{port}` is not a lobe diagram")),
        }
    }
    pub fn table(&self, port: &str) -> Result<&Table, String> {
        match self.value(port)? {
            Value::Table(v) => Ok(v),
            _ => Err(format!("input `{port}` is not a table")),
        }
    }
    pub fn scalar(&self, port: &str) -> Result<&Scalar, String> {
        match self.value(port)? {
            Value::Scalar(v) => Ok(v),
            _ => Err(format!("input `{port}` is not a scalar")),
        }
    }

    /// A warning that does not stop the node; the run shows it with the results.
    pub fn warn(&self, message: impl Into<String>) {
        self.warnings.borrow_mut().push(message.into());
    }
}

/// The values a run produces, by output port.
#[derive(Default)]
pub struct Outputs(Vec<wit::Output>);

impl Outputs {
    pub fn new() -> Outputs {
        Outputs::default()
    }
    pub fn value(mut self, port: &str, value: Value) -> Outputs {
        self.0.push(wit::Output { port: port.into(), value });
        self
    }
    pub fn scalar(self, port: &str, value: f64, si_unit: &str) -> Outputs {
        self.value(port, Value::Scalar(Scalar { value, unit: si_unit.into() }))
    }
    pub fn frf(self, port: &str, frf: Frf) -> Outputs {
        self.value(port, Value::Frf(frf))
    }
    pub fn table(self, port: &str, columns: Vec<Column>) -> Outputs {
        self.value(port, Value::Table(Table { columns }))
    }
    pub fn time_series(self, port: &str, series: TimeSeries) -> Outputs {
        self.value(port, Value::TimeSeries(series))
    }
    pub fn modal_model(self, port: &str, modes: Vec<Mode>) -> Outputs {
        self.value(port, Value::ModalModel(ModalModel { modes }))
    }
}

/// A column of a table: name, SI unit symbol, values.
pub fn column(name: &str, si_unit: &str, values: Vec<f64>) -> Column {
    Column { name: name.into(), unit: si_unit.into(), values }
}

#[doc(hidden)]
pub fn describe(name: &str, version: &str, kinds: &[NodeKind]) -> wit::PluginInfo {
    wit::PluginInfo {
        name: name.into(),
        version: version.into(),
        nodes: kinds.iter().map(|k| k.kind.clone()).collect(),
    }
}

#[doc(hidden)]
#[cfg(not(feature = "interface-0-1-0"))]
pub fn effects(kinds: &[NodeKind]) -> Vec<bindings::exports::spindlelab::plugin::effects::Effect> {
    use bindings::exports::spindlelab::plugin::effects as e;
    kinds
        .iter()
        .filter_map(|k| {
            let effect = k.effect.as_ref()?;
            Some(e::Effect {
                kind: k.kind.kind.clone(),
                name: effect.name.clone(),
                description: effect.description.clone(),
                params: effect
                    .params
                    .iter()
                    .map(|(name, absent, min, max, log)| e::FreeParam {
                        name: name.clone(),
                        absent: *absent,
                        min: *min,
                        max: *max,
                        log: *log,
                    })
                    .collect(),
            })
        })
        .collect()
}

/// Exports the kinds' effects (interface 0.2.0).
#[doc(hidden)]
#[cfg(not(feature = "interface-0-1-0"))]
#[macro_export]
macro_rules! __spindlelab_effects {
    ($plugin:ident, $kinds:ident) => {
        impl $crate::bindings::exports::spindlelab::plugin::effects::Guest for $plugin {
            fn effects() -> ::std::vec::Vec<$crate::bindings::exports::spindlelab::plugin::effects::Effect> {
                $crate::effects(&$kinds())
            }
        }
    };
}

/// Interface 0.1.0 has no effects.
#[doc(hidden)]
#[cfg(feature = "interface-0-1-0")]
#[macro_export]
macro_rules! __spindlelab_effects {
    ($plugin:ident, $kinds:ident) => {};
}

#[doc(hidden)]
pub fn run(run: RunFn, params: Vec<wit::NamedParam>, inputs: Vec<wit::Input>) -> Result<wit::Outcome, String> {
    let call = Call { params, inputs, warnings: Default::default() };
    let outputs = run(&call)?;
    Ok(wit::Outcome { outputs: outputs.0, warnings: call.warnings.into_inner() })
}

/// Declares the plugin's node kinds and exports them: a list of
/// `NodeKind::new("kind.name", "description", function)` with its ports and parameters.
/// The plugin's name and version are the crate's (`Cargo.toml`); the manifest written by
/// `spindlelab plugin build` repeats them. A call goes straight to its kind's function
/// (the descriptions are built only when the host asks for them).
#[macro_export]
macro_rules! plugin {
    ($(NodeKind::new($kind:literal, $desc:expr, $run:expr $(,)?) $(. $method:ident ( $($arg:tt)* ))* ),+ $(,)?) => {
        fn __spindlelab_kinds() -> ::std::vec::Vec<$crate::NodeKind> {
            ::std::vec![$($crate::NodeKind::new($kind, $desc, $run) $(. $method ( $($arg)* ))* ),+]
        }
        struct __SpindlelabPlugin;
        impl $crate::bindings::exports::spindlelab::plugin::node::Guest for __SpindlelabPlugin {
            fn describe() -> $crate::bindings::spindlelab::plugin::types::PluginInfo {
                $crate::describe(env!("CARGO_PKG_NAME"), env!("CARGO_PKG_VERSION"), &__spindlelab_kinds())
            }
            fn run(
                kind: ::std::string::String,
                params: ::std::vec::Vec<$crate::bindings::spindlelab::plugin::types::NamedParam>,
                inputs: ::std::vec::Vec<$crate::bindings::spindlelab::plugin::types::Input>,
            ) -> ::std::result::Result<$crate::bindings::spindlelab::plugin::types::Outcome, ::std::string::String> {
                let run: $crate::RunFn = match kind.as_str() {
                    $($kind => $run,)+
                    _ => return ::std::result::Result::Err(::std::format!("this plugin has no node kind `{kind}`")),
                };
                $crate::run(run, params, inputs)
            }
        }
        $crate::__spindlelab_effects!(__SpindlelabPlugin, __spindlelab_kinds);
        $crate::bindings::export_plugin!(__SpindlelabPlugin with_types_in $crate::bindings);
    };
}
