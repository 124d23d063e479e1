//! The host's binding of interface `spindlelab:plugin@0.1.0` (frozen in
//! `plugins/wit/since_v0.1.0`) and the conversions between its values and the engine's.

wasmtime::component::bindgen!({
    path: "../wit/since_v0.1.0",
    world: "plugin",
});

use spindlelab::plugin::types as wit;
use spindlelab_engine::domain::Speed;
use spindlelab_engine::value::{self as ev, PortType, UnitLabel};

pub use wit::{Material, NamedParam, Outcome, ParamType, ParamValue, PluginInfo, Port, Sensor};

pub fn port_type(t: wit::PortType) -> PortType {
    match t {
        wit::PortType::TimeSeries => PortType::TimeSeries,
        wit::PortType::Frf => PortType::Frf,
        wit::PortType::ModalModel => PortType::ModalModel,
        wit::PortType::Lobes => PortType::Lobes,
        wit::PortType::Table => PortType::Table,
        wit::PortType::Scalar => PortType::Scalar,
    }
}

/// How many numbers a value holds (the output bound counts them).
pub fn numbers_in(v: &wit::Value) -> u64 {
    let n = match v {
        wit::Value::TimeSeries(t) => t.channels.iter().map(|c| c.samples.len()).sum(),
        wit::Value::Frf(f) => f.freq_hz.len() + f.re.len() + f.im.len() + f.coherence.as_ref().map_or(0, Vec::len),
        wit::Value::ModalModel(m) => 3 * m.modes.len(),
        wit::Value::Lobes(l) => l.speed_rpm.len() + l.depth_limit.len() + l.chatter_hz.len(),
        wit::Value::Table(t) => t.columns.iter().map(|c| c.values.len()).sum(),
        wit::Value::Scalar(_) => 1,
    };
    n as u64
}

/// The interface's value as the engine's, checked for shape (equal lengths) so nothing
/// downstream indexes past a list the plugin made short.
pub fn from_wit(v: wit::Value) -> Result<ev::Value, String> {
    let same = |what: &str, a: usize, b: usize| {
        if a == b { Ok(()) } else { Err(format!("{what}: {b} values against {a}")) }
    };
    Ok(match v {
        wit::Value::TimeSeries(t) => {
            let n = t.channels.first().map_or(0, |c| c.samples.len());
            for c in &t.channels {
                same(&format!("time series channel `{}`", c.name), n, c.samples.len())?;
            }
            ev::Value::TimeSeries(ev::TimeSeries {
                sample_rate: t.sample_rate,
                t0: t.t0,
                channels: t
                    .channels
                    .into_iter()
                    .map(|c| ev::Channel { name: c.name, unit: UnitLabel::new(c.unit), samples: c.samples })
                    .collect(),
            })
        }
        wit::Value::Frf(f) => {
            same("FRF real parts", f.freq_hz.len(), f.re.len())?;
            same("FRF imaginary parts", f.freq_hz.len(), f.im.len())?;
            if let Some(c) = &f.coherence {
                same("FRF coherence", f.freq_hz.len(), c.len())?;
            }
            ev::Value::Frf(ev::Frf {
                values: f.re.iter().zip(&f.im).map(|(&re, &im)| num_complex::Complex64::new(re, im)).collect(),
                freq_hz: f.freq_hz,
                coherence: f.coherence,
                unit: UnitLabel::new(f.unit),
                direction: f.direction,
                speed: f.speed_rpm.map(Speed::from_rpm),
                sensor: f.sensor,
                dofs: None,
            })
        }
        wit::Value::ModalModel(m) => ev::Value::ModalModel(ev::ModalModel {
            modes: m
                .modes
                .into_iter()
                .map(|m| ev::Mode { freq_hz: m.freq_hz, damping_ratio: m.damping_ratio, modal_mass: m.modal_mass })
                .collect(),
        }),
        wit::Value::Lobes(l) => {
            same("lobe depths", l.speed_rpm.len(), l.depth_limit.len())?;
            same("lobe chatter frequencies", l.speed_rpm.len(), l.chatter_hz.len())?;
            ev::Value::Lobes(ev::Lobes::from_rpm(&l.speed_rpm, l.depth_limit, l.chatter_hz))
        }
        wit::Value::Table(t) => {
            let n = t.columns.first().map_or(0, |c| c.values.len());
            for c in &t.columns {
                same(&format!("table column `{}`", c.name), n, c.values.len())?;
            }
            ev::Value::Table(ev::Table {
                columns: t
                    .columns
                    .into_iter()
                    .map(|c| ev::Column {
                        name: c.name,
                        unit: UnitLabel::new(c.unit),
                        values: c.values,
                        levels: Vec::new(),
                    })
                    .collect(),
            })
        }
        wit::Value::Scalar(s) => ev::Value::Scalar(ev::Scalar { value: s.value, unit: UnitLabel::new(s.unit) }),
    })
}
