//! Wavefront OBJ.
//!
//! Writing: a `# graftal` header, then `v x y z` per vertex, `f a b c ...` per polygon (1-based,
//! n-gons kept) and `l a b` per wire edge. Vertex scalars are not written (OBJ has no place for
//! them).
//!
//! Reading is a small purpose-built parser rather than `tobj`: tobj renumbers vertices per
//! object in first-use order (dropping unused ones and splitting shared ones), stores `f32`
//! unless built with `use_f64`, and reports index errors without line numbers. This parser keeps
//! original vertex numbering and full `f64` precision, reads `v`, `f`/`fo` (n-gons, `v/vt/vn`
//! references, negative relative indices), and `l` polylines (split into edges); every other
//! statement (`vt`, `vn`, `o`, `g`, `s`, `usemtl`, `mtllib`, `p`, ...) is ignored. Comments (`#`)
//! and `\` line continuations are handled. Forward references to vertices defined later are
//! accepted and checked at the end.

use std::path::Path;

use super::{parse_f64, push_f64, push_u64, text_lines, IoError};
use crate::geom::indexed::IndexedMesh;

/// Encodes `mesh` as OBJ text.
pub fn encode(mesh: &IndexedMesh) -> Result<Vec<u8>, IoError> {
    mesh.validate()?;
    let mut out = Vec::with_capacity(16 + mesh.positions.len() * 40 + mesh.face_indices.len() * 8);
    out.extend_from_slice(b"# graftal\n");
    for p in &mesh.positions {
        out.push(b'v');
        for &c in p {
            out.push(b' ');
            push_f64(&mut out, c);
        }
        out.push(b'\n');
    }
    for poly in mesh.polygons() {
        out.push(b'f');
        for &i in poly {
            out.push(b' ');
            push_u64(&mut out, u64::from(i) + 1);
        }
        out.push(b'\n');
    }
    for line in &mesh.lines {
        out.extend_from_slice(b"l ");
        push_u64(&mut out, u64::from(line[0]) + 1);
        out.push(b' ');
        push_u64(&mut out, u64::from(line[1]) + 1);
        out.push(b'\n');
    }
    Ok(out)
}

/// Decodes OBJ text; `path` names the file in errors.
pub fn decode(bytes: &[u8], path: &Path) -> Result<IndexedMesh, IoError> {
    let mut parser = Parser {
        path,
        mesh: IndexedMesh::new(),
        faces: 0,
        polylines: 0,
        refs: Vec::new(),
        forward: Vec::new(),
    };
    let mut joined: Vec<u8> = Vec::new();
    let mut joined_start = 0;
    for (line_no, raw) in text_lines(bytes) {
        let content = match raw.iter().position(|&b| b == b'#') {
            Some(hash) => &raw[..hash],
            None => raw,
        };
        let content = content.trim_ascii_end();
        if let Some(body) = content.strip_suffix(b"\\") {
            if joined.is_empty() {
                joined_start = line_no;
            }
            joined.extend_from_slice(body);
            joined.push(b' ');
            continue;
        }
        if joined.is_empty() {
            parser.statement(line_no, content)?;
        } else {
            joined.extend_from_slice(content);
            let statement = std::mem::take(&mut joined);
            parser.statement(joined_start, &statement)?;
        }
    }
    if !joined.is_empty() {
        let statement = std::mem::take(&mut joined);
        parser.statement(joined_start, &statement)?;
    }
    parser.finish()
}

/// A vertex reference not yet resolvable when read (index beyond the vertices so far).
struct ForwardRef {
    line: usize,
    element: &'static str,
    index: usize,
    vertex: i64,
}

struct Parser<'a> {
    path: &'a Path,
    mesh: IndexedMesh,
    faces: usize,
    polylines: usize,
    refs: Vec<u32>,
    forward: Vec<ForwardRef>,
}

impl Parser<'_> {
    fn syntax(&self, line: usize, message: String) -> IoError {
        IoError::Syntax {
            path: self.path.to_path_buf(),
            line,
            message,
        }
    }

    fn statement(&mut self, line: usize, text: &[u8]) -> Result<(), IoError> {
        let mut tokens = text
            .split(u8::is_ascii_whitespace)
            .filter(|t| !t.is_empty());
        let Some(keyword) = tokens.next() else {
            return Ok(());
        };
        match keyword {
            b"v" => self.vertex(line, tokens),
            b"f" | b"fo" => {
                self.faces += 1;
                let index = self.faces;
                self.references(line, "face", index, tokens)?;
                if self.refs.len() < 3 {
                    return Err(self.syntax(
                        line,
                        format!(
                            "face {index} has {} vertices (at least 3 required)",
                            self.refs.len()
                        ),
                    ));
                }
                self.mesh.push_polygon(&self.refs);
                Ok(())
            }
            b"l" => {
                self.polylines += 1;
                let index = self.polylines;
                self.references(line, "polyline", index, tokens)?;
                if self.refs.len() < 2 {
                    return Err(self.syntax(
                        line,
                        format!(
                            "polyline {index} has {} vertices (at least 2 required)",
                            self.refs.len()
                        ),
                    ));
                }
                self.mesh
                    .lines
                    .extend(self.refs.windows(2).map(|w| [w[0], w[1]]));
                Ok(())
            }
            _ => Ok(()),
        }
    }

    fn vertex<'t>(
        &mut self,
        line: usize,
        mut tokens: impl Iterator<Item = &'t [u8]>,
    ) -> Result<(), IoError> {
        let number = self.mesh.positions.len() + 1;
        if u32::try_from(number).is_err() {
            return Err(self.syntax(line, "too many vertices (more than u32::MAX)".into()));
        }
        let mut p = [0.0; 3];
        for c in &mut p {
            let token = tokens
                .next()
                .ok_or_else(|| self.syntax(line, format!("vertex {number} needs 3 coordinates")))?;
            *c = parse_f64(token).ok_or_else(|| {
                self.syntax(
                    line,
                    format!(
                        "vertex {number}: invalid number `{}`",
                        String::from_utf8_lossy(token)
                    ),
                )
            })?;
            if !c.is_finite() {
                return Err(
                    self.syntax(line, format!("vertex {number} has a non-finite coordinate"))
                );
            }
        }
        self.mesh.positions.push(p);
        Ok(())
    }

    /// Resolves the vertex references of one `f` or `l` statement into `self.refs`.
    fn references<'t>(
        &mut self,
        line: usize,
        element: &'static str,
        index: usize,
        tokens: impl Iterator<Item = &'t [u8]>,
    ) -> Result<(), IoError> {
        self.refs.clear();
        let count = self.mesh.positions.len();
        for token in tokens {
            let v_part = token.split(|&b| b == b'/').next().unwrap_or_default();
            let value: i64 = std::str::from_utf8(v_part)
                .ok()
                .and_then(|s| s.parse().ok())
                .ok_or_else(|| {
                    self.syntax(
                        line,
                        format!(
                            "{element} {index}: invalid vertex reference `{}`",
                            String::from_utf8_lossy(token)
                        ),
                    )
                })?;
            let resolved = match value {
                0 => {
                    return Err(self.syntax(
                        line,
                        format!("{element} {index}: vertex index 0 is invalid (OBJ counts from 1)"),
                    ))
                }
                v if v > 0 => v - 1,
                // Relative: -1 is the most recent vertex.
                v => count as i64 + v,
            };
            if resolved < 0 {
                return Err(IoError::BadIndex {
                    path: self.path.to_path_buf(),
                    line: Some(line),
                    element,
                    index,
                    vertex: value,
                    count,
                });
            }
            let resolved = u32::try_from(resolved).unwrap_or(u32::MAX);
            if resolved as usize >= count {
                self.forward.push(ForwardRef {
                    line,
                    element,
                    index,
                    vertex: value,
                });
            }
            self.refs.push(resolved);
        }
        Ok(())
    }

    fn finish(self) -> Result<IndexedMesh, IoError> {
        let count = self.mesh.positions.len();
        if let Some(bad) = self
            .forward
            .iter()
            .find(|f| f.vertex < 1 || (f.vertex - 1) as u64 >= count as u64)
        {
            return Err(IoError::BadIndex {
                path: self.path.to_path_buf(),
                line: Some(bad.line),
                element: bad.element,
                index: bad.index,
                vertex: bad.vertex,
                count,
            });
        }
        Ok(self.mesh)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_meshes;

    fn read(text: &str) -> Result<IndexedMesh, IoError> {
        decode(text.as_bytes(), Path::new("mesh.obj"))
    }

    #[test]
    fn writes_expected_text() {
        let mut m = IndexedMesh::new();
        m.positions = vec![
            [0.0, -0.0, 1.5],
            [1e-7, 2.0, 3.0],
            [0.1, 1e300, -4.0],
            [5.0; 3],
        ];
        m.push_polygon(&[0, 1, 2, 3]);
        m.lines.push([3, 0]);
        let text = String::from_utf8(encode(&m).unwrap()).unwrap();
        assert_eq!(
            text,
            "# graftal\nv 0 0 1.5\nv 1e-7 2 3\nv 0.1 1e300 -4\nv 5 5 5\nf 1 2 3 4\nl 4 1\n"
        );
    }

    #[test]
    fn round_trip_keeps_ngons_lines_and_exact_positions() {
        for mesh in [test_meshes::cube_with_wire(), test_meshes::awkward()] {
            let bytes = encode(&mesh).unwrap();
            assert_eq!(bytes, encode(&mesh).unwrap(), "deterministic");
            let back = decode(&bytes, Path::new("t.obj")).unwrap();
            assert_eq!(
                back.positions,
                mesh.positions
                    .iter()
                    .map(|p| p.map(|c| if c == 0.0 { 0.0 } else { c }))
                    .collect::<Vec<_>>()
            );
            assert_eq!(back.face_starts, mesh.face_starts);
            assert_eq!(back.face_indices, mesh.face_indices);
            assert_eq!(back.lines, mesh.lines);
            assert!(back.vertex_scalars.is_empty());
        }
    }

    #[test]
    fn tobj_reads_our_output() {
        let mesh = test_meshes::awkward();
        let bytes = encode(&mesh).unwrap();
        let opts = tobj::LoadOptions {
            single_index: false,
            triangulate: false,
            ..Default::default()
        };
        let (models, _) =
            tobj::load_obj_buf(&mut &bytes[..], &opts, |_| Ok(Default::default())).unwrap();
        assert_eq!(models.len(), 1);
        let m = &models[0].mesh;
        // tobj reads the `l` edges as 2-vertex faces after our polygons.
        let arities: Vec<u32> = mesh
            .polygons()
            .map(|p| p.len() as u32)
            .chain(mesh.lines.iter().map(|_| 2))
            .collect();
        assert_eq!(m.face_arities, arities);
    }

    #[test]
    fn reads_common_obj_features() {
        let text = "# comment\n\
                    mtllib x.mtl\no thing\n\
                    v 0 0 0 1\nv 1 0 0\r\nv 1 1 0 0.5 0.5 0.5\nv 0 1 0\n\
                    vt 0 0\nvn 0 0 1\n\
                    g group\nusemtl m\ns off\n\
                    f 1/1/1 2/1/1 3//1 4 # trailing comment\n\
                    f -4 -2 \\\n  -1\n\
                    l 1 2 3\n\
                    p 1\n";
        let m = read(text).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.positions[2], [1.0, 1.0, 0.0]);
        assert_eq!(m.polygon_count(), 2);
        assert_eq!(m.polygon(0), &[0, 1, 2, 3]);
        assert_eq!(m.polygon(1), &[0, 2, 3]);
        assert_eq!(m.lines, vec![[0, 1], [1, 2]]);
    }

    #[test]
    fn forward_references_are_checked_at_the_end() {
        let m = read("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
        assert_eq!(m.polygon(0), &[0, 1, 2]);
        let e = read("v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\nf 1 2 9\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "mesh.obj: line 5: face 2 refers to vertex 9 but only 3 exist"
        );
    }

    #[test]
    fn errors_name_line_and_element() {
        let cases = [
            ("v 0 0\n", "mesh.obj: line 1: vertex 1 needs 3 coordinates"),
            (
                "v 0 0 zz\n",
                "mesh.obj: line 1: vertex 1: invalid number `zz`",
            ),
            (
                "v 0 0 nan\n",
                "mesh.obj: line 1: vertex 1 has a non-finite coordinate",
            ),
            (
                "v 0 0 inf\n",
                "mesh.obj: line 1: vertex 1 has a non-finite coordinate",
            ),
            (
                "v 0 0 0\nf 1 1\n",
                "mesh.obj: line 2: face 1 has 2 vertices (at least 3 required)",
            ),
            (
                "v 0 0 0\nf 1 0 1\n",
                "mesh.obj: line 2: face 1: vertex index 0 is invalid (OBJ counts from 1)",
            ),
            (
                "v 0 0 0\n\nf 1 -2 1\n",
                "mesh.obj: line 3: face 1 refers to vertex -2 but only 1 exist",
            ),
            (
                "v 0 0 0\nf 1 x 1\n",
                "mesh.obj: line 2: face 1: invalid vertex reference `x`",
            ),
            (
                "v 0 0 0\nl 1\n",
                "mesh.obj: line 2: polyline 1 has 1 vertices (at least 2 required)",
            ),
            (
                "v 0 0 0\nl 1 99999999999999999999\n",
                "mesh.obj: line 2: polyline 1: invalid vertex reference `99999999999999999999`",
            ),
            (
                "v 0 0 0\nl 1 4294967297\n",
                "mesh.obj: line 2: polyline 1 refers to vertex 4294967297 but only 1 exist",
            ),
        ];
        for (text, expected) in cases {
            assert_eq!(read(text).unwrap_err().to_string(), expected, "{text:?}");
        }
    }

    #[test]
    fn garbage_does_not_panic() {
        assert_eq!(read("").unwrap(), IndexedMesh::new());
        let mut state = 7u64;
        for round in 0..300 {
            let mut bytes = Vec::new();
            for _ in 0..(round % 60) {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let alphabet = b"vfl -/0123456789.e#\\\n\t\r\xff";
                bytes.push(alphabet[(state >> 33) as usize % alphabet.len()]);
            }
            let _ = decode(&bytes, Path::new("g.obj"));
        }
        // Truncated real output.
        let full = encode(&test_meshes::awkward()).unwrap();
        for cut in 0..full.len() {
            let _ = decode(&full[..cut], Path::new("t.obj"));
        }
    }
}
