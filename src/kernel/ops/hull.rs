//! Convex hull of selected vertices as a new closed shell (issue 35): the
//! hull is `geom::hull` (Quickhull on exact predicates, coplanar faces
//! merged unless `triangulate`); this module makes it kernel geometry
//! with Euler operators (`make_vert`, the builder's MakeFace). The input vertices
//! stay where they are (delete them after if they are not wanted); each
//! hull vertex copies the attributes of the input vertex it stands on.

use super::{canonical, OpError, Selection};
use crate::geom::hull::{convex_hull as hull_of, HullError};
use crate::kernel::{Mesh, VertId};

/// Makes the convex hull of `verts` (coincident vertices count once).
///
/// Result: the hull's new vertices, edges and faces.
pub fn convex_hull(
    mesh: &mut Mesh,
    verts: &[VertId],
    triangulate: bool,
) -> Result<Selection, OpError> {
    let verts = canonical(verts);
    for &v in &verts {
        mesh.check_vert(v)?;
    }
    let points: Vec<_> = verts.iter().map(|&v| mesh.position(v)).collect();
    let hull = hull_of(&points, !triangulate).map_err(|e| match e {
        HullError::NonFinite(i) => OpError::Degenerate(format!(
            "convex hull: vertex {} has a non-finite position",
            verts[i].index()
        )),
        other => OpError::Degenerate(format!(
            "convex hull of the {} selected vertices: {other}",
            verts.len()
        )),
    })?;
    let mut made = Selection::new();
    let mut copy = vec![None; points.len()];
    for &i in &hull.vertices {
        let c = mesh.make_vert(points[i]);
        mesh.copy_vert_attrs(verts[i], c);
        copy[i] = Some(c);
        made.verts.push(c);
    }
    let mut ring: Vec<VertId> = Vec::new();
    made.faces.reserve(hull.face_count());
    // A hull face's corners are distinct new vertices, so each face is
    // the builder's MakeFace (the face `make_face` makes) with its normal
    // left for one parallel pass at the end (the same bits), and its new
    // edges listed as they are first used: issue 38, the hull of 10⁴
    // points on a sphere made 20k faces one normal at a time, then sorted
    // their 30k edges out of 60k mentions.
    for face in hull.faces() {
        ring.clear();
        ring.extend(face.iter().map(|&i| copy[i].expect("a hull vertex")));
        let f = mesh.make_face_of_clean_ring(&ring, &mut made.edges);
        made.faces.push(f);
    }
    mesh.refresh_normals_of(&made.faces);
    made.normalize();
    Ok(made)
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::kernel::ops::create::create_uv_sphere;

    #[test]
    fn the_hull_of_a_sphere_is_a_closed_outward_shell() {
        let mut mesh = Mesh::new();
        create_uv_sphere(&mut mesh, 16, 8, 1.0).unwrap();
        let verts: Vec<VertId> = mesh.vert_ids().collect();
        let sphere = mesh.report().volume.unwrap();
        let made = convex_hull(&mut mesh, &verts, false).unwrap();
        mesh.validate().unwrap();
        assert_eq!(
            made.verts.len(),
            verts.len(),
            "every vertex of a UV sphere is extreme"
        );
        // The poles' fans stay triangles; a ring quad merges back into one
        // face only where rounding left its corners exactly coplanar.
        assert!((16 * 8..=16 * 2 + 16 * 6 * 2).contains(&made.faces.len()));
        assert!(made
            .faces
            .iter()
            .all(|&f| (3..=4).contains(&mesh.face_len(f))));
        let volume = mesh.report().volume.unwrap();
        assert!(
            (volume - 2.0 * sphere).abs() < 1e-12,
            "{volume} vs 2 × {sphere}"
        );
    }

    /// The hull's faces are made with their normals left for one pass and
    /// their edges listed as first used: the result names every edge of
    /// every new face once, ascending, and every stored normal is the one
    /// `make_face` would have given, also where the new edges and faces
    /// reuse freed slots.
    #[test]
    fn the_hull_names_its_edges_and_stores_fresh_normals() {
        for free_slots in [false, true] {
            let mut mesh = Mesh::new();
            create_uv_sphere(&mut mesh, 12, 6, 1.0).unwrap();
            if free_slots {
                let edges: Vec<_> = mesh.edge_ids().collect();
                for &e in edges.iter().step_by(5) {
                    mesh.kill_edge(e).unwrap();
                }
            }
            let verts: Vec<VertId> = mesh.vert_ids().collect();
            let made = convex_hull(&mut mesh, &verts, true).unwrap();
            mesh.validate().unwrap();
            let mut named: Vec<_> = made
                .faces
                .iter()
                .flat_map(|&f| mesh.face_edges(f))
                .collect();
            named.sort_unstable();
            named.dedup();
            assert_eq!(made.edges, named, "free slots: {free_slots}");
            for &f in &made.faces {
                assert_eq!(mesh.face_len(f), 3);
                let stored = mesh.face_normal(f);
                assert_eq!(stored.to_array(), mesh.compute_face_normal(f).to_array());
                assert!((stored.length() - 1.0).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn flat_selections_are_refused_with_their_reason() {
        let mut mesh = Mesh::new();
        let verts: Vec<VertId> = (0..5)
            .map(|k| mesh.make_vert(DVec3::new(k as f64, (k * k) as f64, 0.0)))
            .collect();
        let err = convex_hull(&mut mesh, &verts, false).unwrap_err();
        assert!(err.to_string().contains("lie in one plane"), "{err}");
        assert_eq!(mesh.vert_count(), 5);
    }
}
