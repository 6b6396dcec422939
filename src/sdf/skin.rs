//! Skinning a grown skeleton into one watertight solid (spec §4.4).
//!
//! f(p) = the order-independent smooth union (sort, then fold the
//! quadratic smin; decision D6) of one primitive per edge — Quilez's exact
//! round cone between the end spheres, or the larger sphere when one end
//! sphere contains the other — and a sphere per isolated node.
//!
//! # Speed and exactness of culling
//!
//! A BVH over the primitives' boxes gives, per region (a block or a point),
//! the candidates that can matter: with U = min_i dᵢ(c) + r (an upper bound
//! of min_i dᵢ over the region of centre c and half-diagonal r), every
//! primitive whose box is farther than U + k from the region is dropped.
//! A dropped primitive has dᵢ ≥ min + k everywhere in the region, and the
//! sorted fold stops (bit-exactly: `smin` returns its first argument when
//! h clamps to 1) before any such value. So the value at a point does not
//! depend on which region it was evaluated for, nor on the order of the
//! edges: cost ∝ skin samples × local edge density.
//!
//! # Input rules
//!
//! Edges are undirected and deduplicated ((a, b) and (b, a) are one edge;
//! the round cone is built from the lower node id). Self-loops, missing
//! nodes, non-finite positions and non-positive radii are located errors.

use glam::DVec3;

use crate::sdf::aabb::Aabb;
use crate::sdf::error::{Result, SdfError};
use crate::sdf::grid::{Field, FieldEval, MeshOptions, Resolution};
use crate::sdf::mesher::{mesh, MeshOutput};
use crate::sdf::primitives::RoundCone;
use crate::sdf::tape::smin_sorted;
use crate::sdf::topology::{check, shell_volumes, MeshCheck};

/// A skeleton node: centre and radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkinNode {
    pub position: [f64; 3],
    pub radius: f64,
}

/// Nodes and undirected edges (pairs of node indices).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Skeleton {
    pub nodes: Vec<SkinNode>,
    pub edges: Vec<[u32; 2]>,
}

/// Skinning options.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkinOptions {
    /// Smooth-union radius k (≥ 0; spec default 0.5 · min radius).
    pub blend: f64,
    /// Cell size; `None` = min radius / 2 (spec §4.4).
    pub cell: Option<f64>,
    /// Mesher settings; `resolution` is replaced by the cell above.
    pub mesh: MeshOptions,
}

/// A skinned solid and its checks.
#[derive(Debug, Clone, PartialEq)]
pub struct SkinOutput {
    pub mesh: MeshOutput,
    pub check: MeshCheck,
    /// Connected components of the skeleton.
    pub skeleton_components: usize,
    /// Outward shells of the mesh (positive volume): the solids. One per
    /// connected skeleton unless blends merge nearby skeletons.
    pub solids: usize,
    /// Inward shells (negative volume): cavities enclosed by the union, e.g.
    /// pockets left between many crossing branches. `check.components` =
    /// solids + cavities.
    pub cavities: usize,
    pub cell: f64,
}

#[derive(Debug, Clone, Copy)]
enum Prim {
    Sphere(DVec3, f64),
    Cone(RoundCone),
}

impl Prim {
    #[inline]
    fn eval(&self, p: DVec3) -> f64 {
        match self {
            Prim::Sphere(c, r) => (p - *c).length() - r,
            Prim::Cone(rc) => rc.eval(p),
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct BNode {
    lo: DVec3,
    hi: DVec3,
    start: u32,
    count: u32,
}

/// The skin's distance field (1-Lipschitz; a [`Field`] for the meshers).
#[derive(Debug, Clone)]
pub struct SkinField {
    prims: Vec<Prim>,
    boxes: Vec<Aabb>,
    nodes: Vec<BNode>,
    k: f64,
    bounds: Aabb,
    min_radius: f64,
    components: usize,
}

impl SkinField {
    /// Validates the skeleton and builds the field.
    pub fn new(skel: &Skeleton, blend: f64) -> Result<SkinField> {
        if !(blend.is_finite() && blend >= 0.0) {
            return Err(SdfError::InvalidOption {
                field: "blend",
                reason: format!("must be finite and ≥ 0, got {blend}"),
            });
        }
        if skel.nodes.is_empty() {
            return Err(SdfError::InvalidOption {
                field: "skeleton",
                reason: "no nodes".into(),
            });
        }
        for (i, n) in skel.nodes.iter().enumerate() {
            if !n.position.iter().all(|c| c.is_finite()) {
                return Err(SdfError::SkinNode {
                    node: i,
                    field: "position",
                    reason: "not finite".into(),
                });
            }
            if !(n.radius.is_finite() && n.radius > 0.0) {
                return Err(SdfError::SkinNode {
                    node: i,
                    field: "radius",
                    reason: format!("must be positive and finite, got {}", n.radius),
                });
            }
        }
        let mut edges: Vec<[u32; 2]> = Vec::with_capacity(skel.edges.len());
        for (i, e) in skel.edges.iter().enumerate() {
            for &v in e {
                if v as usize >= skel.nodes.len() {
                    return Err(SdfError::SkinEdge {
                        edge: i,
                        reason: format!("node {v} does not exist ({} nodes)", skel.nodes.len()),
                    });
                }
            }
            if e[0] == e[1] {
                return Err(SdfError::SkinEdge {
                    edge: i,
                    reason: "joins a node to itself".into(),
                });
            }
            edges.push([e[0].min(e[1]), e[0].max(e[1])]);
        }
        edges.sort_unstable();
        edges.dedup();
        let mut degree = vec![0u32; skel.nodes.len()];
        let mut parent: Vec<u32> = (0..skel.nodes.len() as u32).collect();
        fn root(p: &mut [u32], mut x: u32) -> u32 {
            while p[x as usize] != x {
                p[x as usize] = p[p[x as usize] as usize];
                x = p[x as usize];
            }
            x
        }
        let mut prims = Vec::with_capacity(edges.len());
        for e in &edges {
            degree[e[0] as usize] += 1;
            degree[e[1] as usize] += 1;
            let (ra, rb) = (root(&mut parent, e[0]), root(&mut parent, e[1]));
            if ra != rb {
                parent[ra.max(rb) as usize] = ra.min(rb);
            }
            let (na, nb) = (skel.nodes[e[0] as usize], skel.nodes[e[1] as usize]);
            let (a, b) = (
                DVec3::from_array(na.position),
                DVec3::from_array(nb.position),
            );
            prims.push(if RoundCone::is_proper(a, b, na.radius, nb.radius) {
                Prim::Cone(RoundCone::new(a, b, na.radius, nb.radius))
            } else if na.radius >= nb.radius {
                Prim::Sphere(a, na.radius)
            } else {
                Prim::Sphere(b, nb.radius)
            });
        }
        for (i, n) in skel.nodes.iter().enumerate() {
            if degree[i] == 0 {
                prims.push(Prim::Sphere(DVec3::from_array(n.position), n.radius));
            }
        }
        let components = (0..skel.nodes.len() as u32)
            .filter(|&i| root(&mut parent, i) == i)
            .count();
        let boxes: Vec<Aabb> = prims
            .iter()
            .map(|p| match p {
                Prim::Sphere(c, r) => Aabb::centered(*c, DVec3::splat(*r)),
                Prim::Cone(rc) => Aabb::centered(rc.a, DVec3::splat(rc.r1))
                    .union(&Aabb::centered(rc.a + rc.ba, DVec3::splat(rc.r2))),
            })
            .collect();
        let min_radius = skel
            .nodes
            .iter()
            .map(|n| n.radius)
            .fold(f64::INFINITY, f64::min);
        let nodes = build(&boxes);
        let mut f = SkinField {
            prims,
            boxes,
            nodes,
            k: blend,
            bounds: Aabb::EMPTY,
            min_radius,
            components,
        };
        // The n-ary fold can sink below min by k/4 per primitive within k:
        // grow the box by k/4 × (most primitives near any one, minus 1).
        let mut crowd = 1usize;
        let mut buf = Vec::new();
        let mut all = Aabb::EMPTY;
        for b in &f.boxes {
            buf.clear();
            f.query(&b.grown(blend), 0.0, &mut buf);
            crowd = crowd.max(buf.len());
            all = all.union(b);
        }
        f.bounds = all.grown(blend * 0.25 * crowd.max(2) as f64);
        Ok(f)
    }

    /// Smallest node radius.
    pub fn min_radius(&self) -> f64 {
        self.min_radius
    }

    /// Connected components of the skeleton.
    pub fn skeleton_components(&self) -> usize {
        self.components
    }

    /// Primitives whose boxes lie within `reach` of `region`.
    fn query(&self, region: &Aabb, reach: f64, out: &mut Vec<u32>) {
        let r2 = reach * reach;
        let mut stack = vec![0u32];
        while let Some(ni) = stack.pop() {
            let n = &self.nodes[ni as usize];
            if region.dist2_box(&Aabb::new(n.lo, n.hi)) > r2 {
                continue;
            }
            if n.count > 0 {
                for i in n.start..n.start + n.count {
                    if region.dist2_box(&self.boxes[i as usize]) <= r2 {
                        out.push(i);
                    }
                }
            } else {
                stack.push(n.start + 1);
                stack.push(n.start);
            }
        }
    }

    /// min over primitives of the exact distance at `p` (BVH, best-first).
    fn nearest(&self, p: DVec3) -> f64 {
        let mut best = f64::INFINITY;
        let mut stack = vec![(0u32, 0.0f64)];
        while let Some((ni, d2)) = stack.pop() {
            // Box distance ≥ 0 bounds every primitive in the node below.
            let b = best.max(0.0);
            if d2 > b * b {
                continue;
            }
            let n = &self.nodes[ni as usize];
            if n.count > 0 {
                for i in n.start..n.start + n.count {
                    best = best.min(self.prims[i as usize].eval(p));
                }
            } else {
                let (l, r) = (n.start, n.start + 1);
                let dl = Aabb::new(self.nodes[l as usize].lo, self.nodes[l as usize].hi).dist2(p);
                let dr = Aabb::new(self.nodes[r as usize].lo, self.nodes[r as usize].hi).dist2(p);
                if dl <= dr {
                    stack.push((r, dr));
                    stack.push((l, dl));
                } else {
                    stack.push((l, dl));
                    stack.push((r, dr));
                }
            }
        }
        best
    }

    /// Candidates for a region (see the module doc), with a lower bound
    /// of each one's distance over the region, ascending by that bound.
    fn candidates(&self, region: &Aabb, ids: &mut Vec<u32>, out: &mut Vec<(f64, u32)>) {
        ids.clear();
        out.clear();
        let c = region.center();
        let r = region.size().length() * 0.5;
        let u = self.nearest(c) + r;
        let reach = (u + self.k).max(0.0);
        let reach = reach * (1.0 + 1e-9) + 1e-12 * (1.0 + reach);
        self.query(region, reach, ids);
        // Tighter, still safe: over the region dᵢ ≥ dᵢ(c) − r (Lipschitz),
        // so a primitive with dᵢ(c) − r > U + k never reaches the fold.
        for &i in ids.iter() {
            let lower = self.prims[i as usize].eval(c) - r;
            if lower <= reach {
                out.push((lower, i));
            }
        }
        out.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    }

    /// f at one point (all primitives; tests and oracles).
    pub fn eval_exhaustive(&self, p: DVec3) -> f64 {
        let mut v: Vec<f64> = self.prims.iter().map(|q| q.eval(p)).collect();
        if self.k == 0.0 {
            return v.iter().copied().fold(f64::INFINITY, f64::min);
        }
        smin_sorted(&mut v, self.k)
    }
}

/// Median-split BVH over boxes in their given order (`SkinField::sorted`
/// orders primitives along a Morton curve first, so ranges are compact).
fn build(boxes: &[Aabb]) -> Vec<BNode> {
    let n = boxes.len();
    let mut nodes = vec![BNode {
        lo: DVec3::ZERO,
        hi: DVec3::ZERO,
        start: 0,
        count: 0,
    }];
    let mut work = vec![(0usize, 0usize, n)];
    while let Some((ni, s, e)) = work.pop() {
        let b = boxes[s..e].iter().fold(Aabb::EMPTY, |a, x| a.union(x));
        nodes[ni].lo = b.lo;
        nodes[ni].hi = b.hi;
        if e - s <= 4 {
            nodes[ni].start = s as u32;
            nodes[ni].count = (e - s) as u32;
            continue;
        }
        let m = (s + e) / 2;
        let l = nodes.len();
        nodes.push(nodes[ni]);
        nodes.push(nodes[ni]);
        nodes[ni].start = l as u32;
        nodes[ni].count = 0;
        work.push((l + 1, m, e));
        work.push((l, s, m));
    }
    nodes
}

impl SkinField {
    fn sorted(mut self) -> SkinField {
        // Order primitives along a Morton-like key of their box centres so
        // that the median-split ranges of `build` are spatially coherent.
        let all = self.boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(b));
        let ext = all.size().max(DVec3::splat(f64::MIN_POSITIVE));
        let key = |b: &Aabb| -> u64 {
            let c = (b.center() - all.lo) / ext;
            let q = |x: f64| ((x.clamp(0.0, 1.0) * 1023.0) as u64) & 1023;
            let (x, y, z) = (q(c.x), q(c.y), q(c.z));
            let mut k = 0u64;
            for bit in 0..10 {
                k |= ((x >> bit) & 1) << (3 * bit)
                    | ((y >> bit) & 1) << (3 * bit + 1)
                    | ((z >> bit) & 1) << (3 * bit + 2);
            }
            k
        };
        let mut idx: Vec<usize> = (0..self.prims.len()).collect();
        idx.sort_by_key(|&i| (key(&self.boxes[i]), i));
        self.prims = idx.iter().map(|&i| self.prims[i]).collect();
        self.boxes = idx.iter().map(|&i| self.boxes[i]).collect();
        self.nodes = build(&self.boxes);
        self
    }
}

struct SkinEval<'a> {
    f: &'a SkinField,
    ids: Vec<u32>,
    cand: Vec<(f64, u32)>,
    vals: Vec<f64>,
}

impl FieldEval for SkinEval<'_> {
    fn wants_regions(&self) -> bool {
        true
    }

    fn eval(&mut self, region: &Aabb, xs: &[f64], ys: &[f64], zs: &[f64], out: &mut [f64]) {
        self.f.candidates(region, &mut self.ids, &mut self.cand);
        let k = self.f.k;
        for i in 0..out.len().min(xs.len()) {
            let p = DVec3::new(xs[i], ys[i], zs[i]);
            self.vals.clear();
            // Candidates come by ascending lower bound: once a bound
            // reaches the smallest distance so far plus k, that candidate
            // and every later one is ≥ min + k, which the sorted fold never
            // reads (it stops at acc + k ≤ min + k). So the result is the
            // full fold's, bit for bit, for a few distances.
            let mut least = f64::INFINITY;
            for &(lower, c) in &self.cand {
                let stop = least + k;
                if lower > stop + 1e-12 * (1.0 + stop.abs()) {
                    break;
                }
                let d = self.f.prims[c as usize].eval(p);
                least = least.min(d);
                self.vals.push(d);
            }
            out[i] = if self.vals.is_empty() {
                f64::MAX
            } else if self.f.k == 0.0 {
                self.vals.iter().copied().fold(f64::INFINITY, f64::min)
            } else {
                smin_sorted(&mut self.vals, self.f.k)
            };
        }
    }
}

impl Field for SkinField {
    fn lipschitz(&self) -> f64 {
        1.0
    }
    fn bounds(&self) -> Aabb {
        self.bounds
    }
    fn evaluator(&self) -> Box<dyn FieldEval + '_> {
        Box::new(SkinEval {
            f: self,
            ids: Vec::new(),
            cand: Vec::new(),
            vals: Vec::new(),
        })
    }
}

/// Skins a skeleton: builds the field, checks the cell, meshes, checks the
/// result.
pub fn skin(skel: &Skeleton, opts: &SkinOptions) -> Result<SkinOutput> {
    let field = SkinField::new(skel, opts.blend)?.sorted();
    let min_r = field.min_radius();
    let cell = match opts.cell {
        Some(c) => {
            if !(c.is_finite() && c > 0.0) {
                return Err(SdfError::InvalidOption {
                    field: "cell",
                    reason: format!("must be positive and finite, got {c}"),
                });
            }
            c
        }
        None => min_r / 2.0,
    };
    if min_r / cell < 1.5 {
        return Err(SdfError::CellTooCoarse {
            cell,
            min_radius: min_r,
            ratio: min_r / cell,
        });
    }
    let mut mo = opts.mesh;
    mo.resolution = Resolution::CellSize(cell);
    let m = mesh(&field, &mo)?;
    let c = check(&m.positions, &m.triangles);
    let shells = shell_volumes(&m.positions, &m.triangles);
    Ok(SkinOutput {
        solids: shells.iter().filter(|&&v| v > 0.0).count(),
        cavities: shells.iter().filter(|&&v| v < 0.0).count(),
        mesh: m,
        check: c,
        skeleton_components: field.skeleton_components(),
        cell,
    })
}
