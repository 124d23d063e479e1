//! Entity field tables and the typed entities built from them: materials, machines,
//! tool/holder assemblies of Timoshenko sections, sensors and cutting setups.
//!
//! Together they say everything a lab's case description holds: sections, joints,
//! spindle modes with speed laws, sensor mass and the cutting setup.

use crate::spec::{EntityKind, Field, FieldType as T, Params};
use spindlelab_grammar::Dimension as D;

pub use spindlelab_domain::entity::{
    Assembly, Component, Cutting, Entities, Joint, Machine, Material, Section, Sensor, Spindle, SpindleMode,
};

const RATIO: T = T::Quantity(D::DIMENSIONLESS);

pub const MATERIAL: &[Field] = &[
    Field::req("E", T::Quantity(D::PRESSURE), "Young's modulus"),
    Field::req("rho", T::Quantity(D::DENSITY), "density"),
    Field::opt(
        "nu",
        RATIO,
        "Poisson's ratio: needed by Timoshenko sections (shear) and by contact; Euler–Bernoulli spindle modes do without",
    ),
    Field::def("eta", RATIO, "0", "structural loss factor of the complex modulus E(1 + i eta)"),
];

pub const JOINT: &[Field] = &[
    Field::def("rigid", T::Bool, "false", "a rigid joint (no interface compliance)"),
    Field::opt("kt", T::Quantity(D::STIFFNESS), "translational stiffness"),
    Field::def("ct", T::Quantity(D::DAMPING), "0 N*s/m", "translational viscous damping"),
    Field::opt("kr", T::Quantity(D::ROTATIONAL_STIFFNESS), "rotational stiffness"),
    Field::def("cr", T::Quantity(D::ROTATIONAL_DAMPING), "0 N*m*s/rad", "rotational viscous damping"),
];

pub const SPINDLE_MODE: &[Field] = &[
    Field::req("f", T::Quantity(D::FREQUENCY), "natural frequency of the equivalent fixed-free beam at rest"),
    Field::opt("d", T::Quantity(D::LENGTH), "diameter of the equivalent fixed-free beam (with `eta`)"),
    Field::opt("eta", RATIO, "structural loss factor (with `d`)"),
    Field::opt(
        "stiffness",
        T::Quantity(D::STIFFNESS),
        "modal stiffness at the spindle nose, for a mode stated modally (with `zeta`, instead of `d` and `eta`)",
    ),
    Field::opt("zeta", RATIO, "viscous damping ratio ζ of a mode stated modally (with `stiffness`)"),
    Field::def("kf", RATIO, "0", "speed law: f(n) = f (1 + kf (n/ref_speed)^2)"),
    Field::def("keta", RATIO, "0", "speed law: eta(n) = eta (1 + keta (n/ref_speed)^2)"),
    Field::opt(
        "kk",
        RATIO,
        "bearing stiffness over speed: k(n) = k (1 + kk (n/ref_speed)^p) at the mode's mass (f with its root); default 0",
    ),
    Field::opt(
        "kk_exponent",
        RATIO,
        "exponent p of the bearing law with `kk`; default 2 (preloaded angular-contact bearings soften faster at high speed: a law fitted over three speeds may take more)",
    ),
    Field::opt(
        "gyro",
        RATIO,
        "gyroscopic coefficient g = I_p/I_d of the rotor in this mode: at spin Ω it whirls forward and backward at ω(√(1+e²) ± e), e = gΩ/(2ω); wire spindle.receptance's `cross` into rcsa.couple's `spindle_cross` to couple each whirl; default 0",
    ),
];

const MODE_LIST: T = T::ObjectList(SPINDLE_MODE);

pub const SPINDLE: &[Field] = &[
    Field::req("material", T::Entity(EntityKind::Material), "material of the equivalent beams"),
    Field::def("ref_speed", T::Quantity(D::ROTATIONAL_SPEED), "10000 rpm", "reference speed of the speed law"),
    Field::req("modes", T::MapOf(&MODE_LIST), "equivalent Euler–Bernoulli modes per direction (x, y)"),
];

pub const MACHINE: &[Field] = &[
    Field::def("directions", T::ChoiceList(&["x", "y"]), "[x, y]", "measured directions"),
    Field::opt("speeds", T::QuantityList(D::ROTATIONAL_SPEED), "spindle speeds of interest"),
    Field::opt("max_speed", T::Quantity(D::ROTATIONAL_SPEED), "highest spindle speed"),
    Field::opt("spindle", T::Object(SPINDLE), "spindle-machine receptance at the holder base as modes"),
    Field::opt("holder_interface", T::Object(JOINT), "spindle–holder joint"),
];

pub const SECTION: &[Field] = &[
    Field::req("name", T::Text, "section name"),
    Field::req("component", T::Choice(&["holder", "holder+tool", "tool"]), "which part the section belongs to"),
    Field::def("kind", T::Choice(&["plain", "fluted"]), "plain", "plain or fluted"),
    Field::req("d_out", T::Quantity(D::LENGTH), "outer diameter at the spindle end"),
    Field::opt("d_out_tip", T::Quantity(D::LENGTH), "outer diameter at the tip end (linear taper); default d_out"),
    Field::def("d_in", T::Quantity(D::LENGTH), "0 m", "inner (bore) diameter"),
    Field::req("length", T::Quantity(D::LENGTH), "section length"),
    Field::req("outer", T::Entity(EntityKind::Material), "material of the outer tube"),
    Field::opt("inner", T::Entity(EntityKind::Material), "material of a core filling the bore (composite section)"),
    Field::opt("d_equivalent", T::Quantity(D::LENGTH), "equivalent diameter of a fluted section"),
];

pub const ASSEMBLY: &[Field] = &[
    Field::req("sections", T::ObjectList(SECTION), "sections from the spindle end to the tip"),
    Field::opt("tool_joint", T::Object(JOINT), "holder–tool joint at the holder face"),
];

pub const SENSOR: &[Field] = &[
    Field::req(
        "kind",
        T::Choice(&["capacitance_probe", "laser_vibrometer", "accelerometer", "force_sensor"]),
        "sensor type",
    ),
    Field::def(
        "phase_slope",
        T::Quantity(D::PHASE_SLOPE),
        "0 deg/kHz",
        "phase lag slope of the measuring chain (Eq. 2.11)",
    ),
    Field::def("mass", T::Quantity(D::MASS), "0 kg", "mass added at the measurement point"),
    Field::def("location", T::Text, "tool tip", "where the sensor measures"),
    Field::opt("noise", T::Quantity(D::DIMENSIONLESS), "noise level relative to the signal"),
];

pub const CUTTING: &[Field] = &[
    Field::req("teeth", T::Integer { min: 1, max: 64 }, "number of teeth"),
    Field::req("radial_immersion", RATIO, "radial depth over tool diameter (0, 1]"),
    Field::req("milling", T::Choice(&["up", "down"]), "up- or down-milling"),
    Field::opt("Ks", T::Quantity(D::PRESSURE), "specific cutting force; Kt = Ks sin(beta), Kn = Ks cos(beta)"),
    Field::opt("beta", T::Quantity(D::ANGLE), "force angle"),
    Field::opt("Kt", T::Quantity(D::PRESSURE), "tangential coefficient"),
    Field::opt("Kn", T::Quantity(D::PRESSURE), "normal coefficient"),
    Field::opt("calibrated_at", T::Quantity(D::ROTATIONAL_SPEED), "speed at which the coefficients were calibrated"),
    Field::def("Ks_change", RATIO, "0", "speed law: Ks(n) = Ks (1 + Ks_change (n - calibrated_at)/change_per)"),
    Field::def(
        "beta_change",
        T::Quantity(D::ANGLE),
        "0 deg",
        "speed law: beta(n) = beta + beta_change (n - calibrated_at)/change_per",
    ),
    Field::def(
        "change_per",
        T::Quantity(D::ROTATIONAL_SPEED),
        "10000 rpm",
        "speed step of the `Ks_change` and `beta_change` law",
    ),
    Field::opt("feed_per_tooth", T::Quantity(D::LENGTH), "feed per tooth"),
    Field::opt("workpiece", T::Text, "workpiece material"),
    Field::opt("trial_speeds", T::QuantityList(D::ROTATIONAL_SPEED), "speed range of cutting trials"),
];

/// The field table of an entity kind.
pub fn fields(kind: EntityKind) -> &'static [Field] {
    match kind {
        EntityKind::Material => MATERIAL,
        EntityKind::Machine => MACHINE,
        EntityKind::Assembly => ASSEMBLY,
        EntityKind::Sensor => SENSOR,
        EntityKind::Cutting => CUTTING,
    }
}

/// The material a checked `materials:` entry describes.
pub fn material(p: &Params) -> Material {
    Material {
        youngs_modulus: p.f64("E").unwrap_or(f64::NAN),
        density: p.f64("rho").unwrap_or(f64::NAN),
        poisson: p.f64("nu").unwrap_or(f64::NAN),
        loss_factor: p.f64("eta").unwrap_or(0.0),
    }
}

/// The joint a checked `holder_interface:` or `tool_joint:` object describes: rigid, or
/// compliant with an unset stiffness infinite and an unset damping zero.
pub fn joint(p: &Params) -> Joint {
    if p.bool("rigid").unwrap_or(false) {
        return Joint::Rigid;
    }
    Joint::Compliant {
        kt: p.f64("kt").unwrap_or(f64::INFINITY),
        ct: p.f64("ct").unwrap_or(0.0),
        kr: p.f64("kr").unwrap_or(f64::INFINITY),
        cr: p.f64("cr").unwrap_or(0.0),
    }
}
