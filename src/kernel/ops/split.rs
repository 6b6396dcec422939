//! Edge subdivision: cutting edges into equal parts or at given ratios
//! (DESIGN.md "split edges (cuts, ratios)"; seed 000 §4.4 `EdgeSplit` is
//! the Euler operator underneath, and seed 003's *split edge* command uses
//! the ratio form).
//!
//! Each cut is one [`Mesh::split_edge`], so every face using an edge gains
//! the new vertices in its boundary (a quad with one edge cut twice becomes
//! a 6-gon) and no face is added or removed. Cuts proceed from the edge's
//! first vertex (`edge_verts(e)[0]`) towards its second: the original edge
//! keeps the first piece and the new vertices' ids increase along the edge.
//! New positions are set exactly at `lerp(first, second, ratio)` of the
//! original ends, so repeated splitting does not accumulate rounding; vertex
//! attributes are interpolated by the Euler operator, edge attributes
//! copied to every piece.

use super::{canonical, OpError, Selection};
use crate::kernel::{EdgeId, Mesh};

/// Splits each edge into `cuts + 1` equal parts (`cuts` new vertices per
/// edge; `cuts = 0` changes nothing).
///
/// Result: the new vertices and the new edges (every piece but the first,
/// which keeps the original edge's id).
pub fn split_edges(mesh: &mut Mesh, edges: &[EdgeId], cuts: u32) -> Result<Selection, OpError> {
    let parts = f64::from(cuts) + 1.0;
    split_with(mesh, edges, cuts as usize, |k| (k + 1) as f64 / parts)
}

/// Splits each edge at every ratio in `ratios`, measured from the edge's
/// first vertex (`Mesh::edge_verts(e)[0]`) as a fraction of its length.
/// Ratios must lie strictly between 0 and 1 and increase strictly; an empty
/// list changes nothing.
///
/// Result: the new vertices and the new edges.
pub fn split_edges_at(
    mesh: &mut Mesh,
    edges: &[EdgeId],
    ratios: &[f64],
) -> Result<Selection, OpError> {
    check_ratios(ratios)?;
    split_with(mesh, edges, ratios.len(), |k| ratios[k])
}

/// Cuts every edge at `ratio(0) < … < ratio(count - 1)`, all in (0, 1).
fn split_with(
    mesh: &mut Mesh,
    edges: &[EdgeId],
    count: usize,
    ratio: impl Fn(usize) -> f64,
) -> Result<Selection, OpError> {
    let edges = canonical(edges);
    for &e in &edges {
        mesh.check_edge(e)?;
    }
    // Element ids are u32 slots: refuse a request that cannot fit before
    // making anything (the arena would otherwise panic mid-way).
    let added = edges.len() as u128 * count as u128;
    let room = |capacity: usize| u128::from(u32::MAX) - capacity as u128;
    if added > room(mesh.vert_capacity()) || added > room(mesh.edge_capacity()) {
        return Err(OpError::parameter(
            "cuts",
            format!("{added} new vertices would exceed the mesh's id space"),
        ));
    }

    let mut result = Selection::new();
    for e in edges {
        let [first, second] = mesh.edge_verts(e);
        let (from, to) = (mesh.position(first), mesh.position(second));
        // The piece still to cut runs from the last new vertex (at ratio
        // `done`) to `second`; the Euler operator's parameter is relative
        // to that piece.
        let mut piece = e;
        let mut done = 0.0;
        for k in 0..count {
            let r = ratio(k);
            let (vert, rest) = mesh.split_edge(piece, (r - done) / (1.0 - done))?;
            mesh.move_vert(vert, from.lerp(to, r));
            result.verts.push(vert);
            result.edges.push(rest);
            piece = rest;
            done = r;
        }
    }
    result.normalize();
    Ok(result)
}

fn check_ratios(ratios: &[f64]) -> Result<(), OpError> {
    if let Some(bad) = ratios
        .iter()
        .find(|r| !(r.is_finite() && **r > 0.0 && **r < 1.0))
    {
        return Err(OpError::parameter(
            "ratios",
            format!("every ratio must lie strictly between 0 and 1, got {bad}"),
        ));
    }
    if let Some(pair) = ratios.windows(2).find(|w| w[0] >= w[1]) {
        return Err(OpError::parameter(
            "ratios",
            format!(
                "ratios must increase strictly, got {} then {}",
                pair[0], pair[1]
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::kernel::ops::extrude::tests::{consistently_wound, grid};
    use crate::kernel::{AttrValue, Domain, FaceId, KernelError, VertId};

    #[test]
    fn split_edges_counts_and_positions() {
        let mut m = grid(1, 1, 1.0);
        let bottom = m
            .find_edge(VertId::from_raw(0), VertId::from_raw(1))
            .unwrap();
        let r = split_edges(&mut m, &[bottom], 3).unwrap();
        m.validate().unwrap();
        assert_eq!((r.verts.len(), r.edges.len(), r.faces.len()), (3, 3, 0));
        assert_eq!((m.vert_count(), m.edge_count(), m.face_count()), (7, 7, 1));
        assert_eq!(m.face_len(FaceId::from_raw(0)), 7);
        for (k, &v) in r.verts.iter().enumerate() {
            let x = -0.5 + 0.25 * (k + 1) as f64;
            assert_eq!(m.position(v), DVec3::new(x, -0.5, 0.0));
        }
        // The face walks the new vertices in order, ids increasing.
        let ring: Vec<VertId> = m.face_verts(FaceId::from_raw(0)).collect();
        assert_eq!(
            &ring[..5],
            &[
                VertId::from_raw(0),
                r.verts[0],
                r.verts[1],
                r.verts[2],
                VertId::from_raw(1)
            ]
        );
        assert_eq!(m.edge_verts(bottom), [VertId::from_raw(0), r.verts[0]]);
        assert!((m.face_area(FaceId::from_raw(0)) - 1.0).abs() < 1e-15);

        // Every edge of the square cut once: an octagon outline.
        let mut m = grid(1, 1, 1.0);
        let edges: Vec<EdgeId> = m.edge_ids().collect();
        let r = split_edges(&mut m, &edges, 1).unwrap();
        m.validate().unwrap();
        assert_eq!((r.verts.len(), r.edges.len()), (4, 4));
        assert_eq!((m.edge_count(), m.face_len(FaceId::from_raw(0))), (8, 8));
        for &v in &r.verts {
            let p = m.position(v);
            assert_eq!(p.x.abs() + p.y.abs(), 0.5, "{p} is not an edge midpoint");
        }

        let before = m.clone();
        assert_eq!(split_edges(&mut m, &edges, 0), Ok(Selection::new()));
        assert_eq!(m.edge_count(), before.edge_count());
    }

    #[test]
    fn split_edges_at_measures_from_the_first_vertex() {
        let mut m = Mesh::new();
        let a = m.make_vert(DVec3::ZERO);
        let b = m.make_vert(DVec3::new(10.0, 0.0, 0.0));
        let e = m.make_edge(b, a).unwrap();
        let r = split_edges_at(&mut m, &[e], &[0.1, 0.5]).unwrap();
        m.validate().unwrap();
        let xs: Vec<f64> = r.verts.iter().map(|&v| m.position(v).x).collect();
        assert_eq!(xs, vec![9.0, 5.0]);
        assert_eq!(m.edge_verts(e), [b, r.verts[0]]);
        assert_eq!(m.vert_degree(a), 1);

        // An edge between two faces: both gain the vertices, winding intact.
        let mut m = grid(2, 1, 1.0);
        let shared = m
            .find_edge(VertId::from_raw(1), VertId::from_raw(4))
            .unwrap();
        let r = split_edges_at(&mut m, &[shared, shared], &[0.25, 0.75]).unwrap();
        m.validate().unwrap();
        assert_eq!(r.verts.len(), 2);
        assert_eq!(
            (
                m.face_len(FaceId::from_raw(0)),
                m.face_len(FaceId::from_raw(1))
            ),
            (6, 6)
        );
        assert!(consistently_wound(&m));
        assert_eq!(m.edge_face_count(r.edges[0]), 2);
    }

    #[test]
    fn ratios_are_validated_before_any_change() {
        let mut m = grid(1, 1, 1.0);
        let edges: Vec<EdgeId> = m.edge_ids().collect();
        for bad in [
            &[0.5, 0.5][..],
            &[0.6, 0.3],
            &[0.0],
            &[1.0],
            &[-0.2],
            &[f64::NAN],
            &[0.5, f64::INFINITY],
        ] {
            assert!(
                matches!(
                    split_edges_at(&mut m, &edges, bad),
                    Err(OpError::Parameter { name: "ratios", .. })
                ),
                "{bad:?} accepted"
            );
        }
        assert!(matches!(
            split_edges(&mut m, &edges, u32::MAX),
            Err(OpError::Parameter { name: "cuts", .. })
        ));
        assert_eq!(
            split_edges(&mut m, &[edges[0], EdgeId::from_raw(77)], 2),
            Err(OpError::Kernel(KernelError::Dead {
                domain: Domain::Edge,
                index: 77
            }))
        );
        assert_eq!((m.vert_count(), m.edge_count()), (4, 4));
        m.validate().unwrap();
    }

    #[test]
    fn split_interpolates_vertex_and_copies_edge_attributes() {
        let mut m = Mesh::new();
        m.add_layer("radius", Domain::Vert, AttrValue::Scalar(0.0))
            .unwrap();
        m.add_layer("kind", Domain::Edge, AttrValue::Int(0))
            .unwrap();
        let a = m.make_vert(DVec3::ZERO);
        let (e, b) = m.make_edge_vert(a, DVec3::X).unwrap();
        m.set_attr("radius", Domain::Vert, b.index(), AttrValue::Scalar(1.0));
        m.set_attr("kind", Domain::Edge, e.index(), AttrValue::Int(5));
        let r = split_edges(&mut m, &[e], 3).unwrap();
        m.validate().unwrap();
        for (k, &v) in r.verts.iter().enumerate() {
            let Some(AttrValue::Scalar(radius)) = m.attr("radius", Domain::Vert, v.index()) else {
                panic!("no radius");
            };
            assert!((radius - 0.25 * (k + 1) as f64).abs() < 1e-12);
        }
        for &piece in &r.edges {
            assert_eq!(
                m.attr("kind", Domain::Edge, piece.index()),
                Some(AttrValue::Int(5))
            );
        }
    }
}
