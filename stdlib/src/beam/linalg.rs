//! Small dense linear algebra for the beam model: complex LU with partial pivoting and the
//! symmetric-definite generalized eigenproblem (Cholesky reduction + cyclic Jacobi).
//!
//! Jacobi is kept on purpose: its eigenvectors have high relative accuracy on the graded
//! matrices of steel–carbide assemblies (stiffnesses spanning ~15 orders of magnitude from
//! the first mode to the shortest element's). A QR-type symmetric solver (faer 0.24) gave
//! modal receptances 1e-4 away from the direct solve on such a model, where this one agrees
//! to 1e-8 (`rcsa::tests::two_fe_beams_coupled_equal_one_fe_model_of_the_assembly`).

use num_complex::Complex64;

/// Solves `a x = b` in place for several right-hand sides (`b` is n×r row-major) by LU with
/// partial pivoting; `a` (n×n row-major) is overwritten. Returns false if `a` is singular.
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

/// Cholesky factor `L` (lower, row-major) of a symmetric positive definite matrix.
fn cholesky(m: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; n * n];
    for j in 0..n {
        let mut d = m[j * n + j];
        for k in 0..j {
            d -= l[j * n + k] * l[j * n + k];
        }
        if d <= 0.0 || !d.is_finite() {
            return None;
        }
        let d = d.sqrt();
        l[j * n + j] = d;
        for i in j + 1..n {
            let mut s = m[i * n + j];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            l[i * n + j] = s / d;
        }
    }
    Some(l)
}

/// Eigenvalues and eigenvectors of a symmetric matrix by cyclic Jacobi rotations.
/// Returns (values, vectors) with vector `k` in column `k` of the row-major result.
fn jacobi(a: &mut [f64], n: usize, vectors: bool) -> (Vec<f64>, Vec<f64>) {
    let mut v = vec![0.0; if vectors { n * n } else { 0 }];
    for i in 0..n.min(v.len()) {
        v[i * n + i] = 1.0;
    }
    for _sweep in 0..100 {
        let mut off = 0.0;
        let mut diag = 0.0;
        for i in 0..n {
            diag += a[i * n + i] * a[i * n + i];
            for j in i + 1..n {
                off += a[i * n + j] * a[i * n + j];
            }
        }
        if off <= 1e-32 * diag {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = a[p * n + q];
                if apq == 0.0 {
                    continue;
                }
                let app = a[p * n + p];
                let aqq = a[q * n + q];
                if apq.abs() < 1e-300 || apq.abs() <= 1e-18 * (app.abs() * aqq.abs()).sqrt() {
                    a[p * n + q] = 0.0;
                    a[q * n + p] = 0.0;
                    continue;
                }
                let theta = (aqq - app) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let akp = a[k * n + p];
                    let akq = a[k * n + q];
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for k in 0..n {
                    let apk = a[p * n + k];
                    let aqk = a[q * n + k];
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
                if !vectors {
                    continue;
                }
                for k in 0..n {
                    let vkp = v[k * n + p];
                    let vkq = v[k * n + q];
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    ((0..n).map(|i| a[i * n + i]).collect(), v)
}

/// Generalized eigenproblem `K φ = λ M φ` (K symmetric, M symmetric positive definite).
/// Returns eigenvalues ascending and mass-normalised eigenvectors (φᵀMφ = 1), vector `k` in
/// column `k` of the row-major n×n result; `None` if M is not positive definite.
pub fn generalized_eigen(k: &[f64], m: &[f64], n: usize) -> Option<(Vec<f64>, Vec<f64>)> {
    let l = cholesky(m, n)?;
    // A = L⁻¹ K L⁻ᵀ: first X = L⁻¹ K (forward substitution per column), then A = L⁻¹ Xᵀ.
    let forward = |b: &mut [f64]| {
        // b is n×n row-major; solve L Y = B column by column in place.
        for c in 0..n {
            for i in 0..n {
                let mut s = b[i * n + c];
                for j in 0..i {
                    s -= l[i * n + j] * b[j * n + c];
                }
                b[i * n + c] = s / l[i * n + i];
            }
        }
    };
    let mut x = k.to_vec();
    forward(&mut x);
    let mut a = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            a[i * n + j] = x[j * n + i];
        }
    }
    forward(&mut a);
    for i in 0..n {
        for j in i + 1..n {
            let s = 0.5 * (a[i * n + j] + a[j * n + i]);
            a[i * n + j] = s;
            a[j * n + i] = s;
        }
    }
    let (vals, z) = jacobi(&mut a, n, true);
    // φ = L⁻ᵀ z (back substitution per column).
    let mut phi = z;
    for c in 0..n {
        for i in (0..n).rev() {
            let mut s = phi[i * n + c];
            for j in i + 1..n {
                s -= l[j * n + i] * phi[j * n + c];
            }
            phi[i * n + c] = s / l[i * n + i];
        }
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| vals[a].total_cmp(&vals[b]));
    let values = order.iter().map(|&i| vals[i]).collect();
    let mut vectors = vec![0.0; n * n];
    for (new, &old) in order.iter().enumerate() {
        for i in 0..n {
            vectors[i * n + new] = phi[i * n + old];
        }
    }
    Some((values, vectors))
}

/// Eigenvalues of a symmetric matrix (row-major, overwritten), ascending, by cyclic Jacobi.
pub fn symmetric_eigenvalues(a: &mut [f64], n: usize) -> Vec<f64> {
    let (mut vals, _) = jacobi(a, n, false);
    vals.sort_by(f64::total_cmp);
    vals
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
