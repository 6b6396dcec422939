//! Writing `.gltf` and `.glb` (see the module overview in `gltf`).

use super::*;
use crate::geom::material::{AlphaMode, Material};

pub(crate) const DATA_URI_PREFIX: &str = "data:application/octet-stream;base64,";

/// Encodes `mesh` as a `.gltf` JSON document with an embedded base64 buffer.
pub fn encode_gltf(mesh: &IndexedMesh) -> Result<Vec<u8>, IoError> {
    let (json, _) = build(mesh, true)?;
    Ok(json)
}

/// Encodes `mesh` as binary glTF (`.glb`): the 12-byte header, the JSON
/// chunk padded with spaces and the binary chunk, written once into the
/// output (glTF 2.0 §4.4; no intermediate copy of the buffer).
pub fn encode_glb(mesh: &IndexedMesh) -> Result<Vec<u8>, IoError> {
    let (json, mut bin) = build(mesh, false)?;
    let json_len = json.len().next_multiple_of(4);
    let bin_chunk = if bin.is_empty() { 0 } else { 8 + bin.len() };
    let total = 12 + 8 + json_len + bin_chunk;
    let too_big = || IoError::InvalidMesh {
        message: format!("GLB container: {total} bytes exceed the format's 4 GiB"),
    };
    let total32 = u32::try_from(total).map_err(|_| too_big())?;
    let mut front = Vec::with_capacity(28 + json_len);
    front.extend_from_slice(b"glTF");
    front.extend_from_slice(&2u32.to_le_bytes());
    front.extend_from_slice(&total32.to_le_bytes());
    front.extend_from_slice(&(json_len as u32).to_le_bytes());
    front.extend_from_slice(b"JSON");
    front.extend_from_slice(&json);
    front.resize(20 + json_len, b' ');
    if bin.is_empty() {
        return Ok(front);
    }
    front.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    front.extend_from_slice(b"BIN\0");
    // The buffer was reserved with room for this in front: one move, no copy.
    bin.splice(0..0, front);
    Ok(bin)
}

/// Bytes reserved in front of the binary buffer for the GLB header and JSON.
const GLB_FRONT_ROOM: usize = 64 * 1024;

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

/// One vertex of a primitive: its source vertex and the shading values
/// it is split by (vertices are shared where all of them agree).
#[derive(Clone, Copy, PartialEq)]
pub(super) struct OutVertex {
    source: u32,
    normal: [f32; 3],
    uv: [f32; 2],
    color: [f32; 3],
}

/// A primitive before it is laid out: its mode, material, vertices and
/// indices (triangles or line pairs).
pub(super) struct Draw {
    mode: json::mesh::Mode,
    material: Option<u32>,
    vertices: Vec<OutVertex>,
    indices: Vec<u32>,
}

/// Per-source-vertex chains of the output vertices made from it, so a
/// corner finds an equal vertex of its primitive in a few comparisons
/// (deterministic: no hashing; reset only where touched).
#[derive(Default)]
pub(super) struct Sharing {
    head: Vec<u32>,
    next: Vec<u32>,
    touched: Vec<u32>,
}

impl Sharing {
    fn new(vertices: usize) -> Self {
        Sharing {
            head: vec![u32::MAX; vertices],
            next: Vec::new(),
            touched: Vec::new(),
        }
    }

    /// The index of `v` in `vertices`, added when no equal vertex exists.
    fn index(&mut self, vertices: &mut Vec<OutVertex>, v: OutVertex) -> u32 {
        let slot = v.source as usize;
        let mut at = self.head[slot];
        while at != u32::MAX {
            if vertices[at as usize] == v {
                return at;
            }
            at = self.next[at as usize];
        }
        let index = vertices.len() as u32;
        if self.head[slot] == u32::MAX {
            self.touched.push(v.source);
        }
        self.next.push(self.head[slot]);
        self.head[slot] = index;
        vertices.push(v);
        index
    }

    /// Forgets the primitive just built.
    fn clear(&mut self) {
        for &v in &self.touched {
            self.head[v as usize] = u32::MAX;
        }
        self.touched.clear();
        self.next.clear();
    }
}

/// The primitives of each part, in part order: the surface split by
/// material (material order), then the part's wire edges.
pub(super) fn plan_draws(mesh: &IndexedMesh) -> Result<Vec<Vec<Draw>>, IoError> {
    use json::mesh::Mode;
    let parts = mesh.part_count();
    let materials = mesh.materials.len().max(1);
    let (order, start) = mesh.polygon_groups();
    let mut sharing = Sharing::new(mesh.positions.len());
    let mut tri = PolygonTriangulator::default();
    let mut local: Vec<u32> = Vec::new();
    let mut out = Vec::with_capacity(parts);
    for part in 0..parts {
        let mut draws = Vec::new();
        for material in 0..materials {
            let g = part * materials + material;
            let polygons = &order[start[g]..start[g + 1]];
            if polygons.is_empty() {
                continue;
            }
            // At most one vertex per corner, and three indices per corner
            // beyond the second of each polygon: reserved once.
            let corners: usize = polygons
                .iter()
                .map(|&k| mesh.polygon(k as usize).len())
                .sum();
            let mut draw = Draw {
                mode: Mode::Triangles,
                material: (!mesh.materials.is_empty()).then_some(material as u32),
                vertices: Vec::with_capacity(corners),
                indices: Vec::with_capacity(3 * (corners - 2 * polygons.len())),
            };
            sharing.next.reserve(corners);
            let smooth = !mesh.corner_normals.is_empty();
            for &k in polygons {
                let k = k as usize;
                let poly = mesh.polygon(k);
                // The flat normal only where no corner normal is given; a
                // triangle is its own triangulation.
                let flat = if smooth {
                    tri.triangles.clear();
                    if poly.len() == 3 {
                        tri.triangles.push([0, 1, 2]);
                    } else {
                        tri.run(mesh, poly);
                    }
                    [0.0; 3]
                } else {
                    unit_f32(tri.run(mesh, poly).unwrap_or(DVec3::Z))
                };
                let first = mesh.face_starts[k] as usize;
                local.clear();
                for (i, &v) in poly.iter().enumerate() {
                    let c = first + i;
                    let vertex = OutVertex {
                        source: v,
                        normal: match mesh.corner_normals.get(c) {
                            Some(&n) => unit_f32(DVec3::from_array(n)),
                            None => flat,
                        },
                        uv: mesh
                            .corner_uvs
                            .get(c)
                            // glTF's v runs down the image (§3.7.2.1).
                            .map_or([0.0; 2], |t| [t[0] as f32, (1.0 - t[1]) as f32]),
                        color: mesh
                            .corner_colors
                            .get(c)
                            .map_or([0.0; 3], |c| c.map(|x| x as f32)),
                    };
                    local.push(sharing.index(&mut draw.vertices, vertex));
                }
                draw.indices
                    .extend(tri.triangles.iter().flatten().map(|&i| local[i as usize]));
            }
            sharing.clear();
            if u32::try_from(draw.vertices.len()).is_err() {
                return Err(IoError::InvalidMesh {
                    message: "a primitive's vertices exceed glTF's u32 index range".into(),
                });
            }
            draws.push(draw);
        }
        let mut wire = Draw {
            mode: Mode::Lines,
            material: None,
            vertices: Vec::new(),
            indices: Vec::new(),
        };
        for (k, line) in mesh.lines.iter().enumerate() {
            if mesh.line_part(k) as usize != part {
                continue;
            }
            for &v in line {
                let vertex = OutVertex {
                    source: v,
                    normal: [0.0; 3],
                    uv: [0.0; 2],
                    color: [0.0; 3],
                };
                let index = sharing.index(&mut wire.vertices, vertex);
                wire.indices.push(index);
            }
        }
        sharing.clear();
        if !wire.indices.is_empty() {
            draws.push(wire);
        }
        out.push(draws);
    }
    Ok(out)
}

/// The binary buffer, little-endian; every view starts 4-byte aligned.
pub(super) struct Words(pub Vec<u8>);

impl Words {
    fn floats(&mut self, values: impl Iterator<Item = f32>) {
        for x in values {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
    }

    fn words(&mut self, values: impl Iterator<Item = u32>) {
        for x in values {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
    }
}

/// Document under construction: JSON root, buffer, and the custom
/// attributes to splice into each primitive.
pub(super) struct Builder {
    root: json::Root,
    words: Words,
    custom: Vec<Vec<(String, u32)>>,
}

impl Builder {
    /// Appends a bufferView + accessor over `data` (already pushed from
    /// byte `start`); returns the accessor.
    fn accessor(
        &mut self,
        start: usize,
        count: usize,
        component: json::accessor::ComponentType,
        type_: json::accessor::Type,
        target: json::buffer::Target,
    ) -> Index<json::Accessor> {
        use json::accessor::{ComponentType, Type};
        let component_size = match component {
            ComponentType::U16 => 2,
            _ => 4,
        };
        let dims = match type_ {
            Type::Vec2 => 2,
            Type::Vec3 => 3,
            _ => 1,
        };
        let byte_length = count * dims * component_size;
        let view = self.root.push(json::buffer::View {
            buffer: Index::new(0),
            byte_length: USize64(byte_length as u64),
            byte_offset: (start > 0).then_some(USize64(start as u64)),
            byte_stride: None,
            name: None,
            target: Some(Checked::Valid(target)),
            extensions: Default::default(),
            extras: Default::default(),
        });
        self.root.push(json::Accessor {
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
        })
    }

    /// Lays out one primitive's arrays and returns its JSON.
    fn primitive(
        &mut self,
        mesh: &IndexedMesh,
        draw: &Draw,
        scalars: &[(&str, &[f64])],
        material_indices: &[Index<json::Material>],
    ) -> json::mesh::Primitive {
        use json::accessor::{ComponentType, Type};
        use json::buffer::Target::{ArrayBuffer, ElementArrayBuffer};
        use json::mesh::Semantic;
        let n = draw.vertices.len();
        let mut attributes = BTreeMap::new();
        let start = self.words.0.len();
        let mut bounds = Bounds::new();
        for v in &draw.vertices {
            let p = to_f32(turn_y_up(mesh.positions[v.source as usize]));
            bounds.add(p);
            self.words.floats(p.into_iter());
        }
        let position = self.accessor(start, n, ComponentType::F32, Type::Vec3, ArrayBuffer);
        let to_value = |v: [f32; 3]| json::Value::from(v.map(f64::from).to_vec());
        self.root.accessors[position.value()].min = Some(to_value(bounds.min));
        self.root.accessors[position.value()].max = Some(to_value(bounds.max));
        attributes.insert(Checked::Valid(Semantic::Positions), position);
        let surface = draw.mode == json::mesh::Mode::Triangles;
        if surface {
            let start = self.words.0.len();
            self.words
                .floats(draw.vertices.iter().flat_map(|v| turn_normal(v.normal)));
            let normal = self.accessor(start, n, ComponentType::F32, Type::Vec3, ArrayBuffer);
            attributes.insert(Checked::Valid(Semantic::Normals), normal);
            if !mesh.corner_uvs.is_empty() {
                let start = self.words.0.len();
                self.words.floats(draw.vertices.iter().flat_map(|v| v.uv));
                let uv = self.accessor(start, n, ComponentType::F32, Type::Vec2, ArrayBuffer);
                attributes.insert(Checked::Valid(Semantic::TexCoords(0)), uv);
            }
            if !mesh.corner_colors.is_empty() {
                let start = self.words.0.len();
                self.words
                    .floats(draw.vertices.iter().flat_map(|v| v.color));
                let color = self.accessor(start, n, ComponentType::F32, Type::Vec3, ArrayBuffer);
                attributes.insert(Checked::Valid(Semantic::Colors(0)), color);
            }
        }
        let mut custom = Vec::with_capacity(scalars.len());
        for (name, values) in scalars {
            let start = self.words.0.len();
            self.words.floats(
                draw.vertices
                    .iter()
                    .map(|v| values[v.source as usize] as f32),
            );
            let accessor = self.accessor(start, n, ComponentType::F32, Type::Scalar, ArrayBuffer);
            custom.push((
                format!("_{}", name.to_ascii_uppercase()),
                accessor.value() as u32,
            ));
        }
        self.custom.push(custom);
        // No index buffer where it would only count 0, 1, 2, … (every corner
        // its own vertex: a soup, or flat normals on a smooth surface).
        let identity = draw.indices.len() == n
            && draw
                .indices
                .iter()
                .enumerate()
                .all(|(i, &x)| x as usize == i);
        let indices = (!identity).then(|| {
            // u16 indices while the largest index (n - 1) stays below the restart value.
            let start = self.words.0.len();
            let component = if n > usize::from(u16::MAX) {
                self.words.words(draw.indices.iter().copied());
                ComponentType::U32
            } else {
                for &i in &draw.indices {
                    self.words.0.extend_from_slice(&(i as u16).to_le_bytes());
                }
                // The next view starts 4-byte aligned.
                let padded = self.words.0.len().next_multiple_of(4);
                self.words.0.resize(padded, 0);
                ComponentType::U16
            };
            self.accessor(
                start,
                draw.indices.len(),
                component,
                Type::Scalar,
                ElementArrayBuffer,
            )
        });
        json::mesh::Primitive {
            attributes,
            extensions: Default::default(),
            extras: Default::default(),
            indices,
            material: draw
                .material
                .and_then(|m| material_indices.get(m as usize).copied()),
            mode: Checked::Valid(draw.mode),
            targets: None,
        }
    }
}

/// glTF is +Y up (spec §3.4): the kernel's Z-up (x, y, z) is written as
/// (x, z, −y), exactly (a swap and a negation).
fn turn_y_up(p: [f64; 3]) -> [f64; 3] {
    [p[0], p[2], -p[1] + 0.0]
}

fn turn_normal(n: [f32; 3]) -> [f32; 3] {
    [n[0], n[2], -n[1] + 0.0]
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

/// The glTF form of a material (PBR metallic-roughness, §3.9.2).
fn material_json(m: &Material) -> json::Material {
    use json::material::{
        AlphaCutoff, AlphaMode as Mode, EmissiveFactor, PbrBaseColorFactor, StrengthFactor,
    };
    let (alpha_mode, alpha_cutoff) = match m.alpha {
        AlphaMode::Opaque => (Mode::Opaque, None),
        AlphaMode::Mask(cutoff) => (Mode::Mask, Some(AlphaCutoff(cutoff as f32))),
        AlphaMode::Blend => (Mode::Blend, None),
    };
    json::Material {
        alpha_cutoff,
        alpha_mode: Checked::Valid(alpha_mode),
        double_sided: m.double_sided.unwrap_or(true),
        name: Some(m.name.clone()),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: PbrBaseColorFactor(m.base_color.map(|c| c as f32)),
            metallic_factor: StrengthFactor(m.metallic as f32),
            roughness_factor: StrengthFactor(m.roughness as f32),
            ..Default::default()
        },
        emissive_factor: EmissiveFactor(m.emissive.map(|c| c as f32)),
        ..Default::default()
    }
}

/// Builds the document: (JSON bytes, binary buffer). With `embed`, the
/// buffer is a data URI in the JSON and the returned buffer is empty.
///
/// One node and one mesh per part (named after it, in part order), one
/// primitive per material the part uses plus one of its wire edges;
/// vertices are shared within a primitive where position, normal, texture
/// coordinates and colour agree.
pub(super) fn build(mesh: &IndexedMesh, embed: bool) -> Result<(Vec<u8>, Vec<u8>), IoError> {
    mesh.validate()?;
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
    let draws = plan_draws(mesh)?;
    // The buffer's size is known now: reserve it once (growing a ~100 MB
    // vector by doubling copies it several times over).
    let per_vertex = |d: &Draw| {
        let surface = d.mode == json::mesh::Mode::Triangles;
        let uv = if surface && !mesh.corner_uvs.is_empty() {
            2
        } else {
            0
        };
        let color = if surface && !mesh.corner_colors.is_empty() {
            3
        } else {
            0
        };
        3 + if surface { 3 } else { 0 } + uv + color + scalars.len()
    };
    let words: usize = draws
        .iter()
        .flatten()
        .map(|d| d.vertices.len() * per_vertex(d) + d.indices.len())
        .sum();
    let buffer = Vec::with_capacity(4 * words + GLB_FRONT_ROOM);
    let mut b = Builder {
        root: json::Root {
            asset: json::Asset {
                generator: Some("graftal".to_string()),
                ..Default::default()
            },
            ..Default::default()
        },
        // Room in front for the GLB header and JSON, moved in at the end
        // (one buffer, no second copy; a larger JSON only reallocates).
        words: Words(buffer),
        custom: Vec::new(),
    };
    // Every material is written, in index order, used or not.
    let material_indices: Vec<Index<json::Material>> = mesh
        .materials
        .iter()
        .map(|m| b.root.push(material_json(m)))
        .collect();
    let mut scene_nodes = Vec::new();
    for (part, part_draws) in draws.iter().enumerate() {
        if part_draws.is_empty() {
            continue;
        }
        let primitives = part_draws
            .iter()
            .map(|d| b.primitive(mesh, d, &scalars, &material_indices))
            .collect();
        let name = mesh.parts.get(part).cloned();
        let mesh_index = b.root.push(json::Mesh {
            extensions: Default::default(),
            extras: Default::default(),
            name: name.clone(),
            primitives,
            weights: None,
        });
        scene_nodes.push(b.root.push(json::Node {
            mesh: Some(mesh_index),
            name,
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
    let bin = std::mem::take(&mut b.words.0);
    let bytes: &[u8] = &bin;
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
