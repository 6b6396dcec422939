//! Tests of merging and mirroring.

use super::*;
use crate::kernel::ids::EdgeId;
use crate::kernel::ops::create::tests::{euler_characteristic, is_closed_manifold, signed_volume};
use crate::kernel::ops::create::{create_cube, create_cylinder, create_grid};
use crate::kernel::ops::delete::{delete, DeleteMode};
use crate::kernel::ops::select::select_from_faces;
use crate::kernel::ops::transform::translate;
use crate::kernel::KernelError;

fn v3(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

fn all_verts(m: &Mesh) -> Vec<VertId> {
    m.vert_ids().collect()
}

fn merge_all(m: &mut Mesh, distance: f64) -> Result<MergeResult, OpError> {
    let verts = all_verts(m);
    merge_by_distance(m, &verts, distance)
}

/// An n × n grid of unit squares as a soup: two triangles a square, each
/// with three vertices of its own (6n² corners on (n + 1)² sites).
fn triangle_soup(n: i32) -> Mesh {
    let mut m = Mesh::new();
    for j in 0..n {
        for i in 0..n {
            let p = |di: i32, dj: i32| v3(f64::from(i + di), f64::from(j + dj), 0.0);
            for tri in [[p(0, 0), p(1, 0), p(1, 1)], [p(0, 0), p(1, 1), p(0, 1)]] {
                let vs: Vec<VertId> = tri.iter().map(|&q| m.make_vert(q)).collect();
                m.make_face(&vs).unwrap();
            }
        }
    }
    m
}

type Fingerprint = (
    Vec<(VertId, [f64; 3])>,
    Vec<(EdgeId, [VertId; 2])>,
    Vec<(FaceId, Vec<VertId>)>,
);

/// Every element with its id, position or vertices: equal fingerprints
/// mean identical meshes.
fn fingerprint(m: &Mesh) -> Fingerprint {
    (
        m.vert_ids()
            .map(|v| (v, m.position(v).to_array()))
            .collect(),
        m.edge_ids().map(|e| (e, m.edge_verts(e))).collect(),
        m.face_ids()
            .map(|f| (f, m.face_verts(f).collect()))
            .collect(),
    )
}

/// SplitMix64: a tiny portable generator for test data.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Two 2-unit cubes side by side, touching along x = 1.
fn two_cubes() -> Mesh {
    let mut m = Mesh::new();
    create_cube(&mut m, 2.0).unwrap();
    let b = create_cube(&mut m, 2.0).unwrap();
    translate(&mut m, &b.verts, v3(2.0, 0.0, 0.0)).unwrap();
    m
}

#[test]
fn two_cubes_sharing_a_face_weld_into_twelve_verts() {
    let mut m = two_cubes();
    let r = merge_all(&mut m, 1e-6).unwrap();
    m.validate().unwrap();
    assert_eq!(r.merged, 4);
    assert_eq!(r.survivors.len(), 12);
    // The coincident faces became twins: one stays, inside the block.
    assert_eq!(r.faces_removed, 1);
    assert_eq!(
        (m.vert_count(), m.edge_count(), m.face_count()),
        (12, 20, 11)
    );
    let inner = m.edge_ids().filter(|&e| m.edge_face_count(e) == 3).count();
    assert_eq!(inner, 4);
    // Survivors are the first cube's vertices, unmoved.
    assert!(r.survivors[..8].iter().all(|v| v.index() < 8));
}

#[test]
fn two_open_boxes_weld_into_one_closed_box() {
    let mut m = two_cubes();
    // Remove the touching faces (+X of the first, −X of the second).
    let touching: Vec<FaceId> = m
        .face_ids()
        .filter(|&f| (m.face_center(f).x - 1.0).abs() < 1e-12)
        .collect();
    assert_eq!(touching.len(), 2);
    delete(
        &mut m,
        &Selection::from_parts(vec![], vec![], touching),
        DeleteMode::Faces,
    )
    .unwrap();
    let r = merge_all(&mut m, 1e-6).unwrap();
    m.validate().unwrap();
    assert_eq!((r.merged, r.faces_removed), (4, 0));
    assert_eq!(
        (m.vert_count(), m.edge_count(), m.face_count()),
        (12, 20, 10)
    );
    assert!(is_closed_manifold(&m));
    assert_eq!(euler_characteristic(&m), 2);
    assert!((signed_volume(&m) - 16.0).abs() < 1e-12);
}

#[test]
fn permuted_inputs_give_identical_meshes() {
    let build = || {
        let mut m = two_cubes();
        // Add near-coincident noise so clusters are not trivial.
        let extra = create_cube(&mut m, 2.0).unwrap();
        translate(&mut m, &extra.verts, v3(1e-4, -1e-4, 2.0)).unwrap();
        m
    };
    let mut a = build();
    let mut b = build();
    let mut order = all_verts(&b);
    order.reverse();
    order.rotate_left(5);
    order.push(order[3]);
    let ra = merge_all(&mut a, 1e-3).unwrap();
    let rb = merge_by_distance(&mut b, &order, 1e-3).unwrap();
    a.validate().unwrap();
    assert_eq!(ra, rb);
    assert_eq!(fingerprint(&a), fingerprint(&b));
    assert!(ra.merged >= 8);
}

#[test]
fn chains_within_distance_merge_transitively_onto_the_lowest_id() {
    let mut m = Mesh::new();
    // Lowest id in the middle of the chain; each link 0.9 apart.
    let mid = m.make_vert(v3(0.9, 0.0, 0.0));
    let left = m.make_vert(v3(0.0, 0.0, 0.0));
    let right = m.make_vert(v3(1.8, 0.0, 0.0));
    let far = m.make_vert(v3(2.7, 0.0, 0.0));
    let alone = m.make_vert(v3(5.0, 0.0, 0.0));
    let r = merge_by_distance(&mut m, &[far, alone, right, left, mid], 1.0).unwrap();
    m.validate().unwrap();
    assert_eq!(r.merged, 3);
    assert_eq!(r.survivors, vec![mid, alone]);
    assert_eq!(
        m.position(mid),
        v3(0.9, 0.0, 0.0),
        "the survivor keeps its own position"
    );
    assert_eq!(m.vert_count(), 2);
}

#[test]
fn zero_distance_merges_exact_coincidence_only() {
    let mut m = Mesh::new();
    let a = m.make_vert(v3(0.0, 1.0, 2.0));
    let b = m.make_vert(v3(-0.0, 1.0, 2.0));
    let c = m.make_vert(v3(1e-300, 1.0, 2.0));
    let d = m.make_vert(v3(0.0, 1.0, 2.0));
    let r = merge_by_distance(&mut m, &[a, b, c, d], 0.0).unwrap();
    m.validate().unwrap();
    assert_eq!(r.merged, 2);
    assert_eq!(r.survivors, vec![a, c]);
}

#[test]
fn bad_parameters_and_dead_ids_are_errors() {
    let mut m = two_cubes();
    let verts = all_verts(&m);
    for d in [-1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            merge_by_distance(&mut m, &verts, d),
            Err(OpError::Parameter { .. })
        ));
    }
    assert!(matches!(
        merge_by_distance(&mut m, &[VertId::from_index(999)], 1.0),
        Err(OpError::Kernel(KernelError::Dead { .. }))
    ));
    assert_eq!(m.vert_count(), 16);
    let r = merge_by_distance(&mut m, &[], 1.0).unwrap();
    assert_eq!(r, MergeResult::default());
}

#[test]
fn collapsing_faces_lose_corners_keep_attributes_or_vanish() {
    use crate::kernel::{AttrValue, Domain};
    let mut m = Mesh::new();
    m.add_layer("tag", Domain::Face, AttrValue::Int(0)).unwrap();
    // A quad whose last two corners coincide, and a sliver triangle.
    let q: Vec<VertId> = [
        v3(0.0, 0.0, 0.0),
        v3(1.0, 0.0, 0.0),
        v3(1.0, 1.0, 0.0),
        v3(1.0, 1.0, 0.0),
    ]
    .iter()
    .map(|&p| m.make_vert(p))
    .collect();
    let quad = m.make_face(&q).unwrap();
    m.set_attr("tag", Domain::Face, quad.index(), AttrValue::Int(4));
    let t: Vec<VertId> = [v3(5.0, 0.0, 0.0), v3(6.0, 0.0, 0.0), v3(6.0, 0.0, 0.0)]
        .iter()
        .map(|&p| m.make_vert(p))
        .collect();
    m.make_face(&t).unwrap();
    let r = merge_all(&mut m, 1e-9).unwrap();
    m.validate().unwrap();
    assert_eq!((r.merged, r.faces_removed), (2, 1));
    assert_eq!(m.face_count(), 1);
    let f = m.face_ids().next().unwrap();
    assert_eq!(m.face_verts(f).collect::<Vec<_>>(), vec![q[0], q[1], q[2]]);
    assert_eq!(
        m.attr("tag", Domain::Face, f.index()),
        Some(AttrValue::Int(4))
    );
    assert!((m.face_normal(f) - DVec3::Z).length() < 1e-12);
    // The sliver's long edge stays as a wire edge between survivors;
    // the edge between the merged pair vanished.
    assert_eq!(m.edge_count(), 4);
    assert!(m.find_edge(t[0], t[1]).is_some_and(|e| m.is_wire_edge(e)));
}

#[test]
fn a_pinched_ring_splits_into_simple_faces() {
    let mut m = Mesh::new();
    // A hexagon whose corners 0 and 3 meet in the middle: a bow tie.
    let ring: Vec<VertId> = [
        v3(0.0, 0.0, 0.0),
        v3(1.0, -1.0, 0.0),
        v3(1.0, 1.0, 0.0),
        v3(0.0, 0.0, 0.0),
        v3(-1.0, 1.0, 0.0),
        v3(-1.0, -1.0, 0.0),
    ]
    .iter()
    .map(|&p| m.make_vert(p))
    .collect();
    m.make_face(&ring).unwrap();
    let r = merge_by_distance(&mut m, &ring, 1e-9).unwrap();
    m.validate().unwrap();
    assert_eq!((r.merged, r.faces_removed), (1, 0));
    assert_eq!(m.face_count(), 2);
    for f in m.face_ids() {
        assert_eq!(m.face_len(f), 3);
        assert!(m.face_normal(f).z > 0.0, "pieces keep the winding");
    }
    assert_eq!(m.vert_degree(ring[0]), 4);
}

#[test]
fn simple_cycles_of_closed_walks() {
    let v: Vec<VertId> = (0..6).map(VertId::from_index).collect();
    let (a, b, c, d, e) = (v[0], v[1], v[2], v[3], v[4]);
    assert_eq!(simple_cycles(vec![a, b, c]), vec![vec![a, b, c]]);
    assert_eq!(simple_cycles(vec![a, a, b, c, c, a]), vec![vec![a, b, c]]);
    assert_eq!(
        simple_cycles(vec![a, b, c, a, d, e]),
        vec![vec![a, b, c], vec![a, d, e]]
    );
    assert_eq!(
        simple_cycles(vec![b, c, a, d, e, a]),
        vec![vec![a, d, e], vec![b, c, a]]
    );
    assert!(simple_cycles(vec![a, b, a, b]).is_empty());
    assert!(simple_cycles(vec![a, b, a, c]).is_empty());
    assert!(simple_cycles(vec![a, a, a]).is_empty());
}

#[test]
fn welding_a_triangle_soup_rebuilds_the_shared_grid() {
    use crate::kernel::{AttrValue, Domain};
    let mut m = Mesh::new();
    m.add_layer("tag", Domain::Face, AttrValue::Int(0)).unwrap();
    let n = 3;
    for j in 0..n {
        for i in 0..n {
            let p = |di: i32, dj: i32| v3(f64::from(i + di), f64::from(j + dj), 0.0);
            for tri in [[p(0, 0), p(1, 0), p(1, 1)], [p(0, 0), p(1, 1), p(0, 1)]] {
                let vs: Vec<VertId> = tri.iter().map(|&q| m.make_vert(q)).collect();
                let f = m.make_face(&vs).unwrap();
                m.set_attr(
                    "tag",
                    Domain::Face,
                    f.index(),
                    AttrValue::Int(f.index() as i32),
                );
            }
        }
    }
    let faces_before: Vec<FaceId> = m.face_ids().collect();
    let r = merge_all(&mut m, 1e-9).unwrap();
    m.validate().unwrap();
    assert_eq!((m.vert_count(), m.face_count()), (16, 18));
    assert_eq!(m.edge_count(), 3 * 4 * 2 + 9);
    assert_eq!((r.merged, r.faces_removed), (54 - 16, 0));
    // Clean faces keep their ids and attributes.
    assert_eq!(m.face_ids().collect::<Vec<_>>(), faces_before);
    for f in m.face_ids() {
        assert_eq!(
            m.attr("tag", Domain::Face, f.index()),
            Some(AttrValue::Int(f.index() as i32))
        );
        assert!((m.face_normal(f) - DVec3::Z).length() < 1e-12);
    }
    assert_eq!(euler_characteristic(&m), 1);
}

/// The pairwise path for small inputs agrees with the grid's.
#[test]
fn small_inputs_cluster_as_the_grid_does() {
    for seed in 0..200u64 {
        let mut rng = Rng(seed);
        let n = 2 + (seed as usize % (SMALL_CLUSTER_INPUT - 1));
        let distance = if seed % 5 == 0 { 0.0 } else { 0.3 };
        let points: Vec<DVec3> = (0..n)
            .map(|_| {
                // Coarse coordinates, so exact coincidences happen too.
                let q = |x: f64| (x * 4.0).floor() / 4.0;
                v3(q(rng.unit()), q(rng.unit()), q(rng.unit()))
            })
            .collect();
        let expected = if distance > 0.0 {
            grid_roots(&points[..], distance)
        } else {
            let mut more = points.clone();
            more.resize(SMALL_CLUSTER_INPUT + 1, v3(9.0, 9.0, 9.0));
            cluster_roots(&more[..], 0.0)[..n].to_vec()
        };
        assert_eq!(
            cluster_roots(&points[..], distance),
            expected,
            "seed {seed}"
        );
    }
}

/// The grid's clusters equal brute-force components, also for points
/// straddling cell borders and exactly at the distance.
#[test]
fn grid_clustering_matches_brute_force() {
    for seed in 0..20u64 {
        let mut rng = Rng(seed);
        let distance = 0.05 + rng.unit() * 0.2;
        let points: Vec<DVec3> = (0..300)
            .map(|_| v3(rng.unit(), rng.unit(), rng.unit() * 0.3))
            .collect();
        let mut sets = UnionFind::new(points.len());
        for i in 0..points.len() {
            for j in i + 1..points.len() {
                if points[i].distance(points[j]) <= distance {
                    sets.union(i as u32, j as u32);
                }
            }
        }
        let expected: Vec<u32> = (0..points.len() as u32).map(|i| sets.find(i)).collect();
        assert_eq!(
            cluster_roots(&points[..], distance),
            expected,
            "seed {seed}"
        );
    }
    // Cells too many to pack into 64 bits (the tuple-sorted path), and
    // saturated cell coordinates: still exact.
    for seed in 0..5u64 {
        let mut rng = Rng(100 + seed);
        let mut points = Vec::new();
        for _ in 0..40 {
            let site = v3(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5) * 2e6;
            for _ in 0..3 {
                points.push(site + v3(rng.unit(), rng.unit(), 0.0) * 1.5e-6);
            }
        }
        points.push(v3(1e300, -1e300, 0.0));
        points.push(v3(1e300, -1e300, 0.0));
        points.push(v3(9e299, -1e300, 0.0));
        let mut sets = UnionFind::new(points.len());
        for i in 0..points.len() {
            for j in i + 1..points.len() {
                if within(points[i], points[j], 1e-6) {
                    sets.union(i as u32, j as u32);
                }
            }
        }
        let expected: Vec<u32> = (0..points.len() as u32).map(|i| sets.find(i)).collect();
        assert_eq!(cluster_roots(&points[..], 1e-6), expected, "seed {seed}");
        let n = points.len() as u32;
        assert_eq!(expected[n as usize - 2], n - 3);
        assert_eq!(expected[n as usize - 1], n - 1);
    }
    // Exactly at the distance, across a cell border, on negative coordinates.
    let points = [v3(-0.5, 0.0, 0.0), v3(0.5, 0.0, 0.0), v3(-1.5, -1.0, 0.0)];
    assert_eq!(cluster_roots(&points[..], 1.0), vec![0, 0, 2]);
}

#[test]
fn cell_coordinate_is_floor() {
    let mut rng = Rng(3);
    let mut values = vec![
        0.0, -0.0, -1.0, -0.5, 0.5, 3.0, -3.0, 1e300, -1e300, 4.5e15, -4.5e15,
    ];
    values.extend((0..1000).map(|_| (rng.unit() - 0.5) * 1e6));
    for x in values {
        for d in [1.0, 0.3, 1e-7] {
            let expected = (x / d).floor() as i64;
            assert_eq!(cell_coordinate(x, d), expected, "{x} / {d}");
        }
    }
}

#[test]
fn mirrored_half_grid_is_seamless() {
    let mut m = Mesh::new();
    let g = create_grid(&mut m, 2, 2, 2.0, 2.0).unwrap();
    translate(&mut m, &g.verts, v3(1.0, 0.0, 0.0)).unwrap();
    let copies = mirror(&mut m, &g, DVec3::ZERO, DVec3::X, 1e-6).unwrap();
    m.validate().unwrap();
    assert_eq!((m.vert_count(), m.face_count()), (15, 8));
    assert_eq!((copies.verts.len(), copies.faces.len()), (6, 4));
    assert!(
        g.verts.iter().all(|&v| m.contains_vert(v)),
        "originals survive the weld"
    );
    for f in m.face_ids() {
        assert!(
            (m.face_normal(f) - DVec3::Z).length() < 1e-12,
            "mirrored faces rewound"
        );
    }
    let border: Vec<EdgeId> = m
        .edge_ids()
        .filter(|&e| m.edge_face_count(e) == 1)
        .collect();
    assert_eq!(border.len(), 2 * (4 + 2));
    for e in m.edge_ids() {
        let on_seam = m
            .edge_verts(e)
            .iter()
            .all(|&v| m.position(v).x.abs() < 1e-9);
        if on_seam {
            assert_eq!(m.edge_face_count(e), 2, "seam edge {e} is not welded");
        }
    }
    assert_eq!(euler_characteristic(&m), 1);
}

#[test]
fn mirrored_half_tube_closes_around() {
    let mut m = Mesh::new();
    let tube = create_cylinder(&mut m, 8, 1.0, 1.0, 2.0, false).unwrap();
    let west: Vec<VertId> = tube
        .verts
        .iter()
        .copied()
        .filter(|&v| m.position(v).x < -1e-9)
        .collect();
    delete(
        &mut m,
        &Selection::from_parts(west, vec![], vec![]),
        DeleteMode::All,
    )
    .unwrap();
    assert_eq!((m.vert_count(), m.face_count()), (10, 4));
    let half = select_from_faces(&m, &m.face_ids().collect::<Vec<_>>());
    mirror(&mut m, &half, DVec3::ZERO, v3(-3.0, 0.0, 0.0), 1e-6).unwrap();
    m.validate().unwrap();
    assert_eq!(
        (m.vert_count(), m.edge_count(), m.face_count()),
        (16, 24, 8)
    );
    // Only the two rims are open; every vertical edge has two faces.
    let open = m.edge_ids().filter(|&e| m.edge_face_count(e) == 1).count();
    assert_eq!(open, 16);
    for f in m.face_ids() {
        let (n, c) = (m.face_normal(f), m.face_center(f));
        assert!(n.x * c.x + n.y * c.y > 0.0, "face {f} points inward");
    }
    assert_eq!(euler_characteristic(&m), 0);
}

#[test]
fn mirror_checks_its_plane() {
    let mut m = Mesh::new();
    let c = create_cube(&mut m, 1.0).unwrap();
    assert!(mirror(&mut m, &c, DVec3::ZERO, DVec3::ZERO, 0.0).is_err());
    assert!(mirror(&mut m, &c, DVec3::splat(f64::NAN), DVec3::X, 0.0).is_err());
    assert!(mirror(&mut m, &c, DVec3::ZERO, DVec3::X, -1.0).is_err());
    assert!(
        mirror(&mut m, &c, v3(f64::MAX, 0.0, 0.0), DVec3::X, 0.0).is_err(),
        "overflow"
    );
    assert_eq!(m.vert_count(), 8);
    // A whole cube mirrored off to the side: a second closed cube.
    let copies = mirror(&mut m, &c, v3(2.0, 0.0, 0.0), DVec3::X, 1e-6).unwrap();
    m.validate().unwrap();
    assert_eq!(
        (copies.verts.len(), copies.edges.len(), copies.faces.len()),
        (8, 12, 6)
    );
    assert!((signed_volume(&m) - 2.0).abs() < 1e-12);
}

/// Heavy: `cargo test --release --lib merge_a_million -- --ignored --nocapture`.
#[test]
#[ignore]
fn merge_a_million_points_in_linear_time() {
    let mut rng = Rng(7);
    let distance = 1e-4;
    // ~166k distinct sites, each repeated 6 times with jitter < ε/4.
    let sites = 1_000_000 / 6;
    let mut m = Mesh::new();
    for _ in 0..sites {
        let site = v3(rng.unit(), rng.unit(), rng.unit()) * 10.0;
        for _ in 0..6 {
            let jitter = v3(rng.unit(), rng.unit(), rng.unit()) * (distance / 8.0);
            m.make_vert(site + jitter);
        }
    }
    let verts = all_verts(&m);
    let positions: Vec<DVec3> = verts.iter().map(|&v| m.position(v)).collect();
    let start = std::time::Instant::now();
    let roots = cluster_roots(&positions[..], distance);
    println!("clustering alone: {:?}", start.elapsed());
    drop((positions, roots));
    let start = std::time::Instant::now();
    let r = merge_by_distance(&mut m, &verts, distance).unwrap();
    let points = start.elapsed();
    println!("merge 1M isolated points: {points:?}, merged {}", r.merged);
    m.validate().unwrap();

    // A welded triangle soup: 2·300² triangles, 1.08M corners.
    let mut m = triangle_soup(300);
    let verts = all_verts(&m);
    let start = std::time::Instant::now();
    let r = merge_by_distance(&mut m, &verts, 1e-6).unwrap();
    let soup = start.elapsed();
    println!(
        "weld soup of {} corners: {soup:?}, merged {}",
        verts.len(),
        r.merged
    );
    m.validate().unwrap();
    assert_eq!(m.vert_count(), 301 * 301);
}

/// The radix sort orders by (key, index) for every key width, repeated
/// keys included; 100,001 keys on two threads take the two-halves path
/// (an odd split).
#[test]
fn radix_sort_orders_by_key_then_index() {
    use super::cluster::radix_sort;
    let mut rng = Rng(41);
    for bits in [0u32, 1, 5, 12, 13, 34, 63, 64] {
        for len in [0usize, 1, 7, 1000, 100_001] {
            let mask = if bits == 64 {
                u64::MAX
            } else {
                (1u64 << bits) - 1
            };
            // Few distinct values as well as spread ones.
            let keys: Vec<u64> = (0..len)
                .map(|i| {
                    if i % 3 == 0 {
                        rng.next() & mask & 0xF
                    } else {
                        rng.next() & mask
                    }
                })
                .collect();
            let mut want: Vec<(u64, u32)> = keys.iter().copied().zip(0u32..).collect();
            want.sort_unstable();
            // One thread sorts the whole; two sort halves and merge them.
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let (sorted, order) = pool.install(|| radix_sort(keys.clone(), bits));
                let got: Vec<(u64, u32)> = sorted.into_iter().zip(order).collect();
                assert_eq!(got, want, "{bits} bits, {len} keys, {threads} threads");
            }
        }
    }
}

/// A weld big enough to take every parallel path (the two-halves sort,
/// the parallel face passes) gives the same mesh, ids included, on one
/// thread as on several.
#[test]
fn a_large_soup_welds_the_same_on_one_thread_as_on_several() {
    let welded = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut m = triangle_soup(120);
            let r = merge_all(&mut m, 1e-6).unwrap();
            m.validate().unwrap();
            (fingerprint(&m), r)
        })
    };
    let (one, r) = welded(1);
    assert_eq!(r.merged, 6 * 120 * 120 - 121 * 121);
    assert_eq!(
        (one.0.len(), one.2.len(), r.faces_removed),
        (121 * 121, 2 * 120 * 120, 0)
    );
    assert_eq!(welded(3), (one, r));
}

/// Welded twins are decided in order: a face whose only twin was itself
/// killed as a twin of a third face stays (issue 38: the search runs in
/// parallel, and the faces it finds are asked again as they are killed).
#[test]
fn a_twin_killed_as_a_twin_no_longer_removes_another() {
    let mut m = Mesh::new();
    let a = m.make_vert(v3(0.0, 0.0, 0.0));
    let b = m.make_vert(v3(1.0, 0.0, 0.0));
    let c = m.make_vert(v3(1.0, 1.0, 0.0));
    let d = m.make_vert(v3(0.0, 1.0, 0.0));
    // A copy of `a`: every face below holds it, so every face is touched
    // by the weld and kept whole (clean).
    let a2 = m.make_vert(v3(0.0, 0.0, 0.0));
    // After the weld all three have the vertex set {a, b, c, d}.
    let h = m.make_face(&[b, d, a2, c]).unwrap();
    let g = m.make_face(&[b, d, c, a2]).unwrap();
    let f = m.make_face(&[a2, b, c, d]).unwrap();
    assert!(h < g && g < f);
    let r = merge_all(&mut m, 1e-9).unwrap();
    m.validate().unwrap();
    // h is the lowest: kept. g finds h on its first edge b–d: killed. f's
    // first edge a–b holds g but not h, so with g gone f has no twin.
    assert_eq!(m.face_ids().collect::<Vec<_>>(), [h, f]);
    assert_eq!((r.merged, r.faces_removed), (1, 1));
    assert_eq!(m.face_verts(f).collect::<Vec<_>>(), [a, b, c, d]);
}

/// Clustering enough points to take the two-runs sweep (and the two-halves
/// sort) on two threads gives the roots of the one-thread sweep, with
/// chains of points that cross from one run into the other.
#[test]
fn clusters_are_the_same_on_one_thread_as_on_two() {
    let mut rng = Rng(5);
    let distance = 0.01;
    let mut points: Vec<DVec3> = Vec::new();
    // Sites repeated with jitter below the distance: small clusters.
    for _ in 0..20_000 {
        let site = v3(rng.unit(), rng.unit(), rng.unit());
        for _ in 0..4 {
            points.push(site + v3(rng.unit(), rng.unit(), rng.unit()) * (distance / 4.0));
        }
    }
    // Chains 0.9 · distance apart along each axis, through every cell
    // boundary and the middle of the points: each one cluster.
    let mut chain: Vec<Option<usize>> = vec![None; points.len()];
    for (c, axis) in [DVec3::X, DVec3::Y, DVec3::Z].into_iter().enumerate() {
        let origin = v3(rng.unit(), rng.unit(), rng.unit()) * 0.5;
        points.extend((0..500).map(|i| origin + axis * (0.9 * distance * f64::from(i))));
        chain.extend([Some(c)].repeat(500));
    }
    // Shuffled, so the lowest index of a cluster is anywhere in it.
    for i in (1..points.len()).rev() {
        let j = (rng.next() % (i as u64 + 1)) as usize;
        points.swap(i, j);
        chain.swap(i, j);
    }
    let roots = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| cluster_roots(&points[..], distance))
    };
    let one = roots(1);
    assert_eq!(roots(2), one);
    for c in 0..3 {
        let mut chain_roots: Vec<u32> = (0..points.len())
            .filter(|&i| chain[i] == Some(c))
            .map(|i| one[i])
            .collect();
        chain_roots.dedup();
        assert_eq!(chain_roots.len(), 1, "chain {c}");
    }
}
