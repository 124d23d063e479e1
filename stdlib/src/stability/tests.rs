use super::*;
use num_complex::Complex64;

fn benchmark_model() -> ModalModel {
    ModalModel::new(vec![Mode { freq_hz: 922.0, damping_ratio: 0.011, modal_mass_kg: 0.03993 }], vec![]).unwrap()
}

fn benchmark_milling(immersion: f64) -> Milling {
    Milling::new(2, immersion, MillingDirection::Down, CuttingCoefficients::from_kt_kn(6e8, 2e8).unwrap()).unwrap()
}

#[test]
#[ignore]
fn timing() {
    let model = ModalModel::new(
        vec![Mode { freq_hz: 700.0, damping_ratio: 0.03, modal_mass_kg: 0.5 }],
        vec![Mode { freq_hz: 760.0, damping_ratio: 0.025, modal_mass_kg: 0.4 }],
    )
    .unwrap();
    let mill =
        Milling::new(4, 0.5, MillingDirection::Up, CuttingCoefficients::from_kt_kn(7e8, 2.1e8).unwrap()).unwrap();
    let t = std::time::Instant::now();
    let speeds: Vec<f64> = (0..20).map(|i| 4000.0 + 400.0 * i as f64).collect();
    let depths: Vec<f64> = (0..10).map(|i| 1e-3 * i as f64).collect();
    let map = sd_stability_map(&model, &mill, &speeds, &depths, &SdOptions::default()).unwrap();
    eprintln!("200 pts {:?} {}", t.elapsed(), map.spectral_radius.iter().filter(|r| **r < 1.0).count());
    let mill = benchmark_milling(1.0);
    let t = std::time::Instant::now();
    let speeds: Vec<f64> = (0..20).map(|i| 4000.0 + 400.0 * i as f64).collect();
    let map = sd_stability_map(&benchmark_model(), &mill, &speeds, &depths, &SdOptions::default()).unwrap();
    eprintln!("1dof 200 pts {:?} {}", t.elapsed(), map.spectral_radius.iter().filter(|r| **r < 1.0).count());
}

#[test]
#[ignore]
fn explore() {
    let model = benchmark_model();
    for imm in [1.0, 0.05] {
        let mill = benchmark_milling(imm);
        let freqs: Vec<f64> = (1..=40000).map(|i| i as f64 * 0.1).collect();
        let frf = model.receptance(&freqs).unwrap();
        let speeds: Vec<f64> = (0..=80).map(|i| 5000.0 + 250.0 * i as f64).collect();
        let z =
            zoa_lobes(&frf, &mill, &ZoaOptions { lobes: 30, speeds_rpm: speeds.clone(), keep_lobes: false }).unwrap();
        let max = if imm == 1.0 { 4e-3 } else { 10e-3 };
        let t = std::time::Instant::now();
        let sd = sd_depth_limits(&model, &mill, &speeds, max, &SdOptions::default()).unwrap();
        eprintln!("imm {imm} zoa min {} sd time {:?}", z.min_depth_m, t.elapsed());
        for (i, s) in speeds.iter().enumerate() {
            eprintln!(
                "{s} zoa {:.4} sd {:.4} {:?} {:.4} {}",
                z.limit.depth_m[i] * 1e3,
                sd[i].depth_m * 1e3,
                sd[i].kind,
                sd[i].multiplier,
                sd[i].restabilises
            );
        }
    }
    for m in [10, 20, 40, 80, 160] {
        let opts = SdOptions { steps: m, ..SdOptions::default() };
        let a = sd_depth_limit(&model, &benchmark_milling(1.0), 10000.0, 4e-3, &opts).unwrap();
        let b = sd_depth_limit(&model, &benchmark_milling(0.05), 10000.0, 10e-3, &opts).unwrap();
        eprintln!("m {m}: {:.6e} {:?}  {:.6e} {:?}", a.depth_m, a.kind, b.depth_m, b.kind);
    }
}
