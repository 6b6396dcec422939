//! The registry of signed-distance node kinds (thesis 004; spec
//! `implicit-and-parametric.md` §1): one definition per `kind` an
//! `[sdf.NAME]` table may name, with its children and parameters. Like the
//! operator registry ([`super::operators`]) it is read by the compiler, the
//! JSON Schema, the linter and the documentation test; the tree builder
//! ([`super::sdf_tree`]) matches on [`KindId`].
//!
//! Every node also takes the placement keys of [`PLACEMENT`]: `scale`,
//! then `axis`, then `euler`, then `at` are applied to it, in that order.

use super::operators::{param, required, ArgKind, Default, ParamDef};

/// Every node kind, by identity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum KindId {
    Sphere,
    Box,
    RoundedBox,
    Torus,
    PolygonalTorus,
    Cylinder,
    Cone,
    Prism,
    Pyramid,
    Capsule,
    RoundCone,
    HalfSpace,
    Mesh,
    Union,
    Intersection,
    Difference,
    SmoothUnion,
    SmoothIntersection,
    SmoothDifference,
    Translate,
    Rotate,
    Scale,
    Offset,
    Shell,
    PlaneCut,
}

/// What children a kind takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Children {
    /// A primitive.
    None,
    /// `child`: one tree.
    One,
    /// `children`: a list of trees, at least `min` (the first is the base
    /// of a difference).
    Many { min: usize },
}

/// One node kind.
#[derive(Debug)]
pub struct KindDef {
    pub id: KindId,
    /// The value of `kind` in rule files.
    pub name: &'static str,
    pub children: Children,
    pub params: &'static [ParamDef],
    /// Exact distance, or a bound (spec D1), for the documentation.
    pub exact: &'static str,
    pub summary: &'static str,
}

impl KindDef {
    pub fn param(&self, key: &str) -> Option<&ParamDef> {
        self.params.iter().find(|p| p.key == key)
    }
}

/// The kind named `name`.
pub fn find(name: &str) -> Option<&'static KindDef> {
    KINDS.iter().find(|k| k.name == name)
}

/// Every kind name, in table order.
pub fn names() -> impl Iterator<Item = &'static str> {
    KINDS.iter().map(|k| k.name)
}

/// The key naming a node's kind.
pub const KIND_KEY: &str = "kind";
/// The key of a one-child node's child.
pub const CHILD_KEY: &str = "child";
/// The key of an n-ary node's children.
pub const CHILDREN_KEY: &str = "children";

/// Placement keys every node takes, applied in this order.
pub static PLACEMENT: &[ParamDef] = &[
    param(
        "scale",
        ArgKind::Vector,
        Default::None,
        "scale factor, or [sx, sy, sz] (non-uniform: a bound, not an exact distance)",
    ),
    param(
        "axis",
        ArgKind::Vector,
        Default::None,
        "turn the local +Z axis onto this direction",
    ),
    param(
        "euler",
        ArgKind::Vector,
        Default::None,
        "rotate by [x, y, z] degrees, extrinsic X then Y then Z",
    ),
    param("at", ArgKind::Vector, Default::None, "move to this point"),
];

use ArgKind::{Choice, Path, Scalar, Vector};

const RADIUS: ParamDef = required("radius", Scalar, "radius");
const HEIGHT: ParamDef = required("height", Scalar, "height along local z");
const SIDES: ParamDef = required("sides", Scalar, "number of sides (at least 3)");
const BLEND: ParamDef = ParamDef {
    key: "blend",
    kind: Scalar,
    default: Default::None,
    required: true,
    min: Some(0.0),
    above: None,
    max: None,
    doc: "blend radius k: how far the blend reaches (0: sharp)",
};

/// The registry.
pub static KINDS: &[KindDef] = &[
    KindDef {
        id: KindId::Sphere,
        name: "sphere",
        children: Children::None,
        params: &[RADIUS],
        exact: "exact",
        summary: "a sphere centred on the origin",
    },
    KindDef {
        id: KindId::Box,
        name: "box",
        children: Children::None,
        params: &[required("size", Vector, "full edge lengths [x, y, z], or one for a cube")],
        exact: "exact",
        summary: "a box centred on the origin",
    },
    KindDef {
        id: KindId::RoundedBox,
        name: "rounded_box",
        children: Children::None,
        params: &[
            required("size", Vector, "full edge lengths [x, y, z]"),
            required("radius", Scalar, "edge rounding, at most half the smallest size"),
        ],
        exact: "exact",
        summary: "a box with rounded edges and corners, outer size kept",
    },
    KindDef {
        id: KindId::Torus,
        name: "torus",
        children: Children::None,
        params: &[
            required("major_radius", Scalar, "radius of the ring (centre of the tube)"),
            required("minor_radius", Scalar, "radius of the tube"),
        ],
        exact: "exact",
        summary: "a torus about local z",
    },
    KindDef {
        id: KindId::PolygonalTorus,
        name: "polygonal_torus",
        children: Children::None,
        params: &[
            required("major_radius", Scalar, "apothem of the ring polygon"),
            required("minor_radius", Scalar, "circumradius of the tube polygon"),
            param("ring_sides", Scalar, Default::Number(0.0), "sides of the ring (0: a circle)"),
            param("tube_sides", Scalar, Default::Number(0.0), "sides of the tube (0: a circle)"),
        ],
        exact: "exact with a circular ring, a bound with a polygonal one",
        summary: "a torus whose ring and tube may be regular polygons",
    },
    KindDef {
        id: KindId::Cylinder,
        name: "cylinder",
        children: Children::None,
        params: &[RADIUS, HEIGHT],
        exact: "exact",
        summary: "a capped cylinder about local z, centred on z = 0",
    },
    KindDef {
        id: KindId::Cone,
        name: "cone",
        children: Children::None,
        params: &[
            HEIGHT,
            required("bottom_radius", Scalar, "radius at z = −height/2"),
            param("top_radius", Scalar, Default::Number(0.0), "radius at z = +height/2 (0: a point; > 0: a truncated cone)"),
        ],
        exact: "exact",
        summary: "a cone or truncated cone about local z, centred on z = 0",
    },
    KindDef {
        id: KindId::Prism,
        name: "prism",
        children: Children::None,
        params: &[SIDES, required("radius", Scalar, "circumradius (a vertex on +x)"), HEIGHT],
        exact: "exact",
        summary: "a regular n-sided prism about local z, centred on z = 0",
    },
    KindDef {
        id: KindId::Pyramid,
        name: "pyramid",
        children: Children::None,
        params: &[
            SIDES,
            required("radius", Scalar, "circumradius of the base"),
            required("height", Scalar, "height of the apex above the base"),
            param("top_height", Scalar, Default::None, "cut flat at this height (a truncated pyramid)"),
        ],
        exact: "exact",
        summary: "a regular pyramid standing on z = 0",
    },
    KindDef {
        id: KindId::Capsule,
        name: "capsule",
        children: Children::None,
        params: &[
            required("a", Vector, "one end of the axis segment"),
            required("b", Vector, "the other end"),
            RADIUS,
        ],
        exact: "exact",
        summary: "the points within radius of the segment a–b",
    },
    KindDef {
        id: KindId::RoundCone,
        name: "round_cone",
        children: Children::None,
        params: &[
            required("a", Vector, "centre of the first sphere"),
            required("b", Vector, "centre of the second sphere"),
            required("radius_a", Scalar, "radius at a"),
            required("radius_b", Scalar, "radius at b"),
        ],
        exact: "exact",
        summary: "two spheres and the cone tangent to both (the skin's building block)",
    },
    KindDef {
        id: KindId::HalfSpace,
        name: "half_space",
        children: Children::None,
        params: &[
            required("normal", Vector, "outward normal"),
            param("offset", Scalar, Default::Number(0.0), "keep normal·p ≤ offset (0)"),
        ],
        exact: "exact",
        summary: "the half-space below a plane (unbounded: intersect it, or give a domain)",
    },
    KindDef {
        id: KindId::Mesh,
        name: "mesh",
        children: Children::None,
        params: &[
            required("path", Path, "OBJ, STL, PLY, glTF or GLB file, relative to the rule file"),
            param(
                "sign",
                Choice(&["auto", "pseudonormal", "winding"]),
                Default::Choice(0),
                "inside test: angle-weighted pseudonormals for a closed mesh, the generalized winding number otherwise (\"auto\")",
            ),
            param("up", Choice(&["z", "y"]), Default::Choice(0), "the file's up axis (OBJ, PLY, STL; \"z\")"),
        ],
        exact: "exact (distance to the nearest triangle)",
        summary: "a triangle mesh as a signed distance field",
    },
    KindDef {
        id: KindId::Union,
        name: "union",
        children: Children::Many { min: 1 },
        params: &[],
        exact: "exact outside",
        summary: "min of the children",
    },
    KindDef {
        id: KindId::Intersection,
        name: "intersection",
        children: Children::Many { min: 1 },
        params: &[],
        exact: "exact inside",
        summary: "max of the children",
    },
    KindDef {
        id: KindId::Difference,
        name: "difference",
        children: Children::Many { min: 2 },
        params: &[],
        exact: "exact inside",
        summary: "the first child minus the others",
    },
    KindDef {
        id: KindId::SmoothUnion,
        name: "smooth_union",
        children: Children::Many { min: 1 },
        params: &[BLEND],
        exact: "a bound",
        summary: "union with fillets of radius blend, independent of child order",
    },
    KindDef {
        id: KindId::SmoothIntersection,
        name: "smooth_intersection",
        children: Children::Many { min: 1 },
        params: &[BLEND],
        exact: "a bound",
        summary: "intersection with rounded edges, independent of child order",
    },
    KindDef {
        id: KindId::SmoothDifference,
        name: "smooth_difference",
        children: Children::Many { min: 2 },
        params: &[BLEND],
        exact: "a bound",
        summary: "the first child minus the others, with rounded edges",
    },
    KindDef {
        id: KindId::Translate,
        name: "translate",
        children: Children::One,
        params: &[required("offset", Vector, "displacement")],
        exact: "as the child",
        summary: "the child moved",
    },
    KindDef {
        id: KindId::Rotate,
        name: "rotate",
        children: Children::One,
        params: &[
            required("angle", Scalar, "degrees, right-handed about `about`"),
            param("about", Vector, Default::Vector([0.0, 0.0, 1.0]), "rotation axis ([0, 0, 1])"),
        ],
        exact: "as the child",
        summary: "the child rotated about the origin",
    },
    KindDef {
        id: KindId::Scale,
        name: "scale",
        children: Children::One,
        params: &[required("factor", Vector, "factor, or [sx, sy, sz]")],
        exact: "as the child when uniform (s·f(p/s)); a bound when not (f(p/s)·min s)",
        summary: "the child scaled about the origin",
    },
    KindDef {
        id: KindId::Offset,
        name: "offset",
        children: Children::One,
        params: &[required("distance", Scalar, "> 0 grows, < 0 shrinks")],
        exact: "exact outside when growing, inside when shrinking",
        summary: "the child grown or shrunk by a distance (f − distance)",
    },
    KindDef {
        id: KindId::Shell,
        name: "shell",
        children: Children::One,
        params: &[required("thickness", Scalar, "half the wall width")],
        exact: "exact outside",
        summary: "a wall of width 2·thickness around the child's surface (|f| − thickness)",
    },
    KindDef {
        id: KindId::PlaneCut,
        name: "plane_cut",
        children: Children::One,
        params: &[
            required("normal", Vector, "the side removed"),
            param("point", Vector, Default::Vector([0.0; 3]), "a point of the plane ([0, 0, 0])"),
        ],
        exact: "exact inside",
        summary: "the child cut by a plane, keeping normal·(p − point) ≤ 0",
    },
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_keys_do_not_clash() {
        for (i, a) in KINDS.iter().enumerate() {
            for b in &KINDS[i + 1..] {
                assert!(a.name != b.name && a.id != b.id, "{}", a.name);
            }
            for p in a.params {
                assert!(
                    PLACEMENT.iter().all(|q| q.key != p.key)
                        && ![KIND_KEY, CHILD_KEY, CHILDREN_KEY].contains(&p.key),
                    "{}.{}",
                    a.name,
                    p.key
                );
                assert!(!p.required || p.default == Default::None);
            }
        }
    }
}
