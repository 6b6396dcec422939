//! Patch sets: many surfaces that share borders (the Utah teapot's 32 Bézier patches; any model
//! made of patches), tessellated as one conforming mesh by [`crate::nurbs::tess::tessellate_set`].
//!
//! A border is one side of one surface: the curve at u = u_min (`U0`), u = u_max (`U1`),
//! v = v_min (`V0`) or v = v_max (`V1`). For a surface clamped at that side the curve depends on
//! that side's row of the control net and the knots along it alone, so two borders are the same
//! curve when those rows hold the same homogeneous points — in the same or the reverse order —
//! and their knots agree after mapping both domains onto [0, 1] (reversed with the points).
//! [`PatchSet::borders`] finds these exactly (bit-equal points; the data of a patch file refers
//! to shared control points, so equal is exact), and adds the borders a caller declares
//! ([`Join`]) whose points only nearly agree. Pole borders (collapsed to a point, as the
//! teapot's lid and bottom) and the seams of closed directions are handled by corners and the
//! surface's own topology, not matched here.

use glam::DVec4;

use super::surface::NurbsSurface;

/// One side of a surface's domain.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Side {
    /// u = u_min (the curve runs along v).
    U0,
    /// u = u_max.
    U1,
    /// v = v_min (the curve runs along u).
    V0,
    /// v = v_max.
    V1,
}

impl Side {
    /// All four, in index order.
    pub const ALL: [Side; 4] = [Side::U0, Side::U1, Side::V0, Side::V1];

    /// Index 0..4, the order of [`crate::nurbs::surface::Topology::poles`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// The parameter the border runs along: 1 (v) for `U0`/`U1`, 0 (u) for `V0`/`V1`.
    pub fn along(self) -> usize {
        match self {
            Side::U0 | Side::U1 => 1,
            Side::V0 | Side::V1 => 0,
        }
    }

    /// Its rule-file name: `u0`, `u1`, `v0`, `v1`.
    pub fn name(self) -> &'static str {
        ["u0", "u1", "v0", "v1"][self.index()]
    }

    /// Parses a rule-file name.
    pub fn parse(text: &str) -> Option<Side> {
        Side::ALL.into_iter().find(|s| s.name() == text)
    }
}

/// A border: surface index and side.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct BorderRef {
    pub surface: usize,
    pub side: Side,
}

/// A declared shared border: `a` and `b` are the same curve (their control rows agree to
/// `tolerance`, forward or reversed); the mesh takes `a`'s samples for both.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Join {
    pub a: BorderRef,
    pub b: BorderRef,
}

/// Surfaces meshed together.
#[derive(Debug, Clone, PartialEq)]
pub struct PatchSet {
    pub surfaces: Vec<NurbsSurface>,
    /// Borders declared shared beyond the exact matches.
    pub joins: Vec<Join>,
}

/// A group of borders that are one curve. The first member owns the samples; `reversed[k]`
/// says whether member k runs against the first.
#[derive(Debug, Clone, PartialEq)]
pub struct BorderGroup {
    pub members: Vec<BorderRef>,
    pub reversed: Vec<bool>,
}

/// Why a declared join cannot hold.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JoinError {
    #[error("join {index}: surface {surface} does not exist (the set has {count})")]
    NoSurface {
        index: usize,
        surface: usize,
        count: usize,
    },
    #[error("join {index}: {what}")]
    Mismatch { index: usize, what: String },
}

/// Relative tolerance on normalised knots of borders found or declared shared.
const KNOT_TOLERANCE: f64 = 1e-9;
/// How far a declared join's control rows may differ, relative to the larger net's diagonal.
pub const JOIN_TOLERANCE: f64 = 1e-6;

impl PatchSet {
    /// A set of surfaces with no declared joins.
    pub fn new(surfaces: Vec<NurbsSurface>) -> Self {
        PatchSet {
            surfaces,
            joins: Vec::new(),
        }
    }

    /// The groups of shared borders (at least two members each), ordered by their first member.
    pub fn borders(&self) -> Result<Vec<BorderGroup>, JoinError> {
        let mut candidates: Vec<(Vec<[u64; 4]>, BorderRef, bool)> = Vec::new();
        for (s, surface) in self.surfaces.iter().enumerate() {
            for side in Side::ALL {
                if !matchable(surface, side) {
                    continue;
                }
                let row = border_row(surface, side);
                let forward: Vec<[u64; 4]> = row.iter().map(|h| bits(*h)).collect();
                let mut backward = forward.clone();
                backward.reverse();
                let reversed = backward < forward;
                let key = if reversed { backward } else { forward };
                candidates.push((key, BorderRef { surface: s, side }, reversed));
            }
        }
        // Sort by key, then border: equal rows become neighbours, deterministically.
        candidates.sort();
        let count = self.surfaces.len();
        let position: std::collections::BTreeMap<BorderRef, usize> = candidates
            .iter()
            .enumerate()
            .map(|(k, c)| (c.1, k))
            .collect();
        let index_of = |b: BorderRef| position.get(&b).copied();
        // Links (x, y, y reads reversed against x).
        let mut links: Vec<(usize, usize, bool)> = Vec::new();
        for k in 1..candidates.len() {
            if candidates[k].0 == candidates[k - 1].0 {
                let (a, b) = (candidates[k - 1].1, candidates[k].1);
                let rel = candidates[k - 1].2 != candidates[k].2;
                if knots_agree(&self.surfaces, a, b, rel) {
                    links.push((k - 1, k, rel));
                }
            }
        }
        // Declared joins: orientation by the closer of the two readings.
        for (index, join) in self.joins.iter().enumerate() {
            for r in [join.a, join.b] {
                if r.surface >= count {
                    return Err(JoinError::NoSurface {
                        index,
                        surface: r.surface,
                        count,
                    });
                }
            }
            let (sa, sb) = (
                &self.surfaces[join.a.surface],
                &self.surfaces[join.b.surface],
            );
            let mismatch = |what: String| JoinError::Mismatch { index, what };
            for (r, s) in [(join.a, sa), (join.b, sb)] {
                if !matchable(s, r.side) {
                    return Err(mismatch(format!(
                        "side {} of surface {} is a pole, a seam or not clamped: it cannot be joined",
                        r.side.name(),
                        r.surface
                    )));
                }
            }
            let (ra, rb) = (border_row(sa, join.a.side), border_row(sb, join.b.side));
            if ra.len() != rb.len() {
                return Err(mismatch(format!(
                    "the borders have {} and {} control points",
                    ra.len(),
                    rb.len()
                )));
            }
            let dist = |rev: bool| {
                ra.iter()
                    .enumerate()
                    .map(|(k, h)| {
                        let o = if rev { rb[rb.len() - 1 - k] } else { rb[k] };
                        (project(*h) - project(o)).length()
                    })
                    .fold(0.0f64, f64::max)
            };
            let (df, dr) = (dist(false), dist(true));
            let rev = dr < df;
            let worst = df.min(dr);
            let allowed = JOIN_TOLERANCE * sa.net_diagonal().max(sb.net_diagonal());
            if worst.is_nan() || worst > allowed {
                return Err(mismatch(format!(
                    "the borders' control points differ by up to {worst:e} (allowed: {allowed:e}, 1e-6 of the net's size)"
                )));
            }
            if !knots_agree(&self.surfaces, join.a, join.b, rev) {
                return Err(mismatch("the borders' knots differ".to_owned()));
            }
            let (Some(ia), Some(ib)) = (index_of(join.a), index_of(join.b)) else {
                unreachable!("matchable borders are candidates");
            };
            links.push((ia, ib, rev));
        }
        // Components in order of their smallest border; orientation relative to it by a walk.
        let n = candidates.len();
        let mut adjacency: Vec<Vec<(usize, bool)>> = vec![Vec::new(); n];
        for &(x, y, rel) in &links {
            adjacency[x].push((y, rel));
            adjacency[y].push((x, rel));
        }
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by_key(|&k| candidates[k].1);
        let mut seen: Vec<Option<bool>> = vec![None; n];
        let mut groups = Vec::new();
        for &start in &order {
            if seen[start].is_some() || adjacency[start].is_empty() {
                continue;
            }
            seen[start] = Some(false);
            let mut component = vec![start];
            let mut stack = vec![start];
            while let Some(x) = stack.pop() {
                let ox = seen[x].unwrap_or(false);
                for &(y, rel) in &adjacency[x] {
                    if seen[y].is_none() {
                        seen[y] = Some(ox != rel);
                        component.push(y);
                        stack.push(y);
                    }
                }
            }
            component.sort_by_key(|&k| candidates[k].1);
            groups.push(BorderGroup {
                members: component.iter().map(|&k| candidates[k].1).collect(),
                reversed: component.iter().map(|&k| seen[k] == Some(true)).collect(),
            });
        }
        Ok(groups)
    }
}

/// Whether a side can be matched: clamped there, not a pole, and neither a seam nor running
/// along a closed direction.
fn matchable(surface: &NurbsSurface, side: Side) -> bool {
    let t = surface.topology();
    if t.closed_u || t.closed_v || t.poles[side.index()] {
        return false;
    }
    let [p, q] = surface.degree();
    let (knots, degree, end) = match side {
        Side::U0 => (surface.knots_u(), p, false),
        Side::U1 => (surface.knots_u(), p, true),
        Side::V0 => (surface.knots_v(), q, false),
        Side::V1 => (surface.knots_v(), q, true),
    };
    let ends = if end {
        &knots[knots.len() - degree - 1..]
    } else {
        &knots[..=degree]
    };
    ends.iter().all(|&k| k == ends[0])
}

/// The side's row of the homogeneous net, in increasing parameter order.
pub(crate) fn border_row(surface: &NurbsSurface, side: Side) -> Vec<DVec4> {
    let [nu, nv] = surface.size();
    match side {
        Side::U0 => (0..nv).map(|j| surface.homogeneous_point(0, j)).collect(),
        Side::U1 => (0..nv)
            .map(|j| surface.homogeneous_point(nu - 1, j))
            .collect(),
        Side::V0 => (0..nu).map(|i| surface.homogeneous_point(i, 0)).collect(),
        Side::V1 => (0..nu)
            .map(|i| surface.homogeneous_point(i, nv - 1))
            .collect(),
    }
}

/// The knots along a side, mapped onto [0, 1] (the clamped end knots included).
fn normalised_knots(surface: &NurbsSurface, side: Side) -> Vec<f64> {
    let knots = if side.along() == 0 {
        surface.knots_u()
    } else {
        surface.knots_v()
    };
    let [[u0, u1], [v0, v1]] = surface.domain();
    let (lo, hi) = if side.along() == 0 {
        (u0, u1)
    } else {
        (v0, v1)
    };
    knots.iter().map(|k| (k - lo) / (hi - lo)).collect()
}

fn knots_agree(surfaces: &[NurbsSurface], a: BorderRef, b: BorderRef, reversed: bool) -> bool {
    let ka = normalised_knots(&surfaces[a.surface], a.side);
    let mut kb = normalised_knots(&surfaces[b.surface], b.side);
    if reversed {
        kb = kb.iter().rev().map(|k| 1.0 - k).collect();
    }
    ka.len() == kb.len()
        && ka
            .iter()
            .zip(&kb)
            .all(|(x, y)| (x - y).abs() <= KNOT_TOLERANCE)
}

fn project(h: DVec4) -> glam::DVec3 {
    h.truncate() / h.w
}

/// Bit pattern of a homogeneous point, with −0 read as +0.
fn bits(h: DVec4) -> [u64; 4] {
    h.to_array().map(|x| (x + 0.0).to_bits())
}
