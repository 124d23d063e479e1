use super::*;

/// ROSS's steel (E = 211 GPa, G = 81.2 GPa, ρ = 7810 kg/m³), ν = E/2G − 1.
fn ross_steel() -> Material {
    Material { youngs_modulus: 211e9, density: 7810.0, poisson: 211e9 / (2.0 * 81.2e9) - 1.0, loss_factor: 0.0 }
}

/// ROSS's `rotor3` = Friswell et al. Example 5.9.1.
fn rotor3() -> Rotor {
    let steel = ross_steel();
    Rotor {
        sections: vec![ShaftSection {
            length_m: 1.5,
            inner_diameter_m: 0.0,
            outer_diameter_m: 0.05,
            elements: 6,
            material: steel,
        }],
        disks: vec![
            Disk::from_geometry(2, steel.density, 0.07, 0.05, 0.28),
            Disk::from_geometry(4, steel.density, 0.07, 0.05, 0.35),
        ],
        bearings: vec![Bearing::new(0, 1e6, 0.8e6, 0.0, 0.0), Bearing::new(6, 1e6, 0.8e6, 0.0, 0.0)],
    }
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// ROSS `test_campbell(rotor4)` (rotor4 = rotor3 built from sections): damped natural
/// frequencies, rad/s, at 0, 150 and 300 rad/s, with ROSS's torsional mode (650.40786626,
/// constant) removed since this model has no torsional dof; sorted.
const ROSS_CAMPBELL: [[f64; 5]; 3] = [
    [82.65303734, 86.65811435, 254.52047828, 274.31285391, 679.48903239],
    [82.60929602, 86.68625235, 251.70037114, 276.87787937, 652.85679897],
    [82.48132723, 86.76734307, 245.49092844, 282.33294699, 614.05536277],
];

#[test]
fn example_5_9_1_matches_ross_campbell() {
    let table = rotor3().campbell(&[0.0, 150.0, 300.0], 5).unwrap();
    let mut worst: f64 = 0.0;
    for (row, want) in table.iter().zip(&ROSS_CAMPBELL) {
        assert_eq!(row.modes.len(), 5);
        for (m, &w) in row.modes.iter().zip(want) {
            let e = rel(m.wd_rad_s, w);
            worst = worst.max(e);
            assert!(e < 1e-5, "speed {}: {} vs ROSS {w} (rel {e:e})", row.speed_rad_s, m.wd_rad_s);
            // Undamped: wn = wd, zero damping ratio (to the eigen-solver's rounding).
            assert!(rel(m.wn_rad_s, m.wd_rad_s) < 1e-9 && m.damping_ratio.abs() < 1e-6, "{}", m.damping_ratio);
        }
    }
    assert!(worst < 1e-5, "{worst:e}");
}

#[test]
fn example_5_9_1_torsional_mode_matches_ross() {
    // The speed-independent 650.40786626 rad/s of ROSS's table is rotor4's first torsional mode.
    let w = rotor3().torsional_frequencies().unwrap();
    assert_eq!(w.len(), 6);
    assert!(rel(w[0], 650.40786626) < 1e-6, "{} (rel {:e})", w[0], rel(w[0], 650.40786626));
}

#[test]
fn example_5_9_1_kappa_matches_ross() {
    // ROSS `test_kappa_rotor3`: node 0, modes 0 and 1.
    let r = rotor3();
    let rest = r.modes_at(0.0).unwrap();
    assert!(rel(rest[0].wd_rad_s, 82.653037) < 1e-6);
    assert!(rest[0].kappa[0].abs() < 1e-6, "straight orbit at rest: {}", rest[0].kappa[0]);
    let fast = r.modes_at(2000.0).unwrap();
    assert!(rel(fast[0].wd_rad_s, 77.37957042) < 1e-6, "{}", fast[0].wd_rad_s);
    assert!(rel(fast[0].kappa[0], -0.6148843693807821) < 1e-5, "{}", fast[0].kappa[0]);
    assert_eq!(fast[0].whirl, Whirl::Backward);
    assert!(rel(fast[1].wd_rad_s, 88.98733511566752) < 1e-6, "{}", fast[1].wd_rad_s);
    assert!(rel(fast[1].kappa[0], 0.8456866641084784) < 1e-5, "{}", fast[1].kappa[0]);
    assert!(rel(fast[1].kappa[1], 0.7597878964314968) < 1e-5, "{}", fast[1].kappa[1]);
    assert_eq!(fast[1].whirl, Whirl::Forward);
    // ROSS `test_kappa_mode_rotor3`: mode 0's kappa along the shaft.
    let want = [-0.614884, -0.696056, -0.723983, -0.729245, -0.708471, -0.656976, -0.513044];
    for (k, w) in fast[0].kappa.iter().zip(want) {
        assert!(rel(*k, w) < 1e-5, "{k} vs {w}");
    }
}

#[test]
fn whirls_split_with_speed_backward_down_forward_up() {
    let table = rotor3().campbell(&[0.0, 150.0, 300.0], 6).unwrap();
    let whirls: Vec<Whirl> = table[1].modes.iter().map(|m| m.whirl).collect();
    use Whirl::{Backward as B, Forward as F};
    assert_eq!(whirls, [B, F, B, F, B, F]);
    for pair in 0..3 {
        let (b, f) = (2 * pair, 2 * pair + 1);
        let at = |row: usize, i: usize| table[row].modes[i].wd_rad_s;
        assert!(at(2, b) < at(1, b) && at(1, b) < at(0, b), "backward {pair}");
        assert!(at(2, f) > at(1, f) && at(1, f) > at(0, f), "forward {pair}");
        assert_eq!(table[2].modes[b].whirl, B);
        assert_eq!(table[2].modes[f].whirl, F);
    }
    // At rest with anisotropic bearings the orbits are straight lines: no sense.
    assert!(table[0].modes.iter().all(|m| m.whirl == Whirl::Mixed));
}

#[test]
fn disk_from_geometry_matches_ross() {
    // ROSS DiskElement docstring: DiskElement(0, 32.58972765, 0.17808928, 0.32956362).
    let d = Disk::from_geometry(2, 7810.0, 0.07, 0.05, 0.28);
    assert!(rel(d.mass_kg, 32.58972765) < 1e-8);
    assert!(rel(d.diametral_inertia, 0.17808928) < 1e-7);
    assert!(rel(d.polar_inertia, 0.32956362) < 1e-7);
}

#[test]
fn matrices_are_symmetric_and_gyroscopic_skew() {
    let model = rotor3().assemble().unwrap();
    let n = model.n_dof();
    assert_eq!(n, 28);
    let (m, k, g) = (model.mass(), model.stiffness(), model.gyroscopic());
    for i in 0..n {
        for j in 0..n {
            assert!((m[i * n + j] - m[j * n + i]).abs() < 1e-12 * m[0]);
            assert!((k[i * n + j] - k[j * n + i]).abs() < 1e-9 * k[0]);
            assert!((g[i * n + j] + g[j * n + i]).abs() < 1e-15);
        }
    }
    // Rigid translation in x stores the total mass: shaft ρAL plus both disks.
    let total: f64 = (0..n).step_by(4).map(|i| (0..n).step_by(4).map(|j| m[i * n + j]).sum::<f64>()).sum();
    let r = rotor3();
    let want = 7810.0 * PI * 0.05 * 0.05 / 4.0 * 1.5 + r.disks.iter().map(|d| d.mass_kg).sum::<f64>();
    assert!(rel(total, want) < 1e-12, "{total} vs {want}");
    assert_eq!(model.node_positions().len(), 7);
    assert!(rel(model.node_positions()[6], 1.5) < 1e-12);
}

#[test]
fn pinned_pinned_shaft_matches_euler_bernoulli() {
    // Slender (L/d = 100) uniform shaft on very stiff isotropic supports, at rest:
    // ω_n = (nπ/L)² √(EI/ρA); shear and rotary inertia lower it by well under 0.5 % for n <= 3.
    let steel = ross_steel();
    let (d, l) = (0.01, 1.0);
    let rotor = Rotor {
        sections: vec![ShaftSection {
            length_m: l,
            inner_diameter_m: 0.0,
            outer_diameter_m: d,
            elements: 40,
            material: steel,
        }],
        disks: vec![],
        bearings: vec![Bearing::new(0, 1e10, 1e10, 0.0, 0.0), Bearing::new(40, 1e10, 1e10, 0.0, 0.0)],
    };
    let modes = rotor.modes_at(0.0).unwrap();
    let (area, inertia) = (PI * d * d / 4.0, PI * d.powi(4) / 64.0);
    let c = (steel.youngs_modulus * inertia / (steel.density * area)).sqrt();
    for nmode in 1..=3 {
        let want = (nmode as f64 * PI / l).powi(2) * c;
        // Isotropic supports: each frequency twice (the two planes).
        for m in &modes[2 * (nmode - 1)..2 * nmode] {
            let e = rel(m.wn_rad_s, want);
            assert!(e < 5e-3, "mode {nmode}: {} vs {want} (rel {e:e})", m.wn_rad_s);
        }
    }
}

fn damped_rotor3() -> Rotor {
    let mut r = rotor3();
    for b in &mut r.bearings {
        b.cxx = 20.0;
        b.cyy = 20.0;
    }
    r
}

#[test]
fn receptance_peaks_sit_at_the_modes() {
    let r = damped_rotor3();
    let model = r.assemble().unwrap();
    let modes = model.modes_at(0.0).unwrap();
    for m in &modes[..4] {
        assert!(m.damping_ratio > 0.0 && m.damping_ratio < 0.01, "{}", m.damping_ratio);
        let f0 = m.freq_hz();
        let freqs: Vec<f64> = (-300..=300).map(|i| f0 * (1.0 + 1e-4 * i as f64)).collect();
        let hx = model.receptance(4, Direction::X, 4, Direction::X, &freqs, 0.0).unwrap();
        let hy = model.receptance(4, Direction::Y, 4, Direction::Y, &freqs, 0.0).unwrap();
        let amp: Vec<f64> = hx.iter().zip(&hy).map(|(a, b)| a.norm() + b.norm()).collect();
        let best = (0..amp.len()).max_by(|&a, &b| amp[a].total_cmp(&amp[b])).unwrap();
        assert!(rel(freqs[best], f0) < 1e-3, "peak at {} Hz, mode at {f0} Hz", freqs[best]);
        assert!(best > 0 && best < amp.len() - 1, "interior peak");
    }
    // The Rotor shortcut agrees with the model's receptance.
    let a = r.receptance(2, Direction::X, Direction::Y, &[10.0, 40.0], 100.0).unwrap();
    let b = model.receptance(2, Direction::X, 2, Direction::Y, &[10.0, 40.0], 100.0).unwrap();
    assert_eq!(a, b);
}

#[test]
fn spin_couples_the_planes_and_reverses_reciprocally() {
    let mut r = damped_rotor3();
    r.bearings[1].kxy = 2e5;
    r.bearings[1].kyx = 2e5;
    let model = r.assemble().unwrap();
    let freqs = [5.0, 13.2, 40.0, 44.9, 100.0, 120.0];
    // Symmetric bearings (kxy = kyx): K and C symmetric, G skew, so the dynamic stiffness obeys
    // D(Ω)ᵀ = D(−Ω) and H_out,in(Ω) = H_in,out(−Ω).
    for (ni, no) in [(4, 4), (2, 4), (0, 5)] {
        for (di, dout) in
            [(Direction::X, Direction::Y), (Direction::X, Direction::Beta), (Direction::Alpha, Direction::Y)]
        {
            let a = model.receptance(ni, di, no, dout, &freqs, 300.0).unwrap();
            let b = model.receptance(no, dout, ni, di, &freqs, -300.0).unwrap();
            for (x, y) in a.iter().zip(&b) {
                assert!((x - y).norm() <= 1e-9 * x.norm().max(y.norm()), "{x} vs {y}");
            }
        }
    }
    // Without cross-coupled bearings H_xy is zero at rest and nonzero with spin.
    let model = damped_rotor3().assemble().unwrap();
    let rest = model.receptance(4, Direction::X, 4, Direction::Y, &freqs, 0.0).unwrap();
    let xx = model.receptance(4, Direction::X, 4, Direction::X, &freqs, 0.0).unwrap();
    assert!(rest.iter().zip(&xx).all(|(c, d)| c.norm() <= 1e-12 * d.norm()));
    let spin = model.receptance(4, Direction::X, 4, Direction::Y, &freqs, 300.0).unwrap();
    let xx = model.receptance(4, Direction::X, 4, Direction::X, &freqs, 300.0).unwrap();
    assert!(spin.iter().zip(&xx).any(|(c, d)| c.norm() > 1e-2 * d.norm()));
    let yx = model.receptance(4, Direction::Y, 4, Direction::X, &freqs, 300.0).unwrap();
    let xy_rev = model.receptance(4, Direction::X, 4, Direction::Y, &freqs, -300.0).unwrap();
    for (x, y) in yx.iter().zip(&xy_rev) {
        assert!((x - y).norm() <= 1e-9 * x.norm(), "{x} vs {y}");
    }
}

#[test]
fn bad_input_is_rejected_naming_the_value() {
    let mut r = rotor3();
    r.sections[0].length_m = -1.0;
    assert_eq!(r.validate(), Err(RotorError::BadLength { section: 0, length: -1.0 }));
    let mut r = rotor3();
    r.sections[0].inner_diameter_m = 0.06;
    assert!(matches!(r.validate(), Err(RotorError::BadDiameters { section: 0, .. })));
    let mut r = rotor3();
    r.sections[0].elements = 0;
    assert_eq!(r.validate(), Err(RotorError::NoElements { section: 0 }));
    let mut r = rotor3();
    r.disks[1].node = 9;
    assert_eq!(r.validate(), Err(RotorError::NoSuchNode { what: "disk", node: 9, last: 6 }));
    let mut r = rotor3();
    r.bearings[0].cyy = -3.0;
    assert_eq!(r.validate(), Err(RotorError::BadBearing { node: 0, name: "cyy", value: -3.0 }));
    let mut r = rotor3();
    r.disks[0].polar_inertia = f64::NAN;
    assert!(matches!(r.validate(), Err(RotorError::BadDisk { node: 2, .. })));
    assert_eq!(Rotor { sections: vec![], disks: vec![], bearings: vec![] }.validate(), Err(RotorError::NoSections));
    let r = rotor3();
    assert!(matches!(r.modes_at(f64::NAN), Err(RotorError::BadSpeed(_))));
    assert!(matches!(r.receptance(0, Direction::X, Direction::X, &[-1.0], 0.0), Err(RotorError::BadFrequency(_))));
    assert!(matches!(
        r.assemble().unwrap().receptance(0, Direction::X, 7, Direction::X, &[1.0], 0.0),
        Err(RotorError::NoSuchNode { node: 7, .. })
    ));
    let mut r = rotor3();
    r.sections[0].material.density = 0.0;
    assert!(matches!(r.validate(), Err(RotorError::BadMaterial { section: 0, .. })));
}

/// A motor spindle as a rotor, rear end first, the nose (node 12) last: a hollow shaft with
/// the motor's rotor as a disk, a damped rear bearing and a front pair.
fn spindle_rotor(steel: Material) -> Rotor {
    let section = |length_m: f64, outer_diameter_m: f64, elements: usize| ShaftSection {
        length_m,
        inner_diameter_m: 0.02,
        outer_diameter_m,
        elements,
        material: steel,
    };
    Rotor {
        sections: vec![section(0.08, 0.05, 2), section(0.2, 0.07, 5), section(0.12, 0.07, 3), section(0.04, 0.09, 2)],
        disks: vec![Disk::from_geometry(4, steel.density, 0.15, 0.07, 0.11)],
        bearings: vec![
            Bearing::new(1, 1.5e8, 1.5e8, 1500.0, 1500.0),
            Bearing::new(8, 4e8, 4e8, 3000.0, 3000.0),
            Bearing::new(10, 4e8, 4e8, 3000.0, 3000.0),
        ],
    }
}

/// The coupling of a rotor spindle to a spinning holder and tool (RCSA in forward and backward
/// whirl coordinates, `rcsa::couple_spinning`) equals one rotor model with the holder and tool
/// as further shaft sections: the same structure assembled another way, at rest and at
/// 20,000 rpm, in-plane (`P`) and cross-plane (`Q`) blocks.
#[test]
fn rotor_spindle_coupled_to_a_spinning_holder_equals_one_rotor_model_of_the_assembly() {
    use crate::beam::{BeamModel, BeamSegment, CrossSection, MeshOptions, SpinningModel};
    use crate::rcsa::{self, Interface, RcsaOptions, Receptance, ReceptanceFrf, TwoPort};
    let steel = Material { loss_factor: 0.0, ..Material::STEEL };
    let carbide = Material { loss_factor: 0.0, ..Material::CARBIDE };
    // Holder flange Ø63 × 40 mm, nose Ø32 × 60 mm, carbide tool Ø12 × 60 mm; 5 mm elements.
    let parts = [(0.063, 0.04, steel), (0.032, 0.06, steel), (0.012, 0.06, carbide)];
    let mesh = MeshOptions { max_element_length: 0.005, ..MeshOptions::default() };
    let segments: Vec<BeamSegment> =
        parts.iter().map(|&(d, l, m)| BeamSegment::uniform(CrossSection::solid(d, m), l)).collect();
    let holder = SpinningModel::new(BeamModel::from_segments(&segments, &mesh).unwrap());
    let tip = holder.n_nodes() - 1;
    let spindle = spindle_rotor(steel);
    let mut whole = spindle.clone();
    for &(d, l, m) in &parts {
        let elements = (l / 0.005_f64).round() as usize;
        whole.sections.push(ShaftSection {
            length_m: l,
            inner_diameter_m: 0.0,
            outer_diameter_m: d,
            elements,
            material: m,
        });
    }
    let freqs: Vec<f64> = (1..=500).map(|k| 10.0 * k as f64).collect();
    let nose = spindle.n_nodes() - 1;
    let (spindle, whole) = (spindle.assemble().unwrap(), whole.assemble().unwrap());
    let last = whole.n_nodes() - 1;
    let block = |m: [[Complex64; 2]; 2]| Receptance::new(m[0][0], m[0][1], m[1][0], m[1][1]);
    for rpm in [0.0, 20_000.0] {
        let speed = rpm * TAU / 60.0;
        let two_port = |forward: bool| {
            let lines = holder.whirl_blocks(&[tip, 0], speed, forward, &freqs).unwrap();
            let pick = |k: usize| lines.iter().map(|b| block(b[k])).collect::<Vec<_>>();
            TwoPort { freqs_hz: freqs.clone(), r11: pick(0), r12: pick(1), r21: pick(2), r22: pick(3) }
        };
        let nose_blocks = spindle.point_receptance(nose, &freqs, speed).unwrap();
        let part = |r: usize, c: usize| ReceptanceFrf {
            freqs_hz: freqs.clone(),
            lines: nose_blocks
                .iter()
                .map(|b| Receptance::new(b[r][c], b[r][c + 1], b[r + 1][c], b[r + 1][c + 1]))
                .collect(),
        };
        let (p, q) = rcsa::couple_spinning(
            &two_port(true),
            &two_port(false),
            &(part(0, 0), part(0, 2)),
            &Interface::Rigid,
            0.0,
            &RcsaOptions::default(),
        )
        .unwrap();
        let monolithic = whole.point_receptance(last, &freqs, speed).unwrap();
        let mut worst: f64 = 0.0;
        for (k, b) in monolithic.iter().enumerate() {
            let (pp, qq) = (p.lines[k], q.lines[k]);
            let scale = b[0][0].norm();
            for (a, w) in [(pp.h, b[0][0]), (pp.l, b[0][1]), (pp.n, b[1][0]), (qq.h, b[0][2]), (-qq.h, b[2][0])] {
                worst = worst.max((a - w).norm() / scale.max(w.norm()));
            }
        }
        assert!(worst < 1e-6, "{rpm} rpm: worst relative difference {worst:e}");
        // The spin couples the planes: Q is zero at rest and of the order of P at speed.
        let coupling = q.lines.iter().zip(&p.lines).map(|(q, p)| q.h.norm() / p.h.norm()).fold(0.0, f64::max);
        if rpm == 0.0 {
            assert!(coupling < 1e-9, "cross-plane receptance at rest: {coupling:e}");
        } else {
            assert!(coupling > 0.05, "cross-plane receptance at speed only {coupling:e} of the in-plane one");
        }
    }
}

/// A bearing's speed law `k (1 + c (Ω/Ω_ref)²)` against the closed form: a short, stiff rotor
/// on two equal soft bearings bounces (the cylindrical mode, no tilt, so no gyroscopic moment)
/// at `√(2k/m)/2π`, so at Ω_ref its frequency is `√(1 + c)` times the one at rest; a law that
/// would make the stiffness negative is refused with the bearing and the speed.
#[test]
fn bearing_speed_law_moves_the_bounce_mode_as_the_closed_form() {
    let steel = Material { loss_factor: 0.0, ..Material::STEEL };
    // A low reference speed keeps the backward conical whirl above the bounce.
    let (c, reference) = (-0.3, 50.0);
    let bearing =
        |node| Bearing { speed_coefficient: c, ref_speed_rad_s: reference, ..Bearing::new(node, 1e5, 1e5, 0.0, 0.0) };
    let rotor = Rotor {
        sections: vec![ShaftSection {
            length_m: 0.2,
            inner_diameter_m: 0.0,
            outer_diameter_m: 0.1,
            elements: 4,
            material: steel,
        }],
        disks: vec![],
        bearings: vec![bearing(0), bearing(4)],
    };
    let lowest = |speed: f64| rotor.modes_at(speed).unwrap()[0].freq_hz();
    let mass = steel.density * PI * 0.05 * 0.05 * 0.2;
    let closed = (2.0 * 1e5 / mass).sqrt() / TAU;
    assert!(rel(lowest(0.0), closed) < 1e-4, "at rest {} vs {closed} Hz", lowest(0.0));
    let ratio = lowest(reference) / lowest(0.0);
    assert!(rel(ratio, (1.0 + c).sqrt()) < 1e-4, "ratio {ratio} vs {}", (1.0 + c).sqrt());
    let err = rotor.modes_at(2.0 * reference).unwrap_err();
    assert!(matches!(err, RotorError::SoftenedBearing { node: 0, .. }), "{err}");
}
