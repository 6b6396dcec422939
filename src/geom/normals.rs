//! Shading normals of a triangle mesh split at creases: each corner gets
//! the angle-weighted mean of the face normals around its vertex that lie
//! within the crease angle of its own face's group, so smooth regions
//! share one normal per vertex and edges sharper than the angle keep a
//! normal per side.

use glam::DVec3;

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
    let p = |i: u32| DVec3::from_array(positions[i as usize]);
    let face: Vec<DVec3> = triangles
        .iter()
        .map(|t| {
            (p(t[1]) - p(t[0]))
                .cross(p(t[2]) - p(t[0]))
                .normalize_or_zero()
        })
        .collect();
    // Corners by vertex (counting sort: deterministic, linear).
    let mut start = vec![0u32; positions.len() + 1];
    for t in triangles {
        for &v in t {
            start[v as usize + 1] += 1;
        }
    }
    for i in 0..positions.len() {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut corners = vec![0u32; triangles.len() * 3];
    for (ti, t) in triangles.iter().enumerate() {
        for (k, &v) in t.iter().enumerate() {
            corners[fill[v as usize] as usize] = (ti * 3 + k) as u32;
            fill[v as usize] += 1;
        }
    }
    let cos_crease = libm::cos(crease_degrees.clamp(0.0, 180.0).to_radians());
    let mut out = vec![[[0.0, 0.0, 1.0]; 3]; triangles.len()];
    let mut groups: Vec<(DVec3, DVec3)> = Vec::new(); // (seed normal, weighted sum)
    let mut group_of: Vec<usize> = Vec::new();
    for v in 0..positions.len() {
        let around = &corners[start[v] as usize..start[v + 1] as usize];
        groups.clear();
        group_of.clear();
        for &c in around {
            let (t, k) = (c as usize / 3, c as usize % 3);
            let n = face[t];
            let g = groups
                .iter()
                .position(|(seed, _)| n == DVec3::ZERO || seed.dot(n) >= cos_crease)
                .unwrap_or_else(|| {
                    if groups.len() < MAX_GROUPS {
                        groups.push((n, DVec3::ZERO));
                    }
                    groups.len() - 1
                });
            let tri = triangles[t];
            let (a, b) = (
                p(tri[(k + 1) % 3]) - p(tri[k]),
                p(tri[(k + 2) % 3]) - p(tri[k]),
            );
            let angle = libm::atan2(a.cross(b).length(), a.dot(b));
            groups[g].1 += n * angle;
            group_of.push(g);
        }
        for (&c, &g) in around.iter().zip(&group_of) {
            let n = groups[g].1.normalize_or_zero();
            let n = if n == DVec3::ZERO { groups[g].0 } else { n };
            if n != DVec3::ZERO {
                out[c as usize / 3][c as usize % 3] = n.to_array();
            }
        }
    }
    out
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
