//! Delete, duplicate and dissolve (seed 000 §3.3, the *Modify* category:
//! operators that "change existing elements and add or delete elements as
//! needed, keeping adjacency valid", e.g. *delete*).
//!
//! - [`delete`] kills selected elements through the kill Euler operators, in
//!   one of three [`DeleteMode`]s.
//! - [`duplicate`] copies a selection, detached from the original, with
//!   attributes, and returns the copies.
//! - [`dissolve_edges`] turns every region of faces joined through selected
//!   edges into one face (BMesh's semantics); [`dissolve_edges_report`]
//!   also counts the edges it dissolved and skipped.
//!
//! Every input id is checked first: a dead id is reported as the kernel's
//! [`KernelError::Dead`](crate::kernel::KernelError) before anything
//! changes. Elements that die *during* the operation (a face killed with its
//! edge, say) are skipped silently. Inputs are processed in ascending id
//! order, so results do not depend on the order given.

use super::side_table::SideTable;
use super::{canonical, into_canonical, OpError, Selection};
use crate::geom::UnionFind;
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
    Ok(duplicate_mapped(mesh, selection, true)?.copies)
}

/// A duplicate with the original → copy vertex map (for mirror).
pub(crate) struct Duplicated {
    pub(crate) copies: Selection,
    /// `(original, copy)` pairs, sorted by original.
    pub(crate) vert_pairs: Vec<(VertId, VertId)>,
}

/// With `normals` false the copied faces' stored normals are left zero:
/// the caller moves the copies and refreshes every copied face itself.
pub(crate) fn duplicate_mapped(
    mesh: &mut Mesh,
    selection: &Selection,
    normals: bool,
) -> Result<Duplicated, OpError> {
    let (sel_verts, sel_edges, faces) = checked(mesh, selection)?;
    let mut edges = sel_edges;
    for &f in &faces {
        edges.extend(mesh.face_edges(f));
    }
    let edges = into_canonical(edges);
    let mut verts = sel_verts;
    for &e in &edges {
        verts.extend(mesh.edge_verts(e));
    }
    let verts = into_canonical(verts);
    let corners = faces.iter().map(|&f| mesh.face_len(f)).sum();
    mesh.reserve(verts.len(), edges.len(), corners, faces.len());

    let mut vert_pairs = Vec::with_capacity(verts.len());
    let mut vert_copy = SideTable::new(verts.len(), mesh.vert_capacity());
    for &v in &verts {
        let copy = mesh.make_vert(mesh.position(v));
        mesh.copy_vert_attrs(v, copy);
        vert_pairs.push((v, copy));
        vert_copy.insert(v.index(), copy);
    }
    let map = |v: VertId| -> VertId {
        *vert_copy
            .get(v.index())
            .expect("every vertex of a copied edge or face is copied")
    };
    let mut new_edges = Vec::with_capacity(edges.len());
    let mut edge_copy = SideTable::new(edges.len(), mesh.edge_capacity());
    for &e in &edges {
        let [a, b] = mesh.edge_verts(e);
        let copy = mesh.make_edge(map(a), map(b))?;
        mesh.copy_edge_attrs(e, copy);
        new_edges.push(copy);
        edge_copy.insert(e.index(), copy);
    }
    let mut new_faces = Vec::with_capacity(faces.len());
    let (mut ring, mut sides) = (Vec::new(), Vec::new());
    for &f in &faces {
        ring.clear();
        sides.clear();
        for l in mesh.face_loops(f) {
            ring.push(map(mesh.loop_vert(l)));
            sides.push(
                *edge_copy
                    .get(mesh.loop_edge(l).index())
                    .expect("every edge of a copied face is copied"),
            );
        }
        // The copy's edges exist already (made above), side by side.
        let copy = if normals {
            mesh.make_face_on_edges(&ring, &sides)?
        } else {
            mesh.make_face_on_edges_unrefreshed(&ring, &sides)?
        };
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
    /// Edges left alone: not between exactly two faces, or in a region
    /// whose outline is not one simple loop.
    pub skipped: usize,
}

/// Dissolves edges as BMesh's `dissolve_edges` does: the faces connected
/// through selected edges (each between exactly two faces) form regions,
/// and every region becomes one face bounded by the region's outline,
/// wound like its faces and carrying the attributes of its lowest-id
/// face. The region's inner edges go, and so do vertices left with no
/// edge. Returns the new faces.
///
/// Edges not between two faces are skipped, and so is a whole region whose
/// outline is not one simple loop (a ring of faces round a hole, or faces
/// wound against each other): one face cannot hold it.
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
    // Regions: faces joined through dissolvable edges (union-find over
    // face slots; ids ascend, so the representative is the lowest face).
    let mut sets = UnionFind::new(mesh.face_capacity());
    let mut inner: Vec<EdgeId> = Vec::new();
    for &e in &edges {
        let faces: Vec<FaceId> = mesh.edge_faces(e).collect();
        if faces.len() != 2 || faces[0] == faces[1] {
            result.skipped += 1;
            continue;
        }
        inner.push(e);
        sets.union(faces[0].index() as u32, faces[1].index() as u32);
    }
    // Faces and inner edges by region, regions by their lowest face.
    let mut regions: Vec<(u32, Vec<FaceId>, Vec<EdgeId>)> = Vec::new();
    for &e in &inner {
        let f = mesh.edge_faces(e).next().expect("two faces");
        let r = sets.find(f.index() as u32);
        let slot = match regions.binary_search_by_key(&r, |(key, ..)| *key) {
            Ok(i) => i,
            Err(i) => {
                regions.insert(i, (r, Vec::new(), Vec::new()));
                i
            }
        };
        regions[slot].2.push(e);
    }
    for f in mesh.face_ids() {
        let r = sets.find(f.index() as u32);
        if let Ok(i) = regions.binary_search_by_key(&r, |(key, ..)| *key) {
            regions[i].1.push(f);
        }
    }
    let mut made = Vec::new();
    for (_, faces, inner) in regions {
        // `inner` ascends: the edges were taken in canonical order.
        let Some(outline) = outline(mesh, &faces, |e| inner.binary_search(&e).is_ok()) else {
            result.skipped += inner.len();
            continue;
        };
        let joined = mesh.make_face(&outline)?;
        mesh.copy_face_attrs(faces[0], joined);
        let corners: Vec<VertId> = inner.iter().flat_map(|&e| mesh.edge_verts(e)).collect();
        for &f in &faces {
            mesh.kill_face(f)?;
        }
        for &e in &inner {
            mesh.kill_edge(e)?;
        }
        for v in corners {
            if mesh.contains_vert(v) && mesh.vert_edges(v).next().is_none() {
                mesh.kill_vert(v)?;
            }
        }
        result.dissolved += inner.len();
        made.push(joined);
    }
    made.sort_unstable();
    result.faces = made;
    Ok(result)
}

/// The outline of `faces` as one vertex loop in their winding: the sides
/// whose edge is not `inside`, chained head to tail. `None` unless they
/// form exactly one simple loop.
fn outline(mesh: &Mesh, faces: &[FaceId], inside: impl Fn(EdgeId) -> bool) -> Option<Vec<VertId>> {
    // (from, to) sides, sorted by `from` for lookup.
    let mut sides: Vec<(VertId, VertId)> = Vec::new();
    for &f in faces {
        let ring: Vec<VertId> = mesh.face_verts(f).collect();
        for (k, &v) in ring.iter().enumerate() {
            let w = ring[(k + 1) % ring.len()];
            let e = mesh.find_edge(v, w)?;
            if !inside(e) {
                sides.push((v, w));
            }
        }
    }
    sides.sort_unstable();
    if sides.len() < 3 || sides.windows(2).any(|p| p[0].0 == p[1].0) {
        return None;
    }
    let next = |v: VertId| {
        sides
            .binary_search_by_key(&v, |&(from, _)| from)
            .ok()
            .map(|i| sides[i].1)
    };
    let start = sides[0].0;
    let mut ring = vec![start];
    let mut at = next(start)?;
    while at != start {
        if ring.len() == sides.len() {
            return None;
        }
        ring.push(at);
        at = next(at)?;
    }
    (ring.len() == sides.len()).then_some(ring)
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
        assert_eq!(report.faces.len(), 1);
        let joined = report.faces[0];
        assert_eq!(counts(&m), (8, 8, 1));
        assert_eq!(m.face_len(joined), 8);
        assert!((m.face_area(joined) - 3.0).abs() < 1e-12);

        // Dead ids are the kernel's error.
        input.push(EdgeId::from_index(500));
        assert!(matches!(
            dissolve_edges(&mut m, &input),
            Err(OpError::Kernel(KernelError::Dead { .. }))
        ));
    }

    #[test]
    fn dissolving_every_edge_of_a_cube_dissolves_nothing() {
        // One region, whose outline is empty (a closed surface): no face holds it.
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 1.0).unwrap();
        let report = dissolve_edges_report(&mut m, &c.edges).unwrap();
        m.validate().unwrap();
        assert_eq!((report.dissolved, report.skipped), (0, 12));
        assert_eq!(counts(&m), (8, 12, 6));
    }

    #[test]
    fn a_region_of_edges_dissolves_into_one_face() {
        // The four inner edges of a 2 × 2 grid: every pair of quads shares
        // two of them through the centre; the old edge-by-edge dissolve
        // left a slit. Now: one square face, the centre vertex gone.
        let mut m = Mesh::new();
        let g = create_grid(&mut m, 2, 2, 2.0, 2.0).unwrap();
        m.add_layer("mat", crate::kernel::Domain::Face, AttrValue::Int(0))
            .unwrap();
        m.set_attr("mat", Domain::Face, g.faces[0].index(), AttrValue::Int(7));
        let inner: Vec<EdgeId> = g
            .edges
            .iter()
            .copied()
            .filter(|&e| m.edge_face_count(e) == 2)
            .collect();
        assert_eq!(inner.len(), 4);
        let report = dissolve_edges_report(&mut m, &inner).unwrap();
        m.validate().unwrap();
        assert_eq!((report.dissolved, report.skipped), (4, 0));
        assert_eq!(counts(&m), (8, 8, 1));
        let f = report.faces[0];
        assert_eq!(m.face_len(f), 8);
        assert!((m.face_area(f) - 4.0).abs() < 1e-12);
        assert!(m.face_normal(f).z > 0.99, "wound like the grid");
        assert_eq!(
            m.attr("mat", Domain::Face, f.index()),
            Some(AttrValue::Int(7))
        );

        // Two separate regions in one call: two faces.
        let mut m = Mesh::new();
        let g = create_grid(&mut m, 4, 1, 4.0, 1.0).unwrap();
        let inner: Vec<EdgeId> = g
            .edges
            .iter()
            .copied()
            .filter(|&e| m.edge_face_count(e) == 2)
            .collect();
        let report = dissolve_edges_report(&mut m, &[inner[0], inner[2]]).unwrap();
        m.validate().unwrap();
        assert_eq!((report.dissolved, report.faces.len()), (2, 2));
        assert_eq!(m.face_count(), 2);

        // A ring of faces round a hole has two outlines: left alone.
        let mut m = Mesh::new();
        let g = create_grid(&mut m, 3, 3, 3.0, 3.0).unwrap();
        let centre = g.faces[4];
        delete(
            &mut m,
            &Selection::from_parts(vec![], vec![], vec![centre]),
            DeleteMode::Faces,
        )
        .unwrap();
        let ring: Vec<EdgeId> = m
            .edge_ids()
            .filter(|&e| m.edge_face_count(e) == 2)
            .collect();
        assert_eq!(ring.len(), 8);
        let report = dissolve_edges_report(&mut m, &ring).unwrap();
        m.validate().unwrap();
        assert_eq!((report.dissolved, report.skipped), (0, 8));
        assert_eq!(m.face_count(), 8);
    }
}
