//! The engine: runs a compiled [`Program`](crate::rules::Program) on the
//! kernel and reports what each step did.
//!
//! A step gathers its candidates (every element of its kind, or what an
//! earlier step created), keeps those whose condition holds — evaluated on
//! the mesh as it was before the step, so the result does not depend on
//! visiting order — and hands them, in ascending id order, to its kernel
//! operator. The G³ commands of thesis 003 join this module later.

mod properties;
mod run;

pub use run::{run, CreatedCounts, RunError, RunOptions, RunOutput, StepStats};
