//! Surfaces made from curves: revolution (a lathe) and sweeps of a profile along a path.
//! Neither is in the seed; they are what users of NURBS tools ask for first (issue 15).
//!
//! - [`revolve`]: a profile in the XZ plane turned about +Z by the exact quadratic rational
//!   circle in nine points (Piegl & Tiller §7.5, §8.5): exact.
//! - [`sweep`] with [`Orient::Fixed`]: the translational sweep S(u, v) = C(u) + T(v) with
//!   P_ij = C_i + T_j and w_ij = w_i·w_j (P&T §8.4): exact.
//! - [`sweep`] with [`Orient::Follow`]: the profile carried along the path in a
//!   rotation-minimizing frame (double reflection, Wang et al. 2008), its copies placed at the
//!   path's control points in the frame of their Greville abscissae. The path is first refined
//!   by knot insertion until its control polygon is within `tolerance` of the curve, so the
//!   net follows the path that closely (P&T §10.4's "sweep by control net"; an approximation,
//!   O(h²) in the span length, not an exact sweep, which no NURBS represents in general).
//!   A closed path gets a closed surface: the frame's twist over the loop (its holonomy) is
//!   spread evenly along it, and the last row is the first.

use glam::{DQuat, DVec3};

use super::bezier::project;
use super::curve::NurbsCurve;
use super::error::NurbsError;
use super::surface::NurbsSurface;

/// How a swept profile is oriented along its path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Orient {
    /// Translated only: the profile keeps its orientation (exact).
    Fixed,
    /// Turned with the path: the profile's +Z along the path's tangent, its +X and +Y along a
    /// rotation-minimizing normal and binormal.
    Follow,
}

/// Most control points a refined path may have.
pub const MAX_PATH_POINTS: usize = 1 << 14;

/// Most control points a swept net may have (the rule files' limit on a net).
pub const MAX_SWEEP_NET: usize = 1 << 20;

/// The quadratic rational circle in nine points: the unit square's edge midpoints and
/// corners, weights 1 and √½, knots at the quarters.
pub(crate) const CIRCLE: [[f64; 2]; 9] = [
    [1.0, 0.0],
    [1.0, 1.0],
    [0.0, 1.0],
    [-1.0, 1.0],
    [-1.0, 0.0],
    [-1.0, -1.0],
    [0.0, -1.0],
    [1.0, -1.0],
    [1.0, 0.0],
];
pub(crate) const CIRCLE_KNOTS: [f64; 12] = [
    0.0, 0.0, 0.0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1.0, 1.0, 1.0,
];

pub(crate) fn circle_weight(i: usize) -> f64 {
    if i % 2 == 1 {
        std::f64::consts::FRAC_1_SQRT_2
    } else {
        1.0
    }
}

/// The surface of revolution of `profile` about +Z: u around the axis (degree 2, the nine
/// circle points), v along the profile. The profile's control points are read as (r, ·, z):
/// x is the radius (≥ 0), y is ignored. A profile that rises (z increasing along it) gets
/// outward normals; a profile point on the axis makes a pole.
pub fn revolve(profile: &NurbsCurve) -> Result<NurbsSurface, NurbsError> {
    let rz: Vec<(f64, f64, f64)> = profile
        .homogeneous_points()
        .iter()
        .map(|h| {
            let p = project(*h);
            (p.x, p.z, h.w)
        })
        .collect();
    let n = rz.len();
    let mut points = Vec::with_capacity(CIRCLE.len() * n);
    let mut weights = Vec::with_capacity(CIRCLE.len() * n);
    for (i, c) in CIRCLE.iter().enumerate() {
        for &(r, z, w) in &rz {
            points.push([r * c[0], r * c[1], z]);
            weights.push(circle_weight(i) * w);
        }
    }
    NurbsSurface::new(
        [2, profile.degree()],
        [CIRCLE.len(), n],
        &points,
        Some(&weights),
        CIRCLE_KNOTS.to_vec(),
        profile.knots().to_vec(),
    )
}

/// `profile` swept along `path`: u along the profile, v along the path. The profile is drawn
/// in its own frame: its XY plane is the cross-section, +Z the direction of travel, and the
/// origin rides on the path. With [`Orient::Follow`], `tolerance` (model units, > 0) bounds how
/// far the profile's copies may stray from a true rotation-minimizing sweep.
///
/// The net is P_kj = Q_k + R_k·C_j with weights w_k·w_j, so S(u, v) = T(v) + M(v)·C(u) where
/// M(v) = Σ N_k w_k R_k / Σ N_k w_k: the profile's origin follows the path exactly, and the only
/// error is the blended frame M against the true frame R. The path is refined (every span
/// halved) until |M − R|·(the profile's reach) ≤ `tolerance` at every control point.
pub fn sweep(
    profile: &NurbsCurve,
    path: &NurbsCurve,
    orient: Orient,
    tolerance: f64,
) -> Result<NurbsSurface, NurbsError> {
    let section = profile.homogeneous_points();
    let reach = section
        .iter()
        .map(|h| project(*h).length())
        .fold(0.0f64, f64::max);
    let mut path = path.clone();
    let frames = loop {
        let frames = match orient {
            Orient::Fixed => {
                break vec![[DVec3::X, DVec3::Y, DVec3::Z]; path.homogeneous_points().len()]
            }
            Orient::Follow => follow_frames(&path)?,
        };
        if frame_gap(&path, &frames)? * reach <= tolerance {
            break frames;
        }
        path = halve_spans(&path)?;
    };
    let rows = path.homogeneous_points();
    let (nu, nv) = (section.len(), rows.len());
    let requested = nu as u128 * nv as u128;
    if requested > MAX_SWEEP_NET as u128 {
        return Err(NurbsError::TooLarge {
            what: "swept control net",
            requested,
            limit: MAX_SWEEP_NET as u128,
        });
    }
    let mut points = Vec::with_capacity(nu * nv);
    let mut weights = Vec::with_capacity(nu * nv);
    for c in section {
        let (local, wc) = (project(*c), c.w);
        for (row, [x, y, z]) in rows.iter().zip(&frames) {
            let origin = project(*row);
            let p = origin + *x * local.x + *y * local.y + *z * local.z;
            points.push(p.to_array());
            weights.push(wc * row.w);
        }
    }
    NurbsSurface::new(
        [profile.degree(), path.degree()],
        [nu, nv],
        &points,
        Some(&weights),
        profile.knots().to_vec(),
        path.knots().to_vec(),
    )
}

/// Largest difference between the blended frame M (the frames weighted as the path weights its
/// points) and the frame itself, at each control point's Greville abscissa.
fn frame_gap(path: &NurbsCurve, frames: &[[DVec3; 3]]) -> Result<f64, NurbsError> {
    let weights = path.weights();
    let params = greville(path);
    let mut gap = 0.0f64;
    for axis in 0..3 {
        let points: Vec<[f64; 3]> = frames.iter().map(|f| f[axis].to_array()).collect();
        let blended = NurbsCurve::new(
            path.degree(),
            path.knots().to_vec(),
            &points,
            Some(&weights),
        )?;
        for (f, &u) in frames.iter().zip(&params) {
            gap = gap.max((blended.point(u)? - f[axis]).length());
        }
    }
    Ok(gap)
}

/// The curve with a knot inserted in the middle of every span.
fn halve_spans(curve: &NurbsCurve) -> Result<NurbsCurve, NurbsError> {
    let [a, b] = curve.domain();
    let middles: Vec<f64> = curve
        .knots()
        .windows(2)
        .filter(|w| w[0] < w[1] && w[0] >= a && w[1] <= b)
        .map(|w| 0.5 * (w[0] + w[1]))
        .collect();
    let requested = (curve.homogeneous_points().len() + middles.len()) as u128;
    if requested > MAX_PATH_POINTS as u128 {
        return Err(NurbsError::TooLarge {
            what: "refined sweep path (raise path_tolerance)",
            requested,
            limit: MAX_PATH_POINTS as u128,
        });
    }
    let mut out = curve.clone();
    for m in middles {
        out = out.insert_knot(m, 1)?;
    }
    Ok(out)
}

/// Greville abscissae: where each control point "sits" on the curve (P&T eq. 9.36 style
/// averages of `degree` consecutive knots).
fn greville(curve: &NurbsCurve) -> Vec<f64> {
    let p = curve.degree();
    let k = curve.knots();
    (0..curve.homogeneous_points().len())
        .map(|i| k[i + 1..=i + p].iter().sum::<f64>() / p as f64)
        .collect()
}

/// A unit vector perpendicular to `t`, chosen the same way everywhere: world +X made
/// perpendicular, or +Y when `t` is nearly along X.
fn perpendicular(t: DVec3) -> DVec3 {
    let seed = if t.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    (seed - t * seed.dot(t)).normalize()
}

/// Rotation-minimizing frames `[normal, binormal, tangent]` at the path's control points
/// (double reflection between the curve points of their Greville abscissae).
fn follow_frames(path: &NurbsCurve) -> Result<Vec<[DVec3; 3]>, NurbsError> {
    let params = greville(path);
    let mut at = Vec::with_capacity(params.len());
    let mut previous = DVec3::Z;
    for &u in &params {
        let [x, d1, _] = path.derivatives(u)?;
        // A zero derivative (a cusp, doubled control points): keep the last direction.
        let t = if d1.length_squared() > 1e-300 {
            d1.normalize()
        } else {
            previous
        };
        previous = t;
        at.push((x, t));
    }
    let mut normals = Vec::with_capacity(at.len());
    normals.push(perpendicular(at[0].1));
    for k in 1..at.len() {
        let ((x0, t0), (x1, t1)) = (at[k - 1], at[k]);
        let r0 = normals[k - 1];
        let v1 = x1 - x0;
        let c1 = v1.length_squared();
        let (r_l, t_l) = if c1 > 1e-300 {
            (
                r0 - v1 * (2.0 * v1.dot(r0) / c1),
                t0 - v1 * (2.0 * v1.dot(t0) / c1),
            )
        } else {
            (r0, t0)
        };
        let v2 = t1 - t_l;
        let c2 = v2.length_squared();
        let r1 = if c2 > 1e-300 {
            r_l - v2 * (2.0 * v2.dot(r_l) / c2)
        } else {
            r_l
        };
        // Re-orthogonalize against rounding.
        let r1 = r1 - t1 * r1.dot(t1);
        normals.push(if r1.length_squared() > 1e-300 {
            r1.normalize()
        } else {
            perpendicular(t1)
        });
    }
    let last = at.len() - 1;
    let points = path.homogeneous_points();
    let scale = points
        .iter()
        .map(|h| project(*h).length())
        .fold(1.0f64, f64::max);
    let closed = (project(points[0]) - project(points[last])).length() <= 1e-12 * scale
        && at[0].1.dot(at[last].1) > 1.0 - 1e-12;
    if closed {
        // The twist the frame picked up around the loop, undone in equal steps.
        let t = at[last].1;
        let angle = libm::atan2(
            normals[last].cross(normals[0]).dot(t),
            normals[last].dot(normals[0]),
        );
        for (k, n) in normals.iter_mut().enumerate() {
            let turn = DQuat::from_axis_angle(at[k].1, angle * k as f64 / last as f64);
            *n = (turn * *n).normalize();
        }
        normals[last] = normals[0];
    }
    let mut frames: Vec<[DVec3; 3]> = at
        .iter()
        .zip(&normals)
        .map(|(&(_, t), &n)| [n, t.cross(n), t])
        .collect();
    if closed {
        frames[last] = frames[0];
    }
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nurbs::tess::{tessellate, AdaptiveOptions, Mode};

    /// The unit circle in the XY plane as a rational quadratic NURBS of radius `r`.
    fn circle(r: f64) -> NurbsCurve {
        let points: Vec<[f64; 3]> = CIRCLE.iter().map(|c| [r * c[0], r * c[1], 0.0]).collect();
        let weights: Vec<f64> = (0..9).map(circle_weight).collect();
        NurbsCurve::new(2, CIRCLE_KNOTS.to_vec(), &points, Some(&weights)).unwrap()
    }

    fn spine() -> NurbsCurve {
        let points = [
            [0.0, 0.0, 0.0],
            [0.0, 0.5, 1.0],
            [1.0, 1.0, 1.5],
            [2.0, 0.0, 2.0],
            [2.5, -1.0, 3.0],
        ];
        NurbsCurve::clamped(3, &points, Some(&[1.0, 2.0, 1.0, 0.5, 1.0])).unwrap()
    }

    #[test]
    fn fixed_sweep_is_exactly_profile_plus_path() {
        let (c, t) = (circle(0.3), spine());
        let s = sweep(&c, &t, Orient::Fixed, 1e-3).unwrap();
        for k in 0..50 {
            let (u, v) = ((k as f64 * 0.137) % 1.0, (k as f64 * 0.291) % 1.0);
            let expect = c.point(u).unwrap() + t.point(v).unwrap();
            assert!(
                (s.point(u, v).unwrap() - expect).length() < 1e-12,
                "at {u}, {v}"
            );
        }
    }

    #[test]
    fn follow_along_a_straight_path_is_the_fixed_sweep() {
        let line = NurbsCurve::clamped(
            2,
            &[[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 3.0]],
            None,
        )
        .unwrap();
        let c = circle(0.5);
        let a = sweep(&c, &line, Orient::Follow, 1e-6).unwrap();
        let b = sweep(&c, &line, Orient::Fixed, 1e-6).unwrap();
        for k in 0..20 {
            let (u, v) = (k as f64 / 19.0, (k as f64 * 0.37) % 1.0);
            assert!((a.point(u, v).unwrap() - b.point(u, v).unwrap()).length() < 1e-12);
        }
    }

    /// A circle of radius 0.25 swept around a circle of radius 2 is a torus: every point of
    /// the surface lies 0.25 from the spine circle, within what the refinement promises.
    #[test]
    fn follow_around_a_circle_makes_a_closed_torus() {
        let tube = sweep(&circle(0.25), &circle(2.0), Orient::Follow, 1e-4).unwrap();
        let topo = tube.topology();
        assert!(topo.closed_u && topo.closed_v, "{topo:?}");
        let mut worst = 0.0f64;
        for a in 0..40 {
            for b in 0..40 {
                let p = tube.point(a as f64 / 40.0, b as f64 / 40.0).unwrap();
                let ring = (p.x * p.x + p.y * p.y).sqrt() - 2.0;
                worst = worst.max(((ring * ring + p.z * p.z).sqrt() - 0.25).abs());
            }
        }
        assert!(worst < 2e-3, "torus deviation {worst}");
        let t = tessellate(
            &tube,
            &Mode::Adaptive(AdaptiveOptions::sagitta(1e-3)),
            1 << 20,
        )
        .unwrap();
        let census = t.mesh.edge_census();
        assert!(
            census.boundary.is_empty(),
            "{} boundary edges",
            census.boundary.len()
        );
        assert_eq!(census.non_manifold, 0);
    }

    #[test]
    fn a_twisting_closed_path_still_closes() {
        // A closed space curve (the first and last points and tangents agree).
        let points = [
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.5],
            [-1.0, 1.0, -0.5],
            [-1.0, -1.0, 0.5],
            [1.0, -1.0, -0.5],
            [1.0, 0.0, 0.0],
        ];
        let knots = vec![0.0, 0.0, 0.0, 0.25, 0.5, 0.75, 1.0, 1.0, 1.0];
        let path = NurbsCurve::new(2, knots, &points, None).unwrap();
        let s = sweep(&circle(0.1), &path, Orient::Follow, 1e-3).unwrap();
        assert!(s.topology().closed_v);
        let n = s.size()[1];
        for i in 0..s.size()[0] {
            assert_eq!(s.homogeneous_point(i, 0), s.homogeneous_point(i, n - 1));
        }
    }

    #[test]
    fn revolving_a_line_makes_a_cylinder() {
        let line = NurbsCurve::clamped(1, &[[1.5, 0.0, 0.0], [1.5, 0.0, 2.0]], None).unwrap();
        let s = revolve(&line).unwrap();
        assert!(s.topology().closed_u);
        for k in 0..30 {
            let p = s.point(k as f64 / 29.0, (k as f64 * 0.41) % 1.0).unwrap();
            assert!(((p.x * p.x + p.y * p.y).sqrt() - 1.5).abs() < 1e-12);
        }
    }

    #[test]
    fn a_path_too_fine_for_the_limit_is_refused() {
        let e = sweep(&circle(0.1), &spine(), Orient::Follow, 1e-15).unwrap_err();
        assert!(matches!(e, NurbsError::TooLarge { .. }), "{e}");
    }
}
