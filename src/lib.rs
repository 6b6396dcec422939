//! graftal: a deterministic batch generator of 3D meshes.
//!
//! Data flows one way: rule file → [`rules`] (AST, compiled program) →
//! [`grammar`] (the engine, on the [`kernel`]) → [`io`] (writers).
//! [`cli`] is the command line over all of them. See ARCHITECTURE.md.

#![forbid(unsafe_code)]

pub mod cli;
pub mod geom;
pub mod grammar;
pub mod io;
pub mod kernel;
pub mod nurbs;
pub mod preview;
pub mod rules;
pub mod sdf;
