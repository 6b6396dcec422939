//! Create operators: primitives added to a mesh without touching what is
//! already there (seed 000 §3.3, the *Create* category: "add new elements to
//! the model without changing the current ones", e.g. cube, sphere, grid).
//!
//! Every primitive is centred on the origin and built from Euler operators
//! only: [`Mesh::make_vert`] for the vertices, then [`Mesh::make_face`] on
//! vertex rings (which makes the missing edges) or [`Mesh::make_edge`] for
//! wire rings. Faces are wound counter-clockwise seen from outside, so their
//! Newell normals point out of closed shapes and along +Z for flat ones.
//!
//! Each operator returns a [`Selection`] of everything it created (verts,
//! edges, faces, sorted), the seed's `CreateGridResult` idea (§4.5.2).
//!
//! Sizes must be finite and non-negative: zero is accepted (the structure is
//! valid, the geometry degenerate: coincident vertices and zero normals),
//! negative or non-finite values are parameter errors. Counts that would not
//! fit the `u32` element ids are refused before anything is made.
//!
//! Angles go through `libm` so positions are bit-identical on every platform
//! (DESIGN.md: "transcendental math must be reproducible").
//!
//! ```
//! use graftal::kernel::{Mesh, ops::create};
//! let mut mesh = Mesh::new();
//! let cube = create::create_cube(&mut mesh, 2.0).unwrap();
//! assert_eq!((cube.verts.len(), cube.edges.len(), cube.faces.len()), (8, 12, 6));
//! ```

use glam::DVec3;

use super::{OpError, Selection};
use crate::kernel::ids::{EdgeId, FaceId, VertId};
use crate::kernel::mesh::Mesh;

/// A single isolated vertex (the seed's `CreateVert`, §4.6.1).
pub fn create_vert(mesh: &mut Mesh, position: DVec3) -> Result<Selection, OpError> {
    if !position.is_finite() {
        return Err(OpError::parameter("position", "must be finite"));
    }
    let v = mesh.make_vert(position);
    Ok(Selection::from_parts(vec![v], Vec::new(), Vec::new()))
}

/// A regular polygon of `segments` vertices in the XY plane, the first at
/// `(radius, 0, 0)`, counter-clockwise seen from +Z. Without `fill` it is a
/// ring of wire edges; with `fill` one n-gon face (normal +Z).
pub fn create_circle(
    mesh: &mut Mesh,
    segments: u32,
    radius: f64,
    fill: bool,
) -> Result<Selection, OpError> {
    check_segments("segments", segments, 3)?;
    check_size("radius", radius)?;
    let n = u128::from(segments);
    check_budget(mesh, n, n, if fill { n } else { 0 }, u128::from(fill))?;

    let ring = make_ring(mesh, segments, radius, 0.0);
    let mut faces = Vec::new();
    if fill {
        faces.push(mesh.make_face(&ring)?);
    } else {
        for (i, &v) in ring.iter().enumerate() {
            mesh.make_edge(v, ring[(i + 1) % ring.len()])?;
        }
    }
    Ok(created(mesh, ring, faces))
}

/// A flat grid in the XY plane spanning `size_x × size_y` (centred), cut into
/// `segments_x × segments_y` quads with normal +Z. Vertices are made row by
/// row (y outer, x inner), so vertex `(i, j)` is the `j·(segments_x+1)+i`-th
/// one made; faces follow the same order.
///
/// Linear time: each quad is one [`Mesh::make_face`], whose edge lookups
/// cost the (bounded) degree of a grid vertex.
pub fn create_grid(
    mesh: &mut Mesh,
    segments_x: u32,
    segments_y: u32,
    size_x: f64,
    size_y: f64,
) -> Result<Selection, OpError> {
    check_segments("segments_x", segments_x, 1)?;
    check_segments("segments_y", segments_y, 1)?;
    check_size("size_x", size_x)?;
    check_size("size_y", size_y)?;
    // u128: the counts of a u32 × u32 grid overflow u64.
    let (sx, sy) = (u128::from(segments_x), u128::from(segments_y));
    let quads = sx * sy;
    let edges = sx * (sy + 1) + sy * (sx + 1);
    check_budget(mesh, (sx + 1) * (sy + 1), edges, 4 * quads, quads)?;
    // Within the 2^32 budget just checked (callers bound memory before
    // this: the grammar's growth prediction): the arenas grow once.
    let count = |n: u128| usize::try_from(n).unwrap_or(usize::MAX);
    mesh.reserve(
        count((sx + 1) * (sy + 1)),
        count(edges),
        count(4 * quads),
        count(quads),
    );

    let row = segments_x as usize + 1;
    let mut verts = Vec::with_capacity(row * (segments_y as usize + 1));
    for j in 0..=segments_y {
        let y = grid_coordinate(j, segments_y, size_y);
        for i in 0..=segments_x {
            let x = grid_coordinate(i, segments_x, size_x);
            verts.push(mesh.make_vert(DVec3::new(x, y, 0.0)));
        }
    }
    let mut faces = Vec::with_capacity(quads as usize);
    let mut edges = Vec::with_capacity(count(edges));
    // The sides a quad shares with the quad below (its top) and the quad
    // to its left (its right) are passed on, not searched for; the other
    // sides are new. Edges are made in the order `make_face` would make
    // them, so ids match a face-by-face build.
    let mut below: Vec<Option<EdgeId>> = vec![None; segments_x as usize];
    for j in 0..segments_y as usize {
        let mut left: Option<EdgeId> = None;
        for (i, below) in below.iter_mut().enumerate() {
            let a = j * row + i;
            let b = (j + 1) * row + i;
            // Counter-clockwise from +Z: +x along the row, then +y, then back.
            let ring = [verts[a], verts[a + 1], verts[b + 1], verts[b]];
            let mut side = |known: Option<EdgeId>, k: usize| match known {
                Some(e) => Ok::<_, OpError>(e),
                None => {
                    let e = mesh.make_edge(ring[k], ring[(k + 1) % 4])?;
                    edges.push(e);
                    Ok(e)
                }
            };
            let sides = [
                side(*below, 0)?,
                side(None, 1)?,
                side(None, 2)?,
                side(left, 3)?,
            ];
            faces.push(mesh.make_face_on_edges(&ring, &sides)?);
            *below = Some(sides[2]);
            left = Some(sides[1]);
        }
    }
    Ok(Selection::from_parts(verts, edges, faces))
}

/// An axis-aligned cube of edge length `size`: 8 vertices, 12 edges and 6
/// outward quads.
pub fn create_cube(mesh: &mut Mesh, size: f64) -> Result<Selection, OpError> {
    check_size("size", size)?;
    check_budget(mesh, 8, 12, 24, 6)?;
    let h = size * 0.5;
    // Bottom square (z = -h) counter-clockwise from +Z, then the top square.
    let corners = [
        (-h, -h, -h),
        (h, -h, -h),
        (h, h, -h),
        (-h, h, -h),
        (-h, -h, h),
        (h, -h, h),
        (h, h, h),
        (-h, h, h),
    ];
    let v: Vec<VertId> = corners
        .iter()
        .map(|&(x, y, z)| mesh.make_vert(DVec3::new(x, y, z)))
        .collect();
    // Each ring is counter-clockwise seen from outside its face.
    let rings = [
        [0, 3, 2, 1], // -Z
        [4, 5, 6, 7], // +Z
        [0, 1, 5, 4], // -Y
        [1, 2, 6, 5], // +X
        [2, 3, 7, 6], // +Y
        [3, 0, 4, 7], // -X
    ];
    let mut faces = Vec::with_capacity(6);
    for ring in rings {
        faces.push(mesh.make_face(&ring.map(|i| v[i]))?);
    }
    Ok(created(mesh, v, faces))
}

/// A UV sphere: poles on ±Z, `rings` bands of latitude and `segments` of
/// longitude. Triangles fan around each pole, quads fill the bands between.
/// Closed and manifold: V = segments·(rings−1) + 2, F = segments·rings.
/// Vertices: the +Z pole, the rings from top to bottom (each starting at
/// longitude 0, counter-clockwise from +Z), then the −Z pole.
pub fn create_uv_sphere(
    mesh: &mut Mesh,
    segments: u32,
    rings: u32,
    radius: f64,
) -> Result<Selection, OpError> {
    check_segments("segments", segments, 3)?;
    check_segments("rings", rings, 2)?;
    check_size("radius", radius)?;
    let (s, r) = (u128::from(segments), u128::from(rings));
    let verts = s * (r - 1) + 2;
    let faces = s * r;
    let loops = 3 * s * 2 + 4 * s * (r - 2);
    check_budget(mesh, verts, verts + faces - 2, loops, faces)?;

    let mut all = Vec::with_capacity(verts as usize);
    let top = mesh.make_vert(DVec3::new(0.0, 0.0, radius));
    all.push(top);
    let mut bands: Vec<Vec<VertId>> = Vec::with_capacity(rings as usize - 1);
    for i in 1..rings {
        let polar = std::f64::consts::PI * f64::from(i) / f64::from(rings);
        let ring = make_ring(
            mesh,
            segments,
            radius * libm::sin(polar),
            radius * libm::cos(polar),
        );
        all.extend_from_slice(&ring);
        bands.push(ring);
    }
    let bottom = mesh.make_vert(DVec3::new(0.0, 0.0, -radius));
    all.push(bottom);

    let n = segments as usize;
    let mut made: Vec<FaceId> = Vec::with_capacity(faces as usize);
    let first = &bands[0];
    for j in 0..n {
        made.push(mesh.make_face(&[top, first[j], first[(j + 1) % n]])?);
    }
    for pair in bands.windows(2) {
        let (upper, lower) = (&pair[0], &pair[1]);
        for j in 0..n {
            let k = (j + 1) % n;
            // Down the meridian, along the lower ring, back up: outward.
            made.push(mesh.make_face(&[upper[j], lower[j], lower[k], upper[k]])?);
        }
    }
    let last = &bands[bands.len() - 1];
    for j in 0..n {
        made.push(mesh.make_face(&[bottom, last[(j + 1) % n], last[j]])?);
    }
    Ok(created(mesh, all, made))
}

/// A cylinder (or cone, or truncated cone) along Z from `-depth/2` to
/// `+depth/2`, with `segments` side faces. A zero radius makes that end a
/// single apex vertex with triangles around it (a cone); `caps` then closes
/// only the other end. With `caps` the result is closed. Both radii zero
/// would leave no surface and is refused.
///
/// Vertices: the bottom ring (or apex), then the top ring (or apex); rings
/// start at `(radius, 0, z)` and run counter-clockwise from +Z.
pub fn create_cylinder(
    mesh: &mut Mesh,
    segments: u32,
    radius_bottom: f64,
    radius_top: f64,
    depth: f64,
    caps: bool,
) -> Result<Selection, OpError> {
    check_segments("segments", segments, 3)?;
    check_size("radius_bottom", radius_bottom)?;
    check_size("radius_top", radius_top)?;
    check_size("depth", depth)?;
    if radius_bottom == 0.0 && radius_top == 0.0 {
        return Err(OpError::parameter(
            "radius_bottom",
            "at least one radius must be positive",
        ));
    }
    let s = u128::from(segments);
    check_budget(mesh, 2 * s, 3 * s, 6 * s, s + 2)?;

    let half = depth * 0.5;
    let bottom = end_ring(mesh, segments, radius_bottom, -half);
    let top = end_ring(mesh, segments, radius_top, half);
    let n = segments as usize;
    let mut faces = Vec::with_capacity(n + 2);
    for j in 0..n {
        let k = (j + 1) % n;
        // The quad b_j, b_k, t_k, t_j is outward; at an apex end its two
        // corners are the same vertex, leaving an outward triangle.
        let mut ring = vec![bottom.at(j), bottom.at(k), top.at(k), top.at(j)];
        ring.dedup();
        let face = mesh.make_face(&ring)?;
        faces.push(face);
    }
    if caps {
        if let End::Ring(b) = &bottom {
            // Seen from below (outside) the bottom ring runs the other way.
            let ring: Vec<VertId> = std::iter::once(b[0])
                .chain(b[1..].iter().rev().copied())
                .collect();
            faces.push(mesh.make_face(&ring)?);
        }
        if let End::Ring(t) = &top {
            faces.push(mesh.make_face(t)?);
        }
    }
    let mut verts = bottom.verts();
    verts.extend(top.verts());
    Ok(created(mesh, verts, faces))
}

/// One end of a cylinder: a ring of vertices, or a cone's apex.
enum End {
    Ring(Vec<VertId>),
    Apex(VertId),
}

impl End {
    /// Vertex `j` of the ring; the apex for every `j`.
    fn at(&self, j: usize) -> VertId {
        match self {
            End::Ring(r) => r[j],
            End::Apex(a) => *a,
        }
    }

    fn verts(&self) -> Vec<VertId> {
        match self {
            End::Ring(r) => r.clone(),
            End::Apex(a) => vec![*a],
        }
    }
}

fn end_ring(mesh: &mut Mesh, segments: u32, radius: f64, z: f64) -> End {
    if radius == 0.0 {
        End::Apex(mesh.make_vert(DVec3::new(0.0, 0.0, z)))
    } else {
        End::Ring(make_ring(mesh, segments, radius, z))
    }
}

/// `segments` new vertices on a circle of `radius` at height `z`, the first
/// at angle 0, counter-clockwise seen from +Z.
fn make_ring(mesh: &mut Mesh, segments: u32, radius: f64, z: f64) -> Vec<VertId> {
    (0..segments)
        .map(|i| {
            let angle = std::f64::consts::TAU * f64::from(i) / f64::from(segments);
            let (x, y) = if i == 0 {
                // Exactly (radius, 0): libm's sin(0) is 0 already, but make
                // the documented first vertex independent of that.
                (radius, 0.0)
            } else {
                (radius * libm::cos(angle), radius * libm::sin(angle))
            };
            mesh.make_vert(DVec3::new(x, y, z))
        })
        .collect()
}

/// Coordinate `i` of `segments` cells spanning `size`, centred on 0. The
/// last one is exactly `size/2` so opposite borders are symmetric.
fn grid_coordinate(i: u32, segments: u32, size: f64) -> f64 {
    let half = size * 0.5;
    if i == segments {
        half
    } else {
        -half + size * f64::from(i) / f64::from(segments)
    }
}

/// The created selection: the given new vertices, every edge touching them
/// (all new, since they were made on new vertices only) and the new faces.
fn created(mesh: &Mesh, verts: Vec<VertId>, faces: Vec<FaceId>) -> Selection {
    let mut edges = Vec::new();
    for &v in &verts {
        // Each edge is met from both ends; keep it from its first end only.
        edges.extend(mesh.vert_edges(v).filter(|&e| mesh.edge_verts(e)[0] == v));
    }
    Selection::from_parts(verts, edges, faces)
}

fn check_segments(name: &'static str, value: u32, min: u32) -> Result<(), OpError> {
    if value < min {
        return Err(OpError::parameter(
            name,
            format!("must be at least {min}, got {value}"),
        ));
    }
    Ok(())
}

fn check_size(name: &'static str, value: f64) -> Result<(), OpError> {
    if !value.is_finite() {
        return Err(OpError::parameter(
            name,
            format!("must be finite, got {value}"),
        ));
    }
    if value < 0.0 {
        return Err(OpError::parameter(
            name,
            format!("must not be negative, got {value}"),
        ));
    }
    Ok(())
}

/// Refuses a primitive whose element counts would overflow the `u32` ids
/// (the arenas would panic), before anything is made.
fn check_budget(
    mesh: &Mesh,
    verts: u128,
    edges: u128,
    loops: u128,
    faces: u128,
) -> Result<(), OpError> {
    let limit = u128::from(u32::MAX);
    let over = |have: usize, add: u128| have as u128 + add > limit;
    if over(mesh.vert_count(), verts)
        || over(mesh.edge_count(), edges)
        || over(mesh.loop_count(), loops)
        || over(mesh.face_count(), faces)
    {
        return Err(OpError::parameter(
            "segments",
            "the primitive would exceed the 2^32 element limit",
        ));
    }
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::kernel::ids::EdgeId;

    /// Signed volume of the closed surface: a fan of each face, summed as
    /// tetrahedra with the origin. Positive when faces wind outward.
    pub(crate) fn signed_volume(mesh: &Mesh) -> f64 {
        let mut volume = 0.0;
        for f in mesh.face_ids() {
            let p = mesh.face_positions(f);
            for i in 1..p.len() - 1 {
                volume += p[0].dot(p[i].cross(p[i + 1])) / 6.0;
            }
        }
        volume
    }

    pub(crate) fn euler_characteristic(mesh: &Mesh) -> i64 {
        mesh.vert_count() as i64 - mesh.edge_count() as i64 + mesh.face_count() as i64
    }

    pub(crate) fn is_closed_manifold(mesh: &Mesh) -> bool {
        mesh.edge_ids().all(|e| mesh.edge_face_count(e) == 2)
    }

    fn counts(s: &Selection) -> (usize, usize, usize) {
        (s.verts.len(), s.edges.len(), s.faces.len())
    }

    fn mesh_counts(m: &Mesh) -> (usize, usize, usize) {
        (m.vert_count(), m.edge_count(), m.face_count())
    }

    #[test]
    fn create_vert_checks_its_position() {
        let mut m = Mesh::new();
        let s = create_vert(&mut m, DVec3::new(1.0, 2.0, 3.0)).unwrap();
        assert_eq!(counts(&s), (1, 0, 0));
        assert_eq!(m.position(s.verts[0]), DVec3::new(1.0, 2.0, 3.0));
        assert!(matches!(
            create_vert(&mut m, DVec3::new(f64::NAN, 0.0, 0.0)),
            Err(OpError::Parameter {
                name: "position",
                ..
            })
        ));
        assert_eq!(m.vert_count(), 1);
        m.validate().unwrap();
    }

    #[test]
    fn circle_ring_and_filled_disc() {
        let mut m = Mesh::new();
        let ring = create_circle(&mut m, 6, 2.0, false).unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&ring), (6, 6, 0));
        assert_eq!(m.position(ring.verts[0]), DVec3::new(2.0, 0.0, 0.0));
        assert!(ring.edges.iter().all(|&e| m.is_wire_edge(e)));
        for &v in &ring.verts {
            assert!((m.position(v).length() - 2.0).abs() < 1e-12);
            assert_eq!(m.vert_degree(v), 2);
        }

        let disc = create_circle(&mut m, 5, 1.0, true).unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&disc), (5, 5, 1));
        assert_eq!(m.face_len(disc.faces[0]), 5);
        assert!((m.face_normal(disc.faces[0]) - DVec3::Z).length() < 1e-12);
        // The second vertex is counter-clockwise from the first.
        assert!(m.position(disc.verts[1]).y > 0.0);
        assert_eq!(mesh_counts(&m), (11, 11, 1));
    }

    #[test]
    fn circle_rejects_bad_parameters_without_changing_the_mesh() {
        let mut m = Mesh::new();
        for (segments, radius) in [
            (2, 1.0),
            (0, 1.0),
            (3, -1.0),
            (3, f64::NAN),
            (3, f64::INFINITY),
        ] {
            assert!(matches!(
                create_circle(&mut m, segments, radius, true),
                Err(OpError::Parameter { .. })
            ));
        }
        assert!(m.is_empty());
    }

    #[test]
    fn grid_counts_order_extent_and_normals() {
        let mut m = Mesh::new();
        let g = create_grid(&mut m, 3, 2, 6.0, 4.0).unwrap();
        m.validate().unwrap();
        // (a+1)(b+1) verts, a(b+1)+b(a+1) edges, ab faces.
        assert_eq!(counts(&g), (12, 17, 6));
        assert_eq!(mesh_counts(&m), (12, 17, 6));
        // Row by row: y outer, x inner.
        assert_eq!(m.position(g.verts[0]), DVec3::new(-3.0, -2.0, 0.0));
        assert_eq!(m.position(g.verts[1]), DVec3::new(-1.0, -2.0, 0.0));
        assert_eq!(m.position(g.verts[4]), DVec3::new(-3.0, 0.0, 0.0));
        assert_eq!(m.position(g.verts[11]), DVec3::new(3.0, 2.0, 0.0));
        for &f in &g.faces {
            assert_eq!(m.face_len(f), 4);
            assert!((m.face_normal(f) - DVec3::Z).length() < 1e-12);
            assert!((m.face_area(f) - 4.0).abs() < 1e-12);
        }
        let boundary = g
            .edges
            .iter()
            .filter(|&&e| m.edge_face_count(e) == 1)
            .count();
        assert_eq!(boundary, 2 * (3 + 2));
        assert_eq!(euler_characteristic(&m), 1);
    }

    #[test]
    fn grid_numbers_its_elements_like_a_face_by_face_build() {
        // The grid hands shared sides from quad to quad instead of
        // searching for them; ids must be those of plain `make_face` calls.
        let (nx, ny) = (5u32, 3u32);
        let mut fast = Mesh::new();
        let extra = fast.make_vert(DVec3::Z);
        let sel = create_grid(&mut fast, nx, ny, 2.0, 1.0).unwrap();
        fast.validate().unwrap();
        let mut slow = Mesh::new();
        slow.make_vert(DVec3::Z);
        let row = nx as usize + 1;
        let verts: Vec<VertId> = (0..=ny)
            .flat_map(|j| (0..=nx).map(move |i| (i, j)))
            .map(|(i, j)| {
                let x = grid_coordinate(i, nx, 2.0);
                slow.make_vert(DVec3::new(x, grid_coordinate(j, ny, 1.0), 0.0))
            })
            .collect();
        for j in 0..ny as usize {
            for i in 0..nx as usize {
                let (a, b) = (j * row + i, (j + 1) * row + i);
                slow.make_face(&[verts[a], verts[a + 1], verts[b + 1], verts[b]])
                    .unwrap();
            }
        }
        let edges = |m: &Mesh| m.edge_ids().map(|e| m.edge_verts(e)).collect::<Vec<_>>();
        let faces = |m: &Mesh| {
            m.face_ids()
                .map(|f| m.face_verts(f).collect::<Vec<_>>())
                .collect::<Vec<_>>()
        };
        assert_eq!(edges(&fast), edges(&slow));
        assert_eq!(faces(&fast), faces(&slow));
        let all_edges: Vec<EdgeId> = fast.edge_ids().collect();
        assert_eq!(sel.edges, all_edges);
        assert_eq!(sel.faces.len(), (nx * ny) as usize);
        assert!(!sel.verts.contains(&extra));
    }

    #[test]
    fn grid_rejects_zero_segments_and_negative_sizes() {
        let mut m = Mesh::new();
        assert!(create_grid(&mut m, 0, 2, 1.0, 1.0).is_err());
        assert!(create_grid(&mut m, 2, 0, 1.0, 1.0).is_err());
        assert!(create_grid(&mut m, 2, 2, -1.0, 1.0).is_err());
        assert!(create_grid(&mut m, 2, 2, 1.0, f64::NAN).is_err());
        assert!(
            create_grid(&mut m, u32::MAX, u32::MAX, 1.0, 1.0).is_err(),
            "a grid past the id limit is refused, not a panic"
        );
        assert!(m.is_empty());
    }

    /// Heavy: `cargo test --release --lib grid_of_a_million -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn grid_of_a_million_quads_is_linear() {
        let mut m = Mesh::new();
        let start = std::time::Instant::now();
        let g = create_grid(&mut m, 1000, 1000, 1.0, 1.0).unwrap();
        let elapsed = start.elapsed();
        assert_eq!(counts(&g), (1001 * 1001, 2 * 1000 * 1001, 1_000_000));
        m.validate().unwrap();
        println!("create_grid 1000x1000: {elapsed:?}");
    }

    #[test]
    fn cube_is_closed_outward_and_sized() {
        let mut m = Mesh::new();
        let c = create_cube(&mut m, 2.0).unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&c), (8, 12, 6));
        assert_eq!(mesh_counts(&m), (8, 12, 6));
        assert!(is_closed_manifold(&m));
        assert_eq!(euler_characteristic(&m), 2);
        assert!((signed_volume(&m) - 8.0).abs() < 1e-12);
        for &f in &c.faces {
            // Outward: the normal points the same way as the face centre.
            let n = m.face_normal(f);
            assert!(
                (n - m.face_center(f)).length() < 1e-12,
                "face {f} normal {n}"
            );
        }
        for &e in &c.edges {
            assert!((m.edge_length(e) - 2.0).abs() < 1e-12);
        }
    }

    #[test]
    fn uv_sphere_counts_closure_and_orientation() {
        for (segments, rings) in [(3, 2), (8, 6), (32, 16)] {
            let mut m = Mesh::new();
            let s = create_uv_sphere(&mut m, segments, rings, 1.5).unwrap();
            m.validate().unwrap();
            let (sg, rg) = (segments as usize, rings as usize);
            assert_eq!(s.verts.len(), sg * (rg - 1) + 2);
            assert_eq!(s.faces.len(), sg * rg);
            assert_eq!(mesh_counts(&m), counts(&s));
            assert!(is_closed_manifold(&m));
            assert_eq!(euler_characteristic(&m), 2);
            assert!(signed_volume(&m) > 0.0);
            let tris = s.faces.iter().filter(|&&f| m.face_len(f) == 3).count();
            assert_eq!(tris, 2 * sg, "triangles only around the poles");
            for &v in &s.verts {
                assert!((m.position(v).length() - 1.5).abs() < 1e-12);
            }
            for &f in &s.faces {
                assert!(m.face_normal(f).dot(m.face_center(f)) > 0.0);
            }
        }
        let mut m = Mesh::new();
        let fine = create_uv_sphere(&mut m, 64, 32, 1.0).unwrap();
        let volume = signed_volume(&m);
        assert!(
            (volume - 4.0 / 3.0 * std::f64::consts::PI).abs() < 0.02,
            "{volume}"
        );
        assert!(!fine.is_empty());
        assert!(create_uv_sphere(&mut m, 8, 1, 1.0).is_err());
        assert!(create_uv_sphere(&mut m, 2, 4, 1.0).is_err());
    }

    #[test]
    fn cylinder_with_and_without_caps() {
        let mut m = Mesh::new();
        let c = create_cylinder(&mut m, 8, 1.0, 1.0, 2.0, true).unwrap();
        m.validate().unwrap();
        assert_eq!(counts(&c), (16, 24, 10));
        assert!(is_closed_manifold(&m));
        assert_eq!(euler_characteristic(&m), 2);
        assert!(signed_volume(&m) > 0.0);
        let zs: Vec<f64> = c.verts.iter().map(|&v| m.position(v).z).collect();
        assert!(zs[..8].iter().all(|&z| z == -1.0) && zs[8..].iter().all(|&z| z == 1.0));
        assert_eq!(m.position(c.verts[0]), DVec3::new(1.0, 0.0, -1.0));

        let mut open = Mesh::new();
        let t = create_cylinder(&mut open, 6, 1.0, 0.5, 1.0, false).unwrap();
        open.validate().unwrap();
        assert_eq!(counts(&t), (12, 18, 6));
        let border = t
            .edges
            .iter()
            .filter(|&&e| open.edge_face_count(e) == 1)
            .count();
        assert_eq!(border, 12);
        for &f in &t.faces {
            let n = open.face_normal(f);
            let c = open.face_center(f);
            assert!(n.x * c.x + n.y * c.y > 0.0, "side faces point outward");
        }
    }

    #[test]
    fn cones_have_one_apex_and_a_single_cap() {
        for (bottom, top) in [(1.0, 0.0), (0.0, 1.0)] {
            let mut m = Mesh::new();
            let c = create_cylinder(&mut m, 7, bottom, top, 3.0, true).unwrap();
            m.validate().unwrap();
            assert_eq!(counts(&c), (8, 14, 8));
            assert!(is_closed_manifold(&m));
            assert_eq!(euler_characteristic(&m), 2);
            assert!(signed_volume(&m) > 0.0);
            let tris = c.faces.iter().filter(|&&f| m.face_len(f) == 3).count();
            assert_eq!(tris, 7);
            let apex = c
                .verts
                .iter()
                .copied()
                .find(|&v| m.vert_degree(v) == 7)
                .unwrap();
            assert_eq!(m.position(apex).x, 0.0);
            assert_eq!(m.position(apex).z.abs(), 1.5);

            let mut open = Mesh::new();
            let o = create_cylinder(&mut open, 7, bottom, top, 3.0, false).unwrap();
            open.validate().unwrap();
            assert_eq!(counts(&o), (8, 14, 7));
        }
        let mut m = Mesh::new();
        assert!(create_cylinder(&mut m, 7, 0.0, 0.0, 1.0, true).is_err());
        assert!(create_cylinder(&mut m, 7, 1.0, 1.0, -1.0, true).is_err());
        assert!(create_cylinder(&mut m, 2, 1.0, 1.0, 1.0, true).is_err());
        assert!(m.is_empty());
    }

    #[test]
    fn created_selection_adds_to_an_existing_mesh_without_touching_it() {
        let mut m = Mesh::new();
        let first = create_cube(&mut m, 1.0).unwrap();
        let second = create_cube(&mut m, 1.0).unwrap();
        m.validate().unwrap();
        assert_eq!(mesh_counts(&m), (16, 24, 12));
        let disjoint = |a: &[EdgeId], b: &[EdgeId]| a.iter().all(|e| !b.contains(e));
        assert!(disjoint(&first.edges, &second.edges));
        assert!(first.verts.iter().all(|v| !second.verts.contains(v)));
        assert!((signed_volume(&m) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn primitives_are_deterministic() {
        let build = || {
            let mut m = Mesh::new();
            create_uv_sphere(&mut m, 12, 7, 2.0).unwrap();
            create_cylinder(&mut m, 9, 1.0, 0.0, 2.0, true).unwrap();
            m.vert_ids()
                .map(|v| m.position(v).to_array())
                .collect::<Vec<_>>()
        };
        assert_eq!(build(), build());
    }
}
