//! Axis-aligned boxes with the interval arithmetic the bounds need.
//!
//! A box may be *inverted* (`lo > hi` on some axis): it is then empty, but
//! growing it by `r` is still the exact interval hull of the grown parts
//! (see [`crate::sdf::tree`] for why bounds keep inverted boxes). Infinite
//! coordinates stand for unbounded sides (half-spaces).

use glam::{DMat3, DVec3};

/// An axis-aligned box `[lo, hi]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub lo: DVec3,
    pub hi: DVec3,
}

impl Aabb {
    /// The box `[lo, hi]`.
    pub const fn new(lo: DVec3, hi: DVec3) -> Self {
        Aabb { lo, hi }
    }

    /// The box of all space.
    pub const EVERYTHING: Aabb = Aabb {
        lo: DVec3::splat(f64::NEG_INFINITY),
        hi: DVec3::splat(f64::INFINITY),
    };

    /// The empty box (the identity of [`Aabb::union`]).
    pub const EMPTY: Aabb = Aabb {
        lo: DVec3::splat(f64::INFINITY),
        hi: DVec3::splat(f64::NEG_INFINITY),
    };

    /// The box `c ± e`.
    pub fn centered(c: DVec3, e: DVec3) -> Self {
        Aabb::new(c - e, c + e)
    }

    /// The smallest box holding all `points`.
    pub fn of_points(points: impl IntoIterator<Item = DVec3>) -> Self {
        let mut b = Aabb::EMPTY;
        for p in points {
            b.lo = b.lo.min(p);
            b.hi = b.hi.max(p);
        }
        b
    }

    /// True when some axis has `lo > hi` (or a NaN bound).
    pub fn is_empty(&self) -> bool {
        !(self.lo.x <= self.hi.x && self.lo.y <= self.hi.y && self.lo.z <= self.hi.z)
    }

    /// True when every bound is finite.
    pub fn is_finite(&self) -> bool {
        self.lo.is_finite() && self.hi.is_finite()
    }

    /// Interval hull of both (exact for inverted boxes too).
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb::new(self.lo.min(o.lo), self.hi.max(o.hi))
    }

    /// Intersection (may be inverted, i.e. empty).
    pub fn intersection(&self, o: &Aabb) -> Aabb {
        Aabb::new(self.lo.max(o.lo), self.hi.min(o.hi))
    }

    /// The box grown by `r` on every side (`r` may be negative).
    pub fn grown(&self, r: f64) -> Aabb {
        Aabb::new(self.lo - DVec3::splat(r), self.hi + DVec3::splat(r))
    }

    /// Centre (meaningless for unbounded boxes).
    pub fn center(&self) -> DVec3 {
        (self.lo + self.hi) * 0.5
    }

    /// Edge lengths.
    pub fn size(&self) -> DVec3 {
        self.hi - self.lo
    }

    /// True when `p` lies in the closed box.
    pub fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.lo).all() && p.cmple(self.hi).all()
    }

    /// Squared Euclidean distance from `p` to the box (0 inside).
    pub fn dist2(&self, p: DVec3) -> f64 {
        let d = (self.lo - p).max(p - self.hi).max(DVec3::ZERO);
        d.dot(d)
    }

    /// Squared distance between two boxes (0 when they overlap).
    pub fn dist2_box(&self, o: &Aabb) -> f64 {
        let d = (self.lo - o.hi).max(o.lo - self.hi).max(DVec3::ZERO);
        d.dot(d)
    }

    /// `{ m·x + t : x ∈ self }` bounded conservatively, `growth` scaled by
    /// the largest row sum of |m| (see the module doc of `tree`). Infinite
    /// sides stay infinite on every output axis they reach.
    pub fn transformed(&self, m: &DMat3, t: DVec3) -> Aabb {
        let c = self.center();
        let e = (self.hi - self.lo) * 0.5;
        let mut lo = DVec3::ZERO;
        let mut hi = DVec3::ZERO;
        for row in 0..3 {
            let mut center = t[row];
            let mut half = 0.0;
            let mut infinite = false;
            for col in 0..3 {
                let a = m.col(col)[row];
                if a == 0.0 {
                    continue;
                }
                if !self.lo[col].is_finite() || !self.hi[col].is_finite() {
                    infinite = true;
                    continue;
                }
                center += a * c[col];
                half += a.abs() * e[col];
            }
            if infinite {
                lo[row] = f64::NEG_INFINITY;
                hi[row] = f64::INFINITY;
            } else {
                lo[row] = center - half;
                hi[row] = center + half;
            }
        }
        Aabb::new(lo, hi)
    }
}
