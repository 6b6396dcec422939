//! Whole-mesh measurements: counts, bounds, area, volume, manifoldness,
//! components and Euler characteristic. Linear in the mesh size.

use glam::DVec3;

use crate::geom::UnionFind;

use super::ids::LoopId;
#[cfg(test)]
use super::ids::VertId;
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
            let mut loops = self.edge_loops(e);
            match (loops.next(), loops.next(), loops.next()) {
                (None, _, _) => wire_edges += 1,
                (Some(_), None, _) => boundary_edges += 1,
                (Some(l), Some(m), None) => {
                    if self.lp(l).vert == self.lp(m).vert {
                        consistently_oriented = false;
                    }
                }
                _ => non_manifold_edges += 1,
            }
        }
        // Faces at each vertex (faces repeat no vertex: one loop each) and
        // one loop there to start the fan walk from, in one pass.
        let mut faces_at = vec![0u32; self.vert_capacity()];
        let mut loop_at: Vec<Option<LoopId>> = vec![None; self.vert_capacity()];
        for (index, l) in self.loops.iter() {
            let v = l.vert.0 as usize;
            faces_at[v] += 1;
            loop_at[v].get_or_insert(LoopId(index));
        }
        let mut isolated_verts = 0;
        let mut non_manifold_verts = 0;
        let mut bounds: Option<(DVec3, DVec3)> = None;
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
            let faces = faces_at[v.0 as usize];
            if let (true, Some(start)) = (faces > 1, loop_at[v.0 as usize]) {
                if self.fan_faces(start, faces) < faces {
                    non_manifold_verts += 1;
                }
            }
        }
        let mut area = 0.0;
        let mut signed_volume = 0.0;
        let mut triangles = 0;
        let mut points: Vec<DVec3> = Vec::new();
        for f in self.face_ids() {
            points.clear();
            points.extend(self.face_verts(f).map(|v| self.position(v)));
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

    /// How many faces around `start`'s vertex `v` the fan of `start`'s
    /// face holds: faces are joined across edges at `v` that have exactly
    /// two faces, and `v` is manifold when its fan holds all its faces.
    /// Each face has two edges at `v` and each joining edge two faces, so
    /// the fan is a path or a cycle: walked both ways from `start` without
    /// allocating, in at most `faces` steps (independent of orientation).
    fn fan_faces(&self, start: LoopId, faces: u32) -> u32 {
        let v = self.lp(start).vert;
        let mut reached = 1;
        // Leave `start`'s face by its outgoing edge, then by its incoming
        // one (when the first walk did not come round).
        for leave_by_own_edge in [true, false] {
            let mut at = start;
            let mut own = leave_by_own_edge;
            while reached < faces {
                // The loop of the leaving edge in this face.
                let leaving = if own { at } else { self.lp(at).prev };
                let across = self.lp(leaving).radial_next;
                if across == leaving || self.lp(across).radial_next != leaving {
                    break; // a boundary or non-manifold edge ends the fan
                }
                // The next face's loop at `v`, and whether the walk leaves
                // that face by the loop's own edge (the one it did not
                // arrive by) or by its predecessor's.
                (at, own) = if self.lp(across).vert == v {
                    (across, false)
                } else {
                    (self.lp(across).next, true)
                };
                if at == start {
                    return reached;
                }
                reached += 1;
            }
        }
        reached
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

    /// Fan count by brute force: union faces around `v` across edges at
    /// `v` with exactly two faces.
    fn fans_by_union_find(m: &Mesh, v: VertId) -> usize {
        let faces: Vec<_> = m.vert_faces(v).collect();
        let mut groups = UnionFind::new(faces.len());
        for e in m.vert_edges(v) {
            let around: Vec<_> = m.edge_faces(e).collect();
            if let [a, b] = around[..] {
                let index = |f| faces.iter().position(|&g| g == f).unwrap() as u32;
                groups.union(index(a), index(b));
            }
        }
        (0..faces.len() as u32)
            .filter(|&i| groups.find(i) == i)
            .count()
    }

    #[test]
    fn fan_walk_agrees_with_union_find_on_fans_of_every_shape() {
        // Triangles around a hub: every subset of 8 wedges (open and closed
        // fans, several fans, one wedge flipped so orientation is mixed).
        for mask in 1u32..256 {
            for flipped in [None, Some(mask.trailing_zeros())] {
                let mut m = Mesh::new();
                let hub = m.make_vert(DVec3::ZERO);
                let rim: Vec<_> = (0..8)
                    .map(|k| {
                        let a = k as f64 * std::f64::consts::FRAC_PI_4;
                        m.make_vert(DVec3::new(libm::cos(a), libm::sin(a), 0.0))
                    })
                    .collect();
                for k in 0..8u32 {
                    if mask & (1 << k) != 0 {
                        let (b, c) = (rim[k as usize], rim[(k as usize + 1) % 8]);
                        let ring = if flipped == Some(k) {
                            [hub, c, b]
                        } else {
                            [hub, b, c]
                        };
                        m.make_face(&ring).unwrap();
                    }
                }
                m.validate().unwrap();
                let fans = fans_by_union_find(&m, hub);
                let r = m.report();
                assert_eq!(
                    r.non_manifold_verts,
                    usize::from(fans > 1),
                    "mask {mask:08b} {flipped:?}"
                );
                // A flipped wedge is inconsistent only beside a neighbour.
                let alone =
                    |k: u32| mask & (1 << ((k + 1) % 8)) == 0 && mask & (1 << ((k + 7) % 8)) == 0;
                assert_eq!(r.consistently_oriented, flipped.is_none_or(alone));
            }
        }
    }
}
