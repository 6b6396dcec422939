//! The Pratt parser: tokens to compiled code, with constants folded and
//! names resolved to slots as it goes.

use super::*;

/// A subexpression compiled while parsing.
pub(super) enum Code {
    /// Folded to a value because it reads no slot.
    Const(f64),
    /// Ops that leave one value on the stack, needing `stack` entries on the way.
    /// `boolean` records that the value is already exactly 0 or 1.
    Ops {
        ops: Vec<Op>,
        stack: usize,
        boolean: bool,
    },
}

pub(super) struct Operand {
    pub(super) code: Code,
    pub(super) span: Span,
}

pub(super) fn too_deep(span: Span) -> ExprError {
    ExprError::new("expression too deeply nested", span)
}

pub(super) fn unclosed(open: Span) -> ExprError {
    ExprError::new("unclosed `(`", open)
}

pub(super) struct Parser<'s, 'r> {
    pub(super) source: &'s str,
    pub(super) lexer: Lexer<'s>,
    pub(super) current: Token,
    pub(super) names: &'r dyn NameResolver,
    /// Pool of every constant materialised while parsing; `Expr::assemble` keeps the live ones.
    pub(super) constants: Vec<f64>,
    pub(super) nesting: usize,
}

impl<'s, 'r> Parser<'s, 'r> {
    pub(super) fn new(source: &'s str, names: &'r dyn NameResolver) -> Result<Self, ExprError> {
        let mut lexer = Lexer { source, pos: 0 };
        let current = lexer.next_token()?;
        Ok(Parser {
            source,
            lexer,
            current,
            names,
            constants: Vec::new(),
            nesting: 0,
        })
    }

    /// Moves to the next token and returns the one that was current.
    pub(super) fn bump(&mut self) -> Result<Token, ExprError> {
        let next = self.lexer.next_token()?;
        Ok(std::mem::replace(&mut self.current, next))
    }

    pub(super) fn current_text(&self) -> &'s str {
        &self.source[self.current.span.clone()]
    }

    /// Parses a subexpression one level deeper; `opener` is the token that opened the
    /// level and is where a too-deep error points.
    pub(super) fn nested(&mut self, min_power: u8, opener: &Span) -> Result<Operand, ExprError> {
        if self.nesting >= MAX_NESTING {
            return Err(too_deep(opener.clone()));
        }
        self.nesting += 1;
        let result = self.expression(min_power);
        self.nesting -= 1;
        result
    }

    /// Pratt loop: an operand, then infix operators binding at least `min_power`.
    pub(super) fn expression(&mut self, min_power: u8) -> Result<Operand, ExprError> {
        let mut lhs = self.operand()?;
        let mut previous: Option<Infix> = None;
        while let TokenKind::Infix(op) = self.current.kind {
            let (left_power, right_power) = op.binding_power();
            if left_power < min_power {
                break;
            }
            let op_span = self.current.span.clone();
            // `lhs` came from an operator of the same comparison level in this very loop,
            // so without this check `a < b < c` would silently mean `(a < b) < c`.
            if op.is_comparison()
                && previous.is_some_and(|p| p.binding_power() == op.binding_power())
            {
                return Err(ExprError::new(
                    "comparison operators cannot be chained",
                    op_span,
                ));
            }
            self.bump()?;
            let rhs = self.nested(right_power, &op_span)?;
            lhs = self.infix(op, lhs, rhs)?;
            previous = Some(op);
        }
        Ok(lhs)
    }

    pub(super) fn operand(&mut self) -> Result<Operand, ExprError> {
        let span = self.current.span.clone();
        let prefix = match self.current.kind {
            TokenKind::Number(value) => {
                self.bump()?;
                return Ok(Operand {
                    code: Code::Const(value),
                    span,
                });
            }
            TokenKind::Name => {
                self.bump()?;
                return self.name_or_call(span);
            }
            TokenKind::LParen => {
                self.bump()?;
                let inner = self.nested(0, &span)?;
                let close = self.expect_close(&span)?;
                return Ok(Operand {
                    code: inner.code,
                    span: span.start..close.end,
                });
            }
            TokenKind::Infix(Infix::Sub) => Some(Unary::Neg),
            TokenKind::Bang => Some(Unary::Not),
            TokenKind::Infix(Infix::Add) => None,
            _ => return Err(ExprError::new("expected an expression", span)),
        };
        self.bump()?;
        let operand = self.nested(PREFIX_BINDING_POWER, &span)?;
        let span = span.start..operand.span.end;
        Ok(match prefix {
            Some(function) => self.unary(function, operand, span),
            None => Operand {
                code: operand.code,
                span,
            },
        })
    }

    pub(super) fn expect_close(&mut self, open: &Span) -> Result<Span, ExprError> {
        match self.current.kind {
            TokenKind::RParen => Ok(self.bump()?.span),
            TokenKind::Eof => Err(unclosed(open.clone())),
            _ => Err(ExprError::new(
                format!("expected `)`, found `{}`", self.current_text()),
                self.current.span.clone(),
            )),
        }
    }

    /// Checks that the whole source was consumed.
    pub(super) fn finish(&self) -> Result<(), ExprError> {
        let message = match self.current.kind {
            TokenKind::Eof => return Ok(()),
            TokenKind::RParen | TokenKind::Comma => {
                format!("unexpected `{}`", self.current_text())
            }
            _ => format!("expected an operator, found `{}`", self.current_text()),
        };
        Err(ExprError::new(message, self.current.span.clone()))
    }

    pub(super) fn name_or_call(&mut self, span: Span) -> Result<Operand, ExprError> {
        let name = &self.source[span.clone()];
        if self.current.kind == TokenKind::LParen {
            return self.call(name, span);
        }
        if let Some(value) = builtin_constant(name) {
            return Ok(Operand {
                code: Code::Const(value),
                span,
            });
        }
        match self.names.resolve(name) {
            Some(slot) => Ok(Operand {
                code: Code::Ops {
                    ops: vec![Op::Slot(slot)],
                    stack: 1,
                    boolean: false,
                },
                span,
            }),
            None => Err(ExprError::new(self.unknown_name_message(name), span)),
        }
    }

    pub(super) fn unknown_name_message(&self, name: &str) -> String {
        let mut message = format!("unknown name `{name}`");
        if function(name).is_some() {
            message.push_str(&format!(
                "; `{name}` is a function, call it like `{name}(...)`"
            ));
            return message;
        }
        let mut candidates = self.names.known_names();
        candidates.extend(BUILTIN_CONSTANT_NAMES);
        let close = close_matches(name, &candidates);
        match close.as_slice() {
            [] => {}
            [only] => message.push_str(&format!("; did you mean `{only}`?")),
            several => {
                let listed: Vec<String> = several.iter().map(|c| format!("`{c}`")).collect();
                message.push_str(&format!("; did you mean one of {}?", listed.join(", ")));
            }
        }
        message
    }

    pub(super) fn call(&mut self, name: &str, name_span: Span) -> Result<Operand, ExprError> {
        let Some(callee) = function(name) else {
            return Err(ExprError::new(
                format!("`{name}` is not a function"),
                name_span,
            ));
        };
        let open = self.bump()?.span;
        let mut args = Vec::new();
        if self.current.kind != TokenKind::RParen {
            loop {
                args.push(self.nested(0, &open)?);
                match self.current.kind {
                    TokenKind::Comma => {
                        self.bump()?;
                    }
                    TokenKind::RParen => break,
                    TokenKind::Eof => return Err(unclosed(open)),
                    _ => {
                        return Err(ExprError::new(
                            format!("expected `,` or `)`, found `{}`", self.current_text()),
                            self.current.span.clone(),
                        ))
                    }
                }
            }
        }
        let close = self.bump()?.span;
        let span = name_span.start..close.end;
        let arity_error = |expected: &str, found: usize, span: Span| {
            ExprError::new(format!("`{name}` takes {expected}, found {found}"), span)
        };
        match callee {
            Callee::Unary(function) => match <[Operand; 1]>::try_from(args) {
                Ok([x]) => Ok(self.unary(function, x, span)),
                Err(args) => Err(arity_error("1 argument", args.len(), span)),
            },
            Callee::Binary(function) => match <[Operand; 2]>::try_from(args) {
                Ok([a, b]) => self.binary(function, a, b, span),
                Err(args) => Err(arity_error("2 arguments", args.len(), span)),
            },
            Callee::Ternary(function) => match <[Operand; 3]>::try_from(args) {
                Ok([a, b, c]) => self.ternary(function, a, b, c, span),
                Err(args) => Err(arity_error("3 arguments", args.len(), span)),
            },
            Callee::Variadic(function) => {
                let mut args = args.into_iter();
                let Some(mut folded) = args.next() else {
                    return Err(arity_error("at least 1 argument", 0, span));
                };
                for arg in args {
                    folded = self.binary(function, folded, arg, span.clone())?;
                }
                Ok(Operand {
                    code: folded.code,
                    span,
                })
            }
        }
    }

    pub(super) fn infix(
        &mut self,
        op: Infix,
        lhs: Operand,
        rhs: Operand,
    ) -> Result<Operand, ExprError> {
        let span = lhs.span.start..rhs.span.end;
        let function = match op {
            Infix::Or => return Ok(self.logic(false, lhs, rhs, span)),
            Infix::And => return Ok(self.logic(true, lhs, rhs, span)),
            Infix::Eq => Binary::Eq,
            Infix::Ne => Binary::Ne,
            Infix::Lt => Binary::Lt,
            Infix::Le => Binary::Le,
            Infix::Gt => Binary::Gt,
            Infix::Ge => Binary::Ge,
            Infix::Add => Binary::Add,
            Infix::Sub => Binary::Sub,
            Infix::Mul => Binary::Mul,
            Infix::Div => Binary::Div,
            Infix::Rem => Binary::Rem,
            Infix::Pow => Binary::Pow,
        };
        self.binary(function, lhs, rhs, span)
    }

    pub(super) fn push_constant(&mut self, value: f64) -> u32 {
        self.constants.push(value);
        // Fits: there are fewer constants than source bytes, and sources are at most 1 MiB.
        (self.constants.len() - 1) as u32
    }

    /// Ops and stack need of `code`, pushing a folded value as a pool constant.
    pub(super) fn materialize(&mut self, code: Code) -> (Vec<Op>, usize) {
        match code {
            Code::Const(value) => (vec![Op::Const(self.push_constant(value))], 1),
            Code::Ops { ops, stack, .. } => (ops, stack),
        }
    }

    pub(super) fn unary(&mut self, function: Unary, operand: Operand, span: Span) -> Operand {
        let code = match operand.code {
            Code::Const(value) => Code::Const(function.apply(value)),
            Code::Ops { mut ops, stack, .. } => {
                ops.push(Op::unary(function));
                Code::Ops {
                    ops,
                    stack,
                    boolean: function.yields_boolean(),
                }
            }
        };
        Operand { code, span }
    }

    pub(super) fn binary(
        &mut self,
        function: Binary,
        lhs: Operand,
        rhs: Operand,
        span: Span,
    ) -> Result<Operand, ExprError> {
        let code = match (lhs.code, rhs.code) {
            (Code::Const(a), Code::Const(b)) => Code::Const(function.apply(a, b)),
            (lhs, rhs) => {
                let (mut ops, lhs_stack) = self.materialize(lhs);
                let stack = match rhs {
                    Code::Const(b) => {
                        let index = self.push_constant(b);
                        ops.push(Op::binary_const(function, index));
                        lhs_stack
                    }
                    Code::Ops {
                        ops: rhs_ops,
                        stack: rhs_stack,
                        ..
                    } => {
                        if let &[Op::Slot(slot)] = rhs_ops.as_slice() {
                            ops.push(Op::binary_slot(function, slot));
                            lhs_stack
                        } else {
                            ops.extend(rhs_ops);
                            ops.push(Op::binary(function));
                            lhs_stack.max(rhs_stack + 1)
                        }
                    }
                };
                if stack > MAX_STACK {
                    return Err(too_deep(span));
                }
                Code::Ops {
                    ops,
                    stack,
                    boolean: function.yields_boolean(),
                }
            }
        };
        Ok(Operand { code, span })
    }

    pub(super) fn ternary(
        &mut self,
        function: Ternary,
        a: Operand,
        b: Operand,
        c: Operand,
        span: Span,
    ) -> Result<Operand, ExprError> {
        if let (Code::Const(a), Code::Const(b), Code::Const(c)) = (&a.code, &b.code, &c.code) {
            return Ok(Operand {
                code: Code::Const(function.apply(*a, *b, *c)),
                span,
            });
        }
        let (mut ops, a_stack) = self.materialize(a.code);
        let (b_ops, b_stack) = self.materialize(b.code);
        let (c_ops, c_stack) = self.materialize(c.code);
        ops.extend(b_ops);
        ops.extend(c_ops);
        ops.push(Op::ternary(function));
        let stack = a_stack.max(b_stack + 1).max(c_stack + 2);
        if stack > MAX_STACK {
            return Err(too_deep(span));
        }
        Ok(Operand {
            code: Code::Ops {
                ops,
                stack,
                boolean: false,
            },
            span,
        })
    }

    /// `&&` (`is_and`) or `||`. A constant operand either decides the result outright or
    /// reduces it to the truthiness of the other operand; neither has side effects, so
    /// dropping one is safe.
    pub(super) fn logic(
        &mut self,
        is_and: bool,
        lhs: Operand,
        rhs: Operand,
        span: Span,
    ) -> Operand {
        // The operand value that decides the result without the other: false for `&&`.
        let decides = |value: f64| truthy(value) != is_and;
        let code = match (lhs.code, rhs.code) {
            (Code::Const(a), other) | (other, Code::Const(a)) => {
                if decides(a) {
                    Code::Const(from_bool(!is_and))
                } else {
                    to_bool(other)
                }
            }
            (
                Code::Ops {
                    ops: mut lhs_ops,
                    stack: lhs_stack,
                    ..
                },
                Code::Ops {
                    ops: rhs_ops,
                    stack: rhs_stack,
                    boolean,
                },
            ) => {
                // Fits: op counts are bounded by the source length.
                let skip = (rhs_ops.len() + usize::from(!boolean)) as u32;
                lhs_ops.push(if is_and {
                    Op::AndJump(skip)
                } else {
                    Op::OrJump(skip)
                });
                lhs_ops.extend(rhs_ops);
                if !boolean {
                    lhs_ops.push(Op::Truthy);
                }
                // The jump pops the left value before the right one is pushed.
                Code::Ops {
                    ops: lhs_ops,
                    stack: lhs_stack.max(rhs_stack),
                    boolean: true,
                }
            }
        };
        Operand { code, span }
    }
}

/// Truthiness of `code` as exactly 0 or 1.
pub(super) fn to_bool(code: Code) -> Code {
    match code {
        Code::Const(value) => Code::Const(from_bool(truthy(value))),
        Code::Ops {
            mut ops,
            stack,
            boolean,
        } => {
            if !boolean {
                ops.push(Op::Truthy);
            }
            Code::Ops {
                ops,
                stack,
                boolean: true,
            }
        }
    }
}

/// Up to three candidates close to `name`, closest first
/// ([`crate::geom::names::suggestions`]).
pub(super) fn close_matches<'a>(name: &str, candidates: &[&'a str]) -> Vec<&'a str> {
    let mut out: Vec<&str> = Vec::with_capacity(3);
    for i in crate::geom::names::suggestions(name, candidates) {
        if out.len() == 3 {
            break;
        }
        if !out.contains(&candidates[i]) {
            out.push(candidates[i]);
        }
    }
    out
}
