//! Conservative `f32` boxes around `f64` geometry: every bound is rounded
//! outward, so boxes whose `f64` extents overlap still overlap, and a broad
//! phase on them can add candidates but never lose one.

use glam::DVec3;

/// The largest `f32` not above `x` (−∞ stays −∞).
pub fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) > x {
        step_down(f)
    } else {
        f
    }
}

/// The smallest `f32` not below `x`.
pub fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) < x {
        -step_down(-f)
    } else {
        f
    }
}

/// The next `f32` towards −∞ (`f32::next_down` needs Rust 1.86).
fn step_down(f: f32) -> f32 {
    if f.is_nan() || f == f32::NEG_INFINITY {
        f
    } else if f == 0.0 {
        -f32::from_bits(1)
    } else if f > 0.0 {
        f32::from_bits(f.to_bits() - 1)
    } else {
        f32::from_bits(f.to_bits() + 1)
    }
}

/// An axis-aligned `f32` box; closed (touching boxes overlap).
#[derive(Clone, Copy, Debug)]
pub struct Box3 {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
}

impl Box3 {
    pub const EMPTY: Box3 = Box3 {
        lo: [f32::INFINITY; 3],
        hi: [f32::NEG_INFINITY; 3],
    };

    /// A box around the `f64` box `lo ..= hi` (finite or infinite, not
    /// NaN), clamped to the finite `f32` range. Each bound is first moved
    /// outward by `|x|·2⁻²² + 2⁻¹⁴⁰`, more than the error of the `f64`
    /// subtraction plus half an `f32` step (`|x|·2⁻²⁴`, or `2⁻¹⁵⁰` for
    /// subnormals), so the nearest `f32` is still outside: `lo' ≤ lo` and
    /// `hi' ≥ hi` before clamping (no rounding-direction branches, which
    /// mispredict half the time). Clamping is monotone, so boxes whose
    /// `f64` bounds overlap still overlap here.
    #[inline]
    pub fn around(lo: DVec3, hi: DVec3) -> Box3 {
        const REL: f64 = 1.0 / (1u64 << 22) as f64;
        const ABS: f64 = 1.0 / (1u128 << 70) as f64 / (1u128 << 70) as f64;
        let out = |x: f64, up: bool| {
            let d = x.abs() * REL + ABS;
            let y = if up { x + d } else { x - d };
            (y as f32).clamp(f32::MIN, f32::MAX)
        };
        Box3 {
            lo: lo.to_array().map(|x| out(x, false)),
            hi: hi.to_array().map(|x| out(x, true)),
        }
    }

    #[inline(always)]
    pub fn overlaps(&self, o: &Box3) -> bool {
        (self.lo[0] <= o.hi[0])
            & (o.lo[0] <= self.hi[0])
            & (self.lo[1] <= o.hi[1])
            & (o.lo[1] <= self.hi[1])
            & (self.lo[2] <= o.hi[2])
            & (o.lo[2] <= self.hi[2])
    }

    #[inline]
    pub fn union(&self, o: &Box3) -> Box3 {
        Box3 {
            lo: [0, 1, 2].map(|k| self.lo[k].min(o.lo[k])),
            hi: [0, 1, 2].map(|k| self.hi[k].max(o.hi[k])),
        }
    }

    /// Sum of the extents: orders boxes by size for the descent.
    pub fn size(&self) -> f32 {
        (0..3).map(|k| self.hi[k] - self.lo[k]).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_is_outward() {
        for x in [0.1, -0.1, 1e-300, -1e-300, 3.0, 1e38, 123456.789] {
            assert!(
                f64::from(round_down(x)) <= x && f64::from(round_up(x)) >= x,
                "{x}"
            );
        }
        assert_eq!(round_down(0.5), 0.5);
        let b = Box3::around(DVec3::splat(0.1), DVec3::splat(0.3));
        assert!(f64::from(b.lo[0]) <= 0.1 && f64::from(b.hi[0]) >= 0.3);
        let touching = Box3::around(DVec3::splat(0.3), DVec3::splat(0.5));
        assert!(b.overlaps(&touching));
        assert!(!Box3::EMPTY.overlaps(&b));
    }
}
