//! Extrusion: vertices into edges, edges into quads, faces into prisms
//! (seed 000 §3.3 "Modify" operators, §4.5.3 `ExtrudeVerts`, §4.6).
//!
//! Every operator copies the selected elements, joins each copy to its
//! original with a *side* element one dimension higher, and returns the
//! copies and the side elements in a [`Selection`] — the seed's
//! `ExtrudeVertsResult` / `ExtrudeFacesResult`. The seed's cube (§4.6.1) is
//! a chain of three of them:
//!
//! ```
//! use glam::DVec3;
//! use graftal::kernel::Mesh;
//! use graftal::kernel::ops::extrude::{extrude_edges, extrude_faces, extrude_verts, ExtrudeOffset};
//!
//! let mut mesh = Mesh::new();
//! let v = mesh.make_vert(DVec3::splat(-1.0));
//! let edge = extrude_verts(&mut mesh, &[v], ExtrudeOffset::Vector(2.0 * DVec3::X)).unwrap();
//! let quad = extrude_edges(&mut mesh, &edge.edges, ExtrudeOffset::Vector(2.0 * DVec3::Y)).unwrap();
//! extrude_faces(&mut mesh, &quad.faces, true, ExtrudeOffset::Vector(2.0 * DVec3::Z)).unwrap();
//! assert_eq!((mesh.vert_count(), mesh.edge_count(), mesh.face_count()), (8, 12, 6));
//! ```
//!
//! The seed's operators leave the copy where the original is and let the
//! caller translate the result; [`ExtrudeOffset`] folds that translation in
//! (and adds "along the normal", which a rule cannot easily express itself).
//!
//! Winding: a new face is wound so that it agrees with the face it grows
//! from across every shared edge (each edge is run once in each direction).
//! Orientation is topological, so an extrusion moved *against* the normal
//! yields an inside-out prism, as in Blender; `faces::recompute_normals`
//! fixes that.
//!
//! Attributes: a copied vertex, edge or face copies its original's
//! attributes; side faces copy the attributes of the face they grow from.

use glam::DVec3;
use rustc_hash::{FxHashMap, FxHashSet};

use super::{canonical, OpError, Selection};
use crate::kernel::{EdgeId, FaceId, Mesh, VertId};

/// How the extruded copy is moved right after extrusion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ExtrudeOffset {
    /// The copy stays on the original (the seed's behaviour; translate the
    /// result afterwards).
    None,
    /// Every new vertex moves by this vector.
    Vector(DVec3),
    /// Every new vertex moves this far along a normal: the face normal for
    /// individual faces; the *shell* normal for a face region (the
    /// normalised mean of the unit normals of the region faces around the
    /// vertex, lengthened by 1 / (mean cosine to those normals) so each flat
    /// part of the region moves exactly this distance — Blender's "even
    /// thickness"); the vertex normal (normalised mean of the unit normals of
    /// all faces around it) for vertices and edges, which do not move when
    /// they have no faces.
    Normal(f64),
}

impl ExtrudeOffset {
    fn check(self) -> Result<(), OpError> {
        let finite = match self {
            ExtrudeOffset::None => true,
            ExtrudeOffset::Vector(v) => v.is_finite(),
            ExtrudeOffset::Normal(d) => d.is_finite(),
        };
        if finite {
            Ok(())
        } else {
            Err(OpError::parameter(
                "offset",
                format!("{self:?} is not finite"),
            ))
        }
    }

    /// The displacement of a vertex whose relevant unit normal is `normal`
    /// (zero when it has none).
    fn displacement(self, normal: impl FnOnce() -> DVec3) -> DVec3 {
        match self {
            ExtrudeOffset::None => DVec3::ZERO,
            ExtrudeOffset::Vector(v) => v,
            ExtrudeOffset::Normal(d) => normal() * d,
        }
    }
}

/// The shell factor never exceeds 1 / this: faces folded almost flat onto
/// each other would otherwise send the vertex arbitrarily far.
const MIN_SHELL_COSINE: f64 = 0.1;

/// The even-thickness direction for unit normals `normals` (zero ones are
/// ignored): the normalised mean, divided by the mean cosine between it and
/// each normal, so that a vertex moved by `d` times it keeps every face plane
/// `d` away from the original one where the faces are flat.
fn shell_direction(normals: &[DVec3]) -> DVec3 {
    let n = normals.iter().sum::<DVec3>().normalize_or_zero();
    let used: Vec<f64> = normals
        .iter()
        .filter(|m| **m != DVec3::ZERO)
        .map(|m| m.dot(n))
        .collect();
    if n == DVec3::ZERO || used.is_empty() {
        return DVec3::ZERO;
    }
    let mean_cosine = used.iter().sum::<f64>() / used.len() as f64;
    n / mean_cosine.max(MIN_SHELL_COSINE)
}

/// Refuses a displacement that would put a vertex at a non-finite position
/// (huge offsets overflow), before anything is changed.
fn check_targets(targets: &[DVec3]) -> Result<(), OpError> {
    if targets.iter().all(|p| p.is_finite()) {
        Ok(())
    } else {
        Err(OpError::parameter(
            "offset",
            "moves a vertex to a non-finite position",
        ))
    }
}

/// ExtrudeVerts (seed §4.5.3, code 4.8): each vertex gets a new vertex
/// joined to it by a new wire edge (`make_edge_vert`, so each new edge runs
/// from the original to the copy). With [`ExtrudeOffset::Normal`] the copy
/// moves along the vertex normal (no move without faces).
///
/// Result: the new vertices and the new edges.
pub fn extrude_verts(
    mesh: &mut Mesh,
    verts: &[VertId],
    offset: ExtrudeOffset,
) -> Result<Selection, OpError> {
    offset.check()?;
    let verts = canonical(verts);
    for &v in &verts {
        mesh.check_vert(v)?;
    }
    let targets: Vec<DVec3> = verts
        .iter()
        .map(|&v| mesh.position(v) + offset.displacement(|| mesh.vert_normal_from_positions(v)))
        .collect();
    check_targets(&targets)?;

    let mut result = Selection::new();
    for (&v, &target) in verts.iter().zip(&targets) {
        let (edge, copy) = mesh.make_edge_vert(v, target)?;
        result.verts.push(copy);
        result.edges.push(edge);
    }
    result.normalize();
    Ok(result)
}

/// ExtrudeEdges (seed §4.5.1, code 4.6; §4.6.1): each edge (a, b) becomes a
/// quad a, b, b', a'. A vertex shared by several selected edges is copied
/// once (the seed's `EXTRUDED_VERT` flag), so a chain of edges extrudes into
/// a strip. Each copy is joined to its original by a side edge running
/// original → copy.
///
/// Winding: an edge used by exactly one face gets a quad that runs the edge
/// opposite to that face, so the strip continues the surface consistently
/// (and copies that face's attributes); a wire edge, or one with several
/// faces, gets a → b → b' → a' with `[a, b] = edge_verts(e)`.
///
/// Result: the new vertices, the new edges (copies and side edges), the
/// new faces.
pub fn extrude_edges(
    mesh: &mut Mesh,
    edges: &[EdgeId],
    offset: ExtrudeOffset,
) -> Result<Selection, OpError> {
    offset.check()?;
    let edges = canonical(edges);
    for &e in &edges {
        mesh.check_edge(e)?;
    }
    let verts = canonical(
        &edges
            .iter()
            .flat_map(|&e| mesh.edge_verts(e))
            .collect::<Vec<_>>(),
    );
    let targets: Vec<DVec3> = verts
        .iter()
        .map(|&v| mesh.position(v) + offset.displacement(|| mesh.vert_normal_from_positions(v)))
        .collect();
    check_targets(&targets)?;
    // Winding and attribute source of each quad, decided on the unchanged mesh.
    let plans: Vec<(EdgeId, [VertId; 2], Option<FaceId>)> = edges
        .iter()
        .map(|&e| {
            let loops: Vec<_> = mesh.edge_loops(e).collect();
            if let [only] = loops[..] {
                let start = mesh.lp(only).vert;
                let end = mesh.edge_other_vert(e, start);
                (e, [end, start], Some(mesh.lp(only).face))
            } else {
                (e, mesh.edge_verts(e), None)
            }
        })
        .collect();

    let mut result = Selection::new();
    let mut copy_of = FxHashMap::default();
    for (&v, &target) in verts.iter().zip(&targets) {
        let (side, copy) = mesh.make_edge_vert(v, target)?;
        copy_of.insert(v, copy);
        result.verts.push(copy);
        result.edges.push(side);
    }
    // Every end of a selected edge was copied.
    let copy = |v: VertId| copy_of[&v];
    for (e, [a, b], neighbour) in plans {
        let quad = mesh.make_face(&[a, b, copy(b), copy(a)])?;
        if let Some(f) = neighbour {
            mesh.copy_face_attrs(f, quad);
        }
        if let Some(top) = mesh.find_edge(copy(a), copy(b)) {
            mesh.copy_edge_attrs(e, top);
            result.edges.push(top);
        }
        result.faces.push(quad);
    }
    result.normalize();
    Ok(result)
}

/// ExtrudeFaces, individual (seed §4.6.1 code 4.9, §4.6.2 the chair's legs):
/// each face is extruded on its own — its own copy of every vertex (joined
/// by a side edge original → copy), a top face copying the original's ring,
/// winding and attributes, and a side quad per edge.
///
/// `keep_original = false` kills the original face (its edges and vertices
/// stay as the base of the side quads): an open-bottom prism attached to the
/// surrounding mesh, the way a leg grows out of a seat. `keep_original =
/// true` keeps it but reversed, closing the prism outward — the seed's cube:
/// a quad extruded keeping it is a closed box.
///
/// Side quads run each top edge opposite to the top face, so the prism is
/// consistently wound, outward when it grows along the normal. With
/// [`ExtrudeOffset::Normal`] each top moves along its own face normal.
///
/// Result: the new vertices (the top copies), the new edges, the new faces
/// (tops and sides).
pub fn extrude_faces(
    mesh: &mut Mesh,
    faces: &[FaceId],
    keep_original: bool,
    offset: ExtrudeOffset,
) -> Result<Selection, OpError> {
    offset.check()?;
    let faces = canonical(faces);
    for &f in &faces {
        mesh.check_face(f)?;
    }
    // Rings, their edges and the copies' positions, from the unchanged mesh,
    // in flat arrays (face k's corners are `starts[k]..starts[k + 1]`).
    let corners: usize = faces.iter().map(|&f| mesh.face_len(f)).sum();
    let (mut ring, mut ring_edges) = (Vec::with_capacity(corners), Vec::with_capacity(corners));
    let mut targets = Vec::with_capacity(corners);
    let mut starts = Vec::with_capacity(faces.len() + 1);
    starts.push(0);
    for &f in &faces {
        let shift = offset.displacement(|| mesh.compute_face_normal(f));
        for l in mesh.face_loops(f) {
            let v = mesh.loop_vert(l);
            ring.push(v);
            ring_edges.push(mesh.loop_edge(l));
            targets.push(mesh.position(v) + shift);
        }
        starts.push(ring.len());
    }
    check_targets(&targets)?;

    // Every face adds n vertices, 2n edges, n + 1 faces and 5n loops.
    mesh.reserve(corners, 2 * corners, 5 * corners, corners + faces.len());
    let mut result = Selection::new();
    result.verts.reserve(corners);
    result.edges.reserve(2 * corners);
    result.faces.reserve(corners + faces.len());
    let (mut copies, mut top_edges) = (Vec::new(), Vec::new());
    let mut sides = Vec::new();
    for (k, &face) in faces.iter().enumerate() {
        let span = starts[k]..starts[k + 1];
        let (ring, ring_edges) = (&ring[span.clone()], &ring_edges[span.clone()]);
        let n = ring.len();
        copies.clear();
        sides.clear();
        for (&v, &target) in ring.iter().zip(&targets[span]) {
            let (side, copy) = mesh.make_edge_vert(v, target)?;
            copies.push(copy);
            sides.push(side);
            result.edges.push(side);
        }
        let top = mesh.make_face(&copies)?;
        mesh.copy_face_attrs(face, top);
        result.faces.push(top);
        // The top's loop i runs copy_i → copy_i+1 along its new edge i.
        top_edges.clear();
        top_edges.extend(mesh.face_loops(top).map(|l| mesh.loop_edge(l)));
        for i in 0..n {
            let j = (i + 1) % n;
            mesh.copy_edge_attrs(ring_edges[i], top_edges[i]);
            result.edges.push(top_edges[i]);
            // The top runs copy_i → copy_j; the side runs it back, then down
            // and along the original edge i → j like the original face.
            let side = mesh.make_face_on_edges(
                &[copies[j], copies[i], ring[i], ring[j]],
                &[top_edges[i], sides[i], ring_edges[i], sides[j]],
            )?;
            mesh.copy_face_attrs(face, side);
            result.faces.push(side);
        }
        if keep_original {
            mesh.reverse_face(face)?;
        } else {
            mesh.kill_face(face)?;
        }
        result.verts.extend_from_slice(&copies);
    }
    result.normalize();
    Ok(result)
}

/// ExtrudeFaceRegion (seed §4.6.2, the chair's seat and back): the faces
/// are extruded together. Every region vertex is copied once and the region
/// faces are copied onto the copies (interior edges are copied with them);
/// only the region's *boundary* edges — used by exactly one region face —
/// get side quads, and only boundary vertices get side edges.
///
/// `keep_original = false` kills the original region faces, then the
/// region-interior edges and vertices left unused: extruding the top of a
/// closed box gives a taller closed box. `keep_original = true` keeps the
/// originals, reversed: an open region becomes a closed shell (the seat).
///
/// With [`ExtrudeOffset::Normal`] each vertex moves along its shell
/// direction (see there). A vertex where the region only touches itself
/// (two region faces sharing just that vertex) is still copied once, so
/// the copy is shared, as in Blender.
///
/// Result: the new vertices, the new edges (copies and side edges), the new
/// faces (region copies and side quads).
pub fn extrude_face_region(
    mesh: &mut Mesh,
    faces: &[FaceId],
    keep_original: bool,
    offset: ExtrudeOffset,
) -> Result<Selection, OpError> {
    offset.check()?;
    let faces = canonical(faces);
    for &f in &faces {
        mesh.check_face(f)?;
    }
    // Hashed side tables keep the cost proportional to the region, not
    // to the mesh.
    let in_region: FxHashSet<FaceId> = faces.iter().copied().collect();
    let region_edges = canonical(
        &faces
            .iter()
            .flat_map(|&f| mesh.face_edges(f))
            .collect::<Vec<_>>(),
    );
    let region_verts = canonical(
        &faces
            .iter()
            .flat_map(|&f| mesh.face_verts(f))
            .collect::<Vec<_>>(),
    );
    // Boundary edges with the direction x → y their one region face runs
    // them in, and that face (the side quad's attribute source).
    let mut boundary: Vec<(EdgeId, VertId, VertId, FaceId)> = Vec::new();
    let mut on_boundary: FxHashSet<VertId> = FxHashSet::default();
    let mut boundary_edge: FxHashSet<EdgeId> = FxHashSet::default();
    for &e in &region_edges {
        let region_loops: Vec<_> = mesh
            .edge_loops(e)
            .filter(|&l| in_region.contains(&mesh.lp(l).face))
            .collect();
        if let [only] = region_loops[..] {
            let x = mesh.lp(only).vert;
            let y = mesh.edge_other_vert(e, x);
            boundary.push((e, x, y, mesh.lp(only).face));
            boundary_edge.insert(e);
            on_boundary.insert(x);
            on_boundary.insert(y);
        }
    }
    let mut face_normal: FxHashMap<FaceId, DVec3> = FxHashMap::default();
    if matches!(offset, ExtrudeOffset::Normal(_)) {
        for &f in &faces {
            face_normal.insert(f, mesh.compute_face_normal(f));
        }
    }
    let targets: Vec<DVec3> = region_verts
        .iter()
        .map(|&v| {
            let shift = offset.displacement(|| {
                let normals: Vec<DVec3> = mesh
                    .vert_faces(v)
                    .filter_map(|f| face_normal.get(&f).copied())
                    .collect();
                shell_direction(&normals)
            });
            mesh.position(v) + shift
        })
        .collect();
    check_targets(&targets)?;

    let mut result = Selection::new();
    let mut copy_of = FxHashMap::default();
    for (&v, &target) in region_verts.iter().zip(&targets) {
        let copy = if on_boundary.contains(&v) {
            let (side, copy) = mesh.make_edge_vert(v, target)?;
            result.edges.push(side);
            copy
        } else {
            let copy = mesh.make_vert(target);
            mesh.copy_vert_attrs(v, copy);
            copy
        };
        copy_of.insert(v, copy);
        result.verts.push(copy);
    }
    // Every region vertex was copied.
    let copy = |v: VertId| copy_of[&v];
    for &f in &faces {
        let ring: Vec<VertId> = mesh.face_verts(f).map(copy).collect();
        let top = mesh.make_face(&ring)?;
        mesh.copy_face_attrs(f, top);
        result.faces.push(top);
    }
    for &e in &region_edges {
        let [a, b] = mesh.edge_verts(e);
        if let Some(top_edge) = mesh.find_edge(copy(a), copy(b)) {
            mesh.copy_edge_attrs(e, top_edge);
            result.edges.push(top_edge);
        }
    }
    for &(_, x, y, f) in &boundary {
        // The region copy runs x' → y'; the side quad runs it back, down, and
        // x → y like the region face (opposite to the outer neighbour).
        let side = mesh.make_face(&[copy(y), copy(x), x, y])?;
        mesh.copy_face_attrs(f, side);
        result.faces.push(side);
    }
    if keep_original {
        for &f in &faces {
            mesh.reverse_face(f)?;
        }
    } else {
        for &f in &faces {
            mesh.kill_face(f)?;
        }
        // Interior edges and vertices belonged to the region only; with its
        // faces gone they would dangle inside the new solid.
        for &e in &region_edges {
            if !boundary_edge.contains(&e) && mesh.edge_face_count(e) == 0 {
                mesh.kill_edge(e)?;
            }
        }
        for &v in &region_verts {
            if !on_boundary.contains(&v) && mesh.vert_degree(v) == 0 {
                mesh.kill_vert(v)?;
            }
        }
    }
    result.normalize();
    Ok(result)
}

#[cfg(test)]
pub(crate) mod tests {
    //! Also home of the small mesh builders and checks the sibling operator
    //! tests share (cube, grid, signed volume, consistent winding).
    use super::*;
    use crate::kernel::{AttrValue, Domain, KernelError};

    /// Axis-aligned cube of side 2 centred at the origin, wound outward.
    /// Vertex `i` has coordinates (±1, ±1, ±1) from the bits of `i` (x = bit
    /// 0); faces in order −z, +z, −y, +y, −x, +x.
    pub(crate) fn cube() -> Mesh {
        let mut m = Mesh::new();
        let v: Vec<VertId> = (0..8)
            .map(|i| {
                let bit = |b: u32| if i & (1 << b) != 0 { 1.0 } else { -1.0 };
                m.make_vert(DVec3::new(bit(0), bit(1), bit(2)))
            })
            .collect();
        for ring in [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ] {
            m.make_face(&ring.map(|i| v[i])).unwrap();
        }
        m.validate().unwrap();
        m
    }

    /// An `nx` × `ny` grid of square cells of side `cell` in z = 0, centred
    /// at the origin, every face wound counter-clockwise (+z). Vertex (i, j)
    /// is `j * (nx + 1) + i`; faces row by row.
    pub(crate) fn grid(nx: usize, ny: usize, cell: f64) -> Mesh {
        let mut m = Mesh::new();
        let (w, h) = (nx as f64 * cell, ny as f64 * cell);
        let mut v = Vec::new();
        for j in 0..=ny {
            for i in 0..=nx {
                let p = DVec3::new(i as f64 * cell - w / 2.0, j as f64 * cell - h / 2.0, 0.0);
                v.push(m.make_vert(p));
            }
        }
        let at = |i: usize, j: usize| v[j * (nx + 1) + i];
        for j in 0..ny {
            for i in 0..nx {
                m.make_face(&[at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)])
                    .unwrap();
            }
        }
        m.validate().unwrap();
        m
    }

    /// Signed volume enclosed by the faces (divergence theorem over fan
    /// triangles): positive for a closed, outward-wound shell.
    pub(crate) fn signed_volume(m: &Mesh) -> f64 {
        m.face_ids()
            .map(|f| {
                let p = m.face_positions(f);
                (1..p.len() - 1)
                    .map(|i| p[0].dot(p[i].cross(p[i + 1])))
                    .sum::<f64>()
                    / 6.0
            })
            .sum()
    }

    /// Every edge shared by two faces is run once in each direction.
    pub(crate) fn consistently_wound(m: &Mesh) -> bool {
        m.edge_ids().all(|e| {
            let loops: Vec<_> = m.edge_loops(e).collect();
            loops.len() != 2 || m.lp(loops[0]).vert != m.lp(loops[1]).vert
        })
    }

    /// Closed 2-manifold, consistently wound: every edge has exactly two faces.
    pub(crate) fn closed_and_consistent(m: &Mesh) -> bool {
        m.edge_ids().all(|e| m.edge_face_count(e) == 2) && consistently_wound(m)
    }

    fn counts(m: &Mesh) -> (usize, usize, usize) {
        (m.vert_count(), m.edge_count(), m.face_count())
    }

    fn close(a: DVec3, b: DVec3) -> bool {
        a.distance(b) < 1e-12
    }

    /// The seed's code 4.9 literally: extrude, then translate the result.
    #[test]
    fn seed_cube_by_extrusion_from_one_vertex() {
        let mut m = Mesh::new();
        let translate = |m: &mut Mesh, verts: &[VertId], by: DVec3| {
            for &v in verts {
                m.place(v, m.position(v) + by);
            }
            m.refresh_normals();
        };
        let vert = m.make_vert(DVec3::splat(-1.0));
        let ev = extrude_verts(&mut m, &[vert], ExtrudeOffset::None).unwrap();
        m.validate().unwrap();
        assert_eq!((ev.verts.len(), ev.edges.len(), ev.faces.len()), (1, 1, 0));
        translate(&mut m, &ev.verts, DVec3::new(2.0, 0.0, 0.0));
        let ee = extrude_edges(&mut m, &ev.edges, ExtrudeOffset::None).unwrap();
        m.validate().unwrap();
        assert_eq!((ee.verts.len(), ee.edges.len(), ee.faces.len()), (2, 3, 1));
        translate(&mut m, &ee.verts, DVec3::new(0.0, 2.0, 0.0));
        assert!(close(m.face_normal(ee.faces[0]), DVec3::Z));
        let ef = extrude_faces(&mut m, &ee.faces, true, ExtrudeOffset::None).unwrap();
        m.validate().unwrap();
        assert_eq!((ef.verts.len(), ef.edges.len(), ef.faces.len()), (4, 8, 5));
        translate(&mut m, &ef.verts, DVec3::new(0.0, 0.0, 2.0));

        assert_eq!(counts(&m), (8, 12, 6));
        assert!(closed_and_consistent(&m));
        assert!((signed_volume(&m) - 8.0).abs() < 1e-12);
        for f in m.face_ids() {
            // Outward: each face normal points away from the cube's centre.
            assert!(m.face_normal(f).dot(m.face_center(f)) > 0.99, "{f} inward");
        }
        for v in m.vert_ids() {
            assert!(m.position(v).abs().abs_diff_eq(DVec3::ONE, 1e-12));
        }

        // Folding the translations into the offsets gives the same cube.
        let mut m2 = Mesh::new();
        let vert = m2.make_vert(DVec3::splat(-1.0));
        let ev = extrude_verts(&mut m2, &[vert], ExtrudeOffset::Vector(2.0 * DVec3::X)).unwrap();
        let ee = extrude_edges(&mut m2, &ev.edges, ExtrudeOffset::Vector(2.0 * DVec3::Y)).unwrap();
        extrude_faces(&mut m2, &ee.faces, true, ExtrudeOffset::Normal(2.0)).unwrap();
        m2.validate().unwrap();
        let positions = |m: &Mesh| m.vert_ids().map(|v| m.position(v)).collect::<Vec<_>>();
        assert_eq!(positions(&m), positions(&m2));
        assert!((signed_volume(&m2) - 8.0).abs() < 1e-12);
    }

    #[test]
    fn extrude_region_on_cube_top_gives_a_taller_closed_box() {
        for offset in [ExtrudeOffset::Vector(DVec3::Z), ExtrudeOffset::Normal(1.0)] {
            let mut m = cube();
            let top = FaceId::from_raw(1);
            let r = extrude_face_region(&mut m, &[top], false, offset).unwrap();
            m.validate().unwrap();
            assert_eq!(counts(&m), (12, 20, 10));
            assert_eq!((r.verts.len(), r.edges.len(), r.faces.len()), (4, 8, 5));
            assert!(closed_and_consistent(&m));
            assert!((signed_volume(&m) - 12.0).abs() < 1e-12);
            assert!(!m.contains_face(top));
            for &v in &r.verts {
                assert_eq!(m.position(v).z, 2.0);
            }
        }
    }

    #[test]
    fn extrude_region_removes_interior_edges_and_verts_unless_kept() {
        // 2 × 2 grid: 9 verts, 12 edges, 4 faces; the centre and its four
        // spokes are interior.
        let mut m = grid(2, 2, 1.0);
        let faces: Vec<FaceId> = m.face_ids().collect();
        let r =
            extrude_face_region(&mut m, &faces, false, ExtrudeOffset::Vector(DVec3::Z)).unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&m), (17, 28, 12));
        assert_eq!((r.verts.len(), r.edges.len(), r.faces.len()), (9, 20, 12));
        assert!(
            !m.contains_vert(VertId::from_raw(4)),
            "the interior centre is removed"
        );
        assert!(consistently_wound(&m));

        let mut m = grid(2, 2, 1.0);
        let r = extrude_face_region(&mut m, &faces, true, ExtrudeOffset::Vector(DVec3::Z)).unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&m), (18, 32, 16));
        assert_eq!(r.faces.len(), 12);
        assert!(closed_and_consistent(&m));
        assert!((signed_volume(&m) - 4.0).abs() < 1e-12);
    }

    /// The chair of §4.6.2: the seat is the whole 3 × 3 grid extruded as a
    /// region keeping the original, the legs are its corner faces extruded
    /// individually downward, the back the rear row extruded up.
    #[test]
    fn seed_chair_is_closed_and_outward() {
        let mut m = grid(3, 3, 1.0 / 3.0);
        let faces: Vec<FaceId> = m.face_ids().collect();
        let corner = |m: &Mesh, f: FaceId| {
            let c = m.face_center(f);
            c.x.abs() > 0.01 && c.y.abs() > 0.01
        };
        let legs: Vec<FaceId> = faces.iter().copied().filter(|&f| corner(&m, f)).collect();
        assert_eq!(legs.len(), 4);
        let seat =
            extrude_face_region(&mut m, &faces, true, ExtrudeOffset::Vector(0.05 * DVec3::Z))
                .unwrap();
        m.validate().unwrap();
        assert!(closed_and_consistent(&m));
        assert!((signed_volume(&m) - 0.05).abs() < 1e-12);
        extrude_faces(&mut m, &legs, false, ExtrudeOffset::Vector(-0.5 * DVec3::Z)).unwrap();
        m.validate().unwrap();
        assert!(closed_and_consistent(&m));
        let back: Vec<FaceId> = seat
            .faces
            .iter()
            .copied()
            .filter(|&f| {
                let c = m.face_center(f);
                c.y < -0.5 / 3.0 && c.z > 0.05 / 1.5 && m.face_normal(f).z > 0.5
            })
            .collect();
        assert_eq!(back.len(), 3);
        extrude_face_region(&mut m, &back, false, ExtrudeOffset::Vector(0.5 * DVec3::Z)).unwrap();
        m.validate().unwrap();
        assert!(closed_and_consistent(&m));
        let area = 1.0 / 9.0;
        let expected = 0.05 + 4.0 * area * 0.5 + 3.0 * area * 0.5;
        assert!((signed_volume(&m) - expected).abs() < 1e-12);
    }

    #[test]
    fn extrude_faces_individually_gives_each_face_its_own_copy() {
        // Two quads sharing an edge.
        let mut m = grid(2, 1, 1.0);
        let faces: Vec<FaceId> = m.face_ids().collect();
        let r = extrude_faces(&mut m, &faces, false, ExtrudeOffset::Normal(1.0)).unwrap();
        m.validate().unwrap();
        assert_eq!((r.verts.len(), r.edges.len(), r.faces.len()), (8, 16, 10));
        assert_eq!(counts(&m), (14, 23, 10));
        let tops: Vec<FaceId> = r
            .faces
            .iter()
            .copied()
            .filter(|&f| m.face_normal(f).z > 0.5)
            .collect();
        assert_eq!(tops.len(), 2);
        let ring = |f: FaceId| m.face_verts(f).collect::<Vec<_>>();
        assert!(ring(tops[0]).iter().all(|v| !ring(tops[1]).contains(v)));
        // The shared base edge now carries the two facing walls, one per prism.
        let shared = m
            .find_edge(VertId::from_raw(1), VertId::from_raw(4))
            .unwrap();
        assert_eq!(m.edge_face_count(shared), 2);
        assert!(consistently_wound(&m));
        for &v in &r.verts {
            assert_eq!(m.position(v).z, 1.0);
        }

        // Kept originals close each prism: two unit boxes.
        let mut m = grid(2, 1, 1.0);
        extrude_faces(&mut m, &faces, true, ExtrudeOffset::Normal(1.0)).unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&m), (14, 23, 12));
        assert!((signed_volume(&m) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn extrude_edges_winds_consistently_with_the_neighbour() {
        let mut m = grid(1, 1, 1.0);
        let f = FaceId::from_raw(0);
        // The left edge, run (0, 1) → (0, 0) by the face (v2 → v0).
        let left = m
            .find_edge(VertId::from_raw(2), VertId::from_raw(0))
            .unwrap();
        let r = extrude_edges(&mut m, &[left], ExtrudeOffset::Vector(-DVec3::X)).unwrap();
        m.validate().unwrap();
        assert_eq!((r.verts.len(), r.edges.len(), r.faces.len()), (2, 3, 1));
        let quad = r.faces[0];
        assert!(consistently_wound(&m));
        assert!(close(m.face_normal(quad), m.face_normal(f)));
        let ring: Vec<VertId> = m.face_verts(quad).collect();
        assert_eq!(&ring[..2], &[VertId::from_raw(0), VertId::from_raw(2)]);

        // Two edges meeting at a corner share the corner's copy.
        let mut m = grid(1, 1, 1.0);
        let bottom = m
            .find_edge(VertId::from_raw(0), VertId::from_raw(1))
            .unwrap();
        let right = m
            .find_edge(VertId::from_raw(1), VertId::from_raw(3))
            .unwrap();
        let r = extrude_edges(&mut m, &[right, bottom], ExtrudeOffset::Normal(1.0)).unwrap();
        m.validate().unwrap();
        assert_eq!((r.verts.len(), r.edges.len(), r.faces.len()), (3, 5, 2));
        assert!(consistently_wound(&m));
        for &v in &r.verts {
            assert_eq!(m.position(v).z, 1.0);
        }

        // A wire edge: a → b → b' → a'.
        let mut m = Mesh::new();
        let a = m.make_vert(DVec3::ZERO);
        let (e, b) = m.make_edge_vert(a, DVec3::X).unwrap();
        let r = extrude_edges(&mut m, &[e], ExtrudeOffset::Vector(DVec3::Y)).unwrap();
        m.validate().unwrap();
        let ring: Vec<VertId> = m.face_verts(r.faces[0]).collect();
        assert_eq!(ring, vec![a, b, r.verts[1], r.verts[0]]);
        assert!(close(m.face_normal(r.faces[0]), DVec3::Z));
    }

    #[test]
    fn extrude_verts_along_the_vertex_normal() {
        let mut m = cube();
        let lone = m.make_vert(DVec3::new(5.0, 0.0, 0.0));
        let r = extrude_verts(
            &mut m,
            &[VertId::from_raw(7), lone],
            ExtrudeOffset::Normal(3f64.sqrt()),
        )
        .unwrap();
        m.validate().unwrap();
        assert_eq!((r.verts.len(), r.edges.len()), (2, 2));
        assert!(close(m.position(r.verts[0]), DVec3::splat(2.0)));
        assert!(
            close(m.position(r.verts[1]), m.position(lone)),
            "no faces, no move"
        );
        assert_eq!(m.edge_verts(r.edges[0]), [VertId::from_raw(7), r.verts[0]]);
    }

    #[test]
    fn region_normal_offset_keeps_even_thickness() {
        // Top (+z) and front (−y) of the cube: the shared edge's ends move
        // diagonally so both copies stay flat, 0.5 out of their planes.
        let mut m = cube();
        let (top, front) = (FaceId::from_raw(1), FaceId::from_raw(2));
        let r =
            extrude_face_region(&mut m, &[top, front], false, ExtrudeOffset::Normal(0.5)).unwrap();
        m.validate().unwrap();
        assert!(closed_and_consistent(&m));
        let copies: Vec<FaceId> = r
            .faces
            .iter()
            .copied()
            .filter(|&f| m.face_normal(f).abs().max_element() > 0.999)
            .filter(|&f| {
                let n = m.face_normal(f);
                n.z > 0.999 || n.y < -0.999
            })
            .filter(|&f| m.face_verts(f).all(|v| r.verts.contains(&v)))
            .collect();
        assert_eq!(copies.len(), 2);
        for f in copies {
            let n = m.face_normal(f);
            for p in m.face_positions(f) {
                assert!((p.dot(n) - 1.5).abs() < 1e-12, "{p} not 1.5 along {n}");
            }
        }
    }

    #[test]
    fn extrusion_copies_attributes() {
        let mut m = grid(1, 1, 1.0);
        m.add_layer("mat", Domain::Face, AttrValue::Int(0)).unwrap();
        m.add_layer("r", Domain::Vert, AttrValue::Scalar(1.0))
            .unwrap();
        m.add_layer("crease", Domain::Edge, AttrValue::Scalar(0.0))
            .unwrap();
        m.set_attr("mat", Domain::Face, 0, AttrValue::Int(7));
        m.set_attr("r", Domain::Vert, 3, AttrValue::Scalar(0.5));
        let bottom = m
            .find_edge(VertId::from_raw(0), VertId::from_raw(1))
            .unwrap();
        m.set_attr(
            "crease",
            Domain::Edge,
            bottom.index(),
            AttrValue::Scalar(1.0),
        );
        let r = extrude_faces(
            &mut m,
            &[FaceId::from_raw(0)],
            false,
            ExtrudeOffset::Normal(1.0),
        )
        .unwrap();
        m.validate().unwrap();
        for &f in &r.faces {
            assert_eq!(
                m.attr("mat", Domain::Face, f.index()),
                Some(AttrValue::Int(7))
            );
        }
        let above_3 = m.position(VertId::from_raw(3)) + DVec3::Z;
        let top_of_3 = *r.verts.iter().find(|&&v| m.position(v) == above_3).unwrap();
        assert_eq!(
            m.attr("r", Domain::Vert, top_of_3.index()),
            Some(AttrValue::Scalar(0.5))
        );
        let top_bottom = m.find_edge(r.verts[0], r.verts[1]).unwrap();
        assert_eq!(
            m.attr("crease", Domain::Edge, top_bottom.index()),
            Some(AttrValue::Scalar(1.0))
        );
    }

    #[test]
    fn bad_input_is_refused_without_change() {
        let mut m = cube();
        let far = m.make_vert(DVec3::X * f64::MAX);
        let before = counts(&m);
        let nan = ExtrudeOffset::Vector(DVec3::new(f64::NAN, 0.0, 0.0));
        assert!(matches!(
            extrude_faces(&mut m, &[FaceId::from_raw(0)], false, nan),
            Err(OpError::Parameter { name: "offset", .. })
        ));
        assert!(matches!(
            extrude_face_region(
                &mut m,
                &[FaceId::from_raw(0)],
                false,
                ExtrudeOffset::Normal(f64::INFINITY)
            ),
            Err(OpError::Parameter { .. })
        ));
        assert!(matches!(
            extrude_verts(
                &mut m,
                &[VertId::from_raw(0), far],
                ExtrudeOffset::Vector(DVec3::X * f64::MAX)
            ),
            Err(OpError::Parameter { .. })
        ));
        assert_eq!(
            extrude_faces(
                &mut m,
                &[FaceId::from_raw(1), FaceId::from_raw(40)],
                true,
                ExtrudeOffset::None
            ),
            Err(OpError::Kernel(KernelError::Dead {
                domain: Domain::Face,
                index: 40
            }))
        );
        assert!(matches!(
            extrude_edges(&mut m, &[EdgeId::from_raw(99)], ExtrudeOffset::None),
            Err(OpError::Kernel(KernelError::Dead { .. }))
        ));
        assert_eq!(counts(&m), before);
        m.validate().unwrap();
        assert_eq!(
            extrude_face_region(&mut m, &[], false, ExtrudeOffset::None),
            Ok(Selection::new())
        );
    }

    #[test]
    fn input_order_and_duplicates_do_not_matter() {
        let run = |faces: &[FaceId]| {
            let mut m = grid(3, 1, 1.0);
            let r = extrude_face_region(&mut m, faces, false, ExtrudeOffset::Normal(1.0)).unwrap();
            m.validate().unwrap();
            let positions: Vec<DVec3> = m.vert_ids().map(|v| m.position(v)).collect();
            (r, positions)
        };
        assert_eq!(
            run(&[
                FaceId::from_raw(0),
                FaceId::from_raw(1),
                FaceId::from_raw(2)
            ]),
            run(&[
                FaceId::from_raw(2),
                FaceId::from_raw(0),
                FaceId::from_raw(1),
                FaceId::from_raw(0)
            ])
        );
    }
}
