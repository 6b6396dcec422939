//! Transform operators: move vertices, never touch adjacency (seed 000
//! §3.3, the *Transform* category: "transform existing geometry (vertex
//! coordinates) without changing adjacency or topology").
//!
//! Every operator takes a slice of vertices, moves each one once (duplicates
//! are ignored, order does not matter: inputs go through
//! [`super::canonical`]) and then refreshes the stored normals of the faces
//! around them, so [`Mesh::face_normal`] stays current.
//!
//! All-or-nothing: dead ids, non-finite parameters, or a result that would
//! not be finite (overflow) are reported before any vertex moves, so a failed
//! call leaves the mesh as it was.
//!
//! Rotation uses glam's `DQuat`, built with the `libm` feature, so the same
//! angle gives the same bits on every platform.
//!
//! ```
//! use glam::DVec3;
//! use graftal::kernel::{Mesh, ops::transform};
//! let mut mesh = Mesh::new();
//! let v = mesh.make_vert(DVec3::X);
//! transform::translate(&mut mesh, &[v], DVec3::new(0.0, 2.0, 0.0)).unwrap();
//! assert_eq!(mesh.position(v), DVec3::new(1.0, 2.0, 0.0));
//! ```

use glam::{DAffine3, DQuat, DVec3};

use super::{canonical, OpError};
use crate::kernel::ids::VertId;
use crate::kernel::mesh::Mesh;

/// Moves every vertex by `offset`.
pub fn translate(mesh: &mut Mesh, verts: &[VertId], offset: DVec3) -> Result<(), OpError> {
    if !offset.is_finite() {
        return Err(OpError::parameter("offset", "must be finite"));
    }
    apply(mesh, verts, |p| p + offset)
}

/// Rotates every vertex by `angle_radians` about the line through `center`
/// along `axis` (normalized here; right-handed: a positive angle turns
/// counter-clockwise seen from the tip of the axis). A zero axis is refused.
pub fn rotate(
    mesh: &mut Mesh,
    verts: &[VertId],
    center: DVec3,
    axis: DVec3,
    angle_radians: f64,
) -> Result<(), OpError> {
    if !center.is_finite() {
        return Err(OpError::parameter("center", "must be finite"));
    }
    if !axis.is_finite() {
        return Err(OpError::parameter("axis", "must be finite"));
    }
    let Some(axis) = axis.try_normalize() else {
        return Err(OpError::parameter("axis", "must not be zero"));
    };
    if !angle_radians.is_finite() {
        return Err(OpError::parameter("angle_radians", "must be finite"));
    }
    let rotation = DQuat::from_axis_angle(axis, angle_radians);
    apply(mesh, verts, |p| center + rotation * (p - center))
}

/// Scales every vertex about `center` by per-axis `factors`. Zero factors
/// flatten; negative factors mirror (which turns faces inside out
/// geometrically: flip them with `reverse_face` if that is not wanted).
pub fn scale(
    mesh: &mut Mesh,
    verts: &[VertId],
    center: DVec3,
    factors: DVec3,
) -> Result<(), OpError> {
    if !center.is_finite() {
        return Err(OpError::parameter("center", "must be finite"));
    }
    if !factors.is_finite() {
        return Err(OpError::parameter("factors", "must be finite"));
    }
    apply(mesh, verts, |p| center + (p - center) * factors)
}

/// Applies an affine map (`affine.transform_point3`) to every vertex.
pub fn transform(mesh: &mut Mesh, verts: &[VertId], affine: DAffine3) -> Result<(), OpError> {
    if !affine.is_finite() {
        return Err(OpError::parameter("affine", "must be finite"));
    }
    apply(mesh, verts, |p| affine.transform_point3(p))
}

/// Computes every new position first (so a dead id or an overflow changes
/// nothing), writes them, then refreshes the normals of the faces around.
fn apply(mesh: &mut Mesh, verts: &[VertId], map: impl Fn(DVec3) -> DVec3) -> Result<(), OpError> {
    let verts = canonical(verts);
    let mut moved = Vec::with_capacity(verts.len());
    for &v in &verts {
        mesh.check_vert(v)?;
        let p = map(mesh.position(v));
        if !p.is_finite() {
            return Err(OpError::parameter(
                "transform",
                format!("moving {v} would give a non-finite position"),
            ));
        }
        moved.push((v, p));
    }
    mesh.move_verts(&moved);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::ops::create::tests::signed_volume;
    use crate::kernel::ops::create::{create_cube, create_grid};
    use crate::kernel::KernelError;
    use std::f64::consts::FRAC_PI_2;

    fn close(a: DVec3, b: DVec3) -> bool {
        (a - b).length() < 1e-12
    }

    #[test]
    fn translate_moves_each_vertex_once() {
        let mut m = Mesh::new();
        let g = create_grid(&mut m, 2, 2, 2.0, 2.0).unwrap();
        let v = g.verts[0];
        let before = m.position(v);
        translate(&mut m, &[v, v, g.verts[1]], DVec3::new(0.0, 0.0, 1.0)).unwrap();
        m.validate().unwrap();
        assert_eq!(m.position(v), before + DVec3::Z, "listed twice, moved once");
        assert_eq!(m.position(g.verts[2]).z, 0.0, "unlisted vertices stay");
        // The corner face is no longer flat along +Z; its stored normal follows.
        let f = g.faces[0];
        assert!(close(m.face_normal(f), m.compute_face_normal(f)));
        assert!(m.face_normal(f).z < 1.0 - 1e-6);
    }

    #[test]
    fn rotate_turns_about_the_axis_through_the_center() {
        let mut m = Mesh::new();
        let a = m.make_vert(DVec3::new(2.0, 1.0, 5.0));
        rotate(
            &mut m,
            &[a],
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 0.0, 3.0),
            FRAC_PI_2,
        )
        .unwrap();
        // (1,0) about (1,1) by +90° around +Z lands at (1,2): z unchanged.
        assert!(
            close(m.position(a), DVec3::new(1.0, 2.0, 5.0)),
            "{}",
            m.position(a)
        );
        m.validate().unwrap();
    }

    #[test]
    fn rotating_a_cube_keeps_it_closed_and_outward() {
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 2.0).unwrap();
        rotate(
            &mut m,
            &c.verts,
            DVec3::ZERO,
            DVec3::new(1.0, 1.0, 1.0),
            0.7,
        )
        .unwrap();
        m.validate().unwrap();
        assert!((signed_volume(&m) - 8.0).abs() < 1e-9);
        for &f in &c.faces {
            assert!(close(m.face_normal(f), m.compute_face_normal(f)));
            assert!(m.face_normal(f).dot(m.face_center(f)) > 0.0);
        }
    }

    #[test]
    fn scale_about_a_center() {
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 2.0).unwrap();
        scale(
            &mut m,
            &c.verts,
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(2.0, 1.0, 0.5),
        )
        .unwrap();
        m.validate().unwrap();
        // x: 1 + (±1 - 1)·2 ∈ {-3, 1}; z: 1 + (±1 - 1)·0.5 ∈ {0, 1}.
        let first = m.position(c.verts[0]);
        assert!(close(first, DVec3::new(-3.0, -1.0, 0.0)), "{first}");
        assert!((signed_volume(&m) - 8.0).abs() < 1e-12);
    }

    #[test]
    fn affine_transform_matches_its_matrix() {
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 1.0).unwrap();
        let affine = DAffine3::from_scale_rotation_translation(
            DVec3::splat(2.0),
            DQuat::from_rotation_z(0.3),
            DVec3::new(5.0, -1.0, 2.0),
        );
        let before: Vec<DVec3> = c.verts.iter().map(|&v| m.position(v)).collect();
        transform(&mut m, &c.verts, affine).unwrap();
        m.validate().unwrap();
        for (&v, &p) in c.verts.iter().zip(&before) {
            assert!(close(m.position(v), affine.transform_point3(p)));
        }
        assert!((signed_volume(&m) - 8.0).abs() < 1e-9);
    }

    #[test]
    fn bad_parameters_and_dead_ids_change_nothing() {
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 1.0).unwrap();
        let snapshot: Vec<DVec3> = c.verts.iter().map(|&v| m.position(v)).collect();
        let nan = DVec3::new(f64::NAN, 0.0, 0.0);
        assert!(matches!(
            translate(&mut m, &c.verts, nan),
            Err(OpError::Parameter { .. })
        ));
        assert!(matches!(
            rotate(&mut m, &c.verts, DVec3::ZERO, DVec3::ZERO, 1.0),
            Err(OpError::Parameter { name: "axis", .. })
        ));
        assert!(rotate(&mut m, &c.verts, DVec3::ZERO, DVec3::Z, f64::INFINITY).is_err());
        assert!(scale(&mut m, &c.verts, nan, DVec3::ONE).is_err());
        assert!(transform(&mut m, &c.verts, DAffine3::from_translation(nan)).is_err());
        // Overflow to infinity is refused before anything moves.
        assert!(scale(&mut m, &c.verts, DVec3::splat(-1.0), DVec3::splat(f64::MAX)).is_err());
        let dead = VertId::from_index(99);
        let mut with_dead = c.verts.clone();
        with_dead.push(dead);
        assert!(matches!(
            translate(&mut m, &with_dead, DVec3::X),
            Err(OpError::Kernel(KernelError::Dead { .. }))
        ));
        let after: Vec<DVec3> = c.verts.iter().map(|&v| m.position(v)).collect();
        assert_eq!(snapshot, after);
        m.validate().unwrap();
    }
}
