//! Wire edges as geometry a viewer draws (issue 16: "skeletons that
//! show"): each line becomes a closed prism of `sides` around it, capped,
//! wound outward, in the line's part with a `skeleton` material. Renderers
//! and engines draw no glTF lines in their final images, Blender imports
//! them as loose edges and STL cannot hold them at all; tubes show in all.

use glam::DVec3;

use super::frame::any_perpendicular;
use super::indexed::IndexedMesh;
use super::material::{AlphaMode, Material};

/// Sides of every tube (a hexagonal prism: round enough at preview sizes).
pub const TUBE_SIDES: usize = 6;

/// The name of the tubes' material.
pub const SKELETON_MATERIAL: &str = "skeleton";

/// Tube radius when none is given: this fraction of the bounding box
/// diagonal of the mesh.
pub const DEFAULT_RADIUS_FRACTION: f64 = 0.004;

/// `mesh` with its lines replaced by tubes of `radius` (`None`: the
/// default fraction of the bounding box diagonal). Lines of zero length
/// are dropped. Vertex scalars of the tube vertices come from the line's
/// end they surround.
pub fn lines_as_tubes(mesh: &IndexedMesh, radius: Option<f64>) -> IndexedMesh {
    let mut out = mesh.clone();
    if mesh.lines.is_empty() {
        return out;
    }
    let radius = radius
        .unwrap_or_else(|| DEFAULT_RADIUS_FRACTION * diagonal(mesh))
        .max(1e-12);
    out.lines.clear();
    out.line_parts.clear();
    // Every polygon needs a material once one has: give the old ones the
    // fallback if the mesh had none, then add the tubes' own.
    if out.materials.is_empty() && out.polygon_count() > 0 {
        out.materials.push(Material::fallback());
        out.polygon_materials = vec![0; out.polygon_count()];
    }
    let material = out.materials.len() as u32;
    out.materials.push(Material {
        name: unique_name(&out.materials),
        base_color: [0.05, 0.05, 0.05, 1.0],
        metallic: 0.0,
        roughness: 0.5,
        emissive: [0.0; 3],
        alpha: AlphaMode::Opaque,
        double_sided: Some(false),
    });
    let smooth = !out.corner_normals.is_empty();
    for (k, line) in mesh.lines.iter().enumerate() {
        let (a, b) = (mesh.position(line[0]), mesh.position(line[1]));
        let axis = b - a;
        let Some(dir) = axis.try_normalize() else {
            continue;
        };
        let u = any_perpendicular(dir);
        let v = dir.cross(u);
        let radial = |s: usize| {
            let angle = std::f64::consts::TAU * (s % TUBE_SIDES) as f64 / TUBE_SIDES as f64;
            u * libm::cos(angle) + v * libm::sin(angle)
        };
        let first = out.positions.len() as u32;
        for (end, centre) in [(line[0], a), (line[1], b)] {
            for s in 0..TUBE_SIDES {
                out.positions.push((centre + radial(s) * radius).to_array());
                for (_, values) in out.vertex_scalars.iter_mut() {
                    let value = values[end as usize];
                    values.push(value);
                }
            }
        }
        let ring = |end: u32, s: usize| first + end * TUBE_SIDES as u32 + (s % TUBE_SIDES) as u32;
        let part = mesh.line_part(k);
        let mut add = |corners: &[u32], normals: &[DVec3]| {
            out.face_indices.extend_from_slice(corners);
            out.face_starts.push(out.face_indices.len() as u32);
            if smooth {
                out.corner_normals
                    .extend(normals.iter().map(|n| n.to_array()));
            }
            if !out.corner_uvs.is_empty() {
                out.corner_uvs.extend(corners.iter().map(|_| [0.0; 2]));
            }
            if !out.corner_colors.is_empty() {
                out.corner_colors.extend(corners.iter().map(|_| [0.05; 3]));
            }
            if !out.parts.is_empty() {
                out.polygon_parts.push(part);
            }
            out.polygon_materials.push(material);
        };
        for s in 0..TUBE_SIDES {
            // Counter-clockwise seen from outside: a ring step, then along.
            let quad = [ring(0, s), ring(0, s + 1), ring(1, s + 1), ring(1, s)];
            let n = [radial(s), radial(s + 1), radial(s + 1), radial(s)];
            add(&quad, &n);
        }
        let start: Vec<u32> = (0..TUBE_SIDES).rev().map(|s| ring(0, s)).collect();
        let end: Vec<u32> = (0..TUBE_SIDES).map(|s| ring(1, s)).collect();
        add(&start, &[-dir; TUBE_SIDES]);
        add(&end, &[dir; TUBE_SIDES]);
    }
    out
}

/// `skeleton`, or `skeleton.1`, … when a material already has the name.
fn unique_name(materials: &[Material]) -> String {
    let mut names: Vec<String> = materials.iter().map(|m| m.name.clone()).collect();
    names.push(SKELETON_MATERIAL.into());
    super::material::dedupe_names(&mut names);
    names.pop().expect("pushed")
}

/// Length of the bounding box diagonal of the vertices lines and polygons use.
fn diagonal(mesh: &IndexedMesh) -> f64 {
    let used = mesh.face_indices.iter().chain(mesh.lines.iter().flatten());
    let (lo, hi) = used.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &i| {
        let p = mesh.position(i);
        (lo.min(p), hi.max(p))
    });
    if lo.x <= hi.x {
        (hi - lo).length()
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_becomes_a_closed_outward_prism() {
        let mut m = IndexedMesh::new();
        m.positions = vec![[0.0; 3], [0.0, 0.0, 2.0], [5.0, 5.0, 5.0]];
        m.lines = vec![[0, 1], [2, 2]];
        let t = lines_as_tubes(&m, Some(0.1));
        assert!(t.lines.is_empty());
        // One tube (the zero-length line is dropped): 6 sides + 2 caps.
        assert_eq!(t.polygon_count(), TUBE_SIDES + 2);
        assert_eq!(t.materials.last().unwrap().name, "skeleton");
        t.validate().unwrap();
        // Closed: every edge used twice, in opposite directions.
        let mut edges: Vec<(u32, u32)> = Vec::new();
        for p in t.polygons() {
            for i in 0..p.len() {
                edges.push((p[i], p[(i + 1) % p.len()]));
            }
        }
        for &(a, b) in &edges {
            assert_eq!(edges.iter().filter(|&&e| e == (b, a)).count(), 1);
        }
        // Outward: each side's Newell normal points away from the axis.
        for p in t.polygons().take(TUBE_SIDES) {
            let pts: Vec<DVec3> = p.iter().map(|&i| t.position(i)).collect();
            let n = crate::geom::polygon::newell_normal(&pts);
            let c = pts.iter().copied().sum::<DVec3>() / pts.len() as f64;
            assert!(n.dot(DVec3::new(c.x, c.y, 0.0)) > 0.0);
        }
    }
}
