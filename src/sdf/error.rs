//! Error values of the SDF pillar.
//!
//! Every fallible entry point returns [`SdfError`]; nothing in the library
//! panics on bad input. Errors about tree nodes carry the node index (the
//! [`NodeId`](crate::sdf::tree::NodeId) the caller got from
//! [`Tree::push`](crate::sdf::tree::Tree::push)) and the field name, so the
//! rule-file compiler can map them back to a source location.

/// An error of tree validation, compilation, mesh-field construction,
/// meshing or skinning.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SdfError {
    /// A number that must be finite is NaN or infinite.
    #[error("node {node}: `{field}` must be finite, got {value}")]
    NonFinite {
        node: usize,
        field: String,
        value: f64,
    },
    /// A size, radius or factor that must be > 0 is not.
    #[error("node {node}: `{field}` must be positive, got {value}")]
    NonPositive {
        node: usize,
        field: String,
        value: f64,
    },
    /// A quantity that must be ≥ 0 (blend radius, thickness) is negative.
    #[error("node {node}: `{field}` must not be negative, got {value}")]
    Negative {
        node: usize,
        field: String,
        value: f64,
    },
    /// Any other out-of-range parameter (too few sides, a rounding radius
    /// larger than the box, a zero normal, a truncation above the apex …).
    #[error("node {node}: `{field}`: {reason}")]
    Invalid {
        node: usize,
        field: String,
        reason: String,
    },
    /// A child reference that does not name an earlier node (children must
    /// be pushed before their parents, which also makes cycles impossible).
    #[error("node {node}: `{field}` refers to node {child}, which is not an earlier node")]
    BadChild {
        node: usize,
        field: String,
        child: usize,
    },
    /// An n-ary operation with too few children.
    #[error("node {node}: `{field}` needs at least {min} child(ren), got {got}")]
    TooFewChildren {
        node: usize,
        field: String,
        min: usize,
        got: usize,
    },
    /// A smooth operation over a child that is only a bound where the blend
    /// needs an exact distance (spec D1; a blend of bounds is not the blend
    /// the user asked for, and its bounding box is not known).
    #[error("node {node}: `{field}` is not exact {side}, which a smooth blend needs (a nested smooth operation or a non-uniform scale is only a bound); flatten nested blends into one n-ary node")]
    InexactChild {
        node: usize,
        field: String,
        child: usize,
        side: &'static str,
    },
    /// The tree is deeper than the limit (input-driven recursion is bounded).
    #[error("node {node}: tree depth {depth} exceeds the limit {limit}")]
    TooDeep {
        node: usize,
        depth: usize,
        limit: usize,
    },
    /// Too many nodes, or the compiled tape would be too long (a DAG whose
    /// shared subtrees are reached through many different transforms).
    #[error("{what}: {count} exceeds the limit {limit}")]
    TooLarge {
        what: &'static str,
        count: u64,
        limit: u64,
    },
    /// The root's bounding box is empty (an intersection of disjoint parts).
    #[error("node {node}: the shape is empty (its bounding box is empty)")]
    EmptyBounds { node: usize },
    /// The root is unbounded (a bare half-space); give an explicit domain.
    #[error("node {node}: the shape is unbounded; give an explicit meshing domain")]
    Unbounded { node: usize },
    /// The grid would have more cells than allowed. Checked before anything
    /// is allocated; `cells` is the predicted count.
    #[error("the grid would have {cells} cells ({nx} x {ny} x {nz}), more than the limit {limit}")]
    TooManyCells {
        cells: u128,
        nx: u64,
        ny: u64,
        nz: u64,
        limit: u64,
    },
    /// The output would have more triangles than allowed.
    #[error("the mesh would have more than {limit} triangles")]
    TooManyTriangles { limit: u64 },
    /// The output would have more vertices than allowed.
    #[error("the mesh would have more than {limit} vertices")]
    TooManyVertices { limit: u64 },
    /// A meshing or skinning option is out of range.
    #[error("option `{field}`: {reason}")]
    InvalidOption { field: &'static str, reason: String },
    /// Mesh-field input: a triangle refers to a missing vertex.
    #[error(
        "mesh: triangle {triangle} refers to vertex {index}, but there are only {count} vertices"
    )]
    MeshIndex {
        triangle: usize,
        index: u32,
        count: usize,
    },
    /// Mesh-field input: a vertex coordinate is NaN or infinite.
    #[error("mesh: vertex {vertex} has a non-finite coordinate")]
    MeshNonFinite { vertex: usize },
    /// Mesh-field input: nothing is left after dropping degenerate triangles.
    #[error("mesh: no non-degenerate triangle ({dropped} dropped)")]
    MeshEmpty { dropped: usize },
    /// Skin input: a skeleton node is invalid.
    #[error("skeleton node {node}: `{field}`: {reason}")]
    SkinNode {
        node: usize,
        field: &'static str,
        reason: String,
    },
    /// Skin input: a skeleton edge is invalid.
    #[error("skeleton edge {edge}: {reason}")]
    SkinEdge { edge: usize, reason: String },
    /// The cell is too coarse for the thinnest skeleton part (spec §4.4).
    #[error("cell {cell} is too coarse for the smallest radius {min_radius}: radius / cell = {ratio:.3} < 1.5")]
    CellTooCoarse {
        cell: f64,
        min_radius: f64,
        ratio: f64,
    },
    /// A broken internal invariant (a bug); reported instead of panicking.
    #[error("internal error: {0}")]
    Internal(&'static str),
}

/// Result alias of the SDF pillar.
pub type Result<T> = std::result::Result<T, SdfError>;
