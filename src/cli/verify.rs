//! `graftal verify --golden DIR RULES...`: regenerate and compare with
//! stored goldens; `--bless` rewrites them. For CI: `--junit FILE` writes
//! one JUnit testcase per rule file and seed (the differences as the
//! failure), `--diff-dir DIR` a picture per changed variant (golden | new |
//! where they differ, drawn by the preview renderer with one camera).
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
    /// Also write a JUnit XML report (one testcase per rule file and
    /// seed), which CI systems show as test results.
    #[arg(long, value_name = "FILE", conflicts_with = "bless")]
    pub junit: Option<PathBuf>,
    /// Also write, for each variant that differs, `DIR/<stem>.png`: the
    /// golden mesh, the new one and where their pictures differ.
    #[arg(long, value_name = "DIR", conflicts_with = "bless")]
    pub diff_dir: Option<PathBuf>,
    /// Side of each of the three panels of a `--diff-dir` picture.
    #[arg(long, default_value_t = 256, value_name = "PIXELS", value_parser = clap::value_parser!(u32).range(32..=1024))]
    pub diff_size: u32,
    #[command(flatten)]
    pub input: super::InputArgs,
}

/// One variant regenerated: its golden stem and what it makes.
struct Fresh {
    stem: String,
    stats: String,
    obj: Vec<u8>,
}

/// One compared variant, for the reports.
struct Case {
    /// The rule file as given.
    rules: String,
    seed: Option<u64>,
    stem: String,
    differences: Vec<String>,
}

pub fn verify(args: VerifyArgs) -> Result<(), Failure> {
    if !super::files::is_dir(&args.golden) {
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
    let mut cases: Vec<Case> = Vec::new();
    let mut pictures: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    for ((stem, rules_path), program) in stems.iter().zip(&programs) {
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
            let golden_obj = read_golden(&obj_path)?;
            if let Some(bytes) = &golden_obj {
                compare_obj(&obj_path, bytes, &fresh.obj, &args, &mut differences)?;
            }
            if let (Some(dir), false) = (&args.diff_dir, differences.is_empty()) {
                let png =
                    diff_picture(golden_obj.as_deref(), &obj_path, &fresh.obj, args.diff_size)?;
                pictures.push((dir.join(format!("{}.png", fresh.stem)), png));
            }
            cases.push(Case {
                rules: rules_path.display().to_string(),
                seed: seed.filter(|_| args.seeds.is_some()),
                stem: fresh.stem.clone(),
                differences: differences.clone(),
            });
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
    if let Some(path) = &args.junit {
        write(path, junit_xml(&cases, &args.golden).as_bytes())?;
    }
    if let Some(dir) = &args.diff_dir {
        // Every picture, or none: a half-written folder would mislead.
        let mut staged = super::files::Staged::new();
        for (path, png) in &pictures {
            staged
                .stage(path, png)
                .map_err(|e| Failure::Runtime(format!("cannot write {}: {e}", path.display())))?;
        }
        staged.commit().map_err(|(path, e)| {
            Failure::Runtime(format!("cannot write {}: {e}", path.display()))
        })?;
        if !args.quiet && !pictures.is_empty() {
            eprintln!(
                "{} difference pictures in {}",
                pictures.len(),
                dir.display()
            );
        }
    }
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
    let text = match super::files::read_json_text(path) {
        Ok(Some(text)) => text,
        Ok(None) => {
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

/// The golden mesh at `path`, if there is one.
fn read_golden(path: &Path) -> Result<Option<Vec<u8>>, Failure> {
    match super::files::read_input(path, super::files::MAX_MESH_BYTES) {
        Ok(bytes) => Ok(Some(bytes)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(Failure::Input(format!(
            "cannot read {}: {e}",
            path.display()
        ))),
    }
}

fn compare_obj(
    path: &Path,
    bytes: &[u8],
    fresh: &[u8],
    args: &VerifyArgs,
    out: &mut Vec<String>,
) -> Result<(), Failure> {
    let expected = io::obj::decode(bytes, path).map_err(|e| Failure::Input(e.to_string()))?;
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

/// A JUnit XML report: a testsuite per rule file, a testcase per seed,
/// the differences as the failure's text. No times, so the same results
/// give the same bytes.
fn junit_xml(cases: &[Case], golden: &Path) -> String {
    let failures = cases.iter().filter(|c| !c.differences.is_empty()).count();
    let mut xml = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    xml += &format!(
        "<testsuites name=\"graftal verify\" tests=\"{}\" failures=\"{failures}\" errors=\"0\">\n",
        cases.len()
    );
    let mut start = 0;
    while start < cases.len() {
        let rules = &cases[start].rules;
        let end = start
            + cases[start..]
                .iter()
                .take_while(|c| &c.rules == rules)
                .count();
        let suite = &cases[start..end];
        let failed = suite.iter().filter(|c| !c.differences.is_empty()).count();
        xml += &format!(
            "  <testsuite name=\"{}\" tests=\"{}\" failures=\"{failed}\" errors=\"0\">\n",
            xml_escape(rules),
            suite.len()
        );
        for case in suite {
            let name = match case.seed {
                Some(seed) => format!("seed {seed}"),
                None => "default seed".to_owned(),
            };
            let open = format!(
                "    <testcase classname=\"{}\" name=\"{}\" file=\"{}\"",
                xml_escape(rules),
                xml_escape(&name),
                xml_escape(rules)
            );
            if case.differences.is_empty() {
                xml += &format!("{open}/>\n");
            } else {
                let message = format!(
                    "{} difference(s) from the goldens {}",
                    case.differences.len(),
                    golden.join(format!("{}.*", case.stem)).display()
                );
                xml += &format!(
                    "{open}>\n      <failure type=\"golden mismatch\" message=\"{}\">{}</failure>\n    </testcase>\n",
                    xml_escape(&message),
                    xml_escape(&case.differences.join("\n"))
                );
            }
        }
        xml += "  </testsuite>\n";
        start = end;
    }
    xml += "</testsuites>\n";
    xml
}

/// Text safe in XML content and attribute values; characters XML 1.0
/// cannot hold at all become U+FFFD.
fn xml_escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\n' => out.push_str("&#10;"),
            '\t' | '\r' => out.push(c),
            c if (c as u32) < 0x20 || c == '\u{FFFE}' || c == '\u{FFFF}' => out.push('\u{FFFD}'),
            c => out.push(c),
        }
    }
    out
}

/// The picture of one changed variant: the golden mesh, the new one (one
/// camera framing both) and their pictures' difference, side by side.
fn diff_picture(
    golden: Option<&[u8]>,
    golden_path: &Path,
    fresh: &[u8],
    size: u32,
) -> Result<Vec<u8>, Failure> {
    use crate::preview::{self, Image};
    let decode = |bytes: &[u8]| {
        io::obj::decode(bytes, golden_path).map_err(|e| Failure::Input(e.to_string()))
    };
    let new = decode(fresh)?;
    let old = golden.map(decode).transpose()?;
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in new
        .positions
        .iter()
        .chain(old.iter().flat_map(|m| m.positions.iter()))
    {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let finite = lo.iter().chain(&hi).all(|x| x.is_finite());
    let options = preview::Options {
        width: size,
        height: size,
        edges: true,
        frame: finite.then_some([lo, hi]),
        ..preview::Options::default()
    };
    let draw = |m: &IndexedMesh| {
        super::preview::render(m, &options)
            .map_err(|e| Failure::Runtime(format!("diff picture: {e}")))
    };
    let blank = Image {
        width: size,
        height: size,
        rgba: [255u8, 255, 255, 255].repeat(size as usize * size as usize),
    };
    let new_image = draw(&new)?;
    let (old_image, old_label) = match &old {
        Some(m) => (draw(m)?, "golden"),
        None => (blank.clone(), "golden: no mesh"),
    };
    // Where the two pictures differ: magenta over a faded copy of the new.
    let mut changed = 0usize;
    let mut delta = new_image.clone();
    for (k, px) in delta.rgba.chunks_exact_mut(4).enumerate() {
        let differs =
            old.is_some() && old_image.rgba[4 * k..4 * k + 4] != new_image.rgba[4 * k..4 * k + 4];
        if differs {
            changed += 1;
            px.copy_from_slice(&[255, 0, 255, 255]);
        } else {
            for c in &mut px[..3] {
                *c = 255 - (255 - *c) / 4;
            }
        }
    }
    let delta_label = if old.is_none() {
        "difference: no golden mesh".to_owned()
    } else if changed == 0 {
        "difference: none visible".to_owned()
    } else {
        format!("difference: {changed} px")
    };
    let sheet = preview::contact_sheet(
        &[
            (old_image, old_label.to_owned()),
            (new_image, "new".to_owned()),
            (delta, delta_label),
        ],
        3,
    )
    .map_err(|e| Failure::Runtime(format!("diff picture: {e}")))?;
    preview::encode_png(&sheet).map_err(|e| Failure::Runtime(e.to_string()))
}
