//! Uniform tessellation (thesis §2.1, Figs 2.1–2.2; spec §2.4).
//!
//! One tensor grid of parameters, either n cells over the whole domain or n cells per knot span
//! (= per Bézier patch, the same grid the per-patch scheme gives, with border samples shared).
//! Cell (i, j) with corners a = (i, j), b = (i+1, j), c = (i+1, j+1), d = (i, j+1) becomes
//! (a, b, c) and (a, c, d) (or (a, b, d) and (b, c, d) where [`Diagonal::Best`] finds that
//! diagonal closer to the surface at the cell centre). The grid is evaluated once with basis tables (D9).
//!
//! Seams: column n of a closed direction is column 0. Poles: every sample on a collapsed border
//! is one vertex, and the triangles that collapse are dropped. Both are decided by
//! [`Layout::key`], which the exact count ([`predict_uniform`]) and the build share.

use super::super::error::Dir;
use super::super::mesh::TriMesh;
use super::super::surface::NurbsSurface;
use super::{Diagonal, TessError, TessStats, Tessellation};

/// Which sample a grid index maps to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Key {
    Grid(usize, usize),
    Pole(usize),
}

/// Grid size, seams and poles of a uniform tessellation.
pub(crate) struct Layout {
    pub cu: usize,
    pub cv: usize,
    closed: [bool; 2],
    /// Pole group per border [u_min, u_max, v_min, v_max] (borders sharing a corner and both
    /// collapsed are one point), or None.
    pole_group: [Option<usize>; 4],
    /// [`Layout::is_plain`], decided once: the cells are visited per triangle.
    plain: bool,
}

impl Layout {
    pub fn new(cu: usize, cv: usize, closed: [bool; 2], poles: [bool; 4]) -> Self {
        // Union of collapsed borders that meet at a corner (u border k, v border 2 + l).
        let mut group = [0usize, 1, 2, 3];
        fn find(g: &mut [usize; 4], mut x: usize) -> usize {
            while g[x] != x {
                x = g[x];
            }
            x
        }
        for k in 0..2 {
            for l in 2..4 {
                if poles[k] && poles[l] {
                    let (a, b) = (find(&mut group, k), find(&mut group, l));
                    group[a.max(b)] = a.min(b);
                }
            }
        }
        // A closed direction makes its two borders one curve.
        if closed[0] && poles[0] && poles[1] {
            let (a, b) = (find(&mut group, 0), find(&mut group, 1));
            group[a.max(b)] = a.min(b);
        }
        if closed[1] && poles[2] && poles[3] {
            let (a, b) = (find(&mut group, 2), find(&mut group, 3));
            group[a.max(b)] = a.min(b);
        }
        let mut pole_group = [None; 4];
        for k in 0..4 {
            if poles[k] {
                pole_group[k] = Some(find(&mut group, k));
            }
        }
        let mut layout = Layout {
            cu,
            cv,
            closed,
            pole_group,
            plain: false,
        };
        layout.plain = layout.is_plain();
        layout
    }

    fn key(&self, i: usize, j: usize) -> Key {
        let i = if self.closed[0] && i == self.cu { 0 } else { i };
        let j = if self.closed[1] && j == self.cv { 0 } else { j };
        let borders = [i == 0, i == self.cu, j == 0, j == self.cv];
        for (on, group) in borders.iter().zip(&self.pole_group) {
            if let (true, Some(g)) = (on, group) {
                return Key::Pole(*g);
            }
        }
        Key::Grid(i, j)
    }

    /// Neither seams nor poles: every grid sample is its own vertex and no cell collapses.
    fn is_plain(&self) -> bool {
        !self.closed[0] && !self.closed[1] && self.pole_group.iter().all(Option::is_none)
    }

    /// The two triangles of cell (i, j) as grid corners; `None` where they collapse.
    fn cell(&self, i: usize, j: usize) -> [Option<[(usize, usize); 3]>; 2] {
        let (a, b, c, d) = ((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1));
        if self.plain {
            // Four distinct samples, four distinct keys: nothing to look up.
            return [Some([a, b, c]), Some([a, c, d])];
        }
        let keep = |t: [(usize, usize); 3]| {
            let k = t.map(|(x, y)| self.key(x, y));
            if k[0] == k[1] || k[1] == k[2] || k[0] == k[2] {
                None
            } else {
                Some(t)
            }
        };
        [keep([a, b, c]), keep([a, c, d])]
    }

    /// Exact triangle count. Only cells on the first or last row or column can collapse, so this
    /// costs O(cu + cv).
    pub fn triangle_count(&self) -> u128 {
        let (cu, cv) = (self.cu, self.cv);
        let full = 2 * cu as u128 * cv as u128;
        if self.pole_group.iter().all(Option::is_none) {
            return full;
        }
        let mut lost = 0u128;
        let mut visit = |i: usize, j: usize| {
            for t in self.cell(i, j) {
                if t.is_none() {
                    lost += 1;
                }
            }
        };
        // Border cells, each once.
        for i in 0..cu {
            visit(i, 0);
            if cv > 1 {
                visit(i, cv - 1);
            }
        }
        for j in 1..cv.saturating_sub(1) {
            visit(0, j);
            if cu > 1 {
                visit(cu - 1, j);
            }
        }
        full - lost
    }
}

/// Sample parameters in one direction: `cells` cells over the domain, or per knot span.
fn params(surface: &NurbsSurface, dir: Dir, cells: usize, per_patch: bool) -> Vec<f64> {
    let b = surface.breakpoints(dir);
    if !per_patch {
        let (lo, hi) = (b[0], b[b.len() - 1]);
        return (0..=cells)
            .map(|k| {
                if k == cells {
                    hi
                } else {
                    lo + (hi - lo) * (k as f64 / cells as f64)
                }
            })
            .collect();
    }
    let mut out = Vec::with_capacity((b.len() - 1) * cells + 1);
    for w in b.windows(2) {
        for k in 0..cells {
            out.push(w[0] + (w[1] - w[0]) * (k as f64 / cells as f64));
        }
    }
    out.push(b[b.len() - 1]);
    out
}

/// Cells per direction after applying the closed-direction minimum of 3.
pub(crate) fn cell_counts(
    surface: &NurbsSurface,
    cells: [usize; 2],
    per_patch: bool,
) -> [usize; 2] {
    let t = surface.topology();
    let spans = [
        surface.breakpoints(Dir::U).len() - 1,
        surface.breakpoints(Dir::V).len() - 1,
    ];
    let mut out = [0; 2];
    for d in 0..2 {
        let n = if per_patch {
            cells[d].saturating_mul(spans[d])
        } else {
            cells[d]
        };
        let closed = if d == 0 { t.closed_u } else { t.closed_v };
        // Both borders of the other parameter collapsed (a sphere's poles): one cell row would
        // collapse entirely, so at least 2 cells.
        let both_poles = if d == 0 {
            t.poles[0] && t.poles[1]
        } else {
            t.poles[2] && t.poles[3]
        };
        let n = if both_poles && n < 2 {
            if per_patch {
                cells[d].max(2usize.div_ceil(spans[d])) * spans[d]
            } else {
                2
            }
        } else {
            n
        };
        out[d] = if closed && n < 3 {
            // Fewer than 3 cells around a closed direction would put four triangles on one
            // edge; raise the per-direction count (per patch: per span) until there are 3.
            if per_patch {
                cells[d].max(3usize.div_ceil(spans[d])) * spans[d]
            } else {
                3
            }
        } else {
            n
        };
    }
    out
}

/// Exact (vertex bound, triangle count) of a uniform tessellation, computed without allocating
/// the mesh.
pub fn predict_uniform(
    surface: &NurbsSurface,
    cells: [usize; 2],
    per_patch: bool,
) -> Result<(u128, u128), TessError> {
    for (d, &c) in cells.iter().enumerate() {
        if c == 0 {
            return Err(TessError::InvalidOption {
                name: if d == 0 { "cells_u" } else { "cells_v" },
                value: 0.0,
                reason: "must be at least 1",
            });
        }
    }
    let [cu, cv] = cell_counts(surface, cells, per_patch);
    let t = surface.topology();
    let layout = Layout::new(cu, cv, [t.closed_u, t.closed_v], t.poles);
    let vertices = (cu as u128 + 1) * (cv as u128 + 1);
    Ok((vertices, layout.triangle_count()))
}

/// What a uniform tessellation fixes before sampling: cell counts, sample parameters, layout
/// and the exact triangle count, checked against the caps.
struct Plan {
    cu: usize,
    cv: usize,
    us: Vec<f64>,
    vs: Vec<f64>,
    layout: Layout,
    triangles: u128,
}

fn plan(
    surface: &NurbsSurface,
    cells: [usize; 2],
    per_patch: bool,
    max_triangles: usize,
) -> Result<Plan, TessError> {
    let (vertices, triangles) = predict_uniform(surface, cells, per_patch)?;
    if triangles > max_triangles as u128 {
        return Err(TessError::TriangleLimit {
            needed: triangles,
            limit: max_triangles,
        });
    }
    if vertices > u32::MAX as u128 {
        return Err(TessError::VertexLimit { needed: vertices });
    }
    let [cu, cv] = cell_counts(surface, cells, per_patch);
    let per = |d: Dir, n: usize, total: usize| {
        if per_patch {
            let spans = surface.breakpoints(d).len() - 1;
            params(surface, d, total / spans.max(1), true)
        } else {
            params(surface, d, n, false)
        }
    };
    let top = surface.topology();
    Ok(Plan {
        cu,
        cv,
        us: per(Dir::U, cu, cu),
        vs: per(Dir::V, cv, cv),
        layout: Layout::new(cu, cv, [top.closed_u, top.closed_v], top.poles),
        triangles,
    })
}

/// A uniform tessellation with fixed diagonals whose grid has no seam and no pole, kept as the
/// grid: vertex (i, j) is sample i·n_v + j, and cell (i, j), with corners a = (i, j),
/// b = (i+1, j), c = (i+1, j+1), d = (i, j+1), is (a, b, c) and (a, c, d). It is the mesh
/// [`super::tessellate`] gives, without its normals and triangle list: a caller that builds its
/// own mesh from the grid in closed form needs neither, and at 1000² they are 48 MB written
/// for nothing (issue 38).
#[derive(Debug, Clone, PartialEq)]
pub struct UniformGrid {
    /// S(u_i, v_j) in vertex order.
    pub positions: Vec<[f64; 3]>,
    /// The samples' parameters: vertex (i, j) lies at (us[i], vs[j]).
    pub us: Vec<f64>,
    pub vs: Vec<f64>,
    /// As [`super::tessellate`] reports them.
    pub stats: TessStats,
}

impl UniformGrid {
    /// The triangles of [`super::tessellate`]'s mesh, cell by cell.
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let nv = self.vs.len() as u32;
        let (cu, cv) = (self.us.len() as u32 - 1, nv - 1);
        (0..cu)
            .flat_map(|i| (0..cv).map(move |j| i * nv + j))
            .flat_map(|a| [[a, a + nv, a + nv + 1], [a, a + nv + 1, a + 1]])
            .collect()
    }

    /// The (u, v) of every vertex.
    pub fn uvs(&self) -> Vec<[f64; 2]> {
        grid_uvs(&self.us, &self.vs)
    }
}

/// The (u, v) of every sample of the grid `us × vs`, in vertex order.
fn grid_uvs(us: &[f64], vs: &[f64]) -> Vec<[f64; 2]> {
    us.iter()
        .flat_map(|&u| vs.iter().map(move |&v| [u, v]))
        .collect()
}

/// [`Mode::Uniform`](super::Mode::Uniform) with [`Diagonal::Fixed`] as its grid
/// ([`UniformGrid`]); `None` when the grid has a seam or a pole ([`super::tessellate`] then).
/// The errors are `tessellate`'s.
pub fn uniform_grid(
    surface: &NurbsSurface,
    cells: [usize; 2],
    per_patch: bool,
    max_triangles: usize,
) -> Result<Option<UniformGrid>, TessError> {
    let plan = plan(surface, cells, per_patch, max_triangles)?;
    if !plan.layout.plain {
        return Ok(None);
    }
    let (us, vs) = (plan.us, plan.vs);
    let positions = surface.grid(&us, &vs, false)?.points;
    let max_deviation = grid_deviation(surface, &plan.layout, (&us, &vs), (&positions, None), &[])?;
    let stats = TessStats {
        triangles: plan.triangles as usize,
        vertices: positions.len(),
        max_deviation,
        patch_levels: vec![[plan.cu as u32, plan.cv as u32]],
        ..TessStats::default()
    };
    Ok(Some(UniformGrid {
        positions,
        us,
        vs,
        stats,
    }))
}

pub(crate) fn uniform(
    surface: &NurbsSurface,
    cells: [usize; 2],
    per_patch: bool,
    diagonal: Diagonal,
    max_triangles: usize,
) -> Result<Tessellation, TessError> {
    let Plan {
        cu,
        cv,
        us,
        vs,
        layout,
        triangles,
    } = plan(surface, cells, per_patch, max_triangles)?;
    let grid = surface.grid(&us, &vs, true)?;
    let nv = vs.len();
    let (mut mesh, ids) = if layout.plain {
        // Every grid sample is its own vertex, in grid order: the samples become the mesh.
        let mesh = TriMesh {
            positions: grid.points,
            normals: grid.normals,
            uvs: grid_uvs(&us, &vs),
            triangles: Vec::new(),
        };
        (mesh, (0..(us.len() * nv) as u32).collect())
    } else {
        welded_vertices(&layout, &grid, &us, &vs)
    };
    mesh.triangles.reserve(triangles as usize);
    // Diagonal per cell: (a, c) unless `Best` finds (b, d) closer to the surface at the cell
    // centre. Only cells whose four corners are distinct vertices may flip, so the count is the
    // predicted one.
    let mid = |a: &[f64]| -> Vec<f64> { a.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect() };
    let mut flip = vec![false; cu * cv];
    if diagonal == Diagonal::Best {
        let centres = surface.grid(&mid(&us), &mid(&vs), false)?;
        for i in 0..cu {
            for j in 0..cv {
                let id = |x: usize, y: usize| ids[x * nv + y];
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                let distinct = a != b && a != c && a != d && b != c && b != d && c != d;
                let p = |v: u32| glam::DVec3::from_array(mesh.positions[v as usize]);
                let s = glam::DVec3::from_array(centres.points[i * cv + j]);
                flip[i * cv + j] = distinct
                    && (s - (p(b) + p(d)) * 0.5).length() < (s - (p(a) + p(c)) * 0.5).length();
            }
        }
    }
    for i in 0..cu {
        for j in 0..cv {
            if flip[i * cv + j] {
                let id = |x: usize, y: usize| ids[x * nv + y];
                mesh.triangles.push([id(i, j), id(i + 1, j), id(i, j + 1)]);
                mesh.triangles
                    .push([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
                continue;
            }
            for t in layout.cell(i, j).into_iter().flatten() {
                mesh.triangles.push(t.map(|(x, y)| ids[x * nv + y]));
            }
        }
    }
    debug_assert_eq!(mesh.triangles.len() as u128, triangles);
    let max_deviation = grid_deviation(
        surface,
        &layout,
        (&us, &vs),
        (&mesh.positions, Some(&ids)),
        &flip,
    )?;
    Ok(Tessellation {
        mesh,
        stats: TessStats {
            patch_levels: vec![[cu as u32, cv as u32]],
            max_deviation,
            ..TessStats::default()
        },
    })
}

/// The deviation of spec §2.5 item 4 for a grid mesh: triangle centroids and edge midpoints
/// form five tensor grids (two centroid grids, u-edges, v-edges, diagonals; two more centroid
/// grids where `Best` flipped a cell), each evaluated with basis tables, so this costs about
/// five grid evaluations instead of one point-by-point evaluation per sample. Each grid is
/// taken row by row ([`NurbsSurface::grid_rows_max`]) and never stored.
///
/// `ids` maps grid samples to vertices of `positions` (`None`: sample k is vertex k); `flip`
/// marks the cells `Best` flipped (empty: none).
fn grid_deviation(
    surface: &NurbsSurface,
    layout: &Layout,
    (us, vs): (&[f64], &[f64]),
    (positions, ids): (&[[f64; 3]], Option<&[u32]>),
    flip: &[bool],
) -> Result<f64, TessError> {
    use glam::DVec3;
    let (cv, nv) = (layout.cv, vs.len());
    let pos = |i: usize, j: usize| {
        let k = i * nv + j;
        DVec3::from_array(positions[ids.map_or(k, |ids| ids[k] as usize)])
    };
    let any_flip = flip.iter().any(|&f| f);
    let flip = |i: usize, j: usize| any_flip && flip[i * cv + j];
    let mix = |a: &[f64], wa: f64, wb: f64| -> Vec<f64> {
        a.windows(2)
            .map(|w| (w[0] * wa + w[1] * wb) / (wa + wb))
            .collect()
    };
    let (u_mid, v_mid) = (mix(us, 1.0, 1.0), mix(vs, 1.0, 1.0));
    let far = |s: &[f64; 3], chord: DVec3| (DVec3::from_array(*s) - chord).length();
    // Centroids of (a, b, c) and (a, c, d), or of (a, b, d) and (b, c, d) in flipped cells, as
    // `corners` picks them from the cell's (a, b, c, d); `None` where the cell has no such
    // triangle.
    type Corners<'a> = &'a (dyn Fn(usize, usize) -> Option<[DVec3; 3]> + Sync);
    let centroids = |u: Vec<f64>, v: Vec<f64>, corners: Corners| {
        surface.grid_rows_max(&u, &v, |i, row| {
            (0..cv)
                .filter_map(|j| corners(i, j).map(|[x, y, z]| far(&row[j], (x + y + z) / 3.0)))
                .fold(0.0, f64::max)
        })
    };
    let quad = |i: usize, j: usize| (pos(i, j), pos(i + 1, j), pos(i + 1, j + 1), pos(i, j + 1));
    let mut worst = centroids(mix(us, 1.0, 2.0), mix(vs, 2.0, 1.0), &|i, j| {
        let (a, b, c, _) = quad(i, j);
        (!flip(i, j) && layout.cell(i, j)[0].is_some()).then_some([a, b, c])
    })?;
    worst = worst.max(centroids(mix(us, 2.0, 1.0), mix(vs, 1.0, 2.0), &|i, j| {
        let (a, _, c, d) = quad(i, j);
        (!flip(i, j) && layout.cell(i, j)[1].is_some()).then_some([a, c, d])
    })?);
    if any_flip {
        worst = worst.max(centroids(mix(us, 2.0, 1.0), mix(vs, 2.0, 1.0), &|i, j| {
            let (a, b, _, d) = quad(i, j);
            flip(i, j).then_some([a, b, d])
        })?);
        worst = worst.max(centroids(mix(us, 1.0, 2.0), mix(vs, 1.0, 2.0), &|i, j| {
            let (_, b, c, d) = quad(i, j);
            flip(i, j).then_some([b, c, d])
        })?);
    }
    worst = worst.max(surface.grid_rows_max(&u_mid, vs, |i, row| {
        (0..=cv)
            .map(|j| far(&row[j], (pos(i, j) + pos(i + 1, j)) * 0.5))
            .fold(0.0, f64::max)
    })?);
    worst = worst.max(surface.grid_rows_max(us, &v_mid, |i, row| {
        (0..cv)
            .map(|j| far(&row[j], (pos(i, j) + pos(i, j + 1)) * 0.5))
            .fold(0.0, f64::max)
    })?);
    worst = worst.max(surface.grid_rows_max(&u_mid, &v_mid, |i, row| {
        (0..cv)
            .map(|j| {
                let chord = if flip(i, j) {
                    pos(i + 1, j) + pos(i, j + 1)
                } else {
                    pos(i, j) + pos(i + 1, j + 1)
                };
                far(&row[j], chord * 0.5)
            })
            .fold(0.0, f64::max)
    })?);
    Ok(worst)
}

/// Vertices of a grid with seams or poles: a seam column is its first column, every sample on a
/// collapsed border one vertex ([`Layout::key`]). Returns the mesh's vertices and the vertex of
/// every grid sample.
fn welded_vertices(
    layout: &Layout,
    grid: &super::super::surface::GridSamples,
    us: &[f64],
    vs: &[f64],
) -> (TriMesh, Vec<u32>) {
    let (cu, cv, nv) = (layout.cu, layout.cv, vs.len());
    let mut ids = vec![u32::MAX; us.len() * nv];
    let mut pole_ids = [u32::MAX; 4];
    let mut mesh = TriMesh::default();
    for i in 0..=cu {
        for j in 0..=cv {
            let id = match layout.key(i, j) {
                Key::Grid(gi, gj) => {
                    let slot = gi * nv + gj;
                    if ids[slot] == u32::MAX {
                        ids[slot] = mesh.positions.len() as u32;
                        push_vertex(&mut mesh, grid, us, vs, gi, gj, nv);
                    }
                    ids[slot]
                }
                Key::Pole(g) => {
                    if pole_ids[g] == u32::MAX {
                        pole_ids[g] = mesh.positions.len() as u32;
                        push_vertex(&mut mesh, grid, us, vs, i, j, nv);
                    }
                    pole_ids[g]
                }
            };
            ids[i * nv + j] = id;
        }
    }
    (mesh, ids)
}

fn push_vertex(
    mesh: &mut TriMesh,
    grid: &super::super::surface::GridSamples,
    us: &[f64],
    vs: &[f64],
    i: usize,
    j: usize,
    nv: usize,
) {
    mesh.positions.push(grid.points[i * nv + j]);
    mesh.normals.push(grid.normals[i * nv + j]);
    mesh.uvs.push([us[i], vs[j]]);
}
