//! Spinning Timoshenko shaft (Nelson & McVaugh 1976, Nelson 1980): both bending planes of a
//! [`BeamModel`] coupled by the gyroscopic moments of the spin, for speed-dependent
//! receptances and whirl frequencies (Campbell tables) of a tool/holder or spindle rotor.
//!
//! Equations of motion, spin Ω about +x: `M q̈ + (C + ΩG) q̇ + K(1 + iη) q = f`, four dof per
//! node in the order `[y, θy, z, θz]`. Both planes use slope rotations, `θy = dy/dx` and
//! `θz = dz/dx`, with the sign conventions of the planar model (force along +y or +z, moment
//! positive in the θ sense), so each plane's K, M, C are the planar matrices. (In right-handed
//! rotations about the axes, the rotation about z is θy and the rotation about y is −θz.)
//! Ω > 0 turns y toward z; a forward whirl orbits in that sense, a backward whirl against it.
//!
//! The spin's kinetic energy `Ω ∫ ρI_p θ̇y θz dx` (ρI_p = 2ρI for circular sections) gives
//! `G = [[0, R], [−R, 0]]` between the y and z rotations, R the planar rotary-inertia matrix
//! with ρI_p in place of ρI; G is skew-symmetric, so the spin does no work. A disk adds its
//! polar inertia to R. Supports (node springs and dampers) act alike in both planes, which
//! splits the model into forward and backward circular coordinates `u± = q_y ± i q_z` with
//! `(K(1 + iη) + iωC − ω²M ± ωΩR) u± = f_y ± i f_z`: two planar-sized solves per line. The
//! damping is that of the planar model, stationary; rotating internal damping (a circulatory
//! term) is not modelled.

use super::BeamError;
use super::element;
use super::linalg::{complex_solve_banded, default_shift, symmetric_eigenvalues};
use super::model::{BeamModel, EigenSolver, project, undamped_modes};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// 4×4 receptance block between two nodes of a spinning model: rows are the response
/// `[y, θy, z, θz]` at the first node, columns the excitation `[Fy, My, Fz, Mz]` at the second.
/// With isotropic supports it has the form `[[P, Q], [−Q, P]]`: P the in-plane block
/// (`[[H, L], [N, P]]` of Eq. 5.2), Q the cross-plane block, zero at rest.
pub type SpinningReceptance = [[Complex64; 4]; 4];

/// Whirl frequencies of the undamped spinning model at one speed (Hz, ascending). Zero
/// frequencies (rigid-body translation and precession of a free rotor) are left out.
#[derive(Debug, Clone, PartialEq)]
pub struct Whirl {
    /// Spin speed, rad/s.
    pub speed: f64,
    /// Forward whirls (orbit in the sense of the spin), Hz.
    pub forward: Vec<f64>,
    /// Backward whirls, Hz.
    pub backward: Vec<f64>,
}

/// Frequencies within this fraction of the largest whirl frequency are taken as zero.
const ZERO_WHIRL: f64 = 1e-11;

/// A [`BeamModel`] spinning about its axis: the planar model (both planes alike) and the polar
/// rotary-inertia matrix R of the gyroscopic coupling.
#[derive(Debug, Clone, PartialEq)]
pub struct SpinningModel {
    planar: BeamModel,
    /// Polar rotary-inertia matrix R (planar dof order), kg·m².
    polar: Vec<f64>,
}

impl SpinningModel {
    /// Spinning form of a planar model; its point masses and springs act in both planes.
    /// Point masses carry no polar inertia: add spinning disks with [`SpinningModel::add_disk`].
    pub fn new(planar: BeamModel) -> SpinningModel {
        let n = planar.n_dof();
        let mut polar = vec![0.0; n * n];
        for (e, (props, le)) in planar.elements().iter().enumerate() {
            let mut p = *props;
            p.rho_i *= 2.0;
            let r = element::rotary_mass(&p, *le);
            for (a, row) in r.iter().enumerate() {
                for (b, v) in row.iter().enumerate() {
                    polar[(2 * e + a) * n + 2 * e + b] += v;
                }
            }
        }
        SpinningModel { planar, polar }
    }

    /// The planar model (one bending plane).
    pub fn planar(&self) -> &BeamModel {
        &self.planar
    }

    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.planar.n_nodes()
    }

    /// Polar rotary-inertia matrix R (planar dof order `[y0, θ0, …]`), kg·m².
    pub fn polar_inertia(&self) -> &[f64] {
        &self.polar
    }

    /// Adds a rigid disk at a node: mass (kg), diametral inertia (kg·m², about a transverse
    /// axis) in both planes, and polar inertia (kg·m², about the spin axis).
    pub fn add_disk(&mut self, node: usize, mass: f64, diametral: f64, polar: f64) -> Result<(), BeamError> {
        if !(polar.is_finite() && polar >= 0.0) {
            return Err(BeamError::BadPointMass { node, mass, rotary_inertia: polar });
        }
        self.planar.add_point_mass(node, mass, diametral)?;
        let n = self.planar.n_dof();
        self.polar[(2 * node + 1) * n + 2 * node + 1] += polar;
        Ok(())
    }

    /// Gyroscopic matrix G (4 dof per node, `[y, θy, z, θz]`), row-major: for planar dofs i, j,
    /// `G[y-plane i][z-plane j] = R_ij` and `G[z-plane i][y-plane j] = −R_ij`. Skew-symmetric.
    pub fn gyroscopic(&self) -> Vec<f64> {
        let n = self.planar.n_dof();
        let big = 2 * n;
        let mut g = vec![0.0; big * big];
        for i in 0..n {
            for j in 0..n {
                let r = self.polar[i * n + j];
                let (yi, zi) = (full_index(i, 0), full_index(i, 2));
                let (yj, zj) = (full_index(j, 0), full_index(j, 2));
                g[yi * big + zj] = r;
                g[zi * big + yj] = -r;
            }
        }
        g
    }

    /// Receptance blocks between `response` and `excitation` nodes at spin speed `speed`
    /// (rad/s, sign gives the direction) for each frequency (Hz), by banded complex solves
    /// of the forward and backward circular coordinates.
    pub fn receptance(
        &self,
        response: usize,
        excitation: usize,
        speed: f64,
        freqs: &[f64],
    ) -> Result<Vec<SpinningReceptance>, BeamError> {
        let nodes = self.n_nodes();
        for node in [response, excitation] {
            if node >= nodes {
                return Err(BeamError::NoSuchNode { node, nodes });
            }
        }
        if !speed.is_finite() {
            return Err(BeamError::BadSpeed(speed));
        }
        let n = self.planar.n_dof();
        let band = self.planar.bandwidth();
        let (k, m, kl, c) =
            (self.planar.stiffness(), self.planar.mass(), self.planar.loss_stiffness(), self.planar.damping());
        let zero = Complex64::new(0.0, 0.0);
        let mut a = vec![zero; n * n];
        let mut b = vec![zero; n * 2];
        let mut out = Vec::with_capacity(freqs.len());
        for &f in freqs {
            if !f.is_finite() || f < 0.0 {
                return Err(BeamError::BadFrequency(f));
            }
            let w = TAU * f;
            // h[0] forward (+), h[1] backward (−): 2×2 planar-shaped blocks.
            let mut h = [[[zero; 2]; 2]; 2];
            for (s, sign) in [1.0, -1.0].into_iter().enumerate() {
                let wg = sign * w * speed;
                for (idx, z) in a.iter_mut().enumerate() {
                    *z = Complex64::new(k[idx] - w * w * m[idx] + wg * self.polar[idx], kl[idx] + w * c[idx]);
                }
                b.fill(zero);
                b[2 * excitation * 2] = Complex64::new(1.0, 0.0);
                b[(2 * excitation + 1) * 2 + 1] = Complex64::new(1.0, 0.0);
                if !complex_solve_banded(&mut a, n, band, &mut b, 2) {
                    return Err(BeamError::Singular(f));
                }
                for (r, row) in h[s].iter_mut().enumerate() {
                    let base = (2 * response + r) * 2;
                    *row = [b[base], b[base + 1]];
                }
            }
            let mut block = [[zero; 4]; 4];
            let half_i = Complex64::new(0.0, 0.5);
            for r in 0..2 {
                for col in 0..2 {
                    let p = 0.5 * (h[0][r][col] + h[1][r][col]);
                    let q = half_i * (h[0][r][col] - h[1][r][col]);
                    block[r][col] = p;
                    block[r + 2][col + 2] = p;
                    block[r][col + 2] = q;
                    block[r + 2][col] = -q;
                }
            }
            out.push(block);
        }
        Ok(out)
    }

    /// Receptances in one whirl coordinate `u = q_y + s i q_z` (`s = +1` forward, `−1`
    /// backward) between every pair of `nodes`, at spin speed `speed` (rad/s) and each
    /// frequency (Hz): the planar-shaped blocks `[[w/F, w/M], [θ/F, θ/M]]`, row-major by
    /// (response node, excitation node). In terms of [`SpinningReceptance`]'s `P` and `Q`,
    /// the forward block is `P − iQ` and the backward `P + iQ`; with isotropic supports on
    /// both sides a coupling splits into one planar coupling per whirl coordinate.
    pub fn whirl_blocks(
        &self,
        nodes: &[usize],
        speed: f64,
        forward: bool,
        freqs: &[f64],
    ) -> Result<Vec<Vec<[[Complex64; 2]; 2]>>, BeamError> {
        let count = self.n_nodes();
        if let Some(&node) = nodes.iter().find(|&&n| n >= count) {
            return Err(BeamError::NoSuchNode { node, nodes: count });
        }
        if !speed.is_finite() {
            return Err(BeamError::BadSpeed(speed));
        }
        let n = self.planar.n_dof();
        let band = self.planar.bandwidth();
        let (k, m, kl, c) =
            (self.planar.stiffness(), self.planar.mass(), self.planar.loss_stiffness(), self.planar.damping());
        let sign = if forward { 1.0 } else { -1.0 };
        let r = 2 * nodes.len();
        let zero = Complex64::new(0.0, 0.0);
        let mut a = vec![zero; n * n];
        let mut b = vec![zero; n * r];
        let mut out = Vec::with_capacity(freqs.len());
        for &f in freqs {
            if !f.is_finite() || f < 0.0 {
                return Err(BeamError::BadFrequency(f));
            }
            let w = TAU * f;
            let wg = sign * w * speed;
            // Only the band and the upper factor's fill (2 × band) are touched by the solve.
            for i in 0..n {
                for j in i.saturating_sub(band)..(i + 2 * band + 1).min(n) {
                    let idx = i * n + j;
                    a[idx] = Complex64::new(k[idx] - w * w * m[idx] + wg * self.polar[idx], kl[idx] + w * c[idx]);
                }
            }
            b.fill(zero);
            for (e, &node) in nodes.iter().enumerate() {
                b[2 * node * r + 2 * e] = Complex64::new(1.0, 0.0);
                b[(2 * node + 1) * r + 2 * e + 1] = Complex64::new(1.0, 0.0);
            }
            if !complex_solve_banded(&mut a, n, band, &mut b, r) {
                return Err(BeamError::Singular(f));
            }
            let mut blocks = Vec::with_capacity(nodes.len() * nodes.len());
            for &resp in nodes {
                for e in 0..nodes.len() {
                    let at = |row: usize, col: usize| b[(2 * resp + row) * r + 2 * e + col];
                    blocks.push([[at(0, 0), at(0, 1)], [at(1, 0), at(1, 1)]]);
                }
            }
            out.push(blocks);
        }
        Ok(out)
    }

    /// Forward and backward whirl frequencies at each spin speed (rad/s): a Campbell table.
    ///
    /// In the mass-normalised planar modes (λ_r = ω_r², Φ), the forward coordinate obeys
    /// `(Λ + ωΩR̃ − ω²I) η = 0`, R̃ = ΦᵀRΦ; with `a = Λ^½ η`, `b = ωη` this is the symmetric
    /// eigenproblem `ω [a; b] = [[0, Λ^½], [Λ^½, ΩR̃]] [a; b]`, whose positive roots are the
    /// orbits turning from y toward z (forward for Ω > 0) and whose negative roots, with the
    /// sign changed, the orbits turning the other way.
    pub fn campbell(&self, speeds: &[f64]) -> Result<Vec<Whirl>, BeamError> {
        let n = self.planar.n_dof();
        let rigid = self.planar.rigid_body_modes();
        let sigma = default_shift(self.planar.stiffness(), self.planar.mass(), n);
        let modes = undamped_modes(&self.planar, EigenSolver::Faer, sigma, rigid)?;
        let rt = project(&self.polar, &modes.phi, n);
        let elastic = n - rigid;
        let size = elastic + n;
        let mut s = vec![0.0; size * size];
        let mut out = Vec::with_capacity(speeds.len());
        for &speed in speeds {
            if !speed.is_finite() {
                return Err(BeamError::BadSpeed(speed));
            }
            s.fill(0.0);
            for r in 0..elastic {
                let root = modes.lambda[rigid + r].max(0.0).sqrt();
                s[r * size + elastic + rigid + r] = root;
                s[(elastic + rigid + r) * size + r] = root;
            }
            for i in 0..n {
                for j in 0..n {
                    s[(elastic + i) * size + elastic + j] = speed * 0.5 * (rt[i * n + j] + rt[j * n + i]);
                }
            }
            let vals = symmetric_eigenvalues(&s, size).ok_or(BeamError::NoConvergence)?;
            let top = vals.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let zero = ZERO_WHIRL * top;
            let forward = vals.iter().filter(|v| **v > zero).map(|v| v / TAU).collect();
            let mut backward: Vec<f64> = vals.iter().filter(|v| **v < -zero).map(|v| -v / TAU).collect();
            backward.reverse();
            // Positive roots orbit from y toward z, which is against a negative spin.
            let (forward, backward) = if speed < 0.0 { (backward, forward) } else { (forward, backward) };
            out.push(Whirl { speed, forward, backward });
        }
        Ok(out)
    }
}

/// Index in the 4-dof-per-node order of planar dof `i` (`[y, θ]` of node i/2) in the plane
/// starting at `offset` (0 for y, 2 for z).
fn full_index(i: usize, offset: usize) -> usize {
    4 * (i / 2) + offset + i % 2
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::beam::linalg::complex_solve;
    use crate::beam::{
        BeamSegment, CrossSection, Material, MeshOptions, NodeSpring, segments_from_sections,
        table::tool_holder_sections,
    };
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use std::f64::consts::PI;

    fn steel_no_loss() -> Material {
        Material { loss_factor: 0.0, ..Material::STEEL }
    }

    fn shaft(d: f64, l: f64, elements: usize, material: Material) -> BeamModel {
        let seg = BeamSegment::uniform(CrossSection::solid(d, material), l);
        let mesh = MeshOptions { max_element_length: l / elements as f64 * (1.0 + 1e-12), ..MeshOptions::default() };
        BeamModel::from_segments(&[seg], &mesh).unwrap()
    }

    fn tool_holder() -> BeamModel {
        BeamModel::from_segments(&segments_from_sections(&tool_holder_sections()), &MeshOptions::default()).unwrap()
    }

    fn close(a: Complex64, b: Complex64, scale: f64, tol: f64) -> bool {
        (a - b).norm() <= tol * scale
    }

    fn block_scale(b: &SpinningReceptance) -> f64 {
        b.iter().flatten().fold(0.0f64, |s, z| s.max(z.norm()))
    }

    #[test]
    fn at_rest_each_plane_is_the_planar_model_and_planes_are_uncoupled() {
        let planar = tool_holder();
        let spin = SpinningModel::new(planar.clone());
        let tip = planar.n_nodes() - 1;
        let freqs = [150.0, 1200.0, 3700.0, 9000.0];
        let p = planar.receptance_direct(tip, 0, &freqs).unwrap();
        let s = spin.receptance(tip, 0, 0.0, &freqs).unwrap();
        for (a, b) in p.iter().zip(&s) {
            for r in 0..2 {
                for c in 0..2 {
                    let scale = a[r][c].norm();
                    assert!(close(b[r][c], a[r][c], scale, 1e-12), "y plane [{r}][{c}]");
                    assert!(close(b[r + 2][c + 2], a[r][c], scale, 1e-12), "z plane [{r}][{c}]");
                    assert_eq!(b[r][c + 2].norm(), 0.0);
                    assert_eq!(b[r + 2][c].norm(), 0.0);
                }
            }
        }
    }

    #[test]
    fn gyroscopic_matrix_is_skew_and_holds_the_polar_inertia() {
        let (d, l) = (20e-3, 0.12);
        let mut spin = SpinningModel::new(shaft(d, l, 12, steel_no_loss()));
        let mid = spin.n_nodes() / 2;
        spin.add_disk(mid, 1.5, 2e-3, 4e-3).unwrap();
        let g = spin.gyroscopic();
        let big = 4 * spin.n_nodes();
        let scale = g.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!(scale > 0.0);
        for i in 0..big {
            for j in 0..big {
                assert!((g[i * big + j] + g[j * big + i]).abs() <= 1e-15 * scale, "G[{i}][{j}]");
            }
        }
        // No gyroscopic power: qᵀGq = 0 for any velocity pattern.
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let q: Vec<f64> = (0..big).map(|_| rng.random_range(-1.0..1.0)).collect();
        let power: f64 = (0..big).map(|i| (0..big).map(|j| q[i] * g[i * big + j] * q[j]).sum::<f64>()).sum();
        assert!(power.abs() < 1e-12 * scale * big as f64, "{power}");
        // Rigid tilt (θ = 1, y = x) stores the whole polar inertia 2ρIL + disk; a translation none.
        let n = spin.planar().n_dof();
        let x = spin.planar().node_positions().to_vec();
        let tilt: Vec<f64> = (0..n).map(|i| if i % 2 == 1 { 1.0 } else { x[i / 2] }).collect();
        let lift: Vec<f64> = (0..n).map(|i| if i % 2 == 0 { 1.0 } else { 0.0 }).collect();
        let r = spin.polar_inertia();
        let quad = |v: &[f64]| -> f64 { (0..n).map(|i| (0..n).map(|j| v[i] * r[i * n + j] * v[j]).sum::<f64>()).sum() };
        let ip = 2.0 * 7800.0 * PI * d.powi(4) / 64.0 * l + 4e-3;
        assert!((quad(&tilt) - ip).abs() < 1e-12 * ip, "{} vs {ip}", quad(&tilt));
        assert!(quad(&lift).abs() < 1e-15 * ip);
    }

    /// Full 4-dof-per-node matrices of one planar matrix, both planes alike.
    fn both_planes(a: &[f64], n: usize) -> Vec<f64> {
        let big = 2 * n;
        let mut out = vec![0.0; big * big];
        for i in 0..n {
            for j in 0..n {
                for off in [0, 2] {
                    out[full_index(i, off) * big + full_index(j, off)] = a[i * n + j];
                }
            }
        }
        out
    }

    #[test]
    fn circular_coordinates_solve_the_full_gyroscopic_system() {
        let mut planar = shaft(25e-3, 0.15, 10, Material::STEEL);
        planar.add_spring(0, NodeSpring { kt: 5e7, ct: 300.0, kr: 2e5, cr: 2.0 }).unwrap();
        let mut spin = SpinningModel::new(planar);
        let tip = spin.n_nodes() - 1;
        spin.add_disk(tip, 0.8, 6e-4, 1.1e-3).unwrap();
        let p = spin.planar();
        let n = p.n_dof();
        let big = 2 * n;
        let (k, m, kl, c) = (
            both_planes(p.stiffness(), n),
            both_planes(p.mass(), n),
            both_planes(p.loss_stiffness(), n),
            both_planes(p.damping(), n),
        );
        let g = spin.gyroscopic();
        let speed = 2500.0;
        let freqs = [0.0, 80.0, 700.0, 2300.0, 6100.0];
        for (i, j) in [(tip, 0), (0, tip), (tip, tip), (3, 7)] {
            let got = spin.receptance(i, j, speed, &freqs).unwrap();
            for (fi, &f) in freqs.iter().enumerate() {
                let w = TAU * f;
                let mut a: Vec<Complex64> = (0..big * big)
                    .map(|x| Complex64::new(k[x] - w * w * m[x], kl[x] + w * (c[x] + speed * g[x])))
                    .collect();
                let mut b = vec![Complex64::new(0.0, 0.0); big * 4];
                for e in 0..4 {
                    b[(4 * j + e) * 4 + e] = Complex64::new(1.0, 0.0);
                }
                assert!(complex_solve(&mut a, big, &mut b, 4));
                let scale = block_scale(&got[fi]);
                for r in 0..4 {
                    for e in 0..4 {
                        let want = b[(4 * i + r) * 4 + e];
                        assert!(close(got[fi][r][e], want, scale, 1e-9), "({i},{j}) {f} Hz [{r}][{e}]");
                    }
                }
                // Spin couples the planes: the cross block is not small at speed.
                if f > 0.0 && i == j {
                    let q = got[fi][0][3].norm().max(got[fi][1][2].norm());
                    assert!(q > 1e-6 * scale, "{f} Hz: cross {q} vs {scale}");
                }
            }
        }
    }

    #[test]
    fn reversing_the_spin_transposes_the_receptance() {
        // Gyroscopic reciprocity: H(i, j, Ω) = H(j, i, −Ω)ᵀ.
        let spin = SpinningModel::new(tool_holder());
        let tip = spin.n_nodes() - 1;
        let freqs = [450.0, 2900.0, 7600.0];
        let a = spin.receptance(tip, 5, 3000.0, &freqs).unwrap();
        let b = spin.receptance(5, tip, -3000.0, &freqs).unwrap();
        for (x, y) in a.iter().zip(&b) {
            let scale = block_scale(x);
            for r in 0..4 {
                for c in 0..4 {
                    assert!(close(x[r][c], y[c][r], scale, 1e-9), "[{r}][{c}]");
                }
            }
        }
    }

    #[test]
    fn rigid_rotor_on_springs_whirls_as_the_closed_form() {
        // Shaft of steel's density made a thousand times stiffer than steel (a near-rigid body,
        // elastic modes above 250 kHz) with a centred disk on two equal springs at its ends.
        // Flexibility then shifts the rigid whirls (below 600 Hz) by under 1e-6 relative.
        // Closed forms (m, Id, Ip of shaft plus disk, kθ = 2k(L/2)²): translation √(2k/m) at
        // every speed; tilt Id ω² ∓ IpΩω − kθ = 0, forward ω = (IpΩ + √((IpΩ)² + 4Id kθ)) / 2Id,
        // backward with −IpΩ.
        let (d, l, k) = (40e-3, 0.1, 1e5);
        let rigid = Material { youngs_modulus: 200e12, ..steel_no_loss() };
        let mut spin = SpinningModel::new(shaft(d, l, 20, rigid));
        let (disk_m, disk_id, disk_ip) = (2.0, 0.005, 0.01);
        let last = spin.n_nodes() - 1;
        spin.add_disk(last / 2, disk_m, disk_id, disk_ip).unwrap();
        let mut planar = spin.planar().clone();
        for node in [0, last] {
            planar.add_spring(node, NodeSpring { kt: k, ..NodeSpring::default() }).unwrap();
        }
        let spin = SpinningModel { planar, polar: spin.polar.clone() };
        let (area, i) = (PI * d * d / 4.0, PI * d.powi(4) / 64.0);
        let m = 7800.0 * area * l + disk_m;
        let id = 7800.0 * (area * l.powi(3) / 12.0 + i * l) + disk_id;
        let ip = 2.0 * 7800.0 * i * l + disk_ip;
        let kt = 2.0 * k * (l / 2.0).powi(2);
        let speeds = [0.0, 1000.0, 2000.0, -1500.0];
        let table = spin.campbell(&speeds).unwrap();
        for (row, &speed) in table.iter().zip(&speeds) {
            assert_eq!(row.speed, speed);
            // In the sense of the spin, whichever its direction.
            let g = ip * speed.abs();
            let root = (g * g + 4.0 * id * kt).sqrt();
            let translation = (2.0 * k / m).sqrt() / TAU;
            let forward = (g + root) / (2.0 * id) / TAU;
            let backward = (-g + root) / (2.0 * id) / TAU;
            let has = |list: &[f64], f: f64| list.iter().any(|x| (x - f).abs() < 2e-6 * f);
            assert!(has(&row.forward, translation) && has(&row.backward, translation), "{speed}: {row:?}");
            assert!(has(&row.forward, forward), "{speed}: forward tilt {forward} Hz not in {:?}", &row.forward[..3]);
            assert!(
                has(&row.backward, backward),
                "{speed}: backward tilt {backward} Hz not in {:?}",
                &row.backward[..3]
            );
            assert_eq!(row.forward.len(), row.backward.len());
            assert!(row.forward[2] > 250e3 && row.backward[2] > 250e3, "elastic modes");
        }
    }

    #[test]
    fn free_shaft_nutates_at_ip_over_id_and_whirls_split_with_speed() {
        let (d, l) = (30e-3, 0.2);
        let planar = shaft(d, l, 40, steel_no_loss());
        let rest = planar.modes().unwrap().natural_frequencies();
        let spin = SpinningModel::new(planar);
        let table = spin.campbell(&[0.0, 50.0, 20_000.0]).unwrap();
        // At rest forward and backward whirls are the planar natural frequencies.
        assert_eq!(table[0].forward.len(), rest.len() - 2);
        for ((f, b), r) in table[0].forward.iter().zip(&table[0].backward).zip(&rest[2..]) {
            assert!((f - r).abs() < 1e-9 * r && (b - r).abs() < 1e-9 * r, "{f} {b} {r}");
        }
        // Slow spin: the free rigid body nutates forward at Ω Ip/Id (Id about the centre).
        let (area, i) = (PI * d * d / 4.0, PI * d.powi(4) / 64.0);
        let ratio = 2.0 * i * l / (area * l.powi(3) / 12.0 + i * l);
        let nutation = 50.0 * ratio / TAU;
        let slow = &table[1];
        assert!((slow.forward[0] - nutation).abs() < 1e-6 * nutation, "{} vs {nutation}", slow.forward[0]);
        assert_eq!(slow.forward.len(), slow.backward.len() + 1);
        // Fast spin: each elastic whirl splits, forward up and backward down.
        let fast = &table[2];
        for k in 0..3 {
            let (f, b, r) = (fast.forward[k + 1], fast.backward[k], rest[2 + k]);
            assert!(f > r && b < r, "mode {k}: forward {f}, backward {b}, rest {r}");
        }
    }

    #[test]
    fn bad_speeds_and_nodes_are_rejected() {
        let spin = SpinningModel::new(shaft(20e-3, 0.1, 5, Material::STEEL));
        assert!(matches!(spin.receptance(0, 99, 10.0, &[100.0]), Err(BeamError::NoSuchNode { node: 99, .. })));
        assert!(matches!(spin.receptance(0, 1, f64::NAN, &[100.0]), Err(BeamError::BadSpeed(_))));
        assert!(matches!(spin.receptance(0, 1, 10.0, &[-1.0]), Err(BeamError::BadFrequency(_))));
        assert!(matches!(spin.campbell(&[f64::INFINITY]), Err(BeamError::BadSpeed(_))));
        let mut spin = spin;
        assert!(matches!(spin.add_disk(0, 1.0, 1e-3, -1.0), Err(BeamError::BadPointMass { .. })));
        assert!(matches!(spin.add_disk(42, 1.0, 1e-3, 1e-3), Err(BeamError::NoSuchNode { .. })));
    }
}
