//! Typed errors of the NURBS pillar.
//!
//! Every construction error names the rule-file field it comes from ([`Field`]) and, where there
//! is one, the offending index, so the rule compiler can point at the exact location (thesis
//! §1.2–1.3 define what a valid curve or surface is; spec §2.2.3 lists the checks).

use std::fmt;

use thiserror::Error;

/// The rule-file field an error refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Field {
    /// `degree` of a curve.
    Degree,
    /// `degree[0]` (u) of a surface.
    DegreeU,
    /// `degree[1]` (v) of a surface.
    DegreeV,
    /// `knots` of a curve.
    Knots,
    /// `knots_u` of a surface.
    KnotsU,
    /// `knots_v` of a surface.
    KnotsV,
    /// `points` (control points).
    Points,
    /// `weights`.
    Weights,
}

impl fmt::Display for Field {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Field::Degree => "degree",
            Field::DegreeU => "degree_u",
            Field::DegreeV => "degree_v",
            Field::Knots => "knots",
            Field::KnotsU => "knots_u",
            Field::KnotsV => "knots_v",
            Field::Points => "points",
            Field::Weights => "weights",
        })
    }
}

/// A parameter direction of a surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Dir {
    /// The first parameter (rows of the control net, index `i`).
    U,
    /// The second parameter (columns of the control net, index `j`).
    V,
}

impl fmt::Display for Dir {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Dir::U => "u",
            Dir::V => "v",
        })
    }
}

/// Largest degree accepted in any direction. Basis tables are `(p + 1)²`, so an unbounded
/// degree taken from a rule file could allocate without limit.
pub const MAX_DEGREE: usize = 64;

/// Largest control-point coordinate magnitude accepted. Squared distances of larger values
/// overflow f64, which would turn deviations and normals into infinities.
pub const MAX_COORD: f64 = 1e100;

/// Errors from building or evaluating curves and surfaces.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum NurbsError {
    /// Degree 0 (the thesis's definitions need p ≥ 1).
    #[error("{field}: degree must be at least 1")]
    DegreeZero { field: Field },
    /// Degree above [`MAX_DEGREE`].
    #[error("{field}: degree {degree} exceeds the maximum {max}")]
    DegreeTooLarge {
        field: Field,
        degree: usize,
        max: usize,
    },
    /// Fewer than degree + 1 control points in a direction.
    #[error("{field}: degree {degree} needs at least {needed} control points, found {found}")]
    TooFewPoints {
        field: Field,
        degree: usize,
        needed: usize,
        found: usize,
    },
    /// The control-point array does not match the declared net size.
    #[error("points: expected {expected} control points ({size_u} × {size_v}), found {found}")]
    NetShape {
        size_u: usize,
        size_v: usize,
        expected: usize,
        found: usize,
    },
    /// The weight array has the wrong length.
    #[error("weights: expected {expected} weights, found {found}")]
    WeightCount { expected: usize, found: usize },
    /// Knot count ≠ points + degree + 1.
    #[error("{field}: expected {expected} knots (points + degree + 1), found {found}")]
    KnotCount {
        field: Field,
        expected: usize,
        found: usize,
    },
    /// A knot is NaN or infinite.
    #[error("{field}[{index}]: knot {value} is not finite")]
    KnotNotFinite {
        field: Field,
        index: usize,
        value: f64,
    },
    /// The knot vector decreases at `index`.
    #[error("{field}[{index}]: knot {value} is smaller than the previous knot {previous}")]
    KnotDecreasing {
        field: Field,
        index: usize,
        value: f64,
        previous: f64,
    },
    /// A knot value repeats more often than allowed (degree inside, degree + 1 at the ends).
    #[error("{field}[{index}]: knot {value} has multiplicity {multiplicity}, at most {max} allowed here")]
    KnotMultiplicity {
        field: Field,
        index: usize,
        value: f64,
        multiplicity: usize,
        max: usize,
    },
    /// `knots[p] == knots[n + 1]`: the parameter domain is empty.
    #[error("{field}: the parameter domain [{start}, {end}] is empty")]
    EmptyDomain { field: Field, start: f64, end: f64 },
    /// A control point has a NaN or infinite coordinate.
    #[error("points[{index}]: coordinate {component} is not finite")]
    PointNotFinite { index: usize, component: usize },
    /// A control-point coordinate exceeds [`MAX_COORD`] in magnitude.
    #[error("points[{index}]: coordinate {component} exceeds 1e100 in magnitude")]
    PointTooLarge { index: usize, component: usize },
    /// A weight is zero, negative, NaN or infinite.
    #[error("weights[{index}]: weight {value} must be positive, finite and within 1e-100..1e100")]
    WeightInvalid { index: usize, value: f64 },
    /// A parameter passed to an evaluator or to knot insertion is NaN or infinite.
    #[error("parameter {value} is not finite")]
    ParameterNotFinite { value: f64 },
    /// A knot to insert lies outside the parameter domain.
    #[error("{field}: knot {value} lies outside the domain [{start}, {end}]")]
    KnotOutsideDomain {
        field: Field,
        value: f64,
        start: f64,
        end: f64,
    },
    /// Inserting would push a multiplicity above the degree.
    #[error("{field}: knot {value} already has multiplicity {multiplicity} (degree {degree})")]
    InsertionFull {
        field: Field,
        value: f64,
        multiplicity: usize,
        degree: usize,
    },
    /// A direction declared closed does not meet itself.
    #[error("direction {dir} was declared closed but the surface has a gap of {gap} at the seam")]
    NotClosed { dir: Dir, gap: f64 },
    /// An operation would create more control points than `limit`.
    #[error("{what}: {requested} exceeds the limit {limit}")]
    TooLarge {
        what: &'static str,
        requested: u128,
        limit: u128,
    },
}
