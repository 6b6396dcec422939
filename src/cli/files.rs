//! Every file graftal reads or writes goes through here (nothing below the
//! command line touches the file system).
//!
//! Reading: inputs must be regular files (a FIFO or `/dev/zero` named as a
//! mesh is refused before it is opened for reading), and the files a mesh
//! refers to (a `.gltf`'s external buffers) must stay inside the mesh
//! file's directory — no absolute paths, no `..`, no symlink out of it —
//! unless the user passes `--allow-outside-paths`; at most `byteLength`
//! bytes of them are read.
//!
//! Writing: all outputs of a run or none. [`Staged`] writes each output to
//! a temporary file beside its target, `.{name}.graftal-{pid}-{n}.tmp`, and
//! renames them all only when every one was written; dropped uncommitted,
//! it removes them. A process killed before that leaves its temporary
//! files behind: the next graftal that writes into the directory removes
//! those whose process is gone (on Linux, where `/proc` tells), and the
//! pattern is documented so that users can remove them too.

use std::collections::BTreeSet;
use std::ffi::OsString;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Read, Write};
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use std::sync::Arc;

use sha2::{Digest, Sha256};

use super::Failure;
use crate::grammar::Input;
use crate::io::{self as meshio, IndexedMesh, MeshFormat};
use crate::rules::compile::source_from_bytes;
use crate::rules::diagnostic::SourceFile;
use crate::rules::{compile_source, Override, Program, RuleError};

/// How far input files may reach.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct InputPolicy {
    /// Follow absolute and `..` references out of a file's directory.
    pub allow_outside: bool,
}

/// Reads a rule file (a regular file, UTF-8: a bad byte is located).
pub fn read_rules(path: &Path) -> Result<SourceFile, RuleError> {
    let name = path.display().to_string();
    let bytes = read_input(path).map_err(|err| {
        let empty = SourceFile {
            name: name.clone(),
            text: String::new(),
        };
        RuleError::at(&empty, None, format!("cannot read rule file: {err}"))
    })?;
    source_from_bytes(name, bytes)
}

/// Reads and compiles a rule file; its paths resolve against its directory.
pub fn compile_rules(path: &Path, overrides: &[Override]) -> Result<Program, RuleError> {
    let file = read_rules(path)?;
    compile_source(&file, overrides, &base_dir(path))
}

/// The directory a rule file's paths resolve against (`.` for a bare file
/// name: an empty path cannot be canonicalized to confine references).
pub fn base_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Reads a whole input file, refusing anything but a regular file.
pub fn read_input(path: &Path) -> io::Result<Vec<u8>> {
    let file = open_regular(path)?;
    let mut bytes = Vec::new();
    (&file).read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// Opens `path` for reading if it is a regular file. The type is checked
/// before opening (opening a FIFO blocks until a writer comes) and again
/// on the open file (in case the name was swapped in between).
fn open_regular(path: &Path) -> io::Result<File> {
    let not_regular = || {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a regular file (a directory, device or pipe)",
        )
    };
    if !fs::metadata(path)?.is_file() {
        return Err(not_regular());
    }
    let file = File::open(path)?;
    if !file.metadata()?.is_file() {
        return Err(not_regular());
    }
    Ok(file)
}

/// Reads and decodes a mesh file (format by extension), its external
/// buffers confined by `policy`.
pub fn read_mesh(path: &Path, policy: InputPolicy) -> Result<IndexedMesh, String> {
    let bytes = read_input(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    decode_mesh(path, &bytes, policy)
}

/// Decodes the bytes of mesh file `path` (format by extension), reading
/// its external buffers beside it within `policy`.
fn decode_mesh(path: &Path, bytes: &[u8], policy: InputPolicy) -> Result<IndexedMesh, String> {
    let format = MeshFormat::from_path(path).map_err(|e| e.to_string())?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut resolve = |uri: &str, max: u64| read_beside(&dir, uri, max, policy);
    meshio::decode_with(bytes, format, path, &mut resolve).map_err(|e| e.to_string())
}

/// The files a program needs, read once (a batch shares them).
#[derive(Debug, Clone)]
pub struct Inputs {
    /// Decoded meshes by resource index (their distance fields built on
    /// first use), for `RunOptions::inputs`.
    pub meshes: Arc<[Input]>,
    /// (path as written, SHA-256 of the bytes), for the manifest.
    pub hashes: Vec<(String, String)>,
}

/// Reads every resource of `program` (imports, relative to the rule
/// file and confined to its directory by `policy`). An unreadable or
/// malformed one is an input error at its place in the rule file.
pub fn load_inputs(program: &Program, policy: InputPolicy) -> Result<Inputs, Failure> {
    let mut meshes = Vec::with_capacity(program.resources.len());
    let mut hashes = Vec::with_capacity(program.resources.len());
    for resource in &program.resources {
        let fail = |e: String| {
            Failure::Input(format!(
                "{}: cannot import `{}`: {e}",
                resource.location, resource.written
            ))
        };
        let bytes =
            read_beside(&program.base_dir, &resource.written, u64::MAX, policy).map_err(fail)?;
        let mesh = decode_mesh(&resource.path, &bytes, policy).map_err(fail)?;
        hashes.push((
            resource.written.clone(),
            super::batch::hex(&Sha256::digest(&bytes)),
        ));
        meshes.push(Input::new(Arc::new(mesh)));
    }
    Ok(Inputs {
        meshes: Arc::from(meshes),
        hashes,
    })
}

/// At most `max` bytes of the file `reference` names relative to `dir`,
/// which it may not leave unless `policy` allows it.
pub fn read_beside(
    dir: &Path,
    reference: &str,
    max: u64,
    policy: InputPolicy,
) -> Result<Vec<u8>, String> {
    let relative = Path::new(reference);
    if !policy.allow_outside {
        let escapes = relative
            .components()
            .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir));
        if escapes {
            return Err(format!(
                "{reference:?} leaves the directory of the file that names it (absolute or `..`); pass --allow-outside-paths to follow it"
            ));
        }
    }
    let path = dir.join(relative);
    if !policy.allow_outside {
        // A symlink inside the directory may still point out of it.
        let (Ok(base), Ok(target)) = (dir.canonicalize(), path.canonicalize()) else {
            return Err(format!("cannot find {}", path.display()));
        };
        if !target.starts_with(&base) {
            return Err(format!(
                "{} resolves outside {} (a symbolic link); pass --allow-outside-paths to follow it",
                path.display(),
                base.display()
            ));
        }
    }
    let file = open_regular(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut bytes = Vec::new();
    file.take(max)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(bytes)
}

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Directories this process has swept of stale temporary files.
static SWEPT: Mutex<BTreeSet<PathBuf>> = Mutex::new(BTreeSet::new());

/// Marker in temporary file names: `.{name}.graftal-{pid}-{n}.tmp`.
const TEMP_MARK: &str = ".graftal-";
const TEMP_SUFFIX: &str = ".tmp";

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
        let file_name = target.file_name().ok_or_else(|| {
            io::Error::new(io::ErrorKind::InvalidInput, "output path has no file name")
        })?;
        let dir = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        fs::create_dir_all(&dir)?;
        sweep_once(&dir);
        let mut temp_name = OsString::from(".");
        temp_name.push(file_name);
        temp_name.push(format!(
            "{TEMP_MARK}{}-{}{TEMP_SUFFIX}",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let temp = dir.join(temp_name);
        let written = (|| {
            let mut file = OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&temp)?;
            file.write_all(bytes)?;
            file.flush()
        })();
        match written {
            Ok(()) => {
                self.files.push((temp, target.to_path_buf()));
                Ok(())
            }
            Err(e) => {
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

/// Removes, once per process and directory, the temporary files of
/// graftal processes that no longer run (a `kill -9` mid-write).
fn sweep_once(dir: &Path) {
    let key = dir.to_path_buf();
    {
        let mut swept = SWEPT.lock().unwrap_or_else(|e| e.into_inner());
        if !swept.insert(key) {
            return;
        }
    }
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(temp_owner) else {
            continue;
        };
        if pid != std::process::id() && !process_alive(pid) {
            let _ = fs::remove_file(entry.path());
        }
    }
}

/// The process id in a temporary file name of ours, if it is one.
fn temp_owner(name: &str) -> Option<u32> {
    let body = name.strip_prefix('.')?.strip_suffix(TEMP_SUFFIX)?;
    let (_, tail) = body.rsplit_once(TEMP_MARK)?;
    let (pid, counter) = tail.split_once('-')?;
    counter.parse::<u64>().ok()?;
    pid.parse().ok()
}

/// Whether process `pid` runs; `true` where that cannot be told, so that
/// nothing of a live process is removed.
fn process_alive(pid: u32) -> bool {
    if cfg!(target_os = "linux") {
        Path::new("/proc").join(pid.to_string()).exists()
    } else {
        true
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
    fn stale_temporary_files_of_dead_processes_are_swept() {
        let dir = tempfile::tempdir().unwrap();
        // pid 4194304 is above Linux's largest (2^22): never alive.
        let stale = dir.path().join(".m.obj.graftal-4194304-7.tmp");
        let mine = dir
            .path()
            .join(format!(".m.obj.graftal-{}-999999.tmp", std::process::id()));
        let foreign = dir.path().join(".notes.tmp");
        for f in [&stale, &mine, &foreign] {
            fs::write(f, b"x").unwrap();
        }
        write_atomic(&dir.path().join("other.obj"), b"y").unwrap();
        assert_eq!(!stale.exists(), cfg!(target_os = "linux"));
        assert!(mine.exists() && foreign.exists());
        assert_eq!(temp_owner(".a.b.graftal-12-3.tmp"), Some(12));
        assert_eq!(temp_owner(".a.graftal-x-3.tmp"), None);
        assert_eq!(temp_owner("a.graftal-12-3.tmp"), None);
    }

    #[test]
    fn inputs_must_be_regular_files_inside_their_directory() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_input(dir.path()).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
        if Path::new("/dev/zero").exists() {
            let e = read_input(Path::new("/dev/zero")).unwrap_err();
            assert!(e.to_string().contains("not a regular file"), "{e}");
        }
        fs::write(dir.path().join("data.bin"), [7u8; 100]).unwrap();
        let strict = InputPolicy::default();
        assert_eq!(
            read_beside(dir.path(), "data.bin", 10, strict).unwrap(),
            [7u8; 10]
        );
        let sub = dir.path().join("sub");
        fs::create_dir(&sub).unwrap();
        for bad in ["../data.bin", "/etc/hostname", "sub/../../x"] {
            let e = read_beside(&sub, bad, 10, strict).unwrap_err();
            assert!(e.contains("--allow-outside-paths"), "{bad}: {e}");
        }
        let allow = InputPolicy {
            allow_outside: true,
        };
        assert_eq!(
            read_beside(&sub, "../data.bin", 4, allow).unwrap(),
            [7u8; 4]
        );
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(dir.path().join("data.bin"), sub.join("link.bin")).unwrap();
            let e = read_beside(&sub, "link.bin", 4, strict).unwrap_err();
            assert!(e.contains("symbolic link"), "{e}");
            let e = read_beside(dir.path(), "zero", 4, strict).unwrap_err();
            assert!(e.contains("cannot find"), "{e}");
            std::os::unix::fs::symlink("/dev/zero", dir.path().join("zero")).unwrap();
            let e = read_beside(dir.path(), "zero", 4, allow).unwrap_err();
            assert!(e.contains("not a regular file"), "{e}");
        }
    }
}
