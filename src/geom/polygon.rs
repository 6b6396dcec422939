//! Pure polygon geometry on `glam::DVec3` rings: Newell normals, vector areas, plane bases and a
//! robust, deterministic triangulator.
//!
//! A *ring* is a slice of points in order; the closing edge from the last point back to the first
//! is implied. Rings may be non-convex, non-planar, self-intersecting or degenerate.
//!
//! Every computation works relative to the ring's bounding-box centre, and rings of extreme size
//! (extent beyond 1e±100) are additionally rescaled, so huge (1e300) and tiny (1e-300)
//! coordinates behave like unit-sized ones and nothing overflows on the way. Degeneracy
//! thresholds are relative to the ring's extent.
//!
//! [`triangulate`] (and [`triangulate_with_normal`]) always returns exactly `n - 2` triangles for
//! a ring of `n >= 3` points, wound like the ring (counter-clockwise around the Newell normal).
//! It tries, in order:
//!
//! 1. `n == 3`: the ring itself.
//! 2. `n == 4`: the shorter diagonal (ties pick 0-2) if both halves face along the normal, else
//!    the other diagonal if it does.
//! 3. Strictly convex rings (every turn positive, winding once): a fan from vertex 0.
//! 4. A constrained Delaunay triangulation (spade) of the ring projected onto its Newell plane,
//!    keeping the faces inside by edge-crossing parity.
//! 5. If spade cannot produce exactly `n - 2` triangles (self-intersections, repeated points,
//!    touching edges), ear clipping in the projected plane; if that gets stuck, a fan over the
//!    remaining vertices.
//!
//! Rings with non-finite coordinates or a (near) zero Newell normal (all points collinear or
//! coincident, symmetric bow-ties) get a fan from vertex 0: no orientation exists to honour.

use glam::{DVec2, DVec3};
use spade::{ConstrainedDelaunayTriangulation, HasPosition, Point2, Triangulation};

/// A Newell normal shorter than this times the squared extent, per vertex, counts as zero.
const DEGENERATE_PER_VERTEX: f64 = 1e-14;
/// Twice the area, in the scale-free frame, below which an ear counts as a zero-area sliver.
const SLIVER: f64 = 1e-14;
/// Projected coordinates smaller than this are flushed to zero (spade rejects magnitudes below
/// about 1.8e-43; in the scale-free frame such values are rounding noise).
const FLUSH: f64 = 1e-30;

/// Unnormalized Newell normal (twice the vector area) of a ring.
///
/// Zero for rings with fewer than three points or non-finite coordinates; (nearly) zero for
/// degenerate rings. Infinite only if the true vector area overflows `f64`.
pub fn newell_normal(points: &[DVec3]) -> DVec3 {
    match Frame::new(points) {
        Some(frame) if points.len() >= 3 => frame.normal(points) * frame.area_scale(),
        _ => DVec3::ZERO,
    }
}

/// Unit Newell normal, or `None` when the ring is degenerate: fewer than three points,
/// non-finite coordinates, or a vector area that is tiny relative to the ring's size.
pub fn unit_normal(points: &[DVec3]) -> Option<DVec3> {
    let frame = Frame::new(points)?;
    frame.unit_normal(points)
}

/// [`unit_normal`] of a ring of fixed size: the same arithmetic in the same
/// order (so the same bits), unrolled. Kernel operators make millions of
/// triangles and quads, and each gets its normal when it is made.
#[inline]
pub fn unit_normal_of<const N: usize>(points: &[DVec3; N]) -> Option<DVec3> {
    if N < 3 {
        return unit_normal(points);
    }
    let (mut lo, mut hi) = (points[0], points[0]);
    let mut finite = true;
    for p in points {
        finite &= p.is_finite();
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if !finite {
        return None;
    }
    let half = (hi * 0.5 - lo * 0.5).max_element();
    if !(1e-100..=1e100).contains(&half) {
        // Extreme extents take the rescaled frame.
        return unit_normal(points);
    }
    let centre = lo * 0.5 + hi * 0.5;
    let origin = points[0] - centre;
    let mut sum = DVec3::ZERO;
    let mut prev = (points[1] - centre) - origin;
    for p in &points[2..] {
        let cur = (*p - centre) - origin;
        sum += prev.cross(cur);
        prev = cur;
    }
    let len = sum.length();
    let unit = 2.0 * half;
    let threshold = DEGENERATE_PER_VERTEX * N as f64 * unit * unit;
    (len.is_finite() && len > threshold).then(|| sum / len)
}

/// Magnitude of the vector area (`|newell_normal| / 2`); zero for degenerate rings.
pub fn area(points: &[DVec3]) -> f64 {
    match Frame::new(points) {
        Some(frame) if points.len() >= 3 => {
            frame.normal(points).length() * 0.5 * frame.area_scale()
        }
        _ => 0.0,
    }
}

/// Average of the ring's vertices (zero for an empty ring).
pub fn centroid(points: &[DVec3]) -> DVec3 {
    if points.is_empty() {
        return DVec3::ZERO;
    }
    let inv = 1.0 / points.len() as f64;
    points.iter().fold(DVec3::ZERO, |acc, p| acc + *p * inv)
}

/// Deterministic orthonormal basis `(u, v)` of the plane perpendicular to `normal`, with
/// `u × v` pointing along `normal`. A zero or non-finite `normal` yields `(X, Y)`.
pub fn plane_basis(normal: DVec3) -> (DVec3, DVec3) {
    // Scale by the largest component first so tiny and huge normals normalize exactly as well.
    let big = normal.abs().max_element();
    if !(big.is_finite() && big > 0.0) {
        return (DVec3::X, DVec3::Y);
    }
    let n = (normal / big).normalize();
    let a = n.abs();
    let axis = super::frame::least_aligned_axis(a);
    let u = n.cross(axis).normalize();
    let v = n.cross(u);
    (u, v)
}

/// Signed solid angle of triangle (a, b, c) seen from the origin
/// (Van Oosterom & Strackee 1983); positive for an outward triangle of a
/// closed mesh seen from inside it. Summed over a closed mesh and divided
/// by 4π: the winding number at the origin.
#[inline]
pub fn solid_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let det = a.dot(b.cross(c));
    let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    2.0 * libm::atan2(det, den)
}

/// Triangulates a ring, appending `n - 2` triangles of local indices into `points` to `out`
/// (existing contents of `out` are kept). Rings with fewer than 3 points append nothing.
///
/// Triangles are wound like the ring, i.e. counter-clockwise around the Newell normal. The result
/// depends only on the input values, never panics and never contains out-of-range indices.
/// Rings longer than `u32::MAX` points are not supported and append nothing.
pub fn triangulate(points: &[DVec3], out: &mut Vec<[u32; 3]>) {
    triangulate_impl(points, out, false);
}

/// [`triangulate`] that also returns the ring's [`unit_normal`] (bit-identical to calling it),
/// computed on the way, for callers that need both (writers).
pub fn triangulate_with_normal(points: &[DVec3], out: &mut Vec<[u32; 3]>) -> Option<DVec3> {
    triangulate_impl(points, out, true)
}

fn triangulate_impl(points: &[DVec3], out: &mut Vec<[u32; 3]>, want_normal: bool) -> Option<DVec3> {
    let n = points.len();
    if n < 3 || u32::try_from(n).is_err() {
        return if want_normal {
            unit_normal(points)
        } else {
            None
        };
    }
    if n == 3 {
        // A triangle is its own triangulation (a fan, also when degenerate).
        out.push([0, 1, 2]);
        return if want_normal {
            unit_normal_of(&[points[0], points[1], points[2]])
        } else {
            None
        };
    }
    let Some(frame) = Frame::new(points) else {
        fan(n, out);
        return None;
    };
    let Some(normal) = frame.unit_normal(points) else {
        fan(n, out);
        return None;
    };
    if n == 3 {
        out.push([0, 1, 2]);
    } else if n == 4 {
        let local = [0, 1, 2, 3].map(|i| frame.local(points[i]));
        match split_quad(&local, normal) {
            Some(tris) => out.extend_from_slice(&tris),
            None => triangulate_general(points, &frame, normal, out),
        }
    } else if is_strictly_convex(points, &frame, normal) {
        fan(n, out);
    } else {
        triangulate_general(points, &frame, normal, out);
    }
    Some(normal)
}

/// Which diagonal [`triangulate`] splits a quad along, for a caller that
/// already has the quad's [`unit_normal`] (the kernel stores it, fresh):
/// `Some(true)` for 0–2 (triangles `[0, 1, 2]`, `[0, 2, 3]`), `Some(false)`
/// for 1–3 (`[1, 2, 3]`, `[1, 3, 0]`), `None` when neither diagonal gives
/// two triangles facing along the normal (bow-ties and worse: `triangulate`
/// takes its general path). A degenerate quad (`normal` is `None`) is a fan
/// from corner 0, so 0–2. The same decision, bit for bit, as `triangulate`.
pub fn quad_split_along_0_2(points: &[DVec3; 4], normal: Option<DVec3>) -> Option<bool> {
    let Some(normal) = normal else {
        return Some(true);
    };
    // A unit normal means the corners are finite, so the frame exists.
    let frame = Frame::new(points)?;
    let local = points.map(|p| frame.local(p));
    split_quad(&local, normal).map(|tris| tris[0] == [0, 1, 2])
}

/// The ring's bounding-box frame. Local coordinates are `p - centre` when the extent is in a
/// safe range (no overflow or underflow in cross products: the fast common case), else
/// `(p - centre) / extent` (scale-free, for extreme magnitudes). `unit()` is the extent of the
/// ring in local coordinates, so thresholds can be stated relative to the ring's size.
struct Frame {
    centre: DVec3,
    half: f64,
    raw: bool,
}

impl Frame {
    /// `None` if the ring is empty or has a non-finite coordinate.
    fn new(points: &[DVec3]) -> Option<Frame> {
        let first = *points.first()?;
        let (mut lo, mut hi) = (first, first);
        for p in points {
            if !p.is_finite() {
                return None;
            }
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        // Halving first keeps both the centre and the extent finite for any finite input.
        let half = (hi * 0.5 - lo * 0.5).max_element();
        Some(Frame {
            centre: lo * 0.5 + hi * 0.5,
            half,
            raw: (1e-100..=1e100).contains(&half),
        })
    }

    fn local(&self, p: DVec3) -> DVec3 {
        if self.raw {
            p - self.centre
        } else if self.half > 0.0 {
            (p * 0.5 - self.centre * 0.5) / self.half
        } else {
            DVec3::ZERO
        }
    }

    /// Extent of the ring in local coordinates.
    fn unit(&self) -> f64 {
        if self.raw {
            2.0 * self.half
        } else {
            1.0
        }
    }

    /// Local coordinates divided by `unit()`: always within `[-0.5, 0.5]`.
    fn normalized(&self, p: DVec3) -> DVec3 {
        if self.raw {
            (p - self.centre) / (2.0 * self.half)
        } else {
            self.local(p)
        }
    }

    /// Factor turning a local-frame area into a world area.
    fn area_scale(&self) -> f64 {
        if self.raw {
            1.0
        } else {
            let extent = 2.0 * self.half;
            extent * extent
        }
    }

    /// Newell normal of the ring in local coordinates.
    fn normal(&self, points: &[DVec3]) -> DVec3 {
        if points.len() < 3 {
            return DVec3::ZERO;
        }
        let origin = self.local(points[0]);
        let mut sum = DVec3::ZERO;
        let mut prev = self.local(points[1]) - origin;
        for p in &points[2..] {
            let cur = self.local(*p) - origin;
            sum += prev.cross(cur);
            prev = cur;
        }
        sum
    }

    fn unit_normal(&self, points: &[DVec3]) -> Option<DVec3> {
        let normal = self.normal(points);
        let len = normal.length();
        let unit = self.unit();
        let threshold = DEGENERATE_PER_VERTEX * points.len() as f64 * unit * unit;
        (len.is_finite() && len > threshold).then(|| normal / len)
    }
}

/// Fan from vertex 0: `(0, i, i + 1)`.
fn fan(n: usize, out: &mut Vec<[u32; 3]>) {
    for i in 1..n as u32 - 1 {
        out.push([0, i, i + 1]);
    }
}

/// Orientation of triangle `(a, b, c)` along `normal` (positive: counter-clockwise).
fn orient3(a: DVec3, b: DVec3, c: DVec3, normal: DVec3) -> f64 {
    (b - a).cross(c - a).dot(normal)
}

/// Splits a quad along the shorter diagonal if both halves face along `normal`, else along the
/// other diagonal if that works; `None` if neither does (bow-ties and worse).
fn split_quad(q: &[DVec3; 4], normal: DVec3) -> Option<[[u32; 3]; 2]> {
    let d02 = [[0, 1, 2], [0, 2, 3]];
    let d13 = [[1, 2, 3], [1, 3, 0]];
    let valid = |tris: &[[u32; 3]; 2]| {
        tris.iter()
            .all(|t| orient3(q[t[0] as usize], q[t[1] as usize], q[t[2] as usize], normal) > 0.0)
    };
    let (first, second) = if q[0].distance_squared(q[2]) <= q[1].distance_squared(q[3]) {
        (d02, d13)
    } else {
        (d13, d02)
    };
    if valid(&first) {
        Some(first)
    } else if valid(&second) {
        Some(second)
    } else {
        None
    }
}

/// True if every turn of the projected ring is clearly positive and the ring winds exactly once
/// (edge directions change sign along `u` only twice), so a fan from vertex 0 is valid.
fn is_strictly_convex(points: &[DVec3], frame: &Frame, normal: DVec3) -> bool {
    let n = points.len();
    let (u, _) = plane_basis(normal);
    let local = |i: usize| frame.local(points[i % n]);
    let mut corner = local(1);
    let mut edge = corner - local(0);
    let (mut first_sign, mut last_sign) = (0.0, 0.0);
    let mut sign_changes = 0;
    for i in 0..n {
        // `edge` runs from vertex i to vertex i + 1; `next_edge` from i + 1 to i + 2.
        let next_corner = local(i + 2);
        let next_edge = next_corner - corner;
        let turn = edge.cross(next_edge).dot(normal);
        // Require sin(turn) > 1e-9: collinear and reflex vertices take the general path.
        if !(turn > 0.0 && turn * turn > 1e-18 * edge.length_squared() * next_edge.length_squared())
        {
            return false;
        }
        let dx = edge.dot(u);
        if dx != 0.0 {
            let sign = dx.signum();
            if first_sign == 0.0 {
                first_sign = sign;
            } else if sign != last_sign {
                sign_changes += 1;
            }
            last_sign = sign;
        }
        edge = next_edge;
        corner = next_corner;
    }
    if first_sign != last_sign {
        sign_changes += 1;
    }
    sign_changes <= 2
}

/// Vertex carried through spade with its ring index (spade silently drops duplicates).
#[derive(Clone, Copy, Debug)]
struct RingVertex {
    position: Point2<f64>,
    index: u32,
}

impl HasPosition for RingVertex {
    type Scalar = f64;

    fn position(&self) -> Point2<f64> {
        self.position
    }
}

fn triangulate_general(points: &[DVec3], frame: &Frame, normal: DVec3, out: &mut Vec<[u32; 3]>) {
    let (u, v) = plane_basis(normal);
    let flush = |x: f64| if x.abs() < FLUSH { 0.0 } else { x };
    let projected: Vec<DVec2> = points
        .iter()
        .map(|p| {
            let l = frame.normalized(*p);
            DVec2::new(flush(l.dot(u)), flush(l.dot(v)))
        })
        .collect();
    if !has_duplicates(&projected) && cdt_triangulate(&projected, out) {
        return;
    }
    ear_clip(&projected, out);
}

fn has_duplicates(points: &[DVec2]) -> bool {
    let mut keys: Vec<(u64, u64)> = points
        .iter()
        .map(|p| (p.x.to_bits(), p.y.to_bits()))
        .collect();
    keys.sort_unstable();
    keys.windows(2).any(|w| w[0] == w[1])
}

/// Constrained Delaunay triangulation of a simple ring; keeps faces with odd crossing parity.
/// Returns false (appending nothing) unless it finds exactly `n - 2` inside triangles.
fn cdt_triangulate(points: &[DVec2], out: &mut Vec<[u32; 3]>) -> bool {
    let n = points.len();
    let vertices: Vec<RingVertex> = points
        .iter()
        .enumerate()
        .map(|(i, p)| RingVertex {
            position: Point2::new(p.x, p.y),
            index: i as u32,
        })
        .collect();
    let edges: Vec<[usize; 2]> = (0..n).map(|i| [i, (i + 1) % n]).collect();
    let mut conflict = false;
    let cdt = match ConstrainedDelaunayTriangulation::<RingVertex>::try_bulk_load_cdt(
        vertices,
        edges,
        |_| conflict = true,
    ) {
        Ok(cdt) => cdt,
        Err(_) => return false,
    };
    if conflict || cdt.num_vertices() != n {
        return false;
    }

    const UNSEEN: u8 = u8::MAX;
    let mut parity = vec![UNSEEN; cdt.num_all_faces()];
    let mut stack = Vec::new();
    // Seed with the faces behind the convex hull: inside iff the hull edge is a constraint.
    for edge in cdt.directed_edges() {
        if !edge.face().is_outer() {
            continue;
        }
        let Some(inner) = edge.rev().face().as_inner() else {
            continue;
        };
        let p = u8::from(cdt.is_constraint_edge(edge.fix().as_undirected()));
        let slot = &mut parity[inner.fix().index()];
        if *slot == UNSEEN {
            *slot = p;
            stack.push(inner.fix());
        } else if *slot != p {
            return false;
        }
    }
    while let Some(fixed) = stack.pop() {
        let p = parity[fixed.index()];
        for edge in cdt.face(fixed).adjacent_edges() {
            let Some(neighbour) = edge.rev().face().as_inner() else {
                continue;
            };
            let np = p ^ u8::from(cdt.is_constraint_edge(edge.fix().as_undirected()));
            let slot = &mut parity[neighbour.fix().index()];
            if *slot == UNSEEN {
                *slot = np;
                stack.push(neighbour.fix());
            } else if *slot != np {
                return false;
            }
        }
    }

    let start = out.len();
    for face in cdt.inner_faces() {
        if parity[face.fix().index()] == 1 {
            let [a, b, c] = face.vertices();
            out.push([a.data().index, b.data().index, c.data().index]);
        }
    }
    if out.len() - start != n - 2 {
        out.truncate(start);
        return false;
    }
    true
}

fn orient2(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    (b - a).perp_dot(c - a)
}

/// Ear clipping of a counter-clockwise projected ring. Zero-area slivers (collinear vertices,
/// spikes, repeated points) are clipped first as they come; when no ear is left (or the work
/// budget runs out on pathological input) the remaining ring becomes a fan.
fn ear_clip(points: &[DVec2], out: &mut Vec<[u32; 3]>) {
    let n = points.len();
    let mut next: Vec<usize> = (0..n).map(|i| (i + 1) % n).collect();
    let mut prev: Vec<usize> = (0..n).map(|i| (i + n - 1) % n).collect();
    let mut remaining = n;
    let mut cur = 0;
    let mut misses = 0;
    // Ear clipping is quadratic: on big rings (only rings the CDT refuses
    // get here: repeated points, self-crossings) the work stops at
    // 512 tests per vertex and the rest becomes a fan, so a 100k-point
    // keyhole costs milliseconds, not minutes.
    let n64 = n as u64;
    let mut budget = n64.saturating_mul(n64).saturating_mul(8).min(n64 * 512) + 64;
    while remaining > 3 {
        let Some(left) = budget.checked_sub(1) else {
            break;
        };
        budget = left;
        let (a, b) = (prev[cur], next[cur]);
        let (pa, pc, pb) = (points[a], points[cur], points[b]);
        let o = orient2(pa, pc, pb);
        let clip = if o.abs() <= SLIVER {
            true
        } else if o > 0.0 {
            match is_ear(points, &next, a, cur, b, &mut budget) {
                Some(ear) => ear,
                None => break,
            }
        } else {
            false
        };
        if clip {
            out.push([a as u32, cur as u32, b as u32]);
            next[a] = b;
            prev[b] = a;
            remaining -= 1;
            misses = 0;
            cur = b;
        } else {
            misses += 1;
            if misses >= remaining {
                break;
            }
            cur = b;
        }
    }
    // Fan whatever is left (exactly 3 vertices in the normal case).
    let apex = cur;
    let mut k = next[apex];
    while next[k] != apex {
        out.push([apex as u32, k as u32, next[k] as u32]);
        k = next[k];
    }
}

/// Whether no other remaining vertex lies inside or on the triangle `(a, c, b)`; vertices
/// coinciding with a corner are ignored (keyhole bridges). `None` when the budget is spent.
fn is_ear(
    points: &[DVec2],
    next: &[usize],
    a: usize,
    c: usize,
    b: usize,
    budget: &mut u64,
) -> Option<bool> {
    let (pa, pc, pb) = (points[a], points[c], points[b]);
    let mut k = next[b];
    while k != a {
        *budget = budget.checked_sub(1)?;
        let p = points[k];
        if p != pa
            && p != pc
            && p != pb
            && orient2(pa, pc, p) >= 0.0
            && orient2(pc, pb, p) >= 0.0
            && orient2(pb, pa, p) >= 0.0
        {
            return Some(false);
        }
        k = next[k];
    }
    Some(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring2(xy: &[(f64, f64)]) -> Vec<DVec3> {
        xy.iter().map(|&(x, y)| DVec3::new(x, y, 0.0)).collect()
    }

    fn tris(points: &[DVec3]) -> Vec<[u32; 3]> {
        let mut out = Vec::new();
        triangulate(points, &mut out);
        out
    }

    #[test]
    fn fixed_size_normals_are_the_same_bits() {
        let bits = |n: Option<DVec3>| n.map(|v| v.to_array().map(f64::to_bits));
        let mut state = 7u64;
        let mut unit = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let scales = [1.0, 1e-120, 1e120, 1e-3, 1e5, 0.0];
        for i in 0..20_000 {
            let scale = scales[i % scales.len()];
            let offset = DVec3::splat(if i % 3 == 0 { 1e4 } else { 0.0 });
            let mut p: Vec<DVec3> = (0..4)
                .map(|_| DVec3::new(unit(), unit(), unit() * 0.1) * scale + offset)
                .collect();
            match i % 11 {
                // Collinear, repeated and non-finite corners.
                1 => p[2] = p[0] * 0.5 + p[1] * 0.5,
                2 => p[3] = p[1],
                3 => p[1].y = f64::NAN,
                4 => p[2].z = f64::INFINITY,
                5 => p[0] = DVec3::new(-0.0, 0.0, -0.0),
                _ => {}
            }
            let tri: [DVec3; 3] = [p[0], p[1], p[2]];
            let quad: [DVec3; 4] = [p[0], p[1], p[2], p[3]];
            assert_eq!(bits(unit_normal_of(&tri)), bits(unit_normal(&tri)), "{i}");
            assert_eq!(bits(unit_normal_of(&quad)), bits(unit_normal(&quad)), "{i}");
        }
    }

    /// Checks count, index range, and that each corner index appears in the triangle set.
    fn check_basic(points: &[DVec3], out: &[[u32; 3]]) {
        let n = points.len();
        assert_eq!(out.len(), n.saturating_sub(2), "triangle count for n = {n}");
        for t in out {
            for &i in t {
                assert!((i as usize) < n, "index {i} out of range");
            }
            assert!(
                t[0] != t[1] && t[1] != t[2] && t[0] != t[2],
                "repeated corner {t:?}"
            );
        }
    }

    fn tri_area_vec(points: &[DVec3], t: [u32; 3]) -> DVec3 {
        let [a, b, c] = t.map(|i| points[i as usize]);
        (b - a).cross(c - a) * 0.5
    }

    /// Planar simple polygon: triangle areas sum to the polygon area and all face the normal.
    fn check_simple(points: &[DVec3]) {
        let out = tris(points);
        check_basic(points, &out);
        // Judge areas on a copy rescaled to unit size so 1e-300 rings do not underflow.
        let c = centroid(points);
        let size = points
            .iter()
            .map(|p| (*p - c).abs().max_element())
            .fold(0.0, f64::max);
        let scaled: Vec<DVec3> = points.iter().map(|p| (*p - c) / size).collect();
        assert_eq!(out, tris(points), "deterministic");
        let points = &scaled[..];
        let normal = unit_normal(points).expect("non-degenerate");
        let mut sum = 0.0;
        for &t in &out {
            let a = tri_area_vec(points, t).dot(normal);
            assert!(
                a > 0.0,
                "triangle {t:?} is not wound along the normal (area {a})"
            );
            sum += a;
        }
        let expected = area(points);
        assert!(
            (sum - expected).abs() <= 1e-9 * expected.max(1e-300),
            "area {sum} vs {expected}"
        );
    }

    fn regular(n: usize, radius: f64) -> Vec<DVec3> {
        (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                DVec3::new(radius * a.cos(), radius * a.sin(), 0.0)
            })
            .collect()
    }

    #[test]
    fn newell_of_unit_square() {
        let sq = ring2(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
        assert_eq!(newell_normal(&sq), DVec3::new(0.0, 0.0, 2.0));
        assert_eq!(area(&sq), 1.0);
        assert_eq!(unit_normal(&sq), Some(DVec3::Z));
        assert_eq!(centroid(&sq), DVec3::new(0.5, 0.5, 0.0));
        let mut rev = sq.clone();
        rev.reverse();
        assert_eq!(unit_normal(&rev), Some(-DVec3::Z));
    }

    #[test]
    fn newell_handles_extreme_scales() {
        for s in [1e-200, 1e-3, 1.0, 1e150, 1e300] {
            let sq: Vec<DVec3> = ring2(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)])
                .into_iter()
                .map(|p| p * s)
                .collect();
            assert_eq!(unit_normal(&sq), Some(DVec3::Z), "scale {s}");
            let expected: f64 = s * s;
            let got = area(&sq);
            if expected.is_finite() && expected > 0.0 {
                assert!(
                    (got - expected).abs() <= 1e-12 * expected,
                    "scale {s}: {got}"
                );
            }
        }
    }

    #[test]
    fn degenerate_normals() {
        assert_eq!(newell_normal(&[]), DVec3::ZERO);
        assert_eq!(unit_normal(&[DVec3::ZERO, DVec3::X]), None);
        let line = [DVec3::ZERO, DVec3::X, DVec3::X * 2.0, DVec3::X * 3.0];
        assert_eq!(unit_normal(&line), None);
        let nan = [DVec3::ZERO, DVec3::X, DVec3::new(f64::NAN, 1.0, 0.0)];
        assert_eq!(unit_normal(&nan), None);
        assert_eq!(newell_normal(&nan), DVec3::ZERO);
        assert_eq!(area(&nan), 0.0);
    }

    #[test]
    fn plane_basis_is_right_handed_and_orthonormal() {
        let normals = [
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            -DVec3::Z,
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(-3.0, 0.5, 2.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(1e-300, 0.0, -1e-300),
        ];
        for n in normals {
            let (u, v) = plane_basis(n);
            let nh = (n / n.abs().max_element()).normalize();
            assert!((u.length() - 1.0).abs() < 1e-12);
            assert!((v.length() - 1.0).abs() < 1e-12);
            assert!(u.dot(v).abs() < 1e-12);
            assert!((u.cross(v) - nh).length() < 1e-12, "{n}");
            assert_eq!(plane_basis(n), (u, v), "deterministic");
        }
        assert_eq!(plane_basis(DVec3::ZERO), (DVec3::X, DVec3::Y));
    }

    #[test]
    fn triangulate_with_normal_matches_the_separate_calls() {
        let rings = [
            regular(3, 1.0),
            regular(4, 2.0),
            regular(9, 1e-200),
            ring2(&[
                (0.0, 0.0),
                (2.0, 0.0),
                (2.0, 1.0),
                (1.0, 1.0),
                (1.0, 2.0),
                (0.0, 2.0),
            ]),
            vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0, DVec3::X * 3.0],
            vec![DVec3::ZERO, DVec3::X],
        ];
        for ring in rings {
            let (mut a, mut b) = (Vec::new(), Vec::new());
            let normal = triangulate_with_normal(&ring, &mut a);
            triangulate(&ring, &mut b);
            assert_eq!(a, b);
            assert_eq!(normal, unit_normal(&ring));
        }
    }

    #[test]
    fn quad_split_along_0_2_is_the_diagonal_triangulate_takes() {
        // Random quads on a small integer lattice (so collinear, repeated,
        // bow-tie and non-planar corners all come up), at three scales
        // including the rescaled frame; where the decision is `None`,
        // triangulate takes neither clean split of `split_quad`.
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut coord = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) % 5) as f64 - 2.0
        };
        let (mut decided, mut general) = (0, 0);
        for i in 0..20_000 {
            let scale = [1.0, 1e-3, 1e-120][i % 3];
            let flat = i % 2 == 0;
            let quad: [DVec3; 4] = std::array::from_fn(|_| {
                let (x, y) = (coord(), coord());
                let z = if flat { 0.0 } else { coord() };
                DVec3::new(x, y, z) * scale
            });
            let got = tris(&quad);
            match quad_split_along_0_2(&quad, unit_normal(&quad)) {
                Some(true) => assert!(got == [[0, 1, 2], [0, 2, 3]], "{quad:?}: {got:?}"),
                Some(false) => assert_eq!(got, [[1, 2, 3], [1, 3, 0]], "{quad:?}"),
                None => {
                    assert!(got != [[0, 1, 2], [0, 2, 3]] && got != [[1, 2, 3], [1, 3, 0]]);
                    general += 1;
                    continue;
                }
            }
            decided += 1;
        }
        assert!(decided > 10_000 && general > 100, "{decided} {general}");
    }

    #[test]
    fn small_rings() {
        assert!(tris(&[]).is_empty());
        assert!(tris(&[DVec3::ZERO, DVec3::X]).is_empty());
        assert_eq!(tris(&[DVec3::ZERO, DVec3::X, DVec3::Y]), vec![[0, 1, 2]]);
    }

    #[test]
    fn convex_polygons() {
        check_simple(&ring2(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]));
        for n in [5, 6, 7, 12, 64, 1000] {
            check_simple(&regular(n, 2.5));
        }
        // A regular polygon is fanned from vertex 0.
        let out = tris(&regular(6, 1.0));
        assert_eq!(out, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]]);
    }

    #[test]
    fn quad_uses_shorter_diagonal() {
        // Long along x: diagonal 1-3 is shorter.
        let kite = ring2(&[(0.0, 0.0), (2.0, -0.5), (4.0, 0.0), (2.0, 0.5)]);
        assert_eq!(tris(&kite), vec![[1, 2, 3], [1, 3, 0]]);
        check_simple(&kite);
        // Square: tie goes to 0-2.
        let sq = ring2(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
        assert_eq!(tris(&sq), vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn concave_quad_uses_inside_diagonal() {
        // Dart: vertex 3 is reflex, the shorter diagonal 1-3 is inside, 0-2 is outside.
        let dart = ring2(&[(0.0, 0.0), (2.0, 1.0), (0.0, 2.0), (0.6, 1.0)]);
        assert_eq!(tris(&dart), vec![[1, 2, 3], [1, 3, 0]]);
        check_simple(&dart);
        // Same dart, rotated so the shorter diagonal is the outside one.
        let dart = ring2(&[(0.0, 0.0), (4.0, 1.0), (0.0, 2.0), (3.5, 1.0)]);
        check_simple(&dart);
    }

    #[test]
    fn l_shape_and_combs() {
        let l = ring2(&[
            (0.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ]);
        check_simple(&l);
        // 12-gon star.
        let star: Vec<DVec3> = (0..12)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 12.0;
                let r = if i % 2 == 0 { 3.0 } else { 1.0 };
                DVec3::new(r * a.cos(), r * a.sin(), 0.0)
            })
            .collect();
        check_simple(&star);
        // Comb with 5 teeth, wound clockwise (normal -Z).
        let mut comb = vec![(0.0, 0.0), (10.0, 0.0)];
        for t in (0..5).rev() {
            let x = 2.0 * t as f64;
            comb.extend([(x + 2.0, 3.0), (x + 1.0, 3.0), (x + 1.0, 1.0), (x, 1.0)]);
        }
        comb.pop();
        comb.push((0.0, 3.0));
        let mut comb = ring2(&comb);
        check_simple(&comb);
        comb.reverse();
        check_simple(&comb);
    }

    #[test]
    fn tilted_plane_polygon() {
        let l = ring2(&[
            (0.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ]);
        let rot = glam::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 1.1);
        let l: Vec<DVec3> = l
            .iter()
            .map(|p| rot * *p + DVec3::new(5.0, -3.0, 7.0))
            .collect();
        check_simple(&l);
    }

    #[test]
    fn non_planar_twisted_quad() {
        let q = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.3),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.3),
        ];
        let out = tris(&q);
        check_basic(&q, &out);
        let n = unit_normal(&q).unwrap();
        for t in out {
            assert!(tri_area_vec(&q, t).dot(n) > 0.0);
        }
        // Non-planar hexagon (crown).
        let crown: Vec<DVec3> = (0..6)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 6.0;
                DVec3::new(a.cos(), a.sin(), if i % 2 == 0 { 0.4 } else { -0.4 })
            })
            .collect();
        let out = tris(&crown);
        check_basic(&crown, &out);
        let n = unit_normal(&crown).unwrap();
        for t in out {
            assert!(tri_area_vec(&crown, t).dot(n) > 0.0);
        }
    }

    #[test]
    fn collinear_and_coincident_rings() {
        let line: Vec<DVec3> = (0..7).map(|i| DVec3::X * i as f64).collect();
        let out = tris(&line);
        check_basic(&line, &out);
        let same = vec![DVec3::ONE; 5];
        let out = tris(&same);
        assert_eq!(out.len(), 3);
        // Out and back along a line (zero area).
        let back = vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0, DVec3::X];
        assert_eq!(tris(&back).len(), 2);
    }

    #[test]
    fn duplicate_points() {
        // Repeated consecutive vertex in an L-shape.
        let l = ring2(&[
            (0.0, 0.0),
            (2.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ]);
        let out = tris(&l);
        check_basic_allowing_repeats(&l, &out);
        let normal = unit_normal(&l).unwrap();
        let sum: f64 = out.iter().map(|t| tri_area_vec(&l, *t).dot(normal)).sum();
        assert!((sum - 3.0).abs() < 1e-12, "area {sum}");
        for t in &out {
            assert!(tri_area_vec(&l, *t).dot(normal) >= -1e-12);
        }
    }

    /// Count and range only: with repeated points, degenerate triangles are expected.
    fn check_basic_allowing_repeats(points: &[DVec3], out: &[[u32; 3]]) {
        assert_eq!(out.len(), points.len() - 2);
        for t in out {
            assert!(t.iter().all(|&i| (i as usize) < points.len()));
        }
    }

    #[test]
    fn keyhole_polygon_with_bridge() {
        // 4x4 square with a 2x2 hole, joined by a bridge (two repeated points).
        let k = ring2(&[
            (0.0, 0.0),
            (4.0, 0.0),
            (4.0, 4.0),
            (0.0, 4.0),
            (0.0, 0.0),
            (1.0, 1.0),
            (1.0, 3.0),
            (3.0, 3.0),
            (3.0, 1.0),
            (1.0, 1.0),
        ]);
        let out = tris(&k);
        check_basic_allowing_repeats(&k, &out);
        let sum: f64 = out.iter().map(|t| tri_area_vec(&k, *t).z).sum();
        assert!((sum - 12.0).abs() < 1e-12, "area {sum}");
        for t in &out {
            assert!(tri_area_vec(&k, *t).z >= -1e-12, "flipped {t:?}");
        }
    }

    #[test]
    fn bow_ties() {
        // Symmetric bow-tie: zero Newell normal.
        let sym = ring2(&[(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0)]);
        assert_eq!(unit_normal(&sym), None);
        check_basic(&sym, &tris(&sym));
        // Asymmetric bow-tie (non-zero normal, crossing edges), as quad and as hexagon.
        let asym = ring2(&[(0.0, 0.0), (2.0, 2.0), (2.0, 0.0), (0.0, 1.0)]);
        assert!(unit_normal(&asym).is_some());
        check_basic(&asym, &tris(&asym));
        let hex = ring2(&[
            (0.0, 0.0),
            (1.0, 0.0),
            (3.0, 2.0),
            (3.0, 0.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ]);
        check_basic(&hex, &tris(&hex));
        // Pentagram: every turn has the same sign but it winds twice.
        let pentagram: Vec<DVec3> = (0..5)
            .map(|i| {
                let a = std::f64::consts::TAU * (2 * i) as f64 / 5.0;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let out = tris(&pentagram);
        check_basic(&pentagram, &out);
        assert_ne!(
            out,
            vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]],
            "must not be fanned"
        );
    }

    #[test]
    fn each_general_strategy_handles_an_l_shape() {
        let l = [
            (0.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ]
        .map(|(x, y)| DVec2::new(x, y));
        let check = |out: &[[u32; 3]]| {
            assert_eq!(out.len(), 4);
            let sum: f64 = out
                .iter()
                .map(|t| {
                    let o = orient2(l[t[0] as usize], l[t[1] as usize], l[t[2] as usize]);
                    assert!(o > 0.0, "{t:?}");
                    o * 0.5
                })
                .sum();
            assert_eq!(sum, 3.0);
        };
        let mut out = Vec::new();
        assert!(cdt_triangulate(&l, &mut out));
        check(&out);
        out.clear();
        ear_clip(&l, &mut out);
        check(&out);
        // A crossing ring makes spade report a conflict and append nothing.
        let bow = [(0.0, 0.0), (2.0, 2.0), (2.0, 0.0), (0.0, 1.0), (-1.0, 0.5)]
            .map(|(x, y)| DVec2::new(x, y));
        out.clear();
        assert!(!cdt_triangulate(&bow, &mut out));
        assert!(out.is_empty());
        assert!(has_duplicates(&[DVec2::ONE, DVec2::ZERO, DVec2::ONE]));
        assert!(!has_duplicates(&l));
    }

    #[test]
    fn huge_and_tiny_coordinates() {
        let l = [
            (0.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ];
        for s in [1e-300, 1e-45, 1e-20, 1e20, 1e100, 1e300] {
            let pts: Vec<DVec3> = l
                .iter()
                .map(|&(x, y)| DVec3::new(x * s, y * s, 0.0))
                .collect();
            check_simple(&pts);
            // Far from the origin.
            let off: Vec<DVec3> = l
                .iter()
                .map(|&(x, y)| DVec3::new(x + 1e12, y - 1e12, 5e11))
                .collect();
            check_simple(&off);
        }
        // Mixed extremes: one axis huge, one tiny.
        let pts: Vec<DVec3> = l
            .iter()
            .map(|&(x, y)| DVec3::new(x * 1e300, y * 1e-300, 0.0))
            .collect();
        check_basic(&pts, &tris(&pts));
    }

    #[test]
    fn non_finite_input_is_fanned() {
        let mut pts = regular(7, 1.0);
        pts[3].y = f64::NAN;
        assert_eq!(tris(&pts).len(), 5);
        pts[3].y = f64::INFINITY;
        let out = tris(&pts);
        check_basic(&pts, &out);
    }

    #[test]
    fn deterministic_and_counts_on_random_rings() {
        // Small xorshift so the test is reproducible without extra crates.
        let mut state = 0x9E37_79B9_7F4A_7C15_u64;
        let mut rnd = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for round in 0..400 {
            let n = 3 + round % 17;
            let pts: Vec<DVec3> = (0..n)
                .map(|_| {
                    // Snap to a coarse grid sometimes to create collinear/duplicate points.
                    let q = |x: f64| if round % 3 == 0 { (x * 4.0).round() } else { x };
                    DVec3::new(q(rnd()), q(rnd()), if round % 5 == 0 { rnd() } else { 0.0 })
                })
                .collect();
            let a = tris(&pts);
            assert_eq!(a.len(), n - 2, "round {round}");
            assert!(a.iter().flatten().all(|&i| (i as usize) < n));
            assert_eq!(a, tris(&pts), "non-deterministic in round {round}");
        }
    }

    #[test]
    fn star_shaped_random_simple_polygons_are_exact() {
        let mut state = 12345_u64;
        let mut rnd = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for round in 0..200 {
            let n = 5 + round % 40;
            // Star-shaped around the origin: strictly increasing angles, random radii -> simple.
            let pts: Vec<DVec3> = (0..n)
                .map(|i| {
                    let a = std::f64::consts::TAU * (i as f64 + 0.8 * rnd()) / n as f64;
                    let r = 0.2 + rnd();
                    DVec3::new(r * a.cos(), r * a.sin(), 0.0)
                })
                .collect();
            check_simple(&pts);
        }
    }
}
