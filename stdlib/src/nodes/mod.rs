//! Node adapters: each wraps a physics kernel of this crate as a recipe node kind.

mod compare;
mod convert;
mod error_motion;
mod expr;
mod frf;
mod gap;
mod impact;
mod milling;
mod modal_fit;
mod modal_fit_set;
mod modal_frf;
mod phase;
mod read;
mod read_set;
mod rig;
mod rotor;
mod runout;
mod segment;
mod stability;
mod structure;
mod table;
mod transform;

/// The names of the kinds other crates refer to (the diagnosis finds steps by them and
/// writes them into the recipes it edits): each kind is spelled once, by its node.
pub mod kinds {
    pub use super::gap::FRF_GAP;
    pub use super::read::READ_FRF;
    pub use super::stability::{STABILITY_SPEED_DEPENDENT, TRIALS_SCORE};
    pub use super::structure::{BEAM_SUBSTRUCTURE, RCSA_COUPLE, SPINDLE_RECEPTANCE};
    pub use super::transform::{FRF_ADD_MODE, FRF_PHASE_SLOPE, RECEPTANCE_TIP_MASS, SUBSTRUCTURE_JOINT};
}

pub use compare::FrfCompare;
pub use convert::FrfConvert;
pub use error_motion::{ErrorsSeparate, LdvIntegrate, TachDecode};
pub use expr::RhaiEval;
pub use frf::FrfEstimate;
pub use gap::FrfGap;
pub use impact::ImpactSimulate;
pub use milling::{MillingSimulate, TrialsSimulate};
pub use modal_fit::ModalFitNode;
pub use modal_fit_set::ModalFitSetNode;
pub use modal_frf::ModalFrf;
pub use phase::{PhaseCorrect, PhaseMeasure};
pub use read::{READ_FRF, ReadFrf, ReadReceptance, ReadTimeSeries};
pub use read_set::ReadFrfSet;
pub use rig::{RigShaker, RigSimulate};
pub use rotor::{RotorCampbell, RotorReceptance};
pub use runout::RunoutRemove;
pub use segment::ImpactSegment;
pub use stability::{
    ChatterDetect, ModalModelNode, StabilityBest, StabilityLobes, StabilityProbability, StabilitySd,
    StabilitySpeedDependent, TrialsScore, parse_trials,
};
pub use structure::{BeamCampbell, BeamReceptance, BeamSubstructure, RcsaCouple, RcsaDecouple, SpindleReceptance};
pub use table::TableCollect;
pub use transform::{FrfAddMode, FrfPhaseSlope, ReceptanceTipMass, SubstructureJoint};

use spindlelab_engine::node::NodeError;
use spindlelab_engine::spec::Params;

/// Checks that each named parameter, where given, is positive.
fn positive(p: &Params, names: &[&str]) -> Result<(), NodeError> {
    for &name in names {
        if let Some(v) = p.f64(name)
            && v <= 0.0
        {
            return Err(NodeError::param(name, format!("must be positive, got {}", shown(p, name, v))));
        }
    }
    Ok(())
}

/// A parameter's value as a recipe writes it, with its unit.
fn shown(p: &Params, name: &str, v: f64) -> String {
    p.get(name).map_or_else(|| spindlelab_domain::sig(v, 6), |pv| pv.display())
}

/// Checks that each named parameter, where given, is not negative.
fn non_negative(p: &Params, names: &[&str]) -> Result<(), NodeError> {
    for &name in names {
        if let Some(v) = p.f64(name)
            && v < 0.0
        {
            return Err(NodeError::param(name, format!("must not be negative, got {}", shown(p, name, v))));
        }
    }
    Ok(())
}

/// Helpers for node unit tests: parameters as the compiler makes them, and an empty recipe.
#[cfg(test)]
pub(crate) mod test_support {
    use spindlelab_engine::diag::{Diagnostics, SourceFile};
    use spindlelab_engine::model::Recipe;
    use spindlelab_engine::node::Node;
    use spindlelab_engine::spec::{self, Ctx, EntityNames, Params};
    use spindlelab_engine::syntax::load_yaml;

    /// A recipe's text resolved with the built-in kinds: the recipe, or the diagnostics as text.
    pub(crate) fn resolve_text(text: &str) -> Result<Recipe, String> {
        let file = SourceFile { path: "recipe.yaml".into(), text: text.into() };
        let mut diags = Diagnostics::new();
        let mut registry = spindlelab_engine::node::Registry::new();
        crate::register(&mut registry);
        let raw = load_yaml(&file, &mut diags).ok_or_else(|| diags.to_string())?;
        match spindlelab_engine::model::resolve(&raw, &[], &registry, &mut diags) {
            Some(r) if !diags.has_errors() => Ok(r),
            _ => Err(diags.to_string()),
        }
    }

    /// Node parameters as the compiler makes them from recipe text (defaults filled in).
    pub(crate) fn params(node: &dyn Node, yaml: &str) -> Params {
        let file = SourceFile { path: "params.yaml".into(), text: yaml.into() };
        let mut d = Diagnostics::new();
        let raw = load_yaml(&file, &mut d).unwrap_or_else(|| panic!("{d}"));
        let names = EntityNames::default();
        spec::check_object(
            &raw,
            &node.spec().params,
            "params",
            &Ctx { entities: &names, base_dir: None, confine: None },
            &mut d,
        )
        .unwrap_or_else(|| panic!("{d}"))
    }

    /// A recipe with no entities, steps or outputs, for a node run on its own.
    pub(crate) fn empty_recipe() -> Recipe {
        Recipe { name: "test".into(), ..Recipe::default() }
    }
}
