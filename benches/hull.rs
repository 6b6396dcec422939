//! Convex hull benchmarks (issue 35's `convex_hull`, issue 38's rows):
//! Quickhull on points in the unit ball (few extreme: most points must be
//! discarded cheaply) and on the unit sphere (all extreme: the hull's own
//! growth), as `make bench-peers` runs them against qhull.
//!
//!     cargo bench --bench hull

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use glam::DVec3;

use graftal::geom::hull::convex_hull;

/// `n` points uniform in the unit ball, or on the unit sphere, from a
/// fixed counter-based stream (splitmix64), so every run sees the same.
fn points(n: usize, on_sphere: bool) -> Vec<DVec3> {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        2.0 * ((z >> 11) as f64 / (1u64 << 53) as f64) - 1.0
    };
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let p = DVec3::new(next(), next(), next());
        let r = p.length_squared();
        if !(1e-6..=1.0).contains(&r) {
            continue;
        }
        out.push(if on_sphere { p / r.sqrt() } else { p });
    }
    out
}

fn bench_hull(c: &mut Criterion) {
    let mut g = c.benchmark_group("convex_hull");
    g.sample_size(10);
    for (kind, on_sphere, sizes) in [
        ("ball", false, &[10_000usize, 100_000, 1_000_000][..]),
        ("sphere", true, &[10_000, 100_000][..]),
    ] {
        for &n in sizes {
            let cloud = points(n, on_sphere);
            g.bench_function(format!("{kind}_{n}"), |b| {
                b.iter(|| black_box(convex_hull(&cloud, false).unwrap()))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench_hull);
criterion_main!(benches);
