//! Kernel and writer benchmarks (issue 2 targets, on 2 cores):
//! build a 1000×1000 grid; extrude all its faces; merge 1M points by
//! distance (≤ 300 ms); weld the issue-17 soup of 998,784 corners (an
//! indexed mesh, before any kernel mesh); triangulate 100k quads and 10k non-convex
//! 12-gons; write a 1M-triangle GLB (≤ 300 ms).
//!
//!     cargo bench --bench kernel
//!
//! Smaller sizes run alongside the large ones so linear growth is visible.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use glam::DVec3;

use graftal::geom::indexed::IndexedMesh;
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

/// The issue-17 soup: a `cells`² quad grid of spacing 0.01 exploded into
/// triangles, every corner its own vertex jittered by U(±1e-6) (a
/// counter-based hash, so the input is the same on every run).
fn jittered_soup(cells: u32) -> IndexedMesh {
    let jitter = |k: u64| {
        let mut z = k
            .wrapping_add(0x9E37_79B9_7F4A_7C15)
            .wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 31)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * 1e-6
    };
    let mut soup = IndexedMesh::new();
    let corner = |soup: &mut IndexedMesh, i: u32, j: u32| {
        let k = soup.positions.len() as u64 * 3;
        soup.positions.push([
            i as f64 * 0.01 + jitter(k),
            j as f64 * 0.01 + jitter(k + 1),
            jitter(k + 2),
        ]);
        soup.positions.len() as u32 - 1
    };
    for j in 0..cells {
        for i in 0..cells {
            for tri in [
                [(i, j), (i + 1, j), (i + 1, j + 1)],
                [(i, j), (i + 1, j + 1), (i, j + 1)],
            ] {
                let ids = tri.map(|(a, b)| corner(&mut soup, a, b));
                soup.push_polygon(&ids);
            }
        }
    }
    soup
}

fn bench_weld(c: &mut Criterion) {
    let mut g = c.benchmark_group("weld_indexed");
    g.sample_size(10);
    for cells in [41u32, 408] {
        let soup = jittered_soup(cells);
        g.bench_function(format!("soup_{}_vertices", soup.positions.len()), |b| {
            b.iter(|| black_box(soup.welded(1e-4)))
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
    bench_weld,
    bench_triangulate,
    bench_glb
);
criterion_main!(benches);
