//! Grid fill: each selected quad is replaced by an n × n grid of quads
//! whose inner vertices the caller places (a surface patch built on the
//! quad's corners). The quad's edges are split into n segments with Euler
//! `split_edge`, so faces beside it — selected or not — gain the same
//! vertices and the mesh stays conforming and closed.

use std::collections::BTreeMap;

use glam::DVec3;

use super::{OpError, Selection};
use crate::kernel::{FaceId, KernelError, Mesh, VertId};

/// Where a quad's grid goes: called with the quad's corners (in its
/// winding), unit normal and size (√area); returns the (n + 1)² grid
/// points, row-major with `i` along corner 0 → 1 and `j` along 0 → 3.
/// Only the inner points are used: the border follows the split edges.
pub type PlaceGrid<'a> = dyn FnMut([DVec3; 4], DVec3, f64) -> Vec<DVec3> + 'a;

/// Fills every quad of `faces` (others are skipped) with an `n` × `n` grid.
/// Returns what was made and how many quads were filled.
pub fn grid_fill(
    mesh: &mut Mesh,
    faces: &[FaceId],
    n: usize,
    place: &mut PlaceGrid,
) -> Result<(Selection, usize), OpError> {
    let mut made = Selection::new();
    if n < 1 {
        return Ok((made, 0));
    }
    // Chains of split vertices by original edge (lower vertex id first),
    // ordered from the lower vertex to the higher.
    let mut chains: BTreeMap<(VertId, VertId), Vec<VertId>> = BTreeMap::new();
    // Rings, frames and grids first: filling a quad splits its
    // neighbours' edges, and a selected neighbour is still a quad with
    // split sides.
    let quads: Vec<(FaceId, Vec<VertId>, Vec<DVec3>)> = faces
        .iter()
        .filter(|&&f| mesh.contains_face(f))
        .filter_map(|&f| {
            let ring: Vec<VertId> = mesh.face_verts(f).collect();
            (ring.len() == 4).then(|| {
                let corners = [0, 1, 2, 3].map(|k| mesh.position(ring[k]));
                let points = place(corners, mesh.face_normal(f), mesh.face_area(f).sqrt());
                (f, ring, points)
            })
        })
        .collect();
    let filled = quads.len();
    for (f, ring, points) in quads {
        assert_eq!(
            points.len(),
            (n + 1) * (n + 1),
            "the grid has (n + 1)² points"
        );
        // The border, side by side, each from ring[s] to ring[s + 1].
        let mut sides: [Vec<VertId>; 4] = Default::default();
        for s in 0..4 {
            let (a, b) = (ring[s], ring[(s + 1) % 4]);
            let key = (a.min(b), a.max(b));
            let chain = match chains.get(&key) {
                Some(chain) => chain.clone(),
                None => {
                    let chain = split_evenly(mesh, key.0, key.1, n, &mut made)?;
                    chains.insert(key, chain.clone());
                    chain
                }
            };
            sides[s] = if a < b {
                chain
            } else {
                chain.into_iter().rev().collect()
            };
        }
        mesh.kill_face(f)?;
        let mut grid = vec![ring[0]; (n + 1) * (n + 1)];
        let at = |i: usize, j: usize| i * (n + 1) + j;
        for k in 0..=n {
            grid[at(k, 0)] = sides[0][k];
            grid[at(n, k)] = sides[1][k];
            grid[at(n - k, n)] = sides[2][k];
            grid[at(0, n - k)] = sides[3][k];
        }
        for i in 1..n {
            for j in 1..n {
                let v = mesh.make_vert(points[at(i, j)]);
                made.verts.push(v);
                grid[at(i, j)] = v;
            }
        }
        for i in 0..n {
            for j in 0..n {
                let cell = [
                    grid[at(i, j)],
                    grid[at(i + 1, j)],
                    grid[at(i + 1, j + 1)],
                    grid[at(i, j + 1)],
                ];
                made.faces.push(mesh.make_face(&cell)?);
            }
        }
    }
    made.faces.sort_unstable();
    made.verts.sort_unstable();
    made.edges = made
        .faces
        .iter()
        .flat_map(|&g| mesh.face_edges(g).collect::<Vec<_>>())
        .collect();
    made.edges.sort_unstable();
    made.edges.dedup();
    Ok((made, filled))
}

/// Splits the edge a–b into `n` equal parts; the chain a, …, b.
fn split_evenly(
    mesh: &mut Mesh,
    a: VertId,
    b: VertId,
    n: usize,
    made: &mut Selection,
) -> Result<Vec<VertId>, KernelError> {
    let mut e = mesh
        .find_edge(a, b)
        .expect("a side of a live face is an edge");
    let mut chain = vec![a];
    for k in 0..n - 1 {
        // Split off 1/(remaining) from the end at the chain's last vertex.
        let [v0, _] = mesh.edge_verts(e);
        let remaining = (n - k) as f64;
        let t = if v0 == *chain.last().expect("starts with a") {
            1.0 / remaining
        } else {
            1.0 - 1.0 / remaining
        };
        let (w, new) = mesh.split_edge(e, t)?;
        made.verts.push(w);
        chain.push(w);
        // The piece that still reaches b.
        e = if mesh.edge_verts(new).contains(&b) {
            new
        } else {
            e
        };
    }
    chain.push(b);
    Ok(chain)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::ops::create::create_cube;

    /// Bilinear grids (a flat fill) with the inner points pushed by `lift`.
    fn flat(lift: f64, n: usize) -> impl FnMut([DVec3; 4], DVec3, f64) -> Vec<DVec3> {
        move |c, normal, size| {
            let mut out = Vec::new();
            for i in 0..=n {
                for j in 0..=n {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    let inner = i > 0 && i < n && j > 0 && j < n;
                    out.push(
                        c[0] * ((1.0 - u) * (1.0 - v))
                            + c[1] * (u * (1.0 - v))
                            + c[2] * (u * v)
                            + c[3] * ((1.0 - u) * v)
                            + if inner {
                                normal * lift * size
                            } else {
                                DVec3::ZERO
                            },
                    );
                }
            }
            out
        }
    }

    #[test]
    fn every_face_of_a_cube_filled_stays_closed_and_valid() {
        for n in [1, 2, 3, 5] {
            let mut mesh = Mesh::new();
            let cube = create_cube(&mut mesh, 2.0).unwrap();
            let (made, filled) = grid_fill(&mut mesh, &cube.faces, n, &mut flat(0.1, n)).unwrap();
            mesh.validate().unwrap();
            assert_eq!(filled, 6);
            assert_eq!(mesh.face_count(), 6 * n * n);
            assert_eq!(made.faces.len(), 6 * n * n);
            let report = mesh.report();
            assert!(report.watertight, "n = {n}");
            assert_eq!(report.euler_characteristic, 2);
        }
    }

    #[test]
    fn filling_some_faces_splits_their_neighbours_alike() {
        let mut mesh = Mesh::new();
        let cube = create_cube(&mut mesh, 2.0).unwrap();
        let one = [cube.faces[0]];
        let (_, filled) = grid_fill(&mut mesh, &one, 4, &mut flat(0.0, 4)).unwrap();
        mesh.validate().unwrap();
        assert_eq!(filled, 1);
        let report = mesh.report();
        assert!(report.watertight);
        // The four neighbours gained three vertices on their shared side.
        assert_eq!(mesh.face_count(), 5 + 16);
        let degrees: Vec<usize> = mesh
            .face_ids()
            .map(|f| mesh.face_verts(f).count())
            .collect();
        assert_eq!(
            degrees.iter().filter(|&&d| d == 7).count(),
            4,
            "{degrees:?}"
        );
    }
}
