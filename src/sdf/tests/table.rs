//! The marching-cubes table checked against itself.

use crate::sdf::table::{corner_offset, edge_info, face_corners, table};

/// Undirected segments of face `f` in an entry, as pairs of face-local edge
/// positions (0..4 around the face), with their direction.
fn face_segments(case: usize, mask: usize, f: usize) -> Vec<(usize, usize)> {
    let e = table().entry(case, mask);
    let fc = face_corners(f);
    let pos_of = |ce: usize| -> usize {
        let (c, axis) = edge_info(ce);
        let c1 = c | (1 << axis);
        (0..4)
            .find(|&i| {
                (fc[i] == c && fc[(i + 1) % 4] == c1) || (fc[i] == c1 && fc[(i + 1) % 4] == c)
            })
            .unwrap()
    };
    let mut v = Vec::new();
    for ce in 0..12 {
        if e.seg_face[ce] == f as u8 {
            v.push((pos_of(ce), pos_of(e.next[ce] as usize)));
        }
    }
    v.sort();
    v
}

#[test]
fn every_entry_is_a_set_of_closed_disks() {
    let t = table();
    // Distinct entries (irrelevant mask bits cleared) with a centred loop:
    // loops through three ambiguous faces.
    let distinct = (0..256usize)
        .flat_map(|c| (0..64usize).map(move |m| (c, m)))
        .filter(|&(c, m)| m & !(t.ambiguous[c] as usize) == 0 && !t.entry(c, m).centered.is_empty())
        .count();
    assert_eq!(distinct, 116);
    for case in 0..256usize {
        for mask in 0..64usize {
            let e = t.entry(case, mask);
            // Every crossed edge is in exactly one loop; loops close.
            for ce in 0..12 {
                let (c, axis) = edge_info(ce);
                let crosses = ((case >> c) & 1) != ((case >> (c | (1 << axis))) & 1);
                assert_eq!(crosses, e.edge_loop[ce] != 0xFF, "case {case} edge {ce}");
                if crosses {
                    assert_eq!(e.edge_loop[e.next[ce] as usize], e.edge_loop[ce]);
                }
            }
            // Triangles: each loop side once in loop direction, each
            // diagonal twice in opposite directions, nothing else.
            let mut count = std::collections::BTreeMap::new();
            for tri in &e.tris {
                for k in 0..3 {
                    *count.entry((tri[k], tri[(k + 1) % 3])).or_insert(0) += 1;
                }
            }
            for l in &e.loops {
                for i in 0..l.len() {
                    let (a, b) = (l[i], l[(i + 1) % l.len()]);
                    assert_eq!(
                        count.remove(&(a, b)),
                        Some(1),
                        "case {case} mask {mask}: side {a}->{b}"
                    );
                    assert_eq!(count.get(&(b, a)), None);
                }
            }
            let keys: Vec<_> = count.keys().copied().collect();
            for (a, b) in keys {
                assert_eq!(count.get(&(a, b)), Some(&1));
                assert_eq!(
                    count.get(&(b, a)),
                    Some(&1),
                    "case {case} mask {mask}: diagonal {a}-{b} once"
                );
            }
            // Triangles use no same-face diagonal (it could be used by the
            // neighbouring cube too).
            for &(a, b) in count.keys() {
                if a < 12 && b < 12 {
                    let (fa, fb) = (
                        crate::sdf::table::edge_faces(a as usize),
                        crate::sdf::table::edge_faces(b as usize),
                    );
                    let adjacent = e.loops.iter().any(|l| {
                        (0..l.len()).any(|i| {
                            (l[i], l[(i + 1) % l.len()]) == (a, b)
                                || (l[i], l[(i + 1) % l.len()]) == (b, a)
                        })
                    });
                    assert!(
                        adjacent || !fa.iter().any(|f| fb.contains(f)),
                        "case {case} mask {mask}: diagonal {a}-{b} on one face"
                    );
                }
            }
            let n_tri: usize = e
                .loops
                .iter()
                .enumerate()
                .map(|(i, l)| {
                    if e.centered.contains(&(i as u8)) {
                        l.len()
                    } else {
                        l.len() - 2
                    }
                })
                .sum();
            assert_eq!(e.tris.len(), n_tri);
        }
    }
}

/// Two cubes sharing a face produce the same segments on it, oppositely
/// directed, whatever their other corners: the table cannot crack.
#[test]
fn shared_faces_agree() {
    let t = table();
    for case in 0..256usize {
        for f in 0..6 {
            let axis = f / 2;
            let g = f ^ 1; // the same face seen from the neighbour
            let fa = face_corners(f);
            let fb = face_corners(g);
            for other in 0..16usize {
                // Neighbour: corners on g copy ours on f; the rest from `other`.
                let mut nb = 0usize;
                let mut k = 0;
                for c in 0..8 {
                    if corner_offset(c)[axis] == (g & 1) {
                        let i = fb.iter().position(|&x| x == c).unwrap();
                        if (case >> fa[i]) & 1 == 1 {
                            nb |= 1 << c;
                        }
                    } else {
                        if (other >> k) & 1 == 1 {
                            nb |= 1 << c;
                        }
                        k += 1;
                    }
                }
                for bit in 0..2usize {
                    let ma = if t.ambiguous[case] & (1 << f) != 0 {
                        bit << f
                    } else {
                        0
                    };
                    let mb = if t.ambiguous[nb] & (1 << g) != 0 {
                        bit << g
                    } else {
                        0
                    };
                    assert_eq!(
                        t.ambiguous[case] & (1 << f) != 0,
                        t.ambiguous[nb] & (1 << g) != 0
                    );
                    let sa = face_segments(case, ma, f);
                    let mut sb: Vec<(usize, usize)> = face_segments(nb, mb, g)
                        .into_iter()
                        .map(|(a, b)| (b, a))
                        .collect();
                    sb.sort();
                    assert_eq!(sa, sb, "case {case} face {f} neighbour {nb} decision {bit}");
                }
            }
        }
    }
}

/// The sign rule: f ≤ 0 is inside (either zero), anything above 0 or NaN is
/// not; a cell of zeros is all inside, and a saddle exactly on the level set
/// joins the inside corners.
#[test]
fn zero_counts_as_inside() {
    use crate::sdf::table::{classify_cell, face_joins_inside, inside};
    assert!(inside(0.0) && inside(-0.0) && inside(-1e-300));
    assert!(!inside(f64::MIN_POSITIVE) && !inside(5e-324) && !inside(f64::NAN));
    let tab = table();
    assert_eq!(classify_cell(tab, |_| 0.0).0, 255);
    assert_eq!(classify_cell(tab, |_| -0.0).0, 255);
    assert_eq!(
        classify_cell(tab, |o| if o == [0, 0, 0] { 0.0 } else { 1.0 }).0,
        1
    );
    // a·c = b·d: saddle value 0, inside corners (a, c) joined.
    assert!(face_joins_inside(-1.0, 1.0, -1.0, 1.0));
    assert!(face_joins_inside(1.0, -1.0, 1.0, -1.0));
    // An inside zero: the saddle is outside, not joined.
    assert!(!face_joins_inside(0.0, 1.0, -1.0, 1.0));
    assert!(!face_joins_inside(1.0, -0.0, 1.0, -1.0));
}
