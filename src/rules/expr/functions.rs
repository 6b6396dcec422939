//! The functions, operators and constants of the expression language, and
//! how each evaluates (through `libm`, so every platform gets the same bits).

use super::*;

pub(super) fn from_bool(value: bool) -> f64 {
    if value {
        1.0
    } else {
        0.0
    }
}

pub(super) fn truthy(value: f64) -> bool {
    value != 0.0
}

pub(super) const DEGREES_TO_RADIANS: f64 = PI / 180.0;
pub(super) const RADIANS_TO_DEGREES: f64 = 180.0 / PI;

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

    pub(super) fn yields_boolean(self) -> bool {
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

    pub(super) fn yields_boolean(self) -> bool {
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
pub(super) fn floored_rem(x: f64, y: f64) -> f64 {
    let rem = libm::fmod(x, y);
    if rem == 0.0 {
        libm::copysign(0.0, y)
    } else if (rem < 0.0) != (y < 0.0) {
        rem + y
    } else {
        rem
    }
}

pub(super) fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        x
    }
}

pub(super) fn clamp(x: f64, lo: f64, hi: f64) -> f64 {
    libm::fmin(libm::fmax(x, lo), hi)
}

pub(super) fn step(edge: f64, x: f64) -> f64 {
    from_bool(x >= edge)
}

pub(super) fn smoothstep(edge0: f64, edge1: f64, x: f64) -> f64 {
    // Equal edges would divide by zero; the limit of a vanishing ramp is a step.
    if edge0 == edge1 {
        return step(edge0, x);
    }
    let t = clamp((x - edge0) / (edge1 - edge0), 0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

pub(super) fn builtin_constant(name: &str) -> Option<f64> {
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
pub(super) enum Callee {
    Unary(Unary),
    Binary(Binary),
    Ternary(Ternary),
    /// One or more arguments folded pairwise from the left.
    Variadic(Binary),
}

pub(super) const FUNCTIONS: &[(&str, Callee)] = &[
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

pub(super) fn function(name: &str) -> Option<Callee> {
    FUNCTIONS
        .iter()
        .find(|(known, _)| *known == name)
        .map(|&(_, callee)| callee)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Infix {
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
pub(super) const PREFIX_BINDING_POWER: u8 = 13;

impl Infix {
    /// Left and right binding powers; a higher right power makes the operator
    /// left-associative, a lower one right-associative.
    pub(super) fn binding_power(self) -> (u8, u8) {
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

    pub(super) fn is_comparison(self) -> bool {
        matches!(
            self,
            Infix::Eq | Infix::Ne | Infix::Lt | Infix::Le | Infix::Gt | Infix::Ge
        )
    }
}
