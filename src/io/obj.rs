//! Wavefront OBJ.
//!
//! Writing: a `# graftal` header, a `mtllib` line when there are materials, then `v x y z` per
//! vertex, `vt`/`vn` values when the mesh has UVs or corner normals, `f a b c ...` per polygon
//! (1-based, n-gons kept) grouped by part (`o`) and material (`usemtl`), and `l a b` per wire
//! edge. Numbers are the shortest `f64` text that reads back to the same bits. Vertex scalars
//! are not written (OBJ has no place for them).
//!
//! Reading is a small purpose-built parser rather than `tobj`: tobj renumbers vertices per
//! object in first-use order (dropping unused ones and splitting shared ones), stores `f32`
//! unless built with `use_f64`, and reports index errors without line numbers. This parser keeps
//! original vertex numbering and full `f64` precision, reads `v`, `vt`, `vn` (kept bit for bit
//! where unit: `geom::normals::unit_as_read`), `f`/`fo` (n-gons, `v/vt/vn` references, negative
//! relative indices), `l` polylines (split into edges), `o`/`g` (parts), `usemtl` and `mtllib`
//! (materials, numbered in the order the library declares them, as the writer wrote them);
//! other statements (`s`, `p`, ...) are ignored. Comments (`#`) and `\` line continuations are
//! handled. Forward references to vertices defined later are accepted and checked at the end.

use std::path::Path;

use glam::DVec3;

use super::{parse_f64, push_f64, push_u64, text_lines, IoError};
use crate::geom::indexed::IndexedMesh;
use crate::geom::material::sanitize_name;
use crate::geom::normals::unit_as_read;
use crate::geom::source::PolygonSource;

/// Encodes `mesh` as OBJ text (no material library named).
pub fn encode(mesh: &IndexedMesh) -> Result<Vec<u8>, IoError> {
    encode_with_library(mesh, None)
}

/// Encodes `mesh` as OBJ text; with `library`, a `mtllib` line names the
/// `.mtl` file [`encode_mtl`] makes (written beside the OBJ).
///
/// Layout: `v` lines, then shared `vt` and `vn` lines (each distinct value
/// once, in first-use order), then each part as `o NAME`, its polygons by
/// material after `usemtl NAME`, and its wire edges (`l`).
pub fn encode_with_library(mesh: &IndexedMesh, library: Option<&str>) -> Result<Vec<u8>, IoError> {
    mesh.validate()?;
    let mut out = start(mesh, mesh, library);
    // Texture coordinates and normals, each distinct value written once.
    let uv_index = shared_values(&mesh.corner_uvs, b"vt", &mut out);
    let normal_index = shared_values(&mesh.corner_normals, b"vn", &mut out);
    let (order, starts) = mesh.polygon_groups();
    let materials = mesh.materials.len().max(1);
    let named = !mesh.parts.is_empty();
    for part in 0..mesh.part_count() {
        let groups = part * materials..(part + 1) * materials;
        let has_lines = (0..mesh.lines.len()).any(|k| mesh.line_part(k) as usize == part);
        if named && (starts[groups.start] < starts[groups.end] || has_lines) {
            out.extend_from_slice(b"o ");
            out.extend_from_slice(mesh.parts[part].as_bytes());
            out.push(b'\n');
        }
        for g in groups {
            let polygons = &order[starts[g]..starts[g + 1]];
            if polygons.is_empty() {
                continue;
            }
            if let Some(m) = mesh.materials.get(g % materials) {
                out.extend_from_slice(b"usemtl ");
                out.extend_from_slice(m.name.as_bytes());
                out.push(b'\n');
            }
            for &k in polygons {
                let first = mesh.face_starts[k as usize] as usize;
                let corners = first..first + mesh.polygon(k as usize).len();
                let uvs = uv_index.get(corners.clone()).unwrap_or_default();
                let normals = normal_index.get(corners).unwrap_or_default();
                push_face(&mut out, mesh.polygon(k as usize), uvs, normals);
            }
        }
        for (k, line) in mesh.lines.iter().enumerate() {
            if mesh.line_part(k) as usize != part {
                continue;
            }
            out.extend_from_slice(b"l ");
            push_u64(&mut out, u64::from(line[0]) + 1);
            out.push(b' ');
            push_u64(&mut out, u64::from(line[1]) + 1);
            out.push(b'\n');
        }
    }
    Ok(out)
}

/// The bytes [`encode_with_library`] gives for `look` with the vertices
/// and polygons of `source` in place of its own, written straight from
/// `source` (a kernel mesh: no indexed copy). `look` holds at most one part
/// and one material and nothing per polygon or corner (see
/// `gltf::Planned::new`): every polygon is in its one group.
pub fn encode_streamed<S: PolygonSource>(
    source: &S,
    look: &IndexedMesh,
    library: Option<&str>,
) -> Result<Vec<u8>, IoError> {
    debug_assert!(look.polygon_count() == 0 && look.lines.is_empty() && look.parts.len() <= 1);
    source.check_vertices()?;
    let mut out = start(source, look, library);
    if source.polygon_count() > 0 {
        if let Some(name) = look.parts.first() {
            out.extend_from_slice(b"o ");
            out.extend_from_slice(name.as_bytes());
            out.push(b'\n');
        }
        if let Some(m) = look.materials.first() {
            out.extend_from_slice(b"usemtl ");
            out.extend_from_slice(m.name.as_bytes());
            out.push(b'\n');
        }
        source.for_each_polygon(|poly, _| push_face(&mut out, poly, &[], &[]));
    }
    Ok(out)
}

/// The header (`mtllib` when `mesh` has materials and a library is named)
/// and a `v` line per vertex of `source`.
fn start<S: PolygonSource>(source: &S, mesh: &IndexedMesh, library: Option<&str>) -> Vec<u8> {
    let mut out = Vec::with_capacity(16 + source.vertex_count() * 40 + source.corner_count() * 8);
    out.extend_from_slice(b"# graftal\n");
    if let Some(name) = library.filter(|_| !mesh.materials.is_empty()) {
        out.extend_from_slice(b"mtllib ");
        out.extend_from_slice(name.as_bytes());
        out.push(b'\n');
    }
    for v in 0..source.vertex_count() {
        out.push(b'v');
        for c in source.position(v as u32).to_array() {
            out.push(b' ');
            push_f64(&mut out, c);
        }
        out.push(b'\n');
    }
    out
}

/// One `f` line: 1-based vertex numbers, each with its corner's `vt` and
/// `vn` line numbers where given (0-based, aligned with `poly`).
fn push_face(out: &mut Vec<u8>, poly: &[u32], uvs: &[u32], normals: &[u32]) {
    out.push(b'f');
    for (i, &v) in poly.iter().enumerate() {
        out.push(b' ');
        push_u64(out, u64::from(v) + 1);
        let (uv, normal) = (uvs.get(i), normals.get(i));
        if uv.is_some() || normal.is_some() {
            out.push(b'/');
            if let Some(&t) = uv {
                push_u64(out, u64::from(t) + 1);
            }
            if let Some(&n) = normal {
                out.push(b'/');
                push_u64(out, u64::from(n) + 1);
            }
        }
    }
    out.push(b'\n');
}

/// Writes each distinct value of `values` once as `keyword a b [c]`, in
/// first-use order; returns each entry's line index (0-based).
fn shared_values<const N: usize>(
    values: &[[f64; N]],
    keyword: &[u8],
    out: &mut Vec<u8>,
) -> Vec<u32> {
    let mut seen: std::collections::HashMap<[u64; N], u32> = std::collections::HashMap::new();
    let mut index = Vec::with_capacity(values.len());
    for v in values {
        // -0 and 0 are one value (equal geometry, equal bytes).
        let v = v.map(|c| c + 0.0);
        let next = seen.len() as u32;
        let i = *seen.entry(v.map(f64::to_bits)).or_insert_with(|| {
            out.extend_from_slice(keyword);
            for c in v {
                out.push(b' ');
                push_f64(out, c);
            }
            out.push(b'\n');
            next
        });
        index.push(i);
    }
    index
}

/// The material library (`.mtl`) of `mesh`'s materials, `None` when it
/// has none: `Kd` is the base colour (linear, as Blender writes it), `d`
/// its alpha, `Ke` emission, and the PBR extension's `Pm`/`Pr` metallic
/// and roughness.
pub fn encode_mtl(mesh: &IndexedMesh) -> Option<Vec<u8>> {
    if mesh.materials.is_empty() {
        return None;
    }
    let mut out = b"# graftal\n".to_vec();
    for m in &mesh.materials {
        out.extend_from_slice(b"newmtl ");
        out.extend_from_slice(m.name.as_bytes());
        out.push(b'\n');
        let mut line = |key: &[u8], values: &[f64]| {
            out.extend_from_slice(key);
            for &v in values {
                out.push(b' ');
                push_f64(&mut out, v);
            }
            out.push(b'\n');
        };
        line(b"Kd", &m.base_color[..3]);
        line(b"d", &m.base_color[3..]);
        line(b"Ke", &m.emissive);
        line(b"Pm", &[m.metallic]);
        line(b"Pr", &[m.roughness]);
        out.extend_from_slice(b"illum 2\n");
    }
    Some(out)
}

/// Decodes OBJ text; `path` names the file in errors. Material names
/// come through, with graftal's fallback values (see [`decode_with`]).
pub fn decode(bytes: &[u8], path: &Path) -> Result<IndexedMesh, IoError> {
    decode_with(bytes, path, &mut |_, _| {
        Err("no material library reader".into())
    })
}

/// [`decode`], with `resolve` reading the `mtllib` files (a library that
/// cannot be read leaves its materials at graftal's fallback values).
pub fn decode_with(
    bytes: &[u8],
    path: &Path,
    resolve: &mut super::Resolve,
) -> Result<IndexedMesh, IoError> {
    let mut parser = Parser {
        path,
        mesh: IndexedMesh::new(),
        faces: 0,
        polylines: 0,
        refs: Vec::new(),
        forward: Vec::new(),
        looks: ObjLooks::default(),
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
    let libraries = std::mem::take(&mut parser.looks.libraries);
    let mut mesh = parser.finish()?;
    let mut declared = Vec::new();
    for library in libraries {
        // At most 16 MiB of material library: names and a few numbers.
        if let Ok(text) = resolve(&library, 16 << 20) {
            read_mtl(&text, &mut mesh.materials, &mut declared);
        }
    }
    order_as_declared(&mut mesh, &declared);
    Ok(mesh)
}

/// Numbers the materials in the order their library declares them (the
/// writer's order), then the undeclared ones in first-use order: faces are
/// written grouped by part, so first use alone would reorder the materials
/// of a file graftal wrote, and a second conversion would not be a fixed
/// point.
fn order_as_declared(mesh: &mut IndexedMesh, declared: &[usize]) {
    let count = mesh.materials.len();
    let mut order: Vec<usize> = Vec::with_capacity(count);
    let mut placed = vec![false; count];
    for &i in declared {
        if !std::mem::replace(&mut placed[i], true) {
            order.push(i);
        }
    }
    order.extend((0..count).filter(|&i| !placed[i]));
    if order.iter().enumerate().all(|(k, &i)| k == i) {
        return;
    }
    let mut new_index = vec![0u32; count];
    for (k, &i) in order.iter().enumerate() {
        new_index[i] = k as u32;
    }
    let mut old = std::mem::take(&mut mesh.materials);
    mesh.materials = order
        .iter()
        .map(|&i| std::mem::replace(&mut old[i], crate::geom::Material::fallback()))
        .collect();
    for m in &mut mesh.polygon_materials {
        *m = new_index[*m as usize];
    }
}

/// Materials, parts and corner values as the statements give them.
#[derive(Default)]
struct ObjLooks {
    /// `vt` and `vn` values.
    uvs: Vec<[f64; 2]>,
    normals: Vec<[f64; 3]>,
    /// Per corner, as written; resolved at the end.
    corner_uvs: Vec<CornerRef>,
    corner_normals: Vec<CornerRef>,
    /// Part (`o`/`g`) and material (`usemtl`) names in first-use order.
    parts: Vec<String>,
    materials: Vec<String>,
    part: Option<u32>,
    material: Option<u32>,
    polygon_parts: Vec<Option<u32>>,
    line_parts: Vec<Option<u32>>,
    polygon_materials: Vec<Option<u32>>,
    libraries: Vec<String>,
}

/// A corner's `vt` or `vn` reference as written.
#[derive(Clone, Copy, Default)]
struct CornerRef {
    /// 1-based, negative relative to `count`; 0 = none.
    value: i64,
    /// Values read before the statement (for relative references).
    count: usize,
    line: usize,
    face: usize,
}

/// Index of `name` in `names`, added when new.
fn intern(names: &mut Vec<String>, name: String) -> u32 {
    match names.iter().position(|n| *n == name) {
        Some(i) => i as u32,
        None => {
            names.push(name);
            names.len() as u32 - 1
        }
    }
}

/// Fills the values of `materials` from a `.mtl` library's `newmtl`
/// blocks (`Kd`, `d`/`Tr`, `Ke`, `Pm`, `Pr`; others ignored); unknown
/// materials and malformed lines are skipped.
fn read_mtl(text: &[u8], materials: &mut [crate::geom::Material], declared: &mut Vec<usize>) {
    let mut current: Option<usize> = None;
    for (_, raw) in text_lines(text) {
        let content = match raw.iter().position(|&b| b == b'#') {
            Some(hash) => &raw[..hash],
            None => raw,
        };
        let mut tokens = content
            .split(u8::is_ascii_whitespace)
            .filter(|t| !t.is_empty());
        let Some(keyword) = tokens.next() else {
            continue;
        };
        let rest: Vec<&[u8]> = tokens.collect();
        if keyword == b"newmtl" {
            let name = sanitize_name(&String::from_utf8_lossy(&rest.join(&b' ')), "material");
            current = materials.iter().position(|m| m.name == name);
            declared.extend(current);
            continue;
        }
        let Some(m) = current.map(|i| &mut materials[i]) else {
            continue;
        };
        let numbers: Vec<f64> = rest
            .iter()
            .map_while(|t| parse_f64(t))
            .filter(|x| x.is_finite())
            .map(|x| x.clamp(0.0, 1.0))
            .collect();
        match (keyword, numbers.as_slice()) {
            (b"Kd", [r, g, b, ..]) => m.base_color[..3].copy_from_slice(&[*r, *g, *b]),
            (b"d", [d, ..]) => m.base_color[3] = *d,
            (b"Tr", [t, ..]) => m.base_color[3] = 1.0 - t,
            (b"Ke", [r, g, b, ..]) => m.emissive = [*r, *g, *b],
            (b"Pm", [x, ..]) => m.metallic = *x,
            (b"Pr", [x, ..]) => m.roughness = *x,
            _ => {}
        }
    }
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
    looks: ObjLooks,
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
                self.looks.polygon_parts.push(self.looks.part);
                self.looks.polygon_materials.push(self.looks.material);
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
                let part = self.looks.part;
                self.looks.line_parts.resize(self.mesh.lines.len(), part);
                Ok(())
            }
            b"vt" => {
                let [u, v] = self.numbers(line, "texture coordinate", tokens)?;
                self.looks.uvs.push([u, v]);
                Ok(())
            }
            b"vn" => {
                let n = DVec3::from_array(self.numbers(line, "normal", tokens)?);
                // Unit length (files often round; kept bit for bit where
                // already unit, so a second conversion changes nothing), +Z
                // where degenerate.
                let n = unit_as_read(n).unwrap_or(DVec3::Z);
                self.looks.normals.push(n.to_array());
                Ok(())
            }
            b"o" | b"g" => {
                let name = tokens.collect::<Vec<_>>().join(&b' ');
                let name = sanitize_name(&String::from_utf8_lossy(&name), "group");
                self.looks.part = Some(intern(&mut self.looks.parts, name));
                Ok(())
            }
            b"usemtl" => {
                let name = tokens.collect::<Vec<_>>().join(&b' ');
                let name = sanitize_name(&String::from_utf8_lossy(&name), "material");
                self.looks.material = Some(intern(&mut self.looks.materials, name));
                Ok(())
            }
            b"mtllib" => {
                let name = tokens.collect::<Vec<_>>().join(&b' ');
                self.looks
                    .libraries
                    .push(String::from_utf8_lossy(&name).into_owned());
                Ok(())
            }
            _ => Ok(()),
        }
    }

    /// The `N` finite numbers of a `vt` or `vn` statement (a `vt`'s
    /// optional third coordinate is ignored).
    fn numbers<'t, const N: usize>(
        &self,
        line: usize,
        what: &str,
        mut tokens: impl Iterator<Item = &'t [u8]>,
    ) -> Result<[f64; N], IoError> {
        let mut out = [0.0; N];
        for c in &mut out {
            let token = tokens
                .next()
                .ok_or_else(|| self.syntax(line, format!("{what} needs {N} numbers")))?;
            *c = parse_f64(token).filter(|x| x.is_finite()).ok_or_else(|| {
                self.syntax(
                    line,
                    format!(
                        "{what}: invalid number `{}`",
                        String::from_utf8_lossy(token)
                    ),
                )
            })?;
        }
        Ok(out)
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
            let mut fields = token.split(|&b| b == b'/');
            let v_part = fields.next().unwrap_or_default();
            if element == "face" {
                // `v/vt/vn`, `v//vn`, `v/vt`: the corner's references,
                // resolved against the values read so far.
                let reference =
                    |field: Option<&[u8]>, count: usize| -> Result<CornerRef, IoError> {
                        let Some(text) = field.filter(|t| !t.is_empty()) else {
                            return Ok(CornerRef::default());
                        };
                        let value: i64 = std::str::from_utf8(text)
                            .ok()
                            .and_then(|s| s.parse().ok())
                            .filter(|&v| v != 0)
                            .ok_or_else(|| {
                                self.syntax(
                                    line,
                                    format!(
                                        "{element} {index}: invalid reference `{}`",
                                        String::from_utf8_lossy(token)
                                    ),
                                )
                            })?;
                        Ok(CornerRef {
                            value,
                            count,
                            line,
                            face: index,
                        })
                    };
                let uv = reference(fields.next(), self.looks.uvs.len())?;
                let normal = reference(fields.next(), self.looks.normals.len())?;
                self.looks.corner_uvs.push(uv);
                self.looks.corner_normals.push(normal);
            }
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
        let mut mesh = self.mesh;
        let looks = self.looks;
        let path = self.path;
        let resolve = |r: &CornerRef, total: usize, what: &str| -> Result<Option<usize>, IoError> {
            if r.value == 0 {
                return Ok(None);
            }
            let i = if r.value > 0 {
                r.value - 1
            } else {
                r.count as i64 + r.value
            };
            match usize::try_from(i).ok().filter(|&i| i < total) {
                Some(i) => Ok(Some(i)),
                None => Err(IoError::Syntax {
                    path: path.to_path_buf(),
                    line: r.line,
                    message: format!(
                        "face {}: {what} {} does not exist ({total} read)",
                        r.face, r.value
                    ),
                }),
            }
        };
        if looks.corner_uvs.iter().any(|r| r.value != 0) {
            mesh.corner_uvs = looks
                .corner_uvs
                .iter()
                .map(|r| {
                    resolve(r, looks.uvs.len(), "texture coordinate")
                        .map(|i| i.map_or([0.0; 2], |i| looks.uvs[i]))
                })
                .collect::<Result<_, _>>()?;
        }
        if looks.corner_normals.iter().any(|r| r.value != 0) {
            let mut flat = Vec::with_capacity(mesh.face_indices.len());
            let mut tri = crate::geom::indexed::PolygonTriangulator::default();
            for poly in mesh.polygons() {
                let n = tri.run(&mesh, poly).unwrap_or(DVec3::Z).to_array();
                flat.extend(std::iter::repeat_n(n, poly.len()));
            }
            mesh.corner_normals = looks
                .corner_normals
                .iter()
                .zip(flat)
                .map(|(r, flat)| {
                    resolve(r, looks.normals.len(), "normal")
                        .map(|i| i.map_or(flat, |i| looks.normals[i]))
                })
                .collect::<Result<_, _>>()?;
        }
        let has_parts = !looks.parts.is_empty();
        if has_parts {
            // Elements before the first `o`/`g` form a part of their own.
            let mut parts = looks.parts;
            let unnamed = looks
                .polygon_parts
                .iter()
                .chain(&looks.line_parts)
                .any(Option::is_none);
            let default = parts.len() as u32;
            if unnamed {
                parts.push("default".into());
                crate::geom::material::dedupe_names(&mut parts);
            }
            mesh.parts = parts;
            mesh.polygon_parts = looks
                .polygon_parts
                .iter()
                .map(|p| p.unwrap_or(default))
                .collect();
            mesh.line_parts = looks
                .line_parts
                .iter()
                .map(|p| p.unwrap_or(default))
                .collect();
        }
        if !looks.materials.is_empty() && mesh.polygon_count() > 0 {
            let mut names = looks.materials;
            let default = names.len() as u32;
            if looks.polygon_materials.iter().any(Option::is_none) {
                names.push("default".into());
                crate::geom::material::dedupe_names(&mut names);
            }
            mesh.materials = names
                .into_iter()
                .map(|name| crate::geom::Material {
                    name,
                    ..crate::geom::Material::fallback()
                })
                .collect();
            mesh.polygon_materials = looks
                .polygon_materials
                .iter()
                .map(|m| m.unwrap_or(default))
                .collect();
        }
        Ok(mesh)
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
