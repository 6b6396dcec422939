//! Per-element values an operator keeps beside the mesh while it works.
//!
//! Element ids are dense slot indices, so a region that covers a good part
//! of the mesh is best served by a slot-indexed vector (one load, no
//! hashing, no 100-byte hash entries: issue 17 measured `inset_region`
//! stalling on them); a small region in a big mesh by a hash map, so the
//! cost stays proportional to the region. The choice follows the same rule
//! as the weld's survivor map: dense from one element in eight.

use rustc_hash::{FxHashMap, FxHashSet};

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

/// A set of slot indices: one bit a slot when the set is a good part of
/// the slots (membership an operator tests for every corner of a big
/// region is then a shift and a mask, not a hash probe; a million slots
/// take 125 KB), hashed otherwise, so the cost follows the set, never the
/// mesh. Dense from one entry in 64 slots: the bitmap is then no larger
/// than the entries as words.
pub(crate) enum SlotSet {
    Bits(Vec<u64>),
    Hashed(FxHashSet<usize>),
}

impl SlotSet {
    /// A set for about `entries` indices below `capacity`.
    pub fn new(entries: usize, capacity: usize) -> Self {
        if capacity <= entries.saturating_mul(64) {
            Self::bits(capacity)
        } else {
            let mut set = FxHashSet::default();
            set.reserve(entries);
            SlotSet::Hashed(set)
        }
    }

    /// The bitmap form, for indices below `capacity`.
    pub fn bits(capacity: usize) -> Self {
        SlotSet::Bits(vec![0; capacity.div_ceil(64)])
    }

    #[inline]
    pub fn insert(&mut self, index: usize) {
        match self {
            SlotSet::Bits(words) => words[index / 64] |= 1 << (index % 64),
            SlotSet::Hashed(set) => {
                set.insert(index);
            }
        }
    }

    #[inline]
    pub fn contains(&self, index: usize) -> bool {
        match self {
            SlotSet::Bits(words) => words
                .get(index / 64)
                .is_some_and(|word| word & (1 << (index % 64)) != 0),
            SlotSet::Hashed(set) => set.contains(&index),
        }
    }

    /// The indices held, ascending.
    pub fn into_sorted(self) -> Vec<usize> {
        match self {
            SlotSet::Bits(words) => {
                let mut out = Vec::new();
                for (w, &word) in words.iter().enumerate() {
                    let mut rest = word;
                    while rest != 0 {
                        out.push(w * 64 + rest.trailing_zeros() as usize);
                        rest &= rest - 1;
                    }
                }
                out
            }
            SlotSet::Hashed(set) => {
                let mut out: Vec<usize> = set.into_iter().collect();
                out.sort_unstable();
                out
            }
        }
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
    fn slot_sets_hold_what_was_inserted_either_way() {
        for (entries, capacity) in [(4, 130), (1, 1000)] {
            let mut set = SlotSet::new(entries, capacity);
            assert_eq!(matches!(set, SlotSet::Bits(_)), entries * 64 >= capacity);
            for i in [129, 0, 63, 64, 0] {
                set.insert(i);
            }
            let held: Vec<usize> = (0..200).filter(|&i| set.contains(i)).collect();
            assert_eq!(held, [0, 63, 64, 129]);
            assert_eq!(set.into_sorted(), held);
        }
    }
}
