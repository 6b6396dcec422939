//! Typed element ids.
//!
//! Every element lives in an index-based arena (see [`super::arena`]); an id is
//! the slot index. Ids are stable for the element's lifetime, and freed slots
//! are recycled lowest-first, so the same sequence of operations always yields
//! the same ids.

use std::fmt;

/// An id that is an arena slot index: what slot-indexed scratch tables
/// ([`super::ops::side_table`]) key by.
pub(crate) trait SlotId: Copy + Ord {
    fn slot(self) -> usize;
    fn at_slot(index: usize) -> Self;
}

macro_rules! element_id {
    ($(#[$doc:meta])* $name:ident, $prefix:literal) => {
        $(#[$doc])*
        #[derive(Copy, Clone, PartialEq, Eq, PartialOrd, Ord, Hash)]
        pub struct $name(pub(crate) u32);

        impl $name {
            /// The arena slot index of this element.
            #[inline]
            pub fn index(self) -> usize {
                self.0 as usize
            }

            /// The id for slot `index` (the slot need not be alive).
            #[inline]
            pub fn from_index(index: usize) -> Self {
                Self(u32::try_from(index).expect("element index exceeds u32"))
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
                write!(f, concat!($prefix, "{}"), self.0)
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, concat!($prefix, "{}"), self.0)
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
