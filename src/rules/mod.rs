//! Rule files: the one schema (TOML or RON), its spanned AST, the
//! expression language, parameter distributions and random streams, and
//! the compiler that turns a file into a [`program::Program`].
//!
//! Flow: [`compile::load`] (text → [`ast::RuleFile`], syntax errors located)
//! → [`compile::compile`] (names → slots, expressions compiled, semantic
//! errors located) → the engine in [`crate::grammar`].

pub mod ast;
pub mod compile;
pub mod diagnostic;
pub mod expr;
pub mod lint;
pub mod nurbs_def;
pub mod op_args;
pub mod operators;
pub mod program;
pub mod property;
pub mod random;
pub mod ron;
pub mod schema;
pub mod sdf_kinds;
pub mod sdf_tree;
pub mod spanned;

pub use compile::{compile_source, Override};
pub use diagnostic::RuleError;
pub use program::Program;
