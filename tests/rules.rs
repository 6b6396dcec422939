//! Rule-language tests through the library: one schema in two formats,
//! parameter distributions, overrides, and stream independence.

use std::path::Path;

use graftal::grammar::{run, RunOptions};
use graftal::rules::compile::{compile, parse};
use graftal::rules::diagnostic::SourceFile;
use graftal::rules::spanned::SourceFormat;
use graftal::rules::{Override, Program, RuleError};

fn program(text: &str, format: SourceFormat, overrides: &[Override]) -> Result<Program, RuleError> {
    let file = SourceFile {
        name: "test".into(),
        text: text.into(),
    };
    let ast = parse(&file, format)?;
    compile(&file, &ast, overrides, Path::new("."))
}

fn toml(text: &str) -> Program {
    program(text, SourceFormat::Toml, &[]).unwrap_or_else(|e| panic!("{}", e.headline()))
}

fn params(p: &Program, seed: u64) -> Vec<(String, f64)> {
    run(
        p,
        &RunOptions {
            seed: Some(seed),
            ..RunOptions::default()
        },
    )
    .unwrap()
    .params
}

fn param(p: &Program, seed: u64, name: &str) -> f64 {
    params(p, seed)
        .into_iter()
        .find(|(n, _)| n == name)
        .unwrap()
        .1
}

#[test]
fn toml_and_ron_are_one_schema() {
    let t = toml(
        r#"
seed = 4
[params]
w = { uniform = [1, 2] }
h = "w * 2"
[start]
cube = { size = "w" }
[[step]]
select = "normal.z > 0.5"
inset_faces = { thickness = 0.1 }
[[step]]
name = "up"
select = "normal.z > 0.5 && area > 0.5"
extrude_faces = { offset = [0, 0, "h"] }
"#,
    );
    let r = program(
        r#"(
    seed: 4,
    params: (w: (uniform: [1, 2]), h: "w * 2"),
    start: (cube: (size: "w")),
    step: [
        (select: "normal.z > 0.5", inset_faces: (thickness: 0.1)),
        (name: "up", select: "normal.z > 0.5 && area > 0.5", extrude_faces: (offset: [0, 0, "h"])),
    ],
)"#,
        SourceFormat::Ron,
        &[],
    )
    .unwrap_or_else(|e| panic!("{}", e.headline()));
    let a = run(&t, &RunOptions::default()).unwrap();
    let b = run(&r, &RunOptions::default()).unwrap();
    assert_eq!(a.seed, 4);
    assert_eq!(a.mesh.to_indexed(), b.mesh.to_indexed());
    assert_eq!(a.params, b.params);
    assert_eq!(
        a.steps.last().unwrap().matched,
        1,
        "only the inner top face is large; the inset ring is thin"
    );
}

#[test]
fn distributions_stay_in_range_and_vary_with_the_seed() {
    let p = toml(
        r#"
[params]
u = { uniform = [2, 3] }
n = { normal = [0, 1], clamp = [-0.5, 0.5] }
k = { int = [3, 5] }
c = { choice = [10, 20, 30], weights = [0, 1, 0] }
d = { choice = [1, 2] }
"#,
    );
    let mut seen_k = [false; 3];
    let mut distinct_u = std::collections::BTreeSet::new();
    for seed in 0..200 {
        let v = params(&p, seed);
        let get = |n: &str| v.iter().find(|(k, _)| k == n).unwrap().1;
        assert!((2.0..3.0).contains(&get("u")));
        assert!((-0.5..=0.5).contains(&get("n")));
        let k = get("k");
        assert_eq!(k.fract(), 0.0);
        seen_k[(k - 3.0) as usize] = true;
        assert_eq!(get("c"), 20.0, "zero weights are never chosen");
        assert!(get("d") == 1.0 || get("d") == 2.0);
        distinct_u.insert(get("u").to_bits());
    }
    assert_eq!(seen_k, [true; 3], "inclusive integer range");
    assert_eq!(distinct_u.len(), 200);
}

#[test]
fn parameters_resolve_in_dependency_order() {
    let p = toml("[params]\na = \"b + c\"\nb = \"c * 2\"\nc = 3\n");
    assert_eq!(param(&p, 0, "a"), 9.0);
    assert_eq!(p.param_names, vec!["a", "b", "c"], "slots in name order");
}

#[test]
fn adding_a_parameter_leaves_other_draws_unchanged() {
    let one = toml("[params]\nx = { uniform = [0, 1] }\n");
    let two = toml("[params]\nfirst = { uniform = [0, 1] }\nx = { uniform = [0, 1] }\n");
    for seed in 0..20 {
        assert_eq!(param(&one, seed, "x"), param(&two, seed, "x"));
    }
}

#[test]
fn overrides_replace_definitions_and_are_checked() {
    let text = "[params]\nw = { uniform = [0, 1] }\nd = \"w * 2\"\n";
    let set = |name: &str, value: &str| Override {
        name: name.into(),
        value: value.into(),
    };
    let p = program(text, SourceFormat::Toml, &[set("w", "0.25")]).unwrap();
    assert_eq!(param(&p, 9, "d"), 0.5);
    let p = program(text, SourceFormat::Toml, &[set("d", "w + 100")]).unwrap();
    assert!(param(&p, 9, "d") >= 100.0);
    let e = program(text, SourceFormat::Toml, &[set("zz", "1")]).unwrap_err();
    assert!(
        e.message.contains("no parameter named `zz`"),
        "{}",
        e.message
    );
    let e = program(text, SourceFormat::Toml, &[set("w", "1 +")]).unwrap_err();
    assert!(e.location.starts_with("--set w"), "{}", e.location);
    assert_eq!(Override::parse("a = 2").unwrap(), set("a", "2"));
    assert!(Override::parse("a").is_err());
}

#[test]
fn semantic_errors_are_located() {
    let cases = [
        ("[params]\nlength = 1\n", "test:2:1", "reserved"),
        ("[params]\nx = { uniform = [0, 1], int = [1, 2] }\n", "test:2:5", "exactly one of"),
        ("[params]\nx = { choice = [1, 2], weights = [1] }\n", "test:2:5", "has 2 values but `weights` has 1"),
        ("[start]\ncube = {}\n[[step]]\nname = \"a\"\ncube = {}\n[[step]]\nname = \"a\"\ncube = {}\n", "test:7:9", "two steps are named `a`"),
        ("[start]\nextrude_faces = {}\n", "test:2:1", "must be a create operator"),
        ("[[step]]\nselect = \"id > 1\"\ncube = {}\n", "test:3:1", "takes no `select`"),
        ("[[step]]\non = \"verts\"\ninset_faces = { thickness = 1 }\n", "test:2:", "works on faces"),
        ("[[step]]\ncube = {}\ngrid = {}\n", "test:3:1", "both `cube` and `grid`"),
        ("[[step]]\nextrude_faces = { offset = [0, 0, 1], distance = 2 }\n", "test:2:", "either `offset` or `distance`"),
        ("[[step]]\ncube = { size = \"area * 2\" }\n", "test:2:18", "unknown name `area`"),
        ("[params]\nwidth = 1\n[[step]]\nselect = \"widht > 1\"\ninset_faces = { thickness = 1 }\n", "test:4:11", "unknown name `widht`"),
        ("[[step]]\ntranslate = { offset = [1, 2] }\n", "test:2:", "3 components"),
    ];
    for (text, location, message) in cases {
        let e = program(text, SourceFormat::Toml, &[]).unwrap_err();
        assert!(
            e.location.starts_with(location),
            "{text}: {} (wanted {location})",
            e.location
        );
        assert!(e.message.contains(message), "{text}: {}", e.message);
    }
    let e = program(
        "[params]\nwidth = 1\n[start]\ncube = { size = \"widht\" }\n",
        SourceFormat::Toml,
        &[],
    )
    .unwrap_err();
    assert_eq!(e.help.as_deref(), Some("did you mean `width`?"));
}

#[test]
fn conditions_select_by_element_properties() {
    // 5×5 grid: interior faces have 8 vertex-sharing and 4 edge-sharing neighbours.
    let p = toml(
        r#"
[start]
grid = { segments = [5, 5], size = [5, 5] }
[[step]]
name = "interior"
select = "vert_neighbors == 8 && neighbors == 4"
region_extend = {}
[[step]]
name = "corners"
select = "neighbors == 2"
region_reduce = {}
[[step]]
name = "random-half"
select = "random < 0.5"
region_extend = { by = "vert" }
"#,
    );
    let out = run(&p, &RunOptions::default()).unwrap();
    assert_eq!(out.steps[1].matched, 9);
    assert_eq!(out.steps[2].matched, 4);
    let half = out.steps[3].matched;
    assert!((5..=20).contains(&half), "about half of 25: {half}");
    let again = run(&p, &RunOptions::default()).unwrap();
    assert_eq!(
        again.steps[3].matched, half,
        "random is a pure function of seed, step and id"
    );
    let counts: std::collections::BTreeSet<usize> = (0..10)
        .map(|seed| {
            run(
                &p,
                &RunOptions {
                    seed: Some(seed),
                    ..RunOptions::default()
                },
            )
            .unwrap()
            .steps[3]
                .matched
        })
        .collect();
    assert!(
        counts.len() > 1,
        "other seeds draw other subsets: {counts:?}"
    );
}
