//! Narrow-phase tests on points, segments and triangles in `f64`.
//!
//! Exact tests (thickness 0) use only the signs of Shewchuk's adaptive
//! `orient3d` / `orient2d` (the `robust` crate), so they never misjudge a
//! touching, coplanar or collinear configuration. Exactness holds while the
//! coordinate differences and their products neither overflow nor underflow
//! (magnitudes roughly within 1e±100), the predicates' own limit.
//!
//! Coplanar configurations are decided in 2D without choosing a projection:
//! two convex sets in a common plane meet exactly when their projections onto
//! *all three* coordinate planes meet. A projection is linear, so a real
//! contact survives every projection; and at least one coordinate plane is
//! not perpendicular to the common plane, where the projection is one-to-one
//! and a projected contact is a real one. Planes perpendicular to a
//! coordinate plane collapse onto a line there; the 2D tests handle such
//! degenerate (collinear) input exactly, so the conjunction stays exact.
//!
//! Distance tests (thickness h > 0) compute closest points in floating point;
//! their answer near `distance == h` is as good as `f64` rounding, not exact.
//! They are always combined with the exact test, so a real contact is never
//! lost to rounding however small `h` is.

use glam::DVec3;
use robust::{Coord, Coord3D};

/// A convex piece of a primitive: what the shared-vertex rule tests once a
/// vertex has been taken away (a triangle minus a corner leaves the opposite
/// edge, a segment minus an end leaves the other end).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Shape {
    Point(DVec3),
    Segment(DVec3, DVec3),
    Triangle(DVec3, DVec3, DVec3),
}

/// True when `a` and `b` are within distance `thickness` of each other
/// (closed sets: touching counts). `thickness <= 0` (or NaN) is the exact test.
pub(crate) fn shapes_touch(a: Shape, b: Shape, thickness: f64) -> bool {
    if shapes_meet(a, b) {
        return true;
    }
    thickness > 0.0 && shape_distance_squared(a, b) <= thickness * thickness
}

/// Exact contact test between two shapes.
pub(crate) fn shapes_meet(a: Shape, b: Shape) -> bool {
    use Shape::*;
    match (a, b) {
        (Point(p), Point(q)) => p == q,
        (Point(p), Segment(s0, s1)) | (Segment(s0, s1), Point(p)) => {
            segment_segment_exact(p, p, s0, s1)
        }
        (Point(p), Triangle(t0, t1, t2)) | (Triangle(t0, t1, t2), Point(p)) => {
            segment_triangle_exact(p, p, t0, t1, t2)
        }
        (Segment(a0, a1), Segment(b0, b1)) => segment_segment_exact(a0, a1, b0, b1),
        (Segment(s0, s1), Triangle(t0, t1, t2)) | (Triangle(t0, t1, t2), Segment(s0, s1)) => {
            segment_triangle_exact(s0, s1, t0, t1, t2)
        }
        (Triangle(a0, a1, a2), Triangle(b0, b1, b2)) => {
            triangle_triangle_exact([a0, a1, a2], [b0, b1, b2])
        }
    }
}

/// Squared distance between two shapes, in floating point.
fn shape_distance_squared(a: Shape, b: Shape) -> f64 {
    use Shape::*;
    match (a, b) {
        (Point(p), Point(q)) => p.distance_squared(q),
        (Point(p), Segment(s0, s1)) | (Segment(s0, s1), Point(p)) => {
            point_segment_distance_squared(p, s0, s1)
        }
        (Point(p), Triangle(t0, t1, t2)) | (Triangle(t0, t1, t2), Point(p)) => {
            point_triangle_distance_squared(p, [t0, t1, t2])
        }
        (Segment(a0, a1), Segment(b0, b1)) => segment_segment_distance_squared(a0, a1, b0, b1),
        (Segment(s0, s1), Triangle(t0, t1, t2)) | (Triangle(t0, t1, t2), Segment(s0, s1)) => {
            segment_triangle_distance_squared(s0, s1, [t0, t1, t2])
        }
        (Triangle(a0, a1, a2), Triangle(b0, b1, b2)) => {
            triangle_triangle_distance_squared([a0, a1, a2], [b0, b1, b2])
        }
    }
}

// ---- orientation predicates ----

#[inline]
fn c3(p: DVec3) -> Coord3D<f64> {
    Coord3D {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

/// Exact sign of the volume of tetrahedron `(a, b, c, d)` (Shewchuk's
/// convention: positive when `d` lies below the plane of `a, b, c` seen
/// counter-clockwise from above). Only the sign is used.
#[inline]
pub(crate) fn orient3d(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    let [a, b, c, d] = in_range([a, b, c, d]);
    robust::orient3d(c3(a), c3(b), c3(c), c3(d))
}

/// Coordinates up to 2^300 in magnitude go to Shewchuk's predicates as
/// they are: orient3d multiplies three differences (each up to twice a
/// coordinate), orient2d two, and beyond about 2^340 the products
/// overflow. Then every adaptive stage computes with infinities and NaNs,
/// so each call takes the slowest path and its sign means nothing (fuzzing
/// found a 600-face PLY with coordinates near 1e308 on which `graftal
/// info` spent seconds). Larger points are scaled by one power of two:
/// exact, so the sign is kept, except for coordinates below 2^-774 that
/// underflow beside them. Non-finite points are degenerate (zero).
const ORIENT_SAFE: f64 = 2.037_035_976_334_486e90; // 2^300

#[inline]
fn in_range<const N: usize>(points: [DVec3; N]) -> [DVec3; N] {
    let largest = points
        .iter()
        .map(|p| p.abs().max_element())
        .fold(0.0, f64::max);
    if largest <= ORIENT_SAFE {
        return points;
    }
    if !largest.is_finite() || points.iter().any(|p| !p.is_finite()) {
        return [DVec3::ZERO; N];
    }
    let shift = libm::ilogb(largest) - 300;
    points.map(|p| {
        DVec3::new(
            libm::scalbn(p.x, -shift),
            libm::scalbn(p.y, -shift),
            libm::scalbn(p.z, -shift),
        )
    })
}

/// The sign of [`orient3d`] when its floating-point filter certifies it,
/// else `None`: Shewchuk's first stage (the same bound the `robust` crate
/// applies before its adaptive stages), without the costly exact fallback.
/// Near-coplanar quadruples are common in meshes (the corners of a planar
/// quad), and many tests can be decided from other, well-conditioned
/// orientations, so the exact stage is deferred until it is needed.
#[inline]
pub(crate) fn orient3d_filtered(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> Option<f64> {
    orient3d_filtered_at(a - d, b - d, c - d)
}

/// [`orient3d_filtered`] from the floating-point differences `a − d`,
/// `b − d`, `c − d` (rounded as `-` rounds them: the filter's bound covers
/// that rounding, nothing else), for callers that reuse them.
#[inline]
pub(crate) fn orient3d_filtered_at(ad: DVec3, bd: DVec3, cd: DVec3) -> Option<f64> {
    // Shewchuk's O3DERRBOUND_A with epsilon = 2^-53.
    const EPSILON: f64 = f64::EPSILON * 0.5;
    const BOUND: f64 = (7.0 + 56.0 * EPSILON) * EPSILON;
    let bxcy = bd.x * cd.y;
    let cxby = cd.x * bd.y;
    let cxay = cd.x * ad.y;
    let axcy = ad.x * cd.y;
    let axby = ad.x * bd.y;
    let bxay = bd.x * ad.y;
    let det = ad.z * (bxcy - cxby) + bd.z * (cxay - axcy) + cd.z * (axby - bxay);
    let permanent = (bxcy.abs() + cxby.abs()) * ad.z.abs()
        + (cxay.abs() + axcy.abs()) * bd.z.abs()
        + (axby.abs() + bxay.abs()) * cd.z.abs();
    (det.abs() > BOUND * permanent).then_some(det)
}

/// A triangle's plane with what a certified side test needs, computed once
/// per triangle: the test of a point is then a dot product and a bound.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Plane {
    origin: DVec3,
    /// `(t1 − t0) × (t2 − t0)` in floating point.
    normal: DVec3,
    /// Per component, the sum of the absolute products in that minor.
    minors: DVec3,
}

impl Plane {
    #[inline(always)]
    pub(crate) fn new(t: [DVec3; 3]) -> Self {
        let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
        let products =
            |a: f64, b: f64, c: f64, d: f64| (a * b - c * d, (a * b).abs() + (c * d).abs());
        let (nx, mx) = products(e1.y, e2.z, e1.z, e2.y);
        let (ny, my) = products(e1.z, e2.x, e1.x, e2.z);
        let (nz, mz) = products(e1.x, e2.y, e1.y, e2.x);
        Self {
            origin: t[0],
            normal: DVec3::new(nx, ny, nz),
            minors: DVec3::new(mx, my, mz),
        }
    }

    /// The plane's normal, `(t1 − t0) × (t2 − t0)` in floating point.
    pub(crate) fn normal(&self) -> DVec3 {
        self.normal
    }

    /// The side of the plane `p` is on, when certified: positive or
    /// negative; 0.0 when `p` is on or too near the plane to tell (or the
    /// triangle is degenerate). The expression is a 3×3 determinant with
    /// one difference per entry, the shape of Shewchuk's `orient3d` first
    /// stage, so his error bound applies (with a margin: 8ε, not 7ε).
    #[inline(always)]
    pub(crate) fn side(&self, p: DVec3) -> f64 {
        const BOUND: f64 = 8.0 * f64::EPSILON * 0.5;
        let r = p - self.origin;
        let det = r.dot(self.normal);
        let permanent = r.abs().dot(self.minors);
        if det.abs() > BOUND * permanent {
            det
        } else {
            0.0
        }
    }
}

/// Certified signs `(any positive, any negative)` among filtered values.
fn certified_signs(values: &[Option<f64>]) -> (bool, bool) {
    let pos = values.iter().any(|v| matches!(v, Some(x) if *x > 0.0));
    let neg = values.iter().any(|v| matches!(v, Some(x) if *x < 0.0));
    (pos, neg)
}

/// A point projected onto a coordinate plane.
type P2 = [f64; 2];

/// Drops coordinate `axis` (0 = x, 1 = y, 2 = z).
#[inline]
fn project(p: DVec3, axis: usize) -> P2 {
    match axis {
        0 => [p.y, p.z],
        1 => [p.z, p.x],
        _ => [p.x, p.y],
    }
}

#[inline]
fn orient2d(a: P2, b: P2, c: P2) -> f64 {
    let lift = |p: P2| DVec3::new(p[0], p[1], 0.0);
    let [a, b, c] = in_range([lift(a), lift(b), lift(c)]).map(|p| [p.x, p.y]);
    robust::orient2d(
        Coord { x: a[0], y: a[1] },
        Coord { x: b[0], y: b[1] },
        Coord { x: c[0], y: c[1] },
    )
}

/// [`orient2d`] of three points dropped onto the plane without `axis`
/// (0 = x, 1 = y, 2 = z), as [`project`] drops them.
#[inline]
pub(crate) fn orient2d_dropping(a: DVec3, b: DVec3, c: DVec3, axis: usize) -> f64 {
    orient2d(project(a, axis), project(b, axis), project(c, axis))
}

/// Signs of opposite strictness: one strictly positive, the other strictly negative.
#[inline]
fn opposite(a: f64, b: f64) -> bool {
    (a > 0.0 && b < 0.0) || (a < 0.0 && b > 0.0)
}

// ---- exact 2D tests (inputs may be degenerate: zero-length segments,
// collinear triangles) ----

/// `p` lies in the bounding box of `a`, `b`; for a `p` collinear with them,
/// that is "on the closed segment".
#[inline]
fn in_box_2d(p: P2, a: P2, b: P2) -> bool {
    (0..2).all(|k| a[k].min(b[k]) <= p[k] && p[k] <= a[k].max(b[k]))
}

fn segments_meet_2d(a0: P2, a1: P2, b0: P2, b1: P2) -> bool {
    let d0 = orient2d(b0, b1, a0);
    let d1 = orient2d(b0, b1, a1);
    let d2 = orient2d(a0, a1, b0);
    let d3 = orient2d(a0, a1, b1);
    if opposite(d0, d1) && opposite(d2, d3) {
        return true;
    }
    // Every touching and collinear case has an endpoint on the other segment;
    // a zero orientation makes the box test an exact "on segment" test.
    (d0 == 0.0 && in_box_2d(a0, b0, b1))
        || (d1 == 0.0 && in_box_2d(a1, b0, b1))
        || (d2 == 0.0 && in_box_2d(b0, a0, a1))
        || (d3 == 0.0 && in_box_2d(b1, a0, a1))
}

/// Closed triangle contains `p`; the triangle must not be degenerate.
fn point_in_triangle_2d(p: P2, t: [P2; 3]) -> bool {
    let o0 = orient2d(t[0], t[1], p);
    let o1 = orient2d(t[1], t[2], p);
    let o2 = orient2d(t[2], t[0], p);
    !((o0 < 0.0 || o1 < 0.0 || o2 < 0.0) && (o0 > 0.0 || o1 > 0.0 || o2 > 0.0))
}

fn segment_triangle_2d(s0: P2, s1: P2, t: [P2; 3]) -> bool {
    let edges_hit = || {
        segments_meet_2d(s0, s1, t[0], t[1])
            || segments_meet_2d(s0, s1, t[1], t[2])
            || segments_meet_2d(s0, s1, t[2], t[0])
    };
    if orient2d(t[0], t[1], t[2]) == 0.0 {
        // A collinear triangle is the union of its edges.
        return edges_hit();
    }
    point_in_triangle_2d(s0, t) || edges_hit()
}

// ---- exact 3D tests ----

/// Exact: the closed segments `a0 a1` and `b0 b1` share a point. Zero-length
/// segments are points; collinear overlap and touching at an end count.
pub fn segment_segment_exact(a0: DVec3, a1: DVec3, b0: DVec3, b1: DVec3) -> bool {
    if orient3d(a0, a1, b0, b1) != 0.0 {
        return false;
    }
    (0..3).all(|axis| {
        segments_meet_2d(
            project(a0, axis),
            project(a1, axis),
            project(b0, axis),
            project(b1, axis),
        )
    })
}

/// Exact: the closed segment `s0 s1` and the closed triangle `t0 t1 t2`
/// share a point. Degenerate segments (points) and triangles (segments,
/// points) are handled.
pub fn segment_triangle_exact(s0: DVec3, s1: DVec3, t0: DVec3, t1: DVec3, t2: DVec3) -> bool {
    let f0 = orient3d_filtered(t0, t1, t2, s0);
    let f1 = orient3d_filtered(t0, t1, t2, s1);
    if let (Some(a), Some(b)) = (f0, f1) {
        if opposite(a, -b) {
            // Both ends strictly on one side of the plane.
            return false;
        }
    } else {
        // An end is (nearly) in the plane. If the segment's line certainly
        // passes beside the triangle (strictly opposite sides of two edges)
        // the segment misses it; no exact evaluation needed. A coplanar
        // line has all three orientations 0, so it never gets here.
        let e = [
            orient3d_filtered(s0, s1, t0, t1),
            orient3d_filtered(s0, s1, t1, t2),
            orient3d_filtered(s0, s1, t2, t0),
        ];
        if certified_signs(&e) == (true, true) {
            return false;
        }
    }
    let o0 = f0.unwrap_or_else(|| orient3d(t0, t1, t2, s0));
    let o1 = f1.unwrap_or_else(|| orient3d(t0, t1, t2, s1));
    if opposite(o0, -o1) {
        return false;
    }
    if o0 == 0.0 && o1 == 0.0 {
        // Coplanar, or the triangle is degenerate (then every orient3d is 0).
        return (0..3).all(|axis| {
            let t = [project(t0, axis), project(t1, axis), project(t2, axis)];
            segment_triangle_2d(project(s0, axis), project(s1, axis), t)
        });
    }
    // The segment meets the triangle's plane in exactly one point (the
    // triangle is not degenerate, or both orientations would be 0). That
    // point is in the triangle iff the segment's line passes on the same
    // side of all three edges (zeros: through an edge or a corner).
    let e0 = orient3d(s0, s1, t0, t1);
    let e1 = orient3d(s0, s1, t1, t2);
    let e2 = orient3d(s0, s1, t2, t0);
    let any_pos = e0 > 0.0 || e1 > 0.0 || e2 > 0.0;
    let any_neg = e0 < 0.0 || e1 < 0.0 || e2 < 0.0;
    !(any_pos && any_neg)
}

/// Exact: two closed triangles share a point (coplanar overlap included).
///
/// Thesis §3.2.3: each edge of either triangle is tested against the other
/// triangle. That is complete: if the triangles meet, some point of their
/// intersection lies on the boundary of one of them (in the coplanar case,
/// containment puts a whole edge inside the other triangle).
pub fn triangle_triangle_exact(a: [DVec3; 3], b: [DVec3; 3]) -> bool {
    // Cheap rejection first: all of one triangle strictly on one side of the
    // other's plane (a degenerate triangle has no plane: orient3d is 0).
    let side = |t: [DVec3; 3], p: [DVec3; 3]| {
        let f = p.map(|q| orient3d_filtered(t[0], t[1], t[2], q));
        if certified_signs(&f) == (true, true) {
            return false;
        }
        let o = [0, 1, 2].map(|k| f[k].unwrap_or_else(|| orient3d(t[0], t[1], t[2], p[k])));
        (o[0] > 0.0 && o[1] > 0.0 && o[2] > 0.0) || (o[0] < 0.0 && o[1] < 0.0 && o[2] < 0.0)
    };
    if side(b, a) || side(a, b) {
        return false;
    }
    let edge_hits = |p: [DVec3; 3], t: [DVec3; 3]| {
        (0..3).any(|i| segment_triangle_exact(p[i], p[(i + 1) % 3], t[0], t[1], t[2]))
    };
    edge_hits(a, b) || edge_hits(b, a)
}

/// Exact: `p` lies on the closed segment `a b`.
pub(crate) fn point_on_segment(p: DVec3, a: DVec3, b: DVec3) -> bool {
    segment_segment_exact(p, p, a, b)
}

// ---- distances (floating point) ----

fn point_segment_distance_squared(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance_squared(a + ab * t)
}

/// Squared distance between two segments. Robust to parallel and
/// zero-length segments: the minimum is taken over the four endpoint-to-
/// segment distances (which are where it lies for parallel segments) and,
/// when the lines are not parallel, the clamped interior closest pair. Every
/// candidate is a real pair of points on the segments, so rounding can only
/// make the result slightly larger than the true distance, never report a
/// pair closer than any real one by more than rounding.
pub(crate) fn segment_segment_distance_squared(a0: DVec3, a1: DVec3, b0: DVec3, b1: DVec3) -> f64 {
    let mut best = point_segment_distance_squared(a0, b0, b1)
        .min(point_segment_distance_squared(a1, b0, b1))
        .min(point_segment_distance_squared(b0, a0, a1))
        .min(point_segment_distance_squared(b1, a0, a1));
    let d1 = a1 - a0;
    let d2 = b1 - b0;
    let r = a0 - b0;
    let (a, e) = (d1.length_squared(), d2.length_squared());
    let (b, c, f) = (d1.dot(d2), d1.dot(r), d2.dot(r));
    let denom = a * e - b * b;
    if denom > 0.0 {
        // Closest points of the infinite lines; only an interior minimum
        // can beat the endpoint candidates.
        let s = (b * f - c * e) / denom;
        let t = (a * f - b * c) / denom;
        if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) {
            best = best.min((a0 + d1 * s).distance_squared(b0 + d2 * t));
        }
    }
    best
}

/// Squared distance from `p` to a closed triangle (Ericson, Real-Time
/// Collision Detection §5.1.5, by Voronoi regions). Degenerate triangles
/// fall back to the distance to their edges.
pub(crate) fn point_triangle_distance_squared(p: DVec3, t: [DVec3; 3]) -> f64 {
    let [a, b, c] = t;
    let ab = b - a;
    let ac = c - a;
    let n = ab.cross(ac);
    let area2 = n.length_squared();
    if area2.is_nan() || area2 <= 0.0 {
        return point_segment_distance_squared(p, a, b)
            .min(point_segment_distance_squared(p, b, c))
            .min(point_segment_distance_squared(p, c, a));
    }
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return p.distance_squared(a);
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return p.distance_squared(b);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return p.distance_squared(a + ab * v);
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return p.distance_squared(c);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return p.distance_squared(a + ac * w);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return p.distance_squared(b + (c - b) * w);
    }
    // Inside the face region: distance to the plane.
    let dist = ap.dot(n);
    dist * dist / n.length_squared()
}

/// Squared distance between a segment and a triangle that do not meet: the
/// minimum is at a segment end against the triangle or at the segment
/// against a triangle edge.
fn segment_triangle_distance_squared(s0: DVec3, s1: DVec3, t: [DVec3; 3]) -> f64 {
    point_triangle_distance_squared(s0, t)
        .min(point_triangle_distance_squared(s1, t))
        .min(segment_segment_distance_squared(s0, s1, t[0], t[1]))
        .min(segment_segment_distance_squared(s0, s1, t[1], t[2]))
        .min(segment_segment_distance_squared(s0, s1, t[2], t[0]))
}

/// Squared distance between two triangles that do not meet: the minimum
/// involves an edge of one of them.
fn triangle_triangle_distance_squared(a: [DVec3; 3], b: [DVec3; 3]) -> f64 {
    (0..3)
        .map(|i| {
            segment_triangle_distance_squared(a[i], a[(i + 1) % 3], b)
                .min(segment_triangle_distance_squared(b[i], b[(i + 1) % 3], a))
        })
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_coordinates_keep_their_sign_and_take_the_fast_path() {
        let (a, b, c) = (
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        );
        let d = DVec3::new(0.25, 0.25, -1.0);
        let small = orient3d(a, b, c, d).signum();
        assert_ne!(small, 0.0);
        for scale in [1e100, 1e200, 1e300, f64::MAX / 4.0] {
            let s = |p: DVec3| p * scale;
            assert_eq!(orient3d(s(a), s(b), s(c), s(d)).signum(), small, "{scale}");
            // Coplanar stays exactly coplanar (the scaling is exact).
            let e = DVec3::new(0.5, 0.25, 0.0);
            assert_eq!(orient3d(s(a), s(b), s(c), s(e)), 0.0, "{scale}");
            assert_eq!(
                orient2d_dropping(s(a), s(b), s(e), 2).signum(),
                orient2d_dropping(a, b, e, 2).signum()
            );
        }
        let inf = DVec3::new(f64::INFINITY, 0.0, 0.0);
        assert_eq!(orient3d(a, b, c, inf), 0.0);
    }
}
