//! The face-consistent marching-cubes table (decision D4; spec §1.8.2).
//!
//! The thesis reduces the 256 sign configurations to 15 by rotation *and
//! complement* (§2.2.2); complementing flips how an ambiguous face is split,
//! so two cubes sharing that face can disagree and leave a hole (spec §0.4,
//! §1.10). Here every ambiguous face (two diagonally opposite inside corners,
//! two outside) is decided by a rule that reads **only that face's four
//! corner values**, so both cubes sharing it agree:
//!
//! the inside corners are joined across the face iff the product of the two
//! inside values exceeds the product of the two outside values, i.e. iff the
//! bilinear interpolant's saddle value is negative (the asymptotic decider
//! of Nielson & Hamann, in a division-free form).
//!
//! The table is indexed by (case, decision bits of the case's ambiguous
//! faces): 256 × 64 entries, generated once, not typed in. For each entry:
//! 1. every face contributes oriented segments between the crossing points
//!    on its edges (one segment for two crossings, two for four, paired as
//!    the decision says);
//! 2. the segments chain into closed loops (each crossed cube edge lies on
//!    exactly two faces, so it starts one segment and ends one);
//! 3. each loop is triangulated as a disk without extra vertices, using no
//!    diagonal that joins two crossing points on one cube face (such a
//!    diagonal could also appear in the neighbouring cube and give an edge
//!    with four triangles).
//!
//! Why the output is closed and 2-manifold: each grid edge carries one
//! vertex; each face segment is shared by exactly the two cubes on that face
//! (same decision), so every mesh edge on a face has one triangle per side;
//! loop diagonals are interior to one cube; loops of one cube share no
//! vertex, and around a grid edge the four cubes' fans join into one disk.
//! Internal (cube-interior) ambiguity is resolved by treating every loop as
//! its own disk, which may not match the trilinear topology (MC33) but is
//! always manifold. Orientation: a segment runs so that the face's inside
//! corners are on its left seen from outside the cube; loops then run
//! counter-clockwise seen from the positive side, so triangle normals point
//! to f > 0.

use std::sync::OnceLock;

use glam::DVec3;

/// Corner `c` of the unit cube has offset (c & 1, c >> 1 & 1, c >> 2 & 1).
pub fn corner_offset(c: usize) -> [usize; 3] {
    [c & 1, (c >> 1) & 1, (c >> 2) & 1]
}

/// Cube edge `e = axis·4 + j`: its lower corner and axis. `j` enumerates
/// the other two coordinates in increasing axis order.
pub fn edge_info(e: usize) -> (usize, usize) {
    let axis = e / 4;
    let j = e % 4;
    let (u, v) = other_axes(axis);
    let c = ((j & 1) << u) | (((j >> 1) & 1) << v);
    (c, axis)
}

/// The two axes other than `axis`, increasing.
pub fn other_axes(axis: usize) -> (usize, usize) {
    match axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

/// Face `f = axis·2 + side`: its four corners in cyclic (u, v) order
/// (0,0), (1,0), (1,1), (0,1), with u < v the other two axes.
pub fn face_corners(f: usize) -> [usize; 4] {
    let axis = f / 2;
    let side = f % 2;
    let (u, v) = other_axes(axis);
    let base = side << axis;
    [
        base,
        base | (1 << u),
        base | (1 << u) | (1 << v),
        base | (1 << v),
    ]
}

fn edge_of(c0: usize, c1: usize) -> usize {
    let d = c0 ^ c1;
    let axis = d.trailing_zeros() as usize;
    let lo = c0 & c1;
    let (u, v) = other_axes(axis);
    axis * 4 + ((lo >> u) & 1) + (((lo >> v) & 1) << 1)
}

/// The two faces containing cube edge `e`.
pub fn edge_faces(e: usize) -> [usize; 2] {
    let (c, axis) = edge_info(e);
    let (u, v) = other_axes(axis);
    [u * 2 + ((c >> u) & 1), v * 2 + ((c >> v) & 1)]
}

/// One table entry.
#[derive(Debug, Clone, Default)]
pub struct Entry {
    /// Triangles as cube-edge triples, oriented outward. An index ≥ 12
    /// stands for the centre vertex of loop `index − 12` (see
    /// [`Entry::centered`]).
    pub tris: Vec<[u8; 3]>,
    /// Loops fanned from an extra centre vertex because no triangulation
    /// avoids same-face diagonals (a loop through three ambiguous faces;
    /// 248 entries of 16,384, never met on smooth fields in our tests).
    pub centered: Vec<u8>,
    /// Loops as cube-edge sequences (in segment direction).
    pub loops: Vec<Vec<u8>>,
    /// Loop of each crossed edge (0xFF: not crossed).
    pub edge_loop: [u8; 12],
    /// Successor of each crossed edge in its loop.
    pub next: [u8; 12],
    /// Face holding the segment from an edge to its successor.
    pub seg_face: [u8; 12],
}

/// The whole table and per-case facts.
#[derive(Debug)]
pub struct Table {
    entries: Vec<Entry>,
    /// Bit f set when face f is ambiguous in the case.
    pub ambiguous: [u8; 256],
    /// Number of entries with a centred loop.
    pub centered_entries: usize,
}

impl Table {
    /// The entry of `case` (bit c = corner c inside) with face decisions
    /// `mask` (bit f = inside corners of face f joined; only the ambiguous
    /// faces' bits matter).
    #[inline]
    pub fn entry(&self, case: usize, mask: usize) -> &Entry {
        &self.entries[case * 64 + (mask & self.ambiguous[case] as usize)]
    }
}

/// The table, built on first use.
pub fn table() -> &'static Table {
    static T: OnceLock<Table> = OnceLock::new();
    T.get_or_init(build)
}

/// The meshers' one sign rule: a sample is inside iff f ≤ 0, so an exact
/// zero (+0.0 or −0.0) is inside, as in scikit-image's `marching_cubes`
/// (its case bit is set for `v − level > 0` only). Every decision that
/// reads a sign goes through this predicate (the cell case, which grid
/// edges cross, the ambiguous-face decider, root bracketing), so the case
/// index, the crossed edges and the vertices agree. NaN never reaches it
/// (samples are sanitised to +MAX, i.e. outside).
#[inline]
pub fn inside(f: f64) -> bool {
    f <= 0.0
}

/// Decision of one ambiguous face from its corner values in cyclic order
/// (a, b, c, d): are the inside ([`inside`]: f ≤ 0) corners joined across
/// the face? Iff the bilinear saddle value is ≤ 0 (a saddle exactly on the
/// level set counts as inside, like a sample): the denominator of the
/// saddle value is negative, so that is `inside product ≥ outside product`.
/// Depends only on the four values and is symmetric under the face's
/// symmetries (products and the comparison are), so both cubes agree.
#[inline]
pub fn face_joins_inside(a: f64, b: f64, c: f64, d: f64) -> bool {
    if inside(a) {
        a * c >= b * d
    } else {
        b * d >= a * c
    }
}

/// A cell's case (bit c set when corner c, read through
/// `value_at(corner offset)`, is inside) and its ambiguous-face mask (bit f
/// set when face f joins the inside corners): the key of
/// [`Table::entry`], shared by both meshers so they split cells alike.
#[inline]
pub fn classify_cell(tab: &Table, mut value_at: impl FnMut([usize; 3]) -> f64) -> (usize, usize) {
    let mut vals = [0.0f64; 8];
    let mut case = 0usize;
    for (c, val) in vals.iter_mut().enumerate() {
        *val = value_at(corner_offset(c));
        if inside(*val) {
            case |= 1 << c;
        }
    }
    let mut mask = 0usize;
    let amb = if case == 0 || case == 255 {
        0
    } else {
        tab.ambiguous[case]
    };
    for f in 0..6 {
        if amb & (1 << f) != 0 {
            let fc = face_corners(f);
            if face_joins_inside(vals[fc[0]], vals[fc[1]], vals[fc[2]], vals[fc[3]]) {
                mask |= 1 << f;
            }
        }
    }
    (case, mask)
}

fn build() -> Table {
    let mut entries = Vec::with_capacity(256 * 64);
    let mut ambiguous = [0u8; 256];
    let mut centered_entries = 0;
    for case in 0..256usize {
        let inside = |c: usize| (case >> c) & 1 == 1;
        for f in 0..6 {
            let fc = face_corners(f);
            let s: Vec<bool> = fc.iter().map(|&c| inside(c)).collect();
            if s[0] == s[2] && s[1] == s[3] && s[0] != s[1] {
                ambiguous[case] |= 1 << f;
            }
        }
        for mask in 0..64usize {
            let e = build_entry(case, mask);
            centered_entries += !e.centered.is_empty() as usize;
            entries.push(e);
        }
    }
    Table {
        entries,
        ambiguous,
        centered_entries,
    }
}

fn midpoint(e: usize) -> DVec3 {
    let (c, axis) = edge_info(e);
    let o = corner_offset(c);
    let mut p = DVec3::new(o[0] as f64, o[1] as f64, o[2] as f64);
    p[axis] += 0.5;
    p
}

fn corner_pos(c: usize) -> DVec3 {
    let o = corner_offset(c);
    DVec3::new(o[0] as f64, o[1] as f64, o[2] as f64)
}

fn build_entry(case: usize, mask: usize) -> Entry {
    let inside = |c: usize| (case >> c) & 1 == 1;
    let crosses = |e: usize| {
        let (c, axis) = edge_info(e);
        inside(c) != inside(c | (1 << axis))
    };
    let mut next = [0xFFu8; 12];
    let mut seg_face = [0xFFu8; 12];
    for f in 0..6 {
        let fc = face_corners(f);
        let fe: Vec<usize> = (0..4).map(|i| edge_of(fc[i], fc[(i + 1) % 4])).collect();
        let crossing: Vec<usize> = fe.iter().copied().filter(|&e| crosses(e)).collect();
        let mut segs: Vec<(usize, usize)> = Vec::new();
        if crossing.len() == 2 {
            segs.push((crossing[0], crossing[1]));
        } else if crossing.len() == 4 {
            let join = (mask >> f) & 1 == 1;
            // Cut off the outside corners when the inside ones are joined,
            // the inside corners otherwise.
            for i in 0..4 {
                let c = fc[i];
                if inside(c) != join {
                    let e_prev = edge_of(fc[(i + 3) % 4], c);
                    let e_next = edge_of(c, fc[(i + 1) % 4]);
                    segs.push((e_prev, e_next));
                }
            }
        }
        let axis = f / 2;
        let mut n = DVec3::ZERO;
        n[axis] = if f % 2 == 1 { 1.0 } else { -1.0 };
        for (e1, e2) in segs {
            let (m1, m2) = (midpoint(e1), midpoint(e2));
            let inner = |e: usize| {
                let (c, axis) = edge_info(e);
                if inside(c) {
                    corner_pos(c)
                } else {
                    corner_pos(c | (1 << axis))
                }
            };
            let m_in = (inner(e1) + inner(e2)) * 0.5;
            let mid = (m1 + m2) * 0.5;
            let (a, b) = if (m2 - m1).cross(n).dot(m_in - mid) > 0.0 {
                (e1, e2)
            } else {
                (e2, e1)
            };
            next[a] = b as u8;
            seg_face[a] = f as u8;
        }
    }
    let mut edge_loop = [0xFFu8; 12];
    let mut loops: Vec<Vec<u8>> = Vec::new();
    for start in 0..12 {
        if !crosses(start) || edge_loop[start] != 0xFF {
            continue;
        }
        let li = loops.len() as u8;
        let mut l = Vec::new();
        let mut e = start;
        loop {
            edge_loop[e] = li;
            l.push(e as u8);
            e = next[e] as usize;
            if e == start || e >= 12 || l.len() > 12 {
                break;
            }
        }
        loops.push(l);
    }
    let mut tris = Vec::new();
    let mut centered = Vec::new();
    for (li, l) in loops.iter().enumerate() {
        let (t, forbidden) = triangulate(l);
        if forbidden {
            // Fan from the loop's centre: every new edge is interior to the
            // cube, so the fan cannot collide with a neighbour's triangles.
            centered.push(li as u8);
            for i in 0..l.len() {
                tris.push([12 + li as u8, l[i], l[(i + 1) % l.len()]]);
            }
        } else {
            tris.extend(t);
        }
    }
    Entry {
        tris,
        centered,
        loops,
        edge_loop,
        next,
        seg_face,
    }
}

/// Minimum-total-diagonal-length triangulation of a loop (on the edge
/// midpoints) that avoids diagonals between two crossing points of one cube
/// face. Returns the triangles and whether a forbidden one was needed.
fn triangulate(l: &[u8]) -> (Vec<[u8; 3]>, bool) {
    let n = l.len();
    if n < 3 {
        return (Vec::new(), true);
    }
    let pos: Vec<DVec3> = l.iter().map(|&e| midpoint(e as usize)).collect();
    let share_face = |a: usize, b: usize| {
        let fa = edge_faces(l[a] as usize);
        let fb = edge_faces(l[b] as usize);
        fa.iter().any(|f| fb.contains(f))
    };
    // Cost of chord (i, j): 0 for polygon sides, length for allowed
    // diagonals, a large penalty for forbidden ones.
    let chord = |i: usize, j: usize| -> f64 {
        if j == i + 1 || (i == 0 && j == n - 1) {
            0.0
        } else if share_face(i, j) {
            1e6
        } else {
            (pos[i] - pos[j]).length()
        }
    };
    let mut cost = vec![vec![0.0f64; n]; n];
    let mut pick = vec![vec![0usize; n]; n];
    for len in 2..n {
        for i in 0..n - len {
            let j = i + len;
            let mut best = f64::INFINITY;
            let mut bk = i + 1;
            for k in i + 1..j {
                let c = cost[i][k] + cost[k][j] + chord(i, k) + chord(k, j);
                if c < best {
                    best = c;
                    bk = k;
                }
            }
            cost[i][j] = best;
            pick[i][j] = bk;
        }
    }
    let mut out = Vec::new();
    let mut stack = vec![(0usize, n - 1)];
    while let Some((i, j)) = stack.pop() {
        if j < i + 2 {
            continue;
        }
        let k = pick[i][j];
        out.push([l[i], l[k], l[j]]);
        stack.push((i, k));
        stack.push((k, j));
    }
    (out, cost[0][n - 1] >= 1e6)
}
