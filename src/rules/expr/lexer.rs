//! Tokens of the expression language.

use super::*;

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum TokenKind {
    Number(f64),
    Name,
    LParen,
    RParen,
    Comma,
    Bang,
    Infix(Infix),
    Eof,
}

#[derive(Debug, Clone)]
pub(super) struct Token {
    pub(super) kind: TokenKind,
    pub(super) span: Span,
}

pub(super) fn is_name_start(byte: u8) -> bool {
    byte.is_ascii_alphabetic() || byte == b'_'
}

pub(super) fn is_name_continue(byte: u8) -> bool {
    byte.is_ascii_alphanumeric() || byte == b'_'
}

pub(super) struct Lexer<'s> {
    pub(super) source: &'s str,
    pub(super) pos: usize,
}

impl<'s> Lexer<'s> {
    pub(super) fn byte_at(&self, ahead: usize) -> Option<u8> {
        self.source.as_bytes().get(self.pos + ahead).copied()
    }

    pub(super) fn next_token(&mut self) -> Result<Token, ExprError> {
        let rest = &self.source[self.pos..];
        let trimmed = rest.trim_start();
        self.pos += rest.len() - trimmed.len();
        let start = self.pos;
        let Some(c) = trimmed.chars().next() else {
            return Ok(Token {
                kind: TokenKind::Eof,
                span: start..start,
            });
        };
        let next_is = |byte: u8| self.byte_at(1) == Some(byte);
        let (kind, len) = match c {
            '0'..='9' => return self.number(),
            '.' if self.byte_at(1).is_some_and(|b| b.is_ascii_digit()) => return self.number(),
            'a'..='z' | 'A'..='Z' | '_' => return self.name(),
            '(' => (TokenKind::LParen, 1),
            ')' => (TokenKind::RParen, 1),
            ',' => (TokenKind::Comma, 1),
            '+' => (TokenKind::Infix(Infix::Add), 1),
            '-' => (TokenKind::Infix(Infix::Sub), 1),
            '*' => (TokenKind::Infix(Infix::Mul), 1),
            '/' => (TokenKind::Infix(Infix::Div), 1),
            '%' => (TokenKind::Infix(Infix::Rem), 1),
            '^' => (TokenKind::Infix(Infix::Pow), 1),
            '!' if next_is(b'=') => (TokenKind::Infix(Infix::Ne), 2),
            '!' => (TokenKind::Bang, 1),
            '<' if next_is(b'=') => (TokenKind::Infix(Infix::Le), 2),
            '<' => (TokenKind::Infix(Infix::Lt), 1),
            '>' if next_is(b'=') => (TokenKind::Infix(Infix::Ge), 2),
            '>' => (TokenKind::Infix(Infix::Gt), 1),
            '=' if next_is(b'=') => (TokenKind::Infix(Infix::Eq), 2),
            '&' if next_is(b'&') => (TokenKind::Infix(Infix::And), 2),
            '|' if next_is(b'|') => (TokenKind::Infix(Infix::Or), 2),
            '=' => {
                return Err(Self::lone(
                    start,
                    "`=` is not an operator; use `==` to compare",
                ))
            }
            '&' => return Err(Self::lone(start, "`&` is not an operator; use `&&`")),
            '|' => return Err(Self::lone(start, "`|` is not an operator; use `||`")),
            other => {
                return Err(ExprError::new(
                    format!("unexpected character `{}`", other.escape_debug()),
                    start..start + other.len_utf8(),
                ))
            }
        };
        self.pos += len;
        Ok(Token {
            kind,
            span: start..self.pos,
        })
    }

    pub(super) fn lone(start: usize, message: &str) -> ExprError {
        ExprError::new(message, start..start + 1)
    }

    pub(super) fn skip_digits(&mut self) {
        while self.byte_at(0).is_some_and(|b| b.is_ascii_digit()) {
            self.pos += 1;
        }
    }

    pub(super) fn number(&mut self) -> Result<Token, ExprError> {
        let start = self.pos;
        self.skip_digits();
        if self.byte_at(0) == Some(b'.') {
            self.pos += 1;
            self.skip_digits();
        }
        let mut well_formed = true;
        if matches!(self.byte_at(0), Some(b'e' | b'E')) {
            self.pos += 1;
            if matches!(self.byte_at(0), Some(b'+' | b'-')) {
                self.pos += 1;
            }
            if self.byte_at(0).is_some_and(|b| b.is_ascii_digit()) {
                self.skip_digits();
            } else {
                well_formed = false;
            }
        }
        // Letters, digits or dots glued on (`3x`, `1.2.3`) belong to the same bad token,
        // which gives a clearer message than a missing operator would.
        while self
            .byte_at(0)
            .is_some_and(|b| is_name_continue(b) || b == b'.')
        {
            self.pos += 1;
            well_formed = false;
        }
        let span = start..self.pos;
        let text = &self.source[span.clone()];
        match text.parse::<f64>() {
            Ok(value) if well_formed && value.is_finite() => Ok(Token {
                kind: TokenKind::Number(value),
                span,
            }),
            Ok(_) if well_formed => Err(ExprError::new(
                format!("number `{text}` is too large"),
                span,
            )),
            _ => Err(ExprError::new(format!("invalid number `{text}`"), span)),
        }
    }

    pub(super) fn name(&mut self) -> Result<Token, ExprError> {
        let start = self.pos;
        loop {
            while self.byte_at(0).is_some_and(is_name_continue) {
                self.pos += 1;
            }
            if self.byte_at(0) != Some(b'.') {
                break;
            }
            if !self.byte_at(1).is_some_and(is_name_start) {
                return Err(ExprError::new(
                    "expected a field name after `.`",
                    self.pos..self.pos + 1,
                ));
            }
            self.pos += 1;
        }
        Ok(Token {
            kind: TokenKind::Name,
            span: start..self.pos,
        })
    }
}
