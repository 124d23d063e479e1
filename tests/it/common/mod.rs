//! Helpers shared by the integration tests: run a recipe and pick its outputs by step and
//! port, run the binary on a bad fixture of `tests/bad/`, and find the data of other projects
//! in `../shared` (or skip).
#![allow(dead_code)] // each test crate uses a different part

pub mod binary;
pub mod case;
pub mod measured;
pub mod synthetic;

use spindlelab::engine::exec::RunOptions;
use spindlelab::engine::value::{Lobes, ReceptanceSet, Scalar, Table, Value};
use spindlelab::engine::{self, Compiled};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;

/// A compiled recipe and the report of one uncached run.
pub struct Ran {
    pub compiled: Compiled,
    pub report: engine::RunReport,
}

impl Ran {
    /// The output `port` of the first instance of `step`.
    pub fn value(&self, step: &str, port: &str) -> Arc<Value> {
        let i = self.compiled.graph.by_step[step][0];
        let outputs = self.report.result.outcomes[i].outputs().unwrap_or_else(|| panic!("{step} did not run"));
        Arc::clone(&outputs[port])
    }
    pub fn set(&self, step: &str, port: &str) -> ReceptanceSet {
        match self.value(step, port).as_ref() {
            Value::ReceptanceSet(r) => r.clone(),
            other => panic!("{step}.{port} is {:?}", other.port_type()),
        }
    }
    pub fn lobes(&self, step: &str, port: &str) -> Lobes {
        match self.value(step, port).as_ref() {
            Value::Lobes(l) => l.clone(),
            other => panic!("{step}.{port} is {:?}", other.port_type()),
        }
    }
    pub fn table(&self, step: &str, port: &str) -> Table {
        match self.value(step, port).as_ref() {
            Value::Table(t) => t.clone(),
            other => panic!("{step}.{port} is {:?}", other.port_type()),
        }
    }
    pub fn scalar(&self, step: &str, port: &str) -> Scalar {
        match self.value(step, port).as_ref() {
            Value::Scalar(s) => s.clone(),
            other => panic!("{step}.{port} is {:?}", other.port_type()),
        }
    }
}

/// Compiles and runs the recipe at `path` without the cache, writing outputs to `out`.
pub fn run_at(path: &Path, out: &Path) -> Ran {
    let registry = spindlelab::registry();
    let compiled = engine::compile_file(path, &registry).unwrap_or_else(|e| panic!("{}", e.render(false)));
    let mut opts = RunOptions::new(out).with_renderer(spindlelab::renderer());
    opts.use_cache = false;
    let report = engine::run(&compiled, &registry, &opts, &|_, _| {}).unwrap_or_else(|e| panic!("{e}"));
    Ran { compiled, report }
}

/// [`run_at`] into a temporary directory.
pub fn run(path: &Path) -> Ran {
    let out = tempfile::tempdir().unwrap();
    run_at(path, out.path())
}

/// The file or folder `rel` of `../shared` beside the checkout (data of other projects, kept
/// out of the repository), or `None` when it is not there: the test says on stderr that `what`
/// is skipped and returns. Under CI (`CI` set) its absence fails the test instead.
pub fn shared(rel: &str, what: &str) -> Option<PathBuf> {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")).join(rel);
    if path.exists() {
        return Some(path);
    }
    assert!(std::env::var_os("CI").is_none(), "CI needs {} (../shared beside the checkout)", path.display());
    eprintln!("no {}: {what} is skipped", path.display());
    None
}

pub fn bad_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join("bad")
}

/// Runs the binary on a fixture of `tests/bad/` (from that folder, so messages name it
/// relatively): exit code 2, no panic; returns stderr followed by stdout.
pub fn rejected(file: &str, keep_going: bool) -> String {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let mut args: Vec<&OsStr> = vec![OsStr::new("run"), OsStr::new(file), OsStr::new("-o"), out.as_os_str()];
    if keep_going {
        args.push(OsStr::new("--keep-going"));
    }
    let o = Command::new(env!("CARGO_BIN_EXE_spindlelab"))
        .args(args)
        .current_dir(bad_dir())
        .env("NO_COLOR", "1")
        .env_remove("RUST_BACKTRACE")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stderr).into_owned() + String::from_utf8_lossy(&o.stdout).as_ref();
    assert!(!text.contains("panicked"), "{text}");
    assert_eq!(o.status.code(), Some(2), "{text}");
    text
}

/// Every needle is in `text`.
pub fn assert_has(text: &str, needles: &[&str]) {
    for n in needles {
        assert!(text.contains(n), "missing `{n}` in:\n{text}");
    }
}
