//! The operation tree (thesis §1.5): primitives at the leaves, operations
//! above, as a DAG whose shared subtrees are referenced by index.
//!
//! # Building
//!
//! Nodes are pushed into a [`Tree`]; [`Tree::push`] returns the node's
//! [`NodeId`] (its index). A node may only refer to nodes pushed before it,
//! so a tree is acyclic by construction, and validation, contracts and
//! bounds are one forward pass: no input-driven recursion. Parameters are
//! resolved `f64`s: the caller has already evaluated rule-file expressions
//! and distributions.
//!
//! # Contracts (decision D1)
//!
//! Every node declares a [`Contract`]: its Lipschitz constant (1 for every
//! node kind here) and whether it is the exact distance outside and/or
//! inside the solid. The summary is [`Exactness`]: `Exact` (both), `Bound`
//! (1-Lipschitz, |f| ≤ distance) or `Lipschitz(L)`. A tree's contract
//! follows from its nodes (spec §1.4 tables): a union of exact children is
//! exact outside only, a difference is exact inside only, a non-uniform
//! scale is a bound, and so on. Smooth blends need exact children on the
//! side where they blend (union: outside; intersection: inside; difference:
//! base inside and subtrahends outside); otherwise validation fails with
//! [`SdfError::InexactChild`] unless [`TreeLimits::allow_inexact_blend`].
//!
//! # Bounds
//!
//! Each node has [`Bounds`]: a box `B` and a growth `g` such that every
//! sublevel set `{f ≤ t}` (t ≥ 0) lies in `B` grown by `g·t`. The zero set
//! and the solid lie in `B`. Knowing sublevel sets (not only the zero set)
//! is what makes the boxes of smooth unions (`{min ≤ k/4}`) and offsets
//! (`{f ≤ r}`) conservative even over bound children. Exact-outside nodes
//! have `g = 1`. Boxes may be inverted (empty) inside the tree; the root's
//! must not be.

use std::sync::Arc;

use glam::{DMat3, DQuat, DVec3};

use crate::sdf::aabb::Aabb;
use crate::sdf::error::{Result, SdfError};
use crate::sdf::mesh_field::MeshField;

use super::contract::{combine, fix_growth, half_space_box};
pub use super::contract::{Bounds, Contract, Exactness, NodeInfo};

/// Index of a node in its [`Tree`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct NodeId(pub u32);

impl NodeId {
    /// The index as `usize`.
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// A rotation as written in a rule file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rotation {
    /// Right-handed rotation by `degrees` about `axis` (any length > 0).
    AxisAngle { axis: DVec3, degrees: f64 },
    /// Euler angles in degrees, **extrinsic X, then Y, then Z**: rotate
    /// about the world X axis by `x`, then about world Y by `y`, then about
    /// world Z by `z`; the matrix is `Rz·Ry·Rx` (equivalently intrinsic
    /// Z–Y′–X″).
    EulerXyz { degrees: DVec3 },
    /// A quaternion (normalised on validation; must be non-zero).
    Quaternion(DQuat),
}

impl Rotation {
    /// The rotation taking the canonical local axis +Z onto `axis`
    /// (decision D2's `axis` field for axial primitives).
    pub fn z_to(axis: DVec3) -> Rotation {
        let z = DVec3::Z;
        let a = axis.normalize_or_zero();
        let c = z.dot(a);
        if c < -1.0 + 1e-15 {
            return Rotation::AxisAngle {
                axis: DVec3::X,
                degrees: 180.0,
            };
        }
        let cr = z.cross(a);
        if cr.length_squared() == 0.0 {
            return Rotation::Quaternion(DQuat::IDENTITY);
        }
        let deg = libm::atan2(cr.length(), c).to_degrees();
        Rotation::AxisAngle {
            axis: cr,
            degrees: deg,
        }
    }

    /// The unit quaternion, or `None` if the input is not finite or the
    /// axis / quaternion is zero. Uses `libm` sine and cosine.
    pub fn to_quat(&self) -> Option<DQuat> {
        fn axis_q(axis: DVec3, deg: f64) -> DQuat {
            let half = deg.to_radians() * 0.5;
            let (s, c) = (libm::sin(half), libm::cos(half));
            let v = axis * s;
            DQuat::from_xyzw(v.x, v.y, v.z, c)
        }
        match *self {
            Rotation::AxisAngle { axis, degrees } => {
                if !axis.is_finite() || !degrees.is_finite() || axis.length_squared() == 0.0 {
                    return None;
                }
                Some(axis_q(axis.normalize(), degrees))
            }
            Rotation::EulerXyz { degrees } => {
                if !degrees.is_finite() {
                    return None;
                }
                let qx = axis_q(DVec3::X, degrees.x);
                let qy = axis_q(DVec3::Y, degrees.y);
                let qz = axis_q(DVec3::Z, degrees.z);
                Some(qz * qy * qx)
            }
            Rotation::Quaternion(q) => {
                if !q.is_finite() || q.length_squared() == 0.0 {
                    return None;
                }
                Some(q.normalize())
            }
        }
    }
}

/// One node of the operation tree. Sizes are full edge lengths / heights;
/// axial primitives are centred on the origin along local +Z unless noted.
#[derive(Debug, Clone)]
pub enum Node {
    /// Sphere of `radius` at the origin (thesis §1.2.1).
    Sphere { radius: f64 },
    /// Box with edge lengths `size`, centred (thesis §1.2.2).
    Box { size: DVec3 },
    /// Box with edges rounded by `radius` (0 ≤ radius ≤ min(size)/2).
    RoundedBox { size: DVec3, radius: f64 },
    /// Torus about +Z (thesis §1.2.3; axis per D2).
    Torus {
        major_radius: f64,
        minor_radius: f64,
    },
    /// Polygonal torus (thesis §1.2.4): ring `ring_sides`-gon of apothem
    /// `major_radius` (0 = circle), tube `tube_sides`-gon of circumradius
    /// `minor_radius` (0 = circle).
    PolygonalTorus {
        major_radius: f64,
        minor_radius: f64,
        ring_sides: u32,
        tube_sides: u32,
    },
    /// Capped cylinder about +Z, z ∈ [−height/2, height/2].
    Cylinder { radius: f64, height: f64 },
    /// Cone or truncated cone about +Z, z ∈ [−height/2, height/2], radius
    /// `bottom_radius` at the bottom and `top_radius` at the top.
    Cone {
        height: f64,
        bottom_radius: f64,
        top_radius: f64,
    },
    /// Regular prism about +Z: `sides`-gon of circumradius `radius` (a
    /// vertex on +X), z ∈ [−height/2, height/2].
    Prism {
        sides: u32,
        radius: f64,
        height: f64,
    },
    /// Regular pyramid: `sides`-gon base of circumradius `radius` at z = 0
    /// (an edge normal on +X), apex at z = `height`; cut flat at z =
    /// `top_height` when given (a truncated pyramid).
    Pyramid {
        sides: u32,
        radius: f64,
        height: f64,
        top_height: Option<f64>,
    },
    /// Capsule: segment `a`–`b` with `radius`.
    Capsule { a: DVec3, b: DVec3, radius: f64 },
    /// Round cone (Quilez `sdRoundCone`): spheres (a, radius_a) and
    /// (b, radius_b) and the cone tangent to both; the sphere of the larger
    /// radius when one contains the other.
    RoundCone {
        a: DVec3,
        b: DVec3,
        radius_a: f64,
        radius_b: f64,
    },
    /// Half-space `normal·p ≤ offset` (`normal` is normalised).
    HalfSpace { normal: DVec3, offset: f64 },
    /// Distance to an imported triangle mesh (built once, shared).
    Mesh(Arc<MeshField>),
    /// n-ary union, `min` (thesis §1.3.1).
    Union(Vec<NodeId>),
    /// n-ary intersection, `max` (thesis §1.3.2).
    Intersection(Vec<NodeId>),
    /// `base` minus the union of `subtract`: max(base, −s₁, …) (§1.3.3).
    Difference { base: NodeId, subtract: Vec<NodeId> },
    /// Order-independent smooth union with blend radius `k` (D6).
    SmoothUnion { children: Vec<NodeId>, k: f64 },
    /// Order-independent smooth intersection with blend radius `k`.
    SmoothIntersection { children: Vec<NodeId>, k: f64 },
    /// Order-independent smooth difference with blend radius `k`.
    SmoothDifference {
        base: NodeId,
        subtract: Vec<NodeId>,
        k: f64,
    },
    /// Move the child by `offset` (thesis §1.4.1: f(x − t)).
    Translate { child: NodeId, offset: DVec3 },
    /// Rotate the child about the origin (thesis §1.4.1: f(R⁻¹x)).
    Rotate { child: NodeId, rotation: Rotation },
    /// Uniform scale: s·f(x/s) (D3; exact). Never the thesis's f(x)·s.
    Scale { child: NodeId, factor: f64 },
    /// Non-uniform scale: f(x/s)·min(s) (D3; a bound).
    ScaleXyz { child: NodeId, factors: DVec3 },
    /// Offset: f − distance (> 0 dilates, < 0 erodes).
    Offset { child: NodeId, distance: f64 },
    /// Shell: |f| − thickness (a wall of width 2·thickness on the surface).
    Shell { child: NodeId, thickness: f64 },
    /// Keep the side `normal·(x − point) ≤ 0`: max(f, normal·(x − point)).
    PlaneCut {
        child: NodeId,
        normal: DVec3,
        point: DVec3,
    },
}

impl Node {
    /// The node's children in order, with the field name each came from.
    pub fn children(&self) -> Vec<(NodeId, String)> {
        let list = |f: &str, v: &[NodeId]| -> Vec<(NodeId, String)> {
            v.iter()
                .enumerate()
                .map(|(i, c)| (*c, format!("{f}[{i}]")))
                .collect()
        };
        match self {
            Node::Union(c) | Node::Intersection(c) => list("children", c),
            Node::SmoothUnion { children, .. } | Node::SmoothIntersection { children, .. } => {
                list("children", children)
            }
            Node::Difference { base, subtract } | Node::SmoothDifference { base, subtract, .. } => {
                let mut v = vec![(*base, "base".to_string())];
                v.extend(list("subtract", subtract));
                v
            }
            Node::Translate { child, .. }
            | Node::Rotate { child, .. }
            | Node::Scale { child, .. }
            | Node::ScaleXyz { child, .. }
            | Node::Offset { child, .. }
            | Node::Shell { child, .. }
            | Node::PlaneCut { child, .. } => vec![(*child, "child".to_string())],
            _ => Vec::new(),
        }
    }

    /// The kind's name, as a rule file would spell it.
    pub fn kind_name(&self) -> &'static str {
        match self {
            Node::Sphere { .. } => "sphere",
            Node::Box { .. } => "box",
            Node::RoundedBox { .. } => "rounded_box",
            Node::Torus { .. } => "torus",
            Node::PolygonalTorus { .. } => "polygonal_torus",
            Node::Cylinder { .. } => "cylinder",
            Node::Cone { .. } => "cone",
            Node::Prism { .. } => "prism",
            Node::Pyramid { .. } => "pyramid",
            Node::Capsule { .. } => "capsule",
            Node::RoundCone { .. } => "round_cone",
            Node::HalfSpace { .. } => "half_space",
            Node::Mesh(_) => "mesh",
            Node::Union(_) => "union",
            Node::Intersection(_) => "intersection",
            Node::Difference { .. } => "difference",
            Node::SmoothUnion { .. } => "smooth_union",
            Node::SmoothIntersection { .. } => "smooth_intersection",
            Node::SmoothDifference { .. } => "smooth_difference",
            Node::Translate { .. } => "translate",
            Node::Rotate { .. } => "rotate",
            Node::Scale { .. } => "scale",
            Node::ScaleXyz { .. } => "scale_xyz",
            Node::Offset { .. } => "offset",
            Node::Shell { .. } => "shell",
            Node::PlaneCut { .. } => "plane_cut",
        }
    }
}

/// Limits of tree validation and compilation (input is untrusted).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TreeLimits {
    /// Most nodes a tree may hold.
    pub max_nodes: usize,
    /// Deepest path allowed (the compiler recurses at most this deep).
    pub max_depth: usize,
    /// Longest tape allowed (a DAG reached through many transforms can
    /// expand exponentially when compiled).
    pub max_instructions: usize,
    /// Accept smooth blends over children that are not exact where the
    /// blend needs it (the blend is then still 1-Lipschitz, but not the
    /// shape the formula promises).
    pub allow_inexact_blend: bool,
}

impl Default for TreeLimits {
    fn default() -> Self {
        TreeLimits {
            max_nodes: 1 << 20,
            max_depth: 256,
            max_instructions: 1 << 20,
            allow_inexact_blend: false,
        }
    }
}

/// An operation DAG. See the module doc.
#[derive(Debug, Clone, Default)]
pub struct Tree {
    nodes: Vec<Node>,
}

impl Tree {
    /// An empty tree.
    pub fn new() -> Self {
        Tree { nodes: Vec::new() }
    }

    /// Appends a node and returns its id. Nothing is checked here; call
    /// [`Tree::analyze`] or [`Tree::compile`](crate::sdf::tape).
    pub fn push(&mut self, node: Node) -> NodeId {
        self.nodes.push(node);
        NodeId((self.nodes.len() - 1) as u32)
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// True when there are no nodes.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The node with `id`, if any.
    pub fn node(&self, id: NodeId) -> Option<&Node> {
        self.nodes.get(id.index())
    }

    /// Validates every node reachable from `root` and returns its facts,
    /// indexed by node (`None` for unreachable nodes). One forward pass.
    pub fn analyze(&self, root: NodeId, limits: &TreeLimits) -> Result<Vec<Option<NodeInfo>>> {
        if self.nodes.len() > limits.max_nodes {
            return Err(SdfError::TooLarge {
                what: "tree nodes",
                count: self.nodes.len() as u64,
                limit: limits.max_nodes as u64,
            });
        }
        let r = root.index();
        if r >= self.nodes.len() {
            return Err(SdfError::BadChild {
                node: r,
                field: "root".into(),
                child: r,
            });
        }
        // Reachability, backwards: children always have smaller indices.
        let mut reach = vec![false; r + 1];
        reach[r] = true;
        for i in (0..=r).rev() {
            if !reach[i] {
                continue;
            }
            for (c, field) in self.nodes[i].children() {
                if c.index() >= i {
                    return Err(SdfError::BadChild {
                        node: i,
                        field,
                        child: c.index(),
                    });
                }
                reach[c.index()] = true;
            }
        }
        let mut infos: Vec<Option<NodeInfo>> = vec![None; r + 1];
        for i in 0..=r {
            if reach[i] {
                let info = self.node_info(i, &infos, limits)?;
                infos[i] = Some(info);
            }
        }
        Ok(infos)
    }

    /// Facts of the root only (validating the whole reachable tree).
    pub fn info(&self, root: NodeId, limits: &TreeLimits) -> Result<NodeInfo> {
        let infos = self.analyze(root, limits)?;
        infos[root.index()].ok_or(SdfError::Internal("root not analysed"))
    }

    fn node_info(
        &self,
        i: usize,
        infos: &[Option<NodeInfo>],
        limits: &TreeLimits,
    ) -> Result<NodeInfo> {
        let node = &self.nodes[i];
        let ch = |c: &NodeId| -> Result<NodeInfo> {
            infos[c.index()].ok_or(SdfError::Internal("child analysed after parent"))
        };
        let child_infos: Vec<NodeInfo> = node
            .children()
            .iter()
            .map(|(c, _)| ch(c))
            .collect::<Result<_>>()?;
        let depth = 1 + child_infos.iter().map(|c| c.depth).max().unwrap_or(0);
        if depth > limits.max_depth {
            return Err(SdfError::TooDeep {
                node: i,
                depth,
                limit: limits.max_depth,
            });
        }
        let v = Check { node: i };
        let exact_box = |aabb: Aabb| Bounds { aabb, growth: 1.0 };
        let (contract, bounds) = match node {
            Node::Sphere { radius } => {
                v.positive("radius", *radius)?;
                (
                    Contract::EXACT,
                    exact_box(Aabb::centered(DVec3::ZERO, DVec3::splat(*radius))),
                )
            }
            Node::Box { size } => {
                v.positive_vec("size", *size)?;
                (
                    Contract::EXACT,
                    exact_box(Aabb::centered(DVec3::ZERO, *size * 0.5)),
                )
            }
            Node::RoundedBox { size, radius } => {
                v.positive_vec("size", *size)?;
                v.non_negative("radius", *radius)?;
                if *radius > size.min_element() * 0.5 {
                    return Err(v.invalid(
                        "radius",
                        format!(
                            "{radius} exceeds half the smallest size {}",
                            size.min_element() * 0.5
                        ),
                    ));
                }
                (
                    Contract::EXACT,
                    exact_box(Aabb::centered(DVec3::ZERO, *size * 0.5)),
                )
            }
            Node::Torus {
                major_radius,
                minor_radius,
            } => {
                v.positive("major_radius", *major_radius)?;
                v.positive("minor_radius", *minor_radius)?;
                let e = DVec3::new(
                    major_radius + minor_radius,
                    major_radius + minor_radius,
                    *minor_radius,
                );
                // A spindle torus (minor > major) is exact only outside.
                let c = Contract::with(1.0, true, minor_radius <= major_radius);
                (c, exact_box(Aabb::centered(DVec3::ZERO, e)))
            }
            Node::PolygonalTorus {
                major_radius,
                minor_radius,
                ring_sides,
                tube_sides,
            } => {
                v.positive("major_radius", *major_radius)?;
                v.positive("minor_radius", *minor_radius)?;
                v.sides("ring_sides", *ring_sides, true)?;
                v.sides("tube_sides", *tube_sides, true)?;
                if minor_radius >= major_radius {
                    return Err(v.invalid("minor_radius", format!("the tube (circumradius {minor_radius}) must not reach the axis (major radius {major_radius})")));
                }
                // Inside ring sector j the function is the distance to that
                // sector's straight tube, clipped to the wedge of half-angle
                // a: {f ≤ t} reaches (R + r + t) / cos a from the axis.
                let (c, inv_cos) = if *ring_sides >= 3 {
                    let inv = 1.0 / libm::cos(std::f64::consts::PI / *ring_sides as f64);
                    (Contract::with(1.0, false, false), inv)
                } else {
                    (Contract::EXACT, 1.0)
                };
                let rxy = (major_radius + minor_radius) * inv_cos;
                let e = DVec3::new(rxy, rxy, *minor_radius);
                (
                    c,
                    Bounds {
                        aabb: Aabb::centered(DVec3::ZERO, e),
                        growth: inv_cos,
                    },
                )
            }
            Node::Cylinder { radius, height } => {
                v.positive("radius", *radius)?;
                v.positive("height", *height)?;
                (
                    Contract::EXACT,
                    exact_box(Aabb::centered(
                        DVec3::ZERO,
                        DVec3::new(*radius, *radius, height * 0.5),
                    )),
                )
            }
            Node::Cone {
                height,
                bottom_radius,
                top_radius,
            } => {
                v.positive("height", *height)?;
                v.non_negative("bottom_radius", *bottom_radius)?;
                v.non_negative("top_radius", *top_radius)?;
                if *bottom_radius == 0.0 && *top_radius == 0.0 {
                    return Err(v.invalid("bottom_radius", "both radii are zero".into()));
                }
                let r = bottom_radius.max(*top_radius);
                (
                    Contract::EXACT,
                    exact_box(Aabb::centered(DVec3::ZERO, DVec3::new(r, r, height * 0.5))),
                )
            }
            Node::Prism {
                sides,
                radius,
                height,
            } => {
                v.sides("sides", *sides, false)?;
                v.positive("radius", *radius)?;
                v.positive("height", *height)?;
                (
                    Contract::EXACT,
                    exact_box(Aabb::centered(
                        DVec3::ZERO,
                        DVec3::new(*radius, *radius, height * 0.5),
                    )),
                )
            }
            Node::Pyramid {
                sides,
                radius,
                height,
                top_height,
            } => {
                v.sides("sides", *sides, false)?;
                v.positive("radius", *radius)?;
                v.positive("height", *height)?;
                if let Some(t) = top_height {
                    v.positive("top_height", *t)?;
                    if *t >= *height {
                        return Err(v.invalid(
                            "top_height",
                            format!("{t} is not below the apex height {height}"),
                        ));
                    }
                }
                let top = top_height.unwrap_or(*height);
                (
                    Contract::EXACT,
                    exact_box(Aabb::new(
                        DVec3::new(-radius, -radius, 0.0),
                        DVec3::new(*radius, *radius, top),
                    )),
                )
            }
            Node::Capsule { a, b, radius } => {
                v.finite_vec("a", *a)?;
                v.finite_vec("b", *b)?;
                v.positive("radius", *radius)?;
                (
                    Contract::EXACT,
                    exact_box(Aabb::of_points([*a, *b]).grown(*radius)),
                )
            }
            Node::RoundCone {
                a,
                b,
                radius_a,
                radius_b,
            } => {
                v.finite_vec("a", *a)?;
                v.finite_vec("b", *b)?;
                v.positive("radius_a", *radius_a)?;
                v.positive("radius_b", *radius_b)?;
                let ba = Aabb::centered(*a, DVec3::splat(*radius_a))
                    .union(&Aabb::centered(*b, DVec3::splat(*radius_b)));
                (Contract::EXACT, exact_box(ba))
            }
            Node::HalfSpace { normal, offset } => {
                v.normal("normal", *normal)?;
                v.finite("offset", *offset)?;
                let n = normal.normalize();
                (Contract::EXACT, exact_box(half_space_box(n, *offset)))
            }
            Node::Mesh(field) => (Contract::EXACT, exact_box(field.bounds())),
            Node::Union(c) | Node::Intersection(c) => {
                if c.is_empty() {
                    return Err(SdfError::TooFewChildren {
                        node: i,
                        field: "children".into(),
                        min: 1,
                        got: 0,
                    });
                }
                let union = matches!(node, Node::Union(_));
                combine(&child_infos, union, 0.0)
            }
            Node::SmoothUnion { children, k } | Node::SmoothIntersection { children, k } => {
                if children.is_empty() {
                    return Err(SdfError::TooFewChildren {
                        node: i,
                        field: "children".into(),
                        min: 1,
                        got: 0,
                    });
                }
                v.non_negative("k", *k)?;
                let union = matches!(node, Node::SmoothUnion { .. });
                if *k > 0.0 && children.len() > 1 && !limits.allow_inexact_blend {
                    for (j, (ci, c)) in child_infos.iter().zip(children).enumerate() {
                        let ok = if union {
                            ci.exact_outside()
                        } else {
                            ci.exact_inside()
                        };
                        if !ok {
                            return Err(SdfError::InexactChild {
                                node: i,
                                field: format!("children[{j}]"),
                                child: c.index(),
                                side: if union { "outside" } else { "inside" },
                            });
                        }
                    }
                }
                if *k == 0.0 || children.len() == 1 {
                    combine(&child_infos, union, 0.0)
                } else {
                    combine(&child_infos, union, *k)
                }
            }
            Node::Difference { subtract, .. } | Node::SmoothDifference { subtract, .. } => {
                let k = match node {
                    Node::SmoothDifference { k, .. } => {
                        v.non_negative("k", *k)?;
                        *k
                    }
                    _ => 0.0,
                };
                let base = child_infos[0];
                let subs = &child_infos[1..];
                if k > 0.0 && !subs.is_empty() && !limits.allow_inexact_blend {
                    if !base.exact_inside() {
                        let b = node.children()[0].0;
                        return Err(SdfError::InexactChild {
                            node: i,
                            field: "base".into(),
                            child: b.index(),
                            side: "inside",
                        });
                    }
                    for (j, (si, s)) in subs.iter().zip(subtract).enumerate() {
                        if !si.exact_outside() {
                            return Err(SdfError::InexactChild {
                                node: i,
                                field: format!("subtract[{j}]"),
                                child: s.index(),
                                side: "outside",
                            });
                        }
                    }
                }
                let l = child_infos
                    .iter()
                    .map(|c| c.contract.lipschitz)
                    .fold(1.0, f64::max);
                let c = if subs.is_empty() {
                    base.contract
                } else if k > 0.0 {
                    Contract::with(l, false, false)
                } else {
                    Contract::with(
                        l,
                        false,
                        base.exact_inside() && subs.iter().all(|s| s.exact_outside()),
                    )
                };
                (c, fix_growth(c, base.bounds))
            }
            Node::Translate { offset, .. } => {
                v.finite_vec("offset", *offset)?;
                let c = child_infos[0];
                let b = Bounds {
                    aabb: Aabb::new(c.bounds.aabb.lo + *offset, c.bounds.aabb.hi + *offset),
                    growth: c.bounds.growth,
                };
                (c.contract, b)
            }
            Node::Rotate { rotation, .. } => {
                let q = rotation.to_quat().ok_or_else(|| {
                    v.invalid("rotation", "not finite, or a zero axis / quaternion".into())
                })?;
                let c = child_infos[0];
                let m = DMat3::from_quat(q);
                let aabb = c.bounds.aabb.transformed(&m, DVec3::ZERO);
                let rowsum = (0..3)
                    .map(|r| (0..3).map(|col| m.col(col)[r].abs()).sum::<f64>())
                    .fold(0.0, f64::max);
                let growth = if c.contract.exact_outside {
                    1.0
                } else {
                    c.bounds.growth * rowsum
                };
                (c.contract, Bounds { aabb, growth })
            }
            Node::Scale { factor, .. } => {
                v.positive("factor", *factor)?;
                let c = child_infos[0];
                let aabb = Aabb::new(c.bounds.aabb.lo * *factor, c.bounds.aabb.hi * *factor);
                (
                    c.contract,
                    Bounds {
                        aabb,
                        growth: c.bounds.growth,
                    },
                )
            }
            Node::ScaleXyz { factors, .. } => {
                v.positive_vec("factors", *factors)?;
                let c = child_infos[0];
                let aabb = Aabb::new(c.bounds.aabb.lo * *factors, c.bounds.aabb.hi * *factors);
                let uniform = factors.x == factors.y && factors.y == factors.z;
                let contract = if uniform {
                    c.contract
                } else {
                    Contract::with(c.contract.lipschitz, false, false)
                };
                let growth = c.bounds.growth * factors.max_element() / factors.min_element();
                (contract, fix_growth(contract, Bounds { aabb, growth }))
            }
            Node::Offset { distance, .. } => {
                v.finite("distance", *distance)?;
                let c = child_infos[0];
                let d = *distance;
                let contract = if d > 0.0 {
                    Contract::with(c.contract.lipschitz, c.exact_outside(), false)
                } else if d < 0.0 {
                    Contract::with(c.contract.lipschitz, false, c.exact_inside())
                } else {
                    c.contract
                };
                let aabb = if d > 0.0 {
                    c.bounds.at(d)
                } else {
                    c.bounds.aabb
                };
                (
                    contract,
                    fix_growth(
                        contract,
                        Bounds {
                            aabb,
                            growth: c.bounds.growth,
                        },
                    ),
                )
            }
            Node::Shell { thickness, .. } => {
                v.positive("thickness", *thickness)?;
                let c = child_infos[0];
                let exact = c.exact_inside() && c.exact_outside();
                let contract = Contract::with(c.contract.lipschitz, exact, false);
                let b = Bounds {
                    aabb: c.bounds.at(*thickness),
                    growth: c.bounds.growth,
                };
                (contract, fix_growth(contract, b))
            }
            Node::PlaneCut { normal, point, .. } => {
                v.normal("normal", *normal)?;
                v.finite_vec("point", *point)?;
                let c = child_infos[0];
                let n = normal.normalize();
                let hs = half_space_box(n, n.dot(*point));
                let contract = Contract::with(c.contract.lipschitz, false, c.exact_inside());
                let b = Bounds {
                    aabb: c.bounds.aabb.intersection(&hs),
                    growth: c.bounds.growth.max(1.0),
                };
                (contract, b)
            }
        };
        Ok(NodeInfo {
            contract,
            bounds,
            depth,
        })
    }
}

/// Parameter checks for one node.
struct Check {
    node: usize,
}

impl Check {
    fn finite(&self, field: &str, x: f64) -> Result<()> {
        if x.is_finite() {
            Ok(())
        } else {
            Err(SdfError::NonFinite {
                node: self.node,
                field: field.into(),
                value: x,
            })
        }
    }
    fn positive(&self, field: &str, x: f64) -> Result<()> {
        self.finite(field, x)?;
        if x > 0.0 {
            Ok(())
        } else {
            Err(SdfError::NonPositive {
                node: self.node,
                field: field.into(),
                value: x,
            })
        }
    }
    fn non_negative(&self, field: &str, x: f64) -> Result<()> {
        self.finite(field, x)?;
        if x >= 0.0 {
            Ok(())
        } else {
            Err(SdfError::Negative {
                node: self.node,
                field: field.into(),
                value: x,
            })
        }
    }
    fn finite_vec(&self, field: &str, v: DVec3) -> Result<()> {
        for a in 0..3 {
            self.finite(&format!("{field}[{a}]"), v[a])?;
        }
        Ok(())
    }
    fn positive_vec(&self, field: &str, v: DVec3) -> Result<()> {
        for a in 0..3 {
            self.positive(&format!("{field}[{a}]"), v[a])?;
        }
        Ok(())
    }
    fn normal(&self, field: &str, v: DVec3) -> Result<()> {
        self.finite_vec(field, v)?;
        if v.length_squared() > 0.0 && v.length_squared().is_finite() {
            Ok(())
        } else {
            Err(self.invalid(field, "zero or overflowing vector".into()))
        }
    }
    fn sides(&self, field: &str, n: u32, zero_ok: bool) -> Result<()> {
        if (zero_ok && n == 0) || (3..=1_000_000).contains(&n) {
            Ok(())
        } else {
            Err(self.invalid(
                field,
                format!(
                    "{n} sides (need {}3 ..= 1000000)",
                    if zero_ok { "0 or " } else { "" }
                ),
            ))
        }
    }
    fn invalid(&self, field: &str, reason: String) -> SdfError {
        SdfError::Invalid {
            node: self.node,
            field: field.into(),
            reason,
        }
    }
}
