//! glTF 2.0, as `.gltf` (JSON with the buffer embedded as a base64 `data:` URI) and `.glb`.
//!
//! # Writing
//!
//! One mesh, one node, one scene; `asset.generator = "graftal"`, no material (default material).
//! glTF is +Y up (spec §3.4) and graftal's kernel Z-up: positions are written as
//! (x, z, −y), and read back as (x, −z, y), so a round trip is exact and a
//! model stands upright in every viewer.
//!
//! * Surface primitive (mode TRIANGLES, only if there are polygons): flat shaded. Each polygon's
//!   vertices are duplicated and carry the polygon's unit Newell normal (`(0, 0, 1)` for
//!   degenerate polygons), renormalized in `f32`; the polygon is split with
//!   [`crate::geom::polygon::triangulate`].
//! * Wire primitive (mode LINES, only if there are lines): its own vertices, the ones the lines
//!   use, numbered in first-use order.
//! * Attributes: `POSITION` (f32, `min`/`max` from the written `f32` values), `NORMAL` (surface
//!   only), and one f32 SCALAR `_NAME` per vertex scalar (name upper-cased, e.g. `_RADIUS`).
//! * Indices: u16 when the primitive has at most 65535 vertices, else u32.
//! * Every attribute and index array has its own 4-byte-aligned bufferView with its target set.
//! * An empty mesh gives a scene without nodes, and no mesh, node or buffer.
//!
//! The document is built as a [`gltf::json::Root`] and serialized with
//! `gltf::json::serialize::to_vec`. `gltf-json` can only express `_NAME` attribute semantics with
//! its `extras` cargo feature, so the `_NAME` entries are spliced into each primitive's
//! `"attributes":{` object of the serialized JSON (the document has no other such key).
//!
//! # Reading
//!
//! The JSON is parsed with `serde_json`, `_NAME` attributes are taken out (so reading works
//! whether or not `gltf-json` has the `extras` feature), and the rest is deserialized into a
//! [`gltf::json::Root`]. All lookups are bounds-checked here rather than through
//! `gltf::Document`, whose accessors assume a validated file and panic otherwise.
//!
//! The default scene (else the first scene, else every root node) is traversed with node
//! transforms applied (in `f64`). Primitives of mode TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN
//! become triangles; LINES, LINE_STRIP and LINE_LOOP become lines; POINTS are ignored.
//! Bitwise-equal transformed positions are merged (first-appearance numbering), so flat-shaded
//! files come back connected. Float SCALAR `_NAME` attributes become vertex scalars named in
//! lower case (a merged vertex takes the first value seen; vertices without one get 0).
//! Buffers come from the GLB binary chunk, base64 `data:` URIs, or files relative to the
//! `.gltf` file's directory. Sparse and non-float position accessors are not supported.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;

use ::gltf::json::{self, validation::Checked, validation::USize64, Index};
use glam::DVec3;

use super::IoError;
use crate::geom::indexed::{IndexedMesh, PolygonTriangulator, VertexMerger};

const DATA_URI_PREFIX: &str = "data:application/octet-stream;base64,";

/// Encodes `mesh` as a `.gltf` JSON document with an embedded base64 buffer.
pub fn encode_gltf(mesh: &IndexedMesh) -> Result<Vec<u8>, IoError> {
    let (json, _) = build(mesh, true)?;
    Ok(json)
}

/// Encodes `mesh` as binary glTF (`.glb`).
pub fn encode_glb(mesh: &IndexedMesh) -> Result<Vec<u8>, IoError> {
    let (json, bin) = build(mesh, false)?;
    let glb = ::gltf::binary::Glb {
        header: ::gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            // Recomputed by `to_vec`.
            length: 0,
        },
        json: Cow::Owned(json),
        bin: (!bin.is_empty()).then_some(Cow::Borrowed(bytemuck::cast_slice(&bin))),
    };
    glb.to_vec().map_err(|e| IoError::InvalidMesh {
        message: format!("GLB container: {e}"),
    })
}

fn to_f32(p: [f64; 3]) -> [f32; 3] {
    // Range checked by the caller; -0 is normalized so equal geometry gives equal bytes.
    p.map(|c| if c == 0.0 { 0.0 } else { c as f32 })
}

/// `f32` copy of a unit vector, renormalized in `f32` so its length is 1 to f32 precision.
fn unit_f32(v: DVec3) -> [f32; 3] {
    let c = v.to_array().map(|x| x as f32);
    let len = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
    c.map(|x| {
        let x = x / len;
        if x == 0.0 {
            0.0
        } else {
            x
        }
    })
}

/// Where one primitive's arrays live in the binary buffer (word offsets), and its accessors.
struct Plan {
    position_accessor: Index<json::Accessor>,
    position: usize,
    normal: Option<usize>,
    scalars: Vec<usize>,
    indices: usize,
    wide_indices: bool,
}

/// The binary buffer as little-endian 32-bit words (4-byte alignment for free), filled in place.
struct Words<'a>(&'a mut [u32]);

impl Words<'_> {
    fn vec3(&mut self, at: usize, v: [f32; 3]) {
        self.0[at..at + 3].copy_from_slice(&v.map(f32::to_bits));
    }

    fn index(&mut self, plan: &Plan, k: usize, value: u32) {
        if plan.wide_indices {
            self.0[plan.indices + k] = value;
        } else {
            // Two u16 per word, the first in the low half (little-endian byte order).
            let word = &mut self.0[plan.indices + k / 2];
            *word |= value << (16 * (k % 2));
        }
    }
}

/// Document under construction: JSON root, buffer size in words, and the custom attributes to
/// splice into each primitive.
struct Builder {
    root: json::Root,
    words: usize,
    custom: Vec<Vec<(String, u32)>>,
}

impl Builder {
    /// Reserves a bufferView + accessor of `count` elements; returns the accessor and the word
    /// offset of its data.
    fn accessor(
        &mut self,
        count: usize,
        component: json::accessor::ComponentType,
        type_: json::accessor::Type,
        target: json::buffer::Target,
    ) -> (Index<json::Accessor>, usize) {
        use json::accessor::{ComponentType, Type};
        let component_size = match component {
            ComponentType::U16 => 2,
            _ => 4,
        };
        let dims = match type_ {
            Type::Vec3 => 3,
            _ => 1,
        };
        let byte_length = count * dims * component_size;
        let start = self.words;
        self.words += byte_length.div_ceil(4);
        let view = self.root.push(json::buffer::View {
            buffer: Index::new(0),
            byte_length: USize64(byte_length as u64),
            byte_offset: (start > 0).then_some(USize64(4 * start as u64)),
            byte_stride: None,
            name: None,
            target: Some(Checked::Valid(target)),
            extensions: Default::default(),
            extras: Default::default(),
        });
        let accessor = self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64(count as u64),
            component_type: Checked::Valid(json::accessor::GenericComponentType(component)),
            extensions: Default::default(),
            extras: Default::default(),
            type_: Checked::Valid(type_),
            min: None,
            max: None,
            name: None,
            normalized: false,
            sparse: None,
        });
        (accessor, start)
    }

    /// Declares a primitive of `vertices` vertices and `indices` indices.
    fn primitive(
        &mut self,
        vertices: usize,
        indices: usize,
        normals: bool,
        names: &[&str],
        mode: json::mesh::Mode,
    ) -> (json::mesh::Primitive, Plan) {
        use json::accessor::{ComponentType, Type};
        use json::buffer::Target::{ArrayBuffer, ElementArrayBuffer};
        use json::mesh::Semantic;
        let mut attributes = BTreeMap::new();
        let (position_accessor, position) =
            self.accessor(vertices, ComponentType::F32, Type::Vec3, ArrayBuffer);
        attributes.insert(Checked::Valid(Semantic::Positions), position_accessor);
        let normal = normals.then(|| {
            let (accessor, start) =
                self.accessor(vertices, ComponentType::F32, Type::Vec3, ArrayBuffer);
            attributes.insert(Checked::Valid(Semantic::Normals), accessor);
            start
        });
        let mut custom = Vec::with_capacity(names.len());
        let mut scalars = Vec::with_capacity(names.len());
        for name in names {
            let (accessor, start) =
                self.accessor(vertices, ComponentType::F32, Type::Scalar, ArrayBuffer);
            custom.push((
                format!("_{}", name.to_ascii_uppercase()),
                accessor.value() as u32,
            ));
            scalars.push(start);
        }
        self.custom.push(custom);
        // u16 indices while the largest index (vertices - 1) stays below the restart value.
        let wide_indices = vertices > usize::from(u16::MAX);
        let component = if wide_indices {
            ComponentType::U32
        } else {
            ComponentType::U16
        };
        let (index_accessor, index_start) =
            self.accessor(indices, component, Type::Scalar, ElementArrayBuffer);
        let primitive = json::mesh::Primitive {
            attributes,
            extensions: Default::default(),
            extras: Default::default(),
            indices: Some(index_accessor),
            material: None,
            mode: Checked::Valid(mode),
            targets: None,
        };
        let plan = Plan {
            position_accessor,
            position,
            normal,
            scalars,
            indices: index_start,
            wide_indices,
        };
        (primitive, plan)
    }

    fn set_bounds(&mut self, accessor: Index<json::Accessor>, min: [f32; 3], max: [f32; 3]) {
        let to_value = |v: [f32; 3]| json::Value::from(v.map(f64::from).to_vec());
        let accessor = &mut self.root.accessors[accessor.value()];
        accessor.min = Some(to_value(min));
        accessor.max = Some(to_value(max));
    }
}

/// Running min/max of written positions.
struct Bounds {
    min: [f32; 3],
    max: [f32; 3],
}

impl Bounds {
    fn new() -> Self {
        Bounds {
            min: [f32::INFINITY; 3],
            max: [f32::NEG_INFINITY; 3],
        }
    }

    fn add(&mut self, p: [f32; 3]) {
        for ((lo, hi), c) in self.min.iter_mut().zip(&mut self.max).zip(p) {
            *lo = lo.min(c);
            *hi = hi.max(c);
        }
    }
}

/// Flat-shaded surface: every polygon's corners duplicated with the polygon normal.
fn fill_surface(
    words: &mut Words,
    plan: &Plan,
    mesh: &IndexedMesh,
    scalars: &[(&str, &[f64])],
) -> Bounds {
    let mut bounds = Bounds::new();
    let mut tri = PolygonTriangulator::default();
    let normal_at = plan.normal.unwrap_or_default();
    let (mut v, mut k) = (0usize, 0usize);
    for poly in mesh.polygons() {
        let normal = unit_f32(tri.run(mesh, poly).unwrap_or(DVec3::Z));
        let base = v as u32;
        for &i in poly {
            let p = to_f32(mesh.positions[i as usize]);
            bounds.add(p);
            words.vec3(plan.position + 3 * v, p);
            words.vec3(normal_at + 3 * v, normal);
            for (start, (_, values)) in plan.scalars.iter().zip(scalars) {
                words.0[start + v] = (values[i as usize] as f32).to_bits();
            }
            v += 1;
        }
        for t in &tri.triangles {
            for &corner in t {
                words.index(plan, k, base + corner);
                k += 1;
            }
        }
    }
    bounds
}

/// Wire edges: the vertices the lines use, numbered in first-use order.
fn fill_wire(
    words: &mut Words,
    plan: &Plan,
    mesh: &IndexedMesh,
    scalars: &[(&str, &[f64])],
) -> Bounds {
    let mut bounds = Bounds::new();
    let mut remap = vec![u32::MAX; mesh.positions.len()];
    let mut next = 0u32;
    for (k, &v) in mesh.lines.iter().flatten().enumerate() {
        let slot = &mut remap[v as usize];
        if *slot == u32::MAX {
            *slot = next;
            let at = next as usize;
            let p = to_f32(mesh.positions[v as usize]);
            bounds.add(p);
            words.vec3(plan.position + 3 * at, p);
            for (start, (_, values)) in plan.scalars.iter().zip(scalars) {
                words.0[start + at] = (values[v as usize] as f32).to_bits();
            }
            next += 1;
        }
        words.index(plan, k, *slot);
    }
    bounds
}

/// Number of distinct vertices the lines use.
fn wire_vertex_count(mesh: &IndexedMesh) -> usize {
    let mut seen = vec![false; mesh.positions.len()];
    mesh.lines
        .iter()
        .flatten()
        .filter(|&&v| !std::mem::replace(&mut seen[v as usize], true))
        .count()
}

/// Builds the document: (JSON bytes, binary buffer as little-endian words). With `embed`, the
/// buffer is a data URI in the JSON and the returned buffer is empty.
fn build(mesh: &IndexedMesh, embed: bool) -> Result<(Vec<u8>, Vec<u32>), IoError> {
    use json::mesh::Mode;
    mesh.validate()?;
    // glTF is +Y up (spec §3.4): the kernel's Z-up model is turned so that
    // its height runs along +Y, exactly (a swap and a negation).
    let mut turned = mesh.clone();
    turned.z_up_to_y_up();
    let mesh = &turned;
    mesh.check_f32_range("glTF")?;
    let scalars = mesh.sorted_scalars();
    for (name, values) in &scalars {
        if let Some(vertex) = values.iter().position(|v| v.abs() > f64::from(f32::MAX)) {
            return Err(IoError::InvalidMesh {
                message: format!(
                    "vertex scalar {name:?} at vertex {vertex} ({:e}) does not fit an f32 for glTF",
                    values[vertex]
                ),
            });
        }
    }
    let names: Vec<&str> = scalars.iter().map(|(n, _)| *n).collect();
    let too_big = |what: &str| IoError::InvalidMesh {
        message: format!("{what} exceed glTF's u32 index range"),
    };

    let mut b = Builder {
        root: json::Root {
            asset: json::Asset {
                generator: Some("graftal".to_string()),
                ..Default::default()
            },
            ..Default::default()
        },
        words: 0,
        custom: Vec::new(),
    };
    let mut primitives = Vec::new();
    let mut surface = None;
    if mesh.polygon_count() > 0 {
        let vertices = mesh.face_indices.len();
        let indices = usize::try_from(mesh.triangle_count() * 3)
            .ok()
            .filter(|_| u32::try_from(vertices).is_ok())
            .ok_or_else(|| too_big("flat-shaded vertices"))?;
        let (primitive, plan) = b.primitive(vertices, indices, true, &names, Mode::Triangles);
        primitives.push(primitive);
        surface = Some(plan);
    }
    let mut wire = None;
    if !mesh.lines.is_empty() {
        let (primitive, plan) = b.primitive(
            wire_vertex_count(mesh),
            mesh.lines.len() * 2,
            false,
            &names,
            Mode::Lines,
        );
        primitives.push(primitive);
        wire = Some(plan);
    }

    // Zero-initialized (lazily mapped) words, filled in place: no intermediate arrays.
    let mut bin = vec![0u32; b.words];
    let mut words = Words(&mut bin);
    if let Some(plan) = &surface {
        let bounds = fill_surface(&mut words, plan, mesh, &scalars);
        b.set_bounds(plan.position_accessor, bounds.min, bounds.max);
    }
    if let Some(plan) = &wire {
        let bounds = fill_wire(&mut words, plan, mesh, &scalars);
        b.set_bounds(plan.position_accessor, bounds.min, bounds.max);
    }
    // The words hold little-endian data; make that true in memory on big-endian hosts too.
    for w in &mut bin {
        *w = w.to_le();
    }
    let bytes: &[u8] = bytemuck::cast_slice(&bin);

    let mut scene_nodes = Vec::new();
    if !primitives.is_empty() {
        let mesh_index = b.root.push(json::Mesh {
            extensions: Default::default(),
            extras: Default::default(),
            name: None,
            primitives,
            weights: None,
        });
        scene_nodes.push(b.root.push(json::Node {
            mesh: Some(mesh_index),
            ..Default::default()
        }));
    }
    let scene = b.root.push(json::Scene {
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        nodes: scene_nodes,
    });
    b.root.scene = Some(scene);
    if !bytes.is_empty() {
        b.root.push(json::Buffer {
            byte_length: USize64(bytes.len() as u64),
            name: None,
            // The base64 payload is spliced in after serialization (see below).
            uri: embed.then(|| DATA_URI_PREFIX.to_string()),
            extensions: Default::default(),
            extras: Default::default(),
        });
    }
    let json = json::serialize::to_vec(&b.root).map_err(|e| IoError::InvalidMesh {
        message: format!("glTF JSON serialization: {e}"),
    })?;
    let json = splice_custom_attributes(json, &b.custom)?;
    if embed && !bytes.is_empty() {
        // Encoding straight into the output avoids serde escaping a ~100 MB string.
        Ok((splice_base64(json, bytes)?, Vec::new()))
    } else {
        Ok((json, bin))
    }
}

/// Appends the base64 form of `bin` right after the (only) data URI prefix in `json`.
fn splice_base64(json: Vec<u8>, bin: &[u8]) -> Result<Vec<u8>, IoError> {
    let key = format!("\"uri\":\"{DATA_URI_PREFIX}");
    let Some(at) = json.windows(key.len()).position(|w| w == key.as_bytes()) else {
        return Err(IoError::InvalidMesh {
            message: "glTF JSON: buffer URI not found".into(),
        });
    };
    let split = at + key.len();
    let mut out = Vec::with_capacity(json.len() + bin.len().div_ceil(3) * 4);
    out.extend_from_slice(&json[..split]);
    base64_encode(bin, &mut out);
    out.extend_from_slice(&json[split..]);
    Ok(out)
}

/// Inserts `"_NAME":accessor,` entries at the start of each primitive's attributes object.
fn splice_custom_attributes(
    json: Vec<u8>,
    custom: &[Vec<(String, u32)>],
) -> Result<Vec<u8>, IoError> {
    const KEY: &[u8] = b"\"attributes\":{";
    if custom.iter().all(Vec::is_empty) {
        return Ok(json);
    }
    let mut out = Vec::with_capacity(json.len() + 32 * custom.len());
    let mut rest = &json[..];
    for attributes in custom {
        let Some(at) = rest.windows(KEY.len()).position(|w| w == KEY) else {
            return Err(IoError::InvalidMesh {
                message: "glTF JSON: primitive attributes not found".into(),
            });
        };
        out.extend_from_slice(&rest[..at + KEY.len()]);
        rest = &rest[at + KEY.len()..];
        for (name, accessor) in attributes {
            out.push(b'"');
            out.extend_from_slice(name.as_bytes());
            out.extend_from_slice(b"\":");
            super::push_u64(&mut out, u64::from(*accessor));
            out.push(b',');
        }
    }
    out.extend_from_slice(rest);
    Ok(out)
}

const BASE64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Standard base64 with padding, appended to `out`.
fn base64_encode(bytes: &[u8], out: &mut Vec<u8>) {
    let sextet = |n: u32, shift: u32| BASE64[(n >> shift) as usize & 63];
    out.reserve(bytes.len().div_ceil(3) * 4);
    let mut chunks = bytes.chunks_exact(3);
    for c in &mut chunks {
        let n = u32::from(c[0]) << 16 | u32::from(c[1]) << 8 | u32::from(c[2]);
        out.extend_from_slice(&[sextet(n, 18), sextet(n, 12), sextet(n, 6), sextet(n, 0)]);
    }
    match *chunks.remainder() {
        [a] => {
            let n = u32::from(a) << 16;
            out.extend_from_slice(&[sextet(n, 18), sextet(n, 12), b'=', b'=']);
        }
        [a, b] => {
            let n = u32::from(a) << 16 | u32::from(b) << 8;
            out.extend_from_slice(&[sextet(n, 18), sextet(n, 12), sextet(n, 6), b'=']);
        }
        _ => {}
    }
}

/// Decodes standard (or URL-safe) base64, ignoring whitespace; `None` if malformed.
fn base64_decode(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let mut acc = 0u32;
    let mut bits = 0;
    let mut padding = 0;
    for b in text.bytes() {
        let v = match b {
            b'A'..=b'Z' => b - b'A',
            b'a'..=b'z' => b - b'a' + 26,
            b'0'..=b'9' => b - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => {
                padding += 1;
                continue;
            }
            b' ' | b'\n' | b'\r' | b'\t' => continue,
            _ => return None,
        };
        if padding > 0 {
            return None;
        }
        acc = acc << 6 | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    (padding <= 2 && bits < 6).then_some(out)
}

/// Decodes `.gltf` JSON or `.glb` (detected by the `glTF` magic); `path` names the file in
/// errors. External buffer files are refused: see [`decode_with`].
pub fn decode(bytes: &[u8], path: &Path) -> Result<IndexedMesh, IoError> {
    decode_with(bytes, path, &mut super::no_external_files)
}

/// [`decode`] with `resolve` supplying external buffers (URIs relative to the file).
pub fn decode_with(
    bytes: &[u8],
    path: &Path,
    resolve: &mut super::Resolve,
) -> Result<IndexedMesh, IoError> {
    let malformed = |message: String| IoError::Malformed {
        path: path.to_path_buf(),
        message,
    };
    let (json_bytes, blob) = if bytes.starts_with(b"glTF") {
        split_glb(bytes, path)?
    } else {
        (bytes, None)
    };
    let mut value: json::Value = serde_json::from_slice(json_bytes)
        .map_err(|e| malformed(format!("invalid glTF JSON: {e}")))?;
    let custom = take_custom_attributes(&mut value);
    // glTF allows scenes without `nodes` (our empty files have one); gltf-json requires it.
    if let Some(scenes) = value.get_mut("scenes").and_then(|s| s.as_array_mut()) {
        for scene in scenes {
            if let Some(scene) = scene.as_object_mut() {
                scene
                    .entry("nodes")
                    .or_insert_with(|| json::Value::Array(Vec::new()));
            }
        }
    }
    let root: json::Root = serde_json::from_value(value)
        .map_err(|e| malformed(format!("invalid glTF document: {e}")))?;
    if !root.asset.version.starts_with("2.") {
        return Err(malformed(format!(
            "unsupported glTF version {:?} (expected 2.x)",
            root.asset.version
        )));
    }
    // Quantized attributes are read (positions; the rest is not used).
    const READ_EXTENSIONS: &[&str] = &["KHR_mesh_quantization"];
    if let Some(ext) = root
        .extensions_required
        .iter()
        .find(|e| !READ_EXTENSIONS.contains(&e.as_str()))
    {
        return Err(malformed(format!("requires unsupported extension {ext}")));
    }
    let buffers = load_buffers(&root, blob, path, resolve)?;
    Reader {
        root: &root,
        buffers: &buffers,
        custom: &custom,
        path,
    }
    .read()
}

/// Splits a GLB container into its JSON chunk and optional BIN chunk.
fn split_glb<'a>(bytes: &'a [u8], path: &Path) -> Result<(&'a [u8], Option<&'a [u8]>), IoError> {
    let truncated = |offset: usize, expected: u64| IoError::Truncated {
        path: path.to_path_buf(),
        what: "GLB",
        offset: offset as u64,
        expected,
    };
    let u32_at = |at: usize| {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let (Some(version), Some(length)) = (u32_at(4), u32_at(8)) else {
        return Err(truncated(bytes.len(), 12));
    };
    if version != 2 {
        return Err(IoError::Malformed {
            path: path.to_path_buf(),
            message: format!("unsupported GLB version {version} (expected 2)"),
        });
    }
    let length = length as usize;
    if length > bytes.len() {
        return Err(truncated(bytes.len(), length as u64));
    }
    let bytes = &bytes[..length];
    let mut at = 12;
    let mut json = None;
    let mut bin = None;
    while at < bytes.len() {
        let (Some(chunk_len), Some(kind)) = (u32_at(at), u32_at(at + 4)) else {
            return Err(truncated(bytes.len(), at as u64 + 8));
        };
        if at + 8 > bytes.len() {
            return Err(truncated(bytes.len(), at as u64 + 8));
        }
        let start = at + 8;
        let end = start as u64 + u64::from(chunk_len);
        if end > bytes.len() as u64 {
            return Err(truncated(bytes.len(), end));
        }
        let data = &bytes[start..end as usize];
        match &kind.to_le_bytes() {
            b"JSON" if json.is_none() => json = Some(data),
            b"BIN\0" if bin.is_none() && json.is_some() => bin = Some(data),
            _ => {}
        }
        at = end as usize;
    }
    let json = json.ok_or_else(|| IoError::Malformed {
        path: path.to_path_buf(),
        message: "GLB has no JSON chunk".into(),
    })?;
    Ok((json, bin))
}

/// Removes `_NAME` entries from every primitive's attributes, returning them per mesh and
/// primitive as (NAME without the underscore, accessor index).
#[allow(clippy::type_complexity)]
fn take_custom_attributes(value: &mut json::Value) -> Vec<Vec<Vec<(String, u64)>>> {
    let mut custom = Vec::new();
    let Some(meshes) = value.get_mut("meshes").and_then(|m| m.as_array_mut()) else {
        return custom;
    };
    for mesh in meshes {
        let mut per_mesh = Vec::new();
        if let Some(primitives) = mesh.get_mut("primitives").and_then(|p| p.as_array_mut()) {
            for primitive in primitives {
                let mut found = Vec::new();
                if let Some(attributes) = primitive
                    .get_mut("attributes")
                    .and_then(|a| a.as_object_mut())
                {
                    let keys: Vec<String> = attributes
                        .keys()
                        .filter(|k| k.starts_with('_'))
                        .cloned()
                        .collect();
                    for key in keys {
                        if let Some(index) = attributes.remove(&key).and_then(|v| v.as_u64()) {
                            found.push((key[1..].to_string(), index));
                        }
                    }
                }
                per_mesh.push(found);
            }
        }
        custom.push(per_mesh);
    }
    custom
}

fn load_buffers<'a>(
    root: &json::Root,
    blob: Option<&'a [u8]>,
    path: &Path,
    resolve: &mut super::Resolve,
) -> Result<Vec<Cow<'a, [u8]>>, IoError> {
    let malformed = |message: String| IoError::Malformed {
        path: path.to_path_buf(),
        message,
    };
    let mut buffers = Vec::with_capacity(root.buffers.len());
    for (i, buffer) in root.buffers.iter().enumerate() {
        let data: Cow<[u8]> =
            match buffer.uri.as_deref() {
                None => Cow::Borrowed(blob.ok_or_else(|| {
                    malformed(format!(
                        "buffer {i} has no URI and there is no GLB binary chunk"
                    ))
                })?),
                Some(uri) if uri.starts_with("data:") => {
                    let (meta, payload) = uri.split_once(',').unwrap_or((uri, ""));
                    if !meta.ends_with(";base64") {
                        return Err(malformed(format!(
                            "buffer {i}: only base64 data URIs are supported"
                        )));
                    }
                    Cow::Owned(base64_decode(payload).ok_or_else(|| {
                        malformed(format!("buffer {i}: invalid base64 in data URI"))
                    })?)
                }
                Some(uri) => {
                    if uri.contains("://") {
                        return Err(malformed(format!(
                        "buffer {i}: unsupported URI {uri:?} (only relative files and data URIs)"
                    )));
                    }
                    // At most byteLength bytes: a URI naming /dev/zero or a
                    // huge file costs no more than the buffer declares.
                    let file = percent_decode(uri);
                    Cow::Owned(resolve(&file, buffer.byte_length.0).map_err(|e| {
                        malformed(format!("buffer {i}: cannot read external file {file}: {e}"))
                    })?)
                }
            };
        let declared = buffer.byte_length.0;
        if (data.len() as u64) < declared {
            return Err(malformed(format!(
                "buffer {i} has {} bytes but declares byteLength {declared}",
                data.len()
            )));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// Decodes `%XX` escapes of a relative URI; leaves malformed escapes as they are.
fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            if let (Some(h), Some(l)) = (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Column-major 4x4 matrix.
type Mat4 = [f64; 16];

const IDENTITY: Mat4 = [
    1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
];

fn mul(a: &Mat4, b: &Mat4) -> Mat4 {
    let mut m = [0.0; 16];
    for c in 0..4 {
        for r in 0..4 {
            m[c * 4 + r] = (0..4).map(|k| a[k * 4 + r] * b[c * 4 + k]).sum();
        }
    }
    m
}

fn local_matrix(node: &json::Node) -> Mat4 {
    if let Some(m) = node.matrix {
        return m.map(f64::from);
    }
    let t = node.translation.unwrap_or([0.0; 3]).map(f64::from);
    let [x, y, z, w] = node
        .rotation
        .map_or([0.0, 0.0, 0.0, 1.0], |r| r.0)
        .map(f64::from);
    let s = node.scale.unwrap_or([1.0; 3]).map(f64::from);
    let r = [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ];
    let mut m = IDENTITY;
    for c in 0..3 {
        for row in 0..3 {
            m[c * 4 + row] = r[row][c] * s[c];
        }
        m[12 + c] = t[c];
    }
    m
}

fn transform(m: &Mat4, p: [f32; 3]) -> [f64; 3] {
    let p = p.map(f64::from);
    if *m == IDENTITY {
        return p;
    }
    [0, 1, 2].map(|r| m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r])
}

struct Reader<'a> {
    root: &'a json::Root,
    buffers: &'a [Cow<'a, [u8]>],
    custom: &'a [Vec<Vec<(String, u64)>>],
    path: &'a Path,
}

/// Vertex scalar columns of the mesh being read, with "has a value yet" flags.
struct Columns {
    names: Vec<String>,
    values: Vec<Vec<f64>>,
    set: Vec<Vec<bool>>,
}

impl Reader<'_> {
    fn malformed(&self, message: String) -> IoError {
        IoError::Malformed {
            path: self.path.to_path_buf(),
            message,
        }
    }

    fn read(&self) -> Result<IndexedMesh, IoError> {
        let instances = self.instances()?;
        // Scalar columns: valid `_NAME`s of the instanced meshes, lower-cased, sorted.
        let mut names: Vec<String> = instances
            .iter()
            .filter_map(|(mesh, _)| self.custom.get(*mesh))
            .flatten()
            .flatten()
            .map(|(name, _)| name.to_ascii_lowercase())
            .filter(|n| {
                !n.is_empty()
                    && n.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_')
                    && !matches!(n.as_str(), "x" | "y" | "z")
            })
            .collect();
        names.sort();
        names.dedup();
        let mut columns = Columns {
            values: vec![Vec::new(); names.len()],
            set: vec![Vec::new(); names.len()],
            names,
        };
        let mut merger = VertexMerger::default();
        let mut mesh = IndexedMesh::new();
        for (mesh_index, matrix) in &instances {
            let json_mesh = &self.root.meshes[*mesh_index];
            for (prim_index, primitive) in json_mesh.primitives.iter().enumerate() {
                self.primitive(
                    *mesh_index,
                    prim_index,
                    primitive,
                    matrix,
                    &mut merger,
                    &mut columns,
                    &mut mesh,
                )?;
            }
        }
        mesh.positions = merger.positions;
        mesh.vertex_scalars = columns.names.into_iter().zip(columns.values).collect();
        // glTF is +Y up (spec §3.4); graftal's kernel is Z-up.
        mesh.y_up_to_z_up();
        Ok(mesh)
    }

    /// (mesh index, world matrix) for every node with a mesh, in traversal order.
    fn instances(&self) -> Result<Vec<(usize, Mat4)>, IoError> {
        let root = self.root;
        let roots: Vec<usize> = match root
            .scene
            .map(|s| s.value())
            .or_else(|| (!root.scenes.is_empty()).then_some(0))
        {
            Some(s) => {
                let scene = root
                    .scenes
                    .get(s)
                    .ok_or_else(|| self.malformed(format!("default scene {s} does not exist")))?;
                scene.nodes.iter().map(Index::value).collect()
            }
            None => {
                let mut is_child = vec![false; root.nodes.len()];
                for node in &root.nodes {
                    for child in node.children.iter().flatten() {
                        if let Some(flag) = is_child.get_mut(child.value()) {
                            *flag = true;
                        }
                    }
                }
                (0..root.nodes.len()).filter(|&n| !is_child[n]).collect()
            }
        };
        let mut visited = vec![false; root.nodes.len()];
        let mut stack: Vec<(usize, Mat4)> =
            roots.into_iter().rev().map(|n| (n, IDENTITY)).collect();
        let mut instances = Vec::new();
        while let Some((n, parent)) = stack.pop() {
            let node = root
                .nodes
                .get(n)
                .ok_or_else(|| self.malformed(format!("node {n} does not exist")))?;
            // Each node is visited once, so cycles and shared children cannot loop.
            if std::mem::replace(&mut visited[n], true) {
                continue;
            }
            let world = mul(&parent, &local_matrix(node));
            if let Some(m) = node.mesh {
                if m.value() >= root.meshes.len() {
                    return Err(self.malformed(format!(
                        "node {n} refers to mesh {} which does not exist",
                        m.value()
                    )));
                }
                instances.push((m.value(), world));
            }
            for child in node.children.iter().flatten().rev() {
                stack.push((child.value(), world));
            }
        }
        Ok(instances)
    }

    #[allow(clippy::too_many_arguments)]
    fn primitive(
        &self,
        mesh_index: usize,
        prim_index: usize,
        primitive: &json::mesh::Primitive,
        matrix: &Mat4,
        merger: &mut VertexMerger,
        columns: &mut Columns,
        mesh: &mut IndexedMesh,
    ) -> Result<(), IoError> {
        use json::mesh::Mode;
        let context = format!("mesh {mesh_index} primitive {prim_index}");
        let mode = match primitive.mode {
            Checked::Valid(mode) => mode,
            Checked::Invalid => return Err(self.malformed(format!("{context}: invalid mode"))),
        };
        if mode == Mode::Points {
            return Ok(());
        }
        let Some(position) = primitive
            .attributes
            .get(&Checked::Valid(json::mesh::Semantic::Positions))
        else {
            return Ok(());
        };
        let positions = self.read_quantized(position.value(), 3, &context, "POSITION")?;
        let count = positions.len() / 3;
        // Scalars of this primitive: (column, values).
        let mut scalars = Vec::new();
        let custom = self
            .custom
            .get(mesh_index)
            .and_then(|m| m.get(prim_index))
            .map_or(&[][..], Vec::as_slice);
        for (name, accessor) in custom {
            let lower = name.to_ascii_lowercase();
            let Ok(column) = columns.names.binary_search(&lower) else {
                continue;
            };
            let Ok(accessor) = usize::try_from(*accessor) else {
                continue;
            };
            // Only float SCALAR attributes are vertex scalars; others are skipped.
            let Some(acc) = self.root.accessors.get(accessor) else {
                return Err(self.malformed(format!(
                    "{context}: attribute _{name} refers to accessor {accessor} which does not exist"
                )));
            };
            let is_float_scalar = matches!(acc.type_, Checked::Valid(json::accessor::Type::Scalar))
                && matches!(
                    acc.component_type,
                    Checked::Valid(json::accessor::GenericComponentType(
                        json::accessor::ComponentType::F32
                    ))
                );
            if !is_float_scalar {
                continue;
            }
            let values = self.read_f32(accessor, 1, &context, name)?;
            if values.len() != count {
                return Err(self.malformed(format!(
                    "{context}: attribute _{name} has {} values for {count} vertices",
                    values.len()
                )));
            }
            scalars.push((column, values));
        }
        let mut indices: Vec<u32> = match primitive.indices {
            Some(acc) => self.read_indices(acc.value(), &context)?,
            None => (0..count as u32).collect(),
        };
        // Drop trailing indices that form no complete element, so they add no vertices.
        let n = indices.len();
        let used = match mode {
            Mode::Triangles => n - n % 3,
            Mode::Lines => n - n % 2,
            Mode::TriangleStrip | Mode::TriangleFan if n < 3 => 0,
            Mode::LineStrip | Mode::LineLoop if n < 2 => 0,
            _ => n,
        };
        indices.truncate(used);

        let mut remap = vec![u32::MAX; count];
        let mut resolved = Vec::with_capacity(indices.len());
        for (k, &v) in indices.iter().enumerate() {
            let Some(slot) = remap.get_mut(v as usize) else {
                return Err(self.malformed(format!(
                    "{context}: index {k} refers to vertex {v} but only {count} exist"
                )));
            };
            if *slot == u32::MAX {
                let i = v as usize;
                let p = transform(
                    matrix,
                    [positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]],
                );
                if !p.iter().all(|c| c.is_finite()) {
                    return Err(
                        self.malformed(format!("{context}: vertex {v} has a non-finite position"))
                    );
                }
                let index = merger
                    .index(p)
                    .ok_or_else(|| self.malformed("more than u32::MAX distinct vertices".into()))?;
                if index as usize == columns.values.first().map_or(usize::MAX, Vec::len) {
                    for (values, set) in columns.values.iter_mut().zip(&mut columns.set) {
                        values.push(0.0);
                        set.push(false);
                    }
                }
                for (column, values) in &scalars {
                    let value = f64::from(values[i]);
                    if !value.is_finite() {
                        return Err(self.malformed(format!(
                            "{context}: attribute _{} is not finite at vertex {v}",
                            columns.names[*column].to_ascii_uppercase()
                        )));
                    }
                    let set = &mut columns.set[*column][index as usize];
                    if !*set {
                        columns.values[*column][index as usize] = value;
                        *set = true;
                    }
                }
                *slot = index;
            }
            resolved.push(*slot);
        }

        let r = &resolved;
        match mode {
            Mode::Triangles => {
                for t in r.chunks_exact(3) {
                    mesh.push_polygon(t);
                }
            }
            Mode::TriangleStrip => {
                for i in 0..r.len().saturating_sub(2) {
                    let t = if i % 2 == 0 {
                        [r[i], r[i + 1], r[i + 2]]
                    } else {
                        [r[i + 1], r[i], r[i + 2]]
                    };
                    mesh.push_polygon(&t);
                }
            }
            Mode::TriangleFan => {
                for i in 0..r.len().saturating_sub(2) {
                    mesh.push_polygon(&[r[i + 1], r[i + 2], r[0]]);
                }
            }
            Mode::Lines => mesh.lines.extend(r.chunks_exact(2).map(|l| [l[0], l[1]])),
            Mode::LineStrip => mesh.lines.extend(r.windows(2).map(|l| [l[0], l[1]])),
            Mode::LineLoop => {
                mesh.lines.extend(r.windows(2).map(|l| [l[0], l[1]]));
                if r.len() > 2 {
                    mesh.lines.push([r[r.len() - 1], r[0]]);
                }
            }
            Mode::Points => {}
        }
        Ok(())
    }

    /// Bounds-checked raw view of an accessor: (bytes from its first element, stride, count,
    /// component type, components per element).
    fn accessor_bytes(
        &self,
        index: usize,
        context: &str,
        what: &str,
    ) -> Result<(&[u8], usize, usize, json::accessor::ComponentType, usize), IoError> {
        use json::accessor::{ComponentType, Type};
        let err = |message: String| {
            self.malformed(format!("{context}: {what} accessor {index}: {message}"))
        };
        let acc = self
            .root
            .accessors
            .get(index)
            .ok_or_else(|| err("does not exist".into()))?;
        if acc.sparse.is_some() {
            return Err(err("sparse accessors are not supported".into()));
        }
        let Checked::Valid(json::accessor::GenericComponentType(component)) = acc.component_type
        else {
            return Err(err("invalid componentType".into()));
        };
        let dims = match acc.type_ {
            Checked::Valid(Type::Scalar) => 1,
            Checked::Valid(Type::Vec2) => 2,
            Checked::Valid(Type::Vec3) => 3,
            Checked::Valid(Type::Vec4) => 4,
            _ => return Err(err("unsupported type".into())),
        };
        let size = match component {
            ComponentType::I8 | ComponentType::U8 => 1,
            ComponentType::I16 | ComponentType::U16 => 2,
            ComponentType::U32 | ComponentType::F32 => 4,
        };
        let count = usize::try_from(acc.count.0).map_err(|_| err("count too large".into()))?;
        if count == 0 {
            return Ok((&[], size * dims, 0, component, dims));
        }
        let view_index = acc
            .buffer_view
            .ok_or_else(|| err("has no bufferView".into()))?
            .value();
        let view = self
            .root
            .buffer_views
            .get(view_index)
            .ok_or_else(|| err(format!("bufferView {view_index} does not exist")))?;
        let buffer = self
            .buffers
            .get(view.buffer.value())
            .ok_or_else(|| err(format!("buffer {} does not exist", view.buffer.value())))?;
        let element = size * dims;
        let stride = view.byte_stride.map_or(element, |s| s.0);
        if stride < element {
            return Err(err(format!(
                "byteStride {stride} is smaller than an element"
            )));
        }
        let view_start = view.byte_offset.map_or(0, |o| o.0);
        let view_end = view_start.checked_add(view.byte_length.0);
        let start = view_start.checked_add(acc.byte_offset.map_or(0, |o| o.0));
        let needed = (stride as u64)
            .checked_mul(count as u64 - 1)
            .and_then(|n| n.checked_add(element as u64));
        let (Some(view_end), Some(start), Some(needed)) = (view_end, start, needed) else {
            return Err(err("offsets overflow".into()));
        };
        if view_end > buffer.len() as u64 || start.checked_add(needed).is_none_or(|e| e > view_end)
        {
            return Err(err(format!(
                "{count} elements do not fit in bufferView {view_index} ({} bytes from byte {view_start}) / buffer of {} bytes",
                view.byte_length.0,
                buffer.len()
            )));
        }
        let start = start as usize;
        Ok((
            &buffer[start..start + needed as usize],
            stride,
            count,
            component,
            dims,
        ))
    }

    /// Reads a float accessor with `dims` components per element, flattened.
    fn read_f32(
        &self,
        index: usize,
        dims: usize,
        context: &str,
        what: &str,
    ) -> Result<Vec<f32>, IoError> {
        self.read_floats(index, dims, context, what, false)
    }

    /// [`Self::read_f32`] that also takes the integer encodings of
    /// `KHR_mesh_quantization` (how gltfpack and most optimizers ship
    /// positions): 8- and 16-bit integers, normalized (`c / 127`,
    /// `c / 255`, … clamped at −1, glTF §3.11) or not (their value).
    fn read_quantized(
        &self,
        index: usize,
        dims: usize,
        context: &str,
        what: &str,
    ) -> Result<Vec<f32>, IoError> {
        self.read_floats(index, dims, context, what, true)
    }

    fn read_floats(
        &self,
        index: usize,
        dims: usize,
        context: &str,
        what: &str,
        quantized: bool,
    ) -> Result<Vec<f32>, IoError> {
        use json::accessor::ComponentType;
        let (bytes, stride, count, component, actual) =
            self.accessor_bytes(index, context, what)?;
        let integer = matches!(
            component,
            ComponentType::I8 | ComponentType::U8 | ComponentType::I16 | ComponentType::U16
        );
        if actual != dims || !(component == ComponentType::F32 || quantized && integer) {
            let kinds = if quantized {
                "FLOAT, or (KHR_mesh_quantization) BYTE, UNSIGNED_BYTE, SHORT or UNSIGNED_SHORT,"
            } else {
                "FLOAT"
            };
            return Err(self.malformed(format!(
                "{context}: {what} accessor {index} must be {kinds} with {dims} component(s)"
            )));
        }
        let normalized = self.root.accessors[index].normalized;
        let read: fn(&[u8]) -> f32 = match (component, normalized) {
            (ComponentType::F32, _) => |b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            (ComponentType::I8, false) => |b| f32::from(b[0] as i8),
            (ComponentType::U8, false) => |b| f32::from(b[0]),
            (ComponentType::I16, false) => |b| f32::from(i16::from_le_bytes([b[0], b[1]])),
            (ComponentType::U16, false) => |b| f32::from(u16::from_le_bytes([b[0], b[1]])),
            (ComponentType::I8, true) => |b| (f32::from(b[0] as i8) / 127.0).max(-1.0),
            (ComponentType::U8, true) => |b| f32::from(b[0]) / 255.0,
            (ComponentType::I16, true) => {
                |b| (f32::from(i16::from_le_bytes([b[0], b[1]])) / 32767.0).max(-1.0)
            }
            (ComponentType::U16, true) => |b| f32::from(u16::from_le_bytes([b[0], b[1]])) / 65535.0,
            (ComponentType::U32, _) => unreachable!("refused above"),
        };
        let size = match component {
            ComponentType::I8 | ComponentType::U8 => 1,
            ComponentType::I16 | ComponentType::U16 => 2,
            _ => 4,
        };
        let mut out = Vec::with_capacity(count * dims);
        for e in 0..count {
            for c in 0..dims {
                out.push(read(&bytes[e * stride + size * c..]));
            }
        }
        Ok(out)
    }

    fn read_indices(&self, index: usize, context: &str) -> Result<Vec<u32>, IoError> {
        use json::accessor::ComponentType;
        let (bytes, stride, count, component, dims) =
            self.accessor_bytes(index, context, "indices")?;
        if dims != 1 {
            return Err(self.malformed(format!(
                "{context}: indices accessor {index} must be SCALAR"
            )));
        }
        let read: fn(&[u8]) -> u32 = match component {
            ComponentType::U8 => |b| u32::from(b[0]),
            ComponentType::U16 => |b| u32::from(u16::from_le_bytes([b[0], b[1]])),
            ComponentType::U32 => |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            _ => {
                return Err(self.malformed(format!(
                    "{context}: indices accessor {index} must be unsigned integers"
                )))
            }
        };
        Ok((0..count).map(|e| read(&bytes[e * stride..])).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_meshes;
    use ::gltf::mesh::Mode;

    fn p() -> &'static Path {
        Path::new("mesh.glb")
    }

    fn parse_json(bytes: &[u8]) -> json::Value {
        let json = if bytes.starts_with(b"glTF") {
            split_glb(bytes, p()).unwrap().0
        } else {
            bytes
        };
        serde_json::from_slice(json).unwrap()
    }

    #[test]
    fn base64_round_trip() {
        for len in 0..40usize {
            let data: Vec<u8> = (0..len).map(|i| (i * 37 + 11) as u8).collect();
            let mut s = Vec::new();
            base64_encode(&data, &mut s);
            assert_eq!(s.len(), len.div_ceil(3) * 4);
            assert_eq!(
                base64_decode(std::str::from_utf8(&s).unwrap()).unwrap(),
                data
            );
        }
        let mut s = Vec::new();
        base64_encode(b"graftal", &mut s);
        assert_eq!(s, b"Z3JhZnRhbA==");
        assert!(base64_decode("Z3=JhZ").is_none());
        assert!(base64_decode("Z3J*").is_none());
    }

    /// Reads a GLB with the gltf crate (no validation: without its `extras` feature gltf-json
    /// flags `_RADIUS` as an invalid semantic) and checks accessors.
    #[test]
    fn glb_reads_back_with_the_gltf_crate() {
        let mesh = test_meshes::cube_with_wire();
        let bytes = encode_glb(&mesh).unwrap();
        assert_eq!(bytes.len() % 4, 0);
        let g = ::gltf::Gltf::from_slice_without_validation(&bytes).unwrap();
        let blob = g.blob.clone().unwrap();
        assert_eq!(blob.len() % 4, 0);
        let doc = &g.document;
        assert_eq!(doc.meshes().count(), 1);
        assert_eq!(doc.nodes().count(), 1);
        assert_eq!(doc.default_scene().unwrap().nodes().count(), 1);
        let prims: Vec<_> = doc.meshes().next().unwrap().primitives().collect();
        assert_eq!(prims.len(), 2);
        assert_eq!(prims[0].mode(), Mode::Triangles);
        assert_eq!(prims[1].mode(), Mode::Lines);

        let reader = prims[0].reader(|_| Some(&blob[..]));
        let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
        assert_eq!(positions.len(), 24, "6 quads x 4 duplicated vertices");
        let normals: Vec<[f32; 3]> = reader.read_normals().unwrap().collect();
        for n in &normals {
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            assert!((len - 1.0).abs() < 1e-6, "{n:?}");
        }
        // The cube's bottom face, (0, 0, −1) in the Z-up kernel, is −Y in glTF.
        assert_eq!(normals[0], [0.0, -1.0, 0.0]);
        let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
        assert_eq!(indices.len(), 36);
        assert!(indices.iter().all(|&i| i < 24));
        // Triangles face along their normals.
        for t in indices.chunks(3) {
            let [a, b, c] =
                [0, 1, 2].map(|k| DVec3::from_array(positions[t[k] as usize].map(f64::from)));
            let n = DVec3::from_array(normals[t[0] as usize].map(f64::from));
            assert!((b - a).cross(c - a).dot(n) > 0.0);
        }
        let pos_acc = prims[0].get(&::gltf::Semantic::Positions).unwrap();
        // The unit cube [0, 1]³ turned Y-up: y ∈ [0, 1] from z, z ∈ [−1, 0] from −y.
        assert_eq!(pos_acc.min().unwrap(), serde_json::json!([0.0, 0.0, -1.0]));
        assert_eq!(pos_acc.max().unwrap(), serde_json::json!([1.0, 1.0, 0.0]));
        assert_eq!(
            prims[0].indices().unwrap().data_type(),
            ::gltf::accessor::DataType::U16
        );

        let wire = prims[1].reader(|_| Some(&blob[..]));
        let wire_pos: Vec<[f32; 3]> = wire.read_positions().unwrap().collect();
        assert_eq!(
            wire_pos,
            vec![[1.0, 1.0, -1.0], [2.0, 2.0, -2.0]],
            "turned Y-up"
        );
        let wire_idx: Vec<u32> = wire.read_indices().unwrap().into_u32().collect();
        assert_eq!(wire_idx, vec![0, 1]);
        let wire_acc = prims[1].get(&::gltf::Semantic::Positions).unwrap();
        assert_eq!(wire_acc.min().unwrap(), serde_json::json!([1.0, 1.0, -2.0]));
        assert_eq!(wire_acc.max().unwrap(), serde_json::json!([2.0, 2.0, -1.0]));

        // Buffer views: 4-byte aligned, targets set, inside the buffer.
        for view in doc.views() {
            assert_eq!(view.offset() % 4, 0);
            assert!(view.target().is_some());
            assert!(view.offset() + view.length() <= blob.len());
        }

        // The custom attribute is in the JSON on both primitives, as f32 scalars.
        let v = parse_json(&bytes);
        for k in 0..2 {
            let attrs = &v["meshes"][0]["primitives"][k]["attributes"];
            let acc = attrs["_RADIUS"].as_u64().unwrap() as usize;
            assert_eq!(v["accessors"][acc]["type"], "SCALAR");
            assert_eq!(v["accessors"][acc]["componentType"], 5126);
        }
        assert_eq!(v["asset"]["generator"], "graftal");
        assert_eq!(v["asset"]["version"], "2.0");
    }

    #[test]
    fn round_trip_glb_and_gltf() {
        let mesh = test_meshes::cube_with_wire();
        for bytes in [encode_glb(&mesh).unwrap(), encode_gltf(&mesh).unwrap()] {
            assert_eq!(
                bytes,
                if bytes.starts_with(b"glTF") {
                    encode_glb(&mesh).unwrap()
                } else {
                    encode_gltf(&mesh).unwrap()
                }
            );
            let back = decode(&bytes, p()).unwrap();
            assert_eq!(back.positions.len(), 9, "flat-shaded copies merge back");
            assert_eq!(back.polygon_count(), 12);
            assert_eq!(back.lines.len(), 1);
            let radius = back.vertex_scalar("radius").unwrap();
            for (v, p) in back.positions.iter().enumerate() {
                let original = mesh
                    .positions
                    .iter()
                    .position(|q| (0..3).all(|k| (p[k] - q[k]).abs() < 1e-6))
                    .unwrap();
                let expected = mesh.vertex_scalars[0].1[original];
                assert!((radius[v] - expected).abs() < 1e-6);
            }
            let [a, b] = back.lines[0];
            assert_eq!(back.positions[a as usize], [1.0, 1.0, 1.0]);
            assert_eq!(back.positions[b as usize], [2.0, 2.0, 2.0]);
            // Closed surface: every undirected edge twice.
            let mut counts = BTreeMap::new();
            for poly in back.polygons() {
                for k in 0..3 {
                    let (a, b) = (poly[k], poly[(k + 1) % 3]);
                    *counts.entry((a.min(b), a.max(b))).or_insert(0) += 1;
                }
            }
            assert!(counts.values().all(|&c| c == 2));
        }
    }

    #[test]
    fn gltf_embeds_a_data_uri() {
        let bytes = encode_gltf(&test_meshes::cube_with_wire()).unwrap();
        let v = parse_json(&bytes);
        let uri = v["buffers"][0]["uri"].as_str().unwrap();
        assert!(uri.starts_with(DATA_URI_PREFIX));
        let data = base64_decode(&uri[DATA_URI_PREFIX.len()..]).unwrap();
        assert_eq!(
            data.len() as u64,
            v["buffers"][0]["byteLength"].as_u64().unwrap()
        );
    }

    #[test]
    fn empty_mesh_writes_an_empty_scene() {
        for bytes in [
            encode_glb(&IndexedMesh::new()).unwrap(),
            encode_gltf(&IndexedMesh::default()).unwrap(),
        ] {
            let v = parse_json(&bytes);
            assert_eq!(v["scenes"], serde_json::json!([{}]));
            assert_eq!(v["scene"], 0);
            assert!(v.get("meshes").is_none() && v.get("nodes").is_none());
            assert!(v.get("buffers").is_none());
            assert_eq!(decode(&bytes, p()).unwrap(), IndexedMesh::new());
        }
        // Lines only: one LINES primitive, no surface.
        let mut m = IndexedMesh::new();
        m.positions = vec![[0.0; 3], [1.0, 0.0, 0.0]];
        m.lines.push([1, 0]);
        let bytes = encode_glb(&m).unwrap();
        let v = parse_json(&bytes);
        assert_eq!(v["meshes"][0]["primitives"].as_array().unwrap().len(), 1);
        assert_eq!(v["meshes"][0]["primitives"][0]["mode"], 1);
        let back = decode(&bytes, p()).unwrap();
        assert_eq!(back.lines, vec![[0, 1]]);
        assert_eq!(back.positions, vec![[1.0, 0.0, 0.0], [0.0; 3]]);
    }

    #[test]
    fn awkward_mesh_has_unit_normals_and_no_nan() {
        let mesh = test_meshes::awkward();
        let bytes = encode_glb(&mesh).unwrap();
        let g = ::gltf::Gltf::from_slice_without_validation(&bytes).unwrap();
        let blob = g.blob.clone().unwrap();
        let prim = g
            .document
            .meshes()
            .next()
            .unwrap()
            .primitives()
            .next()
            .unwrap();
        let reader = prim.reader(|_| Some(&blob[..]));
        let normals: Vec<[f32; 3]> = reader.read_normals().unwrap().collect();
        assert_eq!(normals.len(), mesh.face_indices.len());
        for n in &normals {
            assert!(n.iter().all(|c| c.is_finite()));
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            assert!((len - 1.0).abs() < 1e-6);
        }
        // The collinear polygon (4th) gets (0, 0, 1).
        let start = mesh.face_starts[3] as usize;
        assert_eq!(normals[start], [0.0, 0.0, 1.0]);
        let back = decode(&bytes, p()).unwrap();
        assert_eq!(back.polygon_count() as u64, mesh.triangle_count());
        assert_eq!(back.lines.len(), 2);
        assert_eq!(
            back.vertex_scalars
                .iter()
                .map(|(n, _)| n.as_str())
                .collect::<Vec<_>>(),
            vec!["age", "radius"]
        );
    }

    #[test]
    fn large_meshes_switch_to_u32_indices() {
        let mut m = IndexedMesh::new();
        let n = 70_000u32;
        for i in 0..n {
            m.positions.push([f64::from(i), f64::from(i % 7), 0.0]);
        }
        for i in 0..n / 3 {
            m.push_polygon(&[3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let bytes = encode_glb(&m).unwrap();
        let v = parse_json(&bytes);
        let idx = v["meshes"][0]["primitives"][0]["indices"].as_u64().unwrap() as usize;
        assert_eq!(v["accessors"][idx]["componentType"], 5125);
        let back = decode(&bytes, p()).unwrap();
        assert_eq!(back.polygon_count(), m.polygon_count());
    }

    #[test]
    fn out_of_range_values_are_rejected() {
        let mut m = test_meshes::cube_with_wire();
        m.positions[0][0] = -1e39;
        assert!(matches!(
            encode_glb(&m),
            Err(IoError::OutOfRange { vertex: 0, .. })
        ));
        let mut m = test_meshes::cube_with_wire();
        m.vertex_scalars[0].1[2] = 1e40;
        let e = encode_gltf(&m).unwrap_err().to_string();
        assert!(e.contains("\"radius\" at vertex 2"), "{e}");
    }

    /// A tiny hand-written glTF around 4 positions (a unit square in z = 0).
    fn square_gltf(mode: u32, extra_root: serde_json::Value) -> Vec<u8> {
        let pos: [f32; 12] = [0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0.];
        let mut uri = DATA_URI_PREFIX.as_bytes().to_vec();
        base64_encode(bytemuck::cast_slice(&pos), &mut uri);
        let uri = String::from_utf8(uri).unwrap();
        let mut v = serde_json::json!({
            "asset": {"version": "2.0"},
            "buffers": [{"byteLength": 48, "uri": uri}],
            "bufferViews": [{"buffer": 0, "byteLength": 48}],
            "accessors": [{"bufferView": 0, "count": 4, "componentType": 5126, "type": "VEC3",
                           "min": [0, 0, 0], "max": [1, 1, 0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": mode}]}],
            "nodes": [{"mesh": 0}],
        });
        for (k, value) in extra_root.as_object().unwrap() {
            v[k] = value.clone();
        }
        serde_json::to_vec(&v).unwrap()
    }

    #[test]
    fn quantized_positions_are_read() {
        // KHR_mesh_quantization as gltfpack writes it: normalized SHORT
        // positions with a stride of 8, scaled back by the node.
        let shorts: [i16; 12] = [0, 0, 0, 0, 32767, 0, 0, 0, 0, 32767, 0, 0];
        let bytes: &[u8] = bytemuck::cast_slice(&shorts);
        let mut uri = DATA_URI_PREFIX.as_bytes().to_vec();
        base64_encode(bytes, &mut uri);
        let doc = |component: u32, normalized: bool, required: &[&str]| {
            serde_json::to_vec(&serde_json::json!({
                "asset": {"version": "2.0"},
                "extensionsUsed": ["KHR_mesh_quantization"],
                "extensionsRequired": required,
                "buffers": [{"byteLength": 24, "uri": String::from_utf8(uri.clone()).unwrap()}],
                "bufferViews": [{"buffer": 0, "byteLength": 24, "byteStride": 8}],
                "accessors": [{"bufferView": 0, "count": 3, "componentType": component,
                               "normalized": normalized, "type": "VEC3"}],
                "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
                "nodes": [{"mesh": 0, "scale": [2, 2, 2]}],
            }))
            .unwrap()
        };
        let m = decode(&doc(5122, true, &["KHR_mesh_quantization"]), p()).unwrap();
        // glTF (2, 0, 0) and (0, 2, 0) are the kernel's (2, 0, 0) and (0, 0, 2).
        assert_eq!(
            m.positions,
            [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 2.0]]
        );
        // Not normalized: the integers themselves.
        let m = decode(&doc(5122, false, &[]), p()).unwrap();
        assert_eq!(m.positions[1], [65534.0, 0.0, 0.0]);
        // Normalized UNSIGNED_SHORT: 32767 / 65535.
        let m = decode(&doc(5123, true, &[]), p()).unwrap();
        assert_eq!(m.positions[1][0], 2.0 * f64::from(32767.0f32 / 65535.0));
        // Other required extensions are still refused.
        let e = decode(&doc(5122, true, &["KHR_draco_mesh_compression"]), p()).unwrap_err();
        assert!(e.to_string().contains("KHR_draco_mesh_compression"), "{e}");
    }

    #[test]
    fn strips_fans_and_loops() {
        let read = |mode| decode(&square_gltf(mode, serde_json::json!({})), p()).unwrap();
        let strip = read(5);
        assert_eq!(
            strip.polygons().collect::<Vec<_>>(),
            vec![&[0, 1, 2][..], &[2, 1, 3]]
        );
        let fan = read(6);
        assert_eq!(
            fan.polygons().collect::<Vec<_>>(),
            vec![&[1, 2, 0][..], &[2, 3, 0]]
        );
        assert_eq!(read(4).polygon_count(), 1);
        assert_eq!(read(1).lines, vec![[0, 1], [2, 3]]);
        assert_eq!(read(3).lines, vec![[0, 1], [1, 2], [2, 3]]);
        assert_eq!(read(2).lines, vec![[0, 1], [1, 2], [2, 3], [3, 0]]);
        let points = read(0);
        assert_eq!(
            points.polygon_count() + points.lines.len() + points.positions.len(),
            0
        );
    }

    #[test]
    fn node_transforms_are_applied() {
        // Root node translates by (10, 0, 0) and has a child scaled by 2 holding the mesh;
        // a second root mesh node has a matrix; scene lists both roots.
        let bytes = square_gltf(
            4,
            serde_json::json!({
                "nodes": [
                    {"translation": [10, 0, 0], "children": [1]},
                    {"scale": [2, 2, 2], "mesh": 0},
                    {"matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,5,1], "mesh": 0},
                    {"mesh": 0}
                ],
                "scenes": [{"nodes": [0, 2]}],
                "scene": 0
            }),
        );
        let m = decode(&bytes, p()).unwrap();
        assert_eq!(m.polygon_count(), 2, "node 3 is not in the scene");
        // glTF's (x, y, z) is the kernel's (x, −z, y).
        assert_eq!(
            m.positions[..3],
            [[10.0, 0.0, 0.0], [12.0, 0.0, 0.0], [10.0, 0.0, 2.0]]
        );
        assert_eq!(
            m.positions[3..],
            [[0.0, -5.0, 0.0], [1.0, -5.0, 0.0], [0.0, -5.0, 1.0]]
        );
        // 90 degrees about z: (1, 0, 0) -> (0, 1, 0).
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let bytes = square_gltf(
            4,
            serde_json::json!({"nodes": [{"rotation": [0, 0, h, h], "mesh": 0}]}),
        );
        let m = decode(&bytes, p()).unwrap();
        assert!((m.positions[1][0]).abs() < 1e-6 && (m.positions[1][2] - 1.0).abs() < 1e-6);
        // Cycles in the node graph do not loop forever.
        let bytes = square_gltf(
            4,
            serde_json::json!({"nodes": [{"children": [1], "mesh": 0}, {"children": [0]}],
                               "scenes": [{"nodes": [0]}]}),
        );
        assert_eq!(decode(&bytes, p()).unwrap().polygon_count(), 1);
    }

    #[test]
    fn external_buffers_come_through_the_resolver() {
        let mesh = test_meshes::cube_with_wire();
        let glb = encode_glb(&mesh).unwrap();
        let (json_bytes, bin) = split_glb(&glb, p()).unwrap();
        let bin = bin.unwrap().to_vec();
        let mut v: serde_json::Value = serde_json::from_slice(json_bytes).unwrap();
        v["buffers"][0]["uri"] = "my%20data.bin".into();
        let gltf = serde_json::to_vec(&v).unwrap();
        let path = Path::new("model.gltf");
        // The resolver is given the percent-decoded URI and the byteLength.
        let read = |stored: Option<&[u8]>| {
            decode_with(&gltf, path, &mut |uri: &str, max: u64| {
                assert_eq!(uri, "my data.bin");
                let data = stored.ok_or("no such file")?;
                Ok(data[..data.len().min(max as usize)].to_vec())
            })
        };
        let e = read(None).unwrap_err().to_string();
        assert!(
            e.contains("buffer 0: cannot read external file my data.bin: no such file"),
            "{e}"
        );
        // Without a resolver, external files are refused.
        let e = decode(&gltf, path).unwrap_err().to_string();
        assert!(e.contains("not available"), "{e}");
        assert_eq!(read(Some(&bin)).unwrap().polygon_count(), 12);
        // A longer file is cut at byteLength; a shorter one is reported.
        let mut longer = bin.clone();
        longer.extend([0u8; 64]);
        assert_eq!(read(Some(&longer)).unwrap().polygon_count(), 12);
        let e = read(Some(&[0u8; 10])).unwrap_err().to_string();
        assert!(
            e.contains("buffer 0 has 10 bytes but declares byteLength"),
            "{e}"
        );
    }

    #[test]
    fn errors_are_specific() {
        let mesh = test_meshes::cube_with_wire();
        let glb = encode_glb(&mesh).unwrap();
        let e = decode(&glb[..glb.len() - 8], p()).unwrap_err().to_string();
        assert_eq!(
            e,
            format!(
                "mesh.glb: GLB truncated at byte {} (expected {})",
                glb.len() - 8,
                glb.len()
            )
        );
        let e = decode(b"glTF\x01\0\0\0", p()).unwrap_err().to_string();
        assert_eq!(e, "mesh.glb: GLB truncated at byte 8 (expected 12)");
        let e = decode(b"{\"asset\":", p()).unwrap_err().to_string();
        assert!(e.starts_with("mesh.glb: invalid glTF JSON"), "{e}");
        let e = decode(br#"{"asset":{"version":"1.0"}}"#, p())
            .unwrap_err()
            .to_string();
        assert!(e.contains("unsupported glTF version"), "{e}");
        let e = decode(
            br#"{"asset":{"version":"2.0"},"extensionsRequired":["KHR_draco_mesh_compression"]}"#,
            p(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.ends_with("requires unsupported extension KHR_draco_mesh_compression"));
        let bad_uri = br#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":4,"uri":"data:application/octet-stream;base64,@@@@"}]}"#;
        let e = decode(bad_uri, p()).unwrap_err().to_string();
        assert!(e.ends_with("buffer 0: invalid base64 in data URI"), "{e}");
        // POSITION accessor out of range must not panic (gltf-json's validator would).
        let mut v = parse_json(&encode_gltf(&mesh).unwrap());
        v["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 99.into();
        let json = serde_json::to_vec(&v).unwrap();
        let e = decode(&json, p()).unwrap_err().to_string();
        assert!(e.contains("POSITION accessor 99: does not exist"), "{e}");
        // Index out of range.
        let bytes = square_gltf(4, serde_json::json!({}));
        let mut v: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
        let mut uri = DATA_URI_PREFIX.as_bytes().to_vec();
        let mut data: Vec<u8> =
            bytemuck::cast_slice(&[0f32, 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0.]).to_vec();
        data.extend_from_slice(bytemuck::cast_slice(&[0u16, 1, 7, 0]));
        base64_encode(&data, &mut uri);
        let uri = String::from_utf8(uri).unwrap();
        v["buffers"][0] = serde_json::json!({"byteLength": 56, "uri": uri});
        v["bufferViews"]
            .as_array_mut()
            .unwrap()
            .push(serde_json::json!({"buffer": 0, "byteOffset": 48, "byteLength": 6}));
        v["accessors"].as_array_mut().unwrap().push(
            serde_json::json!({"bufferView": 1, "count": 3, "componentType": 5123, "type": "SCALAR"}),
        );
        v["meshes"][0]["primitives"][0]["indices"] = 1.into();
        let e = decode(&serde_json::to_vec(&v).unwrap(), p())
            .unwrap_err()
            .to_string();
        assert!(
            e.ends_with("mesh 0 primitive 0: index 2 refers to vertex 7 but only 4 exist"),
            "{e}"
        );
        // Accessor larger than its view.
        v["accessors"][1]["count"] = 4.into();
        let e = decode(&serde_json::to_vec(&v).unwrap(), p())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("indices accessor 1: 4 elements do not fit in bufferView 1"),
            "{e}"
        );
    }

    #[test]
    fn garbage_and_truncation_never_panic() {
        let mesh = test_meshes::awkward();
        let glb = encode_glb(&mesh).unwrap();
        let gltf = encode_gltf(&mesh).unwrap();
        for cut in 0..glb.len() {
            let _ = decode(&glb[..cut], p());
        }
        for cut in (0..gltf.len()).step_by(7) {
            let _ = decode(&gltf[..cut], p());
        }
        let mut state = 3u64;
        for _ in 0..2000 {
            let mut copy = glb.clone();
            for _ in 0..3 {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let at = (state >> 33) as usize % copy.len();
                copy[at] = (state >> 13) as u8;
            }
            let _ = decode(&copy, p());
        }
        // Numbers in the JSON replaced with hostile values.
        let v = parse_json(&glb);
        let text = serde_json::to_string(&v).unwrap();
        for hostile in [
            "0",
            "1",
            "4294967295",
            "18446744073709551615",
            "-1",
            "1e300",
            "65535",
        ] {
            for (i, _) in text.match_indices(|c: char| c.is_ascii_digit()).step_by(3) {
                let end = text[i..]
                    .find(|c: char| !c.is_ascii_digit() && c != '.')
                    .map_or(text.len(), |e| i + e);
                let patched = format!("{}{}{}", &text[..i], hostile, &text[end..]);
                let _ = decode(patched.as_bytes(), Path::new("x.gltf"));
            }
        }
    }

    /// Writes sample files for the Khronos validator into `$GRAFTAL_GLTF_SAMPLES`:
    /// `GRAFTAL_GLTF_SAMPLES=/tmp/s cargo test --lib gltf_validator_samples -- --ignored`,
    /// then `NODE_PATH=DIR/node_modules node tests/validate_gltf.mjs --strict /tmp/s/*`.
    #[test]
    #[ignore]
    fn gltf_validator_samples() {
        let dir = std::path::PathBuf::from(
            std::env::var("GRAFTAL_GLTF_SAMPLES").expect("set GRAFTAL_GLTF_SAMPLES"),
        );
        std::fs::create_dir_all(&dir).unwrap();
        let mut lines_only = IndexedMesh::new();
        lines_only.positions = vec![[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]];
        lines_only.lines = vec![[0, 1], [1, 2]];
        let mut big = IndexedMesh::new();
        for i in 0..70_000u32 {
            big.positions.push([
                f64::from(i % 300),
                f64::from(i / 300),
                f64::from(i % 7) * 0.1,
            ]);
        }
        for i in 0..69_000u32 {
            if i % 300 < 299 {
                big.push_polygon(&[i, i + 1, i + 301, i + 300]);
            }
        }
        let samples = [
            ("cube_wire_radius", test_meshes::cube_with_wire()),
            ("empty", IndexedMesh::new()),
            ("awkward", test_meshes::awkward()),
            ("lines_only", lines_only),
            ("big_u32_indices", big),
        ];
        for (name, mesh) in samples {
            std::fs::write(dir.join(format!("{name}.glb")), encode_glb(&mesh).unwrap()).unwrap();
            std::fs::write(
                dir.join(format!("{name}.gltf")),
                encode_gltf(&mesh).unwrap(),
            )
            .unwrap();
        }
    }

    /// Writes a 1M-triangle GLB (500k quads) and reports the time; run with
    /// `cargo test --release --lib glb_million_triangles -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn glb_million_triangles_timing() {
        let side = 708; // 707 x 707 quads = 499_849 quads ~ 1M triangles
        let mut m = IndexedMesh::new();
        for j in 0..side {
            for i in 0..side {
                let (x, y) = (i as f64 * 0.01, j as f64 * 0.01);
                m.positions
                    .push([x, y, (x * 3.0).sin() * (y * 2.0).cos() * 0.1]);
            }
        }
        for j in 0..side - 1 {
            for i in 0..side - 1 {
                let v = (j * side + i) as u32;
                let s = side as u32;
                m.push_polygon(&[v, v + 1, v + s + 1, v + s]);
            }
        }
        m.lines.push([0, 1]);
        let radius = (0..m.positions.len())
            .map(|i| (i % 13) as f64 * 0.01)
            .collect();
        m.vertex_scalars.push(("radius".to_string(), radius));
        let tris = m.triangle_count();
        let mut best = f64::INFINITY;
        let mut size = 0;
        for _ in 0..5 {
            let t = std::time::Instant::now();
            let bytes = encode_glb(&m).unwrap();
            best = best.min(t.elapsed().as_secs_f64());
            size = bytes.len();
        }
        let t = std::time::Instant::now();
        let gltf_len = encode_gltf(&m).unwrap().len();
        let gltf_time = t.elapsed().as_secs_f64();
        println!(
            "GLB: {tris} triangles, {size} bytes, best of 5: {:.1} ms; .gltf (base64): {gltf_len} bytes, {:.1} ms",
            best * 1e3,
            gltf_time * 1e3
        );
    }
}
