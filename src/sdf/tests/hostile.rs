//! Hostile input: errors, never panics.

use glam::DVec3;

use crate::sdf::aabb::Aabb;
use crate::sdf::error::SdfError;
use crate::sdf::grid::{MeshOptions, Resolution};
use crate::sdf::mesh_field::{MeshField, SignMode};
use crate::sdf::mesher::mesh;
use crate::sdf::tape::Tape;
use crate::sdf::tree::{Node, NodeId, Rotation, Tree, TreeLimits};

fn compile_err(t: &Tree, root: NodeId) -> SdfError {
    match Tape::compile(t, root, &TreeLimits::default()) {
        Ok(tape) => panic!("compiled to {} instructions", tape.len()),
        Err(e) => e,
    }
}

#[test]
fn bad_parameters_are_located() {
    let mut t = Tree::new();
    let s = t.push(Node::Sphere { radius: f64::NAN });
    assert!(
        matches!(compile_err(&t, s), SdfError::NonFinite { node: 0, ref field, .. } if field == "radius")
    );
    let mut t = Tree::new();
    let b = t.push(Node::Box {
        size: DVec3::new(1.0, -1.0, 1.0),
    });
    assert!(
        matches!(compile_err(&t, b), SdfError::NonPositive { node: 0, ref field, .. } if field == "size[1]")
    );
    let mut t = Tree::new();
    let a = t.push(Node::Sphere { radius: 1.0 });
    let b = t.push(Node::Sphere { radius: 1.0 });
    let u = t.push(Node::SmoothUnion {
        children: vec![a, b],
        k: -0.1,
    });
    assert!(
        matches!(compile_err(&t, u), SdfError::Negative { node: 2, ref field, .. } if field == "k")
    );
    let mut t = Tree::new();
    let a = t.push(Node::Sphere { radius: 1.0 });
    let bad = t.push(Node::Union(vec![a, NodeId(7)]));
    assert!(matches!(
        compile_err(&t, bad),
        SdfError::BadChild {
            node: 1,
            child: 7,
            ..
        }
    ));
    let mut t = Tree::new();
    let a = t.push(Node::Sphere { radius: 1.0 });
    let r = t.push(Node::Rotate {
        child: a,
        rotation: Rotation::AxisAngle {
            axis: DVec3::ZERO,
            degrees: 10.0,
        },
    });
    assert!(matches!(
        compile_err(&t, r),
        SdfError::Invalid { node: 1, .. }
    ));
    let mut t = Tree::new();
    let p = t.push(Node::Pyramid {
        sides: 2,
        radius: 1.0,
        height: 1.0,
        top_height: None,
    });
    assert!(
        matches!(compile_err(&t, p), SdfError::Invalid { node: 0, ref field, .. } if field == "sides")
    );
    let mut t = Tree::new();
    let p = t.push(Node::Pyramid {
        sides: 4,
        radius: 1.0,
        height: 1.0,
        top_height: Some(1.5),
    });
    assert!(
        matches!(compile_err(&t, p), SdfError::Invalid { node: 0, ref field, .. } if field == "top_height")
    );
    let mut t = Tree::new();
    let a = t.push(Node::Union(vec![]));
    assert!(matches!(
        compile_err(&t, a),
        SdfError::TooFewChildren { node: 0, .. }
    ));
}

#[test]
fn smooth_blend_over_a_bound_is_refused() {
    let mut t = Tree::new();
    let a = t.push(Node::Sphere { radius: 1.0 });
    let s = t.push(Node::ScaleXyz {
        child: a,
        factors: DVec3::new(1.0, 2.0, 1.0),
    });
    let b = t.push(Node::Sphere { radius: 1.0 });
    let u = t.push(Node::SmoothUnion {
        children: vec![b, s],
        k: 0.2,
    });
    assert!(
        matches!(compile_err(&t, u), SdfError::InexactChild { node: 3, child: 1, ref field, side: "outside" } if field == "children[1]")
    );
    let lim = TreeLimits {
        allow_inexact_blend: true,
        ..Default::default()
    };
    assert!(Tape::compile(&t, u, &lim).is_ok());
    // A union of exact children is exact outside: blending it is fine;
    // a difference is not exact outside.
    let d = t.push(Node::Difference {
        base: a,
        subtract: vec![b],
    });
    let u2 = t.push(Node::SmoothUnion {
        children: vec![d, b],
        k: 0.2,
    });
    assert!(matches!(
        compile_err(&t, u2),
        SdfError::InexactChild {
            node: 5,
            child: 4,
            ..
        }
    ));
}

#[test]
fn depth_and_size_are_bounded() {
    let mut t = Tree::new();
    let mut id = t.push(Node::Sphere { radius: 1.0 });
    for _ in 0..10_000 {
        id = t.push(Node::Translate {
            child: id,
            offset: DVec3::X * 1e-3,
        });
    }
    assert!(matches!(
        compile_err(&t, id),
        SdfError::TooDeep { limit: 256, .. }
    ));
    // Exponential expansion through shared subtrees under transforms.
    let mut t = Tree::new();
    let mut id = t.push(Node::Sphere { radius: 1.0 });
    for i in 0..60 {
        let m = t.push(Node::Translate {
            child: id,
            offset: DVec3::new(
                libm::sqrt(2.0 + i as f64),
                libm::sqrt(3.0 + 7.0 * i as f64),
                0.0,
            ),
        });
        id = t.push(Node::Union(vec![id, m]));
    }
    assert!(matches!(
        compile_err(&t, id),
        SdfError::TooLarge {
            what: "tape instructions",
            ..
        }
    ));
}

#[test]
fn hostile_meshing_input_is_an_error() {
    let mut t = Tree::new();
    let s = t.push(Node::Sphere { radius: 1e300 });
    let tape = Tape::compile(&t, s, &TreeLimits::default()).unwrap();
    let e = mesh(
        &tape,
        &MeshOptions {
            resolution: Resolution::CellSize(1.0),
            ..Default::default()
        },
    );
    assert!(e.is_err(), "{e:?}");
    let e = mesh(&tape, &MeshOptions::default());
    assert!(e.is_ok() || e.is_err());
    let mut t = Tree::new();
    let s = t.push(Node::Sphere { radius: 1.0 });
    let tape = Tape::compile(&t, s, &TreeLimits::default()).unwrap();
    for bad in [
        MeshOptions {
            resolution: Resolution::CellSize(0.0),
            ..Default::default()
        },
        MeshOptions {
            resolution: Resolution::CellSize(f64::NAN),
            ..Default::default()
        },
        MeshOptions {
            resolution: Resolution::CellsPerAxis(0),
            ..Default::default()
        },
        MeshOptions {
            domain: Some(Aabb::new(DVec3::ONE, DVec3::ONE)),
            grid: crate::sdf::grid::GridKind::Linspace,
            ..Default::default()
        },
        MeshOptions {
            domain: Some(Aabb::new(DVec3::ONE, DVec3::ZERO)),
            ..Default::default()
        },
        MeshOptions {
            domain: Some(Aabb::new(DVec3::splat(f64::NEG_INFINITY), DVec3::ZERO)),
            ..Default::default()
        },
        MeshOptions {
            domain: Some(Aabb::new(DVec3::splat(f64::NAN), DVec3::ZERO)),
            ..Default::default()
        },
        MeshOptions {
            resolution: Resolution::CellSize(1e-300),
            ..Default::default()
        },
        MeshOptions {
            domain: Some(Aabb::new(DVec3::splat(1e15), DVec3::splat(1e15 + 1.0))),
            resolution: Resolution::CellSize(1e-6),
            ..Default::default()
        },
    ] {
        assert!(mesh(&tape, &bad).is_err(), "{bad:?}");
    }
    // A zero-size but valid lattice domain meshes to nothing or to a cap.
    let r = mesh(
        &tape,
        &MeshOptions {
            domain: Some(Aabb::new(DVec3::ZERO, DVec3::ZERO)),
            resolution: Resolution::CellSize(0.1),
            ..Default::default()
        },
    );
    assert!(r.is_ok());
    // Unbounded and empty shapes.
    let mut t = Tree::new();
    let h = t.push(Node::HalfSpace {
        normal: DVec3::Z,
        offset: 0.0,
    });
    let tape = Tape::compile(&t, h, &TreeLimits::default()).unwrap();
    assert!(matches!(
        mesh(&tape, &MeshOptions::default()),
        Err(SdfError::Unbounded { .. })
    ));
    let mut t = Tree::new();
    let a = t.push(Node::Sphere { radius: 1.0 });
    let b = t.push(Node::Sphere { radius: 1.0 });
    let b = t.push(Node::Translate {
        child: b,
        offset: DVec3::X * 5.0,
    });
    let i = t.push(Node::Intersection(vec![a, b]));
    let tape = Tape::compile(&t, i, &TreeLimits::default()).unwrap();
    assert!(matches!(
        mesh(&tape, &MeshOptions::default()),
        Err(SdfError::EmptyBounds { .. })
    ));
}

#[test]
fn hostile_meshes_are_errors() {
    assert!(matches!(
        MeshField::new(&[[0.0, 0.0, f64::INFINITY]], &[], SignMode::Auto),
        Err(SdfError::MeshNonFinite { vertex: 0 })
    ));
    assert!(matches!(
        MeshField::new(&[[0.0; 3]], &[[0, 0, 1]], SignMode::Auto),
        Err(SdfError::MeshIndex {
            triangle: 0,
            index: 1,
            ..
        })
    ));
    let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
    assert!(matches!(
        MeshField::new(&p, &[[0, 1, 2]], SignMode::Auto),
        Err(SdfError::MeshEmpty { dropped: 1 })
    ));
    // Many identical triangles: the tree still builds and answers.
    let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let t = vec![[0u32, 1, 2]; 10_000];
    let mf = MeshField::new(&p, &t, SignMode::Auto).unwrap();
    assert!((mf.unsigned_distance(DVec3::new(0.0, 0.0, 2.0)) - 2.0).abs() < 1e-12);
}
