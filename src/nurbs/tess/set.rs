//! Conforming tessellation of a patch set (issue 37): many surfaces meshed as one, with one
//! vertex per sample of every shared border.
//!
//! Each surface is tessellated by its own mode (uniform, inter-patch or adaptive), under
//! constraints on its shared sides that make both sides of a border sample it at the same
//! parameters (mapped onto [0, 1], reversed where the border runs the other way):
//!
//! - uniform: the cell count along the border is the larger of the two sides';
//! - inter-patch: every border is sampled from its own curve (D8: both sides compute the same
//!   samples), and any sample one side has and the other lacks is forced on the other;
//! - adaptive: every parameter where the neighbour split its side is split here too (from a
//!   uniform start, or from the thesis's per-patch levels, where each Bézier piece of a shared
//!   border gets at least the neighbour's segment count).
//!
//! A surface whose side still differs from its neighbour's is tessellated again with the
//! neighbour's samples as its constraint. Every constraint only adds samples, and counts and
//! dyadic levels are bounded, so this reaches a fixed point (in practice after one or two
//! passes); the passes run in surface order, so the result is deterministic. Then the border
//! samples are welded by index: the group's first border owns them (its evaluation is the one
//! kept, so both sides are bit-identical), and corners and poles with them.

use glam::DVec2;

use super::super::mesh::TriMesh;
use super::super::patchset::{BorderGroup, PatchSet, Side};
use super::super::surface::NurbsSurface;
use super::adaptive::{self, Forced, Initial};
use super::domain::{max_deviation, ParamDomain, PARAM_TOLERANCE};
use super::interpatch::{self, Floors};
use super::uniform;
use super::{check_positive, Mode, TessError, TessStats, Tessellation};
use crate::nurbs::error::Dir;

/// Passes before a set that does not settle is refused (each pass only adds samples).
const MAX_PASSES: usize = 64;

/// Per surface and side: the parameters (the surface's own) at which its neighbours sample
/// the shared border, one list per neighbour, and its own last samples.
type Wanted = [Vec<Vec<f64>>; 4];

/// Tessellates every surface of `set` in `mode` into one conforming mesh of at most
/// `max_triangles` triangles.
pub fn tessellate_set(
    set: &PatchSet,
    mode: &Mode,
    max_triangles: usize,
) -> Result<Tessellation, TessError> {
    let groups = set.borders().map_err(|e| TessError::Join(e.to_string()))?;
    let surfaces = &set.surfaces;
    let doms: Vec<ParamDomain> = surfaces.iter().map(ParamDomain::new).collect();
    let parts = match mode {
        Mode::Adaptive(options) => {
            options.validate()?;
            let initial =
                tessellate_parts(set, &options.initial, &doms, &groups, max_triangles)?.meshes;
            settle(surfaces, &doms, &groups, max_triangles, |s, wanted, cap| {
                let forced = forced_params(&doms[s], wanted);
                adaptive::refine(
                    &surfaces[s],
                    options,
                    initial[s].clone(),
                    &forced,
                    None,
                    cap,
                )
            })?
        }
        Mode::InterPatch { tolerance } => {
            check_positive("tolerance", *tolerance)?;
            settle(surfaces, &doms, &groups, max_triangles, |s, wanted, cap| {
                let forced = forced_params(&doms[s], wanted);
                interpatch::interpatch_adaptive(&surfaces[s], *tolerance, cap, &forced)
            })?
        }
        Mode::Uniform {
            cells,
            per_patch,
            diagonal,
        } => {
            let grid = Initial::Uniform {
                cells: *cells,
                per_patch: *per_patch,
                diagonal: *diagonal,
            };
            tessellate_parts(set, &grid, &doms, &groups, max_triangles)?
        }
    };
    // Uniform mode measures on its own grids; the others are measured here, per surface.
    let measure = !matches!(mode, Mode::Uniform { .. });
    weld(surfaces, &doms, &groups, parts, measure)
}

/// The conforming (not yet welded) per-surface meshes of a uniform grid or of the thesis's
/// per-patch levels (the starts adaptive refinement takes).
fn tessellate_parts(
    set: &PatchSet,
    start: &Initial,
    doms: &[ParamDomain],
    groups: &[BorderGroup],
    max_triangles: usize,
) -> Result<Parts, TessError> {
    let surfaces = &set.surfaces;
    match start {
        Initial::Uniform {
            cells,
            per_patch,
            diagonal,
        } => settle(surfaces, doms, groups, max_triangles, |s, wanted, cap| {
            let cells = uniform_cells(&surfaces[s], *cells, *per_patch, wanted);
            uniform::uniform(&surfaces[s], cells, *per_patch, *diagonal, cap)
        }),
        Initial::InterPatch { tolerance } => {
            check_positive("tolerance", *tolerance)?;
            settle(surfaces, doms, groups, max_triangles, |s, wanted, cap| {
                let floors = interpatch_floors(&surfaces[s], wanted);
                interpatch::interpatch_with_floors(&surfaces[s], *tolerance, cap, &floors)
            })
        }
    }
}

/// Per-surface results before welding.
struct Parts {
    meshes: Vec<Tessellation>,
}

/// Runs `run` on every surface, then again on every surface whose shared sides disagree with a
/// neighbour, until none does. `run` gets the surface, what its neighbours want and the
/// triangles left in the budget.
fn settle(
    surfaces: &[NurbsSurface],
    doms: &[ParamDomain],
    groups: &[BorderGroup],
    max_triangles: usize,
    run: impl Fn(usize, &Wanted, usize) -> Result<Tessellation, TessError>,
) -> Result<Parts, TessError> {
    let n = surfaces.len();
    let mut meshes: Vec<Tessellation> = Vec::with_capacity(n);
    let mut total = 0usize;
    let empty: Wanted = Default::default();
    for s in 0..n {
        let t = run(s, &empty, max_triangles.saturating_sub(total))?;
        total += t.mesh.triangles.len();
        meshes.push(t);
    }
    let mut wanted: Vec<Wanted> = vec![Default::default(); n];
    for _ in 0..MAX_PASSES {
        let samples: Vec<[Vec<f64>; 4]> = meshes
            .iter()
            .zip(doms)
            .map(|(t, dom)| Side::ALL.map(|side| side_samples(&t.mesh, dom, side).0))
            .collect();
        let mut dirty = vec![false; n];
        for group in groups {
            // Each member against the first, both ways: all agree when each agrees with it
            // (linear in the group, however many borders a hostile file makes coincide).
            let pairs = (1..group.members.len()).flat_map(|k| [(k, 0), (0, k)]);
            for (x, y) in pairs {
                let (bx, by) = (group.members[x], group.members[y]);
                let reversed = group.reversed[x] != group.reversed[y];
                let theirs = map_params(
                    &samples[by.surface][by.side.index()],
                    &doms[by.surface],
                    by.side,
                    &doms[bx.surface],
                    bx.side,
                    reversed,
                );
                let mine = &samples[bx.surface][bx.side.index()];
                if !same_params(mine, &theirs, &doms[bx.surface], bx.side) {
                    dirty[bx.surface] = true;
                    let list = &mut wanted[bx.surface][bx.side.index()];
                    list.push(theirs);
                    list.push(mine.clone());
                }
            }
        }
        if !dirty.contains(&true) {
            return Ok(Parts { meshes });
        }
        for s in 0..n {
            if dirty[s] {
                let others = total - meshes[s].mesh.triangles.len();
                let t = run(s, &wanted[s], max_triangles.saturating_sub(others))?;
                total = others + t.mesh.triangles.len();
                meshes[s] = t;
            }
        }
    }
    Err(TessError::Join(format!(
        "the shared borders did not settle after {MAX_PASSES} passes"
    )))
}

/// Uniform cells per direction (per span when `per_patch`) that give every shared side at least
/// its neighbours' segment counts.
fn uniform_cells(
    surface: &NurbsSurface,
    cells: [usize; 2],
    per_patch: bool,
    wanted: &Wanted,
) -> [usize; 2] {
    let mut total = uniform::cell_counts(surface, cells, per_patch);
    for side in Side::ALL {
        let d = side.along();
        for list in &wanted[side.index()] {
            total[d] = total[d].max(list.len().saturating_sub(1));
        }
    }
    if !per_patch {
        return total;
    }
    let spans = [Dir::U, Dir::V].map(|d| surface.breakpoints(d).len().saturating_sub(1).max(1));
    [0, 1].map(|d| total[d].div_ceil(spans[d]).max(cells[d]))
}

/// Inter-patch floors: per shared side and Bézier piece, the most segments a neighbour (or
/// this surface's last run) put there.
fn interpatch_floors(surface: &NurbsSurface, wanted: &Wanted) -> Floors {
    let mut floors: Floors = Default::default();
    for side in Side::ALL {
        let lists = &wanted[side.index()];
        if lists.is_empty() {
            continue;
        }
        let breaks = surface.breakpoints(if side.along() == 0 { Dir::U } else { Dir::V });
        let span = breaks[breaks.len() - 1] - breaks[0];
        let tol = PARAM_TOLERANCE * span;
        let mut floor = vec![0usize; breaks.len() - 1];
        for list in lists {
            for (k, w) in breaks.windows(2).enumerate() {
                // Lists are sorted: the samples strictly inside the piece, by two searches.
                let inside = list
                    .partition_point(|&t| t < w[1] - tol)
                    .saturating_sub(list.partition_point(|&t| t <= w[0] + tol));
                floor[k] = floor[k].max(inside + 1);
            }
        }
        floors[side.index()] = floor;
    }
    floors
}

/// Adaptive: every parameter wanted on a side, sorted and deduplicated.
fn forced_params(dom: &ParamDomain, wanted: &Wanted) -> Forced {
    let mut forced: Forced = Default::default();
    for side in Side::ALL {
        let d = side.along();
        let tol = PARAM_TOLERANCE * (dom.hi[d] - dom.lo[d]);
        let mut all: Vec<f64> = wanted[side.index()].iter().flatten().copied().collect();
        all.sort_by(f64::total_cmp);
        all.dedup_by(|a, b| (*a - *b).abs() <= tol);
        forced[side.index()] = all;
    }
    forced
}

/// The vertices on `side` of a surface's mesh, sorted along it: (parameters, vertex ids).
fn side_samples(mesh: &TriMesh, dom: &ParamDomain, side: Side) -> (Vec<f64>, Vec<u32>) {
    let (fixed, along) = (1 - side.along(), side.along());
    let bound = match side {
        Side::U0 | Side::V0 => dom.lo[fixed],
        Side::U1 | Side::V1 => dom.hi[fixed],
    };
    let mut found: Vec<(f64, u32)> = mesh
        .uvs
        .iter()
        .enumerate()
        // A pole vertex lies on both sides that end at the pole.
        .filter(|(_, uv)| uv[fixed] == bound || dom.free(DVec2::from_array(**uv)) == Some(fixed))
        .map(|(v, uv)| (uv[along], v as u32))
        .collect();
    found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    found.into_iter().unzip()
}

/// Parameters of `from`'s side expressed on `to`'s side (through [0, 1]; reversed or not).
fn map_params(
    params: &[f64],
    from: &ParamDomain,
    from_side: Side,
    to: &ParamDomain,
    to_side: Side,
    reversed: bool,
) -> Vec<f64> {
    let (fd, td) = (from_side.along(), to_side.along());
    let (flo, fhi, tlo, thi) = (from.lo[fd], from.hi[fd], to.lo[td], to.hi[td]);
    let mut out: Vec<f64> = params
        .iter()
        .map(|&t| {
            let mut s = (t - flo) / (fhi - flo);
            if reversed {
                s = 1.0 - s;
            }
            if s <= 0.0 {
                tlo
            } else if s >= 1.0 {
                thi
            } else {
                tlo + (thi - tlo) * s
            }
        })
        .collect();
    out.sort_by(f64::total_cmp);
    out
}

fn same_params(a: &[f64], b: &[f64], dom: &ParamDomain, side: Side) -> bool {
    let d = side.along();
    let tol = PARAM_TOLERANCE * (dom.hi[d] - dom.lo[d]);
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
}

/// One mesh from the settled parts: shared border samples welded (their ends are the corners,
/// and a pole vertex is on both sides that end at it, so corners and poles where patches meet
/// are welded through the borders); the vertex of the lowest surface kept. Corners that only
/// touch, with no border between them (the teapot's handle end on the body), stay apart: a
/// weld there would make a vertex with two fans, not close a crack.
fn weld(
    surfaces: &[NurbsSurface],
    doms: &[ParamDomain],
    groups: &[BorderGroup],
    parts: Parts,
    measure: bool,
) -> Result<Tessellation, TessError> {
    let meshes = parts.meshes;
    let mut offset = Vec::with_capacity(meshes.len() + 1);
    offset.push(0usize);
    for t in &meshes {
        offset.push(offset[offset.len() - 1] + t.mesh.positions.len());
    }
    let total = offset[meshes.len()];
    if total > u32::MAX as usize {
        return Err(TessError::VertexLimit {
            needed: total as u128,
        });
    }
    let mut parent: Vec<u32> = (0..total as u32).collect();
    // Shared border samples, by index along the border.
    for group in groups {
        let owner = group.members[0];
        let (_, owner_ids) = side_samples(
            &meshes[owner.surface].mesh,
            &doms[owner.surface],
            owner.side,
        );
        for (k, &member) in group.members.iter().enumerate().skip(1) {
            let (_, ids) = side_samples(
                &meshes[member.surface].mesh,
                &doms[member.surface],
                member.side,
            );
            if ids.len() != owner_ids.len() {
                return Err(TessError::Join(format!(
                    "border {} of surface {} has {} samples and its neighbour {}",
                    member.side.name(),
                    member.surface,
                    ids.len(),
                    owner_ids.len()
                )));
            }
            let n = ids.len();
            for (x, &id) in ids.iter().enumerate() {
                let y = if group.reversed[k] { n - 1 - x } else { x };
                union(
                    &mut parent,
                    (offset[owner.surface] + owner_ids[y] as usize) as u32,
                    (offset[member.surface] + id as usize) as u32,
                );
            }
        }
    }
    // Output: representatives in global order; triangles remapped, collapsed ones dropped.
    let mut new_id = vec![u32::MAX; total];
    let mut mesh = TriMesh::default();
    for (s, t) in meshes.iter().enumerate() {
        let m = &t.mesh;
        for v in 0..m.positions.len() {
            let g = offset[s] + v;
            if find(&mut parent, g as u32) as usize == g {
                new_id[g] = mesh.positions.len() as u32;
                mesh.positions.push(m.positions[v]);
                mesh.uvs.push(m.uvs[v]);
                mesh.normals.push(m.normals[v]);
            }
        }
    }
    let mut stats = TessStats::default();
    for (s, t) in meshes.iter().enumerate() {
        for tri in &t.mesh.triangles {
            let ids = tri.map(|v| {
                let r = find(&mut parent, (offset[s] + v as usize) as u32);
                new_id[r as usize]
            });
            if ids[0] != ids[1] && ids[1] != ids[2] && ids[0] != ids[2] {
                mesh.triangles.push(ids);
            }
        }
        let deviation = if measure {
            max_deviation(&surfaces[s], &doms[s], &t.mesh)
        } else {
            t.stats.max_deviation
        };
        stats.max_deviation = stats.max_deviation.max(deviation);
        stats.max_level = stats.max_level.max(t.stats.max_level);
        stats.rounds = stats.rounds.max(t.stats.rounds);
        stats.patch_levels.extend_from_slice(&t.stats.patch_levels);
        stats
            .border_levels
            .extend_from_slice(&t.stats.border_levels);
    }
    stats.triangles = mesh.triangles.len();
    stats.vertices = mesh.positions.len();
    Ok(Tessellation { mesh, stats })
}

fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        parent[x as usize] = parent[parent[x as usize] as usize];
        x = parent[x as usize];
    }
    x
}

fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra.max(rb) as usize] = ra.min(rb);
    }
}
