//! The structural validator: checks every kernel invariant and reports the
//! first violation with the element ids involved.
//!
//! Invariants:
//! - every id stored anywhere refers to a live element;
//! - disk cycles: each edge is linked into the disk cycle of both its ends,
//!   `next(prev(e)) == e` both ways, every edge in a vertex's cycle has the
//!   vertex as an end, and the cycle of each vertex holds exactly its edges;
//! - edges: two distinct ends, at most one edge per vertex pair;
//! - radial cycles: consistent both ways, each loop's edge is the edge,
//!   each loop starts at one of the edge's ends, and every loop is in the
//!   radial cycle of its edge;
//! - faces: one boundary cycle of `len >= 3` loops, consistent both ways,
//!   each loop's face is the face, loop `i`'s edge joins its vertex to loop
//!   `i+1`'s, no vertex repeats, and the stored normal is the one its
//!   corners give now (bit for bit);
//! - free slots hold no element; attribute layers cover every slot.
//!
//! Walks are bounded by element counts, so a corrupt cycle cannot hang it.

use rustc_hash::FxHashSet;
use thiserror::Error;

use super::ids::{Domain, EdgeId, FaceId, LoopId, VertId};
use super::mesh::Mesh;

/// The first invariant violation found.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("invalid mesh: {0}")]
pub struct ValidationError(pub String);

macro_rules! ensure {
    ($cond:expr, $($fmt:tt)+) => {
        if !$cond {
            return Err(ValidationError(format!($($fmt)+)));
        }
    };
}

fn bits(v: glam::DVec3) -> [u64; 3] {
    v.to_array().map(f64::to_bits)
}

impl Mesh {
    /// Checks every structural invariant. Cost: linear in the mesh size.
    pub fn validate(&self) -> Result<(), ValidationError> {
        self.validate_free_slots()?;
        self.validate_edges()?;
        self.validate_disks()?;
        self.validate_radials()?;
        self.validate_faces()?;
        self.validate_layers()
    }

    fn validate_free_slots(&self) -> Result<(), ValidationError> {
        for i in self.verts.free_slots() {
            ensure!(
                !self.verts.contains(i),
                "free vertex slot {i} holds a vertex"
            );
        }
        for i in self.edges.free_slots() {
            ensure!(!self.edges.contains(i), "free edge slot {i} holds an edge");
        }
        for i in self.loops.free_slots() {
            ensure!(!self.loops.contains(i), "free loop slot {i} holds a loop");
        }
        for i in self.faces.free_slots() {
            ensure!(!self.faces.contains(i), "free face slot {i} holds a face");
        }
        Ok(())
    }

    fn validate_edges(&self) -> Result<(), ValidationError> {
        let mut pairs = FxHashSet::default();
        for (i, edge) in self.edges.iter() {
            let e = EdgeId::from_raw(i);
            let [a, b] = edge.verts;
            ensure!(self.contains_vert(a), "{e} refers to dead vertex {a}");
            ensure!(self.contains_vert(b), "{e} refers to dead vertex {b}");
            ensure!(a != b, "{e} is a self-loop on {a}");
            ensure!(
                pairs.insert((a.min(b), a.max(b))),
                "more than one edge joins {a} and {b} (one is {e})"
            );
            for link in edge.disk {
                ensure!(
                    self.contains_edge(link.prev),
                    "{e} disk link to dead {}",
                    link.prev
                );
                ensure!(
                    self.contains_edge(link.next),
                    "{e} disk link to dead {}",
                    link.next
                );
            }
            if let Some(l) = edge.first_loop {
                ensure!(self.loops.contains(l.raw()), "{e} refers to dead loop {l}");
            }
        }
        Ok(())
    }

    fn validate_disks(&self) -> Result<(), ValidationError> {
        let mut walked = 0usize;
        for (i, vert) in self.verts.iter() {
            let v = VertId::from_raw(i);
            ensure!(vert.position.is_finite(), "{v} has a non-finite position");
            let Some(start) = vert.edge else { continue };
            ensure!(self.contains_edge(start), "{v} refers to dead edge {start}");
            let mut e = start;
            let mut steps = 0usize;
            loop {
                let edge = self.edge(e);
                ensure!(
                    edge.verts.contains(&v),
                    "{e} is in the disk cycle of {v} but does not end there"
                );
                let link = edge.disk[edge.side(v)];
                let next = self.edge(link.next);
                ensure!(
                    next.verts.contains(&v) && next.disk[next.side(v)].prev == e,
                    "disk cycle of {v}: next of {e} is {} whose prev is not {e}",
                    link.next
                );
                steps += 1;
                ensure!(
                    steps <= self.edge_count(),
                    "disk cycle of {v} does not close"
                );
                e = link.next;
                if e == start {
                    break;
                }
            }
            walked += steps;
        }
        // Each edge is in exactly two disk cycles; with consistent links the
        // walks above cover 2·edges entries exactly when none is missed.
        ensure!(
            walked == 2 * self.edge_count(),
            "disk cycles hold {walked} edge ends, expected {}",
            2 * self.edge_count()
        );
        Ok(())
    }

    fn validate_radials(&self) -> Result<(), ValidationError> {
        let mut walked = 0usize;
        for (i, edge) in self.edges.iter() {
            let e = EdgeId::from_raw(i);
            let Some(start) = edge.first_loop else {
                continue;
            };
            let mut l = start;
            let mut steps = 0usize;
            loop {
                let lp = self.lp(l);
                ensure!(
                    lp.edge == e,
                    "{l} is in the radial cycle of {e} but uses {}",
                    lp.edge
                );
                ensure!(
                    edge.verts.contains(&lp.vert),
                    "{l} on {e} starts at {} which is not an end",
                    lp.vert
                );
                ensure!(
                    self.loops.contains(lp.radial_next.raw()),
                    "{l} radial link to dead {}",
                    lp.radial_next
                );
                ensure!(
                    self.lp(lp.radial_next).radial_prev == l,
                    "radial cycle of {e}: next of {l} does not point back"
                );
                steps += 1;
                ensure!(
                    steps <= self.loop_count(),
                    "radial cycle of {e} does not close"
                );
                l = lp.radial_next;
                if l == start {
                    break;
                }
            }
            walked += steps;
        }
        ensure!(
            walked == self.loop_count(),
            "radial cycles hold {walked} loops, but there are {}",
            self.loop_count()
        );
        Ok(())
    }

    fn validate_faces(&self) -> Result<(), ValidationError> {
        let mut walked = 0usize;
        let mut seen: Vec<VertId> = Vec::new();
        for (i, face) in self.faces.iter() {
            let f = FaceId::from_raw(i);
            ensure!(face.len >= 3, "{f} has {} corners", face.len);
            ensure!(
                self.loops.contains(face.first_loop.raw()),
                "{f} refers to dead loop {}",
                face.first_loop
            );
            seen.clear();
            let mut l = face.first_loop;
            for _ in 0..face.len {
                let lp = self.lp(l);
                ensure!(
                    lp.face == f,
                    "{l} is in the boundary of {f} but names {}",
                    lp.face
                );
                ensure!(
                    self.contains_vert(lp.vert),
                    "{l} refers to dead vertex {}",
                    lp.vert
                );
                ensure!(
                    self.contains_edge(lp.edge),
                    "{l} refers to dead edge {}",
                    lp.edge
                );
                ensure!(
                    self.loops.contains(lp.next.raw()),
                    "{l} links to dead loop {}",
                    lp.next
                );
                let next = self.lp(lp.next);
                ensure!(
                    next.prev == l,
                    "boundary of {f}: next of {l} does not point back"
                );
                let ends = self.edge(lp.edge).verts;
                ensure!(
                    ends.contains(&lp.vert) && ends.contains(&next.vert),
                    "{l} of {f} runs {} -> {} along {} which joins {} and {}",
                    lp.vert,
                    next.vert,
                    lp.edge,
                    ends[0],
                    ends[1]
                );
                seen.push(lp.vert);
                l = lp.next;
            }
            ensure!(
                l == face.first_loop,
                "boundary of {f} does not close after {} loops",
                face.len
            );
            // Stored normals are fresh by construction: every operator that
            // moves a corner or reshapes a face refreshes them, so readers
            // (writers, extrusion, the intersection tests) never recompute.
            let fresh = self.compute_face_normal(f);
            ensure!(
                bits(face.normal) == bits(fresh),
                "{f}'s stored normal {} is stale (its corners give {})",
                face.normal,
                fresh
            );
            seen.sort_unstable();
            if let Some(w) = seen.windows(2).find(|w| w[0] == w[1]) {
                return Err(ValidationError(format!("{f} uses vertex {} twice", w[0])));
            }
            walked += face.len as usize;
        }
        ensure!(
            walked == self.loop_count(),
            "face boundaries hold {walked} loops, but there are {}",
            self.loop_count()
        );
        for (i, lp) in self.loops.iter() {
            ensure!(
                self.contains_face(lp.face),
                "{} belongs to dead face {}",
                LoopId::from_raw(i),
                lp.face
            );
        }
        Ok(())
    }

    fn validate_layers(&self) -> Result<(), ValidationError> {
        // A layer stores a prefix of its slots (the rest read the default);
        // it never holds values for slots the arena does not have.
        for layer in self.attributes.layers() {
            let slots = match layer.domain {
                Domain::Vert => self.vert_capacity(),
                Domain::Edge => self.edge_capacity(),
                Domain::Face => self.face_capacity(),
            };
            ensure!(
                layer.len() <= slots,
                "{} layer `{}` has {} values for {slots} slots",
                layer.domain,
                layer.name,
                layer.len()
            );
        }
        Ok(())
    }
}
