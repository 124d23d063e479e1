//! What each step of a recipe is for, as far as a diagnosis needs to know: which steps
//! compare a model with a measurement, which coupling makes the measured configuration and
//! which the cutting one, and the entities they name. Found by node kind and wiring, so any
//! recipe shaped like the importer's (or written by hand the same way) can be diagnosed.

use crate::engine::Compiled;
use crate::engine::model::{PortRef, Step};
use spindlelab_domain::Speed;
use spindlelab_stdlib::nodes::kinds;

/// A gap step and the model port it compares.
#[derive(Debug, Clone)]
pub struct GapRole {
    pub step: String,
    pub model: PortRef,
}

#[derive(Debug, Clone, Default)]
pub struct Roles {
    pub gaps: Vec<GapRole>,
    /// `rcsa.couple` steps whose FRF a gap compares (the measured configuration).
    pub measured_couplings: Vec<String>,
    /// `rcsa.couple` steps whose FRFs make the stability diagram (the cutting configuration).
    pub cutting_couplings: Vec<String>,
    /// The `beam.substructure` step the couplings take the holder and tool from.
    pub substructure: Option<String>,
    pub assembly: Option<String>,
    pub machine: Option<String>,
    /// Mass of the sensor the measured coupling puts on the tip (kg).
    pub sensor_mass_kg: f64,
    pub cutting: Option<String>,
    pub lobes: Option<String>,
    pub trials: Option<String>,
    /// Directions and speeds (rpm) of the measurements, from the baseline's gaps.
    pub directions: Vec<String>,
    pub speeds_rpm: Vec<f64>,
    /// The highest spindle speed (rpm) any spindle model of the recipe is evaluated at: a
    /// speed law must stay physical up to there.
    pub top_speed_rpm: f64,
    /// The direction of the file most off the floor and the band around its largest
    /// discrepancy (Hz), from the baseline: where a resonance is sought.
    pub discrepancy: Option<(String, [f64; 2])>,
}

impl Roles {
    /// Takes the measured directions and speeds, and the trials' speeds, from the baseline.
    pub fn measured(&mut self, baseline: &super::Evaluation) {
        self.directions = baseline.files.iter().map(|f| f.direction.clone()).collect();
        self.directions.sort();
        self.directions.dedup();
        self.speeds_rpm = baseline.files.iter().map(|f| f.speed_rpm).collect();
        self.speeds_rpm.sort_by(f64::total_cmp);
        self.speeds_rpm.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
        self.top_speed_rpm =
            self.speeds_rpm.iter().chain(&baseline.trial_speeds_rpm).fold(self.top_speed_rpm, |a, &b| a.max(b));
        self.discrepancy = super::locate_unknown(baseline).map(|u| (u.direction, u.band_hz));
    }
}

fn input<'a>(s: &'a Step, port: &str) -> Option<&'a PortRef> {
    s.inputs.iter().find(|b| b.port == port).map(|b| &b.from)
}

impl Roles {
    pub fn find(c: &Compiled) -> Roles {
        let r = &c.recipe;
        let kind = |id: &str| r.step(id).map(|s| s.kind.as_str());
        let mut roles = Roles::default();
        for s in r.steps.iter().filter(|s| s.kind == kinds::FRF_GAP) {
            if let Some(m) = input(s, "model") {
                roles.gaps.push(GapRole { step: s.id.clone(), model: m.clone() });
                if kind(&m.step) == Some(kinds::RCSA_COUPLE) && !roles.measured_couplings.contains(&m.step) {
                    roles.measured_couplings.push(m.step.clone());
                }
            }
        }
        roles.trials = r.steps.iter().find(|s| s.kind == kinds::TRIALS_SCORE).map(|s| s.id.clone());
        let lobes = roles
            .trials
            .as_ref()
            .and_then(|t| r.step(t))
            .and_then(|t| input(t, "lobes"))
            .and_then(|l| r.step(&l.step))
            .filter(|l| l.kind == kinds::STABILITY_SPEED_DEPENDENT);
        if let Some(l) = lobes {
            roles.lobes = Some(l.id.clone());
            roles.cutting = l.params.text("cutting").map(str::to_string);
            if let Some(f) = input(l, "frfs").filter(|f| kind(&f.step) == Some(kinds::RCSA_COUPLE)) {
                roles.cutting_couplings.push(f.step.clone());
            }
        }
        for c in roles.measured_couplings.iter().chain(&roles.cutting_couplings) {
            let Some(step) = r.step(c) else { continue };
            if let Some(sub) =
                input(step, "structure").and_then(|p| r.step(&p.step)).filter(|s| s.kind == kinds::BEAM_SUBSTRUCTURE)
            {
                roles.substructure.get_or_insert_with(|| sub.id.clone());
                if roles.assembly.is_none() {
                    roles.assembly = sub.params.text("assembly").map(str::to_string);
                }
            }
            if roles.machine.is_none() {
                roles.machine = input(step, "spindle")
                    .and_then(|p| r.step(&p.step))
                    .filter(|s| s.kind == kinds::SPINDLE_RECEPTANCE)
                    .and_then(|s| s.params.text("machine"))
                    .map(str::to_string);
            }
        }
        for s in r.steps.iter().filter(|s| s.kind == kinds::SPINDLE_RECEPTANCE) {
            let mut speeds: Vec<f64> = s.params.f64("speed").into_iter().collect();
            for axis in s.sweep.iter().filter(|a| a.param == "speed") {
                for v in &axis.values {
                    if let crate::engine::spec::ParamValue::Quantity { value, .. } = v {
                        speeds.push(*value);
                    }
                }
            }
            for w in speeds {
                roles.top_speed_rpm = roles.top_speed_rpm.max(Speed::from_rad_s(w).rpm());
            }
        }
        if let Some(s) = roles.measured_couplings.first().and_then(|c| r.step(c)).and_then(|s| s.params.text("sensor"))
        {
            roles.sensor_mass_kg = r.sensors.get(s).map_or(0.0, |s| s.mass);
        }
        roles
    }
}
