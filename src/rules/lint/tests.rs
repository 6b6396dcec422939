//! Tests of the linter.

use super::*;
use crate::rules::expr::SlotNames;

/// (can be false, can be true) of `source` over x (any finite), n (an
/// integer ≥ 0), r in [0, 1) and c in [−1, 1].
fn truth(source: &str) -> (bool, bool) {
    let names = SlotNames(&["x", "n", "r", "c"]);
    let expr = Expr::compile(source, &names).unwrap();
    let env = [
        Interval::finite(),
        Interval::new(0.0, f64::INFINITY),
        Interval::new(0.0, next_down(1.0)),
        Interval::new(-1.0, 1.0),
    ];
    let integer = [false, true, false, false];
    Analysis { integer: &integer }
        .eval(&expr.tree(), &env)
        .truth()
}

#[test]
fn impossible_conditions_are_never_true() {
    for source in [
        "x > 1 && x < 0",
        "x >= 1 && x < 1",
        "n < 0",
        "r >= 1",
        "r > 1",
        "c > 1",
        "abs(x) < 0",
        "n > 2 && n < 3",
        "!(x < 1) && x < 0",
        "(x > 1 || x < -1) && abs(x) < 0.5",
        "1 < 0",
        "x < 0 && (c > 2 || x > 5)",
        "sqrt(abs(x)) < 0",
        "sin(x) > 1",
        "n == 0.5",
        "false",
    ] {
        assert!(!truth(source).1, "{source} can be true");
    }
}

#[test]
fn possible_conditions_are_not_flagged() {
    for source in [
        "x > 1 || x < 0",
        "x > 1 && x < 2",
        "n == 8",
        "r < 0.5",
        "abs(c - 0.5) < 0.1",
        "n > 2 && n < 4",
        "!(c < -0.5 && abs(x - 0.5) < 0.1)",
        "x == 0",
        "x / x",
        "ln(x) < 0 || ln(x) >= 0",
        "x % 2 == 1",
        "n - 3 == 0",
        "x ^ 2 < 1",
    ] {
        assert!(truth(source).1, "{source} is flagged as never true");
    }
}

#[test]
fn tautologies_are_always_true() {
    for source in [
        "r < 1",
        "n >= 0",
        "c <= 1 && c >= -1",
        "x > 1 || x <= 1",
        "abs(x) >= 0",
    ] {
        assert_eq!(truth(source), (false, true), "{source}");
    }
    assert_eq!(truth("x > 1 || x < 1"), (true, true));
}
