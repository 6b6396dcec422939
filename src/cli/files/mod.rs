//! Every file graftal reads or writes goes through here (nothing below the
//! command line touches the file system; `tests/layers.rs` holds the rest
//! of `src/` to it).
//!
//! Reading: inputs must be regular files (a FIFO or `/dev/zero` named as a
//! mesh is refused before it is opened for reading) no larger than their
//! kind's limit (checked before reading, and again while reading in case
//! the file grows), and the files a mesh refers to (a `.gltf`'s external
//! buffers) must stay inside the mesh file's directory — no absolute paths,
//! no `..`, no symlink out of it — unless the user passes
//! `--allow-outside-paths`; at most `byteLength` bytes of them are read.
//!
//! Writing: all outputs of a run or none, through [`staged`]'s temporary
//! files, safe in folders shared with writers on other hosts and in other
//! PID namespaces. [`journal`] keeps a batch's progress for `--resume`,
//! [`cache`] the content-addressed store of `--cache`.

pub mod cache;
pub mod journal;
mod staged;

pub use staged::{
    clean, describe_age, parse_age, set_stale_policy, take_notices, write_atomic, Staged,
    StalePolicy,
};

use std::fs::{self, File};
use std::io::{self, Read};
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

use sha2::{Digest, Sha256};

use super::Failure;
use crate::grammar::Input;
use crate::io::{self as meshio, IndexedMesh, MeshFormat};
use crate::rules::compile::source_from_bytes;
use crate::rules::diagnostic::SourceFile;
use crate::rules::program::ResourceKind;
use crate::rules::{compile_source, Override, Program, RuleError};

/// Largest rule file read: rule files are hand-written text.
pub const MAX_RULE_BYTES: u64 = 16 << 20;
/// Largest mesh file read (and a `.gltf`'s buffer).
pub const MAX_MESH_BYTES: u64 = 4 << 30;
/// Largest manifest, stats golden or other JSON document read.
pub const MAX_JSON_BYTES: u64 = 2 << 30;

/// How far input files may reach.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct InputPolicy {
    /// Follow absolute and `..` references out of a file's directory.
    pub allow_outside: bool,
}

/// Reads a rule file (a regular file, UTF-8: a bad byte is located).
pub fn read_rules(path: &Path) -> Result<SourceFile, RuleError> {
    let name = path.display().to_string();
    let bytes = read_input(path, MAX_RULE_BYTES).map_err(|err| {
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

/// Reads a whole input file, refusing anything but a regular file and
/// anything over `max` bytes (before reading, and while reading: a file
/// that grows past the limit is refused, not read to the end).
pub fn read_input(path: &Path, max: u64) -> io::Result<Vec<u8>> {
    let file = open_regular(path)?;
    read_bounded(file, max)
}

fn read_bounded(file: File, max: u64) -> io::Result<Vec<u8>> {
    let too_big = |size: u64| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{size} bytes or more, over the limit of {max} bytes for this kind of file"),
        )
    };
    let size = file.metadata()?.len();
    if size > max {
        return Err(too_big(size));
    }
    let mut bytes = Vec::with_capacity(size as usize);
    file.take(max + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max {
        return Err(too_big(max + 1));
    }
    Ok(bytes)
}

/// Reads a JSON document (a manifest, a golden) as text: a regular file
/// of at most [`MAX_JSON_BYTES`]. `Ok(None)` when there is no such file.
pub fn read_json_text(path: &Path) -> io::Result<Option<String>> {
    match read_input(path, MAX_JSON_BYTES) {
        Ok(bytes) => String::from_utf8(bytes)
            .map(Some)
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "not UTF-8 text")),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e),
    }
}

/// Size and SHA-256 (lowercase hex) of a regular file, streamed; `None`
/// when it is missing or not a regular file.
pub fn size_and_sha256(path: &Path) -> io::Result<Option<(u64, String)>> {
    let file = match open_regular(path) {
        Ok(file) => file,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
        Err(e) if e.kind() == io::ErrorKind::InvalidInput => return Ok(None),
        Err(e) => return Err(e),
    };
    let mut reader = io::BufReader::with_capacity(1 << 16, file);
    let mut hasher = Sha256::new();
    let mut size = 0u64;
    let mut buffer = vec![0u8; 1 << 16];
    loop {
        let n = reader.read(&mut buffer)?;
        if n == 0 {
            break;
        }
        size += n as u64;
        hasher.update(&buffer[..n]);
    }
    Ok(Some((size, hex(&hasher.finalize()))))
}

/// SHA-256 of the running executable, read once: the cache keys on the
/// exact build, since a rebuilt graftal may write other bytes under the
/// same version number.
pub fn executable_sha256() -> io::Result<String> {
    static HASH: std::sync::OnceLock<Result<String, String>> = std::sync::OnceLock::new();
    HASH.get_or_init(|| {
        let exe = std::env::current_exe().map_err(|e| e.to_string())?;
        match size_and_sha256(&exe) {
            Ok(Some((_, sha))) => Ok(sha),
            Ok(None) => Err(format!("{} is not a regular file", exe.display())),
            Err(e) => Err(format!("{}: {e}", exe.display())),
        }
    })
    .clone()
    .map_err(io::Error::other)
}

/// Whether `path` is a directory (following symbolic links).
pub fn is_dir(path: &Path) -> bool {
    fs::metadata(path).is_ok_and(|m| m.is_dir())
}

/// Lowercase hexadecimal.
pub fn hex(bytes: &[u8]) -> String {
    use std::fmt::Write as _;
    let mut out = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(out, "{b:02x}");
    }
    out
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
    let bytes = read_input(path, MAX_MESH_BYTES)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
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
        let bytes = read_beside(
            &program.base_dir,
            &resource.written,
            MAX_MESH_BYTES + 1,
            policy,
        )
        .map_err(fail)?;
        if bytes.len() as u64 > MAX_MESH_BYTES {
            return Err(fail(format!(
                "larger than the limit of {MAX_MESH_BYTES} bytes for a mesh file"
            )));
        }
        // The hash reads the bytes the decode reads: on a second core it
        // costs the run nothing (≈ 13 ms for the suite's 28 MB soup on one).
        let (input, sha256) = rayon::join(
            || -> Result<Input, Failure> {
                Ok(match resource.kind {
                    ResourceKind::Mesh => Input::new(Arc::new(
                        decode_mesh(&resource.path, &bytes, policy).map_err(fail)?,
                    )),
                    ResourceKind::Patches => Input::patches(
                        crate::io::patches::decode_patches(&bytes, &resource.path)
                            .map_err(|e| fail(e.to_string()))?
                            .surfaces,
                    ),
                })
            },
            || hex(&Sha256::digest(&bytes)),
        );
        hashes.push((resource.written.clone(), sha256));
        meshes.push(input?);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_must_be_regular_files_inside_their_directory() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_input(dir.path(), 10).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
        if Path::new("/dev/zero").exists() {
            let e = read_input(Path::new("/dev/zero"), 10).unwrap_err();
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
