//! A bounded, seeded mutation campaign over everything that reads untrusted text: the recipe
//! loader and compiler, the quantity grammar, and the CSV and UFF readers. Each input is a
//! real file with random byte-level damage (flips, deletions, insertions, duplicated and
//! swapped spans); the only acceptable outcomes are a value or an error, never a panic.
//! Mutated recipes that compile are also run, under memory and time limits.
//! Run with `--nocapture` for the tries per class.

use spindlelab::engine::{self, formats};
use std::path::{Path, PathBuf};

/// xorshift64*: a fixed seed gives the same campaign on every machine.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Bytes that matter to the formats under test, besides random ones.
const INTERESTING: &[&[u8]] = &[
    b"-1",
    b"\n",
    b",",
    b";",
    b":",
    b"{",
    b"}",
    b"[",
    b"]",
    b"\"",
    b"'",
    b"*",
    b"&a",
    b"@",
    b"$",
    b"..",
    b" step ",
    b"e308",
    b"1e999",
    b"NaN",
    b"inf",
    b"-0",
    b"99999999999",
    b"58b",
    b"    58",
    b"\t",
    b"\xef\xbb\xbf",
    b"\xff",
    b"rpm",
    b"mm",
    b"kg",
    b"N/m",
    b"^2",
    b"/",
    b"(",
    b")",
    b"#",
    b"!!",
    b"%",
    b"0x",
    b"18446744073709551615",
];

fn mutate(rng: &mut Rng, input: &[u8]) -> Vec<u8> {
    let mut b = input.to_vec();
    for _ in 0..1 + rng.below(4) {
        let len = b.len().max(1);
        let at = rng.below(len);
        match rng.below(6) {
            0 if !b.is_empty() => {
                let i = at.min(b.len() - 1);
                b[i] ^= 1 << rng.below(8);
            }
            1 => {
                let end = (at + 1 + rng.below(16)).min(b.len());
                b.drain(at.min(end)..end);
            }
            2 => {
                let piece = INTERESTING[rng.below(INTERESTING.len())];
                let at = at.min(b.len());
                b.splice(at..at, piece.iter().copied());
            }
            3 => {
                let end = (at + rng.below(64)).min(b.len());
                let span: Vec<u8> = b[at.min(end)..end].to_vec();
                let to = rng.below(b.len() + 1);
                b.splice(to..to, span);
            }
            4 => {
                let at = at.min(b.len());
                b.insert(at, rng.next() as u8);
            }
            _ => {
                // Truncate: a file cut short.
                b.truncate(at);
            }
        }
    }
    b
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &to.join(e.file_name()));
        } else {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).to_path_buf()
}

/// Runs `f` on `tries` mutants of each seed; returns (tries, panics) and names the first panic.
fn campaign(name: &str, seeds: &[Vec<u8>], tries: usize, seed: u64, f: impl Fn(&[u8])) -> (usize, Vec<String>) {
    let mut rng = Rng(seed);
    let mut panics = Vec::new();
    let mut n = 0;
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    for s in seeds {
        for _ in 0..tries {
            let m = mutate(&mut rng, s);
            n += 1;
            if std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(&m))).is_err() {
                panics.push(String::from_utf8_lossy(&m).chars().take(400).collect());
            }
        }
    }
    std::panic::set_hook(hook);
    println!("{name}: {n} tries, {} panics", panics.len());
    (n, panics)
}

fn assert_no_panic(name: &str, (n, panics): (usize, Vec<String>)) {
    assert!(n > 0);
    assert!(panics.is_empty(), "{name}: {} of {n} inputs panicked; the first:\n{}", panics.len(), panics[0]);
}

#[test]
fn mutated_recipes_compile_or_fail_without_panicking() {
    let registry = spindlelab::registry();
    let dir = tempfile::tempdir().unwrap();
    let mut seeds = Vec::new();
    for f in std::fs::read_dir(root().join("scripts")).unwrap() {
        let p = f.unwrap().path();
        if p.extension().is_some_and(|e| e == "yaml") {
            seeds.push(std::fs::read(&p).unwrap());
        }
    }
    assert!(seeds.len() >= 5);
    let path = dir.path().join("mutant.yaml");
    let result = campaign("recipes", &seeds, 600, 0x5eed_0001, |bytes| {
        std::fs::write(&path, bytes).unwrap();
        let _ = engine::compile_file(&path, &registry);
    });
    assert_no_panic("recipes", result);
    // The same beside a copy of the example data, so references to files resolve and mutants
    // reach the deeper stages.
    copy_dir(&root().join("scripts/data"), &dir.path().join("data"));
    // Mutants that compile to a small graph are kept, to be run below.
    let runnable = std::sync::Mutex::new(Vec::new());
    let result = campaign("recipes beside their data", &seeds, 300, 0x5eed_0002, |bytes| {
        std::fs::write(&path, bytes).unwrap();
        if let Ok(c) = engine::compile_file(&path, &registry)
            && c.graph.instances.len() <= MAX_RUN_INSTANCES
            && !seeds.iter().any(|s| s == bytes)
        {
            runnable.lock().unwrap().push(bytes.to_vec());
        }
    });
    assert_no_panic("recipes beside their data", result);
    run_mutants(dir.path(), runnable.into_inner().unwrap());
}

/// The most node instances a compiled mutant may have to be run, and how many are run.
const MAX_RUN_INSTANCES: usize = 40;
const MUTANTS_RUN: usize = 12;

/// Runs compiled mutants through the binary, each under a memory limit (`ulimit -v`, 4 GiB)
/// and a ten-second deadline: it may succeed, fail its run (1) or be refused (2), never panic
/// or die of a signal. A mutant still running at its deadline is stopped and counted apart
/// (a mutated duration may ask for a long simulation); it is not a failure.
fn run_mutants(dir: &Path, mutants: Vec<Vec<u8>>) {
    assert!(mutants.len() >= MUTANTS_RUN, "only {} mutants compiled to a small graph", mutants.len());
    let step = mutants.len() / MUTANTS_RUN;
    let (mut finished, mut stopped) = (0, 0);
    for (k, m) in mutants.iter().step_by(step).take(MUTANTS_RUN).enumerate() {
        let recipe = dir.join(format!("run-{k}.yaml"));
        std::fs::write(&recipe, m).unwrap();
        let mut child = std::process::Command::new("sh")
            .arg("-c")
            .arg("ulimit -v 4194304 && exec \"$0\" run \"$1\" -o \"$2\" --no-cache -q -j 1")
            .arg(env!("CARGO_BIN_EXE_spindlelab"))
            .arg(&recipe)
            .arg(dir.join(format!("out-{k}")))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
        while child.try_wait().unwrap().is_none() && std::time::Instant::now() < deadline {
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap();
            let _ = child.wait();
            stopped += 1;
            continue;
        }
        let o = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        let text = String::from_utf8_lossy(m);
        assert!(
            matches!(o.status.code(), Some(0..=2)),
            "a mutant ended with {:?}:\n{err}\n--- the mutant:\n{text}",
            o.status
        );
        assert!(
            !err.contains("panicked") && !err.contains("internal error"),
            "a mutant panicked:\n{err}\n--- the mutant:\n{text}"
        );
        finished += 1;
    }
    println!("compiled mutants run: {finished} finished, {stopped} stopped at their deadline");
    assert!(finished > 0, "every mutant run was stopped at its deadline");
}

#[test]
fn mutated_quantities_parse_or_fail_without_panicking() {
    let seeds: Vec<Vec<u8>> = [
        "12.7 mm",
        "0.03..0.07 step 0.005 kg",
        "[1, 2, 3] N/m",
        "-13.84 deg/kHz",
        "25 %",
        "5e7 N/m",
        "200 GPa",
        "0..4000 step 500 rpm",
        "3e5 N*m/rad",
        "14500 kg/m^3",
        "@step.port",
        "1.5e8 N/m",
    ]
    .iter()
    .map(|s| s.as_bytes().to_vec())
    .collect();
    let result = campaign("quantities", &seeds, 2000, 0x5eed_0003, |bytes| {
        let text = String::from_utf8_lossy(bytes);
        let _ = spindlelab::engine::grammar::parse_value(&text);
        let _ = spindlelab::engine::grammar::parse_unit(&text);
    });
    assert_no_panic("quantities", result);
}

#[test]
fn mutated_csv_and_uff_files_read_or_fail_without_panicking() {
    let mut csv_seeds: Vec<Vec<u8>> = ["tests/bad/stability/x.csv", "tests/bad/measured/frf_x_0rpm.csv"]
        .iter()
        .map(|p| std::fs::read(root().join(p)).unwrap())
        .map(|b| b[..b.len().min(6000)].to_vec())
        .collect();
    // Swept outputs as the writers make them: sweep columns, a units line, non-finite cells.
    csv_seeds.push(
        b"# units: m/N\nspeed_rpm,direction,freq_hz,real,imag\n0,x,0e0,1e-7,0e0\n0,x,1e1,1e-7,-1e-8\n500,y,0e0,2e-7,0e0\n"
            .to_vec(),
    );
    csv_seeds.push(
        b"# units: speed=rpm, depth=m, outcome=\ndirection,speed_rpm,depth_m,outcome\nx,2e3,5e-4,0e0\ny,3e3,NaN,inf\n"
            .to_vec(),
    );
    let result = campaign("csv", &csv_seeds, 3000, 0x5eed_0004, |bytes| {
        let _ = formats::csv::read_frf(bytes, "m.csv");
        let _ = formats::csv::read_frf_blocks(bytes, "m.csv");
        let _ = formats::csv::read_time_series(bytes, "m.csv");
        let _ = formats::csv::read_receptance(bytes, "m.csv");
        let _ = formats::csv::read_tables(bytes, "m.csv");
        let _ = formats::csv::read_lobes(bytes, "m.csv");
        let _ = formats::csv::read_scalars(bytes, "m.csv");
    });
    assert_no_panic("csv", result);
    // pyuff's files from `../shared` when it is there (each skipped without it), and our own.
    let pyuff = ["frf_x_ascii.uff", "frf_xy_binary.uff", "force_time_ascii.uff"]
        .into_iter()
        .filter_map(|p| crate::common::shared(&format!("data/uff/{p}"), "this seed of the UFF campaign"));
    let uff_seeds: Vec<Vec<u8>> = pyuff
        .chain([root().join("engine/tests/data/uff/skip_then_frf.uff")])
        .map(|p| std::fs::read(p).unwrap())
        .map(|b| b[..b.len().min(20000)].to_vec())
        .collect();
    let result = campaign("uff", &uff_seeds, 1500, 0x5eed_0005, |bytes| {
        let _ = formats::uff::parse(bytes, "m.uff");
    });
    assert_no_panic("uff", result);
}

/// Mutated `case.json` files through the importer, and what it writes through the compiler:
/// a recipe or an error, never a panic; and a written recipe never gains an output or a step
/// the case did not ask for (a mutated string cannot inject one).
#[test]
fn mutated_cases_import_or_fail_without_panicking_or_injecting() {
    let registry = spindlelab::registry();
    let dir = tempfile::tempdir().unwrap();
    let case = std::fs::read(root().join("tests/data/train_07-case.json")).unwrap();
    // The case's data beside the recipe, so the written recipe compiles through to its steps.
    copy_dir(&root().join("tests/data/train-07"), dir.path());
    copy_dir(&root().join("tests/data/train-07"), &dir.path().join("train-07"));
    let path = dir.path().join("imported.yaml");
    let shape = |text: &str| {
        std::fs::write(&path, text).unwrap();
        engine::compile_file(&path, &registry).ok().map(|c| (c.recipe.steps.len(), c.recipe.outputs.len()))
    };
    let base = shape(&spindlelab::import::recipe_from_case(std::str::from_utf8(&case).unwrap(), "case.json").unwrap())
        .expect("the case imports and compiles");
    let (imported, injected) = (std::sync::Mutex::new(0usize), std::sync::Mutex::new(Vec::new()));
    let result = campaign("cases", &[case], 3000, 0x5eed_0005, |bytes| {
        let Ok(json) = std::str::from_utf8(bytes) else { return };
        let Ok(text) = spindlelab::import::recipe_from_case(json, "case.json") else { return };
        *imported.lock().unwrap() += 1;
        if let Some((steps, outputs)) = shape(&text)
            && (steps > base.0 || outputs > base.1)
        {
            injected.lock().unwrap().push(json.chars().take(400).collect::<String>());
        }
    });
    let imported = imported.into_inner().unwrap();
    println!("cases: {imported} imported");
    assert_no_panic("cases", result);
    // The injection check means something only if mutants got through the importer.
    assert!(imported >= 100, "only {imported} of 3000 mutated cases imported: the check above saw too few");
    let injected = injected.into_inner().unwrap();
    assert!(injected.is_empty(), "{} mutants gained a step or an output; the first:\n{}", injected.len(), injected[0]);
}
