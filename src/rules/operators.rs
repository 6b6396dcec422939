//! The operator registry: one definition per rule-file operator (in the
//! spirit of BMesh's `bmesh_opdefines`). Each [`OperatorDef`] says the
//! operator's key, its family, the element kinds it selects, its
//! parameters (kind, default, bounds, documentation) and a summary. The
//! parser, the compiler, the JSON Schema, the linter, `explain` and the
//! documentation test all read this table; the engine's implementations
//! are matched on [`OpId`] (exhaustively: an operator without one does not
//! compile). ARCHITECTURE.md ("How to add an operator") walks through it.

use crate::kernel::Domain;

use super::op_args::{
    Adjacency, Axis, BevelOffset, BooleanOp, ChoiceArg, Combine, DeleteKind, EdgeTestName,
    GridKind, Mesher, PnPattern, SkinMethod, SubdivisionBoundary, SubdivisionScheme, TessMode,
    UpAxis, VertexPlacement,
};

/// Every operator, by identity (the engine's dispatch is a `match` on it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum OpId {
    Vertex,
    Circle,
    Grid,
    Cube,
    UvSphere,
    Cylinder,
    Cone,
    Import,
    Translate,
    Rotate,
    Scale,
    ExtrudeVerts,
    ExtrudeEdges,
    ExtrudeFaces,
    ExtrudeRegion,
    InsetFaces,
    InsetRegion,
    SplitEdges,
    Triangulate,
    Subdivide,
    Crease,
    Solidify,
    Bevel,
    Spin,
    BridgeLoops,
    ConvexHull,
    Boolean,
    Reverse,
    RecomputeNormals,
    Delete,
    Duplicate,
    DissolveEdges,
    MakeFace,
    Merge,
    Mirror,
    RegionExtend,
    RegionReduce,
    CreateEdge,
    SplitEdge,
    CreateFace,
    SplitFace,
    EditNode,
    Skin,
    Sdf,
    SdfPart,
    SdfBoolean,
    Nurbs,
    NurbsPart,
    NurbsPatch,
    PnSmooth,
    Assign,
}

/// How an operator runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// Makes geometry from nothing (no selection); allowed in `[start]`.
    Create,
    /// A kernel operator on the selected elements.
    Kernel,
    /// Works on the whole mesh (no selection).
    WholeMesh,
    /// A G³ command (thesis 003 §2.4.5): planned on generation Gₙ, then applied.
    Command,
}

/// What a parameter takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArgKind {
    /// A number or an expression over parameters.
    Scalar,
    /// A number or expression over parameters and the matched primitive's
    /// properties, evaluated per primitive (G³ commands).
    Element,
    /// `[x, y, z]` of scalars, or one scalar for all three.
    Vector,
    /// [`ArgKind::Vector`] of per-primitive values.
    ElementVector,
    /// `[a, b]` of scalars.
    Pair,
    /// A non-empty list of scalars.
    ScalarList,
    Bool,
    /// One of these names.
    Choice(&'static [&'static str]),
    /// A file, relative to the rule file.
    Path,
    /// A condition over the nodes of the matched face.
    NodeCondition,
    /// A signed distance tree: the name of an `[sdf.NAME]` table, or a
    /// tree written inline (`{ kind = "sphere", radius = 1 }`).
    Tree,
    /// An axis-aligned box, `[[x, y, z], [x, y, z]]` (lowest corner first).
    Bounds,
    /// A parametric surface: the name of a `[nurbs.NAME]` table.
    Surface,
    /// A part: the name a step's `part` (or a `[parts.NAME]` table) gives.
    Part,
}

/// A parameter's value when the file gives none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Default {
    /// Absent: the operator does without.
    None,
    Number(f64),
    Vector([f64; 3]),
    Pair([f64; 2]),
    Bool(bool),
    /// The index of a [`ArgKind::Choice`] name.
    Choice(usize),
    /// The value of another parameter of the same operator.
    SameAs(&'static str),
}

/// One parameter of an operator.
#[derive(Debug, Clone, Copy)]
pub struct ParamDef {
    pub key: &'static str,
    pub kind: ArgKind,
    pub default: Default,
    pub required: bool,
    /// Literal numbers must be at least this (an error before the run).
    pub min: Option<f64>,
    /// Literal numbers must be greater than this.
    pub above: Option<f64>,
    /// Literal numbers must be at most this.
    pub max: Option<f64>,
    pub doc: &'static str,
}

/// One operator.
#[derive(Debug)]
pub struct OperatorDef {
    pub id: OpId,
    /// The key in rule files.
    pub name: &'static str,
    pub family: Family,
    /// Element kinds `on` may name, the default first (empty: no selection).
    pub domains: &'static [Domain],
    pub params: &'static [ParamDef],
    /// Parameter pairs that exclude each other.
    pub exclusive: &'static [(&'static str, &'static str)],
    /// What of the selection its implementation reads (the engine hands
    /// it nothing else).
    pub reads: Reads,
    /// Whether what it returns is geometry a step's `part` and `material`
    /// tag: false for operators that move, merge or remove (naming a part
    /// on them is an error, not a silent no-op).
    pub tags: bool,
    /// The smallest table the compiler and the JSON Schema both accept
    /// (on a cube, after a step named `first`, with a `[nurbs.patch]`
    /// surface and a `mesh.obj` beside the file): what the tests compile
    /// for every operator.
    pub example: &'static str,
    /// One line for the schema, `explain` and the documentation.
    pub summary: &'static str,
}

/// What of the selected elements an operator's implementation reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reads {
    /// Nothing: it makes geometry from nothing or works on the whole mesh.
    Nothing,
    /// The selected elements as selected (faces, or edges, or vertices).
    Selection,
    /// The vertices of the selection (of its edges and faces too).
    Verts,
    /// The edges of the selection (of its faces too).
    Edges,
    /// The selection and everything under it (a face's edges and
    /// vertices).
    Everything,
    /// As [`Reads::Everything`], but selected faces alone (`delete`
    /// removes what is under them by its mode).
    EverythingUnlessFaces,
}

impl OperatorDef {
    pub fn param(&self, key: &str) -> Option<&ParamDef> {
        self.params.iter().find(|p| p.key == key)
    }

    /// Whether it makes geometry from nothing (and may start a file).
    pub fn is_create(&self) -> bool {
        self.family == Family::Create
    }

    /// The keys of its parameters, in table order.
    pub fn keys(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.params.iter().map(|p| p.key)
    }
}

/// The operator named `name`.
pub fn find(name: &str) -> Option<&'static OperatorDef> {
    OPERATORS.iter().find(|d| d.name == name)
}

/// The operator of identity `id`.
pub fn def(id: OpId) -> &'static OperatorDef {
    OPERATORS
        .iter()
        .find(|d| d.id == id)
        .expect("every OpId is registered")
}

/// Every operator key, in table order.
pub fn names() -> impl Iterator<Item = &'static str> {
    OPERATORS.iter().map(|d| d.name)
}

pub const fn param(
    key: &'static str,
    kind: ArgKind,
    default: Default,
    doc: &'static str,
) -> ParamDef {
    ParamDef {
        key,
        kind,
        default,
        required: false,
        min: None,
        above: None,
        max: None,
        doc,
    }
}

/// A parameter whose literal values must be greater than `bound`.
pub const fn above(key: &'static str, kind: ArgKind, bound: f64, doc: &'static str) -> ParamDef {
    ParamDef {
        key,
        kind,
        default: Default::None,
        required: false,
        min: None,
        above: Some(bound),
        max: None,
        doc,
    }
}

/// A parameter whose literal values must be at least `bound`.
pub const fn at_least(
    key: &'static str,
    kind: ArgKind,
    default: Default,
    bound: f64,
    doc: &'static str,
) -> ParamDef {
    ParamDef {
        key,
        kind,
        default,
        required: false,
        min: Some(bound),
        above: None,
        max: None,
        doc,
    }
}

pub const fn required(key: &'static str, kind: ArgKind, doc: &'static str) -> ParamDef {
    ParamDef {
        key,
        kind,
        default: Default::None,
        required: true,
        min: None,
        above: None,
        max: None,
        doc,
    }
}

use ArgKind::*;
use Domain::{Edge, Face, Vert};

const SEGMENTS: ParamDef = param(
    "segments",
    Scalar,
    Default::Number(32.0),
    "number of segments (32)",
);
const RADIUS: ParamDef = param("radius", Scalar, Default::Number(1.0), "radius (1)");
const DEPTH: ParamDef = param("depth", Scalar, Default::Number(2.0), "height along z (2)");
const CENTER: ParamDef = param(
    "center",
    Vector,
    Default::Vector([0.0; 3]),
    "fixed point ([0, 0, 0])",
);

const EXTRUDE: &[ParamDef] = &[
    param(
        "offset",
        Vector,
        Default::None,
        "move the extruded copy by this vector",
    ),
    param(
        "distance",
        Scalar,
        Default::None,
        "or move it this far along the normal",
    ),
    param(
        "keep_original",
        Bool,
        Default::Bool(false),
        "faces: keep the original face, flipped, closing the prism (false)",
    ),
];

const INSET: &[ParamDef] = &[
    required("thickness", Scalar, "inset width"),
    param(
        "depth",
        Scalar,
        Default::Number(0.0),
        "move the inner face along its normal (0)",
    ),
];

const REGION: &[ParamDef] = &[param(
    "by",
    Choice(Adjacency::NAMES),
    Default::Choice(0),
    "adjacency (\"edge\")",
)];

const fn spread(key: &'static str, doc: &'static str) -> ParamDef {
    ParamDef {
        key,
        kind: Element,
        default: Default::None,
        required: false,
        min: Some(0.0),
        above: None,
        max: None,
        doc,
    }
}

/// The parameters of a G³ command (thesis 003 §2.4.3); `split_face` adds `nodes`.
macro_rules! command_params {
    ($($extra:expr),*) => {
        &[
            param("length", Element, Default::None, "l: length of the new edge or displacement (relative: times the preceding primitive's length)"),
            param("radius", Element, Default::None, "radius of the new node (default: the preceding primitive's)"),
            param("heading", ElementVector, Default::None, "H as [x, y, z] in the reference or preceding frame's (H, L, U) basis"),
            param("up", ElementVector, Default::None, "U as [x, y, z]; L = U × H"),
            param("turn", Element, Default::None, "fixed rotation about U, degrees"),
            param("pitch", Element, Default::None, "fixed rotation about L, degrees"),
            param("roll", Element, Default::None, "fixed rotation about H, degrees"),
            spread("vary_length", "σ: uniform in (−σ, σ) added to the length"),
            spread("vary_radius", "σ: uniform in (−σ, σ) added to the radius"),
            spread("vary_turn", "σ: uniform in (−σ, σ) degrees added to the turn"),
            spread("vary_pitch", "σ: uniform in (−σ, σ) degrees added to the pitch"),
            spread("vary_roll", "σ: uniform in (−σ, σ) degrees added to the roll"),
            ParamDef {
                key: "probability",
                kind: Element,
                default: Default::None,
                required: false,
                min: Some(0.0),
                above: None,
                max: Some(1.0),
                doc: "chance of applying to each matched primitive, in [0, 1] (default 1)",
            },
            param("relative", Bool, Default::None, "relative to the preceding primitive instead of the reference frame"),
            $($extra),*
        ]
    };
}

const COMMAND: &[ParamDef] = command_params!();
const SPLIT_FACE: &[ParamDef] = command_params!(param(
    "nodes",
    NodeCondition,
    Default::None,
    "secondary condition over the face's nodes: which to join to the new node"
));

const TREE: ParamDef = required(
    "tree",
    Tree,
    "the shape: the name of an `[sdf.NAME]` tree, or a tree written inline",
);
const CELL: ParamDef = above(
    "cell",
    Scalar,
    0.0,
    "grid cell edge in model units (default: 64 cells along the longest side)",
);
const MESHER: ParamDef = param(
    "mesher",
    Choice(Mesher::NAMES),
    Default::Choice(0),
    "\"marching_cubes\" (smooth shapes) or \"dual_contouring\" (sharp edges and corners)",
);
const VERTEX: ParamDef = param(
    "vertex",
    Choice(VertexPlacement::NAMES),
    Default::Choice(0),
    "where a vertex sits on a grid edge: interpolated (\"linear\"), at the midpoint, or refined on the field (\"refine\": 12 regula falsi steps)",
);

const DOMAIN: ParamDef = param(
    "domain",
    Bounds,
    Default::None,
    "mesh this box instead, [[x, y, z], [x, y, z]]: a shape it cuts is capped",
);

/// The meshing parameters of every step that meshes a field, after the
/// step's own (`$first`).
macro_rules! meshing_params {
    ($($first:expr),*) => {
        &[
            $($first,)*
            CELL,
            ParamDef {
                key: "cells",
                kind: Scalar,
                default: Default::None,
                required: false,
                min: Some(1.0),
                above: None,
                max: None,
                doc: "or this many cells along the longest side of the domain (64)",
            },
            MESHER,
            VERTEX,
            param(
                "grid",
                Choice(GridKind::NAMES),
                Default::Choice(0),
                "sample placement: cell centres of a lattice through the origin offset by half a cell (\"lattice_half\", no sample on a coordinate plane), the lattice k·h, or N evenly spaced samples spanning the domain (\"linspace\", as scikit-image)",
            ),
            at_least(
                "padding",
                Scalar,
                Default::Number(1.0),
                0.0,
                "cells added around the shape's bounding box (1)",
            ),
            DOMAIN,
        ]
    };
}

/// `sdf_part` and `nurbs_part`: whether the part follows the primitive's size.
const RELATIVE: ParamDef = param(
    "relative",
    Bool,
    Default::Bool(true),
    "scale the part (and its cell or tolerance) by the primitive's size: √area of a face, length of an edge, radius of a node (true)",
);

const SDF: &[ParamDef] = meshing_params!(TREE);
const SDF_PART: &[ParamDef] = meshing_params!(TREE, RELATIVE);
const SDF_BOOLEAN: &[ParamDef] = meshing_params!(
    TREE,
    param(
        "operation",
        Choice(BooleanOp::NAMES),
        Default::Choice(0),
        "the mesh minus, plus or intersected with the tree (\"difference\")",
    ),
    at_least(
        "blend",
        Scalar,
        Default::Number(0.0),
        0.0,
        "blend radius of a smooth operation (0: sharp)",
    )
);

const ANY: &[Domain] = &[Vert, Edge, Face];
const FACES: &[Domain] = &[Face];
const FACES_EDGES: &[Domain] = &[Face, Edge];

/// The registry.
pub static OPERATORS: &[OperatorDef] = &[
    OperatorDef {
        id: OpId::Vertex,
        name: "vertex",
        family: Family::Create,
        domains: &[],
        params: &[
            param(
                "at",
                Vector,
                Default::Vector([0.0; 3]),
                "position ([0, 0, 0])",
            ),
            param("radius", Scalar, Default::None, "node radius"),
        ],
        exclusive: &[],
        reads: Reads::Nothing,
        tags: true,
        example: "{}",
        summary: "create: one vertex (node)",
    },
    OperatorDef {
        id: OpId::Circle,
        name: "circle",
        family: Family::Create,
        domains: &[],
        params: &[
            SEGMENTS,
            RADIUS,
            param(
                "fill",
                Bool,
                Default::Bool(false),
                "fill with a face (false)",
            ),
        ],
        exclusive: &[],
        reads: Reads::Nothing,
        tags: true,
        example: "{}",
        summary: "create: a circle in the XY plane",
    },
    OperatorDef {
        id: OpId::Grid,
        name: "grid",
        family: Family::Create,
        domains: &[],
        params: &[
            param(
                "segments",
                Pair,
                Default::Pair([1.0, 1.0]),
                "[nx, ny] quads ([1, 1])",
            ),
            param(
                "size",
                Pair,
                Default::Pair([2.0, 2.0]),
                "[sx, sy] full extents ([2, 2])",
            ),
        ],
        exclusive: &[],
        reads: Reads::Nothing,
        tags: true,
        example: "{}",
        summary: "create: a grid of quads in the XY plane",
    },
    OperatorDef {
        id: OpId::Cube,
        name: "cube",
        family: Family::Create,
        domains: &[],
        params: &[param(
            "size",
            Scalar,
            Default::Number(2.0),
            "edge length (2)",
        )],
        exclusive: &[],
        reads: Reads::Nothing,
        tags: true,
        example: "{}",
        summary: "create: a centred cube",
    },
    OperatorDef {
        id: OpId::UvSphere,
        name: "uv_sphere",
        family: Family::Create,
        domains: &[],
        params: &[
            SEGMENTS,
            param(
                "rings",
                Scalar,
                Default::Number(16.0),
                "number of rings (16)",
            ),
            RADIUS,
        ],
        exclusive: &[],
        reads: Reads::Nothing,
        tags: true,
        example: "{}",
        summary: "create: a UV sphere",
    },
    OperatorDef {
        id: OpId::Cylinder,
        name: "cylinder",
        family: Family::Create,
        domains: &[],
        params: &[
            SEGMENTS,
            RADIUS,
            param(
                "radius_top",
                Scalar,
                Default::SameAs("radius"),
                "top radius (= radius)",
            ),
            DEPTH,
            param("caps", Bool, Default::Bool(true), "close the ends (true)"),
        ],
        exclusive: &[],
        reads: Reads::Nothing,
        tags: true,
        example: "{}",
        summary: "create: a cylinder along z",
    },
    OperatorDef {
        id: OpId::Cone,
        name: "cone",
        family: Family::Create,
        domains: &[],
        params: &[
            SEGMENTS,
            RADIUS,
            DEPTH,
            param("caps", Bool, Default::Bool(true), "close the base (true)"),
        ],
        exclusive: &[],
        reads: Reads::Nothing,
        tags: true,
        example: "{}",
        summary: "create: a cone along z",
    },
    OperatorDef {
        id: OpId::Import,
        name: "import",
        family: Family::Create,
        domains: &[],
        params: &[
            required(
                "path",
                Path,
                "OBJ, STL, PLY, glTF or GLB file, relative to the rule file",
            ),
            ParamDef {
                key: "weld",
                kind: Scalar,
                default: Default::None,
                required: false,
                min: Some(0.0),
                above: None,
                max: None,
                doc: "merge vertices at most this far apart (0: identical positions)",
            },
            param(
                "up",
                Choice(UpAxis::NAMES),
                Default::Choice(0),
                "the file's up axis (OBJ, PLY, STL; \"z\")",
            ),
        ],
        exclusive: &[],
        reads: Reads::Nothing,
        tags: true,
        example: "{ path = \"mesh.obj\" }",
        summary: "create: a mesh from a file",
    },
    OperatorDef {
        id: OpId::Translate,
        name: "translate",
        family: Family::Kernel,
        domains: ANY,
        params: &[required("offset", Vector, "displacement")],
        exclusive: &[],
        reads: Reads::Verts,
        tags: false,
        example: "{ offset = 1 }",
        summary: "move the selected elements' vertices",
    },
    OperatorDef {
        id: OpId::Rotate,
        name: "rotate",
        family: Family::Kernel,
        domains: ANY,
        params: &[
            required("angle", Scalar, "degrees, counter-clockwise about axis"),
            param(
                "axis",
                Vector,
                Default::Vector([0.0, 0.0, 1.0]),
                "rotation axis ([0, 0, 1])",
            ),
            CENTER,
        ],
        exclusive: &[],
        reads: Reads::Verts,
        tags: false,
        example: "{ angle = 10 }",
        summary: "rotate the selected elements' vertices",
    },
    OperatorDef {
        id: OpId::Scale,
        name: "scale",
        family: Family::Kernel,
        domains: ANY,
        params: &[required("factor", Vector, "scale factors"), CENTER],
        exclusive: &[],
        reads: Reads::Verts,
        tags: false,
        example: "{ factor = 2 }",
        summary: "scale the selected elements' vertices",
    },
    OperatorDef {
        id: OpId::ExtrudeVerts,
        name: "extrude_verts",
        family: Family::Kernel,
        domains: ANY,
        params: EXTRUDE,
        exclusive: &[("offset", "distance")],
        reads: Reads::Verts,
        tags: true,
        example: "{ offset = [0, 0, 1] }",
        summary: "extrude vertices into edges",
    },
    OperatorDef {
        id: OpId::ExtrudeEdges,
        name: "extrude_edges",
        family: Family::Kernel,
        domains: &[Edge, Face],
        params: EXTRUDE,
        exclusive: &[("offset", "distance")],
        reads: Reads::Edges,
        tags: true,
        example: "{ offset = [0, 0, 1] }",
        summary: "extrude edges into faces",
    },
    OperatorDef {
        id: OpId::ExtrudeFaces,
        name: "extrude_faces",
        family: Family::Kernel,
        domains: FACES,
        params: EXTRUDE,
        exclusive: &[("offset", "distance")],
        reads: Reads::Selection,
        tags: true,
        example: "{ distance = 1 }",
        summary: "extrude each face separately",
    },
    OperatorDef {
        id: OpId::ExtrudeRegion,
        name: "extrude_region",
        family: Family::Kernel,
        domains: FACES,
        params: EXTRUDE,
        exclusive: &[("offset", "distance")],
        reads: Reads::Selection,
        tags: true,
        example: "{ distance = 1 }",
        summary: "extrude the faces as one region",
    },
    OperatorDef {
        id: OpId::InsetFaces,
        name: "inset_faces",
        family: Family::Kernel,
        domains: FACES,
        params: INSET,
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{ thickness = 0.1 }",
        summary: "inset each face separately",
    },
    OperatorDef {
        id: OpId::InsetRegion,
        name: "inset_region",
        family: Family::Kernel,
        domains: FACES,
        params: INSET,
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{ thickness = 0.1 }",
        summary: "inset the faces as one region",
    },
    OperatorDef {
        id: OpId::SplitEdges,
        name: "split_edges",
        family: Family::Kernel,
        domains: &[Edge, Face],
        params: &[
            param("cuts", Scalar, Default::None, "equal parts (1 cut)"),
            param(
                "ratios",
                ScalarList,
                Default::None,
                "cut positions in (0, 1), increasing, from the edge's first vertex",
            ),
        ],
        exclusive: &[("cuts", "ratios")],
        reads: Reads::Edges,
        tags: true,
        example: "{ cuts = 2 }",
        summary: "split edges into parts",
    },
    OperatorDef {
        id: OpId::Triangulate,
        name: "triangulate",
        family: Family::Kernel,
        domains: FACES,
        params: &[],
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{}",
        summary: "triangulate faces",
    },
    OperatorDef {
        id: OpId::Subdivide,
        name: "subdivide",
        family: Family::Kernel,
        domains: FACES,
        params: &[
            param(
                "scheme",
                Choice(SubdivisionScheme::NAMES),
                Default::Choice(0),
                "\"catmull_clark\" (any faces), \"simple\" (its topology, the shape unchanged) or \"loop\" (triangles)",
            ),
            ParamDef {
                key: "levels",
                kind: Scalar,
                default: Default::Number(1.0),
                required: false,
                min: Some(1.0),
                above: None,
                max: Some(8.0),
                doc: "times to refine, 1 to 8 (1)",
            },
            param(
                "boundary",
                Choice(SubdivisionBoundary::NAMES),
                Default::Choice(0),
                "\"keep_corners\": a boundary vertex of one face stays put (OpenSubdiv's default); \"smooth\": it follows the boundary curve",
            ),
            param(
                "crease_angle",
                Scalar,
                Default::None,
                "edges whose two faces meet at more than this many degrees stay sharp (none)",
            ),
        ],
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{ levels = 2 }",
        summary: "subdivision surface: Catmull–Clark, simple or Loop, with OpenSubdiv's boundary and crease rules",
    },
    OperatorDef {
        id: OpId::Crease,
        name: "crease",
        family: Family::Kernel,
        domains: &[Edge, Face],
        params: &[at_least(
            "sharpness",
            Scalar,
            Default::Number(10.0),
            0.0,
            "levels of `subdivide` the edges stay sharp; fractions blend, 10 or more is always (10)",
        )],
        exclusive: &[],
        reads: Reads::Edges,
        tags: false,
        example: "{ sharpness = 2 }",
        summary: "mark edges as creases for `subdivide` (OpenSubdiv sharpness)",
    },
    OperatorDef {
        id: OpId::Solidify,
        name: "solidify",
        family: Family::Kernel,
        domains: FACES,
        params: &[
            required("thickness", Scalar, "distance between the two shells (negative: against the normals)"),
            ParamDef {
                key: "offset",
                kind: Scalar,
                default: Default::Number(-1.0),
                required: false,
                min: Some(-1.0),
                above: None,
                max: Some(1.0),
                doc: "where the shell lies: -1 behind the faces (default), 0 centred, 1 in front",
            },
            param(
                "even",
                Bool,
                Default::Bool(false),
                "keep the thickness where the sheet bends (Blender's \"Even Thickness\"; false)",
            ),
            param(
                "rim",
                Bool,
                Default::Bool(true),
                "close the boundary with rim faces (true)",
            ),
        ],
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{ thickness = 0.1 }",
        summary: "give faces thickness: a closed shell with rims (Blender's simple solidify)",
    },
    OperatorDef {
        id: OpId::Bevel,
        name: "bevel",
        family: Family::Kernel,
        domains: &[Edge, Vert],
        params: &[
            required("width", Scalar, "how much to cut, measured as `offset_type` says"),
            param(
                "offset_type",
                Choice(BevelOffset::NAMES),
                Default::Choice(0),
                "\"offset\" (from the edge to each new edge, default), \"width\" (across the band), \"depth\" (from the edge to the band) or \"percent\" (of the adjacent edges' lengths)",
            ),
            ParamDef {
                key: "segments",
                kind: Scalar,
                default: Default::Number(1.0),
                required: false,
                min: Some(1.0),
                above: None,
                max: Some(1000.0),
                doc: "faces across each band, 1 to 1000 (1)",
            },
            ParamDef {
                key: "profile",
                kind: Scalar,
                default: Default::Number(0.5),
                required: false,
                min: None,
                above: Some(0.0),
                max: Some(1.0),
                doc: "shape across the band: 0.5 round (default), 0.25 straight, 1 square",
            },
            param(
                "clamp_overlap",
                Bool,
                Default::Bool(true),
                "scale the width down so that no new corner passes another (true)",
            ),
        ],
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{ width = 0.05, segments = 3 }",
        summary: "bevel edges (or vertices) into rounded or chamfered bands, as Blender's bevel",
    },
    OperatorDef {
        id: OpId::Spin,
        name: "spin",
        family: Family::Kernel,
        domains: &[Edge, Vert],
        params: &[
            param(
                "angle",
                Scalar,
                Default::Number(360.0),
                "degrees, counter-clockwise about `axis`, at most one turn (360)",
            ),
            at_least("steps", Scalar, Default::Number(12.0), 1.0, "rings made (12)"),
            param("axis", Vector, Default::Vector([0.0, 0.0, 1.0]), "axis direction ([0,0,1])"),
            CENTER,
        ],
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{ angle = 90, steps = 4 }",
        summary: "lathe: sweep edges into bands (vertices into arcs) about an axis; seam and poles merged",
    },
    OperatorDef {
        id: OpId::BridgeLoops,
        name: "bridge_loops",
        family: Family::Kernel,
        domains: &[Edge],
        params: &[
            param(
                "twist",
                Scalar,
                Default::Number(0.0),
                "whole places the pairing of closed loops is turned past the best one (0)",
            ),
            at_least(
                "segments",
                Scalar,
                Default::Number(1.0),
                1.0,
                "faces across each band (1)",
            ),
        ],
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{ twist = 1, segments = 4 }",
        summary: "join two or more selected edge loops, in order, by bands of quads (Blender's bridge_loops)",
    },
    OperatorDef {
        id: OpId::ConvexHull,
        name: "convex_hull",
        family: Family::Kernel,
        domains: &[Vert, Edge, Face],
        params: &[param(
            "triangulate",
            Bool,
            Default::Bool(false),
            "triangles instead of the merged coplanar polygons (false)",
        )],
        exclusive: &[],
        reads: Reads::Verts,
        tags: true,
        example: "{}",
        summary: "convex hull of the selected vertices as a new closed shell (exact; coplanar faces merged)",
    },
    OperatorDef {
        id: OpId::Boolean,
        name: "boolean",
        family: Family::Kernel,
        domains: FACES,
        params: &[
            param(
                "operation",
                Choice(BooleanOp::NAMES),
                Default::Choice(0),
                "the selection minus, plus or intersected with the part (\"difference\")",
            ),
            required(
                "with",
                Part,
                "the part whose faces are the other operand (a closed shell)",
            ),
        ],
        exclusive: &[],
        reads: Reads::Selection,
        tags: false,
        example: "{ operation = \"union\", with = \"cutter\" }",
        summary: "exact mesh boolean of the selected faces' closed shells and a part's: the result replaces both (pieces keep their faces' parts and materials)",
    },
    OperatorDef {
        id: OpId::Assign,
        name: "assign",
        family: Family::Kernel,
        domains: FACES_EDGES,
        params: &[],
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{}",
        summary: "give the selected faces (or wire edges) the step's `part` and `material`; geometry unchanged",
    },
    OperatorDef {
        id: OpId::Reverse,
        name: "reverse",
        family: Family::Kernel,
        domains: FACES,
        params: &[],
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{}",
        summary: "reverse face winding",
    },
    OperatorDef {
        id: OpId::RecomputeNormals,
        name: "recompute_normals",
        family: Family::Kernel,
        domains: FACES,
        params: &[param(
            "outside",
            Bool,
            Default::Bool(true),
            "make winding consistent and outward (true)",
        )],
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{}",
        summary: "make winding consistent",
    },
    OperatorDef {
        id: OpId::Delete,
        name: "delete",
        family: Family::Kernel,
        domains: &[Face, Edge, Vert],
        params: &[param(
            "mode",
            Choice(DeleteKind::NAMES),
            Default::Choice(0),
            "what goes with the elements (\"all\")",
        )],
        exclusive: &[],
        reads: Reads::EverythingUnlessFaces,
        tags: false,
        example: "{}",
        summary: "delete elements",
    },
    OperatorDef {
        id: OpId::Duplicate,
        name: "duplicate",
        family: Family::Kernel,
        domains: &[Face, Edge, Vert],
        params: &[],
        exclusive: &[],
        reads: Reads::Everything,
        tags: true,
        example: "{}",
        summary: "duplicate elements",
    },
    OperatorDef {
        id: OpId::DissolveEdges,
        name: "dissolve_edges",
        family: Family::Kernel,
        domains: &[Edge, Face],
        params: &[],
        exclusive: &[],
        reads: Reads::Edges,
        tags: false,
        example: "{}",
        summary: "dissolve regions of edges into single faces",
    },
    OperatorDef {
        id: OpId::MakeFace,
        name: "make_face",
        family: Family::Kernel,
        domains: &[Edge, Face],
        params: &[],
        exclusive: &[],
        reads: Reads::Edges,
        tags: true,
        example: "{}",
        summary: "make a face from a closed ring of edges",
    },
    OperatorDef {
        id: OpId::Merge,
        name: "merge",
        family: Family::Kernel,
        domains: ANY,
        params: &[required(
            "distance",
            Scalar,
            "merge vertices within this distance",
        )],
        exclusive: &[],
        reads: Reads::Verts,
        tags: false,
        example: "{ distance = 0.1 }",
        summary: "merge vertices by distance",
    },
    OperatorDef {
        id: OpId::Mirror,
        name: "mirror",
        family: Family::Kernel,
        domains: &[Face, Edge, Vert],
        params: &[
            param(
                "axis",
                Choice(Axis::NAMES),
                Default::None,
                "mirror across the plane perpendicular to this axis",
            ),
            param(
                "normal",
                Vector,
                Default::Vector([1.0, 0.0, 0.0]),
                "or to this normal",
            ),
            param(
                "point",
                Vector,
                Default::Vector([0.0; 3]),
                "a point of the plane ([0, 0, 0])",
            ),
            param(
                "merge_distance",
                Scalar,
                Default::Number(1e-6),
                "weld distance at the seam (1e-6)",
            ),
        ],
        exclusive: &[("axis", "normal")],
        reads: Reads::Everything,
        tags: true,
        example: "{ axis = \"x\" }",
        summary: "mirror across a plane, welding the seam",
    },
    OperatorDef {
        id: OpId::RegionExtend,
        name: "region_extend",
        family: Family::Kernel,
        domains: FACES,
        params: REGION,
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{}",
        summary: "grow the face selection",
    },
    OperatorDef {
        id: OpId::RegionReduce,
        name: "region_reduce",
        family: Family::Kernel,
        domains: FACES,
        params: REGION,
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{}",
        summary: "shrink the face selection",
    },
    OperatorDef {
        id: OpId::CreateEdge,
        name: "create_edge",
        family: Family::Command,
        domains: &[Vert],
        params: COMMAND,
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{ length = 1 }",
        summary: "G³: new node n₁ = n₀ + l·H and edge (n₀, n₁) on every matching node",
    },
    OperatorDef {
        id: OpId::SplitEdge,
        name: "split_edge",
        family: Family::Command,
        domains: &[Edge],
        params: COMMAND,
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{}",
        summary: "G³: split every matching edge at n₀ + l·H",
    },
    OperatorDef {
        id: OpId::CreateFace,
        name: "create_face",
        family: Family::Command,
        domains: &[Edge],
        params: COMMAND,
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{}",
        summary: "G³: a triangle on every matching edge",
    },
    OperatorDef {
        id: OpId::SplitFace,
        name: "split_face",
        family: Family::Command,
        domains: FACES,
        params: SPLIT_FACE,
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{ length = 0.5 }",
        summary: "G³: a fan from a new node at the barycentre (+ l·H) of every matching face",
    },
    OperatorDef {
        id: OpId::EditNode,
        name: "edit_node",
        family: Family::Command,
        domains: &[Vert],
        params: COMMAND,
        exclusive: &[],
        reads: Reads::Selection,
        tags: false,
        example: "{ length = 0.1 }",
        summary: "G³: move every matching node by l·H, set its radius",
    },
    OperatorDef {
        id: OpId::Skin,
        name: "skin",
        family: Family::WholeMesh,
        domains: &[Edge],
        params: &[
            param(
                "sides",
                Scalar,
                Default::Number(8.0),
                "sides of the tube cross-section (8)",
            ),
            param(
                "radius",
                Scalar,
                Default::Number(0.1),
                "radius for nodes without one (0.1)",
            ),
            param(
                "joints",
                Bool,
                Default::Bool(true),
                "spheres at branch nodes (true)",
            ),
            param(
                "keep_wires",
                Bool,
                Default::Bool(false),
                "keep the wire edges (false)",
            ),
            param(
                "method",
                Choice(SkinMethod::NAMES),
                Default::Choice(0),
                "\"tubes\": a polygonal tube per wire edge (fast; tubes overlap at branches); \"field\": one watertight solid per connected skeleton, meshed from a smooth union of round cones",
            ),
            at_least(
                "blend",
                Scalar,
                Default::None,
                0.0,
                "field: blend radius at branches (default: half the smallest node radius)",
            ),
            at_least(
                "min_radius",
                Scalar,
                Default::None,
                0.0,
                "field: thinner nodes are thickened to this radius (the cell follows the thinnest node)",
            ),
            CELL_SKIN,
            MESHER,
            VERTEX,
            DOMAIN,
        ],
        exclusive: &[],
        reads: Reads::Nothing,
        tags: true,
        example: "{ sides = 6 }",
        summary: "turn every wire edge into a tapered tube, or the skeleton into one smooth solid",
    },
    OperatorDef {
        id: OpId::Sdf,
        name: "sdf",
        family: Family::Create,
        domains: &[],
        params: SDF,
        exclusive: &[("cell", "cells")],
        reads: Reads::Nothing,
        tags: true,
        example: "{ tree = { kind = \"sphere\", radius = 1 }, cells = 8 }",
        summary: "create: a signed distance tree, meshed (closed, manifold, outward)",
    },
    OperatorDef {
        id: OpId::SdfPart,
        name: "sdf_part",
        family: Family::Kernel,
        domains: &[Face, Vert, Edge],
        params: SDF_PART,
        exclusive: &[("cell", "cells")],
        reads: Reads::Selection,
        tags: true,
        example: "{ tree = { kind = \"sphere\", radius = 0.2 }, cells = 8 }",
        summary: "a meshed signed distance tree placed in the frame of every selected primitive (a face's centre and normal, a node's frame, an edge's midpoint and direction), appended",
    },
    OperatorDef {
        id: OpId::SdfBoolean,
        name: "sdf_boolean",
        family: Family::WholeMesh,
        domains: &[Face],
        params: SDF_BOOLEAN,
        exclusive: &[("cell", "cells")],
        reads: Reads::Nothing,
        tags: true,
        example: "{ tree = { kind = \"sphere\", radius = 0.5 }, cells = 8 }",
        summary: "combine the mesh with a signed distance tree through the mesh's distance field, and re-mesh the result",
    },
    OperatorDef {
        id: OpId::Nurbs,
        name: "nurbs",
        family: Family::Create,
        domains: &[],
        params: NURBS,
        exclusive: &[],
        reads: Reads::Nothing,
        tags: true,
        example: "{ surface = \"patch\" }",
        summary: "create: a NURBS surface, tessellated into a conforming triangle mesh",
    },
    OperatorDef {
        id: OpId::NurbsPart,
        name: "nurbs_part",
        family: Family::Kernel,
        domains: &[Face, Vert, Edge],
        params: NURBS_PART,
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{ surface = \"patch\", mode = \"uniform\", cells = [2, 2] }",
        summary: "a tessellated NURBS surface placed in the frame of every selected primitive (as sdf_part), appended",
    },
    OperatorDef {
        id: OpId::NurbsPatch,
        name: "nurbs_patch",
        family: Family::Kernel,
        domains: &[Face],
        params: &[
            param(
                "lift",
                Scalar,
                Default::Number(0.25),
                "how far the patch's four inner control points rise along the face normal, in face sizes (√area; 0.25)",
            ),
            ParamDef {
                key: "cells",
                kind: Scalar,
                default: Default::Number(8.0),
                required: false,
                min: Some(1.0),
                above: None,
                max: Some(256.0),
                doc: "grid cells along each side of the quad (8)",
            },
        ],
        exclusive: &[],
        reads: Reads::Selection,
        tags: true,
        example: "{ cells = 2 }",
        summary: "replace every selected quad by a bicubic Bézier patch on its corners (inner control points lifted along the normal), as an n × n grid; edges shared with other faces are split alike, so the mesh stays conforming",
    },
    OperatorDef {
        id: OpId::PnSmooth,
        name: "pn_smooth",
        family: Family::WholeMesh,
        domains: &[Face],
        params: &[
            ParamDef {
                key: "level",
                kind: Scalar,
                default: Default::Number(3.0),
                required: false,
                min: Some(1.0),
                above: None,
                max: Some(MAX_PN_LEVEL as f64),
                doc: "segments per input edge (3): every triangle becomes level² triangles (uniform)",
            },
            param(
                "pattern",
                Choice(PnPattern::NAMES),
                Default::Choice(0),
                "\"uniform\" (a regular barycentric grid) or \"gl\" (OpenGL's ring pattern: a 12-triangle cube at level 5 gives 444 triangles)",
            ),
            ParamDef {
                key: "crease",
                kind: Scalar,
                default: Default::Number(30.0),
                required: false,
                min: Some(0.0),
                above: None,
                max: Some(180.0),
                doc: "degrees: edges whose faces meet at a sharper angle keep split normals, so they stay sharp without opening the mesh (30)",
            },
        ],
        exclusive: &[],
        reads: Reads::Nothing,
        tags: true,
        example: "{ level = 2 }",
        summary: "replace the mesh by PN (curved) triangles: cubic geometry from its vertex normals, closed input stays closed",
    },
];

/// The parameters of the operators that tessellate a surface, after the
/// operator's own (`$extra`).
macro_rules! tessellation_params {
    ($($extra:expr),*) => {
        &[
            required("surface", Surface, "the name of a [nurbs.NAME] surface"),
            param(
                "mode",
                Choice(TessMode::NAMES),
                Default::Choice(0),
                "tessellation: refined in rounds until every edge meets `tolerance` (\"adaptive\"), levels per Bézier patch and border (\"interpatch\"), or a regular grid (\"uniform\")",
            ),
            above(
                "tolerance",
                Scalar,
                0.0,
                "adaptive and interpatch: largest distance from the surface, model units (0.001)",
            ),
            ParamDef {
                key: "max_level",
                kind: Scalar,
                default: Default::Number(12.0),
                required: false,
                min: Some(1.0),
                above: None,
                max: Some(MAX_TESSELLATION_LEVEL as f64),
                doc: "adaptive: most halvings of an edge (12)",
            },
            param(
                "test",
                Choice(EdgeTestName::NAMES),
                Default::Choice(0),
                "adaptive: a thesis edge test (§2.2) applied besides the chordal `tolerance` (\"sagitta\": that alone)",
            ),
            above(
                "threshold",
                Scalar,
                0.0,
                "the test's threshold: |ΔN| for the normal tests (0.02), cos of the largest angle for vector_deviation (cos 2°), |U·N| for the flat tests (0.05)",
            ),
            param(
                "combine",
                Choice(Combine::NAMES),
                Default::Choice(0),
                "adaptive: split an edge when either test says so (\"any\") or only when both do (\"all\")",
            ),
            ParamDef {
                key: "cells",
                kind: Pair,
                default: Default::None,
                required: false,
                min: Some(1.0),
                above: None,
                max: None,
                doc: "uniform: cells along u and v, [8, 8] by default",
            },
            param(
                "per_patch",
                Bool,
                Default::Bool(true),
                "uniform: `cells` per Bézier patch (knot span) rather than over the whole surface (true)",
            ),
            $($extra,)*
        ]
    };
}

const NURBS: &[ParamDef] = tessellation_params!();
const NURBS_PART: &[ParamDef] = tessellation_params!(RELATIVE);

/// Most halvings of an edge adaptive tessellation accepts.
pub const MAX_TESSELLATION_LEVEL: u32 = 24;
/// Largest PN level (a triangle becomes level² triangles): the pillar's.
pub use crate::nurbs::pn::MAX_PN_LEVEL;

const CELL_SKIN: ParamDef = above(
    "cell",
    Scalar,
    0.0,
    "field: grid cell edge (default: half the smallest node radius)",
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_ids_are_unique_and_parameters_consistent() {
        for (i, a) in OPERATORS.iter().enumerate() {
            for b in &OPERATORS[i + 1..] {
                assert!(a.name != b.name && a.id != b.id, "{} twice", a.name);
            }
            assert_eq!(def(a.id).name, a.name);
            for (k, p) in a.params.iter().enumerate() {
                assert!(
                    a.params[k + 1..].iter().all(|q| q.key != p.key),
                    "{}.{}",
                    a.name,
                    p.key
                );
                if let Default::SameAs(other) = p.default {
                    assert!(a.param(other).is_some(), "{}.{}", a.name, p.key);
                }
                if let (Choice(names), Default::Choice(i)) = (p.kind, p.default) {
                    assert!(i < names.len());
                }
                assert!(!p.required || p.default == Default::None);
            }
            for (x, y) in a.exclusive {
                assert!(a.param(x).is_some() && a.param(y).is_some(), "{}", a.name);
            }
            assert_eq!(
                a.domains.is_empty(),
                a.family == Family::Create,
                "{}",
                a.name
            );
        }
    }
}
