//! The peers' NURBS workload (shared/peers.md §3) and PN throughput.
//!
//! `cargo bench --bench nurbs` (criterion). Counts and deviations are printed once per bench.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use graftal::nurbs::pn::{pn_triangles, Pattern, PnOptions};
use graftal::nurbs::surface::NurbsSurface;
use graftal::nurbs::tess::{tessellate, AdaptiveOptions, Diagonal, Mode};

fn peer_surface() -> NurbsSurface {
    let mut pts = Vec::new();
    let mut w = Vec::new();
    for i in 0..10 {
        for j in 0..10 {
            let (fi, fj) = (i as f64, j as f64);
            pts.push([fi, fj, 2.0 * libm::sin(0.7 * fi) * libm::cos(0.5 * fj)]);
            w.push(1.0 + 0.5 * ((i + j) % 3) as f64);
        }
    }
    NurbsSurface::clamped([3, 3], [10, 10], &pts, Some(&w)).unwrap()
}

fn linspace(n: usize) -> Vec<f64> {
    (0..n).map(|k| k as f64 / (n - 1) as f64).collect()
}

fn grid(c: &mut Criterion) {
    let s = peer_surface();
    for n in [100usize, 1000] {
        let ts = linspace(n);
        let g = s.grid(&ts, &ts, false).unwrap();
        let z: f64 = g.points.iter().map(|p| p[2]).sum();
        eprintln!("grid {n}x{n}: sum z = {z:.6}");
        let mut group = c.benchmark_group("grid_points");
        group.throughput(Throughput::Elements((n * n) as u64));
        group.bench_function(format!("{n}x{n}"), |b| {
            b.iter(|| s.grid(&ts, &ts, false).unwrap())
        });
        group.bench_function(format!("{n}x{n}_with_normals"), |b| {
            b.iter(|| s.grid(&ts, &ts, true).unwrap())
        });
        group.finish();
    }
    // Point-by-point, for the factorisation's gain.
    let ts = linspace(100);
    c.bench_function("pointwise_100x100", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for &u in &ts {
                for &v in &ts {
                    acc += s.point(u, v).unwrap().z;
                }
            }
            acc
        })
    });
}

fn adaptive(c: &mut Criterion) {
    let s = peer_surface();
    let mut group = c.benchmark_group("tessellate");
    group.sample_size(20);
    for eps in [1e-2, 1e-3] {
        let mode = Mode::Adaptive(AdaptiveOptions::sagitta(eps));
        let t = tessellate(&s, &mode, 10_000_000).unwrap();
        eprintln!(
            "adaptive sagitta {eps}: {} triangles, {} vertices, max deviation {:.4e}, level {}, rounds {}",
            t.stats.triangles, t.stats.vertices, t.stats.max_deviation, t.stats.max_level, t.stats.rounds
        );
        group.bench_function(format!("adaptive_sagitta_{eps}"), |b| {
            b.iter(|| tessellate(&s, &mode, 10_000_000).unwrap())
        });
    }
    let mode = Mode::Uniform {
        cells: [999, 999],
        per_patch: false,
        diagonal: Diagonal::Fixed,
    };
    group.bench_function("uniform_1000x1000_points", |b| {
        b.iter(|| tessellate(&s, &mode, 10_000_000).unwrap())
    });
    let mode = Mode::InterPatch { tolerance: 1e-2 };
    let t = tessellate(&s, &mode, 10_000_000).unwrap();
    eprintln!(
        "interpatch 1e-2: {} triangles, max deviation {:.4e}",
        t.stats.triangles, t.stats.max_deviation
    );
    group.bench_function("interpatch_1e-2", |b| {
        b.iter(|| tessellate(&s, &mode, 10_000_000).unwrap())
    });
    group.finish();
}

fn pn(c: &mut Criterion) {
    // Input: a 64 × 32-cell uniform tessellation of the peers' surface with its normals.
    let s = peer_surface();
    let base = tessellate(
        &s,
        &Mode::Uniform {
            cells: [64, 32],
            per_patch: false,
            diagonal: Diagonal::Fixed,
        },
        1 << 20,
    )
    .unwrap()
    .mesh;
    let normals: Vec<[[f64; 3]; 3]> = base
        .triangles
        .iter()
        .map(|t| t.map(|v| base.normals[v as usize]))
        .collect();
    let mut group = c.benchmark_group("pn");
    group.sample_size(20);
    for (pattern, level) in [(Pattern::Uniform, 16u32), (Pattern::Gl, 16)] {
        let opts = PnOptions {
            pattern,
            ..PnOptions::level(level)
        };
        let out = pn_triangles(&base.positions, &base.triangles, &normals, &opts, 1 << 26).unwrap();
        let n = out.mesh.triangles.len();
        eprintln!(
            "pn {pattern:?} level {level}: {} input -> {n} output triangles",
            base.triangles.len()
        );
        group.throughput(Throughput::Elements(n as u64));
        group.bench_function(format!("{pattern:?}_level_{level}"), |b| {
            b.iter(|| {
                pn_triangles(&base.positions, &base.triangles, &normals, &opts, 1 << 26).unwrap()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, grid, adaptive, pn);
criterion_main!(benches);
