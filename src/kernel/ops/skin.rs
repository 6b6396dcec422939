//! Skin: turns the wire edges of a mesh (a G³ skeleton) into closed tubes.
//!
//! The skeleton is cut into *chains*: paths along which each node joins
//! exactly two of its edges. A node of degree 2 always joins its two; at a
//! branch node the two edges closest to a straight line continue each
//! other and the others start (or end) there. Every chain becomes one tube
//! in a *new* mesh: a ring of `sides` vertices per node, perpendicular to
//! the chain (at a bend, to the bisector of its two edges, widened in the
//! bend plane so the tube keeps its thickness), quads between consecutive
//! rings and a cap at both ends. So a skeleton's tubes share no ring: no two
//! output vertices coincide, and no skeleton node is left behind. With
//! `joints`, every branch node (degree 3 or more) also gets a low-poly UV
//! sphere of its radius, turned half a segment so its vertices miss the
//! rings. Tubes and spheres are separate closed components that may overlap
//! at branches (there is no boolean union: the field skin of the SDF pillar
//! makes one solid); each is wound outward, so the whole output is
//! watertight.
//!
//! Output order is deterministic: chains in ascending order of their lowest
//! edge id, then joints in ascending vertex id order. A chain's first ring
//! is turned about its edge by the start node's `left` vector (or a world
//! axis) and later rings follow it by parallel transport; angles go through
//! `libm`, so positions are bit-identical on every platform.
//!
//! ```
//! use glam::DVec3;
//! use graftal::kernel::{Mesh, ops::skin::{skin_wire_edges, SkinOptions}};
//! let mut skeleton = Mesh::new();
//! let root = skeleton.make_vert(DVec3::ZERO);
//! skeleton.make_edge_vert(root, DVec3::Z).unwrap();
//! let tube = skin_wire_edges(&skeleton, &SkinOptions::default()).unwrap();
//! assert!(tube.report().watertight);
//! ```

use glam::DVec3;

use super::create::create_uv_sphere;
use super::OpError;
use crate::geom::frame::any_perpendicular;
use crate::kernel::attrs::{AttrValue, LayerKind};
use crate::kernel::ids::{Domain, VertId};
use crate::kernel::mesh::Mesh;

/// Vertex scalar layer holding node radii; copied to the output.
const RADIUS: &str = "radius";
/// Vertex vector layer fixing the ring's rotation about the edge.
const LEFT: &str = "left";

/// How [`skin_wire_edges`] shapes the tubes.
#[derive(Debug, Clone, PartialEq)]
pub struct SkinOptions {
    /// Sides of the cross-section polygon; at least 3.
    pub sides: u32,
    /// Node radius when the mesh has no `radius` vertex layer.
    pub default_radius: f64,
    /// Whether nodes joining two or more edges get a sphere.
    pub joints: bool,
}

impl Default for SkinOptions {
    fn default() -> Self {
        Self {
            sides: 8,
            default_radius: 0.1,
            joints: true,
        }
    }
}

/// One edge to skin: its ends (start, end) and their radii.
struct Tube {
    ends: [VertId; 2],
    radii: [f64; 2],
}

/// Builds tubes for every wire edge of `mesh` into a new mesh.
///
/// Radii come from the scalar vertex layer `radius`, else
/// `options.default_radius`; a radius that is not positive and finite, a
/// `radius` layer of another kind, a non-finite edge or `sides < 3` is a
/// parameter error, reported before anything is built. Zero-length edges are
/// skipped (they have no axis). If the input has the `radius` layer, every
/// output vertex gets the radius of the node it was made for.
pub fn skin_wire_edges(mesh: &Mesh, options: &SkinOptions) -> Result<Mesh, OpError> {
    if options.sides < 3 {
        return Err(OpError::parameter(
            "sides",
            format!("must be at least 3, got {}", options.sides),
        ));
    }
    // First pass: check every input and count, so nothing is built on error.
    let mut tubes = Vec::new();
    let mut degree = vec![0u32; mesh.vert_capacity()];
    for e in mesh.edge_ids().filter(|&e| mesh.is_wire_edge(e)) {
        let ends = mesh.edge_verts(e);
        let length = (mesh.position(ends[1]) - mesh.position(ends[0])).length();
        if !length.is_finite() {
            return Err(OpError::parameter(
                "position",
                format!("edge {e} has a non-finite length"),
            ));
        }
        if length == 0.0 {
            continue;
        }
        let radii = [
            node_radius(mesh, ends[0], options)?,
            node_radius(mesh, ends[1], options)?,
        ];
        for v in ends {
            degree[v.index()] += 1;
        }
        tubes.push(Tube { ends, radii });
    }
    let joints: Vec<VertId> = if options.joints {
        mesh.vert_ids().filter(|v| degree[v.index()] >= 3).collect()
    } else {
        Vec::new()
    };
    let rings = (options.sides / 2).max(2);
    check_budget(tubes.len(), joints.len(), options.sides, rings)?;

    let mut out = Mesh::new();
    let radius_default = mesh
        .attributes()
        .layer(RADIUS, Domain::Vert)
        .filter(|layer| layer.kind() == LayerKind::Scalar)
        .map(|layer| layer.default);
    if let Some(default) = radius_default {
        out.add_layer(RADIUS, Domain::Vert, default)
            .map_err(|_| OpError::parameter("radius", "cannot add the output layer"))?;
    }
    let copy_radius = radius_default.is_some();

    for chain in chains(mesh, &tubes) {
        build_tube(&mut out, mesh, &chain, options, copy_radius)?;
    }
    // Half a segment: a vertical tube's ring at the joint would otherwise
    // coincide with the sphere's equator.
    let half = std::f64::consts::PI / f64::from(options.sides);
    let turn = glam::DQuat::from_axis_angle(DVec3::Z, half);
    for &v in &joints {
        let radius = node_radius(mesh, v, options)?;
        let sphere = create_uv_sphere(&mut out, options.sides, rings, radius)?;
        let center = mesh.position(v);
        for &w in &sphere.verts {
            out.place(w, turn * out.position(w) + center);
            if copy_radius {
                set_radius(&mut out, w, radius);
            }
        }
        // Turning moved the faces: their stored normals follow.
        for &f in &sphere.faces {
            out.refresh_normal(f);
        }
    }
    Ok(out)
}

/// A path of tubes: its nodes in order (one more than its tubes).
struct Chain {
    nodes: Vec<VertId>,
    radii: Vec<f64>,
}

/// Cuts the skeleton into chains (see the module doc). Deterministic: the
/// pairing at each node depends only on positions and edge order, chains
/// come in order of their lowest tube index, and a closed loop is cut at
/// its lowest tube's start.
fn chains(mesh: &Mesh, tubes: &[Tube]) -> Vec<Chain> {
    // Tubes at each node, by tube index (ascending: edge id order).
    let mut at: Vec<Vec<usize>> = vec![Vec::new(); mesh.vert_capacity()];
    for (i, t) in tubes.iter().enumerate() {
        for v in t.ends {
            at[v.index()].push(i);
        }
    }
    let away = |t: usize, v: VertId| -> DVec3 {
        let [a, b] = tubes[t].ends;
        let other = if a == v { b } else { a };
        (mesh.position(other) - mesh.position(v)).normalize()
    };
    // partner[(t, end)] = the tube continuing tube t through its end `end`.
    let mut partner: Vec<[Option<usize>; 2]> = vec![[None; 2]; tubes.len()];
    for v in mesh.vert_ids() {
        let here = &at[v.index()];
        if here.len() < 2 {
            continue;
        }
        // The most nearly opposite pair (ties: lowest indices).
        let mut best: Option<(f64, usize, usize)> = None;
        for (k, &t) in here.iter().enumerate() {
            for &u in &here[k + 1..] {
                let straightness = -away(t, v).dot(away(u, v));
                if best.is_none_or(|(s, _, _)| straightness > s) {
                    best = Some((straightness, t, u));
                }
            }
        }
        let (_, t, u) = best.expect("two tubes at least");
        let end_of = |t: usize| usize::from(tubes[t].ends[1] == v);
        partner[t][end_of(t)] = Some(u);
        partner[u][end_of(u)] = Some(t);
    }
    let mut used = vec![false; tubes.len()];
    let mut out = Vec::new();
    for first in 0..tubes.len() {
        if used[first] {
            continue;
        }
        // Walk back to the chain's start (or once round a loop).
        let (mut t, mut entry) = (first, 0usize);
        loop {
            let node = tubes[t].ends[entry];
            match partner[t][entry] {
                Some(prev) if prev != first => {
                    entry = 1 - usize::from(tubes[prev].ends[1] == node);
                    t = prev;
                }
                _ => break,
            }
        }
        // Walk forward from (t, entry), marking tubes.
        let start = tubes[t].ends[entry];
        let mut nodes = vec![start];
        let mut radii = vec![tubes[t].radii[entry]];
        loop {
            used[t] = true;
            let exit = 1 - entry;
            nodes.push(tubes[t].ends[exit]);
            radii.push(tubes[t].radii[exit]);
            match partner[t][exit] {
                Some(next) if !used[next] => {
                    let node = tubes[t].ends[exit];
                    entry = usize::from(tubes[next].ends[1] == node);
                    t = next;
                }
                _ => break,
            }
        }
        out.push(Chain { nodes, radii });
    }
    out
}

/// One closed tube along `chain`: a ring per node, quads between rings, a
/// cap at each end.
fn build_tube(
    out: &mut Mesh,
    mesh: &Mesh,
    chain: &Chain,
    options: &SkinOptions,
    copy_radius: bool,
) -> Result<(), OpError> {
    let points: Vec<DVec3> = chain.nodes.iter().map(|&v| mesh.position(v)).collect();
    let k = points.len() - 1;
    let directions: Vec<DVec3> = points
        .windows(2)
        .map(|w| (w[1] - w[0]).normalize())
        .collect();
    let sides = options.sides;
    let mut u = reference_perpendicular(mesh, [chain.nodes[0], chain.nodes[1]], directions[0]);
    let mut rings: Vec<Vec<VertId>> = Vec::with_capacity(k + 1);
    for i in 0..=k {
        let (before, after) = (directions[i.saturating_sub(1)], directions[i.min(k - 1)]);
        let bisector = before + after;
        // A reversal has no bisector: the ring then faces the next edge.
        let normal = if bisector.length() > 1e-9 {
            bisector.normalize()
        } else {
            after
        };
        // Parallel transport keeps the rings from twisting along the chain.
        let projected = u - normal * u.dot(normal);
        u = if projected.length() > 1e-9 {
            projected.normalize()
        } else {
            reference_perpendicular(
                mesh,
                [chain.nodes[i.min(k - 1)], chain.nodes[i.min(k - 1) + 1]],
                normal,
            )
        };
        let v = normal.cross(u);
        // At a bend the ring is cut obliquely through the tube: widen it in
        // the bend plane by 1 / cos(half the bend), at most twice.
        let bend = after - before;
        let in_plane = bend - normal * bend.dot(normal);
        let (widen_dir, widen) = if in_plane.length() > 1e-9 {
            let cos_half = normal.dot(after).clamp(0.5, 1.0);
            (in_plane.normalize(), 1.0 / cos_half)
        } else {
            (DVec3::ZERO, 1.0)
        };
        let (center, radius) = (points[i], chain.radii[i]);
        let ring: Vec<VertId> = (0..sides)
            .map(|j| {
                let (c, s) = if j == 0 {
                    (1.0, 0.0)
                } else {
                    let angle = std::f64::consts::TAU * f64::from(j) / f64::from(sides);
                    (libm::cos(angle), libm::sin(angle))
                };
                let mut offset = u * (radius * c) + v * (radius * s);
                offset += widen_dir * (offset.dot(widen_dir) * (widen - 1.0));
                let w = out.make_vert(center + offset);
                if copy_radius {
                    set_radius(out, w, radius);
                }
                w
            })
            .collect();
        rings.push(ring);
    }
    // (u, v, normal) is right-handed, so rings run counter-clockwise seen
    // from ahead along the chain: the winding create_cylinder uses along +Z.
    let n = sides as usize;
    for pair in rings.windows(2) {
        let (bottom, top) = (&pair[0], &pair[1]);
        for j in 0..n {
            let next = (j + 1) % n;
            out.make_face(&[bottom[j], bottom[next], top[next], top[j]])?;
        }
    }
    // Seen from outside the start end, its ring runs the other way.
    let start_cap: Vec<VertId> = rings[0].iter().rev().copied().collect();
    out.make_face(&start_cap)?;
    out.make_face(&rings[k])?;
    Ok(())
}

/// The checked radius of node `v`.
pub fn node_radius(mesh: &Mesh, v: VertId, options: &SkinOptions) -> Result<f64, OpError> {
    let radius = match mesh.attr(RADIUS, Domain::Vert, v.index()) {
        None => options.default_radius,
        Some(AttrValue::Scalar(r)) => r,
        Some(other) => {
            return Err(OpError::parameter(
                "radius",
                format!(
                    "the `radius` vertex layer must be scalar, not {:?}",
                    other.kind()
                ),
            ))
        }
    };
    if !(radius.is_finite() && radius > 0.0) {
        return Err(OpError::parameter(
            "radius",
            format!("node {v} has radius {radius}; it must be positive and finite"),
        ));
    }
    Ok(radius)
}

/// Refuses output whose ids would overflow `u32` (the arenas would panic).
/// Loops outnumber every other element of a closed surface, so bounding them
/// bounds all.
fn check_budget(tubes: usize, joints: usize, sides: u32, rings: u32) -> Result<(), OpError> {
    let (s, r) = (u128::from(sides), u128::from(rings));
    // A frustum: s quads and two s-gon caps. A sphere: 2s pole triangles and
    // s(r-2) quads.
    let loops = tubes as u128 * 6 * s + joints as u128 * (6 * s + 4 * s * (r - 2));
    if loops > u128::from(u32::MAX) {
        return Err(OpError::parameter(
            "sides",
            "the tubes would exceed the 2^32 element limit",
        ));
    }
    Ok(())
}

/// A unit vector perpendicular to `axis` fixing the ring rotation: the
/// `left` vector of the start node (else the end node) if it has one not
/// parallel to the edge, otherwise the world axis least aligned with the
/// edge (ties go to X, then Y), Gram–Schmidt'ed against `axis`.
fn reference_perpendicular(mesh: &Mesh, ends: [VertId; 2], axis: DVec3) -> DVec3 {
    let from_left = ends
        .iter()
        .find_map(|&v| match mesh.attr(LEFT, Domain::Vert, v.index()) {
            Some(AttrValue::Vector(left)) if left.is_finite() => {
                let perp = left - axis * left.dot(axis);
                // Relative test: a near-parallel `left` would give a noisy frame.
                (perp.length() > 1e-6 * left.length()).then(|| perp.normalize())
            }
            _ => None,
        });
    from_left.unwrap_or_else(|| any_perpendicular(axis))
}

fn set_radius(out: &mut Mesh, v: VertId, radius: f64) {
    // The layer was added with scalar kind, so this cannot mismatch.
    let _ = out.set_attr(RADIUS, Domain::Vert, v.index(), AttrValue::Scalar(radius));
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// A skeleton from `points` and `edges` (index pairs) with an optional
    /// `radius` layer.
    fn skeleton(points: &[DVec3], edges: &[(usize, usize)], radii: Option<&[f64]>) -> Mesh {
        let mut m = Mesh::new();
        let verts: Vec<VertId> = points.iter().map(|&p| m.make_vert(p)).collect();
        for &(a, b) in edges {
            m.make_edge(verts[a], verts[b]).unwrap();
        }
        if let Some(radii) = radii {
            m.add_layer(RADIUS, Domain::Vert, AttrValue::Scalar(1.0))
                .unwrap();
            for (&v, &r) in verts.iter().zip(radii) {
                m.set_attr(RADIUS, Domain::Vert, v.index(), AttrValue::Scalar(r))
                    .unwrap()
                    .unwrap();
            }
        }
        m
    }

    fn options(sides: u32) -> SkinOptions {
        SkinOptions {
            sides,
            ..SkinOptions::default()
        }
    }

    /// Distance of `p` from the line through `a` along unit `axis`.
    fn off_axis(p: DVec3, a: DVec3, axis: DVec3) -> f64 {
        let d = p - a;
        (d - axis * d.dot(axis)).length()
    }

    #[test]
    fn single_edge_is_one_closed_frustum_of_the_right_volume() {
        let (a, b) = (DVec3::new(0.5, -1.0, 0.25), DVec3::new(1.5, 1.0, 2.25));
        let (ra, rb) = (0.5, 0.25);
        let m = skeleton(&[a, b], &[(0, 1)], Some(&[ra, rb]));
        let h = (b - a).length();
        let axis = (b - a) / h;
        for sides in [3, 8, 512] {
            let out = skin_wire_edges(&m, &options(sides)).unwrap();
            out.validate().unwrap();
            let r = out.report();
            let s = sides as usize;
            assert_eq!((r.verts, r.edges, r.faces), (2 * s, 3 * s, s + 2));
            assert!(r.watertight && r.manifold, "{r:?}");
            assert_eq!(r.components, 1);
            assert_eq!(r.euler_characteristic, 2);
            // Similar polygonal ends: V = h/3 (A1 + A2 + sqrt(A1 A2)).
            let polygon =
                |radius: f64| 0.5 * sides as f64 * radius * radius * (TAU / sides as f64).sin();
            let (pa, pb) = (polygon(ra), polygon(rb));
            let exact = h / 3.0 * (pa + pb + (pa * pb).sqrt());
            let volume = r.volume.unwrap();
            assert!((volume - exact).abs() < 1e-10, "{volume} vs {exact}");
            if sides == 512 {
                let cone = TAU / 6.0 * h * (ra * ra + ra * rb + rb * rb);
                assert!((volume - cone).abs() < 1e-4 * cone, "{volume} vs {cone}");
            }
            for w in out.vert_ids() {
                let p = out.position(w);
                let Some(AttrValue::Scalar(radius)) = out.attr(RADIUS, Domain::Vert, w.index())
                else {
                    panic!("the radius layer is copied");
                };
                assert!(radius == ra || radius == rb);
                let center = if radius == ra { a } else { b };
                assert!((off_axis(p, a, axis) - radius).abs() < 1e-12);
                assert!(
                    (p - center).dot(axis).abs() < 1e-12,
                    "ring is perpendicular"
                );
            }
        }
    }

    #[test]
    fn y_tree_with_joints_is_closed_everywhere() {
        let points = [
            DVec3::ZERO,
            DVec3::Z,
            DVec3::new(0.5, 0.0, 2.0),
            DVec3::new(-0.5, 0.3, 2.0),
        ];
        let m = skeleton(
            &points,
            &[(0, 1), (1, 2), (1, 3)],
            Some(&[0.3, 0.2, 0.1, 0.1]),
        );
        let out = skin_wire_edges(&m, &options(8)).unwrap();
        out.validate().unwrap();
        let r = out.report();
        // The trunk continues into the straighter branch (one tube of three
        // rings), the other branch is a tube of its own, and the fork gets
        // a sphere; overlapping but each closed.
        assert_eq!(r.components, 3);
        assert!(r.watertight && r.manifold && r.wire_edges == 0, "{r:?}");
        assert_eq!(r.euler_characteristic, 2 * 3);
        assert!(r.volume.unwrap() > 0.0);
        let sphere_verts = 8 * 3 + 2;
        assert_eq!(r.verts, 3 * 8 + 2 * 8 + sphere_verts);
        // The sphere is the last component: centred on the fork, its radius.
        let last: Vec<VertId> = out.vert_ids().skip(5 * 8).collect();
        for &w in &last {
            assert!(((out.position(w) - DVec3::Z).length() - 0.2).abs() < 1e-12);
        }
        // No two output vertices coincide: rings are not repeated where
        // tubes meet, and the sphere is turned off the rings.
        assert!(crate::kernel::intersect::close_vertices(&out, 1e-9).is_empty());

        let without = skin_wire_edges(
            &m,
            &SkinOptions {
                joints: false,
                ..options(8)
            },
        )
        .unwrap();
        without.validate().unwrap();
        assert_eq!(without.report().components, 2);
    }

    #[test]
    fn a_straight_chain_is_one_tube_with_one_ring_per_node() {
        // A vertical chain of four nodes, each joining two edges: the old
        // skin made three frusta with coincident end rings and spheres whose
        // equators lay on them.
        let points: Vec<DVec3> = (0..4).map(|k| DVec3::new(0.0, 0.0, f64::from(k))).collect();
        let m = skeleton(&points, &[(0, 1), (1, 2), (2, 3)], Some(&[0.2; 4]));
        let out = skin_wire_edges(&m, &options(8)).unwrap();
        out.validate().unwrap();
        let r = out.report();
        assert_eq!((r.verts, r.faces, r.components), (32, 3 * 8 + 2, 1));
        assert!(r.watertight && r.manifold);
        assert!(crate::kernel::intersect::close_vertices(&out, 1e-9).is_empty());
        // A bent chain keeps its thickness at the bend: the ring there is
        // widened by 1 / cos(45°) in the bend plane.
        let bent = skeleton(
            &[DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0)],
            &[(0, 1), (1, 2)],
            Some(&[0.1; 3]),
        );
        let out = skin_wire_edges(&bent, &options(4)).unwrap();
        out.validate().unwrap();
        assert!(out.report().watertight);
        let middle: Vec<DVec3> = out
            .vert_ids()
            .skip(4)
            .take(4)
            .map(|v| out.position(v))
            .collect();
        let widest = middle
            .iter()
            .map(|p| (*p - DVec3::X).length())
            .fold(0.0, f64::max);
        assert!(
            (widest - 0.1 * std::f64::consts::SQRT_2).abs() < 1e-12,
            "{widest}"
        );
    }

    #[test]
    fn missing_radius_layer_uses_the_default() {
        let m = skeleton(&[DVec3::ZERO, DVec3::new(0.0, 3.0, 0.0)], &[(0, 1)], None);
        let out = skin_wire_edges(
            &m,
            &SkinOptions {
                default_radius: 0.75,
                ..options(6)
            },
        )
        .unwrap();
        out.validate().unwrap();
        assert!(out.attributes().layer(RADIUS, Domain::Vert).is_none());
        for w in out.vert_ids() {
            assert!((off_axis(out.position(w), DVec3::ZERO, DVec3::Y) - 0.75).abs() < 1e-12);
        }
    }

    #[test]
    fn bad_radii_and_sides_are_errors() {
        let points = [DVec3::ZERO, DVec3::X];
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let m = skeleton(&points, &[(0, 1)], Some(&[1.0, bad]));
            assert!(matches!(
                skin_wire_edges(&m, &options(8)),
                Err(OpError::Parameter { name: "radius", .. })
            ));
            let m = skeleton(&points, &[(0, 1)], None);
            let o = SkinOptions {
                default_radius: bad,
                ..options(8)
            };
            assert!(skin_wire_edges(&m, &o).is_err());
        }
        let m = skeleton(&points, &[(0, 1)], None);
        assert!(matches!(
            skin_wire_edges(&m, &options(2)),
            Err(OpError::Parameter { name: "sides", .. })
        ));
        let mut vector = skeleton(&points, &[(0, 1)], None);
        vector
            .add_layer(RADIUS, Domain::Vert, AttrValue::Vector(DVec3::ONE))
            .unwrap();
        assert!(skin_wire_edges(&vector, &options(8)).is_err());
    }

    #[test]
    fn only_wire_edges_of_nonzero_length_are_skinned() {
        let mut m = Mesh::new();
        crate::kernel::ops::create::create_cube(&mut m, 1.0).unwrap();
        let p = m.make_vert(DVec3::splat(5.0));
        m.make_edge_vert(p, DVec3::splat(5.0)).unwrap();
        let out = skin_wire_edges(&m, &options(8)).unwrap();
        assert!(
            out.is_empty(),
            "faces' edges and zero-length edges make nothing"
        );
        m.make_edge_vert(p, DVec3::new(5.0, 5.0, 6.0)).unwrap();
        let out = skin_wire_edges(&m, &options(8)).unwrap();
        out.validate().unwrap();
        // The zero-length edge does not count towards a joint at `p`.
        assert_eq!(out.report().components, 1);
    }

    #[test]
    fn left_layer_fixes_the_ring_rotation() {
        let mut m = skeleton(&[DVec3::ZERO, DVec3::new(0.0, 0.0, 2.0)], &[(0, 1)], None);
        m.add_layer(LEFT, Domain::Vert, AttrValue::Vector(DVec3::ZERO))
            .unwrap();
        // Tilted out of the ring plane: Gram–Schmidt keeps its direction.
        m.set_attr(
            LEFT,
            Domain::Vert,
            0,
            AttrValue::Vector(DVec3::new(0.0, 2.0, 1.0)),
        )
        .unwrap()
        .unwrap();
        let out = skin_wire_edges(&m, &options(4)).unwrap();
        let first = out.vert_ids().next().unwrap();
        assert_eq!(out.position(first), DVec3::new(0.0, 0.1, 0.0));
        // Parallel `left`: back to the least aligned world axis (X here).
        m.set_attr(LEFT, Domain::Vert, 0, AttrValue::Vector(DVec3::NEG_Z))
            .unwrap()
            .unwrap();
        let out = skin_wire_edges(&m, &options(4)).unwrap();
        let first = out.vert_ids().next().unwrap();
        assert_eq!(out.position(first), DVec3::new(0.1, 0.0, 0.0));
    }

    #[test]
    fn skinning_is_deterministic() {
        let points = [
            DVec3::ZERO,
            DVec3::new(0.1, 0.2, 1.0),
            DVec3::new(0.7, -0.3, 1.9),
            DVec3::new(-0.6, 0.4, 2.1),
            DVec3::new(0.0, 0.9, 2.8),
        ];
        let m = skeleton(
            &points,
            &[(0, 1), (1, 2), (1, 3), (3, 4)],
            Some(&[0.3, 0.25, 0.1, 0.15, 0.05]),
        );
        let run = || {
            let out = skin_wire_edges(&m, &options(7)).unwrap();
            out.vert_ids()
                .map(|v| out.position(v).to_array().map(f64::to_bits))
                .collect::<Vec<_>>()
        };
        let first = run();
        assert!(!first.is_empty());
        assert_eq!(first, run());
    }
}
