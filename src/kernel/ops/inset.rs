//! Inset: a smaller copy of a face (or of a face region's boundary) inside
//! it, joined to the original outline by a ring of quads (seed 000 §3.3
//! lists *inset face* among the "Modify" operators).
//!
//! ```text
//!   3 ───────── 2        individual inset of one quad: the inner face
//!   │ ╲       ╱ │        copies the original's attributes and winding,
//!   │  3'───2'  │        four ring quads fill the frame, the original
//!   │  │    │   │        face is killed — 5 faces, 8 vertices.
//!   │  0'───1'  │
//!   │ ╱       ╲ │
//!   0 ───────── 1
//! ```
//!
//! Geometry (both operators): each inner corner moves inward along the
//! in-plane bisector of its corner by `thickness / sin(half corner angle)`
//! — the mitre offset, which keeps every inner edge exactly `thickness`
//! from its outer edge — and then `depth` along the normal. A large
//! thickness is clamped, per face (individual) or per region, to the *first
//! edge event*: the smallest thickness at which some moving edge would
//! shrink to zero length along its own direction and then flip. Convex
//! faces therefore never invert (a square inset by half its side or more
//! collapses to its centre); non-convex outlines can still self-overlap at
//! large thickness, because split events (a reflex corner running into an
//! opposite edge) are not detected. Only square roots are used, so results
//! are bit-identical across platforms.
//!
//! Winding: ring quads run each outer edge the way the original face did,
//! so they agree with the surrounding mesh and with the inner face.
//! Attributes: inner vertices copy their outer vertex's, inner edges their
//! outer edge's, inner and ring faces the original face's.

use glam::DVec3;

use super::side_table::{SideTable, SlotSet};

use super::{canonical, OpError, Selection};
use crate::kernel::{EdgeId, FaceId, Mesh, VertId};

/// Rejects non-finite parameters and a negative thickness (an outset would
/// push the inner face over its neighbours, which is not an inset).
fn check_parameters(thickness: f64, depth: f64) -> Result<(), OpError> {
    if !thickness.is_finite() || thickness < 0.0 {
        return Err(OpError::parameter(
            "thickness",
            format!("must be finite and non-negative, got {thickness}"),
        ));
    }
    if !depth.is_finite() {
        return Err(OpError::parameter(
            "depth",
            format!("must be finite, got {depth}"),
        ));
    }
    Ok(())
}

/// Below this, `1 + cos` between two inward directions counts as zero: the
/// outline turns straight back on itself and the mitre has no direction.
const FOLD_EPSILON: f64 = 1e-12;

/// The displacement per unit thickness of a corner whose incoming and
/// outgoing edges have unit inward directions `m_in`, `m_out` (zero for a
/// zero-length edge) and unit directions `u_in`, `u_out`: the point at
/// distance 1 from both edge lines, `(m_in + m_out) / (1 + m_in · m_out)`,
/// of length 1 / sin(half corner angle).
fn mitre(m_in: DVec3, m_out: DVec3, u_in: DVec3, u_out: DVec3) -> DVec3 {
    let denominator = 1.0 + m_in.dot(m_out);
    if denominator > FOLD_EPSILON {
        (m_in + m_out) / denominator
    } else {
        // A spike (the outline doubles back): move back along the edges,
        // into the spike; the edge-event clamp bounds how far.
        (u_out - u_in).normalize_or_zero()
    }
}

/// The largest `t ≤ limit` at which no edge (a, b), whose ends move by
/// `t · rate[a]` and `t · rate[b]`, has shrunk past zero length along its
/// own direction: the first edge event of the inset.
fn clamp_to_first_edge_event(
    limit: f64,
    edges: impl Iterator<Item = (DVec3, DVec3, DVec3, DVec3)>,
) -> f64 {
    let mut t = limit;
    for (pa, pb, rate_a, rate_b) in edges {
        let along = pb - pa;
        let length = along.length();
        if length == 0.0 {
            continue;
        }
        let shrink = (rate_b - rate_a).dot(along / length);
        if shrink < 0.0 {
            t = t.min(length / -shrink);
        }
    }
    t
}

/// Inner ring of one polygon for an individual inset (positions only).
fn inset_polygon(points: &[DVec3], normal: DVec3, thickness: f64, depth: f64) -> Vec<DVec3> {
    let n = points.len();
    if normal == DVec3::ZERO {
        // No plane to be inward in (collinear or cancelling outline): move
        // each corner towards the centroid, never past it.
        let centroid = points.iter().sum::<DVec3>() / n as f64;
        return points
            .iter()
            .map(|&p| {
                let to_centre = centroid - p;
                p + to_centre.normalize_or_zero() * thickness.min(to_centre.length())
            })
            .collect();
    }
    // Unit edge directions projected into the face plane (non-planar faces
    // get the mitre of their projection) and inward normals n × u.
    let directions: Vec<DVec3> = (0..n)
        .map(|i| {
            let d = points[(i + 1) % n] - points[i];
            (d - normal * d.dot(normal)).normalize_or_zero()
        })
        .collect();
    let inward: Vec<DVec3> = directions.iter().map(|&u| normal.cross(u)).collect();
    let rates: Vec<DVec3> = (0..n)
        .map(|i| {
            let before = (i + n - 1) % n;
            mitre(inward[before], inward[i], directions[before], directions[i])
        })
        .collect();
    let t = clamp_to_first_edge_event(
        thickness,
        (0..n).map(|i| {
            let j = (i + 1) % n;
            (points[i], points[j], rates[i], rates[j])
        }),
    );
    (0..n)
        .map(|i| points[i] + rates[i] * t + normal * depth)
        .collect()
}

/// Refuses a result position that is not finite, before any change.
fn check_targets<'a>(targets: impl IntoIterator<Item = &'a DVec3>) -> Result<(), OpError> {
    if targets.into_iter().all(|p| p.is_finite()) {
        Ok(())
    } else {
        Err(OpError::parameter(
            "thickness",
            "moves a vertex to a non-finite position",
        ))
    }
}

/// Inset faces, individually: every face gets its own smaller copy inside
/// it (see the module notes for the corner geometry and the clamp), moved
/// `depth` along the face normal, and a ring of quads between the copy and
/// its outline; the original face is killed. Adjacent selected faces are
/// inset independently, so their rings meet along the shared edge.
///
/// Each inner vertex is joined to its outer vertex by an edge running
/// outer → inner.
///
/// Result: the inner faces, the ring faces, the new (inner) vertices and
/// the new edges (inner outline and spokes).
pub fn inset_faces(
    mesh: &mut Mesh,
    faces: &[FaceId],
    thickness: f64,
    depth: f64,
) -> Result<Selection, OpError> {
    check_parameters(thickness, depth)?;
    let faces = canonical(faces);
    for &f in &faces {
        mesh.check_face(f)?;
    }
    struct Plan {
        face: FaceId,
        ring: Vec<VertId>,
        ring_edges: Vec<EdgeId>,
        inner: Vec<DVec3>,
    }
    let plans: Vec<Plan> = faces
        .iter()
        .map(|&f| Plan {
            face: f,
            ring: mesh.face_verts(f).collect(),
            ring_edges: mesh.face_edges(f).collect(),
            inner: inset_polygon(
                &mesh.face_positions(f),
                mesh.compute_face_normal(f),
                thickness,
                depth,
            ),
        })
        .collect();
    check_targets(plans.iter().flat_map(|p| &p.inner))?;

    let mut result = Selection::new();
    for plan in plans {
        let n = plan.ring.len();
        let mut inner = Vec::with_capacity(n);
        for (&v, &target) in plan.ring.iter().zip(&plan.inner) {
            let (spoke, w) = mesh.make_edge_vert(v, target)?;
            inner.push(w);
            result.edges.push(spoke);
        }
        let inner_face = mesh.make_face(&inner)?;
        mesh.copy_face_attrs(plan.face, inner_face);
        result.faces.push(inner_face);
        for i in 0..n {
            let j = (i + 1) % n;
            if let Some(inner_edge) = mesh.find_edge(inner[i], inner[j]) {
                mesh.copy_edge_attrs(plan.ring_edges[i], inner_edge);
                result.edges.push(inner_edge);
            }
            // Runs outer i → j like the original, inner j → i against the
            // inner face.
            let quad = mesh.make_face(&[plan.ring[i], plan.ring[j], inner[j], inner[i]])?;
            mesh.copy_face_attrs(plan.face, quad);
            result.faces.push(quad);
        }
        mesh.kill_face(plan.face)?;
        result.verts.extend(inner);
    }
    result.normalize();
    Ok(result)
}

/// Inset region: the faces are inset together. Only the region's boundary
/// (edges used by exactly one region face) is inset: every boundary vertex
/// gets an inner copy, moved inward within the region's tangent plane
/// there (the mitre of its two boundary edges' inward directions, both
/// projected perpendicular to the region's vertex normal; a vertex with
/// other than two boundary edges moves along their mean inward direction
/// by `thickness`), and a quad is built along every boundary edge. Region
/// faces that touch the boundary are rebuilt on the inner copies (killed
/// and remade, attributes copied); interior vertices and faces stay, and
/// the old interior edges from the outline are removed.
///
/// `depth` moves every inner vertex — copies and interior vertices alike —
/// along its region vertex normal (normalised mean of the unit normals of
/// the region faces around it), lifting the whole inner region. The
/// thickness clamp considers every region edge with a moving end.
///
/// Result: the faces of the inner region (rebuilt and untouched ones) and
/// the ring quads, the new inner boundary vertices, and the new edges.
pub fn inset_region(
    mesh: &mut Mesh,
    faces: &[FaceId],
    thickness: f64,
    depth: f64,
) -> Result<Selection, OpError> {
    check_parameters(thickness, depth)?;
    let faces = canonical(faces);
    for &f in &faces {
        mesh.check_face(f)?;
    }
    // Membership and the region's edges and vertices, ascending, from one
    // walk over the faces' corners (a region that is a good part of the
    // mesh names each vertex about four times; its sets are bitmaps).
    let corner_count: usize = faces.iter().map(|&f| mesh.face_len(f)).sum();
    let mut in_region = SlotSet::new(faces.len(), mesh.face_capacity());
    let mut edge_set = SlotSet::new(corner_count, mesh.edge_capacity());
    let mut vert_set = SlotSet::new(corner_count, mesh.vert_capacity());
    for &f in &faces {
        in_region.insert(f.index());
        for l in mesh.face_loops(f) {
            edge_set.insert(mesh.loop_edge(l).index());
            vert_set.insert(mesh.loop_vert(l).index());
        }
    }
    let region_edges: Vec<EdgeId> = edge_set
        .into_sorted()
        .into_iter()
        .map(EdgeId::from_index)
        .collect();
    let region_verts: Vec<VertId> = vert_set
        .into_sorted()
        .into_iter()
        .map(VertId::from_index)
        .collect();

    // Boundary edges, run x → y as their one region face runs them.
    struct Boundary {
        x: VertId,
        y: VertId,
        face: FaceId,
    }
    let mut boundary: Vec<Boundary> = Vec::new();
    let mut boundary_edge = SlotSet::new(region_edges.len(), mesh.edge_capacity());
    for &e in &region_edges {
        let mut region_loops = mesh
            .edge_loops(e)
            .filter(|&l| in_region.contains(mesh.lp(l).face.index()));
        if let (Some(only), None) = (region_loops.next(), region_loops.next()) {
            let x = mesh.lp(only).vert;
            let y = mesh.edge_other_vert(e, x);
            boundary.push(Boundary {
                x,
                y,
                face: mesh.lp(only).face,
            });
            boundary_edge.insert(e.index());
        }
    }
    let mut on_outline = SlotSet::new(2 * boundary.len(), mesh.vert_capacity());
    for b in &boundary {
        on_outline.insert(b.x.index());
        on_outline.insert(b.y.index());
    }
    let is_boundary = |v: VertId| on_outline.contains(v.index());

    // Region vertex normals (normalised mean of the unit normals of the
    // region faces around a vertex) are needed on the outline (the mitre
    // lies in the tangent plane there) and, when `depth` lifts the inner
    // region, everywhere. An interior vertex at depth 0 moves by
    // `0 · rate + normal · 0`, the same zero whatever its normal, so only
    // the outline's faces and vertices are measured then: the cost of a
    // big flat inset follows its outline. Side tables: slot-indexed for a
    // big set, hashed for a small one.
    let everywhere = depth != 0.0;
    let outline_verts: Vec<VertId>;
    let normal_verts: &[VertId] = if everywhere {
        &region_verts
    } else {
        outline_verts = region_verts
            .iter()
            .copied()
            .filter(|&v| is_boundary(v))
            .collect();
        &outline_verts
    };
    let mut face_normal: SideTable<DVec3> = SideTable::new(
        if everywhere {
            faces.len()
        } else {
            4 * normal_verts.len()
        },
        mesh.face_capacity(),
    );
    if everywhere {
        for &f in &faces {
            face_normal.insert(f.index(), mesh.compute_face_normal(f));
        }
    } else {
        for &v in normal_verts {
            for f in mesh.vert_faces(v) {
                if in_region.contains(f.index()) && !face_normal.contains(f.index()) {
                    face_normal.insert(f.index(), mesh.compute_face_normal(f));
                }
            }
        }
    }

    // Per region vertex its normal and mitre rate (zero inside the
    // region); the boundary edges (direction, inward direction) arriving
    // at and leaving it only for the outline's vertices.
    #[derive(Clone, Copy)]
    struct Corner {
        normal: DVec3,
        rate: DVec3,
    }
    #[derive(Default)]
    struct Outline {
        arriving: Vec<(DVec3, DVec3)>,
        leaving: Vec<(DVec3, DVec3)>,
    }
    const STILL: Corner = Corner {
        normal: DVec3::ZERO,
        rate: DVec3::ZERO,
    };
    let mut corners: SideTable<Corner> = SideTable::new(normal_verts.len(), mesh.vert_capacity());
    for &v in normal_verts {
        let normal = mesh
            .vert_faces(v)
            .filter_map(|f| face_normal.get(f.index()).copied())
            .sum::<DVec3>()
            .normalize_or_zero();
        corners.insert(
            v.index(),
            Corner {
                normal,
                rate: DVec3::ZERO,
            },
        );
    }
    let mut outline: SideTable<Outline> = SideTable::new(2 * boundary.len(), mesh.vert_capacity());
    for b in &boundary {
        let u = (mesh.position(b.y) - mesh.position(b.x)).normalize_or_zero();
        let m = face_normal
            .get(b.face.index())
            .expect("a region face on the outline")
            .cross(u);
        for (v, leaves) in [(b.x, true), (b.y, false)] {
            if !outline.contains(v.index()) {
                outline.insert(v.index(), Outline::default());
            }
            let o = outline.get_mut(v.index()).expect("just filed");
            if leaves {
                o.leaving.push((u, m));
            } else {
                o.arriving.push((u, m));
            }
        }
    }
    for &v in normal_verts {
        let Some(o) = outline.get(v.index()) else {
            continue;
        };
        let c = corners.get_mut(v.index()).expect("a region vertex");
        let n = c.normal;
        let flat = |d: DVec3| (d - n * d.dot(n)).normalize_or_zero();
        c.rate = match (&o.arriving[..], &o.leaving[..]) {
            ([(u_in, m_in)], [(u_out, m_out)]) => {
                mitre(flat(*m_in), flat(*m_out), flat(*u_in), flat(*u_out))
            }
            (all_in, all_out) => {
                let inward: DVec3 = all_in.iter().chain(all_out).map(|(_, m)| *m).sum();
                flat(inward)
            }
        };
    }
    let corner = |v: VertId| corners.get(v.index()).copied().unwrap_or(STILL);
    let t = clamp_to_first_edge_event(
        thickness,
        region_edges.iter().map(|&e| {
            let [a, b] = mesh.edge_verts(e);
            (
                mesh.position(a),
                mesh.position(b),
                corner(a).rate,
                corner(b).rate,
            )
        }),
    );
    let targets: Vec<DVec3> = region_verts
        .iter()
        .map(|&v| {
            let c = corner(v);
            mesh.position(v) + c.rate * t + c.normal * depth
        })
        .collect();
    check_targets(&targets)?;

    let mut result = Selection::new();
    let mut inner_of: SideTable<VertId> = SideTable::new(region_verts.len(), mesh.vert_capacity());
    for (&v, &p) in region_verts.iter().zip(&targets) {
        if is_boundary(v) {
            let (spoke, w) = mesh.make_edge_vert(v, p)?;
            inner_of.insert(v.index(), w);
            result.verts.push(w);
            result.edges.push(spoke);
        } else {
            mesh.place(v, p);
        }
    }
    // Interior vertices are their own inner vertex.
    let inner = |v: VertId| inner_of.get(v.index()).copied().unwrap_or(v);
    let mut rebuilt = Vec::new();
    for &f in &faces {
        if !mesh.face_verts(f).any(is_boundary) {
            // Its vertices are interior: they moved only by `depth`.
            if depth != 0.0 {
                mesh.refresh_normal(f);
            }
            result.faces.push(f);
            continue;
        }
        let ring: Vec<VertId> = mesh.face_verts(f).map(inner).collect();
        let remade = mesh.make_face(&ring)?;
        mesh.copy_face_attrs(f, remade);
        result.faces.push(remade);
        rebuilt.push(f);
    }
    for &e in &region_edges {
        let [a, b] = mesh.edge_verts(e);
        if !is_boundary(a) && !is_boundary(b) {
            continue;
        }
        if let Some(moved) = mesh.find_edge(inner(a), inner(b)) {
            mesh.copy_edge_attrs(e, moved);
            result.edges.push(moved);
        }
    }
    for b in &boundary {
        let quad = mesh.make_face(&[b.x, b.y, inner(b.y), inner(b.x)])?;
        mesh.copy_face_attrs(b.face, quad);
        result.faces.push(quad);
    }
    for f in rebuilt {
        mesh.kill_face(f)?;
    }
    if depth != 0.0 {
        // Interior vertices moved: faces outside the region may use them too.
        for &v in &region_verts {
            if !is_boundary(v) {
                for f in mesh.vert_faces(v).collect::<Vec<_>>() {
                    mesh.refresh_normal(f);
                }
            }
        }
    }
    // Old interior edges from the outline now bound nothing: the rebuilt
    // faces use their inner copies.
    for &e in &region_edges {
        let [a, b] = mesh.edge_verts(e);
        let from_outline = is_boundary(a) || is_boundary(b);
        if from_outline && !boundary_edge.contains(e.index()) && mesh.edge_face_count(e) == 0 {
            mesh.kill_edge(e)?;
        }
    }
    result.normalize();
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::ops::extrude::tests::{
        closed_and_consistent, consistently_wound, cube, grid,
    };
    use crate::kernel::{AttrValue, Domain, KernelError};

    fn counts(m: &Mesh) -> (usize, usize, usize) {
        (m.vert_count(), m.edge_count(), m.face_count())
    }

    /// The result face whose vertices are all new (the inner face).
    fn inner_faces(m: &Mesh, r: &Selection) -> Vec<FaceId> {
        r.faces
            .iter()
            .copied()
            .filter(|&f| m.face_verts(f).all(|v| r.verts.contains(&v)))
            .collect()
    }

    #[test]
    fn inset_quad_counts_and_geometry() {
        let mut m = grid(1, 1, 1.0);
        m.add_layer("mat", Domain::Face, AttrValue::Int(0)).unwrap();
        m.set_attr("mat", Domain::Face, 0, AttrValue::Int(3));
        let r = inset_faces(&mut m, &[FaceId::from_raw(0)], 0.1, 0.0).unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&m), (8, 12, 5));
        assert_eq!((r.verts.len(), r.edges.len(), r.faces.len()), (4, 8, 5));
        for &v in &r.verts {
            let p = m.position(v);
            assert!(
                (p.abs() - DVec3::new(0.4, 0.4, 0.0)).abs().max_element() < 1e-15,
                "{p}"
            );
        }
        let inner = inner_faces(&m, &r);
        assert_eq!(inner.len(), 1);
        assert!((m.face_area(inner[0]) - 0.64).abs() < 1e-12);
        let total: f64 = m.face_ids().map(|f| m.face_area(f)).sum();
        assert!((total - 1.0).abs() < 1e-12);
        for f in m.face_ids() {
            assert!(m.face_normal(f).abs_diff_eq(DVec3::Z, 1e-12));
            assert_eq!(
                m.attr("mat", Domain::Face, f.index()),
                Some(AttrValue::Int(3))
            );
        }
        assert!(consistently_wound(&m));
        for v in 0..4 {
            // Spokes run outer → inner.
            let spoke = m
                .vert_edges(VertId::from_raw(v))
                .find(|&e| r.edges.contains(&e))
                .unwrap();
            assert_eq!(m.edge_verts(spoke)[0], VertId::from_raw(v));
        }
    }

    #[test]
    fn inset_depth_moves_the_inner_face_along_its_normal() {
        let mut m = cube();
        let top = FaceId::from_raw(1);
        let r = inset_faces(&mut m, &[top], 0.5, -0.25).unwrap();
        m.validate().unwrap();
        assert!(closed_and_consistent(&m));
        for &v in &r.verts {
            let p = m.position(v);
            assert!(
                p.abs().abs_diff_eq(DVec3::new(0.5, 0.5, 0.75), 1e-12),
                "{p}"
            );
        }
    }

    #[test]
    fn inset_clamps_thickness_at_the_first_edge_event() {
        // A square inset past half its side collapses to its centre.
        let mut m = grid(1, 1, 1.0);
        let r = inset_faces(&mut m, &[FaceId::from_raw(0)], 0.7, 0.0).unwrap();
        m.validate().unwrap();
        for &v in &r.verts {
            assert!(m.position(v).length() < 1e-12);
        }
        // A 4 × 1 rectangle: the short edges vanish at 0.5, leaving a segment.
        let mut m = Mesh::new();
        let v: Vec<VertId> = [(-2.0, -0.5), (2.0, -0.5), (2.0, 0.5), (-2.0, 0.5)]
            .iter()
            .map(|&(x, y)| m.make_vert(DVec3::new(x, y, 0.0)))
            .collect();
        m.make_face(&v).unwrap();
        let r = inset_faces(&mut m, &[FaceId::from_raw(0)], 2.0, 0.0).unwrap();
        m.validate().unwrap();
        for &v in &r.verts {
            let p = m.position(v);
            assert!((p.x.abs() - 1.5).abs() < 1e-12 && p.y.abs() < 1e-12, "{p}");
        }
    }

    #[test]
    fn inset_triangle_shrinks_about_its_incentre() {
        // Right triangle (0,0), (4,0), (0,3): inradius 1, incentre (1, 1).
        let mut m = Mesh::new();
        let v: Vec<VertId> = [(0.0, 0.0), (4.0, 0.0), (0.0, 3.0)]
            .iter()
            .map(|&(x, y)| m.make_vert(DVec3::new(x, y, 0.0)))
            .collect();
        m.make_face(&v).unwrap();
        let r = inset_faces(&mut m, &[FaceId::from_raw(0)], 0.5, 0.0).unwrap();
        m.validate().unwrap();
        let incentre = DVec3::new(1.0, 1.0, 0.0);
        for (&outer, &inner) in v.iter().zip(&r.verts) {
            let expected = incentre.lerp(m.position(outer), 0.5);
            assert!(m.position(inner).distance(expected) < 1e-12);
        }
    }

    #[test]
    fn inset_degenerate_faces_without_nan() {
        let mut m = Mesh::new();
        let v: Vec<VertId> = [0.0, 1.0, 2.0, 3.0]
            .iter()
            .map(|&x| m.make_vert(DVec3::new(x, 0.0, 0.0)))
            .collect();
        let line = m.make_face(&v).unwrap();
        // A spike: the outline doubles back at (2, 0).
        let w: Vec<VertId> = [(0.0, 1.0), (2.0, 1.0), (0.0, 1.0 + 1e-14), (-1.0, 2.0)]
            .iter()
            .map(|&(x, y)| m.make_vert(DVec3::new(x, y, 0.0)))
            .collect();
        let spike = m.make_face(&w).unwrap();
        let r = inset_faces(&mut m, &[line, spike], 0.3, 0.1).unwrap();
        m.validate().unwrap();
        assert_eq!(r.faces.len(), 10);
        assert!(m.vert_ids().all(|v| m.position(v).is_finite()));
        // The collinear face has no normal: corners move towards the centroid.
        let first_inner = m.position(r.verts[0]);
        assert!(first_inner.abs_diff_eq(DVec3::new(0.3, 0.0, 0.0), 1e-12));
    }

    #[test]
    fn inset_neighbouring_faces_individually() {
        let mut m = grid(3, 3, 1.0);
        let r = inset_faces(
            &mut m,
            &[FaceId::from_raw(4), FaceId::from_raw(5)],
            0.2,
            0.0,
        )
        .unwrap();
        m.validate().unwrap();
        assert_eq!(m.face_count(), 9 - 2 + 10);
        assert_eq!(inner_faces(&m, &r).len(), 2);
        assert!(consistently_wound(&m));
        assert!(m.edge_ids().all(|e| m.edge_face_count(e) <= 2));
        for f in m.face_ids() {
            assert!(m.face_normal(f).abs_diff_eq(DVec3::Z, 1e-12));
        }
    }

    #[test]
    fn inset_region_on_a_2x2_grid_keeps_the_interior_vertex() {
        let mut m = grid(2, 2, 1.0);
        let faces: Vec<FaceId> = m.face_ids().collect();
        let centre = VertId::from_raw(4);
        let r = inset_region(&mut m, &faces, 0.1, 0.0).unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&m), (17, 28, 12));
        assert_eq!((r.verts.len(), r.edges.len(), r.faces.len()), (8, 20, 12));
        assert_eq!(m.position(centre), DVec3::ZERO);
        assert_eq!(m.vert_degree(centre), 4);
        for &v in &r.verts {
            let p = m.position(v);
            // Corners at (±0.9, ±0.9), edge midpoints at (0, ±0.9) / (±0.9, 0).
            assert!((p.x.abs().max(p.y.abs()) - 0.9).abs() < 1e-12, "{p}");
            assert!(p.x.abs() < 1e-12 || p.y.abs() < 1e-12 || (p.x.abs() - 0.9).abs() < 1e-12);
        }
        assert!(consistently_wound(&m));
        let total: f64 = m.face_ids().map(|f| m.face_area(f)).sum();
        assert!((total - 4.0).abs() < 1e-12);
        for f in m.face_ids() {
            assert!(m.face_normal(f).abs_diff_eq(DVec3::Z, 1e-12));
        }

        // Depth lifts the whole inner region, interior vertex included.
        let mut m = grid(2, 2, 1.0);
        let r = inset_region(&mut m, &faces, 0.1, 0.3).unwrap();
        m.validate().unwrap();
        assert_eq!(m.position(centre), DVec3::new(0.0, 0.0, 0.3));
        assert!(r.verts.iter().all(|&v| m.position(v).z == 0.3));
    }

    #[test]
    fn inset_region_of_a_few_faces_in_a_big_mesh_uses_hashed_sets() {
        // The 2×2 block at the centre of a 40×40 grid (sets hashed, not
        // bitmaps of the mesh) insets as the lone 2×2 grid does.
        let mut m = grid(40, 40, 1.0);
        let faces: Vec<FaceId> = m
            .face_ids()
            .filter(|&f| {
                m.face_verts(f)
                    .all(|v| m.position(v).abs().max_element() <= 1.0)
            })
            .collect();
        assert_eq!(faces.len(), 4);
        let before = counts(&m);
        let r = inset_region(&mut m, &faces, 0.1, 0.0).unwrap();
        m.validate().unwrap();
        assert_eq!((r.verts.len(), r.edges.len(), r.faces.len()), (8, 20, 12));
        assert_eq!(counts(&m), (before.0 + 8, before.1 + 16, before.2 + 8));
        for &v in &r.verts {
            let p = m.position(v);
            assert!((p.x.abs().max(p.y.abs()) - 0.9).abs() < 1e-12, "{p}");
        }
        assert!(consistently_wound(&m));
    }

    #[test]
    fn inset_region_at_depth_zero_leaves_the_interior_where_it_was() {
        // A bumpy 6×6 grid, some coordinates −0: at depth 0 only the
        // outline is measured, and the interior's targets are its own
        // positions plus zero (−0 becomes +0, as `p + 0·rate + n·0` does).
        let mut m = grid(6, 6, 1.0);
        let verts: Vec<VertId> = m.vert_ids().collect();
        for (k, &v) in verts.iter().enumerate() {
            let p = m.position(v);
            let z = if k % 5 == 0 {
                -0.0
            } else {
                0.2 * (p.x * 1.3).sin() * (p.y * 0.7).cos()
            };
            m.place(v, DVec3::new(if p.x == 0.0 { -0.0 } else { p.x }, p.y, z));
        }
        m.refresh_normals();
        let before: Vec<DVec3> = verts.iter().map(|&v| m.position(v)).collect();
        // The region: all but the first column of faces.
        let faces: Vec<FaceId> = m
            .face_ids()
            .filter(|&f| m.face_verts(f).all(|v| m.position(v).x > -3.0))
            .collect();
        let r = inset_region(&mut m, &faces, 0.05, 0.0).unwrap();
        m.validate().unwrap();
        let bits = |p: DVec3| p.to_array().map(f64::to_bits);
        let mut interior = 0;
        for (&v, &p) in verts.iter().zip(&before) {
            // Strictly inside the region's block x ∈ [−2, 3], y ∈ [−3, 3].
            if p.x > -2.0 && p.x < 3.0 && p.y.abs() < 3.0 {
                interior += 1;
                assert_eq!(bits(m.position(v)), bits(p + DVec3::ZERO), "{v:?}");
            } else {
                assert_eq!(bits(m.position(v)), bits(p), "outline and outside stay");
            }
        }
        assert_eq!(interior, 4 * 5);
        assert_eq!(
            r.verts.len(),
            2 * (5 + 6),
            "an inner copy per outline vertex"
        );
        assert!(consistently_wound(&m));
    }

    #[test]
    fn inset_region_across_a_fold_stays_closed() {
        // Top and front of the cube: the fold edge is interior to the region.
        let mut m = cube();
        let r = inset_region(
            &mut m,
            &[FaceId::from_raw(1), FaceId::from_raw(2)],
            0.25,
            0.0,
        )
        .unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&m), (14, 24, 12));
        assert!(closed_and_consistent(&m));
        let positions: Vec<DVec3> = r.verts.iter().map(|&v| m.position(v)).collect();
        // The fold's ends move along the fold, away from the x = ±1 sides.
        for p in [DVec3::new(0.75, -1.0, 1.0), DVec3::new(-0.75, -1.0, 1.0)] {
            assert!(
                positions.iter().any(|q| q.distance(p) < 1e-12),
                "{p} missing"
            );
        }
        // A top-only corner moves diagonally within the top.
        let corner = DVec3::new(0.75, 0.75, 1.0);
        assert!(positions.iter().any(|q| q.distance(corner) < 1e-12));
    }

    #[test]
    fn inset_refuses_bad_parameters_without_change() {
        let mut m = grid(1, 1, 1.0);
        let before = counts(&m);
        assert!(matches!(
            inset_faces(&mut m, &[FaceId::from_raw(0)], -0.1, 0.0),
            Err(OpError::Parameter {
                name: "thickness",
                ..
            })
        ));
        assert!(matches!(
            inset_region(&mut m, &[FaceId::from_raw(0)], 0.1, f64::NAN),
            Err(OpError::Parameter { name: "depth", .. })
        ));
        assert!(matches!(
            inset_faces(&mut m, &[FaceId::from_raw(0)], f64::INFINITY, 0.0),
            Err(OpError::Parameter { .. })
        ));
        assert_eq!(
            inset_region(
                &mut m,
                &[FaceId::from_raw(0), FaceId::from_raw(3)],
                0.1,
                0.0
            ),
            Err(OpError::Kernel(KernelError::Dead {
                domain: Domain::Face,
                index: 3
            }))
        );
        assert_eq!(counts(&m), before);
        m.validate().unwrap();
    }
}
