//! Hostile input for error rendering (issue 34): any bytes (CR, CRLF,
//! lone CR, tabs, long lines, wide characters, not UTF-8, nothing) and any
//! span render without a panic, and the snippet marks the line and column
//! the headline names. The fuzz target `error_render` does the same
//! unguided; this runs in the ordinary suite, in well under a second.

use std::path::Path;

use proptest::prelude::*;

use super::{invalid_utf8_offset, line_ranges, RuleError, SourceFile, SNIPPET_WIDTH};
use crate::rules::compile::{compile, load, source_from_bytes};

/// Renders `e` every way and checks the three forms against each other and
/// against the text: the headline is `location: message`; the coloured
/// form is the plain one with ANSI codes; a located error's line and column
/// are those of its span's start (a `\r\n` pair is one break, a lone `\r`
/// is one too), its snippet marks that line, with the caret at that column
/// (in a window for long lines), and the whole stays small.
pub(super) fn assert_renders_consistently(e: &RuleError) {
    let headline = e.headline();
    assert_eq!(
        headline,
        super::visible(&format!("{}: {}", e.location, e.message))
    );
    let plain = e.render(false);
    let color = e.render(true);
    // Escapes the text brings are shown as pictures, so the only ones in
    // the coloured form are ours.
    assert!(!plain.contains('\x1b') && !headline.contains('\x1b'));
    assert_eq!(strip_ansi(&color), plain);
    let own = e.message.len() + e.label.len() + e.help.as_ref().map_or(0, String::len);
    assert!(
        plain.len() <= 2 * own + 3 * e.location.len() + 6 * 4 * (SNIPPET_WIDTH + 20),
        "{} bytes:\n{plain}",
        plain.len()
    );
    let Some(span) = e.span.clone() else {
        assert_eq!(e.location, e.file);
        assert!(!plain.contains('╭'), "{plain}");
        return;
    };
    let text = &e.text;
    assert!(span.start <= span.end && span.end <= text.len(), "{span:?}");
    assert!(text.is_char_boundary(span.start) && text.is_char_boundary(span.end));
    let bytes = text.as_bytes();
    for at in [span.start, span.end] {
        assert!(
            !(at > 0 && bytes[at - 1] == b'\r' && bytes.get(at) == Some(&b'\n')),
            "{span:?} splits a \\r\\n pair"
        );
    }

    // The headline's line and column, against a plain count.
    let (name, line, column) = split_location(&e.location);
    assert_eq!(name, e.file);
    let before = text[..span.start].replace("\r\n", "\n").replace('\r', "\n");
    assert_eq!(line, before.matches('\n').count() + 1, "{:?}", e.location);
    let tail = before.rsplit('\n').next().unwrap_or("");
    assert_eq!(column, tail.chars().count() + 1, "{:?}", e.location);

    // The snippet: a header with the location, the marked line numbered as
    // the headline says, the caret under the column.
    let rows: Vec<&str> = plain.lines().collect();
    let header = format!(" ╭─[{}]", e.location);
    let h = rows
        .iter()
        .position(|r| r.ends_with(&header))
        .unwrap_or_else(|| panic!("no header {header:?} in\n{plain}"));
    let pad = &rows[h][..rows[h].len() - header.len()];
    assert!(pad.bytes().all(|b| b == b' '));
    let marker = format!("{pad} · ");
    let u = h
        + 1
        + rows[h + 1..]
            .iter()
            .position(|r| r.starts_with(&marker))
            .unwrap_or_else(|| panic!("no underline in\n{plain}"));
    let underline = &rows[u][marker.len()..];
    assert!(
        underline.contains('▲') || underline.contains('┬'),
        "{plain}"
    );
    let (number, shown) = rows[u - 1]
        .split_once(" │ ")
        .unwrap_or_else(|| panic!("no source line before the underline in\n{plain}"));
    assert_eq!(
        number.trim_start().parse::<usize>().ok(),
        Some(line),
        "{plain}"
    );
    let caret_at = underline.chars().take_while(|&c| c == ' ').count();
    // Tabs are shown as a space, control characters as their pictures
    // (one character each, so columns hold).
    let content: Vec<char> =
        super::visible(&text[line_ranges(text)[line - 1].clone()].replace('\t', " "))
            .chars()
            .collect();
    let shown: Vec<char> = shown.chars().collect();
    assert!(column <= content.len() + 1);
    if content.len() <= SNIPPET_WIDTH {
        assert_eq!(shown, content, "{plain}");
        assert_eq!(caret_at, column - 1, "{plain}");
    } else {
        // A window: `…` where cut, the caret on the same character.
        assert!(shown.len() <= SNIPPET_WIDTH + 2, "{plain}");
        assert!(caret_at <= shown.len(), "{plain}");
        if column <= content.len() {
            assert_eq!(shown[caret_at], content[column - 1], "{plain}");
        } else {
            assert_eq!(caret_at, shown.len(), "{plain}");
        }
    }
    // The underline stays within what is shown (one past its end at most).
    assert!(
        underline.chars().count() <= shown.len().max(caret_at + 1),
        "{plain}"
    );
}

fn strip_ansi(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(at) = rest.find("\x1b[") {
        out.push_str(&rest[..at]);
        let after = &rest[at + 2..];
        let end = after.find('m').expect("an ANSI code ends in m");
        rest = &after[end + 1..];
    }
    out.push_str(rest);
    out
}

/// `name:line:column`, the name possibly holding colons itself.
fn split_location(location: &str) -> (&str, usize, usize) {
    let mut parts = location.rsplitn(3, ':');
    let column = parts.next().and_then(|c| c.parse().ok());
    let line = parts.next().and_then(|l| l.parse().ok());
    match (parts.next(), line, column) {
        (Some(name), Some(line), Some(column)) => (name, line, column),
        _ => panic!("{location:?} is not name:line:column"),
    }
}

/// A span over `len` bytes, from a choice: anywhere in `0..=len + 2`, at or
/// next to an awkward byte (a break, a tab, inside a character), or far
/// past the end.
fn position(text: &[u8], pick: prop::sample::Index, kind: u8) -> usize {
    match kind {
        0..=3 => pick.index(text.len() + 3),
        4..=6 => {
            let awkward: Vec<usize> = (0..text.len())
                .filter(|&i| matches!(text[i], b'\r' | b'\n' | b'\t') || text[i] >= 0x80)
                .flat_map(|i| [i, i + 1])
                .collect();
            if awkward.is_empty() {
                text.len()
            } else {
                awkward[pick.index(awkward.len())]
            }
        }
        _ => usize::MAX - pick.index(3),
    }
}

/// A piece of a hostile rule file.
fn piece() -> impl Strategy<Value = Vec<u8>> {
    let text = |choices: &[&'static str]| {
        prop::sample::select(choices.to_vec()).prop_map(|s| s.as_bytes().to_vec())
    };
    prop_oneof![
        6 => "[a-z_ =.0-9\"'\\[\\]{}(),:#+*-]{1,12}".prop_map(String::into_bytes),
        3 => Just(b"\r\n".to_vec()),
        2 => Just(b"\n".to_vec()),
        2 => Just(b"\r".to_vec()),
        1 => Just(b"\t".to_vec()),
        2 => text(&["é", "€", "𝄞", "e\u{301}", "漢字", "\u{feff}", "\u{2028}"]),
        // Not UTF-8: a stray byte, truncated sequences, a surrogate, an overlong form.
        1 => prop::sample::select(vec![
            &b"\xff"[..], b"\xc3", b"\xe2\x82", b"\xf0\x9d\x84", b"\xed\xa0\x80", b"\xc0\xaf",
        ]).prop_map(<[u8]>::to_vec),
        // Long lines: past the snippet's width, rarely past column 65535.
        1 => (
            prop_oneof![8 => 50usize..400, 1 => 33_000usize..36_000],
            prop::sample::select(vec!["x", "1,", "é", "\t", "a b"]),
        ).prop_map(|(n, s)| s.repeat(n).into_bytes()),
        // Rule-file text, so that some inputs parse and compile.
        2 => text(&[
            "[start]\ncube = {}\n", "[start]\r\ncube = { size = 2 }\r\n", "[params]\nw = 1\n",
            "[[step]]\nname = \"a\"\nextrude = { distance = \"w\" }\n", "(start: (cube: ()))",
            "(params: (w: 1), start: (cube: (size: \"w +\")))", "seed = 3\r\n", "x = '",
            "\"\"\"", "'''", "r#\"", "[rules.r]\nstep = []\n", "select = \"area >\"\n",
        ]),
    ]
}

fn hostile_bytes() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        1 => Just(Vec::new()),
        1 => prop::collection::vec(any::<u8>(), 0..48),
        12 => prop::collection::vec(piece(), 1..24).prop_map(|p| p.concat()),
    ]
}

type Spans = Vec<Option<(prop::sample::Index, u8, prop::sample::Index, u8)>>;

fn spans() -> impl Strategy<Value = Spans> {
    prop::collection::vec(
        prop::option::weighted(
            0.9,
            (
                any::<prop::sample::Index>(),
                0u8..8,
                any::<prop::sample::Index>(),
                0u8..8,
            ),
        ),
        1..6,
    )
}

/// Loads and compiles `bytes` as `graftal check` does, as TOML and as RON,
/// and renders whatever error comes back.
fn check_like_the_cli(bytes: &[u8]) {
    for name in ["hostile.toml", "hostile.ron"] {
        let result = source_from_bytes(name.to_owned(), bytes.to_vec()).and_then(|file| {
            let ast = load(&file)?;
            compile(&file, &ast, &[], Path::new("/nonexistent/graftal-props")).map(|_| ())
        });
        if let Err(e) = result {
            assert_renders_consistently(&e);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn any_span_of_any_bytes_renders(bytes in hostile_bytes(), spans in spans()) {
        let name = "hostile.toml".to_owned();
        let file = match source_from_bytes(name.clone(), bytes.clone()) {
            Ok(file) => file,
            Err(e) => {
                // Not UTF-8: located at the first bad byte.
                let offset = invalid_utf8_offset(&bytes).expect("only bad bytes fail");
                prop_assert_eq!(e.span.clone(), Some(offset..offset));
                prop_assert_eq!(&e.text, std::str::from_utf8(&bytes[..offset]).unwrap());
                assert_renders_consistently(&e);
                SourceFile { name, text: String::from_utf8_lossy(&bytes).into_owned() }
            }
        };
        let text = file.text.as_bytes();
        for span in &spans {
            let span = span.as_ref().map(|(a, ka, b, kb)| {
                position(text, *a, *ka)..position(text, *b, *kb)
            });
            let e = RuleError::at(&file, span, "hostile").with_label("the label");
            assert_renders_consistently(&e);
            assert_renders_consistently(&e.with_help("a help line"));
        }
        check_like_the_cli(&bytes);
    }
}

/// Every span, reversed or not, over small texts built of the awkward
/// cases, including the 3-byte file of issue 34 (`'\r\n`).
#[test]
fn every_span_of_awkward_texts_renders() {
    let long = format!("{}\r\n\t{}\r", "é".repeat(150), "x".repeat(300));
    let texts = [
        "",
        "'\r\n",
        "\r",
        "\r\n",
        "\n\r",
        "a\r\nb",
        "\r\r\n\n",
        "é\r\n€\rx\ty\n",
        "a\rb\rc = x",
        "\t\t=\r\n\t'\r\n",
        "漢字 = \"𝄞\"\r\n[start]\r\n",
        long.as_str(),
    ];
    for text in texts {
        let file = SourceFile {
            name: "awkward.toml".into(),
            text: text.into(),
        };
        let ends: Vec<usize> = (0..=text.len() + 2).chain([usize::MAX]).collect();
        let step = if text.len() > 100 { 37 } else { 1 };
        for &start in ends.iter().step_by(step) {
            for &end in ends.iter().step_by(step) {
                let e = RuleError::at(&file, Some(start..end), "m");
                assert_renders_consistently(&e);
            }
        }
        check_like_the_cli(text.as_bytes());
    }
}
