//! Whole-mesh measurements: counts, bounds, area, volume, manifoldness,
//! components and Euler characteristic. Linear in the mesh size.

use glam::DVec3;

use crate::geom::{IndexedMesh, UnionFind};

use super::ids::LoopId;
#[cfg(test)]
use super::ids::VertId;
use super::mesh::Mesh;

/// What `graftal info` and the stats report about a mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshReport {
    pub verts: usize,
    pub edges: usize,
    pub faces: usize,
    /// Triangles a triangulating writer emits (Σ corners − 2).
    pub triangles: usize,
    pub wire_edges: usize,
    /// Edges with exactly one face.
    pub boundary_edges: usize,
    /// Edges with three or more faces.
    pub non_manifold_edges: usize,
    /// Vertices whose faces do not form a single fan.
    pub non_manifold_verts: usize,
    pub isolated_verts: usize,
    /// `None` for an empty mesh.
    pub bounds: Option<(DVec3, DVec3)>,
    pub area: f64,
    /// Enclosed volume, when the surface is closed and consistently oriented.
    pub volume: Option<f64>,
    /// Every edge has one or two faces and every vertex a single fan.
    pub manifold: bool,
    /// Manifold, no boundary, no wire edges, consistently oriented.
    pub watertight: bool,
    /// Faces on every two-face edge run it in opposite directions.
    pub consistently_oriented: bool,
    /// Connected components (isolated vertices count as components).
    pub components: usize,
    /// V − E + F.
    pub euler_characteristic: i64,
}

/// Area, enclosed volume and triangle count, summed face by face in face
/// order (both reports sum in the same order, so they agree to the bit).
#[derive(Default)]
struct Surface {
    area: f64,
    signed_volume: f64,
    triangles: usize,
}

impl Surface {
    fn add(&mut self, points: &[DVec3]) {
        self.area += crate::geom::polygon::area(points);
        self.triangles += points.len() - 2;
        // Divergence theorem over a fan: exact for planar faces.
        for i in 1..points.len() - 1 {
            self.signed_volume += points[0].dot(points[i].cross(points[i + 1])) / 6.0;
        }
    }
}

/// What a report is derived from.
struct Tally {
    verts: usize,
    edges: usize,
    faces: usize,
    wire_edges: usize,
    boundary_edges: usize,
    non_manifold_edges: usize,
    non_manifold_verts: usize,
    isolated_verts: usize,
    bounds: Option<(DVec3, DVec3)>,
    surface: Surface,
    consistently_oriented: bool,
    components: usize,
}

impl Tally {
    fn report(self) -> MeshReport {
        let manifold = self.non_manifold_edges == 0 && self.non_manifold_verts == 0;
        let watertight = manifold
            && self.boundary_edges == 0
            && self.wire_edges == 0
            && self.consistently_oriented
            && self.faces > 0;
        MeshReport {
            verts: self.verts,
            edges: self.edges,
            faces: self.faces,
            triangles: self.surface.triangles,
            wire_edges: self.wire_edges,
            boundary_edges: self.boundary_edges,
            non_manifold_edges: self.non_manifold_edges,
            non_manifold_verts: self.non_manifold_verts,
            isolated_verts: self.isolated_verts,
            bounds: self.bounds,
            area: self.surface.area,
            volume: watertight.then_some(self.surface.signed_volume),
            manifold,
            watertight,
            consistently_oriented: self.consistently_oriented,
            components: self.components,
            euler_characteristic: self.verts as i64 - self.edges as i64 + self.faces as i64,
        }
    }
}

/// The smallest box holding `points` (`None` when there are none).
fn bounds_of(points: impl Iterator<Item = DVec3>) -> Option<(DVec3, DVec3)> {
    points.fold(None, |bounds, p| {
        Some(match bounds {
            None => (p, p),
            Some((lo, hi)) => (lo.min(p), hi.max(p)),
        })
    })
}

impl Mesh {
    /// Measures the whole mesh.
    pub fn report(&self) -> MeshReport {
        let mut wire_edges = 0;
        let mut boundary_edges = 0;
        let mut non_manifold_edges = 0;
        let mut consistently_oriented = true;
        let mut components = UnionFind::new(self.vert_capacity());
        for e in self.edge_ids() {
            let [a, b] = self.edge_verts(e);
            components.union(a.raw(), b.raw());
            let mut loops = self.edge_loops(e);
            match (loops.next(), loops.next(), loops.next()) {
                (None, _, _) => wire_edges += 1,
                (Some(_), None, _) => boundary_edges += 1,
                (Some(l), Some(m), None) => {
                    if self.lp(l).vert == self.lp(m).vert {
                        consistently_oriented = false;
                    }
                }
                _ => non_manifold_edges += 1,
            }
        }
        // Faces at each vertex (faces repeat no vertex: one loop each) and
        // one loop there to start the fan walk from, in one pass.
        let mut faces_at = vec![0u32; self.vert_capacity()];
        let mut loop_at: Vec<Option<LoopId>> = vec![None; self.vert_capacity()];
        for (index, l) in self.loops.iter() {
            let v = l.vert.raw() as usize;
            faces_at[v] += 1;
            loop_at[v].get_or_insert(LoopId::from_raw(index));
        }
        let mut isolated_verts = 0;
        let mut non_manifold_verts = 0;
        let bounds = bounds_of(self.vert_ids().map(|v| self.position(v)));
        for v in self.vert_ids() {
            if self.vert(v).edge.is_none() {
                isolated_verts += 1;
                continue;
            }
            let faces = faces_at[v.raw() as usize];
            if let (true, Some(start)) = (faces > 1, loop_at[v.raw() as usize]) {
                if self.fan_faces(start, faces) < faces {
                    non_manifold_verts += 1;
                }
            }
        }
        let mut surface = Surface::default();
        let mut points: Vec<DVec3> = Vec::new();
        for f in self.face_ids() {
            points.clear();
            points.extend(self.face_verts(f).map(|v| self.position(v)));
            surface.add(&points);
        }
        let components = self
            .vert_ids()
            .filter(|&v| components.find(v.raw()) == v.raw())
            .count();
        Tally {
            verts: self.vert_count(),
            edges: self.edge_count(),
            faces: self.face_count(),
            wire_edges,
            boundary_edges,
            non_manifold_edges,
            non_manifold_verts,
            isolated_verts,
            bounds,
            surface,
            consistently_oriented,
            components,
        }
        .report()
    }

    /// How many faces around `start`'s vertex `v` the fan of `start`'s
    /// face holds: faces are joined across edges at `v` that have exactly
    /// two faces, and `v` is manifold when its fan holds all its faces.
    /// Each face has two edges at `v` and each joining edge two faces, so
    /// the fan is a path or a cycle: walked both ways from `start` without
    /// allocating, in at most `faces` steps (independent of orientation).
    fn fan_faces(&self, start: LoopId, faces: u32) -> u32 {
        let v = self.lp(start).vert;
        let mut reached = 1;
        // Leave `start`'s face by its outgoing edge, then by its incoming
        // one (when the first walk did not come round).
        for leave_by_own_edge in [true, false] {
            let mut at = start;
            let mut own = leave_by_own_edge;
            while reached < faces {
                // The loop of the leaving edge in this face.
                let leaving = if own { at } else { self.lp(at).prev };
                let across = self.lp(leaving).radial_next;
                if across == leaving || self.lp(across).radial_next != leaving {
                    break; // a boundary or non-manifold edge ends the fan
                }
                // The next face's loop at `v`, and whether the walk leaves
                // that face by the loop's own edge (the one it did not
                // arrive by) or by its predecessor's.
                (at, own) = if self.lp(across).vert == v {
                    (across, false)
                } else {
                    (self.lp(across).next, true)
                };
                if at == start {
                    return reached;
                }
                reached += 1;
            }
        }
        reached
    }
}

/// A polygon side or a line, filed under its lower vertex.
#[derive(Clone, Copy)]
struct Side {
    /// The higher vertex.
    high: u32,
    /// The polygon corners at the lower and the higher vertex ([`LINE`]
    /// for a line).
    at_low: u32,
    at_high: u32,
    /// The polygon runs the side from the lower vertex to the higher.
    upward: bool,
}

const LINE: u32 = u32::MAX;

/// The report of the kernel mesh [`mesh_from_indexed`] builds from
/// `indexed`, measured in `indexed` itself, when it
/// [`builds_one_to_one`] (vertex `i` becomes vertex `i`, polygon `k` face
/// `k`; otherwise the answer means nothing). Equal to that mesh's
/// [`Mesh::report`] field for field and bit for bit: the same sums in the
/// same order, and the counts of the same edges — every distinct pair of
/// vertices a polygon side or a line joins, found by filing the sides
/// under their lower vertex (a counting sort, no hashing) — and the same
/// fans (corners joined across two-face edges, a vertex non-manifold when
/// its corners fall into more than one set). `graftal info` uses it when
/// no operator needs the kernel mesh.
///
/// [`mesh_from_indexed`]: super::build::mesh_from_indexed
/// [`builds_one_to_one`]: super::build::builds_one_to_one
pub fn report_of_indexed(indexed: &IndexedMesh) -> MeshReport {
    let verts = indexed.positions.len();
    let corners = &indexed.face_indices;
    // Each side once: from each corner to the next one of its polygon.
    let sides = || {
        indexed.face_starts.windows(2).flat_map(|w| {
            let (start, end) = (w[0], w[1]);
            (start..end).map(move |c| {
                let n = if c + 1 == end { start } else { c + 1 };
                (c, n)
            })
        })
    };
    let lines = || indexed.lines.iter().filter(|[a, b]| a != b);
    // Counting sort of sides and lines by lower vertex.
    let mut filed_end = vec![0u32; verts + 1];
    for (c, n) in sides() {
        let low = corners[c as usize].min(corners[n as usize]);
        filed_end[low as usize + 1] += 1;
    }
    for &[a, b] in lines() {
        filed_end[a.min(b) as usize + 1] += 1;
    }
    for v in 1..=verts {
        filed_end[v] += filed_end[v - 1];
    }
    let empty = Side {
        high: 0,
        at_low: LINE,
        at_high: LINE,
        upward: false,
    };
    let mut filed = vec![empty; filed_end[verts] as usize];
    let mut cursor = filed_end[..verts].to_vec();
    let mut file = |low: u32, side: Side| {
        let at = &mut cursor[low as usize];
        filed[*at as usize] = side;
        *at += 1;
    };
    for (c, n) in sides() {
        let (a, b) = (corners[c as usize], corners[n as usize]);
        let (low, side) = if a < b {
            (
                a,
                Side {
                    high: b,
                    at_low: c,
                    at_high: n,
                    upward: true,
                },
            )
        } else {
            (
                b,
                Side {
                    high: a,
                    at_low: n,
                    at_high: c,
                    upward: false,
                },
            )
        };
        file(low, side);
    }
    for &[a, b] in lines() {
        file(
            a.min(b),
            Side {
                high: a.max(b),
                ..empty
            },
        );
    }
    drop(cursor);

    let mut edges = 0;
    let mut wire_edges = 0;
    let mut boundary_edges = 0;
    let mut non_manifold_edges = 0;
    let mut consistently_oriented = true;
    let mut touched = vec![false; verts];
    let mut components = UnionFind::new(verts);
    let mut fans = UnionFind::new(corners.len());
    for low in 0..verts {
        let bucket = &mut filed[filed_end[low] as usize..filed_end[low + 1] as usize];
        // Lines sort after the sides of their edge.
        bucket.sort_unstable_by_key(|s| (s.high, s.at_low));
        for edge in bucket.chunk_by(|s, t| s.high == t.high) {
            let high = edge[0].high;
            edges += 1;
            touched[low] = true;
            touched[high as usize] = true;
            components.union(low as u32, high);
            match edge.iter().take_while(|s| s.at_low != LINE).count() {
                0 => wire_edges += 1,
                1 => boundary_edges += 1,
                2 => {
                    let (s, t) = (edge[0], edge[1]);
                    consistently_oriented &= s.upward != t.upward;
                    fans.union(s.at_low, t.at_low);
                    fans.union(s.at_high, t.at_high);
                }
                _ => non_manifold_edges += 1,
            }
        }
    }
    drop(filed);
    // A vertex's fans: the sets its corners fall into.
    let mut fans_at = vec![0u8; verts];
    for c in 0..corners.len() as u32 {
        if fans.find(c) == c {
            let at = &mut fans_at[corners[c as usize] as usize];
            *at = at.saturating_add(1);
        }
    }
    let non_manifold_verts = fans_at.iter().filter(|&&n| n > 1).count();
    let isolated_verts = touched.iter().filter(|&&t| !t).count();

    let mut surface = Surface::default();
    let mut points: Vec<DVec3> = Vec::new();
    for polygon in indexed.polygons() {
        points.clear();
        points.extend(polygon.iter().map(|&i| indexed.position(i)));
        surface.add(&points);
    }
    Tally {
        verts,
        edges,
        faces: indexed.polygon_count(),
        wire_edges,
        boundary_edges,
        non_manifold_edges,
        non_manifold_verts,
        isolated_verts,
        bounds: bounds_of(indexed.positions.iter().map(|&p| DVec3::from_array(p))),
        surface,
        consistently_oriented,
        components: (0..verts as u32)
            .filter(|&v| components.find(v) == v)
            .count(),
    }
    .report()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::build::{builds_one_to_one, mesh_from_indexed};
    use crate::kernel::ops::create;
    use proptest::prelude::*;

    /// The unit cube centred on the origin.
    fn cube() -> Mesh {
        let mut m = Mesh::new();
        crate::kernel::ops::create::create_cube(&mut m, 1.0).unwrap();
        m
    }

    #[test]
    fn unit_cube_is_watertight_with_volume_one() {
        let r = cube().report();
        assert_eq!((r.verts, r.edges, r.faces, r.triangles), (8, 12, 6, 12));
        assert!(r.manifold && r.watertight && r.consistently_oriented);
        assert!((r.volume.unwrap() - 1.0).abs() < 1e-12, "{:?}", r.volume);
        assert_eq!(r.area, 6.0);
        assert_eq!(r.euler_characteristic, 2);
        assert_eq!(r.components, 1);
        assert_eq!(r.bounds, Some((DVec3::splat(-0.5), DVec3::splat(0.5))));
    }

    #[test]
    fn open_and_non_manifold_shapes_are_reported() {
        let mut m = cube();
        let f = m.face_ids().next().unwrap();
        m.kill_face(f).unwrap();
        let r = m.report();
        assert_eq!(r.boundary_edges, 4);
        assert!(!r.watertight);
        assert_eq!(r.volume, None);
        // Two cubes touching at one vertex: a non-manifold vertex.
        let mut a = cube();
        let b = cube();
        let map = a.join_mesh(&b);
        let ids: Vec<VertId> = map.verts.iter().flatten().copied().collect();
        let corner_b = *ids
            .iter()
            .find(|&&v| a.position(v) == DVec3::splat(-0.5))
            .unwrap();
        for &v in &ids {
            let p = a.position(v);
            a.place(v, p + DVec3::ONE);
        }
        let corner_a = a
            .vert_ids()
            .find(|&v| a.position(v) == DVec3::splat(0.5) && !ids.contains(&v))
            .unwrap();
        a.glue_verts(corner_a, corner_b).unwrap();
        a.validate().unwrap();
        let r = a.report();
        assert_eq!(r.non_manifold_verts, 1);
        assert!(!r.manifold);
        assert_eq!(r.components, 1);
        let mut w = Mesh::new();
        let p = w.make_vert(DVec3::ZERO);
        w.make_edge_vert(p, DVec3::X).unwrap();
        w.make_vert(DVec3::Y);
        let r = w.report();
        assert_eq!((r.wire_edges, r.isolated_verts, r.components), (1, 1, 2));
    }

    /// Fan count by brute force: union faces around `v` across edges at
    /// `v` with exactly two faces.
    fn fans_by_union_find(m: &Mesh, v: VertId) -> usize {
        let faces: Vec<_> = m.vert_faces(v).collect();
        let mut groups = UnionFind::new(faces.len());
        for e in m.vert_edges(v) {
            let around: Vec<_> = m.edge_faces(e).collect();
            if let [a, b] = around[..] {
                let index = |f| faces.iter().position(|&g| g == f).unwrap() as u32;
                groups.union(index(a), index(b));
            }
        }
        (0..faces.len() as u32)
            .filter(|&i| groups.find(i) == i)
            .count()
    }

    #[test]
    fn fan_walk_agrees_with_union_find_on_fans_of_every_shape() {
        // Triangles around a hub: every subset of 8 wedges (open and closed
        // fans, several fans, one wedge flipped so orientation is mixed).
        for mask in 1u32..256 {
            for flipped in [None, Some(mask.trailing_zeros())] {
                let mut m = Mesh::new();
                let hub = m.make_vert(DVec3::ZERO);
                let rim: Vec<_> = (0..8)
                    .map(|k| {
                        let a = k as f64 * std::f64::consts::FRAC_PI_4;
                        m.make_vert(DVec3::new(libm::cos(a), libm::sin(a), 0.0))
                    })
                    .collect();
                for k in 0..8u32 {
                    if mask & (1 << k) != 0 {
                        let (b, c) = (rim[k as usize], rim[(k as usize + 1) % 8]);
                        let ring = if flipped == Some(k) {
                            [hub, c, b]
                        } else {
                            [hub, b, c]
                        };
                        m.make_face(&ring).unwrap();
                    }
                }
                m.validate().unwrap();
                let fans = fans_by_union_find(&m, hub);
                let r = m.report();
                assert_eq!(
                    r.non_manifold_verts,
                    usize::from(fans > 1),
                    "mask {mask:08b} {flipped:?}"
                );
                // A flipped wedge is inconsistent only beside a neighbour.
                let alone =
                    |k: u32| mask & (1 << ((k + 1) % 8)) == 0 && mask & (1 << ((k + 7) % 8)) == 0;
                assert_eq!(r.consistently_oriented, flipped.is_none_or(alone));
            }
        }
    }

    /// The report of the indexed mesh against the report of the kernel
    /// mesh it builds: every field, floats to the bit.
    fn assert_reports_agree(indexed: &IndexedMesh) {
        assert!(builds_one_to_one(indexed));
        let (built, _) = mesh_from_indexed(indexed).unwrap();
        let (ours, theirs) = (report_of_indexed(indexed), built.report());
        assert_eq!(ours, theirs);
        assert_eq!(ours.area.to_bits(), theirs.area.to_bits());
        let bits = |v: Option<f64>| v.map(f64::to_bits);
        assert_eq!(bits(ours.volume), bits(theirs.volume));
    }

    /// Closed, open, non-manifold and wire shapes from the kernel's own
    /// makers, edited the ways broken files are: faces dropped, flipped
    /// or repeated, lines added along faces and apart, vertices left out.
    fn shapes() -> Vec<IndexedMesh> {
        let mut out = Vec::new();
        let mut make = |f: &dyn Fn(&mut Mesh)| {
            let mut m = Mesh::new();
            f(&mut m);
            out.push(m.to_indexed());
        };
        make(&|m| drop(create::create_cube(m, 1.0)));
        make(&|m| drop(create::create_uv_sphere(m, 12, 7, 1.0)));
        make(&|m| drop(create::create_grid(m, 5, 4, 1.0, 1.0)));
        make(&|m| drop(create::create_cylinder(m, 9, 1.0, 0.5, 2.0, false)));
        make(&|m| {
            // Two cubes sharing a corner vertex, and a lone vertex.
            let _ = create::create_cube(m, 1.0);
            let b = create::create_cube(m, 1.0).unwrap();
            for v in b.verts {
                let p = m.position(v);
                m.place(v, p + DVec3::ONE);
            }
            m.make_vert(DVec3::splat(9.0));
        });
        let mut cubes = out[4].clone();
        let corner = |m: &IndexedMesh, p: [f64; 3], from: usize| {
            (from..m.positions.len())
                .find(|&i| m.positions[i] == p)
                .unwrap() as u32
        };
        let (a, b) = (corner(&cubes, [0.5; 3], 0), corner(&cubes, [0.5; 3], 8));
        for i in &mut cubes.face_indices {
            if *i == b {
                *i = a;
            }
        }
        out.push(cubes);
        out
    }

    #[test]
    fn indexed_report_equals_the_report_of_the_built_mesh_on_whole_shapes() {
        let shapes = shapes();
        for shape in &shapes {
            assert_reports_agree(shape);
        }
        // The glued cubes: one non-manifold vertex, one component.
        let glued = report_of_indexed(&shapes[5]);
        assert_eq!((glued.non_manifold_verts, glued.isolated_verts), (1, 2));
        assert!(report_of_indexed(&shapes[0]).watertight);
    }

    fn edited_shape() -> impl Strategy<Value = IndexedMesh> {
        (
            0..6usize,
            proptest::collection::vec((0..6u8, any::<u32>()), 0..12),
            proptest::collection::vec((any::<u32>(), any::<u32>()), 0..6),
        )
            .prop_map(|(which, edits, lines)| {
                let shape = shapes().swap_remove(which);
                let mut polygons: Vec<Vec<u32>> = shape.polygons().map(<[u32]>::to_vec).collect();
                for (kind, pick) in edits {
                    if polygons.is_empty() {
                        break;
                    }
                    let k = pick as usize % polygons.len();
                    match kind {
                        0 => drop(polygons.remove(k)),
                        1 => polygons[k].reverse(),
                        2 => polygons.push(polygons[k].clone()),
                        3 => {
                            let mut flipped = polygons[k].clone();
                            flipped.reverse();
                            polygons.push(flipped);
                        }
                        4 => polygons[k].rotate_left(pick as usize % 3 + 1),
                        _ => {
                            // A triangle across three of the mesh's vertices.
                            let n = shape.positions.len() as u32;
                            let ring = [pick % n, (pick / 7 + 1) % n, (pick / 49 + 2) % n];
                            if ring[0] != ring[1] && ring[1] != ring[2] && ring[0] != ring[2] {
                                polygons.push(ring.to_vec());
                            }
                        }
                    }
                }
                let mut m = IndexedMesh::new();
                m.positions = shape.positions.clone();
                for polygon in &polygons {
                    m.push_polygon(polygon);
                }
                let n = m.positions.len() as u32;
                m.lines = lines.iter().map(|&(a, b)| [a % n, b % n]).collect();
                // Lines along a polygon side too.
                if let (Some(p), Some(&(a, _))) = (polygons.first(), lines.first()) {
                    let i = a as usize % p.len();
                    m.lines.push([p[i], p[(i + 1) % p.len()]]);
                }
                m
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn indexed_report_equals_the_report_of_the_built_mesh(m in edited_shape()) {
            assert_reports_agree(&m);
        }
    }
}
