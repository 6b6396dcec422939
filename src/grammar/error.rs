//! Typed errors of a run: [`StepError`] says what went wrong in a step (or
//! while evaluating the parameters), [`RunError`] adds which step it was
//! and where the file writes it, and [`RunErrorKind`] the exit code family.

use thiserror::Error;

use super::commands::CommandError;
use crate::geom::sink::SinkError;
use crate::kernel::ops::OpError;
use crate::kernel::{Domain, ValidationError};

/// Why a run failed, as scripts tell it apart (the CLI maps it to exit codes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunErrorKind {
    /// An operator or command could not be applied.
    Failed,
    /// The model outgrew `max_elements`.
    TooLarge,
    /// The run passed its deadline.
    Timeout,
    /// The run evaluated more expressions than `max_evaluations`.
    EvaluationLimit,
}

/// What went wrong in one step.
#[derive(Debug, Error)]
pub enum StepError {
    /// A kernel operator refused its input.
    #[error(transparent)]
    Operator(#[from] OpError),
    /// A parameter that counts something evaluated to no whole number.
    #[error("{what} must be a whole number ≥ 0, got {value}")]
    NotACount { what: &'static str, value: f64 },
    /// An imported file was not read before the run (a caller's mistake).
    #[error("`{0}` was not loaded before the run")]
    NotLoaded(String),
    #[error("{file}: {error}")]
    Import { file: String, error: SinkError },
    /// A G³ command could not be planned or applied on a primitive.
    #[error("{domain} {index}: {error}")]
    Command {
        domain: Domain,
        index: usize,
        error: CommandError,
    },
    #[error("probability evaluates to {value} for {domain} {index}; it must be in [0, 1]")]
    Probability {
        domain: Domain,
        index: usize,
        value: f64,
    },
    /// Under `policy = "intersect"` with `on_intersection = "error"`, or a
    /// cancel nobody could catch.
    #[error("applied to {domain} {index}, `{op}` would make a primitive that intersects the model{uncaught}")]
    Intersects {
        domain: Domain,
        index: usize,
        op: &'static str,
        /// Why a cancel became a failure (empty otherwise).
        uncaught: &'static str,
    },
    #[error("compound `{compound}` on {domain} {index}: length or radius is not finite")]
    CompoundFrame {
        compound: String,
        domain: Domain,
        index: usize,
    },
    #[error("merging: {0}")]
    Merging(OpError),
    #[error("invalid mesh after the step: {0}")]
    Invalid(ValidationError),
    #[error("integer range [{low}, {high}] is empty")]
    EmptyRange { low: f64, high: f64 },
    #[error("clamp range [{low}, {high}] is empty")]
    EmptyClamp { low: f64, high: f64 },
    #[error("parameter `{name}` evaluates to {value}")]
    NotFinite { name: String, value: f64 },
    #[error("{count} expression evaluations, over the limit of {limit}; raise it with --max-evaluations if the work is intended")]
    Evaluations { count: u64, limit: u64 },
    #[error("the program runs at least {steps} steps, one evaluation each, over the limit of {limit}; raise it with --max-evaluations if the work is intended")]
    TooManySteps { steps: u64, limit: u64 },
    #[error("the run passed its time limit (--timeout)")]
    Timeout,
    #[error("the model has {total} primitives, over the limit of {limit}; raise it with --max-primitives if the growth is intended")]
    TooLarge { total: usize, limit: usize },
    /// A signed distance tree that cannot be built (located at its node).
    #[error("{0}")]
    Tree(String),
    /// Meshing a field, or building one, failed.
    #[error("{what}: {error}")]
    Field {
        what: String,
        /// Boxed: the pillar's errors are large and rare.
        error: Box<crate::sdf::SdfError>,
    },
    /// A parametric surface could not be built or tessellated.
    #[error("nurbs surface `{surface}`: {message}")]
    Surface { surface: String, message: String },
    /// A meshing parameter evaluated out of range.
    #[error("`{key}` {message}")]
    Option { key: &'static str, message: String },
    #[error("the grid would have {cells} cells ({} x {} x {}), over the limit of {limit}; use a larger `cell` (or fewer `cells`), or raise --max-cells", grid[0], grid[1], grid[2])]
    TooManyCells {
        /// Saturated (a hostile grid's count may pass u64).
        cells: u64,
        grid: [u64; 3],
        limit: u64,
    },
    #[error("{what} would add about {coming} primitives, more than the {budget} left under --max-primitives; raise it if the growth is intended")]
    FieldTooLarge {
        what: String,
        coming: u64,
        budget: u64,
    },
    #[error("the model would grow past the limit of {limit} primitives (it has {total}, this step adds about {coming}); raise it with --max-primitives if the growth is intended")]
    WouldBeTooLarge {
        total: usize,
        coming: usize,
        limit: usize,
    },
}

impl StepError {
    /// The family of exit codes the error belongs to.
    pub fn kind(&self) -> RunErrorKind {
        match self {
            StepError::Evaluations { .. } | StepError::TooManySteps { .. } => {
                RunErrorKind::EvaluationLimit
            }
            StepError::Timeout => RunErrorKind::Timeout,
            StepError::TooLarge { .. }
            | StepError::WouldBeTooLarge { .. }
            | StepError::TooManyCells { .. }
            | StepError::FieldTooLarge { .. } => RunErrorKind::TooLarge,
            _ => RunErrorKind::Failed,
        }
    }
}

/// A failure while running: which step, where it is written, and why.
#[derive(Debug, Error)]
#[error("{location}: step `{step}`: {error}")]
pub struct RunError {
    pub kind: RunErrorKind,
    /// The step's path (`params.NAME` for a parameter).
    pub step: String,
    /// `file:line:column` of the step's operator (or the file).
    pub location: String,
    pub error: StepError,
}
