use glam::DVec3;
use proptest::prelude::*;

use super::*;
use crate::kernel::ops::{create, transform};
use crate::kernel::{AttrValue, Domain};

fn p(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

fn v(i: u32) -> Option<VertId> {
    Some(VertId::from_raw(i))
}

// ---- segment–segment ----

#[test]
fn parallel_segments_apart() {
    let (a0, a1) = (p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0));
    let (b0, b1) = (p(0.0, 1.0, 0.0), p(1.0, 1.0, 0.0));
    assert!(!segment_segment(a0, a1, b0, b1, 0.0));
    assert!(!segment_segment(a0, a1, b0, b1, 0.5));
    assert!(
        segment_segment(a0, a1, b0, b1, 1.0),
        "distance 1 is within 1"
    );
    // Parallel, offset along the axis so no perpendicular covers both.
    let (c0, c1) = (p(3.0, 1.0, 0.0), p(4.0, 1.0, 0.0));
    assert!(!segment_segment(a0, a1, c0, c1, 1.0));
    assert!(segment_segment(a0, a1, c0, c1, 5f64.sqrt() + 1e-12));
}

#[test]
fn collinear_segments() {
    let (a0, a1) = (p(0.0, 0.0, 0.0), p(2.0, 0.0, 0.0));
    // Overlapping.
    assert!(segment_segment(
        a0,
        a1,
        p(1.0, 0.0, 0.0),
        p(3.0, 0.0, 0.0),
        0.0
    ));
    // Contained, reversed.
    assert!(segment_segment(
        a0,
        a1,
        p(1.5, 0.0, 0.0),
        p(0.5, 0.0, 0.0),
        0.0
    ));
    // Touching end to end.
    assert!(segment_segment(
        a0,
        a1,
        p(2.0, 0.0, 0.0),
        p(3.0, 0.0, 0.0),
        0.0
    ));
    // Apart on the same line: a gap of 1.
    let (b0, b1) = (p(3.0, 0.0, 0.0), p(4.0, 0.0, 0.0));
    assert!(!segment_segment(a0, a1, b0, b1, 0.0));
    assert!(!segment_segment(a0, a1, b0, b1, 0.99));
    assert!(segment_segment(a0, a1, b0, b1, 1.0));
    // On a tilted line (3D collinear, all coordinates exact).
    let d = p(1.0, 2.0, -3.0);
    assert!(segment_segment(d * 0.0, d * 2.0, d * 1.0, d * 3.0, 0.0));
    assert!(!segment_segment(d * 0.0, d * 1.0, d * 2.0, d * 3.0, 0.0));
    assert!(segment_segment(d * 0.0, d * 1.0, d * 1.0, d * 3.0, 0.0));
}

#[test]
fn skew_segments_near_miss() {
    let (a0, a1) = (p(-1.0, 0.0, 0.0), p(1.0, 0.0, 0.0));
    let (b0, b1) = (p(0.0, -1.0, 1e-3), p(0.0, 1.0, 1e-3));
    assert!(!segment_segment(a0, a1, b0, b1, 0.0));
    assert!(!segment_segment(a0, a1, b0, b1, 0.9e-3), "beyond thickness");
    assert!(segment_segment(a0, a1, b0, b1, 1.1e-3), "within thickness");
    // The closest points of the lines are outside b: the ends decide.
    let (c0, c1) = (p(0.0, 2.0, 1e-3), p(0.0, 3.0, 1e-3));
    assert!(!segment_segment(a0, a1, c0, c1, 1.5));
    assert!(segment_segment(a0, a1, c0, c1, 2.001));
}

#[test]
fn crossing_and_touching_segments() {
    let (a0, a1) = (p(-1.0, 0.0, 0.0), p(1.0, 0.0, 0.0));
    assert!(segment_segment(
        a0,
        a1,
        p(0.0, -1.0, 0.0),
        p(0.0, 1.0, 0.0),
        0.0
    ));
    // T-junction: an endpoint on the other segment's interior.
    assert!(segment_segment(
        a0,
        a1,
        p(0.0, 0.0, 0.0),
        p(0.0, 1.0, 0.0),
        0.0
    ));
    // Endpoint to endpoint.
    assert!(segment_segment(a0, a1, a1, p(2.0, 5.0, 1.0), 0.0));
    // The smallest miss f64 can express near 0.
    let tiny = f64::MIN_POSITIVE;
    assert!(!segment_segment(
        a0,
        a1,
        p(0.0, tiny, 0.0),
        p(0.0, 1.0, 0.0),
        0.0
    ));
    // Zero-length segments are points.
    let q = p(0.25, 0.0, 0.0);
    assert!(segment_segment(a0, a1, q, q, 0.0));
    assert!(!segment_segment(
        a0,
        a1,
        q + DVec3::Z * 1e-300,
        q + DVec3::Z * 1e-300,
        0.0
    ));
    assert!(segment_segment(q, q, q, q, 0.0));
}

#[test]
fn near_parallel_segments() {
    // Crossing at x = 0.5 at an angle of 2e-12: exact.
    let (a0, a1) = (p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0));
    let (b0, b1) = (p(0.0, -1e-12, 0.0), p(1.0, 1e-12, 0.0));
    assert!(segment_segment(a0, a1, b0, b1, 0.0));
    // The same, lifted by 1e-9: skew, closest at distance 1e-9.
    let lift = DVec3::Z * 1e-9;
    assert!(!segment_segment(a0, a1, b0 + lift, b1 + lift, 0.0));
    assert!(!segment_segment(a0, a1, b0 + lift, b1 + lift, 0.99e-9));
    assert!(segment_segment(a0, a1, b0 + lift, b1 + lift, 1.01e-9));
    // Nearly parallel, not crossing.
    let (c0, c1) = (p(0.0, 1e-9, 0.0), p(1.0, 1e-9 + 1e-12, 0.0));
    assert!(!segment_segment(a0, a1, c0, c1, 0.0));
    assert!(segment_segment(a0, a1, c0, c1, 1.01e-9));
    assert!(!segment_segment(a0, a1, c0, c1, 0.99e-9));
}

#[test]
fn negative_and_nan_thickness_mean_exact() {
    let (a0, a1) = (p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0));
    let (b0, b1) = (p(0.0, 0.5, 0.0), p(1.0, 0.5, 0.0));
    assert!(!segment_segment(a0, a1, b0, b1, -1.0));
    assert!(!segment_segment(a0, a1, b0, b1, f64::NAN));
}

// ---- segment–triangle ----

const T: [DVec3; 3] = [
    DVec3::new(0.0, 0.0, 0.0),
    DVec3::new(1.0, 0.0, 0.0),
    DVec3::new(0.0, 1.0, 0.0),
];

fn st(s0: DVec3, s1: DVec3) -> bool {
    let hit = segment_triangle(s0, s1, T[0], T[1], T[2]);
    // The answer never depends on the order of corners or ends.
    for t in [[T[1], T[2], T[0]], [T[2], T[1], T[0]], [T[0], T[2], T[1]]] {
        assert_eq!(segment_triangle(s0, s1, t[0], t[1], t[2]), hit);
        assert_eq!(segment_triangle(s1, s0, t[0], t[1], t[2]), hit);
    }
    hit
}

#[test]
fn segment_through_triangle() {
    assert!(st(p(0.2, 0.2, -1.0), p(0.2, 0.2, 1.0)), "interior");
    assert!(st(p(0.5, 0.0, -1.0), p(0.5, 0.0, 1.0)), "edge");
    assert!(st(p(0.5, 0.5, -1.0), p(0.5, 0.5, 1.0)), "hypotenuse");
    assert!(st(p(0.0, 0.0, -1.0), p(0.0, 0.0, 1.0)), "vertex");
    assert!(st(p(1.0, 0.0, -1.0), p(1.0, 0.0, 1.0)), "vertex");
    assert!(
        !st(p(0.5, -1e-300, -1.0), p(0.5, -1e-300, 1.0)),
        "just outside an edge"
    );
    assert!(
        st(p(0.2, 0.2, 0.0), p(0.2, 0.2, 1.0)),
        "ends on the triangle"
    );
    assert!(
        !st(p(0.2, 0.2, 1e-300), p(0.2, 0.2, 1.0)),
        "ends just above"
    );
    // Slanted through the interior.
    assert!(st(p(-1.0, -1.0, -1.0), p(1.0, 1.0, 1.0)));
    assert!(!st(p(-1.0, -1.0, 1.0), p(1.0, 1.0, 3.0)));
}

#[test]
fn segment_coplanar_with_triangle() {
    assert!(st(p(-1.0, 0.25, 0.0), p(2.0, 0.25, 0.0)), "crossing");
    assert!(st(p(0.1, 0.1, 0.0), p(0.2, 0.2, 0.0)), "inside");
    assert!(!st(p(1.0, 1.0, 0.0), p(2.0, 2.0, 0.0)), "outside");
    assert!(!st(p(0.6, 0.6, 0.0), p(1.0, 1.0, 0.0)), "outside, near");
    assert!(
        st(p(0.5, 0.5, 0.0), p(1.0, 1.0, 0.0)),
        "touching the hypotenuse"
    );
    assert!(st(p(-1.0, 0.0, 0.0), p(2.0, 0.0, 0.0)), "along an edge");
    assert!(
        !st(p(-1.0, -0.5, 0.0), p(-0.5, -1.0, 0.0)),
        "beside a corner"
    );
    // Plane z = x + y (exact coordinates).
    let t = [p(0.0, 0.0, 0.0), p(1.0, 0.0, 1.0), p(0.0, 1.0, 1.0)];
    assert!(segment_triangle(
        p(0.25, 0.25, 0.5),
        p(-1.0, 0.25, -0.75),
        t[0],
        t[1],
        t[2]
    ));
    assert!(!segment_triangle(
        p(1.0, 1.0, 2.0),
        p(2.0, 1.0, 3.0),
        t[0],
        t[1],
        t[2]
    ));
    // Plane y = 0: perpendicular to two coordinate planes.
    let t = [p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(0.0, 0.0, 1.0)];
    assert!(segment_triangle(
        p(0.2, 0.0, -1.0),
        p(0.2, 0.0, 2.0),
        t[0],
        t[1],
        t[2]
    ));
    assert!(!segment_triangle(
        p(2.0, 0.0, 0.0),
        p(2.0, 0.0, 1.0),
        t[0],
        t[1],
        t[2]
    ));
}

#[test]
fn segment_parallel_to_triangle() {
    assert!(!st(p(-1.0, 0.25, 1.0), p(2.0, 0.25, 1.0)), "parallel above");
    assert!(
        !st(p(0.1, 0.1, -1e-300), p(0.2, 0.2, -1e-300)),
        "parallel just below"
    );
}

#[test]
fn degenerate_triangles_are_their_edges() {
    let line = [p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(2.0, 0.0, 0.0)];
    let [a, b, c] = line;
    assert!(segment_triangle(
        p(0.5, -1.0, 0.0),
        p(0.5, 1.0, 0.0),
        a,
        b,
        c
    ));
    assert!(!segment_triangle(
        p(0.5, -1.0, 1.0),
        p(0.5, 1.0, 1.0),
        a,
        b,
        c
    ));
    assert!(!segment_triangle(
        p(3.0, -1.0, 0.0),
        p(3.0, 1.0, 0.0),
        a,
        b,
        c
    ));
    let dot = [p(1.0, 1.0, 1.0); 3];
    assert!(segment_triangle(
        p(0.0, 0.0, 0.0),
        p(2.0, 2.0, 2.0),
        dot[0],
        dot[1],
        dot[2]
    ));
    assert!(!segment_triangle(
        p(0.0, 0.0, 0.0),
        p(2.0, 2.0, 2.1),
        dot[0],
        dot[1],
        dot[2]
    ));
}

// ---- triangle–triangle ----

const A: [DVec3; 3] = [
    DVec3::new(0.0, 0.0, 0.0),
    DVec3::new(2.0, 0.0, 0.0),
    DVec3::new(0.0, 2.0, 0.0),
];

fn tt(a: [DVec3; 3], b: [DVec3; 3]) -> bool {
    let hit = triangle_triangle(a, b);
    assert_eq!(triangle_triangle(b, a), hit, "symmetric");
    assert_eq!(
        triangle_triangle([a[1], a[2], a[0]], [b[2], b[1], b[0]]),
        hit
    );
    hit
}

#[test]
fn crossing_triangles() {
    let b = [p(0.5, 0.5, -1.0), p(0.5, 0.5, 1.0), p(-1.0, -1.0, 0.0)];
    assert!(tt(A, b));
    // Interlocked like chain links: each pierces the other's interior.
    let b = [p(1.0, 0.5, -1.0), p(1.0, 0.5, 1.0), p(1.0, 5.0, 0.0)];
    assert!(tt(A, b));
    // Above the plane.
    let b = [p(0.5, 0.5, 0.1), p(0.5, 0.5, 1.0), p(-1.0, -1.0, 0.1)];
    assert!(!tt(A, b));
    // Straddling the plane, but beside the triangle.
    let b = [p(3.0, 3.0, -1.0), p(3.0, 3.0, 1.0), p(5.0, 1.0, 0.0)];
    assert!(!tt(A, b));
    // Touching at a single corner, no shared id: contact counts.
    let b = [p(2.0, 0.0, 0.0), p(3.0, 0.0, 1.0), p(3.0, 1.0, 1.0)];
    assert!(tt(A, b));
}

#[test]
fn coplanar_triangles() {
    assert!(
        tt(A, [p(0.5, 0.5, 0.0), p(3.0, 0.5, 0.0), p(0.5, 3.0, 0.0)]),
        "overlapping"
    );
    assert!(
        tt(A, [p(0.2, 0.2, 0.0), p(0.4, 0.2, 0.0), p(0.2, 0.4, 0.0)]),
        "contained"
    );
    assert!(
        tt(
            A,
            [p(-1.0, -1.0, 0.0), p(5.0, -1.0, 0.0), p(-1.0, 5.0, 0.0)]
        ),
        "containing"
    );
    assert!(
        !tt(A, [p(3.0, 3.0, 0.0), p(4.0, 3.0, 0.0), p(3.0, 4.0, 0.0)]),
        "disjoint"
    );
    assert!(
        tt(A, [p(1.0, 1.0, 0.0), p(2.0, 1.0, 0.0), p(1.0, 2.0, 0.0)]),
        "touching"
    );
    let eps = 1e-15;
    assert!(
        !tt(
            A,
            [
                p(1.0 + eps, 1.0, 0.0),
                p(2.0, 1.0, 0.0),
                p(1.0, 2.0 + eps, 0.0)
            ]
        ),
        "just apart"
    );
}

// ---- shared vertices ----

fn tri(pts: [DVec3; 3], ids: [Option<VertId>; 3]) -> Primitive {
    Primitive::triangle(pts, ids)
}

fn both_ways(a: &Primitive, b: &Primitive, h: f64) -> bool {
    let hit = primitives_intersect(a, b, h);
    assert_eq!(primitives_intersect(b, a, h), hit, "symmetric");
    hit
}

#[test]
fn triangles_sharing_an_edge() {
    let (u, w) = (p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0));
    let a = tri([u, w, p(0.5, 1.0, 0.0)], [v(0), v(1), v(2)]);
    // Opposite sides, coplanar: a flat strip.
    let b = tri([w, u, p(0.5, -1.0, 0.0)], [v(1), v(0), v(3)]);
    assert!(!both_ways(&a, &b, 0.0));
    // Bent along the edge.
    let b = tri([w, u, p(0.5, -1.0, 0.7)], [v(1), v(0), v(3)]);
    assert!(!both_ways(&a, &b, 0.0));
    let b = tri([w, u, p(0.5, 1.0, 0.7)], [v(1), v(0), v(3)]);
    assert!(!both_ways(&a, &b, 0.0), "sharp fold, not flat");
    // Folded flat onto each other.
    let b = tri([w, u, p(0.5, 0.5, 0.0)], [v(1), v(0), v(3)]);
    assert!(both_ways(&a, &b, 0.0));
    // Same geometry without ids: they touch along the edge.
    assert!(triangle_triangle(
        a.points().try_into().unwrap(),
        [w, u, p(0.5, -1.0, 0.0)]
    ));
    // The shared pair is a triangulation diagonal of `a`: they meet along it.
    let diag = Primitive::face_triangle(
        [u, w, p(0.5, 1.0, 0.0)],
        [v(0), v(1), v(2)],
        [false, true, true],
    );
    let b = tri([w, u, p(0.5, -1.0, 0.7)], [v(1), v(0), v(3)]);
    assert!(both_ways(&diag, &b, 0.0));
}

#[test]
fn triangles_sharing_a_vertex() {
    let o = p(0.0, 0.0, 0.0);
    let a = tri([o, p(2.0, 0.0, 0.0), p(0.0, 2.0, 0.0)], [v(0), v(1), v(2)]);
    // Touching only at the shared vertex (out of plane, and in plane).
    let b = tri(
        [o, p(-1.0, 0.0, 1.0), p(0.0, -1.0, 1.0)],
        [v(0), v(3), v(4)],
    );
    assert!(!both_ways(&a, &b, 0.0));
    let b = tri(
        [o, p(-1.0, 0.0, 0.0), p(0.0, -1.0, 0.0)],
        [v(0), v(3), v(4)],
    );
    assert!(!both_ways(&a, &b, 0.0));
    // In plane, the wedges touch along a ray only beyond... no: they share an edge direction.
    let b = tri([o, p(1.0, 0.0, 0.0), p(0.0, -1.0, 0.0)], [v(0), v(3), v(4)]);
    assert!(both_ways(&a, &b, 0.0), "overlap along the x axis");
    // Sharing the vertex and piercing: B stands in the plane x = y.
    let b = tri([o, p(0.5, 0.5, -1.0), p(0.5, 0.5, 1.0)], [v(0), v(3), v(4)]);
    assert!(both_ways(&a, &b, 0.0));
    // Sharing the vertex, crossing far from it.
    let b = tri([o, p(1.0, 0.5, -1.0), p(0.5, 1.0, 1.0)], [v(0), v(3), v(4)]);
    assert!(both_ways(&a, &b, 0.0));
    // Coplanar, B's wedge inside A's, B much smaller.
    let b = tri(
        [o, p(0.1, 0.05, 0.0), p(0.05, 0.1, 0.0)],
        [v(0), v(3), v(4)],
    );
    assert!(both_ways(&a, &b, 0.0));
    // Without ids every one of these touches at the origin.
    assert!(triangle_triangle(
        a.points().try_into().unwrap(),
        [o, p(-1.0, 0.0, 1.0), p(0.0, -1.0, 1.0)]
    ));
}

#[test]
fn segment_and_triangle_sharing_an_endpoint() {
    let o = p(0.0, 0.0, 0.0);
    let t = tri([o, p(2.0, 0.0, 0.0), p(0.0, 2.0, 0.0)], [v(0), v(1), v(2)]);
    let seg = |end: DVec3| Primitive::segment([o, end], [v(0), v(9)]);
    assert!(
        !both_ways(&seg(p(0.0, 0.0, 1.0)), &t, 0.0),
        "out of the plane"
    );
    assert!(
        !both_ways(&seg(p(-1.0, -1.0, 0.0)), &t, 0.0),
        "in plane, away"
    );
    assert!(
        both_ways(&seg(p(0.5, 0.5, 0.0)), &t, 0.0),
        "into the interior, coplanar"
    );
    assert!(
        both_ways(&seg(p(3.0, 3.0, 0.0)), &t, 0.0),
        "across the interior, coplanar"
    );
    assert!(both_ways(&seg(p(1.0, 0.0, 0.0)), &t, 0.0), "along an edge");
    // Starting at the vertex and piercing the far edge region of another triangle.
    let far = tri([o, p(2.0, 0.0, 0.0), p(1.0, 1.0, -1.0)], [v(0), v(1), v(5)]);
    let s = Primitive::segment([o, p(1.0, 1.0, 1.0)], [v(0), v(9)]);
    assert!(!both_ways(&s, &far, 0.0));
    // A segment along the shared edge of a face: allowed.
    let edge = Primitive::segment([o, p(2.0, 0.0, 0.0)], [v(0), v(1)]);
    assert!(!both_ways(&edge, &t, 0.0));
    // A segment along a triangulation diagonal: it lies in the face.
    let diag = Primitive::face_triangle(
        [o, p(2.0, 0.0, 0.0), p(0.0, 2.0, 0.0)],
        [v(0), v(1), v(2)],
        [false, true, true],
    );
    assert!(both_ways(&edge, &diag, 0.0));
}

#[test]
fn segments_sharing_an_endpoint() {
    let o = p(0.0, 0.0, 0.0);
    let a = Primitive::segment([o, p(1.0, 0.0, 0.0)], [v(0), v(1)]);
    let seg = |end: DVec3| Primitive::segment([o, end], [v(0), v(2)]);
    assert!(!both_ways(&a, &seg(p(0.0, 1.0, 0.0)), 0.0));
    assert!(
        !both_ways(&a, &seg(p(-1.0, 0.0, 0.0)), 0.0),
        "collinear, opposite"
    );
    assert!(
        both_ways(&a, &seg(p(2.0, 0.0, 0.0)), 0.0),
        "collinear, overlapping"
    );
    assert!(
        both_ways(&a, &seg(p(0.5, 0.0, 0.0)), 0.0),
        "collinear, inside"
    );
    // Thickness: the far end of one within h of the other.
    let b = seg(p(1.0, 0.1, 0.0));
    assert!(!both_ways(&a, &b, 0.05));
    assert!(both_ways(&a, &b, 0.2));
    // Without ids they touch at the origin whatever the thickness.
    assert!(segment_segment(
        o,
        p(1.0, 0.0, 0.0),
        o,
        p(0.0, 1.0, 0.0),
        0.0
    ));
    // The same edge twice: the contact is the shared edge.
    let same = Primitive::segment([p(1.0, 0.0, 0.0), o], [v(1), v(0)]);
    assert!(!both_ways(&a, &same, 0.0));
}

#[test]
fn triangles_on_the_same_three_vertices_overlap() {
    let pts = [p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(0.0, 1.0, 0.0)];
    let a = tri(pts, [v(0), v(1), v(2)]);
    let b = tri([pts[2], pts[1], pts[0]], [v(2), v(1), v(0)]);
    assert!(both_ways(&a, &b, 0.0));
}

// ---- whole meshes ----

fn cube(size: f64) -> Mesh {
    let mut m = Mesh::new();
    create::create_cube(&mut m, size).unwrap();
    m
}

#[test]
fn closed_shapes_do_not_self_intersect() {
    assert!(self_intersections(&cube(1.0)).is_empty());
    let mut sphere = Mesh::new();
    create::create_uv_sphere(&mut sphere, 32, 16, 1.0).unwrap();
    assert!(self_intersections(&sphere).is_empty());
    let mut cyl = Mesh::new();
    create::create_cylinder(&mut cyl, 24, 1.0, 0.5, 2.0, true).unwrap();
    assert!(self_intersections(&cyl).is_empty());
    let mut cone = Mesh::new();
    create::create_cylinder(&mut cone, 7, 1.0, 0.0, 2.0, true).unwrap();
    assert!(self_intersections(&cone).is_empty());
    // Flat: every neighbour is coplanar (shared edges and shared corners).
    let mut grid = Mesh::new();
    create::create_grid(&mut grid, 12, 9, 3.0, 2.0).unwrap();
    assert!(self_intersections(&grid).is_empty());
    // A flat n-gon fan: coplanar triangles around a centre vertex.
    let mut circle = Mesh::new();
    create::create_circle(&mut circle, 9, 1.0, true).unwrap();
    assert!(self_intersections(&circle).is_empty());
}

#[test]
fn cube_with_a_corner_pushed_through() {
    let mut m = cube(1.0);
    let corner = m
        .vert_ids()
        .find(|&v| m.position(v) == DVec3::splat(0.5))
        .unwrap();
    m.place(corner, p(0.2, 0.2, -0.9));
    let pairs = self_intersections(&m);
    assert!(!pairs.is_empty());
    // The bottom face (-Z) is pierced by faces that used the corner.
    let bottom = m
        .face_ids()
        .find(|&f| m.face_verts(f).all(|v| m.position(v).z == -0.5))
        .unwrap();
    let moved: Vec<FaceId> = m.vert_faces(corner).collect();
    assert!(pairs
        .iter()
        .any(|&(a, b)| (a == bottom && moved.contains(&b)) || (b == bottom && moved.contains(&a))));
    assert!(
        pairs.windows(2).all(|w| w[0] < w[1]),
        "sorted, deduplicated"
    );
    assert!(pairs.iter().all(|(a, b)| a < b));
}

#[test]
fn two_joined_interpenetrating_cubes() {
    let mut m = cube(1.0);
    let map = m.join_mesh(&cube(1.0));
    let second: Vec<VertId> = map.verts.iter().flatten().copied().collect();
    for &v in &second {
        let q = m.position(v);
        m.place(v, q + DVec3::splat(0.5));
    }
    // Each of the first cube's +X, +Y, +Z faces crosses two of the second
    // cube's -X, -Y, -Z faces (the perpendicular ones).
    let pairs = self_intersections(&m);
    assert_eq!(pairs.len(), 6, "{pairs:?}");
    let normal = |f: FaceId| m.compute_face_normal(f);
    for (a, b) in pairs {
        let (na, nb) = (normal(a), normal(b));
        assert_eq!(na.dot(nb), 0.0, "perpendicular faces");
        assert_eq!(na.element_sum() + nb.element_sum(), 0.0, "one +, one -");
    }
}

#[test]
fn flat_fold_is_an_intersection() {
    let mut m = Mesh::new();
    let u = m.make_vert(p(0.0, 0.0, 0.0));
    let w = m.make_vert(p(1.0, 0.0, 0.0));
    let a = m.make_vert(p(0.5, 1.0, 0.0));
    let b = m.make_vert(p(0.5, 0.5, 0.0));
    let f0 = m.make_face(&[u, w, a]).unwrap();
    let f1 = m.make_face(&[w, u, b]).unwrap();
    assert_eq!(self_intersections(&m), vec![(f0, f1)]);
    m.place(b, p(0.5, -0.5, 0.0));
    assert!(self_intersections(&m).is_empty());
}

#[test]
fn non_planar_faces_use_their_triangulation() {
    // A twisted quad next to a flat one, sharing an edge; neither crosses.
    let mut m = Mesh::new();
    let q = [
        p(0.0, 0.0, 0.0),
        p(1.0, 0.0, 0.3),
        p(1.0, 1.0, 0.0),
        p(0.0, 1.0, 0.3),
        p(2.0, 0.0, 0.0),
        p(2.0, 1.0, 0.0),
    ]
    .map(|x| m.make_vert(x));
    m.make_face(&[q[0], q[1], q[2], q[3]]).unwrap();
    m.make_face(&[q[1], q[4], q[5], q[2]]).unwrap();
    assert!(self_intersections(&m).is_empty());
}

#[test]
fn wire_edges_with_thickness() {
    let mut m = Mesh::new();
    // Two parallel wires 0.3 apart, and a path of two wires sharing a node.
    let a0 = m.make_vert(p(0.0, 0.0, 0.0));
    let (e0, _) = m.make_edge_vert(a0, p(1.0, 0.0, 0.0)).unwrap();
    let b0 = m.make_vert(p(0.0, 0.3, 0.0));
    let (e1, b1) = m.make_edge_vert(b0, p(1.0, 0.3, 0.0)).unwrap();
    let (e2, _) = m.make_edge_vert(b1, p(1.0, 0.3, 1.0)).unwrap();
    m.add_layer("radius", Domain::Vert, AttrValue::Scalar(0.1))
        .unwrap();
    let thin = self_intersections_with(&m, WireThickness::VertLayer("radius"));
    assert!(thin.is_empty(), "0.1 + 0.1 < 0.3: {thin:?}");
    m.set_attr("radius", Domain::Vert, a0.index(), AttrValue::Scalar(0.25));
    let thick = self_intersections_with(&m, WireThickness::VertLayer("radius"));
    // e2 rises from b1, which is 0.3 from the end of e0.
    assert_eq!(thick.edges, vec![(e0, e1), (e0, e2)], "0.25 + 0.1 >= 0.3");
    assert!(self_intersections_with(&m, WireThickness::Zero).is_empty());
    let per_edge = |e: EdgeId| if e == e2 { 5.0 } else { 0.0 };
    let fat = self_intersections_with(&m, WireThickness::PerEdge(&per_edge));
    // e1 shares b1 with e2, but its far end b0 is within e2's 5 too.
    assert_eq!(fat.edges, vec![(e0, e2), (e1, e2)]);
    let short = |e: EdgeId| if e == e2 { 0.5 } else { 0.0 };
    let r = self_intersections_with(&m, WireThickness::PerEdge(&short));
    assert_eq!(
        r.edges,
        vec![(e0, e2)],
        "b0 is 1 from e2: the shared node is excused"
    );
    // A wire piercing a face of a cube; another one beside it.
    let mut m = cube(1.0);
    let s = m.make_vert(p(0.0, 0.0, 0.0));
    let (pierce, _) = m.make_edge_vert(s, p(0.0, 0.0, 2.0)).unwrap();
    let t = m.make_vert(p(2.0, 0.0, -1.0));
    let (beside, _) = m.make_edge_vert(t, p(2.0, 0.0, 1.0)).unwrap();
    let top = m
        .face_ids()
        .find(|&f| m.compute_face_normal(f) == DVec3::Z)
        .unwrap();
    let r = self_intersections_with(&m, WireThickness::Zero);
    assert_eq!(r.edge_faces, vec![(pierce, top)]);
    assert!(r.faces.is_empty() && r.edges.is_empty());
    let wide = |e: EdgeId| if e == beside { 1.5 } else { 0.0 };
    let r = self_intersections_with(&m, WireThickness::PerEdge(&wide));
    let hit: Vec<EdgeId> = r.edge_faces.iter().map(|&(e, _)| e).collect();
    assert!(hit.contains(&beside) && hit.contains(&pierce));
    assert!(self_intersections(&m).is_empty(), "faces only");
}

#[test]
fn large_meshes_on_several_threads() {
    // Two spheres of 2·80·79 triangles each, overlapping: enough items for
    // the threaded descent.
    let mut m = Mesh::new();
    create::create_uv_sphere(&mut m, 80, 80, 1.0).unwrap();
    let map = m.join_mesh(&{
        let mut s = Mesh::new();
        create::create_uv_sphere(&mut s, 80, 80, 1.0).unwrap();
        s
    });
    for v in map.verts.iter().flatten() {
        let q = m.position(*v);
        m.place(*v, q + DVec3::new(1.0, 0.25, 0.125));
    }
    let items = mesh_items(&m, None);
    assert!(items.len() >= super::bvh::PARALLEL_ITEMS);
    let one = bvh::intersecting_pairs_on(items.clone(), 1);
    assert!(!one.is_empty());
    assert_eq!(one, bvh::intersecting_pairs_on(items, 2));
    let faces: Vec<(FaceId, FaceId)> = one
        .iter()
        .map(|&(a, b)| match (a, b) {
            (Element::Face(a), Element::Face(b)) => (a, b),
            _ => unreachable!(),
        })
        .collect();
    assert_eq!(self_intersections(&m), faces);
    // Each crossing pair has one face of each sphere.
    let first = m.face_count() as u32 / 2;
    assert!(faces
        .iter()
        .all(|&(a, b)| a.raw() < first && b.raw() >= first));
}

#[test]
fn empty_and_single_element_meshes() {
    assert!(self_intersections(&Mesh::new()).is_empty());
    let mut m = Mesh::new();
    create::create_circle(&mut m, 5, 1.0, true).unwrap();
    assert!(self_intersections(&m).is_empty());
    assert!(IntersectionIndex::from_mesh(&Mesh::new(), WireThickness::Zero).is_empty());
}

// ---- the index ----

#[test]
fn index_segment_queries_on_a_cube() {
    let m = cube(2.0);
    let index = IntersectionIndex::from_mesh(&m, WireThickness::Zero);
    assert_eq!(index.len(), 12);
    let corner =
        |x: f64, y: f64, z: f64| m.vert_ids().find(|&v| m.position(v) == p(x, y, z)).unwrap();
    let c0 = corner(-1.0, -1.0, -1.0);
    let c6 = corner(1.0, 1.0, 1.0);
    let (q0, q6) = (m.position(c0), m.position(c6));
    // Outward from a corner: touches only there.
    assert!(index.segment_hits(q0, p(-2.0, -2.0, -2.0), 0.0, &[]));
    assert!(!index.segment_hits(q0, p(-2.0, -2.0, -2.0), 0.0, &[c0]));
    // The other end still counts unless it too is attached.
    assert!(index.segment_hits(q0, q6, 0.0, &[c0]));
    assert!(
        !index.segment_hits(q0, q6, 0.0, &[c0, c6]),
        "the cube is hollow"
    );
    // From a corner to the middle of the opposite face.
    assert!(index.segment_hits(q0, p(0.0, 0.0, 1.0), 0.0, &[c0]));
    // Along the cube's own edge from c0: the edge is shared with the faces
    // only if the query ends are both vertices of it.
    let c1 = corner(1.0, -1.0, -1.0);
    assert!(!index.segment_hits(q0, m.position(c1), 0.0, &[c0, c1]));
    assert!(
        index.segment_hits(q0, p(0.0, -1.0, -1.0), 0.0, &[c0]),
        "half an edge"
    );
    // An ignored vertex the query does not start at changes nothing.
    assert!(index.segment_hits(p(0.0, 0.0, -5.0), p(0.0, 0.0, 5.0), 0.0, &[c0]));
    // Triangles and faces.
    assert!(index.triangle_hits([p(0.0, 0.0, 0.0), p(3.0, 0.0, 0.0), p(0.0, 3.0, 0.0)], &[]));
    assert!(!index.triangle_hits(
        [p(-0.5, -0.5, 0.0), p(0.5, -0.5, 0.0), p(0.0, 0.5, 0.0)],
        &[]
    ));
    let cap = [q6, p(1.0, 1.0, 3.0), p(0.0, 2.0, 2.0)];
    assert!(index.triangle_hits(cap, &[]));
    assert!(!index.triangle_hits(cap, &[c6]));
    let ring = [
        p(-0.5, -0.5, 5.0),
        p(0.5, -0.5, 5.0),
        p(0.5, 0.5, 5.0),
        p(-0.5, 0.5, 5.0),
    ];
    assert!(!index.face_hits(&ring, &[]));
    let ring = ring.map(|q| q - DVec3::Z * 4.0);
    assert!(index.face_hits(&ring, &[]));
}

#[test]
fn index_wire_edges_add_their_thickness() {
    let mut m = Mesh::new();
    let a = m.make_vert(p(0.0, 0.0, 0.0));
    let (e, _) = m.make_edge_vert(a, p(0.0, 0.0, 1.0)).unwrap();
    let mut index = IntersectionIndex::new();
    index.insert_edge(&m, e, 0.25);
    let (q0, q1) = (p(0.5, -1.0, 0.5), p(0.5, 1.0, 0.5));
    assert!(!index.segment_hits(q0, q1, 0.2, &[]));
    assert!(index.segment_hits(q0, q1, 0.3, &[]));
    assert!(!index.triangle_hits([p(0.3, -1.0, 0.0), p(0.3, 1.0, 0.0), p(0.3, 0.0, 1.0)], &[]));
    assert!(index.triangle_hits([p(0.2, -1.0, 0.0), p(0.2, 1.0, 0.0), p(0.2, 0.0, 1.0)], &[]));
}

#[test]
fn index_insert_products_and_many_levels() {
    let mut m = Mesh::new();
    let made = create::create_grid(&mut m, 20, 20, 20.0, 20.0).unwrap();
    let mut index = IntersectionIndex::new();
    index.insert_products(&m, &made, WireThickness::Zero);
    assert_eq!(index.len(), 800, "two triangles per quad");
    assert!(index.tree_count() >= 2, "several levels");
    let centre = |x: f64, y: f64| p(x + 0.5, y + 0.5, 0.0);
    for i in -10..10 {
        let c = centre(i as f64, 3.0);
        assert!(index.segment_hits(c - DVec3::Z, c + DVec3::Z, 0.0, &[]));
        assert!(!index.segment_hits(c + DVec3::Z, c + DVec3::Z * 2.0, 0.0, &[]));
    }
    assert!(!index.segment_hits(p(11.0, 0.0, -1.0), p(11.0, 0.0, 1.0), 0.0, &[]));
}

#[test]
fn index_removed_elements_keep_only_their_new_shape() {
    // Enough faces that the removed ones sit in trees, not the buffer.
    let mut m = Mesh::new();
    let made = create::create_grid(&mut m, 20, 20, 20.0, 20.0).unwrap();
    let mut index = IntersectionIndex::from_mesh(&m, WireThickness::Zero);
    let through = |index: &IntersectionIndex, z: f64| {
        index.segment_hits(p(0.5, 0.5, z - 0.25), p(0.5, 0.5, z + 0.25), 0.0, &[])
    };
    assert!(through(&index, 0.0));
    let f = made
        .faces
        .iter()
        .copied()
        .find(|&g| m.face_verts(g).map(|v| m.position(v)).sum::<DVec3>() / 4.0 == p(0.5, 0.5, 0.0))
        .expect("a cell centred at (0.5, 0.5)");
    index.remove(Element::Face(f));
    assert!(!through(&index, 0.0), "removed");
    // The face lifted by 1 and stored again: only its new shape counts,
    // and removing it again takes that one out too.
    for v in m.face_verts(f).collect::<Vec<_>>() {
        m.place(v, m.position(v) + DVec3::Z);
    }
    index.insert_face(&m, f);
    assert!(through(&index, 1.0) && !through(&index, 0.0));
    index.remove(Element::Face(f));
    assert!(!through(&index, 1.0));
    // Other faces are untouched.
    assert!(index.segment_hits(p(5.5, 5.5, -1.0), p(5.5, 5.5, 1.0), 0.0, &[]));
}

/// A small soup of triangles and segments over a pool of shared vertices,
/// with coordinates on a coarse grid so that coplanar, collinear and
/// touching cases are common; split into stored items and queries that use
/// the same vertices.
fn soup_strategy() -> impl Strategy<Value = (Vec<Item>, Vec<Item>)> {
    let coord = (-4i32..=4).prop_map(|x| x as f64 * 0.5);
    let point = (coord.clone(), coord.clone(), coord);
    (
        prop::collection::vec(point, 8..14),
        prop::collection::vec((0usize..14, 0usize..14, 0usize..14, 0u8..4, 0u8..8), 1..32),
        0usize..32,
    )
        .prop_map(|(pool, prims, split)| {
            let pool: Vec<DVec3> = pool
                .into_iter()
                .map(|(x, y, z)| DVec3::new(x, y, z))
                .collect();
            let n = pool.len();
            let mut items: Vec<Item> = prims
                .into_iter()
                .enumerate()
                .filter_map(|(k, (i, j, l, kind, flags))| {
                    let (i, j, l) = (i % n, j % n, l % n);
                    let id = |x: usize| Some(VertId::from_raw(x as u32));
                    if kind == 0 {
                        (i != j).then(|| Item {
                            prim: Primitive::segment([pool[i], pool[j]], [id(i), id(j)]),
                            thickness: f64::from(flags % 3) * 0.25,
                            owner: Element::Edge(EdgeId::from_raw(k as u32)),
                            epoch: 0,
                        })
                    } else {
                        (i != j && j != l && i != l).then(|| Item {
                            prim: Primitive::face_triangle(
                                [pool[i], pool[j], pool[l]],
                                [id(i), id(j), id(l)],
                                [flags & 1 != 0, flags & 2 != 0, flags & 4 != 0],
                            ),
                            thickness: 0.0,
                            owner: Element::Face(FaceId::from_raw(k as u32)),
                            epoch: 0,
                        })
                    }
                })
                .collect();
            let queries = items.split_off(split.min(items.len()));
            (items, queries)
        })
}

fn translated(prim: &Primitive, offset: DVec3) -> Primitive {
    let p = prim.points;
    let v: Vec<Option<VertId>> = prim.verts().collect();
    if prim.is_segment() {
        Primitive::segment([p[0] + offset, p[1] + offset], [v[0], v[1]])
    } else {
        let bits = [0, 1, 2].map(|i| prim.boundary & (1 << i) != 0);
        Primitive::face_triangle(p.map(|q| q + offset), [v[0], v[1], v[2]], bits)
    }
}

fn brute_force(items: &[Item]) -> Vec<(Element, Element)> {
    let mut out = Vec::new();
    for (i, a) in items.iter().enumerate() {
        for b in &items[i + 1..] {
            if a.owner != b.owner && items_intersect(a, b) {
                out.push((a.owner.min(b.owner), a.owner.max(b.owner)));
            }
        }
    }
    out.sort_unstable();
    out.dedup();
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn bvh_pairs_equal_brute_force((mut items, queries) in soup_strategy(), shift in -3i32..3) {
        items.extend(queries);
        // Far from the origin too, where f32 rounding is coarse.
        let offset = DVec3::splat(f64::from(shift) * 1e7);
        let moved: Vec<Item> = items
            .iter()
            .map(|item| Item { prim: translated(&item.prim, offset), ..*item })
            .collect();
        prop_assert_eq!(bvh::intersecting_pairs(moved.clone()), brute_force(&moved));
    }

    #[test]
    fn threads_do_not_change_the_pairs((mut items, queries) in soup_strategy()) {
        items.extend(queries);
        let one = bvh::intersecting_pairs_on(items.clone(), 1);
        prop_assert_eq!(&one, &bvh::intersecting_pairs_on(items.clone(), 2));
        prop_assert_eq!(&one, &bvh::intersecting_pairs_on(items, 3));
    }

    #[test]
    fn shared_vertices_only_excuse_contact((mut items, queries) in soup_strategy()) {
        items.extend(queries);
        let strip = |p: &Primitive| {
            let mut q = *p;
            q.verts = [NO_VERT; 3];
            q
        };
        for a in &items {
            for b in &items {
                let h = a.thickness + b.thickness;
                let hit = primitives_intersect(&a.prim, &b.prim, h);
                prop_assert_eq!(hit, primitives_intersect(&b.prim, &a.prim, h), "symmetric");
                if hit {
                    prop_assert!(primitives_intersect(&strip(&a.prim), &strip(&b.prim), h));
                }
                // Turning a triangle's corners (with their edge flags) changes
                // nothing. Only checked for the exact tests: with a thickness
                // the distance is computed in floating point, and a pair at
                // exactly that distance may round either way by corner order.
                if !a.prim.is_segment() && h == 0.0 {
                    let p = a.prim.points;
                    let v: Vec<Option<VertId>> = a.prim.verts().collect();
                    let bits = [0, 1, 2].map(|i| a.prim.boundary & (1 << i) != 0);
                    let turned = Primitive::face_triangle(
                        [p[1], p[2], p[0]],
                        [v[1], v[2], v[0]],
                        [bits[1], bits[2], bits[0]],
                    );
                    prop_assert_eq!(hit, primitives_intersect(&turned, &b.prim, h), "turned");
                }
            }
        }
    }

    #[test]
    fn index_queries_equal_brute_force((items, queries) in soup_strategy()) {
        let mut index = IntersectionIndex::new();
        for item in &items {
            index.insert(*item);
        }
        let whole = IntersectionIndex::single_tree(items.clone());
        for q in &queries {
            let expect = items.iter().any(|item| {
                primitives_intersect(&q.prim, &item.prim, q.thickness + item.thickness)
            });
            prop_assert_eq!(index.primitive_hits(&q.prim, q.thickness), expect);
            prop_assert_eq!(whole.primitive_hits(&q.prim, q.thickness), expect);
        }
    }

    #[test]
    fn exact_predicates_are_symmetric_and_agree_with_distance(
        pts in prop::collection::vec((-4i32..=4, -4i32..=4, -4i32..=4), 6)
    ) {
        let q: Vec<DVec3> = pts
            .iter()
            .map(|&(x, y, z)| DVec3::new(f64::from(x), f64::from(y), f64::from(z)) * 0.5)
            .collect();
        let a = [q[0], q[1], q[2]];
        let b = [q[3], q[4], q[5]];
        let hit = triangle_triangle(a, b);
        prop_assert_eq!(hit, triangle_triangle(b, a));
        prop_assert_eq!(hit, triangle_triangle([a[2], a[0], a[1]], [b[1], b[0], b[2]]));
        let d2 = predicates::shapes_touch(
            Shape::Triangle(a[0], a[1], a[2]),
            Shape::Triangle(b[0], b[1], b[2]),
            1e-9,
        );
        // On this grid, a miss is at least ~1e-3 away.
        prop_assert_eq!(hit, d2);
        let s = segment_segment(q[0], q[1], q[2], q[3], 0.0);
        prop_assert_eq!(s, segment_segment(q[3], q[2], q[1], q[0], 0.0));
        prop_assert_eq!(s, segment_segment(q[0], q[1], q[2], q[3], 1e-9));
        let st = segment_triangle(q[0], q[1], q[2], q[3], q[4]);
        prop_assert_eq!(st, segment_triangle(q[1], q[0], q[4], q[2], q[3]));
        prop_assert_eq!(
            st,
            predicates::shapes_touch(Shape::Segment(q[0], q[1]), Shape::Triangle(q[2], q[3], q[4]), 1e-9)
        );
    }
}

// ---- close vertices ----

#[test]
fn close_vertices_by_grid() {
    let mut m = Mesh::new();
    let a = m.make_vert(p(0.0, 0.0, 0.0));
    let b = m.make_vert(p(1e-7, 0.0, 0.0));
    let c = m.make_vert(p(1.0, 1.0, 1.0));
    let d = m.make_vert(p(1.0, 1.0, 1.0 - 2.5e-7));
    // A vertex far from all: in no pair.
    m.make_vert(p(5.0, 5.0, 5.0));
    let f = m.make_vert(p(-0.0, 0.0, 0.0));
    assert_eq!(close_vertices(&m, 1.5e-7), vec![(a, b), (a, f), (b, f)]);
    assert_eq!(close_vertices(&m, 2.5e-7), vec![(a, b), (a, f), (b, f)]);
    assert_eq!(
        close_vertices(&m, 2.6e-7),
        vec![(a, b), (a, f), (b, f), (c, d)]
    );
    assert_eq!(close_vertices(&m, 0.0), vec![(a, f)], "-0 equals +0");
    assert!(close_vertices(&m, 1e-9).contains(&(a, f)));
    assert_eq!(close_vertices(&m, 100.0).len(), 15);
    // Straddling cell boundaries in every axis.
    let mut m = Mesh::new();
    let cell = 4.0 * 0.1;
    let g = m.make_vert(DVec3::splat(cell - 0.01));
    let h = m.make_vert(DVec3::splat(cell + 0.01));
    assert_eq!(close_vertices(&m, 0.1), vec![(g, h)]);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(100))]

    #[test]
    fn close_vertices_equal_brute_force(
        pts in prop::collection::vec((-20i32..20, -20i32..20, -20i32..20), 0..60),
        tol in 0.05f64..0.6,
    ) {
        let mut m = Mesh::new();
        for (x, y, z) in pts {
            m.make_vert(DVec3::new(f64::from(x), f64::from(y), f64::from(z)) * 0.1);
        }
        let ids: Vec<VertId> = m.vert_ids().collect();
        let mut expect = Vec::new();
        for (i, &a) in ids.iter().enumerate() {
            for &b in &ids[i + 1..] {
                if m.position(a).distance_squared(m.position(b)) <= tol * tol {
                    expect.push((a, b));
                }
            }
        }
        prop_assert_eq!(close_vertices(&m, tol), expect);
    }
}

/// A grid of quads with heights and offsets on a coarse lattice (coplanar
/// neighbours, folds and crossings are common; about half the cases
/// intersect): the mesh path of the whole-mesh test (flat soups, certified
/// filters) must agree with the reference on every pair of items.
fn bumpy_grid_strategy() -> impl Strategy<Value = Mesh> {
    (
        2u32..6,
        prop::collection::vec((-2i32..=2, -3i32..=3, -3i32..=3), 49),
    )
        .prop_map(|(k, jitter)| {
            let mut m = Mesh::new();
            create::create_grid(&mut m, k, k, f64::from(k), f64::from(k)).unwrap();
            let verts: Vec<VertId> = m.vert_ids().collect();
            for (v, (z, x, y)) in verts.into_iter().zip(jitter) {
                let q = m.position(v);
                let d = DVec3::new(f64::from(x) * 0.25, f64::from(y) * 0.25, f64::from(z) * 0.5);
                m.place(v, q + d);
            }
            m
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn mesh_pairs_equal_brute_force(m in bumpy_grid_strategy()) {
        let items = mesh_items(&m, None);
        let expect: Vec<(FaceId, FaceId)> = brute_force(&items)
            .into_iter()
            .map(|pair| match pair {
                (Element::Face(a), Element::Face(b)) => (a, b),
                _ => unreachable!("faces only"),
            })
            .collect();
        prop_assert_eq!(&self_intersections(&m), &expect);
        for threads in 1..=3 {
            let soup = pairs::mesh_soup(&m, None, threads);
            let found = pairs::intersecting_pairs(soup, threads);
            prop_assert_eq!(&found, &brute_force(&items));
        }
    }
}

// ---- the indexed mesh read as the kernel mesh it builds ----

/// Two overlapping UV spheres (quads and triangles, past the size where
/// faces are split between threads) and a bumpy sheet through them, as
/// the indexed mesh a reader would hand over.
fn crossing_shells() -> crate::geom::IndexedMesh {
    let mut m = Mesh::new();
    create::create_uv_sphere(&mut m, 64, 40, 1.0).unwrap();
    let other = create::create_uv_sphere(&mut m, 48, 30, 0.8).unwrap();
    transform::translate(&mut m, &other.verts, p(0.9, 0.1, 0.0)).unwrap();
    let sheet = create::create_grid(&mut m, 20, 20, 3.0, 3.0).unwrap();
    for &v in &sheet.verts {
        let q = m.position(v);
        m.place(v, q + p(0.0, 0.0, 0.05 * (3.0 * q.x).sin()));
    }
    m.to_indexed()
}

#[test]
fn indexed_search_equals_the_search_of_the_built_mesh() {
    let indexed = crossing_shells();
    assert!(crate::kernel::build::builds_one_to_one(&indexed));
    let (built, _) = crate::kernel::build::mesh_from_indexed(&indexed).unwrap();
    assert!(built.face_count() > pairs::PARALLEL_FACES);
    let limits = PairLimits::for_items;
    let expect = self_intersection_search(&built, limits);
    assert!(expect.count > 100 && expect.complete, "{expect:?}");
    assert_eq!(indexed_self_intersection_search(&indexed, limits), expect);
    // Under a test budget too small to finish, both stop alike.
    let tight = |_| PairLimits {
        keep: 10,
        max_tests: 5_000,
    };
    let stopped = self_intersection_search(&built, tight);
    assert!(!stopped.complete);
    assert_eq!(indexed_self_intersection_search(&indexed, tight), stopped);
    for threads in 1..=3 {
        let soup = pairs::indexed_soup(&indexed, threads);
        assert_eq!(soup.certified_fans(), certified(&built));
        assert_eq!(
            pairs::intersecting_pairs(soup, threads),
            pairs::intersecting_pairs(pairs::mesh_soup(&built, None, threads), threads)
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn indexed_pairs_equal_the_built_mesh_pairs(m in bumpy_grid_strategy()) {
        let indexed = m.to_indexed();
        prop_assert!(crate::kernel::build::builds_one_to_one(&indexed));
        let (built, _) = crate::kernel::build::mesh_from_indexed(&indexed).unwrap();
        prop_assert_eq!(
            indexed_self_intersection_search(&indexed, PairLimits::for_items),
            self_intersection_search(&built, PairLimits::for_items)
        );
    }
}

// ---- certified vertex fans ----

/// Per vertex id of `mesh`, whether the whole-mesh pass certified its fan.
fn certified(mesh: &Mesh) -> Vec<bool> {
    pairs::mesh_soup(mesh, None, 1).certified_fans().to_vec()
}

/// The whole-mesh pass on 1 and 2 threads against the all-pairs reference.
fn assert_pairs_match_reference(m: &Mesh) {
    let expect = brute_force(&mesh_items(m, None));
    for threads in 1..=2 {
        let found = pairs::intersecting_pairs(pairs::mesh_soup(m, None, threads), threads);
        assert_eq!(found, expect, "{threads} thread(s)");
    }
}

#[test]
fn every_fan_of_a_sphere_is_certified() {
    // 40 segments: the poles' fans are larger than the pairwise check
    // takes, and go through the sorted one.
    for segments in [6, 24, 40] {
        let mut m = Mesh::new();
        create::create_uv_sphere(&mut m, segments, 9, 1.0).unwrap();
        let fans = certified(&m);
        let uncertified: Vec<VertId> = m.vert_ids().filter(|v| !fans[v.index()]).collect();
        assert_eq!(uncertified, Vec::<VertId>::new(), "{segments} segments");
    }
}

/// A vertex at the origin with a closed fan of `n` triangles to a ring of
/// points `ring(i)`.
fn fan_mesh(n: usize, ring: impl Fn(usize) -> DVec3) -> (Mesh, VertId) {
    let mut m = Mesh::new();
    let centre = m.make_vert(DVec3::ZERO);
    let around: Vec<VertId> = (0..n).map(|i| m.make_vert(ring(i))).collect();
    for i in 0..n {
        m.make_face(&[centre, around[i], around[(i + 1) % n]])
            .unwrap();
    }
    (m, centre)
}

#[test]
fn a_flat_closed_fan_is_certified_and_a_fan_winding_twice_is_not() {
    let circle = |turns: f64, n: usize, rise: f64| {
        move |i: usize| {
            let angle = turns * std::f64::consts::TAU * i as f64 / n as f64;
            DVec3::new(angle.cos(), angle.sin(), rise * i as f64)
        }
    };
    for n in [4, 7, 40] {
        let (m, centre) = fan_mesh(n, circle(1.0, n, 0.0));
        assert!(certified(&m)[centre.index()], "flat fan of {n}");
        assert_pairs_match_reference(&m);
    }
    // The ring goes round twice (rising, so no two points coincide): the
    // link is one cycle, every sector turns the same way, yet the
    // triangles overlap.
    for (n, rise) in [(8, 0.0), (8, 0.05), (9, 0.02), (80, 0.001)] {
        let (m, centre) = fan_mesh(n, circle(2.0, n, rise));
        assert!(
            !certified(&m)[centre.index()],
            "double fan of {n}, rise {rise}"
        );
        assert_pairs_match_reference(&m);
        if rise == 0.0 {
            assert!(!self_intersections(&m).is_empty());
        }
    }
}

#[test]
fn folded_open_and_pinched_fans_are_not_certified() {
    // One ring point pulled across the centre: a sector turns the other
    // way.
    let (m, centre) = fan_mesh(6, |i| {
        let angle = std::f64::consts::TAU * i as f64 / 6.0;
        let r = if i == 2 { -0.3 } else { 1.0 };
        DVec3::new(r * angle.cos(), r * angle.sin(), 0.2)
    });
    assert!(!certified(&m)[centre.index()]);
    assert_pairs_match_reference(&m);

    // An open fan: the corner of a grid and its edge vertices.
    let mut grid = Mesh::new();
    create::create_grid(&mut grid, 3, 3, 3.0, 3.0).unwrap();
    let fans = certified(&grid);
    let certified_count = grid.vert_ids().filter(|v| fans[v.index()]).count();
    assert_eq!(certified_count, 4, "only the 2 × 2 inner vertices");

    // Two cones sharing their apex: two cycles in the link.
    let mut m = Mesh::new();
    let apex = m.make_vert(DVec3::ZERO);
    for z in [1.0, -1.0] {
        let ring: Vec<VertId> = (0..5)
            .map(|i| {
                let angle = std::f64::consts::TAU * f64::from(i) / 5.0;
                m.make_vert(DVec3::new(angle.cos(), angle.sin(), z))
            })
            .collect();
        for i in 0..5 {
            m.make_face(&[apex, ring[i], ring[(i + 1) % 5]]).unwrap();
        }
    }
    assert!(!certified(&m)[apex.index()]);
    assert_pairs_match_reference(&m);
}

/// A coarse UV sphere with every vertex moved by up to ±0.4 per axis:
/// closed fans, many certified, some folded through their neighbours.
fn jittered_sphere_strategy() -> impl Strategy<Value = Mesh> {
    prop::collection::vec((-4i32..=4, -4i32..=4, -4i32..=4), 42).prop_map(|jitter| {
        let mut m = Mesh::new();
        create::create_uv_sphere(&mut m, 8, 6, 1.0).unwrap();
        let verts: Vec<VertId> = m.vert_ids().collect();
        assert_eq!(verts.len(), jitter.len());
        for (v, (x, y, z)) in verts.into_iter().zip(jitter) {
            let d = DVec3::new(f64::from(x), f64::from(y), f64::from(z)) * 0.1;
            m.place(v, m.position(v) + d);
        }
        m
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn jittered_sphere_pairs_equal_brute_force(m in jittered_sphere_strategy()) {
        let expect = brute_force(&mesh_items(&m, None));
        for threads in 1..=2 {
            let found = pairs::intersecting_pairs(pairs::mesh_soup(&m, None, threads), threads);
            prop_assert_eq!(&found, &expect);
        }
    }
}
