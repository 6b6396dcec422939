//! PN triangles: geometry, watertightness, crease handling, counts, canonical output.

use crate::nurbs::pn::{
    gl_triangle_count, pn_triangles, Creases, Levels, NormalMode, Pattern, PnError, PnOptions,
};
use glam::DVec3;

const CAP: usize = 10_000_000;

fn octahedron() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let p = vec![
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    let t = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    (p, t)
}

/// Unit cube, 12 outward triangles.
fn cube() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut p = Vec::new();
    for i in 0..8 {
        p.push([(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64]);
    }
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let mut t = Vec::new();
    for q in quads {
        t.push([q[0], q[1], q[2]]);
        t.push([q[0], q[2], q[3]]);
    }
    (p, t)
}

fn smooth_normals(p: &[[f64; 3]], t: &[[u32; 3]], centre: DVec3) -> Vec<[[f64; 3]; 3]> {
    t.iter()
        .map(|tri| {
            tri.map(|v| {
                (DVec3::from_array(p[v as usize]) - centre)
                    .normalize()
                    .to_array()
            })
        })
        .collect()
}

fn face_normals(p: &[[f64; 3]], t: &[[u32; 3]]) -> Vec<[[f64; 3]; 3]> {
    t.iter()
        .map(|tri| {
            let q = tri.map(|v| DVec3::from_array(p[v as usize]));
            let n = (q[1] - q[0]).cross(q[2] - q[0]).normalize().to_array();
            [n, n, n]
        })
        .collect()
}

/// Closed and manifold after welding vertices by their point id.
fn welded_census(m: &crate::nurbs::pn::PnMesh) -> crate::nurbs::mesh::EdgeCensus {
    let mut welded = m.mesh.clone();
    for t in &mut welded.triangles {
        *t = t.map(|v| m.point_of_vertex[v as usize]);
    }
    welded.edge_census()
}

#[test]
fn octahedron_edge_midpoints_and_face_centres() {
    let (p, t) = octahedron();
    let n = smooth_normals(&p, &t, DVec3::ZERO);
    for pattern in [Pattern::Uniform, Pattern::Gl] {
        let opts = PnOptions {
            pattern,
            ..PnOptions::level(6)
        };
        let out = pn_triangles(&p, &t, &n, &opts, CAP).unwrap();
        // Edge midpoints: one zero coordinate, the other two equal in magnitude.
        let mut mids = 0;
        for q in &out.mesh.positions {
            let a = q.map(f64::abs);
            let nonzero: Vec<f64> = a.iter().copied().filter(|c| *c > 1e-15).collect();
            if nonzero.len() == 2 && (nonzero[0] - nonzero[1]).abs() < 1e-12 {
                assert!(
                    (DVec3::from_array(*q).length() - 5.0 * 2f64.sqrt() / 8.0).abs() < 1e-12,
                    "{q:?}"
                );
                mids += 1;
            }
        }
        assert_eq!(mids, 12, "{pattern:?}");
        assert!(welded_census(&out).is_closed_manifold());
        assert!(out.mesh.edge_census().is_closed_manifold());
    }
    let out = pn_triangles(&p, &t, &n, &PnOptions::level(3), CAP).unwrap();
    let centres = out
        .mesh
        .positions
        .iter()
        .map(|q| DVec3::from_array(*q))
        .filter(|q| {
            q.x.abs() > 0.1
                && (q.x.abs() - q.y.abs()).abs() < 1e-12
                && (q.y.abs() - q.z.abs()).abs() < 1e-12
        })
        .inspect(|q| {
            assert!(
                (q.length() - 4.0 * 3f64.sqrt() / 9.0).abs() < 1e-12,
                "{q:?}"
            )
        })
        .count();
    assert_eq!(centres, 8);
}

#[test]
fn flat_input_stays_flat() {
    // A planar fan with normals = the plane normal: PN control points stay in the plane.
    let p = vec![
        [0.0, 0.0, 1.0],
        [2.0, 0.0, 1.0],
        [2.0, 3.0, 1.0],
        [0.0, 2.0, 1.0],
        [-1.0, 1.0, 1.0],
    ];
    let t = vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]];
    let n = vec![[[0.0, 0.0, 1.0]; 3]; 3];
    for pattern in [Pattern::Uniform, Pattern::Gl] {
        let out = pn_triangles(
            &p,
            &t,
            &n,
            &PnOptions {
                pattern,
                ..PnOptions::level(7)
            },
            CAP,
        )
        .unwrap();
        for q in &out.mesh.positions {
            assert!((q[2] - 1.0).abs() < 1e-14, "{q:?}");
        }
        for nn in &out.mesh.normals {
            assert_eq!(*nn, [0.0, 0.0, 1.0]);
        }
        let c = out.mesh.edge_census();
        assert_eq!(c.non_manifold + c.misoriented + c.degenerate, 0);
    }
}

#[test]
fn counts_follow_the_patterns() {
    // Spec §2.7.2: T(1…6) = 1, 6, 13, 24, 37, 54; T(10) = 150; T(51) = 3901.
    let expected = [
        (1, 1),
        (2, 6),
        (3, 13),
        (4, 24),
        (5, 37),
        (6, 54),
        (10, 150),
        (51, 3901),
    ];
    for (n, t) in expected {
        assert_eq!(gl_triangle_count(n, [n; 3]), t);
        let m = n as u128;
        let formula = if n % 2 == 0 {
            6 * (m / 2) * (m / 2)
        } else {
            (3 * m * m - 1) / 2
        };
        assert_eq!(t, formula);
    }
    assert_eq!(gl_triangle_count(5, [4, 1, 6]), 33);
    let (p, t) = cube();
    let n = face_normals(&p, &t);
    for (level, count) in [(5, 444), (10, 1800), (51, 46_812)] {
        let out = pn_triangles(
            &p,
            &t,
            &n,
            &PnOptions {
                pattern: Pattern::Gl,
                ..PnOptions::level(level)
            },
            CAP,
        )
        .unwrap();
        assert_eq!(out.mesh.triangles.len(), count);
        assert!(welded_census(&out).is_closed_manifold(), "gl {level}");
    }
    for level in [1, 2, 5, 8] {
        let out = pn_triangles(&p, &t, &n, &PnOptions::level(level), CAP).unwrap();
        assert_eq!(out.mesh.triangles.len(), 12 * (level * level) as usize);
        let l = level as usize;
        // welded points: 8 corners + 18 edges·(l−1) + 12 faces·(l−1)(l−2)/2
        assert_eq!(
            out.points,
            8 + 18 * (l - 1) + 12 * (l - 1) * (l.saturating_sub(2)) / 2
        );
    }
}

#[test]
fn creases_do_not_open_the_mesh() {
    // Flat-shaded cube: every vertex has three normals and every edge is a crease.
    let (p, t) = cube();
    let n = face_normals(&p, &t);
    for creases in [Creases::SmoothGeometry, Creases::Keep] {
        for pattern in [Pattern::Uniform, Pattern::Gl] {
            let opts = PnOptions {
                creases,
                pattern,
                ..PnOptions::level(6)
            };
            let out = pn_triangles(&p, &t, &n, &opts, CAP).unwrap();
            assert!(
                welded_census(&out).is_closed_manifold(),
                "{creases:?} {pattern:?}"
            );
            // Vertices sharing a point are bit-identical.
            let mut first = vec![None; out.points];
            for (v, &pt) in out.point_of_vertex.iter().enumerate() {
                let q = out.mesh.positions[v];
                match first[pt as usize] {
                    None => first[pt as usize] = Some(q),
                    Some(f) => assert_eq!(f, q),
                }
            }
            assert!(!out.mesh.has_non_finite());
            assert!(out.mesh.max_normal_error() < 1e-12);
        }
    }
    // Keep: a crease edge stays straight, so the cube keeps its edges.
    let out = pn_triangles(
        &p,
        &t,
        &n,
        &PnOptions {
            creases: Creases::Keep,
            ..PnOptions::level(4)
        },
        CAP,
    )
    .unwrap();
    for q in &out.mesh.positions {
        assert!(q.iter().all(|c| (-1e-12..=1.0 + 1e-12).contains(c)));
    }
}

#[test]
fn closed_smooth_input_stays_closed_and_unwelded_topology_too() {
    let (p, t) = octahedron();
    let n = smooth_normals(&p, &t, DVec3::ZERO);
    let opts = PnOptions {
        levels: Levels::Auto {
            max_edge: 0.3,
            max_angle: 0.2,
            max_level: 16,
        },
        ..PnOptions::level(1)
    };
    for pattern in [Pattern::Uniform, Pattern::Gl] {
        let out = pn_triangles(&p, &t, &n, &PnOptions { pattern, ..opts }, CAP).unwrap();
        let c = out.mesh.edge_census();
        assert!(
            c.is_closed_manifold(),
            "{pattern:?} {:?}",
            (
                c.boundary.len(),
                c.non_manifold,
                c.misoriented,
                c.degenerate
            )
        );
    }
    // Differing outer levels on one mesh (an irregular mesh: edge lengths differ).
    let mut q = p.clone();
    q[4] = [0.0, 0.0, 2.5];
    let n = smooth_normals(&q, &t, DVec3::ZERO);
    for pattern in [Pattern::Uniform, Pattern::Gl] {
        let out = pn_triangles(&q, &t, &n, &PnOptions { pattern, ..opts }, CAP).unwrap();
        assert!(out.mesh.edge_census().is_closed_manifold(), "{pattern:?}");
        assert!(!out.mesh.has_non_finite());
    }
}

#[test]
fn triangle_order_does_not_change_the_bytes() {
    let (p, t) = cube();
    let n = smooth_normals(&p, &t, DVec3::splat(0.5));
    let opts = PnOptions {
        normals: NormalMode::Quadratic,
        ..PnOptions::level(5)
    };
    let a = pn_triangles(&p, &t, &n, &opts, CAP).unwrap();
    // Reverse the order and rotate every triangle's corners.
    let mut t2: Vec<[u32; 3]> = t.iter().rev().map(|x| [x[1], x[2], x[0]]).collect();
    let mut n2: Vec<[[f64; 3]; 3]> = n.iter().rev().map(|x| [x[1], x[2], x[0]]).collect();
    let b = pn_triangles(&p, &t2, &n2, &opts, CAP).unwrap();
    assert_eq!(a, b);
    t2.swap(0, 5);
    n2.swap(0, 5);
    let c = pn_triangles(&p, &t2, &n2, &opts, CAP).unwrap();
    assert_eq!(a, c);
    // And at any thread count.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let d = pool.install(|| pn_triangles(&p, &t, &n, &opts, CAP).unwrap());
    assert_eq!(a, d);
}

#[test]
fn bad_input_gives_typed_errors() {
    let (p, t) = cube();
    let n = face_normals(&p, &t);
    assert!(matches!(
        pn_triangles(&p, &t, &n[..3], &PnOptions::level(2), CAP),
        Err(PnError::NormalCount { .. })
    ));
    let mut bad = t.clone();
    bad[4][1] = 99;
    assert!(matches!(
        pn_triangles(&p, &bad, &n, &PnOptions::level(2), CAP),
        Err(PnError::IndexOutOfRange {
            triangle: 4,
            corner: 1,
            ..
        })
    ));
    bad[4] = [1, 1, 2];
    assert!(matches!(
        pn_triangles(&p, &bad, &n, &PnOptions::level(2), CAP),
        Err(PnError::DegenerateTriangle { triangle: 4 })
    ));
    let mut nn = n.clone();
    nn[2][0] = [0.0; 3];
    assert!(matches!(
        pn_triangles(&p, &t, &nn, &PnOptions::level(2), CAP),
        Err(PnError::BadNormal {
            triangle: 2,
            corner: 0
        })
    ));
    let mut pp = p.clone();
    pp[3][0] = f64::INFINITY;
    assert!(matches!(
        pn_triangles(&pp, &t, &n, &PnOptions::level(2), CAP),
        Err(PnError::PositionNotFinite { vertex: 3 })
    ));
    for bad in [0, crate::nurbs::pn::MAX_PN_LEVEL + 1] {
        assert!(matches!(
            pn_triangles(&p, &t, &n, &PnOptions::level(bad), CAP),
            Err(PnError::InvalidOption { .. })
        ));
    }
    assert!(matches!(
        pn_triangles(&p, &t, &n, &PnOptions::level(64), 1000),
        Err(PnError::TriangleLimit { needed: 49_152, .. })
    ));
}
