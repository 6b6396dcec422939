//! [`IndexedMesh`]: the neutral polygon soup that every reader produces and every writer
//! consumes, plus the shared helpers the formats use (validation, per-polygon triangulation and
//! first-appearance vertex merging).
//!
//! Polygons are stored flat: polygon `k` is `face_indices[face_starts[k]..face_starts[k + 1]]`.
//! An empty mesh has `face_starts == [0]`; `IndexedMesh::default()` (with `face_starts` empty) is
//! accepted as an empty mesh too.

use std::collections::HashMap;

use glam::DVec3;

use super::cells::{CellLists, Cells, NONE};
use super::material::Material;
use super::polygon;

/// Why an [`IndexedMesh`] cannot be written.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// A vertex has a NaN or infinite coordinate.
    #[error("cannot write mesh: vertex {vertex} has a non-finite coordinate")]
    NonFinite { vertex: usize },
    /// A vertex scalar is NaN or infinite.
    #[error("cannot write mesh: vertex scalar {name:?} is not finite at vertex {vertex}")]
    NonFiniteScalar { name: String, vertex: usize },
    /// A coordinate does not fit the format's number type.
    #[error("cannot write {format}: vertex {vertex} coordinate {value:e} does not fit an f32")]
    OutOfRange {
        vertex: usize,
        value: f64,
        format: &'static str,
    },
    /// The storage is inconsistent or exceeds a limit.
    #[error("cannot write mesh: {message}")]
    Invalid { message: String },
}

/// A format-neutral indexed polygon mesh.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IndexedMesh {
    /// Vertex positions.
    pub positions: Vec<[f64; 3]>,
    /// Flat polygon storage: polygon k uses `face_indices[face_starts[k]..face_starts[k + 1]]`.
    /// Has `polygon_count() + 1` entries and starts with 0 (`[0]` when there are no polygons).
    pub face_starts: Vec<u32>,
    /// Vertex indices of all polygons, concatenated.
    pub face_indices: Vec<u32>,
    /// Wire edges (edges with no face), written as line primitives.
    pub lines: Vec<[u32; 2]>,
    /// Named per-vertex scalar attributes, sorted by name, each with `positions.len()` values
    /// (e.g. `"radius"`). Names are ASCII letters, digits and `_`.
    pub vertex_scalars: Vec<(String, Vec<f64>)>,
    /// Part names (glTF nodes, OBJ groups, PLY's `part`), unique; empty:
    /// one unnamed part.
    pub parts: Vec<String>,
    /// Part of each polygon (index into `parts`); empty when `parts` is.
    pub polygon_parts: Vec<u32>,
    /// Part of each line (index into `parts`); empty when `parts` is.
    pub line_parts: Vec<u32>,
    /// Materials, unique by name.
    pub materials: Vec<Material>,
    /// Material of each polygon (index into `materials`); empty when
    /// `materials` is (the format's default material).
    pub polygon_materials: Vec<u32>,
    /// Unit shading normal of each polygon corner, aligned with
    /// `face_indices`; empty: flat shading (each polygon's own normal).
    pub corner_normals: Vec<[f64; 3]>,
    /// Texture coordinates of each corner, aligned with `face_indices`;
    /// empty: none.
    pub corner_uvs: Vec<[f64; 2]>,
    /// Linear RGB colour of each corner (components in [0, 1]), aligned
    /// with `face_indices`; empty: none.
    pub corner_colors: Vec<[f64; 3]>,
    /// Unit normal of each polygon as its producer stored it (the kernel's
    /// stored face normals, fresh by construction: the same bits as
    /// `polygon::unit_normal` of the polygon's corners), zero where the
    /// polygon is degenerate. Empty, or not one per polygon (polygons
    /// added since): writers compute flat normals themselves.
    pub polygon_normals: Vec<[f64; 3]>,
}

impl IndexedMesh {
    /// An empty mesh (`face_starts == [0]`).
    pub fn new() -> Self {
        IndexedMesh {
            face_starts: vec![0],
            ..Default::default()
        }
    }

    /// Appends a polygon given by vertex indices.
    ///
    /// # Panics
    /// Panics if the total number of polygon indices would exceed `u32::MAX`.
    pub fn push_polygon(&mut self, indices: &[u32]) {
        if self.face_starts.is_empty() {
            self.face_starts.push(0);
        }
        self.face_indices.extend_from_slice(indices);
        let end = u32::try_from(self.face_indices.len()).expect("more than u32::MAX indices");
        self.face_starts.push(end);
    }

    /// Number of polygons.
    pub fn polygon_count(&self) -> usize {
        self.face_starts.len().saturating_sub(1)
    }

    /// Vertex indices of polygon `k`.
    ///
    /// # Panics
    /// Panics if `k >= polygon_count()` or the storage is malformed (see [`Self::validate`]).
    pub fn polygon(&self, k: usize) -> &[u32] {
        let start = self.face_starts[k] as usize;
        let end = self.face_starts[k + 1] as usize;
        &self.face_indices[start..end]
    }

    /// Iterator over all polygons in order.
    ///
    /// # Panics
    /// The iterator panics on malformed storage (see [`Self::validate`]).
    pub fn polygons(&self) -> impl ExactSizeIterator<Item = &[u32]> + Clone + '_ {
        self.face_starts
            .windows(2)
            .map(|w| &self.face_indices[w[0] as usize..w[1] as usize])
    }

    /// Position of vertex `i` as a `DVec3`.
    pub fn position(&self, i: u32) -> DVec3 {
        DVec3::from_array(self.positions[i as usize])
    }

    /// Values of the vertex scalar called `name`, if present.
    pub fn vertex_scalar(&self, name: &str) -> Option<&[f64]> {
        self.vertex_scalars
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }

    /// Checks everything the writers rely on: polygon storage, polygon sizes (at least 3),
    /// index ranges, finite positions, and scalar names, lengths and values.
    pub fn validate(&self) -> Result<(), MeshError> {
        let invalid = |message: String| Err(MeshError::Invalid { message });
        let count = self.positions.len();
        if u32::try_from(count).is_err() {
            return invalid(format!("{count} vertices exceed the u32 index range"));
        }
        for (vertex, p) in self.positions.iter().enumerate() {
            if !p.iter().all(|c| c.is_finite()) {
                return Err(MeshError::NonFinite { vertex });
            }
        }
        let starts = &self.face_starts;
        let storage_ok = if starts.is_empty() {
            self.face_indices.is_empty()
        } else {
            starts[0] == 0
                && starts.windows(2).all(|w| w[0] <= w[1])
                && starts[starts.len() - 1] as usize == self.face_indices.len()
        };
        if !storage_ok {
            return invalid(format!(
                "face_starts must start at 0, never decrease and end at face_indices.len() \
                 ({} entries, {} indices)",
                starts.len(),
                self.face_indices.len()
            ));
        }
        // Linear scans first; only a mesh that fails one looks for the first
        // polygon at fault (to name it).
        let sizes_ok = starts
            .windows(2)
            .fold(true, |ok, w| ok & (w[1] - w[0] >= 3));
        let indices_ok = self
            .face_indices
            .iter()
            .max()
            .is_none_or(|&v| (v as usize) < count);
        if !(sizes_ok && indices_ok) {
            for (k, poly) in self.polygons().enumerate() {
                if poly.len() < 3 {
                    return invalid(format!(
                        "polygon {k} has {} vertices (at least 3 required)",
                        poly.len()
                    ));
                }
                if let Some(&v) = poly.iter().find(|&&v| v as usize >= count) {
                    return invalid(format!(
                        "polygon {k} refers to vertex {v} but only {count} exist"
                    ));
                }
            }
        }
        for (k, line) in self.lines.iter().enumerate() {
            if let Some(&v) = line.iter().find(|&&v| v as usize >= count) {
                return invalid(format!(
                    "line {k} refers to vertex {v} but only {count} exist"
                ));
            }
        }
        for (i, (name, values)) in self.vertex_scalars.iter().enumerate() {
            let name_ok = !name.is_empty()
                && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_')
                && !["x", "y", "z"].iter().any(|r| name.eq_ignore_ascii_case(r));
            if !name_ok {
                return invalid(format!(
                    "vertex scalar name {name:?} must be non-empty ASCII letters, digits or '_' \
                     and not x, y or z"
                ));
            }
            if let Some((other, _)) = self.vertex_scalars[..i]
                .iter()
                .find(|(other, _)| other.eq_ignore_ascii_case(name))
            {
                return invalid(format!(
                    "vertex scalar names {other:?} and {name:?} collide (names are compared \
                     case-insensitively)"
                ));
            }
            if values.len() != count {
                return invalid(format!(
                    "vertex scalar {name:?} has {} values for {count} vertices",
                    values.len()
                ));
            }
            if let Some(vertex) = values.iter().position(|v| !v.is_finite()) {
                return Err(MeshError::NonFiniteScalar {
                    name: name.clone(),
                    vertex,
                });
            }
        }
        self.validate_looks()
    }

    /// The part, material and per-corner checks of [`Self::validate`].
    fn validate_looks(&self) -> Result<(), MeshError> {
        let invalid = |message: String| Err(MeshError::Invalid { message });
        let polygons = self.polygon_count();
        let unique = |names: &mut dyn Iterator<Item = &str>, what: &str| {
            let mut seen: Vec<&str> = names.collect();
            for name in &seen {
                if !Material::valid_name(name) {
                    return invalid(format!(
                        "{what} name {name:?} must be 1 to 64 ASCII letters, digits, '_', '-' or '.'"
                    ));
                }
            }
            seen.sort_unstable();
            match seen.windows(2).find(|w| w[0] == w[1]) {
                Some(w) => invalid(format!("{what} name {:?} is used twice", w[0])),
                None => Ok(()),
            }
        };
        unique(&mut self.parts.iter().map(String::as_str), "part")?;
        unique(
            &mut self.materials.iter().map(|m| m.name.as_str()),
            "material",
        )?;
        let table = |values: &[u32], expect: usize, of: usize, what: &str, table: &str| {
            if of == 0 {
                return if values.is_empty() {
                    Ok(())
                } else {
                    invalid(format!("{what} are given but there are no {table}"))
                };
            }
            if values.len() != expect {
                return invalid(format!("{} {what} for {expect} elements", values.len()));
            }
            match values.iter().find(|&&v| v as usize >= of) {
                Some(v) => invalid(format!("{what}: {v} is past the {of} {table}")),
                None => Ok(()),
            }
        };
        table(
            &self.polygon_parts,
            polygons,
            self.parts.len(),
            "polygon parts",
            "parts",
        )?;
        table(
            &self.line_parts,
            self.lines.len(),
            self.parts.len(),
            "line parts",
            "parts",
        )?;
        table(
            &self.polygon_materials,
            polygons,
            self.materials.len(),
            "polygon materials",
            "materials",
        )?;
        for m in &self.materials {
            let unit = |x: f64| (0.0..=1.0).contains(&x);
            let cutoff_ok = match m.alpha {
                super::material::AlphaMode::Mask(c) => unit(c),
                _ => true,
            };
            if !(m.base_color.iter().all(|&c| unit(c))
                && m.emissive.iter().all(|&c| unit(c))
                && unit(m.metallic)
                && unit(m.roughness)
                && cutoff_ok)
            {
                return invalid(format!(
                    "material {:?} has a colour, factor or cutoff outside [0, 1]",
                    m.name
                ));
            }
        }
        let corners = self.face_indices.len();
        let per_corner = |len: usize, what: &str| {
            if len != 0 && len != corners {
                invalid(format!("{len} corner {what} for {corners} corners"))
            } else {
                Ok(())
            }
        };
        per_corner(self.corner_normals.len(), "normals")?;
        per_corner(self.corner_uvs.len(), "texture coordinates")?;
        per_corner(self.corner_colors.len(), "colours")?;
        if let Some(k) = self.corner_normals.iter().position(|n| {
            let len2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
            !(len2 - 1.0).abs().le(&1e-6)
        }) {
            return invalid(format!("corner normal {k} is not a unit vector"));
        }
        if let Some(k) = self
            .corner_uvs
            .iter()
            .position(|t| !t.iter().all(|c| c.is_finite()))
        {
            return invalid(format!("corner texture coordinate {k} is not finite"));
        }
        if let Some(k) = self
            .corner_colors
            .iter()
            .position(|c| !c.iter().all(|x| (0.0..=1.0).contains(x)))
        {
            return invalid(format!("corner colour {k} is outside [0, 1]"));
        }
        Ok(())
    }

    /// Part of polygon `k` (0 when the mesh has no parts).
    pub fn polygon_part(&self, k: usize) -> u32 {
        self.polygon_parts.get(k).copied().unwrap_or(0)
    }

    /// Part of line `k` (0 when the mesh has no parts).
    pub fn line_part(&self, k: usize) -> u32 {
        self.line_parts.get(k).copied().unwrap_or(0)
    }

    /// Material of polygon `k`, if the mesh has materials.
    pub fn polygon_material(&self, k: usize) -> Option<u32> {
        self.polygon_materials.get(k).copied()
    }

    /// Polygons grouped by (part, material), each group in mesh order:
    /// `(order, starts)` where group `part * materials + material` (with
    /// `materials = self.materials.len().max(1)`) is
    /// `order[starts[g]..starts[g + 1]]` (a counting sort: linear,
    /// deterministic). What the writers emit part by part.
    pub fn polygon_groups(&self) -> (Vec<u32>, Vec<usize>) {
        let materials = self.materials.len().max(1);
        let key = |k: usize| {
            self.polygon_part(k) as usize * materials
                + self.polygon_material(k).unwrap_or(0) as usize
        };
        let groups = self.part_count() * materials;
        let mut start = vec![0usize; groups + 1];
        for k in 0..self.polygon_count() {
            start[key(k) + 1] += 1;
        }
        for i in 0..groups {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut order = vec![0u32; self.polygon_count()];
        for k in 0..self.polygon_count() {
            let g = key(k);
            order[fill[g]] = k as u32;
            fill[g] += 1;
        }
        (order, start)
    }

    /// Number of parts a writer emits: at least one when there is geometry.
    pub fn part_count(&self) -> usize {
        self.parts.len().max(1)
    }

    /// Settles every material whose double-sidedness is undecided: single-
    /// sided when every polygon using it lies on a closed, consistently
    /// oriented shell (back faces are never seen; docs/rules.md,
    /// "Materials"), double-sided otherwise. A material's faces need not
    /// close on their own: a cottage's roof material covers part of a
    /// closed shell.
    pub fn decide_double_sided(&mut self) {
        if self.materials.iter().all(|m| m.double_sided.is_some()) {
            return;
        }
        let decided = self.double_sided_decided();
        for (material, double) in self.materials.iter_mut().zip(decided) {
            material.double_sided = Some(double);
        }
    }

    /// Each material's double-sidedness: as set, else decided as
    /// [`Self::decide_double_sided`] does (a writer given a mesh read from a
    /// file that does not say, such as OBJ, decides the same way).
    pub fn double_sided_decided(&self) -> Vec<bool> {
        let set: Vec<Option<bool>> = self.materials.iter().map(|m| m.double_sided).collect();
        if set.iter().all(Option::is_some) {
            return set.into_iter().flatten().collect();
        }
        let count = self.materials.len();
        let mut faces = vec![0usize; count];
        for k in 0..self.polygon_count() {
            if let Some(m) = self.polygon_material(k) {
                faces[m as usize] += 1;
            }
        }
        // One material on every face (the common case): its shells are the
        // whole mesh, and a border anywhere (almost surely an unbalanced
        // quick sum) settles it in one pass without building shells.
        if faces.iter().any(|&f| f == self.polygon_count() && f > 0) {
            let sum = self
                .polygons()
                .fold(0u64, |sum, poly| sum.wrapping_add(reversal_sum(poly)));
            if sum != 0 {
                return set.iter().map(|d| d.unwrap_or(true)).collect();
            }
        }
        let closed = self.polygons_on_closed_shells();
        let mut open = vec![false; count];
        for (k, &closed) in closed.iter().enumerate() {
            if let Some(m) = self.polygon_material(k) {
                open[m as usize] |= !closed;
            }
        }
        set.iter()
            .enumerate()
            .map(|(index, d)| d.unwrap_or(faces[index] == 0 || open[index]))
            .collect()
    }

    /// Per polygon, whether its shell (the polygons connected to it through
    /// shared edges) is closed and consistently oriented: every edge of it
    /// is used as often one way as the other, so the shell bounds a volume
    /// (two boxes meeting along an edge included). A degenerate edge opens
    /// its shell. Edges are filed under their lower vertex (a counting
    /// sort), each vertex's few sorted by their upper one: near-linear.
    pub(crate) fn polygons_on_closed_shells(&self) -> Vec<bool> {
        fn edges(poly: &[u32]) -> impl Iterator<Item = (u32, u32)> + '_ {
            let last = *poly.last().unwrap_or(&0);
            poly.iter()
                .scan(last, |a, &b| Some((std::mem::replace(a, b), b)))
        }
        let polygons = self.polygon_count();
        let mut start = vec![0u32; self.positions.len() + 1];
        for poly in self.polygons() {
            for (a, b) in edges(poly).filter(|(a, b)| a != b) {
                start[a.min(b) as usize + 1] += 1;
            }
        }
        for v in 1..start.len() {
            start[v] += start[v - 1];
        }
        // (upper vertex, polygon, written lower → upper) per edge use.
        let mut uses = vec![(0u32, 0u32, false); *start.last().unwrap_or(&0) as usize];
        let mut fill = start.clone();
        let mut open = vec![false; polygons];
        for (k, poly) in self.polygons().enumerate() {
            for (a, b) in edges(poly) {
                if a == b {
                    open[k] = true;
                    continue;
                }
                let slot = &mut fill[a.min(b) as usize];
                uses[*slot as usize] = (a.max(b), k as u32, a < b);
                *slot += 1;
            }
        }
        let mut shells = super::union_find::UnionFind::new(polygons);
        for v in 0..self.positions.len() {
            let bucket = &mut uses[start[v] as usize..start[v + 1] as usize];
            bucket.sort_unstable();
            for edge in bucket.chunk_by(|x, y| x.0 == y.0) {
                let forward = edge.iter().filter(|u| u.2).count();
                if 2 * forward != edge.len() {
                    open[edge[0].1 as usize] = true;
                }
                for u in &edge[1..] {
                    shells.union(edge[0].1, u.1);
                }
            }
        }
        let mut open_shell = vec![false; polygons];
        for k in 0..polygons as u32 {
            if open[k as usize] {
                open_shell[shells.find(k) as usize] = true;
            }
        }
        (0..polygons as u32)
            .map(|k| !open_shell[shells.find(k) as usize])
            .collect()
    }

    /// Vertex scalars in name order, whatever order they are stored in.
    pub(crate) fn sorted_scalars(&self) -> Vec<(&str, &[f64])> {
        let mut sorted: Vec<(&str, &[f64])> = self
            .vertex_scalars
            .iter()
            .map(|(n, v)| (n.as_str(), v.as_slice()))
            .collect();
        sorted.sort_by(|a, b| a.0.cmp(b.0));
        sorted
    }
}

/// A necessary condition for a closed, oriented surface, in one pass without
/// allocating: on a closed, consistently oriented surface each half-edge
/// a → b meets its reverse b → a, so a sum of a hash of each edge, signed
/// by its direction, cancels. A border (every open sheet) almost surely
/// leaves it unbalanced.
#[cfg(test)]
fn reversal_balanced<'a>(polygons: impl Iterator<Item = &'a [u32]>) -> bool {
    polygons.fold(0u64, |sum, poly| sum.wrapping_add(reversal_sum(poly))) == 0
}

/// One polygon's share of [`reversal_balanced`]'s sum: one hash per edge.
fn reversal_sum(poly: &[u32]) -> u64 {
    let mut sum = 0u64;
    let mut a = *poly.last().unwrap_or(&0);
    for &b in poly {
        let h = splitmix64(super::edge_key::directed(a.min(b), a.max(b)));
        // Negated (two's complement, without a branch) for b → a.
        let flip = u64::from(a > b).wrapping_neg();
        sum = sum.wrapping_add((h ^ flip).wrapping_sub(flip));
        a = b;
    }
    sum
}

/// SplitMix64's finalizer: a bijection on `u64` that scatters every bit.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Which axis points up in a file. graftal's kernel is Z-up; glTF is
/// always +Y up (its writer and reader convert); OBJ, PLY and STL are
/// written Z-up unless asked otherwise (`--up y`, which Blender's and
/// most engines' OBJ importers expect).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum UpAxis {
    Y,
    #[default]
    Z,
}

impl IndexedMesh {
    /// Every polygon triangulated in its plane, as indices into
    /// `positions`, polygon by polygon; a degenerate polygon gives none.
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let mut out = Vec::with_capacity(self.face_indices.len());
        let mut tri = PolygonTriangulator::default();
        for poly in self.polygons() {
            if tri.run(self, poly).is_some() {
                out.extend(tri.triangles.iter().map(|t| t.map(|k| poly[k as usize])));
            }
        }
        out
    }

    /// Turns a Z-up mesh into the Y-up frame: (x, y, z) → (x, z, −y), a
    /// rotation (handedness and winding are kept). Exact: only a swap and
    /// a negation.
    pub fn z_up_to_y_up(&mut self) {
        // `+ 0.0` keeps −0 out of the files (equal geometry, equal bytes).
        let turn = |p: &mut [f64; 3]| *p = [p[0], p[2], -p[1] + 0.0];
        self.positions.iter_mut().for_each(turn);
        self.corner_normals.iter_mut().for_each(turn);
        // A turned Newell sum is not the same bits as the sum of turned
        // corners: writers recompute.
        self.polygon_normals.clear();
    }

    /// The inverse of [`Self::z_up_to_y_up`]: (x, y, z) → (x, −z, y).
    pub fn y_up_to_z_up(&mut self) {
        let turn = |p: &mut [f64; 3]| *p = [p[0], -p[2] + 0.0, p[1]];
        self.positions.iter_mut().for_each(turn);
        self.corner_normals.iter_mut().for_each(turn);
        self.polygon_normals.clear();
    }

    /// The stored normal of polygon `k`, when the mesh carries one per
    /// polygon: `Some(None)` for a degenerate polygon.
    pub(crate) fn stored_normal(&self, k: usize) -> Option<Option<DVec3>> {
        if self.polygon_normals.len() != self.polygon_count() {
            return None;
        }
        let n = DVec3::from_array(self.polygon_normals[k]);
        Some((n != DVec3::ZERO).then_some(n))
    }

    /// A copy with vertices at most `distance` apart merged (`distance <=
    /// 0`: bitwise-equal positions only), for files that repeat a vertex
    /// per corner (OBJ and PLY written after a glTF import). Each vertex
    /// joins the first earlier vertex within `distance` that kept its own
    /// place (deterministic: the file's order decides); polygons lose
    /// repeated corners and those left with fewer than 3 go, as do lines
    /// of one vertex. Vertex scalars come from the kept vertex.
    pub fn welded(&self, distance: f64) -> IndexedMesh {
        let n = self.positions.len();
        let mut map: Vec<u32> = Vec::with_capacity(n);
        self.weld_map(distance, 1 << 16, |chunk| {
            map.extend_from_slice(chunk);
            true
        });
        // A vertex keeps its own place exactly when it is mapped to the
        // number of vertices kept before it.
        let mut kept: Vec<u32> = Vec::new();
        for (i, &m) in map.iter().enumerate() {
            if m as usize == kept.len() {
                kept.push(i as u32);
            }
        }
        let mut out = IndexedMesh::new();
        out.positions = kept.iter().map(|&i| self.positions[i as usize]).collect();
        out.vertex_scalars = self
            .vertex_scalars
            .iter()
            .map(|(name, values)| {
                (
                    name.clone(),
                    kept.iter().map(|&i| values[i as usize]).collect(),
                )
            })
            .collect();
        out.parts = self.parts.clone();
        out.materials = self.materials.clone();
        // Kept corners by their index in `face_indices`, so per-corner
        // values follow their corner.
        let mut corners: Vec<(u32, usize)> = Vec::new();
        for (k, poly) in self.polygons().enumerate() {
            let first = self.face_starts[k] as usize;
            if !welded_ring(poly, first, &map, &mut corners) {
                continue;
            }
            out.face_indices.extend(corners.iter().map(|c| c.0));
            out.face_starts.push(out.face_indices.len() as u32);
            let take = |from: &[[f64; 3]], to: &mut Vec<[f64; 3]>| {
                if !from.is_empty() {
                    to.extend(corners.iter().map(|c| from[c.1]));
                }
            };
            take(&self.corner_normals, &mut out.corner_normals);
            take(&self.corner_colors, &mut out.corner_colors);
            if !self.corner_uvs.is_empty() {
                out.corner_uvs
                    .extend(corners.iter().map(|c| self.corner_uvs[c.1]));
            }
            if !self.polygon_parts.is_empty() {
                out.polygon_parts.push(self.polygon_parts[k]);
            }
            if !self.polygon_materials.is_empty() {
                out.polygon_materials.push(self.polygon_materials[k]);
            }
        }
        for (k, l) in self.lines.iter().enumerate() {
            let l = l.map(|v| map[v as usize]);
            if l[0] != l[1] {
                out.lines.push(l);
                if !self.line_parts.is_empty() {
                    out.line_parts.push(self.line_parts[k]);
                }
            }
        }
        out
    }

    /// The weld of [`Self::welded`] as a map, streamed: `on_chunk` gets
    /// every vertex's index among the kept vertices, in vertex order, in
    /// chunks of `chunk` (the last one shorter), and stops the weld by
    /// returning `false`. A vertex keeps its own place exactly when it is
    /// mapped to the number of vertices kept before it.
    pub fn weld_map(&self, distance: f64, chunk: usize, mut on_chunk: impl FnMut(&[u32]) -> bool) {
        let n = self.positions.len();
        let chunk = chunk.clamp(1, n.max(1));
        let mut map: Vec<u32> = Vec::with_capacity(chunk);
        let mut flush = |map: &mut Vec<u32>, last: bool| {
            if map.len() == chunk || (last && !map.is_empty()) {
                let go_on = on_chunk(map);
                map.clear();
                go_on
            } else {
                true
            }
        };
        if distance > 0.0 && distance.is_finite() {
            // Each cell (geom::cells: 8 searched per point) lists the kept
            // vertices in it, newest first. How many cells the kept
            // vertices fill is unknown, so the table grows.
            let cells = Cells::for_distance(distance);
            let mut lists = CellLists::with_capacity(n, 0);
            // The kept positions in kept order, so a candidate costs one
            // load, not two dependent ones.
            let mut kept_at: Vec<DVec3> = Vec::new();
            let d2 = distance * distance;
            for p in &self.positions {
                let point = DVec3::from_array(*p);
                let (lo, hi) = cells.around(*p);
                let mut found = NONE;
                for cx in lo[0]..=hi[0] {
                    for cy in lo[1]..=hi[1] {
                        for cz in lo[2]..=hi[2] {
                            let mut j = lists.head([cx, cy, cz]);
                            while j != NONE {
                                // Lists run newest first: every later entry is lower.
                                if j < found && kept_at[j as usize].distance_squared(point) <= d2 {
                                    found = j;
                                }
                                j = lists.next(j);
                            }
                        }
                    }
                }
                let index = if found != NONE {
                    found
                } else {
                    kept_at.push(point);
                    lists.push(cells.of(*p))
                };
                map.push(index);
                if !flush(&mut map, false) {
                    return;
                }
            }
        } else {
            let mut exact: HashMap<[u64; 3], u32> = HashMap::new();
            for p in &self.positions {
                let bits = p.map(|c| (c + 0.0).to_bits());
                let next = exact.len() as u32;
                let index = *exact.entry(bits).or_insert(next);
                map.push(index);
                if !flush(&mut map, false) {
                    return;
                }
            }
        }
        flush(&mut map, true);
    }
}

/// Polygon `poly` (its first corner at `first` in `face_indices`) after
/// [`IndexedMesh::welded`]'s `map`: its corners as (kept vertex, corner
/// index), repeated neighbours (the closing pair too) made one. `false`
/// when fewer than 3 are left: the weld drops the polygon.
pub fn welded_ring(
    poly: &[u32],
    first: usize,
    map: &[u32],
    corners: &mut Vec<(u32, usize)>,
) -> bool {
    corners.clear();
    for (i, &v) in poly.iter().enumerate() {
        let w = map[v as usize];
        if corners.last().map(|c| c.0) != Some(w) {
            corners.push((w, first + i));
        }
    }
    while corners.len() > 1 && corners.first().map(|c| c.0) == corners.last().map(|c| c.0) {
        corners.pop();
    }
    corners.len() >= 3
}

/// Reusable buffers for triangulating a mesh polygon by polygon without allocating.
#[derive(Default)]
pub(crate) struct PolygonTriangulator {
    /// Positions of the current polygon.
    pub points: Vec<DVec3>,
    /// Triangles of the current polygon, as local indices into `points`.
    pub triangles: Vec<[u32; 3]>,
}

impl PolygonTriangulator {
    /// Loads `poly` (indices into `mesh.positions`) and triangulates it; returns the polygon's
    /// unit normal (`None` if degenerate).
    pub fn run(&mut self, mesh: &IndexedMesh, poly: &[u32]) -> Option<DVec3> {
        self.run_with(poly, |i| mesh.position(i))
    }

    /// [`Self::run`] with the positions given by `position`.
    pub fn run_with(&mut self, poly: &[u32], position: impl Fn(u32) -> DVec3) -> Option<DVec3> {
        self.points.clear();
        self.points.extend(poly.iter().map(|&i| position(i)));
        self.triangles.clear();
        polygon::triangulate_with_normal(&self.points, &mut self.triangles)
    }
}

/// Merges bitwise-equal positions (with `-0.0` treated as `0.0`), numbering vertices in order of
/// first appearance so the result does not depend on hashing.
#[derive(Default)]
pub(crate) struct VertexMerger {
    map: HashMap<[u64; 3], u32>,
    /// Positions in first-appearance order.
    pub positions: Vec<[f64; 3]>,
}

impl VertexMerger {
    /// Index of `p`, adding it if new; `None` once the u32 index range is exhausted.
    pub fn index(&mut self, p: [f64; 3]) -> Option<u32> {
        let p = p.map(|c| if c == 0.0 { 0.0 } else { c });
        let key = p.map(f64::to_bits);
        if let Some(&i) = self.map.get(&key) {
            return Some(i);
        }
        let i = u32::try_from(self.positions.len()).ok()?;
        if i == u32::MAX {
            return None;
        }
        self.map.insert(key, i);
        self.positions.push(p);
        Some(i)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An indexed mesh of `polys` over `vertices` points (positions unused).
    fn shells(vertices: usize, polys: &[&[u32]]) -> Vec<bool> {
        let mut m = IndexedMesh {
            positions: vec![[0.0; 3]; vertices],
            ..Default::default()
        };
        for p in polys {
            m.push_polygon(p);
        }
        m.polygons_on_closed_shells()
    }

    #[test]
    fn closed_shells_use_every_edge_as_often_each_way() {
        const TETRA: [[u32; 3]; 4] = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]];
        let tetra = |offset: u32| TETRA.map(|t| t.map(|v| v + offset));
        let (a, b) = (tetra(0), tetra(4));
        fn all(p: &[[u32; 3]]) -> Vec<&[u32]> {
            p.iter().map(|t| &t[..]).collect()
        }
        assert_eq!(shells(4, &all(&a)), vec![true; 4]);
        // The quick test never rejects a closed surface.
        assert!(reversal_balanced(a.iter().map(|p| &p[..])));
        // Open: a face missing (a border) opens only its own shell.
        let mut two: Vec<[u32; 3]> = a[..3].to_vec();
        two.extend(b);
        assert_eq!(
            shells(8, &all(&two)),
            [vec![false; 3], vec![true; 4]].concat()
        );
        assert!(!reversal_balanced(a[..3].iter().map(|p| &p[..])));
        // One face wound the other way.
        let mut flipped = a;
        flipped[0] = [0, 1, 2];
        assert_eq!(shells(4, &all(&flipped)), vec![false; 4]);
        // Two closed shells meeting along an edge (vertices 0 and 1 shared):
        // each edge is still used as often each way.
        let joined = [
            a,
            tetra(4).map(|t| t.map(|v| if v < 6 { v - 4 } else { v })),
        ]
        .concat();
        assert_eq!(shells(8, &all(&joined)), vec![true; 8]);
        // A degenerate edge opens its shell; no polygons, no shells.
        assert_eq!(shells(3, &[&[0, 1, 1, 2]]), vec![false]);
        assert!(shells(0, &[]).is_empty());
    }

    #[test]
    fn empty_meshes_are_valid() {
        let m = IndexedMesh::new();
        assert_eq!(m.face_starts, vec![0]);
        assert_eq!(m.polygon_count(), 0);
        m.validate().unwrap();
        let d = IndexedMesh::default();
        assert_eq!(d.polygon_count(), 0);
        assert_eq!(d.polygons().count(), 0);
        d.validate().unwrap();
    }

    #[test]
    fn push_and_iterate_polygons() {
        let mut m = IndexedMesh {
            positions: vec![[0.0; 3]; 5],
            ..Default::default()
        };
        m.push_polygon(&[0, 1, 2]);
        m.push_polygon(&[1, 2, 3, 4]);
        assert_eq!(m.face_starts, vec![0, 3, 7]);
        assert_eq!(m.polygon_count(), 2);
        assert_eq!(m.polygon(1), &[1, 2, 3, 4]);
        let all: Vec<&[u32]> = m.polygons().collect();
        assert_eq!(all, vec![&[0, 1, 2][..], &[1, 2, 3, 4][..]]);
        m.validate().unwrap();
    }

    #[test]
    fn validation_catches_each_problem() {
        let mut base = IndexedMesh::new();
        base.positions = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        base.push_polygon(&[0, 1, 2]);
        base.validate().unwrap();

        let mut m = base.clone();
        m.positions[1][2] = f64::NAN;
        assert!(matches!(
            m.validate(),
            Err(MeshError::NonFinite { vertex: 1 })
        ));

        let mut m = base.clone();
        m.push_polygon(&[0, 1]);
        let e = m.validate().unwrap_err().to_string();
        assert!(e.contains("polygon 1 has 2 vertices"), "{e}");

        let mut m = base.clone();
        m.push_polygon(&[0, 1, 7]);
        let e = m.validate().unwrap_err().to_string();
        assert!(e.contains("refers to vertex 7 but only 3 exist"), "{e}");

        let mut m = base.clone();
        m.lines.push([0, 3]);
        assert!(m.validate().is_err());

        let mut m = base.clone();
        m.face_starts = vec![0, 2];
        assert!(m.validate().is_err());

        let mut m = base.clone();
        m.vertex_scalars.push(("radius".into(), vec![1.0, 2.0]));
        assert!(m.validate().is_err());

        let mut m = base.clone();
        m.vertex_scalars.push(("bad name".into(), vec![1.0; 3]));
        assert!(m.validate().is_err());

        let mut m = base.clone();
        m.vertex_scalars.push(("Y".into(), vec![1.0; 3]));
        assert!(m.validate().is_err());

        let mut m = base.clone();
        m.vertex_scalars.push(("a".into(), vec![1.0; 3]));
        m.vertex_scalars.push(("A".into(), vec![1.0; 3]));
        assert!(m.validate().is_err());

        let mut m = base.clone();
        m.vertex_scalars
            .push(("r".into(), vec![1.0, f64::INFINITY, 0.0]));
        assert!(matches!(
            m.validate(),
            Err(MeshError::NonFiniteScalar { vertex: 1, .. })
        ));
    }

    #[test]
    fn merger_numbers_by_first_appearance() {
        let mut m = VertexMerger::default();
        assert_eq!(m.index([1.0, 2.0, 3.0]), Some(0));
        assert_eq!(m.index([0.0, 0.0, 0.0]), Some(1));
        assert_eq!(m.index([1.0, 2.0, 3.0]), Some(0));
        assert_eq!(m.index([-0.0, 0.0, -0.0]), Some(1));
        assert_eq!(m.positions.len(), 2);
    }
}
