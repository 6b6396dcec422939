//! The `--cache DIR` store: a variant's files by content address.
//!
//! The caller computes the key (a SHA-256 over everything that decides the
//! bytes; `cli::batch::cache_key`); this module keeps what that key made:
//! named files ("roles": the mesh, its `.mtl`, the stats document, …), each
//! with its size and SHA-256, and an opaque JSON record (the manifest
//! fields). Layout under `DIR/graftal-cache-1/`:
//!
//! ```text
//! entries/ab/abcdef…/meta.json   roles with sizes and hashes, the record
//! entries/ab/abcdef…/<role>      one file per role
//! tmp/                           entries being stored or removed
//! ```
//!
//! Safe for any number of concurrent processes, on any hosts or PID
//! namespaces sharing the folder: an entry is written whole into `tmp/`
//! under a random name and renamed into place (a directory rename is
//! atomic), entries are never modified in place, and every read checks
//! every size and hash, so a torn, evicted or tampered entry is a miss,
//! never wrong bytes. A hit sets `meta.json`'s modification time: eviction
//! (when the store outgrows its size bound) removes the least recently used
//! entries first.

use std::fs::{self, File};
use std::io;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::staged::random_u64;
use super::{hex, read_input};

/// Name of the store's folder inside the cache directory; a new layout
/// gets a new name, so old graftals and new ones never misread each other.
pub const STORE_NAME: &str = "graftal-cache-1";

/// Largest `meta.json` read.
const MAX_META_BYTES: u64 = 64 << 20;

/// Leftovers in `tmp/` older than this belong to a killed process.
const STALE_TMP_AGE: Duration = Duration::from_secs(3600);

/// One stored file of an entry.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct StoredFile {
    pub role: String,
    pub bytes: u64,
    pub sha256: String,
}

#[derive(Serialize, Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct Meta {
    format: String,
    key: String,
    files: Vec<StoredFile>,
    record: serde_json::Value,
}

/// An entry found whole: its record and the verified bytes of the roles
/// asked for.
#[derive(Debug)]
pub struct Hit {
    pub record: serde_json::Value,
    /// (role, bytes, their SHA-256), each checked.
    pub files: Vec<(String, Vec<u8>, String)>,
}

#[cfg(test)]
impl Hit {
    /// The bytes of `role`, if it was asked for.
    pub fn file(&self, role: &str) -> Option<&[u8]> {
        self.files
            .iter()
            .find(|(r, _, _)| r == role)
            .map(|(_, b, _)| b.as_slice())
    }
}

/// What an eviction did.
#[derive(Debug, Default, Clone, Copy)]
pub struct Evicted {
    pub entries: usize,
    pub bytes: u64,
    /// The store's size after it.
    pub remaining: u64,
}

/// An open cache store.
#[derive(Debug)]
pub struct Cache {
    root: PathBuf,
    max_size: u64,
}

impl Cache {
    /// Opens (creating) the store in `dir`.
    pub fn open(dir: &Path, max_size: u64) -> io::Result<Cache> {
        let root = dir.join(STORE_NAME);
        fs::create_dir_all(root.join("entries"))?;
        fs::create_dir_all(root.join("tmp"))?;
        Ok(Cache { root, max_size })
    }

    fn entry_dir(&self, key: &str) -> PathBuf {
        let shard = key.get(..2).unwrap_or("00");
        self.root.join("entries").join(shard).join(key)
    }

    /// The entry for `key` if it is whole and holds every role in
    /// `required`, with those and every other role `also` accepts (each
    /// read and checked against its size and hash); marks it used.
    pub fn lookup(&self, key: &str, also: &dyn Fn(&str) -> bool, required: &[&str]) -> Option<Hit> {
        let dir = self.entry_dir(key);
        let meta_path = dir.join("meta.json");
        let meta: Meta =
            serde_json::from_slice(&read_input(&meta_path, MAX_META_BYTES).ok()?).ok()?;
        if meta.format != STORE_NAME || meta.key != key {
            return None;
        }
        if !required
            .iter()
            .all(|r| meta.files.iter().any(|f| f.role == *r))
        {
            return None;
        }
        let mut files = Vec::new();
        for stored in meta
            .files
            .iter()
            .filter(|f| required.contains(&f.role.as_str()) || also(&f.role))
        {
            let bytes = read_input(&dir.join(&stored.role), stored.bytes).ok()?;
            if bytes.len() as u64 != stored.bytes || hex(&Sha256::digest(&bytes)) != stored.sha256 {
                return None;
            }
            files.push((stored.role.clone(), bytes, stored.sha256.clone()));
        }
        // Least recently used: a hit moves the entry to the front.
        if let Ok(file) = File::options().write(true).open(&meta_path) {
            let _ = file.set_modified(SystemTime::now());
        }
        Some(Hit {
            record: meta.record,
            files,
        })
    }

    /// Stores `files` (role, bytes, and their SHA-256 when the caller
    /// already has it) and `record` under `key`, replacing an entry that
    /// is there. Another process storing the same key at the same time is
    /// harmless: one whole entry wins.
    pub fn store(
        &self,
        key: &str,
        files: &[(&str, &[u8], Option<&str>)],
        record: serde_json::Value,
    ) -> io::Result<()> {
        for (role, _, _) in files {
            let plain = !role.is_empty()
                && role != &"meta.json"
                && role
                    .bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b == b'.' || b == b'-');
            if !plain {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidInput,
                    format!("cache role `{role}` is not a plain file name"),
                ));
            }
        }
        let staging = self
            .root
            .join("tmp")
            .join(format!("store-{:016x}", random_u64()));
        fs::create_dir(&staging)?;
        let written = (|| {
            let mut stored = Vec::with_capacity(files.len());
            for (role, bytes, sha256) in files {
                fs::write(staging.join(role), bytes)?;
                stored.push(StoredFile {
                    role: (*role).to_owned(),
                    bytes: bytes.len() as u64,
                    sha256: sha256.map_or_else(|| hex(&Sha256::digest(bytes)), str::to_owned),
                });
            }
            let meta = Meta {
                format: STORE_NAME.to_owned(),
                key: key.to_owned(),
                files: stored,
                record,
            };
            let text = serde_json::to_vec(&meta).map_err(io::Error::other)?;
            fs::write(staging.join("meta.json"), text)?;
            let target = self.entry_dir(key);
            fs::create_dir_all(target.parent().expect("entries have a parent"))?;
            if fs::rename(&staging, &target).is_ok() {
                return Ok(());
            }
            // An entry is there (whole, torn or lacking a role): set it
            // aside, then move ours in. If another process is doing the
            // same, whichever rename lands last wins; both are whole.
            let aside = self
                .root
                .join("tmp")
                .join(format!("old-{:016x}", random_u64()));
            if fs::rename(&target, &aside).is_ok() {
                let _ = fs::remove_dir_all(&aside);
            }
            fs::rename(&staging, &target)
        })();
        if written.is_err() {
            let _ = fs::remove_dir_all(&staging);
        }
        written
    }

    /// Removes least recently used entries until the store holds at most
    /// its size bound; also clears `tmp/` of what killed processes left.
    pub fn evict(&self) -> io::Result<Evicted> {
        let now = SystemTime::now();
        if let Ok(entries) = fs::read_dir(self.root.join("tmp")) {
            for entry in entries.flatten() {
                let old = entry
                    .metadata()
                    .and_then(|m| m.modified())
                    .is_ok_and(|t| now.duration_since(t).unwrap_or_default() > STALE_TMP_AGE);
                if old {
                    let _ = fs::remove_dir_all(entry.path());
                }
            }
        }
        // (last use, size, entry folder)
        let mut entries: Vec<(SystemTime, u64, PathBuf)> = Vec::new();
        for shard in fs::read_dir(self.root.join("entries"))?.flatten() {
            let Ok(keys) = fs::read_dir(shard.path()) else {
                continue;
            };
            for key in keys.flatten() {
                let dir = key.path();
                let used = fs::metadata(dir.join("meta.json"))
                    .and_then(|m| m.modified())
                    .unwrap_or(SystemTime::UNIX_EPOCH);
                let size = fs::read_dir(&dir)
                    .map(|files| {
                        files
                            .flatten()
                            .filter_map(|f| f.metadata().ok())
                            .map(|m| m.len())
                            .sum()
                    })
                    .unwrap_or(0);
                entries.push((used, size, dir));
            }
        }
        let mut total: u64 = entries.iter().map(|e| e.1).sum();
        let mut evicted = Evicted::default();
        if total > self.max_size {
            entries.sort();
            for (_, size, dir) in entries {
                if total <= self.max_size {
                    break;
                }
                let aside = self
                    .root
                    .join("tmp")
                    .join(format!("evict-{:016x}", random_u64()));
                if fs::rename(&dir, &aside).is_ok() {
                    let _ = fs::remove_dir_all(&aside);
                    total -= size;
                    evicted.entries += 1;
                    evicted.bytes += size;
                }
            }
        }
        evicted.remaining = total;
        Ok(evicted)
    }
}

/// `--cache-max-size`: bytes, or a number with K, M, G or T (powers of
/// 1024; `KiB`, `MB`… are read the same).
pub fn parse_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(t.len());
    let (number, unit) = (t[..split].trim(), t[split..].to_ascii_uppercase());
    let shift = match unit.trim_end_matches("IB").trim_end_matches('B') {
        "" => 0,
        "K" => 10,
        "M" => 20,
        "G" => 30,
        "T" => 40,
        _ => {
            return Err(format!(
                "`{text}`: sizes are bytes or K, M, G, T (e.g. 500M, 10G)"
            ))
        }
    };
    let value: f64 = number
        .parse()
        .map_err(|_| format!("`{text}` is not a size such as 500M or 10G"))?;
    let bytes = value * (1u64 << shift) as f64;
    if !(0.0..1.8e19).contains(&bytes) {
        return Err(format!("`{text}`: a size must be positive and finite"));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn store_of(dir: &Path, max: u64) -> Cache {
        Cache::open(dir, max).unwrap()
    }

    #[test]
    fn stores_and_finds_whole_entries_only() {
        let dir = tempfile::tempdir().unwrap();
        let cache = store_of(dir.path(), 1 << 20);
        let key = "ab".repeat(32);
        assert!(cache.lookup(&key, &|_| false, &["mesh"]).is_none());
        let record = serde_json::json!({"faces": 6});
        cache
            .store(
                &key,
                &[("mesh", b"solid", None), ("stats.json", b"{}", None)],
                record.clone(),
            )
            .unwrap();
        let hit = cache
            .lookup(&key, &|r| r == "stats.json", &["mesh"])
            .unwrap();
        assert_eq!(hit.file("mesh"), Some(&b"solid"[..]));
        assert_eq!(hit.record, record);
        // A role it does not hold is a miss.
        assert!(cache.lookup(&key, &|_| true, &["thumbnail-64"]).is_none());
        // A tampered file is a miss, never wrong bytes.
        let mesh = cache.entry_dir(&key).join("mesh");
        fs::write(&mesh, b"SOLID").unwrap();
        assert!(cache.lookup(&key, &|_| false, &["mesh"]).is_none());
        // Storing again replaces it.
        cache
            .store(&key, &[("mesh", b"solid", None)], serde_json::Value::Null)
            .unwrap();
        assert_eq!(
            cache
                .lookup(&key, &|_| false, &["mesh"])
                .unwrap()
                .file("mesh"),
            Some(&b"solid"[..])
        );
        // A torn meta is a miss.
        fs::write(cache.entry_dir(&key).join("meta.json"), b"{\"format\"").unwrap();
        assert!(cache.lookup(&key, &|_| false, &[]).is_none());
        assert!(cache
            .store(&key, &[("../x", b"", None)], serde_json::Value::Null)
            .is_err());
        assert!(cache
            .store(&key, &[("meta.json", b"", None)], serde_json::Value::Null)
            .is_err());
        // Nothing is left in tmp/.
        assert_eq!(fs::read_dir(cache.root.join("tmp")).unwrap().count(), 0);
    }

    #[test]
    fn eviction_removes_the_least_recently_used_first() {
        let dir = tempfile::tempdir().unwrap();
        let cache = store_of(dir.path(), 2700);
        let keys: Vec<String> = (0..4).map(|k| format!("{k:02x}").repeat(32)).collect();
        for (k, key) in keys.iter().enumerate() {
            cache
                .store(
                    key,
                    &[("mesh", &[k as u8; 1000], None)],
                    serde_json::Value::Null,
                )
                .unwrap();
            // Distinct, increasing last-use times.
            let meta = cache.entry_dir(key).join("meta.json");
            let t = SystemTime::now() - Duration::from_secs(100 - k as u64);
            File::options()
                .write(true)
                .open(meta)
                .unwrap()
                .set_modified(t)
                .unwrap();
        }
        // Using the oldest makes it the newest.
        assert!(cache.lookup(&keys[0], &|_| false, &["mesh"]).is_some());
        let evicted = cache.evict().unwrap();
        assert_eq!(evicted.entries, 2, "{evicted:?}");
        assert!(evicted.remaining <= 2700);
        let present: Vec<bool> = keys
            .iter()
            .map(|k| cache.lookup(k, &|_| false, &["mesh"]).is_some())
            .collect();
        assert_eq!(present, [true, false, false, true]);
    }

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("1000").unwrap(), 1000);
        assert_eq!(parse_size("500M").unwrap(), 500 << 20);
        assert_eq!(parse_size("10G").unwrap(), 10 << 30);
        assert_eq!(parse_size("1.5 GiB").unwrap(), 3 << 29);
        assert_eq!(parse_size("2kb").unwrap(), 2048);
        for bad in ["", "G", "-1G", "5X", "1e30T"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }
}
