//! Select operators: convert a set of one element kind into the others and
//! grow or shrink face regions, without changing the mesh (seed 000 §3.2:
//! "functions that transform selected vertices, edges and faces into other
//! elements"; §3.3, the *Select* category).
//!
//! The seed's rules (§3.2, `SelectFromVerts` in its example 3.3):
//! - from faces: the faces, and the vertices and edges of their boundaries;
//! - from edges: the edges, their vertices, and the faces whose whole
//!   boundary is selected;
//! - from vertices: the vertices, and the edges and faces whose whole
//!   boundary is selected.
//!
//! Results are canonical (sorted, deduplicated), whatever the input order.
//! These functions cannot fail, so ids of dead elements in the input are
//! ignored rather than reported.
//!
//! Membership tests binary-search the sorted input, so a call costs
//! O(k log k) in the size k of what it touches, never the size of the mesh.

use super::{canonical, into_canonical, Selection};
use crate::kernel::ids::{EdgeId, FaceId, SlotId, VertId};
use crate::kernel::mesh::Mesh;

/// Which neighbours a region grows to or shrinks from: faces sharing an edge,
/// or faces sharing at least a vertex.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Adjacency {
    Edge,
    Vert,
}

/// The vertices, the edges with both ends among them, and the faces with
/// all their vertices among them.
pub fn select_from_verts(mesh: &Mesh, verts: &[VertId]) -> Selection {
    let verts = live(verts, |v| mesh.contains_vert(v));
    let selected = |v: VertId| verts.binary_search(&v).is_ok();
    let mut edges = Vec::new();
    let mut faces = Vec::new();
    for &v in &verts {
        for e in mesh.vert_edges(v) {
            let other = mesh.edge_other_vert(e, v);
            // Met from both ends: keep it from the lower one.
            if v < other && selected(other) {
                edges.push(e);
            }
        }
        for f in mesh.vert_faces(v) {
            if mesh.face_verts(f).all(selected) {
                faces.push(f);
            }
        }
    }
    Selection::from_parts(verts, edges, faces)
}

/// The edges, their vertices, and the faces whose edges are all among them.
pub fn select_from_edges(mesh: &Mesh, edges: &[EdgeId]) -> Selection {
    let edges = live(edges, |e| mesh.contains_edge(e));
    let selected = |e: EdgeId| edges.binary_search(&e).is_ok();
    let mut verts = Vec::with_capacity(2 * edges.len());
    let mut faces = Vec::new();
    for &e in &edges {
        verts.extend(mesh.edge_verts(e));
        for f in mesh.edge_faces(e) {
            if mesh.face_edges(f).all(selected) {
                faces.push(f);
            }
        }
    }
    Selection::from_parts(verts, edges, faces)
}

/// The faces with the edges and vertices of their boundaries.
pub fn select_from_faces(mesh: &Mesh, faces: &[FaceId]) -> Selection {
    let faces = live(faces, |f| mesh.contains_face(f));
    let mut verts = Vec::new();
    let mut edges = Vec::new();
    for &f in &faces {
        verts.extend(mesh.face_verts(f));
        edges.extend(mesh.face_edges(f));
    }
    let verts = into_canonical(verts);
    let edges = into_canonical(edges);
    Selection::from_parts(verts, edges, faces)
}

/// The region grown by one step: the faces plus every face sharing an edge
/// ([`Adjacency::Edge`]) or at least a vertex ([`Adjacency::Vert`]) with one
/// of them, sorted.
pub fn region_extend(mesh: &Mesh, faces: &[FaceId], by: Adjacency) -> Vec<FaceId> {
    let faces = live(faces, |f| mesh.contains_face(f));
    let mut out = faces.clone();
    for &f in &faces {
        match by {
            Adjacency::Edge => out.extend(mesh.face_edge_neighbors(f)),
            Adjacency::Vert => out.extend(mesh.face_vert_neighbors(f)),
        }
    }
    out.sort_unstable();
    out.dedup();
    out
}

/// The region shrunk by one step: the faces that are not on its border.
///
/// A face is on the border when one of its edges ([`Adjacency::Edge`]) or
/// vertices ([`Adjacency::Vert`]) is shared with a face outside the region,
/// **or** lies on the mesh boundary: an edge with a single face (for
/// `Vert`: such an edge at the vertex). So reducing a whole open grid peels
/// off its outer ring, as shrinking a selection does in modelling tools;
/// a closed mesh reduced as a whole stays whole. Wire edges (no face) bound
/// no surface and are not a border. Sorted.
pub fn region_reduce(mesh: &Mesh, faces: &[FaceId], by: Adjacency) -> Vec<FaceId> {
    let faces = live(faces, |f| mesh.contains_face(f));
    let inside = |g: FaceId| faces.binary_search(&g).is_ok();
    let edge_is_interior = |e: EdgeId| {
        let mut count = 0usize;
        let all_inside = mesh.edge_faces(e).all(|g| {
            count += 1;
            inside(g)
        });
        // A wire edge has no faces: it is neither inside nor a border.
        all_inside && count != 1
    };
    faces
        .iter()
        .copied()
        .filter(|&f| match by {
            Adjacency::Edge => mesh.face_edges(f).all(edge_is_interior),
            Adjacency::Vert => mesh
                .face_verts(f)
                .all(|v| mesh.vert_edges(v).all(edge_is_interior)),
        })
        .collect()
}

/// Sorted, deduplicated live ids.
fn live<T: SlotId>(ids: &[T], alive: impl Fn(T) -> bool) -> Vec<T> {
    let mut out = canonical(ids);
    out.retain(|&id| alive(id));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::ops::create::{create_cube, create_grid};

    /// A 5×5 grid; face (i, j) is `faces[j * 5 + i]`.
    fn grid5() -> (Mesh, Selection) {
        let mut m = Mesh::new();
        let g = create_grid(&mut m, 5, 5, 5.0, 5.0).unwrap();
        (m, g)
    }

    #[test]
    fn from_verts_takes_fully_selected_edges_and_faces() {
        let (m, g) = grid5();
        // Vertex (i, j) is verts[j * 6 + i]: the 2×2 block of verts at the
        // corner spans exactly one face; add a lone vertex far away.
        let row = 6;
        let picked = [
            g.verts[0],
            g.verts[1],
            g.verts[row],
            g.verts[row + 1],
            g.verts[35],
        ];
        let s = select_from_verts(&m, &picked);
        assert_eq!(s.verts.len(), 5);
        assert_eq!(s.edges.len(), 4);
        assert_eq!(s.faces, vec![g.faces[0]]);
        // Order and duplicates do not matter.
        let mut shuffled = picked.to_vec();
        shuffled.reverse();
        shuffled.push(g.verts[0]);
        assert_eq!(select_from_verts(&m, &shuffled), s);
        // A dead id is ignored, not a panic.
        shuffled.push(VertId::from_index(10_000));
        assert_eq!(select_from_verts(&m, &shuffled), s);
    }

    #[test]
    fn from_edges_takes_verts_and_closed_faces() {
        let (m, g) = grid5();
        let f = g.faces[7];
        let boundary: Vec<EdgeId> = m.face_edges(f).collect();
        let s = select_from_edges(&m, &boundary[..3]);
        assert_eq!(s.edges.len(), 3);
        assert_eq!(s.verts.len(), 4);
        assert!(
            s.faces.is_empty(),
            "three of four edges do not close the face"
        );
        let s = select_from_edges(&m, &boundary);
        assert_eq!(s.faces, vec![f]);
        assert_eq!(s.verts.len(), 4);
    }

    #[test]
    fn from_faces_takes_their_boundaries() {
        let (m, g) = grid5();
        let s = select_from_faces(&m, &[g.faces[1], g.faces[0]]);
        assert_eq!((s.verts.len(), s.edges.len(), s.faces.len()), (6, 7, 2));
        // Round trip: the verts of faces select back those faces.
        assert_eq!(select_from_verts(&m, &s.verts).faces, s.faces);
        assert_eq!(select_from_edges(&m, &s.edges), s);
    }

    #[test]
    fn extend_an_interior_face_by_vert_and_by_edge() {
        let (m, g) = grid5();
        let center = g.faces[12];
        let by_vert = region_extend(&m, &[center], Adjacency::Vert);
        let by_edge = region_extend(&m, &[center], Adjacency::Edge);
        assert_eq!(by_vert.len(), 9);
        assert_eq!(by_edge.len(), 5);
        assert_eq!(
            by_edge,
            vec![
                g.faces[7],
                g.faces[11],
                g.faces[12],
                g.faces[13],
                g.faces[17]
            ]
        );
        assert!(by_edge.iter().all(|f| by_vert.contains(f)));
        // A corner face has 3 vertex neighbours and 2 edge neighbours.
        assert_eq!(region_extend(&m, &[g.faces[0]], Adjacency::Vert).len(), 4);
        assert_eq!(region_extend(&m, &[g.faces[0]], Adjacency::Edge).len(), 3);
    }

    #[test]
    fn reduce_inverts_extend_inside_and_peels_the_mesh_boundary() {
        let (m, g) = grid5();
        let center = g.faces[12];
        let block = region_extend(&m, &[center], Adjacency::Vert);
        assert_eq!(region_reduce(&m, &block, Adjacency::Vert), vec![center]);
        assert_eq!(region_reduce(&m, &block, Adjacency::Edge), vec![center]);

        // The plus shape: its centre shares every edge inside the region,
        // but its corners touch faces outside it.
        let plus = region_extend(&m, &[center], Adjacency::Edge);
        assert_eq!(region_reduce(&m, &plus, Adjacency::Edge), vec![center]);
        assert!(region_reduce(&m, &plus, Adjacency::Vert).is_empty());

        // The whole grid: the faces on the mesh boundary are the border.
        let interior = region_reduce(&m, &g.faces, Adjacency::Edge);
        assert_eq!(interior.len(), 9);
        assert_eq!(region_reduce(&m, &g.faces, Adjacency::Vert), interior);
    }

    #[test]
    fn a_closed_mesh_reduced_as_a_whole_stays_whole() {
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 1.0).unwrap();
        assert_eq!(region_reduce(&m, &c.faces, Adjacency::Edge), c.faces);
        assert_eq!(region_reduce(&m, &c.faces, Adjacency::Vert), c.faces);
        let top = [c.faces[1]];
        assert!(region_reduce(&m, &top, Adjacency::Edge).is_empty());
        assert_eq!(region_extend(&m, &top, Adjacency::Edge).len(), 5);
        assert_eq!(region_extend(&m, &top, Adjacency::Vert).len(), 5);
    }
}
