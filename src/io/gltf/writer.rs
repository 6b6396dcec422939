//! Writing `.gltf` and `.glb` (see the module overview in `gltf`).

use super::*;

pub(crate) const DATA_URI_PREFIX: &str = "data:application/octet-stream;base64,";

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

pub(super) fn to_f32(p: [f64; 3]) -> [f32; 3] {
    // Range checked by the caller; -0 is normalized so equal geometry gives equal bytes.
    p.map(|c| if c == 0.0 { 0.0 } else { c as f32 })
}

/// `f32` copy of a unit vector, renormalized in `f32` so its length is 1 to f32 precision.
pub(super) fn unit_f32(v: DVec3) -> [f32; 3] {
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
pub(super) struct Plan {
    position_accessor: Index<json::Accessor>,
    position: usize,
    normal: Option<usize>,
    scalars: Vec<usize>,
    indices: usize,
    wide_indices: bool,
}

/// The binary buffer as little-endian 32-bit words (4-byte alignment for free), filled in place.
pub(super) struct Words<'a>(&'a mut [u32]);

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
pub(super) struct Builder {
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
pub(super) struct Bounds {
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
pub(super) fn fill_surface(
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
pub(super) fn fill_wire(
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
pub(super) fn wire_vertex_count(mesh: &IndexedMesh) -> usize {
    let mut seen = vec![false; mesh.positions.len()];
    mesh.lines
        .iter()
        .flatten()
        .filter(|&&v| !std::mem::replace(&mut seen[v as usize], true))
        .count()
}

/// Builds the document: (JSON bytes, binary buffer as little-endian words). With `embed`, the
/// buffer is a data URI in the JSON and the returned buffer is empty.
pub(super) fn build(mesh: &IndexedMesh, embed: bool) -> Result<(Vec<u8>, Vec<u32>), IoError> {
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
pub(super) fn splice_base64(json: Vec<u8>, bin: &[u8]) -> Result<Vec<u8>, IoError> {
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
pub(super) fn splice_custom_attributes(
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
            crate::io::push_u64(&mut out, u64::from(*accessor));
            out.push(b',');
        }
    }
    out.extend_from_slice(rest);
    Ok(out)
}
