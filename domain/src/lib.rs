//! The domain floor of spindlelab: what the physics kernels and the engine both speak.
//!
//! - [`value`]: the typed values that cross node boundaries (FRF, receptance set, modal
//!   model, lobes, tables…) and the one [`Mode`];
//! - [`entity`]: what a recipe names (materials, machines, Timoshenko sections, sensors,
//!   cutting setups), in SI;
//! - [`speed`]: the one spindle [`Speed`] type and the one [`SpeedLaw`] of a spindle mode.
//!
//! No I/O, no recipe syntax: units enter and leave at the edges (the grammar, the readers
//! and writers), never here.

#![forbid(unsafe_code)]

pub mod entity;
pub mod num;
pub mod speed;
pub mod value;

pub use entity::Material;
pub use num::{round_sig, sig};
pub use speed::{Speed, SpeedLaw};
pub use value::Mode;
