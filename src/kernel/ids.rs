//! Typed element ids.
//!
//! Every element lives in an index-based arena (see [`super::arena`]); an id is
//! the slot index. Ids are stable for the element's lifetime, and freed slots
//! are recycled lowest-first, so the same sequence of operations always yields
//! the same ids.

use std::fmt;
use std::num::NonZeroU32;

/// An id that is an arena slot index: what slot-indexed scratch tables
/// ([`super::ops::side_table`]) key by.
pub(crate) trait SlotId: Copy + Ord {
    fn slot(self) -> usize;
    fn at_slot(index: usize) -> Self;
}

macro_rules! element_id {
    ($(#[$doc:meta])* $name:ident, $prefix:literal) => {
        $(#[$doc])*
        ///
        /// Stored as the slot index plus one, so that `Option` of an id,
        /// and of every record holding one, needs no extra tag: the
        /// kernel's records are smaller by that much (a loop is 28 bytes,
        /// not 32).
        #[derive(Copy, Clone, PartialEq, Eq, PartialOrd, Ord, Hash)]
        pub struct $name(NonZeroU32);

        impl $name {
            /// The arena slot index of this element.
            #[inline]
            pub fn index(self) -> usize {
                (self.0.get() - 1) as usize
            }

            /// The slot index as the arenas store it.
            #[inline]
            pub(crate) fn raw(self) -> u32 {
                self.0.get() - 1
            }

            /// The id for slot `raw` (below `u32::MAX`).
            #[inline]
            pub(crate) fn from_raw(raw: u32) -> Self {
                Self(NonZeroU32::new(raw.wrapping_add(1)).expect("element index exceeds u32"))
            }

            /// The id for slot `index` (the slot need not be alive).
            #[inline]
            pub fn from_index(index: usize) -> Self {
                u32::try_from(index)
                    .ok()
                    .and_then(|i| i.checked_add(1))
                    .and_then(NonZeroU32::new)
                    .map(Self)
                    .expect("element index exceeds u32")
            }
        }

        impl SlotId for $name {
            #[inline]
            fn slot(self) -> usize {
                self.index()
            }
            #[inline]
            fn at_slot(index: usize) -> Self {
                Self::from_index(index)
            }
        }

        impl fmt::Debug for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, concat!($prefix, "{}"), self.index())
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, concat!($prefix, "{}"), self.index())
            }
        }
    };
}

element_id!(
    /// A vertex (a G³ node).
    VertId,
    "v"
);
element_id!(
    /// An edge between two distinct vertices.
    EdgeId,
    "e"
);
element_id!(
    /// A loop: one corner of one face, the use of one edge by that face.
    LoopId,
    "l"
);
element_id!(
    /// A face: a single boundary cycle of at least three distinct vertices.
    FaceId,
    "f"
);

/// The kind of a mesh element, for attribute domains and error messages.
#[derive(Copy, Clone, PartialEq, Eq, PartialOrd, Ord, Hash, Debug)]
pub enum Domain {
    Vert,
    Edge,
    Face,
}

impl fmt::Display for Domain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Domain::Vert => "vertex",
            Domain::Edge => "edge",
            Domain::Face => "face",
        })
    }
}
