//! Per-element values an operator keeps beside the mesh while it works.
//!
//! Element ids are dense slot indices, so a region that covers a good part
//! of the mesh is best served by a slot-indexed vector (one load, no
//! hashing, no 100-byte hash entries: issue 17 measured `inset_region`
//! stalling on them); a small region in a big mesh by a hash map, so the
//! cost stays proportional to the region. The choice follows the same rule
//! as the weld's survivor map: dense from one element in eight.

use rustc_hash::FxHashMap;

/// Values keyed by an element's slot index.
pub(crate) enum SideTable<V> {
    Dense(Vec<Option<V>>),
    Sparse(FxHashMap<usize, V>),
}

impl<V> SideTable<V> {
    /// A table for about `entries` values among `capacity` slots.
    pub fn new(entries: usize, capacity: usize) -> Self {
        if capacity <= entries.saturating_mul(8) {
            SideTable::Dense(std::iter::repeat_with(|| None).take(capacity).collect())
        } else {
            let mut map = FxHashMap::default();
            map.reserve(entries);
            SideTable::Sparse(map)
        }
    }

    pub fn insert(&mut self, index: usize, value: V) {
        match self {
            SideTable::Dense(slots) => slots[index] = Some(value),
            SideTable::Sparse(map) => {
                map.insert(index, value);
            }
        }
    }

    #[inline]
    pub fn get(&self, index: usize) -> Option<&V> {
        match self {
            SideTable::Dense(slots) => slots.get(index).and_then(Option::as_ref),
            SideTable::Sparse(map) => map.get(&index),
        }
    }

    #[inline]
    pub fn get_mut(&mut self, index: usize) -> Option<&mut V> {
        match self {
            SideTable::Dense(slots) => slots.get_mut(index).and_then(Option::as_mut),
            SideTable::Sparse(map) => map.get_mut(&index),
        }
    }

    pub fn contains(&self, index: usize) -> bool {
        self.get(index).is_some()
    }
}

/// A set of slot indices as one bit a slot: membership tests that an
/// operator makes for every corner of a big region (is this vertex on the
/// outline?) are a shift and a mask, not a hash probe. A million slots
/// take 125 KB.
pub(crate) struct SlotBits(Vec<u64>);

impl SlotBits {
    pub fn new(capacity: usize) -> Self {
        SlotBits(vec![0; capacity.div_ceil(64)])
    }

    pub fn insert(&mut self, index: usize) {
        self.0[index / 64] |= 1 << (index % 64);
    }

    #[inline]
    pub fn contains(&self, index: usize) -> bool {
        self.0
            .get(index / 64)
            .is_some_and(|word| word & (1 << (index % 64)) != 0)
    }

    /// The indices held, ascending.
    pub fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.0.iter().enumerate().flat_map(|(w, &word)| {
            let mut rest = word;
            std::iter::from_fn(move || {
                (rest != 0).then(|| {
                    let bit = rest.trailing_zeros() as usize;
                    rest &= rest - 1;
                    w * 64 + bit
                })
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_and_sparse_tables_agree() {
        for (entries, capacity) in [(10, 20), (2, 1000)] {
            let mut t = SideTable::new(entries, capacity);
            assert_eq!(matches!(t, SideTable::Dense(_)), entries * 8 >= capacity);
            t.insert(3, 'a');
            t.insert(7, 'b');
            *t.get_mut(7).unwrap() = 'c';
            assert_eq!(t.get(3), Some(&'a'));
            assert_eq!(t.get(7), Some(&'c'));
            assert!(!t.contains(4));
            assert_eq!(t.get(capacity + 5), None);
        }
    }

    #[test]
    fn slot_bits_hold_what_was_inserted() {
        let mut bits = SlotBits::new(130);
        for i in [0, 63, 64, 129] {
            bits.insert(i);
        }
        let held: Vec<usize> = (0..200).filter(|&i| bits.contains(i)).collect();
        assert_eq!(held, [0, 63, 64, 129]);
        assert_eq!(bits.iter().collect::<Vec<_>>(), held);
    }
}
