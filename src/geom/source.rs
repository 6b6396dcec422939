//! [`PolygonSource`]: read-only access to a polygon mesh in its canonical
//! order, for writers that stream from the mesh that holds the geometry
//! (the kernel's) instead of from an [`IndexedMesh`] copy of it.
//!
//! The copy costs a pass and, for a million triangles, about 50 MB of
//! fresh memory (positions, the flat corner lists and an `f64` normal per
//! polygon) that a writer reads once (issue 38, deliverable 2).

use glam::DVec3;

use super::indexed::MeshError;
use super::IndexedMesh;

/// A polygon mesh as a writer reads it: vertices numbered `0..vertex_count`
/// and polygons visited in order, each with its corners and, where the
/// producer stores one, its unit normal.
pub trait PolygonSource {
    /// Number of vertices; vertex indices run below it.
    fn vertex_count(&self) -> usize;
    /// Number of polygons [`Self::for_each_polygon`] visits.
    fn polygon_count(&self) -> usize;
    /// Total corners of all polygons.
    fn corner_count(&self) -> usize;
    /// Position of vertex `v`.
    fn position(&self, v: u32) -> DVec3;
    /// Corners of the largest polygon (0 without polygons).
    fn max_polygon_len(&self) -> usize;
    /// Whether [`Self::for_each_polygon`] gives each polygon's stored normal
    /// (the same bits as `polygon::unit_normal` of its corners).
    fn stores_normals(&self) -> bool;
    /// Calls `visit(corners, stored)` for every polygon in order: its vertex
    /// indices and, when [`Self::stores_normals`], `Some(unit normal)`, or
    /// `Some(None)` for a degenerate polygon; `None` otherwise.
    fn for_each_polygon(&self, visit: impl FnMut(&[u32], Option<Option<DVec3>>));

    /// Triangles of a triangulation of every polygon (each polygon of `n`
    /// corners gives `n - 2`).
    fn triangle_count(&self) -> u64 {
        self.corner_count() as u64 - 2 * self.polygon_count() as u64
    }

    /// What [`IndexedMesh::validate`] checks of the vertices, in its order
    /// and with its messages: their count fits a `u32` index, and every
    /// position is finite. (The polygons of a source index its vertices
    /// by construction.)
    fn check_vertices(&self) -> Result<(), MeshError> {
        let count = self.vertex_count();
        if u32::try_from(count).is_err() {
            return Err(MeshError::Invalid {
                message: format!("{count} vertices exceed the u32 index range"),
            });
        }
        match (0..count).find(|&v| !self.position(v as u32).is_finite()) {
            Some(vertex) => Err(MeshError::NonFinite { vertex }),
            None => Ok(()),
        }
    }

    /// [`IndexedMesh::check_f32_range`] of the source's vertices.
    fn check_f32_range(&self, format: &'static str) -> Result<(), MeshError> {
        for vertex in 0..self.vertex_count() {
            let p = self.position(vertex as u32).to_array();
            if let Some(&value) = p.iter().find(|c| c.abs() > f32::MAX as f64) {
                return Err(MeshError::OutOfRange {
                    vertex,
                    value,
                    format,
                });
            }
        }
        Ok(())
    }
}

impl PolygonSource for IndexedMesh {
    fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    fn polygon_count(&self) -> usize {
        IndexedMesh::polygon_count(self)
    }

    fn corner_count(&self) -> usize {
        self.face_indices.len()
    }

    fn position(&self, v: u32) -> DVec3 {
        IndexedMesh::position(self, v)
    }

    fn max_polygon_len(&self) -> usize {
        self.polygons().map(<[u32]>::len).max().unwrap_or(0)
    }

    fn stores_normals(&self) -> bool {
        self.polygon_normals.len() == IndexedMesh::polygon_count(self)
    }

    fn for_each_polygon(&self, mut visit: impl FnMut(&[u32], Option<Option<DVec3>>)) {
        for (k, poly) in self.polygons().enumerate() {
            visit(poly, self.stored_normal(k));
        }
    }
}
