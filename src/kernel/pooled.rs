//! Layer storage as narrow indices into a table of distinct values.
//!
//! A G³ model's layers repeat values: a split edge copies its frame to the
//! new half, a grown node takes its edge's frame, ages count steps, radii
//! come from a few parameters. At 10⁶ primitives the synthetic grammar
//! stores 857k headings and lefts but only 71k distinct ones, 5 distinct
//! ages and 2 radii. So a layer keeps each distinct value once and, per
//! slot, an index 1, 2, 3 or 4 bytes wide (as wide as the table needs): the
//! frames take about a third of their plain bytes, ages and radii an
//! eighth or less (issue 38, deliverable 3).
//!
//! Values are interned bit for bit (`-0.0` and `0.0` stay apart): a copy
//! shares the index, and a written value is looked up in a small
//! direct-mapped cache of recent values, so equal values written close
//! together share one entry without a hash map the size of the layer.
//! When the table has doubled since it was last cleaned (and holds at
//! least half as many values as slots), entries no slot uses any more are
//! dropped and equal ones merged; if the values are then so many that
//! indices and table outweigh a plain vector (a NURBS parameter per
//! vertex), the layer turns into a plain vector for good. Every choice
//! depends on the sequence of writes alone, never on addresses or
//! threads, and reads return the same bits whichever form the layer is in.

use glam::DVec3;
use rustc_hash::FxHashMap;

use super::arena::reserve_growth;

/// Entries of the recent-value cache (a power of two): small enough to stay
/// in the first-level data cache, since every write of a new element's
/// value looks here; what it misses, compaction merges.
const TABLE: usize = 1 << 8;
/// Below this many distinct values a layer always stays pooled.
const MIN_POOL: usize = 1 << 12;

/// Runs `$body` on the index vector, whatever its width.
macro_rules! each_width {
    ($ids:expr, $v:ident => $body:expr) => {
        match $ids {
            Ids::U8($v) => $body,
            Ids::U16($v) => $body,
            Ids::U24($v) => $body,
            Ids::U32($v) => $body,
        }
    };
}

/// A value a layer can intern: compared and hashed by its bits.
pub trait PoolValue: Copy {
    fn bits(self) -> [u64; 3];
}

impl PoolValue for f64 {
    fn bits(self) -> [u64; 3] {
        [self.to_bits(), 0, 0]
    }
}

impl PoolValue for DVec3 {
    fn bits(self) -> [u64; 3] {
        self.to_array().map(f64::to_bits)
    }
}

impl PoolValue for i32 {
    fn bits(self) -> [u64; 3] {
        [u64::from(self as u32), 0, 0]
    }
}

impl PoolValue for u64 {
    fn bits(self) -> [u64; 3] {
        [self, 0, 0]
    }
}

/// A layer's stored prefix: pooled while its values repeat, else plain.
#[derive(Clone, Debug)]
pub enum Stored<T> {
    Pooled(Pooled<T>),
    Plain(Vec<T>),
}

impl<T: PoolValue> Stored<T> {
    /// Storage that pools values; `default` is what new slots hold.
    pub fn pooled(default: T) -> Self {
        Stored::Pooled(Pooled {
            ids: Ids::U8(Vec::new()),
            values: vec![default],
            recent: Vec::new(),
            compact_at: MIN_POOL,
            last: EMPTY,
        })
    }

    /// Storage for values that never repeat (lineage keys).
    pub fn plain() -> Self {
        Stored::Plain(Vec::new())
    }

    pub fn len(&self) -> usize {
        match self {
            Stored::Pooled(p) => p.ids.len(),
            Stored::Plain(v) => v.len(),
        }
    }

    #[inline]
    pub fn get(&self, slot: usize) -> Option<T> {
        match self {
            Stored::Pooled(p) => p.ids.get(slot).map(|i| p.values[i as usize]),
            Stored::Plain(v) => v.get(slot).copied(),
        }
    }

    /// Bytes in use and allocated.
    pub fn bytes(&self) -> (usize, usize) {
        let size = std::mem::size_of::<T>();
        match self {
            Stored::Pooled(p) => {
                let (ids, ids_reserved) = p.ids.bytes();
                let rest = p.recent.len() * std::mem::size_of::<Recent>();
                (
                    ids + p.values.len() * size + rest,
                    ids_reserved + p.values.capacity() * size + rest,
                )
            }
            Stored::Plain(v) => (v.len() * size, v.capacity() * size),
        }
    }

    /// Room for `additional` more slots ([`reserve_growth`]).
    pub fn reserve_growth(&mut self, additional: usize) {
        match self {
            Stored::Pooled(p) => each_width!(&mut p.ids, v => reserve_growth(v, additional)),
            Stored::Plain(v) => reserve_growth(v, additional),
        }
    }

    /// Grows the stored prefix to `len` slots holding `default`.
    pub fn extend_to(&mut self, len: usize, default: T) {
        match self {
            Stored::Pooled(p) => p.ids.resize(len),
            Stored::Plain(v) => v.resize(len, default),
        }
    }

    /// Stores `value` in `slot` (inside the prefix).
    pub fn write(&mut self, slot: usize, value: T) {
        match self {
            Stored::Pooled(p) => match p.intern(value) {
                Some(id) => p.ids.set(slot, id),
                None => {
                    let mut plain = p.to_plain();
                    plain[slot] = value;
                    *self = Stored::Plain(plain);
                }
            },
            Stored::Plain(v) => v[slot] = value,
        }
    }

    /// Stores every `(slot, value)` in turn, every slot below `end`; reads then return what the
    /// same writes one at a time would. A value other than `default` (the layer's) past the
    /// prefix grows it to `end` at once, not slot by slot (the slots between read the default
    /// either way). A pooled layer interns the values exactly, in a map of the values this call
    /// added, rather than through the cache of recent values: a NURBS grid's v parameters cycle
    /// through more values than the cache holds, and there every miss adds an entry a
    /// compaction must merge later (issue 38).
    pub fn write_many<I: IntoIterator<Item = (usize, T)>>(
        &mut self,
        default: T,
        end: usize,
        writes: I,
    ) {
        let past =
            |len: usize, slot: usize, value: T| slot >= len && value.bits() == default.bits();
        // The writes into a plain vector: those from the start, or those
        // left once a pooled layer has turned plain.
        let write_plain = |v: &mut Vec<T>, writes: &mut I::IntoIter| {
            for (slot, value) in writes {
                if !past(v.len(), slot, value) {
                    if slot >= v.len() {
                        grow_to(v, end.max(slot + 1), default);
                    }
                    v[slot] = value;
                }
            }
        };
        let mut writes = writes.into_iter();
        let mut plain = match self {
            Stored::Plain(v) => {
                write_plain(v, &mut writes);
                return;
            }
            Stored::Pooled(p) => {
                let mut added = FxHashMap::default();
                // The value written last and its index: a run of one value skips the map.
                let mut last: Option<([u64; 3], u32)> = None;
                loop {
                    let Some((slot, value)) = writes.next() else {
                        return;
                    };
                    if past(p.ids.len(), slot, value) {
                        continue;
                    }
                    if slot >= p.ids.len() {
                        p.ids.resize(end.max(slot + 1));
                    }
                    let bits = value.bits();
                    let id = match last {
                        Some((b, id)) if b == bits => Some(id),
                        _ => p.intern_exact(value, &mut added),
                    };
                    match id {
                        Some(id) => {
                            p.ids.set(slot, id);
                            last = Some((bits, id));
                        }
                        None => {
                            let mut plain = p.to_plain();
                            plain[slot] = value;
                            break plain;
                        }
                    }
                }
            }
        };
        write_plain(&mut plain, &mut writes);
        *self = Stored::Plain(plain);
    }

    /// Slot `to` takes slot `from`'s value (both inside the prefix).
    pub fn copy(&mut self, from: usize, to: usize) {
        match self {
            Stored::Pooled(p) => {
                let id = p.ids.get(from).expect("inside the prefix");
                p.ids.set(to, id);
            }
            Stored::Plain(v) => v[to] = v[from],
        }
    }
}

/// Distinct values and an index per slot.
#[derive(Clone, Debug)]
pub struct Pooled<T> {
    ids: Ids,
    /// Distinct values; entry 0 is the layer's default.
    values: Vec<T>,
    /// Recently written values and their `values` index, by the hash of
    /// their bits (the bits are kept here so a lookup reads one cache
    /// line, not the table); allocated at the first non-default write.
    recent: Vec<Recent>,
    /// Table size that triggers the next compaction: twice what the last
    /// one kept (so compactions cost O(1) a write), at least half the slots.
    compact_at: usize,
    /// The value written last and its index.
    last: Recent,
}

/// An entry of the recent-value cache.
#[derive(Copy, Clone, Debug)]
struct Recent {
    bits: [u64; 3],
    /// `u32::MAX`: empty.
    id: u32,
}

const EMPTY: Recent = Recent {
    bits: [0; 3],
    id: u32::MAX,
};

fn cache_slot([x, y, z]: [u64; 3]) -> usize {
    let h = (x ^ y.rotate_left(21) ^ z.rotate_left(42)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    (h >> 56) as usize & (TABLE - 1)
}

impl<T: PoolValue> Pooled<T> {
    /// The index of `value`, added if new; `None` when the values are
    /// mostly distinct and the layer should be plain.
    fn intern(&mut self, value: T) -> Option<u32> {
        let bits = value.bits();
        if bits == self.values[0].bits() {
            return Some(0);
        }
        // A run of equal writes (a step's age, a radius parameter) stays
        // out of the cache table.
        if self.last.id != u32::MAX && self.last.bits == bits {
            return Some(self.last.id);
        }
        if self.recent.is_empty() {
            self.recent = vec![EMPTY; TABLE];
        }
        let at = cache_slot(bits);
        let cached = self.recent[at];
        if cached.id != u32::MAX && cached.bits == bits {
            self.last = cached;
            return Some(cached.id);
        }
        let id = self.push_new(value)?;
        self.recent[at] = Recent { bits, id };
        self.last = Recent { bits, id };
        Some(id)
    }

    /// Adds `value` as a new entry, compacting first when the table has grown to
    /// `compact_at`; `None` when the layer should then be plain.
    fn push_new(&mut self, value: T) -> Option<u32> {
        if self.values.len() >= self.compact_at {
            self.compact();
            // Plain once pooling no longer saves memory: indices of `w`
            // bytes and the values cost more than the values per slot.
            let (n, d) = (self.ids.len(), self.values.len());
            let size = std::mem::size_of::<T>();
            let w = width_of(d as u32);
            if d >= MIN_POOL && d * size >= n * size.saturating_sub(w) {
                return None;
            }
            self.compact_at = (2 * d).max(n / 2).max(MIN_POOL);
        }
        let id = u32::try_from(self.values.len()).ok()?;
        self.values.push(value);
        Some(id)
    }

    /// The index of `value` for [`Stored::write_many`]: the default, or the one `added` maps it
    /// to, or a new entry ([`Pooled::push_new`], which may compact: `added` then starts over);
    /// `None` when the layer should be plain.
    fn intern_exact(&mut self, value: T, added: &mut FxHashMap<[u64; 3], u32>) -> Option<u32> {
        let bits = value.bits();
        if bits == self.values[0].bits() {
            return Some(0);
        }
        if let Some(&id) = added.get(&bits) {
            return Some(id);
        }
        if self.values.len() >= self.compact_at {
            added.clear();
        }
        let id = self.push_new(value)?;
        added.insert(bits, id);
        Some(id)
    }

    /// Drops the values no slot uses and merges equal ones the cache did
    /// not catch, keeping the rest in order of first use by slot (so the
    /// result depends on the slots alone), and forgets the cache.
    fn compact(&mut self) {
        let mut remap = vec![u32::MAX; self.values.len()];
        remap[0] = 0;
        let mut kept = vec![self.values[0]];
        let mut by_bits: FxHashMap<[u64; 3], u32> = FxHashMap::default();
        by_bits.insert(self.values[0].bits(), 0);
        for slot in 0..self.ids.len() {
            let old = self.ids.get(slot).expect("inside the prefix") as usize;
            if remap[old] == u32::MAX {
                let value = self.values[old];
                let next = kept.len() as u32;
                let id = *by_bits.entry(value.bits()).or_insert(next);
                if id == next {
                    kept.push(value);
                }
                remap[old] = id;
            }
            self.ids.set(slot, remap[old]);
        }
        self.values = kept;
        self.recent.fill(EMPTY);
        self.last = EMPTY;
    }

    fn to_plain(&self) -> Vec<T> {
        (0..self.ids.len())
            .map(|slot| self.values[self.ids.get(slot).expect("inside the prefix") as usize])
            .collect()
    }
}

/// Grows `v` to `len` entries of `fill`, by [`reserve_growth`] rather
/// than doubling: a frame layer's indices grow a slot at a time as
/// elements are made and widen once or twice. Measured at 10⁶ G³
/// primitives: 6 MB less peak RSS than doubling (the same for plain
/// lineage keys, which the per-step reserve already sizes, measured 1 MB
/// worse, so they keep `Vec::resize`).
fn grow_to<T: Clone>(v: &mut Vec<T>, len: usize, fill: T) {
    reserve_growth(v, len.saturating_sub(v.len()));
    v.resize(len, fill);
}

/// Indices as narrow as the table allows: widened (once per width) when
/// an index no longer fits. Three bytes is a width of its own: the frames
/// of a 10⁶-primitive model number about 71k, just past two bytes.
#[derive(Clone, Debug)]
enum Ids {
    U8(Vec<u8>),
    U16(Vec<u16>),
    U24(Vec<[u8; 3]>),
    U32(Vec<u32>),
}

/// Bytes an index needs to hold `id`.
fn width_of(id: u32) -> usize {
    match id {
        0..=0xFF => 1,
        0x100..=0xFFFF => 2,
        0x1_0000..=0xFF_FFFF => 3,
        _ => 4,
    }
}

impl Ids {
    fn len(&self) -> usize {
        each_width!(self, v => v.len())
    }

    fn capacity(&self) -> usize {
        each_width!(self, v => v.capacity())
    }

    fn width(&self) -> usize {
        match self {
            Ids::U8(_) => 1,
            Ids::U16(_) => 2,
            Ids::U24(_) => 3,
            Ids::U32(_) => 4,
        }
    }

    fn bytes(&self) -> (usize, usize) {
        (self.width() * self.len(), self.width() * self.capacity())
    }

    #[inline]
    fn get(&self, slot: usize) -> Option<u32> {
        match self {
            Ids::U8(v) => v.get(slot).map(|&i| u32::from(i)),
            Ids::U16(v) => v.get(slot).map(|&i| u32::from(i)),
            Ids::U24(v) => v
                .get(slot)
                .map(|&[a, b, c]| u32::from_le_bytes([a, b, c, 0])),
            Ids::U32(v) => v.get(slot).copied(),
        }
    }

    fn set(&mut self, slot: usize, id: u32) {
        self.widen_for(id);
        match self {
            Ids::U8(v) => v[slot] = id as u8,
            Ids::U16(v) => v[slot] = id as u16,
            Ids::U24(v) => {
                let [a, b, c, _] = id.to_le_bytes();
                v[slot] = [a, b, c];
            }
            Ids::U32(v) => v[slot] = id,
        }
    }

    /// Makes the indices wide enough to hold `id`.
    fn widen_for(&mut self, id: u32) {
        let width = width_of(id);
        if width <= self.width() {
            return;
        }
        let old = &*self;
        let ids = (0..old.len()).map(|slot| old.get(slot).unwrap_or(0));
        *self = match width {
            2 => Ids::U16(ids.map(|i| i as u16).collect()),
            3 => Ids::U24(
                ids.map(|i| {
                    let [a, b, c, _] = i.to_le_bytes();
                    [a, b, c]
                })
                .collect(),
            ),
            _ => Ids::U32(ids.collect()),
        };
    }

    /// Grows to `len` slots holding index 0.
    fn resize(&mut self, len: usize) {
        each_width!(self, v => grow_to(v, len, Default::default()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn values<T>(s: &Stored<T>) -> usize {
        match s {
            Stored::Pooled(p) => p.values.len(),
            Stored::Plain(_) => usize::MAX,
        }
    }

    #[test]
    fn copies_and_repeated_values_share_one_entry() {
        let mut s = Stored::pooled(DVec3::Z);
        s.extend_to(100, DVec3::Z);
        for slot in 0..50 {
            s.write(slot, DVec3::X);
        }
        for slot in 50..100 {
            s.copy(slot - 50, slot);
        }
        assert_eq!(values(&s), 2);
        assert_eq!(s.get(99), Some(DVec3::X));
        assert_eq!(s.get(100), None);
        s.write(3, DVec3::Z);
        assert_eq!(values(&s), 2, "the default is entry 0");
        assert_eq!(s.get(3), Some(DVec3::Z));
        assert_eq!(s.bytes().0, 100 + 2 * 24 + 32 * TABLE, "one byte a slot");
    }

    /// 70k frames, just past two bytes of index: three bytes a slot, not
    /// four, and the values once each.
    #[test]
    fn past_two_bytes_an_index_takes_three() {
        let n = 100_000;
        let distinct = 70_000;
        let mut s = Stored::pooled(DVec3::ZERO);
        s.extend_to(n, DVec3::ZERO);
        let value = |k: usize| DVec3::new(k as f64, 1.0, -(k as f64));
        for slot in 0..n {
            s.write(slot, value(slot % distinct + 1));
        }
        assert!(matches!(&s, Stored::Pooled(p) if matches!(p.ids, Ids::U24(_))));
        for slot in (0..n).step_by(997) {
            assert_eq!(s.get(slot), Some(value(slot % distinct + 1)));
        }
        // The default, each value once, and at most the one written just
        // after a compaction again.
        assert!((distinct + 1..=distinct + 2).contains(&values(&s)));
        assert_eq!(s.bytes().0, 3 * n + 24 * values(&s) + 32 * TABLE);
    }

    #[test]
    fn zero_and_negative_zero_stay_apart() {
        let mut s = Stored::pooled(0.0f64);
        s.extend_to(2, 0.0);
        s.write(1, -0.0);
        assert!(s.get(1).unwrap().is_sign_negative());
        assert!(s.get(0).unwrap().is_sign_positive());
    }

    /// Random writes and copies read back exactly, through one- and
    /// two-byte indices, compactions and the turn to a plain vector (three
    /// bytes: `past_two_bytes_an_index_takes_three`).
    #[test]
    fn reads_never_change_through_widening_compaction_and_plain() {
        for distinct in [3u32, 300, 70_000, 1_000_000] {
            let n = 20_000;
            let mut s = Stored::pooled(-1i32);
            s.extend_to(n, -1);
            let mut expect = vec![-1i32; n];
            let mut x = 12345u64;
            for k in 0..200_000u64 {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let slot = (x >> 33) as usize % n;
                if k % 5 == 0 {
                    let from = (x >> 13) as usize % n;
                    s.copy(from, slot);
                    expect[slot] = expect[from];
                } else {
                    let v = ((x >> 40) as u32 % distinct) as i32;
                    s.write(slot, v);
                    expect[slot] = v;
                }
            }
            for (slot, v) in expect.iter().enumerate() {
                assert_eq!(s.get(slot), Some(*v), "{distinct} distinct, slot {slot}");
            }
            let plain = matches!(s, Stored::Plain(_));
            assert_eq!(plain, distinct >= 70_000, "{distinct} distinct");
            if !plain {
                assert!(values(&s) <= (n / 2).max(MIN_POOL) + 1);
            }
        }
    }

    /// The slots and values `write_many` is given, in turn: runs of one value, values cycling
    /// through `distinct`, and the default, over slots inside and past the prefix.
    fn writes(distinct: u32, n: usize, seed: u64) -> Vec<(usize, i32)> {
        let mut x = seed;
        (0..n)
            .map(|k| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let value = match k % 7 {
                    0 => -1,
                    1 | 2 => 7,
                    _ => ((x >> 40) as u32 % distinct) as i32,
                };
                ((x >> 33) as usize % (2 * n), value)
            })
            .collect()
    }

    #[test]
    fn many_writes_read_as_the_same_writes_one_at_a_time() {
        for distinct in [3u32, 300, 5_000, 1_000_000] {
            let n = 20_000;
            let mut one = Stored::pooled(-1i32);
            let mut many = Stored::pooled(-1i32);
            // A prefix of n slots written first, then a run reaching past it.
            for s in [&mut one, &mut many] {
                s.extend_to(n, -1);
                s.write(3, 9);
            }
            for round in 0..2u64 {
                let run = writes(distinct, n, 99 + round);
                for &(slot, value) in &run {
                    if slot >= one.len() {
                        if value == -1 {
                            continue;
                        }
                        one.extend_to(slot + 1, -1);
                    }
                    one.write(slot, value);
                }
                many.write_many(-1, 2 * n, run);
            }
            for slot in 0..2 * n + 1 {
                assert_eq!(
                    many.get(slot),
                    one.get(slot),
                    "{distinct} distinct, slot {slot}"
                );
            }
            if (distinct as usize) < MIN_POOL {
                // The default, 9, and each call's 7 and values once.
                let most = 2 + 2 * (distinct as usize + 1);
                assert!(values(&many) <= most, "{distinct}: interned exactly");
            }
        }
        // Values that never repeat turn the layer plain partway, and the rest still land.
        let mut s = Stored::pooled(0u64);
        s.write_many(0, 50_000, (0..50_000).map(|k| (k, k as u64 + 1)));
        assert!(matches!(s, Stored::Plain(_)));
        assert!((0..50_000).all(|k| s.get(k) == Some(k as u64 + 1)));
        assert_eq!(s.get(50_000), None);
    }
}
