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
        let bytes = std::fs::read(path)
            .map_err(|e| Failure::Input(format!("cannot read {}: {e}", path.display())))?;
        serde_json::from_slice(&bytes).map_err(|e| {
            Failure::Input(format!(
                "{}:{}:{}: not a graftal manifest: {e}",
                path.display(),
                e.line(),
                e.column()
            ))
        })
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
        let differs = |what: &str, a: &dyn std::fmt::Debug, b: &dyn std::fmt::Debug| {
            Failure::Input(format!(
                "{} and {} come from different {what}: {a:?} vs {b:?}",
                name(0),
                name(k)
            ))
        };
        if m.graftal_version != first.graftal_version {
            return Err(differs(
                "graftal versions",
                &first.graftal_version,
                &m.graftal_version,
            ));
        }
        if m.rule_sha256 != first.rule_sha256 || m.rules != first.rules {
            return Err(differs(
                "rule files",
                &(&first.rules, &first.rule_sha256),
                &(&m.rules, &m.rule_sha256),
            ));
        }
        if m.batch != first.batch || m.variant_count != first.variant_count {
            return Err(differs(
                "batches (seeds, grid, overrides, template or limits)",
                &first.batch,
                &m.batch,
            ));
        }
        let Some(shard) = m.shard else {
            return Err(Failure::Input(format!(
                "{} is a whole batch's manifest, not a shard's",
                name(k)
            )));
        };
        if shard.count != first_shard.count {
            return Err(differs("shard counts", &first_shard.count, &shard.count));
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
