//! The `merge` policy (thesis 003 §3.1): after a command, the nodes it
//! created or moved are merged with the nodes they coincide with.
//!
//! The kernel finds the clusters and repairs the topology
//! ([`coincide`](crate::kernel::ops::coincide)); this module adds what the
//! grammar model asks for: the surviving node takes the mean position and
//! radius of its cluster (§3.1.2.1), and edges that come to share both ends
//! are glued with their left directions averaged and re-orthogonalized
//! (§3.1.2.2).

use glam::DVec3;
use rustc_hash::FxHashMap;

use super::graph::{self, Frame};
use crate::kernel::ids::{Domain, EdgeId, VertId};
use crate::kernel::mesh::Mesh;
use crate::kernel::ops::coincide::{coinciding, weld_clusters, Cluster, VertexGrid};
use crate::kernel::ops::{OpError, Selection};

/// The vertex grid a run keeps between merging commands.
pub struct Merger {
    grid: Option<VertexGrid>,
    /// Largest tolerance the grid answers (its cell size).
    cell: f64,
}

impl Merger {
    pub fn new() -> Self {
        Self {
            grid: None,
            cell: 0.0,
        }
    }

    /// Forgets the grid: a step that is not a G³ command may have moved or
    /// made any vertex. The next merge rebuilds it from the mesh.
    pub fn invalidate(&mut self) {
        self.grid = None;
    }

    /// Records vertices a non-merging command made or moved, so later
    /// merges find them.
    pub fn record(&mut self, mesh: &Mesh, verts: &[VertId]) {
        if let Some(grid) = &mut self.grid {
            for &v in verts {
                if mesh.contains_vert(v) {
                    grid.insert(mesh, v);
                }
            }
        }
    }

    /// Merges `new` (vertices a command made or moved, already in the mesh)
    /// with every vertex within `tolerance`, and rewrites `made` (the
    /// command's products) to what survives: the clusters' survivors
    /// replace merged vertices, dead edges and faces are dropped, faces
    /// remade by the repair are added. Returns the number of vertices merged
    /// away.
    pub fn merge(
        &mut self,
        mesh: &mut Mesh,
        new: &[VertId],
        tolerance: f64,
        made: &mut Selection,
    ) -> Result<usize, OpError> {
        made.normalize();
        if new.is_empty() {
            // Nothing made or moved: no grid to build or search.
            return Ok(0);
        }
        let grid = match &mut self.grid {
            Some(grid) if tolerance <= self.cell => grid,
            _ => {
                // Everything but `new`: the grid holds the mesh as it was.
                self.cell = self.cell.max(tolerance);
                let mut grid = VertexGrid::new(self.cell);
                for v in mesh.vert_ids() {
                    grid.insert(mesh, v);
                }
                self.grid.insert(grid)
            }
        };
        let clusters = coinciding(mesh, grid, new, tolerance)?;
        let merged = if clusters.is_empty() {
            0
        } else {
            average_nodes(mesh, &clusters);
            let glued = edge_groups(mesh, &clusters, &made.edges);
            let result = weld_clusters(mesh, &clusters)?;
            settle_glued(mesh, glued)?;
            drop_flat_faces(mesh, &clusters, tolerance)?;
            made.faces.extend(result.remade);
            made.verts.extend(clusters.iter().map(|c| c.keep));
            result.merged
        };
        for &v in new.iter().chain(clusters.iter().map(|c| &c.keep)) {
            if mesh.contains_vert(v) {
                grid.insert(mesh, v);
            }
        }
        made.verts.retain(|&v| mesh.contains_vert(v));
        made.edges.retain(|&e| mesh.contains_edge(e));
        made.faces.retain(|&f| mesh.contains_face(f));
        made.normalize();
        Ok(merged)
    }
}

/// Each survivor takes its cluster's mean position and radius; the faces
/// around it get fresh normals.
fn average_nodes(mesh: &mut Mesh, clusters: &[Cluster]) {
    for c in clusters {
        let members = || std::iter::once(c.keep).chain(c.gone.iter().copied());
        let n = (c.gone.len() + 1) as f64;
        let position = members().map(|v| mesh.position(v)).sum::<DVec3>() / n;
        let radius = members().map(|v| graph::radius(mesh, v)).sum::<f64>() / n;
        mesh.move_vert(c.keep, position);
        graph::set_radius(mesh, c.keep, radius);
    }
}

/// Kills the faces around the survivors that merging left flat: all their
/// nodes within `tolerance` of one line (zero area, or collinear nodes, say
/// a triangle whose apex merged onto its base's line). A face is flat when
/// its area is at most `tolerance` × half its perimeter — its width is
/// below what the merge treats as one point. Its edges stay.
fn drop_flat_faces(mesh: &mut Mesh, clusters: &[Cluster], tolerance: f64) -> Result<(), OpError> {
    let mut faces: Vec<_> = clusters
        .iter()
        .filter(|c| mesh.contains_vert(c.keep))
        .flat_map(|c| mesh.vert_faces(c.keep))
        .collect();
    faces.sort_unstable();
    faces.dedup();
    for f in faces {
        let ring = mesh.face_positions(f);
        let perimeter: f64 = (0..ring.len())
            .map(|i| ring[i].distance(ring[(i + 1) % ring.len()]))
            .sum();
        let area = mesh.face_area(f);
        let width_area = tolerance.max(f64::EPSILON) * 0.5 * perimeter;
        // A NaN area counts as flat.
        if area.is_nan() || area <= width_area {
            mesh.kill_face(f)?;
        }
    }
    Ok(())
}

/// Edges that will become one once the clusters are glued: their ends
/// (survivor ids, lower first), each edge's left direction turned to point
/// the way it would on an edge running lower → higher, and the direction
/// the glued edge should run.
struct GluedEdges {
    ends: [VertId; 2],
    lefts: Vec<DVec3>,
    /// Whether the glued edge runs `ends[0]` → `ends[1]`.
    forward: bool,
}

/// The groups of edges that will share both ends once the clusters are
/// glued (two or more edges each), in ascending order of ends.
///
/// Which edge of a group the kernel keeps depends on ids, and ids depend
/// on the order a command's plans were applied in, so the glued edge's
/// direction is decided here without ids: the lowest-id edge that existed
/// before the command (`made_edges` are the command's), else the direction
/// from the endpoint with the lexicographically smaller position.
fn edge_groups(mesh: &Mesh, clusters: &[Cluster], made_edges: &[EdgeId]) -> Vec<GluedEdges> {
    let survivor: FxHashMap<VertId, VertId> = clusters
        .iter()
        .flat_map(|c| c.gone.iter().map(move |&g| (g, c.keep)))
        .collect();
    let map = |v: VertId| survivor.get(&v).copied().unwrap_or(v);
    let mut touched: Vec<EdgeId> = clusters
        .iter()
        .flat_map(|c| std::iter::once(c.keep).chain(c.gone.iter().copied()))
        .flat_map(|v| mesh.vert_edges(v))
        .collect();
    touched.sort_unstable();
    touched.dedup();
    // Ends → (lefts, direction of the lowest old edge).
    let mut groups: FxHashMap<[VertId; 2], (Vec<DVec3>, Option<bool>)> = FxHashMap::default();
    for e in touched {
        let [a, b] = mesh.edge_verts(e).map(map);
        if a == b {
            continue; // collapses
        }
        let left = graph::edge_frame(mesh, e).l;
        let (ends, left) = if a < b {
            ([a, b], left)
        } else {
            ([b, a], -left)
        };
        let group = groups.entry(ends).or_default();
        group.0.push(left);
        let old = made_edges.binary_search(&e).is_err();
        if old && group.1.is_none() {
            // `touched` is ascending: the first old edge is the lowest.
            group.1 = Some(a < b);
        }
    }
    let mut groups: Vec<GluedEdges> = groups
        .into_iter()
        .filter(|(_, (lefts, _))| lefts.len() > 1)
        .map(|(ends, (lefts, old_forward))| {
            let forward = old_forward.unwrap_or_else(|| {
                let [p, q] = ends.map(|v| mesh.position(v).to_array());
                p <= q
            });
            GluedEdges {
                ends,
                lefts,
                forward,
            }
        })
        .collect();
    groups.sort_unstable_by_key(|g| g.ends);
    groups
}

/// Turns the edge each group was glued into the group's direction and
/// gives it the group's mean left direction, re-orthogonalized.
fn settle_glued(mesh: &mut Mesh, groups: Vec<GluedEdges>) -> Result<(), OpError> {
    for group in groups {
        let [a, b] = group.ends;
        let Some(e) = mesh.find_edge(a, b) else {
            continue;
        };
        let (from, to) = if group.forward { (a, b) } else { (b, a) };
        if mesh.edge_verts(e)[0] != from {
            mesh.reverse_edge(e)?;
        }
        let mut left: DVec3 = group.lefts.iter().sum();
        if !group.forward {
            left = -left;
        }
        let frame = Frame::from_heading_left(mesh.position(to) - mesh.position(from), left);
        graph::set_frame(mesh, Domain::Edge, e.index(), &frame);
    }
    Ok(())
}

impl Default for Merger {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A triangle A B C and a lone node at `d`; C is moved onto `d` and
    /// merged as an `edit_node` with the merge policy would.
    fn move_apex_onto(d: DVec3) -> Mesh {
        let mut mesh = Mesh::new();
        graph::ensure_layers(&mut mesh);
        let a = mesh.make_vert(DVec3::ZERO);
        let b = mesh.make_vert(DVec3::new(2.0, 0.0, 0.0));
        let c = mesh.make_vert(DVec3::new(1.0, 1.0, 0.0));
        mesh.make_face(&[a, b, c]).unwrap();
        mesh.make_vert(d);
        mesh.move_vert(c, d);
        let mut made = Selection::default();
        made.verts.push(c);
        let merged = Merger::new()
            .merge(&mut mesh, &[c], 1e-6, &mut made)
            .unwrap();
        assert_eq!(merged, 1);
        mesh.validate().unwrap();
        mesh
    }

    #[test]
    fn a_face_merged_flat_is_removed_and_its_edges_stay() {
        let mesh = move_apex_onto(DVec3::new(1.0, 0.0, 0.0));
        assert_eq!(
            [mesh.vert_count(), mesh.edge_count(), mesh.face_count()],
            [3, 3, 0]
        );
    }

    #[test]
    fn a_thin_face_that_is_not_flat_stays() {
        let mesh = move_apex_onto(DVec3::new(1.0, 1e-3, 0.0));
        assert_eq!(mesh.face_count(), 1);
        assert!(mesh.face_ids().all(|f| mesh.face_area(f) > 0.0));
    }
}
