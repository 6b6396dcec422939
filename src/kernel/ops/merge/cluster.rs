//! Clustering points within a distance (deterministic: the lowest index
//! represents each cluster, whatever order pairs are found in).

use rayon::prelude::*;

use super::*;

/// Points per parallel task in the passes that read every point once
/// (cell keys, the gather): below this a task costs more than it saves.
const PARALLEL_CHUNK: usize = 4096;

/// Up to this many points [`cluster_roots`] compares every pair.
pub(super) const SMALL_CLUSTER_INPUT: usize = 24;

/// Points read by index: a list, or some of a mesh's vertices read in
/// place ([`VertPoints`]), so a merge of a million vertices does not first
/// copy their 24 MB of positions (issue 38: the memory a step touches for
/// the first time is much of its cost).
pub(in crate::kernel::ops) trait Points: Sync {
    fn count(&self) -> usize;
    fn point(&self, i: usize) -> DVec3;
}

impl Points for [DVec3] {
    fn count(&self) -> usize {
        self.len()
    }
    #[inline]
    fn point(&self, i: usize) -> DVec3 {
        self[i]
    }
}

/// The positions of `verts` (live vertices of `mesh`), in that order.
pub(in crate::kernel::ops) struct VertPoints<'a> {
    pub mesh: &'a Mesh,
    pub verts: &'a [VertId],
}

impl Points for VertPoints<'_> {
    fn count(&self) -> usize {
        self.verts.len()
    }
    #[inline]
    fn point(&self, i: usize) -> DVec3 {
        self.mesh.position(self.verts[i])
    }
}

/// Every point of `points`, in order.
fn each<P: Points + ?Sized>(points: &P) -> impl Iterator<Item = DVec3> + '_ {
    (0..points.count()).map(|i| points.point(i))
}

/// For each point, the lowest index of its cluster: the connected component
/// of the graph joining points at most `distance` apart.
pub(in crate::kernel::ops) fn cluster_roots<P: Points + ?Sized>(
    points: &P,
    distance: f64,
) -> Vec<u32> {
    let n = points.count();
    if n <= SMALL_CLUSTER_INPUT {
        // A grammar command's merge often looks at a handful of points;
        // the sort below costs a fixed few microseconds, the pairs nothing.
        let mut sets = UnionFind::new(n);
        for (i, p) in each(points).enumerate() {
            for (j, q) in each(points).enumerate().skip(i + 1) {
                let close = if distance > 0.0 {
                    within(p, q, distance)
                } else {
                    p.x == q.x && p.y == q.y && p.z == q.z
                };
                if close {
                    sets.union(i as u32, j as u32);
                }
            }
        }
        return (0..n as u32).map(|i| sets.find(i)).collect();
    }
    if distance > 0.0 {
        return grid_roots(points, distance);
    }
    // Exact coincidence: sort by the coordinates' bits; equal runs are the
    // clusters. Adding +0 folds −0 onto +0, so equal coordinates have
    // equal bits.
    let mut sets = UnionFind::new(n);
    let mut keyed: Vec<([u64; 3], u32)> = each(points)
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
    (0..n as u32).map(|i| sets.find(i)).collect()
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
pub(super) fn grid_roots<P: Points + ?Sized>(points: &P, distance: f64) -> Vec<u32> {
    // Cell coordinates are recomputed where needed rather than stored: a
    // stored copy is 24 bytes a point of memory touched for the first time.
    let cell = |p: DVec3| {
        [
            cell_coordinate(p.x, distance),
            cell_coordinate(p.y, distance),
            cell_coordinate(p.z, distance),
        ]
    };
    let (low, high) = cell_bounds(points, distance);
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
        // Each key is a pure function of its point: computed in parallel,
        // collected in index order.
        let keys: Vec<u64> = (0..points.count())
            .into_par_iter()
            .with_min_len(PARALLEL_CHUNK)
            .map(|i| {
                let c = cell(points.point(i));
                let field = |axis: usize| (c[axis] - low[axis] + 1) as u64;
                field(0) << shift_x | field(1) << shift_y | field(2)
            })
            .collect();
        let (cell_keys, order) = radix_sort(keys, bits.iter().sum());
        let step = |k: u64, [dx, dy, dz]: [i64; 3]| {
            let offset = (dx << shift_x) + (dy << shift_y) + dz;
            k.wrapping_add(offset as u64)
        };
        gathered_roots(&cell_keys, &order, points, distance, step)
    } else {
        // Cells spanning more than 2⁶⁴ in all: sort the coordinates as they are.
        let mut keyed: Vec<([i64; 3], u32)> = each(points).map(cell).zip(0u32..).collect();
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

/// The lowest and highest cell coordinates of `points` on each axis.
///
/// `floor(x / distance)` never decreases as `x` grows (division by a
/// positive number and the floor are both monotone), so the extreme cells
/// are the cells of the extreme coordinates: a min/max over the
/// coordinates and six divisions, not three divisions a point. A NaN
/// coordinate (whose cell, 0, need not lie between the others') falls
/// back to taking every point's cell.
fn cell_bounds<P: Points + ?Sized>(points: &P, distance: f64) -> ([i64; 3], [i64; 3]) {
    let (mut least, mut most) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    let mut nan = false;
    for p in each(points) {
        nan |= p.is_nan();
        least = least.min(p);
        most = most.max(p);
    }
    let cell = |p: DVec3| {
        [
            cell_coordinate(p.x, distance),
            cell_coordinate(p.y, distance),
            cell_coordinate(p.z, distance),
        ]
    };
    if !nan {
        return (cell(least), cell(most));
    }
    let (mut low, mut high) = ([i64::MAX; 3], [i64::MIN; 3]);
    for c in each(points).map(cell) {
        for axis in 0..3 {
            low[axis] = low[axis].min(c[axis]);
            high[axis] = high[axis].max(c[axis]);
        }
    }
    (low, high)
}

/// `floor(x / distance)` as an integer. `as` saturates: absurdly far points
/// share an end cell, which only costs comparisons, never correctness (real
/// distances are checked). Truncation plus a correction instead of
/// `f64::floor`, which is a library call on baseline x86-64.
#[inline]
pub(in crate::kernel::ops) fn cell_coordinate(x: f64, distance: f64) -> i64 {
    crate::geom::cells::floor_i64(x / distance)
}

/// Sorts `keys` (of `bits` significant bits), returning the sorted keys
/// and, for each, its original index; equal keys stay in index order.
///
/// A large input, given two threads or more, is sorted as two halves at
/// once, then merged taking the lower half first on equal keys: the result
/// is the one stable order by (key, index), however many threads ran.
pub(super) fn radix_sort(keys: Vec<u64>, bits: u32) -> (Vec<u64>, Vec<u32>) {
    let n = keys.len();
    let mut keys = keys;
    let mut order: Vec<u32> = (0..n as u32).collect();
    if bits.div_ceil(MAX_DIGIT) == 0 {
        return (keys, order);
    }
    let (mut keys_to, mut order_to) = (vec![0u64; n], vec![0u32; n]);
    // One thread sorts the whole (the halves' merge would be a pass for
    // nothing); the order is the same either way.
    if n < PARALLEL_SORT || rayon::current_num_threads() < 2 {
        if radix_passes([&mut keys, &mut keys_to], [&mut order, &mut order_to], bits) {
            return (keys_to, order_to);
        }
        return (keys, order);
    }
    let mid = n / 2;
    let (keys_low, keys_high) = keys.split_at_mut(mid);
    let (to_low, to_high) = keys_to.split_at_mut(mid);
    let (order_low, order_high) = order.split_at_mut(mid);
    let (order_to_low, order_to_high) = order_to.split_at_mut(mid);
    let (moved, _) = rayon::join(
        || radix_passes([keys_low, to_low], [order_low, order_to_low], bits),
        || radix_passes([keys_high, to_high], [order_high, order_to_high], bits),
    );
    // Both halves took the same number of passes: both sit in the same
    // pair of buffers. Merge them into the other pair.
    if moved {
        merge_halves(&keys_to, &order_to, mid, &mut keys, &mut order);
        (keys, order)
    } else {
        merge_halves(&keys, &order, mid, &mut keys_to, &mut order_to);
        (keys_to, order_to)
    }
}

/// Digits of at most this many bits: 4,096 counters stay in the cache.
const MAX_DIGIT: u32 = 12;

/// From this many keys [`radix_sort`] sorts two halves at once.
const PARALLEL_SORT: usize = 1 << 16;

/// Least significant digit first, in passes of at most [`MAX_DIGIT`]
/// bits, back and forth between `keys[0]`/`order[0]` (the input) and
/// `keys[1]`/`order[1]`: each pass is stable, so starting from index order
/// the result is ordered by (key, index). Linear whatever the keys'
/// spread; the digit counts of every pass are taken in one read of the
/// keys. Returns whether the result ended in the second pair (an odd
/// number of passes).
fn radix_passes(keys: [&mut [u64]; 2], order: [&mut [u32]; 2], bits: u32) -> bool {
    let passes = bits.div_ceil(MAX_DIGIT) as usize;
    let [mut keys, mut keys_to] = keys;
    let [mut order, mut order_to] = order;
    // Equal digit widths: 34 bits sort in three passes of 12, 12 and 10.
    let digit = bits.div_ceil(passes as u32);
    let buckets = 1usize << digit;
    let mask = buckets as u64 - 1;
    let mut counts = vec![0usize; passes * buckets];
    for &k in keys.iter() {
        for pass in 0..passes {
            counts[pass * buckets + ((k >> (pass as u32 * digit)) & mask) as usize] += 1;
        }
    }
    for pass in 0..passes {
        let shift = pass as u32 * digit;
        let next = &mut counts[pass * buckets..(pass + 1) * buckets];
        let mut total = 0;
        for count in next.iter_mut() {
            let c = *count;
            *count = total;
            total += c;
        }
        for (&k, &i) in keys.iter().zip(order.iter()) {
            let slot = &mut next[((k >> shift) & mask) as usize];
            keys_to[*slot] = k;
            order_to[*slot] = i;
            *slot += 1;
        }
        std::mem::swap(&mut keys, &mut keys_to);
        std::mem::swap(&mut order, &mut order_to);
    }
    passes % 2 == 1
}

/// Merges the sorted runs `..mid` and `mid..` of `keys`/`order` into
/// `keys_to`/`order_to`, the first run winning ties (its indices are the
/// lower ones).
fn merge_halves(
    keys: &[u64],
    order: &[u32],
    mid: usize,
    keys_to: &mut [u64],
    order_to: &mut [u32],
) {
    let (mut a, mut b) = (0, mid);
    for (key_to, index_to) in keys_to.iter_mut().zip(order_to.iter_mut()) {
        let take_a = b == keys.len() || (a < mid && keys[a] <= keys[b]);
        let from = if take_a { &mut a } else { &mut b };
        *key_to = keys[*from];
        *index_to = order[*from];
        *from += 1;
    }
}

/// Whether `a` and `b` are at most `distance` apart. Uses the hardware
/// square root (`f64::sqrt` is correctly rounded by IEEE 754, so the same on
/// every platform; glam's `length` goes through the much slower software
/// `libm`). Squares that overflow or underflow are compared scaled instead.
#[inline]
pub(super) fn within(a: DVec3, b: DVec3, distance: f64) -> bool {
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
pub(super) const FORWARD_ROWS: [(i64, i64, i64, i64); 5] = [
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
pub(super) fn gathered_roots<K: Copy + Ord + Sync, P: Points + ?Sized>(
    sorted_cells: &[K],
    order: &[u32],
    points: &P,
    distance: f64,
    step: impl Fn(K, [i64; 3]) -> K + Sync,
) -> Vec<u32> {
    let gathered: Vec<DVec3> = order
        .par_iter()
        .with_min_len(PARALLEL_CHUNK)
        .map(|&i| points.point(i as usize))
        .collect();
    let mut sets = UnionFind::new(order.len());
    sweep(sorted_cells, &gathered, distance, &mut sets, step);
    // The copy goes before the tables below are made: a lower peak.
    drop(gathered);
    let gathered_roots = sets.into_roots();
    let mut lowest = vec![u32::MAX; order.len()];
    for (&root, &i) in gathered_roots.iter().zip(order) {
        lowest[root as usize] = lowest[root as usize].min(i);
    }
    let mut roots = vec![0u32; order.len()];
    for (&root, &i) in gathered_roots.iter().zip(order) {
        roots[i as usize] = lowest[root as usize];
    }
    roots
}

/// Unions, in `sets`, every pair of `points` at most `distance` apart.
/// `sorted_cells[k]` is the cell of point `k`, ascending; `step` moves a
/// cell key by a cell offset, preserving order (lexicographic x, y, z), so
/// each row cursor only ever moves forward.
///
/// Given two threads and enough points, the cells are swept as two runs
/// at once: the second run's pairs join sets of its own over the points
/// from its first one on (every pair it finds lies there: neighbours are
/// looked for forward only), merged into `sets` after. The pairs found are
/// the same, so are the sets.
pub(super) fn sweep<K: Copy + Ord + Sync>(
    sorted_cells: &[K],
    points: &[DVec3],
    distance: f64,
    sets: &mut UnionFind,
    step: impl Fn(K, [i64; 3]) -> K + Sync,
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
    let grid = SweepGrid {
        keys: &keys,
        start: &start,
        points,
        distance,
        step: &step,
    };
    if points.len() < PARALLEL_SWEEP || rayon::current_num_threads() < 2 {
        grid.sweep(0..keys.len(), sets, 0);
        return;
    }
    // The cell where the second half of the points begins.
    let mid = start.partition_point(|&s| s < points.len() / 2);
    let offset = start[mid];
    let mut upper = UnionFind::new(points.len() - offset);
    rayon::join(
        || grid.sweep(0..mid, sets, 0),
        || grid.sweep(mid..keys.len(), &mut upper, offset),
    );
    for (k, root) in upper.into_roots().into_iter().enumerate() {
        if root as usize != k {
            sets.union((offset + k) as u32, offset as u32 + root);
        }
    }
}

/// From this many points [`sweep`] runs two halves of the cells at once.
const PARALLEL_SWEEP: usize = 1 << 16;

/// The occupied cells of a sweep, in order, and the points they hold.
struct SweepGrid<'a, K, S> {
    keys: &'a [K],
    start: &'a [usize],
    points: &'a [DVec3],
    distance: f64,
    step: &'a S,
}

impl<K: Copy + Ord, S: Fn(K, [i64; 3]) -> K> SweepGrid<'_, K, S> {
    /// Links the pairs found from the cells `cells` (each with itself and
    /// its forward neighbours) in `sets`, which numbers point `i` as
    /// `i - offset`.
    fn sweep(&self, cells: std::ops::Range<usize>, sets: &mut UnionFind, offset: usize) {
        let (keys, start, points) = (self.keys, self.start, self.points);
        let link = |sets: &mut UnionFind, i: usize, j: usize| {
            // Same set already is the common case inside a cluster, and cheaper.
            let (a, b) = ((i - offset) as u32, (j - offset) as u32);
            if sets.find(a) != sets.find(b) && within(points[i], points[j], self.distance) {
                sets.union(a, b);
            }
        };
        // Each row's cursor starts at the first cell at or past the row's
        // first neighbour of the first cell, as a sweep from cell 0 would
        // have left it.
        let mut cursors = FORWARD_ROWS.map(|(dx, dy, z_low, _)| match cells.clone().next() {
            Some(c) => {
                let first = (self.step)(keys[c], [dx, dy, z_low]);
                keys.partition_point(|&k| k < first)
            }
            None => 0,
        });
        for c in cells {
            let key = keys[c];
            let here = start[c]..start[c + 1];
            for i in here.clone() {
                for j in i + 1..here.end {
                    link(sets, i, j);
                }
            }
            for (row, &(dx, dy, z_low, z_high)) in FORWARD_ROWS.iter().enumerate() {
                let first = (self.step)(key, [dx, dy, z_low]);
                let last = (self.step)(key, [dx, dy, z_high]);
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
}
