//! Criterion benchmarks of the SDF pillar (peers.md §2 workloads).
//!
//! `cargo bench --bench sdf` (2 threads by default: rayon's global pool).

use std::sync::Arc;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::DVec3;
use graftal::sdf::grid::sample_grid;
use graftal::sdf::*;

fn sphere_minus_box() -> Tape {
    let mut t = Tree::new();
    let ball = t.push(Node::Sphere { radius: 1.0 });
    let cube = t.push(Node::Box { size: DVec3::ONE });
    let cube = t.push(Node::Translate {
        child: cube,
        offset: DVec3::splat(0.5),
    });
    let root = t.push(Node::Difference {
        base: ball,
        subtract: vec![cube],
    });
    Tape::compile(&t, root, &TreeLimits::default()).unwrap()
}

fn union_mesh() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let b: &[u8] = include_bytes!("../fixtures/sdf/union.bin");
    let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    let f64_at = |o: usize| f64::from_le_bytes(b[o..o + 8].try_into().unwrap());
    let (nv, nt) = (u32_at(0) as usize, u32_at(4) as usize);
    let pos = (0..nv)
        .map(|i| [f64_at(8 + 24 * i), f64_at(16 + 24 * i), f64_at(24 + 24 * i)])
        .collect();
    let base = 8 + 24 * nv;
    let tris = (0..nt)
        .map(|i| {
            [
                u32_at(base + 12 * i),
                u32_at(base + 12 * i + 4),
                u32_at(base + 12 * i + 8),
            ]
        })
        .collect();
    (pos, tris)
}

fn opts(n: u32, mesher: Mesher) -> MeshOptions {
    MeshOptions {
        mesher,
        resolution: Resolution::CellSize(2.4 / n as f64),
        domain: Some(Aabb::new(DVec3::splat(-1.2), DVec3::splat(1.2))),
        ..Default::default()
    }
}

fn meshing(c: &mut Criterion) {
    let tape = sphere_minus_box();
    let mut g = c.benchmark_group("sphere_minus_box");
    g.sample_size(20);
    for n in [64u32, 128, 256, 512] {
        g.bench_with_input(BenchmarkId::new("mc", n), &n, |b, &n| {
            b.iter(|| mesh(&tape, &opts(n, Mesher::MarchingCubes)).unwrap())
        });
    }
    for n in [128u32, 256] {
        g.bench_with_input(BenchmarkId::new("dc", n), &n, |b, &n| {
            b.iter(|| mesh(&tape, &opts(n, Mesher::DualContouring)).unwrap())
        });
    }
    g.finish();
}

fn mesh_distance(c: &mut Criterion) {
    let (p, t) = union_mesh();
    let mut g = c.benchmark_group("union_mesh_sdf");
    g.sample_size(10);
    g.bench_function("build", |b| {
        b.iter(|| MeshField::new(&p, &t, SignMode::Auto).unwrap())
    });
    let mf = Arc::new(MeshField::new(&p, &t, SignMode::Auto).unwrap());
    let mut tree = Tree::new();
    let m = tree.push(Node::Mesh(mf));
    let tape = Tape::compile(&tree, m, &TreeLimits::default()).unwrap();
    for n in [64usize, 128] {
        g.bench_with_input(BenchmarkId::new("grid", n), &n, |b, &n| {
            b.iter(|| {
                sample_grid(
                    &tape,
                    DVec3::splat(-1.3),
                    DVec3::splat(2.0),
                    [n, n, n],
                    u64::MAX,
                    0,
                )
                .unwrap()
            })
        });
    }
    g.finish();
}

fn skinning(c: &mut Criterion) {
    let (pos, rad, edges) = grown_tree(2000);
    let nodes = pos
        .iter()
        .zip(&rad)
        .map(|(p, r)| SkinNode {
            position: *p,
            radius: *r,
        })
        .collect();
    let skel = Skeleton { nodes, edges };
    let o = SkinOptions {
        blend: 0.006,
        cell: None,
        mesh: MeshOptions::default(),
    };
    let mut g = c.benchmark_group("skin");
    g.sample_size(10);
    g.bench_function("grown_tree_2000_edges", |b| {
        b.iter(|| skin(&skel, &o).unwrap())
    });
    g.finish();
}

criterion_group!(benches, meshing, mesh_distance, skinning);
criterion_main!(benches);

/// A branching tree grown outwards (a plant-like skeleton): node i hangs
/// from node (i − 1) / 2, continuing its parent's direction with noise;
/// segments shorten and thin with depth. `n` edges.
pub fn grown_tree(n: u32) -> (Vec<[f64; 3]>, Vec<f64>, Vec<[u32; 2]>) {
    let mut s = 7u64;
    let mut rnd = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut pos = vec![[0.0, 0.0, 0.0]];
    let mut dir = vec![[0.0, 0.0, 1.0]];
    let mut rad = vec![0.06];
    let mut edges = Vec::new();
    for i in 1..=n {
        let p = ((i - 1) / 2) as usize;
        let depth = (32 - (i + 1).leading_zeros()) as f64;
        let d = dir[p];
        let mut nd = [
            d[0] + rnd() * 1.2,
            d[1] + rnd() * 1.2,
            d[2] + rnd() * 0.6 + 0.2,
        ];
        let l = (nd[0] * nd[0] + nd[1] * nd[1] + nd[2] * nd[2]).sqrt();
        nd = [nd[0] / l, nd[1] / l, nd[2] / l];
        let len = 0.35 * 0.85f64.powf(depth);
        let q = pos[p];
        pos.push([q[0] + nd[0] * len, q[1] + nd[1] * len, q[2] + nd[2] * len]);
        dir.push(nd);
        rad.push((0.06 * 0.85f64.powf(depth)).max(0.012));
        edges.push([p as u32, i]);
    }
    (pos, rad, edges)
}
