//! Mesh file input and output.
//!
//! Every format goes through the neutral [`IndexedMesh`]: readers produce one, writers consume
//! one, and the caller converts to and from the kernel mesh.
//!
//! | format | read | write |
//! | --- | --- | --- |
//! | OBJ (`.obj`) | `v`, `f` (n-gons, negative indices), `l` | `v`, `f`, `l` |
//! | STL (`.stl`) | ASCII or binary, detected by content; coincident corners merged | binary (default) or ASCII |
//! | PLY (`.ply`) | ASCII, binary little/big endian: vertex, face, edge elements | binary little endian (default) or ASCII |
//! | glTF (`.gltf`, `.glb`) | triangle and line primitives of the default scene, node transforms applied, coincident vertices merged | flat-shaded triangles + a line primitive |
//!
//! NURBS patch files (`.bpt`, OBJ free-form `surf`) are read into surfaces, not meshes: see
//! [`patches`].
//!
//! Writers are deterministic: the same mesh always encodes to the same bytes (no dates,
//! versions or hash-map order in any output). Text formats print floats in their shortest
//! round-trip form (`-0` becomes `0`). Non-finite values are rejected, never written.
//! Readers never panic on malformed input; errors name the file and, where there is one, the
//! line, element index or byte offset.
//!
//! Nothing here touches the file system: the command line reads and writes
//! the files (atomically, all outputs of a run or none), and a `.gltf`'s
//! external buffers come through a [`Resolve`] callback it supplies.

pub mod gltf;
pub mod obj;
pub mod parts;
pub mod patches;
pub mod ply;
pub mod stl;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

pub use crate::geom::indexed::{IndexedMesh, MeshError, UpAxis};
use crate::geom::source::PolygonSource;

/// Supplies a file a mesh file refers to (a `.gltf`'s external buffer):
/// given its URI as written (percent-decoded, relative to the mesh file)
/// and the most bytes wanted, returns at most that many.
pub type Resolve<'a> = dyn FnMut(&str, u64) -> Result<Vec<u8>, String> + 'a;

/// The [`Resolve`] of [`decode`]: no external files.
pub(crate) fn no_external_files(uri: &str, _max: u64) -> Result<Vec<u8>, String> {
    Err(format!("external file {uri:?} is not available here"))
}

/// Errors of mesh reading and writing.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The file extension names no supported format.
    #[error(
        "{}: unknown mesh format (expected a .obj, .stl, .ply, .gltf or .glb extension)",
        .path.display()
    )]
    UnknownFormat { path: PathBuf },
    /// A text file has a syntax or value error on a given line (1-based).
    #[error("{}: line {line}: {message}", .path.display())]
    Syntax {
        path: PathBuf,
        line: usize,
        message: String,
    },
    /// A text file has an error at a given line and column (both 1-based; the column counts
    /// bytes).
    #[error("{}:{line}:{column}: {message}", .path.display())]
    Located {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
    /// The file extension names no supported NURBS patch format.
    #[error(
        "{}: unknown patch format (expected a .bpt or .obj extension)",
        .path.display()
    )]
    UnknownPatchFormat { path: PathBuf },
    /// A face or line refers to a vertex that does not exist.
    #[error(
        "{}: {}{element} {index} refers to vertex {vertex} but only {count} exist",
        .path.display(),
        line_prefix(*.line)
    )]
    BadIndex {
        path: PathBuf,
        /// 1-based line of a text file, if known.
        line: Option<usize>,
        /// `"face"`, `"polyline"`, `"edge"`, ...
        element: &'static str,
        /// Element number as the format counts it (1-based for OBJ, 0-based otherwise).
        index: usize,
        /// The vertex reference as written in the file.
        vertex: i64,
        count: usize,
    },
    /// A binary file ends early.
    #[error("{}: {what} truncated at byte {offset} (expected {expected})", .path.display())]
    Truncated {
        path: PathBuf,
        what: &'static str,
        offset: u64,
        expected: u64,
    },
    /// Any other problem with the content of a file.
    #[error("{}: {message}", .path.display())]
    Malformed { path: PathBuf, message: String },
    /// A mesh to be written has a NaN or infinite coordinate.
    #[error("cannot write mesh: vertex {vertex} has a non-finite coordinate")]
    NonFinite { vertex: usize },
    /// A mesh to be written has a NaN or infinite vertex scalar.
    #[error("cannot write mesh: vertex scalar {name:?} is not finite at vertex {vertex}")]
    NonFiniteScalar { name: String, vertex: usize },
    /// A coordinate does not fit the format's number type.
    #[error("cannot write {format}: vertex {vertex} coordinate {value:e} does not fit an f32")]
    OutOfRange {
        vertex: usize,
        value: f64,
        format: &'static str,
    },
    /// A mesh to be written is structurally invalid or exceeds a format limit.
    #[error("cannot write mesh: {message}")]
    InvalidMesh { message: String },
}

impl From<MeshError> for IoError {
    fn from(e: MeshError) -> IoError {
        match e {
            MeshError::NonFinite { vertex } => IoError::NonFinite { vertex },
            MeshError::NonFiniteScalar { name, vertex } => {
                IoError::NonFiniteScalar { name, vertex }
            }
            MeshError::OutOfRange {
                vertex,
                value,
                format,
            } => IoError::OutOfRange {
                vertex,
                value,
                format,
            },
            MeshError::Invalid { message } => IoError::InvalidMesh { message },
        }
    }
}

fn line_prefix(line: Option<usize>) -> String {
    line.map(|l| format!("line {l}: ")).unwrap_or_default()
}

/// Supported file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MeshFormat {
    Obj,
    StlAscii,
    StlBinary,
    PlyAscii,
    PlyBinary,
    Gltf,
    Glb,
}

impl MeshFormat {
    /// Format implied by the (case-insensitive) extension: `.obj`, `.stl` (binary), `.ply`
    /// (binary little endian), `.gltf`, `.glb`. Readers detect ASCII vs binary by content.
    pub fn from_path(path: &Path) -> Result<MeshFormat, IoError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("obj") => Ok(MeshFormat::Obj),
            Some("stl") => Ok(MeshFormat::StlBinary),
            Some("ply") => Ok(MeshFormat::PlyBinary),
            Some("gltf") => Ok(MeshFormat::Gltf),
            Some("glb") => Ok(MeshFormat::Glb),
            _ => Err(IoError::UnknownFormat {
                path: path.to_path_buf(),
            }),
        }
    }

    /// The usual file extension (without the dot).
    pub fn extension(self) -> &'static str {
        match self {
            MeshFormat::Obj => "obj",
            MeshFormat::StlAscii | MeshFormat::StlBinary => "stl",
            MeshFormat::PlyAscii | MeshFormat::PlyBinary => "ply",
            MeshFormat::Gltf => "gltf",
            MeshFormat::Glb => "glb",
        }
    }
}

/// The bytes [`encode`] gives for `look` with the vertices and polygons of
/// `source` in place of its own, written straight from `source` (the
/// kernel's mesh, without an indexed copy; issue 38). `look` holds what
/// the file adds to the geometry, as [`gltf::Planned::new`] describes.
pub fn encode_streamed<S: PolygonSource>(
    source: &S,
    look: &IndexedMesh,
    format: MeshFormat,
) -> Result<Vec<u8>, IoError> {
    match format {
        MeshFormat::Obj => obj::encode_streamed(source, look, None),
        MeshFormat::StlAscii => stl::encode_streamed(source, true),
        MeshFormat::StlBinary => stl::encode_streamed(source, false),
        MeshFormat::PlyAscii => ply::encode_streamed(source, look, ply::Encoding::Ascii),
        MeshFormat::PlyBinary => {
            ply::encode_streamed(source, look, ply::Encoding::BinaryLittleEndian)
        }
        MeshFormat::Gltf => gltf::encode_streamed(source, look, false),
        MeshFormat::Glb => gltf::encode_streamed(source, look, true),
    }
}

/// Encodes `mesh` in `format`. Validates the mesh first (see [`IndexedMesh::validate`]).
pub fn encode(mesh: &IndexedMesh, format: MeshFormat) -> Result<Vec<u8>, IoError> {
    match format {
        MeshFormat::Obj => obj::encode(mesh),
        MeshFormat::StlAscii => stl::encode_ascii(mesh),
        MeshFormat::StlBinary => stl::encode_binary(mesh),
        MeshFormat::PlyAscii => ply::encode(mesh, ply::Encoding::Ascii),
        MeshFormat::PlyBinary => ply::encode(mesh, ply::Encoding::BinaryLittleEndian),
        MeshFormat::Gltf => gltf::encode_gltf(mesh),
        MeshFormat::Glb => gltf::encode_glb(mesh),
    }
}

/// Decodes `bytes` as `format`; `path` names the file in errors. ASCII and
/// binary STL/PLY are detected by content, so either STL or PLY variant
/// reads both. A `.gltf` that refers to external buffer files fails: see
/// [`decode_with`].
pub fn decode(bytes: &[u8], format: MeshFormat, path: &Path) -> Result<IndexedMesh, IoError> {
    decode_with(bytes, format, path, &mut no_external_files)
}

/// [`decode`] with `resolve` supplying a `.gltf`'s external buffers.
pub fn decode_with(
    bytes: &[u8],
    format: MeshFormat,
    path: &Path,
    resolve: &mut Resolve,
) -> Result<IndexedMesh, IoError> {
    match format {
        MeshFormat::Obj => obj::decode_with(bytes, path, resolve),
        MeshFormat::StlAscii | MeshFormat::StlBinary => stl::decode(bytes, path),
        MeshFormat::PlyAscii | MeshFormat::PlyBinary => ply::decode(bytes, path),
        MeshFormat::Gltf | MeshFormat::Glb => gltf::decode_with(bytes, path, resolve),
    }
}

/// Appends the canonical text form of `x`: shortest round-trip digits, positional for
/// `1e-5 <= |x| < 1e16` and scientific (`1.5e-7`, `1e300`) otherwise; `-0` prints as `0`.
/// `x` must be finite (writers validate first).
pub(crate) fn push_f64(out: &mut Vec<u8>, x: f64) {
    let x = if x == 0.0 { 0.0 } else { x };
    let a = x.abs();
    let mut w = ByteWriter(out);
    // Writing into a Vec cannot fail.
    let _ = if a == 0.0 || (1e-5..1e16).contains(&a) {
        write!(w, "{x}")
    } else {
        write!(w, "{x:e}")
    };
}

/// Appends the decimal form of `x`.
pub(crate) fn push_u64(out: &mut Vec<u8>, mut x: u64) {
    let mut buf = [0u8; 20];
    let mut i = buf.len();
    loop {
        i -= 1;
        buf[i] = b'0' + (x % 10) as u8;
        x /= 10;
        if x == 0 {
            break;
        }
    }
    out.extend_from_slice(&buf[i..]);
}

/// `fmt::Write` adapter appending to a byte vector.
struct ByteWriter<'a>(&'a mut Vec<u8>);

impl std::fmt::Write for ByteWriter<'_> {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.0.extend_from_slice(s.as_bytes());
        Ok(())
    }
}

/// Splits text into lines (LF or CRLF), yielding 1-based line numbers.
pub(crate) fn text_lines(bytes: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    let trimmed = bytes.strip_suffix(b"\n").unwrap_or(bytes);
    let empty = bytes.is_empty();
    trimmed
        .split(|&b| b == b'\n')
        .filter(move |_| !empty)
        .enumerate()
        .map(|(i, line)| (i + 1, line.strip_suffix(b"\r").unwrap_or(line)))
}

/// Parses an ASCII token as a finite or non-finite `f64` (`None` if it is not a number).
pub(crate) fn parse_f64(token: &[u8]) -> Option<f64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

#[cfg(test)]
pub(crate) mod test_meshes {
    //! Meshes shared by the format tests.
    use super::IndexedMesh;

    /// Unit cube (6 quads, outward winding), one wire edge off a corner, and a `radius` scalar.
    pub fn cube_with_wire() -> IndexedMesh {
        let mut m = IndexedMesh::new();
        for i in 0..8u32 {
            let c = |bit: u32| f64::from((i >> bit) & 1);
            m.positions.push([c(0), c(1), c(2)]);
        }
        m.positions.push([2.0, 2.0, 2.0]);
        for quad in [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ] {
            m.push_polygon(&quad);
        }
        m.lines.push([7, 8]);
        let radius = (0..9).map(|i| 0.1 + 0.05 * f64::from(i)).collect();
        m.vertex_scalars.push(("radius".to_string(), radius));
        m
    }

    /// A mesh exercising awkward cases: an L-shaped hexagon, a pentagon, a triangle sharing
    /// vertices, a collinear (zero-area) polygon, negative zero, tiny/huge magnitudes, two lines
    /// and an unused vertex.
    pub fn awkward() -> IndexedMesh {
        let mut m = IndexedMesh::new();
        let pts = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 2.0, 0.0],
            [-0.0, 2.0, -0.0],
            [0.1, 0.2, 0.3],
            [1e-7, 123456.789, -3.5e-12],
            [3.0, 3.0, 3.0],
            [4.0, 4.0, 4.0],
            [1e17, -2.5e20, 7.0],
            [5.0, 5.0, 5.0],
        ];
        m.positions.extend_from_slice(&pts);
        m.push_polygon(&[0, 1, 2, 3, 4, 5]);
        m.push_polygon(&[1, 6, 7, 2, 3]);
        m.push_polygon(&[0, 3, 5]);
        m.push_polygon(&[8, 9, 11]); // collinear -> degenerate normal
        m.push_polygon(&[8, 8, 9]); // repeated index
        m.lines.push([9, 6]);
        m.lines.push([0, 9]);
        m.vertex_scalars.push((
            "radius".to_string(),
            (0..pts.len()).map(|i| i as f64 * 0.25 - 1.0).collect(),
        ));
        m.vertex_scalars.push((
            "age".to_string(),
            (0..pts.len()).map(|i| i as f64).collect(),
        ));
        m.vertex_scalars.sort_by(|a, b| a.0.cmp(&b.0));
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn f(x: f64) -> String {
        let mut v = Vec::new();
        push_f64(&mut v, x);
        String::from_utf8(v).unwrap()
    }

    #[test]
    fn canonical_floats() {
        assert_eq!(f(0.0), "0");
        assert_eq!(f(-0.0), "0");
        assert_eq!(f(1.0), "1");
        assert_eq!(f(-2.5), "-2.5");
        assert_eq!(f(0.1), "0.1");
        assert_eq!(f(1.0 / 3.0), "0.3333333333333333");
        assert_eq!(f(1e-5), "0.00001");
        assert_eq!(f(1.5e-7), "1.5e-7");
        assert_eq!(f(1e300), "1e300");
        assert_eq!(f(-1.25e16), "-1.25e16");
        assert_eq!(f(123456789012345.6), "123456789012345.6");
        for x in [0.1, 1.0 / 3.0, 1.5e-7, 1e300, 5e-324, f64::MAX, -7.25e-310] {
            assert_eq!(f(x).parse::<f64>().unwrap(), x, "round trip of {x}");
        }
    }

    #[test]
    fn integers() {
        let mut v = Vec::new();
        for x in [0, 7, 10, 4294967295, u64::MAX] {
            v.clear();
            push_u64(&mut v, x);
            assert_eq!(String::from_utf8(v.clone()).unwrap(), x.to_string());
        }
    }

    #[test]
    fn text_lines_numbers_lines() {
        let lines: Vec<(usize, &[u8])> = text_lines(b"a\r\nb\n\nc").collect();
        assert_eq!(lines, vec![(1, &b"a"[..]), (2, b"b"), (3, b""), (4, b"c")]);
        assert_eq!(text_lines(b"").count(), 0);
        assert_eq!(text_lines(b"x\n").count(), 1);
    }

    #[test]
    fn formats_from_paths() {
        let p = |s: &str| MeshFormat::from_path(Path::new(s));
        assert_eq!(p("a.OBJ").unwrap(), MeshFormat::Obj);
        assert_eq!(p("dir.x/a.Stl").unwrap(), MeshFormat::StlBinary);
        assert_eq!(p("a.ply").unwrap(), MeshFormat::PlyBinary);
        assert_eq!(p("a.gltf").unwrap(), MeshFormat::Gltf);
        assert_eq!(p("a.GLB").unwrap(), MeshFormat::Glb);
        let e = p("a.fbx").unwrap_err().to_string();
        assert!(e.starts_with("a.fbx: unknown mesh format"), "{e}");
        assert!(p("noext").is_err());
    }

    #[test]
    fn error_messages_read_well() {
        let e = IoError::BadIndex {
            path: "mesh.obj".into(),
            line: Some(57),
            element: "face",
            index: 12,
            vertex: 40,
            count: 38,
        };
        assert_eq!(
            e.to_string(),
            "mesh.obj: line 57: face 12 refers to vertex 40 but only 38 exist"
        );
        let e = IoError::Truncated {
            path: "model.stl".into(),
            what: "binary STL",
            offset: 1284,
            expected: 1334,
        };
        assert_eq!(
            e.to_string(),
            "model.stl: binary STL truncated at byte 1284 (expected 1334)"
        );
    }

    #[test]
    fn encode_then_decode_every_format() {
        let mesh = test_meshes::cube_with_wire();
        for (name, format) in [
            ("m.obj", MeshFormat::Obj),
            ("m.stl", MeshFormat::StlBinary),
            ("a.stl", MeshFormat::StlAscii),
            ("m.ply", MeshFormat::PlyBinary),
            ("a.ply", MeshFormat::PlyAscii),
            ("m.gltf", MeshFormat::Gltf),
            ("m.glb", MeshFormat::Glb),
        ] {
            let bytes = encode(&mesh, format).unwrap();
            let path = Path::new(name);
            let back = decode(&bytes, MeshFormat::from_path(path).unwrap(), path).unwrap();
            assert!(back.polygon_count() > 0, "{name}");
            let expected_vertices = match format {
                MeshFormat::StlAscii | MeshFormat::StlBinary => 8,
                _ => 9,
            };
            assert_eq!(back.positions.len(), expected_vertices, "{name}");
        }
        assert_eq!(
            MeshFormat::from_path(Path::new("x.GLB")).unwrap(),
            MeshFormat::Glb
        );
        // Invalid meshes encode to nothing.
        let mut bad = mesh.clone();
        bad.positions[0][0] = f64::NAN;
        assert!(matches!(
            encode(&bad, MeshFormat::Obj),
            Err(IoError::NonFinite { vertex: 0 })
        ));
    }
}
