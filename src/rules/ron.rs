//! A span-preserving reader for RON rule files.
//!
//! The `ron` crate's deserializer reports where a *syntax* error is, but
//! gives values no spans, so semantic errors (an unknown name in an
//! expression, a bad `repeat`) could only be located by searching the text
//! for the literal — wrong when the literal repeats. This module parses RON
//! into a [`Value`] tree where every value and key carries its byte range,
//! then deserializes the tree with serde, speaking `serde_spanned`'s
//! protocol as the TOML deserializer does. So every RON error is as exact
//! as a TOML one, through the same [`super::spanned::Spanned`] type.
//!
//! The dialect is RON as rule files use it: structs `(key: value)`, with an
//! optional name (`Step(...)`), tuples `(a, b)`, lists `[...]`, maps
//! `{"key": value}`, strings with escapes and raw strings `r#"..."#`,
//! chars, integers (decimal, `0x`, `0o`, `0b`, `_` separators), floats
//! (`1.5`, `1e-3`, `inf`, `NaN`), `true`/`false`, bare identifiers (enum
//! variants such as `faces`), `Some(x)`/`None` (or the value itself:
//! optional values are implicitly `Some`), `//` and nested `/* */`
//! comments and `#![enable(...)]` attributes. Nesting is limited to
//! [`MAX_DEPTH`] levels, so hostile input cannot overflow the stack.

use std::fmt;
use std::ops::Range;

use serde::de::{self, DeserializeSeed, IntoDeserializer, Visitor};

/// Deepest nesting of lists, tuples, structs and maps a file may use.
pub const MAX_DEPTH: usize = 128;

/// A parsed value and the bytes it was written in.
#[derive(Debug, Clone, PartialEq)]
pub struct Value {
    pub kind: Kind,
    pub span: Range<usize>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum Kind {
    /// `()`
    Unit,
    Bool(bool),
    Integer(i128),
    Float(f64),
    Str(String),
    Char(char),
    /// A bare identifier: an enum variant, a unit struct, `None`.
    Ident(String),
    /// `[a, b]`
    List(Vec<Value>),
    /// `(a, b)` or `Name(a, b)` (`Some(x)` is one).
    Tuple(Option<String>, Vec<Value>),
    /// `(key: value)` or `Name(key: value)`; keys are [`Kind::Str`] values.
    Struct(Option<String>, Vec<(Value, Value)>),
    /// `{key: value}`
    Map(Vec<(Value, Value)>),
}

/// A syntax error, or a value that does not fit the schema.
#[derive(Debug, Clone, PartialEq)]
pub struct Error {
    pub message: String,
    pub span: Option<Range<usize>>,
}

impl Error {
    fn at(span: Range<usize>, message: impl Into<String>) -> Error {
        Error {
            message: message.into(),
            span: Some(span),
        }
    }

    /// Locates an error raised without a position (serde's own messages).
    fn or_at(mut self, span: &Range<usize>) -> Error {
        if self.span.is_none() {
            self.span = Some(span.clone());
        }
        self
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Error {}

impl de::Error for Error {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        // serde says "invalid type: map, expected …"; RON calls maps structs.
        Error {
            message: msg.to_string(),
            span: None,
        }
    }
}

/// Parses RON text into a value tree.
pub fn parse(text: &str) -> Result<Value, Error> {
    let mut p = Parser { text, at: 0 };
    p.skip_space()?;
    p.attributes()?;
    let value = p.value(0)?;
    p.skip_space()?;
    if p.at < text.len() {
        let end = p.char_end(p.at);
        return Err(Error::at(
            p.at..end,
            "unexpected text after the value (a file holds one value)",
        ));
    }
    Ok(value)
}

/// Deserializes `T` from a parsed value.
pub fn from_value<'a, T: de::Deserialize<'a>>(value: &'a Value) -> Result<T, Error> {
    T::deserialize(ValueDeserializer { value }).map_err(|e| e.or_at(&value.span))
}

struct Parser<'t> {
    text: &'t str,
    at: usize,
}

fn is_ident_start(c: char) -> bool {
    c.is_ascii_alphabetic() || c == '_'
}

fn is_ident_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

impl Parser<'_> {
    fn peek(&self) -> Option<char> {
        self.text[self.at..].chars().next()
    }

    fn peek_at(&self, k: usize) -> Option<char> {
        self.text[self.at..].chars().nth(k)
    }

    fn char_end(&self, at: usize) -> usize {
        at + self.text[at..].chars().next().map_or(0, char::len_utf8)
    }

    /// Where "unexpected end" errors point: just past the last token.
    fn end_error(&self, what: &str) -> Error {
        let end = self.text.trim_end().len();
        Error::at(end..end, format!("unexpected end of file, expected {what}"))
    }

    fn unexpected(&self, what: &str) -> Error {
        match self.peek() {
            None => self.end_error(what),
            Some(c) => Error::at(
                self.at..self.at + c.len_utf8(),
                format!("expected {what}, found `{c}`"),
            ),
        }
    }

    fn skip_space(&mut self) -> Result<(), Error> {
        loop {
            let rest = &self.text[self.at..];
            let trimmed = rest.trim_start();
            self.at += rest.len() - trimmed.len();
            if trimmed.starts_with("//") {
                self.at += trimmed.find('\n').unwrap_or(trimmed.len());
            } else if trimmed.starts_with("/*") {
                let start = self.at;
                let mut depth = 0usize;
                loop {
                    let rest = &self.text[self.at..];
                    if rest.starts_with("/*") {
                        depth += 1;
                        self.at += 2;
                    } else if rest.starts_with("*/") {
                        depth -= 1;
                        self.at += 2;
                        if depth == 0 {
                            break;
                        }
                    } else if let Some(c) = rest.chars().next() {
                        self.at += c.len_utf8();
                    } else {
                        return Err(Error::at(start..start + 2, "unclosed block comment"));
                    }
                }
            } else {
                return Ok(());
            }
        }
    }

    fn eat(&mut self, c: char) -> Result<bool, Error> {
        self.skip_space()?;
        if self.peek() == Some(c) {
            self.at += c.len_utf8();
            Ok(true)
        } else {
            Ok(false)
        }
    }

    fn expect(&mut self, c: char, what: &str) -> Result<(), Error> {
        if self.eat(c)? {
            Ok(())
        } else {
            Err(self.unexpected(what))
        }
    }

    /// `#![enable(implicit_some, ...)]` lines at the top (implicit `Some`
    /// is always on; other extensions change nothing rule files use).
    fn attributes(&mut self) -> Result<(), Error> {
        while self.text[self.at..].starts_with("#!") {
            let start = self.at;
            self.at += 2;
            self.expect('[', "`[` after `#!`")?;
            self.skip_space()?;
            let name = self.ident().unwrap_or_default();
            if name != "enable" {
                return Err(Error::at(
                    start..self.at,
                    "only `#![enable(...)]` attributes are known",
                ));
            }
            self.expect('(', "`(` after `enable`")?;
            loop {
                self.skip_space()?;
                if self.eat(')')? {
                    break;
                }
                if self.ident().is_none() {
                    return Err(self.unexpected("an extension name"));
                }
                if !self.eat(',')? {
                    self.expect(')', "`,` or `)`")?;
                    break;
                }
            }
            self.expect(']', "`]` closing the attribute")?;
            self.skip_space()?;
        }
        Ok(())
    }

    /// An identifier (`r#` raw identifiers too), or `None` (nothing read).
    fn ident(&mut self) -> Option<String> {
        let rest = &self.text[self.at..];
        let (prefix, body) = match rest.strip_prefix("r#") {
            Some(body) if body.starts_with(is_ident_start) => (2, body),
            _ => (0, rest),
        };
        if !body.starts_with(is_ident_start) {
            return None;
        }
        let len = body.find(|c: char| !is_ident_char(c)).unwrap_or(body.len());
        self.at += prefix + len;
        Some(body[..len].to_owned())
    }

    fn value(&mut self, depth: usize) -> Result<Value, Error> {
        self.skip_space()?;
        let start = self.at;
        if depth >= MAX_DEPTH {
            return Err(Error::at(
                start..self.char_end(start),
                format!("values are nested more than {MAX_DEPTH} levels deep"),
            ));
        }
        let Some(c) = self.peek() else {
            return Err(self.end_error("a value"));
        };
        let kind = match c {
            '(' => {
                self.at += 1;
                self.parenthesized(None, depth)?
            }
            '[' => {
                self.at += 1;
                let items = self.items(']', depth)?;
                Kind::List(items)
            }
            '{' => {
                self.at += 1;
                self.map(depth)?
            }
            '"' => Kind::Str(self.string()?),
            'r' if matches!(self.peek_at(1), Some('"' | '#'))
                && self.text[self.at + 1..]
                    .trim_start_matches('#')
                    .starts_with('"') =>
            {
                Kind::Str(self.raw_string()?)
            }
            '\'' => Kind::Char(self.char_literal()?),
            '0'..='9' | '+' | '-' | '.' => self.number()?,
            c if is_ident_start(c) => {
                let name = self.ident().expect("starts with an identifier character");
                match name.as_str() {
                    "true" => Kind::Bool(true),
                    "false" => Kind::Bool(false),
                    "inf" => Kind::Float(f64::INFINITY),
                    "NaN" => Kind::Float(f64::NAN),
                    _ => {
                        let before = self.at;
                        if self.eat('(')? {
                            self.parenthesized(Some(name), depth)?
                        } else {
                            self.at = before;
                            Kind::Ident(name)
                        }
                    }
                }
            }
            _ => return Err(self.unexpected("a value")),
        };
        Ok(Value {
            kind,
            span: start..self.at,
        })
    }

    /// After `(`: `()`, a struct `(key: value, ...)` or a tuple `(a, ...)`.
    fn parenthesized(&mut self, name: Option<String>, depth: usize) -> Result<Kind, Error> {
        self.skip_space()?;
        if self.eat(')')? {
            return Ok(match name {
                None => Kind::Unit,
                Some(n) => Kind::Tuple(Some(n), Vec::new()),
            });
        }
        // `ident :` (not `::`) starts a struct.
        let save = self.at;
        let is_struct = match self.ident() {
            Some(_) => {
                self.skip_space()?;
                self.text[self.at..].starts_with(':') && !self.text[self.at..].starts_with("::")
            }
            None => false,
        };
        self.at = save;
        if !is_struct {
            return Ok(Kind::Tuple(name, self.items(')', depth)?));
        }
        let mut fields = Vec::new();
        loop {
            self.skip_space()?;
            if self.eat(')')? {
                break;
            }
            let key_start = self.at;
            let Some(key) = self.ident() else {
                return Err(self.unexpected("a field name"));
            };
            let key = Value {
                kind: Kind::Str(key),
                span: key_start..self.at,
            };
            self.expect(':', "`:` after the field name")?;
            let value = self.value(depth + 1)?;
            fields.push((key, value));
            if !self.eat(',')? {
                self.expect(')', "`,` or `)`")?;
                break;
            }
        }
        Ok(Kind::Struct(name, fields))
    }

    /// Comma-separated values up to `close` (a trailing comma is allowed).
    fn items(&mut self, close: char, depth: usize) -> Result<Vec<Value>, Error> {
        let mut items = Vec::new();
        loop {
            if self.eat(close)? {
                break;
            }
            items.push(self.value(depth + 1)?);
            if !self.eat(',')? {
                self.expect(close, &format!("`,` or `{close}`"))?;
                break;
            }
        }
        Ok(items)
    }

    fn map(&mut self, depth: usize) -> Result<Kind, Error> {
        let mut entries = Vec::new();
        loop {
            if self.eat('}')? {
                break;
            }
            let key = self.value(depth + 1)?;
            self.expect(':', "`:` after the key")?;
            let value = self.value(depth + 1)?;
            entries.push((key, value));
            if !self.eat(',')? {
                self.expect('}', "`,` or `}`")?;
                break;
            }
        }
        Ok(Kind::Map(entries))
    }

    fn string(&mut self) -> Result<String, Error> {
        let start = self.at;
        self.at += 1;
        let mut out = String::new();
        loop {
            let Some(c) = self.peek() else {
                return Err(Error::at(start..start + 1, "unclosed string"));
            };
            self.at += c.len_utf8();
            match c {
                '"' => return Ok(out),
                '\\' => out.push(self.escape()?),
                c => out.push(c),
            }
        }
    }

    fn escape(&mut self) -> Result<char, Error> {
        let start = self.at - 1;
        let Some(c) = self.peek() else {
            return Err(Error::at(start..start + 1, "unclosed string"));
        };
        self.at += c.len_utf8();
        let bad = |p: &Self, what: &str| Error::at(start..p.at, format!("invalid escape: {what}"));
        Ok(match c {
            '"' => '"',
            '\'' => '\'',
            '\\' => '\\',
            '/' => '/',
            'n' => '\n',
            'r' => '\r',
            't' => '\t',
            '0' => '\0',
            'b' => '\u{8}',
            'f' => '\u{c}',
            'x' => {
                let hex = self.text.get(self.at..self.at + 2).unwrap_or("");
                let code = u8::from_str_radix(hex, 16)
                    .map_err(|_| bad(self, "`\\x` needs two hex digits"))?;
                self.at += 2;
                if code > 0x7f {
                    return Err(bad(self, "`\\x` escapes stop at 7f"));
                }
                code as char
            }
            'u' => {
                let (hex, len) = if self.peek() == Some('{') {
                    let close = self.text[self.at..]
                        .find('}')
                        .ok_or_else(|| bad(self, "unclosed `\\u{`"))?;
                    (&self.text[self.at + 1..self.at + close], close + 1)
                } else {
                    (self.text.get(self.at..self.at + 4).unwrap_or(""), 4)
                };
                let code = u32::from_str_radix(hex, 16).map_err(|_| bad(self, "bad `\\u` code"))?;
                self.at += len;
                char::from_u32(code).ok_or_else(|| bad(self, "not a Unicode scalar value"))?
            }
            other => return Err(bad(self, &format!("`\\{other}`"))),
        })
    }

    fn raw_string(&mut self) -> Result<String, Error> {
        let start = self.at;
        self.at += 1;
        let hashes =
            self.text[self.at..].len() - self.text[self.at..].trim_start_matches('#').len();
        self.at += hashes + 1;
        let close = format!("\"{}", "#".repeat(hashes));
        let Some(end) = self.text[self.at..].find(&close) else {
            return Err(Error::at(start..start + 1, "unclosed raw string"));
        };
        let body = self.text[self.at..self.at + end].to_owned();
        self.at += end + close.len();
        Ok(body)
    }

    fn char_literal(&mut self) -> Result<char, Error> {
        let start = self.at;
        self.at += 1;
        let c = match self.peek() {
            Some('\\') => {
                self.at += 1;
                self.escape()?
            }
            Some(c) => {
                self.at += c.len_utf8();
                c
            }
            None => return Err(Error::at(start..start + 1, "unclosed character literal")),
        };
        if self.peek() != Some('\'') {
            return Err(Error::at(
                start..self.at,
                "a character literal holds one character (strings use double quotes)",
            ));
        }
        self.at += 1;
        Ok(c)
    }

    fn number(&mut self) -> Result<Kind, Error> {
        let start = self.at;
        let negative = match self.peek() {
            Some('-') => {
                self.at += 1;
                true
            }
            Some('+') => {
                self.at += 1;
                false
            }
            _ => false,
        };
        let rest = &self.text[self.at..];
        if rest.starts_with("inf") && !rest[3..].starts_with(is_ident_char) {
            self.at += 3;
            return Ok(Kind::Float(if negative {
                f64::NEG_INFINITY
            } else {
                f64::INFINITY
            }));
        }
        if rest.starts_with("NaN") && !rest[3..].starts_with(is_ident_char) {
            self.at += 3;
            return Ok(Kind::Float(f64::NAN));
        }
        let radix = match rest.get(..2) {
            Some("0x") => 16,
            Some("0o") => 8,
            Some("0b") => 2,
            _ => 10,
        };
        let bad = |p: &Self, what: &str| Error::at(start..p.at.max(start + 1), what.to_owned());
        if radix != 10 {
            self.at += 2;
            let len = self.text[self.at..]
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .unwrap_or(self.text.len() - self.at);
            let digits: String = self.text[self.at..self.at + len].replace('_', "");
            self.at += len;
            let magnitude = i128::from_str_radix(&digits, radix)
                .map_err(|_| bad(self, "not a valid integer"))?;
            return Ok(Kind::Integer(if negative { -magnitude } else { magnitude }));
        }
        let mut float = false;
        let mut digits = String::new();
        let bytes = self.text.as_bytes();
        let mut i = self.at;
        while i < bytes.len() {
            let b = bytes[i];
            match b {
                b'0'..=b'9' => digits.push(b as char),
                b'_' => {}
                b'.' if !float => {
                    float = true;
                    digits.push('.');
                }
                b'e' | b'E' if !digits.contains(['e', 'E']) && !digits.is_empty() => {
                    float = true;
                    digits.push('e');
                    if matches!(bytes.get(i + 1), Some(b'+' | b'-')) {
                        i += 1;
                        digits.push(bytes[i] as char);
                    }
                }
                _ => break,
            }
            i += 1;
        }
        self.at = i;
        if self.peek().is_some_and(is_ident_char) {
            let end = self.char_end(self.at);
            self.at = end;
            return Err(bad(self, "not a valid number"));
        }
        if digits.is_empty() || digits == "." {
            return Err(bad(self, "not a valid number"));
        }
        if float {
            let x: f64 = digits
                .parse()
                .map_err(|_| bad(self, "not a valid number"))?;
            Ok(Kind::Float(if negative { -x } else { x }))
        } else {
            let magnitude: i128 = digits
                .parse()
                .map_err(|_| bad(self, "integer out of range"))?;
            Ok(Kind::Integer(if negative { -magnitude } else { magnitude }))
        }
    }
}

/// Deserializes one [`Value`].
struct ValueDeserializer<'a> {
    value: &'a Value,
}

impl<'a> ValueDeserializer<'a> {
    fn locate<T>(&self, result: Result<T, Error>) -> Result<T, Error> {
        result.map_err(|e| e.or_at(&self.value.span))
    }

    fn describe(&self) -> &'static str {
        match &self.value.kind {
            Kind::Unit => "`()`",
            Kind::Bool(_) => "a boolean",
            Kind::Integer(_) => "an integer",
            Kind::Float(_) => "a number",
            Kind::Str(_) => "a string",
            Kind::Char(_) => "a character",
            Kind::Ident(_) => "an identifier",
            Kind::List(_) => "a list",
            Kind::Tuple(..) => "a tuple",
            Kind::Struct(..) => "a struct",
            Kind::Map(_) => "a map",
        }
    }
}

const SPANNED_NAME: &str = "$__serde_spanned_private_Spanned";
const SPANNED_START: &str = "$__serde_spanned_private_start";
const SPANNED_END: &str = "$__serde_spanned_private_end";
const SPANNED_VALUE: &str = "$__serde_spanned_private_value";

impl<'de> de::Deserializer<'de> for ValueDeserializer<'de> {
    type Error = Error;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let result = match &self.value.kind {
            Kind::Unit => visitor.visit_unit(),
            Kind::Bool(b) => visitor.visit_bool(*b),
            Kind::Integer(x) => {
                if let Ok(x) = i64::try_from(*x) {
                    visitor.visit_i64(x)
                } else if let Ok(x) = u64::try_from(*x) {
                    visitor.visit_u64(x)
                } else {
                    Err(Error::at(self.value.span.clone(), "integer out of range"))
                }
            }
            Kind::Float(x) => visitor.visit_f64(*x),
            Kind::Str(s) => visitor.visit_borrowed_str(s),
            Kind::Char(c) => visitor.visit_char(*c),
            Kind::Ident(name) if name == "None" => visitor.visit_none(),
            Kind::Ident(name) => Err(Error::at(
                self.value.span.clone(),
                format!("`{name}` is an identifier here, not a value (strings and expressions are written in double quotes: \"{name}\")"),
            )),
            Kind::Tuple(Some(name), items) if name == "Some" && items.len() == 1 => {
                visitor.visit_some(ValueDeserializer { value: &items[0] })
            }
            Kind::List(items) | Kind::Tuple(_, items) => visitor.visit_seq(Seq { items: items.iter() }),
            Kind::Struct(_, entries) | Kind::Map(entries) => visitor.visit_map(Entries {
                entries: entries.iter(),
                value: None,
            }),
        };
        self.locate(result)
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let result = match &self.value.kind {
            Kind::Ident(name) if name == "None" => visitor.visit_none(),
            Kind::Tuple(Some(name), items) if name == "Some" && items.len() == 1 => {
                visitor.visit_some(ValueDeserializer { value: &items[0] })
            }
            // Implicit `Some`: an optional key written with its value.
            _ => visitor.visit_some(ValueDeserializer { value: self.value }),
        };
        self.locate(result)
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        name: &'static str,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Error> {
        if name == SPANNED_NAME {
            return self.locate(visitor.visit_map(SpannedAccess {
                value: self.value,
                field: 0,
            }));
        }
        match &self.value.kind {
            Kind::Unit => self.locate(visitor.visit_map(Entries {
                entries: [].iter(),
                value: None,
            })),
            Kind::Struct(..) | Kind::Map(_) => self.deserialize_any(visitor),
            _ => {
                let expected = if fields.is_empty() {
                    "a struct `(name: value, ...)` or a map `{\"name\": value}`".to_owned()
                } else {
                    "a struct `(key: value, ...)`".to_owned()
                };
                Err(Error::at(
                    self.value.span.clone(),
                    format!("expected {expected}, found {}", self.describe()),
                ))
            }
        }
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Error> {
        let result = match &self.value.kind {
            // A string too, as TOML writes it: `on: "faces"` and `on: faces` alike.
            Kind::Ident(_) | Kind::Str(_) | Kind::Tuple(Some(_), _) | Kind::Struct(Some(_), _) => {
                visitor.visit_enum(Enum { value: self.value })
            }
            _ => Err(Error::at(
                self.value.span.clone(),
                format!("expected a name such as `faces`, found {}", self.describe()),
            )),
        };
        self.locate(result)
    }

    fn deserialize_identifier<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let result = match &self.value.kind {
            Kind::Ident(s) | Kind::Str(s) => visitor.visit_borrowed_str(s),
            _ => return self.deserialize_any(visitor),
        };
        self.locate(result)
    }

    fn deserialize_ignored_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        visitor.visit_unit()
    }

    fn deserialize_unit<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        match &self.value.kind {
            Kind::Unit => self.locate(visitor.visit_unit()),
            Kind::Tuple(_, items) if items.is_empty() => self.locate(visitor.visit_unit()),
            _ => self.deserialize_any(visitor),
        }
    }

    fn deserialize_unit_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, Error> {
        match &self.value.kind {
            Kind::Ident(_) => self.locate(visitor.visit_unit()),
            _ => self.deserialize_unit(visitor),
        }
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, Error> {
        let result = match &self.value.kind {
            Kind::Tuple(Some(_), items) if items.len() == 1 => {
                visitor.visit_newtype_struct(ValueDeserializer { value: &items[0] })
            }
            _ => visitor.visit_newtype_struct(ValueDeserializer { value: self.value }),
        };
        self.locate(result)
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string
        bytes byte_buf seq tuple tuple_struct map
    }
}

struct Seq<'a> {
    items: std::slice::Iter<'a, Value>,
}

impl<'de> de::SeqAccess<'de> for Seq<'de> {
    type Error = Error;

    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, Error> {
        match self.items.next() {
            None => Ok(None),
            Some(value) => seed
                .deserialize(ValueDeserializer { value })
                .map(Some)
                .map_err(|e| e.or_at(&value.span)),
        }
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.items.len())
    }
}

struct Entries<'a> {
    entries: std::slice::Iter<'a, (Value, Value)>,
    value: Option<&'a Value>,
}

impl<'de> de::MapAccess<'de> for Entries<'de> {
    type Error = Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Error> {
        match self.entries.next() {
            None => Ok(None),
            Some((key, value)) => {
                self.value = Some(value);
                seed.deserialize(ValueDeserializer { value: key })
                    .map(Some)
                    .map_err(|e| e.or_at(&key.span))
            }
        }
    }

    fn next_value_seed<T: DeserializeSeed<'de>>(&mut self, seed: T) -> Result<T::Value, Error> {
        let value = self.value.take().expect("next_value after next_key");
        seed.deserialize(ValueDeserializer { value })
            .map_err(|e| e.or_at(&value.span))
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.entries.len())
    }
}

/// `serde_spanned`'s protocol: a struct of start, end and the value.
struct SpannedAccess<'a> {
    value: &'a Value,
    field: usize,
}

impl<'de> de::MapAccess<'de> for SpannedAccess<'de> {
    type Error = Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Error> {
        let key = match self.field {
            0 => SPANNED_START,
            1 => SPANNED_END,
            2 => SPANNED_VALUE,
            _ => return Ok(None),
        };
        seed.deserialize(de::value::BorrowedStrDeserializer::<Error>::new(key))
            .map(Some)
    }

    fn next_value_seed<T: DeserializeSeed<'de>>(&mut self, seed: T) -> Result<T::Value, Error> {
        self.field += 1;
        match self.field {
            1 => seed.deserialize(self.value.span.start.into_deserializer()),
            2 => seed.deserialize(self.value.span.end.into_deserializer()),
            _ => seed.deserialize(ValueDeserializer { value: self.value }),
        }
    }
}

/// An enum variant: `name`, `"name"`, `Name(args)` or `Name(key: value)`.
struct Enum<'a> {
    value: &'a Value,
}

impl<'de> de::EnumAccess<'de> for Enum<'de> {
    type Error = Error;
    type Variant = Variant<'de>;

    fn variant_seed<V: DeserializeSeed<'de>>(
        self,
        seed: V,
    ) -> Result<(V::Value, Variant<'de>), Error> {
        let name = match &self.value.kind {
            Kind::Ident(n) | Kind::Str(n) | Kind::Tuple(Some(n), _) | Kind::Struct(Some(n), _) => n,
            _ => unreachable!("deserialize_enum checks the kind"),
        };
        let variant = seed
            .deserialize(de::value::BorrowedStrDeserializer::<Error>::new(name))
            .map_err(|e| e.or_at(&self.value.span))?;
        Ok((variant, Variant { value: self.value }))
    }
}

struct Variant<'a> {
    value: &'a Value,
}

impl<'de> de::VariantAccess<'de> for Variant<'de> {
    type Error = Error;

    fn unit_variant(self) -> Result<(), Error> {
        match &self.value.kind {
            Kind::Ident(_) | Kind::Str(_) => Ok(()),
            _ => Err(Error::at(
                self.value.span.clone(),
                "this variant takes no value",
            )),
        }
    }

    fn newtype_variant_seed<T: DeserializeSeed<'de>>(self, seed: T) -> Result<T::Value, Error> {
        match &self.value.kind {
            Kind::Tuple(_, items) if items.len() == 1 => {
                seed.deserialize(ValueDeserializer { value: &items[0] })
            }
            _ => Err(Error::at(
                self.value.span.clone(),
                "this variant takes one value: `Name(value)`",
            )),
        }
    }

    fn tuple_variant<V: Visitor<'de>>(self, _len: usize, visitor: V) -> Result<V::Value, Error> {
        match &self.value.kind {
            Kind::Tuple(_, items) => visitor.visit_seq(Seq {
                items: items.iter(),
            }),
            _ => Err(Error::at(
                self.value.span.clone(),
                "this variant takes values: `Name(a, b)`",
            )),
        }
    }

    fn struct_variant<V: Visitor<'de>>(
        self,
        _fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Error> {
        match &self.value.kind {
            Kind::Struct(_, entries) => visitor.visit_map(Entries {
                entries: entries.iter(),
                value: None,
            }),
            _ => Err(Error::at(
                self.value.span.clone(),
                "this variant takes fields: `Name(key: value)`",
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kind(text: &str) -> Kind {
        parse(text).unwrap().kind
    }

    #[test]
    fn scalars() {
        assert_eq!(kind("42"), Kind::Integer(42));
        assert_eq!(kind("-0x1F"), Kind::Integer(-31));
        assert_eq!(kind("0b101"), Kind::Integer(5));
        assert_eq!(kind("1_000"), Kind::Integer(1000));
        assert_eq!(kind("1.5e-3"), Kind::Float(1.5e-3));
        assert_eq!(kind("+.5"), Kind::Float(0.5));
        assert_eq!(kind("-inf"), Kind::Float(f64::NEG_INFINITY));
        assert!(matches!(kind("NaN"), Kind::Float(x) if x.is_nan()));
        assert_eq!(kind("true"), Kind::Bool(true));
        assert_eq!(kind(r#""a\"b\n\u{e9}""#), Kind::Str("a\"b\né".into()));
        assert_eq!(
            kind(r##"r#"a "quoted" b"#"##),
            Kind::Str("a \"quoted\" b".into())
        );
        assert_eq!(kind("'x'"), Kind::Char('x'));
        assert_eq!(kind("faces"), Kind::Ident("faces".into()));
        assert_eq!(kind("()"), Kind::Unit);
    }

    #[test]
    fn spans_cover_values_and_keys() {
        let text = "(a: [1, \"x\"], b: Some(2), c: {\"k\": ()})";
        let v = parse(text).unwrap();
        let Kind::Struct(None, fields) = &v.kind else {
            panic!("{v:?}")
        };
        assert_eq!(v.span, 0..text.len());
        let names: Vec<&str> = fields.iter().map(|(k, _)| &text[k.span.clone()]).collect();
        assert_eq!(names, ["a", "b", "c"]);
        assert_eq!(&text[fields[0].1.span.clone()], "[1, \"x\"]");
        let Kind::List(items) = &fields[0].1.kind else {
            panic!()
        };
        assert_eq!(&text[items[1].span.clone()], "\"x\"");
        assert_eq!(&text[fields[1].1.span.clone()], "Some(2)");
    }

    #[test]
    fn comments_attributes_and_trailing_commas() {
        let text = "#![enable(implicit_some)]\n// a\n/* b /* nested */ */ (x: [1, 2,], y: (),)";
        assert!(matches!(kind(text), Kind::Struct(None, f) if f.len() == 2));
    }

    #[test]
    fn syntax_errors_are_located() {
        let cases = [
            ("(a: 1", 5..5, "unexpected end of file"),
            ("(a: 1 b: 2)", 6..7, "expected `,` or `)`"),
            ("[1, @]", 4..5, "expected a value"),
            ("\"abc", 0..1, "unclosed string"),
            ("1.5x", 0..4, "not a valid number"),
            ("(a: 1) 2", 7..8, "unexpected text"),
        ];
        for (text, span, message) in cases {
            let e = parse(text).unwrap_err();
            assert_eq!(e.span, Some(span), "{text}: {e}");
            assert!(e.message.contains(message), "{text}: {e}");
        }
    }

    #[test]
    fn nesting_is_bounded() {
        let deep = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000));
        let e = parse(&deep).unwrap_err();
        assert!(e.message.contains("nested more than"), "{e}");
        assert_eq!(e.span, Some(MAX_DEPTH..MAX_DEPTH + 1));
        let ok = format!("{}{}", "[".repeat(MAX_DEPTH), "]".repeat(MAX_DEPTH));
        assert!(parse(&ok).is_ok());
    }

    #[derive(serde::Deserialize, Debug, PartialEq)]
    #[serde(deny_unknown_fields)]
    struct Sample {
        name: serde_spanned::Spanned<String>,
        on: Option<Side>,
        list: Vec<f64>,
        pair: (i64, bool),
    }

    #[derive(serde::Deserialize, Debug, PartialEq)]
    #[serde(rename_all = "snake_case")]
    enum Side {
        Left,
        Right,
    }

    #[test]
    fn deserializes_with_spans() {
        let text = "(name: \"n\", on: right, list: [1, 2.5], pair: (3, true))";
        let v = parse(text).unwrap();
        let s: Sample = from_value(&v).unwrap();
        assert_eq!(s.name.span(), 7..10);
        assert_eq!(s.on, Some(Side::Right));
        assert_eq!(s.list, [1.0, 2.5]);
        assert_eq!(s.pair, (3, true));
        let quoted: Sample =
            from_value(&parse(&text.replace("right", "\"left\"")).unwrap()).unwrap();
        assert_eq!(quoted.on, Some(Side::Left));
    }

    #[test]
    fn schema_errors_point_at_the_value_or_key() {
        let text = "(name: \"n\", list: [1, \"x\"], pair: (3, true))";
        let e = from_value::<Sample>(&parse(text).unwrap()).unwrap_err();
        assert_eq!(&text[e.span.clone().unwrap()], "\"x\"");
        let text = "(name: \"n\", list: [], pair: (3, true), extra: 1)";
        let e = from_value::<Sample>(&parse(text).unwrap()).unwrap_err();
        assert_eq!(&text[e.span.clone().unwrap()], "extra");
        assert!(e.message.contains("unknown field"), "{e}");
        let text = "(name: \"n\", on: up, list: [], pair: (3, true))";
        let e = from_value::<Sample>(&parse(text).unwrap()).unwrap_err();
        assert_eq!(&text[e.span.clone().unwrap()], "up");
        let text = "(name: \"n\", list: [])";
        let e = from_value::<Sample>(&parse(text).unwrap()).unwrap_err();
        assert_eq!(e.span, Some(0..text.len()));
        assert!(e.message.contains("missing field `pair`"), "{e}");
    }
}
