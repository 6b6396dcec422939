//! PN (curved point-normal, Bézier) triangles as a mesh smoother (thesis ch. 4, spec §2.7,
//! decision D10).
//!
//! Each input triangle with corner normals becomes a cubic Bézier triangle (thesis eq. 4.1) with
//! Vlachos et al.'s control points: corners = the vertices, two points per edge projected onto
//! the nearest corner's tangent plane, b111 = E + (E − V)/2. Shading normals are the quadratic
//! normal patch (Vlachos) or linear (the thesis's TES). The triangle is sampled in one of two
//! patterns:
//!
//! - [`Pattern::Uniform`] (default): the barycentric grid, n² triangles per input triangle;
//! - [`Pattern::Gl`]: OpenGL's concentric rings with equal spacing (§3.2 of the thesis), which
//!   is what the thesis's counts come from: T(n) = 6m² for n = 2m, (3n² − 1)/2 for odd n, so a
//!   12-triangle cube at level 5 gives 444.
//!
//! Watertightness: every edge's curve depends only on its two end vertices and their *geometry*
//! normals, and its sample points are computed once, from the lower vertex id, and shared by
//! both triangles (D8). Outer levels are functions of the edge alone. Where a vertex has several
//! normals (a crease), [`Creases::SmoothGeometry`] builds the geometry from the vertex's averaged
//! normal, so both sides of a crease edge still share one curve; the split normals stay for
//! shading, so vertices on a crease are duplicated with bit-identical positions and
//! [`PnMesh::point_of_vertex`] names the shared point.
//!
//! Canonical output: triangles are first rotated to start at their smallest vertex id and
//! sorted, so a mesh given in another triangle order (or with rotated triangles) produces the
//! same bytes.

use glam::DVec3;
use rayon::prelude::*;
use thiserror::Error;

use super::hash::edge_key;
use super::mesh::TriMesh;

/// Sampling pattern of each Bézier triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Pattern {
    /// Regular barycentric grid: n² triangles, (n + 1)(n + 2)/2 points per triangle.
    #[default]
    Uniform,
    /// OpenGL's ring pattern (triangles domain, equal spacing, integer levels).
    Gl,
}

/// Tessellation levels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Levels {
    /// inner = outer = n everywhere (the thesis's single user level).
    Fixed(u32),
    /// Per-edge outer level ⌈max(length / max_edge, angle between the end normals / max_angle)⌉
    /// clamped to [1, max_level] (a function of the edge alone); inner = the largest outer.
    Auto {
        /// Target edge length in model units.
        max_edge: f64,
        /// Target normal turn per segment, radians.
        max_angle: f64,
        /// Upper bound of every level.
        max_level: u32,
    },
}

/// Crease handling where a vertex has several corner normals.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Creases {
    /// Geometry from each vertex's averaged normal (D10); split normals kept for shading.
    #[default]
    SmoothGeometry,
    /// Crease edges stay straight (cubic with control points at the thirds).
    Keep,
}

/// Shading normals of the output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NormalMode {
    /// Vlachos's quadratic normal patch.
    #[default]
    Quadratic,
    /// Linear interpolation of the corner normals (the thesis's TES), normalised.
    Linear,
}

/// Options of [`pn_triangles`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PnOptions {
    /// Levels.
    pub levels: Levels,
    /// Sampling pattern.
    pub pattern: Pattern,
    /// Crease handling.
    pub creases: Creases,
    /// Shading normals.
    pub normals: NormalMode,
}

impl PnOptions {
    /// Fixed level n, uniform pattern, smooth geometry, quadratic normals.
    pub fn level(n: u32) -> Self {
        PnOptions {
            levels: Levels::Fixed(n),
            pattern: Pattern::Uniform,
            creases: Creases::SmoothGeometry,
            normals: NormalMode::Quadratic,
        }
    }
}

/// Largest level accepted.
pub const MAX_PN_LEVEL: u32 = 64;

/// Errors of the PN smoother.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PnError {
    /// `normals` must hold one entry per triangle.
    #[error("normals: expected {expected} entries (one per triangle), found {found}")]
    NormalCount { expected: usize, found: usize },
    /// A triangle refers to a vertex that does not exist.
    #[error("triangles[{triangle}][{corner}]: vertex {index} out of range ({vertices} vertices)")]
    IndexOutOfRange {
        triangle: usize,
        corner: usize,
        index: u32,
        vertices: usize,
    },
    /// A triangle repeats a vertex.
    #[error("triangles[{triangle}]: repeated vertex")]
    DegenerateTriangle { triangle: usize },
    /// A position is NaN, infinite or beyond 1e100 in magnitude.
    #[error("positions[{vertex}]: not finite or beyond 1e100")]
    PositionNotFinite { vertex: usize },
    /// A corner normal is NaN, infinite or zero.
    #[error("normals[{triangle}][{corner}]: not a usable normal (zero or not finite)")]
    BadNormal { triangle: usize, corner: usize },
    /// An option is out of range.
    #[error("option {name} = {value} is invalid: {reason}")]
    InvalidOption {
        name: &'static str,
        value: f64,
        reason: &'static str,
    },
    /// The output would exceed the caller's triangle cap (known exactly before allocating).
    #[error("PN smoothing needs {needed} triangles, more than the limit {limit}")]
    TriangleLimit { needed: u128, limit: usize },
    /// More vertices than u32 indices allow.
    #[error("PN smoothing needs {needed} vertices, more than u32 indices allow")]
    VertexLimit { needed: u128 },
}

/// Output of [`pn_triangles`].
#[derive(Debug, Clone, PartialEq)]
pub struct PnMesh {
    /// The smoothed mesh (its `uvs` are empty).
    pub mesh: TriMesh,
    /// For each vertex, the geometric point it sits on. Vertices split only by their shading
    /// normal (creases) share a point and have bit-identical positions; welding by this id gives
    /// the closed topology of a closed input.
    pub point_of_vertex: Vec<u32>,
    /// Number of distinct points.
    pub points: usize,
}

/// Where a pattern point lies on its triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Site {
    Corner(u8),
    /// Side s (corner s → s + 1), index i of the side's outer level.
    Edge(u8, u32),
    Interior,
}

/// A sampling pattern for one (inner, outer levels) combination.
#[derive(Debug, Clone)]
struct LocalPattern {
    /// Barycentric weights (corner 0, 1, 2) and site of each point.
    points: Vec<([f64; 3], Site)>,
    triangles: Vec<[u32; 3]>,
    interior: usize,
}

/// Exact triangle count of the GL ring pattern (spec §2.7.2).
pub fn gl_triangle_count(inner: u32, outer: [u32; 3]) -> u128 {
    let mut n = inner.max(1) as u128;
    let o: u128 = outer.iter().map(|&x| x.max(1) as u128).sum();
    if n == 1 {
        if outer.iter().all(|&x| x <= 1) {
            return 1;
        }
        n = 2;
    }
    // R(k) = 3k + 3(k − 2) + R(k − 2), R(0) = 0, R(1) = 1, for the rings inside ring 0.
    let mut r = 0u128;
    let mut k = n - 2;
    loop {
        match k {
            0 => break,
            1 => {
                r += 1;
                break;
            }
            _ => {
                r += 3 * k + 3 * (k - 2);
                k -= 2;
            }
        }
    }
    o + 3 * (n - 2) + r
}

fn effective_inner(inner: u32, outer: [u32; 3], pattern: Pattern) -> u32 {
    match pattern {
        Pattern::Gl => {
            if inner <= 1 && outer.iter().any(|&x| x > 1) {
                2
            } else {
                inner.max(1)
            }
        }
        Pattern::Uniform => {
            if outer.iter().all(|&o| o == inner) {
                inner.max(1)
            } else {
                inner.max(3)
            }
        }
    }
}

/// Exact triangle count of one input triangle.
fn pattern_count(inner: u32, outer: [u32; 3], pattern: Pattern) -> u128 {
    let n = effective_inner(inner, outer, pattern) as u128;
    match pattern {
        Pattern::Gl => gl_triangle_count(inner, outer),
        Pattern::Uniform => {
            if outer.iter().all(|&o| o as u128 == n) {
                n * n
            } else {
                // inner grid of level n − 3, plus three zipped strips
                let inner_tris = if n >= 3 { (n - 3) * (n - 3) } else { 0 };
                inner_tris + outer.iter().map(|&o| o as u128 + (n - 3)).sum::<u128>()
            }
        }
    }
}

/// Zips an outer chain (params ascending in [0, 1]) and an inner chain; pushes triangles of
/// local ids, oriented counter-clockwise in the (w1, w2) plane.
fn zip(outer: &[(u32, f64)], inner: &[(u32, f64)], coords: &[[f64; 3]], out: &mut Vec<[u32; 3]>) {
    let (na, nb) = (outer.len() - 1, inner.len() - 1);
    let (mut k, mut l) = (0, 0);
    let mut emit = |t: [u32; 3]| {
        let p = t.map(|i| coords[i as usize]);
        let area =
            (p[1][1] - p[0][1]) * (p[2][2] - p[0][2]) - (p[1][2] - p[0][2]) * (p[2][1] - p[0][1]);
        out.push(if area >= 0.0 { t } else { [t[0], t[2], t[1]] });
    };
    while k < na || l < nb {
        let advance_outer = l == nb || (k < na && outer[k + 1].1 <= inner[l + 1].1);
        if advance_outer {
            emit([outer[k].0, outer[k + 1].0, inner[l].0]);
            k += 1;
        } else {
            emit([outer[k].0, inner[l + 1].0, inner[l].0]);
            l += 1;
        }
    }
}

impl LocalPattern {
    fn new(inner: u32, outer: [u32; 3], pattern: Pattern) -> Self {
        match pattern {
            Pattern::Uniform => Self::uniform(effective_inner(inner, outer, pattern), outer),
            Pattern::Gl => Self::gl(inner, outer),
        }
    }

    fn push(&mut self, w: [f64; 3], site: Site) -> u32 {
        if site == Site::Interior {
            self.interior += 1;
        }
        self.points.push((w, site));
        (self.points.len() - 1) as u32
    }

    /// Corner and outer-edge points: ids of the chain along side s (corner s → s + 1).
    fn outer_ring(&mut self, outer: [u32; 3]) -> [Vec<(u32, f64)>; 3] {
        let corners: Vec<u32> = (0..3)
            .map(|c| {
                let mut w = [0.0; 3];
                w[c] = 1.0;
                self.push(w, Site::Corner(c as u8))
            })
            .collect();
        let mut chains: [Vec<(u32, f64)>; 3] = Default::default();
        for s in 0..3 {
            let o = outer[s].max(1);
            let mut chain = vec![(corners[s], 0.0)];
            for i in 1..o {
                let t = i as f64 / o as f64;
                let mut w = [0.0; 3];
                w[s] = 1.0 - t;
                w[(s + 1) % 3] = t;
                chain.push((self.push(w, Site::Edge(s as u8, i)), t));
            }
            chain.push((corners[(s + 1) % 3], 1.0));
            chains[s] = chain;
        }
        chains
    }

    fn uniform(n: u32, outer: [u32; 3]) -> Self {
        let mut pat = LocalPattern {
            points: Vec::new(),
            triangles: Vec::new(),
            interior: 0,
        };
        let nf = n as f64;
        if outer.iter().all(|&o| o == n) {
            // Full grid; corners and edges first so that sites are known.
            let chains = pat.outer_ring(outer);
            let n = n as usize;
            // id of grid point (a, b): weight a/n on corner 1, b/n on corner 2
            let mut id = vec![u32::MAX; (n + 1) * (n + 1)];
            let at = |a: usize, b: usize| a * (n + 1) + b;
            for (i, &(pid, _)) in chains[0].iter().enumerate() {
                id[at(i, 0)] = pid; // side 0: corner 0 → 1
            }
            for (i, &(pid, _)) in chains[1].iter().enumerate() {
                id[at(n - i, i)] = pid; // side 1: corner 1 → 2
            }
            for (i, &(pid, _)) in chains[2].iter().enumerate() {
                id[at(0, n - i)] = pid; // side 2: corner 2 → 0
            }
            for a in 1..n {
                for b in 1..n - a {
                    let w = [(n - a - b) as f64 / nf, a as f64 / nf, b as f64 / nf];
                    id[at(a, b)] = pat.push(w, Site::Interior);
                }
            }
            for a in 0..n {
                for b in 0..n - a {
                    pat.triangles
                        .push([id[at(a, b)], id[at(a + 1, b)], id[at(a, b + 1)]]);
                    if a + b + 2 <= n {
                        pat.triangles.push([
                            id[at(a + 1, b)],
                            id[at(a + 1, b + 1)],
                            id[at(a, b + 1)],
                        ]);
                    }
                }
            }
            return pat;
        }
        // Outer levels differ: interior grid of points with every weight ≥ 1/n, zipped to the
        // outer polylines.
        let chains = pat.outer_ring(outer);
        let n = n as usize;
        let mut id = vec![u32::MAX; (n + 1) * (n + 1)];
        let at = |a: usize, b: usize| a * (n + 1) + b;
        for a in 1..n {
            for b in 1..n - a {
                let w = [(n - a - b) as f64 / nf, a as f64 / nf, b as f64 / nf];
                id[at(a, b)] = pat.push(w, Site::Interior);
            }
        }
        for a in 1..n.saturating_sub(2) {
            for b in 1..n - 1 - a {
                pat.triangles
                    .push([id[at(a, b)], id[at(a + 1, b)], id[at(a, b + 1)]]);
                if a + b + 3 <= n {
                    pat.triangles
                        .push([id[at(a + 1, b)], id[at(a + 1, b + 1)], id[at(a, b + 1)]]);
                }
            }
        }
        let coords: Vec<[f64; 3]> = pat.points.iter().map(|p| p.0).collect();
        let inner_chain = |s: usize| -> Vec<(u32, f64)> {
            (1..=n - 2)
                .map(|i| match s {
                    0 => (id[at(i, 1)], (i as f64 + 0.5) / nf),
                    1 => (id[at(n - 1 - i, i)], (i as f64 + 0.5) / nf),
                    _ => (id[at(1, n - 1 - i)], (i as f64 + 0.5) / nf),
                })
                .collect()
        };
        let mut tris = Vec::new();
        for (s, chain) in chains.iter().enumerate() {
            zip(chain, &inner_chain(s), &coords, &mut tris);
        }
        pat.triangles.extend(tris);
        pat
    }

    fn gl(inner: u32, outer: [u32; 3]) -> Self {
        let mut pat = LocalPattern {
            points: Vec::new(),
            triangles: Vec::new(),
            interior: 0,
        };
        if inner <= 1 && outer.iter().all(|&o| o <= 1) {
            let _ = pat.outer_ring([1, 1, 1]);
            pat.triangles.push([0, 1, 2]);
            return pat;
        }
        let n = effective_inner(inner, outer, Pattern::Gl) as usize;
        let nf = n as f64;
        let mut ring = pat.outer_ring(outer);
        let mut k = 0usize;
        loop {
            let m = n - 2 * k; // segments per side of ring k (its inner-level count)
            if m == 1 {
                // innermost triangle (odd n): ring k's three corners
                pat.triangles
                    .push([ring[0][0].0, ring[1][0].0, ring[2][0].0]);
                break;
            }
            let coords_next: Vec<(u32, f64)>;
            let mut next: [Vec<(u32, f64)>; 3] = Default::default();
            if m == 2 {
                let c = pat.push([1.0 / 3.0; 3], Site::Interior);
                coords_next = vec![(c, 0.5)];
                for chain in next.iter_mut() {
                    *chain = coords_next.clone();
                }
            } else {
                // ring k + 1 corners: weights (1 − 2t, t, t) with t = 2(k + 1)/(3n)
                let t = 2.0 * (k + 1) as f64 / (3.0 * nf);
                let corner = |c: usize| {
                    let mut w = [t; 3];
                    w[c] = 1.0 - 2.0 * t;
                    w
                };
                let mi = m - 2;
                let mut corner_ids = [0u32; 3];
                for (c, slot) in corner_ids.iter_mut().enumerate() {
                    *slot = pat.push(corner(c), Site::Interior);
                }
                for s in 0..3 {
                    let (a, b) = (corner(s), corner((s + 1) % 3));
                    let mut chain = vec![(corner_ids[s], 1.0 / m as f64)];
                    for i in 1..mi {
                        let f = i as f64 / mi as f64;
                        let w = [0, 1, 2].map(|j| a[j] + (b[j] - a[j]) * f);
                        chain.push((pat.push(w, Site::Interior), (1 + i) as f64 / m as f64));
                    }
                    chain.push((corner_ids[(s + 1) % 3], (m - 1) as f64 / m as f64));
                    next[s] = chain;
                }
            }
            let coords: Vec<[f64; 3]> = pat.points.iter().map(|p| p.0).collect();
            let mut tris = Vec::new();
            for s in 0..3 {
                zip(&ring[s], &next[s], &coords, &mut tris);
            }
            pat.triangles.extend(tris);
            if m == 2 {
                break;
            }
            // ring k + 1's own chains use params i / (m − 2) for the next zip
            for chain in next.iter_mut() {
                let len = chain.len() - 1;
                for (i, p) in chain.iter_mut().enumerate() {
                    p.1 = i as f64 / len as f64;
                }
            }
            ring = next;
            k += 1;
        }
        pat
    }
}

/// Vlachos control points and normal coefficients of one triangle.
struct Patch {
    b: [DVec3; 10], // b300 b030 b003 b210 b120 b021 b012 b102 b201 b111
    n: [DVec3; 6],  // n200 n020 n002 n110 n011 n101
    linear: bool,
    face: DVec3,
}

impl Patch {
    fn point(&self, w: [f64; 3]) -> DVec3 {
        let [u, v, x] = w; // weights of corners 0, 1, 2
        let b = &self.b;
        b[0] * (u * u * u)
            + b[1] * (v * v * v)
            + b[2] * (x * x * x)
            + b[3] * (3.0 * u * u * v)
            + b[4] * (3.0 * u * v * v)
            + b[5] * (3.0 * v * v * x)
            + b[6] * (3.0 * v * x * x)
            + b[7] * (3.0 * u * x * x)
            + b[8] * (3.0 * u * u * x)
            + b[9] * (6.0 * u * v * x)
    }

    fn normal(&self, w: [f64; 3]) -> DVec3 {
        let [u, v, x] = w;
        let n = &self.n;
        let raw = if self.linear {
            n[0] * u + n[1] * v + n[2] * x
        } else {
            n[0] * (u * u)
                + n[1] * (v * v)
                + n[2] * (x * x)
                + n[3] * (u * v)
                + n[4] * (v * x)
                + n[5] * (x * u)
        };
        unit_or(raw, self.face)
    }
}

#[inline]
fn unit_or(v: DVec3, fallback: DVec3) -> DVec3 {
    let l = v.length();
    if l > 0.0 && l.is_finite() {
        v / l
    } else {
        fallback
    }
}

/// Edge control point near `p` toward `q` with normal `n` (None: straight).
#[inline]
fn edge_control(p: DVec3, q: DVec3, n: Option<DVec3>) -> DVec3 {
    match n {
        Some(n) => (2.0 * p + q - (q - p).dot(n) * n) / 3.0,
        None => (2.0 * p + q) / 3.0,
    }
}

/// Vlachos's mid-edge normal coefficient.
#[inline]
fn mid_normal(p: DVec3, q: DVec3, np: DVec3, nq: DVec3) -> DVec3 {
    let d = q - p;
    let l2 = d.dot(d);
    let v = if l2 > 0.0 {
        2.0 * d.dot(np + nq) / l2
    } else {
        0.0
    };
    unit_or(np + nq - v * d, unit_or(np + nq, np))
}

/// Edge data shared by its triangles.
struct EdgeInfo {
    key: u64,
    level: u32,
    crease: bool,
    /// Offsets into the output vertices: one block of (level − 1) vertices per normal variant.
    first_vertex: u32,
    /// Normal variants: (corner normal at the lower end, at the higher end), sorted.
    variants: Vec<([u64; 3], [u64; 3])>,
    first_point: u32,
}

fn bits(v: DVec3) -> [u64; 3] {
    [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()]
}

fn from_bits(b: [u64; 3]) -> DVec3 {
    DVec3::new(
        f64::from_bits(b[0]),
        f64::from_bits(b[1]),
        f64::from_bits(b[2]),
    )
}

/// Splits `data` into consecutive chunks of the given lengths.
fn split_lengths<T>(mut data: &mut [T], lengths: impl Iterator<Item = usize>) -> Vec<&mut [T]> {
    let mut out = Vec::new();
    for len in lengths {
        let (head, tail) = data.split_at_mut(len);
        out.push(head);
        data = tail;
    }
    out
}

/// PN-smooths a triangle mesh. `normals[t][k]` is the normal at corner k of triangle t (the
/// caller computes them; they are normalised here). Refuses to produce more than
/// `max_triangles` triangles, decided exactly before allocating the output.
pub fn pn_triangles(
    positions: &[[f64; 3]],
    triangles: &[[u32; 3]],
    normals: &[[[f64; 3]; 3]],
    options: &PnOptions,
    max_triangles: usize,
) -> Result<PnMesh, PnError> {
    // ---- validation
    if normals.len() != triangles.len() {
        return Err(PnError::NormalCount {
            expected: triangles.len(),
            found: normals.len(),
        });
    }
    for (v, p) in positions.iter().enumerate() {
        if p.iter()
            .any(|x| !(x.is_finite() && x.abs() <= super::error::MAX_COORD))
        {
            return Err(PnError::PositionNotFinite { vertex: v });
        }
    }
    let mut unit_normals = Vec::with_capacity(triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        for (corner, &index) in tri.iter().enumerate() {
            if index as usize >= positions.len() {
                return Err(PnError::IndexOutOfRange {
                    triangle: t,
                    corner,
                    index,
                    vertices: positions.len(),
                });
            }
        }
        if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            return Err(PnError::DegenerateTriangle { triangle: t });
        }
        let mut ns = [DVec3::ZERO; 3];
        for corner in 0..3 {
            let n = DVec3::from_array(normals[t][corner]);
            let l = n.length();
            if !(l.is_finite() && l > 0.0) {
                return Err(PnError::BadNormal {
                    triangle: t,
                    corner,
                });
            }
            ns[corner] = n / l;
        }
        unit_normals.push(ns);
    }
    match options.levels {
        Levels::Fixed(n) => {
            if n == 0 || n > MAX_PN_LEVEL {
                return Err(PnError::InvalidOption {
                    name: "level",
                    value: f64::from(n),
                    reason: "must be in 1..=64 (MAX_PN_LEVEL)",
                });
            }
        }
        Levels::Auto {
            max_edge,
            max_angle,
            max_level,
        } => {
            for (name, v) in [("max_edge", max_edge), ("max_angle", max_angle)] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(PnError::InvalidOption {
                        name,
                        value: v,
                        reason: "must be positive and finite",
                    });
                }
            }
            if max_level == 0 || max_level > MAX_PN_LEVEL {
                return Err(PnError::InvalidOption {
                    name: "max_level",
                    value: f64::from(max_level),
                    reason: "must be in 1..=64 (MAX_PN_LEVEL)",
                });
            }
        }
    }
    let pos: Vec<DVec3> = positions.iter().map(|p| DVec3::from_array(*p)).collect();

    // ---- canonical triangle order: rotate to the smallest id, sort by (ids, normal bits)
    let mut order: Vec<(usize, usize)> = (0..triangles.len())
        .map(|t| {
            let tri = triangles[t];
            let r = (0..3).min_by_key(|&k| tri[k]).unwrap_or(0);
            (t, r)
        })
        .collect();
    let canon = |&(t, r): &(usize, usize)| {
        let tri = triangles[t];
        let ids = [tri[r], tri[(r + 1) % 3], tri[(r + 2) % 3]];
        let ns = [0, 1, 2].map(|k| bits(unit_normals[t][(r + k) % 3]));
        (ids, ns)
    };
    order.sort_by_cached_key(canon);
    let tris: Vec<[u32; 3]> = order.iter().map(|o| canon(o).0).collect();
    let corner_n: Vec<[DVec3; 3]> = order
        .iter()
        .map(|&(t, r)| [0, 1, 2].map(|k| unit_normals[t][(r + k) % 3]))
        .collect();

    // ---- vertex normal variants (sorted bit patterns) and geometry normals
    let nv = pos.len();
    let mut corner_list: Vec<(u32, [u64; 3])> = Vec::with_capacity(tris.len() * 3);
    for (t, tri) in tris.iter().enumerate() {
        for k in 0..3 {
            corner_list.push((tri[k], bits(corner_n[t][k])));
        }
    }
    corner_list.sort_unstable();
    let mut vertex_variants: Vec<Vec<[u64; 3]>> = vec![Vec::new(); nv];
    let mut geometry_n = vec![DVec3::Z; nv];
    {
        let mut i = 0;
        while i < corner_list.len() {
            let v = corner_list[i].0 as usize;
            let mut j = i;
            let mut sum = DVec3::ZERO;
            while j < corner_list.len() && corner_list[j].0 as usize == v {
                let b = corner_list[j].1;
                if vertex_variants[v].last() != Some(&b) {
                    vertex_variants[v].push(b);
                }
                sum += from_bits(b);
                j += 1;
            }
            geometry_n[v] = if vertex_variants[v].len() == 1 {
                from_bits(vertex_variants[v][0])
            } else {
                unit_or(sum, from_bits(vertex_variants[v][0]))
            };
            i = j;
        }
    }

    // ---- edges (sorted keys), creases, levels
    let mut directed: Vec<(u64, u32)> = Vec::with_capacity(tris.len() * 3);
    for (t, tri) in tris.iter().enumerate() {
        for s in 0..3 {
            directed.push((edge_key(tri[s], tri[(s + 1) % 3]), (t * 3 + s) as u32));
        }
    }
    directed.sort_unstable();
    let mut edges: Vec<EdgeInfo> = Vec::new();
    let mut tri_edge = vec![[0u32; 3]; tris.len()];
    {
        let mut i = 0;
        while i < directed.len() {
            let key = directed[i].0;
            let mut j = i;
            let mut variants = Vec::new();
            while j < directed.len() && directed[j].0 == key {
                let code = directed[j].1 as usize;
                let (t, s) = (code / 3, code % 3);
                tri_edge[t][s] = edges.len() as u32;
                let (a, b) = (tris[t][s], tris[t][(s + 1) % 3]);
                let (na, nb) = (corner_n[t][s], corner_n[t][(s + 1) % 3]);
                variants.push(if a < b {
                    (bits(na), bits(nb))
                } else {
                    (bits(nb), bits(na))
                });
                j += 1;
            }
            let incident = j - i;
            variants.sort_unstable();
            variants.dedup();
            let crease = variants.len() > 1 || incident > 2;
            let lo = (key >> 32) as usize;
            let hi = (key & 0xffff_ffff) as usize;
            let level = match options.levels {
                Levels::Fixed(n) => n,
                Levels::Auto {
                    max_edge,
                    max_angle,
                    max_level,
                } => {
                    let len = (pos[hi] - pos[lo]).length();
                    let cos = geometry_n[lo].dot(geometry_n[hi]).clamp(-1.0, 1.0);
                    let angle = libm::acos(cos);
                    let by_len = (len / max_edge).ceil();
                    let by_angle = (angle / max_angle).ceil();
                    let l = by_len.max(by_angle);
                    if l.is_finite() {
                        (l as u64).clamp(1, u64::from(max_level)) as u32
                    } else {
                        max_level
                    }
                }
            };
            edges.push(EdgeInfo {
                key,
                level,
                crease,
                first_vertex: 0,
                variants,
                first_point: 0,
            });
            i = j;
        }
    }

    // ---- per-triangle levels and patterns
    let tri_levels: Vec<(u32, [u32; 3])> = (0..tris.len())
        .map(|t| {
            let outer = tri_edge[t].map(|e| edges[e as usize].level);
            let inner = match options.levels {
                Levels::Fixed(n) => n,
                Levels::Auto { .. } => outer.iter().copied().max().unwrap_or(1),
            };
            (inner, outer)
        })
        .collect();
    let mut needed: u128 = 0;
    for &(inner, outer) in &tri_levels {
        needed += pattern_count(inner, outer, options.pattern);
    }
    if needed > max_triangles as u128 {
        return Err(PnError::TriangleLimit {
            needed,
            limit: max_triangles,
        });
    }
    let mut patterns: Vec<((u32, [u32; 3]), LocalPattern)> = Vec::new();
    let mut pattern_of = Vec::with_capacity(tris.len());
    for &lv in &tri_levels {
        let idx = match patterns.iter().position(|(k, _)| *k == lv) {
            Some(i) => i,
            None => {
                patterns.push((lv, LocalPattern::new(lv.0, lv.1, options.pattern)));
                patterns.len() - 1
            }
        };
        pattern_of.push(idx);
    }

    // ---- output layout: input-vertex variants, edge blocks, triangle interiors
    let mut next_vertex: u128 = 0;
    let mut next_point: u128 = 0;
    let mut vertex_first = vec![0u32; nv];
    let mut vertex_point = vec![u32::MAX; nv];
    for v in 0..nv {
        vertex_first[v] = next_vertex as u32;
        if !vertex_variants[v].is_empty() {
            vertex_point[v] = next_point as u32;
            next_point += 1;
        }
        next_vertex += vertex_variants[v].len() as u128;
    }
    for e in edges.iter_mut() {
        e.first_vertex = next_vertex.min(u32::MAX as u128) as u32;
        e.first_point = next_point.min(u32::MAX as u128) as u32;
        let inner_pts = u128::from(e.level - 1);
        next_vertex += inner_pts * e.variants.len() as u128;
        next_point += inner_pts;
    }
    let mut tri_first = Vec::with_capacity(tris.len());
    let mut tri_first_point = Vec::with_capacity(tris.len());
    for &p in &pattern_of {
        tri_first.push(next_vertex.min(u32::MAX as u128) as u32);
        tri_first_point.push(next_point.min(u32::MAX as u128) as u32);
        next_vertex += patterns[p].1.interior as u128;
        next_point += patterns[p].1.interior as u128;
    }
    if next_vertex > u32::MAX as u128 {
        return Err(PnError::VertexLimit {
            needed: next_vertex,
        });
    }
    let total_vertices = next_vertex as usize;
    let mut out_pos = vec![[0.0; 3]; total_vertices];
    let mut out_nrm = vec![[0.0; 3]; total_vertices];
    let mut out_point = vec![0u32; total_vertices];
    let mut out_tris = vec![[0u32; 3]; needed as usize];

    // Geometry normal of vertex `v` on edge `e` (None: straight, for kept creases).
    let geom = |v: u32, e: &EdgeInfo, own: DVec3| -> Option<DVec3> {
        match options.creases {
            Creases::SmoothGeometry => Some(geometry_n[v as usize]),
            Creases::Keep => {
                if e.crease {
                    None
                } else {
                    Some(own)
                }
            }
        }
    };

    // ---- input vertices
    for v in 0..nv {
        for (k, b) in vertex_variants[v].iter().enumerate() {
            let i = vertex_first[v] as usize + k;
            out_pos[i] = positions[v];
            out_nrm[i] = from_bits(*b).to_array();
            out_point[i] = vertex_point[v];
        }
    }

    // ---- edge points, from the lower id, once per edge and normal variant (parallel)
    {
        let lens: Vec<usize> = edges
            .iter()
            .map(|e| (e.level as usize - 1) * e.variants.len())
            .collect();
        let start = vertex_first
            .last()
            .map_or(0, |&f| f as usize + vertex_variants[nv - 1].len());
        let (_, rest_p) = out_pos.split_at_mut(start);
        let (_, rest_n) = out_nrm.split_at_mut(start);
        let (_, rest_pt) = out_point.split_at_mut(start);
        let pc = split_lengths(rest_p, lens.iter().copied());
        let nc = split_lengths(rest_n, lens.iter().copied());
        let ptc = split_lengths(rest_pt, lens.iter().copied());
        edges
            .par_iter()
            .zip(
                pc.into_par_iter()
                    .zip(nc.into_par_iter().zip(ptc.into_par_iter())),
            )
            .for_each(|(e, (pc, (nc, ptc)))| {
                let (lo, hi) = ((e.key >> 32) as u32, (e.key & 0xffff_ffff) as u32);
                let (p, q) = (pos[lo as usize], pos[hi as usize]);
                let m = e.level as usize;
                // geometry: the same for every variant of this edge
                let (nl0, nh0) = (from_bits(e.variants[0].0), from_bits(e.variants[0].1));
                let b1 = edge_control(p, q, geom(lo, e, nl0));
                let b2 = edge_control(q, p, geom(hi, e, nh0));
                for (vi, &(nl, nh)) in e.variants.iter().enumerate() {
                    let (nl, nh) = (from_bits(nl), from_bits(nh));
                    let nm = mid_normal(p, q, nl, nh);
                    for i in 1..m {
                        let t = i as f64 / m as f64;
                        let s = 1.0 - t;
                        let x = p * (s * s * s)
                            + b1 * (3.0 * s * s * t)
                            + b2 * (3.0 * s * t * t)
                            + q * (t * t * t);
                        let raw = match options.normals {
                            NormalMode::Quadratic => nl * (s * s) + nh * (t * t) + nm * (s * t),
                            NormalMode::Linear => nl * s + nh * t,
                        };
                        let slot = vi * (m - 1) + i - 1;
                        pc[slot] = x.to_array();
                        nc[slot] = unit_or(raw, unit_or(nl + nh, nl)).to_array();
                        ptc[slot] = e.first_point + (i - 1) as u32;
                    }
                }
            });
    }

    // ---- triangles: interior points and connectivity (parallel)
    {
        let interior_start = tri_first.first().copied().unwrap_or(total_vertices as u32) as usize;
        let lens: Vec<usize> = pattern_of.iter().map(|&p| patterns[p].1.interior).collect();
        let tri_lens: Vec<usize> = pattern_of
            .iter()
            .map(|&p| patterns[p].1.triangles.len())
            .collect();
        let (_, rest_p) = out_pos.split_at_mut(interior_start);
        let (_, rest_n) = out_nrm.split_at_mut(interior_start);
        let (_, rest_pt) = out_point.split_at_mut(interior_start);
        let pc = split_lengths(rest_p, lens.iter().copied());
        let nc = split_lengths(rest_n, lens.iter().copied());
        let ptc = split_lengths(rest_pt, lens.iter().copied());
        let tc = split_lengths(&mut out_tris[..], tri_lens.iter().copied());
        pc.into_par_iter()
            .zip(
                nc.into_par_iter()
                    .zip(ptc.into_par_iter().zip(tc.into_par_iter())),
            )
            .enumerate()
            .for_each(|(t, (pc, (nc, (ptc, tc))))| {
                let tri = tris[t];
                let ns = corner_n[t];
                let pat = &patterns[pattern_of[t]].1;
                let p = tri.map(|v| pos[v as usize]);
                // control points from the shared edge data
                let ctrl = |s: usize| -> (DVec3, DVec3) {
                    let e = &edges[tri_edge[t][s] as usize];
                    let (a, b) = (tri[s], tri[(s + 1) % 3]);
                    let (pa, pb) = (p[s], p[(s + 1) % 3]);
                    (
                        edge_control(pa, pb, geom(a, e, ns[s])),
                        edge_control(pb, pa, geom(b, e, ns[(s + 1) % 3])),
                    )
                };
                let (b210, b120) = ctrl(0);
                let (b021, b012) = ctrl(1);
                let (b102, b201) = ctrl(2);
                let ee = (b210 + b120 + b021 + b012 + b102 + b201) / 6.0;
                let vv = (p[0] + p[1] + p[2]) / 3.0;
                let face = unit_or((p[1] - p[0]).cross(p[2] - p[0]), ns[0]);
                let patch = Patch {
                    b: [
                        p[0],
                        p[1],
                        p[2],
                        b210,
                        b120,
                        b021,
                        b012,
                        b102,
                        b201,
                        ee + (ee - vv) * 0.5,
                    ],
                    n: [
                        ns[0],
                        ns[1],
                        ns[2],
                        mid_normal(p[0], p[1], ns[0], ns[1]),
                        mid_normal(p[1], p[2], ns[1], ns[2]),
                        mid_normal(p[2], p[0], ns[2], ns[0]),
                    ],
                    linear: options.normals == NormalMode::Linear,
                    face,
                };
                let mut map = Vec::with_capacity(pat.points.len());
                let mut next = 0usize;
                for (w, site) in &pat.points {
                    let id = match *site {
                        Site::Corner(c) => {
                            let v = tri[c as usize] as usize;
                            let b = bits(ns[c as usize]);
                            let k = vertex_variants[v].binary_search(&b).unwrap_or(0);
                            vertex_first[v] + k as u32
                        }
                        Site::Edge(s, i) => {
                            let s = s as usize;
                            let e = &edges[tri_edge[t][s] as usize];
                            let (a, b) = (tri[s], tri[(s + 1) % 3]);
                            let m = e.level;
                            let (idx, var) = if a < b {
                                (i, (bits(ns[s]), bits(ns[(s + 1) % 3])))
                            } else {
                                (m - i, (bits(ns[(s + 1) % 3]), bits(ns[s])))
                            };
                            let vi = e.variants.binary_search(&var).unwrap_or(0);
                            e.first_vertex + vi as u32 * (m - 1) + idx - 1
                        }
                        Site::Interior => {
                            pc[next] = patch.point(*w).to_array();
                            nc[next] = patch.normal(*w).to_array();
                            ptc[next] = tri_first_point[t] + next as u32;
                            next += 1;
                            tri_first[t] + next as u32 - 1
                        }
                    };
                    map.push(id);
                }
                for (dst, src) in tc.iter_mut().zip(&pat.triangles) {
                    *dst = src.map(|l| map[l as usize]);
                }
            });
    }
    // Unreferenced input vertices would have no variant; they produce no output vertex.
    Ok(PnMesh {
        mesh: TriMesh {
            positions: out_pos,
            uvs: Vec::new(),
            normals: out_nrm,
            triangles: out_tris,
        },
        point_of_vertex: out_point,
        points: next_point as usize,
    })
}
