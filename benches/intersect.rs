//! Intersection benchmarks (thesis 003 §3.2):
//! - whole-mesh self-intersection of a UV sphere with ~180k triangles
//!   (target ≤ 100 ms on 2 cores), and a ~20k one to show the scaling;
//! - the gates of `graftal info` on the peers' workload (issue 17): two
//!   crossing icospheres of 102,400 triangles, 902 pairs, searched in the
//!   indexed mesh (target ≤ 30 ms), with its close-vertex count beside;
//! - growth tests: 1k segments queried and inserted one by one into
//!   [`IntersectionIndex`]es of 10³…10⁶ primitives (the cost should stay
//!   about flat as the model grows), and the same 1k queries alone.
//!
//!     cargo bench --bench intersect

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use glam::DVec3;

use graftal::geom::IndexedMesh;
use graftal::kernel::intersect::{self, IntersectionIndex, PairLimits, WireThickness};
use graftal::kernel::ops::create;
use graftal::kernel::{EdgeId, Mesh};

fn sphere(segments: u32, rings: u32) -> Mesh {
    let mut mesh = Mesh::new();
    create::create_uv_sphere(&mut mesh, segments, rings, 1.0).unwrap();
    mesh
}

fn bench_self_intersections(c: &mut Criterion) {
    let mut g = c.benchmark_group("self_intersections");
    g.sample_size(10);
    // Triangles: 2 · segments · (rings − 1).
    for (segments, rings) in [(100u32, 101u32), (300, 301)] {
        let mesh = sphere(segments, rings);
        let triangles = mesh.report().triangles;
        assert!(intersect::self_intersections(&mesh).is_empty());
        g.bench_function(format!("uv_sphere_{triangles}_triangles"), |b| {
            b.iter(|| black_box(intersect::self_intersections(&mesh)))
        });
    }
    g.finish();
}

/// An icosphere: the icosahedron, each triangle split in four
/// `subdivisions` times with the new vertices pushed out to the sphere
/// (trimesh's `creation.icosphere`, which `bench-peers` uses).
fn icosphere(subdivisions: u32, radius: f64, centre: DVec3, out: &mut IndexedMesh) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut points: Vec<DVec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .map(|p| DVec3::from_array(p).normalize())
    .to_vec();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut middles = std::collections::BTreeMap::new();
        let mut middle = |a: u32, b: u32, points: &mut Vec<DVec3>| {
            *middles.entry((a.min(b), a.max(b))).or_insert_with(|| {
                points.push(((points[a as usize] + points[b as usize]) * 0.5).normalize());
                points.len() as u32 - 1
            })
        };
        triangles = triangles
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = (
                    middle(a, b, &mut points),
                    middle(b, c, &mut points),
                    middle(c, a, &mut points),
                );
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    let base = out.positions.len() as u32;
    out.positions
        .extend(points.iter().map(|&p| (p * radius + centre).to_array()));
    for triangle in triangles {
        out.push_polygon(&triangle.map(|i| i + base));
    }
}

fn bench_info_gates(c: &mut Criterion) {
    let mut spheres = IndexedMesh::new();
    icosphere(6, 1.0, DVec3::ZERO, &mut spheres);
    icosphere(5, 0.8, DVec3::new(0.9, 0.0, 0.0), &mut spheres);
    assert_eq!(spheres.polygon_count(), 102_400);
    let found = intersect::indexed_self_intersection_search(&spheres, PairLimits::for_items);
    assert!(found.complete && found.count > 800, "{found:?}");
    let mut g = c.benchmark_group("info_gates");
    g.sample_size(20);
    g.bench_function("two_icospheres_self_intersections", |b| {
        b.iter(|| {
            black_box(intersect::indexed_self_intersection_search(
                &spheres,
                PairLimits::for_items,
            ))
        })
    });
    let points: Vec<DVec3> = (0..spheres.positions.len() as u32)
        .map(|i| spheres.position(i))
        .collect();
    g.bench_function("two_icospheres_close_vertices", |b| {
        b.iter(|| black_box(intersect::count_close_points(&points, 1e-6, u64::MAX)))
    });
    g.finish();
}

/// A flat grid of about `primitives` triangles (cells of size 1), plus 1k
/// short wire edges scattered over it, some crossing it; the index holds
/// the grid only.
fn model(primitives: usize) -> (Mesh, IntersectionIndex, Vec<EdgeId>) {
    let k = ((primitives / 2) as f64).sqrt().round() as u32;
    let mut mesh = Mesh::new();
    create::create_grid(&mut mesh, k, k, f64::from(k), f64::from(k)).unwrap();
    let index = IntersectionIndex::from_mesh(&mesh, WireThickness::Zero);
    let mut state = 0x2545_F491_4F6C_DD1D_u64;
    let mut rnd = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let half = f64::from(k) * 0.5;
    let edges = (0..1000)
        .map(|_| {
            let a = DVec3::new(
                (rnd() - 0.5) * 2.0 * half,
                (rnd() - 0.5) * 2.0 * half,
                rnd() - 0.3,
            );
            let b = a + DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5);
            let v = mesh.make_vert(a);
            mesh.make_edge_vert(v, b).unwrap().0
        })
        .collect();
    (mesh, index, edges)
}

fn bench_index(c: &mut Criterion) {
    let mut g = c.benchmark_group("intersection_index");
    g.sample_size(10);
    for primitives in [1_000usize, 10_000, 100_000, 1_000_000] {
        let (mesh, index, edges) = model(primitives);
        let ends = |e: EdgeId| {
            let [a, b] = mesh.edge_verts(e);
            (mesh.position(a), mesh.position(b), a)
        };
        g.bench_function(format!("query_1k_segments_in_{}", index.len()), |b| {
            b.iter(|| {
                edges
                    .iter()
                    .filter(|&&e| {
                        let (p0, p1, v) = ends(e);
                        index.segment_hits(p0, p1, 0.05, &[v])
                    })
                    .count()
            })
        });
        g.bench_function(
            format!("query_and_insert_1k_segments_in_{}", index.len()),
            |b| {
                b.iter_batched(
                    || index.clone(),
                    |mut index| {
                        let mut hits = 0;
                        for &e in &edges {
                            let (p0, p1, v) = ends(e);
                            hits += usize::from(index.segment_hits(p0, p1, 0.05, &[v]));
                            index.insert_edge(&mesh, e, 0.05);
                        }
                        (index, hits)
                    },
                    BatchSize::LargeInput,
                )
            },
        );
    }
    g.finish();
}

criterion_group!(
    benches,
    bench_self_intersections,
    bench_info_gates,
    bench_index
);
criterion_main!(benches);
