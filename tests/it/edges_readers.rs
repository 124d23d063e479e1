//! Readers and globs at their limits: a header of hundreds of thousands of columns, a data file
//! of one enormous line, an FRF in the wrong unit, a UFF file of a hundred thousand datasets and
//! globs that would walk the whole disk. Each ends in a value or a short error that names the
//! place and what to do (exit code 2 through the binary), never a panic, a hang or an
//! allocation the file's length does not vouch for.

use spindlelab::engine::formats::{self, FileFormat, FrfSelect};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::Path;

// ---------------------------------------------------------------- the binary

use crate::common::binary::{no_panic, run_in, text};

/// Runs `args` in `dir` and expects bad input: exit code 2 and no panic; returns what it said.
fn refused(dir: &Path, args: &[&str]) -> String {
    let o = run_in(dir, args);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    text(&o)
}

fn recipe(dir: &Path, body: &str) {
    std::fs::write(dir.join("r.yaml"), format!("spindlelab: 1\nname: edges\n{body}")).unwrap();
}

// ---------------------------------------------------------------- allocation, per thread

/// The system allocator, counting the bytes each thread has live and the most it had at once.
struct Counting;

thread_local! {
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

fn count(bytes: isize) {
    let _ = LIVE.try_with(|live| {
        let now = live.get() + bytes;
        live.set(now);
        let _ = PEAK.try_with(|peak| peak.set(peak.get().max(now)));
    });
}

// SAFETY: every call is passed to `System` unchanged; the counters only add.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as the caller's contract.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            count(layout.size() as isize);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as the caller's contract.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            count(layout.size() as isize);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as the caller's contract.
        unsafe { System.dealloc(ptr, layout) };
        count(-(layout.size() as isize));
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as the caller's contract.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            // The old block and the new one are both held while it is copied.
            count(new_size as isize);
            count(-(layout.size() as isize));
        }
        p
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

/// What `f` returns, and the most bytes it held allocated at once on this thread.
fn peak_of<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = LIVE.with(Cell::get);
    PEAK.with(|p| p.set(base));
    let out = f();
    (out, usize::try_from(PEAK.with(Cell::get) - base).unwrap_or(0))
}

const MIB: usize = 1024 * 1024;

/// A CSV file of one line of 64 MiB, in each form a spreadsheet could give it, is refused by
/// its header holding the file once: the old reader gathered every cell (16 bytes each, 8 times
/// the file) and a spreadsheet's copy of the whole file before it looked at the header.
#[test]
fn a_one_line_csv_of_64_mib_is_refused_holding_the_file_once() {
    let dir = tempfile::tempdir().unwrap();
    for (name, cell, sep) in [("plain.csv", "a", ","), ("upper.csv", "A", ","), ("semicolons.csv", "a", ";")] {
        let path = dir.path().join(name);
        let line = format!("{cell}{sep}").repeat(32 * MIB);
        std::fs::write(&path, &line).unwrap();
        drop(line);
        let size = 64 * MIB;
        let (frf, peak) = peak_of(|| formats::read_frf(&path, FileFormat::Csv, &FrfSelect::default()));
        let e = frf.unwrap_err().to_string();
        assert!(e.contains(&format!("{name}:1:")) && e.contains("the header row has 33554433 columns"), "{e}");
        assert!(peak < size + size / 8, "{name}: {} MiB held for a file of 64 MiB", peak / MIB);
        let (ts, peak) = peak_of(|| formats::read_time_series(&path, FileFormat::Csv, None));
        assert!(ts.is_err());
        assert!(peak < size + size / 8, "{name}: {} MiB held for a file of 64 MiB", peak / MIB);
    }
    // One enormous data row after a good header: ragged, counted no further than the cap.
    let path = dir.path().join("row.csv");
    std::fs::write(&path, format!("freq_hz;real;imag\n{}", "1,5;".repeat(16 * MIB))).unwrap();
    let (frf, peak) = peak_of(|| formats::read_frf(&path, FileFormat::Csv, &FrfSelect::default()));
    let e = frf.unwrap_err().to_string();
    assert!(e.contains("row.csv:2: ragged row: more than 4096 values, expected 3"), "{e}");
    assert!(peak < 64 * MIB + 8 * MIB, "{} MiB held for a file of 64 MiB", peak / MIB);
}

/// Samples are reserved for the rows the file's length can hold, not for its line count per
/// channel: a header of 4096 channels over four million one-cell rows.
#[test]
fn sample_vectors_are_sized_by_what_the_file_can_hold() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tall.csv");
    let names: Vec<String> = (0..4096).map(|i| format!("c{i}")).collect();
    std::fs::write(&path, format!("# sample_rate: 1 kHz\n{}\n{}", names.join(","), "1\n".repeat(4 * MIB))).unwrap();
    let (ts, peak) = peak_of(|| formats::read_time_series(&path, FileFormat::Csv, None));
    assert!(ts.unwrap_err().to_string().contains("ragged row: 1 values, expected 4096"));
    // The file (8 MiB) and at most four times its length in samples.
    assert!(peak < 5 * 9 * MIB, "{} MiB held for a file of 8 MiB", peak / MIB);
}

// ---------------------------------------------------------------- through the binary

#[test]
fn a_time_series_of_200k_channels_is_refused_with_its_line_and_count() {
    let tmp = tempfile::tempdir().unwrap();
    let names: Vec<String> = (0..200_000).map(|i| format!("c{i}")).collect();
    let ones = vec!["1"; 200_000].join(",");
    std::fs::write(tmp.path().join("wide.csv"), format!("# sample_rate: 1 kHz\n{}\n{ones}\n", names.join(",")))
        .unwrap();
    recipe(tmp.path(), "steps:\n  s:\n    kind: read.time_series\n    params: { file: wide.csv }\n");
    let said = refused(tmp.path(), &["run", "r.yaml", "-o", "o", "-q"]);
    assert!(said.contains("wide.csv:2:"), "{said}");
    assert!(said.contains("the header row has 200000 columns; at most 4096 channels are read"), "{said}");
    assert!(said.contains("split the recording into files of fewer channels"), "{said}");
    assert!(said.len() < 2000, "{} characters", said.len());
}

#[test]
fn frf_units_of_another_dimension_are_refused_where_they_are_written() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("kg.csv"), "# units: kg\nfreq_hz,real,imag\n100,1e-6,0\n").unwrap();
    std::fs::write(d.join("plain.csv"), "freq_hz,real,imag\n100,1e-6,0\n").unwrap();
    // In the file: refused when it is read, at the unit's line and column.
    recipe(d, "steps:\n  h:\n    kind: read.frf\n    params: { file: kg.csv }\n");
    let said = refused(d, &["run", "r.yaml", "-o", "o", "-q"]);
    assert!(said.contains("kg.csv:1:10: `# units:` `kg` is a mass (kg), not the unit of an FRF"), "{said}");
    assert!(said.contains("a receptance, length per force (`m/N`"), "{said}");
    // In the recipe: refused before anything runs, at the parameter.
    for (unit, why) in [
        ("kg", "`kg` is a mass (kg), not the unit of an FRF"),
        ("\"N/m\"", "is a stiffness"),
        ("\"m^999999999999/N\"", "is not a unit"),
    ] {
        recipe(d, &format!("measurements:\n  tip:\n    files: plain.csv\n    units: {unit}\n"));
        let said = refused(d, &["check", "r.yaml"]);
        assert!(said.contains(why) && said.contains("the values of an FRF are a receptance"), "{unit}: {said}");
        assert!(said.contains("r.yaml:"), "{unit}: {said}");
        recipe(d, &format!("steps:\n  h:\n    kind: read.frf\n    params: {{ file: plain.csv, units: {unit} }}\n"));
        let said = refused(d, &["check", "r.yaml"]);
        assert!(said.contains(why), "{unit}: {said}");
    }
    // A receptance in another unit, a mobility and an accelerance are read.
    for unit in ["um/N", "\"m/s/N\"", "\"m/s^2/N\""] {
        recipe(d, &format!("measurements:\n  tip:\n    files: plain.csv\n    units: {unit}\n"));
        let o = run_in(d, &["check", "r.yaml"]);
        assert_eq!(o.status.code(), Some(0), "{unit}: {}", text(&o));
    }
}

#[test]
fn a_uff_file_of_100k_datasets_gives_a_short_error_and_a_few_notes() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let skipped = "    -1\n    15\n    1 0 0 0\n    -1\n".repeat(100_000);
    std::fs::write(d.join("none.uff"), &skipped).unwrap();
    recipe(d, "steps:\n  h:\n    kind: read.frf\n    params: { file: none.uff }\n");
    let said = refused(d, &["run", "r.yaml", "-o", "o", "-q"]);
    assert!(said.contains("no dataset 58 or 58b") && said.contains("… and 99992 more"), "{said}");
    assert!(said.len() < 2000, "{} characters", said.len());
    // One FRF among them: read, with eight notes and one that counts the rest.
    let frf = spindlelab::engine::value::Frf {
        freq_hz: vec![10.0, 20.0],
        values: vec![num_complex::Complex64::new(1e-6, 0.0); 2],
        coherence: None,
        unit: spindlelab::engine::value::UnitLabel::new("m/N"),
        direction: Some("x".into()),
        speed: None,
        sensor: None,
        dofs: None,
    };
    let mut one = String::new();
    formats::uff::write_frf(&mut one, &frf, "");
    std::fs::write(d.join("one.uff"), one + skipped.as_str()).unwrap();
    recipe(d, "steps:\n  h:\n    kind: read.frf\n    params: { file: one.uff }\n");
    let o = run_in(d, &["run", "r.yaml", "-o", "o"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let said = text(&o);
    assert!(said.contains("… and 99992 more passed over like these"), "{said}");
    assert!(said.len() < 5000, "{} characters", said.len());
}

#[test]
fn globs_that_leave_the_recipe_folder_are_refused_before_any_folder_is_read() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    recipe(
        d,
        "measurements:\n  a: { files: \"/**/*.csv\" }\n  b: { files: \"../../../../../../**/*.csv\" }\n  c: { files: \"m/**/x/**/*.csv\" }\n",
    );
    let said = refused(d, &["check", "r.yaml"]);
    assert!(said.contains("`/**/*.csv` is an absolute glob") && said.contains("r.yaml:4:15"), "{said}");
    assert!(said.contains("data files are named relative to the recipe's folder"), "{said}");
    assert!(said.contains("`../../../../../../**/*.csv` leads out of the recipe's folder with `..`"), "{said}");
    assert!(said.contains("r.yaml:5:15"), "{said}");
    assert!(said.contains("`m/**/x/**/*.csv` has more than one `**`") && said.contains("r.yaml:6:15"), "{said}");
}

#[test]
fn a_glob_is_walked_only_as_deep_as_its_any_depth_reaches() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let frf = "# units: m/N\nfreq_hz,real,imag\n100,1e-6,0\n";
    let mut deep = d.join("m");
    for level in 0..12 {
        std::fs::create_dir_all(&deep).unwrap();
        std::fs::write(deep.join(format!("frf_{level}.csv")), frf).unwrap();
        deep = deep.join("d");
    }
    recipe(d, "measurements:\n  tip: { files: \"m/**/frf_*.csv\" }\n");
    let o = run_in(d, &["plan", "r.yaml", "-o", "o"]);
    no_panic(&o);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    // `**` reaches eight folders down: nine of the twelve files.
    let said = text(&o);
    assert!(said.contains("frf_8.csv") && !said.contains("frf_9.csv"), "{said}");
}
