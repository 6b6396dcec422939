//! Criterion benchmarks for `graftal::rules::expr`: compiling and evaluating rule expressions.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use graftal::rules::expr::{Expr, SlotNames};

const NAMES: &[&str] = &[
    "normal.z",
    "center.x",
    "width",
    "a",
    "b",
    "random",
    "pre.length",
];
const SLOTS: [f64; 7] = [0.9, -1.0, 6.0, 1.0, 3.0, 0.25, 2.0];

/// (benchmark name, source); the first two have ten syntax-tree nodes each.
const CASES: &[(&str, &str)] = &[
    (
        "condition_10_nodes",
        "normal.z > 0.5 && abs(center.x) < width / 3",
    ),
    (
        "arithmetic_10_nodes",
        "lerp(a, b, random) * 0.6 + pre.length ^ 2",
    ),
    ("scale_3_nodes", "0.6 * pre.length"),
    (
        "mixed_24_nodes",
        "clamp(smoothstep(0, width, abs(center.x)) * 2 - 1, -1, 1) + max(a, b, random) % 0.5 * sin(pre.length * pi)",
    ),
];

fn eval(c: &mut Criterion) {
    let names = SlotNames(NAMES);
    let mut group = c.benchmark_group("expr_eval");
    for &(name, source) in CASES {
        let expr = Expr::compile(source, &names).expect("benchmark expression compiles");
        group.bench_function(name, |bench| {
            bench.iter(|| black_box(&expr).eval(black_box(&SLOTS)))
        });
    }
    group.finish();
}

fn compile(c: &mut Criterion) {
    let names = SlotNames(NAMES);
    let mut group = c.benchmark_group("expr_compile");
    for &(name, source) in CASES {
        group.bench_function(name, |bench| {
            bench.iter(|| Expr::compile(black_box(source), &names))
        });
    }
    group.finish();
}

criterion_group!(benches, eval, compile);
criterion_main!(benches);
