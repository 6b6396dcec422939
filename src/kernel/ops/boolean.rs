//! Exact mesh booleans of two closed shells (issue 36): the arrangement
//! and the choice of pieces are `geom::boolean`'s; this module hands it the
//! faces and writes the result with Euler operators. Faces no crossing
//! touched stay as they are (reversed where a difference keeps the
//! cutter's inside); cut faces are replaced by their kept pieces, which
//! copy the cut face's attributes (part, material: a cut through the
//! cutter keeps the cutter's material); a crossing vertex copies the
//! attributes of its edge's first vertex. Faces, edges and vertices left
//! with nothing are removed.

use super::{canonical, OpError, Selection};
use crate::geom::boolean::{self as arrangement, Input, Operand, Operation, PointSource};
use crate::geom::indexed::IndexedMesh;
use crate::kernel::intersect::{indexed_self_intersection_search, PairLimits};
use crate::kernel::{FaceId, Mesh, VertId};

pub use crate::geom::boolean::Operation as BooleanOperation;

/// `operation` of the shells of faces `a` and `b` (disjoint lists; each
/// closed and consistently oriented).
///
/// Result: every face of the result, and the vertices and edges made.
pub fn boolean(
    mesh: &mut Mesh,
    a: &[FaceId],
    b: &[FaceId],
    operation: Operation,
) -> Result<Selection, OpError> {
    let (a, b) = (canonical(a), canonical(b));
    for &f in a.iter().chain(&b) {
        mesh.check_face(f)?;
    }
    // Local point indices, in first-use order over the faces in id order
    // (by vertex slot: no hashing).
    let mut index: Vec<u32> = vec![u32::MAX; mesh.vert_capacity()];
    let mut verts: Vec<VertId> = Vec::new();
    let mut input = Input::default();
    let mut faces: Vec<FaceId> = Vec::with_capacity(a.len() + b.len());
    for (list, operand) in [(&a, Operand::A), (&b, Operand::B)] {
        for &f in list.iter() {
            let ring: Vec<u32> = mesh
                .face_verts(f)
                .map(|v| {
                    let slot = &mut index[v.index()];
                    if *slot == u32::MAX {
                        *slot = verts.len() as u32;
                        verts.push(v);
                        input.points.push(mesh.position(v));
                    }
                    *slot
                })
                .collect();
            input.polygons.push((ring, operand));
            faces.push(f);
        }
    }
    let error = |e: arrangement::BooleanError| OpError::Degenerate(format!("boolean: {e}"));
    // Closed first (cheap, and the more basic fault), then not crossing
    // itself (the exact search), then the work.
    let prepared = arrangement::prepare(&input).map_err(error)?;
    // The search and the boolean side by side (the search's verdict wins;
    // neither depends on the other or on the threads).
    let (checked, out) = rayon::join(
        || check_not_self_crossing(&input, &faces),
        || prepared.boolean(&input, operation),
    );
    checked?;
    let out = out.map_err(error)?;

    let mut made = Selection::new();
    // Result points: input vertices stay; crossings are new vertices.
    let mut vert_of: Vec<Option<VertId>> = vec![None; out.points.len()];
    for (i, v) in verts.iter().enumerate() {
        vert_of[i] = Some(*v);
    }
    let mut used = vec![false; out.points.len()];
    for p in &out.polygons {
        for &i in &p.ring {
            used[i as usize] = true;
        }
    }
    for (i, source) in out.sources.iter().enumerate() {
        if let (PointSource::Crossing(from, _) | PointSource::Copy(from), true) = (source, used[i])
        {
            let v = mesh.make_vert(out.points[i]);
            mesh.copy_vert_attrs(verts[*from as usize], v);
            vert_of[i] = Some(v);
            made.verts.push(v);
        }
    }
    // Whole faces kept: stay (reversed where asked); pieces: new faces.
    let mut keep = vec![false; faces.len()];
    for p in &out.polygons {
        let source = faces[p.source as usize];
        if p.whole {
            keep[p.source as usize] = true;
            if p.reversed {
                mesh.reverse_face(source)?;
            }
            made.faces.push(source);
        } else {
            let ring: Vec<VertId> = p
                .ring
                .iter()
                .map(|&i| vert_of[i as usize].expect("a result point"))
                .collect();
            let f = mesh.make_face(&ring)?;
            mesh.copy_face_attrs(source, f);
            made.faces.push(f);
        }
    }
    // What is left: the faces not kept whole, then edges and vertices of
    // theirs that no face uses any more.
    let mut edges = Vec::new();
    for (k, &f) in faces.iter().enumerate() {
        if !keep[k] {
            edges.extend(mesh.face_edges(f));
            mesh.kill_face(f)?;
        }
    }
    let edges = canonical(&edges);
    let mut loose = Vec::new();
    for e in edges {
        if mesh.contains_edge(e) && mesh.is_wire_edge(e) {
            loose.extend(mesh.edge_verts(e));
            mesh.kill_edge(e)?;
        }
    }
    for v in canonical(&loose) {
        if mesh.contains_vert(v) && mesh.vert_edges(v).next().is_none() {
            mesh.kill_vert(v)?;
        }
    }
    for &f in &made.faces {
        made.edges.extend(mesh.face_edges(f));
    }
    made.normalize();
    Ok(made)
}

/// An operand that crosses itself has no inside to speak of: refused,
/// naming the first pair of faces. Each operand is searched on its own
/// (the exact search of `graftal info`, over its polygons as gathered):
/// pairs of one face from each operand are the boolean's work, and faces
/// outside both are not its business.
fn check_not_self_crossing(input: &Input, faces: &[FaceId]) -> Result<(), OpError> {
    for (operand, name) in [
        (Operand::A, "the selection"),
        (Operand::B, "the `with` part"),
    ] {
        let mut soup = IndexedMesh::new();
        soup.positions = input.points.iter().map(|p| p.to_array()).collect();
        let mut polygon_face: Vec<FaceId> = Vec::new();
        for ((ring, o), &face) in input.polygons.iter().zip(faces) {
            if *o == operand {
                soup.push_polygon(ring);
                polygon_face.push(face);
            }
        }
        let found = indexed_self_intersection_search(&soup, |_| PairLimits::UNLIMITED);
        if let Some(&(f, g)) = found.pairs.first() {
            return Err(OpError::Degenerate(format!(
                "boolean: {name} crosses itself: {} pairs of its faces intersect (the first: \
                 faces {} and {}); fuse it first (`sdf_boolean`, or `merge` where the crossing \
                 is coincident copies)",
                found.count,
                polygon_face[f.index()].index(),
                polygon_face[g.index()].index()
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;

    fn cube(mesh: &mut Mesh, lo: DVec3, size: f64, turn: f64) -> Vec<FaceId> {
        let (s, c) = (libm::sin(turn), libm::cos(turn));
        let centre = lo + DVec3::splat(size / 2.0);
        let corner = |i: usize| {
            let p =
                lo + DVec3::new(
                    if i & 1 == 0 { 0.0 } else { size },
                    if i & 2 == 0 { 0.0 } else { size },
                    if i & 4 == 0 { 0.0 } else { size },
                ) - centre;
            // Turned about z, then about x.
            let p = DVec3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z);
            DVec3::new(p.x, c * p.y - s * p.z, s * p.y + c * p.z) + centre
        };
        let v: Vec<VertId> = (0..8).map(|i| mesh.make_vert(corner(i))).collect();
        [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ]
        .iter()
        .map(|q| mesh.make_face(&q.map(|i| v[i])).unwrap())
        .collect()
    }

    #[test]
    fn a_turned_cube_cut_from_a_cube_leaves_a_valid_closed_mesh() {
        let mut mesh = Mesh::new();
        let a = cube(&mut mesh, DVec3::ZERO, 1.0, 0.0);
        let b = cube(&mut mesh, DVec3::splat(0.45), 1.0, 0.35);
        let made = boolean(&mut mesh, &a, &b, Operation::Difference).unwrap();
        mesh.validate().unwrap();
        assert!(!made.faces.is_empty());
        assert_eq!(made.faces.len(), mesh.face_count());
        let report = mesh.report();
        assert!(report.watertight && report.manifold && report.consistently_oriented);
        let volume = report.volume.unwrap();
        assert!(volume > 0.3 && volume < 1.0, "{volume}");
    }

    #[test]
    fn an_operand_crossing_itself_is_refused() {
        let mut mesh = Mesh::new();
        let mut a = cube(&mut mesh, DVec3::ZERO, 1.0, 0.0);
        a.extend(cube(&mut mesh, DVec3::splat(0.5), 1.0, 0.3));
        let b = cube(&mut mesh, DVec3::splat(3.0), 1.0, 0.2);
        let err = boolean(&mut mesh, &a, &b, Operation::Union).unwrap_err();
        assert!(
            err.to_string().contains("the selection crosses itself"),
            "{err}"
        );
    }

    #[test]
    fn an_open_operand_is_refused_naming_its_boundary() {
        let mut mesh = Mesh::new();
        let mut a = cube(&mut mesh, DVec3::ZERO, 1.0, 0.0);
        let b = cube(&mut mesh, DVec3::splat(0.5), 1.0, 0.3);
        a.pop();
        let err = boolean(&mut mesh, &a, &b, Operation::Union).unwrap_err();
        assert!(err.to_string().contains("4 boundary edges"), "{err}");
    }
}
