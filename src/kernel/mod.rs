//! The polygon kernel: a BMesh-like non-manifold mesh (seed 000).
//!
//! - [`Mesh`] stores vertices, edges, loops and faces in index-based arenas
//!   ([`ids`]) with disk, radial and boundary cycles ([`mesh`]).
//! - [`euler`] holds the Euler operators, the only code that writes
//!   adjacency (with `grid_build`, the bulk MakeTriangleGrid:
//!   [`Mesh::append_triangle_grid`]); [`Mesh::validate`] checks every
//!   invariant.
//! - [`attrs`] holds named per-element attribute layers.
//! - [`ops`] holds the high-level modelling operators built on Euler
//!   operators, each returning a typed result naming what it made.
//! - [`build`] is the kernel's [`MeshSink`](crate::geom::MeshSink): emitted
//!   geometry becomes kernel elements, and [`Mesh::emit`] hands a mesh to
//!   any sink (the writers' [`IndexedMesh`](crate::geom::IndexedMesh)).
//! - [`intersect`] holds exact intersection predicates, a BVH broad phase,
//!   self-intersection, an incremental index for growth tests and
//!   close-vertex detection.
//!
//! The kernel uses only the geometry floor ([`crate::geom`]); it knows
//! nothing of rule files, grammars or file formats.

mod arena;
pub mod attrs;
pub mod build;
pub mod euler;
mod grid_build;
pub mod ids;
pub mod intersect;
pub mod measure;
pub mod mesh;
pub mod ops;
mod pooled;
pub mod validate;

pub use attrs::{AttrValue, LayerKind};
pub use euler::{JoinMap, KernelError};
pub use ids::{Domain, EdgeId, FaceId, LoopId, VertId};
pub use measure::MeshReport;
pub use mesh::{MemoryPart, Mesh};
pub use validate::ValidationError;

#[cfg(test)]
mod euler_tests;
