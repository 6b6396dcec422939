//! Kernel and writer benchmarks (issue 2 targets, on 2 cores):
//! build a 1000×1000 grid; extrude all its faces; merge 1M points by
//! distance (≤ 300 ms); triangulate 100k quads and 10k non-convex
//! 12-gons; write a 1M-triangle GLB (≤ 300 ms).
//!
//!     cargo bench --bench kernel
//!
//! Smaller sizes run alongside the large ones so linear growth is visible.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use glam::DVec3;

use graftal::io::{self, MeshFormat};
use graftal::kernel::ops::{create, extrude, faces, merge};
use graftal::kernel::{Mesh, VertId};

fn grid(n: u32) -> Mesh {
    let mut mesh = Mesh::new();
    create::create_grid(&mut mesh, n, n, n as f64, n as f64).unwrap();
    mesh
}

fn bench_grid(c: &mut Criterion) {
    let mut g = c.benchmark_group("grid");
    g.sample_size(10);
    for n in [250u32, 500, 1000] {
        g.bench_function(format!("create_{n}x{n}"), |b| b.iter(|| black_box(grid(n))));
    }
    g.finish();
}

fn bench_extrude(c: &mut Criterion) {
    let mut g = c.benchmark_group("extrude_faces");
    g.sample_size(10);
    for n in [250u32, 1000] {
        let base = grid(n);
        let faces: Vec<_> = base.face_ids().collect();
        g.bench_function(format!("all_faces_{n}x{n}"), |b| {
            b.iter_batched(
                || base.clone(),
                |mut mesh| {
                    extrude::extrude_faces(
                        &mut mesh,
                        &faces,
                        false,
                        extrude::ExtrudeOffset::Normal(1.0),
                    )
                    .unwrap();
                    mesh
                },
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

/// `n` isolated points, each repeated 6 times within 1e-7 (a deterministic jitter).
fn point_cloud(n: usize) -> (Mesh, Vec<VertId>) {
    let mut mesh = Mesh::new();
    let mut verts = Vec::with_capacity(n);
    let distinct = n / 6;
    for i in 0..n {
        let k = (i % distinct) as f64;
        let jitter = (i / distinct) as f64 * 1e-8;
        let p = DVec3::new((k * 0.618_034) % 100.0, (k * 0.414_214) % 100.0, k * 1e-4) + jitter;
        verts.push(mesh.make_vert(p));
    }
    (mesh, verts)
}

fn bench_merge(c: &mut Criterion) {
    let mut g = c.benchmark_group("merge_by_distance");
    g.sample_size(10);
    for n in [100_000usize, 1_000_000] {
        let (base, verts) = point_cloud(n);
        g.bench_function(format!("{n}_points"), |b| {
            b.iter_batched(
                || base.clone(),
                |mut mesh| {
                    merge::merge_by_distance(&mut mesh, &verts, 1e-6).unwrap();
                    mesh
                },
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

fn star_12gons(count: usize) -> Mesh {
    let mut mesh = Mesh::new();
    for k in 0..count {
        let centre = DVec3::new((k % 100) as f64 * 3.0, (k / 100) as f64 * 3.0, 0.0);
        let ring: Vec<VertId> = (0..12)
            .map(|i| {
                let t = i as f64 * std::f64::consts::TAU / 12.0;
                let r = if i % 2 == 0 { 1.0 } else { 0.45 };
                mesh.make_vert(centre + DVec3::new(r * t.cos(), r * t.sin(), 0.0))
            })
            .collect();
        mesh.make_face(&ring).unwrap();
    }
    mesh
}

fn bench_triangulate(c: &mut Criterion) {
    let mut g = c.benchmark_group("triangulate");
    g.sample_size(10);
    let quads = grid(317); // 100,489 quads
    let quad_faces: Vec<_> = quads.face_ids().collect();
    g.bench_function("100k_quads", |b| {
        b.iter_batched(
            || quads.clone(),
            |mut mesh| {
                faces::triangulate(&mut mesh, &quad_faces).unwrap();
                mesh
            },
            BatchSize::LargeInput,
        )
    });
    let stars = star_12gons(10_000);
    let star_faces: Vec<_> = stars.face_ids().collect();
    g.bench_function("10k_nonconvex_12gons", |b| {
        b.iter_batched(
            || stars.clone(),
            |mut mesh| {
                faces::triangulate(&mut mesh, &star_faces).unwrap();
                mesh
            },
            BatchSize::LargeInput,
        )
    });
    g.finish();
}

fn bench_glb(c: &mut Criterion) {
    let mut g = c.benchmark_group("write_glb");
    g.sample_size(10);
    for n in [250u32, 708] {
        // 2·n² triangles: 708² · 2 ≈ 1.0M.
        let indexed = grid(n).to_indexed();
        g.bench_function(format!("{}_triangles", 2 * n * n), |b| {
            b.iter(|| black_box(io::encode(&indexed, MeshFormat::Glb).unwrap()))
        });
    }
    g.finish();
}

criterion_group!(
    benches,
    bench_grid,
    bench_extrude,
    bench_merge,
    bench_triangulate,
    bench_glb
);
criterion_main!(benches);
