//! Knot insertion, Bézier decomposition, topology detection, validation.

use super::common;

use crate::nurbs::error::{Dir, Field, NurbsError};
use crate::nurbs::surface::{NurbsSurface, Topology};
use glam::DVec3;

/// Deterministic pseudo-random parameters (SplitMix64).
fn randoms(n: usize, seed: u64) -> Vec<f64> {
    let mut x = seed;
    (0..n)
        .map(|_| {
            x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = x;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^= z >> 31;
            (z >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
        })
        .collect()
}

fn all_fixtures() -> Vec<(&'static str, NurbsSurface)> {
    vec![
        ("peer", common::peer_surface()),
        ("example_115", common::example_115()),
        ("torus", common::torus()),
        ("sphere", common::sphere()),
        ("bottle", common::bottle()),
        ("periodic", common::periodic_tube()),
    ]
}

#[test]
fn decomposition_equals_the_nurbs() {
    for (name, s) in all_fixtures() {
        let net = s.decompose().unwrap();
        let [[a, b], [c, d]] = s.domain();
        let patches = net.all_patches();
        assert_eq!(patches.len(), net.patches[0] * net.patches[1]);
        let r = randoms(400, 7);
        for k in 0..200 {
            let (u, v) = (a + (b - a) * r[2 * k], c + (d - c) * r[2 * k + 1]);
            let pa = net
                .breaks_u
                .partition_point(|&x| x <= u)
                .clamp(1, net.patches[0])
                - 1;
            let pb = net
                .breaks_v
                .partition_point(|&x| x <= v)
                .clamp(1, net.patches[1])
                - 1;
            let patch = net.patch(pa, pb);
            let expected = s.point(u, v).unwrap();
            let got = patch.point(u, v);
            let scale = s.net_diagonal().max(1.0);
            assert!(
                (expected - got).length() < 1e-12 * scale,
                "{name}: {expected:?} vs {got:?}"
            );
        }
    }
    // Spec §2.2.4: the peers' surface gives 7 × 7 bicubic patches on a 22 × 22 net.
    let net = common::peer_surface().decompose().unwrap();
    assert_eq!(net.patches, [7, 7]);
    assert_eq!(net.net.len(), 22 * 22);
}

#[test]
fn knot_insertion_leaves_the_surface_unchanged() {
    let s = common::peer_surface();
    let s2 = s
        .insert_knot(Dir::U, 0.31, 2)
        .unwrap()
        .insert_knot(Dir::V, 4.0 / 7.0, 1)
        .unwrap();
    assert_eq!(s2.size(), [12, 11]);
    let r = randoms(200, 11);
    for k in 0..100 {
        let (u, v) = (r[2 * k], r[2 * k + 1]);
        let (p, q) = (s.point(u, v).unwrap(), s2.point(u, v).unwrap());
        assert!((p - q).length() < 1e-12, "{p:?} vs {q:?}");
    }
    // Multiplicity beyond the degree is refused with a typed error.
    assert!(matches!(
        s.insert_knot(Dir::U, 0.31, 4),
        Err(NurbsError::InsertionFull {
            field: Field::KnotsU,
            ..
        })
    ));
    assert!(matches!(
        s.insert_knot(Dir::V, 2.0, 1),
        Err(NurbsError::KnotOutsideDomain { .. })
    ));
    assert!(matches!(
        s.insert_knot(Dir::V, f64::NAN, 1),
        Err(NurbsError::ParameterNotFinite { .. })
    ));
}

#[test]
fn topology_is_detected() {
    let t = common::torus().topology();
    assert!(t.closed_u && t.closed_v && t.poles == [false; 4]);
    let t = common::cylinder().topology();
    assert!(t.closed_u && !t.closed_v && t.poles == [false; 4]);
    let t = common::sphere().topology();
    assert!(t.closed_u && !t.closed_v && t.poles == [false, false, true, true]);
    let t = common::bottle().topology();
    assert!(t.closed_u && !t.closed_v && t.poles == [false, false, true, false]);
    let t = common::peer_surface().topology();
    assert_eq!(t, Topology::default());
    assert!(common::periodic_tube().topology().closed_u);
    // Declaring a closure that is not there is refused.
    let bad = common::peer_surface().with_topology(Topology {
        closed_u: true,
        ..Topology::default()
    });
    assert!(matches!(
        bad,
        Err(NurbsError::NotClosed { dir: Dir::U, .. })
    ));
}

#[test]
fn sphere_is_round_and_normals_point_outward() {
    let s = common::sphere();
    let r = randoms(200, 3);
    for k in 0..100 {
        let p = s.point(r[2 * k], r[2 * k + 1]).unwrap();
        assert!((p.length() - 1.0).abs() < 1e-12);
        let n = s.normal(r[2 * k], r[2 * k + 1]).unwrap();
        assert!(n.dot(p) > 0.999 || n.dot(p) < -0.999);
    }
    // Poles: finite unit normals along the axis.
    for v in [0.0, 1.0] {
        let n = s.normal(0.3, v).unwrap();
        assert!(n.is_finite() && (n.length() - 1.0).abs() < 1e-12);
        assert!(n.cross(DVec3::Z).length() < 1e-3, "{n:?}");
    }
}

#[test]
fn validation_names_the_field_and_index() {
    let pts = vec![[0.0, 0.0, 0.0]; 16];
    let e = NurbsSurface::new(
        [3, 3],
        [4, 4],
        &pts,
        None,
        vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0],
        vec![0.0; 8],
    );
    assert!(matches!(
        e,
        Err(NurbsError::KnotMultiplicity {
            field: Field::KnotsV,
            index: 4,
            multiplicity: 8,
            max: 4,
            ..
        })
    ));
    let e = NurbsSurface::new(
        [3, 3],
        [4, 4],
        &pts,
        None,
        vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
        vec![0.0; 8],
    );
    assert!(matches!(
        e,
        Err(NurbsError::KnotCount {
            field: Field::KnotsU,
            expected: 8,
            found: 7
        })
    ));
    let mut w = vec![1.0; 16];
    w[5] = 0.0;
    let e = NurbsSurface::clamped([3, 3], [4, 4], &pts, Some(&w));
    assert!(matches!(e, Err(NurbsError::WeightInvalid { index: 5, .. })));
    let mut p2 = pts.clone();
    p2[9][2] = f64::NAN;
    let e = NurbsSurface::clamped([3, 3], [4, 4], &p2, None);
    assert!(matches!(
        e,
        Err(NurbsError::PointNotFinite {
            index: 9,
            component: 2
        })
    ));
    let e = NurbsSurface::clamped([4, 3], [4, 4], &pts, None);
    assert!(matches!(
        e,
        Err(NurbsError::TooFewPoints {
            field: Field::DegreeU,
            ..
        })
    ));
    let e = NurbsSurface::clamped([3, 3], [4, 4], &pts[..15], None);
    assert!(matches!(e, Err(NurbsError::NetShape { .. })));
    let e = NurbsSurface::new(
        [2, 3],
        [4, 4],
        &pts,
        None,
        vec![0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 1.0],
        crate::nurbs::knots::clamped_uniform(3, 4, Field::DegreeV).unwrap(),
    );
    assert!(matches!(
        e,
        Err(NurbsError::KnotMultiplicity {
            field: Field::KnotsU,
            index: 5,
            multiplicity: 3,
            max: 2,
            ..
        })
    ));
    // The message names the rule-file field.
    assert_eq!(
        NurbsError::KnotDecreasing {
            field: Field::KnotsV,
            index: 4,
            value: 0.1,
            previous: 0.5
        }
        .to_string(),
        "knots_v[4]: knot 0.1 is smaller than the previous knot 0.5"
    );
}
