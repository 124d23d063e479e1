//! Timing of the data-file layer: a 65,536-line FRF through UFF dataset 58 (ASCII write and
//! read) and a two-channel, 65,536-sample time series through CSV.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_engine::formats::{csv, uff};
use spindlelab_engine::value::{Channel, Frf, TimeSeries, UnitLabel};
use std::hint::black_box;

const LEN: usize = 65_536;

fn bench_formats(c: &mut Criterion) {
    // Built through the CSV reader, which is the one way in without naming the complex type.
    let mut rows = String::from("# units: m/N\n# direction: x\nfreq_hz,real,imag\n");
    for i in 0..LEN {
        let (f, w) = (i as f64 * 100.0e3 / (2 * LEN) as f64, i as f64 / 4000.0);
        let (re, im) = (1e7 * (1.0 - w * w), 1e6 * w);
        let d = re * re + im * im;
        rows.push_str(&format!("{f:e},{:e},{:e}\n", re / d, -im / d));
    }
    let frf: Frf = csv::read_frf(rows.as_bytes(), "bench.csv").expect("valid FRF");
    let mut text = String::new();
    uff::write_frf(&mut text, &frf, "");
    c.bench_function("uff58/write frf 65536", |b| {
        b.iter(|| {
            let mut out = String::with_capacity(text.len());
            uff::write_frf(&mut out, black_box(&frf), "");
            out
        })
    });
    c.bench_function("uff58/read frf 65536", |b| {
        b.iter(|| uff::parse(black_box(text.as_bytes()), "bench.uff").expect("valid file"))
    });

    let ts = TimeSeries {
        sample_rate: 100.0e3,
        t0: -1e-3,
        channels: ["force", "response"]
            .iter()
            .enumerate()
            .map(|(k, name)| Channel {
                name: name.to_string(),
                unit: UnitLabel::new(if k == 0 { "N" } else { "m" }),
                samples: (0..LEN).map(|i| ((i * (k + 1)) as f64 * 0.001).sin() * 1e-3).collect(),
            })
            .collect(),
    };
    let csv_text = csv::write_time_series(&ts);
    c.bench_function("csv/write time series 2x65536", |b| b.iter(|| csv::write_time_series(black_box(&ts))));
    c.bench_function("csv/read time series 2x65536", |b| {
        b.iter(|| csv::read_time_series(black_box(csv_text.as_bytes()), "bench.csv").expect("valid file"))
    });
}

criterion_group!(benches, bench_formats);
criterion_main!(benches);
