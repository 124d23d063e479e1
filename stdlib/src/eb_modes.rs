//! Fixed-free Euler–Bernoulli beam receptances, the "equivalent modes" of a spindle, dissertation §5.1.
//!
//! Each measured spindle mode is represented by a solid circular cantilever of diameter `d`, loss factor
//! `η` (complex modulus `E(1 + iη)`) and a free length chosen by Eq. 5.6 so that its first bending mode is
//! at the mode's natural frequency. The free-end receptances are Bishop & Johnson's closed forms
//! (Eqs. 5.5, 5.10, 5.11) with the fixed-free denominator `1 + cos λL cosh λL` (the printed
//! `cos λL cosh λL − 1` is the free-free frequency equation). A spindle direction is the sum of its modes'
//! receptances (Eqs. 5.7, 5.12).
//!
//! Sign convention (the whole project): displacement `y`, rotation `θ = dy/dx`, force along `+y`, moment in
//! the `θ` sense, and the beam axis runs from the clamped end to the free end. Then all four free-end
//! receptances have positive static limits `H = L³/3EI`, `L = N = L²/2EI`, `P = L/EI`.

use crate::rcsa::{Receptance, ReceptanceFrf};
use num_complex::Complex64;
use spindlelab_domain::entity::{SpindleMode, Whirl};
use spindlelab_domain::{Material, Speed};
use std::f64::consts::{PI, TAU};
use thiserror::Error;

/// First root of the fixed-free frequency equation `1 + cos x cosh x = 0` (Eq. 5.6).
pub const FIXED_FREE_ROOT_1: f64 = 1.875_104_068_711_961;

/// Below this `|λL|` the receptances are evaluated from power series (exact static limit, no cancellation).
const SERIES_LIMIT: f64 = 1.0;

/// Errors of the equivalent-mode model.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EbError {
    /// A parameter is out of range.
    #[error("invalid {name} = {value}: {requirement}")]
    InvalidParameter {
        /// Which parameter.
        name: &'static str,
        /// The offending value.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// A frequency of the grid is negative or not finite.
    #[error("frequency line {index} is {value} Hz; frequencies must be finite and ≥ 0")]
    InvalidFrequency {
        /// Index in the grid.
        index: usize,
        /// The offending value, Hz.
        value: f64,
    },
    /// A mode's speed law (with its bearing stiffness change and whirl split) gives a non-positive
    /// frequency or a negative loss factor at the requested speed.
    #[error("mode {mode} at {speed}: {what} = {value} (speed law out of range; check kf, keta, kk, split)")]
    SpeedLaw {
        /// Index of the mode.
        mode: usize,
        /// Spindle speed.
        speed: Speed,
        /// `frequency` or `loss factor`.
        what: &'static str,
        /// The resulting value.
        value: f64,
    },
}

/// The properties an Euler–Bernoulli beam needs of a material: E and ρ.
fn check_material(m: &Material) -> Result<(), EbError> {
    positive("E", m.youngs_modulus)?;
    positive("rho", m.density)
}

fn positive(name: &'static str, value: f64) -> Result<(), EbError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(EbError::InvalidParameter { name, value, requirement: "must be finite and > 0" })
    }
}

fn non_negative(name: &'static str, value: f64) -> Result<(), EbError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(EbError::InvalidParameter { name, value, requirement: "must be finite and ≥ 0" })
    }
}

/// Free length of a solid fixed-free steel-like beam of diameter `d_m` whose first mode is at `f_hz`
/// (Eq. 5.6): `L = sqrt(1.87510407² d / (2π f) · sqrt(E / (16ρ)))`.
pub fn free_length(f_hz: f64, d_m: f64, material: &Material) -> Result<f64, EbError> {
    positive("f_hz", f_hz)?;
    positive("d_m", d_m)?;
    check_material(material)?;
    Ok((FIXED_FREE_ROOT_1 * FIXED_FREE_ROOT_1 * d_m / (TAU * f_hz)
        * (material.youngs_modulus / (16.0 * material.density)).sqrt())
    .sqrt())
}

/// A solid circular fixed-free Euler–Bernoulli beam with structural damping (complex modulus `E(1 + iη)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedFreeBeam {
    /// Free length, m.
    pub length_m: f64,
    /// Diameter, m.
    pub d_m: f64,
    /// Structural loss factor η (≥ 0).
    pub eta: f64,
    /// Material.
    pub material: Material,
}

impl FixedFreeBeam {
    /// Checks the parameters.
    pub fn new(length_m: f64, d_m: f64, eta: f64, material: Material) -> Result<Self, EbError> {
        positive("length_m", length_m)?;
        positive("d_m", d_m)?;
        non_negative("eta", eta)?;
        check_material(&material)?;
        Ok(FixedFreeBeam { length_m, d_m, eta, material })
    }

    /// The beam of Eq. 5.6 whose first mode is at `f_hz`.
    pub fn equivalent(f_hz: f64, d_m: f64, eta: f64, material: Material) -> Result<Self, EbError> {
        let length_m = free_length(f_hz, d_m, &material)?;
        Self::new(length_m, d_m, eta, material)
    }

    /// Second moment of area `π d⁴ / 64`, m⁴.
    pub fn second_moment(&self) -> f64 {
        PI * self.d_m.powi(4) / 64.0
    }

    /// Cross-section area `π d² / 4`, m².
    pub fn area(&self) -> f64 {
        PI * self.d_m * self.d_m / 4.0
    }

    /// Complex bending stiffness `E I (1 + iη)`, N m².
    pub fn ei_complex(&self) -> Complex64 {
        Complex64::new(1.0, self.eta) * (self.material.youngs_modulus * self.second_moment())
    }

    /// Free-end receptance `[[H, L], [N, P]]` at angular frequency `omega` (rad/s, ≥ 0), Eqs. 5.5, 5.10,
    /// 5.11 with the fixed-free denominator.
    ///
    /// With `x = λL`, `λ⁴ = ω² ρA / (EI(1 + iη))`, `D = 1 + cos x cosh x`:
    /// `H = (sin x cosh x − cos x sinh x) / (λ³ EI* D)`, `L = N = sin x sinh x / (λ² EI* D)`,
    /// `P = (sin x cosh x + cos x sinh x) / (λ EI* D)`. For `|x| ≥ 1` numerator and denominator are divided by
    /// `cosh x` (written with `e^{−x}`, so no overflow at any `λL`); below, power series give the static
    /// limits without cancellation.
    pub fn tip_receptance(&self, omega: f64) -> Receptance {
        self.tip().at(omega)
    }

    /// The constants of [`FixedFreeBeam::tip_receptance`], for a sweep over frequency.
    pub fn tip(&self) -> TipReceptance {
        let ei = self.ei_complex();
        // Principal fourth root: Re k > 0, small negative Im k for η > 0; λ = √ω k.
        let k = (Complex64::from(self.material.density * self.area()) / ei).powf(0.25);
        TipReceptance { ei, len: self.length_m, k, inv_k: k.inv() }
    }
}

/// A [`FixedFreeBeam`]'s free-end receptance with what does not depend on ω computed once:
/// `λ = √ω k`, `k = (ρA / EI*)^{1/4}`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TipReceptance {
    ei: Complex64,
    len: f64,
    k: Complex64,
    inv_k: Complex64,
}

impl TipReceptance {
    /// The receptance at angular frequency `omega` (rad/s, ≥ 0); see
    /// [`FixedFreeBeam::tip_receptance`].
    pub fn at(&self, omega: f64) -> Receptance {
        let (ei, len) = (self.ei, self.len);
        let root = omega.sqrt();
        let lam = self.k * root;
        let x = lam * len;
        // |x|² against the limit squared (1): no hypot per line.
        if x.norm_sqr() < SERIES_LIMIT * SERIES_LIMIT {
            let (gh, gl, gp, d) = series(x);
            let inv = Complex64::from(1.0) / (ei * d);
            return Receptance::new(gh * len.powi(3) * inv, gl * len * len * inv, gl * len * len * inv, gp * len * inv);
        }
        // x = a + ib: sin x = sin a cosh b + i cos a sinh b, cos x = cos a cosh b − i sin a sinh b,
        // e = e^{−x} = e^{−a}(cos b − i sin b); cosh x = (1 + e²)/(2e), sinh x = (1 − e²)/(2e).
        let (a, b) = (x.re, x.im);
        let (sa, ca) = a.sin_cos();
        let (sb, cb) = b.sin_cos();
        // sinh and cosh from one e^b − 1 (exact for small b, where e^b ± e^−b would cancel).
        let m = b.exp_m1();
        let ratio = m / (1.0 + m);
        let (shb, chb) = (0.5 * (m + ratio), 1.0 + 0.5 * m * ratio);
        let s = Complex64::new(sa * chb, ca * shb);
        let c = Complex64::new(ca * chb, -sa * shb);
        let ea = (-a).exp();
        let e = Complex64::new(ea * cb, -ea * sb);
        let e2 = e * e;
        let one = Complex64::from(1.0);
        let inv_sum = (one + e2).inv();
        let tanh = (one - e2) * inv_sum;
        let sech = e * 2.0 * inv_sum;
        // 1/(λ D'), D' = EI*(sech x + cos x) = EI* D / cosh x; 1/λ = k⁻¹/√ω.
        let inv = (lam * ei * (sech + c)).inv();
        let inv_lam = self.inv_k / root;
        let l = s * tanh * inv * inv_lam;
        Receptance::new((s - c * tanh) * inv * inv_lam * inv_lam, l, l, (s + c * tanh) * inv)
    }
}

/// Power series of the reduced numerators `(sin x cosh x − cos x sinh x)/x³`, `sin x sinh x / x²`,
/// `(sin x cosh x + cos x sinh x)/x` and of `D = 1 + cos x cosh x`, for small complex `x`.
///
/// Uses `sin x cosh x ± i cos x sinh x = sin((1 ± i)x)` and `cos x cosh x − i sin x sinh x = cos((1 + i)x)`
/// written as series in `x` with coefficients `(1 + i)^k`.
fn series(x: Complex64) -> (Complex64, Complex64, Complex64, Complex64) {
    let one_i = Complex64::new(1.0, 1.0);
    let x2 = x * x;
    let mut gh = Complex64::from(0.0);
    let mut gl = Complex64::from(0.0);
    let mut gp = Complex64::from(0.0);
    let mut d = Complex64::from(1.0); // the 1 of 1 + cos x cosh x
    // term_k = x^{2k} / (2k)! · (1+i)^{2k} (even) and x^{2k} / (2k+1)! · (1+i)^{2k+1} (odd, divided by x).
    let mut xpow = Complex64::from(1.0); // x^{2k}
    let mut xshift = Complex64::from(0.0); // x^{2k-2} (0 for k = 0, where its coefficients vanish)
    let mut pow_even = Complex64::from(1.0); // (1+i)^{2k}
    let mut fact_even = 1.0; // (2k)!
    for k in 0..24 {
        let kk = k as f64;
        let pow_odd = pow_even * one_i;
        let fact_odd = fact_even * (2.0 * kk + 1.0);
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        // sin((1+i)x) = Σ (−1)^k ((1+i)x)^{2k+1}/(2k+1)!: real part → sin cosh, imaginary part → cos sinh.
        let odd = sign / fact_odd;
        let a = pow_odd.re * odd; // coefficient of x^{2k+1} in sin x cosh x
        let b = pow_odd.im * odd; // coefficient of x^{2k+1} in cos x sinh x
        // cos((1+i)x) = Σ (−1)^k ((1+i)x)^{2k}/(2k)!: real → cos cosh, −imag → sin sinh.
        let even = sign / fact_even;
        let cc = pow_even.re * even;
        let ss = -pow_even.im * even;
        // gh = Σ (a − b) x^{2k+1} / x³: the k = 0 term vanishes (a = b = 1).
        gh += xshift * (a - b);
        gp += xpow * (a + b);
        gl += xshift * ss;
        d += xpow * cc;
        xshift = xpow;
        xpow *= x2;
        pow_even = pow_odd * one_i;
        fact_even = fact_odd * (2.0 * kk + 2.0);
    }
    (gh, gl, gp, d)
}

/// Free-end receptances of one spindle direction at `speed`: the sum over the equivalent modes of the
/// fixed-free beam receptances (Eqs. 5.5–5.7, 5.10–5.12), each mode at `speed` by its speed law
/// about `reference`, on the grid `freqs_hz`. In `whirl` (none: without gyroscopic coupling)
/// each mode with a gyroscopic coefficient is taken in that whirl's coordinate, `F = P − iQ`
/// or `B = P + iQ` of [`spindle_gyroscopic`] with the direction its own partner (an isotropic
/// spindle).
pub fn spindle_receptance(
    modes: &[SpindleMode],
    material: &Material,
    speed: Speed,
    reference: Speed,
    freqs_hz: &[f64],
    whirl: Option<Whirl>,
) -> Result<ReceptanceFrf, EbError> {
    let s = match whirl {
        None => return spindle_still(modes, material, speed, reference, freqs_hz),
        Some(Whirl::Forward) => Complex64::new(0.0, -1.0),
        Some(Whirl::Backward) => Complex64::new(0.0, 1.0),
    };
    let (p, q) = spindle_gyroscopic(modes, modes, material, speed, reference, freqs_hz)?;
    let lines = p.lines.iter().zip(&q.lines).map(|(p, q)| *p + *q * s).collect();
    Ok(ReceptanceFrf { freqs_hz: freqs_hz.to_vec(), lines })
}

/// The spindle without gyroscopic coupling: the sum of the equivalent beams at `speed`.
fn spindle_still(
    modes: &[SpindleMode],
    material: &Material,
    speed: Speed,
    reference: Speed,
    freqs_hz: &[f64],
) -> Result<ReceptanceFrf, EbError> {
    let beams = still_beams(modes, material, speed, reference, freqs_hz)?;
    let lines = freqs_hz
        .iter()
        .map(|&f| {
            let w = TAU * f;
            beams.iter().fold(Receptance::ZERO, |acc, (b, _)| acc + b.at(w))
        })
        .collect();
    Ok(ReceptanceFrf { freqs_hz: freqs_hz.to_vec(), lines })
}

/// An equivalent beam's tip receptance with the `(frequency Hz, diameter m, loss factor)` it
/// was made from.
type StillBeam = (TipReceptance, (f64, f64, f64));

/// Each mode's equivalent beam at `speed` with its frequency, diameter and loss factor there,
/// the speed and the grid checked.
fn still_beams(
    modes: &[SpindleMode],
    material: &Material,
    speed: Speed,
    reference: Speed,
    freqs_hz: &[f64],
) -> Result<Vec<StillBeam>, EbError> {
    check_material(material)?;
    if !speed.rad_s().is_finite() {
        return Err(EbError::InvalidParameter { name: "speed", value: speed.rpm(), requirement: "must be finite" });
    }
    if !speed.is_rest() {
        positive("ref_speed", reference.rpm())?;
    }
    for (index, &f) in freqs_hz.iter().enumerate() {
        if !(f.is_finite() && f >= 0.0) {
            return Err(EbError::InvalidFrequency { index, value: f });
        }
    }
    let mut beams = Vec::with_capacity(modes.len());
    for (i, m) in modes.iter().enumerate() {
        let (f, d, eta) = m.beam_at(speed, reference);
        if !(f.is_finite() && f > 0.0) {
            return Err(EbError::SpeedLaw { mode: i, speed, what: "frequency", value: f });
        }
        if !(eta.is_finite() && eta >= 0.0) {
            return Err(EbError::SpeedLaw { mode: i, speed, what: "loss factor", value: eta });
        }
        beams.push((FixedFreeBeam::equivalent(f, d, eta, *material)?.tip(), (f, d, eta)));
    }
    Ok(beams)
}

/// The in-plane and cross-plane blocks `(P, Q)` at the spindle nose of one direction whose
/// modes are `modes`, across from the direction whose modes are `partner` (the same list for
/// an isotropic spindle). Mode `i` with a gyroscopic coefficient `g` and its partner's mode `i`
/// are one rotor mode in two planes, `ẍ + ω_x²(1+iη_x) x + G ẏ = F/m`, `ÿ + ω_y²(1+iη_y) y − G ẋ
/// = 0`, `G = gΩ`: its first-mode term `A/(ω_x²(1+iη_x) − ω²)` becomes `A (ω_y²(1+iη_y) − ω²)/Δ`
/// in `P` and `−iGω A/Δ` in `Q`, `Δ = (ω_x²(1+iη_x) − ω²)(ω_y²(1+iη_y) − ω²) − G²ω²`, whose
/// roots are the forward and backward whirls (`ω_n(√(1+e²) ± e)`, `e = G/(2ω_n)`, when `ω_x =
/// ω_y`). The equivalent beam's higher modes, which only round out its static compliance, stay
/// as they are. `A` is the beam's residue at its first mode.
pub fn spindle_gyroscopic(
    modes: &[SpindleMode],
    partner: &[SpindleMode],
    material: &Material,
    speed: Speed,
    reference: Speed,
    freqs_hz: &[f64],
) -> Result<(ReceptanceFrf, ReceptanceFrf), EbError> {
    let beams = still_beams(modes, material, speed, reference, freqs_hz)?;
    // Per gyroscopic mode: its residue, its pole and its partner's (with damping), and G.
    let mut pairs: Vec<(Receptance, Complex64, Complex64, f64)> = Vec::new();
    for (i, (m, (_, (f, d, eta)))) in modes.iter().zip(&beams).enumerate() {
        if m.gyro == 0.0 || speed.is_rest() {
            continue;
        }
        let (fp, etap) = partner.get(i).map_or((*f, *eta), |pm| {
            let (fp, _, etap) = pm.beam_at(speed, reference);
            (fp, etap)
        });
        // At its first natural frequency a nearly undamped beam is its first mode,
        // A/(iη ω₁²), to a part in 1e9.
        const PROBE: f64 = 1e-9;
        let w1 = TAU * f;
        let a =
            FixedFreeBeam::equivalent(*f, *d, PROBE, *material)?.tip().at(w1) * Complex64::new(0.0, PROBE * w1 * w1);
        let pole = |f: f64, eta: f64| Complex64::new(1.0, eta) * (TAU * f).powi(2);
        pairs.push((a, pole(*f, *eta), pole(fp, etap), m.gyro * speed.rad_s()));
    }
    let (mut p, mut q) = (Vec::with_capacity(freqs_hz.len()), Vec::with_capacity(freqs_hz.len()));
    for &f in freqs_hz {
        let w = TAU * f;
        let w2 = w * w;
        let still = beams.iter().fold(Receptance::ZERO, |acc, (b, _)| acc + b.at(w));
        let (mut pl, mut ql) = (still, Receptance::ZERO);
        for (a, own, other, g) in &pairs {
            let (dx, dy) = (*own - w2, *other - w2);
            let delta = dx * dy - (g * w).powi(2);
            pl = pl + *a * (dy / delta - dx.inv());
            ql = ql + *a * (Complex64::new(0.0, -g * w) / delta);
        }
        p.push(pl);
        q.push(ql);
    }
    Ok((
        ReceptanceFrf { freqs_hz: freqs_hz.to_vec(), lines: p },
        ReceptanceFrf { freqs_hz: freqs_hz.to_vec(), lines: q },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use spindlelab_domain::SpeedLaw;

    fn rel(a: Complex64, b: Complex64) -> f64 {
        (a - b).norm() / b.norm()
    }

    /// The per-line form equals Eqs. 5.5, 5.10, 5.11 written out with complex sin, cos, sinh
    /// and cosh (where they do not overflow), from below the series switch to λL ≈ 30.
    #[test]
    fn tip_receptance_equals_the_textbook_formulas() {
        let beam = FixedFreeBeam::new(0.25, 0.06, 0.05, Material::STEEL).unwrap();
        let (ei, len) = (beam.ei_complex(), beam.length_m);
        let mut checked = 0;
        for k in 1..400 {
            let omega = 40.0 * k as f64 * k as f64;
            let lam = (Complex64::from(omega * omega * beam.material.density * beam.area()) / ei).powf(0.25);
            let x = lam * len;
            if x.norm() < SERIES_LIMIT {
                continue;
            }
            let d = 1.0 + x.cos() * x.cosh();
            let want = Receptance::new(
                (x.sin() * x.cosh() - x.cos() * x.sinh()) / (lam.powi(3) * ei * d),
                x.sin() * x.sinh() / (lam * lam * ei * d),
                x.sin() * x.sinh() / (lam * lam * ei * d),
                (x.sin() * x.cosh() + x.cos() * x.sinh()) / (lam * ei * d),
            );
            let got = beam.tip_receptance(omega);
            for (a, b) in [(got.h, want.h), (got.l, want.l), (got.n, want.n), (got.p, want.p)] {
                assert!(rel(a, b) < 1e-9, "omega {omega}: {a} vs {b}");
            }
            checked += 1;
        }
        assert!(checked > 300);
    }

    #[test]
    fn static_limits_match_cantilever_flexibility() {
        let beam = FixedFreeBeam::new(0.3, 0.05, 0.02, Material::STEEL).unwrap();
        let ei = beam.ei_complex();
        let l = beam.length_m;
        let h0 = Complex64::from(l.powi(3) / 3.0) / ei;
        let l0 = Complex64::from(l * l / 2.0) / ei;
        let p0 = Complex64::from(l) / ei;
        // Exactly static, and slightly above on both sides of the series / closed-form switch.
        let r = beam.tip_receptance(0.0);
        assert!(rel(r.h, h0) < 1e-14 && rel(r.l, l0) < 1e-14 && rel(r.n, l0) < 1e-14 && rel(r.p, p0) < 1e-14);
        let f1 = FIXED_FREE_ROOT_1.powi(2) / l.powi(2)
            * (beam.material.youngs_modulus * beam.second_moment() / (beam.material.density * beam.area())).sqrt();
        for frac in [1e-4, 1e-3] {
            let r = beam.tip_receptance(frac * f1);
            assert!(rel(r.h, h0) < 1e-5, "h at {frac}: {}", rel(r.h, h0));
            assert!(rel(r.l, l0) < 1e-5 && rel(r.p, p0) < 1e-5);
            assert!(r.h.re > 0.0 && r.l.re > 0.0 && r.p.re > 0.0);
        }
    }

    #[test]
    fn series_and_closed_form_agree_at_the_switch() {
        let beam = FixedFreeBeam::new(0.2, 0.04, 0.05, Material::STEEL).unwrap();
        // Find ω where |x| = 1 and compare just below (series) with just above (closed form).
        let ei = beam.ei_complex();
        let c = (Complex64::from(beam.material.density * beam.area()) / ei).norm().powf(0.25) * beam.length_m;
        let w = (1.0 / c).powi(2);
        let a = beam.tip_receptance(w * (1.0 - 1e-9));
        let b = beam.tip_receptance(w * (1.0 + 1e-9));
        assert!(rel(a.h, b.h) < 1e-8 && rel(a.l, b.l) < 1e-8 && rel(a.p, b.p) < 1e-8);
        // Direct evaluation with cosh at the same point (no overflow there) as an independent check.
        let lam = (Complex64::from(w * w * beam.material.density * beam.area()) / ei).powf(0.25);
        let x = lam * beam.length_m;
        let d = Complex64::from(1.0) + x.cos() * x.cosh();
        let h = (x.sin() * x.cosh() - x.cos() * x.sinh()) / (lam * lam * lam * ei * d);
        let p = (x.sin() * x.cosh() + x.cos() * x.sinh()) / (lam * ei * d);
        let l = x.sin() * x.sinh() / (lam * lam * ei * d);
        assert!(rel(a.h, h) < 1e-8 && rel(a.l, l) < 1e-8 && rel(a.p, p) < 1e-8);
    }

    #[test]
    fn free_length_puts_first_peak_at_mode_frequency() {
        let mat = Material::STEEL;
        for (f, d) in [(650.0, 0.12), (1800.0, 0.06), (4200.0, 0.03)] {
            let beam = FixedFreeBeam::equivalent(f, d, 0.01, mat).unwrap();
            // Eq. 5.6 inverts the fixed-free first-mode frequency.
            let fn1 = FIXED_FREE_ROOT_1.powi(2) / (TAU * beam.length_m.powi(2))
                * (mat.youngs_modulus * beam.second_moment() / (mat.density * beam.area())).sqrt();
            assert!((fn1 / f - 1.0).abs() < 1e-12);
            // Peak of |H| on a 0.1 Hz grid over ±20 %: within 0.05 % of f (η shifts it slightly).
            let mut best = (0.0, 0.0);
            let mut fq = 0.8 * f;
            while fq < 1.2 * f {
                let m = beam.tip_receptance(TAU * fq).h.norm();
                if m > best.1 {
                    best = (fq, m);
                }
                fq += 0.1;
            }
            assert!((best.0 / f - 1.0).abs() < 5e-4, "peak {} for {f}", best.0);
        }
    }

    #[test]
    fn cross_receptances_are_equal_and_stable_at_high_lambda_l() {
        let beam = FixedFreeBeam::equivalent(300.0, 0.1, 0.03, Material::STEEL).unwrap();
        for f in [10.0, 299.0, 1e3, 1e4, 1e5, 1e6, 1e8] {
            let r = beam.tip_receptance(TAU * f);
            assert_eq!(r.l, r.n);
            for v in [r.h, r.l, r.p] {
                assert!(v.re.is_finite() && v.im.is_finite(), "non-finite at {f} Hz: {r:?}");
            }
        }
        // Far above the first modes the damped beam behaves as a semi-infinite one: tanh x → 1, sech x → 0, so
        // H → (sin x − cos x)/(λ³ EI* cos x), which with damping averages to |H| ∝ ω^{-3/2}.
        let a = beam.tip_receptance(TAU * 1e7).h.norm();
        let b = beam.tip_receptance(TAU * 4e7).h.norm();
        assert!((a / b / 8.0 - 1.0).abs() < 0.05, "ratio {}", a / b);
    }

    #[test]
    fn undamped_limit_diverges_only_at_resonance() {
        let f = 1200.0;
        let undamped = FixedFreeBeam::equivalent(f, 0.05, 0.0, Material::STEEL).unwrap();
        let light = FixedFreeBeam::equivalent(f, 0.05, 1e-9, Material::STEEL).unwrap();
        let stat = undamped.tip_receptance(0.0).h.norm();
        assert!(light.tip_receptance(TAU * f).h.norm() > 1e6 * stat);
        assert!(undamped.tip_receptance(TAU * f).h.norm() > 1e6 * stat);
        for fr in [0.3, 0.7, 1.5, 3.0] {
            let a = undamped.tip_receptance(TAU * fr * f);
            let b = light.tip_receptance(TAU * fr * f);
            assert!(a.h.norm() < 20.0 * stat, "finite away from resonance");
            assert!(rel(b.h, a.h) < 1e-6 && a.h.im.abs() < 1e-12 * a.h.norm());
        }
    }

    #[test]
    fn spindle_sums_modes_and_follows_speed_laws() {
        let mat = Material::STEEL;
        let rpm = Speed::from_rpm;
        let mut m0 = SpindleMode::new(900.0, 0.09, 0.04);
        let m1 = SpindleMode::new(2500.0, 0.05, 0.03);
        let grid: Vec<f64> = (0..200).map(|i| 20.0 * i as f64).collect();
        let s = spindle_receptance(&[m0, m1], &mat, Speed::ZERO, rpm(10000.0), &grid, None).unwrap();
        let b0 = FixedFreeBeam::equivalent(900.0, 0.09, 0.04, mat).unwrap();
        let b1 = FixedFreeBeam::equivalent(2500.0, 0.05, 0.03, mat).unwrap();
        for (i, &f) in grid.iter().enumerate() {
            let want = b0.tip_receptance(TAU * f) + b1.tip_receptance(TAU * f);
            // Equal but for rounding: where the sweep's loop is inlined, sin and cos of the same
            // argument may come from one joint libm call, and near a resonance (D → 0) an ulp
            // there grows to ~1e-13.
            assert!((s.lines[i] - want).max_norm() <= 1e-12 * want.max_norm(), "{f} Hz: {:?} vs {want:?}", s.lines[i]);
        }
        m0.law = SpeedLaw { kf: 0.02, kd: -0.05 };
        let (f, eta) = m0.at_speed(rpm(20000.0), rpm(10000.0));
        assert!((f - 900.0 * 1.08).abs() < 1e-9 && (eta - 0.04 * 0.8).abs() < 1e-12);
        let fast = spindle_receptance(&[m0], &mat, rpm(20000.0), rpm(10000.0), &[f], None).unwrap();
        let want = FixedFreeBeam::equivalent(f, 0.09, eta, mat).unwrap().tip_receptance(TAU * f);
        assert_eq!(fast.lines[0], want);
        m0.law.kf = -2.0;
        assert!(matches!(
            spindle_receptance(&[m0], &mat, rpm(10000.0), rpm(10000.0), &grid, None),
            Err(EbError::SpeedLaw { mode: 0, .. })
        ));
        assert!(matches!(
            spindle_receptance(&[m1], &mat, Speed::ZERO, rpm(1.0), &[-1.0], None),
            Err(EbError::InvalidFrequency { index: 0, .. })
        ));
    }

    /// A bearing stiffness change keeps the modal mass: the frequency moves with √q and the
    /// static flexibility with 1/q. A whirl moves the mode's first-mode term to its whirl
    /// frequency, forward above and backward below (their product the square of the mode's), and
    /// leaves the equivalent beam's higher modes where they are; at rest, or without a
    /// gyroscopic coefficient, neither whirl moves anything.
    #[test]
    fn bearing_change_keeps_the_mass_and_a_whirl_moves_only_the_mode() {
        let mat = Material::STEEL;
        let rpm = Speed::from_rpm;
        let mode = SpindleMode::from_modal(800.0, 1.5e8, 0.01, &mat, SpeedLaw::NONE);
        let soft = SpindleMode { stiffness_change: -0.19, ..mode };
        let (f, d, _) = soft.beam_at(rpm(10000.0), rpm(10000.0));
        assert!((f - 800.0 * 0.9).abs() < 1e-9, "{f}");
        // A law that bends: at twice the reference speed the change is kk 2^p.
        let bent = SpindleMode { stiffness_change: -0.01, stiffness_exponent: 4.0, ..mode };
        let (f2, _, _) = bent.beam_at(rpm(20000.0), rpm(10000.0));
        assert!((f2 - 800.0 * (1.0f64 - 0.01 * 16.0).sqrt()).abs() < 1e-9, "{f2}");
        assert_eq!(bent.beam_at(Speed::ZERO, rpm(10000.0)).0, 800.0);
        let at = |f: f64, d: f64| FixedFreeBeam::equivalent(f, d, 0.0, mat).unwrap().tip_receptance(0.0).h.re;
        assert!((at(800.0, mode.diameter) / at(f, d) - 0.81).abs() < 1e-9);
        let gyro = SpindleMode { gyro: 0.4, ..soft };
        for w in [Whirl::Forward, Whirl::Backward] {
            assert_eq!(gyro.whirl_at(Speed::ZERO, rpm(10000.0), w), 800.0);
            assert_eq!(soft.whirl_at(rpm(20000.0), rpm(10000.0), w), soft.beam_at(rpm(20000.0), rpm(10000.0)).0);
        }
        let f0 = 800.0 * (1.0 - 0.19 * 4.0f64).sqrt();
        let (ff, fb) = (
            gyro.whirl_at(rpm(20000.0), rpm(10000.0), Whirl::Forward),
            gyro.whirl_at(rpm(20000.0), rpm(10000.0), Whirl::Backward),
        );
        assert!(ff > f0 && fb < f0 && (ff * fb - f0 * f0).abs() < 1e-6 * f0 * f0, "{ff} {fb} {f0}");
        // The receptance in each whirl peaks at the whirl's frequency; far above, by the beam's
        // second mode (6.27 f), it is the still beam's.
        let grid: Vec<f64> = (1..=20000).map(|k| 0.1 * k as f64).collect();
        let still = spindle_receptance(&[gyro], &mat, rpm(20000.0), rpm(10000.0), &grid, None).unwrap();
        for (w, want) in [(Whirl::Forward, ff), (Whirl::Backward, fb)] {
            let r = spindle_receptance(&[gyro], &mat, rpm(20000.0), rpm(10000.0), &grid, Some(w)).unwrap();
            let peak =
                grid[(0..grid.len()).max_by(|&i, &j| r.lines[i].h.norm().total_cmp(&r.lines[j].h.norm())).unwrap()];
            assert!((peak - want).abs() < 0.5, "{w:?}: peak at {peak} Hz, whirl at {want} Hz");
            let far = [6.27 * f0];
            let (a, b) = (
                spindle_receptance(&[gyro], &mat, rpm(20000.0), rpm(10000.0), &far, Some(w)).unwrap(),
                spindle_receptance(&[gyro], &mat, rpm(20000.0), rpm(10000.0), &far, None).unwrap(),
            );
            // Only the first-mode term differs there: a few per cent of the still response.
            assert!((a.lines[0].h - b.lines[0].h).norm() < 0.05 * b.lines[0].h.norm());
        }
        assert!(still.lines.iter().all(|l| l.h.is_finite()));
    }

    /// The whirls of an isotropic mode with gyroscopic coupling, against the two-plane equations
    /// solved directly: `m(ẍ + ω_n² x) + gmΩ ẏ = F`, `m(ÿ + ω_n² y) − gmΩ ẋ = 0`, whose undamped
    /// `x/F` has its poles where `det [[ω_n² − ω², iωgΩ], [−iωgΩ, ω_n² − ω²]] = 0`, found here by
    /// bisection on the determinant (not by the closed form `ω_n (√(1+e²) ∓ e)`).
    #[test]
    fn whirl_frequencies_are_the_poles_of_the_gyroscopic_pair() {
        use spindlelab_domain::entity::whirl_frequency;
        for (f_n, g, rpm) in
            [(600.0, 0.22, 15000.0), (600.0, 0.22, 30000.0), (1200.0, 1.0, 24000.0), (300.0, 2.0, 40000.0)]
        {
            let (wn, spin) = (TAU * f_n, Speed::from_rpm(rpm).rad_s());
            let det = |w: f64| (wn * wn - w * w).powi(2) - (w * g * spin).powi(2);
            let root = |mut lo: f64, mut hi: f64| {
                for _ in 0..200 {
                    let mid = 0.5 * (lo + hi);
                    if det(lo).signum() == det(mid).signum() { lo = mid } else { hi = mid }
                }
                0.5 * (lo + hi) / TAU
            };
            // One pole below ω_n and one above it.
            let (backward, forward) = (root(1e-3 * wn, wn), root(wn, 10.0 * wn));
            let n = Speed::from_rpm(rpm);
            let got = (whirl_frequency(f_n, g, n, Whirl::Backward), whirl_frequency(f_n, g, n, Whirl::Forward));
            assert!(
                (got.0 / backward - 1.0).abs() < 1e-9 && (got.1 / forward - 1.0).abs() < 1e-9,
                "{got:?} {backward} {forward}"
            );
            // The closed form of the issue: e = gΩ/(2ω_n).
            let e = g * spin / (2.0 * wn);
            assert!((got.1 / (f_n * ((1.0 + e * e).sqrt() + e)) - 1.0).abs() < 1e-12);
        }
    }
}
