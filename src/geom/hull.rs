//! Convex hulls of points in 3D (issue 35's `convex_hull`): Quickhull
//! (Barber, Dobkin & Huhdanpaa 1996) with exact orientation predicates, so
//! the hull is right on any input, not only in general position.
//!
//! - Visibility is exact (`orient3d` < 0: strictly outside a face's plane).
//!   A point on a face's plane is not outside it, so a point on the hull's
//!   surface never becomes a vertex, and the visible region from a point
//!   outside the hull is always a connected set bounded by one horizon
//!   cycle: no epsilon, no "thick" facets, no repair.
//! - Quickhull's choices (which face next, which of its outside points)
//!   only steer the work; they are taken in float and in index order, so
//!   the result does not depend on them beyond its triangulation.
//! - Adjacent triangles that are exactly coplanar are merged into one
//!   convex polygon, and polygon corners that lie exactly on the segment
//!   of their neighbours are dropped: only extreme points are vertices, as
//!   in qhull, and the hull of a cube's lattice is its 8 corners and 6
//!   quads (`merge_coplanar`). Without it each polygon is fanned from its
//!   lowest index (in general position: the triangles as made).
//!
//! Cost: expected O(n log n) for points spread in a volume (each point is
//! tested against the faces made while it is outside); O(n h) at worst.

use glam::DVec3;
use thiserror::Error;

use super::predicates::{orient2d_dropping, orient3d};
use super::union_find::UnionFind;

/// A convex hull: faces wound counter-clockwise seen from outside, as
/// indices into the input points; each face starts at its lowest index
/// and the faces are sorted, so the same points give the same hull.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Hull {
    /// The hull's vertices, ascending (of coincident points, the first).
    pub vertices: Vec<usize>,
    /// Every face's corners, one face after another (one allocation for
    /// the whole hull: a hull of 10⁶ points has 2·10⁶ faces).
    corners: Vec<usize>,
    /// Where each face's corners end in `corners`.
    ends: Vec<usize>,
}

impl Hull {
    /// The faces, in order.
    pub fn faces(&self) -> impl ExactSizeIterator<Item = &[usize]> + '_ {
        (0..self.ends.len()).map(|k| {
            let start = if k == 0 { 0 } else { self.ends[k - 1] };
            &self.corners[start..self.ends[k]]
        })
    }

    pub fn face_count(&self) -> usize {
        self.ends.len()
    }
}

/// Why points have no three-dimensional hull.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum HullError {
    #[error("point {0} is not finite")]
    NonFinite(usize),
    #[error("a hull needs 4 points that are not coplanar, and there are {0} distinct points")]
    TooFew(usize),
    #[error("all {0} distinct points lie on one line: their hull is a segment, not a solid")]
    Collinear(usize),
    #[error("all {0} distinct points lie in one plane: their hull is a polygon, not a solid")]
    Coplanar(usize),
    /// Points so far apart in magnitude (the smallest below 2^-900 of the
    /// largest) that their products underflow and no predicate is exact.
    #[error("the points' coordinates span too many orders of magnitude for an exact hull")]
    Inexact,
    #[error("{0} points are more than a hull takes (at most 2^32 − 2)")]
    TooMany(usize),
}

/// An outside point as its face holds it: the coordinates travel with the
/// index, so partitioning streams through memory instead of gathering
/// from the whole input at random (at 10⁶ points that gather was most of
/// the time).
#[derive(Debug, Clone, Copy)]
struct Candidate {
    p: DVec3,
    i: u32,
}

/// A face's plane as the visibility test needs it.
#[derive(Debug, Clone, Copy)]
struct Plane {
    /// The position of `v[0]`, where the test starts.
    origin: DVec3,
    /// `(b − a) × (c − a)` in float, and per component the sum of the
    /// magnitudes of its two products: what the float filter needs.
    normal: DVec3,
    permanent: DVec3,
    v: [u32; 3],
}

#[derive(Debug, Clone)]
struct Face {
    plane: Plane,
    /// The face across edge i (v[i] -> v[i + 1]).
    next: [u32; 3],
    /// Its outside points: a list in the shared table, or [`NO_LIST`].
    outside: u32,
    alive: bool,
}

/// A face with no outside points holds no list.
const NO_LIST: u32 = u32::MAX;

/// No neighbour yet.
const UNLINKED: u32 = u32::MAX;

/// The convex hull of `points`.
pub fn convex_hull(points: &[DVec3], merge_coplanar: bool) -> Result<Hull, HullError> {
    if let Some(i) = points.iter().position(|p| !p.is_finite()) {
        return Err(HullError::NonFinite(i));
    }
    // Indices travel as u32 inside the hull (smaller records).
    if points.len() >= UNLINKED as usize {
        return Err(HullError::TooMany(points.len()));
    }
    // Scaled by one power of two (exact, the hull's indices unchanged) so
    // the largest coordinate is near 1: products of tiny coordinates would
    // underflow, where no predicate is exact.
    let largest = points
        .iter()
        .map(|p| p.abs().max_element())
        .fold(0.0, f64::max);
    let scaled: Vec<DVec3>;
    let points: &[DVec3] = if largest > 0.0 && !(1.0e-30..=1.0e30).contains(&largest) {
        let shift = -libm::ilogb(largest);
        scaled = points
            .iter()
            .map(|p| {
                DVec3::new(
                    libm::scalbn(p.x, shift),
                    libm::scalbn(p.y, shift),
                    libm::scalbn(p.z, shift),
                )
            })
            .collect();
        &scaled
    } else {
        points
    };
    hull_of(points, merge_coplanar)
}

/// The hull of finite, scaled points. The result depends only on the
/// points: the extreme points, the exactly coplanar faces merged, each
/// polygon from its lowest index and the polygons sorted. So neither the
/// interior points thrown away first nor the order Quickhull works in
/// can change it, and coincident points are represented by their lowest
/// index (they take every decision together, and ties go to the lower).
fn hull_of(points: &[DVec3], merge_coplanar: bool) -> Result<Hull, HullError> {
    let candidates: Vec<u32> = match outside_inner_ball(points) {
        Some(kept) => kept,
        None => (0..points.len() as u32).collect(),
    };
    let faces = quickhull(points, &candidates)?;
    finish(points, &faces, merge_coplanar)
}

/// Akl and Toussaint's throw-away step (1978), made exact: the hull of a
/// fixed sample (every 32nd point) is built first, and every point
/// strictly inside a ball inside that hull is dropped with one distance
/// test, as it cannot be a vertex or lie on the hull. In a volume most
/// points go (in a ball, 75% at 10⁵ points and more beyond), so Quickhull
/// sees few; on a sphere none do, for about 3% more work. `None` when the
/// sample is too small or flat to help.
fn outside_inner_ball(points: &[DVec3]) -> Option<Vec<u32>> {
    const STRIDE: usize = 32;
    // Below this the sample's hull is too coarse to drop many points.
    const SMALLEST_SAMPLE: usize = 64;
    if points.len() < STRIDE * SMALLEST_SAMPLE {
        return None;
    }
    let sample: Vec<DVec3> = points.iter().step_by(STRIDE).copied().collect();
    let hull = hull_of(&sample, true).ok()?;
    let corners: Vec<DVec3> = hull.vertices.iter().map(|&i| sample[i]).collect();
    let centre = corners.iter().copied().sum::<DVec3>() / corners.len() as f64;
    // The largest radius whose ball around the centre lies strictly inside
    // every face's plane, bounded from below with the predicates' own
    // float filter, so it holds for slivers too: n·(a − centre) is at
    // least the float value less its error bound (as in `Plane::sees`),
    // and |n| at most the float length plus the cross product's rounding.
    let mut radius = f64::INFINITY;
    for face in hull.faces() {
        let plane = Plane::new(&sample, [face[0], face[1], face[2]].map(|i| i as u32));
        let d = centre - plane.origin;
        let depth = -plane.normal.dot(d) - 1.0e-15 * plane.permanent.dot(d.abs());
        let length = plane.normal.length() + 1.0e-15 * plane.permanent.length();
        radius = radius.min(depth / (length * (1.0 + 1.0e-15)));
    }
    // The last roundings (this quotient, the squared distances below) are
    // a few units in the last place: a relative margin of 1e-12 covers them.
    let radius = radius * (1.0 - 1.0e-12);
    if radius.is_nan() || radius <= 0.0 {
        return None;
    }
    let within = radius * radius;
    Some(
        (0..points.len() as u32)
            .filter(|&i| (points[i as usize] - centre).length_squared() >= within)
            .collect(),
    )
}

/// Outside lists, shared by the faces: a face holds one only while it has
/// outside points, and a dead face's list is reused, so the lists live as
/// long as the work does and not once per face ever made.
#[derive(Default)]
struct Lists {
    lists: Vec<Vec<Candidate>>,
    spare: Vec<u32>,
}

impl Lists {
    fn take(&mut self) -> u32 {
        self.spare.pop().unwrap_or_else(|| {
            self.lists.push(Vec::new());
            (self.lists.len() - 1) as u32
        })
    }

    fn give_back(&mut self, list: u32) {
        self.lists[list as usize].clear();
        self.spare.push(list);
    }
}

/// Quickhull over `candidates` (indices into `points`): the living faces
/// are triangles, the dead ones are marked.
fn quickhull(points: &[DVec3], candidates: &[u32]) -> Result<Vec<Face>, HullError> {
    let p = |i: u32| points[i as usize];
    let simplex = initial_simplex(points, candidates)?;
    // A hull of m points has at most 2m − 4 faces; with the slots of one
    // round's visible faces (freed after its new ones are made) that is
    // about the most slots in use, so the face table is rarely copied as
    // it grows.
    let mut faces: Vec<Face> = Vec::with_capacity(2 * candidates.len() + 8);
    let mut lists = Lists::default();
    let [a, b, c, d] = simplex;
    for (x, y, z, opposite) in [(a, b, c, d), (a, d, b, c), (b, d, c, a), (a, c, d, b)] {
        let v = if orient3d(p(x), p(y), p(z), p(opposite)) > 0.0 {
            [x, y, z]
        } else {
            [x, z, y]
        };
        faces.push(Face {
            plane: Plane::new(points, v),
            next: [UNLINKED; 3],
            outside: lists.take(),
            alive: true,
        });
    }
    link_all(&mut faces);
    for &i in candidates {
        if simplex.contains(&i) {
            continue;
        }
        let candidate = Candidate { p: p(i), i };
        if let Some(f) = (0..4).find(|&f| faces[f].plane.sees(points, &candidate.p)) {
            lists.lists[faces[f].outside as usize].push(candidate);
        }
    }
    for face in &mut faces {
        if lists.lists[face.outside as usize].is_empty() {
            lists.give_back(face.outside);
            face.outside = NO_LIST;
        }
    }

    // Dead faces' slots are reused, so memory follows the living hull,
    // not all the faces ever made.
    let mut free: Vec<u32> = Vec::new();
    let mut work: Vec<u32> = (0..4).rev().collect();
    let mut visible: Vec<u32> = Vec::new();
    // This round's new faces: slot, plane and outside list side by side,
    // so handing out the orphans reads one small array.
    let mut made: Vec<(u32, Plane, u32)> = Vec::new();
    let mut from: Vec<(u32, u32)> = Vec::new(); // (start vertex, new face)
    let mut to: Vec<(u32, u32)> = Vec::new(); // (end vertex, new face)
    let mut orphans: Vec<Candidate> = Vec::new(); // the visible faces' outside points
    let mut taken: Vec<Candidate> = Vec::new(); // those a new face sees
    let mut mark: Vec<u32> = Vec::with_capacity(faces.capacity());
    mark.resize(4, 0);
    let mut round = 0u32;
    while let Some(f) = work.pop() {
        let f = f as usize;
        if !faces[f].alive || faces[f].outside == NO_LIST {
            continue;
        }
        // The farthest outside point (float: it only chooses; ties go to
        // the lower index).
        let Plane { origin, normal, .. } = faces[f].plane;
        let eye = lists.lists[faces[f].outside as usize]
            .iter()
            .map(|c| ((c.p - origin).dot(normal), c))
            .reduce(|best, next| {
                if next.0 > best.0 || (next.0 == best.0 && next.1.i < best.1.i) {
                    next
                } else {
                    best
                }
            })
            .map(|(_, c)| *c)
            .expect("a face with a list has outside points");

        // The faces the eye sees: connected, found from `f`.
        round += 1;
        visible.clear();
        visible.push(f as u32);
        mark[f] = round;
        let mut k = 0;
        while k < visible.len() {
            let g = visible[k] as usize;
            k += 1;
            for n in faces[g].next {
                if mark[n as usize] != round && faces[n as usize].plane.sees(points, &eye.p) {
                    mark[n as usize] = round;
                    visible.push(n);
                }
            }
        }
        // The horizon: edges of visible faces whose neighbour is not.
        made.clear();
        from.clear();
        for &g in &visible {
            for e in 0..3 {
                let n = faces[g as usize].next[e];
                if mark[n as usize] == round {
                    continue;
                }
                let v = faces[g as usize].plane.v;
                let (s, t) = (v[e], v[(e + 1) % 3]);
                let face = Face {
                    plane: Plane::new(points, [s, t, eye.i]),
                    next: [n, UNLINKED, UNLINKED],
                    outside: NO_LIST,
                    alive: true,
                };
                let plane = face.plane;
                // Slots freed by earlier rounds only: this round's visible
                // faces are still read.
                let new = match free.pop() {
                    Some(slot) => {
                        faces[slot as usize] = face;
                        slot
                    }
                    None => {
                        faces.push(face);
                        mark.push(0);
                        (faces.len() - 1) as u32
                    }
                };
                let back = faces[n as usize]
                    .plane
                    .v
                    .iter()
                    .position(|&x| x == t)
                    .ok_or(HullError::Inexact)?;
                faces[n as usize].next[back] = new;
                from.push((s, new));
                made.push((new, plane, NO_LIST));
            }
        }
        // Around the eye: the new face on s -> t meets, across t -> eye,
        // the one that starts at t, and across eye -> s the one ending at
        // s. A horizon is usually a handful of edges: those are matched
        // by scanning, longer ones through sorted lists.
        to.clear();
        to.extend(made.iter().map(|(g, plane, _)| (plane.v[1], *g)));
        let short = made.len() <= 16;
        if !short {
            from.sort_unstable();
            to.sort_unstable();
        }
        let face_at = |list: &[(u32, u32)], v: u32| {
            let found = if short {
                list.iter().find(|&&(x, _)| x == v).map(|&(_, g)| g)
            } else {
                list.binary_search_by_key(&v, |&(x, _)| x)
                    .ok()
                    .map(|k| list[k].1)
            };
            found.ok_or(HullError::Inexact)
        };
        for (g, plane, _) in &made {
            let [s, t, _] = plane.v;
            faces[*g as usize].next[1] = face_at(&from, t)?;
            faces[*g as usize].next[2] = face_at(&to, s)?;
        }
        // The visible faces' points go to the first new face that sees
        // them; the rest are inside now. Each new face in turn takes what
        // it sees of what is left, so the lists are the ones a search for
        // each point's first seeing face makes, and no test branches on
        // its outcome (issue 38: that search, 4 tests a point with one
        // unpredictable exit, was a third of the hull of 10⁴ points on a
        // sphere).
        orphans.clear();
        for &g in &visible {
            let face = &mut faces[g as usize];
            face.alive = false;
            let list = std::mem::replace(&mut face.outside, NO_LIST);
            if list != NO_LIST {
                let points = lists.lists[list as usize].iter();
                orphans.extend(points.filter(|c| c.i != eye.i));
                lists.give_back(list);
            }
        }
        if taken.len() < orphans.len() {
            taken.resize(orphans.len(), orphans[0]);
        }
        for (_, plane, list) in made.iter_mut() {
            if orphans.is_empty() {
                break;
            }
            let (mut kept, mut took) = (0, 0);
            for k in 0..orphans.len() {
                let sees = plane.sees(points, &orphans[k].p);
                let c = orphans[k];
                taken[took] = c;
                orphans[kept] = c;
                took += usize::from(sees);
                kept += usize::from(!sees);
            }
            orphans.truncate(kept);
            if took > 0 {
                *list = lists.take();
                lists.lists[*list as usize].extend_from_slice(&taken[..took]);
            }
        }
        for (g, _, list) in &made {
            faces[*g as usize].outside = *list;
        }
        free.extend_from_slice(&visible);
        work.extend(made.iter().rev().map(|(g, _, _)| *g));
    }
    Ok(faces)
}

/// Four points spanning a solid, the lexicographically lowest among them.
/// Scans in index order with ties to the lower index, so of coincident
/// points only the first can be chosen.
fn initial_simplex(points: &[DVec3], candidates: &[u32]) -> Result<[u32; 4], HullError> {
    let p = |i: u32| points[i as usize];
    let a = *candidates
        .iter()
        .min_by(|&&i, &&j| {
            let (pi, pj) = (p(i), p(j));
            pi.x.total_cmp(&pj.x)
                .then(pi.y.total_cmp(&pj.y))
                .then(pi.z.total_cmp(&pj.z))
                .then(i.cmp(&j))
        })
        .ok_or(HullError::TooFew(0))?;
    let farthest = |score: &dyn Fn(u32) -> f64| {
        candidates
            .iter()
            .copied()
            .max_by(|&i, &j| score(i).total_cmp(&score(j)).then(j.cmp(&i)))
            .expect("not empty")
    };
    let b = farthest(&|i| p(i).distance_squared(p(a)));
    if p(b) == p(a) {
        return Err(HullError::TooFew(distinct_count(points, candidates)));
    }
    let dir = p(b) - p(a);
    let collinear = |i: u32| (0..3).all(|axis| orient2d_dropping(p(a), p(b), p(i), axis) == 0.0);
    let mut c = farthest(&|i| (p(i) - p(a)).cross(dir).length_squared());
    if collinear(c) {
        // Rounding can make an exactly collinear point look farthest.
        c = match candidates.iter().find(|&&i| !collinear(i)) {
            Some(&c) => c,
            None => return Err(too_few_or(points, candidates, HullError::Collinear)),
        };
    }
    let normal = (p(b) - p(a)).cross(p(c) - p(a));
    let mut d = farthest(&|i| (p(i) - p(a)).dot(normal).abs());
    if orient3d(p(a), p(b), p(c), p(d)) == 0.0 {
        d = match candidates
            .iter()
            .find(|&&i| orient3d(p(a), p(b), p(c), p(i)) != 0.0)
        {
            Some(&d) => d,
            None => return Err(too_few_or(points, candidates, HullError::Coplanar)),
        };
    }
    Ok([a, b, c, d])
}

/// How many distinct positions `candidates` hold (only for errors: it sorts).
fn distinct_count(points: &[DVec3], candidates: &[u32]) -> usize {
    let mut at: Vec<[u64; 3]> = candidates
        .iter()
        .map(|&i| {
            // +0 and −0 are one position.
            let q = points[i as usize] + DVec3::ZERO;
            [q.x.to_bits(), q.y.to_bits(), q.z.to_bits()]
        })
        .collect();
    at.sort_unstable();
    at.dedup();
    at.len()
}

/// `degenerate(count)`, or `TooFew` when under 4 distinct points.
fn too_few_or(
    points: &[DVec3],
    candidates: &[u32],
    degenerate: fn(usize) -> HullError,
) -> HullError {
    match distinct_count(points, candidates) {
        n if n < 4 => HullError::TooFew(n),
        n => degenerate(n),
    }
}

impl Plane {
    fn new(points: &[DVec3], v: [u32; 3]) -> Plane {
        let [a, b, c] = v.map(|v| points[v as usize]);
        let (u, w) = (b - a, c - a);
        Plane {
            origin: a,
            normal: u.cross(w),
            permanent: DVec3::new(
                (u.y * w.z).abs() + (u.z * w.y).abs(),
                (u.z * w.x).abs() + (u.x * w.z).abs(),
                (u.x * w.y).abs() + (u.y * w.x).abs(),
            ),
            v,
        }
    }

    /// `orient3d(a, b, c, p)` where the float value `n · (p − a)` is
    /// farther from 0 than its rounding error can reach (Shewchuk's
    /// first-stage bound on the same cofactor expansion, taken with
    /// margin: 9 units in the last place of the permanent) is only its
    /// sign: `None` when the exact predicate must decide.
    fn side_in_float(&self, p: DVec3) -> Option<f64> {
        let d = p - self.origin;
        let value = self.normal.dot(d);
        let bound = 1.0e-15 * self.permanent.dot(d.abs());
        (value.abs() > bound).then_some(-value)
    }

    /// Whether point `p` is strictly outside the plane: exactly, as
    /// `orient3d(a, b, c, p) < 0`, decided in float where the filter
    /// can ([`Plane::side_in_float`]). Most tests end in the filter.
    ///
    /// `p` by reference, and the exact test out of line: a point passed
    /// by value to the predicate's call was copied to the stack in two
    /// stores and read back across them, a store-forwarding stall on
    /// every test (issue 38: a quarter of Quickhull's time on a sphere).
    fn sees(&self, points: &[DVec3], p: &DVec3) -> bool {
        match self.side_in_float(*p) {
            Some(side) => side < 0.0,
            None => self.orient_exactly(points, p) < 0.0,
        }
    }

    #[cold]
    #[inline(never)]
    fn orient_exactly(&self, points: &[DVec3], p: &DVec3) -> f64 {
        self.orient(points, *p)
    }

    /// `orient3d(a, b, c, p)`, exactly.
    fn orient(&self, points: &[DVec3], p: DVec3) -> f64 {
        let [a, b, c] = self.v.map(|v| points[v as usize]);
        orient3d(a, b, c, p)
    }
}

/// Sets every face's neighbours from shared edges (the initial simplex).
fn link_all(faces: &mut [Face]) {
    for f in 0..faces.len() {
        for e in 0..3 {
            let (s, t) = (faces[f].plane.v[e], faces[f].plane.v[(e + 1) % 3]);
            for g in 0..faces.len() {
                let v = faces[g].plane.v;
                if (0..3).any(|k| v[k] == t && v[(k + 1) % 3] == s) {
                    faces[f].next[e] = g as u32;
                }
            }
        }
    }
}

/// The living faces as the result: merged and cleaned, or as triangles.
fn finish(points: &[DVec3], faces: &[Face], merge_coplanar: bool) -> Result<Hull, HullError> {
    let alive: Vec<usize> = (0..faces.len()).filter(|&f| faces[f].alive).collect();
    let mut groups = UnionFind::new(faces.len());
    // Faces with an exactly coplanar neighbour; the others (in general
    // position, all of them) are their own polygon and skip the outlines.
    let mut joined = vec![false; faces.len()];
    for &f in &alive {
        let plane = &faces[f].plane;
        for n in faces[f].next {
            let n = n as usize;
            // Each pair once, from its lower face.
            if n < f {
                continue;
            }
            let opposite = faces[n]
                .plane
                .v
                .iter()
                .copied()
                .find(|v| !plane.v.contains(v))
                .ok_or(HullError::Inexact)?;
            let q = points[opposite as usize];
            let side = plane
                .side_in_float(q)
                .unwrap_or_else(|| plane.orient(points, q));
            if side == 0.0 {
                groups.union(f as u32, n as u32);
                joined[f] = true;
                joined[n] = true;
            }
        }
    }
    // Polygons as (first two corners, where its corners are), sorted at
    // the end: a directed edge lies on one face only, so the first two
    // corners decide the lexicographic order of whole polygons.
    let mut order: Vec<(usize, usize, u32, u32)> = Vec::with_capacity(alive.len());
    let mut corners: Vec<usize> = Vec::with_capacity(3 * alive.len());
    let mut push = |ring: &[usize], order: &mut Vec<(usize, usize, u32, u32)>| {
        let lowest = (0..ring.len()).min_by_key(|&k| ring[k]).expect("not empty");
        let start = corners.len();
        corners.extend_from_slice(&ring[lowest..]);
        corners.extend_from_slice(&ring[..lowest]);
        order.push((
            corners[start],
            corners[start + 1],
            start as u32,
            ring.len() as u32,
        ));
    };
    // Each merged group's outline: its edges whose neighbour is elsewhere,
    // chained from start to end.
    let mut outline: std::collections::BTreeMap<u32, Vec<(usize, usize)>> =
        std::collections::BTreeMap::new();
    for &f in &alive {
        let v = faces[f].plane.v.map(|v| v as usize);
        if !joined[f] {
            push(&v, &mut order);
            continue;
        }
        let root = groups.find(f as u32);
        for e in 0..3 {
            if groups.find(faces[f].next[e]) != root {
                outline
                    .entry(root)
                    .or_default()
                    .push((v[e], v[(e + 1) % 3]));
            }
        }
    }
    for mut edges in outline.into_values() {
        edges.sort_unstable();
        let mut ring = vec![edges[0].0];
        let mut at = edges[0].1;
        while at != ring[0] {
            // An outline visits each of its edges once.
            if ring.len() > edges.len() {
                return Err(HullError::Inexact);
            }
            ring.push(at);
            let k = edges
                .binary_search_by_key(&at, |&(s, _)| s)
                .map_err(|_| HullError::Inexact)?;
            at = edges[k].1;
        }
        let mut ring = drop_straight_corners(points, ring);
        if merge_coplanar {
            push(&ring, &mut order);
        } else {
            // A convex polygon without straight corners fans from any
            // corner: from its lowest index, so the triangles are canonical.
            let lowest = (0..ring.len()).min_by_key(|&k| ring[k]).expect("not empty");
            ring.rotate_left(lowest);
            for k in 1..ring.len() - 1 {
                push(&[ring[0], ring[k], ring[k + 1]], &mut order);
            }
        }
    }
    order.sort_unstable();
    let mut hull = Hull {
        vertices: Vec::new(),
        corners: Vec::with_capacity(corners.len()),
        ends: Vec::with_capacity(order.len()),
    };
    for &(_, _, start, len) in &order {
        let (start, len) = (start as usize, len as usize);
        hull.corners.extend_from_slice(&corners[start..start + len]);
        hull.ends.push(hull.corners.len());
    }
    let mut used = vec![false; points.len()];
    for &i in &hull.corners {
        used[i] = true;
    }
    hull.vertices = (0..points.len()).filter(|&i| used[i]).collect();
    Ok(hull)
}

/// `ring` without the corners that lie exactly between their neighbours
/// (a point on a hull edge, made a vertex before the hull grew past it).
fn drop_straight_corners(points: &[DVec3], mut ring: Vec<usize>) -> Vec<usize> {
    let p = |i: usize| points[i];
    let mut k = 0;
    while ring.len() > 3 && k < ring.len() {
        let n = ring.len();
        let (a, b, c) = (ring[(k + n - 1) % n], ring[k], ring[(k + 1) % n]);
        if (0..3).all(|axis| orient2d_dropping(p(a), p(b), p(c), axis) == 0.0) {
            ring.remove(k);
        } else {
            k += 1;
        }
    }
    ring
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice(n: usize) -> Vec<DVec3> {
        let mut points = Vec::new();
        for x in 0..n {
            for y in 0..n {
                for z in 0..n {
                    points.push(DVec3::new(x as f64, y as f64, z as f64));
                }
            }
        }
        points
    }

    #[test]
    fn a_lattice_gives_its_eight_corners_and_six_squares() {
        let points = lattice(5);
        let hull = convex_hull(&points, true).unwrap();
        assert_eq!(hull.vertices, vec![0, 4, 20, 24, 100, 104, 120, 124]);
        assert_eq!(hull.face_count(), 6);
        assert!(hull.faces().all(|f| f.len() == 4));
        // Triangulated: 12 triangles on the same corners, once the
        // lattice's inner points are gone.
        let tris = convex_hull(&points, false).unwrap();
        assert!(tris.faces().all(|f| f.len() == 3));
    }

    /// Closed (every directed edge once, its reverse once) and a sphere
    /// (V − E + F = 2).
    fn assert_closed_sphere(hull: &Hull) {
        let mut edges: Vec<(usize, usize)> = hull
            .faces()
            .flat_map(|f| (0..f.len()).map(move |k| (f[k], f[(k + 1) % f.len()])))
            .collect();
        edges.sort_unstable();
        let uses = edges.len();
        edges.dedup();
        assert_eq!(edges.len(), uses, "a directed edge used twice");
        assert!(edges
            .iter()
            .all(|&(s, t)| edges.binary_search(&(t, s)).is_ok()));
        let (v, e) = (hull.vertices.len() as i64, (edges.len() / 2) as i64);
        assert_eq!(v - e + hull.face_count() as i64, 2);
    }

    #[test]
    fn every_face_sees_every_point_on_its_inner_side() {
        // Points on and in a sphere, duplicates and collinear runs mixed in.
        let mut points = Vec::new();
        let mut s = 12345u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        // Enough points that the throw-away step runs (a sample of 64).
        for _ in 0..2100 {
            let v = DVec3::new(next() - 0.5, next() - 0.5, next() - 0.5);
            points.push(if next() < 0.5 { v.normalize() } else { v });
        }
        points.extend_from_within(..50);
        for k in 0..10 {
            points.push(DVec3::new(0.0, 0.0, -1.0 + 0.2 * k as f64));
        }
        let hull = convex_hull(&points, true).unwrap();
        for face in hull.faces() {
            let [a, b, c] = [face[0], face[1], face[2]].map(|i| points[i]);
            for (i, &q) in points.iter().enumerate() {
                assert!(
                    orient3d(a, b, c, q) >= 0.0,
                    "point {i} outside face {face:?}"
                );
            }
        }
        assert_closed_sphere(&hull);
    }

    #[test]
    fn tiny_and_huge_coordinates_give_the_same_hull() {
        let points = lattice(4);
        let want = convex_hull(&points, true).unwrap();
        for scale in [1e-105, 1e-300, 1e200, 1e300] {
            let scaled: Vec<DVec3> = points.iter().map(|&p| p * scale).collect();
            assert_eq!(convex_hull(&scaled, true).unwrap(), want, "{scale}");
        }
    }

    /// Points uniform in the unit ball (splitmix64, fixed seed).
    fn ball(n: usize, seed: u64) -> Vec<DVec3> {
        let mut state = seed;
        let mut next = || {
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^= z >> 31;
            2.0 * ((z >> 11) as f64 / (1u64 << 53) as f64) - 1.0
        };
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            let p = DVec3::new(next(), next(), next());
            if p.length_squared() <= 1.0 {
                out.push(p);
            }
        }
        out
    }

    /// `faces` (renumbered from another hull) put in canonical order, each
    /// from its lowest index and sorted, equal `hull`'s faces.
    fn assert_same_faces(mut faces: Vec<Vec<usize>>, hull: &Hull) {
        for face in &mut faces {
            let lowest = (0..face.len()).min_by_key(|&k| face[k]).unwrap();
            face.rotate_left(lowest);
        }
        faces.sort();
        assert_eq!(
            faces,
            hull.faces().map(<[usize]>::to_vec).collect::<Vec<_>>()
        );
    }

    #[test]
    fn the_throw_away_step_drops_most_of_a_ball_and_no_hull_vertex() {
        let points = ball(100_000, 7);
        let kept = outside_inner_ball(&points).expect("a ball's sample has a solid hull");
        // About a quarter stays at this size (the sample's hull reaches
        // about 0.91 of the radius everywhere).
        assert!(
            kept.len() < points.len() * 3 / 10,
            "kept {} of {}",
            kept.len(),
            points.len()
        );
        let hull = convex_hull(&points, true).unwrap();
        assert!(hull
            .vertices
            .iter()
            .all(|&v| kept.binary_search(&(v as u32)).is_ok()));
        // The same hull from the extreme points alone, where the step
        // drops nothing (too few) and Quickhull sees every point.
        let extreme: Vec<DVec3> = hull.vertices.iter().map(|&v| points[v]).collect();
        let alone = convex_hull(&extreme, true).unwrap();
        let back = |f: &[usize]| f.iter().map(|&k| hull.vertices[k]).collect::<Vec<_>>();
        assert_same_faces(alone.faces().map(back).collect(), &hull);
    }

    #[test]
    fn the_hull_does_not_depend_on_the_order_of_the_points() {
        let points = ball(20_000, 11);
        let hull = convex_hull(&points, false).unwrap();
        // Reversed: point i is now n − 1 − i.
        let n = points.len();
        let reversed: Vec<DVec3> = points.iter().rev().copied().collect();
        let other = convex_hull(&reversed, false).unwrap();
        let faces = other
            .faces()
            .map(|f| f.iter().map(|&i| n - 1 - i).collect())
            .collect();
        assert_same_faces(faces, &hull);
    }

    /// The hull's faces as rings of positions, each from its least
    /// position (compared as coordinate triples) and sorted: comparable
    /// between inputs that hold the same points in another order, whatever
    /// copy of a repeated point a hull keeps.
    fn faces_by_position(points: &[DVec3], hull: &Hull) -> Vec<Vec<[f64; 3]>> {
        let key = |p: DVec3| p.to_array();
        let mut faces: Vec<Vec<[f64; 3]>> = hull
            .faces()
            .map(|f| {
                let mut ring: Vec<[f64; 3]> = f.iter().map(|&i| key(points[i])).collect();
                let least = (0..ring.len())
                    .min_by(|&a, &b| ring[a].partial_cmp(&ring[b]).unwrap())
                    .unwrap();
                ring.rotate_left(least);
                ring
            })
            .collect();
        faces.sort_by(|a, b| a.partial_cmp(b).unwrap());
        faces
    }

    #[test]
    fn lattice_subsets_in_any_order_give_one_closed_convex_hull() {
        // Small sets drawn from a 4 × 4 × 4 lattice, with repeats: nearly
        // every face is coplanar with other points and every edge has
        // points along it, so Quickhull's visibility tests keep falling to
        // the exact predicate, its orphans are handed to new faces that
        // share planes, and coplanar faces merge. Each hull must contain
        // every point, be closed with V − E + F = 2, and come out the
        // same, face for face, from the points shuffled. (Deciding an
        // undecided float test either way without the exact predicate
        // fails here; the tests above do not notice.)
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = |n: u64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state % n
        };
        let mut hulls = 0;
        for set in 0..300 {
            let n = 5 + next(60) as usize;
            // Every other set in tenths, which binary cannot hold: points
            // that are coplanar in decimal are a rounding off it, and only
            // the exact predicate tells which side.
            let unit = if set % 2 == 0 { 1.0 } else { 0.1 };
            let mut coordinate = || next(4) as f64 * unit;
            let points: Vec<DVec3> = (0..n)
                .map(|_| DVec3::new(coordinate(), coordinate(), coordinate()))
                .collect();
            let Ok(hull) = convex_hull(&points, true) else {
                continue;
            };
            hulls += 1;
            for face in hull.faces() {
                let [a, b, c] = [face[0], face[1], face[2]].map(|i| points[i]);
                assert!(points.iter().all(|&q| orient3d(a, b, c, q) >= 0.0));
            }
            assert_closed_sphere(&hull);
            let mut shuffled = points.clone();
            for k in (1..shuffled.len()).rev() {
                shuffled.swap(k, next(k as u64 + 1) as usize);
            }
            let other = convex_hull(&shuffled, true).expect("the same points");
            assert_eq!(
                faces_by_position(&shuffled, &other),
                faces_by_position(&points, &hull)
            );
        }
        assert!(hulls > 250, "only {hulls} of 300 sets had a solid hull");
    }

    #[test]
    fn degenerate_inputs_are_named() {
        let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        assert_eq!(
            convex_hull(&[p(0.0, 0.0, 0.0); 5], true),
            Err(HullError::TooFew(1))
        );
        let line: Vec<DVec3> = (0..6).map(|k| p(k as f64, 2.0 * k as f64, 0.5)).collect();
        assert_eq!(convex_hull(&line, true), Err(HullError::Collinear(6)));
        let plane: Vec<DVec3> = (0..9)
            .map(|k| p((k % 3) as f64, (k / 3) as f64, 1.0))
            .collect();
        assert_eq!(convex_hull(&plane, true), Err(HullError::Coplanar(9)));
        assert_eq!(
            convex_hull(&[p(0.0, 0.0, f64::NAN)], true),
            Err(HullError::NonFinite(0))
        );
    }
}
