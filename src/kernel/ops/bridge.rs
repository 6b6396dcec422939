//! Bridge loops: selected edge loops joined, in order, by bands of faces
//! (issue 35). Blender 3.4's `bmesh.ops.bridge_loops` (`bmo_bridge.c`,
//! `bmesh_edgeloop.c`) is the anchor; its decisions are followed one by
//! one so that the same cage gives the same pairing:
//!
//! - **loops**: the selected edges split into chains, each a closed loop
//!   or an open one (a vertex with three or more selected edges is
//!   refused); each is listed from its lowest edge as Blender lists it.
//!   Two loops are bridged to each other; three or more are chained in
//!   Blender's order (the loop furthest from the mean of the loops'
//!   centres first, then each time the nearest remaining one);
//! - **direction**: of each pair, the loop with more vertices is `a`. The
//!   loops' directions are made to agree (open loops: their end-to-end
//!   directions, seen across the gap between the loops' centres; closed
//!   loops: their Newell normals against that gap), then both turn so that
//!   the band is wound as the faces already on the loops' edges are, or,
//!   with none, so that the loops' normals point from `b` to `a` (a tube
//!   comes out wound outward);
//! - **unequal counts**: the shorter loop's list repeats vertices
//!   (Blender's `BM_edgeloop_expand` without splitting: doubled while it is
//!   at most half as long, then the rest spread evenly), so a repeated
//!   vertex makes a triangle where the longer loop advances alone. Blender
//!   then triangulates the whole band and "beautifies" it; graftal keeps
//!   the quads and the triangles (the same vertices, half the faces);
//! - **rotation**: for closed loops, the shorter loop's list is rotated
//!   so the summed distances between paired vertices is least (the first
//!   least one), then by `twist` more places;
//! - **segments** (Blender's "Bridge Edge Loops" operator calls these
//!   cuts): `segments − 1` rings between each pair, each vertex on the
//!   straight line between the two it pairs (linear interpolation, also of
//!   vertex attributes); the triangles of unequal counts lie in the band
//!   next to the shorter loop.
//!
//! Built from Euler operators only (`make_vert`, `make_face`, which finds
//! or makes the band's edges). Each new face takes the attributes (part,
//! material) of a face on its column's edge of `a`, else at its vertices,
//! else on `b`'s side (Blender's example face); a face that already exists
//! is not made again.

use glam::DVec3;
use rustc_hash::FxHashMap;

use super::{into_canonical, OpError, Selection};
use crate::kernel::{EdgeId, FaceId, Mesh, VertId};

/// What [`bridge_loops`] is asked to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Bridge {
    /// Places the shorter loop's pairing is turned past the best one
    /// (closed loops; Blender's `twist_offset`).
    pub twist: i64,
    /// Faces across each band (at least 1).
    pub segments: u32,
}

impl Default for Bridge {
    fn default() -> Self {
        Self {
            twist: 0,
            segments: 1,
        }
    }
}

/// The most segments a band may have.
pub const MAX_SEGMENTS: u32 = 1 << 12;

/// Blender's tolerances (`bmo_bridge.c`, `bmesh_edgeloop.c`).
const EPS: f64 = 0.00001;
const NORMAL_EPS: f64 = 1e-10;

/// One loop of selected edges, vertices in order.
#[derive(Debug, Clone)]
struct EdgeLoop {
    verts: Vec<VertId>,
    closed: bool,
    center: DVec3,
}

impl EdgeLoop {
    fn flip(&mut self) {
        self.verts.reverse();
    }
    /// Consecutive pairs: `(v[i], v[i + 1])`, and the closing one.
    fn sides(&self) -> impl Iterator<Item = (VertId, VertId)> + '_ {
        let n = self.verts.len();
        let count = if self.closed { n } else { n - 1 };
        (0..count).map(move |i| (self.verts[i], self.verts[(i + 1) % n]))
    }
}

/// Joins the loops of the selected `edges` by bands of faces.
///
/// Result: the new faces, the new vertices (of `segments > 1`) and the
/// band's edges (the faces' edges that are not selected).
pub fn bridge_loops(
    mesh: &mut Mesh,
    edges: &[EdgeId],
    options: Bridge,
) -> Result<Selection, OpError> {
    let edges = into_canonical(edges.to_vec());
    for &e in &edges {
        mesh.check_edge(e)?;
    }
    if options.segments == 0 || options.segments > MAX_SEGMENTS {
        return Err(OpError::parameter(
            "segments",
            format!("must lie in 1..={MAX_SEGMENTS}, got {}", options.segments),
        ));
    }
    let loops = find_loops(mesh, &edges)?;
    if loops.len() < 2 {
        return Err(OpError::Degenerate(format!(
            "bridge_loops needs at least two loops of selected edges, found {}",
            loops.len()
        )));
    }
    if loops.iter().any(|l| l.closed) && loops.iter().any(|l| !l.closed) {
        return Err(OpError::Degenerate(
            "bridge_loops: the selected loops must be all closed or all open, not a mix".into(),
        ));
    }
    let loops = if loops.len() > 2 {
        chain_order(loops)
    } else {
        loops
    };
    // Refusals of what would overflow, before anything is made.
    let segments = options.segments as usize;
    let mut added_verts: u128 = 0;
    let mut added_faces: u128 = 0;
    for pair in loops.windows(2) {
        let n = pair[0].verts.len().max(pair[1].verts.len()) as u128;
        added_verts += n * (segments as u128 - 1);
        added_faces += n * segments as u128;
        let reach = |l: &EdgeLoop| {
            l.verts
                .iter()
                .map(|&v| mesh.position(v).abs().max_element())
                .fold(0.0, f64::max)
        };
        if !(reach(&pair[0]) + reach(&pair[1])).is_finite() {
            return Err(OpError::Degenerate(
                "bridge_loops: a new position overflows (coordinates near the limit of f64)".into(),
            ));
        }
    }
    let room = |capacity: usize| u128::from(u32::MAX) - capacity as u128;
    if added_verts > room(mesh.vert_capacity())
        || 2 * added_faces + added_verts > room(mesh.edge_capacity())
        || added_faces > room(mesh.face_capacity())
    {
        return Err(OpError::parameter(
            "segments",
            format!("{added_faces} new faces would exceed the mesh's id space"),
        ));
    }

    let mut made = Selection::new();
    for pair in loops.windows(2) {
        // Planned against the mesh as the previous bands left it: their
        // faces vote on this band's winding, as in Blender.
        let (a, b) = plan(mesh, &pair[0], &pair[1], options.twist);
        build_band(mesh, &a, &b, pair[0].closed, segments, &mut made)?;
    }
    // The band's edges: those of the new faces that were not selected.
    let mut band_edges: Vec<EdgeId> = Vec::new();
    for &f in &made.faces {
        band_edges.extend(
            mesh.face_edges(f)
                .filter(|e| edges.binary_search(e).is_err()),
        );
    }
    made.edges = band_edges;
    made.normalize();
    Ok(made)
}

/// The selected edges as loops, each listed as Blender's
/// `BM_mesh_edgeloops_find` lists it, in the order of their lowest edge.
fn find_loops(mesh: &Mesh, edges: &[EdgeId]) -> Result<Vec<EdgeLoop>, OpError> {
    // Each vertex's selected edges (at most two).
    let mut at: FxHashMap<VertId, Vec<EdgeId>> = FxHashMap::default();
    for &e in edges {
        for v in mesh.edge_verts(e) {
            let list = at.entry(v).or_default();
            list.push(e);
            if list.len() > 2 {
                let p = mesh.position(v);
                return Err(OpError::Degenerate(format!(
                    "bridge_loops: the selected edges must form simple chains or loops; \
                     the vertex at ({}, {}, {}) has three or more",
                    p.x, p.y, p.z
                )));
            }
        }
    }
    let mut used: rustc_hash::FxHashSet<EdgeId> = rustc_hash::FxHashSet::default();
    // From `v`, away from edge `from`: the vertices met, and whether the
    // walk came back to `stop`.
    let walk = |used: &mut rustc_hash::FxHashSet<EdgeId>,
                mut v: VertId,
                mut from: EdgeId,
                stop: VertId|
     -> (Vec<VertId>, bool) {
        let mut met = vec![v];
        loop {
            let Some(&e) = at[&v].iter().find(|&&e| e != from) else {
                return (met, false);
            };
            used.insert(e);
            let w = mesh.edge_other_vert(e, v);
            if w == stop {
                return (met, true);
            }
            met.push(w);
            v = w;
            from = e;
        }
    };
    let mut loops = Vec::new();
    for &e in edges {
        if !used.insert(e) {
            continue;
        }
        let [v1, v2] = mesh.edge_verts(e);
        // Blender walks from v2 away from v1 adding at the head, then from
        // v1 away from v2 adding at the tail.
        let (mut forward, closed) = walk(&mut used, v2, e, v1);
        let verts = if closed {
            // [v1, ..., v2]: the walk from v2 came round to v1.
            forward.push(v1);
            forward.reverse();
            forward
        } else {
            let (back, _) = walk(&mut used, v1, e, v2);
            forward.reverse();
            forward.extend(back);
            forward
        };
        let center = center_of(mesh, &verts);
        loops.push(EdgeLoop {
            verts,
            closed,
            center,
        });
    }
    Ok(loops)
}

/// Blender's `BM_edgeloop_calc_center`: each vertex weighted by the
/// lengths of its two sides (the list taken as cyclic, open or not).
fn center_of(mesh: &Mesh, verts: &[VertId]) -> DVec3 {
    let n = verts.len();
    let p = |i: usize| mesh.position(verts[i % n]);
    let mut sum = DVec3::ZERO;
    let mut total = 0.0;
    for i in 0..n {
        let (prev, curr, next) = (p(i + n - 1), p(i), p(i + 1));
        let w = prev.distance(curr) + curr.distance(next);
        sum += curr * w;
        total += w;
    }
    if total != 0.0 {
        sum / total
    } else {
        sum
    }
}

/// Blender's `BM_mesh_edgeloops_calc_order` (without normals): the loop
/// furthest from the mean centre first, then each time the nearest one.
fn chain_order(mut rest: Vec<EdgeLoop>) -> Vec<EdgeLoop> {
    let mean = rest.iter().map(|l| l.center).sum::<DVec3>() / rest.len() as f64;
    let mut first = 0;
    let mut best = -1.0;
    for (i, l) in rest.iter().enumerate() {
        let d = mean.distance_squared(l.center);
        if d > best {
            best = d;
            first = i;
        }
    }
    let mut ordered = vec![rest.remove(first)];
    while !rest.is_empty() {
        let last = ordered[ordered.len() - 1].center;
        let mut next = 0;
        let mut best = f64::INFINITY;
        for (i, l) in rest.iter().enumerate() {
            let d = last.distance_squared(l.center);
            if d < best {
                best = d;
                next = i;
            }
        }
        ordered.push(rest.remove(next));
    }
    ordered
}

/// Newell's normal of a loop taken as closed; +Z when degenerate.
fn newell(mesh: &Mesh, verts: &[VertId]) -> DVec3 {
    let mut n = DVec3::ZERO;
    let mut prev = mesh.position(verts[verts.len() - 1]);
    for &v in verts {
        let curr = mesh.position(v);
        n.x += (prev.y - curr.y) * (prev.z + curr.z);
        n.y += (prev.z - curr.z) * (prev.x + curr.x);
        n.z += (prev.x - curr.x) * (prev.y + curr.y);
        prev = curr;
    }
    unit_or_z(n)
}

/// Blender's `BM_edgeloop_calc_normal_aligned`: the sum over the sides of
/// each side's component across `align`.
fn aligned_normal(mesh: &Mesh, verts: &[VertId], align: DVec3) -> DVec3 {
    let mut n = DVec3::ZERO;
    let mut prev = mesh.position(verts[verts.len() - 1]);
    for &v in verts {
        let curr = mesh.position(v);
        let dir = curr - prev;
        n += dir.cross(align.cross(dir));
        prev = curr;
    }
    unit_or_z(n)
}

fn unit_or_z(n: DVec3) -> DVec3 {
    let length = n.length();
    if length < NORMAL_EPS || !length.is_finite() {
        DVec3::Z
    } else {
        n / length
    }
}

/// Blender's `bridge_loop_pair` up to the faces: the two vertex lists,
/// equally long, the `i`th of each paired (the second may repeat
/// vertices).
fn plan(
    mesh: &Mesh,
    first: &EdgeLoop,
    second: &EdgeLoop,
    twist: i64,
) -> (Vec<VertId>, Vec<VertId>) {
    let (mut a, mut b) = (first.clone(), second.clone());
    if a.verts.len() < b.verts.len() {
        std::mem::swap(&mut a, &mut b);
    }
    let closed = a.closed && b.closed;
    let el_dir = a.center - b.center;
    let (no_a, mut no_b);
    if closed {
        no_a = newell(mesh, &a.verts);
        no_b = newell(mesh, &b.verts);
    } else {
        let ends =
            |l: &EdgeLoop| mesh.position(l.verts[0]) - mesh.position(l.verts[l.verts.len() - 1]);
        let (dir_a_orig, dir_b_orig) = (ends(&a), ends(&b));
        let dir_a = dir_a_orig.cross(el_dir).cross(el_dir);
        let dir_b = dir_b_orig.cross(el_dir).cross(el_dir);
        let (test_a, test_b) = if dir_a != DVec3::ZERO && dir_b != DVec3::ZERO {
            (dir_a, dir_b)
        } else {
            (dir_a_orig, dir_b_orig)
        };
        if test_a.dot(test_b) < 0.0 {
            b.flip();
        }
        let align = el_dir.normalize_or_zero();
        no_a = aligned_normal(mesh, &a.verts, align);
        no_b = aligned_normal(mesh, &b.verts, align);
    }
    let dot_a = no_a.dot(el_dir);
    let dot_b = no_b.dot(el_dir);
    let flip_b = |b: &mut EdgeLoop, no_b: &mut DVec3| {
        b.flip();
        *no_b = -*no_b;
    };
    if el_dir.length_squared() < EPS || (dot_a.abs() < EPS && dot_b.abs() < EPS) {
        // No depth between the loops: only their normals can agree.
        if no_a.dot(no_b) < 0.0 {
            flip_b(&mut b, &mut no_b);
        }
    } else if (dot_a < 0.0) != (dot_b < 0.0) {
        flip_b(&mut b, &mut no_b);
    }
    // Winding: along the gap, unless faces on the loops' edges say else.
    if (no_a + no_b).dot(el_dir) < 0.0 {
        a.flip();
        b.flip();
    }
    if mesh.face_count() > 0 {
        let mut votes = [0i64; 2];
        for (i, (l, sign)) in [(&a, 1i64), (&b, -1i64)].into_iter().enumerate() {
            for (v, w) in l.sides() {
                let Some(e) = mesh.find_edge(v, w) else {
                    continue;
                };
                if mesh.edge_face_count(e) != 1 {
                    continue;
                }
                let l0 = mesh.edge_loops(e).next().expect("one face");
                votes[i] += if mesh.loop_vert(l0) == v { sign } else { -sign };
            }
        }
        if votes != [0, 0] {
            let mut flip = [false, false];
            if dot_a.abs() < EPS && votes[0] < 0 {
                flip[0] = true;
                votes[0] = -votes[0];
            }
            if dot_b.abs() < EPS && votes[1] < 0 {
                flip[1] = true;
                votes[1] = -votes[1];
            }
            if votes[0] + votes[1] < 0 {
                flip = [!flip[0], !flip[1]];
            }
            if flip[0] {
                a.flip();
            }
            if flip[1] {
                b.flip();
            }
        }
    }
    let mut b_list = expand(&b.verts, a.verts.len());
    if closed {
        let n = a.verts.len();
        let pos_a: Vec<DVec3> = a.verts.iter().map(|&v| mesh.position(v)).collect();
        let pos_b: Vec<DVec3> = b_list.iter().map(|&v| mesh.position(v)).collect();
        let mut best = 0;
        let mut best_len = f64::INFINITY;
        for k in 0..n {
            let mut len = 0.0;
            for (i, p) in pos_a.iter().enumerate() {
                len += p.distance(pos_b[(i + k) % n]);
                if len >= best_len {
                    break;
                }
            }
            if len < best_len {
                best_len = len;
                best = k;
            }
        }
        // `twist` more places the way Blender's positive `twist_offset`
        // turns it (Blender's turns one place further: it rotates to the
        // `twist`-th last vertex, so its −1 is no turn and its 1 is two).
        let shift = (best as i64 - twist.rem_euclid(n as i64)).rem_euclid(n as i64) as usize;
        b_list.rotate_left(shift);
    }
    (a.verts, b_list)
}

/// Blender's `BM_edgeloop_expand` without splitting: `verts` lengthened to
/// `len` by repeating vertices in place.
fn expand(verts: &[VertId], len: usize) -> Vec<VertId> {
    let mut list = verts.to_vec();
    while list.len() * 2 < len {
        list = list.iter().flat_map(|&v| [v, v]).collect();
    }
    if list.len() < len {
        let repeat = sparse_range(list.len(), len - list.len());
        let mut out = Vec::with_capacity(len);
        let mut r = repeat.iter().peekable();
        for (i, &v) in list.iter().enumerate() {
            out.push(v);
            if r.peek() == Some(&&i) {
                r.next();
                out.push(v);
            }
        }
        list = out;
    }
    list
}

/// Blender's `BLI_FOREACH_SPARSE_RANGE(src, dst)`: `dst` indices below
/// `src`, evenly spread.
fn sparse_range(src: usize, dst: usize) -> Vec<usize> {
    let (src, dst) = (src as i64, dst as i64);
    let (src2, dst2) = (src * 2, dst * 2);
    let mut error = dst2 - src;
    let mut i = 0i64;
    let mut out = Vec::new();
    loop {
        let delta = error.div_euclid(dst2);
        i -= delta;
        if i >= src {
            return out;
        }
        out.push(i as usize);
        error -= delta * dst2 + src2;
    }
}

/// The face whose attributes a new face in column `i` takes: one on the
/// column's side of `a`, else at its vertices; then the same of `b`.
fn example(mesh: &Mesh, side: [VertId; 2]) -> Option<FaceId> {
    let [v, w] = side;
    if v != w {
        if let Some(e) = mesh.find_edge(v, w) {
            if let Some(f) = mesh.edge_faces(e).min() {
                return Some(f);
            }
        }
    }
    mesh.vert_faces(v)
        .min()
        .or_else(|| mesh.vert_faces(w).min())
}

/// Rings from `a` to `b` and the faces between them.
fn build_band(
    mesh: &mut Mesh,
    a: &[VertId],
    b: &[VertId],
    closed: bool,
    segments: usize,
    made: &mut Selection,
) -> Result<(), OpError> {
    let n = a.len();
    let columns = if closed { n } else { n - 1 };
    let examples: Vec<Option<FaceId>> = (0..columns)
        .map(|i| {
            let j = (i + 1) % n;
            example(mesh, [a[i], a[j]]).or_else(|| example(mesh, [b[i], b[j]]))
        })
        .collect();
    let mut rings: Vec<Vec<VertId>> = vec![a.to_vec()];
    for k in 1..segments {
        let t = k as f64 / segments as f64;
        let ring = (0..n)
            .map(|i| {
                let p = mesh.position(a[i]).lerp(mesh.position(b[i]), t);
                let w = mesh.make_vert(p);
                mesh.interpolate_vert_attrs(a[i], b[i], t, w);
                made.verts.push(w);
                w
            })
            .collect();
        rings.push(ring);
    }
    rings.push(b.to_vec());
    for k in 0..segments {
        let (x, y) = (&rings[k], &rings[k + 1]);
        for (i, &example) in examples.iter().enumerate() {
            let j = (i + 1) % n;
            // Blender's corner order: v_b, v_b_next, v_a_next, v_a.
            let ring: Vec<VertId> = if y[i] == y[j] {
                vec![y[i], x[j], x[i]]
            } else {
                vec![y[i], y[j], x[j], x[i]]
            };
            if mesh.find_face(&ring).is_some() {
                continue;
            }
            let f = mesh.make_face(&ring)?;
            if let Some(g) = example {
                mesh.copy_face_attrs(g, f);
            }
            made.faces.push(f);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// A closed loop of `n` edges on a circle of `radius` at height `z`,
    /// turned by `phase` radians.
    fn circle(mesh: &mut Mesh, n: usize, radius: f64, z: f64, phase: f64) -> Vec<EdgeId> {
        let v: Vec<VertId> = (0..n)
            .map(|i| {
                let a = phase + TAU * i as f64 / n as f64;
                mesh.make_vert(DVec3::new(radius * a.cos(), radius * a.sin(), z))
            })
            .collect();
        (0..n)
            .map(|i| mesh.make_edge(v[i], v[(i + 1) % n]).unwrap())
            .collect()
    }

    fn polyline(mesh: &mut Mesh, points: &[DVec3]) -> Vec<EdgeId> {
        let v: Vec<VertId> = points.iter().map(|&p| mesh.make_vert(p)).collect();
        v.windows(2)
            .map(|w| mesh.make_edge(w[0], w[1]).unwrap())
            .collect()
    }

    fn opts(twist: i64, segments: u32) -> Bridge {
        Bridge { twist, segments }
    }

    #[test]
    fn blenders_sparse_range() {
        assert_eq!(sparse_range(19, 4), vec![2, 7, 11, 16]);
        assert_eq!(sparse_range(100, 5), vec![9, 29, 49, 69, 89]);
        assert_eq!(sparse_range(100, 3), vec![16, 49, 83]);
        assert_eq!(sparse_range(100, 100), (0..100).collect::<Vec<_>>());
        let v: Vec<VertId> = (0..3).map(VertId::from_index).collect();
        // 3 -> 7: doubled to 6, then one more.
        assert_eq!(expand(&v, 7).len(), 7);
        assert_eq!(expand(&v, 3), v);
    }

    #[test]
    fn two_circles_make_an_open_tube_of_quads() {
        let mut mesh = Mesh::new();
        let mut edges = circle(&mut mesh, 8, 1.0, 0.0, 0.0);
        edges.extend(circle(&mut mesh, 8, 1.0, 2.0, 0.3));
        let made = bridge_loops(&mut mesh, &edges, Bridge::default()).unwrap();
        mesh.validate().unwrap();
        assert_eq!(made.faces.len(), 8);
        assert_eq!(made.edges.len(), 8);
        assert!(made.verts.is_empty());
        assert!(made.faces.iter().all(|&f| mesh.face_len(f) == 4));
        let report = mesh.report();
        assert!(report.manifold && report.consistently_oriented);
        assert_eq!(report.boundary_edges, 16);
        // With no faces on the loops, Blender's rule winds a tube outward.
        for &f in &made.faces {
            let c = mesh.face_center(f);
            assert!(mesh.face_normal(f).dot(DVec3::new(c.x, c.y, 0.0)) > 0.0);
        }
        // Best rotation: every rung joins a vertex to the nearest one of
        // the other circle (0.3 rad apart), not to one a step further.
        let rung = 4.0 + 2.0 - 2.0 * 0.3f64.cos();
        for &e in &made.edges {
            assert!((mesh.edge_length(e).powi(2) - rung).abs() < 1e-12);
        }
    }

    #[test]
    fn twist_turns_the_pairing_and_segments_add_rings() {
        let mut mesh = Mesh::new();
        let mut edges = circle(&mut mesh, 6, 1.0, 0.0, 0.0);
        edges.extend(circle(&mut mesh, 6, 1.0, 1.0, 0.0));
        let made = bridge_loops(&mut mesh, &edges, opts(1, 1)).unwrap();
        mesh.validate().unwrap();
        // One step of a hexagon of radius 1 is 1 apart: rungs √2 long.
        for &e in &made.edges {
            assert!((mesh.edge_length(e) - 2f64.sqrt()).abs() < 1e-12);
        }
        let mut mesh = Mesh::new();
        let mut edges = circle(&mut mesh, 6, 1.0, 0.0, 0.0);
        edges.extend(circle(&mut mesh, 6, 1.0, 1.0, 0.0));
        let made = bridge_loops(&mut mesh, &edges, opts(0, 3)).unwrap();
        mesh.validate().unwrap();
        assert_eq!((made.verts.len(), made.faces.len()), (12, 18));
        assert!(mesh.report().consistently_oriented);
        let mut heights: Vec<f64> = made.verts.iter().map(|&v| mesh.position(v).z).collect();
        heights.sort_by(f64::total_cmp);
        heights.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
        assert_eq!(heights.len(), 2);
        assert!((heights[0] - 1.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn unequal_counts_make_quads_and_triangles() {
        let mut mesh = Mesh::new();
        let mut edges = circle(&mut mesh, 8, 1.0, 0.0, 0.0);
        edges.extend(circle(&mut mesh, 12, 1.5, 1.0, 0.1));
        let made = bridge_loops(&mut mesh, &edges, Bridge::default()).unwrap();
        mesh.validate().unwrap();
        let tris = made
            .faces
            .iter()
            .filter(|&&f| mesh.face_len(f) == 3)
            .count();
        assert_eq!((made.faces.len(), tris), (12, 4));
        assert_eq!(mesh.vert_count(), 20);
        let report = mesh.report();
        assert!(report.manifold && report.consistently_oriented);
        assert_eq!(report.boundary_edges, 20);
        // With rings between, the triangles lie next to the short loop.
        let mut mesh = Mesh::new();
        let mut edges = circle(&mut mesh, 6, 1.0, 0.0, 0.0);
        edges.extend(circle(&mut mesh, 9, 1.5, 1.0, 0.0));
        let made = bridge_loops(&mut mesh, &edges, opts(0, 2)).unwrap();
        mesh.validate().unwrap();
        assert_eq!((made.verts.len(), made.faces.len()), (9, 18));
        assert!(mesh.report().manifold);
    }

    #[test]
    fn open_loops_pair_their_ends_and_chains_follow_blenders_order() {
        let mut mesh = Mesh::new();
        let mut edges = polyline(
            &mut mesh,
            &[
                DVec3::ZERO,
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(2.0, 0.0, 0.0),
            ],
        );
        // The second one listed the other way round: still no crossing.
        edges.extend(polyline(
            &mut mesh,
            &[
                DVec3::new(2.0, 1.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ],
        ));
        let made = bridge_loops(&mut mesh, &edges, Bridge::default()).unwrap();
        mesh.validate().unwrap();
        assert_eq!(made.faces.len(), 2);
        for &e in &made.edges {
            assert!((mesh.edge_length(e) - 1.0).abs() < 1e-12);
        }
        // Three circles, the middle one listed last: chained in space order.
        let mut mesh = Mesh::new();
        let mut edges = circle(&mut mesh, 8, 1.0, 0.0, 0.0);
        edges.extend(circle(&mut mesh, 8, 1.0, 2.0, 0.0));
        edges.extend(circle(&mut mesh, 8, 1.2, 1.0, 0.0));
        let made = bridge_loops(&mut mesh, &edges, Bridge::default()).unwrap();
        mesh.validate().unwrap();
        assert_eq!(made.faces.len(), 16);
        let report = mesh.report();
        assert!(report.manifold && report.consistently_oriented);
        assert_eq!(report.boundary_edges, 16);
    }

    #[test]
    fn faces_on_the_loops_set_the_winding_and_lend_their_attributes() {
        use crate::kernel::{AttrValue, Domain};
        // Two capped cylinders' caps removed: bridging must wind the band
        // as the caps' walls are wound, whichever way the loops run.
        let mut mesh = Mesh::new();
        let bottom = circle(&mut mesh, 6, 1.0, 0.0, 0.0);
        let top = circle(&mut mesh, 6, 1.0, 1.0, 0.0);
        let ring = |mesh: &Mesh, edges: &[EdgeId]| -> Vec<VertId> {
            let mut v: Vec<VertId> = edges.iter().map(|&e| mesh.edge_verts(e)[0]).collect();
            v.dedup();
            v
        };
        let (rb, rt) = (ring(&mesh, &bottom), ring(&mesh, &top));
        // A floor under the bottom (wound downward) and a roof on top.
        let mut floor = rb.clone();
        floor.reverse();
        let f_floor = mesh.make_face(&floor).unwrap();
        let f_roof = mesh.make_face(&rt).unwrap();
        mesh.add_layer("material", Domain::Face, AttrValue::Int(0))
            .unwrap();
        let _ = mesh.set_attr("material", Domain::Face, f_floor.index(), AttrValue::Int(7));
        let _ = mesh.set_attr("material", Domain::Face, f_roof.index(), AttrValue::Int(7));
        let mut edges = bottom;
        edges.extend(top);
        let made = bridge_loops(&mut mesh, &edges, Bridge::default()).unwrap();
        mesh.validate().unwrap();
        let report = mesh.report();
        assert!(report.watertight && report.consistently_oriented);
        assert!(report.volume.unwrap() > 0.0);
        for &f in &made.faces {
            assert_eq!(
                mesh.attr("material", Domain::Face, f.index()),
                Some(AttrValue::Int(7))
            );
        }
    }

    #[test]
    fn bad_selections_are_refused_before_anything_is_made() {
        let check = |mesh: &mut Mesh, edges: &[EdgeId], options: Bridge, needle: &str| {
            let (v, e, f) = (mesh.vert_count(), mesh.edge_count(), mesh.face_count());
            let err = bridge_loops(mesh, edges, options).unwrap_err();
            assert!(err.to_string().contains(needle), "{err}");
            assert_eq!(
                (mesh.vert_count(), mesh.edge_count(), mesh.face_count()),
                (v, e, f)
            );
        };
        let mut mesh = Mesh::new();
        let one = circle(&mut mesh, 5, 1.0, 0.0, 0.0);
        check(
            &mut mesh,
            &one,
            Bridge::default(),
            "at least two loops of selected edges, found 1",
        );
        check(&mut mesh, &[], Bridge::default(), "found 0");
        let mut mixed = one.clone();
        mixed.extend(polyline(&mut mesh, &[DVec3::Z, DVec3::new(1.0, 0.0, 1.0)]));
        check(
            &mut mesh,
            &mixed,
            Bridge::default(),
            "all closed or all open",
        );
        // A spoke from the circle: a vertex with three selected edges.
        let v0 = mesh.edge_verts(one[0])[0];
        let hub = mesh.make_vert(DVec3::new(0.0, 0.0, -1.0));
        let spoke = mesh.make_edge(v0, hub).unwrap();
        let mut branched = one.clone();
        branched.push(spoke);
        branched.extend(circle(&mut mesh, 5, 1.0, 3.0, 0.0));
        check(
            &mut mesh,
            &branched,
            Bridge::default(),
            "simple chains or loops",
        );
        let mut two = one.clone();
        two.extend(circle(&mut mesh, 5, 1.0, 2.0, 0.0));
        check(&mut mesh, &two, opts(0, 0), "segments");
        check(&mut mesh, &two, opts(0, MAX_SEGMENTS + 1), "segments");
        let mut far = Mesh::new();
        let mut edges = polyline(
            &mut far,
            &[DVec3::X * 1.5e308, DVec3::new(1.5e308, 1.0, 0.0)],
        );
        edges.extend(polyline(
            &mut far,
            &[DVec3::X * -1.5e308, DVec3::new(-1.5e308, 1.0, 0.0)],
        ));
        check(&mut far, &edges, opts(0, 2), "overflows");
    }
}
