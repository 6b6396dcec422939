//! Parametric surfaces (seed 002, Mlinarić 2019, "Problem teselacije NURBS ploha"): Bézier,
//! B-spline and NURBS curves and surfaces, their tessellation into conforming triangle meshes,
//! and PN (Bézier) triangles as a mesh smoother.
//!
//! - [`knots`]: knot validation with located errors, clamped/periodic shorthands, spans and
//!   basis functions (thesis eqs. 1.8–1.9 with their errata fixed), basis tables for grids.
//! - [`bezier`]: de Casteljau for (rational) Bézier curves and patches (eqs. 1.1–1.7).
//! - [`curve`]: [`curve::NurbsCurve`] (eqs. 1.10, 1.12–1.14), derivatives, knot insertion,
//!   Bézier segments.
//! - [`surface`]: [`surface::NurbsSurface`] (eqs. 1.11, 1.15), derivatives to order 2, unit
//!   normals with the degenerate-normal fallback (eq. 1.18, spec §2.2.5), factorised grid
//!   evaluation (D9), knot insertion, Bézier decomposition, closed directions and poles.
//! - [`sweep`]: surfaces of revolution and sweeps of a profile curve along a path.
//! - [`tess`]: uniform, inter-patch adaptive and fully adaptive tessellation (thesis ch. 2,
//!   decisions D7–D8), with a triangle cap checked before allocating.
//! - [`patchset`]: [`patchset::PatchSet`], surfaces sharing borders (found exactly or
//!   declared), meshed as one conforming mesh by [`tess::tessellate_set`].
//! - [`pn`]: PN triangles with the uniform or OpenGL ring pattern (thesis ch. 3–4, D10).
//! - [`mesh`]: the neutral [`mesh::TriMesh`] output and its edge census.
//! - [`error`]: [`error::NurbsError`] and the rule-file [`error::Field`] names.
//!
//! Determinism: every transcendental goes through `libm`; hash maps are only looked up, never
//! iterated into outputs; parallel work (rayon) computes independent items that are stored at
//! precomputed positions, so the output is byte-identical at any thread count.
//!
//! Example (compiled and run as the unit test `tests::docs_example` below; shown as `ignore`
//! so that this file names no crate and can move into graftal unchanged):
//!
//! ```ignore
//! use crate::nurbs::surface::NurbsSurface;
//! use crate::nurbs::tess::{tessellate, AdaptiveOptions, Mode};
//!
//! // A 4 × 4 bicubic B-spline patch with a bump.
//! let mut points = Vec::new();
//! for i in 0..4 {
//!     for j in 0..4 {
//!         let z = if (1..3).contains(&i) && (1..3).contains(&j) { 1.0 } else { 0.0 };
//!         points.push([i as f64, j as f64, z]);
//!     }
//! }
//! let surface = NurbsSurface::clamped([3, 3], [4, 4], &points, None).unwrap();
//! let t = tessellate(&surface, &Mode::Adaptive(AdaptiveOptions::sagitta(1e-3)), 1_000_000).unwrap();
//! assert!(t.stats.max_deviation <= 1e-3);
//! let census = t.mesh.edge_census();
//! assert_eq!(census.non_manifold, 0);
//! // Boundary edges only on the four borders of the domain.
//! assert!(census.boundary.iter().all(|e| {
//!     let (a, b) = (t.mesh.uvs[e[0] as usize], t.mesh.uvs[e[1] as usize]);
//!     (0..2).any(|k| (a[k] == 0.0 && b[k] == 0.0) || (a[k] == 1.0 && b[k] == 1.0))
//! }));
//! ```

pub mod bezier;
pub mod curve;
pub mod error;
pub mod hash;
pub mod knots;
pub mod mesh;
pub mod patchset;
pub mod pn;
pub mod surface;
pub mod sweep;
pub mod tess;

#[cfg(test)]
mod tests;
