//! Bézier and rational Bézier curves and patches by de Casteljau (spec §2.2.2).
//!
//! Thesis §1.1 defines Bézier curves by Bernstein polynomials (eqs. 1.1–1.2), rational ones by
//! eq. (1.4) and the (rational) Bézier surface by eq. (1.7). Everything here works in
//! homogeneous coordinates P^w = (w·P, w), so the rational and polynomial cases share one code
//! path, and the intermediate points of de Casteljau give the two halves of a subdivision.

use glam::{DVec3, DVec4};

/// Homogeneous point (w·x, w·y, w·z, w) of a Euclidean point and a weight.
#[inline]
pub fn homogeneous(p: DVec3, w: f64) -> DVec4 {
    DVec4::new(p.x * w, p.y * w, p.z * w, w)
}

/// Euclidean point of a homogeneous one.
#[inline]
pub fn project(h: DVec4) -> DVec3 {
    DVec3::new(h.x, h.y, h.z) / h.w
}

/// de Casteljau on homogeneous control points at parameter t (any degree ≥ 0).
pub fn de_casteljau(points: &[DVec4], t: f64) -> DVec4 {
    let mut work: Vec<DVec4> = points.to_vec();
    let n = work.len();
    for r in 1..n {
        for i in 0..n - r {
            work[i] = work[i] * (1.0 - t) + work[i + 1] * t;
        }
    }
    work[0]
}

/// A (rational) Bézier curve of degree `points.len() − 1` on [0, 1].
#[derive(Debug, Clone, PartialEq)]
pub struct BezierCurve {
    /// Homogeneous control points.
    pub points: Vec<DVec4>,
}

impl BezierCurve {
    /// A polynomial Bézier curve through the given control points (thesis eq. 1.1).
    pub fn new(points: &[[f64; 3]]) -> Self {
        BezierCurve {
            points: points
                .iter()
                .map(|p| homogeneous(DVec3::from_array(*p), 1.0))
                .collect(),
        }
    }

    /// A rational Bézier curve (thesis eq. 1.4); weights are not checked here (see
    /// [`crate::nurbs::curve::NurbsCurve`] for a validated constructor).
    pub fn rational(points: &[[f64; 3]], weights: &[f64]) -> Self {
        BezierCurve {
            points: points
                .iter()
                .zip(weights)
                .map(|(p, &w)| homogeneous(DVec3::from_array(*p), w))
                .collect(),
        }
    }

    /// Degree n.
    pub fn degree(&self) -> usize {
        self.points.len().saturating_sub(1)
    }

    /// C(t) by de Casteljau.
    pub fn point(&self, t: f64) -> DVec3 {
        project(de_casteljau(&self.points, t))
    }

    /// Splits at t into the control polygons of [0, t] and [t, 1].
    pub fn subdivide(&self, t: f64) -> (BezierCurve, BezierCurve) {
        let n = self.points.len();
        let mut work = self.points.clone();
        let mut left = Vec::with_capacity(n);
        let mut right = vec![DVec4::ZERO; n];
        left.push(work[0]);
        right[n - 1] = work[n - 1];
        for r in 1..n {
            for i in 0..n - r {
                work[i] = work[i] * (1.0 - t) + work[i + 1] * t;
            }
            left.push(work[0]);
            right[n - 1 - r] = work[n - 1 - r];
        }
        (BezierCurve { points: left }, BezierCurve { points: right })
    }
}

/// Bernstein polynomial B_{i,n}(t) (thesis eq. 1.2), by the recurrence (no factorials).
pub fn bernstein(i: usize, n: usize, t: f64) -> f64 {
    if i > n {
        return 0.0;
    }
    let mut b = vec![0.0; n + 1];
    b[0] = 1.0;
    for k in 1..=n {
        for j in (1..=k).rev() {
            b[j] = b[j] * (1.0 - t) + b[j - 1] * t;
        }
        b[0] *= 1.0 - t;
    }
    b[i]
}

/// A (rational) tensor-product Bézier patch of degrees (p, q) on [0, 1]², with its place in the
/// parameter domain of the surface it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct BezierPatch {
    /// Degree in u.
    pub degree_u: usize,
    /// Degree in v.
    pub degree_v: usize,
    /// Homogeneous control points, row-major: `points[i * (degree_v + 1) + j]`.
    pub points: Vec<DVec4>,
    /// The u interval of the source surface this patch covers.
    pub u_range: [f64; 2],
    /// The v interval of the source surface this patch covers.
    pub v_range: [f64; 2],
}

impl BezierPatch {
    /// S(s, t) at local parameters in [0, 1]² by tensor de Casteljau (thesis eq. 1.7).
    pub fn point_local(&self, s: f64, t: f64) -> DVec3 {
        project(self.eval_h(s, t))
    }

    /// S at a parameter of the source surface.
    pub fn point(&self, u: f64, v: f64) -> DVec3 {
        let s = (u - self.u_range[0]) / (self.u_range[1] - self.u_range[0]);
        let t = (v - self.v_range[0]) / (self.v_range[1] - self.v_range[0]);
        self.point_local(s, t)
    }

    fn eval_h(&self, s: f64, t: f64) -> DVec4 {
        let w = self.degree_v + 1;
        let column: Vec<DVec4> = (0..=self.degree_u)
            .map(|i| de_casteljau(&self.points[i * w..(i + 1) * w], t))
            .collect();
        de_casteljau(&column, s)
    }

    /// Euclidean control point (i, j).
    pub fn control_point(&self, i: usize, j: usize) -> DVec3 {
        project(self.points[i * (self.degree_v + 1) + j])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_example_1_1_2_quadratic() {
        // Listing 1.1: (0,0), (10,15), (20,0); C(u) = (1−u)²P0 + 2u(1−u)P1 + u²P2.
        let c = BezierCurve::new(&[[0.0, 0.0, 0.0], [10.0, 15.0, 0.0], [20.0, 0.0, 0.0]]);
        for k in 0..=10 {
            let u = k as f64 / 10.0;
            let expected = DVec3::new(20.0 * u, 30.0 * u * (1.0 - u), 0.0);
            assert!((c.point(u) - expected).length() < 1e-12);
        }
        assert_eq!(c.point(1.0), DVec3::new(20.0, 0.0, 0.0));
        let (l, r) = c.subdivide(0.3);
        for k in 0..=10 {
            let s = k as f64 / 10.0;
            assert!((l.point(s) - c.point(0.3 * s)).length() < 1e-12);
            assert!((r.point(s) - c.point(0.3 + 0.7 * s)).length() < 1e-12);
        }
        assert!((bernstein(1, 2, 0.25) - 2.0 * 0.25 * 0.75).abs() < 1e-15);
    }
}
