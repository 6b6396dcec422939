//! Writing `.gltf` and `.glb` (see the module overview in `gltf`).

use super::*;
use crate::geom::material::{AlphaMode, Material};
use crate::geom::polygon;
use json::accessor::ComponentType;
use std::mem::take;

use crate::io::parts::FileParts;

pub(crate) const DATA_URI_PREFIX: &str = "data:application/octet-stream;base64,";

/// Encodes `mesh` as a `.gltf` JSON document with an embedded base64 buffer.
pub fn encode_gltf(mesh: &IndexedMesh) -> Result<Vec<u8>, IoError> {
    gltf_container(Document::new(mesh, true)?)
}

fn gltf_container(doc: Document) -> Result<Vec<u8>, IoError> {
    if doc.bin_len == 0 {
        return Ok(doc.json);
    }
    let mut bin = FileParts::default();
    let json = doc.write_buffer(&mut bin);
    let bin = bin.into_vec();
    // Encoding straight into the output avoids serde escaping a ~100 MB string.
    splice_base64(json, &bin)
}

/// Encodes `mesh` as binary glTF (`.glb`): the 12-byte header, the JSON
/// chunk padded with spaces and the binary chunk (glTF 2.0 §4.4). The JSON
/// is made from the buffer's layout first, so the buffer is written once,
/// into an output allocated at its final size.
pub fn encode_glb(mesh: &IndexedMesh) -> Result<Vec<u8>, IoError> {
    Ok(glb_container(Document::new(mesh, false)?)?.into_vec())
}

/// The bytes [`encode_glb`] (`glb`) or [`encode_gltf`] would give for
/// `look` with the polygons of `source` in place of its own: written
/// straight from `source` (a kernel mesh), with no indexed copy of it.
/// [`Planned`] does the same in two halves.
pub fn encode_streamed<S: PolygonSource>(
    source: &S,
    look: &IndexedMesh,
    glb: bool,
) -> Result<Vec<u8>, IoError> {
    Planned::new(source, look, glb)?.encode()
}

/// A glTF planned from a [`PolygonSource`]: its JSON and primitives, which
/// hold everything the file needs, so the source may be dropped before
/// [`Planned::encode`] allocates the file (peak memory is the larger of
/// source + primitives and primitives + file, not their sum).
pub struct Planned<'l> {
    doc: Document<'l>,
    glb: bool,
}

impl<'l> Planned<'l> {
    /// Plans the file for `look` with the polygons of `source`.
    ///
    /// `look` carries what a file adds to the geometry and holds none
    /// itself: at most one part, at most one material with its
    /// double-sidedness decided (the caller knows the shells), and no
    /// polygons, lines, vertex scalars or corner values. A mesh that needs
    /// more goes through [`encode_glb`]. Checks what
    /// [`IndexedMesh::validate`] and the `f32` range check would, in the
    /// same order, with the same messages.
    pub fn new<S: PolygonSource>(
        source: &S,
        look: &'l IndexedMesh,
        glb: bool,
    ) -> Result<Self, IoError> {
        debug_assert!(
            look.positions.is_empty()
                && look.polygon_count() == 0
                && look.lines.is_empty()
                && look.vertex_scalars.is_empty()
                && look.parts.len() <= 1
                && look.materials.len() <= 1
                && look.materials.iter().all(|m| m.double_sided.is_some()),
            "a streamed look holds no geometry, one part and decided materials"
        );
        source.check_vertices()?;
        source.check_f32_range("glTF")?;
        let count = source.vertex_count();
        let mut draws = Vec::new();
        if source.polygon_count() > 0 {
            let material = (!look.materials.is_empty()).then_some(0);
            let mut sharing = Sharing::new(count);
            draws.push(plan_flat_surface(source, material, &mut sharing)?);
        }
        let doc = Document::lay_out(look, Vec::new(), vec![draws], !glb)?;
        Ok(Planned { doc, glb })
    }

    /// The file's bytes.
    pub fn encode(self) -> Result<Vec<u8>, IoError> {
        Ok(self.encode_parts()?.into_vec())
    }

    /// The file [`Planned::encode`] gives, as parts: a GLB's columns are
    /// handed over as they were planned, not copied into one buffer.
    pub fn encode_parts(self) -> Result<FileParts, IoError> {
        if self.glb {
            glb_container(self.doc)
        } else {
            gltf_container(self.doc).map(FileParts::from)
        }
    }
}

fn glb_container(doc: Document) -> Result<FileParts, IoError> {
    let json_len = doc.json.len().next_multiple_of(4);
    let bin_chunk = if doc.bin_len == 0 { 0 } else { 8 + doc.bin_len };
    let total = 12 + 8 + json_len + bin_chunk;
    let too_big = || IoError::InvalidMesh {
        message: format!("GLB container: {total} bytes exceed the format's 4 GiB"),
    };
    let total32 = u32::try_from(total).map_err(|_| too_big())?;
    let mut head = Vec::with_capacity(28 + json_len);
    head.extend_from_slice(b"glTF");
    head.extend_from_slice(&2u32.to_le_bytes());
    head.extend_from_slice(&total32.to_le_bytes());
    head.extend_from_slice(&(json_len as u32).to_le_bytes());
    head.extend_from_slice(b"JSON");
    head.extend_from_slice(&doc.json);
    head.resize(20 + json_len, b' ');
    if doc.bin_len > 0 {
        head.extend_from_slice(&(doc.bin_len as u32).to_le_bytes());
        head.extend_from_slice(b"BIN\0");
    }
    let mut out = FileParts::from(head);
    if doc.bin_len > 0 {
        doc.write_buffer(&mut out);
    }
    debug_assert_eq!(out.len(), total);
    Ok(out)
}

pub(super) fn to_f32(p: [f64; 3]) -> [f32; 3] {
    // Range checked by the caller; -0 (also one rounded from a tiny negative)
    // is written as 0 so equal geometry gives equal bytes.
    p.map(|c| {
        let c = c as f32;
        if c == 0.0 {
            0.0
        } else {
            c
        }
    })
}

/// `f32` copy of a unit vector, rounded once from `f64`: a normal read
/// from a file (kept bit for bit when unit, `geom::normals::unit_as_read`)
/// comes back as the same `f32`s, so a conversion is a fixed point.
/// Renormalising in `f32` would not be: it moves the last bit each round.
/// The rounded vector is unit to within 2⁻²³, well inside the validator's
/// tolerance.
pub(super) fn unit_f32(v: DVec3) -> [f32; 3] {
    to_f32(v.to_array())
}

/// A primitive before it is laid out: its mode, material, vertices (one
/// column per value, as the buffer holds them) and indices (triangles or
/// line pairs).
pub(super) struct Draw {
    mode: json::mesh::Mode,
    material: Option<u32>,
    /// Each vertex's source vertex (for the vertex scalars).
    sources: Vec<u32>,
    /// Positions as written: `f32`, Y-up.
    positions: Vec<[f32; 3]>,
    /// A surface's normals (Y-up), and its texture coordinates and colours
    /// where the mesh has them; empty otherwise.
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    colors: Vec<[f32; 3]>,
    indices: Vec<u32>,
    /// Running min/max of `positions` (kept as they are added, while hot).
    bounds: Bounds,
}

/// One array of a primitive, in the order the buffer holds them.
#[derive(Clone, Copy)]
enum Array {
    Positions,
    Normals,
    Uvs,
    Colors,
    Scalar(usize),
    /// Omitted where the indices would only count 0, 1, 2, …
    Indices(ComponentType),
}

impl Draw {
    fn vertex_count(&self) -> usize {
        self.sources.len()
    }

    /// The arrays this primitive writes, in buffer order.
    fn arrays(&self, mesh: &IndexedMesh, scalars: usize) -> Vec<Array> {
        let mut arrays = vec![Array::Positions];
        if self.mode == json::mesh::Mode::Triangles {
            arrays.push(Array::Normals);
            if !mesh.corner_uvs.is_empty() {
                arrays.push(Array::Uvs);
            }
            if !mesh.corner_colors.is_empty() {
                arrays.push(Array::Colors);
            }
        }
        arrays.extend((0..scalars).map(Array::Scalar));
        // No index buffer where it would only count 0, 1, 2, … (every corner
        // its own vertex: a soup, or flat normals on a smooth surface).
        let n = self.vertex_count();
        let identity = self.indices.len() == n
            && self
                .indices
                .iter()
                .enumerate()
                .all(|(i, &x)| x as usize == i);
        if !identity {
            // u16 indices while the largest index (n - 1) stays below the restart value.
            arrays.push(Array::Indices(if n > usize::from(u16::MAX) {
                ComponentType::U32
            } else {
                ComponentType::U16
            }));
        }
        arrays
    }

    /// Bytes `array` takes in the buffer (u16 indices padded so the next
    /// view starts 4-byte aligned).
    fn bytes(&self, array: Array) -> usize {
        let n = self.vertex_count();
        match array {
            Array::Positions | Array::Normals | Array::Colors => 12 * n,
            Array::Uvs => 8 * n,
            Array::Scalar(_) => 4 * n,
            Array::Indices(ComponentType::U16) => (2 * self.indices.len()).next_multiple_of(4),
            Array::Indices(_) => 4 * self.indices.len(),
        }
    }
}

const NONE: u32 = u32::MAX;

/// Per-source-vertex chains of the output vertices made from it, so a
/// corner finds an equal vertex of its primitive in a few comparisons
/// (deterministic: no hashing; reset only where touched).
#[derive(Default)]
pub(super) struct Sharing {
    head: Vec<u32>,
    next: Vec<u32>,
    touched: Vec<u32>,
}

/// What a surface corner's vertex carries besides its position.
struct Shading {
    normal: [f32; 3],
    /// Where the mesh has texture coordinates or colours.
    uv: Option<[f32; 2]>,
    color: Option<[f32; 3]>,
}

impl Sharing {
    fn new(vertices: usize) -> Self {
        Sharing {
            head: vec![NONE; vertices],
            next: Vec::new(),
            touched: Vec::new(),
        }
    }

    /// The index of the surface vertex (`source`, `s`) in `draw`, added when
    /// no equal one exists (compared as `f32` values, as written).
    fn surface(
        &mut self,
        draw: &mut Draw,
        source: u32,
        position: impl FnOnce() -> DVec3,
        s: &Shading,
    ) -> u32 {
        let mut at = self.head[source as usize];
        while at != NONE {
            let i = at as usize;
            if draw.normals[i] == s.normal
                && s.uv.is_none_or(|uv| draw.uvs[i] == uv)
                && s.color.is_none_or(|color| draw.colors[i] == color)
            {
                return at;
            }
            at = self.next[i];
        }
        draw.normals.push(s.normal);
        draw.uvs.extend(s.uv);
        draw.colors.extend(s.color);
        self.add(draw, source, position())
    }

    /// The index of a wire vertex: one per source vertex.
    fn wire(&mut self, draw: &mut Draw, mesh: &IndexedMesh, source: u32) -> u32 {
        match self.head[source as usize] {
            NONE => self.add(draw, source, mesh.position(source)),
            at => at,
        }
    }

    fn add(&mut self, draw: &mut Draw, source: u32, position: DVec3) -> u32 {
        let slot = source as usize;
        let index = draw.sources.len() as u32;
        if self.head[slot] == NONE {
            self.touched.push(source);
        }
        self.next.push(self.head[slot]);
        self.head[slot] = index;
        draw.sources.push(source);
        let p = to_f32(turn_y_up(position.to_array()));
        draw.bounds.add(p);
        draw.positions.push(p);
        index
    }

    /// Forgets the primitive just built.
    fn clear(&mut self) {
        for &v in &self.touched {
            self.head[v as usize] = NONE;
        }
        self.touched.clear();
        self.next.clear();
    }
}

impl Draw {
    fn new(mode: json::mesh::Mode, material: Option<u32>) -> Self {
        Draw {
            mode,
            material,
            sources: Vec::new(),
            positions: Vec::new(),
            normals: Vec::new(),
            uvs: Vec::new(),
            colors: Vec::new(),
            indices: Vec::new(),
            bounds: Bounds::new(),
        }
    }
}

/// Polygons planned at a time (their flat normals first).
const BLOCK: usize = 256;

/// The primitives of each part, in part order: the surface split by
/// material (material order), then the part's wire edges.
pub(super) fn plan_draws(mesh: &IndexedMesh) -> Result<Vec<Vec<Draw>>, IoError> {
    use json::mesh::Mode;
    let parts = mesh.part_count();
    let materials = mesh.materials.len().max(1);
    // One group (part, material) is every polygon in order: no sort.
    let (order, start) = if parts * materials == 1 {
        (Vec::new(), vec![0, mesh.polygon_count()])
    } else {
        mesh.polygon_groups()
    };
    let mut sharing = Sharing::new(mesh.positions.len());
    let mut tri = PolygonTriangulator::default();
    let mut local: Vec<u32> = Vec::new();
    let mut flats: Vec<[f32; 3]> = Vec::with_capacity(BLOCK);
    let smooth = !mesh.corner_normals.is_empty();
    let (has_uv, has_color) = (!mesh.corner_uvs.is_empty(), !mesh.corner_colors.is_empty());
    let mut out = Vec::with_capacity(parts);
    for part in 0..parts {
        let mut draws = Vec::new();
        for material in 0..materials {
            let g = part * materials + material;
            let range = start[g]..start[g + 1];
            if range.is_empty() {
                continue;
            }
            let polygon_at = |i: usize| {
                if order.is_empty() {
                    i
                } else {
                    order[i] as usize
                }
            };
            // At most one vertex per corner, and three indices per corner
            // beyond the second of each polygon: reserved once.
            let corners: usize = if order.is_empty() {
                mesh.face_indices.len()
            } else {
                range
                    .clone()
                    .map(|i| mesh.polygon(polygon_at(i)).len())
                    .sum()
            };
            let material_index = (!mesh.materials.is_empty()).then_some(material as u32);
            // Every polygon in order, flat-shaded from stored normals: the
            // streaming planner, the one a kernel mesh is written with.
            if order.is_empty() && !smooth && !has_uv && !has_color && mesh.stores_normals() {
                draws.push(plan_flat_surface(mesh, material_index, &mut sharing)?);
                continue;
            }
            let mut draw = Draw::new(Mode::Triangles, material_index);
            draw.sources.reserve(corners);
            draw.positions.reserve(corners);
            draw.normals.reserve(corners);
            if has_uv {
                draw.uvs.reserve(corners);
            }
            if has_color {
                draw.colors.reserve(corners);
            }
            draw.indices.reserve(3 * (corners - 2 * range.len()));
            sharing.next.reserve(corners);
            let position = |v: u32| DVec3::from_array(mesh.positions[v as usize]);
            let stored = mesh.polygon_normals.len() == mesh.polygon_count();
            let mut block = range.start..range.start;
            while block.end < range.end {
                block = block.end..(block.end + BLOCK).min(range.end);
                // Triangles' flat normals first, in a loop of their own: the
                // square roots and divisions of neighbouring triangles overlap.
                // A triangle's normal is the one `PolygonTriangulator::run`
                // gives it (the same function).
                flats.clear();
                if !smooth {
                    flats.extend(block.clone().map(|i| {
                        let k = polygon_at(i);
                        match *mesh.polygon(k) {
                            // The producer's stored normal is these bits already.
                            [_, _, _] if stored => {
                                unit_f32(mesh.stored_normal(k).flatten().unwrap_or(DVec3::Z))
                            }
                            [a, b, c] => {
                                let corners = [position(a), position(b), position(c)];
                                unit_f32(polygon::unit_normal_of(&corners).unwrap_or(DVec3::Z))
                            }
                            _ => [0.0; 3],
                        }
                    }));
                }
                for (b, i) in block.clone().enumerate() {
                    let k = polygon_at(i);
                    let first = mesh.face_starts[k] as usize;
                    let poly = &mesh.face_indices[first..mesh.face_starts[k + 1] as usize];
                    let triangle = poly.len() == 3;
                    // The flat normal only where no corner normal is given; a
                    // triangle is its own triangulation.
                    let flat = if smooth {
                        if !triangle {
                            tri.run(mesh, poly);
                        }
                        [0.0; 3]
                    } else if triangle {
                        flats[b]
                    } else {
                        unit_f32(tri.run(mesh, poly).unwrap_or(DVec3::Z))
                    };
                    let vertex_of = |draw: &mut Draw, sharing: &mut Sharing, j: usize| {
                        let c = first + j;
                        let normal = match mesh.corner_normals.get(c) {
                            Some(&n) => unit_f32(DVec3::from_array(n)),
                            None => flat,
                        };
                        let shading = Shading {
                            normal: turn_normal(normal),
                            uv: mesh
                                .corner_uvs
                                .get(c)
                                // glTF's v runs down the image (§3.7.2.1).
                                .map(|t| [t[0] as f32, (1.0 - t[1]) as f32]),
                            color: mesh.corner_colors.get(c).map(|c| c.map(|x| x as f32)),
                        };
                        let v = poly[j];
                        sharing.surface(draw, v, || mesh.position(v), &shading)
                    };
                    push_triangles(&mut draw, poly.len(), &tri.triangles, &mut local, |d, j| {
                        vertex_of(d, &mut sharing, j)
                    });
                }
            }
            sharing.clear();
            check_index_range(&draw)?;
            draws.push(draw);
        }
        let mut wire = Draw::new(Mode::Lines, None);
        for (k, line) in mesh.lines.iter().enumerate() {
            if mesh.line_part(k) as usize != part {
                continue;
            }
            for &v in line {
                let index = sharing.wire(&mut wire, mesh, v);
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

/// Appends one polygon's triangles to `draw`: a triangle's corners in
/// order, a larger polygon's as `triangles` (local corner indices) split
/// it. `vertex_of(draw, j)` gives corner `j`'s vertex, asked once per
/// corner, in the order the triangles first use them: the triangles read
/// back from the file then number the vertices the same way, and
/// converting it again changes no byte.
fn push_triangles(
    draw: &mut Draw,
    corners: usize,
    triangles: &[[u32; 3]],
    local: &mut Vec<u32>,
    mut vertex_of: impl FnMut(&mut Draw, usize) -> u32,
) {
    if corners == 3 {
        for j in 0..3 {
            let index = vertex_of(draw, j);
            draw.indices.push(index);
        }
        return;
    }
    local.clear();
    local.resize(corners, u32::MAX);
    for &j in triangles.iter().flatten() {
        let j = j as usize;
        if local[j] == u32::MAX {
            local[j] = vertex_of(draw, j);
        }
        draw.indices.push(local[j]);
    }
}

fn check_index_range(draw: &Draw) -> Result<(), IoError> {
    match u32::try_from(draw.vertex_count()) {
        Ok(_) => Ok(()),
        Err(_) => Err(IoError::InvalidMesh {
            message: "a primitive's vertices exceed glTF's u32 index range".into(),
        }),
    }
}

/// One primitive of every polygon of `source`, in order, flat-shaded:
/// what [`plan_draws`] plans for a mesh of one part and one material with
/// neither corner normals, texture coordinates nor colours, read from any
/// [`PolygonSource`] (the kernel's mesh, without an indexed copy).
fn plan_flat_surface<S: PolygonSource>(
    source: &S,
    material: Option<u32>,
    sharing: &mut Sharing,
) -> Result<Draw, IoError> {
    let (corners, polygons) = (source.corner_count(), source.polygon_count());
    let mut draw = Draw::new(json::mesh::Mode::Triangles, material);
    // At most one vertex per corner, and three indices per corner beyond
    // the second of each polygon: reserved once.
    draw.sources.reserve(corners);
    draw.positions.reserve(corners);
    draw.normals.reserve(corners);
    draw.indices.reserve(3 * (corners - 2 * polygons));
    sharing.next.reserve(corners);
    let mut tri = PolygonTriangulator::default();
    let mut local: Vec<u32> = Vec::new();
    source.for_each_polygon(|poly, stored| {
        let position = |v: u32| source.position(v);
        let flat = match (poly, stored) {
            // The producer's stored normal is these bits already.
            ([_, _, _], Some(stored)) => unit_f32(stored.unwrap_or(DVec3::Z)),
            // A triangle's normal is the one `PolygonTriangulator::run`
            // gives it (the same function).
            (&[a, b, c], None) => {
                let corners = [position(a), position(b), position(c)];
                unit_f32(polygon::unit_normal_of(&corners).unwrap_or(DVec3::Z))
            }
            _ => unit_f32(tri.run_with(poly, position).unwrap_or(DVec3::Z)),
        };
        let shading = Shading {
            normal: turn_normal(flat),
            uv: None,
            color: None,
        };
        push_triangles(&mut draw, poly.len(), &tri.triangles, &mut local, |d, j| {
            let v = poly[j];
            sharing.surface(d, v, || position(v), &shading)
        });
    });
    sharing.clear();
    check_index_range(&draw)?;
    Ok(draw)
}

/// The document: its JSON, made from the buffer's layout, and the
/// primitives that fill the buffer when it is written.
struct Document<'m> {
    json: Vec<u8>,
    scalars: Vec<(&'m str, &'m [f64])>,
    /// Every primitive, in buffer order, with its arrays.
    draws: Vec<(Draw, Vec<Array>)>,
    bin_len: usize,
}

/// JSON under construction: the root, the next free buffer byte, and the
/// custom attributes to splice into each primitive.
struct Builder {
    root: json::Root,
    offset: usize,
    custom: Vec<Vec<(String, u32)>>,
}

impl Builder {
    /// Appends a bufferView + accessor over the next `count` elements of
    /// the buffer (`bytes` of it); returns the accessor.
    fn accessor(
        &mut self,
        bytes: usize,
        count: usize,
        component: ComponentType,
        type_: json::accessor::Type,
        target: json::buffer::Target,
    ) -> Index<json::Accessor> {
        use json::accessor::Type;
        let start = self.offset;
        self.offset += bytes;
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

    /// The JSON of one primitive, its arrays laid out next in the buffer.
    fn primitive(
        &mut self,
        draw: &Draw,
        arrays: &[Array],
        scalars: &[(&str, &[f64])],
        material_indices: &[Index<json::Material>],
    ) -> json::mesh::Primitive {
        use json::accessor::Type;
        use json::buffer::Target::{ArrayBuffer, ElementArrayBuffer};
        use json::mesh::Semantic;
        let n = draw.vertex_count();
        let mut attributes = BTreeMap::new();
        let mut custom = Vec::with_capacity(scalars.len());
        let mut indices = None;
        for &array in arrays {
            let bytes = draw.bytes(array);
            let (semantic, type_) = match array {
                Array::Positions => (Semantic::Positions, Type::Vec3),
                Array::Normals => (Semantic::Normals, Type::Vec3),
                Array::Uvs => (Semantic::TexCoords(0), Type::Vec2),
                Array::Colors => (Semantic::Colors(0), Type::Vec3),
                Array::Scalar(s) => {
                    let accessor =
                        self.accessor(bytes, n, ComponentType::F32, Type::Scalar, ArrayBuffer);
                    let name = format!("_{}", scalars[s].0.to_ascii_uppercase());
                    custom.push((name, accessor.value() as u32));
                    continue;
                }
                Array::Indices(component) => {
                    let count = draw.indices.len();
                    indices = Some(self.accessor(
                        bytes,
                        count,
                        component,
                        Type::Scalar,
                        ElementArrayBuffer,
                    ));
                    continue;
                }
            };
            let accessor = self.accessor(bytes, n, ComponentType::F32, type_, ArrayBuffer);
            if let Array::Positions = array {
                let bounds = &draw.bounds;
                let to_value = |v: [f32; 3]| json::Value::from(v.map(f64::from).to_vec());
                self.root.accessors[accessor.value()].min = Some(to_value(bounds.min));
                self.root.accessors[accessor.value()].max = Some(to_value(bounds.max));
            }
            attributes.insert(Checked::Valid(semantic), accessor);
        }
        self.custom.push(custom);
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

impl<'m> Document<'m> {
    /// Plans the primitives and makes the JSON. With `embed`, the buffer is
    /// a data URI whose payload is spliced in after serialization.
    ///
    /// One node and one mesh per part (named after it, in part order), one
    /// primitive per material the part uses plus one of its wire edges;
    /// vertices are shared within a primitive where position, normal,
    /// texture coordinates and colour agree.
    fn new(mesh: &'m IndexedMesh, embed: bool) -> Result<Self, IoError> {
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
        let planned = plan_draws(mesh)?;
        Self::lay_out(mesh, scalars, planned, embed)
    }

    /// The JSON for the primitives `planned` (per part, in part order) of
    /// `mesh`, whose materials, part names and corner arrays it names.
    fn lay_out(
        mesh: &'m IndexedMesh,
        scalars: Vec<(&'m str, &'m [f64])>,
        planned: Vec<Vec<Draw>>,
        embed: bool,
    ) -> Result<Self, IoError> {
        let mut b = Builder {
            root: json::Root {
                asset: json::Asset {
                    generator: Some("graftal".to_string()),
                    ..Default::default()
                },
                ..Default::default()
            },
            offset: 0,
            custom: Vec::new(),
        };
        // Every material is written, in index order, used or not; one the
        // source left undecided (OBJ has no such field) is decided from the
        // mesh, as `run` decides it.
        let double_sided = mesh.double_sided_decided();
        let material_indices: Vec<Index<json::Material>> = mesh
            .materials
            .iter()
            .zip(double_sided)
            .map(|(m, double)| b.root.push(material_json(m, double)))
            .collect();
        let mut draws = Vec::new();
        let mut scene_nodes = Vec::new();
        for (part, part_draws) in planned.into_iter().enumerate() {
            if part_draws.is_empty() {
                continue;
            }
            let mut primitives = Vec::with_capacity(part_draws.len());
            for draw in part_draws {
                let arrays = draw.arrays(mesh, scalars.len());
                primitives.push(b.primitive(&draw, &arrays, &scalars, &material_indices));
                draws.push((draw, arrays));
            }
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
        let bin_len = b.offset;
        if bin_len > 0 {
            b.root.push(json::Buffer {
                byte_length: USize64(bin_len as u64),
                name: None,
                // The base64 payload is spliced in after serialization (see above).
                uri: embed.then(|| DATA_URI_PREFIX.to_string()),
                extensions: Default::default(),
                extras: Default::default(),
            });
        }
        let json = json::serialize::to_vec(&b.root).map_err(|e| IoError::InvalidMesh {
            message: format!("glTF JSON serialization: {e}"),
        })?;
        let json = splice_custom_attributes(json, &b.custom)?;
        Ok(Document {
            json,
            scalars,
            draws,
            bin_len,
        })
    }

    /// Appends the binary buffer (`bin_len` bytes, little-endian) to `out`,
    /// array by array as [`Builder::primitive`] laid them out: each column
    /// handed over as planned, only the converted ones (vertex scalars,
    /// 16-bit indices) copied. Returns the JSON.
    fn write_buffer(self, out: &mut FileParts) -> Vec<u8> {
        let start = out.len();
        for (mut draw, arrays) in self.draws {
            for array in arrays {
                // Measured before a column is taken out of the draw.
                let (at, bytes) = (out.len(), draw.bytes(array));
                match array {
                    Array::Positions => out.push_f32s(take(&mut draw.positions).into_flattened()),
                    Array::Normals => out.push_f32s(take(&mut draw.normals).into_flattened()),
                    Array::Uvs => out.push_f32s(take(&mut draw.uvs).into_flattened()),
                    Array::Colors => out.push_f32s(take(&mut draw.colors).into_flattened()),
                    Array::Scalar(s) => {
                        let values = self.scalars[s].1;
                        let column = draw.sources.iter().map(|&v| values[v as usize] as f32);
                        out.push_f32s(column.collect());
                    }
                    Array::Indices(ComponentType::U16) => {
                        let mut column: Vec<u8> = draw
                            .indices
                            .iter()
                            .flat_map(|&i| (i as u16).to_le_bytes())
                            .collect();
                        // The next view starts 4-byte aligned.
                        column.resize(column.len().next_multiple_of(4), 0);
                        out.push_bytes(column);
                    }
                    Array::Indices(_) => out.push_u32s(take(&mut draw.indices)),
                }
                debug_assert_eq!(out.len() - at, bytes);
            }
        }
        debug_assert_eq!(out.len() - start, self.bin_len);
        self.json
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
fn material_json(m: &Material, double_sided: bool) -> json::Material {
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
        double_sided,
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
