//! Reference values from geomdl 5.4.0 / splinepy 0.2.1 (src/nurbs/tests/oracle_gen.py); the numbers are
//! committed, Python is not needed to run the tests.

use super::common;

use crate::nurbs::curve::NurbsCurve;
use glam::DVec3;

/// u, v, S, Su, Sv, Suu, Suv, Svv, unit normal (geomdl `derivatives(order=2)`, `operations.normal`).
const PEER: [[f64; 23]; 7] = [
    [
        0.3,
        0.6,
        3.049784615371517,
        5.140605009557634,
        -1.2761697831512313,
        6.226358482322168,
        -0.17292748015506448,
        3.7097660413332347,
        -0.17682367788228434,
        6.182280418205452,
        -2.158854006358439,
        5.331239514208152,
        13.678769783850681,
        28.8540930008808,
        13.666954648371583,
        9.939846029933536,
        11.005135142055432,
        9.594154716230005,
        12.012795511422208,
        18.765051109765924,
        -0.4863628776213521,
        0.27562677488910703,
        0.829144759517967,
    ],
    [
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        31.5,
        0.0,
        40.58571429597453,
        0.0,
        31.5,
        0.0,
        -735.0,
        0.0,
        -1125.1555591977158,
        -110.25,
        -110.25,
        -281.16517673886005,
        0.0,
        -735.0,
        0.0,
        -0.7899806564625214,
        0.0,
        0.6131317659484328,
    ],
    [
        1.0,
        1.0,
        9.0,
        9.0,
        -0.0070885991882961435,
        42.0,
        0.0,
        -11.475463034987664,
        0.0,
        42.0,
        0.6254639327397477,
        2204.999999999999,
        0.0,
        -630.0614092916804,
        1102.5,
        1102.5,
        94.88991870159984,
        0.0,
        2204.999999999999,
        34.02350299295043,
        0.2635373538652085,
        -0.014363961547329149,
        0.9645422436194232,
    ],
    [
        0.5,
        0.5,
        4.462679647658784,
        4.462679647658785,
        0.009521567901267734,
        7.519767771005291,
        1.0941766722570305,
        5.826056054443786,
        1.0941766722570203,
        7.519767771005284,
        0.9877665582298288,
        12.584970175324155,
        8.188476049074772,
        7.675906153847529,
        7.314940134373263,
        7.314940134373263,
        29.89669366407179,
        8.188476049074843,
        12.584970175324155,
        3.949169254409275,
        -0.6110162742863183,
        -0.015057990538130946,
        0.7914748065972915,
    ],
    [
        0.123,
        0.987,
        1.7665694906661145,
        8.779004964789086,
        -0.5322804177311776,
        7.94217620668519,
        -0.31947217026468555,
        -1.4545954251258564,
        -1.7439784728907424,
        17.075034896288685,
        12.525040134333821,
        -54.40882730228074,
        -13.12763565337954,
        20.756552297235647,
        -41.303618205898374,
        8.241502014992264,
        39.287866148379,
        -52.26744892142046,
        -2.540759345024481,
        53.003102639450134,
        0.12435960347701461,
        -0.5785856012523012,
        0.8060852256719216,
    ],
    [
        0.9,
        0.05,
        7.440440821075421,
        0.8335965533672377,
        -1.3801638282165503,
        10.310315132141302,
        -0.3709193427109785,
        5.947481224182906,
        -1.174408207811341,
        15.072828748485636,
        4.310579977894568,
        89.44785759623224,
        23.808085681437703,
        125.28410873227793,
        28.651195635260706,
        40.18460008940747,
        9.61183300947216,
        60.0674182862797,
        -71.74395263016596,
        56.50817288034782,
        -0.4878180496555536,
        -0.2749500410212253,
        0.8285143483203405,
    ],
    [
        0.14285714285714285,
        0.42857142857142855,
        1.8676470588235292,
        3.9705882352941173,
        -0.6574202959186833,
        10.027681660899653,
        0.5813148788927334,
        -1.579033018774795,
        0.638840830449826,
        7.805363321799304,
        -6.132573133399887,
        -9.559637695908805,
        11.100549562385508,
        11.307671082221873,
        10.861184612253203,
        19.02951353551801,
        -21.283247252447904,
        16.048671890901694,
        1.50351109301848,
        2.713797602063349,
        0.08847311846782477,
        0.610898245396405,
        0.7867501770448939,
    ],
];

/// u, v, S, Su, Sv, Suu, Suv, Svv of the thesis's Example 1.1.5 patch.
const EX115: [[f64; 20]; 5] = [
    [
        0.0, 0.0, 4.0, 7.0, 11.0, 6.0, 3.0, 0.0, 4.0, 2.0, 0.0, -6.0, -24.0, -48.0, -6.0, 6.0, 6.0,
        -6.0, -8.0, -12.0,
    ],
    [
        0.25,
        0.75,
        6.0556640625,
        8.4794921875,
        6.8232421875,
        2.87109375,
        5.75390625,
        -4.04296875,
        -0.6328125,
        0.4140625,
        -8.5546875,
        0.09375,
        -21.46875,
        -5.71875,
        0.28125,
        15.46875,
        13.21875,
        -4.21875,
        -3.65625,
        -12.40625,
    ],
    [
        0.5, 0.5, 6.84375, 8.46875, 6.40625, 3.1875, -0.1875, -9.9375, 0.125, 3.625, -2.375, 2.25,
        -3.75, -5.25, -0.75, 6.75, 14.25, -2.25, -0.25, -4.75,
    ],
    [
        1.0, 1.0, 9.0, 11.0, 5.0, 6.0, 0.0, -3.0, 0.0, 4.0, 10.0, 6.0, 0.0, -24.0, 0.0, -12.0,
        12.0, 0.0, 0.0, 16.0,
    ],
    [
        0.8,
        0.1,
        7.924240000000001,
        6.732800000000001,
        3.5864,
        4.844400000000003,
        1.098000000000002,
        -8.784000000000002,
        0.18080000000000185,
        4.112,
        -2.032,
        4.476000000000003,
        18.720000000000013,
        26.220000000000006,
        -1.7519999999999993,
        0.12000000000000108,
        -8.880000000000003,
        -0.4320000000000057,
        1.2799999999999976,
        8.480000000000002,
    ],
];

const EX115_NORMALS: [[f64; 5]; 2] = [
    [
        0.25,
        0.75,
        -0.8652824352819339,
        0.4935188751140143,
        0.0878944088026296,
    ],
    [
        0.5,
        0.5,
        0.9403448721035462,
        0.1631703826914894,
        0.29854136685035465,
    ],
];

/// Listing 1.1 (Bézier, degree 2): u, C, C', C'' (2D).
const L11: [[f64; 7]; 5] = [
    [0.0, 0.0, 0.0, 20.0, 30.0, 0.0, -60.0],
    [0.1, 2.0000000000000004, 2.7, 20.0, 24.0, 0.0, -60.0],
    [0.5, 10.0, 7.5, 20.0, 0.0, 0.0, -60.0],
    [0.77, 15.4, 5.313, 20.0, -16.200000000000003, 0.0, -60.0],
    [1.0, 20.0, 0.0, 20.0, -30.0, 0.0, -60.0],
];

/// Listing 1.5 (NURBS, degree 2, knots 0..9): t (geomdl normalises knots to [0, 1]), C, C', C''
/// with respect to t. graftal keeps the knots as given: u = 9t, C'(u) = C'(t)/9, C''(u) = C''(t)/81.
const L15: [[f64; 7]; 5] = [
    [0.2222222222222222, -2.0, 4.0, 18.0, 18.0, 81.0, 0.0],
    [
        0.3,
        -0.35500000000000004,
        5.4,
        24.3,
        18.000000000000004,
        81.00000000000001,
        0.0,
    ],
    [
        0.5,
        3.2500000000000004,
        0.8750000000000004,
        18.000000000000004,
        -31.5,
        161.99999999999997,
        566.9999999999997,
    ],
    [
        0.61,
        5.84995,
        0.48019999999999946,
        22.589999999999996,
        17.639999999999993,
        -80.99999999999999,
        324.0000000000001,
    ],
    [
        0.7777777777777778,
        9.0,
        3.249999999999999,
        18.0,
        -13.5,
        0.0,
        -445.4999999999998,
    ],
];

fn close(a: DVec3, b: &[f64], tol: f64, what: &str) {
    let b = DVec3::new(b[0], b[1], b[2]);
    let scale = 1.0f64.max(b.length());
    assert!((a - b).length() <= tol * scale, "{what}: {a:?} vs {b:?}");
}

#[test]
fn peer_surface_point_matches_geomdl_splinepy_and_ocp() {
    let s = common::peer_surface();
    let p = s.point(0.3, 0.6).unwrap();
    // peers.md: (3.0497846, 5.1406050, −1.2761698) in geomdl, splinepy and OCP.
    let expected = DVec3::new(3.0497846154, 5.1406050096, -1.2761697832);
    assert!((p - expected).abs().max_element() < 1e-7, "{p:?}");
    close(
        p,
        &[3.049784615371517, 5.140605009557634, -1.2761697831512313],
        1e-12,
        "splinepy",
    );
}

#[test]
fn peer_surface_derivatives_and_normals_match_geomdl() {
    let s = common::peer_surface();
    for r in PEER {
        let d = s.derivatives(r[0], r[1]).unwrap();
        close(d.s, &r[2..5], 1e-12, "S");
        close(d.su, &r[5..8], 1e-11, "Su");
        close(d.sv, &r[8..11], 1e-11, "Sv");
        close(d.suu, &r[11..14], 1e-10, "Suu");
        close(d.suv, &r[14..17], 1e-10, "Suv");
        close(d.svv, &r[17..20], 1e-10, "Svv");
        close(s.normal(r[0], r[1]).unwrap(), &r[20..23], 1e-10, "normal");
    }
}

#[test]
fn peer_grid_sums_match_curvo_and_ocp() {
    // peers.md: Σz over the closed-[0,1]² grid is 9.705 at 100² and 1016.447 at 1000²
    // (splinepy: 9.705059104123848 and 1016.4470210365253).
    let s = common::peer_surface();
    for (n, expected) in [(100usize, 9.705059104123848), (1000, 1016.4470210365253)] {
        let ts: Vec<f64> = (0..n).map(|k| k as f64 / (n - 1) as f64).collect();
        let g = s.grid(&ts, &ts, false).unwrap();
        let sum: f64 = g.points.iter().map(|p| p[2]).sum();
        // numpy sums pairwise, this loop sequentially: allow rounding of 1e6 terms.
        assert!((sum - expected).abs() < 1e-7, "{n}: {sum}");
    }
}

#[test]
fn grid_equals_pointwise_evaluation() {
    let s = common::peer_surface();
    let us: Vec<f64> = (0..37).map(|k| k as f64 / 36.0).collect();
    let vs: Vec<f64> = (0..23).map(|k| (k as f64 / 22.0).powi(2)).collect();
    let g = s.grid(&us, &vs, true).unwrap();
    for (i, &u) in us.iter().enumerate() {
        for (j, &v) in vs.iter().enumerate() {
            let p = s.point(u, v).unwrap();
            let n = s.normal(u, v).unwrap();
            let k = i * vs.len() + j;
            assert!((p - DVec3::from_array(g.points[k])).length() < 1e-12);
            assert!((n - DVec3::from_array(g.normals[k])).length() < 1e-10);
        }
    }
}

#[test]
fn grid_rows_max_equals_the_maximum_over_the_stored_grid() {
    let s = common::peer_surface();
    // 37 × 23 samples a row per call in turn; 250 × 180 (past 2^15) a row per task.
    for (nu, nv) in [(37usize, 23usize), (250, 180)] {
        let us: Vec<f64> = (0..nu).map(|k| k as f64 / (nu - 1) as f64).collect();
        let vs: Vec<f64> = (0..nv)
            .map(|k| (k as f64 / (nv - 1) as f64).powi(2))
            .collect();
        let g = s.grid(&us, &vs, false).unwrap();
        let target = DVec3::new(0.3, -0.2, 0.1);
        // Each sample's distance to a point, weighted by its row so rows differ.
        let measure = |i: usize, row: &[[f64; 3]]| {
            row.iter()
                .map(|p| (DVec3::from_array(*p) - target).length() * (1.0 + i as f64))
                .fold(0.0, f64::max)
        };
        let stored = g
            .points
            .chunks(nv)
            .enumerate()
            .map(|(i, row)| measure(i, row))
            .fold(0.0, f64::max);
        let streamed = s.grid_rows_max(&us, &vs, measure).unwrap();
        assert_eq!(streamed.to_bits(), stored.to_bits(), "{nu} × {nv}");
        assert!(stored > 0.0);
        // The row handed to `measure` is the stored grid's row, bit for bit.
        let same = s
            .grid_rows_max(&us, &vs, |i, row| {
                f64::from(u8::from(row != &g.points[i * nv..(i + 1) * nv]))
            })
            .unwrap();
        assert_eq!(same, 0.0, "{nu} × {nv}: a row differs");
    }
    assert_eq!(s.grid_rows_max(&[0.5], &[], |_, _| 1.0).unwrap(), 0.0);
    assert!(s.grid_rows_max(&[f64::NAN], &[0.5], |_, _| 1.0).is_err());
}

#[test]
fn example_115_matches_geomdl() {
    let s = common::example_115();
    for r in EX115 {
        let d = s.derivatives(r[0], r[1]).unwrap();
        close(d.s, &r[2..5], 1e-12, "S");
        close(d.su, &r[5..8], 1e-12, "Su");
        close(d.sv, &r[8..11], 1e-12, "Sv");
        close(d.suu, &r[11..14], 1e-12, "Suu");
        close(d.suv, &r[14..17], 1e-12, "Suv");
        close(d.svv, &r[17..20], 1e-12, "Svv");
    }
    for r in EX115_NORMALS {
        close(s.normal(r[0], r[1]).unwrap(), &r[2..5], 1e-12, "normal");
    }
}

#[test]
fn example_115_degenerate_corner_has_a_finite_fallback_normal() {
    // spec §2.2.5: S_u = (6,3,0) ∥ S_v = (4,2,0) at (0,0); geomdl raises
    // "The magnitude of the vector is zero" there (the thesis's printed error).
    let s = common::example_115();
    let d = s.derivatives(0.0, 0.0).unwrap();
    assert_eq!(d.su, DVec3::new(6.0, 3.0, 0.0));
    assert_eq!(d.sv, DVec3::new(4.0, 2.0, 0.0));
    let n = s.normal(0.0, 0.0).unwrap();
    assert!(n.is_finite() && (n.length() - 1.0).abs() < 1e-12);
    // The fallback steps toward the centre along the diagonal: the diagonal limit of spec
    // §2.2.5 is (0.4019, −0.8039, 0.4385).
    assert!(
        (n - DVec3::new(0.4019, -0.8039, 0.4385)).length() < 2e-3,
        "{n:?}"
    );
    // Deterministic: the same bits every call.
    assert_eq!(s.normal(0.0, 0.0).unwrap(), n);
}

#[test]
fn listing_1_1_bezier_curve() {
    let c = NurbsCurve::bezier(
        &[[0.0, 0.0, 0.0], [10.0, 15.0, 0.0], [20.0, 0.0, 0.0]],
        None,
    )
    .unwrap();
    for r in L11 {
        let d = c.derivatives(r[0]).unwrap();
        close(d[0], &[r[1], r[2], 0.0], 1e-13, "C");
        close(d[1], &[r[3], r[4], 0.0], 1e-13, "C'");
        close(d[2], &[r[5], r[6], 0.0], 1e-13, "C''");
    }
}

#[test]
fn listing_1_5_unclamped_nurbs_curve() {
    let pts = [
        [-3.0, 3.0, 0.0],
        [-1.0, 5.0, 0.0],
        [2.0, 7.0, 0.0],
        [3.0, 0.0, 0.0],
        [6.0, 0.0, 0.0],
        [8.0, 4.0, 0.0],
        [10.0, 2.5, 0.0],
    ];
    let knots: Vec<f64> = (0..10).map(f64::from).collect();
    let c = NurbsCurve::new(2, knots, &pts, None).unwrap();
    assert_eq!(c.domain(), [2.0, 7.0]);
    // Starts at (P0 + P1)/2 (spec §2.2.2), not at P0.
    assert_eq!(c.point(2.0).unwrap(), DVec3::new(-2.0, 4.0, 0.0));
    for r in L15 {
        let u = 9.0 * r[0];
        let d = c.derivatives(u).unwrap();
        close(d[0], &[r[1], r[2], 0.0], 1e-12, "C");
        close(d[1], &[r[3] / 9.0, r[4] / 9.0, 0.0], 1e-12, "C'");
        close(d[2], &[r[5] / 81.0, r[6] / 81.0, 0.0], 1e-10, "C''");
    }
}
