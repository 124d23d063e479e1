//! The undamped generalized eigenproblem by Cholesky reduction and cyclic Jacobi rotations:
//! slow (O(n³) per sweep, several sweeps) but accurate component by component on graded
//! matrices (Demmel & Veselić 1992). faer's tridiagonal solver, even shift-inverted, leaves
//! the tip-rotation components of a 1 mm-element steel–carbide beam with a stiff spring off
//! (its tip P 3e-7 away from the direct solve undamped, 2e-4 with two loss factors, against
//! 3e-12 and 1e-9 here), so this solver stays selectable: [`super::EigenSolver::Jacobi`].

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
