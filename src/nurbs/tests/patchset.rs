//! Patch sets (issue 37): shared borders found exactly or declared, and meshed conformingly in
//! every mode — one vertex per border sample, bit-identical on both sides.

use crate::nurbs::mesh::TriMesh;
use crate::nurbs::patchset::{BorderRef, Join, PatchSet, Side};
use crate::nurbs::surface::NurbsSurface;
use crate::nurbs::tess::{tessellate_set, AdaptiveOptions, Diagonal, Initial, Mode, TessError};

/// Height along the shared border x = 3: chosen so that evaluating it at t and at 1 − t gives
/// different last bits (the crack the issue saw at z = 0.15).
fn bump(j: usize) -> f64 {
    [0.0, 0.45, 0.05, 0.3][j]
}

/// A: x ∈ [0, 3], u along +x, v along +y. B: x ∈ [3, 6], u along −y, v along +x, so B's side
/// v0 is A's side u1 run backwards; both face +z.
fn two_patches(offset: f64) -> Vec<NurbsSurface> {
    let mut a = Vec::new();
    for i in 0..4 {
        for j in 0..4 {
            let z = if i == 3 {
                bump(j)
            } else {
                0.1 * (i * j) as f64
            };
            a.push([i as f64, j as f64, z]);
        }
    }
    let mut b = Vec::new();
    for i in 0..4 {
        for j in 0..4 {
            let (x, y) = (3.0 + j as f64, 3.0 - i as f64);
            let z = if j == 0 {
                bump(3 - i) + offset
            } else {
                0.2 * (j as f64) * (i as f64 - 1.5)
            };
            b.push([x, y, z]);
        }
    }
    vec![
        NurbsSurface::clamped([3, 3], [4, 4], &a, None).unwrap(),
        NurbsSurface::clamped([3, 3], [4, 4], &b, None).unwrap(),
    ]
}

fn modes() -> Vec<(&'static str, Mode)> {
    vec![
        (
            "uniform",
            Mode::Uniform {
                cells: [8, 8],
                per_patch: false,
                diagonal: Diagonal::Fixed,
            },
        ),
        (
            "uniform 8 × 3",
            Mode::Uniform {
                cells: [8, 3],
                per_patch: false,
                diagonal: Diagonal::Fixed,
            },
        ),
        ("interpatch", Mode::InterPatch { tolerance: 1e-3 }),
        ("adaptive", Mode::Adaptive(AdaptiveOptions::sagitta(1e-4))),
        (
            "adaptive from the thesis's per-patch levels",
            Mode::Adaptive(AdaptiveOptions {
                initial: Initial::InterPatch { tolerance: 1e-3 },
                ..AdaptiveOptions::sagitta(1e-4)
            }),
        ),
    ]
}

/// Boundary loops of a mesh (components of its boundary edges).
pub(crate) fn boundary_loops(mesh: &TriMesh) -> usize {
    let census = mesh.edge_census();
    let mut parent: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            x = p[x as usize];
        }
        x
    }
    let mut on = vec![false; mesh.positions.len()];
    for e in &census.boundary {
        on[e[0] as usize] = true;
        on[e[1] as usize] = true;
        let (a, b) = (find(&mut parent, e[0]), find(&mut parent, e[1]));
        parent[a.max(b) as usize] = a.min(b);
    }
    (0..mesh.positions.len() as u32)
        .filter(|&v| on[v as usize] && find(&mut parent, v) == v)
        .count()
}

/// Distinct vertices at bit-identical positions: the crack vertices a weld would hide.
pub(crate) fn crack_vertices(mesh: &TriMesh) -> usize {
    let mut keys: Vec<[u64; 3]> = mesh
        .positions
        .iter()
        .map(|p| p.map(|x| (x + 0.0).to_bits()))
        .collect();
    keys.sort_unstable();
    let n = keys.len();
    keys.dedup();
    n - keys.len()
}

#[test]
fn the_shared_border_is_found_reversed() {
    let set = PatchSet::new(two_patches(0.0));
    let groups = set.borders().unwrap();
    assert_eq!(groups.len(), 1);
    let g = &groups[0];
    assert_eq!(
        g.members,
        vec![
            BorderRef {
                surface: 0,
                side: Side::U1
            },
            BorderRef {
                surface: 1,
                side: Side::V0
            }
        ]
    );
    assert_eq!(g.reversed, vec![false, true]);
}

#[test]
fn two_patches_with_a_reversed_border_mesh_as_one() {
    let set = PatchSet::new(two_patches(0.0));
    for (name, mode) in modes() {
        let t = tessellate_set(&set, &mode, 1_000_000).unwrap();
        let census = t.mesh.edge_census();
        assert_eq!(census.non_manifold, 0, "{name}");
        assert_eq!(census.misoriented, 0, "{name}");
        assert_eq!(census.degenerate, 0, "{name}");
        assert_eq!(
            boundary_loops(&t.mesh),
            1,
            "{name}: one outline around both"
        );
        assert_eq!(crack_vertices(&t.mesh), 0, "{name}");
        // No boundary edge on the shared border x = 3 (except none: it is interior now).
        let on_seam = census
            .boundary
            .iter()
            .filter(|e| e.iter().all(|&v| t.mesh.positions[v as usize][0] == 3.0))
            .filter(|e| {
                let y = |v: u32| t.mesh.positions[v as usize][1];
                y(e[0]) > 0.0 && y(e[0]) < 3.0 || y(e[1]) > 0.0 && y(e[1]) < 3.0
            })
            .count();
        assert_eq!(on_seam, 0, "{name}: the shared border is interior");
        assert!(t.stats.max_deviation.is_finite(), "{name}");
    }
}

#[test]
fn uniform_counts_follow_the_neighbour() {
    // A's shared side runs along v (3 cells asked), B's along u (8 cells): both get 8.
    let set = PatchSet::new(two_patches(0.0));
    let mode = Mode::Uniform {
        cells: [8, 3],
        per_patch: false,
        diagonal: Diagonal::Fixed,
    };
    let t = tessellate_set(&set, &mode, 1_000_000).unwrap();
    // A: 8 × 8 cells, B: 8 × 3: 2 · (64 + 24) triangles.
    assert_eq!(t.mesh.triangles.len(), 2 * (64 + 24));
    assert_eq!(t.stats.patch_levels, vec![[8, 8], [8, 3]]);
}

#[test]
fn an_almost_equal_border_needs_a_declared_join() {
    let surfaces = two_patches(1e-9);
    let mode = Mode::Uniform {
        cells: [8, 8],
        per_patch: false,
        diagonal: Diagonal::Fixed,
    };
    let loose = tessellate_set(&PatchSet::new(surfaces.clone()), &mode, 1_000_000).unwrap();
    assert_eq!(
        boundary_loops(&loose.mesh),
        2,
        "not exactly equal: two patches"
    );
    let join = Join {
        a: BorderRef {
            surface: 0,
            side: Side::U1,
        },
        b: BorderRef {
            surface: 1,
            side: Side::V0,
        },
    };
    let set = PatchSet {
        surfaces: surfaces.clone(),
        joins: vec![join],
    };
    let joined = tessellate_set(&set, &mode, 1_000_000).unwrap();
    assert_eq!(boundary_loops(&joined.mesh), 1);
    assert_eq!(joined.mesh.edge_census().non_manifold, 0);
    // A join between borders that are far apart is refused.
    let far = PatchSet {
        surfaces: two_patches(1e-3),
        joins: vec![join],
    };
    match tessellate_set(&far, &mode, 1_000_000) {
        Err(TessError::Join(message)) => assert!(message.contains("differ by up to"), "{message}"),
        other => panic!("expected a join error, got {other:?}"),
    }
    // A join naming a surface that is not there.
    let missing = PatchSet {
        surfaces,
        joins: vec![Join {
            a: join.a,
            b: BorderRef {
                surface: 5,
                side: Side::U0,
            },
        }],
    };
    assert!(matches!(
        tessellate_set(&missing, &mode, 1_000_000),
        Err(TessError::Join(_))
    ));
}

#[test]
fn a_set_is_deterministic_and_capped() {
    let set = PatchSet::new(two_patches(0.0));
    let mode = Mode::Adaptive(AdaptiveOptions::sagitta(1e-4));
    let a = tessellate_set(&set, &mode, 1_000_000).unwrap();
    let b = tessellate_set(&set, &mode, 1_000_000).unwrap();
    assert_eq!(a, b);
    let cap = a.mesh.triangles.len() / 2;
    assert!(matches!(
        tessellate_set(&set, &mode, cap),
        Err(TessError::TriangleLimit { .. })
    ));
}

#[test]
fn many_coincident_patches_stay_linear() {
    // A hostile set: 2,000 copies of one patch. Every border is shared by 2,000 sides; the
    // exchange and the weld compare each with the first, so this stays fast.
    let one = two_patches(0.0).remove(0);
    let set = PatchSet::new(vec![one; 2000]);
    let mode = Mode::Uniform {
        cells: [2, 2],
        per_patch: false,
        diagonal: Diagonal::Fixed,
    };
    let t = tessellate_set(&set, &mode, 1_000_000).unwrap();
    assert_eq!(t.mesh.triangles.len(), 2000 * 8);
    // The copies share their 8 border vertices; each keeps its own centre.
    assert_eq!(t.mesh.positions.len(), 8 + 2000);
    assert_eq!(t.mesh.edge_census().boundary.len(), 0);
}
