//! The UFF reader against files written by an independent writer (pyuff), checked field by
//! field against their `expected.json`, plus a hand-written file of ours whose other datasets
//! must be skipped and listed. pyuff's files are not in the repository: they are read from
//! `../shared/data/uff/` beside the checkout (described in the README there); without them the
//! tests that need them say so and pass, except under CI (`CI` set), where their absence fails.

use spindlelab_engine::formats::uff::{self, Abscissa};
use spindlelab_engine::formats::{self, FileFormat, FormatError, FrfSelect, Skipped};
use std::path::{Path, PathBuf};

/// Our own UFF file `name`.
fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/uff").join(name)
}

/// The file `rel` of `../shared` beside the checkout, or `None` when it is not there: the test
/// says on stderr that `what` is skipped and returns. Under CI its absence fails the test.
fn shared(rel: &str, what: &str) -> Option<PathBuf> {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared")).join(rel);
    if path.exists() {
        return Some(path);
    }
    assert!(std::env::var_os("CI").is_none(), "CI needs {} (../shared beside the checkout)", path.display());
    eprintln!("no {}: {what} is skipped", path.display());
    None
}

/// pyuff's file `name` in `../shared/data/uff/`, or `None` (said) when it is not there.
fn pyuff(name: &str, what: &str) -> Option<PathBuf> {
    shared(&format!("data/uff/{name}"), what)
}

/// ASCII values carry 12 significant digits (README: compare to about 1e-10); binary
/// values are the exact doubles.
fn assert_close(found: f64, expected: f64, binary: bool, what: &str) {
    if binary {
        assert_eq!(found, expected, "{what}");
    } else {
        let tol = 1e-10 * expected.abs().max(found.abs());
        assert!((found - expected).abs() <= tol, "{what}: {found} vs {expected}");
    }
}

#[test]
fn every_expected_field_of_the_pyuff_fixtures() {
    let what = "the check of every field against pyuff";
    let Some(expected) = pyuff("expected.json", what) else { return };
    let expected: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(expected).unwrap()).unwrap();
    let files = expected.as_object().unwrap();
    assert_eq!(files.len(), 3);
    for (name, sets) in files {
        let Some(path) = pyuff(name, what) else { return };
        let bytes = std::fs::read(path).unwrap();
        let file = uff::parse(&bytes, name).unwrap_or_else(|e| panic!("{e}"));
        let sets = sets.as_array().unwrap();
        assert_eq!(file.datasets.len(), sets.len(), "{name}");
        assert!(file.skipped.is_empty(), "{name}");
        for (k, (d, e)) in file.datasets.iter().zip(sets).enumerate() {
            let what = |field: &str| format!("{name} dataset {} {field}", k + 1);
            let binary = name.contains("binary");
            assert_eq!(d.binary, binary, "{}", what("binary"));
            assert_eq!(i64::from(d.function_type), e["func_type"].as_i64().unwrap(), "{}", what("func_type"));
            assert_eq!(i64::from(d.response.direction), e["rsp_dir"].as_i64().unwrap(), "{}", what("rsp_dir"));
            assert_eq!(d.len() as u64, e["num_pts"].as_u64().unwrap(), "{}", what("num_pts"));
            assert_close(d.abscissa_at(0), e["x_first"].as_f64().unwrap(), binary, &what("x_first"));
            assert_close(d.abscissa_at(d.len() - 1), e["x_last"].as_f64().unwrap(), binary, &what("x_last"));
            let at = d.value_at(440);
            let want = e["data_at_index_440"].as_array().unwrap();
            assert_close(at.re, want[0].as_f64().unwrap(), binary, &what("re at 440"));
            assert_close(at.im, want[1].as_f64().unwrap(), binary, &what("im at 440"));
            // A magnitude is computed (hypot), not stored: libm implementations may differ in
            // the last bit, so it is compared to 1e-15 even for binary data.
            let max_abs = (0..d.len()).map(|i| d.value_at(i).norm()).fold(0.0, f64::max);
            let want = e["max_abs"].as_f64().unwrap();
            let tol = if binary { 1e-15 } else { 1e-10 } * want;
            assert!((max_abs - want).abs() <= tol, "{}: {max_abs} vs {want}", what("max_abs"));
            assert_eq!(d.id[0], e["id1"].as_str().unwrap(), "{}", what("id1"));
        }
    }
}

#[test]
fn fixtures_map_to_typed_values_in_si() {
    let what = "the typed values of pyuff's files";
    let Some(x_file) = pyuff("frf_x_ascii.uff", what) else { return };
    let Some(path) = pyuff("frf_xy_binary.uff", what) else { return };
    let Some(force_file) = pyuff("force_time_ascii.uff", what) else { return };
    let x = formats::read_frf(&x_file, FileFormat::Uff, &FrfSelect::default()).unwrap();
    assert!(x.notes.is_empty());
    let frf = x.value;
    assert_eq!((frf.unit.symbol.as_str(), frf.direction.as_deref()), ("m/N", Some("x")));
    assert_eq!((frf.freq_hz.len(), frf.freq_hz[0], frf.freq_hz[1000]), (1001, 0.0, 2000.0));
    assert!(frf.coherence.is_none() && frf.speed.is_none());

    // Two FRFs in one binary file: either is chosen by direction or by position, never guessed.
    let y = |select: FrfSelect| formats::read_frf(&path, FileFormat::Uff, &select).unwrap().value;
    let by_dir = y(FrfSelect { direction: Some("y".into()), ..Default::default() });
    let by_index = y(FrfSelect { dataset: Some(2), ..Default::default() });
    assert_eq!(by_dir, by_index);
    assert_eq!(by_dir.direction.as_deref(), Some("y"));
    assert_eq!(by_dir.values[440].re, 8.756411605840658e-07);
    let e = formats::read_frf(&path, FileFormat::Uff, &FrfSelect::default()).unwrap_err();
    assert!(e.to_string().contains("`direction` or `dataset`"), "{e}");
    let e =
        formats::read_frf(&path, FileFormat::Uff, &FrfSelect { dataset: Some(3), ..Default::default() }).unwrap_err();
    assert!(matches!(e, FormatError::Selection { .. }), "{e}");

    let ts = formats::read_time_series(&force_file, FileFormat::Uff, None).unwrap().value;
    assert_eq!((ts.sample_rate, ts.t0, ts.len()), (100_000.0, 0.0, 2048));
    assert_eq!(ts.channels[0].name, "impact force");
    assert_eq!(ts.channels[0].unit.symbol, "N");
    assert_eq!(ts.channels[0].samples.iter().fold(0.0f64, |m, v| m.max(v.abs())), 400.0);
    // A time file asked for an FRF says what it holds.
    let e = formats::read_frf(&force_file, FileFormat::Uff, &FrfSelect::default()).unwrap_err();
    assert!(e.to_string().contains("a time response"), "{e}");
    assert_eq!(FileFormat::detect(&path).unwrap(), FileFormat::Uff);
}

#[test]
fn other_datasets_before_a_58_are_skipped_and_listed() {
    let path = data("skip_then_frf.uff");
    let file = uff::parse(&std::fs::read(&path).unwrap(), "skip_then_frf.uff").unwrap();
    assert_eq!(
        file.skipped,
        [Skipped { dataset: 151, line: 2 }, Skipped { dataset: 15, line: 11 }, Skipped { dataset: 164, line: 16 }]
    );
    assert_eq!(file.datasets.len(), 1);
    let d = &file.datasets[0];
    assert_eq!((d.line, d.function_type, d.response.direction, d.reference.direction), (22, 4, -3, -3));
    assert_eq!(d.abscissa, Abscissa::Even { min: 100.0, step: 50.0 });

    let read = formats::read_frf(&path, FileFormat::Uff, &FrfSelect::default()).unwrap();
    assert_eq!(read.notes.len(), 3);
    assert!(read.notes[1].contains("dataset 15 at line 11"), "{:?}", read.notes);
    let frf = read.value;
    // kHz to Hz, mm/N to m/N; response and reference both in -z: the signs cancel.
    assert_eq!(frf.freq_hz, [100e3, 150e3, 200e3]);
    assert_eq!(frf.unit.symbol, "m/N");
    assert_eq!(frf.direction.as_deref(), Some("z"));
    let expect = [(1.0, -2.0), (3.0, -4.0), (5.0, -6.0)];
    for (v, (re, im)) in frf.values.iter().zip(expect) {
        assert!((v.re - re * 1e-3).abs() < 1e-18 && (v.im - im * 1e-3).abs() < 1e-18, "{v}");
    }
}

#[test]
fn a_truncated_binary_file_is_reported_at_its_dataset() {
    let Some(path) = pyuff("frf_xy_binary.uff", "the truncated binary file") else { return };
    let bytes = std::fs::read(path).unwrap();
    let cut = &bytes[..bytes.len() - 5000];
    let e = uff::parse(cut, "cut.uff").unwrap_err();
    match &e {
        FormatError::Truncated { at, needed, available, .. } => {
            assert_eq!(at.line, 76, "{e}");
            assert_eq!(*needed, 1001 * 3 * 8);
            assert!(available < needed);
        }
        other => panic!("{other}"),
    }
    assert!(e.to_string().starts_with("cut.uff:76: truncated binary data"), "{e}");
}
