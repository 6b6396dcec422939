//! Compound-command scopes (thesis 003 §3.3.2): the set of primitives a
//! compound's commands may see, and the reference frame and sizes their
//! parameters build on (Table 3.2).

use glam::DVec3;
use rustc_hash::FxHashSet;

use crate::kernel::ops::Selection;
use crate::kernel::{Domain, EdgeId, FaceId, Mesh, VertId};

use super::graph::{self, Frame};

/// Members of one element kind: a list for ordered iteration, a set for
/// membership (never iterated, so hash order cannot leak into results).
#[derive(Debug, Default, Clone)]
struct Members {
    list: Vec<u32>,
    set: FxHashSet<u32>,
}

impl Members {
    fn insert(&mut self, index: usize) {
        if self.set.insert(index as u32) {
            self.list.push(index as u32);
        }
    }
}

/// What relative parameters and the scope's commands measure against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reference {
    pub frame: Frame,
    pub length: f64,
    pub radius: f64,
}

impl Reference {
    /// Top level: world axes, unit length and radius.
    pub const WORLD: Reference = Reference {
        frame: Frame::WORLD,
        length: 1.0,
        radius: 1.0,
    };
}

/// Where relative conditions (`rel.x`, `rel.length`, `rel.area`) measure:
/// the initial primitive's frame, extent and size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measure {
    pub origin: DVec3,
    pub frame: Frame,
    /// Divisors for the three local coordinates.
    pub extent: DVec3,
    /// Length unit and area unit.
    pub size: f64,
    pub area: f64,
}

impl Measure {
    pub const WORLD: Measure = Measure {
        origin: DVec3::ZERO,
        frame: Frame::WORLD,
        extent: DVec3::ONE,
        size: 1.0,
        area: 1.0,
    };

    /// Measures of an initial primitive: a face spans [0, 1] in x and y
    /// over its extent along its frame (H along its longest edge, U its
    /// normal), with z in units of √area; an edge runs from 0 to 1 along x
    /// with lengths in its length; a node measures in its radius.
    pub fn of(mesh: &Mesh, domain: Domain, index: usize) -> Measure {
        let safe = |x: f64| if x > 1e-300 { x } else { 1.0 };
        match domain {
            Domain::Face => {
                let f = FaceId::from_index(index);
                let frame = graph::face_frame(mesh, f);
                let first = mesh.face_verts(f).next().expect("face has vertices");
                let p0 = mesh.position(first);
                let (lo, hi) = mesh.face_verts(f).fold(
                    (DVec3::INFINITY, DVec3::NEG_INFINITY),
                    |(lo, hi), v| {
                        let q = frame.to_local(mesh.position(v) - p0);
                        (lo.min(q), hi.max(q))
                    },
                );
                let area = mesh.face_area(f);
                let size = safe(area.sqrt());
                Measure {
                    origin: p0 + frame.h * lo.x + frame.l * lo.y,
                    frame,
                    extent: DVec3::new(safe(hi.x - lo.x), safe(hi.y - lo.y), size),
                    size,
                    area: safe(area),
                }
            }
            Domain::Edge => {
                let e = EdgeId::from_index(index);
                let length = safe(mesh.edge_length(e));
                Measure {
                    origin: mesh.position(mesh.edge_verts(e)[0]),
                    frame: graph::edge_frame(mesh, e),
                    extent: DVec3::splat(length),
                    size: length,
                    area: length * length,
                }
            }
            Domain::Vert => {
                let v = VertId::from_index(index);
                let r = safe(graph::radius(mesh, v).abs());
                Measure {
                    origin: mesh.position(v),
                    frame: graph::node_frame(mesh, v),
                    extent: DVec3::splat(r),
                    size: r,
                    area: r * r,
                }
            }
        }
    }

    /// A point in the initial primitive's relative coordinates.
    pub fn relative(&self, p: DVec3) -> DVec3 {
        self.frame.to_local(p - self.origin) / self.extent
    }
}

/// One compound application's scope: its initial primitive and
/// sub-primitives, plus everything its commands create.
#[derive(Debug, Clone)]
pub struct Scope {
    verts: Members,
    edges: Members,
    faces: Members,
    pub reference: Reference,
    pub measure: Measure,
}

impl Scope {
    /// The scope of initial primitive `index` of `domain`: a face brings its
    /// edges and nodes, an edge its two nodes.
    pub fn new(
        mesh: &Mesh,
        domain: Domain,
        index: usize,
        reference: Reference,
        measure: Measure,
    ) -> Scope {
        let mut scope = Scope {
            verts: Members::default(),
            edges: Members::default(),
            faces: Members::default(),
            reference,
            measure,
        };
        let mut initial = Selection::new();
        match domain {
            Domain::Vert => initial.verts.push(VertId::from_index(index)),
            Domain::Edge => {
                let e = EdgeId::from_index(index);
                initial.edges.push(e);
                initial.verts.extend(mesh.edge_verts(e));
            }
            Domain::Face => {
                let f = FaceId::from_index(index);
                initial.faces.push(f);
                initial.edges.extend(mesh.face_edges(f));
                initial.verts.extend(mesh.face_verts(f));
            }
        }
        scope.add(&initial);
        scope
    }

    pub fn add(&mut self, s: &Selection) {
        for v in &s.verts {
            self.verts.insert(v.index());
        }
        for e in &s.edges {
            self.edges.insert(e.index());
        }
        for f in &s.faces {
            self.faces.insert(f.index());
        }
    }

    pub fn contains(&self, domain: Domain, index: usize) -> bool {
        let members = match domain {
            Domain::Vert => &self.verts,
            Domain::Edge => &self.edges,
            Domain::Face => &self.faces,
        };
        members.set.contains(&(index as u32))
    }

    /// Members of `domain` that are still alive, ascending.
    pub fn members(&self, mesh: &Mesh, domain: Domain) -> Vec<usize> {
        let (list, alive): (&[u32], &dyn Fn(usize) -> bool) = match domain {
            Domain::Vert => (&self.verts.list, &|i| {
                mesh.contains_vert(VertId::from_index(i))
            }),
            Domain::Edge => (&self.edges.list, &|i| {
                mesh.contains_edge(EdgeId::from_index(i))
            }),
            Domain::Face => (&self.faces.list, &|i| {
                mesh.contains_face(FaceId::from_index(i))
            }),
        };
        let mut out: Vec<usize> = list
            .iter()
            .map(|&i| i as usize)
            .filter(|&i| alive(i))
            .collect();
        out.sort_unstable();
        out
    }

    /// Member counts per kind: a mark for [`Scope::added_since`].
    pub fn sizes(&self) -> [usize; 3] {
        [
            self.verts.list.len(),
            self.edges.list.len(),
            self.faces.list.len(),
        ]
    }

    /// What joined this scope since it had `sizes` members (members are
    /// only ever appended).
    pub fn added_since(&self, sizes: [usize; 3]) -> Selection {
        fn tail(now: &Members, from: usize) -> impl Iterator<Item = usize> + '_ {
            now.list[from..].iter().map(|&i| i as usize)
        }
        Selection::from_parts(
            tail(&self.verts, sizes[0])
                .map(VertId::from_index)
                .collect(),
            tail(&self.edges, sizes[1])
                .map(EdgeId::from_index)
                .collect(),
            tail(&self.faces, sizes[2])
                .map(FaceId::from_index)
                .collect(),
        )
    }
}
