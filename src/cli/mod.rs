//! The command line, and the only code that touches files.
//!
//! Commands: `run` (one variant or a batch: [`batch`]), `check`, `info`,
//! `convert`, `verify` (golden checks: [`verify`]), `manifest merge` and
//! `manifest check` ([`manifest`]), `clean`, `lint`, `explain`, `schema`,
//! `completions`, `man` ([`tooling`]). [`files`] reads inputs (regular
//! files only, size-limited, references confined to their directory) and
//! writes outputs (all of a run's or none), the resume journal and the
//! cache; [`stats`] renders stats and mesh reports.
//!
//! Exit codes: 0 success (also when standard output is closed early); 1
//! runtime failure (a step failed, an output could not be written, a format
//! could not hold the mesh under `--strict`); 2 usage error, bad rule file
//! or bad input file; 3 over `--max-primitives`; 4 over `--timeout`; 5 over
//! `--max-evaluations`.

mod batch;
mod files;
mod manifest;
mod preview;
mod stats;
mod tooling;
mod verify;

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::grammar;
use crate::io;
use crate::rules::{Override, RuleError};

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
    Run(Box<batch::RunArgs>),
    /// Parse and compile a rule file, and read the files it imports,
    /// without running it.
    Check {
        rules: PathBuf,
        #[arg(long = "set", value_name = "NAME=VALUE", value_parser = parse_override)]
        overrides: Vec<Override>,
        #[command(flatten)]
        input: InputArgs,
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
        #[command(flatten)]
        input: InputArgs,
    },
    /// Regenerate rule files and compare with stored goldens (stats JSON,
    /// and OBJ meshes where present); exit 1 on a difference.
    Verify(verify::VerifyArgs),
    /// Batch manifests: `graftal manifest merge SHARD... -o OUT`,
    /// `graftal manifest check MANIFEST`.
    Manifest {
        #[command(subcommand)]
        action: ManifestAction,
    },
    /// Remove the temporary files runs that were killed left in output
    /// folders (`.NAME.graftal-….tmp`). Only when no run writes there,
    /// or with `--older-than`: graftal never removes another writer's
    /// temporary files by itself.
    Clean {
        /// Folders to clean (searched recursively).
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Only files at least this old: `30m`, `2h`, `7d`, or seconds.
        #[arg(long, value_name = "AGE", value_parser = files::parse_age)]
        older_than: Option<std::time::Duration>,
        /// List what would be removed, remove nothing.
        #[arg(long)]
        dry_run: bool,
        /// No list, only errors.
        #[arg(short, long)]
        quiet: bool,
    },
    /// Convert a mesh between formats (by extension).
    Convert {
        #[arg(value_name = "INPUT")]
        source: PathBuf,
        output: PathBuf,
        #[command(flatten)]
        write: WriteArgs,
        #[command(flatten)]
        input: InputArgs,
    },
    /// Render a shaded PNG of a mesh file or of what a rule file makes.
    Preview(preview::PreviewArgs),
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
        #[command(flatten)]
        input: InputArgs,
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
    /// Exits 1 when a variant failed or did not run (the manifest is
    /// written all the same), unless `--allow-failed`.
    Merge {
        /// Every shard's manifest, in any order.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// The merged manifest (`-` or omitted: standard output).
        #[arg(short, long, value_name = "FILE")]
        output: Option<PathBuf>,
        /// Exit 0 even when variants failed or did not run.
        #[arg(long)]
        allow_failed: bool,
    },
    /// Check that every file a manifest lists exists with its recorded
    /// size and SHA-256 (paths from the current directory, as the batch
    /// wrote them); names each one that does not and exits 1. Failed and
    /// not-run variants are problems too, unless `--allow-failed`.
    Check {
        manifest: PathBuf,
        /// Failed and not-run variants are no problem.
        #[arg(long)]
        allow_failed: bool,
        /// No success line.
        #[arg(short, long)]
        quiet: bool,
    },
}

/// How input files are read (`check`, `run`, `info`, `convert`, `explain`).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct InputArgs {
    /// Follow file references that leave the directory of the file that
    /// makes them (absolute paths, `..`, symbolic links out): a rule
    /// file's imports, a `.gltf`'s buffers. Off by default, so a file
    /// from elsewhere cannot make graftal read arbitrary files.
    #[arg(long)]
    pub allow_outside_paths: bool,
    /// Merge vertices at most DISTANCE apart after reading a mesh (0, the
    /// default when the flag has no value, merges identical positions):
    /// for files with one vertex per face corner, such as OBJ and PLY
    /// exported after a glTF import. Off by default.
    #[arg(long, value_name = "DISTANCE", num_args = 0..=1, default_missing_value = "0", value_parser = parse_tolerance)]
    pub weld: Option<f64>,
}

impl InputArgs {
    pub(crate) fn policy(&self) -> files::InputPolicy {
        files::InputPolicy {
            allow_outside: self.allow_outside_paths,
        }
    }

    /// Reads a mesh file as these options say.
    fn read_mesh(&self, path: &Path) -> Result<io::IndexedMesh, Failure> {
        let mesh = files::read_mesh(path, self.policy()).map_err(Failure::Input)?;
        Ok(match self.weld {
            Some(distance) => mesh.welded(distance),
            None => mesh,
        })
    }
}

/// Which axis is up in OBJ, PLY and STL output (glTF is always +Y up).
#[derive(clap::ValueEnum, Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Up {
    /// +Y up: (x, y, z) written as (x, z, −y), as glTF, Blender's OBJ
    /// importer and most engines expect.
    Y,
    /// +Z up, graftal's own frame (the default).
    #[default]
    Z,
}

/// How meshes are written (`run`, `convert`).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct WriteArgs {
    /// Write STL and PLY as ASCII.
    #[arg(long)]
    pub ascii: bool,
    /// The up axis of OBJ, PLY and STL output (glTF is +Y up always).
    #[arg(long, value_enum, default_value_t = Up::Z)]
    pub up: Up,
    /// Fail (exit 1) instead of warning when the output format cannot
    /// hold part of the mesh (STL has no wire edges).
    #[arg(long)]
    pub strict: bool,
    /// What wire edges (a G³ skeleton's lines) become: `lines` (the
    /// default: kept as line primitives, `l` and edge elements), `tubes`
    /// (closed hexagonal prisms with a dark `skeleton` material, which
    /// every viewer, renderer and STL shows) or `omit`.
    #[arg(long, value_enum, default_value_t = Skeleton::Lines)]
    pub skeleton: Skeleton,
    /// Radius of `--skeleton tubes` (default: 0.4% of the model's
    /// bounding box diagonal).
    #[arg(long, value_name = "R", value_parser = parse_tolerance)]
    pub tube_radius: Option<f64>,
}

/// What wire edges become in the written file.
#[derive(clap::ValueEnum, Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Skeleton {
    #[default]
    Lines,
    Tubes,
    Omit,
}

/// A mesh encoded for its file, and what the format could not hold.
pub(crate) struct Encoded {
    pub bytes: io::parts::FileParts,
    /// Files that go beside it (an OBJ's `.mtl`), written with it.
    pub companions: Vec<(PathBuf, Vec<u8>)>,
    pub dropped_wire_edges: usize,
}

impl Encoded {
    /// Stages the mesh file and its companions (all land or none).
    pub fn stage(&self, path: &Path, staged: &mut files::Staged) -> Result<(), String> {
        let cannot =
            |path: &Path, e: std::io::Error| format!("cannot write {}: {e}", path.display());
        staged
            .stage_parts(path, self.bytes.iter())
            .map_err(|e| cannot(path, e))?;
        for (path, bytes) in &self.companions {
            staged.stage(path, bytes).map_err(|e| cannot(path, e))?;
        }
        Ok(())
    }
}

/// Encodes `mesh` for `path` as `write` says. STL keeps no wire edges: a
/// warning names how many and what to do (`--strict`: an error).
pub(crate) fn encode_for(
    mesh: &io::IndexedMesh,
    format: io::MeshFormat,
    write: &WriteArgs,
    path: &Path,
) -> Result<Encoded, String> {
    let shown;
    let mesh = match write.skeleton {
        Skeleton::Lines => mesh,
        _ if mesh.lines.is_empty() => mesh,
        Skeleton::Tubes => {
            shown = crate::geom::tubes::lines_as_tubes(mesh, write.tube_radius);
            &shown
        }
        Skeleton::Omit => {
            let mut copy = mesh.clone();
            copy.lines.clear();
            copy.line_parts.clear();
            shown = copy;
            &shown
        }
    };
    let stl = matches!(format, io::MeshFormat::StlAscii | io::MeshFormat::StlBinary);
    let dropped_wire_edges = if stl { mesh.lines.len() } else { 0 };
    if dropped_wire_edges > 0 {
        let message = format!(
            "{}: STL cannot hold the {dropped_wire_edges} wire edges of this mesh (a skeleton's lines); show them as tubes (`--skeleton tubes`), skin them (`skin = {{}}`) or write OBJ, PLY or glTF, which keep lines",
            path.display()
        );
        if write.strict {
            return Err(message);
        }
        eprintln!("warning: {message}; left out");
    }
    let is_gltf = matches!(format, io::MeshFormat::Gltf | io::MeshFormat::Glb);
    let turned;
    let mesh = if write.up == Up::Y && !is_gltf {
        let mut copy = mesh.clone();
        copy.z_up_to_y_up();
        turned = copy;
        &turned
    } else {
        mesh
    };
    let library = obj_library(mesh, format, path);
    let bytes = match &library {
        Some((mtl, _)) => io::obj::encode_with_library(mesh, Some(library_name(mtl))),
        None => io::encode(mesh, format),
    }
    .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(Encoded {
        bytes: bytes.into(),
        companions: library.into_iter().collect(),
        dropped_wire_edges,
    })
}

/// An OBJ's material library: its materials go in a `.mtl` of the same
/// stem beside it (not for standard output, which has no beside).
fn obj_library(
    mesh: &io::IndexedMesh,
    format: io::MeshFormat,
    path: &Path,
) -> Option<(PathBuf, Vec<u8>)> {
    (format == io::MeshFormat::Obj && path.as_os_str() != "-")
        .then(|| io::obj::encode_mtl(mesh))
        .flatten()
        .map(|bytes| (path.with_extension("mtl"), bytes))
}

/// The name an OBJ's `mtllib` line gives its library.
fn library_name(mtl: &Path) -> &str {
    mtl.file_name()
        .and_then(|n| n.to_str())
        .unwrap_or("materials.mtl")
}

/// [`encode_for`] of a plain model ([`crate::grammar::export_look`]) in a
/// format other than glTF, written straight from the kernel mesh `source`
/// (issue 38): the same bytes and companions, without the indexed copy.
/// (The batch runner writes glTF in two halves itself, dropping the mesh
/// between them: [`io::gltf::Planned`].)
pub(crate) fn encode_streamed_for(
    source: &impl crate::geom::source::PolygonSource,
    look: &io::IndexedMesh,
    format: io::MeshFormat,
    path: &Path,
) -> Result<Encoded, String> {
    let library = obj_library(look, format, path);
    let bytes = match &library {
        Some((mtl, _)) => io::obj::encode_streamed(source, look, Some(library_name(mtl))),
        None => io::encode_streamed(source, look, format),
    }
    .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(Encoded {
        bytes: bytes.into(),
        companions: library.into_iter().collect(),
        dropped_wire_edges: 0,
    })
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
    let result = execute(cli.command);
    for notice in files::take_notices() {
        eprintln!("warning: {notice}");
    }
    match result {
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
    /// Standard output was closed (`graftal … | head`): stop quietly,
    /// status 0, as ripgrep and coreutils' tools do.
    PipeClosed,
}

impl Failure {
    fn code(&self) -> u8 {
        match self {
            Failure::Rule(_) | Failure::Input(_) => EXIT_INPUT,
            Failure::Runtime(_) => EXIT_RUNTIME,
            Failure::Limit(code, _) | Failure::Batch(code, _) => *code,
            Failure::PipeClosed => 0,
        }
    }

    fn report(&self) {
        let mut err = std::io::stderr().lock();
        match self {
            Failure::Rule(e) => {
                let color =
                    std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none();
                let _ = writeln!(err, "error: {}", e.headline());
                let _ = write!(err, "{}", e.render(color));
            }
            Failure::Input(m)
            | Failure::Runtime(m)
            | Failure::Limit(_, m)
            | Failure::Batch(_, m) => {
                let _ = writeln!(err, "error: {m}");
            }
            Failure::PipeClosed => {}
        }
    }
}

impl From<RuleError> for Failure {
    fn from(e: RuleError) -> Self {
        Failure::Rule(Box::new(e))
    }
}

/// Writes to standard output; a closed pipe is [`Failure::PipeClosed`].
pub(crate) fn write_stdout(bytes: &[u8]) -> Result<(), Failure> {
    let mut out = std::io::stdout().lock();
    match out.write_all(bytes).and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(Failure::PipeClosed),
        Err(e) => Err(Failure::Runtime(format!(
            "cannot write to standard output: {e}"
        ))),
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

pub fn execute(command: Command) -> Result<(), Failure> {
    match command {
        Command::Run(args) => batch::run(*args),
        Command::Verify(args) => verify::verify(args),
        Command::Manifest { action } => manifest_command(action),
        Command::Clean {
            dirs,
            older_than,
            dry_run,
            quiet,
        } => clean(&dirs, older_than, dry_run, quiet),
        Command::Check {
            rules,
            overrides,
            input,
        } => {
            let program = files::compile_rules(&rules, &overrides)?;
            files::load_inputs(&program, input.policy())?;
            write_stdout(
                format!(
                    "{}: ok ({} parameters, {} steps)\n",
                    program.file,
                    program.param_names.len(),
                    program.steps.len()
                )
                .as_bytes(),
            )
        }
        Command::Info {
            mesh,
            json,
            tolerance,
            input,
        } => {
            let indexed = input.read_mesh(&mesh)?;
            let (report, gates, import) = stats::info_of(&indexed, tolerance)
                .map_err(|e| Failure::Input(format!("{}: {e}", mesh.display())))?;
            let text = if json {
                format!("{}\n", stats::info_json(&mesh, &report, &gates, &import))
            } else {
                stats::info_text(&mesh, &report, &gates, &import)
            };
            write_stdout(text.as_bytes())
        }
        Command::Convert {
            source,
            output,
            write,
            input,
        } => {
            let format = output_format(&output, write.ascii)?;
            let indexed = input.read_mesh(&source)?;
            let encoded =
                encode_for(&indexed, format, &write, &output).map_err(Failure::Runtime)?;
            let mut staged = files::Staged::new();
            encoded
                .stage(&output, &mut staged)
                .map_err(Failure::Runtime)?;
            staged.commit().map_err(|(path, e)| {
                Failure::Runtime(format!("cannot write {}: {e}", path.display()))
            })
        }
        Command::Preview(args) => preview::run(&args),
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
            input,
        } => tooling::explain(&rules, seed, &overrides, json, max_primitives, &input),
        Command::Completions { shell } => tooling::completions(shell),
        Command::Man { dir } => tooling::man(dir.as_deref()),
    }
}

fn manifest_command(action: ManifestAction) -> Result<(), Failure> {
    match action {
        ManifestAction::Merge {
            shards,
            output,
            allow_failed,
        } => {
            let merged = manifest::merge(&shards)?;
            manifest::write(output.as_deref().unwrap_or(Path::new("-")), &merged)?;
            let s = merged.summary;
            if (s.failed > 0 || s.not_run > 0) && !allow_failed {
                let first = merged
                    .variants
                    .iter()
                    .find(|v| v.status != manifest::Status::Ok)
                    .map(|v| match &v.error {
                        Some(e) => format!(
                            "; the first: variant {} (seed {}): {}",
                            v.index, v.seed, e.message
                        ),
                        None => format!(
                            "; the first: variant {} (seed {}) did not run",
                            v.index, v.seed
                        ),
                    })
                    .unwrap_or_default();
                return Err(Failure::Limit(
                    EXIT_RUNTIME,
                    format!(
                        "the merged batch is incomplete: {} of {} variants failed and {} did not run{first} (the manifest was written; rerun those shards with --resume and merge again, or pass --allow-failed)",
                        s.failed,
                        merged.variants.len(),
                        s.not_run
                    ),
                ));
            }
            Ok(())
        }
        ManifestAction::Check {
            manifest: path,
            allow_failed,
            quiet,
        } => {
            let m = manifest::Manifest::read(&path)?;
            let problems = manifest::check(&m, allow_failed);
            let mut text = String::new();
            for p in &problems {
                text += &format!("{}\n", p.message);
            }
            eprint!("{text}");
            if !problems.is_empty() {
                return Err(Failure::Limit(
                    EXIT_RUNTIME,
                    format!(
                        "{}: {} problem(s) in {} variants",
                        path.display(),
                        problems.len(),
                        m.variants.len()
                    ),
                ));
            }
            if !quiet {
                let files: usize = m
                    .variants
                    .iter()
                    .filter(|v| v.status == manifest::Status::Ok)
                    .map(|v| 1 + v.extra_files.len())
                    .sum();
                eprintln!(
                    "{}: {files} files of {} variants match their sizes and SHA-256",
                    path.display(),
                    m.variants.len()
                );
            }
            Ok(())
        }
    }
}

/// `graftal clean`: removes graftal temporary files under `dirs`.
fn clean(
    dirs: &[PathBuf],
    older_than: Option<std::time::Duration>,
    dry_run: bool,
    quiet: bool,
) -> Result<(), Failure> {
    let mut failed = 0;
    for dir in dirs {
        let cleaned = files::clean(dir, older_than, dry_run)
            .map_err(|e| Failure::Input(format!("{}: {e}", dir.display())))?;
        if !quiet {
            let verb = if dry_run { "would remove" } else { "removed" };
            let mut text = String::new();
            for t in &cleaned.removed {
                text += &format!(
                    "{verb} {} ({} old)\n",
                    t.path.display(),
                    files::describe_age(t.age)
                );
            }
            write_stdout(text.as_bytes())?;
        }
        for (path, e) in &cleaned.failed {
            eprintln!("error: cannot remove {}: {e}", path.display());
        }
        failed += cleaned.failed.len();
    }
    if failed > 0 {
        return Err(Failure::Runtime(format!(
            "{failed} temporary file(s) could not be removed"
        )));
    }
    Ok(())
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
