//! What a node promises about its field (decision D1) and where its
//! solid lies: [`Contract`] (Lipschitz constant, exactness outside and
//! inside), its summary [`Exactness`], [`Bounds`] (a box and a growth that
//! hold every sublevel set) and [`NodeInfo`], and how an operation's
//! follow from its children's (spec §1.4 tables). See [`super::tree`].

use glam::DVec3;

use crate::sdf::aabb::Aabb;

/// Summary of a [`Contract`] (decision D1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Exactness {
    /// |f| is the Euclidean distance to the surface everywhere.
    Exact,
    /// 1-Lipschitz with the right sign, so |f| ≤ the distance.
    Bound,
    /// L-Lipschitz with L > 1: divide by L before culling on it.
    Lipschitz(f64),
}

/// What a node's function promises.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contract {
    /// Lipschitz constant (1 for every node kind in this module).
    pub lipschitz: f64,
    /// f is the exact distance where f > 0.
    pub exact_outside: bool,
    /// f is the exact (negated) distance where f < 0.
    pub exact_inside: bool,
}

impl Contract {
    pub(super) const EXACT: Contract = Contract {
        lipschitz: 1.0,
        exact_outside: true,
        exact_inside: true,
    };

    pub(super) fn with(lipschitz: f64, exact_outside: bool, exact_inside: bool) -> Contract {
        Contract {
            lipschitz,
            exact_outside,
            exact_inside,
        }
    }

    /// The summary kind.
    pub fn exactness(&self) -> Exactness {
        if self.lipschitz > 1.0 {
            Exactness::Lipschitz(self.lipschitz)
        } else if self.exact_inside && self.exact_outside {
            Exactness::Exact
        } else {
            Exactness::Bound
        }
    }
}

/// Sublevel-set bounds: `{f ≤ t} ⊂ aabb.grown(growth · t)` for t ≥ 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    pub aabb: Aabb,
    pub growth: f64,
}

impl Bounds {
    /// The box of `{f ≤ t}`.
    pub fn at(&self, t: f64) -> Aabb {
        self.aabb.grown(self.growth * t.max(0.0))
    }
}

/// Validated facts about one node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeInfo {
    pub contract: Contract,
    pub bounds: Bounds,
    /// 1 for a leaf, 1 + the deepest child otherwise.
    pub depth: usize,
}

impl NodeInfo {
    pub(super) fn exact_outside(&self) -> bool {
        self.contract.exact_outside && self.contract.lipschitz <= 1.0
    }
    pub(super) fn exact_inside(&self) -> bool {
        self.contract.exact_inside && self.contract.lipschitz <= 1.0
    }
}

/// Exact-outside functions have growth 1 whatever their children had.
pub(super) fn fix_growth(c: Contract, b: Bounds) -> Bounds {
    if c.exact_outside && c.lipschitz <= 1.0 {
        Bounds {
            aabb: b.aabb,
            growth: 1.0,
        }
    } else {
        b
    }
}

/// Contract and bounds of an n-ary (smooth, when k > 0) union or
/// intersection.
pub(super) fn combine(children: &[NodeInfo], union: bool, k: f64) -> (Contract, Bounds) {
    let l = children
        .iter()
        .map(|c| c.contract.lipschitz)
        .fold(1.0, f64::max);
    let growth = children.iter().map(|c| c.bounds.growth).fold(0.0, f64::max);
    if children.len() == 1 {
        return (children[0].contract, children[0].bounds);
    }
    let contract = if k > 0.0 {
        Contract::with(l, false, false)
    } else if union {
        Contract::with(l, children.iter().all(|c| c.exact_outside()), false)
    } else {
        Contract::with(l, false, children.iter().all(|c| c.exact_inside()))
    };
    let mut aabb = if union { Aabb::EMPTY } else { Aabb::EVERYTHING };
    for c in children {
        // Quadratic smin ≥ min − k/4, so {smin ≤ t} ⊂ {min ≤ t + k/4}.
        let b = c.bounds.at(k * 0.25);
        aabb = if union {
            aabb.union(&b)
        } else {
            aabb.intersection(&b)
        };
    }
    (contract, fix_growth(contract, Bounds { aabb, growth }))
}

/// Box of the half-space `n·x ≤ d` (unit n): bounded on one side only when
/// n is an axis.
pub(super) fn half_space_box(n: DVec3, d: f64) -> Aabb {
    let mut b = Aabb::EVERYTHING;
    for a in 0..3 {
        let others_zero = (0..3).all(|o| o == a || n[o] == 0.0);
        if others_zero && n[a] != 0.0 {
            if n[a] > 0.0 {
                b.hi[a] = d / n[a];
            } else {
                b.lo[a] = d / n[a];
            }
        }
    }
    b
}
