//! graftal: a deterministic batch generator of 3D meshes.
//!
//! Data flows one way: rule file → [`rules`] (AST, compiled program) →
//! [`grammar`] (the engine, on the [`kernel`]) → [`io`] (writers).
//! See ARCHITECTURE.md for the map.

pub mod kernel;
