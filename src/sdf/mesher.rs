//! Meshing driver: grid set-up, limits, block culling, parallel block
//! processing and deterministic assembly, shared by both meshers.
//!
//! Blocks are processed in parallel (rayon) and their results put back in
//! block order (z, y, x) before anything order-dependent happens: vertex ids
//! come from each block's owned grid edges (marching cubes) or cells (dual
//! contouring), in index order, offset by a prefix sum over the blocks. The
//! output is therefore byte-identical at any thread count.

use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;

use crate::geom::sink::{Begin, MeshSink, SinkError};
use crate::sdf::aabb::Aabb;
use crate::sdf::error::{Result, SdfError};
use crate::sdf::grid::{live_blocks, Field, Grid, MeshOptions, Mesher};
use crate::sdf::table::inside;

/// A neutral indexed triangle mesh with its statistics.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshOutput {
    pub positions: Vec<[f64; 3]>,
    /// Counter-clockwise seen from outside (normals point to f > 0).
    pub triangles: Vec<[u32; 3]>,
    pub stats: MeshStats,
    /// Only when [`MeshOptions::timings`]; never compare it.
    pub timings: Option<Timings>,
}

impl MeshOutput {
    /// Hands the triangles to `sink` (the kernel's builder, or an
    /// `IndexedMesh` for the writers), ending it; an error aborts it.
    pub fn emit(&self, sink: &mut dyn MeshSink) -> std::result::Result<(), SinkError> {
        let run = |sink: &mut dyn MeshSink| {
            sink.begin(&Begin {
                vertices: self.positions.len(),
                polygons: self.triangles.len(),
                ..Begin::default()
            })?;
            for p in &self.positions {
                sink.vertex(DVec3::from_array(*p), &[])?;
            }
            for t in &self.triangles {
                sink.polygon(t)?;
            }
            sink.end()
        };
        run(sink).inspect_err(|_| sink.abort())
    }
}

/// Deterministic statistics of one meshing run.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MeshStats {
    /// Cells per axis.
    pub grid: [usize; 3],
    pub cell_size: [f64; 3],
    pub grid_cells: u64,
    /// Cells in live sub-blocks (their corners were evaluated).
    pub cells_evaluated: u64,
    pub blocks: u64,
    pub blocks_culled: u64,
    pub subblocks_culled: u64,
    /// Every field evaluation: culling centres, samples, vertex refinement,
    /// the max-|f| check, dual-contouring gradients.
    pub field_evaluations: u64,
    pub triangles: u64,
    pub vertices: u64,
    /// max |f| over the output vertices.
    pub max_abs_f_at_vertices: f64,
    /// Triangles whose computed area is exactly 0 (0 for marching cubes by
    /// construction; see DESIGN.md for dual contouring).
    pub zero_area_triangles: u64,
    /// Dual contouring: quads kept as fans around their edge vertex because
    /// a flip would have made an edge non-manifold.
    pub dc_fan_quads: u64,
}

/// Wall-clock measurements (only on request; sums over threads).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Timings {
    pub total: Duration,
    /// Sum over threads of time inside field evaluation.
    pub field: Duration,
    /// Sum over threads of meshing time outside field evaluation.
    pub mesh: Duration,
}

/// Meshes `field` (a compiled [`Tape`](crate::sdf::tape::Tape), a skin
/// field, …) with the options. The output is closed, 2-manifold and
/// outward-oriented (marching cubes: always; dual contouring: see
/// [`crate::sdf::dc`]).
pub fn mesh(field: &dyn Field, opts: &MeshOptions) -> Result<MeshOutput> {
    // +∞ is allowed: a field without a usable bound is evaluated everywhere.
    let l = field.lipschitz();
    if l.is_nan() || l <= 0.0 {
        return Err(SdfError::InvalidOption {
            field: "field",
            reason: format!("Lipschitz constant {l}"),
        });
    }
    let grid = Grid::new(field.bounds(), opts)?;
    if opts.threads > 0 {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(opts.threads)
            .build()
            .map_err(|e| SdfError::InvalidOption {
                field: "threads",
                reason: e.to_string(),
            })?;
        pool.install(|| run(field, &grid, opts))
    } else {
        run(field, &grid, opts)
    }
}

fn run(field: &dyn Field, grid: &Grid, opts: &MeshOptions) -> Result<MeshOutput> {
    let t0 = Instant::now();
    let (live, culled, evals) = live_blocks(grid, field);
    opts.progress.add_total(live.len());
    let nb = grid.blocks();
    let mut out = match opts.mesher {
        Mesher::MarchingCubes => crate::sdf::mc::mesh_blocks(field, grid, opts, &live)?,
        Mesher::DualContouring => crate::sdf::dc::mesh_blocks(field, grid, opts, &live)?,
    };
    out.stats.grid = grid.n;
    out.stats.cell_size = grid.h;
    out.stats.grid_cells = grid.cells();
    out.stats.blocks = (nb[0] * nb[1] * nb[2]) as u64;
    out.stats.blocks_culled = culled;
    out.stats.field_evaluations += evals;
    out.stats.triangles = out.triangles.len() as u64;
    out.stats.vertices = out.positions.len() as u64;
    out.stats.zero_area_triangles = count_zero_area(&out.positions, &out.triangles);
    if let Some(t) = out.timings.as_mut() {
        t.total = t0.elapsed();
    }
    if !opts.timings {
        out.timings = None;
    }
    Ok(out)
}

/// Triangles whose cross product is exactly zero.
pub fn count_zero_area(p: &[[f64; 3]], t: &[[u32; 3]]) -> u64 {
    t.par_iter()
        .filter(|tri| {
            let a = DVec3::from_array(p[tri[0] as usize]);
            let b = DVec3::from_array(p[tri[1] as usize]);
            let c = DVec3::from_array(p[tri[2] as usize]);
            (b - a).cross(c - a).length_squared() == 0.0
        })
        .count() as u64
}

/// Time spent in a closure, when timing is on.
#[inline]
pub fn timed<T>(on: bool, acc: &mut Duration, f: impl FnOnce() -> T) -> T {
    if on {
        let t = Instant::now();
        let r = f();
        *acc += t.elapsed();
        r
    } else {
        f()
    }
}

/// How close (as a fraction of the edge) a vertex may come to a grid
/// sample: τ = 2⁻¹⁰. A surface through (or very near) a sample would put
/// the vertices of up to six edges on one point (spec §0.9): kept τ·h off
/// it, no triangle has zero area and no two vertices are closer than
/// √2·τ·h (1.4·10⁻³ of a cell), so the close-vertex gate of `info` and an
/// artist's merge-by-distance find nothing to merge. The cost is a vertex
/// moved by at most τ·h along its edge, far below the interpolation error.
pub const EDGE_MARGIN: f64 = 1.0 / 1024.0;

/// Position of the crossing on a grid edge with end values f0 ≤ 0 < f1 (or
/// the reverse; zero is inside, [`crate::sdf::table::inside`]): parameter
/// from the lower end, kept inside [τ, 1 − τ] ([`EDGE_MARGIN`]). An end
/// exactly 0 gives t = 0 or 1 (the vertex at that sample, as scikit-image
/// puts it), moved τ into the edge; f0 − f1 is never 0 on a crossed edge,
/// and a NaN (two infinities) gives the midpoint.
#[inline]
pub fn edge_t(f0: f64, f1: f64) -> f64 {
    const TAU: f64 = EDGE_MARGIN;
    let t = f0 / (f0 - f1);
    if t.is_nan() {
        0.5
    } else {
        t.clamp(TAU, 1.0 - TAU)
    }
}

/// Region box of a set of points (for region-aware fields).
pub fn region_of(ps: &[[f64; 3]]) -> Aabb {
    Aabb::of_points(ps.iter().map(|p| DVec3::from_array(*p)))
}

/// Bracketed root refinement on segments a → b (Illinois regula falsi,
/// bisecting after three retentions of one side): `ts` holds the start
/// parameters and receives the refined ones. `fa`, `fb` are the end values
/// (on opposite sides in the f ≤ 0 sense). Returns the evaluations spent.
#[allow(clippy::too_many_arguments)]
pub fn refine_roots(
    ev: &mut dyn crate::sdf::grid::FieldEval,
    region: &Aabb,
    a: &[DVec3],
    b: &[DVec3],
    fa: &[f64],
    fb: &[f64],
    steps: u32,
    ts: &mut [f64],
) -> u64 {
    const TAU: f64 = EDGE_MARGIN;
    let n = ts.len();
    let mut lo = vec![0.0f64; n];
    let mut hi = vec![1.0f64; n];
    let mut flo = fa.to_vec();
    let mut fhi = fb.to_vec();
    let mut side = vec![0i8; n];
    let (mut xs, mut ys, mut zs, mut fs) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for _ in 0..steps {
        for i in 0..n {
            let q = a[i] + (b[i] - a[i]) * ts[i];
            xs[i] = q.x;
            ys[i] = q.y;
            zs[i] = q.z;
        }
        ev.eval(region, &xs, &ys, &zs, &mut fs);
        for i in 0..n {
            let f = fs[i];
            if f.is_nan() {
                continue;
            }
            if inside(f) == inside(flo[i]) {
                lo[i] = ts[i];
                flo[i] = f;
                if side[i] < 0 {
                    fhi[i] *= 0.5;
                }
                side[i] = if side[i] < 0 { side[i] - 1 } else { -1 };
            } else {
                hi[i] = ts[i];
                fhi[i] = f;
                if side[i] > 0 {
                    flo[i] *= 0.5;
                }
                side[i] = if side[i] > 0 { side[i] + 1 } else { 1 };
            }
            let t = if side[i].abs() >= 3 {
                side[i] = 0;
                0.5 * (lo[i] + hi[i])
            } else {
                lo[i] + (hi[i] - lo[i]) * edge_t(flo[i], fhi[i])
            };
            ts[i] = t.clamp(TAU, 1.0 - TAU);
        }
    }
    (n as u64) * steps as u64
}

/// max |f| over `positions`, evaluated in chunks (small chunks with their
/// own regions when the field wants regions). Returns (max, evaluations).
pub fn max_abs_at(ev: &mut dyn crate::sdf::grid::FieldEval, positions: &[[f64; 3]]) -> (f64, u64) {
    let chunk = if ev.wants_regions() { 16 } else { 4096 };
    let mut m = 0.0f64;
    let (mut xs, mut ys, mut zs, mut fs) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for ch in positions.chunks(chunk) {
        xs.clear();
        ys.clear();
        zs.clear();
        xs.extend(ch.iter().map(|p| p[0]));
        ys.extend(ch.iter().map(|p| p[1]));
        zs.extend(ch.iter().map(|p| p[2]));
        fs.clear();
        fs.resize(ch.len(), 0.0);
        ev.eval(&region_of(ch), &xs, &ys, &zs, &mut fs);
        m = fs.iter().fold(m, |a, f| a.max(f.abs()));
    }
    (m, positions.len() as u64)
}
