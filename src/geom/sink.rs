//! One way to emit geometry, in the spirit of lyon's `GeometryBuilder`: a
//! producer (a file reader, the SDF mesher, the NURBS tessellator, PN
//! smoothing, a kernel mesh being exported) calls [`MeshSink::begin`], then
//! [`MeshSink::vertex`] for each vertex and [`MeshSink::polygon`] /
//! [`MeshSink::line`] over their indices, then [`MeshSink::end`] (or
//! [`MeshSink::abort`] when it gives up). The sink decides what the
//! geometry becomes: [`IndexedMesh`] collects it for the writers, the
//! kernel's builder turns it into kernel elements through Euler operators
//! and names what it made. Producers never see either.
//!
//! ```
//! use glam::DVec3;
//! use graftal::geom::sink::{emit_polygons, Begin, MeshSink};
//! use graftal::geom::IndexedMesh;
//!
//! let mut mesh = IndexedMesh::new();
//! let square = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
//! emit_polygons(&mut mesh, &square, &[&[0, 1, 2, 3]]).unwrap();
//! assert_eq!((mesh.positions.len(), mesh.polygon_count()), (4, 1));
//! ```

use glam::DVec3;
use thiserror::Error;

use super::indexed::IndexedMesh;

/// What a producer announces before emitting (sizes are hints for
/// reserving memory; a sink may refuse sizes over its limits here, before
/// anything is allocated).
#[derive(Debug, Clone, Copy, Default)]
pub struct Begin<'a> {
    pub vertices: usize,
    pub polygons: usize,
    /// Polygon corners in all (0: not known; three per polygon assumed).
    pub corners: usize,
    pub lines: usize,
    /// Names of the per-vertex scalars each [`MeshSink::vertex`] call
    /// carries, in order.
    pub scalars: &'a [&'a str],
}

/// Why a sink refused what it was given.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SinkError {
    #[error("vertex {index} has a non-finite coordinate")]
    NonFinite { index: usize },
    #[error("face {face} refers to vertex {vertex}, but only {count} vertices exist")]
    BadIndex {
        face: usize,
        vertex: u32,
        count: usize,
    },
    #[error("line {line} refers to vertex {vertex}, but only {count} vertices exist")]
    BadLineIndex {
        line: usize,
        vertex: u32,
        count: usize,
    },
    #[error("vertex {vertex} carries {found} scalars, but {expected} were announced")]
    ScalarCount {
        vertex: usize,
        found: usize,
        expected: usize,
    },
    /// A size the sink cannot hold (the producer should have asked less).
    #[error("{0}")]
    Limit(String),
}

/// The receiving end of emitted geometry.
pub trait MeshSink {
    /// Starts an emission; `begin.scalars` names the per-vertex values.
    fn begin(&mut self, begin: &Begin) -> Result<(), SinkError>;
    /// Adds a vertex; its index is the number of vertices emitted before it.
    fn vertex(&mut self, position: DVec3, scalars: &[f64]) -> Result<(), SinkError>;
    /// Adds a polygon over earlier vertices (in winding order).
    fn polygon(&mut self, corners: &[u32]) -> Result<(), SinkError>;
    /// Adds a wire edge between two earlier vertices.
    fn line(&mut self, a: u32, b: u32) -> Result<(), SinkError>;
    /// Ends the emission.
    fn end(&mut self) -> Result<(), SinkError>;
    /// Gives up: the sink drops what this emission gave it, where it can.
    fn abort(&mut self);
}

/// Emits `points` as vertices and `polygons` over them into `sink`, then
/// ends it (aborts it on an error).
pub fn emit_polygons(
    sink: &mut impl MeshSink,
    points: &[DVec3],
    polygons: &[&[u32]],
) -> Result<(), SinkError> {
    let run = |sink: &mut dyn MeshSink| -> Result<(), SinkError> {
        sink.begin(&Begin {
            vertices: points.len(),
            polygons: polygons.len(),
            ..Begin::default()
        })?;
        for &p in points {
            sink.vertex(p, &[])?;
        }
        for polygon in polygons {
            sink.polygon(polygon)?;
        }
        sink.end()
    };
    run(sink).inspect_err(|_| sink.abort())
}

impl IndexedMesh {
    /// Emits this mesh into `sink` in its own order (vertices, polygons,
    /// lines, the vertex scalars with each vertex), ending it; an error
    /// aborts it.
    pub fn emit(&self, sink: &mut dyn MeshSink) -> Result<(), SinkError> {
        let names: Vec<&str> = self
            .vertex_scalars
            .iter()
            .map(|(n, _)| n.as_str())
            .collect();
        let run = |sink: &mut dyn MeshSink| -> Result<(), SinkError> {
            sink.begin(&Begin {
                vertices: self.positions.len(),
                polygons: self.polygon_count(),
                corners: self.face_indices.len(),
                lines: self.lines.len(),
                scalars: &names,
            })?;
            let mut scalars = vec![0.0; names.len()];
            for (i, p) in self.positions.iter().enumerate() {
                for (slot, (_, values)) in scalars.iter_mut().zip(&self.vertex_scalars) {
                    *slot = values.get(i).copied().ok_or(SinkError::ScalarCount {
                        vertex: i,
                        found: values.len(),
                        expected: self.positions.len(),
                    })?;
                }
                sink.vertex(DVec3::from_array(*p), &scalars)?;
            }
            for polygon in self.polygons() {
                sink.polygon(polygon)?;
            }
            for &[a, b] in &self.lines {
                sink.line(a, b)?;
            }
            sink.end()
        };
        run(sink).inspect_err(|_| sink.abort())
    }
}

/// Collecting into an [`IndexedMesh`]: what the writers read. Indices are
/// taken as given (the writers validate).
impl MeshSink for IndexedMesh {
    fn begin(&mut self, begin: &Begin) -> Result<(), SinkError> {
        *self = IndexedMesh::new();
        self.positions.reserve(begin.vertices);
        self.face_starts.reserve(begin.polygons);
        self.face_indices.reserve(begin.corners);
        self.lines.reserve(begin.lines);
        self.vertex_scalars = begin
            .scalars
            .iter()
            .map(|n| (n.to_string(), Vec::with_capacity(begin.vertices)))
            .collect();
        Ok(())
    }

    fn vertex(&mut self, position: DVec3, scalars: &[f64]) -> Result<(), SinkError> {
        if scalars.len() != self.vertex_scalars.len() {
            return Err(SinkError::ScalarCount {
                vertex: self.positions.len(),
                found: scalars.len(),
                expected: self.vertex_scalars.len(),
            });
        }
        self.positions.push(position.to_array());
        for ((_, column), &x) in self.vertex_scalars.iter_mut().zip(scalars) {
            column.push(x);
        }
        Ok(())
    }

    fn polygon(&mut self, corners: &[u32]) -> Result<(), SinkError> {
        if u32::try_from(self.face_indices.len() + corners.len()).is_err() {
            return Err(SinkError::Limit("more than 2^32 polygon corners".into()));
        }
        self.push_polygon(corners);
        Ok(())
    }

    fn line(&mut self, a: u32, b: u32) -> Result<(), SinkError> {
        self.lines.push([a, b]);
        Ok(())
    }

    fn end(&mut self) -> Result<(), SinkError> {
        Ok(())
    }

    fn abort(&mut self) {
        *self = IndexedMesh::new();
    }
}

/// A sink that passes everything on to `inner` with vertex positions
/// mapped by `p ↦ origin + linear·p` (a placed copy). A map that mirrors
/// (negative determinant) reverses polygon winding, so outward faces stay
/// outward.
pub struct Placed<'s> {
    pub inner: &'s mut dyn MeshSink,
    pub linear: glam::DMat3,
    pub origin: DVec3,
    reversed: Vec<u32>,
}

impl<'s> Placed<'s> {
    pub fn new(inner: &'s mut dyn MeshSink, linear: glam::DMat3, origin: DVec3) -> Self {
        Placed {
            inner,
            linear,
            origin,
            reversed: Vec::new(),
        }
    }
}

impl MeshSink for Placed<'_> {
    fn begin(&mut self, begin: &Begin) -> Result<(), SinkError> {
        self.inner.begin(begin)
    }

    fn vertex(&mut self, position: DVec3, scalars: &[f64]) -> Result<(), SinkError> {
        self.inner
            .vertex(self.origin + self.linear * position, scalars)
    }

    fn polygon(&mut self, corners: &[u32]) -> Result<(), SinkError> {
        if self.linear.determinant() < 0.0 {
            self.reversed.clear();
            self.reversed.extend(corners.iter().rev());
            self.inner.polygon(&self.reversed)
        } else {
            self.inner.polygon(corners)
        }
    }

    fn line(&mut self, a: u32, b: u32) -> Result<(), SinkError> {
        self.inner.line(a, b)
    }

    fn end(&mut self) -> Result<(), SinkError> {
        self.inner.end()
    }

    fn abort(&mut self) {
        self.inner.abort()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_indexed_mesh_emits_itself_unchanged() {
        let mut m = IndexedMesh::new();
        m.positions = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [5.0; 3]];
        m.push_polygon(&[0, 1, 2]);
        m.lines.push([2, 3]);
        m.vertex_scalars
            .push(("radius".into(), vec![1.0, 2.0, 3.0, 4.0]));
        let mut copy = IndexedMesh::new();
        m.emit(&mut copy).unwrap();
        assert_eq!(copy, m);
    }

    #[test]
    fn abort_drops_the_emission() {
        let mut m = IndexedMesh::new();
        m.positions = vec![[0.0; 3]];
        m.vertex_scalars.push(("radius".into(), vec![]));
        let mut copy = IndexedMesh::new();
        assert!(matches!(
            m.emit(&mut copy),
            Err(SinkError::ScalarCount { .. })
        ));
        assert_eq!(copy, IndexedMesh::new());
    }
}
