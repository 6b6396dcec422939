//! Rendering of rule errors: any file text (CR, CRLF, tabs, wide and
//! combining characters, long lines), any byte span (reversed, past the
//! end, inside a character or a CRLF pair), any message, label and help.
//! `headline()`, `render(false)` and `render(true)` must never panic and
//! stay in proportion to the error.
#![no_main]

#[path = "../common/mod.rs"]
mod common;

use arbitrary::Arbitrary;
use graftal::rules::diagnostic::SourceFile;
use graftal::rules::RuleError;
use libfuzzer_sys::fuzz_target;

#[derive(Debug, Arbitrary)]
struct Input {
    name: String,
    message: String,
    label: Option<String>,
    help: Option<String>,
    span: Option<(u16, u16)>,
    /// The text last, so that it takes the rest of the input.
    text: String,
}

fuzz_target!(|input: Input| {
    if input.text.len() > common::MAX_RULE_BYTES {
        return;
    }
    let file = SourceFile {
        name: input.name,
        text: input.text,
    };
    let span = input.span.map(|(a, b)| a as usize..b as usize);
    let mut error = RuleError::at(&file, span, input.message);
    if let Some(label) = input.label {
        error = error.with_label(label);
    }
    if let Some(help) = input.help {
        error = error.with_help(help);
    }
    common::render(&error);
    // The not-UTF-8 error of rule files, on the same bytes.
    let mut bytes = file.text.into_bytes();
    if let Some(at) = input.span.map(|(a, _)| a as usize).filter(|&a| a < bytes.len()) {
        bytes[at] = 0xff;
    }
    if let Err(error) = graftal::rules::compile::source_from_bytes(file.name, bytes) {
        common::render(&error);
    }
});
