//! Merge by distance and mirror (seed 000 §3.3, the *Modify* category,
//! whose examples name *mirror*; DESIGN.md pillar 1: "mirror with merge …
//! merge by distance").
//!
//! # Merge by distance
//!
//! [`merge_by_distance`] welds vertices that lie within `distance` of each
//! other. "Within distance" is not transitive, so clusters are the
//! connected components of the within-distance graph (union-find): a chain
//! of points each within `distance` of the next becomes one vertex even if
//! its ends are far apart. Each cluster keeps its **lowest-id vertex, at its
//! own position**; the others are glued onto it. Both rules depend only on
//! the set of vertices, never on visiting or input order, so permuted inputs
//! give identical meshes.
//!
//! Neighbours are found on a grid of cell size `distance` (27-cell
//! neighbourhood, visited as the cell itself plus 13 "forward" cells so each
//! pair of cells is looked at once), kept as a sorted list swept with
//! forward-only cursors: a sort plus linear work for bounded density.
//! `distance == 0` merges exactly coincident positions only, by sorting the
//! coordinates' bits (with −0 folded onto +0).
//!
//! The topology is then rewritten with Euler operators only:
//! 1. A face touching a merged vertex is *clean* when its vertices still map
//!    to distinct survivors: it simply follows the glue below and keeps its id
//!    and attributes. Otherwise it is *degenerate*: its ring and attributes
//!    are recorded and it is killed ([`Mesh::kill_face`]).
//! 2. Each merged vertex is glued onto its survivor ([`Mesh::glue_verts`]),
//!    in ascending id order. No remaining face holds two vertices of one
//!    cluster, so every glue is legal; edges between a vertex and its
//!    survivor collapse away, edges that become parallel merge (wire edges
//!    between survivors are kept).
//! 3. A clean face that now has the same vertex set as another face (two
//!    welded coincident faces) is killed, unless that other face is itself a
//!    later clean face: of twins, an untouched face wins, then the lowest id.
//! 4. Each degenerate ring, with consecutive repeats removed, is split into
//!    its simple sub-cycles; those of three or more vertices that do not
//!    duplicate an existing face are remade ([`Mesh::make_face`]) with the
//!    original face's attributes.
//!
//! `faces_removed` counts the faces that did not come back: degenerate faces
//! with no remade piece, and clean faces killed as duplicates. A face split
//! into several pieces counts as kept.
//!
//! # Mirror
//!
//! [`mirror`] duplicates a selection, reflects the copies across a plane,
//! flips their winding (a reflection turns faces inside out), and welds
//! copies to originals near the plane. On the seam the original vertex is
//! always the one kept, so the original elements keep their ids.

use glam::DVec3;
use rustc_hash::FxHashMap;

use super::delete::duplicate_mapped;
use crate::geom::UnionFind;

use super::{canonical, OpError, Selection};
use crate::kernel::attrs::AttrValue;
use crate::kernel::ids::{Domain, FaceId, VertId};
use crate::kernel::mesh::Mesh;

/// What [`merge_by_distance`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MergeResult {
    /// Vertices removed (glued onto a survivor).
    pub merged: usize,
    /// The input vertices still alive, one per cluster, sorted.
    pub survivors: Vec<VertId>,
    /// Faces that did not come back (see the module overview).
    pub faces_removed: usize,
    /// Faces made from the pieces of degenerate faces, ascending.
    pub remade: Vec<FaceId>,
}

/// Welds the given vertices that lie within `distance` of each other (see
/// the module overview). `distance` must be finite and non-negative.
pub fn merge_by_distance(
    mesh: &mut Mesh,
    verts: &[VertId],
    distance: f64,
) -> Result<MergeResult, OpError> {
    check_distance("distance", distance)?;
    let verts = canonical(verts);
    for &v in &verts {
        mesh.check_vert(v)?;
    }
    let positions: Vec<DVec3> = verts.iter().map(|&v| mesh.position(v)).collect();
    // Union by lower index and ids sorted: each root is its cluster's
    // lowest id, which is the survivor.
    let targets = cluster_roots(&positions, distance);
    weld(mesh, &verts, &targets)
}

/// Duplicates `selection`, reflects the copies across the plane through
/// `plane_point` with normal `plane_normal`, reverses their winding, then
/// merges by distance (`merge_distance`, same clusters as
/// [`merge_by_distance`]) the vertices of the selection and of the copy
/// that lie within `merge_distance` of the plane, keeping an original in
/// each cluster (the lowest id) so original ids survive. Like a
/// remove-doubles pass, this also welds originals that close to each other
/// on the seam. A copied face that comes to coincide with an original (a
/// face lying in the plane) is dropped as a duplicate.
///
/// Returns the copies still alive after the weld. (A copied face that loses
/// a corner is remade, possibly in a slot the weld freed.)
pub fn mirror(
    mesh: &mut Mesh,
    selection: &Selection,
    plane_point: DVec3,
    plane_normal: DVec3,
    merge_distance: f64,
) -> Result<Selection, OpError> {
    if !plane_point.is_finite() {
        return Err(OpError::parameter("plane_point", "must be finite"));
    }
    if !plane_normal.is_finite() {
        return Err(OpError::parameter("plane_normal", "must be finite"));
    }
    let Some(normal) = plane_normal.try_normalize() else {
        return Err(OpError::parameter("plane_normal", "must not be zero"));
    };
    check_distance("merge_distance", merge_distance)?;

    let signed = |p: DVec3| (p - plane_point).dot(normal);
    let reflect = |p: DVec3| p - 2.0 * signed(p) * normal;
    // Check every id and reflected position first, so a dead id or an
    // overflow is refused before anything is made.
    let mut touched: Vec<VertId> = selection.verts.clone();
    for &e in &selection.edges {
        mesh.check_edge(e)?;
        touched.extend(mesh.edge_verts(e));
    }
    for &f in &selection.faces {
        mesh.check_face(f)?;
        touched.extend(mesh.face_verts(f));
    }
    for v in canonical(&touched) {
        mesh.check_vert(v)?;
        if !reflect(mesh.position(v)).is_finite() {
            return Err(OpError::parameter(
                "plane_point",
                format!("reflecting {v} overflows"),
            ));
        }
    }

    let dup = duplicate_mapped(mesh, selection)?;
    for &(_, copy) in &dup.vert_pairs {
        let p = mesh.position(copy);
        mesh.set_position(copy, reflect(p));
    }
    for &f in &dup.copies.faces {
        // Also refreshes the stored normal from the reflected positions.
        mesh.reverse_face(f)?;
    }

    // Seam candidates: the pairs whose original (and so its copy) lies
    // within merge_distance of the plane. Two points on opposite sides of
    // the plane are at least as far apart as the sum of their distances to
    // it, so no other copy–original pair across it can be that close.
    let mut candidates: Vec<VertId> = Vec::new();
    for &(original, copy) in &dup.vert_pairs {
        if signed(mesh.position(original)).abs() <= merge_distance {
            candidates.push(original);
            candidates.push(copy);
        }
    }
    let candidates = canonical(&candidates);
    let positions: Vec<DVec3> = candidates.iter().map(|&v| mesh.position(v)).collect();
    let roots = cluster_roots(&positions, merge_distance);
    let is_copy = |v: VertId| dup.copies.verts.binary_search(&v).is_ok();
    // Per cluster, keep an original if there is one (lowest id first).
    let rank = |i: usize| (is_copy(candidates[i]), i);
    let mut best: Vec<u32> = (0..candidates.len() as u32).collect();
    for (i, &root) in roots.iter().enumerate() {
        let r = root as usize;
        if rank(i) < rank(best[r] as usize) {
            best[r] = i as u32;
        }
    }
    let targets: Vec<u32> = roots.iter().map(|&r| best[r as usize]).collect();
    weld(mesh, &candidates, &targets)?;

    let copies = dup.copies;
    Ok(Selection {
        verts: copies
            .verts
            .into_iter()
            .filter(|&v| mesh.contains_vert(v))
            .collect(),
        edges: copies
            .edges
            .into_iter()
            .filter(|&e| mesh.contains_edge(e))
            .collect(),
        faces: copies
            .faces
            .into_iter()
            .filter(|&f| mesh.contains_face(f))
            .collect(),
    })
}

fn check_distance(name: &'static str, distance: f64) -> Result<(), OpError> {
    if !distance.is_finite() || distance < 0.0 {
        return Err(OpError::parameter(
            name,
            format!("must be finite and not negative, got {distance}"),
        ));
    }
    Ok(())
}

// ---- clustering ----

/// Up to this many points [`cluster_roots`] compares every pair.
const SMALL_CLUSTER_INPUT: usize = 24;

/// For each point, the lowest index of its cluster: the connected component
/// of the graph joining points at most `distance` apart.
pub(super) fn cluster_roots(points: &[DVec3], distance: f64) -> Vec<u32> {
    if points.len() <= SMALL_CLUSTER_INPUT {
        // A grammar command's merge often looks at a handful of points;
        // the sort below costs a fixed few microseconds, the pairs nothing.
        let mut sets = UnionFind::new(points.len());
        for (i, p) in points.iter().enumerate() {
            for (j, q) in points.iter().enumerate().skip(i + 1) {
                let close = if distance > 0.0 {
                    within(*p, *q, distance)
                } else {
                    p.x == q.x && p.y == q.y && p.z == q.z
                };
                if close {
                    sets.union(i as u32, j as u32);
                }
            }
        }
        return (0..points.len() as u32).map(|i| sets.find(i)).collect();
    }
    if distance > 0.0 {
        return grid_roots(points, distance);
    }
    // Exact coincidence: sort by the coordinates' bits; equal runs are the
    // clusters. Adding +0 folds −0 onto +0, so equal coordinates have
    // equal bits.
    let mut sets = UnionFind::new(points.len());
    let mut keyed: Vec<([u64; 3], u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            (
                [
                    (p.x + 0.0).to_bits(),
                    (p.y + 0.0).to_bits(),
                    (p.z + 0.0).to_bits(),
                ],
                i as u32,
            )
        })
        .collect();
    keyed.sort_unstable();
    for pair in keyed.windows(2) {
        if pair[0].0 == pair[1].0 {
            sets.union(pair[0].1, pair[1].1);
        }
    }
    (0..points.len() as u32).map(|i| sets.find(i)).collect()
}

/// [`cluster_roots`] for `distance > 0`, on a grid of cell size `distance`:
/// two points at most `distance` apart lie in the same or adjacent cells.
///
/// The grid is a sorted list rather than a hash map: cells are packed into
/// integers and sorted with the point index as tie-break, and the
/// forward neighbours of each cell are found by five cursors, one per
/// neighbouring row of cells, that only move forward as the cells are
/// visited in order. A linear sort plus a linear sweep over sequential
/// memory; hashing a million points into cells and probing 13 neighbours
/// each was measured about twice as slow.
fn grid_roots(points: &[DVec3], distance: f64) -> Vec<u32> {
    let cells: Vec<[i64; 3]> = points
        .iter()
        .map(|p| {
            [
                cell_coordinate(p.x, distance),
                cell_coordinate(p.y, distance),
                cell_coordinate(p.z, distance),
            ]
        })
        .collect();
    let (mut low, mut high) = ([i64::MAX; 3], [i64::MIN; 3]);
    for c in &cells {
        for axis in 0..3 {
            low[axis] = low[axis].min(c[axis]);
            high[axis] = high[axis].max(c[axis]);
        }
    }
    // Bits per axis for coordinates shifted to 1..=span+1, so that a
    // neighbour step (±1) never leaves its bit field: span + 2 < 2^bits.
    let bits: Vec<u32> = (0..3)
        .map(|axis| {
            let span = i128::from(high[axis]) - i128::from(low[axis]) + 2;
            128 - (span as u128).leading_zeros()
        })
        .collect();
    if bits.iter().sum::<u32>() <= 64 {
        // Fast path: the cell packed into one u64 (x | y | z).
        let (shift_y, shift_x) = (bits[2], bits[1] + bits[2]);
        let keys: Vec<u64> = cells
            .iter()
            .map(|c| {
                let field = |axis: usize| (c[axis] - low[axis] + 1) as u64;
                field(0) << shift_x | field(1) << shift_y | field(2)
            })
            .collect();
        drop(cells);
        let (cell_keys, order) = radix_sort(keys, bits.iter().sum());
        let step = |k: u64, [dx, dy, dz]: [i64; 3]| {
            let offset = (dx << shift_x) + (dy << shift_y) + dz;
            k.wrapping_add(offset as u64)
        };
        gathered_roots(&cell_keys, &order, points, distance, step)
    } else {
        // Cells spanning more than 2⁶⁴ in all: sort the coordinates as they are.
        let mut keyed: Vec<([i64; 3], u32)> = cells.into_iter().zip(0u32..).collect();
        keyed.sort_unstable();
        let order: Vec<u32> = keyed.iter().map(|&(_, i)| i).collect();
        let cell_keys: Vec<[i64; 3]> = keyed.into_iter().map(|(c, _)| c).collect();
        let step = |k: [i64; 3], d: [i64; 3]| {
            [
                k[0].saturating_add(d[0]),
                k[1].saturating_add(d[1]),
                k[2].saturating_add(d[2]),
            ]
        };
        gathered_roots(&cell_keys, &order, points, distance, step)
    }
}

/// `floor(x / distance)` as an integer. `as` saturates: absurdly far points
/// share an end cell, which only costs comparisons, never correctness (real
/// distances are checked). Truncation plus a correction instead of
/// `f64::floor`, which is a library call on baseline x86-64.
#[inline]
pub(super) fn cell_coordinate(x: f64, distance: f64) -> i64 {
    let q = x / distance;
    let t = q as i64;
    if (t as f64) > q {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// Sorts `keys` (of `bits` significant bits), returning the sorted keys
/// and, for each, its original index; equal keys stay in index order. One
/// radix pass on the top 11 bits spreads the keys into cache-sized buckets,
/// each then sorted by (key, index): linear for spread-out keys, and never
/// worse than a comparison sort for clumped ones.
fn radix_sort(keys: Vec<u64>, bits: u32) -> (Vec<u64>, Vec<u32>) {
    const DIGIT: u32 = 11;
    const BUCKETS: usize = 1 << DIGIT;
    let shift = bits.saturating_sub(DIGIT);
    let bucket = |k: u64| (k >> shift) as usize & (BUCKETS - 1);
    let mut start = vec![0usize; BUCKETS + 1];
    for &k in &keys {
        start[bucket(k) + 1] += 1;
    }
    for b in 0..BUCKETS {
        start[b + 1] += start[b];
    }
    let mut next = start.clone();
    let mut pairs = vec![(0u64, 0u32); keys.len()];
    for (i, &k) in keys.iter().enumerate() {
        let b = bucket(k);
        pairs[next[b]] = (k, i as u32);
        next[b] += 1;
    }
    drop(keys);
    for b in 0..BUCKETS {
        pairs[start[b]..start[b + 1]].sort_unstable();
    }
    pairs.into_iter().unzip()
}

/// Whether `a` and `b` are at most `distance` apart. Uses the hardware
/// square root (`f64::sqrt` is correctly rounded by IEEE 754, so the same on
/// every platform; glam's `length` goes through the much slower software
/// `libm`). Squares that overflow or underflow are compared scaled instead.
#[inline]
fn within(a: DVec3, b: DVec3, distance: f64) -> bool {
    let diff = a - b;
    let square = diff.length_squared();
    if square.is_normal() {
        square.sqrt() <= distance
    } else {
        (diff / distance).length_squared() <= 1.0
    }
}

/// The forward neighbour rows of a cell, as (dx, dy, lowest dz, highest
/// dz): with the cell itself, and mirrored, they cover all 27 cells, and
/// each pair of neighbouring cells is met exactly once (from the lower one).
const FORWARD_ROWS: [(i64, i64, i64, i64); 5] = [
    (0, 0, 1, 1),
    (0, 1, -1, 1),
    (1, -1, -1, 1),
    (1, 0, -1, 1),
    (1, 1, -1, 1),
];

/// Sweeps the grid (see [`sweep`]) over the points gathered in cell order,
/// then maps the clusters back: for each input point, the lowest input
/// index of its cluster. Gathering first turns the pair tests' scattered
/// reads into sequential ones (most of the cost at a million points).
fn gathered_roots<K: Copy + Ord>(
    sorted_cells: &[K],
    order: &[u32],
    points: &[DVec3],
    distance: f64,
    step: impl Fn(K, [i64; 3]) -> K,
) -> Vec<u32> {
    let gathered: Vec<DVec3> = order.iter().map(|&i| points[i as usize]).collect();
    let mut sets = UnionFind::new(order.len());
    sweep(sorted_cells, &gathered, distance, &mut sets, step);
    let mut lowest = vec![u32::MAX; order.len()];
    for (k, &i) in order.iter().enumerate() {
        let root = sets.find(k as u32) as usize;
        lowest[root] = lowest[root].min(i);
    }
    let mut roots = vec![0u32; order.len()];
    for (k, &i) in order.iter().enumerate() {
        roots[i as usize] = lowest[sets.find(k as u32) as usize];
    }
    roots
}

/// Unions, in `sets`, every pair of `points` at most `distance` apart.
/// `sorted_cells[k]` is the cell of point `k`, ascending; `step` moves a
/// cell key by a cell offset, preserving order (lexicographic x, y, z), so
/// each row cursor only ever moves forward.
fn sweep<K: Copy + Ord>(
    sorted_cells: &[K],
    points: &[DVec3],
    distance: f64,
    sets: &mut UnionFind,
    step: impl Fn(K, [i64; 3]) -> K,
) {
    // Runs of equal keys: cell c holds points start[c]..start[c + 1].
    let mut keys: Vec<K> = Vec::new();
    let mut start: Vec<usize> = Vec::new();
    for (k, &cell) in sorted_cells.iter().enumerate() {
        if keys.last() != Some(&cell) {
            keys.push(cell);
            start.push(k);
        }
    }
    start.push(sorted_cells.len());
    let link = |sets: &mut UnionFind, i: usize, j: usize| {
        // Same set already is the common case inside a cluster, and cheaper.
        let (a, b) = (i as u32, j as u32);
        if sets.find(a) != sets.find(b) && within(points[i], points[j], distance) {
            sets.union(a, b);
        }
    };

    let mut cursors = [0usize; FORWARD_ROWS.len()];
    for (c, &key) in keys.iter().enumerate() {
        let here = start[c]..start[c + 1];
        for i in here.clone() {
            for j in i + 1..here.end {
                link(sets, i, j);
            }
        }
        for (row, &(dx, dy, z_low, z_high)) in FORWARD_ROWS.iter().enumerate() {
            let first = step(key, [dx, dy, z_low]);
            let last = step(key, [dx, dy, z_high]);
            let cursor = &mut cursors[row];
            while *cursor < keys.len() && keys[*cursor] < first {
                *cursor += 1;
            }
            let mut d = *cursor;
            while d < keys.len() && keys[d] <= last {
                // Only a saturated key (coordinates near ±2⁶³ cells) can
                // land on the cell itself or behind it.
                if d > c {
                    for i in here.clone() {
                        for j in start[d]..start[d + 1] {
                            link(sets, i, j);
                        }
                    }
                }
                d += 1;
            }
        }
    }
}

// ---- topology rewrite ----

/// A degenerate face, recorded before it is killed.
struct Degenerate {
    /// Its ring mapped to survivors (may repeat vertices).
    ring: Vec<VertId>,
    /// Its value in each face layer, in layer order.
    attrs: Vec<AttrValue>,
}

/// Glues `verts[i]` onto `verts[targets[i]]` wherever they differ (each
/// target is its own target) and rewrites the faces around them.
fn weld(mesh: &mut Mesh, verts: &[VertId], targets: &[u32]) -> Result<MergeResult, OpError> {
    let mut gone: Vec<(VertId, VertId)> = Vec::new();
    let mut survivors = Vec::new();
    for (i, &t) in targets.iter().enumerate() {
        if t as usize == i {
            survivors.push(verts[i]);
        } else {
            gone.push((verts[i], verts[t as usize]));
        }
    }
    weld_gone(mesh, gone, survivors)
}

/// Glues each `(vertex, survivor)` of `gone` (ascending by vertex; no
/// survivor is itself glued) and repairs the faces, steps 1–4 of the module
/// overview. `survivors` is reported back as given.
pub(super) fn weld_gone(
    mesh: &mut Mesh,
    gone: Vec<(VertId, VertId)>,
    survivors: Vec<VertId>,
) -> Result<MergeResult, OpError> {
    let mut result = MergeResult {
        merged: gone.len(),
        survivors,
        faces_removed: 0,
        remade: Vec::new(),
    };
    if gone.is_empty() {
        return Ok(result);
    }
    let mut affected: Vec<FaceId> = gone.iter().flat_map(|&(v, _)| mesh.vert_faces(v)).collect();
    affected.sort_unstable();
    affected.dedup();

    let face_layers: Vec<String> = mesh
        .attributes()
        .layers()
        .iter()
        .filter(|l| l.domain == Domain::Face)
        .map(|l| l.name.clone())
        .collect();
    let mut clean = Vec::with_capacity(affected.len());
    let mut degenerate = Vec::new();
    if !affected.is_empty() {
        let map = SurvivorMap::new(mesh.vert_capacity(), &gone);
        let mut ring: Vec<VertId> = Vec::new();
        let mut sorted: Vec<VertId> = Vec::new();
        for &f in &affected {
            ring.clear();
            ring.extend(mesh.face_verts(f).map(|v| map.get(v)));
            sorted.clear();
            sorted.extend_from_slice(&ring);
            sorted.sort_unstable();
            if sorted.windows(2).any(|w| w[0] == w[1]) {
                let attrs = face_layers
                    .iter()
                    .filter_map(|name| mesh.attr(name, Domain::Face, f.index()))
                    .collect();
                degenerate.push(Degenerate {
                    ring: ring.clone(),
                    attrs,
                });
            } else {
                clean.push(f);
            }
        }
    }
    // Step 1: no face may hold two vertices of one cluster when gluing.
    for &f in &affected {
        if clean.binary_search(&f).is_err() {
            mesh.kill_face(f)?;
        }
    }
    // Step 2: glue (never refused: see the module overview). An isolated
    // vertex carries nothing to glue: killing it is the same, and cheaper.
    for &(v, keep) in &gone {
        if mesh.vert_degree(v) == 0 {
            mesh.kill_vert(v)?;
        } else {
            mesh.glue_verts(keep, v)?;
        }
    }
    // Step 3: welded twins.
    let is_affected = |g: FaceId| affected.binary_search(&g).is_ok();
    for &f in &clean {
        let ring: Vec<VertId> = mesh.face_verts(f).collect();
        if twin(mesh, &ring, |g| g != f && (!is_affected(g) || g < f)).is_some() {
            mesh.kill_face(f)?;
            result.faces_removed += 1;
        }
    }
    // Step 4: remake the pieces of degenerate faces.
    for face in degenerate {
        let mut made_any = false;
        for piece in simple_cycles(face.ring) {
            if twin(mesh, &piece, |_| true).is_some() {
                continue;
            }
            let f = mesh.make_face(&piece)?;
            for (name, &value) in face_layers.iter().zip(&face.attrs) {
                mesh.set_attr(name, Domain::Face, f.index(), value);
            }
            result.remade.push(f);
            made_any = true;
        }
        if !made_any {
            result.faces_removed += 1;
        }
    }
    result.remade.sort_unstable();
    Ok(result)
}

/// Merged vertex → survivor. A dense table by slot when the merge touches a
/// good share of the mesh (no hashing), a hash map when it is a few
/// vertices of a large mesh (no table the size of the mesh).
enum SurvivorMap {
    Dense(Vec<u32>),
    Sparse(FxHashMap<VertId, VertId>),
}

impl SurvivorMap {
    const NONE: u32 = u32::MAX;

    fn new(capacity: usize, gone: &[(VertId, VertId)]) -> Self {
        if capacity <= 8 * gone.len() {
            let mut table = vec![Self::NONE; capacity];
            for &(v, keep) in gone {
                table[v.index()] = keep.index() as u32;
            }
            SurvivorMap::Dense(table)
        } else {
            SurvivorMap::Sparse(gone.iter().copied().collect())
        }
    }

    /// The survivor of `v`, or `v` itself if it is not merged away.
    fn get(&self, v: VertId) -> VertId {
        match self {
            SurvivorMap::Dense(table) => match table[v.index()] {
                Self::NONE => v,
                keep => VertId::from_index(keep as usize),
            },
            SurvivorMap::Sparse(map) => map.get(&v).copied().unwrap_or(v),
        }
    }
}

/// A face other than those `accept` refuses, with the same vertex set as
/// `ring` (the test of [`Mesh::find_face`], with a filter).
fn twin(mesh: &Mesh, ring: &[VertId], accept: impl Fn(FaceId) -> bool) -> Option<FaceId> {
    let e = mesh.find_edge(ring[0], ring[1])?;
    let mut key = ring.to_vec();
    key.sort_unstable();
    let mut other = Vec::with_capacity(ring.len());
    mesh.edge_faces(e).find(|&g| {
        if !accept(g) || mesh.face_len(g) != ring.len() {
            return false;
        }
        other.clear();
        other.extend(mesh.face_verts(g));
        other.sort_unstable();
        other == key
    })
}

/// Splits a closed walk of vertices into simple cycles of three or more
/// vertices, keeping its winding: consecutive repeats (also around the
/// end) vanish; whenever a vertex comes back, the loop since its last visit
/// is cut off. A ring of fewer than three distinct vertices gives nothing.
fn simple_cycles(mut ring: Vec<VertId>) -> Vec<Vec<VertId>> {
    ring.dedup();
    while ring.len() > 1 && ring.first() == ring.last() {
        ring.pop();
    }
    let mut out = Vec::new();
    let mut path: Vec<VertId> = Vec::with_capacity(ring.len());
    let mut at: FxHashMap<VertId, usize> = FxHashMap::default();
    for v in ring {
        if let Some(&i) = at.get(&v) {
            let mut cycle = vec![v];
            for w in path.drain(i + 1..) {
                at.remove(&w);
                cycle.push(w);
            }
            if cycle.len() >= 3 {
                out.push(cycle);
            }
        } else {
            at.insert(v, path.len());
            path.push(v);
        }
    }
    if path.len() >= 3 {
        out.push(path);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::ids::EdgeId;
    use crate::kernel::ops::create::tests::{
        euler_characteristic, is_closed_manifold, signed_volume,
    };
    use crate::kernel::ops::create::{create_cube, create_cylinder, create_grid};
    use crate::kernel::ops::delete::{delete, DeleteMode};
    use crate::kernel::ops::select::select_from_faces;
    use crate::kernel::ops::transform::translate;
    use crate::kernel::KernelError;

    fn v3(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z)
    }

    fn all_verts(m: &Mesh) -> Vec<VertId> {
        m.vert_ids().collect()
    }

    fn merge_all(m: &mut Mesh, distance: f64) -> Result<MergeResult, OpError> {
        let verts = all_verts(m);
        merge_by_distance(m, &verts, distance)
    }

    type Fingerprint = (
        Vec<(VertId, [f64; 3])>,
        Vec<(EdgeId, [VertId; 2])>,
        Vec<(FaceId, Vec<VertId>)>,
    );

    /// Every element with its id, position or vertices: equal fingerprints
    /// mean identical meshes.
    fn fingerprint(m: &Mesh) -> Fingerprint {
        (
            m.vert_ids()
                .map(|v| (v, m.position(v).to_array()))
                .collect(),
            m.edge_ids().map(|e| (e, m.edge_verts(e))).collect(),
            m.face_ids()
                .map(|f| (f, m.face_verts(f).collect()))
                .collect(),
        )
    }

    /// SplitMix64: a tiny portable generator for test data.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
        fn unit(&mut self) -> f64 {
            (self.next() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
        }
    }

    /// Two 2-unit cubes side by side, touching along x = 1.
    fn two_cubes() -> Mesh {
        let mut m = Mesh::new();
        create_cube(&mut m, 2.0).unwrap();
        let b = create_cube(&mut m, 2.0).unwrap();
        translate(&mut m, &b.verts, v3(2.0, 0.0, 0.0)).unwrap();
        m
    }

    #[test]
    fn two_cubes_sharing_a_face_weld_into_twelve_verts() {
        let mut m = two_cubes();
        let r = merge_all(&mut m, 1e-6).unwrap();
        m.validate().unwrap();
        assert_eq!(r.merged, 4);
        assert_eq!(r.survivors.len(), 12);
        // The coincident faces became twins: one stays, inside the block.
        assert_eq!(r.faces_removed, 1);
        assert_eq!(
            (m.vert_count(), m.edge_count(), m.face_count()),
            (12, 20, 11)
        );
        let inner = m.edge_ids().filter(|&e| m.edge_face_count(e) == 3).count();
        assert_eq!(inner, 4);
        // Survivors are the first cube's vertices, unmoved.
        assert!(r.survivors[..8].iter().all(|v| v.index() < 8));
    }

    #[test]
    fn two_open_boxes_weld_into_one_closed_box() {
        let mut m = two_cubes();
        // Remove the touching faces (+X of the first, −X of the second).
        let touching: Vec<FaceId> = m
            .face_ids()
            .filter(|&f| (m.face_center(f).x - 1.0).abs() < 1e-12)
            .collect();
        assert_eq!(touching.len(), 2);
        delete(
            &mut m,
            &Selection::from_parts(vec![], vec![], touching),
            DeleteMode::Faces,
        )
        .unwrap();
        let r = merge_all(&mut m, 1e-6).unwrap();
        m.validate().unwrap();
        assert_eq!((r.merged, r.faces_removed), (4, 0));
        assert_eq!(
            (m.vert_count(), m.edge_count(), m.face_count()),
            (12, 20, 10)
        );
        assert!(is_closed_manifold(&m));
        assert_eq!(euler_characteristic(&m), 2);
        assert!((signed_volume(&m) - 16.0).abs() < 1e-12);
    }

    #[test]
    fn permuted_inputs_give_identical_meshes() {
        let build = || {
            let mut m = two_cubes();
            // Add near-coincident noise so clusters are not trivial.
            let extra = create_cube(&mut m, 2.0).unwrap();
            translate(&mut m, &extra.verts, v3(1e-4, -1e-4, 2.0)).unwrap();
            m
        };
        let mut a = build();
        let mut b = build();
        let mut order = all_verts(&b);
        order.reverse();
        order.rotate_left(5);
        order.push(order[3]);
        let ra = merge_all(&mut a, 1e-3).unwrap();
        let rb = merge_by_distance(&mut b, &order, 1e-3).unwrap();
        a.validate().unwrap();
        assert_eq!(ra, rb);
        assert_eq!(fingerprint(&a), fingerprint(&b));
        assert!(ra.merged >= 8);
    }

    #[test]
    fn chains_within_distance_merge_transitively_onto_the_lowest_id() {
        let mut m = Mesh::new();
        // Lowest id in the middle of the chain; each link 0.9 apart.
        let mid = m.make_vert(v3(0.9, 0.0, 0.0));
        let left = m.make_vert(v3(0.0, 0.0, 0.0));
        let right = m.make_vert(v3(1.8, 0.0, 0.0));
        let far = m.make_vert(v3(2.7, 0.0, 0.0));
        let alone = m.make_vert(v3(5.0, 0.0, 0.0));
        let r = merge_by_distance(&mut m, &[far, alone, right, left, mid], 1.0).unwrap();
        m.validate().unwrap();
        assert_eq!(r.merged, 3);
        assert_eq!(r.survivors, vec![mid, alone]);
        assert_eq!(
            m.position(mid),
            v3(0.9, 0.0, 0.0),
            "the survivor keeps its own position"
        );
        assert_eq!(m.vert_count(), 2);
    }

    #[test]
    fn zero_distance_merges_exact_coincidence_only() {
        let mut m = Mesh::new();
        let a = m.make_vert(v3(0.0, 1.0, 2.0));
        let b = m.make_vert(v3(-0.0, 1.0, 2.0));
        let c = m.make_vert(v3(1e-300, 1.0, 2.0));
        let d = m.make_vert(v3(0.0, 1.0, 2.0));
        let r = merge_by_distance(&mut m, &[a, b, c, d], 0.0).unwrap();
        m.validate().unwrap();
        assert_eq!(r.merged, 2);
        assert_eq!(r.survivors, vec![a, c]);
    }

    #[test]
    fn bad_parameters_and_dead_ids_are_errors() {
        let mut m = two_cubes();
        let verts = all_verts(&m);
        for d in [-1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                merge_by_distance(&mut m, &verts, d),
                Err(OpError::Parameter { .. })
            ));
        }
        assert!(matches!(
            merge_by_distance(&mut m, &[VertId::from_index(999)], 1.0),
            Err(OpError::Kernel(KernelError::Dead { .. }))
        ));
        assert_eq!(m.vert_count(), 16);
        let r = merge_by_distance(&mut m, &[], 1.0).unwrap();
        assert_eq!(r, MergeResult::default());
    }

    #[test]
    fn collapsing_faces_lose_corners_keep_attributes_or_vanish() {
        use crate::kernel::{AttrValue, Domain};
        let mut m = Mesh::new();
        m.add_layer("tag", Domain::Face, AttrValue::Int(0)).unwrap();
        // A quad whose last two corners coincide, and a sliver triangle.
        let q: Vec<VertId> = [
            v3(0.0, 0.0, 0.0),
            v3(1.0, 0.0, 0.0),
            v3(1.0, 1.0, 0.0),
            v3(1.0, 1.0, 0.0),
        ]
        .iter()
        .map(|&p| m.make_vert(p))
        .collect();
        let quad = m.make_face(&q).unwrap();
        m.set_attr("tag", Domain::Face, quad.index(), AttrValue::Int(4));
        let t: Vec<VertId> = [v3(5.0, 0.0, 0.0), v3(6.0, 0.0, 0.0), v3(6.0, 0.0, 0.0)]
            .iter()
            .map(|&p| m.make_vert(p))
            .collect();
        m.make_face(&t).unwrap();
        let r = merge_all(&mut m, 1e-9).unwrap();
        m.validate().unwrap();
        assert_eq!((r.merged, r.faces_removed), (2, 1));
        assert_eq!(m.face_count(), 1);
        let f = m.face_ids().next().unwrap();
        assert_eq!(m.face_verts(f).collect::<Vec<_>>(), vec![q[0], q[1], q[2]]);
        assert_eq!(
            m.attr("tag", Domain::Face, f.index()),
            Some(AttrValue::Int(4))
        );
        assert!((m.face_normal(f) - DVec3::Z).length() < 1e-12);
        // The sliver's long edge stays as a wire edge between survivors;
        // the edge between the merged pair vanished.
        assert_eq!(m.edge_count(), 4);
        assert!(m.find_edge(t[0], t[1]).is_some_and(|e| m.is_wire_edge(e)));
    }

    #[test]
    fn a_pinched_ring_splits_into_simple_faces() {
        let mut m = Mesh::new();
        // A hexagon whose corners 0 and 3 meet in the middle: a bow tie.
        let ring: Vec<VertId> = [
            v3(0.0, 0.0, 0.0),
            v3(1.0, -1.0, 0.0),
            v3(1.0, 1.0, 0.0),
            v3(0.0, 0.0, 0.0),
            v3(-1.0, 1.0, 0.0),
            v3(-1.0, -1.0, 0.0),
        ]
        .iter()
        .map(|&p| m.make_vert(p))
        .collect();
        m.make_face(&ring).unwrap();
        let r = merge_by_distance(&mut m, &ring, 1e-9).unwrap();
        m.validate().unwrap();
        assert_eq!((r.merged, r.faces_removed), (1, 0));
        assert_eq!(m.face_count(), 2);
        for f in m.face_ids() {
            assert_eq!(m.face_len(f), 3);
            assert!(m.face_normal(f).z > 0.0, "pieces keep the winding");
        }
        assert_eq!(m.vert_degree(ring[0]), 4);
    }

    #[test]
    fn simple_cycles_of_closed_walks() {
        let v: Vec<VertId> = (0..6).map(VertId::from_index).collect();
        let (a, b, c, d, e) = (v[0], v[1], v[2], v[3], v[4]);
        assert_eq!(simple_cycles(vec![a, b, c]), vec![vec![a, b, c]]);
        assert_eq!(simple_cycles(vec![a, a, b, c, c, a]), vec![vec![a, b, c]]);
        assert_eq!(
            simple_cycles(vec![a, b, c, a, d, e]),
            vec![vec![a, b, c], vec![a, d, e]]
        );
        assert_eq!(
            simple_cycles(vec![b, c, a, d, e, a]),
            vec![vec![a, d, e], vec![b, c, a]]
        );
        assert!(simple_cycles(vec![a, b, a, b]).is_empty());
        assert!(simple_cycles(vec![a, b, a, c]).is_empty());
        assert!(simple_cycles(vec![a, a, a]).is_empty());
    }

    #[test]
    fn welding_a_triangle_soup_rebuilds_the_shared_grid() {
        use crate::kernel::{AttrValue, Domain};
        let mut m = Mesh::new();
        m.add_layer("tag", Domain::Face, AttrValue::Int(0)).unwrap();
        let n = 3;
        for j in 0..n {
            for i in 0..n {
                let p = |di: i32, dj: i32| v3(f64::from(i + di), f64::from(j + dj), 0.0);
                for tri in [[p(0, 0), p(1, 0), p(1, 1)], [p(0, 0), p(1, 1), p(0, 1)]] {
                    let vs: Vec<VertId> = tri.iter().map(|&q| m.make_vert(q)).collect();
                    let f = m.make_face(&vs).unwrap();
                    m.set_attr(
                        "tag",
                        Domain::Face,
                        f.index(),
                        AttrValue::Int(f.index() as i64),
                    );
                }
            }
        }
        let faces_before: Vec<FaceId> = m.face_ids().collect();
        let r = merge_all(&mut m, 1e-9).unwrap();
        m.validate().unwrap();
        assert_eq!((m.vert_count(), m.face_count()), (16, 18));
        assert_eq!(m.edge_count(), 3 * 4 * 2 + 9);
        assert_eq!((r.merged, r.faces_removed), (54 - 16, 0));
        // Clean faces keep their ids and attributes.
        assert_eq!(m.face_ids().collect::<Vec<_>>(), faces_before);
        for f in m.face_ids() {
            assert_eq!(
                m.attr("tag", Domain::Face, f.index()),
                Some(AttrValue::Int(f.index() as i64))
            );
            assert!((m.face_normal(f) - DVec3::Z).length() < 1e-12);
        }
        assert_eq!(euler_characteristic(&m), 1);
    }

    /// The pairwise path for small inputs agrees with the grid's.
    #[test]
    fn small_inputs_cluster_as_the_grid_does() {
        for seed in 0..200u64 {
            let mut rng = Rng(seed);
            let n = 2 + (seed as usize % (SMALL_CLUSTER_INPUT - 1));
            let distance = if seed % 5 == 0 { 0.0 } else { 0.3 };
            let points: Vec<DVec3> = (0..n)
                .map(|_| {
                    // Coarse coordinates, so exact coincidences happen too.
                    let q = |x: f64| (x * 4.0).floor() / 4.0;
                    v3(q(rng.unit()), q(rng.unit()), q(rng.unit()))
                })
                .collect();
            let expected = if distance > 0.0 {
                grid_roots(&points, distance)
            } else {
                let mut more = points.clone();
                more.resize(SMALL_CLUSTER_INPUT + 1, v3(9.0, 9.0, 9.0));
                cluster_roots(&more, 0.0)[..n].to_vec()
            };
            assert_eq!(cluster_roots(&points, distance), expected, "seed {seed}");
        }
    }

    /// The grid's clusters equal brute-force components, also for points
    /// straddling cell borders and exactly at the distance.
    #[test]
    fn grid_clustering_matches_brute_force() {
        for seed in 0..20u64 {
            let mut rng = Rng(seed);
            let distance = 0.05 + rng.unit() * 0.2;
            let points: Vec<DVec3> = (0..300)
                .map(|_| v3(rng.unit(), rng.unit(), rng.unit() * 0.3))
                .collect();
            let mut sets = UnionFind::new(points.len());
            for i in 0..points.len() {
                for j in i + 1..points.len() {
                    if points[i].distance(points[j]) <= distance {
                        sets.union(i as u32, j as u32);
                    }
                }
            }
            let expected: Vec<u32> = (0..points.len() as u32).map(|i| sets.find(i)).collect();
            assert_eq!(cluster_roots(&points, distance), expected, "seed {seed}");
        }
        // Cells too many to pack into 64 bits (the tuple-sorted path), and
        // saturated cell coordinates: still exact.
        for seed in 0..5u64 {
            let mut rng = Rng(100 + seed);
            let mut points = Vec::new();
            for _ in 0..40 {
                let site = v3(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5) * 2e6;
                for _ in 0..3 {
                    points.push(site + v3(rng.unit(), rng.unit(), 0.0) * 1.5e-6);
                }
            }
            points.push(v3(1e300, -1e300, 0.0));
            points.push(v3(1e300, -1e300, 0.0));
            points.push(v3(9e299, -1e300, 0.0));
            let mut sets = UnionFind::new(points.len());
            for i in 0..points.len() {
                for j in i + 1..points.len() {
                    if within(points[i], points[j], 1e-6) {
                        sets.union(i as u32, j as u32);
                    }
                }
            }
            let expected: Vec<u32> = (0..points.len() as u32).map(|i| sets.find(i)).collect();
            assert_eq!(cluster_roots(&points, 1e-6), expected, "seed {seed}");
            let n = points.len() as u32;
            assert_eq!(expected[n as usize - 2], n - 3);
            assert_eq!(expected[n as usize - 1], n - 1);
        }
        // Exactly at the distance, across a cell border, on negative coordinates.
        let points = [v3(-0.5, 0.0, 0.0), v3(0.5, 0.0, 0.0), v3(-1.5, -1.0, 0.0)];
        assert_eq!(cluster_roots(&points, 1.0), vec![0, 0, 2]);
    }

    #[test]
    fn cell_coordinate_is_floor() {
        let mut rng = Rng(3);
        let mut values = vec![
            0.0, -0.0, -1.0, -0.5, 0.5, 3.0, -3.0, 1e300, -1e300, 4.5e15, -4.5e15,
        ];
        values.extend((0..1000).map(|_| (rng.unit() - 0.5) * 1e6));
        for x in values {
            for d in [1.0, 0.3, 1e-7] {
                let expected = (x / d).floor() as i64;
                assert_eq!(cell_coordinate(x, d), expected, "{x} / {d}");
            }
        }
    }

    #[test]
    fn mirrored_half_grid_is_seamless() {
        let mut m = Mesh::new();
        let g = create_grid(&mut m, 2, 2, 2.0, 2.0).unwrap();
        translate(&mut m, &g.verts, v3(1.0, 0.0, 0.0)).unwrap();
        let copies = mirror(&mut m, &g, DVec3::ZERO, DVec3::X, 1e-6).unwrap();
        m.validate().unwrap();
        assert_eq!((m.vert_count(), m.face_count()), (15, 8));
        assert_eq!((copies.verts.len(), copies.faces.len()), (6, 4));
        assert!(
            g.verts.iter().all(|&v| m.contains_vert(v)),
            "originals survive the weld"
        );
        for f in m.face_ids() {
            assert!(
                (m.face_normal(f) - DVec3::Z).length() < 1e-12,
                "mirrored faces rewound"
            );
        }
        let border: Vec<EdgeId> = m
            .edge_ids()
            .filter(|&e| m.edge_face_count(e) == 1)
            .collect();
        assert_eq!(border.len(), 2 * (4 + 2));
        for e in m.edge_ids() {
            let on_seam = m
                .edge_verts(e)
                .iter()
                .all(|&v| m.position(v).x.abs() < 1e-9);
            if on_seam {
                assert_eq!(m.edge_face_count(e), 2, "seam edge {e} is not welded");
            }
        }
        assert_eq!(euler_characteristic(&m), 1);
    }

    #[test]
    fn mirrored_half_tube_closes_around() {
        let mut m = Mesh::new();
        let tube = create_cylinder(&mut m, 8, 1.0, 1.0, 2.0, false).unwrap();
        let west: Vec<VertId> = tube
            .verts
            .iter()
            .copied()
            .filter(|&v| m.position(v).x < -1e-9)
            .collect();
        delete(
            &mut m,
            &Selection::from_parts(west, vec![], vec![]),
            DeleteMode::All,
        )
        .unwrap();
        assert_eq!((m.vert_count(), m.face_count()), (10, 4));
        let half = select_from_faces(&m, &m.face_ids().collect::<Vec<_>>());
        mirror(&mut m, &half, DVec3::ZERO, v3(-3.0, 0.0, 0.0), 1e-6).unwrap();
        m.validate().unwrap();
        assert_eq!(
            (m.vert_count(), m.edge_count(), m.face_count()),
            (16, 24, 8)
        );
        // Only the two rims are open; every vertical edge has two faces.
        let open = m.edge_ids().filter(|&e| m.edge_face_count(e) == 1).count();
        assert_eq!(open, 16);
        for f in m.face_ids() {
            let (n, c) = (m.face_normal(f), m.face_center(f));
            assert!(n.x * c.x + n.y * c.y > 0.0, "face {f} points inward");
        }
        assert_eq!(euler_characteristic(&m), 0);
    }

    #[test]
    fn mirror_checks_its_plane() {
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 1.0).unwrap();
        assert!(mirror(&mut m, &c, DVec3::ZERO, DVec3::ZERO, 0.0).is_err());
        assert!(mirror(&mut m, &c, DVec3::splat(f64::NAN), DVec3::X, 0.0).is_err());
        assert!(mirror(&mut m, &c, DVec3::ZERO, DVec3::X, -1.0).is_err());
        assert!(
            mirror(&mut m, &c, v3(f64::MAX, 0.0, 0.0), DVec3::X, 0.0).is_err(),
            "overflow"
        );
        assert_eq!(m.vert_count(), 8);
        // A whole cube mirrored off to the side: a second closed cube.
        let copies = mirror(&mut m, &c, v3(2.0, 0.0, 0.0), DVec3::X, 1e-6).unwrap();
        m.validate().unwrap();
        assert_eq!(
            (copies.verts.len(), copies.edges.len(), copies.faces.len()),
            (8, 12, 6)
        );
        assert!((signed_volume(&m) - 2.0).abs() < 1e-12);
    }

    /// Heavy: `cargo test --release --lib merge_a_million -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn merge_a_million_points_in_linear_time() {
        let mut rng = Rng(7);
        let distance = 1e-4;
        // ~166k distinct sites, each repeated 6 times with jitter < ε/4.
        let sites = 1_000_000 / 6;
        let mut m = Mesh::new();
        for _ in 0..sites {
            let site = v3(rng.unit(), rng.unit(), rng.unit()) * 10.0;
            for _ in 0..6 {
                let jitter = v3(rng.unit(), rng.unit(), rng.unit()) * (distance / 8.0);
                m.make_vert(site + jitter);
            }
        }
        let verts = all_verts(&m);
        let positions: Vec<DVec3> = verts.iter().map(|&v| m.position(v)).collect();
        let start = std::time::Instant::now();
        let roots = cluster_roots(&positions, distance);
        println!("clustering alone: {:?}", start.elapsed());
        drop((positions, roots));
        let start = std::time::Instant::now();
        let r = merge_by_distance(&mut m, &verts, distance).unwrap();
        let points = start.elapsed();
        println!("merge 1M isolated points: {points:?}, merged {}", r.merged);
        m.validate().unwrap();

        // A welded triangle soup: 2·300² triangles, 1.08M corners.
        let mut m = Mesh::new();
        let n = 300;
        for j in 0..n {
            for i in 0..n {
                let p = |di: i32, dj: i32| v3(f64::from(i + di), f64::from(j + dj), 0.0);
                for tri in [[p(0, 0), p(1, 0), p(1, 1)], [p(0, 0), p(1, 1), p(0, 1)]] {
                    let vs: Vec<VertId> = tri.iter().map(|&q| m.make_vert(q)).collect();
                    m.make_face(&vs).unwrap();
                }
            }
        }
        let verts = all_verts(&m);
        let start = std::time::Instant::now();
        let r = merge_by_distance(&mut m, &verts, 1e-6).unwrap();
        let soup = start.elapsed();
        println!(
            "weld soup of {} corners: {soup:?}, merged {}",
            verts.len(),
            r.merged
        );
        m.validate().unwrap();
        assert_eq!(m.vert_count(), 301 * 301);
    }
}
