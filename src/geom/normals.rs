//! Shading normals of a polygon mesh split at creases: each corner gets
//! the angle-weighted mean of the face normals around its vertex that lie
//! within the crease angle of its own face's group, so smooth regions
//! share one normal per vertex and edges sharper than the angle keep a
//! normal per side.

use glam::DVec3;

use super::indexed::IndexedMesh;
use super::polygon;

/// Groups per vertex beyond which faces join the last group (bounds the
/// work on hostile fans: O(groups × faces) per vertex).
const MAX_GROUPS: usize = 32;

/// Per corner (`normals[t][k]` for corner k of triangle t), unit normals
/// smoothed within `crease_degrees`. Degenerate triangles (zero area)
/// contribute nothing and take their group's normal, or +Z when alone.
pub fn corner_normals(
    positions: &[[f64; 3]],
    triangles: &[[u32; 3]],
    crease_degrees: f64,
) -> Vec<[[f64; 3]; 3]> {
    let starts: Vec<u32> = (0..=triangles.len() as u32).map(|t| 3 * t).collect();
    let indices: Vec<u32> = triangles.iter().flatten().copied().collect();
    let flat = smooth_polygons(positions, &starts, &indices, &|_| (0, crease_degrees));
    flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

/// Per corner of `mesh` (aligned with `face_indices`), unit normals
/// smoothed within each polygon's part's crease angle (`crease_by_part[p]`
/// in degrees; 0 keeps a part flat). Corners of different parts never
/// share a normal: a part's border stays sharp.
pub fn mesh_corner_normals(mesh: &IndexedMesh, crease_by_part: &[f64]) -> Vec<[f64; 3]> {
    smooth_polygons(
        &mesh.positions,
        &mesh.face_starts,
        &mesh.face_indices,
        &|k| {
            let part = mesh.polygon_part(k);
            (
                part,
                crease_by_part.get(part as usize).copied().unwrap_or(0.0),
            )
        },
    )
}

/// The angle-weighted, crease-split normals of polygons given as flat
/// lists; `key(k)` gives polygon k's group key (faces with different keys
/// never share a normal) and crease angle in degrees.
fn smooth_polygons(
    positions: &[[f64; 3]],
    face_starts: &[u32],
    face_indices: &[u32],
    key: &dyn Fn(usize) -> (u32, f64),
) -> Vec<[f64; 3]> {
    let p = |i: u32| DVec3::from_array(positions[i as usize]);
    let polygons = face_starts.len().saturating_sub(1);
    let mut ring: Vec<DVec3> = Vec::new();
    let mut face = Vec::with_capacity(polygons);
    let mut keys = Vec::with_capacity(polygons);
    let mut poly_of = vec![0u32; face_indices.len()];
    for k in 0..polygons {
        let (a, b) = (face_starts[k] as usize, face_starts[k + 1] as usize);
        ring.clear();
        ring.extend(face_indices[a..b].iter().map(|&i| p(i)));
        // Triangles by their cross product (what PN smoothing was measured
        // with); larger polygons by Newell's method.
        face.push(match ring[..] {
            [a, b, c] => (b - a).cross(c - a).normalize_or_zero(),
            _ => polygon::unit_normal(&ring).unwrap_or(DVec3::ZERO),
        });
        let (group, crease) = key(k);
        let cos = libm::cos(crease.clamp(0.0, 180.0).to_radians());
        keys.push((group, cos));
        poly_of[a..b].fill(k as u32);
    }
    // Corners by vertex (counting sort: deterministic, linear).
    let mut start = vec![0u32; positions.len() + 1];
    for &v in face_indices {
        start[v as usize + 1] += 1;
    }
    for i in 0..positions.len() {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut corners = vec![0u32; face_indices.len()];
    for (c, &v) in face_indices.iter().enumerate() {
        corners[fill[v as usize] as usize] = c as u32;
        fill[v as usize] += 1;
    }
    let mut out = vec![[0.0, 0.0, 1.0]; face_indices.len()];
    // (seed normal, group key, weighted sum)
    let mut groups: Vec<(DVec3, u32, DVec3)> = Vec::new();
    let mut group_of: Vec<usize> = Vec::new();
    for v in 0..positions.len() {
        let around = &corners[start[v] as usize..start[v + 1] as usize];
        groups.clear();
        group_of.clear();
        for &c in around {
            let k = poly_of[c as usize] as usize;
            let (n, (group, cos_crease)) = (face[k], keys[k]);
            let g = groups
                .iter()
                .position(|&(seed, key, _)| {
                    key == group && (n == DVec3::ZERO || seed.dot(n) >= cos_crease)
                })
                .unwrap_or_else(|| {
                    if groups.len() < MAX_GROUPS {
                        groups.push((n, group, DVec3::ZERO));
                    }
                    groups.len() - 1
                });
            let (first, last) = (face_starts[k] as usize, face_starts[k + 1] as usize);
            let len = last - first;
            let i = c as usize - first;
            let here = p(face_indices[c as usize]);
            let (a, b) = (
                p(face_indices[first + (i + 1) % len]) - here,
                p(face_indices[first + (i + len - 1) % len]) - here,
            );
            let angle = libm::atan2(a.cross(b).length(), a.dot(b));
            groups[g].2 += n * angle;
            group_of.push(g);
        }
        for (&c, &g) in around.iter().zip(&group_of) {
            let n = groups[g].2.normalize_or_zero();
            let n = if n == DVec3::ZERO { groups[g].0 } else { n };
            if n != DVec3::ZERO {
                out[c as usize] = n.to_array();
            }
        }
    }
    out
}

/// A normal as a file gives it, made unit only where it is not already:
/// one that is unit to `f32` precision is kept bit for bit, so reading
/// what graftal wrote and writing it again changes no byte (a second
/// normalisation moves the last bits every round). `None` for a zero or
/// non-finite vector.
pub fn unit_as_read(v: DVec3) -> Option<DVec3> {
    /// |v|² − 1 of a unit `f64` vector rounded to `f32` is under 2⁻²³;
    /// a file printed to 6 digits is off by about 10⁻⁶ and is normalised.
    const UNIT_TOLERANCE: f64 = 1.0 / (1u64 << 22) as f64;
    if !v.is_finite() || v == DVec3::ZERO {
        return None;
    }
    let length_squared = v.length_squared();
    if (length_squared - 1.0).abs() <= UNIT_TOLERANCE {
        Some(v)
    } else {
        v.try_normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube as 12 outward triangles.
    fn cube() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let p: Vec<[f64; 3]> = (0..8)
            .map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let t = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        (p, t)
    }

    #[test]
    fn a_cube_keeps_its_faces_below_the_crease_and_rounds_above() {
        let (p, t) = cube();
        let sharp = corner_normals(&p, &t, 30.0);
        for (ti, tri) in t.iter().enumerate() {
            let a = DVec3::from_array(p[tri[0] as usize]);
            let face = (DVec3::from_array(p[tri[1] as usize]) - a)
                .cross(DVec3::from_array(p[tri[2] as usize]) - a)
                .normalize();
            for n in sharp[ti] {
                assert!((DVec3::from_array(n) - face).length() < 1e-12);
            }
        }
        // Past 90°, every corner of a vertex shares the diagonal normal.
        let smooth = corner_normals(&p, &t, 100.0);
        let expect = DVec3::splat(-1.0).normalize();
        assert!((DVec3::from_array(smooth[0][0]) - expect).length() < 1e-12);
    }
}
