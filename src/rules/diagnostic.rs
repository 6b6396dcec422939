//! Located rule-file errors, rendered with file:line:column and a caret.

use std::ops::Range;

use miette::{Diagnostic, NamedSource, SourceSpan};
use thiserror::Error;

/// A rule file's text and display name, kept for error rendering.
#[derive(Clone, Debug)]
pub struct SourceFile {
    pub name: String,
    pub text: String,
}

/// A rule-file error: what is wrong and where. Boxed so `Result`s that
/// carry it stay small; fields are readable through `Deref`.
#[derive(Debug, Error, Diagnostic)]
#[error(transparent)]
#[diagnostic(transparent)]
pub struct RuleError(Box<LocatedError>);

/// The content of a [`RuleError`].
#[derive(Debug, Error, Diagnostic)]
#[error("{message}")]
pub struct LocatedError {
    pub message: String,
    #[source_code]
    pub source_code: NamedSource<String>,
    #[label("{label}")]
    pub span: Option<SourceSpan>,
    pub label: String,
    #[help]
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
        let location = match &span {
            Some(range) => {
                let (line, column) = line_column(&file.text, range.start);
                format!("{}:{line}:{column}", file.name)
            }
            None => file.name.clone(),
        };
        let message = message.into();
        RuleError(Box::new(LocatedError {
            label: "here".to_owned(),
            span: span.map(|r| SourceSpan::new(r.start.into(), r.end.saturating_sub(r.start))),
            source_code: NamedSource::new(file.name.clone(), file.text.clone()),
            help: None,
            location,
            message,
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
        format!("{}: {}", self.location, self.message)
    }
}

impl std::ops::Deref for RuleError {
    type Target = LocatedError;
    fn deref(&self) -> &LocatedError {
        &self.0
    }
}

/// 1-based line and column (in characters) of a byte offset.
pub fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text[..floor_char_boundary(text, offset)];
    let line = before.bytes().filter(|&b| b == b'\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before[line_start..].chars().count() + 1;
    (line, column)
}

/// Byte offset of a 1-based line and column (in characters).
pub fn offset_of(text: &str, line: usize, column: usize) -> usize {
    let mut offset = 0;
    for (i, l) in text.split_inclusive('\n').enumerate() {
        if i + 1 == line {
            let within: usize = l
                .chars()
                .take(column.saturating_sub(1))
                .map(char::len_utf8)
                .sum();
            return offset + within;
        }
        offset += l.len();
    }
    text.len()
}

fn floor_char_boundary(text: &str, mut offset: usize) -> usize {
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    offset
}

/// Span of the first string literal whose content is `content` — the RON
/// fallback for values the RON deserializer gives no span for.
pub fn find_literal(text: &str, content: &str) -> Option<Range<usize>> {
    for quote in ['"', '\''] {
        let needle = format!("{quote}{content}{quote}");
        if let Some(i) = text.find(&needle) {
            return Some(i + 1..i + 1 + content.len());
        }
    }
    None
}

/// Span of the first occurrence of a key `name` followed by `:` or `=`.
pub fn find_key(text: &str, name: &str) -> Option<Range<usize>> {
    let mut start = 0;
    while let Some(i) = text[start..].find(name) {
        let at = start + i;
        let before_ok = at == 0
            || !text[..at]
                .chars()
                .next_back()
                .is_some_and(|c| c.is_alphanumeric() || c == '_');
        let rest = text[at + name.len()..].trim_start();
        if before_ok && (rest.starts_with(':') || rest.starts_with('=')) {
            return Some(at..at + name.len());
        }
        start = at + name.len();
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_column_counts_characters_from_one() {
        let text = "a = 1\nbé = \"x\"\n";
        assert_eq!(line_column(text, 0), (1, 1));
        assert_eq!(line_column(text, 6), (2, 1));
        let quote = text.find('"').unwrap();
        assert_eq!(line_column(text, quote), (2, 6));
        assert_eq!(offset_of(text, 2, 6), quote);
    }

    #[test]
    fn literal_and_key_search() {
        let text = "(params: {\"w\": \"1 +\"}, step: [(name: \"x\")])";
        assert_eq!(find_literal(text, "1 +"), Some(16..19));
        assert_eq!(
            find_key(text, "name"),
            Some(text.find("name").unwrap()..text.find("name").unwrap() + 4)
        );
        assert_eq!(find_key(text, "nam"), None);
    }
}
