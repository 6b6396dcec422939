//! High-level modelling operators (seed 000 §3.3, §4.5), built only from
//! Euler operators and geometry writes.
//!
//! Every operator takes the elements it works on and returns a
//! [`Selection`] naming what it *created* (the seed's `ExtrudeFacesResult`
//! idea), so a caller — or a rule step — can chain on "what the previous
//! step made" without searching. Inputs are processed in ascending id order
//! whatever order they are given in, so results never depend on it.
//!
//! | module | operators |
//! |---|---|
//! | [`create`] | vertex, circle, grid, cube, UV sphere, cylinder / cone |
//! | [`transform`] | translate, rotate, scale, affine |
//! | [`select`] | from verts / edges / faces, region extend / reduce |
//! | [`delete`] | delete (all / faces / faces and edges), duplicate, dissolve edges |
//! | [`merge`] | merge by distance, mirror |
//! | [`coincide`] | incremental merge of new vertices into a growing mesh (thesis 003 §3.1) |
//! | [`extrude`] | extrude verts, edges, faces (individual), face region |
//! | [`inset`] | inset faces (individual), inset region |
//! | [`split`] | split edges (cuts, ratios) |
//! | [`bevel`] | bevel edges or vertices (Blender's offsets, superellipse profile, segments, clamp overlap) |
//! | [`subdivide`] | Catmull–Clark, simple and Loop subdivision (OpenSubdiv rules, creases) |
//! | [`faces`] | make face from edges, triangulate, reverse, recompute normals |
//! | [`solidify`] | a sheet into a closed shell (Blender's simple solidify: offset, even thickness, rim) |
//! | [`spin`] | a lathe: edges swept into bands about an axis, vertices into arcs; seam and poles merged |
//! | [`bridge`] | edge loops joined in order by bands of quads (twist, segments, unequal counts as Blender) |
//! | [`hull`] | convex hull of vertices as a new closed shell (exact, coplanar faces merged) |
//! | [`skin`] | wire edges into closed tubes (frusta, joint spheres) |

use thiserror::Error;

use super::euler::KernelError;
use super::ids::{EdgeId, FaceId, SlotId, VertId};

pub mod bevel;
pub mod boolean;
pub mod bridge;
pub mod coincide;
pub mod create;
pub mod delete;
pub mod extrude;
pub mod faces;
pub mod grid_fill;
pub mod hull;
pub mod inset;
pub mod merge;
pub mod select;
pub(crate) mod side_table;
pub mod skin;
pub mod solidify;
pub mod spin;
pub mod split;
pub mod subdivide;
pub mod transform;

/// A set of elements: sorted ascending, no duplicates.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Selection {
    pub verts: Vec<VertId>,
    pub edges: Vec<EdgeId>,
    pub faces: Vec<FaceId>,
}

impl Selection {
    pub fn new() -> Self {
        Self::default()
    }

    /// Sorts and deduplicates every list (the canonical form).
    pub fn normalize(&mut self) {
        sort_ids(&mut self.verts);
        sort_ids(&mut self.edges);
        sort_ids(&mut self.faces);
    }

    /// Builds a canonical selection from unordered lists.
    pub fn from_parts(verts: Vec<VertId>, edges: Vec<EdgeId>, faces: Vec<FaceId>) -> Self {
        let mut s = Self {
            verts,
            edges,
            faces,
        };
        s.normalize();
        s
    }

    pub fn is_empty(&self) -> bool {
        self.verts.is_empty() && self.edges.is_empty() && self.faces.is_empty()
    }

    /// Appends everything of `other` without restoring the canonical form:
    /// callers gathering many selections append them all, then call
    /// [`Selection::normalize`] once (sorting after every append would make
    /// gathering quadratic).
    pub fn append(&mut self, other: &Selection) {
        self.verts.extend_from_slice(&other.verts);
        self.edges.extend_from_slice(&other.edges);
        self.faces.extend_from_slice(&other.faces);
    }
}

/// Sorts and dedups ids, in one linear pass when they are already strictly
/// ascending (what most operators produce: new ids come in slot order).
/// Otherwise ids that are dense among their slots (the largest below 64
/// per id: a region's corner lists, an operator's results) are marked in a
/// bitmap of the slots and read back in order, one bit per slot and no
/// comparison sort; sparse lists are sorted.
pub(crate) fn sort_ids<T: SlotId>(ids: &mut Vec<T>) {
    if ids.windows(2).all(|w| w[0] < w[1]) {
        return;
    }
    let Some(max) = ids.iter().map(|id| id.slot()).max() else {
        return;
    };
    if ids.len() < 64 || max / 64 > ids.len() {
        ids.sort_unstable();
        ids.dedup();
        return;
    }
    let mut marks = side_table::SlotSet::bits(max + 1);
    for id in ids.iter() {
        marks.insert(id.slot());
    }
    ids.clear();
    ids.extend(marks.into_sorted().into_iter().map(T::at_slot));
}

/// Why a high-level operator failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum OpError {
    #[error(transparent)]
    Kernel(#[from] KernelError),
    #[error("invalid parameter `{name}`: {reason}")]
    Parameter { name: &'static str, reason: String },
    /// The selection has no result of the kind asked for (the convex hull
    /// of coplanar points); the message says why.
    #[error("{0}")]
    Degenerate(String),
}

impl OpError {
    pub(crate) fn parameter(name: &'static str, reason: impl Into<String>) -> Self {
        OpError::Parameter {
            name,
            reason: reason.into(),
        }
    }
}

/// Sorted, deduplicated copy of an id list: operators iterate inputs in id
/// order so their results do not depend on the order the caller gave.
pub(crate) fn canonical<T: SlotId>(ids: &[T]) -> Vec<T> {
    into_canonical(ids.to_vec())
}

/// `ids` sorted and deduplicated in place (see [`sort_ids`]).
pub(crate) fn into_canonical<T: SlotId>(mut ids: Vec<T>) -> Vec<T> {
    sort_ids(&mut ids);
    ids
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sort_ids_marked_or_sorted_agree() {
        let ids: Vec<VertId> = [9, 3, 3, 0, 9, 7, 3].map(VertId::from_index).to_vec();
        let want: Vec<VertId> = [0, 3, 7, 9].map(VertId::from_index).to_vec();
        assert_eq!(into_canonical(ids), want);
        assert_eq!(into_canonical(want.clone()), want);
        assert!(into_canonical(Vec::<VertId>::new()).is_empty());
        // Ids past any slot count are kept (a caller refuses them), not a panic.
        let past: Vec<VertId> = [12, 3, 12].map(VertId::from_index).to_vec();
        assert_eq!(
            into_canonical(past),
            [3, 12].map(VertId::from_index).to_vec()
        );
        // Long lists: dense ones take the bitmap, sparse ones the sort;
        // both give the ascending distinct ids.
        for spread in [1usize, 7, 63, 64, 65, 1000] {
            let ids: Vec<FaceId> = (0..500usize)
                .map(|i| FaceId::from_index((i * 7919 % 500) * spread + i % 3))
                .chain((0..100).map(|i| FaceId::from_index(i * spread)))
                .collect();
            let mut want = ids.clone();
            want.sort_unstable();
            want.dedup();
            assert_eq!(into_canonical(ids), want, "spread {spread}");
        }
    }
}
