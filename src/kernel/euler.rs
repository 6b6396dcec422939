//! Euler operators: the only code that writes adjacency.
//!
//! Each operator checks its input first and returns a [`KernelError`] without
//! touching the mesh when the input is bad, so a mesh is valid after every
//! call, successful or not (seed 000 §4.4). High-level operators in
//! [`super::ops`] are compositions of these.
//!
//! | operator | effect |
//! |---|---|
//! | [`Mesh::make_vert`] | new isolated vertex |
//! | [`Mesh::make_edge`] | new wire edge between two vertices |
//! | [`Mesh::make_edge_vert`] | new vertex and a wire edge to it |
//! | [`Mesh::make_face`] | new face on a ring of vertices (missing edges made) |
//! | [`Mesh::make_face_from_edges`] | new face on a ring of edges |
//! | [`Mesh::split_face`] | split a face by a new edge between two of its vertices |
//! | [`Mesh::split_edge`] | split an edge by a new vertex |
//! | [`Mesh::join_faces`] | dissolve an edge shared by two faces, joining them |
//! | [`Mesh::collapse_edge`] | squeeze an edge to one vertex |
//! | [`Mesh::glue_verts`] | merge two vertices |
//! | [`Mesh::glue_edges`] | merge two edges |
//! | [`Mesh::reverse_face`] | flip a face's winding |
//! | [`Mesh::kill_vert`], [`Mesh::kill_edge`], [`Mesh::kill_face`] | delete, with what depends on it |
//! | [`Mesh::join_mesh`] | append another mesh |

use glam::DVec3;
use thiserror::Error;

use super::ids::{Domain, EdgeId, FaceId, LoopId, VertId};
use super::mesh::{normal_of, normal_of_corners, DiskLink, Edge, Face, Loop, Mesh, Occupied, Vert};

/// Why an Euler operator refused its input. The mesh is unchanged.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum KernelError {
    #[error("{domain} {index} does not exist")]
    Dead { domain: Domain, index: u32 },
    #[error("an edge needs two distinct vertices, got {0} twice")]
    SameVertex(VertId),
    #[error("an edge between {0} and {1} already exists ({2})")]
    EdgeExists(VertId, VertId, EdgeId),
    #[error("a face needs at least 3 vertices, got {0}")]
    TooFewVertices(usize),
    #[error("vertex {0} appears twice in the face")]
    RepeatedVertex(VertId),
    #[error("vertex {vert} is not on face {face}")]
    NotInFace { vert: VertId, face: FaceId },
    #[error("vertices {0} and {1} are already adjacent in face {2}")]
    AdjacentInFace(VertId, VertId, FaceId),
    #[error("edge {edge} has {faces} faces; joining needs exactly 2 distinct faces")]
    NotTwoFaces { edge: EdgeId, faces: usize },
    #[error("joining the faces of edge {edge} would repeat vertex {vert}")]
    JoinRepeatsVertex { edge: EdgeId, vert: VertId },
    #[error("vertices {a} and {b} both lie on face {face} without an edge between them; gluing them would repeat a vertex")]
    GlueWithinFace { a: VertId, b: VertId, face: FaceId },
    #[error("the edges do not form a closed ring (at edge {0})")]
    NotARing(EdgeId),
    #[error("a ring of {verts} vertices has {verts} sides, got {edges} edges")]
    SideCount { verts: usize, edges: usize },
    #[error("vertex {vert} is not an end of edge {edge}")]
    NotAnEnd { vert: VertId, edge: EdgeId },
    #[error("position or parameter is not finite")]
    NonFinite,
}

fn dead(domain: Domain, index: u32) -> KernelError {
    KernelError::Dead { domain, index }
}

/// Where [`Mesh::join_mesh`] put the other mesh's elements: `verts[i]` is the
/// new id of the other mesh's vertex slot `i` (`None` for free slots).
#[derive(Debug, Clone, Default)]
pub struct JoinMap {
    pub verts: Vec<Option<VertId>>,
    pub edges: Vec<Option<EdgeId>>,
    pub faces: Vec<Option<FaceId>>,
}

/// The lowest vertex a ring holds twice, if any. Small rings (nearly all)
/// are compared pairwise, without allocating.
fn repeated_vertex(ring: &[VertId]) -> Option<VertId> {
    if ring.len() <= 8 {
        let mut lowest: Option<VertId> = None;
        for (i, &v) in ring.iter().enumerate() {
            if ring[i + 1..].contains(&v) && lowest.is_none_or(|w| v < w) {
                lowest = Some(v);
            }
        }
        return lowest;
    }
    let mut sorted = ring.to_vec();
    sorted.sort_unstable();
    sorted.windows(2).find(|w| w[0] == w[1]).map(|w| w[0])
}

/// Whether an Euler operator refreshes the stored normals of the faces it
/// changed, or leaves that to the operator that calls it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Normals {
    Refresh,
    Defer,
}

/// Whether a glue checks that no face holds both vertices, or its caller
/// has made sure of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SharedFaces {
    Check,
    NoneByConstruction,
}

impl Mesh {
    // ---- checks ----

    pub(crate) fn check_vert(&self, v: VertId) -> Result<(), KernelError> {
        if self.contains_vert(v) {
            Ok(())
        } else {
            Err(dead(Domain::Vert, v.raw()))
        }
    }
    pub(crate) fn check_edge(&self, e: EdgeId) -> Result<(), KernelError> {
        if self.contains_edge(e) {
            Ok(())
        } else {
            Err(dead(Domain::Edge, e.raw()))
        }
    }
    pub(crate) fn check_face(&self, f: FaceId) -> Result<(), KernelError> {
        if self.contains_face(f) {
            Ok(())
        } else {
            Err(dead(Domain::Face, f.raw()))
        }
    }

    // ---- private link surgery (never leaves this module) ----

    fn edge_mut(&mut self, e: EdgeId) -> &mut Edge {
        self.edges.get_mut(e.raw()).expect("dead edge id")
    }
    fn loop_mut(&mut self, l: LoopId) -> &mut Loop {
        self.loops.get_mut(l.raw()).expect("dead loop id")
    }
    fn face_mut(&mut self, f: FaceId) -> &mut Face {
        self.faces.get_mut(f.raw()).expect("dead face id")
    }
    fn vert_mut(&mut self, v: VertId) -> &mut Vert {
        self.verts.get_mut(v.raw()).expect("dead vertex id")
    }

    /// Inserts `e` into the disk cycle of its end `v`.
    fn disk_insert(&mut self, e: EdgeId, v: VertId) {
        let side = self.edge(e).side(v);
        match self.vert(v).edge {
            None => {
                self.edge_mut(e).disk[side] = DiskLink { prev: e, next: e };
                self.vert_mut(v).edge = Some(e);
            }
            Some(first) => {
                let first_side = self.edge(first).side(v);
                let last = self.edge(first).disk[first_side].prev;
                let last_side = self.edge(last).side(v);
                self.edge_mut(e).disk[side] = DiskLink {
                    prev: last,
                    next: first,
                };
                self.edge_mut(last).disk[last_side].next = e;
                self.edge_mut(first).disk[first_side].prev = e;
            }
        }
    }

    /// Removes `e` from the disk cycle of its end `v`.
    fn disk_remove(&mut self, e: EdgeId, v: VertId) {
        let side = self.edge(e).side(v);
        let DiskLink { prev, next } = self.edge(e).disk[side];
        if next == e {
            self.vert_mut(v).edge = None;
        } else {
            let prev_side = self.edge(prev).side(v);
            let next_side = self.edge(next).side(v);
            self.edge_mut(prev).disk[prev_side].next = next;
            self.edge_mut(next).disk[next_side].prev = prev;
            if self.vert(v).edge == Some(e) {
                self.vert_mut(v).edge = Some(next);
            }
        }
    }

    fn radial_insert(&mut self, l: LoopId, e: EdgeId) {
        match self.edge(e).first_loop {
            None => {
                let lp = self.loop_mut(l);
                lp.radial_next = l;
                lp.radial_prev = l;
                self.edge_mut(e).first_loop = Some(l);
            }
            Some(first) => {
                let last = self.lp(first).radial_prev;
                {
                    let lp = self.loop_mut(l);
                    lp.radial_prev = last;
                    lp.radial_next = first;
                }
                self.loop_mut(last).radial_next = l;
                self.loop_mut(first).radial_prev = l;
            }
        }
        self.loop_mut(l).edge = e;
    }

    fn radial_remove(&mut self, l: LoopId) {
        let Loop {
            edge,
            radial_next,
            radial_prev,
            ..
        } = *self.lp(l);
        if radial_next == l {
            self.edge_mut(edge).first_loop = None;
        } else {
            self.loop_mut(radial_prev).radial_next = radial_next;
            self.loop_mut(radial_next).radial_prev = radial_prev;
            if self.edge(edge).first_loop == Some(l) {
                self.edge_mut(edge).first_loop = Some(radial_next);
            }
        }
    }

    fn new_edge_unchecked(&mut self, a: VertId, b: VertId) -> EdgeId {
        let placeholder = DiskLink {
            prev: EdgeId::from_raw(0),
            next: EdgeId::from_raw(0),
        };
        let e = EdgeId::from_raw(self.edges.insert(Edge {
            verts: [a, b],
            disk: [placeholder; 2],
            first_loop: None,
        }));
        self.disk_insert(e, a);
        self.disk_insert(e, b);
        self.attributes.on_new(Domain::Edge, e.index());
        e
    }

    /// Allocates a loop with self-links; the caller links it into its cycles.
    fn new_loop(&mut self, vert: VertId, edge: EdgeId, face: FaceId) -> LoopId {
        let dummy = LoopId::from_raw(0);
        let l = LoopId::from_raw(self.loops.insert(Loop {
            vert,
            edge,
            face,
            next: dummy,
            prev: dummy,
            radial_next: dummy,
            radial_prev: dummy,
        }));
        let lp = self.loop_mut(l);
        lp.next = l;
        lp.prev = l;
        lp.radial_next = l;
        lp.radial_prev = l;
        l
    }

    /// Unlinks `l` from its face's boundary cycle (not from its radial cycle).
    fn boundary_remove(&mut self, l: LoopId) {
        let Loop {
            next, prev, face, ..
        } = *self.lp(l);
        self.loop_mut(prev).next = next;
        self.loop_mut(next).prev = prev;
        let fc = self.face_mut(face);
        fc.len -= 1;
        if fc.first_loop == l {
            fc.first_loop = next;
        }
    }

    // ---- make ----

    /// MakeVert: a new isolated vertex.
    pub fn make_vert(&mut self, position: DVec3) -> VertId {
        let v = VertId::from_raw(self.verts.insert(Vert {
            position,
            edge: None,
            slot: Occupied::Yes,
        }));
        self.attributes.on_new(Domain::Vert, v.index());
        v
    }

    /// MakeEdge: a new wire edge between two existing, distinct, unconnected vertices.
    pub fn make_edge(&mut self, a: VertId, b: VertId) -> Result<EdgeId, KernelError> {
        self.check_two_verts(a, b)?;
        if let Some(e) = self.find_edge(a, b) {
            return Err(KernelError::EdgeExists(a, b, e));
        }
        Ok(self.new_edge_unchecked(a, b))
    }

    /// MakeEdgeVert: a new vertex at `position` joined to `v` by a new wire
    /// edge. The new vertex inherits `v`'s attributes (extrusion semantics).
    pub fn make_edge_vert(
        &mut self,
        v: VertId,
        position: DVec3,
    ) -> Result<(EdgeId, VertId), KernelError> {
        self.check_vert(v)?;
        if !position.is_finite() {
            return Err(KernelError::NonFinite);
        }
        let w = self.make_vert(position);
        self.copy_vert_attrs(v, w);
        let e = self.new_edge_unchecked(v, w);
        Ok((e, w))
    }

    /// MakeFace on a ring of vertices, wound in the given order. Edges that do
    /// not exist yet are made. The ring needs at least 3 distinct live vertices.
    pub fn make_face(&mut self, ring: &[VertId]) -> Result<FaceId, KernelError> {
        self.check_face_ring(ring)?;
        Ok(
            self.make_face_unchecked(ring, Normals::Refresh, |mesh, _, v, w| {
                match mesh.find_edge(v, w) {
                    Some(e) => e,
                    None => mesh.new_edge_unchecked(v, w),
                }
            }),
        )
    }

    /// MakeFace for a bulk builder ([`super::build::KernelBuilder`]): the
    /// face [`Mesh::make_face`] would make, but `ring` is known to be at
    /// least 3 distinct live vertices (the builder cleaned it), and the
    /// stored normal is left zero for one [`Mesh::refresh_normals_of`]
    /// pass over every face the builder made (in parallel, the same bits).
    /// Edges this face is the first to use are pushed to `first_used`, in
    /// ring order: over a build, every edge its faces use, in the order
    /// they were first used.
    pub(in crate::kernel) fn make_face_of_clean_ring(
        &mut self,
        ring: &[VertId],
        first_used: &mut Vec<EdgeId>,
    ) -> FaceId {
        debug_assert!(self.check_face_ring(ring).is_ok());
        self.make_face_unchecked(ring, Normals::Defer, |mesh, _, v, w| {
            let e = match mesh.find_edge(v, w) {
                Some(e) => e,
                None => mesh.new_edge_unchecked(v, w),
            };
            // A simple ring uses an edge once, so no earlier side of this
            // face has taken it.
            if mesh.edge(e).first_loop.is_none() {
                first_used.push(e);
            }
            e
        })
    }

    /// MakeFace on a ring of vertices whose sides already exist as the given
    /// edges (`edges[i]` joins `ring[i]` and `ring[i + 1]`, the last joins
    /// the last vertex to the first): the face [`Mesh::make_face`] would
    /// make, without searching disk cycles for edges the caller holds.
    pub fn make_face_on_edges(
        &mut self,
        ring: &[VertId],
        edges: &[EdgeId],
    ) -> Result<FaceId, KernelError> {
        self.make_face_on_edges_with(ring, edges, Normals::Refresh)
    }

    /// [`Mesh::make_face_on_edges`] leaving the stored normal zero, for an
    /// operator that moves the new face's corners and then refreshes it
    /// (mirror: copy, reflect, reverse), so the normal is computed once.
    pub(in crate::kernel) fn make_face_on_edges_unrefreshed(
        &mut self,
        ring: &[VertId],
        edges: &[EdgeId],
    ) -> Result<FaceId, KernelError> {
        self.make_face_on_edges_with(ring, edges, Normals::Defer)
    }

    fn make_face_on_edges_with(
        &mut self,
        ring: &[VertId],
        edges: &[EdgeId],
        normals: Normals,
    ) -> Result<FaceId, KernelError> {
        self.check_face_ring(ring)?;
        if edges.len() != ring.len() {
            return Err(KernelError::SideCount {
                verts: ring.len(),
                edges: edges.len(),
            });
        }
        for (i, &e) in edges.iter().enumerate() {
            self.check_edge(e)?;
            let (v, w) = (ring[i], ring[(i + 1) % ring.len()]);
            if !matches!(self.edge_verts(e), [a, b] if (a, b) == (v, w) || (b, a) == (v, w)) {
                return Err(KernelError::NotARing(e));
            }
        }
        Ok(self.make_face_unchecked(ring, normals, |_, i, _, _| edges[i]))
    }

    /// The edge joining two distinct live vertices, made (as a wire edge)
    /// if there is none; `true` when it was made.
    pub fn find_or_make_edge(
        &mut self,
        a: VertId,
        b: VertId,
    ) -> Result<(EdgeId, bool), KernelError> {
        self.check_two_verts(a, b)?;
        Ok(match self.find_edge(a, b) {
            Some(e) => (e, false),
            None => (self.new_edge_unchecked(a, b), true),
        })
    }

    /// Two distinct live vertices.
    fn check_two_verts(&self, a: VertId, b: VertId) -> Result<(), KernelError> {
        self.check_vert(a)?;
        self.check_vert(b)?;
        if a == b {
            return Err(KernelError::SameVertex(a));
        }
        Ok(())
    }

    /// At least 3 distinct live vertices.
    fn check_face_ring(&self, ring: &[VertId]) -> Result<(), KernelError> {
        if ring.len() < 3 {
            return Err(KernelError::TooFewVertices(ring.len()));
        }
        for &v in ring {
            self.check_vert(v)?;
        }
        match repeated_vertex(ring) {
            Some(v) => Err(KernelError::RepeatedVertex(v)),
            None => Ok(()),
        }
    }

    /// MakeFace on a checked ring; `side(mesh, i, v, w)` gives the edge
    /// joining `ring[i]` = v to the next vertex w, making it if need be.
    fn make_face_unchecked(
        &mut self,
        ring: &[VertId],
        normals: Normals,
        mut side: impl FnMut(&mut Self, usize, VertId, VertId) -> EdgeId,
    ) -> FaceId {
        let f = FaceId::from_raw(self.faces.insert(Face {
            first_loop: LoopId::from_raw(0),
            len: ring.len() as u32,
            normal: DVec3::ZERO,
        }));
        let mut first: Option<LoopId> = None;
        let mut prev: Option<LoopId> = None;
        for (i, &v) in ring.iter().enumerate() {
            let w = ring[(i + 1) % ring.len()];
            let e = side(self, i, v, w);
            let l = self.new_loop(v, e, f);
            self.radial_insert(l, e);
            if let Some(p) = prev {
                self.loop_mut(p).next = l;
                self.loop_mut(l).prev = p;
            }
            first.get_or_insert(l);
            prev = Some(l);
        }
        let (first, last) = (
            first.expect("ring not empty"),
            prev.expect("ring not empty"),
        );
        self.loop_mut(last).next = first;
        self.loop_mut(first).prev = last;
        self.face_mut(f).first_loop = first;
        self.attributes.on_new(Domain::Face, f.index());
        if normals == Normals::Refresh {
            // The ring is the face's corners from its first loop on: the
            // same points, in the same order, as `compute_face_normal`
            // reads, so the same bits, without walking back through the
            // loops just written.
            let normal = self.ring_normal(ring);
            self.face_mut(f).normal = normal;
        }
        f
    }

    /// The unit normal of a new face's ring (zero when degenerate), as
    /// [`Mesh::compute_face_normal`] would compute it from the face.
    fn ring_normal(&self, ring: &[VertId]) -> DVec3 {
        normal_of_corners(ring.len(), ring.iter().map(|&v| self.position(v)))
    }

    /// MakeFace on a ring of edges given in ring order (each edge shares a
    /// vertex with the next, the last with the first).
    pub fn make_face_from_edges(&mut self, ring: &[EdgeId]) -> Result<FaceId, KernelError> {
        if ring.len() < 3 {
            return Err(KernelError::TooFewVertices(ring.len()));
        }
        for &e in ring {
            self.check_edge(e)?;
        }
        // The start vertex of edge 0 is the one it does not share with edge 1.
        let [a, b] = self.edge_verts(ring[0]);
        let next_verts = self.edge_verts(ring[1]);
        let mut current = if next_verts.contains(&b) {
            a
        } else if next_verts.contains(&a) {
            b
        } else {
            return Err(KernelError::NotARing(ring[1]));
        };
        let start = current;
        let mut verts = Vec::with_capacity(ring.len());
        for &e in ring {
            let [x, y] = self.edge_verts(e);
            verts.push(current);
            current = if x == current {
                y
            } else if y == current {
                x
            } else {
                return Err(KernelError::NotARing(e));
            };
        }
        if current != start {
            return Err(KernelError::NotARing(ring[ring.len() - 1]));
        }
        self.make_face(&verts)
    }

    // ---- split ----

    /// Splits face `f` by a new edge from `a` to `b` (two non-adjacent
    /// vertices of `f`). `f` keeps the part from `a` to `b` in winding order;
    /// the returned new face (a copy of `f`'s attributes) gets the rest. An
    /// existing edge between `a` and `b` (used by other faces) is reused.
    pub fn split_face(
        &mut self,
        f: FaceId,
        a: VertId,
        b: VertId,
    ) -> Result<(FaceId, EdgeId), KernelError> {
        let (g, e) = self.split_face_unrefreshed(f, a, b)?;
        self.refresh_normal(f);
        self.refresh_normal(g);
        Ok((g, e))
    }

    /// [`Mesh::split_face`], then each piece's boundary starts at `first`
    /// where the piece has that corner (where it has not, it starts as
    /// `split_face` leaves it: `f` at `a`, the new face at `b`). What
    /// `triangulate` uses to split a quad in place with its triangles
    /// listed from the quad's first corner, as if made corner by corner.
    pub fn split_face_starting_at(
        &mut self,
        f: FaceId,
        a: VertId,
        b: VertId,
        first: VertId,
    ) -> Result<(FaceId, EdgeId), KernelError> {
        let (g, e) = self.split_face_unrefreshed(f, a, b)?;
        for piece in [f, g] {
            if let Some(l) = self.face_loop_at(piece, first) {
                self.face_mut(piece).first_loop = l;
            }
            // After the restart: a normal sums its corners in boundary order.
            self.refresh_normal(piece);
        }
        Ok((g, e))
    }

    /// The four corners of quad `f` from its first, or `None` when `f` is
    /// not a quad. Panics on a dead id.
    pub fn quad_loops(&self, f: FaceId) -> Option<[LoopId; 4]> {
        let face = self.face(f);
        if face.len != 4 {
            return None;
        }
        let l0 = face.first_loop;
        let l1 = self.lp(l0).next;
        let l2 = self.lp(l1).next;
        Some([l0, l1, l2, self.lp(l2).next])
    }

    /// SplitQuad: [`Mesh::split_face_starting_at`] for a quad whose corners
    /// `loops` ([`Mesh::quad_loops`]) the caller has read, along its 0–2
    /// diagonal or its 1–3 one, in closed form: the same records, ids,
    /// cycles and normals as that operator, without its searches (the
    /// corners are known, each piece's first loop and length too).
    /// `triangulate` splits every quad this way (issue 38: the row where
    /// graftal was furthest behind its peers). Returns the new face, the
    /// diagonal and whether the diagonal was made (another face may have
    /// made it already).
    pub fn split_quad(
        &mut self,
        f: FaceId,
        loops: [LoopId; 4],
        along_0_2: bool,
    ) -> (FaceId, EdgeId, bool) {
        let corners = loops.map(|l| self.position(self.lp(l).vert));
        let normals = Self::quad_piece_normals(&corners, along_0_2);
        self.split_quad_with_normals(f, loops, along_0_2, normals)
    }

    /// The stored normals [`Mesh::split_quad`] gives its two pieces (the
    /// face kept, then the new one), from the quad's corner positions in
    /// ring order: each piece's corners are taken from its first loop on,
    /// as `compute_face_normal` reads them, so the bits are the same.
    /// `triangulate` computes them in its parallel pass over the quads,
    /// which has the corners at hand (issue 38: a second pass walked
    /// every piece's loops again to refresh them).
    pub(in crate::kernel) fn quad_piece_normals(
        corners: &[DVec3; 4],
        along_0_2: bool,
    ) -> [DVec3; 2] {
        let [c0, c1, c2, c3] = *corners;
        // Along 0–2: f is 0 1 2 from corner 0, g is 0 2 3 from its
        // closing loop. Along 1–3: f is 0 1 3 from corner 0, g is 1 2 3
        // from corner 1 (see `split_quad_unrefreshed`).
        if along_0_2 {
            [normal_of(&[c0, c1, c2]), normal_of(&[c0, c2, c3])]
        } else {
            [normal_of(&[c0, c1, c3]), normal_of(&[c1, c2, c3])]
        }
    }

    /// [`Mesh::split_quad`] storing the pieces' normals the caller computed
    /// with [`Mesh::quad_piece_normals`] from the corners of `loops`.
    pub(in crate::kernel) fn split_quad_with_normals(
        &mut self,
        f: FaceId,
        loops: [LoopId; 4],
        along_0_2: bool,
        normals: [DVec3; 2],
    ) -> (FaceId, EdgeId, bool) {
        let split = self.split_quad_unrefreshed(f, loops, along_0_2);
        self.face_mut(f).normal = normals[0];
        self.face_mut(split.0).normal = normals[1];
        debug_assert_eq!(
            [f, split.0].map(|face| self.compute_face_normal(face).to_array().map(f64::to_bits)),
            normals.map(|n| n.to_array().map(f64::to_bits)),
            "the normals given are the pieces' own"
        );
        split
    }

    /// [`Mesh::split_quad`] leaving both pieces' stored normals to the
    /// caller (`triangulate` refreshes every piece in one parallel pass).
    pub(in crate::kernel) fn split_quad_unrefreshed(
        &mut self,
        f: FaceId,
        loops: [LoopId; 4],
        along_0_2: bool,
    ) -> (FaceId, EdgeId, bool) {
        let [l0, l1, l2, l3] = loops;
        let [v0, v1, v2, v3] = loops.map(|l| self.lp(l).vert);
        // `split_face_unrefreshed(f, a, b)` with la, lb the loops at a, b:
        // f keeps a .. before_b and the closing b → a, the new face g
        // takes b .. before_a and a → b.
        let (a, b, la, lb, before_a, before_b) = if along_0_2 {
            (v0, v2, l0, l2, l3, l1)
        } else {
            (v3, v1, l3, l1, l2, l0)
        };
        let (e, made) = match self.find_edge(a, b) {
            Some(e) => (e, false),
            None => (self.new_edge_unchecked(a, b), true),
        };
        let g = FaceId::from_raw(self.faces.insert(Face {
            first_loop: lb,
            len: 3,
            normal: DVec3::ZERO,
        }));
        self.attributes.on_new(Domain::Face, g.index());
        self.copy_face_attrs(f, g);
        // The two closing loops are written with their boundary links;
        // a new diagonal's radial cycle is just the pair (what two
        // `radial_insert`s leave).
        let closing_f = LoopId::from_raw(self.loops.insert(Loop {
            vert: b,
            edge: e,
            face: f,
            next: la,
            prev: before_b,
            radial_next: la,
            radial_prev: la,
        }));
        let closing_g = LoopId::from_raw(self.loops.insert(Loop {
            vert: a,
            edge: e,
            face: g,
            next: lb,
            prev: before_a,
            radial_next: closing_f,
            radial_prev: closing_f,
        }));
        if made {
            let cf = self.loop_mut(closing_f);
            cf.radial_next = closing_g;
            cf.radial_prev = closing_g;
            self.edge_mut(e).first_loop = Some(closing_f);
        } else {
            self.radial_insert(closing_f, e);
            self.radial_insert(closing_g, e);
        }
        self.loop_mut(before_b).next = closing_f;
        self.loop_mut(la).prev = closing_f;
        let lp = self.loop_mut(before_a);
        lp.next = closing_g;
        lp.face = g;
        let lp = self.loop_mut(lb);
        lp.prev = closing_g;
        lp.face = g;
        // Each piece restarts at corner 0 where it has it: f always (at
        // l0), g only along 0–2 (at its closing loop); along 1–3 g keeps
        // starting at corner 1.
        if along_0_2 {
            self.face_mut(g).first_loop = closing_g;
        }
        let fc = self.face_mut(f);
        fc.len = 3;
        fc.first_loop = l0;
        (g, e, made)
    }

    /// The topology of [`Mesh::split_face`]; both pieces' stored normals
    /// are left for the caller to refresh.
    pub(in crate::kernel) fn split_face_unrefreshed(
        &mut self,
        f: FaceId,
        a: VertId,
        b: VertId,
    ) -> Result<(FaceId, EdgeId), KernelError> {
        self.check_face(f)?;
        self.check_two_verts(a, b)?;
        let la = self
            .face_loop_at(f, a)
            .ok_or(KernelError::NotInFace { vert: a, face: f })?;
        let lb = self
            .face_loop_at(f, b)
            .ok_or(KernelError::NotInFace { vert: b, face: f })?;
        if self.lp(la).next == lb || self.lp(lb).next == la {
            return Err(KernelError::AdjacentInFace(a, b, f));
        }
        let e = match self.find_edge(a, b) {
            Some(e) => e,
            None => self.new_edge_unchecked(a, b),
        };
        let g = FaceId::from_raw(self.faces.insert(Face {
            first_loop: lb,
            len: 0,
            normal: DVec3::ZERO,
        }));
        self.attributes.on_new(Domain::Face, g.index());
        self.copy_face_attrs(f, g);

        let before_b = self.lp(lb).prev;
        let before_a = self.lp(la).prev;
        // f: a .. before_b, then b -> a.   g: b .. before_a, then a -> b.
        let closing_f = self.new_loop(b, e, f);
        let closing_g = self.new_loop(a, e, g);
        self.radial_insert(closing_f, e);
        self.radial_insert(closing_g, e);
        self.loop_mut(before_b).next = closing_f;
        self.loop_mut(closing_f).prev = before_b;
        self.loop_mut(closing_f).next = la;
        self.loop_mut(la).prev = closing_f;
        self.loop_mut(before_a).next = closing_g;
        self.loop_mut(closing_g).prev = before_a;
        self.loop_mut(closing_g).next = lb;
        self.loop_mut(lb).prev = closing_g;

        let mut len_g = 0;
        let mut l = lb;
        loop {
            self.loop_mut(l).face = g;
            len_g += 1;
            if l == closing_g {
                break;
            }
            l = self.lp(l).next;
        }
        let len_f = self.face(f).len + 2 - len_g;
        self.face_mut(g).len = len_g;
        let fc = self.face_mut(f);
        fc.len = len_f;
        fc.first_loop = la;
        Ok((g, e))
    }

    /// Splits edge `e` = (v0, v1) at parameter `t` (0 at v0, 1 at v1) with a
    /// new vertex `w`: `e` becomes (v0, w) and the returned new edge is
    /// (w, v1). Faces using `e` gain the new vertex. `w` interpolates the
    /// vertex attributes of v0 and v1; the new edge copies `e`'s.
    pub fn split_edge(&mut self, e: EdgeId, t: f64) -> Result<(VertId, EdgeId), KernelError> {
        let (w, e2) = self.split_edge_unrefreshed(e, t)?;
        // A corner more changes the faces' Newell sums in the last bits.
        self.refresh_faces_around(w);
        Ok((w, e2))
    }

    /// [`Mesh::split_edge`] leaving the stored normals of the edge's faces
    /// to the caller (an operator that refreshes every face it touched,
    /// once, before it returns).
    pub(in crate::kernel) fn split_edge_unrefreshed(
        &mut self,
        e: EdgeId,
        t: f64,
    ) -> Result<(VertId, EdgeId), KernelError> {
        self.check_edge(e)?;
        if !t.is_finite() {
            return Err(KernelError::NonFinite);
        }
        let [v0, v1] = self.edge_verts(e);
        let position = self.position(v0).lerp(self.position(v1), t);
        let w = self.make_vert(position);
        self.interpolate_vert_attrs(v0, v1, t, w);

        // Re-end `e` at w instead of v1.
        self.disk_remove(e, v1);
        self.edge_mut(e).verts[1] = w;
        self.disk_insert(e, w);
        let e2 = self.new_edge_unchecked(w, v1);
        self.copy_edge_attrs(e, e2);

        let loops: Vec<LoopId> = self.edge_loops(e).collect();
        for l in loops {
            let Loop {
                vert, face, next, ..
            } = *self.lp(l);
            let inserted = if vert == v0 {
                // v0 -> v1 becomes v0 -(e)-> w -(e2)-> v1.
                let n = self.new_loop(w, e2, face);
                self.radial_insert(n, e2);
                n
            } else {
                // v1 -> v0 becomes v1 -(e2)-> w -(e)-> v0.
                self.radial_remove(l);
                self.radial_insert(l, e2);
                let n = self.new_loop(w, e, face);
                self.radial_insert(n, e);
                n
            };
            self.loop_mut(l).next = inserted;
            self.loop_mut(inserted).prev = l;
            self.loop_mut(inserted).next = next;
            self.loop_mut(next).prev = inserted;
            self.face_mut(face).len += 1;
        }
        Ok((w, e2))
    }

    // ---- join / collapse / glue ----

    /// Dissolves edge `e`, joining its two faces into the lower-id one, which
    /// is returned. A face wound against the other is flipped first.
    pub fn join_faces(&mut self, e: EdgeId) -> Result<FaceId, KernelError> {
        self.check_edge(e)?;
        let loops: Vec<LoopId> = self.edge_loops(e).collect();
        let faces: Vec<FaceId> = loops.iter().map(|&l| self.lp(l).face).collect();
        if loops.len() != 2 || faces[0] == faces[1] {
            return Err(KernelError::NotTwoFaces {
                edge: e,
                faces: loops.len(),
            });
        }
        let ends = self.edge_verts(e);
        let mut seen: Vec<VertId> = self
            .face_verts(faces[0])
            .chain(self.face_verts(faces[1]))
            .filter(|v| !ends.contains(v))
            .collect();
        seen.sort_unstable();
        if let Some(w) = seen.windows(2).find(|w| w[0] == w[1]) {
            return Err(KernelError::JoinRepeatsVertex {
                edge: e,
                vert: w[0],
            });
        }
        let (keep_index, kill_index) = if faces[0] < faces[1] { (0, 1) } else { (1, 0) };
        let (keep, kill) = (faces[keep_index], faces[kill_index]);
        if self.lp(loops[0]).vert == self.lp(loops[1]).vert {
            self.reverse_face_links(kill);
        }
        let l_keep = loops[keep_index];
        let l_kill = loops[kill_index];
        let (keep_prev, keep_next) = (self.lp(l_keep).prev, self.lp(l_keep).next);
        let (kill_prev, kill_next) = (self.lp(l_kill).prev, self.lp(l_kill).next);
        // keep: .. keep_prev -> [e] -> keep_next ..; kill: .. kill_prev -> [e] -> kill_next ..
        self.loop_mut(keep_prev).next = kill_next;
        self.loop_mut(kill_next).prev = keep_prev;
        self.loop_mut(kill_prev).next = keep_next;
        self.loop_mut(keep_next).prev = kill_prev;
        let mut l = kill_next;
        while l != keep_next {
            self.loop_mut(l).face = keep;
            l = self.lp(l).next;
        }
        let len = self.face(keep).len + self.face(kill).len - 2;
        self.radial_remove(l_keep);
        self.radial_remove(l_kill);
        self.loops.remove(l_keep.raw());
        self.loops.remove(l_kill.raw());
        self.faces.remove(kill.raw());
        let fc = self.face_mut(keep);
        fc.len = len;
        fc.first_loop = keep_next;
        let [a, b] = ends;
        self.disk_remove(e, a);
        self.disk_remove(e, b);
        self.edges.remove(e.raw());
        self.refresh_normal(keep);
        Ok(keep)
    }

    /// Squeezes edge `e` to its end `keep`, which moves to `position`; the
    /// other end is deleted. Faces using `e` lose a corner (triangles
    /// vanish); edges that come to share both ends are merged.
    pub fn collapse_edge(
        &mut self,
        e: EdgeId,
        keep: VertId,
        position: DVec3,
    ) -> Result<VertId, KernelError> {
        self.collapse_edge_with(e, keep, position, Normals::Refresh)
    }

    fn collapse_edge_with(
        &mut self,
        e: EdgeId,
        keep: VertId,
        position: DVec3,
        normals: Normals,
    ) -> Result<VertId, KernelError> {
        self.check_edge(e)?;
        let [a, b] = self.edge_verts(e);
        if keep != a && keep != b {
            return Err(KernelError::NotAnEnd {
                vert: keep,
                edge: e,
            });
        }
        if !position.is_finite() {
            return Err(KernelError::NonFinite);
        }
        let gone = if keep == a { b } else { a };
        let edge_faces: Vec<FaceId> = self.edge_faces(e).collect();
        self.check_glue(keep, gone, &edge_faces)?;

        for l in self.edge_loops(e).collect::<Vec<_>>() {
            let face = self.lp(l).face;
            if self.face(face).len == 3 {
                self.kill_face_unchecked(face);
            } else {
                self.radial_remove(l);
                self.boundary_remove(l);
                self.loops.remove(l.raw());
            }
        }
        self.disk_remove(e, a);
        self.disk_remove(e, b);
        self.edges.remove(e.raw());
        self.merge_vert_into(keep, gone);
        self.place(keep, position);
        if normals == Normals::Refresh {
            self.refresh_faces_around(keep);
        }
        Ok(keep)
    }

    /// Glues vertex `gone` onto `keep` (GlueVert). If an edge joins them it
    /// is collapsed; otherwise they must not share a face. Edges that come to
    /// share both ends are merged. `keep` keeps its position.
    pub fn glue_verts(&mut self, keep: VertId, gone: VertId) -> Result<VertId, KernelError> {
        self.glue_verts_with(keep, gone, Normals::Refresh, SharedFaces::Check)
    }

    /// [`Mesh::glue_verts`] for a weld that has killed every face holding
    /// two vertices of one cluster first (so no face holds both `keep` and
    /// `gone`), leaving the stored normals of the faces around `keep` as
    /// they were: it refreshes each changed face once (issue 17: the soup
    /// weld computed ≈ 10 normals per face). The walk over `gone`'s faces
    /// that checks for a shared face is skipped (issue 38: a weld glues a
    /// million vertices); debug builds still make it.
    pub(in crate::kernel) fn glue_verts_sharing_no_face(
        &mut self,
        keep: VertId,
        gone: VertId,
    ) -> Result<VertId, KernelError> {
        self.glue_verts_with(keep, gone, Normals::Defer, SharedFaces::NoneByConstruction)
    }

    fn glue_verts_with(
        &mut self,
        keep: VertId,
        gone: VertId,
        normals: Normals,
        shared: SharedFaces,
    ) -> Result<VertId, KernelError> {
        self.check_two_verts(keep, gone)?;
        // Only `gone`'s cycle is searched: the merge below walks all of it
        // anyway, where `find_edge`'s lockstep also reads `keep`'s edges,
        // scattered (issue 38: a soup weld glues a million vertices of
        // degree 2 onto survivors of degree 6 and more).
        let joining = self
            .vert_edges(gone)
            .find(|&e| self.edge_other_vert(e, gone) == keep);
        if let Some(e) = joining {
            let position = self.position(keep);
            return self.collapse_edge_with(e, keep, position, normals);
        }
        match shared {
            SharedFaces::Check => self.check_glue(keep, gone, &[])?,
            SharedFaces::NoneByConstruction => {
                debug_assert!(self.check_glue(keep, gone, &[]).is_ok());
            }
        }
        self.merge_vert_into(keep, gone);
        if normals == Normals::Refresh {
            self.refresh_faces_around(keep);
        }
        Ok(keep)
    }

    /// Glues edge `gone` onto edge `keep` (GlueEdge): the ends of `gone` are
    /// glued to the ends of `keep` (a shared end stays; otherwise end i to
    /// end i), then the two edges, now parallel, merge into `keep`.
    pub fn glue_edges(&mut self, keep: EdgeId, gone: EdgeId) -> Result<EdgeId, KernelError> {
        self.check_edge(keep)?;
        self.check_edge(gone)?;
        if keep == gone {
            return Ok(keep);
        }
        let [k0, k1] = self.edge_verts(keep);
        let [mut g0, mut g1] = self.edge_verts(gone);
        if g0 == k1 || g1 == k0 {
            std::mem::swap(&mut g0, &mut g1);
        }
        // Check both glues on the unchanged mesh: gluing g0 onto k0 renames
        // g0 only, so it cannot create or remove a face holding both k1 and g1.
        if g0 != k0 {
            self.check_glue_pair(k0, g0)?;
        }
        if g1 != k1 {
            self.check_glue_pair(k1, g1)?;
        }
        if g0 != k0 {
            self.glue_verts(k0, g0)?;
        }
        if g1 != k1 {
            self.glue_verts(k1, g1)?;
        }
        Ok(self.find_edge(k0, k1).unwrap_or(keep))
    }

    /// The precondition of [`Mesh::glue_verts`] without the change.
    fn check_glue_pair(&self, keep: VertId, gone: VertId) -> Result<(), KernelError> {
        match self.find_edge(keep, gone) {
            Some(e) => {
                let faces: Vec<FaceId> = self.edge_faces(e).collect();
                self.check_glue(keep, gone, &faces)
            }
            None => self.check_glue(keep, gone, &[]),
        }
    }

    /// Fails if gluing `gone` onto `keep` would put a vertex twice on a face:
    /// any face holding both that is not in `allowed` (faces of the edge
    /// being collapsed, which lose the corner instead).
    fn check_glue(
        &self,
        keep: VertId,
        gone: VertId,
        allowed: &[FaceId],
    ) -> Result<(), KernelError> {
        for f in self.vert_faces(gone) {
            if !allowed.contains(&f) && self.face_contains_vert(f, keep) {
                return Err(KernelError::GlueWithinFace {
                    a: keep,
                    b: gone,
                    face: f,
                });
            }
        }
        Ok(())
    }

    /// Moves everything of `gone` onto `keep` and deletes `gone`. Callers
    /// have checked that no face holds both.
    ///
    /// Edges are taken from the head of `gone`'s disk cycle until it is
    /// empty and loops from the head of a radial cycle (each removal moves
    /// the head to the next), so both go in cycle order without being
    /// collected: a weld glues hundreds of thousands of vertices.
    fn merge_vert_into(&mut self, keep: VertId, gone: VertId) {
        while let Some(eg) = self.vert(gone).edge {
            // The corners of `gone` on this edge's faces become corners of
            // `keep` (each face has one: no face holds both).
            let mut at = self.edge(eg).first_loop;
            while let Some(l) = at {
                if self.lp(l).vert == gone {
                    self.loop_mut(l).vert = keep;
                }
                let next = self.lp(l).radial_next;
                at = (Some(next) != self.edge(eg).first_loop).then_some(next);
            }
            let other = self.edge_other_vert(eg, gone);
            self.disk_remove(eg, gone);
            match self.find_edge(keep, other) {
                Some(ek) => {
                    // Parallel edges: move eg's loops onto ek, delete eg.
                    while let Some(l) = self.edge(eg).first_loop {
                        self.radial_remove(l);
                        self.radial_insert(l, ek);
                    }
                    self.disk_remove(eg, other);
                    self.edges.remove(eg.raw());
                }
                None => {
                    let side = self.edge(eg).side(gone);
                    self.edge_mut(eg).verts[side] = keep;
                    self.disk_insert(eg, keep);
                }
            }
        }
        self.verts.remove(gone.raw());
    }

    /// Swaps the ends of edge `e`: its first vertex becomes its second. Only
    /// the edge's own record changes (each disk link moves with its vertex);
    /// loops and faces do not depend on which end comes first.
    pub fn reverse_edge(&mut self, e: EdgeId) -> Result<(), KernelError> {
        self.check_edge(e)?;
        let edge = self.edge_mut(e);
        edge.verts.swap(0, 1);
        edge.disk.swap(0, 1);
        Ok(())
    }

    /// Flips the winding of face `f`. Edges keep their loops; each loop now
    /// starts at the other end of its edge.
    pub fn reverse_face(&mut self, f: FaceId) -> Result<(), KernelError> {
        self.check_face(f)?;
        self.reverse_face_links(f);
        self.refresh_normal(f);
        Ok(())
    }

    fn reverse_face_links(&mut self, f: FaceId) {
        // Loop i ran v_i -> v_{i+1}; it now runs v_{i+1} -> v_i. Walked
        // once around without collecting (extrusion reverses every face
        // it keeps): loop i reads v_{i+1} before loop i + 1 is rewritten.
        let face = self.face(f);
        let (first, len) = (face.first_loop, face.len);
        let first_vert = self.lp(first).vert;
        let mut l = first;
        for i in 0..len {
            let next = self.lp(l).next;
            let vert = if i + 1 == len {
                first_vert
            } else {
                self.lp(next).vert
            };
            let lp = self.loop_mut(l);
            lp.vert = vert;
            std::mem::swap(&mut lp.next, &mut lp.prev);
            l = next;
        }
    }

    // ---- kill ----

    /// KillFace: deletes a face and its loops; its edges and vertices stay.
    pub fn kill_face(&mut self, f: FaceId) -> Result<(), KernelError> {
        self.check_face(f)?;
        self.kill_face_unchecked(f);
        Ok(())
    }

    fn kill_face_unchecked(&mut self, f: FaceId) {
        // Radial unlinking leaves the boundary links alone, so the boundary
        // can be walked while its loops go.
        let (mut l, len) = (self.face(f).first_loop, self.face(f).len);
        for _ in 0..len {
            let next = self.lp(l).next;
            self.radial_remove(l);
            self.loops.remove(l.raw());
            l = next;
        }
        self.faces.remove(f.raw());
    }

    /// KillEdge: deletes an edge and every face using it.
    pub fn kill_edge(&mut self, e: EdgeId) -> Result<(), KernelError> {
        self.check_edge(e)?;
        let faces: Vec<FaceId> = self.edge_faces(e).collect();
        for f in faces {
            self.kill_face_unchecked(f);
        }
        let [a, b] = self.edge_verts(e);
        self.disk_remove(e, a);
        self.disk_remove(e, b);
        self.edges.remove(e.raw());
        Ok(())
    }

    /// KillVert: deletes a vertex with its edges and their faces.
    pub fn kill_vert(&mut self, v: VertId) -> Result<(), KernelError> {
        self.check_vert(v)?;
        while let Some(e) = self.vert(v).edge {
            self.kill_edge(e)?;
        }
        self.verts.remove(v.raw());
        Ok(())
    }

    /// Appends a copy of `other` (elements in id order, attributes of
    /// same-named layers carried; other layers are added).
    pub fn join_mesh(&mut self, other: &Mesh) -> JoinMap {
        for layer in other.attributes.layers() {
            let _ = self.add_layer(&layer.name, layer.domain, layer.default);
        }
        let mut map = JoinMap {
            verts: vec![None; other.vert_capacity()],
            edges: vec![None; other.edge_capacity()],
            faces: vec![None; other.face_capacity()],
        };
        for v in other.vert_ids() {
            let nv = self.make_vert(other.position(v));
            self.attributes
                .copy_from(&other.attributes, Domain::Vert, v.index(), nv.index());
            map.verts[v.index()] = Some(nv);
        }
        let vmap = |v: VertId, map: &JoinMap| map.verts[v.index()].expect("live vertex");
        for e in other.edge_ids() {
            let [a, b] = other.edge_verts(e);
            let ne = self.new_edge_unchecked(vmap(a, &map), vmap(b, &map));
            self.attributes
                .copy_from(&other.attributes, Domain::Edge, e.index(), ne.index());
            map.edges[e.index()] = Some(ne);
        }
        for f in other.face_ids() {
            let ring: Vec<VertId> = other.face_verts(f).map(|v| vmap(v, &map)).collect();
            let nf = self
                .make_face(&ring)
                .expect("a valid mesh's faces are valid rings");
            self.attributes
                .copy_from(&other.attributes, Domain::Face, f.index(), nf.index());
            map.faces[f.index()] = Some(nf);
        }
        map
    }
}
