//! Hash maps of the pillar (rustc's FxHash: looked up only, never iterated
//! for output, so the hash cannot change a result) and its edge keys (the
//! geometry floor's).

pub use crate::geom::edge_key::{ends as edge_ends, undirected as edge_key};
pub use rustc_hash::FxHashMap;
