//! Knot vectors and B-spline basis functions.
//!
//! - [`validate_knots`] checks a knot vector against a degree and a control-point count
//!   (spec §2.2.3) and reports the offending index.
//! - [`clamped_uniform`] and [`periodic_uniform`] are the shorthands of rule files.
//! - [`find_span`] is Piegl & Tiller A2.1 with the half-open convention the thesis's eq. (1.8)
//!   needs (erratum: u = u_max belongs to the last non-empty span).
//! - [`basis_funs`] and [`ders_basis_funs`] are A2.2 / A2.3: the triangular, division-safe
//!   form of the Cox–de Boor recursion, eq. (1.9) with its erratum fixed (N_{i,p−1}).
//! - [`BasisTable`] holds spans and basis values for a list of parameters, computed once and
//!   reused by every row of a grid (decision D9).
//!
//! Knot vectors are never normalised to [0, 1] (geomdl does; graftal does not): the domain is
//! [u_p, u_{n+1}].

use super::error::{Field, NurbsError, MAX_DEGREE};

/// Checks a knot vector for a direction of degree `degree` with `points` control points.
///
/// Rules: 1 ≤ degree ≤ [`MAX_DEGREE`], points ≥ degree + 1, count = points + degree + 1,
/// every knot finite, non-decreasing, interior multiplicity ≤ degree, multiplicity ≤ degree + 1
/// for the knot values at the ends, and a non-empty domain.
pub fn validate_knots(
    knots: &[f64],
    degree: usize,
    points: usize,
    degree_field: Field,
    knot_field: Field,
) -> Result<(), NurbsError> {
    validate_degree(degree, points, degree_field)?;
    let expected = points + degree + 1;
    if knots.len() != expected {
        return Err(NurbsError::KnotCount {
            field: knot_field,
            expected,
            found: knots.len(),
        });
    }
    for (index, &value) in knots.iter().enumerate() {
        if !value.is_finite() {
            return Err(NurbsError::KnotNotFinite {
                field: knot_field,
                index,
                value,
            });
        }
        if index > 0 && value < knots[index - 1] {
            return Err(NurbsError::KnotDecreasing {
                field: knot_field,
                index,
                value,
                previous: knots[index - 1],
            });
        }
    }
    let first = knots[0];
    let last = knots[knots.len() - 1];
    let mut start = 0;
    while start < knots.len() {
        let mut end = start + 1;
        while end < knots.len() && knots[end] == knots[start] {
            end += 1;
        }
        let multiplicity = end - start;
        let at_end = knots[start] == first || knots[start] == last;
        let max = if at_end { degree + 1 } else { degree };
        if multiplicity > max {
            return Err(NurbsError::KnotMultiplicity {
                field: knot_field,
                index: start + max,
                value: knots[start],
                multiplicity,
                max,
            });
        }
        start = end;
    }
    let (a, b) = (knots[degree], knots[points]);
    if a >= b {
        return Err(NurbsError::EmptyDomain {
            field: knot_field,
            start: a,
            end: b,
        });
    }
    Ok(())
}

/// Checks the degree alone against the point count.
pub fn validate_degree(degree: usize, points: usize, field: Field) -> Result<(), NurbsError> {
    if degree == 0 {
        return Err(NurbsError::DegreeZero { field });
    }
    if degree > MAX_DEGREE {
        return Err(NurbsError::DegreeTooLarge {
            field,
            degree,
            max: MAX_DEGREE,
        });
    }
    if points < degree + 1 {
        return Err(NurbsError::TooFewPoints {
            field,
            degree,
            needed: degree + 1,
            found: points,
        });
    }
    Ok(())
}

/// Clamped uniform knots on [0, 1]: degree + 1 zeros, interior knots k/(n − p), degree + 1 ones
/// (what geomdl's `generate_knot_vector` produces). `points ≥ degree + 1` is checked.
pub fn clamped_uniform(degree: usize, points: usize, field: Field) -> Result<Vec<f64>, NurbsError> {
    validate_degree(degree, points, field)?;
    let segments = points - degree;
    let mut knots = Vec::with_capacity(points + degree + 1);
    knots.extend(std::iter::repeat_n(0.0, degree + 1));
    for k in 1..segments {
        knots.push(k as f64 / segments as f64);
    }
    knots.extend(std::iter::repeat_n(1.0, degree + 1));
    Ok(knots)
}

/// Uniform unclamped knots 0, 1, …, points + degree: with the last `degree` control points
/// equal to the first `degree`, the curve is periodic (C^{p−1} at the seam) on [p, points].
pub fn periodic_uniform(
    degree: usize,
    points: usize,
    field: Field,
) -> Result<Vec<f64>, NurbsError> {
    validate_degree(degree, points, field)?;
    Ok((0..points + degree + 1).map(|k| k as f64).collect())
}

/// Knot span index k with u_k ≤ u < u_{k+1} inside the domain [u_p, u_{n+1}] (A2.1).
///
/// `n` is the index of the last control point. Parameters at or beyond the ends map to the first
/// or last non-empty span; callers pass clamped parameters.
pub fn find_span(knots: &[f64], degree: usize, n: usize, u: f64) -> usize {
    let p = degree;
    if u >= knots[n + 1] {
        let mut k = n;
        while k > p && knots[k] >= knots[n + 1] {
            k -= 1;
        }
        return k;
    }
    if u <= knots[p] {
        let mut k = p;
        while knots[k + 1] <= knots[p] {
            k += 1;
        }
        return k;
    }
    let (mut low, mut high) = (p, n + 1);
    let mut mid = (low + high) / 2;
    while u < knots[mid] || u >= knots[mid + 1] {
        if u < knots[mid] {
            high = mid;
        } else {
            low = mid;
        }
        mid = (low + high) / 2;
    }
    mid
}

/// The p + 1 non-zero basis functions N_{span−p..span, p}(u) (A2.2), written to `out`.
/// `scratch` must hold 2·(p + 1) values.
pub fn basis_funs(
    knots: &[f64],
    span: usize,
    u: f64,
    p: usize,
    out: &mut [f64],
    scratch: &mut [f64],
) {
    let (left, right) = scratch.split_at_mut(p + 1);
    out[0] = 1.0;
    for j in 1..=p {
        left[j] = u - knots[span + 1 - j];
        right[j] = knots[span + j] - u;
        let mut saved = 0.0;
        for r in 0..j {
            let denom = right[r + 1] + left[j - r];
            // 0/0 := 0 (spec §2.2.1, eq. 1.9 convention); only reachable for empty spans.
            let temp = if denom != 0.0 { out[r] / denom } else { 0.0 };
            out[r] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        out[j] = saved;
    }
}

/// Basis functions and their derivatives up to order `d` (A2.3).
///
/// `out[k * (p + 1) + j]` is the k-th derivative of N_{span−p+j, p}(u), for k ≤ d. Derivatives of
/// order above p are zero.
pub fn ders_basis_funs(knots: &[f64], span: usize, u: f64, p: usize, d: usize, out: &mut [f64]) {
    let w = p + 1;
    let need = w * w + 4 * w;
    if need <= 96 {
        let mut work = [0.0; 96];
        ders_basis_funs_in(knots, span, u, p, d, out, &mut work);
    } else {
        let mut work = vec![0.0; need];
        ders_basis_funs_in(knots, span, u, p, d, out, &mut work);
    }
}

fn ders_basis_funs_in(
    knots: &[f64],
    span: usize,
    u: f64,
    p: usize,
    d: usize,
    out: &mut [f64],
    work: &mut [f64],
) {
    let w = p + 1;
    // ndu[j][r] row-major (p+1)×(p+1), then left, right and the two rows of `a`.
    let (ndu, rest) = work.split_at_mut(w * w);
    let (left, rest) = rest.split_at_mut(w);
    let (right, a) = rest.split_at_mut(w);
    ndu[0] = 1.0;
    for j in 1..=p {
        left[j] = u - knots[span + 1 - j];
        right[j] = knots[span + j] - u;
        let mut saved = 0.0;
        for r in 0..j {
            // lower triangle: knot differences
            ndu[j * w + r] = right[r + 1] + left[j - r];
            let denom = ndu[j * w + r];
            let temp = if denom != 0.0 {
                ndu[r * w + j - 1] / denom
            } else {
                0.0
            };
            ndu[r * w + j] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        ndu[j * w + j] = saved;
    }
    for v in out.iter_mut().take((d + 1) * w) {
        *v = 0.0;
    }
    for j in 0..=p {
        out[j] = ndu[j * w + p];
    }
    let dd = d.min(p);
    for r in 0..=p {
        let (mut s1, mut s2) = (0usize, 1usize);
        a[0] = 1.0;
        for k in 1..=dd {
            let mut dval = 0.0;
            let rk = r as isize - k as isize;
            let pk = p - k;
            if r >= k {
                let denom = ndu[(pk + 1) * w + rk as usize];
                a[s2 * w] = if denom != 0.0 { a[s1 * w] / denom } else { 0.0 };
                dval = a[s2 * w] * ndu[(rk as usize) * w + pk];
            }
            let j1 = if rk >= -1 { 1 } else { (-rk) as usize };
            let j2 = if (r as isize) - 1 <= pk as isize {
                k - 1
            } else {
                p - r
            };
            for j in j1..=j2 {
                let idx = (rk + j as isize) as usize;
                let denom = ndu[(pk + 1) * w + idx];
                a[s2 * w + j] = if denom != 0.0 {
                    (a[s1 * w + j] - a[s1 * w + j - 1]) / denom
                } else {
                    0.0
                };
                dval += a[s2 * w + j] * ndu[idx * w + pk];
            }
            if r <= pk {
                let denom = ndu[(pk + 1) * w + r];
                a[s2 * w + k] = if denom != 0.0 {
                    -a[s1 * w + k - 1] / denom
                } else {
                    0.0
                };
                dval += a[s2 * w + k] * ndu[r * w + pk];
            }
            out[k * w + r] = dval;
            std::mem::swap(&mut s1, &mut s2);
        }
    }
    let mut factor = p as f64;
    for k in 1..=dd {
        for j in 0..=p {
            out[k * w + j] *= factor;
        }
        factor *= (p - k) as f64;
    }
}

/// Spans and basis values (with derivatives up to `order`) for a list of parameters, in one
/// direction. Built once per grid axis and shared by all rows (decision D9).
#[derive(Debug, Clone)]
pub struct BasisTable {
    /// Degree in this direction.
    pub degree: usize,
    /// Highest derivative order stored.
    pub order: usize,
    /// Span index per parameter.
    pub spans: Vec<usize>,
    /// `values[(s * (order + 1) + k) * (p + 1) + j]`: k-th derivative of basis j at sample s.
    pub values: Vec<f64>,
}

impl BasisTable {
    /// Builds the table. `n` is the index of the last control point; parameters are clamped to
    /// the domain.
    pub fn new(knots: &[f64], degree: usize, n: usize, params: &[f64], order: usize) -> Self {
        let w = degree + 1;
        let stride = (order + 1) * w;
        let mut spans = Vec::with_capacity(params.len());
        let mut values = vec![0.0; params.len() * stride];
        let (a, b) = (knots[degree], knots[n + 1]);
        let mut scratch = vec![0.0; 2 * w];
        for (s, &u) in params.iter().enumerate() {
            let u = u.clamp(a, b);
            let span = find_span(knots, degree, n, u);
            spans.push(span);
            let out = &mut values[s * stride..(s + 1) * stride];
            if order == 0 {
                basis_funs(knots, span, u, degree, out, &mut scratch);
            } else {
                ders_basis_funs(knots, span, u, degree, order, out);
            }
        }
        BasisTable {
            degree,
            order,
            spans,
            values,
        }
    }

    /// The basis values of derivative order `k` at sample `s`.
    #[inline]
    pub fn row(&self, s: usize, k: usize) -> &[f64] {
        let w = self.degree + 1;
        let base = (s * (self.order + 1) + k) * w;
        &self.values[base..base + w]
    }
}

/// Distinct knot values inside the domain [u_p, u_{n+1}], both ends included, ascending.
pub fn breakpoints(knots: &[f64], degree: usize, points: usize) -> Vec<f64> {
    let (a, b) = (knots[degree], knots[points]);
    let mut out = vec![a];
    for &k in &knots[degree + 1..points] {
        if k > *out.last().unwrap_or(&a) && k < b {
            out.push(k);
        }
    }
    out.push(b);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn span_and_partition_of_unity() {
        let knots = [0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 3.0, 3.0, 3.0];
        let n = 5;
        assert_eq!(find_span(&knots, 3, n, 0.0), 3);
        assert_eq!(find_span(&knots, 3, n, 1.0), 4);
        assert_eq!(find_span(&knots, 3, n, 3.0), 5);
        let mut out = [0.0; 4];
        let mut scratch = [0.0; 8];
        for s in 0..=30 {
            let u = s as f64 * 0.1;
            let span = find_span(&knots, 3, n, u);
            basis_funs(&knots, span, u, 3, &mut out, &mut scratch);
            let sum: f64 = out.iter().sum();
            assert!((sum - 1.0).abs() < 1e-14);
            let mut d = [0.0; 12];
            ders_basis_funs(&knots, span, u, 3, 2, &mut d);
            for j in 0..4 {
                assert!((d[j] - out[j]).abs() < 1e-14);
            }
            let d1: f64 = d[4..8].iter().sum();
            let d2: f64 = d[8..12].iter().sum();
            assert!(d1.abs() < 1e-12 && d2.abs() < 1e-12);
        }
    }

    #[test]
    fn validation_names_index() {
        let e = validate_knots(
            &[0.0, 0.0, 1.0, 0.5, 1.0],
            1,
            3,
            Field::Degree,
            Field::Knots,
        );
        assert!(matches!(
            e,
            Err(NurbsError::KnotDecreasing { index: 3, .. })
        ));
        let e = validate_knots(
            &[0.0, 0.0, 0.5, 0.5, 1.0, 1.0],
            1,
            4,
            Field::Degree,
            Field::Knots,
        );
        assert!(matches!(
            e,
            Err(NurbsError::KnotMultiplicity { index: 3, .. })
        ));
        assert!(validate_knots(
            &[0.0, 0.0, 0.5, 1.0, 1.0],
            1,
            3,
            Field::Degree,
            Field::Knots
        )
        .is_ok());
    }
}
