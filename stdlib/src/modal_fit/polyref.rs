//! Poles shared across the FRFs of a measurement set: the multi-FRF (poly-reference) form of
//! the least-squares complex frequency-domain estimator and of the least-squares frequency-domain
//! residues.
//!
//! A modal test gives many FRFs of one structure; they share its poles and differ in their
//! residues. The estimate follows Guillaume, Verboven, Vanlanduit, Van der Auweraer and Peeters,
//! *A poly-reference implementation of the least-squares complex frequency-domain estimator*
//! (IMAC XXI, 2003), and Peeters, Van der Auweraer, Guillaume and Leuridan, *The PolyMAX
//! frequency-domain method: a new standard for modal parameter estimation?* (Shock and Vibration
//! 11, 2004), in the common-denominator form that sdypy-EMA (`EMA.Model(frf=H_all, …)`,
//! `get_poles`) implements and that serves as the peer of the tests:
//!
//! 1. **Common denominator.** Each FRF `o` on the fit band is modelled as `B_o(z)/A(z)` in
//!    `z = e^{iωΔt}` (`Δt = 1/(2 f_max)`, real coefficients): one denominator `A` for all, a
//!    numerator per FRF. The linearised least-squares problem `Σ_o Σ_k |w_ok (B_o − H_ok A)|²`
//!    gives per FRF the Toeplitz blocks `R_o`, `S_o`, `T_o` (Verboven, *Frequency-domain system
//!    identification for modal analysis*, PhD thesis, VUB 2002, Eq. 5.26); the numerators are
//!    eliminated and the reduced normal equations `Σ_o (T_o − S_oᵀ R_o⁻¹ S_o) a = 0` with
//!    `a_n = 1` are stacked over the FRFs. `R_o` is Toeplitz, so one Cholesky factor at the
//!    highest order serves every lower order (its leading block), and the Gram matrices of
//!    `L_o⁻¹ S_o` grow order by order: the whole stabilisation diagram costs about one solve at
//!    the highest order.
//! 2. **Stabilisation diagram.** The poles of each order `n = 2, 4, …, max_order` (`λ = ln z/Δt`,
//!    physical ones: positive frequency inside the band, damping ratio in `(0, 0.3)`) are compared
//!    with the nearest pole of order `n − 2`: stable in frequency within `stable_frequency`
//!    (relative), and in damping too within `stable_damping` (relative).
//! 3. **Pole selection.** Around each peak of the summed `|H|` (or each frequency given), the
//!    poles stable in frequency and damping within the peak's window are searched for the
//!    densest column of the diagram (a physical mode is found again at order after order, within
//!    a line or a tenth of the frequency tolerance, where spurious poles wander); of that column
//!    the pole nearest its median frequency is chosen (ties: the higher order), as sdypy-EMA's
//!    `select_closest_poles` takes the stable pole nearest the mean of its narrowing windows.
//! 4. **Residues (LSFD).** With the poles fixed, each FRF is linear in its residues and in
//!    complex lower and upper residual terms,
//!    `H_o(ω) = (iω)^k [Σ_r A_or/(iω − λ_r) + Ā_or/(iω − λ̄_r) − LR_o/ω² + UR_o]`,
//!    `k` the FRF's kind (0 receptance, 1 mobility, 2 accelerance), fitted in the kind measured
//!    as sdypy-EMA's `LSFD(…, frf_form)` does. `A_or` is the receptance residue (modal
//!    constant over `2iω_d`), whose sign says whether response and reference move together.

use super::lsfd::{least_squares, pair_basis, pair_h, residual_measures};
use super::{FitError, MIN_LINES, Weighting, lscf};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Largest damping ratio of a physical pole (as the single-FRF LSCF).
pub const MAX_XI: f64 = 0.3;

/// How the poles to keep are found in the stabilisation diagram.
#[derive(Debug, Clone, PartialEq)]
pub enum Targets {
    /// Near the peaks of the summed `|H|` in the band: the `count` most prominent ones that have
    /// a stable pole, or (`None`) every peak at least `prominence_db` prominent that has one.
    Peaks {
        /// How many modes to keep; `None`: every peak that passes.
        count: Option<usize>,
        /// Least prominence of a peak of the summed `|H|` above the higher of its two flanking
        /// minima, dB.
        prominence_db: f64,
    },
    /// Near these natural frequencies, Hz (each must find a stable pole).
    Frequencies(Vec<f64>),
}

/// Options of [`fit_set`].
#[derive(Debug, Clone, PartialEq)]
pub struct SetOptions {
    /// Lower end of the fit band, Hz.
    pub min_frequency_hz: f64,
    /// Upper end of the fit band, Hz (infinite: the last line).
    pub max_frequency_hz: f64,
    /// Highest model order: the number of poles of the common denominator (conjugates counted),
    /// even; orders 2, 4, … up to it make the stabilisation diagram. sdypy-EMA's
    /// `pol_order_high = p` reaches order `2p`.
    pub max_order: usize,
    /// Line weights of the LSCF and LSFD least squares: none (each FRF scaled to unit RMS on the
    /// band, so the peaks lead, as sdypy-EMA) or `1/|H|` (every line by its relative error).
    pub weighting: Weighting,
    /// The FRFs' kind as a power of `iω`: 0 receptance, 1 mobility, 2 accelerance.
    pub kind_order: i32,
    /// Relative frequency change to the previous order under which a pole is stable in frequency.
    pub stable_frequency: f64,
    /// Relative damping change under which a pole stable in frequency is stable in damping too.
    pub stable_damping: f64,
    /// Where to take poles.
    pub targets: Targets,
}

impl Default for SetOptions {
    fn default() -> Self {
        SetOptions {
            min_frequency_hz: 0.0,
            max_frequency_hz: f64::INFINITY,
            max_order: 120,
            weighting: Weighting::Absolute,
            kind_order: 0,
            stable_frequency: 0.01,
            stable_damping: 0.05,
            targets: Targets::Peaks { count: None, prominence_db: 6.0 },
        }
    }
}

/// A pole's class in the stabilisation diagram.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Stability {
    /// No pole of the previous order within the frequency tolerance.
    New,
    /// Stable in frequency only.
    Frequency,
    /// Stable in frequency and damping.
    Damping,
}

/// One pole of the stabilisation diagram.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiagramPole {
    /// Model order (number of poles of the denominator).
    pub order: usize,
    /// Natural frequency `|λ|/2π`, Hz.
    pub f_hz: f64,
    /// Damping ratio `−Re λ/|λ|`.
    pub xi: f64,
    /// The pole, rad/s.
    pub lambda: Complex64,
    /// Its class against the previous order.
    pub stability: Stability,
}

/// A pole kept for the set: shared by every FRF.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SharedPole {
    /// Natural frequency, Hz.
    pub f_hz: f64,
    /// Damping ratio.
    pub xi: f64,
    /// The pole, rad/s.
    pub lambda: Complex64,
    /// The model order it was taken from.
    pub order: usize,
    /// The peak (or given frequency) it was selected for, Hz.
    pub target_hz: f64,
}

/// Result of [`fit_set`].
#[derive(Debug, Clone, PartialEq)]
pub struct SetFit {
    /// The shared poles, by frequency.
    pub poles: Vec<SharedPole>,
    /// Receptance residues `A_or`, `[frf][mode]`, m/(N·s) for FRFs in newtons.
    pub residues: Vec<Vec<Complex64>>,
    /// Lower residual per FRF (receptance term `−LR/ω²`), complex.
    pub lower: Vec<Complex64>,
    /// Upper residual per FRF (receptance term `UR`), complex.
    pub upper: Vec<Complex64>,
    /// Indices of the lines fitted (inside the band, above 0 Hz).
    pub lines: Vec<usize>,
    /// The model on those lines, `[frf][line]`, in the FRFs' kind.
    pub fitted: Vec<Vec<Complex64>>,
    /// Global relative L2 residual `‖H − H_fit‖/‖H‖` of each FRF on the fitted lines.
    pub relative_residual: Vec<f64>,
    /// `1/|H|`-weighted relative error (RMS of `|H − H_fit|/|H|`) of each FRF.
    pub weighted_residual: Vec<f64>,
    /// The global relative L2 residual over every FRF and line together.
    pub global_relative_residual: f64,
    /// The `1/|H|`-weighted relative error over every FRF and line together.
    pub global_weighted_residual: f64,
    /// Every physical pole of every order, with its class.
    pub diagram: Vec<DiagramPole>,
    /// The orders computed (those whose normal equations were not singular).
    pub orders: Vec<usize>,
    /// The peaks (or given frequencies) poles were looked for at, Hz.
    pub targets_hz: Vec<f64>,
    /// Targets that found no pole stable in frequency and damping, Hz.
    pub unmatched_hz: Vec<f64>,
    /// The summed `|H|` of the FRFs on the fitted lines (what the peaks were picked on).
    pub summed: Vec<f64>,
}

fn bad(name: &'static str, value: f64, requirement: &'static str) -> FitError {
    FitError::InvalidOption { name, value, requirement }
}

fn check(freqs_hz: &[f64], frfs: &[&[Complex64]], o: &SetOptions) -> Result<(), FitError> {
    if frfs.is_empty() {
        return Err(FitError::TooFewLines { lines: 0, min: MIN_LINES, place: "in the set (it holds no FRF)" });
    }
    for h in frfs {
        super::check_grid(freqs_hz, h)?;
    }
    if !(o.min_frequency_hz.is_finite() && o.min_frequency_hz >= 0.0) {
        return Err(bad("min_frequency", o.min_frequency_hz, "must be finite and ≥ 0"));
    }
    if o.max_frequency_hz.is_nan() || o.max_frequency_hz <= o.min_frequency_hz {
        return Err(bad("max_frequency", o.max_frequency_hz, "must be above min_frequency"));
    }
    if !(4..=300).contains(&o.max_order) || !o.max_order.is_multiple_of(2) {
        return Err(bad("max_order", o.max_order as f64, "must be even and between 4 and 300"));
    }
    if !(o.stable_frequency > 0.0 && o.stable_frequency < 1.0) {
        return Err(bad("stable_frequency", o.stable_frequency, "must be in (0, 1)"));
    }
    if !(o.stable_damping > 0.0 && o.stable_damping.is_finite()) {
        return Err(bad("stable_damping", o.stable_damping, "must be positive"));
    }
    match &o.targets {
        Targets::Peaks { count, prominence_db } => {
            if count == &Some(0) {
                return Err(bad("modes", 0.0, "must be at least 1"));
            }
            if !(prominence_db.is_finite() && *prominence_db >= 0.0) {
                return Err(bad("prominence", *prominence_db, "must be finite and ≥ 0 dB"));
            }
        }
        Targets::Frequencies(f) => {
            if f.is_empty() {
                return Err(bad("frequencies", 0.0, "must list at least one frequency"));
            }
            if let Some(v) = f.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
                return Err(bad("frequencies", *v, "must be finite and positive"));
            }
        }
    }
    Ok(())
}

/// Identifies the poles shared by the FRFs `frfs` (each on `freqs_hz`, all of one kind) and the
/// residues of each FRF (see the module documentation).
pub fn fit_set(freqs_hz: &[f64], frfs: &[&[Complex64]], opts: &SetOptions) -> Result<SetFit, FitError> {
    check(freqs_hz, frfs, opts)?;
    let lines: Vec<usize> = (0..freqs_hz.len())
        .filter(|&k| freqs_hz[k] > 0.0 && freqs_hz[k] >= opts.min_frequency_hz && freqs_hz[k] <= opts.max_frequency_hz)
        .collect();
    if lines.len() < MIN_LINES {
        return Err(FitError::TooFewLines { lines: lines.len(), min: MIN_LINES, place: "in the fit band" });
    }
    let f: Vec<f64> = lines.iter().map(|&k| freqs_hz[k]).collect();
    let h: Vec<Vec<Complex64>> = frfs.iter().map(|v| lines.iter().map(|&k| v[k]).collect()).collect();
    let (lo, hi) = (f[0], f[f.len() - 1]);
    let dt = 1.0 / (2.0 * hi);
    let (diagram, orders) = stabilisation(&f, &h, dt, opts)?;
    let summed: Vec<f64> = (0..f.len()).map(|k| h.iter().map(|v| v[k].norm()).sum()).collect();
    let df = (hi - lo) / (f.len() - 1) as f64;
    let (poles, targets_hz, unmatched_hz) = select(&f, &summed, &diagram, df, &opts.targets, opts.stable_frequency);
    if poles.is_empty() {
        return Err(FitError::NothingLeft {
            method: "poly-reference LSCF",
            why: match (&opts.targets, targets_hz.is_empty()) {
                (Targets::Peaks { .. }, true) => "the summed |H| has no peak prominent enough in the band".into(),
                _ => format!(
                    "no pole stable in frequency and damping near {} Hz up to order {}",
                    listed(&targets_hz),
                    opts.max_order
                ),
            },
        });
    }
    let lambdas: Vec<Complex64> = poles.iter().map(|p| p.lambda).collect();
    let mut residues = Vec::with_capacity(h.len());
    let (mut lower, mut upper, mut fitted) = (Vec::new(), Vec::new(), Vec::new());
    let (mut relative_residual, mut weighted_residual) = (Vec::new(), Vec::new());
    for ho in &h {
        let r = lsfd_kind(&f, ho, &lambdas, opts.kind_order, opts.weighting)?;
        let (g, w) = residual_measures(ho, &r.fitted);
        relative_residual.push(g);
        weighted_residual.push(w);
        residues.push(r.residues);
        lower.push(r.lower);
        upper.push(r.upper);
        fitted.push(r.fitted);
    }
    let all_h: Vec<Complex64> = h.iter().flatten().copied().collect();
    let all_fit: Vec<Complex64> = fitted.iter().flatten().copied().collect();
    let (global_relative_residual, global_weighted_residual) = residual_measures(&all_h, &all_fit);
    Ok(SetFit {
        poles,
        residues,
        lower,
        upper,
        lines,
        fitted,
        relative_residual,
        weighted_residual,
        global_relative_residual,
        global_weighted_residual,
        diagram,
        orders,
        targets_hz,
        unmatched_hz,
        summed,
    })
}

fn listed(f: &[f64]) -> String {
    f.iter().map(|v| format!("{v:.1}")).collect::<Vec<_>>().join(", ")
}

/// The stabilisation diagram: every physical pole of the orders 2, 4, …, `max_order`, classed
/// against the previous order; and the orders computed.
fn stabilisation(
    f: &[f64],
    h: &[Vec<Complex64>],
    dt: f64,
    opts: &SetOptions,
) -> Result<(Vec<DiagramPole>, Vec<usize>), FitError> {
    let nmax = opts.max_order;
    let m = nmax + 1;
    let (lo, hi) = (f[0], f[f.len() - 1]);
    let orders_wanted: Vec<usize> = (2..=nmax).step_by(2).collect();
    let weights: Vec<Option<Vec<f64>>> = h.iter().map(|ho| line_weights(ho, opts.weighting)).collect();
    let seqs = toeplitz_sequences(f, h, &weights, dt, m);
    if seqs.is_empty() {
        return Err(FitError::NothingLeft {
            method: "poly-reference LSCF",
            why: "every FRF is zero in the band".into(),
        });
    }
    let normal = ReducedNormal::new(&seqs, m, &orders_wanted);
    drop(seqs);
    let mut diagram: Vec<DiagramPole> = Vec::new();
    let mut orders = Vec::new();
    let mut previous: Vec<DiagramPole> = Vec::new();
    for (&n, block) in orders_wanted.iter().zip(&normal.blocks) {
        if n + 1 > normal.usable {
            break;
        }
        let Some(denominator) = normal.denominator(n, block) else {
            previous.clear();
            continue;
        };
        orders.push(n);
        let mut here: Vec<DiagramPole> = lscf::roots(&denominator)
            .into_iter()
            .filter_map(|zr| {
                let lambda = zr.ln() / dt;
                let wn = lambda.norm();
                let f_hz = wn / TAU;
                let xi = -lambda.re / wn;
                (lambda.im > 0.0 && xi > 0.0 && xi < MAX_XI && f_hz >= lo && f_hz <= hi).then_some(DiagramPole {
                    order: n,
                    f_hz,
                    xi,
                    lambda,
                    stability: Stability::New,
                })
            })
            .collect();
        here.sort_by(|p, q| p.f_hz.total_cmp(&q.f_hz));
        classify(&mut here, &previous, opts);
        diagram.extend_from_slice(&here);
        previous = here;
    }
    if orders.is_empty() {
        return Err(FitError::Singular { what: "poly-reference denominator at every order" });
    }
    Ok((diagram, orders))
}

/// Each line's weight in the least squares of one FRF: `1/rms²` (absolute) or `1/|H|²`
/// (relative); `None` for an FRF that is zero or not finite in the band.
fn line_weights(ho: &[Complex64], weighting: Weighting) -> Option<Vec<f64>> {
    let rms = (ho.iter().map(|v| v.norm_sqr()).sum::<f64>() / ho.len() as f64).sqrt();
    (rms > 0.0 && rms.is_finite()).then(|| {
        ho.iter()
            .map(|v| match weighting {
                Weighting::Absolute => 1.0 / (rms * rms),
                Weighting::Relative if v.norm_sqr() > 0.0 => 1.0 / v.norm_sqr(),
                Weighting::Relative => 0.0,
            })
            .collect()
    })
}

/// One FRF's Toeplitz sequences of R, T and S up to the highest order:
/// `r_q = Σ w² cos qθ`, `t_q = Σ w²|H|² cos qθ`, `s±_q = −Σ w² H e^{±iqθ}`.
struct Sequences {
    r: Vec<f64>,
    t: Vec<f64>,
    sp: Vec<Complex64>,
    sm: Vec<Complex64>,
}

/// The sequences of every weighted FRF (of length `m`), in one pass over the lines.
fn toeplitz_sequences(
    f: &[f64],
    h: &[Vec<Complex64>],
    weights: &[Option<Vec<f64>>],
    dt: f64,
    m: usize,
) -> Vec<Sequences> {
    let zero = Complex64::from(0.0);
    let mut seqs: Vec<Sequences> = weights
        .iter()
        .filter(|w| w.is_some())
        .map(|_| Sequences { r: vec![0.0; m], t: vec![0.0; m], sp: vec![zero; m], sm: vec![zero; m] })
        .collect();
    let mut zq = vec![zero; m];
    for (k, &fk) in f.iter().enumerate() {
        for (q, z) in zq.iter_mut().enumerate() {
            *z = Complex64::from_polar(1.0, q as f64 * TAU * fk * dt);
        }
        let used = h.iter().zip(weights).filter_map(|(ho, w)| w.as_ref().map(|w| (ho[k], w[k])));
        for ((hk, w), s) in used.zip(seqs.iter_mut()) {
            let hw = -w * hk;
            let th = w * hk.norm_sqr();
            for (q, &z) in zq.iter().enumerate() {
                s.r[q] += w * z.re;
                s.t[q] += th * z.re;
                s.sp[q] += hw * z;
                s.sm[q] += hw * z.conj();
            }
        }
    }
    seqs
}

/// The reduced normal matrix of every order, summed over the FRFs.
///
/// The reduced normal matrix of order n is the leading (n+1)×(n+1) block of
/// Σ_o (T_o − S_oᵀ R_o⁻¹ S_o), and S_oᵀ R_o⁻¹ S_o = Y_oᵀ Y_o with Y_o = L_o⁻¹ S_o (L_o the
/// Cholesky factor of R_o): the leading block of order n takes the first n+1 rows of Y_o only,
/// so one factor at the highest order and a Gram matrix grown row by row give every order.
struct ReducedNormal {
    m: usize,
    /// Σ_o T_o at the highest order, `m × m`.
    t_sum: Vec<f64>,
    /// `blocks[i]` sums the leading blocks of `Y_oᵀ Y_o` over the FRFs for the `i`-th order.
    blocks: Vec<Vec<f64>>,
    /// How many rows every factor reached (R loses rank at high orders on a narrow band).
    usable: usize,
}

impl ReducedNormal {
    fn new(seqs: &[Sequences], m: usize, orders_wanted: &[usize]) -> Self {
        let mut t_sum = vec![0.0; m * m];
        let mut blocks: Vec<Vec<f64>> = orders_wanted.iter().map(|n| vec![0.0; (n + 1) * (n + 1)]).collect();
        let mut usable = m;
        let mut l = vec![0.0; m * m];
        let mut y = vec![0.0; m * m];
        let mut gram = vec![0.0; m * m];
        for s in seqs {
            for i in 0..m {
                for j in 0..m {
                    t_sum[i * m + j] += s.t[i.abs_diff(j)];
                }
            }
            let rows = toeplitz_cholesky(&s.r, &mut l, m);
            usable = usable.min(rows);
            let s_at = |i: usize, j: usize| if j >= i { s.sp[j - i].re } else { s.sm[i - j].re };
            gram.iter_mut().for_each(|v| *v = 0.0);
            let mut next = 0;
            for i in 0..rows {
                for j in 0..m {
                    let mut v = s_at(i, j);
                    for k in 0..i {
                        v -= l[i * m + k] * y[k * m + j];
                    }
                    y[i * m + j] = v / l[i * m + i];
                }
                let row = &y[i * m..i * m + m];
                for a in 0..m {
                    let ya = row[a];
                    if ya != 0.0 {
                        for b in 0..m {
                            gram[a * m + b] += ya * row[b];
                        }
                    }
                }
                // Rows 0..=n are in: the block of order n is complete.
                while next < orders_wanted.len() && orders_wanted[next] == i {
                    let size = i + 1;
                    let block = &mut blocks[next];
                    for a in 0..size {
                        for b in 0..size {
                            block[a * size + b] += gram[a * m + b];
                        }
                    }
                    next += 1;
                }
            }
        }
        ReducedNormal { m, t_sum, blocks, usable }
    }

    /// The monic denominator of order `n` (coefficients from the constant up, the last 1) from
    /// its block; `None` where the normal equations are singular.
    fn denominator(&self, n: usize, block: &[f64]) -> Option<Vec<f64>> {
        let (m, size) = (self.m, n + 1);
        let mut a = vec![0.0; n * n];
        let mut rhs = vec![0.0; n];
        for i in 0..n {
            for j in 0..n {
                a[i * n + j] = self.t_sum[i * m + j] - block[i * size + j];
            }
            rhs[i] = -(self.t_sum[i * m + n] - block[i * size + n]);
        }
        lscf::solve(&mut a, &mut rhs, n, 1)?;
        rhs.push(1.0);
        Some(rhs)
    }
}

/// The Cholesky factor `l` (`m × m`, row-major, lower) of the symmetric Toeplitz matrix of `r`,
/// as far as it stays positive definite; returns the number of rows factored.
fn toeplitz_cholesky(r: &[f64], l: &mut [f64], m: usize) -> usize {
    l.iter_mut().for_each(|v| *v = 0.0);
    for i in 0..m {
        for j in 0..=i {
            let mut v = r[i.abs_diff(j)];
            for k in 0..j {
                v -= l[i * m + k] * l[j * m + k];
            }
            if i == j {
                if v <= 1e-13 * r[0] {
                    return i;
                }
                l[i * m + i] = v.sqrt();
            } else {
                l[i * m + j] = v / l[j * m + j];
            }
        }
    }
    m
}

/// Classes each pole of one order against the nearest pole of the previous order: stable in
/// frequency, and also in damping, within the options' tolerances.
fn classify(here: &mut [DiagramPole], previous: &[DiagramPole], opts: &SetOptions) {
    for p in here {
        let nearest = previous.iter().min_by(|a, b| (a.f_hz - p.f_hz).abs().total_cmp(&(b.f_hz - p.f_hz).abs()));
        if let Some(q) = nearest
            && (q.f_hz - p.f_hz).abs() <= opts.stable_frequency * p.f_hz
        {
            p.stability = if (q.xi - p.xi).abs() <= opts.stable_damping * p.xi {
                Stability::Damping
            } else {
                Stability::Frequency
            };
        }
    }
}

/// Peaks of `y` (local maxima over lines `f`) with their prominence: the ratio of the peak to the
/// higher of the lowest points between it and the nearest higher line on either side (or the
/// band's end), in dB. By frequency.
pub fn peaks(f: &[f64], y: &[f64]) -> Vec<(f64, f64)> {
    let n = y.len();
    let mut out = Vec::new();
    for k in 1..n.saturating_sub(1) {
        if !(y[k] > y[k - 1] && y[k] >= y[k + 1]) || y[k] <= 0.0 {
            continue;
        }
        let mut left = y[k];
        let mut i = k;
        while i > 0 && y[i - 1] <= y[k] {
            i -= 1;
            left = left.min(y[i]);
        }
        let mut right = y[k];
        let mut j = k;
        while j + 1 < n && y[j + 1] <= y[k] {
            j += 1;
            right = right.min(y[j]);
        }
        let col = left.max(right);
        let prominence = if col > 0.0 { 20.0 * (y[k] / col).log10() } else { f64::INFINITY };
        out.push((f[k], prominence));
    }
    out
}

/// The pole of the diagram's column at a target: among the poles stable in frequency and damping
/// within `[lo, hi]`, the densest cluster (the most poles within `radius` Hz of one, ties: the one
/// nearer `target`), a physical mode being found again at order after order where spurious poles
/// wander; of that cluster, the pole nearest its median frequency (ties: the higher order).
fn pick_in(diagram: &[DiagramPole], lo: f64, hi: f64, target: f64, radius: f64) -> Option<DiagramPole> {
    let mut column: Vec<&DiagramPole> =
        diagram.iter().filter(|p| p.stability == Stability::Damping && p.f_hz >= lo && p.f_hz <= hi).collect();
    column.sort_by(|a, b| a.f_hz.total_cmp(&b.f_hz).then(a.order.cmp(&b.order)));
    // Poles within `radius` of each, by a window sliding over the sorted frequencies.
    let (mut first, mut last) = (0, 0);
    let mut best: Option<(usize, usize, usize)> = None;
    for (i, p) in column.iter().enumerate() {
        while column[first].f_hz < p.f_hz - radius {
            first += 1;
        }
        last = last.max(i);
        while last + 1 < column.len() && column[last + 1].f_hz <= p.f_hz + radius {
            last += 1;
        }
        let count = last + 1 - first;
        let better = match best {
            None => true,
            Some((b, bf, bl)) => {
                let held = bl + 1 - bf;
                count > held || (count == held && (p.f_hz - target).abs() < (column[b].f_hz - target).abs())
            }
        };
        if better {
            best = Some((i, first, last));
        }
    }
    let (_, first, last) = best?;
    let cluster = &column[first..=last];
    let c = cluster.len();
    let median = if c % 2 == 1 { cluster[c / 2].f_hz } else { 0.5 * (cluster[c / 2 - 1].f_hz + cluster[c / 2].f_hz) };
    cluster
        .iter()
        .min_by(|a, b| (a.f_hz - median).abs().total_cmp(&(b.f_hz - median).abs()).then(b.order.cmp(&a.order)))
        .map(|p| **p)
}

/// The window of target `j` among the sorted `targets`: half-way to each neighbour, at most 10 %
/// of its frequency and at least two lines each side.
fn window(targets: &[f64], j: usize, df: f64) -> (f64, f64) {
    let t = targets[j];
    let reach = 0.1 * t;
    let below = if j > 0 { (0.5 * (t - targets[j - 1])).min(reach) } else { reach };
    let above = if j + 1 < targets.len() { (0.5 * (targets[j + 1] - t)).min(reach) } else { reach };
    (t - below.max(2.0 * df), t + above.max(2.0 * df))
}

/// The shared poles for the targets, the targets looked at and those left without a pole.
fn select(
    f: &[f64],
    summed: &[f64],
    diagram: &[DiagramPole],
    df: f64,
    targets: &Targets,
    stable_frequency: f64,
) -> (Vec<SharedPole>, Vec<f64>, Vec<f64>) {
    // A mode's poles over the orders cluster within a line, or a tenth of the stability tolerance.
    let radius = |f: f64| df.max(0.1 * stable_frequency * f);
    let (mut chosen, mut looked, mut unmatched) = (Vec::new(), Vec::new(), Vec::new());
    match targets {
        Targets::Frequencies(given) => {
            let mut t = given.clone();
            t.sort_by(f64::total_cmp);
            for j in 0..t.len() {
                let (a, b) = window(&t, j, df);
                match pick_in(diagram, a, b, t[j], radius(t[j])) {
                    Some(p) => chosen.push(shared(p, t[j])),
                    None => unmatched.push(t[j]),
                }
            }
            dedup(&mut chosen);
            (chosen, t, unmatched)
        }
        Targets::Peaks { count, prominence_db } => {
            let mut candidates: Vec<(f64, f64)> =
                peaks(f, summed).into_iter().filter(|(_, p)| *p >= *prominence_db).collect();
            let all: Vec<f64> = candidates.iter().map(|c| c.0).collect();
            // Most prominent first; windows from every candidate so that neighbours split the axis.
            candidates.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.total_cmp(&b.0)));
            for (fp, _) in candidates {
                if count.is_some_and(|c| chosen.len() >= c) {
                    break;
                }
                let j = all.iter().position(|v| *v == fp).unwrap_or(0);
                let (a, b) = window(&all, j, df);
                looked.push(fp);
                match pick_in(diagram, a, b, fp, radius(fp)) {
                    Some(p) if !chosen.iter().any(|c: &SharedPole| c.lambda == p.lambda) => chosen.push(shared(p, fp)),
                    _ => unmatched.push(fp),
                }
            }
            chosen.sort_by(|a, b| a.f_hz.total_cmp(&b.f_hz));
            looked.sort_by(f64::total_cmp);
            unmatched.sort_by(f64::total_cmp);
            (chosen, looked, unmatched)
        }
    }
}

fn shared(p: DiagramPole, target_hz: f64) -> SharedPole {
    SharedPole { f_hz: p.f_hz, xi: p.xi, lambda: p.lambda, order: p.order, target_hz }
}

/// Drops a pole chosen twice (two given frequencies within one window).
fn dedup(chosen: &mut Vec<SharedPole>) {
    chosen.sort_by(|a, b| a.f_hz.total_cmp(&b.f_hz));
    chosen.dedup_by(|a, b| a.lambda == b.lambda);
}

/// LSFD of one FRF in its kind (see the module documentation).
struct KindFit {
    residues: Vec<Complex64>,
    lower: Complex64,
    upper: Complex64,
    fitted: Vec<Complex64>,
}

/// `(iω)^k`.
fn i_omega_pow(w: f64, k: i32) -> Complex64 {
    Complex64::new(0.0, w).powi(k)
}

fn lsfd_kind(
    f: &[f64],
    h: &[Complex64],
    poles: &[Complex64],
    k: i32,
    weighting: Weighting,
) -> Result<KindFit, FitError> {
    let p = poles.len();
    let cols = 2 * p + 4;
    let used: Vec<usize> = (0..f.len()).filter(|&i| h[i].norm() > 0.0 || weighting == Weighting::Absolute).collect();
    let rows = 2 * used.len();
    if rows < 2 * cols {
        return Err(FitError::TooFewLines { lines: used.len(), min: cols, place: "for the residues" });
    }
    let mut a = vec![0.0; rows * cols];
    let mut y = vec![0.0; rows];
    let basis = |w: f64| -> Vec<Complex64> {
        let s = i_omega_pow(w, k);
        let mut b = Vec::with_capacity(cols);
        for &l in poles {
            let (u, v) = pair_basis(l, w);
            b.push(u * s);
            b.push(v * s);
        }
        let low = s * (-1.0 / (w * w));
        b.push(low);
        b.push(low * Complex64::i());
        b.push(s);
        b.push(s * Complex64::i());
        b
    };
    for (r, &i) in used.iter().enumerate() {
        let w = TAU * f[i];
        let wt = match weighting {
            Weighting::Relative => 1.0 / h[i].norm(),
            Weighting::Absolute => 1.0,
        };
        for (c, v) in basis(w).into_iter().enumerate() {
            a[c * rows + 2 * r] = v.re * wt;
            a[c * rows + 2 * r + 1] = v.im * wt;
        }
        y[2 * r] = h[i].re * wt;
        y[2 * r + 1] = h[i].im * wt;
    }
    let x = least_squares(&mut a, &mut y, rows, cols).ok_or(FitError::Singular { what: "LSFD residues of the set" })?;
    let residues: Vec<Complex64> = (0..p).map(|m| Complex64::new(x[2 * m], x[2 * m + 1])).collect();
    let lower = Complex64::new(x[2 * p], x[2 * p + 1]);
    let upper = Complex64::new(x[2 * p + 2], x[2 * p + 3]);
    let fitted = f
        .iter()
        .map(|&fk| {
            let w = TAU * fk;
            let modal: Complex64 = residues.iter().zip(poles).map(|(&a, &l)| pair_h(a, l, w)).sum();
            (modal - lower / (w * w) + upper) * i_omega_pow(w, k)
        })
        .collect();
    Ok(KindFit { residues, lower, upper, fitted })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::modal_fit::lsfd::pole;
    use spindlelab_domain::value::Mode;

    /// Three modes of a structure seen at three points: the residue of mode `r` in FRF `o` is
    /// `φ_o,r φ_1,r/(2iω_d m_r)` (reference at point 1, response at points 1–3), so that the
    /// FRFs share their poles and differ in residues, some negative.
    fn three_point_model() -> (Vec<Mode>, Vec<Vec<Complex64>>) {
        let modes = vec![
            Mode { freq_hz: 180.0, damping_ratio: 0.012, modal_mass: 1.0 },
            Mode { freq_hz: 455.0, damping_ratio: 0.02, modal_mass: 1.0 },
            Mode { freq_hz: 820.0, damping_ratio: 0.015, modal_mass: 1.0 },
        ];
        let shapes = [[1.0, 0.9, 0.6], [0.7, -0.4, -1.1], [0.3, -0.8, 0.9]];
        let masses = [2.0, 1.5, 0.8];
        let residues = (0..3)
            .map(|o| {
                modes
                    .iter()
                    .enumerate()
                    .map(|(r, m)| {
                        let wd = pole(m).im;
                        Complex64::new(0.0, -shapes[o][r] * shapes[0][r] / (2.0 * masses[r] * wd))
                    })
                    .collect()
            })
            .collect();
        (modes, residues)
    }

    fn frfs(freqs: &[f64], modes: &[Mode], residues: &[Vec<Complex64>], k: i32) -> Vec<Vec<Complex64>> {
        residues
            .iter()
            .map(|res| {
                freqs
                    .iter()
                    .map(|&f| {
                        let w = TAU * f;
                        let h: Complex64 = res.iter().zip(modes).map(|(&a, m)| pair_h(a, pole(m), w)).sum();
                        h * i_omega_pow(w, k)
                    })
                    .collect()
            })
            .collect()
    }

    /// Validation on a closed-form model: three accelerance FRFs of a 3-mode structure, fitted
    /// together, give the poles to 1e-6 and every residue to 1e-4 (relative).
    #[test]
    fn shared_poles_and_residues_of_a_closed_form_three_mode_set_are_recovered() {
        let (modes, want) = three_point_model();
        let freqs: Vec<f64> = (0..=2000).map(|k| k as f64 * 0.5).collect();
        for (k, weighting) in [(2, Weighting::Absolute), (0, Weighting::Relative), (1, Weighting::Absolute)] {
            let data = frfs(&freqs, &modes, &want, k);
            let refs: Vec<&[Complex64]> = data.iter().map(Vec::as_slice).collect();
            let opts = SetOptions {
                min_frequency_hz: 20.0,
                max_frequency_hz: 1000.0,
                max_order: 40,
                weighting,
                kind_order: k,
                targets: Targets::Peaks { count: Some(3), prominence_db: 6.0 },
                ..SetOptions::default()
            };
            let fit = fit_set(&freqs, &refs, &opts).unwrap();
            assert_eq!(fit.poles.len(), 3, "kind {k}: {:?}", fit.poles);
            for (p, m) in fit.poles.iter().zip(&modes) {
                let truth = pole(m);
                let e = (p.lambda - truth).norm() / truth.norm();
                assert!(e < 1e-6, "kind {k}: pole {} against {truth}: {e:e}", p.lambda);
            }
            for (o, res) in fit.residues.iter().enumerate() {
                for (r, a) in res.iter().enumerate() {
                    let e = (a - want[o][r]).norm() / want[o][r].norm();
                    assert!(e < 1e-4, "kind {k}: FRF {o}, mode {r}: {a} against {}: {e:e}", want[o][r]);
                }
            }
            assert!(fit.global_relative_residual < 1e-5, "kind {k}: {}", fit.global_relative_residual);
        }
    }
}
