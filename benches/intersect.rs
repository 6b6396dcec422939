//! Intersection benchmarks (thesis 003 §3.2):
//! - whole-mesh self-intersection of a UV sphere with ~180k triangles
//!   (target ≤ 100 ms on 2 cores), and a ~20k one to show the scaling;
//! - growth tests: 1k segments queried and inserted one by one into
//!   [`IntersectionIndex`]es of 10³…10⁶ primitives (the cost should stay
//!   about flat as the model grows), and the same 1k queries alone.
//!
//!     cargo bench --bench intersect

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use glam::DVec3;

use graftal::kernel::intersect::{self, IntersectionIndex, WireThickness};
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

criterion_group!(benches, bench_self_intersections, bench_index);
criterion_main!(benches);
