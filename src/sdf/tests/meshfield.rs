//! Mesh distance fields: brute-force equality, sign methods, winding
//! number on open input, the peers' union mesh.

use std::sync::Arc;

use glam::DVec3;

use super::{compile, Rng};
use crate::sdf::grid::{MeshOptions, Resolution};
use crate::sdf::mesh_field::{MeshField, SignMethod, SignMode};
use crate::sdf::mesher::mesh;
use crate::sdf::topology::check;
use crate::sdf::tree::{Node, Tree};

/// A closed genus-1 mesh: our marching cubes of a torus.
fn torus_mesh() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut t = Tree::new();
    let to = t.push(Node::Torus {
        major_radius: 1.0,
        minor_radius: 0.35,
    });
    let tape = compile(&t, to);
    let m = mesh(
        &tape,
        &MeshOptions {
            resolution: Resolution::CellsPerAxis(40),
            ..Default::default()
        },
    )
    .unwrap();
    (m.positions, m.triangles)
}

/// The peers' union mesh (tools/make_union_fixture.py).
pub fn union_fixture() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let b: &[u8] = include_bytes!("../../../fixtures/sdf/union.bin");
    let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    let f64_at = |o: usize| f64::from_le_bytes(b[o..o + 8].try_into().unwrap());
    let (nv, nt) = (u32_at(0) as usize, u32_at(4) as usize);
    let pos = (0..nv)
        .map(|i| [f64_at(8 + 24 * i), f64_at(16 + 24 * i), f64_at(24 + 24 * i)])
        .collect();
    let base = 8 + 24 * nv;
    let tris = (0..nt)
        .map(|i| {
            [
                u32_at(base + 12 * i),
                u32_at(base + 12 * i + 4),
                u32_at(base + 12 * i + 8),
            ]
        })
        .collect();
    (pos, tris)
}

#[test]
fn nearest_equals_brute_force() {
    let (p, t) = torus_mesh();
    let mf = MeshField::new(&p, &t, SignMode::Auto).unwrap();
    let mut r = Rng(3);
    let mut prev: Option<(DVec3, f64)> = None;
    for i in 0..3000 {
        // Mix of near, far and exactly-on-vertex queries.
        let q = match i % 3 {
            0 => r.vec(-2.0, 2.0),
            1 => r.vec(-6.0, 6.0),
            _ => DVec3::from_array(p[r.below(p.len() as u64) as usize]) + r.vec(-1e-3, 1e-3),
        };
        let (bd, bt) = mf.nearest_brute(q);
        let n = mf.nearest(q, None);
        assert_eq!(n.distance.to_bits(), bd.to_bits(), "query {q}");
        assert_eq!(n.triangle, bt);
        // A warm-start hint (previous query's distance + step) changes nothing.
        if let Some((pp, pd)) = prev {
            let h = mf.nearest(q, Some(pd + (q - pp).length()));
            assert_eq!(h.distance.to_bits(), bd.to_bits());
            assert_eq!(h.triangle, bt);
        }
        // A wrong (too small) hint falls back to the full search.
        let w = mf.nearest(q, Some(bd * 0.5));
        assert_eq!(w.distance.to_bits(), bd.to_bits());
        prev = Some((q, bd));
    }
}

#[test]
fn sign_methods_agree_on_closed_input() {
    let (p, t) = torus_mesh();
    let pn = MeshField::new(&p, &t, SignMode::Auto).unwrap();
    assert_eq!(pn.report().sign, SignMethod::Pseudonormal);
    let wn = MeshField::new(&p, &t, SignMode::Force(SignMethod::WindingNumber)).unwrap();
    let mut r = Rng(5);
    let mut inside = 0;
    for _ in 0..4000 {
        let q = r.vec(-1.6, 1.6);
        let (a, b) = (pn.signed_distance(q), wn.signed_distance(q));
        assert_eq!(a.abs().to_bits(), b.abs().to_bits());
        if a.abs() > 1e-9 {
            assert_eq!(a < 0.0, b < 0.0, "at {q}: {a} vs {b}");
        }
        let w = wn.winding_number(q);
        let wb = wn.winding_number_brute(q);
        assert!((w - wb).abs() < 0.05, "fast {w} brute {wb}");
        inside += (a < 0.0) as usize;
    }
    assert!(inside > 100);
    // The signed distance against the torus formula: the mesh is within
    // MC error of it.
    for _ in 0..500 {
        let q = r.vec(-1.6, 1.6);
        let exact = DVec3::new(q.x, q.y, 0.0).length() - 1.0;
        let exact = (exact * exact + q.z * q.z).sqrt() - 0.35;
        assert!((pn.signed_distance(q) - exact).abs() < 0.01);
    }
}

#[test]
fn winding_number_on_open_input() {
    let (p, t) = torus_mesh();
    // Cut a window into the top of the tube.
    let open: Vec<[u32; 3]> = t
        .iter()
        .copied()
        .filter(|tri| {
            let c = tri
                .iter()
                .map(|&v| DVec3::from_array(p[v as usize]))
                .sum::<DVec3>()
                / 3.0;
            !(c.z > 0.25 && c.x > 0.5 && c.y.abs() < 0.3)
        })
        .collect();
    assert!(open.len() < t.len());
    let mf = MeshField::new(&p, &open, SignMode::Auto).unwrap();
    let rep = mf.report();
    assert_eq!(rep.sign, SignMethod::WindingNumber, "{rep:?}");
    assert!(rep.boundary_edges > 0);
    assert!(rep.reason.contains("boundary"));
    // Inside the tube, away from the window: w ≈ 1; outside: w ≈ 0.
    let mut r = Rng(9);
    for _ in 0..2000 {
        let ang = r.range(0.0, std::f64::consts::TAU);
        let rho = 1.0 + r.range(-0.2, 0.2);
        let z = r.range(-0.2, 0.2);
        let q = DVec3::new(rho * libm::cos(ang), rho * libm::sin(ang), z);
        if q.x > 0.3 && q.y.abs() < 0.5 {
            continue;
        }
        let w = mf.winding_number(q);
        assert!(w > 0.75, "inside {q}: w = {w}");
        assert!(mf.signed_distance(q) < 0.0);
        let o = DVec3::new(r.range(-0.4, 0.4), r.range(-0.4, 0.4), r.range(-1.0, 1.0));
        let wo = mf.winding_number(o);
        assert!(wo.abs() < 0.25, "outside {o}: w = {wo}");
        assert!(mf.signed_distance(o) > 0.0);
    }
}

#[test]
fn mesh_node_in_a_tree() {
    let (p, t) = torus_mesh();
    let mf = Arc::new(MeshField::new(&p, &t, SignMode::Auto).unwrap());
    let mut tr = Tree::new();
    let m = tr.push(Node::Mesh(mf.clone()));
    let moved = tr.push(Node::Translate {
        child: m,
        offset: DVec3::new(3.0, 0.0, 0.0),
    });
    let tape = compile(&tr, moved);
    let mut ev = tape.evaluator();
    let q = DVec3::new(4.0, 0.0, 0.0);
    assert_eq!(
        ev.eval(q).to_bits(),
        mf.signed_distance(DVec3::new(1.0, 0.0, 0.0)).to_bits()
    );
    let out = mesh(
        &tape,
        &MeshOptions {
            resolution: Resolution::CellsPerAxis(30),
            ..Default::default()
        },
    )
    .unwrap();
    let c = check(&out.positions, &out.triangles);
    assert!(c.is_closed_manifold());
    assert_eq!(c.genus(), Some(1));
}

/// peers.md: Open3D, point-cloud-utils and libigl agree on 37,612 inside
/// samples of linspace(−1.3, 2.0, 64)³ for the union mesh.
#[test]
fn union_fixture_inside_count_matches_peers() {
    let (p, t) = union_fixture();
    assert_eq!(t.len(), 82_768);
    let mf = MeshField::new(&p, &t, SignMode::Auto).unwrap();
    assert_eq!(
        mf.report().sign,
        SignMethod::Pseudonormal,
        "{:?}",
        mf.report()
    );
    let n = 64;
    let g: Vec<f64> = (0..n)
        .map(|i| {
            if i == n - 1 {
                2.0
            } else {
                -1.3 + i as f64 * 3.3 / (n - 1) as f64
            }
        })
        .collect();
    let mut inside = 0;
    let mut prev: Option<(DVec3, f64)> = None;
    for &x in &g {
        for &y in &g {
            for &z in &g {
                let q = DVec3::new(x, y, z);
                let (d, s) =
                    mf.signed_distance_hint(q, prev.map(|(pp, pd)| pd + (q - pp).length()));
                prev = Some((q, d));
                inside += (s < 0.0) as usize;
            }
        }
    }
    assert_eq!(inside, 37_612);
}

/// The pruning bounds (f32 boxes, cylinders, disks) never lose the exact
/// answer on the real 82,768-triangle mesh either.
#[test]
fn union_fixture_nearest_equals_brute_force() {
    let (p, t) = union_fixture();
    let mf = MeshField::new(&p, &t, SignMode::Auto).unwrap();
    let mut r = Rng(21);
    let mut seed = None;
    for i in 0..300 {
        let q = if i % 2 == 0 {
            r.vec(-1.3, 2.0)
        } else {
            DVec3::from_array(p[r.below(p.len() as u64) as usize]) + r.vec(-0.01, 0.01)
        };
        let (bd, bt) = mf.nearest_brute(q);
        let n = mf.nearest(q, None);
        assert_eq!(
            (n.distance.to_bits(), n.triangle),
            (bd.to_bits(), bt),
            "at {q}"
        );
        let (d, _) = mf.signed_distance_seeded(q, Some(bd * 1.5 + 0.01), &mut seed);
        assert_eq!(d.to_bits(), bd.to_bits());
    }
}

/// Built once, shared by many evaluations.
#[test]
fn shared_structures_are_send_and_sync() {
    fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<MeshField>();
    assert_send_sync::<crate::sdf::tape::Tape>();
    assert_send_sync::<crate::sdf::skin::SkinField>();
    assert_send_sync::<crate::sdf::tree::Tree>();
}
