//! Delete, duplicate and dissolve (seed 000 §3.3, the *Modify* category:
//! operators that "change existing elements and add or delete elements as
//! needed, keeping adjacency valid", e.g. *delete*).
//!
//! - [`delete`] kills selected elements through the kill Euler operators, in
//!   one of three [`DeleteMode`]s.
//! - [`duplicate`] copies a selection, detached from the original, with
//!   attributes, and returns the copies.
//! - [`dissolve_edges`] removes edges between two faces by joining the faces
//!   ([`Mesh::join_faces`]); [`dissolve_edges_report`] also counts the
//!   edges it had to skip.
//!
//! Every input id is checked first: a dead id is reported as the kernel's
//! [`KernelError::Dead`](crate::kernel::KernelError) before anything
//! changes. Elements that die *during* the operation (a face killed with its
//! edge, say) are skipped silently. Inputs are processed in ascending id
//! order, so results do not depend on the order given.

use super::{canonical, OpError, Selection};
use crate::kernel::ids::{EdgeId, FaceId, VertId};
use crate::kernel::mesh::Mesh;

/// What [`delete`] removes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeleteMode {
    /// The selected faces, the selected edges (with every face using them)
    /// and the selected vertices (with every edge and face using them).
    All,
    /// Only `selection.faces`; their edges and vertices stay.
    Faces,
    /// The selected faces, the selected edges (with every face using them),
    /// and the edges of the selected faces that are left with no face.
    /// Vertices stay, possibly isolated.
    FacesAndEdges,
}

/// Deletes the selection according to `mode`. Creates nothing, so the
/// returned selection is empty.
pub fn delete(
    mesh: &mut Mesh,
    selection: &Selection,
    mode: DeleteMode,
) -> Result<Selection, OpError> {
    let (verts, edges, faces) = checked(mesh, selection)?;
    match mode {
        DeleteMode::Faces => {
            for f in faces {
                mesh.kill_face(f)?;
            }
        }
        DeleteMode::FacesAndEdges => {
            // Edges of the faces, gathered before the faces go.
            let mut boundary: Vec<EdgeId> =
                faces.iter().flat_map(|&f| mesh.face_edges(f)).collect();
            boundary.sort_unstable();
            boundary.dedup();
            for f in faces {
                mesh.kill_face(f)?;
            }
            kill_live_edges(mesh, &edges)?;
            for e in boundary {
                if mesh.contains_edge(e) && mesh.is_wire_edge(e) {
                    mesh.kill_edge(e)?;
                }
            }
        }
        DeleteMode::All => {
            // Faces first, then edges, then vertices: each kill takes what
            // depends on it, so later ids may already be gone.
            for f in faces {
                if mesh.contains_face(f) {
                    mesh.kill_face(f)?;
                }
            }
            kill_live_edges(mesh, &edges)?;
            for v in verts {
                if mesh.contains_vert(v) {
                    mesh.kill_vert(v)?;
                }
            }
        }
    }
    Ok(Selection::new())
}

/// Copies the selection: the selected faces with their edges and vertices,
/// the selected edges with their vertices, and the selected vertices. The
/// copy shares nothing with the original (it sits on top of it), carries
/// the original's attributes, and keeps its winding. Copies are made in
/// ascending order of their originals (vertices, then edges, then faces),
/// so the copy of a lower id gets the lower new id when slots are fresh.
/// Returns the copies.
pub fn duplicate(mesh: &mut Mesh, selection: &Selection) -> Result<Selection, OpError> {
    Ok(duplicate_mapped(mesh, selection)?.copies)
}

/// A duplicate with the original → copy vertex map (for mirror).
pub(crate) struct Duplicated {
    pub(crate) copies: Selection,
    /// `(original, copy)` pairs, sorted by original.
    pub(crate) vert_pairs: Vec<(VertId, VertId)>,
}

pub(crate) fn duplicate_mapped(
    mesh: &mut Mesh,
    selection: &Selection,
) -> Result<Duplicated, OpError> {
    let (sel_verts, sel_edges, faces) = checked(mesh, selection)?;
    let mut edges = sel_edges;
    for &f in &faces {
        edges.extend(mesh.face_edges(f));
    }
    edges.sort_unstable();
    edges.dedup();
    let mut verts = sel_verts;
    for &e in &edges {
        verts.extend(mesh.edge_verts(e));
    }
    verts.sort_unstable();
    verts.dedup();

    let mut vert_pairs = Vec::with_capacity(verts.len());
    for &v in &verts {
        let copy = mesh.make_vert(mesh.position(v));
        mesh.copy_vert_attrs(v, copy);
        vert_pairs.push((v, copy));
    }
    let map = |v: VertId| -> VertId {
        let i = vert_pairs
            .binary_search_by_key(&v, |&(original, _)| original)
            .expect("every vertex of a copied edge or face is copied");
        vert_pairs[i].1
    };
    let mut new_edges = Vec::with_capacity(edges.len());
    for &e in &edges {
        let [a, b] = mesh.edge_verts(e);
        let copy = mesh.make_edge(map(a), map(b))?;
        mesh.copy_edge_attrs(e, copy);
        new_edges.push(copy);
    }
    let mut new_faces = Vec::with_capacity(faces.len());
    for &f in &faces {
        let ring: Vec<VertId> = mesh.face_verts(f).map(map).collect();
        // The edges exist already (copied above): make_face finds them.
        let copy = mesh.make_face(&ring)?;
        mesh.copy_face_attrs(f, copy);
        new_faces.push(copy);
    }
    let new_verts = vert_pairs.iter().map(|&(_, copy)| copy).collect();
    Ok(Duplicated {
        copies: Selection::from_parts(new_verts, new_edges, new_faces),
        vert_pairs,
    })
}

/// What [`dissolve_edges_report`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DissolveResult {
    /// The joined faces that survive, sorted.
    pub faces: Vec<FaceId>,
    /// Edges removed by joining their two faces.
    pub dissolved: usize,
    /// Edges left alone: not exactly two distinct faces, or joining would
    /// repeat a vertex (the faces also meet elsewhere).
    pub skipped: usize,
}

/// Dissolves each edge that has exactly two faces by joining them
/// ([`Mesh::join_faces`]), in ascending id order; other edges are skipped.
/// Returns the surviving joined faces. Vertices left with two edges stay
/// (no vertex dissolve).
pub fn dissolve_edges(mesh: &mut Mesh, edges: &[EdgeId]) -> Result<Selection, OpError> {
    let report = dissolve_edges_report(mesh, edges)?;
    Ok(Selection::from_parts(Vec::new(), Vec::new(), report.faces))
}

/// [`dissolve_edges`] with counts of dissolved and skipped edges.
pub fn dissolve_edges_report(mesh: &mut Mesh, edges: &[EdgeId]) -> Result<DissolveResult, OpError> {
    let edges = canonical(edges);
    for &e in &edges {
        mesh.check_edge(e)?;
    }
    let mut result = DissolveResult::default();
    let mut joined = Vec::new();
    for e in edges {
        // join_faces removes only its own edge, but stay defensive.
        if !mesh.contains_edge(e) {
            continue;
        }
        if mesh.edge_face_count(e) != 2 {
            result.skipped += 1;
            continue;
        }
        // join_faces checks everything before changing anything: a refusal
        // (same face twice, repeated vertex) leaves the mesh as it was.
        match mesh.join_faces(e) {
            Ok(f) => {
                joined.push(f);
                result.dissolved += 1;
            }
            Err(_) => result.skipped += 1,
        }
    }
    // A face joined early may have been absorbed by a later join.
    joined.retain(|&f| mesh.contains_face(f));
    joined.sort_unstable();
    joined.dedup();
    result.faces = joined;
    Ok(result)
}

/// The selection's lists, canonical, after checking every id is alive.
#[allow(clippy::type_complexity)]
fn checked(
    mesh: &Mesh,
    selection: &Selection,
) -> Result<(Vec<VertId>, Vec<EdgeId>, Vec<FaceId>), OpError> {
    let verts = canonical(&selection.verts);
    let edges = canonical(&selection.edges);
    let faces = canonical(&selection.faces);
    for &v in &verts {
        mesh.check_vert(v)?;
    }
    for &e in &edges {
        mesh.check_edge(e)?;
    }
    for &f in &faces {
        mesh.check_face(f)?;
    }
    Ok((verts, edges, faces))
}

fn kill_live_edges(mesh: &mut Mesh, edges: &[EdgeId]) -> Result<(), OpError> {
    for &e in edges {
        if mesh.contains_edge(e) {
            mesh.kill_edge(e)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::ops::create::tests::{euler_characteristic, signed_volume};
    use crate::kernel::ops::create::{create_cube, create_grid};
    use crate::kernel::ops::select::select_from_faces;
    use crate::kernel::{AttrValue, Domain, KernelError};

    fn counts(m: &Mesh) -> (usize, usize, usize) {
        (m.vert_count(), m.edge_count(), m.face_count())
    }

    #[test]
    fn delete_faces_keeps_edges_and_verts() {
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 1.0).unwrap();
        let top = Selection::from_parts(vec![], vec![], vec![c.faces[1]]);
        let made = delete(&mut m, &top, DeleteMode::Faces).unwrap();
        m.validate().unwrap();
        assert!(made.is_empty());
        assert_eq!(counts(&m), (8, 12, 5));
        let open = m.edge_ids().filter(|&e| m.edge_face_count(e) == 1).count();
        assert_eq!(open, 4);
    }

    #[test]
    fn delete_faces_and_edges_removes_edges_left_bare() {
        let mut m = Mesh::new();
        let g = create_grid(&mut m, 2, 1, 2.0, 1.0).unwrap();
        // Deleting the left quad: its three outer edges go bare and die; the
        // middle edge still holds the right quad and stays.
        let left = Selection::from_parts(vec![], vec![], vec![g.faces[0]]);
        delete(&mut m, &left, DeleteMode::FacesAndEdges).unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&m), (6, 4, 1));
        assert_eq!(m.vert_ids().filter(|&v| m.vert_degree(v) == 0).count(), 2);

        // A selected edge takes its faces with it.
        let mut m = Mesh::new();
        let g = create_grid(&mut m, 2, 1, 2.0, 1.0).unwrap();
        let middle = g
            .edges
            .iter()
            .copied()
            .find(|&e| m.edge_face_count(e) == 2)
            .unwrap();
        delete(
            &mut m,
            &Selection::from_parts(vec![], vec![middle], vec![]),
            DeleteMode::FacesAndEdges,
        )
        .unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&m), (6, 6, 0));
    }

    #[test]
    fn delete_all_takes_dependents_of_verts() {
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 1.0).unwrap();
        // One corner vertex: its 3 edges and 3 faces go.
        let corner = Selection::from_parts(vec![c.verts[0]], vec![], vec![]);
        delete(&mut m, &corner, DeleteMode::All).unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&m), (7, 9, 3));

        // A selection whose faces die with its verts: no error for ids
        // killed along the way.
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 1.0).unwrap();
        delete(&mut m, &c, DeleteMode::All).unwrap();
        m.validate().unwrap();
        assert!(m.is_empty() && m.edge_count() == 0 && m.face_count() == 0);
    }

    #[test]
    fn delete_refuses_dead_ids_before_changing_anything() {
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 1.0).unwrap();
        let mut bad = c.clone();
        bad.faces.push(FaceId::from_index(77));
        for mode in [
            DeleteMode::All,
            DeleteMode::Faces,
            DeleteMode::FacesAndEdges,
        ] {
            assert!(matches!(
                delete(&mut m, &bad, mode),
                Err(OpError::Kernel(KernelError::Dead { .. }))
            ));
            assert_eq!(counts(&m), (8, 12, 6));
        }
        m.validate().unwrap();
    }

    #[test]
    fn duplicate_copies_detached_with_attributes() {
        let mut m = Mesh::new();
        m.add_layer("age", Domain::Face, AttrValue::Int(0)).unwrap();
        m.add_layer("radius", Domain::Vert, AttrValue::Scalar(1.0))
            .unwrap();
        let c = create_cube(&mut m, 2.0).unwrap();
        m.set_attr("age", Domain::Face, c.faces[2].index(), AttrValue::Int(7));
        m.set_attr(
            "radius",
            Domain::Vert,
            c.verts[0].index(),
            AttrValue::Scalar(0.5),
        );
        let faces = [c.faces[2], c.faces[0]];
        let copy = duplicate(
            &mut m,
            &Selection::from_parts(vec![c.verts[6]], vec![], faces.to_vec()),
        )
        .unwrap();
        m.validate().unwrap();
        // Two adjacent quads: 6 verts, 7 edges, 2 faces; plus a lone vertex.
        assert_eq!(
            (copy.verts.len(), copy.edges.len(), copy.faces.len()),
            (7, 7, 2)
        );
        assert_eq!(counts(&m), (15, 19, 8));
        assert!(copy.verts.iter().all(|v| !c.verts.contains(v)));
        // Same positions and winding, same attributes.
        assert_eq!(
            m.attr("age", Domain::Face, copy.faces[1].index()),
            Some(AttrValue::Int(7))
        );
        assert_eq!(
            m.attr("age", Domain::Face, copy.faces[0].index()),
            Some(AttrValue::Int(0))
        );
        let first = copy.verts[0];
        assert_eq!(m.position(first), m.position(c.verts[0]));
        assert_eq!(
            m.attr("radius", Domain::Vert, first.index()),
            Some(AttrValue::Scalar(0.5))
        );
        for (&orig, &dup) in faces.iter().rev().zip(&copy.faces) {
            assert_eq!(m.face_normal(orig), m.face_normal(dup));
        }
        // The copy is a separate piece: no copied edge touches an original vertex.
        for &e in &copy.edges {
            assert!(m.edge_verts(e).iter().all(|v| copy.verts.contains(v)));
        }
    }

    #[test]
    fn duplicate_of_a_closed_mesh_is_closed() {
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 2.0).unwrap();
        let all = select_from_faces(&m, &c.faces);
        let copy = duplicate(&mut m, &all).unwrap();
        m.validate().unwrap();
        assert_eq!(
            (copy.verts.len(), copy.edges.len(), copy.faces.len()),
            (8, 12, 6)
        );
        assert_eq!(euler_characteristic(&m), 4);
        assert!((signed_volume(&m) - 16.0).abs() < 1e-12);
    }

    #[test]
    fn dissolve_joins_faces_and_skips_the_rest() {
        let mut m = Mesh::new();
        let g = create_grid(&mut m, 3, 1, 3.0, 1.0).unwrap();
        let inner: Vec<EdgeId> = g
            .edges
            .iter()
            .copied()
            .filter(|&e| m.edge_face_count(e) == 2)
            .collect();
        assert_eq!(inner.len(), 2);
        let outer = g
            .edges
            .iter()
            .copied()
            .find(|&e| m.edge_face_count(e) == 1)
            .unwrap();
        let mut input = vec![inner[1], outer, inner[0], inner[1]];
        let report = dissolve_edges_report(&mut m, &input).unwrap();
        m.validate().unwrap();
        assert_eq!(report.dissolved, 2);
        assert_eq!(report.skipped, 1);
        assert_eq!(report.faces, vec![g.faces[0]]);
        assert_eq!(counts(&m), (8, 8, 1));
        assert_eq!(m.face_len(g.faces[0]), 8);
        assert!((m.face_area(g.faces[0]) - 3.0).abs() < 1e-12);

        // Dead ids are the kernel's error.
        input.push(EdgeId::from_index(500));
        assert!(matches!(
            dissolve_edges(&mut m, &input),
            Err(OpError::Kernel(KernelError::Dead { .. }))
        ));
    }

    #[test]
    fn dissolving_every_edge_of_a_cube_stops_where_faces_would_repeat_a_vertex() {
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 1.0).unwrap();
        let report = dissolve_edges_report(&mut m, &c.edges).unwrap();
        m.validate().unwrap();
        assert_eq!(report.dissolved + report.skipped, 12);
        assert!(report.dissolved >= 1);
        assert_eq!(m.edge_count(), 12 - report.dissolved);
        assert!(report.faces.iter().all(|&f| m.contains_face(f)));
        assert_eq!(m.face_count(), 6 - report.dissolved);
        assert_eq!(euler_characteristic(&m), 2);
    }
}
