//! Slot arenas with deterministic slot recycling.
//!
//! Freed slots are reused lowest index first. This keeps ids small and makes
//! them a pure function of the operation sequence (thesis 003 §4.1 recycles
//! deleted ids the same way), which the byte-identical output guarantee needs.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use rayon::prelude::*;

#[derive(Clone, Debug)]
pub(crate) struct Arena<T> {
    slots: Vec<Option<T>>,
    free: BinaryHeap<Reverse<u32>>,
    live: usize,
}

impl<T> Default for Arena<T> {
    fn default() -> Self {
        Self {
            slots: Vec::new(),
            free: BinaryHeap::new(),
            live: 0,
        }
    }
}

impl<T> Arena<T> {
    /// Stores `value` in the lowest free slot (or a new one) and returns its index.
    pub fn insert(&mut self, value: T) -> u32 {
        self.live += 1;
        if let Some(Reverse(index)) = self.free.pop() {
            self.slots[index as usize] = Some(value);
            index
        } else {
            let index = u32::try_from(self.slots.len()).expect("arena exceeds u32 slots");
            self.slots.push(Some(value));
            index
        }
    }

    /// Room for `additional` more elements without growing (when no slot
    /// is free to reuse).
    pub fn reserve(&mut self, additional: usize) {
        self.slots
            .reserve(additional.saturating_sub(self.free.len()));
    }

    /// Room for `additional` more elements, grown by at least an eighth
    /// rather than doubled: a step that knows what it adds grows its
    /// arenas once, and the spare capacity (which a reused heap block has
    /// already touched) stays within 12.5 % while growth stays geometric,
    /// so many small steps still copy each slot O(1) times.
    pub fn reserve_growth(&mut self, additional: usize) {
        reserve_growth(&mut self.slots, additional.saturating_sub(self.free.len()));
    }

    /// Whether a freed slot waits to be reused (the next insert takes it,
    /// not a new slot past the end).
    pub fn has_free(&self) -> bool {
        !self.free.is_empty()
    }

    /// Stores `values`, made in parallel, in new slots past the last one,
    /// in order: the first gets slot [`Arena::capacity`]. Only when no
    /// freed slot waits ([`Arena::has_free`]), or these would be the ids
    /// inserting one by one gives.
    pub fn par_extend_fresh<I>(&mut self, values: I)
    where
        I: IndexedParallelIterator<Item = T>,
        T: Send,
    {
        debug_assert!(self.free.is_empty());
        let before = self.slots.len();
        self.slots.par_extend(values.map(Some));
        self.live += self.slots.len() - before;
    }

    /// Calls `update` on the live element at each of `ids` (whose slots,
    /// `index(id)`, strictly ascend), in parallel: the slots are cut into
    /// disjoint runs, each with the ids it holds, so each element is
    /// written where it lies, with no buffer of results to gather and
    /// copy back.
    pub fn par_update_ascending<I, F>(
        &mut self,
        ids: &[I],
        index: impl Fn(&I) -> u32 + Sync,
        update: F,
    ) where
        I: Sync,
        F: Fn(&mut T) + Sync,
        T: Send,
    {
        /// Ids per parallel task.
        const RUN: usize = 2048;
        debug_assert!(ids.windows(2).all(|w| index(&w[0]) < index(&w[1])));
        let mut runs = Vec::with_capacity(ids.len().div_ceil(RUN));
        let mut rest: &mut [Option<T>] = &mut self.slots;
        let mut base = 0;
        for run in ids.chunks(RUN) {
            let end = index(&run[run.len() - 1]) as usize + 1;
            let (here, after) = std::mem::take(&mut rest).split_at_mut(end - base);
            runs.push((base, here, run));
            rest = after;
            base = end;
        }
        runs.into_par_iter().for_each(|(base, slots, run)| {
            for id in run {
                let slot = index(id) as usize - base;
                update(slots[slot].as_mut().expect("live slot"));
            }
        });
    }

    pub fn remove(&mut self, index: u32) -> Option<T> {
        let value = self.slots.get_mut(index as usize)?.take()?;
        self.free.push(Reverse(index));
        self.live -= 1;
        Some(value)
    }

    #[inline]
    pub fn get(&self, index: u32) -> Option<&T> {
        self.slots.get(index as usize)?.as_ref()
    }

    #[inline]
    pub fn get_mut(&mut self, index: u32) -> Option<&mut T> {
        self.slots.get_mut(index as usize)?.as_mut()
    }

    #[inline]
    pub fn contains(&self, index: u32) -> bool {
        self.get(index).is_some()
    }

    /// Number of live elements.
    #[inline]
    pub fn len(&self) -> usize {
        self.live
    }

    /// Number of slots, live or free: every live index is below this.
    #[inline]
    pub fn capacity(&self) -> usize {
        self.slots.len()
    }

    /// Live elements in index order.
    pub fn iter(&self) -> impl Iterator<Item = (u32, &T)> + '_ {
        self.slots
            .iter()
            .enumerate()
            .filter_map(|(i, slot)| slot.as_ref().map(|value| (i as u32, value)))
    }

    /// Bytes of the slots in use and of the slot vector's reserve, for the
    /// memory report ([`crate::kernel::Mesh::memory`]).
    pub fn bytes(&self) -> (usize, usize) {
        let slot = std::mem::size_of::<Option<T>>();
        (self.slots.len() * slot, self.slots.capacity() * slot)
    }

    /// Indices of free slots, for the validator.
    pub fn free_slots(&self) -> impl Iterator<Item = u32> + '_ {
        self.free.iter().map(|Reverse(i)| *i)
    }
}

/// Room for `additional` more entries of `v`, grown by at least an eighth
/// of its length rather than doubled: how arenas and layers grow (issue
/// 38, deliverable 3). Spare capacity stays within 12.5 % (doubling left up
/// to half of a megabytes-long vector reserved, in heap blocks later copied
/// out of), and growth stays geometric, so each entry is copied O(1) times.
pub(super) fn reserve_growth<T>(v: &mut Vec<T>, additional: usize) {
    if v.capacity() - v.len() < additional {
        v.reserve_exact(additional.max(v.len() / 8));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recycles_lowest_free_slot_first() {
        let mut arena = Arena::default();
        for i in 0..5 {
            assert_eq!(arena.insert(i), i);
        }
        arena.remove(3);
        arena.remove(1);
        assert_eq!(arena.len(), 3);
        assert_eq!(arena.insert(10), 1);
        assert_eq!(arena.insert(11), 3);
        assert_eq!(arena.insert(12), 5);
        assert_eq!(arena.get(1), Some(&10));
        assert!(arena.remove(9).is_none());
        assert!(arena.remove(1).is_some());
        assert!(arena.remove(1).is_none(), "double free must be refused");
    }

    #[test]
    fn par_update_ascending_writes_exactly_the_listed_slots() {
        // Runs of 2,048 ids cut the slots at ids that are not run ends;
        // sparse, dense, first-slot and last-slot lists, and no list.
        let n = 20_000u32;
        let lists: Vec<Vec<u32>> = vec![
            (0..n).collect(),
            (0..n).filter(|i| i % 7 == 3).collect(),
            vec![0, n - 1],
            (0..n)
                .filter(|i| i.wrapping_mul(2654435761) >> 29 == 0)
                .collect(),
            Vec::new(),
        ];
        for list in lists {
            let mut arena = Arena::default();
            for i in 0..n {
                arena.insert(u64::from(i));
            }
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(2)
                .build()
                .unwrap();
            pool.install(|| arena.par_update_ascending(&list, |&i| i, |v| *v += 1_000_000));
            for i in 0..n {
                let bumped = list.binary_search(&i).is_ok();
                let expected = u64::from(i) + if bumped { 1_000_000 } else { 0 };
                assert_eq!(arena.get(i), Some(&expected), "slot {i}");
            }
        }
    }
}
