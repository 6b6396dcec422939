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

use super::side_table::{SideTable, SlotSet};
use super::{into_canonical, OpError, Selection};
use crate::kernel::{EdgeId, FaceId, LoopId, Mesh, VertId};
use glam::DVec3;

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
    /// The face's loop at the vertex.
    lp: LoopId,
    /// The edge entering the vertex in the face's ring, and leaving it.
    e_in: EdgeId,
    e_out: EdgeId,
    /// The neighbours along them.
    prev: VertId,
    next: VertId,
}

/// The faces around a vertex, each followed by the one across its
/// `e_out`; `closed` when the last leads back to the first.
#[derive(Clone, Copy)]
struct Fan<'a> {
    corners: &'a [Corner],
    closed: bool,
}

/// Every centre's fan, back to back in one vector (a big bevel has a
/// million of them: one allocation each was a good part of its time).
/// A corner's index here is its index in the plan's per-corner lists too.
#[derive(Default)]
struct Fans {
    corners: Vec<Corner>,
    /// Per centre: where its corners start, and whether its fan is closed.
    heads: Vec<(usize, bool)>,
}

impl Fans {
    fn get(&self, c: usize) -> Fan<'_> {
        let (start, closed) = self.heads[c];
        let end = self.heads.get(c + 1).map_or(self.corners.len(), |h| h.0);
        Fan {
            corners: &self.corners[start..end],
            closed,
        }
    }
}

/// A run of points in the plan's arena ([`Plan::pts`]).
#[derive(Debug, Clone, Copy, Default)]
struct Span {
    start: usize,
    len: usize,
}

impl Span {
    fn of(pts: &[Pt], start: usize) -> Span {
        Span {
            start,
            len: pts.len() - start,
        }
    }

    fn get(self, pts: &[Pt]) -> &[Pt] {
        &pts[self.start..self.start + self.len]
    }

    fn at(self, pts: &[Pt], i: usize) -> Pt {
        self.get(pts)[i]
    }

    fn range(self) -> std::ops::Range<usize> {
        self.start..self.start + self.len
    }
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
    // The beveled edges in id order, and a set of them by slot (tested
    // for every edge at every centre: a bit, not a hash probe).
    let bands: Vec<EdgeId> = match options.affect {
        Affect::Edges => edges
            .iter()
            .copied()
            .filter(|&e| mesh.edge_face_count(e) == 2)
            .collect(),
        Affect::Vertices => Vec::new(),
    };
    let mut beveled = SlotSet::new(bands.len(), mesh.edge_capacity());
    for &e in &bands {
        beveled.insert(e.index());
    }
    let centres: Vec<VertId> = match options.affect {
        Affect::Edges => into_canonical(bands.iter().flat_map(|&e| mesh.edge_verts(e)).collect()),
        Affect::Vertices => verts
            .iter()
            .copied()
            .filter(|&v| mesh.vert_faces(v).next().is_some())
            .collect(),
    };
    if centres.is_empty() {
        return Ok(Selection::new());
    }
    let mut fans = Fans::default();
    let mut scratch = FanScratch::default();
    for &v in &centres {
        let start = fans.corners.len();
        let closed = fan(mesh, v, &mut scratch, &mut fans.corners)?;
        fans.heads.push((start, closed));
    }
    // Each fan corner by its face's loop at the centre: a face's ring
    // and a band's ends find their corners with one look-up.
    let mut corner_of_loop = SideTable::new(fans.corners.len(), mesh.loops.capacity());
    for (g, c) in fans.corners.iter().enumerate() {
        corner_of_loop.insert(c.lp.index(), g);
    }
    let ctx = Context {
        mesh,
        options: &options,
        beveled: &beveled,
        bands: &bands,
        fans: &fans,
        corner_of_loop: &corner_of_loop,
        chords: superellipse_chords(options.segments as usize, options.profile),
    };
    let mut plan = ctx.plan(&centres, 1.0)?;
    if options.clamp_overlap && plan.overlap_limit < 1.0 {
        plan = ctx.plan(&centres, plan.overlap_limit)?;
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

/// Buffers [`fan`] reuses from one vertex to the next.
#[derive(Default)]
struct FanScratch {
    faces: Vec<FaceId>,
    corners: Vec<Corner>,
    /// (e_in, corner) and the e_outs, sorted: looked up by binary search.
    by_in: Vec<(EdgeId, usize)>,
    outs: Vec<EdgeId>,
}

/// Appends the faces around `v` to `out` in fan order (each face's `e_out`
/// is the next face's `e_in`), starting after a boundary where there is
/// one; whether the fan is closed.
fn fan(mesh: &Mesh, v: VertId, s: &mut FanScratch, out: &mut Vec<Corner>) -> Result<bool, OpError> {
    s.faces.clear();
    s.faces.extend(mesh.vert_faces(v));
    s.faces.sort_unstable();
    s.faces.dedup();
    s.corners.clear();
    for &f in &s.faces {
        for l in mesh.face_loops(f) {
            if mesh.loop_vert(l) != v {
                continue;
            }
            // Edges are unique per pair of vertices: the loops' edges are
            // the ones joining v to its neighbours in the face.
            let before = mesh.lp(l).prev;
            s.corners.push(Corner {
                face: f,
                lp: l,
                e_in: mesh.loop_edge(before),
                e_out: mesh.loop_edge(l),
                prev: mesh.loop_vert(before),
                next: mesh.loop_vert(mesh.lp(l).next),
            });
        }
    }
    let corners = &s.corners;
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
    s.by_in.clear();
    s.by_in
        .extend(corners.iter().enumerate().map(|(i, c)| (c.e_in, i)));
    s.by_in.sort_unstable();
    if s.by_in.windows(2).any(|w| w[0].0 == w[1].0) {
        return Err(non_manifold());
    }
    let by_in = |e: EdgeId| {
        s.by_in
            .binary_search_by_key(&e, |&(e_in, _)| e_in)
            .ok()
            .map(|k| s.by_in[k].1)
    };
    s.outs.clear();
    s.outs.extend(corners.iter().map(|c| c.e_out));
    s.outs.sort_unstable();
    // Start at a corner whose e_in has no face before it (a boundary).
    let start = corners
        .iter()
        .position(|c| mesh.edge_face_count(c.e_in) == 1 || s.outs.binary_search(&c.e_in).is_err())
        .unwrap_or(0);
    let base = out.len();
    out.push(corners[start]);
    let mut closed = false;
    loop {
        let last = *out.last().unwrap();
        match by_in(last.e_out) {
            Some(i) if i == start => {
                closed = true;
                break;
            }
            Some(i) if out.len() - base < corners.len() => out.push(corners[i]),
            _ => break,
        }
    }
    if out.len() - base != corners.len() {
        return Err(non_manifold());
    }
    Ok(closed)
}

struct Context<'a> {
    mesh: &'a Mesh,
    options: &'a Bevel,
    beveled: &'a SlotSet,
    /// The beveled edges, in id order.
    bands: &'a [EdgeId],
    fans: &'a Fans,
    /// A fan corner's index by its face's loop at the centre.
    corner_of_loop: &'a SideTable<usize>,
    /// The profile's points in the unit square, (1,0) to (0,1).
    chords: Vec<(f64, f64)>,
}

/// Everything the bevel makes, computed before anything is made.
struct Plan {
    /// New points: position and the vertex whose attributes they take.
    points: Vec<(DVec3, VertId)>,
    /// Every list of points the plan holds, back to back (one vector, not
    /// one per ring and profile).
    pts: Vec<Pt>,
    /// The ring each face around a beveled vertex gets.
    rings: Vec<(FaceId, Span)>,
    /// New faces and the face whose attributes they copy.
    faces: Vec<(Span, FaceId)>,
    /// The largest factor of the offsets at which nothing overlaps.
    overlap_limit: f64,
}

/// What the plan gathers vertex by vertex: per fan corner (indexed as in
/// [`Fans`]) the points replacing the vertex in its face, and the profile
/// across its `e_out` if beveled (from the corner before it in the fan to
/// the one after).
struct Gathered {
    points: Vec<(DVec3, VertId)>,
    pts: Vec<Pt>,
    corner: Vec<Span>,
    arc: Vec<Option<Span>>,
    reach: Reach,
    /// Scratch per vertex: where its non-beveled edges end (by fan edge),
    /// and its distinct corner points.
    end: Vec<Option<Pt>>,
    distinct: Vec<Pt>,
}

/// Along each edge, how far each end's new points reach (summed).
struct Reach {
    along: SideTable<f64>,
    touched: Vec<EdgeId>,
}

impl Reach {
    fn add(&mut self, e: EdgeId, t: f64) {
        if !self.along.contains(e.index()) {
            self.along.insert(e.index(), 0.0);
            self.touched.push(e);
        }
        *self.along.get_mut(e.index()).expect("inserted") += t.max(0.0);
    }
}

/// Ends the list of points from `start` to the arena's end without
/// consecutive repeats (first and last count as consecutive): its span.
fn close_ring(pts: &mut Vec<Pt>, start: usize) -> Span {
    let mut end = start;
    for i in start..pts.len() {
        if end == start || pts[i] != pts[end - 1] {
            pts[end] = pts[i];
            end += 1;
        }
    }
    pts.truncate(end);
    while pts.len() - start > 1 && pts[start] == pts[pts.len() - 1] {
        pts.pop();
    }
    Span::of(pts, start)
}

impl Context<'_> {
    fn bev(&self, e: EdgeId) -> bool {
        self.beveled.contains(e.index())
    }

    fn plan(&self, centres: &[VertId], scale: f64) -> Result<Plan, OpError> {
        let fans = self.fans;
        let total = fans.corners.len();
        let mut g = Gathered {
            points: Vec::new(),
            pts: Vec::new(),
            corner: vec![Span::default(); total],
            arc: vec![None; total],
            reach: Reach {
                along: SideTable::new(total + centres.len(), self.mesh.edge_capacity()),
                touched: Vec::new(),
            },
            end: Vec::new(),
            distinct: Vec::new(),
        };
        let mut cap: Vec<bool> = Vec::with_capacity(centres.len());
        for (i, &v) in centres.iter().enumerate() {
            cap.push(self.plan_vertex(v, fans.get(i), fans.heads[i].0, scale, &mut g)?);
        }
        let mut limit = f64::INFINITY;
        for &e in &g.reach.touched {
            let used = *g.reach.along.get(e.index()).expect("touched");
            let length = self.mesh.edge_length(e);
            if used > length * (1.0 + 1e-12) {
                limit = limit.min(length / used);
            }
        }
        let Gathered {
            mut points,
            mut pts,
            corner,
            arc,
            ..
        } = g;
        // Rings of the faces around beveled vertices.
        let mut affected: Vec<FaceId> = centres
            .iter()
            .flat_map(|&v| self.mesh.vert_faces(v))
            .collect();
        affected = into_canonical(affected);
        let mut rings = Vec::with_capacity(affected.len());
        for &f in &affected {
            let start = pts.len();
            for l in self.mesh.face_loops(f) {
                match self.corner_of_loop.get(l.index()) {
                    Some(&k) => pts.extend_from_within(corner[k].range()),
                    None => pts.push(Pt::Old(self.mesh.loop_vert(l))),
                }
            }
            let ring = close_ring(&mut pts, start);
            if ring.len < 3 {
                return Err(OpError::Degenerate(format!(
                    "bevel: face {} would collapse (a width larger than the face allows; \
                     set `clamp_overlap = true` or a smaller width)",
                    f.index()
                )));
            }
            rings.push((f, ring));
        }
        let mut faces: Vec<(Span, FaceId)> = Vec::new();
        // Bands along beveled edges, in edge order. The profile at each end
        // is the one of the corner whose face leaves that end along the edge.
        for &e in self.bands {
            let end_arc = |x: VertId| {
                let l = self
                    .mesh
                    .edge_loops(e)
                    .find(|&l| self.mesh.loop_vert(l) == x)?;
                arc[*self.corner_of_loop.get(l.index())?]
            };
            let [u, w] = self.mesh.edge_verts(e);
            let (Some(pu), Some(pw)) = (end_arc(u), end_arc(w)) else {
                continue;
            };
            debug_assert_eq!(pu.len, pw.len);
            let n = pu.len - 1;
            let source = self
                .mesh
                .edge_faces(e)
                .min()
                .expect("a beveled edge has two faces");
            for k in 0..n {
                let quad = [
                    pw.at(&pts, n - k),
                    pu.at(&pts, k),
                    pu.at(&pts, k + 1),
                    pw.at(&pts, n - k - 1),
                ];
                let start = pts.len();
                pts.extend_from_slice(&quad);
                let ring = close_ring(&mut pts, start);
                if ring.len >= 3 {
                    faces.push((ring, source));
                } else {
                    pts.truncate(start);
                }
            }
        }
        // The corner faces at each vertex.
        for (i, &v) in centres.iter().enumerate() {
            let base = fans.heads[i].0;
            let fan = fans.get(i);
            let k = fan.corners.len();
            let here = Here {
                corner: &corner[base..base + k],
                arc: &arc[base..base + k],
                cap: cap[i],
            };
            self.corner_faces(v, fan, here, &mut points, &mut pts, &mut faces);
        }
        Ok(Plan {
            points,
            pts,
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

    /// Plans the corners (and profiles) of `v`, whose fan corners start at
    /// `base` in [`Fans`]; false when its hole needs no cap (already
    /// closed: a terminal edge's profile taken into the face across from it).
    fn plan_vertex(
        &self,
        v: VertId,
        fan: Fan<'_>,
        base: usize,
        scale: f64,
        g: &mut Gathered,
    ) -> Result<bool, OpError> {
        let mesh = self.mesh;
        let pv = mesh.position(v);
        let k = fan.corners.len();
        let dir = |x: VertId| (mesh.position(x) - pv).normalize_or_zero();
        let n = self.options.segments as usize;
        // The fan's edges: edge j sits between corner j-1 (its e_out) and
        // corner j (its e_in); an open fan has one more, the last e_out.
        // Corner i's e_in is edge i, its e_out edge (i + 1) % m.
        let m = if fan.closed { k } else { k + 1 };
        let edge_at = |j: usize| -> (EdgeId, VertId) {
            if j < k {
                (fan.corners[j].e_in, fan.corners[j].prev)
            } else {
                (fan.corners[k - 1].e_out, fan.corners[k - 1].next)
            }
        };
        g.end.clear();
        g.end.resize(m, None);
        if self.options.affect == Affect::Vertices {
            // Every edge slides: its new end at `width` along it.
            for i in 0..k {
                let mut pair = [Pt::Old(v); 2];
                for (s, j) in [i, (i + 1) % m].into_iter().enumerate() {
                    pair[s] = match g.end[j] {
                        Some(p) => p,
                        None => {
                            let (e, x) = edge_at(j);
                            let t = match self.options.offset_type {
                                OffsetType::Percent => {
                                    mesh.edge_length(e) * self.options.width * scale / 100.0
                                }
                                _ => self.options.width * scale,
                            };
                            g.reach.add(e, t);
                            let p = new_point_into(&mut g.points, v, pv + dir(x) * t);
                            g.end[j] = Some(p);
                            p
                        }
                    };
                }
                let [a, b] = pair;
                let start = g.pts.len();
                g.pts.push(a);
                let (pa, pb) = (position(&g.points, a, mesh), position(&g.points, b, mesh));
                for j in 1..n {
                    let p = self.profile_point(pa, pb, pv, j);
                    g.pts.push(new_point_into(&mut g.points, v, p));
                }
                g.pts.push(b);
                g.corner[base + i] = Span::of(&g.pts, start);
            }
            return Ok(true);
        }

        let bev = |e: EdgeId| self.bev(e);
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
        // Where each non-beveled edge at v ends.
        for j in 0..m {
            let (e, x) = edge_at(j);
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
            let mut ts = [0.0; 2];
            let mut count = 0;
            if let Some(c) = before.filter(|c| bev(c.e_in)) {
                ts[count] = slide_t(c.e_in, c.prev, c.face, x);
                count += 1;
            }
            if let Some(c) = after.filter(|c| bev(c.e_out)) {
                ts[count] = slide_t(c.e_out, c.next, c.face, x);
                count += 1;
            }
            if count == 0 {
                g.end[j] = Some(Pt::Old(v));
                continue;
            }
            let t = ts[..count].iter().sum::<f64>() / count as f64;
            // Between two beveled edges the point stays on the edge (the
            // mean of where the two offset lines reach it); Blender takes
            // where the lines come closest, off the surface where it bends
            // and ill-conditioned where they run nearly parallel.
            g.reach.add(e, t);
            g.end[j] = Some(new_point_into(&mut g.points, v, pv + dir(x) * t));
        }
        for (i, c) in fan.corners.iter().enumerate() {
            let start = g.pts.len();
            if bev(c.e_in) && bev(c.e_out) {
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
                g.pts.push(new_point_into(&mut g.points, v, p));
            } else {
                for j in [i, (i + 1) % m] {
                    if let Some(p) = g.end[j] {
                        if g.pts.len() == start || g.pts.last() != Some(&p) {
                            g.pts.push(p);
                        }
                    }
                }
            }
            g.corner[base + i] = Span::of(&g.pts, start);
        }
        let corner = |g: &Gathered, i: usize| -> Span { g.corner[base + i] };
        // Two beveled edges whose bands meet at two points only (a ring of
        // edges turning a corner, or running straight through): one shared
        // profile between the bands, its middle at the vertex (Blender's
        // vertex with two boundary vertices), and no corner face.
        g.distinct.clear();
        for i in 0..k {
            let s = corner(g, i);
            g.distinct.extend_from_slice(s.get(&g.pts));
        }
        g.distinct.sort_unstable_by_key(|p| match p {
            Pt::Old(v) => (0, v.index() as u64),
            Pt::New(i) => (1, u64::from(*i)),
        });
        g.distinct.dedup();
        let beveled_here = (0..k).filter(|&i| bev(fan.corners[i].e_out)).count();
        if fan.closed && beveled_here == 2 && g.distinct.len() == 2 {
            let mut bands = (0..k).filter(|&i| bev(fan.corners[i].e_out));
            let (i1, i2) = (bands.next().expect("two"), bands.next().expect("two"));
            let a = *corner(g, i1).get(&g.pts).last().expect("a corner point");
            let b = *corner(g, (i1 + 1) % k)
                .get(&g.pts)
                .first()
                .expect("a corner point");
            let (pa, pb) = (position(&g.points, a, mesh), position(&g.points, b, mesh));
            let start = g.pts.len();
            g.pts.push(a);
            for j in 1..n {
                let p = self.profile_point(pa, pb, pv, j);
                g.pts.push(new_point_into(&mut g.points, v, p));
            }
            g.pts.push(b);
            let arc = Span::of(&g.pts, start);
            for (i, e) in [(i1, fan.corners[i1].e_out), (i2, fan.corners[i2].e_out)] {
                let along = dir(fan.corners[i].next);
                g.reach
                    .add(e, (pa - pv).dot(along).max((pb - pv).dot(along)));
            }
            // The second band reads the profile the other way.
            let reversed = g.pts.len();
            g.pts.extend_from_within(arc.range());
            g.pts[reversed..].reverse();
            g.arc[base + i2] = Some(Span::of(&g.pts, reversed));
            g.arc[base + i1] = Some(arc);
            return Ok(false);
        }
        // Profiles across beveled edges, from the corner before to the one after.
        for i in 0..k {
            let c = fan.corners[i];
            if !bev(c.e_out) || (i + 1 == k && !fan.closed) {
                continue;
            }
            let (Some(&a), Some(&b)) = (
                corner(g, i).get(&g.pts).last(),
                corner(g, (i + 1) % k).get(&g.pts).first(),
            ) else {
                continue;
            };
            debug_assert_eq!(fan.corners[(i + 1) % k].e_in, c.e_out);
            let (pa, pb) = (position(&g.points, a, mesh), position(&g.points, b, mesh));
            // How far along the edge this end of the band reaches.
            let along = dir(c.next);
            g.reach
                .add(c.e_out, (pa - pv).dot(along).max((pb - pv).dot(along)));
            let start = g.pts.len();
            g.pts.push(a);
            let middle = nearest_on_line(pv, along, pa, pb);
            for j in 1..n {
                let p = self.profile_point(pa, pb, middle, j);
                g.pts.push(new_point_into(&mut g.points, v, p));
            }
            g.pts.push(b);
            g.arc[base + i] = Some(Span::of(&g.pts, start));
        }
        // A terminal edge at a corner of three faces: its profile becomes
        // part of the face across from it, as Blender does (no cap face
        // between a straight edge and the arc, in that face's plane).
        let mut across =
            (0..k).filter(|&i| !bev(fan.corners[i].e_in) && !bev(fan.corners[i].e_out));
        let only_across = match (across.next(), across.next()) {
            (Some(i), None) => Some(i),
            _ => None,
        };
        if let Some(i) = only_across.filter(|_| n > 1 && fan.closed && k == 3 && beveled_here == 1)
        {
            let arc = g.arc[base..base + k]
                .iter()
                .flatten()
                .next()
                .copied()
                .expect("one beveled edge");
            let start = g.pts.len();
            g.pts.extend_from_within(arc.range());
            g.pts[start..].reverse();
            g.corner[base + i] = Span::of(&g.pts, start);
            return Ok(false);
        }
        Ok(true)
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
        fan: Fan<'_>,
        here: Here<'_>,
        points: &mut Vec<(DVec3, VertId)>,
        pts: &mut Vec<Pt>,
        faces: &mut Vec<(Span, FaceId)>,
    ) {
        // A hole at an open vertex stays open, as Blender leaves it: a
        // face there would span the opening between a band's profile and
        // its chord.
        if !here.cap || !fan.closed {
            return;
        }
        let k = fan.corners.len();
        let n = self.options.segments as usize;
        let source = fan.corners[0].face;
        let regular = n > 1
            && fan.closed
            && k >= 3
            && match self.options.affect {
                Affect::Edges => (0..k).all(|i| here.arc[i].is_some() && here.corner[i].len == 1),
                Affect::Vertices => true,
            };
        if regular {
            // Sides of the hole, each from one corner point to the next.
            let sides: Vec<Span> = match self.options.affect {
                Affect::Edges => here.arc.iter().map(|a| a.expect("regular")).collect(),
                // The faces' arcs, e_in to e_out in each face.
                Affect::Vertices => here.corner.to_vec(),
            };
            self.grid_fill(v, &sides, points, pts, faces, source);
            return;
        }
        // In fan order: each corner's points, then the profile across its
        // e_out (vertex bevels: the faces' own arcs, in the corner lists).
        let start = pts.len();
        for i in 0..k {
            pts.extend_from_within(here.corner[i].range());
            if let Some(arc) = here.arc[i] {
                pts.extend_from_within(arc.start + 1..arc.start + arc.len - 1);
            }
        }
        let ring = close_ring(pts, start);
        if ring.len >= 3 {
            pts[start..].reverse();
            faces.push((ring, source));
        } else {
            pts.truncate(start);
        }
    }

    /// Quads filling a hole whose `sides` (fan order, each from its corner
    /// point to the next's) all have `n` segments: per corner a grid between
    /// the halves of its two sides and spokes to the centre; for odd `n` a
    /// strip between spokes and a centre polygon.
    fn grid_fill(
        &self,
        v: VertId,
        sides: &[Span],
        points: &mut Vec<(DVec3, VertId)>,
        pts: &mut Vec<Pt>,
        faces: &mut Vec<(Span, FaceId)>,
        source: FaceId,
    ) {
        let mesh = self.mesh;
        let m = sides.len();
        let n = sides[0].len - 1;
        let h = n / 2;
        let pv = mesh.position(v);
        let corners: Vec<DVec3> = sides
            .iter()
            .map(|s| position(points, s.at(pts, 0), mesh))
            .collect();
        // The superellipsoid's centre and the point of it toward v.
        let o = pv + corners.iter().map(|&b| b - pv).sum::<DVec3>() / (m as f64 - 1.0);
        let r = profile_exponent(self.options.profile);
        let towards = if r.is_infinite() {
            1.0
        } else {
            libm::pow(m as f64, -1.0 / r)
        };
        let centre = o + (pv - o) * towards;
        let odd = n % 2 == 1;
        // c[i]: the inner corner of corner i's grid.
        let c: Vec<Pt> = if odd {
            (0..m)
                .map(|i| new_point_into(points, v, centre + (corners[i] - centre) / n as f64))
                .collect()
        } else {
            let p = new_point_into(points, v, centre);
            vec![p; m]
        };
        // Spokes: from side i's point h (and n-h) to the inner corners.
        let spoke = |points: &mut Vec<(DVec3, VertId)>, pts: &mut Vec<Pt>, from: Pt, to: Pt| {
            let (a, b) = (position(points, from, mesh), position(points, to, mesh));
            let start = pts.len();
            pts.push(from);
            for t in 1..h {
                pts.push(new_point_into(
                    points,
                    v,
                    a + (b - a) * (t as f64 / h as f64),
                ));
            }
            pts.push(to);
            Span::of(pts, start)
        };
        // spoke_a[i]: side i's point h to c[i]; spoke_b[i]: side i's point
        // n-h to c[i+1] (the same as spoke_a for even n).
        let mut spoke_a = Vec::with_capacity(m);
        let mut spoke_b = Vec::with_capacity(m);
        for i in 0..m {
            let a = spoke(points, pts, sides[i].at(pts, h), c[i]);
            let b = if odd {
                spoke(points, pts, sides[i].at(pts, n - h), c[(i + 1) % m])
            } else {
                a
            };
            spoke_a.push(a);
            spoke_b.push(b);
        }
        // A quad, reversed (the corner's faces face away from the fan).
        let mut quad = |pts: &mut Vec<Pt>, mut ring: [Pt; 4]| {
            ring.reverse();
            let start = pts.len();
            pts.extend_from_slice(&ring);
            faces.push((Span::of(pts, start), source));
        };
        // grid[p * (h + 1) + q]: p along side `prev` backwards, q along side i.
        let w = h + 1;
        let mut grid = vec![Pt::Old(v); w * w];
        for i in 0..m {
            let prev = (i + m - 1) % m;
            for q in 0..=h {
                grid[q] = sides[i].at(pts, q);
                grid[h * w + q] = spoke_b[prev].at(pts, q);
            }
            for p in 0..=h {
                grid[p * w] = sides[prev].at(pts, n - p);
                grid[p * w + h] = spoke_a[i].at(pts, p);
            }
            for p in 1..h {
                for q in 1..h {
                    let (s, t) = (p as f64 / h as f64, q as f64 / h as f64);
                    let at = |pp: usize, qq: usize| position(points, grid[pp * w + qq], mesh);
                    let value =
                        (1.0 - s) * at(0, q) + s * at(h, q) + (1.0 - t) * at(p, 0) + t * at(p, h)
                            - ((1.0 - s) * (1.0 - t) * at(0, 0)
                                + (1.0 - s) * t * at(0, h)
                                + s * (1.0 - t) * at(h, 0)
                                + s * t * at(h, h));
                    grid[p * w + q] = new_point_into(points, v, value);
                }
            }
            for p in 0..h {
                for q in 0..h {
                    quad(
                        pts,
                        [
                            grid[p * w + q],
                            grid[p * w + q + 1],
                            grid[(p + 1) * w + q + 1],
                            grid[(p + 1) * w + q],
                        ],
                    );
                }
            }
            if odd {
                for t in 0..h {
                    let (a, b) = (spoke_a[i], spoke_b[i]);
                    let ring = [
                        a.at(pts, t),
                        b.at(pts, t),
                        b.at(pts, t + 1),
                        a.at(pts, t + 1),
                    ];
                    quad(pts, ring);
                }
            }
        }
        if odd {
            let start = pts.len();
            pts.extend(c.iter().rev());
            faces.push((Span::of(pts, start), source));
        }
    }
}

/// One vertex's part of the plan: its fan corners' points and profiles,
/// and whether its hole gets a cap.
#[derive(Clone, Copy)]
struct Here<'a> {
    corner: &'a [Span],
    arc: &'a [Option<Span>],
    cap: bool,
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
    // One buffer for every ring's vertices.
    let mut ring: Vec<VertId> = Vec::new();
    let rings = plan.rings.iter().map(|&(f, s)| (s, f));
    for (span, from) in rings.chain(plan.faces.iter().copied()) {
        ring.clear();
        ring.extend(span.get(&plan.pts).iter().map(|&p| vert(p)));
        let g = mesh.make_face(&ring)?;
        mesh.copy_face_attrs(from, g);
        made.faces.push(g);
    }
    for &(f, _) in &plan.rings {
        mesh.kill_face(f)?;
    }
    // Edges at the beveled vertices that lost their faces (beveled and
    // slid edges) go; so do the vertices left with nothing.
    let mut dead: Vec<EdgeId> = Vec::new();
    for &v in centres {
        dead.clear();
        dead.extend(mesh.vert_edges(v).filter(|&e| mesh.edge_face_count(e) == 0));
        for &e in &dead {
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
