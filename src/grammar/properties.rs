//! Element properties that conditions and command parameters read,
//! computed only when used. Inside a compound command, topological counts
//! see only the current scope (thesis 003 §3.3.2) and relative properties
//! measure in the scope's initial primitive.

use glam::DVec3;

use crate::kernel::{Domain, EdgeId, FaceId, Mesh, VertId};
use crate::rules::program::Property;
use crate::rules::random;

use super::graph;
use super::scope::{Measure, Scope};

/// Where properties are read: the mesh, the innermost scope (if any), and
/// the running step's random stream and generation.
pub struct Context<'a> {
    pub mesh: &'a Mesh,
    pub scope: Option<&'a Scope>,
    pub seed: u64,
    pub stream: u64,
    pub generation: u32,
}

impl Context<'_> {
    fn in_scope(&self, domain: Domain, index: usize) -> bool {
        self.scope.is_none_or(|s| s.contains(domain, index))
    }

    fn measure(&self) -> &Measure {
        self.scope.map_or(&Measure::WORLD, |s| &s.measure)
    }

    fn count_edges(&self, edges: impl Iterator<Item = EdgeId>) -> f64 {
        edges
            .filter(|e| self.in_scope(Domain::Edge, e.index()))
            .count() as f64
    }

    fn count_faces(&self, faces: impl Iterator<Item = FaceId>) -> f64 {
        faces
            .filter(|f| self.in_scope(Domain::Face, f.index()))
            .count() as f64
    }
}

fn bounds(points: impl Iterator<Item = DVec3>) -> (DVec3, DVec3) {
    points.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
        (lo.min(p), hi.max(p))
    })
}

/// Edges at `v` whose pre-node (`side` 0) or post-node (`side` 1) is `v`.
fn directed_edges(mesh: &Mesh, v: VertId, side: usize) -> impl Iterator<Item = EdgeId> + '_ {
    mesh.vert_edges(v)
        .filter(move |&e| mesh.edge_verts(e)[side] == v)
}

/// The value of `property` for element `index` of `domain`.
pub fn property(ctx: &Context, domain: Domain, index: usize, property: Property) -> f64 {
    use Property::*;
    let mesh = ctx.mesh;
    match property {
        Id => return index as f64,
        // Keyed by lineage, not id: see `lineage`.
        Random => {
            return random::unit(
                ctx.seed,
                ctx.stream,
                super::lineage::key(mesh, domain, index),
                0,
            )
        }
        Age => return graph::age(mesh, domain, index) as f64,
        Generation => return f64::from(ctx.generation),
        _ => {}
    }
    match domain {
        Domain::Vert => {
            let v = VertId::from_index(index);
            match property {
                Position(i) => mesh.position(v)[i],
                Relative(i) => ctx.measure().relative(mesh.position(v))[i],
                Normal(i) => mesh.vert_normal(v)[i],
                Degree => ctx.count_edges(mesh.vert_edges(v)),
                FaceCount => ctx.count_faces(mesh.vert_faces(v)),
                OutEdges => ctx.count_edges(directed_edges(mesh, v, 0)),
                InEdges => ctx.count_edges(directed_edges(mesh, v, 1)),
                Radius => graph::radius(mesh, v),
                PreLength => {
                    let (sum, n) = directed_edges(mesh, v, 1)
                        .fold((0.0, 0usize), |(s, n), e| (s + mesh.edge_length(e), n + 1));
                    if n == 0 {
                        0.0
                    } else {
                        sum / n as f64
                    }
                }
                _ => unreachable!("compiler admits only vertex properties"),
            }
        }
        Domain::Edge => {
            let e = EdgeId::from_index(index);
            let [a, b] = mesh.edge_verts(e);
            let (pa, pb) = (mesh.position(a), mesh.position(b));
            match property {
                Length | PreLength => pa.distance(pb),
                RelativeLength => pa.distance(pb) / ctx.measure().size,
                Center(i) => ((pa + pb) * 0.5)[i],
                Relative(i) => ctx.measure().relative((pa + pb) * 0.5)[i],
                Direction(i) => (pb - pa).try_normalize().unwrap_or(DVec3::ZERO)[i],
                PrePosition(i) => pa[i],
                PostPosition(i) => pb[i],
                Min(i) => pa.min(pb)[i],
                Max(i) => pa.max(pb)[i],
                FaceCount => ctx.count_faces(mesh.edge_faces(e)),
                OutEdges => ctx.count_edges(directed_edges(mesh, b, 0)),
                InEdges => ctx.count_edges(directed_edges(mesh, a, 1)),
                EdgeNeighborEdges => ctx.count_edges(
                    mesh.vert_edges(a)
                        .chain(mesh.vert_edges(b))
                        .filter(|&other| other != e),
                ),
                Radius => graph::mean_radius(mesh, [a, b].into_iter()),
                _ => unreachable!("compiler admits only edge properties"),
            }
        }
        Domain::Face => {
            let f = FaceId::from_index(index);
            match property {
                Center(i) => mesh.face_center(f)[i],
                Relative(i) => ctx.measure().relative(mesh.face_center(f))[i],
                Normal(i) => mesh.face_normal(f)[i],
                Area => mesh.face_area(f),
                RelativeArea => mesh.face_area(f) / ctx.measure().area,
                Sides => mesh.face_len(f) as f64,
                EdgeNeighbors => ctx.count_faces(mesh.face_edge_neighbors(f).into_iter()),
                VertNeighbors => ctx.count_faces(mesh.face_vert_neighbors(f).into_iter()),
                Min(i) => bounds(mesh.face_verts(f).map(|v| mesh.position(v))).0[i],
                Max(i) => bounds(mesh.face_verts(f).map(|v| mesh.position(v))).1[i],
                Radius => graph::mean_radius(mesh, mesh.face_verts(f)),
                _ => unreachable!("compiler admits only face properties"),
            }
        }
    }
}
