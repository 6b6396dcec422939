//! Solidify: a sheet of faces becomes a shell with thickness, as Blender's
//! solidify modifier does in its "simple" mode (issue 35).
//!
//! Every vertex of the region moves along its normal (the corner-angle
//! weighted mean of its region faces' normals, Blender's vertex normal):
//! the original sheet to `offset_original`, a copy to `offset_original +
//! thickness` (Blender's `ofs_orig`, `ofs_new`: with `offset` in [−1, 1]
//! the shell lies behind the sheet at −1, centred on it at 0, in front at
//! 1). With `even`, each vertex's offset is scaled by the corner-angle
//! weighted mean of `1 / cos` of the angle between its normal and each
//! face's, so faces keep their thickness where the sheet bends (Blender's
//! "Even Thickness"). The shell further along the normals keeps the sheet's
//! winding, the other is reversed, and each boundary edge of the region
//! (one region face) gets a quad joining the two (the rim): a sheet
//! becomes a closed, consistently wound solid.
//!
//! Built from Euler operators only: `make_vert`, `make_face` (its edges
//! found or made), `reverse_face`. The copies and the rim take their
//! face's attributes (part, material); copied vertices their vertex's.

use glam::DVec3;
use rustc_hash::FxHashMap;

use super::{canonical, into_canonical, OpError, Selection};
use crate::kernel::{EdgeId, FaceId, Mesh, VertId};

/// What [`solidify`] is asked to do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solidify {
    /// Distance between the two shells (negative: the copy goes against
    /// the normals).
    pub thickness: f64,
    /// Where the shell lies, in [−1, 1]: −1 behind the sheet (Blender's
    /// default), 0 centred, 1 in front.
    pub offset: f64,
    /// Blender's "Even Thickness".
    pub even: bool,
    /// Close the boundary with rim faces.
    pub rim: bool,
}

/// Solidifies the region `faces`.
///
/// Result: the faces made (the copies and the rim), the copied vertices
/// and the new edges (those with a copied end).
pub fn solidify(
    mesh: &mut Mesh,
    faces: &[FaceId],
    options: Solidify,
) -> Result<Selection, OpError> {
    let region = canonical(faces);
    for &f in &region {
        mesh.check_face(f)?;
    }
    if !options.thickness.is_finite() {
        return Err(OpError::parameter("thickness", "must be a finite number"));
    }
    if !(options.offset.is_finite() && (-1.0..=1.0).contains(&options.offset)) {
        return Err(OpError::parameter(
            "offset",
            format!("must lie in [-1, 1], got {}", options.offset),
        ));
    }
    let corners: usize = region.iter().map(|&f| mesh.face_len(f)).sum();
    let room = |capacity: usize| u32::MAX as usize - capacity;
    if corners > room(mesh.vert_capacity()) || 2 * corners > room(mesh.face_capacity()) {
        return Err(OpError::parameter(
            "faces",
            "the shell would exceed the mesh's id space",
        ));
    }

    let verts = into_canonical(region.iter().flat_map(|&f| mesh.face_verts(f)).collect());
    let (normal, factor) = vertex_normals(mesh, &region, options.even);
    // Blender's `ofs_orig` and `ofs_new` (MOD_solidify_extrude.c).
    let t = options.thickness;
    let at_original = -((1.0 - options.offset) * 0.5 * t);
    let at_copy = t + at_original;

    // Boundary edges of the region, each with the region face using it
    // and that face's direction along it (a -> b).
    let mut uses: FxHashMap<EdgeId, (u32, VertId, VertId)> = FxHashMap::default();
    for &f in &region {
        for l in mesh.face_loops(f) {
            let e = mesh.loop_edge(l);
            let a = mesh.loop_vert(l);
            let b = mesh.edge_other_vert(e, a);
            let entry = uses.entry(e).or_insert((0, a, b));
            entry.0 += 1;
        }
    }
    let mut boundary: Vec<(EdgeId, VertId, VertId)> = uses
        .into_iter()
        .filter(|&(_, (count, _, _))| count == 1)
        .map(|(e, (_, a, b))| (e, a, b))
        .collect();
    boundary.sort_unstable_by_key(|&(e, _, _)| e);

    // Refused before anything is made: faces wound against each other
    // (their normals cancel at a vertex, which would not move) and
    // positions that overflow.
    for &v in &verts {
        if normal[&v] == DVec3::ZERO {
            return Err(OpError::Degenerate(format!(
                "solidify: the selected faces at vertex {} have no common side (they are                  wound against each other, or degenerate); make their winding consistent                  with `recompute_normals` first",
                v.index()
            )));
        }
        let p = mesh.position(v);
        let along = normal[&v] * factor[&v];
        if !(p + along * at_copy).is_finite() || !(p + along * at_original).is_finite() {
            return Err(OpError::Degenerate(
                "solidify: a new position overflows (coordinates or thickness near the limit of f64)"
                    .into(),
            ));
        }
    }
    let mut made = Selection::new();
    let mut copy_of: FxHashMap<VertId, VertId> = FxHashMap::default();
    for &v in &verts {
        let c = mesh.make_vert(mesh.position(v));
        mesh.copy_vert_attrs(v, c);
        copy_of.insert(v, c);
        made.verts.push(c);
    }
    for &f in &region {
        let ring: Vec<VertId> = mesh.face_verts(f).map(|v| copy_of[&v]).collect();
        let g = mesh.make_face(&ring)?;
        mesh.copy_face_attrs(f, g);
        made.faces.push(g);
    }
    // The inner shell is the one behind the other along the normals.
    let copy_is_outer = at_copy >= at_original;
    let inner: Vec<FaceId> = if copy_is_outer {
        region.clone()
    } else {
        made.faces.clone()
    };
    for &f in &inner {
        mesh.reverse_face(f)?;
    }
    if options.rim {
        // The original region face ran a -> b; the rim runs against both
        // shells' use of the edge.
        for &(e, a, b) in &boundary {
            let (ca, cb) = (copy_of[&a], copy_of[&b]);
            let ring = if copy_is_outer {
                [a, b, cb, ca]
            } else {
                [b, a, ca, cb]
            };
            let rim = mesh.make_face(&ring)?;
            let source = mesh.edge_faces(e).find(|f| region.binary_search(f).is_ok());
            if let Some(f) = source {
                mesh.copy_face_attrs(f, rim);
            }
            made.faces.push(rim);
        }
    }

    for &v in &verts {
        let along = normal[&v] * factor[&v];
        let p = mesh.position(v);
        mesh.place(copy_of[&v], p + along * at_copy);
        mesh.place(v, p + along * at_original);
    }
    let mut touched: Vec<FaceId> = verts
        .iter()
        .flat_map(|&v| [v, copy_of[&v]])
        .flat_map(|v| mesh.vert_faces(v).collect::<Vec<_>>())
        .collect();
    touched = into_canonical(touched);
    for f in touched {
        mesh.refresh_normal(f);
    }
    // The new edges are those with a copied end.
    let copies: rustc_hash::FxHashSet<VertId> = made.verts.iter().copied().collect();
    made.edges = made
        .faces
        .iter()
        .flat_map(|&f| mesh.face_edges(f))
        .filter(|&e| mesh.edge_verts(e).iter().any(|v| copies.contains(v)))
        .collect();
    made.normalize();
    Ok(made)
}

/// Each region vertex's unit normal (corner-angle weighted) and, with
/// `even`, the factor that keeps faces at their thickness (else 1).
fn vertex_normals(
    mesh: &Mesh,
    region: &[FaceId],
    even: bool,
) -> (FxHashMap<VertId, DVec3>, FxHashMap<VertId, f64>) {
    let mut corners: Vec<(VertId, FaceId, f64)> = Vec::new();
    let mut sum: FxHashMap<VertId, DVec3> = FxHashMap::default();
    for &f in region {
        let ring: Vec<VertId> = mesh.face_verts(f).collect();
        let n = mesh.face_normal(f);
        for (i, &v) in ring.iter().enumerate() {
            let p = mesh.position(v);
            let prev = mesh.position(ring[(i + ring.len() - 1) % ring.len()]);
            let next = mesh.position(ring[(i + 1) % ring.len()]);
            let cos = (prev - p)
                .normalize_or_zero()
                .dot((next - p).normalize_or_zero());
            let angle = libm::acos(cos.clamp(-1.0, 1.0));
            *sum.entry(v).or_insert(DVec3::ZERO) += n * angle;
            corners.push((v, f, angle));
        }
    }
    let normal: FxHashMap<VertId, DVec3> = sum
        .into_iter()
        .map(|(v, s)| (v, s.normalize_or_zero()))
        .collect();
    let mut weighted: FxHashMap<VertId, (f64, f64)> = FxHashMap::default();
    for &(v, f, interior) in &corners {
        // Blender weighs the even factor by the corner's turning angle
        // (π − the interior one, at least f32's epsilon: its inlined
        // `face_angles_calc` measures prev − v against v − next), not by
        // the interior angle its vertex normals use.
        let angle = (std::f64::consts::PI - interior).max(f64::from(f32::EPSILON));
        let entry = weighted.entry(v).or_insert((0.0, 0.0));
        if even {
            // Blender's `shell_v3v3_normalized_to_dist`: 1 / |cos|, or 1
            // when the faces are nearly perpendicular to the normal.
            let cos = normal[&v].dot(mesh.face_normal(f)).abs();
            entry.0 += angle * if cos < 1.0e-6 { 1.0 } else { 1.0 / cos };
        } else {
            entry.0 += angle;
        }
        entry.1 += angle;
    }
    let factor = weighted
        .into_iter()
        .map(|(v, (w, total))| (v, if total > 0.0 { w / total } else { 1.0 }))
        .collect();
    (normal, factor)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::ops::create::{create_cylinder, create_grid};
    use crate::kernel::{AttrValue, Domain};

    fn options(thickness: f64, offset: f64) -> Solidify {
        Solidify {
            thickness,
            offset,
            even: false,
            rim: true,
        }
    }

    fn grid() -> (Mesh, Vec<FaceId>) {
        let mut mesh = Mesh::new();
        create_grid(&mut mesh, 4, 4, 2.0, 2.0).unwrap();
        let faces = mesh.face_ids().collect();
        (mesh, faces)
    }

    #[test]
    fn a_grid_becomes_a_closed_slab() {
        for (thickness, offset, z) in [
            (0.1, -1.0, (-0.1, 0.0)),
            (0.1, 0.0, (-0.05, 0.05)),
            (0.1, 1.0, (0.0, 0.1)),
            (-0.1, -1.0, (0.0, 0.1)),
        ] {
            let (mut mesh, faces) = grid();
            let made = solidify(&mut mesh, &faces, options(thickness, offset)).unwrap();
            mesh.validate().unwrap();
            assert_eq!(
                (mesh.vert_count(), mesh.edge_count(), mesh.face_count()),
                (50, 96, 48)
            );
            assert_eq!((made.verts.len(), made.faces.len()), (25, 32));
            let report = mesh.report();
            assert!(report.watertight && report.manifold && report.consistently_oriented);
            let volume = report.volume.unwrap();
            assert!(
                (volume - 0.4).abs() < 1e-12,
                "{thickness} {offset}: {volume}"
            );
            let (lo, hi) = report.bounds.unwrap();
            assert!((lo.z - z.0).abs() < 1e-15 && (hi.z - z.1).abs() < 1e-15);
        }
    }

    #[test]
    fn even_thickness_keeps_a_tube_wall_thick() {
        // An open 8-sided tube: at each vertex two faces meet at 45°, so a
        // plain offset makes the walls thinner by cos 22.5°; even does not.
        for even in [false, true] {
            let mut mesh = Mesh::new();
            create_cylinder(&mut mesh, 8, 1.0, 1.0, 2.0, false).unwrap();
            let faces: Vec<FaceId> = mesh.face_ids().collect();
            let done = solidify(
                &mut mesh,
                &faces,
                Solidify {
                    even,
                    ..options(0.1, 1.0)
                },
            )
            .unwrap();
            mesh.validate().unwrap();
            assert!(mesh.report().watertight);
            let copy = done.verts[0];
            let radius = mesh.position(copy).truncate().length();
            // The wall's inner face (at distance cos 22.5° from the axis)
            // moved out by the thickness measured along its normal.
            let apothem = libm::cos(std::f64::consts::PI / 8.0);
            let wall = (radius * libm::cos(std::f64::consts::PI / 8.0)) - apothem;
            let want = if even { 0.1 } else { 0.1 * apothem };
            assert!((wall - want).abs() < 1e-12, "even {even}: {wall} vs {want}");
        }
    }

    #[test]
    fn copies_and_rims_take_their_faces_attributes() {
        let (mut mesh, faces) = grid();
        mesh.add_layer("material", Domain::Face, AttrValue::Int(0))
            .unwrap();
        for &f in &faces {
            let _ = mesh.set_attr("material", Domain::Face, f.index(), AttrValue::Int(3));
        }
        let made = solidify(&mut mesh, &faces, options(0.1, -1.0)).unwrap();
        for f in made.faces {
            assert_eq!(
                mesh.attr("material", Domain::Face, f.index()),
                Some(AttrValue::Int(3))
            );
        }
    }

    #[test]
    fn cancelling_normals_and_overflowing_positions_are_refused() {
        // Two triangles on one edge, wound against each other: at the
        // shared vertices their normals cancel.
        let mut mesh = Mesh::new();
        let v: Vec<VertId> = [
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(0.5, 1.0, 0.0),
            DVec3::new(0.5, -1.0, 0.0),
        ]
        .iter()
        .map(|&p| mesh.make_vert(p))
        .collect();
        let a = mesh.make_face(&[v[0], v[1], v[2]]).unwrap();
        let b = mesh.make_face(&[v[0], v[1], v[3]]).unwrap();
        let err = solidify(&mut mesh, &[a, b], options(0.1, 0.0)).unwrap_err();
        assert!(err.to_string().contains("recompute_normals"), "{err}");
        assert_eq!(mesh.vert_count(), 4);
        let (mut mesh, faces) = grid();
        for v in mesh.vert_ids().collect::<Vec<_>>() {
            let p = mesh.position(v);
            mesh.place(v, p + DVec3::Z * 1e308);
        }
        let err = solidify(&mut mesh, &faces, options(1e308, 1.0)).unwrap_err();
        assert!(err.to_string().contains("overflows"), "{err}");
        assert_eq!(mesh.vert_count(), 25);
    }

    #[test]
    fn bad_parameters_are_refused_before_anything_is_made() {
        let (mut mesh, faces) = grid();
        for (t, o, name) in [(f64::NAN, 0.0, "thickness"), (0.1, 1.5, "offset")] {
            let err = solidify(&mut mesh, &faces, options(t, o)).unwrap_err();
            assert!(matches!(err, OpError::Parameter { name: n, .. } if n == name));
            assert_eq!(mesh.vert_count(), 25);
        }
        // Without a rim the two sheets stay open.
        let made = solidify(
            &mut mesh,
            &faces,
            Solidify {
                rim: false,
                ..options(0.1, 0.0)
            },
        )
        .unwrap();
        assert_eq!(made.faces.len(), 16);
        assert_eq!(mesh.report().boundary_edges, 32);
    }
}
