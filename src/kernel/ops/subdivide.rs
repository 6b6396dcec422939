//! Subdivision surfaces on a region of faces: Catmull–Clark, its "simple"
//! (midpoint) topology, and Loop for triangles, with OpenSubdiv's rules
//! (Sdc) for boundaries and semi-sharp creases, so a cage gives the points
//! Blender's subdivision-surface modifier gives (limit surface off).
//!
//! One level:
//! 1. every new position is computed from the current cage (face points,
//!    edge points, vertex points; Sdc's Catmark and Loop masks);
//! 2. the topology changes by Euler operators only: every region edge is
//!    split at its middle (`split_edge`), then every face is cut into
//!    quads around a centre vertex (Catmull–Clark: one `split_face`, one
//!    `split_edge` of that diagonal for the centre, `n − 2` more
//!    `split_face`s) or into four triangles (Loop: three `split_face`s);
//! 3. the positions are written and the touched faces' normals refreshed.
//!
//! The region's border (edges with one region face) is a boundary, edges
//! with more than two region faces are non-manifold: both are infinitely
//! sharp, as in OpenSubdiv. Faces outside the region that share a border
//! edge gain its midpoint, which lies on the edge; the border's vertices
//! follow the crease rule, so a neighbour stays flat where the border is
//! straight and bends with it where it curves. Each new piece copies its
//! face's attributes (parts, materials) through `split_face`.
//!
//! Creases (OpenSubdiv "uniform" creasing): an edge's sharpness `s` makes
//! its edge point `lerp(smooth, midpoint, min(s, 1))`; its two children
//! get `s − 1`. A vertex on no or one sharp edge is smooth, on two a
//! crease (`(a + 6v + b) / 8`), on more (or a boundary corner) a corner
//! (fixed). When a vertex's rule changes from parent to child level the
//! two positions are blended by the mean sharpness of the edges that
//! became smooth (Sdc `Crease::ComputeFractionalWeightAtVertex`).

use glam::DVec3;
use rayon::prelude::*;
use rustc_hash::FxHashMap;

use super::side_table::{SideTable, SlotSet};
use super::{canonical, OpError, Selection};
use crate::kernel::{EdgeId, FaceId, Mesh, VertId};

/// Which refinement rules [`subdivide`] applies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scheme {
    /// Catmull–Clark: quads around face points, smoothed.
    CatmullClark,
    /// Catmull–Clark's topology with points at face centres and edge
    /// midpoints; the shape does not change.
    Simple,
    /// Loop: every triangle into four, smoothed (triangles only).
    Loop,
}

/// How boundary vertices with a single face behave (OpenSubdiv's
/// `VtxBoundaryInterpolation`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Boundary {
    /// `EDGE_AND_CORNER`, OpenSubdiv's default: such a vertex is a corner
    /// and stays where it is (Blender: "Keep Corners").
    KeepCorners,
    /// `EDGE_ONLY`: boundary vertices all follow the boundary curve
    /// (Blender: "All").
    Smooth,
}

/// What [`subdivide`] is asked to do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Subdivision {
    pub scheme: Scheme,
    pub levels: u32,
    pub boundary: Boundary,
    /// Edges whose two faces' normals differ by more than this many
    /// degrees are infinitely sharp (judged on the cage).
    pub crease_angle: Option<f64>,
}

/// What [`subdivide`] made, and the sharpness left on the final edges.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Subdivided {
    /// The faces that replace the region (the originals keep their ids as
    /// one of their pieces), the new vertices and the new edges.
    pub made: Selection,
    /// Every final edge with sharpness left of `creases` (`s − levels > 0`;
    /// an infinite crease as [`SHARPNESS_INFINITE`]), ascending: what a
    /// further subdivision reads. Creases by angle are not included.
    pub creases: Vec<(EdgeId, f64)>,
}

/// The most levels one call refines (each multiplies the faces by about 4).
pub const MAX_LEVELS: u32 = 8;

/// The most elements (of each kind) one call may create: far past any
/// mesh a run may make, and well inside the u32 id space.
const MAX_NEW: u128 = 1 << 30;

/// Subdivides the region `faces` `levels` times. `creases` gives the
/// sharpness of cage edges (any order; edges not listed, or outside the
/// region, are smooth; `f64::INFINITY` is sharp at every level).
pub fn subdivide(
    mesh: &mut Mesh,
    faces: &[FaceId],
    options: Subdivision,
    creases: &[(EdgeId, f64)],
) -> Result<Subdivided, OpError> {
    let mut region = canonical(faces);
    for &f in &region {
        mesh.check_face(f)?;
    }
    if !(1..=MAX_LEVELS).contains(&options.levels) {
        return Err(OpError::parameter(
            "levels",
            format!("must lie in 1..={MAX_LEVELS}, got {}", options.levels),
        ));
    }
    if let Some(angle) = options.crease_angle {
        if !(angle.is_finite() && (0.0..=180.0).contains(&angle)) {
            return Err(OpError::parameter(
                "crease_angle",
                format!("must lie in [0, 180] degrees, got {angle}"),
            ));
        }
    }
    if region.is_empty() {
        return Ok(Subdivided::default());
    }
    if options.scheme == Scheme::Loop {
        let bad: Vec<FaceId> = region
            .iter()
            .copied()
            .filter(|&f| mesh.face_len(f) != 3)
            .collect();
        if let Some(first) = bad.first() {
            return Err(OpError::parameter(
                "scheme",
                format!(
                    "Loop subdivision takes triangles only: {} selected face(s) have more \
                     than three sides (the first is face {}, of {} sides); triangulate them \
                     first or use scheme = \"catmull_clark\"",
                    bad.len(),
                    first.index(),
                    mesh.face_len(*first)
                ),
            ));
        }
    }
    let predicted = predict(mesh, &region, options);
    let room = |capacity: usize| u128::from(u32::MAX) - capacity as u128;
    if predicted.iter().any(|&n| n > MAX_NEW)
        || predicted[0] > room(mesh.vert_capacity())
        || predicted[1] > room(mesh.edge_capacity())
        || predicted[2] > room(mesh.face_capacity())
    {
        return Err(OpError::parameter(
            "levels",
            format!(
                "{} levels would make {} vertices and {} faces, past the mesh's id space",
                options.levels, predicted[0], predicted[2]
            ),
        ));
    }

    // Per creased edge: (the sharpness the rules use, the part of it that
    // came from `creases`, which is what is handed back; creases by angle
    // are the caller's to recompute).
    let mut sharp: FxHashMap<EdgeId, (f64, f64)> = creases
        .iter()
        .copied()
        .filter(|&(e, s)| s > 0.0 && mesh.contains_edge(e))
        .map(|(e, s)| {
            let s = if s >= SHARPNESS_INFINITE { INFINITE } else { s };
            (e, (s, s))
        })
        .collect();
    if let Some(angle) = options.crease_angle {
        let mut in_region = SlotSet::new(region.len(), mesh.face_capacity());
        for f in &region {
            in_region.insert(f.index());
        }
        let cos_limit = libm::cos(angle.to_radians());
        for &f in &region {
            for e in mesh.face_edges(f) {
                if let Some([a, b]) = region_pair(mesh, e, &in_region) {
                    if mesh.face_normal(a).dot(mesh.face_normal(b)) < cos_limit {
                        sharp.entry(e).or_insert((0.0, 0.0)).0 = INFINITE;
                    }
                }
            }
        }
    }
    let mut made = Selection::new();
    for _ in 0..options.levels {
        let level = refine(mesh, &region, options, &sharp)?;
        made.verts.extend_from_slice(&level.new_verts);
        made.edges.extend_from_slice(&level.new_edges);
        region = level.faces;
        sharp = level.sharp;
    }
    made.faces = region;
    made.normalize();
    let mut creases: Vec<(EdgeId, f64)> = sharp
        .into_iter()
        .filter(|&(_, (_, stored))| stored > 0.0)
        .map(|(e, (_, stored))| (e, stored.min(SHARPNESS_INFINITE)))
        .collect();
    creases.sort_unstable_by_key(|&(e, _)| e);
    Ok(Subdivided { made, creases })
}

/// Vertices, edges and faces `options` adds to the region (an upper bound
/// the caller checks before anything is made; a face of `n` sides becomes
/// `n` quads, or a triangle four triangles).
pub fn predict(mesh: &Mesh, faces: &[FaceId], options: Subdivision) -> [u128; 3] {
    let corners: u128 = faces.iter().map(|&f| mesh.face_len(f) as u128).sum();
    let mut f = faces.len() as u128;
    // Region edges: each is used by one or two faces (more only where
    // non-manifold); bound it by the corners.
    let mut e = corners;
    let mut made = [0u128; 3];
    for level in 0..options.levels {
        let (new_v, new_e, new_f) = match options.scheme {
            Scheme::Loop => (e, e + 3 * f, 3 * f),
            _ if level == 0 => (e + f, e + corners, corners.saturating_sub(f)),
            _ => (e + f, e + 4 * f, 3 * f),
        };
        made[0] = made[0].saturating_add(new_v);
        made[1] = made[1].saturating_add(new_e);
        made[2] = made[2].saturating_add(new_f);
        e = e.saturating_add(new_e);
        f = f.saturating_add(new_f);
        if made.iter().any(|&n| n > MAX_NEW) {
            break;
        }
    }
    made
}

struct Level {
    faces: Vec<FaceId>,
    new_verts: Vec<VertId>,
    new_edges: Vec<EdgeId>,
    sharp: FxHashMap<EdgeId, (f64, f64)>,
}

/// An infinitely sharp edge (boundaries, non-manifold edges, creases by
/// angle): sharp at every level.
const INFINITE: f64 = f64::INFINITY;

/// Sharpness from which a crease is infinite (OpenSubdiv's
/// `Crease::SHARPNESS_INFINITE`; Blender's crease 1.0 maps to it).
pub const SHARPNESS_INFINITE: f64 = 10.0;

/// What one level reads of its cage, slot-indexed: membership and values
/// an edge or vertex rule looks up for every corner around it are a load,
/// not a hash probe.
struct Cage {
    in_region: SlotSet,
    /// Effective sharpness of each region edge.
    sharpness: SideTable<f64>,
    face_point: SideTable<DVec3>,
}

impl Cage {
    fn sharpness(&self, e: EdgeId) -> Option<f64> {
        self.sharpness.get(e.index()).copied()
    }

    fn face_point(&self, f: FaceId) -> DVec3 {
        self.face_point
            .get(f.index())
            .copied()
            .unwrap_or(DVec3::ZERO)
    }
}

/// One level of refinement of `region` (canonical order).
fn refine(
    mesh: &mut Mesh,
    region: &[FaceId],
    options: Subdivision,
    sharp: &FxHashMap<EdgeId, (f64, f64)>,
) -> Result<Level, OpError> {
    let mut in_region = SlotSet::new(region.len(), mesh.face_capacity());
    for f in region {
        in_region.insert(f.index());
    }
    // The region's edges and vertices, in canonical order.
    let mut edges: Vec<EdgeId> = region.iter().flat_map(|&f| mesh.face_edges(f)).collect();
    edges = super::into_canonical(edges);
    let mut verts: Vec<VertId> = region.iter().flat_map(|&f| mesh.face_verts(f)).collect();
    verts = super::into_canonical(verts);

    // Effective sharpness: boundary and non-manifold edges are infinitely
    // sharp (Sdc treats both as creases).
    let mut sharpness = SideTable::new(edges.len(), mesh.edge_capacity());
    for &e in &edges {
        let s = if mesh.edge_face_count(e) == 0 || region_pair(mesh, e, &in_region).is_none() {
            INFINITE
        } else {
            sharp.get(&e).map_or(0.0, |s| s.0)
        };
        sharpness.insert(e.index(), s);
    }

    // 1. New positions from the cage: each a pure function of the cage,
    // computed in parallel and collected in canonical order.
    let view: &Mesh = mesh;
    let centres: Vec<DVec3> = region.par_iter().map(|&f| view.face_center(f)).collect();
    let mut face_point = SideTable::new(region.len(), view.face_capacity());
    for (&f, &p) in region.iter().zip(&centres) {
        face_point.insert(f.index(), p);
    }
    let cage = Cage {
        in_region,
        sharpness,
        face_point,
    };
    let edge_points: Vec<DVec3> = edges
        .par_iter()
        .map(|&e| edge_point(view, e, options, &cage))
        .collect();
    let vert_points: Vec<DVec3> = verts
        .par_iter()
        .map(|&v| match options.scheme {
            Scheme::Simple => view.position(v),
            _ => vertex_point(view, v, options, &cage),
        })
        .collect();

    // Coordinates near the f64 limit can overflow in the sums: refuse
    // before anything is made.
    if edge_points
        .iter()
        .chain(&vert_points)
        .chain(&centres)
        .any(|p| !p.is_finite())
    {
        return Err(OpError::Degenerate(
            "subdivide: a new position overflows (coordinates near the limit of f64)".into(),
        ));
    }

    // 2. Topology. Every region edge split at its middle; the children
    // inherit the sharpness less one. Stored normals are refreshed once,
    // at the end, from the final positions.
    let mut new_verts = Vec::with_capacity(edges.len() + region.len());
    let mut new_edges = Vec::new();
    let mut child_sharp: FxHashMap<EdgeId, (f64, f64)> = FxHashMap::default();
    let mut midpoints = SlotSet::new(edges.len(), mesh.vert_capacity() + edges.len());
    for (&e, &point) in edges.iter().zip(&edge_points) {
        let (m, rest) = mesh.split_edge_unrefreshed(e, 0.5)?;
        mesh.place(m, point);
        new_verts.push(m);
        new_edges.push(rest);
        midpoints.insert(m.index());
        if let Some(&(s, stored)) = sharp.get(&e) {
            if s - 1.0 > 0.0 || stored - 1.0 > 0.0 {
                let child = ((s - 1.0).max(0.0), (stored - 1.0).max(0.0));
                child_sharp.insert(e, child);
                child_sharp.insert(rest, child);
            }
        }
    }
    let mut faces = Vec::with_capacity(region.len() * 4);
    let mut mids: Vec<VertId> = Vec::new();
    for (&f, &centre_point) in region.iter().zip(&centres) {
        // The face's midpoints, in winding order from its first corner:
        // its ring alternates corner, midpoint.
        mids.clear();
        mids.extend(mesh.face_verts(f).filter(|v| midpoints.contains(v.index())));
        debug_assert_eq!(mids.len() * 2, mesh.face_len(f));
        faces.push(f);
        match options.scheme {
            Scheme::Loop => {
                // Cut the three corners off; `f` keeps the first.
                let (rest, e0) = mesh.split_face_unrefreshed(f, mids[0], mids[1])?;
                let (rest2, e1) = mesh.split_face_unrefreshed(rest, mids[1], mids[2])?;
                let (centre, e2) = mesh.split_face_unrefreshed(rest2, mids[2], mids[0])?;
                new_edges.extend([e0, e1, e2]);
                faces.extend([rest, rest2, centre]);
            }
            _ => {
                // The first quad is cut off along a diagonal whose middle
                // becomes the face point; then one quad per other midpoint.
                let (mut rest, diagonal) = mesh.split_face_unrefreshed(f, mids[0], mids[1])?;
                let (centre, half) = mesh.split_edge_unrefreshed(diagonal, 0.5)?;
                mesh.place(centre, centre_point);
                new_verts.push(centre);
                new_edges.extend([diagonal, half]);
                for &m in &mids[2..] {
                    let (next, spoke) = mesh.split_face_unrefreshed(rest, centre, m)?;
                    faces.push(rest);
                    new_edges.push(spoke);
                    rest = next;
                }
                faces.push(rest);
            }
        }
    }

    // 3. The cage's vertices move last (the edge and face points above
    // were computed from their old positions).
    for (&v, &p) in verts.iter().zip(&vert_points) {
        mesh.place(v, p);
    }
    // Every new region face changed; so did each face outside the region
    // that holds a moved cage vertex or a new midpoint. Only vertices with
    // a face outside the region are walked for those.
    let faces = super::into_canonical(faces);
    let mut in_refined = SlotSet::new(faces.len(), mesh.face_capacity());
    for f in &faces {
        in_refined.insert(f.index());
    }
    let view: &Mesh = mesh;
    let mut touched: Vec<FaceId> = verts
        .par_iter()
        .chain(new_verts.par_iter())
        .flat_map_iter(|&v| {
            view.vert_faces(v)
                .filter(|f| !in_refined.contains(f.index()))
                .collect::<Vec<_>>()
        })
        .collect();
    touched.extend_from_slice(&faces);
    mesh.refresh_normals_of(&super::into_canonical(touched));
    Ok(Level {
        faces,
        new_verts,
        new_edges,
        sharp: child_sharp,
    })
}

/// The edge point of region edge `e` (its midpoint where sharp).
fn edge_point(mesh: &Mesh, e: EdgeId, options: Subdivision, cage: &Cage) -> DVec3 {
    let [a, b] = mesh.edge_verts(e);
    let (pa, pb) = (mesh.position(a), mesh.position(b));
    let mid = (pa + pb) * 0.5;
    let s = cage.sharpness(e).unwrap_or(INFINITE);
    match options.scheme {
        Scheme::Simple => mid,
        _ if s >= 1.0 => mid,
        Scheme::CatmullClark => {
            let Some([f0, f1]) = region_pair(mesh, e, &cage.in_region) else {
                return mid;
            };
            let smooth = (pa + pb + cage.face_point(f0) + cage.face_point(f1)) * 0.25;
            smooth.lerp(mid, s)
        }
        Scheme::Loop => {
            let Some([f0, f1]) = region_pair(mesh, e, &cage.in_region) else {
                return mid;
            };
            let opposite = |f: FaceId| {
                mesh.face_verts(f)
                    .find(|&v| v != a && v != b)
                    .map_or(mid, |v| mesh.position(v))
            };
            let smooth = (pa + pb) * 0.375 + (opposite(f0) + opposite(f1)) * 0.125;
            smooth.lerp(mid, s)
        }
    }
}

/// A vertex's rule (Sdc `Crease::Rule`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Rule {
    Smooth,
    Crease,
    Corner,
}

/// The rule for a vertex on `sharp_edges` sharp edges.
fn rule_of(sharp_edges: usize, corner: bool) -> Rule {
    match sharp_edges {
        _ if corner => Rule::Corner,
        0 | 1 => Rule::Smooth,
        2 => Rule::Crease,
        _ => Rule::Corner,
    }
}

/// The refined position of cage vertex `v` (Catmull–Clark or Loop).
fn vertex_point(mesh: &Mesh, v: VertId, options: Subdivision, cage: &Cage) -> DVec3 {
    let p = mesh.position(v);
    // The region's edges and faces around `v`, in canonical order (sums
    // in a fixed order: the same bits on every run).
    let mut edges: Vec<EdgeId> = mesh
        .vert_edges(v)
        .filter(|&e| cage.sharpness(e).is_some())
        .collect();
    edges.sort_unstable();
    let mut faces: Vec<FaceId> = mesh
        .vert_faces(v)
        .filter(|f| cage.in_region.contains(f.index()))
        .collect();
    faces.sort_unstable();
    faces.dedup();
    let sharpness: Vec<f64> = edges
        .iter()
        .map(|&e| cage.sharpness(e).unwrap_or(INFINITE))
        .collect();
    let boundary_edges = edges
        .iter()
        .zip(&sharpness)
        .filter(|&(&e, &s)| s == INFINITE && region_pair(mesh, e, &cage.in_region).is_none())
        .count();
    // A boundary vertex of one face is a corner under EDGE_AND_CORNER; so
    // is a vertex where fans of faces meet only at the vertex (two cones
    // apex to apex), as OpenSubdiv makes non-manifold vertices.
    let corner =
        (options.boundary == Boundary::KeepCorners && boundary_edges > 0 && faces.len() == 1)
            || fans(mesh, v, &faces, &cage.in_region) > 1;
    let parent = rule_of(sharpness.iter().filter(|&&s| s > 0.0).count(), corner);
    let child = rule_of(sharpness.iter().filter(|&&s| s - 1.0 > 0.0).count(), corner);

    // `spent`: the sharpness the level has used up (0 for the parent's
    // rule, 1 for the child's), so a crease's two edges are the right ones.
    let at = |rule: Rule, spent: f64| -> DVec3 {
        match rule {
            Rule::Corner => p,
            Rule::Crease => {
                // The two sharp edges' far ends.
                let ends: Vec<DVec3> = edges
                    .iter()
                    .zip(&sharpness)
                    .filter(|(_, &s)| s - spent > 0.0)
                    .map(|(&e, _)| mesh.position(mesh.edge_other_vert(e, v)))
                    .collect();
                (ends[0] + p * 6.0 + ends[1]) * 0.125
            }
            Rule::Smooth => {
                let n = edges.len() as f64;
                let ring: DVec3 = edges
                    .iter()
                    .map(|&e| mesh.position(mesh.edge_other_vert(e, v)))
                    .sum();
                match options.scheme {
                    Scheme::Loop => {
                        let c = 0.375 + 0.25 * libm::cos(2.0 * std::f64::consts::PI / n);
                        let beta = (0.625 - c * c) / n;
                        p * (1.0 - n * beta) + ring * beta
                    }
                    _ => {
                        let centres: DVec3 = faces.iter().map(|&f| cage.face_point(f)).sum();
                        (p * (n - 2.0) + ring / n + centres / n) / n
                    }
                }
            }
        }
    };
    let parent_point = at(parent, 0.0);
    if parent == child {
        return parent_point;
    }
    // Blend by the mean sharpness of the edges that turn smooth.
    let turning: Vec<f64> = sharpness
        .iter()
        .copied()
        .filter(|&s| s > 0.0 && s - 1.0 <= 0.0)
        .collect();
    if turning.is_empty() {
        return parent_point;
    }
    let weight = (turning.iter().sum::<f64>() / turning.len() as f64).min(1.0);
    parent_point * weight + at(child, 1.0) * (1.0 - weight)
}

/// How many fans of `faces` (the region's faces at `v`) are joined
/// through `v`'s edges that have two region faces: one on a manifold
/// vertex, more where surfaces touch only at `v`.
fn fans(mesh: &Mesh, v: VertId, faces: &[FaceId], in_region: &SlotSet) -> usize {
    if faces.len() <= 1 {
        return faces.len();
    }
    let mut groups = crate::geom::union_find::UnionFind::new(faces.len());
    let at = |f: FaceId| faces.binary_search(&f).ok();
    for e in mesh.vert_edges(v) {
        if let Some([a, b]) = region_pair(mesh, e, in_region) {
            if let (Some(i), Some(j)) = (at(a), at(b)) {
                groups.union(i as u32, j as u32);
            }
        }
    }
    let mut roots: Vec<u32> = (0..faces.len() as u32).map(|i| groups.find(i)).collect();
    roots.sort_unstable();
    roots.dedup();
    roots.len()
}

/// The region's two faces on edge `e`, ascending; `None` unless there are
/// exactly two (a boundary or non-manifold edge of the region).
fn region_pair(mesh: &Mesh, e: EdgeId, in_region: &SlotSet) -> Option<[FaceId; 2]> {
    let mut pair: [Option<FaceId>; 2] = [None; 2];
    for f in mesh.edge_faces(e).filter(|f| in_region.contains(f.index())) {
        match pair {
            [None, _] => pair[0] = Some(f),
            [Some(a), None] if a != f => pair[1] = Some(f),
            [Some(a), Some(b)] if a != f && b != f => return None,
            _ => {}
        }
    }
    let [Some(a), Some(b)] = pair else {
        return None;
    };
    Some([a.min(b), a.max(b)])
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::kernel::ops::create::create_cube;
    use crate::kernel::{AttrValue, Domain};

    fn options(scheme: Scheme, levels: u32) -> Subdivision {
        Subdivision {
            scheme,
            levels,
            boundary: Boundary::KeepCorners,
            crease_angle: None,
        }
    }

    fn cube() -> (Mesh, Vec<FaceId>) {
        let mut mesh = Mesh::new();
        create_cube(&mut mesh, 2.0).unwrap();
        let faces = mesh.face_ids().collect();
        (mesh, faces)
    }

    #[test]
    fn a_cube_refines_to_the_catmull_clark_counts() {
        for (levels, want) in [(1, (26, 48, 24)), (2, (98, 192, 96)), (3, (386, 768, 384))] {
            let (mut mesh, faces) = cube();
            let done = subdivide(
                &mut mesh,
                &faces,
                options(Scheme::CatmullClark, levels),
                &[],
            )
            .unwrap();
            mesh.validate().unwrap();
            let got = (mesh.vert_count(), mesh.edge_count(), mesh.face_count());
            assert_eq!(got, want, "level {levels}");
            assert_eq!(done.made.faces.len(), want.2);
            let report = mesh.report();
            assert!(report.watertight && report.consistently_oriented);
            assert!(mesh.face_ids().all(|f| mesh.face_len(f) == 4));
        }
        // Level 1 by hand: a corner of valence 3 goes to
        // ((n − 2) v + Σ edge ends / n + Σ face points / n) / n.
        let (mut mesh, faces) = cube();
        subdivide(&mut mesh, &faces, options(Scheme::CatmullClark, 1), &[]).unwrap();
        // At (1, 1, 1): edge ends and face points each sum to (1, 1, 1),
        // so the corner goes to (1 + 1/3 + 1/3) / 3 = 5/9.
        let corner = DVec3::splat(5.0 / 9.0);
        let far = mesh
            .vert_ids()
            .map(|v| mesh.position(v))
            .max_by(|a, b| a.element_sum().total_cmp(&b.element_sum()))
            .unwrap();
        assert!((far - corner).length() < 1e-15, "{far} vs {corner}");
    }

    #[test]
    fn loop_on_a_tetrahedron_gives_loops_weights() {
        // A regular tetrahedron centred at the origin: the corners sum to
        // zero, so with β = 3/16 (valence 3) a corner goes to v / 4 and an
        // edge point 3/8 (a + b) + 1/8 (c + d) to (a + b) / 4.
        let mut mesh = Mesh::new();
        let p = [
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(1.0, -1.0, -1.0),
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(-1.0, -1.0, 1.0),
        ];
        let v: Vec<VertId> = p.iter().map(|&q| mesh.make_vert(q)).collect();
        for ring in [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]] {
            mesh.make_face(&ring.map(|i| v[i])).unwrap();
        }
        let faces: Vec<FaceId> = mesh.face_ids().collect();
        let done = subdivide(&mut mesh, &faces, options(Scheme::Loop, 1), &[]).unwrap();
        mesh.validate().unwrap();
        assert_eq!(
            (mesh.vert_count(), mesh.edge_count(), mesh.face_count()),
            (10, 24, 16)
        );
        assert!(mesh.face_ids().all(|f| mesh.face_len(f) == 3));
        for (i, &corner) in v.iter().enumerate() {
            assert!((mesh.position(corner) - p[i] / 4.0).length() < 1e-15);
        }
        let mut mids: Vec<DVec3> = done.made.verts.iter().map(|&m| mesh.position(m)).collect();
        let mut want: Vec<DVec3> = (0..4)
            .flat_map(|i| (i + 1..4).map(move |j| (i, j)))
            .map(|(i, j)| (p[i] + p[j]) / 4.0)
            .collect();
        let key = |q: &DVec3| (q.x, q.y, q.z);
        mids.sort_by(|a, b| key(a).partial_cmp(&key(b)).unwrap());
        want.sort_by(|a, b| key(a).partial_cmp(&key(b)).unwrap());
        assert_eq!(mids.len(), 6);
        for (m, w) in mids.iter().zip(&want) {
            assert!((*m - *w).length() < 1e-15, "{m} vs {w}");
        }
        assert_eq!(mesh.report().volume.map(f64::signum), Some(1.0));
    }

    #[test]
    fn loop_refuses_faces_that_are_not_triangles() {
        let (mut mesh, faces) = cube();
        let err = subdivide(&mut mesh, &faces, options(Scheme::Loop, 1), &[]).unwrap_err();
        assert!(
            matches!(err, OpError::Parameter { name: "scheme", .. }),
            "{err}"
        );
        assert_eq!(mesh.vert_count(), 8, "nothing made before the refusal");
    }

    #[test]
    fn simple_keeps_the_shape_and_an_infinite_crease_keeps_the_cube() {
        let (mut mesh, faces) = cube();
        subdivide(&mut mesh, &faces, options(Scheme::Simple, 2), &[]).unwrap();
        mesh.validate().unwrap();
        let report = mesh.report();
        assert!((report.area - 24.0).abs() < 1e-12 && (report.volume.unwrap() - 8.0).abs() < 1e-12);
        // Every edge infinitely sharp: Catmull–Clark points on sharp edges
        // are midpoints and the corners stay, so the cube stays a cube.
        let (mut mesh, faces) = cube();
        let creases: Vec<(EdgeId, f64)> = mesh.edge_ids().map(|e| (e, 10.0)).collect();
        let done = subdivide(
            &mut mesh,
            &faces,
            options(Scheme::CatmullClark, 2),
            &creases,
        )
        .unwrap();
        assert!((mesh.report().volume.unwrap() - 8.0).abs() < 1e-12);
        assert!(done.creases.iter().all(|&(_, s)| s == SHARPNESS_INFINITE));
        assert_eq!(done.creases.len(), 12 * 4, "each cube edge in four pieces");
        // By angle: the same.
        let (mut mesh, faces) = cube();
        let by_angle = Subdivision {
            crease_angle: Some(45.0),
            ..options(Scheme::CatmullClark, 2)
        };
        subdivide(&mut mesh, &faces, by_angle, &[]).unwrap();
        assert!((mesh.report().volume.unwrap() - 8.0).abs() < 1e-12);
    }

    #[test]
    fn two_cones_touching_at_their_apex_keep_it_as_a_corner() {
        // Two square pyramids (heights 1 and 2, so a smooth rule would move
        // the apex), apex to apex at the origin: every edge has
        // two faces, but the apex joins two fans; OpenSubdiv makes it a
        // corner, so it stays where it is.
        let mut mesh = Mesh::new();
        let apex = mesh.make_vert(DVec3::ZERO);
        for z in [1.0, -2.0] {
            let base: Vec<VertId> = [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)]
                .iter()
                .map(|&(x, y)| mesh.make_vert(DVec3::new(x, y, z)))
                .collect();
            for k in 0..4 {
                let (a, b) = (base[k], base[(k + 1) % 4]);
                let ring = if z > 0.0 { [apex, a, b] } else { [apex, b, a] };
                mesh.make_face(&ring).unwrap();
            }
            let cap: Vec<VertId> = if z > 0.0 {
                base.iter().rev().copied().collect()
            } else {
                base.clone()
            };
            mesh.make_face(&cap).unwrap();
        }
        let faces: Vec<FaceId> = mesh.face_ids().collect();
        subdivide(&mut mesh, &faces, options(Scheme::CatmullClark, 2), &[]).unwrap();
        mesh.validate().unwrap();
        assert_eq!(mesh.position(apex), DVec3::ZERO);
    }

    #[test]
    fn levels_outside_one_to_eight_are_refused_and_nothing_is_asked_of_nothing() {
        let (mut mesh, faces) = cube();
        for levels in [0, 9, u32::MAX] {
            let err = subdivide(
                &mut mesh,
                &faces,
                options(Scheme::CatmullClark, levels),
                &[],
            )
            .unwrap_err();
            assert!(matches!(err, OpError::Parameter { name: "levels", .. }));
        }
        let done = subdivide(&mut mesh, &[], options(Scheme::CatmullClark, 8), &[]).unwrap();
        assert!(done.made.is_empty());
        assert_eq!(mesh.vert_count(), 8);
    }

    #[test]
    fn overflowing_positions_are_refused_before_anything_is_made() {
        let mut mesh = Mesh::new();
        let v: Vec<VertId> = [
            (1.5e308, 0.0),
            (1.6e308, 0.0),
            (1.6e308, 1.0),
            (1.5e308, 1.0),
        ]
        .iter()
        .map(|&(x, y)| mesh.make_vert(DVec3::new(x, y, 0.0)))
        .collect();
        let f = mesh.make_face(&v).unwrap();
        let err = subdivide(&mut mesh, &[f], options(Scheme::CatmullClark, 1), &[]).unwrap_err();
        assert!(err.to_string().contains("overflows"), "{err}");
        assert_eq!((mesh.vert_count(), mesh.face_count()), (4, 1));
    }

    #[test]
    fn sharpness_is_spent_one_level_at_a_time() {
        let (mut mesh, faces) = cube();
        let e = mesh.edge_ids().next().unwrap();
        let done = subdivide(
            &mut mesh,
            &faces,
            options(Scheme::CatmullClark, 2),
            &[(e, 2.5)],
        )
        .unwrap();
        assert_eq!(done.creases.len(), 4);
        assert!(done.creases.iter().all(|&(_, s)| (s - 0.5).abs() < 1e-15));
    }

    #[test]
    fn a_region_subdivides_alone_and_its_neighbours_gain_midpoints() {
        let (mut mesh, faces) = cube();
        mesh.add_layer("part", Domain::Face, AttrValue::Int(0))
            .unwrap();
        let top = faces
            .iter()
            .copied()
            .find(|&f| mesh.face_normal(f).z > 0.5)
            .unwrap();
        let _ = mesh.set_attr("part", Domain::Face, top.index(), AttrValue::Int(7));
        let done = subdivide(&mut mesh, &[top], options(Scheme::CatmullClark, 1), &[]).unwrap();
        mesh.validate().unwrap();
        assert_eq!(mesh.face_count(), 6 - 1 + 4);
        assert_eq!(done.made.faces.len(), 4);
        for &f in &done.made.faces {
            assert_eq!(
                mesh.attr("part", Domain::Face, f.index()),
                Some(AttrValue::Int(7))
            );
        }
        // The four side faces are pentagons now, still flat: the border
        // is sharp, its midpoints and (kept) corners stay in place.
        let sides: Vec<FaceId> = mesh.face_ids().filter(|&f| mesh.face_len(f) == 5).collect();
        assert_eq!(sides.len(), 4);
        let report = mesh.report();
        assert!(report.watertight);
        assert!(
            (report.volume.unwrap() - 8.0).abs() < 1e-12,
            "the top's border stays"
        );
    }
}
