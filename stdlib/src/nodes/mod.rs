//! Node adapters: each wraps a physics kernel of this crate as a recipe node kind.

mod compare;
mod error_motion;
mod expr;
mod frf;
mod impact;
mod phase;
mod read;
mod rig;
mod runout;
mod segment;
mod table;

pub use compare::FrfCompare;
pub use error_motion::{ErrorsSeparate, LdvIntegrate, TachDecode};
pub use expr::RhaiEval;
pub use frf::FrfEstimate;
pub use impact::ImpactSimulate;
pub use phase::{PhaseCorrect, PhaseMeasure};
pub use read::{ReadFrf, ReadTimeSeries};
pub use rig::{RigShaker, RigSimulate};
pub use runout::RunoutRemove;
pub use segment::ImpactSegment;
pub use table::TableCollect;
