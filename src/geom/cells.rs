//! Hash-grid cells for fixed-distance searches (weld, close-vertex gate).
//!
//! With cells of side `2d`, every point within `d` of `p` lies in the cells
//! that the box `[p − d, p + d]` touches: two per axis, so 8 cells are
//! searched instead of the 27 a cell of side `d` needs. The box is widened
//! by a millionth of a cell so that rounding in `x / side` (relative 2⁻⁵²
//! of the coordinate in cells) cannot drop a neighbour for coordinates up
//! to about 10⁹ cells from the origin; at exactly half a cell three cells
//! are searched along that axis.

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
        p.map(|x| (x / self.side).floor() as i64)
    }

    /// Inclusive lower and upper cells that hold every point within the
    /// distance of `p`.
    pub fn around(&self, p: [f64; 3]) -> ([i64; 3], [i64; 3]) {
        let reach = |x: f64, sign: f64| (x / self.side + sign * (0.5 + 1e-6)).floor() as i64;
        (p.map(|x| reach(x, -1.0)), p.map(|x| reach(x, 1.0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
