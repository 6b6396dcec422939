//! Parametric surfaces as the program holds them (`[nurbs.NAME]`, thesis
//! 002 §1.2): degrees, net size, control points and weights as compiled
//! expressions — a list, or a generator over the net indices `i`, `j` —
//! and knot vectors. [`SurfaceDef::build`] evaluates them for one variant
//! and hands them to [`crate::nurbs`], whose typed errors name the key.

use crate::nurbs::error::{Field, NurbsError};
use crate::nurbs::knots::clamped_uniform;
use crate::nurbs::surface::NurbsSurface;
use crate::rules::program::Scalar;

/// Most control points a net may have (checked before allocating).
pub const MAX_NET_POINTS: usize = 1 << 20;

/// Highest degree a direction may have.
pub const MAX_DEGREE: usize = crate::nurbs::error::MAX_DEGREE;

/// Names a generator binds besides the parameters: the net indices.
pub const GENERATOR_NAMES: [&str; 2] = ["i", "j"];

/// A `[nurbs.NAME]` surface.
#[derive(Debug, Clone)]
pub struct SurfaceDef {
    pub name: String,
    /// `file:line:column` of its table.
    pub location: String,
    /// Degree along u and v.
    pub degree: [Scalar; 2],
    /// Control points along u and v.
    pub size: [Scalar; 2],
    pub points: Points,
    /// `None`: every weight 1 (a polynomial B-spline).
    pub weights: Option<Weights>,
    /// Knots along u, then v.
    pub knots: [Knots; 2],
}

/// Control points, row-major (`i` along u slowest).
#[derive(Debug, Clone)]
pub enum Points {
    /// `[x, y, z]` expressions over the parameters and `i`, `j`.
    Generator(Box<[Scalar; 3]>),
    List(Vec<[Scalar; 3]>),
}

#[derive(Debug, Clone)]
pub enum Weights {
    /// An expression over the parameters and `i`, `j`.
    Generator(Scalar),
    List(Vec<Scalar>),
}

#[derive(Debug, Clone)]
pub enum Knots {
    /// End knots repeated degree + 1 times, interior knots evenly spaced.
    ClampedUniform,
    List(Vec<Scalar>),
}

/// Why a surface could not be built: the key (and index) and the reason.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceError {
    pub key: String,
    pub message: String,
}

impl SurfaceError {
    fn new(key: impl Into<String>, message: impl Into<String>) -> SurfaceError {
        SurfaceError {
            key: key.into(),
            message: message.into(),
        }
    }
}

impl From<NurbsError> for SurfaceError {
    fn from(e: NurbsError) -> SurfaceError {
        let field = match &e {
            NurbsError::DegreeZero { field }
            | NurbsError::DegreeTooLarge { field, .. }
            | NurbsError::TooFewPoints { field, .. }
            | NurbsError::KnotCount { field, .. }
            | NurbsError::KnotNotFinite { field, .. }
            | NurbsError::KnotDecreasing { field, .. }
            | NurbsError::KnotMultiplicity { field, .. }
            | NurbsError::EmptyDomain { field, .. } => *field,
            NurbsError::WeightCount { .. } | NurbsError::WeightInvalid { .. } => Field::Weights,
            _ => Field::Points,
        };
        // The rule file writes both degrees as one `degree` key.
        let key = match field {
            Field::Degree | Field::DegreeU | Field::DegreeV => "degree".to_owned(),
            other => other.to_string(),
        };
        SurfaceError::new(key, e.to_string())
    }
}

impl SurfaceDef {
    /// The surface with the parameters at `slots` (one value per
    /// parameter, in slot order).
    pub fn build(&self, slots: &[f64]) -> Result<NurbsSurface, SurfaceError> {
        let whole = |e: &Scalar, key: &str, min: usize, max: usize| {
            let x = e.eval(slots);
            let n = libm::round(x);
            if !(x.is_finite() && (x - n).abs() < 1e-9 && n >= min as f64 && n <= max as f64) {
                return Err(SurfaceError::new(
                    key,
                    format!("must be a whole number in [{min}, {max}], got {x}"),
                ));
            }
            Ok(n as usize)
        };
        let degree = [
            whole(&self.degree[0], "degree", 1, MAX_DEGREE)?,
            whole(&self.degree[1], "degree", 1, MAX_DEGREE)?,
        ];
        let size = [
            whole(&self.size[0], "size", 2, MAX_NET_POINTS)?,
            whole(&self.size[1], "size", 2, MAX_NET_POINTS)?,
        ];
        let count = size[0].saturating_mul(size[1]);
        if count > MAX_NET_POINTS {
            return Err(SurfaceError::new(
                "size",
                format!(
                    "{} × {} control points is more than the limit of {MAX_NET_POINTS}",
                    size[0], size[1]
                ),
            ));
        }
        let points: Vec<[f64; 3]> = match &self.points {
            Points::Generator(xyz) => over_net(slots, size, |s| {
                [xyz[0].eval(s), xyz[1].eval(s), xyz[2].eval(s)]
            }),
            Points::List(list) => {
                if list.len() != count {
                    return Err(SurfaceError::new(
                        "points",
                        format!(
                            "a {} × {} net needs {count} points, the list has {}",
                            size[0],
                            size[1],
                            list.len()
                        ),
                    ));
                }
                list.iter()
                    .map(|p| [p[0].eval(slots), p[1].eval(slots), p[2].eval(slots)])
                    .collect()
            }
        };
        if let Some(k) = points.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
            return Err(SurfaceError::new(
                "points",
                format!(
                    "point [{}, {}] is {:?}: every coordinate must be finite",
                    k / size[1],
                    k % size[1],
                    points[k]
                ),
            ));
        }
        let weights: Option<Vec<f64>> = match &self.weights {
            None => None,
            Some(Weights::Generator(w)) => Some(over_net(slots, size, |s| w.eval(s))),
            Some(Weights::List(list)) => {
                if list.len() != count {
                    return Err(SurfaceError::new(
                        "weights",
                        format!(
                            "the net has {count} points, the list has {} weights",
                            list.len()
                        ),
                    ));
                }
                Some(list.iter().map(|w| w.eval(slots)).collect())
            }
        };
        let knots = |k: &Knots, d: usize, field: Field| -> Result<Vec<f64>, SurfaceError> {
            Ok(match k {
                Knots::ClampedUniform => clamped_uniform(degree[d], size[d], field)?,
                Knots::List(list) => list.iter().map(|x| x.eval(slots)).collect(),
            })
        };
        let knots_u = knots(&self.knots[0], 0, Field::DegreeU)?;
        let knots_v = knots(&self.knots[1], 1, Field::DegreeV)?;
        Ok(NurbsSurface::new(
            degree,
            size,
            &points,
            weights.as_deref(),
            knots_u,
            knots_v,
        )?)
    }
}

/// `f` at every net index, row-major, with `i` and `j` in the slots after
/// the parameters.
fn over_net<T>(slots: &[f64], size: [usize; 2], mut f: impl FnMut(&[f64]) -> T) -> Vec<T> {
    let base = slots.len();
    let mut indexed = slots.to_vec();
    indexed.extend([0.0, 0.0]);
    let mut out = Vec::with_capacity(size[0] * size[1]);
    for i in 0..size[0] {
        for j in 0..size[1] {
            indexed[base] = i as f64;
            indexed[base + 1] = j as f64;
            out.push(f(&indexed));
        }
    }
    out
}
