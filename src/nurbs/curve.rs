//! B-spline and NURBS curves of any degree (thesis §1.2–1.3, eqs. 1.10 and 1.12–1.14).
//!
//! A [`NurbsCurve`] stores homogeneous control points P^w = (w·P, w); a B-spline is the case
//! w ≡ 1, and a (rational) Bézier curve the case of clamped knots with no interior knot.
//! Evaluation is de Boor on the homogeneous points through the basis of A2.2; derivatives use
//! A2.3 and the rational quotient rule (A4.2). Planar curves of the thesis's listings use z = 0.

use glam::{DVec3, DVec4};

use super::bezier::{homogeneous, project, BezierCurve};
use super::error::{Field, NurbsError, MAX_COORD};
use super::knots::{
    basis_funs, breakpoints, clamped_uniform, ders_basis_funs, find_span, validate_knots,
};

/// A validated NURBS curve.
#[derive(Debug, Clone, PartialEq)]
pub struct NurbsCurve {
    degree: usize,
    knots: Vec<f64>,
    points: Vec<DVec4>,
}

/// Checks control points and weights and builds the homogeneous points.
pub(crate) fn homogeneous_points(
    points: &[[f64; 3]],
    weights: Option<&[f64]>,
) -> Result<Vec<DVec4>, NurbsError> {
    if let Some(w) = weights {
        if w.len() != points.len() {
            return Err(NurbsError::WeightCount {
                expected: points.len(),
                found: w.len(),
            });
        }
    }
    let mut out = Vec::with_capacity(points.len());
    for (index, p) in points.iter().enumerate() {
        if let Some(component) = p.iter().position(|c| !c.is_finite()) {
            return Err(NurbsError::PointNotFinite { index, component });
        }
        if let Some(component) = p.iter().position(|c| c.abs() > MAX_COORD) {
            return Err(NurbsError::PointTooLarge { index, component });
        }
        let w = weights.map_or(1.0, |w| w[index]);
        // Weights far from 1 overflow w·P or underflow the denominator: keep them in a range
        // where homogeneous arithmetic is exact enough.
        if !(w.is_finite() && (1e-100..=1e100).contains(&w)) {
            return Err(NurbsError::WeightInvalid { index, value: w });
        }
        let h = homogeneous(DVec3::from_array(*p), w);
        if !(h.x.is_finite() && h.y.is_finite() && h.z.is_finite()) {
            // w·P overflowed: report it on the point, the caller can scale the model.
            return Err(NurbsError::PointNotFinite {
                index,
                component: if h.x.is_finite() {
                    if h.y.is_finite() {
                        2
                    } else {
                        1
                    }
                } else {
                    0
                },
            });
        }
        out.push(h);
    }
    Ok(out)
}

impl NurbsCurve {
    /// A curve of degree `degree` with explicit knots; `weights = None` gives a B-spline.
    pub fn new(
        degree: usize,
        knots: Vec<f64>,
        points: &[[f64; 3]],
        weights: Option<&[f64]>,
    ) -> Result<Self, NurbsError> {
        validate_knots(&knots, degree, points.len(), Field::Degree, Field::Knots)?;
        let points = homogeneous_points(points, weights)?;
        Ok(NurbsCurve {
            degree,
            knots,
            points,
        })
    }

    /// A curve with clamped uniform knots on [0, 1] (the `knots = "clamped_uniform"` shorthand).
    pub fn clamped(
        degree: usize,
        points: &[[f64; 3]],
        weights: Option<&[f64]>,
    ) -> Result<Self, NurbsError> {
        let knots = clamped_uniform(degree, points.len(), Field::Degree)?;
        Self::new(degree, knots, points, weights)
    }

    /// A (rational) Bézier curve as a NURBS: degree = points − 1, knots [0…0, 1…1].
    pub fn bezier(points: &[[f64; 3]], weights: Option<&[f64]>) -> Result<Self, NurbsError> {
        let degree = points.len().saturating_sub(1);
        Self::clamped(degree, points, weights)
    }

    /// Degree p.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// The knot vector.
    pub fn knots(&self) -> &[f64] {
        &self.knots
    }

    /// Homogeneous control points.
    pub fn homogeneous_points(&self) -> &[DVec4] {
        &self.points
    }

    /// Euclidean control points.
    pub fn control_points(&self) -> Vec<DVec3> {
        self.points.iter().map(|h| project(*h)).collect()
    }

    /// Weights.
    pub fn weights(&self) -> Vec<f64> {
        self.points.iter().map(|h| h.w).collect()
    }

    /// The parameter domain [u_p, u_{n+1}].
    pub fn domain(&self) -> [f64; 2] {
        [self.knots[self.degree], self.knots[self.points.len()]]
    }

    fn check(&self, u: f64) -> Result<f64, NurbsError> {
        if !u.is_finite() {
            return Err(NurbsError::ParameterNotFinite { value: u });
        }
        let [a, b] = self.domain();
        Ok(u.clamp(a, b))
    }

    /// C(u); parameters outside the domain are clamped to it.
    pub fn point(&self, u: f64) -> Result<DVec3, NurbsError> {
        let u = self.check(u)?;
        let p = self.degree;
        let n = self.points.len() - 1;
        let span = find_span(&self.knots, p, n, u);
        let mut basis = vec![0.0; p + 1];
        let mut scratch = vec![0.0; 2 * (p + 1)];
        basis_funs(&self.knots, span, u, p, &mut basis, &mut scratch);
        let mut h = DVec4::ZERO;
        for (j, b) in basis.iter().enumerate() {
            h += self.points[span - p + j] * *b;
        }
        Ok(project(h))
    }

    /// C(u), C'(u), C''(u) (A2.3 on the homogeneous points, then A4.2).
    pub fn derivatives(&self, u: f64) -> Result<[DVec3; 3], NurbsError> {
        let u = self.check(u)?;
        let p = self.degree;
        let n = self.points.len() - 1;
        let span = find_span(&self.knots, p, n, u);
        let mut ders = vec![0.0; 3 * (p + 1)];
        ders_basis_funs(&self.knots, span, u, p, 2, &mut ders);
        let mut a = [DVec4::ZERO; 3];
        for (k, ak) in a.iter_mut().enumerate() {
            for j in 0..=p {
                *ak += self.points[span - p + j] * ders[k * (p + 1) + j];
            }
        }
        Ok(rational_curve_derivs(&a))
    }

    /// Boehm knot insertion (A5.1) of `u`, `times` times. The curve is unchanged.
    pub fn insert_knot(&self, u: f64, times: usize) -> Result<NurbsCurve, NurbsError> {
        let (knots, points) = insert_knot_h(
            &self.knots,
            self.degree,
            &self.points,
            u,
            times,
            Field::Knots,
        )?;
        Ok(NurbsCurve {
            degree: self.degree,
            knots,
            points,
        })
    }

    /// Decomposition into Bézier segments over the domain (A5.6 by repeated insertion), with the
    /// parameter interval of each.
    pub fn to_bezier(&self) -> Result<Vec<([f64; 2], BezierCurve)>, NurbsError> {
        let p = self.degree;
        let mut curve = self.clone();
        for x in breakpoints(&self.knots, p, self.points.len()) {
            let m = multiplicity(&curve.knots, x);
            if m < p {
                curve = curve.insert_knot(x, p - m)?;
            }
        }
        let bps = breakpoints(&curve.knots, p, curve.points.len());
        let mut out = Vec::with_capacity(bps.len() - 1);
        for w in bps.windows(2) {
            let span = find_span(&curve.knots, p, curve.points.len() - 1, 0.5 * (w[0] + w[1]));
            out.push((
                [w[0], w[1]],
                BezierCurve {
                    points: curve.points[span - p..=span].to_vec(),
                },
            ));
        }
        Ok(out)
    }
}

/// Number of knots equal to `x`.
pub(crate) fn multiplicity(knots: &[f64], x: f64) -> usize {
    knots.iter().filter(|&&k| k == x).count()
}

/// Rational derivatives from homogeneous ones (A4.2, orders 0–2).
pub(crate) fn rational_curve_derivs(a: &[DVec4; 3]) -> [DVec3; 3] {
    let w0 = a[0].w;
    let c0 = a[0].truncate() / w0;
    let c1 = (a[1].truncate() - c0 * a[1].w) / w0;
    let c2 = (a[2].truncate() - c1 * (2.0 * a[1].w) - c0 * a[2].w) / w0;
    [c0, c1, c2]
}

/// Boehm insertion on homogeneous control points (Piegl & Tiller A5.1).
pub(crate) fn insert_knot_h(
    knots: &[f64],
    p: usize,
    points: &[DVec4],
    u: f64,
    times: usize,
    field: Field,
) -> Result<(Vec<f64>, Vec<DVec4>), NurbsError> {
    if !u.is_finite() {
        return Err(NurbsError::ParameterNotFinite { value: u });
    }
    let n = points.len() - 1;
    let (a, b) = (knots[p], knots[n + 1]);
    if u < a || u > b {
        return Err(NurbsError::KnotOutsideDomain {
            field,
            value: u,
            start: a,
            end: b,
        });
    }
    let s = multiplicity(knots, u);
    if times == 0 {
        return Ok((knots.to_vec(), points.to_vec()));
    }
    if s + times > p {
        return Err(NurbsError::InsertionFull {
            field,
            value: u,
            multiplicity: s,
            degree: p,
        });
    }
    let r = times;
    // k: the last index with knots[k] <= u (over the whole vector, so that u = b of an
    // unclamped domain is handled).
    let k = knots.partition_point(|&x| x <= u) - 1;
    let mp = n + p + 1;
    let mut uq = Vec::with_capacity(knots.len() + r);
    uq.extend_from_slice(&knots[..=k]);
    uq.extend(std::iter::repeat_n(u, r));
    uq.extend_from_slice(&knots[k + 1..=mp]);
    let mut qw = vec![DVec4::ZERO; n + 1 + r];
    qw[..=(k - p)].copy_from_slice(&points[..=(k - p)]);
    qw[(k - s + r)..=(n + r)].copy_from_slice(&points[(k - s)..=n]);
    let mut rw: Vec<DVec4> = (0..=p - s).map(|i| points[k - p + i]).collect();
    let mut l = 0;
    for j in 1..=r {
        l = k - p + j;
        for i in 0..=(p - j - s) {
            let alpha = (u - knots[l + i]) / (knots[i + k + 1] - knots[l + i]);
            rw[i] = rw[i + 1] * alpha + rw[i] * (1.0 - alpha);
        }
        qw[l] = rw[0];
        qw[k + r - j - s] = rw[p - j - s];
    }
    if l + 1 < k - s {
        qw[(l + 1)..(k - s)].copy_from_slice(&rw[1..(k - s - l)]);
    }
    Ok((uq, qw))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bezier_matches_de_casteljau_and_insertion_is_exact() {
        let pts = [
            [0.0, 0.0, 0.0],
            [1.0, 2.0, 0.5],
            [3.0, 2.5, -1.0],
            [4.0, 0.0, 0.0],
        ];
        let w = [1.0, 0.5, 2.0, 1.0];
        let c = NurbsCurve::bezier(&pts, Some(&w)).unwrap();
        let b = BezierCurve::rational(&pts, &w);
        for k in 0..=20 {
            let u = k as f64 / 20.0;
            assert!((c.point(u).unwrap() - b.point(u)).length() < 1e-13);
        }
        let c2 = c.insert_knot(0.37, 2).unwrap();
        for k in 0..=20 {
            let u = k as f64 / 20.0;
            assert!((c.point(u).unwrap() - c2.point(u).unwrap()).length() < 1e-13);
        }
    }
}
