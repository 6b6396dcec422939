//! The `intersect` policy (thesis 003 §3.2): before a command is applied to
//! a primitive, the products it would make are tested against the model,
//! and an application whose products would intersect it is not made.
//!
//! The kernel's [`IntersectionIndex`] answers the tests (BVH broad phase,
//! exact narrow phase, contact at an attached vertex allowed). This module
//! turns a command's plan into the primitives to test: the new edges as
//! capsules as thick as their nodes, the new or reshaped faces as their
//! triangles. Primitives the application reshapes or removes (the edge a
//! `split_edge` splits, its faces, the face a `split_face` fans, the edges
//! and faces around a node `edit_node` moves) are left out of its test;
//! once it is made they leave the index and their new shapes join it, so
//! the next application of the command meets the model as it now is.

use glam::DVec3;
use rustc_hash::FxHashSet;

use super::commands::{Fan, Plan};
use super::graph::{self, RADIUS};
use crate::kernel::ids::{EdgeId, FaceId, VertId};
use crate::kernel::intersect::{Element, IntersectionIndex, WireThickness};
use crate::kernel::mesh::Mesh;
use crate::kernel::ops::Selection;
use crate::rules::program::CommandKind;

/// Wire edges are as thick as the larger radius of their two nodes.
const WIRES: WireThickness<'static> = WireThickness::VertLayer(RADIUS);

/// The intersection index a run keeps between testing commands.
#[derive(Default)]
pub struct Guard {
    index: Option<IntersectionIndex>,
    /// What the application being tested would reshape or remove.
    pending: FxHashSet<Element>,
}

impl Guard {
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets the index: a step reshaped or removed primitives it holds.
    /// The next test rebuilds it from the mesh.
    pub fn invalidate(&mut self) {
        self.index = None;
    }

    /// Adds what a command made, so later tests see it. `reshaped`: the
    /// command also changed existing primitives, so the index is rebuilt.
    pub fn record(&mut self, mesh: &Mesh, products: &Selection, reshaped: bool) {
        if reshaped {
            self.invalidate();
        } else if let Some(index) = &mut self.index {
            index.insert_products(mesh, products, WIRES);
        }
    }

    /// Whether applying `plan` of a `kind` command would make a product
    /// that intersects the model (what the application reshapes is tested
    /// in its new shape only).
    pub fn would_intersect(
        &mut self,
        mesh: &Mesh,
        kind: CommandKind,
        plan: &Plan,
        fan: Option<&Fan>,
    ) -> bool {
        let index = self
            .index
            .get_or_insert_with(|| IntersectionIndex::from_mesh(mesh, WIRES));
        let Tests {
            segments,
            faces,
            skip,
        } = tests(mesh, kind, plan, fan);
        let left_out = |e: Element| skip.contains(&e);
        let hit = segments.iter().any(|s| {
            index.segment_hits_except(s.ends[0], s.ends[1], s.thickness, &s.attached, &left_out)
        }) || faces
            .iter()
            .any(|f| index.face_hits_except(&f.ring, &f.attached, &left_out));
        self.pending = skip;
        hit
    }

    /// The application just tested was made: what it reshaped or removed
    /// leaves the index, and what it made and the new shapes of what it
    /// reshaped join it.
    pub fn accept(&mut self, mesh: &Mesh, products: &Selection) {
        let mut reshaped: Vec<Element> = self.pending.drain().collect();
        let Some(index) = &mut self.index else {
            return;
        };
        // Sorted: the trees' shape then follows the ids, not hashing.
        reshaped.sort_unstable();
        for &element in &reshaped {
            index.remove(element);
        }
        for element in reshaped {
            match element {
                Element::Face(f) if mesh.contains_face(f) && !products.faces.contains(&f) => {
                    index.insert_face(mesh, f);
                }
                Element::Edge(e)
                    if mesh.contains_edge(e)
                        && !products.edges.contains(&e)
                        && mesh.is_wire_edge(e) =>
                {
                    index.insert_edge(mesh, e, WIRES.of(mesh, e));
                }
                _ => {}
            }
        }
        index.insert_products(mesh, products, WIRES);
    }

    /// A testing command ended; if it reshaped primitives the index is
    /// rebuilt before the next test (dropping the removed primitives it
    /// still holds).
    pub fn finish_command(&mut self, reshaped: bool) {
        if reshaped {
            self.invalidate();
        }
    }
}

/// A would-be edge: its ends, its thickness, the existing nodes it joins.
struct Segment {
    ends: [DVec3; 2],
    thickness: f64,
    attached: Vec<VertId>,
}

/// A would-be face: its corners in order, the existing nodes among them.
struct Ring {
    ring: Vec<DVec3>,
    attached: Vec<VertId>,
}

struct Tests {
    segments: Vec<Segment>,
    faces: Vec<Ring>,
    /// Stored primitives the application reshapes or removes.
    skip: FxHashSet<Element>,
}

fn tests(mesh: &Mesh, kind: CommandKind, plan: &Plan, fan: Option<&Fan>) -> Tests {
    let mut t = Tests {
        segments: Vec::new(),
        faces: Vec::new(),
        skip: FxHashSet::default(),
    };
    let p = |v: VertId| mesh.position(v);
    let r = |v: VertId| graph::radius(mesh, v);
    let new_radius = |from: VertId| plan.radius().unwrap_or_else(|| r(from));
    match kind {
        CommandKind::CreateEdge => {
            let n0 = VertId::from_index(plan.target());
            t.segments.push(Segment {
                ends: [p(n0), plan.position],
                thickness: r(n0).max(new_radius(n0)),
                attached: vec![n0],
            });
        }
        CommandKind::SplitEdge => {
            let edge = EdgeId::from_index(plan.target());
            let [n0, n1] = mesh.edge_verts(edge);
            let radius = new_radius(n0);
            for n in [n0, n1] {
                t.segments.push(Segment {
                    ends: [p(n), plan.position],
                    thickness: r(n).max(radius),
                    attached: vec![n],
                });
            }
            t.skip.insert(Element::Edge(edge));
            for f in mesh.edge_faces(edge) {
                t.skip.insert(Element::Face(f));
                // The face with the new node between n0 and n1.
                let verts: Vec<VertId> = mesh.face_verts(f).collect();
                let mut ring = Vec::with_capacity(verts.len() + 1);
                for (i, &v) in verts.iter().enumerate() {
                    ring.push(p(v));
                    let next = verts[(i + 1) % verts.len()];
                    if (v == n0 && next == n1) || (v == n1 && next == n0) {
                        ring.push(plan.position);
                    }
                }
                t.faces.push(Ring {
                    ring,
                    attached: verts,
                });
            }
        }
        CommandKind::CreateFace => {
            let edge = EdgeId::from_index(plan.target());
            let [n0, n1] = mesh.edge_verts(edge);
            skip_wire(mesh, edge, &mut t.skip);
            t.faces.push(Ring {
                ring: vec![p(n0), p(n1), plan.position],
                attached: vec![n0, n1],
            });
        }
        CommandKind::SplitFace => {
            if let Some(fan) = fan {
                split_face_tests(mesh, plan, fan, &mut t);
            }
        }
        CommandKind::EditNode => {
            let v = VertId::from_index(plan.target());
            let radius = new_radius(v);
            for e in mesh.vert_edges(v) {
                t.skip.insert(Element::Edge(e));
                let [a, b] = mesh.edge_verts(e);
                let other = if a == v { b } else { a };
                if mesh.is_wire_edge(e) {
                    t.segments.push(Segment {
                        ends: [p(other), plan.position],
                        thickness: r(other).max(radius),
                        attached: vec![other],
                    });
                }
            }
            for f in mesh.vert_faces(v) {
                t.skip.insert(Element::Face(f));
                let verts: Vec<VertId> = mesh.face_verts(f).collect();
                let ring = verts
                    .iter()
                    .map(|&u| if u == v { plan.position } else { p(u) })
                    .collect();
                let attached = verts.into_iter().filter(|&u| u != v).collect();
                t.faces.push(Ring { ring, attached });
            }
        }
    }
    t
}

fn split_face_tests(mesh: &Mesh, plan: &Plan, fan: &Fan, t: &mut Tests) {
    let f = FaceId::from_index(plan.target());
    let ring: Vec<VertId> = mesh.face_verts(f).collect();
    let p = |v: VertId| mesh.position(v);
    let picked = &fan.nodes;
    match picked.len() {
        0 => {}
        1 => {
            let r = graph::radius(mesh, picked[0]);
            t.segments.push(Segment {
                ends: [p(picked[0]), plan.position],
                thickness: r.max(plan.radius().unwrap_or(r)),
                attached: vec![picked[0]],
            });
        }
        2 => {
            // A cut across the face (or nothing, for adjacent nodes); a wire
            // edge already joining the two becomes the cut.
            t.skip.insert(Element::Face(f));
            if let Some(edge) = mesh.find_edge(picked[0], picked[1]) {
                skip_wire(mesh, edge, &mut t.skip);
            }
            t.segments.push(Segment {
                ends: [p(picked[0]), p(picked[1])],
                thickness: 0.0,
                attached: picked.clone(),
            });
        }
        _ => {
            // The fan: one piece per run of the boundary between
            // consecutive picked nodes, closed by the new node.
            t.skip.insert(Element::Face(f));
            let at = |v: VertId| ring.iter().position(|&u| u == v).unwrap_or(0);
            for (k, &from) in picked.iter().enumerate() {
                let to = picked[(k + 1) % picked.len()];
                let (start, end) = (at(from), at(to));
                let mut verts = Vec::new();
                let mut i = start;
                loop {
                    verts.push(ring[i]);
                    if i == end {
                        break;
                    }
                    i = (i + 1) % ring.len();
                }
                let mut points: Vec<DVec3> = verts.iter().map(|&v| p(v)).collect();
                points.push(plan.position);
                t.faces.push(Ring {
                    ring: points,
                    attached: verts,
                });
            }
        }
    }
}

/// A wire edge that gains a face stops being a capsule: its stored one is
/// left out of the test and, once the face is made, leaves the index.
fn skip_wire(mesh: &Mesh, edge: EdgeId, skip: &mut FxHashSet<Element>) {
    if mesh.is_wire_edge(edge) {
        skip.insert(Element::Edge(edge));
    }
}
