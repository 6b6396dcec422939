//! Skeleton skinning.

use super::Rng;
use crate::sdf::error::SdfError;
use crate::sdf::grid::MeshOptions;
use crate::sdf::skin::{skin, Skeleton, SkinField, SkinNode, SkinOptions};
use glam::DVec3;

fn y_skeleton() -> Skeleton {
    let n = |x: f64, y: f64, z: f64, r: f64| SkinNode {
        position: [x, y, z],
        radius: r,
    };
    Skeleton {
        nodes: vec![
            n(0.0, 0.0, 0.0, 0.25),
            n(0.0, 0.0, 1.0, 0.2),
            n(0.5, 0.0, 1.7, 0.12),
            n(-0.5, 0.1, 1.6, 0.15),
        ],
        edges: vec![[0, 1], [1, 2], [1, 3]],
    }
}

fn opts(threads: usize) -> SkinOptions {
    SkinOptions {
        blend: 0.06,
        cell: None,
        mesh: MeshOptions {
            threads,
            ..Default::default()
        },
    }
}

#[test]
fn y_skeleton_is_one_genus_zero_solid() {
    let out = skin(&y_skeleton(), &opts(0)).unwrap();
    assert!(out.check.is_closed_manifold(), "{:?}", out.check);
    assert_eq!(out.check.components, 1);
    assert_eq!(out.skeleton_components, 1);
    assert_eq!((out.solids, out.cavities), (1, 0));
    assert_eq!(out.check.genus(), Some(0));
    assert_eq!(out.check.zero_area, 0);
    assert!(out.check.volume > 0.0);
    assert!((out.cell - 0.06).abs() < 1e-15);
}

#[test]
fn edge_order_and_direction_do_not_matter() {
    let a = skin(&y_skeleton(), &opts(1)).unwrap();
    let mut s = y_skeleton();
    s.edges = vec![[3, 1], [2, 1], [1, 0], [0, 1]];
    for threads in [1, 2, 3] {
        let b = skin(&s, &opts(threads)).unwrap();
        assert_eq!(a.mesh.triangles, b.mesh.triangles);
        assert!(a
            .mesh
            .positions
            .iter()
            .zip(&b.mesh.positions)
            .all(|(p, q)| p.iter().zip(q).all(|(x, y)| x.to_bits() == y.to_bits())));
        assert_eq!(a.mesh.positions.len(), b.mesh.positions.len());
    }
}

#[test]
fn culled_evaluation_equals_exhaustive() {
    use crate::sdf::grid::Field;
    use crate::sdf::Aabb;
    let mut r = Rng(11);
    // A random tree-like skeleton with many edges.
    let mut nodes = vec![SkinNode {
        position: [0.0; 3],
        radius: 0.1,
    }];
    let mut edges = Vec::new();
    for i in 1..200u32 {
        let p = r.below(i as u64) as usize;
        let base = DVec3::from_array(nodes[p].position);
        nodes.push(SkinNode {
            position: (base + r.vec(-0.3, 0.3)).to_array(),
            radius: r.range(0.03, 0.1),
        });
        edges.push([p as u32, i]);
    }
    let f = SkinField::new(&Skeleton { nodes, edges }, 0.05).unwrap();
    let mut ev = f.evaluator();
    for _ in 0..2000 {
        let c = r.vec(-2.0, 2.0);
        let region = Aabb::centered(c, DVec3::splat(r.range(0.0, 0.3)));
        let p = c + r.vec(-1.0, 1.0) * (region.hi - c);
        let mut out = [0.0];
        ev.eval(&region, &[p.x], &[p.y], &[p.z], &mut out);
        assert_eq!(out[0].to_bits(), f.eval_exhaustive(p).to_bits(), "at {p}");
    }
}

/// Two separate skeletons give two solids.
#[test]
fn separate_skeletons_give_separate_solids() {
    let mut s = y_skeleton();
    let k = s.nodes.len() as u32;
    for n in y_skeleton().nodes {
        s.nodes.push(SkinNode {
            position: [n.position[0] + 2.0, n.position[1], n.position[2]],
            radius: n.radius,
        });
    }
    for e in y_skeleton().edges {
        s.edges.push([e[0] + k, e[1] + k]);
    }
    let out = skin(&s, &opts(0)).unwrap();
    assert!(out.check.is_closed_manifold());
    assert_eq!(
        (out.skeleton_components, out.solids, out.cavities),
        (2, 2, 0)
    );
    assert_eq!(out.check.genus(), Some(0));
}

#[test]
fn bad_skeletons_are_errors() {
    let mut s = y_skeleton();
    s.nodes[2].radius = f64::NAN;
    assert!(matches!(
        skin(&s, &opts(0)),
        Err(SdfError::SkinNode {
            node: 2,
            field: "radius",
            ..
        })
    ));
    let mut s = y_skeleton();
    s.edges.push([1, 1]);
    assert!(matches!(
        skin(&s, &opts(0)),
        Err(SdfError::SkinEdge { edge: 3, .. })
    ));
    let mut s = y_skeleton();
    s.edges.push([1, 9]);
    assert!(matches!(
        skin(&s, &opts(0)),
        Err(SdfError::SkinEdge { edge: 3, .. })
    ));
    let mut o = opts(0);
    o.cell = Some(0.1);
    assert!(matches!(
        skin(&y_skeleton(), &o),
        Err(SdfError::CellTooCoarse { .. })
    ));
    let mut o = opts(0);
    o.blend = -1.0;
    assert!(skin(&y_skeleton(), &o).is_err());
}
