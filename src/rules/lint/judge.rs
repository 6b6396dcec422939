//! Judging conditions by interval arithmetic over the expression language:
//! the set of values an expression can take when its inputs range over
//! sets, so that a condition that can never (or always) hold is found.

use super::*;

pub(super) fn unary(f: Unary, x: Interval) -> Interval {
    use std::f64::consts::{FRAC_PI_2, PI};
    if x.is_empty() && !matches!(f, Unary::Not | Unary::Truthy) {
        return x;
    }
    let nan_if = |cond: bool| x.nan || cond;
    match f {
        Unary::Neg => Interval {
            lo: -x.hi,
            hi: -x.lo,
            nan: x.nan,
        },
        Unary::Not => {
            let (can_false, can_true) = x.truth();
            Interval::boolean(can_true, can_false)
        }
        Unary::Truthy => {
            let (can_false, can_true) = x.truth();
            Interval::boolean(can_false, can_true)
        }
        Unary::Abs => {
            if x.lo >= 0.0 {
                x
            } else if x.hi <= 0.0 {
                unary(Unary::Neg, x)
            } else {
                Interval {
                    lo: 0.0,
                    hi: (-x.lo).max(x.hi),
                    nan: x.nan,
                }
            }
        }
        Unary::Sqrt => {
            let real = Interval::new(x.lo.max(0.0), x.hi).monotone(libm::sqrt);
            Interval {
                nan: nan_if(x.lo < 0.0),
                ..real
            }
        }
        Unary::Ln | Unary::Log10 => {
            let g = if f == Unary::Ln {
                libm::log
            } else {
                libm::log10
            };
            let real = Interval::new(x.lo.max(0.0), x.hi).monotone(g);
            Interval {
                nan: nan_if(x.lo < 0.0),
                ..real
            }
        }
        Unary::Exp
        | Unary::Floor
        | Unary::Ceil
        | Unary::Round
        | Unary::Sign
        | Unary::Atan
        | Unary::Radians
        | Unary::Degrees => x.monotone(|v| f.apply(v)),
        Unary::Sin | Unary::Cos => Interval {
            lo: -1.0,
            hi: 1.0,
            nan: nan_if(x.infinite()),
        },
        Unary::Asin => Interval {
            lo: -FRAC_PI_2,
            hi: FRAC_PI_2,
            nan: nan_if(x.lo < -1.0 || x.hi > 1.0),
        },
        Unary::Acos => Interval {
            lo: 0.0,
            hi: PI,
            nan: nan_if(x.lo < -1.0 || x.hi > 1.0),
        },
        Unary::Tan => Interval::all(),
    }
}

pub(super) fn binary(f: Binary, a: Interval, b: Interval) -> Interval {
    use std::f64::consts::PI;
    let nan = a.nan || b.nan;
    let compare = |can_true: bool, can_false: bool, nan_result: bool| {
        // A NaN operand makes every comparison false (and `!=` true).
        let (mut can_false, mut can_true) = (can_false, can_true);
        if nan {
            if nan_result {
                can_true = true;
            } else {
                can_false = true;
            }
        }
        Interval::boolean(can_false, can_true)
    };
    let empty = a.is_empty() || b.is_empty();
    match f {
        Binary::Lt | Binary::Le | Binary::Gt | Binary::Ge | Binary::Eq | Binary::Ne if empty => {
            compare(false, false, f == Binary::Ne)
        }
        Binary::Lt => compare(a.lo < b.hi, a.hi >= b.lo, false),
        Binary::Le => compare(a.lo <= b.hi, a.hi > b.lo, false),
        Binary::Gt => compare(a.hi > b.lo, a.lo <= b.hi, false),
        Binary::Ge => compare(a.hi >= b.lo, a.lo < b.hi, false),
        Binary::Eq => {
            let overlap = a.lo <= b.hi && b.lo <= a.hi;
            let always = a.lo == a.hi && b.lo == b.hi && a.lo == b.lo;
            compare(overlap, !always, false)
        }
        Binary::Ne => {
            let overlap = a.lo <= b.hi && b.lo <= a.hi;
            let always = a.lo == a.hi && b.lo == b.hi && a.lo == b.lo;
            compare(!always, overlap, true)
        }
        Binary::Step => binary(Binary::Ge, b, a),
        Binary::Min | Binary::Max => {
            // fmin/fmax ignore a NaN operand.
            let g = if f == Binary::Min { f64::min } else { f64::max };
            if a.is_empty() {
                return Interval {
                    nan: a.nan && b.nan,
                    ..b
                };
            }
            if b.is_empty() {
                return Interval {
                    nan: a.nan && b.nan,
                    ..a
                };
            }
            let mut r = Interval {
                lo: g(a.lo, b.lo),
                hi: g(a.hi, b.hi),
                nan: a.nan && b.nan,
            };
            if a.nan {
                r = r.hull(Interval::new(b.lo, b.hi));
            }
            if b.nan {
                r = r.hull(Interval::new(a.lo, a.hi));
            }
            r
        }
        _ if empty => Interval {
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
            nan: true,
        },
        Binary::Add => Interval::from_candidates(&[a.lo + b.lo, a.hi + b.hi], nan),
        Binary::Sub => Interval::from_candidates(&[a.lo - b.hi, a.hi - b.lo], nan),
        Binary::Mul => {
            Interval::from_candidates(&[a.lo * b.lo, a.lo * b.hi, a.hi * b.lo, a.hi * b.hi], nan)
        }
        Binary::Div => {
            if b.contains(0.0) || b.infinite() || a.infinite() {
                Interval::all()
            } else {
                Interval::from_candidates(
                    &[a.lo / b.lo, a.lo / b.hi, a.hi / b.lo, a.hi / b.hi],
                    nan,
                )
            }
        }
        Binary::Rem => {
            let nan = nan || a.infinite();
            if b.lo > 0.0 {
                Interval {
                    lo: 0.0,
                    hi: b.hi,
                    nan,
                }
            } else if b.hi < 0.0 {
                Interval {
                    lo: b.lo,
                    hi: 0.0,
                    nan,
                }
            } else {
                Interval::all()
            }
        }
        Binary::Pow => {
            let n = b.lo;
            if b.lo == b.hi && n.fract() == 0.0 && (1.0..=64.0).contains(&n) && !b.nan {
                if n % 2.0 == 0.0 {
                    unary(Unary::Abs, a).monotone(|v| libm::pow(v, n))
                } else {
                    a.monotone(|v| libm::pow(v, n))
                }
            } else {
                Interval::all()
            }
        }
        Binary::Atan2 => Interval {
            lo: -PI,
            hi: PI,
            nan,
        },
    }
}

pub(super) fn ternary(f: Ternary, a: Interval, b: Interval, c: Interval) -> Interval {
    match f {
        Ternary::Clamp => binary(Binary::Min, binary(Binary::Max, a, b), c),
        Ternary::Lerp => binary(
            Binary::Add,
            a,
            binary(Binary::Mul, binary(Binary::Sub, b, a), c),
        ),
        Ternary::Smoothstep => Interval {
            lo: 0.0,
            hi: 1.0,
            nan: a.nan || b.nan || c.nan || a.infinite() || b.infinite() || c.infinite(),
        },
    }
}

/// Interval evaluation of expression trees, narrowing compared slots
/// through `&&` and `||`.
pub(super) struct Analysis<'i> {
    /// Slots holding integers.
    pub(super) integer: &'i [bool],
}

impl Analysis<'_> {
    pub(super) fn eval(&self, t: &Tree, env: &[Interval]) -> Interval {
        match t {
            Tree::Const(v) => Interval::point(*v),
            Tree::Slot(s) => env.get(*s as usize).copied().unwrap_or(Interval::all()),
            Tree::Unary(f, x) => unary(*f, self.eval(x, env)),
            Tree::Binary(f, a, b) => {
                let r = binary(*f, self.eval(a, env), self.eval(b, env));
                let compares_slot = matches!(**a, Tree::Slot(_)) || matches!(**b, Tree::Slot(_));
                if negate(*f).is_none() || !compares_slot {
                    return r;
                }
                // Integer slots: `n > 2 && n < 3`, `n == 0.5`.
                let (mut can_false, mut can_true) = r.truth();
                can_true = can_true && self.compare(*f, a, b, true, env).is_some();
                can_false = can_false && self.compare(*f, a, b, false, env).is_some();
                Interval::boolean(can_false, can_true)
            }
            Tree::Ternary(f, a, b, c) => {
                ternary(*f, self.eval(a, env), self.eval(b, env), self.eval(c, env))
            }
            Tree::And(a, b) | Tree::Or(a, b) => {
                let and = matches!(t, Tree::And(..));
                let (a_false, a_true) = self.eval(a, env).truth();
                // `&&`: false when the left is; else the right decides.
                let (decides, goes_on) = if and {
                    (a_false, a_true)
                } else {
                    (a_true, a_false)
                };
                let (mut can_false, mut can_true) = if and {
                    (decides, false)
                } else {
                    (false, decides)
                };
                if goes_on {
                    for narrowed in self.assume(a, and, env) {
                        let (b_false, b_true) = self.eval(b, &narrowed).truth();
                        can_false |= b_false;
                        can_true |= b_true;
                    }
                }
                Interval::boolean(can_false, can_true)
            }
        }
    }

    /// The slot ranges left when `t`'s truth is `truth`: a union of boxes
    /// (empty when it cannot be), so `(x > 1 || x < -1)` keeps both sides.
    fn assume(&self, t: &Tree, truth: bool, env: &[Interval]) -> Vec<Vec<Interval>> {
        let (can_false, can_true) = self.eval(t, env).truth();
        if (truth && !can_true) || (!truth && !can_false) {
            return Vec::new();
        }
        let boxes = match t {
            Tree::And(a, b) | Tree::Or(a, b) => {
                let and = matches!(t, Tree::And(..));
                let mut out = Vec::new();
                if and == truth {
                    // Both sides hold `truth`.
                    for narrowed in self.assume(a, truth, env) {
                        out.extend(self.assume(b, truth, &narrowed));
                    }
                } else {
                    // The left alone, or the left not and the right.
                    out.extend(self.assume(a, truth, env));
                    for narrowed in self.assume(a, !truth, env) {
                        out.extend(self.assume(b, truth, &narrowed));
                    }
                }
                out
            }
            Tree::Unary(Unary::Not, x) => self.assume(x, !truth, env),
            Tree::Unary(Unary::Truthy, x) => self.assume(x, truth, env),
            Tree::Binary(f, a, b) => self.compare(*f, a, b, truth, env).into_iter().collect(),
            _ => vec![env.to_vec()],
        };
        if boxes.len() <= MAX_BOXES {
            return boxes;
        }
        let hull = boxes
            .into_iter()
            .reduce(|a, b| a.iter().zip(&b).map(|(x, y)| x.hull(*y)).collect())
            .expect("more than MAX_BOXES");
        vec![hull]
    }

    /// The slot ranges left when comparison `a f b` has value `truth`
    /// (unchanged unless it compares a slot); `None` when it cannot.
    fn compare(
        &self,
        f: Binary,
        a: &Tree,
        b: &Tree,
        truth: bool,
        env: &[Interval],
    ) -> Option<Vec<Interval>> {
        let op = if truth { Some(f) } else { negate(f) };
        let mut out = env.to_vec();
        let Some(op) = op else {
            return Some(out);
        };
        if let Tree::Slot(s) = *a {
            let bound = self.eval(b, env);
            // A NaN makes a comparison false whatever the slot holds.
            if truth || !bound.nan {
                self.narrow(&mut out, s as usize, op, bound)?;
            }
        }
        if let Tree::Slot(s) = *b {
            let bound = self.eval(a, env);
            if let (Some(mirrored), true) = (mirror(op), truth || !bound.nan) {
                self.narrow(&mut out, s as usize, mirrored, bound)?;
            }
        }
        Some(out)
    }

    /// Narrows slot `s` to the values `x` with `x op bound` for some value
    /// of `bound`; `None` when none is left.
    fn narrow(&self, env: &mut [Interval], s: usize, op: Binary, bound: Interval) -> Option<()> {
        let Some(current) = env.get(s).copied() else {
            return Some(());
        };
        if bound.is_empty() {
            return Some(());
        }
        let allowed = match op {
            Binary::Lt => Interval::new(f64::NEG_INFINITY, next_down(bound.hi)),
            Binary::Le => Interval::new(f64::NEG_INFINITY, bound.hi),
            Binary::Gt => Interval::new(next_up(bound.lo), f64::INFINITY),
            Binary::Ge => Interval::new(bound.lo, f64::INFINITY),
            Binary::Eq => Interval::new(bound.lo, bound.hi),
            _ => return Some(()),
        };
        let mut r = current.intersect(allowed);
        r.nan = false;
        if self.integer.get(s).copied().unwrap_or(false) {
            r.lo = r.lo.ceil();
            r.hi = r.hi.floor();
        }
        if r.is_empty() {
            return None;
        }
        env[s] = r;
        Some(())
    }
}

/// Most boxes [`Analysis::assume`] keeps apart before joining them.
pub(super) const MAX_BOXES: usize = 16;

/// The comparison that holds when `f` does not (slots are never NaN).
pub(super) fn negate(f: Binary) -> Option<Binary> {
    Some(match f {
        Binary::Lt => Binary::Ge,
        Binary::Le => Binary::Gt,
        Binary::Gt => Binary::Le,
        Binary::Ge => Binary::Lt,
        Binary::Eq => Binary::Ne,
        Binary::Ne => Binary::Eq,
        _ => return None,
    })
}

/// `b op' a` equivalent to `a op b`.
pub(super) fn mirror(f: Binary) -> Option<Binary> {
    Some(match f {
        Binary::Lt => Binary::Gt,
        Binary::Le => Binary::Ge,
        Binary::Gt => Binary::Lt,
        Binary::Ge => Binary::Le,
        Binary::Eq => Binary::Eq,
        Binary::Ne => Binary::Ne,
        _ => return None,
    })
}
