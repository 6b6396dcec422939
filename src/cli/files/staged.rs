//! Writing outputs all or none, safely in folders other writers share.
//!
//! [`Staged`] writes each output to a temporary file beside its target and
//! renames them all only when every one was written; dropped uncommitted,
//! it removes them. A temporary file is named
//! `.{name}.graftal-{host}-{pid}-{random}.tmp`: the host's id, the process
//! id *and* 64 random bits, created with `O_EXCL`, so that no two writers
//! collide whether they run on other hosts of a shared file system or in
//! other PID namespaces on this one (where process ids repeat).
//!
//! graftal never removes a temporary file it did not create: whether
//! another writer is still alive cannot be told across hosts and PID
//! namespaces (issue 33: a sweep by `/proc` lost variants of shards in
//! other namespaces). Files left by a killed run are *reported* the first
//! time a run writes into their folder, once they are older than
//! [`STALE_REPORT_AGE`]; they are removed only by `graftal clean`, or by
//! a run given `--remove-stale-temps AGE`.

use std::collections::BTreeSet;
use std::ffi::OsString;
use std::fs::{self, OpenOptions};
use std::hash::{BuildHasher, Hasher};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, SystemTime};

/// Marker in temporary file names.
const TEMP_MARK: &str = ".graftal-";
const TEMP_SUFFIX: &str = ".tmp";

/// Temporary files older than this are mentioned when a run first writes
/// beside them: no output takes an hour between its write and its rename.
pub const STALE_REPORT_AGE: Duration = Duration::from_secs(3600);

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// What a run does with other writers' old temporary files.
#[derive(Clone, Copy, Debug, Default)]
pub struct StalePolicy {
    /// Remove graftal temporary files older than this in every folder the
    /// run writes to (`--remove-stale-temps`); `None`: only report them.
    pub remove_older_than: Option<Duration>,
}

static POLICY: Mutex<StalePolicy> = Mutex::new(StalePolicy {
    remove_older_than: None,
});

/// Folders this process has looked at for stale temporary files.
static SEEN: Mutex<BTreeSet<PathBuf>> = Mutex::new(BTreeSet::new());

/// Warnings about stale temporary files, for the command to print.
static NOTICES: Mutex<Vec<String>> = Mutex::new(Vec::new());

/// Sets what this process does with stale temporary files it finds.
pub fn set_stale_policy(policy: StalePolicy) {
    *POLICY.lock().unwrap_or_else(|e| e.into_inner()) = policy;
}

/// The warnings gathered so far (each once), emptied.
pub fn take_notices() -> Vec<String> {
    std::mem::take(&mut *NOTICES.lock().unwrap_or_else(|e| e.into_inner()))
}

/// Outputs of one run, written all or none (see the module doc).
#[derive(Debug, Default)]
pub struct Staged {
    /// (temporary file, target), in staging order.
    files: Vec<(PathBuf, PathBuf)>,
}

impl Staged {
    pub fn new() -> Staged {
        Staged::default()
    }

    /// Writes `bytes` to a temporary file beside `target` (creating its
    /// directory if needed); the target is untouched until [`Self::commit`].
    pub fn stage(&mut self, target: &Path, bytes: &[u8]) -> io::Result<()> {
        self.stage_parts(target, [bytes])
    }

    /// [`Self::stage`] of the bytes `parts` give in order (a file's
    /// columns, written without joining them first).
    pub fn stage_parts<'a>(
        &mut self,
        target: &Path,
        parts: impl IntoIterator<Item = &'a [u8]>,
    ) -> io::Result<()> {
        let temp = self.create_temp(target, |file| {
            for part in parts {
                file.write_all(part)?;
            }
            file.flush()
        })?;
        self.files.push((temp, target.to_path_buf()));
        Ok(())
    }

    /// Creates a fresh temporary file beside `target` and fills it; on
    /// failure the temporary file is removed.
    fn create_temp(
        &mut self,
        target: &Path,
        fill: impl FnOnce(&mut fs::File) -> io::Result<()>,
    ) -> io::Result<PathBuf> {
        let file_name = target.file_name().ok_or_else(|| {
            io::Error::new(io::ErrorKind::InvalidInput, "output path has no file name")
        })?;
        let dir = parent_dir(target);
        fs::create_dir_all(&dir)?;
        look_for_stale_once(&dir);
        // 64 random bits make a clash all but impossible; `create_new`
        // makes it harmless: the next name is tried.
        let mut attempts = 0;
        let (temp, mut file) = loop {
            let temp = dir.join(temp_name(file_name));
            match OpenOptions::new().write(true).create_new(true).open(&temp) {
                Ok(file) => break (temp, file),
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists && attempts < 8 => {
                    attempts += 1;
                }
                Err(e) => return Err(e),
            }
        };
        match fill(&mut file) {
            Ok(()) => Ok(temp),
            Err(e) => {
                drop(file);
                let _ = fs::remove_file(&temp);
                Err(e)
            }
        }
    }

    /// Renames every staged file over its target. A rename that fails
    /// stops the commit; the files not yet renamed are removed.
    pub fn commit(mut self) -> Result<(), (PathBuf, io::Error)> {
        let files = std::mem::take(&mut self.files);
        let mut pending = files.into_iter();
        while let Some((temp, target)) = pending.next() {
            if let Err(e) = fs::rename(&temp, &target) {
                let _ = fs::remove_file(&temp);
                for (rest, _) in pending {
                    let _ = fs::remove_file(rest);
                }
                return Err((target, e));
            }
        }
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        for (temp, _) in &self.files {
            let _ = fs::remove_file(temp);
        }
    }
}

/// Writes one file all or nothing (a [`Staged`] of one).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let mut staged = Staged::new();
    staged.stage(path, bytes)?;
    staged.commit().map_err(|(_, e)| e)
}

/// The directory a file goes in (`.` for a bare name).
pub(super) fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// `.{name}.graftal-{host}-{pid}-{random}.tmp`.
fn temp_name(file_name: &std::ffi::OsStr) -> OsString {
    let mut name = OsString::from(".");
    name.push(file_name);
    name.push(format!(
        "{TEMP_MARK}{:08x}-{}-{:016x}{TEMP_SUFFIX}",
        host_id(),
        std::process::id(),
        random_u64()
    ));
    name
}

/// 64 bits no other process can predict: std's `RandomState` is keyed
/// from the operating system's random source once per thread (and moved
/// on per instance), hashed with the process id, a counter and the clock.
pub(super) fn random_u64() -> u64 {
    let mut hasher = std::collections::hash_map::RandomState::new().build_hasher();
    hasher.write_u32(std::process::id());
    hasher.write_u64(COUNTER.fetch_add(1, Ordering::Relaxed));
    if let Ok(t) = SystemTime::now().duration_since(SystemTime::UNIX_EPOCH) {
        hasher.write_u128(t.as_nanos());
    }
    hasher.finish()
}

/// A 32-bit id of this host (FNV-1a of its name), for telling whose a
/// temporary file is; uniqueness comes from the random part.
fn host_id() -> u32 {
    static ID: OnceLock<u32> = OnceLock::new();
    *ID.get_or_init(|| {
        let name = fs::read_to_string("/proc/sys/kernel/hostname")
            .ok()
            .or_else(|| std::env::var("HOSTNAME").ok())
            .or_else(|| std::env::var("COMPUTERNAME").ok())
            .unwrap_or_default();
        let mut hash: u32 = 0x811c_9dc5;
        for byte in name.trim().bytes() {
            hash ^= u32::from(byte);
            hash = hash.wrapping_mul(0x0100_0193);
        }
        hash
    })
}

/// Whether `name` is a graftal temporary file: this version's
/// `.{name}.graftal-{host}-{pid}-{random}.tmp` or the earlier
/// `.{name}.graftal-{pid}-{n}.tmp`.
pub fn is_temp_name(name: &str) -> bool {
    let Some(body) = name
        .strip_prefix('.')
        .and_then(|n| n.strip_suffix(TEMP_SUFFIX))
    else {
        return false;
    };
    let Some((target, tail)) = body.rsplit_once(TEMP_MARK) else {
        return false;
    };
    let parts: Vec<&str> = tail.split('-').collect();
    let hex = |s: &str, n: usize| s.len() == n && s.bytes().all(|b| b.is_ascii_hexdigit());
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    !target.is_empty()
        && match parts.as_slice() {
            [host, pid, random] => hex(host, 8) && digits(pid) && hex(random, 16),
            [pid, counter] => digits(pid) && digits(counter),
            _ => false,
        }
}

/// A graftal temporary file found in a folder, with its age.
#[derive(Debug, Clone)]
pub struct TempFile {
    pub path: PathBuf,
    pub age: Duration,
}

/// The graftal temporary files directly in `dir`, oldest first.
fn temp_files_in(dir: &Path) -> Vec<TempFile> {
    let Ok(entries) = fs::read_dir(dir) else {
        return Vec::new();
    };
    let now = SystemTime::now();
    let mut found: Vec<TempFile> = entries
        .flatten()
        .filter(|e| e.file_name().to_str().is_some_and(is_temp_name))
        .filter_map(|e| {
            let meta = e.metadata().ok()?;
            let modified = meta.modified().ok()?;
            meta.is_file().then(|| TempFile {
                path: e.path(),
                age: now.duration_since(modified).unwrap_or_default(),
            })
        })
        .collect();
    found.sort_by(|a, b| b.age.cmp(&a.age).then_with(|| a.path.cmp(&b.path)));
    found
}

/// The first time this process writes into `dir`: removes (by the
/// stale policy) or reports the temporary files older writers left.
fn look_for_stale_once(dir: &Path) {
    {
        let mut seen = SEEN.lock().unwrap_or_else(|e| e.into_inner());
        if !seen.insert(dir.to_path_buf()) {
            return;
        }
    }
    let policy = *POLICY.lock().unwrap_or_else(|e| e.into_inner());
    let threshold = policy.remove_older_than.unwrap_or(STALE_REPORT_AGE);
    let stale: Vec<TempFile> = temp_files_in(dir)
        .into_iter()
        .filter(|t| t.age >= threshold)
        .collect();
    let Some(oldest) = stale.first() else {
        return;
    };
    let notice = if policy.remove_older_than.is_some() {
        let removed = stale
            .iter()
            .filter(|t| fs::remove_file(&t.path).is_ok())
            .count();
        format!(
            "{}: removed {removed} graftal temporary file(s) older than {} (--remove-stale-temps)",
            dir.display(),
            describe_age(threshold)
        )
    } else {
        format!(
            "{}: {} graftal temporary file(s) older than {} (the oldest, {}, is {} old): left by a run that was killed; once no run writes here, remove them with `graftal clean {}` (or pass --remove-stale-temps AGE)",
            dir.display(),
            stale.len(),
            describe_age(threshold),
            oldest.path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
            describe_age(oldest.age),
            dir.display()
        )
    };
    NOTICES
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(notice);
}

/// What `graftal clean` did (or would do, with `dry_run`).
#[derive(Debug, Default)]
pub struct Cleaned {
    /// Files removed (or to be removed), in path order.
    pub removed: Vec<TempFile>,
    /// Files that could not be removed, with why.
    pub failed: Vec<(PathBuf, String)>,
}

/// Deepest folder `graftal clean` descends into.
const CLEAN_DEPTH: usize = 32;

/// Removes the graftal temporary files under `dir` (following no symbolic
/// links) that are at least `older_than` old (all of them for `None`).
pub fn clean(dir: &Path, older_than: Option<Duration>, dry_run: bool) -> io::Result<Cleaned> {
    if !fs::metadata(dir)?.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a directory",
        ));
    }
    let mut cleaned = Cleaned::default();
    let mut stack = vec![(dir.to_path_buf(), 0)];
    while let Some((folder, depth)) = stack.pop() {
        for temp in temp_files_in(&folder) {
            if older_than.is_some_and(|age| temp.age < age) {
                continue;
            }
            match if dry_run {
                Ok(())
            } else {
                fs::remove_file(&temp.path)
            } {
                Ok(()) => cleaned.removed.push(temp),
                Err(e) => cleaned.failed.push((temp.path, e.to_string())),
            }
        }
        if depth < CLEAN_DEPTH {
            if let Ok(entries) = fs::read_dir(&folder) {
                for entry in entries.flatten() {
                    if entry.file_type().is_ok_and(|t| t.is_dir()) {
                        stack.push((entry.path(), depth + 1));
                    }
                }
            }
        }
    }
    cleaned.removed.sort_by(|a, b| a.path.cmp(&b.path));
    Ok(cleaned)
}

/// `90s`, `15m`, `2h`, `7d` or plain seconds.
pub fn parse_age(text: &str) -> Result<Duration, String> {
    let t = text.trim();
    let (number, unit) = match t.char_indices().find(|(_, c)| c.is_ascii_alphabetic()) {
        Some((i, _)) => (&t[..i], &t[i..]),
        None => (t, "s"),
    };
    let scale = match unit {
        "s" => 1.0,
        "m" | "min" => 60.0,
        "h" => 3600.0,
        "d" => 86400.0,
        _ => {
            return Err(format!(
                "`{text}`: the units are s, m, h and d (e.g. 30m, 2h)"
            ))
        }
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not an age such as 30m, 2h or 7d"))?;
    let seconds = value * scale;
    if !(0.0..1e12).contains(&seconds) {
        return Err(format!("`{text}`: an age must be positive and finite"));
    }
    Ok(Duration::from_secs_f64(seconds))
}

/// An age in the largest whole unit: `3 h`, `45 min`, `20 s`.
pub fn describe_age(age: Duration) -> String {
    let s = age.as_secs();
    match s {
        s if s >= 86400 && s % 86400 == 0 => format!("{} d", s / 86400),
        s if s >= 3600 => format!("{} h", s / 3600),
        s if s >= 60 => format!("{} min", s / 60),
        s => format!("{s} s"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leftovers(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(TEMP_SUFFIX))
            .collect();
        names.sort();
        names
    }

    #[test]
    fn writes_and_replaces() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.obj");
        write_atomic(&target, b"first").unwrap();
        assert_eq!(fs::read(&target).unwrap(), b"first");
        write_atomic(&target, b"second, longer").unwrap();
        assert_eq!(fs::read(&target).unwrap(), b"second, longer");
        write_atomic(&target, b"").unwrap();
        assert_eq!(fs::read(&target).unwrap(), b"");
        assert!(leftovers(dir.path()).is_empty());
    }

    #[test]
    fn all_outputs_or_none() {
        let dir = tempfile::tempdir().unwrap();
        let (mesh, stats) = (dir.path().join("m.obj"), dir.path().join("m.json"));
        // Dropped before commit: nothing appears, nothing is left.
        let mut staged = Staged::new();
        staged.stage(&mesh, b"mesh").unwrap();
        staged.stage(&stats, b"stats").unwrap();
        drop(staged);
        assert!(!mesh.exists() && !stats.exists());
        assert!(leftovers(dir.path()).is_empty());
        // A second output that cannot be written: the first is not written either.
        let mut staged = Staged::new();
        staged.stage(&mesh, b"mesh").unwrap();
        let unwritable = dir.path().join("file-not-dir");
        fs::write(&unwritable, b"x").unwrap();
        assert!(staged.stage(&unwritable.join("stats.json"), b"s").is_err());
        drop(staged);
        assert!(!mesh.exists());
        assert!(leftovers(dir.path()).is_empty());
        // Committed: both.
        let mut staged = Staged::new();
        staged.stage(&mesh, b"mesh").unwrap();
        staged.stage(&stats, b"stats").unwrap();
        staged.commit().unwrap();
        assert_eq!(fs::read(&stats).unwrap(), b"stats");
        assert!(leftovers(dir.path()).is_empty());
    }

    #[test]
    fn failure_leaves_nothing_behind() {
        let dir = tempfile::tempdir().unwrap();
        // Renaming a file over a non-empty directory fails after the temp file was written.
        let target = dir.path().join("occupied");
        fs::create_dir(&target).unwrap();
        fs::write(target.join("keep"), b"x").unwrap();
        assert!(write_atomic(&target, b"data").is_err());
        assert!(leftovers(dir.path()).is_empty());
        assert!(target.join("keep").exists());
        // No file name at all.
        assert!(write_atomic(Path::new("/"), b"data").is_err());
    }

    #[test]
    fn temporary_names_are_recognised_and_never_repeat() {
        let names: BTreeSet<String> = (0..1000)
            .map(|_| temp_name("a.glb".as_ref()).to_string_lossy().into_owned())
            .collect();
        assert_eq!(names.len(), 1000);
        assert!(names.iter().all(|n| is_temp_name(n)), "{names:?}");
        assert!(is_temp_name(".m.obj.graftal-4194304-7.tmp"));
        assert!(is_temp_name(
            ".a.b.graftal-0badf00d-12-0123456789abcdef.tmp"
        ));
        for not_ours in [
            ".notes.tmp",
            "a.graftal-12-3.tmp",
            ".a.graftal-x-3.tmp",
            ".graftal-12-3.tmp",
            ".a.graftal-0badf00d-12-0123.tmp",
            ".a.graftal-0badf00d-12-0123456789abcdef.tmp.bak",
        ] {
            assert!(!is_temp_name(not_ours), "{not_ours}");
        }
    }

    /// Sets a file's modification time `age` into the past.
    fn age_file(path: &Path, age: Duration) {
        let file = fs::File::options().write(true).open(path).unwrap();
        file.set_modified(SystemTime::now() - age).unwrap();
    }

    #[test]
    fn other_writers_temporary_files_are_reported_never_removed() {
        let dir = tempfile::tempdir().unwrap();
        let old = dir.path().join(".m.obj.graftal-4194304-7.tmp");
        let fresh = dir
            .path()
            .join(".n.obj.graftal-0badf00d-12-0123456789abcdef.tmp");
        let foreign = dir.path().join(".notes.tmp");
        for f in [&old, &fresh, &foreign] {
            fs::write(f, b"x").unwrap();
        }
        age_file(&old, Duration::from_secs(3 * 3600));
        write_atomic(&dir.path().join("other.obj"), b"y").unwrap();
        assert!(old.exists() && fresh.exists() && foreign.exists());
        let notices = take_notices();
        let mine: Vec<&String> = notices
            .iter()
            .filter(|n| n.starts_with(&dir.path().display().to_string()))
            .collect();
        assert_eq!(mine.len(), 1, "{notices:?}");
        assert!(
            mine[0].contains("1 graftal temporary file(s)"),
            "{}",
            mine[0]
        );
        assert!(mine[0].contains("3 h old") && mine[0].contains("graftal clean"));
    }

    #[test]
    fn clean_removes_temporary_files_by_age_only() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("a/b");
        fs::create_dir_all(&sub).unwrap();
        let old = sub.join(".m.obj.graftal-0badf00d-12-0123456789abcdef.tmp");
        let new = dir.path().join(".n.obj.graftal-77-1.tmp");
        let keep = dir.path().join("n.obj");
        for f in [&old, &new, &keep] {
            fs::write(f, b"x").unwrap();
        }
        age_file(&old, Duration::from_secs(7200));
        let dry = clean(dir.path(), None, true).unwrap();
        assert_eq!(dry.removed.len(), 2);
        assert!(old.exists() && new.exists());
        let aged = clean(dir.path(), Some(Duration::from_secs(3600)), false).unwrap();
        assert_eq!(aged.removed.len(), 1);
        assert_eq!(aged.removed[0].path, old);
        assert!(!old.exists() && new.exists() && keep.exists());
        let all = clean(dir.path(), None, false).unwrap();
        assert_eq!(all.removed.len(), 1);
        assert!(!new.exists() && keep.exists());
        assert!(clean(&keep, None, false).is_err());
    }

    #[test]
    fn ages_parse_and_print() {
        assert_eq!(parse_age("90").unwrap(), Duration::from_secs(90));
        assert_eq!(parse_age("15m").unwrap(), Duration::from_secs(900));
        assert_eq!(parse_age("2h").unwrap(), Duration::from_secs(7200));
        assert_eq!(parse_age("1.5d").unwrap(), Duration::from_secs(129_600));
        for bad in ["", "h", "-1h", "2w", "nan", "1e300d"] {
            assert!(parse_age(bad).is_err(), "{bad}");
        }
        assert_eq!(describe_age(Duration::from_secs(7200)), "2 h");
        assert_eq!(describe_age(Duration::from_secs(86400 * 2)), "2 d");
        assert_eq!(describe_age(Duration::from_secs(59)), "59 s");
    }
}
