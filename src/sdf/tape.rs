//! Compilation of a tree to a flat instruction tape, and its evaluation
//! over batches of points (spec §1.5 step 4: fidget's idea, without a JIT).
//!
//! # Compilation
//!
//! The DAG is walked from the root (recursion bounded by the validated
//! depth). Transform chains are folded: every *frame* is one affine map from
//! the world point, `local = M·p + t`, so a chain of translate / rotate /
//! scale nodes costs one point transform. A node is compiled once per
//! `(node, frame)`: a subtree shared under the same frame is evaluated once
//! per point. The result is SSA code; a linear scan over last uses then maps
//! it to a small set of reusable registers (an output never aliases an input,
//! so every instruction is a plain element-wise loop).
//!
//! # Evaluation
//!
//! [`Evaluator`] owns all scratch (registers of `batch` lanes, the sort
//! buffer of the smooth operations), allocated once; evaluation allocates
//! nothing. [`Evaluator::eval`] is the one-point case of the same code, so
//! scalar and batched results are bit-identical. The smooth n-ary operations
//! sort their arguments then fold (decision D6), so they do not depend on
//! the order of the children.

use std::collections::BTreeMap;
use std::sync::Arc;

use glam::{DMat3, DQuat, DVec2, DVec3};

use crate::sdf::error::{Result, SdfError};
use crate::sdf::mesh_field::MeshField;
use crate::sdf::primitives::{self as prim, PolyTorus, Pyramid, RoundCone};
use crate::sdf::tree::{Node, NodeId, NodeInfo, Tree, TreeLimits};

/// Lanes per register: points evaluated per instruction loop.
pub const BATCH: usize = 256;

#[derive(Debug, Clone)]
enum Inst {
    Affine {
        src: u32,
        dst: u32,
        m: DMat3,
        t: DVec3,
    },
    Sphere {
        p: u32,
        o: u32,
        r: f64,
    },
    Cuboid {
        p: u32,
        o: u32,
        h: DVec3,
    },
    RoundedBox {
        p: u32,
        o: u32,
        h: DVec3,
        r: f64,
    },
    Torus {
        p: u32,
        o: u32,
        big: f64,
        small: f64,
    },
    PolyTorus {
        p: u32,
        o: u32,
        t: PolyTorus,
    },
    Cylinder {
        p: u32,
        o: u32,
        r: f64,
        h: f64,
    },
    Cone {
        p: u32,
        o: u32,
        h: f64,
        r1: f64,
        r2: f64,
    },
    Prism {
        p: u32,
        o: u32,
        a: f64,
        ca: f64,
        sa: f64,
        r: f64,
        h: f64,
    },
    Pyramid {
        p: u32,
        o: u32,
        t: Pyramid,
    },
    Capsule {
        p: u32,
        o: u32,
        a: DVec3,
        b: DVec3,
        r: f64,
    },
    RoundCone {
        p: u32,
        o: u32,
        c: RoundCone,
    },
    HalfSpace {
        p: u32,
        o: u32,
        n: DVec3,
        d: f64,
    },
    Mesh {
        p: u32,
        o: u32,
        mesh: u32,
    },
    Min {
        a: u32,
        b: u32,
        o: u32,
    },
    Max {
        a: u32,
        b: u32,
        o: u32,
    },
    /// max(a, −b)
    MaxNeg {
        a: u32,
        b: u32,
        o: u32,
    },
    /// Sorted-fold smooth minimum of `args[start..start+len]`.
    SmoothMin {
        start: u32,
        len: u32,
        k: f64,
        o: u32,
    },
    /// Sorted-fold smooth maximum.
    SmoothMax {
        start: u32,
        len: u32,
        k: f64,
        o: u32,
    },
    /// Smooth max of (base, −s₁, …, −sₙ); `args[start]` is the base.
    SmoothDiff {
        start: u32,
        len: u32,
        k: f64,
        o: u32,
    },
    Mul {
        a: u32,
        c: f64,
        o: u32,
    },
    Sub {
        a: u32,
        c: f64,
        o: u32,
    },
    AbsSub {
        a: u32,
        c: f64,
        o: u32,
    },
    PlaneMax {
        a: u32,
        p: u32,
        n: DVec3,
        d: f64,
        o: u32,
    },
}

/// A compiled tree. Immutable; share it between threads (`Send + Sync`)
/// and give each thread its own [`Evaluator`].
#[derive(Debug, Clone)]
pub struct Tape {
    insts: Vec<Inst>,
    args: Vec<u32>,
    meshes: Vec<Arc<MeshField>>,
    n_vals: usize,
    n_pts: usize,
    out: u32,
    max_args: usize,
    info: NodeInfo,
}

impl Tape {
    /// Validates the tree below `root` and compiles it.
    pub fn compile(tree: &Tree, root: NodeId, limits: &TreeLimits) -> Result<Tape> {
        let infos = tree.analyze(root, limits)?;
        let info = infos[root.index()].ok_or(SdfError::Internal("root not analysed"))?;
        let mut c = Compiler {
            tree,
            limits,
            code: Vec::new(),
            args: Vec::new(),
            meshes: Vec::new(),
            memo: BTreeMap::new(),
            frames: vec![(DMat3::IDENTITY, DVec3::ZERO)],
            frame_ids: BTreeMap::new(),
            frame_pt: vec![Some(0)],
            n_val: 0,
            n_pt: 1,
        };
        c.frame_ids
            .insert(frame_key(&DMat3::IDENTITY, DVec3::ZERO), 0);
        let out = c.value(root, 0)?;
        Ok(c.finish(out, info))
    }

    /// Facts (contract, bounds) of the root.
    pub fn info(&self) -> &NodeInfo {
        &self.info
    }

    /// The mesh fields the tape reads.
    pub fn meshes(&self) -> &[Arc<MeshField>] {
        &self.meshes
    }

    /// Number of instructions.
    pub fn len(&self) -> usize {
        self.insts.len()
    }

    /// True for an empty tape (never produced by `compile`).
    pub fn is_empty(&self) -> bool {
        self.insts.is_empty()
    }

    /// A fresh evaluator with its scratch allocated.
    pub fn evaluator(&self) -> Evaluator<'_> {
        Evaluator {
            tape: self,
            vals: vec![vec![0.0; BATCH]; self.n_vals],
            pts: (0..self.n_pts)
                .map(|_| [vec![0.0; BATCH], vec![0.0; BATCH], vec![0.0; BATCH]])
                .collect(),
            sort: Vec::with_capacity(self.max_args),
        }
    }
}

fn frame_key(m: &DMat3, t: DVec3) -> [u64; 12] {
    let a = m.to_cols_array();
    let mut k = [0u64; 12];
    for i in 0..9 {
        k[i] = a[i].to_bits();
    }
    for i in 0..3 {
        k[9 + i] = t[i].to_bits();
    }
    k
}

/// SSA form: `o`, `p`, `a`, `b`, `dst` are virtual ids.
struct Compiler<'a> {
    tree: &'a Tree,
    limits: &'a TreeLimits,
    code: Vec<Inst>,
    args: Vec<u32>,
    meshes: Vec<Arc<MeshField>>,
    memo: BTreeMap<(u32, u32), u32>,
    frames: Vec<(DMat3, DVec3)>,
    frame_ids: BTreeMap<[u64; 12], u32>,
    frame_pt: Vec<Option<u32>>,
    n_val: u32,
    n_pt: u32,
}

impl Compiler<'_> {
    fn emit(&mut self, i: Inst) -> Result<()> {
        if self.code.len() >= self.limits.max_instructions {
            return Err(SdfError::TooLarge {
                what: "tape instructions",
                count: self.code.len() as u64 + 1,
                limit: self.limits.max_instructions as u64,
            });
        }
        self.code.push(i);
        Ok(())
    }

    fn new_val(&mut self) -> u32 {
        self.n_val += 1;
        self.n_val - 1
    }

    fn frame(&mut self, m: DMat3, t: DVec3) -> u32 {
        let key = frame_key(&m, t);
        if let Some(&f) = self.frame_ids.get(&key) {
            return f;
        }
        let id = self.frames.len() as u32;
        self.frames.push((m, t));
        self.frame_pt.push(None);
        self.frame_ids.insert(key, id);
        id
    }

    /// The point register of a frame, emitting its affine on first use.
    fn point(&mut self, f: u32) -> Result<u32> {
        if let Some(p) = self.frame_pt[f as usize] {
            return Ok(p);
        }
        let (m, t) = self.frames[f as usize];
        let dst = self.n_pt;
        self.n_pt += 1;
        self.emit(Inst::Affine { src: 0, dst, m, t })?;
        self.frame_pt[f as usize] = Some(dst);
        Ok(dst)
    }

    /// Compiles `node` in frame `f`; recursion depth ≤ the validated depth.
    fn value(&mut self, id: NodeId, f: u32) -> Result<u32> {
        if let Some(&v) = self.memo.get(&(id.0, f)) {
            return Ok(v);
        }
        let node = self
            .tree
            .node(id)
            .ok_or(SdfError::Internal("missing node"))?
            .clone();
        let v = match node {
            Node::Translate { child, offset } => {
                let (m, t) = self.frames[f as usize];
                let cf = self.frame(m, t - offset);
                self.value(child, cf)?
            }
            Node::Rotate { child, rotation } => {
                let q: DQuat = rotation.to_quat().ok_or(SdfError::Internal("rotation"))?;
                let inv = DMat3::from_quat(q.conjugate());
                let (m, t) = self.frames[f as usize];
                let cf = self.frame(inv * m, inv * t);
                self.value(child, cf)?
            }
            Node::Scale { child, factor } => {
                let (m, t) = self.frames[f as usize];
                let cf = self.frame(m * (1.0 / factor), t / factor);
                let c = self.value(child, cf)?;
                self.unary(c, |a, o| Inst::Mul { a, c: factor, o })?
            }
            Node::ScaleXyz { child, factors } => {
                let (m, t) = self.frames[f as usize];
                let inv = DMat3::from_diagonal(DVec3::ONE / factors);
                let cf = self.frame(inv * m, t / factors);
                let c = self.value(child, cf)?;
                let s = factors.min_element();
                self.unary(c, |a, o| Inst::Mul { a, c: s, o })?
            }
            Node::Offset { child, distance } => {
                let c = self.value(child, f)?;
                self.unary(c, |a, o| Inst::Sub { a, c: distance, o })?
            }
            Node::Shell { child, thickness } => {
                let c = self.value(child, f)?;
                self.unary(c, |a, o| Inst::AbsSub { a, c: thickness, o })?
            }
            Node::PlaneCut {
                child,
                normal,
                point,
            } => {
                let c = self.value(child, f)?;
                let p = self.point(f)?;
                let n = normal.normalize();
                let d = n.dot(point);
                let o = self.new_val();
                self.emit(Inst::PlaneMax { a: c, p, n, d, o })?;
                o
            }
            Node::Union(ch) => self.fold(&ch, f, |a, b, o| Inst::Min { a, b, o })?,
            Node::Intersection(ch) => self.fold(&ch, f, |a, b, o| Inst::Max { a, b, o })?,
            Node::Difference { base, subtract } => {
                let mut acc = self.value(base, f)?;
                for s in subtract {
                    let b = self.value(s, f)?;
                    let o = self.new_val();
                    self.emit(Inst::MaxNeg { a: acc, b, o })?;
                    acc = o;
                }
                acc
            }
            Node::SmoothUnion { children, k } | Node::SmoothIntersection { children, k } => {
                let union = matches!(self.tree.node(id), Some(Node::SmoothUnion { .. }));
                if k == 0.0 || children.len() == 1 {
                    if union {
                        self.fold(&children, f, |a, b, o| Inst::Min { a, b, o })?
                    } else {
                        self.fold(&children, f, |a, b, o| Inst::Max { a, b, o })?
                    }
                } else {
                    let vals = children
                        .iter()
                        .map(|c| self.value(*c, f))
                        .collect::<Result<Vec<_>>>()?;
                    let start = self.args.len() as u32;
                    self.args.extend(&vals);
                    let len = vals.len() as u32;
                    let o = self.new_val();
                    if union {
                        self.emit(Inst::SmoothMin { start, len, k, o })?;
                    } else {
                        self.emit(Inst::SmoothMax { start, len, k, o })?;
                    }
                    o
                }
            }
            Node::SmoothDifference { base, subtract, k } => {
                if k == 0.0 || subtract.is_empty() {
                    let mut acc = self.value(base, f)?;
                    for s in subtract {
                        let b = self.value(s, f)?;
                        let o = self.new_val();
                        self.emit(Inst::MaxNeg { a: acc, b, o })?;
                        acc = o;
                    }
                    acc
                } else {
                    let mut vals = vec![self.value(base, f)?];
                    for s in &subtract {
                        vals.push(self.value(*s, f)?);
                    }
                    let start = self.args.len() as u32;
                    self.args.extend(&vals);
                    let o = self.new_val();
                    self.emit(Inst::SmoothDiff {
                        start,
                        len: vals.len() as u32,
                        k,
                        o,
                    })?;
                    o
                }
            }
            leaf => {
                let p = self.point(f)?;
                let o = self.new_val();
                let inst = match leaf {
                    Node::Sphere { radius } => Inst::Sphere { p, o, r: radius },
                    Node::Box { size } => Inst::Cuboid {
                        p,
                        o,
                        h: size * 0.5,
                    },
                    Node::RoundedBox { size, radius } => Inst::RoundedBox {
                        p,
                        o,
                        h: size * 0.5,
                        r: radius,
                    },
                    Node::Torus {
                        major_radius,
                        minor_radius,
                    } => Inst::Torus {
                        p,
                        o,
                        big: major_radius,
                        small: minor_radius,
                    },
                    Node::PolygonalTorus {
                        major_radius,
                        minor_radius,
                        ring_sides,
                        tube_sides,
                    } => Inst::PolyTorus {
                        p,
                        o,
                        t: PolyTorus::new(ring_sides, tube_sides, major_radius, minor_radius),
                    },
                    Node::Cylinder { radius, height } => Inst::Cylinder {
                        p,
                        o,
                        r: radius,
                        h: height * 0.5,
                    },
                    Node::Cone {
                        height,
                        bottom_radius,
                        top_radius,
                    } => Inst::Cone {
                        p,
                        o,
                        h: height * 0.5,
                        r1: bottom_radius,
                        r2: top_radius,
                    },
                    Node::Prism {
                        sides,
                        radius,
                        height,
                    } => {
                        let a = std::f64::consts::PI / sides as f64;
                        Inst::Prism {
                            p,
                            o,
                            a,
                            ca: libm::cos(a),
                            sa: libm::sin(a),
                            r: radius,
                            h: height * 0.5,
                        }
                    }
                    Node::Pyramid {
                        sides,
                        radius,
                        height,
                        top_height,
                    } => Inst::Pyramid {
                        p,
                        o,
                        t: Pyramid::new(sides, radius, height, top_height),
                    },
                    Node::Capsule { a, b, radius } => {
                        if a == b {
                            Inst::Sphere {
                                p: self.point_offset(f, a)?,
                                o,
                                r: radius,
                            }
                        } else {
                            Inst::Capsule {
                                p,
                                o,
                                a,
                                b,
                                r: radius,
                            }
                        }
                    }
                    Node::RoundCone {
                        a,
                        b,
                        radius_a,
                        radius_b,
                    } => {
                        if RoundCone::is_proper(a, b, radius_a, radius_b) {
                            Inst::RoundCone {
                                p,
                                o,
                                c: RoundCone::new(a, b, radius_a, radius_b),
                            }
                        } else {
                            // One end sphere contains the other (spec §4.4).
                            let (c, r) = if radius_a >= radius_b {
                                (a, radius_a)
                            } else {
                                (b, radius_b)
                            };
                            Inst::Sphere {
                                p: self.point_offset(f, c)?,
                                o,
                                r,
                            }
                        }
                    }
                    Node::HalfSpace { normal, offset } => Inst::HalfSpace {
                        p,
                        o,
                        n: normal.normalize(),
                        d: offset,
                    },
                    Node::Mesh(field) => {
                        let idx = match self.meshes.iter().position(|m| Arc::ptr_eq(m, &field)) {
                            Some(i) => i,
                            None => {
                                self.meshes.push(field.clone());
                                self.meshes.len() - 1
                            }
                        };
                        Inst::Mesh {
                            p,
                            o,
                            mesh: idx as u32,
                        }
                    }
                    _ => return Err(SdfError::Internal("unhandled node kind")),
                };
                self.emit(inst)?;
                o
            }
        };
        self.memo.insert((id.0, f), v);
        Ok(v)
    }

    /// The point register of frame `f` moved by `−c` (a sphere centred at c).
    fn point_offset(&mut self, f: u32, c: DVec3) -> Result<u32> {
        let (m, t) = self.frames[f as usize];
        let cf = self.frame(m, t - c);
        self.point(cf)
    }

    fn unary(&mut self, a: u32, mk: impl Fn(u32, u32) -> Inst) -> Result<u32> {
        let o = self.new_val();
        self.emit(mk(a, o))?;
        Ok(o)
    }

    fn fold(&mut self, ch: &[NodeId], f: u32, mk: impl Fn(u32, u32, u32) -> Inst) -> Result<u32> {
        let mut acc = self.value(ch[0], f)?;
        for c in &ch[1..] {
            let b = self.value(*c, f)?;
            let o = self.new_val();
            self.emit(mk(acc, b, o))?;
            acc = o;
        }
        Ok(acc)
    }

    /// Linear-scan register allocation over the SSA code.
    fn finish(self, out: u32, info: NodeInfo) -> Tape {
        let n_val = self.n_val as usize;
        let n_pt = self.n_pt as usize;
        let mut last_val = vec![usize::MAX; n_val];
        let mut last_pt = vec![usize::MAX; n_pt];
        for (i, inst) in self.code.iter().enumerate() {
            let (vs, ps) = uses(inst, &self.args);
            for v in vs {
                last_val[v as usize] = i;
            }
            for p in ps {
                last_pt[p as usize] = i;
            }
        }
        let mut map_val = vec![u32::MAX; n_val];
        let mut map_pt = vec![u32::MAX; n_pt];
        map_pt[0] = 0;
        let (mut free_val, mut free_pt): (Vec<u32>, Vec<u32>) = (Vec::new(), Vec::new());
        let (mut nv, mut np) = (0u32, 1u32);
        let mut insts = Vec::with_capacity(self.code.len());
        let mut args = self.args.clone();
        for (i, inst) in self.code.iter().enumerate() {
            let mut inst = inst.clone();
            // Inputs first (mapped), then the output (never an input's reg).
            let (vs, ps) = uses(&inst, &self.args);
            remap_inputs(&mut inst, &mut args, &map_val, &map_pt);
            let (out_reg, slot) = output(&mut inst);
            *slot = match out_reg {
                Out::Val(v) => {
                    let r = free_val.pop().unwrap_or_else(|| {
                        nv += 1;
                        nv - 1
                    });
                    map_val[v as usize] = r;
                    r
                }
                Out::Pt(p) => {
                    let r = free_pt.pop().unwrap_or_else(|| {
                        np += 1;
                        np - 1
                    });
                    map_pt[p as usize] = r;
                    r
                }
            };
            for v in vs {
                if last_val[v as usize] == i && v != out {
                    let r = map_val[v as usize];
                    if !free_val.contains(&r) {
                        free_val.push(r);
                    }
                }
            }
            for p in ps {
                if last_pt[p as usize] == i && p != 0 {
                    let r = map_pt[p as usize];
                    if !free_pt.contains(&r) {
                        free_pt.push(r);
                    }
                }
            }
            insts.push(inst);
        }
        let max_args = self
            .code
            .iter()
            .map(|i| match i {
                Inst::SmoothMin { len, .. }
                | Inst::SmoothMax { len, .. }
                | Inst::SmoothDiff { len, .. } => *len as usize,
                _ => 0,
            })
            .max()
            .unwrap_or(0);
        Tape {
            insts,
            args,
            meshes: self.meshes,
            n_vals: nv as usize,
            n_pts: np as usize,
            out: map_val[out as usize],
            max_args,
            info,
        }
    }
}

enum Out {
    Val(u32),
    Pt(u32),
}

/// The instruction's output register: a value or a point register.
fn output(i: &mut Inst) -> (Out, &mut u32) {
    match i {
        Inst::Affine { dst, .. } => (Out::Pt(*dst), dst),
        Inst::Sphere { o, .. }
        | Inst::Cuboid { o, .. }
        | Inst::RoundedBox { o, .. }
        | Inst::Torus { o, .. }
        | Inst::PolyTorus { o, .. }
        | Inst::Cylinder { o, .. }
        | Inst::Cone { o, .. }
        | Inst::Prism { o, .. }
        | Inst::Pyramid { o, .. }
        | Inst::Capsule { o, .. }
        | Inst::RoundCone { o, .. }
        | Inst::HalfSpace { o, .. }
        | Inst::Mesh { o, .. }
        | Inst::Min { o, .. }
        | Inst::Max { o, .. }
        | Inst::MaxNeg { o, .. }
        | Inst::SmoothMin { o, .. }
        | Inst::SmoothMax { o, .. }
        | Inst::SmoothDiff { o, .. }
        | Inst::Mul { o, .. }
        | Inst::Sub { o, .. }
        | Inst::AbsSub { o, .. }
        | Inst::PlaneMax { o, .. } => (Out::Val(*o), o),
    }
}

/// (value inputs, point inputs) of an instruction.
fn uses(i: &Inst, args: &[u32]) -> (Vec<u32>, Vec<u32>) {
    match i {
        Inst::Affine { src, .. } => (vec![], vec![*src]),
        Inst::Sphere { p, .. }
        | Inst::Cuboid { p, .. }
        | Inst::RoundedBox { p, .. }
        | Inst::Torus { p, .. }
        | Inst::PolyTorus { p, .. }
        | Inst::Cylinder { p, .. }
        | Inst::Cone { p, .. }
        | Inst::Prism { p, .. }
        | Inst::Pyramid { p, .. }
        | Inst::Capsule { p, .. }
        | Inst::RoundCone { p, .. }
        | Inst::HalfSpace { p, .. }
        | Inst::Mesh { p, .. } => (vec![], vec![*p]),
        Inst::Min { a, b, .. } | Inst::Max { a, b, .. } | Inst::MaxNeg { a, b, .. } => {
            (vec![*a, *b], vec![])
        }
        Inst::SmoothMin { start, len, .. }
        | Inst::SmoothMax { start, len, .. }
        | Inst::SmoothDiff { start, len, .. } => (
            args[*start as usize..(*start + *len) as usize].to_vec(),
            vec![],
        ),
        Inst::Mul { a, .. } | Inst::Sub { a, .. } | Inst::AbsSub { a, .. } => (vec![*a], vec![]),
        Inst::PlaneMax { a, p, .. } => (vec![*a], vec![*p]),
    }
}

fn remap_inputs(i: &mut Inst, args: &mut [u32], mv: &[u32], mp: &[u32]) {
    match i {
        Inst::Affine { src, .. } => *src = mp[*src as usize],
        Inst::Sphere { p, .. }
        | Inst::Cuboid { p, .. }
        | Inst::RoundedBox { p, .. }
        | Inst::Torus { p, .. }
        | Inst::PolyTorus { p, .. }
        | Inst::Cylinder { p, .. }
        | Inst::Cone { p, .. }
        | Inst::Prism { p, .. }
        | Inst::Pyramid { p, .. }
        | Inst::Capsule { p, .. }
        | Inst::RoundCone { p, .. }
        | Inst::HalfSpace { p, .. }
        | Inst::Mesh { p, .. } => *p = mp[*p as usize],
        Inst::Min { a, b, .. } | Inst::Max { a, b, .. } | Inst::MaxNeg { a, b, .. } => {
            *a = mv[*a as usize];
            *b = mv[*b as usize];
        }
        Inst::SmoothMin { start, len, .. }
        | Inst::SmoothMax { start, len, .. }
        | Inst::SmoothDiff { start, len, .. } => {
            for x in &mut args[*start as usize..(*start + *len) as usize] {
                *x = mv[*x as usize];
            }
        }
        Inst::Mul { a, .. } | Inst::Sub { a, .. } | Inst::AbsSub { a, .. } => *a = mv[*a as usize],
        Inst::PlaneMax { a, p, .. } => {
            *a = mv[*a as usize];
            *p = mp[*p as usize];
        }
    }
}

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
