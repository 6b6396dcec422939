//! Tests of the expression language.

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
