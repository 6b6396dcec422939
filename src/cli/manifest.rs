//! The batch manifest: what a batch was asked to make and what each
//! variant became. Field order is fixed by the structs and floats print in
//! shortest round-trip form (read back exactly: serde_json's
//! `float_roundtrip`), so a manifest re-serialized after reading is the same
//! bytes — which is what lets `manifest merge` rebuild, from shard
//! manifests, exactly the manifest an unsharded run writes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::stats::StepJson;
use super::Failure;

/// The whole manifest of a batch, or of one shard of it.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    pub graftal_version: String,
    /// The rule file as given on the command line.
    pub rules: String,
    /// SHA-256 of the rule file's bytes.
    pub rule_sha256: String,
    /// The files the rule file imports, as written, with the SHA-256 of
    /// their bytes (read once for the whole batch).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inputs: Vec<InputEntry>,
    pub batch: BatchSpec,
    /// `null` for a whole batch; the shard a shard manifest covers.
    pub shard: Option<ShardSpec>,
    /// Variants in the whole batch (a shard lists only its own).
    pub variant_count: usize,
    pub summary: Summary,
    /// In ascending `index`.
    pub variants: Vec<VariantEntry>,
}

/// A file a rule file needs.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct InputEntry {
    pub path: String,
    pub sha256: String,
}

/// What the batch was asked to make: everything that decides its outputs
/// (not `-j`, which never changes a byte).
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BatchSpec {
    /// `--seeds` as normalized text, `--seed` as a number; `null` for the
    /// file's own seed.
    pub seeds: Option<String>,
    pub grid: Vec<GridSpec>,
    /// `--set` overrides, `name=value`.
    pub set: Vec<String>,
    /// The output path template.
    pub output: String,
    pub max_primitives: usize,
    pub max_evaluations: u64,
    /// `--max-cells`; absent for the default.
    #[serde(
        default = "default_max_cells",
        skip_serializing_if = "is_default_max_cells"
    )]
    pub max_cells: u64,
    pub timeout_seconds: Option<f64>,
    pub ascii: bool,
    pub timings: bool,
    /// `--up y` (OBJ, PLY and STL written Y-up); absent for the default.
    #[serde(default, skip_serializing_if = "is_false")]
    pub up_y: bool,
}

fn default_max_cells() -> u64 {
    crate::grammar::DEFAULT_MAX_CELLS
}

fn is_default_max_cells(n: &u64) -> bool {
    *n == crate::grammar::DEFAULT_MAX_CELLS
}

fn is_false(b: &bool) -> bool {
    !*b
}

#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    pub name: String,
    pub values: Vec<String>,
}

#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct ShardSpec {
    /// 0-based.
    pub index: usize,
    pub count: usize,
}

#[derive(Serialize, Deserialize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Summary {
    pub ok: usize,
    pub failed: usize,
    /// Variants `--fail-fast` never started.
    pub not_run: usize,
}

impl Summary {
    pub fn of(variants: &[VariantEntry]) -> Summary {
        let mut s = Summary::default();
        for v in variants {
            match v.status {
                Status::Ok => s.ok += 1,
                Status::Failed => s.failed += 1,
                Status::NotRun => s.not_run += 1,
            }
        }
        s
    }
}

#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Ok,
    Failed,
    NotRun,
}

/// One variant: its inputs, and its output or why there is none.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct VariantEntry {
    /// Position in the whole batch: grid combinations in order, seeds
    /// fastest.
    pub index: usize,
    pub seed: u64,
    /// Every parameter's value for this variant, by name.
    pub params: BTreeMap<String, f64>,
    pub output: String,
    pub status: Status,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bytes: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sha256: Option<String>,
    /// The other files the variant wrote (an OBJ's `.mtl`, its own stats
    /// file), checked like the output by `--resume` and `manifest check`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extra_files: Vec<FileEntry>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub counts: Option<Counts>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorEntry>,
    /// Wall-clock time of the variant, with `--timings` only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_ms: Option<f64>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub steps: Vec<StepJson>,
}

/// A file a variant wrote besides its output.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct FileEntry {
    pub path: String,
    pub bytes: u64,
    pub sha256: String,
}

#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Counts {
    pub vertices: usize,
    pub edges: usize,
    pub faces: usize,
}

#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct ErrorEntry {
    /// `failed`, `too_large`, `timeout`, `evaluation_limit` or `write`.
    pub kind: String,
    pub exit_code: u8,
    pub message: String,
}

impl Manifest {
    /// The manifest's bytes: pretty JSON and a final newline.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut text = serde_json::to_string_pretty(self).expect("manifest serializes");
        text.push('\n');
        text.into_bytes()
    }

    pub fn read(path: &Path) -> Result<Manifest, Failure> {
        let text = super::files::read_json_text(path)
            .map_err(|e| Failure::Input(format!("cannot read {}: {e}", path.display())))?
            .ok_or_else(|| {
                Failure::Input(format!("cannot read {}: no such file", path.display()))
            })?;
        Manifest::parse(path, &text)
    }

    pub fn parse(path: &Path, text: &str) -> Result<Manifest, Failure> {
        serde_json::from_str(text).map_err(|e| {
            Failure::Input(format!(
                "{}:{}:{}: not a graftal manifest: {e}",
                path.display(),
                e.line(),
                e.column()
            ))
        })
    }

    /// Whether `other` records the same batch (tool, rule file, inputs,
    /// batch spec, shard): its entries describe the same variants.
    pub fn same_batch(&self, other: &Manifest) -> Option<String> {
        let mine = serde_json::json!({
            "graftal_version": self.graftal_version, "rules": self.rules,
            "rule_sha256": self.rule_sha256, "inputs": self.inputs, "batch": self.batch,
            "shard": self.shard, "variant_count": self.variant_count,
        });
        let theirs = serde_json::json!({
            "graftal_version": other.graftal_version, "rules": other.rules,
            "rule_sha256": other.rule_sha256, "inputs": other.inputs, "batch": other.batch,
            "shard": other.shard, "variant_count": other.variant_count,
        });
        first_difference("", &mine, &theirs)
    }
}

/// The first field (a dotted path) where `a` and `b` differ, shown with
/// both values: `batch.seeds: "0..1000" vs "0..999"`.
fn first_difference(at: &str, a: &serde_json::Value, b: &serde_json::Value) -> Option<String> {
    use serde_json::Value;
    let here = |key: &str| {
        if at.is_empty() {
            key.to_owned()
        } else {
            format!("{at}.{key}")
        }
    };
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            keys.into_iter().find_map(|k| match (x.get(k), y.get(k)) {
                (Some(p), Some(q)) => first_difference(&here(k), p, q),
                (p, q) => Some(format!(
                    "{}: {} vs {}",
                    here(k),
                    p.map_or("absent".into(), |v| v.to_string()),
                    q.map_or("absent".into(), |v| v.to_string())
                )),
            })
        }
        _ if a == b => None,
        _ => Some(format!(
            "{}: {a} vs {b}",
            if at.is_empty() { "(document)" } else { at }
        )),
    }
}

/// `graftal manifest merge`: the shard manifests of one batch combined into
/// the manifest the unsharded batch writes. Every shard must come from the
/// same tool version, rule file and batch, and each of the `n` shards must
/// be given exactly once.
pub fn merge(inputs: &[PathBuf]) -> Result<Manifest, Failure> {
    if inputs.is_empty() {
        return Err(Failure::Input(
            "manifest merge needs shard manifests".into(),
        ));
    }
    let manifests: Vec<Manifest> = inputs
        .iter()
        .map(|p| Manifest::read(p))
        .collect::<Result<_, _>>()?;
    let first = &manifests[0];
    let name = |k: usize| inputs[k].display().to_string();
    let Some(first_shard) = first.shard else {
        return Err(Failure::Input(format!(
            "{} is a whole batch's manifest, not a shard's",
            name(0)
        )));
    };
    let mut seen: Vec<Option<usize>> = vec![None; first_shard.count];
    for (k, m) in manifests.iter().enumerate() {
        let Some(shard) = m.shard else {
            return Err(Failure::Input(format!(
                "{} is a whole batch's manifest, not a shard's",
                name(k)
            )));
        };
        // Shard manifests differ in their shard index, summary and
        // variants; everything else names the batch and must agree.
        let identity = |m: &Manifest| Manifest {
            shard: m.shard.map(|s| ShardSpec { index: 0, ..s }),
            summary: Summary::default(),
            variants: Vec::new(),
            ..m.clone()
        };
        if let Some(field) = identity(first).same_batch(&identity(m)) {
            return Err(Failure::Input(format!(
                "{} and {} are not shards of one batch: {field}",
                name(0),
                name(k)
            )));
        }
        if let Some(other) = seen[shard.index].replace(k) {
            return Err(Failure::Input(format!(
                "{} and {} are both shard {}/{}",
                name(other),
                name(k),
                shard.index,
                shard.count
            )));
        }
        if let Some(v) = m
            .variants
            .iter()
            .find(|v| v.index % shard.count != shard.index)
        {
            return Err(Failure::Input(format!(
                "{}: variant {} does not belong to shard {}/{}",
                name(k),
                v.index,
                shard.index,
                shard.count
            )));
        }
    }
    let missing: Vec<String> = seen
        .iter()
        .enumerate()
        .filter(|(_, s)| s.is_none())
        .map(|(i, _)| format!("{i}/{}", first_shard.count))
        .collect();
    if !missing.is_empty() {
        return Err(Failure::Input(format!(
            "shard manifests missing: {}",
            missing.join(", ")
        )));
    }
    let mut variants: Vec<VariantEntry> = manifests
        .iter()
        .flat_map(|m| m.variants.iter().cloned())
        .collect();
    variants.sort_by_key(|v| v.index);
    if let Some(k) = (0..first.variant_count).find(|&k| variants.get(k).map(|v| v.index) != Some(k))
    {
        return Err(Failure::Input(format!(
            "the shards do not list variant {k} exactly once ({} variants in the batch)",
            first.variant_count
        )));
    }
    if variants.len() != first.variant_count {
        return Err(Failure::Input(format!(
            "the shards list {} variants, the batch has {}",
            variants.len(),
            first.variant_count
        )));
    }
    Ok(Manifest {
        shard: None,
        summary: Summary::of(&variants),
        variants,
        ..first.clone()
    })
}

/// Writes `manifest` to `path` atomically, or to standard output for `-`.
pub fn write(path: &Path, manifest: &Manifest) -> Result<(), Failure> {
    let bytes = manifest.to_bytes();
    if path.as_os_str() == "-" {
        return super::write_stdout(&bytes);
    }
    super::files::write_atomic(path, &bytes)
        .map_err(|e| Failure::Runtime(format!("cannot write {}: {e}", path.display())))
}

/// What `manifest check` found wrong with one variant.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    pub index: usize,
    pub message: String,
}

/// Checks every file a manifest lists against its recorded size and
/// SHA-256 (relative paths from the current directory, as the batch wrote
/// them); with `allow_failed`, failed and not-run variants are no problem.
/// Problems come in variant order.
pub fn check(manifest: &Manifest, allow_failed: bool) -> Vec<Problem> {
    use rayon::prelude::*;
    let mut problems: Vec<Problem> = manifest
        .variants
        .par_iter()
        .flat_map_iter(|v| {
            let mut found = Vec::new();
            let problem = |message: String| Problem {
                index: v.index,
                message,
            };
            match v.status {
                Status::Ok => {
                    let output = (v.output.as_str(), v.bytes, v.sha256.as_deref());
                    let extras = v
                        .extra_files
                        .iter()
                        .map(|f| (f.path.as_str(), Some(f.bytes), Some(f.sha256.as_str())));
                    for (path, bytes, sha256) in std::iter::once(output).chain(extras) {
                        if let Some(m) = file_problem(path, bytes, sha256) {
                            found.push(problem(format!("{path}: {m}")));
                        }
                    }
                }
                _ if allow_failed => {}
                Status::Failed => found.push(problem(format!(
                    "{}: variant {} (seed {}) failed: {}",
                    v.output,
                    v.index,
                    v.seed,
                    v.error
                        .as_ref()
                        .map_or("no error recorded", |e| e.message.as_str())
                ))),
                Status::NotRun => found.push(problem(format!(
                    "{}: variant {} (seed {}) did not run",
                    v.output, v.index, v.seed
                ))),
            }
            found
        })
        .collect();
    problems.sort_by_key(|p| p.index);
    problems
}

/// Why the file at `path` is not the one recorded, if it is not.
pub fn file_problem(path: &str, bytes: Option<u64>, sha256: Option<&str>) -> Option<String> {
    if path == "-" {
        return None;
    }
    match super::files::size_and_sha256(Path::new(path)) {
        Err(e) => Some(format!("cannot read: {e}")),
        Ok(None) => Some("missing (or not a regular file)".into()),
        Ok(Some((size, _))) if bytes.is_some_and(|b| b != size) => Some(format!(
            "{size} bytes, the manifest records {}",
            bytes.unwrap_or_default()
        )),
        Ok(Some((_, hash))) if sha256.is_some_and(|h| h != hash) => Some(format!(
            "SHA-256 {hash}, the manifest records {}",
            sha256.unwrap_or_default()
        )),
        Ok(Some(_)) if sha256.is_none() => Some("the manifest records no SHA-256".into()),
        Ok(Some(_)) => None,
    }
}
