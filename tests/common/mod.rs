//! Helpers shared by the integration tests (each test crate uses some).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use graftal::grammar::{run, RunOptions, RunOutput, StepStats};
use graftal::rules::compile::{compile, parse};
use graftal::rules::diagnostic::SourceFile;
use graftal::rules::spanned::SourceFormat;
use graftal::rules::{Program, RuleError};

/// Compiles TOML rule text named `test.toml`, with `rules/` as its folder.
pub fn program(text: &str) -> Result<Program, RuleError> {
    let file = SourceFile {
        name: "test.toml".into(),
        text: text.into(),
    };
    let ast = parse(&file, SourceFormat::Toml)?;
    compile(&file, &ast, &[], Path::new("rules"))
}

/// Asserts that each rule text fails to compile with a headline that
/// contains its expected text.
pub fn assert_rejected(cases: &[(&str, &str)]) {
    for (text, expected) in cases {
        let message = match program(text) {
            Ok(_) => panic!("expected an error for:\n{text}"),
            Err(e) => e.headline(),
        };
        assert!(
            message.contains(expected),
            "{message}\n  should contain: {expected}"
        );
    }
}

/// Compiles TOML rule text, panicking with the headline on an error.
pub fn toml(text: &str) -> Program {
    program(text).unwrap_or_else(|e| panic!("{}", e.headline()))
}

/// The JSON chunk of a GLB.
pub fn glb_json(path: &Path) -> serde_json::Value {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[..4], b"glTF");
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    assert_eq!(&bytes[16..20], b"JSON");
    serde_json::from_slice(&bytes[20..20 + len]).unwrap()
}

/// Reads and decodes a mesh file (format by extension).
pub fn read_mesh(path: &Path) -> graftal::io::IndexedMesh {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let format = graftal::io::MeshFormat::from_path(path).unwrap();
    graftal::io::decode(&bytes, format, path).unwrap_or_else(|e| panic!("{e}"))
}

/// The files a program imports, read as the command line would.
pub fn inputs(p: &Program) -> std::sync::Arc<[graftal::grammar::Input]> {
    p.resources
        .iter()
        .map(|r| match r.kind {
            graftal::rules::program::ResourceKind::Mesh => {
                graftal::grammar::Input::new(std::sync::Arc::new(read_mesh(&r.path)))
            }
            graftal::rules::program::ResourceKind::Patches => {
                let bytes = std::fs::read(&r.path).unwrap();
                let file = graftal::io::patches::decode_patches(&bytes, &r.path).unwrap();
                graftal::grammar::Input::patches(file.surfaces)
            }
        })
        .collect()
}

/// Runs a program with the kernel validated after every step.
pub fn run_validated(p: &Program, options: RunOptions) -> RunOutput {
    let options = RunOptions {
        validate_each_step: true,
        inputs: inputs(p),
        ..options
    };
    let out = run(p, &options).unwrap_or_else(|e| panic!("{e}"));
    out.mesh.validate().unwrap();
    out
}

/// Compiles and runs rule text with the kernel validated after every step.
pub fn grow(text: &str) -> RunOutput {
    run_validated(&toml(text), RunOptions::default())
}

/// The statistics of the step named `name`.
pub fn step<'a>(out: &'a RunOutput, name: &str) -> &'a StepStats {
    out.steps
        .iter()
        .find(|s| &*s.name == name)
        .unwrap_or_else(|| panic!("no step {name}"))
}

/// Runs the graftal binary in `dir` (relative paths in outputs and
/// manifests are relative to it).
pub fn graftal_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_graftal"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("graftal runs")
}

/// Runs the graftal binary in the project folder.
pub fn graftal(args: &[&str]) -> Output {
    graftal_in(Path::new(env!("CARGO_MANIFEST_DIR")), args)
}

pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The example rule files in `rules/`, sorted.
pub fn examples() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> =
        std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("rules"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("toml" | "ron")))
            .collect();
    files.sort();
    assert!(files.len() >= 10, "rules/ holds the examples");
    files
}

/// Writes `text` as `dir/rules.toml` and asserts that `check` and `run`
/// both fail with exit 2, an error at `location` containing `words`, no
/// panic and no output file.
pub fn assert_located_error(dir: &Path, text: &str, location: &str, words: &str) {
    std::fs::write(dir.join("rules.toml"), text).unwrap();
    for args in [
        &["check", "rules.toml"][..],
        &["run", "rules.toml", "-o", "out.obj"],
    ] {
        let o = graftal_in(dir, args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?} {text}\n{err}");
        assert!(
            err.contains(location),
            "{text}\nexpected {location} in:\n{err}"
        );
        assert!(err.contains(words), "{text}\nexpected {words:?} in:\n{err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!dir.join("out.obj").exists(), "no output on error");
    }
}

/// Runs `graftal run RULES -o DIR/TEMPLATE EXTRA…` in the project folder at
/// 1 thread / 1 job, 2 threads / 1 job and 2 threads / 2 jobs, and asserts
/// the `.glb` files written are the same bytes every time; returns how
/// many there were.
pub fn assert_same_bytes_at_any_thread_and_job_count(
    rules: &str,
    template: &str,
    extra: &[&str],
) -> usize {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut outputs = Vec::new();
    for (threads, jobs) in [("1", "1"), ("2", "1"), ("2", "2")] {
        let out = dir.path().join(format!("t{threads}j{jobs}"));
        std::fs::create_dir(&out).unwrap();
        let target = format!("{}/{template}", out.display());
        let mut args = vec!["run", rules, "-o", &target, "-j", jobs];
        args.extend_from_slice(extra);
        let o = Command::new(env!("CARGO_BIN_EXE_graftal"))
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .env("RAYON_NUM_THREADS", threads)
            .args(&args)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap())
            .filter(|e| e.file_name().to_string_lossy().ends_with(".glb"))
            .map(|e| {
                (
                    e.file_name().into_string().unwrap(),
                    std::fs::read(e.path()).unwrap(),
                )
            })
            .collect();
        files.sort();
        outputs.push(files);
    }
    assert!(
        outputs.windows(2).all(|w| w[0] == w[1]),
        "{rules}: bytes depend on threads or jobs"
    );
    outputs[0].len()
}
