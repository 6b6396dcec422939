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
//! In [`super::eval`] ([`Evaluator`]), re-exported here.

use std::collections::BTreeMap;
use std::sync::Arc;

use glam::{DMat3, DQuat, DVec3};

use crate::sdf::error::{Result, SdfError};
use crate::sdf::mesh_field::MeshField;
use crate::sdf::primitives::{PolyTorus, Pyramid, RoundCone};
use crate::sdf::tree::{Node, NodeId, NodeInfo, Tree, TreeLimits};

/// Lanes per register: points evaluated per instruction loop.
pub const BATCH: usize = 256;

#[derive(Debug, Clone)]
pub(super) enum Inst {
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
    pub(super) insts: Vec<Inst>,
    pub(super) args: Vec<u32>,
    pub(super) meshes: Vec<Arc<MeshField>>,
    pub(super) n_vals: usize,
    pub(super) n_pts: usize,
    pub(super) out: u32,
    pub(super) max_args: usize,
    pub(super) info: NodeInfo,
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
        Evaluator::new(self)
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

pub use super::eval::{insertion_sort, smin, smin_sorted, Evaluator};
