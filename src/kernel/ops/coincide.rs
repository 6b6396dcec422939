//! Merging vertices that a growing mesh makes coincide with existing ones
//! (thesis 003 §3.1).
//!
//! A grammar adds a few vertices at a time to a large mesh, so the search
//! for coinciding vertices must cost in proportion to the new vertices, not
//! the mesh. [`VertexGrid`] is an incremental hash grid over vertex
//! positions; [`coinciding`] asks it for the vertices near each new one and
//! groups them into clusters; [`weld_clusters`] glues each cluster onto its
//! survivor and repairs the faces, with the same rules as merge by distance
//! (see [`super::merge`]): an edge between two merged vertices collapses,
//! edges that come to share both ends are glued, faces that hold a vertex
//! twice are split into their simple cycles, pieces with fewer than three
//! vertices and faces that duplicate another are dropped.

use glam::DVec3;
use rustc_hash::FxHashMap;

use super::merge::{cell_coordinate, cluster_roots, weld_gone, MergeResult, VertPoints};
use super::{canonical, OpError};
use crate::kernel::ids::VertId;
use crate::kernel::mesh::Mesh;

/// Vertex ids bucketed by the grid cell of their position.
///
/// Entries are never removed: a vertex that died, moved or whose slot was
/// reused is filtered out when a query checks the live position, and a moved
/// vertex is simply inserted again. The stale entries this leaves are
/// bounded by the insertions, so the grid stays proportional to the work.
#[derive(Debug, Clone)]
pub struct VertexGrid {
    cell: f64,
    cells: FxHashMap<[i64; 3], Vec<VertId>>,
}

impl VertexGrid {
    /// An empty grid for queries up to `distance` (cells are that large; a
    /// zero distance still gets a positive cell, as exact matches share one).
    pub fn new(distance: f64) -> Self {
        Self {
            cell: if distance > 0.0 { distance } else { 1e-9 },
            cells: FxHashMap::default(),
        }
    }

    /// A grid holding every vertex of `mesh`.
    pub fn from_mesh(mesh: &Mesh, distance: f64) -> Self {
        let mut grid = Self::new(distance);
        for v in mesh.vert_ids() {
            grid.insert(mesh, v);
        }
        grid
    }

    fn key(&self, p: DVec3) -> [i64; 3] {
        [
            cell_coordinate(p.x, self.cell),
            cell_coordinate(p.y, self.cell),
            cell_coordinate(p.z, self.cell),
        ]
    }

    /// Records `v` at its current position.
    pub fn insert(&mut self, mesh: &Mesh, v: VertId) {
        let key = self.key(mesh.position(v));
        self.cells.entry(key).or_default().push(v);
    }

    /// Appends to `out` the live vertices within `distance` (at most the
    /// grid's cell size) of `p`. May append a vertex more than once.
    pub fn near(&self, mesh: &Mesh, p: DVec3, distance: f64, out: &mut Vec<VertId>) {
        debug_assert!(distance <= self.cell);
        let [x, y, z] = self.key(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let key = [
                        x.saturating_add(dx),
                        y.saturating_add(dy),
                        z.saturating_add(dz),
                    ];
                    let Some(bucket) = self.cells.get(&key) else {
                        continue;
                    };
                    out.extend(bucket.iter().copied().filter(|&v| {
                        mesh.contains_vert(v) && mesh.position(v).distance(p) <= distance
                    }));
                }
            }
        }
    }
}

/// A group of vertices to become one: `gone` are glued onto `keep`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Cluster {
    pub keep: VertId,
    /// Ascending.
    pub gone: Vec<VertId>,
}

/// The clusters that the vertices `new` form with each other and with the
/// vertices of `grid` within `distance`: connected groups of the
/// within-distance graph (as merge by distance), each with at least one
/// vertex of `new`. The survivor is an old vertex if the cluster has one
/// (the lowest id), so the mesh keeps what it had and new vertices join it
/// (thesis §3.1.2.1); else the new vertex listed first in `new`, so a
/// caller whose ids depend on the order it made things in can still get
/// the same survivors by listing them in a canonical order. Sorted by
/// survivor; independent of the grid's insertion order.
pub fn coinciding(
    mesh: &Mesh,
    grid: &VertexGrid,
    new: &[VertId],
    distance: f64,
) -> Result<Vec<Cluster>, OpError> {
    if !distance.is_finite() || distance < 0.0 {
        return Err(OpError::parameter(
            "distance",
            format!("must be finite and not negative, got {distance}"),
        ));
    }
    // Listing order of each new vertex (the first listing counts).
    let mut order: FxHashMap<VertId, usize> = FxHashMap::default();
    for (k, &v) in new.iter().enumerate() {
        order.entry(v).or_insert(k);
    }
    let mut all = new.to_vec();
    for &v in new {
        mesh.check_vert(v)?;
        grid.near(mesh, mesh.position(v), distance, &mut all);
    }
    let all = canonical(&all);
    let roots = cluster_roots(&VertPoints { mesh, verts: &all }, distance);
    let is_new = |v: VertId| order.contains_key(&v);
    // Per root: the best survivor (old by id, then new by listing order)
    // and whether the cluster holds a new vertex at all.
    let rank = |i: usize| {
        let v = all[i];
        match order.get(&v) {
            None => (false, v.index()),
            Some(&k) => (true, k),
        }
    };
    let mut best: Vec<usize> = (0..all.len()).collect();
    let mut has_new = vec![false; all.len()];
    for (i, &root) in roots.iter().enumerate() {
        let r = root as usize;
        if rank(i) < rank(best[r]) {
            best[r] = i;
        }
        has_new[r] |= is_new(all[i]);
    }
    let mut clusters: Vec<Cluster> = Vec::new();
    let mut index_of_root: Vec<u32> = vec![u32::MAX; all.len()];
    for (i, &root) in roots.iter().enumerate() {
        let r = root as usize;
        if !has_new[r] || best[r] == i {
            continue;
        }
        if index_of_root[r] == u32::MAX {
            index_of_root[r] = clusters.len() as u32;
            clusters.push(Cluster {
                keep: all[best[r]],
                gone: Vec::new(),
            });
        }
        clusters[index_of_root[r] as usize].gone.push(all[i]);
    }
    clusters.sort_unstable_by_key(|c| c.keep);
    Ok(clusters)
}

/// Glues every cluster's `gone` vertices onto its `keep` and repairs the
/// faces (see the module overview). Positions are not changed: set the
/// survivors' positions first if they should move.
pub fn weld_clusters(mesh: &mut Mesh, clusters: &[Cluster]) -> Result<MergeResult, OpError> {
    let mut gone: Vec<(VertId, VertId)> = Vec::new();
    for c in clusters {
        mesh.check_vert(c.keep)?;
        for &v in &c.gone {
            mesh.check_vert(v)?;
            gone.push((v, c.keep));
        }
    }
    gone.sort_unstable();
    if gone.windows(2).any(|w| w[0].0 == w[1].0) {
        return Err(OpError::parameter(
            "clusters",
            "a vertex is in two clusters",
        ));
    }
    let survivors = canonical(&clusters.iter().map(|c| c.keep).collect::<Vec<_>>());
    weld_gone(mesh, gone, survivors)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(mesh: &mut Mesh, x: f64, y: f64, z: f64) -> VertId {
        mesh.make_vert(DVec3::new(x, y, z))
    }

    /// Each face's vertex set, sorted.
    fn rings(mesh: &Mesh) -> Vec<Vec<VertId>> {
        let mut rings: Vec<Vec<VertId>> = mesh
            .face_ids()
            .map(|f| canonical(&mesh.face_verts(f).collect::<Vec<_>>()))
            .collect();
        rings.sort();
        rings
    }

    fn counts(mesh: &Mesh) -> [usize; 3] {
        [mesh.vert_count(), mesh.edge_count(), mesh.face_count()]
    }

    /// Merges `new` into the rest of the mesh as a grammar step would.
    fn merge_new(mesh: &mut Mesh, new: &[VertId]) -> MergeResult {
        let grid = VertexGrid::from_mesh(mesh, 1e-6);
        let clusters = coinciding(mesh, &grid, new, 1e-6).unwrap();
        let result = weld_clusters(mesh, &clusters).unwrap();
        mesh.validate().unwrap();
        result
    }

    #[test]
    fn grid_finds_only_live_vertices_within_distance() {
        let mut mesh = Mesh::new();
        let a = v(&mut mesh, 0.0, 0.0, 0.0);
        let b = v(&mut mesh, 0.05, 0.0, 0.0);
        let c = v(&mut mesh, 0.2, 0.0, 0.0);
        let grid = VertexGrid::from_mesh(&mesh, 0.1);
        let mut out = Vec::new();
        grid.near(&mesh, DVec3::ZERO, 0.1, &mut out);
        assert_eq!(canonical(&out), vec![a, b]);
        mesh.kill_vert(b).unwrap();
        out.clear();
        grid.near(&mesh, DVec3::ZERO, 0.1, &mut out);
        assert_eq!(out, vec![a]);
        // Moved: found at the new place once inserted again.
        mesh.place(c, DVec3::new(0.01, 0.0, 0.0));
        let mut grid = grid;
        grid.insert(&mesh, c);
        out.clear();
        grid.near(&mesh, DVec3::ZERO, 0.1, &mut out);
        assert_eq!(canonical(&out), vec![a, c]);
    }

    #[test]
    fn an_old_vertex_survives_even_with_a_higher_id() {
        let mut mesh = Mesh::new();
        let new = v(&mut mesh, 1.0, 0.0, 0.0);
        let old = v(&mut mesh, 1.0, 0.0, 0.0);
        let far = v(&mut mesh, 5.0, 0.0, 0.0);
        let grid = VertexGrid::from_mesh(&mesh, 1e-6);
        let clusters = coinciding(&mesh, &grid, &[new, far], 1e-6).unwrap();
        assert_eq!(
            clusters,
            vec![Cluster {
                keep: old,
                gone: vec![new]
            }]
        );
    }

    #[test]
    fn clusters_do_not_depend_on_the_order_of_new_vertices() {
        let mut mesh = Mesh::new();
        let ids: Vec<VertId> = (0..12)
            .map(|i| v(&mut mesh, f64::from(i % 4), 0.0, 0.0))
            .collect();
        let grid = VertexGrid::from_mesh(&mesh, 1e-6);
        let forward = coinciding(&mesh, &grid, &ids[6..], 1e-6).unwrap();
        let mut reversed: Vec<VertId> = ids[6..].to_vec();
        reversed.reverse();
        assert_eq!(coinciding(&mesh, &grid, &reversed, 1e-6).unwrap(), forward);
        assert_eq!(forward.len(), 4);
    }

    #[test]
    fn among_new_vertices_the_first_listed_survives() {
        let mut mesh = Mesh::new();
        let a = v(&mut mesh, 2.0, 0.0, 0.0);
        let b = v(&mut mesh, 2.0, 0.0, 0.0);
        let grid = VertexGrid::new(1e-6);
        let keep = |new: &[VertId]| coinciding(&mesh, &grid, new, 1e-6).unwrap()[0].keep;
        assert_eq!(keep(&[b, a]), b);
        assert_eq!(keep(&[a, b]), a);
    }

    #[test]
    fn bad_distance_is_refused() {
        let mesh = Mesh::new();
        let grid = VertexGrid::new(1.0);
        for d in [-1.0, f64::NAN, f64::INFINITY] {
            assert!(coinciding(&mesh, &grid, &[], d).is_err());
        }
    }

    /// Fig 3.4 (a): the new node lands on a node joined to it by an edge
    /// e_i. e_i goes, the triangle f2 on it goes, the quad f1 on it loses a
    /// corner, and the two edges that now share both ends become one.
    #[test]
    fn fig_3_4_a_edge_between_merged_nodes_is_deleted() {
        let mut mesh = Mesh::new();
        let ni = v(&mut mesh, 0.0, 0.0, 0.0);
        let a = v(&mut mesh, 1.0, 1.0, 0.0);
        let b = v(&mut mesh, -1.0, 1.0, 0.0);
        let c = v(&mut mesh, -1.0, -1.0, 0.0);
        let n_new = v(&mut mesh, 0.0, -1.0, 0.0);
        // f2: triangle (ni, n_new, a); f1: quad (ni, b, c, n_new) on the other side.
        mesh.make_face(&[ni, n_new, a]).unwrap();
        mesh.make_face(&[ni, b, c, n_new]).unwrap();
        mesh.place(n_new, DVec3::ZERO);
        assert_eq!(counts(&mesh), [5, 6, 2]);
        let result = merge_new(&mut mesh, &[n_new]);
        assert_eq!(result.merged, 1);
        assert!(mesh.contains_vert(ni) && !mesh.contains_vert(n_new));
        // f2 is gone (it would have two nodes), f1 is the triangle (ni, b,
        // c) (freed slots are reused, so compare rings, not ids); e_i is
        // gone and (n_new, a) became (ni, a).
        let rings = rings(&mesh);
        assert_eq!(rings, vec![canonical(&[ni, b, c])]);
        assert_eq!(counts(&mesh), [4, 4, 1]);
        assert!(mesh.find_edge(ni, a).is_some());
    }

    /// Fig 3.4 (b): a face holds the merged node twice (non-consecutive):
    /// it is split into two faces.
    #[test]
    fn fig_3_4_b_face_with_a_node_twice_is_split() {
        let mut mesh = Mesh::new();
        // A hexagon-like ring whose vertices 1 and 4 come to coincide.
        let p = [
            (0.0, -2.0),
            (0.0, 0.0),
            (-2.0, 1.0),
            (-2.0, -1.0),
            (0.0, 0.1),
            (2.0, -1.0),
        ];
        let ids: Vec<VertId> = p.iter().map(|&(x, y)| v(&mut mesh, x, y, 0.0)).collect();
        // Ring: 0 → 5 → 4 → 3 → 2 → 1 would cross; use 1,2,3,4,5,0 with 4 near 1.
        mesh.make_face(&[ids[1], ids[2], ids[3], ids[4], ids[5], ids[0]])
            .unwrap();
        mesh.place(ids[4], DVec3::ZERO);
        let result = merge_new(&mut mesh, &[ids[4]]);
        assert_eq!(result.merged, 1);
        // Pieces: (1, 2, 3) and (1, 5, 0).
        let rings = rings(&mesh);
        assert_eq!(
            rings,
            vec![
                canonical(&[ids[0], ids[1], ids[5]]),
                canonical(&[ids[1], ids[2], ids[3]])
            ]
        );
        assert_eq!(result.remade.len(), 2);
    }

    /// Fig 3.4 (c): merging makes a face's ring run through an edge twice
    /// (two sub-loops joined by e_i): the face is split into the two loops
    /// and the edge between them stays as a plain edge.
    #[test]
    fn fig_3_4_c_sub_loops_joined_by_an_edge_are_split() {
        let mut mesh = Mesh::new();
        // Ring a b n_i c d n_new with n_new coming onto n_i, and b–n_i /
        // n_new–a making the two loops (a, b, n_i) and (n_i, c, d).
        let a = v(&mut mesh, -1.0, 1.0, 0.0);
        let b = v(&mut mesh, -1.0, -1.0, 0.0);
        let ni = v(&mut mesh, 0.0, 0.0, 0.0);
        let c = v(&mut mesh, 1.0, -1.0, 0.0);
        let d = v(&mut mesh, 1.0, 1.0, 0.0);
        let n_new = v(&mut mesh, 0.0, 0.5, 0.0);
        mesh.make_face(&[a, b, ni, c, d, n_new]).unwrap();
        mesh.place(n_new, DVec3::ZERO);
        let result = merge_new(&mut mesh, &[n_new]);
        let rings = rings(&mesh);
        assert_eq!(rings, vec![canonical(&[a, b, ni]), canonical(&[ni, c, d])]);
        assert_eq!(result.merged, 1);
    }

    /// Fig 3.4 (d): a triangle f2 that, after the merge, duplicates a piece
    /// of the split face f1 is deleted; f1 is split into two.
    #[test]
    fn fig_3_4_d_duplicate_triangle_is_deleted() {
        let mut mesh = Mesh::new();
        let a = v(&mut mesh, -1.0, 0.0, 0.0);
        let b = v(&mut mesh, 0.0, 1.0, 0.0);
        let ni = v(&mut mesh, 1.0, 0.0, 0.0);
        let c = v(&mut mesh, 2.0, 1.0, 0.0);
        let d = v(&mut mesh, 2.0, -1.0, 0.0);
        let n_new = v(&mut mesh, 0.5, -1.0, 0.0);
        // f1 = (a, b, ni, c, d, n_new): n_new lands on ni, so f1 holds ni
        // twice and splits into (a, b, ni) and (ni, c, d).
        mesh.make_face(&[a, n_new, d, c, ni, b]).unwrap();
        // f2 = (a, b, ni) seen from the other side: a duplicate of a piece.
        let f2 = mesh.make_face(&[a, b, ni]).unwrap();
        mesh.place(n_new, mesh.position(ni));
        let result = merge_new(&mut mesh, &[n_new]);
        assert!(mesh.contains_face(f2), "the untouched face is kept");
        let rings = rings(&mesh);
        assert_eq!(rings, vec![canonical(&[a, b, ni]), canonical(&[ni, c, d])]);
        assert_eq!(result.merged, 1);
    }

    #[test]
    fn a_vertex_in_two_clusters_is_refused() {
        let mut mesh = Mesh::new();
        let a = v(&mut mesh, 0.0, 0.0, 0.0);
        let b = v(&mut mesh, 0.0, 0.0, 0.0);
        let c = v(&mut mesh, 0.0, 0.0, 0.0);
        let clusters = [
            Cluster {
                keep: a,
                gone: vec![c],
            },
            Cluster {
                keep: b,
                gone: vec![c],
            },
        ];
        assert!(weld_clusters(&mut mesh, &clusters).is_err());
    }
}
