//! The first stage of `graftal run`: everything the batch needs before a
//! variant runs. The rule file is read once and compiled per grid
//! combination, its imports read once; every variant's output, stats path,
//! resume candidate and cache key is known; every bad input (templates,
//! shards, clashing paths, an unwritable manifest) is refused here, so a
//! batch that starts does not fail for a reason it could have seen.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Serialize;
use sha2::{Digest, Sha256};

use super::spec::{FieldValue, GridAxis, Shard, Template, MAX_VARIANTS};
use super::RunArgs;
use crate::cli::files::{self, cache::Cache, journal, Inputs, Staged};
use crate::cli::manifest::{
    BatchSpec, GridSpec, InputEntry, Manifest, ShardSpec, Status, Summary, VariantEntry,
};
use crate::cli::{output_format, Failure};
use crate::grammar;
use crate::io::MeshFormat;
use crate::rules::{compile_source, Override, Program};

/// Where a variant's statistics go.
pub(super) enum StatsSink {
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

impl StatsSink {
    fn is_ndjson(&self) -> bool {
        matches!(self, StatsSink::Stdout | StatsSink::File(_))
    }
}

/// One variant, all its paths known.
pub(super) struct Variant {
    pub index: usize,
    /// Which grid combination (and so which program) it runs.
    pub combo: usize,
    pub seed: u64,
    pub params: Vec<(String, f64)>,
    pub output: PathBuf,
    pub format: MeshFormat,
    pub stats: Option<PathBuf>,
    /// What an earlier run of the batch recorded for it (`--resume`):
    /// reused if its files still check out.
    pub prior: Option<VariantEntry>,
    /// Its content address (`--cache`).
    pub cache_key: Option<String>,
}

/// Everything resolved; the later stages only read it.
pub(super) struct Plan<'a> {
    pub args: &'a RunArgs,
    pub batch: bool,
    pub programs: Vec<Program>,
    /// The files the programs import, read once.
    pub inputs: Inputs,
    pub stats_sink: StatsSink,
    pub variants: Vec<Variant>,
    pub manifest_path: Option<PathBuf>,
    /// The manifest without variants: what identifies the batch (the
    /// journal's header, and what a resumed manifest must match).
    pub identity: Manifest,
    pub cache: Option<Cache>,
}

impl Plan<'_> {
    /// Stats are computed for every variant.
    pub fn want_stats(&self) -> bool {
        !matches!(self.stats_sink, StatsSink::None)
    }

    /// The manifest of this batch with `variants`.
    pub fn manifest(&self, variants: Vec<VariantEntry>) -> Manifest {
        Manifest {
            summary: Summary::of(&variants),
            variants,
            ..self.identity.clone()
        }
    }
}

pub(super) fn resolve(args: &RunArgs) -> Result<Plan<'_>, Failure> {
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
    let shard = args
        .shard
        .map(|s| s.resolve(&|name| std::env::var(name).ok()))
        .transpose()
        .map_err(Failure::Input)?;

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
    let rule_file = files::read_rules(&args.rules)?;
    let base_dir = files::base_dir(&args.rules);
    let combos: Vec<Vec<Override>> = grid_combinations(&args.grid)
        .into_iter()
        .map(|combo| {
            let mut overrides = args.overrides.clone();
            overrides.extend(args.grid.iter().zip(combo).map(|(axis, value)| Override {
                name: axis.name.clone(),
                value,
            }));
            overrides
        })
        .collect();
    let programs = combos
        .iter()
        .map(|overrides| compile_source(&rule_file, overrides, &base_dir))
        .collect::<Result<Vec<Program>, _>>()?;
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
        if shard.is_some_and(|s| index % s.count != s.index) {
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
            prior: None,
            cache_key: None,
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
            let file = match shard {
                Some(s) => format!("manifest.shard-{}-of-{}.json", s.index, s.count),
                None => "manifest.json".to_string(),
            };
            Some(dir.join(file))
        }
    };
    check_distinct_paths(&variants, manifest_path.as_deref(), &stats_sink)?;
    if let Some(sheet) = &args.contact_sheet {
        super::report::check_contact_sheet(sheet, variants.len(), args.thumbnail_size)?;
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

    let identity = Manifest {
        graftal_version: env!("CARGO_PKG_VERSION").to_string(),
        rules: args.rules.display().to_string(),
        rule_sha256: files::hex(&Sha256::digest(rule_file.text.as_bytes())),
        inputs: inputs
            .hashes
            .iter()
            .map(|(path, sha256)| InputEntry {
                path: path.clone(),
                sha256: sha256.clone(),
            })
            .collect(),
        batch: batch_spec(args, &output),
        shard: shard.map(|s| ShardSpec {
            index: s.index,
            count: s.count,
        }),
        variant_count: total,
        summary: Summary::default(),
        variants: Vec::new(),
    };

    if args.resume {
        offer_priors(
            args,
            batch,
            &stats_sink,
            manifest_path.as_deref(),
            &identity,
            &mut variants,
        )?;
    }

    let cache = match &args.cache {
        None => None,
        Some(dir) => {
            let cache = Cache::open(dir, args.cache_max_size)
                .map_err(|e| Failure::Runtime(format!("--cache {}: {e}", dir.display())))?;
            // Times differ run to run: a run that records them neither
            // reads nor fills the cache.
            if !args.timings {
                let build = files::executable_sha256().map_err(|e| {
                    Failure::Runtime(format!("--cache: cannot hash graftal itself: {e}"))
                })?;
                let rule_path = args.rules.display().to_string();
                for v in &mut variants {
                    v.cache_key = Some(cache_key(&KeyParts {
                        store: files::cache::STORE_NAME,
                        graftal: env!("CARGO_PKG_VERSION"),
                        build: &build,
                        rules: &rule_path,
                        rule_sha256: &identity.rule_sha256,
                        inputs: &identity.inputs,
                        overrides: combos[v.combo]
                            .iter()
                            .map(|o| format!("{}={}", o.name, o.value))
                            .collect(),
                        params: v.params.iter().cloned().collect(),
                        seed: v.seed,
                        format: format!("{:?}", v.format),
                        obj_name: (v.format == MeshFormat::Obj)
                            .then(|| {
                                v.output
                                    .file_name()
                                    .map(|n| n.to_string_lossy().into_owned())
                            })
                            .flatten(),
                        ascii: args.write.ascii,
                        up: format!("{:?}", args.write.up),
                        skeleton: format!("{:?}", args.write.skeleton),
                        tube_radius: args.write.tube_radius,
                        strict: args.write.strict,
                        max_primitives: args.max_primitives,
                        max_evaluations: args.max_evaluations,
                        max_cells: args.max_cells,
                        allow_outside_paths: args.input.allow_outside_paths,
                    }));
                }
            }
            Some(cache)
        }
    };

    Ok(Plan {
        args,
        batch,
        programs,
        inputs,
        stats_sink,
        variants,
        manifest_path,
        identity,
        cache,
    })
}

/// What the batch was asked to make, as the manifest records it.
fn batch_spec(args: &RunArgs, output: &Template) -> BatchSpec {
    BatchSpec {
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
        up_y: args.write.up == crate::cli::Up::Y,
    }
}

/// Everything that decides a variant's bytes, hashed into its cache key.
/// Not the timeout (it decides whether a variant finishes, never what
/// it writes) nor `-j`.
#[derive(Serialize)]
struct KeyParts<'a> {
    store: &'a str,
    graftal: &'a str,
    /// SHA-256 of the executable: a rebuilt graftal is another graftal.
    build: &'a str,
    /// The rule file as named (the stats record it).
    rules: &'a str,
    rule_sha256: &'a str,
    inputs: &'a [InputEntry],
    overrides: Vec<String>,
    params: BTreeMap<String, f64>,
    seed: u64,
    format: String,
    /// An OBJ names its `.mtl` after itself.
    obj_name: Option<String>,
    ascii: bool,
    up: String,
    skeleton: String,
    tube_radius: Option<f64>,
    strict: bool,
    max_primitives: usize,
    max_evaluations: u64,
    max_cells: u64,
    allow_outside_paths: bool,
}

fn cache_key(parts: &KeyParts) -> String {
    let text = serde_json::to_vec(parts).expect("cache key parts serialize");
    files::hex(&Sha256::digest(&text))
}

/// `--resume`: reads what an earlier run of this batch recorded — its
/// manifest, then the journal a killed run leaves — and offers each
/// variant recorded ok with the same seed, parameters and output as a
/// candidate; the workers check its files.
fn offer_priors(
    args: &RunArgs,
    batch: bool,
    stats_sink: &StatsSink,
    manifest_path: Option<&Path>,
    identity: &Manifest,
    variants: &mut [Variant],
) -> Result<(), Failure> {
    let refuse = |why: &str| Err(Failure::Input(format!("--resume: {why}")));
    let manifest_path = match manifest_path {
        Some(p) if batch && p.as_os_str() != "-" => p,
        _ => return refuse(
            "resuming needs a batch manifest file (--seeds, --grid, --shard or --manifest FILE)",
        ),
    };
    if stats_sink.is_ndjson() {
        return refuse("the NDJSON stats of the variants it skips are not kept; write one stats file per variant (--stats 'stats/{name}-{seed}.json'), which resuming checks like the outputs");
    }
    if args.contact_sheet.is_some() {
        return refuse("a contact sheet needs every variant's mesh; make the sheet in a separate run (or with graftal preview)");
    }
    let mut priors: BTreeMap<usize, VariantEntry> = BTreeMap::new();
    let warn = |what: &Path, why: String| {
        eprintln!(
            "warning: --resume: {}: {why}; nothing taken from it",
            what.display()
        );
    };
    match files::read_json_text(manifest_path) {
        Ok(None) => {}
        Ok(Some(text)) => match Manifest::parse(manifest_path, &text) {
            Ok(m) => match identity.same_batch(&m) {
                None => priors.extend(m.variants.into_iter().map(|v| (v.index, v))),
                Some(field) => warn(manifest_path, format!("a different batch ({field})")),
            },
            Err(_) => warn(manifest_path, "not a manifest".into()),
        },
        Err(e) => warn(manifest_path, e.to_string()),
    }
    let journal_path = journal::path_for(manifest_path);
    match journal::read(&journal_path) {
        Ok(None) => {}
        Ok(Some((header, lines))) => {
            match serde_json::from_str::<Manifest>(&header)
                .ok()
                .map(|m| identity.same_batch(&m))
            {
                Some(None) => {
                    // Later lines are newer; a line that does not parse
                    // was not written whole.
                    for line in lines {
                        if let Ok(v) = serde_json::from_str::<VariantEntry>(&line) {
                            priors.insert(v.index, v);
                        }
                    }
                }
                Some(Some(field)) => warn(&journal_path, format!("a different batch ({field})")),
                None => warn(&journal_path, "not a graftal journal".into()),
            }
        }
        Err(e) => warn(&journal_path, e.to_string()),
    }
    for v in variants {
        let Some(prior) = priors.remove(&v.index) else {
            continue;
        };
        let params: BTreeMap<String, f64> = v.params.iter().cloned().collect();
        let same = prior.status == Status::Ok
            && prior.seed == v.seed
            && prior.params == params
            && Path::new(&prior.output) == v.output
            && prior.sha256.is_some();
        if same {
            v.prior = Some(prior);
        }
    }
    Ok(())
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

/// The key of one shard in a scheduler's terms, for messages.
pub(super) fn describe_shard(shard: Option<Shard>) -> String {
    shard.map_or_else(String::new, |s| format!(" (shard {}/{})", s.index, s.count))
}
