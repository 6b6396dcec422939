//! The boolean's arrangement in exact rational arithmetic: the path taken
//! when the surfaces touch instead of crossing cleanly — coplanar faces, a
//! vertex on the other surface, an edge through an edge, equal shells
//! (issue 36, item 2). The general-position path rounds its crossing
//! points and refuses such contacts; this one never rounds before the
//! output.
//!
//! 1. Every pair of triangles whose boxes touch (inclusive: faces that
//!    only touch count) is intersected exactly: the segment where two
//!    planes' traces overlap, or, for coplanar triangles, one clipped by the
//!    other (Sutherland–Hodgman). Points are rationals, so a contact at a
//!    vertex or along an edge is the same point in every triangle that
//!    meets it.
//! 2. Every touched triangle is cut by its contacts: the contact segments
//!    are split where they cross or meet, the points inserted into the
//!    triangle, and the segments recovered by edge flips (Sloan 1993) — a
//!    constrained triangulation decided by exact orientations.
//! 3. Each piece is labelled by the winding numbers of both operands just
//!    in front of and just behind it: `w(c ± εn)` at its centroid `c`,
//!    a ray along +x from a symbolically perturbed point (the perturbation
//!    is a polynomial in ε; every sign is its first non-zero coefficient,
//!    as in Edelsbrunner and Mücke's simulation of simplicity). A piece is
//!    kept when the operation's indicator differs on its two sides, wound
//!    from inside to outside: the labelling of Zhou et al. 2016 ("Mesh
//!    arrangements for solid geometry"), per piece. Where pieces of both
//!    operands coincide (coplanar contact), the selection's are the ones
//!    kept.
//! 4. The result must be edge-manifold: two solids meeting only along an
//!    edge are refused with the point.
//!
//! Cost: rational arithmetic and per-piece ray casts, so this path is for
//! the touching contacts that real models have (boxes stacked, cutters
//! flush with a wall), not for 10⁵ crossing triangles (the
//! general-position path).

use glam::DVec3;
use num_bigint::BigInt;
use num_rational::BigRational;
use num_traits::{Signed, ToPrimitive, Zero};
use rustc_hash::FxHashMap;
use std::collections::VecDeque;

use super::{
    bounds, sign, BooleanError, Bvh, Input, Operand, Operation, OutPolygon, Output, PointSource,
    Tri,
};
use crate::geom::predicates::{orient3d, triangle_triangle_exact};

type Q = BigRational;

/// The most work (the sum over touched triangles of their contacts
/// squared) the exact path takes on: about 5 s on one core (a triangle
/// with 10,000 contacts).
const CONTACT_WORK_LIMIT: u64 = 100_000_000;
type V3 = [Q; 3];

/// A point with exact rational coordinates.
#[derive(Clone, Debug, PartialEq, Eq)]
struct P3(V3);

impl std::hash::Hash for P3 {
    /// Ratios are kept reduced with a positive denominator, so equal
    /// points have equal parts (`Ratio`'s own hash expands a continued
    /// fraction to be independent of that, which dominated the profile).
    fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
        for x in &self.0 {
            x.numer().hash(state);
            x.denom().hash(state);
        }
    }
}

fn q(x: f64) -> Q {
    let (n, e) = integer(x);
    power_of_two(n, e)
}

/// A finite f64 as `n · 2^e` with `n` odd (or zero).
fn integer(x: f64) -> (BigInt, i32) {
    debug_assert!(
        x.is_finite(),
        "finite coordinates (checked when triangulating)"
    );
    let (mantissa, exponent, sign) = num_traits::Float::integer_decode(x);
    if mantissa == 0 {
        return (BigInt::zero(), 0);
    }
    let shift = mantissa.trailing_zeros();
    let n = BigInt::from(mantissa >> shift) * BigInt::from(sign);
    (n, exponent as i32 + shift as i32)
}

/// `n · 2^e` as a reduced ratio.
fn power_of_two(n: BigInt, e: i32) -> Q {
    if e >= 0 {
        Q::from_integer(n << e as u32)
    } else {
        Q::new(n, BigInt::from(1) << (-e) as u32)
    }
}

/// Where segment `p q` crosses the plane of `u` (its ends strictly on
/// either side), exactly: every input scaled to an integer over one power
/// of two, the plane and the interpolation in integers, one reduction per
/// coordinate at the end.
fn edge_plane_point(p: DVec3, q: DVec3, u: [DVec3; 3]) -> P3 {
    let values = [p, q, u[0], u[1], u[2]];
    let decoded: Vec<[(BigInt, i32); 3]> = values
        .iter()
        .map(|v| [integer(v.x), integer(v.y), integer(v.z)])
        .collect();
    let base = decoded
        .iter()
        .flatten()
        .filter(|(n, _)| !n.is_zero())
        .map(|&(_, e)| e)
        .min()
        .unwrap_or(0);
    let int: Vec<[BigInt; 3]> = decoded
        .into_iter()
        .map(|c| c.map(|(n, e)| n << (e - base) as u32))
        .collect();
    let d = |a: &[BigInt; 3], b: &[BigInt; 3]| [&a[0] - &b[0], &a[1] - &b[1], &a[2] - &b[2]];
    let (e1, e2) = (d(&int[3], &int[2]), d(&int[4], &int[2]));
    let n = [
        &e1[1] * &e2[2] - &e1[2] * &e2[1],
        &e1[2] * &e2[0] - &e1[0] * &e2[2],
        &e1[0] * &e2[1] - &e1[1] * &e2[0],
    ];
    let dot = |a: &[BigInt; 3]| &n[0] * &a[0] + &n[1] * &a[1] + &n[2] * &a[2];
    let (dp, dq) = (dot(&d(&int[0], &int[2])), dot(&d(&int[1], &int[2])));
    let den = &dp - &dq;
    P3([0, 1, 2].map(|k| {
        let num = &int[0][k] * -&dq + &int[1][k] * &dp;
        if base >= 0 {
            Q::new(num << base as u32, den.clone())
        } else {
            Q::new(num, den.clone() << (-base) as u32)
        }
    }))
}

fn exact(p: DVec3) -> P3 {
    P3([q(p.x), q(p.y), q(p.z)])
}

fn rounded(p: &P3) -> DVec3 {
    let f = |x: &Q| x.to_f64().unwrap_or(f64::NAN);
    DVec3::new(f(&p.0[0]), f(&p.0[1]), f(&p.0[2]))
}

fn sub(a: &P3, b: &P3) -> V3 {
    [&a.0[0] - &b.0[0], &a.0[1] - &b.0[1], &a.0[2] - &b.0[2]]
}

fn cross(a: &V3, b: &V3) -> V3 {
    [
        &a[1] * &b[2] - &a[2] * &b[1],
        &a[2] * &b[0] - &a[0] * &b[2],
        &a[0] * &b[1] - &a[1] * &b[0],
    ]
}

fn dot(a: &V3, b: &V3) -> Q {
    &a[0] * &b[0] + &a[1] * &b[1] + &a[2] * &b[2]
}

fn normal(t: &[P3; 3]) -> V3 {
    cross(&sub(&t[1], &t[0]), &sub(&t[2], &t[0]))
}

/// `a + (b − a) · s`.
fn lerp(a: &P3, b: &P3, s: &Q) -> P3 {
    let d = sub(b, a);
    P3([
        &a.0[0] + &d[0] * s,
        &a.0[1] + &d[1] * s,
        &a.0[2] + &d[2] * s,
    ])
}

fn sgn(x: &Q) -> i8 {
    if x.is_positive() {
        1
    } else if x.is_negative() {
        -1
    } else {
        0
    }
}

/// The first non-zero sign of a perturbation's coefficients (0 if all
/// vanish).
fn first_sign(coefficients: &[Q]) -> i8 {
    coefficients.iter().map(sgn).find(|&s| s != 0).unwrap_or(0)
}

/// The axis of `n`'s largest component: dropping it projects a plane with
/// normal `n` one to one.
fn dominant_axis(n: &V3) -> usize {
    let a = n.clone().map(|x| x.abs());
    if a[0] >= a[1] && a[0] >= a[2] {
        0
    } else if a[1] >= a[2] {
        1
    } else {
        2
    }
}

/// The two axes kept when dropping `axis`, in cyclic order.
fn kept(axis: usize) -> (usize, usize) {
    ((axis + 1) % 3, (axis + 2) % 3)
}

/// Twice the signed area of `a b c` projected on axes `(i, j)`.
fn orient2(a: &P3, b: &P3, c: &P3, (i, j): (usize, usize)) -> Q {
    (&b.0[i] - &a.0[i]) * (&c.0[j] - &a.0[j]) - (&b.0[j] - &a.0[j]) * (&c.0[i] - &a.0[i])
}

/// The sign of [`orient2`] without reducing fractions: the differences
/// and products over unreduced integer numerators and denominators
/// (denominators are positive), since the gcds of `Ratio`'s reductions
/// are most of its cost.
fn orient2_sign(a: &P3, b: &P3, c: &P3, (i, j): (usize, usize)) -> i8 {
    let diff = |x: &Q, y: &Q| {
        (
            x.numer() * y.denom() - y.numer() * x.denom(),
            x.denom() * y.denom(),
        )
    };
    let (x1, x1d) = diff(&b.0[i], &a.0[i]);
    let (y2, y2d) = diff(&c.0[j], &a.0[j]);
    let (y1, y1d) = diff(&b.0[j], &a.0[j]);
    let (x2, x2d) = diff(&c.0[i], &a.0[i]);
    let lhs = &x1 * &y2 * (&y1d * &x2d);
    let rhs = &y1 * &x2 * (&x1d * &y2d);
    match lhs.cmp(&rhs) {
        std::cmp::Ordering::Greater => 1,
        std::cmp::Ordering::Less => -1,
        std::cmp::Ordering::Equal => 0,
    }
}

/// The contact of two triangles as segments (`a == b` for a lone point);
/// empty when they do not meet. `tf`/`uf` are the same corners in f64, for
/// the exact orientation filter.
fn contact(t: &[P3; 3], tf: [DVec3; 3], u: &[P3; 3], uf: [DVec3; 3]) -> Vec<(P3, P3)> {
    let st = tf.map(|p| sign(orient3d(uf[0], uf[1], uf[2], p)));
    if st.iter().all(|&s| s == st[0] && s != 0) {
        return Vec::new();
    }
    let su = uf.map(|p| sign(orient3d(tf[0], tf[1], tf[2], p)));
    if su.iter().all(|&s| s == su[0] && s != 0) {
        return Vec::new();
    }
    if st == [0, 0, 0] {
        return coplanar_contact(t, u);
    }
    // Where each triangle meets the other's plane: a point or a segment
    // on the planes' common line.
    let trace = |tri: &[P3; 3], f: [DVec3; 3], s: [i8; 3], plane: [DVec3; 3]| -> Vec<P3> {
        let mut out: Vec<P3> = (0..3)
            .filter(|&k| s[k] == 0)
            .map(|k| tri[k].clone())
            .collect();
        for k in 0..3 {
            let j = (k + 1) % 3;
            if s[k] * s[j] < 0 {
                out.push(edge_plane_point(f[k], f[j], plane));
            }
        }
        out
    };
    let on_t = trace(t, tf, st, uf);
    let on_u = trace(u, uf, su, tf);
    // An axis along which the common line advances: the floating-point
    // direction's largest component where rounding cannot make it zero.
    let axis = {
        // (The cross products' error is a few ulps of their edges'
        // lengths' products, however thin the triangles.)
        let normal_f = |c: [DVec3; 3]| {
            let (e1, e2) = (c[1] - c[0], c[2] - c[0]);
            (e1.cross(e2), e1.length() * e2.length())
        };
        let ((a, la), (b, lb)) = (normal_f(tf), normal_f(uf));
        let line = a.cross(b);
        let k = line.abs().max_position();
        if line[k].abs() > 1e-10 * la * lb {
            k
        } else {
            dominant_axis(&cross(&normal(t), &normal(u)))
        }
    };
    let key = |p: &P3| p.0[axis].clone();
    let span = |pts: Vec<P3>| -> (P3, P3) {
        let (a, b) = (pts[0].clone(), pts[pts.len() - 1].clone());
        if key(&a) <= key(&b) {
            (a, b)
        } else {
            (b, a)
        }
    };
    let (t_lo, t_hi) = span(on_t);
    let (u_lo, u_hi) = span(on_u);
    let lo = if key(&t_lo) >= key(&u_lo) { t_lo } else { u_lo };
    let hi = if key(&t_hi) <= key(&u_hi) { t_hi } else { u_hi };
    match key(&lo).cmp(&key(&hi)) {
        std::cmp::Ordering::Greater => Vec::new(),
        std::cmp::Ordering::Equal => vec![(lo.clone(), lo)],
        std::cmp::Ordering::Less => vec![(lo, hi)],
    }
}

/// Two triangles in one plane: `t` clipped by `u`'s three edges, as the
/// boundary of the (possibly degenerate) convex overlap.
fn coplanar_contact(t: &[P3; 3], u: &[P3; 3]) -> Vec<(P3, P3)> {
    let axes = kept(dominant_axis(&normal(t)));
    let su = orient2_sign(&u[0], &u[1], &u[2], axes);
    let mut poly: Vec<P3> = t.to_vec();
    for e in 0..3 {
        let (a, b) = (&u[e], &u[(e + 1) % 3]);
        let side = |p: &P3| {
            let o = orient2(a, b, p, axes);
            if su < 0 {
                -o
            } else {
                o
            }
        };
        let sides: Vec<Q> = poly.iter().map(side).collect();
        let mut next = Vec::with_capacity(poly.len() + 1);
        for i in 0..poly.len() {
            let j = (i + 1) % poly.len();
            let (dp, dq) = (&sides[i], &sides[j]);
            if !dp.is_negative() {
                next.push(poly[i].clone());
            }
            if sgn(dp) * sgn(dq) < 0 {
                next.push(lerp(&poly[i], &poly[j], &(dp / (dp - dq))));
            }
        }
        next.dedup();
        while next.len() > 1 && next.first() == next.last() {
            next.pop();
        }
        poly = next;
        if poly.is_empty() {
            return Vec::new();
        }
    }
    match poly.len() {
        1 => vec![(poly[0].clone(), poly[0].clone())],
        2 => vec![(poly[0].clone(), poly[1].clone())],
        n => (0..n)
            .map(|i| (poly[i].clone(), poly[(i + 1) % n].clone()))
            .collect(),
    }
}

/// Triangle `t` cut by its contacts (segments inside it, `a == b` for a
/// point).
struct Arrangement {
    points: Vec<P3>,
    /// Wound as `t` is.
    triangles: Vec<[usize; 3]>,
    /// The edges that lie on a contact (the other surface touches them).
    contact_edges: Vec<(usize, usize)>,
}

/// Points in a plane, projected along one axis, with their rounded
/// coordinates for a filtered orientation test.
struct Planar {
    axes: (usize, usize),
    points: Vec<P3>,
    rounded: Vec<[f64; 2]>,
    index: FxHashMap<P3, usize>,
}

impl Planar {
    fn add(&mut self, p: &P3) -> usize {
        if let Some(&i) = self.index.get(p) {
            return i;
        }
        let f = |x: &Q| x.to_f64().unwrap_or(f64::NAN);
        self.points.push(p.clone());
        self.rounded
            .push([f(&p.0[self.axes.0]), f(&p.0[self.axes.1])]);
        self.index.insert(p.clone(), self.points.len() - 1);
        self.points.len() - 1
    }

    fn exact(&self, a: usize, b: usize, c: usize) -> Q {
        orient2(&self.points[a], &self.points[b], &self.points[c], self.axes)
    }

    /// The sign of [`orient2`]: in floating point where the rounding of
    /// the points and of the arithmetic cannot flip it, else exactly.
    fn sign(&self, a: usize, b: usize, c: usize) -> i8 {
        let ([ax, ay], [bx, by], [cx, cy]) = (self.rounded[a], self.rounded[b], self.rounded[c]);
        let (dbx, dby, dcx, dcy) = (bx - ax, by - ay, cx - ax, cy - ay);
        let o = dbx * dcy - dby * dcx;
        let size = ax
            .abs()
            .max(ay.abs())
            .max(bx.abs())
            .max(by.abs())
            .max(cx.abs())
            .max(cy.abs());
        let err = 32.0
            * f64::EPSILON
            * ((dbx * dcy).abs()
                + (dby * dcx).abs()
                + size * (dbx.abs() + dby.abs() + dcx.abs() + dcy.abs()));
        if o.abs() > err && o.is_finite() {
            sign(o)
        } else {
            orient2_sign(&self.points[a], &self.points[b], &self.points[c], self.axes)
        }
    }
}

fn arrange(t: &[P3; 3], contacts: &[(P3, P3)]) -> Result<Arrangement, BooleanError> {
    let axes = kept(dominant_axis(&normal(t)));
    let st = orient2_sign(&t[0], &t[1], &t[2], axes);
    let mut plane = Planar {
        axes,
        points: Vec::new(),
        rounded: Vec::new(),
        index: FxHashMap::default(),
    };
    for c in t {
        plane.add(c);
    }
    // (ends, lies on a contact)
    let mut segments: Vec<(usize, usize)> = vec![(0, 1), (1, 2), (2, 0)];
    let mut on_contact = vec![false; 3];
    for (a, b) in contacts {
        let (i, j) = (plane.add(a), plane.add(b));
        if i != j {
            segments.push((i, j));
            on_contact.push(true);
        }
    }
    let key = |(i, j): (usize, usize)| (i.min(j), i.max(j));
    let mut order: Vec<usize> = (0..segments.len()).collect();
    order.sort_by_key(|&k| (key(segments[k]), !on_contact[k]));
    order.dedup_by_key(|&mut k| key(segments[k]));
    let on_contact: Vec<bool> = order.iter().map(|&k| on_contact[k]).collect();
    let segments: Vec<(usize, usize)> = order.iter().map(|&k| segments[k]).collect();
    let boxes: Vec<([f64; 2], [f64; 2])> = segments
        .iter()
        .map(|&(i, j)| {
            let (a, b) = (plane.rounded[i], plane.rounded[j]);
            let pad = |x: f64, y: f64| 1e-9 * (1.0 + x.abs().max(y.abs()));
            let (px, py) = (pad(a[0], b[0]), pad(a[1], b[1]));
            (
                [a[0].min(b[0]) - px, a[1].min(b[1]) - py],
                [a[0].max(b[0]) + px, a[1].max(b[1]) + py],
            )
        })
        .collect();
    let apart = |(lo1, hi1): ([f64; 2], [f64; 2]), (lo2, hi2): ([f64; 2], [f64; 2])| {
        lo1[0] > hi2[0] || lo2[0] > hi1[0] || lo1[1] > hi2[1] || lo2[1] > hi1[1]
    };
    // Where segments cross (each other's interiors).
    let mut crossings: Vec<P3> = Vec::new();
    for s in 0..segments.len() {
        for r in s + 1..segments.len() {
            if apart(boxes[s], boxes[r]) {
                continue;
            }
            let ((a, b), (c, d)) = (segments[s], segments[r]);
            if plane.sign(a, b, c) * plane.sign(a, b, d) >= 0
                || plane.sign(c, d, a) * plane.sign(c, d, b) >= 0
            {
                continue;
            }
            let (o3, o4) = (plane.exact(c, d, a), plane.exact(c, d, b));
            crossings.push(lerp(
                &plane.points[a],
                &plane.points[b],
                &(&o3 / (&o3 - &o4)),
            ));
        }
    }
    for p in &crossings {
        plane.add(p);
    }
    // Each segment split at every point on it.
    let mut edges: Vec<(usize, usize)> = Vec::new();
    let mut contact_edges: Vec<(usize, usize)> = Vec::new();
    for (k, (&(a, b), &contact)) in segments.iter().zip(&on_contact).enumerate() {
        let pts = &plane.points;
        let along = if pts[b].0[axes.0] == pts[a].0[axes.0] {
            axes.1
        } else {
            axes.0
        };
        let (lo, hi) = {
            let (x, y) = (&pts[a].0[along], &pts[b].0[along]);
            if x <= y {
                (x, y)
            } else {
                (y, x)
            }
        };
        let (blo, bhi) = boxes[k];
        let mut on: Vec<usize> = (0..pts.len())
            .filter(|&p| {
                let [x, y] = plane.rounded[p];
                p != a
                    && p != b
                    && x >= blo[0]
                    && x <= bhi[0]
                    && y >= blo[1]
                    && y <= bhi[1]
                    && pts[p].0[along] > *lo
                    && pts[p].0[along] < *hi
                    && plane.sign(a, b, p) == 0
            })
            .collect();
        let forward = pts[a].0[along] <= pts[b].0[along];
        on.sort_by(|&x, &y| {
            let c = pts[x].0[along].cmp(&pts[y].0[along]);
            if forward {
                c
            } else {
                c.reverse()
            }
        });
        let chain: Vec<usize> = std::iter::once(a)
            .chain(on)
            .chain(std::iter::once(b))
            .collect();
        edges.extend(chain.windows(2).map(|w| (w[0], w[1])));
        if contact {
            contact_edges.extend(chain.windows(2).map(|w| (w[0], w[1])));
        }
    }
    // Points inserted into the triangle (wound counter-clockwise in the
    // projection), splitting the triangle or the edge they fall in.
    let mut tris: Vec<[usize; 3]> = vec![if st > 0 { [0, 1, 2] } else { [0, 2, 1] }];
    let sign = |a: usize, b: usize, c: usize| plane.sign(a, b, c);
    for p in 3..plane.points.len() {
        insert_point(&mut tris, p, &sign);
    }
    // Segments recovered by flips.
    for &(a, b) in &edges {
        recover_edge(&mut tris, a, b, &sign).map_err(|()| BooleanError::NonManifoldResult {
            at: rounded(&plane.points[a]),
        })?;
    }
    if st < 0 {
        for t in &mut tris {
            t.swap(1, 2);
        }
    }
    Ok(Arrangement {
        points: plane.points,
        triangles: tris,
        contact_edges,
    })
}

/// Inserts point `p` into a counter-clockwise triangulation: the triangle
/// holding it splits in three, or the two triangles beside the edge it
/// lies on split in two each.
fn insert_point(tris: &mut Vec<[usize; 3]>, p: usize, sign: &dyn Fn(usize, usize, usize) -> i8) {
    for ti in 0..tris.len() {
        let [a, b, c] = tris[ti];
        let s = [sign(a, b, p), sign(b, c, p), sign(c, a, p)];
        if s.contains(&-1) {
            continue;
        }
        match s.iter().filter(|&&x| x == 0).count() {
            0 => {
                tris[ti] = [a, b, p];
                tris.push([b, c, p]);
                tris.push([c, a, p]);
            }
            1 => {
                let k = s.iter().position(|&x| x == 0).expect("one zero");
                let (x, y, z) = ([a, b, c][k], [a, b, c][(k + 1) % 3], [a, b, c][(k + 2) % 3]);
                tris[ti] = [x, p, z];
                tris.push([p, y, z]);
                if let Some(tj) = tris.iter().position(|t| has_directed(t, y, x)) {
                    let w = third(&tris[tj], y, x);
                    tris[tj] = [y, p, w];
                    tris.push([p, x, w]);
                }
            }
            // On a vertex: points are distinct, so never.
            _ => {}
        }
        return;
    }
}

fn has_directed(t: &[usize; 3], a: usize, b: usize) -> bool {
    (0..3).any(|k| t[k] == a && t[(k + 1) % 3] == b)
}

/// The corner of triangle `t` that is neither `a` nor `b`.
fn third<T: Copy + PartialEq>(t: &[T], a: T, b: T) -> T {
    *t.iter().find(|&&v| v != a && v != b).expect("a triangle")
}

/// Makes `a b` an edge of the triangulation by flipping the edges that
/// cross it (Sloan's queue: a crossing edge whose quadrilateral is not
/// convex waits its turn). No point lies inside `a b`, and no other
/// constraint crosses it, so constraints are never flipped.
fn recover_edge(
    tris: &mut [[usize; 3]],
    a: usize,
    b: usize,
    sign: &dyn Fn(usize, usize, usize) -> i8,
) -> Result<(), ()> {
    let has_edge = |tris: &[[usize; 3]]| {
        tris.iter()
            .any(|t| has_directed(t, a, b) || has_directed(t, b, a))
    };
    if has_edge(tris) {
        return Ok(());
    }
    let crosses = |c: usize, d: usize| {
        c != a
            && c != b
            && d != a
            && d != b
            && sign(a, b, c) * sign(a, b, d) < 0
            && sign(c, d, a) * sign(c, d, b) < 0
    };
    let mut queue: VecDeque<(usize, usize)> = VecDeque::new();
    for t in tris.iter() {
        for k in 0..3 {
            let (c, d) = (t[k], t[(k + 1) % 3]);
            if c < d && crosses(c, d) {
                queue.push_back((c, d));
            }
        }
    }
    let mut budget = 64 * (queue.len() + 1) * (queue.len() + 1) + 1024;
    while let Some((c, d)) = queue.pop_front() {
        budget = budget.checked_sub(1).ok_or(())?;
        let t1 = tris.iter().position(|t| has_directed(t, c, d)).ok_or(())?;
        let t2 = tris.iter().position(|t| has_directed(t, d, c)).ok_or(())?;
        let (e, f) = (third(&tris[t1], c, d), third(&tris[t2], d, c));
        if sign(e, f, c) * sign(e, f, d) < 0 {
            tris[t1] = [e, c, f];
            tris[t2] = [f, d, e];
            if crosses(e, f) {
                queue.push_back((e, f));
            }
        } else {
            queue.push_back((c, d));
        }
    }
    if has_edge(tris) {
        Ok(())
    } else {
        Err(())
    }
}

/// [`ray_crossings`] decided in floating point where the error bounds
/// allow (the ray far from the triangle's edges and plane): `None` where
/// they do not. `cf` is `c` rounded.
fn ray_crossings_filtered(u: [DVec3; 3], cf: DVec3) -> Option<[i32; 2]> {
    const BOUND: f64 = 16.0 * f64::EPSILON;
    let nx = sign(robust::orient2d(
        robust::Coord {
            x: u[0].y,
            y: u[0].z,
        },
        robust::Coord {
            x: u[1].y,
            y: u[1].z,
        },
        robust::Coord {
            x: u[2].y,
            y: u[2].z,
        },
    ));
    if nx == 0 {
        return Some([0, 0]);
    }
    let c_size = cf.y.abs() + cf.z.abs();
    let mut s0 = 0;
    for e in 0..3 {
        let (a, b) = (u[e], u[(e + 1) % 3]);
        let (gy, gz) = (b.y - a.y, b.z - a.z);
        let (dy, dz) = (cf.y - a.y, cf.z - a.z);
        let o = gy * dz - gz * dy;
        let err = BOUND * ((gy * dz).abs() + (gz * dy).abs() + (gy.abs() + gz.abs()) * c_size);
        if o.abs() <= err {
            return None;
        }
        let s = sign(o);
        if s0 != 0 && s != s0 {
            return Some([0, 0]);
        }
        s0 = s;
    }
    let (e1, e2, d) = (u[1] - u[0], u[2] - u[0], cf - u[0]);
    let n = e1.cross(e2);
    let f = n.dot(d);
    let size = e1.abs().dot(DVec3::ONE) * e2.abs().dot(DVec3::ONE);
    let err = BOUND * size * (d.abs().dot(DVec3::ONE) + cf.abs().dot(DVec3::ONE));
    if f.abs() <= err {
        return None;
    }
    let crosses = sign(f) == -nx;
    Some(if crosses { [nx as i32; 2] } else { [0, 0] })
}

/// Crossing sign of the ray from `c + εm + ε²x̂ + ε³ŷ + ε⁴ẑ` along +x with
/// triangle `u`: ±1 (the sign of u's normal's x) when it passes through,
/// 0 otherwise; for `m` and `−m` at once.
fn ray_crossings(u: &[P3; 3], c: &P3, m: &V3) -> [i32; 2] {
    let n = normal(u);
    let nx = sgn(&n[0]);
    if nx == 0 {
        return [0, 0];
    }
    let mut out = [0i32; 2];
    for (k, flip) in [(0, false), (1, true)] {
        let first = |mut co: [Q; 5], len: usize| {
            if flip {
                co[1] = -co[1].clone();
            }
            first_sign(&co[..len])
        };
        let mut inside = true;
        let mut s0 = 0i8;
        for e in 0..3 {
            let (a, b) = (&u[e], &u[(e + 1) % 3]);
            let gy = -(&b.0[2] - &a.0[2]);
            let gz = &b.0[1] - &a.0[1];
            let s = first(
                [
                    orient2(a, b, c, (1, 2)),
                    &gy * &m[1] + &gz * &m[2],
                    gy,
                    gz,
                    Q::zero(),
                ],
                4,
            );
            if s == 0 || (s0 != 0 && s != s0) {
                inside = false;
                break;
            }
            s0 = s;
        }
        if !inside {
            continue;
        }
        let side = first(
            [
                dot(&n, &sub(c, &u[0])),
                dot(&n, m),
                n[0].clone(),
                n[1].clone(),
                n[2].clone(),
            ],
            5,
        );
        if side == -nx {
            out[k] = nx as i32;
        }
    }
    out
}

/// The winding number at `c` (off the surface) of the closed shells whose
/// triangles `tree` holds: crossings of the ray along +x, each decided in
/// floating point where the bounds allow and exactly (with the symbolic
/// perturbation of [`ray_crossings`]) where not. O(log n) boxes a ray for
/// a well-spread surface, where summing solid angles reads every triangle.
pub(super) fn ray_winding(tree: &Bvh, corners: &dyn Fn(u32) -> [DVec3; 3], c: DVec3) -> i32 {
    let pad = DVec3::splat(1e-9) * (1.0 + c.abs());
    let hi = DVec3::new(f64::INFINITY, c.y + pad.y, c.z + pad.z);
    let still = [Q::zero(), Q::zero(), Q::zero()];
    let mut exact_c: Option<P3> = None;
    tree.overlapping(c - pad, hi)
        .into_iter()
        .map(|t| {
            let f = corners(t);
            ray_crossings_filtered(f, c).unwrap_or_else(|| {
                let cq = exact_c.get_or_insert_with(|| exact(c));
                ray_crossings(&f.map(exact), cq, &still)
            })[0]
        })
        .sum()
}

/// Whether `c` lies on triangle `t` (on its plane, inside or on its
/// boundary).
fn on_triangle(t: &[P3; 3], c: &P3) -> bool {
    let n = normal(t);
    if !dot(&n, &sub(c, &t[0])).is_zero() {
        return false;
    }
    let axes = kept(dominant_axis(&n));
    let s: Vec<i8> = (0..3)
        .map(|e| orient2_sign(&t[e], &t[(e + 1) % 3], c, axes))
        .collect();
    !(s.contains(&1) && s.contains(&-1))
}

/// Computes `operation` in exact arithmetic (see the module docs); `tris`
/// are `input`'s triangles, both operands closed.
pub(super) fn boolean(
    input: &Input,
    tris: &[Tri],
    operation: Operation,
) -> Result<Output, BooleanError> {
    bounded(input, tris, operation, CONTACT_WORK_LIMIT)
}

/// [`boolean`] with the bound on its work given.
pub(super) fn bounded(
    input: &Input,
    tris: &[Tri],
    operation: Operation,
    work_limit: u64,
) -> Result<Output, BooleanError> {
    let points = &input.points;
    let corners_f = |t: u32| tris[t as usize].v.map(|i| points[i as usize]);
    // Exact coordinates of the input points, made as they are needed (most
    // are not: faces far from the contacts only need their labels).
    let exact_input: Vec<std::cell::OnceCell<P3>> = (0..points.len())
        .map(|_| std::cell::OnceCell::new())
        .collect();
    let ex = |i: u32| exact_input[i as usize].get_or_init(|| exact(points[i as usize]));
    let corners_q = |t: u32| tris[t as usize].v.map(|i| ex(i).clone());
    // And of the points the contacts make, in result order after the
    // input's.
    let mut made: Vec<P3> = Vec::new();
    let (a_tris, b_tris): (Vec<u32>, Vec<u32>) =
        (0..tris.len() as u32).partition(|&t| tris[t as usize].operand == Operand::A);
    let tree_a = Bvh::new(&a_tris, |t| bounds(&corners_f(t)));
    let tree_b = Bvh::new(&b_tris, |t| bounds(&corners_f(t)));
    // 1. Contacts per triangle.
    let mut contacts: FxHashMap<u32, Vec<(P3, P3)>> = FxHashMap::default();
    let mut candidates = tree_a.overlapping_pairs(&tree_b);
    candidates.sort_unstable();
    for (ta, tb) in candidates {
        let (fa, fb) = (corners_f(ta), corners_f(tb));
        let (la, ha) = bounds(&fa);
        let (lb, hb) = bounds(&fb);
        if la.cmpgt(hb).any() || lb.cmpgt(ha).any() {
            continue;
        }
        // Exact and in floating point: most pairs whose boxes meet do not.
        if !triangle_triangle_exact(fa, fb) {
            continue;
        }
        let found = contact(&corners_q(ta), fa, &corners_q(tb), fb);
        if found.is_empty() {
            continue;
        }
        contacts
            .entry(ta)
            .or_default()
            .extend(found.iter().cloned());
        contacts.entry(tb).or_default().extend(found);
    }

    // 2. Result points: the input's (coincident ones merged into the
    // first), then the contacts' new ones.
    let mut out = Output {
        points: points.clone(),
        sources: (0..points.len() as u32).map(PointSource::Input).collect(),
        polygons: Vec::new(),
    };
    // Cutting a triangle is quadratic in its contacts (segment pairs,
    // point location by scan): bounded before any of it starts.
    let work: u64 = contacts.values().map(|c| (c.len() as u64).pow(2)).sum();
    if work > work_limit {
        let (&t, c) = contacts
            .iter()
            .max_by_key(|(&t, c)| (c.len(), std::cmp::Reverse(t)))
            .expect("work > 0");
        let [a, b, cc] = corners_f(t);
        return Err(BooleanError::TooManyContacts {
            at: (a + b + cc) / 3.0,
            contacts: c.len(),
        });
    }
    // Coincident input points of touched triangles (a corner of each
    // operand at one place) become one, the first in triangle order.
    let mut index: FxHashMap<P3, u32> = FxHashMap::default();
    let mut representative: Vec<u32> = (0..points.len() as u32).collect();
    {
        let mut touched: Vec<u32> = contacts.keys().copied().collect();
        touched.sort_unstable();
        for t in touched {
            for v in tris[t as usize].v {
                representative[v as usize] = *index.entry(ex(v).clone()).or_insert(v);
            }
        }
    }

    // Faces to label: pieces of touched polygons, then untouched polygons
    // whole; each with one of its triangles (exact) for the label.
    struct Face {
        ring: Vec<u32>,
        /// A piece's corners, or the input triangle (converted only if
        /// its patch is labelled by it).
        triangle: Result<[P3; 3], u32>,
        polygon: u32,
        whole: bool,
        /// An input triangle that its contacts left as it was (they only
        /// touch its corners or edges without a point on them).
        intact: bool,
    }
    let mut faces: Vec<Face> = Vec::new();
    // Result edges on a contact: a patch ends there.
    let mut contact_edges: rustc_hash::FxHashSet<(u32, u32)> = Default::default();
    let mut cut_polygon = vec![false; input.polygons.len()];
    let mut touched: Vec<u32> = contacts.keys().copied().collect();
    touched.sort_unstable();
    for &t in &touched {
        cut_polygon[tris[t as usize].polygon as usize] = true;
    }
    for (t, tri) in tris.iter().enumerate() {
        let t = t as u32;
        if !cut_polygon[tri.polygon as usize] {
            continue;
        }
        let Some(found) = contacts.get(&t) else {
            faces.push(Face {
                ring: tri.v.map(|v| representative[v as usize]).to_vec(),
                triangle: Err(t),
                polygon: tri.polygon,
                whole: false,
                intact: true,
            });
            continue;
        };
        let cut = arrange(&corners_q(t), found)?;
        let ids: Vec<u32> = cut
            .points
            .iter()
            .map(|p| {
                *index.entry(p.clone()).or_insert_with(|| {
                    out.points.push(rounded(p));
                    made.push(p.clone());
                    out.sources.push(PointSource::Crossing(tri.v[0], tri.v[1]));
                    (out.points.len() - 1) as u32
                })
            })
            .collect();
        for &(i, j) in &cut.contact_edges {
            let (a, b) = (ids[i], ids[j]);
            contact_edges.insert((a.min(b), a.max(b)));
        }
        let intact = cut.points.len() == 3;
        for l in cut.triangles {
            faces.push(Face {
                intact,
                ring: l.map(|i| ids[i]).to_vec(),
                triangle: Ok(l.map(|i| cut.points[i].clone())),
                polygon: tri.polygon,
                whole: false,
            });
        }
    }
    let mut first_tri: Vec<Option<u32>> = vec![None; input.polygons.len()];
    for (t, tri) in tris.iter().enumerate() {
        first_tri[tri.polygon as usize].get_or_insert(t as u32);
    }
    for (k, (ring, _)) in input.polygons.iter().enumerate() {
        if let Some(t) = first_tri[k].filter(|_| !cut_polygon[k]) {
            faces.push(Face {
                ring: ring.iter().map(|&v| representative[v as usize]).collect(),
                triangle: Err(t),
                polygon: k as u32,
                whole: true,
                intact: true,
            });
        }
    }
    let operand_of = |f: &Face| input.polygons[f.polygon as usize].1;
    // 3. Patches: faces of one operand joined across edges off the
    // contacts, where neither operand's winding number changes; each
    // labelled once.
    let mut patches = crate::geom::union_find::UnionFind::new(faces.len());
    {
        let mut seen: FxHashMap<(u32, u32, bool), u32> = FxHashMap::default();
        for (i, f) in faces.iter().enumerate() {
            let n = f.ring.len();
            for k in 0..n {
                let (a, b) = (f.ring[k], f.ring[(k + 1) % n]);
                let key = (a.min(b), a.max(b));
                if contact_edges.contains(&key) {
                    continue;
                }
                match seen.entry((key.0, key.1, operand_of(f) == Operand::A)) {
                    std::collections::hash_map::Entry::Occupied(o) => {
                        patches.union(*o.get(), i as u32)
                    }
                    std::collections::hash_map::Entry::Vacant(v) => {
                        v.insert(i as u32);
                    }
                }
            }
        }
    }
    let inside = |w: (i32, i32)| {
        let (a, b) = (w.0 > 0, w.1 > 0);
        match operation {
            Operation::Union => a || b,
            Operation::Intersection => a && b,
            Operation::Difference => a && !b,
        }
    };
    let third_q = Q::new(1.into(), 3.into());
    // `Some(reversed)` when a face with this triangle bounds the result.
    let verdict = |corners: &[P3; 3], operand: Operand| -> Option<bool> {
        let sum = [0, 1, 2].map(|k| &corners[0].0[k] + &corners[1].0[k] + &corners[2].0[k]);
        let c = P3(sum.map(|x| x * &third_q));
        let cf = rounded(&c);
        let pad = DVec3::splat(1e-9) * (1.0 + cf.abs());
        if operand == Operand::B
            && tree_a
                .overlapping(cf - pad, cf + pad)
                .into_iter()
                .any(|t| on_triangle(&corners_q(t), &c))
        {
            // On the selection's surface: its own faces there decide.
            return None;
        }
        let n = normal(corners);
        let mut w = [(0i32, 0i32); 2];
        let ray_hi = DVec3::new(f64::INFINITY, cf.y + pad.y, cf.z + pad.z);
        for (tree, is_a) in [(&tree_a, true), (&tree_b, false)] {
            for t in tree.overlapping(cf - pad, ray_hi) {
                let s = ray_crossings_filtered(corners_f(t), cf)
                    .unwrap_or_else(|| ray_crossings(&corners_q(t), &c, &n));
                for k in 0..2 {
                    if is_a {
                        w[k].0 += s[k];
                    } else {
                        w[k].1 += s[k];
                    }
                }
            }
        }
        let (front, back) = (inside(w[0]), inside(w[1]));
        (front != back).then_some(front)
    };
    let mut label: FxHashMap<u32, Option<bool>> = FxHashMap::default();
    // Kept pieces by polygon, in order: (face, reversed).
    let mut kept: Vec<(usize, bool)> = Vec::new();
    for (i, f) in faces.iter().enumerate() {
        let root = patches.find(i as u32);
        let reversed = *label.entry(root).or_insert_with(|| match &f.triangle {
            Ok(corners) => verdict(corners, operand_of(f)),
            Err(t) => verdict(&corners_q(*t), operand_of(f)),
        });
        if let Some(reversed) = reversed {
            kept.push((i, reversed));
        }
    }
    let mut triangles_of = vec![0usize; input.polygons.len()];
    for tri in tris {
        triangles_of[tri.polygon as usize] += 1;
    }
    let emit = |ring: Vec<u32>, polygon: u32, whole: bool, reversed: bool, out: &mut Output| {
        let mut ring = ring;
        let whole = whole && ring == input.polygons[polygon as usize].0;
        if reversed {
            ring.reverse();
        }
        out.polygons.push(OutPolygon {
            ring,
            source: polygon,
            whole,
            reversed,
        });
    };
    for run in kept.chunk_by(|x, y| faces[x.0].polygon == faces[y.0].polygon) {
        let polygon = faces[run[0].0].polygon;
        let reversed = run[0].1;
        // A touched polygon whose contacts left every triangle as it was
        // and that is kept whole one way: the polygon, not its triangles.
        let unchanged = run.len() == triangles_of[polygon as usize]
            && run.iter().all(|&(i, r)| faces[i].intact && r == reversed);
        if faces[run[0].0].whole || (unchanged && run.len() > 1) {
            let ring = input.polygons[polygon as usize]
                .0
                .iter()
                .map(|&v| representative[v as usize])
                .collect();
            emit(ring, polygon, true, reversed, &mut out);
        } else {
            for &(i, r) in run {
                emit(faces[i].ring.clone(), polygon, false, r, &mut out);
            }
        }
    }
    out.polygons.sort_by_key(|p| (p.source, !p.whole));
    // 4. Where solids touch along an edge or at a point, each gets its
    // own copy.
    let n_input = points.len();
    let exact_of = |i: u32| match (i as usize).checked_sub(n_input) {
        None => ex(i).clone(),
        Some(k) => made[k].clone(),
    };
    split_touching(&mut out, &exact_of)?;
    collapse_rounded_edges(&mut out, n_input);
    flip_rounded_caps(&mut out, n_input);
    Ok(out)
}

/// Distinct exact points can lie closer than f64 resolves (a crossing
/// 1e-16 from another): rounded, their thin triangles may fold over and
/// cross their neighbours. Each edge with a made point at one end that
/// rounding left a few ulps long is collapsed onto its other end (an
/// input point where there is one) where the link condition holds — the
/// two triangles on the edge go, the surface stays closed and manifold.
pub(super) fn collapse_rounded_edges(out: &mut Output, n_input: usize) {
    let close = |a: DVec3, b: DVec3| {
        let scale = a.abs().max(b.abs()).max_element().max(f64::MIN_POSITIVE);
        (a - b).abs().max_element() <= 8.0 * f64::EPSILON * scale
    };
    let mut candidates: Vec<(u32, u32)> = Vec::new();
    for p in &out.polygons {
        let n = p.ring.len();
        for k in 0..n {
            let (a, b) = (p.ring[k], p.ring[(k + 1) % n]);
            let made = a as usize >= n_input || b as usize >= n_input;
            if a < b && made && close(out.points[a as usize], out.points[b as usize]) {
                candidates.push((a, b));
            }
        }
    }
    if candidates.is_empty() {
        return;
    }
    candidates.sort_unstable();
    let mut polygons_of: FxHashMap<u32, Vec<usize>> = FxHashMap::default();
    for (i, p) in out.polygons.iter().enumerate() {
        for &v in &p.ring {
            polygons_of.entry(v).or_default().push(i);
        }
    }
    let mut removed = vec![false; out.polygons.len()];
    let mut dead: rustc_hash::FxHashSet<u32> = Default::default();
    for (a, b) in candidates {
        if dead.contains(&a) || dead.contains(&b) {
            continue;
        }
        // Keep the input point (or the lower index).
        let (keep, gone) = if b as usize >= n_input {
            (a, b)
        } else {
            (b, a)
        };
        let live = |v: u32, removed: &[bool]| -> Vec<usize> {
            polygons_of[&v]
                .iter()
                .copied()
                .filter(|&i| !removed[i])
                .collect()
        };
        let (pk, pg) = (live(keep, &removed), live(gone, &removed));
        let shared: Vec<usize> = pg.iter().copied().filter(|i| pk.contains(i)).collect();
        if shared.len() != 2 || shared.iter().any(|&i| out.polygons[i].ring.len() != 3) {
            continue;
        }
        let neighbours = |v: u32, list: &[usize]| -> rustc_hash::FxHashSet<u32> {
            let mut set = rustc_hash::FxHashSet::default();
            for &i in list {
                let r = &out.polygons[i].ring;
                let k = r.iter().position(|&x| x == v).expect("on it");
                set.insert(r[(k + 1) % r.len()]);
                set.insert(r[(k + r.len() - 1) % r.len()]);
            }
            set
        };
        let (nk, ng) = (neighbours(keep, &pk), neighbours(gone, &pg));
        let common: Vec<u32> = nk.iter().copied().filter(|v| ng.contains(v)).collect();
        let opposite: Vec<u32> = shared
            .iter()
            .map(|&i| third(&out.polygons[i].ring, keep, gone))
            .collect();
        if common.len() != 2 || !opposite.iter().all(|v| common.contains(v)) {
            continue;
        }
        for &i in &shared {
            removed[i] = true;
        }
        for &i in &pg {
            if removed[i] {
                continue;
            }
            for v in &mut out.polygons[i].ring {
                if *v == gone {
                    *v = keep;
                }
            }
            out.polygons[i].whole = false;
            polygons_of.get_mut(&keep).expect("listed").push(i);
        }
        dead.insert(gone);
    }
    let mut k = 0;
    out.polygons.retain(|_| {
        k += 1;
        !removed[k - 1]
    });
}

/// A made point a few ulps from the far edge of its triangle (a crossing
/// that lies 1e-17 off an edge in exact arithmetic) leaves a flat
/// triangle once rounded, and the long edge then passes the wrong side of
/// the point. The long edge is flipped to end at the point instead, where
/// both new triangles come out wound as the old ones (Shewchuk's cure for
/// caps), until no such triangle is left.
pub(super) fn flip_rounded_caps(out: &mut Output, n_input: usize) {
    let pos = |v: u32, out: &Output| out.points[v as usize];
    // A flat triangle with a made corner across its longest edge: that
    // edge (u, v) and the corner w.
    let cap = |ring: &[u32], out: &Output| -> Option<(u32, u32, u32)> {
        if ring.len() != 3 || ring.iter().all(|&v| (v as usize) < n_input) {
            return None;
        }
        let len = |k: usize| (pos(ring[(k + 1) % 3], out) - pos(ring[k], out)).length();
        let k = (0..3).max_by(|&x, &y| len(x).total_cmp(&len(y)))?;
        let (u, v, w) = (ring[k], ring[(k + 1) % 3], ring[(k + 2) % 3]);
        let (pu, pv, pw) = (pos(u, out), pos(v, out), pos(w, out));
        let scale = pu.abs().max(pv.abs()).max(pw.abs()).max_element();
        let flat = (pv - pu).cross(pw - pu).length() <= 32.0 * f64::EPSILON * len(k) * scale;
        (flat && w as usize >= n_input).then_some((u, v, w))
    };
    // The edge table only where some cap is (almost never: not on the
    // general path's hot loop).
    let mut edge: Option<FxHashMap<(u32, u32), usize>> = None;
    for _pass in 0..4 {
        let caps: Vec<usize> = (0..out.polygons.len())
            .filter(|&i| cap(&out.polygons[i].ring, out).is_some())
            .collect();
        if caps.is_empty() {
            break;
        }
        let edge = edge.get_or_insert_with(|| {
            let mut map = FxHashMap::default();
            for (i, p) in out.polygons.iter().enumerate() {
                let n = p.ring.len();
                for k in 0..n {
                    map.insert((p.ring[k], p.ring[(k + 1) % n]), i);
                }
            }
            map
        });
        let mut flipped = false;
        for i in caps {
            // (An earlier flip of this pass may have changed it.)
            let Some((u, v, w)) = cap(&out.polygons[i].ring, out) else {
                continue;
            };
            let Some(&j) = edge.get(&(v, u)) else {
                continue;
            };
            let rj = out.polygons[j].ring.clone();
            if rj.len() != 3 {
                continue;
            }
            let x = third(&rj, u, v);
            if edge.contains_key(&(w, x)) {
                continue;
            }
            let (pu, pv, pw, px) = (pos(u, out), pos(v, out), pos(w, out), pos(x, out));
            let n = (pu - pv).cross(px - pv);
            let wound = |a: DVec3, b: DVec3, c: DVec3| (b - a).cross(c - a).dot(n) > 0.0;
            if !(wound(pu, px, pw) && wound(px, pv, pw)) {
                continue;
            }
            for (a, b) in [(u, v), (v, w), (w, u), (v, u), (u, x), (x, v)] {
                edge.remove(&(a, b));
            }
            out.polygons[i].ring = vec![u, x, w];
            out.polygons[j].ring = vec![x, v, w];
            for (a, b, p) in [
                (u, x, i),
                (x, w, i),
                (w, u, i),
                (x, v, j),
                (v, w, j),
                (w, x, j),
            ] {
                edge.insert((a, b), p);
            }
            out.polygons[i].whole = false;
            out.polygons[j].whole = false;
            flipped = true;
        }
        if !flipped {
            break;
        }
    }
}

/// One use of an edge: polygon, corner where the edge starts.
type Use = (usize, usize);

/// Makes the result a manifold surface where its solids (or a solid and
/// a cavity) touch: the faces around an edge used more than twice are
/// paired across the solid wedges between them (sorted about the edge
/// exactly), then every point whose corners fall into several fans gets a
/// copy per fan after the first (as Manifold's output has them).
fn split_touching(out: &mut Output, at: &dyn Fn(u32) -> P3) -> Result<(), BooleanError> {
    let polys = &out.polygons;
    let mut uses: FxHashMap<(u32, u32), Vec<Use>> = FxHashMap::default();
    for (p, poly) in polys.iter().enumerate() {
        let n = poly.ring.len();
        for k in 0..n {
            let (a, b) = (poly.ring[k], poly.ring[(k + 1) % n]);
            uses.entry((a.min(b), a.max(b))).or_default().push((p, k));
        }
    }
    let mut keys: Vec<(u32, u32)> = uses.keys().copied().collect();
    keys.sort_unstable();
    let error = |v: u32, out: &Output| BooleanError::NonManifoldResult {
        at: out.points[v as usize],
    };
    // Corners (polygon, position) joined across paired edges.
    let offsets: Vec<usize> = polys
        .iter()
        .scan(0, |acc, p| {
            let start = *acc;
            *acc += p.ring.len();
            Some(start)
        })
        .collect();
    let corner = |(p, k): Use| offsets[p] + k % polys[p].ring.len();
    let total = polys.iter().map(|p| p.ring.len()).sum();
    let mut fans = crate::geom::union_find::UnionFind::new(total);
    let mut pairs: Vec<(Use, Use)> = Vec::new();
    for (a, b) in keys {
        let list = &uses[&(a, b)];
        let forward = |&(p, k): &Use| polys[p].ring[k] == a;
        let fwd = list.iter().filter(|u| forward(u)).count();
        if fwd * 2 != list.len() {
            return Err(error(a, out));
        }
        if list.len() == 2 {
            let (f, r) = if forward(&list[0]) {
                (list[0], list[1])
            } else {
                (list[1], list[0])
            };
            pairs.push((f, r));
            continue;
        }
        // About the edge a → b: each face's direction away from it, in a
        // plane across it, sorted counter-clockwise (seen from b).
        let (pa, pb) = (at(a), at(b));
        let e = sub(&pb, &pa);
        let w = {
            let m = e.clone().map(|x| x.abs());
            let axis = if m[0] <= m[1] && m[0] <= m[2] {
                0
            } else if m[1] <= m[2] {
                1
            } else {
                2
            };
            let mut w: V3 = [Q::zero(), Q::zero(), Q::zero()];
            w[axis] = Q::from_integer(1.into());
            w
        };
        let u = cross(&e, &w);
        let v = cross(&e, &u);
        let mut around: Vec<(Q, Q, Use)> = list
            .iter()
            .map(|&(p, k)| {
                let ring = &polys[p].ring;
                let n = ring.len();
                // The corner after the edge (before it, for a reverse use).
                let c = if forward(&(p, k)) {
                    ring[(k + 2) % n]
                } else {
                    ring[(k + n - 1) % n]
                };
                let r = sub(&at(c), &pa);
                (dot(&r, &u), dot(&r, &v), (p, k))
            })
            .collect();
        let half = |x: &Q, y: &Q| y.is_negative() || (y.is_zero() && x.is_negative());
        around.sort_by(|p, q| {
            half(&p.0, &p.1).cmp(&half(&q.0, &q.1)).then_with(|| {
                // Counter-clockwise first: q to the left of p.
                sgn(&(&q.0 * &p.1 - &q.1 * &p.0)).cmp(&0)
            })
        });
        let n = around.len();
        for i in 0..n {
            let this = around[i].2;
            if !forward(&this) {
                continue;
            }
            // A face's solid lies clockwise of it (its normal turns its
            // direction a quarter counter-clockwise about a → b).
            let next = around[(i + n - 1) % n].2;
            let same = {
                let (x, y) = (&around[i], &around[(i + n - 1) % n]);
                half(&x.0, &x.1) == half(&y.0, &y.1) && (&x.0 * &y.1 - &x.1 * &y.0).is_zero()
            };
            if forward(&next) || same {
                return Err(error(a, out));
            }
            pairs.push((this, next));
        }
    }
    for (f, r) in pairs {
        // f runs a → b at corners k, k + 1; r runs b → a at j, j + 1.
        fans.union(corner(f) as u32, corner((r.0, r.1 + 1)) as u32);
        fans.union(corner((f.0, f.1 + 1)) as u32, corner(r) as u32);
    }
    // Points with several fans: a copy for each fan after the first.
    let mut first_fan: FxHashMap<u32, u32> = FxHashMap::default();
    let mut copy_of: FxHashMap<(u32, u32), u32> = FxHashMap::default();
    let Output {
        points,
        sources,
        polygons,
    } = out;
    for (poly, &offset) in polygons.iter_mut().zip(&offsets) {
        for k in 0..poly.ring.len() {
            let v = poly.ring[k];
            let fan = fans.find((offset + k) as u32);
            let first = *first_fan.entry(v).or_insert(fan);
            if first == fan {
                continue;
            }
            let copy = *copy_of.entry((v, fan)).or_insert_with(|| {
                points.push(points[v as usize]);
                sources.push(match sources[v as usize] {
                    PointSource::Input(i) => PointSource::Copy(i),
                    other => other,
                });
                (points.len() - 1) as u32
            });
            poly.ring[k] = copy;
            poly.whole = false;
        }
    }
    Ok(())
}
