//! Two-node Timoshenko beam element (Przemieniecki's shear-deformable element, used for the
//! tool/holder slices of dissertation §5.4): stiffness and consistent mass (translational
//! plus rotary inertia), dof order `[y1, θ1, y2, θ2]`, θ = dy/dx positive.

use super::section::SectionProperties;

/// 4×4 element matrix, row-major.
pub type Mat4 = [[f64; 4]; 4];

/// Shear parameter Φ = 12 EI / (κGA L²).
pub fn shear_parameter(p: &SectionProperties, length: f64) -> f64 {
    12.0 * p.ei / (p.ga_s * length * length)
}

/// Element stiffness matrix (real part; the complex stiffness is this times (1 + iη)).
pub fn stiffness(p: &SectionProperties, l: f64) -> Mat4 {
    let phi = shear_parameter(p, l);
    let c = p.ei / ((1.0 + phi) * l * l * l);
    let l2 = l * l;
    let a = (4.0 + phi) * l2;
    let b = (2.0 - phi) * l2;
    [
        [12.0 * c, 6.0 * l * c, -12.0 * c, 6.0 * l * c],
        [6.0 * l * c, a * c, -6.0 * l * c, b * c],
        [-12.0 * c, -6.0 * l * c, 12.0 * c, -6.0 * l * c],
        [6.0 * l * c, b * c, -6.0 * l * c, a * c],
    ]
}

/// Consistent mass matrix: translational inertia ρA and rotary inertia ρI.
pub fn mass(p: &SectionProperties, l: f64) -> Mat4 {
    let f = shear_parameter(p, l);
    let f2 = f * f;
    let l2 = l * l;
    let ct = p.rho_a * l / ((1.0 + f) * (1.0 + f));
    let t11 = 13.0 / 35.0 + 7.0 * f / 10.0 + f2 / 3.0;
    let t12 = (11.0 / 210.0 + 11.0 * f / 120.0 + f2 / 24.0) * l;
    let t13 = 9.0 / 70.0 + 3.0 * f / 10.0 + f2 / 6.0;
    let t14 = -(13.0 / 420.0 + 3.0 * f / 40.0 + f2 / 24.0) * l;
    let t22 = (1.0 / 105.0 + f / 60.0 + f2 / 120.0) * l2;
    let t24 = -(1.0 / 140.0 + f / 60.0 + f2 / 120.0) * l2;
    let cr = p.rho_i / ((1.0 + f) * (1.0 + f) * l);
    let r11 = 6.0 / 5.0;
    let r12 = (1.0 / 10.0 - f / 2.0) * l;
    let r22 = (2.0 / 15.0 + f / 6.0 + f2 / 3.0) * l2;
    let r24 = (-1.0 / 30.0 - f / 6.0 + f2 / 6.0) * l2;
    let m11 = ct * t11 + cr * r11;
    let m12 = ct * t12 + cr * r12;
    let m13 = ct * t13 - cr * r11;
    let m14 = ct * t14 + cr * r12;
    let m22 = ct * t22 + cr * r22;
    let m23 = -ct * t14 - cr * r12;
    let m24 = ct * t24 + cr * r24;
    [[m11, m12, m13, m14], [m12, m22, m23, m24], [m13, m23, m11, -m12], [m14, m24, -m12, m22]]
}

/// Rotary-inertia part of [`mass`]: `∫ ρI Nψᵀ Nψ dx` over the section-rotation shape
/// functions. With ρI replaced by the polar ρI_p = 2ρI of a circular section it is the
/// block that the spin couples between the two bending planes (Nelson 1980).
pub fn rotary_mass(p: &SectionProperties, l: f64) -> Mat4 {
    let f = shear_parameter(p, l);
    let f2 = f * f;
    let l2 = l * l;
    let cr = p.rho_i / ((1.0 + f) * (1.0 + f) * l);
    let r11 = cr * 6.0 / 5.0;
    let r12 = cr * (1.0 / 10.0 - f / 2.0) * l;
    let r22 = cr * (2.0 / 15.0 + f / 6.0 + f2 / 3.0) * l2;
    let r24 = cr * (-1.0 / 30.0 - f / 6.0 + f2 / 6.0) * l2;
    [[r11, r12, -r11, r12], [r12, r22, -r12, r24], [-r11, -r12, r11, -r12], [r12, r24, -r12, r22]]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn props() -> SectionProperties {
        SectionProperties { ei: 3.0e3, ga_s: 2.0e7, rho_a: 5.0, rho_i: 2.0e-4, eta: 0.0 }
    }

    #[test]
    fn element_matrices_are_symmetric_with_rigid_body_null_space() {
        let p = props();
        let l = 0.02;
        let k = stiffness(&p, l);
        let m = mass(&p, l);
        for i in 0..4 {
            for j in 0..4 {
                assert!((k[i][j] - k[j][i]).abs() <= 1e-12 * k[0][0]);
                assert!((m[i][j] - m[j][i]).abs() <= 1e-12 * m[0][0]);
            }
        }
        // Rigid translation and rotation produce no elastic forces.
        for v in [[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, l, 1.0]] {
            for row in &k {
                let f: f64 = row.iter().zip(v).map(|(a, b)| a * b).sum();
                assert!(f.abs() < 1e-9 * k[0][0], "{f}");
            }
        }
        // Rigid translation kinetic energy: total mass; rigid rotation about node 1: ρA L³/3 + ρI L.
        let quad = |v: [f64; 4]| -> f64 { (0..4).map(|i| (0..4).map(|j| v[i] * m[i][j] * v[j]).sum::<f64>()).sum() };
        assert!((quad([1.0, 0.0, 1.0, 0.0]) - p.rho_a * l).abs() < 1e-12 * p.rho_a * l);
        let jr = p.rho_a * l.powi(3) / 3.0 + p.rho_i * l;
        assert!((quad([0.0, 1.0, l, 1.0]) - jr).abs() < 1e-10 * jr);
    }

    #[test]
    fn rotary_part_is_the_mass_matrix_without_translational_inertia() {
        let p = props();
        let l = 0.03;
        let r = rotary_mass(&p, l);
        let m = mass(&p, l);
        let m0 = mass(&SectionProperties { rho_i: 0.0, ..p }, l);
        for i in 0..4 {
            for j in 0..4 {
                assert!((m[i][j] - m0[i][j] - r[i][j]).abs() <= 1e-12 * m[0][0], "[{i}][{j}]");
            }
        }
        // A rigid rotation ψ = 1 stores ρI L; a rigid translation none.
        let quad = |v: [f64; 4]| -> f64 { (0..4).map(|i| (0..4).map(|j| v[i] * r[i][j] * v[j]).sum::<f64>()).sum() };
        assert!((quad([0.0, 1.0, l, 1.0]) - p.rho_i * l).abs() < 1e-12 * p.rho_i * l);
        assert!(quad([1.0, 0.0, 1.0, 0.0]).abs() < 1e-20);
    }

    #[test]
    fn static_tip_deflection_includes_shear() {
        // Cantilever from one element: clamp node 1 and load node 2 with a unit force.
        let p = props();
        let l = 0.05;
        let k = stiffness(&p, l);
        let (a, b, c) = (k[2][2], k[2][3], k[3][3]);
        let det = a * c - b * b;
        let y = c / det;
        let th = -b / det;
        let exact_y = l.powi(3) / (3.0 * p.ei) + l / p.ga_s;
        assert!((y - exact_y).abs() < 1e-12 * exact_y, "{y} vs {exact_y}");
        assert!((th - l * l / (2.0 * p.ei)).abs() < 1e-12 * th);
    }
}
