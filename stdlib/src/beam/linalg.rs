//! Dense linear algebra for the beam model: banded complex LU with partial pivoting (direct
//! receptances), the undamped generalized eigenproblem in shift-inverted form, and the complex
//! symmetric factorization and eigen-decomposition of non-proportional structural damping.
//! The eigen-solvers and Cholesky are faer's; the graded stiffness of steel–carbide
//! assemblies is handled by the shift-invert (see [`ShiftedModes`]).

use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_upper_triangular_in_place};
use faer::{Mat, Par, Side, c64};
use num_complex::Complex64;

/// Solves `a x = b` in place for several right-hand sides (`b` is n×r row-major) by LU with
/// partial pivoting; `a` (n×n row-major) is overwritten. Returns false if `a` is singular.
#[cfg(test)]
pub fn complex_solve(a: &mut [Complex64], n: usize, b: &mut [Complex64], r: usize) -> bool {
    complex_solve_banded(a, n, n.saturating_sub(1), b, r)
}

/// [`complex_solve`] for a matrix whose entries vanish beyond `band` of the diagonal
/// (`a[i][j] = 0` for `|i − j| > band`): pivot rows lie within the band and the fill of the
/// upper factor within twice the band, so a beam's solve costs O(n·band²) instead of O(n³).
/// Entries outside the band are never read or written except for that fill, so they must be
/// zero. The arithmetic on the non-zero entries is the dense algorithm's.
pub fn complex_solve_banded(a: &mut [Complex64], n: usize, band: usize, b: &mut [Complex64], r: usize) -> bool {
    let zero = Complex64::new(0.0, 0.0);
    for k in 0..n {
        let rows = (k + band + 1).min(n);
        let cols = (k + 2 * band + 1).min(n);
        let mut p = k;
        let mut best = a[k * n + k].norm();
        for i in k + 1..rows {
            let v = a[i * n + k].norm();
            if v > best {
                best = v;
                p = i;
            }
        }
        if best == 0.0 || !best.is_finite() {
            return false;
        }
        if p != k {
            for j in k..cols {
                a.swap(k * n + j, p * n + j);
            }
            for j in 0..r {
                b.swap(k * r + j, p * r + j);
            }
        }
        let inv = 1.0 / a[k * n + k];
        for i in k + 1..rows {
            let f = a[i * n + k] * inv;
            if f == zero {
                continue;
            }
            for j in k + 1..cols {
                let v = a[k * n + j];
                a[i * n + j] -= f * v;
            }
            for j in 0..r {
                let v = b[k * r + j];
                b[i * r + j] -= f * v;
            }
        }
    }
    for k in (0..n).rev() {
        let cols = (k + 2 * band + 1).min(n);
        let inv = 1.0 / a[k * n + k];
        for j in 0..r {
            let mut s = b[k * r + j];
            for i in k + 1..cols {
                s -= a[k * n + i] * b[i * r + j];
            }
            b[k * r + j] = s * inv;
        }
    }
    true
}

/// Largest `|i − j|` with a non-zero entry in any of the n×n matrices.
pub fn bandwidth(mats: &[&[f64]], n: usize) -> usize {
    let mut band = 0;
    for m in mats {
        for i in 0..n {
            for j in i + band + 1..n {
                if m[i * n + j] != 0.0 || m[j * n + i] != 0.0 {
                    band = j - i;
                }
            }
        }
    }
    band
}

/// A complex symmetric banded matrix factored as `A = CᵀC` (C upper triangular with the same
/// half-bandwidth b, no pivoting, no conjugation): for `K + iK_η + σM`, positive definite
/// plus a small imaginary part, as stable as the real Cholesky factorization.
#[derive(Debug, Clone, PartialEq)]
pub struct BandCholesky {
    n: usize,
    band: usize,
    /// `C[i][i + t]` at `i·(b + 1) + t`.
    c: Vec<Complex64>,
    /// `1 / C[i][i]`: substitution multiplies.
    inv_diag: Vec<Complex64>,
}

impl BandCholesky {
    /// Factors the symmetric matrix with entries `a(i, j)` (read for `i ≤ j ≤ i + band`);
    /// `None` at a zero or non-finite pivot.
    pub fn new(n: usize, band: usize, a: impl Fn(usize, usize) -> Complex64) -> Option<BandCholesky> {
        let w = band + 1;
        let mut c: Vec<Complex64> = (0..n * w)
            .map(|k| (k / w, k / w + k % w))
            .map(|(i, j)| if j < n { a(i, j) } else { Complex64::new(0.0, 0.0) })
            .collect();
        let mut inv_diag = vec![Complex64::new(0.0, 0.0); n];
        for j in 0..n {
            let d = c[j * w];
            if d.norm() == 0.0 || !d.is_finite() {
                return None;
            }
            let r = d.sqrt();
            let inv = 1.0 / r;
            c[j * w] = r;
            inv_diag[j] = inv;
            for t in 1..w {
                c[j * w + t] *= inv;
            }
            for t in 1..w.min(n - j) {
                let f = c[j * w + t];
                let i = j + t;
                for u in t..w {
                    let v = c[j * w + u];
                    c[i * w + u - t] -= f * v;
                }
            }
        }
        Some(BandCholesky { n, band, c, inv_diag })
    }

    /// Solves `Cᵀ y = x` in place (forward substitution; leading zeros of x stay zero).
    pub fn solve_transposed(&self, x: &mut [Complex64]) {
        let (n, w) = (self.n, self.band + 1);
        let Some(first) = x.iter().position(|v| v.re != 0.0 || v.im != 0.0) else { return };
        for i in first..n {
            let lo = i.saturating_sub(self.band).max(first);
            // C[k][i] sits at k·w + i − k = k·(w − 1) + i.
            let s: Complex64 = x[lo..i].iter().zip(lo..).map(|(&xk, k)| self.c[k * (w - 1) + i] * xk).sum();
            x[i] = (x[i] - s) * self.inv_diag[i];
        }
    }

    /// `C⁻ᵀ M C⁻¹` (row-major n×n, symmetric) of a symmetric real `m` (row-major n×n): with C
    /// banded, O(n²b).
    pub fn congruence(&self, m: &[f64]) -> Vec<Complex64> {
        let n = self.n;
        // W = C⁻ᵀM, then C⁻ᵀWᵀ = C⁻ᵀMC⁻¹ (M is symmetric).
        let mut w: Vec<Complex64> = m.iter().map(|&v| Complex64::new(v, 0.0)).collect();
        self.solve_transposed_rows(&mut w);
        let mut v = vec![Complex64::new(0.0, 0.0); n * n];
        for i in 0..n {
            for j in 0..n {
                v[i * n + j] = w[j * n + i];
            }
        }
        self.solve_transposed_rows(&mut v);
        for i in 0..n {
            for j in 0..i {
                let a = 0.5 * (v[i * n + j] + v[j * n + i]);
                v[i * n + j] = a;
                v[j * n + i] = a;
            }
        }
        v
    }

    /// Solves `Cᵀ Y = B` in place for the n columns of `b` (row-major n×n) at once: row i of
    /// Y is row i of B less the rows above it, so each step is an axpy along a whole row.
    fn solve_transposed_rows(&self, b: &mut [Complex64]) {
        let (n, w) = (self.n, self.band + 1);
        for i in 0..n {
            let (above, rest) = b.split_at_mut(i * n);
            let row = &mut rest[..n];
            for k in i.saturating_sub(self.band)..i {
                // C[k][i] sits at k·w + i − k.
                let c = self.c[k * (w - 1) + i];
                for (y, &x) in row.iter_mut().zip(&above[k * n..(k + 1) * n]) {
                    *y -= c * x;
                }
            }
            let inv = self.inv_diag[i];
            for y in row.iter_mut() {
                *y *= inv;
            }
        }
    }
}

/// Undamped modes of `K φ = λ M φ` in shift-inverted form: with `K_σ = K + σM = L Lᵀ`, the
/// symmetric matrix `L⁻¹ M L⁻ᵀ` has eigenvalues `μ = 1/(λ + σ)` and eigenvectors `y`, and
/// `z = L⁻ᵀ y` satisfies `zᵀ K_σ z = 1`, `zᵀ M z = μ`.
///
/// Why shift-invert: a backward-stable eigen-solver errs by about ε·‖A‖ on every eigenvalue.
/// On `L_M⁻¹ K L_M⁻ᵀ` that is ε·λ_max, and a steel–carbide assembly with short elements or
/// stiff springs has λ_max/λ_1 up to 1e15, which leaves the lowest modes with few correct
/// digits. Inverted, the lowest modes are the largest eigenvalues (μ ≤ 1/σ) and keep nearly
/// full relative accuracy; the stiffest modes shrink towards 0, where their absolute error is
/// harmless because they enter receptances as `z zᵀ/(1 − sμ)`, a static flexibility.
#[derive(Debug, Clone, PartialEq)]
pub struct ShiftedModes {
    /// The shift σ, rad²/s².
    pub sigma: f64,
    /// `μ_r = 1/(λ_r + σ)`, descending (lowest natural frequency first).
    pub mu: Vec<f64>,
    /// `z_r` in column r of the row-major n×n matrix.
    pub z: Vec<f64>,
}

/// Solves the undamped generalized eigenproblem (K symmetric positive semi-definite, M
/// symmetric positive definite, both n×n row-major) with shift σ > 0 by faer's Cholesky and
/// self-adjoint eigen-solver; `None` if `K + σM` is not positive definite.
pub fn shifted_eigen(k: &[f64], m: &[f64], n: usize, sigma: f64) -> Option<ShiftedModes> {
    let ks = Mat::<f64>::from_fn(n, n, |i, j| k[i * n + j] + sigma * m[i * n + j]);
    let llt = ks.llt(Side::Lower).ok()?;
    let l = llt.L();
    // B = L⁻¹ M L⁻ᵀ: X = L⁻¹ M, then B = L⁻¹ Xᵀ (M is symmetric).
    let mut x = Mat::<f64>::from_fn(n, n, |i, j| m[i * n + j]);
    solve_lower_triangular_in_place(l, x.as_mut(), Par::Seq);
    let mut b = x.transpose().to_owned();
    solve_lower_triangular_in_place(l, b.as_mut(), Par::Seq);
    let b = Mat::<f64>::from_fn(n, n, |i, j| 0.5 * (b[(i, j)] + b[(j, i)]));
    let evd = b.self_adjoint_eigen(Side::Lower).ok()?;
    let mut z = evd.U().to_owned();
    solve_upper_triangular_in_place(l.transpose(), z.as_mut(), Par::Seq);
    let s = evd.S().column_vector();
    // faer sorts ascending; the lowest natural frequency has the largest μ.
    let mu: Vec<f64> = (0..n).rev().map(|r| s[r]).collect();
    let mut zr = vec![0.0; n * n];
    for i in 0..n {
        for (c, r) in (0..n).rev().enumerate() {
            zr[i * n + c] = z[(i, r)];
        }
    }
    if mu.iter().any(|v| !v.is_finite()) || zr.iter().any(|v| !v.is_finite()) {
        return None;
    }
    Some(ShiftedModes { sigma, mu, z: zr })
}

/// Generalized eigenproblem `K φ = λ M φ` (K symmetric, M symmetric positive definite):
/// eigenvalues ascending and mass-normalised eigenvectors (φᵀMφ = 1), vector `k` in column `k`
/// of the row-major n×n result; `None` if `K + σM` is not positive definite. The shift σ is
/// the mean of the diagonal ratios `K_ii/M_ii` scaled down by n⁴ (a free–free beam's lowest
/// flexible mode lies about that far below its element modes).
#[cfg(test)]
pub fn generalized_eigen(k: &[f64], m: &[f64], n: usize) -> Option<(Vec<f64>, Vec<f64>)> {
    let sigma = default_shift(k, m, n);
    let modes = shifted_eigen(k, m, n, sigma)?;
    let mut phi = modes.z.clone();
    for (c, mu) in modes.mu.iter().enumerate() {
        let scale = 1.0 / mu.sqrt();
        for i in 0..n {
            phi[i * n + c] *= scale;
        }
    }
    Some((modes.mu.iter().map(|mu| 1.0 / mu - sigma).collect(), phi))
}

/// A shift for [`shifted_eigen`] near the lowest flexible mode, from the matrices alone: a
/// uniform free–free beam of N elements has λ_1 ≈ 16 K_ii/(M_ii N⁴) for its translational
/// dofs (n = 2N dofs, so λ_1 ≈ 256·K_ii/(M_ii n⁴)). The median ratio is used so that a stiff
/// spring at one node does not move the shift. Being a decade off costs about a digit.
pub fn default_shift(k: &[f64], m: &[f64], n: usize) -> f64 {
    let mut ratios: Vec<f64> =
        (0..n).step_by(2).map(|i| k[i * n + i] / m[i * n + i]).filter(|r| r.is_finite() && *r > 0.0).collect();
    if ratios.is_empty() {
        return 1.0;
    }
    ratios.sort_by(f64::total_cmp);
    let median = ratios[ratios.len() / 2];
    let scale = ((n as f64).powi(4) / 256.0).max(1.0);
    median / scale
}

/// Eigenvalues of a symmetric matrix (row-major), ascending, by faer's self-adjoint solver.
pub fn symmetric_eigenvalues(a: &[f64], n: usize) -> Option<Vec<f64>> {
    let mat = Mat::<f64>::from_fn(n, n, |i, j| 0.5 * (a[i * n + j] + a[j * n + i]));
    mat.self_adjoint_eigenvalues(Side::Lower).ok()
}

/// Factors a complex symmetric (not Hermitian) matrix as `T = Rᵀ R`, R upper triangular, in
/// place (the upper triangle of `t`, row-major n×n, becomes R; the strict lower triangle is
/// zeroed). No pivoting: meant for `T = I + iE` with E real symmetric and small, whose
/// factorization is stable; returns false on a zero or non-finite pivot. faer's Cholesky and
/// LDLᵀ are Hermitian (they conjugate), so this one is written out.
pub fn complex_symmetric_cholesky(t: &mut [Complex64], n: usize) -> bool {
    // Right-looking, by rows, on split real and imaginary parts (so the updates run along
    // contiguous f64 rows and vectorise): row j of R is final once the rows above have
    // updated it.
    let mut re: Vec<f64> = t.iter().map(|z| z.re).collect();
    let mut im: Vec<f64> = t.iter().map(|z| z.im).collect();
    for j in 0..n {
        let (done_re, rest_re) = re.split_at_mut((j + 1) * n);
        let (done_im, rest_im) = im.split_at_mut((j + 1) * n);
        let (row_re, row_im) = (&mut done_re[j * n..], &mut done_im[j * n..]);
        let d = Complex64::new(row_re[j], row_im[j]);
        if d.norm() == 0.0 || !d.is_finite() {
            return false;
        }
        let r = d.sqrt();
        let inv = 1.0 / r;
        row_re[j] = r.re;
        row_im[j] = r.im;
        for (a, b) in row_re[j + 1..].iter_mut().zip(&mut row_im[j + 1..]) {
            let v = Complex64::new(*a, *b) * inv;
            (*a, *b) = (v.re, v.im);
        }
        row_re[..j].fill(0.0);
        row_im[..j].fill(0.0);
        let (row_re, row_im) = (&row_re[..], &row_im[..]);
        for i in j + 1..n {
            let (fr, fi) = (row_re[i], row_im[i]);
            let span = (i - j - 1) * n + i..(i - j) * n;
            let (tr, ti) = (&mut rest_re[span.clone()], &mut rest_im[span]);
            for (((ar, ai), &br), &bi) in tr.iter_mut().zip(ti.iter_mut()).zip(&row_re[i..]).zip(&row_im[i..]) {
                *ar -= fr * br - fi * bi;
                *ai -= fr * bi + fi * br;
            }
        }
    }
    for (z, (&a, &b)) in t.iter_mut().zip(re.iter().zip(&im)) {
        *z = Complex64::new(a, b);
    }
    true
}

/// Eigen-decomposition of a complex symmetric matrix `V = Y diag(ν) Yᵀ` with `YᵀY = I`, by
/// faer's general complex eigen-solver and complex-orthogonal normalisation of each vector.
/// `None` if the solver fails or a vector is (nearly) self-orthogonal, `yᵀy ≈ 0`, which means
/// the matrix is (nearly) defective and the modal form does not exist.
pub fn complex_symmetric_eigen(v: &[Complex64], n: usize) -> Option<(Vec<Complex64>, Vec<Complex64>)> {
    let mat = Mat::<c64>::from_fn(n, n, |i, j| {
        let a = v[i * n + j];
        c64::new(a.re, a.im)
    });
    let evd = mat.eigen().ok()?;
    let (u, s) = (evd.U(), evd.S().column_vector());
    let mut nu = Vec::with_capacity(n);
    let mut y = vec![Complex64::new(0.0, 0.0); n * n];
    for c in 0..n {
        let mut dot = Complex64::new(0.0, 0.0);
        let mut norm = 0.0;
        for i in 0..n {
            let e = Complex64::new(u[(i, c)].re, u[(i, c)].im);
            dot += e * e;
            norm += e.norm_sqr();
        }
        if dot.norm().partial_cmp(&(1e-6 * norm)) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let scale = 1.0 / dot.sqrt();
        for i in 0..n {
            y[i * n + c] = Complex64::new(u[(i, c)].re, u[(i, c)].im) * scale;
        }
        nu.push(Complex64::new(s[c].re, s[c].im));
    }
    Some((nu, y))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `CᵀC` rebuilds a banded complex symmetric matrix, and the congruence equals the dense
    /// `C⁻ᵀ M C⁻¹` (checked as `Cᵀ V C = M`).
    #[test]
    fn band_cholesky_factors_and_its_congruence_inverts() {
        let (n, band) = (9, 3);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut a = vec![Complex64::new(0.0, 0.0); n * n];
        let mut m = vec![0.0; n * n];
        for i in 0..n {
            for j in i..(i + band + 1).min(n) {
                let (re, im) = if i == j {
                    (4.0 + rng.random::<f64>(), 0.1)
                } else {
                    (rng.random::<f64>() - 0.5, 0.05 * (rng.random::<f64>() - 0.5))
                };
                a[i * n + j] = Complex64::new(re, im);
                a[j * n + i] = a[i * n + j];
                let mv = if i == j { 2.0 } else { 0.3 * (rng.random::<f64>() - 0.5) };
                m[i * n + j] = mv;
                m[j * n + i] = mv;
            }
        }
        let f = BandCholesky::new(n, band, |i, j| a[i * n + j]).unwrap();
        let c = |i: usize, j: usize| {
            if j >= i && j <= i + band { f.c[i * (band + 1) + j - i] } else { Complex64::new(0.0, 0.0) }
        };
        for i in 0..n {
            for j in 0..n {
                let ctc: Complex64 = (0..n).map(|k| c(k, i) * c(k, j)).sum();
                assert!((ctc - a[i * n + j]).norm() < 1e-13, "CᵀC [{i}][{j}]");
            }
        }
        let v = f.congruence(&m);
        for i in 0..n {
            for j in 0..n {
                let back: Complex64 = (0..n)
                    .flat_map(|k| (0..n).map(move |l| (k, l)))
                    .map(|(k, l)| c(k, i) * v[k * n + l] * c(l, j))
                    .sum();
                assert!((back - m[i * n + j]).norm() < 1e-12, "CᵀVC [{i}][{j}] = {back}");
            }
        }
    }
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn generalized_eigen_satisfies_definition_and_normalisation() {
        let n = 12;
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut b = vec![0.0; n * n];
        let mut c = vec![0.0; n * n];
        for v in b.iter_mut().chain(c.iter_mut()) {
            *v = rng.random_range(-1.0..1.0);
        }
        let mut k = vec![0.0; n * n];
        let mut m = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                for l in 0..n {
                    k[i * n + j] += b[i * n + l] * b[j * n + l];
                    m[i * n + j] += c[i * n + l] * c[j * n + l];
                }
            }
            m[i * n + i] += 0.5;
        }
        let (vals, phi) = generalized_eigen(&k, &m, n).unwrap();
        for r in 0..n {
            for i in 0..n {
                let kv: f64 = (0..n).map(|j| k[i * n + j] * phi[j * n + r]).sum();
                let mv: f64 = (0..n).map(|j| m[i * n + j] * phi[j * n + r]).sum();
                assert!((kv - vals[r] * mv).abs() < 1e-9 * (1.0 + vals[r].abs()), "mode {r}");
            }
            let norm: f64 =
                (0..n).map(|i| (0..n).map(|j| phi[i * n + r] * m[i * n + j] * phi[j * n + r]).sum::<f64>()).sum();
            assert!((norm - 1.0).abs() < 1e-10);
        }
        assert!(vals.windows(2).all(|w| w[0] <= w[1]));
    }

    #[test]
    fn banded_lu_matches_dense_lu_and_needs_pivoting() {
        let (n, band) = (17, 3);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut a = vec![Complex64::new(0.0, 0.0); n * n];
        for i in 0..n {
            for j in i.saturating_sub(band)..(i + band + 1).min(n) {
                a[i * n + j] = Complex64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            }
            // Small diagonal: partial pivoting must swap rows inside the band.
            a[i * n + i] *= 1e-3;
        }
        assert_eq!(bandwidth(&[&a.iter().map(|z| z.norm()).collect::<Vec<_>>()], n), band);
        let x: Vec<Complex64> = (0..2 * n).map(|k| Complex64::new(k as f64 * 0.1 - 1.0, 0.3)).collect();
        let b: Vec<Complex64> = (0..n)
            .flat_map(|i| (0..2).map(move |c| (i, c)))
            .map(|(i, c)| (0..n).map(|j| a[i * n + j] * x[j * 2 + c]).sum())
            .collect();
        let (mut ab, mut bb) = (a.clone(), b.clone());
        let (mut ad, mut bd) = (a.clone(), b.clone());
        assert!(complex_solve_banded(&mut ab, n, band, &mut bb, 2));
        assert!(complex_solve(&mut ad, n, &mut bd, 2));
        for k in 0..2 * n {
            assert!((bb[k] - x[k]).norm() < 1e-10, "{k}: {} vs {}", bb[k], x[k]);
            assert!((bb[k] - bd[k]).norm() < 1e-13);
        }
    }

    #[test]
    fn complex_lu_solves_random_system() {
        let n = 9;
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let a: Vec<Complex64> =
            (0..n * n).map(|_| Complex64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))).collect();
        let x: Vec<Complex64> =
            (0..n).map(|_| Complex64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))).collect();
        let mut b: Vec<Complex64> = (0..n).map(|i| (0..n).map(|j| a[i * n + j] * x[j]).sum()).collect();
        let mut lu = a.clone();
        assert!(complex_solve(&mut lu, n, &mut b, 1));
        for i in 0..n {
            assert!((b[i] - x[i]).norm() < 1e-12);
        }
        let mut z = vec![Complex64::new(0.0, 0.0); n * n];
        assert!(!complex_solve(&mut z, n, &mut b, 1));
    }
}
