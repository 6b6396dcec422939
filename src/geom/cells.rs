//! Hash-grid cells for fixed-distance searches (weld, close-vertex gate).
//!
//! With cells of side `2d`, every point within `d` of `p` lies in the cells
//! that the box `[p − d, p + d]` touches: two per axis, so 8 cells are
//! searched instead of the 27 a cell of side `d` needs. The box is widened
//! by a millionth of a cell so that rounding in `x / side` (relative 2⁻⁵²
//! of the coordinate in cells) cannot drop a neighbour for coordinates up
//! to about 10⁹ cells from the origin; at exactly half a cell three cells
//! are searched along that axis.

use rustc_hash::FxHashMap;

/// A grid of cubic cells sized for searches within one distance.
#[derive(Clone, Copy, Debug)]
pub struct Cells {
    side: f64,
}

impl Cells {
    /// Cells for finding every point within `distance` (> 0, finite).
    pub fn for_distance(distance: f64) -> Cells {
        Cells {
            side: 2.0 * distance,
        }
    }

    /// The cell holding `p`.
    pub fn of(&self, p: [f64; 3]) -> [i64; 3] {
        p.map(|x| floor_i64(x / self.side))
    }

    /// Inclusive lower and upper cells that hold every point within the
    /// distance of `p`.
    pub fn around(&self, p: [f64; 3]) -> ([i64; 3], [i64; 3]) {
        let reach = |x: f64, sign: f64| floor_i64(x / self.side + sign * (0.5 + 1e-6));
        (p.map(|x| reach(x, -1.0)), p.map(|x| reach(x, 1.0)))
    }
}

/// `x.floor() as i64`, the same value for every input (saturating at the
/// ends, 0 for NaN), by truncation and a correction: `f64::floor` is a
/// library call on baseline x86-64, and a weld takes nine a point.
#[inline]
pub fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// No index: the end of a list, or an empty cell.
pub const NONE: u32 = u32::MAX;

/// Indices filed by cell: each cell heads a list of the indices pushed
/// into it, newest first, threaded through one `next` array. Beside the
/// hash table sits an occupancy bitmap (a bit per hashed cell, about 8
/// per entry), so the common lookup — one of the 8 cells around a point
/// that holds nothing — is a test of one bit in a table that stays in
/// cache instead of a probe of the hash table.
pub struct CellLists {
    heads: FxHashMap<[i64; 3], u32>,
    next: Vec<u32>,
    occupied: Vec<u64>,
    /// Bits in `occupied` minus one (a power of two minus one).
    mask: u64,
}

impl CellLists {
    /// Empty lists with room for `indices` indices filed in about
    /// `cells` distinct cells. Reserve cells only when their number is
    /// known: a table reserved for a million cells is 37 MB of pages
    /// touched for the first time, which costs more than growing one to
    /// the 167k cells a welded soup of a million corners fills.
    pub fn with_capacity(indices: usize, cells: usize) -> CellLists {
        let bits = indices
            .saturating_mul(8)
            .clamp(64, 1 << 33)
            .next_power_of_two();
        let mut heads = FxHashMap::default();
        heads.reserve(cells);
        CellLists {
            heads,
            next: Vec::with_capacity(indices),
            occupied: vec![0; bits / 64],
            mask: bits as u64 - 1,
        }
    }

    fn bit(&self, cell: [i64; 3]) -> (usize, u64) {
        // A multiplicative mix of the three coordinates (the top bits are
        // the best mixed).
        let h = (cell[0] as u64)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add((cell[1] as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F))
            .wrapping_add((cell[2] as u64).wrapping_mul(0x1656_67B1_9E37_79F9));
        let slot = ((h ^ (h >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9) >> 16) & self.mask;
        ((slot / 64) as usize, 1 << (slot % 64))
    }

    /// The newest index in `cell`, or [`NONE`].
    #[inline]
    pub fn head(&self, cell: [i64; 3]) -> u32 {
        let (word, bit) = self.bit(cell);
        if self.occupied[word] & bit == 0 {
            return NONE;
        }
        self.heads.get(&cell).copied().unwrap_or(NONE)
    }

    /// The index pushed into the same cell before `index`, or [`NONE`].
    #[inline]
    pub fn next(&self, index: u32) -> u32 {
        self.next[index as usize]
    }

    /// Files the next index (the number pushed so far) under `cell`.
    pub fn push(&mut self, cell: [i64; 3]) -> u32 {
        let index = self.next.len() as u32;
        let (word, bit) = self.bit(cell);
        self.occupied[word] |= bit;
        let head = self.heads.entry(cell).or_insert(NONE);
        self.next.push(*head);
        *head = index;
        index
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_i64_is_floor_as_i64_everywhere() {
        let values = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.5,
            -2.5,
            1e-300,
            -1e-300,
            4503599627370495.5,
            -4503599627370495.5,
            9.2e18,
            -9.2e18,
            9.3e18,
            -9.3e18,
            1e300,
            -1e300,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            9223372036854775807.0,
            -9223372036854775808.0,
        ];
        for x in values
            .into_iter()
            .chain((0..2000).map(|i| (i as f64 - 1000.0) * 0.37))
        {
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
        }
    }

    #[test]
    fn around_covers_the_distance_with_two_cells_per_axis() {
        let cells = Cells::for_distance(0.5);
        // Side 1: 0.2 needs cells −1 and 0; 0.8 needs 0 and 1.
        assert_eq!(cells.around([0.2, 0.8, -0.3]), ([-1, 0, -1], [0, 1, 0]));
        assert_eq!(cells.of([0.2, 0.8, -0.3]), [0, 0, -1]);
        // Every point within the distance falls in the searched range.
        for k in 0..1000 {
            let x = k as f64 * 0.0137 - 7.0;
            let (lo, hi) = cells.around([x, x, x]);
            for y in [x - 0.5, x + 0.5, x - 0.4999, x + 0.25] {
                let c = cells.of([y, y, y])[0];
                assert!(lo[0] <= c && c <= hi[0], "{x} {y}");
            }
            assert!(hi[0] - lo[0] <= 2);
        }
    }

    #[test]
    fn cell_lists_file_indices_newest_first_and_miss_empty_cells() {
        let mut lists = CellLists::with_capacity(4, 0);
        let cells = [[0, 0, 0], [1, -2, 3], [0, 0, 0], [i64::MIN, i64::MAX, 0]];
        for (k, &cell) in cells.iter().enumerate() {
            assert_eq!(lists.push(cell), k as u32);
        }
        let list = |cell| {
            let mut out = Vec::new();
            let mut at = lists.head(cell);
            while at != NONE {
                out.push(at);
                at = lists.next(at);
            }
            out
        };
        assert_eq!(list([0, 0, 0]), [2, 0]);
        assert_eq!(list([1, -2, 3]), [1]);
        assert_eq!(list([i64::MIN, i64::MAX, 0]), [3]);
        // Empty cells, whether or not their bit is shared with a full one.
        for x in -50..50 {
            for y in -5..5 {
                let cell = [x, y, 7];
                assert_eq!(list(cell), [] as [u32; 0]);
            }
        }
    }
}
