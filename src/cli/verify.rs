//! `graftal verify --golden DIR RULES...`: regenerate and compare with
//! stored goldens; `--bless` rewrites them.
//!
//! Each variant has a stats golden `<stem>.json` (`<stem>-<seed>.json`
//! with `--seeds`), always compared, and optionally a mesh golden
//! `<stem>.obj` beside it, compared when present. Integers, strings,
//! topology and structure must match exactly; floats within
//! `abs_tol + rel_tol · max(|expected|, |got|)` (both 0 by default: graftal
//! is deterministic, so a golden that moves at all is news).

use std::path::{Path, PathBuf};

use serde_json::Value;

use super::batch::SeedSet;
use super::{stats, Failure, EXIT_RUNTIME};
use crate::grammar::{self, RunOptions};
use crate::io::{self, IndexedMesh};
use crate::rules::{self, Override};

/// Stats fields that name the tool or the invocation rather than the
/// model: not compared.
const IGNORED_FIELDS: &[&str] = &["graftal_version", "rules"];

/// Differences listed per golden file before the rest are only counted.
const SHOWN_DIFFERENCES: usize = 12;

#[derive(clap::Args, Debug)]
pub struct VerifyArgs {
    /// Directory of goldens: `<stem>.json` (and optionally `<stem>.obj`)
    /// per rule file, `<stem>-<seed>.*` with `--seeds`.
    #[arg(long, value_name = "DIR")]
    pub golden: PathBuf,
    /// Rule files to regenerate.
    #[arg(required = true)]
    pub rules: Vec<PathBuf>,
    /// Verify these seeds of each file (default: the file's seed).
    #[arg(long, value_name = "RANGE", value_parser = SeedSet::parse)]
    pub seeds: Option<SeedSet>,
    #[arg(long = "set", value_name = "NAME=VALUE", value_parser = super::parse_override)]
    pub overrides: Vec<Override>,
    /// Absolute tolerance for floats.
    #[arg(long, default_value_t = 0.0, value_parser = super::parse_tolerance)]
    pub abs_tol: f64,
    /// Relative tolerance for floats.
    #[arg(long, default_value_t = 0.0, value_parser = super::parse_tolerance)]
    pub rel_tol: f64,
    /// Rewrite the goldens with the current output instead of comparing.
    #[arg(long)]
    pub bless: bool,
    /// With --bless: write only the stats goldens, no OBJ meshes.
    #[arg(long, requires = "bless")]
    pub stats_only: bool,
    /// No success line.
    #[arg(short, long)]
    pub quiet: bool,
    #[command(flatten)]
    pub input: super::InputArgs,
}

/// One variant regenerated: its golden stem and what it makes.
struct Fresh {
    stem: String,
    stats: String,
    obj: Vec<u8>,
}

pub fn verify(args: VerifyArgs) -> Result<(), Failure> {
    if !args.golden.is_dir() {
        return Err(Failure::Input(format!(
            "golden directory {} does not exist (create it, then run with --bless to fill it)",
            args.golden.display()
        )));
    }
    let mut stems: Vec<(String, &Path)> = Vec::new();
    for rules in &args.rules {
        let stem = rules
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        if let Some((_, other)) = stems.iter().find(|(s, _)| *s == stem) {
            return Err(Failure::Input(format!(
                "{} and {} would share the goldens `{stem}.*`; verify them against different directories",
                other.display(),
                rules.display()
            )));
        }
        stems.push((stem, rules));
    }
    // Compile everything first: a bad rule file is an input error, and
    // nothing is compared or blessed.
    let programs = args
        .rules
        .iter()
        .map(|r| super::files::compile_rules(r, &args.overrides))
        .collect::<Result<Vec<_>, _>>()?;

    let mut report = String::new();
    let mut mismatched = 0;
    let mut checked = 0;
    let mut blessed = 0;
    for ((stem, _), program) in stems.iter().zip(&programs) {
        let inputs = super::files::load_inputs(program, args.input.policy())?;
        let seeds: Vec<Option<u64>> = match &args.seeds {
            Some(set) => set.seeds.iter().map(|&s| Some(s)).collect(),
            None => vec![None],
        };
        for seed in seeds {
            let stem = match seed {
                Some(s) if args.seeds.is_some() => format!("{stem}-{s}"),
                _ => stem.clone(),
            };
            let fresh = regenerate(program, &inputs, seed, stem)?;
            let json_path = args.golden.join(format!("{}.json", fresh.stem));
            let obj_path = args.golden.join(format!("{}.obj", fresh.stem));
            if args.bless {
                write(&json_path, fresh.stats.as_bytes())?;
                blessed += 1;
                if !args.stats_only {
                    write(&obj_path, &fresh.obj)?;
                    blessed += 1;
                }
                continue;
            }
            checked += 1;
            let mut differences = Vec::new();
            compare_stats(&json_path, &fresh.stats, &args, &mut differences)?;
            if obj_path.exists() {
                compare_obj(&obj_path, &fresh.obj, &args, &mut differences)?;
            }
            if !differences.is_empty() {
                mismatched += 1;
                for d in differences.iter().take(SHOWN_DIFFERENCES) {
                    report += &format!("{d}\n");
                }
                if differences.len() > SHOWN_DIFFERENCES {
                    report += &format!(
                        "{}: … and {} more differences\n",
                        fresh.stem,
                        differences.len() - SHOWN_DIFFERENCES
                    );
                }
            }
        }
    }
    if args.bless {
        if !args.quiet {
            eprintln!(
                "blessed {blessed} golden files in {}",
                args.golden.display()
            );
        }
        return Ok(());
    }
    eprint!("{report}");
    if mismatched > 0 {
        return Err(Failure::Limit(
            EXIT_RUNTIME,
            format!(
                "{mismatched} of {checked} variants differ from the goldens in {} (run with --bless to accept the new output)",
                args.golden.display()
            ),
        ));
    }
    if !args.quiet {
        eprintln!(
            "{checked} variants match the goldens in {}",
            args.golden.display()
        );
    }
    Ok(())
}

fn regenerate(
    program: &rules::Program,
    inputs: &super::files::Inputs,
    seed: Option<u64>,
    stem: String,
) -> Result<Fresh, Failure> {
    let options = RunOptions {
        seed,
        inputs: std::sync::Arc::clone(&inputs.meshes),
        ..RunOptions::default()
    };
    let result =
        grammar::run(program, &options).map_err(|e| Failure::Limit(EXIT_RUNTIME, e.to_string()))?;
    let (report, gates) = stats::report_and_gates(&result.mesh, stats::CLOSE_TOLERANCE);
    let mut stats = serde_json::to_string_pretty(&stats::run_stats_doc(
        program, &result, &report, &gates, 0, false,
    ))
    .expect("stats serialize");
    stats.push('\n');
    let obj = io::encode(&grammar::export(program, &result.mesh), io::MeshFormat::Obj)
        .map_err(|e| Failure::Runtime(format!("{stem}: {e}")))?;
    Ok(Fresh { stem, stats, obj })
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), Failure> {
    super::files::write_atomic(path, bytes)
        .map_err(|e| Failure::Runtime(format!("cannot write {}: {e}", path.display())))
}

/// Whether two floats agree within the tolerances (exactly, when both are 0).
fn close(expected: f64, got: f64, args: &VerifyArgs) -> bool {
    if expected == got {
        return true;
    }
    let diff = (expected - got).abs();
    diff <= args.abs_tol + args.rel_tol * expected.abs().max(got.abs())
}

fn compare_stats(
    path: &Path,
    fresh: &str,
    args: &VerifyArgs,
    out: &mut Vec<String>,
) -> Result<(), Failure> {
    let text = match std::fs::read_to_string(path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            out.push(format!(
                "{}: missing golden (run with --bless to create it)",
                path.display()
            ));
            return Ok(());
        }
        Err(e) => {
            return Err(Failure::Input(format!(
                "cannot read {}: {e}",
                path.display()
            )))
        }
    };
    let expected: Value = serde_json::from_str(&text).map_err(|e| {
        Failure::Input(format!(
            "{}:{}:{}: not a JSON stats golden: {e}",
            path.display(),
            e.line(),
            e.column()
        ))
    })?;
    let got: Value = serde_json::from_str(fresh).expect("fresh stats parse");
    let mut walk = JsonWalk {
        file: path.display().to_string(),
        args,
        out,
    };
    walk.value("", &expected, &got);
    Ok(())
}

struct JsonWalk<'a> {
    file: String,
    args: &'a VerifyArgs,
    out: &'a mut Vec<String>,
}

impl JsonWalk<'_> {
    fn differ(&mut self, at: &str, expected: &dyn std::fmt::Display, got: &dyn std::fmt::Display) {
        let at = if at.is_empty() { "(document)" } else { at };
        self.out.push(format!(
            "{}: {at}: expected {expected}, got {got}",
            self.file
        ));
    }

    fn value(&mut self, at: &str, expected: &Value, got: &Value) {
        match (expected, got) {
            (Value::Number(e), Value::Number(g)) => {
                let floats = e.is_f64() || g.is_f64();
                match (e.as_f64(), g.as_f64()) {
                    (Some(x), Some(y)) if floats && close(x, y, self.args) => {}
                    _ if !floats && e == g => {}
                    _ => self.differ(at, e, g),
                }
            }
            (Value::Array(e), Value::Array(g)) => {
                if e.len() != g.len() {
                    self.differ(&format!("{at} (length)"), &e.len(), &g.len());
                }
                for (k, (x, y)) in e.iter().zip(g).enumerate() {
                    self.value(&format!("{at}[{k}]"), x, y);
                }
            }
            (Value::Object(e), Value::Object(g)) => {
                for (key, x) in e {
                    if at.is_empty() && IGNORED_FIELDS.contains(&key.as_str()) {
                        continue;
                    }
                    let here = if at.is_empty() {
                        key.clone()
                    } else {
                        format!("{at}.{key}")
                    };
                    match g.get(key) {
                        Some(y) => self.value(&here, x, y),
                        None => self.differ(&here, x, &"nothing (field gone)"),
                    }
                }
                for (key, y) in g {
                    if !e.contains_key(key) {
                        let here = if at.is_empty() {
                            key.clone()
                        } else {
                            format!("{at}.{key}")
                        };
                        self.differ(&here, &"nothing (new field)", y);
                    }
                }
            }
            (e, g) if e == g => {}
            (e, g) => self.differ(at, e, g),
        }
    }
}

fn compare_obj(
    path: &Path,
    fresh: &[u8],
    args: &VerifyArgs,
    out: &mut Vec<String>,
) -> Result<(), Failure> {
    let bytes = std::fs::read(path)
        .map_err(|e| Failure::Input(format!("cannot read {}: {e}", path.display())))?;
    let expected = io::obj::decode(&bytes, path).map_err(|e| Failure::Input(e.to_string()))?;
    let got = io::obj::decode(fresh, path).expect("fresh OBJ decodes");
    let file = path.display();
    let counts = |m: &IndexedMesh| [m.positions.len(), m.polygon_count(), m.lines.len()];
    let (ce, cg) = (counts(&expected), counts(&got));
    for (k, what) in ["vertices", "faces", "lines"].iter().enumerate() {
        if ce[k] != cg[k] {
            out.push(format!("{file}: {what}: expected {}, got {}", ce[k], cg[k]));
        }
    }
    for (k, (e, g)) in expected.positions.iter().zip(&got.positions).enumerate() {
        for (axis, name) in ["x", "y", "z"].iter().enumerate() {
            if !close(e[axis], g[axis], args) {
                out.push(format!(
                    "{file}: vertex {} {name}: expected {}, got {} (difference {:e})",
                    k + 1,
                    e[axis],
                    g[axis],
                    g[axis] - e[axis]
                ));
            }
        }
    }
    for (k, (e, g)) in expected.polygons().zip(got.polygons()).enumerate() {
        if e != g {
            out.push(format!(
                "{file}: face {}: expected vertices {e:?}, got {g:?} (0-based)",
                k + 1
            ));
        }
    }
    // Parts and materials by name, face by face.
    let part = |m: &IndexedMesh, k: usize| {
        m.parts
            .get(m.polygon_part(k) as usize)
            .cloned()
            .unwrap_or_default()
    };
    let material = |m: &IndexedMesh, k: usize| {
        m.polygon_material(k)
            .and_then(|i| m.materials.get(i as usize))
            .map(|m| m.name.clone())
            .unwrap_or_default()
    };
    for k in 0..ce[1].min(cg[1]) {
        let (e, g) = (
            (part(&expected, k), material(&expected, k)),
            (part(&got, k), material(&got, k)),
        );
        if e != g {
            out.push(format!(
                "{file}: face {}: expected part {:?} material {:?}, got part {:?} material {:?}",
                k + 1,
                e.0,
                e.1,
                g.0,
                g.1
            ));
        }
    }
    for (k, (e, g)) in expected.lines.iter().zip(&got.lines).enumerate() {
        if e != g {
            out.push(format!(
                "{file}: line {}: expected vertices {e:?}, got {g:?} (0-based)",
                k + 1
            ));
        }
    }
    Ok(())
}
