//! Stanford PLY, ASCII and binary.
//!
//! Writing (`format ascii 1.0` or `format binary_little_endian 1.0`, one `comment graftal`):
//!
//! ```text
//! element vertex N      property double x, y, z, then one `property double NAME` per scalar
//! element face M        property list uchar int vertex_indices   (uint counts if a polygon
//!                       has more than 255 vertices)
//! element edge K        property int vertex1, property int vertex2   (only if there are lines)
//! ```
//!
//! A mesh with parts names them in `comment part K NAME` header lines and
//! gives faces and edges an `int part` property (read back the same way).
//!
//! Reading accepts ASCII, binary little endian and binary big endian with any scalar types:
//! `vertex` (`x`, `y`, `z` required; every other scalar property whose name is a valid scalar
//! name becomes a vertex scalar), `face` (`vertex_indices` or `vertex_index` list), `edge`
//! (`vertex1`, `vertex2`); other elements and properties are skipped.

use std::path::Path;

use super::{push_f64, push_u64, IoError};
use crate::geom::indexed::IndexedMesh;
use crate::geom::material::{linear_to_srgb, sanitize_name, srgb_to_linear};
use crate::geom::source::PolygonSource;

/// Most parts a PLY file's `part` property may number (a part becomes a
/// node or group in other formats).
const MAX_PARTS: u32 = 1 << 16;

/// PLY body encoding for writing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    Ascii,
    BinaryLittleEndian,
}

/// Encodes `mesh` as PLY.
pub fn encode(mesh: &IndexedMesh, encoding: Encoding) -> Result<Vec<u8>, IoError> {
    mesh.validate()?;
    encode_look(mesh, mesh, encoding)
}

/// The bytes [`encode`] gives for `look` with the vertices and polygons of
/// `source` in place of its own, written straight from `source` (a kernel
/// mesh: no indexed copy). `look` gives the parts, lines, face colours
/// and vertex scalars, numbered as `source` numbers its polygons and
/// vertices (a look without per-polygon parts puts every face in part 0).
pub fn encode_streamed<S: PolygonSource>(
    source: &S,
    look: &IndexedMesh,
    encoding: Encoding,
) -> Result<Vec<u8>, IoError> {
    source.check_vertices()?;
    encode_look(source, look, encoding)
}

fn encode_look<S: PolygonSource>(
    source: &S,
    mesh: &IndexedMesh,
    encoding: Encoding,
) -> Result<Vec<u8>, IoError> {
    let vertex_count = source.vertex_count();
    if i32::try_from(vertex_count).is_err() {
        return Err(IoError::InvalidMesh {
            message: format!("{vertex_count} vertices exceed PLY's int index range"),
        });
    }
    let scalars = mesh.sorted_scalars();
    let wide_counts = source.max_polygon_len() > 255;

    let mut out = Vec::with_capacity(
        256 + vertex_count * (24 + 8 * scalars.len()) + source.corner_count() * 5,
    );
    out.extend_from_slice(b"ply\nformat ");
    out.extend_from_slice(match encoding {
        Encoding::Ascii => b"ascii",
        Encoding::BinaryLittleEndian => b"binary_little_endian",
    });
    out.extend_from_slice(b" 1.0\ncomment graftal\n");
    // Part names ride in comments; faces and edges carry the index.
    for (k, name) in mesh.parts.iter().enumerate() {
        out.extend_from_slice(b"comment part ");
        push_u64(&mut out, k as u64);
        out.push(b' ');
        out.extend_from_slice(name.as_bytes());
        out.push(b'\n');
    }
    let parts = !mesh.parts.is_empty();
    out.extend_from_slice(b"element vertex ");
    push_u64(&mut out, vertex_count as u64);
    out.extend_from_slice(b"\nproperty double x\nproperty double y\nproperty double z\n");
    for (name, _) in &scalars {
        out.extend_from_slice(b"property double ");
        out.extend_from_slice(name.as_bytes());
        out.push(b'\n');
    }
    out.extend_from_slice(b"element face ");
    push_u64(&mut out, source.polygon_count() as u64);
    out.extend_from_slice(if wide_counts {
        b"\nproperty list uint int vertex_indices\n"
    } else {
        b"\nproperty list uchar int vertex_indices\n"
    });
    if parts {
        out.extend_from_slice(b"property int part\n");
    }
    let colors = face_colors(mesh);
    if !colors.is_empty() {
        out.extend_from_slice(b"property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    if !mesh.lines.is_empty() {
        out.extend_from_slice(b"element edge ");
        push_u64(&mut out, mesh.lines.len() as u64);
        out.extend_from_slice(b"\nproperty int vertex1\nproperty int vertex2\n");
        if parts {
            out.extend_from_slice(b"property int part\n");
        }
    }
    out.extend_from_slice(b"end_header\n");

    match encoding {
        Encoding::Ascii => {
            for v in 0..vertex_count {
                let p = source.position(v as u32).to_array();
                let values = p.into_iter().chain(scalars.iter().map(|(_, s)| s[v]));
                for (k, x) in values.enumerate() {
                    if k > 0 {
                        out.push(b' ');
                    }
                    push_f64(&mut out, x);
                }
                out.push(b'\n');
            }
            let mut k = 0;
            source.for_each_polygon(|poly, _| {
                push_u64(&mut out, poly.len() as u64);
                for &i in poly {
                    out.push(b' ');
                    push_u64(&mut out, u64::from(i));
                }
                if parts {
                    out.push(b' ');
                    push_u64(&mut out, u64::from(mesh.polygon_part(k)));
                }
                for &c in colors.get(k).into_iter().flatten() {
                    out.push(b' ');
                    push_u64(&mut out, u64::from(c));
                }
                out.push(b'\n');
                k += 1;
            });
            for (k, line) in mesh.lines.iter().enumerate() {
                push_u64(&mut out, u64::from(line[0]));
                out.push(b' ');
                push_u64(&mut out, u64::from(line[1]));
                if parts {
                    out.push(b' ');
                    push_u64(&mut out, u64::from(mesh.line_part(k)));
                }
                out.push(b'\n');
            }
        }
        Encoding::BinaryLittleEndian => {
            for v in 0..vertex_count {
                let p = source.position(v as u32).to_array();
                let values = p.into_iter().chain(scalars.iter().map(|(_, s)| s[v]));
                for x in values {
                    let x = if x == 0.0 { 0.0 } else { x };
                    out.extend_from_slice(&x.to_le_bytes());
                }
            }
            let mut k = 0;
            source.for_each_polygon(|poly, _| {
                if wide_counts {
                    out.extend_from_slice(&(poly.len() as u32).to_le_bytes());
                } else {
                    out.push(poly.len() as u8);
                }
                for &i in poly {
                    // Validated above: every index is below the vertex count <= i32::MAX.
                    out.extend_from_slice(&(i as i32).to_le_bytes());
                }
                if parts {
                    out.extend_from_slice(&(mesh.polygon_part(k) as i32).to_le_bytes());
                }
                if let Some(c) = colors.get(k) {
                    out.extend_from_slice(c);
                }
                k += 1;
            });
            for (k, line) in mesh.lines.iter().enumerate() {
                for &i in line {
                    out.extend_from_slice(&(i as i32).to_le_bytes());
                }
                if parts {
                    out.extend_from_slice(&(mesh.line_part(k) as i32).to_le_bytes());
                }
            }
        }
    }
    Ok(out)
}

/// Each polygon's colour as sRGB bytes (its first corner's: graftal's
/// colours are per face), or nothing when the mesh has no colours.
fn face_colors(mesh: &IndexedMesh) -> Vec<[u8; 3]> {
    if mesh.corner_colors.is_empty() {
        return Vec::new();
    }
    (0..mesh.polygon_count())
        .map(|k| {
            let c = mesh.corner_colors[mesh.face_starts[k] as usize];
            c.map(|x| (linear_to_srgb(x) * 255.0).round().clamp(0.0, 255.0) as u8)
        })
        .collect()
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The value of `raw` (exactly [`Scalar::size`] bytes), as `f64`
    /// (every PLY scalar type converts exactly).
    #[inline]
    fn decode(self, raw: &[u8], big_endian: bool) -> f64 {
        let size = self.size();
        let mut buf = [0u8; 8];
        buf[..size].copy_from_slice(&raw[..size]);
        if big_endian {
            buf[..size].reverse();
        }
        let [b0, b1, b2, b3, ..] = buf;
        match self {
            Scalar::I8 => f64::from(b0 as i8),
            Scalar::U8 => f64::from(b0),
            Scalar::I16 => f64::from(i16::from_le_bytes([b0, b1])),
            Scalar::U16 => f64::from(u16::from_le_bytes([b0, b1])),
            Scalar::I32 => f64::from(i32::from_le_bytes([b0, b1, b2, b3])),
            Scalar::U32 => f64::from(u32::from_le_bytes([b0, b1, b2, b3])),
            Scalar::F32 => f64::from(f32::from_le_bytes([b0, b1, b2, b3])),
            Scalar::F64 => f64::from_le_bytes(buf),
        }
    }
}

#[derive(Debug)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Ascii,
    Binary { big_endian: bool },
}

struct Header {
    format: Format,
    elements: Vec<Element>,
    /// `comment part K NAME` lines: part names by index.
    part_names: Vec<(u64, String)>,
    /// Byte offset of the body.
    body: usize,
}

fn parse_header(bytes: &[u8], path: &Path) -> Result<Header, IoError> {
    let syntax = |line: usize, message: String| IoError::Syntax {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut offset = 0;
    let mut line_no = 0;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut part_names = Vec::new();
    loop {
        line_no += 1;
        let Some(len) = bytes[offset..].iter().position(|&b| b == b'\n') else {
            return Err(syntax(line_no, "header has no `end_header` line".into()));
        };
        let raw = &bytes[offset..offset + len];
        offset += len + 1;
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        let text = std::str::from_utf8(raw)
            .map_err(|_| syntax(line_no, "header line is not valid text".into()))?;
        let mut words = text.split_ascii_whitespace();
        if line_no == 1 {
            if text.trim() != "ply" {
                return Err(syntax(
                    1,
                    "not a PLY file (first line must be `ply`)".into(),
                ));
            }
            continue;
        }
        match words.next() {
            Some("comment") => {
                if let (Some("part"), Some(k), Some(name)) =
                    (words.next(), words.next(), words.next())
                {
                    if let Ok(k) = k.parse::<u64>() {
                        part_names.push((k, name.to_owned()));
                    }
                }
            }
            None | Some("obj_info") => {}
            Some("format") => {
                let f = match words.next() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::Binary { big_endian: false },
                    Some("binary_big_endian") => Format::Binary { big_endian: true },
                    other => {
                        return Err(syntax(
                            line_no,
                            format!("unknown PLY format {:?}", other.unwrap_or("")),
                        ))
                    }
                };
                if words.next() != Some("1.0") {
                    return Err(syntax(line_no, "only PLY version 1.0 is supported".into()));
                }
                format = Some(f);
            }
            Some("element") => {
                let (Some(name), Some(count)) = (words.next(), words.next()) else {
                    return Err(syntax(line_no, "`element` needs a name and a count".into()));
                };
                let count = count
                    .parse()
                    .map_err(|_| syntax(line_no, format!("invalid element count `{count}`")))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            Some("property") => {
                let Some(element) = elements.last_mut() else {
                    return Err(syntax(line_no, "`property` before any `element`".into()));
                };
                let parts: Vec<&str> = words.collect();
                let type_of = |name: &str| {
                    Scalar::parse(name)
                        .ok_or_else(|| syntax(line_no, format!("unknown property type `{name}`")))
                };
                let property = match parts.as_slice() {
                    ["list", count, item, name] => Property {
                        name: name.to_string(),
                        kind: Kind::List {
                            count: type_of(count)?,
                            item: type_of(item)?,
                        },
                    },
                    [ty, name] if *ty != "list" => Property {
                        name: name.to_string(),
                        kind: Kind::Scalar(type_of(ty)?),
                    },
                    _ => return Err(syntax(line_no, format!("malformed property `{text}`"))),
                };
                if let Kind::List { count, .. } = property.kind {
                    if !count.is_integer() {
                        return Err(syntax(line_no, "list counts must be integers".into()));
                    }
                }
                element.properties.push(property);
            }
            Some("end_header") => break,
            Some(other) => {
                return Err(syntax(line_no, format!("unknown header keyword `{other}`")))
            }
        }
    }
    let format = format.ok_or_else(|| syntax(line_no, "header has no `format` line".into()))?;
    Ok(Header {
        format,
        elements,
        part_names,
        body: offset,
    })
}

/// Reads body values as `f64` (every PLY scalar type converts exactly).
trait Body {
    fn value(&mut self, ty: Scalar, what: &dyn Fn() -> String) -> Result<f64, IoError>;

    /// A binary body's bytes, its read offset and byte order, for the
    /// fixed-layout fast path ([`fixed_layout_records`]); `None` for text.
    fn binary(&mut self) -> Option<(&[u8], &mut usize, bool)> {
        None
    }
}

struct BinaryBody<'a> {
    bytes: &'a [u8],
    offset: usize,
    big_endian: bool,
    path: &'a Path,
}

impl Body for BinaryBody<'_> {
    fn binary(&mut self) -> Option<(&[u8], &mut usize, bool)> {
        Some((self.bytes, &mut self.offset, self.big_endian))
    }

    fn value(&mut self, ty: Scalar, _what: &dyn Fn() -> String) -> Result<f64, IoError> {
        let size = ty.size();
        let Some(raw) = self.bytes.get(self.offset..self.offset + size) else {
            return Err(IoError::Truncated {
                path: self.path.to_path_buf(),
                what: "binary PLY",
                offset: self.bytes.len() as u64,
                expected: (self.offset + size) as u64,
            });
        };
        self.offset += size;
        Ok(ty.decode(raw, self.big_endian))
    }
}

struct AsciiBody<'a> {
    bytes: &'a [u8],
    offset: usize,
    line: usize,
    /// Line of the last token read (where an unexpected end of file is reported).
    last_line: usize,
    path: &'a Path,
}

impl Body for AsciiBody<'_> {
    fn value(&mut self, ty: Scalar, what: &dyn Fn() -> String) -> Result<f64, IoError> {
        while let Some(&b) = self.bytes.get(self.offset) {
            if !b.is_ascii_whitespace() {
                break;
            }
            if b == b'\n' {
                self.line += 1;
            }
            self.offset += 1;
        }
        let start = self.offset;
        while self
            .bytes
            .get(self.offset)
            .is_some_and(|b| !b.is_ascii_whitespace())
        {
            self.offset += 1;
        }
        let token = &self.bytes[start..self.offset];
        if token.is_empty() {
            return Err(IoError::Syntax {
                path: self.path.to_path_buf(),
                line: self.last_line,
                message: format!("file ends before {}", what()),
            });
        }
        self.last_line = self.line;
        let syntax = |message: String| IoError::Syntax {
            path: self.path.to_path_buf(),
            line: self.line,
            message,
        };
        let value = super::parse_f64(token)
            .filter(|v| !ty.is_integer() || v.fract() == 0.0)
            .ok_or_else(|| {
                syntax(format!(
                    "invalid {} `{}`",
                    what(),
                    String::from_utf8_lossy(token)
                ))
            })?;
        Ok(value)
    }
}

/// Decodes PLY; `path` names the file in errors.
pub fn decode(bytes: &[u8], path: &Path) -> Result<IndexedMesh, IoError> {
    let header = parse_header(bytes, path)?;
    match header.format {
        Format::Ascii => {
            let header_lines = bytes[..header.body].iter().filter(|&&b| b == b'\n').count();
            let mut body = AsciiBody {
                bytes,
                offset: header.body,
                line: header_lines + 1,
                last_line: header_lines,
                path,
            };
            read_body(&header, &mut body, path)
        }
        Format::Binary { big_endian } => {
            let mut body = BinaryBody {
                bytes,
                offset: header.body,
                big_endian,
                path,
            };
            read_body(&header, &mut body, path)
        }
    }
}

/// What a property of a known element turns into.
#[derive(Clone, Copy)]
enum Role {
    Skip,
    Coordinate(usize),
    Scalar(usize),
    FaceIndices,
    EdgeEnd(usize),
    Part,
    /// A face's red, green or blue (0–255 for integers, 0–1 for floats).
    Color(usize),
}

fn read_body(header: &Header, body: &mut dyn Body, path: &Path) -> Result<IndexedMesh, IoError> {
    let malformed = |message: String| IoError::Malformed {
        path: path.to_path_buf(),
        message,
    };
    let vertex_count = header
        .elements
        .iter()
        .find(|e| e.name == "vertex")
        .map_or(0, |e| e.count);
    if u32::try_from(vertex_count).is_err() {
        return Err(malformed(format!(
            "{vertex_count} vertices exceed the u32 range"
        )));
    }
    let mut mesh = IndexedMesh::new();
    let mut scalars: Vec<(String, Vec<f64>)> = Vec::new();
    let mut list: Vec<u32> = Vec::new();
    let (mut polygon_parts, mut line_parts, mut parts_read) = (Vec::new(), Vec::new(), false);
    let (mut face_colors, mut colors_read) = (Vec::new(), false);
    let mut vertex_colors: Vec<[f64; 3]> = Vec::new();
    // Caps up-front allocation: counts come from an untrusted header.
    let cap = |count: u64| count.min(1 << 16) as usize;

    for element in &header.elements {
        // red, green and blue together are a colour; one alone a scalar.
        let rgb = ["red", "green", "blue"].iter().all(|c| {
            element
                .properties
                .iter()
                .any(|p| p.name == *c && matches!(p.kind, Kind::Scalar(_)))
        });
        let roles: Vec<Role> = element
            .properties
            .iter()
            .map(
                |p| match (element.name.as_str(), p.name.as_str(), &p.kind) {
                    ("vertex", "x", Kind::Scalar(_)) => Role::Coordinate(0),
                    ("vertex", "y", Kind::Scalar(_)) => Role::Coordinate(1),
                    ("vertex", "z", Kind::Scalar(_)) => Role::Coordinate(2),
                    // Vertex colours (what trimesh, MeshLab and Open3D write):
                    // each corner takes its vertex's.
                    ("vertex", "red", Kind::Scalar(_)) if rgb => Role::Color(0),
                    ("vertex", "green", Kind::Scalar(_)) if rgb => Role::Color(1),
                    ("vertex", "blue", Kind::Scalar(_)) if rgb => Role::Color(2),
                    ("vertex", name, Kind::Scalar(_)) if valid_scalar_name(name) => {
                        // A case-insensitive duplicate name is skipped rather than rejected.
                        if scalars.iter().any(|(n, _)| n.eq_ignore_ascii_case(name)) {
                            Role::Skip
                        } else {
                            scalars
                                .push((name.to_string(), Vec::with_capacity(cap(element.count))));
                            Role::Scalar(scalars.len() - 1)
                        }
                    }
                    ("face", "vertex_indices" | "vertex_index", Kind::List { .. }) => {
                        Role::FaceIndices
                    }
                    ("edge", "vertex1", Kind::Scalar(_)) => Role::EdgeEnd(0),
                    ("edge", "vertex2", Kind::Scalar(_)) => Role::EdgeEnd(1),
                    ("face" | "edge", "part", Kind::Scalar(_)) => Role::Part,
                    ("face", "red", Kind::Scalar(_)) => Role::Color(0),
                    ("face", "green", Kind::Scalar(_)) => Role::Color(1),
                    ("face", "blue", Kind::Scalar(_)) => Role::Color(2),
                    _ => Role::Skip,
                },
            )
            .collect();
        let has = |f: &dyn Fn(&Role) -> bool| roles.iter().any(f);
        let has_color = has(&|r| matches!(r, Role::Color(_)));
        match element.name.as_str() {
            "vertex" => {
                for axis in 0..3 {
                    if !has(&|r| matches!(r, Role::Coordinate(a) if *a == axis)) {
                        return Err(malformed(format!(
                            "vertex element has no `{}` property",
                            ["x", "y", "z"][axis]
                        )));
                    }
                }
                mesh.positions.reserve(cap(element.count));
            }
            "face" if !has(&|r| matches!(r, Role::FaceIndices)) => {
                return Err(malformed(
                    "face element has no `vertex_indices` list".to_string(),
                ));
            }
            "edge"
                if !(has(&|r| matches!(r, Role::EdgeEnd(0)))
                    && has(&|r| matches!(r, Role::EdgeEnd(1)))) =>
            {
                return Err(malformed(
                    "edge element needs `vertex1` and `vertex2` properties".to_string(),
                ));
            }
            _ => {}
        }
        if element.properties.is_empty() {
            continue;
        }
        if fixed_layout_records(element, &roles, vertex_count, body, &mut mesh) {
            if element.name == "face" {
                polygon_parts.resize(mesh.polygon_count(), 0);
            }
            continue;
        }
        for index in 0..element.count {
            let index = index as usize;
            let corners_before = mesh.face_indices.len();
            let mut position = [0.0; 3];
            let mut edge = [0u32; 2];
            let mut part = 0u32;
            let mut color = [1.0f64; 3];
            for (property, role) in element.properties.iter().zip(&roles) {
                let what = || format!("property `{}` of {} {index}", property.name, element.name);
                match property.kind {
                    Kind::Scalar(ty) => {
                        let value = body.value(ty, &what)?;
                        match *role {
                            Role::Coordinate(axis) => position[axis] = value,
                            Role::Scalar(k) => scalars[k].1.push(value),
                            Role::EdgeEnd(end) => {
                                edge[end] = vertex_ref(value, vertex_count, "edge", index, path)?
                            }
                            Role::Part => {
                                part = u32::try_from(value as i64)
                                    .ok()
                                    .filter(|&p| f64::from(p) == value && p < MAX_PARTS)
                                    .ok_or_else(|| {
                                        malformed(format!(
                                            "{} is {value}, not a part index below {MAX_PARTS}",
                                            what()
                                        ))
                                    })?;
                                parts_read = true;
                            }
                            Role::Color(channel) => {
                                let unit = if ty.is_integer() {
                                    value / 255.0
                                } else {
                                    value
                                };
                                if !unit.is_finite() {
                                    return Err(malformed(format!("{} is not finite", what())));
                                }
                                color[channel] = srgb_to_linear(unit.clamp(0.0, 1.0));
                            }
                            Role::Skip | Role::FaceIndices => {}
                        }
                    }
                    Kind::List { count, item } => {
                        let n = body.value(count, &what)?;
                        if n < 0.0 {
                            return Err(malformed(format!("{} has a negative length", what())));
                        }
                        let is_face = matches!(role, Role::FaceIndices);
                        list.clear();
                        for _ in 0..n as u64 {
                            let value = body.value(item, &what)?;
                            if is_face {
                                list.push(vertex_ref(value, vertex_count, "face", index, path)?);
                            }
                        }
                        if is_face {
                            if list.len() < 3 {
                                return Err(malformed(format!(
                                    "face {index} has {} vertices (at least 3 required)",
                                    list.len()
                                )));
                            }
                            mesh.push_polygon(&list);
                        }
                    }
                }
            }
            match element.name.as_str() {
                "vertex" => {
                    if !position.iter().all(|c| c.is_finite()) {
                        return Err(malformed(format!(
                            "vertex {index} has a non-finite coordinate"
                        )));
                    }
                    mesh.positions.push(position);
                    if has_color {
                        vertex_colors.push(color);
                    }
                }
                "edge" => {
                    mesh.lines.push(edge);
                    line_parts.push(part);
                }
                "face" => {
                    polygon_parts.push(part);
                    if has_color {
                        // Corners of faces without a colour are white.
                        colors_read = true;
                        face_colors.resize(corners_before, [1.0; 3]);
                        face_colors.resize(mesh.face_indices.len(), color);
                    }
                }
                _ => {}
            }
        }
    }
    if parts_read {
        let count = polygon_parts
            .iter()
            .chain(&line_parts)
            .max()
            .map_or(0, |&p| p as usize + 1);
        let mut names: Vec<String> = (0..count)
            .map(|k| {
                header
                    .part_names
                    .iter()
                    .find(|(i, _)| *i == k as u64)
                    .map_or_else(|| format!("part_{k}"), |(_, n)| sanitize_name(n, "part"))
            })
            .collect();
        crate::geom::material::dedupe_names(&mut names);
        mesh.parts = names;
        mesh.polygon_parts = polygon_parts;
        mesh.line_parts = line_parts;
    }
    if colors_read {
        face_colors.resize(mesh.face_indices.len(), [1.0; 3]);
        mesh.corner_colors = face_colors;
    } else if !vertex_colors.is_empty() {
        mesh.corner_colors = mesh
            .face_indices
            .iter()
            .map(|&v| vertex_colors[v as usize])
            .collect();
    }
    for (name, values) in &scalars {
        if let Some(vertex) = values.iter().position(|v| !v.is_finite()) {
            return Err(malformed(format!(
                "vertex {vertex} has a non-finite `{name}` value"
            )));
        }
    }
    scalars.sort_by(|a, b| a.0.cmp(&b.0));
    mesh.vertex_scalars = scalars;
    Ok(mesh)
}

/// The fast path for the layouts nearly every binary PLY has: vertices
/// whose properties are scalars of which only x, y and z are read, and
/// faces that are only a vertex list. Their records are decoded straight
/// from the bytes (fixed offsets for vertices), instead of one dynamic
/// call per value. Returns `false`, with nothing read or kept, for any
/// other layout and for any record the general path must judge (a
/// non-finite coordinate, a bad index, a short list, a truncated file),
/// so that errors read exactly as before.
fn fixed_layout_records(
    element: &Element,
    roles: &[Role],
    vertex_count: u64,
    body: &mut dyn Body,
    mesh: &mut IndexedMesh,
) -> bool {
    let Some((bytes, offset, big_endian)) = body.binary() else {
        return false;
    };
    let Ok(count) = usize::try_from(element.count) else {
        return false;
    };
    match element.name.as_str() {
        "vertex" => {
            let mut stride = 0;
            let mut axes = [(0usize, Scalar::F32); 3];
            for (property, role) in element.properties.iter().zip(roles) {
                let Kind::Scalar(ty) = property.kind else {
                    return false;
                };
                match *role {
                    Role::Coordinate(axis) => axes[axis] = (stride, ty),
                    Role::Skip => {}
                    _ => return false,
                }
                stride += ty.size();
            }
            let Some(block) = count
                .checked_mul(stride)
                .and_then(|len| bytes.get(*offset..offset.checked_add(len)?))
            else {
                return false;
            };
            let kept = mesh.positions.len();
            mesh.positions.reserve(count);
            for record in block.chunks_exact(stride) {
                let p = axes.map(|(at, ty)| ty.decode(&record[at..], big_endian));
                if !p.iter().all(|c| c.is_finite()) {
                    mesh.positions.truncate(kept);
                    return false;
                }
                mesh.positions.push(p);
            }
            *offset += block.len();
            true
        }
        "face" => {
            let [Property {
                kind:
                    Kind::List {
                        count: length,
                        item,
                    },
                ..
            }] = element.properties.as_slice()
            else {
                return false;
            };
            if !matches!(roles, [Role::FaceIndices]) || !item.is_integer() {
                return false;
            }
            let (length, item) = (*length, *item);
            let kept = (mesh.face_indices.len(), mesh.face_starts.len());
            let undo = |mesh: &mut IndexedMesh| {
                mesh.face_indices.truncate(kept.0);
                mesh.face_starts.truncate(kept.1);
                false
            };
            let mut at = *offset;
            let mut list: Vec<u32> = Vec::new();
            for _ in 0..count {
                let Some(raw) = bytes.get(at..at + length.size()) else {
                    return undo(mesh);
                };
                let n = length.decode(raw, big_endian);
                at += length.size();
                // Negative, short and NaN lengths are the general path's errors.
                if n.is_nan() || n < 3.0 {
                    return undo(mesh);
                }
                let n = n as usize;
                let Some(items) = n
                    .checked_mul(item.size())
                    .and_then(|len| bytes.get(at..at.checked_add(len)?))
                else {
                    return undo(mesh);
                };
                list.clear();
                for raw in items.chunks_exact(item.size()) {
                    let v = item.decode(raw, big_endian);
                    if !(v >= 0.0 && v < vertex_count as f64) {
                        return undo(mesh);
                    }
                    list.push(v as u32);
                }
                at += items.len();
                mesh.push_polygon(&list);
            }
            *offset = at;
            true
        }
        _ => false,
    }
}

fn valid_scalar_name(name: &str) -> bool {
    !name.is_empty()
        && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_')
        && !["x", "y", "z"].iter().any(|r| name.eq_ignore_ascii_case(r))
}

/// Checks a vertex reference read as `f64` against the declared vertex count.
fn vertex_ref(
    value: f64,
    count: u64,
    element: &'static str,
    index: usize,
    path: &Path,
) -> Result<u32, IoError> {
    if value >= 0.0 && value < count as f64 && value.fract() == 0.0 {
        return Ok(value as u32);
    }
    Err(IoError::BadIndex {
        path: path.to_path_buf(),
        line: None,
        element,
        index,
        vertex: value as i64,
        count: count as usize,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_colours_become_corner_colours() {
        let text = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
element face 1\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n3 0 1 2\n";
        let m = decode(text, Path::new("c.ply")).unwrap();
        assert!(m.vertex_scalars.is_empty(), "colours are not scalars");
        assert_eq!(
            m.corner_colors,
            vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        );
    }
    use crate::io::test_meshes;

    fn p() -> &'static Path {
        Path::new("mesh.ply")
    }

    #[test]
    fn ascii_layout() {
        let mesh = test_meshes::cube_with_wire();
        let text = String::from_utf8(encode(&mesh, Encoding::Ascii).unwrap()).unwrap();
        let expected_header = "ply\nformat ascii 1.0\ncomment graftal\nelement vertex 9\n\
                               property double x\nproperty double y\nproperty double z\n\
                               property double radius\nelement face 6\n\
                               property list uchar int vertex_indices\nelement edge 1\n\
                               property int vertex1\nproperty int vertex2\nend_header\n";
        assert!(text.starts_with(expected_header), "{text}");
        let body: Vec<&str> = text[expected_header.len()..].lines().collect();
        assert_eq!(body[0], "0 0 0 0.1");
        assert_eq!(body[8], "2 2 2 0.5");
        assert_eq!(body[9], "4 0 2 3 1");
        assert_eq!(body[15], "7 8");
        assert_eq!(body.len(), 16);
    }

    #[test]
    fn round_trips_both_encodings() {
        for mesh in [test_meshes::cube_with_wire(), test_meshes::awkward()] {
            for encoding in [Encoding::Ascii, Encoding::BinaryLittleEndian] {
                let bytes = encode(&mesh, encoding).unwrap();
                assert_eq!(bytes, encode(&mesh, encoding).unwrap(), "deterministic");
                let back = decode(&bytes, p()).unwrap();
                let mut expected = mesh.clone();
                for pos in &mut expected.positions {
                    *pos = pos.map(|c| if c == 0.0 { 0.0 } else { c });
                }
                assert_eq!(back, expected, "{encoding:?}");
            }
        }
    }

    #[test]
    fn wide_polygons_use_uint_counts() {
        let mut m = IndexedMesh::new();
        let n = 300u32;
        for i in 0..n {
            let a = std::f64::consts::TAU * f64::from(i) / f64::from(n);
            m.positions.push([a.cos(), a.sin(), 0.0]);
        }
        m.push_polygon(&(0..n).collect::<Vec<_>>());
        for encoding in [Encoding::Ascii, Encoding::BinaryLittleEndian] {
            let bytes = encode(&m, encoding).unwrap();
            let text = String::from_utf8_lossy(&bytes);
            assert!(text.contains("property list uint int vertex_indices"));
            assert!(!text.contains("element edge"));
            assert_eq!(decode(&bytes, p()).unwrap(), m);
        }
    }

    #[test]
    fn reads_foreign_layouts() {
        // Big endian, float coordinates, an extra element, uchar color, ushort list, int8 items.
        let mut bytes = b"ply\r\nformat binary_big_endian 1.0\r\ncomment hi\r\n\
                          element vertex 3\r\nproperty float x\r\nproperty float y\r\n\
                          property float z\r\nproperty uchar red\r\n\
                          element material 1\r\nproperty list uchar float stuff\r\n\
                          element face 1\r\nproperty uchar flags\r\n\
                          property list ushort char vertex_index\r\nend_header\r\n"
            .to_vec();
        for (i, v) in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.5]]
            .iter()
            .enumerate()
        {
            for c in v {
                bytes.extend_from_slice(&c.to_be_bytes());
            }
            bytes.push(10 * i as u8);
        }
        bytes.extend_from_slice(&[2, 0, 0, 0, 0, 0, 0, 0, 0]);
        bytes.push(7);
        bytes.extend_from_slice(&3u16.to_be_bytes());
        bytes.extend_from_slice(&[0, 1, 2]);
        let m = decode(&bytes, p()).unwrap();
        assert_eq!(
            m.positions,
            vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.5]]
        );
        assert_eq!(m.polygon(0), &[0, 1, 2]);
        assert_eq!(
            m.vertex_scalars,
            vec![("red".to_string(), vec![0.0, 10.0, 20.0])]
        );
    }

    #[test]
    fn errors() {
        let cases: [(&[u8], &str); 9] = [
            (b"", "mesh.ply: line 1: header has no `end_header` line"),
            (b"plx\n", "mesh.ply: line 1: not a PLY file (first line must be `ply`)"),
            (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nend_header\n0\n",
             "mesh.ply: vertex element has no `y` property"),
            (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nproperty double y\nproperty double z\nend_header\n0 0\n",
             "mesh.ply: line 8: file ends before property `z` of vertex 0"),
            (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nproperty double y\nproperty double z\nend_header\n0 0 q\n",
             "mesh.ply: line 8: invalid property `z` of vertex 0 `q`"),
            (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nproperty double y\nproperty double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 0 4\n",
             "mesh.ply: face 0 refers to vertex 4 but only 1 exist"),
            (b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty double x\nproperty double y\nproperty double z\nend_header\n\0\0\0\0\0\0\0\0\0\0",
             "mesh.ply: binary PLY truncated at byte 128 (expected 134)"),
            (b"ply\nformat ascii 2.0\nend_header\n", "mesh.ply: line 2: only PLY version 1.0 is supported"),
            (b"ply\nformat ascii 1.0\nproperty float x\nend_header\n", "mesh.ply: line 3: `property` before any `element`"),
        ];
        for (bytes, expected) in cases {
            assert_eq!(decode(bytes, p()).unwrap_err().to_string(), expected);
        }
    }

    #[test]
    fn hostile_headers_do_not_allocate_or_loop() {
        // Huge counts: allocation is capped and reading stops at the end of the data.
        let text = b"ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\n\
                     property float x\nproperty float y\nproperty float z\nend_header\n";
        assert!(decode(text, p()).is_err());
        let text = b"ply\nformat binary_little_endian 1.0\nelement nothing 18446744073709551615\n\
                     element vertex 0\nproperty float x\nproperty float y\nproperty float z\n\
                     end_header\n";
        assert_eq!(decode(text, p()).unwrap(), IndexedMesh::new());
        let text = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n\
                     property float y\nproperty float z\nelement face 1\n\
                     property list uint int vertex_indices\nend_header\n\
                     \0\0\0\0\0\0\0\0\0\0\0\0\xff\xff\xff\xff";
        assert!(decode(text, p()).is_err());
    }

    #[test]
    fn the_fixed_layout_fast_path_reads_as_the_general_path() {
        // Triangles, a quad and a pentagon over coordinates that need every
        // bit of a double: the binary file takes the fast path, its ASCII
        // twin the general one.
        let mut mesh = IndexedMesh::new();
        let mut state = 3u64;
        for _ in 0..40 {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
            let c = |k: u32| ((state >> k) & 0xffff) as f64 / 3.0 - 1e4;
            mesh.positions.push([c(1), c(17), c(33)]);
        }
        for k in 0..10u32 {
            mesh.push_polygon(&[k, k + 1, k + 2]);
        }
        mesh.push_polygon(&[20, 21, 22, 23]);
        mesh.push_polygon(&[30, 31, 32, 33, 39]);
        let binary = decode(&encode(&mesh, Encoding::BinaryLittleEndian).unwrap(), p()).unwrap();
        let ascii = decode(&encode(&mesh, Encoding::Ascii).unwrap(), p()).unwrap();
        assert_eq!(binary, ascii);
        assert_eq!(binary.positions, mesh.positions);
        assert_eq!(binary.polygon_count(), 12);

        // Big endian, float coordinates, a skipped property between them,
        // uint list lengths and ushort items.
        let mut bytes = b"ply\nformat binary_big_endian 1.0\nelement vertex 4\n\
                          property float x\nproperty float y\nproperty list uchar int skip\n\
                          property float z\nelement face 1\n\
                          property list uint ushort vertex_indices\nend_header\n"
            .to_vec();
        for v in [
            [0.0f32, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.25],
        ] {
            bytes.extend_from_slice(&v[0].to_be_bytes());
            bytes.extend_from_slice(&v[1].to_be_bytes());
            bytes.push(0);
            bytes.extend_from_slice(&v[2].to_be_bytes());
        }
        bytes.extend_from_slice(&4u32.to_be_bytes());
        for i in [0u16, 1, 2, 3] {
            bytes.extend_from_slice(&i.to_be_bytes());
        }
        let m = decode(&bytes, p()).unwrap();
        assert_eq!(m.positions[3], [0.0, 1.0, 0.25]);
        assert_eq!(m.polygon(0), &[0, 1, 2, 3]);

        // What the fast path leaves to the general one reads as before:
        // a bad index, a short face, a non-finite coordinate.
        let plain = encode(&mesh, Encoding::BinaryLittleEndian).unwrap();
        let body = plain
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap()
            + 11;
        let faces = body + 40 * 24;
        let mut bad_index = plain.clone();
        bad_index[faces + 1..faces + 5].copy_from_slice(&99i32.to_le_bytes());
        let message = decode(&bad_index, p()).unwrap_err().to_string();
        assert!(message.contains("99"), "{message}");
        let mut short = plain.clone();
        short[faces] = 2;
        let message = decode(&short, p()).unwrap_err().to_string();
        assert!(message.contains("face 0 has 2 vertices"), "{message}");
        let mut not_finite = plain.clone();
        not_finite[body + 24..body + 32].copy_from_slice(&f64::NAN.to_le_bytes());
        let message = decode(&not_finite, p()).unwrap_err().to_string();
        assert!(
            message.contains("vertex 1 has a non-finite coordinate"),
            "{message}"
        );
    }

    #[test]
    fn truncation_and_garbage_never_panic() {
        let mesh = test_meshes::awkward();
        for encoding in [Encoding::Ascii, Encoding::BinaryLittleEndian] {
            let bytes = encode(&mesh, encoding).unwrap();
            for cut in 0..bytes.len() {
                let _ = decode(&bytes[..cut], p());
            }
            let mut state = 5u64;
            for _ in 0..300 {
                let mut copy = bytes.clone();
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
                let at = (state >> 33) as usize % copy.len();
                copy[at] = (state >> 20) as u8;
                let _ = decode(&copy, p());
            }
        }
    }
}
