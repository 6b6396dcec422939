//! MakeTriangleGrid: a bulk Euler operator that writes a triangulated grid
//! of new vertices in closed form (issue 38: "bulk builders that write
//! records in closed form").
//!
//! A face-by-face build ([`super::build::KernelBuilder`]) searches a disk
//! cycle for every side and threads every new edge and loop into its cycles
//! one at a time: pointer chasing, in sequence. On a grid every id and every
//! cycle is known beforehand, so each record is a function of its own index
//! and all of them are written in parallel. The result is the face-by-face
//! build's, element for element (the same ids, the same cycle orders, the
//! same normals), which the tests compare field by field.
//!
//! The grid: vertex (i, j) is `i·nv + j`, for i < nu and j < nv; cell
//! (i, j), for i < nu − 1 and j < nv − 1 in that order (i outer), is split
//! into the triangles (a, b, c) and (a, c, d) with a = (i, j),
//! b = (i + 1, j), c = (i + 1, j + 1), d = (i, j + 1): what a uniform
//! tessellation without seams or poles emits.

use glam::DVec3;
use rayon::prelude::*;

use super::ids::{EdgeId, FaceId, LoopId, VertId};
use super::mesh::{normal_of, DiskLink, Edge, Face, Loop, Mesh, Occupied, Vert};
use super::ops::Selection;

/// Slot counts of a grid's elements, with the first slot of each arena.
#[derive(Clone, Copy)]
struct Grid {
    nv: usize,
    cu: usize,
    cv: usize,
    vert0: u32,
    edge0: u32,
    loop0: u32,
    face0: u32,
}

/// Which side of a cell an edge is: the u edge from (i, j) to (i + 1, j),
/// the v edge from (i, j) to (i, j + 1), or the cell's diagonal.
#[derive(Clone, Copy)]
enum Side {
    U,
    V,
    Diagonal,
}

impl Grid {
    fn vert(&self, i: usize, j: usize) -> VertId {
        VertId::from_raw(self.vert0 + (i * self.nv + j) as u32)
    }

    fn cell(&self, i: usize, j: usize) -> usize {
        i * self.cv + j
    }

    /// Edges made before cell (i, j). Cell (i, j) makes, in order: U(i, 0)
    /// when j = 0 (its first side, a→b), V(i + 1, j) (b→c), the diagonal
    /// (c→a), U(i, j + 1) (c→d of the second triangle), and V(0, j) when
    /// i = 0 (d→a); every other side was made by an earlier cell.
    fn edges_before(&self, i: usize, j: usize) -> usize {
        let first_row = self.cv; // row 0 also makes the V(0, j) column
        let rows = i * (3 * self.cv + 1) + if i > 0 { first_row } else { 0 };
        rows + 3 * j + usize::from(j > 0) + if i == 0 { j } else { 0 }
    }

    /// The local id of an edge, by the cell and side that made it.
    fn edge_local(&self, side: Side, i: usize, j: usize) -> usize {
        match side {
            Side::U if j == 0 => self.edges_before(i, 0),
            Side::U => self.edges_before(i, j - 1) + usize::from(j == 1) + 2,
            Side::V if i == 0 => self.edges_before(0, j) + usize::from(j == 0) + 3,
            Side::V => self.edges_before(i - 1, j) + usize::from(j == 0),
            Side::Diagonal => self.edges_before(i, j) + usize::from(j == 0) + 1,
        }
    }

    fn edge(&self, side: Side, i: usize, j: usize) -> EdgeId {
        EdgeId::from_raw(self.edge0 + self.edge_local(side, i, j) as u32)
    }

    fn loop_id(&self, local: usize) -> LoopId {
        LoopId::from_raw(self.loop0 + local as u32)
    }

    fn edge_count(&self) -> usize {
        self.edges_before(self.cu, 0)
    }

    /// Which side, at which cell, local edge `e` is (the inverse of
    /// [`Grid::edge_local`]).
    fn edge_at(&self, e: usize) -> (Side, usize, usize) {
        // The row: the last one whose first edge is at or before e.
        let (mut lo, mut hi) = (0, self.cu - 1);
        while lo < hi {
            let mid = (lo + hi).div_ceil(2);
            if self.edges_before(mid, 0) <= e {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        let i = lo;
        let per_cell = 3 + usize::from(i == 0);
        let mut at = e - self.edges_before(i, 0);
        if at == 0 {
            return (Side::U, i, 0);
        }
        at -= 1;
        let (j, k) = (at / per_cell, at % per_cell);
        match k {
            0 => (Side::V, i + 1, j),
            1 => (Side::Diagonal, i, j),
            2 => (Side::U, i, j + 1),
            _ => (Side::V, 0, j),
        }
    }

    /// The edge's ends as the face-by-face build made it (`make_face`'s
    /// side v→w becomes an edge from v to w), and its loops in the order
    /// they were made (local loop ids: triangle t of cell c has loops
    /// 6c + 3t + k, side k).
    fn edge_shape(
        &self,
        side: Side,
        i: usize,
        j: usize,
    ) -> ([(usize, usize); 2], [Option<usize>; 2]) {
        let cell_loop = |ci: usize, cj: usize, k: usize| 6 * self.cell(ci, cj) + k;
        match side {
            // U(i, j): side c→d of cell (i, j − 1)'s second triangle, then
            // side a→b of cell (i, j)'s first.
            Side::U => {
                let ends = if j == 0 {
                    [(i, 0), (i + 1, 0)]
                } else {
                    [(i + 1, j), (i, j)]
                };
                let below = (j > 0).then(|| cell_loop(i, j - 1, 4));
                let above = (j < self.cv).then(|| cell_loop(i, j, 0));
                (ends, first_two(below, above))
            }
            // V(i, j): side b→c of cell (i − 1, j)'s first triangle, then
            // side d→a of cell (i, j)'s second.
            Side::V => {
                let ends = if i == 0 {
                    [(0, j + 1), (0, j)]
                } else {
                    [(i, j), (i, j + 1)]
                };
                let left = (i > 0).then(|| cell_loop(i - 1, j, 1));
                let right = (i < self.cu).then(|| cell_loop(i, j, 5));
                (ends, first_two(left, right))
            }
            // Side c→a of the first triangle, then a→c of the second.
            Side::Diagonal => (
                [(i + 1, j + 1), (i, j)],
                [Some(cell_loop(i, j, 2)), Some(cell_loop(i, j, 3))],
            ),
        }
    }

    /// The edges around vertex (i, j) in the order they were made: its
    /// disk cycle, from the vertex's first edge.
    fn disk(&self, i: usize, j: usize) -> ([EdgeId; 6], usize) {
        if (1..self.cu).contains(&i) && (1..self.cv).contains(&j) {
            // Inside, in closed form: cell (i − 1, j − 1) made V(i, j − 1),
            // its diagonal and U(i − 1, j); cell (i − 1, j) made V(i, j);
            // cell (i, j − 1) made U(i, j); cell (i, j) its diagonal.
            let around = [
                self.edge(Side::V, i, j - 1),
                self.edge(Side::Diagonal, i - 1, j - 1),
                self.edge(Side::U, i - 1, j),
                self.edge(Side::V, i, j),
                self.edge(Side::U, i, j),
                self.edge(Side::Diagonal, i, j),
            ];
            debug_assert!(around.windows(2).all(|w| w[0] < w[1]));
            return (around, 6);
        }
        // On the border the first row's and column's edges come in their
        // own order: sort what is there.
        let mut around = [EdgeId::from_raw(0); 6];
        let mut n = 0;
        let mut add = |present: bool, side: Side, ci: usize, cj: usize| {
            if present {
                around[n] = self.edge(side, ci, cj);
                n += 1;
            }
        };
        let (inner_u, inner_v) = (i < self.cu, j < self.cv);
        add(i > 0, Side::U, i.wrapping_sub(1), j);
        add(inner_u, Side::U, i, j);
        add(j > 0, Side::V, i, j.wrapping_sub(1));
        add(inner_v, Side::V, i, j);
        add(inner_u && inner_v, Side::Diagonal, i, j);
        add(
            i > 0 && j > 0,
            Side::Diagonal,
            i.wrapping_sub(1),
            j.wrapping_sub(1),
        );
        around[..n].sort_unstable();
        (around, n)
    }

    /// The ring of triangle t (0 or 1) of cell (i, j), as grid points.
    fn ring(i: usize, j: usize, t: usize) -> [(usize, usize); 3] {
        let (a, b, c, d) = ((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1));
        if t == 0 {
            [a, b, c]
        } else {
            [a, c, d]
        }
    }

    /// The other loop on the edge of side k of triangle t of cell (i, j),
    /// if a neighbouring triangle shares it (the mirror of
    /// [`Grid::edge_shape`]'s loop lists).
    fn radial_other(&self, i: usize, j: usize, t: usize, k: usize) -> Option<usize> {
        let at = |ci: usize, cj: usize, loop_in_cell: usize| 6 * self.cell(ci, cj) + loop_in_cell;
        match (t, k) {
            (0, 0) => (j > 0).then(|| at(i, j - 1, 4)),
            (0, 1) => (i + 1 < self.cu).then(|| at(i + 1, j, 5)),
            (0, _) => Some(at(i, j, 3)),
            (1, 0) => Some(at(i, j, 2)),
            (1, 1) => (j + 1 < self.cv).then(|| at(i, j + 1, 0)),
            _ => (i > 0).then(|| at(i - 1, j, 1)),
        }
    }

    /// The edge of side k of triangle t of cell (i, j).
    fn side_edge(&self, i: usize, j: usize, t: usize, k: usize) -> EdgeId {
        match (t, k) {
            (0, 0) => self.edge(Side::U, i, j),
            (0, 1) => self.edge(Side::V, i + 1, j),
            (1, 1) => self.edge(Side::U, i, j + 1),
            (1, 2) => self.edge(Side::V, i, j),
            _ => self.edge(Side::Diagonal, i, j),
        }
    }
}

/// Loops of an edge in order, the missing one dropped.
fn first_two(a: Option<usize>, b: Option<usize>) -> [Option<usize>; 2] {
    match a {
        Some(_) => [a, b],
        None => [b, None],
    }
}

impl Mesh {
    /// MakeTriangleGrid (see the module doc): appends `nu × nv` new
    /// vertices at `positions` (row `i` is `positions[i·nv..][..nv]`) and
    /// the two triangles of every grid cell, with ids, cycles and stored
    /// normals exactly as [`super::build::KernelBuilder`] would make them
    /// from the same vertices and triangles. Returns what was made, or
    /// `None`, having changed nothing, when ids would not come out in
    /// closed form (the mesh has freed slots to reuse, or the ids would
    /// pass `u32`), or the input is not a grid of finite points with at
    /// least one cell: the caller then builds face by face.
    pub fn append_triangle_grid<P: Copy + Into<DVec3> + Sync>(
        &mut self,
        nu: usize,
        nv: usize,
        positions: &[P],
    ) -> Option<Selection> {
        if nu < 2 || nv < 2 || nu.checked_mul(nv) != Some(positions.len()) {
            return None;
        }
        if self.verts.has_free() || self.edges.has_free() || self.loops.has_free() {
            return None;
        }
        if self.faces.has_free() || !positions.iter().all(|&p| p.into().is_finite()) {
            return None;
        }
        let (cu, cv) = (nu - 1, nv - 1);
        let cells = cu.checked_mul(cv)?;
        let grid = Grid {
            nv,
            cu,
            cv,
            vert0: u32::try_from(self.verts.capacity()).ok()?,
            edge0: u32::try_from(self.edges.capacity()).ok()?,
            loop0: u32::try_from(self.loops.capacity()).ok()?,
            face0: u32::try_from(self.faces.capacity()).ok()?,
        };
        let edge_count = grid.edge_count();
        let fits =
            |first: u32, count: usize| u64::from(first) + count as u64 <= u64::from(u32::MAX - 1);
        if !(fits(grid.vert0, positions.len())
            && fits(grid.edge0, edge_count)
            && fits(grid.loop0, 6 * cells)
            && fits(grid.face0, 2 * cells))
        {
            return None;
        }
        // New slots lie past every layer's stored prefix (the validator
        // keeps prefixes within the arenas), so they read the default
        // without the `on_new` a single make would call.
        let vert_records = (0..positions.len()).into_par_iter().map(|v| {
            let (i, j) = (v / nv, v % nv);
            Vert {
                position: positions[v].into(),
                edge: Some(grid.disk(i, j).0[0]),
                slot: Occupied::Yes,
            }
        });
        self.verts.par_extend_fresh(vert_records);
        let edge_records = (0..edge_count).into_par_iter().map(|e| {
            let (side, i, j) = grid.edge_at(e);
            let (ends, loops) = grid.edge_shape(side, i, j);
            let id = EdgeId::from_raw(grid.edge0 + e as u32);
            let link = |(vi, vj): (usize, usize)| {
                let (around, n) = grid.disk(vi, vj);
                let at = around[..n]
                    .iter()
                    .position(|&x| x == id)
                    .expect("edge in its disk");
                DiskLink {
                    prev: around[(at + n - 1) % n],
                    next: around[(at + 1) % n],
                }
            };
            Edge {
                verts: ends.map(|(vi, vj)| grid.vert(vi, vj)),
                disk: ends.map(link),
                first_loop: loops[0].map(|l| grid.loop_id(l)),
            }
        });
        self.edges.par_extend_fresh(edge_records);
        let loop_records = (0..6 * cells).into_par_iter().map(|l| {
            let (cell, t, k) = (l / 6, (l % 6) / 3, l % 3);
            let (i, j) = (cell / cv, cell % cv);
            let ring = Grid::ring(i, j, t);
            let edge = grid.side_edge(i, j, t, k);
            // The other loop of the edge (the same loop on the border): a
            // radial cycle of one or two loops.
            let other = grid.radial_other(i, j, t, k).unwrap_or(l);
            let face_first = l - k;
            Loop {
                vert: grid.vert(ring[k].0, ring[k].1),
                edge,
                face: FaceId::from_raw(grid.face0 + (l / 3) as u32),
                next: grid.loop_id(face_first + (k + 1) % 3),
                prev: grid.loop_id(face_first + (k + 2) % 3),
                radial_next: grid.loop_id(other),
                radial_prev: grid.loop_id(other),
            }
        });
        self.loops.par_extend_fresh(loop_records);
        let face_records = (0..2 * cells).into_par_iter().map(|f| {
            let (cell, t) = (f / 2, f % 2);
            let (i, j) = (cell / cv, cell % cv);
            let corners = Grid::ring(i, j, t).map(|(vi, vj)| positions[vi * nv + vj].into());
            Face {
                first_loop: grid.loop_id(3 * f),
                len: 3,
                normal: normal_of(&corners),
            }
        });
        self.faces.par_extend_fresh(face_records);
        let ids = |first: u32, count: usize| first..first + count as u32;
        Some(Selection::from_parts(
            ids(grid.vert0, positions.len())
                .map(VertId::from_raw)
                .collect(),
            ids(grid.edge0, edge_count).map(EdgeId::from_raw).collect(),
            ids(grid.face0, 2 * cells).map(FaceId::from_raw).collect(),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::sink::{Begin, MeshSink};
    use crate::kernel::build::KernelBuilder;

    fn points(nu: usize, nv: usize) -> Vec<DVec3> {
        (0..nu * nv)
            .map(|v| {
                let (i, j) = ((v / nv) as f64, (v % nv) as f64);
                DVec3::new(i * 0.7, j * 1.3, libm::sin(0.9 * i) * libm::cos(0.4 * j))
            })
            .collect()
    }

    /// The face-by-face build of the same grid.
    fn face_by_face(mesh: &mut Mesh, nu: usize, nv: usize, positions: &[DVec3]) -> Selection {
        let mut builder = KernelBuilder::new(mesh);
        builder
            .begin(&Begin {
                vertices: positions.len(),
                polygons: 2 * (nu - 1) * (nv - 1),
                ..Begin::default()
            })
            .unwrap();
        for &p in positions {
            builder.vertex(p, &[]).unwrap();
        }
        for i in 0..nu - 1 {
            for j in 0..nv - 1 {
                let a = (i * nv + j) as u32;
                let (b, d) = (a + nv as u32, a + 1);
                builder.polygon(&[a, b, b + 1]).unwrap();
                builder.polygon(&[a, b + 1, d]).unwrap();
            }
        }
        builder.end().unwrap();
        builder.finish().0
    }

    /// A mesh that already holds a quad and a wire edge.
    fn with_content() -> Mesh {
        let mut mesh = Mesh::new();
        let v: Vec<VertId> = (0..5)
            .map(|i| mesh.make_vert(DVec3::new(f64::from(i), 1.0, -2.0)))
            .collect();
        mesh.make_face(&[v[0], v[1], v[2], v[3]]).unwrap();
        mesh.make_edge(v[3], v[4]).unwrap();
        mesh
    }

    #[test]
    fn a_grid_in_closed_form_is_the_face_by_face_build() {
        for (nu, nv) in [
            (2, 2),
            (2, 3),
            (3, 2),
            (2, 7),
            (7, 2),
            (3, 3),
            (4, 6),
            (9, 5),
            (17, 23),
        ] {
            for earlier in [false, true] {
                let fresh = || if earlier { with_content() } else { Mesh::new() };
                let positions = points(nu, nv);
                let mut expected = fresh();
                let expected_made = face_by_face(&mut expected, nu, nv, &positions);
                let mut mesh = fresh();
                let made = mesh.append_triangle_grid(nu, nv, &positions).unwrap();
                mesh.validate().unwrap();
                assert_eq!(made, expected_made, "{nu} × {nv}");
                // Every record, cycle link and normal bit, and the free lists.
                assert!(
                    format!("{mesh:?}") == format!("{expected:?}"),
                    "{nu} × {nv}"
                );
            }
        }
    }

    #[test]
    fn a_grid_is_declined_where_closed_form_ids_would_be_wrong() {
        let positions = points(3, 4);
        // Freed slots would be reused first.
        let mut mesh = with_content();
        let f = mesh.face_ids().next().unwrap();
        mesh.kill_face(f).unwrap();
        let before = format!("{mesh:?}");
        assert!(mesh.append_triangle_grid(3, 4, &positions).is_none());
        assert_eq!(format!("{mesh:?}"), before);
        // Not a grid, no cell, or a point that is not finite.
        let mut mesh = Mesh::new();
        assert!(mesh.append_triangle_grid(3, 3, &positions).is_none());
        assert!(mesh.append_triangle_grid(1, 12, &positions).is_none());
        let mut bad = positions.clone();
        bad[5].z = f64::NAN;
        assert!(mesh.append_triangle_grid(3, 4, &bad).is_none());
        assert!(mesh.is_empty());
    }
}
