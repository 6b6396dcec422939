//! Intersection tests (thesis 003 §3.2): exact narrow-phase predicates on
//! segments and triangles, a BVH broad phase, whole-mesh self-intersection,
//! an incremental index for growth tests, and close-vertex detection.
//!
//! # Primitives
//!
//! Edges are segments; faces are their triangles. A face is triangulated by
//! [`polygon::triangulate`] (the writers' triangulation), so a non-planar or
//! non-convex n-gon has one defined triangle set (thesis §3.2.4: "for the
//! result of intersection to be defined without ambiguities"). Triangles of
//! the same face are never tested against each other.
//!
//! # Touching
//!
//! All primitives are closed sets. With thickness 0, two primitives
//! intersect when they share at least one point: a proper crossing, an
//! endpoint or corner lying on the other primitive, coplanar or collinear
//! overlap, and coincident endpoints all count. The decision uses only the
//! signs of exact `orient3d` / `orient2d` (see [`predicates`]), so it does not
//! depend on rounding. With thickness `h > 0` two primitives intersect when
//! their distance is at most `h` (capsules around segments; thesis §3.2.1
//! checks the line parameters against `−h` and `l + h`, which this closest-
//! point test makes exact in geometry, though not in arithmetic).
//!
//! # Shared vertices
//!
//! Primitives that share vertices (the same [`VertId`]) always touch there.
//! The rule: **two primitives intersect unless every point they share lies
//! on their shared vertices or on a shared mesh edge.** A shared mesh edge is
//! an edge both primitives have on their boundary: a segment's own edge, a
//! triangle edge that is an edge of its face (not a triangulation diagonal).
//! Per number of shared vertices:
//!
//! - **none**: the plain test.
//! - **one, `v`**: for convex `A`, `B` with `v` a corner of both,
//!   `A ∩ B ≠ {v}` exactly when `hull(A \ v)` meets `B` or `hull(B \ v)`
//!   meets `A` — the edge opposite `v` (for a segment: its other end) tested
//!   against the whole other primitive. Proof: if `A ∩ B` holds a point
//!   `p ≠ v`, walk from `v` through `p`; the ray leaves `A` at a point of
//!   `hull(A \ v)` and `B` at a point of `hull(B \ v)` (`v` is a corner, so
//!   a ray from it exits through the opposite side); the nearer exit lies in
//!   both. Conversely `hull(A \ v)` does not contain `v`. So the test is
//!   exact and not merely local: a pair sharing a vertex that also crosses
//!   far away is caught, a pair touching only at `v` is not. If `v` is not a
//!   corner in the geometric sense (a degenerate triangle with `v` inside an
//!   edge, or another corner at the same position) the test reports an
//!   intersection whenever the other primitive touches `v`: conservative.
//!   With thickness, the same two far-part tests are made at distance `h`,
//!   so closeness that only comes from meeting at `v` is ignored.
//! - **two, `u` and `v`**: both primitives contain the segment `u v`. If it
//!   is a shared mesh edge, two triangles intersect only if they are
//!   coplanar and fold onto the same side of it (overlap), and a segment
//!   *is* that edge, so it adds nothing. If `u v` is a diagonal of either
//!   side (a wire edge along a face diagonal, two faces meeting along a
//!   diagonal) they intersect.
//! - **three**: two triangles on the same three vertices (duplicate faces,
//!   or a triangle face repeating part of a larger face, thesis Fig. 3.4 (d))
//!   overlap: they intersect.
//!
//! Contact that is not on shared vertices or edges counts even when it is
//! only touching: a T-junction (a vertex on another face's edge), a part
//! standing on a face, coplanar faces meeting along a segment. That is
//! what a growth test must refuse, and a mesh quality gate should see.
//!
//! # Speed
//!
//! Most candidate pairs of a mesh are neighbours that share a vertex or an
//! edge. Before the exact tests, certified floating-point plane tests (the
//! error bound of Shewchuk's first stage, so a "no" is exact) settle the
//! common cases: one primitive beside the other's plane; the far parts of
//! two neighbours on the two sides of a plane through their shared vertex
//! or edge (flat and smooth surfaces); a far part beyond an edge of the
//! other triangle. Only what they cannot settle reaches the adaptive
//! predicates. Exactly coplanar configurations that are not axis-aligned
//! and not separable that way (rare) cost microseconds per pair.
//!
//! Whole-mesh self-intersection (`pairs`) stores primitives as flat
//! records of vertex indices, specializes these filters to triangles (and
//! adds one more for pairs sharing a vertex: a plane through an edge at
//! that vertex), and hands everything undecided, every segment and every
//! pair with a thickness to [`primitives_intersect`] itself.
//!
//! # Broad phase
//!
//! BVHs over `f32` boxes rounded outward from the `f64` bounds (and widened
//! by each primitive's thickness), so `f32` can add candidates but never
//! lose one; every candidate is decided by the exact `f64` tests. The
//! growth index uses [`obvhs`] trees; whole-mesh self-intersection a
//! Morton-ordered tree of its own, walked against itself on two threads.
//! Traversal order is never part of a result: pair lists are sorted.

pub mod bvh;
mod pairs;
#[cfg(test)]
mod tests;

use glam::DVec3;
use rustc_hash::FxHashMap;

pub use bvh::IntersectionIndex;
pub use pairs::{PairLimits, PairSearch};

use super::ids::{Domain, EdgeId, FaceId, VertId};
use super::mesh::Mesh;
use crate::geom::cells::{CellLists, Cells, NONE};
use crate::geom::polygon;
use crate::geom::predicates::{
    self, orient2d_dropping, orient3d, point_on_segment, shapes_meet, shapes_touch, Plane, Shape,
};
use crate::geom::IndexedMesh;

// ---- the narrow phase on bare geometry ----

/// Segment–segment test (thesis §3.2.1).
///
/// `thickness == 0`: exact; the closed segments share a point (crossing,
/// touching at an endpoint, collinear overlap; zero-length segments are
/// points). `thickness > 0`: their distance is at most `thickness`, robust to
/// parallel and degenerate segments. Negative or NaN thickness counts as 0.
pub fn segment_segment(a0: DVec3, a1: DVec3, b0: DVec3, b1: DVec3, thickness: f64) -> bool {
    shapes_touch(Shape::Segment(a0, a1), Shape::Segment(b0, b1), thickness)
}

/// Exact segment–triangle test (thesis §3.2.2): the closed segment and the
/// closed triangle share a point. A segment in the triangle's plane is
/// decided in 2D; degenerate triangles count as their edges.
pub fn segment_triangle(s0: DVec3, s1: DVec3, t0: DVec3, t1: DVec3, t2: DVec3) -> bool {
    predicates::segment_triangle_exact(s0, s1, t0, t1, t2)
}

/// Exact triangle–triangle test (thesis §3.2.3): the closed triangles share
/// a point, coplanar overlap and containment included.
pub fn triangle_triangle(a: [DVec3; 3], b: [DVec3; 3]) -> bool {
    predicates::triangle_triangle_exact(a, b)
}

// ---- primitives with vertex ids ----

/// A segment or triangle whose corners may name mesh vertices, so that
/// contact at shared vertices and edges can be excused (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Primitive {
    points: [DVec3; 3],
    /// Vertex ids of the corners, [`NO_VERT`] where unknown (a plain
    /// `u32` keeps the struct small and the shared-corner scan cheap).
    verts: [u32; 3],
    /// 2 for a segment, 3 for a triangle.
    len: u8,
    /// Bit `i`: the edge from corner `i` to corner `i + 1` is a mesh edge
    /// (for a triangle of a face: a face edge, not a diagonal).
    boundary: u8,
    /// A triangle's plane, for quick certified rejections.
    plane: Option<Plane>,
}

impl Primitive {
    /// A segment (an edge).
    pub fn segment(ends: [DVec3; 2], verts: [Option<VertId>; 2]) -> Self {
        Self {
            points: [ends[0], ends[1], ends[1]],
            verts: [id(verts[0]), id(verts[1]), NO_VERT],
            len: 2,
            boundary: 1,
            plane: None,
        }
    }

    /// A triangle whose three edges are all mesh edges (a triangular face).
    pub fn triangle(corners: [DVec3; 3], verts: [Option<VertId>; 3]) -> Self {
        Self::face_triangle(corners, verts, [true; 3])
    }

    /// A triangle of a triangulated face: `boundary[i]` tells whether the
    /// edge from corner `i` to corner `i + 1` is a face edge (`false` for a
    /// triangulation diagonal).
    pub fn face_triangle(
        corners: [DVec3; 3],
        verts: [Option<VertId>; 3],
        boundary: [bool; 3],
    ) -> Self {
        let bits = boundary
            .iter()
            .enumerate()
            .fold(0u8, |acc, (i, &b)| acc | (u8::from(b) << i));
        Self {
            points: corners,
            verts: verts.map(id),
            len: 3,
            boundary: bits,
            plane: Some(Plane::new(corners)),
        }
    }

    /// The corners (two for a segment, three for a triangle).
    pub fn points(&self) -> &[DVec3] {
        &self.points[..self.len as usize]
    }

    /// The vertex ids of the corners, where known.
    pub fn verts(&self) -> impl Iterator<Item = Option<VertId>> + '_ {
        self.verts[..self.len as usize]
            .iter()
            .map(|&v| (v != NO_VERT).then(|| VertId::from_raw(v)))
    }

    pub fn is_segment(&self) -> bool {
        self.len == 2
    }

    fn is_finite(&self) -> bool {
        self.points().iter().all(|p| p.is_finite())
    }

    fn shape(&self) -> Shape {
        let [a, b, c] = self.points;
        if self.len == 2 {
            Shape::Segment(a, b)
        } else {
            Shape::Triangle(a, b, c)
        }
    }

    /// The hull of the corners other than corner `i`.
    fn without(&self, i: usize) -> Shape {
        let [a, b, c] = self.points;
        match (self.len, i) {
            (2, 0) => Shape::Point(b),
            (2, _) => Shape::Point(a),
            (_, 0) => Shape::Segment(b, c),
            (_, 1) => Shape::Segment(c, a),
            _ => Shape::Segment(a, b),
        }
    }

    /// Whether the edge between corners `i` and `j` is a mesh edge.
    fn is_boundary(&self, i: usize, j: usize) -> bool {
        let n = self.len as usize;
        let edge = if n == 2 {
            // A segment's one edge, whichever way round.
            0
        } else if (i + 1) % n == j {
            i
        } else if (j + 1) % n == i {
            j
        } else {
            return false;
        };
        self.boundary & (1 << edge) != 0
    }
}

/// The corner id of a primitive corner that names no vertex.
const NO_VERT: u32 = u32::MAX;

fn id(v: Option<VertId>) -> u32 {
    v.map_or(NO_VERT, |v| v.raw())
}

/// Whether two primitives intersect, excusing contact on shared vertices and
/// shared mesh edges (module docs, "Shared vertices"). `thickness` is the
/// distance at or below which they count as touching (0: exact).
pub fn primitives_intersect(a: &Primitive, b: &Primitive, thickness: f64) -> bool {
    let mut shared = [(0usize, 0usize); 3];
    let mut count = 0;
    let mut used = [false; 3];
    for i in 0..a.len as usize {
        let v = a.verts[i];
        if v == NO_VERT {
            continue;
        }
        if let Some(j) = (0..b.len as usize).find(|&j| !used[j] && b.verts[j] == v) {
            used[j] = true;
            shared[count] = (i, j);
            count += 1;
        }
    }
    let exact = thickness.is_nan() || thickness <= 0.0;
    if exact && quick_miss(a, b, &shared[..count]) {
        return false;
    }
    match count {
        0 => shapes_touch(a.shape(), b.shape(), thickness),
        1 => shares_more_than_vertex(a, b, shared[0], thickness),
        2 => shares_more_than_edge(a, b, shared[0], shared[1], thickness),
        _ => true,
    }
}

/// A certified "no" from plane-side tests alone, for the common cases (a
/// primitive beside another's plane, neighbours on a smooth or flat
/// surface); `false` means "undecided", not "intersecting". Exact-contact
/// semantics only (no thickness).
fn quick_miss(a: &Primitive, b: &Primitive, shared: &[(usize, usize)]) -> bool {
    match *shared {
        // All of one strictly on one side of the other's plane, or the two
        // strictly apart across a plane between them.
        [] => beside_plane(a, b, 0) || beside_plane(b, a, 0) || split(a, 0, b, 0, None),
        // The far parts strictly apart across a plane through the shared
        // vertex (flat and smooth neighbourhoods), or each far part apart
        // from the other primitive: either way A ∩ B = {v}.
        [(i, j)] => {
            split(a, 1 << i, b, 1 << j, Some(a.points[i]))
                || (separated(a, b, i) && separated(b, a, j))
        }
        // Sharing a mesh edge: the contact is the edge if the apexes are
        // certainly not coplanar, or strictly on the two sides of a plane
        // through the edge (a flat strip).
        [(i0, j0), (i1, j1)] => {
            a.len == 3
                && b.len == 3
                && a.is_boundary(i0, i1)
                && b.is_boundary(j0, j1)
                && (beside_plane(b, a, (1 << j0) | (1 << j1))
                    || apart_across_edge(a, b, i0, i1, 3 - j0 - j1))
        }
        _ => false,
    }
}

/// The corners of `p` outside the bit set `skip_p` and those of `q`
/// outside `skip_q` lie strictly on opposite sides of a plane whose normal
/// points from the first group's centre to the second's; the plane passes
/// through `anchor` (the shared vertex) or else midway. Then the hulls of
/// the two groups are apart, and if `anchor` is a shared corner, the
/// primitives meet only there (every other point of each is a convex
/// combination with positive weight on its strict side).
///
/// The side of `x` is `m · (x − c)` for fixed floating-point `m` and `c`;
/// with one rounded difference and a three-term dot product its error is
/// below `4u Σ|mₖ rₖ|` (u = 2⁻⁵³, Higham's bounds), so `8u` certifies it.
fn split(p: &Primitive, skip_p: u8, q: &Primitive, skip_q: u8, anchor: Option<DVec3>) -> bool {
    let centre = |x: &Primitive, skip: u8| {
        let (sum, n) = (0..x.len as usize)
            .filter(|&k| skip & (1 << k) == 0)
            .fold((DVec3::ZERO, 0.0), |(s, n), k| (s + x.points[k], n + 1.0));
        sum / n
    };
    let (cp, cq) = (centre(p, skip_p), centre(q, skip_q));
    let m = cq - cp;
    let c = anchor.unwrap_or((cp + cq) * 0.5);
    if !(m.is_finite() && c.is_finite()) {
        return false;
    }
    const BOUND: f64 = 4.0 * f64::EPSILON;
    let side = |x: DVec3| {
        let r = x - c;
        let d = m.dot(r);
        if d.abs() > BOUND * m.abs().dot(r.abs()) {
            d
        } else {
            0.0
        }
    };
    let all = |x: &Primitive, skip: u8, positive: bool| {
        (0..x.len as usize)
            .filter(|&k| skip & (1 << k) == 0)
            .all(|k| {
                let d = side(x.points[k]);
                if positive {
                    d > 0.0
                } else {
                    d < 0.0
                }
            })
    };
    all(p, skip_p, false) && all(q, skip_q, true)
}

/// Triangles `a` and `b` share the edge from `a`'s corner `i0` to `i1`;
/// `b`'s apex is its corner `apex_b`. They meet only in the edge if their
/// apexes lie strictly on the two sides of a plane through the edge (here
/// the one about perpendicular to `a`).
fn apart_across_edge(a: &Primitive, b: &Primitive, i0: usize, i1: usize, apex_b: usize) -> bool {
    let Some(plane) = &a.plane else { return false };
    let (u, v) = (a.points[i0], a.points[i1]);
    let n = plane.normal();
    let scale = v.distance(u) / n.length();
    if !scale.is_finite() {
        return false;
    }
    let edge_plane = Plane::new([u, v, u + n * scale]);
    let sa = edge_plane.side(a.points[3 - i0 - i1]);
    let sb = edge_plane.side(b.points[apex_b]);
    (sa > 0.0 && sb < 0.0) || (sa < 0.0 && sb > 0.0)
}

/// The corners of `p` other than those in the bit set `skip` lie strictly
/// on one side of the plane of triangle `t` (certified).
#[inline]
fn beside_plane(p: &Primitive, t: &Primitive, skip: u8) -> bool {
    let Some(plane) = &t.plane else { return false };
    let mut sign = 0.0;
    for k in 0..p.len as usize {
        if skip & (1 << k) != 0 {
            continue;
        }
        let side = plane.side(p.points[k]);
        if side == 0.0 || (sign != 0.0 && (side > 0.0) != (sign > 0.0)) {
            return false;
        }
        sign = side;
    }
    sign != 0.0
}

/// The corners of `p` other than corner `skip` (its far part) are
/// certainly apart from triangle `t`: strictly beside its plane, or beyond
/// one of its edges — on the other side than `t`'s third corner of a plane
/// through that edge (any plane through the two exact corners separates
/// validly; this one is about perpendicular to `t`). The edge planes settle
/// the common flat case: the far part of a neighbour lying in `t`'s plane.
fn separated(p: &Primitive, t: &Primitive, skip: usize) -> bool {
    if beside_plane(p, t, 1 << skip) {
        return true;
    }
    let Some(plane) = &t.plane else { return false };
    let n = plane.normal();
    let far = (0..p.len as usize)
        .filter(|&k| k != skip)
        .map(|k| p.points[k]);
    (0..3).any(|k| {
        let (t0, t1, opposite) = (t.points[k], t.points[(k + 1) % 3], t.points[(k + 2) % 3]);
        let scale = t1.distance(t0) / n.length();
        if !scale.is_finite() {
            return false;
        }
        let edge_plane = Plane::new([t0, t1, t0 + n * scale]);
        let inside = edge_plane.side(opposite);
        inside != 0.0
            && far.clone().all(|q| {
                let side = edge_plane.side(q);
                side != 0.0 && (side > 0.0) != (inside > 0.0)
            })
    })
}

/// `A ∩ B ≠ {v}` for `v` = corner `i` of `a` = corner `j` of `b`.
fn shares_more_than_vertex(a: &Primitive, b: &Primitive, (i, j): (usize, usize), h: f64) -> bool {
    shapes_touch(a.without(i), b.shape(), h) || shapes_touch(a.shape(), b.without(j), h)
}

/// Two shared corners `u` (= `a[i0]`, `b[j0]`) and `v` (= `a[i1]`, `b[j1]`).
fn shares_more_than_edge(
    a: &Primitive,
    b: &Primitive,
    (i0, j0): (usize, usize),
    (i1, j1): (usize, usize),
    h: f64,
) -> bool {
    let (u, v) = (a.points[i0], a.points[i1]);
    if u == v {
        // The "edge" is a point: only the vertex rule applies.
        return shares_more_than_vertex(a, b, (i0, j0), h);
    }
    if !(a.is_boundary(i0, i1) && b.is_boundary(j0, j1)) {
        // Both contain the segment u v, which is a diagonal on some side.
        return true;
    }
    if a.is_segment() || b.is_segment() {
        // The segment is the shared edge itself.
        return false;
    }
    let a_apex = a.points[3 - i0 - i1];
    let b_apex = b.points[3 - j0 - j1];
    folded_onto_each_other(u, v, a_apex, b_apex)
}

/// Triangles `(u, v, a)` and `(u, v, b)` sharing the edge `u v` meet beyond
/// it: exactly when they are coplanar and on the same side of `u v` (if
/// not coplanar their planes meet in the line `u v`, which each triangle
/// meets only in the edge). Degenerate triangles are segments on the line.
fn folded_onto_each_other(u: DVec3, v: DVec3, a: DVec3, b: DVec3) -> bool {
    if orient3d(u, v, a, b) != 0.0 {
        return false;
    }
    let side = |p: DVec3, axis: usize| orient2d_dropping(u, v, p, axis);
    // In a projection where (u, v, a) keeps its area the plane projects one
    // to one, so the sides there are the sides in the plane.
    for axis in 0..3 {
        let sa = side(a, axis);
        if sa != 0.0 {
            let sb = side(b, axis);
            return (sa > 0.0 && sb > 0.0) || (sa < 0.0 && sb < 0.0);
        }
    }
    if (0..3).any(|axis| side(b, axis) != 0.0) {
        // `a` lies on the line u v and the triangle (u, v, b) meets that
        // line only in the edge.
        return false;
    }
    // Both degenerate: segments on the line u v, overlapping beyond the
    // edge iff one's far point is outside the edge and inside the other.
    let tri_a = Shape::Triangle(u, v, a);
    let tri_b = Shape::Triangle(u, v, b);
    (!point_on_segment(a, u, v) && shapes_meet(Shape::Point(a), tri_b))
        || (!point_on_segment(b, u, v) && shapes_meet(Shape::Point(b), tri_a))
}

// ---- mesh primitives ----

/// A mesh element a primitive comes from. Edges order before faces.
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Element {
    Edge(EdgeId),
    Face(FaceId),
}

/// How thick a wire edge (an edge without faces) is for the capsule tests.
/// Non-finite or negative thicknesses count as 0.
#[derive(Clone, Copy)]
pub enum WireThickness<'a> {
    /// Bare segments.
    Zero,
    /// The larger of a vertex scalar layer's values at the two ends (the
    /// G³ node radius lives in the layer `"radius"`); 0 if the layer is
    /// missing or not scalar.
    VertLayer(&'a str),
    /// Any per-edge rule.
    PerEdge(&'a dyn Fn(EdgeId) -> f64),
}

impl WireThickness<'_> {
    /// The thickness of edge `e` of `mesh`.
    pub fn of(&self, mesh: &Mesh, e: EdgeId) -> f64 {
        let t = match *self {
            WireThickness::Zero => 0.0,
            WireThickness::VertLayer(name) => {
                let [a, b] = mesh.edge_verts(e);
                let value = |v: VertId| match mesh.attr(name, Domain::Vert, v.index()) {
                    Some(super::AttrValue::Scalar(x)) => x,
                    _ => 0.0,
                };
                value(a).max(value(b))
            }
            WireThickness::PerEdge(f) => f(e),
        };
        if t.is_finite() && t > 0.0 {
            t
        } else {
            0.0
        }
    }
}

/// A primitive with the element it belongs to and its own thickness.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Item {
    pub(crate) prim: Primitive,
    pub(crate) thickness: f64,
    pub(crate) owner: Element,
    /// The [`IntersectionIndex`] epoch the item was stored in, which tells
    /// a removed element's old primitives from its new ones (0 elsewhere).
    pub(crate) epoch: u64,
}

/// Appends the triangles of face `f` (its triangulation, with face edges
/// marked as boundary).
pub(crate) fn push_face(mesh: &Mesh, f: FaceId, scratch: &mut Scratch, out: &mut Vec<Item>) {
    scratch.verts.clear();
    scratch.points.clear();
    for v in mesh.face_verts(f) {
        scratch.verts.push(Some(v));
        scratch.points.push(mesh.position(v));
    }
    push_ring(
        &scratch.points,
        &scratch.verts,
        Element::Face(f),
        &mut scratch.tris,
        out,
    );
}

/// Reused buffers for triangulating faces one after another.
#[derive(Clone, Debug, Default)]
pub(crate) struct Scratch {
    verts: Vec<Option<VertId>>,
    points: Vec<DVec3>,
    tris: Vec<[u32; 3]>,
}

/// Appends the triangles of a ring whose corners may name vertices.
fn push_ring(
    points: &[DVec3],
    verts: &[Option<VertId>],
    owner: Element,
    tris: &mut Vec<[u32; 3]>,
    out: &mut Vec<Item>,
) {
    let n = points.len();
    tris.clear();
    polygon::triangulate(points, tris);
    for t in tris.iter() {
        let [i, j, k] = t.map(|x| x as usize);
        // A ring edge joins neighbours in the ring; anything else is a diagonal.
        let is_edge = |p: usize, q: usize| (p + 1) % n == q || (q + 1) % n == p;
        out.push(Item {
            prim: Primitive::face_triangle(
                [points[i], points[j], points[k]],
                [verts[i], verts[j], verts[k]],
                [is_edge(i, j), is_edge(j, k), is_edge(k, i)],
            ),
            thickness: 0.0,
            owner,
            epoch: 0,
        });
    }
}

pub(crate) fn edge_item(mesh: &Mesh, e: EdgeId, thickness: f64) -> Item {
    let [a, b] = mesh.edge_verts(e);
    Item {
        prim: Primitive::segment([mesh.position(a), mesh.position(b)], [Some(a), Some(b)]),
        thickness: if thickness.is_finite() && thickness > 0.0 {
            thickness
        } else {
            0.0
        },
        owner: Element::Edge(e),
        epoch: 0,
    }
}

/// Face triangles (and, if `wires` is given, wire edges) of a mesh, in id order.
fn mesh_items(mesh: &Mesh, wires: Option<WireThickness>) -> Vec<Item> {
    let mut items = Vec::with_capacity(mesh.face_count() * 2);
    let mut scratch = Scratch::default();
    for f in mesh.face_ids() {
        push_face(mesh, f, &mut scratch, &mut items);
    }
    if let Some(thickness) = wires {
        for e in mesh.edge_ids().filter(|&e| mesh.is_wire_edge(e)) {
            items.push(edge_item(mesh, e, thickness.of(mesh, e)));
        }
    }
    items
}

/// Whether two items of different elements intersect: the pair threshold
/// is the sum of their thicknesses (two tubes touch when their axes are
/// `r₁ + r₂` apart; a tube touches a face at `r`).
#[cfg(test)]
pub(crate) fn items_intersect(a: &Item, b: &Item) -> bool {
    primitives_intersect(&a.prim, &b.prim, a.thickness + b.thickness)
}

// ---- whole-mesh self-intersection ----

/// Every pair of elements of a mesh that intersect, each list sorted
/// ascending with the smaller id first.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SelfIntersections {
    pub faces: Vec<(FaceId, FaceId)>,
    /// Wire edge against face.
    pub edge_faces: Vec<(EdgeId, FaceId)>,
    /// Wire edge against wire edge.
    pub edges: Vec<(EdgeId, EdgeId)>,
}

impl SelfIntersections {
    pub fn is_empty(&self) -> bool {
        self.faces.is_empty() && self.edge_faces.is_empty() && self.edges.is_empty()
    }
}

/// All pairs of faces whose triangles intersect, excusing contact on shared
/// vertices and shared edges (module docs), sorted and deduplicated.
/// Wire edges are ignored; see [`self_intersections_with`].
pub fn self_intersections(mesh: &Mesh) -> Vec<(FaceId, FaceId)> {
    mesh_pairs(mesh, None)
        .into_iter()
        .filter_map(|pair| match pair {
            (Element::Face(a), Element::Face(b)) => Some((a, b)),
            _ => None,
        })
        .collect()
}

/// The intersecting element pairs of the primitives of [`mesh_items`],
/// built and tested on the threads the mesh's size calls for.
fn mesh_pairs(mesh: &Mesh, wires: Option<WireThickness>) -> Vec<(Element, Element)> {
    let build_threads = bvh::threads_for(2 * mesh.face_count());
    let soup = pairs::mesh_soup(mesh, wires, build_threads);
    let threads = bvh::threads_for(soup.len());
    pairs::intersecting_pairs(soup, threads)
}

/// [`self_intersections`] within bounds on time and memory: every pair
/// counted, the first `limits.keep` kept, the search stopped (and said to
/// be incomplete) after `limits.max_tests` tests. [`PairLimits::for_items`]
/// of the face count suits reports; the answer never depends on the thread
/// count.
pub fn self_intersection_search(
    mesh: &Mesh,
    limits: impl FnOnce(usize) -> PairLimits,
) -> PairSearch<(FaceId, FaceId)> {
    let build_threads = bvh::threads_for(2 * mesh.face_count());
    face_pairs(pairs::mesh_soup(mesh, None, build_threads), limits)
}

/// [`self_intersection_search`] of the kernel mesh `mesh` builds, read
/// straight from it (no kernel mesh is built): face `k` is polygon `k`.
/// Only meaningful when [`crate::kernel::build::builds_one_to_one`] holds;
/// `graftal info` then runs it beside the build.
pub fn indexed_self_intersection_search(
    mesh: &IndexedMesh,
    limits: impl FnOnce(usize) -> PairLimits,
) -> PairSearch<(FaceId, FaceId)> {
    let build_threads = bvh::threads_for(2 * mesh.polygon_count());
    face_pairs(pairs::indexed_soup(mesh, build_threads), limits)
}

/// The face pairs of a soup without wires, within limits.
fn face_pairs(
    soup: pairs::Soup,
    limits: impl FnOnce(usize) -> PairLimits,
) -> PairSearch<(FaceId, FaceId)> {
    let threads = bvh::threads_for(soup.len());
    let limits = limits(soup.len());
    let found = pairs::search_pairs(soup, threads, limits);
    PairSearch {
        count: found.count,
        pairs: found
            .pairs
            .into_iter()
            .filter_map(|pair| match pair {
                (Element::Face(a), Element::Face(b)) => Some((a, b)),
                _ => None,
            })
            .collect(),
        complete: found.complete,
    }
}

/// [`self_intersections`] with wire edges too, tested as capsules of the
/// given thickness against faces and against each other.
pub fn self_intersections_with(mesh: &Mesh, wires: WireThickness) -> SelfIntersections {
    let mut out = SelfIntersections::default();
    for pair in mesh_pairs(mesh, Some(wires)) {
        match pair {
            (Element::Face(a), Element::Face(b)) => out.faces.push((a, b)),
            (Element::Edge(e), Element::Face(f)) => out.edge_faces.push((e, f)),
            (Element::Edge(a), Element::Edge(b)) => out.edges.push((a, b)),
            // Pairs come ordered, and edges order before faces.
            (Element::Face(_), Element::Edge(_)) => unreachable!("pairs are ordered"),
        }
    }
    out
}

// ---- close vertices ----

/// How many pairs of distinct points are at most `tolerance` apart, with
/// bounded time and memory on degenerate input (24,000 vertices at three
/// positions are 96 million pairs): identical positions are merged first
/// and counted as `k (k - 1) / 2`, the rest through a hash grid of the
/// distinct positions, and the search stops after `max_tests` distance
/// tests (`complete` is then `false` and the count a lower bound).
/// Non-finite points are skipped; `tolerance <= 0` counts identical ones.
pub fn count_close_points(points: &[DVec3], tolerance: f64, max_tests: u64) -> PairSearch<()> {
    // Distinct positions with their multiplicities (−0 folded onto +0).
    let mut keyed: Vec<[u64; 3]> = points
        .iter()
        .filter(|p| p.is_finite())
        .map(|p| p.to_array().map(|x| (x + 0.0).to_bits()))
        .collect();
    keyed.sort_unstable();
    let mut distinct: Vec<(DVec3, u64)> = Vec::new();
    let mut count: u64 = 0;
    for run in keyed.chunk_by(|a, b| a == b) {
        let k = run.len() as u64;
        count = count.saturating_add(k * (k - 1) / 2);
        distinct.push((DVec3::from_array(run[0].map(f64::from_bits)), k));
    }
    let mut out = PairSearch {
        count,
        pairs: Vec::new(),
        complete: true,
    };
    if !(tolerance > 0.0 && tolerance.is_finite()) {
        return out;
    }
    // Each cell (geom::cells: 8 searched per point) lists the distinct
    // points in it in descending index order, so a walk stops at the
    // first index not above its own.
    let cells = Cells::for_distance(tolerance);
    let mut lists = CellLists::with_capacity(distinct.len(), distinct.len());
    for (p, _) in &distinct {
        lists.push(cells.of(p.to_array()));
    }
    let tol2 = tolerance * tolerance;
    let mut budget = max_tests;
    for (index, &(p, weight)) in distinct.iter().enumerate() {
        let (lo, hi) = cells.around(p.to_array());
        for cx in lo[0]..=hi[0] {
            for cy in lo[1]..=hi[1] {
                for cz in lo[2]..=hi[2] {
                    let mut other = lists.head([cx, cy, cz]);
                    while other != NONE && other as usize > index {
                        let Some(left) = budget.checked_sub(1) else {
                            out.complete = false;
                            return out;
                        };
                        budget = left;
                        let (q, w) = distinct[other as usize];
                        if p.distance_squared(q) <= tol2 {
                            out.count = out.count.saturating_add(weight.saturating_mul(w));
                        }
                        other = lists.next(other);
                    }
                }
            }
        }
    }
    out
}

/// All pairs of distinct vertices at most `tolerance` apart (Euclidean),
/// smaller id first, sorted. A hash grid makes it linear in the vertex count
/// plus the output. `tolerance <= 0` (or NaN) finds exactly coincident
/// positions only. Vertices with non-finite coordinates are skipped.
pub fn close_vertices(mesh: &Mesh, tolerance: f64) -> Vec<(VertId, VertId)> {
    let verts: Vec<(VertId, DVec3)> = mesh
        .vert_ids()
        .map(|v| (v, mesh.position(v)))
        .filter(|(_, p)| p.is_finite())
        .collect();
    let mut pairs = Vec::new();
    if !(tolerance > 0.0 && tolerance.is_finite()) {
        // Coincident positions: group by bit pattern (−0 folded onto +0).
        let key = |p: DVec3| p.to_array().map(|x| (x + 0.0).to_bits());
        let mut groups: FxHashMap<[u64; 3], Vec<VertId>> = FxHashMap::default();
        for &(v, p) in &verts {
            groups.entry(key(p)).or_default().push(v);
        }
        for group in groups.values() {
            for (i, &a) in group.iter().enumerate() {
                pairs.extend(group[i + 1..].iter().map(|&b| (a.min(b), a.max(b))));
            }
        }
        pairs.sort_unstable();
        return pairs;
    }
    // Cells of 4 × tolerance: a point needs the neighbour cell along an axis
    // only when it lies within `tolerance` of that side, so most points
    // look at one to three cells instead of 27.
    let cell = 4.0 * tolerance;
    let coord = |x: f64| (x / cell).floor() as i64;
    let mut grid: FxHashMap<[i64; 3], Vec<u32>> = FxHashMap::default();
    for (index, &(_, p)) in verts.iter().enumerate() {
        let key = p.to_array().map(coord);
        grid.entry(key).or_default().push(index as u32);
    }
    let tol2 = tolerance * tolerance;
    for (index, &(v, p)) in verts.iter().enumerate() {
        let home = p.to_array().map(coord);
        let offsets = |axis: usize| {
            let x = p[axis];
            let low = x - tolerance;
            let high = x + tolerance;
            let lo = if coord(low) < home[axis] { -1 } else { 0 };
            let hi = if coord(high) > home[axis] { 1 } else { 0 };
            lo..=hi
        };
        for dx in offsets(0) {
            for dy in offsets(1) {
                for dz in offsets(2) {
                    let key = [
                        home[0].saturating_add(dx),
                        home[1].saturating_add(dy),
                        home[2].saturating_add(dz),
                    ];
                    let Some(bucket) = grid.get(&key) else {
                        continue;
                    };
                    for &other in bucket {
                        // Each pair once: from its lower index.
                        if (other as usize) > index {
                            let (w, q) = verts[other as usize];
                            if p.distance_squared(q) <= tol2 {
                                pairs.push((v.min(w), v.max(w)));
                            }
                        }
                    }
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs
}
