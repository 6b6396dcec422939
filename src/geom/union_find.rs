//! Disjoint sets over `0..n` whose representative is always the lowest
//! member, so groupings never depend on the order unions are made in.

/// Union–find with path halving; [`UnionFind::find`] returns the lowest
/// index of the set.
#[derive(Debug, Clone)]
pub struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    /// `n` singletons.
    pub fn new(n: usize) -> Self {
        Self {
            parent: (0..n as u32).collect(),
        }
    }

    /// The lowest member of `i`'s set.
    pub fn find(&mut self, mut i: u32) -> u32 {
        while self.parent[i as usize] != i {
            let grand = self.parent[self.parent[i as usize] as usize];
            self.parent[i as usize] = grand;
            i = grand;
        }
        i
    }

    /// Joins the sets of `a` and `b` (the lower representative stays).
    pub fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (low, high) = (ra.min(rb), ra.max(rb));
            self.parent[high as usize] = low;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn representatives_are_the_lowest_member_whatever_the_order() {
        for order in [[(3, 1), (1, 4), (6, 5)], [(6, 5), (4, 1), (1, 3)]] {
            let mut u = UnionFind::new(7);
            for (a, b) in order {
                u.union(a, b);
            }
            let roots: Vec<u32> = (0..7).map(|i| u.find(i)).collect();
            assert_eq!(roots, [0, 1, 2, 1, 1, 5, 5]);
        }
    }
}
