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

mod tree;
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

fn from_bool(value: bool) -> f64 {
    if value {
        1.0
    } else {
        0.0
    }
}

fn truthy(value: f64) -> bool {
    value != 0.0
}

const DEGREES_TO_RADIANS: f64 = PI / 180.0;
const RADIANS_TO_DEGREES: f64 = 180.0 / PI;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Unary {
    Neg,
    Not,
    /// Maps a value to exactly 0 or 1; ends `&&` and `||`.
    Truthy,
    Sin,
    Cos,
    Tan,
    Asin,
    Acos,
    Atan,
    Sqrt,
    Abs,
    Floor,
    Ceil,
    Round,
    Sign,
    Exp,
    Ln,
    Log10,
    Radians,
    Degrees,
}

impl Unary {
    #[inline(always)]
    pub(crate) fn apply(self, x: f64) -> f64 {
        match self {
            Unary::Neg => -x,
            Unary::Not => from_bool(x == 0.0),
            Unary::Truthy => from_bool(truthy(x)),
            Unary::Sin => libm::sin(x),
            Unary::Cos => libm::cos(x),
            Unary::Tan => libm::tan(x),
            Unary::Asin => libm::asin(x),
            Unary::Acos => libm::acos(x),
            Unary::Atan => libm::atan(x),
            Unary::Sqrt => libm::sqrt(x),
            Unary::Abs => libm::fabs(x),
            Unary::Floor => libm::floor(x),
            Unary::Ceil => libm::ceil(x),
            Unary::Round => libm::round(x),
            Unary::Sign => sign(x),
            Unary::Exp => libm::exp(x),
            Unary::Ln => libm::log(x),
            Unary::Log10 => libm::log10(x),
            Unary::Radians => x * DEGREES_TO_RADIANS,
            Unary::Degrees => x * RADIANS_TO_DEGREES,
        }
    }

    fn yields_boolean(self) -> bool {
        matches!(self, Unary::Not | Unary::Truthy)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Binary {
    Add,
    Sub,
    Mul,
    Div,
    Rem,
    Pow,
    Lt,
    Le,
    Gt,
    Ge,
    Eq,
    Ne,
    Atan2,
    Min,
    Max,
    Step,
}

impl Binary {
    #[inline(always)]
    pub(crate) fn apply(self, a: f64, b: f64) -> f64 {
        match self {
            Binary::Add => a + b,
            Binary::Sub => a - b,
            Binary::Mul => a * b,
            Binary::Div => a / b,
            Binary::Rem => floored_rem(a, b),
            Binary::Pow => libm::pow(a, b),
            Binary::Lt => from_bool(a < b),
            Binary::Le => from_bool(a <= b),
            Binary::Gt => from_bool(a > b),
            Binary::Ge => from_bool(a >= b),
            Binary::Eq => from_bool(a == b),
            Binary::Ne => from_bool(a != b),
            Binary::Atan2 => libm::atan2(a, b),
            Binary::Min => libm::fmin(a, b),
            Binary::Max => libm::fmax(a, b),
            Binary::Step => step(a, b),
        }
    }

    fn yields_boolean(self) -> bool {
        matches!(
            self,
            Binary::Lt
                | Binary::Le
                | Binary::Gt
                | Binary::Ge
                | Binary::Eq
                | Binary::Ne
                | Binary::Step
        )
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Ternary {
    Clamp,
    Lerp,
    Smoothstep,
}

impl Ternary {
    #[inline(always)]
    pub(crate) fn apply(self, a: f64, b: f64, c: f64) -> f64 {
        match self {
            Ternary::Clamp => clamp(a, b, c),
            Ternary::Lerp => a + (b - a) * c,
            Ternary::Smoothstep => smoothstep(a, b, c),
        }
    }
}

/// Floored modulo with the sign of the divisor, like Python's `%`. Starting from the exact
/// `fmod` avoids the rounding error of computing `x - y * floor(x / y)` literally.
fn floored_rem(x: f64, y: f64) -> f64 {
    let rem = libm::fmod(x, y);
    if rem == 0.0 {
        libm::copysign(0.0, y)
    } else if (rem < 0.0) != (y < 0.0) {
        rem + y
    } else {
        rem
    }
}

fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        x
    }
}

fn clamp(x: f64, lo: f64, hi: f64) -> f64 {
    libm::fmin(libm::fmax(x, lo), hi)
}

fn step(edge: f64, x: f64) -> f64 {
    from_bool(x >= edge)
}

fn smoothstep(edge0: f64, edge1: f64, x: f64) -> f64 {
    // Equal edges would divide by zero; the limit of a vanishing ramp is a step.
    if edge0 == edge1 {
        return step(edge0, x);
    }
    let t = clamp((x - edge0) / (edge1 - edge0), 0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn builtin_constant(name: &str) -> Option<f64> {
    match name {
        "pi" => Some(PI),
        "tau" => Some(TAU),
        "e" => Some(E),
        "true" => Some(1.0),
        "false" => Some(0.0),
        _ => None,
    }
}

pub(crate) const BUILTIN_CONSTANT_NAMES: [&str; 5] = ["pi", "tau", "e", "true", "false"];

#[derive(Debug, Clone, Copy)]
enum Callee {
    Unary(Unary),
    Binary(Binary),
    Ternary(Ternary),
    /// One or more arguments folded pairwise from the left.
    Variadic(Binary),
}

const FUNCTIONS: &[(&str, Callee)] = &[
    ("sin", Callee::Unary(Unary::Sin)),
    ("cos", Callee::Unary(Unary::Cos)),
    ("tan", Callee::Unary(Unary::Tan)),
    ("asin", Callee::Unary(Unary::Asin)),
    ("acos", Callee::Unary(Unary::Acos)),
    ("atan", Callee::Unary(Unary::Atan)),
    ("atan2", Callee::Binary(Binary::Atan2)),
    ("sqrt", Callee::Unary(Unary::Sqrt)),
    ("abs", Callee::Unary(Unary::Abs)),
    ("min", Callee::Variadic(Binary::Min)),
    ("max", Callee::Variadic(Binary::Max)),
    ("clamp", Callee::Ternary(Ternary::Clamp)),
    ("lerp", Callee::Ternary(Ternary::Lerp)),
    ("floor", Callee::Unary(Unary::Floor)),
    ("ceil", Callee::Unary(Unary::Ceil)),
    ("round", Callee::Unary(Unary::Round)),
    ("sign", Callee::Unary(Unary::Sign)),
    ("exp", Callee::Unary(Unary::Exp)),
    ("ln", Callee::Unary(Unary::Ln)),
    ("log10", Callee::Unary(Unary::Log10)),
    ("pow", Callee::Binary(Binary::Pow)),
    ("radians", Callee::Unary(Unary::Radians)),
    ("degrees", Callee::Unary(Unary::Degrees)),
    ("step", Callee::Binary(Binary::Step)),
    ("smoothstep", Callee::Ternary(Ternary::Smoothstep)),
];

fn function(name: &str) -> Option<Callee> {
    FUNCTIONS
        .iter()
        .find(|(known, _)| *known == name)
        .map(|&(_, callee)| callee)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Infix {
    Or,
    And,
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
    Add,
    Sub,
    Mul,
    Div,
    Rem,
    Pow,
}

/// Binding power of the operand of unary `-`, `+` and `!`: above `*`, below `^`.
const PREFIX_BINDING_POWER: u8 = 13;

impl Infix {
    /// Left and right binding powers; a higher right power makes the operator
    /// left-associative, a lower one right-associative.
    fn binding_power(self) -> (u8, u8) {
        match self {
            Infix::Or => (1, 2),
            Infix::And => (3, 4),
            Infix::Eq | Infix::Ne => (5, 6),
            Infix::Lt | Infix::Le | Infix::Gt | Infix::Ge => (7, 8),
            Infix::Add | Infix::Sub => (9, 10),
            Infix::Mul | Infix::Div | Infix::Rem => (11, 12),
            Infix::Pow => (15, 14),
        }
    }

    fn is_comparison(self) -> bool {
        matches!(
            self,
            Infix::Eq | Infix::Ne | Infix::Lt | Infix::Le | Infix::Gt | Infix::Ge
        )
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum TokenKind {
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
struct Token {
    kind: TokenKind,
    span: Span,
}

fn is_name_start(byte: u8) -> bool {
    byte.is_ascii_alphabetic() || byte == b'_'
}

fn is_name_continue(byte: u8) -> bool {
    byte.is_ascii_alphanumeric() || byte == b'_'
}

struct Lexer<'s> {
    source: &'s str,
    pos: usize,
}

impl<'s> Lexer<'s> {
    fn byte_at(&self, ahead: usize) -> Option<u8> {
        self.source.as_bytes().get(self.pos + ahead).copied()
    }

    fn next_token(&mut self) -> Result<Token, ExprError> {
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

    fn lone(start: usize, message: &str) -> ExprError {
        ExprError::new(message, start..start + 1)
    }

    fn skip_digits(&mut self) {
        while self.byte_at(0).is_some_and(|b| b.is_ascii_digit()) {
            self.pos += 1;
        }
    }

    fn number(&mut self) -> Result<Token, ExprError> {
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

    fn name(&mut self) -> Result<Token, ExprError> {
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

/// A subexpression compiled while parsing.
enum Code {
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

struct Operand {
    code: Code,
    span: Span,
}

fn too_deep(span: Span) -> ExprError {
    ExprError::new("expression too deeply nested", span)
}

fn unclosed(open: Span) -> ExprError {
    ExprError::new("unclosed `(`", open)
}

struct Parser<'s, 'r> {
    source: &'s str,
    lexer: Lexer<'s>,
    current: Token,
    names: &'r dyn NameResolver,
    /// Pool of every constant materialised while parsing; `Expr::assemble` keeps the live ones.
    constants: Vec<f64>,
    nesting: usize,
}

impl<'s, 'r> Parser<'s, 'r> {
    fn new(source: &'s str, names: &'r dyn NameResolver) -> Result<Self, ExprError> {
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
    fn bump(&mut self) -> Result<Token, ExprError> {
        let next = self.lexer.next_token()?;
        Ok(std::mem::replace(&mut self.current, next))
    }

    fn current_text(&self) -> &'s str {
        &self.source[self.current.span.clone()]
    }

    /// Parses a subexpression one level deeper; `opener` is the token that opened the
    /// level and is where a too-deep error points.
    fn nested(&mut self, min_power: u8, opener: &Span) -> Result<Operand, ExprError> {
        if self.nesting >= MAX_NESTING {
            return Err(too_deep(opener.clone()));
        }
        self.nesting += 1;
        let result = self.expression(min_power);
        self.nesting -= 1;
        result
    }

    /// Pratt loop: an operand, then infix operators binding at least `min_power`.
    fn expression(&mut self, min_power: u8) -> Result<Operand, ExprError> {
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

    fn operand(&mut self) -> Result<Operand, ExprError> {
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

    fn expect_close(&mut self, open: &Span) -> Result<Span, ExprError> {
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
    fn finish(&self) -> Result<(), ExprError> {
        let message = match self.current.kind {
            TokenKind::Eof => return Ok(()),
            TokenKind::RParen | TokenKind::Comma => {
                format!("unexpected `{}`", self.current_text())
            }
            _ => format!("expected an operator, found `{}`", self.current_text()),
        };
        Err(ExprError::new(message, self.current.span.clone()))
    }

    fn name_or_call(&mut self, span: Span) -> Result<Operand, ExprError> {
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

    fn unknown_name_message(&self, name: &str) -> String {
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

    fn call(&mut self, name: &str, name_span: Span) -> Result<Operand, ExprError> {
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

    fn infix(&mut self, op: Infix, lhs: Operand, rhs: Operand) -> Result<Operand, ExprError> {
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

    fn push_constant(&mut self, value: f64) -> u32 {
        self.constants.push(value);
        // Fits: there are fewer constants than source bytes, and sources are at most 1 MiB.
        (self.constants.len() - 1) as u32
    }

    /// Ops and stack need of `code`, pushing a folded value as a pool constant.
    fn materialize(&mut self, code: Code) -> (Vec<Op>, usize) {
        match code {
            Code::Const(value) => (vec![Op::Const(self.push_constant(value))], 1),
            Code::Ops { ops, stack, .. } => (ops, stack),
        }
    }

    fn unary(&mut self, function: Unary, operand: Operand, span: Span) -> Operand {
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

    fn binary(
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

    fn ternary(
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
    fn logic(&mut self, is_and: bool, lhs: Operand, rhs: Operand, span: Span) -> Operand {
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
fn to_bool(code: Code) -> Code {
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
fn close_matches<'a>(name: &str, candidates: &[&'a str]) -> Vec<&'a str> {
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

#[cfg(test)]
mod tests {
    use super::*;

    const NAMES: &[&str] = &[
        "x",
        "y",
        "z",
        "pos.x",
        "pos.y",
        "pre.length",
        "width",
        "nan",
    ];
    const VALUES: [f64; 8] = [2.0, 3.0, -0.5, 10.0, -4.0, 7.5, 6.0, f64::NAN];

    fn compile(source: &str) -> Result<Expr, ExprError> {
        Expr::compile(source, &SlotNames(NAMES))
    }

    fn eval(source: &str) -> f64 {
        compile(source)
            .unwrap_or_else(|err| panic!("`{source}` failed: {err} at {:?}", err.span))
            .eval(&VALUES)
    }

    fn error(source: &str) -> (String, Span) {
        match compile(source) {
            Ok(expr) => panic!("`{source}` compiled to {expr:?}"),
            Err(err) => (err.message, err.span),
        }
    }

    fn assert_same(actual: f64, expected: f64, what: &str) {
        assert!(
            actual.to_bits() == expected.to_bits() || (actual.is_nan() && expected.is_nan()),
            "{what}: got {actual:?}, expected {expected:?}"
        );
    }

    // Evaluation speed depends on instructions staying one machine word.
    const _: () = assert!(std::mem::size_of::<Op>() == 8);

    #[test]
    fn precedence_and_associativity_of_constants() {
        let table: &[(&str, f64)] = &[
            ("1 + 2 * 3", 7.0),
            ("(1 + 2) * 3", 9.0),
            ("10 - 4 - 3", 3.0),
            ("8 / 4 / 2", 1.0),
            ("7 % 4 * 2", 6.0),
            ("2 * 3 ^ 2", 18.0),
            ("-2 ^ 2", -4.0),
            ("(-2) ^ 2", 4.0),
            ("2 ^ 3 ^ 2", 512.0),
            ("(2 ^ 3) ^ 2", 64.0),
            ("2 ^ -1", 0.5),
            ("-2 ^ -2", -0.25),
            ("2 * -3", -6.0),
            ("- -3", 3.0),
            ("+-+3", -3.0),
            ("-3 % 5", 2.0),
            ("1 + 2 < 4", 1.0),
            ("1 < 2 == 2 > 1", 1.0),
            ("(1 < 2) < 3", 1.0),
            ("1 == 1 && 0", 0.0),
            ("1 || 0 && 0", 1.0),
            ("(1 || 0) && 0", 0.0),
            ("!0 + 1", 2.0),
            ("!1 == 0", 1.0),
            ("!!5", 1.0),
            ("1 - 2 * 3 + 4 / 2", -3.0),
            ("2 ^ 2 * 3", 12.0),
            ("1 < 2 && 3 < 4 || 0", 1.0),
        ];
        for &(source, expected) in table {
            let expr = compile(source).unwrap();
            assert_eq!(expr.constant(), Some(expected), "{source}");
            assert_eq!(expr.eval(&[]), expected, "{source}");
        }
    }

    #[test]
    fn precedence_and_associativity_with_slots() {
        // x = 2, y = 3, z = -0.5: the same shapes as above, run by the stack machine.
        let table: &[(&str, f64)] = &[
            ("x + y * x", 8.0),
            ("(x + y) * x", 10.0),
            ("y - x - x", -1.0),
            ("width / y / x", 1.0),
            ("-x ^ 2", -4.0),
            ("x ^ y ^ x", 512.0),
            ("(x ^ y) ^ x", 64.0),
            ("x ^ -x", 0.25),
            ("x * -y", -6.0),
            ("- -x", 2.0),
            ("x + y < 6", 1.0),
            ("x < y == y > x", 1.0),
            ("x == x && 0 * y", 0.0),
            ("x || 0 * y && 0 * y", 1.0),
            ("!z + x", 2.0),
            ("pos.x - x * y + width / x", 7.0),
            ("x * (y + (x * (y + x)))", 26.0),
        ];
        for &(source, expected) in table {
            let expr = compile(source).unwrap();
            assert_eq!(expr.constant(), None, "{source}");
            assert_eq!(expr.eval(&VALUES), expected, "{source}");
        }
    }

    #[test]
    fn numbers() {
        let table: &[(&str, f64)] = &[
            ("1", 1.0),
            ("1.5", 1.5),
            (".5", 0.5),
            ("1.", 1.0),
            ("1e-3", 1e-3),
            ("2.5E+2", 250.0),
            ("1E2", 100.0),
            ("0.1", 0.1),
            ("1e-400", 0.0),
            ("  42\t\n", 42.0),
        ];
        for &(source, expected) in table {
            assert_eq!(eval(source), expected, "{source}");
        }
    }

    #[test]
    fn constants_are_reserved() {
        assert_eq!(eval("pi"), PI);
        assert_eq!(eval("tau"), TAU);
        assert_eq!(eval("e"), E);
        assert_eq!(eval("true + true"), 2.0);
        assert_eq!(eval("false"), 0.0);
        // A resolver that binds `pi` is never asked.
        let everything = |_: &str| Some(0);
        let expr = Expr::compile("pi + e", &everything).unwrap();
        assert_eq!(expr.constant(), Some(PI + E));
        // Dotted names starting with a constant's name are ordinary names.
        let expr = Expr::compile("e.x", &everything).unwrap();
        assert_eq!(expr.used_slots(), &[0]);
    }

    #[test]
    fn dotted_names_reach_the_resolver_whole() {
        let seen = std::cell::RefCell::new(Vec::new());
        let resolver = |name: &str| {
            seen.borrow_mut().push(name.to_owned());
            Some(0)
        };
        Expr::compile("scope.size.x * pos.x + a_b1", &resolver).unwrap();
        assert_eq!(*seen.borrow(), ["scope.size.x", "pos.x", "a_b1"]);
    }

    #[test]
    fn functions_match_libm_bit_for_bit() {
        type Reference = fn(f64) -> f64;
        let unary: &[(&str, Reference)] = &[
            ("sin", libm::sin),
            ("cos", libm::cos),
            ("tan", libm::tan),
            ("asin", libm::asin),
            ("acos", libm::acos),
            ("atan", libm::atan),
            ("sqrt", libm::sqrt),
            ("abs", libm::fabs),
            ("floor", libm::floor),
            ("ceil", libm::ceil),
            ("round", libm::round),
            ("exp", libm::exp),
            ("ln", libm::log),
            ("log10", libm::log10),
        ];
        for &(name, reference) in unary {
            for input in [0.3, -0.7, 0.5, 2.5, 1.0] {
                let expected = reference(input);
                // Folded at compile time and run by the stack machine: both must agree.
                assert_same(eval(&format!("{name}({input})")), expected, name);
                let expr = Expr::compile(&format!("{name}(v)"), &SlotNames(&["v"])).unwrap();
                assert_same(expr.eval(&[input]), expected, name);
            }
        }
        assert_eq!(eval("sin(1)").to_bits(), libm::sin(1.0).to_bits());
        assert_eq!(eval("sin(x - 1)").to_bits(), libm::sin(1.0).to_bits());
        assert_eq!(eval("atan2(1, -1)"), libm::atan2(1.0, -1.0));
        assert_eq!(eval("atan2(y, -x)"), libm::atan2(3.0, -2.0));
        assert_eq!(eval("pow(1.1, 7.3)"), libm::pow(1.1, 7.3));
        assert_eq!(eval("1.1 ^ 7.3"), libm::pow(1.1, 7.3));
        assert_eq!(eval("pow(x, z)"), libm::pow(2.0, -0.5));
    }

    #[test]
    fn function_values() {
        let table: &[(&str, f64)] = &[
            ("round(2.5)", 3.0),
            ("round(-2.5)", -3.0),
            ("round(2.49)", 2.0),
            ("floor(-1.5)", -2.0),
            ("ceil(-1.5)", -1.0),
            ("abs(z)", 0.5),
            ("sqrt(16)", 4.0),
            ("sign(-3)", -1.0),
            ("sign(z)", -1.0),
            ("sign(0)", 0.0),
            ("sign(x)", 1.0),
            ("min(3, 1, 2)", 1.0),
            ("min(x, y, z)", -0.5),
            ("max(3)", 3.0),
            ("max(x, y, z, pos.y)", 3.0),
            ("max(nan, x)", 2.0),
            ("clamp(5, 0, 1)", 1.0),
            ("clamp(z, 0, 1)", 0.0),
            ("clamp(0.25, 0, 1)", 0.25),
            ("lerp(2, 4, 0.25)", 2.5),
            ("lerp(x, y, 0.5)", 2.5),
            ("step(1, 0.5)", 0.0),
            ("step(1, 1)", 1.0),
            ("step(x, y)", 1.0),
            ("smoothstep(0, 1, 0.5)", 0.5),
            ("smoothstep(0, 2, 3)", 1.0),
            ("smoothstep(0, 2, -1)", 0.0),
            ("smoothstep(0, 4, x)", 0.5),
            ("smoothstep(1, 1, 0.5)", 0.0),
            ("smoothstep(1, 1, 1)", 1.0),
            ("radians(180)", PI),
            ("degrees(pi)", 180.0),
            ("exp(0)", 1.0),
            ("ln(1)", 0.0),
            ("log10(100)", 2.0),
            ("pow(2, 10)", 1024.0),
            ("atan2(0, 1)", 0.0),
        ];
        for &(source, expected) in table {
            assert_eq!(eval(source), expected, "{source}");
        }
        assert!(eval("sign(nan)").is_nan());
        assert!(eval("sqrt(-1)").is_nan());
        assert_eq!(eval("sign(-0.0)").to_bits(), (-0.0_f64).to_bits());
    }

    #[test]
    fn floored_modulo() {
        let table: &[(&str, f64)] = &[
            ("7 % 3", 1.0),
            ("-7 % 3", 2.0),
            ("7 % -3", -2.0),
            ("-7 % -3", -1.0),
            ("5.5 % 2", 1.5),
            ("-5.5 % 2", 0.5),
            ("6 % 3", 0.0),
            ("x % y", 2.0),
            ("z % x", 1.5),
            ("pos.x % pos.y", -2.0),
            ("-1 % (1 / 0)", f64::INFINITY),
        ];
        for &(source, expected) in table {
            assert_eq!(eval(source), expected, "{source}");
        }
        assert!(eval("1 % 0").is_nan());
        assert_eq!(eval("-6 % 3").to_bits(), 0.0_f64.to_bits());
        assert_eq!(eval("6 % -3").to_bits(), (-0.0_f64).to_bits());
    }

    #[test]
    fn comparisons_and_logic() {
        let table: &[(&str, f64)] = &[
            ("x < y", 1.0),
            ("x <= x", 1.0),
            ("x > y", 0.0),
            ("x >= y", 0.0),
            ("x == 2", 1.0),
            ("x != 2", 0.0),
            ("nan == nan", 0.0),
            ("nan != nan", 1.0),
            ("nan < 1", 0.0),
            ("x && y", 1.0),
            ("x && 0 * y", 0.0),
            ("0 * x || y", 1.0),
            ("0 * x || 0 * y", 0.0),
            ("!x", 0.0),
            ("!(0 * x)", 1.0),
            ("nan && x", 1.0),
            ("-0.0 * x || 0 * y", 0.0),
            ("(x > 1) + (y > 1)", 2.0),
            ("x > 1 && y > 1 || z > 1", 1.0),
        ];
        for &(source, expected) in table {
            assert_eq!(eval(source), expected, "{source}");
        }
        // `&&` of a negative zero yields a positive zero.
        assert_eq!(eval("-0.0 * x && y").to_bits(), 0.0_f64.to_bits());
    }

    #[test]
    fn eval_with_asks_only_for_the_slots_it_reaches() {
        struct Counting {
            values: [f64; 2],
            asked: Vec<u32>,
        }
        impl SlotSource for Counting {
            fn slot(&mut self, slot: u32) -> f64 {
                self.asked.push(slot);
                self.values[slot as usize]
            }
        }
        let names = SlotNames(&["x", "y"]);
        let and = Expr::compile("x == 1 && y > 0", &names).unwrap();
        let mut source = Counting {
            values: [0.0, 5.0],
            asked: Vec::new(),
        };
        assert_eq!(and.eval_with(&mut source), 0.0);
        assert_eq!(source.asked, [0]);
        let mut source = Counting {
            values: [1.0, 5.0],
            asked: Vec::new(),
        };
        assert_eq!(and.eval_with(&mut source), 1.0);
        assert_eq!(source.asked, [0, 1]);
        // The same answers as slot values given up front.
        for values in [[0.0, 5.0], [1.0, 5.0], [1.0, -1.0]] {
            let mut source = Counting {
                values,
                asked: Vec::new(),
            };
            assert_eq!(and.eval_with(&mut source), and.eval(&values));
        }
    }

    #[test]
    fn short_circuit_skips_the_right_operand() {
        // `y` is NaN here, and `nan == nan` would be 0, so reaching it would change the result.
        let names = SlotNames(&["x", "y"]);
        let and = Expr::compile("x && y == y", &names).unwrap();
        assert_eq!(and.eval(&[0.0, f64::NAN]), 0.0);
        assert_eq!(and.eval(&[1.0, f64::NAN]), 0.0);
        assert_eq!(and.eval(&[1.0, 4.0]), 1.0);
        let or = Expr::compile("x || y != y", &names).unwrap();
        assert_eq!(or.eval(&[5.0, 1.0]), 1.0);
        assert_eq!(or.eval(&[0.0, 1.0]), 0.0);
        assert_eq!(or.eval(&[0.0, f64::NAN]), 1.0);
        // Nested short circuits keep the stack balanced.
        let nested = Expr::compile("(x && y) + (x || y) * 2 + (y && x || x)", &names).unwrap();
        assert_eq!(nested.eval(&[1.0, 0.0]), 3.0);
        assert_eq!(nested.eval(&[0.0, 0.0]), 0.0);
        assert_eq!(nested.eval(&[0.0, 1.0]), 2.0);
        assert_eq!(nested.eval(&[1.0, 1.0]), 4.0);
        // Logic inside a larger computation, with values on the stack beneath.
        let inside = Expr::compile("x * 10 + (y - (x && y))", &names).unwrap();
        assert_eq!(inside.eval(&[2.0, 3.0]), 22.0);
        assert_eq!(inside.eval(&[0.0, 3.0]), 3.0);
    }

    #[test]
    fn constant_folding() {
        let expr = compile("2*pi").unwrap();
        assert_eq!(expr.constant(), Some(TAU));
        assert_eq!(expr.used_slots(), &[] as &[u32]);
        assert_eq!(
            compile("sin(pi / 2) + max(1, 2)").unwrap().constant(),
            Some(3.0)
        );
        assert_eq!(compile("pos.x+1").unwrap().constant(), None);
        // A constant operand of `&&` or `||` may decide the result alone.
        assert_eq!(compile("0 && pos.x").unwrap().constant(), Some(0.0));
        assert_eq!(compile("pos.x && 0").unwrap().constant(), Some(0.0));
        assert_eq!(compile("1 || pos.x").unwrap().constant(), Some(1.0));
        assert_eq!(compile("pos.x || 2").unwrap().constant(), Some(1.0));
        let reduced = compile("1 && pos.x").unwrap();
        assert_eq!(reduced.constant(), None);
        assert_eq!(reduced.eval(&VALUES), 1.0);
        // Folded subtrees leave a single pool constant behind.
        let partial = compile("x * (2 * pi) + x * tau").unwrap();
        assert_eq!(partial.constants, [TAU]);
        assert_eq!(partial.eval(&VALUES), 4.0 * TAU);
        // Constants discarded by folding (the `3`) do not linger in the pool.
        let pruned = compile("x + (0 && y * 3)").unwrap();
        assert_eq!(pruned.constants, [0.0]);
        assert_eq!(pruned.used_slots(), &[0]);
    }

    #[test]
    fn used_slots_are_sorted_and_deduplicated() {
        let expr = compile("width + x * x + pos.x - x / width").unwrap();
        assert_eq!(expr.used_slots(), &[0, 3, 6]);
        assert_eq!(expr.source(), "width + x * x + pos.x - x / width");
        assert_eq!(compile("7").unwrap().used_slots(), &[] as &[u32]);
    }

    #[test]
    fn eval_bool_and_equality() {
        assert!(compile("x > 1").unwrap().eval_bool(&VALUES));
        assert!(!compile("x > y").unwrap().eval_bool(&VALUES));
        assert_eq!(compile("x + 1").unwrap(), compile("x + 1").unwrap());
    }

    #[test]
    #[should_panic(expected = "reads slot 6 but only 2 slot values were given")]
    fn eval_panics_on_missing_slots() {
        compile("x + width").unwrap().eval(&[1.0, 2.0]);
    }

    #[test]
    fn error_messages_and_spans() {
        let table: &[(&str, &str, Span)] = &[
            ("", "expected an expression", 0..0),
            ("   ", "expected an expression", 3..3),
            ("1 +", "expected an expression", 3..3),
            ("1 + )", "expected an expression", 4..5),
            ("* 2", "expected an expression", 0..1),
            ("min(1,)", "expected an expression", 6..7),
            ("()", "expected an expression", 1..2),
            ("1)", "unexpected `)`", 1..2),
            ("(x + 1))", "unexpected `)`", 7..8),
            ("1, 2", "unexpected `,`", 1..2),
            ("(1 + 2", "unclosed `(`", 0..1),
            ("x * ((y)", "unclosed `(`", 4..5),
            ("sin(1", "unclosed `(`", 3..4),
            ("sinn(1)", "`sinn` is not a function", 0..4),
            ("2 * pos.x(1)", "`pos.x` is not a function", 4..9),
            ("clamp(x, 1)", "`clamp` takes 3 arguments, found 2", 0..11),
            ("1 + sin()", "`sin` takes 1 argument, found 0", 4..9),
            ("sin(1, 2)", "`sin` takes 1 argument, found 2", 0..9),
            ("atan2( 1 )", "`atan2` takes 2 arguments, found 1", 0..10),
            ("min()", "`min` takes at least 1 argument, found 0", 0..5),
            ("x < y < z", "comparison operators cannot be chained", 6..7),
            (
                "x < y + 1 >= z",
                "comparison operators cannot be chained",
                10..12,
            ),
            (
                "x == y != z",
                "comparison operators cannot be chained",
                7..9,
            ),
            ("1 # 2", "unexpected character `#`", 2..3),
            ("1 + é", "unexpected character `é`", 4..6),
            ("x\u{0}", "unexpected character `\\0`", 1..2),
            ("x . y", "unexpected character `.`", 2..3),
            ("1e", "invalid number `1e`", 0..2),
            ("x * 1e+", "invalid number `1e+`", 4..7),
            ("1.2.3", "invalid number `1.2.3`", 0..5),
            ("3abc + 1", "invalid number `3abc`", 0..4),
            ("1e999", "number `1e999` is too large", 0..5),
            ("foo + 1", "unknown name `foo`", 0..3),
            (
                "2 * widht",
                "unknown name `widht`; did you mean `width`?",
                4..9,
            ),
            (
                "pos.z",
                "unknown name `pos.z`; did you mean one of `pos.x`, `pos.y`?",
                0..5,
            ),
            ("tau2", "unknown name `tau2`; did you mean `tau`?", 0..4),
            (
                "sin + 1",
                "unknown name `sin`; `sin` is a function, call it like `sin(...)`",
                0..3,
            ),
            ("1 2", "expected an operator, found `2`", 2..3),
            ("x y", "expected an operator, found `y`", 2..3),
            ("(1 2)", "expected `)`, found `2`", 3..4),
            ("min(1 2)", "expected `,` or `)`, found `2`", 6..7),
            ("pos.", "expected a field name after `.`", 3..4),
            ("pos.1", "expected a field name after `.`", 3..4),
            ("x = 1", "`=` is not an operator; use `==` to compare", 2..3),
            ("x & y", "`&` is not an operator; use `&&`", 2..3),
            ("x | y", "`|` is not an operator; use `||`", 2..3),
        ];
        for (source, message, span) in table {
            let (actual_message, actual_span) = error(source);
            assert_eq!(
                (actual_message.as_str(), actual_span),
                (*message, span.clone()),
                "{source}"
            );
        }
    }

    #[test]
    fn closure_resolvers_give_plain_unknown_names() {
        let none = |_: &str| None;
        let err = Expr::compile("widht", &none).unwrap_err();
        assert_eq!(err.message, "unknown name `widht`");
        assert_eq!(err.to_string(), "unknown name `widht`");
        assert_eq!(err.offset_by(10).span, 10..15);
    }

    #[test]
    fn nesting_limit() {
        let parens = |depth: usize| format!("{}x{}", "(".repeat(depth), ")".repeat(depth));
        assert_eq!(eval(&parens(MAX_NESTING)), 2.0);
        assert_eq!(
            error(&parens(MAX_NESTING + 1)),
            ("expression too deeply nested".to_owned(), 64..65)
        );
        let negations = format!("{}x", "-".repeat(70));
        assert_eq!(
            error(&negations),
            ("expression too deeply nested".to_owned(), 64..65)
        );
        let powers = format!("x{}", "^x".repeat(70));
        assert_eq!(
            error(&powers),
            ("expression too deeply nested".to_owned(), 129..130)
        );
        // Hostile input fails quickly instead of overflowing the native stack.
        let hostile = "(".repeat(200_000);
        assert_eq!(error(&hostile).0, "expression too deeply nested");
        let hostile = "sin(".repeat(100_000);
        assert_eq!(error(&hostile).0, "expression too deeply nested");
    }

    #[test]
    fn long_flat_chains_compile_without_recursion() {
        let sum = vec!["x"; 100_000].join(" + ");
        let expr = compile(&sum).unwrap();
        assert_eq!(expr.eval(&VALUES), 200_000.0);
        assert_eq!(expr.max_stack, 1);
        let conjunction = vec!["x > 1"; 20_000].join(" && ");
        assert_eq!(eval(&conjunction), 1.0);
    }

    #[test]
    fn stack_limit_and_the_large_stack_path() {
        // Each nested `clamp` keeps two more values on the stack.
        let clamps = |depth: usize| {
            let mut source = "z".to_owned();
            for _ in 0..depth {
                source = format!("clamp(x, y, {source})");
            }
            source
        };
        let deepest = compile(&clamps(31)).unwrap();
        assert_eq!(deepest.max_stack, 63);
        // clamp(2, 3, hi) is min(3, hi), and the innermost hi is z = -0.5.
        assert_eq!(deepest.eval(&VALUES), -0.5);
        let too_deep = clamps(32);
        assert_eq!(
            error(&too_deep),
            ("expression too deeply nested".to_owned(), 0..too_deep.len())
        );
        // Right-nested sums need one entry per level.
        let mut source = "x".to_owned();
        for _ in 0..20 {
            source = format!("x + ({source})");
        }
        let expr = compile(&source).unwrap();
        assert!(expr.max_stack > SMALL_STACK);
        assert_eq!(expr.eval(&VALUES), 42.0);
    }

    #[test]
    fn source_length_limit() {
        let source = "1".repeat(MAX_SOURCE_LEN + 1);
        assert_eq!(
            error(&source),
            (
                "expression is too long (the limit is 1 MiB)".to_owned(),
                0..source.len()
            )
        );
    }

    /// Deterministic xorshift generator, so the fuzz test needs no extra dependency.
    struct XorShift(u64);

    impl XorShift {
        fn below(&mut self, bound: usize) -> usize {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 % bound as u64) as usize
        }
    }

    fn check_never_panics(source: &str) {
        match compile(source) {
            Ok(expr) => {
                let value = expr.eval(&VALUES);
                if let Some(constant) = expr.constant() {
                    assert_same(value, constant, source);
                }
                assert!(expr.max_stack <= MAX_STACK, "{source}");
            }
            Err(err) => {
                assert!(err.span.start <= err.span.end, "{source}: {err:?}");
                assert!(err.span.end <= source.len(), "{source}: {err:?}");
                assert!(source.is_char_boundary(err.span.start), "{source}: {err:?}");
                assert!(source.is_char_boundary(err.span.end), "{source}: {err:?}");
                assert!(!err.message.is_empty());
            }
        }
    }

    /// Random syntactically plausible expression over the test names, with each name's
    /// literal value substituted into `folded` so that version reads no slot.
    fn random_expression(rng: &mut XorShift, budget: usize, vm: &mut String, folded: &mut String) {
        const ATOMS: &[(&str, &str)] = &[
            ("x", "(2)"),
            ("y", "(3)"),
            ("z", "(-0.5)"),
            ("pos.x", "(10)"),
            ("pos.y", "(-4)"),
            ("nan", "(0/0)"),
            ("0", "0"),
            ("1.5", "1.5"),
            ("pi", "pi"),
        ];
        const INFIX: &[&str] = &[
            "+", "-", "*", "/", "%", "^", "<", "<=", ">", ">=", "==", "!=", "&&", "||",
        ];
        const CALLS: &[(&str, usize)] = &[
            ("sin", 1),
            ("abs", 1),
            ("sign", 1),
            ("round", 1),
            ("sqrt", 1),
            ("atan2", 2),
            ("step", 2),
            ("pow", 2),
            ("clamp", 3),
            ("lerp", 3),
            ("smoothstep", 3),
            ("min", 1),
            ("max", 4),
        ];
        let both = |vm: &mut String, folded: &mut String, text: &str| {
            vm.push_str(text);
            folded.push_str(text);
        };
        let choice = if budget == 0 { 0 } else { rng.below(6) };
        match choice {
            0 => {
                let (name, value) = ATOMS[rng.below(ATOMS.len())];
                vm.push_str(name);
                folded.push_str(value);
            }
            1 | 2 => {
                random_expression(rng, budget / 2, vm, folded);
                both(vm, folded, &format!(" {} ", INFIX[rng.below(INFIX.len())]));
                random_expression(rng, budget / 2, vm, folded);
            }
            3 => {
                both(vm, folded, ["-", "!", "+"][rng.below(3)]);
                random_expression(rng, budget - 1, vm, folded);
            }
            4 => {
                both(vm, folded, "(");
                random_expression(rng, budget - 1, vm, folded);
                both(vm, folded, ")");
            }
            _ => {
                let (name, arity) = CALLS[rng.below(CALLS.len())];
                both(vm, folded, &format!("{name}("));
                for argument in 0..arity {
                    if argument > 0 {
                        both(vm, folded, ", ");
                    }
                    random_expression(rng, budget / arity, vm, folded);
                }
                both(vm, folded, ")");
            }
        }
    }

    #[test]
    fn stack_machine_agrees_with_constant_folding() {
        let mut rng = XorShift(0x2545_F491_4F6C_DD1D);
        let mut compiled = 0;
        for _ in 0..3000 {
            let (mut vm, mut folded) = (String::new(), String::new());
            random_expression(&mut rng, 12, &mut vm, &mut folded);
            match (compile(&vm), compile(&folded)) {
                (Ok(vm_expr), Ok(folded_expr)) => {
                    let constant = folded_expr
                        .constant()
                        .expect("substituted text is constant");
                    assert_same(vm_expr.eval(&VALUES), constant, &vm);
                    compiled += 1;
                }
                // Chained comparisons fail in both versions, with the same message.
                (Err(vm_err), Err(folded_err)) => assert_eq!(vm_err.message, folded_err.message),
                (vm_result, folded_result) => {
                    panic!("`{vm}` gave {vm_result:?} but `{folded}` gave {folded_result:?}")
                }
            }
        }
        assert!(compiled > 2000, "only {compiled} expressions compiled");
    }

    #[test]
    fn fuzz_compile_never_panics() {
        const TOKENS: &[&str] = &[
            "1",
            "2.5",
            ".5",
            "1e3",
            "1e",
            "0",
            "x",
            "y",
            "pos.x",
            "pos.",
            "foo",
            "pi",
            "e",
            "true",
            "sin",
            "min",
            "clamp",
            "smoothstep",
            "(",
            "(",
            ")",
            ")",
            ",",
            "+",
            "-",
            "*",
            "/",
            "%",
            "^",
            "!",
            "<",
            "<=",
            ">",
            ">=",
            "==",
            "!=",
            "&&",
            "||",
            "&",
            "|",
            "=",
            "#",
            "é",
            ".",
            " ",
            " ",
            "\t",
        ];
        const BYTES: &[u8] = b"0123456789.eExyzpos_()+-*/%^!<>=&|, #\t";
        let mut rng = XorShift(0x9E37_79B9_7F4A_7C15);
        for _ in 0..4000 {
            let length = rng.below(24);
            let source: String = (0..length)
                .map(|_| TOKENS[rng.below(TOKENS.len())])
                .collect();
            check_never_panics(&source);
            let raw: Vec<u8> = (0..rng.below(16))
                .map(|_| BYTES[rng.below(BYTES.len())])
                .collect();
            check_never_panics(&String::from_utf8_lossy(&raw));
        }
    }
}
