//! Evaluation of a compiled [`Tape`] over batches of points.
//!
//! [`Evaluator`] owns all scratch (registers of `batch` lanes, the sort
//! buffer of the smooth operations), allocated once; evaluation allocates
//! nothing. [`Evaluator::eval`] is the one-point case of the same code, so
//! scalar and batched results are bit-identical. The smooth n-ary operations
//! sort their arguments then fold (decision D6), so they do not depend on
//! the order of the children.

use glam::{DVec2, DVec3};

use crate::sdf::primitives as prim;
use crate::sdf::tape::{Inst, Tape, BATCH};

/// Quadratic smooth minimum (spec §1.4, fogleman `dn.py`), with the exact
/// short cuts that make a sorted fold culling-exact: when h clamps to 1
/// the result *is* `a` (not `b + (a − b)`, which can round differently).
#[inline]
pub fn smin(a: f64, b: f64, k: f64) -> f64 {
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    if h >= 1.0 {
        a
    } else if h <= 0.0 {
        b
    } else {
        b + (a - b) * h - k * h * (1.0 - h)
    }
}

/// Smooth minimum of all `v` (sorted ascending in place, then folded).
/// Bit-identical for any permutation of `v`; stops as soon as the next
/// value is ≥ the accumulator + k (it and all later ones change nothing).
#[inline]
pub fn smin_sorted(v: &mut [f64], k: f64) -> f64 {
    insertion_sort(v);
    let mut acc = v[0];
    for &b in &v[1..] {
        if b - acc >= k {
            break;
        }
        acc = smin(acc, b, k);
    }
    acc
}

/// Ascending insertion sort by `total_cmp` (the argument lists are short).
#[inline]
pub fn insertion_sort(v: &mut [f64]) {
    for i in 1..v.len() {
        let x = v[i];
        let mut j = i;
        while j > 0 && v[j - 1].total_cmp(&x).is_gt() {
            v[j] = v[j - 1];
            j -= 1;
        }
        v[j] = x;
    }
}

/// Per-thread evaluation state of a [`Tape`] (all scratch preallocated).
pub struct Evaluator<'t> {
    tape: &'t Tape,
    vals: Vec<Vec<f64>>,
    pts: Vec<[Vec<f64>; 3]>,
    sort: Vec<f64>,
}

impl<'t> Evaluator<'t> {
    /// A fresh evaluator of `tape` with its scratch allocated.
    pub(super) fn new(tape: &'t Tape) -> Evaluator<'t> {
        Evaluator {
            tape,
            vals: vec![vec![0.0; BATCH]; tape.n_vals],
            pts: (0..tape.n_pts)
                .map(|_| [vec![0.0; BATCH], vec![0.0; BATCH], vec![0.0; BATCH]])
                .collect(),
            sort: Vec::with_capacity(tape.max_args),
        }
    }
}

impl Evaluator<'_> {
    /// f at one point (the batched code with one lane).
    pub fn eval(&mut self, p: DVec3) -> f64 {
        let mut out = [0.0];
        self.eval_many(&[p.x], &[p.y], &[p.z], &mut out);
        out[0]
    }

    /// f at every point of an array.
    pub fn eval_points(&mut self, ps: &[DVec3], out: &mut [f64]) {
        for (chunk, o) in ps.chunks(BATCH).zip(out.chunks_mut(BATCH)) {
            let n = chunk.len();
            for (i, p) in chunk.iter().enumerate() {
                self.pts[0][0][i] = p.x;
                self.pts[0][1][i] = p.y;
                self.pts[0][2][i] = p.z;
            }
            self.run(n);
            o.copy_from_slice(&self.vals[self.tape.out as usize][..n]);
        }
    }

    /// f at points given as three coordinate slices (structure of arrays).
    pub fn eval_many(&mut self, xs: &[f64], ys: &[f64], zs: &[f64], out: &mut [f64]) {
        let n_all = xs.len().min(ys.len()).min(zs.len()).min(out.len());
        let mut s = 0;
        while s < n_all {
            let n = (n_all - s).min(BATCH);
            self.pts[0][0][..n].copy_from_slice(&xs[s..s + n]);
            self.pts[0][1][..n].copy_from_slice(&ys[s..s + n]);
            self.pts[0][2][..n].copy_from_slice(&zs[s..s + n]);
            self.run(n);
            out[s..s + n].copy_from_slice(&self.vals[self.tape.out as usize][..n]);
            s += n;
        }
    }

    fn run(&mut self, n: usize) {
        let tape = self.tape;
        for inst in &tape.insts {
            match inst {
                Inst::Affine { src, dst, m, t } => {
                    let [mut x, mut y, mut z] = std::mem::take(&mut self.pts[*dst as usize]);
                    let s = &self.pts[*src as usize];
                    let (c0, c1, c2) = (m.x_axis, m.y_axis, m.z_axis);
                    for i in 0..n {
                        let (px, py, pz) = (s[0][i], s[1][i], s[2][i]);
                        x[i] = c0.x * px + c1.x * py + c2.x * pz + t.x;
                        y[i] = c0.y * px + c1.y * py + c2.y * pz + t.y;
                        z[i] = c0.z * px + c1.z * py + c2.z * pz + t.z;
                    }
                    self.pts[*dst as usize] = [x, y, z];
                }
                Inst::Sphere { p, o, r } => self.leaf(*p, *o, n, |q| prim::sphere(q, *r)),
                Inst::Cuboid { p, o, h } => self.leaf(*p, *o, n, |q| prim::cuboid(q, *h)),
                Inst::RoundedBox { p, o, h, r } => {
                    self.leaf(*p, *o, n, |q| prim::rounded_box(q, *h, *r))
                }
                Inst::Torus { p, o, big, small } => {
                    self.leaf(*p, *o, n, |q| prim::torus(q, *big, *small))
                }
                Inst::PolyTorus { p, o, t } => self.leaf(*p, *o, n, |q| t.eval(q)),
                Inst::Cylinder { p, o, r, h } => {
                    self.leaf(*p, *o, n, |q| prim::cylinder(q, *r, *h))
                }
                Inst::Cone { p, o, h, r1, r2 } => {
                    self.leaf(*p, *o, n, |q| prim::capped_cone(q, *h, *r1, *r2))
                }
                Inst::Prism {
                    p,
                    o,
                    a,
                    ca,
                    sa,
                    r,
                    h,
                } => self.leaf(*p, *o, n, |q| {
                    prim::extrude(
                        prim::ngon2_with(DVec2::new(q.x, q.y), *a, *ca, *sa, *r),
                        q.z,
                        *h,
                    )
                }),
                Inst::Pyramid { p, o, t } => self.leaf(*p, *o, n, |q| t.eval(q)),
                Inst::Capsule { p, o, a, b, r } => {
                    self.leaf(*p, *o, n, |q| prim::capsule(q, *a, *b, *r))
                }
                Inst::RoundCone { p, o, c } => self.leaf(*p, *o, n, |q| c.eval(q)),
                Inst::HalfSpace { p, o, n: nn, d } => self.leaf(*p, *o, n, |q| nn.dot(q) - *d),
                Inst::Mesh { p, o, mesh } => {
                    let field = &tape.meshes[*mesh as usize];
                    let mut out = std::mem::take(&mut self.vals[*o as usize]);
                    let s = &self.pts[*p as usize];
                    // Lipschitz warm start from the previous lane (spec
                    // §1.7.3) and its nearest triangle as the seed. (A
                    // 4-lane packet traversal was tried: 1.6× more
                    // instructions under callgrind, so not kept.)
                    let mut prev: Option<(DVec3, f64)> = None;
                    let mut seed = None;
                    for (i, slot) in out.iter_mut().enumerate().take(n) {
                        let q = DVec3::new(s[0][i], s[1][i], s[2][i]);
                        let bound = prev.map(|(pp, d)| d + (q - pp).length());
                        let (d, signed) = field.signed_distance_seeded(q, bound, &mut seed);
                        prev = Some((q, d));
                        *slot = signed;
                    }
                    self.vals[*o as usize] = out;
                }
                Inst::Min { a, b, o } => self.binary(*a, *b, *o, n, f64::min),
                Inst::Max { a, b, o } => self.binary(*a, *b, *o, n, f64::max),
                Inst::MaxNeg { a, b, o } => self.binary(*a, *b, *o, n, |x, y| x.max(-y)),
                Inst::Mul { a, c, o } => self.unary(*a, *o, n, |x| x * *c),
                Inst::Sub { a, c, o } => self.unary(*a, *o, n, |x| x - *c),
                Inst::AbsSub { a, c, o } => self.unary(*a, *o, n, |x| x.abs() - *c),
                Inst::PlaneMax { a, p, n: nn, d, o } => {
                    let mut out = std::mem::take(&mut self.vals[*o as usize]);
                    let va = &self.vals[*a as usize];
                    let s = &self.pts[*p as usize];
                    for i in 0..n {
                        let plane = nn.x * s[0][i] + nn.y * s[1][i] + nn.z * s[2][i] - *d;
                        out[i] = va[i].max(plane);
                    }
                    self.vals[*o as usize] = out;
                }
                Inst::SmoothMin { start, len, k, o }
                | Inst::SmoothMax { start, len, k, o }
                | Inst::SmoothDiff { start, len, k, o } => {
                    let args = &tape.args[*start as usize..(*start + *len) as usize];
                    let mut out = std::mem::take(&mut self.vals[*o as usize]);
                    let mut buf = std::mem::take(&mut self.sort);
                    let kind = match inst {
                        Inst::SmoothMin { .. } => 0,
                        Inst::SmoothMax { .. } => 1,
                        _ => 2,
                    };
                    for (i, slot) in out.iter_mut().enumerate().take(n) {
                        buf.clear();
                        for (j, &r) in args.iter().enumerate() {
                            let x = self.vals[r as usize][i];
                            // smax(v) = −smin(−v); the difference negates the
                            // base and keeps the subtrahends: −smax(b, −s) =
                            // smin(−b, s).
                            let y = match kind {
                                0 => x,
                                1 => -x,
                                _ => {
                                    if j == 0 {
                                        -x
                                    } else {
                                        x
                                    }
                                }
                            };
                            buf.push(y);
                        }
                        let m = smin_sorted(&mut buf, *k);
                        *slot = if kind == 0 { m } else { -m };
                    }
                    self.sort = buf;
                    self.vals[*o as usize] = out;
                }
            }
        }
    }

    #[inline]
    fn leaf(&mut self, p: u32, o: u32, n: usize, f: impl Fn(DVec3) -> f64) {
        let mut out = std::mem::take(&mut self.vals[o as usize]);
        let s = &self.pts[p as usize];
        let (xs, ys, zs) = (&s[0][..n], &s[1][..n], &s[2][..n]);
        for (i, slot) in out[..n].iter_mut().enumerate() {
            *slot = f(DVec3::new(xs[i], ys[i], zs[i]));
        }
        self.vals[o as usize] = out;
    }

    #[inline]
    fn binary(&mut self, a: u32, b: u32, o: u32, n: usize, f: impl Fn(f64, f64) -> f64) {
        let mut out = std::mem::take(&mut self.vals[o as usize]);
        let (va, vb) = (&self.vals[a as usize][..n], &self.vals[b as usize][..n]);
        for (i, slot) in out[..n].iter_mut().enumerate() {
            *slot = f(va[i], vb[i]);
        }
        self.vals[o as usize] = out;
    }

    #[inline]
    fn unary(&mut self, a: u32, o: u32, n: usize, f: impl Fn(f64) -> f64) {
        let mut out = std::mem::take(&mut self.vals[o as usize]);
        let va = &self.vals[a as usize][..n];
        for (i, slot) in out[..n].iter_mut().enumerate() {
            *slot = f(va[i]);
        }
        self.vals[o as usize] = out;
    }
}
