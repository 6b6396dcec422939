//! Welding clustered vertices: the topology rewrite through Euler
//! operators (faces that shrink, repeat a vertex or coincide are repaired).

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use super::*;

/// Faces per parallel task in the weld's read-only passes.
const PARALLEL_CHUNK: usize = 1024;

/// A degenerate face, recorded before it is killed.
pub(super) struct Degenerate {
    /// Its ring mapped to survivors (may repeat vertices).
    ring: Vec<VertId>,
    /// Its value in each face layer, in layer order.
    attrs: Vec<AttrValue>,
}

/// Glues `verts[i]` onto `verts[targets[i]]` wherever they differ (each
/// target is its own target) and rewrites the faces around them.
pub(super) fn weld(
    mesh: &mut Mesh,
    verts: &[VertId],
    targets: &[u32],
) -> Result<MergeResult, OpError> {
    let mut gone: Vec<(VertId, VertId)> = Vec::new();
    let mut survivors = Vec::new();
    for (i, &t) in targets.iter().enumerate() {
        if t as usize == i {
            survivors.push(verts[i]);
        } else {
            gone.push((verts[i], verts[t as usize]));
        }
    }
    weld_gone(mesh, gone, survivors)
}

/// Glues each `(vertex, survivor)` of `gone` (ascending by vertex; no
/// survivor is itself glued) and repairs the faces, steps 1–4 of the module
/// overview. `survivors` is reported back as given.
pub(in crate::kernel::ops) fn weld_gone(
    mesh: &mut Mesh,
    gone: Vec<(VertId, VertId)>,
    survivors: Vec<VertId>,
) -> Result<MergeResult, OpError> {
    let mut result = MergeResult {
        merged: gone.len(),
        survivors,
        faces_removed: 0,
        remade: Vec::new(),
    };
    if gone.is_empty() {
        return Ok(result);
    }
    let affected = faces_around(mesh, &gone);

    let face_layers: Vec<String> = mesh
        .attributes()
        .layers()
        .iter()
        .filter(|l| l.domain == Domain::Face)
        .map(|l| l.name.clone())
        .collect();
    let mut clean = Vec::with_capacity(affected.len());
    let mut degenerate = Vec::new();
    if !affected.is_empty() {
        let map = SurvivorMap::new(mesh.vert_capacity(), &gone);
        // Each face's fate is a pure function of its ring: decided in
        // parallel, gathered in `affected` order.
        let view: &Mesh = mesh;
        let repeats: Vec<bool> = affected
            .par_iter()
            .with_min_len(PARALLEL_CHUNK)
            .map_init(Vec::new, |sorted, &f| {
                sorted.clear();
                sorted.extend(view.face_verts(f).map(|v| map.get(v)));
                sorted.sort_unstable();
                sorted.windows(2).any(|w| w[0] == w[1])
            })
            .collect();
        for (&f, repeats) in affected.iter().zip(repeats) {
            if repeats {
                let attrs = face_layers
                    .iter()
                    .filter_map(|name| mesh.attr(name, Domain::Face, f.index()))
                    .collect();
                let ring = mesh.face_verts(f).map(|v| map.get(v)).collect();
                degenerate.push(Degenerate { ring, attrs });
            } else {
                clean.push(f);
            }
        }
    }
    // Step 1: no face may hold two vertices of one cluster when gluing.
    // `clean` is the ascending subsequence of `affected` that stays.
    let mut kept = clean.iter().peekable();
    for &f in &affected {
        if kept.next_if_eq(&&f).is_none() {
            mesh.kill_face(f)?;
        }
    }
    // Step 2: glue (never refused: see the module overview). An isolated
    // vertex carries nothing to glue: killing it is the same, and cheaper.
    for &(v, keep) in &gone {
        if mesh.vert_edges(v).next().is_none() {
            mesh.kill_vert(v)?;
        } else {
            mesh.glue_verts_sharing_no_face(keep, v)?;
        }
    }
    // Each surviving face that lost a corner to a glue, refreshed once.
    mesh.refresh_normals_of(&clean);
    // Step 3: welded twins.
    // Killing a face only takes twins away, so a face with no twin on the
    // glued mesh has none when its turn comes: the search runs in
    // parallel on the glued mesh, and only the faces it finds are asked
    // again, ascending, as they are killed (a twin found then may have
    // been killed as a twin of another face, so the answer can change).
    let is_affected = |g: FaceId| affected.binary_search(&g).is_ok();
    let has_twin = |mesh: &Mesh, ring: &mut Vec<VertId>, f: FaceId| {
        ring.clear();
        ring.extend(mesh.face_verts(f));
        // The face's first side is the edge from ring[0] to ring[1]: read
        // from its first loop, not searched for in the disk cycles.
        let first = mesh.face_loops(f).next().expect("a face has corners");
        let side = mesh.loop_edge(first);
        twin_on(mesh, side, ring, |g| g != f && (!is_affected(g) || g < f)).is_some()
    };
    let view: &Mesh = mesh;
    let maybe_doubled: Vec<FaceId> = clean
        .par_iter()
        .with_min_len(PARALLEL_CHUNK)
        .map_init(Vec::new, |ring, &f| has_twin(view, ring, f).then_some(f))
        .flatten_iter()
        .collect();
    let mut ring: Vec<VertId> = Vec::new();
    for f in maybe_doubled {
        if has_twin(mesh, &mut ring, f) {
            mesh.kill_face(f)?;
            result.faces_removed += 1;
        }
    }
    // Step 4: remake the pieces of degenerate faces.
    for face in degenerate {
        let mut made_any = false;
        for piece in simple_cycles(face.ring) {
            if twin(mesh, &piece, |_| true).is_some() {
                continue;
            }
            let f = mesh.make_face(&piece)?;
            for (name, &value) in face_layers.iter().zip(&face.attrs) {
                mesh.set_attr(name, Domain::Face, f.index(), value);
            }
            result.remade.push(f);
            made_any = true;
        }
        if !made_any {
            result.faces_removed += 1;
        }
    }
    result.remade.sort_unstable();
    Ok(result)
}

/// Merged vertex → survivor. A dense table by slot when the merge touches a
/// good share of the mesh (no hashing), a hash map when it is a few
/// vertices of a large mesh (no table the size of the mesh).
pub(super) enum SurvivorMap {
    Dense(Vec<u32>),
    Sparse(FxHashMap<VertId, VertId>),
}

impl SurvivorMap {
    const NONE: u32 = u32::MAX;

    fn new(capacity: usize, gone: &[(VertId, VertId)]) -> Self {
        if capacity <= 8 * gone.len() {
            let mut table = vec![Self::NONE; capacity];
            for &(v, keep) in gone {
                table[v.index()] = keep.index() as u32;
            }
            SurvivorMap::Dense(table)
        } else {
            SurvivorMap::Sparse(gone.iter().copied().collect())
        }
    }

    /// The survivor of `v`, or `v` itself if it is not merged away.
    fn get(&self, v: VertId) -> VertId {
        match self {
            SurvivorMap::Dense(table) => match table[v.index()] {
                Self::NONE => v,
                keep => VertId::from_index(keep as usize),
            },
            SurvivorMap::Sparse(map) => map.get(&v).copied().unwrap_or(v),
        }
    }
}

/// A face other than those `accept` refuses, with the same vertex set as
/// `ring` (the test of [`Mesh::find_face`], with a filter). `ring` holds
/// no vertex twice, nor does a face: equal lengths and every corner of the
/// candidate in `ring` make the sets equal. Small rings compare pairwise,
/// without allocating (the weld asks this of every face it kept).
pub(super) fn twin(
    mesh: &Mesh,
    ring: &[VertId],
    accept: impl Fn(FaceId) -> bool,
) -> Option<FaceId> {
    twin_on(mesh, mesh.find_edge(ring[0], ring[1])?, ring, accept)
}

/// [`twin`] given `e`, the edge from `ring[0]` to `ring[1]`.
fn twin_on(
    mesh: &Mesh,
    e: EdgeId,
    ring: &[VertId],
    accept: impl Fn(FaceId) -> bool,
) -> Option<FaceId> {
    const PAIRWISE: usize = 8;
    let sorted = (ring.len() > PAIRWISE).then(|| {
        let mut key = ring.to_vec();
        key.sort_unstable();
        key
    });
    mesh.edge_faces(e).find(|&g| {
        if !accept(g) || mesh.face_len(g) != ring.len() {
            return false;
        }
        match &sorted {
            None => mesh.face_verts(g).all(|v| ring.contains(&v)),
            Some(key) => mesh.face_verts(g).all(|v| key.binary_search(&v).is_ok()),
        }
    })
}

/// Splits a closed walk of vertices into simple cycles of three or more
/// vertices, keeping its winding: consecutive repeats (also around the
/// end) vanish; whenever a vertex comes back, the loop since its last visit
/// is cut off. A ring of fewer than three distinct vertices gives nothing.
pub(super) fn simple_cycles(mut ring: Vec<VertId>) -> Vec<Vec<VertId>> {
    ring.dedup();
    while ring.len() > 1 && ring.first() == ring.last() {
        ring.pop();
    }
    let mut out = Vec::new();
    let mut path: Vec<VertId> = Vec::with_capacity(ring.len());
    let mut at: FxHashMap<VertId, usize> = FxHashMap::default();
    for v in ring {
        if let Some(&i) = at.get(&v) {
            let mut cycle = vec![v];
            for w in path.drain(i + 1..) {
                at.remove(&w);
                cycle.push(w);
            }
            if cycle.len() >= 3 {
                out.push(cycle);
            }
        } else {
            at.insert(v, path.len());
            path.push(v);
        }
    }
    if path.len() >= 3 {
        out.push(path);
    }
    out
}

/// The faces around the glued vertices, ascending, each once. A large weld
/// marks them in a slot-indexed table and scans it (linear); a small one
/// sorts what it found.
fn faces_around(mesh: &Mesh, gone: &[(VertId, VertId)]) -> Vec<FaceId> {
    let capacity = mesh.face_capacity();
    if gone.len().saturating_mul(16) < capacity {
        let mut found: Vec<FaceId> = gone.iter().flat_map(|&(v, _)| mesh.vert_faces(v)).collect();
        found.sort_unstable();
        found.dedup();
        return found;
    }
    // Marked in parallel: the marks are a set, whatever order they land in.
    let marked: Vec<AtomicBool> = (0..capacity).map(|_| AtomicBool::new(false)).collect();
    gone.par_iter()
        .with_min_len(PARALLEL_CHUNK)
        .for_each(|&(v, _)| {
            for f in mesh.vert_faces(v) {
                marked[f.index()].store(true, Ordering::Relaxed);
            }
        });
    marked
        .iter()
        .enumerate()
        .filter(|(_, m)| m.load(Ordering::Relaxed))
        .map(|(i, _)| FaceId::from_index(i))
        .collect()
}
