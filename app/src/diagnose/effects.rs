//! The library of candidate effects. Each is a transform of the recipe: it declares
//! parameters (starting where the effect is absent), puts them where the physics acts, and
//! bounds them physically. The library is a list of trait objects, so another source of
//! effects (a plugin) adds to it without touching the search.

use super::roles::Roles;
use crate::engine::Compiled;
use crate::engine::node::{EffectSpec, Registry};
use crate::engine::syntax::Raw;
use crate::engine::syntax::edit::{EditError, RecipeText, Seg, path};
use serde_json::{Map, Value as Json, json};
use spindlelab_domain::entity::{Whirl, whirl_frequency};
use spindlelab_domain::{Speed, SpeedLaw};
use spindlelab_stdlib::nodes::kinds;
use spindlelab_stdlib::nodes::kinds::{FRF_ADD_MODE, FRF_PHASE_SLOPE, RECEPTANCE_TIP_MASS, SUBSTRUCTURE_JOINT};

/// Where an effect acts; a measurement-only effect leaves the cutting configuration alone,
/// which is how the trials tell it from a structural one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Scope {
    Measurement,
    Structure,
    Cutting,
}

/// A free parameter an effect declares, in the unit it is written in.
#[derive(Debug, Clone)]
pub struct Free {
    pub name: String,
    pub unit: &'static str,
    pub start: f64,
    pub min: f64,
    pub max: f64,
    pub log: bool,
}

impl Free {
    fn lin(name: &str, unit: &'static str, start: f64, min: f64, max: f64) -> Free {
        Free { name: name.into(), unit, start, min, max, log: false }
    }
    fn log(name: &str, unit: &'static str, start: f64, min: f64, max: f64) -> Free {
        Free { name: name.into(), unit, start, min, max, log: true }
    }
    /// `v` as the recipe writes it: a number, or with the parameter's unit a quantity in the
    /// shortest text that reads back as `v`, in plain decimals where a person would write them
    /// (1e-3 to 1e6).
    pub fn value(&self, v: f64) -> Raw {
        if self.unit.is_empty() {
            return Raw::float(v);
        }
        let n = if v == 0.0 || (1e-3..1e6).contains(&v.abs()) { format!("{v}") } else { format!("{v:e}") };
        Raw::text(format!("{n} {}", self.unit))
    }
}

/// Why an effect does not apply to a recipe (it is then left out, and the reason reported).
pub type NotApplicable = String;

/// A physical effect the baseline model may lack.
pub trait Effect: Sync + Send {
    /// The vocabulary name (`interface_compliance`).
    fn name(&self) -> &'static str;
    fn scope(&self) -> Scope;
    /// One line on what the effect is, for the report.
    fn description(&self) -> &'static str;
    /// Adds the effect to the recipe text with its parameters declared at their starts.
    fn apply(&self, roles: &Roles, c: &Compiled, r: &mut RecipeText) -> Result<Vec<Free>, NotApplicable>;
    /// Independent starting points worth sampling in the bounds box (several basins).
    fn starts(&self, free: &[Free]) -> usize {
        let _ = free;
        0
    }
    /// Simpler forms of the effect, each as the parameters it holds at their starts (the
    /// effect absent in them): nested models BIC prefers when the data do not resolve the
    /// held parameters.
    fn nested(&self) -> Vec<Vec<&'static str>> {
        vec![]
    }
    /// Lets the values a forward model is given say where the effect acts (a direction in a
    /// parameter's name) before it is applied; a diagnosis locates it from the measurements.
    fn place(&self, values: &[(&str, f64)], roles: &mut Roles) {
        let _ = (values, roles);
    }
    /// The fitted values in the vocabulary's parameter names and units (SI, `_deg`, …).
    fn report(&self, values: &[(String, f64)], roles: &Roles, c: &Compiled) -> Map<String, Json>;
}

/// The library: the built-in effects and those the registry's plugin kinds offer, in the
/// order effects are applied when combined (a tip mass acts on receptances, a plugin's
/// effect on the model FRF that results, a delay on the measured chain last).
pub fn library(registry: &Registry) -> Vec<Box<dyn Effect>> {
    let mut lib: Vec<Box<dyn Effect>> = vec![
        Box::new(InterfaceCompliance),
        Box::new(FluteReducedStiffness),
        Box::new(SpindleSpeedStiffening),
        Box::new(BearingStiffnessChange),
        Box::new(GyroscopicModeSplit),
        Box::new(MachineResonance),
        Box::new(MassLoading),
    ];
    let builtin = ["sensor_delay", "speed_dependent_cutting_coefficients"];
    for node in registry.kinds() {
        if let Some(spec) = node.effect() {
            let taken = |n: &str| builtin.contains(&n) || lib.iter().any(|e| e.name() == n);
            // A plugin's name that a built-in effect (or another plugin) has is reported by
            // the node kind instead.
            let name = if taken(spec.name) { kind_name(node.spec().kind) } else { spec.name };
            if !taken(name) {
                lib.push(Box::new(PluginEffect { kind: node.spec().kind, name, spec: spec.clone() }));
            }
        }
    }
    lib.push(Box::new(SensorDelay));
    lib.push(Box::new(SpeedDependentCuttingCoefficients));
    lib
}

/// `effect.tip_mass` → `effect_tip_mass`, leaked once per plugin kind and process.
fn kind_name(kind: &'static str) -> &'static str {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    static NAMES: OnceLock<Mutex<HashMap<&'static str, &'static str>>> = OnceLock::new();
    let mut names = NAMES.get_or_init(Default::default).lock().unwrap_or_else(|e| e.into_inner());
    names.entry(kind).or_insert_with(|| Box::leak(kind.replace('.', "_").into_boxed_str()))
}

fn e(err: EditError) -> NotApplicable {
    err.to_string()
}

fn value(values: &[(String, f64)], name: &str) -> f64 {
    values.iter().find(|(n, _)| n == name).map_or(f64::NAN, |v| v.1)
}

/// Declares every free parameter at its start.
fn declare(r: &mut RecipeText, free: &[Free]) -> Result<(), NotApplicable> {
    for f in free.iter().rev() {
        r.declare_param(&f.name, &f.value(f.start)).map_err(e)?;
    }
    Ok(())
}

/// A step of node `kind` with `params` whose `frf` input is `source`.
fn frf_step(kind: &str, params: Raw, source: &str) -> Raw {
    Raw::mapping([
        ("kind", Raw::text(kind)),
        ("params", params),
        ("inputs", Raw::mapping([("frf", Raw::text(source))])),
    ])
}

/// Puts a new step between each gap and the model it compares, rewiring the gap's `model`
/// input: `make(source)` gives the step (its kind, parameters and inputs), written under the
/// comment `comment`. Sources that are already wrapped by this step are left alone.
fn wrap_gap_models(
    roles: &Roles,
    r: &mut RecipeText,
    step: &str,
    comment: &str,
    make: &dyn Fn(&str) -> Raw,
) -> Result<(), NotApplicable> {
    let mut done: Vec<(String, String)> = Vec::new();
    for (k, gap) in roles.gaps.iter().enumerate() {
        let current = r
            .get(&path(&["steps", &gap.step, "inputs", "model"]))
            .and_then(|v| v.as_str())
            .map(str::to_string)
            .ok_or_else(|| format!("gap `{}` has no `model` input in the text", gap.step))?;
        let name = match done.iter().find(|(src, _)| *src == current) {
            Some((_, n)) => n.clone(),
            None => {
                let n = if roles.gaps.len() == 1 || done.is_empty() { step.to_string() } else { format!("{step}_{k}") };
                r.insert_step_before(&gap.step, comment, &n, &make(&current)).map_err(e)?;
                done.push((current.clone(), n.clone()));
                n
            }
        };
        r.replace(&path(&["steps", &gap.step, "inputs", "model"]), &Raw::port(&name, "frf")).map_err(e)?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------

/// An effect a plugin offers: its node kind between each model and the measurement it is
/// compared with, the freed parameters declared at their absent values within the plugin's
/// bounds (SI).
pub struct PluginEffect {
    kind: &'static str,
    name: &'static str,
    spec: EffectSpec,
}

impl PluginEffect {
    fn param(&self, p: &str) -> String {
        format!("{}_{p}", self.name)
    }
}

impl Effect for PluginEffect {
    fn name(&self) -> &'static str {
        self.name
    }
    fn scope(&self) -> Scope {
        Scope::Measurement
    }
    fn description(&self) -> &'static str {
        self.spec.description
    }
    fn apply(&self, roles: &Roles, _c: &Compiled, r: &mut RecipeText) -> Result<Vec<Free>, NotApplicable> {
        if roles.gaps.is_empty() {
            return Err("no model is compared with a measurement".into());
        }
        let free: Vec<Free> = self
            .spec
            .params
            .iter()
            .map(|p| Free {
                name: self.param(p.name),
                unit: p.si_unit,
                start: p.absent,
                min: p.min,
                max: p.max,
                log: p.log,
            })
            .collect();
        declare(r, &free)?;
        let params = Raw::mapping(self.spec.params.iter().map(|p| (p.name, Raw::param(&self.param(p.name)))));
        let comment = format!("Diagnosed: {} (plugin kind {}), measured configuration only.", self.name, self.kind);
        wrap_gap_models(roles, r, self.name, &comment, &|src| frf_step(self.kind, params.clone(), src))?;
        Ok(free)
    }
    /// Nothing is known of a plugin effect's basins: sample its box well.
    fn starts(&self, free: &[Free]) -> usize {
        16 * free.len()
    }
    fn report(&self, values: &[(String, f64)], _roles: &Roles, _c: &Compiled) -> Map<String, Json> {
        let mut m = Map::new();
        for p in &self.spec.params {
            let key = if p.si_unit.is_empty() { p.name.to_string() } else { format!("{}_{}", p.name, p.si_unit) };
            m.insert(key, json!(value(values, &self.param(p.name))));
        }
        m.insert("node_kind".into(), json!(self.kind));
        m
    }
}

/// A resonance outside the library, along one direction and within a band: one mode added
/// to the model FRFs of that direction (`frf.add_mode`). Never named: it stands in for what
/// the library cannot say, so a known effect can be judged beside it and the rest located.
pub struct UnknownResonance {
    pub direction: String,
    /// The band its frequency is searched in, Hz.
    pub band_hz: [f64; 2],
}

impl Effect for UnknownResonance {
    fn name(&self) -> &'static str {
        "unknown_resonance"
    }
    fn scope(&self) -> Scope {
        Scope::Measurement
    }
    fn description(&self) -> &'static str {
        "one mode the model lacks, along one direction (not an effect of the library)"
    }
    fn apply(&self, roles: &Roles, _c: &Compiled, r: &mut RecipeText) -> Result<Vec<Free>, NotApplicable> {
        if roles.gaps.is_empty() {
            return Err("no model is compared with a measurement".into());
        }
        let [lo, hi] = self.band_hz;
        let free = vec![
            Free::lin("unknown_f", "Hz", 0.5 * (lo + hi), lo, hi),
            Free::log("unknown_zeta", "", 0.03, 0.003, 0.3),
            Free::log("unknown_k", "N/m", 1e10, 1e5, 1e12),
        ];
        declare(r, &free)?;
        let direction = self.direction.clone();
        let comment = format!("Diagnosed: a resonance outside the library along {direction}, located, not named.");
        let params = Raw::mapping([
            ("f", Raw::param("unknown_f")),
            ("zeta", Raw::param("unknown_zeta")),
            ("stiffness", Raw::param("unknown_k")),
            ("direction", Raw::text(direction)),
        ]);
        wrap_gap_models(roles, r, "unknown_resonance", &comment, &|src| frf_step(FRF_ADD_MODE, params.clone(), src))?;
        Ok(free)
    }
    fn starts(&self, free: &[Free]) -> usize {
        16 * free.len()
    }
    fn report(&self, values: &[(String, f64)], _roles: &Roles, _c: &Compiled) -> Map<String, Json> {
        let mut m = Map::new();
        m.insert("direction".into(), json!(self.direction));
        m.insert("f_hz".into(), json!(value(values, "unknown_f")));
        m.insert("zeta".into(), json!(value(values, "unknown_zeta")));
        m.insert("stiffness_n_per_m".into(), json!(value(values, "unknown_k")));
        m
    }
}

/// A sensor's phase lag linear in frequency (§2.3, Eq. 2.11): acts on the measured FRFs only.
pub struct SensorDelay;

impl Effect for SensorDelay {
    fn name(&self) -> &'static str {
        "sensor_delay"
    }
    fn scope(&self) -> Scope {
        Scope::Measurement
    }
    fn description(&self) -> &'static str {
        "the measuring chain's phase lag, linear in frequency (H exp(i s f)); measured FRFs only"
    }
    fn apply(&self, roles: &Roles, _c: &Compiled, r: &mut RecipeText) -> Result<Vec<Free>, NotApplicable> {
        if roles.gaps.is_empty() {
            return Err("no model is compared with a measurement".into());
        }
        // ±60 deg/kHz spans the gauges of §2.3 (about −14 deg/kHz) several times over.
        let free = vec![Free::lin("sensor_phase_slope", "deg/kHz", 0.0, -60.0, 60.0)];
        declare(r, &free)?;
        let comment = "Diagnosed: the sensor's phase lag (sensor_delay), measured configuration only.";
        let params = Raw::mapping([("slope", Raw::param("sensor_phase_slope"))]);
        wrap_gap_models(roles, r, "sensor_delay", comment, &|src| frf_step(FRF_PHASE_SLOPE, params.clone(), src))?;
        Ok(free)
    }
    fn report(&self, values: &[(String, f64)], _roles: &Roles, _c: &Compiled) -> Map<String, Json> {
        let mut m = Map::new();
        m.insert("phase_slope_deg_per_khz".into(), json!(value(values, "sensor_phase_slope")));
        m
    }
}

/// A translational mass at the tip beyond the declared sensor mass: measured FRFs only.
pub struct MassLoading;

impl Effect for MassLoading {
    fn name(&self) -> &'static str {
        "mass_loading"
    }
    fn scope(&self) -> Scope {
        Scope::Measurement
    }
    fn description(&self) -> &'static str {
        "a point mass on the tip beyond the declared sensor mass, G' = G (I − ω² diag(m, 0) G)⁻¹; measured FRFs only"
    }
    fn apply(&self, roles: &Roles, _c: &Compiled, r: &mut RecipeText) -> Result<Vec<Free>, NotApplicable> {
        // The mass acts on the 2×2 tip receptances, so each gap's model must be a coupling.
        for g in &roles.gaps {
            if !roles.measured_couplings.contains(&g.model.step) {
                return Err(format!("the model of gap `{}` is not a tip coupling (rcsa.couple)", g.step));
            }
        }
        // Down to minus the declared sensor mass (the declared one too heavy), up to 50 g.
        let declared_g = roles.sensor_mass_kg * 1e3;
        let free = vec![Free::lin("added_tip_mass", "g", 0.0, -declared_g, 50.0)];
        declare(r, &free)?;
        let comment =
            "Diagnosed: a mass on the tip beyond the declared sensor's (mass_loading), measured configuration only.";
        wrap_gap_models(roles, r, "added_mass", comment, &|src| {
            let coupling = src.trim_start_matches('@').split('.').next().unwrap_or_default();
            Raw::mapping([
                ("kind", Raw::text(RECEPTANCE_TIP_MASS)),
                ("params", Raw::mapping([("mass", Raw::param("added_tip_mass"))])),
                ("inputs", Raw::mapping([("tip", Raw::port(coupling, "tip"))])),
            ])
        })?;
        Ok(free)
    }
    /// A few grams on a light tool move its mode by several half-power bandwidths, and the
    /// residual is flat until the peaks overlap: a dense scan of the one parameter finds the well.
    fn starts(&self, _free: &[Free]) -> usize {
        32
    }
    fn report(&self, values: &[(String, f64)], _roles: &Roles, _c: &Compiled) -> Map<String, Json> {
        let mut m = Map::new();
        m.insert("added_mass_kg".into(), json!(value(values, "added_tip_mass") * 1e-3));
        m
    }
}

/// A compliant tool–holder joint at the holder face: the tool overhang coupled to the holder
/// through `diag(kt + iω ct, kr + iω cr)`; acts while cutting too.
pub struct InterfaceCompliance;

impl Effect for InterfaceCompliance {
    fn name(&self) -> &'static str {
        "interface_compliance"
    }
    fn scope(&self) -> Scope {
        Scope::Structure
    }
    fn description(&self) -> &'static str {
        "a compliant tool–holder joint at the holder face, K = diag(kt + iω ct, kr + iω cr) (§5.4); measured and cutting"
    }
    fn apply(&self, roles: &Roles, _c: &Compiled, r: &mut RecipeText) -> Result<Vec<Free>, NotApplicable> {
        let sub = roles.substructure.as_ref().ok_or("no beam.substructure step reduces the holder and tool")?;
        r.set_key(&path(&["steps", sub, "params"]), "split", &Raw::text("holder_face")).map_err(e)?;
        // Holder–tool joints of shrink-fit and collet holders span these ranges; the start is
        // a joint stiff enough to be rigid for the tool modes.
        let free = vec![
            Free::log("joint_kt", "N/m", 1e10, 1e6, 1e11),
            Free::log("joint_ct", "N*s/m", 100.0, 1.0, 1e4),
            Free::log("joint_kr", "N*m/rad", 1e8, 1e3, 1e9),
            Free::log("joint_cr", "N*m*s/rad", 1.0, 1e-2, 1e3),
        ];
        declare(r, &free)?;
        let first = roles
            .measured_couplings
            .iter()
            .chain(&roles.cutting_couplings)
            .next()
            .ok_or("no rcsa.couple step uses the substructure")?
            .clone();
        let joint = Raw::mapping([
            ("kind", Raw::text(SUBSTRUCTURE_JOINT)),
            ("params", Raw::mapping(["kt", "ct", "kr", "cr"].map(|k| (k, Raw::param(&format!("joint_{k}")))))),
            ("inputs", Raw::mapping([("structure", Raw::port(sub, "model"))])),
        ]);
        let comment = "Diagnosed: a compliant tool–holder joint at the holder face (interface_compliance).";
        r.insert_step_before(&first, comment, "holder_face_joint", &joint).map_err(e)?;
        for c in roles.measured_couplings.iter().chain(&roles.cutting_couplings) {
            r.replace(&path(&["steps", c, "inputs", "structure"]), &Raw::port("holder_face_joint", "structure"))
                .map_err(e)?;
        }
        Ok(free)
    }
    fn starts(&self, free: &[Free]) -> usize {
        16 * free.len()
    }
    fn report(&self, values: &[(String, f64)], _roles: &Roles, _c: &Compiled) -> Map<String, Json> {
        let mut m = Map::new();
        for (k, n) in [
            ("kt_n_per_m", "joint_kt"),
            ("ct_ns_per_m", "joint_ct"),
            ("kr_nm_per_rad", "joint_kr"),
            ("cr_nms_per_rad", "joint_cr"),
        ] {
            m.insert(k.into(), json!(value(values, n)));
        }
        m
    }
}

/// The fluted part of the tool modelled as a solid cylinder of an equivalent diameter
/// (§5.3, Fig. 5.16) for stiffness, shear, mass and rotary inertia.
pub struct FluteReducedStiffness;

impl FluteReducedStiffness {
    /// `(section index, name, nominal diameter m)` of each fluted section.
    fn fluted(roles: &Roles, c: &Compiled) -> Vec<(usize, String, f64)> {
        let Some(a) = roles.assembly.as_ref().and_then(|a| c.recipe.assemblies.get(a)) else { return vec![] };
        a.sections
            .iter()
            .enumerate()
            .filter(|(_, s)| s.fluted)
            .map(|(i, s)| (i, s.name.clone(), s.d_out_spindle_end))
            .collect()
    }
}

impl Effect for FluteReducedStiffness {
    fn name(&self) -> &'static str {
        "flute_reduced_stiffness"
    }
    fn scope(&self) -> Scope {
        Scope::Structure
    }
    fn description(&self) -> &'static str {
        "the fluted section as a solid cylinder of an equivalent diameter below the nominal one (§5.3); measured and cutting"
    }
    fn apply(&self, roles: &Roles, c: &Compiled, r: &mut RecipeText) -> Result<Vec<Free>, NotApplicable> {
        let assembly = roles.assembly.as_ref().ok_or("no assembly is modelled")?;
        let fluted = Self::fluted(roles, c);
        let Some(&(_, _, d)) = fluted.first() else {
            return Err(format!("assembly `{assembly}` has no section of `kind: fluted`"));
        };
        let d_mm = d * 1e3;
        // The flutes take away at most what §5.3's search allows (a quarter of the diameter
        // left would be no tool); they never add stiffness.
        let free = vec![Free::lin("flute_d_equivalent", "mm", d_mm, 0.5 * d_mm, d_mm)];
        for (i, _, _) in &fluted {
            let p: Vec<Seg> = path(&["assemblies", assembly, "sections", &i.to_string()]);
            r.set_key(&p, "d_equivalent", &Raw::param("flute_d_equivalent")).map_err(e)?;
        }
        declare(r, &free)?;
        Ok(free)
    }
    /// The equivalent diameter moves the tool modes by several bandwidths over its range.
    fn starts(&self, free: &[Free]) -> usize {
        24 * free.len()
    }
    fn report(&self, values: &[(String, f64)], roles: &Roles, c: &Compiled) -> Map<String, Json> {
        let fluted = Self::fluted(roles, c);
        let d = fluted.first().map_or(f64::NAN, |f| f.2);
        let de = value(values, "flute_d_equivalent") * 1e-3;
        let mut m = Map::new();
        m.insert("sections".into(), json!(fluted.iter().map(|f| f.1.clone()).collect::<Vec<_>>()));
        m.insert("nominal_diameter_m".into(), json!(d));
        m.insert("equivalent_diameter_m".into(), json!(de));
        m.insert("equivalent_diameter_ratio".into(), json!(de / d));
        m
    }
}

/// Spindle modes whose frequency and damping change with speed beyond the baseline law:
/// `f(n) = f (1 + kf (n/ref)²)`, `η(n) = η (1 + kη (n/ref)²)` with kf and kη fitted per mode.
pub struct SpindleSpeedStiffening;

impl SpindleSpeedStiffening {
    /// `(direction, mode index, kf, keta)` of every mode in a measured direction.
    fn modes(roles: &Roles, c: &Compiled) -> Vec<(String, usize, f64, f64)> {
        let Some(s) = roles.machine.as_ref().and_then(|m| c.recipe.machines.get(m)).and_then(|m| m.spindle.as_ref())
        else {
            return vec![];
        };
        s.modes
            .iter()
            .filter(|(d, _)| roles.directions.contains(d))
            .flat_map(|(d, modes)| modes.iter().enumerate().map(move |(i, m)| (d.clone(), i, m.law.kf, m.law.kd)))
            .collect()
    }
}

impl Effect for SpindleSpeedStiffening {
    fn name(&self) -> &'static str {
        "spindle_speed_stiffening"
    }
    fn scope(&self) -> Scope {
        Scope::Structure
    }
    fn description(&self) -> &'static str {
        "spindle modes stiffening (and damping changing) with speed beyond the baseline speed law; measured and cutting"
    }
    fn apply(&self, roles: &Roles, c: &Compiled, r: &mut RecipeText) -> Result<Vec<Free>, NotApplicable> {
        let (machine, spindle) = coupled_spindle(roles, c)?;
        let top = roles.speeds_rpm.iter().copied().fold(0.0, f64::max);
        if roles.speeds_rpm.len() < 2 || top <= 0.0 {
            return Err("the measurements are at one speed; a speed law needs FRFs at two speeds or more".into());
        }
        let modes = Self::modes(roles, c);
        if modes.is_empty() {
            return Err("the machine has no spindle modes in the measured directions".into());
        }
        // At the fastest measured speed a mode moves by at most ±30 % in frequency and its
        // loss factor by at most ±80 %; at the fastest speed the recipe uses (the cutting
        // configuration's) a mode keeps at least half its frequency and a tenth of its loss.
        let s2 = SpeedLaw::ratio_squared(Speed::from_rpm(top), spindle.ref_speed);
        let s2_all = SpeedLaw::ratio_squared(Speed::from_rpm(roles.top_speed_rpm.max(top)), spindle.ref_speed);
        let mut free = Vec::new();
        for (d, i, kf, keta) in &modes {
            let p = path(&["machines", machine, "spindle", "modes", d, &i.to_string()]);
            let (nf, ne) = (format!("spindle_{d}{i}_kf"), format!("spindle_{d}{i}_keta"));
            r.set_key(&p, "keta", &Raw::param(&ne)).map_err(e)?;
            r.set_key(&p, "kf", &Raw::param(&nf)).map_err(e)?;
            let kf_min = (kf - 0.3 / s2).max(-0.5 / s2_all).min(*kf);
            let keta_min = (keta - 0.8 / s2).max(-0.9 / s2_all).min(*keta);
            free.push(Free::lin(&nf, "", *kf, kf_min, kf + 0.3 / s2));
            free.push(Free::lin(&ne, "", *keta, keta_min, keta + 0.8 / s2));
        }
        declare(r, &free)?;
        Ok(free)
    }
    fn report(&self, values: &[(String, f64)], roles: &Roles, c: &Compiled) -> Map<String, Json> {
        let changes: Vec<Json> = Self::modes(roles, c)
            .iter()
            .map(|(d, i, kf, keta)| {
                json!({
                    "direction": d,
                    "mode_index": i,
                    "delta_kf": value(values, &format!("spindle_{d}{i}_kf")) - kf,
                    "delta_keta": value(values, &format!("spindle_{d}{i}_keta")) - keta,
                })
            })
            .collect();
        let mut m = Map::new();
        m.insert("changes".into(), Json::Array(changes));
        m
    }
}

/// The name and spindle model of the machine the measured couplings stand on.
fn coupled_spindle<'c>(
    roles: &Roles,
    c: &'c Compiled,
) -> Result<(&'c String, &'c spindlelab_domain::entity::Spindle), NotApplicable> {
    let machine = roles.machine.as_ref().ok_or("no spindle model is coupled")?;
    let (name, m) = c.recipe.machines.get_key_value(machine).ok_or("no spindle model is coupled")?;
    Ok((name, m.spindle.as_ref().ok_or("the machine has no spindle modes")?))
}

/// The machine's spindle model, the directions it has modes in and the fastest measured
/// speed: what the speed-dependent spindle effects need.
fn spindle_at_speed<'c>(
    roles: &Roles,
    c: &'c Compiled,
    what: &str,
) -> Result<(&'c String, &'c spindlelab_domain::entity::Spindle, f64), NotApplicable> {
    let (name, spindle) = coupled_spindle(roles, c)?;
    let top = roles.speeds_rpm.iter().copied().fold(0.0, f64::max);
    if top <= 0.0 {
        return Err(format!("every measurement is at rest; {what} shows only at speed"));
    }
    Ok((name, spindle, top))
}

/// A bearing set whose stiffness changes with speed (centrifugal softening, preload change):
/// `k(n) = k (1 + c (n/n_ref)^p)` for every spindle mode at its own mass, so each mode's
/// frequency moves with `√k` and its flexibility with `1/k`, one `c` for all of them. `p` is 2
/// (the quadratic law) unless three speeds or more are measured: then it is fitted, since a
/// preloaded angular-contact bearing softens faster at high speed as its balls' centrifugal
/// load turns the contact angles (Jones–Harris).
pub struct BearingStiffnessChange;

impl Effect for BearingStiffnessChange {
    fn name(&self) -> &'static str {
        "bearing_stiffness_change"
    }
    fn scope(&self) -> Scope {
        Scope::Structure
    }
    fn description(&self) -> &'static str {
        "the bearings' stiffness changing with speed, k(n) = k (1 + c (n/n_ref)^p) for every spindle mode at its mass (f ∝ √k, flexibility ∝ 1/k), p = 2 or fitted over three speeds or more; measured and cutting"
    }
    fn apply(&self, roles: &Roles, c: &Compiled, r: &mut RecipeText) -> Result<Vec<Free>, NotApplicable> {
        let (machine, spindle, top) = spindle_at_speed(roles, c, "a bearing stiffness law")?;
        if roles.speeds_rpm.len() < 2 {
            return Err("the measurements are at one speed; a speed law needs FRFs at two speeds or more".into());
        }
        let changes: Vec<f64> = spindle.modes.iter().flat_map(|(_, m)| m.iter().map(|m| m.stiffness_change)).collect();
        let start = changes.first().copied().unwrap_or(0.0);
        if changes.iter().any(|c| *c != start) {
            return Err("the spindle's modes already carry different bearing laws (`kk`)".into());
        }
        // At the fastest measured speed the bearings keep at least half their stiffness and gain
        // at most 30 %; at the fastest speed the recipe uses they keep at least a fifth.
        let s2 = SpeedLaw::ratio_squared(Speed::from_rpm(top), spindle.ref_speed);
        let s2_all = SpeedLaw::ratio_squared(Speed::from_rpm(roles.top_speed_rpm.max(top)), spindle.ref_speed);
        let mut free = vec![Free::lin("bearing_kk", "", start, (-0.5 / s2).max(-0.8 / s2_all).min(start), 0.3 / s2)];
        // Three speeds or more resolve how the law bends: its exponent is fitted too (the
        // quadratic law is the nested form BIC falls back to); two fix the quadratic law.
        let bends = roles.speeds_rpm.len() >= 3;
        if bends {
            free.push(Free::lin("bearing_p", "", 2.0, 1.0, 8.0));
        }
        for (d, modes) in &spindle.modes {
            for i in 0..modes.len() {
                let p = path(&["machines", machine, "spindle", "modes", d, &i.to_string()]);
                r.set_key(&p, "kk", &Raw::param("bearing_kk")).map_err(e)?;
                if bends {
                    r.set_key(&p, "kk_exponent", &Raw::param("bearing_p")).map_err(e)?;
                }
            }
        }
        declare(r, &free)?;
        Ok(free)
    }
    /// A change of a few per cent moves every spindle mode by more than its bandwidth at the
    /// fastest speed: a scan of the one parameter finds the well.
    fn starts(&self, free: &[Free]) -> usize {
        16 * free.len()
    }
    /// The quadratic law: the exponent held at 2.
    fn nested(&self) -> Vec<Vec<&'static str>> {
        vec![vec!["bearing_p"]]
    }
    fn report(&self, values: &[(String, f64)], roles: &Roles, c: &Compiled) -> Map<String, Json> {
        let reference = roles
            .machine
            .as_ref()
            .and_then(|m| c.recipe.machines.get(m))
            .and_then(|m| m.spindle.as_ref())
            .map_or(f64::NAN, |s| s.ref_speed.rpm());
        let kk = value(values, "bearing_kk");
        let top = roles.speeds_rpm.iter().copied().fold(0.0, f64::max);
        let mut m = Map::new();
        m.insert("reference_rpm".into(), json!(reference));
        m.insert("relative_change_at_reference".into(), json!(kk));
        m.insert("fastest_measured_rpm".into(), json!(top));
        let p = values.iter().find(|(n, _)| n == "bearing_p").map_or(2.0, |v| v.1);
        m.insert("exponent".into(), json!(p));
        m.insert("law".into(), json!(if p == 2.0 { "quadratic" } else { "exponent fitted over three speeds or more" }));
        m.insert("relative_change_at_fastest_measured".into(), json!(kk * (top / reference).powf(p)));
        m
    }
}

/// Spindle modes whirling forward and backward with speed (gyroscopic coupling of an
/// isotropic rotor), in the form the physics gives it: mode `i` has a gyroscopic coefficient
/// `g = I_p/I_d` (one per mode index, x and y see the same rotor), its whirls are at
/// `ω (√(1+e²) ± e)`, `e = gΩ/(2ω)`, and the whole assembly is coupled in each whirl's
/// coordinates and the two averaged (spindle.receptance's `cross` wired into each coupling's
/// `spindle_cross`): the split of the coupled modes then follows each one's shape.
pub struct GyroscopicModeSplit;

impl GyroscopicModeSplit {
    /// How many mode indices the measured directions have.
    fn count(roles: &Roles, c: &Compiled) -> usize {
        roles.machine.as_ref().and_then(|m| c.recipe.machines.get(m)).and_then(|m| m.spindle.as_ref()).map_or(0, |s| {
            s.modes.iter().filter(|(d, _)| roles.directions.contains(d)).map(|(_, m)| m.len()).max().unwrap_or(0)
        })
    }

    /// The largest gyroscopic coefficient: a thin disk's, `I_p = 2 I_d`.
    const MAX_GYRO: f64 = 2.0;
}

impl Effect for GyroscopicModeSplit {
    fn name(&self) -> &'static str {
        "gyroscopic_mode_split"
    }
    fn scope(&self) -> Scope {
        Scope::Structure
    }
    fn description(&self) -> &'static str {
        "spindle modes whirling forward and backward at ω(√(1+e²) ± e), e = gΩ/(2ω), g = I_p/I_d per mode, the assembly coupled in each whirl and the two averaged; measured and cutting"
    }
    fn apply(&self, roles: &Roles, c: &Compiled, r: &mut RecipeText) -> Result<Vec<Free>, NotApplicable> {
        let (machine, spindle, top) = spindle_at_speed(roles, c, "a gyroscopic whirl")?;
        let count = Self::count(roles, c);
        if count == 0 {
            return Err("the machine has no spindle modes in the measured directions".into());
        }
        // At most a thin disk's, and at most what moves the lowest mode's whirls by 40 % at the
        // fastest measured speed (e = gΩ/(2ω) ≤ 0.4): a mode split further is no longer that
        // mode. The whirls of every mode part by about gΩ/2, so one range serves them all.
        let lowest = spindle.modes.iter().flat_map(|(_, m)| m.iter().map(|m| m.freq_hz)).fold(f64::INFINITY, f64::min);
        let max = Self::MAX_GYRO.min(0.8 * lowest / (top / 60.0));
        let mut free = Vec::new();
        for i in 0..count {
            let name = format!("spindle_{i}_gyro");
            let mut start = 0.0;
            for (d, modes) in spindle.modes.iter().filter(|(_, m)| m.len() > i) {
                start = modes[i].gyro;
                let p = path(&["machines", machine, "spindle", "modes", d, &i.to_string()]);
                r.set_key(&p, "gyro", &Raw::param(&name)).map_err(e)?;
            }
            free.push(Free::lin(&name, "", start.clamp(0.0, max), 0.0, max.max(start)));
        }
        // Every coupling of the spindle model takes its whirls.
        let mut wired = 0;
        for coupling in roles.measured_couplings.iter().chain(&roles.cutting_couplings) {
            let Some(step) = c.recipe.step(coupling) else { continue };
            let Some(from) = step.inputs.iter().find(|b| b.port == "spindle").map(|b| &b.from) else { continue };
            if c.recipe.step(&from.step).is_none_or(|s| s.kind != kinds::SPINDLE_RECEPTANCE) {
                continue;
            }
            let cross = Raw::text(format!("@{}.cross", from.step));
            r.set_key(&path(&["steps", coupling, "inputs"]), "spindle_cross", &cross).map_err(e)?;
            wired += 1;
        }
        if wired == 0 {
            return Err("no coupling takes its spindle from a spindle model".into());
        }
        declare(r, &free)?;
        Ok(free)
    }
    /// The whirls are even in `g` about no coupling (the residual is flat there) and move by
    /// several bandwidths over its range: a scan finds the well.
    fn starts(&self, free: &[Free]) -> usize {
        16 * free.len()
    }
    fn report(&self, values: &[(String, f64)], roles: &Roles, c: &Compiled) -> Map<String, Json> {
        let spindle = roles.machine.as_ref().and_then(|m| c.recipe.machines.get(m)).and_then(|m| m.spindle.as_ref());
        let top = roles.speeds_rpm.iter().copied().fold(0.0, f64::max);
        let modes: Vec<Json> = (0..Self::count(roles, c))
            .map(|i| {
                let g = value(values, &format!("spindle_{i}_gyro"));
                // Each direction's whirls at the fastest measured speed, Hz, from its frequency at rest.
                let whirls: Map<String, Json> = spindle
                    .map(|sp| {
                        sp.modes
                            .iter()
                            .filter(|(_, m)| m.len() > i)
                            .map(|(d, m)| {
                                let at = |w| whirl_frequency(m[i].freq_hz, g, Speed::from_rpm(top), w);
                                (d.clone(), json!({ "backward_hz": at(Whirl::Backward), "forward_hz": at(Whirl::Forward) }))
                            })
                            .collect()
                    })
                    .unwrap_or_default();
                // The whirls part by g Ω/2 for small e: Hz per 1000 rpm.
                json!({ "mode_index": i, "gyro_ratio": g, "rate_hz_per_1000_rpm": g * 1000.0 / 60.0 / 2.0, "whirls_at_fastest_measured": whirls })
            })
            .collect();
        let mut m = Map::new();
        m.insert("fastest_measured_rpm".into(), json!(top));
        m.insert("modes".into(), Json::Array(modes));
        m
    }
}

/// A resonance of the machine structure seen at the holder base, hence in every tool's FRF:
/// one more mode in the spindle receptance of one direction, stated modally (frequency,
/// modal stiffness, damping ratio), sought where the largest discrepancy is and within the
/// band of the spindle's own modes (a discrepancy above them is the tool's or the sensor's).
pub struct MachineResonance;

impl MachineResonance {
    fn names(d: &str) -> [String; 3] {
        [format!("machine_{d}_f"), format!("machine_{d}_k"), format!("machine_{d}_zeta")]
    }
}

impl Effect for MachineResonance {
    fn name(&self) -> &'static str {
        "machine_resonance"
    }
    fn scope(&self) -> Scope {
        Scope::Structure
    }
    fn description(&self) -> &'static str {
        "a resonance of the machine structure at the holder base, one more mode of the spindle receptance along one direction; measured and cutting"
    }
    fn apply(&self, roles: &Roles, c: &Compiled, r: &mut RecipeText) -> Result<Vec<Free>, NotApplicable> {
        let (machine, spindle) = coupled_spindle(roles, c)?;
        let (d, [lo, hi]) = roles.discrepancy.clone().ok_or("every measurement is at the floor")?;
        let freqs: Vec<f64> =
            spindle.modes.iter().filter(|(dir, _)| *dir == d).flat_map(|(_, m)| m.iter().map(|m| m.freq_hz)).collect();
        let (low, top) =
            (freqs.iter().copied().fold(f64::INFINITY, f64::min), freqs.iter().copied().fold(0.0, f64::max));
        if freqs.is_empty() || top <= 0.0 {
            return Err(format!("the spindle has no modes along {d}"));
        }
        // The machine is seen through the spindle: its resonance is sought over the spindle's
        // band along that direction (from a quarter of its lowest mode to its highest), not
        // only where the discrepancy peaks, since the coupled tool mode it moves may peak
        // higher; it starts there when the discrepancy lies within the band.
        let band = [0.25 * low, top];
        let start = (0.5 * (lo + hi)).clamp(band[0], band[1]);
        let [nf, nk, nz] = Self::names(&d);
        let free = vec![
            Free::lin(&nf, "Hz", start, band[0], band[1]),
            Free::log(&nk, "N/m", 1e10, 1e6, 1e11),
            Free::log(&nz, "", 0.03, 0.005, 0.2),
        ];
        r.push_item(
            &path(&["machines", machine, "spindle", "modes", &d]),
            &Raw::mapping([("f", Raw::param(&nf)), ("stiffness", Raw::param(&nk)), ("zeta", Raw::param(&nz))]),
        )
        .map_err(e)?;
        declare(r, &free)?;
        Ok(free)
    }
    /// A narrow peak anywhere in the spindle's band: a dense scan of the box.
    fn starts(&self, free: &[Free]) -> usize {
        32 * free.len()
    }
    /// The direction the values name (`machine_x_f`), at the frequency they give.
    fn place(&self, values: &[(&str, f64)], roles: &mut Roles) {
        for (n, v) in values {
            if let Some(d) = n.strip_prefix("machine_").and_then(|r| r.strip_suffix("_f")) {
                roles.discrepancy = Some((d.to_string(), [0.5 * v, 1.5 * v]));
            }
        }
    }
    fn report(&self, values: &[(String, f64)], _roles: &Roles, _c: &Compiled) -> Map<String, Json> {
        let mut m = Map::new();
        let Some((n, _)) = values.iter().find(|(n, _)| n.starts_with("machine_") && n.ends_with("_f")) else {
            return m;
        };
        let d = n.trim_start_matches("machine_").trim_end_matches("_f");
        let [nf, nk, nz] = Self::names(d);
        m.insert("direction".into(), json!(d));
        m.insert("f_hz".into(), json!(value(values, &nf)));
        m.insert("stiffness_n_per_m".into(), json!(value(values, &nk)));
        m.insert("zeta".into(), json!(value(values, &nz)));
        m
    }
}

/// Cutting coefficients that change linearly with speed about the calibration speed
/// (§6.2): the trials move, the FRFs do not.
pub struct SpeedDependentCuttingCoefficients;

impl Effect for SpeedDependentCuttingCoefficients {
    fn name(&self) -> &'static str {
        "speed_dependent_cutting_coefficients"
    }
    fn scope(&self) -> Scope {
        Scope::Cutting
    }
    fn description(&self) -> &'static str {
        "cutting coefficients changing linearly with speed about the calibration speed, Ks(n) = Ks (1 + a Δn), β(n) = β + b Δn; trials only"
    }
    fn apply(&self, roles: &Roles, c: &Compiled, r: &mut RecipeText) -> Result<Vec<Free>, NotApplicable> {
        let cutting = roles.cutting.as_ref().ok_or("no stability diagram is scored against trials")?;
        if roles.trials.is_none() {
            return Err("no cutting trials are scored".into());
        }
        if c.recipe.cutting.get(cutting).is_some_and(|c| c.calibrated_at.is_none()) {
            return Err(format!("cutting `{cutting}` states no `calibrated_at` speed to hold the law about"));
        }
        // Per 10000 rpm: Ks within ±60 %, β within ±15°.
        let free = vec![
            Free::lin("cutting_ks_change", "", 0.0, -0.6, 0.6),
            Free::lin("cutting_beta_change", "deg", 0.0, -15.0, 15.0),
        ];
        let p = path(&["cutting", cutting]);
        r.set_key(&p, "change_per", &Raw::text("10000 rpm")).map_err(e)?;
        r.set_key(&p, "beta_change", &Raw::param("cutting_beta_change")).map_err(e)?;
        r.set_key(&p, "Ks_change", &Raw::param("cutting_ks_change")).map_err(e)?;
        declare(r, &free)?;
        Ok(free)
    }
    /// The trials' likelihood is nearly flat in the coefficients' speed law away from the
    /// trials (a trial counts most as it crosses the boundary): a scan of the plane finds
    /// the well. Four times as many samples found the same ends on every case tried.
    fn starts(&self, free: &[Free]) -> usize {
        8 * free.len()
    }
    /// A change of Ks and one of β move the boundary alike at most speeds, so the trials
    /// often fix the law's effect on the lobes better than its split: Ks alone is the
    /// simpler law, named when the split is not resolved.
    fn nested(&self) -> Vec<Vec<&'static str>> {
        vec![vec!["cutting_beta_change"]]
    }
    fn report(&self, values: &[(String, f64)], roles: &Roles, c: &Compiled) -> Map<String, Json> {
        let reference = roles
            .cutting
            .as_ref()
            .and_then(|n| c.recipe.cutting.get(n))
            .and_then(|c| c.calibrated_at)
            .map_or(f64::NAN, Speed::rpm);
        let mut m = Map::new();
        m.insert("reference_rpm".into(), json!(reference));
        m.insert("ks_relative_change_per_10000_rpm".into(), json!(value(values, "cutting_ks_change")));
        m.insert("beta_change_deg_per_10000_rpm".into(), json!(value(values, "cutting_beta_change")));
        m
    }
}
