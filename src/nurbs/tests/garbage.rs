//! Random garbage in, typed errors (or valid output) out: never a panic, never NaN.

use crate::nurbs::curve::NurbsCurve;
use crate::nurbs::pn::{pn_triangles, Levels, Pattern, PnOptions};
use crate::nurbs::surface::NurbsSurface;
use crate::nurbs::tess::{tessellate, AdaptiveOptions, Diagonal, EdgeTest, Initial, Mode};
use proptest::prelude::*;

fn float() -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => -10.0f64..10.0,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(0.0),
        1 => Just(-1.0),
        1 => Just(1e300),
    ]
}

fn weight() -> impl Strategy<Value = f64> {
    prop_oneof![8 => 0.1f64..4.0, 1 => Just(0.0), 1 => Just(-2.0), 1 => Just(f64::NAN)]
}

#[derive(Debug, Clone)]
struct Raw {
    degree: [usize; 2],
    size: [usize; 2],
    points: Vec<[f64; 3]>,
    weights: Option<Vec<f64>>,
    knots: [Option<Vec<f64>>; 2],
}

/// A clean random surface, then at most one corruption (none half of the time).
fn raw_surface() -> impl Strategy<Value = Raw> {
    (
        prop_oneof![6 => 1usize..4, 1 => 0usize..100],
        prop_oneof![6 => 1usize..4, 1 => 0usize..100],
        1usize..8,
        1usize..8,
    )
        .prop_flat_map(|(p, q, nu, nv)| {
            let n = nu * nv;
            (
                Just([p, q]),
                Just([nu, nv]),
                prop::collection::vec(
                    (-5.0f64..5.0, -5.0f64..5.0, -5.0f64..5.0).prop_map(|(a, b, c)| [a, b, c]),
                    n..=n,
                ),
                prop::option::of(prop::collection::vec(0.2f64..4.0, n..=n)),
                any::<bool>(),
                0usize..12,
                any::<prop::sample::Index>(),
                float(),
                weight(),
            )
        })
        .prop_map(
            |(degree, size, mut points, mut weights, uniform_knots, corruption, at, x, w)| {
                let mut knots: [Option<Vec<f64>>; 2] = [None, None];
                if !uniform_knots {
                    // Explicit non-uniform clamped knots.
                    for d in 0..2 {
                        let (p, n) = (degree[d], size[d]);
                        if n > p && p <= 8 {
                            let mut k = vec![0.0; p + 1];
                            for i in 1..n - p {
                                k.push(i as f64 * i as f64);
                            }
                            let last = ((n - p) * (n - p)) as f64;
                            k.extend(std::iter::repeat_n(last, p + 1));
                            knots[d] = Some(k);
                        }
                    }
                }
                match corruption {
                    0 => {
                        let i = at.index(points.len());
                        points[i][at.index(3)] = x;
                    }
                    1 => {
                        let len = points.len();
                        weights.get_or_insert_with(|| vec![1.0; len])[at.index(len)] = w;
                    }
                    2 => {
                        if let Some(k) = knots[0].as_mut() {
                            let i = at.index(k.len());
                            k[i] = x;
                        }
                    }
                    3 => {
                        if let Some(k) = knots[1].as_mut() {
                            k.truncate(at.index(k.len()));
                        }
                    }
                    4 => {
                        points.pop();
                    }
                    5 => {
                        if let Some(k) = knots[0].as_mut() {
                            let last = k.len() - 1;
                            k.swap(0, last);
                        }
                    }
                    _ => {}
                }
                Raw {
                    degree,
                    size,
                    points,
                    weights,
                    knots,
                }
            },
        )
}

fn build(r: &Raw) -> Option<NurbsSurface> {
    let w = r.weights.as_deref();
    let s = match (&r.knots[0], &r.knots[1]) {
        (Some(a), Some(b)) => {
            NurbsSurface::new(r.degree, r.size, &r.points, w, a.clone(), b.clone())
        }
        _ => NurbsSurface::clamped(r.degree, r.size, &r.points, w),
    };
    match s {
        Ok(s) => Some(s),
        Err(e) => {
            // Every error renders a message naming something.
            assert!(!e.to_string().is_empty());
            None
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, .. ProptestConfig::default() })]

    #[test]
    fn surfaces_never_panic(r in raw_surface(), u in float(), v in float(), cells in 0usize..6, eps in float()) {
        if let Some(s) = build(&r) {
            let _ = s.point(u, v);
            let _ = s.derivatives(u, v);
            if let Ok(n) = s.normal(u, v) {
                prop_assert!(n.is_finite());
            }
            let _ = s.decompose();
            let modes = [
                Mode::Uniform { cells: [cells, cells + 1], per_patch: cells % 2 == 0, diagonal: if cells % 3 == 0 { Diagonal::Best } else { Diagonal::Fixed } },
                Mode::InterPatch { tolerance: eps },
                Mode::Adaptive(AdaptiveOptions::sagitta(eps)),
                Mode::Adaptive(AdaptiveOptions {
                    tests: vec![EdgeTest::UmbrellaFlat { t: 0.1 }, EdgeTest::FirstOrderNeighbour { t3: 0.01 }],
                    initial: Initial::InterPatch { tolerance: 0.5 },
                    max_level: 30,
                    ..AdaptiveOptions::sagitta(0.1)
                }),
            ];
            for mode in &modes {
                if let Ok(t) = tessellate(&s, mode, 20_000) {
                    prop_assert!(!t.mesh.has_non_finite());
                    prop_assert!(t.mesh.triangles.len() <= 20_000);
                    prop_assert!(t.stats.max_deviation.is_finite());
                }
            }
        }
    }

    #[test]
    fn curves_never_panic(p in prop_oneof![4 => 1usize..5, 1 => 0usize..200], pts in prop::collection::vec((float(), float(), float()), 0..10), knots in prop::option::of(prop::collection::vec(float(), 0..20)), u in float(), x in float()) {
        let pts: Vec<[f64; 3]> = pts.into_iter().map(|(a, b, c)| [a, b, c]).collect();
        let c = match knots {
            Some(k) => NurbsCurve::new(p, k, &pts, None),
            None => NurbsCurve::clamped(p, &pts, None),
        };
        if let Ok(c) = c {
            let _ = c.point(u);
            let _ = c.derivatives(u);
            let _ = c.insert_knot(x, 1);
            let _ = c.to_bezier();
        }
    }

    #[test]
    fn pn_never_panics(pos in prop::collection::vec((float(), float(), float()), 0..8), tris in prop::collection::vec((0u32..9, 0u32..9, 0u32..9), 0..8), normals in prop::collection::vec((float(), float(), float()), 0..30), level in prop_oneof![4 => 1u32..6, 1 => 0u32..100_000], gl in any::<bool>()) {
        let pos: Vec<[f64; 3]> = pos.into_iter().map(|(a, b, c)| [a, b, c]).collect();
        let tris: Vec<[u32; 3]> = tris.into_iter().map(|(a, b, c)| [a, b, c]).collect();
        let ns: Vec<[[f64; 3]; 3]> = normals.chunks_exact(3).map(|c| [[c[0].0, c[0].1, c[0].2], [c[1].0, c[1].1, c[1].2], [c[2].0, c[2].1, c[2].2]]).collect();
        let ns: Vec<[[f64; 3]; 3]> = (0..tris.len()).map(|k| ns.get(k).copied().unwrap_or([[0.0, 0.0, 1.0]; 3])).collect();
        let pattern = if gl { Pattern::Gl } else { Pattern::Uniform };
        for levels in [Levels::Fixed(level), Levels::Auto { max_edge: 0.01, max_angle: 0.01, max_level: level.max(1) }] {
            let opts = PnOptions { levels, pattern, ..PnOptions::level(1) };
            if let Ok(out) = pn_triangles(&pos, &tris, &ns, &opts, 50_000) {
                prop_assert!(!out.mesh.has_non_finite());
                prop_assert!(out.mesh.triangles.len() <= 50_000);
            }
        }
    }
}
