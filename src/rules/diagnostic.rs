//! Located rule-file errors, rendered with `file:line:column` and a snippet
//! with a caret under the offending text.
//!
//! One line-numbering function ([`line_column`]) serves the one-line
//! headline and the snippet, so the two always agree. Line breaks are
//! `\n`, `\r\n` and a lone `\r` (old Mac files); columns count characters.
//! Lines longer than [`SNIPPET_WIDTH`] characters are shown as a window
//! around the caret, so a one-line 100 KB file renders a readable snippet
//! (and never trips a formatter's width limits).

use std::fmt::Write as _;
use std::ops::Range;

use thiserror::Error;

/// A rule file's text and display name, kept for error rendering.
#[derive(Clone, Debug)]
pub struct SourceFile {
    pub name: String,
    pub text: String,
}

/// Widest stretch of one source line a snippet shows, in characters.
pub const SNIPPET_WIDTH: usize = 100;

/// A rule-file error: what is wrong and where. Boxed so `Result`s that
/// carry it stay small; fields are readable through `Deref`.
#[derive(Debug, Error)]
#[error("{}", .0.message)]
pub struct RuleError(Box<LocatedError>);

/// The content of a [`RuleError`].
#[derive(Debug)]
pub struct LocatedError {
    pub message: String,
    /// Display name of the file.
    pub file: String,
    /// The file's text (for the snippet).
    pub text: String,
    /// Byte range the error is about, if any.
    pub span: Option<Range<usize>>,
    pub label: String,
    pub help: Option<String>,
    /// `file:line:column` (or just `file`) for the one-line form.
    pub location: String,
}

impl RuleError {
    /// An error at a byte range of the file (or the whole file when `None`).
    pub fn at(
        file: &SourceFile,
        span: Option<Range<usize>>,
        message: impl Into<String>,
    ) -> RuleError {
        // Into the text, onto character boundaries, and out of `\r\n`
        // pairs (an offset between the two is the break itself); never
        // reversed.
        let span = span.map(|r| {
            let start = snap(&file.text, r.start);
            let end = snap(&file.text, r.end.max(start));
            start..end
        });
        let location = match &span {
            Some(range) => {
                let (line, column) = line_column(&file.text, range.start);
                format!("{}:{line}:{column}", file.name)
            }
            None => file.name.clone(),
        };
        RuleError(Box::new(LocatedError {
            message: message.into(),
            file: file.name.clone(),
            text: file.text.clone(),
            span,
            label: "here".to_owned(),
            help: None,
            location,
        }))
    }

    pub fn with_help(mut self, help: impl Into<String>) -> Self {
        self.0.help = Some(help.into());
        self
    }

    pub fn with_label(mut self, label: impl Into<String>) -> Self {
        self.0.label = label.into();
        self
    }

    /// `file:line:column: message`, for logs and scripts.
    pub fn headline(&self) -> String {
        visible(&format!("{}: {}", self.location, self.message))
    }

    /// The message, the snippet with the caret and label, and the help,
    /// as lines for a terminal (`color`: ANSI colours).
    pub fn render(&self, color: bool) -> String {
        let paint = |code: &str, s: &str| {
            if color {
                format!("\x1b[{code}m{s}\x1b[0m")
            } else {
                s.to_owned()
            }
        };
        let mut out = String::new();
        let _ = writeln!(out, "  {} {}", paint("31", "×"), visible(&self.message));
        if let Some(span) = &self.span {
            self.render_snippet(&mut out, span.clone(), &paint);
        }
        if let Some(help) = &self.help {
            let _ = writeln!(out, "  {} {}", paint("36", "help:"), visible(help));
        }
        out
    }

    fn render_snippet(
        &self,
        out: &mut String,
        span: Range<usize>,
        paint: &dyn Fn(&str, &str) -> String,
    ) {
        let text = &self.text;
        let lines = line_ranges(text);
        let (line, _) = line_column(text, span.start);
        let first = line.saturating_sub(1).max(1);
        let mut last = (line + 1).min(lines.len());
        // The empty "line" after a final line break is not worth showing.
        if last > line && lines[last - 1].is_empty() {
            last -= 1;
        }
        let gutter = last.to_string().len();
        let pad = " ".repeat(gutter);
        let _ = writeln!(out, "{pad} ╭─[{}]", visible(&self.location));
        for number in first..=last {
            let range = lines[number - 1].clone();
            let content = &text[range.clone()];
            if number != line {
                let (shown, _) = window(content, 0, 0);
                let _ = writeln!(out, "{number:>gutter$} │ {shown}");
                continue;
            }
            // The span's part on this line, in bytes: a span that starts
            // at the line break is marked just past the line's last
            // character, one that goes on to later lines up to the break.
            let start_byte = span.start.clamp(range.start, range.end);
            let end_byte = span.end.clamp(start_byte, range.end);
            // Caret columns in characters within this line.
            let start = text[range.start..start_byte].chars().count();
            let width = text[start_byte..end_byte].chars().count().max(1);
            let (shown, offset) = window(content, start, width);
            let _ = writeln!(out, "{number:>gutter$} │ {shown}");
            let caret_at = start - offset;
            // In a window, the underline stops at the window's edge.
            let width = width.min(shown.chars().count().saturating_sub(caret_at).max(1));
            let underline = if width == 1 {
                "▲".to_owned()
            } else {
                let half = width / 2;
                format!("{}┬{}", "─".repeat(half), "─".repeat(width - half - 1))
            };
            let _ = writeln!(
                out,
                "{pad} · {}{}",
                " ".repeat(caret_at),
                paint("35", &underline)
            );
            let stem = caret_at + if width == 1 { 0 } else { width / 2 };
            let _ = writeln!(
                out,
                "{pad} · {}{} {}",
                " ".repeat(stem),
                paint("35", "╰──"),
                visible(&self.label)
            );
        }
        let _ = writeln!(out, "{pad} ╰────");
    }
}

impl std::ops::Deref for RuleError {
    type Target = LocatedError;
    fn deref(&self) -> &LocatedError {
        &self.0
    }
}

/// At most [`SNIPPET_WIDTH`] characters of `line` around the characters
/// `start..start + width` (tabs shown as one space, so carets line up),
/// with `…` where it was cut; returns the text and how many characters
/// of the line precede the first one shown (the `…` counted in).
fn window(line: &str, start: usize, width: usize) -> (String, usize) {
    let total = line.chars().count();
    let clean = |s: &str| visible(&s.replace('\t', " "));
    if total <= SNIPPET_WIDTH {
        return (clean(line), 0);
    }
    let context = SNIPPET_WIDTH.saturating_sub(width.min(SNIPPET_WIDTH / 2)) / 2;
    let from = start.saturating_sub(context);
    let to = (from + SNIPPET_WIDTH).min(total);
    let from = to.saturating_sub(SNIPPET_WIDTH).min(from);
    let body: String = line.chars().skip(from).take(to - from).collect();
    let mut shown = String::new();
    let mut offset = from;
    if from > 0 {
        shown.push('…');
        offset -= 1;
    }
    shown.push_str(&clean(&body));
    if to < total {
        shown.push('…');
    }
    (shown, offset)
}

/// `text` safe to print on a terminal: control characters (an escape
/// sequence in a hostile rule file could move the cursor or retitle the
/// window) become their visible pictures, one character for one, so
/// columns and carets stay where they were. Tabs and line breaks stay.
pub fn visible(text: &str) -> String {
    text.chars()
        .map(|c| match c {
            '\t' | '\n' => c,
            '\u{0}'..='\u{1f}' => char::from_u32(0x2400 + c as u32).unwrap_or('\u{fffd}'),
            '\u{7f}' => '\u{2421}',
            '\u{80}'..='\u{9f}' => '\u{fffd}',
            c => c,
        })
        .collect()
}

/// Byte ranges of the lines of `text`, without their line breaks (`\n`,
/// `\r\n` or a lone `\r`). A text ending in a break has an empty last line.
pub fn line_ranges(text: &str) -> Vec<Range<usize>> {
    let bytes = text.as_bytes();
    let mut out = Vec::new();
    let mut start = 0;
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'\n' => {
                out.push(start..i);
                start = i + 1;
            }
            b'\r' => {
                out.push(start..i);
                if bytes.get(i + 1) == Some(&b'\n') {
                    i += 1;
                }
                start = i + 1;
            }
            _ => {}
        }
        i += 1;
    }
    out.push(start..bytes.len());
    out
}

/// 1-based line and column (in characters) of a byte offset; line breaks
/// as in [`line_ranges`]. An offset past the end, inside a character or
/// between the `\r` and the `\n` of a pair is taken as the end, the
/// character's start or the `\r`.
pub fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = snap(text, offset);
    let bytes = text.as_bytes();
    let mut line = 1;
    let mut line_start = 0;
    let mut i = 0;
    while i < offset {
        match bytes[i] {
            b'\n' => {
                line += 1;
                line_start = i + 1;
            }
            b'\r' => {
                // The break is the pair (`offset` is never between the two).
                if bytes.get(i + 1) == Some(&b'\n') {
                    i += 1;
                }
                line += 1;
                line_start = i + 1;
            }
            _ => {}
        }
        i += 1;
    }
    let column = text[line_start..offset].chars().count() + 1;
    (line, column)
}

/// The span of a string's content inside the span of its literal (TOML's
/// `"…"`, `'…'`, `"""…"""`, `'''…'''`, RON's `"…"` and `r#"…"#`), for
/// locating an error inside an expression. A value that is not a quoted
/// literal (a bare number) gives its own span.
pub fn content_span(text: &str, literal: Range<usize>, content: &str) -> Range<usize> {
    let raw = text.get(literal.clone()).unwrap_or("");
    let quote = if raw.starts_with("\"\"\"") || raw.starts_with("'''") {
        3
    } else if raw.starts_with('"') || raw.starts_with('\'') {
        1
    } else if let Some(rest) = raw.strip_prefix('r') {
        let hashes = rest.len() - rest.trim_start_matches('#').len();
        if rest[hashes..].starts_with('"') {
            2 + hashes
        } else {
            0
        }
    } else {
        0
    };
    let start = literal.start + quote;
    start..(start + content.len()).min(text.len())
}

/// `offset` moved into `text`, onto the start of its character, and from
/// between the `\r` and the `\n` of a pair back to the `\r`: a line break
/// is one place, on the line it ends.
fn snap(text: &str, offset: usize) -> usize {
    let offset = floor_char_boundary(text, offset.min(text.len()));
    let bytes = text.as_bytes();
    if offset > 0 && bytes[offset - 1] == b'\r' && bytes.get(offset) == Some(&b'\n') {
        offset - 1
    } else {
        offset
    }
}

pub(crate) fn floor_char_boundary(text: &str, mut offset: usize) -> usize {
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    offset
}

/// The byte offset at which `bytes` stop being UTF-8, if they do: for
/// locating a rule file that is not text.
pub fn invalid_utf8_offset(bytes: &[u8]) -> Option<usize> {
    std::str::from_utf8(bytes).err().map(|e| e.valid_up_to())
}

#[cfg(test)]
mod props;

#[cfg(test)]
mod tests {

    #[test]
    fn control_characters_are_shown_not_sent() {
        let file = SourceFile {
            name: "e.toml".into(),
            text: "a = \"\u{1b}]0;owned\u{7}\"\nb".into(),
        };
        let e = RuleError::at(&file, Some(5..6), "bad \u{1b}[2J value");
        for shown in [e.headline(), e.render(false)] {
            assert!(
                !shown.contains('\u{1b}') && !shown.contains('\u{7}'),
                "{shown:?}"
            );
            assert!(shown.contains('\u{241b}'), "{shown:?}");
        }
        assert_eq!(visible("a\tb\u{0}\u{7f}"), "a\tb\u{2400}\u{2421}");
    }

    use super::*;

    fn file(text: &str) -> SourceFile {
        SourceFile {
            name: "f.toml".into(),
            text: text.into(),
        }
    }

    #[test]
    fn line_column_counts_characters_from_one() {
        let text = "a = 1\nbé = \"x\"\n";
        assert_eq!(line_column(text, 0), (1, 1));
        assert_eq!(line_column(text, 6), (2, 1));
        let quote = text.find('"').unwrap();
        assert_eq!(line_column(text, quote), (2, 6));
    }

    #[test]
    fn every_line_break_style_counts_once() {
        for text in ["a\nb\nc = x", "a\r\nb\r\nc = x", "a\rb\rc = x"] {
            let x = text.find('x').unwrap();
            assert_eq!(line_column(text, x), (3, 5), "{text:?}");
            assert_eq!(line_ranges(text).len(), 3);
        }
        // Mixed: CRLF, then a lone CR, then LF.
        let text = "a\r\nb\rc\nd";
        assert_eq!(line_column(text, text.find('d').unwrap()), (4, 1));
    }

    #[test]
    fn snippet_header_and_headline_agree_for_cr_only_files() {
        let text = "[params]\rw = 1\rh = \"w +\"\r";
        let at = text.find("w +").unwrap();
        let e = RuleError::at(&file(text), Some(at..at + 3), "bad");
        assert_eq!(e.location, "f.toml:3:6");
        let rendered = e.render(false);
        assert!(rendered.contains("╭─[f.toml:3:6]"), "{rendered}");
        assert!(rendered.contains("3 │ h = \"w +\""), "{rendered}");
    }

    #[test]
    fn a_caret_past_column_65535_renders_a_window() {
        let mut text = "x = [".to_owned();
        text.push_str(&"1,".repeat(40_000));
        let at = text.len();
        text.push('\n');
        let e = RuleError::at(&file(&text), Some(at..at + 1), "unclosed array");
        assert_eq!(e.location, format!("f.toml:1:{}", at + 1));
        let rendered = e.render(false);
        assert!(rendered.len() < 1_000, "{} bytes", rendered.len());
        let lines: Vec<&str> = rendered.lines().collect();
        let shown = lines.iter().find(|l| l.starts_with("1 │ ")).unwrap();
        let caret = lines.iter().find(|l| l.contains('▲')).unwrap();
        // The caret sits one past the last shown character (the end of the line).
        assert_eq!(
            caret.chars().position(|c| c == '▲'),
            Some(shown.chars().count())
        );
        assert!(shown.starts_with("1 │ …1,1,"));
    }

    #[test]
    fn caret_lines_up_in_a_window_in_the_middle_of_a_long_line() {
        let text = format!("{}zzz{}", "a".repeat(5_000), "b".repeat(5_000));
        let e = RuleError::at(&file(&text), Some(5_000..5_003), "unknown name `zzz`");
        let rendered = e.render(false);
        let lines: Vec<&str> = rendered.lines().collect();
        let shown = lines.iter().find(|l| l.starts_with("1 │ ")).unwrap();
        let under = lines.iter().find(|l| l.contains('┬')).unwrap();
        let z = shown.chars().position(|c| c == 'z').unwrap();
        assert_eq!(under.chars().position(|c| c == '─'), Some(z));
        assert!(shown.ends_with('…') && shown.chars().count() < SNIPPET_WIDTH + 10);
    }

    #[test]
    fn spans_are_clamped_into_the_text() {
        let e = RuleError::at(&file("a = é"), Some(5..99), "x");
        assert_eq!(e.span, Some(4..6));
        assert!(e.render(false).contains('▲'));
    }

    #[test]
    fn a_span_between_cr_and_lf_is_the_line_break() {
        // `graftal check` on the 3 bytes `'\r\n` (issue 34): TOML's error
        // is at the `\n`, past the end of line 1 as the snippet cut it.
        let text = "'\r\n";
        for at in [1, 2] {
            let e = RuleError::at(&file(text), Some(at..at), "key with no value");
            assert_eq!(e.span, Some(1..1));
            assert_eq!(e.location, "f.toml:1:2");
            assert_eq!(
                e.render(false),
                "  × key with no value\n  ╭─[f.toml:1:2]\n1 │ '\n  ·  ▲\n  ·  ╰── here\n  ╰────\n"
            );
        }
        // A span from inside the pair to the next line.
        let e = RuleError::at(&file("ab\r\ncd"), Some(3..6), "x");
        assert_eq!(e.span, Some(2..6));
        assert_eq!(e.location, "f.toml:1:3");
        assert!(e.render(false).contains("1 │ ab\n  ·   ▲\n"));
        assert_eq!(line_column("a\r\nb", 2), (1, 2));
        assert_eq!(line_column("a\r\nb", 3), (2, 1));
    }

    #[test]
    fn invalid_utf8_is_found() {
        assert_eq!(invalid_utf8_offset(b"ab\xffc"), Some(2));
        assert_eq!(invalid_utf8_offset("é".as_bytes()), None);
    }
}
