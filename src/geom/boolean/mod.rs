//! Mesh booleans of two closed, consistently oriented polygon shells
//! (issue 36): union, difference and intersection, the topology decided by
//! exact predicates.
//!
//! 1. Both operands are triangulated and checked closed (a vertex-indexed
//!    table of directed edges, which also finds each edge's twin later);
//!    every pair of triangles whose boxes overlap (one bounding-volume
//!    hierarchy per operand, walked together) is tested with exact
//!    `orient3d`: each edge of one that pierces the other
//!    triangle is an *event* (one point per edge and triangle, shared by
//!    every triangle that meets it), and the two events of a crossing pair
//!    bound the segment of the intersection curve inside both triangles.
//! 2. Every cut triangle is re-triangulated with its events and segments as
//!    constraints (spade's constrained Delaunay triangulation of the
//!    triangle projected along its normal's largest axis).
//! 3. Pieces are grouped into patches across edges that are not on the
//!    intersection curve; a patch lies wholly inside or outside the other
//!    operand. Patches along the curve are classified by which side of the
//!    crossing triangle's plane their pieces lie (the other operand's
//!    inside is behind its outward faces); patches that touch no curve by
//!    the winding number of the other operand at one of their points (a ray
//!    cast through its hierarchy, exact where rounding could decide it).
//! 4. The operation keeps A outside B and B outside A (union), A inside B
//!    and B inside A (intersection), or A outside B and B inside A,
//!    reversed (difference). Faces no event touched come back whole.
//!
//! What is exact: whether and where (which edges, which triangles) the
//! surfaces cross, so the result's topology is closed and manifold
//! whenever the inputs are. Event positions are rounded to f64 (one
//! rounding of the edge-plane intersection). This path needs general
//! position; where any contact is degenerate — a vertex on the other
//! surface, an edge through another edge, coplanar overlapping faces —
//! it stops, and [`exact`] computes the whole boolean in rational
//! arithmetic instead (slower, and as exact).

use glam::{DVec2, DVec3};
use rustc_hash::FxHashMap;
use spade::{ConstrainedDelaunayTriangulation, HasPosition, Point2, Triangulation};

use super::predicates::{orient3d, triangle_triangle_exact};

mod exact;

/// Which of the two operands a polygon belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Operand {
    A,
    B,
}

/// The boolean operations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Operation {
    Union,
    Difference,
    Intersection,
}

/// Two shells as polygons over one point list.
#[derive(Debug, Clone, Default)]
pub struct Input {
    pub points: Vec<DVec3>,
    /// Polygons (indices into `points`) and the operand of each.
    pub polygons: Vec<(Vec<u32>, Operand)>,
}

/// Where a result point comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PointSource {
    /// An input point.
    Input(u32),
    /// Where the edge between two input points crosses the other operand
    /// (or a point made inside the triangle whose first edge this is).
    Crossing(u32, u32),
    /// A second vertex at the place of input point `i`: the result's
    /// solids touch there, and each side has its own vertex.
    Copy(u32),
}

/// One result polygon.
#[derive(Debug, Clone, PartialEq)]
pub struct OutPolygon {
    /// Indices into [`Output::points`].
    pub ring: Vec<u32>,
    /// The input polygon it is (a part of).
    pub source: u32,
    /// True when it is the input polygon itself, untouched (reversed if
    /// `reversed`).
    pub whole: bool,
    /// Wound against its source (B's faces kept by a difference).
    pub reversed: bool,
}

/// The result: the input points first (whether used or not), then the
/// crossings.
#[derive(Debug, Clone, Default)]
pub struct Output {
    pub points: Vec<DVec3>,
    pub sources: Vec<PointSource>,
    pub polygons: Vec<OutPolygon>,
}

/// Why a boolean has no result.
#[derive(Debug, Clone, PartialEq)]
pub enum BooleanError {
    /// An operand has edges with one face (or more than two).
    Open {
        operand: Operand,
        boundary_edges: usize,
        non_manifold_edges: usize,
    },
    /// A polygon of an operand has no area (or a non-finite point).
    DegenerateFace { operand: Operand, polygon: u32 },
    /// The surfaces touch without crossing cleanly there (the
    /// general-position path's refusal, which hands over to the exact one).
    DegenerateContact { at: DVec3 },
    /// The result's solids would meet along an edge (or the exact cut of a
    /// triangle failed there).
    NonManifoldResult { at: DVec3 },
    /// The exact path's work would exceed its bound: a face touches the
    /// other operand in too many places.
    TooManyContacts { at: DVec3, contacts: usize },
}

impl std::fmt::Display for BooleanError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = |o: &Operand| match o {
            Operand::A => "the selection",
            Operand::B => "the `with` part",
        };
        match self {
            BooleanError::Open {
                operand,
                boundary_edges,
                non_manifold_edges,
            } => write!(
                f,
                "{} is not a closed shell: {boundary_edges} boundary edges, \
                 {non_manifold_edges} edges with more than two faces or faces wound \
                 against each other",
                name(operand)
            ),
            BooleanError::DegenerateFace { operand, polygon } => {
                write!(f, "face {} of {} has no area", polygon, name(operand))
            }
            BooleanError::DegenerateContact { at } => write!(
                f,
                "the operands touch without crossing cleanly near ({:.6}, {:.6}, {:.6}) \
                 (a vertex on the other surface, an edge through an edge, or coplanar \
                 faces): the general-position path stops here and the exact one takes over",
                at.x, at.y, at.z
            ),
            BooleanError::TooManyContacts { at, contacts } => write!(
                f,
                "a face near ({:.6}, {:.6}, {:.6}) touches the other operand in {contacts} places: \
                 the exact path for touching contacts cuts each face in time quadratic in its \
                 contacts, and stops before starting work that large; subdivide the larger \
                 faces first, or move an operand off the contact",
                at.x, at.y, at.z
            ),
            BooleanError::NonManifoldResult { at } => write!(
                f,
                "the result would not be a manifold surface near ({:.6}, {:.6}, {:.6}): \
                 its solids (or a solid and a cavity) meet only along an edge there; \
                 move an operand off the contact, or union through the signed distance pillar",
                at.x, at.y, at.z
            ),
        }
    }
}

impl std::error::Error for BooleanError {}

/// One triangle of the triangulated operands.
#[derive(Debug, Clone, Copy)]
struct Tri {
    v: [u32; 3],
    polygon: u32,
    operand: Operand,
}

/// An edge of one operand piercing a triangle of the other.
#[derive(Debug, Clone, Copy)]
struct Event {
    /// The edge's endpoints, lower id first.
    edge: (u32, u32),
    position: DVec3,
}

/// Computes `operation` of the two operands: in general position with
/// rounded crossings, or, where the surfaces touch, in exact arithmetic.
pub fn boolean(input: &Input, operation: Operation) -> Result<Output, BooleanError> {
    prepare(input)?.boolean(input, operation)
}

/// The operands triangulated and checked closed: what a caller may check
/// further (that neither crosses itself) before the work starts.
pub struct Prepared {
    tris: Vec<Tri>,
    adjacency: Adjacency,
}

/// Triangulates the operands and checks each closed and consistently
/// wound.
pub fn prepare(input: &Input) -> Result<Prepared, BooleanError> {
    let tris = triangulate(input)?;
    let adjacency = Adjacency::new(input.points.len(), &tris);
    adjacency.check_closed(&tris)?;
    Ok(Prepared { tris, adjacency })
}

impl Prepared {
    /// Computes `operation` of the operands `self` was prepared from.
    pub fn boolean(&self, input: &Input, operation: Operation) -> Result<Output, BooleanError> {
        match general_position(input, &self.tris, &self.adjacency, operation) {
            Err(BooleanError::DegenerateContact { .. }) => {
                exact::boolean(input, &self.tris, operation)
            }
            result => result,
        }
    }
}

/// The exact path alone, whatever the contacts (for tests that compare the
/// two paths).
pub fn boolean_exact(input: &Input, operation: Operation) -> Result<Output, BooleanError> {
    exact::boolean(input, &prepare(input)?.tris, operation)
}

/// The general-position path: refuses degenerate contacts.
fn general_position(
    input: &Input,
    tris: &[Tri],
    adjacency: &Adjacency,
    operation: Operation,
) -> Result<Output, BooleanError> {
    let points = &input.points;
    let (a_tris, b_tris): (Vec<u32>, Vec<u32>) = {
        let mut a = Vec::new();
        let mut b = Vec::new();
        for (i, t) in tris.iter().enumerate() {
            match t.operand {
                Operand::A => a.push(i as u32),
                Operand::B => b.push(i as u32),
            }
        }
        (a, b)
    };
    let corners = |t: u32| tris[t as usize].v.map(|i| points[i as usize]);

    // 1. Events and segments.
    let mut events: Vec<Event> = Vec::new();
    let mut event_of: FxHashMap<(u32, u32, u32), u32> = FxHashMap::default();
    // Per triangle: its segments (event pairs) and, per segment, the
    // triangle of the other operand it lies on.
    let mut segments: FxHashMap<u32, Vec<(u32, u32, u32)>> = FxHashMap::default();
    // Candidate pairs from both hierarchies at once: subtrees of A far
    // from B's surface are dropped whole. Sorted, so events are numbered
    // in one order whatever the trees look like.
    // One tree per core (the trees do not depend on which builds first).
    let (tree_a, tree_b) = rayon::join(
        || Bvh::new(&a_tris, |t| bounds(&corners(t))),
        || Bvh::new(&b_tris, |t| bounds(&corners(t))),
    );
    let mut candidates = tree_a.overlapping_pairs(&tree_b);
    candidates.sort_unstable();
    // The exact tests on both cores; their results read in candidate order
    // (the first degenerate pair in that order stops it, whatever the
    // threads did).
    let crossings: Vec<_> = {
        use rayon::prelude::*;
        candidates
            .par_iter()
            .with_min_len(1024)
            .map(|&(ta, tb)| crossing(tris, points, ta, tb))
            .collect()
    };
    for (&(ta, tb), found) in candidates.iter().zip(crossings) {
        let Some(pair) = found? else {
            continue;
        };
        let mut ids = [0u32; 2];
        for (k, (edge, tri)) in pair.into_iter().enumerate() {
            let key = (edge.0, edge.1, tri);
            ids[k] = *event_of.entry(key).or_insert_with(|| {
                let t = tri_corners(tris, points, tri);
                events.push(Event {
                    edge,
                    position: edge_plane_point(points[edge.0 as usize], points[edge.1 as usize], t),
                });
                (events.len() - 1) as u32
            });
        }
        if ids[0] == ids[1] {
            return Err(BooleanError::DegenerateContact {
                at: events[ids[0] as usize].position,
            });
        }
        segments.entry(ta).or_default().push((ids[0], ids[1], tb));
        segments.entry(tb).or_default().push((ids[0], ids[1], ta));
    }
    let n_points = points.len() as u32;
    let event_vertex = |e: u32| n_points + e;

    // Events on each triangle's edges, by edge key.
    let mut on_edge: FxHashMap<(u32, u32), Vec<u32>> = FxHashMap::default();
    for (i, e) in events.iter().enumerate() {
        on_edge.entry(e.edge).or_default().push(i as u32);
    }

    // 2. Pieces: every triangle, cut ones re-triangulated.
    let mut all_points: Vec<DVec3> = points.clone();
    all_points.extend(events.iter().map(|e| e.position));
    let mut pieces: Vec<Piece> = Vec::with_capacity(tris.len());
    let mut cut_polygon = vec![false; input.polygons.len()];
    // The piece an uncut triangle is (NONE for cut ones).
    let mut piece_of_tri = vec![NONE; tris.len()];
    for (t, tri) in tris.iter().enumerate() {
        let t = t as u32;
        let segs = segments.get(&t);
        let has_edge_events = (0..3).any(|k| {
            let (u, v) = ordered(tri.v[k], tri.v[(k + 1) % 3]);
            on_edge.contains_key(&(u, v))
        });
        if segs.is_none() && !has_edge_events {
            piece_of_tri[t as usize] = pieces.len() as u32;
            pieces.push(Piece {
                v: tri.v,
                tri: t,
                cut: false,
            });
            continue;
        }
        cut_polygon[tri.polygon as usize] = true;
        let segs = segs.map(Vec::as_slice).unwrap_or(&[]);
        retriangulate(
            tri,
            t,
            &all_points,
            &on_edge,
            segs,
            &event_vertex,
            &mut pieces,
        )?;
    }

    // 3. Patches: pieces of one operand joined across edges off the curve.
    let mut curve: rustc_hash::FxHashSet<u64> = rustc_hash::FxHashSet::default();
    for segs in segments.values() {
        for &(e0, e1, _) in segs {
            curve.insert(super::edge_key::undirected(
                event_vertex(e0),
                event_vertex(e1),
            ));
        }
    }
    let mut patches = super::union_find::UnionFind::new(pieces.len());
    {
        // Cut pieces by their directed edges (uncut triangles find their
        // neighbours through the vertex adjacency instead: no hashing for
        // the bulk of the mesh).
        let key = super::edge_key::directed;
        let mut cut_edges: FxHashMap<u64, u32> = FxHashMap::default();
        for (i, p) in pieces.iter().enumerate().filter(|(_, p)| p.cut) {
            for k in 0..3 {
                cut_edges.insert(key(p.v[k], p.v[(k + 1) % 3]), i as u32);
            }
        }
        let operand = |i: u32| tris[pieces[i as usize].tri as usize].operand;
        for (i, p) in pieces.iter().enumerate() {
            let i = i as u32;
            for k in 0..3 {
                let (a, b) = (p.v[k], p.v[(k + 1) % 3]);
                let other = if p.cut {
                    if curve.contains(&super::edge_key::undirected(a, b)) {
                        continue;
                    }
                    // Its twin is a cut piece's, or an uncut triangle's
                    // (joined from that side).
                    match cut_edges.get(&key(b, a)) {
                        Some(&q) => q,
                        None => continue,
                    }
                } else {
                    let twin = adjacency.twin_triangle(a, b);
                    match piece_of_tri[twin as usize] {
                        // A cut neighbour keeps this edge whole, unless
                        // its triangulation put a point on it (a contact
                        // within rounding of the edge): refused.
                        NONE => match cut_edges.get(&key(b, a)) {
                            Some(&q) => q,
                            None => {
                                return Err(BooleanError::DegenerateContact {
                                    at: all_points[a as usize],
                                })
                            }
                        },
                        q => q,
                    }
                };
                if other > i && operand(other) == operand(i) {
                    patches.union(i, other);
                }
            }
        }
    }
    // Votes: signed distances of pieces along the curve from the other
    // operand's crossing plane (negative: inside).
    let mut vote: FxHashMap<u32, f64> = FxHashMap::default();
    {
        let mut curve_owner: FxHashMap<(u32, u32, u32), u32> = FxHashMap::default();
        for (&t, segs) in &segments {
            for &(e0, e1, other) in segs {
                let key = ordered(event_vertex(e0), event_vertex(e1));
                curve_owner.insert((key.0, key.1, t), other);
            }
        }
        for (i, p) in pieces.iter().enumerate() {
            if !p.cut {
                continue;
            }
            for k in 0..3 {
                let key = ordered(p.v[k], p.v[(k + 1) % 3]);
                let Some(&other) = curve_owner.get(&(key.0, key.1, p.tri)) else {
                    continue;
                };
                let opposite = all_points[p.v[(k + 2) % 3] as usize];
                let [o0, o1, o2] = tri_corners(tris, points, other);
                let n = (o1 - o0).cross(o2 - o0);
                let len = n.length();
                if len > 0.0 {
                    *vote.entry(patches.find(i as u32)).or_insert(0.0) +=
                        n.dot(opposite - o0) / len;
                }
            }
        }
    }
    let mut inside: FxHashMap<u32, bool> = FxHashMap::default();
    for (i, p) in pieces.iter().enumerate() {
        let root = patches.find(i as u32);
        if inside.contains_key(&root) {
            continue;
        }
        let verdict = match vote.get(&root) {
            Some(&v) if v != 0.0 => v < 0.0,
            _ => {
                let c = (all_points[p.v[0] as usize]
                    + all_points[p.v[1] as usize]
                    + all_points[p.v[2] as usize])
                    / 3.0;
                let other = match tris[p.tri as usize].operand {
                    Operand::A => &tree_b,
                    Operand::B => &tree_a,
                };
                exact::ray_winding(other, &|t| tri_corners(tris, points, t), c) > 0
            }
        };
        inside.insert(root, verdict);
    }

    // 4. Keep by the operation.
    let keep = |operand: Operand, is_inside: bool| match (operation, operand) {
        (Operation::Union, _) => !is_inside,
        (Operation::Intersection, _) => is_inside,
        (Operation::Difference, Operand::A) => !is_inside,
        (Operation::Difference, Operand::B) => is_inside,
    };
    let reversed = |operand: Operand| operation == Operation::Difference && operand == Operand::B;
    let mut out = Output {
        points: all_points,
        sources: (0..n_points)
            .map(PointSource::Input)
            .chain(
                events
                    .iter()
                    .map(|e| PointSource::Crossing(e.edge.0, e.edge.1)),
            )
            .collect(),
        polygons: Vec::new(),
    };
    // Whole polygons: decided by their first triangle's piece.
    let mut polygon_verdict: Vec<Option<bool>> = vec![None; input.polygons.len()];
    for (i, p) in pieces.iter().enumerate() {
        let tri = &tris[p.tri as usize];
        let is_inside = inside[&patches.find(i as u32)];
        if cut_polygon[tri.polygon as usize] {
            if keep(tri.operand, is_inside) {
                let mut ring = p.v.to_vec();
                if reversed(tri.operand) {
                    ring.reverse();
                }
                out.polygons.push(OutPolygon {
                    ring,
                    source: tri.polygon,
                    whole: false,
                    reversed: reversed(tri.operand),
                });
            }
        } else {
            polygon_verdict[tri.polygon as usize].get_or_insert(is_inside);
        }
    }
    for (k, (ring, operand)) in input.polygons.iter().enumerate() {
        let Some(is_inside) = polygon_verdict[k] else {
            continue;
        };
        if keep(*operand, is_inside) {
            let mut ring = ring.clone();
            if reversed(*operand) {
                ring.reverse();
            }
            out.polygons.push(OutPolygon {
                ring,
                source: k as u32,
                whole: true,
                reversed: reversed(*operand),
            });
        }
    }
    // Canonical order: by source polygon, whole ones first, then pieces in
    // the order they were made.
    out.polygons.sort_by_key(|p| (p.source, !p.whole));
    exact::collapse_rounded_edges(&mut out, n_points as usize);
    exact::flip_rounded_caps(&mut out, n_points as usize);
    Ok(out)
}

/// A triangle of the result before selection.
#[derive(Debug, Clone, Copy)]
struct Piece {
    v: [u32; 3],
    /// The input triangle it is (part of).
    tri: u32,
    cut: bool,
}

fn ordered(a: u32, b: u32) -> (u32, u32) {
    if a < b {
        (a, b)
    } else {
        (b, a)
    }
}

fn tri_corners(tris: &[Tri], points: &[DVec3], t: u32) -> [DVec3; 3] {
    tris[t as usize].v.map(|i| points[i as usize])
}

fn bounds(c: &[DVec3; 3]) -> (DVec3, DVec3) {
    (c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]))
}

const NONE: u32 = u32::MAX;

/// The triangles' directed edges by first vertex (compressed rows): each
/// edge's twin is found among its second vertex's few edges, in linear
/// time and without hashing.
struct Adjacency {
    /// Per point: where its edges start in `to` and `tri`.
    start: Vec<u32>,
    /// Each directed edge's second vertex and triangle.
    to: Vec<u32>,
    tri: Vec<u32>,
}

impl Adjacency {
    fn new(points: usize, tris: &[Tri]) -> Adjacency {
        let mut start = vec![0u32; points + 1];
        for t in tris {
            for &v in &t.v {
                start[v as usize + 1] += 1;
            }
        }
        for i in 0..points {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut to = vec![0u32; 3 * tris.len()];
        let mut tri = vec![0u32; 3 * tris.len()];
        for (t, x) in tris.iter().enumerate() {
            for k in 0..3 {
                let a = x.v[k] as usize;
                let slot = fill[a] as usize;
                to[slot] = x.v[(k + 1) % 3];
                tri[slot] = t as u32;
                fill[a] += 1;
            }
        }
        Adjacency { start, to, tri }
    }

    fn edges(&self, a: u32) -> std::ops::Range<usize> {
        self.start[a as usize] as usize..self.start[a as usize + 1] as usize
    }

    /// The triangle on the other side of directed edge `a → b` (the
    /// shells are closed: checked first).
    fn twin_triangle(&self, a: u32, b: u32) -> u32 {
        let r = self.edges(b);
        let k = self.to[r].iter().position(|&w| w == a).expect("closed");
        self.tri[self.start[b as usize] as usize + k]
    }

    /// Every undirected edge of each operand used exactly twice, once each
    /// way.
    fn check_closed(&self, tris: &[Tri]) -> Result<(), BooleanError> {
        for operand in [Operand::A, Operand::B] {
            let (mut boundary, mut bad, mut any) = (0, 0, false);
            let count = |from: u32, to: u32| {
                self.edges(from)
                    .filter(|&i| self.to[i] == to && tris[self.tri[i] as usize].operand == operand)
                    .count()
            };
            for a in 0..self.start.len() as u32 - 1 {
                for i in self.edges(a) {
                    let b = self.to[i];
                    if tris[self.tri[i] as usize].operand != operand {
                        continue;
                    }
                    any = true;
                    // Counted once per undirected edge: at its first
                    // entry from the lower vertex, or from the only side.
                    let first = self.edges(a).find(|&j| {
                        self.to[j] == b && tris[self.tri[j] as usize].operand == operand
                    });
                    if first != Some(i) {
                        continue;
                    }
                    let (fwd, bwd) = (count(a, b), count(b, a));
                    if bwd > 0 && a > b {
                        continue;
                    }
                    if fwd + bwd == 1 {
                        boundary += 1;
                    } else if (fwd, bwd) != (1, 1) {
                        bad += 1;
                    }
                }
            }
            if boundary > 0 || bad > 0 || !any {
                return Err(BooleanError::Open {
                    operand,
                    boundary_edges: boundary,
                    non_manifold_edges: bad,
                });
            }
        }
        Ok(())
    }
}

fn triangulate(input: &Input) -> Result<Vec<Tri>, BooleanError> {
    let mut tris = Vec::new();
    let mut local = Vec::new();
    let mut ring_points = Vec::new();
    for (k, (ring, operand)) in input.polygons.iter().enumerate() {
        let degenerate = BooleanError::DegenerateFace {
            operand: *operand,
            polygon: k as u32,
        };
        ring_points.clear();
        ring_points.extend(ring.iter().map(|&i| input.points[i as usize]));
        if ring_points.iter().any(|p| !p.is_finite()) {
            return Err(degenerate);
        }
        local.clear();
        if ring.len() == 3 {
            local.push([0, 1, 2]);
        } else {
            super::polygon::triangulate(&ring_points, &mut local);
        }
        for t in &local {
            let v = t.map(|i| ring[i as usize]);
            let c = v.map(|i| input.points[i as usize]);
            // The exact test only where rounding could hide a line.
            let n = (c[1] - c[0]).cross(c[2] - c[0]);
            let scale = (c[1] - c[0])
                .length_squared()
                .max((c[2] - c[0]).length_squared());
            let clearly_spanning = n.length_squared() > 1e-24 * scale * scale;
            if !clearly_spanning && !collinear_free(c) {
                return Err(degenerate);
            }
            tris.push(Tri {
                v,
                polygon: k as u32,
                operand: *operand,
            });
        }
    }
    Ok(tris)
}

/// False when the three points are exactly collinear (every projection
/// degenerate).
fn collinear_free(c: [DVec3; 3]) -> bool {
    (0..3).any(|axis| super::predicates::orient2d_dropping(c[0], c[1], c[2], axis) != 0.0)
}

/// An edge (its ends, lower first) piercing a triangle.
type Pierce = ((u32, u32), u32);

/// The two events bounding the intersection of triangles `ta` (of A) and
/// `tb` (of B), as (edge, triangle it pierces); `None` when they do not
/// meet. Every sign is exact; a contact that is not a clean crossing is an
/// error.
fn crossing(
    tris: &[Tri],
    points: &[DVec3],
    ta: u32,
    tb: u32,
) -> Result<Option<[Pierce; 2]>, BooleanError> {
    let a = tris[ta as usize].v;
    let b = tris[tb as usize].v;
    let pa = a.map(|i| points[i as usize]);
    let pb = b.map(|i| points[i as usize]);
    let sa = pa.map(|p| sign(orient3d(pb[0], pb[1], pb[2], p)));
    if sa.iter().all(|&s| s == sa[0] && s != 0) {
        return Ok(None);
    }
    let sb = pb.map(|p| sign(orient3d(pa[0], pa[1], pa[2], p)));
    if sb.iter().all(|&s| s == sb[0] && s != 0) {
        return Ok(None);
    }
    let degenerate = || {
        Err(BooleanError::DegenerateContact {
            at: (pa[0] + pa[1] + pa[2]) / 3.0,
        })
    };
    if sa.contains(&0) || sb.contains(&0) {
        return if triangle_triangle_exact(pa, pb) {
            degenerate()
        } else {
            Ok(None)
        };
    }
    let mut found: Vec<Pierce> = Vec::with_capacity(2);
    for (verts, signs, other, other_id) in [(a, sa, pb, tb), (b, sb, pa, ta)] {
        for k in 0..3 {
            let (i, j) = (k, (k + 1) % 3);
            if signs[i] == signs[j] {
                continue;
            }
            let (u, v) = ordered(verts[i], verts[j]);
            match pierces(points[u as usize], points[v as usize], other) {
                Some(true) => found.push(((u, v), other_id)),
                Some(false) => {}
                None => return degenerate(),
            }
        }
    }
    match found.len() {
        0 => Ok(None),
        2 => Ok(Some([found[0], found[1]])),
        _ => degenerate(),
    }
}

fn sign(x: f64) -> i8 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}

/// Whether segment `p q` (whose ends lie strictly on either side of the
/// triangle's plane) passes through the triangle's interior; `None` when
/// it meets the triangle's boundary.
fn pierces(p: DVec3, q: DVec3, t: [DVec3; 3]) -> Option<bool> {
    let s = [
        sign(orient3d(p, q, t[0], t[1])),
        sign(orient3d(p, q, t[1], t[2])),
        sign(orient3d(p, q, t[2], t[0])),
    ];
    if (s.contains(&1) && s.contains(&-1)) || s == [0, 0, 0] {
        return Some(false);
    }
    if s.contains(&0) {
        return None;
    }
    Some(true)
}

/// Where segment `p q` crosses the plane of `t` (its ends strictly on
/// either side): one rounding of `p + (q − p) · dp / (dp − dq)`.
fn edge_plane_point(p: DVec3, q: DVec3, t: [DVec3; 3]) -> DVec3 {
    let dp = orient3d(t[0], t[1], t[2], p);
    let dq = orient3d(t[0], t[1], t[2], q);
    let s = (dp / (dp - dq)).clamp(0.0, 1.0);
    p + (q - p) * s
}

/// A point carried through spade with its result index.
#[derive(Clone, Copy, Debug)]
struct CdtVertex {
    position: Point2<f64>,
    index: u32,
}

impl HasPosition for CdtVertex {
    type Scalar = f64;

    fn position(&self) -> Point2<f64> {
        self.position
    }
}

/// Splits `tri` by its events and segments into pieces wound as it is.
fn retriangulate(
    tri: &Tri,
    t: u32,
    all_points: &[DVec3],
    on_edge: &FxHashMap<(u32, u32), Vec<u32>>,
    segs: &[(u32, u32, u32)],
    event_vertex: &dyn Fn(u32) -> u32,
    pieces: &mut Vec<Piece>,
) -> Result<(), BooleanError> {
    let c = tri.v.map(|i| all_points[i as usize]);
    let normal = (c[1] - c[0]).cross(c[2] - c[0]);
    let axis = normal.abs().max_position();
    let (u_axis, v_axis) = ((axis + 1) % 3, (axis + 2) % 3);
    let origin = c[0];
    let scale = 1.0
        / (c[1] - c[0])
            .abs()
            .max(c[2] - c[0])
            .abs()
            .max_element()
            .max(f64::MIN_POSITIVE);
    let project = |p: DVec3| {
        let d = (p - origin) * scale;
        DVec2::new(d[u_axis], d[v_axis])
    };
    // The ring: corners with each edge's events in order along it.
    let mut ring: Vec<u32> = Vec::new();
    for k in 0..3 {
        let (a, b) = (tri.v[k], tri.v[(k + 1) % 3]);
        ring.push(a);
        if let Some(list) = on_edge.get(&ordered(a, b)) {
            let (pa, pb) = (all_points[a as usize], all_points[b as usize]);
            let d = pb - pa;
            let mut along: Vec<(f64, u32)> = list
                .iter()
                .map(|&e| {
                    let v = event_vertex(e);
                    ((all_points[v as usize] - pa).dot(d), v)
                })
                .collect();
            along.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            ring.extend(along.iter().map(|&(_, v)| v));
        }
    }
    let mut verts: Vec<u32> = ring.clone();
    for &(e0, e1, _) in segs {
        for e in [event_vertex(e0), event_vertex(e1)] {
            if !verts.contains(&e) {
                verts.push(e);
            }
        }
    }
    let index_of = |v: u32| verts.iter().position(|&w| w == v).expect("listed");
    let mut edges: Vec<[usize; 2]> = (0..ring.len()).map(|i| [i, (i + 1) % ring.len()]).collect();
    for &(e0, e1, _) in segs {
        edges.push([index_of(event_vertex(e0)), index_of(event_vertex(e1))]);
    }
    let at = all_points[tri.v[0] as usize];
    let degenerate = || BooleanError::DegenerateContact { at };
    let vertices: Vec<CdtVertex> = verts
        .iter()
        .map(|&v| {
            let p = project(all_points[v as usize]);
            CdtVertex {
                position: Point2::new(p.x, p.y),
                index: v,
            }
        })
        .collect();
    {
        let mut keys: Vec<(u64, u64)> = vertices
            .iter()
            .map(|v| (v.position.x.to_bits(), v.position.y.to_bits()))
            .collect();
        keys.sort_unstable();
        if keys.windows(2).any(|w| w[0] == w[1]) {
            return Err(degenerate());
        }
    }
    let mut conflict = false;
    let cdt =
        ConstrainedDelaunayTriangulation::<CdtVertex>::try_bulk_load_cdt(vertices, edges, |_| {
            conflict = true
        })
        .map_err(|_| degenerate())?;
    if conflict {
        return Err(degenerate());
    }
    // Inside: faces not reachable from the outside without crossing a
    // constraint (the triangle's sides are constraints).
    let faces: Vec<_> = cdt.inner_faces().collect();
    let mut outside = vec![false; faces.len()];
    let mut stack: Vec<usize> = Vec::new();
    let face_index: FxHashMap<_, usize> = faces
        .iter()
        .enumerate()
        .map(|(i, f)| (f.fix(), i))
        .collect();
    for (i, f) in faces.iter().enumerate() {
        let touches_hull = f
            .adjacent_edges()
            .iter()
            .any(|e| e.rev().face().is_outer() && !e.as_undirected().is_constraint_edge());
        if touches_hull {
            outside[i] = true;
            stack.push(i);
        }
    }
    while let Some(i) = stack.pop() {
        for e in faces[i].adjacent_edges() {
            if e.as_undirected().is_constraint_edge() {
                continue;
            }
            if let Some(inner) = e.rev().face().as_inner() {
                let j = face_index[&inner.fix()];
                if !outside[j] {
                    outside[j] = true;
                    stack.push(j);
                }
            }
        }
    }
    let flip = normal[axis] < 0.0;
    let before = pieces.len();
    for (i, f) in faces.iter().enumerate() {
        if outside[i] {
            continue;
        }
        let v = f.vertices().map(|h| h.data().index);
        // spade's faces are counter-clockwise in the projection.
        let v = if flip { [v[0], v[2], v[1]] } else { v };
        pieces.push(Piece {
            v,
            tri: t,
            cut: true,
        });
    }
    // The inside must be covered: at least one piece per ring corner
    // beyond two, else the ring crossed itself in the projection.
    if pieces.len() - before + 2 < ring.len() {
        return Err(degenerate());
    }
    Ok(())
}

/// A bounding-volume hierarchy over triangle boxes (median splits).
struct Bvh {
    nodes: Vec<BvhNode>,
    items: Vec<u32>,
}

struct BvhNode {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: `items[start..start + count]`; inner: children at `start` and
    /// `start + 1` when `count == 0`.
    start: u32,
    count: u32,
}

impl Bvh {
    fn new(items: &[u32], bounds_of: impl Fn(u32) -> (DVec3, DVec3)) -> Bvh {
        let boxes: Vec<(DVec3, DVec3, u32)> = items
            .iter()
            .map(|&i| {
                let (lo, hi) = bounds_of(i);
                (lo, hi, i)
            })
            .collect();
        let mut bvh = Bvh {
            nodes: Vec::new(),
            items: Vec::with_capacity(items.len()),
        };
        if !boxes.is_empty() {
            bvh.nodes.push(BvhNode {
                lo: DVec3::ZERO,
                hi: DVec3::ZERO,
                start: 0,
                count: 0,
            });
            let mut boxes = boxes;
            bvh.build(0, &mut boxes);
        }
        bvh
    }

    fn build(&mut self, node: usize, boxes: &mut [(DVec3, DVec3, u32)]) {
        let (mut lo, mut hi) = (boxes[0].0, boxes[0].1);
        for b in boxes.iter() {
            lo = lo.min(b.0);
            hi = hi.max(b.1);
        }
        self.nodes[node].lo = lo;
        self.nodes[node].hi = hi;
        if boxes.len() <= 4 {
            self.nodes[node].start = self.items.len() as u32;
            self.nodes[node].count = boxes.len() as u32;
            self.items.extend(boxes.iter().map(|b| b.2));
            return;
        }
        let axis = (hi - lo).max_position();
        let mid = boxes.len() / 2;
        boxes.select_nth_unstable_by(mid, |x, y| {
            (x.0[axis] + x.1[axis])
                .total_cmp(&(y.0[axis] + y.1[axis]))
                .then(x.2.cmp(&y.2))
        });
        let first = self.nodes.len();
        for _ in 0..2 {
            self.nodes.push(BvhNode {
                lo,
                hi,
                start: 0,
                count: 0,
            });
        }
        self.nodes[node].start = first as u32;
        self.nodes[node].count = 0;
        let (left, right) = boxes.split_at_mut(mid);
        self.build(first, left);
        self.build(first + 1, right);
    }

    /// The items of every leaf whose box overlaps the box `lo..hi`.
    fn overlapping(&self, lo: DVec3, hi: DVec3) -> Vec<u32> {
        let mut out = Vec::new();
        if self.nodes.is_empty() {
            return out;
        }
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let x = &self.nodes[i];
            if x.lo.cmpgt(hi).any() || x.hi.cmplt(lo).any() {
                continue;
            }
            if x.count > 0 {
                out.extend_from_slice(&self.items[x.start as usize..(x.start + x.count) as usize]);
            } else {
                stack.push(x.start as usize);
                stack.push(x.start as usize + 1);
            }
        }
        out
    }

    /// Every pair of items, one of each tree, whose boxes overlap.
    fn overlapping_pairs(&self, other: &Bvh) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        if self.nodes.is_empty() || other.nodes.is_empty() {
            return out;
        }
        let overlap =
            |x: &BvhNode, y: &BvhNode| !(x.lo.cmpgt(y.hi).any() || x.hi.cmplt(y.lo).any());
        let mut stack = vec![(0usize, 0usize)];
        while let Some((i, j)) = stack.pop() {
            let (x, y) = (&self.nodes[i], &other.nodes[j]);
            if !overlap(x, y) {
                continue;
            }
            match (x.count > 0, y.count > 0) {
                (true, true) => {
                    for &a in &self.items[x.start as usize..(x.start + x.count) as usize] {
                        for &b in &other.items[y.start as usize..(y.start + y.count) as usize] {
                            out.push((a, b));
                        }
                    }
                }
                // Descend the larger box (or the inner node).
                (false, true) => {
                    stack.push((x.start as usize, j));
                    stack.push((x.start as usize + 1, j));
                }
                (true, false) => {
                    stack.push((i, y.start as usize));
                    stack.push((i, y.start as usize + 1));
                }
                (false, false) => {
                    if (x.hi - x.lo).length_squared() >= (y.hi - y.lo).length_squared() {
                        stack.push((x.start as usize, j));
                        stack.push((x.start as usize + 1, j));
                    } else {
                        stack.push((i, y.start as usize));
                        stack.push((i, y.start as usize + 1));
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An axis-aligned box's 6 outward quads, points appended to `input`.
    fn add_box(input: &mut Input, lo: DVec3, hi: DVec3, operand: Operand) {
        let base = input.points.len() as u32;
        for i in 0..8 {
            input.points.push(DVec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            ));
        }
        for q in [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ] {
            input
                .polygons
                .push((q.iter().map(|&i| base + i).collect(), operand));
        }
    }

    fn volume(out: &Output) -> f64 {
        let mut v = 0.0;
        for p in &out.polygons {
            let r: Vec<DVec3> = p.ring.iter().map(|&i| out.points[i as usize]).collect();
            for k in 1..r.len() - 1 {
                v += r[0].dot(r[k].cross(r[k + 1])) / 6.0;
            }
        }
        v
    }

    /// Every undirected edge used twice, once each way.
    fn closed(out: &Output) -> bool {
        let mut uses: FxHashMap<(u32, u32), (u32, u32)> = FxHashMap::default();
        for p in &out.polygons {
            for k in 0..p.ring.len() {
                let (a, b) = (p.ring[k], p.ring[(k + 1) % p.ring.len()]);
                let e = uses.entry(ordered(a, b)).or_insert((0, 0));
                if a < b {
                    e.0 += 1;
                } else {
                    e.1 += 1;
                }
            }
        }
        uses.values().all(|&u| u == (1, 1))
    }

    fn two_boxes(offset: DVec3) -> Input {
        let mut input = Input::default();
        add_box(&mut input, DVec3::ZERO, DVec3::ONE, Operand::A);
        // Tilted slightly so no face is coplanar with A's.
        let base = input.points.len();
        add_box(&mut input, DVec3::ZERO, DVec3::ONE, Operand::B);
        let (s, c) = (0.3f64.sin(), 0.3f64.cos());
        for p in &mut input.points[base..] {
            let q = *p - 0.5;
            let r = DVec3::new(c * q.x - s * q.y, s * q.x + c * q.y, q.z);
            let (s2, c2) = (0.2f64.sin(), 0.2f64.cos());
            let r = DVec3::new(r.x, c2 * r.y - s2 * r.z, s2 * r.y + c2 * r.z);
            *p = r + 0.5 + offset;
        }
        input
    }

    #[test]
    fn overlapping_boxes_give_closed_results_whose_volumes_add_up() {
        let input = two_boxes(DVec3::new(0.5, 0.4, 0.3));
        let u = boolean(&input, Operation::Union).unwrap();
        let i = boolean(&input, Operation::Intersection).unwrap();
        let d = boolean(&input, Operation::Difference).unwrap();
        for out in [&u, &i, &d] {
            assert!(closed(out));
        }
        // Inclusion–exclusion: |A ∪ B| + |A ∩ B| = |A| + |B| = 2, and
        // |A − B| + |A ∩ B| = |A| = 1.
        let (vu, vi, vd) = (volume(&u), volume(&i), volume(&d));
        assert!(vi > 0.05 && vi < 0.95, "{vi}");
        assert!((vu + vi - 2.0).abs() < 1e-12, "{vu} {vi}");
        assert!((vd + vi - 1.0).abs() < 1e-12, "{vd} {vi}");
    }

    /// Area of convex polygon `subject` clipped by convex, counter-clockwise
    /// `clip` (Sutherland–Hodgman), by the shoelace formula.
    fn clipped_area(subject: &[DVec2], clip: &[DVec2]) -> f64 {
        let mut poly = subject.to_vec();
        for k in 0..clip.len() {
            let (a, b) = (clip[k], clip[(k + 1) % clip.len()]);
            let side = |p: DVec2| (b - a).perp_dot(p - a);
            let mut next = Vec::new();
            for i in 0..poly.len() {
                let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
                let (sp, sq) = (side(p), side(q));
                if sp >= 0.0 {
                    next.push(p);
                }
                if (sp >= 0.0) != (sq >= 0.0) {
                    next.push(p + (q - p) * (sp / (sp - sq)));
                }
            }
            poly = next;
        }
        (0..poly.len())
            .map(|i| poly[i].perp_dot(poly[(i + 1) % poly.len()]))
            .sum::<f64>()
            / 2.0
    }

    #[test]
    fn a_box_and_a_turned_prism_meet_in_the_prism_of_their_squares_overlap() {
        // A: the unit cube; B: a unit square turned 0.4 rad about z around
        // (0.8, 0.7), from z = -0.5 to 1.5. A ∩ B is the squares' overlap
        // times height 1.
        let mut input = Input::default();
        add_box(&mut input, DVec3::ZERO, DVec3::ONE, Operand::A);
        let base = input.points.len();
        add_box(
            &mut input,
            DVec3::new(-0.5, -0.5, -0.5),
            DVec3::new(0.5, 0.5, 1.5),
            Operand::B,
        );
        let (s, c) = (0.4f64.sin(), 0.4f64.cos());
        let centre = DVec2::new(0.8, 0.7);
        for p in &mut input.points[base..] {
            *p = DVec3::new(
                c * p.x - s * p.y + centre.x,
                s * p.x + c * p.y + centre.y,
                p.z,
            );
        }
        let square = [DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y];
        let turned = square.map(|q| {
            let q = q - 0.5;
            DVec2::new(c * q.x - s * q.y, s * q.x + c * q.y) + centre
        });
        let overlap = clipped_area(&turned, &square);
        let i = boolean(&input, Operation::Intersection).unwrap();
        let d = boolean(&input, Operation::Difference).unwrap();
        let u = boolean(&input, Operation::Union).unwrap();
        assert!(closed(&i) && closed(&d) && closed(&u));
        assert!(
            (volume(&i) - overlap).abs() < 1e-12,
            "{} {overlap}",
            volume(&i)
        );
        assert!((volume(&d) - (1.0 - overlap)).abs() < 1e-12);
        assert!((volume(&u) - (3.0 - overlap)).abs() < 1e-12);
    }

    #[test]
    fn disjoint_and_nested_shells_are_classified_by_winding() {
        let far = two_boxes(DVec3::splat(5.0));
        let u = boolean(&far, Operation::Union).unwrap();
        assert_eq!(u.polygons.len(), 12);
        assert!(boolean(&far, Operation::Intersection)
            .unwrap()
            .polygons
            .is_empty());
        let mut nested = Input::default();
        add_box(&mut nested, DVec3::ZERO, DVec3::splat(3.0), Operand::A);
        add_box(&mut nested, DVec3::ONE, DVec3::splat(2.0), Operand::B);
        let d = boolean(&nested, Operation::Difference).unwrap();
        assert!((volume(&d) - 26.0).abs() < 1e-12);
        assert!(d.polygons.iter().filter(|p| p.reversed).count() == 6);
        let i = boolean(&nested, Operation::Intersection).unwrap();
        assert!((volume(&i) - 1.0).abs() < 1e-12);
    }

    fn boxes(a: (DVec3, DVec3), b: (DVec3, DVec3)) -> Input {
        let mut input = Input::default();
        add_box(&mut input, a.0, a.1, Operand::A);
        add_box(&mut input, b.0, b.1, Operand::B);
        input
    }

    /// V − E + F of a closed result: 2 − 2·genus per component.
    fn euler_characteristic(out: &Output) -> i64 {
        let mut edges = rustc_hash::FxHashSet::default();
        let mut verts = rustc_hash::FxHashSet::default();
        for p in &out.polygons {
            for k in 0..p.ring.len() {
                verts.insert(p.ring[k]);
                edges.insert(ordered(p.ring[k], p.ring[(k + 1) % p.ring.len()]));
            }
        }
        verts.len() as i64 - edges.len() as i64 + out.polygons.len() as i64
    }

    #[test]
    fn touching_coplanar_and_equal_boxes_are_computed_exactly() {
        let v = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        let unit = (DVec3::ZERO, DVec3::ONE);
        // (B, volumes of A ∪ B, A − B, A ∩ B), A the unit cube.
        let cases = [
            ((v(1.0, 0.0, 0.0), v(2.0, 1.0, 1.0)), [2.0, 1.0, 0.0]),
            ((v(1.0, 0.25, 0.25), v(2.0, 0.75, 1.25)), [1.5, 1.0, 0.0]),
            ((v(0.25, 0.25, 1.0), v(1.25, 1.25, 2.0)), [2.0, 1.0, 0.0]),
            ((v(0.5, 0.5, 0.5), v(1.5, 1.5, 1.0)), [1.375, 0.875, 0.125]),
            (unit, [1.0, 0.0, 1.0]),
            ((v(0.5, 0.0, 0.0), v(1.5, 1.0, 1.0)), [1.5, 0.5, 0.5]),
            // B's edges pass through the middle of A's faces' diagonals.
            (
                (DVec3::splat(0.5), DVec3::splat(1.5)),
                [1.875, 0.875, 0.125],
            ),
        ];
        for (b, volumes) in cases {
            let input = boxes(unit, b);
            for (operation, expected) in [
                Operation::Union,
                Operation::Difference,
                Operation::Intersection,
            ]
            .into_iter()
            .zip(volumes)
            {
                let out = boolean(&input, operation).unwrap();
                let label = format!("{b:?} {operation:?}");
                assert!(closed(&out), "{label}");
                assert!(
                    (volume(&out) - expected).abs() < 1e-12,
                    "{label}: {}",
                    volume(&out)
                );
                if expected == 0.0 {
                    assert!(out.polygons.is_empty(), "{label}");
                } else {
                    assert_eq!(euler_characteristic(&out), 2, "{label}");
                }
            }
        }
    }

    #[test]
    fn a_cutter_flush_with_both_faces_of_a_slab_leaves_a_clean_hole() {
        let slab = (DVec3::ZERO, DVec3::new(4.0, 1.0, 4.0));
        let window = (DVec3::new(1.0, 0.0, 1.0), DVec3::new(3.0, 1.0, 3.0));
        let out = boolean(&boxes(slab, window), Operation::Difference).unwrap();
        assert!(closed(&out));
        assert!((volume(&out) - 12.0).abs() < 1e-12, "{}", volume(&out));
        assert_eq!(euler_characteristic(&out), 0, "genus 1");
        // The window's flush faces are gone; its four sides line the hole.
        let reversed = out.polygons.iter().filter(|p| p.reversed).count();
        assert!(reversed >= 4, "{reversed}");
    }

    #[test]
    fn an_edge_rounding_left_a_few_ulps_long_is_collapsed_onto_its_input_end() {
        // A tetrahedron whose edge 0-1 is split by a made point 1 ulp from
        // corner 0: its two triangles at that edge go, the rest close up.
        let a = DVec3::new(0.3, 0.0, 0.0);
        let made = DVec3::new(0.3 + f64::EPSILON / 4.0, 0.0, 0.0);
        let mut out = Output {
            points: vec![a, DVec3::X, DVec3::Y, DVec3::Z, made],
            sources: vec![],
            polygons: vec![],
        };
        for ring in [
            [0, 4, 2],
            [4, 1, 2],
            [4, 0, 3],
            [1, 4, 3],
            [0, 2, 3],
            [1, 3, 2],
        ] {
            out.polygons.push(OutPolygon {
                ring: ring.to_vec(),
                source: 0,
                whole: false,
                reversed: false,
            });
        }
        exact::collapse_rounded_edges(&mut out, 4);
        assert_eq!(out.polygons.len(), 4);
        assert!(closed(&out));
        assert!(out.polygons.iter().all(|p| !p.ring.contains(&4)));
    }

    #[test]
    fn the_exact_path_agrees_with_the_general_position_path() {
        for offset in [
            DVec3::new(0.5, 0.4, 0.3),
            DVec3::splat(0.2),
            DVec3::splat(5.0),
        ] {
            let input = two_boxes(offset);
            for operation in [
                Operation::Union,
                Operation::Difference,
                Operation::Intersection,
            ] {
                let fast = boolean(&input, operation).unwrap();
                let exact = boolean_exact(&input, operation).unwrap();
                assert!(closed(&exact));
                assert!(
                    (volume(&fast) - volume(&exact)).abs() < 1e-12,
                    "{operation:?} {} {}",
                    volume(&fast),
                    volume(&exact)
                );
                assert_eq!(euler_characteristic(&fast), euler_characteristic(&exact));
            }
        }
    }

    #[test]
    fn solids_touching_along_an_edge_or_at_a_corner_get_their_own_vertices() {
        for (b, copies) in [
            ((DVec3::new(1.0, 1.0, 0.0), DVec3::new(2.0, 2.0, 1.0)), 2),
            ((DVec3::ONE, DVec3::splat(2.0)), 1),
        ] {
            let input = boxes((DVec3::ZERO, DVec3::ONE), b);
            let union = boolean(&input, Operation::Union).unwrap();
            assert!(closed(&union));
            assert!((volume(&union) - 2.0).abs() < 1e-12);
            // Two cubes: 16 vertices, 2 components of Euler characteristic 2.
            assert_eq!(euler_characteristic(&union), 4, "{b:?}");
            let copied: Vec<_> = union
                .sources
                .iter()
                .filter(|s| matches!(s, PointSource::Copy(_)))
                .collect();
            assert_eq!(copied.len(), copies, "{b:?}");
            assert!(boolean(&input, Operation::Intersection)
                .unwrap()
                .polygons
                .is_empty());
            let d = boolean(&input, Operation::Difference).unwrap();
            assert!(closed(&d) && (volume(&d) - 1.0).abs() < 1e-12);
        }
        // Work beyond the exact path's bound: refused before it starts,
        // naming the face with the most contacts.
        let input = boxes(
            (DVec3::ZERO, DVec3::ONE),
            (DVec3::new(0.5, 0.0, 0.0), DVec3::new(1.5, 1.0, 1.0)),
        );
        let tris = triangulate(&input).unwrap();
        let err = exact::bounded(&input, &tris, Operation::Union, 10).unwrap_err();
        assert!(
            matches!(err, BooleanError::TooManyContacts { contacts, .. } if contacts > 3),
            "{err}"
        );
        let mut open = two_boxes(DVec3::splat(0.5));
        open.polygons.remove(0);
        assert_eq!(
            boolean(&open, Operation::Union).unwrap_err(),
            BooleanError::Open {
                operand: Operand::A,
                boundary_edges: 4,
                non_manifold_edges: 0
            }
        );
    }
}
