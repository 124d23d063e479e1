//! `impact.simulate`: the Hertz hammer–target model of dissertation §2.1 as a recipe node.

use crate::impact::{
    Contact, Hammer, ImpactError, ImpactSetup, ModalTarget, SensorNoise, Sphere, Table21Target, first_contact,
    simulate, table_2_1_target,
};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::spec::{EntityKind, Field, FieldType as T, Params};
use spindlelab_engine::value::{Channel, PortType, Scalar, TimeSeries, UnitLabel, Value};
use spindlelab_grammar::Dimension as D;

const TARGET_MODE: &[Field] = &[
    Field::req("mass", T::Quantity(D::MASS), "modal mass"),
    Field::req("stiffness", T::Quantity(D::STIFFNESS), "modal stiffness"),
    Field::def("damping", T::Quantity(D::DAMPING), "0 N*s/m", "modal viscous damping"),
];

pub struct ImpactSimulate {
    spec: NodeSpec,
}

impl Default for ImpactSimulate {
    fn default() -> Self {
        Self::new()
    }
}

impl ImpactSimulate {
    pub fn new() -> Self {
        ImpactSimulate {
            spec: NodeSpec {
                kind: "impact.simulate",
                version: 1,
                description: "Hertz hammer–target impact with hysteresis damping (§2.1, Eqs. 2.2–2.7): force, response and figures of merit.",
                inputs: vec![],
                outputs: vec![
                    PortSpec::new("force", PortType::TimeSeries, "contact force, one channel per impact (N)"),
                    PortSpec::new(
                        "displacement",
                        PortType::TimeSeries,
                        "target displacement at the impact point, one channel per impact (m)",
                    ),
                    PortSpec::new("impulse_time", PortType::Scalar, "first to last contact (s), §2.1 (ii)"),
                    PortSpec::new(
                        "excited_bandwidth",
                        PortType::Scalar,
                        "where the force spectrum first falls 10 dB below DC (Hz), §2.1 (i)",
                    ),
                    PortSpec::new(
                        "response_magnitude",
                        PortType::Scalar,
                        "|X| at the target's first natural frequency (m), §2.1 (iii)",
                    ),
                    PortSpec::new("peak_force", PortType::Scalar, "largest contact force (N)"),
                    PortSpec::new(
                        "contacts",
                        PortType::Scalar,
                        "number of separate contacts (2 or more is a double hit)",
                    ),
                ],
                params: vec![
                    Field::req("hammer_mass", T::Quantity(D::MASS), "hammer mass M_h"),
                    Field::def("hammer_stiffness", T::Quantity(D::STIFFNESS), "100 N/m", "hammer spring K_h"),
                    Field::def("hammer_damping", T::Quantity(D::DAMPING), "0 N*s/m", "hammer damping C_h"),
                    Field::opt("target_mass", T::Quantity(D::MASS), "single-DOF target mass M_t"),
                    Field::opt("target_stiffness", T::Quantity(D::STIFFNESS), "single-DOF target stiffness K_t"),
                    Field::def("target_damping", T::Quantity(D::DAMPING), "0 N*s/m", "single-DOF target damping C_t"),
                    Field::opt("target_modes", T::ObjectList(TARGET_MODE), "multi-DOF target as modes in modal space"),
                    Field::opt(
                        "target_preset",
                        T::Choice(&["table-2.1-target-1", "table-2.1-target-2"]),
                        "a 10-mode target of Table 2.1",
                    ),
                    Field::def("tip_radius", T::Quantity(D::LENGTH), "6.35 mm", "hammer tip sphere radius r1"),
                    Field::def("target_radius", T::Quantity(D::LENGTH), "1 mm", "target sphere radius r2"),
                    Field::opt(
                        "tip_material",
                        T::Entity(EntityKind::Material),
                        "hammer tip material (default steel 200 GPa, 0.29)",
                    ),
                    Field::opt(
                        "target_material",
                        T::Entity(EntityKind::Material),
                        "target material (default steel 200 GPa, 0.29)",
                    ),
                    Field::def(
                        "restitution",
                        T::Quantity(D::DIMENSIONLESS),
                        "0.95",
                        "coefficient of restitution e of Eq. 2.4",
                    ),
                    Field::def("release", T::Quantity(D::LENGTH), "10 mm", "hammer position at release X_hi"),
                    Field::def("contact", T::Quantity(D::LENGTH), "-3 mm", "target contact point X_t0"),
                    Field::def("dt", T::Quantity(D::TIME), "1e-8 s", "integration step of Eq. 2.7"),
                    Field::def("duration", T::Quantity(D::TIME), "10 ms", "record length after first contact"),
                    Field::def("pre_trigger", T::Quantity(D::TIME), "0 s", "record kept before first contact"),
                    Field::def("sample_rate", T::Quantity(D::FREQUENCY), "100 kHz", "output sampling rate"),
                    Field::def(
                        "noise",
                        T::Quantity(D::LENGTH),
                        "0 m",
                        "standard deviation of sensor noise on the displacement",
                    ),
                    Field::def(
                        "impacts",
                        T::Integer { min: 1, max: 1000 },
                        "1",
                        "records to make, each with its own noise",
                    ),
                    Field::def("seed", T::Integer { min: 0, max: i64::MAX }, "0", "noise seed"),
                    Field::def(
                        "integrator",
                        T::Choice(&["exact-free-flight", "euler"]),
                        "exact-free-flight",
                        "free flight between contacts solved exactly, or Eq. 2.7 throughout",
                    ),
                ],
            },
        }
    }
}

fn steel() -> (f64, f64) {
    (crate::impact::STEEL_YOUNGS_MODULUS, crate::impact::STEEL_POISSON)
}

fn setup_from(
    params: &Params,
    recipe: Option<&spindlelab_engine::model::Recipe>,
    spec: &NodeSpec,
) -> Result<ImpactSetup, NodeError> {
    let f = |n: &str| params.f64(n).unwrap_or(f64::NAN);
    let target = if let Some(preset) = params.text("target_preset") {
        if params.get("target_modes").is_some() || params.get("target_mass").is_some() {
            return Err(NodeError::param(
                "target_preset",
                "give one target: a preset, `target_modes`, or `target_mass` with `target_stiffness`",
            ));
        }
        table_2_1_target(if preset.ends_with('1') { Table21Target::Target1 } else { Table21Target::Target2 })
    } else if let Some(modes) = params.objects("target_modes") {
        if params.get("target_mass").is_some() {
            return Err(NodeError::param("target_modes", "give either `target_modes` or `target_mass`, not both"));
        }
        let rows: Vec<(f64, f64, f64)> = modes
            .iter()
            .map(|m| {
                (
                    m.f64("mass").unwrap_or(f64::NAN),
                    m.f64("stiffness").unwrap_or(f64::NAN),
                    m.f64("damping").unwrap_or(0.0),
                )
            })
            .collect();
        ModalTarget::from_mass_stiffness_damping(&rows).map_err(|e| NodeError::param("target_modes", e.to_string()))?
    } else {
        match (params.f64("target_mass"), params.f64("target_stiffness")) {
            (Some(m), Some(k)) => ModalTarget::from_mass_stiffness_damping(&[(m, k, f("target_damping"))])
                .map_err(|e| to_node_error(e, spec))?,
            _ => {
                return Err(NodeError::param(
                    "target_mass",
                    "no target: give `target_mass` and `target_stiffness`, `target_modes`, or `target_preset`",
                ));
            }
        }
    };
    let material = |name: &str| -> (f64, f64) {
        match (params.text(name), recipe) {
            (Some(m), Some(r)) => r.materials.get(m).map(|m| (m.youngs_modulus, m.poisson)).unwrap_or_else(steel),
            _ => steel(),
        }
    };
    let (e1, nu1) = material("tip_material");
    let (e2, nu2) = material("target_material");
    let hammer = Hammer { mass: f("hammer_mass"), stiffness: f("hammer_stiffness"), damping: f("hammer_damping") };
    let mut setup = ImpactSetup::new(hammer, target);
    setup.contact = Contact {
        hammer_tip: Sphere { radius: f("tip_radius"), youngs_modulus: e1, poisson: nu1 },
        target: Sphere { radius: f("target_radius"), youngs_modulus: e2, poisson: nu2 },
        restitution: f("restitution"),
    };
    setup.release_position = f("release");
    setup.contact_position = f("contact");
    setup.dt = f("dt");
    setup.duration = f("duration");
    setup.pre_trigger = f("pre_trigger");
    setup.sample_rate = f("sample_rate");
    setup.exact_free_flight = params.text("integrator") != Some("euler");
    Ok(setup)
}

/// Maps a simulation error to the recipe parameter a user would change, in recipe terms.
fn to_node_error(e: ImpactError, spec: &NodeSpec) -> NodeError {
    match &e {
        ImpactError::InvalidParameter { name, field, value, requirement } => {
            let param = match (*name, *field) {
                ("hammer", f) => format!("hammer_{f}"),
                ("target mode", "mass") => "target_mass".into(),
                ("target mode", "stiffness") => "target_stiffness".into(),
                ("target mode", "damping") => "target_damping".into(),
                ("contact", "restitution") => "restitution".into(),
                ("contact.hammer_tip", "radius") => "tip_radius".into(),
                ("contact.target", "radius") => "target_radius".into(),
                ("setup", "release_position") => "release".into(),
                ("setup", "contact_position") => "contact".into(),
                ("setup", f) => f.to_string(),
                ("noise", _) => "noise".into(),
                (n, f) => format!("{n}.{f}"),
            };
            let unit = match spec.param(&param).map(|f| f.ty) {
                Some(T::Quantity(d)) if d != D::DIMENSIONLESS => format!(" {}", d.si_unit()),
                _ => String::new(),
            };
            let requirement =
                requirement.replace("release_position", "`release`").replace("contact_position", "`contact`");
            NodeError::param(&param, format!("{value}{unit} {requirement}"))
        }
        ImpactError::NoContact => {
            NodeError::param("release", "the hammer never reaches the target: move `release` or `contact`")
        }
        ImpactError::TooManySteps { .. } => NodeError::param("dt", format!("{e}: raise `dt` or shorten `duration`")),
        ImpactError::EmptyTarget => NodeError::param("target_modes", e.to_string()),
    }
}

fn scalar(v: f64, unit: &str) -> Value {
    Value::Scalar(Scalar::new(v, unit))
}

impl Node for ImpactSimulate {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn validate(&self, params: &Params) -> Result<(), NodeError> {
        // The closed-form approach phase checks every parameter and that contact happens.
        let setup = setup_from(params, None, &self.spec)?;
        first_contact(&setup).map(|_| ()).map_err(|e| to_node_error(e, &self.spec))
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let mut setup = setup_from(ctx.params, Some(ctx.recipe), &self.spec)?;
        let impacts = ctx.params.int("impacts").unwrap_or(1).max(1) as usize;
        let noise = ctx.params.f64("noise").unwrap_or(0.0);
        let seed = ctx.params.int("seed").unwrap_or(0) as u64;
        let mut forces = Vec::with_capacity(impacts);
        let mut disps = Vec::with_capacity(impacts);
        let mut first = None;
        for k in 0..impacts {
            setup.noise = (noise > 0.0).then_some(SensorNoise { std_dev: noise, seed: seed.wrapping_add(k as u64) });
            let r = simulate(&setup).map_err(|e| to_node_error(e, &self.spec))?;
            let name = |base: &str| if impacts == 1 { base.to_string() } else { format!("{base}_{}", k + 1) };
            forces.push(Channel { name: name("force"), unit: UnitLabel::new("N"), samples: r.force.clone() });
            disps.push(Channel {
                name: name("displacement"),
                unit: UnitLabel::new("m"),
                samples: r.target_displacement.clone(),
            });
            if first.is_none() {
                first = Some(r);
            }
        }
        let r = first.expect("at least one impact");
        let t0 = -(r.first_contact_index as f64) / r.sample_rate;
        let series = |channels| Value::TimeSeries(TimeSeries { sample_rate: r.sample_rate, t0, channels });
        let mut out = Outputs::new();
        out.insert("force".into(), series(forces));
        out.insert("displacement".into(), series(disps));
        out.insert("impulse_time".into(), scalar(r.impulse_time, "s"));
        out.insert("excited_bandwidth".into(), scalar(r.excited_bandwidth, "Hz"));
        out.insert("response_magnitude".into(), scalar(r.response_magnitude, "m"));
        out.insert("peak_force".into(), scalar(r.peak_force, "N"));
        out.insert("contacts".into(), scalar(r.contact_count() as f64, ""));
        Ok(out)
    }
}
