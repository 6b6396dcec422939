//! One key for an edge between two vertex ids, as a `u64`: sortable (by
//! the first id, then the second) and hashable. Undirected keys put the
//! lower id first, so (a, b) and (b, a) meet; directed keys keep the order,
//! so a half-edge a → b and its twin b → a differ.

/// Key of the undirected edge {a, b}: lower id in the high half.
#[inline]
pub fn undirected(a: u32, b: u32) -> u64 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    directed(lo, hi)
}

/// Key of the half-edge a → b.
#[inline]
pub fn directed(a: u32, b: u32) -> u64 {
    (u64::from(a) << 32) | u64::from(b)
}

/// The two ids of a key, in key order (lower first for an undirected key).
#[inline]
pub fn ends(key: u64) -> (u32, u32) {
    ((key >> 32) as u32, key as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_round_trip_and_order() {
        assert_eq!(undirected(7, 3), undirected(3, 7));
        assert_ne!(directed(7, 3), directed(3, 7));
        assert_eq!(ends(undirected(9, 2)), (2, 9));
        assert_eq!(ends(directed(9, 2)), (9, 2));
        assert!(undirected(1, u32::MAX) < undirected(2, 3));
    }
}
