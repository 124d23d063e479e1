//! A physical effect for the diagnosis workflow: a point mass added at (or, negative,
//! removed from) the point where an FRF was measured, such as an accelerometer or a
//! clamped nut.

use spindlelab_plugin_sdk::*;

/// `H' = H / (1 − ω² m H)`: displacement `x = H (F + ω² m x)` when the mass's inertia force
/// `−m ẍ = ω² m x` acts on the structure beside the applied force `F`.
fn add_mass(call: &Call) -> Result<Outputs, String> {
    let mass = match (call.number_opt("mass"), call.sensor("sensor")) {
        (Some(m), None) => m,
        (None, Some(s)) => s.mass,
        _ => return Err("give `mass` or `sensor` (whose mass is added), one of them".into()),
    };
    let frf = call.frf("frf")?;
    if !mass.is_finite() {
        return Err(format!("parameter `mass`: {mass} is not a number of kilograms"));
    }
    let mut re = Vec::with_capacity(frf.re.len());
    let mut im = Vec::with_capacity(frf.im.len());
    for ((&f, &hr), &hi) in frf.freq_hz.iter().zip(&frf.re).zip(&frf.im) {
        let w = std::f64::consts::TAU * f;
        let a = w * w * mass;
        // (hr + i hi) / ((1 − a hr) − i a hi)
        let (dr, di) = (1.0 - a * hr, -a * hi);
        let den = dr * dr + di * di;
        if den == 0.0 {
            return Err(format!("the mass {mass} kg cancels the structure's stiffness at {f} Hz exactly"));
        }
        re.push((hr * dr + hi * di) / den);
        im.push((hi * dr - hr * di) / den);
    }
    if mass < 0.0 {
        call.warn(format!(
            "a negative mass ({} g) removes mass: the result is only as good as the measurement",
            mass * 1e3
        ));
    }
    Ok(Outputs::new().frf("frf", Frf { re, im, coherence: None, ..frf.clone() }))
}

plugin! {
    NodeKind::new(
        "effect.tip_mass",
        "A point mass added at the FRF's measurement point (negative: removed), H' = H/(1 − ω²mH).",
        add_mass,
    )
    .input(Port::new("frf", PortType::Frf, "direct receptance at the point (m/N)"))
    .output(Port::new("frf", PortType::Frf, "the receptance with the mass"))
    .param(Param::quantity("mass", "kg", "mass added at the point (negative removes it)").optional())
    .param(Param::sensor("sensor", "a sensor of the recipe mounted at the point: its mass is added").optional())
    // For the diagnosis: a mass at the measurement point the model lacks (a sensor heavier
    // than declared, a nut, a fixture), −50 g (less than modelled) to 100 g.
    .effect(
        Effect::new("tip_mass", "a point mass at the measurement point, H' = H/(1 − ω²mH); measured FRFs only")
            .free("mass", 0.0, -0.05, 0.1),
    ),
}
