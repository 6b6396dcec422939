//! Sparse block sampling of a field on a [`Grid`] (spec §1.8.6; see
//! [`super::grid`] for the conventions): blocks culled by the distance
//! bound at three levels, the samples of live children evaluated in
//! batches.

use glam::DVec3;

use crate::sdf::aabb::Aabb;
use crate::sdf::error::{Result, SdfError};
use crate::sdf::grid::{may_hold_surface, Field, FieldEval, Grid, BLOCK, BP, SUB};

/// Cells per child edge (the finest culling level).
pub const CHILD: usize = 2;

/// Value given to a border sample that is inside (f ≤ 0): the smallest
/// positive normal f64, outside under the meshers' rule (inside iff f ≤ 0,
/// [`crate::sdf::table::inside`]; a clamp to 0 would leave it inside and
/// the output open). Its crossings sit at the margin next to the border.
pub const BORDER_OUTSIDE: f64 = f64::MIN_POSITIVE;

/// Samples of one block: only the points of live children are valid.
pub struct BlockSamples {
    /// Block index per axis.
    pub b: [usize; 3],
    /// First cell of the block.
    pub c0: [usize; 3],
    /// Cells per axis in this block (≤ BLOCK at the grid's far end).
    pub nc: [usize; 3],
    /// Values at local points (lx + BP·(ly + BP·lz)); sanitised: NaN → +MAX,
    /// border samples clamped to > 0 ([`BORDER_OUTSIDE`]). Only `valid`
    /// entries are meaningful.
    pub v: Vec<f64>,
    /// Which local points were evaluated.
    pub valid: Vec<bool>,
    /// Bit s set for a live 4³ sub-block (s = sx + 4·(sy + 4·sz)).
    pub live: u64,
    /// Bit set for a live 2³ child (c = cx + 8·(cy + 8·cz)).
    pub live_cells: [u64; 8],
    pub subblocks: u32,
    pub children_culled: u32,
    pub field_evals: u64,
}

/// Reusable buffers for sampling a block.
pub struct SampleScratch {
    xs: Vec<f64>,
    ys: Vec<f64>,
    zs: Vec<f64>,
    out: Vec<f64>,
    idx: Vec<u32>,
    border: Vec<bool>,
    meta: Vec<(usize, f64, bool)>,
}

impl SampleScratch {
    pub fn new() -> Self {
        let n = BP * BP * BP;
        SampleScratch {
            xs: Vec::with_capacity(n),
            ys: Vec::with_capacity(n),
            zs: Vec::with_capacity(n),
            out: Vec::with_capacity(n),
            idx: Vec::with_capacity(n),
            border: Vec::with_capacity(n),
            meta: Vec::with_capacity(512),
        }
    }
}

impl Default for SampleScratch {
    fn default() -> Self {
        Self::new()
    }
}

/// Local point index in a block.
#[inline]
pub fn lidx(x: usize, y: usize, z: usize) -> usize {
    x + BP * (y + BP * z)
}

/// Samples block `b` into `out` (reused): culls 4³ sub-blocks, then 2³
/// children of the live ones, then evaluates the closed point ranges of
/// the live children.
pub fn sample_block(
    grid: &Grid,
    ev: &mut dyn FieldEval,
    l: f64,
    b: [usize; 3],
    s: &mut SampleScratch,
    out: &mut BlockSamples,
) {
    let c0 = [b[0] * BLOCK, b[1] * BLOCK, b[2] * BLOCK];
    let nc = [
        (grid.n[0] - c0[0]).min(BLOCK),
        (grid.n[1] - c0[1]).min(BLOCK),
        (grid.n[2] - c0[2]).min(BLOCK),
    ];
    out.b = b;
    out.c0 = c0;
    out.nc = nc;
    if out.v.len() != BP * BP * BP {
        out.v.resize(BP * BP * BP, f64::MAX);
    }
    out.valid.clear();
    out.valid.resize(BP * BP * BP, false);
    out.live = 0;
    out.live_cells = [0; 8];
    out.field_evals = 0;
    out.children_culled = 0;
    let region = grid.cell_box(c0, [c0[0] + nc[0], c0[1] + nc[1], c0[2] + nc[2]]);
    // Level 1: 4³ sub-blocks.
    let ns = [
        nc[0].div_ceil(SUB),
        nc[1].div_ceil(SUB),
        nc[2].div_ceil(SUB),
    ];
    out.subblocks = (ns[0] * ns[1] * ns[2]) as u32;
    s.xs.clear();
    s.ys.clear();
    s.zs.clear();
    s.meta.clear();
    let cube = |a: [usize; 3], size: usize| -> (Aabb, bool) {
        let e = [
            (a[0] + size).min(c0[0] + nc[0]),
            (a[1] + size).min(c0[1] + nc[1]),
            (a[2] + size).min(c0[2] + nc[2]),
        ];
        (
            grid.cell_box(a, e),
            (0..3).any(|k| a[k] == 0 || e[k] == grid.n[k]),
        )
    };
    for sz in 0..ns[2] {
        for sy in 0..ns[1] {
            for sx in 0..ns[0] {
                let (bx, border) =
                    cube([c0[0] + sx * SUB, c0[1] + sy * SUB, c0[2] + sz * SUB], SUB);
                let c = bx.center();
                s.xs.push(c.x);
                s.ys.push(c.y);
                s.zs.push(c.z);
                s.meta
                    .push((sx + 4 * (sy + 4 * sz), bx.size().length() * 0.5, border));
            }
        }
    }
    s.out.clear();
    s.out.resize(s.xs.len(), 0.0);
    ev.eval(&region, &s.xs, &s.ys, &s.zs, &mut s.out);
    out.field_evals += s.xs.len() as u64;
    for (k, &(bit, r, border)) in s.meta.iter().enumerate() {
        if may_hold_surface(s.out[k], r, l, border) {
            out.live |= 1u64 << bit;
        }
    }
    if out.live == 0 {
        return;
    }
    // Level 2: 2³ children of live sub-blocks.
    let nch = [
        nc[0].div_ceil(CHILD),
        nc[1].div_ceil(CHILD),
        nc[2].div_ceil(CHILD),
    ];
    s.xs.clear();
    s.ys.clear();
    s.zs.clear();
    s.meta.clear();
    for cz in 0..nch[2] {
        for cy in 0..nch[1] {
            for cx in 0..nch[0] {
                if out.live & (1u64 << (cx / 2 + 4 * (cy / 2 + 4 * (cz / 2)))) == 0 {
                    continue;
                }
                let (bx, border) = cube(
                    [c0[0] + cx * CHILD, c0[1] + cy * CHILD, c0[2] + cz * CHILD],
                    CHILD,
                );
                let c = bx.center();
                s.xs.push(c.x);
                s.ys.push(c.y);
                s.zs.push(c.z);
                s.meta
                    .push((cx + 8 * (cy + 8 * cz), bx.size().length() * 0.5, border));
            }
        }
    }
    s.out.clear();
    s.out.resize(s.xs.len(), 0.0);
    ev.eval(&region, &s.xs, &s.ys, &s.zs, &mut s.out);
    out.field_evals += s.xs.len() as u64;
    let mut any = false;
    for (k, &(bit, r, border)) in s.meta.iter().enumerate() {
        if may_hold_surface(s.out[k], r, l, border) {
            out.live_cells[bit / 64] |= 1u64 << (bit % 64);
            any = true;
        } else {
            out.children_culled += 1;
        }
    }
    if !any {
        return;
    }
    for cz in 0..nch[2] {
        for cy in 0..nch[1] {
            for cx in 0..nch[0] {
                let bit = cx + 8 * (cy + 8 * cz);
                if out.live_cells[bit / 64] & (1u64 << (bit % 64)) == 0 {
                    continue;
                }
                let z1 = (cz * CHILD + CHILD).min(nc[2]);
                let y1 = (cy * CHILD + CHILD).min(nc[1]);
                let x1 = (cx * CHILD + CHILD).min(nc[0]);
                for z in cz * CHILD..=z1 {
                    for y in cy * CHILD..=y1 {
                        for x in cx * CHILD..=x1 {
                            out.valid[lidx(x, y, z)] = true;
                        }
                    }
                }
            }
        }
    }
    s.idx.clear();
    s.border.clear();
    s.xs.clear();
    s.ys.clear();
    s.zs.clear();
    let on_border = |a: usize, i: usize| i == 0 || i == grid.n[a];
    let push = |s: &mut SampleScratch, x: usize, y: usize, z: usize| {
        let i = lidx(x, y, z);
        let g = [c0[0] + x, c0[1] + y, c0[2] + z];
        s.idx.push(i as u32);
        s.border
            .push(on_border(0, g[0]) || on_border(1, g[1]) || on_border(2, g[2]));
        s.xs.push(grid.coord(0, g[0]));
        s.ys.push(grid.coord(1, g[1]));
        s.zs.push(grid.coord(2, g[2]));
    };
    if ev.wants_regions() {
        // Per live sub-block, with its own region; each point once (in the
        // sub-block holding it as a cell origin, the far faces clamped).
        for sz in 0..ns[2] {
            for sy in 0..ns[1] {
                for sx in 0..ns[0] {
                    if out.live & (1u64 << (sx + 4 * (sy + 4 * sz))) == 0 {
                        continue;
                    }
                    let start = s.xs.len();
                    let hi = |sk: usize, n: usize| {
                        if sk * SUB + SUB >= n {
                            n
                        } else {
                            sk * SUB + SUB - 1
                        }
                    };
                    for z in sz * SUB..=hi(sz, nc[2]) {
                        for y in sy * SUB..=hi(sy, nc[1]) {
                            for x in sx * SUB..=hi(sx, nc[0]) {
                                if out.valid[lidx(x, y, z)] {
                                    push(s, x, y, z);
                                }
                            }
                        }
                    }
                    // Points of this sub-block's far faces that belong to a
                    // culled neighbour sub-block are evaluated here too.
                    for z in sz * SUB..=(sz * SUB + SUB).min(nc[2]) {
                        for y in sy * SUB..=(sy * SUB + SUB).min(nc[1]) {
                            for x in sx * SUB..=(sx * SUB + SUB).min(nc[0]) {
                                let inner =
                                    x <= hi(sx, nc[0]) && y <= hi(sy, nc[1]) && z <= hi(sz, nc[2]);
                                if inner || !out.valid[lidx(x, y, z)] {
                                    continue;
                                }
                                let owner = |v: usize, n: usize| (v / SUB).min(n.div_ceil(SUB) - 1);
                                let (ox, oy, oz) =
                                    (owner(x, nc[0]), owner(y, nc[1]), owner(z, nc[2]));
                                if out.live & (1u64 << (ox + 4 * (oy + 4 * oz))) == 0 {
                                    // Claim it (first live sub-block in order).
                                    let i = lidx(x, y, z);
                                    if !s.idx[start..].contains(&(i as u32)) {
                                        push(s, x, y, z);
                                    }
                                }
                            }
                        }
                    }
                    let end = s.xs.len();
                    if end > start {
                        let lo = grid.point([c0[0] + sx * SUB, c0[1] + sy * SUB, c0[2] + sz * SUB]);
                        let hi_p = grid.point([
                            c0[0] + (sx * SUB + SUB).min(nc[0]),
                            c0[1] + (sy * SUB + SUB).min(nc[1]),
                            c0[2] + (sz * SUB + SUB).min(nc[2]),
                        ]);
                        let r = Aabb::new(lo, hi_p);
                        s.out.resize(end, 0.0);
                        let (xs, ys, zs) =
                            (&s.xs[start..end], &s.ys[start..end], &s.zs[start..end]);
                        ev.eval(&r, xs, ys, zs, &mut s.out[start..end]);
                    }
                }
            }
        }
        // A point claimed by two sub-blocks is written twice with equal values.
    } else {
        // One call for the block; coordinates and border flags per row.
        for z in 0..=nc[2] {
            let gz = c0[2] + z;
            let (zc, bz) = (grid.coord(2, gz), on_border(2, gz));
            for y in 0..=nc[1] {
                let gy = c0[1] + y;
                let (yc, by) = (grid.coord(1, gy), on_border(1, gy));
                for x in 0..=nc[0] {
                    let i = lidx(x, y, z);
                    if out.valid[i] {
                        let gx = c0[0] + x;
                        s.idx.push(i as u32);
                        s.border.push(bz || by || on_border(0, gx));
                        s.xs.push(grid.coord(0, gx));
                        s.ys.push(yc);
                        s.zs.push(zc);
                    }
                }
            }
        }
        s.out.clear();
        s.out.resize(s.xs.len(), 0.0);
        ev.eval(&region, &s.xs, &s.ys, &s.zs, &mut s.out);
    }
    out.field_evals += s.xs.len() as u64;
    for (k, &i) in s.idx.iter().enumerate() {
        let mut f = s.out[k];
        if f.is_nan() {
            f = f64::MAX;
        }
        if s.border[k] && f <= 0.0 {
            f = BORDER_OUTSIDE;
        }
        out.v[i as usize] = f;
    }
}

impl BlockSamples {
    /// An empty buffer.
    pub fn new() -> Self {
        BlockSamples {
            b: [0; 3],
            c0: [0; 3],
            nc: [0; 3],
            v: vec![f64::MAX; BP * BP * BP],
            valid: Vec::with_capacity(BP * BP * BP),
            live: 0,
            live_cells: [0; 8],
            subblocks: 0,
            children_culled: 0,
            field_evals: 0,
        }
    }

    /// True if the cell at local (x, y, z) is in a live child.
    #[inline]
    pub fn cell_live(&self, x: usize, y: usize, z: usize) -> bool {
        let bit = x / CHILD + 8 * (y / CHILD + 8 * (z / CHILD));
        self.live_cells[bit / 64] & (1u64 << (bit % 64)) != 0
    }
}

impl Default for BlockSamples {
    fn default() -> Self {
        Self::new()
    }
}

/// Blocks that may hold surface, in block order (z, y, x), with the count
/// of blocks skipped and the field evaluations spent deciding.
pub fn live_blocks(grid: &Grid, field: &dyn Field) -> (Vec<[usize; 3]>, u64, u64) {
    use rayon::prelude::*;
    let nb = grid.blocks();
    let l = field.lipschitz();
    let fb = field.bounds();
    let total = nb[0] * nb[1] * nb[2];
    // One z-slab of blocks per task.
    let per_z: Vec<(Vec<[usize; 3]>, u64, u64)> = (0..nb[2])
        .into_par_iter()
        .map(|bz| {
            let mut ev = field.evaluator();
            let mut live = Vec::new();
            let mut evals = 0u64;
            let (mut xs, mut ys, mut zs) = (Vec::new(), Vec::new(), Vec::new());
            let mut cand: Vec<([usize; 3], f64, bool)> = Vec::new();
            for by in 0..nb[1] {
                for bx in 0..nb[0] {
                    let b = [bx, by, bz];
                    let c0 = [bx * BLOCK, by * BLOCK, bz * BLOCK];
                    let c1 = [
                        (c0[0] + BLOCK).min(grid.n[0]),
                        (c0[1] + BLOCK).min(grid.n[1]),
                        (c0[2] + BLOCK).min(grid.n[2]),
                    ];
                    let bxb = grid.cell_box(c0, c1);
                    let border = (0..3).any(|k| c0[k] == 0 || c1[k] == grid.n[k]);
                    // Outside the solid's box, f > 0 (unless the field's box
                    // is unbounded, when this test never fires).
                    if bxb.intersection(&fb).is_empty() {
                        continue;
                    }
                    let c = bxb.center();
                    xs.push(c.x);
                    ys.push(c.y);
                    zs.push(c.z);
                    cand.push((b, bxb.size().length() * 0.5, border));
                }
            }
            let mut out = vec![0.0; xs.len()];
            if !xs.is_empty() {
                // Evaluate centres one by one so a region-aware field gets a
                // tight region per point.
                for i in 0..xs.len() {
                    let p = DVec3::new(xs[i], ys[i], zs[i]);
                    let r = Aabb::new(p, p);
                    ev.eval(
                        &r,
                        &xs[i..i + 1],
                        &ys[i..i + 1],
                        &zs[i..i + 1],
                        &mut out[i..i + 1],
                    );
                }
                evals += xs.len() as u64;
            }
            for (k, (b, r, border)) in cand.into_iter().enumerate() {
                if may_hold_surface(out[k], r, l, border) {
                    live.push(b);
                }
            }
            (live, evals, 0)
        })
        .collect();
    let mut live = Vec::new();
    let mut evals = 0;
    for (l, e, _) in per_z {
        live.extend(l);
        evals += e;
    }
    let culled = (total - live.len()) as u64;
    (live, culled, evals)
}

/// f on a full `n[0] × n[1] × n[2]` linspace grid over `[lo, hi]` (x fastest,
/// then y, then z), in parallel over z-slices; no culling. For fields that
/// are needed everywhere (a mesh's distance on a grid, the peers' "SDF of a
/// mesh" workload). Checked against `max_samples` before allocating.
pub fn sample_grid(
    field: &dyn Field,
    lo: DVec3,
    hi: DVec3,
    n: [usize; 3],
    max_samples: u64,
    threads: usize,
) -> Result<Vec<f64>> {
    use rayon::prelude::*;
    let total = n[0] as u128 * n[1] as u128 * n[2] as u128;
    if n.contains(&0) || total > max_samples as u128 {
        return Err(SdfError::TooManyCells {
            cells: total,
            nx: n[0] as u64,
            ny: n[1] as u64,
            nz: n[2] as u64,
            limit: max_samples,
        });
    }
    if !(lo.is_finite() && hi.is_finite()) || lo.cmpgt(hi).any() {
        return Err(SdfError::InvalidOption {
            field: "domain",
            reason: "non-finite or inverted".into(),
        });
    }
    let coord = |a: usize, i: usize| -> f64 {
        if n[a] == 1 {
            lo[a]
        } else if i == n[a] - 1 {
            hi[a]
        } else {
            lo[a] + i as f64 * ((hi[a] - lo[a]) / (n[a] - 1) as f64)
        }
    };
    let xs: Vec<f64> = (0..n[0]).map(|i| coord(0, i)).collect();
    let run = || {
        let mut out = vec![0.0; total as usize];
        out.par_chunks_mut(n[0] * n[1]).enumerate().for_each_init(
            || field.evaluator(),
            |ev, (z, slab)| {
                let zc = coord(2, z);
                let zs = vec![zc; n[0]];
                let mut ys = vec![0.0; n[0]];
                for (y, row) in slab.chunks_mut(n[0]).enumerate() {
                    ys.fill(coord(1, y));
                    let region =
                        Aabb::new(DVec3::new(lo.x, ys[0], zc), DVec3::new(hi.x, ys[0], zc));
                    ev.eval(&region, &xs, &ys, &zs, row);
                }
            },
        );
        out
    };
    if threads > 0 {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| SdfError::InvalidOption {
                field: "threads",
                reason: e.to_string(),
            })?;
        Ok(pool.install(run))
    } else {
        Ok(run())
    }
}
