//! Texture coordinates by projection, per part: box (each polygon onto the
//! axis plane its normal faces most), planar (onto one axis plane) and
//! cylindrical (around one axis through the part's centre). `size` is the
//! model length one texture repeat covers, so a brick texture has the same
//! scale on every wall of any size.

use glam::DVec3;

use super::indexed::IndexedMesh;
use super::polygon;

/// How a part's texture coordinates are made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// Per polygon, onto the axis plane its normal is closest to, oriented
    /// so that a texture reads unmirrored from outside and +Z is up.
    Box,
    /// Onto the plane normal to `axis` (0 = X, 1 = Y, 2 = Z).
    Planar { axis: usize },
    /// Around `axis` through the centre of the part's bounding box: u is
    /// the angle (one turn = one repeat, whatever the radius), v the
    /// height along the axis divided by `size`.
    Cylindrical { axis: usize },
    /// A parametric surface's own (u, v), from the vertex scalars
    /// [`SURFACE_U`] and [`SURFACE_V`] its tessellation left (divided by
    /// `size`: 1 maps the surface onto the texture once). A polygon across
    /// a closed direction's seam takes its low side one period up.
    Surface,
}

/// Vertex scalar holding a tessellated surface's u parameter.
pub const SURFACE_U: &str = "surface_u";
/// Vertex scalar holding a tessellated surface's v parameter.
pub const SURFACE_V: &str = "surface_v";

/// One part's projection and texture size (model units per repeat).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UvMapping {
    pub projection: Projection,
    pub size: f64,
}

/// Texture coordinates of every corner of `mesh` (aligned with
/// `face_indices`), each polygon by its part's mapping; parts without one
/// get (0, 0).
pub fn project(mesh: &IndexedMesh, by_part: &[Option<UvMapping>]) -> Vec<[f64; 2]> {
    let centres = part_centres(mesh);
    let mut out = vec![[0.0; 2]; mesh.face_indices.len()];
    let mut ring: Vec<DVec3> = Vec::new();
    for (k, poly) in mesh.polygons().enumerate() {
        let part = mesh.polygon_part(k) as usize;
        let Some(mapping) = by_part.get(part).copied().flatten() else {
            continue;
        };
        let scale = 1.0 / mapping.size;
        ring.clear();
        ring.extend(poly.iter().map(|&i| mesh.position(i)));
        let first = mesh.face_starts[k] as usize;
        let uvs = &mut out[first..first + poly.len()];
        match mapping.projection {
            Projection::Box => {
                let n = polygon::newell_normal(&ring);
                let facing = dominant_axis(n);
                let sign = if n[facing] < 0.0 { -1.0 } else { 1.0 };
                for (uv, p) in uvs.iter_mut().zip(&ring) {
                    *uv = box_uv(*p, facing, sign).map(|c| c * scale);
                }
            }
            Projection::Planar { axis } => {
                for (uv, p) in uvs.iter_mut().zip(&ring) {
                    *uv = box_uv(*p, axis, 1.0).map(|c| c * scale);
                }
            }
            Projection::Surface => {
                let (Some(us), Some(vs)) =
                    (mesh.vertex_scalar(SURFACE_U), mesh.vertex_scalar(SURFACE_V))
                else {
                    continue;
                };
                for (uv, &i) in uvs.iter_mut().zip(poly) {
                    *uv = [us[i as usize], vs[i as usize]];
                }
                for c in 0..2 {
                    unwrap_seam(uvs, c);
                }
                fix_poles(uvs);
                for uv in uvs.iter_mut() {
                    *uv = uv.map(|x| x * scale);
                }
            }
            Projection::Cylindrical { axis } => {
                let centre = centres[part];
                let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
                for (uv, p) in uvs.iter_mut().zip(&ring) {
                    let d = *p - centre;
                    let turn = libm::atan2(d[b], d[a]) / std::f64::consts::TAU + 0.5;
                    *uv = [turn, p[axis] * scale];
                }
                // A polygon across the seam (u jumps by more than half a
                // turn) takes its low side one turn up, so it does not
                // stretch over the whole texture.
                unwrap_seam(uvs, 0);
            }
        }
    }
    out
}

/// A polygon whose coordinate `c` jumps by more than half a period (a
/// seam at 0 / 1) takes its low side one period up, so it does not
/// stretch over the whole texture.
fn unwrap_seam(uvs: &mut [[f64; 2]], c: usize) {
    let (lo, hi) = uvs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), uv| {
            (lo.min(uv[c]), hi.max(uv[c]))
        });
    if hi - lo > 0.5 {
        for uv in uvs.iter_mut().filter(|uv| uv[c] < 0.5) {
            uv[c] += 1.0;
        }
    }
}

/// A pole (a boundary of v collapsed to one point, as a lathe's closed
/// bottom) is one vertex with one u for every triangle around it: a
/// corner on v's border more than a quarter period in u from the
/// polygon's other corners takes their mean u, as UV spheres do.
fn fix_poles(uvs: &mut [[f64; 2]]) {
    let n = uvs.len() as f64;
    for k in 0..uvs.len() {
        let [u, v] = uvs[k];
        if v != 0.0 && v != 1.0 {
            continue;
        }
        let others = uvs.iter().enumerate().filter(|&(j, _)| j != k);
        let mean = others.map(|(_, t)| t[0]).sum::<f64>() / (n - 1.0);
        if (u - mean).abs() > 0.25 {
            uvs[k][0] = mean;
        }
    }
}

/// The axis `n` points along most (ties go to the later axis: Z wins, so
/// floors and roofs of boxes are projected from above).
fn dominant_axis(n: DVec3) -> usize {
    let a = n.abs();
    if a.z >= a.x && a.z >= a.y {
        2
    } else if a.y >= a.x {
        1
    } else {
        0
    }
}

/// The two in-plane coordinates of `p` seen from the `sign` side of
/// `axis`, right-handed (unmirrored) and with the up direction (+Z, or +Y
/// when looking along Z) as v.
fn box_uv(p: DVec3, axis: usize, sign: f64) -> [f64; 2] {
    match axis {
        0 => [sign * p.y, p.z],
        1 => [-sign * p.x, p.z],
        _ => [sign * p.x, p.y],
    }
}

/// Centre of each part's bounding box (over its polygons' vertices).
fn part_centres(mesh: &IndexedMesh) -> Vec<DVec3> {
    let mut boxes = vec![(DVec3::INFINITY, DVec3::NEG_INFINITY); mesh.part_count()];
    for (k, poly) in mesh.polygons().enumerate() {
        let b = &mut boxes[mesh.polygon_part(k) as usize];
        for &i in poly {
            let p = mesh.position(i);
            *b = (b.0.min(p), b.1.max(p));
        }
    }
    boxes
        .into_iter()
        .map(|(lo, hi)| {
            if lo.x <= hi.x {
                (lo + hi) * 0.5
            } else {
                DVec3::ZERO
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(points: [[f64; 3]; 4]) -> IndexedMesh {
        let mut m = IndexedMesh::new();
        m.positions = points.to_vec();
        m.push_polygon(&[0, 1, 2, 3]);
        m
    }

    #[test]
    fn box_projection_scales_by_size_and_reads_unmirrored() {
        // A wall facing -Y (the front), 2 wide and 1 high.
        let wall = quad([
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
        ]);
        let mapping = UvMapping {
            projection: Projection::Box,
            size: 0.5,
        };
        let uv = project(&wall, &[Some(mapping)]);
        assert_eq!(uv, vec![[0.0, 0.0], [4.0, 0.0], [4.0, 2.0], [0.0, 2.0]]);
        // u grows to the right as seen from outside (front, looking +Y).
    }

    #[test]
    fn cylindrical_polygons_do_not_wrap_across_the_seam() {
        // A thin quad straddling the -X direction (the seam at u = 0 / 1).
        let q = quad([
            [-1.0, 0.1, 0.0],
            [-1.0, -0.1, 0.0],
            [-1.0, -0.1, 1.0],
            [-1.0, 0.1, 1.0],
        ]);
        let mut m = q.clone();
        // Make the part's centre the origin: a far point of another polygon.
        m.positions
            .extend([[1.0, 0.0, 0.0], [1.0, 0.1, 0.0], [1.0, 0.0, 1.0]]);
        m.push_polygon(&[4, 5, 6]);
        let mapping = UvMapping {
            projection: Projection::Cylindrical { axis: 2 },
            size: 1.0,
        };
        let uv = project(&m, &[Some(mapping)]);
        let us: Vec<f64> = uv[..4].iter().map(|t| t[0]).collect();
        let span = us.iter().cloned().fold(f64::MIN, f64::max)
            - us.iter().cloned().fold(f64::MAX, f64::min);
        assert!(span < 0.1, "{us:?}");
        assert_eq!(uv[2][1], 1.0);
    }

    #[test]
    fn parts_without_a_mapping_get_zeros() {
        let q = quad([[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]);
        assert_eq!(project(&q, &[None]), vec![[0.0; 2]; 4]);
    }
}
