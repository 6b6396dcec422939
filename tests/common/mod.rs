//! Helpers shared by the integration tests.

use std::path::Path;

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
