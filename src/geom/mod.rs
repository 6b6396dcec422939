//! The geometry floor: math every other part of graftal shares, knowing
//! nothing of the rest of the crate (no kernel, rules, engine or files).
//!
//! - [`polygon`]: Newell normals, areas, plane bases, triangulation of any
//!   ring (constrained Delaunay through spade, ear clipping as a bounded
//!   fallback).
//! - [`predicates`]: exact orientation tests and segment/triangle contact
//!   (robust `orient3d`/`orient2d` with filters).
//! - [`boxes`]: conservative `f32` boxes around `f64` geometry (rounded
//!   outward, so a broad phase never loses a candidate).
//! - [`frame`]: orthonormal turtle frames and a deterministic perpendicular.
//! - [`hull`]: convex hulls of points (Quickhull on exact predicates,
//!   coplanar faces merged).
//! - [`interval`]: interval arithmetic with a NaN flag (the linter judges
//!   conditions with it).
//! - [`indexed`]: [`IndexedMesh`], the neutral polygon mesh every reader
//!   makes and every writer takes, and [`sink`]: the [`MeshSink`] trait
//!   every producer of geometry emits through; [`source`]: the
//!   [`source::PolygonSource`] trait writers stream from instead.
//! - [`material`]: PBR metallic-roughness materials and the sRGB
//!   transfer functions; [`normals`]: shading normals split at creases;
//!   [`uv`]: texture-coordinate projections; [`tubes`]: wire edges as
//!   closed prisms a viewer draws.
//! - [`cells`]: hash-grid cells for fixed-distance searches (8 cells, not
//!   27).
//! - [`union_find`], [`names`] (the "did you mean" of every message) and
//!   [`edge_key`] (one `u64` key for an edge between two vertex ids).

pub mod boolean;
pub mod boxes;
pub mod cells;
pub mod edge_key;
pub mod frame;
pub mod hull;
pub mod indexed;
pub mod interval;
pub mod material;
pub mod names;
pub mod normals;
pub mod polygon;
pub mod predicates;
pub mod sink;
pub mod source;
pub mod tubes;
pub mod union_find;
pub mod uv;

pub use indexed::IndexedMesh;
pub use material::Material;
pub use sink::MeshSink;
pub use union_find::UnionFind;
