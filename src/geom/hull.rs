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
    pub faces: Vec<Vec<usize>>,
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
}

#[derive(Debug, Clone)]
struct Face {
    v: [usize; 3],
    /// `(b − a) × (c − a)` in float, and per component the sum of the
    /// magnitudes of its two products: what the visibility filter needs.
    normal: DVec3,
    permanent: DVec3,
    /// The face across edge i (v[i] -> v[i + 1]).
    next: [usize; 3],
    outside: Vec<usize>,
    alive: bool,
}

/// The convex hull of `points`.
pub fn convex_hull(points: &[DVec3], merge_coplanar: bool) -> Result<Hull, HullError> {
    if let Some(i) = points.iter().position(|p| !p.is_finite()) {
        return Err(HullError::NonFinite(i));
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
    // Distinct positions, the first index of each.
    let mut order: Vec<usize> = (0..points.len()).collect();
    let key = |i: &usize| (points[*i].x, points[*i].y, points[*i].z, *i);
    order.sort_by(|a, b| {
        let (ka, kb) = (key(a), key(b));
        ka.0.total_cmp(&kb.0)
            .then(ka.1.total_cmp(&kb.1))
            .then(ka.2.total_cmp(&kb.2))
            .then(ka.3.cmp(&kb.3))
    });
    order.dedup_by(|b, a| points[*a] == points[*b]);
    let distinct = order;
    if distinct.len() < 4 {
        return Err(HullError::TooFew(distinct.len()));
    }
    let p = |i: usize| points[i];
    let simplex = initial_simplex(points, &distinct)?;

    let mut faces: Vec<Face> = Vec::new();
    let [a, b, c, d] = simplex;
    for (x, y, z, opposite) in [(a, b, c, d), (a, d, b, c), (b, d, c, a), (a, c, d, b)] {
        let v = if orient3d(p(x), p(y), p(z), p(opposite)) > 0.0 {
            [x, y, z]
        } else {
            [x, z, y]
        };
        faces.push(Face {
            v,
            normal: DVec3::ZERO,
            permanent: DVec3::ZERO,
            next: [usize::MAX; 3],
            outside: Vec::new(),
            alive: true,
        });
    }
    link_all(&mut faces);
    for face in &mut faces {
        face.set_plane(points);
    }
    for &i in &distinct {
        if simplex.contains(&i) {
            continue;
        }
        if let Some(f) = (0..4).find(|&f| sees(points, &faces[f], i)) {
            faces[f].outside.push(i);
        }
    }

    let mut work: Vec<usize> = (0..4).rev().collect();
    let mut visible: Vec<usize> = Vec::new();
    let mut mark: Vec<u32> = vec![0; 4];
    let mut round = 0u32;
    while let Some(f) = work.pop() {
        if !faces[f].alive || faces[f].outside.is_empty() {
            continue;
        }
        // The farthest outside point (float: it only chooses).
        let (fa, normal) = (p(faces[f].v[0]), faces[f].normal);
        let eye = *faces[f]
            .outside
            .iter()
            .max_by(|&&i, &&j| {
                (p(i) - fa)
                    .dot(normal)
                    .total_cmp(&(p(j) - fa).dot(normal))
                    .then(j.cmp(&i))
            })
            .expect("not empty");

        // The faces the eye sees: connected, found from `f`.
        round += 1;
        visible.clear();
        visible.push(f);
        mark[f] = round;
        let mut k = 0;
        while k < visible.len() {
            let g = visible[k];
            k += 1;
            for n in faces[g].next {
                if mark[n] != round && sees(points, &faces[n], eye) {
                    mark[n] = round;
                    visible.push(n);
                }
            }
        }
        // The horizon: edges of visible faces whose neighbour is not.
        let first_new = faces.len();
        let mut from: Vec<(usize, usize)> = Vec::new(); // (start vertex, new face)
        for &g in &visible {
            for e in 0..3 {
                let n = faces[g].next[e];
                if mark[n] == round {
                    continue;
                }
                let (s, t) = (faces[g].v[e], faces[g].v[(e + 1) % 3]);
                let new = faces.len();
                faces.push(Face {
                    v: [s, t, eye],
                    normal: DVec3::ZERO,
                    permanent: DVec3::ZERO,
                    next: [n, usize::MAX, usize::MAX],
                    outside: Vec::new(),
                    alive: true,
                });
                let made = faces.len() - 1;
                faces[made].set_plane(points);
                mark.push(0);
                let back = faces[n]
                    .v
                    .iter()
                    .position(|&x| x == t)
                    .ok_or(HullError::Inexact)?;
                faces[n].next[back] = new;
                from.push((s, new));
            }
        }
        // Around the eye: the new face on s -> t meets, across t -> eye,
        // the one that starts at t, and across eye -> s the one ending at s.
        from.sort_unstable();
        let mut to: Vec<(usize, usize)> = (first_new..faces.len())
            .map(|g| (faces[g].v[1], g))
            .collect();
        to.sort_unstable();
        let face_at = |list: &[(usize, usize)], v: usize| {
            list.binary_search_by_key(&v, |&(x, _)| x)
                .map(|k| list[k].1)
                .map_err(|_| HullError::Inexact)
        };
        for face in &mut faces[first_new..] {
            let [s, t, _] = face.v;
            face.next[1] = face_at(&from, t)?;
            face.next[2] = face_at(&to, s)?;
        }
        // The visible faces' points go to the new faces that see them.
        let mut orphans: Vec<usize> = Vec::new();
        for &g in &visible {
            faces[g].alive = false;
            orphans.append(&mut faces[g].outside);
        }
        for i in orphans {
            if i == eye {
                continue;
            }
            if let Some(n) = (first_new..faces.len()).find(|&n| sees(points, &faces[n], i)) {
                faces[n].outside.push(i);
            }
        }
        work.extend((first_new..faces.len()).rev());
    }
    finish(points, &faces, merge_coplanar)
}

/// Four points spanning a solid, the first of `distinct` among them.
fn initial_simplex(points: &[DVec3], distinct: &[usize]) -> Result<[usize; 4], HullError> {
    let p = |i: usize| points[i];
    let a = distinct[0];
    let farthest = |score: &dyn Fn(usize) -> f64| {
        distinct
            .iter()
            .copied()
            .max_by(|&i, &j| score(i).total_cmp(&score(j)).then(j.cmp(&i)))
            .expect("not empty")
    };
    let b = farthest(&|i| p(i).distance_squared(p(a)));
    let dir = p(b) - p(a);
    let collinear = |i: usize| (0..3).all(|axis| orient2d_dropping(p(a), p(b), p(i), axis) == 0.0);
    let mut c = farthest(&|i| (p(i) - p(a)).cross(dir).length_squared());
    if collinear(c) {
        // Rounding can make an exactly collinear point look farthest.
        c = *distinct
            .iter()
            .find(|&&i| !collinear(i))
            .ok_or(HullError::Collinear(distinct.len()))?;
    }
    let normal = (p(b) - p(a)).cross(p(c) - p(a));
    let mut d = farthest(&|i| (p(i) - p(a)).dot(normal).abs());
    if orient3d(p(a), p(b), p(c), p(d)) == 0.0 {
        d = *distinct
            .iter()
            .find(|&&i| orient3d(p(a), p(b), p(c), p(i)) != 0.0)
            .ok_or(HullError::Coplanar(distinct.len()))?;
    }
    Ok([a, b, c, d])
}

/// Whether point `i` is strictly outside `face`'s plane: exactly, as
/// `orient3d(a, b, c, p) < 0`, decided in float when the float value
/// `n · (p − a)` is farther from 0 than its rounding error can reach
/// (Shewchuk's first-stage bound on the same cofactor expansion, taken
/// with margin: 9 units in the last place of the permanent), else by the
/// exact predicate. Most tests end in the filter.
fn sees(points: &[DVec3], face: &Face, i: usize) -> bool {
    let a = points[face.v[0]];
    let d = points[i] - a;
    let value = face.normal.dot(d);
    let bound = 1.0e-15 * face.permanent.dot(d.abs());
    if value > bound {
        return true;
    }
    if value < -bound {
        return false;
    }
    let [a, b, c] = face.v.map(|v| points[v]);
    orient3d(a, b, c, points[i]) < 0.0
}

impl Face {
    fn set_plane(&mut self, points: &[DVec3]) {
        let [a, b, c] = self.v.map(|v| points[v]);
        let (u, w) = (b - a, c - a);
        self.normal = u.cross(w);
        self.permanent = DVec3::new(
            (u.y * w.z).abs() + (u.z * w.y).abs(),
            (u.z * w.x).abs() + (u.x * w.z).abs(),
            (u.x * w.y).abs() + (u.y * w.x).abs(),
        );
    }
}

/// Sets every face's neighbours from shared edges (the initial simplex).
fn link_all(faces: &mut [Face]) {
    for f in 0..faces.len() {
        for e in 0..3 {
            let (s, t) = (faces[f].v[e], faces[f].v[(e + 1) % 3]);
            for g in 0..faces.len() {
                if (0..3).any(|k| faces[g].v[k] == t && faces[g].v[(k + 1) % 3] == s) {
                    faces[f].next[e] = g;
                }
            }
        }
    }
}

/// The living faces as the result: merged and cleaned, or as triangles.
fn finish(points: &[DVec3], faces: &[Face], merge_coplanar: bool) -> Result<Hull, HullError> {
    let p = |i: usize| points[i];
    let alive: Vec<usize> = (0..faces.len()).filter(|&f| faces[f].alive).collect();
    let merged: Vec<Vec<usize>> = {
        let mut groups = UnionFind::new(faces.len());
        for &f in &alive {
            let [a, b, c] = faces[f].v.map(p);
            for n in faces[f].next {
                let opposite = faces[n]
                    .v
                    .iter()
                    .copied()
                    .find(|v| !faces[f].v.contains(v))
                    .ok_or(HullError::Inexact)?;
                if orient3d(a, b, c, p(opposite)) == 0.0 {
                    groups.union(f as u32, n as u32);
                }
            }
        }
        // Each group's outline: its edges whose neighbour is elsewhere,
        // chained from start to end.
        let mut outline: std::collections::BTreeMap<u32, Vec<(usize, usize)>> =
            std::collections::BTreeMap::new();
        for &f in &alive {
            let root = groups.find(f as u32);
            for e in 0..3 {
                if groups.find(faces[f].next[e] as u32) != root {
                    outline
                        .entry(root)
                        .or_default()
                        .push((faces[f].v[e], faces[f].v[(e + 1) % 3]));
                }
            }
        }
        outline
            .into_values()
            .map(|mut edges| {
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
                Ok(drop_straight_corners(points, ring))
            })
            .collect::<Result<_, _>>()?
    };
    let mut polygons: Vec<Vec<usize>> = if merge_coplanar {
        merged
    } else {
        // A convex polygon without straight corners fans from any corner:
        // from its lowest index, so the triangles are canonical.
        merged
            .into_iter()
            .flat_map(|mut ring| {
                let lowest = (0..ring.len()).min_by_key(|&k| ring[k]).expect("not empty");
                ring.rotate_left(lowest);
                (1..ring.len() - 1)
                    .map(move |k| vec![ring[0], ring[k], ring[k + 1]])
                    .collect::<Vec<_>>()
            })
            .collect()
    };

    for ring in &mut polygons {
        let lowest = (0..ring.len()).min_by_key(|&k| ring[k]).expect("not empty");
        ring.rotate_left(lowest);
    }
    polygons.sort();
    let mut vertices: Vec<usize> = polygons.iter().flatten().copied().collect();
    vertices.sort_unstable();
    vertices.dedup();
    Ok(Hull {
        vertices,
        faces: polygons,
    })
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
        assert_eq!(hull.faces.len(), 6);
        assert!(hull.faces.iter().all(|f| f.len() == 4));
        // Triangulated: 12 triangles on the same corners, once the
        // lattice's inner points are gone.
        let tris = convex_hull(&points, false).unwrap();
        assert!(tris.faces.iter().all(|f| f.len() == 3));
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
        for _ in 0..2000 {
            let v = DVec3::new(next() - 0.5, next() - 0.5, next() - 0.5);
            points.push(if next() < 0.5 { v.normalize() } else { v });
        }
        points.extend_from_within(..50);
        for k in 0..10 {
            points.push(DVec3::new(0.0, 0.0, -1.0 + 0.2 * k as f64));
        }
        let hull = convex_hull(&points, true).unwrap();
        for face in &hull.faces {
            let [a, b, c] = [face[0], face[1], face[2]].map(|i| points[i]);
            for (i, &q) in points.iter().enumerate() {
                assert!(
                    orient3d(a, b, c, q) >= 0.0,
                    "point {i} outside face {face:?}"
                );
            }
        }
        // Closed: every directed edge once, its reverse once.
        let mut edges: Vec<(usize, usize)> = hull
            .faces
            .iter()
            .flat_map(|f| (0..f.len()).map(move |k| (f[k], f[(k + 1) % f.len()])))
            .collect();
        edges.sort_unstable();
        let before = edges.len();
        edges.dedup();
        assert_eq!(edges.len(), before);
        assert!(edges
            .iter()
            .all(|&(s, t)| edges.binary_search(&(t, s)).is_ok()));
        // Euler: V − E + F = 2.
        let v = hull.vertices.len() as i64;
        let e = (edges.len() / 2) as i64;
        assert_eq!(v - e + hull.faces.len() as i64, 2);
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
