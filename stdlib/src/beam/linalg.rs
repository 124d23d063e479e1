//! Dense linear algebra for the beam model, on `faer` (sequential, so results do not depend
//! on the thread count): complex LU solves and the symmetric-definite generalized
//! eigenproblem by Cholesky reduction.

use faer::linalg::solvers::SolveCore;
use faer::{Mat, Side};
use num_complex::Complex64;

/// Solves `a x = b` in place for several right-hand sides (`b` is n×r row-major) by LU with
/// partial pivoting; `a` is n×n row-major. Returns false if `a` is singular (the solution
/// is not finite).
pub fn complex_solve(a: &mut [Complex64], n: usize, b: &mut [Complex64], r: usize) -> bool {
    let am = Mat::<Complex64>::from_fn(n, n, |i, j| a[i * n + j]);
    let lu = am.partial_piv_lu();
    let mut x = Mat::<Complex64>::from_fn(n, r, |i, j| b[i * r + j]);
    lu.solve_in_place_with_conj(faer::Conj::No, x.as_mut());
    for i in 0..n {
        for j in 0..r {
            let v = x[(i, j)];
            if !(v.re.is_finite() && v.im.is_finite()) {
                return false;
            }
            b[i * r + j] = v;
        }
    }
    true
}

/// Generalized eigenproblem `K φ = λ M φ` (K symmetric, M symmetric positive definite).
/// Returns eigenvalues ascending and mass-normalised eigenvectors (φᵀMφ = 1), vector `k` in
/// column `k` of the row-major n×n result; `None` if M is not positive definite.
pub fn generalized_eigen(k: &[f64], m: &[f64], n: usize) -> Option<(Vec<f64>, Vec<f64>)> {
    let mm = Mat::<f64>::from_fn(n, n, |i, j| m[i * n + j]);
    let llt = mm.llt(Side::Lower).ok()?;
    let l = llt.L();
    // A = L⁻¹ K L⁻ᵀ: X = L⁻¹ K, then A = L⁻¹ Xᵀ (K symmetric).
    let mut x = Mat::<f64>::from_fn(n, n, |i, j| k[i * n + j]);
    l.solve_lower_triangular_in_place(x.as_mut());
    let mut a = x.transpose().to_owned();
    l.solve_lower_triangular_in_place(a.as_mut());
    let a = Mat::<f64>::from_fn(n, n, |i, j| 0.5 * (a[(i, j)] + a[(j, i)]));
    let evd = a.self_adjoint_eigen(Side::Lower).ok()?;
    // φ = L⁻ᵀ u, so that φᵀ M φ = uᵀ u = 1.
    let mut phi = evd.U().to_owned();
    l.transpose().solve_upper_triangular_in_place(phi.as_mut());
    let values: Vec<f64> = evd.S().column_vector().iter().copied().collect();
    let mut vectors = vec![0.0; n * n];
    for i in 0..n {
        for c in 0..n {
            vectors[i * n + c] = phi[(i, c)];
        }
    }
    Some((values, vectors))
}
#[cfg(test)]
mod tests {
    use super::*;
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
