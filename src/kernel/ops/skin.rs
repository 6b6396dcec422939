//! Skin: turns the wire edges of a mesh (a G³ skeleton) into closed tubes.
//!
//! Every wire edge becomes a capped frustum in a *new* mesh: its end rings
//! are regular `sides`-gons of the end nodes' radii, perpendicular to the
//! edge, and both ends are closed. With `joints`, every node where two or
//! more skinned edges meet also gets a low-poly UV sphere of its radius, so
//! bends look closed. Frusta and spheres are separate closed components that
//! may overlap (there is no boolean union); each is wound outward, so the
//! whole output is watertight.
//!
//! Output order is deterministic: frusta in ascending edge id order, then
//! joints in ascending vertex id order. A ring's rotation about its edge is
//! fixed by the start node's `left` vector (or a world axis), and angles go
//! through `libm`, so positions are bit-identical on every platform.
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
        mesh.vert_ids().filter(|v| degree[v.index()] >= 2).collect()
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

    for tube in &tubes {
        build_frustum(&mut out, mesh, tube, options.sides, copy_radius)?;
    }
    for &v in &joints {
        let radius = node_radius(mesh, v, options)?;
        let sphere = create_uv_sphere(&mut out, options.sides, rings, radius)?;
        let center = mesh.position(v);
        for &w in &sphere.verts {
            // Translation keeps the stored face normals valid.
            out.set_position(w, out.position(w) + center);
            if copy_radius {
                set_radius(&mut out, w, radius);
            }
        }
    }
    Ok(out)
}

/// The checked radius of node `v`.
fn node_radius(mesh: &Mesh, v: VertId, options: &SkinOptions) -> Result<f64, OpError> {
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

/// One capped frustum from `tube.ends[0]` to `tube.ends[1]`.
fn build_frustum(
    out: &mut Mesh,
    mesh: &Mesh,
    tube: &Tube,
    sides: u32,
    copy_radius: bool,
) -> Result<(), OpError> {
    let [a, b] = tube.ends.map(|v| mesh.position(v));
    let axis = (b - a).normalize();
    let u = reference_perpendicular(mesh, tube.ends, axis);
    // (u, v, axis) is right-handed, so rings run counter-clockwise seen from
    // the end node `b`: the winding create_cylinder uses along +Z.
    let v = axis.cross(u);
    let mut ring = |center: DVec3, radius: f64| -> Vec<VertId> {
        (0..sides)
            .map(|i| {
                let (c, s) = if i == 0 {
                    (1.0, 0.0)
                } else {
                    let angle = std::f64::consts::TAU * f64::from(i) / f64::from(sides);
                    (libm::cos(angle), libm::sin(angle))
                };
                let w = out.make_vert(center + u * (radius * c) + v * (radius * s));
                if copy_radius {
                    set_radius(out, w, radius);
                }
                w
            })
            .collect()
    };
    let bottom = ring(a, tube.radii[0]);
    let top = ring(b, tube.radii[1]);
    let n = bottom.len();
    for j in 0..n {
        let k = (j + 1) % n;
        out.make_face(&[bottom[j], bottom[k], top[k], top[j]])?;
    }
    // Seen from outside the start end, its ring runs the other way.
    let start_cap: Vec<VertId> = bottom.iter().rev().copied().collect();
    out.make_face(&start_cap)?;
    out.make_face(&top)?;
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
    from_left.unwrap_or_else(|| {
        let m = axis.abs();
        let world = if m.x <= m.y && m.x <= m.z {
            DVec3::X
        } else if m.y <= m.z {
            DVec3::Y
        } else {
            DVec3::Z
        };
        // |cos| <= 1/sqrt(3) with the least aligned axis: never degenerate.
        (world - axis * axis.dot(world)).normalize()
    })
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
        // Three frusta and one sphere at the fork; overlapping but each closed.
        assert_eq!(r.components, 4);
        assert!(r.watertight && r.manifold && r.wire_edges == 0, "{r:?}");
        assert_eq!(r.euler_characteristic, 2 * 4);
        assert!(r.volume.unwrap() > 0.0);
        let sphere_verts = 8 * 3 + 2;
        assert_eq!(r.verts, 3 * 16 + sphere_verts);
        // The sphere is the last component: centred on the fork, its radius.
        let last: Vec<VertId> = out.vert_ids().skip(3 * 16).collect();
        for &w in &last {
            assert!(((out.position(w) - DVec3::Z).length() - 0.2).abs() < 1e-12);
        }

        let without = skin_wire_edges(
            &m,
            &SkinOptions {
                joints: false,
                ..options(8)
            },
        )
        .unwrap();
        without.validate().unwrap();
        assert_eq!(without.report().components, 3);
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
