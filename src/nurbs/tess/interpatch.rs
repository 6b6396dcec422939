//! Inter-patch adaptive tessellation (thesis §2.1, Fig. 2.3; spec §2.5; decision D8).
//!
//! The surface is decomposed into Bézier patches. Every border curve gets its own segment count
//! n_e = ⌈√(M_e / 8ε)⌉ from the second differences of its control points, a function of the
//! curve alone, so both neighbours agree; its points are evaluated once and shared by id. Every
//! patch interior gets (n_u, n_v) from the Filip–Magedson–Markot bound on its net; rational
//! patches (where the bound on the Euclidean net is not rigorous) and rational border curves are
//! then doubled until the sagitta measured at cell centres, edge midpoints and centroids is
//! ≤ ε. The ring between the interior grid and the four border polylines is zipped.

use glam::{DVec2, DVec3, DVec4};

use super::super::bezier::{de_casteljau, project};
use super::super::mesh::TriMesh;
use super::super::surface::{BezierNet, NurbsSurface};
use super::domain::{sample, ParamDomain};
use super::{TessError, TessStats, Tessellation};

/// Upper bound on any per-patch or per-border level.
const MAX_LEVEL: usize = 1 << 12;

/// One zipped strip: the border, the inner chain of grid indices, whether the border runs along
/// u, the border's fixed local coordinate, the inner chain's fixed local coordinate.
type Strip = (Border, Vec<(usize, usize)>, bool, f64, f64);

/// Border identity: (u-border: curve along u at v-break jb over patch column a) or
/// (v-border: curve along v at u-break ia over patch row b).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Border {
    AlongU { a: usize, jb: usize },
    AlongV { ia: usize, b: usize },
}

struct Ctx<'a> {
    surface: &'a NurbsSurface,
    net: BezierNet,
    dom: ParamDomain,
    eps: f64,
}

impl<'a> Ctx<'a> {
    /// The surface's Bézier decomposition and domain, at tolerance `eps`.
    fn new(surface: &'a NurbsSurface, eps: f64) -> Result<Self, TessError> {
        Ok(Ctx {
            surface,
            dom: ParamDomain::new(surface),
            net: surface.decompose()?,
            eps,
        })
    }

    fn canonical(&self, border: Border) -> Border {
        let [pu, pv] = self.net.patches;
        match border {
            Border::AlongU { a, jb } if self.dom.closed[1] && jb == pv => {
                Border::AlongU { a, jb: 0 }
            }
            Border::AlongV { ia, b } if self.dom.closed[0] && ia == pu => {
                Border::AlongV { ia: 0, b }
            }
            other => other,
        }
    }

    fn border_points(&self, border: Border) -> Vec<DVec4> {
        let [p, q] = self.net.degree;
        match border {
            Border::AlongU { a, jb } => (0..=p).map(|k| self.net.at(a * p + k, jb * q)).collect(),
            Border::AlongV { ia, b } => (0..=q).map(|k| self.net.at(ia * p, b * q + k)).collect(),
        }
    }

    fn is_pole(&self, border: Border) -> bool {
        let [pu, pv] = self.net.patches;
        match border {
            Border::AlongU { jb, .. } => {
                (jb == 0 && self.dom.poles[2]) || (jb == pv && self.dom.poles[3])
            }
            Border::AlongV { ia, .. } => {
                (ia == 0 && self.dom.poles[0]) || (ia == pu && self.dom.poles[1])
            }
        }
    }

    /// Global parameter of local t on a border.
    fn border_uv(&self, border: Border, t: f64) -> DVec2 {
        let (bu, bv) = (&self.net.breaks_u, &self.net.breaks_v);
        match border {
            Border::AlongU { a, jb } => DVec2::new(lerp(bu[a], bu[a + 1], t), bv[jb]),
            Border::AlongV { ia, b } => DVec2::new(bu[ia], lerp(bv[b], bv[b + 1], t)),
        }
    }

    /// Segment count of a border curve (a function of its control points only).
    fn border_level(&self, border: Border) -> usize {
        if self.is_pole(border) {
            return 1;
        }
        let pts = self.border_points(border);
        let n = pts.len() - 1;
        let euclid: Vec<DVec3> = pts.iter().map(|h| project(*h)).collect();
        let m = second_difference(&euclid) * (n * n.saturating_sub(1)) as f64;
        if pts.iter().all(|h| h.w == pts[0].w) {
            // Polynomial: |C − polyline| ≤ Δt²·sup|C''|/8 is rigorous.
            return level_from_bound(m / (8.0 * self.eps));
        }
        // Rational: the bound on the Euclidean points is not valid; search the smallest level
        // whose measured sagitta passes (doubling, then bisection). Deterministic.
        smallest_passing(1, |n| curve_sagitta(&pts, n) <= self.eps)
    }

    /// (n_u, n_v) of patch (a, b), each ≥ 2.
    fn patch_level(
        &self,
        a: usize,
        b: usize,
        max_triangles: usize,
    ) -> Result<[usize; 2], TessError> {
        let patch = self.net.patch(a, b);
        let (p, q) = (patch.degree_u, patch.degree_v);
        let too_many = |n: [usize; 2]| 2 * n[0] as u128 * n[1] as u128 > max_triangles as u128;
        let limit = |n: [usize; 2]| TessError::TriangleLimit {
            needed: 2 * n[0] as u128 * n[1] as u128,
            limit: max_triangles,
        };
        if patch.points.iter().all(|h| h.w == patch.points[0].w) {
            let pt = |i: usize, j: usize| patch.control_point(i, j);
            let (mut muu, mut mvv, mut muv) = (0.0f64, 0.0f64, 0.0f64);
            for i in 0..=p {
                for j in 0..=q {
                    if i + 2 <= p {
                        muu = muu.max((pt(i + 2, j) - 2.0 * pt(i + 1, j) + pt(i, j)).length());
                    }
                    if j + 2 <= q {
                        mvv = mvv.max((pt(i, j + 2) - 2.0 * pt(i, j + 1) + pt(i, j)).length());
                    }
                    if i < p && j < q {
                        muv = muv.max(
                            (pt(i + 1, j + 1) - pt(i + 1, j) - pt(i, j + 1) + pt(i, j)).length(),
                        );
                    }
                }
            }
            muu *= (p * p.saturating_sub(1)) as f64;
            mvv *= (q * q.saturating_sub(1)) as f64;
            muv *= (p * q) as f64;
            let n = [
                level_from_bound((muu + muv) / (4.0 * self.eps)).max(2),
                level_from_bound((mvv + muv) / (4.0 * self.eps)).max(2),
            ];
            return if too_many(n) { Err(limit(n)) } else { Ok(n) };
        }
        // Rational patch: grow the failing direction(s) by doubling until the measured
        // deviation of the patch grid passes, then bisect each direction down.
        let pass = |n: [usize; 2]| {
            let (du, dv) = grid_sagitta(self.surface, patch.u_range, patch.v_range, n);
            (du <= self.eps, dv <= self.eps)
        };
        let mut n = [2usize, 2usize];
        loop {
            if too_many(n) {
                return Err(limit(n));
            }
            let (ou, ov) = pass(n);
            if ou && ov {
                break;
            }
            if (!ou && n[0] >= MAX_LEVEL) || (!ov && n[1] >= MAX_LEVEL) {
                return Ok([n[0].min(MAX_LEVEL), n[1].min(MAX_LEVEL)]);
            }
            if !ou {
                n[0] *= 2;
            }
            if !ov {
                n[1] *= 2;
            }
        }
        for d in 0..2 {
            let (mut lo, mut hi) = (n[d] / 2, n[d]);
            while hi - lo > 1 && hi > 2 {
                let mid = (lo + hi) / 2;
                let mut m = n;
                m[d] = mid.max(2);
                let (ou, ov) = pass(m);
                if ou && ov {
                    hi = m[d];
                } else {
                    lo = mid;
                }
            }
            n[d] = hi.max(2);
        }
        Ok(n)
    }
}

/// Smallest level ≥ `start` passing `ok`, by doubling then bisection (capped at MAX_LEVEL).
fn smallest_passing(start: usize, ok: impl Fn(usize) -> bool) -> usize {
    let mut hi = start.max(1);
    while !ok(hi) {
        if hi >= MAX_LEVEL {
            return MAX_LEVEL;
        }
        hi *= 2;
    }
    let mut lo = hi / 2;
    if lo < start {
        return hi;
    }
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if ok(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

#[inline]
fn lerp(a: f64, b: f64, t: f64) -> f64 {
    if t >= 1.0 {
        b
    } else {
        a + (b - a) * t
    }
}

fn level_from_bound(x: f64) -> usize {
    if !x.is_finite() {
        return MAX_LEVEL;
    }
    (x.sqrt().ceil() as usize).clamp(1, MAX_LEVEL)
}

fn second_difference(p: &[DVec3]) -> f64 {
    p.windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).length())
        .fold(0.0, f64::max)
}

/// Max chordal deviation of a (rational) Bézier curve split into `n` equal segments.
fn curve_sagitta(points: &[DVec4], n: usize) -> f64 {
    let at = |t: f64| project(de_casteljau(points, t));
    let mut worst = 0.0f64;
    let mut prev = at(0.0);
    for k in 0..n {
        let next = at((k + 1) as f64 / n as f64);
        let mid = at((k as f64 + 0.5) / n as f64);
        worst = worst.max((mid - (prev + next) * 0.5).length());
        prev = next;
    }
    worst
}

/// Max deviation of a patch's n_u × n_v grid: (along u-edges and cells, along v-edges and
/// cells). Cells are measured at the centre against both diagonals and at the centroids of all
/// four possible triangles (the zipped strips use the other diagonal at some corners). Every
/// sample family is a tensor grid, evaluated with basis tables (D9).
fn grid_sagitta(surface: &NurbsSurface, ur: [f64; 2], vr: [f64; 2], n: [usize; 2]) -> (f64, f64) {
    let (nu, nv) = (n[0], n[1]);
    let axis = |r: [f64; 2], cells: usize, f: f64, count: usize| -> Vec<f64> {
        (0..count)
            .map(|k| lerp(r[0], r[1], (k as f64 + f) / cells as f64))
            .collect()
    };
    let grid = |us: Vec<f64>, vs: Vec<f64>| -> Vec<DVec3> {
        match surface.grid(&us, &vs, false) {
            Ok(g) => g.points.into_iter().map(DVec3::from_array).collect(),
            Err(_) => Vec::new(),
        }
    };
    let nodes = grid(axis(ur, nu, 0.0, nu + 1), axis(vr, nv, 0.0, nv + 1));
    if nodes.is_empty() {
        return (f64::INFINITY, f64::INFINITY);
    }
    let g = |i: usize, j: usize| nodes[i * (nv + 1) + j];
    let (mut du, mut dv) = (0.0f64, 0.0f64);
    let umid = grid(axis(ur, nu, 0.5, nu), axis(vr, nv, 0.0, nv + 1));
    for i in 0..nu {
        for j in 0..=nv {
            du = du.max((umid[i * (nv + 1) + j] - (g(i, j) + g(i + 1, j)) * 0.5).length());
        }
    }
    let vmid = grid(axis(ur, nu, 0.0, nu + 1), axis(vr, nv, 0.5, nv));
    for i in 0..=nu {
        for j in 0..nv {
            dv = dv.max((vmid[i * nv + j] - (g(i, j) + g(i, j + 1)) * 0.5).length());
        }
    }
    let centre = grid(axis(ur, nu, 0.5, nu), axis(vr, nv, 0.5, nv));
    let third = |fu: f64, fv: f64| grid(axis(ur, nu, fu, nu), axis(vr, nv, fv, nv));
    let (c1, c2) = (third(2.0 / 3.0, 1.0 / 3.0), third(1.0 / 3.0, 2.0 / 3.0));
    let (c3, c4) = (third(1.0 / 3.0, 1.0 / 3.0), third(2.0 / 3.0, 2.0 / 3.0));
    let mut cells = 0.0f64;
    for i in 0..nu {
        for j in 0..nv {
            let k = i * nv + j;
            let (a, b, c, d) = (g(i, j), g(i + 1, j), g(i + 1, j + 1), g(i, j + 1));
            cells = cells
                .max((centre[k] - (a + c) * 0.5).length())
                .max((centre[k] - (b + d) * 0.5).length())
                .max((c1[k] - (a + b + c) / 3.0).length())
                .max((c2[k] - (a + c + d) / 3.0).length())
                .max((c3[k] - (a + b + d) / 3.0).length())
                .max((c4[k] - (b + c + d) / 3.0).length());
        }
    }
    (du.max(cells), dv.max(cells))
}

/// Vertex registry keyed by the geometric element a sample belongs to.
struct Builder<'a> {
    ctx: &'a Ctx<'a>,
    mesh: TriMesh,
    corner_ids: Vec<u32>,
    pole_ids: [u32; 4],
}

impl Builder<'_> {
    fn push(&mut self, uv: DVec2) -> u32 {
        let s = sample(self.ctx.surface, uv);
        self.mesh.positions.push(s.p.to_array());
        self.mesh.normals.push(s.n.to_array());
        self.mesh.uvs.push(uv.to_array());
        (self.mesh.positions.len() - 1) as u32
    }

    /// Pole group of a grid corner or border sample on a collapsed border, if any.
    fn pole_of(&self, uv: DVec2) -> Option<usize> {
        let d = &self.ctx.dom;
        let on = [
            uv.x == d.lo.x,
            uv.x == d.hi.x,
            uv.y == d.lo.y,
            uv.y == d.hi.y,
        ];
        (0..4).find(|&k| d.poles[k] && on[k])
    }

    fn pole_vertex(&mut self, k: usize) -> u32 {
        // Canonical parameter of a pole: the border value in the fixed coordinate, the domain
        // start in the free one.
        let d = self.ctx.dom;
        if self.pole_ids[k] == u32::MAX {
            let canon = match k {
                0 => DVec2::new(d.lo.x, d.lo.y),
                1 => DVec2::new(d.hi.x, d.lo.y),
                2 => DVec2::new(d.lo.x, d.lo.y),
                _ => DVec2::new(d.lo.x, d.hi.y),
            };
            self.pole_ids[k] = self.push(canon);
        }
        self.pole_ids[k]
    }

    fn corner(&mut self, ia: usize, jb: usize) -> u32 {
        let [pu, pv] = self.ctx.net.patches;
        let ia = if self.ctx.dom.closed[0] && ia == pu {
            0
        } else {
            ia
        };
        let jb = if self.ctx.dom.closed[1] && jb == pv {
            0
        } else {
            jb
        };
        let uv = DVec2::new(self.ctx.net.breaks_u[ia], self.ctx.net.breaks_v[jb]);
        if let Some(k) = self.pole_of(uv) {
            return self.pole_vertex(k);
        }
        let slot = ia * (pv + 1) + jb;
        if self.corner_ids[slot] == u32::MAX {
            self.corner_ids[slot] = self.push(uv);
        }
        self.corner_ids[slot]
    }
}

/// Per-patch start cells of inter-patch mode (the adaptive default's start, so border samples
/// are dyadic refinements of the same grid).
const START_CELLS: usize = 3;

/// Inter-patch mode (issue 37): every Bézier border curve is sampled at START_CELLS · 2^L
/// equal parameter steps, L the smallest level whose chordal deviation measured on the curve
/// alone is ≤ ε (D8: a function of the border's control points, so both neighbours agree, across
/// surfaces of a patch set too); each patch's interior is then refined by the adaptive criterion
/// (sagitta at edge midpoints and centroids, flips) with its border samples fixed. The thesis's
/// per-patch levels (one uniform grid per patch, the worst region's resolution) made 5× the
/// adaptive count on the peers' surface; this keeps the structure and spends triangles where the
/// patch curves.
pub(crate) fn interpatch_adaptive(
    surface: &NurbsSurface,
    eps: f64,
    max_triangles: usize,
    forced: &super::adaptive::Forced,
) -> Result<Tessellation, TessError> {
    let options = super::adaptive::AdaptiveOptions::sagitta(eps);
    let initial = super::uniform::uniform(
        surface,
        [START_CELLS, START_CELLS],
        true,
        super::Diagonal::Best,
        max_triangles,
    )?;
    let rule = BorderRule::new(surface, eps, options.max_level)?;
    let levels = rule.segment_counts();
    let mut t = super::adaptive::refine(
        surface,
        &options,
        initial,
        forced,
        Some(&rule),
        max_triangles,
    )?;
    t.stats.border_levels = levels;
    t.stats.patch_levels.clear();
    Ok(t)
}

/// Where inter-patch mode samples each Bézier border curve.
pub(crate) struct BorderRule {
    /// Patch borders along u and along v.
    breaks: [Vec<f64>; 2],
    /// `samples[d][k][piece]`: sorted parameters (the other coordinate) of the samples inside
    /// border piece `piece` of the line where coordinate d equals `breaks[d][k]`.
    samples: [Vec<Vec<Vec<f64>>>; 2],
}

impl BorderRule {
    fn new(surface: &NurbsSurface, eps: f64, max_level: u32) -> Result<Self, TessError> {
        let ctx = Ctx::new(surface, eps)?;
        let [pu, pv] = ctx.net.patches;
        let steps = |border: Border| -> usize {
            if ctx.is_pole(border) {
                return START_CELLS;
            }
            let pts = ctx.border_points(border);
            let mut n = START_CELLS;
            for _ in 0..max_level {
                if curve_sagitta(&pts, n) <= eps {
                    break;
                }
                n *= 2;
            }
            n
        };
        let inside = |lo: f64, hi: f64, n: usize| -> Vec<f64> {
            (1..n).map(|k| lerp(lo, hi, k as f64 / n as f64)).collect()
        };
        let (bu, bv) = (&ctx.net.breaks_u, &ctx.net.breaks_v);
        // Lines u = bu[ia] (curves along v), pieces b; lines v = bv[jb], pieces a.
        let line = |pieces: &[f64], border: &dyn Fn(usize) -> Border| -> Vec<Vec<f64>> {
            (0..pieces.len() - 1)
                .map(|k| inside(pieces[k], pieces[k + 1], steps(ctx.canonical(border(k)))))
                .collect()
        };
        let along_v: Vec<Vec<Vec<f64>>> = (0..=pu)
            .map(|ia| line(bv, &|b| Border::AlongV { ia, b }))
            .collect();
        let along_u: Vec<Vec<Vec<f64>>> = (0..=pv)
            .map(|jb| line(bu, &|a| Border::AlongU { a, jb }))
            .collect();
        Ok(BorderRule {
            breaks: [bu.clone(), bv.clone()],
            samples: [along_v, along_u],
        })
    }

    /// Segments of every border piece (lines u = const first, then v = const).
    fn segment_counts(&self) -> Vec<u32> {
        self.samples
            .iter()
            .flatten()
            .flatten()
            .map(|s| s.len() as u32 + 1)
            .collect()
    }

    /// For an edge on a patch border line: whether a sample lies strictly inside it (split it)
    /// or not (keep it). `None` for an edge inside a patch.
    pub(crate) fn verdict(&self, a: DVec2, b: DVec2) -> Option<bool> {
        for d in 0..2 {
            if a[d] != b[d] {
                continue;
            }
            let Ok(k) = self.breaks[d].binary_search_by(|x| x.total_cmp(&a[d])) else {
                continue;
            };
            let other = &self.breaks[1 - d];
            let (t0, t1) = (a[1 - d].min(b[1 - d]), a[1 - d].max(b[1 - d]));
            let piece = other
                .partition_point(|&x| x <= t0)
                .saturating_sub(1)
                .min(other.len().saturating_sub(2));
            let list = &self.samples[d][k][piece];
            let tol = super::domain::PARAM_TOLERANCE * (other[other.len() - 1] - other[0]);
            let i = list.partition_point(|&f| f <= t0 + tol);
            return Some(i < list.len() && list[i] < t1 - tol);
        }
        None
    }
}

/// The thesis's inter-patch levels (one grid per Bézier patch from curvature bounds, borders
/// zipped): the start [`super::adaptive::Initial::InterPatch`] refines from.
pub(crate) fn interpatch(
    surface: &NurbsSurface,
    eps: f64,
    max_triangles: usize,
) -> Result<Tessellation, TessError> {
    interpatch_with_floors(surface, eps, max_triangles, &Default::default())
}

/// Least segment counts of the outer border curves, per side
/// ([`crate::nurbs::patchset::Side`] order) and Bézier piece along it: a patch set's
/// neighbour needs them so both sides of a shared border have the same samples.
pub(crate) type Floors = [Vec<usize>; 4];

pub(crate) fn interpatch_with_floors(
    surface: &NurbsSurface,
    eps: f64,
    max_triangles: usize,
    floors: &Floors,
) -> Result<Tessellation, TessError> {
    let floor = |side: usize, piece: usize| floors[side].get(piece).copied().unwrap_or(0);
    let ctx = Ctx::new(surface, eps)?;
    let [pu, pv] = ctx.net.patches;
    // Levels: patches first, then borders. A border's level is the maximum of its curve's own
    // level and the along-border level of the patches on both sides: a function of data both
    // neighbours hold, so they agree (D8), and the zipped strips are never coarser along the
    // border than the interior grid next to them.
    let patch_levels: Vec<[usize; 2]> = (0..pu)
        .flat_map(|a| (0..pv).map(move |b| (a, b)))
        .map(|(a, b)| ctx.patch_level(a, b, max_triangles))
        .collect::<Result<_, _>>()?;
    let wrap_b = |b: isize| -> Option<usize> {
        if b >= 0 && (b as usize) < pv {
            Some(b as usize)
        } else if ctx.dom.closed[1] {
            Some(b.rem_euclid(pv as isize) as usize)
        } else {
            None
        }
    };
    let wrap_a = |a: isize| -> Option<usize> {
        if a >= 0 && (a as usize) < pu {
            Some(a as usize)
        } else if ctx.dom.closed[0] {
            Some(a.rem_euclid(pu as isize) as usize)
        } else {
            None
        }
    };
    let along_u: Vec<usize> = (0..pu)
        .flat_map(|a| (0..=pv).map(move |jb| (a, jb)))
        .map(|(a, jb)| {
            let border = ctx.canonical(Border::AlongU { a, jb });
            let mut level = ctx.border_level(border);
            if jb == 0 || jb == pv {
                level = level.max(floor(if jb == 0 { 2 } else { 3 }, a));
            }
            if !ctx.is_pole(border) {
                for b in [wrap_b(jb as isize - 1), wrap_b(jb as isize)]
                    .into_iter()
                    .flatten()
                {
                    level = level.max(patch_levels[a * pv + b][0]);
                }
            }
            level
        })
        .collect();
    let along_v: Vec<usize> = (0..=pu)
        .flat_map(|ia| (0..pv).map(move |b| (ia, b)))
        .map(|(ia, b)| {
            let border = ctx.canonical(Border::AlongV { ia, b });
            let mut level = ctx.border_level(border);
            if ia == 0 || ia == pu {
                level = level.max(floor(if ia == 0 { 0 } else { 1 }, b));
            }
            if !ctx.is_pole(border) {
                for a in [wrap_a(ia as isize - 1), wrap_a(ia as isize)]
                    .into_iter()
                    .flatten()
                {
                    level = level.max(patch_levels[a * pv + b][1]);
                }
            }
            level
        })
        .collect();
    let level_of = |b: Border| match ctx.canonical(b) {
        Border::AlongU { a, jb } => along_u[a * (pv + 1) + jb],
        Border::AlongV { ia, b } => along_v[ia * pv + b],
    };
    // Exact count before building anything.
    let mut needed: u128 = 0;
    for a in 0..pu {
        for b in 0..pv {
            let [nu, nv] = patch_levels[a * pv + b];
            needed += 2 * (nu as u128 - 2) * (nv as u128 - 2);
            let sides = [
                (Border::AlongU { a, jb: b }, nu - 2),
                (Border::AlongU { a, jb: b + 1 }, nu - 2),
                (Border::AlongV { ia: a, b }, nv - 2),
                (Border::AlongV { ia: a + 1, b }, nv - 2),
            ];
            for (border, inner) in sides {
                let ne = level_of(border);
                needed += ne as u128 + inner as u128;
                if ctx.is_pole(border) {
                    needed -= ne as u128;
                }
            }
        }
    }
    if needed > max_triangles as u128 {
        return Err(TessError::TriangleLimit {
            needed,
            limit: max_triangles,
        });
    }
    let vertex_bound: u128 = patch_levels
        .iter()
        .map(|n| (n[0] as u128 + 1) * (n[1] as u128 + 1))
        .sum();
    if vertex_bound > u32::MAX as u128 {
        return Err(TessError::VertexLimit {
            needed: vertex_bound,
        });
    }
    let mut bld = Builder {
        ctx: &ctx,
        mesh: TriMesh::default(),
        corner_ids: vec![u32::MAX; (pu + 1) * (pv + 1)],
        pole_ids: [u32::MAX; 4],
    };
    // Corners, u-major.
    for ia in 0..=pu {
        for jb in 0..=pv {
            bld.corner(ia, jb);
        }
    }
    // Border polylines (ids from start corner to end corner), canonical borders only.
    let mut polyline_u: Vec<Vec<u32>> = vec![Vec::new(); pu * (pv + 1)];
    let mut polyline_v: Vec<Vec<u32>> = vec![Vec::new(); (pu + 1) * pv];
    for a in 0..pu {
        for jb in 0..=pv {
            let border = Border::AlongU { a, jb };
            if ctx.canonical(border) != border {
                continue;
            }
            let ne = level_of(border);
            let mut ids = vec![bld.corner(a, jb)];
            for k in 1..ne {
                let uv = ctx.border_uv(border, k as f64 / ne as f64);
                let id = match bld.pole_of(uv) {
                    Some(pk) => bld.pole_vertex(pk),
                    None => bld.push(uv),
                };
                ids.push(id);
            }
            ids.push(bld.corner(a + 1, jb));
            polyline_u[a * (pv + 1) + jb] = ids;
        }
    }
    for ia in 0..=pu {
        for b in 0..pv {
            let border = Border::AlongV { ia, b };
            if ctx.canonical(border) != border {
                continue;
            }
            let ne = level_of(border);
            let mut ids = vec![bld.corner(ia, b)];
            for k in 1..ne {
                let uv = ctx.border_uv(border, k as f64 / ne as f64);
                let id = match bld.pole_of(uv) {
                    Some(pk) => bld.pole_vertex(pk),
                    None => bld.push(uv),
                };
                ids.push(id);
            }
            ids.push(bld.corner(ia, b + 1));
            polyline_v[ia * pv + b] = ids;
        }
    }
    let polyline = |border: Border| -> &Vec<u32> {
        match ctx.canonical(border) {
            Border::AlongU { a, jb } => &polyline_u[a * (pv + 1) + jb],
            Border::AlongV { ia, b } => &polyline_v[ia * pv + b],
        }
    };
    // Patches.
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(needed as usize);
    let (bu, bv) = (ctx.net.breaks_u.clone(), ctx.net.breaks_v.clone());
    for a in 0..pu {
        for b in 0..pv {
            let [nu, nv] = patch_levels[a * pv + b];
            let us: Vec<f64> = (1..nu)
                .map(|i| lerp(bu[a], bu[a + 1], i as f64 / nu as f64))
                .collect();
            let vs: Vec<f64> = (1..nv)
                .map(|j| lerp(bv[b], bv[b + 1], j as f64 / nv as f64))
                .collect();
            let grid = surface.grid(&us, &vs, true)?;
            let base = bld.mesh.positions.len() as u32;
            for (i, &u) in us.iter().enumerate() {
                for (j, &v) in vs.iter().enumerate() {
                    let k = i * vs.len() + j;
                    bld.mesh.positions.push(grid.points[k]);
                    bld.mesh.normals.push(grid.normals[k]);
                    bld.mesh.uvs.push([u, v]);
                }
            }
            let inner = |i: usize, j: usize| base + ((i - 1) * (nv - 1) + (j - 1)) as u32;
            let local = |i: usize, j: usize| DVec2::new(i as f64 / nu as f64, j as f64 / nv as f64);
            let mut emit = |t: [(u32, DVec2); 3]| {
                let (ids, uv) = (t.map(|x| x.0), t.map(|x| x.1));
                if ids[0] == ids[1] || ids[1] == ids[2] || ids[0] == ids[2] {
                    return;
                }
                let area = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]);
                triangles.push(if area >= 0.0 {
                    ids
                } else {
                    [ids[0], ids[2], ids[1]]
                });
            };
            // Interior cells.
            for i in 1..nu - 1 {
                for j in 1..nv - 1 {
                    let (pa, pb, pc, pd) = ((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1));
                    let x = |c: (usize, usize)| (inner(c.0, c.1), local(c.0, c.1));
                    emit([x(pa), x(pb), x(pc)]);
                    emit([x(pa), x(pc), x(pd)]);
                }
            }
            // Four zipped strips: (border, inner chain, fixed local coordinate of each chain).
            let strips: [Strip; 4] = [
                (
                    Border::AlongU { a, jb: b },
                    (1..nu).map(|i| (i, 1)).collect(),
                    true,
                    0.0,
                    1.0 / nv as f64,
                ),
                (
                    Border::AlongU { a, jb: b + 1 },
                    (1..nu).map(|i| (i, nv - 1)).collect(),
                    true,
                    1.0,
                    1.0 - 1.0 / nv as f64,
                ),
                (
                    Border::AlongV { ia: a, b },
                    (1..nv).map(|j| (1, j)).collect(),
                    false,
                    0.0,
                    1.0 / nu as f64,
                ),
                (
                    Border::AlongV { ia: a + 1, b },
                    (1..nv).map(|j| (nu - 1, j)).collect(),
                    false,
                    1.0,
                    1.0 - 1.0 / nu as f64,
                ),
            ];
            for (border, chain, along_u, outer_fixed, _inner_fixed) in strips {
                let outer = polyline(border);
                let ne = outer.len() - 1;
                let outer_uv = |k: usize| {
                    let t = k as f64 / ne as f64;
                    if along_u {
                        DVec2::new(t, outer_fixed)
                    } else {
                        DVec2::new(outer_fixed, t)
                    }
                };
                let inner_param = |l: usize| {
                    let (i, j) = chain[l];
                    if along_u {
                        i as f64 / nu as f64
                    } else {
                        j as f64 / nv as f64
                    }
                };
                let (mut k, mut l) = (0usize, 0usize);
                let nb = chain.len() - 1;
                while k < ne || l < nb {
                    let advance_outer =
                        l == nb || (k < ne && (k + 1) as f64 / ne as f64 <= inner_param(l + 1));
                    let (ci, cj) = chain[l];
                    if advance_outer {
                        emit([
                            (outer[k], outer_uv(k)),
                            (outer[k + 1], outer_uv(k + 1)),
                            (inner(ci, cj), local(ci, cj)),
                        ]);
                        k += 1;
                    } else {
                        let (ni, nj) = chain[l + 1];
                        emit([
                            (outer[k], outer_uv(k)),
                            (inner(ni, nj), local(ni, nj)),
                            (inner(ci, cj), local(ci, cj)),
                        ]);
                        l += 1;
                    }
                }
            }
        }
    }
    let mut mesh = bld.mesh;
    mesh.triangles = triangles;
    Ok(Tessellation {
        mesh,
        stats: TessStats {
            patch_levels: patch_levels
                .iter()
                .map(|n| [n[0] as u32, n[1] as u32])
                .collect(),
            border_levels: along_u.iter().chain(&along_v).map(|&n| n as u32).collect(),
            ..TessStats::default()
        },
    })
}
