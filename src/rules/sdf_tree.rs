//! Signed distance trees as the program holds them ([`SdfForest`]: the
//! `[sdf.NAME]` tables and inline trees of a file, compiled, children by
//! index so shared subtrees stay shared), and their evaluation into the
//! SDF pillar's [`Tree`] once parameter values are known
//! ([`SdfForest::build`]). Errors name the node (`tree.children[1]`), the
//! key and the place in the rule file.

use std::sync::Arc;

use glam::DVec3;

use super::expr::Expr;
use super::program::Arg;
use super::sdf_kinds::{KindDef, KindId, PLACEMENT};
use crate::sdf::{
    MeshField, Node, NodeId, Rotation, SdfError, SignMethod, SignMode, Tree, TreeLimits,
};

/// Deepest nesting of trees (inline tables and names) a file may write.
pub const MAX_TREE_DEPTH: usize = 64;

/// Limits the pillar applies to a built tree: each program node adds at
/// most four placement nodes.
pub fn tree_limits() -> TreeLimits {
    TreeLimits {
        max_depth: 5 * MAX_TREE_DEPTH + 8,
        ..TreeLimits::default()
    }
}

/// Every tree node of a program; children precede their parents.
#[derive(Debug, Clone, Default)]
pub struct SdfForest {
    pub nodes: Vec<SdfNode>,
}

/// One compiled node.
#[derive(Debug, Clone)]
pub struct SdfNode {
    pub kind: &'static KindDef,
    /// One per parameter of the kind, in its order, defaults filled in.
    pub args: Vec<Arg>,
    /// One per [`PLACEMENT`] key (`Absent` when not written).
    pub placement: Vec<Arg>,
    /// Indices of the children, all below this node's.
    pub children: Vec<usize>,
    /// Path for messages: the tree's name, then `.children[i]` / `.child`.
    pub name: String,
    /// `file:line:column` of the node's `kind`.
    pub location: String,
}

/// A tree built for meshing: the pillar's tree, its root, and for each
/// of its nodes the program node (and placement key) it came from.
pub struct BuiltTree {
    pub tree: Tree,
    pub root: NodeId,
    origins: Vec<(usize, Option<&'static str>)>,
}

/// A tree that cannot be built, at its program node.
#[derive(Debug, Clone, PartialEq)]
pub struct TreeError {
    /// Index of the program node.
    pub node: usize,
    /// The key the problem is about, when one is.
    pub key: Option<String>,
    /// Names the key itself.
    pub message: String,
}

/// How a mesh node's file becomes a distance field: by resource index,
/// sign mode and whether the file is Y-up. The engine builds each field
/// once per batch and shares it.
pub type FieldSource<'a> = dyn FnMut(usize, SignMode, bool) -> Result<Arc<MeshField>, String> + 'a;

impl SdfForest {
    /// Builds the tree rooted at program node `root` with parameter values
    /// `slots`. Only nodes reachable from `root` are built; a node reached
    /// twice is built once (the DAG stays a DAG).
    pub fn build(
        &self,
        root: usize,
        slots: &[f64],
        fields: &mut FieldSource,
    ) -> Result<BuiltTree, TreeError> {
        let mut reach = vec![false; root + 1];
        reach[root] = true;
        for i in (0..=root).rev() {
            if reach[i] {
                for &c in &self.nodes[i].children {
                    reach[c] = true;
                }
            }
        }
        let mut b = Builder {
            forest: self,
            tree: Tree::new(),
            origins: Vec::new(),
            built: vec![None; root + 1],
        };
        for i in (0..=root).filter(|&i| reach[i]) {
            let id = b.node(i, slots, fields)?;
            b.built[i] = Some(id);
        }
        Ok(BuiltTree {
            tree: b.tree,
            root: b.built[root].expect("the root is reachable"),
            origins: b.origins,
        })
    }

    /// The pillar's validation error about a node of `built`, as an error
    /// about the program node it came from.
    pub fn locate(&self, built: &BuiltTree, error: &SdfError) -> TreeError {
        let (node, field) = match error {
            SdfError::NonFinite { node, field, .. }
            | SdfError::NonPositive { node, field, .. }
            | SdfError::Negative { node, field, .. }
            | SdfError::Invalid { node, field, .. }
            | SdfError::BadChild { node, field, .. }
            | SdfError::TooFewChildren { node, field, .. }
            | SdfError::InexactChild { node, field, .. } => (*node, field.as_str()),
            SdfError::TooDeep { node, .. }
            | SdfError::EmptyBounds { node }
            | SdfError::Unbounded { node } => (*node, ""),
            _ => (built.root.index(), ""),
        };
        let (program_node, placement) = built
            .origins
            .get(node)
            .or_else(|| built.origins.get(built.root.index()))
            .copied()
            .expect("every built node has an origin");
        match placement {
            Some(key) => TreeError {
                node: program_node,
                key: Some(key.to_string()),
                message: format!("`{key}`: {}", without_node(error)),
            },
            None => TreeError {
                node: program_node,
                key: (!field.is_empty()).then(|| rule_key(field)),
                message: rule_message(error, field),
            },
        }
    }

    /// `file:line:column: sdf node `path`: message`, for errors at run time.
    pub fn describe(&self, error: &TreeError) -> String {
        let n = &self.nodes[error.node];
        format!("{}: sdf node `{}`: {}", n.location, n.name, error.message)
    }
}

/// The pillar's message without its "node N: " prefix (the caller names
/// the node its own way).
fn without_node(error: &SdfError) -> String {
    let text = error.to_string();
    match text.strip_prefix("node ") {
        Some(rest) => match rest.split_once(": ") {
            Some((_, message)) => message.to_string(),
            None => text,
        },
        None => text,
    }
}

/// The pillar's message with its field names spelled as rule files
/// spell them.
fn rule_message(error: &SdfError, field: &str) -> String {
    let key = rule_key(field);
    let text = without_node(error);
    if field.is_empty() || key == field {
        text
    } else {
        text.replacen(&format!("`{field}`"), &format!("`{key}`"), 1)
    }
}

/// A pillar field name (`k`, `base`, `subtract[0]`, `size[1]`) as the
/// rule file's key.
fn rule_key(field: &str) -> String {
    if field == "k" {
        return "blend".into();
    }
    if field == "base" {
        return "children[0]".into();
    }
    if let Some(i) = field
        .strip_prefix("subtract[")
        .and_then(|r| r.strip_suffix(']'))
        .and_then(|i| i.parse::<usize>().ok())
    {
        return format!("children[{}]", i + 1);
    }
    if field.starts_with("factors") {
        return "factor".into();
    }
    if field.starts_with("rotation") {
        return "about".into();
    }
    match field.split_once('[') {
        Some((key, _)) if key != "children" => key.into(),
        _ => field.into(),
    }
}

struct Builder<'f> {
    forest: &'f SdfForest,
    tree: Tree,
    origins: Vec<(usize, Option<&'static str>)>,
    built: Vec<Option<NodeId>>,
}

impl Builder<'_> {
    fn push(&mut self, node: Node, origin: (usize, Option<&'static str>)) -> NodeId {
        self.origins.push(origin);
        self.tree.push(node)
    }

    fn node(
        &mut self,
        i: usize,
        slots: &[f64],
        fields: &mut FieldSource,
    ) -> Result<NodeId, TreeError> {
        let n = &self.forest.nodes[i];
        let fail = |key: &str, message: String| TreeError {
            node: i,
            key: Some(key.to_string()),
            message: format!("`{key}` {message}"),
        };
        let arg = |key: &str| -> &Arg {
            let k = n
                .kind
                .params
                .iter()
                .position(|p| p.key == key)
                .unwrap_or_else(|| panic!("`{}` has no parameter `{key}`", n.kind.name));
            &n.args[k]
        };
        let s = |key: &str| scalar(arg(key), slots);
        let v = |key: &str| vector(arg(key), slots);
        let count = |key: &str| -> Result<u32, TreeError> {
            let x = libm::round(s(key));
            if !(x.is_finite() && (0.0..=u32::MAX as f64).contains(&x)) {
                return Err(fail(key, format!("must be a whole number, got {x}")));
            }
            Ok(x as u32)
        };
        let child = |k: usize| self.built[n.children[k]].expect("children are built first");
        let children = || -> Vec<NodeId> {
            n.children
                .iter()
                .map(|&c| self.built[c].expect("children are built first"))
                .collect()
        };
        let node = match n.kind.id {
            KindId::Sphere => Node::Sphere {
                radius: s("radius"),
            },
            KindId::Box => Node::Box { size: v("size") },
            KindId::RoundedBox => Node::RoundedBox {
                size: v("size"),
                radius: s("radius"),
            },
            KindId::Torus => Node::Torus {
                major_radius: s("major_radius"),
                minor_radius: s("minor_radius"),
            },
            KindId::PolygonalTorus => Node::PolygonalTorus {
                major_radius: s("major_radius"),
                minor_radius: s("minor_radius"),
                ring_sides: count("ring_sides")?,
                tube_sides: count("tube_sides")?,
            },
            KindId::Cylinder => Node::Cylinder {
                radius: s("radius"),
                height: s("height"),
            },
            KindId::Cone => Node::Cone {
                height: s("height"),
                bottom_radius: s("bottom_radius"),
                top_radius: s("top_radius"),
            },
            KindId::Prism => Node::Prism {
                sides: count("sides")?,
                radius: s("radius"),
                height: s("height"),
            },
            KindId::Pyramid => Node::Pyramid {
                sides: count("sides")?,
                radius: s("radius"),
                height: s("height"),
                top_height: match arg("top_height") {
                    Arg::Absent => None,
                    a => Some(scalar(a, slots)),
                },
            },
            KindId::Capsule => Node::Capsule {
                a: v("a"),
                b: v("b"),
                radius: s("radius"),
            },
            KindId::RoundCone => Node::RoundCone {
                a: v("a"),
                b: v("b"),
                radius_a: s("radius_a"),
                radius_b: s("radius_b"),
            },
            KindId::HalfSpace => Node::HalfSpace {
                normal: v("normal"),
                offset: s("offset"),
            },
            KindId::Mesh => {
                let Arg::Resource(resource) = arg("path") else {
                    unreachable!("a mesh node's path is a resource")
                };
                let sign = match choice(arg("sign")) {
                    1 => SignMode::Force(SignMethod::Pseudonormal),
                    2 => SignMode::Force(SignMethod::WindingNumber),
                    _ => SignMode::Auto,
                };
                let y_up = choice(arg("up")) == 1;
                let field = fields(*resource, sign, y_up).map_err(|e| fail("path", e))?;
                Node::Mesh(field)
            }
            KindId::Union => Node::Union(children()),
            KindId::Intersection => Node::Intersection(children()),
            KindId::Difference => {
                let c = children();
                Node::Difference {
                    base: c[0],
                    subtract: c[1..].to_vec(),
                }
            }
            KindId::SmoothUnion => Node::SmoothUnion {
                children: children(),
                k: s("blend"),
            },
            KindId::SmoothIntersection => Node::SmoothIntersection {
                children: children(),
                k: s("blend"),
            },
            KindId::SmoothDifference => {
                let c = children();
                Node::SmoothDifference {
                    base: c[0],
                    subtract: c[1..].to_vec(),
                    k: s("blend"),
                }
            }
            KindId::Translate => Node::Translate {
                child: child(0),
                offset: v("offset"),
            },
            KindId::Rotate => Node::Rotate {
                child: child(0),
                rotation: Rotation::AxisAngle {
                    axis: v("about"),
                    degrees: s("angle"),
                },
            },
            KindId::Scale => scale_node(child(0), v("factor")),
            KindId::Offset => Node::Offset {
                child: child(0),
                distance: s("distance"),
            },
            KindId::Shell => Node::Shell {
                child: child(0),
                thickness: s("thickness"),
            },
            KindId::PlaneCut => Node::PlaneCut {
                child: child(0),
                normal: v("normal"),
                point: v("point"),
            },
        };
        let mut id = self.push(node, (i, None));
        // Placement, in `PLACEMENT` order: scale, axis, euler, at.
        for (p, a) in PLACEMENT.iter().zip(&n.placement) {
            if matches!(a, Arg::Absent) {
                continue;
            }
            let value = vector(a, slots);
            let placed = match p.key {
                "scale" => scale_node(id, value),
                "axis" => {
                    if !(value.is_finite() && value.length_squared() > 0.0) {
                        return Err(fail(
                            "axis",
                            format!("must be a non-zero direction, got {value}"),
                        ));
                    }
                    Node::Rotate {
                        child: id,
                        rotation: Rotation::z_to(value),
                    }
                }
                "euler" => Node::Rotate {
                    child: id,
                    rotation: Rotation::EulerXyz { degrees: value },
                },
                "at" => Node::Translate {
                    child: id,
                    offset: value,
                },
                other => unreachable!("placement key {other}"),
            };
            id = self.push(placed, (i, Some(p.key)));
        }
        Ok(id)
    }
}

/// A uniform scale when the factors are equal (exact), else non-uniform
/// (a bound; spec D3).
fn scale_node(child: NodeId, f: DVec3) -> Node {
    if f.x == f.y && f.y == f.z {
        Node::Scale { child, factor: f.x }
    } else {
        Node::ScaleXyz { child, factors: f }
    }
}

fn scalar(a: &Arg, slots: &[f64]) -> f64 {
    match a {
        Arg::Scalar(e) => e.eval(slots),
        other => panic!("{other:?} is not a scalar"),
    }
}

fn vector(a: &Arg, slots: &[f64]) -> DVec3 {
    match a {
        Arg::Vector(v) => {
            let c = |e: &Expr| e.eval(slots);
            DVec3::new(c(&v.0[0]), c(&v.0[1]), c(&v.0[2]))
        }
        other => panic!("{other:?} is not a vector"),
    }
}

fn choice(a: &Arg) -> usize {
    match a {
        Arg::Choice(i) => *i,
        other => panic!("{other:?} is not a choice"),
    }
}
