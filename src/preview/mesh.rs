//! From the writers' [`IndexedMesh`] to a [`Scene`]: polygons
//! triangulated, each triangle coloured by its corner colours (their mean)
//! or its material's base colour, shaded with the mesh's normals where it
//! has them, wire edges kept.

use super::Scene;
use crate::geom::indexed::PolygonTriangulator;
use crate::geom::IndexedMesh;

/// The arrays a [`Scene`] borrows, owned.
pub struct SceneData<'m> {
    mesh: &'m IndexedMesh,
    triangles: Vec<[u32; 3]>,
    colors: Vec<[f32; 3]>,
    normals: Vec<[[f64; 3]; 3]>,
}

impl<'m> SceneData<'m> {
    /// Triangulates `mesh` for drawing.
    pub fn new(mesh: &'m IndexedMesh) -> Self {
        let mut triangles = Vec::with_capacity(mesh.face_indices.len());
        let mut colors = Vec::with_capacity(mesh.face_indices.len());
        let mut normals = Vec::new();
        let mut tri = PolygonTriangulator::default();
        for (k, poly) in mesh.polygons().enumerate() {
            if tri.run(mesh, poly).is_none() {
                continue;
            }
            let first = mesh.face_starts[k] as usize;
            let material = mesh
                .polygon_material(k)
                .and_then(|m| mesh.materials.get(m as usize))
                .map(|m| [m.base_color[0], m.base_color[1], m.base_color[2]]);
            for t in &tri.triangles {
                triangles.push(t.map(|i| poly[i as usize]));
                let corner = |i: u32| first + i as usize;
                let color = if mesh.corner_colors.is_empty() {
                    material.unwrap_or([0.8; 3])
                } else {
                    let sum = t.iter().fold([0.0; 3], |acc, &i| {
                        let c = mesh.corner_colors[corner(i)];
                        [acc[0] + c[0], acc[1] + c[1], acc[2] + c[2]]
                    });
                    sum.map(|x| x / 3.0)
                };
                colors.push(color.map(|c| c as f32));
                if !mesh.corner_normals.is_empty() {
                    normals.push(t.map(|i| mesh.corner_normals[corner(i)]));
                }
            }
        }
        SceneData {
            mesh,
            triangles,
            colors,
            normals,
        }
    }

    /// The scene to render.
    pub fn scene(&self) -> Scene<'_> {
        Scene {
            positions: &self.mesh.positions,
            triangles: &self.triangles,
            triangle_colors: &self.colors,
            corner_normals: &self.normals,
            lines: &self.mesh.lines,
        }
    }
}
