//! Checks of an indexed triangle mesh: closed, edge- and vertex-manifold,
//! consistently oriented, components, Euler characteristic, genus, volume.
//! The meshers' guarantees are tested with these, and the skin reports them.

use glam::DVec3;

use crate::geom::union_find::UnionFind;

/// What [`check`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshCheck {
    /// Vertices used by some triangle.
    pub vertices: usize,
    pub triangles: usize,
    pub edges: usize,
    /// Edges with one triangle.
    pub boundary_edges: usize,
    /// Edges with three or more triangles.
    pub nonmanifold_edges: usize,
    /// Edges whose two triangles run the same way.
    pub inconsistent_edges: usize,
    /// Vertices whose triangles do not form a single disk (checked only when
    /// every edge is manifold and consistent).
    pub nonmanifold_vertices: usize,
    /// Triangles with two equal indices.
    pub degenerate_indices: usize,
    /// Triangles with zero computed area.
    pub zero_area: usize,
    /// Connected components (triangles sharing a vertex).
    pub components: usize,
    /// V − E + F.
    pub euler: i64,
    /// Signed volume (positive for outward orientation).
    pub volume: f64,
    pub area: f64,
}

impl MeshCheck {
    /// Closed, 2-manifold and consistently oriented.
    pub fn is_closed_manifold(&self) -> bool {
        self.boundary_edges == 0
            && self.nonmanifold_edges == 0
            && self.inconsistent_edges == 0
            && self.nonmanifold_vertices == 0
            && self.degenerate_indices == 0
    }

    /// Total genus of a closed orientable surface: Σ (2 − χᵢ)/2 =
    /// components − χ/2.
    pub fn genus(&self) -> Option<i64> {
        if self.is_closed_manifold() && (2 * self.components as i64 - self.euler) % 2 == 0 {
            Some((2 * self.components as i64 - self.euler) / 2)
        } else {
            None
        }
    }
}

/// Checks a mesh.
pub fn check(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> MeshCheck {
    let nv = positions.len();
    let mut used = vec![false; nv];
    let mut degenerate = 0;
    let mut zero_area = 0;
    let mut volume = 0.0;
    let mut area = 0.0;
    for t in triangles {
        for &v in t {
            used[v as usize] = true;
        }
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            degenerate += 1;
        }
        let a = DVec3::from_array(positions[t[0] as usize]);
        let b = DVec3::from_array(positions[t[1] as usize]);
        let c = DVec3::from_array(positions[t[2] as usize]);
        let cr = (b - a).cross(c - a);
        if cr.length_squared() == 0.0 {
            zero_area += 1;
        }
        area += cr.length() * 0.5;
        volume += a.dot(b.cross(c)) / 6.0;
    }
    let counts = edge_counts(nv, triangles, degenerate == 0);
    let mut sets = UnionFind::new(nv);
    for t in triangles {
        sets.union(t[0], t[1]);
        sets.union(t[0], t[2]);
    }
    let components = (0..nv as u32)
        .filter(|&v| used[v as usize] && sets.find(v) == v)
        .count();
    let vcount = used.iter().filter(|&&u| u).count();
    MeshCheck {
        vertices: vcount,
        triangles: triangles.len(),
        edges: counts.edges,
        boundary_edges: counts.boundary,
        nonmanifold_edges: counts.nonmanifold,
        inconsistent_edges: counts.inconsistent,
        nonmanifold_vertices: counts.nonmanifold_vertices,
        degenerate_indices: degenerate,
        zero_area,
        components,
        euler: vcount as i64 - counts.edges as i64 + triangles.len() as i64,
        volume,
        area,
    }
}

/// Component label per triangle (smallest vertex id of the component),
/// for splitting a mesh into solids.
pub fn triangle_components(nv: usize, triangles: &[[u32; 3]]) -> Vec<u32> {
    let mut sets = UnionFind::new(nv);
    for t in triangles {
        sets.union(t[0], t[1]);
        sets.union(t[0], t[2]);
    }
    triangles.iter().map(|t| sets.find(t[0])).collect()
}

/// Edges of a triangle list by their number of triangles, and vertices
/// whose triangles do not form one disk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EdgeCounts {
    pub edges: usize,
    /// Edges with one triangle.
    pub boundary: usize,
    /// Edges with three or more triangles.
    pub nonmanifold: usize,
    /// Edges whose two triangles run the same way.
    pub inconsistent: usize,
    /// Counted only when `walk_fans` and every edge has two consistent
    /// triangles (a fan walk needs both); 0 otherwise.
    pub nonmanifold_vertices: usize,
}

/// Counts edges by sorting directed half-edges (no hashing: the same
/// answer in the same time on any input order), then walks every vertex's
/// fan across opposite half-edges.
pub fn edge_counts(nv: usize, triangles: &[[u32; 3]], walk_fans: bool) -> EdgeCounts {
    let key = crate::geom::edge_key::directed;
    let mut half: Vec<(u64, u32)> = Vec::with_capacity(triangles.len() * 3);
    for (ti, t) in triangles.iter().enumerate() {
        for k in 0..3 {
            half.push((key(t[k], t[(k + 1) % 3]), ti as u32));
        }
    }
    let mut undirected: Vec<(u64, bool)> = half
        .iter()
        .map(|&(k, _)| {
            let (a, b) = ((k >> 32) as u32, k as u32);
            (key(a.min(b), a.max(b)), a < b)
        })
        .collect();
    undirected.sort_unstable();
    let mut counts = EdgeCounts {
        edges: 0,
        boundary: 0,
        nonmanifold: 0,
        inconsistent: 0,
        nonmanifold_vertices: 0,
    };
    for run in undirected.chunk_by(|x, y| x.0 == y.0) {
        counts.edges += 1;
        match run.len() {
            1 => counts.boundary += 1,
            2 if run[0].1 == run[1].1 => counts.inconsistent += 1,
            2 => {}
            _ => counts.nonmanifold += 1,
        }
    }
    if !walk_fans || counts.boundary + counts.nonmanifold + counts.inconsistent > 0 {
        return counts;
    }
    half.sort_unstable();
    let find = |a: u32, b: u32| -> Option<u32> {
        let k = key(a, b);
        let i = half.partition_point(|h| h.0 < k);
        (i < half.len() && half[i].0 == k).then(|| half[i].1)
    };
    let mut corners = vec![0u32; nv];
    for t in triangles {
        for &v in t {
            corners[v as usize] += 1;
        }
    }
    let mut seen = vec![false; nv];
    for (ti, t) in triangles.iter().enumerate() {
        for k in 0..3 {
            let v = t[k];
            if std::mem::replace(&mut seen[v as usize], true) {
                continue;
            }
            // Walk the fan of v: from triangle (v, a, ·) to the triangle
            // holding a→v, where v's successor is the next spoke.
            let mut steps = 0u32;
            let mut a = t[(k + 1) % 3];
            loop {
                steps += 1;
                let Some(t2) = find(a, v) else { break };
                if t2 as usize == ti || steps > corners[v as usize] {
                    break;
                }
                let tr = triangles[t2 as usize];
                let kv = (0..3).find(|&m| tr[m] == v).unwrap_or(0);
                a = tr[(kv + 1) % 3];
            }
            if steps != corners[v as usize] {
                counts.nonmanifold_vertices += 1;
            }
        }
    }
    counts
}

/// Signed volume of every connected component, ordered by the component's
/// smallest vertex id: positive for an outward shell (a solid), negative
/// for an inward one (a cavity inside a solid).
pub fn shell_volumes(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Vec<f64> {
    let lab = triangle_components(positions.len(), triangles);
    let mut vol: std::collections::BTreeMap<u32, f64> = std::collections::BTreeMap::new();
    for (t, l) in triangles.iter().zip(&lab) {
        let p = |i: u32| DVec3::from_array(positions[i as usize]);
        *vol.entry(*l).or_insert(0.0) += p(t[0]).dot(p(t[1]).cross(p(t[2]))) / 6.0;
    }
    vol.into_values().collect()
}
