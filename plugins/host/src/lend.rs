//! A call's inputs lent to the plugin: the interface's `input` and `value` over the engine's
//! own arrays and strings. Lowering copies them into the plugin's memory once; the owned
//! types of the bindings would need a copy of each array first (512 KiB for a record of
//! 65,536 samples). Wasmtime checks these types against the component's own when a call
//! looks up `run` (both interface versions share them).

use crate::v0_1_0::spindlelab::plugin::types::Mode;
use spindlelab_engine::value as ev;
use wasmtime::component::{ComponentType, Lower};

#[derive(ComponentType, Lower)]
#[component(record)]
pub struct Channel<'a> {
    name: &'a str,
    unit: &'a str,
    samples: &'a [f64],
}

#[derive(ComponentType, Lower)]
#[component(record)]
pub struct TimeSeries<'a> {
    #[component(name = "sample-rate")]
    sample_rate: f64,
    t0: f64,
    channels: Vec<Channel<'a>>,
}

#[derive(ComponentType, Lower)]
#[component(record)]
pub struct Frf<'a> {
    #[component(name = "freq-hz")]
    freq_hz: &'a [f64],
    re: Vec<f64>,
    im: Vec<f64>,
    coherence: Option<&'a [f64]>,
    unit: &'a str,
    direction: Option<&'a str>,
    #[component(name = "speed-rpm")]
    speed_rpm: Option<f64>,
    sensor: Option<&'a str>,
}

#[derive(ComponentType, Lower)]
#[component(record)]
pub struct ModalModel {
    modes: Vec<Mode>,
}

#[derive(ComponentType, Lower)]
#[component(record)]
pub struct Lobes<'a> {
    #[component(name = "speed-rpm")]
    speed_rpm: Vec<f64>,
    #[component(name = "depth-limit")]
    depth_limit: &'a [f64],
    #[component(name = "chatter-hz")]
    chatter_hz: &'a [f64],
}

#[derive(ComponentType, Lower)]
#[component(record)]
pub struct Column<'a> {
    name: &'a str,
    unit: &'a str,
    values: &'a [f64],
}

#[derive(ComponentType, Lower)]
#[component(record)]
pub struct Table<'a> {
    columns: Vec<Column<'a>>,
}

#[derive(ComponentType, Lower)]
#[component(record)]
pub struct Scalar<'a> {
    value: f64,
    unit: &'a str,
}

#[derive(ComponentType, Lower)]
#[component(variant)]
pub enum Value<'a> {
    #[component(name = "time-series")]
    TimeSeries(TimeSeries<'a>),
    #[component(name = "frf")]
    Frf(Frf<'a>),
    #[component(name = "modal-model")]
    ModalModel(ModalModel),
    #[component(name = "lobes")]
    Lobes(Lobes<'a>),
    #[component(name = "table")]
    Table(Table<'a>),
    #[component(name = "scalar")]
    Scalar(Scalar<'a>),
}

#[derive(ComponentType, Lower)]
#[component(record)]
pub struct Input<'a> {
    pub port: &'a str,
    pub label: &'a str,
    pub value: Value<'a>,
}

/// The engine's value as the interface carries it; `None` for types the interface has not.
pub fn value(v: &ev::Value) -> Option<Value<'_>> {
    Some(match v {
        ev::Value::TimeSeries(t) => Value::TimeSeries(TimeSeries {
            sample_rate: t.sample_rate,
            t0: t.t0,
            channels: t
                .channels
                .iter()
                .map(|c| Channel { name: &c.name, unit: &c.unit.symbol, samples: &c.samples })
                .collect(),
        }),
        ev::Value::Frf(f) => Value::Frf(Frf {
            freq_hz: &f.freq_hz,
            re: f.values.iter().map(|c| c.re).collect(),
            im: f.values.iter().map(|c| c.im).collect(),
            coherence: f.coherence.as_deref(),
            unit: &f.unit.symbol,
            direction: f.direction.as_deref(),
            speed_rpm: f.speed.map(|s| s.rpm_as_written()),
            sensor: f.sensor.as_deref(),
        }),
        ev::Value::ModalModel(m) => Value::ModalModel(ModalModel {
            modes: m
                .modes
                .iter()
                .map(|m| Mode { freq_hz: m.freq_hz, damping_ratio: m.damping_ratio, modal_mass: m.modal_mass })
                .collect(),
        }),
        ev::Value::Lobes(l) => {
            Value::Lobes(Lobes { speed_rpm: l.speeds_rpm(), depth_limit: &l.depth_limit, chatter_hz: &l.chatter_hz })
        }
        ev::Value::Table(t) => Value::Table(Table {
            columns: t
                .columns
                .iter()
                .map(|c| Column { name: &c.name, unit: &c.unit.symbol, values: &c.values })
                .collect(),
        }),
        ev::Value::Scalar(s) => Value::Scalar(Scalar { value: s.value, unit: &s.unit.symbol }),
        ev::Value::ReceptanceSet(_) | ev::Value::BeamModel(_) | ev::Value::Substructure(_) | ev::Value::FrfSet(_) => {
            return None;
        }
    })
}
