//! Free–free Timoshenko beam assembly of a tool/holder/artifact (dissertation §5.4) and its
//! receptances (§5.1): direct complex solve per frequency line and modal expansion.
//!
//! Tapered segments are subdivided into several elements, each with the cross-section at its
//! mid-point (a stepped approximation of the cone that converges as elements shrink).
//! Damping: structural, as complex modulus E(1 + iη) per element (hysteretic stiffness
//! `i Σ η_e K_e`), plus viscous dampers of node springs (`iωC`).

use super::BeamError;
use super::element;
use super::linalg::{bandwidth, complex_solve, complex_solve_banded, generalized_eigen};
use super::section::{BeamSegment, SectionProperties, ShearCoefficient};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// 2×2 receptance block between two nodes, `[[H, L], [N, P]]`: H = y/F, L = y/M, N = θ/F,
/// P = θ/M (Eq. 5.2), response at the first node, excitation at the second.
pub type Receptance = [[Complex64; 2]; 2];

/// Most elements a model may have: its matrices are dense, 4 × (2·nodes)² values.
pub const MAX_ELEMENTS: usize = 2000;

/// Meshing options for [`BeamModel::from_segments`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshOptions {
    /// Longest element, m; each segment is split into `ceil(length / max_element_length)`.
    pub max_element_length: f64,
    /// Fewest elements per tapered segment (mid-point properties per element).
    pub min_taper_elements: usize,
    /// Shear coefficient model.
    pub shear: ShearCoefficient,
}

impl Default for MeshOptions {
    fn default() -> Self {
        MeshOptions { max_element_length: 2e-3, min_taper_elements: 4, shear: ShearCoefficient::Cowper }
    }
}

/// Translational and rotational spring with viscous dampers attached between a node and ground.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NodeSpring {
    /// Translational stiffness, N/m.
    pub kt: f64,
    /// Translational damping, N·s/m.
    pub ct: f64,
    /// Rotational stiffness, N·m/rad.
    pub kr: f64,
    /// Rotational damping, N·m·s/rad.
    pub cr: f64,
}

/// Assembled beam: node positions and global matrices (row-major, dof `[y0, θ0, y1, θ1, …]`).
#[derive(Debug, Clone, PartialEq)]
pub struct BeamModel {
    node_x: Vec<f64>,
    k: Vec<f64>,
    k_loss: Vec<f64>,
    c: Vec<f64>,
    m: Vec<f64>,
    springs: Vec<(usize, NodeSpring)>,
    /// Section properties and length of each element, spindle end first.
    elements: Vec<(SectionProperties, f64)>,
}

impl BeamModel {
    /// Assembles a free–free beam from segments laid end to end, node 0 at the spindle end.
    pub fn from_segments(segments: &[BeamSegment], mesh: &MeshOptions) -> Result<BeamModel, BeamError> {
        if segments.is_empty() {
            return Err(BeamError::NoSegments);
        }
        if !(mesh.max_element_length.is_finite() && mesh.max_element_length > 0.0) {
            return Err(BeamError::BadElementLength(mesh.max_element_length));
        }
        let mut counts = Vec::with_capacity(segments.len());
        for (index, seg) in segments.iter().enumerate() {
            if !(seg.length.is_finite() && seg.length > 0.0) {
                return Err(BeamError::BadLength { segment: index, length: seg.length });
            }
            // Both ends, so a cone whose bore breaks through at one end is caught even when
            // every element mid-point still has a wall.
            for end in seg.end_sections() {
                end.properties(mesh.shear)
                    .map_err(|err| BeamError::Segment { segment: index, source: Box::new(err) })?;
            }
            let mut count = (seg.length / mesh.max_element_length).ceil().max(1.0);
            if seg.is_tapered() {
                count = count.max(mesh.min_taper_elements.max(1) as f64);
            }
            counts.push(count);
        }
        let total: f64 = counts.iter().sum();
        if total > MAX_ELEMENTS as f64 {
            return Err(BeamError::TooManyElements { elements: total, limit: MAX_ELEMENTS });
        }
        let mut elements = Vec::new();
        let mut node_x = vec![0.0];
        for (index, (seg, &count)) in segments.iter().zip(&counts).enumerate() {
            let count = count as usize;
            let le = seg.length / count as f64;
            for e in 0..count {
                let props = seg
                    .section_at((e as f64 + 0.5) / count as f64)
                    .properties(mesh.shear)
                    .map_err(|err| BeamError::Segment { segment: index, source: Box::new(err) })?;
                elements.push((props, le));
                let last = *node_x.last().unwrap_or(&0.0);
                node_x.push(last + le);
            }
        }
        let n = 2 * node_x.len();
        let mut model = BeamModel {
            node_x,
            k: vec![0.0; n * n],
            k_loss: vec![0.0; n * n],
            c: vec![0.0; n * n],
            m: vec![0.0; n * n],
            springs: Vec::new(),
            elements: Vec::new(),
        };
        for (e, (props, le)) in elements.iter().enumerate() {
            let ke = element::stiffness(props, *le);
            let me = element::mass(props, *le);
            let base = 2 * e;
            for a in 0..4 {
                for b in 0..4 {
                    let idx = (base + a) * n + base + b;
                    model.k[idx] += ke[a][b];
                    model.k_loss[idx] += props.eta * ke[a][b];
                    model.m[idx] += me[a][b];
                }
            }
        }
        model.elements = elements;
        Ok(model)
    }

    /// Number of nodes (the tip is `n_nodes() - 1`).
    pub fn n_nodes(&self) -> usize {
        self.node_x.len()
    }

    /// Number of degrees of freedom (2 per node).
    pub fn n_dof(&self) -> usize {
        2 * self.node_x.len()
    }

    /// Node positions from the spindle end, m.
    pub fn node_positions(&self) -> &[f64] {
        &self.node_x
    }

    /// Node closest to position `x` (m from the spindle end).
    pub fn node_at(&self, x: f64) -> usize {
        let mut best = 0;
        for (i, xi) in self.node_x.iter().enumerate() {
            if (xi - x).abs() < (self.node_x[best] - x).abs() {
                best = i;
            }
        }
        best
    }

    /// Real stiffness matrix K (elastic plus springs), row-major.
    pub fn stiffness(&self) -> &[f64] {
        &self.k
    }

    /// Consistent mass matrix M (including point masses), row-major.
    pub fn mass(&self) -> &[f64] {
        &self.m
    }

    /// Hysteretic stiffness `Σ η_e K_e` (the imaginary part of the complex stiffness), row-major.
    pub fn loss_stiffness(&self) -> &[f64] {
        &self.k_loss
    }

    /// Viscous damping matrix C of the node dampers, row-major.
    pub fn damping(&self) -> &[f64] {
        &self.c
    }

    /// Section properties and length of each element, spindle end first.
    pub fn elements(&self) -> &[(SectionProperties, f64)] {
        &self.elements
    }

    /// Largest distance from the diagonal of a non-zero entry of K, M, C or K_η (3 for
    /// two-node elements with two dof per node).
    pub fn bandwidth(&self) -> usize {
        bandwidth(&[&self.k, &self.m, &self.c, &self.k_loss], self.n_dof())
    }

    /// Total mass of the model, kg (rigid translation kinetic energy).
    pub fn total_mass(&self) -> f64 {
        let n = self.n_dof();
        let mut s = 0.0;
        for i in (0..n).step_by(2) {
            for j in (0..n).step_by(2) {
                s += self.m[i * n + j];
            }
        }
        s
    }

    fn check_node(&self, node: usize) -> Result<(), BeamError> {
        if node < self.n_nodes() { Ok(()) } else { Err(BeamError::NoSuchNode { node, nodes: self.n_nodes() }) }
    }

    /// Adds a point mass (kg) with rotary inertia (kg·m²) at a node, e.g. an accelerometer.
    pub fn add_point_mass(&mut self, node: usize, mass: f64, rotary_inertia: f64) -> Result<(), BeamError> {
        self.check_node(node)?;
        if !(mass.is_finite() && mass >= 0.0 && rotary_inertia.is_finite() && rotary_inertia >= 0.0) {
            return Err(BeamError::BadPointMass { node, mass, rotary_inertia });
        }
        let n = self.n_dof();
        self.m[2 * node * n + 2 * node] += mass;
        self.m[(2 * node + 1) * n + 2 * node + 1] += rotary_inertia;
        Ok(())
    }

    /// Adds a grounded translational/rotational spring with viscous dampers at a node.
    pub fn add_spring(&mut self, node: usize, spring: NodeSpring) -> Result<(), BeamError> {
        self.check_node(node)?;
        let vals = [spring.kt, spring.ct, spring.kr, spring.cr];
        if vals.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(BeamError::BadSpring { node, spring });
        }
        let n = self.n_dof();
        let (t, r) = (2 * node * n + 2 * node, (2 * node + 1) * n + 2 * node + 1);
        self.k[t] += spring.kt;
        self.k[r] += spring.kr;
        self.c[t] += spring.ct;
        self.c[r] += spring.cr;
        self.springs.push((node, spring));
        Ok(())
    }

    /// Receptances between `response` and `excitation` nodes at each frequency (Hz) by a
    /// complex banded LU solve of `(K + iK_η + iωC − ω²M) x = f` per line.
    pub fn receptance_direct(
        &self,
        response: usize,
        excitation: usize,
        freqs: &[f64],
    ) -> Result<Vec<Receptance>, BeamError> {
        self.check_node(response)?;
        self.check_node(excitation)?;
        let n = self.n_dof();
        let band = self.bandwidth();
        let mut a = vec![Complex64::new(0.0, 0.0); n * n];
        let mut b = vec![Complex64::new(0.0, 0.0); n * 2];
        let mut out = Vec::with_capacity(freqs.len());
        for &f in freqs {
            if !f.is_finite() || f < 0.0 {
                return Err(BeamError::BadFrequency(f));
            }
            let w = TAU * f;
            for (idx, z) in a.iter_mut().enumerate() {
                *z = Complex64::new(self.k[idx] - w * w * self.m[idx], self.k_loss[idx] + w * self.c[idx]);
            }
            b.fill(Complex64::new(0.0, 0.0));
            b[2 * excitation * 2] = Complex64::new(1.0, 0.0);
            b[(2 * excitation + 1) * 2 + 1] = Complex64::new(1.0, 0.0);
            if !complex_solve_banded(&mut a, n, band, &mut b, 2) {
                return Err(BeamError::Singular(f));
            }
            let (r0, r1) = (2 * response * 2, (2 * response + 1) * 2);
            out.push([[b[r0], b[r0 + 1]], [b[r1], b[r1 + 1]]]);
        }
        Ok(out)
    }

    /// Number of rigid-body modes left free by the springs: 2 minus the rank of the springs'
    /// stiffness against rigid translation and rotation.
    pub fn rigid_body_modes(&self) -> usize {
        let (mut tt, mut tr, mut rr) = (0.0, 0.0, 0.0);
        for (node, s) in &self.springs {
            let x = self.node_x[*node];
            tt += s.kt;
            tr += s.kt * x;
            rr += s.kt * x * x + s.kr;
        }
        if tt + rr == 0.0 {
            2
        } else if tt * rr - tr * tr > 1e-10 * tt * rr {
            0
        } else {
            1
        }
    }

    /// Undamped modes of the model, for the modal receptance form.
    pub fn modes(&self) -> Result<ModalModel, BeamError> {
        ModalModel::new(self)
    }
}

/// Modal form of a [`BeamModel`]: undamped modes of `K φ = ω² M φ` (mass-normalised) with the
/// hysteretic and viscous damping projected onto them. Rigid-body modes (free–free: one
/// translation, one rotation) have ω = 0 exactly and contribute `φφᵀ / (−ω²)`.
#[derive(Debug, Clone, PartialEq)]
pub struct ModalModel {
    n: usize,
    pub(super) lambda: Vec<f64>,
    pub(super) phi: Vec<f64>,
    /// Projected hysteretic stiffness Φᵀ K_η Φ (n×n).
    d: Vec<f64>,
    /// Projected viscous damping Φᵀ C Φ (n×n).
    cm: Vec<f64>,
    diagonal: bool,
    rigid: usize,
}

pub(super) fn project(a: &[f64], phi: &[f64], n: usize) -> Vec<f64> {
    let mut t = vec![0.0; n * n];
    for i in 0..n {
        for k in 0..n {
            let aik = a[i * n + k];
            if aik == 0.0 {
                continue;
            }
            for j in 0..n {
                t[i * n + j] += aik * phi[k * n + j];
            }
        }
    }
    let mut p = vec![0.0; n * n];
    for k in 0..n {
        for i in 0..n {
            let pki = phi[k * n + i];
            for j in 0..n {
                p[i * n + j] += pki * t[k * n + j];
            }
        }
    }
    p
}

impl ModalModel {
    /// Solves the undamped generalized eigenproblem and projects the damping.
    pub fn new(model: &BeamModel) -> Result<ModalModel, BeamError> {
        let n = model.n_dof();
        let (mut lambda, phi) = generalized_eigen(&model.k, &model.m, n).ok_or(BeamError::MassNotDefinite)?;
        // Rigid-body modes are the lowest ones; their eigenvalues are roundoff and set to 0.
        let rigid = model.rigid_body_modes();
        for l in lambda.iter_mut().take(rigid) {
            *l = 0.0;
        }
        let mut d = project(&model.k_loss, &phi, n);
        let mut cm = project(&model.c, &phi, n);
        for r in 0..rigid {
            for s in 0..n {
                d[r * n + s] = 0.0;
                d[s * n + r] = 0.0;
            }
        }
        let small = |mat: &[f64]| {
            let dmax = (0..n).fold(0.0f64, |a, i| a.max(mat[i * n + i].abs()));
            let floor = 1e-12 * dmax;
            (0..n).all(|i| {
                (0..n).all(|j| {
                    i == j
                        || mat[i * n + j].abs()
                            <= 1e-10 * (mat[i * n + i].abs().max(floor) * mat[j * n + j].abs().max(floor)).sqrt()
                })
            })
        };
        let diagonal = small(&d) && small(&cm);
        if diagonal {
            for i in 0..n {
                for j in 0..n {
                    if i != j {
                        d[i * n + j] = 0.0;
                        cm[i * n + j] = 0.0;
                    }
                }
            }
        }
        Ok(ModalModel { n, lambda, phi, d, cm, diagonal, rigid })
    }

    /// Natural frequencies, Hz, ascending (rigid-body modes first, at 0 Hz).
    pub fn natural_frequencies(&self) -> Vec<f64> {
        self.lambda.iter().map(|l| l.max(0.0).sqrt() / TAU).collect()
    }

    /// Number of rigid-body (zero-frequency) modes.
    pub fn rigid_modes(&self) -> usize {
        self.rigid
    }

    /// Whether the projected damping is diagonal (uniform η, no dampers), so each mode is
    /// summed independently; otherwise the coupled modal matrix is solved per line.
    pub fn is_diagonal(&self) -> bool {
        self.diagonal
    }

    /// Receptances between two nodes at each frequency (Hz) by modal expansion over all modes.
    pub fn receptance(&self, response: usize, excitation: usize, freqs: &[f64]) -> Result<Vec<Receptance>, BeamError> {
        let nodes = self.n / 2;
        for node in [response, excitation] {
            if node >= nodes {
                return Err(BeamError::NoSuchNode { node, nodes });
            }
        }
        let n = self.n;
        let row = |dof: usize| &self.phi[dof * n..(dof + 1) * n];
        let (ay, at) = (row(2 * response), row(2 * response + 1));
        let (by, bt) = (row(2 * excitation), row(2 * excitation + 1));
        let mut out = Vec::with_capacity(freqs.len());
        if self.diagonal {
            for &f in freqs {
                if !f.is_finite() || f < 0.0 {
                    return Err(BeamError::BadFrequency(f));
                }
                if f == 0.0 && self.rigid > 0 {
                    return Err(BeamError::Singular(f));
                }
            }
            let sum = ModalSum::new(&self.lambda, &self.d, &self.cm, n, [ay, at, by, bt]);
            sum.run(freqs, &mut out)?;
        } else {
            let mut z = vec![Complex64::new(0.0, 0.0); n * n];
            let mut q = vec![Complex64::new(0.0, 0.0); n * 2];
            for &f in freqs {
                if !f.is_finite() || f < 0.0 {
                    return Err(BeamError::BadFrequency(f));
                }
                let w = TAU * f;
                for i in 0..n {
                    for j in 0..n {
                        let re = if i == j { self.lambda[i] - w * w } else { 0.0 };
                        z[i * n + j] = Complex64::new(re, self.d[i * n + j] + w * self.cm[i * n + j]);
                    }
                    q[2 * i] = Complex64::new(by[i], 0.0);
                    q[2 * i + 1] = Complex64::new(bt[i], 0.0);
                }
                if !complex_solve(&mut z, n, &mut q, 2) {
                    return Err(BeamError::Singular(f));
                }
                let mut h = [[Complex64::new(0.0, 0.0); 2]; 2];
                for r in 0..n {
                    h[0][0] += ay[r] * q[2 * r];
                    h[0][1] += ay[r] * q[2 * r + 1];
                    h[1][0] += at[r] * q[2 * r];
                    h[1][1] += at[r] * q[2 * r + 1];
                }
                out.push(h);
            }
        }
        Ok(out)
    }
}

/// Appends one summed line `[Re H, Im H, Re L, …]` as a receptance block; a non-finite sum
/// means the frequency sits on an undamped pole.
fn push_line(out: &mut Vec<Receptance>, f: f64, a: [f64; 8]) -> Result<(), BeamError> {
    if a.iter().any(|v| !v.is_finite()) {
        return Err(BeamError::Singular(f));
    }
    let c = |k: usize| Complex64::new(a[k], a[k + 1]);
    out.push([[c(0), c(2)], [c(4), c(6)]]);
    Ok(())
}

/// Lanes of the modal sum: modes are summed in groups of 4, in a fixed order on every CPU.
const LANES: usize = 4;

/// Per-mode data of a diagonal modal receptance between two nodes: pole `λ_r − ω² + i(d_r +
/// ω c_r)` and the four residue products `φ_y φ_y, φ_y φ_θ, φ_θ φ_y, φ_θ φ_θ` of the response
/// and excitation dofs, packed per group of [`LANES`] modes so each line is one pass over a
/// contiguous block that vectorises.
struct ModalSum {
    /// Per group: λ, d, c, yy, yt, ty, tt (7 × LANES values).
    groups: Vec<[[f64; LANES]; 7]>,
}

impl ModalSum {
    fn new(lambda: &[f64], d: &[f64], c: &[f64], n: usize, rows: [&[f64]; 4]) -> ModalSum {
        let [ay, at, by, bt] = rows;
        // Padding lanes: a damped unit pole (never singular) with zero residues.
        let mut groups =
            vec![
                [[0.0; LANES], [1.0; LANES], [0.0; LANES], [0.0; LANES], [0.0; LANES], [0.0; LANES], [0.0; LANES]];
                n.div_ceil(LANES)
            ];
        for r in 0..n {
            let g = &mut groups[r / LANES];
            let l = r % LANES;
            g[0][l] = lambda[r];
            g[1][l] = d[r * n + r];
            g[2][l] = c[r * n + r];
            g[3][l] = ay[r] * by[r];
            g[4][l] = ay[r] * bt[r];
            g[5][l] = at[r] * by[r];
            g[6][l] = at[r] * bt[r];
        }
        for r in n..groups.len() * LANES {
            groups[r / LANES][0][r % LANES] = 1.0;
        }
        ModalSum { groups }
    }

    /// Receptance block at ω (rad/s): Σ_r residues / pole, as `[Re H, Im H, Re L, …]`.
    #[inline(always)]
    fn line(&self, w: f64) -> [f64; 8] {
        let w2 = w * w;
        let mut acc = [[0.0f64; LANES]; 8];
        for g in &self.groups {
            let re: [f64; LANES] = std::array::from_fn(|l| g[0][l] - w2);
            let im: [f64; LANES] = std::array::from_fn(|l| g[1][l] + w * g[2][l]);
            let den: [f64; LANES] = std::array::from_fn(|l| re[l] * re[l] + im[l] * im[l]);
            let inv: [f64; LANES] = std::array::from_fn(|l| 1.0 / den[l]);
            let gr: [f64; LANES] = std::array::from_fn(|l| re[l] * inv[l]);
            let gi: [f64; LANES] = std::array::from_fn(|l| -im[l] * inv[l]);
            for k in 0..4 {
                for l in 0..LANES {
                    acc[2 * k][l] += gr[l] * g[3 + k][l];
                    acc[2 * k + 1][l] += gi[l] * g[3 + k][l];
                }
            }
        }
        std::array::from_fn(|k| (acc[k][0] + acc[k][1]) + (acc[k][2] + acc[k][3]))
    }

    #[inline(always)]
    fn lines(&self, freqs: &[f64], out: &mut Vec<Receptance>) -> Result<(), BeamError> {
        for &f in freqs {
            let a = self.line(TAU * f);
            if a.iter().any(|v| !v.is_finite()) {
                return Err(BeamError::Singular(f));
            }
            out.push([
                [Complex64::new(a[0], a[1]), Complex64::new(a[2], a[3])],
                [Complex64::new(a[4], a[5]), Complex64::new(a[6], a[7])],
            ]);
        }
        Ok(())
    }

    /// [`ModalSum::line`] in 256-bit vectors, one group of modes per vector, operation for
    /// operation (no fused multiply-add), so the results are bit-identical.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn line_avx(&self, w: f64) -> [f64; 8] {
        use std::arch::x86_64::*;
        let (wv, w2) = (_mm256_set1_pd(w), _mm256_set1_pd(w * w));
        let (one, sign) = (_mm256_set1_pd(1.0), _mm256_set1_pd(-0.0));
        let mut acc = [_mm256_setzero_pd(); 8];
        for g in &self.groups {
            // SAFETY: each row of a group is a [f64; LANES] with LANES = 4 readable values.
            let v: [__m256d; 7] = std::array::from_fn(|k| unsafe { _mm256_loadu_pd(g[k].as_ptr()) });
            let re = _mm256_sub_pd(v[0], w2);
            let im = _mm256_add_pd(v[1], _mm256_mul_pd(wv, v[2]));
            let den = _mm256_add_pd(_mm256_mul_pd(re, re), _mm256_mul_pd(im, im));
            let inv = _mm256_div_pd(one, den);
            let gr = _mm256_mul_pd(re, inv);
            let gi = _mm256_mul_pd(_mm256_xor_pd(im, sign), inv);
            for k in 0..4 {
                acc[2 * k] = _mm256_add_pd(acc[2 * k], _mm256_mul_pd(gr, v[3 + k]));
                acc[2 * k + 1] = _mm256_add_pd(acc[2 * k + 1], _mm256_mul_pd(gi, v[3 + k]));
            }
        }
        std::array::from_fn(|k| {
            let mut a = [0.0f64; LANES];
            // SAFETY: `a` holds LANES = 4 writable values.
            unsafe { _mm256_storeu_pd(a.as_mut_ptr(), acc[k]) };
            (a[0] + a[1]) + (a[2] + a[3])
        })
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn lines_avx(&self, freqs: &[f64], out: &mut Vec<Receptance>) -> Result<(), BeamError> {
        for &f in freqs {
            let a = self.line_avx(TAU * f);
            push_line(out, f, a)?;
        }
        Ok(())
    }

    fn run(&self, freqs: &[f64], out: &mut Vec<Receptance>) -> Result<(), BeamError> {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU supports AVX, checked just above.
            return unsafe { self.lines_avx(freqs, out) };
        }
        self.lines(freqs, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::beam::{segments_from_sections, table::tool_holder_sections};

    #[test]
    fn vector_and_scalar_modal_sums_are_bit_identical() {
        let segs = segments_from_sections(&tool_holder_sections());
        // An element length that leaves the last group of modes partly padded.
        let model = [2e-3, 2.1e-3, 2.2e-3, 2.3e-3]
            .iter()
            .map(|&h| BeamModel::from_segments(&segs, &MeshOptions { max_element_length: h, ..MeshOptions::default() }))
            .find_map(|m| m.ok().filter(|m| m.n_dof() % LANES != 0))
            .expect("a mesh with padding");
        let modes = model.modes().unwrap();
        let (n, tip) = (modes.n, model.n_nodes() - 1);
        let row = |dof: usize| &modes.phi[dof * n..(dof + 1) * n];
        let sum =
            ModalSum::new(&modes.lambda, &modes.d, &modes.cm, n, [row(2 * tip), row(2 * tip + 1), row(0), row(1)]);
        let freqs: Vec<f64> = (0..500).map(|k| 3.7 + 41.3 * k as f64).collect();
        let (mut scalar, mut dispatched) = (Vec::new(), Vec::new());
        sum.lines(&freqs, &mut scalar).unwrap();
        sum.run(&freqs, &mut dispatched).unwrap();
        for (a, b) in scalar.iter().zip(&dispatched) {
            for (x, y) in a.iter().flatten().zip(b.iter().flatten()) {
                assert_eq!(x.re.to_bits(), y.re.to_bits());
                assert_eq!(x.im.to_bits(), y.im.to_bits());
            }
        }
    }
}
