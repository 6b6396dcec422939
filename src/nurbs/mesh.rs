//! The neutral triangle mesh every tessellator and the PN smoother produce, and the checks the
//! tests (and the integrator) run on it.
//!
//! [`TriMesh`] is indexed: positions, per-vertex (u, v), per-vertex unit normals and
//! counter-clockwise triangles (seen from the side the normal points to; for surfaces the
//! normal is S_u × S_v). Its order is canonical: it depends only on the input, never on thread
//! count or hash order. [`TriMesh::edge_census`] counts boundary, interior and non-manifold
//! edges (thesis Definition 2.1.1's "well aligned" tessellation has no T-junctions: every
//! interior edge has exactly two triangles).

use super::hash::edge_ends;

/// An indexed triangle mesh.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriMesh {
    /// Vertex positions.
    pub positions: Vec<[f64; 3]>,
    /// Per-vertex parameters: (u, v) on a surface (seam vertices carry the lower end of a closed
    /// direction); barycentric-interpolated input (u, v) for PN output when given, else empty.
    pub uvs: Vec<[f64; 2]>,
    /// Per-vertex unit normals.
    pub normals: Vec<[f64; 3]>,
    /// Triangles as vertex indices, counter-clockwise.
    pub triangles: Vec<[u32; 3]>,
}

/// Edge statistics of a mesh.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct EdgeCensus {
    /// Edges with exactly one triangle, as (lower, higher) vertex ids, sorted.
    pub boundary: Vec<[u32; 2]>,
    /// Edges with exactly two triangles.
    pub interior: usize,
    /// Edges with three or more triangles.
    pub non_manifold: usize,
    /// Interior edges whose two triangles traverse it in the same direction (inconsistent
    /// orientation).
    pub misoriented: usize,
    /// Triangles with a repeated vertex.
    pub degenerate: usize,
}

impl EdgeCensus {
    /// True when the mesh is closed, manifold and consistently oriented.
    pub fn is_closed_manifold(&self) -> bool {
        self.boundary.is_empty()
            && self.non_manifold == 0
            && self.misoriented == 0
            && self.degenerate == 0
    }
}

impl TriMesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Whether any position, normal or parameter is NaN or infinite.
    pub fn has_non_finite(&self) -> bool {
        self.positions.iter().flatten().any(|x| !x.is_finite())
            || self.normals.iter().flatten().any(|x| !x.is_finite())
            || self.uvs.iter().flatten().any(|x| !x.is_finite())
    }

    /// Counts boundary, interior and non-manifold edges by sorting directed edges.
    pub fn edge_census(&self) -> EdgeCensus {
        let mut directed: Vec<(u64, bool)> = Vec::with_capacity(self.triangles.len() * 3);
        let mut degenerate = 0;
        for t in &self.triangles {
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                degenerate += 1;
            }
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let forward = a < b;
                directed.push((super::hash::edge_key(a, b), forward));
            }
        }
        directed.sort_unstable();
        let mut census = EdgeCensus {
            degenerate,
            ..EdgeCensus::default()
        };
        let mut i = 0;
        while i < directed.len() {
            let mut j = i + 1;
            while j < directed.len() && directed[j].0 == directed[i].0 {
                j += 1;
            }
            match j - i {
                1 => {
                    let (a, b) = edge_ends(directed[i].0);
                    census.boundary.push([a, b]);
                }
                2 => {
                    census.interior += 1;
                    if directed[i].1 == directed[i + 1].1 {
                        census.misoriented += 1;
                    }
                }
                _ => census.non_manifold += 1,
            }
            i = j;
        }
        census
    }

    /// Maximum |normal| deviation from 1 (0 for unit normals).
    pub fn max_normal_error(&self) -> f64 {
        self.normals
            .iter()
            .map(|n| ((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs())
            .fold(0.0, f64::max)
    }
}
