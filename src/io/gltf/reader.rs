//! Reading `.gltf` and `.glb` (see the module overview in `gltf`).

use super::*;
use crate::geom::material::{sanitize_name, AlphaMode, Material};
use crate::geom::normals::unit_as_read;

/// Decodes `.gltf` JSON or `.glb` (detected by the `glTF` magic); `path` names the file in
/// errors. External buffer files are refused: see [`decode_with`].
pub fn decode(bytes: &[u8], path: &Path) -> Result<IndexedMesh, IoError> {
    decode_with(bytes, path, &mut crate::io::no_external_files)
}

/// [`decode`] with `resolve` supplying external buffers (URIs relative to the file).
pub fn decode_with(
    bytes: &[u8],
    path: &Path,
    resolve: &mut crate::io::Resolve,
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
    let compression = meshopt_views::take_compression(&mut value).map_err(&malformed)?;
    let draco = draco_primitives::take_draco(&mut value).map_err(&malformed)?;
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
    // Quantized attributes are dequantized as the spec says; compressed
    // bufferViews are decoded before any accessor reads them.
    const READ_EXTENSIONS: &[&str] = &[
        "KHR_mesh_quantization",
        "EXT_meshopt_compression",
        "KHR_draco_mesh_compression",
    ];
    if let Some(ext) = root
        .extensions_required
        .iter()
        .find(|e| !READ_EXTENSIONS.contains(&e.as_str()))
    {
        return Err(malformed(format!("requires unsupported extension {ext}")));
    }
    let buffers = load_buffers(&root, blob, &compression.fallback_buffers, path, resolve)?;
    let decoded_views =
        meshopt_views::decode_views(&compression.views, &buffers).map_err(&malformed)?;
    let decoded_accessors =
        draco_primitives::decode_accessors(&draco, &root, &custom, &buffers).map_err(malformed)?;
    Reader {
        root: &root,
        buffers: &buffers,
        decoded_views: &decoded_views,
        decoded_accessors: &decoded_accessors,
        custom: &custom,
        path,
    }
    .read()
}

/// Splits a GLB container into its JSON chunk and optional BIN chunk.
pub(super) fn split_glb<'a>(
    bytes: &'a [u8],
    path: &Path,
) -> Result<(&'a [u8], Option<&'a [u8]>), IoError> {
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
pub(super) fn take_custom_attributes(value: &mut json::Value) -> Vec<Vec<Vec<(String, u64)>>> {
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

pub(super) fn load_buffers<'a>(
    root: &json::Root,
    blob: Option<&'a [u8]>,
    fallback: &[bool],
    path: &Path,
    resolve: &mut crate::io::Resolve,
) -> Result<Vec<Cow<'a, [u8]>>, IoError> {
    let malformed = |message: String| IoError::Malformed {
        path: path.to_path_buf(),
        message,
    };
    let mut buffers = Vec::with_capacity(root.buffers.len());
    for (i, buffer) in root.buffers.iter().enumerate() {
        if fallback.get(i) == Some(&true) {
            // EXT_meshopt_compression's fallback: only compressed views
            // point into it, and they are read from their compressed buffer.
            buffers.push(Cow::Borrowed(&[][..]));
            continue;
        }
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
pub(super) fn percent_decode(uri: &str) -> String {
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
pub(super) type Mat4 = [f64; 16];

pub(super) const IDENTITY: Mat4 = [
    1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
];

pub(super) fn mul(a: &Mat4, b: &Mat4) -> Mat4 {
    let mut m = [0.0; 16];
    for c in 0..4 {
        for r in 0..4 {
            m[c * 4 + r] = (0..4).map(|k| a[k * 4 + r] * b[c * 4 + k]).sum();
        }
    }
    m
}

pub(super) fn local_matrix(node: &json::Node) -> Mat4 {
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

pub(super) fn transform(m: &Mat4, p: [f32; 3]) -> [f64; 3] {
    let p = p.map(f64::from);
    if *m == IDENTITY {
        return p;
    }
    [0, 1, 2].map(|r| m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r])
}

pub(super) struct Reader<'a> {
    root: &'a json::Root,
    buffers: &'a [Cow<'a, [u8]>],
    /// Per bufferView, its bytes when it was stored compressed.
    decoded_views: &'a [Option<Vec<u8>>],
    /// Per accessor, its bytes when its primitive was Draco-compressed.
    decoded_accessors: &'a [Option<Vec<u8>>],
    custom: &'a [Vec<Vec<(String, u64)>>],
    path: &'a Path,
}

/// Parts, materials and corner values of the mesh being read, per
/// polygon (and per line) and per corner, as they are pushed.
#[derive(Default)]
pub(super) struct Looks {
    /// Part of the instance being read.
    part: u32,
    polygon_parts: Vec<u32>,
    line_parts: Vec<u32>,
    materials: Vec<Option<u32>>,
    normals: Vec<Option<[f64; 3]>>,
    uvs: Vec<Option<[f64; 2]>>,
    colors: Vec<Option<[f64; 3]>>,
}

/// Part names for the instances (valid and unique: other characters
/// become `_`, repeats get `.1`, `.2`, …, missing names `mesh_N`) and
/// each instance's part; instances of one name share a part.
fn part_names(instances: &[(usize, Mat4, Option<String>)]) -> (Vec<String>, Vec<u32>) {
    let mut names: Vec<String> = Vec::new();
    let mut of = Vec::with_capacity(instances.len());
    for (mesh, _, name) in instances {
        let name = sanitize_name(name.as_deref().unwrap_or(""), &format!("mesh_{mesh}"));
        let index = match names.iter().position(|n| *n == name) {
            Some(i) => i,
            None => {
                names.push(name);
                names.len() - 1
            }
        };
        of.push(index as u32);
    }
    (names, of)
}

/// Makes material names unique (`wood`, `wood.1`, …).
fn dedupe_names(materials: &mut [Material]) {
    let mut names: Vec<String> = materials.iter().map(|m| m.name.clone()).collect();
    crate::geom::material::dedupe_names(&mut names);
    for (m, name) in materials.iter_mut().zip(names) {
        m.name = name;
    }
}

/// A glTF material as graftal's (factors clamped into [0, 1]).
fn material((index, m): (usize, &json::Material)) -> Material {
    let unit = |x: f32| {
        let x = f64::from(x);
        if x.is_nan() {
            1.0
        } else {
            x.clamp(0.0, 1.0)
        }
    };
    let pbr = &m.pbr_metallic_roughness;
    let alpha = match m.alpha_mode {
        Checked::Valid(json::material::AlphaMode::Mask) => {
            AlphaMode::Mask(m.alpha_cutoff.map_or(0.5, |c| unit(c.0)))
        }
        Checked::Valid(json::material::AlphaMode::Blend) => AlphaMode::Blend,
        _ => AlphaMode::Opaque,
    };
    Material {
        name: sanitize_name(
            m.name.as_deref().unwrap_or(""),
            &format!("material_{index}"),
        ),
        base_color: pbr.base_color_factor.0.map(unit),
        metallic: unit(pbr.metallic_factor.0),
        roughness: unit(pbr.roughness_factor.0),
        emissive: m.emissive_factor.0.map(unit),
        alpha,
        double_sided: Some(m.double_sided),
    }
}

/// How normals transform under a node's matrix: the inverse transpose of
/// its linear part, up to a positive scale (the cofactor matrix, with the
/// determinant's sign taken out so mirroring keeps normals pointing out).
fn cofactor(m: &Mat4) -> glam::DMat3 {
    // Column-major: column c is m[4c..4c + 3].
    let col = |c: usize| DVec3::new(m[4 * c], m[4 * c + 1], m[4 * c + 2]);
    let (a, b, c) = (col(0), col(1), col(2));
    let cof = glam::DMat3::from_cols(b.cross(c), c.cross(a), a.cross(b));
    if a.dot(b.cross(c)) < 0.0 {
        -cof
    } else {
        cof
    }
}

/// Vertex scalar columns of the mesh being read, with "has a value yet" flags.
pub(super) struct Columns {
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
            .filter_map(|(mesh, _, _)| self.custom.get(*mesh))
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
        let mut looks = Looks::default();
        let names = part_names(&instances);
        for ((mesh_index, matrix, _), part) in instances.iter().zip(&names.1) {
            let json_mesh = &self.root.meshes[*mesh_index];
            looks.part = *part;
            for (prim_index, primitive) in json_mesh.primitives.iter().enumerate() {
                self.primitive(
                    *mesh_index,
                    prim_index,
                    primitive,
                    matrix,
                    &mut merger,
                    &mut columns,
                    &mut looks,
                    &mut mesh,
                )?;
            }
        }
        mesh.positions = merger.positions;
        mesh.vertex_scalars = columns.names.into_iter().zip(columns.values).collect();
        if names.0.len() > 1 || instances.iter().any(|i| i.2.is_some()) {
            mesh.parts = names.0;
            mesh.polygon_parts = looks.polygon_parts;
            mesh.line_parts = looks.line_parts;
        }
        self.finish_looks(
            &mut mesh,
            looks.materials,
            looks.normals,
            looks.uvs,
            looks.colors,
        );
        // glTF is +Y up (spec §3.4); graftal's kernel is Z-up.
        mesh.y_up_to_z_up();
        Ok(mesh)
    }

    /// Materials, and the per-corner values where any primitive had them
    /// (the others' corners get their polygon's normal, (0, 0), white).
    fn finish_looks(
        &self,
        mesh: &mut IndexedMesh,
        materials: Vec<Option<u32>>,
        normals: Vec<Option<[f64; 3]>>,
        uvs: Vec<Option<[f64; 2]>>,
        colors: Vec<Option<[f64; 3]>>,
    ) {
        if !self.root.materials.is_empty() && mesh.polygon_count() > 0 {
            mesh.materials = self
                .root
                .materials
                .iter()
                .enumerate()
                .map(material)
                .collect();
            dedupe_names(&mut mesh.materials);
            let fallback = mesh.materials.len() as u32;
            // A primitive naming a material the file lacks gets the default.
            let materials: Vec<Option<u32>> = materials
                .into_iter()
                .map(|m| m.filter(|&m| m < fallback))
                .collect();
            if materials.iter().any(Option::is_none) {
                // The glTF default material (§3.9.6): white, metallic, rough.
                mesh.materials.push(Material {
                    name: "gltf_default".into(),
                    base_color: [1.0; 4],
                    metallic: 1.0,
                    roughness: 1.0,
                    emissive: [0.0; 3],
                    alpha: AlphaMode::Opaque,
                    double_sided: Some(false),
                });
                dedupe_names(&mut mesh.materials);
            }
            mesh.polygon_materials = materials.iter().map(|m| m.unwrap_or(fallback)).collect();
        }
        if normals.iter().any(Option::is_some) {
            let mut tri = PolygonTriangulator::default();
            let mut out = Vec::with_capacity(normals.len());
            let mut at = 0;
            for k in 0..mesh.polygon_count() {
                let poly = mesh.polygon(k);
                let flat = tri.run(mesh, poly).unwrap_or(DVec3::Z).to_array();
                out.extend(
                    normals[at..at + poly.len()]
                        .iter()
                        .map(|n| n.unwrap_or(flat)),
                );
                at += poly.len();
            }
            mesh.corner_normals = out;
        }
        if uvs.iter().any(Option::is_some) {
            mesh.corner_uvs = uvs.iter().map(|t| t.unwrap_or([0.0; 2])).collect();
        }
        if colors.iter().any(Option::is_some) {
            mesh.corner_colors = colors.iter().map(|c| c.unwrap_or([1.0; 3])).collect();
        }
    }

    /// (mesh index, world matrix, name) for every node with a mesh, in
    /// traversal order; the name is the node's, else its mesh's.
    fn instances(&self) -> Result<Vec<(usize, Mat4, Option<String>)>, IoError> {
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
                let name = node
                    .name
                    .clone()
                    .or_else(|| root.meshes[m.value()].name.clone());
                instances.push((m.value(), world, name));
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
        looks: &mut Looks,
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
        // Triangles as positions in `indices`, so each corner finds its
        // source vertex's normal, texture coordinates and colour.
        let mut triangles: Vec<[usize; 3]> = Vec::new();
        match mode {
            Mode::Triangles => {
                triangles.extend((0..r.len() / 3).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]))
            }
            Mode::TriangleStrip => triangles.extend((0..r.len().saturating_sub(2)).map(|i| {
                if i % 2 == 0 {
                    [i, i + 1, i + 2]
                } else {
                    [i + 1, i, i + 2]
                }
            })),
            Mode::TriangleFan => {
                triangles.extend((0..r.len().saturating_sub(2)).map(|i| [i + 1, i + 2, 0]))
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
        looks.line_parts.resize(mesh.lines.len(), looks.part);
        if triangles.is_empty() {
            return Ok(());
        }
        let semantic = |s: json::mesh::Semantic| {
            primitive
                .attributes
                .get(&Checked::Valid(s))
                .map(|a| a.value())
        };
        let per_vertex = |accessor: Option<usize>, dims: &[usize], what: &str| {
            let Some(accessor) = accessor else {
                return Ok(None);
            };
            let actual = self.accessor_bytes(accessor, &context, what)?.4;
            let wanted = if dims.contains(&actual) {
                actual
            } else {
                dims[0]
            };
            let values = self.read_quantized(accessor, wanted, &context, what)?;
            if values.len() != count * wanted {
                return Err(self.malformed(format!(
                    "{context}: {what} has {} values for {count} vertices",
                    values.len() / wanted
                )));
            }
            Ok(Some((values, wanted)))
        };
        use json::mesh::Semantic;
        let normals = per_vertex(semantic(Semantic::Normals), &[3], "NORMAL")?;
        let uvs = per_vertex(semantic(Semantic::TexCoords(0)), &[2], "TEXCOORD_0")?;
        let colors = per_vertex(semantic(Semantic::Colors(0)), &[3, 4], "COLOR_0")?;
        let cofactor = cofactor(matrix);
        for t in &triangles {
            mesh.push_polygon(&t.map(|k| r[k]));
            looks.polygon_parts.push(looks.part);
            looks
                .materials
                .push(primitive.material.map(|m| m.value() as u32));
            for &k in t {
                let v = indices[k] as usize;
                looks.normals.push(normals.as_ref().and_then(|(n, _)| {
                    let local = DVec3::new(
                        f64::from(n[3 * v]),
                        f64::from(n[3 * v + 1]),
                        f64::from(n[3 * v + 2]),
                    );
                    // Kept as read where it is unit already (an identity
                    // node): converting again then changes no bit.
                    unit_as_read(cofactor * local).map(|n| n.to_array())
                }));
                looks.uvs.push(uvs.as_ref().and_then(|(t, _)| {
                    let (s, tt) = (f64::from(t[2 * v]), f64::from(t[2 * v + 1]));
                    // glTF's v runs down the image; graftal's up.
                    (s.is_finite() && tt.is_finite()).then_some([s, 1.0 - tt])
                }));
                looks.colors.push(colors.as_ref().map(|(c, dims)| {
                    let at = dims * v;
                    [c[at], c[at + 1], c[at + 2]]
                        .map(|x| f64::from(x).clamp(0.0, 1.0))
                        .map(|x| if x.is_nan() { 1.0 } else { x })
                }));
            }
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
        use json::accessor::ComponentType;
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
        let dims = components(&acc.type_).ok_or_else(|| err("unsupported type".into()))?;
        let size = match component {
            ComponentType::I8 | ComponentType::U8 => 1,
            ComponentType::I16 | ComponentType::U16 => 2,
            ComponentType::U32 | ComponentType::F32 => 4,
        };
        let count = usize::try_from(acc.count.0).map_err(|_| err("count too large".into()))?;
        if count == 0 {
            return Ok((&[], size * dims, 0, component, dims));
        }
        if let (None, Some(Some(decoded))) = (acc.buffer_view, self.decoded_accessors.get(index)) {
            if decoded.len() as u64 != (size * dims) as u64 * count as u64 {
                return Err(err("does not match its decoded Draco data".into()));
            }
            return Ok((decoded, size * dims, count, component, dims));
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
        let (buffer, view_start, view_length) =
            match self.decoded_views.get(view_index) {
                // Decoded: the bytes are the view's own, from its start.
                Some(Some(decoded)) => (&decoded[..], 0, decoded.len() as u64),
                _ => (
                    &self.buffers.get(view.buffer.value()).ok_or_else(|| {
                        err(format!("buffer {} does not exist", view.buffer.value()))
                    })?[..],
                    view.byte_offset.map_or(0, |o| o.0),
                    view.byte_length.0,
                ),
            };
        let element = size * dims;
        let stride = view.byte_stride.map_or(element, |s| s.0);
        if stride < element {
            return Err(err(format!(
                "byteStride {stride} is smaller than an element"
            )));
        }
        let view_end = view_start.checked_add(view_length);
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
                "{count} elements do not fit in bufferView {view_index} ({view_length} bytes from byte {view_start}) / buffer of {} bytes",
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

/// Components per element of an accessor type this reader takes.
pub(super) fn components(type_: &Checked<json::accessor::Type>) -> Option<usize> {
    use json::accessor::Type;
    match type_ {
        Checked::Valid(Type::Scalar) => Some(1),
        Checked::Valid(Type::Vec2) => Some(2),
        Checked::Valid(Type::Vec3) => Some(3),
        Checked::Valid(Type::Vec4) => Some(4),
        _ => None,
    }
}
