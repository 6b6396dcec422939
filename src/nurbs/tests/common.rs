//! Shared fixtures and mesh checks for the integration tests.
#![allow(dead_code)]

use std::f64::consts::FRAC_1_SQRT_2;

use crate::nurbs::mesh::TriMesh;
use crate::nurbs::surface::NurbsSurface;

/// The peers' workload (peers.md §3): degree 3×3, 10×10 points, rational, clamped uniform.
pub fn peer_surface() -> NurbsSurface {
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

/// The thesis's Example 1.1.5 / Listing 1.2 Bézier patch (degrees 3, 2; 4×3 points).
pub fn example_115() -> NurbsSurface {
    let pts = [
        [4.0, 7.0, 11.0],
        [6.0, 8.0, 11.0],
        [5.0, 5.0, 5.0],
        [6.0, 8.0, 11.0],
        [7.0, 10.0, 12.0],
        [6.0, 11.0, 3.0],
        [7.0, 5.0, 3.0],
        [7.0, 7.0, 3.0],
        [7.0, 11.0, 6.0],
        [9.0, 7.0, 3.0],
        [9.0, 9.0, 0.0],
        [9.0, 11.0, 5.0],
    ];
    NurbsSurface::clamped([3, 2], [4, 3], &pts, None).unwrap()
}

/// Control points and weights of the exact rational quadratic unit circle (9 points).
pub fn circle() -> (Vec<[f64; 2]>, Vec<f64>, Vec<f64>) {
    use crate::nurbs::sweep::{circle_weight, CIRCLE, CIRCLE_KNOTS};
    (
        CIRCLE.to_vec(),
        (0..9).map(circle_weight).collect(),
        CIRCLE_KNOTS.to_vec(),
    )
}

/// Exact torus, major radius 3, minor radius 1: closed in both directions.
pub fn torus() -> NurbsSurface {
    let (c, w, k) = circle();
    let (big, small) = (3.0, 1.0);
    let mut pts = Vec::new();
    let mut ws = Vec::new();
    for i in 0..9 {
        for j in 0..9 {
            let rad = big + small * c[j][0];
            pts.push([rad * c[i][0], rad * c[i][1], small * c[j][1]]);
            ws.push(w[i] * w[j]);
        }
    }
    NurbsSurface::new([2, 2], [9, 9], &pts, Some(&ws), k.clone(), k).unwrap()
}

/// Unit cylinder of height 2: closed in u, open in v.
pub fn cylinder() -> NurbsSurface {
    let (c, w, k) = circle();
    let mut pts = Vec::new();
    let mut ws = Vec::new();
    for i in 0..9 {
        for z in [0.0, 2.0] {
            pts.push([c[i][0], c[i][1], z]);
            ws.push(w[i]);
        }
    }
    NurbsSurface::new([2, 1], [9, 2], &pts, Some(&ws), k, vec![0.0, 0.0, 1.0, 1.0]).unwrap()
}

/// Exact unit sphere: closed in u, poles at v = 0 and v = 1.
pub fn sphere() -> NurbsSurface {
    let (c, w, k) = circle();
    let semi = [[0.0, -1.0], [1.0, -1.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let sw = [1.0, FRAC_1_SQRT_2, 1.0, FRAC_1_SQRT_2, 1.0];
    let mut pts = Vec::new();
    let mut ws = Vec::new();
    for i in 0..9 {
        for j in 0..5 {
            pts.push([semi[j][0] * c[i][0], semi[j][0] * c[i][1], semi[j][1]]);
            ws.push(w[i] * sw[j]);
        }
    }
    NurbsSurface::new(
        [2, 2],
        [9, 5],
        &pts,
        Some(&ws),
        k,
        vec![0.0, 0.0, 0.0, 0.5, 0.5, 1.0, 1.0, 1.0],
    )
    .unwrap()
}

/// A bottle: a cubic profile revolved; closed in u, a pole at the bottom, open mouth on top.
pub fn bottle() -> NurbsSurface {
    let (c, w, k) = circle();
    let profile = [
        [0.0, 0.0],
        [1.0, 0.0],
        [1.2, 0.5],
        [1.0, 1.5],
        [0.4, 2.0],
        [0.4, 2.5],
    ];
    let mut pts = Vec::new();
    let mut ws = Vec::new();
    for i in 0..9 {
        for p in &profile {
            pts.push([p[0] * c[i][0], p[0] * c[i][1], p[1]]);
            ws.push(w[i]);
        }
    }
    let kv =
        crate::nurbs::knots::clamped_uniform(3, 6, crate::nurbs::error::Field::DegreeV).unwrap();
    NurbsSurface::new([2, 3], [9, 6], &pts, Some(&ws), k, kv).unwrap()
}

/// A periodic bicubic B-spline tube: 8 distinct rows wrapped (3 repeated), uniform unclamped
/// knots.
pub fn periodic_tube() -> NurbsSurface {
    let (n, p) = (8usize, 3usize);
    let mut pts = Vec::new();
    for i in 0..n + p {
        let a = std::f64::consts::TAU * (i % n) as f64 / n as f64;
        for j in 0..5 {
            let r = 1.0 + 0.2 * j as f64;
            pts.push([r * libm::cos(a), r * libm::sin(a), j as f64]);
        }
    }
    let ku = crate::nurbs::knots::periodic_uniform(p, n + p, crate::nurbs::error::Field::DegreeU)
        .unwrap();
    let kv =
        crate::nurbs::knots::clamped_uniform(3, 5, crate::nurbs::error::Field::DegreeV).unwrap();
    NurbsSurface::new([3, 3], [n + p, 5], &pts, None, ku, kv).unwrap()
}

/// What a conforming surface mesh must satisfy. `open_borders` lists which domain borders
/// [u_min, u_max, v_min, v_max] may carry boundary edges.
pub fn check_surface_mesh(mesh: &TriMesh, surface: &NurbsSurface, open_borders: [bool; 4]) {
    assert!(!mesh.has_non_finite(), "NaN or infinity in the mesh");
    assert!(mesh.max_normal_error() < 1e-12, "normals not unit");
    assert_eq!(mesh.positions.len(), mesh.uvs.len());
    assert_eq!(mesh.positions.len(), mesh.normals.len());
    let census = mesh.edge_census();
    assert_eq!(census.non_manifold, 0, "non-manifold edges");
    assert_eq!(census.misoriented, 0, "inconsistent orientation");
    assert_eq!(census.degenerate, 0, "degenerate triangles");
    let [[a, b], [c, d]] = surface.domain();
    for e in &census.boundary {
        let (p, q) = (mesh.uvs[e[0] as usize], mesh.uvs[e[1] as usize]);
        let on = |k: usize, uv: [f64; 2]| match k {
            0 => uv[0] == a,
            1 => uv[0] == b,
            2 => uv[1] == c,
            _ => uv[1] == d,
        };
        let ok = (0..4).any(|k| open_borders[k] && on(k, p) && on(k, q));
        assert!(
            ok,
            "boundary edge {:?} {:?} -> {:?} not on an open domain border",
            e, p, q
        );
    }
    // Welded: no two vertices share a position bit for bit.
    let mut keys: Vec<[u64; 3]> = mesh.positions.iter().map(|p| p.map(f64::to_bits)).collect();
    keys.sort_unstable();
    let before = keys.len();
    keys.dedup();
    assert_eq!(
        before,
        keys.len(),
        "duplicate vertex positions (unwelded seam or border)"
    );
    for t in &mesh.triangles {
        for &v in t {
            assert!((v as usize) < mesh.positions.len());
        }
    }
}

/// Fraction of triangles whose geometric normal agrees with the mean vertex normal.
pub fn orientation_agreement(mesh: &TriMesh) -> f64 {
    let mut good = 0usize;
    for t in &mesh.triangles {
        let p = t.map(|v| glam::DVec3::from_array(mesh.positions[v as usize]));
        let n = t.map(|v| glam::DVec3::from_array(mesh.normals[v as usize]));
        if (p[1] - p[0]).cross(p[2] - p[0]).dot(n[0] + n[1] + n[2]) > 0.0 {
            good += 1;
        }
    }
    good as f64 / mesh.triangles.len().max(1) as f64
}

/// Every triangle is counter-clockwise in (u, v) (so its normal agrees with S_u × S_v), after
/// unwrapping seams and giving pole vertices the mean free parameter of the other corners.
pub fn check_uv_orientation(mesh: &TriMesh, surface: &NurbsSurface) {
    let [[a, b], [c, d]] = surface.domain();
    let t = surface.topology();
    let (lo, hi) = ([a, c], [b, d]);
    for tri in &mesh.triangles {
        let mut uv = tri.map(|v| mesh.uvs[v as usize]);
        let free: Vec<Option<usize>> = uv
            .iter()
            .map(|p| {
                if (t.poles[0] && p[0] == a) || (t.poles[1] && p[0] == b) {
                    Some(1)
                } else if (t.poles[2] && p[1] == c) || (t.poles[3] && p[1] == d) {
                    Some(0)
                } else {
                    None
                }
            })
            .collect();
        for dim in 0..2 {
            let closed = if dim == 0 { t.closed_u } else { t.closed_v };
            let fixed: Vec<usize> = (0..3).filter(|&k| free[k] != Some(dim)).collect();
            if closed {
                let period = hi[dim] - lo[dim];
                let top = fixed
                    .iter()
                    .map(|&k| uv[k][dim])
                    .fold(f64::NEG_INFINITY, f64::max);
                for &k in &fixed {
                    if uv[k][dim] < top - 0.5 * period {
                        uv[k][dim] += period;
                    }
                }
            }
            if fixed.len() < 3 && !fixed.is_empty() {
                let mean = fixed.iter().map(|&k| uv[k][dim]).sum::<f64>() / fixed.len() as f64;
                for k in 0..3 {
                    if free[k] == Some(dim) {
                        uv[k][dim] = mean;
                    }
                }
            }
        }
        let area = (uv[1][0] - uv[0][0]) * (uv[2][1] - uv[0][1])
            - (uv[1][1] - uv[0][1]) * (uv[2][0] - uv[0][0]);
        assert!(
            area > 0.0,
            "triangle {tri:?} with uv {uv:?} is not counter-clockwise"
        );
    }
}
