//! Rule-file load + compile (`graftal check`): TOML when the first byte is
//! even, RON when it is odd; the rest is the file (at most 64 KiB). Every
//! error is rendered. Never panics, never runs long.
#![no_main]

#[path = "../common/mod.rs"]
mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((format, body)) = common::rule_input(data) else {
        return;
    };
    // The RON reader on its own, as `parse` uses it.
    if matches!(format, graftal::rules::spanned::SourceFormat::Ron) {
        if let Ok(text) = std::str::from_utf8(body) {
            let _ = graftal::rules::ron::parse(text);
        }
    }
    let _ = common::parse_and_compile(format, body);
});
