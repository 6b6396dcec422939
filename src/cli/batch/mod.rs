//! `graftal run`: one variant or a batch of them.
//!
//! A batch is the cartesian product of `--grid` values (first axis
//! slowest) with `--seeds` (fastest); variant `index` counts through it.
//! Everything a variant writes depends only on its rule file, overrides and
//! seed — never on `-j`, on scheduling or on which other variants run — so
//! workers take variants in any order, and whatever is reported in order
//! (NDJSON stats, the manifest) is put back in index order first.
//!
//! Three stages: [`resolve`] (inputs read once, programs compiled, every
//! variant's paths, resume candidates and cache keys known before anything
//! runs, every bad input refused), [`execute`] (variants on `-j` workers:
//! resumed, restored from the cache, or generated) and [`report`] (the
//! batch's own files, the summary, the exit code). [`spec`] parses what
//! the user typed.

mod execute;
mod report;
mod resolve;
mod spec;

use std::path::PathBuf;

pub use spec::{GridAxis, SeedSet, Shard, ShardArg};

use super::{files, Failure};
use crate::rules::Override;

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
    /// and write a shard manifest for `graftal manifest merge`. `auto`
    /// takes I and N from a Slurm job array, `auto/N` the index from a
    /// Kubernetes Indexed Job (`JOB_COMPLETION_INDEX`); `GRAFTAL_SHARD=I/N`
    /// serves any other scheduler.
    #[arg(long, value_name = "I/N|auto|auto/N", value_parser = ShardArg::parse)]
    pub shard: Option<ShardArg>,
    /// Skip the variants an earlier run of this batch already wrote: each
    /// one its manifest (or, after a kill, its journal) records as ok whose
    /// files are still there with their recorded sizes and SHA-256. The
    /// manifest written is the same bytes a fresh run writes.
    #[arg(long)]
    pub resume: bool,
    /// Content-addressed cache of outputs: a variant whose inputs (build,
    /// rule file and the files it reads, overrides, seed, format, limits)
    /// were made before is restored, hash-checked, instead of generated.
    /// Never changes an output byte or the manifest; safe to share between
    /// concurrent runs.
    #[arg(long, value_name = "DIR")]
    pub cache: Option<PathBuf>,
    /// Bound of the cache's size (least recently used entries go first):
    /// bytes or K, M, G, T (powers of 1024).
    #[arg(long, value_name = "SIZE", default_value = "10G", value_parser = files::cache::parse_size, requires = "cache")]
    pub cache_max_size: u64,
    /// Remove graftal temporary files at least AGE old (`30m`, `2h`, `7d`)
    /// from the folders this run writes to: the leftovers of killed runs.
    /// Without it they are only reported; a live writer's file is never
    /// that old.
    #[arg(long, value_name = "AGE", value_parser = files::parse_age)]
    pub remove_stale_temps: Option<std::time::Duration>,
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

pub fn run(args: RunArgs) -> Result<(), Failure> {
    files::set_stale_policy(files::StalePolicy {
        remove_older_than: args.remove_stale_temps,
    });
    let plan = resolve::resolve(&args)?;
    let done = execute::execute(&plan);
    report::report(&plan, done)
}
