//! Node adapters: each wraps a physics kernel of this crate as a recipe node kind.

mod compare;
mod error_motion;
mod expr;
mod frf;
mod impact;
mod modal_fit;
mod phase;
mod read;
mod rig;
mod runout;
mod segment;
mod stability;
mod structure;
mod table;

pub use compare::FrfCompare;
pub use error_motion::{ErrorsSeparate, LdvIntegrate, TachDecode};
pub use expr::RhaiEval;
pub use frf::FrfEstimate;
pub use impact::ImpactSimulate;
pub use modal_fit::ModalFitNode;
pub use phase::{PhaseCorrect, PhaseMeasure};
pub use read::{ReadFrf, ReadReceptance, ReadTimeSeries};
pub use rig::{RigShaker, RigSimulate};
pub use runout::RunoutRemove;
pub use segment::ImpactSegment;
pub use stability::{ChatterDetect, StabilityLobes, StabilitySd, StabilitySpeedDependent, TrialsScore};
pub use structure::{BeamCampbell, BeamReceptance, RcsaCouple, RcsaDecouple, SpindleReceptance};
pub use table::TableCollect;

use spindlelab_engine::node::NodeError;
use spindlelab_engine::spec::Params;

/// Checks that each named parameter, where given, is positive.
fn positive(p: &Params, names: &[&str]) -> Result<(), NodeError> {
    for &name in names {
        if let Some(v) = p.f64(name)
            && v <= 0.0
        {
            return Err(NodeError::param(name, format!("must be positive, got {v}")));
        }
    }
    Ok(())
}

/// Checks that each named parameter, where given, is not negative.
fn non_negative(p: &Params, names: &[&str]) -> Result<(), NodeError> {
    for &name in names {
        if let Some(v) = p.f64(name)
            && v < 0.0
        {
            return Err(NodeError::param(name, format!("must not be negative, got {v}")));
        }
    }
    Ok(())
}
