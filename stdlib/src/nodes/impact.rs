//! `impact.simulate`: the Hertz hammer–target model of dissertation §2.1 as a recipe node.

use crate::impact::{
    Contact, Hammer, ImpactError, ImpactSetup, ModalTarget, SensorNoise, Sphere, Table21Target, first_contact,
    simulate, table_2_1_target,
};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::{EntityKind, Field, FieldType as T, Params};
use spindlelab_engine::value::{Channel, PortType, Scalar, TimeSeries, UnitLabel, Value};
use spindlelab_grammar::Dimension as D;

const TARGET_MODE: &[Field] = &[
    Field::req("mass", T::Quantity(D::MASS), "modal mass"),
    Field::req("stiffness", T::Quantity(D::STIFFNESS), "modal stiffness"),
    Field::def("damping", T::Quantity(D::DAMPING), "0 N*s/m", "modal viscous damping"),
];

node_params! {
    /// Parameters of `impact.simulate`.
    pub struct ImpactSimulateParams<'a> {
        hammer_mass: req f64 = (T::Quantity(D::MASS), "hammer mass M_h"),
        hammer_stiffness: def f64 = (T::Quantity(D::STIFFNESS), "100 N/m", "hammer spring K_h"),
        hammer_damping: def f64 = (T::Quantity(D::DAMPING), "0 N*s/m", "hammer damping C_h"),
        target_mass: opt f64 = (T::Quantity(D::MASS), "single-DOF target mass M_t"),
        target_stiffness: opt f64 = (T::Quantity(D::STIFFNESS), "single-DOF target stiffness K_t"),
        target_damping: def f64 = (T::Quantity(D::DAMPING), "0 N*s/m", "single-DOF target damping C_t"),
        target_modes: opt &'a [Params] = (T::ObjectList(TARGET_MODE), "multi-DOF target as modes in modal space"),
        target_preset: opt &'a str = (
            T::Choice(&["table-2.1-target-1", "table-2.1-target-2"]),
            "a 10-mode target of Table 2.1",
        ),
        tip_radius: def f64 = (T::Quantity(D::LENGTH), "6.35 mm", "hammer tip sphere radius r1"),
        target_radius: def f64 = (T::Quantity(D::LENGTH), "1 mm", "target sphere radius r2"),
        tip_material: opt &'a str = (
            T::Entity(EntityKind::Material),
            "hammer tip material (default steel 200 GPa, 0.29)",
        ),
        target_material: opt &'a str = (
            T::Entity(EntityKind::Material),
            "target material (default steel 200 GPa, 0.29)",
        ),
        restitution: def f64 = (
            T::Quantity(D::DIMENSIONLESS),
            "0.95",
            "coefficient of restitution e of Eq. 2.4",
        ),
        release: def f64 = (T::Quantity(D::LENGTH), "10 mm", "hammer position at release X_hi"),
        contact: def f64 = (T::Quantity(D::LENGTH), "-3 mm", "target contact point X_t0"),
        dt: def f64 = (T::Quantity(D::TIME), "1e-8 s", "integration step of Eq. 2.7"),
        duration: def f64 = (T::Quantity(D::TIME), "10 ms", "record length after first contact"),
        pre_trigger: def f64 = (T::Quantity(D::TIME), "0 s", "record kept before first contact"),
        sample_rate: def f64 = (T::Quantity(D::FREQUENCY), "100 kHz", "output sampling rate"),
        noise: def f64 = (
            T::Quantity(D::LENGTH),
            "0 m",
            "standard deviation of sensor noise on the displacement",
        ),
        impacts: def usize = (
            T::Integer { min: 1, max: 1000 },
            "1",
            "records to make, each with its own noise",
        ),
        seed: def u64 = (T::Integer { min: 0, max: i64::MAX }, "0", "noise seed"),
        integrator: def &'a str = (
            T::Choice(&["exact-free-flight", "euler"]),
            "exact-free-flight",
            "free flight between contacts solved exactly, or Eq. 2.7 throughout",
        ),
    }
}

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
                version: 2,
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
                        "first_impulse_time",
                        PortType::Scalar,
                        "the first contact alone (s): the impulse a lab keeps when it rejects a double hit",
                    ),
                    PortSpec::new(
                        "excited_bandwidth",
                        PortType::Scalar,
                        "where the force spectrum first falls 10 dB below DC (Hz), §2.1 (i)",
                    ),
                    PortSpec::new(
                        "first_excited_bandwidth",
                        PortType::Scalar,
                        "the same of the first contact's force alone (Hz)",
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
                params: ImpactSimulateParams::fields(),
            },
        }
    }
}

fn steel() -> (f64, f64) {
    (crate::impact::STEEL_YOUNGS_MODULUS, crate::impact::STEEL_POISSON)
}

fn setup_from(
    p: &ImpactSimulateParams,
    recipe: Option<&spindlelab_engine::model::Entities>,
    spec: &NodeSpec,
) -> Result<ImpactSetup, NodeError> {
    let target = if let Some(preset) = p.target_preset {
        if p.target_modes.is_some() || p.target_mass.is_some() {
            return Err(NodeError::param(
                "target_preset",
                "give one target: a preset, `target_modes`, or `target_mass` with `target_stiffness`",
            ));
        }
        table_2_1_target(if preset.ends_with('1') { Table21Target::Target1 } else { Table21Target::Target2 })
    } else if let Some(modes) = p.target_modes {
        if p.target_mass.is_some() {
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
        match (p.target_mass, p.target_stiffness) {
            (Some(m), Some(k)) => ModalTarget::from_mass_stiffness_damping(&[(m, k, p.target_damping)])
                .map_err(|e| to_node_error(e, spec))?,
            _ => {
                return Err(NodeError::param(
                    "target_mass",
                    "no target: give `target_mass` and `target_stiffness`, `target_modes`, or `target_preset`",
                ));
            }
        }
    };
    let material = |name: Option<&str>| -> (f64, f64) {
        match (name, recipe) {
            (Some(m), Some(r)) => r.materials.get(m).map(|m| (m.youngs_modulus, m.poisson)).unwrap_or_else(steel),
            _ => steel(),
        }
    };
    let (e1, nu1) = material(p.tip_material);
    let (e2, nu2) = material(p.target_material);
    let hammer = Hammer { mass: p.hammer_mass, stiffness: p.hammer_stiffness, damping: p.hammer_damping };
    let mut setup = ImpactSetup::new(hammer, target);
    setup.contact = Contact {
        hammer_tip: Sphere { radius: p.tip_radius, youngs_modulus: e1, poisson: nu1 },
        target: Sphere { radius: p.target_radius, youngs_modulus: e2, poisson: nu2 },
        restitution: p.restitution,
    };
    setup.release_position = p.release;
    setup.contact_position = p.contact;
    setup.dt = p.dt;
    setup.duration = p.duration;
    setup.pre_trigger = p.pre_trigger;
    setup.sample_rate = p.sample_rate;
    setup.exact_free_flight = p.integrator != "euler";
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
        let setup = setup_from(&ImpactSimulateParams::read(params)?, None, &self.spec)?;
        first_contact(&setup).map(|_| ()).map_err(|e| to_node_error(e, &self.spec))
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = ImpactSimulateParams::read(ctx.params)?;
        let mut setup = setup_from(&p, Some(ctx.entities), &self.spec)?;
        let (impacts, noise, seed) = (p.impacts.max(1), p.noise, p.seed);
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
        out.insert("first_impulse_time".into(), scalar(r.first_impulse_time, "s"));
        out.insert("excited_bandwidth".into(), scalar(r.excited_bandwidth, "Hz"));
        out.insert("first_excited_bandwidth".into(), scalar(r.first_excited_bandwidth, "Hz"));
        if r.contact_count() > 1 {
            ctx.warn(format!(
                "double hit: the hammer struck {} times in the record (the last {:.3} ms after the first); a lab rejects such a hit — impulse_time and excited_bandwidth span every contact, first_impulse_time and first_excited_bandwidth the first alone",
                r.contact_count(),
                r.contacts.last().map_or(0.0, |c| c.start) * 1e3
            ));
        }
        out.insert("response_magnitude".into(), scalar(r.response_magnitude, "m"));
        out.insert("peak_force".into(), scalar(r.peak_force, "N"));
        out.insert("contacts".into(), scalar(r.contact_count() as f64, ""));
        Ok(out)
    }
}
