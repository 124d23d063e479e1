//! What a hostile recipe, case or data file can make the command do, through the binary:
//! generated workflows that no string of the user's can turn into code, `--confine` that
//! refuses on the path before reading, and bounded work for files of any size and recipes
//! of any fan-out. Each test failed before the fix it holds.

use crate::common::binary::{bin, no_panic, run_in, text};
use std::path::Path;
use std::process::Command;

fn write(path: &Path, text: &str) {
    if let Some(p) = path.parent() {
        std::fs::create_dir_all(p).unwrap();
    }
    std::fs::write(path, text).unwrap();
}

/// A one-step recipe named `name`, whose output is a small CSV.
fn impact_recipe(name: &str) -> String {
    format!(
        "spindlelab: 1\nname: {}\nsteps:\n  hit:\n    kind: impact.simulate\n    params: {{ hammer_mass: 0.05 kg, hammer_stiffness: 500 N/m, target_mass: 0.1 kg, target_stiffness: 5e7 N/m }}\noutputs:\n  - {{ from: \"@hit.impulse_time\", file: t.csv }}\n",
        spindlelab::engine::syntax::yaml_quoted(name)
    )
}

/// Runs `command`, giving it ten seconds; `None` (the process killed) when it takes longer.
fn within_ten_seconds(command: &mut Command) -> Option<std::process::Output> {
    let mut child = command.stdout(std::process::Stdio::piped()).stderr(std::process::Stdio::piped()).spawn().unwrap();
    for _ in 0..100 {
        if child.try_wait().unwrap().is_some() {
            return Some(child.wait_with_output().unwrap());
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    if child.try_wait().unwrap().is_some() {
        return Some(child.wait_with_output().unwrap());
    }
    child.kill().unwrap();
    let _ = child.wait();
    None
}

fn refused(o: &std::process::Output) -> String {
    no_panic(o);
    assert_eq!(o.status.code(), Some(2), "{}", text(o));
    text(o)
}

/// Names, folders and paths holding a line break, quotes, braces, backslashes and `#` go into
/// an exported Snakefile as data: Snakemake reads it (`-n`, which still runs its Python), none
/// of the injected statements runs, and it plans the jobs. A path Snakemake reads as a file
/// pattern (the cache's, a batch's output and case folders) cannot hold a brace (a wildcard
/// there, however written) or a line break: it is refused with exit 2, naming it.
#[test]
fn an_exported_workflow_holds_hostile_names_as_data_that_snakemake_reads() {
    let Some(snakemake) = crate::shards::snakemake() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let pwned = tmp.path().join("PWNED");
    let inject = format!("x\nopen({:?}, 'w').write('1')\n#", pwned.display().to_string());
    let hostile = [
        inject.as_str(),
        "q\"uote' {wildcard} }{ \\back\\slash # hash",
        "cr\r\nopen('/tmp/x','w') # \u{2028} \u{fc}n\u{ef}",
        "coding: utf-7 +AAo-",
    ];
    for (i, name) in hostile.iter().enumerate() {
        // The recipe's folder and the output folder carry the hostile text too; the cache's
        // quotes, `#` and backslashes.
        let folder = tmp.path().join(format!("f{i} {{a}} \"q\" #h \\b\nnl"));
        let recipe = folder.join("r.yaml");
        write(&recipe, &impact_recipe(name));
        let (wf, out, cache) =
            (folder.join("wf"), folder.join("out {x}\n"), tmp.path().join(format!("cache{i} \"q\" #h \\b")));
        let export = |cache: &Path| {
            bin()
                .args(["export", "snakemake"])
                .arg(&recipe)
                .arg("-o")
                .arg(&wf)
                .arg("--out")
                .arg(&out)
                .arg("--cache")
                .arg(cache)
                .output()
                .unwrap()
        };
        for bad in [folder.join("cache {c}"), tmp.path().join("cache\nnl")] {
            let said = refused(&export(&bad));
            assert!(said.contains("the cache folder") && said.contains("Snakemake"), "{said}");
            assert!(!wf.exists(), "a refused workflow was written");
        }
        let o = export(&cache);
        assert!(o.status.success(), "{name:?}: {}", text(&o));
        let snakefile = std::fs::read_to_string(wf.join("Snakefile")).unwrap();
        assert!(snakefile.is_ascii(), "{snakefile}");
        for line in snakefile.lines().take(2) {
            assert!(!line.contains("coding"), "the first two lines hold no text of the user's: {line}");
        }
        let o = Command::new(&snakemake)
            .arg("-n")
            .arg("-s")
            .arg(wf.join("Snakefile"))
            .arg("--profile")
            .arg(wf.join("profile"))
            .args(["--cores", "1"])
            .current_dir(&folder)
            .output()
            .unwrap();
        assert!(o.status.success(), "{name:?}: snakemake could not read the workflow:\n{}\n{snakefile}", text(&o));
        assert!(!pwned.exists(), "{name:?}: the recipe's name ran as code:\n{snakefile}");
        // The dry run plans the shard jobs and the collect job.
        let said = String::from_utf8_lossy(&o.stdout);
        assert!(said.contains("collect") && said.contains("shard"), "{said}");
        std::fs::remove_dir_all(&wf).unwrap();
    }
    // A batch whose case folders hold quotes, `#` and backslashes; braces are refused.
    let cases = tmp.path().join("batch");
    write(&cases.join("a \"c\" #d \\e").join("case.json"), "{}");
    write(&cases.join("b's case").join("case.json"), "{}");
    let batch = |pattern: &str, out: &str| {
        bin()
            .args(["export", "snakemake", "--batch", pattern, "-o", "bwf", "--out", out])
            .current_dir(tmp.path())
            .output()
            .unwrap()
    };
    assert!(refused(&batch("batch/*/case.json", "b {o}")).contains("the output folder"));
    let o = batch("batch/*/case.json", "b \"o\" #");
    assert!(o.status.success(), "{}", text(&o));
    let o = Command::new(&snakemake)
        .args(["-n", "-s", "bwf/Snakefile", "--profile", "bwf/profile", "--cores", "1"])
        .current_dir(tmp.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("case"), "{}", text(&o));
    write(&cases.join("c {x}").join("case.json"), "{}");
    assert!(refused(&batch("batch/*/case.json", "b2")).contains("a case's folder"));
}

/// `--confine` refuses a library, a recipe run as a step and a data file named outside the
/// recipe's folder by the name alone: a file that would block whoever opens it (a pipe) is
/// never opened, and a file of secrets is never quoted.
#[test]
fn confine_refuses_files_outside_by_their_path_before_reading_a_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let secret = "password: [unclosed \"TOP-SECRET-LINE";
    write(&tmp.path().join("lib.yaml"), secret);
    write(&tmp.path().join("sub.yaml"), secret);
    let pipe = tmp.path().join("pipe.csv");
    let c = std::ffi::CString::new(pipe.to_str().unwrap()).unwrap();
    // SAFETY: mkfifo with a valid path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let dir = tmp.path().join("recipe");
    for (what, body) in [
        ("library", "use: [../lib.yaml]\nsteps: {}\n".to_string()),
        ("library", format!("use: [{}]\nsteps: {{}}\n", tmp.path().join("lib.yaml").display())),
        ("recipe", "steps:\n  s: { kind: recipe, file: ../sub.yaml }\n".to_string()),
        ("data file", "steps:\n  m: { kind: read.frf, params: { file: ../pipe.csv } }\n".to_string()),
    ] {
        write(&dir.join("r.yaml"), &format!("spindlelab: 1\nname: c\n{body}"));
        // A reader of the pipe would wait for a writer for ever.
        let o = within_ten_seconds(bin().args(["--confine", "check", "r.yaml"]).current_dir(&dir))
            .unwrap_or_else(|| panic!("{what}: `--confine check` opened the pipe outside the recipe's folder"));
        let said = refused(&o);
        assert!(said.contains("outside the recipe's folder") && said.contains("--confine"), "{what}: {said}");
        assert!(said.contains("r.yaml:"), "{what}: the refusal is placed in the recipe: {said}");
        assert!(!said.contains("TOP-SECRET"), "{what}: a file outside was quoted: {said}");
    }
}

/// A cycle of Rhai modules is said as one, at the import that closes it, not as a module
/// that is not found.
#[test]
fn a_cycle_of_rhai_modules_is_named_as_a_cycle() {
    let tmp = tempfile::tempdir().unwrap();
    write(&tmp.path().join("a.rhai"), "import \"b\" as b;\nfn one() { 1 }\n");
    write(&tmp.path().join("b.rhai"), "import \"a\" as a;\nfn two() { 2 }\n");
    write(&tmp.path().join("r.rhai"), "import \"a\" as a;\n#{ spindlelab: 1, name: \"r\", steps: #{} }\n");
    let said = refused(&run_in(tmp.path(), &["check", "r.rhai"]));
    assert!(said.contains("imports itself"), "{said}");
    assert!(!said.contains("not found"), "{said}");
    assert!(said.contains("b.rhai:1"), "the import that closes the cycle: {said}");
}

/// `import` and `diagnose` read a case file through the cap of a recipe: `/dev/zero`, or a
/// batch's `case.json` of 64 MiB, is refused at once, naming the limit.
#[test]
fn a_case_file_is_read_through_a_cap() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(tmp.path().join("cases/z")).unwrap();
    std::fs::File::create(tmp.path().join("cases/z/case.json")).unwrap().set_len(64 << 20).unwrap();
    for args in [&["import", "/dev/zero"][..], &["diagnose", "--batch", "cases/*/case.json", "-o", "d"][..]] {
        let o = run_in(tmp.path(), args);
        no_panic(&o);
        assert_ne!(o.status.code(), Some(0), "{args:?}: {}", text(&o));
        let said =
            format!("{}{}", text(&o), std::fs::read_to_string(tmp.path().join("d/summary.csv")).unwrap_or_default());
        assert!(said.contains("limit"), "{args:?}: {said}");
    }
}

/// Seventeen small recipes, each running the next twice, would make 2^16 steps: `check`
/// refuses it at once with the size, before inlining, and names nothing else.
#[test]
fn a_fan_out_of_recipes_run_as_steps_is_refused_at_its_size() {
    let tmp = tempfile::tempdir().unwrap();
    write(
        &tmp.path().join("f16.yaml"),
        "spindlelab: 1\nname: leaf\nsteps:\n  hit:\n    kind: impact.simulate\n    params: { hammer_mass: 0.05 kg, hammer_stiffness: 500 N/m, target_mass: 0.1 kg, target_stiffness: 5e7 N/m }\nexports: { t: \"@hit.impulse_time\" }\n",
    );
    for k in 0..16 {
        write(
            &tmp.path().join(format!("f{k}.yaml")),
            &format!(
                "spindlelab: 1\nname: f{k}\nsteps:\n  a: {{ kind: recipe, file: f{n}.yaml }}\n  b: {{ kind: recipe, file: f{n}.yaml }}\nexports: {{ t: \"@a.t\" }}\n",
                n = k + 1
            ),
        );
    }
    let said = refused(&run_in(tmp.path(), &["check", "f0.yaml"]));
    assert!(said.contains("65536 steps") && said.contains("50000"), "{said}");
    assert!(!said.contains("is not a step"), "{said}");
    // One level less is within the cap: 2^15 steps.
    let o = run_in(tmp.path(), &["check", "f1.yaml"]);
    assert!(o.status.success(), "{}", text(&o));
}

/// A time series whose header is one enormous channel name, and a `# key:` line of the same
/// size, are refused at their line and column, naming the limit.
#[test]
fn names_and_labels_in_data_files_are_bounded() {
    let tmp = tempfile::tempdir().unwrap();
    let long = "n".repeat(5000);
    for (file, body, at) in [
        ("ts.csv", format!("# sample_rate: 1000 Hz\n# units: {long}=N\n{long}\n1\n2\n"), ":2:10"),
        ("ts2.csv", format!("# sample_rate: 1000 Hz\nforce,{long}\n1,2\n"), ":2:7"),
    ] {
        write(&tmp.path().join(file), &body);
        write(
            &tmp.path().join("r.yaml"),
            &format!(
                "spindlelab: 1\nname: r\nsteps:\n  ts:\n    kind: read.time_series\n    params: {{ file: {file} }}\n"
            ),
        );
        let said = refused(&run_in(tmp.path(), &["run", "r.yaml", "-o", "o", "-q"]));
        assert!(said.contains(&format!("{file}{at}")) && said.contains("at most 4096 bytes"), "{file}: {said}");
        assert!(!said.contains(&long), "{file}: the name was quoted whole");
    }
}

/// An FRF file's frequencies rise from 0 Hz, each once, and its coherence lies in [0, 1]:
/// anything else is refused at its file, line and column; an UFF dataset whose frequency
/// step is zero or negative is refused naming its file and line.
#[test]
fn frf_files_with_impossible_frequencies_or_coherence_are_refused_where_written() {
    let tmp = tempfile::tempdir().unwrap();
    let head = "# units: m/N\nfreq_hz,real,imag,coherence\n";
    for (rows, at, says) in [
        ("10,1e-7,0,0.9\n20,1e-7,0,1.5\n", "f.csv:4:4", "a coherence between 0 and 1"),
        ("10,1e-7,0,0.9\n20,1e-7,0,-0.1\n", "f.csv:4:4", "a coherence between 0 and 1"),
        ("-10,1e-7,0,0.9\n20,1e-7,0,0.9\n", "f.csv:3:1", "at least 0 Hz"),
        ("10,1e-7,0,0.9\n5,1e-7,0,0.9\n", "f.csv:4:1", "above the one before"),
        ("10,1e-7,0,0.9\n10,1e-7,0,0.9\n", "f.csv:4:1", "above the one before"),
    ] {
        write(&tmp.path().join("f.csv"), &format!("{head}{rows}"));
        write(
            &tmp.path().join("r.yaml"),
            "spindlelab: 1\nname: r\nsteps:\n  m:\n    kind: read.frf\n    params: { file: f.csv }\n",
        );
        let said = refused(&run_in(tmp.path(), &["run", "r.yaml", "-o", "o", "-q"]));
        assert!(said.contains(at) && said.contains(says), "{rows}: {said}");
    }
    // An UFF 58 dataset written by the tool, its frequency step then set to 0 and to -1.
    let frf = spindlelab::engine::value::Frf {
        freq_hz: vec![10.0, 20.0, 30.0],
        values: vec![num_complex::Complex64::new(1e-7, 0.0); 3],
        coherence: None,
        unit: spindlelab::engine::value::UnitLabel::new("m/N"),
        direction: Some("x".into()),
        speed: None,
        sensor: None,
        dofs: None,
    };
    let mut good = String::new();
    spindlelab::engine::formats::uff::write_frf(&mut good, &frf, "f");
    // Record 7 (the ninth line): types and count in three fields of 10, then the first
    // frequency, the step and the z value in fields of 13.
    let lines: Vec<&str> = good.lines().collect();
    assert_eq!(lines[8][43..56].trim().parse::<f64>().unwrap(), 10.0, "{good}");
    for bad in ["  0.00000E+00", " -1.00000E+00"] {
        let mut record = lines[8].to_string();
        record.replace_range(43..56, bad);
        let text: Vec<&str> =
            lines[..8].iter().copied().chain([record.as_str()]).chain(lines[9..].iter().copied()).collect();
        write(&tmp.path().join("f.uff"), &(text.join("\n") + "\n"));
        write(
            &tmp.path().join("r.yaml"),
            "spindlelab: 1\nname: r\nsteps:\n  m:\n    kind: read.frf\n    params: { file: f.uff }\n",
        );
        let said = refused(&run_in(tmp.path(), &["run", "r.yaml", "-o", "o", "-q"]));
        assert!(said.contains("f.uff:") && said.contains("positive frequency step"), "{bad}: {said}");
    }
}

/// The example plugins run under an address-space limit of a few GB (`ulimit -v`), where a
/// pool of 4 GiB reservations per memory cannot be mapped.
#[test]
fn plugins_run_under_an_address_space_limit() {
    let home = tempfile::tempdir().unwrap();
    let plugins = spindlelab_plugin_examples::dir();
    let root = env!("CARGO_MANIFEST_DIR");
    let o = Command::new("bash")
        .arg("-c")
        .arg(format!(
            "ulimit -v 4000000 && exec {:?} run scripts/plugin-nodes.yaml -q --plugin {:?} -o {:?} --no-cache",
            env!("CARGO_BIN_EXE_spindlelab"),
            plugins,
            home.path().join("o")
        ))
        .current_dir(root)
        .env("HOME", home.path())
        .env_remove("SPINDLELAB_PLUGIN_PATH")
        .env_remove("SPINDLELAB_PLUGIN_CACHE")
        .output()
        .unwrap();
    no_panic(&o);
    assert!(o.status.success(), "{}", text(&o));
    assert!(home.path().join("o/chatter-energy-ratio.csv").is_file());
}

/// A lattice of Rhai modules (each importing the next twice) is refused at its depth or its
/// count of imports, at once; values nested deeper than a recipe can be (closures that capture
/// closures, arrays in arrays) are dropped without overflowing the stack, and a recipe nested
/// that deep is refused with exit 2, and one whose building grows quadratically is stopped by
/// the time limit.
#[test]
fn rhai_module_lattices_and_deep_values_are_bounded() {
    let tmp = tempfile::tempdir().unwrap();
    for i in 1..=22 {
        write(
            &tmp.path().join(format!("w{i}.rhai")),
            &format!("import \"w{n}\" as a;\nimport \"w{n}\" as b;\nfn f() {{ 1 }}\n", n = i + 1),
        );
    }
    write(&tmp.path().join("w23.rhai"), "fn f() { 1 }\n");
    write(&tmp.path().join("t.rhai"), "import \"w1\" as x;\n#{ spindlelab: 1, name: \"r\", steps: #{} }\n");
    let said = refused(&run_in(tmp.path(), &["check", "t.rhai"]));
    assert!(said.contains("deep") || said.contains("imports"), "{said}");
    write(
        &tmp.path().join("c.rhai"),
        "let f = |x| x;\nfor i in 0..50000 { let g = f; f = |x| g.call(x); }\n#{ spindlelab: 1, name: \"r\", steps: #{} }\n",
    );
    let o = run_in(tmp.path(), &["check", "c.rhai"]);
    no_panic(&o);
    assert!(o.status.success(), "{}", text(&o));
    write(
        &tmp.path().join("n.rhai"),
        "let a = [];\nfor i in 0..2000 { a = [a]; }\n#{ spindlelab: 1, name: \"r\", steps: #{}, extra: a }\n",
    );
    let said = refused(&run_in(tmp.path(), &["check", "n.rhai"]));
    assert!(said.contains("nests deeper than 64"), "{said}");
    // Thirty thousand deep, each level costs more to build than the last: the time limit
    // stops the script long before the operation limit would.
    write(
        &tmp.path().join("d.rhai"),
        &std::fs::read_to_string(tmp.path().join("n.rhai")).unwrap().replace("2000", "30000"),
    );
    let o = within_ten_seconds(bin().args(["check", "d.rhai"]).current_dir(tmp.path()))
        .expect("a script nesting arrays 30,000 deep is stopped within ten seconds");
    let said = refused(&o);
    assert!(said.contains("ran longer than 5 s") || said.contains("nests deeper than 64"), "{said}");
}

/// A pipe named on the command line (a recipe, a case) is opened without waiting for a
/// writer: with none it reads as empty and is refused at once; one being written is read.
#[test]
fn a_pipe_named_on_the_command_line_is_not_waited_on() {
    let tmp = tempfile::tempdir().unwrap();
    for name in ["p.yaml", "case.json"] {
        let c = std::ffi::CString::new(tmp.path().join(name).to_str().unwrap()).unwrap();
        // SAFETY: mkfifo with a valid path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    }
    for args in [&["check", "p.yaml"][..], &["import", "case.json"][..]] {
        let o = within_ten_seconds(bin().args(args).current_dir(tmp.path()))
            .unwrap_or_else(|| panic!("{args:?}: waited on a pipe with no writer"));
        refused(&o);
    }
    // A pipe with a writer (as `<(…)` gives): the recipe arrives through it.
    let mut child = bin()
        .args(["check", "/dev/stdin"])
        .current_dir(tmp.path())
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(200));
    std::io::Write::write_all(child.stdin.as_mut().unwrap(), impact_recipe("piped").as_bytes()).unwrap();
    drop(child.stdin.take());
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
}

/// `cache du` on an output folder whose cache is a link refuses it as `gc` and `clean` do,
/// without measuring where it leads.
#[test]
fn cache_du_does_not_follow_a_linked_cache() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(tmp.path().join("elsewhere/ab")).unwrap();
    std::fs::write(tmp.path().join("elsewhere/ab/entry"), "x").unwrap();
    std::fs::create_dir_all(tmp.path().join("out")).unwrap();
    std::os::unix::fs::symlink(tmp.path().join("elsewhere"), tmp.path().join("out/.spindlelab-cache")).unwrap();
    for verb in ["du", "gc", "clean"] {
        let said = refused(&run_in(tmp.path(), &["cache", verb, "out"]));
        assert!(said.contains("symbolic link"), "{verb}: {said}");
    }
    assert!(tmp.path().join("elsewhere/ab/entry").is_file(), "nothing removed where the link leads");
}
