//! The kernel's side of [`MeshSink`]: [`KernelBuilder`] turns emitted
//! geometry into kernel elements (through Euler operators only) and names
//! what it made; [`Mesh::emit`] hands a kernel mesh to any sink in
//! canonical order (vertices in id order, compacted; faces in id order,
//! each from its first loop; wire edges in id order; scalar vertex layers
//! in layer order), so equal meshes give equal buffers and writers equal
//! bytes.
//!
//! ```
//! use graftal::geom::IndexedMesh;
//! use graftal::kernel::build::mesh_from_indexed;
//!
//! let mut square = IndexedMesh::new();
//! square.positions = vec![[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
//! square.push_polygon(&[0, 1, 2, 3]);
//! let (mesh, report) = mesh_from_indexed(&square).unwrap();
//! assert_eq!((mesh.face_count(), report.degenerate_faces), (1, 0));
//! assert_eq!(mesh.to_indexed(), square);
//! ```

use glam::DVec3;

use super::attrs::{AttrValue, Layer, LayerKind};
use super::ids::{Domain, EdgeId, FaceId, VertId};
use super::mesh::Mesh;
use super::ops::Selection;
use crate::geom::indexed::welded_ring;
use crate::geom::sink::{Begin, MeshSink, SinkError};
use crate::geom::source::PolygonSource;
use crate::geom::IndexedMesh;

/// What was dropped while building kernel elements from emitted geometry.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ImportReport {
    /// Polygons with fewer than 3 distinct corners (degenerate input).
    pub degenerate_faces: usize,
}

/// Builds kernel elements into a mesh, fresh or not, from emitted
/// geometry. Polygons are cleaned of consecutive repeated corners; a
/// polygon that still repeats a corner is split into its simple loops;
/// loops under 3 corners are dropped and counted. Every vertex is new, so
/// every edge between them is too.
pub struct KernelBuilder<'m> {
    mesh: &'m mut Mesh,
    /// Emitted vertex index → kernel vertex.
    verts: Vec<VertId>,
    scalars: Vec<String>,
    faces: Vec<FaceId>,
    lines: Vec<EdgeId>,
    polygons_seen: usize,
    report: ImportReport,
    ring: Vec<VertId>,
    /// Every edge the faces use, in the order they were first used.
    face_edges: Vec<EdgeId>,
    /// `faces[..settled]` have their stored normals.
    settled: usize,
}

impl<'m> KernelBuilder<'m> {
    pub fn new(mesh: &'m mut Mesh) -> Self {
        KernelBuilder {
            mesh,
            verts: Vec::new(),
            scalars: Vec::new(),
            faces: Vec::new(),
            lines: Vec::new(),
            polygons_seen: 0,
            report: ImportReport::default(),
            ring: Vec::new(),
            face_edges: Vec::new(),
            settled: 0,
        }
    }

    /// What the emission made (ids ascending) and what it dropped.
    pub fn finish(mut self) -> (Selection, ImportReport) {
        self.settle_normals();
        // Every vertex is new, so every edge of a new face is too; the faces listed the edges
        // in the order they were first used, which is the order they were made (ascending ids
        // unless freed slots were reused), so normalizing is one linear pass.
        let mut edges = std::mem::take(&mut self.face_edges);
        edges.extend(&self.lines);
        let made = Selection::from_parts(self.verts, edges, self.faces);
        (made, self.report)
    }

    /// The stored normals of the faces made since the last call, in one
    /// pass (faces are made with the normal left for it: see
    /// [`Mesh::make_face_of_clean_ring`]).
    fn settle_normals(&mut self) {
        let fresh = &self.faces[self.settled..];
        self.mesh.refresh_normals_of(fresh);
        self.settled = self.faces.len();
    }
}

impl MeshSink for KernelBuilder<'_> {
    fn begin(&mut self, begin: &Begin) -> Result<(), SinkError> {
        for name in begin.scalars {
            // A same-named layer of another kind stays; values then do not land.
            let _ = self
                .mesh
                .add_layer(name, Domain::Vert, AttrValue::Scalar(0.0));
        }
        self.scalars = begin.scalars.iter().map(|n| n.to_string()).collect();
        self.verts.reserve(begin.vertices);
        let corners = match begin.corners {
            0 => begin.polygons.saturating_mul(3),
            n => n,
        };
        // Edges: one per corner in a soup, half that in a closed mesh;
        // reserve the half, so closed meshes never over-allocate.
        self.mesh.reserve(
            begin.vertices,
            corners / 2 + begin.lines,
            corners,
            begin.polygons,
        );
        Ok(())
    }

    fn vertex(&mut self, position: DVec3, scalars: &[f64]) -> Result<(), SinkError> {
        if !position.is_finite() {
            return Err(SinkError::NonFinite {
                index: self.verts.len(),
            });
        }
        if scalars.len() != self.scalars.len() {
            return Err(SinkError::ScalarCount {
                vertex: self.verts.len(),
                found: scalars.len(),
                expected: self.scalars.len(),
            });
        }
        let v = self.mesh.make_vert(position);
        for (name, &value) in self.scalars.iter().zip(scalars) {
            self.mesh
                .set_attr(name, Domain::Vert, v.index(), AttrValue::Scalar(value));
        }
        self.verts.push(v);
        Ok(())
    }

    fn polygon(&mut self, corners: &[u32]) -> Result<(), SinkError> {
        let face = self.polygons_seen;
        self.polygons_seen += 1;
        let count = self.verts.len();
        self.ring.clear();
        for &i in corners {
            let v = *self.verts.get(i as usize).ok_or(SinkError::BadIndex {
                face,
                vertex: i,
                count,
            })?;
            if self.ring.last() != Some(&v) {
                self.ring.push(v);
            }
        }
        while self.ring.len() > 1 && self.ring.first() == self.ring.last() {
            self.ring.pop();
        }
        // Every corner is a live vertex of this build, so a ring of at least 3 distinct
        // corners is one `make_face` accepts.
        if self.ring.len() >= 3 && !has_repeats(&self.ring) {
            // The common case: a simple ring, made as it is.
            let f = self
                .mesh
                .make_face_of_clean_ring(&self.ring, &mut self.face_edges);
            self.faces.push(f);
            return Ok(());
        }
        for piece in simple_loops(&self.ring) {
            if piece.len() >= 3 {
                let f = self
                    .mesh
                    .make_face_of_clean_ring(&piece, &mut self.face_edges);
                self.faces.push(f);
            } else {
                self.report.degenerate_faces += 1;
            }
        }
        Ok(())
    }

    fn line(&mut self, a: u32, b: u32) -> Result<(), SinkError> {
        let line = self.lines.len();
        let count = self.verts.len();
        let get = |i: u32| {
            self.verts
                .get(i as usize)
                .copied()
                .ok_or(SinkError::BadLineIndex {
                    line,
                    vertex: i,
                    count,
                })
        };
        let (a, b) = (get(a)?, get(b)?);
        if a != b && self.mesh.find_edge(a, b).is_none() {
            let e = self
                .mesh
                .make_edge(a, b)
                .expect("distinct live vertices without an edge");
            self.lines.push(e);
        }
        Ok(())
    }

    fn end(&mut self) -> Result<(), SinkError> {
        Ok(())
    }

    /// Leaves what was built: a caller that gives up drops the mesh (a
    /// fresh one) or fails the run (the engine's working mesh).
    fn abort(&mut self) {
        self.settle_normals();
    }
}

/// Whether a ring visits a vertex twice.
fn has_repeats<T: Ord + Copy>(ring: &[T]) -> bool {
    if ring.len() <= 16 {
        return ring
            .iter()
            .enumerate()
            .any(|(i, v)| ring[i + 1..].contains(v));
    }
    let mut sorted = ring.to_vec();
    sorted.sort_unstable();
    sorted.windows(2).any(|w| w[0] == w[1])
}

/// Splits a ring that visits a vertex more than once into simple loops.
fn simple_loops(ring: &[VertId]) -> Vec<Vec<VertId>> {
    let mut out = Vec::new();
    let mut stack: Vec<VertId> = Vec::with_capacity(ring.len());
    for &v in ring {
        if let Some(at) = stack.iter().position(|&w| w == v) {
            out.push(stack.split_off(at));
        }
        stack.push(v);
    }
    out.push(stack);
    out.retain(|l| !l.is_empty());
    out
}

/// A fresh kernel mesh from an indexed one, with what was dropped.
pub fn mesh_from_indexed(indexed: &IndexedMesh) -> Result<(Mesh, ImportReport), SinkError> {
    let mut mesh = Mesh::new();
    let mut builder = KernelBuilder::new(&mut mesh);
    indexed.emit(&mut builder)?;
    let (_, report) = builder.finish();
    Ok((mesh, report))
}

/// Whether [`mesh_from_indexed`] would succeed and make vertex `i` of
/// `indexed` kernel vertex `i` and polygon `k` face `k`, cleaning,
/// splitting and dropping nothing: every position finite, every scalar
/// column full, every polygon at least 3 distinct corners that index a
/// vertex, every line's ends in range. Code that only reads the kernel
/// mesh can then read the indexed mesh in its place (`graftal info`
/// measures it and searches it for self-intersections without building
/// the kernel mesh: [`report_of_indexed`](super::measure::report_of_indexed)).
pub fn builds_one_to_one(indexed: &IndexedMesh) -> bool {
    let count = indexed.positions.len();
    let in_range = |i: &u32| (*i as usize) < count;
    indexed
        .positions
        .iter()
        .all(|p| p.iter().all(|x| x.is_finite()))
        && indexed
            .vertex_scalars
            .iter()
            .all(|(_, values)| values.len() == count)
        && indexed
            .polygons()
            .all(|ring| ring.len() >= 3 && ring.iter().all(in_range) && !has_repeats(ring))
        && indexed.lines.iter().flatten().all(in_range)
}

/// Appends an indexed mesh to `mesh`; returns what was made.
pub fn append_indexed(mesh: &mut Mesh, indexed: &IndexedMesh) -> Result<Selection, SinkError> {
    let mut builder = KernelBuilder::new(mesh);
    indexed.emit(&mut builder)?;
    Ok(builder.finish().0)
}

/// Input vertices the weld hands over at a time in [`append_welded`].
const WELD_CHUNK: usize = 1 << 14;

/// [`append_indexed`] of `indexed.welded(distance)`: the same calls into
/// the same builder, so the same mesh, bit for bit. The weld
/// ([`IndexedMesh::weld_map`]) runs as one task and this build as another,
/// which takes each kept vertex and each polygon as soon as the weld has
/// placed its corners (in a soup, right after them), so on two cores the
/// build, a third of an import, hides behind the weld. The map reaches the
/// build in order over a channel that never blocks the weld, so the
/// result cannot depend on timing, and with one thread the weld simply
/// runs first.
pub fn append_welded(
    mesh: &mut Mesh,
    indexed: &IndexedMesh,
    distance: f64,
) -> Result<Selection, SinkError> {
    append_welded_in_chunks(mesh, indexed, distance, WELD_CHUNK)
}

/// [`append_welded`] with the weld handing over `chunk` vertices at a time.
fn append_welded_in_chunks(
    mesh: &mut Mesh,
    indexed: &IndexedMesh,
    distance: f64,
    chunk: usize,
) -> Result<Selection, SinkError> {
    let (send, receive) = std::sync::mpsc::channel::<Vec<u32>>();
    let mut builder = KernelBuilder::new(mesh);
    let weld = move || {
        // A send fails only once the build has given up: stop there.
        indexed.weld_map(distance, chunk, |map| send.send(map.to_vec()).is_ok());
    };
    // The weld is the task `join` starts on this thread: it never waits
    // for the build, so one thread runs it to the end, then the build.
    let ((), built) = rayon::join(weld, || {
        let built = build_welded(&mut builder, indexed, receive);
        if built.is_err() {
            builder.abort();
        }
        built
    });
    built?;
    Ok(builder.finish().0)
}

/// The build side of [`append_welded`]: what `indexed.welded(…).emit(…)`
/// would hand `builder`, taken as the weld's map arrives.
fn build_welded(
    builder: &mut KernelBuilder,
    indexed: &IndexedMesh,
    map_chunks: std::sync::mpsc::Receiver<Vec<u32>>,
) -> Result<(), SinkError> {
    let n = indexed.positions.len();
    let names: Vec<&str> = indexed
        .vertex_scalars
        .iter()
        .map(|(name, _)| name.as_str())
        .collect();
    // The welded counts are not known yet; the input's bound them.
    builder.begin(&Begin {
        vertices: n,
        polygons: indexed.polygon_count(),
        corners: indexed.face_indices.len(),
        lines: indexed.lines.len(),
        scalars: &names,
    })?;
    let mut map: Vec<u32> = Vec::with_capacity(n);
    let mut scalars = vec![0.0; names.len()];
    let mut corners: Vec<(u32, usize)> = Vec::new();
    let mut ring: Vec<u32> = Vec::new();
    let polygons = indexed.polygon_count();
    let mut next = 0;
    // Polygons from `next` on whose corners are all mapped, in order.
    let mut build_ready = |builder: &mut KernelBuilder, map: &[u32], next: &mut usize| {
        while *next < polygons {
            let k = *next;
            let poly = indexed.polygon(k);
            if let Some(&v) = poly.iter().find(|&&v| v as usize >= map.len()) {
                if map.len() < n {
                    return Ok(());
                }
                // Everything is mapped and this corner still is not: the
                // input is malformed (readers validate, so only a caller's).
                return Err(SinkError::BadIndex {
                    face: k,
                    vertex: v,
                    count: n,
                });
            }
            if welded_ring(poly, indexed.face_starts[k] as usize, map, &mut corners) {
                ring.clear();
                ring.extend(corners.iter().map(|c| c.0));
                builder.polygon(&ring)?;
            }
            *next += 1;
        }
        Ok(())
    };
    for chunk in map_chunks {
        for &m in &chunk {
            let i = map.len();
            if m as usize == builder.verts.len() {
                // A vertex that keeps its own place: the next kept one.
                for (slot, (_, values)) in scalars.iter_mut().zip(&indexed.vertex_scalars) {
                    *slot = values.get(i).copied().ok_or(SinkError::ScalarCount {
                        vertex: i,
                        found: values.len(),
                        expected: n,
                    })?;
                }
                builder.vertex(DVec3::from_array(indexed.positions[i]), &scalars)?;
            }
            map.push(m);
        }
        build_ready(builder, &map, &mut next)?;
    }
    build_ready(builder, &map, &mut next)?;
    for l in &indexed.lines {
        let [a, b] = l.map(|v| map.get(v as usize).copied().unwrap_or(u32::MAX));
        if a != b {
            builder.line(a, b)?;
        }
    }
    builder.end()
}

impl Mesh {
    /// Hands the mesh to `sink` in canonical order (see the module doc).
    pub fn emit(&self, sink: &mut dyn MeshSink) -> Result<(), SinkError> {
        let layers: Vec<&Layer> = self
            .attributes()
            .layers()
            .iter()
            .filter(|layer| layer.domain == Domain::Vert && layer.kind() == LayerKind::Scalar)
            .collect();
        let names: Vec<&str> = layers.iter().map(|l| l.name.as_str()).collect();
        let wires: Vec<EdgeId> = self.edge_ids().filter(|&e| self.is_wire_edge(e)).collect();
        let run = |sink: &mut dyn MeshSink| -> Result<(), SinkError> {
            sink.begin(&Begin {
                vertices: self.vert_count(),
                polygons: self.face_count(),
                corners: self.loop_count(),
                lines: wires.len(),
                scalars: &names,
            })?;
            let mut index_of = vec![u32::MAX; self.vert_capacity()];
            let mut scalars = vec![0.0; layers.len()];
            for (i, v) in self.vert_ids().enumerate() {
                index_of[v.index()] = i as u32;
                for (slot, layer) in scalars.iter_mut().zip(&layers) {
                    *slot = layer.scalar(v.index()).unwrap_or_default();
                }
                sink.vertex(self.position(v), &scalars)?;
            }
            let mut corners: Vec<u32> = Vec::new();
            for f in self.face_ids() {
                corners.clear();
                corners.extend(self.face_verts(f).map(|v| index_of[v.index()]));
                sink.polygon(&corners)?;
            }
            for &e in &wires {
                let [a, b] = self.edge_verts(e);
                sink.line(index_of[a.index()], index_of[b.index()])?;
            }
            sink.end()
        };
        run(sink).inspect_err(|_| sink.abort())
    }

    /// [`Mesh::to_indexed`] carrying each face's stored normal (fresh by
    /// construction), so writers need not compute flat normals again.
    pub fn to_indexed_with_normals(&self) -> IndexedMesh {
        let mut out = self.to_indexed();
        // Sized once: the arena's iterator cannot tell its length, and
        // growing by doubling copies and faults up to twice the bytes.
        out.polygon_normals = Vec::with_capacity(self.face_count());
        out.polygon_normals
            .extend(self.faces.iter().map(|(_, face)| face.normal.to_array()));
        out
    }

    /// The canonical indexed view of the mesh (what the writers take).
    pub fn to_indexed(&self) -> IndexedMesh {
        let mut out = IndexedMesh::new();
        self.emit(&mut out)
            .expect("collecting a valid mesh into an indexed one cannot fail");
        out
    }
}

impl Mesh {
    /// The mesh as a [`PolygonSource`] in canonical order (what
    /// [`Mesh::to_indexed_with_normals`] would hold), read in place: a
    /// writer streams from it without the indexed copy.
    pub fn canonical_view(&self) -> CanonicalView<'_> {
        // Compact (no freed vertex slot, the usual case): a vertex's index
        // is its slot, and no map is needed either way.
        let (slot_of, index_of) = if self.vert_count() == self.vert_capacity() {
            (Vec::new(), Vec::new())
        } else {
            let mut index_of = vec![u32::MAX; self.vert_capacity()];
            let slot_of: Vec<u32> = self.vert_ids().map(VertId::raw).collect();
            for (i, &slot) in slot_of.iter().enumerate() {
                index_of[slot as usize] = i as u32;
            }
            (slot_of, index_of)
        };
        CanonicalView {
            mesh: self,
            slot_of,
            index_of,
        }
    }
}

impl Mesh {
    /// Whether every pair of vertices the faces join is walked as often one
    /// way as the other: the faces make closed, consistently oriented
    /// shells. The answer [`IndexedMesh::double_sided_decided`] reaches for
    /// one material on every face of the canonical view, read from the
    /// edges' radial cycles instead; parallel edges between the same two
    /// vertices count together, as the indexed view's vertex pairs do.
    pub fn faces_on_closed_shells(&self) -> bool {
        // Uses of `e` from its first vertex, minus uses from its second.
        let balance = |e: EdgeId| {
            let [a, _] = self.edge_verts(e);
            self.edge_loops(e)
                .map(|l| if self.loop_vert(l) == a { 1i64 } else { -1 })
                .sum::<i64>()
        };
        self.edge_ids().all(|e| {
            balance(e) == 0 || {
                let [a, b] = self.edge_verts(e);
                let pair: i64 = self
                    .vert_edges(a)
                    .filter(|&p| self.edge_other_vert(p, a) == b)
                    .map(|p| {
                        let sign = if self.edge_verts(p)[0] == a { 1 } else { -1 };
                        sign * balance(p)
                    })
                    .sum();
                pair == 0
            }
        })
    }
}

/// A kernel mesh read as a [`PolygonSource`]: vertices in id order,
/// compacted; faces in id order, each from its first loop, with its stored
/// normal (fresh by construction, checked by the validator).
pub struct CanonicalView<'m> {
    mesh: &'m Mesh,
    /// Vertex index → slot; empty when the slots are compact.
    slot_of: Vec<u32>,
    /// Slot → vertex index; empty when the slots are compact.
    index_of: Vec<u32>,
}

impl PolygonSource for CanonicalView<'_> {
    fn vertex_count(&self) -> usize {
        self.mesh.vert_count()
    }

    fn polygon_count(&self) -> usize {
        self.mesh.face_count()
    }

    fn corner_count(&self) -> usize {
        self.mesh.loop_count()
    }

    fn position(&self, v: u32) -> DVec3 {
        let slot = self.slot_of.get(v as usize).copied().unwrap_or(v);
        self.mesh.position(VertId::from_raw(slot))
    }

    fn max_polygon_len(&self) -> usize {
        self.mesh
            .faces
            .iter()
            .map(|(_, face)| face.len as usize)
            .max()
            .unwrap_or(0)
    }

    fn stores_normals(&self) -> bool {
        true
    }

    fn for_each_polygon(&self, mut visit: impl FnMut(&[u32], Option<Option<DVec3>>)) {
        let mut corners: Vec<u32> = Vec::new();
        for (f, face) in self.mesh.faces.iter() {
            corners.clear();
            let verts = self.mesh.face_verts(FaceId::from_raw(f)).map(VertId::raw);
            if self.index_of.is_empty() {
                corners.extend(verts);
            } else {
                corners.extend(verts.map(|slot| self.index_of[slot as usize]));
            }
            let n = face.normal;
            visit(&corners, Some((n != DVec3::ZERO).then_some(n)));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_to_one_needs_simple_polygons_of_finite_vertices() {
        let square = || {
            let mut m = IndexedMesh::new();
            m.positions = vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
            m.push_polygon(&[0, 1, 2, 3]);
            m.lines.push([0, 2]);
            m
        };
        assert!(builds_one_to_one(&square()));
        let (mesh, _) = mesh_from_indexed(&square()).unwrap();
        assert_eq!(
            mesh.face_verts(FaceId::from_raw(0))
                .map(|v| v.raw())
                .collect::<Vec<_>>(),
            [0, 1, 2, 3]
        );
        for (broken, corners) in [
            ("consecutive repeat", vec![0, 1, 1, 2]),
            ("repeat around the end", vec![0, 1, 2, 0]),
            ("repeat inside", vec![0, 1, 0, 2, 3]),
            ("two corners", vec![0, 1]),
            ("index past the vertices", vec![0, 1, 7]),
        ] {
            let mut m = square();
            m.push_polygon(&corners);
            assert!(!builds_one_to_one(&m), "{broken}");
        }
        let mut m = square();
        m.positions[2][1] = f64::NAN;
        assert!(!builds_one_to_one(&m));
        let mut m = square();
        m.lines.push([3, 4]);
        assert!(!builds_one_to_one(&m), "line past the vertices");
        assert!(mesh_from_indexed(&m).is_err());
        let mut m = square();
        m.vertex_scalars.push(("radius".into(), vec![1.0; 3]));
        assert!(!builds_one_to_one(&m), "a scalar short of a vertex");
        assert!(mesh_from_indexed(&m).is_err());
        m.vertex_scalars[0].1.push(1.0);
        assert!(builds_one_to_one(&m));
    }

    #[test]
    fn round_trip_keeps_topology_lines_and_attributes() {
        let mut m = IndexedMesh::new();
        m.positions = vec![
            [0., 0., 0.],
            [1., 0., 0.],
            [1., 1., 0.],
            [0., 1., 0.],
            [2., 2., 2.],
        ];
        m.push_polygon(&[0, 1, 2, 3]);
        m.lines.push([2, 4]);
        m.vertex_scalars
            .push(("radius".into(), vec![0.1, 0.2, 0.3, 0.4, 0.5]));
        let (mesh, _) = mesh_from_indexed(&m).unwrap();
        mesh.validate().unwrap();
        assert_eq!(
            (mesh.vert_count(), mesh.edge_count(), mesh.face_count()),
            (5, 5, 1)
        );
        assert_eq!(mesh.to_indexed(), m);
    }

    #[test]
    fn degenerate_polygons_are_cleaned_or_counted() {
        let mut m = IndexedMesh::new();
        m.positions = vec![
            [0., 0., 0.],
            [1., 0., 0.],
            [1., 1., 0.],
            [0., 1., 0.],
            [2., 0., 0.],
            [2., 1., 0.],
        ];
        m.push_polygon(&[0, 1, 1, 2]); // consecutive repeat: a triangle
        m.push_polygon(&[0, 0, 3]); // two distinct corners: dropped
        m.push_polygon(&[1, 4, 5, 1, 2, 3]); // bow-tie through 1: two loops
        let (mesh, report) = mesh_from_indexed(&m).unwrap();
        mesh.validate().unwrap();
        assert_eq!(mesh.face_count(), 3);
        assert_eq!(report.degenerate_faces, 1);
    }

    #[test]
    fn bad_indices_are_reported_not_panicked() {
        let mut m = IndexedMesh::new();
        m.positions = vec![[0., 0., 0.]];
        m.push_polygon(&[0, 1, 2]);
        assert_eq!(
            mesh_from_indexed(&m).unwrap_err(),
            SinkError::BadIndex {
                face: 0,
                vertex: 1,
                count: 1
            }
        );
    }

    #[test]
    fn appending_names_what_was_made() {
        let mut m = IndexedMesh::new();
        m.positions = vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [3., 3., 3.]];
        m.push_polygon(&[0, 1, 2]);
        m.lines.push([2, 3]);
        let mut mesh = Mesh::new();
        let first = append_indexed(&mut mesh, &m).unwrap();
        let second = append_indexed(&mut mesh, &m).unwrap();
        mesh.validate().unwrap();
        for made in [&first, &second] {
            assert_eq!(
                (made.verts.len(), made.edges.len(), made.faces.len()),
                (4, 4, 1)
            );
        }
        assert!(first.verts.iter().all(|v| !second.verts.contains(v)));
    }

    /// A soup in the shape imports weld: a jittered grid of points, each
    /// repeated per corner, shuffled, with collapsing triangles, quads that
    /// reach far ahead, lines (some collapsing) and a vertex scalar.
    fn jittered_soup(seed: u64, cells: usize, jitter: f64) -> IndexedMesh {
        let mut state = seed;
        let mut next = move || {
            // splitmix64
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        };
        let mut unit = move || (next() >> 11) as f64 / (1u64 << 53) as f64;
        let mut m = IndexedMesh::new();
        let corner = |m: &mut IndexedMesh, i: usize, j: usize, unit: &mut dyn FnMut() -> f64| {
            let p = [
                i as f64 + jitter * (unit() - 0.5),
                j as f64 + jitter * (unit() - 0.5),
                0.25 * ((i * j) % 3) as f64,
            ];
            m.positions.push(p);
            (m.positions.len() - 1) as u32
        };
        for i in 0..cells {
            for j in 0..cells {
                let a = corner(&mut m, i, j, &mut unit);
                let b = corner(&mut m, i + 1, j, &mut unit);
                let c = corner(&mut m, i + 1, j + 1, &mut unit);
                m.push_polygon(&[a, b, c]);
                let d = corner(&mut m, i, j + 1, &mut unit);
                let e = corner(&mut m, i, j, &mut unit);
                let f = corner(&mut m, i + 1, j + 1, &mut unit);
                m.push_polygon(&[e, f, d]);
            }
        }
        let soup = m.positions.len() as u32;
        // Collapses to a segment once welded, and a triangle closing on itself.
        let (p, q) = (
            corner(&mut m, 0, 0, &mut unit),
            corner(&mut m, 0, 0, &mut unit),
        );
        let r = corner(&mut m, 1, 0, &mut unit);
        m.push_polygon(&[p, q, r]);
        // Quads over vertices from all over the file, the last ones included.
        for k in 0..cells as u32 {
            let at = |x: u32| (x * 7919 + k * 104_729) % soup;
            m.push_polygon(&[at(1), at(2), soup + 2, at(3)]);
        }
        m.lines.push([0, 1]);
        m.lines.push([p, q]);
        m.lines.push([soup - 1, 2]);
        let values = (0..m.positions.len()).map(|i| i as f64 * 0.5).collect();
        m.vertex_scalars.push(("w".into(), values));
        m
    }

    /// The mesh with another mesh already in it, some slots freed.
    fn with_earlier_content() -> Mesh {
        let mut mesh = Mesh::new();
        let v: Vec<VertId> = (0..5)
            .map(|i| mesh.make_vert(DVec3::new(f64::from(i), 0.5 * f64::from(i * i), 1.0)))
            .collect();
        let f = mesh.make_face(&[v[0], v[1], v[2]]).unwrap();
        mesh.make_face(&[v[0], v[2], v[3], v[4]]).unwrap();
        mesh.kill_face(f).unwrap();
        mesh
    }

    #[test]
    fn welding_while_building_makes_the_mesh_the_welded_copy_makes() {
        for (seed, distance) in [(1, 0.05), (2, 0.05), (3, 0.0), (4, 0.3)] {
            // Distance 0 welds bitwise-equal points only: no jitter there.
            let jitter = if distance > 0.0 { 0.04 } else { 0.0 };
            let soup = jittered_soup(seed, 9, jitter);
            for earlier in [false, true] {
                let fresh = || {
                    if earlier {
                        with_earlier_content()
                    } else {
                        Mesh::new()
                    }
                };
                let mut expected = fresh();
                let made = append_indexed(&mut expected, &soup.welded(distance)).unwrap();
                expected.validate().unwrap();
                let expected_state = format!("{expected:?}");
                for threads in [1, 2] {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    for chunk in [1, 7, 64, WELD_CHUNK] {
                        let mut mesh = fresh();
                        let got = pool
                            .install(|| append_welded_in_chunks(&mut mesh, &soup, distance, chunk))
                            .unwrap();
                        let case = format!("seed {seed}, {threads} threads, chunk {chunk}");
                        assert_eq!(got, made, "{case}");
                        assert!(format!("{mesh:?}") == expected_state, "{case}");
                    }
                }
            }
        }
    }

    #[test]
    fn welding_while_building_reports_a_bad_index_and_stops() {
        let mut soup = jittered_soup(5, 4, 0.04);
        let n = soup.positions.len() as u32;
        soup.push_polygon(&[0, n + 3, 1]);
        let mut mesh = Mesh::new();
        let err = append_welded_in_chunks(&mut mesh, &soup, 0.05, 5).unwrap_err();
        assert!(
            matches!(err, SinkError::BadIndex { vertex, .. } if vertex == n + 3),
            "{err}"
        );
        // What was built before the bad polygon stands (the caller drops it
        // or fails the run) and is a valid mesh, normals included.
        mesh.validate().unwrap();
    }
}
