//! The mesh structure and its read-only adjacency queries.
//!
//! Four arenas hold the elements. Adjacency follows BMesh (seed 000 §4.3):
//! - the *disk cycle*: the edges around a vertex, a doubly linked cycle
//!   threaded through the edges (each edge has one link pair per endpoint);
//! - the *radial cycle*: the loops around an edge, one per face using it;
//! - the *boundary cycle*: the loops of a face, in winding order.
//!
//! A loop `l` belongs to face `l.face`, starts at vertex `l.vert` and runs
//! along `l.edge` to the next loop's vertex.
//!
//! Adjacency fields are private to the kernel: only [`super::euler`] writes
//! them. Positions and attributes are geometry, writable by anyone.

use glam::DVec3;

use super::arena::Arena;
use super::attrs::{AttrValue, Attributes, LayerKind};
use super::ids::{Domain, EdgeId, FaceId, LoopId, VertId};
use crate::geom::polygon;

#[derive(Copy, Clone, Debug)]
pub(crate) struct Vert {
    pub(in crate::kernel) position: DVec3,
    /// Any edge of the disk cycle; `None` for an isolated vertex.
    pub(in crate::kernel) edge: Option<EdgeId>,
    /// No information: a byte of the record's padding whose type has
    /// spare values, so that an arena slot (`Option<Vert>`) needs no tag
    /// (32 bytes, not 40: the edge's niche is taken by its own `Option`).
    #[allow(dead_code)]
    pub(in crate::kernel) slot: Occupied,
}

/// See [`Vert::slot`].
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
#[repr(u8)]
pub(crate) enum Occupied {
    Yes = 1,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(crate) struct DiskLink {
    pub(in crate::kernel) prev: EdgeId,
    pub(in crate::kernel) next: EdgeId,
}

#[derive(Copy, Clone, Debug)]
pub(crate) struct Edge {
    pub(in crate::kernel) verts: [VertId; 2],
    /// `disk[i]` links this edge into the disk cycle of `verts[i]`.
    pub(in crate::kernel) disk: [DiskLink; 2],
    /// Any loop of the radial cycle; `None` for a wire edge.
    pub(in crate::kernel) first_loop: Option<LoopId>,
}

#[derive(Copy, Clone, Debug)]
pub(crate) struct Loop {
    pub(in crate::kernel) vert: VertId,
    pub(in crate::kernel) edge: EdgeId,
    pub(in crate::kernel) face: FaceId,
    pub(in crate::kernel) next: LoopId,
    pub(in crate::kernel) prev: LoopId,
    pub(in crate::kernel) radial_next: LoopId,
    pub(in crate::kernel) radial_prev: LoopId,
}

#[derive(Copy, Clone, Debug)]
pub(crate) struct Face {
    pub(in crate::kernel) first_loop: LoopId,
    pub(in crate::kernel) len: u32,
    pub(in crate::kernel) normal: DVec3,
}

/// One part of [`Mesh::memory`]: bytes in use and bytes allocated.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryPart {
    pub name: String,
    pub used: usize,
    pub reserved: usize,
}

impl MemoryPart {
    fn new(name: &str, (used, reserved): (usize, usize)) -> Self {
        Self {
            name: name.to_owned(),
            used,
            reserved,
        }
    }
}

/// A non-manifold polygon mesh: vertices, edges, loops and faces.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub(in crate::kernel) verts: Arena<Vert>,
    pub(in crate::kernel) edges: Arena<Edge>,
    pub(in crate::kernel) loops: Arena<Loop>,
    pub(in crate::kernel) faces: Arena<Face>,
    pub(in crate::kernel) attributes: Attributes,
}

impl Edge {
    /// Which end (0 or 1) of the edge `v` is. Callers guarantee `v` is an end.
    #[inline]
    pub(in crate::kernel) fn side(&self, v: VertId) -> usize {
        debug_assert!(self.verts.contains(&v));
        usize::from(self.verts[0] != v)
    }
}

impl Mesh {
    pub fn new() -> Self {
        Self::default()
    }

    // ---- counts and existence ----

    pub fn vert_count(&self) -> usize {
        self.verts.len()
    }
    pub fn edge_count(&self) -> usize {
        self.edges.len()
    }
    pub fn face_count(&self) -> usize {
        self.faces.len()
    }
    pub fn loop_count(&self) -> usize {
        self.loops.len()
    }
    pub fn is_empty(&self) -> bool {
        self.verts.len() == 0
    }
    /// Upper bound (exclusive) of vertex slot indices, for dense side tables.
    pub fn vert_capacity(&self) -> usize {
        self.verts.capacity()
    }
    pub fn edge_capacity(&self) -> usize {
        self.edges.capacity()
    }
    pub fn face_capacity(&self) -> usize {
        self.faces.capacity()
    }

    pub fn contains_vert(&self, v: VertId) -> bool {
        self.verts.contains(v.raw())
    }
    pub fn contains_edge(&self, e: EdgeId) -> bool {
        self.edges.contains(e.raw())
    }
    pub fn contains_face(&self, f: FaceId) -> bool {
        self.faces.contains(f.raw())
    }

    // ---- element iteration, always in id order ----

    pub fn vert_ids(&self) -> impl Iterator<Item = VertId> + '_ {
        self.verts.iter().map(|(i, _)| VertId::from_raw(i))
    }
    pub fn edge_ids(&self) -> impl Iterator<Item = EdgeId> + '_ {
        self.edges.iter().map(|(i, _)| EdgeId::from_raw(i))
    }
    pub fn face_ids(&self) -> impl Iterator<Item = FaceId> + '_ {
        self.faces.iter().map(|(i, _)| FaceId::from_raw(i))
    }

    // ---- internal accessors (panic on dead ids: callers check first) ----

    #[inline]
    pub(in crate::kernel) fn vert(&self, v: VertId) -> &Vert {
        self.verts.get(v.raw()).expect("dead vertex id")
    }
    #[inline]
    pub(in crate::kernel) fn edge(&self, e: EdgeId) -> &Edge {
        self.edges.get(e.raw()).expect("dead edge id")
    }
    #[inline]
    pub(in crate::kernel) fn lp(&self, l: LoopId) -> &Loop {
        self.loops.get(l.raw()).expect("dead loop id")
    }
    #[inline]
    pub(in crate::kernel) fn face(&self, f: FaceId) -> &Face {
        self.faces.get(f.raw()).expect("dead face id")
    }

    // ---- geometry ----

    /// Position of a live vertex. Panics on a dead id.
    #[inline]
    pub fn position(&self, v: VertId) -> DVec3 {
        self.vert(v).position
    }

    /// Moves a vertex; the stored normals of the faces around it follow.
    /// Stored normals are fresh by construction (the validator checks it
    /// bit for bit), so no reader ever recomputes one. Panics on a dead id.
    pub fn move_vert(&mut self, v: VertId, position: DVec3) {
        self.place(v, position);
        self.refresh_faces_around(v);
    }

    /// Moves many vertices; each face around them gets its normal once,
    /// from the final positions.
    pub fn move_verts(&mut self, moves: &[(VertId, DVec3)]) {
        for &(v, p) in moves {
            self.place(v, p);
        }
        let mut faces: Vec<FaceId> = moves
            .iter()
            .flat_map(|&(v, _)| self.vert_faces(v))
            .collect();
        faces.sort_unstable();
        faces.dedup();
        for f in faces {
            self.refresh_normal(f);
        }
    }

    /// Moves a vertex and leaves the stored normals around it to the
    /// caller: a kernel operator that moves many corners refreshes every
    /// face it touched, once, before it returns.
    #[inline]
    pub(in crate::kernel) fn place(&mut self, v: VertId, position: DVec3) {
        self.verts
            .get_mut(v.raw())
            .expect("dead vertex id")
            .position = position;
    }

    /// Refreshes the stored normal of every face around `v`.
    pub(in crate::kernel) fn refresh_faces_around(&mut self, v: VertId) {
        let faces: Vec<FaceId> = self.vert_faces(v).collect();
        for f in faces {
            self.refresh_normal(f);
        }
    }

    /// Stored unit normal of a face (Newell normal at creation or last refresh;
    /// zero for a degenerate face).
    pub fn face_normal(&self, f: FaceId) -> DVec3 {
        self.face(f).normal
    }

    /// Recomputes the stored normal of `f` from its current vertex positions.
    pub fn refresh_normal(&mut self, f: FaceId) {
        let normal = self.compute_face_normal(f);
        self.faces.get_mut(f.raw()).expect("dead face id").normal = normal;
    }

    /// Room for this many more elements of each kind, reserved once (an
    /// import or a large generator knows its counts: growing the arenas
    /// by doubling copies them and touches every page twice).
    pub fn reserve(&mut self, verts: usize, edges: usize, loops: usize, faces: usize) {
        self.verts.reserve(verts);
        self.edges.reserve(edges);
        self.loops.reserve(loops);
        self.faces.reserve(faces);
    }

    /// Room for what a step is about to add (an upper bound is fine):
    /// each arena, and each layer every element so far has a value in,
    /// grows once by at least an eighth instead of doubling when a push
    /// finds it full. Peak memory then holds ≤ 12.5 % spare capacity
    /// rather than up to 100 % (issue 38, deliverable 3).
    pub fn reserve_growth(&mut self, verts: usize, edges: usize, loops: usize, faces: usize) {
        let slots = [
            (Domain::Vert, self.verts.capacity(), verts),
            (Domain::Edge, self.edges.capacity(), edges),
            (Domain::Face, self.faces.capacity(), faces),
        ];
        self.verts.reserve_growth(verts);
        self.edges.reserve_growth(edges);
        self.loops.reserve_growth(loops);
        self.faces.reserve_growth(faces);
        for (domain, slots, additional) in slots {
            self.attributes.reserve_growth(domain, slots, additional);
        }
    }

    /// Recomputes the stored normals of `faces` (live), computed in
    /// parallel: each is a pure function of its corners.
    pub(in crate::kernel) fn refresh_normals_of(&mut self, faces: &[FaceId]) {
        if !faces.windows(2).all(|w| w[0] < w[1]) {
            // Rare (triangulate's undecided quads): a sorted copy of the
            // ids, 4 bytes a face, rather than a second mechanism.
            let mut sorted = faces.to_vec();
            sorted.sort_unstable();
            sorted.dedup();
            return self.refresh_normals_of(&sorted);
        }
        // Each record written in place, in parallel, with no buffer of
        // normals (issue 38: a weld refreshes a million faces, 24 MB
        // touched for nothing).
        let Mesh {
            verts,
            loops,
            faces: records,
            ..
        } = self;
        records.par_update_ascending(
            faces,
            |f| f.raw(),
            |face| face.normal = loops_normal(loops, verts, face.first_loop, face.len),
        );
    }

    /// Recomputes every stored face normal.
    pub fn refresh_normals(&mut self) {
        let ids: Vec<FaceId> = self.face_ids().collect();
        for f in ids {
            self.refresh_normal(f);
        }
    }

    /// The normalised mean of the *stored* unit normals of the faces around
    /// `v` (what conditions read as `normal.x`); zero when it has no faces
    /// or they cancel.
    pub fn vert_normal(&self, v: VertId) -> DVec3 {
        let sum: DVec3 = self.vert_faces(v).map(|f| self.face_normal(f)).sum();
        sum.try_normalize().unwrap_or(DVec3::ZERO)
    }

    /// The normalised mean of the face normals around `v` *recomputed from
    /// current positions* (extrusion along normals must not trust a stored
    /// normal a transform left stale); zero without faces or if they cancel.
    pub fn vert_normal_from_positions(&self, v: VertId) -> DVec3 {
        self.vert_faces(v)
            .map(|f| self.compute_face_normal(f))
            .sum::<DVec3>()
            .normalize_or_zero()
    }

    /// Unit Newell normal from current positions; zero when degenerate.
    pub fn compute_face_normal(&self, f: FaceId) -> DVec3 {
        // Every Euler operator that reshapes a face calls this (a new
        // face takes its ring's: `ring_normal`): small faces (nearly all)
        // gather their corners on the stack.
        let face = self.face(f);
        loops_normal(&self.loops, &self.verts, face.first_loop, face.len)
    }

    pub fn face_positions(&self, f: FaceId) -> Vec<DVec3> {
        self.face_verts(f).map(|v| self.position(v)).collect()
    }

    /// Vertex average of a face.
    pub fn face_center(&self, f: FaceId) -> DVec3 {
        let mut sum = DVec3::ZERO;
        let mut n = 0.0;
        for v in self.face_verts(f) {
            sum += self.position(v);
            n += 1.0;
        }
        sum / n
    }

    pub fn face_area(&self, f: FaceId) -> f64 {
        polygon::area(&self.face_positions(f))
    }

    pub fn edge_length(&self, e: EdgeId) -> f64 {
        let [a, b] = self.edge(e).verts;
        self.position(a).distance(self.position(b))
    }

    // ---- adjacency queries ----

    /// The two vertices of an edge, in creation order.
    #[inline]
    pub fn edge_verts(&self, e: EdgeId) -> [VertId; 2] {
        self.edge(e).verts
    }

    /// The end of `e` that is not `v`.
    #[inline]
    pub fn edge_other_vert(&self, e: EdgeId, v: VertId) -> VertId {
        let [a, b] = self.edge(e).verts;
        if a == v {
            b
        } else {
            a
        }
    }

    /// Edges around a vertex (its disk cycle).
    pub fn vert_edges(&self, v: VertId) -> DiskIter<'_> {
        let start = self.vert(v).edge;
        DiskIter {
            mesh: self,
            vert: v,
            start,
            next: start,
        }
    }

    pub fn vert_degree(&self, v: VertId) -> usize {
        self.vert_edges(v).count()
    }

    /// Neighbouring vertices (across each edge), in disk order.
    pub fn vert_neighbors(&self, v: VertId) -> impl Iterator<Item = VertId> + '_ {
        self.vert_edges(v).map(move |e| self.edge_other_vert(e, v))
    }

    /// Faces around a vertex, each once.
    pub fn vert_faces(&self, v: VertId) -> impl Iterator<Item = FaceId> + '_ {
        // Each face uses `v` in exactly one loop (no repeated vertices), and
        // that loop starts at `v`: collecting those loops lists each face once.
        self.vert_edges(v).flat_map(move |e| {
            self.edge_loops(e)
                .filter(move |&l| self.lp(l).vert == v)
                .map(move |l| self.lp(l).face)
        })
    }

    /// The face a loop belongs to.
    pub fn loop_face(&self, l: LoopId) -> FaceId {
        self.lp(l).face
    }

    /// The vertex a loop starts at (its face runs from it along the loop's edge).
    pub fn loop_vert(&self, l: LoopId) -> VertId {
        self.lp(l).vert
    }

    /// The edge a loop runs along (from its vertex to the next loop's).
    pub fn loop_edge(&self, l: LoopId) -> EdgeId {
        self.lp(l).edge
    }

    /// Loops around an edge (its radial cycle).
    pub fn edge_loops(&self, e: EdgeId) -> RadialIter<'_> {
        let start = self.edge(e).first_loop;
        RadialIter {
            mesh: self,
            start,
            next: start,
        }
    }

    /// Faces using an edge (a face appears once: it cannot use an edge twice).
    pub fn edge_faces(&self, e: EdgeId) -> impl Iterator<Item = FaceId> + '_ {
        self.edge_loops(e).map(move |l| self.lp(l).face)
    }

    pub fn edge_face_count(&self, e: EdgeId) -> usize {
        self.edge_loops(e).count()
    }

    pub fn is_wire_edge(&self, e: EdgeId) -> bool {
        self.edge(e).first_loop.is_none()
    }

    /// Loops of a face in winding order, starting at its first loop.
    pub fn face_loops(&self, f: FaceId) -> FaceLoopIter<'_> {
        let face = self.face(f);
        FaceLoopIter {
            mesh: self,
            next: face.first_loop,
            remaining: face.len,
        }
    }

    /// Vertices of a face in winding order.
    pub fn face_verts(&self, f: FaceId) -> impl Iterator<Item = VertId> + '_ {
        self.face_loops(f).map(move |l| self.lp(l).vert)
    }

    /// Edges of a face in winding order (edge i runs from vertex i to i+1).
    pub fn face_edges(&self, f: FaceId) -> impl Iterator<Item = EdgeId> + '_ {
        self.face_loops(f).map(move |l| self.lp(l).edge)
    }

    pub fn face_len(&self, f: FaceId) -> usize {
        self.face(f).len as usize
    }

    /// Faces sharing at least one edge with `f`, ascending, without `f`.
    pub fn face_edge_neighbors(&self, f: FaceId) -> Vec<FaceId> {
        let mut out: Vec<FaceId> = self
            .face_edges(f)
            .flat_map(|e| self.edge_faces(e))
            .filter(|&g| g != f)
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Faces sharing at least one vertex with `f`, ascending, without `f`
    /// (thesis 003 counts these: 8 for an interior face of a grid).
    pub fn face_vert_neighbors(&self, f: FaceId) -> Vec<FaceId> {
        let mut out: Vec<FaceId> = self
            .face_verts(f)
            .flat_map(|v| self.vert_faces(v))
            .filter(|&g| g != f)
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// The loop of face `f` that starts at vertex `v`.
    pub(crate) fn face_loop_at(&self, f: FaceId, v: VertId) -> Option<LoopId> {
        self.face_loops(f).find(|&l| self.lp(l).vert == v)
    }

    pub fn face_contains_vert(&self, f: FaceId, v: VertId) -> bool {
        self.face_loop_at(f, v).is_some()
    }

    /// The edge between `a` and `b`, if any. Cost: degree of `a`.
    pub fn find_edge(&self, a: VertId, b: VertId) -> Option<EdgeId> {
        // Both disk cycles in lockstep: the walk costs twice the smaller
        // degree, so the hub of a fan (a triangulated 100k-gon, repeated
        // barycentric splits) is never walked once per spoke. An edge a–b
        // is in both cycles and there is at most one, so either walk finds
        // the same edge, and running out of either proves there is none.
        let (mut from_a, mut from_b) = (self.vert_edges(a), self.vert_edges(b));
        loop {
            let e = from_a.next()?;
            if self.edge_other_vert(e, a) == b {
                return Some(e);
            }
            let e = from_b.next()?;
            if self.edge_other_vert(e, b) == a {
                return Some(e);
            }
        }
    }

    /// A face whose boundary uses exactly these vertices in this cyclic order
    /// (either direction), if one exists.
    pub fn find_face(&self, verts: &[VertId]) -> Option<FaceId> {
        if verts.len() < 3 {
            return None;
        }
        let e = self.find_edge(verts[0], verts[1])?;
        let mut key: Vec<VertId> = verts.to_vec();
        key.sort_unstable();
        self.edge_faces(e).find(|&f| {
            if self.face_len(f) != verts.len() {
                return false;
            }
            let mut fv: Vec<VertId> = self.face_verts(f).collect();
            fv.sort_unstable();
            fv == key
        })
    }

    // ---- attributes ----

    /// Heap bytes of the mesh, part by part: each arena's slots and each
    /// layer's stored prefix, in use and reserved (issue 38's memory
    /// budget is read from this and from the process's peak RSS).
    pub fn memory(&self) -> Vec<MemoryPart> {
        let mut parts = vec![
            MemoryPart::new("vertex records", self.verts.bytes()),
            MemoryPart::new("edge records", self.edges.bytes()),
            MemoryPart::new("loop records", self.loops.bytes()),
            MemoryPart::new("face records", self.faces.bytes()),
        ];
        for layer in self.attributes.layers() {
            let name = format!("{:?} layer {}", layer.domain, layer.name);
            parts.push(MemoryPart::new(&name, layer.bytes()));
        }
        parts
    }

    pub fn attributes(&self) -> &Attributes {
        &self.attributes
    }

    /// Adds a named layer for `domain` with `default` for every element
    /// (existing ones included). Adding an existing layer of the same kind is a no-op.
    pub fn add_layer(
        &mut self,
        name: &str,
        domain: Domain,
        default: AttrValue,
    ) -> Result<(), LayerKind> {
        self.attributes.add_layer(name, domain, default).map(|_| ())
    }

    pub fn remove_layer(&mut self, name: &str, domain: Domain) -> bool {
        self.attributes.remove_layer(name, domain)
    }

    /// Sets one element's value in a named layer. `None` if no such layer;
    /// `Some(Err(kind))` if the value is of another kind than the layer.
    pub fn set_attr(
        &mut self,
        name: &str,
        domain: Domain,
        index: usize,
        value: AttrValue,
    ) -> Option<Result<(), LayerKind>> {
        self.attributes.set(name, domain, index, value)
    }

    /// [`Mesh::set_attr`] for many slots of one scalar layer: the layer looked up once and the
    /// values interned in one pass. `None` without the layer; `Err` with the kind of a layer that
    /// is not scalar, and nothing stored. Every slot lies below `end`.
    pub fn set_scalar_attrs(
        &mut self,
        name: &str,
        domain: Domain,
        end: usize,
        values: impl IntoIterator<Item = (usize, f64)>,
    ) -> Option<Result<(), LayerKind>> {
        self.attributes.set_scalars(name, domain, end, values)
    }

    pub fn attr(&self, name: &str, domain: Domain, index: usize) -> Option<AttrValue> {
        self.attributes.layer(name, domain).map(|l| l.get(index))
    }

    /// Copies every vertex attribute of `from` to `to`.
    pub fn copy_vert_attrs(&mut self, from: VertId, to: VertId) {
        self.attributes.copy(Domain::Vert, from.index(), to.index());
    }
    pub fn copy_edge_attrs(&mut self, from: EdgeId, to: EdgeId) {
        self.attributes.copy(Domain::Edge, from.index(), to.index());
    }
    pub fn copy_face_attrs(&mut self, from: FaceId, to: FaceId) {
        self.attributes.copy(Domain::Face, from.index(), to.index());
    }
    /// Sets `to`'s vertex attributes to the blend of `a` and `b` at `t`.
    pub fn interpolate_vert_attrs(&mut self, a: VertId, b: VertId, t: f64, to: VertId) {
        self.attributes
            .interpolate(Domain::Vert, a.index(), b.index(), t, to.index());
    }
}

/// The unit Newell normal of the `len` corners from loop `first` on
/// ([`Mesh::compute_face_normal`]), from the arenas alone, so a pass can
/// write face records while it reads loops and vertices.
fn loops_normal(loops: &Arena<Loop>, verts: &Arena<Vert>, first: LoopId, len: u32) -> DVec3 {
    let corners = (0..len).scan(first, |l, _| {
        let corner = loops.get(l.raw()).expect("dead loop id");
        *l = corner.next;
        Some(
            verts
                .get(corner.vert.raw())
                .expect("dead vertex id")
                .position,
        )
    });
    normal_of_corners(len as usize, corners)
}

/// [`normal_of`] the `len` points `corners` gives, gathered on the stack
/// when they are few (nearly every face): what a face's stored normal and
/// a new face's ring normal are both computed by.
#[inline]
pub(in crate::kernel) fn normal_of_corners(
    len: usize,
    corners: impl Iterator<Item = DVec3>,
) -> DVec3 {
    if len <= SMALL_FACE {
        let mut points = [DVec3::ZERO; SMALL_FACE];
        for (point, p) in points.iter_mut().zip(corners) {
            *point = p;
        }
        return normal_of(&points[..len]);
    }
    normal_of(&corners.collect::<Vec<_>>())
}

/// Faces up to this many corners gather their points on the stack.
const SMALL_FACE: usize = 8;

/// The unit normal (Newell's, zero when degenerate) of a face's corners in
/// order: triangles and quads (nearly all faces) unrolled.
#[inline]
pub(in crate::kernel) fn normal_of(points: &[DVec3]) -> DVec3 {
    let normal = match points {
        [a, b, c] => polygon::unit_normal_of(&[*a, *b, *c]),
        [a, b, c, d] => polygon::unit_normal_of(&[*a, *b, *c, *d]),
        _ => polygon::unit_normal(points),
    };
    normal.unwrap_or(DVec3::ZERO)
}

/// Iterator over the disk cycle of a vertex.
pub struct DiskIter<'a> {
    mesh: &'a Mesh,
    vert: VertId,
    start: Option<EdgeId>,
    next: Option<EdgeId>,
}

impl Iterator for DiskIter<'_> {
    type Item = EdgeId;
    fn next(&mut self) -> Option<EdgeId> {
        let current = self.next?;
        let edge = self.mesh.edge(current);
        let following = edge.disk[edge.side(self.vert)].next;
        self.next = (Some(following) != self.start).then_some(following);
        Some(current)
    }
}

/// Iterator over the radial cycle of an edge.
pub struct RadialIter<'a> {
    mesh: &'a Mesh,
    start: Option<LoopId>,
    next: Option<LoopId>,
}

impl Iterator for RadialIter<'_> {
    type Item = LoopId;
    fn next(&mut self) -> Option<LoopId> {
        let current = self.next?;
        let following = self.mesh.lp(current).radial_next;
        self.next = (Some(following) != self.start).then_some(following);
        Some(current)
    }
}

/// Iterator over the boundary cycle of a face.
pub struct FaceLoopIter<'a> {
    mesh: &'a Mesh,
    next: LoopId,
    remaining: u32,
}

impl Iterator for FaceLoopIter<'_> {
    type Item = LoopId;
    fn next(&mut self) -> Option<LoopId> {
        if self.remaining == 0 {
            return None;
        }
        self.remaining -= 1;
        let current = self.next;
        self.next = self.mesh.lp(current).next;
        Some(current)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.remaining as usize, Some(self.remaining as usize))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What a million-face model costs is these sizes times its counts:
    /// ids keep a niche (`NonZeroU32`), so an arena slot (`Option` of a
    /// record) and an optional id cost no tag.
    #[test]
    fn records_stay_small() {
        use std::mem::size_of;
        assert_eq!(size_of::<Option<EdgeId>>(), 4);
        assert_eq!(size_of::<Option<Vert>>(), 32);
        assert_eq!(size_of::<Option<Edge>>(), 28);
        assert_eq!(size_of::<Option<Loop>>(), 28);
        assert_eq!(size_of::<Option<Face>>(), 32);
    }

    #[test]
    fn a_new_face_takes_the_normal_its_face_computes() {
        let mut m = Mesh::new();
        let ring: Vec<VertId> = [
            DVec3::new(0.0, 0.0, 0.1),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.3, 1.1, 0.2),
            DVec3::new(0.1, 0.9, 0.0),
            DVec3::new(-0.4, 0.5, 0.3),
        ]
        .map(|p| m.make_vert(p))
        .to_vec();
        for n in 3..=5 {
            let f = m.make_face(&ring[..n]).unwrap();
            assert_eq!(
                m.face_normal(f).to_array().map(f64::to_bits),
                m.compute_face_normal(f).to_array().map(f64::to_bits)
            );
        }
    }

    /// Repeated layer values cost an index, not a copy, and the report
    /// counts what the records and layers hold.
    #[test]
    fn memory_reports_records_and_pooled_layers() {
        let mut m = Mesh::new();
        m.add_layer("heading", Domain::Vert, AttrValue::Vector(DVec3::X))
            .unwrap();
        let n = 10_000;
        m.reserve_growth(n, 0, 0, 0);
        for i in 0..n {
            let v = m.make_vert(DVec3::new(i as f64, 0.0, 0.0));
            let value = if i % 2 == 0 { DVec3::Y } else { DVec3::Z };
            m.set_attr("heading", Domain::Vert, v.index(), AttrValue::Vector(value))
                .unwrap()
                .unwrap();
        }
        let parts = m.memory();
        let part = |name: &str| parts.iter().find(|p| p.name == name).unwrap();
        assert_eq!(part("vertex records").used, 32 * n);
        assert_eq!(
            part("vertex records").reserved,
            32 * n,
            "reserved once, exactly"
        );
        // One byte an index and three distinct values (and the cache of
        // recent values), instead of 24 bytes a vertex.
        let heading = part("Vert layer heading").used;
        assert!(heading < 2 * n, "{heading} bytes");
        assert_eq!(
            m.attr("heading", Domain::Vert, 9_999),
            Some(AttrValue::Vector(DVec3::Z))
        );
        // A step growing by a little grows the arena by an eighth.
        m.reserve_growth(1, 0, 0, 0);
        let after = &m.memory()[0];
        assert_eq!((after.used, after.reserved), (32 * n, 32 * (n + n / 8)));
    }
}
