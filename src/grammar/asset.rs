//! From a grown model to an asset (issue 16): the part and material every
//! face carries (kernel face layers, inherited through the operators'
//! attribute copies), and the export that turns the kernel mesh into the
//! writers' [`IndexedMesh`] with named parts, materials, shading normals
//! and texture coordinates.

use crate::geom::material::srgb_to_linear;
use crate::geom::material::Material;
use crate::geom::uv::UvMapping;
use crate::geom::{normals, uv, IndexedMesh};
use crate::kernel::attrs::AttrValue;
use crate::kernel::ops::Selection;
use crate::kernel::FaceId;
use crate::kernel::{Domain, LayerKind, Mesh};
use crate::rules::program::{Program, COLOR_LAYER, MATERIAL_LAYER, NO_MATERIAL, PART_LAYER};
use crate::rules::{property, random};
use glam::DVec3;

use super::properties::Context;
use super::run::{LazyProperties, Runner};

/// Adds the part and material layers (part 0, no material).
pub(super) fn ensure_layers(mesh: &mut Mesh) {
    for (name, domain, default) in [
        (PART_LAYER, Domain::Face, AttrValue::Int(0)),
        (PART_LAYER, Domain::Edge, AttrValue::Int(0)),
        (MATERIAL_LAYER, Domain::Face, AttrValue::Int(NO_MATERIAL)),
    ] {
        let _ = mesh.add_layer(name, domain, default);
    }
}

/// Gives a step's products its part and material (`looks`), where set.
pub(super) fn tag(mesh: &mut Mesh, made: &Selection, looks: (Option<u32>, Option<u32>)) {
    if let Some(part) = looks.0 {
        let part = AttrValue::Int(layer_int(part));
        for f in &made.faces {
            let _ = mesh.set_attr(PART_LAYER, Domain::Face, f.index(), part);
        }
        for e in &made.edges {
            let _ = mesh.set_attr(PART_LAYER, Domain::Edge, e.index(), part);
        }
    }
    if let Some(material) = looks.1 {
        let material = AttrValue::Int(layer_int(material));
        for f in &made.faces {
            let _ = mesh.set_attr(MATERIAL_LAYER, Domain::Face, f.index(), material);
        }
    }
}

/// The model as the writers take it: the kernel's canonical indexed view
/// with the parts that hold geometry (in the program's part order), the
/// materials they use (the program's order, graftal's fallback last),
/// shading normals where a part asks for them, texture coordinates where
/// a part has a projection, and double-sidedness decided.
pub fn export(program: &Program, mesh: &Mesh) -> IndexedMesh {
    let mut out = mesh.to_indexed_with_normals();
    let look = &program.look;
    // Wire edges are walked only when the export found some.
    let (mut face_parts, mut line_parts) = element_parts(program, mesh, !out.lines.is_empty());
    if face_parts.is_empty() && line_parts.is_empty() {
        return out;
    }

    // Parts with geometry, renumbered in the program's order.
    let mut used = vec![false; look.parts.len().max(1)];
    for &p in face_parts.iter().chain(&line_parts) {
        used[p as usize] = true;
    }
    let (kept, part_index) = renumber(&used);
    out.parts = kept.iter().map(|&p| part_name(program, p)).collect();
    line_parts
        .iter_mut()
        .for_each(|p| *p = part_index[*p as usize]);
    out.line_parts = line_parts;
    if face_parts.is_empty() {
        return out;
    }

    let fallback = look.materials.len();
    let material_of = |own: i32, part: u32| face_material(program, own, part);
    let mut face_materials: Vec<u32> =
        match uniform_int(mesh, MATERIAL_LAYER, Domain::Face, NO_MATERIAL) {
            Some(own) => face_parts.iter().map(|&p| material_of(own, p)).collect(),
            None => {
                let own_material = int_layer(mesh, MATERIAL_LAYER, Domain::Face, NO_MATERIAL);
                mesh.face_ids()
                    .zip(&face_parts)
                    .map(|(f, &p)| material_of(own_material(f.index()), p))
                    .collect()
            }
        };
    // Renumbered in place: the program's indices become the file's.
    face_parts
        .iter_mut()
        .for_each(|p| *p = part_index[*p as usize]);
    out.polygon_parts = face_parts;
    let mut used = vec![false; fallback + 1];
    for &m in &face_materials {
        used[m as usize] = true;
    }
    let (kept_materials, material_index) = renumber(&used);
    out.materials = kept_materials
        .iter()
        .map(|&m| material(program, m))
        .collect();
    face_materials
        .iter_mut()
        .for_each(|m| *m = material_index[*m as usize]);
    out.polygon_materials = face_materials;

    // Per out-part settings.
    let setting = |k: &usize| look.parts.get(*k);
    let creases: Vec<f64> = kept
        .iter()
        .map(|k| setting(k).map_or(0.0, |p| p.crease))
        .collect();
    if creases.iter().any(|&c| c > 0.0) {
        out.corner_normals = normals::mesh_corner_normals(&out, &creases);
    }
    let mappings: Vec<Option<UvMapping>> =
        kept.iter().map(|k| setting(k).and_then(|p| p.uv)).collect();
    if mappings.iter().any(Option::is_some) {
        out.corner_uvs = uv::project(&out, &mappings);
    }
    // Surface parameters are the tessellations' bookkeeping, not scalars
    // the files should carry: they leave as texture coordinates only.
    out.vertex_scalars
        .retain(|(name, _)| name != uv::SURFACE_U && name != uv::SURFACE_V);
    if let Some(layer) = mesh.attributes().layer(COLOR_LAYER, Domain::Face) {
        let mut colors = Vec::with_capacity(out.face_indices.len());
        for (k, f) in mesh.face_ids().enumerate() {
            let c = match layer.get(f.index()) {
                AttrValue::Vector(c) => c.to_array().map(|x| x.clamp(0.0, 1.0)),
                _ => [1.0; 3],
            };
            let corners = out.face_starts[k + 1] - out.face_starts[k];
            colors.extend(std::iter::repeat_n(c, corners as usize));
        }
        out.corner_colors = colors;
        // COLOR_0 multiplies the base colour: the fallback turns white so
        // the colours show as computed.
        for m in out
            .materials
            .iter_mut()
            .filter(|m| m.name == Material::fallback().name)
        {
            m.base_color = [1.0; 4];
        }
    }
    out.decide_double_sided();
    out
}

/// What [`export`] would give with its geometry left out, when that is
/// all a writer needs besides the kernel mesh itself
/// ([`crate::io::encode_streamed`] reads the polygons from
/// [`Mesh::canonical_view`]): every face in one part and one material,
/// flat-shaded (no crease angle), without texture coordinates, colours,
/// wire edges or vertex scalars to write. `None` otherwise, or for a mesh
/// without faces.
pub fn export_look(program: &Program, mesh: &Mesh) -> Option<IndexedMesh> {
    let look = &program.look;
    let part = uniform_int(mesh, PART_LAYER, Domain::Face, 0)?;
    let own = uniform_int(mesh, MATERIAL_LAYER, Domain::Face, NO_MATERIAL)?;
    let part = part_index(program, part) as usize;
    let plain = look
        .parts
        .get(part)
        .is_none_or(|p| p.crease <= 0.0 && p.uv.is_none());
    let scalars = mesh.attributes().layers().iter().any(|layer| {
        layer.domain == Domain::Vert
            && layer.kind() == LayerKind::Scalar
            && layer.name != uv::SURFACE_U
            && layer.name != uv::SURFACE_V
    });
    if !plain
        || scalars
        || mesh.face_count() == 0
        || mesh.attributes().layer(COLOR_LAYER, Domain::Face).is_some()
        || mesh.edge_ids().any(|e| mesh.is_wire_edge(e))
    {
        return None;
    }
    let mut out = IndexedMesh::new();
    out.parts = vec![part_name(program, part)];
    let mut material = material(program, face_material(program, own, part as u32) as usize);
    // One material on every face: double-sided exactly where the faces
    // leave a border (as `decide_double_sided` settles it).
    if material.double_sided.is_none() {
        material.double_sided = Some(!mesh.faces_on_closed_shells());
    }
    out.materials = vec![material];
    Some(out)
}

/// A part layer value as an index into the program's parts (an unknown
/// one is the first part).
fn part_index(program: &Program, v: i32) -> u32 {
    let parts = program.look.parts.len();
    usize::try_from(v).ok().filter(|&p| p < parts).unwrap_or(0) as u32
}

/// The name of the program's part `p` (`model` for the implicit one).
fn part_name(program: &Program, p: usize) -> String {
    program
        .look
        .parts
        .get(p)
        .map_or_else(|| "model".to_owned(), |part| part.name.clone())
}

/// A face's material (an index into the program's materials, one past
/// them for the fallback): the step's (`own`), else its part's, else the
/// fallback.
fn face_material(program: &Program, own: i32, part: u32) -> u32 {
    let look = &program.look;
    usize::try_from(own)
        .ok()
        .filter(|&m| m < look.materials.len())
        .or_else(|| {
            look.parts
                .get(part as usize)
                .and_then(|part| part.material)
                .map(|m| m as usize)
        })
        .unwrap_or(look.materials.len()) as u32
}

/// The program's material `m`, or the fallback one past them.
fn material(program: &Program, m: usize) -> Material {
    program
        .look
        .materials
        .get(m)
        .cloned()
        .unwrap_or_else(Material::fallback)
}

/// A part or material index as an integer layer value. Indices count the
/// rule file's parts and materials, far below `i32::MAX`.
fn layer_int(index: u32) -> i32 {
    i32::try_from(index).unwrap_or(i32::MAX)
}

/// Drops the layers [`export`] does not read (the turtle frames and ages
/// of the G³ model, any vector or integer layer besides part, material and
/// colour), for a caller that exports the mesh and then discards it: the
/// export's indexed mesh then grows into memory the frames held (at 10⁶ G³
/// primitives, 45 MB of the peak). The export's result is unchanged.
pub fn drop_unexported_layers(mesh: &mut Mesh) {
    let unread: Vec<(String, Domain)> = mesh
        .attributes()
        .layers()
        .iter()
        .filter(|l| {
            let scalar_of_vertex = l.domain == Domain::Vert && l.kind() == LayerKind::Scalar;
            let look = [PART_LAYER, MATERIAL_LAYER, COLOR_LAYER].contains(&l.name.as_str())
                && l.domain != Domain::Vert;
            !(scalar_of_vertex || look)
        })
        .map(|l| (l.name.clone(), l.domain))
        .collect();
    for (name, domain) in unread {
        mesh.remove_layer(&name, domain);
    }
}

/// Reads an integer layer: looked up once (not per element), `default`
/// where the layer or the value is missing.
pub(super) fn int_layer<'m>(
    mesh: &'m Mesh,
    name: &str,
    domain: Domain,
    default: i32,
) -> impl Fn(usize) -> i32 + 'm {
    let layer = mesh.attributes().layer(name, domain);
    move |index| match layer.map(|l| l.get(index)) {
        Some(AttrValue::Int(v)) => v,
        _ => default,
    }
}

/// The value [`int_layer`] reads for every element, when it is the same
/// for all: the layer is missing or stores no value (so every slot reads
/// its default). Spares a walk of the elements.
fn uniform_int(mesh: &Mesh, name: &str, domain: Domain, default: i32) -> Option<i32> {
    match mesh.attributes().layer(name, domain) {
        None => Some(default),
        Some(layer) if layer.is_empty() => match layer.default {
            AttrValue::Int(v) => Some(v),
            _ => Some(default),
        },
        Some(_) => None,
    }
}

/// The part (index into the program's parts) of every face and, with
/// `lines`, of every wire edge, in the kernel's canonical export order.
fn element_parts(program: &Program, mesh: &Mesh, lines: bool) -> (Vec<u32>, Vec<u32>) {
    let part_of = |v: i32| part_index(program, v);
    let faces = match uniform_int(mesh, PART_LAYER, Domain::Face, 0) {
        Some(v) => vec![part_of(v); mesh.face_count()],
        None => {
            let face_part = int_layer(mesh, PART_LAYER, Domain::Face, 0);
            mesh.face_ids()
                .map(|f| part_of(face_part(f.index())))
                .collect()
        }
    };
    let lines = if lines {
        let edge_part = int_layer(mesh, PART_LAYER, Domain::Edge, 0);
        mesh.edge_ids()
            .filter(|&e| mesh.is_wire_edge(e))
            .map(|e| part_of(edge_part(e.index())))
            .collect()
    } else {
        Vec::new()
    };
    (faces, lines)
}

/// How many faces and wire edges one part holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PartCount {
    pub name: String,
    pub faces: usize,
    pub wire_edges: usize,
}

/// Element counts of the parts that hold any, in the program's part
/// order (the stats' `parts`).
pub fn part_counts(program: &Program, mesh: &Mesh) -> Vec<PartCount> {
    let (faces, lines) = element_parts(program, mesh, true);
    let mut counts: Vec<PartCount> = (0..program.look.parts.len().max(1))
        .map(|p| PartCount {
            name: program
                .look
                .parts
                .get(p)
                .map_or_else(|| "model".to_owned(), |part| part.name.clone()),
            faces: 0,
            wire_edges: 0,
        })
        .collect();
    for p in faces {
        counts[p as usize].faces += 1;
    }
    for p in lines {
        counts[p as usize].wire_edges += 1;
    }
    counts.retain(|c| c.faces + c.wire_edges > 0);
    counts
}

/// The indices marked `used`, in order, and each index's new number
/// (`u32::MAX` for unused ones).
fn renumber(used: &[bool]) -> (Vec<usize>, Vec<u32>) {
    let mut kept = Vec::new();
    let mut index = vec![u32::MAX; used.len()];
    for (i, _) in used.iter().enumerate().filter(|(_, &u)| u) {
        index[i] = kept.len() as u32;
        kept.push(i);
    }
    (kept, index)
}

/// The colour pass, run once the steps end.
impl Runner<'_> {
    /// Evaluates each face's part's colour expression on the finished
    /// model into the colour layer (issue 16; nothing when no part has
    /// one). Channels are clamped into [0, 1] (hue wraps) and read as
    /// sRGB; the layer holds linear RGB, as glTF's COLOR_0 does.
    pub(super) fn paint(&mut self, mesh: &mut Mesh) {
        let look = &self.program.look;
        if look.colors.is_empty() {
            return;
        }
        let stream = random::stream_key("color");
        let generation = self.program.step_count as u32 + 1;
        let base = self.program.param_names.len();
        let faces: Vec<FaceId> = mesh.face_ids().collect();
        let mut painted = Vec::with_capacity(faces.len());
        let part_of = super::asset::int_layer(mesh, PART_LAYER, Domain::Face, 0);
        for &f in &faces {
            let part = usize::try_from(part_of(f.index())).unwrap_or(0);
            let Some(spec) = look
                .parts
                .get(part)
                .and_then(|p| p.color)
                .map(|c| &look.colors[c as usize])
            else {
                painted.push(None);
                continue;
            };
            let ctx = Context {
                mesh,
                scope: None,
                seed: self.seed,
                stream,
                generation,
            };
            let mut source = LazyProperties {
                params: &self.slots[..base],
                ctx: &ctx,
                domain: Domain::Face,
                index: f.index(),
                values: [0.0; property::SLOT_COUNT],
                known: 0,
            };
            let [a, b, c] = [0, 1, 2].map(|k| spec.channels[k].expr.eval_with(&mut source));
            self.evaluations += 3;
            let srgb = if spec.hsv {
                hsv_to_rgb(a, b, c)
            } else {
                [a, b, c].map(unit)
            };
            painted.push(Some(DVec3::from_array(srgb.map(srgb_to_linear))));
        }
        drop(part_of);
        let _ = mesh.add_layer(COLOR_LAYER, Domain::Face, AttrValue::Vector(DVec3::ONE));
        for (f, color) in faces.into_iter().zip(painted) {
            if let Some(color) = color {
                let _ = mesh.set_attr(
                    COLOR_LAYER,
                    Domain::Face,
                    f.index(),
                    AttrValue::Vector(color),
                );
            }
        }
    }
}

/// `x` clamped into [0, 1]; NaN → 0.
fn unit(x: f64) -> f64 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(0.0, 1.0)
    }
}

/// HSV (hue in turns, wrapping; saturation and value clamped) to RGB.
fn hsv_to_rgb(h: f64, s: f64, v: f64) -> [f64; 3] {
    let h = if h.is_finite() { h - h.floor() } else { 0.0 };
    let (s, v) = (unit(s), unit(v));
    let sector = h * 6.0;
    let i = (sector.floor() as usize).min(5);
    let f = sector - i as f64;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    match i {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    }
}

#[cfg(test)]
mod color_tests {
    use super::hsv_to_rgb;

    #[test]
    fn hsv_primaries_and_wrap() {
        assert_eq!(hsv_to_rgb(0.0, 1.0, 1.0), [1.0, 0.0, 0.0]);
        assert_eq!(hsv_to_rgb(1.0 / 3.0, 1.0, 1.0)[1], 1.0);
        assert_eq!(hsv_to_rgb(2.0 / 3.0, 1.0, 1.0)[2], 1.0);
        assert_eq!(hsv_to_rgb(1.25, 0.0, 0.5), [0.5; 3]);
        assert_eq!(hsv_to_rgb(f64::NAN, 2.0, -1.0), [0.0; 3]);
    }
}
