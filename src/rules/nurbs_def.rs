//! Parametric surfaces as the program holds them (`[nurbs.NAME]`, thesis
//! 002 §1.2): degrees, net size, control points and weights as compiled
//! expressions — a list, or a generator over the net indices `i`, `j` —
//! and knot vectors. [`SurfaceDef::build`] evaluates them for one variant
//! and hands them to [`crate::nurbs`], whose typed errors name the key.

use crate::nurbs::curve::NurbsCurve;
use crate::nurbs::error::{Field, NurbsError};
use crate::nurbs::knots::clamped_uniform;
use crate::nurbs::patchset::{BorderRef, Join, PatchSet, Side};
use crate::nurbs::surface::NurbsSurface;
pub use crate::nurbs::sweep::Orient;
use crate::nurbs::sweep::{revolve, sweep};
use crate::rules::program::Scalar;

/// Most control points a net may have (checked before allocating).
pub const MAX_NET_POINTS: usize = 1 << 20;

/// Highest degree a direction may have.
pub const MAX_DEGREE: usize = crate::nurbs::error::MAX_DEGREE;

/// Names a generator binds besides the parameters: the net indices.
pub const GENERATOR_NAMES: [&str; 2] = ["i", "j"];

/// A `[nurbs.NAME]` table: a surface, or a curve other surfaces are made
/// of (a profile to revolve or sweep, a path to sweep along).
#[derive(Debug, Clone)]
pub struct SurfaceDef {
    pub name: String,
    /// `file:line:column` of its table.
    pub location: String,
    pub kind: Kind,
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

/// What a `[nurbs.NAME]` table defines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Surface,
    /// A curve (`size` one number): `degree[0]`, `size[0]`, `points` (a
    /// list, or a generator over `i`), `weights` and `knots[0]` are its own.
    Curve,
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
    /// A patch set (`patches`): many surfaces meshed as one, shared
    /// borders welded (issue 37).
    Set {
        patches: PatchSource,
        joins: Vec<JoinDef>,
    },
    /// A named curve (`profile`, index into the program's tables) swept
    /// along another (`path`).
    Sweep {
        profile: usize,
        path: usize,
        orient: Orient,
        /// How far the refined path's control polygon may stray from the
        /// path (model units; `Follow` only).
        tolerance: Scalar,
    },
}

/// Where a patch set's surfaces come from.
#[derive(Debug, Clone)]
pub enum PatchSource {
    /// A patch file (index into the program's resources): `.bpt` or OBJ free-form.
    File(usize),
    /// `[nurbs.NAME]` surfaces (indices into the program's tables).
    Named(Vec<usize>),
}

/// A declared shared border: (patch index within the set, side) twice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JoinDef {
    pub a: (usize, Side),
    pub b: (usize, Side),
}

/// The profile of a surface of revolution.
#[derive(Debug, Clone)]
pub enum Profile {
    /// `[r, z]` expressions over the parameters and `j`.
    Generator(Box<[Scalar; 2]>),
    List(Vec<[Scalar; 2]>),
    /// A named curve (index into the program's tables), drawn in the XZ
    /// plane: x the radius, z the height.
    Curve(usize),
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

/// Net points a revolved profile may have (the circle takes nine rows).
const MAX_PROFILE_POINTS: usize = MAX_NET_POINTS / 9;

impl SurfaceDef {
    /// The surface with the parameters at `slots` (one value per
    /// parameter, in slot order); `defs` are the program's tables, which
    /// profiles and paths name.
    pub fn build(&self, defs: &[SurfaceDef], slots: &[f64]) -> Result<NurbsSurface, SurfaceError> {
        match &self.points {
            _ if self.kind == Kind::Curve => Err(SurfaceError::new(
                "size",
                format!("`{}` is a curve, not a surface", self.name),
            )),
            Points::Revolve(profile) => self.revolve(profile, defs, slots),
            Points::Sweep {
                profile,
                path,
                orient,
                tolerance,
            } => {
                let tolerance = tolerance.eval(slots);
                if !(tolerance.is_finite() && tolerance > 0.0) {
                    return Err(SurfaceError::new(
                        "path_tolerance",
                        format!("must be a positive number, got {tolerance}"),
                    ));
                }
                let profile = named_curve(defs, *profile, "profile", slots)?;
                let path = named_curve(defs, *path, "path", slots)?;
                sweep(&profile, &path, *orient, tolerance)
                    .map_err(|e| SurfaceError::new("path", e.to_string()))
            }
            Points::Generator(_) | Points::List(_) => self.net(slots),
            Points::Set { .. } => Err(SurfaceError::new(
                "patches",
                format!("`{}` is a patch set, not one surface", self.name),
            )),
        }
    }

    /// Whether this table is a patch set.
    pub fn is_set(&self) -> bool {
        matches!(self.points, Points::Set { .. })
    }

    /// The patch set with the parameters at `slots` (a single surface is a set of one);
    /// `file_patches` gives the surfaces a patch file holds, by resource index.
    pub fn build_set(
        &self,
        defs: &[SurfaceDef],
        slots: &[f64],
        file_patches: &dyn Fn(usize) -> Option<Vec<NurbsSurface>>,
    ) -> Result<PatchSet, SurfaceError> {
        let Points::Set { patches, joins } = &self.points else {
            return Ok(PatchSet::new(vec![self.build(defs, slots)?]));
        };
        let surfaces = match patches {
            PatchSource::File(resource) => file_patches(*resource).ok_or_else(|| {
                SurfaceError::new("patches", "the patch file was not read before the run")
            })?,
            PatchSource::Named(list) => list
                .iter()
                .map(|&k| {
                    defs[k].build(defs, slots).map_err(|e| {
                        SurfaceError::new("patches", format!("`{}`: {}", defs[k].name, e.message))
                    })
                })
                .collect::<Result<_, _>>()?,
        };
        let joins = joins
            .iter()
            .map(|j| Join {
                a: BorderRef {
                    surface: j.a.0,
                    side: j.a.1,
                },
                b: BorderRef {
                    surface: j.b.0,
                    side: j.b.1,
                },
            })
            .collect();
        Ok(PatchSet { surfaces, joins })
    }

    /// A curve table's curve with the parameters at `slots`.
    pub fn build_curve(&self, slots: &[f64]) -> Result<NurbsCurve, SurfaceError> {
        let degree = whole(self.degree[0].eval(slots), "degree", 1, MAX_DEGREE)?;
        let points: Vec<[f64; 3]> = match &self.points {
            Points::List(list) => list
                .iter()
                .map(|p| [p[0].eval(slots), p[1].eval(slots), p[2].eval(slots)])
                .collect(),
            Points::Generator(xyz) => {
                let n = whole(self.size[0].eval(slots), "size", 2, MAX_NET_POINTS)?;
                over_net(slots, [n, 1], |s| {
                    [xyz[0].eval(s), xyz[1].eval(s), xyz[2].eval(s)]
                })
            }
            _ => unreachable!("a curve has a list or a generator"),
        };
        if let Points::List(list) = &self.points {
            let n = whole(self.size[0].eval(slots), "size", 2, MAX_NET_POINTS)?;
            if n != list.len() {
                return Err(SurfaceError::new(
                    "size",
                    format!("the curve lists {} points, `size` says {n}", list.len()),
                ));
            }
        }
        let weights = self.weights_for(slots, [points.len(), 1])?;
        let knots = match &self.knots[0] {
            Knots::ClampedUniform => clamped_uniform(degree, points.len(), Field::Degree)?,
            Knots::List(list) => list.iter().map(|x| x.eval(slots)).collect(),
        };
        Ok(NurbsCurve::new(degree, knots, &points, weights.as_deref())?)
    }

    /// The weights at every net point (`None`: all 1).
    fn weights_for(
        &self,
        slots: &[f64],
        size: [usize; 2],
    ) -> Result<Option<Vec<f64>>, SurfaceError> {
        let count = size[0] * size[1];
        Ok(match &self.weights {
            None => None,
            Some(Weights::Generator(w)) => Some(over_net(slots, size, |s| w.eval(s))),
            Some(Weights::List(list)) => {
                if list.len() != count {
                    return Err(SurfaceError::new(
                        "weights",
                        format!(
                            "there are {count} control points, the list has {} weights",
                            list.len()
                        ),
                    ));
                }
                Some(list.iter().map(|w| w.eval(slots)).collect())
            }
        })
    }

    /// A surface given by its control net.
    fn net(&self, slots: &[f64]) -> Result<NurbsSurface, SurfaceError> {
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
            _ => unreachable!("built by revolve or sweep"),
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
        let weights = self.weights_for(slots, size)?;
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
    fn revolve(
        &self,
        profile: &Profile,
        defs: &[SurfaceDef],
        slots: &[f64],
    ) -> Result<NurbsSurface, SurfaceError> {
        let curve = match profile {
            Profile::Curve(k) => named_curve(defs, *k, "profile", slots)?,
            Profile::List(_) | Profile::Generator(_) => self.profile_curve(profile, slots)?,
        };
        for (k, p) in curve.control_points().iter().enumerate() {
            if !(p.x >= 0.0 && p.y == 0.0) {
                return Err(SurfaceError::new(
                    "profile",
                    format!(
                        "profile point {k} is ({}, {}, {}): a profile lies in the XZ plane (y = 0) with radius x ≥ 0",
                        p.x, p.y, p.z
                    ),
                ));
            }
        }
        Ok(revolve(&curve)?)
    }

    /// The `[r, z]` profile written in the table, as a curve in the XZ plane.
    fn profile_curve(&self, profile: &Profile, slots: &[f64]) -> Result<NurbsCurve, SurfaceError> {
        let degree = whole(self.degree[1].eval(slots), "degree", 1, MAX_DEGREE)?;
        let n = whole(self.size[1].eval(slots), "size", 2, MAX_PROFILE_POINTS)?;
        let rz: Vec<[f64; 2]> = match profile {
            Profile::List(list) => {
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
            Profile::Generator(rz) => over_net(slots, [1, n], |s| [rz[0].eval(s), rz[1].eval(s)]),
            Profile::Curve(_) => unreachable!("a named curve"),
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
        let weights = self.weights_for(slots, [1, n])?;
        let knots = match &self.knots[1] {
            Knots::ClampedUniform => clamped_uniform(degree, n, Field::DegreeV)?,
            Knots::List(list) => list.iter().map(|x| x.eval(slots)).collect(),
        };
        let points: Vec<[f64; 3]> = rz.iter().map(|p| [p[0], 0.0, p[1]]).collect();
        NurbsCurve::new(degree, knots, &points, weights.as_deref()).map_err(|e| {
            // The table writes the profile's knots as `knots_v`.
            let mut e = SurfaceError::from(e);
            if e.key == "knots" {
                e.key = "knots_v".into();
            }
            e
        })
    }
}

/// Curve `k` of the program's tables built, its errors reported at `key`.
fn named_curve(
    defs: &[SurfaceDef],
    k: usize,
    key: &str,
    slots: &[f64],
) -> Result<NurbsCurve, SurfaceError> {
    let def = &defs[k];
    def.build_curve(slots).map_err(|e| {
        SurfaceError::new(
            key,
            format!("curve `{}`: {}: {}", def.name, e.key, e.message),
        )
    })
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
