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
    /// A surface of revolution about +Z: the profile's `[r, z]` points
    /// (along v) swept by the exact rational circle (along u). `size` is
    /// then the profile's point count, `degree` its degree, `weights` its
    /// weights.
    Revolve(Profile),
}

/// The profile of a surface of revolution.
#[derive(Debug, Clone)]
pub enum Profile {
    /// `[r, z]` expressions over the parameters and `j`.
    Generator(Box<[Scalar; 2]>),
    List(Vec<[Scalar; 2]>),
}

/// The quadratic rational circle in nine points (Piegl & Tiller §7.5):
/// corners of the unit square's midpoints and corners, weights 1 and √½.
const CIRCLE: [[f64; 2]; 9] = [
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
const CIRCLE_KNOTS: [f64; 12] = [
    0.0, 0.0, 0.0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1.0, 1.0, 1.0,
];

fn circle_weight(i: usize) -> f64 {
    if i % 2 == 1 {
        std::f64::consts::FRAC_1_SQRT_2
    } else {
        1.0
    }
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
        if let Points::Revolve(profile) = &self.points {
            return self.revolve(profile, slots);
        }
        let whole =
            |e: &Scalar, key: &str, min: usize, max: usize| whole(e.eval(slots), key, min, max);
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
            Points::Revolve(_) => unreachable!("built by revolve"),
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

    /// A surface of revolution: the profile (along v) swept about +Z by the
    /// exact circle (along u), closed in u, with a pole wherever the
    /// profile touches the axis.
    fn revolve(&self, profile: &Profile, slots: &[f64]) -> Result<NurbsSurface, SurfaceError> {
        let whole =
            |e: &Scalar, key: &str, min: usize, max: usize| whole(e.eval(slots), key, min, max);
        let degree = whole(&self.degree[1], "degree", 1, MAX_DEGREE)?;
        let rz: Vec<[f64; 2]> = match profile {
            Profile::List(list) => {
                let n = whole(&self.size[1], "size", 2, MAX_NET_POINTS / CIRCLE.len())?;
                if n != list.len() {
                    return Err(SurfaceError::new(
                        "size",
                        format!("the profile lists {} points, `size` says {n}", list.len()),
                    ));
                }
                list.iter()
                    .map(|p| [p[0].eval(slots), p[1].eval(slots)])
                    .collect()
            }
            Profile::Generator(rz) => {
                let n = whole(&self.size[1], "size", 2, MAX_NET_POINTS / CIRCLE.len())?;
                over_net(slots, [1, n], |s| [rz[0].eval(s), rz[1].eval(s)])
            }
        };
        if let Some(k) = rz
            .iter()
            .position(|p| !(p[0].is_finite() && p[1].is_finite() && p[0] >= 0.0))
        {
            return Err(SurfaceError::new(
                "profile",
                format!(
                    "profile point {k} is {:?}: r must be finite and ≥ 0, z finite",
                    rz[k]
                ),
            ));
        }
        let n = rz.len();
        let profile_weights: Vec<f64> = match &self.weights {
            None => vec![1.0; n],
            Some(Weights::Generator(w)) => over_net(slots, [1, n], |s| w.eval(s)),
            Some(Weights::List(list)) => {
                if list.len() != n {
                    return Err(SurfaceError::new(
                        "weights",
                        format!(
                            "the profile has {n} points, the list has {} weights",
                            list.len()
                        ),
                    ));
                }
                list.iter().map(|w| w.eval(slots)).collect()
            }
        };
        let mut points = Vec::with_capacity(CIRCLE.len() * n);
        let mut weights = Vec::with_capacity(CIRCLE.len() * n);
        for (i, c) in CIRCLE.iter().enumerate() {
            for (p, w) in rz.iter().zip(&profile_weights) {
                points.push([p[0] * c[0], p[0] * c[1], p[1]]);
                weights.push(circle_weight(i) * w);
            }
        }
        let knots_v = match &self.knots[1] {
            Knots::ClampedUniform => clamped_uniform(degree, n, Field::DegreeV)?,
            Knots::List(list) => list.iter().map(|x| x.eval(slots)).collect(),
        };
        Ok(NurbsSurface::new(
            [2, degree],
            [CIRCLE.len(), n],
            &points,
            Some(&weights),
            CIRCLE_KNOTS.to_vec(),
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

/// `x` as a whole number in [min, max], or the error at `key`.
fn whole(x: f64, key: &str, min: usize, max: usize) -> Result<usize, SurfaceError> {
    let n = libm::round(x);
    if !(x.is_finite() && (x - n).abs() < 1e-9 && n >= min as f64 && n <= max as f64) {
        return Err(SurfaceError::new(
            key,
            format!("must be a whole number in [{min}, {max}], got {x}"),
        ));
    }
    Ok(n as usize)
}
