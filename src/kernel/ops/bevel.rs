//! Bevel (issue 35): selected edges become bands of `segments` faces
//! (vertices with `on = "vertices"`: corners cut off), as Blender's
//! `bmesh.ops.bevel` (bmesh_bevel.c), whose definitions it follows:
//!
//! - **Offsets.** Each beveled edge's faces get an offset line parallel to
//!   it, at the distance the `offset_type` asks for: `offset` is that
//!   distance; `width` the chord across the band (`w / 2 sin(θ/2)`, θ the
//!   angle between the faces); `depth` the distance from the edge to the
//!   band (`d / cos(θ/2)`); `percent` a share of the adjacent edges'
//!   lengths. Where two beveled edges meet in a face, the new corner is
//!   where their offset lines meet; next to an edge that is not beveled it
//!   slides along that edge (one edge between two beveled ones: the point
//!   on it that both offset lines reach, their mean if they differ).
//! - **Profile.** Between the two new corners of a beveled edge at a
//!   vertex lies a superellipse `x^r + y^r = 1` (`r = −2 ln 2 / ln p`,
//!   `p = profile`: 0.5 a quarter circle, 0.25 a straight chamfer, 1 a
//!   square corner) in the parallelogram spanned by the corners and the
//!   point of the edge nearest to them, `segments` chords of equal length
//!   in the unit square (Blender's `find_even_superellipse_chords`).
//! - **Corners.** The hole left at each vertex is one face (a cube's
//!   corner: a triangle, so a cube's 12 edges with 1 segment give 24
//!   vertices, 48 edges, 26 faces, as Blender). With more segments, where
//!   every edge at a vertex is beveled, the hole is filled with quads: one
//!   grid per corner between the profiles' halves and spokes to a centre
//!   on the superellipsoid through the vertex (Blender's "adj" pattern; at
//!   2 segments the same points as Blender, beyond that a Coons patch
//!   rather than Blender's subdivision, so interior points differ).
//! - **Clamp overlap.** Offsets are scaled down together until no new
//!   corner passes another along an edge (Blender's global limit).
//!
//! Edges with other than two faces are left sharp, as Blender leaves them.
//! Built from Euler operators (`make_vert`, `make_face`, `kill_face`,
//! `kill_edge`, `kill_vert`); new faces copy the attributes (part,
//! material) of the face they replace or border, new vertices those of the
//! vertex they come from.

use glam::DVec3;
use rustc_hash::{FxHashMap, FxHashSet};

use super::{into_canonical, OpError, Selection};
use crate::kernel::{EdgeId, FaceId, Mesh, VertId};

/// How `width` is measured (Blender's offset types).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OffsetType {
    /// From the edge to each new edge, in its faces.
    Offset,
    /// Across the band.
    Width,
    /// From the edge to the band.
    Depth,
    /// A percentage of the adjacent edges' lengths.
    Percent,
}

/// What [`bevel`] bevels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Affect {
    Edges,
    Vertices,
}

/// What [`bevel`] is asked to do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bevel {
    pub width: f64,
    pub offset_type: OffsetType,
    pub segments: u32,
    /// 0.5 round, 0.25 straight, 1 square (Blender's profile).
    pub profile: f64,
    pub clamp_overlap: bool,
    pub affect: Affect,
}

/// The most segments a bevel may have.
pub const MAX_SEGMENTS: u32 = 1000;

/// A point of the result: an old vertex kept, or a new one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Pt {
    Old(VertId),
    New(u32),
}

/// One face corner at a beveled vertex, in fan order.
#[derive(Debug, Clone, Copy)]
struct Corner {
    face: FaceId,
    /// The edge entering the vertex in the face's ring, and leaving it.
    e_in: EdgeId,
    e_out: EdgeId,
    /// The neighbours along them.
    prev: VertId,
    next: VertId,
}

/// The faces around a vertex, each followed by the one across its
/// `e_out`; `closed` when the last leads back to the first.
struct Fan {
    corners: Vec<Corner>,
    closed: bool,
}

/// Bevels `edges` (or, with [`Affect::Vertices`], `verts`).
///
/// Result: the new vertices and the faces made (bands, corners and the
/// faces that replaced those around beveled vertices).
pub fn bevel(
    mesh: &mut Mesh,
    edges: &[EdgeId],
    verts: &[VertId],
    options: Bevel,
) -> Result<Selection, OpError> {
    check_options(&options)?;
    let edges = into_canonical(edges.to_vec());
    let verts = into_canonical(verts.to_vec());
    for &e in &edges {
        mesh.check_edge(e)?;
    }
    for &v in &verts {
        mesh.check_vert(v)?;
    }
    if options.affect == Affect::Vertices
        && matches!(options.offset_type, OffsetType::Width | OffsetType::Depth)
    {
        return Err(OpError::parameter(
            "offset_type",
            "a vertex bevel measures along the edges: `offset` or `percent`",
        ));
    }
    if options.width == 0.0 {
        return Ok(Selection::new()); // nothing to cut, as Blender
    }
    let beveled: FxHashSet<EdgeId> = match options.affect {
        Affect::Edges => edges
            .iter()
            .copied()
            .filter(|&e| mesh.edge_face_count(e) == 2)
            .collect(),
        Affect::Vertices => FxHashSet::default(),
    };
    let centres: Vec<VertId> = match options.affect {
        Affect::Edges => {
            let mut c: Vec<VertId> = edges
                .iter()
                .filter(|e| beveled.contains(e))
                .flat_map(|&e| mesh.edge_verts(e))
                .collect();
            c = into_canonical(c);
            c
        }
        Affect::Vertices => verts
            .iter()
            .copied()
            .filter(|&v| mesh.vert_faces(v).next().is_some())
            .collect(),
    };
    if centres.is_empty() {
        return Ok(Selection::new());
    }
    let mut fans = Vec::with_capacity(centres.len());
    for &v in &centres {
        fans.push(fan(mesh, v)?);
    }
    let ctx = Context {
        mesh,
        options: &options,
        beveled: &beveled,
        chords: superellipse_chords(options.segments as usize, options.profile),
    };
    let mut plan = ctx.plan(&centres, &fans, 1.0)?;
    if options.clamp_overlap && plan.overlap_limit < 1.0 {
        plan = ctx.plan(&centres, &fans, plan.overlap_limit)?;
    }
    if plan.points.iter().any(|(p, _)| !p.is_finite()) {
        return Err(OpError::Degenerate(
            "bevel: a new position overflows (coordinates or width near the limit of f64)".into(),
        ));
    }
    let room =
        |capacity: usize, added: usize| (capacity as u128 + added as u128) < u128::from(u32::MAX);
    if !room(mesh.vert_capacity(), plan.points.len())
        || !room(mesh.face_capacity(), plan.faces.len())
        || !room(mesh.edge_capacity(), 4 * plan.faces.len())
    {
        return Err(OpError::parameter(
            "segments",
            "the bevel would exceed the mesh's id space",
        ));
    }
    build(mesh, &centres, plan)
}

fn check_options(o: &Bevel) -> Result<(), OpError> {
    if !(o.width.is_finite() && o.width >= 0.0) {
        return Err(OpError::parameter("width", "must be a finite number ≥ 0"));
    }
    if o.offset_type == OffsetType::Percent && o.width > 100.0 {
        return Err(OpError::parameter("width", "a percentage lies in 0..=100"));
    }
    if o.segments == 0 || o.segments > MAX_SEGMENTS {
        return Err(OpError::parameter(
            "segments",
            format!("must lie in 1..={MAX_SEGMENTS}, got {}", o.segments),
        ));
    }
    if !(o.profile > 0.0 && o.profile <= 1.0) {
        return Err(OpError::parameter("profile", "must lie in (0, 1]"));
    }
    Ok(())
}

/// The faces around `v` in fan order (each face's `e_out` is the next
/// face's `e_in`), starting after a boundary where there is one.
fn fan(mesh: &Mesh, v: VertId) -> Result<Fan, OpError> {
    let mut corners: Vec<Corner> = Vec::new();
    let mut faces: Vec<FaceId> = mesh.vert_faces(v).collect();
    faces.sort_unstable();
    faces.dedup();
    for &f in &faces {
        let ring: Vec<VertId> = mesh.face_verts(f).collect();
        let n = ring.len();
        for i in 0..n {
            if ring[i] != v {
                continue;
            }
            let (prev, next) = (ring[(i + n - 1) % n], ring[(i + 1) % n]);
            let (Some(e_in), Some(e_out)) = (mesh.find_edge(prev, v), mesh.find_edge(v, next))
            else {
                continue;
            };
            corners.push(Corner {
                face: f,
                e_in,
                e_out,
                prev,
                next,
            });
        }
    }
    let non_manifold = || {
        OpError::Degenerate(format!(
            "bevel: the faces around vertex {} do not form one fan (a non-manifold vertex); \
             bevel the edges on either side separately, or `merge`/`delete` first",
            v.index()
        ))
    };
    if corners
        .iter()
        .any(|c| mesh.edge_face_count(c.e_in) > 2 || mesh.edge_face_count(c.e_out) > 2)
        || corners.iter().any(|c| c.e_in == c.e_out)
    {
        return Err(non_manifold());
    }
    // Start at a corner whose e_in has no face before it (a boundary).
    let by_in: FxHashMap<EdgeId, usize> = corners
        .iter()
        .enumerate()
        .map(|(i, c)| (c.e_in, i))
        .collect();
    if by_in.len() != corners.len() {
        return Err(non_manifold());
    }
    let start = corners
        .iter()
        .position(|c| {
            mesh.edge_face_count(c.e_in) == 1 || !corners.iter().any(|d| d.e_out == c.e_in)
        })
        .unwrap_or(0);
    let mut order = vec![corners[start]];
    let mut closed = false;
    loop {
        let last = *order.last().unwrap();
        match by_in.get(&last.e_out) {
            Some(&i) if i == start => {
                closed = true;
                break;
            }
            Some(&i) if order.len() < corners.len() => order.push(corners[i]),
            _ => break,
        }
    }
    if order.len() != corners.len() {
        return Err(non_manifold());
    }
    Ok(Fan {
        corners: order,
        closed,
    })
}

struct Context<'a> {
    mesh: &'a Mesh,
    options: &'a Bevel,
    beveled: &'a FxHashSet<EdgeId>,
    /// The profile's points in the unit square, (1,0) to (0,1).
    chords: Vec<(f64, f64)>,
}

/// Everything the bevel makes, computed before anything is made.
struct Plan {
    /// New points: position and the vertex whose attributes they take.
    points: Vec<(DVec3, VertId)>,
    /// The ring each face around a beveled vertex gets.
    rings: Vec<(FaceId, Vec<Pt>)>,
    /// New faces and the face whose attributes they copy.
    faces: Vec<(Vec<Pt>, FaceId)>,
    /// The largest factor of the offsets at which nothing overlaps.
    overlap_limit: f64,
}

/// What one vertex contributes: the points replacing it in each face
/// corner, the profile across each beveled edge (from the corner before
/// it in the fan to the one after), and where slid edges end.
#[derive(Default)]
struct VertexPlan {
    corner: Vec<Vec<Pt>>,
    /// Per fan corner: the profile across its `e_out`, if beveled.
    arc: Vec<Option<Vec<Pt>>>,
    /// False when the hole is already closed (a terminal edge's profile
    /// taken into the face across from it).
    cap: bool,
}

impl Context<'_> {
    fn plan(&self, centres: &[VertId], fans: &[Fan], scale: f64) -> Result<Plan, OpError> {
        let mut points: Vec<(DVec3, VertId)> = Vec::new();
        let mut per_vertex: Vec<VertexPlan> = Vec::with_capacity(centres.len());
        let mut limit = f64::INFINITY;
        // Along each edge, how far each end's new points reach.
        let mut reach: FxHashMap<EdgeId, f64> = FxHashMap::default();
        let mut ends: FxHashMap<(EdgeId, VertId), Vec<Pt>> = FxHashMap::default();
        for (&v, fan) in centres.iter().zip(fans) {
            let vp = self.plan_vertex(v, fan, scale, &mut points, &mut reach)?;
            for (i, c) in fan.corners.iter().enumerate() {
                if let Some(arc) = &vp.arc[i] {
                    ends.insert((c.e_out, v), arc.clone());
                }
            }
            per_vertex.push(vp);
        }
        for (&e, &used) in &reach {
            let length = self.mesh.edge_length(e);
            if used > length * (1.0 + 1e-12) {
                limit = limit.min(length / used);
            }
        }
        // Rings of the faces around beveled vertices.
        let index: FxHashMap<VertId, usize> =
            centres.iter().enumerate().map(|(i, &v)| (v, i)).collect();
        let mut affected: Vec<FaceId> = centres
            .iter()
            .flat_map(|&v| self.mesh.vert_faces(v))
            .collect();
        affected = into_canonical(affected);
        let mut rings = Vec::with_capacity(affected.len());
        for &f in &affected {
            let mut ring: Vec<Pt> = Vec::new();
            for x in self.mesh.face_verts(f) {
                match index.get(&x) {
                    Some(&i) => {
                        let k = fans[i]
                            .corners
                            .iter()
                            .position(|c| c.face == f)
                            .expect("the fan holds each face at its vertex");
                        ring.extend_from_slice(&per_vertex[i].corner[k]);
                    }
                    None => ring.push(Pt::Old(x)),
                }
            }
            let ring = cyclic_dedup(ring);
            if ring.len() < 3 {
                return Err(OpError::Degenerate(format!(
                    "bevel: face {} would collapse (a width larger than the face allows; \
                     set `clamp_overlap = true` or a smaller width)",
                    f.index()
                )));
            }
            rings.push((f, ring));
        }
        let mut faces: Vec<(Vec<Pt>, FaceId)> = Vec::new();
        // Bands along beveled edges, in edge order.
        let mut bands: Vec<EdgeId> = self.beveled.iter().copied().collect();
        bands = into_canonical(bands);
        for &e in &bands {
            let [u, w] = self.mesh.edge_verts(e);
            let (Some(pu), Some(pw)) = (ends.get(&(e, u)), ends.get(&(e, w))) else {
                continue;
            };
            let n = pu.len() - 1;
            let source = self
                .mesh
                .edge_faces(e)
                .min()
                .expect("a beveled edge has two faces");
            for k in 0..n {
                let ring = cyclic_dedup(vec![pw[n - k], pu[k], pu[k + 1], pw[n - k - 1]]);
                if ring.len() >= 3 {
                    faces.push((ring, source));
                }
            }
        }
        // The corner faces at each vertex.
        for (i, &v) in centres.iter().enumerate() {
            self.corner_faces(v, &fans[i], &per_vertex[i], &mut points, &mut faces);
        }
        Ok(Plan {
            points,
            rings,
            faces,
            overlap_limit: limit,
        })
    }

    fn offset_of(&self, e: EdgeId, face_side: FaceId, v: VertId, scale: f64) -> f64 {
        let w = self.options.width * scale;
        match self.options.offset_type {
            OffsetType::Offset => w,
            OffsetType::Width | OffsetType::Depth => {
                let normals: Vec<DVec3> = self
                    .mesh
                    .edge_faces(e)
                    .map(|f| self.mesh.face_normal(f))
                    .collect();
                // The angle between the faces (π − the angle of normals).
                let theta = std::f64::consts::PI - angle(normals[0], normals[1]);
                let z = if self.options.offset_type == OffsetType::Width {
                    (2.0 * libm::sin(theta / 2.0)).abs()
                } else {
                    libm::cos(theta / 2.0).abs()
                };
                if z < 1e-6 {
                    0.01 * w
                } else {
                    w / z
                }
            }
            OffsetType::Percent => {
                // The offset at which the new edge meets the adjacent edge
                // of `face_side` at `width` percent of its length.
                let ring: Vec<VertId> = self.mesh.face_verts(face_side).collect();
                let n = ring.len();
                let i = ring.iter().position(|&x| x == v).unwrap_or(0);
                let other = self.mesh.edge_other_vert(e, v);
                let neighbour = if ring[(i + 1) % n] == other {
                    ring[(i + n - 1) % n]
                } else {
                    ring[(i + 1) % n]
                };
                let (pv, po, pn) = (
                    self.mesh.position(v),
                    self.mesh.position(other),
                    self.mesh.position(neighbour),
                );
                let a = angle(po - pv, pn - pv);
                (pn - pv).length() * w / 100.0 * libm::sin(a)
            }
        }
    }

    fn plan_vertex(
        &self,
        v: VertId,
        fan: &Fan,
        scale: f64,
        points: &mut Vec<(DVec3, VertId)>,
        reach: &mut FxHashMap<EdgeId, f64>,
    ) -> Result<VertexPlan, OpError> {
        let mesh = self.mesh;
        let pv = mesh.position(v);
        let k = fan.corners.len();
        let dir = |x: VertId| (mesh.position(x) - pv).normalize_or_zero();
        let mut plan = VertexPlan {
            corner: vec![Vec::new(); k],
            arc: vec![None; k],
            cap: true,
        };
        let n = self.options.segments as usize;
        if self.options.affect == Affect::Vertices {
            // Every edge slides: its new end at `width` along it.
            let mut slid: FxHashMap<EdgeId, Pt> = FxHashMap::default();
            let mut slide = |e: EdgeId, x: VertId, points: &mut Vec<(DVec3, VertId)>| -> Pt {
                if let Some(&p) = slid.get(&e) {
                    return p;
                }
                let t = match self.options.offset_type {
                    OffsetType::Percent => mesh.edge_length(e) * self.options.width * scale / 100.0,
                    _ => self.options.width * scale,
                };
                add_reach(reach, e, t);
                let p = new_point_into(points, v, pv + dir(x) * t);
                slid.insert(e, p);
                p
            };
            for (i, c) in fan.corners.iter().enumerate() {
                let a = slide(c.e_in, c.prev, points);
                let b = slide(c.e_out, c.next, points);
                let mut list = vec![a];
                let (pa, pb) = (position(points, a, mesh), position(points, b, mesh));
                for j in 1..n {
                    let p = self.profile_point(pa, pb, pv, j);
                    list.push(new_point_into(points, v, p));
                }
                list.push(b);
                plan.corner[i] = list;
            }
            return Ok(plan);
        }

        let bev = |e: EdgeId| self.beveled.contains(&e);
        // The offset line of beveled edge `e` (to `x`) in face `f` meets
        // the line of edge (v, y) at distance t along it.
        let slide_t = |e: EdgeId, x: VertId, f: FaceId, y: VertId| {
            let off = self.offset_of(e, f, v, scale);
            let s = libm::sin(angle(dir(x), dir(y)));
            if s.abs() < 1e-12 {
                off
            } else {
                off / s
            }
        };
        // Where each non-beveled edge at v ends (by fan index of the
        // corner whose e_out it is, or e_in of the first for open fans).
        let mut end: FxHashMap<EdgeId, Pt> = FxHashMap::default();
        let edges_in_order: Vec<(EdgeId, VertId)> = {
            let mut list: Vec<(EdgeId, VertId)> =
                fan.corners.iter().map(|c| (c.e_in, c.prev)).collect();
            if !fan.closed {
                let last = fan.corners[k - 1];
                list.push((last.e_out, last.next));
            }
            list
        };
        // Edge j sits between corner j-1 (its e_out) and corner j (its e_in).
        for (j, &(e, x)) in edges_in_order.iter().enumerate() {
            if bev(e) {
                continue;
            }
            let before = if j > 0 {
                Some(fan.corners[j - 1])
            } else if fan.closed {
                Some(fan.corners[k - 1])
            } else {
                None
            };
            let after = fan.corners.get(j).copied();
            let mut ts = Vec::new();
            if let Some(c) = before.filter(|c| bev(c.e_in)) {
                ts.push(slide_t(c.e_in, c.prev, c.face, x));
            }
            if let Some(c) = after.filter(|c| bev(c.e_out)) {
                ts.push(slide_t(c.e_out, c.next, c.face, x));
            }
            if ts.is_empty() {
                end.insert(e, Pt::Old(v));
                continue;
            }
            let t = ts.iter().sum::<f64>() / ts.len() as f64;
            // Between two beveled edges the point stays on the edge (the
            // mean of where the two offset lines reach it); Blender takes
            // where the lines come closest, off the surface where it bends
            // and ill-conditioned where they run nearly parallel.
            add_reach(reach, e, t);
            end.insert(e, new_point_into(points, v, pv + dir(x) * t));
        }
        for (i, c) in fan.corners.iter().enumerate() {
            plan.corner[i] = if bev(c.e_in) && bev(c.e_out) {
                let off_in = self.offset_of(c.e_in, c.face, v, scale);
                let off_out = self.offset_of(c.e_out, c.face, v, scale);
                let p = meet(
                    pv,
                    mesh.position(c.prev),
                    mesh.position(c.next),
                    mesh.face_normal(c.face),
                    off_in,
                    off_out,
                );
                vec![new_point_into(points, v, p)]
            } else {
                let mut list = Vec::new();
                for e in [c.e_in, c.e_out] {
                    if let Some(&p) = end.get(&e) {
                        if list.last() != Some(&p) {
                            list.push(p);
                        }
                    }
                }
                list
            };
        }
        // Two beveled edges whose bands meet at two points only (a ring of
        // edges turning a corner, or running straight through): one shared
        // profile between the bands, its middle at the vertex (Blender's
        // vertex with two boundary vertices), and no corner face.
        let mut distinct: Vec<Pt> = plan.corner.iter().flatten().copied().collect();
        distinct.sort_unstable_by_key(|p| match p {
            Pt::Old(v) => (0, v.index() as u64),
            Pt::New(i) => (1, u64::from(*i)),
        });
        distinct.dedup();
        let bands: Vec<usize> = (0..k).filter(|&i| bev(fan.corners[i].e_out)).collect();
        if fan.closed && bands.len() == 2 && distinct.len() == 2 {
            let (i1, i2) = (bands[0], bands[1]);
            let (a, b) = (
                *plan.corner[i1].last().expect("a corner point"),
                *plan.corner[(i1 + 1) % k].first().expect("a corner point"),
            );
            let (pa, pb) = (position(points, a, mesh), position(points, b, mesh));
            let mut arc = vec![a];
            for j in 1..n {
                let p = self.profile_point(pa, pb, pv, j);
                arc.push(new_point_into(points, v, p));
            }
            arc.push(b);
            for (i, e) in [(i1, fan.corners[i1].e_out), (i2, fan.corners[i2].e_out)] {
                let along = dir(fan.corners[i].next);
                add_reach(reach, e, (pa - pv).dot(along).max((pb - pv).dot(along)));
            }
            plan.arc[i2] = Some(arc.iter().rev().copied().collect());
            plan.arc[i1] = Some(arc);
            plan.cap = false;
            return Ok(plan);
        }
        // Profiles across beveled edges, from the corner before to the one after.
        for i in 0..k {
            let c = fan.corners[i];
            if !bev(c.e_out) {
                continue;
            }
            let Some(d) = fan
                .corners
                .get((i + 1) % k)
                .filter(|_| i + 1 < k || fan.closed)
                .copied()
            else {
                continue;
            };
            let (Some(&a), Some(&b)) = (plan.corner[i].last(), plan.corner[(i + 1) % k].first())
            else {
                continue;
            };
            debug_assert_eq!(d.e_in, c.e_out);
            let (pa, pb) = (position(points, a, mesh), position(points, b, mesh));
            // How far along the edge this end of the band reaches.
            let along = dir(c.next);
            add_reach(
                reach,
                c.e_out,
                (pa - pv).dot(along).max((pb - pv).dot(along)),
            );
            let mut arc = vec![a];
            let middle = nearest_on_line(pv, along, pa, pb);
            for j in 1..n {
                let p = self.profile_point(pa, pb, middle, j);
                arc.push(new_point_into(points, v, p));
            }
            arc.push(b);
            plan.arc[i] = Some(arc);
        }
        // A terminal edge at a corner of three faces: its profile becomes
        // part of the face across from it, as Blender does (no cap face
        // between a straight edge and the arc, in that face's plane).
        let beveled_here = (0..k).filter(|&i| bev(fan.corners[i].e_out)).count();
        let across: Vec<usize> = (0..k)
            .filter(|&i| !bev(fan.corners[i].e_in) && !bev(fan.corners[i].e_out))
            .collect();
        if n > 1 && fan.closed && k == 3 && beveled_here == 1 && across.len() == 1 {
            let arc = plan.arc.iter().flatten().next().expect("one beveled edge");
            plan.corner[across[0]] = arc.iter().rev().copied().collect();
            plan.cap = false;
        }
        Ok(plan)
    }

    /// Point `j` of the profile from `a` to `b` bulging toward `middle`.
    fn profile_point(&self, a: DVec3, b: DVec3, middle: DVec3, j: usize) -> DVec3 {
        let o = a + b - middle;
        let (x, y) = self.chords[j];
        o + (a - o) * x + (b - o) * y
    }

    /// Faces filling the hole at `v`: one polygon, or with more segments
    /// where every edge is beveled, quad grids per corner.
    fn corner_faces(
        &self,
        v: VertId,
        fan: &Fan,
        plan: &VertexPlan,
        points: &mut Vec<(DVec3, VertId)>,
        faces: &mut Vec<(Vec<Pt>, FaceId)>,
    ) {
        // A hole at an open vertex stays open, as Blender leaves it: a
        // face there would span the opening between a band's profile and
        // its chord.
        if !plan.cap || !fan.closed {
            return;
        }
        let k = fan.corners.len();
        let n = self.options.segments as usize;
        let source = fan.corners[0].face;
        let regular = n > 1
            && fan.closed
            && k >= 3
            && match self.options.affect {
                Affect::Edges => (0..k).all(|i| plan.arc[i].is_some() && plan.corner[i].len() == 1),
                Affect::Vertices => true,
            };
        if regular {
            // Sides of the hole, each from one corner point to the next.
            let sides: Vec<Vec<Pt>> = match self.options.affect {
                Affect::Edges => (0..k)
                    .map(|i| plan.arc[i].clone().expect("regular"))
                    .collect(),
                // The faces' arcs, e_in to e_out in each face.
                Affect::Vertices => plan.corner.clone(),
            };
            self.grid_fill(v, &sides, points, faces, source);
            return;
        }
        // In fan order: each corner's points, then the profile across its
        // e_out (vertex bevels: the faces' own arcs, in the corner lists).
        let mut ring: Vec<Pt> = Vec::new();
        for i in 0..k {
            ring.extend_from_slice(&plan.corner[i]);
            if let Some(arc) = &plan.arc[i] {
                ring.extend_from_slice(&arc[1..arc.len() - 1]);
            }
        }
        let mut ring = cyclic_dedup(ring);
        if ring.len() >= 3 {
            ring.reverse();
            faces.push((ring, source));
        }
    }

    /// Quads filling a hole whose `sides` (fan order, each from its corner
    /// point to the next's) all have `n` segments: per corner a grid between
    /// the halves of its two sides and spokes to the centre; for odd `n` a
    /// strip between spokes and a centre polygon.
    fn grid_fill(
        &self,
        v: VertId,
        sides: &[Vec<Pt>],
        points: &mut Vec<(DVec3, VertId)>,
        faces: &mut Vec<(Vec<Pt>, FaceId)>,
        source: FaceId,
    ) {
        let mesh = self.mesh;
        let m = sides.len();
        let n = sides[0].len() - 1;
        let h = n / 2;
        let pv = mesh.position(v);
        let pos = |points: &Vec<(DVec3, VertId)>, p: Pt| position(points, p, mesh);
        let corners: Vec<DVec3> = sides.iter().map(|s| pos(points, s[0])).collect();
        // The superellipsoid's centre and the point of it toward v.
        let o = pv + corners.iter().map(|&b| b - pv).sum::<DVec3>() / (m as f64 - 1.0);
        let r = profile_exponent(self.options.profile);
        let towards = if r.is_infinite() {
            1.0
        } else {
            libm::pow(m as f64, -1.0 / r)
        };
        let centre = o + (pv - o) * towards;
        let new_point = |points: &mut Vec<(DVec3, VertId)>, p: DVec3| new_point_into(points, v, p);
        let odd = n % 2 == 1;
        // c[i]: the inner corner of corner i's grid.
        let c: Vec<Pt> = if odd {
            (0..m)
                .map(|i| new_point(points, centre + (corners[i] - centre) / n as f64))
                .collect()
        } else {
            let p = new_point(points, centre);
            vec![p; m]
        };
        // Spokes: from side i's point h (and n-h) to the inner corners.
        let spoke = |points: &mut Vec<(DVec3, VertId)>, from: Pt, to: Pt| -> Vec<Pt> {
            let (a, b) = (position(points, from, mesh), position(points, to, mesh));
            let mut list = vec![from];
            for t in 1..h {
                list.push(new_point_into(
                    points,
                    v,
                    a + (b - a) * (t as f64 / h as f64),
                ));
            }
            list.push(to);
            list
        };
        // spoke_a[i]: side i's point h to c[i]; spoke_b[i]: side i's point
        // n-h to c[i+1] (the same as spoke_a for even n).
        let mut spoke_a = Vec::with_capacity(m);
        let mut spoke_b = Vec::with_capacity(m);
        for i in 0..m {
            let a = spoke(points, sides[i][h], c[i]);
            let b = if odd {
                spoke(points, sides[i][n - h], c[(i + 1) % m])
            } else {
                a.clone()
            };
            spoke_a.push(a);
            spoke_b.push(b);
        }
        for i in 0..m {
            let prev = (i + m - 1) % m;
            // grid[p][q]: p along side `prev` backwards, q along side i.
            let mut grid = vec![vec![Pt::Old(v); h + 1]; h + 1];
            for q in 0..=h {
                grid[0][q] = sides[i][q];
                grid[h][q] = spoke_b[prev][q];
            }
            for p in 0..=h {
                grid[p][0] = sides[prev][n - p];
                grid[p][h] = spoke_a[i][p];
            }
            for p in 1..h {
                for q in 1..h {
                    let (s, t) = (p as f64 / h as f64, q as f64 / h as f64);
                    let g = |pt: Pt| position(points, pt, mesh);
                    let value = (1.0 - s) * g(grid[0][q])
                        + s * g(grid[h][q])
                        + (1.0 - t) * g(grid[p][0])
                        + t * g(grid[p][h])
                        - ((1.0 - s) * (1.0 - t) * g(grid[0][0])
                            + (1.0 - s) * t * g(grid[0][h])
                            + s * (1.0 - t) * g(grid[h][0])
                            + s * t * g(grid[h][h]));
                    grid[p][q] = new_point(points, value);
                }
            }
            for p in 0..h {
                for q in 0..h {
                    let mut ring = vec![
                        grid[p][q],
                        grid[p][q + 1],
                        grid[p + 1][q + 1],
                        grid[p + 1][q],
                    ];
                    ring.reverse();
                    faces.push((ring, source));
                }
            }
            if odd {
                for t in 0..h {
                    let mut ring = vec![
                        spoke_a[i][t],
                        spoke_b[i][t],
                        spoke_b[i][t + 1],
                        spoke_a[i][t + 1],
                    ];
                    ring.reverse();
                    faces.push((ring, source));
                }
            }
        }
        if odd {
            let mut ring = c;
            ring.reverse();
            faces.push((ring, source));
        }
    }
}

fn add_reach(reach: &mut FxHashMap<EdgeId, f64>, e: EdgeId, t: f64) {
    *reach.entry(e).or_insert(0.0) += t.max(0.0);
}

fn new_point_into(points: &mut Vec<(DVec3, VertId)>, v: VertId, p: DVec3) -> Pt {
    points.push((p, v));
    Pt::New((points.len() - 1) as u32)
}

fn position(points: &[(DVec3, VertId)], p: Pt, mesh: &Mesh) -> DVec3 {
    match p {
        Pt::Old(v) => mesh.position(v),
        Pt::New(i) => points[i as usize].0,
    }
}

/// `ring` without consecutive repeats (first and last count as consecutive).
fn cyclic_dedup(mut ring: Vec<Pt>) -> Vec<Pt> {
    ring.dedup();
    while ring.len() > 1 && ring.first() == ring.last() {
        ring.pop();
    }
    ring
}

/// The angle between two vectors, robust near 0 and π.
fn angle(a: DVec3, b: DVec3) -> f64 {
    libm::atan2(a.cross(b).length(), a.dot(b))
}

/// The point of the line through `p` along unit `d` nearest to the line
/// through `a` and `b` (Blender's `project_to_edge`).
fn nearest_on_line(p: DVec3, d: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let e = b - a;
    let w = p - a;
    let (dd, de, ee) = (d.dot(d), d.dot(e), e.dot(e));
    let (dw, ew) = (d.dot(w), e.dot(w));
    let den = dd * ee - de * de;
    if den.abs() <= 1e-30 * dd.max(1.0) * ee.max(1.0) {
        // Parallel: the foot of the chord's midpoint.
        let mid = (a + b) / 2.0;
        return p + d * (mid - p).dot(d) / dd;
    }
    let s = (de * ew - ee * dw) / den;
    p + d * s
}

/// Where the offset lines of the face's edges into and out of `v` meet:
/// `v + x` with `x` at `off_in` from the edge `prev → v` and `off_out` from
/// `v → next`, both toward the face's inside, in the plane of the two
/// edges (oriented by the face normal; collinear edges: straight across).
fn meet(
    v: DVec3,
    prev: DVec3,
    next: DVec3,
    face_normal: DVec3,
    off_in: f64,
    off_out: f64,
) -> DVec3 {
    let d1 = (v - prev).normalize_or_zero();
    let d2 = (next - v).normalize_or_zero();
    let mut n = d2.cross(d1);
    if n.length() < 1e-9 {
        // Collinear: the offset straight into the face.
        let inward = face_normal.cross(d1).normalize_or_zero();
        return v + inward * (off_in + off_out) / 2.0;
    }
    n = n.normalize();
    if n.dot(face_normal) > 0.0 {
        n = -n;
    }
    // Unit vectors perpendicular to each edge, inside the face.
    let m1 = (-n).cross(d1).normalize();
    let m2 = (-n).cross(d2).normalize();
    // x = α m1 + β m2 with x·m1 = off_in, x·m2 = off_out.
    let c = m1.dot(m2);
    let det = 1.0 - c * c;
    let alpha = (off_in - c * off_out) / det;
    let beta = (off_out - c * off_in) / det;
    v + m1 * alpha + m2 * beta
}

/// Blender's exponent for a profile value: 0.5 → 2 (a circle).
fn profile_exponent(profile: f64) -> f64 {
    if profile >= 1.0 {
        f64::INFINITY
    } else {
        -2.0 * std::f64::consts::LN_2 / libm::log(profile)
    }
}

/// `segments + 1` points of the superellipse `x^r + y^r = 1` from (1, 0)
/// to (0, 1) with chords of equal length (for a circle: equal angles).
fn superellipse_chords(segments: usize, profile: f64) -> Vec<(f64, f64)> {
    let r = profile_exponent(profile);
    let n = segments;
    if r.is_infinite() {
        // The square corner: along (1, 0) → (1, 1) → (0, 1), evenly.
        return (0..=n)
            .map(|j| {
                let u = 2.0 * j as f64 / n as f64;
                if u <= 1.0 {
                    (1.0, u)
                } else {
                    (2.0 - u, 1.0)
                }
            })
            .collect();
    }
    let half_pi = std::f64::consts::FRAC_PI_2;
    let at = |theta: f64| -> (f64, f64) {
        // cos θ as sin(π/2 − θ): exactly 0 at the end (cos(π/2) is 6e-17,
        // whose small power is far from 0).
        let (s, c) = (libm::sin(theta), libm::sin(half_pi - theta));
        (
            libm::pow(c.max(0.0), 2.0 / r),
            libm::pow(s.max(0.0), 2.0 / r),
        )
    };
    if (r - 2.0).abs() < 1e-12 {
        let points: Vec<(f64, f64)> = (0..=n).map(|j| at(half_pi * j as f64 / n as f64)).collect();
        return symmetric(points);
    }
    if (r - 1.0).abs() < 1e-12 {
        return (0..=n)
            .map(|j| {
                let t = j as f64 / n as f64;
                (1.0 - t, t)
            })
            .collect();
    }
    let dist = |a: (f64, f64), b: (f64, f64)| ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt();
    // From theta0, the angle whose point lies `chord` away.
    let step = |theta0: f64, chord: f64| -> f64 {
        let p0 = at(theta0);
        let (mut lo, mut hi) = (theta0, half_pi);
        if dist(p0, at(hi)) < chord {
            return f64::INFINITY;
        }
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if dist(p0, at(mid)) < chord {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    };
    // The chord length whose n steps end exactly at (0, 1).
    let walk = |chord: f64| -> f64 {
        let mut theta = 0.0;
        for _ in 0..n - 1 {
            theta = step(theta, chord);
            if !theta.is_finite() {
                return f64::NEG_INFINITY; // ran past the end: too long
            }
        }
        dist(at(theta), at(half_pi)) - chord
    };
    let (mut lo, mut hi) = (0.0, 2f64.sqrt());
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if walk(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let chord = 0.5 * (lo + hi);
    let mut out = vec![(1.0, 0.0)];
    let mut theta = 0.0;
    for _ in 1..n {
        theta = step(theta, chord).min(half_pi);
        out.push(at(theta));
    }
    out.push((0.0, 1.0));
    if n % 2 == 0 {
        // The middle point lies on the diagonal: x = y = 2^(−1/r).
        let d = libm::pow(2.0, -1.0 / r);
        out[n / 2] = (d, d);
    }
    symmetric(out)
}

/// The profile's points made exactly symmetric (the second half mirrors
/// the first), so a band's profile is the same read from either side,
/// with exact ends.
fn symmetric(mut points: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    let n = points.len() - 1;
    points[0] = (1.0, 0.0);
    for j in (n / 2 + 1)..=n {
        let (x, y) = points[n - j];
        points[j] = (y, x);
    }
    points
}

fn build(mesh: &mut Mesh, centres: &[VertId], plan: Plan) -> Result<Selection, OpError> {
    let mut made = Selection::new();
    let mut ids: Vec<VertId> = Vec::with_capacity(plan.points.len());
    for &(p, from) in &plan.points {
        let x = mesh.make_vert(p);
        mesh.copy_vert_attrs(from, x);
        ids.push(x);
        made.verts.push(x);
    }
    let vert = |p: Pt| match p {
        Pt::Old(v) => v,
        Pt::New(i) => ids[i as usize],
    };
    for (f, ring) in &plan.rings {
        let ring: Vec<VertId> = ring.iter().map(|&p| vert(p)).collect();
        let g = mesh.make_face(&ring)?;
        mesh.copy_face_attrs(*f, g);
        made.faces.push(g);
    }
    for (ring, from) in &plan.faces {
        let ring: Vec<VertId> = ring.iter().map(|&p| vert(p)).collect();
        let g = mesh.make_face(&ring)?;
        mesh.copy_face_attrs(*from, g);
        made.faces.push(g);
    }
    for (f, _) in &plan.rings {
        mesh.kill_face(*f)?;
    }
    // Edges at the beveled vertices that lost their faces (beveled and
    // slid edges) go; so do the vertices left with nothing.
    for &v in centres {
        let dead: Vec<EdgeId> = mesh
            .vert_edges(v)
            .filter(|&e| mesh.edge_face_count(e) == 0)
            .collect();
        for e in dead {
            if mesh.contains_edge(e) {
                mesh.kill_edge(e)?;
            }
        }
        if mesh.vert_degree(v) == 0 {
            mesh.kill_vert(v)?;
        }
    }
    made.normalize();
    Ok(made)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::ops::create;

    fn options(width: f64, segments: u32) -> Bevel {
        Bevel {
            width,
            offset_type: OffsetType::Offset,
            segments,
            profile: 0.5,
            clamp_overlap: true,
            affect: Affect::Edges,
        }
    }

    fn cube() -> Mesh {
        let mut mesh = Mesh::new();
        create::create_cube(&mut mesh, 2.0).unwrap();
        mesh
    }

    fn counts(mesh: &Mesh) -> (usize, usize, usize) {
        (mesh.vert_count(), mesh.edge_count(), mesh.face_count())
    }

    #[test]
    fn a_cube_beveled_gives_blenders_counts_and_positions() {
        let mut mesh = cube();
        let edges: Vec<EdgeId> = mesh.edge_ids().collect();
        bevel(&mut mesh, &edges, &[], options(0.2, 1)).unwrap();
        mesh.validate().unwrap();
        assert_eq!(counts(&mesh), (24, 48, 26));
        let report = mesh.report();
        assert!(report.watertight && report.manifold && report.consistently_oriented);
        for v in mesh.vert_ids() {
            let mut c: Vec<f64> = mesh.position(v).abs().to_array().to_vec();
            c.sort_by(f64::total_cmp);
            assert!(
                (c[0] - 0.8).abs() < 1e-12
                    && (c[1] - 0.8).abs() < 1e-12
                    && (c[2] - 1.0).abs() < 1e-12,
                "{c:?}"
            );
        }

        let mut mesh = cube();
        let edges: Vec<EdgeId> = mesh.edge_ids().collect();
        bevel(&mut mesh, &edges, &[], options(0.2, 2)).unwrap();
        mesh.validate().unwrap();
        assert_eq!(counts(&mesh), (56, 108, 54));
        assert!(mesh.report().watertight && mesh.report().consistently_oriented);
        // The corner's centre on the sphere of radius 0.2 about (0.8, 0.8, 0.8).
        let c = 0.8 + 0.2 / 3f64.sqrt();
        assert!(mesh
            .vert_ids()
            .any(|v| (mesh.position(v) - DVec3::splat(c)).length() < 1e-12));
    }

    #[test]
    fn odd_and_even_segments_close_the_cube() {
        let mut last = 0.0;
        for segments in 1..=6 {
            let mut mesh = cube();
            let edges: Vec<EdgeId> = mesh.edge_ids().collect();
            bevel(&mut mesh, &edges, &[], options(0.3, segments)).unwrap();
            mesh.validate().unwrap();
            let r = mesh.report();
            assert!(
                r.watertight && r.manifold && r.consistently_oriented,
                "{segments}"
            );
            // A chamfer (7.064) rounds toward the quarter-circle's volume.
            let volume = r.volume.unwrap();
            assert!(volume > last && volume < 8.0, "{segments}: {volume}");
            if segments == 1 {
                assert!((volume - 7.064).abs() < 1e-12, "{volume}");
            }
            last = volume;
        }
    }

    #[test]
    fn one_edge_of_a_cube() {
        let mut mesh = cube();
        let e = mesh.edge_ids().next().unwrap();
        bevel(&mut mesh, &[e], &[], options(0.2, 1)).unwrap();
        mesh.validate().unwrap();
        assert_eq!((mesh.vert_count(), mesh.face_count()), (10, 7));
        assert!(mesh.report().watertight);
        let mut mesh = cube();
        let e = mesh.edge_ids().next().unwrap();
        bevel(&mut mesh, &[e], &[], options(0.2, 4)).unwrap();
        mesh.validate().unwrap();
        assert_eq!(
            (mesh.vert_count(), mesh.face_count()),
            (8 + 2 * 5 - 2, 6 + 4)
        );
        assert!(mesh.report().watertight && mesh.report().consistently_oriented);
    }

    #[test]
    fn clamp_overlap_limits_the_width() {
        let mut mesh = cube();
        let edges: Vec<EdgeId> = mesh.edge_ids().collect();
        bevel(&mut mesh, &edges, &[], options(5.0, 1)).unwrap();
        mesh.validate().unwrap();
        let extent = mesh
            .vert_ids()
            .map(|v| mesh.position(v).abs().min_element())
            .fold(0.0, f64::max);
        assert!(extent < 1e-12, "offsets clamped to half an edge: {extent}");
    }

    #[test]
    fn vertices_are_cut_off() {
        let mut mesh = cube();
        let verts: Vec<VertId> = mesh.vert_ids().collect();
        let mut o = options(0.5, 1);
        o.affect = Affect::Vertices;
        bevel(&mut mesh, &[], &verts, o).unwrap();
        mesh.validate().unwrap();
        assert_eq!((mesh.vert_count(), mesh.face_count()), (24, 14));
        assert!(mesh.report().watertight && mesh.report().consistently_oriented);
        let mut mesh = cube();
        let verts: Vec<VertId> = mesh.vert_ids().collect();
        o.segments = 3;
        bevel(&mut mesh, &[], &verts, o).unwrap();
        mesh.validate().unwrap();
        assert!(mesh.report().watertight && mesh.report().consistently_oriented);
    }

    #[test]
    fn closed_meshes_of_any_valence_stay_closed_at_every_setting() {
        // A UV sphere: valence 4, and 8 at the poles (triangle fans); a
        // cylinder: n-gon caps.
        let makers: [fn(&mut Mesh); 2] = [
            |m| {
                create::create_uv_sphere(m, 8, 5, 1.0).unwrap();
            },
            |m| {
                create::create_cylinder(m, 7, 1.0, 0.6, 2.0, true).unwrap();
            },
        ];
        for make in makers {
            for offset_type in [
                OffsetType::Offset,
                OffsetType::Width,
                OffsetType::Depth,
                OffsetType::Percent,
            ] {
                for (segments, profile) in [(1, 0.5), (2, 0.5), (3, 0.25), (4, 1.0), (3, 0.8)] {
                    let mut mesh = Mesh::new();
                    make(&mut mesh);
                    let edges: Vec<EdgeId> = mesh.edge_ids().collect();
                    let width = if offset_type == OffsetType::Percent {
                        20.0
                    } else {
                        0.08
                    };
                    let o = Bevel {
                        width,
                        offset_type,
                        segments,
                        profile,
                        clamp_overlap: true,
                        affect: Affect::Edges,
                    };
                    bevel(&mut mesh, &edges, &[], o).unwrap();
                    mesh.validate().unwrap();
                    let r = mesh.report();
                    let label = format!("{offset_type:?} {segments} {profile}");
                    assert!(
                        r.watertight && r.manifold && r.consistently_oriented,
                        "{label}"
                    );
                    assert!(r.volume.unwrap() > 0.0, "{label}");
                }
            }
        }
    }

    #[test]
    fn holes_at_open_vertices_stay_open() {
        // An open box's vertical edges: at the top the bands end in the
        // opening (Blender: 32 vertices, 48 edges, 17 faces, 16 open edges).
        let mut mesh = cube();
        let top: Vec<FaceId> = mesh
            .face_ids()
            .filter(|&f| mesh.face_normal(f).z > 0.5)
            .collect();
        for f in top {
            mesh.kill_face(f).unwrap();
        }
        let vertical: Vec<EdgeId> = mesh
            .edge_ids()
            .filter(|&e| {
                let [a, b] = mesh.edge_verts(e);
                (mesh.position(a) - mesh.position(b)).normalize().z.abs() > 0.99
            })
            .collect();
        bevel(&mut mesh, &vertical, &[], options(0.3, 3)).unwrap();
        mesh.validate().unwrap();
        assert_eq!(counts(&mesh), (32, 48, 17));
        assert_eq!(mesh.report().boundary_edges, 16);
    }

    #[test]
    fn zero_width_changes_nothing() {
        let mut mesh = cube();
        let edges: Vec<EdgeId> = mesh.edge_ids().collect();
        let made = bevel(&mut mesh, &edges, &[], options(0.0, 3)).unwrap();
        assert!(made.is_empty());
        assert_eq!(counts(&mesh), (8, 12, 6));
    }

    #[test]
    fn superellipse_chords_are_equal() {
        for (profile, n) in [(0.5, 4), (0.3, 5), (0.8, 6), (0.25, 3), (1.0, 4)] {
            let pts = superellipse_chords(n, profile);
            assert_eq!(pts.len(), n + 1);
            assert_eq!(pts[0], (1.0, 0.0));
            assert_eq!(pts[n], (0.0, 1.0));
            if profile < 1.0 {
                let d: Vec<f64> = pts
                    .windows(2)
                    .map(|w| ((w[0].0 - w[1].0).powi(2) + (w[0].1 - w[1].1).powi(2)).sqrt())
                    .collect();
                for x in &d {
                    assert!((x - d[0]).abs() < 1e-9, "{profile}: {d:?}");
                }
            }
        }
    }

    #[test]
    fn bad_options_are_refused_before_anything_is_made() {
        let mut mesh = cube();
        let edges: Vec<EdgeId> = mesh.edge_ids().collect();
        for o in [
            Bevel {
                width: -1.0,
                ..options(0.1, 1)
            },
            Bevel {
                width: f64::NAN,
                ..options(0.1, 1)
            },
            options(0.1, 0),
            Bevel {
                profile: 0.0,
                ..options(0.1, 1)
            },
            Bevel {
                offset_type: OffsetType::Percent,
                width: 150.0,
                ..options(0.1, 1)
            },
        ] {
            assert!(matches!(
                bevel(&mut mesh, &edges, &[], o),
                Err(OpError::Parameter { .. })
            ));
        }
        assert_eq!(counts(&mesh), (8, 12, 6));
    }
}
