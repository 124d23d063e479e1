//! Node adapters: each wraps a physics kernel of this crate as a recipe node kind.

mod error_motion;
mod expr;
mod frf;
mod impact;
mod table;

pub use error_motion::{ErrorsSeparate, LdvIntegrate, TachDecode};
pub use expr::RhaiEval;
pub use frf::FrfEstimate;
pub use impact::ImpactSimulate;
pub use table::TableCollect;
