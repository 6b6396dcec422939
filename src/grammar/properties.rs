//! Element properties that conditions read, computed only when used.

use glam::DVec3;

use crate::kernel::{Domain, EdgeId, FaceId, Mesh, VertId};
use crate::rules::program::Property;
use crate::rules::random;

/// Average of the unit normals of the faces around `v`, normalized
/// (zero when it has no faces or they cancel).
pub fn vertex_normal(mesh: &Mesh, v: VertId) -> DVec3 {
    let sum: DVec3 = mesh.vert_faces(v).map(|f| mesh.face_normal(f)).sum();
    sum.try_normalize().unwrap_or(DVec3::ZERO)
}

fn bounds(points: impl Iterator<Item = DVec3>) -> (DVec3, DVec3) {
    points.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
        (lo.min(p), hi.max(p))
    })
}

/// The value of `property` for element `index` of `domain`.
pub fn property(
    mesh: &Mesh,
    domain: Domain,
    index: usize,
    property: Property,
    seed: u64,
    stream: u64,
) -> f64 {
    use Property::*;
    match property {
        Id => return index as f64,
        Random => return random::unit(seed, stream, index as u64, 0),
        _ => {}
    }
    match domain {
        Domain::Vert => {
            let v = VertId::from_index(index);
            match property {
                Position(i) => mesh.position(v)[i],
                Normal(i) => vertex_normal(mesh, v)[i],
                Degree => mesh.vert_degree(v) as f64,
                FaceCount => mesh.vert_faces(v).count() as f64,
                _ => unreachable!("compiler admits only vertex properties"),
            }
        }
        Domain::Edge => {
            let e = EdgeId::from_index(index);
            let [a, b] = mesh.edge_verts(e);
            let (pa, pb) = (mesh.position(a), mesh.position(b));
            match property {
                Length => pa.distance(pb),
                Center(i) => ((pa + pb) * 0.5)[i],
                Direction(i) => (pb - pa).try_normalize().unwrap_or(DVec3::ZERO)[i],
                Min(i) => pa.min(pb)[i],
                Max(i) => pa.max(pb)[i],
                FaceCount => mesh.edge_face_count(e) as f64,
                _ => unreachable!("compiler admits only edge properties"),
            }
        }
        Domain::Face => {
            let f = FaceId::from_index(index);
            match property {
                Center(i) => mesh.face_center(f)[i],
                Normal(i) => mesh.face_normal(f)[i],
                Area => mesh.face_area(f),
                Sides => mesh.face_len(f) as f64,
                EdgeNeighbors => mesh.face_edge_neighbors(f).len() as f64,
                VertNeighbors => mesh.face_vert_neighbors(f).len() as f64,
                Min(i) => bounds(mesh.face_verts(f).map(|v| mesh.position(v))).0[i],
                Max(i) => bounds(mesh.face_verts(f).map(|v| mesh.position(v))).1[i],
                _ => unreachable!("compiler admits only face properties"),
            }
        }
    }
}
