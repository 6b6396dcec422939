//! Interval arithmetic with a NaN flag: a set of `f64` values as the reals
//! in `[lo, hi]` plus, when `nan`, NaN. Endpoints are computed in plain
//! floating point from candidate values (sound for the monotone pieces the
//! callers build; see `rules::lint`, which judges conditions with it).

/// A set of values: the reals in [lo, hi] (empty when lo > hi), and NaN when
/// `nan`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Interval {
    pub lo: f64,
    pub hi: f64,
    pub nan: bool,
}

impl std::fmt::Display for Interval {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let bound = |x: f64| {
            if x == f64::INFINITY {
                "∞".to_owned()
            } else if x == f64::NEG_INFINITY {
                "−∞".to_owned()
            } else if x == f64::MAX {
                "max".to_owned()
            } else if x == f64::MIN {
                "−max".to_owned()
            } else if x < 1.0 && x > 0.999_999 {
                "1)".to_owned()
            } else {
                format!("{x}")
            }
        };
        if self.is_empty() {
            return f.write_str(if self.nan { "{NaN}" } else { "{}" });
        }
        let hi = bound(self.hi);
        if hi.ends_with(')') {
            write!(f, "[{}, {hi}", bound(self.lo))
        } else {
            write!(f, "[{}, {hi}]", bound(self.lo))
        }
    }
}

impl Interval {
    pub fn new(lo: f64, hi: f64) -> Interval {
        Interval { lo, hi, nan: false }
    }

    pub fn all() -> Interval {
        Interval {
            lo: f64::NEG_INFINITY,
            hi: f64::INFINITY,
            nan: true,
        }
    }

    /// Any finite value (parameters, positions).
    pub fn finite() -> Interval {
        Interval::new(f64::MIN, f64::MAX)
    }

    pub fn point(x: f64) -> Interval {
        if x.is_nan() {
            Interval {
                lo: f64::INFINITY,
                hi: f64::NEG_INFINITY,
                nan: true,
            }
        } else {
            Interval::new(x, x)
        }
    }

    pub fn boolean(can_false: bool, can_true: bool) -> Interval {
        match (can_false, can_true) {
            (true, true) => Interval::new(0.0, 1.0),
            (true, false) => Interval::point(0.0),
            (false, true) => Interval::point(1.0),
            (false, false) => Interval {
                lo: f64::INFINITY,
                hi: f64::NEG_INFINITY,
                nan: false,
            },
        }
    }

    pub fn is_empty(&self) -> bool {
        self.lo > self.hi
    }

    pub fn contains(&self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }

    /// (can be false, can be true) as a condition: zero is false, anything
    /// else (NaN included) true.
    pub fn truth(&self) -> (bool, bool) {
        let can_false = self.contains(0.0);
        let can_true = self.nan || (!self.is_empty() && (self.lo != 0.0 || self.hi != 0.0));
        (can_false, can_true)
    }

    pub fn hull(self, other: Interval) -> Interval {
        Interval {
            lo: self.lo.min(other.lo),
            hi: self.hi.max(other.hi),
            nan: self.nan || other.nan,
        }
    }

    pub fn intersect(self, other: Interval) -> Interval {
        Interval {
            lo: self.lo.max(other.lo),
            hi: self.hi.min(other.hi),
            nan: self.nan && other.nan,
        }
    }

    /// A range from endpoint candidates; NaN among them means anything.
    pub fn from_candidates(candidates: &[f64], nan: bool) -> Interval {
        if candidates.iter().any(|c| c.is_nan()) {
            return Interval::all();
        }
        let lo = candidates.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = candidates.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Interval { lo, hi, nan }
    }

    /// Applies a non-decreasing function.
    pub fn monotone(self, f: impl Fn(f64) -> f64) -> Interval {
        if self.is_empty() {
            return self;
        }
        Interval::from_candidates(&[f(self.lo), f(self.hi)], self.nan)
    }

    pub fn infinite(&self) -> bool {
        self.lo == f64::NEG_INFINITY || self.hi == f64::INFINITY
    }
}

pub fn next_up(x: f64) -> f64 {
    if x.is_nan() || x == f64::INFINITY {
        return x;
    }
    if x == 0.0 {
        return f64::from_bits(1);
    }
    let bits = x.to_bits();
    f64::from_bits(if x > 0.0 { bits + 1 } else { bits - 1 })
}

pub fn next_down(x: f64) -> f64 {
    -next_up(-x)
}
