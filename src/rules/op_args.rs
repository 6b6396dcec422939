//! Every operator's arguments, typed: what the compiler makes of an
//! operator's table and the engine matches on (exhaustively, so an
//! operator without an implementation does not compile, and nothing looks
//! an argument up by name or compares a choice as text at run time).
//!
//! The registry ([`super::operators`]) describes each parameter (key,
//! kind, default, bounds, docs) for the parser, the schema and the linter;
//! `compile::args` turns the checked table into these structs, reading it
//! by key once, at compile time. Choices are enums whose `NAMES` the
//! registry rows use, so the two cannot disagree. `tests/tooling.rs`
//! compiles every row's example, which builds every variant.

use super::program::{Scalar, Vector};

/// A choice parameter's enum: its names in the rule file, in order (the
/// registry's `Choice` list), and the value of each.
pub trait ChoiceArg: Sized + Copy + 'static {
    const NAMES: &'static [&'static str];
    const VALUES: &'static [Self];

    /// The value at `index` among [`Self::NAMES`].
    fn from_index(index: usize) -> Self {
        Self::VALUES[index]
    }
}

macro_rules! choice {
    ($(#[$doc:meta])* $name:ident { $($(#[$vdoc:meta])* $variant:ident = $text:literal),+ $(,)? }) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub enum $name {
            $($(#[$vdoc])* $variant),+
        }

        impl ChoiceArg for $name {
            const NAMES: &'static [&'static str] = &[$($text),+];
            const VALUES: &'static [Self] = &[$($name::$variant),+];
        }
    };
}

choice!(
    /// `import`'s up axis.
    UpAxis { Z = "z", Y = "y" }
);
choice!(
    /// What `delete` removes of the selection.
    DeleteKind { All = "all", Faces = "faces", FacesAndEdges = "faces_and_edges" }
);
choice!(
    /// `mirror`'s axis, when given instead of a normal.
    Axis { X = "x", Y = "y", Z = "z" }
);
choice!(
    /// Face adjacency of `region_extend` and `region_reduce`.
    Adjacency { Edge = "edge", Vert = "vert" }
);
choice!(
    /// How `skin` makes its solid.
    SkinMethod { Tubes = "tubes", Field = "field" }
);
choice!(
    /// The field mesher.
    Mesher { MarchingCubes = "marching_cubes", DualContouring = "dual_contouring" }
);
choice!(
    /// Where a vertex sits on a grid edge.
    VertexPlacement { Linear = "linear", Midpoint = "midpoint", Refine = "refine" }
);
choice!(
    /// Sample placement of a field's grid.
    GridKind { LatticeHalf = "lattice_half", Lattice = "lattice", Linspace = "linspace" }
);
choice!(
    /// `sdf_boolean`'s operation.
    BooleanOp { Difference = "difference", Union = "union", Intersection = "intersection" }
);
choice!(
    /// NURBS tessellation mode.
    TessMode { Adaptive = "adaptive", InterPatch = "interpatch", Uniform = "uniform" }
);
choice!(
    /// The adaptive tessellation's extra edge test (seed 002).
    EdgeTestName {
        Sagitta = "sagitta",
        OneEdgeNormal = "one_edge_normal",
        OneEdgeComplementary = "one_edge_complementary",
        TwoTriangle = "two_triangle",
        FirstOrderNeighbour = "first_order_neighbour",
        VectorDeviation = "vector_deviation",
        LocalFlat = "local_flat",
        UmbrellaFlat = "umbrella_flat",
    }
);
choice!(
    /// How several edge tests combine.
    Combine { Any = "any", All = "all" }
);
choice!(
    /// PN triangles' tessellation pattern.
    PnPattern { Uniform = "uniform", Gl = "gl" }
);

choice!(
    /// How `bevel`'s `width` is measured (Blender's offset types).
    BevelOffset { Offset = "offset", Width = "width", Depth = "depth", Percent = "percent" }
);
choice!(
    /// `subdivide`'s refinement rules.
    SubdivisionScheme { CatmullClark = "catmull_clark", Simple = "simple", Loop = "loop" }
);
choice!(
    /// `subdivide`'s boundary vertices of one face (OpenSubdiv's boundary
    /// interpolation: edge and corner, or edge only).
    SubdivisionBoundary { KeepCorners = "keep_corners", Smooth = "smooth" }
);

/// `extrude_*`: how far the copy moves (`offset` wins over `distance`).
#[derive(Debug, Clone)]
pub struct ExtrudeArgs {
    pub offset: Option<Vector>,
    pub distance: Option<Scalar>,
    pub keep_original: bool,
}

#[derive(Debug, Clone)]
pub struct InsetArgs {
    pub thickness: Scalar,
    pub depth: Scalar,
}

/// The grid of a step that meshes a signed distance field.
#[derive(Debug, Clone)]
pub struct MeshingArgs {
    /// Cell edge; `cells` when absent.
    pub cell: Option<Scalar>,
    /// Cells along the longest side (`skin` has no such key: `None`).
    pub cells: Option<Scalar>,
    pub mesher: Mesher,
    pub vertex: VertexPlacement,
    /// `skin` has no `grid` or `padding`: the defaults.
    pub grid: GridKind,
    pub padding: Option<Scalar>,
    pub domain: Option<Box<[Vector; 2]>>,
}

#[derive(Debug, Clone)]
pub struct SkinArgs {
    pub sides: Scalar,
    pub radius: Scalar,
    pub joints: bool,
    pub keep_wires: bool,
    pub method: SkinMethod,
    pub blend: Option<Scalar>,
    pub min_radius: Option<Scalar>,
    pub meshing: MeshingArgs,
}

/// How `nurbs` and `nurbs_part` tessellate.
#[derive(Debug, Clone)]
pub struct TessellateArgs {
    /// Index into [`super::program::Program::nurbs`].
    pub surface: usize,
    pub mode: TessMode,
    pub tolerance: Option<Scalar>,
    pub max_level: Scalar,
    pub test: EdgeTestName,
    pub threshold: Option<Scalar>,
    pub combine: Combine,
    pub cells: Option<[Scalar; 2]>,
    pub per_patch: bool,
}

/// A create, kernel or whole-mesh operator's arguments (G³ commands are
/// [`super::program::Command`]s).
#[derive(Debug, Clone)]
pub enum OpArgs {
    Vertex {
        at: Vector,
        radius: Option<Scalar>,
    },
    Circle {
        segments: Scalar,
        radius: Scalar,
        fill: bool,
    },
    Grid {
        segments: [Scalar; 2],
        size: [Scalar; 2],
    },
    Cube {
        size: Scalar,
    },
    UvSphere {
        segments: Scalar,
        rings: Scalar,
        radius: Scalar,
    },
    Cylinder {
        segments: Scalar,
        radius: Scalar,
        radius_top: Scalar,
        depth: Scalar,
        caps: bool,
    },
    Cone {
        segments: Scalar,
        radius: Scalar,
        depth: Scalar,
        caps: bool,
    },
    Import {
        /// Index into [`super::program::Program::resources`].
        path: usize,
        weld: Option<Scalar>,
        up: UpAxis,
    },
    Translate {
        offset: Vector,
    },
    Rotate {
        angle: Scalar,
        axis: Vector,
        center: Vector,
    },
    Scale {
        factor: Vector,
        center: Vector,
    },
    ExtrudeVerts(ExtrudeArgs),
    ExtrudeEdges(ExtrudeArgs),
    ExtrudeFaces(ExtrudeArgs),
    ExtrudeRegion(ExtrudeArgs),
    InsetFaces(InsetArgs),
    InsetRegion(InsetArgs),
    SplitEdges {
        cuts: Option<Scalar>,
        ratios: Option<Vec<Scalar>>,
    },
    Triangulate,
    Subdivide {
        scheme: SubdivisionScheme,
        levels: Scalar,
        boundary: SubdivisionBoundary,
        crease_angle: Option<Scalar>,
    },
    Crease {
        sharpness: Scalar,
    },
    ConvexHull {
        triangulate: bool,
    },
    Boolean {
        operation: BooleanOp,
        /// The other operand: every face of this part (an index into the
        /// program's parts).
        with: u32,
    },
    Spin {
        angle: Scalar,
        steps: Scalar,
        axis: Vector,
        center: Vector,
    },
    BridgeLoops {
        twist: Scalar,
        segments: Scalar,
    },
    Bevel {
        width: Scalar,
        offset_type: BevelOffset,
        segments: Scalar,
        profile: Scalar,
        clamp_overlap: bool,
    },
    Solidify {
        thickness: Scalar,
        offset: Scalar,
        even: bool,
        rim: bool,
    },
    Assign,
    Reverse,
    RecomputeNormals {
        outside: bool,
    },
    Delete {
        mode: DeleteKind,
    },
    Duplicate,
    DissolveEdges,
    MakeFace,
    Merge {
        distance: Scalar,
    },
    Mirror {
        axis: Option<Axis>,
        normal: Vector,
        point: Vector,
        merge_distance: Scalar,
    },
    RegionExtend {
        by: Adjacency,
    },
    RegionReduce {
        by: Adjacency,
    },
    Skin(Box<SkinArgs>),
    Sdf {
        /// The root node in [`super::program::Program::sdf`].
        tree: usize,
        meshing: Box<MeshingArgs>,
    },
    SdfPart {
        tree: usize,
        relative: bool,
        meshing: Box<MeshingArgs>,
    },
    SdfBoolean {
        tree: usize,
        operation: BooleanOp,
        blend: Scalar,
        meshing: Box<MeshingArgs>,
    },
    Nurbs(Box<TessellateArgs>),
    NurbsPart {
        tessellate: Box<TessellateArgs>,
        relative: bool,
    },
    NurbsPatch {
        lift: Scalar,
        cells: Scalar,
    },
    PnSmooth {
        level: Scalar,
        pattern: PnPattern,
        crease: Scalar,
    },
}
