//! Eigenvalues of a small dense real matrix: balancing, reduction to Hessenberg form by stabilised elementary
//! similarity transforms and the shifted Francis double-step QR iteration (Wilkinson & Reinsch, *Handbook for
//! Automatic Computation* II, procedures balance, elmhes and hqr).

/// Eigenvalues of the row-major `n × n` matrix `a` (destroyed), as `(re, im)` pairs, complex pairs adjacent.
/// `None` if the QR iteration does not converge.
pub(crate) fn eigenvalues(a: &mut [f64], n: usize, out: &mut Vec<(f64, f64)>) -> Option<()> {
    out.clear();
    let n = deflate(a, n, out);
    let a = &mut a[..n * n];
    balance(a, n);
    hessenberg(a, n);
    hqr(a, n, out)
}

/// Eigenvalues of the row-major upper Hessenberg `n × n` matrix `a` (destroyed) by the QR iteration alone.
pub(crate) fn hessenberg_eigenvalues(a: &mut [f64], n: usize, out: &mut Vec<(f64, f64)>) -> Option<()> {
    out.clear();
    hqr(a, n, out)
}

/// Removes, one at a time, indices whose column or row is zero outside the diagonal-free remainder: each is
/// an eigenvalue `a_jj` of a block-triangular permutation, and the rest of the spectrum is that of the compacted
/// matrix. Returns the remaining order (matrix compacted in place) and pushes the removed eigenvalues to `out`.
pub(crate) fn deflate(a: &mut [f64], n: usize, out: &mut Vec<(f64, f64)>) -> usize {
    let mut keep: Vec<usize> = (0..n).collect();
    loop {
        let before = keep.len();
        let mut k = 0;
        while k < keep.len() {
            let j = keep[k];
            let col_zero = keep.iter().all(|&i| i == j || a[i * n + j] == 0.0);
            let row_zero = keep.iter().all(|&i| i == j || a[j * n + i] == 0.0);
            if col_zero || row_zero {
                out.push((a[j * n + j], 0.0));
                keep.remove(k);
            } else {
                k += 1;
            }
        }
        if keep.len() == before {
            break;
        }
    }
    let r = keep.len();
    for (ni, &i) in keep.iter().enumerate() {
        for (nj, &j) in keep.iter().enumerate() {
            a[ni * r + nj] = a[i * n + j];
        }
    }
    r
}

fn balance(a: &mut [f64], n: usize) {
    const RADIX: f64 = 2.0;
    let mut done = false;
    let mut sweeps = 0;
    while !done && sweeps < 100 {
        done = true;
        sweeps += 1;
        for i in 0..n {
            let (mut c, mut r) = (0.0, 0.0);
            for j in 0..n {
                if j != i {
                    c += a[j * n + i].abs();
                    r += a[i * n + j].abs();
                }
            }
            if c != 0.0 && r != 0.0 {
                let s = c + r;
                let mut f = 1.0;
                let mut g = r / RADIX;
                while c < g {
                    f *= RADIX;
                    c *= RADIX * RADIX;
                }
                g = r * RADIX;
                while c > g {
                    f /= RADIX;
                    c /= RADIX * RADIX;
                }
                if (c + r) / f < 0.95 * s {
                    done = false;
                    let g = 1.0 / f;
                    for j in 0..n {
                        a[i * n + j] *= g;
                    }
                    for j in 0..n {
                        a[j * n + i] *= f;
                    }
                }
            }
        }
    }
}

fn hessenberg(a: &mut [f64], n: usize) {
    for m in 1..n.saturating_sub(1) {
        let mut x: f64 = 0.0;
        let mut i = m;
        for j in m..n {
            if a[j * n + m - 1].abs() > x.abs() {
                x = a[j * n + m - 1];
                i = j;
            }
        }
        if i != m {
            for j in (m - 1)..n {
                a.swap(i * n + j, m * n + j);
            }
            for j in 0..n {
                a.swap(j * n + i, j * n + m);
            }
        }
        if x != 0.0 {
            for i in (m + 1)..n {
                let mut y = a[i * n + m - 1];
                if y != 0.0 {
                    y /= x;
                    a[i * n + m - 1] = 0.0;
                    for j in m..n {
                        a[i * n + j] -= y * a[m * n + j];
                    }
                    for j in 0..n {
                        a[j * n + m] += y * a[j * n + i];
                    }
                }
            }
        }
    }
}

fn sign(a: f64, b: f64) -> f64 {
    if b >= 0.0 { a.abs() } else { -a.abs() }
}

#[allow(clippy::many_single_char_names, unused_assignments)]
fn hqr(a: &mut [f64], n: usize, out: &mut Vec<(f64, f64)>) -> Option<()> {
    if n == 0 {
        return Some(());
    }
    let idx = |i: isize, j: isize| i as usize * n + j as usize;
    let mut wr = vec![0.0; n];
    let mut wi = vec![0.0; n];
    let mut anorm = 0.0;
    for i in 0..n {
        for j in i.saturating_sub(1)..n {
            anorm += a[i * n + j].abs();
        }
    }
    let mut nn = n as isize - 1;
    let mut t = 0.0;
    let (mut p, mut q, mut r, mut s, mut w, mut x, mut y, mut z) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    while nn >= 0 {
        let mut its = 0;
        loop {
            let mut l = nn;
            while l > 0 {
                s = a[idx(l - 1, l - 1)].abs() + a[idx(l, l)].abs();
                if s == 0.0 {
                    s = anorm;
                }
                if a[idx(l, l - 1)].abs() <= f64::EPSILON * s {
                    a[idx(l, l - 1)] = 0.0;
                    break;
                }
                l -= 1;
            }
            x = a[idx(nn, nn)];
            if l == nn {
                wr[nn as usize] = x + t;
                wi[nn as usize] = 0.0;
                nn -= 1;
            } else {
                y = a[idx(nn - 1, nn - 1)];
                w = a[idx(nn, nn - 1)] * a[idx(nn - 1, nn)];
                if l == nn - 1 {
                    p = 0.5 * (y - x);
                    q = p * p + w;
                    z = q.abs().sqrt();
                    x += t;
                    let (i1, i0) = (nn as usize, nn as usize - 1);
                    if q >= 0.0 {
                        z = p + sign(z, p);
                        wr[i0] = x + z;
                        wr[i1] = x + z;
                        if z != 0.0 {
                            wr[i1] = x - w / z;
                        }
                        wi[i0] = 0.0;
                        wi[i1] = 0.0;
                    } else {
                        wr[i0] = x + p;
                        wr[i1] = x + p;
                        wi[i0] = -z;
                        wi[i1] = z;
                    }
                    nn -= 2;
                } else {
                    if its == 150 {
                        return None;
                    }
                    if its > 0 && its % 10 == 0 {
                        t += x;
                        for i in 0..=nn {
                            a[idx(i, i)] -= x;
                        }
                        s = a[idx(nn, nn - 1)].abs() + a[idx(nn - 1, nn - 2)].abs();
                        x = 0.75 * s;
                        y = x;
                        w = -0.4375 * s * s;
                    }
                    its += 1;
                    let mut m = nn - 2;
                    while m >= l {
                        z = a[idx(m, m)];
                        r = x - z;
                        s = y - z;
                        p = (r * s - w) / a[idx(m + 1, m)] + a[idx(m, m + 1)];
                        q = a[idx(m + 1, m + 1)] - z - r - s;
                        r = a[idx(m + 2, m + 1)];
                        s = p.abs() + q.abs() + r.abs();
                        p /= s;
                        q /= s;
                        r /= s;
                        if m == l {
                            break;
                        }
                        let u = a[idx(m, m - 1)].abs() * (q.abs() + r.abs());
                        let v = p.abs() * (a[idx(m - 1, m - 1)].abs() + z.abs() + a[idx(m + 1, m + 1)].abs());
                        if u <= f64::EPSILON * v {
                            break;
                        }
                        m -= 1;
                    }
                    for i in m..(nn - 1) {
                        a[idx(i + 2, i)] = 0.0;
                        if i != m {
                            a[idx(i + 2, i - 1)] = 0.0;
                        }
                    }
                    let mut k = m;
                    while k < nn {
                        if k != m {
                            p = a[idx(k, k - 1)];
                            q = a[idx(k + 1, k - 1)];
                            r = 0.0;
                            if k + 1 != nn {
                                r = a[idx(k + 2, k - 1)];
                            }
                            x = p.abs() + q.abs() + r.abs();
                            if x != 0.0 {
                                p /= x;
                                q /= x;
                                r /= x;
                            }
                        }
                        s = sign((p * p + q * q + r * r).sqrt(), p);
                        if s != 0.0 {
                            if k == m {
                                if l != m {
                                    a[idx(k, k - 1)] = -a[idx(k, k - 1)];
                                }
                            } else {
                                a[idx(k, k - 1)] = -s * x;
                            }
                            p += s;
                            x = p / s;
                            y = q / s;
                            z = r / s;
                            q /= p;
                            r /= p;
                            for j in k..=nn {
                                p = a[idx(k, j)] + q * a[idx(k + 1, j)];
                                if k + 1 != nn {
                                    p += r * a[idx(k + 2, j)];
                                    a[idx(k + 2, j)] -= p * z;
                                }
                                a[idx(k + 1, j)] -= p * y;
                                a[idx(k, j)] -= p * x;
                            }
                            let mmin = if nn < k + 3 { nn } else { k + 3 };
                            for i in l..=mmin {
                                p = x * a[idx(i, k)] + y * a[idx(i, k + 1)];
                                if k + 1 != nn {
                                    p += z * a[idx(i, k + 2)];
                                    a[idx(i, k + 2)] -= p * r;
                                }
                                a[idx(i, k + 1)] -= p * q;
                                a[idx(i, k)] -= p;
                            }
                        }
                        k += 1;
                    }
                }
            }
            if l + 1 >= nn {
                break;
            }
        }
    }
    out.extend(wr.into_iter().zip(wi));
    Some(())
}

#[cfg(test)]
mod tests {
    use super::eigenvalues;

    /// A companion matrix has the roots of its polynomial as eigenvalues: `(λ − 2)(λ + 0.5)(λ² − 2λ cos 1 + 1)`
    /// plus a rotation-scaled block; checks real, negative and complex pairs.
    #[test]
    fn eigenvalues_of_known_spectrum() {
        // Build A = S D S⁻¹ with a fixed well-conditioned S (upper unit triangular), D block diagonal.
        let n = 6;
        let mut d = vec![0.0; n * n];
        d[0] = 2.0;
        d[n + 1] = -0.5;
        let (c, s) = (0.9 * 1.0f64.cos(), 0.9 * 1.0f64.sin());
        d[2 * n + 2] = c;
        d[2 * n + 3] = s;
        d[3 * n + 2] = -s;
        d[3 * n + 3] = c;
        d[4 * n + 4] = 1e-3;
        d[5 * n + 5] = -0.999;
        let mut sm = vec![0.0; n * n];
        let mut si = vec![0.0; n * n];
        for i in 0..n {
            sm[i * n + i] = 1.0;
            si[i * n + i] = 1.0;
            if i + 1 < n {
                sm[i * n + i + 1] = 0.7;
            }
        }
        // Inverse of I + 0.7 U (U the shift): Σ (−0.7 U)^k.
        for i in 0..n {
            for j in (i + 1)..n {
                si[i * n + j] = (-0.7f64).powi((j - i) as i32);
            }
        }
        let mul = |a: &[f64], b: &[f64]| {
            let mut c = vec![0.0; n * n];
            for i in 0..n {
                for k in 0..n {
                    for j in 0..n {
                        c[i * n + j] += a[i * n + k] * b[k * n + j];
                    }
                }
            }
            c
        };
        let mut a = mul(&mul(&sm, &d), &si);
        let mut ev = Vec::new();
        eigenvalues(&mut a, n, &mut ev).expect("converges");
        let mut got: Vec<(f64, f64)> = ev;
        got.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.total_cmp(&q.1)));
        let want = [(-0.999, 0.0), (-0.5, 0.0), (1e-3, 0.0), (c, -s), (c, s), (2.0, 0.0)];
        for (g, w) in got.iter().zip(want) {
            assert!((g.0 - w.0).abs() < 1e-12 && (g.1 - w.1).abs() < 1e-12, "{g:?} vs {w:?}");
        }
    }
}
