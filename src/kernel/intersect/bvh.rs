//! Broad phase: [`obvhs`] BVHs over conservative `f32` boxes.
//!
//! - Whole-mesh self-intersection lives in `super::pairs` (its own linear
//!   BVH over flat primitives); `intersecting_pairs` here is its entry for
//!   lists of items (tests), and [`threads_for`] its thread policy.
//! - [`IntersectionIndex`] answers "would this new primitive hit anything?"
//!   while a model grows, with the Bentley–Saxe logarithmic method: a small
//!   buffer scanned linearly plus static BVHs of doubling capacity. An
//!   insertion fills the buffer; a full buffer is carried into the first
//!   empty level that can hold it, merging the full levels it passes (a
//!   binary counter). Each primitive is rebuilt O(log n) times in all, so
//!   insertion is amortized O(log n) per primitive and never rebuilds the
//!   whole tree per insert; a query visits O(log n) trees.

use std::time::Duration;

use glam::{DVec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::builder::build_bvh2;
use obvhs::bvh2::Bvh2;
use obvhs::ploc::{PlocSearchDistance, SortPrecision};
use obvhs::BvhBuildParams;
use rustc_hash::FxHashMap;

#[cfg(test)]
use super::pairs::{self, Soup};
use super::{
    edge_item, mesh_items, primitives_intersect, push_face, push_ring, Element, Item, Primitive,
    Scratch, WireThickness, NO_VERT,
};
use crate::geom::boxes::{round_down, round_up};
use crate::kernel::ids::{EdgeId, FaceId, VertId};
use crate::kernel::mesh::Mesh;
use crate::kernel::ops::Selection;

/// Box of a primitive grown by `pad`, rounded outward to `f32` and clamped
/// to the finite `f32` range. Rounding outward and clamping are monotone, so
/// boxes that overlap in `f64` still overlap in `f32`. `None` for
/// non-finite geometry, which never intersects anything.
fn aabb(prim: &Primitive, pad: f64) -> Option<Aabb> {
    if !prim.is_finite() {
        return None;
    }
    let points = prim.points();
    let (lo, hi) = points[1..]
        .iter()
        .fold((points[0], points[0]), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    let (lo, hi) = (lo - DVec3::splat(pad), hi + DVec3::splat(pad));
    let clamp = |x: f32| x.clamp(f32::MIN, f32::MAX);
    let down = lo.to_array().map(|x| clamp(round_down(x)));
    let up = hi.to_array().map(|x| clamp(round_up(x)));
    Some(Aabb::new(Vec3A::from_array(down), Vec3A::from_array(up)))
}

/// Up to this many consecutive triangles of one face form one BVH
/// primitive: a quad is one primitive, a large n-gon several.
const CHUNK: usize = 8;

/// Chunks per leaf, at most.
const LEAF: u32 = 1;

/// A static BVH over items. The tree's primitives are *chunks*: runs of
/// consecutive items of one element (a face's triangles are consecutive),
/// so pairs within a face are never generated, and the tree has about one
/// primitive per face (the build cost is per primitive).
#[derive(Clone)]
struct Tree {
    items: Vec<Item>,
    /// Per item; empty (never overlapping) for non-finite geometry.
    boxes: Vec<Aabb>,
    /// Item ranges, in the tree's leaf order (a leaf holds a run of them).
    chunks: Vec<(u32, u32)>,
    chunk_boxes: Vec<Aabb>,
    bvh: Bvh2,
}

impl Tree {
    fn new(items: Vec<Item>) -> Self {
        let boxes: Vec<Aabb> = items
            .iter()
            .map(|item| aabb(&item.prim, item.thickness).unwrap_or_else(Aabb::empty))
            .collect();
        let mut chunks: Vec<(u32, u32)> = Vec::with_capacity(items.len());
        let mut chunk_boxes: Vec<Aabb> = Vec::with_capacity(items.len());
        let mut start = 0;
        while start < items.len() {
            let owner = items[start].owner;
            let mut end = start + 1;
            while end < items.len() && end - start < CHUNK && items[end].owner == owner {
                end += 1;
            }
            let union = boxes[start..end]
                .iter()
                .fold(Aabb::empty(), |acc, b| acc.union(b));
            // A chunk of non-finite items only has no box: leave it out.
            if union.valid() {
                chunks.push((start as u32, end as u32));
                chunk_boxes.push(union);
            }
            start = end;
        }
        // PLOC with search distance 1, no reinsertion, one chunk per leaf:
        // these trees are walked once (self-intersection) or queried a few
        // times per primitive, so build time matters more than tree quality.
        let params = BvhBuildParams {
            pre_split: false,
            ploc_search_distance: PlocSearchDistance::Minimum,
            search_depth_threshold: 0,
            reinsertion_batch_ratio: 0.0,
            post_collapse_reinsertion_batch_ratio_multiplier: 0.0,
            sort_precision: SortPrecision::U64,
            max_prims_per_leaf: LEAF,
            collapse_traversal_cost: 1.0,
        };
        let bvh = build_bvh2(&chunk_boxes, params, &mut Duration::default());
        let order = &bvh.primitive_indices;
        let chunks = order.iter().map(|&k| chunks[k as usize]).collect();
        let chunk_boxes = order.iter().map(|&k| chunk_boxes[k as usize]).collect();
        Tree {
            items,
            boxes,
            chunks,
            chunk_boxes,
            bvh,
        }
    }

    /// The chunk slots of a leaf node.
    #[inline]
    fn leaf(&self, node: u32) -> std::ops::Range<usize> {
        let n = &self.bvh.nodes[node as usize];
        let first = n.first_index as usize;
        first..first + n.prim_count as usize
    }

    /// The items of chunk slot `c`.
    #[inline]
    fn chunk(&self, c: usize) -> std::ops::Range<usize> {
        let (start, end) = self.chunks[c];
        start as usize..end as usize
    }

    /// Whether any stored item whose box overlaps `query` passes `test`.
    fn any(&self, query: Aabb, mut test: impl FnMut(&Item) -> bool) -> bool {
        let mut hit = false;
        self.bvh.aabb_traverse(query, |_, node| {
            for c in self.leaf(node) {
                if !self.chunk_boxes[c].intersect_aabb(&query) {
                    continue;
                }
                for i in self.chunk(c) {
                    if self.boxes[i].intersect_aabb(&query) && test(&self.items[i]) {
                        hit = true;
                        return false;
                    }
                }
            }
            true
        });
        hit
    }
}

/// Every pair of distinct elements whose items intersect, smaller element
/// first, sorted and deduplicated. A face's triangles must be consecutive.
/// (The mesh passes build flat primitives directly; tests use items.)
///
/// Runs on up to [`THREADS`] threads for large inputs (see
/// [`super::pairs`]); the result is a sorted set, the same whatever the
/// thread count or timing.
#[cfg(test)]
pub(crate) fn intersecting_pairs(items: Vec<Item>) -> Vec<(Element, Element)> {
    let threads = threads_for(items.len());
    intersecting_pairs_on(items, threads)
}

/// [`intersecting_pairs`] on a given number of threads.
#[cfg(test)]
pub(crate) fn intersecting_pairs_on(items: Vec<Item>, threads: usize) -> Vec<(Element, Element)> {
    pairs::intersecting_pairs(Soup::from_items(&items), threads)
}

/// Threads for the self-intersection descent over `items` primitives.
pub(crate) fn threads_for(items: usize) -> usize {
    if items < PARALLEL_ITEMS {
        1
    } else {
        std::thread::available_parallelism().map_or(1, |n| n.get().min(THREADS))
    }
}

/// Threads for the self-intersection descent, at most.
pub(crate) const THREADS: usize = 2;

/// Below this many items one thread is faster than starting more.
pub(crate) const PARALLEL_ITEMS: usize = 20_000;

// ---- the incremental index ----

/// Primitives scanned linearly before they go into a tree.
const BUFFER: usize = 32;

/// An index of mesh primitives (face triangles and wire-edge capsules) for
/// growth tests: "would this new edge or face intersect the model?"
/// (thesis §3.2: a command is applied only if its products would not
/// intersect any existing primitive).
///
/// The index is a snapshot: it keeps the positions it was given when each
/// primitive was inserted. Queries answer `bool`, so the internal order of
/// the trees never shows. Primitives with non-finite coordinates are not
/// stored (they intersect nothing).
///
/// Queries name the existing vertices the new primitive is attached to
/// (`ignore_verts`): contact with a stored primitive only at such a shared
/// vertex (or along a shared mesh edge) is not a hit, but crossing anywhere
/// else is (module docs, "Shared vertices"). A query corner is that vertex
/// when its position equals, bit for bit, the stored position of the
/// vertex in the primitive being tested.
///
/// ```
/// use glam::DVec3;
/// use graftal::kernel::{Mesh, intersect::IntersectionIndex, ops::create};
/// let mut mesh = Mesh::new();
/// create::create_cube(&mut mesh, 2.0).unwrap();
/// let index = IntersectionIndex::from_mesh(&mesh, graftal::kernel::intersect::WireThickness::Zero);
/// // Through the cube: a hit. Beside it: none.
/// assert!(index.segment_hits(DVec3::new(0.0, 0.0, -5.0), DVec3::new(0.0, 0.0, 5.0), 0.0, &[]));
/// assert!(!index.segment_hits(DVec3::new(3.0, 0.0, -5.0), DVec3::new(3.0, 0.0, 5.0), 0.0, &[]));
/// // With a thickness of 1 the segment beside the cube reaches it.
/// assert!(index.segment_hits(DVec3::new(2.0, 0.0, -5.0), DVec3::new(2.0, 0.0, 5.0), 1.0, &[]));
/// ```
#[derive(Clone, Default)]
pub struct IntersectionIndex {
    buffer: Vec<Item>,
    buffer_boxes: Vec<Aabb>,
    /// `levels[i]` holds at most `BUFFER · 2^i` primitives.
    levels: Vec<Option<Tree>>,
    len: usize,
    scratch: Scratch,
    /// Bumped by each removal; items are stored with the current epoch.
    epoch: u64,
    /// Per removed element, the epoch of its removal: its items stored
    /// before it are dead (left in the trees, skipped by queries).
    removed: FxHashMap<Element, u64>,
}

impl IntersectionIndex {
    pub fn new() -> Self {
        Self::default()
    }

    /// An index of every face and wire edge of `mesh`, built as one tree.
    pub fn from_mesh(mesh: &Mesh, wires: WireThickness) -> Self {
        let mut index = Self::new();
        let items: Vec<Item> = mesh_items(mesh, Some(wires))
            .into_iter()
            .filter(|item| item.prim.is_finite())
            .collect();
        index.len = items.len();
        if !items.is_empty() {
            let mut level = 0;
            while BUFFER << level < items.len() {
                level += 1;
            }
            index.levels.resize_with(level + 1, || None);
            index.levels[level] = Some(Tree::new(items));
        }
        index
    }

    /// Number of stored primitives (triangles and segments), including
    /// those of removed elements.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Stores the triangles of face `f` (current positions).
    pub fn insert_face(&mut self, mesh: &Mesh, f: FaceId) {
        let mut items = Vec::new();
        push_face(mesh, f, &mut self.scratch, &mut items);
        for item in items {
            self.insert(item);
        }
    }

    /// Stores edge `e` as a capsule of the given thickness, whether or not
    /// it has faces (callers store wire edges; a face's edges are covered by
    /// its triangles).
    pub fn insert_edge(&mut self, mesh: &Mesh, e: EdgeId, thickness: f64) {
        self.insert(edge_item(mesh, e, thickness));
    }

    /// Stores what an operator made: every face of `products`, and every
    /// edge of it that is a wire edge, with the given thickness.
    pub fn insert_products(&mut self, mesh: &Mesh, products: &Selection, wires: WireThickness) {
        for &f in &products.faces {
            self.insert_face(mesh, f);
        }
        for &e in &products.edges {
            if mesh.is_wire_edge(e) {
                self.insert_edge(mesh, e, wires.of(mesh, e));
            }
        }
    }

    /// All of `items` in one tree (tests compare it with the levelled form).
    #[cfg(test)]
    pub(super) fn single_tree(items: Vec<Item>) -> Self {
        let mut index = Self::new();
        index.len = items.len();
        index.levels.push(Some(Tree::new(items)));
        index
    }

    #[cfg(test)]
    pub(super) fn tree_count(&self) -> usize {
        self.levels.iter().flatten().count()
    }

    /// Takes `element`'s stored primitives out of every later query; what
    /// is stored for it afterwards (its new shape) counts. A caller that
    /// edits the mesh between queries removes what the edit reshaped or
    /// deleted and stores the new shapes, keeping the index true to the
    /// mesh without a rebuild.
    pub fn remove(&mut self, element: Element) {
        self.epoch += 1;
        self.removed.insert(element, self.epoch);
    }

    /// Whether `item` belongs to an element removed after it was stored.
    #[inline]
    fn is_dead(&self, item: &Item) -> bool {
        !self.removed.is_empty()
            && self
                .removed
                .get(&item.owner)
                .is_some_and(|&at| item.epoch < at)
    }

    pub(super) fn insert(&mut self, mut item: Item) {
        let Some(b) = aabb(&item.prim, item.thickness) else {
            return;
        };
        item.epoch = self.epoch;
        self.len += 1;
        self.buffer.push(item);
        self.buffer_boxes.push(b);
        if self.buffer.len() < BUFFER {
            return;
        }
        self.buffer_boxes.clear();
        let mut carry = std::mem::take(&mut self.buffer);
        let mut level = 0;
        loop {
            if level == self.levels.len() {
                self.levels.push(None);
            }
            match self.levels[level].take() {
                None if carry.len() <= BUFFER << level => {
                    self.levels[level] = Some(Tree::new(carry));
                    return;
                }
                None => {}
                Some(full) => carry.extend(full.items),
            }
            level += 1;
        }
    }

    /// Would the segment `p0 p1` of the given thickness (a capsule radius;
    /// against a stored wire edge the two radii add up) intersect a stored
    /// primitive? `ignore_verts`: existing vertices the segment starts or
    /// ends at.
    pub fn segment_hits(
        &self,
        p0: DVec3,
        p1: DVec3,
        thickness: f64,
        ignore_verts: &[VertId],
    ) -> bool {
        self.hits(
            &Primitive::segment([p0, p1], [None; 2]),
            thickness,
            ignore_verts,
        )
    }

    /// Would the triangle intersect a stored primitive (exact; against a
    /// stored wire edge, at that edge's thickness)?
    pub fn triangle_hits(&self, corners: [DVec3; 3], ignore_verts: &[VertId]) -> bool {
        self.hits(&Primitive::triangle(corners, [None; 3]), 0.0, ignore_verts)
    }

    /// Would a face with this ring of corners intersect a stored primitive?
    /// The ring is triangulated as the face would be.
    pub fn face_hits(&self, ring: &[DVec3], ignore_verts: &[VertId]) -> bool {
        let mut tris = Vec::new();
        let mut items = Vec::new();
        let none = vec![None; ring.len()];
        // The owner is never compared: queries are not stored.
        push_ring(
            ring,
            &none,
            Element::Face(FaceId::from_raw(u32::MAX - 1)),
            &mut tris,
            &mut items,
        );
        items
            .iter()
            .any(|item| self.hits(&item.prim, 0.0, ignore_verts))
    }

    /// Would `query` (whose corners may already name vertices) intersect a
    /// stored primitive, at the given thickness?
    pub fn primitive_hits(&self, query: &Primitive, thickness: f64) -> bool {
        self.hits(query, thickness, &[])
    }

    /// [`segment_hits`](Self::segment_hits), leaving out stored primitives
    /// whose element `left_out` names (ones the caller is about to reshape
    /// or remove).
    pub fn segment_hits_except(
        &self,
        p0: DVec3,
        p1: DVec3,
        thickness: f64,
        ignore_verts: &[VertId],
        left_out: &dyn Fn(Element) -> bool,
    ) -> bool {
        self.hits_except(
            &Primitive::segment([p0, p1], [None; 2]),
            thickness,
            ignore_verts,
            left_out,
        )
    }

    /// [`face_hits`](Self::face_hits), leaving out stored primitives whose
    /// element `left_out` names.
    pub fn face_hits_except(
        &self,
        ring: &[DVec3],
        ignore_verts: &[VertId],
        left_out: &dyn Fn(Element) -> bool,
    ) -> bool {
        let mut tris = Vec::new();
        let mut items = Vec::new();
        let none = vec![None::<VertId>; ring.len()];
        push_ring(
            ring,
            &none,
            Element::Face(FaceId::from_raw(u32::MAX - 1)),
            &mut tris,
            &mut items,
        );
        items
            .iter()
            .any(|item| self.hits_except(&item.prim, 0.0, ignore_verts, left_out))
    }

    fn hits(&self, query: &Primitive, thickness: f64, ignore_verts: &[VertId]) -> bool {
        self.hits_except(query, thickness, ignore_verts, &|_| false)
    }

    fn hits_except(
        &self,
        query: &Primitive,
        thickness: f64,
        ignore_verts: &[VertId],
        left_out: &dyn Fn(Element) -> bool,
    ) -> bool {
        let thickness = if thickness.is_finite() && thickness > 0.0 {
            thickness
        } else {
            0.0
        };
        let Some(qbox) = aabb(query, thickness) else {
            return false;
        };
        let test = &|item: &Item| {
            if left_out(item.owner) || self.is_dead(item) {
                return false;
            }
            let q = attach(query, &item.prim, ignore_verts);
            primitives_intersect(&q, &item.prim, thickness + item.thickness)
        };
        let in_buffer = self
            .buffer
            .iter()
            .zip(&self.buffer_boxes)
            .any(|(item, b)| b.intersect_aabb(&qbox) && test(item));
        if in_buffer {
            return true;
        }
        self.levels
            .iter()
            .flatten()
            .any(|tree| tree.any(qbox, test))
    }
}

/// The query with the ids of `ignore_verts` given to the corners that sit
/// exactly on a corner of `stored` carrying that id.
fn attach(query: &Primitive, stored: &Primitive, ignore_verts: &[VertId]) -> Primitive {
    let mut q = *query;
    if ignore_verts.is_empty() {
        return q;
    }
    for (v, &p) in stored.verts().zip(stored.points()) {
        let Some(v) = v.filter(|v| ignore_verts.contains(v)) else {
            continue;
        };
        if q.verts().any(|w| w == Some(v)) {
            continue;
        }
        let n = q.len as usize;
        if let Some(k) = (0..n).find(|&k| q.verts[k] == NO_VERT && q.points[k] == p) {
            q.verts[k] = v.raw();
        }
    }
    q
}
