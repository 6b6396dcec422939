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
    Run(batch::RunArgs),
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
    Verify(verify::VerifyArgs),
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
        Command::Run(args) => batch::run(args),
        Command::Verify(args) => verify::verify(args),
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
