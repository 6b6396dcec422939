//! Whole-mesh self-intersection: every pair of elements whose primitives
//! intersect ([`super::self_intersections`]). The pass is bound by memory
//! traffic and by the number of candidate pairs (about 1.3 million for
//! 180k triangles, nine in ten of them neighbours sharing a vertex or an
//! edge), so:
//!
//! - Primitives are built straight from the mesh into flat arrays of small
//!   plain records ([`Flat`]: three corner indices into one array of
//!   positions, the vertex ids being those indices), with an `f32` box
//!   each and *chunks* (runs of up to [`CHUNK`] triangles of one face, so
//!   that pairs within a face are never generated): no per-item
//!   allocation, no stored planes. Faces are split between threads; the
//!   result is the same.
//! - The broad phase is a BVH over chunks, ordered along a Morton curve of
//!   the chunk centres and split at the highest differing Morton bit (a
//!   linear BVH: a sort and one linear pass). Boxes are `f32`, rounded
//!   outward from the `f64` bounds, so they can add candidates but never
//!   lose one.
//! - The tree is walked against itself (a simultaneous descent visits each
//!   pair of overlapping leaves once, and only overlapping node pairs are
//!   stacked). With several threads the top of that descent is expanded
//!   breadth first into independent node-pair tasks, which the threads
//!   take from a shared counter.
//! - Each vertex gets one certificate that its fan of triangles is
//!   embedded, a flat or smooth umbrella ([`certified_fans`]: O(valence)
//!   filtered orientation tests), which settles at once the candidate
//!   pairs of triangles around it that share it alone or a mesh edge at
//!   it: nine in ten of all pairs on a smooth surface.
//! - Each other candidate pair of triangles is first given certified
//!   floating-point tests ([`triangles_miss`]) whose "miss" implies a miss
//!   of [`super::primitives_intersect`]; whatever they leave undecided goes
//!   to `primitives_intersect` itself (the reference, with the exact
//!   predicates). Segments and pairs with a thickness always go there.
//!
//! The result is a sorted set of element pairs, so it does not depend on
//! the tree's shape, the thread count or the order tasks were taken in.

use std::collections::{BinaryHeap, VecDeque};
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::DVec3;
use rustc_hash::FxHashSet;

#[cfg(test)]
use super::Item;
use super::{primitives_intersect, Element, Primitive, WireThickness, NO_VERT};
use crate::geom::boxes::Box3;
use crate::geom::polygon;
use crate::geom::predicates::{orient3d_filtered_at, Plane};
use crate::geom::IndexedMesh;
use crate::kernel::ids::{EdgeId, FaceId};
use crate::kernel::mesh::Mesh;

// ---- flat primitives ----

/// A primitive as the self-intersection pass stores it: indices of its
/// corners in `Soup::points` and what [`Primitive`] keeps besides
/// (16 bytes, where an `Item` takes 184). The element is its chunk's.
#[derive(Clone, Copy, Debug)]
struct Flat {
    /// Corner positions (a segment repeats its second end, as
    /// [`Primitive::segment`] does).
    pt: [u32; 3],
    /// 2 for a segment, 3 for a triangle.
    len: u8,
    /// As [`Primitive`]'s: bit `i` marks the edge from corner `i` to `i + 1`
    /// as a mesh edge.
    boundary: u8,
}

/// Flat primitives with the positions they index, grouped in chunks.
pub(crate) struct Soup {
    points: Vec<DVec3>,
    flats: Vec<Flat>,
    /// Vertex ids per flat ([`NO_VERT`] where unknown); empty when they are
    /// the corner indices (a mesh's soup indexes positions by vertex id).
    ids: Vec<[u32; 3]>,
    /// Per flat, when any has a thickness; else empty (all 0).
    thickness: Vec<f64>,
    /// Per flat: [`Soup::bounds`] as a [`Box3`], empty for non-finite
    /// corners.
    boxes: Vec<Box3>,
    /// In item order; items with non-finite corners are in none.
    chunks: Vec<Chunk>,
    /// Per vertex id, whether its fan is certified embedded
    /// ([`certified_fans`]); empty when none is (a soup of loose items).
    fans: Vec<bool>,
}

/// A run of items `start .. end` of one element, all with finite corners,
/// with a box around them (grown by their thickness).
#[derive(Clone, Copy, Debug)]
struct Chunk {
    bounds: Box3,
    start: u32,
    end: u32,
    owner: Element,
    /// Whether the owner has other chunks: only then can one element pair
    /// be found through two chunk pairs (so only then is it remembered).
    shared: bool,
}

/// Up to this many consecutive triangles of one face form one chunk: a
/// quad is one chunk, a large n-gon several.
const CHUNK: usize = 8;

/// Appends the chunks of the items `run` of element `owner`: runs of up to
/// [`CHUNK`] consecutive items that `bounds` gives an `f64` box (those with
/// finite corners).
fn push_chunks(
    run: std::ops::Range<usize>,
    owner: Element,
    bounds: impl Fn(usize) -> Option<(DVec3, DVec3)>,
    out: &mut Vec<Chunk>,
) {
    let first = out.len();
    let mut open: Option<(usize, DVec3, DVec3)> = None;
    let close = |open: &mut Option<(usize, DVec3, DVec3)>, end: usize, out: &mut Vec<Chunk>| {
        if let Some((start, lo, hi)) = open.take() {
            out.push(Chunk {
                bounds: Box3::around(lo, hi),
                start: start as u32,
                end: end as u32,
                owner,
                shared: false,
            });
        }
    };
    for k in run.clone() {
        match bounds(k) {
            None => close(&mut open, k, out),
            Some((lo, hi)) => {
                if matches!(open, Some((start, ..)) if k - start == CHUNK) {
                    close(&mut open, k, out);
                }
                open = Some(match open {
                    None => (k, lo, hi),
                    Some((start, l, h)) => (start, l.min(lo), h.max(hi)),
                });
            }
        }
    }
    close(&mut open, run.end, out);
    if out.len() - first > 1 {
        for chunk in &mut out[first..] {
            chunk.shared = true;
        }
    }
}

impl Soup {
    /// The soup of a list of items, in their order.
    #[cfg(test)]
    pub(crate) fn from_items(items: &[Item]) -> Self {
        let mut soup = Soup {
            points: Vec::with_capacity(3 * items.len()),
            flats: Vec::with_capacity(items.len()),
            ids: Vec::with_capacity(items.len()),
            thickness: Vec::new(),
            boxes: Vec::new(),
            chunks: Vec::new(),
            fans: Vec::new(),
        };
        for item in items {
            let k = soup.points.len() as u32;
            soup.points.extend_from_slice(&item.prim.points);
            soup.flats.push(Flat {
                pt: [k, k + 1, k + 2],
                len: item.prim.len,
                boundary: item.prim.boundary,
            });
            soup.ids.push(item.prim.verts);
        }
        if items.iter().any(|item| item.thickness != 0.0) {
            soup.thickness = items.iter().map(|item| item.thickness).collect();
        }
        soup.boxes = (0..items.len()).map(|k| soup.item_box(k)).collect();
        let mut start = 0;
        while start < items.len() {
            let owner = items[start].owner;
            let run_end = (start..items.len())
                .find(|&k| items[k].owner != owner)
                .unwrap_or(items.len());
            let mut chunks = Vec::new();
            push_chunks(start..run_end, owner, |k| soup.bounds(k), &mut chunks);
            soup.chunks.extend(chunks);
            start = run_end;
        }
        soup
    }

    /// Per vertex id, whether its fan is certified embedded.
    #[cfg(test)]
    pub(crate) fn certified_fans(&self) -> &[bool] {
        &self.fans
    }

    /// Number of primitives.
    pub(crate) fn len(&self) -> usize {
        self.flats.len()
    }

    #[inline(always)]
    fn ids(&self, k: usize) -> [u32; 3] {
        match self.ids.get(k) {
            Some(&ids) => ids,
            None => self.flats[k].pt,
        }
    }

    #[inline(always)]
    fn thickness(&self, k: usize) -> f64 {
        self.thickness.get(k).copied().unwrap_or(0.0)
    }

    /// The [`Primitive`] flat `k` was made from (equal field by field).
    fn prim(&self, k: usize) -> Primitive {
        let f = &self.flats[k];
        let points = f.pt.map(|i| self.points[i as usize]);
        Primitive {
            points,
            verts: self.ids(k),
            len: f.len,
            boundary: f.boundary,
            plane: (f.len == 3).then(|| Plane::new(points)),
        }
    }

    /// [`Soup::bounds`] of flat `k` as a [`Box3`].
    fn item_box(&self, k: usize) -> Box3 {
        self.bounds(k)
            .map_or(Box3::EMPTY, |(lo, hi)| Box3::around(lo, hi))
    }

    /// The `f64` box of flat `k` grown by its thickness, `None` for
    /// non-finite corners (such a primitive never intersects anything).
    fn bounds(&self, k: usize) -> Option<(DVec3, DVec3)> {
        let f = &self.flats[k];
        let p = f.pt.map(|i| self.points[i as usize]);
        if !p[..f.len as usize].iter().all(|q| q.is_finite()) {
            return None;
        }
        let t = self.thickness(k);
        let pad = DVec3::splat(if t > 0.0 { t } else { 0.0 });
        Some((
            p[0].min(p[1]).min(p[2]) - pad,
            p[0].max(p[1]).max(p[2]) + pad,
        ))
    }
}

/// Faces of a mesh below this count are triangulated on one thread.
pub(crate) const PARALLEL_FACES: usize = 4096;

/// Where a soup's faces come from: the corner vertex ids of each, in
/// order, and the positions they index.
pub(crate) trait FaceRings: Sync {
    /// Appends the corners of face `f` to `out`.
    fn ring(&self, f: FaceId, out: &mut Vec<u32>);
}

impl FaceRings for Mesh {
    fn ring(&self, f: FaceId, out: &mut Vec<u32>) {
        out.extend(self.face_verts(f).map(|v| v.raw()));
    }
}

/// An indexed mesh read as the kernel mesh [`crate::kernel::build`] makes
/// of it when that is one to one: polygon `k` is face `k`, vertex `i` is
/// vertex `i`.
impl FaceRings for IndexedMesh {
    fn ring(&self, f: FaceId, out: &mut Vec<u32>) {
        out.extend_from_slice(self.polygon(f.index()));
    }
}

/// The triangles of every face of `mesh` (its triangulation, as
/// [`super::push_face`] makes them) and, if `wires` is given, its wire
/// edges, in id order: the primitives of [`super::mesh_items`].
pub(crate) fn mesh_soup(mesh: &Mesh, wires: Option<WireThickness>, threads: usize) -> Soup {
    let mut points = vec![DVec3::NAN; mesh.vert_capacity()];
    for v in mesh.vert_ids() {
        points[v.index()] = mesh.position(v);
    }
    let faces: Vec<FaceId> = mesh.face_ids().collect();
    let soup = face_soup(mesh, points, &faces, threads);
    match wires {
        Some(wires) => with_wires(soup, mesh, wires, threads),
        None => certified(soup, threads),
    }
}

/// [`mesh_soup`] without wires of the kernel mesh an indexed mesh builds
/// one to one ([`crate::kernel::build::builds_one_to_one`]), without
/// building it: the same primitives, elements and certificates.
pub(crate) fn indexed_soup(mesh: &IndexedMesh, threads: usize) -> Soup {
    let points = (0..mesh.positions.len() as u32)
        .map(|i| mesh.position(i))
        .collect();
    let faces: Vec<FaceId> = (0..mesh.polygon_count() as u32)
        .map(FaceId::from_raw)
        .collect();
    certified(face_soup(mesh, points, &faces, threads), threads)
}

/// The triangles of `faces` (in that order) over `points`, split between
/// `threads`; no wires, no certificates yet.
fn face_soup(
    source: &impl FaceRings,
    points: Vec<DVec3>,
    faces: &[FaceId],
    threads: usize,
) -> Soup {
    let (flats, boxes, chunks) = if threads <= 1 || faces.len() < PARALLEL_FACES {
        let mut out = (
            Vec::with_capacity(faces.len() * 2),
            Vec::with_capacity(faces.len() * 2),
            Vec::with_capacity(faces.len()),
        );
        push_faces(source, &points, faces, &mut out);
        out
    } else {
        // The first share is made in the final arrays, the others are
        // appended (their chunks shifted).
        let share = faces.len().div_ceil(threads);
        let points = &points;
        let make = move |part: &[FaceId]| {
            let mut out = (
                Vec::with_capacity(part.len() * 2),
                Vec::with_capacity(part.len() * 2),
                Vec::with_capacity(part.len()),
            );
            push_faces(source, points, part, &mut out);
            out
        };
        std::thread::scope(|scope| {
            let handles: Vec<_> = faces[share..]
                .chunks(share)
                .map(|part| scope.spawn(move || make(part)))
                .collect();
            let (mut flats, mut boxes, mut chunks) = make(&faces[..share]);
            for handle in handles {
                let (more_flats, more_boxes, more_chunks) = join(handle);
                let offset = flats.len() as u32;
                flats.extend_from_slice(&more_flats);
                boxes.extend_from_slice(&more_boxes);
                chunks.extend(more_chunks.into_iter().map(|c| Chunk {
                    start: c.start + offset,
                    end: c.end + offset,
                    ..c
                }));
            }
            (flats, boxes, chunks)
        })
    };
    Soup {
        points,
        flats,
        ids: Vec::new(),
        thickness: Vec::new(),
        boxes,
        chunks,
        fans: Vec::new(),
    }
}

/// `soup` with the wire edges of `mesh` appended as segments, certified.
fn with_wires(soup: Soup, mesh: &Mesh, wires: WireThickness, threads: usize) -> Soup {
    let Soup {
        points,
        mut flats,
        mut boxes,
        mut chunks,
        ..
    } = soup;
    let mut soup = Soup {
        points,
        flats: Vec::new(),
        ids: Vec::new(),
        thickness: Vec::new(),
        boxes: Vec::new(),
        chunks: Vec::new(),
        fans: Vec::new(),
    };
    let first = flats.len();
    let edges: Vec<EdgeId> = mesh.edge_ids().filter(|&e| mesh.is_wire_edge(e)).collect();
    let mut thickness = Vec::with_capacity(edges.len());
    for &e in &edges {
        let [a, b] = mesh.edge_verts(e);
        // As `super::edge_item`.
        let t = wires.of(mesh, e);
        thickness.push(if t.is_finite() && t > 0.0 { t } else { 0.0 });
        flats.push(Flat {
            pt: [a.raw(), b.raw(), b.raw()],
            len: 2,
            boundary: 1,
        });
    }
    if thickness.iter().any(|&t| t != 0.0) {
        soup.thickness = vec![0.0; first];
        soup.thickness.extend(thickness);
    }
    if !edges.is_empty() {
        // The third corner of a segment names no vertex.
        soup.ids = flats.iter().map(|f| f.pt).collect();
        for id in &mut soup.ids[first..] {
            id[2] = NO_VERT;
        }
    }
    soup.flats = flats;
    for (k, &e) in (first..).zip(&edges) {
        boxes.push(soup.item_box(k));
        push_chunks(k..k + 1, Element::Edge(e), |k| soup.bounds(k), &mut chunks);
    }
    soup.boxes = boxes;
    soup.chunks = chunks;
    certified(soup, threads)
}

/// `soup` with its vertex fans certified (positions are indexed by vertex
/// id, as the certificate needs).
fn certified(mut soup: Soup, threads: usize) -> Soup {
    soup.fans = certified_fans(&soup.points, &soup.flats, threads);
    soup
}

/// Appends the triangles of `faces` and their chunks, as
/// [`super::push_ring`] makes them.
fn push_faces(
    source: &impl FaceRings,
    points: &[DVec3],
    faces: &[FaceId],
    (out, boxes, chunks): &mut (Vec<Flat>, Vec<Box3>, Vec<Chunk>),
) {
    let mut verts: Vec<u32> = Vec::new();
    let mut ring: Vec<DVec3> = Vec::new();
    let mut tris: Vec<[u32; 3]> = Vec::new();
    for &f in faces {
        verts.clear();
        ring.clear();
        source.ring(f, &mut verts);
        ring.extend(verts.iter().map(|&v| points[v as usize]));
        tris.clear();
        polygon::triangulate(&ring, &mut tris);
        let n = ring.len();
        // A ring edge joins neighbours in the ring; anything else is a
        // diagonal (no `%`: an integer division per test shows here).
        let next = |p: usize| if p + 1 == n { 0 } else { p + 1 };
        let is_edge = |p: usize, q: usize| next(p) == q || next(q) == p;
        let start = out.len();
        for t in &tris {
            let [i, j, k] = t.map(|x| x as usize);
            let boundary = u8::from(is_edge(i, j))
                | (u8::from(is_edge(j, k)) << 1)
                | (u8::from(is_edge(k, i)) << 2);
            out.push(Flat {
                pt: [verts[i], verts[j], verts[k]],
                len: 3,
                boundary,
            });
        }
        let bounds = |k: usize| {
            let p = tris[k - start].map(|x| ring[x as usize]);
            p.iter()
                .all(|q| q.is_finite())
                .then(|| (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2])))
        };
        for k in start..out.len() {
            boxes.push(bounds(k).map_or(Box3::EMPTY, |(lo, hi)| Box3::around(lo, hi)));
        }
        push_chunks(start..out.len(), Element::Face(f), bounds, chunks);
    }
}

fn join<T>(handle: std::thread::ScopedJoinHandle<'_, T>) -> T {
    handle
        .join()
        .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
}

// ---- the linear BVH ----

/// Chunks per leaf, at most.
const LEAF: usize = 8;

/// A tree node: a leaf holds chunk slots `first .. first + count`; an
/// inner node (`count == 0`) has its children at `first` and `first + 1`.
#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Box3,
    first: u32,
    count: u32,
}

struct Tree {
    soup: Soup,
    /// In leaf order (chunks of non-finite items only are left out).
    chunks: Vec<Chunk>,
    /// The root is node 0 (absent when no chunk has a box).
    nodes: Vec<Node>,
}

/// Spreads the low 21 bits of `x` three bits apart.
fn spread(x: u64) -> u64 {
    let mut x = x & 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

impl Tree {
    fn new(mut soup: Soup, threads: usize) -> Self {
        let chunks = std::mem::take(&mut soup.chunks);
        if chunks.is_empty() {
            return Tree {
                soup,
                chunks,
                nodes: Vec::new(),
            };
        }
        // Morton codes of the chunk centres (in f64: no overflow).
        let centre = |b: &Box3| {
            DVec3::from_array([0, 1, 2].map(|k| (f64::from(b.lo[k]) + f64::from(b.hi[k])) * 0.5))
        };
        let (lo, hi) = chunks.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), c| {
                let c = centre(&c.bounds);
                (lo.min(c), hi.max(c))
            },
        );
        let extent = hi - lo;
        let scale =
            DVec3::from_array(
                extent
                    .to_array()
                    .map(|e| if e > 0.0 { 2_097_151.0 / e } else { 0.0 }),
            );
        let sorted_keys = |range: std::ops::Range<usize>| {
            let mut keyed: Vec<(u64, u32)> = range
                .map(|k| {
                    let q = ((centre(&chunks[k].bounds) - lo) * scale).to_array();
                    let bits = q.map(|x| spread(x.clamp(0.0, 2_097_151.0) as u64));
                    (bits[0] | bits[1] << 1 | bits[2] << 2, k as u32)
                })
                .collect();
            keyed.sort_unstable();
            keyed
        };
        let n = chunks.len();
        let keyed = if threads <= 1 || n < PARALLEL_FACES {
            sorted_keys(0..n)
        } else {
            // Two sorted halves, merged.
            let (first, second) = std::thread::scope(|scope| {
                let second = scope.spawn(|| sorted_keys(n / 2..n));
                (sorted_keys(0..n / 2), join(second))
            });
            let mut keyed = Vec::with_capacity(n);
            let (mut x, mut y) = (first.into_iter().peekable(), second.into_iter().peekable());
            while let (Some(a), Some(b)) = (x.peek(), y.peek()) {
                let take_x = a <= b;
                keyed.extend(if take_x { x.next() } else { y.next() });
            }
            keyed.extend(x);
            keyed.extend(y);
            keyed
        };
        let codes: Vec<u64> = keyed.iter().map(|&(c, _)| c).collect();
        let chunks: Vec<Chunk> = keyed.iter().map(|&(_, k)| chunks[k as usize]).collect();
        let mut nodes = Vec::with_capacity(2 * chunks.len().div_ceil(LEAF));
        nodes.push(Node {
            bounds: Box3::EMPTY,
            first: 0,
            count: 0,
        });
        build(&codes, &chunks, &mut nodes, 0, 0, chunks.len());
        Tree {
            soup,
            chunks,
            nodes,
        }
    }
}

/// Fills node `node` with a subtree over the chunk slots `lo .. hi`
/// (sorted by Morton code), split where the highest differing bit of the
/// codes changes (or in the middle when all codes are equal).
fn build(
    codes: &[u64],
    chunks: &[Chunk],
    nodes: &mut Vec<Node>,
    node: usize,
    lo: usize,
    hi: usize,
) {
    if hi - lo <= LEAF {
        let bounds = chunks[lo..hi]
            .iter()
            .fold(Box3::EMPTY, |acc, c| acc.union(&c.bounds));
        nodes[node] = Node {
            bounds,
            first: lo as u32,
            count: (hi - lo) as u32,
        };
        return;
    }
    let (a, z) = (codes[lo], codes[hi - 1]);
    let mid = if a == z {
        (lo + hi) / 2
    } else {
        // The codes share every bit above `bit` and are sorted, so the
        // ones with `bit` clear come first.
        let bit = 63 - (a ^ z).leading_zeros();
        lo + codes[lo..hi].partition_point(|&c| c & (1 << bit) == 0)
    };
    let child = nodes.len();
    let blank = nodes[node];
    nodes.extend([blank, blank]);
    build(codes, chunks, nodes, child, lo, mid);
    build(codes, chunks, nodes, child + 1, mid, hi);
    nodes[node] = Node {
        bounds: nodes[child].bounds.union(&nodes[child + 1].bounds),
        first: child as u32,
        count: 0,
    };
}

// ---- the descent ----

/// Bounds on a pair search, so that degenerate input (thousands of
/// coincident triangles, a face over four vertices repeated 12,000 times)
/// costs bounded time and memory: every pair is counted, but only the
/// smallest `keep` are kept, and the search stops after `max_tests`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairLimits {
    /// Pairs kept: the first ones in canonical (sorted) order.
    pub keep: usize,
    /// Tests allowed (a chunk pair's box test, an item pair's primitive
    /// test), shared equally by the search's tasks.
    pub max_tests: u64,
}

impl PairLimits {
    /// Every pair, however long it takes (tests and small meshes).
    pub const UNLIMITED: PairLimits = PairLimits {
        keep: usize::MAX,
        max_tests: u64::MAX,
    };

    /// What `info` and the stats use: 1,000 pairs kept, and on the order
    /// of a hundred tests per item (a smooth 180k-triangle sphere needs
    /// about eight) before the search gives up.
    pub fn for_items(items: usize) -> PairLimits {
        PairLimits {
            keep: 1_000,
            max_tests: (items as u64)
                .saturating_mul(128)
                .saturating_add(20_000_000),
        }
    }
}

/// Most pairs of multi-chunk elements a search remembers, over all its
/// tasks (16 bytes each and the sets' overhead: about 40 MB), before it
/// stops early: each task may hold its share.
const MAX_SHARED_PAIRS: usize = 1 << 20;
const SHARED_PAIRS_PER_TASK: usize = MAX_SHARED_PAIRS / TASKS;

/// What a pair search found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PairSearch<T> {
    /// Distinct intersecting pairs found (all of them when `complete`).
    pub count: u64,
    /// The smallest [`PairLimits::keep`] of them, sorted.
    pub pairs: Vec<T>,
    /// Whether the search ran to the end (within [`PairLimits::max_tests`]).
    pub complete: bool,
}

/// What one task of the descent found, within its share of the tests.
struct Found {
    /// Pairs of elements of one chunk each: found through one chunk pair
    /// only, so they are counted without being remembered.
    single: u64,
    /// Pairs with an element of several chunks (large n-gons), remembered
    /// so that a second chunk pair of the same elements is not counted
    /// again. Looked up only, never iterated into output order.
    shared: FxHashSet<(Element, Element)>,
    /// The smallest `keep` pairs, as a max-heap.
    smallest: BinaryHeap<(Element, Element)>,
    keep: usize,
    budget: u64,
    exhausted: bool,
    /// Stopped by the memory cap on remembered pairs, not by its tests:
    /// more tests would not help, so the task is not run again.
    capped: bool,
}

impl Found {
    fn new(keep: usize, budget: u64) -> Found {
        Found {
            single: 0,
            shared: FxHashSet::default(),
            smallest: BinaryHeap::new(),
            keep,
            budget,
            exhausted: false,
            capped: false,
        }
    }

    /// Takes one test from the budget; `false` once it is spent.
    #[inline]
    fn spend(&mut self) -> bool {
        match self.budget.checked_sub(1) {
            Some(left) => {
                self.budget = left;
                true
            }
            None => {
                self.exhausted = true;
                false
            }
        }
    }

    fn insert(&mut self, key: (Element, Element), shared: bool) {
        if shared {
            if !self.shared.insert(key) {
                return;
            }
            // Remembered pairs are memory: a degenerate input (one OBJ face
            // of a million corners winding over itself) would grow the set
            // by every test. Past the cap the search stops, its counts
            // lower bounds, as when the test budget is spent.
            if self.shared.len() >= SHARED_PAIRS_PER_TASK {
                self.budget = 0;
                self.exhausted = true;
                self.capped = true;
            }
        } else {
            self.single += 1;
        }
        // Keep the smallest `keep`: a key past the largest kept one (the
        // usual case once the heap is full) costs one comparison.
        if self.smallest.len() < self.keep {
            self.smallest.push(key);
        } else if self.smallest.peek().is_some_and(|&max| key < max) {
            self.smallest.pop();
            self.smallest.push(key);
        }
    }
}

impl Tree {
    #[inline]
    fn leaf(&self, node: &Node) -> std::ops::Range<usize> {
        node.first as usize..(node.first + node.count) as usize
    }

    /// Tests chunk slots `ca` and `cb`: nothing for chunks of one element;
    /// else one test from the budget (`false` once it is spent) and, if
    /// their boxes overlap, their items ([`Tree::overlapping_chunks`]).
    /// Kept small enough to inline into the leaf loops: most chunk pairs
    /// end at the box test.
    #[inline(always)]
    fn chunk_pair(&self, ca: usize, cb: usize, found: &mut Found) -> bool {
        let (a, b) = (&self.chunks[ca], &self.chunks[cb]);
        if a.owner == b.owner {
            return true;
        }
        if !found.spend() {
            return false;
        }
        if a.bounds.overlaps(&b.bounds) {
            self.overlapping_chunks(a, b, found);
        }
        true
    }

    /// Tests the item pairs with overlapping boxes of two chunks of
    /// different elements whose boxes overlap.
    #[inline(never)]
    fn overlapping_chunks(&self, a: &Chunk, b: &Chunk, found: &mut Found) {
        let key = (a.owner.min(b.owner), a.owner.max(b.owner));
        let shared = a.shared || b.shared;
        // Skip pairs already found (only elements of several chunks repeat).
        if shared && found.shared.contains(&key) {
            return;
        }
        let boxes = &self.soup.boxes;
        let (ra, rb) = (
            a.start as usize..a.end as usize,
            b.start as usize..b.end as usize,
        );
        let hit = ra.into_iter().any(|i| {
            let bi = boxes[i];
            rb.clone()
                .any(|j| bi.overlaps(&boxes[j]) && found.spend() && self.soup.intersect(i, j))
        });
        if hit {
            found.insert(key, shared);
        }
    }

    /// Pushes the node pairs task `(a, b)` expands into, where `(a, a)`
    /// stands for "the pairs within subtree `a`" and other pairs are known
    /// to overlap (only overlapping pairs are pushed); `false` for
    /// leaf-level work, which it leaves to the caller.
    #[inline]
    fn expand(&self, (a, b): (u32, u32), out: &mut impl Extend<(u32, u32)>) -> bool {
        let nodes = &self.nodes;
        let (na, nb) = (&nodes[a as usize], &nodes[b as usize]);
        if a == b {
            if na.count > 0 {
                return false;
            }
            let c = na.first;
            out.extend([(c, c), (c + 1, c + 1)]);
            if nodes[c as usize]
                .bounds
                .overlaps(&nodes[c as usize + 1].bounds)
            {
                out.extend([(c, c + 1)]);
            }
            return true;
        }
        let split_a = match (na.count > 0, nb.count > 0) {
            (true, true) => return false,
            (false, leaf_b) => leaf_b || na.bounds.size() >= nb.bounds.size(),
            (true, false) => false,
        };
        if split_a {
            let c = na.first;
            for child in [c, c + 1] {
                if nodes[child as usize].bounds.overlaps(&nb.bounds) {
                    out.extend([(child, b)]);
                }
            }
        } else {
            let c = nb.first;
            for child in [c, c + 1] {
                if na.bounds.overlaps(&nodes[child as usize].bounds) {
                    out.extend([(a, child)]);
                }
            }
        }
        true
    }

    /// The simultaneous descent from the node pairs in `stack` to the end
    /// (or until the task's tests are spent).
    fn descend(&self, stack: &mut Vec<(u32, u32)>, found: &mut Found) {
        while let Some((a, b)) = stack.pop() {
            if found.exhausted {
                stack.clear();
                return;
            }
            if self.expand((a, b), stack) {
                continue;
            }
            let (na, nb) = (&self.nodes[a as usize], &self.nodes[b as usize]);
            // A spent budget ends the task (`found.exhausted` is set).
            if a == b {
                let chunks = self.leaf(na);
                for ca in chunks.clone() {
                    for cb in ca + 1..chunks.end {
                        if !self.chunk_pair(ca, cb, found) {
                            return stack.clear();
                        }
                    }
                }
            } else {
                for ca in self.leaf(na) {
                    for cb in self.leaf(nb) {
                        if !self.chunk_pair(ca, cb, found) {
                            return stack.clear();
                        }
                    }
                }
            }
        }
    }
}

/// Every pair of distinct elements whose primitives intersect, smaller
/// element first, sorted and deduplicated, found on `threads` threads (the
/// result does not depend on it). A face's triangles must be consecutive.
pub(crate) fn intersecting_pairs(soup: Soup, threads: usize) -> Vec<(Element, Element)> {
    search_pairs(soup, threads, PairLimits::UNLIMITED).pairs
}

/// [`intersecting_pairs`] within `limits`. The descent is cut into the
/// same tasks whatever the thread count, and each task gets the same share
/// of the tests, so even a search that stops early gives the same answer
/// on any number of threads.
pub(crate) fn search_pairs(
    soup: Soup,
    threads: usize,
    limits: PairLimits,
) -> PairSearch<(Element, Element)> {
    let tree = Tree::new(soup, threads);
    if tree.nodes.is_empty() {
        return PairSearch {
            count: 0,
            pairs: Vec::new(),
            complete: true,
        };
    }
    // Breadth first, so that the tasks are of about the same depth.
    let mut queue: VecDeque<(u32, u32)> = VecDeque::from([(0, 0)]);
    let mut leaves: Vec<(u32, u32)> = Vec::new();
    while queue.len() + leaves.len() < TASKS {
        let Some(task) = queue.pop_front() else { break };
        if !tree.expand(task, &mut queue) {
            leaves.push(task);
        }
    }
    let tasks: Vec<(u32, u32)> = queue.into_iter().chain(leaves).collect();
    let share = (limits.max_tests / tasks.len().max(1) as u64).max(1);
    // Runs the tasks numbered `which` with their shares, in parallel,
    // returning what each found in `which`'s order.
    let run_tasks = |which: &[usize], shares: &[u64]| -> Vec<Found> {
        let run = |k: usize| {
            let mut found = Found::new(limits.keep, shares[k]);
            tree.descend(&mut vec![tasks[k]], &mut found);
            found
        };
        if threads <= 1 {
            return which.iter().map(|&k| run(k)).collect();
        }
        let next = AtomicUsize::new(0);
        let work = || {
            let mut mine = Vec::new();
            loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(&k) = which.get(i) else { break };
                mine.push((i, run(k)));
            }
            mine
        };
        let mut indexed: Vec<(usize, Found)> = std::thread::scope(|scope| {
            let handles: Vec<_> = (1..threads).map(|_| scope.spawn(work)).collect();
            let mut all = work();
            for h in handles {
                all.extend(join(h));
            }
            all
        });
        indexed.sort_unstable_by_key(|(i, _)| *i);
        indexed.into_iter().map(|(_, f)| f).collect()
    };
    let mut shares = vec![share; tasks.len()];
    let all: Vec<usize> = (0..tasks.len()).collect();
    let mut results = run_tasks(&all, &shares);
    // Work is rarely spread evenly (one long branch of a model holds most
    // of the close pairs): tasks that ran out of their share run again
    // with what the others left unused. The shares depend only on what
    // the tasks found, so the answer is the same on any number of threads.
    loop {
        let spent: u64 = results
            .iter()
            .zip(&shares)
            .map(|(f, s)| s - f.budget)
            .fold(0, u64::saturating_add);
        let left = limits.max_tests.saturating_sub(spent);
        let again: Vec<usize> = all
            .iter()
            .copied()
            .filter(|&k| results[k].exhausted && !results[k].capped)
            .collect();
        if again.is_empty() || left < again.len() as u64 {
            break;
        }
        let extra = left / again.len() as u64;
        for &k in &again {
            shares[k] = shares[k].saturating_add(extra);
        }
        for (k, found) in again.iter().zip(run_tasks(&again, &shares)) {
            results[*k] = found;
        }
    }
    let mut single = 0u64;
    let mut complete = true;
    let mut shared: FxHashSet<(Element, Element)> = FxHashSet::default();
    let mut pairs: Vec<(Element, Element)> = Vec::new();
    for found in results {
        single += found.single;
        complete &= !found.exhausted;
        shared.extend(found.shared);
        pairs.extend(found.smallest);
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs.truncate(limits.keep);
    PairSearch {
        count: single + shared.len() as u64,
        pairs,
        complete,
    }
}

/// Tasks the descent is cut into (whatever the thread count): enough that
/// a thread finishing early finds more work.
const TASKS: usize = 128;

// ---- the narrow phase ----

impl Soup {
    /// [`super::primitives_intersect`] of flats `i` and `j` at the sum of
    /// their thicknesses, with the common triangle cases settled first.
    #[inline]
    fn intersect(&self, i: usize, j: usize) -> bool {
        let (a, b) = (&self.flats[i], &self.flats[j]);
        let thickness = self.thickness(i) + self.thickness(j);
        let exact = thickness.is_nan() || thickness <= 0.0;
        if exact
            && a.len == 3
            && b.len == 3
            && triangles_miss(&self.points, &self.fans, a, self.ids(i), b, self.ids(j))
        {
            return false;
        }
        primitives_intersect(&self.prim(i), &self.prim(j), thickness)
    }
}

/// A certified "no" for two triangles `a`, `b` (corner ids `ids_a`,
/// `ids_b`) under exact contact (thickness 0): `true` only if
/// [`super::primitives_intersect`] is `false`; `false` means "undecided".
///
/// Shared corners are found as `primitives_intersect` pairs them when that
/// is plain (no unknown ids, no id twice); anything else is left undecided.
/// Then, with the certified tests of [`super::quick_miss`] (any certified
/// side test is exact in sign, whatever the floating-point plane or normal,
/// so corner order does not matter):
///
/// - none: one triangle strictly beside the other's plane, or
///   `split` across a plane between them;
/// - one, `v`: `v`'s fan certified embedded ([`certified_fans`]);
///   `split` through `v`; both far parts strictly beside the
///   other's plane (the opening tests of both `separated` calls); or a
///   plane through an edge of one triangle at `v`, about perpendicular to
///   it (`separated`'s edge planes), with that triangle's third corner
///   strictly on one side and both far corners of the other strictly on
///   the other. That plane holds `v` and the edge's other end exactly (the
///   plane of three floating-point points, tested by the certified
///   [`Plane::side`]), so one triangle lies in its closed half-space and
///   the other, but for `v`, in the open opposite one: they meet only at
///   `v` (their corners at `v` must be the same point, which is checked).
///   The first triangle is then not degenerate (its third corner is off
///   the line of the edge) and `v` is a proper corner of it, so `v` lies
///   on neither far part and the exact shared-vertex test agrees;
/// - two along a mesh edge of both: the fan of either end certified (the
///   two are consecutive sectors there, meeting in the edge alone, and
///   not folded onto each other), or the other's apex strictly beside the
///   first's plane (the planes are not the same, so they meet only in the
///   edge's line).
#[inline(always)]
fn triangles_miss(
    points: &[DVec3],
    fans: &[bool],
    a: &Flat,
    ids_a: [u32; 3],
    b: &Flat,
    ids_b: [u32; 3],
) -> bool {
    // Corners are read straight from `points` by index, never through
    // arrays of points indexed at run time (those go through the stack).
    let p = |k: u32| points[k as usize];
    if ids_a.contains(&NO_VERT) {
        return false;
    }
    let mut mask = 0u32;
    for (i, va) in ids_a.into_iter().enumerate() {
        for (j, vb) in ids_b.into_iter().enumerate() {
            mask |= u32::from(va == vb) << (3 * i + j);
        }
    }
    // The number of shared corners (no `count_ones`: without a `popcnt`
    // target feature it is a bit-twiddling loop).
    let count = if mask == 0 {
        0
    } else if mask & (mask - 1) == 0 {
        1
    } else if (mask & (mask - 1)) & ((mask & (mask - 1)) - 1) == 0 {
        2
    } else {
        3
    };
    match count {
        0 => {
            let (a0, a1, a2) = (p(a.pt[0]), p(a.pt[1]), p(a.pt[2]));
            let (b0, b1, b2) = (p(b.pt[0]), p(b.pt[1]), p(b.pt[2]));
            let (plane_a, plane_b) = (Plane::new([a0, a1, a2]), Plane::new([b0, b1, b2]));
            beside3(a0, a1, a2, &plane_b)
                || beside3(b0, b1, b2, &plane_a)
                || split3(a0, a1, a2, b0, b1, b2)
        }
        1 => {
            let bit = mask.trailing_zeros() as usize;
            let (i, j) = (bit / 3, bit % 3);
            if fans.get(ids_a[i] as usize) == Some(&true) {
                return true;
            }
            let (va, a1, a2) = (p(a.pt[i]), p(a.pt[(i + 1) % 3]), p(a.pt[(i + 2) % 3]));
            let (vb, b1, b2) = (p(b.pt[j]), p(b.pt[(j + 1) % 3]), p(b.pt[(j + 2) % 3]));
            if split2(va, a1, a2, b1, b2) {
                return true;
            }
            let (plane_a, plane_b) = (Plane::new([va, a1, a2]), Plane::new([vb, b1, b2]));
            (beside2(b1, b2, &plane_a) && beside2(a1, a2, &plane_b))
                || (va == vb
                    && (beyond_edge_at(va, [a1, a2], &plane_a, &[b1, b2])
                        || beyond_edge_at(vb, [b1, b2], &plane_b, &[a1, a2])))
        }
        2 => {
            let (first, second) = (mask.trailing_zeros(), 31 - mask.leading_zeros());
            let ((i0, j0), (i1, j1)) = (
                (first as usize / 3, first as usize % 3),
                (second as usize / 3, second as usize % 3),
            );
            if i0 == i1 || j0 == j1 {
                // An id twice in one triangle: leave it to the reference.
                return false;
            }
            let certified = |v: u32| fans.get(v as usize) == Some(&true);
            is_boundary(a.boundary, i0, i1)
                && is_boundary(b.boundary, j0, j1)
                && (certified(ids_a[i0])
                    || certified(ids_a[i1])
                    || Plane::new([p(a.pt[0]), p(a.pt[1]), p(a.pt[2])]).side(p(b.pt[3 - j0 - j1]))
                        != 0.0)
        }
        _ => false,
    }
}

/// `Primitive::is_boundary` for a triangle's corners `i != j`.
#[inline(always)]
fn is_boundary(bits: u8, i: usize, j: usize) -> bool {
    let edge = if (i + 1) % 3 == j { i } else { j };
    bits & (1 << edge) != 0
}

/// Both strictly on the same side of the plane (certified).
#[inline(always)]
fn beside2(p: DVec3, q: DVec3, plane: &Plane) -> bool {
    let (s, t) = (plane.side(p), plane.side(q));
    (s > 0.0 && t > 0.0) || (s < 0.0 && t < 0.0)
}

/// All three strictly on the same side of the plane (certified).
#[inline(always)]
fn beside3(p: DVec3, q: DVec3, r: DVec3, plane: &Plane) -> bool {
    let (s, t, u) = (plane.side(p), plane.side(q), plane.side(r));
    (s > 0.0 && t > 0.0 && u > 0.0) || (s < 0.0 && t < 0.0 && u < 0.0)
}

/// The certified sign of `m · (x − c)` for fixed floating-point `m` and
/// `c` (`super::split`'s test: one rounded difference and a three-term dot
/// product err by less than `4u Σ|mₖ rₖ|`, u = 2⁻⁵³, so `8u` certifies);
/// 0 when too close to tell.
#[inline(always)]
fn side_of(m: DVec3, c: DVec3, x: DVec3) -> f64 {
    const BOUND: f64 = 4.0 * f64::EPSILON;
    let r = x - c;
    let d = m.dot(r);
    if d.abs() > BOUND * m.abs().dot(r.abs()) {
        d
    } else {
        0.0
    }
}

/// `super::split` through the shared corner `v`: the far corners `a1, a2`
/// of one triangle strictly on the negative side, `b1, b2` of the other on
/// the positive side, of the plane through `v` along the difference of
/// their centres.
#[inline(always)]
fn split2(v: DVec3, a1: DVec3, a2: DVec3, b1: DVec3, b2: DVec3) -> bool {
    let m = (b1 + b2) / 2.0 - (a1 + a2) / 2.0;
    if !(m.is_finite() && v.is_finite()) {
        return false;
    }
    side_of(m, v, a1) < 0.0
        && side_of(m, v, a2) < 0.0
        && side_of(m, v, b1) > 0.0
        && side_of(m, v, b2) > 0.0
}

/// `super::split` for triangles sharing no corner: the plane midway
/// between their centres, across the difference of the centres.
#[inline(always)]
fn split3(a0: DVec3, a1: DVec3, a2: DVec3, b0: DVec3, b1: DVec3, b2: DVec3) -> bool {
    let (ca, cb) = ((a0 + a1 + a2) / 3.0, (b0 + b1 + b2) / 3.0);
    let m = cb - ca;
    let c = (ca + cb) * 0.5;
    if !(m.is_finite() && c.is_finite()) {
        return false;
    }
    side_of(m, c, a0) < 0.0
        && side_of(m, c, a1) < 0.0
        && side_of(m, c, a2) < 0.0
        && side_of(m, c, b0) > 0.0
        && side_of(m, c, b1) > 0.0
        && side_of(m, c, b2) > 0.0
}

/// For a triangle with corner `v`, the two others `ends` and plane
/// `plane`: is there an edge from `v` to one of `ends` whose plane about
/// perpendicular to the triangle (built as `super::separated` builds it)
/// has the triangle's third corner strictly on one side and both of `far`
/// strictly on the other?
#[inline(never)]
fn beyond_edge_at(v: DVec3, ends: [DVec3; 2], plane: &Plane, far: &[DVec3; 2]) -> bool {
    let n = plane.normal();
    // Any positive scale gives the same plane in exact terms; this one (in
    // 1-norms, no square roots) makes the third point about as far from
    // `v` as the edge is long, so that it does not round onto the edge.
    let length = n.abs().element_sum();
    [(ends[0], ends[1]), (ends[1], ends[0])]
        .into_iter()
        .any(|(end, third)| {
            let scale = (end - v).abs().element_sum() / length;
            if !scale.is_finite() {
                return false;
            }
            let edge_plane = Plane::new([v, end, v + n * scale]);
            let inside = edge_plane.side(third);
            inside != 0.0
                && far.iter().all(|&q| {
                    let side = edge_plane.side(q);
                    side != 0.0 && (side > 0.0) != (inside > 0.0)
                })
        })
}

// ---- certified vertex fans ----

/// Per vertex id (an index into `points`), whether its *fan* (every
/// triangle of `flats` with it as a corner) is certified embedded: any two
/// of its triangles that share no other corner meet in that vertex alone,
/// and two that share a second corner `w` meet in the segment `v w` alone,
/// from opposite sides. Nine in ten candidate pairs of a smooth surface
/// are such neighbours, and one certificate per vertex (O(valence)
/// filtered orientation tests) settles them all.
///
/// The certificate for vertex `v` at `p`, with its triangles rotated to
/// `(v, aₖ, bₖ)` in corner order, and two floating-point points `q` and
/// `r` (any points: they only fix a projection and a reference ray):
///
/// 1. Every triangle holds `v` once, and the `aₖ` are distinct and are
///    exactly the `bₖ`: the link of `v` is a union of cycles.
/// 2. `s(aₖ, bₖ)` has one sign σ for all k, where
///    `s(x, y) = orient3d(x, y, q, p)` (certified by the floating-point
///    filter): projected along `q − p`, each triangle is a proper sector at
///    `p` turning the same way, of angle in (0, π).
/// 3. `s(w, r) ≠ 0` for every neighbour `w` (certified), so the ray from
///    `p` towards `r` lies on no sector's side, and exactly one k has
///    `σ·s(aₖ, r) > 0` and `σ·s(bₖ, r) < 0`: one sector holds the ray.
///
/// Walking a cycle of the link turns by whole turns, at least one, and a
/// ray on no side is inside as many sectors as the turns; so (3) leaves one
/// cycle turning once. Its sectors tile the plane around `p`. Two that are
/// not consecutive share no corner besides `v` (a neighbour `w` is the
/// start of one sector and the end of one, which are consecutive), and
/// their closed sectors meet only in `p`: projections of the triangles
/// then meet only in `p`, which only `v` projects to, so the triangles
/// meet only in `v`, not on the far edge of either (each is proper), and
/// [`super::primitives_intersect`] says no. Two consecutive ones share
/// the ray towards `w` and lie on its two sides; only the segment `v w`
/// of either projects onto the ray, so they meet in it alone, not folded
/// onto each other, and `primitives_intersect` says no when `v w` is a
/// mesh edge of both (which the caller checks). Anything less certain (open
/// fans, folds, pinched or degenerate fans, non-finite corners, three
/// triangles or fewer) leaves the vertex uncertified, and its pairs go to
/// the other tests.
fn certified_fans(points: &[DVec3], flats: &[Flat], threads: usize) -> Vec<bool> {
    // The triangles at each vertex, as offsets into one array.
    let mut start = vec![0u32; points.len() + 1];
    for f in flats.iter().filter(|f| f.len == 3) {
        for &p in &f.pt {
            start[p as usize + 1] += 1;
        }
    }
    for k in 1..start.len() {
        start[k] += start[k - 1];
    }
    let mut fan = vec![0u32; start[points.len()] as usize];
    let mut fill = start.clone();
    for (k, f) in flats.iter().enumerate().filter(|(_, f)| f.len == 3) {
        for &p in &f.pt {
            fan[fill[p as usize] as usize] = k as u32;
            fill[p as usize] += 1;
        }
    }
    let certify = |range: std::ops::Range<usize>| {
        let mut sectors = Vec::new();
        range
            .map(|v| {
                let triangles = &fan[start[v] as usize..start[v + 1] as usize];
                fan_is_embedded(points, flats, v as u32, triangles, &mut sectors)
            })
            .collect::<Vec<bool>>()
    };
    let n = points.len();
    if threads <= 1 || n < PARALLEL_FACES {
        return certify(0..n);
    }
    let share = n.div_ceil(threads);
    std::thread::scope(|scope| {
        let handles: Vec<_> = (share..n)
            .step_by(share)
            .map(|lo| scope.spawn(move || certify(lo..n.min(lo + share))))
            .collect();
        let mut fans = certify(0..share);
        for handle in handles {
            fans.extend(join(handle));
        }
        fans
    })
}

/// One triangle `(v, a, b)` of a fan, as [`fan_is_embedded`] keeps it.
#[derive(Clone, Copy, Debug)]
struct Sector {
    a: u32,
    b: u32,
    /// `s(a, r) > 0`.
    a_before_ray: bool,
}

/// Fans up to this size are checked to be cycles by comparing every pair
/// of sectors (no sort); larger ones (the poles of a UV sphere) are sorted.
const SMALL_FAN: usize = 32;

/// The certificate of [`certified_fans`] for vertex `v` and its triangles;
/// `sectors` is a buffer reused from vertex to vertex.
fn fan_is_embedded(
    points: &[DVec3],
    flats: &[Flat],
    v: u32,
    triangles: &[u32],
    sectors: &mut Vec<Sector>,
) -> bool {
    if triangles.len() < 4 {
        return false;
    }
    // The corners after `v` in a triangle holding it once.
    let rotate = |k: u32| {
        let pt = flats[k as usize].pt;
        let at = pt.iter().position(|&c| c == v)?;
        let (a, b) = (pt[(at + 1) % 3], pt[(at + 2) % 3]);
        (a != v && b != v).then_some((a, b))
    };
    let p = points[v as usize];
    let Some((a0, b0)) = rotate(triangles[0]) else {
        return false;
    };
    // The first triangle's normal, scaled to about its edges' length (a
    // tiny or huge offset would round `q − p` badly), and a ray between
    // its two edges, off their bisector (which points straight away from
    // a neighbour in a regular fan of odd valence): choices that make the
    // tests decisive, not sound.
    let (x, y) = (points[a0 as usize] - p, points[b0 as usize] - p);
    let normal = x.cross(y);
    let q = p + normal * ((x.abs() + y.abs()).element_sum() / normal.abs().element_sum());
    let r = p + x + y * 1.618_033_988_749_895;
    if !(q.is_finite() && r.is_finite()) {
        return false;
    }
    // `s(·, ·)` from rounded differences, as `orient3d_filtered` takes them.
    let (qd, rd) = (q - p, r - p);
    sectors.clear();
    let mut sigma: Option<bool> = None;
    for &k in triangles {
        let Some((a, b)) = rotate(k) else {
            return false;
        };
        let (ad, bd) = (points[a as usize] - p, points[b as usize] - p);
        let (Some(sector), Some(ray)) = (
            orient3d_filtered_at(ad, bd, qd),
            orient3d_filtered_at(ad, rd, qd),
        ) else {
            return false;
        };
        if *sigma.get_or_insert(sector > 0.0) != (sector > 0.0) {
            return false;
        }
        sectors.push(Sector {
            a,
            b,
            a_before_ray: ray > 0.0,
        });
    }
    let sigma = sigma == Some(true);
    // Per sector, the sector starting where it ends; `None` unless the
    // starts are distinct and are exactly the ends.
    let holds_ray =
        |s: &Sector, next: &Sector| s.a_before_ray == sigma && next.a_before_ray != sigma;
    let mut holding = 0;
    if sectors.len() <= SMALL_FAN {
        let mut taken = 0u32;
        for s in sectors.iter() {
            let mut found = None;
            for (j, t) in sectors.iter().enumerate() {
                if t.a == s.b {
                    if found.is_some() {
                        return false;
                    }
                    found = Some(j);
                }
            }
            let Some(j) = found else { return false };
            if taken & (1 << j) != 0 {
                return false;
            }
            taken |= 1 << j;
            holding += usize::from(holds_ray(s, &sectors[j]));
        }
    } else {
        sectors.sort_unstable_by_key(|s| s.a);
        if sectors.windows(2).any(|w| w[0].a == w[1].a) {
            return false;
        }
        let mut ends: Vec<u32> = sectors.iter().map(|s| s.b).collect();
        ends.sort_unstable();
        if sectors.iter().map(|s| s.a).ne(ends.iter().copied()) {
            return false;
        }
        for s in sectors.iter() {
            let next = &sectors[sectors.partition_point(|t| t.a < s.b)];
            holding += usize::from(holds_ray(s, next));
        }
    }
    holding == 1
}
