//! Fully adaptive tessellation (thesis §2.2, Figs 2.4–2.8; spec §2.6; decision D7).
//!
//! The thesis's loop takes triangles off a list and splits them at once (Gauss–Seidel), so its
//! result depends on the visiting order and its splits leave T-junctions. graftal works in
//! rounds instead:
//!
//! 1. on a snapshot of the mesh, every edge gets a verdict from the chosen [`EdgeTest`]s
//!    (which look only at the edge, its two triangles and its first-order neighbours, data both
//!    sides see identically);
//! 2. marked edges get their midpoint vertex (the parametric midpoint V₁₂ of §2.2, evaluated on
//!    the surface, once per edge), and every triangle is split by the number of its marked
//!    edges: 1 → 2, 2 → 3 (cut from the longer marked edge; or 5 around a centre vertex),
//!    3 → 4 (Fig. 2.6);
//! 3. repeat until no edge is marked. Split edges' halves get the parent's level + 1, edges made
//!    inside a triangle the level of its new halves; edges at `max_level` are never marked.
//!
//! Splitting only marked edges on both sides of each edge keeps the mesh conforming; processing
//! in edge-key and triangle order keeps it deterministic. The triangle cap is checked before
//! each round allocates, so memory stays bounded by it.

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use super::super::hash::{edge_ends, edge_key, FxHashMap};
use super::super::mesh::TriMesh;
use super::super::surface::NurbsSurface;
use super::domain::{sample, ParamDomain, Sample};
use super::interpatch::BorderRule;
use super::{check_positive, interpatch, uniform, Diagonal, TessError, TessStats, Tessellation};

/// One edge test of thesis §2.2 (spec §2.6.3). Each answers "subdivide this edge?". N are unit
/// normals, V positions, V₁₂ / N₁₂ the surface point and normal at the edge's parametric
/// midpoint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EdgeTest {
    /// Chordal: |V₁₂ − (V₁ + V₂)/2| > tolerance (model units); also marks the longest edge of a
    /// triangle whose centroid deviates more than `tolerance`, so the reported deviation (edge
    /// midpoints and centroids) ends ≤ tolerance unless `max_level` stops it. The default.
    Sagitta { tolerance: f64 },
    /// Eq. (2.1): |N₁ − N₁₂| > t1 ∨ |N₂ − N₁₂| > t1 (|ΔN| = 2 sin(θ/2); 0.02 ≈ 1.15°).
    OneEdgeNormal { t1: f64 },
    /// Eq. (2.3): (2.1) ∨ |N₁ − N₂| > t2.
    OneEdgeComplementary { t1: f64, t2: f64 },
    /// Eq. (2.4): |N₁₂ − N'| > t3, N' = (N₁ + N₂ + N₆ + N₁₀)/4 (apexes of the two triangles; a
    /// border edge uses its one apex and /3).
    TwoTriangle { t3: f64 },
    /// Eq. (2.5): |N₁₂ − N''| > t3, N'' the mean normal of {V₁, V₂} ∪ link(V₁) ∪ link(V₂).
    FirstOrderNeighbour { t3: f64 },
    /// Eq. (2.6) as its prose means it: d, a, b the unit vectors V₁→V₂, V₁→V₁₂, V₁₂→V₂;
    /// subdivide iff min(a·d, b·d) < cos_max (e.g. cos 2° = 0.99939).
    VectorDeviation { cos_max: f64 },
    /// Local flat test: U = unit(V₁ − V₂); |U·N₁| > t ∨ |U·N₂| > t (t = sin of the allowed
    /// angle, e.g. 0.05).
    LocalFlat { t: f64 },
    /// Umbrella flat test (Def. 2.2.1): Û(V) the unit umbrella vector mean(link) − V;
    /// |Û₁·N₁| > t ∨ |Û₂·N₂| > t. A vanishing umbrella (|U| < 1e-12 × mean link edge) is flat.
    UmbrellaFlat { t: f64 },
}

/// How several tests combine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Combine {
    /// Subdivide if any test says so (default).
    #[default]
    Any,
    /// Subdivide only if every test says so.
    All,
}

/// The two-edge split of Fig. 2.6.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TwoEdgeSplit {
    /// No extra vertex: the quad is cut from the midpoint of the longer marked edge (3D length,
    /// ties to the smaller edge key) to the opposite corner: 3 triangles.
    #[default]
    LongerEdge,
    /// An extra vertex at the quad's parametric centre: 5 triangles.
    Centre,
}

/// The mesh refinement starts from (spec §2.6.4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Initial {
    /// Uniform grid (as [`super::Mode::Uniform`]).
    Uniform {
        cells: [usize; 2],
        per_patch: bool,
        diagonal: Diagonal,
    },
    /// Inter-patch mesh at a tolerance (as [`super::Mode::InterPatch`]).
    InterPatch { tolerance: f64 },
}

/// Options of the fully adaptive mode.
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptiveOptions {
    /// The starting mesh.
    pub initial: Initial,
    /// Edge tests; an empty list refines nothing.
    pub tests: Vec<EdgeTest>,
    /// How tests combine.
    pub combine: Combine,
    /// Edges at this level are never split (default 8).
    pub max_level: u32,
    /// The two-edge split variant.
    pub two_edge: TwoEdgeSplit,
    /// Sagitta only: before splitting, flip a marked interior edge instead when it is the only
    /// marked edge of its two triangles and the flipped diagonal and both new triangles meet the
    /// tolerance (a generalised "shorter diagonal" rule, beyond the thesis). Saves triangles.
    pub flips: bool,
}

impl AdaptiveOptions {
    /// The recommended setting: a chordal tolerance in model units, 3 × 3 cells per Bézier patch
    /// with the better diagonal per cell to start, flips on, `max_level` 12 (spec §2.6.2 says 8 for a 24 × 24 start; a 2 × 2-per-patch start
    /// needs four more levels for the same finest cell, and near poles the radial splits use up
    /// levels of the ring edges).
    pub fn sagitta(tolerance: f64) -> Self {
        AdaptiveOptions {
            initial: Initial::Uniform {
                cells: [3, 3],
                per_patch: true,
                diagonal: Diagonal::Best,
            },
            tests: vec![EdgeTest::Sagitta { tolerance }],
            combine: Combine::Any,
            max_level: 12,
            two_edge: TwoEdgeSplit::LongerEdge,
            flips: true,
        }
    }

    pub(crate) fn validate(&self) -> Result<(), TessError> {
        let nonneg = |name: &'static str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(TessError::InvalidOption {
                    name,
                    value: v,
                    reason: "must be finite and non-negative",
                })
            }
        };
        for t in &self.tests {
            match *t {
                EdgeTest::Sagitta { tolerance } => check_positive("sagitta", tolerance)?,
                EdgeTest::OneEdgeNormal { t1 } => nonneg("t1", t1)?,
                EdgeTest::OneEdgeComplementary { t1, t2 } => {
                    nonneg("t1", t1)?;
                    nonneg("t2", t2)?;
                }
                EdgeTest::TwoTriangle { t3 } | EdgeTest::FirstOrderNeighbour { t3 } => {
                    nonneg("t3", t3)?
                }
                EdgeTest::VectorDeviation { cos_max } => {
                    if !(cos_max.is_finite() && (-1.0..=1.0).contains(&cos_max)) {
                        return Err(TessError::InvalidOption {
                            name: "cos_max",
                            value: cos_max,
                            reason: "must be in [-1, 1]",
                        });
                    }
                }
                EdgeTest::LocalFlat { t } | EdgeTest::UmbrellaFlat { t } => nonneg("t", t)?,
            }
        }
        if self.max_level > 30 {
            return Err(TessError::InvalidOption {
                name: "max_level",
                value: f64::from(self.max_level),
                reason: "must be at most 30",
            });
        }
        Ok(())
    }
}

/// Snapshot topology of one round.
struct Edges {
    keys: Vec<u64>,
    /// Up to two incident (triangle·3 + local edge) codes; u32::MAX when absent.
    tris: Vec<[u32; 2]>,
    /// Per triangle, the edge index of its local edges (v0v1, v1v2, v2v0).
    of_tri: Vec<[u32; 3]>,
}

fn build_edges(tris: &[[u32; 3]]) -> Edges {
    let mut directed: Vec<(u64, u32)> = Vec::with_capacity(tris.len() * 3);
    for (t, tri) in tris.iter().enumerate() {
        for k in 0..3 {
            directed.push((edge_key(tri[k], tri[(k + 1) % 3]), (t * 3 + k) as u32));
        }
    }
    directed.par_sort_unstable();
    let mut keys = Vec::with_capacity(directed.len() / 2 + 8);
    let mut inc = Vec::with_capacity(directed.len() / 2 + 8);
    let mut of_tri = vec![[0u32; 3]; tris.len()];
    for &(key, code) in &directed {
        if keys.last() != Some(&key) {
            keys.push(key);
            inc.push([u32::MAX; 2]);
        }
        let e = keys.len() - 1;
        let slot = &mut inc[e];
        if slot[0] == u32::MAX {
            slot[0] = code;
        } else if slot[1] == u32::MAX {
            slot[1] = code;
        }
        of_tri[(code / 3) as usize][(code % 3) as usize] = e as u32;
    }
    Edges {
        keys,
        tris: inc,
        of_tri,
    }
}

/// Vertex links (CSR), each sorted ascending, from the sorted edge list.
fn build_links(n: usize, keys: &[u64]) -> (Vec<u32>, Vec<u32>) {
    let mut deg = vec![0u32; n + 1];
    for &k in keys {
        let (a, b) = edge_ends(k);
        deg[a as usize] += 1;
        deg[b as usize] += 1;
    }
    let mut offsets = vec![0u32; n + 1];
    for i in 0..n {
        offsets[i + 1] = offsets[i] + deg[i];
    }
    let mut fill = offsets.clone();
    let mut links = vec![0u32; offsets[n] as usize];
    for &k in keys {
        let (a, b) = edge_ends(k);
        links[fill[a as usize] as usize] = b;
        fill[a as usize] += 1;
        links[fill[b as usize] as usize] = a;
        fill[b as usize] += 1;
    }
    for i in 0..n {
        links[offsets[i] as usize..offsets[i + 1] as usize].sort_unstable();
    }
    (offsets, links)
}

struct State {
    dom: ParamDomain,
    pos: Vec<DVec3>,
    nrm: Vec<DVec3>,
    uv: Vec<DVec2>,
    tris: Vec<[u32; 3]>,
    levels: FxHashMap<u64, u32>,
    mids: FxHashMap<u64, (DVec2, Sample)>,
    max_level_reached: u32,
}

impl State {
    fn level(&self, key: u64) -> u32 {
        self.levels.get(&key).copied().unwrap_or(0)
    }

    fn set_level(&mut self, a: u32, b: u32, level: u32) {
        self.levels.insert(edge_key(a, b), level);
        self.max_level_reached = self.max_level_reached.max(level);
    }

    fn push(&mut self, uv: DVec2, s: Sample) -> u32 {
        self.pos.push(s.p);
        self.nrm.push(s.n);
        self.uv.push(uv);
        (self.pos.len() - 1) as u32
    }

    fn umbrella_flat(&self, v: u32, offsets: &[u32], links: &[u32], t: f64) -> bool {
        let link = &links[offsets[v as usize] as usize..offsets[v as usize + 1] as usize];
        if link.is_empty() {
            return false;
        }
        let p = self.pos[v as usize];
        let (mut sum, mut len) = (DVec3::ZERO, 0.0);
        for &w in link {
            let q = self.pos[w as usize];
            sum += q;
            len += (q - p).length();
        }
        let n = link.len() as f64;
        let u = sum / n - p;
        let l = u.length();
        if l < 1e-12 * (len / n) || l == 0.0 {
            return false;
        }
        (u / l).dot(self.nrm[v as usize]).abs() > t
    }
}

#[inline]
fn unit_or(v: DVec3, fallback: DVec3) -> DVec3 {
    let l = v.length();
    if l > 0.0 && l.is_finite() {
        v / l
    } else {
        fallback
    }
}

pub(crate) fn adaptive(
    surface: &NurbsSurface,
    options: &AdaptiveOptions,
    max_triangles: usize,
) -> Result<Tessellation, TessError> {
    options.validate()?;
    let initial = match options.initial {
        Initial::Uniform {
            cells,
            per_patch,
            diagonal,
        } => uniform::uniform(surface, cells, per_patch, diagonal, max_triangles)?,
        Initial::InterPatch { tolerance } => {
            check_positive("tolerance", tolerance)?;
            interpatch::interpatch(surface, tolerance, max_triangles)?
        }
    };
    refine(
        surface,
        options,
        initial,
        &Default::default(),
        None,
        max_triangles,
    )
}

/// Border parameters a refinement must reach, per side ([`crate::nurbs::patchset::Side`]
/// order), sorted: a patch set's neighbour split its side of a shared border there.
pub(crate) type Forced = [Vec<f64>; 4];

/// Adaptive refinement of a conforming `initial` mesh of `surface`; a border edge with a
/// `forced` parameter strictly inside is split whatever the tests say (the level cap
/// included: the neighbour reached it from the same start). With a `rule`, edges on Bézier
/// patch borders are split where the rule says and nowhere else (inter-patch mode).
pub(crate) fn refine(
    surface: &NurbsSurface,
    options: &AdaptiveOptions,
    initial: Tessellation,
    forced: &Forced,
    rule: Option<&BorderRule>,
    max_triangles: usize,
) -> Result<Tessellation, TessError> {
    let mesh = initial.mesh;
    let mut st = State {
        dom: ParamDomain::new(surface),
        pos: mesh
            .positions
            .iter()
            .map(|p| DVec3::from_array(*p))
            .collect(),
        nrm: mesh.normals.iter().map(|p| DVec3::from_array(*p)).collect(),
        uv: mesh.uvs.iter().map(|p| DVec2::from_array(*p)).collect(),
        tris: mesh.triangles,
        levels: FxHashMap::default(),
        mids: FxHashMap::default(),
        max_level_reached: 0,
    };
    let sagitta = options.tests.iter().find_map(|t| match t {
        EdgeTest::Sagitta { tolerance } => Some(*tolerance),
        _ => None,
    });
    let needs_links = options.tests.iter().any(|t| {
        matches!(
            t,
            EdgeTest::FirstOrderNeighbour { .. } | EdgeTest::UmbrellaFlat { .. }
        )
    });
    let max_level = options.max_level;
    let has_forced = forced.iter().any(|f| !f.is_empty());
    let mut rounds = 0u32;
    // Levels bound the depth; the round cap is a second guard.
    let max_rounds = 4 * max_level + 64;
    while rounds < max_rounds && (!options.tests.is_empty() || has_forced) {
        let edges = build_edges(&st.tris);
        let ne = edges.keys.len();
        // Edges whose fate is decided by the border samples, not by the tests.
        let pinned: Vec<Option<bool>> = if has_forced || rule.is_some() {
            edges
                .keys
                .par_iter()
                .map(|&key| {
                    let (a, b) = edge_ends(key);
                    let (a, b) = (st.uv[a as usize], st.uv[b as usize]);
                    if has_forced && st.dom.forced_between(forced, a, b) {
                        Some(true)
                    } else {
                        // Across a seam or from a pole, as the edge's midpoint will be.
                        rule.and_then(|r| {
                            let mut ends = [a, b];
                            st.dom.unwrap(&mut ends);
                            r.verdict(ends[0], ends[1])
                        })
                    }
                })
                .collect()
        } else {
            vec![None; ne]
        };
        // Midpoints of splittable edges, evaluated once per edge and cached across rounds.
        let missing: Vec<u64> = edges
            .keys
            .iter()
            .copied()
            .filter(|k| st.level(*k) < max_level && !st.mids.contains_key(k))
            .collect();
        let computed: Vec<(DVec2, Sample)> = missing
            .par_iter()
            .map(|&k| {
                let (a, b) = edge_ends(k);
                let uv = st.dom.edge_mid(st.uv[a as usize], st.uv[b as usize]);
                (uv, sample(surface, uv))
            })
            .collect();
        for (k, m) in missing.into_iter().zip(computed) {
            st.mids.insert(k, m);
        }
        // Centroid part of the sagitta test: mark the longest splittable edge of a triangle
        // whose centroid deviates too much.
        let mut centroid_mark = vec![false; ne];
        if let Some(eps) = sagitta {
            let picks: Vec<Option<u32>> = st
                .tris
                .par_iter()
                .enumerate()
                .map(|(t, tri)| {
                    let [a, b, c] = tri.map(|v| v as usize);
                    let uv = st.dom.centroid(st.uv[a], st.uv[b], st.uv[c]);
                    let flat = (st.pos[a] + st.pos[b] + st.pos[c]) / 3.0;
                    if (surface.eval_point(uv.x, uv.y) - flat).length() <= eps {
                        return None;
                    }
                    let mut best: Option<(f64, u64, u32)> = None;
                    for k in 0..3 {
                        let e = edges.of_tri[t][k];
                        let key = edges.keys[e as usize];
                        if st.level(key) >= max_level || pinned[e as usize].is_some() {
                            continue;
                        }
                        let (x, y) = edge_ends(key);
                        let len = (st.pos[x as usize] - st.pos[y as usize]).length();
                        let better = match best {
                            None => true,
                            Some((bl, bk, _)) => len > bl || (len == bl && key < bk),
                        };
                        if better {
                            best = Some((len, key, e));
                        }
                    }
                    best.map(|b| b.2)
                })
                .collect();
            for e in picks.into_iter().flatten() {
                centroid_mark[e as usize] = true;
            }
        }
        let (offsets, links) = if needs_links {
            build_links(st.pos.len(), &edges.keys)
        } else {
            (Vec::new(), Vec::new())
        };
        let mut marked: Vec<bool> = (0..ne)
            .into_par_iter()
            .map(|e| {
                let key = edges.keys[e];
                let (a, b) = edge_ends(key);
                let (a, b) = (a as usize, b as usize);
                if let Some(verdict) = pinned[e] {
                    return verdict;
                }
                if st.level(key) >= max_level {
                    return false;
                }
                let (_, mid) = st.mids[&key];
                let (p1, p2, n1, n2) = (st.pos[a], st.pos[b], st.nrm[a], st.nrm[b]);
                let apexes = edges.tris[e].iter().filter(|&&c| c != u32::MAX).map(|&c| {
                    let (t, k) = ((c / 3) as usize, (c % 3) as usize);
                    st.tris[t][(k + 2) % 3] as usize
                });
                let verdict = |test: &EdgeTest| -> bool {
                    match *test {
                        EdgeTest::Sagitta { tolerance } => {
                            centroid_mark[e] || (mid.p - (p1 + p2) * 0.5).length() > tolerance
                        }
                        EdgeTest::OneEdgeNormal { t1 } => {
                            (n1 - mid.n).length() > t1 || (n2 - mid.n).length() > t1
                        }
                        EdgeTest::OneEdgeComplementary { t1, t2 } => {
                            (n1 - mid.n).length() > t1
                                || (n2 - mid.n).length() > t1
                                || (n1 - n2).length() > t2
                        }
                        EdgeTest::TwoTriangle { t3 } => {
                            let (mut sum, mut count) = (n1 + n2, 2.0);
                            for apex in apexes.clone() {
                                sum += st.nrm[apex];
                                count += 1.0;
                            }
                            (mid.n - sum / count).length() > t3
                        }
                        EdgeTest::FirstOrderNeighbour { t3 } => {
                            let la = &links[offsets[a] as usize..offsets[a + 1] as usize];
                            let lb = &links[offsets[b] as usize..offsets[b + 1] as usize];
                            let (mut i, mut j) = (0, 0);
                            let (mut sum, mut count) = (DVec3::ZERO, 0.0);
                            while i < la.len() || j < lb.len() {
                                let v = if j == lb.len() || (i < la.len() && la[i] < lb[j]) {
                                    i += 1;
                                    la[i - 1]
                                } else if i == la.len() || lb[j] < la[i] {
                                    j += 1;
                                    lb[j - 1]
                                } else {
                                    i += 1;
                                    j += 1;
                                    la[i - 1]
                                };
                                sum += st.nrm[v as usize];
                                count += 1.0;
                            }
                            count > 0.0 && (mid.n - sum / count).length() > t3
                        }
                        EdgeTest::VectorDeviation { cos_max } => {
                            let d = unit_or(p2 - p1, DVec3::X);
                            let ua = unit_or(mid.p - p1, d);
                            let ub = unit_or(p2 - mid.p, d);
                            ua.dot(d).min(ub.dot(d)) < cos_max
                        }
                        EdgeTest::LocalFlat { t } => {
                            let u = unit_or(p1 - p2, DVec3::ZERO);
                            u.dot(n1).abs() > t || u.dot(n2).abs() > t
                        }
                        EdgeTest::UmbrellaFlat { t } => {
                            st.umbrella_flat(a as u32, &offsets, &links, t)
                                || st.umbrella_flat(b as u32, &offsets, &links, t)
                        }
                    }
                };
                match options.combine {
                    _ if options.tests.is_empty() => false,
                    Combine::Any => options.tests.iter().any(verdict),
                    Combine::All => options.tests.iter().all(verdict),
                }
            })
            .collect();
        if !marked.iter().any(|&m| m) {
            break;
        }
        rounds += 1;
        let flips = match (options.flips, sagitta, options.tests.len()) {
            (true, Some(eps), 1) => flip_pass(&mut st, &edges, &mut marked, &pinned, eps, surface),
            _ => Vec::new(),
        };
        if !marked.iter().any(|&m| m) {
            for (t, tri) in flips {
                st.tris[t] = tri;
            }
            continue;
        }
        // Exact growth of this round, checked before allocating.
        let mut added: u128 = 0;
        let mut centres: u128 = 0;
        for tri_edges in &edges.of_tri {
            let m = tri_edges.iter().filter(|&&e| marked[e as usize]).count();
            added += match (m, options.two_edge) {
                (2, TwoEdgeSplit::Centre) => {
                    centres += 1;
                    4
                }
                (m, _) => m as u128,
            };
        }
        let needed = st.tris.len() as u128 + added;
        if needed > max_triangles as u128 {
            return Err(TessError::TriangleLimit {
                needed,
                limit: max_triangles,
            });
        }
        let new_vertices =
            st.pos.len() as u128 + marked.iter().filter(|&&m| m).count() as u128 + centres;
        if new_vertices > u32::MAX as u128 {
            return Err(TessError::VertexLimit {
                needed: new_vertices,
            });
        }
        // Midpoint vertices, in edge-key order.
        let mut mid_id = vec![u32::MAX; ne];
        for e in 0..ne {
            if !marked[e] {
                continue;
            }
            let key = edges.keys[e];
            let (uv, s) = st.mids.remove(&key).unwrap_or_else(|| {
                let (a, b) = edge_ends(key);
                let uv = st.dom.edge_mid(st.uv[a as usize], st.uv[b as usize]);
                (uv, sample(surface, uv))
            });
            let id = st.push(uv, s);
            mid_id[e] = id;
            let level = st.level(key) + 1;
            let (a, b) = edge_ends(key);
            st.levels.remove(&key);
            st.set_level(a, id, level);
            st.set_level(id, b, level);
        }
        // Split triangles in order: first child in place, the others appended.
        let count = st.tris.len();
        st.tris.reserve(added as usize);
        for t in 0..count {
            let tri = st.tris[t];
            let te = edges.of_tri[t];
            let mk = te.map(|e| marked[e as usize]);
            let m = mk.iter().filter(|&&x| x).count();
            match m {
                0 => {}
                1 => {
                    let k = mk.iter().position(|&x| x).unwrap_or(0);
                    let (a, b, c) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                    let mid = mid_id[te[k] as usize];
                    // the split edge's key is gone; its halves carry level + 1
                    let level = st.level(edge_key(a, mid));
                    st.tris[t] = [a, mid, c];
                    st.tris.push([mid, b, c]);
                    st.set_level(mid, c, level);
                }
                3 => {
                    let [m0, m1, m2] = te.map(|e| mid_id[e as usize]);
                    let level = [
                        edge_key(tri[0], m0),
                        edge_key(tri[1], m1),
                        edge_key(tri[2], m2),
                    ]
                    .iter()
                    .map(|k| st.level(*k))
                    .max()
                    .unwrap_or(0);
                    st.tris[t] = [tri[0], m0, m2];
                    st.tris.push([m0, tri[1], m1]);
                    st.tris.push([m2, m1, tri[2]]);
                    st.tris.push([m0, m1, m2]);
                    st.set_level(m0, m1, level);
                    st.set_level(m1, m2, level);
                    st.set_level(m2, m0, level);
                }
                _ => {
                    // Unmarked local edge u = (c, a); marked (a, b) and (b, c).
                    let u = mk.iter().position(|&x| !x).unwrap_or(0);
                    let (c, a, b) = (tri[u], tri[(u + 1) % 3], tri[(u + 2) % 3]);
                    let (e_ab, e_bc) = (te[(u + 1) % 3] as usize, te[(u + 2) % 3] as usize);
                    let (m1, m2) = (mid_id[e_ab], mid_id[e_bc]);
                    let level = st.level(edge_key(a, m1)).max(st.level(edge_key(b, m2)));
                    st.tris[t] = [m1, b, m2];
                    match options.two_edge {
                        TwoEdgeSplit::LongerEdge => {
                            let lab = (st.pos[a as usize] - st.pos[b as usize]).length();
                            let lbc = (st.pos[b as usize] - st.pos[c as usize]).length();
                            let ab_longer =
                                lab > lbc || (lab == lbc && edges.keys[e_ab] < edges.keys[e_bc]);
                            if ab_longer {
                                st.tris.push([a, m1, c]);
                                st.tris.push([m1, m2, c]);
                                st.set_level(m1, c, level);
                            } else {
                                st.tris.push([a, m1, m2]);
                                st.tris.push([a, m2, c]);
                                st.set_level(a, m2, level);
                            }
                            st.set_level(m1, m2, level);
                        }
                        TwoEdgeSplit::Centre => {
                            let mut quad = [
                                st.uv[a as usize],
                                st.uv[m1 as usize],
                                st.uv[m2 as usize],
                                st.uv[c as usize],
                            ];
                            st.dom.unwrap(&mut quad);
                            let centre =
                                st.dom.wrap((quad[0] + quad[1] + quad[2] + quad[3]) * 0.25);
                            let q = st.push(centre, sample(surface, centre));
                            st.tris.push([a, m1, q]);
                            st.tris.push([m1, m2, q]);
                            st.tris.push([m2, c, q]);
                            st.tris.push([c, a, q]);
                            for (x, y) in [(m1, m2), (a, q), (m1, q), (m2, q), (c, q)] {
                                st.set_level(x, y, level);
                            }
                        }
                    }
                }
            }
        }
        for (t, tri) in flips {
            st.tris[t] = tri;
        }
    }
    let mesh = TriMesh {
        positions: st.pos.iter().map(|p| p.to_array()).collect(),
        uvs: st.uv.iter().map(|p| p.to_array()).collect(),
        normals: st.nrm.iter().map(|p| p.to_array()).collect(),
        triangles: st.tris,
    };
    Ok(Tessellation {
        mesh,
        stats: TessStats {
            max_level: st.max_level_reached,
            rounds,
            patch_levels: initial.stats.patch_levels,
            border_levels: initial.stats.border_levels,
            ..TessStats::default()
        },
    })
}

/// One flip pass (see [`AdaptiveOptions::flips`]): returns the triangles to replace after the
/// split step (flipped triangles have no marked edge left, so the split step skips them).
fn flip_pass(
    st: &mut State,
    edges: &Edges,
    marked: &mut [bool],
    pinned: &[Option<bool>],
    eps: f64,
    surface: &NurbsSurface,
) -> Vec<(usize, [u32; 3])> {
    let mut out = Vec::new();
    let mut touched: FxHashMap<u32, ()> = FxHashMap::default();
    let mut new_edges: FxHashMap<u64, ()> = FxHashMap::default();
    for e in 0..edges.keys.len() {
        if !marked[e] || edges.tris[e][1] == u32::MAX || pinned[e].is_some() {
            continue;
        }
        let (c0, c1) = (edges.tris[e][0], edges.tris[e][1]);
        let (t0, t1) = ((c0 / 3) as usize, (c1 / 3) as usize);
        if t0 == t1 || touched.contains_key(&(t0 as u32)) || touched.contains_key(&(t1 as u32)) {
            continue;
        }
        // The flipped edge must be the only marked edge of both triangles.
        let others_marked = edges.of_tri[t0]
            .iter()
            .chain(&edges.of_tri[t1])
            .any(|&x| x as usize != e && marked[x as usize]);
        if others_marked {
            continue;
        }
        let k0 = (c0 % 3) as usize;
        let tri0 = st.tris[t0];
        let (a, b, c) = (tri0[k0], tri0[(k0 + 1) % 3], tri0[(k0 + 2) % 3]);
        let tri1 = st.tris[t1];
        let k1 = (c1 % 3) as usize;
        let d = tri1[(k1 + 2) % 3];
        if tri1[k1] != b || tri1[(k1 + 1) % 3] != a || c == d {
            continue; // inconsistent orientation: never flip
        }
        let key = edge_key(c, d);
        if edges.keys.binary_search(&key).is_ok() || new_edges.contains_key(&key) {
            continue;
        }
        let uv = |v: u32| st.uv[v as usize];
        if [a, b, c, d].iter().any(|&v| st.dom.free(uv(v)).is_some()) {
            continue;
        }
        // Both new triangles (a, d, c) and (d, b, c) counter-clockwise in (u, v).
        let mut q = [uv(a), uv(d), uv(b), uv(c)];
        st.dom.unwrap(&mut q);
        let ccw = |p: DVec2, r: DVec2, s: DVec2| (r - p).perp_dot(s - p) > 0.0;
        if !(ccw(q[0], q[1], q[3]) && ccw(q[1], q[2], q[3])) {
            continue;
        }
        let p = |v: u32| st.pos[v as usize];
        let mid_uv = st.dom.edge_mid(uv(c), uv(d));
        let mid = sample(surface, mid_uv);
        if (mid.p - (p(c) + p(d)) * 0.5).length() > eps {
            continue;
        }
        let centroid_ok = |x: u32, y: u32, z: u32| {
            let cuv = st.dom.centroid(uv(x), uv(y), uv(z));
            (surface.eval_point(cuv.x, cuv.y) - (p(x) + p(y) + p(z)) / 3.0).length() <= eps
        };
        if !(centroid_ok(a, d, c) && centroid_ok(d, b, c)) {
            continue;
        }
        marked[e] = false;
        touched.insert(t0 as u32, ());
        touched.insert(t1 as u32, ());
        new_edges.insert(key, ());
        let level = st.level(edges.keys[e]);
        st.levels.remove(&edges.keys[e]);
        if level > 0 {
            st.levels.insert(key, level);
        }
        st.mids.insert(key, (mid_uv, mid));
        out.push((t0, [a, d, c]));
        out.push((t1, [d, b, c]));
    }
    out
}
