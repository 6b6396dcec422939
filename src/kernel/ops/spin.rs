//! Spin: a lathe in the kernel (issue 35). Selected edges (a profile) are
//! swept about an axis into a band of quads; selected vertices without an
//! edge into a wire arc. Blender's `bmesh.ops.spin` is the anchor.
//!
//! Step `k` of `steps` places a ring of copies at the profile rotated by
//! `k · angle / steps` about the axis through `center` (each ring from the
//! profile's own positions, so no rounding accumulates from step to step),
//! and joins consecutive rings: a quad for each profile edge and step,
//! then the band's winding is made consistent (and outward where the lathe
//! closes into a solid, as `recompute_normals` does).
//! Two things make a lathe what an artist expects where Blender leaves
//! degenerate geometry:
//! - at a full turn (|angle| = 360°) the last ring *is* the first: the
//!   seam is closed, not two coincident rings (Blender's `use_merge`);
//! - a profile vertex on the axis is not copied: it is the pole that its
//!   edges' quads, now triangles, share (Blender makes a copy per step and
//!   a sliver quad, to be removed by "merge by distance").
//!
//! Built from Euler operators only (`make_vert`, `make_edge`, `make_face`,
//! which finds or makes the ring edges). New elements copy the attributes
//! of the profile element they come from.

use glam::{DQuat, DVec3};
use rustc_hash::FxHashMap;

use super::{into_canonical, OpError, Selection};
use crate::kernel::{EdgeId, Mesh, VertId};

/// What [`spin`] is asked to do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spin {
    /// Degrees, counter-clockwise about `axis` (right-hand rule).
    pub angle_degrees: f64,
    /// Rings made (at least 1).
    pub steps: u32,
    pub axis: DVec3,
    pub center: DVec3,
}

/// The most steps a spin may take.
pub const MAX_STEPS: u32 = 1 << 16;

/// Sweeps the profile `edges` and the lone `verts` (vertices of the
/// edges may be listed too) about the axis.
///
/// Result: the new vertices, edges and faces.
pub fn spin(
    mesh: &mut Mesh,
    edges: &[EdgeId],
    verts: &[VertId],
    options: Spin,
) -> Result<Selection, OpError> {
    let edges = into_canonical(edges.to_vec());
    for &e in &edges {
        mesh.check_edge(e)?;
    }
    for &v in verts {
        mesh.check_vert(v)?;
    }
    if !(options.angle_degrees.is_finite() && options.angle_degrees != 0.0) {
        return Err(OpError::parameter(
            "angle",
            "must be a finite, non-zero number of degrees",
        ));
    }
    if options.angle_degrees.abs() > 360.0 {
        return Err(OpError::parameter(
            "angle",
            format!("at most one turn (±360°), got {}", options.angle_degrees),
        ));
    }
    if options.steps == 0 || options.steps > MAX_STEPS {
        return Err(OpError::parameter(
            "steps",
            format!("must lie in 1..={MAX_STEPS}, got {}", options.steps),
        ));
    }
    if !options.center.is_finite() {
        return Err(OpError::parameter("center", "must be finite"));
    }
    // Scaled by its largest component first, so that neither 1e200 nor
    // 1e-200 overflows the length.
    let largest = options.axis.abs().max_element();
    let Some(axis) = (options.axis / largest)
        .try_normalize()
        .filter(|a| a.is_finite() && largest.is_finite())
    else {
        return Err(OpError::parameter(
            "axis",
            "must be a finite, non-zero vector",
        ));
    };
    let mut profile: Vec<VertId> = verts.to_vec();
    for &e in &edges {
        profile.extend(mesh.edge_verts(e));
    }
    let profile = into_canonical(profile);
    let steps = options.steps as usize;
    let full_turn = options.angle_degrees.abs() == 360.0;
    if full_turn && steps < 3 {
        return Err(OpError::parameter(
            "steps",
            format!("a full turn needs at least 3 steps, got {steps}"),
        ));
    }
    // Rings 1..=last are made; at a full turn the ring `steps` is ring 0.
    let last = if full_turn { steps - 1 } else { steps };
    let added = (profile.len() as u128) * last as u128;
    let room = |capacity: usize| u128::from(u32::MAX) - capacity as u128;
    if added > room(mesh.vert_capacity()) || 3 * added > room(mesh.edge_capacity()) {
        return Err(OpError::parameter(
            "steps",
            format!("{added} new vertices would exceed the mesh's id space"),
        ));
    }

    // Vertices on the axis stay single (poles).
    let scale = profile
        .iter()
        .map(|&v| (mesh.position(v) - options.center).length())
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let on_axis = |p: DVec3| {
        let d = p - options.center;
        (d - axis * d.dot(axis)).length() <= 1e-12 * scale
    };
    let step = options.angle_degrees.to_radians() / options.steps as f64;
    // Every ring's positions, computed once and checked before anything
    // is made (a centre far from the profile can overflow `p − center`).
    let mut placed: Vec<Vec<DVec3>> = Vec::with_capacity(last);
    for k in 1..=last {
        let turn = DQuat::from_axis_angle(axis, step * k as f64);
        let ring: Vec<DVec3> = profile
            .iter()
            .map(|&v| options.center + turn * (mesh.position(v) - options.center))
            .collect();
        if ring.iter().any(|p| !p.is_finite()) {
            return Err(OpError::Degenerate(
                "spin: a new position overflows (coordinates near the limit of f64)".into(),
            ));
        }
        placed.push(ring);
    }
    let mut made = Selection::new();
    // ring[k][i]: profile vertex i in ring k.
    let mut rings: Vec<Vec<VertId>> = vec![profile.clone()];
    for positions in &placed {
        let ring = profile
            .iter()
            .zip(positions)
            .map(|(&v, &q)| {
                if on_axis(mesh.position(v)) {
                    return v;
                }
                let c = mesh.make_vert(q);
                mesh.copy_vert_attrs(v, c);
                made.verts.push(c);
                c
            })
            .collect();
        rings.push(ring);
    }
    if full_turn {
        rings.push(profile.clone());
    }
    let index: FxHashMap<VertId, usize> =
        profile.iter().enumerate().map(|(i, &v)| (v, i)).collect();

    // Vertices of no selected edge sweep into wire arcs.
    let mut on_edges: Vec<VertId> = edges.iter().flat_map(|&e| mesh.edge_verts(e)).collect();
    on_edges = into_canonical(on_edges);
    for &v in &profile {
        if on_edges.binary_search(&v).is_ok() {
            continue;
        }
        let i = index[&v];
        for k in 0..steps {
            let (a, b) = (rings[k][i], rings[k + 1][i]);
            if a != b {
                made.edges.push(mesh.make_edge(a, b)?);
            }
        }
    }
    // Each profile edge a -> b into a band: (a_k, b_k, b_k+1, a_k+1).
    for &e in &edges {
        let [a, b] = mesh.edge_verts(e).map(|v| index[&v]);
        for k in 0..steps {
            let mut ring = vec![rings[k][a], rings[k][b], rings[k + 1][b], rings[k + 1][a]];
            ring.dedup();
            if ring.first() == ring.last() {
                ring.pop();
            }
            if ring.len() < 3 {
                continue; // an edge on the axis sweeps nothing
            }
            made.faces.push(mesh.make_face(&ring)?);
        }
    }
    // Profile edges stored in either direction give bands wound either
    // way: make the winding consistent (outward where the lathe closes).
    super::faces::recompute_normals(mesh, &made.faces, true)?;
    // The edges the faces made are the ones with a new end.
    let new: rustc_hash::FxHashSet<VertId> = made.verts.iter().copied().collect();
    let faces = made.faces.clone();
    for f in faces {
        for e in mesh.face_edges(f).collect::<Vec<_>>() {
            if mesh.edge_verts(e).iter().any(|v| new.contains(v)) {
                made.edges.push(e);
            }
        }
    }
    made.normalize();
    Ok(made)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn profile(mesh: &mut Mesh, points: &[DVec3]) -> Vec<EdgeId> {
        let v: Vec<VertId> = points.iter().map(|&p| mesh.make_vert(p)).collect();
        // Edges stored in alternating directions: the band must still be
        // consistently wound.
        v.windows(2)
            .enumerate()
            .map(|(i, w)| {
                let (a, b) = if i % 2 == 0 {
                    (w[0], w[1])
                } else {
                    (w[1], w[0])
                };
                mesh.make_edge(a, b).unwrap()
            })
            .collect()
    }

    fn turn(angle_degrees: f64, steps: u32) -> Spin {
        Spin {
            angle_degrees,
            steps,
            axis: DVec3::Z,
            center: DVec3::ZERO,
        }
    }

    #[test]
    fn a_profile_touching_the_axis_lathes_into_a_closed_prism() {
        let mut mesh = Mesh::new();
        let edges = profile(
            &mut mesh,
            &[
                DVec3::new(0.0, 0.0, -1.0),
                DVec3::new(1.0, 0.0, -1.0),
                DVec3::new(1.0, 0.0, 1.0),
                DVec3::new(0.0, 0.0, 1.0),
            ],
        );
        let n = 16;
        let made = spin(&mut mesh, &edges, &[], turn(360.0, n)).unwrap();
        mesh.validate().unwrap();
        // Two poles and two rings of n: the seam and the poles merged.
        assert_eq!(mesh.vert_count(), 2 + 2 * n as usize);
        assert_eq!(made.faces.len(), 3 * n as usize);
        let report = mesh.report();
        assert!(report.watertight && report.manifold && report.consistently_oriented);
        // An n-gon prism of circumradius 1 and height 2, wound outward.
        let area = f64::from(n) / 2.0 * libm::sin(std::f64::consts::TAU / f64::from(n));
        let volume = report.volume.unwrap();
        assert!((volume - 2.0 * area).abs() < 1e-12, "{volume}");
    }

    #[test]
    fn a_partial_turn_leaves_both_ends_and_vertices_sweep_arcs() {
        let mut mesh = Mesh::new();
        let edges = profile(
            &mut mesh,
            &[DVec3::new(1.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 1.0)],
        );
        spin(&mut mesh, &edges, &[], turn(90.0, 3)).unwrap();
        mesh.validate().unwrap();
        assert_eq!((mesh.vert_count(), mesh.face_count()), (8, 3));
        assert_eq!(mesh.report().boundary_edges, 8);
        // The last ring sits at exactly a quarter turn.
        let far = mesh
            .vert_ids()
            .map(|v| mesh.position(v))
            .max_by(|a, b| a.y.total_cmp(&b.y))
            .unwrap();
        assert!((far - DVec3::new(0.0, 1.0, far.z)).length() < 1e-15);

        let mut mesh = Mesh::new();
        let v = mesh.make_vert(DVec3::new(2.0, 0.0, 0.0));
        let made = spin(&mut mesh, &[], &[v], turn(360.0, 8)).unwrap();
        mesh.validate().unwrap();
        assert_eq!(
            (made.verts.len(), made.edges.len(), mesh.face_count()),
            (7, 8, 0)
        );
    }

    #[test]
    fn bad_parameters_are_refused_before_anything_is_made() {
        let mut mesh = Mesh::new();
        let edges = profile(&mut mesh, &[DVec3::X, DVec3::new(1.0, 0.0, 1.0)]);
        for (options, name) in [
            (turn(0.0, 4), "angle"),
            (turn(400.0, 4), "angle"),
            (turn(f64::NAN, 4), "angle"),
            (turn(90.0, 0), "steps"),
            (turn(360.0, 2), "steps"),
            (
                Spin {
                    axis: DVec3::new(1e300, 0.0, 0.0),
                    angle_degrees: f64::NAN,
                    ..turn(90.0, 4)
                },
                "angle",
            ),
            (
                Spin {
                    axis: DVec3::ZERO,
                    ..turn(90.0, 4)
                },
                "axis",
            ),
        ] {
            let err = spin(&mut mesh, &edges, &[], options).unwrap_err();
            assert!(
                matches!(err, OpError::Parameter { name: n, .. } if n == name),
                "{err}"
            );
            assert_eq!(mesh.vert_count(), 2);
        }
        // A centre far from the profile overflows `p − center`.
        let far = Spin {
            center: DVec3::new(-1.5e308, 0.0, 0.0),
            ..turn(90.0, 4)
        };
        let mut mesh = Mesh::new();
        let edges = profile(
            &mut mesh,
            &[DVec3::new(1.5e308, 0.0, 0.0), DVec3::new(1.5e308, 0.0, 1.0)],
        );
        let err = spin(&mut mesh, &edges, &[], far).unwrap_err();
        assert!(err.to_string().contains("overflows"), "{err}");
        assert_eq!(mesh.vert_count(), 2);
        // A huge or tiny axis is still a direction.
        for scale in [1e300, 1e-300] {
            let mut mesh = Mesh::new();
            let edges = profile(&mut mesh, &[DVec3::X, DVec3::new(1.0, 0.0, 1.0)]);
            let tilted = Spin {
                axis: DVec3::Z * scale,
                ..turn(90.0, 2)
            };
            spin(&mut mesh, &edges, &[], tilted).unwrap();
            mesh.validate().unwrap();
        }
    }
}
