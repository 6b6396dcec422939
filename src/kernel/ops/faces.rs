//! Face operators: make a face from a ring of edges, triangulate, reverse,
//! and recompute normals (DESIGN.md pillar 1: "make face, triangulate,
//! reverse, normals"; seed 000 §4.4 `MakeFace`/`MakeLoop` underneath).
//!
//! - [`make_face_from_edges`] accepts the ring's edges in any order (a rule
//!   selects them by condition, not by walk order) and orders them itself.
//! - [`triangulate`] replaces every n-gon by n − 2 triangles from the
//!   constrained Delaunay triangulation in [`crate::geom::polygon`],
//!   falling back to a fan when that cannot give a valid triangulation of
//!   the ring (degenerate outlines). Triangles are wound by ring order, not
//!   by geometry, so they always agree with the original face.
//! - [`reverse_faces`] flips windings; [`recompute_normals`] refreshes the
//!   stored normals and, on request, makes windings consistent and points
//!   closed shells outward.

use std::collections::VecDeque;

use glam::DVec3;
use rayon::prelude::*;
use rustc_hash::{FxHashMap, FxHashSet};

use super::{canonical, OpError, Selection};
use crate::geom::polygon;
use crate::kernel::{EdgeId, FaceId, KernelError, LoopId, Mesh, VertId};

/// One face on a closed ring of existing edges, given in any order.
///
/// The edges (deduplicated) must form exactly one simple cycle: at least 3
/// edges, every vertex touched by exactly two of them, all connected —
/// otherwise [`KernelError::NotARing`] names an offending edge and nothing
/// changes. Winding rule: the face starts at the first vertex
/// (`edge_verts(e)[0]`) of the lowest-id edge `e` and runs along `e` first.
/// A face already spanning the same ring is not looked for: the kernel
/// allows two faces on one ring (e.g. a double-sided sheet).
///
/// Result: the new face (its edges all existed).
pub fn make_face_from_edges(mesh: &mut Mesh, edges: &[EdgeId]) -> Result<Selection, OpError> {
    let edges = canonical(edges);
    for &e in &edges {
        mesh.check_edge(e)?;
    }
    if edges.len() < 3 {
        return Err(KernelError::TooFewVertices(edges.len()).into());
    }
    // The (at most two) ring edges at each vertex; a third is an error.
    let mut at: FxHashMap<VertId, Vec<EdgeId>> = FxHashMap::default();
    for &e in &edges {
        for v in mesh.edge_verts(e) {
            let list = at.entry(v).or_default();
            list.push(e);
            if list.len() > 2 {
                return Err(KernelError::NotARing(e).into());
            }
        }
    }
    let first = edges[0];
    let [start, mut vert] = mesh.edge_verts(first);
    let mut ordered = vec![first];
    let mut previous = first;
    while vert != start {
        let next = match at[&vert][..] {
            [a, b] => {
                if a == previous {
                    b
                } else {
                    a
                }
            }
            // A dead end: the chain through `previous` is open.
            _ => return Err(KernelError::NotARing(previous).into()),
        };
        ordered.push(next);
        vert = mesh.edge_other_vert(next, vert);
        previous = next;
    }
    if ordered.len() != edges.len() {
        // Closed, but other edges form further cycles.
        let mut used = ordered.clone();
        used.sort_unstable();
        let stray = edges
            .iter()
            .copied()
            .find(|e| used.binary_search(e).is_err())
            .unwrap_or(first);
        return Err(KernelError::NotARing(stray).into());
    }
    // The Euler operator starts at the end of ordered[0] not shared with
    // ordered[1]: `start`, as documented.
    let face = mesh.make_face_from_edges(&ordered)?;
    Ok(Selection::from_parts(Vec::new(), Vec::new(), vec![face]))
}

/// Triangulates every face of more than three vertices into n − 2
/// triangles ([`polygon::triangulate`]: constrained Delaunay on the face's
/// Newell plane, with its own fallbacks for degenerate outlines; should its
/// output ever not be a triangulation of the ring, a fan from the first
/// vertex is used instead). Each triangle copies the face's attributes and is
/// wound like it. A quad is split in place (it keeps its id on the triangle
/// with its first side; the other is a new face); a larger face is killed
/// and its triangles made anew. Every triangle starts at its lowest ring
/// position, so both ways list corners alike. Quads (nearly all faces)
/// decide their diagonal in parallel and split in closed form
/// ([`Mesh::split_quad`]); the outputs do not depend on the thread count.
///
/// Result: the triangles now covering the given faces (given triangles
/// included, untouched) and the new diagonal edges.
pub fn triangulate(mesh: &mut Mesh, faces: &[FaceId]) -> Result<Selection, OpError> {
    let faces = canonical(faces);
    // Every n-gon becomes n − 2 triangles and n − 3 diagonals; the arenas
    // grow once (the killed face and its loops leave slots to reuse).
    let (mut new_edges, mut new_loops, mut new_faces) = (0, 0, 0);
    for &f in &faces {
        mesh.check_face(f)?;
        let n = mesh.face_len(f);
        if n > 3 {
            new_edges += n - 3;
            new_loops += 2 * n - 6;
            new_faces += n - 3;
        }
    }
    mesh.reserve(0, new_edges, new_loops, new_faces);
    let mut result = Selection::new();
    let (mut ring, mut sides, mut points) = (Vec::new(), Vec::new(), Vec::new());
    let mut triangles = Vec::new();
    // Rings up to this size keep their diagonals in a list scanned
    // linearly; longer ones look each up in the disk cycles (cost of the
    // smaller degree) so a 100k-gon stays linear.
    const SCANNED_RING: u32 = 16;
    let mut diagonals: Vec<((u32, u32), EdgeId)> = Vec::new();
    // Each quad's diagonal, decided in parallel (a pure function of its
    // corners and its stored normal, fresh by construction: the one
    // `ring_triangles` picks, without gathering the ring), with its
    // pieces' normals from the same corners. Only a quad left undecided
    // has its pieces refreshed, in one parallel pass at the end.
    let view: &Mesh = mesh;
    let plans: Vec<Option<QuadPlan>> = faces
        .par_iter()
        .with_min_len(1024)
        .map(|&f| {
            let loops = view.quad_loops(f)?;
            let corners = loops.map(|l| view.position(view.loop_vert(l)));
            let normal = view.face_normal(f);
            let normal = (normal != DVec3::ZERO).then_some(normal);
            let decided = polygon::quad_split_along_0_2(&corners, normal)
                .map(|along_0_2| (along_0_2, Mesh::quad_piece_normals(&corners, along_0_2)));
            Some((loops, decided))
        })
        .collect();
    let quads = plans.iter().filter(|plan| plan.is_some()).count();
    let mut unrefreshed = Vec::new();
    result.faces.reserve(2 * quads);
    result.edges.reserve(quads);
    // The undecided quads split so far get their normals even if a later face fails.
    let split_all = || -> Result<(), OpError> {
        for (f, plan) in faces.into_iter().zip(plans) {
            if let Some((loops, decided)) = plan {
                // A quad splits in place along its diagonal (one edge, one face
                // and two loops, where rebuilding makes two faces and six
                // loops): it keeps its id on the triangle with its first side,
                // the new face gets its third, and both start at its first
                // corner, listed as a rebuild would list them. Only a quad
                // neither diagonal splits well takes the general path.
                let (g, e, made) = match decided {
                    Some((along_0_2, normals)) => {
                        mesh.split_quad_with_normals(f, loops, along_0_2, normals)
                    }
                    None => {
                        let corners = loops.map(|l| mesh.position(mesh.loop_vert(l)));
                        ring_triangles(&corners, &mut triangles);
                        let along_0_2 = triangles.contains(&[0, 1, 2]);
                        let (g, e, made) = mesh.split_quad_unrefreshed(f, loops, along_0_2);
                        unrefreshed.extend([f, g]);
                        (g, e, made)
                    }
                };
                if made {
                    result.edges.push(e);
                }
                result.faces.extend([f, g]);
                continue;
            }
            ring.clear();
            sides.clear();
            points.clear();
            for l in mesh.face_loops(f) {
                let v = mesh.loop_vert(l);
                ring.push(v);
                sides.push(mesh.loop_edge(l));
                points.push(mesh.position(v));
            }
            if ring.len() == 3 {
                result.faces.push(f);
                continue;
            }
            ring_triangles(&points, &mut triangles);
            let n = ring.len() as u32;
            diagonals.clear();
            for tri in &triangles {
                let corners = tri.map(|i| ring[i as usize]);
                // Ring sides are the face's own edges. Each diagonal is shared
                // by two triangles: the first looks it up (another face may
                // have made it) or makes it, the second finds it in
                // `diagonals` when the ring is small enough to scan.
                let mut edges = [sides[0]; 3];
                for k in 0..3 {
                    // Corners are ascending, so the closing side runs high to
                    // low: keys are (low, high).
                    let (i, j) = (tri[k], tri[(k + 1) % 3]);
                    let key = (i.min(j), i.max(j));
                    edges[k] = if key.1 == key.0 + 1 {
                        sides[key.0 as usize]
                    } else if key == (0, n - 1) {
                        sides[key.1 as usize]
                    } else if let Some(&(_, e)) = diagonals.iter().find(|d| d.0 == key) {
                        e
                    } else {
                        let (e, made) = mesh.find_or_make_edge(corners[k], corners[(k + 1) % 3])?;
                        if made {
                            result.edges.push(e);
                        }
                        if n <= SCANNED_RING {
                            diagonals.push((key, e));
                        }
                        e
                    };
                }
                let t = mesh.make_face_on_edges(&corners, &edges)?;
                mesh.copy_face_attrs(f, t);
                result.faces.push(t);
            }
            mesh.kill_face(f)?;
        }
        Ok(())
    };
    let outcome = split_all();
    mesh.refresh_normals_of(&unrefreshed);
    outcome?;
    result.normalize();
    Ok(result)
}

/// A quad's corner loops and, when its corners decide it, its diagonal
/// (along 0–2 or not) with its two pieces' normals.
type QuadPlan = ([LoopId; 4], Option<(bool, [DVec3; 2])>);

/// Triangles of a ring of `points` as ascending index triples. Listing a
/// triangle's corners in ring order winds it like the ring (each triangle
/// of a polygon triangulation cuts the boundary into three arcs in cyclic
/// order), whatever the geometry — so degenerate triangles cannot flip.
fn ring_triangles(points: &[DVec3], out: &mut Vec<[u32; 3]>) {
    out.clear();
    polygon::triangulate(points, out);
    for tri in out.iter_mut() {
        tri.sort_unstable();
    }
    if !is_triangulation_of_ring(out, points.len()) {
        out.clear();
        let n = points.len() as u32;
        out.extend((1..n - 1).map(|i| [0, i, i + 1]));
    }
}

/// Whether sorted triples form a triangulation of an n-ring: n − 2
/// triangles of distinct in-range corners, every ring edge used once and
/// every other edge (a diagonal) twice.
fn is_triangulation_of_ring(triangles: &[[u32; 3]], n: usize) -> bool {
    if triangles.len() + 2 != n {
        return false;
    }
    if let &[s, t] = triangles {
        // A quad: split along 0–2 or 1–3, the halves in either order.
        let halves = if s < t { [s, t] } else { [t, s] };
        return halves == [[0, 1, 2], [0, 2, 3]] || halves == [[0, 1, 3], [1, 2, 3]];
    }
    let n = n as u32;
    let mut sides: Vec<(u32, u32)> = Vec::with_capacity(3 * triangles.len());
    for &[a, b, c] in triangles {
        if !(a < b && b < c && c < n) {
            return false;
        }
        sides.extend([(a, b), (b, c), (a, c)]);
    }
    sides.sort_unstable();
    let mut i = 0;
    while i < sides.len() {
        let mut j = i;
        while j < sides.len() && sides[j] == sides[i] {
            j += 1;
        }
        let (a, b) = sides[i];
        let on_ring = b == a + 1 || (a == 0 && b == n - 1);
        if j - i != if on_ring { 1 } else { 2 } {
            return false;
        }
        i = j;
    }
    true
}

/// Flips the winding of every given face (all checked before any flips).
///
/// Result: empty (nothing is created).
pub fn reverse_faces(mesh: &mut Mesh, faces: &[FaceId]) -> Result<Selection, OpError> {
    let faces = canonical(faces);
    for &f in &faces {
        mesh.check_face(f)?;
    }
    for f in faces {
        mesh.reverse_face(f)?;
    }
    Ok(Selection::new())
}

/// Refreshes the stored normals of the given faces from their positions.
///
/// With `outside`, windings are also made consistent: the given faces fall
/// into components connected through edges used by exactly two given
/// faces; each component is walked breadth-first from its lowest face id,
/// flipping every neighbour that runs the shared edge the same way as the
/// face it was reached from. A *closed* component (each of its edges used
/// by exactly two of its faces) is then flipped as a whole if its signed
/// volume is negative, so it faces outward. An open component keeps the
/// winding of its lowest-id face: "outside" has no meaning there, and a
/// guess could flip a terrain upside down. A non-orientable component
/// (a Möbius strip) keeps the first winding the walk gives each face.
///
/// Result: the faces whose winding changed.
pub fn recompute_normals(
    mesh: &mut Mesh,
    faces: &[FaceId],
    outside: bool,
) -> Result<Selection, OpError> {
    let faces = canonical(faces);
    for &f in &faces {
        mesh.check_face(f)?;
    }
    for &f in &faces {
        mesh.refresh_normal(f);
    }
    if !outside {
        return Ok(Selection::new());
    }
    // Component (its seed face) of every given face reached so far; hashed
    // so the cost follows the selection, not the mesh.
    let given: FxHashSet<FaceId> = faces.iter().copied().collect();
    let mut component_of: FxHashMap<FaceId, FaceId> = FxHashMap::default();
    let mut flipped: FxHashSet<FaceId> = FxHashSet::default();
    let mut queue = VecDeque::new();
    for &seed in &faces {
        if component_of.contains_key(&seed) {
            continue;
        }
        component_of.insert(seed, seed);
        queue.push_back(seed);
        let mut component = Vec::new();
        while let Some(f) = queue.pop_front() {
            component.push(f);
            let loops: Vec<_> = mesh.face_loops(f).collect();
            for l in loops {
                let edge = mesh.lp(l).edge;
                let mut users = mesh
                    .edge_loops(edge)
                    .filter(|&o| given.contains(&mesh.lp(o).face));
                let (Some(x), Some(y), None) = (users.next(), users.next(), users.next()) else {
                    continue;
                };
                let other = if x == l { y } else { x };
                let g = mesh.lp(other).face;
                if component_of.contains_key(&g) {
                    continue;
                }
                component_of.insert(g, seed);
                // Same start vertex on the shared edge: same direction.
                if mesh.lp(other).vert == mesh.lp(l).vert {
                    mesh.reverse_face(g)?;
                    toggle(&mut flipped, g);
                }
                queue.push_back(g);
            }
        }
        let closed = component.iter().all(|&f| {
            mesh.face_edges(f).all(|e| {
                mesh.edge_faces(e)
                    .filter(|g| component_of.get(g) == Some(&seed))
                    .count()
                    == 2
            })
        });
        if closed && signed_volume(mesh, &component) < 0.0 {
            for &f in &component {
                mesh.reverse_face(f)?;
                toggle(&mut flipped, f);
            }
        }
    }
    let changed = faces.into_iter().filter(|f| flipped.contains(f)).collect();
    Ok(Selection::from_parts(Vec::new(), Vec::new(), changed))
}

fn toggle(set: &mut FxHashSet<FaceId>, f: FaceId) {
    if !set.remove(&f) {
        set.insert(f);
    }
}

/// Signed volume enclosed by closed `faces` (sum of fan tetrahedra about
/// the first vertex of the first face, which keeps the terms small far
/// from the origin); positive when wound outward.
fn signed_volume(mesh: &Mesh, faces: &[FaceId]) -> f64 {
    let Some(origin) = faces
        .first()
        .and_then(|&f| mesh.face_verts(f).next())
        .map(|v| mesh.position(v))
    else {
        return 0.0;
    };
    faces
        .iter()
        .map(|&f| {
            let p: Vec<DVec3> = mesh
                .face_verts(f)
                .map(|v| mesh.position(v) - origin)
                .collect();
            (1..p.len() - 1)
                .map(|i| p[0].dot(p[i].cross(p[i + 1])))
                .sum::<f64>()
        })
        .sum::<f64>()
        / 6.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::ops::extrude::tests::{
        closed_and_consistent, consistently_wound, cube, grid, signed_volume,
    };
    use crate::kernel::{AttrValue, Domain};

    fn counts(m: &Mesh) -> (usize, usize, usize) {
        (m.vert_count(), m.edge_count(), m.face_count())
    }

    /// Shoelace area of a ring in the z = 0 plane.
    fn planar_area(points: &[DVec3]) -> f64 {
        let n = points.len();
        (0..n)
            .map(|i| {
                let (a, b) = (points[i], points[(i + 1) % n]);
                a.x * b.y - b.x * a.y
            })
            .sum::<f64>()
            / 2.0
    }

    #[test]
    fn make_face_from_shuffled_edges() {
        let mut m = Mesh::new();
        let v: Vec<VertId> = (0..5)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 5.0;
                m.make_vert(DVec3::new(a.cos(), a.sin(), 0.0))
            })
            .collect();
        let e: Vec<EdgeId> = [(2, 3), (0, 1), (4, 0), (1, 2), (3, 4)]
            .iter()
            .map(|&(a, b)| m.make_edge(v[a], v[b]).unwrap())
            .collect();
        let r = make_face_from_edges(&mut m, &[e[4], e[1], e[0], e[3], e[2], e[1]]).unwrap();
        m.validate().unwrap();
        assert_eq!((r.verts.len(), r.edges.len(), r.faces.len()), (0, 0, 1));
        assert_eq!(counts(&m), (5, 5, 1));
        // Starts at the first vertex of the lowest edge (e0 = v2 → v3).
        let ring: Vec<VertId> = m.face_verts(r.faces[0]).collect();
        assert_eq!(ring, vec![v[2], v[3], v[4], v[0], v[1]]);
        assert!(m.face_normal(r.faces[0]).abs_diff_eq(DVec3::Z, 1e-12));
    }

    #[test]
    fn make_face_from_edges_needs_exactly_one_simple_cycle() {
        let mut m = Mesh::new();
        let v: Vec<VertId> = (0..7).map(|k| m.make_vert(DVec3::X * k as f64)).collect();
        let mut edge = |a: usize, b: usize| m.make_edge(v[a], v[b]).unwrap();
        let t1 = [edge(0, 1), edge(1, 2), edge(2, 0)];
        let t2 = [edge(3, 4), edge(4, 5), edge(5, 3)];
        let spur = edge(0, 6);
        let not_a_ring = |r: Result<Selection, OpError>| {
            matches!(r, Err(OpError::Kernel(KernelError::NotARing(_))))
        };
        let both: Vec<EdgeId> = t1.iter().chain(&t2).copied().collect();
        assert!(not_a_ring(make_face_from_edges(&mut m, &both)));
        assert!(not_a_ring(make_face_from_edges(
            &mut m,
            &[t1[0], t1[1], spur]
        )));
        assert!(not_a_ring(make_face_from_edges(
            &mut m,
            &[t1[0], t1[1], t1[2], spur]
        )));
        assert_eq!(
            make_face_from_edges(&mut m, &[t1[0], t1[1]]),
            Err(OpError::Kernel(KernelError::TooFewVertices(2)))
        );
        assert!(matches!(
            make_face_from_edges(&mut m, &[t1[0], t1[1], EdgeId::from_raw(50)]),
            Err(OpError::Kernel(KernelError::Dead { .. }))
        ));
        assert_eq!(m.face_count(), 0);
        m.validate().unwrap();
        assert_eq!(make_face_from_edges(&mut m, &t2).unwrap().faces.len(), 1);
        m.validate().unwrap();
    }

    #[test]
    fn triangulate_a_non_convex_star() {
        let mut m = Mesh::new();
        m.add_layer("mat", Domain::Face, AttrValue::Int(0)).unwrap();
        let points: Vec<DVec3> = (0..12)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 12.0;
                let r = if k % 2 == 0 { 1.0 } else { 0.4 };
                DVec3::new(r * a.cos(), r * a.sin(), 0.0)
            })
            .collect();
        let ring: Vec<VertId> = points.iter().map(|&p| m.make_vert(p)).collect();
        let star = m.make_face(&ring).unwrap();
        m.set_attr("mat", Domain::Face, star.index(), AttrValue::Int(9));
        let r = triangulate(&mut m, &[star]).unwrap();
        m.validate().unwrap();
        assert_eq!((r.faces.len(), r.edges.len()), (10, 9));
        assert_eq!(counts(&m), (12, 21, 10));
        assert!(consistently_wound(&m));
        let mut total = 0.0;
        for &t in &r.faces {
            let signed = planar_area(&m.face_positions(t));
            assert!(signed > 0.0, "{t} is wound against the star or degenerate");
            total += signed;
            assert_eq!(
                m.attr("mat", Domain::Face, t.index()),
                Some(AttrValue::Int(9))
            );
        }
        assert!((total - planar_area(&points)).abs() < 1e-12);
    }

    #[test]
    fn triangulate_a_cube_and_degenerate_faces() {
        let mut m = cube();
        let faces: Vec<FaceId> = m.face_ids().collect();
        let r = triangulate(&mut m, &faces).unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&m), (8, 18, 12));
        assert_eq!((r.faces.len(), r.edges.len()), (12, 6));
        assert!(closed_and_consistent(&m));
        assert!((signed_volume(&m) - 8.0).abs() < 1e-12);
        // Already triangles: kept as they are and named in the result.
        let again = triangulate(&mut m, &r.faces).unwrap();
        assert_eq!(again.faces, r.faces);
        assert!(again.edges.is_empty());

        // A collinear hexagon: no plane, still 4 triangles, no NaN.
        let mut m = Mesh::new();
        let ring: Vec<VertId> = (0..6).map(|k| m.make_vert(DVec3::X * k as f64)).collect();
        let line = m.make_face(&ring).unwrap();
        let r = triangulate(&mut m, &[line]).unwrap();
        m.validate().unwrap();
        assert_eq!(r.faces.len(), 4);
        assert!(consistently_wound(&m));
        assert!(r.faces.iter().all(|&f| m.face_normal(f).is_finite()));
    }

    #[test]
    fn quads_neither_diagonal_splits_well_take_the_general_path_among_others() {
        // A bow-tie, a collinear quad (no normal: a fan), a pentagon and a
        // plain quad in one call: the quads are decided in parallel before
        // anything is split, the pentagon is rebuilt between them.
        let mut m = Mesh::new();
        let rings = [
            vec![[0.0, 0.0], [2.0, 2.0], [2.0, 0.0], [0.0, 1.0]],
            vec![[2.0, 0.0], [3.0, 0.0], [4.0, 0.0], [5.0, 0.0]],
            vec![[6.0, 0.0], [7.0, 0.0], [7.5, 1.0], [6.5, 1.5], [5.8, 1.0]],
            vec![[8.0, 0.0], [9.0, 0.0], [9.0, 1.0], [8.0, 1.0]],
        ];
        let faces: Vec<FaceId> = rings
            .iter()
            .map(|ring| {
                let ring: Vec<VertId> = ring
                    .iter()
                    .map(|&[x, y]| m.make_vert(DVec3::new(x, y, 0.0)))
                    .collect();
                m.make_face(&ring).unwrap()
            })
            .collect();
        let decide = |f: FaceId| {
            let points: Vec<DVec3> = m.face_verts(f).map(|v| m.position(v)).collect();
            let normal = polygon::unit_normal(&points);
            polygon::quad_split_along_0_2(&points.try_into().unwrap(), normal)
        };
        assert_eq!(decide(faces[0]), None, "the bow-tie takes the general path");
        assert_eq!(decide(faces[1]), Some(true), "the collinear quad is a fan");
        let r = triangulate(&mut m, &faces).unwrap();
        m.validate().unwrap();
        assert_eq!(
            (r.faces.len(), r.edges.len()),
            (2 + 2 + 3 + 2, 1 + 1 + 2 + 1)
        );
        assert!(m.face_ids().all(|f| m.face_len(f) == 3));
        assert!(consistently_wound(&m));
    }

    #[test]
    fn triangulate_is_the_same_at_any_thread_count() {
        // Enough quads for the parallel decision and normal passes to
        // split into several tasks, bumpy so the diagonals differ, with a
        // hexagon now and then between them: every record, id and normal
        // bit the same on one thread and on four. The corners carry
        // arbitrary low bits, so a normal computed from another corner
        // order differs in its last bits and fails `validate`.
        let mut m = Mesh::new();
        let n = 60;
        // Heights that make either diagonal the shorter one, and small
        // offsets across: arbitrary low bits on every axis.
        let jitter =
            |i: usize, j: usize, a: f64, b: f64| (i as f64 * a + j as f64 * b).fract() * 1e-3;
        let point = |i: usize, j: usize| {
            DVec3::new(
                i as f64 + jitter(i, j, 0.377, 0.613),
                j as f64 + jitter(i, j, 0.719, 0.283),
                (i as f64 * 0.541 + j as f64 * 0.877).fract() * 0.4,
            )
        };
        let v: Vec<VertId> = (0..=n)
            .flat_map(|j| (0..=n).map(move |i| (i, j)))
            .map(|(i, j)| m.make_vert(point(i, j)))
            .collect();
        let at = |i: usize, j: usize| v[j * (n + 1) + i];
        let mut i = 0;
        for j in 0..n {
            while i < n {
                if (i + j) % 17 == 0 && i + 2 <= n {
                    let ring = [
                        at(i, j),
                        at(i + 1, j),
                        at(i + 2, j),
                        at(i + 2, j + 1),
                        at(i + 1, j + 1),
                        at(i, j + 1),
                    ];
                    m.make_face(&ring).unwrap();
                    i += 2;
                } else {
                    m.make_face(&[at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)])
                        .unwrap();
                    i += 1;
                }
            }
            i = 0;
        }
        let faces: Vec<FaceId> = m.face_ids().collect();
        assert!(faces.len() > 3000);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut mesh = m.clone();
            let r = pool.install(|| triangulate(&mut mesh, &faces)).unwrap();
            mesh.validate().unwrap();
            (format!("{mesh:?}"), r)
        };
        let (one, r1) = run(1);
        let (four, r4) = run(4);
        assert_eq!(r1, r4);
        assert!(one == four, "triangulate depends on the thread count");
        assert_eq!(r1.faces.len(), 2 * n * n, "two triangles per grid cell");
    }

    #[test]
    fn quads_split_in_place_as_a_rebuild_would_list_them() {
        // Convex quads and a dart whose reflex corner 1 forces the 1–3 cut,
        // with an attribute to carry.
        let mut m = Mesh::new();
        m.add_layer("mat", Domain::Face, AttrValue::Int(0)).unwrap();
        let quads = [
            [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            [[4.0, 0.0], [3.2, 0.2], [3.0, 1.0], [3.0, 0.0]],
            [[5.0, 0.0], [5.8, 0.8], [6.0, 2.0], [4.6, 0.8]],
        ];
        let mut rings = Vec::new();
        for (k, q) in quads.iter().enumerate() {
            let ring: Vec<VertId> = q
                .iter()
                .map(|&[x, y]| m.make_vert(DVec3::new(x, y, 0.0)))
                .collect();
            let f = m.make_face(&ring).unwrap();
            m.set_attr("mat", Domain::Face, f.index(), AttrValue::Int(k as i32 + 1));
            rings.push((f, ring));
        }
        let faces: Vec<FaceId> = rings.iter().map(|r| r.0).collect();
        let r = triangulate(&mut m, &faces).unwrap();
        m.validate().unwrap();
        assert_eq!((r.faces.len(), r.edges.len()), (6, 3));
        assert!(consistently_wound(&m));
        for (k, (f, ring)) in rings.iter().enumerate() {
            // The quad keeps its id on the triangle with its first side,
            // listed from its first corner, with its attributes.
            let kept: Vec<VertId> = m.face_verts(*f).collect();
            assert_eq!(&kept[..2], &ring[..2], "quad {k}");
            // The expected halves: what `ring_triangles` decides.
            let points: Vec<DVec3> = ring.iter().map(|&v| m.position(v)).collect();
            let mut tris = Vec::new();
            ring_triangles(&points, &mut tris);
            let halves: Vec<Vec<VertId>> = tris
                .iter()
                .map(|t| t.iter().map(|&i| ring[i as usize]).collect())
                .collect();
            let other = r
                .faces
                .iter()
                .copied()
                .find(|&g| {
                    g != *f
                        && m.face_verts(g).any(|v| v == ring[2])
                        && m.face_verts(g).any(|v| v == ring[3])
                })
                .unwrap();
            let got: Vec<Vec<VertId>> = [*f, other]
                .iter()
                .map(|&t| m.face_verts(t).collect())
                .collect();
            let mut want = halves.clone();
            want.sort_by_key(|h| h.contains(&ring[1]) && h.contains(&ring[0]));
            want.reverse();
            assert_eq!(got, want, "quad {k}");
            for t in [*f, other] {
                assert_eq!(
                    m.attr("mat", Domain::Face, t.index()),
                    Some(AttrValue::Int(k as i32 + 1))
                );
                assert_eq!(m.face_normal(t), m.compute_face_normal(t));
                assert!(m.face_normal(t).z > 0.0);
            }
        }
        // The dart's 0–2 diagonal is outside it: it was cut 1–3.
        let dart = &rings[1].1;
        assert!(m.find_edge(dart[1], dart[3]).is_some() && m.find_edge(dart[0], dart[2]).is_none());
    }

    #[test]
    fn reverse_faces_flips_and_checks_first() {
        let mut m = grid(2, 1, 1.0);
        assert_eq!(
            reverse_faces(&mut m, &[FaceId::from_raw(1), FaceId::from_raw(5)]),
            Err(OpError::Kernel(KernelError::Dead {
                domain: Domain::Face,
                index: 5
            }))
        );
        assert_eq!(
            m.face_normal(FaceId::from_raw(1)),
            DVec3::Z,
            "nothing flipped on error"
        );
        assert_eq!(
            reverse_faces(&mut m, &[FaceId::from_raw(1), FaceId::from_raw(0)]),
            Ok(Selection::new())
        );
        m.validate().unwrap();
        assert!(m.face_ids().all(|f| m.face_normal(f) == -DVec3::Z));
        assert!(consistently_wound(&m));
    }

    #[test]
    fn recompute_normals_fixes_a_cube_with_three_flipped_faces() {
        let mut m = cube();
        let all: Vec<FaceId> = m.face_ids().collect();
        reverse_faces(
            &mut m,
            &[
                FaceId::from_raw(0),
                FaceId::from_raw(3),
                FaceId::from_raw(5),
            ],
        )
        .unwrap();
        assert!(!consistently_wound(&m));
        let r = recompute_normals(&mut m, &all, true).unwrap();
        m.validate().unwrap();
        assert_eq!(
            r.faces,
            vec![
                FaceId::from_raw(0),
                FaceId::from_raw(3),
                FaceId::from_raw(5)
            ]
        );
        assert!(closed_and_consistent(&m));
        assert!((signed_volume(&m) - 8.0).abs() < 1e-12);
        for f in m.face_ids() {
            assert!(m.face_normal(f).dot(m.face_center(f)) > 0.99);
        }

        // Inside out: every face turns; already right: none does.
        let mut m = cube();
        reverse_faces(&mut m, &all).unwrap();
        assert_eq!(recompute_normals(&mut m, &all, true).unwrap().faces, all);
        assert!((signed_volume(&m) - 8.0).abs() < 1e-12);
        assert!(recompute_normals(&mut m, &all, true).unwrap().is_empty());
    }

    #[test]
    fn recompute_normals_per_component_and_open_surfaces() {
        // Two cubes, the second inside out and far away: fixed independently.
        let mut m = cube();
        let second = m.join_mesh(&cube());
        let second: Vec<FaceId> = second.faces.iter().flatten().copied().collect();
        for v in m.vert_ids().collect::<Vec<_>>().into_iter().skip(8) {
            m.place(v, m.position(v) + DVec3::new(100.0, 0.0, 0.0));
        }
        reverse_faces(&mut m, &second).unwrap();
        let all: Vec<FaceId> = m.face_ids().collect();
        let r = recompute_normals(&mut m, &all, true).unwrap();
        assert_eq!(r.faces, second);
        assert!((signed_volume(&m) - 16.0).abs() < 1e-9);

        // An open strip takes the winding of its lowest face.
        let mut m = grid(3, 1, 1.0);
        reverse_faces(&mut m, &[FaceId::from_raw(0)]).unwrap();
        let r = recompute_normals(
            &mut m,
            &[
                FaceId::from_raw(2),
                FaceId::from_raw(1),
                FaceId::from_raw(0),
            ],
            true,
        )
        .unwrap();
        m.validate().unwrap();
        assert_eq!(r.faces, vec![FaceId::from_raw(1), FaceId::from_raw(2)]);
        assert!(m.face_ids().all(|f| m.face_normal(f) == -DVec3::Z));

        // Without `outside`, only stale normals are refreshed.
        let mut m = grid(1, 1, 1.0);
        m.place(VertId::from_raw(3), DVec3::new(0.5, 0.5, 1.0));
        let stale = m.face_normal(FaceId::from_raw(0));
        let r = recompute_normals(&mut m, &[FaceId::from_raw(0)], false).unwrap();
        assert!(r.is_empty());
        assert_ne!(m.face_normal(FaceId::from_raw(0)), stale);
        assert_eq!(
            m.face_normal(FaceId::from_raw(0)),
            m.compute_face_normal(FaceId::from_raw(0))
        );
    }

    /// Random operator sequences (every operator of the four modules, on
    /// random selections) keep the mesh valid and finite, never fail on
    /// live input, and replay identically.
    #[test]
    fn random_operator_sequences_keep_the_mesh_valid() {
        use crate::kernel::ops::extrude::{
            extrude_edges, extrude_face_region, extrude_faces, extrude_verts, ExtrudeOffset,
        };
        use crate::kernel::ops::inset::{inset_faces, inset_region};
        use crate::kernel::ops::split::{split_edges, split_edges_at};

        fn run(seed: u64) -> Vec<(Vec<VertId>, Vec<[u64; 3]>)> {
            let mut state = seed;
            let mut next = move || {
                // xorshift64*: enough spread for picking operators and subsets.
                state ^= state >> 12;
                state ^= state << 25;
                state ^= state >> 27;
                state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11
            };
            let mut m = grid(3, 3, 1.0);
            let mut snapshots = Vec::new();
            for step in 0..150 {
                if m.face_count() > 600 {
                    m = cube();
                }
                let mut pick = |n: u64| next() % n;
                let faces: Vec<FaceId> = m.face_ids().filter(|_| pick(6) == 0).collect();
                let edges: Vec<EdgeId> = m.edge_ids().filter(|_| pick(8) == 0).collect();
                let verts: Vec<VertId> = m.vert_ids().filter(|_| pick(10) == 0).collect();
                let amount = pick(1000) as f64 / 2000.0;
                let keep = pick(2) == 0;
                let offset = match pick(3) {
                    0 => ExtrudeOffset::None,
                    1 => ExtrudeOffset::Vector(DVec3::new(amount, -amount, 0.3)),
                    _ => ExtrudeOffset::Normal(amount - 0.1),
                };
                let op = pick(12);
                let result = match op {
                    0 => extrude_verts(&mut m, &verts, offset),
                    1 => extrude_edges(&mut m, &edges, offset),
                    2 => extrude_faces(&mut m, &faces, keep, offset),
                    3 => extrude_face_region(&mut m, &faces, keep, offset),
                    4 => inset_faces(&mut m, &faces, amount, amount - 0.2),
                    5 => inset_region(&mut m, &faces, amount, 0.1 - amount),
                    6 => split_edges(&mut m, &edges, (amount * 6.0) as u32),
                    7 => split_edges_at(&mut m, &edges, &[0.2, 0.3, 0.9]),
                    8 => triangulate(&mut m, &faces),
                    9 => reverse_faces(&mut m, &faces),
                    10 => {
                        let all: Vec<FaceId> = m.face_ids().collect();
                        recompute_normals(&mut m, &all, true)
                    }
                    _ => make_face_from_edges(&mut m, &edges).or(Ok(Selection::new())),
                };
                let result = result.unwrap_or_else(|e| panic!("step {step} op {op}: {e}"));
                m.validate()
                    .unwrap_or_else(|e| panic!("step {step} op {op}: {e}"));
                for v in &result.verts {
                    assert!(
                        m.contains_vert(*v),
                        "step {step} op {op}: dead {v} in result"
                    );
                }
                for e in &result.edges {
                    assert!(
                        m.contains_edge(*e),
                        "step {step} op {op}: dead {e} in result"
                    );
                }
                for f in &result.faces {
                    assert!(
                        m.contains_face(*f),
                        "step {step} op {op}: dead {f} in result"
                    );
                }
                assert!(m.vert_ids().all(|v| m.position(v).is_finite()));
                let rings: Vec<VertId> = m.face_ids().flat_map(|f| m.face_verts(f)).collect();
                let bits: Vec<[u64; 3]> = m
                    .vert_ids()
                    .map(|v| m.position(v).to_array().map(f64::to_bits))
                    .collect();
                snapshots.push((rings, bits));
            }
            snapshots
        }
        for seed in [1, 2, 3, 0x9e37_79b9_7f4a_7c15] {
            assert_eq!(run(seed), run(seed), "seed {seed} is not reproducible");
        }
    }
}
