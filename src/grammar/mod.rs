//! The engine: runs a compiled [`Program`](crate::rules::Program) on the
//! kernel and reports what each step did.
//!
//! - [`graph`]: the G³ graph on the kernel — node radius, turtle frames,
//!   ages — in attribute layers.
//! - [`commands`]: the five G³ commands, planned on generation Gₙ and then
//!   applied, so visiting order cannot change the result.
//! - [`merge`]: the `merge` policy — new nodes merged with coinciding ones.
//! - [`intersect`]: the `intersect` policy — would-be products tested
//!   against the model before an application is made.
//! - [`scope`]: compound-command scopes and their reference frames.
//! - [`properties`]: what conditions and parameters read.
//! - [`lineage`]: the key each primitive's random draws are keyed by —
//!   derived from the step that made it and its parent, not its id.
//! - `fields`: the signed distance operators (`sdf`, `sdf_part`,
//!   `sdf_boolean`, the field `skin`) and [`Input`], the files a run reads
//!   with their distance fields built once per batch.
//! - `operators`: the implementations of the registry's create, kernel
//!   and whole-mesh operators (dispatch on [`OpId`](crate::rules::operators::OpId)).
//! - `run`: the step loop, rules, compounds, statistics; `error`: its
//!   typed errors ([`StepError`], [`RunError`]).

mod asset;
pub mod commands;
mod error;
mod fields;
pub mod graph;
pub mod intersect;
pub mod lineage;
pub mod merge;
mod operators;
mod properties;
mod run;
pub mod scope;
mod surfaces;

pub use asset::{drop_unexported_layers, export, export_look, part_counts, PartCount};
pub use error::{RunError, RunErrorKind, StepError};
pub use fields::{FieldStats, Input, SkinCounts};
pub use run::{
    parameter_values, run, CreatedCounts, RunOptions, RunOutput, StepStats, DEFAULT_MAX_CELLS,
    DEFAULT_MAX_ELEMENTS, DEFAULT_MAX_EVALUATIONS,
};
pub use surfaces::SurfaceStats;
