//! Node adapters: each wraps a physics kernel of this crate as a recipe node kind.

mod expr;
mod frf;
mod impact;
mod read;
mod table;

pub use expr::RhaiEval;
pub use frf::FrfEstimate;
pub use impact::ImpactSimulate;
pub use read::{ReadFrf, ReadTimeSeries};
pub use table::TableCollect;
