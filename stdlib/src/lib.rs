//! Built-in node kinds of spindlelab, and the physics kernels behind them.
//!
//! Kernels (`impact`, `frf`, `signal`) are plain functions on typed structs, SI units, no
//! I/O; [`nodes`] adapts them to the engine's node trait. [`register`] is the one place
//! where built-in kinds are listed.

pub mod beam;
pub mod chatter;
pub mod compare;
pub mod eb_modes;
pub mod error_motion;
pub mod filter;
pub mod frf;
pub mod gap;
pub mod impact;
pub mod milling;
pub mod modal_fit;
pub mod nodes;
pub mod optimize;
pub mod phase;
pub mod rcsa;
pub mod rig;
pub mod rotor;
pub mod runout;
pub mod segment;
pub mod signal;
pub mod stability;
pub mod tach;

use spindlelab_engine::node::Registry;
use std::sync::Arc;

/// Registers every built-in node kind.
pub fn register(registry: &mut Registry) {
    registry.register(Arc::new(nodes::ImpactSimulate::new()));
    registry.register(Arc::new(nodes::FrfEstimate::new()));
    registry.register(Arc::new(nodes::FrfCompare::new()));
    registry.register(Arc::new(nodes::FrfConvert::new()));
    registry.register(Arc::new(nodes::ImpactSegment::new()));
    registry.register(Arc::new(nodes::PhaseCorrect::new()));
    registry.register(Arc::new(nodes::PhaseMeasure::new()));
    registry.register(Arc::new(nodes::RunoutRemove::new()));
    registry.register(Arc::new(nodes::TableCollect::new()));
    registry.register(Arc::new(nodes::RhaiEval::new()));
    registry.register(Arc::new(nodes::ReadTimeSeries::new()));
    registry.register(Arc::new(nodes::ReadFrf::new()));
    registry.register(Arc::new(nodes::ReadFrfSet::new()));
    registry.register(Arc::new(nodes::TachDecode::new()));
    registry.register(Arc::new(nodes::ErrorsSeparate::new()));
    registry.register(Arc::new(nodes::LdvIntegrate::new()));
    registry.register(Arc::new(nodes::RigSimulate::new()));
    registry.register(Arc::new(nodes::RigShaker::new()));
    registry.register(Arc::new(nodes::ReadReceptance::new()));
    registry.register(Arc::new(nodes::BeamReceptance::new()));
    registry.register(Arc::new(nodes::BeamCampbell::new()));
    registry.register(Arc::new(nodes::BeamSubstructure::new()));
    registry.register(Arc::new(nodes::SpindleReceptance::new()));
    registry.register(Arc::new(nodes::RcsaCouple::new()));
    registry.register(Arc::new(nodes::RcsaDecouple::new()));
    registry.register(Arc::new(nodes::ModalFitNode::new()));
    registry.register(Arc::new(nodes::ModalFitSetNode::new()));
    registry.register(Arc::new(nodes::StabilityLobes::new()));
    registry.register(Arc::new(nodes::StabilitySd::new()));
    registry.register(Arc::new(nodes::MillingSimulate::new()));
    registry.register(Arc::new(nodes::TrialsSimulate::new()));
    registry.register(Arc::new(nodes::StabilitySpeedDependent::new()));
    registry.register(Arc::new(nodes::ChatterDetect::new()));
    registry.register(Arc::new(nodes::StabilityBest::new()));
    registry.register(Arc::new(nodes::StabilityProbability::new()));
    registry.register(Arc::new(nodes::RotorCampbell::new()));
    registry.register(Arc::new(nodes::RotorReceptance::new()));
    registry.register(Arc::new(nodes::TrialsScore::new()));
    registry.register(Arc::new(nodes::ModalModelNode::new()));
    registry.register(Arc::new(nodes::ModalFrf::new()));
    registry.register(Arc::new(nodes::FrfGap::new()));
    registry.register(Arc::new(nodes::SubstructureJoint::new()));
    registry.register(Arc::new(nodes::ReceptanceTipMass::new()));
    registry.register(Arc::new(nodes::FrfPhaseSlope::new()));
    registry.register(Arc::new(nodes::FrfAddMode::new()));
    registry.set_measurement_reader(nodes::READ_FRF).expect("`read.frf` takes a measurement set's parameters");
}
