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

    /// Every member's representative, `find(i)` for each `i`, in one
    /// ascending pass: a parent is never above its child (unions hang the
    /// higher root under the lower, halving only moves a link lower), so
    /// when `i` is reached its parent already points at its root.
    pub fn into_roots(mut self) -> Vec<u32> {
        for i in 0..self.parent.len() {
            let parent = self.parent[i] as usize;
            self.parent[i] = self.parent[parent];
        }
        self.parent
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

    #[test]
    fn into_roots_is_find_of_every_member() {
        // Long chains built in both directions, with finds in between so
        // that some links are already halved and some are not.
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = |n: u64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % n) as u32
        };
        for n in [1u32, 2, 7, 100, 5000] {
            let mut u = UnionFind::new(n as usize);
            for step in 0..n * 2 {
                let (a, b) = (next(u64::from(n)), next(u64::from(n)));
                u.union(a, b);
                if step % 3 == 0 {
                    u.find(next(u64::from(n)));
                }
            }
            let mut expected = u.clone();
            let expected: Vec<u32> = (0..n).map(|i| expected.find(i)).collect();
            assert_eq!(u.into_roots(), expected, "n = {n}");
        }
        let mut chain = UnionFind::new(6);
        for i in (1..6).rev() {
            chain.union(i, i - 1);
        }
        assert_eq!(chain.into_roots(), [0; 6]);
    }
}
