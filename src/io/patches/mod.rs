//! Readers of NURBS patch files: each produces the file's surfaces as [`NurbsSurface`]s.
//!
//! | format | extension | reads |
//! | --- | --- | --- |
//! | Newell/Bourke patches | `.bpt` | the patch count, then per patch `du dv` and (du+1)(dv+1) points `x y z` (Bézier patches) |
//! | Wavefront OBJ free-form | `.obj` | `v`, `cstype [rat] bezier\|bspline`, `deg`, `surf`, `parm`, `end` |
//!
//! [`encode_obj_surfaces`] writes surfaces back as OBJ free-form B-splines, bit-exactly.
//!
//! Like the rest of [`crate::io`], nothing here touches the file system, and readers never
//! panic: every error names the file, the 1-based line and the 1-based column (in bytes) of
//! the offending token or statement ([`IoError::Located`]), except the one file-level error
//! "no surfaces in file" ([`IoError::Malformed`]). Sizes are checked before anything is
//! allocated for them: see the `MAX_*` constants.

mod bpt;
mod obj_surf;
#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};

use super::IoError;
use crate::nurbs::error::MAX_DEGREE;
use crate::nurbs::surface::NurbsSurface;

pub use bpt::decode_bpt;
pub use obj_surf::{decode_obj_surfaces, encode_obj_surfaces};

/// Surfaces read from a patch file, in file order, and the 1-based line where each starts.
#[derive(Debug, Clone, PartialEq)]
pub struct PatchFile {
    pub surfaces: Vec<NurbsSurface>,
    pub lines: Vec<usize>,
}

/// Most patches (surfaces) one file may hold.
pub const MAX_PATCHES: usize = 100_000;
/// Most control points of one surface.
pub const MAX_SURFACE_POINTS: usize = 1 << 20;
/// Most control points of all the surfaces of one file.
pub const MAX_FILE_POINTS: usize = 1 << 22;

/// Decodes a patch file by its (case-insensitive) extension: `.bpt` → [`decode_bpt`],
/// `.obj` → [`decode_obj_surfaces`].
pub fn decode_patches(bytes: &[u8], path: &Path) -> Result<PatchFile, IoError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("bpt") => decode_bpt(bytes, path),
        Some("obj") => decode_obj_surfaces(bytes, path),
        _ => Err(IoError::UnknownPatchFormat {
            path: path.to_path_buf(),
        }),
    }
}

/// A whitespace-separated token and where it starts (1-based line and byte column).
#[derive(Debug, Clone, Copy)]
struct Token<'a> {
    text: &'a [u8],
    line: usize,
    column: usize,
    /// Byte offset in the file.
    offset: usize,
}

impl Token<'_> {
    /// Bytes of the file after this token.
    fn bytes_after(&self, file: &[u8]) -> usize {
        file.len().saturating_sub(self.offset + self.text.len())
    }
}

/// Splits `bytes` at ASCII whitespace, keeping each token's position. LF ends a line (a CR
/// before it is whitespace).
fn tokens(bytes: &[u8]) -> impl Iterator<Item = Token<'_>> {
    let mut pos = 0;
    let mut line = 1;
    let mut line_start = 0;
    std::iter::from_fn(move || {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            if bytes[pos] == b'\n' {
                line += 1;
                line_start = pos + 1;
            }
            pos += 1;
        }
        if pos == bytes.len() {
            return None;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        Some(Token {
            text: &bytes[start..pos],
            line,
            column: start - line_start + 1,
            offset: start,
        })
    })
}

/// Builds located errors for one file.
struct Locator<'p> {
    path: &'p Path,
}

impl Locator<'_> {
    fn at(&self, line: usize, column: usize, message: impl Into<String>) -> IoError {
        IoError::Located {
            path: PathBuf::from(self.path),
            line,
            column,
            message: message.into(),
        }
    }

    fn token(&self, t: &Token, message: impl Into<String>) -> IoError {
        self.at(t.line, t.column, message)
    }
}

/// The token as text for messages (lossy, shortened).
fn shown(text: &[u8]) -> String {
    let s = String::from_utf8_lossy(text);
    if s.chars().count() > 40 {
        format!("{}…", s.chars().take(40).collect::<String>())
    } else {
        s.into_owned()
    }
}

/// Parses a degree token: an integer in 1..=[`MAX_DEGREE`].
fn parse_degree(t: &Token, what: &str, at: &Locator) -> Result<usize, IoError> {
    std::str::from_utf8(t.text)
        .ok()
        .and_then(|s| s.parse::<usize>().ok())
        .filter(|d| (1..=MAX_DEGREE).contains(d))
        .ok_or_else(|| {
            at.token(
                t,
                format!(
                    "{what} must be an integer from 1 to {MAX_DEGREE}, found {:?}",
                    shown(t.text)
                ),
            )
        })
}

/// Parses a finite number token.
fn parse_finite(t: &Token, what: &str, at: &Locator) -> Result<f64, IoError> {
    match super::parse_f64(t.text) {
        Some(x) if x.is_finite() => Ok(x),
        Some(_) => Err(at.token(t, format!("{what} is not finite: {:?}", shown(t.text)))),
        None => Err(at.token(
            t,
            format!("{what}: expected a number, found {:?}", shown(t.text)),
        )),
    }
}
