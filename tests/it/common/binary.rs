//! Running the binary: with plain output, in a folder, and checking that it did not panic.

use std::path::Path;
use std::process::{Command, Output};

/// The binary, with plain (uncoloured) output and no backtraces.
pub fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_spindlelab"));
    c.env("NO_COLOR", "1").env_remove("RUST_BACKTRACE");
    c
}

/// Runs `args` in `cwd`.
pub fn run_in(cwd: &Path, args: &[&str]) -> Output {
    bin().args(args).current_dir(cwd).output().expect("the binary starts")
}

/// Standard output and error, labelled, for messages.
pub fn text(o: &Output) -> String {
    format!("stdout:\n{}\nstderr:\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// Fails when the binary panicked.
pub fn no_panic(o: &Output) {
    let t = text(o);
    assert!(!t.contains("panicked"), "the binary panicked:\n{t}");
    assert_ne!(o.status.code(), Some(101), "{t}");
}
