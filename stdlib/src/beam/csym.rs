//! Eigen-decomposition of a complex symmetric matrix, `V = Y diag(ν) Yᵀ` with `YᵀY = I`, by
//! complex-orthogonal Householder tridiagonalisation and the implicit QL algorithm (the
//! complex symmetric forms of EISPACK's `tred2`/`tql2`, as in Cullum and Willoughby's
//! `CMTQL1`). Y is kept factored (the reflectors and the plane rotations), so a row vector
//! times Y costs O(n²) and no n × n eigenvector matrix is formed: a substructure needs its
//! modes' shapes at a few coupling dofs only.
//!
//! Complex orthogonal transformations are not unitary, so their backward stability is not
//! guaranteed; it holds while each has a norm near 1, as for the nearly real matrices of
//! structural damping (`V` real plus an imaginary part of the order of the loss factors). The
//! largest norm met is returned as [`ComplexSymmetricEigen::growth`]; a caller falls back to a
//! unitary (general) eigen-solver above a bound.

use num_complex::Complex64;

/// `|re| + |im|`: a norm within √2 of the modulus and cheaper, for tests and scaling.
fn abs1(z: Complex64) -> f64 {
    z.re.abs() + z.im.abs()
}

/// Principal square root, algebraically (`Complex64::sqrt` goes through polar form, several
/// times slower; the QL sweep takes one per rotation).
fn sqrt(z: Complex64) -> Complex64 {
    let (x, y) = (z.re, z.im);
    let m = x.abs().max(y.abs());
    let modulus = if m > 1e-150 && m < 1e150 { (x * x + y * y).sqrt() } else { x.hypot(y) };
    if modulus == 0.0 {
        return Complex64::new(0.0, 0.0);
    }
    let t = (0.5 * (x.abs() + modulus)).sqrt();
    if x >= 0.0 { Complex64::new(t, 0.5 * y / t) } else { Complex64::new(0.5 * y.abs() / t, t.copysign(y)) }
}

/// [`sqrt`] and its reciprocal together: `|√z|² = |z|`, so `1/√z = conj(√z)/|z|` costs no
/// complex division (the QL sweep needs both per rotation). The reciprocal of 0 is not finite.
fn sqrt_inv(z: Complex64) -> (Complex64, Complex64) {
    let (x, y) = (z.re, z.im);
    let m = x.abs().max(y.abs());
    let modulus = if m > 1e-150 && m < 1e150 { (x * x + y * y).sqrt() } else { x.hypot(y) };
    if modulus == 0.0 {
        return (Complex64::new(0.0, 0.0), Complex64::new(f64::INFINITY, 0.0));
    }
    let t = (0.5 * (x.abs() + modulus)).sqrt();
    let half_y_over_t = 0.5 * y * t.recip();
    let root =
        if x >= 0.0 { Complex64::new(t, half_y_over_t) } else { Complex64::new(half_y_over_t.abs(), t.copysign(y)) };
    let inv_mod = modulus.recip();
    (root, Complex64::new(root.re * inv_mod, -root.im * inv_mod))
}

/// A complex orthogonal reflector `H = I − v vᵀ / h` on the first `len` indices (`vᵀv = 2h`).
#[derive(Debug, Clone, PartialEq)]
struct Reflector {
    offset: usize,
    len: usize,
    inv_h: Complex64,
}

/// A plane rotation of indices `i, i + 1` with `c² + s² = 1`, applied to a row vector as
/// `(x_i, x_{i+1}) ← (c x_i − s x_{i+1}, s x_i + c x_{i+1})`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Rotation {
    i: u32,
    c: Complex64,
    s: Complex64,
}

/// The eigenvalues of a complex symmetric matrix and its complex orthogonal eigenvectors in
/// factored form.
#[derive(Debug, Clone, PartialEq)]
pub struct ComplexSymmetricEigen {
    n: usize,
    /// Eigenvalues, in descending order of real part.
    pub values: Vec<Complex64>,
    /// The largest norm of a transformation used (`‖v‖²/|vᵀv|` of a reflector,
    /// `|c|² + |s|²` of a rotation; both 1 for real data).
    pub growth: f64,
    reflectors: Vec<Reflector>,
    vectors: Vec<Complex64>,
    rotations: Vec<Rotation>,
    /// Column `k` of the output is internal column `order[k]`.
    order: Vec<usize>,
}

/// Most QL iterations per eigenvalue before giving up.
const MAX_ITERATIONS: usize = 60;

impl ComplexSymmetricEigen {
    /// Decomposes the complex symmetric `v` (row-major n × n; only symmetric matrices give a
    /// meaningful result). `None` when a transformation breaks down (an isotropic vector,
    /// `vᵀv = 0`) or the QL iteration does not converge.
    pub fn new(v: &[Complex64], n: usize) -> Option<ComplexSymmetricEigen> {
        assert_eq!(v.len(), n * n, "matrix size");
        let zero = Complex64::new(0.0, 0.0);
        // Reversed, so the largest entries (V's are at the top left) come last: Householder
        // reduction from the last row and QL both work best on matrices graded that way.
        // Lower triangle only, column-major (column j holds rows j..n at j·n + i), with real
        // and imaginary parts apart so the updates run on contiguous f64 and vectorise.
        let mut lower = Lower { n, re: vec![0.0; n * n], im: vec![0.0; n * n] };
        for j in 0..n {
            for i in j..n {
                let z = v[(n - 1 - i) * n + (n - 1 - j)];
                lower.re[j * n + i] = z.re;
                lower.im[j * n + i] = z.im;
            }
        }
        let mut growth = 1.0f64;
        let mut reflectors = Vec::new();
        let mut vectors = Vec::new();
        let mut d = vec![zero; n];
        let mut e = vec![zero; n];
        let mut work = Work::new(n);
        for i in (1..n).rev() {
            let l = i - 1;
            // Row i left of the diagonal: column j's entry at row i.
            let row: Vec<Complex64> = (0..i).map(|j| lower.at(i, j)).collect();
            let scale: f64 = row.iter().map(|&z| abs1(z)).sum();
            if l == 0 || scale == 0.0 {
                e[i] = row[l];
                continue;
            }
            let offset = vectors.len();
            vectors.extend(row.iter().map(|&z| z / scale));
            let x = &mut vectors[offset..];
            let sigma: Complex64 = x.iter().map(|&z| z * z).sum();
            let mut alpha = sqrt(sigma);
            if (x[l] * alpha.conj()).re > 0.0 {
                alpha = -alpha;
            }
            // H = I − v vᵀ/h, v = x − α e_l, h = vᵀv/2 = σ − α x_l.
            let h = sigma - alpha * x[l];
            x[l] -= alpha;
            let norm2: f64 = x.iter().map(|z| z.norm_sqr()).sum();
            if abs1(h) == 0.0 || !h.is_finite() {
                return None;
            }
            growth = growth.max(norm2 / (2.0 * h.norm()));
            e[i] = alpha * scale;
            let inv_h = 1.0 / h;
            // A ← H A H on the leading m = i block: p = A v / h, q = p − (vᵀp / 2h) v,
            // A ← A − v qᵀ − q vᵀ.
            work.reflect(&mut lower, &vectors[offset..offset + i], inv_h);
            reflectors.push(Reflector { offset, len: i, inv_h });
        }
        for (i, di) in d.iter_mut().enumerate() {
            *di = lower.at(i, i);
        }
        drop(lower);
        // e[i] couples i − 1 and i; QL below wants e[i] coupling i and i + 1.
        for i in 1..n {
            e[i - 1] = e[i];
        }
        if n > 0 {
            e[n - 1] = zero;
        }
        let rotations = ql(&mut d, &mut e, &mut growth)?;
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&i, &j| d[j].re.total_cmp(&d[i].re).then(i.cmp(&j)));
        let values = order.iter().map(|&k| d[k]).collect();
        if !growth.is_finite() {
            return None;
        }
        Some(ComplexSymmetricEigen { n, values, growth, reflectors, vectors, rotations, order })
    }

    /// `x Y` for each row vector `x` (length n) of `rows`: their components along the
    /// eigenvectors, in the order of [`ComplexSymmetricEigen::values`]. Rows go through the
    /// transformations together, so several cost little more than one.
    pub fn project(&self, rows: &[&[Complex64]]) -> Vec<Vec<Complex64>> {
        let n = self.n;
        let k = rows.len();
        // Interleaved: component i of row q at i·k + q.
        let mut r = vec![Complex64::new(0.0, 0.0); n * k];
        for (q, x) in rows.iter().enumerate() {
            assert_eq!(x.len(), n, "row length");
            for (i, &v) in x.iter().rev().enumerate() {
                r[i * k + q] = v;
            }
        }
        let mut t = vec![Complex64::new(0.0, 0.0); k];
        for h in &self.reflectors {
            let v = &self.vectors[h.offset..h.offset + h.len];
            t.fill(Complex64::new(0.0, 0.0));
            for (i, &vi) in v.iter().enumerate() {
                for (tq, &rq) in t.iter_mut().zip(&r[i * k..(i + 1) * k]) {
                    *tq += vi * rq;
                }
            }
            for tq in &mut t {
                *tq *= h.inv_h;
            }
            for (i, &vi) in v.iter().enumerate() {
                for (rq, &tq) in r[i * k..(i + 1) * k].iter_mut().zip(&t) {
                    *rq -= tq * vi;
                }
            }
        }
        for g in &self.rotations {
            let i = g.i as usize;
            let (a, b) = r[i * k..(i + 2) * k].split_at_mut(k);
            for (x, y) in a.iter_mut().zip(b.iter_mut()) {
                let (u, w) = (*x, *y);
                *x = g.c * u - g.s * w;
                *y = g.s * u + g.c * w;
            }
        }
        (0..k).map(|q| self.order.iter().map(|&c| r[c * k + q]).collect()).collect()
    }
}

/// The lower triangle of a complex symmetric matrix, column-major, real and imaginary parts
/// apart.
struct Lower {
    n: usize,
    re: Vec<f64>,
    im: Vec<f64>,
}

impl Lower {
    /// Entry (i, j), i ≥ j.
    fn at(&self, i: usize, j: usize) -> Complex64 {
        Complex64::new(self.re[j * self.n + i], self.im[j * self.n + i])
    }
}

/// Buffers of one Householder step: v and p (then q) split.
struct Work {
    xr: Vec<f64>,
    xi: Vec<f64>,
    pr: Vec<f64>,
    pi: Vec<f64>,
}

impl Work {
    fn new(n: usize) -> Work {
        Work { xr: vec![0.0; n], xi: vec![0.0; n], pr: vec![0.0; n], pi: vec![0.0; n] }
    }

    /// `A ← H A H` on the leading `m = v.len()` block of `a`, `H = I − v vᵀ h⁻¹`.
    fn reflect(&mut self, a: &mut Lower, v: &[Complex64], inv_h: Complex64) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
            #[target_feature(enable = "avx2,fma")]
            fn fast(w: &mut Work, a: &mut Lower, v: &[Complex64], inv_h: Complex64) {
                w.reflect_generic(a, v, inv_h)
            }
            // SAFETY: the CPU supports AVX2 and FMA, checked just above.
            return unsafe { fast(self, a, v, inv_h) };
        }
        self.reflect_generic(a, v, inv_h)
    }

    /// The loops use `mul_add`: one instruction with FMA, a library call on CPUs without it
    /// (older than about 2013), where this path is correct but slow.
    #[inline(always)]
    fn reflect_generic(&mut self, a: &mut Lower, v: &[Complex64], inv_h: Complex64) {
        let (n, m) = (a.n, v.len());
        let (xr, xi) = (&mut self.xr[..m], &mut self.xi[..m]);
        for (k, z) in v.iter().enumerate() {
            xr[k] = z.re;
            xi[k] = z.im;
        }
        let (pr, pi) = (&mut self.pr[..m], &mut self.pi[..m]);
        pr.fill(0.0);
        pi.fill(0.0);
        // p = A x from the lower triangle: column j adds x_j · A[j+1.., j] below the diagonal
        // and A[j+1.., j] · x[j+1..] at row j.
        for j in 0..m {
            let col = j * n;
            let (cr, ci) = (&a.re[col + j + 1..col + m], &a.im[col + j + 1..col + m]);
            let (sr, si) = (xr[j], xi[j]);
            let (ur, ui) = (&xr[j + 1..], &xi[j + 1..]);
            let (tr, ti) = (&mut pr[j + 1..], &mut pi[j + 1..]);
            for (((t_r, t_i), &are), &aim) in tr.iter_mut().zip(ti.iter_mut()).zip(cr).zip(ci) {
                *t_r = are.mul_add(sr, (-aim).mul_add(si, *t_r));
                *t_i = are.mul_add(si, aim.mul_add(sr, *t_i));
            }
            // The dot product in four partial sums, so it vectorises.
            let mut acc = [[0.0f64; 4]; 2];
            let (c4r, c4i, u4r, u4i) = (cr.chunks_exact(4), ci.chunks_exact(4), ur.chunks_exact(4), ui.chunks_exact(4));
            let whole = cr.len() - c4r.remainder().len();
            for (((a4r, a4i), x4r), x4i) in c4r.zip(c4i).zip(u4r).zip(u4i) {
                for u in 0..4 {
                    acc[0][u] = a4r[u].mul_add(x4r[u], (-a4i[u]).mul_add(x4i[u], acc[0][u]));
                    acc[1][u] = a4r[u].mul_add(x4i[u], a4i[u].mul_add(x4r[u], acc[1][u]));
                }
            }
            let mut dr = (acc[0][0] + acc[0][1]) + (acc[0][2] + acc[0][3]);
            let mut di = (acc[1][0] + acc[1][1]) + (acc[1][2] + acc[1][3]);
            for t in whole..cr.len() {
                dr += cr[t] * ur[t] - ci[t] * ui[t];
                di += cr[t] * ui[t] + ci[t] * ur[t];
            }
            let (djr, dji) = (a.re[col + j], a.im[col + j]);
            pr[j] += djr * sr - dji * si + dr;
            pi[j] += djr * si + dji * sr + di;
        }
        // p ← p / h, then q = p − (xᵀp / 2h) x.
        let mut dot = Complex64::new(0.0, 0.0);
        for k in 0..m {
            let p = Complex64::new(pr[k], pi[k]) * inv_h;
            pr[k] = p.re;
            pi[k] = p.im;
            dot += Complex64::new(xr[k], xi[k]) * p;
        }
        let kk = dot * (0.5 * inv_h);
        for k in 0..m {
            let q = Complex64::new(pr[k], pi[k]) - kk * Complex64::new(xr[k], xi[k]);
            pr[k] = q.re;
            pi[k] = q.im;
        }
        // A ← A − x qᵀ − q xᵀ on the lower triangle.
        for j in 0..m {
            let col = j * n;
            let (qjr, qji, xjr, xji) = (pr[j], pi[j], xr[j], xi[j]);
            let (cr, ci) = (&mut a.re[col + j..col + m], &mut a.im[col + j..col + m]);
            let (ur, ui, wr, wi) = (&xr[j..], &xi[j..], &pr[j..], &pi[j..]);
            for t in 0..cr.len() {
                cr[t] = (-ur[t]).mul_add(qjr, ui[t].mul_add(qji, (-wr[t]).mul_add(xjr, wi[t].mul_add(xji, cr[t]))));
                ci[t] =
                    (-ur[t]).mul_add(qji, (-ui[t]).mul_add(qjr, (-wr[t]).mul_add(xji, (-wi[t]).mul_add(xjr, ci[t]))));
            }
        }
    }
}

/// Implicit QL with Wilkinson shifts on the complex symmetric tridiagonal matrix with diagonal
/// `d` and off-diagonal `e` (`e[i]` couples i and i + 1, `e[n − 1] = 0`): on return `d` holds
/// the eigenvalues; the rotations, in the order applied, map the identity to the eigenvectors.
fn ql(d: &mut [Complex64], e: &mut [Complex64], growth: &mut f64) -> Option<Vec<Rotation>> {
    let n = d.len();
    let one = Complex64::new(1.0, 0.0);
    let zero = Complex64::new(0.0, 0.0);
    let mut rotations = Vec::new();
    for l in 0..n {
        let mut iterations = 0;
        loop {
            let mut m = l;
            while m + 1 < n {
                let dd = abs1(d[m]) + abs1(d[m + 1]);
                if abs1(e[m]) <= f64::EPSILON * dd {
                    break;
                }
                m += 1;
            }
            if m == l {
                break;
            }
            iterations += 1;
            if iterations > MAX_ITERATIONS {
                return None;
            }
            let mut g = (d[l + 1] - d[l]) / (2.0 * e[l]);
            let mut r = sqrt(g * g + one);
            if (g * r.conj()).re < 0.0 {
                r = -r;
            }
            g = d[m] - d[l] + e[l] / (g + r);
            let (mut s, mut c, mut p) = (one, one, zero);
            let mut i = m;
            let mut deflated = false;
            while i > l {
                i -= 1;
                let f = s * e[i];
                let b = c * e[i];
                let (root, inv) = sqrt_inv(f * f + g * g);
                r = root;
                e[i + 1] = r;
                if abs1(r) == 0.0 {
                    // Underflow: the matrix splits here.
                    d[i + 1] -= p;
                    e[m] = zero;
                    deflated = true;
                    break;
                }
                s = f * inv;
                c = g * inv;
                *growth = growth.max(s.norm_sqr() + c.norm_sqr());
                g = d[i + 1] - p;
                r = (d[i] - g) * s + 2.0 * c * b;
                p = s * r;
                d[i + 1] = g + p;
                g = c * r - b;
                rotations.push(Rotation { i: i as u32, c, s });
            }
            if deflated {
                continue;
            }
            d[l] -= p;
            e[l] = g;
            e[m] = zero;
            if !(d[l].is_finite() && g.is_finite()) {
                return None;
            }
        }
    }
    Some(rotations)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A graded complex symmetric matrix shaped like a structurally damped beam's
    /// `R⁻ᵀ diag(μ) R⁻¹` (`RᵀR = I + iE`): `V = D½ (I − iE + S) D½` with D graded over
    /// `decades` (largest first), E symmetric of the size of the loss factor `eta` and S a real
    /// symmetric coupling of the modes, so the matrix is full.
    fn damped(n: usize, decades: f64, eta: f64, seed: u64) -> Vec<Complex64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let d: Vec<f64> = (0..n).map(|k| 10f64.powf(-decades * k as f64 / (n.max(2) - 1) as f64)).collect();
        let mut v = vec![Complex64::new(0.0, 0.0); n * n];
        for i in 0..n {
            for j in 0..=i {
                let coupling = if i == j { 1.0 } else { 0.2 * (rng.random::<f64>() - 0.5) };
                let e = eta * (rng.random::<f64>() - 0.5);
                v[i * n + j] = Complex64::new(coupling, -e) * (d[i] * d[j]).sqrt();
                v[j * n + i] = v[i * n + j];
            }
        }
        v
    }

    /// `V y_k = ν_k y_k` and `YᵀY = I`, checked on the explicit Y (rows of the identity
    /// projected), relative to ‖V‖.
    fn check(v: &[Complex64], n: usize, tol: f64) -> ComplexSymmetricEigen {
        let eig = ComplexSymmetricEigen::new(v, n).expect("decomposes");
        let zero = Complex64::new(0.0, 0.0);
        let y: Vec<Vec<Complex64>> = (0..n)
            .map(|i| {
                let mut unit = vec![zero; n];
                unit[i] = Complex64::new(1.0, 0.0);
                eig.project(&[&unit]).swap_remove(0)
            })
            .collect();
        let vnorm = v.iter().map(|z| z.norm()).fold(0.0, f64::max) * n as f64;
        for k in 0..n {
            for i in 0..n {
                let vy: Complex64 = (0..n).map(|j| v[i * n + j] * y[j][k]).sum();
                let err = (vy - eig.values[k] * y[i][k]).norm();
                assert!(err < tol * vnorm, "residual {err} of pair {k} at row {i}");
            }
            for j in 0..n {
                let dot: Complex64 = (0..n).map(|i| y[i][k] * y[i][j]).sum();
                let want = if j == k { 1.0 } else { 0.0 };
                assert!((dot - want).norm() < tol * n as f64, "Y^T Y [{k}][{j}] = {dot}");
            }
        }
        for w in eig.values.windows(2) {
            assert!(w[0].re >= w[1].re, "values are in descending order of real part");
        }
        eig
    }

    #[test]
    fn algebraic_square_root_is_the_principal_one() {
        for (re, im) in [
            (4.0, 0.0),
            (-4.0, 0.0),
            (-4.0, -0.0),
            (0.0, 2.0),
            (3.0, -4.0),
            (-3.0, 4.0),
            (1e-170, 1e-170),
            (1e200, -1e200),
        ] {
            let z = Complex64::new(re, im);
            let (a, b) = (sqrt(z), z.sqrt());
            assert!((a - b).norm() <= 1e-15 * b.norm(), "{z}: {a} vs {b}");
        }
        assert_eq!(sqrt(Complex64::new(0.0, 0.0)), Complex64::new(0.0, 0.0));
        for z in [
            Complex64::new(3.0, -4.0),
            Complex64::new(-2.5, 1e-9),
            Complex64::new(1e-200, 3e-201),
            Complex64::new(-7.0, 0.0),
        ] {
            let (root, inv) = sqrt_inv(z);
            assert!((root - z.sqrt()).norm() <= 1e-15 * root.norm(), "{z}");
            assert!((inv * root - 1.0).norm() <= 1e-15, "{z}");
        }
    }

    #[test]
    fn decomposes_graded_nearly_real_matrices() {
        for (n, decades, eta, seed) in [(1, 0.0, 0.02, 1), (2, 1.0, 0.02, 2), (7, 4.0, 0.025, 3), (40, 10.0, 0.02, 4)] {
            let eig = check(&damped(n, decades, eta, seed), n, 1e-12);
            assert!(eig.growth < 2.0, "n {n}: growth {}", eig.growth);
        }
    }

    /// Real data stay real: the second-difference matrix's eigenvalues, known in closed form,
    /// with rotations and reflectors of norm 1.
    #[test]
    fn eigenvalues_of_a_real_symmetric_matrix_are_real_and_exact() {
        let n = 12;
        // The second-difference matrix: eigenvalues 2 − 2 cos(kπ/(n + 1)).
        let mut v = vec![Complex64::new(0.0, 0.0); n * n];
        for i in 0..n {
            v[i * n + i] = Complex64::new(2.0, 0.0);
            if i + 1 < n {
                v[i * n + i + 1] = Complex64::new(-1.0, 0.0);
                v[(i + 1) * n + i] = Complex64::new(-1.0, 0.0);
            }
        }
        let eig = check(&v, n, 1e-13);
        for (k, nu) in eig.values.iter().enumerate() {
            let exact = 2.0 - 2.0 * ((n - k) as f64 * std::f64::consts::PI / (n + 1) as f64).cos();
            assert!((nu.re - exact).abs() < 1e-13 && nu.im.abs() < 1e-13, "{k}: {nu} vs {exact}");
        }
        assert!((eig.growth - 1.0).abs() < 1e-12);
    }

    /// Far from real, the transformations grow: the growth reports it.
    #[test]
    fn strongly_complex_matrices_report_growth() {
        let n = 20;
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut v = vec![Complex64::new(0.0, 0.0); n * n];
        for i in 0..n {
            for j in 0..=i {
                v[i * n + j] = Complex64::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5);
                v[j * n + i] = v[i * n + j];
            }
        }
        if let Some(eig) = ComplexSymmetricEigen::new(&v, n) {
            assert!(eig.growth > 1.5, "growth {}", eig.growth);
        }
    }
}
