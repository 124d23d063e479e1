//! Node adapters: each wraps a physics kernel of this crate as a recipe node kind.

mod expr;
mod frf;
mod impact;
mod rig;
mod table;

pub use expr::RhaiEval;
pub use frf::FrfEstimate;
pub use impact::ImpactSimulate;
pub use rig::{RigShaker, RigSimulate};
pub use table::TableCollect;
