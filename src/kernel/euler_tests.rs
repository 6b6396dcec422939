//! Unit tests of each Euler operator, validating after every call.

use glam::DVec3;

use super::*;

fn v3(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// A unit square split into two quads along x = 0.5: verts 0..6.
///   3 --- 4 --- 5
///   |  f0 |  f1 |
///   0 --- 1 --- 2
fn two_quads() -> (Mesh, Vec<VertId>, FaceId, FaceId) {
    let mut m = Mesh::new();
    let v: Vec<VertId> = [(0., 0.), (0.5, 0.), (1., 0.), (0., 1.), (0.5, 1.), (1., 1.)]
        .iter()
        .map(|&(x, y)| m.make_vert(v3(x, y, 0.)))
        .collect();
    let f0 = m.make_face(&[v[0], v[1], v[4], v[3]]).unwrap();
    let f1 = m.make_face(&[v[1], v[2], v[5], v[4]]).unwrap();
    m.validate().unwrap();
    (m, v, f0, f1)
}

fn ring(m: &Mesh, f: FaceId) -> Vec<VertId> {
    m.face_verts(f).collect()
}

/// Whether `b` comes right after `a` in the cyclic ring.
fn follows(ring: &[VertId], a: VertId, b: VertId) -> bool {
    (0..ring.len()).any(|i| ring[i] == a && ring[(i + 1) % ring.len()] == b)
}

#[test]
fn make_edge_rejects_duplicates_self_loops_and_dead_vertices() {
    let mut m = Mesh::new();
    let a = m.make_vert(DVec3::ZERO);
    let b = m.make_vert(DVec3::X);
    let e = m.make_edge(a, b).unwrap();
    assert_eq!(m.make_edge(b, a), Err(KernelError::EdgeExists(b, a, e)));
    assert_eq!(m.make_edge(a, a), Err(KernelError::SameVertex(a)));
    assert!(matches!(
        m.make_edge(a, VertId::from_raw(9)),
        Err(KernelError::Dead { .. })
    ));
    assert_eq!(m.edge_count(), 1);
    assert_eq!(m.vert_degree(a), 1);
    m.validate().unwrap();
}

#[test]
fn make_edge_vert_copies_attributes_of_its_source() {
    let mut m = Mesh::new();
    m.add_layer("radius", Domain::Vert, AttrValue::Scalar(1.0))
        .unwrap();
    let a = m.make_vert(DVec3::ZERO);
    m.set_attr("radius", Domain::Vert, a.index(), AttrValue::Scalar(0.25));
    let (e, b) = m.make_edge_vert(a, DVec3::Y).unwrap();
    assert_eq!(m.edge_verts(e), [a, b]);
    assert_eq!(
        m.attr("radius", Domain::Vert, b.index()),
        Some(AttrValue::Scalar(0.25))
    );
    assert_eq!(
        m.make_edge_vert(a, v3(f64::NAN, 0., 0.)),
        Err(KernelError::NonFinite)
    );
    m.validate().unwrap();
}

#[test]
fn make_face_builds_missing_edges_and_checks_its_ring() {
    let (m, v, f0, f1) = two_quads();
    assert_eq!(m.edge_count(), 7);
    assert_eq!(m.loop_count(), 8);
    assert_eq!(ring(&m, f0), vec![v[0], v[1], v[4], v[3]]);
    let shared = m.find_edge(v[1], v[4]).unwrap();
    assert_eq!(m.edge_face_count(shared), 2);
    assert_eq!(m.face_normal(f1), DVec3::Z);
    assert_eq!(m.face_edge_neighbors(f0), vec![f1]);
    assert_eq!(m.find_face(&[v[4], v[3], v[0], v[1]]), Some(f0));

    let mut m2 = m.clone();
    assert_eq!(
        m2.make_face(&[v[0], v[1]]),
        Err(KernelError::TooFewVertices(2))
    );
    assert_eq!(
        m2.make_face(&[v[0], v[1], v[0]]),
        Err(KernelError::RepeatedVertex(v[0]))
    );
    assert_eq!(m2.edge_count(), 7, "a refused face leaves no edges behind");
    m2.validate().unwrap();
}

#[test]
fn non_manifold_edges_take_any_number_of_faces() {
    let (mut m, v, _, _) = two_quads();
    let apex = m.make_vert(v3(0.5, 0.5, 1.));
    let f = m.make_face(&[v[1], v[4], apex]).unwrap();
    let shared = m.find_edge(v[1], v[4]).unwrap();
    assert_eq!(m.edge_face_count(shared), 3);
    assert_eq!(m.face_len(f), 3);
    m.validate().unwrap();
}

#[test]
fn make_face_from_edges_orders_the_ring() {
    let mut m = Mesh::new();
    let a = m.make_vert(DVec3::ZERO);
    let (e0, b) = m.make_edge_vert(a, DVec3::X).unwrap();
    let (e1, c) = m.make_edge_vert(b, DVec3::Y).unwrap();
    let e2 = m.make_edge(c, a).unwrap();
    let f = m.make_face_from_edges(&[e0, e1, e2]).unwrap();
    assert_eq!(ring(&m, f), vec![a, b, c]);
    let d = m.make_vert(DVec3::Z);
    let e3 = m.make_edge(c, d).unwrap();
    assert_eq!(
        m.make_face_from_edges(&[e0, e1, e3]),
        Err(KernelError::NotARing(e3))
    );
    m.validate().unwrap();
}

#[test]
fn make_face_on_edges_matches_make_face_and_checks_its_edges() {
    let (mut m, v, f0, _) = two_quads();
    let apex = m.make_vert(v3(0.25, 0.5, 1.));
    let (side_a, _) = m.find_or_make_edge(v[0], apex).unwrap();
    let (base, made) = m.find_or_make_edge(v[0], v[1]).unwrap();
    assert!(!made);
    assert_eq!(Some(base), m.find_edge(v[1], v[0]));
    let (side_b, made) = m.find_or_make_edge(v[1], apex).unwrap();
    assert!(made);
    let before = (m.edge_count(), m.loop_count(), m.face_count());
    // Wrong count, an edge off its side, a dead edge: refused, mesh unchanged.
    let ring = [v[0], v[1], apex];
    assert_eq!(
        m.make_face_on_edges(&ring, &[base, side_b]),
        Err(KernelError::SideCount { verts: 3, edges: 2 })
    );
    assert_eq!(
        m.make_face_on_edges(&ring, &[base, side_a, side_b]),
        Err(KernelError::NotARing(side_a))
    );
    assert!(matches!(
        m.make_face_on_edges(&ring, &[base, side_b, EdgeId::from_raw(99)]),
        Err(KernelError::Dead { .. })
    ));
    assert_eq!(
        m.make_face_on_edges(&[v[0], v[1], v[0]], &[base, base, base]),
        Err(KernelError::RepeatedVertex(v[0]))
    );
    assert_eq!((m.edge_count(), m.loop_count(), m.face_count()), before);
    m.validate().unwrap();

    let f = m
        .make_face_on_edges(&ring, &[base, side_b, side_a])
        .unwrap();
    m.validate().unwrap();
    let mut reference = m.clone();
    reference.kill_face(f).unwrap();
    let g = reference.make_face(&ring).unwrap();
    assert_eq!(f, g);
    assert_eq!(m.face_verts(f).collect::<Vec<_>>(), ring);
    assert_eq!(
        m.face_edges(f).collect::<Vec<_>>(),
        vec![base, side_b, side_a]
    );
    assert_eq!(m.face_normal(f), reference.face_normal(g));
    assert_eq!(m.edge_face_count(base), 2);
    assert_ne!(m.face_normal(f), m.face_normal(f0));
    assert_eq!(
        m.find_or_make_edge(apex, apex),
        Err(KernelError::SameVertex(apex))
    );
}

#[test]
fn kill_face_unlinks_every_loop_of_a_shared_boundary() {
    let (mut m, v, f0, f1) = two_quads();
    m.kill_face(f0).unwrap();
    m.validate().unwrap();
    assert_eq!(m.loop_count(), 4);
    let shared = m.find_edge(v[1], v[4]).unwrap();
    assert_eq!(m.edge_faces(shared).collect::<Vec<_>>(), vec![f1]);
    assert_eq!(m.edge_count(), 7);
}

#[test]
fn split_face_makes_two_faces_sharing_the_new_edge() {
    let (mut m, v, f0, _) = two_quads();
    let (g, e) = m.split_face(f0, v[0], v[4]).unwrap();
    m.validate().unwrap();
    assert_eq!(ring(&m, f0), vec![v[0], v[1], v[4]]);
    assert_eq!(ring(&m, g), vec![v[4], v[3], v[0]]);
    assert_eq!(m.edge_face_count(e), 2);
    assert_eq!(m.face_count(), 3);
    assert_eq!(
        m.split_face(f0, v[0], v[1]),
        Err(KernelError::AdjacentInFace(v[0], v[1], f0))
    );
    assert_eq!(
        m.split_face(f0, v[0], v[5]),
        Err(KernelError::NotInFace {
            vert: v[5],
            face: f0
        })
    );
    m.validate().unwrap();
}

#[test]
fn split_edge_inserts_the_vertex_in_every_face() {
    let (mut m, v, f0, f1) = two_quads();
    m.add_layer("radius", Domain::Vert, AttrValue::Scalar(0.0))
        .unwrap();
    m.set_attr("radius", Domain::Vert, v[1].index(), AttrValue::Scalar(2.0));
    let shared = m.find_edge(v[1], v[4]).unwrap();
    let (w, e2) = m.split_edge(shared, 0.25).unwrap();
    m.validate().unwrap();
    assert_eq!(m.position(w), v3(0.5, 0.25, 0.));
    assert_eq!(
        m.attr("radius", Domain::Vert, w.index()),
        Some(AttrValue::Scalar(1.5))
    );
    assert_eq!(m.face_len(f0), 5);
    assert_eq!(m.face_len(f1), 5);
    assert!(follows(&ring(&m, f0), v[1], w));
    assert!(follows(&ring(&m, f1), w, v[1]));
    assert!(follows(&ring(&m, f1), v[4], w));
    assert_eq!(m.edge_verts(e2)[0], w);
    // A wire edge splits too.
    let (e, _) = m.make_edge_vert(v[0], v3(-1., 0., 0.)).unwrap();
    m.split_edge(e, 0.5).unwrap();
    m.validate().unwrap();
}

#[test]
fn join_faces_dissolves_the_shared_edge() {
    let (mut m, v, f0, f1) = two_quads();
    let shared = m.find_edge(v[1], v[4]).unwrap();
    let f = m.join_faces(shared).unwrap();
    m.validate().unwrap();
    assert_eq!(f, f0.min(f1));
    assert_eq!(m.face_count(), 1);
    assert_eq!(m.edge_count(), 6);
    let mut r = ring(&m, f);
    r.sort();
    assert_eq!(r, v);
    let boundary = m.find_edge(v[0], v[1]).unwrap();
    assert_eq!(
        m.join_faces(boundary),
        Err(KernelError::NotTwoFaces {
            edge: boundary,
            faces: 1
        })
    );
}

#[test]
fn join_faces_flips_a_face_wound_the_other_way() {
    let (mut m, v, f0, f1) = two_quads();
    m.reverse_face(f1).unwrap();
    m.validate().unwrap();
    assert_eq!(m.face_normal(f1), -DVec3::Z);
    let shared = m.find_edge(v[1], v[4]).unwrap();
    let f = m.join_faces(shared).unwrap();
    m.validate().unwrap();
    assert_eq!(f, f0);
    assert_eq!(m.face_len(f), 6);
    assert_eq!(m.face_normal(f), DVec3::Z);
}

#[test]
fn join_faces_refuses_to_repeat_a_vertex() {
    // Faces abcd and baxc share edges a-b and b-c: joining across a-b would
    // put c twice on the joined boundary.
    let mut m = Mesh::new();
    let a = m.make_vert(v3(0., 0., 0.));
    let b = m.make_vert(v3(1., 0., 0.));
    let c = m.make_vert(v3(1., 1., 0.));
    let d = m.make_vert(v3(0., 1., 0.));
    let x = m.make_vert(v3(0.5, -1., 0.));
    m.make_face(&[a, b, c, d]).unwrap();
    m.make_face(&[b, a, x, c]).unwrap();
    m.validate().unwrap();
    let e = m.find_edge(a, b).unwrap();
    assert_eq!(
        m.join_faces(e),
        Err(KernelError::JoinRepeatsVertex { edge: e, vert: c })
    );
    m.validate().unwrap();
    assert_eq!(m.face_count(), 2);
}

#[test]
fn collapse_edge_shrinks_faces_and_merges_parallel_edges() {
    // A fan of triangles around a centre; collapse one spoke.
    let mut m = Mesh::new();
    let c = m.make_vert(DVec3::ZERO);
    let rim: Vec<VertId> = (0..6)
        .map(|i| {
            let t = i as f64 * std::f64::consts::TAU / 6.0;
            m.make_vert(v3(t.cos(), t.sin(), 0.))
        })
        .collect();
    for i in 0..6 {
        m.make_face(&[c, rim[i], rim[(i + 1) % 6]]).unwrap();
    }
    let spoke = m.find_edge(c, rim[0]).unwrap();
    let kept = m.collapse_edge(spoke, c, v3(0.5, 0., 0.)).unwrap();
    m.validate().unwrap();
    assert_eq!(kept, c);
    assert!(!m.contains_vert(rim[0]));
    assert_eq!(m.face_count(), 4, "the two triangles on the spoke vanish");
    assert_eq!(m.vert_count(), 6);
    assert_eq!(m.edge_count(), 9);
    assert_eq!(m.position(c), v3(0.5, 0., 0.));
    assert!(m.find_edge(c, rim[1]).is_some());
}

#[test]
fn collapse_edge_of_a_quad_leaves_a_triangle() {
    let (mut m, v, f0, f1) = two_quads();
    let e = m.find_edge(v[0], v[1]).unwrap();
    m.collapse_edge(e, v[1], m.position(v[1])).unwrap();
    m.validate().unwrap();
    assert_eq!(m.face_len(f0), 3);
    assert_eq!(m.face_len(f1), 4);
}

#[test]
fn glue_verts_with_an_edge_between_collapses_it() {
    let mut m = Mesh::new();
    let a = m.make_vert(v3(0., 0., 0.));
    let b = m.make_vert(v3(1., 0., 0.));
    let c = m.make_vert(v3(0., 1., 0.));
    let d = m.make_vert(v3(1., 1., 0.));
    m.make_face(&[a, b, c]).unwrap();
    m.make_face(&[b, d, c]).unwrap();
    m.glue_verts(b, c).unwrap();
    m.validate().unwrap();
    assert_eq!(m.face_count(), 0, "both triangles on b-c degenerate");
    assert_eq!((m.vert_count(), m.edge_count()), (3, 2));
    assert_eq!(m.position(b), v3(1., 0., 0.), "the kept vertex stays put");
}

#[test]
fn glue_verts_merges_parallel_edges() {
    // Two triangles p0 p1 q and p2 p3 q; gluing p2 onto p1 makes q-p1 and
    // q-p2 parallel, so they merge into one edge used by both faces.
    let mut m = Mesh::new();
    let p: Vec<VertId> = (0..4).map(|i| m.make_vert(v3(i as f64, 0., 0.))).collect();
    let q = m.make_vert(v3(0., 1., 0.));
    let f = m.make_face(&[p[0], p[1], q]).unwrap();
    let g = m.make_face(&[p[2], p[3], q]).unwrap();
    m.glue_verts(p[1], p[2]).unwrap();
    m.validate().unwrap();
    assert_eq!((m.vert_count(), m.edge_count(), m.face_count()), (4, 5, 2));
    let shared = m.find_edge(q, p[1]).unwrap();
    assert_eq!(m.edge_faces(shared).collect::<Vec<_>>(), vec![f, g]);
}

#[test]
fn glue_verts_refuses_two_corners_of_one_face() {
    let mut m = Mesh::new();
    let r: Vec<VertId> = (0..4)
        .map(|i| m.make_vert(v3(i as f64, (i % 2) as f64, 0.)))
        .collect();
    let f = m.make_face(&r).unwrap();
    assert_eq!(
        m.glue_verts(r[0], r[2]),
        Err(KernelError::GlueWithinFace {
            a: r[0],
            b: r[2],
            face: f
        })
    );
    assert_eq!(m.glue_verts(r[1], r[1]), Err(KernelError::SameVertex(r[1])));
    m.validate().unwrap();
    assert_eq!(m.vert_count(), 4);
}

#[test]
fn glue_edges_stitches_two_faces_along_an_edge() {
    // Two quads side by side with a gap; glue their facing edges.
    let mut m = Mesh::new();
    let a: Vec<VertId> = [(0., 0.), (1., 0.), (1., 1.), (0., 1.)]
        .iter()
        .map(|&(x, y)| m.make_vert(v3(x, y, 0.)))
        .collect();
    let b: Vec<VertId> = [(1., 0.), (2., 0.), (2., 1.), (1., 1.)]
        .iter()
        .map(|&(x, y)| m.make_vert(v3(x, y, 0.)))
        .collect();
    m.make_face(&a).unwrap();
    m.make_face(&b).unwrap();
    let keep = m.find_edge(a[1], a[2]).unwrap();
    let gone = m.find_edge(b[0], b[3]).unwrap();
    let e = m.glue_edges(keep, gone).unwrap();
    m.validate().unwrap();
    assert_eq!(e, keep);
    assert_eq!(m.edge_face_count(keep), 2);
    assert_eq!(m.vert_count(), 6);
    assert_eq!(m.edge_count(), 7);
}

#[test]
fn kill_operators_remove_dependents() {
    let (mut m, v, f0, f1) = two_quads();
    m.kill_face(f0).unwrap();
    m.validate().unwrap();
    assert_eq!((m.face_count(), m.edge_count(), m.loop_count()), (1, 7, 4));
    let shared = m.find_edge(v[1], v[4]).unwrap();
    m.kill_edge(shared).unwrap();
    m.validate().unwrap();
    assert!(!m.contains_face(f1));
    m.kill_vert(v[0]).unwrap();
    m.validate().unwrap();
    assert_eq!((m.vert_count(), m.edge_count(), m.face_count()), (5, 4, 0));
    assert!(m.kill_vert(v[0]).is_err());
}

#[test]
fn freed_ids_are_recycled_lowest_first() {
    let (mut m, v, f0, _) = two_quads();
    m.kill_vert(v[0]).unwrap();
    m.kill_face(f0).ok();
    let w = m.make_vert(DVec3::ONE);
    assert_eq!(w, v[0]);
    m.validate().unwrap();
}

#[test]
fn join_mesh_appends_a_copy_with_attributes() {
    let (mut a, _, _, _) = two_quads();
    let (mut b, vb, _, _) = two_quads();
    b.add_layer("age", Domain::Vert, AttrValue::Int(0)).unwrap();
    b.set_attr("age", Domain::Vert, vb[2].index(), AttrValue::Int(7));
    let map = a.join_mesh(&b);
    a.validate().unwrap();
    assert_eq!(
        (a.vert_count(), a.edge_count(), a.face_count()),
        (12, 14, 4)
    );
    let moved = map.verts[vb[2].index()].unwrap();
    assert_eq!(
        a.attr("age", Domain::Vert, moved.index()),
        Some(AttrValue::Int(7))
    );
}

#[test]
fn split_quad_writes_what_split_face_starting_at_writes() {
    // The same ids, cycles, lengths, first loops and stored normals, for
    // both diagonals; with the diagonal new, already a wire edge, already
    // another face's side; and with freed slots to reuse.
    for along_0_2 in [true, false] {
        for setup in ["new", "wire", "shared", "freed"] {
            let (mut a, v, f0, f1) = two_quads();
            // Lift a corner so the two pieces' normals differ.
            a.move_vert(v[4], v3(0.5, 1.0, 0.3));
            let ring0 = ring(&a, f0);
            let (x, y) = if along_0_2 {
                (ring0[0], ring0[2])
            } else {
                (ring0[3], ring0[1])
            };
            match setup {
                "wire" => {
                    a.make_edge(x, y).unwrap();
                }
                "shared" => {
                    let w = a.make_vert(v3(0.2, 0.5, 1.0));
                    a.make_face(&[x, y, w]).unwrap();
                }
                "freed" => {
                    a.kill_face(f1).unwrap();
                    a.kill_edge(a.find_edge(v[2], v[5]).unwrap()).unwrap();
                }
                _ => {}
            }
            let mut b = a.clone();
            let existed = a.find_edge(x, y).is_some();
            let (ga, ea) = a.split_face_starting_at(f0, x, y, ring0[0]).unwrap();
            let loops = b.quad_loops(f0).unwrap();
            let (gb, eb, made) = b.split_quad(f0, loops, along_0_2);
            assert_eq!((gb, eb, made), (ga, ea, !existed), "{setup} {along_0_2}");
            assert_eq!(format!("{b:?}"), format!("{a:?}"), "{setup} {along_0_2}");
            b.validate().unwrap();
            assert_eq!(b.quad_loops(f0), None);
        }
    }
}

#[test]
fn refresh_normals_of_writes_each_face_its_own_normal_in_any_list_order() {
    // 60 × 60 quads (several parallel runs), corners moved without a
    // refresh; then the faces refreshed from an ascending list (written in
    // place) or a shuffled one (gathered first). Both must give each
    // listed face the normal its corners give, bit for bit, and leave the
    // others alone.
    let bits = |n: DVec3| n.to_array().map(f64::to_bits);
    for ascending in [true, false] {
        let mut m = crate::kernel::ops::extrude::tests::grid(60, 60, 0.5);
        let verts: Vec<VertId> = m.vert_ids().collect();
        for (k, &v) in verts.iter().enumerate() {
            let p = m.position(v);
            let lift = ((k * 2654435761) % 1000) as f64 * 1e-3;
            m.place(v, p + DVec3::new(0.0, 0.0, lift));
        }
        let faces: Vec<FaceId> = m.face_ids().collect();
        let before: Vec<DVec3> = faces.iter().map(|&f| m.face_normal(f)).collect();
        let mut listed: Vec<FaceId> = faces
            .iter()
            .copied()
            .filter(|f| f.index() % 3 != 1)
            .collect();
        if !ascending {
            listed.reverse();
            listed.swap(0, 7);
        }
        m.refresh_normals_of(&listed);
        for (&f, &old) in faces.iter().zip(&before) {
            let expected = if f.index() % 3 != 1 {
                m.compute_face_normal(f)
            } else {
                old
            };
            assert_eq!(
                bits(m.face_normal(f)),
                bits(expected),
                "face {f} ({ascending})"
            );
        }
        assert!(listed
            .iter()
            .any(|&f| bits(m.face_normal(f)) != bits(DVec3::Z)));
    }
}
