//! The last stage of `graftal run`: a single run's files land together; a
//! batch writes its own files (NDJSON stats, contact sheet, manifest),
//! retires its journal, keeps the cache within its bound, prints its
//! summary and picks the exit code.

use std::path::Path;

use super::execute::{Done, Produced, Source};
use super::resolve::{describe_shard, Plan, StatsSink, Variant};
use super::RunArgs;
use crate::cli::files;
use crate::cli::manifest::{self, Status};
use crate::cli::Failure;

pub(super) fn report(plan: &Plan, done: Done) -> Result<(), Failure> {
    let args = plan.args;
    let Done {
        results,
        elapsed,
        ndjson,
        journal,
        journal_error,
    } = done;
    let mut produced = results;
    if !plan.batch {
        return single(plan, &mut produced);
    }
    if let StatsSink::File(path) = &plan.stats_sink {
        files::write_atomic(path, &ndjson)
            .map_err(|e| Failure::Runtime(format!("cannot write {}: {e}", path.display())))?;
    }
    if let Some(path) = &args.contact_sheet {
        let png = contact_sheet(args, &plan.variants, &produced)?;
        files::write_atomic(path, &png)
            .map_err(|e| Failure::Runtime(format!("cannot write {}: {e}", path.display())))?;
    }
    let count = |s: Source| {
        produced
            .iter()
            .filter(|p| p.source == s && p.entry.status == Status::Ok)
            .count()
    };
    let (cached, resumed) = (count(Source::Cached), count(Source::Resumed));
    // The entries move into the manifest (a million-step program's step
    // records are not copied).
    let mut manifest = plan.manifest(produced.into_iter().map(|p| p.entry).collect());
    let summary = manifest.summary;
    if let Some(path) = &plan.manifest_path {
        manifest::write(path, &manifest)?;
    }
    let entries = std::mem::take(&mut manifest.variants);
    if let Some(journal) = journal {
        if let Err(e) = journal.finish() {
            eprintln!("warning: cannot remove the journal: {e}");
        }
    }
    if let Some(e) = journal_error {
        eprintln!("warning: {e} (--resume of this batch will redo more)");
    }
    let evicted = match &plan.cache {
        Some(cache) => match cache.evict() {
            Ok(e) => Some(e),
            Err(e) => {
                eprintln!("warning: --cache: cannot keep the cache within its size: {e}");
                None
            }
        },
        None => None,
    };
    let first_failure = entries
        .iter()
        .find_map(|e| e.error.as_ref().map(|err| (e, err)));
    let shard = plan.identity.shard.map(|s| super::Shard {
        index: s.index,
        count: s.count,
    });
    if !args.quiet {
        let seconds = elapsed.as_secs_f64();
        let mut how = Vec::new();
        if plan.cache.is_some() {
            how.push(format!("{cached} from the cache"));
        }
        if args.resume {
            how.push(format!("{resumed} already in place"));
        }
        let how = if how.is_empty() {
            String::new()
        } else {
            format!(" ({})", how.join(", "))
        };
        eprintln!(
            "{}{}: {} variants: {} written{how}, {} failed, {} not run{} ({:.2} s, {:.0} variants/s)",
            args.rules.display(),
            describe_shard(shard),
            entries.len(),
            summary.ok,
            summary.failed,
            summary.not_run,
            plan.manifest_path
                .as_ref()
                .map_or(String::new(), |p| format!("; manifest {}", p.display())),
            seconds,
            entries.len() as f64 / seconds.max(1e-9)
        );
        if let Some(e) = evicted.filter(|e| e.entries > 0) {
            eprintln!(
                "--cache: removed {} least recently used entries ({} bytes) to stay within {} bytes",
                e.entries, e.bytes, args.cache_max_size
            );
        }
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
            "manifest": plan.manifest_path.as_ref().map(|p| p.display().to_string()),
            "failures": failures,
        });
        if plan.cache.is_some() {
            doc["cache_hits"] = serde_json::json!(cached);
            if let Some(e) = evicted {
                doc["cache_evicted"] = serde_json::json!(e.entries);
            }
        }
        if args.resume {
            doc["resumed"] = serde_json::json!(resumed);
        }
        if let Some(s) = shard {
            doc["shard"] = serde_json::json!({"index": s.index, "count": s.count});
        }
        if args.timings {
            doc["seconds"] = serde_json::json!(elapsed.as_secs_f64());
        }
        crate::cli::write_stdout(format!("{doc}\n").as_bytes())?;
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

/// A single run: its mesh, stats file, contact sheet and manifest land
/// together, or none does.
fn single(plan: &Plan, produced: &mut [Produced]) -> Result<(), Failure> {
    let args = plan.args;
    if let Some(err) = &produced[0].entry.error {
        return Err(Failure::Limit(err.exit_code, err.message.clone()));
    }
    let p = &mut produced[0];
    let mut staged = p
        .staged
        .take()
        .expect("a single run's outputs wait to be committed");
    let cannot = |path: &Path, e: std::io::Error| {
        Failure::Runtime(format!("cannot write {}: {e}", path.display()))
    };
    let mut print_stats = None;
    if let (StatsSink::Single(target), Some(doc)) = (&plan.stats_sink, &p.stats) {
        match target {
            None => print_stats = Some(doc.clone()),
            Some(path) => staged
                .stage(path, format!("{doc}\n").as_bytes())
                .map_err(|e| cannot(path, e))?,
        }
    }
    if let Some(path) = &args.contact_sheet {
        let png = contact_sheet(args, &plan.variants, produced)?;
        staged.stage(path, &png).map_err(|e| cannot(path, e))?;
    }
    staged.commit().map_err(|(path, e)| cannot(&path, e))?;
    let (entry, source) = (&produced[0].entry, produced[0].source);
    if let Some(doc) = print_stats {
        crate::cli::write_stdout(format!("{doc}\n").as_bytes())?;
    }
    if !args.quiet {
        let counts = entry.counts.unwrap_or(manifest::Counts {
            vertices: 0,
            edges: 0,
            faces: 0,
        });
        let from = match source {
            Source::Cached => ", from the cache",
            _ => "",
        };
        eprintln!(
            "wrote {} ({} vertices, {} faces, seed {}{from})",
            entry.output, counts.vertices, counts.faces, entry.seed
        );
    }
    Ok(())
}

/// Refuses, before anything runs, a contact sheet that is not a PNG or
/// would exceed the renderer's size limit.
pub(super) fn check_contact_sheet(path: &Path, tiles: usize, size: u32) -> Result<(), Failure> {
    if !crate::cli::preview::has_extension(path, "png") {
        return Err(Failure::Input(format!(
            "--contact-sheet {}: a contact sheet is a PNG; name it *.png",
            path.display()
        )));
    }
    let columns = u64::from(crate::cli::preview::sheet_columns(tiles));
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
    produced: &[Produced],
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
            match p.thumbnail.clone() {
                Some(image) => (image, label),
                None => (blank.clone(), format!("{label} failed")),
            }
        })
        .collect();
    let sheet =
        crate::preview::contact_sheet(&tiles, crate::cli::preview::sheet_columns(tiles.len()))
            .map_err(|e| Failure::Runtime(format!("contact sheet: {e}")))?;
    crate::preview::encode_png(&sheet).map_err(|e| Failure::Runtime(e.to_string()))
}
