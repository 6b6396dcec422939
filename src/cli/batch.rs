//! `graftal run`: one variant or a batch of them.
//!
//! A batch is the cartesian product of `--grid` values (first axis
//! slowest) with `--seeds` (fastest); variant `index` counts through it.
//! Everything a variant writes depends only on its rule file, overrides and
//! seed — never on `-j`, on scheduling or on which other variants run — so
//! workers take variants in any order, and whatever is reported in order
//! (NDJSON stats, the manifest) is put back in index order first.

use std::collections::{BTreeMap, BTreeSet};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use sha2::{Digest, Sha256};

use super::files::{self, Staged};
use super::manifest::{
    self, BatchSpec, Counts, ErrorEntry, GridSpec, InputEntry, Manifest, ShardSpec, Status,
    Summary, VariantEntry,
};
use super::stats::{self, steps_json};
use super::{output_format, Failure, EXIT_RUNTIME};
use crate::grammar::{self, RunErrorKind, RunOptions};
use crate::io;
use crate::rules::{Override, Program};

/// More variants than this in one batch is surely a typo'd range.
pub const MAX_VARIANTS: u64 = 10_000_000;

/// `--seeds`: comma-separated items, each `N`, `A..B` (B excluded) or
/// `A..=B`.
#[derive(Clone, Debug)]
pub struct SeedSet {
    /// Normalized text (what the manifest records).
    pub text: String,
    pub seeds: Vec<u64>,
}

impl SeedSet {
    pub fn parse(text: &str) -> Result<SeedSet, String> {
        let number = |s: &str| -> Result<u64, String> {
            s.trim().parse::<u64>().map_err(|_| {
                format!(
                    "`{}` is not a seed (a whole number from 0 to 2^64 - 1)",
                    s.trim()
                )
            })
        };
        let mut seeds = Vec::new();
        let mut items = Vec::new();
        for item in text.split(',') {
            let item = item.trim();
            if item.is_empty() {
                return Err(format!(
                    "`{text}`: empty item (expected N, A..B or A..=B, comma-separated)"
                ));
            }
            // Inclusive bounds, so that seed 2^64 - 1 is a seed like any other.
            let (first, last) = if let Some((a, b)) = item.split_once("..=") {
                (number(a)?, Some(number(b)?))
            } else if let Some((a, b)) = item.split_once("..") {
                (number(a)?, number(b)?.checked_sub(1))
            } else {
                let n = number(item)?;
                (n, Some(n))
            };
            let Some(last) = last.filter(|&last| first <= last) else {
                return Err(format!("the range `{item}` is empty"));
            };
            if (seeds.len() as u64)
                .saturating_add(last - first)
                .saturating_add(1)
                > MAX_VARIANTS
            {
                return Err(format!(
                    "`{text}` names more than {MAX_VARIANTS} seeds; split the batch"
                ));
            }
            seeds.extend(first..=last);
            items.push(item.replace(' ', ""));
        }
        let mut sorted = seeds.clone();
        sorted.sort_unstable();
        if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
            return Err(format!("seed {} is listed twice in `{text}`", w[0]));
        }
        Ok(SeedSet {
            text: items.join(","),
            seeds,
        })
    }
}

/// `--grid name=v1,v2,…`: one axis of the parameter grid.
#[derive(Clone, Debug)]
pub struct GridAxis {
    pub name: String,
    pub values: Vec<String>,
}

impl GridAxis {
    pub fn parse(text: &str) -> Result<GridAxis, String> {
        let (name, values) = text
            .split_once('=')
            .ok_or_else(|| format!("`{text}` is not of the form name=v1,v2,..."))?;
        let name = name.trim();
        let first = name.chars().next();
        if !first.is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        {
            return Err(format!("`{name}` is not a parameter name"));
        }
        let values: Vec<String> = values.split(',').map(|v| v.trim().to_string()).collect();
        if values.iter().any(String::is_empty) {
            return Err(format!("`{text}`: empty value in the list"));
        }
        Ok(GridAxis {
            name: name.to_string(),
            values,
        })
    }
}

/// `--shard i/n`: the variants whose index is `i` modulo `n` (0-based).
#[derive(Clone, Copy, Debug)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    pub fn parse(text: &str) -> Result<Shard, String> {
        let (i, n) = text
            .split_once('/')
            .ok_or_else(|| format!("`{text}` is not of the form i/n (e.g. 0/4)"))?;
        let parse = |s: &str| {
            s.trim()
                .parse::<usize>()
                .map_err(|_| format!("`{text}`: `{s}` is not a whole number"))
        };
        let (index, count) = (parse(i)?, parse(n)?);
        if count == 0 {
            return Err(format!("`{text}`: the shard count must be at least 1"));
        }
        if index >= count {
            return Err(format!(
                "`{text}`: shards are numbered from 0 to {} (0-based)",
                count - 1
            ));
        }
        Ok(Shard { index, count })
    }
}

/// An output path template: literal text and `{field}` or `{field:0N}`
/// (zero-padded to N digits; seeds and indices only); `{{` and `}}` are
/// literal braces.
#[derive(Clone, Debug)]
pub struct Template {
    text: String,
    pieces: Vec<Piece>,
}

#[derive(Clone, Debug)]
enum Piece {
    Text(String),
    Field { name: String, width: Option<usize> },
}

/// A value a template field takes.
enum FieldValue<'a> {
    Int(u64),
    Float(f64),
    Text(&'a str),
}

impl Template {
    pub fn parse(text: &str) -> Result<Template, String> {
        let mut pieces = Vec::new();
        let mut literal = String::new();
        let mut chars = text.chars().peekable();
        while let Some(c) = chars.next() {
            match c {
                '{' if chars.peek() == Some(&'{') => {
                    chars.next();
                    literal.push('{');
                }
                '}' if chars.peek() == Some(&'}') => {
                    chars.next();
                    literal.push('}');
                }
                '{' => {
                    let mut spec = String::new();
                    loop {
                        match chars.next() {
                            Some('}') => break,
                            Some(c) => spec.push(c),
                            None => return Err(format!("`{text}`: `{{` without a closing `}}`")),
                        }
                    }
                    let (name, width) = match spec.split_once(':') {
                        None => (spec.as_str(), None),
                        Some((name, w)) => {
                            let digits = w.strip_prefix('0').unwrap_or(w);
                            let width = digits.parse::<usize>().ok().filter(|&w| w <= 20);
                            match width {
                                Some(width) if w.starts_with('0') => (name, Some(width)),
                                _ => {
                                    return Err(format!(
                                        "`{text}`: `{{{spec}}}`: the only format is `:0N`, zero-padding to N digits (N up to 20)"
                                    ))
                                }
                            }
                        }
                    };
                    if name.is_empty() {
                        return Err(format!("`{text}`: empty field `{{{spec}}}`"));
                    }
                    if !literal.is_empty() {
                        pieces.push(Piece::Text(std::mem::take(&mut literal)));
                    }
                    pieces.push(Piece::Field {
                        name: name.to_string(),
                        width,
                    });
                }
                '}' => {
                    return Err(format!(
                        "`{text}`: `}}` without an opening `{{` (write `}}}}` for a brace)"
                    ))
                }
                c => literal.push(c),
            }
        }
        if !literal.is_empty() {
            pieces.push(Piece::Text(literal));
        }
        Ok(Template {
            text: text.to_string(),
            pieces,
        })
    }

    pub fn text(&self) -> &str {
        &self.text
    }

    /// The literal text before the first field.
    fn fixed_prefix(&self) -> &str {
        match self.pieces.first() {
            Some(Piece::Text(t)) => t,
            _ => "",
        }
    }

    /// Checks every field against the names a variant can fill in.
    fn check_fields(&self, what: &str, params: &[String]) -> Result<(), Failure> {
        for piece in &self.pieces {
            let Piece::Field { name, width } = piece else {
                continue;
            };
            let integer = matches!(name.as_str(), "seed" | "index");
            let known = integer || name == "name" || params.iter().any(|p| p == name);
            if !known {
                let mut fields = vec!["name".to_string(), "seed".into(), "index".into()];
                fields.extend(params.iter().cloned());
                return Err(Failure::Input(format!(
                    "{what} `{}`: unknown field `{{{name}}}`; fields are {}",
                    self.text,
                    fields.join(", ")
                )));
            }
            if width.is_some() && !integer {
                return Err(Failure::Input(format!(
                    "{what} `{}`: `{{{name}}}` cannot be zero-padded (only seed and index)",
                    self.text
                )));
            }
        }
        Ok(())
    }

    fn render<'a>(&self, field: impl Fn(&str) -> FieldValue<'a>) -> String {
        let mut out = String::new();
        for piece in &self.pieces {
            match piece {
                Piece::Text(t) => out.push_str(t),
                Piece::Field { name, width } => match (field(name), width) {
                    (FieldValue::Int(n), Some(w)) => out.push_str(&format!("{n:0w$}")),
                    (FieldValue::Int(n), None) => out.push_str(&n.to_string()),
                    (FieldValue::Float(x), _) => out.push_str(&x.to_string()),
                    (FieldValue::Text(t), _) => out.push_str(t),
                },
            }
        }
        out
    }
}

/// Everything `graftal run` was given.
#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// Rule file (.toml or .ron).
    pub rules: PathBuf,
    /// Output mesh: .obj, .gltf, .glb, .stl (binary), .ply (binary).
    /// A template: `{name}`, `{seed}`, `{index}` and parameter names
    /// are filled in per variant (`{seed:04}` zero-pads). Defaults to
    /// `{name}.obj`; in a batch `{name}-{seed}.obj` (with a grid
    /// `{name}-{index}.obj`).
    #[arg(short, long, value_name = "OUT")]
    pub output: Option<String>,
    /// Seed for every random draw (default: the file's `seed`, else 0).
    #[arg(long, conflicts_with = "seeds")]
    pub seed: Option<u64>,
    /// A batch over seeds: `0..1000` (end excluded), `0..=999`, `1,5,9`
    /// or a mix (`0..10,100`).
    #[arg(long, value_name = "RANGE", value_parser = SeedSet::parse)]
    pub seeds: Option<SeedSet>,
    /// Override a parameter: `--set name=value` (a number or expression).
    #[arg(long = "set", value_name = "NAME=VALUE", value_parser = super::parse_override)]
    pub overrides: Vec<Override>,
    /// A parameter grid axis: `--grid name=v1,v2,v3`; several axes and
    /// `--seeds` make a cartesian product (first axis slowest, seeds
    /// fastest).
    #[arg(long = "grid", value_name = "NAME=V1,V2,...", value_parser = GridAxis::parse)]
    pub grid: Vec<GridAxis>,
    /// Variants run at once (default: every core). Never changes a byte.
    #[arg(short = 'j', long = "jobs", value_name = "N", value_parser = clap::value_parser!(u64).range(1..=1024))]
    pub jobs: Option<u64>,
    /// Run only shard I of N (0-based: variants whose index is I mod N)
    /// and write a shard manifest for `graftal manifest merge`.
    #[arg(long, value_name = "I/N", value_parser = Shard::parse)]
    pub shard: Option<Shard>,
    /// Batch manifest path (default: `manifest.json` in the output
    /// template's directory; `manifest.shard-I-of-N.json` for a shard).
    #[arg(long, value_name = "FILE")]
    pub manifest: Option<PathBuf>,
    /// Write run statistics as JSON to FILE, or `-` for standard output.
    /// In a batch: `-` streams NDJSON (one line per variant, in index
    /// order), a path with `{...}` fields writes one file per variant,
    /// any other path gets the NDJSON.
    #[arg(long, value_name = "FILE")]
    pub stats: Option<String>,
    /// Include wall-clock times in the stats and manifest (makes them
    /// differ run to run).
    #[arg(long)]
    pub timings: bool,
    /// Stop (exit code 3, no output) when the model would exceed this
    /// many primitives (vertices + edges + faces).
    #[arg(long, visible_alias = "max-elements", default_value_t = crate::grammar::DEFAULT_MAX_ELEMENTS, value_name = "N")]
    pub max_primitives: usize,
    /// Stop (exit code 5, no output) after this many evaluations of
    /// conditions and per-primitive parameters.
    #[arg(long, default_value_t = crate::grammar::DEFAULT_MAX_EVALUATIONS, value_name = "N")]
    pub max_evaluations: u64,
    /// Stop (exit code 3, no output) before meshing a signed distance
    /// field on a grid of more than N cells (checked before allocating).
    #[arg(long, default_value_t = crate::grammar::DEFAULT_MAX_CELLS, value_name = "N")]
    pub max_cells: u64,
    /// Stop a variant (exit code 4, no output) after SECONDS of wall
    /// clock.
    #[arg(long, value_name = "SECONDS", value_parser = super::parse_timeout)]
    pub timeout: Option<f64>,
    /// Stop starting variants after the first failure.
    #[arg(long)]
    pub fail_fast: bool,
    /// No progress bar, no summary, no "wrote" line (errors still go to
    /// standard error).
    #[arg(short, long)]
    pub quiet: bool,
    /// Print a machine-readable summary of the batch on standard output.
    #[arg(long)]
    pub json: bool,
    /// Also write a PNG contact sheet: a shaded thumbnail of every
    /// variant (three-quarter view), labelled with its seed and grid
    /// values, in variant order.
    #[arg(long, value_name = "SHEET.png")]
    pub contact_sheet: Option<PathBuf>,
    /// Thumbnail width and height on the contact sheet, in pixels.
    #[arg(long, default_value_t = 192, value_name = "PIXELS", value_parser = clap::value_parser!(u32).range(32..=1024))]
    pub thumbnail_size: u32,
    #[command(flatten)]
    pub write: super::WriteArgs,
    #[command(flatten)]
    pub input: super::InputArgs,
}

impl RunArgs {
    /// A batch reports through a manifest and a summary; a single run (no
    /// `--seeds`, `--grid`, `--shard` or `--manifest`) as it always did.
    fn is_batch(&self) -> bool {
        self.seeds.is_some()
            || !self.grid.is_empty()
            || self.shard.is_some()
            || self.manifest.is_some()
    }
}

/// Where a variant's statistics go.
enum StatsSink {
    None,
    /// One JSON document per variant at a templated path.
    Files(Template),
    /// NDJSON, one line per variant, to standard output.
    Stdout,
    /// NDJSON, one line per variant, to a file.
    File(PathBuf),
    /// A single run's pretty document to standard output or a file.
    Single(Option<PathBuf>),
}

struct Variant {
    index: usize,
    combo: usize,
    seed: u64,
    params: Vec<(String, f64)>,
    output: PathBuf,
    format: io::MeshFormat,
    stats: Option<PathBuf>,
}

/// What producing one variant gave.
struct Produced {
    entry: VariantEntry,
    /// Its stats document (compact for NDJSON), when stats are wanted.
    stats: Option<String>,
    /// A single run's outputs, written but not yet in place: the stats
    /// file and the manifest join them, and all are renamed together.
    staged: Option<Staged>,
    /// Counts for the single-run message.
    faces: usize,
    vertices: usize,
    /// Warnings of the run (the batch prints each once).
    warnings: Vec<String>,
    /// Its contact-sheet thumbnail, when a sheet is wanted.
    thumbnail: Option<crate::preview::Image>,
}

pub fn run(args: RunArgs) -> Result<(), Failure> {
    let batch = args.is_batch();
    let name = args
        .rules
        .file_stem()
        .map_or_else(|| "out".into(), |s| s.to_string_lossy().into_owned());
    let output = Template::parse(args.output.as_deref().unwrap_or(if !batch {
        "{name}.obj"
    } else if args.grid.is_empty() {
        "{name}-{seed}.obj"
    } else {
        "{name}-{index}.obj"
    }))
    .map_err(|m| Failure::Input(format!("--output: {m}")))?;

    // Overrides of every grid combination, then one program each.
    for axis in &args.grid {
        if args.overrides.iter().any(|o| o.name == axis.name)
            || args.grid.iter().filter(|a| a.name == axis.name).count() > 1
        {
            return Err(Failure::Input(format!(
                "parameter `{}` is given twice (in --set or --grid)",
                axis.name
            )));
        }
    }
    let combos = grid_combinations(&args.grid);
    let rule_bytes = std::fs::read(&args.rules)
        .map_err(|e| Failure::Input(format!("cannot read {}: {e}", args.rules.display())))?;
    let mut programs: Vec<Program> = Vec::with_capacity(combos.len());
    for combo in &combos {
        let mut overrides = args.overrides.clone();
        overrides.extend(args.grid.iter().zip(combo).map(|(axis, value)| Override {
            name: axis.name.clone(),
            value: value.clone(),
        }));
        programs.push(super::files::compile_rules(&args.rules, &overrides)?);
    }
    // Every grid combination compiles the same file, so needs the same
    // files: read once, shared by every variant.
    let inputs = files::load_inputs(&programs[0], args.input.policy())?;
    let param_names = programs[0].param_names.clone();
    output.check_fields("--output", &param_names)?;

    let stats_sink = match (&args.stats, batch) {
        (None, _) => StatsSink::None,
        (Some(s), false) if !s.contains('{') => {
            StatsSink::Single((s != "-").then(|| PathBuf::from(s)))
        }
        (Some(s), _) if s == "-" => StatsSink::Stdout,
        (Some(s), _) if s.contains('{') => {
            let t = Template::parse(s).map_err(|m| Failure::Input(format!("--stats: {m}")))?;
            t.check_fields("--stats", &param_names)?;
            StatsSink::Files(t)
        }
        (Some(s), _) => StatsSink::File(PathBuf::from(s)),
    };

    // Variants, all paths known before anything runs.
    let seeds: Vec<Option<u64>> = match (&args.seeds, args.seed) {
        (Some(set), _) => set.seeds.iter().map(|&s| Some(s)).collect(),
        (None, seed) => vec![seed],
    };
    let total = combos.len() as u64 * seeds.len() as u64;
    if total > MAX_VARIANTS {
        return Err(Failure::Input(format!(
            "the batch has {total} variants, more than {MAX_VARIANTS}; split it"
        )));
    }
    let total = total as usize;
    let mut variants = Vec::new();
    for index in 0..total {
        if args.shard.is_some_and(|s| index % s.count != s.index) {
            continue;
        }
        let combo = index / seeds.len();
        let program = &programs[combo];
        let seed = seeds[index % seeds.len()].unwrap_or(program.default_seed);
        let params = grammar::parameter_values(program, Some(seed))
            .map_err(|e| Failure::Runtime(e.to_string()))?;
        let field = |f: &str| match f {
            "name" => FieldValue::Text(&name),
            "seed" => FieldValue::Int(seed),
            "index" => FieldValue::Int(index as u64),
            p => FieldValue::Float(
                params
                    .iter()
                    .find(|(n, _)| n == p)
                    .map_or(f64::NAN, |(_, v)| *v),
            ),
        };
        let path = PathBuf::from(output.render(field));
        let format = output_format(&path, args.write.ascii)?;
        let stats = match &stats_sink {
            StatsSink::Files(t) => Some(PathBuf::from(t.render(field))),
            _ => None,
        };
        variants.push(Variant {
            index,
            combo,
            seed,
            params,
            output: path,
            format,
            stats,
        });
    }
    let manifest_path = match (&args.manifest, batch) {
        (Some(p), _) => Some(p.clone()),
        (None, false) => None,
        (None, true) => {
            let prefix = Path::new(output.fixed_prefix());
            let dir = if output.fixed_prefix().ends_with('/') {
                prefix
            } else {
                prefix.parent().unwrap_or(Path::new(""))
            };
            let file = match args.shard {
                Some(s) => format!("manifest.shard-{}-of-{}.json", s.index, s.count),
                None => "manifest.json".to_string(),
            };
            Some(dir.join(file))
        }
    };
    check_distinct_paths(&variants, manifest_path.as_deref(), &stats_sink)?;
    if let Some(sheet) = &args.contact_sheet {
        check_contact_sheet(sheet, variants.len(), args.thumbnail_size)?;
    }
    // A batch's own files are written last: find out now whether they can
    // be, so that a bad path fails before any variant is written.
    if batch {
        let own = [
            manifest_path.as_deref(),
            match &stats_sink {
                StatsSink::File(path) => Some(path.as_path()),
                _ => None,
            },
        ];
        for path in own.into_iter().flatten().filter(|p| p.as_os_str() != "-") {
            Staged::new()
                .stage(path, b"")
                .map_err(|e| Failure::Runtime(format!("cannot write {}: {e}", path.display())))?;
        }
    }

    let spec = BatchSpec {
        seeds: match (&args.seeds, args.seed) {
            (Some(set), _) => Some(set.text.clone()),
            (None, Some(s)) => Some(s.to_string()),
            (None, None) => None,
        },
        grid: args
            .grid
            .iter()
            .map(|a| GridSpec {
                name: a.name.clone(),
                values: a.values.clone(),
            })
            .collect(),
        set: args
            .overrides
            .iter()
            .map(|o| format!("{}={}", o.name, o.value))
            .collect(),
        output: output.text().to_string(),
        max_primitives: args.max_primitives,
        max_evaluations: args.max_evaluations,
        max_cells: args.max_cells,
        timeout_seconds: args.timeout,
        ascii: args.write.ascii,
        timings: args.timings,
        up_y: args.write.up == super::Up::Y,
    };
    let context = Context {
        batch,
        programs: &programs,
        inputs: &inputs,
        args: &args,
        want_stats: !matches!(stats_sink, StatsSink::None),
        pretty_stats: matches!(stats_sink, StatsSink::Single(_) | StatsSink::Files(_)),
        mesh_progress: crate::sdf::Progress(Some(&MESH_PROGRESS)),
    };
    // A batch shows variants; a single run that meshes a field for a while
    // shows the blocks meshed.
    let mesh_bar = MeshBar::start(!batch && !args.quiet && std::io::stderr().is_terminal());

    let started = Instant::now();
    let progress = Progress::new(
        batch && !args.quiet && std::io::stderr().is_terminal(),
        variants.len(),
    );
    let mut ndjson = Vec::new();
    let mut stdout_closed = false;
    let entries = run_variants(&context, &variants, &progress, |produced| {
        if let Some(line) = &produced.stats {
            match &stats_sink {
                StatsSink::Stdout if !stdout_closed => {
                    // A reader that went away (`| head`) stops the batch as
                    // --fail-fast would: the rest is not run.
                    stdout_closed = super::write_stdout(format!("{line}\n").as_bytes()).is_err();
                }
                StatsSink::File(_) => {
                    ndjson.extend_from_slice(line.as_bytes());
                    ndjson.push(b'\n');
                }
                _ => {}
            }
        }
        !stdout_closed
    });
    progress.finish();
    drop(mesh_bar);
    let elapsed = started.elapsed();

    if let StatsSink::File(path) = &stats_sink {
        files::write_atomic(path, &ndjson)
            .map_err(|e| Failure::Runtime(format!("cannot write {}: {e}", path.display())))?;
    }

    let (entries, produced): (Vec<VariantEntry>, Vec<Option<Produced>>) =
        entries.into_iter().unzip();
    let summary = Summary::of(&entries);
    let manifest = manifest_path.as_ref().map(|path| {
        let m = make_manifest(&args, &rule_bytes, &inputs, spec, total, entries.clone());
        (path, m)
    });

    if !batch {
        let entry = &entries[0];
        if let Some(err) = &entry.error {
            return Err(Failure::Limit(err.exit_code, err.message.clone()));
        }
        let mut produced = produced;
        let p = produced[0].as_mut().expect("an ok variant was produced");
        let mut staged = p
            .staged
            .take()
            .expect("a single run's outputs wait to be committed");
        let cannot = |path: &Path, e: std::io::Error| {
            Failure::Runtime(format!("cannot write {}: {e}", path.display()))
        };
        let mut print_stats = None;
        if let (StatsSink::Single(target), Some(doc)) = (&stats_sink, &p.stats) {
            match target {
                None => print_stats = Some(doc.clone()),
                Some(path) => staged
                    .stage(path, format!("{doc}\n").as_bytes())
                    .map_err(|e| cannot(path, e))?,
            }
        }
        if let Some(path) = &args.contact_sheet {
            let png = contact_sheet(&args, &variants, &produced)?;
            staged.stage(path, &png).map_err(|e| cannot(path, e))?;
        }
        let mut print_manifest = None;
        if let Some((path, m)) = &manifest {
            if path.as_os_str() == "-" {
                print_manifest = Some(m.to_bytes());
            } else {
                staged
                    .stage(path, &m.to_bytes())
                    .map_err(|e| cannot(path, e))?;
            }
        }
        staged.commit().map_err(|(path, e)| cannot(&path, e))?;
        if let Some(doc) = print_stats {
            super::write_stdout(format!("{doc}\n").as_bytes())?;
        }
        if let Some(bytes) = print_manifest {
            super::write_stdout(&bytes)?;
        }
        let p = produced[0].as_ref().expect("an ok variant was produced");
        if !args.quiet {
            eprintln!(
                "wrote {} ({} vertices, {} faces, seed {})",
                entry.output, p.vertices, p.faces, entry.seed
            );
        }
        return Ok(());
    }

    if let Some(path) = &args.contact_sheet {
        let png = contact_sheet(&args, &variants, &produced)?;
        files::write_atomic(path, &png)
            .map_err(|e| Failure::Runtime(format!("cannot write {}: {e}", path.display())))?;
    }
    if let Some((path, m)) = &manifest {
        manifest::write(path, m)?;
    }
    let first_failure = entries
        .iter()
        .find_map(|e| e.error.as_ref().map(|err| (e, err)));
    if !args.quiet {
        let seconds = elapsed.as_secs_f64();
        eprintln!(
            "{}: {} variants: {} written, {} failed, {} not run{} ({:.2} s, {:.0} variants/s)",
            args.rules.display(),
            entries.len(),
            summary.ok,
            summary.failed,
            summary.not_run,
            manifest_path
                .as_ref()
                .map_or(String::new(), |p| format!("; manifest {}", p.display())),
            seconds,
            entries.len() as f64 / seconds.max(1e-9)
        );
    }
    let exit_code = first_failure.map_or(0, |(_, err)| err.exit_code);
    if args.json {
        let failures: Vec<serde_json::Value> = entries
            .iter()
            .filter_map(|e| {
                e.error.as_ref().map(|err| {
                    serde_json::json!({
                        "index": e.index,
                        "seed": e.seed,
                        "output": e.output,
                        "kind": err.kind,
                        "exit_code": err.exit_code,
                        "message": err.message,
                    })
                })
            })
            .collect();
        let mut doc = serde_json::json!({
            "rules": args.rules.display().to_string(),
            "variants": entries.len(),
            "ok": summary.ok,
            "failed": summary.failed,
            "not_run": summary.not_run,
            "exit_code": exit_code,
            "manifest": manifest_path.as_ref().map(|p| p.display().to_string()),
            "failures": failures,
        });
        if args.timings {
            doc["seconds"] = serde_json::json!(elapsed.as_secs_f64());
        }
        super::write_stdout(format!("{doc}\n").as_bytes())?;
    }
    match first_failure {
        None => Ok(()),
        Some((entry, err)) => Err(Failure::Batch(
            err.exit_code,
            format!(
                "{} of {} variants failed; the first: variant {} (seed {}): {}",
                summary.failed,
                entries.len(),
                entry.index,
                entry.seed,
                err.message
            ),
        )),
    }
}

fn make_manifest(
    args: &RunArgs,
    rule_bytes: &[u8],
    inputs: &files::Inputs,
    batch: BatchSpec,
    total: usize,
    variants: Vec<VariantEntry>,
) -> Manifest {
    Manifest {
        graftal_version: env!("CARGO_PKG_VERSION").to_string(),
        rules: args.rules.display().to_string(),
        rule_sha256: hex(&Sha256::digest(rule_bytes)),
        inputs: inputs
            .hashes
            .iter()
            .map(|(path, sha256)| InputEntry {
                path: path.clone(),
                sha256: sha256.clone(),
            })
            .collect(),
        batch,
        shard: args.shard.map(|s| ShardSpec {
            index: s.index,
            count: s.count,
        }),
        variant_count: total,
        summary: Summary::of(&variants),
        variants,
    }
}

/// Every combination of the grid's values, first axis slowest.
fn grid_combinations(grid: &[GridAxis]) -> Vec<Vec<String>> {
    let mut combos: Vec<Vec<String>> = vec![Vec::new()];
    for axis in grid {
        combos = combos
            .into_iter()
            .flat_map(|c| {
                axis.values.iter().map(move |v| {
                    let mut c = c.clone();
                    c.push(v.clone());
                    c
                })
            })
            .collect();
    }
    combos
}

/// Two variants writing one path would race and lose one of them.
fn check_distinct_paths(
    variants: &[Variant],
    manifest: Option<&Path>,
    stats: &StatsSink,
) -> Result<(), Failure> {
    let mut paths: Vec<(&Path, String)> = Vec::new();
    for v in variants {
        paths.push((
            &v.output,
            format!("the output of variant {} (seed {})", v.index, v.seed),
        ));
        if let Some(s) = &v.stats {
            paths.push((
                s,
                format!("the stats of variant {} (seed {})", v.index, v.seed),
            ));
        }
    }
    if let Some(m) = manifest {
        paths.push((m, "the manifest".to_string()));
    }
    if let StatsSink::File(p) | StatsSink::Single(Some(p)) = stats {
        paths.push((p, "the stats file".to_string()));
    }
    paths.sort_by(|a, b| a.0.cmp(b.0));
    if let Some(w) = paths.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(Failure::Input(format!(
            "{} and {} would both be written to {}; add {{seed}}, {{index}} or a parameter to the template",
            w[0].1,
            w[1].1,
            w[0].0.display()
        )));
    }
    Ok(())
}

struct Context<'a> {
    /// A batch reports each failure as it comes; a single run returns it.
    batch: bool,
    programs: &'a [Program],
    /// The files the programs import, read once.
    inputs: &'a files::Inputs,
    args: &'a RunArgs,
    want_stats: bool,
    /// Stats as pretty documents rather than NDJSON lines.
    pretty_stats: bool,
    /// Where meshers count blocks for the meshing bar of a single run.
    mesh_progress: crate::sdf::Progress,
}

/// Runs every variant on `-j` workers and hands each result to `emit` in
/// index order; returns the manifest entries (with what was produced) in
/// index order, variants never started (`--fail-fast`) as `not_run`.
fn run_variants(
    context: &Context,
    variants: &[Variant],
    progress: &Progress,
    mut emit: impl FnMut(&Produced) -> bool,
) -> Vec<(VariantEntry, Option<Produced>)> {
    let jobs = context
        .args
        .jobs
        .map(|j| j as usize)
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .clamp(1, variants.len().max(1));
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let mut slots: Vec<Option<Produced>> = (0..variants.len()).map(|_| None).collect();
    std::thread::scope(|scope| {
        let (sender, receiver) = mpsc::channel::<(usize, Produced)>();
        for _ in 0..jobs {
            let sender = sender.clone();
            let (next, stop) = (&next, &stop);
            scope.spawn(move || loop {
                if stop.load(Ordering::Relaxed) {
                    break;
                }
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(variant) = variants.get(k) else {
                    break;
                };
                let produced = produce(context, variant);
                if context.args.fail_fast && produced.entry.status == Status::Failed {
                    stop.store(true, Ordering::Relaxed);
                }
                if sender.send((k, produced)).is_err() {
                    break;
                }
            });
        }
        drop(sender);
        let mut emitted = 0;
        let mut warned: BTreeSet<String> = BTreeSet::new();
        for (k, produced) in receiver {
            progress.tick();
            if let (true, Some(err)) = (context.batch, &produced.entry.error) {
                progress.println(&format!(
                    "error: variant {} (seed {}): {}",
                    produced.entry.index, produced.entry.seed, err.message
                ));
            }
            slots[k] = Some(produced);
            while let Some(Some(p)) = slots.get(emitted) {
                // In variant order, so stderr does not depend on -j.
                warn_once(progress, &mut warned, &p.warnings);
                if !emit(p) {
                    stop.store(true, Ordering::Relaxed);
                }
                emitted += 1;
            }
        }
        // After a fail-fast stop, what ran beyond a gap is still reported.
        for p in slots[emitted..].iter().flatten() {
            warn_once(progress, &mut warned, &p.warnings);
            if !emit(p) {
                break;
            }
        }
    });
    variants
        .iter()
        .zip(slots)
        .map(|(v, produced)| match produced {
            Some(p) => (p.entry.clone(), Some(p)),
            None => (entry_for(v, Status::NotRun), None),
        })
        .collect()
}

fn entry_for(v: &Variant, status: Status) -> VariantEntry {
    VariantEntry {
        index: v.index,
        seed: v.seed,
        params: v.params.iter().cloned().collect::<BTreeMap<_, _>>(),
        output: v.output.display().to_string(),
        status,
        bytes: None,
        sha256: None,
        counts: None,
        error: None,
        time_ms: None,
        steps: Vec::new(),
    }
}

/// Runs one variant and writes its files. Never panics on bad geometry or
/// limits: a failure is recorded in the entry.
fn produce(context: &Context, v: &Variant) -> Produced {
    let started = Instant::now();
    let args = context.args;
    let program = &context.programs[v.combo];
    let mut entry = entry_for(v, Status::Ok);
    let fail = |mut entry: VariantEntry, kind: &str, exit_code: u8, message: String| {
        entry.status = Status::Failed;
        entry.error = Some(ErrorEntry {
            kind: kind.to_string(),
            exit_code,
            message,
        });
        entry.time_ms = args.timings.then(|| started.elapsed().as_secs_f64() * 1e3);
        Produced {
            entry,
            stats: None,
            staged: None,
            faces: 0,
            vertices: 0,
            warnings: Vec::new(),
            thumbnail: None,
        }
    };
    let options = RunOptions {
        seed: Some(v.seed),
        max_elements: args.max_primitives,
        max_evaluations: args.max_evaluations,
        deadline: args.timeout.map(|s| started + Duration::from_secs_f64(s)),
        inputs: std::sync::Arc::clone(&context.inputs.meshes),
        max_cells: args.max_cells,
        mesh_progress: context.mesh_progress,
        ..RunOptions::default()
    };
    let mut result = match grammar::run(program, &options) {
        Ok(result) => result,
        Err(e) => {
            let kind = match e.kind {
                RunErrorKind::Failed => "failed",
                RunErrorKind::TooLarge => "too_large",
                RunErrorKind::Timeout => "timeout",
                RunErrorKind::EvaluationLimit => "evaluation_limit",
            };
            return fail(entry, kind, super::run_exit_code(e.kind), e.to_string());
        }
    };
    if !context.want_stats {
        // Nothing but the export reads the kernel mesh from here on: the
        // layers it does not read go before it runs, the rest before the
        // file is encoded, so peak memory is the larger of the mesh and its
        // encoding, not their sum.
        grammar::drop_unexported_layers(&mut result.mesh);
    }
    let indexed = grammar::export(program, &result.mesh);
    let counts = Counts {
        vertices: result.mesh.vert_count(),
        edges: result.mesh.edge_count(),
        faces: result.mesh.face_count(),
    };
    if !context.want_stats {
        result.mesh = crate::kernel::Mesh::default();
    }
    let thumbnail = match args.contact_sheet.is_some().then(|| {
        let options = crate::preview::Options {
            width: args.thumbnail_size,
            height: args.thumbnail_size,
            edges: true,
            ..crate::preview::Options::default()
        };
        super::preview::render(&indexed, &options)
    }) {
        Some(Err(m)) => return fail(entry, "failed", EXIT_RUNTIME, format!("thumbnail: {m}")),
        Some(Ok(image)) => Some(image),
        None => None,
    };
    let encoded = match super::encode_for(&indexed, v.format, &args.write, &v.output) {
        Ok(encoded) => encoded,
        Err(m) => return fail(entry, "failed", EXIT_RUNTIME, m),
    };
    let mut staged = Staged::new();
    if let Err(m) = encoded.stage(&v.output, &mut staged) {
        return fail(entry, "write", EXIT_RUNTIME, m);
    }
    drop(indexed);
    let bytes = encoded.bytes;
    let mesh = &result.mesh;
    entry.bytes = Some(bytes.len() as u64);
    // Hashed only when something records it (a manifest, stats lines, the
    // JSON summary): SHA-256 of a large mesh costs as much as encoding it.
    if context.batch || context.want_stats || args.json {
        entry.sha256 = Some(hex(&Sha256::digest(&bytes)));
    }
    entry.counts = Some(counts);
    entry.steps = steps_json(&result.steps, args.timings);
    let stats = context.want_stats.then(|| {
        let (report, gates) = stats::report_and_gates(mesh, stats::CLOSE_TOLERANCE);
        let doc = stats::run_stats_doc(
            program,
            &result,
            &report,
            &gates,
            encoded.dropped_wire_edges,
            args.timings,
        );
        if context.pretty_stats {
            serde_json::to_string_pretty(&doc)
        } else {
            serde_json::to_string(&stats::VariantLine {
                index: v.index,
                output: &entry.output,
                sha256: entry.sha256.as_deref().unwrap_or_default(),
                stats: doc,
            })
        }
        .expect("stats serialize")
    });
    if let (Some(path), Some(doc)) = (&v.stats, &stats) {
        if let Err(e) = staged.stage(path, format!("{doc}\n").as_bytes()) {
            let m = format!("cannot write {}: {e}", path.display());
            return fail(entry, "write", EXIT_RUNTIME, m);
        }
    }
    // A batch variant's files land together now; a single run's wait for
    // its stats and manifest.
    let staged = if context.batch {
        if let Err((path, e)) = staged.commit() {
            let m = format!("cannot write {}: {e}", path.display());
            return fail(entry, "write", EXIT_RUNTIME, m);
        }
        None
    } else {
        Some(staged)
    };
    entry.time_ms = args.timings.then(|| started.elapsed().as_secs_f64() * 1e3);
    Produced {
        entry,
        stats,
        staged,
        faces: counts.faces,
        vertices: counts.vertices,
        warnings: result.warnings.clone(),
        thumbnail,
    }
}

/// Refuses, before anything runs, a contact sheet that is not a PNG or
/// would exceed the renderer's size limit.
fn check_contact_sheet(path: &Path, tiles: usize, size: u32) -> Result<(), Failure> {
    if !super::preview::has_extension(path, "png") {
        return Err(Failure::Input(format!(
            "--contact-sheet {}: a contact sheet is a PNG; name it *.png",
            path.display()
        )));
    }
    let columns = u64::from(super::preview::sheet_columns(tiles));
    let rows = (tiles as u64).div_ceil(columns);
    let cell = u64::from(size + crate::preview::SHEET_PADDING);
    let pixels = columns * cell * rows * (cell + u64::from(crate::preview::LABEL_HEIGHT));
    if pixels > crate::preview::MAX_SHEET_PIXELS {
        return Err(Failure::Input(format!(
            "--contact-sheet: {tiles} thumbnails of {size} pixels make a sheet of {pixels} pixels, more than {}; use fewer variants or a smaller --thumbnail-size",
            crate::preview::MAX_SHEET_PIXELS
        )));
    }
    Ok(())
}

/// The contact sheet's PNG: one labelled thumbnail per variant, in
/// variant order (a failed variant's tile is blank, labelled "failed").
fn contact_sheet(
    args: &RunArgs,
    variants: &[Variant],
    produced: &[Option<Produced>],
) -> Result<Vec<u8>, Failure> {
    let size = args.thumbnail_size;
    let blank = crate::preview::Image {
        width: size,
        height: size,
        rgba: vec![255; size as usize * size as usize * 4],
    };
    let tiles: Vec<(crate::preview::Image, String)> = variants
        .iter()
        .zip(produced)
        .map(|(v, p)| {
            let mut label = format!("seed {}", v.seed);
            for axis in &args.grid {
                if let Some((_, value)) = v.params.iter().find(|(n, _)| *n == axis.name) {
                    label.push_str(&format!(" {}={value}", axis.name));
                }
            }
            match p.as_ref().and_then(|p| p.thumbnail.clone()) {
                Some(image) => (image, label),
                None => (blank.clone(), format!("{label} failed")),
            }
        })
        .collect();
    let sheet = crate::preview::contact_sheet(&tiles, super::preview::sheet_columns(tiles.len()))
        .map_err(|e| Failure::Runtime(format!("contact sheet: {e}")))?;
    crate::preview::encode_png(&sheet).map_err(|e| Failure::Runtime(e.to_string()))
}

/// Lowercase hexadecimal.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Prints each warning the batch has not printed yet.
fn warn_once(progress: &Progress, warned: &mut BTreeSet<String>, warnings: &[String]) {
    for w in warnings {
        if warned.insert(w.clone()) {
            progress.println(&format!("warning: {w}"));
        }
    }
}

/// The blocks every meshing of this process has announced and meshed.
static MESH_PROGRESS: crate::sdf::MeshProgress = crate::sdf::MeshProgress::new();

/// A bar of blocks meshed, drawn by its own thread once meshing has taken
/// half a second (short runs never show it); cleared when dropped.
struct MeshBar {
    stop: std::sync::Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl MeshBar {
    fn start(show: bool) -> MeshBar {
        let stop = std::sync::Arc::new(AtomicBool::new(false));
        let thread = show.then(|| {
            let stop = std::sync::Arc::clone(&stop);
            std::thread::spawn(move || {
                let started = Instant::now();
                let mut bar: Option<indicatif::ProgressBar> = None;
                while !stop.load(Ordering::Relaxed) {
                    std::thread::sleep(Duration::from_millis(100));
                    let (done, total) = MESH_PROGRESS.get();
                    if total == 0 || started.elapsed() < Duration::from_millis(500) {
                        continue;
                    }
                    let bar = bar.get_or_insert_with(|| {
                        let bar = indicatif::ProgressBar::with_draw_target(
                            Some(total),
                            indicatif::ProgressDrawTarget::stderr(),
                        );
                        if let Ok(style) = indicatif::ProgressStyle::with_template(
                            "{elapsed_precise} [{bar:30}] {pos}/{len} blocks meshed, ETA {eta}",
                        ) {
                            bar.set_style(style.progress_chars("=> "));
                        }
                        bar
                    });
                    bar.set_length(total);
                    bar.set_position(done);
                }
                if let Some(bar) = bar {
                    bar.finish_and_clear();
                }
            })
        });
        MeshBar { stop, thread }
    }
}

impl Drop for MeshBar {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// An indicatif bar on a terminal; nothing otherwise.
struct Progress(Option<indicatif::ProgressBar>);

impl Progress {
    fn new(show: bool, total: usize) -> Progress {
        Progress(show.then(|| {
            let bar = indicatif::ProgressBar::with_draw_target(
                Some(total as u64),
                indicatif::ProgressDrawTarget::stderr(),
            );
            if let Ok(style) = indicatif::ProgressStyle::with_template(
                "{elapsed_precise} [{bar:30}] {pos}/{len} variants, {per_sec}, ETA {eta}",
            ) {
                bar.set_style(style.progress_chars("=> "));
            }
            bar
        }))
    }

    fn tick(&self) {
        if let Some(bar) = &self.0 {
            bar.inc(1);
        }
    }

    fn println(&self, line: &str) {
        match &self.0 {
            Some(bar) => bar.println(line),
            None => eprintln!("{line}"),
        }
    }

    fn finish(&self) {
        if let Some(bar) = &self.0 {
            bar.finish_and_clear();
        }
    }
}
