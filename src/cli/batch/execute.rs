//! The second stage of `graftal run`: every variant on `-j` workers. A
//! variant is *resumed* (an earlier run's files are still there, hashes
//! checked), *restored* (its content address is in the cache, hashes
//! checked) or *made* (the rule file runs, then the cache is filled);
//! whichever, the same files land with the same bytes and the manifest
//! entry is the same.

use std::collections::{BTreeMap, BTreeSet};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::resolve::{Plan, StatsSink, Variant};
use crate::cli::files::{self, journal::Journal, Staged};
use crate::cli::manifest::{Counts, ErrorEntry, FileEntry, Status, VariantEntry};
use crate::cli::stats::{self, steps_json, StepJson};
use crate::cli::{manifest, EXIT_RUNTIME};
use crate::grammar::{self, RunErrorKind, RunOptions};
use crate::io::parts::FileParts;
use crate::io::MeshFormat;

/// How a variant's files came to be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Source {
    Made,
    Cached,
    Resumed,
}

/// What one variant gave.
pub(super) struct Produced {
    pub entry: VariantEntry,
    /// Its stats document (pretty JSON, no final newline), when stats are
    /// wanted.
    pub stats: Option<String>,
    /// A single run's outputs, written but not yet in place: the stats
    /// file and the manifest join them, and all are renamed together.
    pub staged: Option<Staged>,
    /// Warnings of the run (the batch prints each once).
    pub warnings: Vec<String>,
    /// Its contact-sheet thumbnail, when a sheet is wanted.
    pub thumbnail: Option<crate::preview::Image>,
    pub source: Source,
}

/// Everything the workers produced, in variant order.
pub(super) struct Done {
    /// Per variant, in order, what it produced (a `not_run` entry for a
    /// variant `--fail-fast` never started).
    pub results: Vec<Produced>,
    pub elapsed: Duration,
    /// The NDJSON stats lines, when they go to a file.
    pub ndjson: Vec<u8>,
    /// The progress journal, kept until the manifest is in place.
    pub journal: Option<Journal>,
    /// A problem with the journal (the batch still completes).
    pub journal_error: Option<String>,
}

/// A made variant's products, before they are written: what the cache
/// keeps and restores.
struct Artifacts {
    /// The mesh file's bytes, as its writer left them ([`FileParts`]).
    mesh: FileParts,
    /// The mesh's SHA-256 once something computed it (it is hashed once).
    mesh_sha256: Option<String>,
    /// Files beside the mesh by extension (an OBJ's `mtl`).
    companions: Vec<(String, Vec<u8>)>,
    stats: Option<String>,
    thumbnail: Option<crate::preview::Image>,
    record: Record,
    /// The kernel mesh, once nothing reads it: [`produce`] frees a large
    /// one while the files are written, a small one before.
    retired: crate::kernel::Mesh,
}

/// The manifest facts of a made variant (kept in the cache beside its
/// files).
#[derive(Serialize, Deserialize, Clone, Debug)]
struct Record {
    counts: Counts,
    steps: Vec<StepJson>,
    warnings: Vec<String>,
}

/// The cache's role names.
const MESH_ROLE: &str = "mesh";
const STATS_ROLE: &str = "stats.json";
const COMPANION_PREFIX: &str = "companion.";

fn thumbnail_role(size: u32) -> String {
    format!("thumbnail-{size}.rgba")
}

pub(super) fn execute(plan: &Plan) -> Done {
    let args = plan.args;
    // A batch shows variants; a single run that meshes a field for a while
    // shows the blocks meshed.
    let mesh_bar = MeshBar::start(!plan.batch && !args.quiet && std::io::stderr().is_terminal());
    let started = Instant::now();
    let progress = Progress::new(
        plan.batch && !args.quiet && std::io::stderr().is_terminal(),
        plan.variants.len(),
    );
    let mut journal_error = None;
    let mut journal = match &plan.manifest_path {
        Some(path) if plan.batch && path.as_os_str() != "-" => {
            let header = serde_json::to_string(&plan.identity).expect("manifest serializes");
            match Journal::start(&files::journal::path_for(path), &header) {
                Ok(j) => Some(j),
                Err(e) => {
                    journal_error = Some(format!(
                        "cannot write the journal beside {}: {e}",
                        path.display()
                    ));
                    None
                }
            }
        }
        _ => None,
    };
    let mut ndjson = Vec::new();
    let mut stdout_closed = false;
    let results = run_variants(
        plan,
        &progress,
        |produced| {
            // As each variant finishes, whatever the order: the journal
            // is what a killed batch leaves for --resume.
            if let Some(j) = &mut journal {
                let line = serde_json::to_string(&produced.entry).expect("entry serializes");
                if let Err(e) = j.append(&line) {
                    journal_error = Some(format!("cannot write the journal: {e}"));
                    journal = None;
                }
            }
        },
        |produced| {
            if let Some(doc) = &produced.stats {
                let line = || ndjson_line(&produced.entry, doc);
                match &plan.stats_sink {
                    StatsSink::Stdout if !stdout_closed => {
                        // A reader that went away (`| head`) stops the batch as
                        // --fail-fast would: the rest is not run.
                        stdout_closed =
                            crate::cli::write_stdout(format!("{}\n", line()).as_bytes()).is_err();
                    }
                    StatsSink::File(_) => {
                        ndjson.extend_from_slice(line().as_bytes());
                        ndjson.push(b'\n');
                    }
                    _ => {}
                }
            }
            !stdout_closed
        },
    );
    progress.finish();
    drop(mesh_bar);
    Done {
        results,
        elapsed: started.elapsed(),
        ndjson,
        journal,
        journal_error,
    }
}

/// A batch's NDJSON line: which variant, then its stats document (the
/// pretty document made compact, so one stored form serves both).
fn ndjson_line(entry: &VariantEntry, pretty: &str) -> String {
    let compact = compact_json(pretty);
    let body = compact.strip_prefix('{').unwrap_or(&compact);
    let head = serde_json::json!({
        "index": entry.index,
        "output": entry.output,
        "sha256": entry.sha256.as_deref().unwrap_or_default(),
    });
    // `json!` sorts keys; the line's order is index, output, sha256.
    let head = format!(
        "{{\"index\":{},\"output\":{},\"sha256\":{}",
        head["index"], head["output"], head["sha256"]
    );
    if body == "}" {
        format!("{head}}}")
    } else {
        format!("{head},{body}")
    }
}

/// serde_json's pretty output with the whitespace outside strings taken
/// out: exactly its compact output of the same value.
fn compact_json(pretty: &str) -> String {
    let mut out = String::with_capacity(pretty.len());
    let (mut in_string, mut escaped) = (false, false);
    for c in pretty.chars() {
        if in_string {
            out.push(c);
            match (escaped, c) {
                (true, _) => escaped = false,
                (false, '\\') => escaped = true,
                (false, '"') => in_string = false,
                _ => {}
            }
        } else if c == '"' {
            in_string = true;
            out.push(c);
        } else if !c.is_whitespace() {
            out.push(c);
        }
    }
    out
}

/// Runs every variant on `-j` workers; `finished` sees each as it ends,
/// `emit` each in index order (returning false stops the batch). Returns
/// what each produced in index order, variants never started
/// (`--fail-fast`) as `not_run`.
fn run_variants(
    plan: &Plan,
    progress: &Progress,
    mut finished: impl FnMut(&Produced),
    mut emit: impl FnMut(&Produced) -> bool,
) -> Vec<Produced> {
    let variants = &plan.variants;
    let jobs = plan
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
                let produced = produce(plan, variant);
                if plan.args.fail_fast && produced.entry.status == Status::Failed {
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
            finished(&produced);
            if let (true, Some(err)) = (plan.batch, &produced.entry.error) {
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
        .map(|(v, produced)| {
            produced.unwrap_or_else(|| Produced {
                entry: entry_for(v, Status::NotRun),
                stats: None,
                staged: None,
                warnings: Vec::new(),
                thumbnail: None,
                source: Source::Made,
            })
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
        extra_files: Vec::new(),
        counts: None,
        error: None,
        time_ms: None,
        steps: Vec::new(),
    }
}

/// Whether a thumbnail is wanted, and its size.
fn thumbnail_size(plan: &Plan) -> Option<u32> {
    plan.args
        .contact_sheet
        .is_some()
        .then_some(plan.args.thumbnail_size)
}

/// One variant: resumed, restored or made, and its files written. Never
/// panics on bad geometry or limits: a failure is recorded in the entry.
fn produce(plan: &Plan, v: &Variant) -> Produced {
    let started = Instant::now();
    let timed = |mut p: Produced| {
        if plan.args.timings && p.source != Source::Resumed {
            p.entry.time_ms = Some(started.elapsed().as_secs_f64() * 1e3);
        }
        p
    };
    if let Some(p) = resume(v) {
        return timed(p);
    }
    if let Some(a) = restore(plan, v) {
        return timed(land(plan, v, a, Source::Cached));
    }
    let artifacts = match make(plan, v, started) {
        Ok(a) => a,
        Err(error) => {
            let mut entry = entry_for(v, Status::Failed);
            entry.error = Some(error);
            return timed(Produced {
                entry,
                stats: None,
                staged: None,
                warnings: Vec::new(),
                thumbnail: None,
                source: Source::Made,
            });
        }
    };
    let mut artifacts = artifacts;
    // Returning a large kernel mesh's pages to the system takes about as
    // long as writing its file (issue 38): the two run at once. A small
    // mesh is freed in less time than handing it to another thread takes.
    let retired = std::mem::take(&mut artifacts.retired);
    if retired.loop_count() < FREE_ALONGSIDE {
        drop(retired);
        return timed(keep_and_land(plan, v, artifacts));
    }
    let (produced, ()) = rayon::join(|| keep_and_land(plan, v, artifacts), || drop(retired));
    timed(produced)
}

/// Corners (loops) from which a made variant's kernel mesh is freed on
/// another thread while its files are written.
const FREE_ALONGSIDE: usize = 1 << 16;

/// Stores a made variant in the cache (when there is one) and lands it.
fn keep_and_land(plan: &Plan, v: &Variant, mut artifacts: Artifacts) -> Produced {
    if let (Some(cache), Some(key)) = (&plan.cache, &v.cache_key) {
        let sha = sha256_of(&artifacts.mesh);
        // The cache stores one buffer: a file handed over in parts is
        // joined here, for the cache only.
        let joined = artifacts.mesh.joined();
        let mut roles: Vec<(String, &[u8], Option<&str>)> =
            vec![(MESH_ROLE.into(), &joined, Some(&sha))];
        for (ext, bytes) in &artifacts.companions {
            roles.push((format!("{COMPANION_PREFIX}{ext}"), bytes, None));
        }
        if let Some(doc) = &artifacts.stats {
            roles.push((STATS_ROLE.into(), doc.as_bytes(), None));
        }
        if let Some(image) = &artifacts.thumbnail {
            roles.push((thumbnail_role(image.width), &image.rgba, None));
        }
        let roles: Vec<(&str, &[u8], Option<&str>)> =
            roles.iter().map(|(r, b, h)| (r.as_str(), *b, *h)).collect();
        let record = serde_json::to_value(&artifacts.record).expect("record serializes");
        // A cache that cannot be written never fails the batch.
        let stored = cache.store(key, &roles, record);
        artifacts.mesh_sha256 = Some(sha);
        if let Err(e) = stored {
            let mut p = land(plan, v, artifacts, Source::Made);
            p.warnings
                .push(format!("--cache: cannot store variant {}: {e}", v.index));
            return p;
        }
    }
    land(plan, v, artifacts, Source::Made)
}

/// An earlier run's entry, if every file it lists is still there with its
/// recorded size and SHA-256 (modification times are not trusted).
fn resume(v: &Variant) -> Option<Produced> {
    let prior = v.prior.as_ref()?;
    let files = std::iter::once((prior.output.as_str(), prior.bytes, prior.sha256.as_deref()))
        .chain(
            prior
                .extra_files
                .iter()
                .map(|f| (f.path.as_str(), Some(f.bytes), Some(f.sha256.as_str()))),
        );
    for (path, bytes, sha256) in files {
        if manifest::file_problem(path, bytes, sha256).is_some() {
            return None;
        }
    }
    // The stats file the variant writes now must be one it listed.
    if let Some(stats) = &v.stats {
        let listed = prior
            .extra_files
            .iter()
            .any(|f| Path::new(&f.path) == stats);
        if !listed {
            return None;
        }
    }
    Some(Produced {
        entry: prior.clone(),
        stats: None,
        staged: None,
        warnings: Vec::new(),
        thumbnail: None,
        source: Source::Resumed,
    })
}

/// The variant's products from the cache, if its entry is whole and holds
/// everything this run wants.
fn restore(plan: &Plan, v: &Variant) -> Option<Artifacts> {
    let (cache, key) = (plan.cache.as_ref()?, v.cache_key.as_ref()?);
    let mut required = vec![MESH_ROLE.to_owned()];
    if plan.want_stats() {
        required.push(STATS_ROLE.into());
    }
    if let Some(size) = thumbnail_size(plan) {
        required.push(thumbnail_role(size));
    }
    let required: Vec<&str> = required.iter().map(String::as_str).collect();
    let hit = cache.lookup(key, &|role| role.starts_with(COMPANION_PREFIX), &required)?;
    let record: Record = serde_json::from_value(hit.record.clone()).ok()?;
    let mut companions = Vec::new();
    let mut mesh = FileParts::default();
    let mut mesh_sha256 = None;
    let mut stats = None;
    let mut thumbnail = None;
    for (role, bytes, sha256) in hit.files {
        if role == MESH_ROLE {
            mesh = FileParts::from(bytes);
            mesh_sha256 = Some(sha256);
        } else if role == STATS_ROLE {
            stats = Some(String::from_utf8(bytes).ok()?);
        } else if let Some(ext) = role.strip_prefix(COMPANION_PREFIX) {
            companions.push((ext.to_owned(), bytes));
        } else if let Some(size) = thumbnail_size(plan).filter(|&s| role == thumbnail_role(s)) {
            if bytes.len() != size as usize * size as usize * 4 {
                return None;
            }
            thumbnail = Some(crate::preview::Image {
                width: size,
                height: size,
                rgba: bytes,
            });
        }
    }
    Some(Artifacts {
        mesh,
        mesh_sha256,
        companions,
        stats,
        thumbnail,
        record,
        retired: crate::kernel::Mesh::default(),
    })
}

/// Runs the variant's program and encodes what it makes.
fn make(plan: &Plan, v: &Variant, started: Instant) -> Result<Artifacts, ErrorEntry> {
    let args = plan.args;
    let program = &plan.programs[v.combo];
    let fail = |kind: &str, exit_code: u8, message: String| ErrorEntry {
        kind: kind.to_string(),
        exit_code,
        message,
    };
    let options = RunOptions {
        seed: Some(v.seed),
        max_elements: args.max_primitives,
        max_evaluations: args.max_evaluations,
        deadline: args.timeout.map(|s| started + Duration::from_secs_f64(s)),
        inputs: std::sync::Arc::clone(&plan.inputs.meshes),
        max_cells: args.max_cells,
        mesh_progress: crate::sdf::Progress(Some(&MESH_PROGRESS)),
        ..RunOptions::default()
    };
    let mut result = grammar::run(program, &options).map_err(|e| {
        let kind = match e.kind {
            RunErrorKind::Failed => "failed",
            RunErrorKind::TooLarge => "too_large",
            RunErrorKind::Timeout => "timeout",
            RunErrorKind::EvaluationLimit => "evaluation_limit",
        };
        fail(kind, crate::cli::run_exit_code(e.kind), e.to_string())
    })?;
    let want_stats = plan.want_stats();
    if !want_stats {
        // Nothing but the export reads the kernel mesh from here on: the
        // layers it does not read go before it runs, the rest before the
        // file is encoded, so peak memory is the larger of the mesh and its
        // encoding, not their sum.
        grammar::drop_unexported_layers(&mut result.mesh);
    }
    let counts = Counts {
        vertices: result.mesh.vert_count(),
        edges: result.mesh.edge_count(),
        faces: result.mesh.face_count(),
    };
    // A plain model (one part and material, flat, nothing per corner) is
    // written straight from the kernel mesh, with no indexed copy (issue
    // 38), unless a thumbnail needs the copy too or the file turns Y-up
    // (glTF is always Y-up; its writer turns it).
    let thumbnail_size = thumbnail_size(plan);
    let format = v.format;
    let gltf = matches!(format, MeshFormat::Glb | MeshFormat::Gltf);
    let streamed = (thumbnail_size.is_none() && (gltf || args.write.up == crate::cli::Up::Z))
        .then(|| grammar::export_look(program, &result.mesh))
        .flatten();
    let (encoded, thumbnail) = match streamed {
        Some(look) => {
            let failed = |e: crate::io::IoError| {
                fail(
                    "failed",
                    EXIT_RUNTIME,
                    format!("{}: {e}", v.output.display()),
                )
            };
            let view = result.mesh.canonical_view();
            let encoded = if gltf {
                let glb = format == MeshFormat::Glb;
                let planned = crate::io::gltf::Planned::new(&view, &look, glb).map_err(failed)?;
                // The primitives hold all the file needs. A GLB hands them
                // over as they are, so the mesh may wait to be freed while
                // the file is written; a `.gltf` allocates its base64 text,
                // so the mesh goes first.
                drop(view);
                if !want_stats && !glb {
                    result.mesh = crate::kernel::Mesh::default();
                }
                crate::cli::Encoded {
                    bytes: planned.encode_parts().map_err(failed)?,
                    companions: Vec::new(),
                    dropped_wire_edges: 0,
                }
            } else {
                crate::cli::encode_streamed_for(&view, &look, format, &v.output)
                    .map_err(|m| fail("failed", EXIT_RUNTIME, m))?
            };
            (encoded, None)
        }
        None => {
            let indexed = grammar::export(program, &result.mesh);
            if !want_stats {
                result.mesh = crate::kernel::Mesh::default();
            }
            let thumbnail = match thumbnail_size {
                Some(size) => {
                    let options = crate::preview::Options {
                        width: size,
                        height: size,
                        edges: true,
                        ..crate::preview::Options::default()
                    };
                    Some(
                        crate::cli::preview::render(&indexed, &options)
                            .map_err(|m| fail("failed", EXIT_RUNTIME, format!("thumbnail: {m}")))?,
                    )
                }
                None => None,
            };
            let encoded = crate::cli::encode_for(&indexed, v.format, &args.write, &v.output)
                .map_err(|m| fail("failed", EXIT_RUNTIME, m))?;
            (encoded, thumbnail)
        }
    };
    let stats = want_stats.then(|| {
        let (report, gates) = stats::report_and_gates(&result.mesh, stats::CLOSE_TOLERANCE);
        let doc = stats::run_stats_doc(
            program,
            &result,
            &report,
            &gates,
            encoded.dropped_wire_edges,
            args.timings,
        );
        serde_json::to_string_pretty(&doc).expect("stats serialize")
    });
    let companions = encoded
        .companions
        .into_iter()
        .map(|(path, bytes)| {
            let ext = path
                .extension()
                .map_or_else(String::new, |e| e.to_string_lossy().into_owned());
            (ext, bytes)
        })
        .collect();
    Ok(Artifacts {
        mesh: encoded.bytes,
        mesh_sha256: None,
        companions,
        stats,
        thumbnail,
        record: Record {
            counts,
            // Only a manifest or stats record them: a single run's
            // million-step program need not copy a million records.
            steps: if plan.batch || want_stats {
                steps_json(&result.steps, args.timings)
            } else {
                Vec::new()
            },
            warnings: result.warnings.clone(),
        },
        retired: std::mem::take(&mut result.mesh),
    })
}

/// Writes a variant's products where they go and makes its entry.
fn land(plan: &Plan, v: &Variant, a: Artifacts, source: Source) -> Produced {
    let args = plan.args;
    let mut entry = entry_for(v, Status::Ok);
    let fail = |mut entry: VariantEntry, message: String| {
        entry.status = Status::Failed;
        entry.error = Some(ErrorEntry {
            kind: "write".into(),
            exit_code: EXIT_RUNTIME,
            message,
        });
        Produced {
            entry,
            stats: None,
            staged: None,
            warnings: Vec::new(),
            thumbnail: None,
            source,
        }
    };
    let mut staged = Staged::new();
    let mut extra: Vec<(PathBuf, &[u8])> = a
        .companions
        .iter()
        .map(|(ext, bytes)| (v.output.with_extension(ext), bytes.as_slice()))
        .collect();
    let stats_file = match (&v.stats, &a.stats) {
        (Some(path), Some(doc)) => Some((path.clone(), format!("{doc}\n"))),
        _ => None,
    };
    if let Some((path, text)) = &stats_file {
        extra.push((path.clone(), text.as_bytes()));
    }
    let cannot = |path: &Path, e: std::io::Error| format!("cannot write {}: {e}", path.display());
    if let Err(e) = staged.stage_parts(&v.output, a.mesh.iter()) {
        return fail(entry, cannot(&v.output, e));
    }
    for (path, bytes) in &extra {
        if let Err(e) = staged.stage(path, bytes) {
            return fail(entry, cannot(path, e));
        }
    }
    entry.bytes = Some(a.mesh.len() as u64);
    // Hashed only when something records it (a manifest, stats lines, the
    // JSON summary): SHA-256 of a large mesh costs as much as encoding it.
    if plan.batch || plan.want_stats() || args.json || plan.cache.is_some() {
        let sha = a.mesh_sha256.clone();
        entry.sha256 = Some(sha.unwrap_or_else(|| sha256_of(&a.mesh)));
    }
    if plan.batch {
        entry.extra_files = extra
            .iter()
            .map(|(path, bytes)| FileEntry {
                path: path.display().to_string(),
                bytes: bytes.len() as u64,
                sha256: files::hex(&Sha256::digest(bytes)),
            })
            .collect();
    }
    entry.counts = Some(a.record.counts);
    entry.steps = a.record.steps;
    // A batch variant's files land together now; a single run's wait for
    // its stats and manifest.
    let staged = if plan.batch {
        if let Err((path, e)) = staged.commit() {
            return fail(entry, format!("cannot write {}: {e}", path.display()));
        }
        None
    } else {
        Some(staged)
    };
    Produced {
        entry,
        stats: a.stats,
        staged,
        warnings: a.record.warnings,
        thumbnail: a.thumbnail,
        source,
    }
}

/// The hex SHA-256 of a file given in parts.
fn sha256_of(parts: &FileParts) -> String {
    let mut hasher = Sha256::new();
    for part in parts.iter() {
        hasher.update(part);
    }
    files::hex(&hasher.finalize())
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
pub(super) struct Progress(Option<indicatif::ProgressBar>);

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compacting_pretty_json_gives_serde_jsons_compact_form() {
        let value = serde_json::json!({
            "a": [1, 2.5, -0.0, 1e300],
            "b": {"c d": "x \" y\\", "e": [], "f": {}},
            "g": "line\nbreak\ttab",
            "h": null,
        });
        let pretty = serde_json::to_string_pretty(&value).unwrap();
        assert_eq!(
            compact_json(&pretty),
            serde_json::to_string(&value).unwrap()
        );
    }
}
