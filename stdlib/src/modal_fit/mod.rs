//! Equivalent-mode identification of a direct tip receptance, dissertation §5.2.
//!
//! A measured direct FRF `H11^m` is represented by a sum of single-degree-of-freedom modes (Eq. 5.8,
//! `H = 1/(K − Mω² + iωC)`, `K = M(2πf)²`, `C = 2ξ sqrt(MK)`), each of which is then mapped to a solid
//! fixed-free Euler–Bernoulli beam of the same natural frequency (§5.2.5). The sum of the beams' free-end
//! receptances gives the fitted FRF (Eq. 5.7) and the full 2×2 tip block `G11` (Eqs. 5.10–5.12, with the
//! fixed-free denominator `1 + cos λL cosh λL`). By default the beams are then refitted jointly against the
//! measured FRF (see `refit`), because a beam's higher bending modes and above-resonance behaviour make the
//! plain sum of separately mapped beams depart from the measurement away from each beam's own resonance.
//!
//! Two identification methods produce the same outputs:
//! - [`Method::Simplex`], the dissertation's procedure: peak picking (§5.2.1), a Nelder–Mead fit per mode on a
//!   band chosen by Eq. 5.13 (§5.2.2), optional floating modes (§5.2.3, Eqs. 5.14–5.15), global iterations with
//!   the other modes held and deletion of modes stuck at their bounds (§5.2.4);
//! - [`Method::Lscf`], a least-squares complex frequency-domain (z-domain common-denominator) estimate of the
//!   poles with a frequency/damping stabilisation check, and residues by least squares with lower and upper
//!   residual terms.
//!
//! The FRFs of a measurement set are fitted together by [`fit_set`] (`polyref`): one set of poles for all,
//! from the poly-reference LSCF and its stabilisation diagram, and residues per FRF by LSFD.

mod lscf;
mod lsfd;
mod map;
mod pick;
mod polyref;
mod refit;
mod simplex;
#[cfg(test)]
mod tests;

pub use lsfd::{ResidueFit, lsfd, lsfd_weighted, mode_of_residue, pair_h, pole, real_residue, signed_mode_of_residue};
pub use map::{beam_for_mode, closed_form_diameter};
pub use pick::{Peak, moving_average, pick_modes, pick_modes_signed};
pub use polyref::{DiagramPole, SetFit, SetOptions, SharedPole, Stability, Targets, fit_set};
pub use refit::REFIT_ITERATIONS;

use crate::eb_modes::{EbError, FixedFreeBeam};
use crate::rcsa::{Receptance, ReceptanceFrf};
use num_complex::Complex64;
use spindlelab_domain::Material;
use spindlelab_domain::value::Mode;
use std::f64::consts::TAU;
use thiserror::Error;

/// Fewest frequency lines an FRF (and the fit band) must have.
pub const MIN_LINES: usize = 8;

/// Lines of a mode's band (within ±3 half-power widths) on which its beam is matched (§5.2.5).
pub const MAP_POINTS: usize = 32;

/// Half-width limit of a per-mode band, constraint b of Eq. 5.13, Hz.
pub const BAND_HALF_WIDTH_HZ: f64 = 200.0;

/// Errors of the modal fit.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FitError {
    /// The grid and the values differ in length.
    #[error("{freqs} frequencies but {values} FRF values; both must have one entry per line")]
    LengthMismatch {
        /// Number of frequencies.
        freqs: usize,
        /// Number of values.
        values: usize,
    },
    /// Too few lines to fit anything.
    #[error("{lines} frequency line(s) {place}; at least {min} are needed (widen the band or measure more lines)")]
    TooFewLines {
        /// Lines found.
        lines: usize,
        /// Lines required.
        min: usize,
        /// Where (`in the FRF`, `in the fit band`).
        place: &'static str,
    },
    /// A frequency is not larger than the one before it.
    #[error("frequency line {index} is {value} Hz, not above the previous {previous} Hz; the grid must increase")]
    NonIncreasing {
        /// Index of the line.
        index: usize,
        /// Previous frequency, Hz.
        previous: f64,
        /// This frequency, Hz.
        value: f64,
    },
    /// A frequency or an FRF value is not finite (or a frequency is negative).
    #[error("{what} at line {index} is {value}; frequencies must be finite and ≥ 0 and FRF values finite")]
    NonFinite {
        /// `frequency` or `FRF value`.
        what: &'static str,
        /// Index of the line.
        index: usize,
        /// The offending number (the real or imaginary part for values).
        value: f64,
    },
    /// An option is out of range.
    #[error("option {name} = {value}: {requirement}")]
    InvalidOption {
        /// Option name.
        name: &'static str,
        /// Offending value.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// Im(H) has no negative peak in the fit band.
    #[error(
        "Im(H) has no negative peak between {lo_hz} and {hi_hz} Hz; a direct receptance has negative \
         imaginary peaks at its modes (check the sign convention, the band, or lower h_sens)"
    )]
    NoPeaks {
        /// Fit band start, Hz.
        lo_hz: f64,
        /// Fit band end, Hz.
        hi_hz: f64,
    },
    /// No negative peak reaches the vertical sensitivity cut-off.
    #[error(
        "no mode passes v_sens: the largest |Im H| in the band is {largest:e} m/N, so the cut-off is {cutoff:e} m/N \
         (v_sens = {v_sens}), but the deepest negative peak is only {deepest:e} m/N; lower v_sens or move the band"
    )]
    NoModes {
        /// Largest |Im H| (smoothed) in the fit band.
        largest: f64,
        /// The cut-off `v_sens · largest`.
        cutoff: f64,
        /// The option.
        v_sens: f64,
        /// The deepest negative peak found.
        deepest: f64,
    },
    /// Every mode was deleted or rejected.
    #[error("{method}: no mode survived ({why}); check the band, h_sens/v_sens or the model order")]
    NothingLeft {
        /// `simplex` or `lscf`.
        method: &'static str,
        /// Why.
        why: String,
    },
    /// A linear least-squares system of the LSCF method is singular.
    #[error("LSCF {what}: the normal equations are singular (lower the order or widen the band)")]
    Singular {
        /// Which system.
        what: &'static str,
    },
    /// The optimiser failed.
    #[error("Nelder–Mead for the mode near {f_hz} Hz failed: {message}")]
    Optimiser {
        /// Mode frequency, Hz.
        f_hz: f64,
        /// The optimiser's message.
        message: String,
    },
    /// The beam of a mode could not be built.
    #[error("equivalent beam of mode {mode} ({f_hz} Hz): {source}")]
    Beam {
        /// Index of the mode.
        mode: usize,
        /// Its frequency, Hz.
        f_hz: f64,
        /// The beam model's error.
        source: EbError,
    },
}

/// Peak magnitude of a mode's imaginary part, `1/(2ξK)`, m/N (the v_sens cut-off compares modes by it).
pub(crate) fn im_peak(mode: &Mode) -> f64 {
    1.0 / (2.0 * mode.damping_ratio * mode.stiffness())
}

/// Eq. 5.8 for mass `m`, natural angular frequency `wn` and damping ratio `xi` at `w`:
/// `1/(m(wn² − w²) + i·2ξ·m·wn·w)`.
#[inline]
pub(crate) fn mode_h(m: f64, wn: f64, xi: f64, w: f64) -> Complex64 {
    let re = m * (wn * wn - w * w);
    let im = 2.0 * xi * m * wn * w;
    let inv = 1.0 / (re * re + im * im);
    Complex64::new(re * inv, -im * inv)
}

/// How the modes are identified.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// The §5.2 simplex procedure.
    Simplex,
    /// Least-squares complex frequency-domain estimate; `order` is the denominator order (number of poles,
    /// even); `None` takes four poles per picked peak (at least 8), then six and eight while fewer poles than
    /// peaks are stable.
    Lscf {
        /// Model order.
        order: Option<usize>,
    },
}

/// How the least-squares steps (LSCF, LSFD) weight the lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Weighting {
    /// Each line by `1/|H|`: every line counts by its relative error, so the antiresonances and
    /// the skirts weigh as much as the peaks.
    Relative,
    /// Every line alike: the fit minimises the global L2 distance, which the peaks dominate.
    Absolute,
}

/// The residue model of the identified modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Residues {
    /// Real modal masses (Eq. 5.8, proportional damping), the dissertation's model.
    Real,
    /// A complex residue per mode (non-proportional damping): the simplex fits each mode's pole with its residue
    /// solved by linear least squares, and the final residues with lower and upper residual terms come from an
    /// LSFD estimate on the fit band (see [`lsfd`]); reported modal masses are `1/(2ω_d|A|)`.
    Complex,
}

/// Options of [`fit`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// Identification method.
    pub method: Method,
    /// Lower end of the fit band, Hz.
    pub min_frequency_hz: f64,
    /// Upper end of the fit band, Hz (infinite: up to the last line).
    pub max_frequency_hz: f64,
    /// Width of the moving average on Im(H) for peak picking, points (`H_sens`, §5.2.1).
    pub h_sens: usize,
    /// Peak cut-off as a fraction of the largest |Im H| in the band (`V_sens`, §5.2.1).
    pub v_sens: f64,
    /// Least prominence of the smoothed `|H|` at a picked peak, dB (0 disables the check; see [`pick_modes`]).
    pub prominence_db: f64,
    /// Residue model.
    pub residues: Residues,
    /// Global iterations of step 4 (§5.2.4).
    pub iterations: usize,
    /// Stuck modes are deleted after this many global iterations (§5.2.4.1); ≥ `iterations` disables deletion.
    pub delete_after: usize,
    /// Add the random floating modes of §5.2.3.
    pub floating_modes: bool,
    /// Seed of the floating modes.
    pub seed: u64,
    /// Points each band is interpolated to for the per-mode fits (bands with fewer lines use their lines).
    pub band_points: usize,
    /// Material of the equivalent beams.
    pub material: Material,
    /// Refit the mapped beams jointly against the measured FRF (global iterations on the beam model); `false`
    /// keeps the plain per-mode mapping of §5.2.5.
    pub beam_refit: bool,
    /// Modal constants may be negative (a transfer FRF, response and reference at different points or
    /// directions); `false` for a driving point, whose modal masses are all positive.
    pub signed: bool,
    /// Line weights of the least-squares steps.
    pub weighting: Weighting,
    /// The power of `iω` of the FRF the receptance was converted from (0 receptance, 1 mobility, 2
    /// accelerance): modes are picked on `ω^order |H|`-scaled lines and the global L2 residual is measured
    /// in that kind, so the lines a measurement resolves best (an accelerometer's at high frequency) lead,
    /// and low-frequency noise divided by `ω²` does not.
    pub kind_order: i32,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            method: Method::Simplex,
            min_frequency_hz: 0.0,
            max_frequency_hz: f64::INFINITY,
            h_sens: 5,
            v_sens: 0.001,
            prominence_db: 3.0,
            residues: Residues::Real,
            iterations: 20,
            delete_after: 14,
            floating_modes: false,
            seed: 0,
            band_points: 200,
            material: Material::STEEL,
            beam_refit: true,
            signed: false,
            weighting: Weighting::Relative,
            kind_order: 0,
        }
    }
}

/// The frequency range one mode is fitted on (§5.2.2.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Band {
    /// Lower edge, Hz.
    pub lo_hz: f64,
    /// Upper edge, Hz.
    pub hi_hz: f64,
    /// Whether the fit band's edge cut it ([`mode_bands`]); in a [`ModalFit`], whether that edge cuts into the
    /// mode's resonance ([`clips`]).
    pub clipped: bool,
}

/// A mode's equivalent fixed-free beam (§5.2.5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EquivalentBeam {
    /// Natural frequency of its first mode, Hz: the mode's, or where the joint refit moved it (inside the
    /// mode's band).
    pub f_hz: f64,
    /// The beam (diameter, loss factor, free length of Eq. 5.6, material).
    pub beam: FixedFreeBeam,
}

/// Fit quality on one mode's band: `Σ|H^m − H^f| / Σ|H^m|` over the measured lines in the band.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BandError {
    /// Mode frequency, Hz.
    pub f_hz: f64,
    /// Band lower edge, Hz.
    pub lo_hz: f64,
    /// Band upper edge, Hz.
    pub hi_hz: f64,
    /// Error of the sum of Eq. 5.8 modes.
    pub modal: f64,
    /// Error of the sum of equivalent beams (the `fitted` FRF).
    pub beam: f64,
    /// Error of the sum of the beams as mapped mode by mode (§5.2.5), before the joint refit (equal to
    /// `beam` when the refit is off).
    pub mapped: f64,
}

/// Result of [`fit`].
#[derive(Debug, Clone, PartialEq)]
pub struct ModalFit {
    /// Identified modes, by frequency.
    pub modes: Vec<Mode>,
    /// Each mode's band.
    pub bands: Vec<Band>,
    /// Each mode's equivalent beam.
    pub beams: Vec<EquivalentBeam>,
    /// Sum of the beams' H on the input grid (Eq. 5.7).
    pub fitted: Vec<Complex64>,
    /// Sum of the beams' free-end blocks on the input grid (Eqs. 5.7, 5.10–5.12).
    pub tip: ReceptanceFrf,
    /// Fit error per band.
    pub band_errors: Vec<BandError>,
    /// Frequencies picked in step 1, Hz.
    pub picked_hz: Vec<f64>,
    /// Modes removed by §5.2.4.1 (simplex) or rejected by the stabilisation / mass checks (LSCF).
    pub deleted: Vec<Mode>,
    /// Global iterations run (simplex), or orders tried (LSCF).
    pub iterations: usize,
    /// Sweeps of the joint beam refit (0 when it is off).
    pub refit_sweeps: usize,
    /// Residues of the modes, the residual terms and the relative L2 residual of the modal model on the fit band:
    /// the LSFD estimate with complex residues, the Eq. 5.8 residues of the real modes (no residual terms)
    /// otherwise.
    pub residue_fit: ResidueFit,
}

/// Checks the grid: same lengths, at least [`MIN_LINES`] lines, finite and strictly increasing frequencies ≥ 0,
/// finite values.
pub fn check_grid(freqs_hz: &[f64], h: &[Complex64]) -> Result<(), FitError> {
    if freqs_hz.len() != h.len() {
        return Err(FitError::LengthMismatch { freqs: freqs_hz.len(), values: h.len() });
    }
    if freqs_hz.len() < MIN_LINES {
        return Err(FitError::TooFewLines { lines: freqs_hz.len(), min: MIN_LINES, place: "in the FRF" });
    }
    for (index, (&f, v)) in freqs_hz.iter().zip(h).enumerate() {
        if !(f.is_finite() && f >= 0.0) {
            return Err(FitError::NonFinite { what: "frequency", index, value: f });
        }
        if !v.re.is_finite() || !v.im.is_finite() {
            let value = if v.re.is_finite() { v.im } else { v.re };
            return Err(FitError::NonFinite { what: "FRF value", index, value });
        }
        if index > 0 && f <= freqs_hz[index - 1] {
            return Err(FitError::NonIncreasing { index, previous: freqs_hz[index - 1], value: f });
        }
    }
    Ok(())
}

fn check_options(o: &FitOptions) -> Result<(), FitError> {
    let bad = |name, value: f64, requirement| Err(FitError::InvalidOption { name, value, requirement });
    if !(o.min_frequency_hz.is_finite() && o.min_frequency_hz >= 0.0) {
        return bad("min_frequency", o.min_frequency_hz, "must be finite and ≥ 0");
    }
    if o.max_frequency_hz.is_nan() || o.max_frequency_hz <= o.min_frequency_hz {
        return bad("max_frequency", o.max_frequency_hz, "must be above min_frequency");
    }
    if o.h_sens == 0 {
        return bad("h_sens", 0.0, "must be at least 1 point");
    }
    if !(o.v_sens > 0.0 && o.v_sens <= 1.0) {
        return bad("v_sens", o.v_sens, "must be in (0, 1]");
    }
    if !(o.prominence_db.is_finite() && o.prominence_db >= 0.0) {
        return bad("prominence", o.prominence_db, "must be finite and ≥ 0 dB");
    }
    if o.band_points < 8 {
        return bad("band_points", o.band_points as f64, "must be at least 8");
    }
    if let Method::Lscf { order: Some(n) } = o.method
        && !(4..=200).contains(&n)
    {
        return bad("order", n as f64, "must be between 4 and 200");
    }
    Ok(())
}

/// Index range of the lines inside the fit band.
fn fit_range(freqs_hz: &[f64], o: &FitOptions) -> Result<std::ops::Range<usize>, FitError> {
    let start = freqs_hz.partition_point(|&f| f < o.min_frequency_hz);
    let end = freqs_hz.partition_point(|&f| f <= o.max_frequency_hz);
    if end.saturating_sub(start) < MIN_LINES {
        return Err(FitError::TooFewLines {
            lines: end.saturating_sub(start),
            min: MIN_LINES,
            place: "in the fit band",
        });
    }
    Ok(start..end)
}

/// Per-mode bands of §5.2.2.1 around the (sorted) centre frequencies: constraint a) 40 % of the distance to
/// each neighbour (`f⁰ = 0`; above the last mode no neighbour), b) at most [`BAND_HALF_WIDTH_HZ`], then the
/// fit band `[lo, hi]` clips, and c) neither side more than three times the other. Each side keeps at least
/// two line spacings `df`.
pub fn mode_bands(centres_hz: &[f64], lo: f64, hi: f64, df: f64) -> Vec<Band> {
    (0..centres_hz.len())
        .map(|j| {
            let f = centres_hz[j];
            let prev = if j == 0 { 0.0 } else { centres_hz[j - 1] };
            let mut lower = (0.4 * (f - prev)).min(BAND_HALF_WIDTH_HZ);
            let mut upper = match centres_hz.get(j + 1) {
                Some(next) => (0.4 * (next - f)).min(BAND_HALF_WIDTH_HZ),
                None => BAND_HALF_WIDTH_HZ,
            };
            let mut clipped = false;
            if f - lower < lo {
                lower = (f - lo).max(0.0);
                clipped = true;
            }
            if f + upper > hi {
                upper = (hi - f).max(0.0);
                clipped = true;
            }
            lower = lower.max(2.0 * df);
            upper = upper.max(2.0 * df);
            if lower > 3.0 * upper {
                lower = 3.0 * upper;
            } else if upper > 3.0 * lower {
                upper = 3.0 * lower;
            }
            Band { lo_hz: f - lower, hi_hz: f + upper, clipped }
        })
        .collect()
}

/// The result of a fit whose modes cannot be beams (a negative modal constant): the fitted FRF is the modal
/// model (Eq. 5.8 modes, or the LSFD residues with their residual terms), the tip blocks `L`, `N`, `P` are NaN.
#[allow(clippy::too_many_arguments)]
fn without_beams(
    freqs_hz: &[f64],
    h: &[Complex64],
    modes: Vec<Mode>,
    bands: Vec<Band>,
    picked_hz: Vec<f64>,
    deleted: Vec<Mode>,
    iterations: usize,
    residue_fit: ResidueFit,
) -> ModalFit {
    let poles: Vec<Complex64> = modes.iter().map(pole).collect();
    let fitted: Vec<Complex64> = freqs_hz
        .iter()
        .map(|&f| {
            let w = TAU * f;
            let modal: Complex64 = residue_fit.residues.iter().zip(&poles).map(|(&a, &l)| pair_h(a, l, w)).sum();
            let lower = if w > 0.0 { residue_fit.lower / (w * w) } else { 0.0 };
            modal - lower + residue_fit.upper
        })
        .collect();
    let nan = Complex64::new(f64::NAN, f64::NAN);
    let lines = fitted.iter().map(|&v| Receptance { h: v, l: nan, n: nan, p: nan }).collect();
    let band_errors = bands
        .iter()
        .zip(&modes)
        .map(|(b, m)| {
            let a = freqs_hz.partition_point(|&f| f < b.lo_hz);
            let e = freqs_hz.partition_point(|&f| f <= b.hi_hz);
            let num: f64 = (a..e).map(|k| (h[k] - fitted[k]).norm()).sum();
            let den: f64 = (a..e).map(|k| h[k].norm()).sum();
            let err = if den > 0.0 { num / den } else { f64::NAN };
            BandError { f_hz: m.freq_hz, lo_hz: b.lo_hz, hi_hz: b.hi_hz, modal: err, beam: f64::NAN, mapped: f64::NAN }
        })
        .collect();
    ModalFit {
        modes,
        bands,
        beams: Vec::new(),
        fitted,
        tip: ReceptanceFrf { freqs_hz: freqs_hz.to_vec(), lines },
        band_errors,
        picked_hz,
        deleted,
        iterations,
        refit_sweeps: 0,
        residue_fit,
    }
}

/// Mean line spacing of a grid, Hz (0 for fewer than two lines).
pub fn line_spacing(freqs_hz: &[f64]) -> f64 {
    match (freqs_hz.first(), freqs_hz.last()) {
        (Some(a), Some(b)) if freqs_hz.len() > 1 => (b - a) / (freqs_hz.len() - 1) as f64,
        _ => 0.0,
    }
}

/// Indices of the modes whose half-power width `2ξf` (Eq. 5.8: the band where `|H|` is above
/// `1/√2` of its peak) is narrower than one line of `freqs_hz`: the lines cannot resolve such a
/// damping, and a fitted value is only a bound.
pub fn unresolved_damping(modes: &[Mode], freqs_hz: &[f64]) -> Vec<usize> {
    let df = line_spacing(freqs_hz);
    modes.iter().enumerate().filter(|(_, m)| 2.0 * m.damping_ratio * m.freq_hz < df).map(|(i, _)| i).collect()
}

/// Half-power widths (`2ξf`) of a mode that must lie inside the fit band on either side for its
/// resonance and skirts to be fitted; the band's edge nearer than that (or than [`CLIP_LINES`]
/// lines) clips the mode.
pub const CLIP_WIDTHS: f64 = 3.0;

/// Lines that must lie inside the fit band on either side of a mode (see [`CLIP_WIDTHS`]).
pub const CLIP_LINES: f64 = 3.0;

/// Whether the fit band `[lo, hi]` cuts into the resonance of `mode`: an edge within
/// [`CLIP_WIDTHS`] half-power widths or [`CLIP_LINES`] lines of its frequency. A per-mode band
/// (±200 Hz at most, Eq. 5.13) cut by the fit band's edge loses lines far from the resonance,
/// which the fit does not need; only a cut near the resonance deserves a warning.
pub fn clips(mode: &Mode, lo: f64, hi: f64, df: f64) -> bool {
    let reach = (CLIP_WIDTHS * 2.0 * mode.damping_ratio * mode.freq_hz).max(CLIP_LINES * df);
    mode.freq_hz - lo < reach || hi - mode.freq_hz < reach
}

/// Identifies the modes of the direct receptance `h` (m/N) on `freqs_hz`, maps each to its equivalent
/// fixed-free beam and returns the fitted FRF, the tip block `G11` and the fit errors (§5.2).
pub fn fit(freqs_hz: &[f64], h: &[Complex64], opts: &FitOptions) -> Result<ModalFit, FitError> {
    check_grid(freqs_hz, h)?;
    check_options(opts)?;
    let range = fit_range(freqs_hz, opts)?;
    let peaks = picked_peaks(freqs_hz, h, range.clone(), opts)?;
    let picked_hz: Vec<f64> = peaks.iter().map(|p| p.freq_hz).collect();
    let (lo, hi) = (freqs_hz[range.start], freqs_hz[range.end - 1]);
    let df = (hi - lo) / (range.len() - 1) as f64;
    let complex = opts.residues == Residues::Complex;
    let (mut modes, mut bands, deleted, iterations) = match opts.method {
        Method::Simplex => {
            let (modes, _, bands, deleted, iterations) = simplex::fit_modes(freqs_hz, h, range.clone(), &peaks, opts)?;
            (modes, bands, deleted, iterations)
        }
        Method::Lscf { order } => {
            let (modes, rejected, orders) = lscf::fit_modes(
                freqs_hz,
                h,
                range.clone(),
                &peaks,
                order,
                opts.v_sens,
                complex,
                opts.signed,
                opts.weighting,
            )?;
            let centres: Vec<f64> = modes.iter().map(|m| m.freq_hz).collect();
            (modes, mode_bands(&centres, lo, hi, df), rejected, orders)
        }
    };
    let residue_fit = fit_residues(freqs_hz, h, range, &mut modes, opts)?;
    for (b, m) in bands.iter_mut().zip(&modes) {
        b.clipped = clips(m, lo, hi, df);
    }
    // Equivalent beams have positive masses: a mode with a negative modal constant (a transfer FRF) has none,
    // and the fitted FRF is then the modal model itself.
    if modes.iter().any(|m| m.modal_mass < 0.0) {
        return Ok(without_beams(freqs_hz, h, modes, bands, picked_hz, deleted, iterations, residue_fit));
    }
    let mut beams = Vec::with_capacity(modes.len());
    for (i, (m, b)) in modes.iter().zip(&bands).enumerate() {
        let beam = beam_for_mode(m, b, &opts.material, MAP_POINTS).map_err(|source| FitError::Beam {
            mode: i,
            f_hz: m.freq_hz,
            source,
        })?;
        beams.push(EquivalentBeam { f_hz: m.freq_hz, beam });
    }
    let mapped = beams.clone();
    let mut refit_sweeps = 0;
    if opts.beam_refit {
        let r = refit::refit_beams(freqs_hz, h, &bands, &beams, &opts.material, opts.band_points);
        beams = r.beams;
        refit_sweeps = r.sweeps;
    }
    let fast: Vec<refit::FastH> = beams.iter().map(|b| refit::FastH::new(b.beam)).collect();
    let lines: Vec<Receptance> = freqs_hz
        .iter()
        .map(|&f| {
            let sw = (TAU * f).sqrt();
            fast.iter().fold(Receptance::ZERO, |acc, b| acc + b.block(sw))
        })
        .collect();
    let fitted: Vec<Complex64> = lines.iter().map(|r| r.h).collect();
    let mapped = opts.beam_refit.then_some(mapped.as_slice());
    let band_errors = band_errors(freqs_hz, h, &bands, &modes, &fitted, mapped);
    Ok(ModalFit {
        modes,
        bands,
        beams,
        fitted,
        tip: ReceptanceFrf { freqs_hz: freqs_hz.to_vec(), lines },
        band_errors,
        picked_hz,
        deleted,
        iterations,
        refit_sweeps,
        residue_fit,
    })
}

/// The peaks picked in the fit band (§5.2.1), on `h` times `ω^kind_order` (an accelerance or
/// mobility is picked as measured), with their heights back in receptance.
fn picked_peaks(
    freqs_hz: &[f64],
    h: &[Complex64],
    range: std::ops::Range<usize>,
    opts: &FitOptions,
) -> Result<Vec<Peak>, FitError> {
    let scaled: Vec<Complex64>;
    let h_pick = if opts.kind_order == 0 {
        h
    } else {
        scaled = freqs_hz.iter().zip(h).map(|(&f, &v)| v * (TAU * f).powi(opts.kind_order)).collect();
        &scaled
    };
    let mut peaks = pick_modes_signed(
        freqs_hz,
        h_pick,
        range,
        opts.h_sens,
        opts.v_sens,
        10f64.powf(opts.prominence_db / 20.0),
        opts.signed,
    )?;
    for p in &mut peaks {
        p.im /= (TAU * p.freq_hz).powi(opts.kind_order);
    }
    Ok(peaks)
}

/// The residues of the fitted poles: complex by least squares in the frequency domain (the
/// modes then take the residues' modal constants), or the modes' own real ones; with the
/// residuals of the whole model over the fit band, in the measured kind.
fn fit_residues(
    freqs_hz: &[f64],
    h: &[Complex64],
    range: std::ops::Range<usize>,
    modes: &mut [Mode],
    opts: &FitOptions,
) -> Result<ResidueFit, FitError> {
    let mut residue_fit = if opts.residues == Residues::Complex {
        let r = lsfd::lsfd_weighted(&freqs_hz[range.clone()], &h[range.clone()], modes, opts.weighting)?;
        for (m, a) in modes.iter_mut().zip(&r.residues) {
            *m = if opts.signed {
                signed_mode_of_residue(m.freq_hz, m.damping_ratio, *a)
            } else {
                mode_of_residue(m.freq_hz, m.damping_ratio, *a)
            };
        }
        r
    } else {
        let fits: Vec<Complex64> =
            range.clone().map(|k| modes.iter().map(|m| m.receptance(TAU * freqs_hz[k])).sum()).collect();
        let (relative_residual, weighted_residual) = lsfd::residual_measures(&h[range.clone()], &fits);
        ResidueFit {
            residues: modes.iter().map(real_residue).collect(),
            lower: 0.0,
            upper: 0.0,
            relative_residual,
            weighted_residual,
        }
    };
    let poles: Vec<Complex64> = modes.iter().map(pole).collect();
    let r = &residue_fit;
    let scale = |f: f64| (TAU * f).powi(opts.kind_order);
    let lines: Vec<usize> = range.filter(|&k| freqs_hz[k] > 0.0).collect();
    let fits: Vec<Complex64> = lines
        .iter()
        .map(|&k| {
            let w = TAU * freqs_hz[k];
            let modal: Complex64 = r.residues.iter().zip(&poles).map(|(&a, &l)| pair_h(a, l, w)).sum();
            (modal - r.lower / (w * w) + r.upper) * scale(freqs_hz[k])
        })
        .collect();
    let measured: Vec<Complex64> = lines.iter().map(|&k| h[k] * scale(freqs_hz[k])).collect();
    let (global, weighted) = lsfd::residual_measures(&measured, &fits);
    residue_fit.relative_residual = global;
    residue_fit.weighted_residual = weighted;
    Ok(residue_fit)
}

/// Each mode's band error (Eq. 5.14): the modal model's, the fitted beams' and, when the beams
/// were refitted, the beams as first mapped (`mapped`; otherwise the fitted beams' again).
fn band_errors(
    freqs_hz: &[f64],
    h: &[Complex64],
    bands: &[Band],
    modes: &[Mode],
    fitted: &[Complex64],
    mapped: Option<&[EquivalentBeam]>,
) -> Vec<BandError> {
    let mapped_h: Vec<refit::FastH> = mapped.unwrap_or_default().iter().map(|b| refit::FastH::new(b.beam)).collect();
    bands
        .iter()
        .zip(modes)
        .map(|(b, m)| {
            let (mut num_m, mut num_b, mut num_p, mut den) = (0.0, 0.0, 0.0, 0.0);
            let a = freqs_hz.partition_point(|&f| f < b.lo_hz);
            let e = freqs_hz.partition_point(|&f| f <= b.hi_hz);
            for k in a..e {
                let w = TAU * freqs_hz[k];
                let modal: Complex64 = modes.iter().map(|q| q.receptance(w)).sum();
                num_m += (h[k] - modal).norm();
                num_b += (h[k] - fitted[k]).norm();
                if mapped.is_some() {
                    let plain: Complex64 = mapped_h.iter().map(|q| q.h(w.sqrt())).sum();
                    num_p += (h[k] - plain).norm();
                }
                den += h[k].norm();
            }
            if mapped.is_none() {
                num_p = num_b;
            }
            let den = if den > 0.0 { den } else { f64::INFINITY };
            BandError {
                f_hz: m.freq_hz,
                lo_hz: b.lo_hz,
                hi_hz: b.hi_hz,
                modal: num_m / den,
                beam: num_b / den,
                mapped: num_p / den,
            }
        })
        .collect()
}
