//! The command line: `run`, `check`, `info`, `convert`.
//!
//! Exit codes: 0 success; 1 runtime failure (a step failed, an output could
//! not be written); 2 usage error, bad rule file or bad input mesh.
//! Outputs are written atomically: a temporary file, then a rename.

mod batch;
mod manifest;
mod stats;
mod tooling;
mod verify;

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::grammar;
use crate::io::{self, bridge};
use crate::rules::{self, Override, RuleError};

/// Exit status for a failure at run time.
pub const EXIT_RUNTIME: u8 = 1;
/// Exit code when the model outgrows `--max-primitives` (runaway growth).
pub const EXIT_TOO_LARGE: u8 = 3;
/// Exit code when a variant runs past `--timeout`.
pub const EXIT_TIMEOUT: u8 = 4;
/// Exit code when a variant evaluates more than `--max-evaluations`.
pub const EXIT_EVALUATIONS: u8 = 5;
/// Exit status for usage errors, bad rule files and bad input meshes.
pub const EXIT_INPUT: u8 = 2;

#[derive(Parser, Debug)]
#[command(
    name = "graftal",
    version,
    about = "Deterministic batch generator of 3D meshes from rule files"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Run a rule file and write the mesh (format from OUT's extension),
    /// or a batch of variants (`--seeds`, `--grid`).
    Run {
        /// Rule file (.toml or .ron).
        rules: PathBuf,
        /// Output mesh: .obj, .gltf, .glb, .stl (binary), .ply (binary).
        /// A template: `{name}`, `{seed}`, `{index}` and parameter names
        /// are filled in per variant (`{seed:04}` zero-pads). Defaults to
        /// `{name}.obj`; in a batch `{name}-{seed}.obj` (with a grid
        /// `{name}-{index}.obj`).
        #[arg(short, long, value_name = "OUT")]
        output: Option<String>,
        /// Seed for every random draw (default: the file's `seed`, else 0).
        #[arg(long, conflicts_with = "seeds")]
        seed: Option<u64>,
        /// A batch over seeds: `0..1000` (end excluded), `0..=999`, `1,5,9`
        /// or a mix (`0..10,100`).
        #[arg(long, value_name = "RANGE", value_parser = batch::SeedSet::parse)]
        seeds: Option<batch::SeedSet>,
        /// Override a parameter: `--set name=value` (a number or expression).
        #[arg(long = "set", value_name = "NAME=VALUE", value_parser = parse_override)]
        overrides: Vec<Override>,
        /// A parameter grid axis: `--grid name=v1,v2,v3`; several axes and
        /// `--seeds` make a cartesian product (first axis slowest, seeds
        /// fastest).
        #[arg(long = "grid", value_name = "NAME=V1,V2,...", value_parser = batch::GridAxis::parse)]
        grid: Vec<batch::GridAxis>,
        /// Variants run at once (default: every core). Never changes a byte.
        #[arg(short = 'j', long = "jobs", value_name = "N", value_parser = clap::value_parser!(u64).range(1..=1024))]
        jobs: Option<u64>,
        /// Run only shard I of N (0-based: variants whose index is I mod N)
        /// and write a shard manifest for `graftal manifest merge`.
        #[arg(long, value_name = "I/N", value_parser = batch::Shard::parse)]
        shard: Option<batch::Shard>,
        /// Batch manifest path (default: `manifest.json` in the output
        /// template's directory; `manifest.shard-I-of-N.json` for a shard).
        #[arg(long, value_name = "FILE")]
        manifest: Option<PathBuf>,
        /// Write run statistics as JSON to FILE, or `-` for standard output.
        /// In a batch: `-` streams NDJSON (one line per variant, in index
        /// order), a path with `{...}` fields writes one file per variant,
        /// any other path gets the NDJSON.
        #[arg(long, value_name = "FILE")]
        stats: Option<String>,
        /// Include wall-clock times in the stats and manifest (makes them
        /// differ run to run).
        #[arg(long)]
        timings: bool,
        /// Stop (exit code 3, no output) when the model would exceed this
        /// many primitives (vertices + edges + faces).
        #[arg(long, visible_alias = "max-elements", default_value_t = grammar::DEFAULT_MAX_ELEMENTS, value_name = "N")]
        max_primitives: usize,
        /// Stop (exit code 5, no output) after this many evaluations of
        /// conditions and per-primitive parameters.
        #[arg(long, default_value_t = grammar::DEFAULT_MAX_EVALUATIONS, value_name = "N")]
        max_evaluations: u64,
        /// Stop a variant (exit code 4, no output) after SECONDS of wall
        /// clock.
        #[arg(long, value_name = "SECONDS", value_parser = parse_timeout)]
        timeout: Option<f64>,
        /// Stop starting variants after the first failure.
        #[arg(long)]
        fail_fast: bool,
        /// No progress bar, no summary, no "wrote" line (errors still go to
        /// standard error).
        #[arg(short, long)]
        quiet: bool,
        /// Print a machine-readable summary of the batch on standard output.
        #[arg(long)]
        json: bool,
        /// Text-format variants: write STL and PLY as ASCII.
        #[arg(long)]
        ascii: bool,
    },
    /// Parse and compile a rule file without running it.
    Check {
        rules: PathBuf,
        #[arg(long = "set", value_name = "NAME=VALUE", value_parser = parse_override)]
        overrides: Vec<Override>,
    },
    /// Describe a mesh file: counts, bounds, area, volume, manifoldness.
    Info {
        mesh: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
        /// Report vertex pairs at most this far apart (model units).
        #[arg(long, default_value_t = stats::CLOSE_TOLERANCE, value_parser = parse_tolerance)]
        tolerance: f64,
    },
    /// Regenerate rule files and compare with stored goldens (stats JSON,
    /// and OBJ meshes where present); exit 1 on a difference.
    Verify {
        /// Directory of goldens: `<stem>.json` (and optionally `<stem>.obj`)
        /// per rule file, `<stem>-<seed>.*` with `--seeds`.
        #[arg(long, value_name = "DIR")]
        golden: PathBuf,
        /// Rule files to regenerate.
        #[arg(required = true)]
        rules: Vec<PathBuf>,
        /// Verify these seeds of each file (default: the file's seed).
        #[arg(long, value_name = "RANGE", value_parser = batch::SeedSet::parse)]
        seeds: Option<batch::SeedSet>,
        #[arg(long = "set", value_name = "NAME=VALUE", value_parser = parse_override)]
        overrides: Vec<Override>,
        /// Absolute tolerance for floats.
        #[arg(long, default_value_t = 0.0, value_parser = parse_tolerance)]
        abs_tol: f64,
        /// Relative tolerance for floats.
        #[arg(long, default_value_t = 0.0, value_parser = parse_tolerance)]
        rel_tol: f64,
        /// Rewrite the goldens with the current output instead of comparing.
        #[arg(long)]
        bless: bool,
        /// With --bless: write only the stats goldens, no OBJ meshes.
        #[arg(long, requires = "bless")]
        stats_only: bool,
        /// No success line.
        #[arg(short, long)]
        quiet: bool,
    },
    /// Batch manifests: `graftal manifest merge SHARD... -o OUT`.
    Manifest {
        #[command(subcommand)]
        action: ManifestAction,
    },
    /// Convert a mesh between formats (by extension).
    Convert {
        input: PathBuf,
        output: PathBuf,
        /// Write STL and PLY as ASCII.
        #[arg(long)]
        ascii: bool,
    },
    /// Print the JSON Schema of rule files (for editors; see docs/tooling.md).
    Schema,
    /// Check rule files for likely mistakes: undefined names, unused
    /// parameters, rules and compounds, probabilities outside [0, 1],
    /// conditions that can never (or always) match. Exit 0 clean, 1 with
    /// warnings, 2 when a file does not compile.
    Lint {
        /// Rule files (.toml or .ron).
        #[arg(required = true)]
        rules: Vec<PathBuf>,
        #[arg(long = "set", value_name = "NAME=VALUE", value_parser = parse_override)]
        overrides: Vec<Override>,
        /// Do not report findings with this code (repeatable).
        #[arg(long, value_name = "CODE", value_parser = clap::builder::PossibleValuesParser::new(crate::rules::lint::CODES))]
        allow: Vec<String>,
    },
    /// Run a rule file without writing a mesh and tell, per step, what it
    /// matched, what it applied to, and why the rest was not.
    Explain {
        rules: PathBuf,
        #[arg(long)]
        seed: Option<u64>,
        #[arg(long = "set", value_name = "NAME=VALUE", value_parser = parse_override)]
        overrides: Vec<Override>,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
        #[arg(long, default_value_t = grammar::DEFAULT_MAX_ELEMENTS, value_name = "N")]
        max_primitives: usize,
    },
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell).
    Completions {
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
    /// Print the man page (roff), or write one page per command to DIR.
    Man {
        #[arg(long, value_name = "DIR")]
        dir: Option<PathBuf>,
    },
}

#[derive(Subcommand, Debug)]
pub enum ManifestAction {
    /// Combine the shard manifests of one batch (`run --shard i/n`) into
    /// the manifest the unsharded batch writes, byte for byte.
    Merge {
        /// Every shard's manifest, in any order.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// The merged manifest (`-` or omitted: standard output).
        #[arg(short, long, value_name = "FILE")]
        output: Option<PathBuf>,
    },
}

fn parse_override(text: &str) -> Result<Override, String> {
    Override::parse(text)
}

/// Entry point used by `main`: parses arguments, runs, maps errors to exit codes.
pub fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(err) => {
            let _ = err.print();
            return ExitCode::from(if err.use_stderr() { EXIT_INPUT } else { 0 });
        }
    };
    match execute(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            failure.report();
            ExitCode::from(failure.code())
        }
    }
}

/// Why a command failed.
pub enum Failure {
    Rule(Box<RuleError>),
    Input(String),
    Runtime(String),
    /// A run stopped with its own exit code (a limit, or a failed step).
    Limit(u8, String),
    /// Variants of a batch failed; the code is the first failure's.
    Batch(u8, String),
}

impl Failure {
    fn code(&self) -> u8 {
        match self {
            Failure::Rule(_) | Failure::Input(_) => EXIT_INPUT,
            Failure::Runtime(_) => EXIT_RUNTIME,
            Failure::Limit(code, _) | Failure::Batch(code, _) => *code,
        }
    }

    fn report(&self) {
        let mut err = std::io::stderr().lock();
        match self {
            Failure::Rule(e) => {
                let _ = writeln!(err, "error: {}", e.headline());
                let theme =
                    if std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none() {
                        miette::GraphicalTheme::unicode()
                    } else {
                        miette::GraphicalTheme::unicode_nocolor()
                    };
                let mut rendered = String::new();
                let handler = miette::GraphicalReportHandler::new_themed(theme);
                if handler
                    .render_report(&mut rendered, e.as_ref() as &dyn miette::Diagnostic)
                    .is_ok()
                {
                    let _ = write!(err, "{rendered}");
                }
            }
            Failure::Input(m)
            | Failure::Runtime(m)
            | Failure::Limit(_, m)
            | Failure::Batch(_, m) => {
                let _ = writeln!(err, "error: {m}");
            }
        }
    }
}

impl From<RuleError> for Failure {
    fn from(e: RuleError) -> Self {
        Failure::Rule(Box::new(e))
    }
}

fn output_format(path: &Path, ascii: bool) -> Result<io::MeshFormat, Failure> {
    let format = io::MeshFormat::from_path(path).map_err(|e| Failure::Input(e.to_string()))?;
    Ok(match (format, ascii) {
        (io::MeshFormat::StlBinary, true) => io::MeshFormat::StlAscii,
        (io::MeshFormat::PlyBinary, true) => io::MeshFormat::PlyAscii,
        (f, _) => f,
    })
}

fn write_output(
    path: &Path,
    format: io::MeshFormat,
    mesh: &io::IndexedMesh,
) -> Result<(), Failure> {
    let bytes = io::encode(mesh, format)
        .map_err(|e| Failure::Runtime(format!("{}: {e}", path.display())))?;
    io::atomic::write_atomic(path, &bytes)
        .map_err(|e| Failure::Runtime(format!("cannot write {}: {e}", path.display())))
}

pub fn execute(command: Command) -> Result<(), Failure> {
    match command {
        Command::Run {
            rules,
            output,
            seed,
            seeds,
            overrides,
            grid,
            jobs,
            shard,
            manifest,
            stats,
            timings,
            max_primitives,
            max_evaluations,
            timeout,
            fail_fast,
            quiet,
            json,
            ascii,
        } => batch::run(batch::RunArgs {
            rules,
            output,
            seed,
            seeds,
            overrides,
            grid,
            jobs: jobs.map(|j| j as usize),
            shard,
            manifest,
            stats,
            timings,
            max_primitives,
            max_evaluations,
            timeout,
            fail_fast,
            quiet,
            json,
            ascii,
        }),
        Command::Verify {
            golden,
            rules,
            seeds,
            overrides,
            abs_tol,
            rel_tol,
            bless,
            stats_only,
            quiet,
        } => verify::verify(verify::VerifyArgs {
            golden,
            rules,
            seeds,
            overrides,
            abs_tol,
            rel_tol,
            bless,
            stats_only,
            quiet,
        }),
        Command::Manifest {
            action: ManifestAction::Merge { shards, output },
        } => {
            let merged = manifest::merge(&shards)?;
            manifest::write(output.as_deref().unwrap_or(Path::new("-")), &merged)
        }
        Command::Check { rules, overrides } => {
            let program = rules::compile_file(&rules, &overrides)?;
            println!(
                "{}: ok ({} parameters, {} steps)",
                program.file,
                program.param_names.len(),
                program.steps.len()
            );
            Ok(())
        }
        Command::Info {
            mesh,
            json,
            tolerance,
        } => {
            let indexed = io::read_mesh(&mesh).map_err(|e| Failure::Input(e.to_string()))?;
            let (kernel_mesh, import) = bridge::mesh_from_indexed_report(&indexed)
                .map_err(|e| Failure::Input(format!("{}: {e}", mesh.display())))?;
            let report = kernel_mesh.report();
            let gates = stats::gates(&kernel_mesh, tolerance);
            if json {
                println!("{}", stats::info_json(&mesh, &report, &gates, &import));
            } else {
                print!("{}", stats::info_text(&mesh, &report, &gates, &import));
            }
            Ok(())
        }
        Command::Convert {
            input,
            output,
            ascii,
        } => {
            let format = output_format(&output, ascii)?;
            let indexed = io::read_mesh(&input).map_err(|e| Failure::Input(e.to_string()))?;
            write_output(&output, format, &indexed)
        }
        Command::Schema => tooling::schema(),
        Command::Lint {
            rules,
            overrides,
            allow,
        } => tooling::lint(&rules, &overrides, &allow),
        Command::Explain {
            rules,
            seed,
            overrides,
            json,
            max_primitives,
        } => tooling::explain(&rules, seed, &overrides, json, max_primitives),
        Command::Completions { shell } => tooling::completions(shell),
        Command::Man { dir } => tooling::man(dir.as_deref()),
    }
}

/// The exit code of a failed run: 1, or the code of the limit it hit.
pub(crate) fn run_exit_code(kind: grammar::RunErrorKind) -> u8 {
    match kind {
        grammar::RunErrorKind::Failed => EXIT_RUNTIME,
        grammar::RunErrorKind::TooLarge => EXIT_TOO_LARGE,
        grammar::RunErrorKind::Timeout => EXIT_TIMEOUT,
        grammar::RunErrorKind::EvaluationLimit => EXIT_EVALUATIONS,
    }
}

/// Seconds for `--timeout`: finite and positive.
fn parse_timeout(text: &str) -> Result<f64, String> {
    let value: f64 = text
        .parse()
        .map_err(|_| format!("`{text}` is not a number of seconds"))?;
    if value.is_finite() && value > 0.0 && value < 1e9 {
        Ok(value)
    } else {
        Err(format!("must be a positive number of seconds, got {text}"))
    }
}

/// A distance for `--tolerance`: finite and not negative.
fn parse_tolerance(text: &str) -> Result<f64, String> {
    let value: f64 = text
        .parse()
        .map_err(|_| format!("`{text}` is not a number"))?;
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(format!("must be finite and not negative, got {text}"))
    }
}
