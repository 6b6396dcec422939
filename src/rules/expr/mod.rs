//! A small expression language for rule files, compiled once and evaluated fast.
//!
//! Rule files carry expressions such as `normal.z > 0.5 && abs(center.x) < width / 3`,
//! `0.6 * pre.length` or `lerp(a, b, random)`. [`Expr::compile`] lexes and parses such a
//! string with a Pratt parser, binds every name to a numeric slot through a
//! [`NameResolver`], folds every subexpression that reads no slot, and emits a flat op
//! vector for a small stack machine. [`Expr::eval`] runs those ops against a slice of slot
//! values without allocating.
//!
//! # Values
//!
//! Every value is an `f64`. Booleans are `1.0` (true) and `0.0` (false); any value other
//! than `0.0` or `-0.0` counts as true, NaN included. Comparisons, `!`, `&&` and `||`
//! always yield exactly `1.0` or `0.0`.
//!
//! # Grammar
//!
//! - Numbers: `1`, `1.5`, `.5`, `1.`, `1e-3`, `2.5E+2`. Letters or dots glued to a number
//!   (`1e`, `3x`, `1.2.3`) make it invalid; literals that overflow `f64` are rejected.
//! - Names: `[A-Za-z_][A-Za-z0-9_]*`, optionally dotted: `pos.x`, `pre.length`. A dotted
//!   name is one name; the resolver receives the full string `"pos.x"`.
//! - Built-in constants: `pi`, `tau`, `e`, `true` (1) and `false` (0). They are looked up
//!   before the resolver, so they are reserved: a resolver cannot shadow them.
//! - Calls: `name(arg, ...)` to one of the built-in functions below. Only functions can
//!   be called, and a plain name is never a function, so a resolver may bind names such
//!   as `step` or `sign` as values.
//!
//! Operators, from lowest to highest precedence:
//!
//! | level | operators | associativity |
//! |---|---|---|
//! | 1 | <code>&#124;&#124;</code> | left; short-circuits, yields 0 or 1 |
//! | 2 | `&&` | left; short-circuits, yields 0 or 1 |
//! | 3 | `==` `!=` | none: `a == b == c` is an error |
//! | 4 | `<` `<=` `>` `>=` | none: `a < b < c` is an error |
//! | 5 | `+` `-` | left |
//! | 6 | `*` `/` `%` | left |
//! | 7 | unary `-` `+` `!` | prefix |
//! | 8 | `^` (power) | right: `2^3^2 == 512`, and `-2^2 == -4` |
//!
//! Parentheses group as usual; a parenthesised comparison may be compared again
//! (`(a < b) == c`). `%` is the floored modulo, `x - y * floor(x / y)`, whose result has
//! the sign of the divisor as in Python (`-7 % 3 == 2`); it is computed exactly from
//! `fmod`. `==` and `!=` compare exactly.
//!
//! # Functions
//!
//! | function | value |
//! |---|---|
//! | `sin(x)` `cos(x)` `tan(x)` | trigonometry in radians |
//! | `asin(x)` `acos(x)` `atan(x)` `atan2(y, x)` | inverse trigonometry in radians |
//! | `sqrt(x)` `abs(x)` `exp(x)` `ln(x)` `log10(x)` `pow(a, b)` | as named; `pow(a, b)` is `a ^ b` |
//! | `floor(x)` `ceil(x)` `round(x)` | `round` takes halves away from zero |
//! | `sign(x)` | `-1`, `0` or `1`; zero and NaN pass through unchanged |
//! | `min(a, ...)` `max(a, ...)` | one or more arguments; NaN arguments are ignored |
//! | `clamp(x, lo, hi)` | `min(max(x, lo), hi)` |
//! | `lerp(a, b, t)` | `a + (b - a) * t` |
//! | `radians(deg)` `degrees(rad)` | angle conversion |
//! | `step(edge, x)` | `1` when `x >= edge`, else `0` |
//! | `smoothstep(e0, e1, x)` | Hermite `t * t * (3 - 2 * t)` with `t` clamped to 0..1; `step(e0, x)` when `e0 == e1` |
//!
//! Arity is checked at compile time. Every transcendental function, power and rounding
//! function goes through the `libm` crate, never `std`, so results are bit-identical on
//! every platform; constant folding calls the very same code as evaluation.
//!
//! # Limits
//!
//! Compilation never panics: any string gives `Ok` or an [`ExprError`] whose
//! [`span`](ExprError::span) is the byte range of the offending text. Nesting deeper than
//! 64 levels (each parenthesis, function argument list, unary operator and right-hand
//! operand opens one), expressions that would need more than 64 stack entries, and
//! sources longer than 1 MiB are rejected, so hostile input cannot overflow the stack.
//!
//! # Example
//!
//! ```
//! use graftal::rules::expr::{Expr, ExprError, SlotNames};
//!
//! // Slot i holds the value of the i-th name.
//! let names = SlotNames(&["normal.z", "center.x", "width"]);
//! let expr = Expr::compile("normal.z > 0.5 && abs(center.x) < width / 3", &names)?;
//! assert_eq!(expr.used_slots(), &[0, 1, 2]);
//! assert_eq!(expr.eval(&[0.9, -1.0, 6.0]), 1.0);
//! assert_eq!(expr.eval(&[0.9, -2.5, 6.0]), 0.0);
//!
//! // Any `Fn(&str) -> Option<u32>` is a resolver too.
//! let resolver = |name: &str| (name == "pre.length").then_some(0);
//! let expr = Expr::compile("0.5 * pre.length", &resolver)?;
//! assert_eq!(expr.eval(&[10.0]), 5.0);
//!
//! // Expressions that read no slot are folded at compile time.
//! let expr = Expr::compile("2 * pi", &resolver)?;
//! assert_eq!(expr.constant(), Some(std::f64::consts::TAU));
//!
//! let err = Expr::compile("clamp(pre.length, 1)", &resolver).unwrap_err();
//! assert_eq!(err.message, "`clamp` takes 3 arguments, found 2");
//! assert_eq!(err.span, 0..20);
//! # Ok::<(), ExprError>(())
//! ```

use std::collections::HashMap;
use std::f64::consts::{E, PI, TAU};

mod functions;
mod lexer;
mod parser;
#[cfg(test)]
mod tests;
mod tree;

use functions::*;
pub(crate) use functions::{Binary, Ternary, Unary, BUILTIN_CONSTANT_NAMES};
use lexer::*;
use parser::*;
pub(crate) use tree::Tree;

/// Byte range within the expression source string.
pub type Span = std::ops::Range<usize>;

/// Deepest parser recursion accepted; bounds the native stack used by compilation.
const MAX_NESTING: usize = 64;
/// Most values the evaluation stack may hold at once.
const MAX_STACK: usize = 64;
/// Stack size used for the common shallow expressions, so `eval` zeroes less memory.
const SMALL_STACK: usize = 8;
/// Longest accepted source; also keeps every op index within `u32`.
const MAX_SOURCE_LEN: usize = 1 << 20;

/// A compile error with the byte range of the offending source text.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct ExprError {
    /// One-line description, without a trailing period.
    pub message: String,
    /// Byte range of the offending text in the expression source; empty at the end of
    /// the source when more input was expected.
    pub span: Span,
}

impl ExprError {
    fn new(message: impl Into<String>, span: Span) -> Self {
        ExprError {
            message: message.into(),
            span,
        }
    }

    /// Moves the span `offset` bytes to the right, for an expression embedded at
    /// `offset` in a larger file.
    #[must_use]
    pub fn offset_by(self, offset: usize) -> Self {
        ExprError {
            message: self.message,
            span: self.span.start + offset..self.span.end + offset,
        }
    }
}

/// How names are bound at compile time: returns a slot index for a name, or None if unknown.
pub trait NameResolver {
    fn resolve(&self, name: &str) -> Option<u32>;

    /// Names this resolver knows, offered as "did you mean" hints when a name is unknown.
    /// The default offers none.
    fn known_names(&self) -> Vec<&str> {
        Vec::new()
    }
}

impl<F: Fn(&str) -> Option<u32>> NameResolver for F {
    fn resolve(&self, name: &str) -> Option<u32> {
        self(name)
    }
}

/// Where an expression's slot values come from when it is evaluated with
/// [`Expr::eval_with`].
pub trait SlotSource {
    fn slot(&mut self, slot: u32) -> f64;
}

/// Slot values given up front: `slots[i]` is slot i.
struct SliceSlots<'a>(&'a [f64]);

impl SlotSource for SliceSlots<'_> {
    #[inline]
    fn slot(&mut self, slot: u32) -> f64 {
        self.0[slot as usize]
    }
}

/// A resolver over a fixed list of names: the name at index `i` is slot `i`.
#[derive(Debug, Clone, Copy)]
pub struct SlotNames<'a>(pub &'a [&'a str]);

impl NameResolver for SlotNames<'_> {
    fn resolve(&self, name: &str) -> Option<u32> {
        let index = self.0.iter().position(|known| *known == name)?;
        u32::try_from(index).ok()
    }

    fn known_names(&self) -> Vec<&str> {
        self.0.to_vec()
    }
}

/// A compiled expression.
#[derive(Debug, Clone, PartialEq)]
pub struct Expr {
    ops: Vec<Op>,
    /// Constant pool indexed by `Op::Const` and the `…Const` binary instructions.
    constants: Vec<f64>,
    /// Most values the stack holds at once while running `ops`.
    max_stack: usize,
    used_slots: Vec<u32>,
    /// The folded value when the expression reads no slot; `ops` is then empty.
    constant: Option<f64>,
    source: String,
}

impl Expr {
    /// Compiles `source`, binding names through `names`. Built-in constants (`pi`, `tau`,
    /// `e`, `true`, `false`) are resolved before `names` is asked.
    pub fn compile(source: &str, names: &dyn NameResolver) -> Result<Expr, ExprError> {
        if source.len() > MAX_SOURCE_LEN {
            return Err(ExprError::new(
                "expression is too long (the limit is 1 MiB)",
                0..source.len(),
            ));
        }
        let mut parser = Parser::new(source, names)?;
        let operand = parser.expression(0)?;
        parser.finish()?;
        Ok(Expr::assemble(operand.code, &parser.constants, source))
    }

    /// Evaluate with slot values. `slots[i]` is the value of slot i.
    ///
    /// Never allocates.
    ///
    /// # Panics
    ///
    /// Panics if `slots` is too short for a slot in [`used_slots`](Self::used_slots);
    /// that is the caller's bug, not a property of the expression.
    #[inline]
    pub fn eval(&self, slots: &[f64]) -> f64 {
        if let Some(value) = self.constant {
            return value;
        }
        if let Some(&highest) = self.used_slots.last() {
            assert!(
                (highest as usize) < slots.len(),
                "expression `{}` reads slot {highest} but only {} slot values were given",
                self.source,
                slots.len()
            );
        }
        self.eval_with(&mut SliceSlots(slots))
    }

    /// Evaluate, asking `source` for each slot value when an instruction
    /// reads it. Operands that `&&` and `||` skip are never asked
    /// for, so a source can compute costly values on demand.
    ///
    /// Never allocates (the source may).
    #[inline]
    pub fn eval_with<S: SlotSource>(&self, source: &mut S) -> f64 {
        if let Some(value) = self.constant {
            return value;
        }
        if self.max_stack <= SMALL_STACK {
            self.run::<SMALL_STACK, S>(source)
        } else {
            self.run::<MAX_STACK, S>(source)
        }
    }

    /// Evaluates and applies truthiness: true unless the value is zero.
    ///
    /// # Panics
    ///
    /// As [`eval`](Self::eval).
    #[inline]
    pub fn eval_bool(&self, slots: &[f64]) -> bool {
        self.eval(slots) != 0.0
    }

    /// Slots this expression reads (sorted, deduplicated) so callers compute only needed properties.
    pub fn used_slots(&self) -> &[u32] {
        &self.used_slots
    }

    /// Some(value) when the expression uses no slots (constant-folded at compile time).
    pub fn constant(&self) -> Option<f64> {
        self.constant
    }

    /// The source text this expression was compiled from.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// Builds the final expression, keeping only the pool constants that survived folding.
    fn assemble(code: Code, pool: &[f64], source: &str) -> Expr {
        let (mut ops, max_stack) = match code {
            Code::Const(value) => {
                return Expr {
                    ops: Vec::new(),
                    constants: Vec::new(),
                    max_stack: 0,
                    used_slots: Vec::new(),
                    constant: Some(value),
                    source: source.to_owned(),
                }
            }
            Code::Ops { ops, stack, .. } => (ops, stack),
        };
        let mut constants = Vec::new();
        let mut index_by_bits: HashMap<u64, u32> = HashMap::new();
        let mut used_slots = Vec::new();
        for op in &mut ops {
            if let Some(index) = op.constant_index_mut() {
                let value = pool[*index as usize];
                *index = *index_by_bits.entry(value.to_bits()).or_insert_with(|| {
                    constants.push(value);
                    // Fits: there are fewer constants than source bytes.
                    (constants.len() - 1) as u32
                });
            }
            used_slots.extend(op.slot());
        }
        used_slots.sort_unstable();
        used_slots.dedup();
        Expr {
            ops,
            constants,
            max_stack,
            used_slots,
            constant: None,
            source: source.to_owned(),
        }
    }
}

/// Declares the flat instruction set `Op` and the evaluator loop from one list of
/// operations. Every (operation, operand form) pair is its own variant, such as `Mul`,
/// `MulConst(index)` and `MulSlot(slot)`, so evaluation dispatches once per instruction
/// and each arm inlines its operation instead of branching on a nested function enum.
macro_rules! instruction_set {
    (
        unary { $($unary:ident),* $(,)? }
        binary { $($binary:ident / $binary_const:ident / $binary_slot:ident),* $(,)? }
        ternary { $($ternary:ident),* $(,)? }
    ) => {
        /// One stack-machine instruction.
        ///
        /// `Const` and `Slot` push a value. A unary instruction replaces the top with
        /// `f(top)`. A plain binary instruction pops `b` and replaces `a` with `f(a, b)`;
        /// its `…Const` and `…Slot` forms fuse the push of `b` from the constant pool or a
        /// slot. A ternary instruction pops `c` and `b` and replaces `a` with `f(a, b, c)`.
        /// `AndJump(n)` makes a false top exactly 0 and skips `n` instructions, else pops
        /// it; `OrJump(n)` does the same for a true top, making it 1.
        #[derive(Debug, Clone, Copy, PartialEq)]
        enum Op {
            Const(u32),
            Slot(u32),
            AndJump(u32),
            OrJump(u32),
            $($unary,)*
            $($binary, $binary_const(u32), $binary_slot(u32),)*
            $($ternary,)*
        }

        impl Op {
            fn unary(function: Unary) -> Op {
                match function {
                    $(Unary::$unary => Op::$unary,)*
                }
            }

            fn binary(function: Binary) -> Op {
                match function {
                    $(Binary::$binary => Op::$binary,)*
                }
            }

            fn binary_const(function: Binary, index: u32) -> Op {
                match function {
                    $(Binary::$binary => Op::$binary_const(index),)*
                }
            }

            fn binary_slot(function: Binary, slot: u32) -> Op {
                match function {
                    $(Binary::$binary => Op::$binary_slot(slot),)*
                }
            }

            fn ternary(function: Ternary) -> Op {
                match function {
                    $(Ternary::$ternary => Op::$ternary,)*
                }
            }

            /// The constant-pool index this instruction reads, if any.
            fn constant_index_mut(&mut self) -> Option<&mut u32> {
                match self {
                    Op::Const(index) $(| Op::$binary_const(index))* => Some(index),
                    _ => None,
                }
            }

            /// The slot this instruction reads, if any.
            fn slot(self) -> Option<u32> {
                match self {
                    Op::Slot(slot) $(| Op::$binary_slot(slot))* => Some(slot),
                    _ => None,
                }
            }

            /// The instruction as an operation and its operand form, for
            /// rebuilding the expression tree (see [`Tree`]).
            fn decoded(self) -> tree::Decoded {
                use tree::{Decoded, Operand};
                match self {
                    Op::Const(index) => Decoded::Push(Operand::Const(index)),
                    Op::Slot(slot) => Decoded::Push(Operand::Slot(slot)),
                    Op::AndJump(skip) => Decoded::Logic { and: true, skip },
                    Op::OrJump(skip) => Decoded::Logic { and: false, skip },
                    $(Op::$unary => Decoded::Unary(Unary::$unary),)*
                    $(
                        Op::$binary => Decoded::Binary(Binary::$binary, None),
                        Op::$binary_const(index) => {
                            Decoded::Binary(Binary::$binary, Some(Operand::Const(index)))
                        }
                        Op::$binary_slot(slot) => {
                            Decoded::Binary(Binary::$binary, Some(Operand::Slot(slot)))
                        }
                    )*
                    $(Op::$ternary => Decoded::Ternary(Ternary::$ternary),)*
                }
            }
        }

        impl Expr {
            /// Runs the ops on a stack of `N >= max_stack` entries.
            fn run<const N: usize, S: SlotSource>(&self, slots: &mut S) -> f64 {
                let ops = self.ops.as_slice();
                let constants = self.constants.as_slice();
                // `top` keeps the top of the stack in a register and `stack[..depth]`
                // holds the values beneath it. The first push spills the meaningless
                // initial `top`, which is why a logical depth of `max_stack` needs
                // `max_stack` entries.
                let mut stack = [0.0_f64; N];
                let mut depth = 0_usize;
                let mut top = 0.0_f64;
                let mut pc = 0_usize;
                while let Some(&op) = ops.get(pc) {
                    pc += 1;
                    match op {
                        Op::Const(index) => {
                            stack[depth] = top;
                            depth += 1;
                            top = constants[index as usize];
                        }
                        Op::Slot(slot) => {
                            stack[depth] = top;
                            depth += 1;
                            top = slots.slot(slot);
                        }
                        Op::AndJump(skip) => {
                            if top == 0.0 {
                                // Normalises -0.0 so `&&` yields exactly 0.0.
                                top = 0.0;
                                pc += skip as usize;
                            } else {
                                depth -= 1;
                                top = stack[depth];
                            }
                        }
                        Op::OrJump(skip) => {
                            if top != 0.0 {
                                top = 1.0;
                                pc += skip as usize;
                            } else {
                                depth -= 1;
                                top = stack[depth];
                            }
                        }
                        $(Op::$unary => top = Unary::$unary.apply(top),)*
                        $(
                            Op::$binary => {
                                depth -= 1;
                                top = Binary::$binary.apply(stack[depth], top);
                            }
                            Op::$binary_const(index) => {
                                top = Binary::$binary.apply(top, constants[index as usize]);
                            }
                            Op::$binary_slot(slot) => {
                                top = Binary::$binary.apply(top, slots.slot(slot));
                            }
                        )*
                        $(
                            Op::$ternary => {
                                depth -= 2;
                                top = Ternary::$ternary.apply(stack[depth], stack[depth + 1], top);
                            }
                        )*
                    }
                }
                top
            }
        }
    };
}

instruction_set! {
    unary {
        Neg, Not, Truthy, Sin, Cos, Tan, Asin, Acos, Atan, Sqrt, Abs, Floor, Ceil, Round,
        Sign, Exp, Ln, Log10, Radians, Degrees,
    }
    binary {
        Add / AddConst / AddSlot,
        Sub / SubConst / SubSlot,
        Mul / MulConst / MulSlot,
        Div / DivConst / DivSlot,
        Rem / RemConst / RemSlot,
        Pow / PowConst / PowSlot,
        Lt / LtConst / LtSlot,
        Le / LeConst / LeSlot,
        Gt / GtConst / GtSlot,
        Ge / GeConst / GeSlot,
        Eq / EqConst / EqSlot,
        Ne / NeConst / NeSlot,
        Atan2 / Atan2Const / Atan2Slot,
        Min / MinConst / MinSlot,
        Max / MaxConst / MaxSlot,
        Step / StepConst / StepSlot,
    }
    ternary { Clamp, Lerp, Smoothstep }
}
