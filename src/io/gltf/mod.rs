//! glTF 2.0, as `.gltf` (JSON with the buffer embedded as a base64 `data:` URI) and `.glb`.
//!
//! # Writing
//!
//! One mesh, one node, one scene; `asset.generator = "graftal"`, no material (default material).
//! glTF is +Y up (spec §3.4) and graftal's kernel Z-up: positions are written as
//! (x, z, −y), and read back as (x, −z, y), so a round trip is exact and a
//! model stands upright in every viewer.
//!
//! * Surface primitive (mode TRIANGLES, only if there are polygons): flat shaded unless the mesh
//!   carries corner normals. A flat polygon's vertices carry its unit Newell normal (`(0, 0, 1)`
//!   for degenerate polygons); every normal, UV and colour is rounded to `f32` once from the
//!   `f64` value read or computed (never renormalised in `f32`, which moves the last bit on
//!   every pass). The polygon is split with [`crate::geom::polygon::triangulate`]; vertices are
//!   numbered in the order the triangles first use them, so reading the file back and writing
//!   it again gives the same bytes.
//! * Wire primitive (mode LINES, only if there are lines): its own vertices, the ones the lines
//!   use, numbered in first-use order.
//! * Attributes: `POSITION` (f32, `min`/`max` from the written `f32` values), `NORMAL` (surface
//!   only), and one f32 SCALAR `_NAME` per vertex scalar (name upper-cased, e.g. `_RADIUS`).
//! * Indices: u16 when the primitive has at most 65535 vertices, else u32.
//! * Every attribute and index array has its own 4-byte-aligned bufferView with its target set.
//! * An empty mesh gives a scene without nodes, and no mesh, node or buffer.
//!
//! The document is built as a [`gltf::json::Root`] and serialized with
//! `gltf::json::serialize::to_vec`. `gltf-json` can only express `_NAME` attribute semantics with
//! its `extras` cargo feature, so the `_NAME` entries are spliced into each primitive's
//! `"attributes":{` object of the serialized JSON (the document has no other such key).
//!
//! # Reading
//!
//! The JSON is parsed with `serde_json`, `_NAME` attributes are taken out (so reading works
//! whether or not `gltf-json` has the `extras` feature), and the rest is deserialized into a
//! [`gltf::json::Root`]. All lookups are bounds-checked here rather than through
//! `gltf::Document`, whose accessors assume a validated file and panic otherwise.
//!
//! The default scene (else the first scene, else every root node) is traversed with node
//! transforms applied (in `f64`). Primitives of mode TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN
//! become triangles; LINES, LINE_STRIP and LINE_LOOP become lines; POINTS are ignored. A normal
//! that is unit to `f32` precision is kept bit for bit (`geom::normals::unit_as_read`), others
//! are normalised.
//! Bitwise-equal transformed positions are merged (first-appearance numbering), so flat-shaded
//! files come back connected. Float SCALAR `_NAME` attributes become vertex scalars named in
//! lower case (a merged vertex takes the first value seen; vertices without one get 0).
//! Buffers come from the GLB binary chunk, base64 `data:` URIs, or files relative to the
//! `.gltf` file's directory. Sparse accessors are not supported. Quantised attributes
//! (`KHR_mesh_quantization`) are dequantised as the spec says; views compressed with
//! `EXT_meshopt_compression` are decoded first (`meshopt_views`), and primitives compressed
//! with `KHR_draco_mesh_compression` decoded into their accessors' bytes (`draco_primitives`).

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;

use ::gltf::json::{self, validation::Checked, validation::USize64, Index};
use glam::DVec3;

use super::IoError;
use crate::geom::indexed::{IndexedMesh, PolygonTriangulator, VertexMerger};
use crate::geom::source::PolygonSource;

mod base64;
mod draco_primitives;
mod meshopt_views;
mod reader;
#[cfg(test)]
mod tests;
mod writer;

use base64::{base64_decode, base64_encode};

/// What one file's compressed views and primitives may decode to in all:
/// as much as the largest mesh file graftal reads (`cli::files`), so a
/// small file that claims gigabytes of constant data is refused before
/// anything is allocated for it.
const MAX_DECODED_BYTES: u64 = 4 << 30;
#[cfg(test)]
use reader::*;
pub use reader::{decode, decode_with};
#[cfg(test)]
use writer::*;
pub use writer::{encode_glb, encode_gltf, encode_streamed, Planned};
