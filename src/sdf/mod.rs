//! The implicit-surface (signed distance field) pillar of graftal
//! (issue 14; thesis seed 004, spec `implicit-and-parametric.md` §1).
//!
//! Data flow:
//!
//! ```text
//! Tree (nodes, resolved f64 parameters) ──Tape::compile──▶ Tape
//! Tape / SkinField (any `grid::Field`) ──mesher::mesh(options)──▶ MeshOutput
//! positions + triangles ──MeshField::new──▶ Arc<MeshField> ──▶ Node::Mesh
//! ```
//!
//! Modules:
//! - [`tree`]: node kinds, validation with located errors; [`contract`]:
//!   contracts (exact / bound / Lipschitz, decision D1) and sublevel-set
//!   bounds.
//! - [`primitives`]: the distance functions (local frame, axis +Z, D2).
//! - [`tape`]: compilation to a register tape; [`eval`]: its batched
//!   evaluation without allocation, the order-independent smooth
//!   operations (D6).
//! - [`mesh_field`]: imported meshes as distance fields (BVH, exact
//!   point–triangle distance, pseudonormal or winding-number sign).
//! - [`table`]: the face-consistent marching-cubes table (D4).
//! - [`grid`]: options and grid conventions; [`sample`]: sparse block
//!   sampling.
//! - [`mesher`]: the driver (limits, parallel blocks, deterministic
//!   assembly); [`mc`] marching cubes; [`dc`] manifold dual contouring.
//! - [`skin`]: the skeleton skin field (spec §4.4).
//! - [`topology`]: mesh checks (closed, manifold, orientation, genus).
//!
//! Sign convention: negative inside, positive outside, zero on the surface.
//!
//! The pillar knows only the geometry floor ([`crate::geom`]): its meshes
//! leave through a [`MeshSink`](crate::geom::MeshSink)
//! ([`MeshOutput::emit`]); the rule compiler and the engine build its trees.
//!
//! ```
//! use graftal::sdf::{Tree, Node, Tape, TreeLimits, MeshOptions, Resolution, mesh};
//! use glam::DVec3;
//! let mut t = Tree::new();
//! let ball = t.push(Node::Sphere { radius: 1.0 });
//! let cube = t.push(Node::Box { size: DVec3::ONE });
//! let cube = t.push(Node::Translate { child: cube, offset: DVec3::splat(0.5) });
//! let root = t.push(Node::Difference { base: ball, subtract: vec![cube] });
//! let tape = Tape::compile(&t, root, &TreeLimits::default()).unwrap();
//! let opts = MeshOptions { resolution: Resolution::CellsPerAxis(32), ..Default::default() };
//! let m = mesh(&tape, &opts).unwrap();
//! assert!(m.triangles.len() > 1000);
//! ```

// Geometry code indexes parallel fixed-size arrays (corners, axes, cube
// edges); index loops read better there than zipped iterators.
#![allow(clippy::needless_range_loop)]

pub mod aabb;
pub mod contract;
pub mod dc;
pub mod error;
pub mod eval;
pub mod grid;
pub mod mc;
pub mod mesh_field;
pub mod mesher;
pub mod primitives;
pub mod sample;
pub mod skin;
pub mod table;
pub mod tape;
pub mod topology;
pub mod tree;

#[cfg(test)]
mod tests;

pub use aabb::Aabb;
pub use error::{Result, SdfError};
pub use grid::{
    sample_grid, Field, FieldEval, GridKind, MeshLimits, MeshOptions, MeshProgress, Mesher,
    Progress, Resolution, VertexPlacement,
};
pub use mesh_field::{MeshField, MeshFieldReport, SignMethod, SignMode};
pub use mesher::{mesh, MeshOutput, MeshStats, Timings};
pub use skin::{skin, Skeleton, SkinField, SkinNode, SkinOptions, SkinOutput};
pub use tape::{Evaluator, Tape};
pub use topology::{check, MeshCheck};
pub use tree::{Bounds, Contract, Exactness, Node, NodeId, NodeInfo, Rotation, Tree, TreeLimits};
