//! STL, ASCII and binary.
//!
//! Writing triangulates every polygon with [`crate::geom::polygon::triangulate`]. Each facet
//! normal is a triangle's stored normal (`IndexedMesh::polygon_normals`: as read from an STL, or
//! the kernel's), else the triangle's unit normal, or the polygon's unit Newell normal when the
//! triangle is degenerate, or `0 0 0` when both are. Wire edges and vertex scalars are not written.
//! The binary header is `graftal binary STL` padded with spaces to 80 bytes; binary values are
//! `f32` (coordinates beyond the `f32` range are an error). ASCII values are printed in the
//! canonical shortest round-trip `f64` form.
//!
//! Reading detects the variant by content: binary when the size is exactly
//! `84 + 50 * triangle_count`, otherwise ASCII when the text starts with `solid` (several solids
//! are concatenated). Bitwise-equal corner positions (with `-0 == 0`) are merged into one vertex,
//! numbered by first appearance, to recover the topology. Facet normals are kept as the
//! triangles' stored normals (bit for bit where unit; computed where a file writes `0 0 0`), so
//! converting an STL into STL again changes no byte.

use std::path::Path;

use glam::DVec3;

use super::{parse_f64, push_f64, text_lines, IoError};
use crate::geom::indexed::{IndexedMesh, PolygonTriangulator, VertexMerger};
use crate::geom::normals::unit_as_read;
use crate::geom::polygon;
use crate::geom::source::PolygonSource;

const HEADER: &[u8; 18] = b"graftal binary STL";

/// Calls `emit(normal, [a, b, c])` for every triangle of every polygon, in order.
fn for_each_triangle<S: PolygonSource>(mesh: &S, mut emit: impl FnMut(DVec3, [DVec3; 3])) {
    let mut tri = PolygonTriangulator::default();
    mesh.for_each_polygon(|poly, stored| {
        let poly_normal = tri.run_with(poly, |v| mesh.position(v));
        if let [p0, p1, p2] = tri.points[..] {
            // A triangle's normal as read or as its producer stored it
            // (a file's facet normal comes back unchanged).
            if let Some(Some(stored)) = stored {
                emit(stored, [p0, p1, p2]);
                return;
            }
            // A triangle's own normal is the polygon's: the same points, and
            // `unit_normal_of` (which `run` uses) gives `unit_normal`'s bits.
            emit(poly_normal.unwrap_or(DVec3::ZERO), [p0, p1, p2]);
            return;
        }
        for t in &tri.triangles {
            let corners = t.map(|i| tri.points[i as usize]);
            let normal = polygon::unit_normal(&corners)
                .or(poly_normal)
                .unwrap_or(DVec3::ZERO);
            emit(normal, corners);
        }
    });
}

/// Encodes `mesh` as binary STL.
pub fn encode_binary(mesh: &IndexedMesh) -> Result<Vec<u8>, IoError> {
    mesh.validate()?;
    binary_of(mesh)
}

/// Encodes `mesh` as ASCII STL.
pub fn encode_ascii(mesh: &IndexedMesh) -> Result<Vec<u8>, IoError> {
    mesh.validate()?;
    ascii_of(mesh)
}

/// The bytes [`encode_binary`] or [`encode_ascii`] gives for the polygons
/// of `source`, written straight from it (a kernel mesh: no indexed copy;
/// STL holds nothing else).
pub fn encode_streamed<S: PolygonSource>(source: &S, ascii: bool) -> Result<Vec<u8>, IoError> {
    source.check_vertices()?;
    if ascii {
        ascii_of(source)
    } else {
        binary_of(source)
    }
}

fn binary_of<S: PolygonSource>(mesh: &S) -> Result<Vec<u8>, IoError> {
    mesh.check_f32_range("binary STL")?;
    let count = mesh.triangle_count();
    let count32 = u32::try_from(count).map_err(|_| IoError::InvalidMesh {
        message: format!("{count} triangles exceed the binary STL limit of u32::MAX"),
    })?;
    let mut out = Vec::with_capacity(84 + 50 * count as usize);
    out.extend_from_slice(HEADER);
    out.resize(80, b' ');
    out.extend_from_slice(&count32.to_le_bytes());
    for_each_triangle(mesh, |normal, corners| {
        // One 50-byte record, appended whole.
        let mut record = [0u8; 50];
        let values = std::iter::once(normal)
            .chain(corners)
            .flat_map(|v| v.to_array());
        for (bytes, c) in record.chunks_exact_mut(4).zip(values) {
            // -0 is normalized so equal geometry always gives equal bytes.
            let c = if c == 0.0 { 0.0f32 } else { c as f32 };
            bytes.copy_from_slice(&c.to_le_bytes());
        }
        out.extend_from_slice(&record);
    });
    Ok(out)
}

fn ascii_of<S: PolygonSource>(mesh: &S) -> Result<Vec<u8>, IoError> {
    let mut out = Vec::with_capacity(32 + mesh.triangle_count() as usize * 200);
    out.extend_from_slice(b"solid graftal\n");
    let push_vec = |out: &mut Vec<u8>, v: DVec3| {
        for c in v.to_array() {
            out.push(b' ');
            push_f64(out, c);
        }
        out.push(b'\n');
    };
    for_each_triangle(mesh, |normal, corners| {
        out.extend_from_slice(b"  facet normal");
        push_vec(&mut out, normal);
        out.extend_from_slice(b"    outer loop\n");
        for c in corners {
            out.extend_from_slice(b"      vertex");
            push_vec(&mut out, c);
        }
        out.extend_from_slice(b"    endloop\n  endfacet\n");
    });
    out.extend_from_slice(b"endsolid graftal\n");
    Ok(out)
}

/// Decodes ASCII or binary STL; `path` names the file in errors.
pub fn decode(bytes: &[u8], path: &Path) -> Result<IndexedMesh, IoError> {
    let len = bytes.len() as u64;
    let expected = (bytes.len() >= 84).then(|| {
        84 + 50
            * u64::from(u32::from_le_bytes([
                bytes[80], bytes[81], bytes[82], bytes[83],
            ]))
    });
    if expected == Some(len) {
        return decode_binary(bytes, path);
    }
    let text_start = bytes.trim_ascii_start();
    let looks_ascii = text_start.len() >= 5 && text_start[..5].eq_ignore_ascii_case(b"solid");
    if looks_ascii {
        let ascii = decode_ascii(bytes, path);
        // A binary file whose header happens to start with "solid" but whose size is off is
        // better reported as a broken binary file.
        let binary_like = bytes.contains(&0);
        match (ascii, expected) {
            (Ok(mesh), _) => return Ok(mesh),
            (Err(e), None) => return Err(e),
            (Err(e), Some(_)) if !binary_like => return Err(e),
            _ => {}
        }
    }
    let path_buf = path.to_path_buf();
    match expected {
        None if bytes.is_empty() => Err(IoError::Malformed {
            path: path_buf,
            message: "empty file is not an STL mesh".into(),
        }),
        None => Err(IoError::Truncated {
            path: path_buf,
            what: "binary STL header",
            offset: len,
            expected: 84,
        }),
        Some(expected) if len < expected => Err(IoError::Truncated {
            path: path_buf,
            what: "binary STL",
            offset: len,
            expected,
        }),
        Some(expected) => Err(IoError::Malformed {
            path: path_buf,
            message: format!(
                "binary STL has {} unexpected bytes after the last triangle at byte {expected} \
                 (the header declares {} triangles)",
                len - expected,
                (expected - 84) / 50
            ),
        }),
    }
}

fn decode_binary(bytes: &[u8], path: &Path) -> Result<IndexedMesh, IoError> {
    let count = (bytes.len() - 84) / 50;
    let mut merger = VertexMerger::default();
    let mut mesh = IndexedMesh::new();
    mesh.face_indices.reserve(count * 3);
    mesh.face_starts.reserve(count);
    let mut facet_normals = Vec::with_capacity(count);
    for (t, record) in bytes[84..].chunks_exact(50).enumerate() {
        let value = |at: usize| {
            f32::from_le_bytes([record[at], record[at + 1], record[at + 2], record[at + 3]])
        };
        facet_normals.push([0, 4, 8].map(|at| f64::from(value(at))));
        let mut tri = [0u32; 3];
        for (k, slot) in tri.iter_mut().enumerate() {
            let mut p = [0.0f64; 3];
            for (axis, c) in p.iter_mut().enumerate() {
                let at = 12 + 12 * k + 4 * axis;
                let value = value(at);
                if !value.is_finite() {
                    return Err(IoError::Malformed {
                        path: path.to_path_buf(),
                        message: format!(
                            "triangle {t} has a non-finite coordinate at byte {}",
                            84 + 50 * t + at
                        ),
                    });
                }
                *c = f64::from(value);
            }
            *slot = merger.index(p).ok_or_else(|| too_many(path))?;
        }
        mesh.push_polygon(&tri);
    }
    mesh.positions = merger.positions;
    keep_facet_normals(&mut mesh, &facet_normals);
    Ok(mesh)
}

/// Each facet's normal as the file gives it (bit for bit where it is unit,
/// `unit_as_read`), else the facet's own: the writer puts it back, so a
/// second conversion changes no byte. Files that write `0 0 0` get
/// computed normals.
fn keep_facet_normals(mesh: &mut IndexedMesh, read: &[[f64; 3]]) {
    let normals = mesh
        .polygons()
        .zip(read)
        .map(|(poly, &n)| {
            unit_as_read(DVec3::from_array(n))
                .or_else(|| {
                    let corners: Vec<DVec3> = poly
                        .iter()
                        .map(|&v| DVec3::from_array(mesh.positions[v as usize]))
                        .collect();
                    polygon::unit_normal(&corners)
                })
                .map_or([0.0; 3], |n| n.to_array())
        })
        .collect();
    mesh.polygon_normals = normals;
}

fn too_many(path: &Path) -> IoError {
    IoError::Malformed {
        path: path.to_path_buf(),
        message: "more than u32::MAX distinct vertices".into(),
    }
}

#[derive(PartialEq)]
enum State {
    /// Before `solid` or after `endsolid`.
    Outside,
    /// Inside a solid, between facets.
    Solid,
    /// After `facet`, before `outer loop`.
    Facet,
    /// Inside `outer loop`.
    Loop,
    /// After `endloop`, before `endfacet`.
    LoopDone,
}

fn decode_ascii(bytes: &[u8], path: &Path) -> Result<IndexedMesh, IoError> {
    let syntax = |line: usize, message: String| IoError::Syntax {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut merger = VertexMerger::default();
    let mut mesh = IndexedMesh::new();
    let mut state = State::Outside;
    let mut corners: Vec<u32> = Vec::new();
    let mut facets = 0usize;
    let mut facet_normals = Vec::new();
    let mut last_line = 0;
    for (line_no, line) in text_lines(bytes) {
        last_line = line_no;
        let mut tokens = line
            .split(u8::is_ascii_whitespace)
            .filter(|t| !t.is_empty());
        let Some(keyword) = tokens.next() else {
            continue;
        };
        let is = |word: &[u8]| keyword.eq_ignore_ascii_case(word);
        match state {
            State::Outside if is(b"solid") => state = State::Solid,
            State::Solid if is(b"facet") => {
                state = State::Facet;
                corners.clear();
                // `facet normal nx ny nz`; a missing or unreadable normal is
                // computed instead.
                let mut normal = [f64::NAN; 3];
                if tokens
                    .next()
                    .is_some_and(|t| t.eq_ignore_ascii_case(b"normal"))
                {
                    for (c, token) in normal.iter_mut().zip(tokens.by_ref()) {
                        *c = parse_f64(token).unwrap_or(f64::NAN);
                    }
                }
                facet_normals.push(normal);
            }
            State::Solid if is(b"endsolid") => state = State::Outside,
            State::Facet if is(b"outer") => state = State::Loop,
            State::Loop if is(b"vertex") => {
                let mut p = [0.0; 3];
                for c in &mut p {
                    let token = tokens.next().ok_or_else(|| {
                        syntax(
                            line_no,
                            format!("facet {facets}: vertex needs 3 coordinates"),
                        )
                    })?;
                    *c = parse_f64(token).filter(|v| v.is_finite()).ok_or_else(|| {
                        syntax(
                            line_no,
                            format!(
                                "facet {facets}: invalid coordinate `{}`",
                                String::from_utf8_lossy(token)
                            ),
                        )
                    })?;
                }
                corners.push(merger.index(p).ok_or_else(|| too_many(path))?);
            }
            State::Loop if is(b"endloop") => state = State::LoopDone,
            State::LoopDone if is(b"endfacet") => {
                if corners.len() < 3 {
                    return Err(syntax(
                        line_no,
                        format!(
                            "facet {facets} has {} vertices (at least 3 required)",
                            corners.len()
                        ),
                    ));
                }
                mesh.push_polygon(&corners);
                facets += 1;
                state = State::Solid;
            }
            _ => {
                let expected = match state {
                    State::Outside => "`solid`",
                    State::Solid => "`facet` or `endsolid`",
                    State::Facet => "`outer loop`",
                    State::Loop => "`vertex` or `endloop`",
                    State::LoopDone => "`endfacet`",
                };
                return Err(syntax(
                    line_no,
                    format!(
                        "expected {expected}, found `{}`",
                        String::from_utf8_lossy(keyword)
                    ),
                ));
            }
        }
    }
    // A missing final `endsolid` is tolerated; an unfinished facet is not.
    if !matches!(state, State::Outside | State::Solid) {
        return Err(syntax(
            last_line,
            format!("file ends inside facet {facets}"),
        ));
    }
    mesh.positions = merger.positions;
    keep_facet_normals(&mut mesh, &facet_normals);
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_meshes;

    fn path() -> &'static Path {
        Path::new("model.stl")
    }

    #[test]
    fn binary_layout() {
        let mesh = test_meshes::cube_with_wire();
        let bytes = encode_binary(&mesh).unwrap();
        assert_eq!(bytes.len(), 84 + 50 * 12);
        assert_eq!(&bytes[..18], b"graftal binary STL");
        assert!(bytes[18..80].iter().all(|&b| b == b' '));
        assert_eq!(u32::from_le_bytes(bytes[80..84].try_into().unwrap()), 12);
        // First facet normal: the bottom face (z = 0) faces -Z.
        let n: Vec<f32> = (0..3)
            .map(|k| f32::from_le_bytes(bytes[84 + 4 * k..88 + 4 * k].try_into().unwrap()))
            .collect();
        assert_eq!(n, vec![0.0, 0.0, -1.0]);
        assert_eq!(bytes, encode_binary(&mesh).unwrap(), "deterministic");
    }

    #[test]
    fn ascii_layout() {
        let mut m = IndexedMesh::new();
        m.positions = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.5, 0.0]];
        m.push_polygon(&[0, 1, 2]);
        let text = String::from_utf8(encode_ascii(&m).unwrap()).unwrap();
        assert_eq!(
            text,
            "solid graftal\n  facet normal 0 0 1\n    outer loop\n      vertex 0 0 0\n      \
             vertex 1 0 0\n      vertex 0 0.5 0\n    endloop\n  endfacet\nendsolid graftal\n"
        );
    }

    #[test]
    fn round_trips_merge_vertices() {
        let mesh = test_meshes::cube_with_wire();
        for bytes in [encode_binary(&mesh).unwrap(), encode_ascii(&mesh).unwrap()] {
            let back = decode(&bytes, path()).unwrap();
            // The wire-only vertex 8 is not in STL.
            assert_eq!(back.positions.len(), 8);
            assert_eq!(back.polygon_count(), 12);
            assert!(back.lines.is_empty());
            for p in &back.positions {
                assert!(mesh.positions[..8]
                    .iter()
                    .any(|q| (0..3).all(|k| (p[k] - q[k]).abs() < 1e-6)));
            }
            // Closed manifold: every undirected edge is used exactly twice.
            let mut edges = Vec::new();
            for poly in back.polygons() {
                for k in 0..3 {
                    let (a, b) = (poly[k], poly[(k + 1) % 3]);
                    edges.push((a.min(b), a.max(b)));
                }
            }
            edges.sort();
            let mut counts = std::collections::BTreeMap::new();
            for e in edges {
                *counts.entry(e).or_insert(0) += 1;
            }
            assert!(counts.values().all(|&c| c == 2), "{counts:?}");
            assert_eq!(counts.len(), 18);
        }
    }

    #[test]
    fn awkward_mesh_writes_without_nan() {
        let mesh = test_meshes::awkward();
        let bin = encode_binary(&mesh).unwrap();
        for chunk in bin[84..].chunks_exact(50) {
            for k in 0..12 {
                let v = f32::from_le_bytes(chunk[4 * k..4 * k + 4].try_into().unwrap());
                assert!(v.is_finite());
            }
        }
        // Collinear polygon (6, 8, 9) gets a 0 0 0 normal.
        let text = String::from_utf8(encode_ascii(&mesh).unwrap()).unwrap();
        assert!(!text.contains("NaN") && !text.contains("inf"));
        assert!(text.contains("facet normal 0 0 0\n"));
        let back = decode(text.as_bytes(), path()).unwrap();
        assert_eq!(back.polygon_count() as u64, mesh.triangle_count());
    }

    #[test]
    fn f32_range_is_enforced_for_binary() {
        let mut m = test_meshes::cube_with_wire();
        m.positions[3][1] = 1e39;
        assert!(matches!(
            encode_binary(&m),
            Err(IoError::OutOfRange { vertex: 3, .. })
        ));
        encode_ascii(&m).unwrap();
    }

    #[test]
    fn binary_header_starting_with_solid_is_still_binary() {
        let mut bytes = encode_binary(&test_meshes::cube_with_wire()).unwrap();
        bytes[..5].copy_from_slice(b"solid");
        assert_eq!(decode(&bytes, path()).unwrap().polygon_count(), 12);
        // Truncated: reported as a binary problem, not as bad ASCII.
        let e = decode(&bytes[..bytes.len() - 16], path()).unwrap_err();
        assert_eq!(
            e.to_string(),
            "model.stl: binary STL truncated at byte 668 (expected 684)"
        );
    }

    #[test]
    fn errors() {
        let bin = encode_binary(&test_meshes::cube_with_wire()).unwrap();
        let e = decode(&bin[..100], path()).unwrap_err().to_string();
        assert_eq!(
            e,
            "model.stl: binary STL truncated at byte 100 (expected 684)"
        );
        let mut long = bin.clone();
        long.extend_from_slice(&[0; 7]);
        let e = decode(&long, path()).unwrap_err().to_string();
        assert!(
            e.contains("7 unexpected bytes after the last triangle at byte 684"),
            "{e}"
        );
        let e = decode(b"", path()).unwrap_err().to_string();
        assert_eq!(e, "model.stl: empty file is not an STL mesh");
        let e = decode(b"hello", path()).unwrap_err().to_string();
        assert_eq!(
            e,
            "model.stl: binary STL header truncated at byte 5 (expected 84)"
        );
        let mut nan = bin.clone();
        nan[84 + 12..84 + 16].copy_from_slice(&f32::NAN.to_le_bytes());
        let e = decode(&nan, path()).unwrap_err().to_string();
        assert_eq!(
            e,
            "model.stl: triangle 0 has a non-finite coordinate at byte 96"
        );
        let cases = [
            (
                "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0\n",
                "line 4: facet 0: vertex needs 3 coordinates",
            ),
            (
                "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 nan\n",
                "line 4: facet 0: invalid coordinate `nan`",
            ),
            (
                "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nendloop\nendfacet\n",
                "line 6: facet 0 has 1 vertices (at least 3 required)",
            ),
            (
                "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n",
                "line 4: file ends inside facet 0",
            ),
            (
                "solid x\nvertex 0 0 0\n",
                "line 2: expected `facet` or `endsolid`, found `vertex`",
            ),
        ];
        for (text, expected) in cases {
            let e = decode(text.as_bytes(), path()).unwrap_err().to_string();
            assert_eq!(e, format!("model.stl: {expected}"), "{text:?}");
        }
    }

    #[test]
    fn ascii_variants() {
        // Two solids, mixed case, no final endsolid, CRLF, a polygonal facet.
        let text = "SOLID a\r\n facet normal 0 0 1\r\n  outer loop\r\n   vertex 0 0 0\r\n   \
                    vertex 1 0 0\r\n   vertex 1 1 0\r\n   vertex 0 1 0\r\n  endloop\r\n \
                    endfacet\r\nendsolid a\r\nsolid b\nfacet normal 0 0 0\nouter loop\n\
                    vertex 0 0 0\nvertex 1 1 0\nvertex -0 1 0\nendloop\nendfacet\n";
        let m = decode(text.as_bytes(), path()).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.polygon(0), &[0, 1, 2, 3]);
        assert_eq!(m.polygon(1), &[0, 2, 3]);
        let empty = decode(b"solid empty\nendsolid empty\n", path()).unwrap();
        assert_eq!(empty.polygon_count(), 0);
    }

    #[test]
    fn garbage_and_truncation_never_panic() {
        let bin = encode_binary(&test_meshes::awkward()).unwrap();
        let ascii = encode_ascii(&test_meshes::awkward()).unwrap();
        for cut in 0..bin.len() {
            let _ = decode(&bin[..cut], path());
        }
        for cut in 0..ascii.len() {
            let _ = decode(&ascii[..cut], path());
        }
        let mut state = 99u64;
        for round in 0..200 {
            let mut bytes = b"solid ".to_vec();
            for _ in 0..(round % 150) {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
                bytes.push((state >> 56) as u8);
            }
            let _ = decode(&bytes, path());
            let _ = decode(&bytes[6..], path());
        }
    }
}
