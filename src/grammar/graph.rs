//! The G³ graph on the kernel (thesis 003 §2.4.1): a node is a vertex with
//! a radius and a turtle frame, an edge is directed from its first vertex
//! (pre-node) to its second (post-node) and carries its own frame, a face is
//! a kernel face. Every primitive records its age. All of it lives in
//! attribute layers, so kernel operators carry it along.

use glam::DVec3;

pub use crate::geom::frame::{any_perpendicular, Frame};

use crate::kernel::{AttrValue, Domain, EdgeId, FaceId, Mesh, VertId};

/// Node radius (vertex scalar; written as `_RADIUS` in glTF).
pub const RADIUS: &str = "radius";
/// Turtle heading H (vertex and edge vector).
pub const HEADING: &str = "heading";
/// Turtle left L (vertex and edge vector); up is U = H × L.
pub const LEFT: &str = "left";
/// Generation that created the primitive (integer, every domain).
pub const AGE: &str = "age";

/// Radius of a node nobody gave one.
pub const DEFAULT_RADIUS: f64 = 1.0;

/// Adds the graph layers if missing: radius 1, world frame, age 0.
pub fn ensure_layers(mesh: &mut Mesh) {
    let layers = [
        (RADIUS, Domain::Vert, AttrValue::Scalar(DEFAULT_RADIUS)),
        (HEADING, Domain::Vert, AttrValue::Vector(Frame::WORLD.h)),
        (LEFT, Domain::Vert, AttrValue::Vector(Frame::WORLD.l)),
        (HEADING, Domain::Edge, AttrValue::Vector(Frame::WORLD.h)),
        (LEFT, Domain::Edge, AttrValue::Vector(Frame::WORLD.l)),
        (AGE, Domain::Vert, AttrValue::Int(0)),
        (AGE, Domain::Edge, AttrValue::Int(0)),
        (AGE, Domain::Face, AttrValue::Int(0)),
    ];
    for (name, domain, default) in layers {
        // A same-named layer of another kind (from an imported file) stays;
        // reads then fall back to the defaults.
        let _ = mesh.add_layer(name, domain, default);
    }
}

fn vector(mesh: &Mesh, name: &str, domain: Domain, index: usize, default: DVec3) -> DVec3 {
    match mesh.attr(name, domain, index) {
        Some(AttrValue::Vector(v)) => v,
        _ => default,
    }
}

pub fn radius(mesh: &Mesh, v: VertId) -> f64 {
    match mesh.attr(RADIUS, Domain::Vert, v.index()) {
        Some(AttrValue::Scalar(r)) => r,
        _ => DEFAULT_RADIUS,
    }
}

pub fn age(mesh: &Mesh, domain: Domain, index: usize) -> i32 {
    match mesh.attr(AGE, domain, index) {
        Some(AttrValue::Int(a)) => a,
        _ => 0,
    }
}

/// Records the generation that made a primitive. Generations count steps
/// (at most 10⁶ after unrolling), so the 32-bit layer holds every one.
pub fn set_age(mesh: &mut Mesh, domain: Domain, index: usize, generation: u32) {
    let age = i32::try_from(generation).unwrap_or(i32::MAX);
    let _ = mesh.set_attr(AGE, domain, index, AttrValue::Int(age));
}

pub fn set_radius(mesh: &mut Mesh, v: VertId, r: f64) {
    let _ = mesh.set_attr(RADIUS, Domain::Vert, v.index(), AttrValue::Scalar(r));
}

/// Stores `frame` on a vertex or an edge.
pub fn set_frame(mesh: &mut Mesh, domain: Domain, index: usize, frame: &Frame) {
    set_heading_left(mesh, domain, index, frame.h, frame.l);
}

/// Stores a frame given by its heading and left (up is H × L on reading).
pub fn set_heading_left(mesh: &mut Mesh, domain: Domain, index: usize, h: DVec3, l: DVec3) {
    let _ = mesh.set_attr(HEADING, domain, index, AttrValue::Vector(h));
    let _ = mesh.set_attr(LEFT, domain, index, AttrValue::Vector(l));
}

pub fn node_frame(mesh: &Mesh, v: VertId) -> Frame {
    let h = vector(mesh, HEADING, Domain::Vert, v.index(), Frame::WORLD.h);
    let l = vector(mesh, LEFT, Domain::Vert, v.index(), Frame::WORLD.l);
    Frame::from_heading_left(h, l)
}

/// An edge's frame: H along the edge (pre → post), L from its stored left.
pub fn edge_frame(mesh: &Mesh, e: EdgeId) -> Frame {
    let [a, b] = mesh.edge_verts(e);
    let stored_h = vector(mesh, HEADING, Domain::Edge, e.index(), Frame::WORLD.h);
    let h = (mesh.position(b) - mesh.position(a))
        .try_normalize()
        .unwrap_or(stored_h);
    let l = vector(mesh, LEFT, Domain::Edge, e.index(), Frame::WORLD.l);
    Frame::from_heading_left(h, l)
}

/// A face's frame: H along its longest edge (the first of equals, in
/// winding order), U its normal. The longest edge makes a wall's frame
/// horizontal whichever vertex its boundary starts at.
pub fn face_frame(mesh: &Mesh, f: FaceId) -> Frame {
    let ring: Vec<DVec3> = mesh.face_verts(f).map(|v| mesh.position(v)).collect();
    let mut h = DVec3::ZERO;
    for (i, &p) in ring.iter().enumerate() {
        let d = ring[(i + 1) % ring.len()] - p;
        // Ties within rounding keep the earlier edge.
        if d.length_squared() > h.length_squared() * (1.0 + 1e-9) {
            h = d;
        }
    }
    Frame::from_heading_up(h, mesh.face_normal(f))
}

/// Mean radius of the nodes of a face or an edge.
pub fn mean_radius(mesh: &Mesh, verts: impl Iterator<Item = VertId>) -> f64 {
    let (sum, n) = verts.fold((0.0, 0usize), |(s, n), v| (s + radius(mesh, v), n + 1));
    if n == 0 {
        DEFAULT_RADIUS
    } else {
        sum / n as f64
    }
}

/// Edges entering node `v` (whose post-node is `v`), ascending.
pub fn incoming_edges(mesh: &Mesh, v: VertId) -> Vec<EdgeId> {
    let mut edges: Vec<EdgeId> = mesh
        .vert_edges(v)
        .filter(|&e| mesh.edge_verts(e)[1] == v)
        .collect();
    edges.sort_unstable();
    edges
}

#[cfg(test)]
mod tests {
    use super::*;

    fn orthonormal(f: &Frame) -> bool {
        let unit = |v: DVec3| (v.length() - 1.0).abs() < 1e-12;
        unit(f.h)
            && unit(f.l)
            && unit(f.u)
            && f.h.dot(f.l).abs() < 1e-12
            && (f.l.cross(f.u) - f.h).length() < 1e-12
    }

    #[test]
    fn world_frame_satisfies_h_equals_l_cross_u() {
        assert!(orthonormal(&Frame::WORLD));
        assert_eq!(
            Frame::WORLD.to_world(DVec3::new(1.0, 2.0, 3.0)),
            DVec3::new(1.0, 2.0, 3.0)
        );
    }

    #[test]
    fn frames_from_degenerate_input_stay_orthonormal() {
        for (h, up) in [
            (DVec3::Z, DVec3::Z),
            (DVec3::ZERO, DVec3::Y),
            (DVec3::new(1.0, 1.0, 0.0), DVec3::new(0.0, 0.0, 2.0)),
        ] {
            assert!(orthonormal(&Frame::from_heading_up(h, up)));
            assert!(orthonormal(&Frame::from_heading_left(h, up)));
        }
    }

    #[test]
    fn rotations_follow_the_turtle() {
        let f = Frame::WORLD;
        // Turning 90° about U swings H to L.
        let t = f.rotated(std::f64::consts::FRAC_PI_2, 0.0, 0.0);
        assert!((t.h - DVec3::Y).length() < 1e-12, "{t:?}");
        // Pitching 90° about L swings H down to −U (right-handed about L).
        let p = f.rotated(0.0, std::f64::consts::FRAC_PI_2, 0.0);
        assert!((p.h - DVec3::NEG_Z).length() < 1e-12, "{p:?}");
        // Rolling keeps H.
        let r = f.rotated(0.0, 0.0, 1.0);
        assert!((r.h - DVec3::X).length() < 1e-12 && orthonormal(&r));
    }

    #[test]
    fn relative_basis_maps_local_to_world_and_back() {
        let f = Frame::from_heading_up(DVec3::new(0.0, 1.0, 1.0), DVec3::X);
        let v = DVec3::new(0.3, -2.0, 5.0);
        assert!((f.to_local(f.to_world(v)) - v).length() < 1e-12);
    }
}
