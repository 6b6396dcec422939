//! Whole-mesh measurements: counts, bounds, area, volume, manifoldness,
//! components and Euler characteristic. Linear in the mesh size.

use glam::DVec3;

use crate::geom::UnionFind;

use super::ids::{FaceId, VertId};
use super::mesh::Mesh;

/// What `graftal info` and the stats report about a mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshReport {
    pub verts: usize,
    pub edges: usize,
    pub faces: usize,
    /// Triangles a triangulating writer emits (Σ corners − 2).
    pub triangles: usize,
    pub wire_edges: usize,
    /// Edges with exactly one face.
    pub boundary_edges: usize,
    /// Edges with three or more faces.
    pub non_manifold_edges: usize,
    /// Vertices whose faces do not form a single fan.
    pub non_manifold_verts: usize,
    pub isolated_verts: usize,
    /// `None` for an empty mesh.
    pub bounds: Option<(DVec3, DVec3)>,
    pub area: f64,
    /// Enclosed volume, when the surface is closed and consistently oriented.
    pub volume: Option<f64>,
    /// Every edge has one or two faces and every vertex a single fan.
    pub manifold: bool,
    /// Manifold, no boundary, no wire edges, consistently oriented.
    pub watertight: bool,
    /// Faces on every two-face edge run it in opposite directions.
    pub consistently_oriented: bool,
    /// Connected components (isolated vertices count as components).
    pub components: usize,
    /// V − E + F.
    pub euler_characteristic: i64,
}

impl Mesh {
    /// Measures the whole mesh.
    pub fn report(&self) -> MeshReport {
        let mut wire_edges = 0;
        let mut boundary_edges = 0;
        let mut non_manifold_edges = 0;
        let mut consistently_oriented = true;
        let mut components = UnionFind::new(self.vert_capacity());
        for e in self.edge_ids() {
            let [a, b] = self.edge_verts(e);
            components.union(a.0, b.0);
            let loops: Vec<_> = self.edge_loops(e).collect();
            match loops.len() {
                0 => wire_edges += 1,
                1 => boundary_edges += 1,
                2 => {
                    if self.lp(loops[0]).vert == self.lp(loops[1]).vert {
                        consistently_oriented = false;
                    }
                }
                _ => non_manifold_edges += 1,
            }
        }
        let mut isolated_verts = 0;
        let mut non_manifold_verts = 0;
        let mut bounds: Option<(DVec3, DVec3)> = None;
        let mut fan_faces: Vec<FaceId> = Vec::new();
        for v in self.vert_ids() {
            let p = self.position(v);
            bounds = Some(match bounds {
                None => (p, p),
                Some((lo, hi)) => (lo.min(p), hi.max(p)),
            });
            if self.vert(v).edge.is_none() {
                isolated_verts += 1;
                continue;
            }
            fan_faces.clear();
            fan_faces.extend(self.vert_faces(v));
            if fan_faces.len() > 1 && self.fan_count(v, &fan_faces) > 1 {
                non_manifold_verts += 1;
            }
        }
        let mut area = 0.0;
        let mut signed_volume = 0.0;
        let mut triangles = 0;
        for f in self.face_ids() {
            let points = self.face_positions(f);
            area += crate::geom::polygon::area(&points);
            triangles += points.len() - 2;
            // Divergence theorem over a fan: exact for planar faces.
            for i in 1..points.len() - 1 {
                signed_volume += points[0].dot(points[i].cross(points[i + 1])) / 6.0;
            }
        }
        let root_count = self
            .vert_ids()
            .filter(|&v| components.find(v.0) == v.0)
            .count();
        let manifold = non_manifold_edges == 0 && non_manifold_verts == 0;
        let watertight = manifold
            && boundary_edges == 0
            && wire_edges == 0
            && consistently_oriented
            && self.face_count() > 0;
        MeshReport {
            verts: self.vert_count(),
            edges: self.edge_count(),
            faces: self.face_count(),
            triangles,
            wire_edges,
            boundary_edges,
            non_manifold_edges,
            non_manifold_verts,
            isolated_verts,
            bounds,
            area,
            volume: watertight.then_some(signed_volume),
            manifold,
            watertight,
            consistently_oriented,
            components: root_count,
            euler_characteristic: self.vert_count() as i64 - self.edge_count() as i64
                + self.face_count() as i64,
        }
    }

    /// Number of edge-connected fans the faces around `v` form, joining
    /// faces across edges at `v` that have exactly two faces.
    fn fan_count(&self, v: VertId, faces: &[FaceId]) -> usize {
        let mut sorted = faces.to_vec();
        sorted.sort_unstable();
        let index = |f: FaceId| sorted.binary_search(&f).expect("face around v");
        let mut groups = UnionFind::new(faces.len());
        for e in self.vert_edges(v) {
            let around: Vec<FaceId> = self.edge_faces(e).collect();
            if around.len() == 2 {
                groups.union(index(around[0]) as u32, index(around[1]) as u32);
            }
        }
        (0..faces.len() as u32)
            .filter(|&i| groups.find(i) == i)
            .count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit cube centred on the origin.
    fn cube() -> Mesh {
        let mut m = Mesh::new();
        crate::kernel::ops::create::create_cube(&mut m, 1.0).unwrap();
        m
    }

    #[test]
    fn unit_cube_is_watertight_with_volume_one() {
        let r = cube().report();
        assert_eq!((r.verts, r.edges, r.faces, r.triangles), (8, 12, 6, 12));
        assert!(r.manifold && r.watertight && r.consistently_oriented);
        assert!((r.volume.unwrap() - 1.0).abs() < 1e-12, "{:?}", r.volume);
        assert_eq!(r.area, 6.0);
        assert_eq!(r.euler_characteristic, 2);
        assert_eq!(r.components, 1);
        assert_eq!(r.bounds, Some((DVec3::splat(-0.5), DVec3::splat(0.5))));
    }

    #[test]
    fn open_and_non_manifold_shapes_are_reported() {
        let mut m = cube();
        let f = m.face_ids().next().unwrap();
        m.kill_face(f).unwrap();
        let r = m.report();
        assert_eq!(r.boundary_edges, 4);
        assert!(!r.watertight);
        assert_eq!(r.volume, None);
        // Two cubes touching at one vertex: a non-manifold vertex.
        let mut a = cube();
        let b = cube();
        let map = a.join_mesh(&b);
        let ids: Vec<VertId> = map.verts.iter().flatten().copied().collect();
        let corner_b = *ids
            .iter()
            .find(|&&v| a.position(v) == DVec3::splat(-0.5))
            .unwrap();
        for &v in &ids {
            let p = a.position(v);
            a.set_position(v, p + DVec3::ONE);
        }
        let corner_a = a
            .vert_ids()
            .find(|&v| a.position(v) == DVec3::splat(0.5) && !ids.contains(&v))
            .unwrap();
        a.glue_verts(corner_a, corner_b).unwrap();
        a.validate().unwrap();
        let r = a.report();
        assert_eq!(r.non_manifold_verts, 1);
        assert!(!r.manifold);
        assert_eq!(r.components, 1);
        let mut w = Mesh::new();
        let p = w.make_vert(DVec3::ZERO);
        w.make_edge_vert(p, DVec3::X).unwrap();
        w.make_vert(DVec3::Y);
        let r = w.report();
        assert_eq!((r.wire_edges, r.isolated_verts, r.components), (1, 1, 2));
    }
}
