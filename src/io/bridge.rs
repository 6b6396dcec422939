//! Conversion between the kernel mesh and the neutral [`IndexedMesh`] that
//! readers produce and writers consume.
//!
//! Kernel → indexed is canonical: vertices in id order (compacted), faces in
//! id order starting at each face's first loop, wire edges in id order,
//! scalar vertex layers in name order. Equal meshes give equal buffers, so
//! writers give equal bytes.

use glam::DVec3;
use thiserror::Error;

use super::indexed::IndexedMesh;
use crate::kernel::attrs::LayerData;
use crate::kernel::{AttrValue, Domain, Mesh, VertId};

#[derive(Debug, Error, PartialEq)]
pub enum BridgeError {
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
    #[error("attribute `{name}` has {found} values for {count} vertices")]
    AttributeLength {
        name: String,
        found: usize,
        count: usize,
    },
}

/// What was dropped while building a kernel mesh from an indexed one.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ImportReport {
    /// Polygons with fewer than 3 distinct corners (degenerate input).
    pub degenerate_faces: usize,
}

/// Builds a kernel mesh (through Euler operators). Polygons are cleaned of
/// consecutive repeated corners; a polygon that still repeats a corner is
/// split into its simple loops; loops under 3 corners are dropped and counted.
pub fn mesh_from_indexed(indexed: &IndexedMesh) -> Result<Mesh, BridgeError> {
    mesh_from_indexed_report(indexed).map(|(mesh, _)| mesh)
}

pub fn mesh_from_indexed_report(
    indexed: &IndexedMesh,
) -> Result<(Mesh, ImportReport), BridgeError> {
    let count = indexed.positions.len();
    let mut mesh = Mesh::new();
    let mut report = ImportReport::default();
    for (name, values) in &indexed.vertex_scalars {
        if values.len() != count {
            return Err(BridgeError::AttributeLength {
                name: name.clone(),
                found: values.len(),
                count,
            });
        }
        mesh.add_layer(name, Domain::Vert, AttrValue::Scalar(0.0))
            .expect("a fresh mesh has no conflicting layer");
    }
    let mut verts = Vec::with_capacity(count);
    for (index, p) in indexed.positions.iter().enumerate() {
        let p = DVec3::from_array(*p);
        if !p.is_finite() {
            return Err(BridgeError::NonFinite { index });
        }
        let v = mesh.make_vert(p);
        for (name, values) in &indexed.vertex_scalars {
            mesh.set_attr(
                name,
                Domain::Vert,
                v.index(),
                AttrValue::Scalar(values[index]),
            );
        }
        verts.push(v);
    }
    let mut ring: Vec<VertId> = Vec::new();
    for face in 0..indexed.polygon_count() {
        ring.clear();
        for &i in indexed.polygon(face) {
            let v = *verts.get(i as usize).ok_or(BridgeError::BadIndex {
                face,
                vertex: i,
                count,
            })?;
            if ring.last() != Some(&v) {
                ring.push(v);
            }
        }
        while ring.len() > 1 && ring.first() == ring.last() {
            ring.pop();
        }
        for piece in simple_loops(&ring) {
            if piece.len() < 3 || mesh.make_face(&piece).is_err() {
                report.degenerate_faces += 1;
            }
        }
    }
    for (line, &[a, b]) in indexed.lines.iter().enumerate() {
        let get = |i: u32| {
            verts
                .get(i as usize)
                .copied()
                .ok_or(BridgeError::BadLineIndex {
                    line,
                    vertex: i,
                    count,
                })
        };
        let (a, b) = (get(a)?, get(b)?);
        if a != b && mesh.find_edge(a, b).is_none() {
            mesh.make_edge(a, b)
                .expect("distinct live vertices without an edge");
        }
    }
    Ok((mesh, report))
}

/// Splits a ring that visits a vertex more than once into simple loops.
fn simple_loops(ring: &[VertId]) -> Vec<Vec<VertId>> {
    let mut out = Vec::new();
    let mut stack: Vec<VertId> = Vec::with_capacity(ring.len());
    for &v in ring {
        if let Some(at) = stack.iter().position(|&w| w == v) {
            out.push(stack.split_off(at));
        }
        stack.push(v);
    }
    out.push(stack);
    out.retain(|l| !l.is_empty());
    out
}

/// The canonical indexed view of a kernel mesh.
pub fn mesh_to_indexed(mesh: &Mesh) -> IndexedMesh {
    let mut out = IndexedMesh::new();
    let mut index_of = vec![u32::MAX; mesh.vert_capacity()];
    out.positions.reserve(mesh.vert_count());
    for (i, v) in mesh.vert_ids().enumerate() {
        index_of[v.index()] = i as u32;
        out.positions.push(mesh.position(v).to_array());
    }
    out.face_indices.reserve(mesh.loop_count());
    out.face_starts.reserve(mesh.face_count());
    for f in mesh.face_ids() {
        for v in mesh.face_verts(f) {
            out.face_indices.push(index_of[v.index()]);
        }
        out.face_starts.push(out.face_indices.len() as u32);
    }
    for e in mesh.edge_ids() {
        if mesh.is_wire_edge(e) {
            let [a, b] = mesh.edge_verts(e);
            out.lines.push([index_of[a.index()], index_of[b.index()]]);
        }
    }
    for layer in mesh.attributes().layers() {
        if layer.domain != Domain::Vert {
            continue;
        }
        if let LayerData::Scalar(values) = &layer.data {
            let column: Vec<f64> = mesh.vert_ids().map(|v| values[v.index()]).collect();
            out.vertex_scalars.push((layer.name.clone(), column));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_keeps_topology_lines_and_attributes() {
        let mut m = IndexedMesh::new();
        m.positions = vec![
            [0., 0., 0.],
            [1., 0., 0.],
            [1., 1., 0.],
            [0., 1., 0.],
            [2., 2., 2.],
        ];
        m.push_polygon(&[0, 1, 2, 3]);
        m.lines.push([2, 4]);
        m.vertex_scalars
            .push(("radius".into(), vec![0.1, 0.2, 0.3, 0.4, 0.5]));
        let mesh = mesh_from_indexed(&m).unwrap();
        mesh.validate().unwrap();
        assert_eq!(
            (mesh.vert_count(), mesh.edge_count(), mesh.face_count()),
            (5, 5, 1)
        );
        assert_eq!(mesh_to_indexed(&mesh), m);
    }

    #[test]
    fn degenerate_polygons_are_cleaned_or_counted() {
        let mut m = IndexedMesh::new();
        m.positions = vec![
            [0., 0., 0.],
            [1., 0., 0.],
            [1., 1., 0.],
            [0., 1., 0.],
            [2., 0., 0.],
            [2., 1., 0.],
        ];
        m.push_polygon(&[0, 1, 1, 2]); // consecutive repeat: a triangle
        m.push_polygon(&[0, 0, 3]); // two distinct corners: dropped
        m.push_polygon(&[1, 4, 5, 1, 2, 3]); // bow-tie through 1: two loops
        let (mesh, report) = mesh_from_indexed_report(&m).unwrap();
        mesh.validate().unwrap();
        assert_eq!(mesh.face_count(), 3);
        assert_eq!(report.degenerate_faces, 1);
    }

    #[test]
    fn bad_indices_are_reported_not_panicked() {
        let mut m = IndexedMesh::new();
        m.positions = vec![[0., 0., 0.]];
        m.push_polygon(&[0, 1, 2]);
        assert_eq!(
            mesh_from_indexed(&m).unwrap_err(),
            BridgeError::BadIndex {
                face: 0,
                vertex: 1,
                count: 1
            }
        );
    }
}
