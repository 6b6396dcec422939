//! Tests of the parametric pillar: oracle values (geomdl, splinepy),
//! geometry (decomposition, knot insertion, topology), every tessellation
//! mode, PN triangles, and random garbage.

mod common;
mod garbage;
mod geometry;
mod oracle;
mod patchset;
mod pn;
mod tessellation;

use crate::nurbs::surface::NurbsSurface;
use crate::nurbs::tess::{tessellate, AdaptiveOptions, Mode};

#[test]
fn docs_example() {
    let mut points = Vec::new();
    for i in 0..4 {
        for j in 0..4 {
            let z = if (1..3).contains(&i) && (1..3).contains(&j) {
                1.0
            } else {
                0.0
            };
            points.push([i as f64, j as f64, z]);
        }
    }
    let surface = NurbsSurface::clamped([3, 3], [4, 4], &points, None).unwrap();
    let t = tessellate(
        &surface,
        &Mode::Adaptive(AdaptiveOptions::sagitta(1e-3)),
        1_000_000,
    )
    .unwrap();
    assert!(t.stats.max_deviation <= 1e-3);
    let census = t.mesh.edge_census();
    assert_eq!(census.non_manifold, 0);
    assert!(census.boundary.iter().all(|e| {
        let (a, b) = (t.mesh.uvs[e[0] as usize], t.mesh.uvs[e[1] as usize]);
        (0..2).any(|k| (a[k] == 0.0 && b[k] == 0.0) || (a[k] == 1.0 && b[k] == 1.0))
    }));
}
