//! Zero-order approximation of milling stability (Altintas & Budak 1995, CIRP Annals 44:357–362; Altintas,
//! *Manufacturing Automation*, 2nd ed., §3.5). With the time-averaged force matrix `H0 = −(N Kt/4π)[α]` the
//! characteristic equation is `det(I + Λ [α][Φ(iω_c)]) = 0`, `Λ = −(N a Kt/4π)(1 − e^{−iω_c τ})`, so
//! `Λ = −1/λ` for each eigenvalue `λ` of `[α][Φ]`. A real depth needs
//! `b_lim = −2π Λ_R (1 + κ²)/(N Kt)`, `κ = Λ_I/Λ_R` (only lines with `Λ_R < 0`), and the phase
//! `ε = π − 2 atan κ` places lobe `k` at `n = 60 f_c / (N (k + ε/2π))` rpm.

use super::{Milling, StabilityError};
use num_complex::Complex64;
use std::f64::consts::{PI, TAU};

/// Tool-point receptances in the feed (`x`) and normal (`y`) directions on one frequency grid, m/N.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolPointFrf {
    /// Frequency lines, Hz, strictly increasing.
    pub freqs_hz: Vec<f64>,
    /// `Φxx`, m/N.
    pub xx: Vec<Complex64>,
    /// `Φyy`, m/N.
    pub yy: Vec<Complex64>,
    /// Optional cross terms `(Φxy, Φyx)`, m/N.
    pub cross: Option<(Vec<Complex64>, Vec<Complex64>)>,
}

impl ToolPointFrf {
    /// Direct receptances on a common grid (no cross terms).
    pub fn new(freqs_hz: Vec<f64>, xx: Vec<Complex64>, yy: Vec<Complex64>) -> Result<Self, StabilityError> {
        let frf = ToolPointFrf { freqs_hz, xx, yy, cross: None };
        frf.validate()?;
        Ok(frf)
    }

    /// Direct receptances measured on two grids, which must be the same (to 1e-9 relative).
    pub fn from_pair(
        freqs_x_hz: &[f64],
        xx: Vec<Complex64>,
        freqs_y_hz: &[f64],
        yy: Vec<Complex64>,
    ) -> Result<Self, StabilityError> {
        if freqs_x_hz.len() != freqs_y_hz.len() {
            return Err(StabilityError::GridMismatch {
                what: "x and y FRF grids",
                detail: format!("{} lines in x, {} in y", freqs_x_hz.len(), freqs_y_hz.len()),
            });
        }
        if let Some(i) =
            freqs_x_hz.iter().zip(freqs_y_hz).position(|(a, b)| (a - b).abs() > 1e-9 * a.abs().max(b.abs()))
        {
            return Err(StabilityError::GridMismatch {
                what: "x and y FRF grids",
                detail: format!("line {i} is {} Hz in x and {} Hz in y", freqs_x_hz[i], freqs_y_hz[i]),
            });
        }
        Self::new(freqs_x_hz.to_vec(), xx, yy)
    }

    /// Adds the cross receptances `Φxy` (x response to a y force) and `Φyx`.
    pub fn with_cross(mut self, xy: Vec<Complex64>, yx: Vec<Complex64>) -> Result<Self, StabilityError> {
        self.cross = Some((xy, yx));
        self.validate()?;
        Ok(self)
    }

    pub(crate) fn validate(&self) -> Result<(), StabilityError> {
        let n = self.freqs_hz.len();
        let mut series: Vec<(&'static str, &[Complex64])> = vec![("Φxx", &self.xx), ("Φyy", &self.yy)];
        if let Some((xy, yx)) = &self.cross {
            series.push(("Φxy", xy));
            series.push(("Φyx", yx));
        }
        for (what, s) in series {
            if s.len() != n {
                return Err(StabilityError::GridMismatch {
                    what,
                    detail: format!("{} values for {n} frequency lines", s.len()),
                });
            }
            if let Some(index) = s.iter().position(|z| !z.is_finite()) {
                return Err(StabilityError::NonFinite { what, index });
            }
        }
        if let Some(index) = self.freqs_hz.iter().position(|f| !f.is_finite() || *f < 0.0) {
            return Err(StabilityError::NonFinite { what: "frequency grid (finite, ≥ 0 Hz)", index });
        }
        if let Some(i) = self.freqs_hz.windows(2).position(|w| w[1] <= w[0]) {
            return Err(StabilityError::GridMismatch {
                what: "frequency grid",
                detail: format!("not strictly increasing at line {}", i + 1),
            });
        }
        Ok(())
    }
}

/// Options of [`zoa_lobes`].
#[derive(Debug, Clone, PartialEq)]
pub struct ZoaOptions {
    /// Number of lobes `k = 0 … lobes − 1`; `None` takes as many as the FRF's band needs down to the lowest
    /// speed ([`lobes_needed`]).
    pub lobes: Option<usize>,
    /// Speeds (rpm, increasing, > 0) at which the envelope is evaluated.
    pub speeds_rpm: Vec<f64>,
    /// Keep the per-lobe curves (set false when only the envelope is wanted).
    pub keep_lobes: bool,
    /// The coarsest line spacing the lobes are resolved at, Hz: an FRF on a coarser grid is interpolated
    /// ([`refine`]) first; `None` takes the grid as it is.
    pub resolution_hz: Option<f64>,
}

impl Default for ZoaOptions {
    fn default() -> Self {
        ZoaOptions {
            lobes: None,
            speeds_rpm: (1..=2000).map(|i| 10.0 * i as f64).collect(),
            keep_lobes: true,
            resolution_hz: Some(DEFAULT_RESOLUTION_HZ),
        }
    }
}

/// The line spacing lobes are resolved at by default, Hz. Depths between two lines are interpolated
/// linearly, which overestimates a lobe's minimum: on a 2.5 Hz grid by 0.5–1.5 % for the lightly damped modes
/// of tools; at 1 Hz by less than 0.2 %.
pub const DEFAULT_RESOLUTION_HZ: f64 = 1.0;

/// The FRF on a grid no coarser than `resolution_hz`: each interval wider than it is split evenly, and the
/// receptances at the new lines are cubic Hermite interpolants of the complex values with slopes from the
/// neighbouring lines (Catmull–Rom on a non-uniform grid), which follow a resonance spanning a few lines far
/// better than a straight line. The original lines are kept exactly. Grids of one FRF split alike, so FRFs that
/// share a grid still share it after.
pub fn refine(frf: &ToolPointFrf, resolution_hz: Option<f64>) -> std::borrow::Cow<'_, ToolPointFrf> {
    use std::borrow::Cow;
    let Some(res) = resolution_hz.filter(|r| r.is_finite() && *r > 0.0) else { return Cow::Borrowed(frf) };
    let f = &frf.freqs_hz;
    let n = f.len();
    if n < 2 || f.windows(2).all(|w| w[1] - w[0] <= res * (1.0 + 1e-9)) {
        return Cow::Borrowed(frf);
    }
    // The number of pieces per interval, capped so a sparse grid cannot ask for an absurd count.
    let pieces: Vec<usize> =
        f.windows(2).map(|w| (((w[1] - w[0]) / res) * (1.0 - 1e-9)).ceil().clamp(1.0, 1000.0) as usize).collect();
    let total = 1 + pieces.iter().sum::<usize>();
    let slope = |y: &[Complex64], j: usize| -> Complex64 {
        let (a, b) = (j.saturating_sub(1), (j + 1).min(n - 1));
        (y[b] - y[a]) / (f[b] - f[a])
    };
    let interpolate = |y: &[Complex64]| -> Vec<Complex64> {
        let mut out = Vec::with_capacity(total);
        for j in 0..n - 1 {
            let h = f[j + 1] - f[j];
            let (y0, y1, m0, m1) = (y[j], y[j + 1], slope(y, j) * h, slope(y, j + 1) * h);
            out.push(y0);
            for p in 1..pieces[j] {
                let t = p as f64 / pieces[j] as f64;
                let (t2, t3) = (t * t, t * t * t);
                out.push(
                    y0 * (2.0 * t3 - 3.0 * t2 + 1.0)
                        + m0 * (t3 - 2.0 * t2 + t)
                        + y1 * (-2.0 * t3 + 3.0 * t2)
                        + m1 * (t3 - t2),
                );
            }
        }
        out.push(y[n - 1]);
        out
    };
    let mut freqs = Vec::with_capacity(total);
    for j in 0..n - 1 {
        for p in 0..pieces[j] {
            freqs.push(if p == 0 { f[j] } else { f[j] + (f[j + 1] - f[j]) * p as f64 / pieces[j] as f64 });
        }
    }
    freqs.push(f[n - 1]);
    Cow::Owned(ToolPointFrf {
        freqs_hz: freqs,
        xx: interpolate(&frf.xx),
        yy: interpolate(&frf.yy),
        cross: frf.cross.as_ref().map(|(xy, yx)| (interpolate(xy), interpolate(yx))),
    })
}

/// A receptance line is significant for the lobe count when its magnitude is within this fraction of the
/// band's peak (−40 dB): the ZOA depth at a line is `2π/(N Kt Re λ)` with `Re λ ≤ ‖[α]‖·|Φ|`, so a line 40 dB
/// down limits the cut only at a hundred times the deepest limit.
pub const SIGNIFICANT_RESPONSE: f64 = 1e-2;

/// The most lobes a diagram may take (explicit or automatic): beyond it the speed range reaches so far below
/// the band's modes that the diagram is a dense band at the minimum depth.
pub const MAX_LOBES: usize = 50_000;

/// The highest frequency (Hz) of significant response of `frf`: the last line where the largest of `|Φxx|`,
/// `|Φyy|` (and the cross terms) is within [`SIGNIFICANT_RESPONSE`] of that largest magnitude's peak.
pub fn band_top_hz(frf: &ToolPointFrf) -> f64 {
    let n = frf.freqs_hz.len();
    // Squared magnitudes: the same order without a square root per line.
    let mag2 = |j: usize| {
        let mut m = frf.xx[j].norm_sqr().max(frf.yy[j].norm_sqr());
        if let Some((xy, yx)) = &frf.cross {
            m = m.max(xy[j].norm_sqr()).max(yx[j].norm_sqr());
        }
        m
    };
    let peak2 = (0..n).map(mag2).fold(0.0, f64::max);
    let floor2 = SIGNIFICANT_RESPONSE * SIGNIFICANT_RESPONSE * peak2;
    (0..n).rev().find(|&j| mag2(j) >= floor2).map_or(0.0, |j| frf.freqs_hz[j])
}

/// Lobes needed for every line up to `f_max_hz` to reach the slowest speed `n_min_rpm` with `teeth` teeth:
/// lobe `k` at chatter frequency `f` lies at `n = 60 f/(N (k + e))` with `0 ≤ e < 1`, so
/// `k_max = ⌈60 f_max/(N n_min)⌉ + 1`.
pub fn lobes_needed(f_max_hz: f64, teeth: usize, n_min_rpm: f64) -> usize {
    if !(f_max_hz > 0.0 && n_min_rpm > 0.0) || teeth == 0 {
        return 1;
    }
    let k = (60.0 * f_max_hz / (teeth as f64 * n_min_rpm)).ceil();
    if k >= MAX_LOBES as f64 { MAX_LOBES + 1 } else { k as usize + 1 }
}

/// The lobe count a diagram uses: the explicit one, or [`lobes_needed`] for the band of significant response;
/// refuses more than [`MAX_LOBES`].
pub(crate) fn lobe_count(
    explicit: Option<usize>,
    f_max_hz: f64,
    teeth: usize,
    n_min_rpm: f64,
) -> Result<usize, StabilityError> {
    let needed = lobes_needed(f_max_hz, teeth, n_min_rpm);
    let count = explicit.unwrap_or(needed);
    if count > MAX_LOBES {
        return Err(StabilityError::TooManyLobes { lobes: count, f_max_hz, n_min_rpm, teeth });
    }
    Ok(count)
}

/// One point of a lobe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LobePoint {
    /// Spindle speed, rpm.
    pub speed_rpm: f64,
    /// Limiting axial depth, m.
    pub depth_m: f64,
    /// Chatter frequency, Hz.
    pub chatter_hz: f64,
}

/// Every lobe curve of [`zoa_lobes`], stored compactly: the chatter frequency and depth of each point of a run of
/// contiguous lines with a root (one eigenvalue branch) once, shared by all lobes, and per lobe only the speeds.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LobeSet {
    /// Number of lobes `k = 0 … lobes − 1`.
    lobes: usize,
    /// Runs as (branch, first point, number of points), in order of branch and frequency.
    runs: Vec<(usize, usize, usize)>,
    /// Chatter frequency of each run point, Hz.
    chatter_hz: Vec<f64>,
    /// Limiting depth of each run point, m.
    depth_m: Vec<f64>,
    /// Speed of each run point on each lobe, rpm: run `(_, start, len)`, lobe `k`, point `i` at
    /// `lobes · start + k · len + i`.
    speed_rpm: Vec<f64>,
}

/// One lobe curve of a [`LobeSet`]: lobe `index` over contiguous frequency lines of one eigenvalue branch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lobe<'a> {
    /// Lobe number `k` (number of whole waves between teeth).
    pub index: usize,
    /// Eigenvalue branch, 0 or 1.
    pub branch: usize,
    /// Chatter frequencies, Hz, increasing.
    pub chatter_hz: &'a [f64],
    /// Limiting depths, m.
    pub depth_m: &'a [f64],
    /// Speeds, rpm.
    pub speed_rpm: &'a [f64],
}

impl<'a> Lobe<'a> {
    /// The points in order of chatter frequency.
    pub fn points(&self) -> impl Iterator<Item = LobePoint> + 'a {
        let (f, a, n) = (self.chatter_hz, self.depth_m, self.speed_rpm);
        (0..f.len()).map(move |i| LobePoint { speed_rpm: n[i], depth_m: a[i], chatter_hz: f[i] })
    }
}

impl LobeSet {
    /// Number of lobe curves (lobes × runs).
    pub fn len(&self) -> usize {
        self.lobes * self.runs.len()
    }

    /// True when no curve is kept.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The curves in order of branch, lobe number and frequency.
    pub fn iter(&self) -> impl Iterator<Item = Lobe<'_>> + '_ {
        (0..2).flat_map(move |branch| {
            (0..self.lobes).flat_map(move |k| {
                self.runs.iter().filter(move |r| r.0 == branch).map(move |&(_, start, len)| {
                    let at = self.lobes * start + k * len;
                    Lobe {
                        index: k,
                        branch,
                        chatter_hz: &self.chatter_hz[start..start + len],
                        depth_m: &self.depth_m[start..start + len],
                        speed_rpm: &self.speed_rpm[at..at + len],
                    }
                })
            })
        })
    }
}

/// The stability limit on a speed grid: the lowest lobe through each speed.
#[derive(Debug, Clone, PartialEq)]
pub struct StabilityLimit {
    /// Speeds, rpm.
    pub speed_rpm: Vec<f64>,
    /// Limiting depth, m; `+∞` where no lobe of the band passes (no limit found, not a stable guarantee).
    pub depth_m: Vec<f64>,
    /// Chatter frequency of the limiting lobe, Hz (0 where no lobe passes).
    pub chatter_hz: Vec<f64>,
    /// Lobe number `k` that sets the limit.
    pub lobe: Vec<Option<usize>>,
}

impl StabilityLimit {
    fn unbounded(speeds: &[f64]) -> Self {
        StabilityLimit {
            speed_rpm: speeds.to_vec(),
            depth_m: vec![f64::INFINITY; speeds.len()],
            chatter_hz: vec![0.0; speeds.len()],
            lobe: vec![None; speeds.len()],
        }
    }

    fn offer(&mut self, i: usize, depth: f64, chatter: f64, k: usize) {
        if depth < self.depth_m[i] {
            self.depth_m[i] = depth;
            self.chatter_hz[i] = chatter;
            self.lobe[i] = Some(k);
        }
    }
}

/// Lobes and envelope of [`zoa_lobes`].
#[derive(Debug, Clone, PartialEq)]
pub struct ZoaLobes {
    /// Per-lobe curves (empty unless `keep_lobes`).
    pub lobes: LobeSet,
    /// The envelope on the requested speeds.
    pub limit: StabilityLimit,
    /// The smallest limiting depth of any line (the common minimum of all lobes), m.
    pub min_depth_m: f64,
    /// Chatter frequency at that minimum, Hz.
    pub min_depth_chatter_hz: f64,
    /// The number of lobes solved (the explicit count, or the automatic one).
    pub lobe_count: usize,
    /// The lobes the band of significant response needs down to the slowest speed ([`lobes_needed`]); an
    /// explicit count below it leaves part of the band unreached at the low speeds.
    pub lobes_needed: usize,
    /// The highest frequency of significant response, Hz ([`band_top_hz`]).
    pub band_top_hz: f64,
}

/// Depth and phase fraction `e = ε/2π` of one eigenvalue branch at one line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LineRoot {
    pub depth: f64,
    /// `e`, exact or within [`PHASE_APPROX_ERROR`] (see [`line_roots`]).
    pub e: f64,
    /// `Im λ/Re λ`, from which the exact `e = ½ + atan(ratio)/π` follows.
    pub ratio: f64,
}

impl LineRoot {
    /// The exact phase fraction.
    #[inline]
    pub fn exact_e(&self) -> f64 {
        0.5 + self.ratio.atan() / PI
    }
}

/// Bound on the error of the approximate phase fraction: `|Δe| ≤ 0.0016 rad/π ≈ 5e-4`, with margin.
pub(crate) const PHASE_APPROX_ERROR: f64 = 1e-3;

/// `atan x` within 0.0016 rad (`π x/4 − x(|x| − 1)(0.2447 + 0.0663|x|)` on `|x| ≤ 1`, Rajan et al. 2006,
/// IEEE Signal Processing Magazine 23:108; reflected through `π/2 − atan(1/x)` outside).
#[inline]
fn atan_approx(x: f64) -> f64 {
    let a = x.abs();
    let core = |t: f64| std::f64::consts::FRAC_PI_4 * t - t * (t - 1.0) * (0.2447 + 0.0663 * t);
    let v = if a <= 1.0 { core(a) } else { std::f64::consts::FRAC_PI_2 - core(1.0 / a) };
    v.copysign(x)
}

/// Principal square root by the real formula (`√((|z| + |Re z|)/2)` and `Im z/(2·that)`), much cheaper than the
/// polar form; scaled where the squares could under- or overflow.
#[inline]
fn csqrt(z: Complex64) -> Complex64 {
    let (x, y) = (z.re, z.im);
    if x == 0.0 && y == 0.0 {
        return z;
    }
    let scale = x.abs().max(y.abs());
    let r = if (1e-150..1e150).contains(&scale) {
        (x * x + y * y).sqrt()
    } else {
        let (u, v) = (x / scale, y / scale);
        scale * (u * u + v * v).sqrt()
    };
    let t = (0.5 * (r + x.abs())).sqrt();
    if x >= 0.0 { Complex64::new(t, 0.5 * y / t) } else { Complex64::new(0.5 * y.abs() / t, t.copysign(y)) }
}

/// Receptances of one grid as slices (`cross` = `(Φxy, Φyx)`), possibly a leading part of the grid.
#[derive(Clone, Copy)]
pub(crate) struct FrfSlices<'a> {
    pub freqs_hz: &'a [f64],
    pub xx: &'a [Complex64],
    pub yy: &'a [Complex64],
    pub cross: Option<(&'a [Complex64], &'a [Complex64])>,
}

impl ToolPointFrf {
    /// The first `lines` lines as slices.
    pub(crate) fn slices(&self, lines: usize) -> FrfSlices<'_> {
        let l = lines.min(self.freqs_hz.len());
        FrfSlices {
            freqs_hz: &self.freqs_hz[..l],
            xx: &self.xx[..l],
            yy: &self.yy[..l],
            cross: self.cross.as_ref().map(|(p, q)| (&p[..l], &q[..l])),
        }
    }
}

/// The oriented transfer function `[Φ][A₀]` at line `j` (`a` the directional factors), row-major.
#[inline]
fn oriented(frf: &FrfSlices<'_>, a: &[[f64; 2]; 2], j: usize) -> [Complex64; 4] {
    let zero = Complex64::new(0.0, 0.0);
    let (xx, yy) = (frf.xx[j], frf.yy[j]);
    let (xy, yx) = frf.cross.map_or((zero, zero), |(p, q)| (p[j], q[j]));
    [xx * a[0][0] + yx * a[0][1], xy * a[0][0] + yy * a[0][1], xx * a[1][0] + yx * a[1][1], xy * a[1][0] + yy * a[1][1]]
}

/// The two eigenvalues of a 2 × 2 matrix (row-major).
#[inline]
fn eigenvalues([m00, m01, m10, m11]: [Complex64; 4]) -> [Complex64; 2] {
    let half_tr = 0.5 * (m00 + m11);
    let disc = csqrt(half_tr * half_tr - (m00 * m11 - m01 * m10));
    [half_tr + disc, half_tr - disc]
}

/// `lam` in the order that pairs each of its eigenvalues with the nearer one of the previous line's `prev`
/// (nearest-eigenvalue matching of the two branches).
#[inline]
fn matched(mut lam: [Complex64; 2], prev: &[Complex64; 2]) -> [Complex64; 2] {
    let (p, l) = (prev, lam);
    if (l[0] - p[0]).norm_sqr().sqrt() + (l[1] - p[1]).norm_sqr().sqrt()
        > (l[0] - p[1]).norm_sqr().sqrt() + (l[1] - p[0]).norm_sqr().sqrt()
    {
        lam.swap(0, 1);
    }
    lam
}

/// The ZOA root of eigenvalue `l` at frequency `f`, if it has one (`Re λ > 0`): depth `2π/(N Kt Re λ)` with
/// `n_kt = N Kt`, and the phase fraction, approximate unless `exact_phase`.
#[inline]
fn line_root(f: f64, l: Complex64, n_kt: f64, exact_phase: bool) -> Option<LineRoot> {
    if f <= 0.0 || l.re.is_nan() || l.re <= 0.0 {
        return None;
    }
    let depth = TAU / (l.re * n_kt);
    let ratio = l.im / l.re;
    let e = 0.5 + if exact_phase { ratio.atan() } else { atan_approx(ratio) } / PI;
    (depth.is_finite() && depth > 0.0).then_some(LineRoot { depth, e, ratio })
}

/// Per line, the ZOA roots of both eigenvalue branches (branches followed by nearest-eigenvalue matching). With
/// `Λ = −1/λ` the depth `−2πΛ_R(1 + κ²)/(N Kt)` simplifies to `2π/(N Kt Re λ)` and the phase
/// `ε = π − 2 atan κ` to `π + 2 atan(Im λ/Re λ)`; a line has a root where `Re λ > 0` (`Re Λ < 0`).
///
/// With `exact_phase` false, `e` is approximated (within [`PHASE_APPROX_ERROR`]); callers that only need to know
/// which lobes pass between lines then take [`LineRoot::exact_e`] where one does.
pub(crate) fn line_roots(
    frf: FrfSlices<'_>,
    milling: &Milling,
    exact_phase: bool,
    out: &mut Vec<[Option<LineRoot>; 2]>,
) {
    line_roots_oriented(frf, &milling.directional_factors(), milling, exact_phase, out);
}

/// [`line_roots`] with the directional factors `a` given instead of [`Milling::directional_factors`] (the
/// average-tooth-angle formulation of [`super::process_damping`] takes them at one angle).
pub(crate) fn line_roots_oriented(
    frf: FrfSlices<'_>,
    a: &[[f64; 2]; 2],
    milling: &Milling,
    exact_phase: bool,
    out: &mut Vec<[Option<LineRoot>; 2]>,
) {
    let n_kt = milling.teeth as f64 * milling.coefficients.kt;
    out.clear();
    out.reserve(frf.freqs_hz.len());
    // First the eigenvalues of every line (independent lines, so the square roots overlap), then the branch
    // matching and the roots.
    let lams: Vec<[Complex64; 2]> = (0..frf.freqs_hz.len()).map(|j| eigenvalues(oriented(&frf, a, j))).collect();
    let mut prev: Option<[Complex64; 2]> = None;
    for (j, &lam) in lams.iter().enumerate() {
        let lam = prev.map_or(lam, |p| matched(lam, &p));
        prev = Some(lam);
        let f = frf.freqs_hz[j];
        out.push([line_root(f, lam[0], n_kt, exact_phase), line_root(f, lam[1], n_kt, exact_phase)]);
    }
}

/// Linear interpolation of a lobe segment at speed `s` (the same arithmetic for the envelope and the
/// speed-dependent limit).
#[inline]
pub(crate) fn segment_at(n1: f64, a1: f64, f1: f64, n2: f64, a2: f64, f2: f64, s: f64) -> (f64, f64) {
    if n2 == n1 {
        return if a1 <= a2 { (a1, f1) } else { (a2, f2) };
    }
    let t = (s - n1) / (n2 - n1);
    (a1 + t * (a2 - a1), f1 + t * (f2 - f1))
}

/// ZOA lobes and their envelope on `options.speeds_rpm`. Every lobe has the same minimum depth (the depth
/// depends on the chatter frequency only), reported as [`ZoaLobes::min_depth_m`].
pub fn zoa_lobes(frf: &ToolPointFrf, milling: &Milling, options: &ZoaOptions) -> Result<ZoaLobes, StabilityError> {
    if !milling.has_equal_pitch() {
        return Err(StabilityError::UnequalPitch);
    }
    frf.validate()?;
    let frf = &*refine(frf, options.resolution_hz);
    let grid = &options.speeds_rpm;
    if let Some(i) = grid.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(StabilityError::InvalidParameter {
            name: "speed grid value",
            value: grid[i],
            requirement: "finite and > 0 rpm",
        });
    }
    if let Some(i) = grid.windows(2).position(|w| w[1] <= w[0]) {
        return Err(StabilityError::InvalidParameter {
            name: "speed grid value",
            value: grid[i + 1],
            requirement: "speeds must increase strictly",
        });
    }
    let mut roots = Vec::new();
    line_roots(frf.slices(usize::MAX), milling, true, &mut roots);
    let (mut min_depth, mut min_f) = (f64::INFINITY, 0.0);
    for (j, r) in roots.iter().enumerate() {
        for x in r.iter().flatten() {
            if x.depth < min_depth {
                min_depth = x.depth;
                min_f = frf.freqs_hz[j];
            }
        }
    }
    if !min_depth.is_finite() {
        return Err(StabilityError::NoResonance {
            f_lo: frf.freqs_hz.first().copied().unwrap_or(0.0),
            f_hi: frf.freqs_hz.last().copied().unwrap_or(0.0),
        });
    }
    let band_top = band_top_hz(frf);
    let n_min = grid.first().copied().unwrap_or(f64::INFINITY);
    let needed = lobes_needed(band_top, milling.teeth, n_min);
    let count = lobe_count(options.lobes, band_top, milling.teeth, n_min)?;
    let mut limit = StabilityLimit::unbounded(grid);
    let per_tooth = 60.0 / milling.teeth as f64;
    let mut lobes = LobeSet { lobes: count, ..LobeSet::default() };
    if options.keep_lobes {
        // One allocation per array, sized exactly: every line with a root is one point of every lobe.
        let points = roots.iter().flatten().filter(|r| r.is_some()).count();
        lobes.chatter_hz.reserve_exact(points);
        lobes.depth_m.reserve_exact(points);
        lobes.speed_rpm.reserve_exact(points * count);
    }
    // Per branch, the runs of consecutive lines with a root as (f, N-scaled f, depth, e) in structure-of-arrays
    // form; the eigenproblem is solved once per line and each lobe is only a speed mapping n = 60 f/(N (k + e))
    // of the same points, written straight into the kept lobes (or a scratch row) and offered to the envelope.
    let cap = roots.len();
    let (mut rf, mut rc, mut ra, mut re) =
        (Vec::with_capacity(cap), Vec::with_capacity(cap), Vec::with_capacity(cap), Vec::with_capacity(cap));
    let mut scratch: Vec<f64> = Vec::with_capacity(if options.keep_lobes { 0 } else { cap });
    for branch in 0..2 {
        let mut start = 0;
        while start < roots.len() {
            if roots[start][branch].is_none() {
                start += 1;
                continue;
            }
            rf.clear();
            rc.clear();
            ra.clear();
            re.clear();
            let mut j = start;
            while let Some(Some(x)) = roots.get(j).map(|r| r[branch]) {
                let f = frf.freqs_hz[j];
                rf.push(f);
                rc.push(per_tooth * f);
                ra.push(x.depth);
                re.push(x.e);
                j += 1;
            }
            start = j;
            if options.keep_lobes {
                lobes.runs.push((branch, lobes.chatter_hz.len(), rf.len()));
                lobes.chatter_hz.extend_from_slice(&rf);
                lobes.depth_m.extend_from_slice(&ra);
            }
            for k in 0..count {
                let kf = k as f64;
                let speeds = if options.keep_lobes {
                    let at = lobes.speed_rpm.len();
                    lobes.speed_rpm.extend(rc.iter().zip(&re).map(|(&c, &e)| c / (kf + e)));
                    &lobes.speed_rpm[at..]
                } else {
                    scratch.clear();
                    scratch.extend(rc.iter().zip(&re).map(|(&c, &e)| c / (kf + e)));
                    &scratch[..]
                };
                envelope_pass(grid, &rf, &ra, speeds, k, &mut limit);
            }
        }
    }
    Ok(ZoaLobes {
        lobes,
        limit,
        min_depth_m: min_depth,
        min_depth_chatter_hz: min_f,
        lobe_count: count,
        lobes_needed: needed,
        band_top_hz: band_top,
    })
}

/// Offers lobe `k`'s run of points (chatter frequency `freqs[i]`, depth `depths[i]` at speed `speeds[i]`) to the envelope: every grid
/// speed between two consecutive points gets the linearly interpolated depth. The speed along a run changes
/// smoothly, so the grid index is followed by walking rather than searched.
fn envelope_pass(grid: &[f64], freqs: &[f64], depths: &[f64], speeds: &[f64], k: usize, limit: &mut StabilityLimit) {
    let Some(&first) = speeds.first() else { return };
    let (grid_lo, grid_hi) = (grid.first().copied().unwrap_or(0.0), grid.last().copied().unwrap_or(0.0));
    // cursor = number of grid speeds below the current point n, which lies in the cell (cl, ch].
    let mut cursor = grid.partition_point(|&g| g < first);
    let cell = |c: usize| {
        (if c == 0 { f64::NEG_INFINITY } else { grid[c - 1] }, grid.get(c).copied().unwrap_or(f64::INFINITY))
    };
    let (mut cl, mut ch) = cell(cursor);
    for i in 1..speeds.len() {
        let (n1, n) = (speeds[i - 1], speeds[i]);
        // Most segments lie strictly inside one grid cell and hold no grid speed.
        if n > cl && n < ch && n1 < ch {
            continue;
        }
        let (lo, hi) = if n1 <= n { (n1, n) } else { (n, n1) };
        let (f1, a1, f, a) = (freqs[i - 1], depths[i - 1], freqs[i], depths[i]);
        // The interpolated depth is at least min(a1, a) up to rounding: a grid speed whose limit is already at or
        // below that bound (with a 1e-12 margin for the rounding) cannot be lowered, and skips the division.
        let floor = a1.min(a) * (1.0 - 1e-12);
        while cursor > 0 && grid[cursor - 1] >= n {
            cursor -= 1;
        }
        while cursor < grid.len() && grid[cursor] < n {
            cursor += 1;
        }
        (cl, ch) = cell(cursor);
        if hi < grid_lo || lo > grid_hi {
            continue;
        }
        let mut g = cursor;
        if n1 <= n {
            if g < grid.len() && grid[g] == n && floor < limit.depth_m[g] {
                let (d, fc) = segment_at(n1, a1, f1, n, a, f, grid[g]);
                limit.offer(g, d, fc, k);
            }
            while g > 0 && grid[g - 1] >= lo {
                g -= 1;
                if floor < limit.depth_m[g] {
                    let (d, fc) = segment_at(n1, a1, f1, n, a, f, grid[g]);
                    limit.offer(g, d, fc, k);
                }
            }
        } else {
            while g < grid.len() && grid[g] <= hi {
                if floor < limit.depth_m[g] {
                    let (d, fc) = segment_at(n1, a1, f1, n, a, f, grid[g]);
                    limit.offer(g, d, fc, k);
                }
                g += 1;
            }
        }
    }
}

/// ZOA limit at one speed from the lobes passing through it: for each pair of adjacent valid lines and each
/// lobe `k` whose speed `60 f/(N(k + e))` brackets `speed_rpm`, the depth interpolated as in [`zoa_lobes`].
/// Every segment is offered: the reference [`limit_at_speed_pruned`] is checked against.
#[cfg(test)]
pub(crate) fn limit_at_speed(
    freqs_hz: &[f64],
    roots: &[[Option<LineRoot>; 2]],
    teeth: usize,
    lobes: usize,
    speed_rpm: f64,
) -> (f64, f64, Option<usize>) {
    let segment = Segment::at(teeth, lobes, speed_rpm);
    let mut best = (f64::INFINITY, 0.0, None);
    for branch in 0..2 {
        for j in 1..roots.len() {
            let (Some(p), Some(q)) = (roots[j - 1][branch], roots[j][branch]) else { continue };
            segment.offer(freqs_hz[j - 1], p, freqs_hz[j], q, &mut best);
        }
    }
    best
}

/// The lobes of one speed through one segment between adjacent lines.
struct Segment {
    per_tooth: f64,
    period: f64,
    lobes: usize,
    speed_rpm: f64,
}

impl Segment {
    fn at(teeth: usize, lobes: usize, speed_rpm: f64) -> Self {
        let per_tooth = 60.0 / teeth as f64;
        Segment { per_tooth, period: per_tooth / speed_rpm, lobes, speed_rpm }
    }

    /// Lowers `best` (depth, chatter frequency, lobe) by the lobes passing the speed between root `p` at `f1` and
    /// root `q` at `f2`.
    #[inline]
    fn offer(&self, f1: f64, p: LineRoot, f2: f64, q: LineRoot, best: &mut (f64, f64, Option<usize>)) {
        let (per_tooth, period, lobes) = (self.per_tooth, self.period, self.lobes);
        // Screen with the stored (possibly approximate) phases widened by their error, then decide exactly.
        let (v1, v2) = (f1 * period - p.e, f2 * period - q.e);
        let (lo, hi) = if v1 <= v2 { (v1, v2) } else { (v2, v1) };
        if integer_range(lo - PHASE_APPROX_ERROR, hi + PHASE_APPROX_ERROR, lobes).is_none() {
            return;
        }
        let (e1, e2) = (p.exact_e(), q.exact_e());
        let (u1, u2) = (f1 * period - e1, f2 * period - e2);
        let (lo, hi) = if u1 <= u2 { (u1, u2) } else { (u2, u1) };
        let Some((k_lo, k_hi)) = integer_range(lo, hi, lobes) else { return };
        let mut kf = k_lo;
        while kf <= k_hi {
            let (n1, n2) = (per_tooth * f1 / (kf + e1), per_tooth * f2 / (kf + e2));
            let (d, fc) = segment_at(n1, p.depth, f1, n2, q.depth, f2, self.speed_rpm);
            if d < best.0 {
                *best = (d, fc, Some(kf as usize));
            }
            kf += 1.0;
        }
    }
}

/// Reused buffers of [`limit_at_speed_pruned`].
#[derive(Default)]
pub(crate) struct LimitScratch {
    /// Per line, the eigenvalues once solved.
    lam: Vec<Option<[Complex64; 2]>>,
    /// Per segment (line `j − 1` to `j`), the larger squared norm `‖[Φ][A₀]‖_F²` of its two lines, widened.
    norm2: Vec<f64>,
    /// Per segment, whether it was offered.
    offered: Vec<bool>,
}

/// The ZOA limit at one speed over the lines of `frf`, as [`line_roots`] and [`limit_at_speed`] over every line
/// give it, solving the eigenproblem only where a root can set it.
///
/// Every root of a line is at least `2π/(N Kt ‖[Φ][A₀]‖_F)` deep (`Re λ ≤ |λ| ≤ ‖·‖_F`), and a lobe between two
/// lines is at least the shallower end deep. The segments are offered in passes of a rising depth bound,
/// starting at four times the lowest line bound, until the limit found lies within the bound: a segment left
/// out is then deeper than the limit. The branches of a segment are paired by nearest eigenvalues between its
/// two lines alone, as [`line_roots`] pairs them; the result is the same limit except that of two lobes
/// exactly equally deep at the speed, the one found first is kept.
pub(crate) fn limit_at_speed_pruned(
    frf: FrfSlices<'_>,
    milling: &Milling,
    lobes: usize,
    speed_rpm: f64,
    scratch: &mut LimitScratch,
) -> (f64, f64, Option<usize>) {
    limit_at_speed_oriented(frf, &milling.directional_factors(), milling, lobes, speed_rpm, scratch)
}

/// [`limit_at_speed_pruned`] with the directional factors `a` given instead of [`Milling::directional_factors`]
/// (as [`line_roots_oriented`]).
pub(crate) fn limit_at_speed_oriented(
    frf: FrfSlices<'_>,
    a: &[[f64; 2]; 2],
    milling: &Milling,
    lobes: usize,
    speed_rpm: f64,
    scratch: &mut LimitScratch,
) -> (f64, f64, Option<usize>) {
    let n = frf.freqs_hz.len();
    let n_kt = milling.teeth as f64 * milling.coefficients.kt;
    let segment = Segment::at(milling.teeth, lobes, speed_rpm);
    let mut best = (f64::INFINITY, 0.0, None);
    if n < 2 {
        return best;
    }
    let LimitScratch { lam, norm2, offered } = scratch;
    lam.clear();
    lam.resize(n, None);
    offered.clear();
    offered.resize(n, false);
    norm2.clear();
    // `‖[Φ][A₀]‖_F²` per line, widened far beyond the rounding of the eigenvalues' and the interpolation's
    // arithmetic so the depth bound `2π/(N Kt √norm2)` stays below every depth of a segment; NaN offers always.
    let widen = |v: f64| if v.is_nan() { f64::INFINITY } else { v * (1.0 + 1e-6) };
    match frf.cross {
        // Without cross terms the columns are Φxx (a00, a10) and Φyy (a01, a11).
        None => {
            let (cx, cy) = (a[0][0] * a[0][0] + a[1][0] * a[1][0], a[0][1] * a[0][1] + a[1][1] * a[1][1]);
            norm2.extend(frf.xx.iter().zip(frf.yy).map(|(x, y)| widen(x.norm_sqr() * cx + y.norm_sqr() * cy)));
        }
        Some(_) => norm2.extend((0..n).map(|j| widen(oriented(&frf, a, j).iter().map(|z| z.norm_sqr()).sum()))),
    }
    // Per segment (ending at line j), the larger of its two lines.
    let mut largest = 0.0f64;
    for j in (1..n).rev() {
        norm2[j] = norm2[j].max(norm2[j - 1]);
        largest = largest.max(norm2[j]);
    }
    if largest == 0.0 {
        return best;
    }
    // The squared norm a segment needs to reach a depth at or below `depth`.
    let needed = |depth: f64| {
        let r = TAU / (n_kt * depth);
        r * r
    };
    // Four times the lowest bound in depth is a sixteenth in squared norm.
    let mut threshold = largest / 16.0;
    loop {
        for j in 1..n {
            if offered[j] || norm2[j] < threshold {
                continue;
            }
            offered[j] = true;
            if best.0.is_finite() && norm2[j] < needed(best.0) {
                continue;
            }
            let mut solved = |i: usize| *lam[i].get_or_insert_with(|| eigenvalues(oriented(&frf, a, i)));
            let p = solved(j - 1);
            let q = matched(solved(j), &p);
            let (f1, f2) = (frf.freqs_hz[j - 1], frf.freqs_hz[j]);
            for b in 0..2 {
                if let (Some(r1), Some(r2)) = (line_root(f1, p[b], n_kt, false), line_root(f2, q[b], n_kt, false)) {
                    segment.offer(f1, r1, f2, r2, &mut best);
                }
            }
        }
        if threshold == 0.0 || (best.0.is_finite() && needed(best.0) >= threshold) {
            return best;
        }
        // Everything that can reach the limit found must be offered; with none found yet, widen the bound (from
        // the largest finite one when a line's norm overflowed, so the passes always end).
        threshold = if best.0.is_finite() {
            needed(best.0)
        } else if threshold.is_finite() {
            threshold / 256.0
        } else {
            f64::MAX
        };
        if threshold < f64::MIN_POSITIVE {
            threshold = 0.0;
        }
    }
}

/// The lobe numbers `k` in `[⌈lo⌉, ⌊hi⌋] ∩ [0, lobes − 1]` as floats, `None` if there is none (integer casts
/// truncate, which is `⌊·⌋` for values ≥ 0).
#[inline]
fn integer_range(lo: f64, hi: f64, lobes: usize) -> Option<(f64, f64)> {
    // NaN compares false: no lobe.
    if hi.is_nan() || hi < 0.0 || lobes == 0 {
        return None;
    }
    let k_hi = (hi.min(lobes as f64 - 1.0) as u64) as f64;
    let k_lo = if lo <= 0.0 {
        0.0
    } else {
        let t = lo.min(1e18) as u64 as f64;
        if t < lo { t + 1.0 } else { t }
    };
    (k_lo <= k_hi).then_some((k_lo, k_hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The approximate arctangent stays within 0.0016 rad of `atan` (worst 0.00151) over twelve decades either side of zero, so
    /// the phase fraction is within [`PHASE_APPROX_ERROR`].
    #[test]
    fn approximate_atan_error_is_bounded() {
        let mut worst = 0.0f64;
        for i in -60_000..=60_000 {
            let x = 10f64.powf(i as f64 / 5000.0);
            for v in [x, -x] {
                worst = worst.max((atan_approx(v) - v.atan()).abs());
            }
        }
        assert!(worst < 0.0016, "{worst}");
        assert!(worst > 1e-4, "{worst}");
        assert!(worst / PI < PHASE_APPROX_ERROR);
        assert_eq!(atan_approx(0.0), 0.0);
    }

    /// The pruned limit at a speed is the limit over every line: on two- and one-direction modal FRFs, with and
    /// without cross terms, up- and down-milling, at 1,500 speeds from far below to above the modes.
    #[test]
    fn the_pruned_limit_at_a_speed_equals_the_full_one() {
        use crate::stability::{CuttingCoefficients, MillingDirection};
        let model = crate::stability::tests::w04_model();
        let freqs: Vec<f64> = (1..=6000).map(|i| i as f64).collect();
        let two = model.receptance(&freqs).unwrap();
        let cross: Vec<Complex64> = two.xx.iter().zip(&two.yy).map(|(a, b)| 0.3 * (a - b)).collect();
        let coupled = two.clone().with_cross(cross.clone(), cross.iter().map(|c| -0.5 * c).collect()).unwrap();
        let one =
            ToolPointFrf::new(freqs.clone(), two.xx.clone(), vec![Complex64::new(0.0, 0.0); freqs.len()]).unwrap();
        let mut scratch = LimitScratch::default();
        let mut roots = Vec::new();
        let mut compared = 0;
        for (frf, direction, immersion) in [
            (&two, MillingDirection::Up, 0.25),
            (&coupled, MillingDirection::Down, 0.5),
            (&one, MillingDirection::Down, 1.0),
        ] {
            let k = CuttingCoefficients::from_ks_beta(2000e6, 70f64.to_radians()).unwrap();
            let milling = Milling::new(4, immersion, direction, k).unwrap();
            for i in 0..500 {
                let speed = 300.0 * 1.01f64.powi(i);
                let lines = frf.slices(usize::MAX);
                line_roots(lines, &milling, false, &mut roots);
                let full = limit_at_speed(lines.freqs_hz, &roots, 4, 40, speed);
                let pruned = limit_at_speed_pruned(lines, &milling, 40, speed, &mut scratch);
                assert_eq!(full.0.to_bits(), pruned.0.to_bits(), "{speed} rpm: {full:?} vs {pruned:?}");
                assert_eq!((full.1.to_bits(), full.2), (pruned.1.to_bits(), pruned.2), "{speed} rpm");
                compared += usize::from(full.0.is_finite());
            }
        }
        assert!(compared > 1000, "{compared}");
    }

    /// A line whose norm overflows and no line with a root: the passes end, with no limit.
    #[test]
    fn the_pruned_limit_ends_when_a_norm_overflows() {
        use crate::stability::{CuttingCoefficients, MillingDirection};
        let milling =
            Milling::new(2, 1.0, MillingDirection::Down, CuttingCoefficients::from_kt_kn(6e8, 2e8).unwrap()).unwrap();
        // Positive real receptances have no root in slotting; 1e160 squared overflows.
        let mut c = vec![Complex64::new(1e-7, 0.0); 50];
        c[20] = Complex64::new(1e160, 0.0);
        let frf = ToolPointFrf::new((1..=50).map(f64::from).collect(), c.clone(), c).unwrap();
        let limit = limit_at_speed_pruned(frf.slices(usize::MAX), &milling, 10, 3000.0, &mut LimitScratch::default());
        assert_eq!(limit, (f64::INFINITY, 0.0, None));
    }
}
