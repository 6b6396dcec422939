//! Point values (spec §1 formulas), Lipschitz and exactness properties,
//! bounds, order independence, tape sharing.

use std::f64::consts::{FRAC_1_SQRT_2, SQRT_2};

use glam::{DQuat, DVec3};
use proptest::prelude::*;

use super::{compile, eval, Rng};
use crate::sdf::tape::{smin, Tape};
use crate::sdf::tree::{Exactness, Node, NodeId, Rotation, Tree, TreeLimits};

fn one(node: Node) -> (Tree, NodeId) {
    let mut t = Tree::new();
    let id = t.push(node);
    (t, id)
}

fn close(a: f64, b: f64) {
    assert!((a - b).abs() < 1e-12, "{a} != {b}");
}

#[test]
fn primitive_point_values() {
    let (t, s) = one(Node::Sphere { radius: 1.0 });
    close(eval(&t, s, DVec3::new(3.0, 0.0, 0.0)), 2.0);
    close(eval(&t, s, DVec3::ZERO), -1.0);

    let (t, b) = one(Node::Box {
        size: DVec3::splat(2.0),
    });
    close(eval(&t, b, DVec3::new(2.0, 0.0, 0.0)), 1.0);
    close(eval(&t, b, DVec3::new(2.0, 2.0, 0.0)), SQRT_2);
    close(eval(&t, b, DVec3::new(0.5, 0.0, 0.0)), -0.5);

    let (t, b) = one(Node::RoundedBox {
        size: DVec3::splat(2.0),
        radius: 0.25,
    });
    close(eval(&t, b, DVec3::new(2.0, 0.0, 0.0)), 1.0);
    close(eval(&t, b, DVec3::new(2.0, 2.0, 0.0)), 1.25 * SQRT_2 - 0.25);

    // Torus about +Z (D2).
    let (t, to) = one(Node::Torus {
        major_radius: 2.0,
        minor_radius: 0.5,
    });
    close(eval(&t, to, DVec3::new(2.0, 0.0, 0.0)), -0.5);
    close(eval(&t, to, DVec3::new(0.0, 3.0, 0.0)), 0.5);
    close(eval(&t, to, DVec3::new(2.0, 0.0, 1.0)), 0.5);
    close(eval(&t, to, DVec3::ZERO), 1.5);

    let (t, c) = one(Node::Cylinder {
        radius: 1.0,
        height: 2.0,
    });
    close(eval(&t, c, DVec3::ZERO), -1.0);
    close(eval(&t, c, DVec3::new(0.0, 2.0, 0.0)), 1.0);
    close(eval(&t, c, DVec3::new(0.0, 0.0, 3.0)), 2.0);
    close(eval(&t, c, DVec3::new(2.0, 0.0, 2.0)), SQRT_2);

    let (t, c) = one(Node::Cone {
        height: 2.0,
        bottom_radius: 1.0,
        top_radius: 0.0,
    });
    close(eval(&t, c, DVec3::new(0.0, 0.0, 1.0)), 0.0);
    close(eval(&t, c, DVec3::new(0.0, 0.0, -2.0)), 1.0);
    close(eval(&t, c, DVec3::new(2.0, 0.0, -1.0)), 1.0);
    // Apex region: distance to the apex point.
    close(eval(&t, c, DVec3::new(0.0, 0.0, 3.0)), 2.0);

    // Square prism (vertex on +X): vertices (±√2, 0), (0, ±√2).
    let (t, p) = one(Node::Prism {
        sides: 4,
        radius: SQRT_2,
        height: 4.0,
    });
    close(eval(&t, p, DVec3::ZERO), -1.0);
    close(eval(&t, p, DVec3::new(2.0, 0.0, 0.0)), 2.0 - SQRT_2);
    close(
        eval(
            &t,
            p,
            DVec3::new(2.0 * FRAC_1_SQRT_2, 2.0 * FRAC_1_SQRT_2, 0.0),
        ),
        1.0,
    );
    close(eval(&t, p, DVec3::new(0.0, 0.0, 3.0)), 1.0);

    let (t, c) = one(Node::Capsule {
        a: DVec3::ZERO,
        b: DVec3::new(0.0, 0.0, 2.0),
        radius: 0.5,
    });
    close(eval(&t, c, DVec3::new(1.0, 0.0, 1.0)), 0.5);
    close(eval(&t, c, DVec3::new(0.0, 0.0, 3.0)), 0.5);

    let (t, c) = one(Node::RoundCone {
        a: DVec3::ZERO,
        b: DVec3::new(0.0, 0.0, 2.0),
        radius_a: 1.0,
        radius_b: 0.5,
    });
    close(eval(&t, c, DVec3::new(0.0, 0.0, -2.0)), 1.0);
    close(eval(&t, c, DVec3::new(0.0, 0.0, 4.0)), 1.5);
    // Side: the tangent line touches the spheres; at the middle the radius
    // is between the two. Checked against the geometric construction.
    let sin_t = 0.5 / 2.0; // (ra − rb) / |b − a|
    let cos_t = (1.0f64 - sin_t * sin_t).sqrt();
    // The tangent point on sphere a lies at angle θ above the equator.
    let ta = DVec3::new(cos_t, 0.0, sin_t);
    let q = ta + DVec3::new(cos_t, 0.0, sin_t) * 0.75; // 0.75 outside along the normal
    close(eval(&t, c, q), 0.75);

    let (t, h) = one(Node::HalfSpace {
        normal: DVec3::new(0.0, 0.0, 2.0),
        offset: 1.0,
    });
    close(eval(&t, h, DVec3::new(5.0, 5.0, 3.0)), 2.0);

    // Circle ring and circle tube: the polygonal torus is the torus.
    let (t, pt) = one(Node::PolygonalTorus {
        major_radius: 2.0,
        minor_radius: 0.5,
        ring_sides: 0,
        tube_sides: 0,
    });
    let (t2, to) = one(Node::Torus {
        major_radius: 2.0,
        minor_radius: 0.5,
    });
    let mut r = Rng(1);
    for _ in 0..100 {
        let p = r.vec(-3.0, 3.0);
        close(eval(&t, pt, p), eval(&t2, to, p));
    }
    // Square ring of apothem 2 with a square tube: on the +X segment the
    // distance is the 2D square's.
    let (t, pt) = one(Node::PolygonalTorus {
        major_radius: 2.0,
        minor_radius: 0.5,
        ring_sides: 4,
        tube_sides: 4,
    });
    close(eval(&t, pt, DVec3::new(3.0, 0.0, 0.0)), 0.5);
    close(eval(&t, pt, DVec3::new(0.0, -3.0, 0.0)), 0.5);
}

#[test]
fn operation_point_values() {
    let mut t = Tree::new();
    let s = t.push(Node::Sphere { radius: 1.0 });
    // Spec §1.4 / D3: scale of sphere(1) by 2 is 1 at (3,0,0) (the thesis's
    // f(x)·s would give 4).
    let sc = t.push(Node::Scale {
        child: s,
        factor: 2.0,
    });
    close(eval(&t, sc, DVec3::new(3.0, 0.0, 0.0)), 1.0);
    let sx = t.push(Node::ScaleXyz {
        child: s,
        factors: DVec3::new(2.0, 1.0, 1.0),
    });
    close(eval(&t, sx, DVec3::new(3.0, 0.0, 0.0)), 0.5);
    let tr = t.push(Node::Translate {
        child: s,
        offset: DVec3::new(1.0, 2.0, 3.0),
    });
    close(eval(&t, tr, DVec3::new(1.0, 2.0, 6.0)), 2.0);
    let off = t.push(Node::Offset {
        child: s,
        distance: 0.5,
    });
    close(eval(&t, off, DVec3::new(3.0, 0.0, 0.0)), 1.5);
    let sh = t.push(Node::Shell {
        child: s,
        thickness: 0.1,
    });
    close(eval(&t, sh, DVec3::ZERO), 0.9);
    close(eval(&t, sh, DVec3::new(1.0, 0.0, 0.0)), -0.1);
    let pc = t.push(Node::PlaneCut {
        child: s,
        normal: DVec3::X,
        point: DVec3::ZERO,
    });
    close(eval(&t, pc, DVec3::new(0.5, 0.0, 0.0)), 0.5);
    close(eval(&t, pc, DVec3::new(-0.5, 0.0, 0.0)), -0.5);
    // Rotations: a box 4×1×1 rotated 90° about Z lies along Y.
    let b = t.push(Node::Box {
        size: DVec3::new(4.0, 1.0, 1.0),
    });
    let r = t.push(Node::Rotate {
        child: b,
        rotation: Rotation::AxisAngle {
            axis: DVec3::Z,
            degrees: 90.0,
        },
    });
    close(eval(&t, r, DVec3::new(0.0, 3.0, 0.0)), 1.0);
    let e = t.push(Node::Rotate {
        child: b,
        rotation: Rotation::EulerXyz {
            degrees: DVec3::new(0.0, 0.0, 90.0),
        },
    });
    close(eval(&t, e, DVec3::new(0.0, 3.0, 0.0)), 1.0);
    // Extrinsic X then Z: X first leaves the X-long box alone, Z turns it to Y.
    let e2 = t.push(Node::Rotate {
        child: b,
        rotation: Rotation::EulerXyz {
            degrees: DVec3::new(90.0, 0.0, 90.0),
        },
    });
    close(eval(&t, e2, DVec3::new(0.0, 3.0, 0.0)), 1.0);
    let a = t.push(Node::Sphere { radius: 1.0 });
    let a2 = t.push(Node::Translate {
        child: a,
        offset: DVec3::new(1.5, 0.0, 0.0),
    });
    let u = t.push(Node::Union(vec![s, a2]));
    let i = t.push(Node::Intersection(vec![s, a2]));
    let d = t.push(Node::Difference {
        base: s,
        subtract: vec![a2],
    });
    let p = DVec3::new(0.75, 0.0, 0.0);
    close(eval(&t, u, p), -0.25);
    close(eval(&t, i, p), -0.25);
    close(eval(&t, u, DVec3::ZERO), -1.0);
    close(eval(&t, i, DVec3::ZERO), 0.5);
    close(eval(&t, d, p), 0.25);
    let su = t.push(Node::SmoothUnion {
        children: vec![s, a2],
        k: 0.5,
    });
    close(eval(&t, su, p), smin(-0.25, -0.25, 0.5));
    close(eval(&t, su, p), -0.25 - 0.125);
    let si = t.push(Node::SmoothIntersection {
        children: vec![s, a2],
        k: 0.5,
    });
    close(eval(&t, si, p), 0.125 - 0.25);
    let sd = t.push(Node::SmoothDifference {
        base: s,
        subtract: vec![a2],
        k: 0.5,
    });
    // smax(−0.25, 0.25): the values differ by k, so no blend.
    close(eval(&t, sd, p), 0.25);
}

/// Random trees of every kind with their contracts, for the properties.
fn random_tree(r: &mut Rng) -> (Tree, NodeId) {
    let mut t = Tree::new();
    let kind = r.below(14);
    let leaf = match kind {
        0 => Node::Sphere {
            radius: r.range(0.2, 1.5),
        },
        1 => Node::Box {
            size: r.vec(0.2, 2.0),
        },
        2 => {
            let size = r.vec(0.4, 2.0);
            Node::RoundedBox {
                size,
                radius: r.range(0.0, size.min_element() * 0.5),
            }
        }
        3 => Node::Torus {
            major_radius: r.range(0.6, 1.2),
            minor_radius: r.range(0.1, 0.5),
        },
        4 => Node::PolygonalTorus {
            major_radius: r.range(0.8, 1.2),
            minor_radius: r.range(0.1, 0.5),
            ring_sides: [0, 3, 5, 8][r.below(4) as usize],
            tube_sides: [0, 3, 4, 6][r.below(4) as usize],
        },
        5 => Node::Cylinder {
            radius: r.range(0.2, 1.0),
            height: r.range(0.2, 2.0),
        },
        6 => Node::Cone {
            height: r.range(0.3, 2.0),
            bottom_radius: r.range(0.0, 1.0),
            top_radius: r.range(0.05, 1.0),
        },
        7 => Node::Prism {
            sides: 3 + r.below(6) as u32,
            radius: r.range(0.3, 1.0),
            height: r.range(0.3, 2.0),
        },
        8 => {
            let h = r.range(0.5, 2.0);
            Node::Pyramid {
                sides: 3 + r.below(6) as u32,
                radius: r.range(0.3, 1.0),
                height: h,
                top_height: if r.below(2) == 0 {
                    None
                } else {
                    Some(r.range(0.1, 0.9) * h)
                },
            }
        }
        9 => Node::Capsule {
            a: r.vec(-1.0, 1.0),
            b: r.vec(-1.0, 1.0),
            radius: r.range(0.1, 0.6),
        },
        10 => Node::RoundCone {
            a: r.vec(-1.0, 1.0),
            b: r.vec(-1.0, 1.0),
            radius_a: r.range(0.1, 0.8),
            radius_b: r.range(0.1, 0.8),
        },
        _ => Node::Sphere {
            radius: r.range(0.2, 1.5),
        },
    };
    let a = t.push(leaf);
    let b = t.push(Node::Sphere {
        radius: r.range(0.2, 1.0),
    });
    let b = t.push(Node::Translate {
        child: b,
        offset: r.vec(-1.0, 1.0),
    });
    let root = match kind {
        11 => t.push(Node::SmoothUnion {
            children: vec![a, b],
            k: r.range(0.0, 0.5),
        }),
        12 => t.push(Node::ScaleXyz {
            child: a,
            factors: r.vec(0.5, 2.0),
        }),
        13 => t.push(Node::Shell {
            child: a,
            thickness: r.range(0.05, 0.3),
        }),
        _ => {
            let q = DQuat::from_xyzw(
                r.range(-1.0, 1.0),
                r.range(-1.0, 1.0),
                r.range(-1.0, 1.0),
                r.range(-1.0, 1.0),
            );
            let rot = t.push(Node::Rotate {
                child: a,
                rotation: Rotation::Quaternion(q),
            });
            let sc = t.push(Node::Scale {
                child: rot,
                factor: r.range(0.5, 2.0),
            });
            match r.below(5) {
                0 => t.push(Node::Union(vec![sc, b])),
                1 => t.push(Node::Intersection(vec![sc, b])),
                2 => t.push(Node::Difference {
                    base: sc,
                    subtract: vec![b],
                }),
                3 => t.push(Node::Offset {
                    child: sc,
                    distance: r.range(-0.1, 0.3),
                }),
                _ => sc,
            }
        }
    };
    (t, root)
}

fn grad(ev: &mut crate::sdf::tape::Evaluator<'_>, p: DVec3) -> DVec3 {
    let h = 1e-6;
    DVec3::new(
        ev.eval(p + DVec3::X * h) - ev.eval(p - DVec3::X * h),
        ev.eval(p + DVec3::Y * h) - ev.eval(p - DVec3::Y * h),
        ev.eval(p + DVec3::Z * h) - ev.eval(p - DVec3::Z * h),
    ) / (2.0 * h)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// Every node here claims Lipschitz 1: check it on random pairs.
    #[test]
    fn one_lipschitz(seed in any::<u64>()) {
        let mut r = Rng(seed);
        let (t, root) = random_tree(&mut r);
        let tape = compile(&t, root);
        prop_assert_eq!(tape.info().contract.lipschitz, 1.0);
        let mut ev = tape.evaluator();
        for _ in 0..50 {
            let a = r.vec(-2.5, 2.5);
            let b = if r.below(2) == 0 { a + r.vec(-0.05, 0.05) } else { r.vec(-2.5, 2.5) };
            let (fa, fb) = (ev.eval(a), ev.eval(b));
            prop_assert!((fa - fb).abs() <= (a - b).length() * (1.0 + 1e-9) + 1e-12,
                "{} {:?}: |{fa} - {fb}| > |{a} - {b}|", seed, t.node(root).map(|n| n.kind_name()));
        }
    }

    /// Exact nodes: |∇f| = 1 almost everywhere and the projection
    /// p − f(p)·∇f(p) lands on the surface (with 1-Lipschitz this makes |f|
    /// the distance). Exact-outside / -inside nodes are checked on their side.
    #[test]
    fn exact_where_claimed(seed in any::<u64>()) {
        let mut r = Rng(seed);
        let (t, root) = random_tree(&mut r);
        let tape = compile(&t, root);
        let c = tape.info().contract;
        let mut ev = tape.evaluator();
        for _ in 0..200 {
            let p = r.vec(-2.5, 2.5);
            let f = ev.eval(p);
            if (f > 0.0 && !c.exact_outside) || (f < 0.0 && !c.exact_inside) || f.abs() < 1e-3 {
                continue;
            }
            let g = grad(&mut ev, p);
            // Skip the medial axis / creases where the gradient is not unit.
            if (g.length() - 1.0).abs() > 1e-4 {
                continue;
            }
            let q = p - g * f;
            let fq = ev.eval(q);
            prop_assert!(fq.abs() < 1e-5 * (1.0 + f.abs()), "seed {seed} {:?}: f(p) = {f}, f(projection) = {fq}", t.node(root).map(|n| n.kind_name()));
        }
    }

    /// The zero set and every sublevel set lie in the node's bounds.
    #[test]
    fn bounds_contain_sublevel_sets(seed in any::<u64>()) {
        let mut r = Rng(seed);
        let (t, root) = random_tree(&mut r);
        let tape = compile(&t, root);
        let b = tape.info().bounds;
        let mut ev = tape.evaluator();
        for _ in 0..400 {
            let p = r.vec(-4.0, 4.0);
            let f = ev.eval(p);
            let tt = f.max(0.0);
            prop_assert!(b.at(tt).grown(1e-9).contains(p), "seed {seed}: f({p}) = {f} outside {:?}", b.at(tt));
        }
    }

    /// Smooth n-ary operations are bit-identical under any child order.
    #[test]
    fn smooth_ops_order_independent(seed in any::<u64>()) {
        let mut r = Rng(seed);
        let n = 2 + r.below(5) as usize;
        let centres: Vec<DVec3> = (0..n).map(|_| r.vec(-1.0, 1.0)).collect();
        let radii: Vec<f64> = (0..n).map(|_| r.range(0.2, 0.8)).collect();
        let k = r.range(0.01, 1.0);
        let mut perm: Vec<usize> = (0..n).collect();
        let build = |order: &[usize], kind: u64| -> Tape {
            let mut t = Tree::new();
            let kids: Vec<NodeId> = order.iter().map(|&i| {
                let s = t.push(Node::Sphere { radius: radii[i] });
                t.push(Node::Translate { child: s, offset: centres[i] })
            }).collect();
            let root = match kind {
                0 => t.push(Node::SmoothUnion { children: kids, k }),
                1 => t.push(Node::SmoothIntersection { children: kids, k }),
                _ => {
                    let base = t.push(Node::Box { size: DVec3::splat(1.5) });
                    t.push(Node::SmoothDifference { base, subtract: kids, k })
                }
            };
            Tape::compile(&t, root, &TreeLimits::default()).unwrap()
        };
        for kind in 0..3 {
            let a = build(&perm, kind);
            for i in (1..n).rev() {
                let j = r.below(i as u64 + 1) as usize;
                perm.swap(i, j);
            }
            let b = build(&perm, kind);
            let (mut ea, mut eb) = (a.evaluator(), b.evaluator());
            for _ in 0..100 {
                let p = r.vec(-2.0, 2.0);
                prop_assert_eq!(ea.eval(p).to_bits(), eb.eval(p).to_bits());
            }
        }
    }
}

#[test]
fn contracts_follow_the_nodes() {
    let mut t = Tree::new();
    let s = t.push(Node::Sphere { radius: 1.0 });
    let b = t.push(Node::Box { size: DVec3::ONE });
    let u = t.push(Node::Union(vec![s, b]));
    let d = t.push(Node::Difference {
        base: s,
        subtract: vec![b],
    });
    let sx = t.push(Node::ScaleXyz {
        child: s,
        factors: DVec3::new(1.0, 2.0, 3.0),
    });
    let sc = t.push(Node::Scale {
        child: s,
        factor: 3.0,
    });
    let l = TreeLimits::default();
    let info = |id| t.info(id, &l).unwrap().contract;
    assert_eq!(info(s).exactness(), Exactness::Exact);
    assert_eq!(info(sc).exactness(), Exactness::Exact);
    assert!(info(u).exact_outside && !info(u).exact_inside);
    assert!(!info(d).exact_outside && info(d).exact_inside);
    assert_eq!(info(sx).exactness(), Exactness::Bound);
}

#[test]
fn scalar_and_batch_are_bit_identical() {
    let mut r = Rng(7);
    for _ in 0..50 {
        let (t, root) = random_tree(&mut r);
        let tape = compile(&t, root);
        let mut ev = tape.evaluator();
        let pts: Vec<DVec3> = (0..1000).map(|_| r.vec(-2.0, 2.0)).collect();
        let mut out = vec![0.0; pts.len()];
        ev.eval_points(&pts, &mut out);
        for (p, o) in pts.iter().zip(&out) {
            assert_eq!(ev.eval(*p).to_bits(), o.to_bits());
        }
    }
}

#[test]
fn shared_subtrees_compile_once() {
    let mut t = Tree::new();
    let s = t.push(Node::Torus {
        major_radius: 1.0,
        minor_radius: 0.2,
    });
    let a = t.push(Node::Offset {
        child: s,
        distance: 0.1,
    });
    let b = t.push(Node::Shell {
        child: s,
        thickness: 0.05,
    });
    let u = t.push(Node::Union(vec![a, b, s]));
    let tape = compile(&t, u);
    // torus, offset, shell, two mins: the torus is evaluated once.
    assert_eq!(tape.len(), 5);
    // Under two different transforms it is evaluated twice.
    let t1 = t.push(Node::Translate {
        child: u,
        offset: DVec3::X,
    });
    let t2 = t.push(Node::Union(vec![u, t1]));
    let tape = compile(&t, t2);
    assert_eq!(tape.len(), 5 + 1 + 5 + 1);
}

#[test]
fn pyramid_and_prism_match_their_meshes() {
    use crate::sdf::mesh_field::{MeshField, SignMode};
    // Mesh of a regular n-gon pyramid (base z = 0, edge normal on +X).
    for (n, top) in [(3u32, None), (4, None), (5, Some(0.6)), (7, Some(0.3))] {
        let (r, h) = (0.8, 1.3);
        let a = std::f64::consts::PI / n as f64;
        let mut pos: Vec<[f64; 3]> = Vec::new();
        let mut tris: Vec<[u32; 3]> = Vec::new();
        let ring = |z: f64, s: f64, pos: &mut Vec<[f64; 3]>| {
            for k in 0..n {
                // Vertex k at angle a·(2k − 1): sector 0's edge normal on +X.
                let ang = a * (2.0 * k as f64 - 1.0);
                pos.push([s * r * libm::cos(ang), s * r * libm::sin(ang), z]);
            }
        };
        ring(0.0, 1.0, &mut pos);
        let nn = n;
        match top {
            None => {
                pos.push([0.0, 0.0, h]);
                for k in 0..nn {
                    tris.push([k, (k + 1) % nn, nn]);
                }
            }
            Some(tz) => {
                let f: f64 = tz;
                ring(f * h, 1.0 - f, &mut pos);
                for k in 0..nn {
                    let k1 = (k + 1) % nn;
                    tris.push([k, k1, nn + k1]);
                    tris.push([k, nn + k1, nn + k]);
                }
                for k in 1..nn - 1 {
                    tris.push([nn, nn + k, nn + k + 1]);
                }
            }
        }
        for k in 1..nn - 1 {
            tris.push([0, k + 1, k]);
        }
        let mf = MeshField::new(&pos, &tris, SignMode::Auto).unwrap();
        assert_eq!(
            mf.report().sign,
            crate::sdf::mesh_field::SignMethod::Pseudonormal
        );
        let mut t = Tree::new();
        let p = t.push(Node::Pyramid {
            sides: n,
            radius: r,
            height: h,
            top_height: top.map(|f| f * h),
        });
        let tape = compile(&t, p);
        let mut ev = tape.evaluator();
        let mut rng = Rng(n as u64);
        for _ in 0..2000 {
            let q = rng.vec(-1.5, 1.8);
            let (a, b) = (ev.eval(q), mf.signed_distance(q));
            assert!(
                (a - b).abs() < 1e-12,
                "n {n} top {top:?} at {q}: {a} vs mesh {b}"
            );
        }
    }
}
