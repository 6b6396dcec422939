//! Helpers shared by the integration tests (each test crate uses some).
#![allow(dead_code)]

use std::path::Path;

use graftal::grammar::{run, RunOptions, RunOutput, StepStats};
use graftal::rules::compile::{compile, parse};
use graftal::rules::diagnostic::SourceFile;
use graftal::rules::spanned::SourceFormat;
use graftal::rules::{Program, RuleError};

/// Compiles TOML rule text named `test.toml`, with `rules/` as its folder.
pub fn program(text: &str) -> Result<Program, RuleError> {
    let file = SourceFile {
        name: "test.toml".into(),
        text: text.into(),
    };
    let ast = parse(&file, SourceFormat::Toml)?;
    compile(&file, SourceFormat::Toml, &ast, &[], Path::new("rules"))
}

/// Asserts that each rule text fails to compile with a headline that
/// contains its expected text.
pub fn assert_rejected(cases: &[(&str, &str)]) {
    for (text, expected) in cases {
        let message = match program(text) {
            Ok(_) => panic!("expected an error for:\n{text}"),
            Err(e) => e.headline(),
        };
        assert!(
            message.contains(expected),
            "{message}\n  should contain: {expected}"
        );
    }
}

/// Compiles and runs rule text with the kernel validated after every step.
pub fn grow(text: &str) -> RunOutput {
    let p = program(text).unwrap_or_else(|e| panic!("{}", e.headline()));
    let options = RunOptions {
        validate_each_step: true,
        ..RunOptions::default()
    };
    let out = run(&p, &options).unwrap_or_else(|e| panic!("{e}"));
    out.mesh.validate().unwrap();
    out
}

/// The statistics of the step named `name`.
pub fn step<'a>(out: &'a RunOutput, name: &str) -> &'a StepStats {
    out.steps
        .iter()
        .find(|s| s.name == name)
        .unwrap_or_else(|| panic!("no step {name}"))
}
