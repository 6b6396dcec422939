//! Rule-file tooling and shell integration: `schema` (validated with a real
//! JSON-Schema validator against every example and against targeted bad
//! files, and kept in step with the compiler), `lint`, `explain`,
//! `completions`, `man`.

mod common;
use common::{examples, graftal, stderr, stdout};

use std::path::Path;

use graftal::rules::compile;
use graftal::rules::diagnostic::SourceFile;
use graftal::rules::schema;
use graftal::rules::spanned::SourceFormat;
use serde_json::Value;

/// The subcommands completions and the man page must list.
const COMMANDS: &[&str] = &[
    "run",
    "check",
    "info",
    "convert",
    "schema",
    "lint",
    "explain",
    "completions",
    "man",
    "manifest",
    "verify",
];

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn validator() -> jsonschema::Validator {
    jsonschema::draft7::new(&schema::schema()).expect("the schema is a valid draft-07 schema")
}

fn errors(v: &jsonschema::Validator, instance: &Value) -> Vec<String> {
    v.iter_errors(instance)
        .map(|e| format!("{} at {}", e, e.instance_path()))
        .collect()
}

fn toml_json(text: &str) -> Value {
    schema::to_json(text, SourceFormat::Toml).expect("valid TOML")
}

// ---- schema ----------------------------------------------------------------

#[test]
fn schema_command_prints_the_committed_schema() {
    let o = graftal(&["schema"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let committed = std::fs::read_to_string(root().join("docs/graftal.schema.json"))
        .expect("docs/graftal.schema.json is committed");
    assert!(
        stdout(&o) == committed,
        "docs/graftal.schema.json is out of date: run `graftal schema > docs/graftal.schema.json`"
    );
    let parsed: Value = serde_json::from_str(&committed).unwrap();
    assert_eq!(parsed["$schema"], "http://json-schema.org/draft-07/schema#");
}

#[test]
fn every_example_validates_against_the_schema() {
    let v = validator();
    let mut files = examples();
    files.extend(
        std::fs::read_dir(root().join("benches"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml")),
    );
    for path in files {
        let file = graftal::rules::diagnostic::SourceFile {
            name: path.display().to_string(),
            text: std::fs::read_to_string(&path).unwrap(),
        };
        let json = schema::file_to_json(&file).expect("example converts to JSON");
        let errs = errors(&v, &json);
        assert!(errs.is_empty(), "{}: {errs:#?}", path.display());
    }
}

#[test]
fn ron_and_toml_of_one_file_give_the_same_json() {
    let toml = r#"
        seed = 3
        [params]
        w = 0.5
        [start]
        cube = { size = "w" }
        [[step]]
        select = "normal.z > 0.5"
        triangulate = {}
    "#;
    let ron = r#"(seed: 3, params: (w: 0.5), start: (cube: (size: "w")),
        step: [(select: "normal.z > 0.5", triangulate: ())])"#;
    assert_eq!(
        schema::to_json(toml, SourceFormat::Toml).unwrap(),
        schema::to_json(ron, SourceFormat::Ron).unwrap()
    );
}

/// Files the parser or compiler rejects for a reason the schema can see.
#[test]
fn bad_files_fail_validation() {
    let v = validator();
    let base = "[start]\ncube = {}\n";
    let cases = [
        (
            "typo'd step key",
            "[[step]]\nselct = \"area > 1\"\ninset_faces = { thickness = 0.1 }\n",
        ),
        (
            "typo'd operator key",
            "[[step]]\nextrude_face = { distance = 1 }\n",
        ),
        (
            "typo'd operator parameter",
            "[[step]]\nextrude_faces = { distnce = 1 }\n",
        ),
        ("typo'd top-level key", "polcy = \"merge\"\n"),
        ("bad policy", "policy = \"merg\"\n"),
        (
            "cancel at file level",
            "on_intersection = \"cancel_compound\"\n",
        ),
        (
            "bad on_intersection",
            "[[step]]\non = \"verts\"\ncreate_edge = {}\non_intersection = \"abort\"\n",
        ),
        (
            "bad on",
            "[[step]]\non = \"nodes\"\ntranslate = { offset = 1 }\n",
        ),
        (
            "on not allowed for the operator",
            "[[step]]\non = \"faces\"\ncreate_edge = {}\n",
        ),
        (
            "two operators",
            "[[step]]\ntriangulate = {}\nreverse = {}\n",
        ),
        ("no operator", "[[step]]\nname = \"x\"\n"),
        (
            "missing required parameter",
            "[[step]]\ninset_faces = { depth = 0.1 }\n",
        ),
        (
            "select on a create operator",
            "[[step]]\nselect = \"id > 0\"\ncube = {}\n",
        ),
        (
            "policy on a kernel operator",
            "[[step]]\npolicy = \"merge\"\ntriangulate = {}\n",
        ),
        (
            "tolerance without merge",
            "[[step]]\non = \"verts\"\ntolerance = 0.1\ncreate_edge = {}\n",
        ),
        (
            "probability above 1",
            "[[step]]\ncreate_edge = { probability = 1.5 }\n",
        ),
        (
            "negative spread",
            "[[step]]\ncreate_edge = { vary_turn = -1 }\n",
        ),
        (
            "nodes outside split_face",
            "[[step]]\ncreate_edge = { nodes = \"id > 0\" }\n",
        ),
        (
            "bad delete mode",
            "[[step]]\ndelete = { mode = \"everything\" }\n",
        ),
        (
            "offset and distance",
            "[[step]]\nextrude_faces = { offset = 1, distance = 1 }\n",
        ),
        (
            "vector of two",
            "[[step]]\ntranslate = { offset = [1, 2] }\n",
        ),
        ("repeat 0", "[[step]]\nrepeat = 0\ntriangulate = {}\n"),
        (
            "compound without on",
            "[compound.c]\nstep = [{ triangulate = {} }]\n",
        ),
        ("compound without steps", "[compound.c]\non = \"faces\"\n"),
        (
            "create inside a compound",
            "[compound.c]\non = \"faces\"\nstep = [{ cube = {} }]\n",
        ),
        (
            "two distributions",
            "[params]\nw = { uniform = [0, 1], int = [0, 2] }\n",
        ),
        (
            "weights without choice",
            "[params]\nw = { uniform = [0, 1], weights = [1] }\n",
        ),
        ("reserved parameter name", "[params]\narea = 1\n"),
        ("tolerance above 1", "tolerance = 2\n"),
        ("negative seed", "seed = -1\n"),
        (
            "step named with a slash",
            "[[step]]\nname = \"a/b\"\ntriangulate = {}\n",
        ),
    ];
    for (what, extra) in cases {
        let text = format!("{extra}{base}");
        // The parser or compiler rejects each of them too.
        let file = SourceFile {
            name: "bad.toml".into(),
            text: text.clone(),
        };
        let compiled = compile::parse(&file, SourceFormat::Toml)
            .and_then(|ast| compile::compile(&file, &ast, &[], Path::new(".")));
        assert!(compiled.is_err(), "{what}: graftal accepts it");
        let json = toml_json(&text);
        assert!(
            !validator().is_valid(&json) && !v.is_valid(&json),
            "{what}: the schema accepts it"
        );
    }
}

/// Minimal valid value of every operator.
/// What every operator's example needs besides a cube: a NURBS surface
/// named `patch` (the example's import names `mesh.obj`, which compiling
/// does not read).
const EXAMPLE_CONTEXT: &str =
    "[nurbs.patch]\ndegree = [1, 1]\nsize = [2, 2]\npoints = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]\n";

/// For every operator and every `on` value and step key, the schema accepts
/// a step exactly when the compiler does.
#[test]
fn schema_agrees_with_the_compiler_on_every_operator() {
    let v = validator();
    let mut mismatches = Vec::new();
    let variants = [
        "",
        "on = \"verts\"\n",
        "on = \"edges\"\n",
        "on = \"faces\"\n",
        "select = \"id >= 0\"\n",
        "from = \"first\"\n",
        "policy = \"merge\"\n",
        "policy = \"intersect\"\n",
        "policy = \"merge\"\ntolerance = 0.01\n",
        "policy = \"none\"\ntolerance = 0.01\n",
        "on_intersection = \"skip\"\n",
        "repeat = 2\n",
    ];
    for def in graftal::rules::operators::OPERATORS {
        let op = def.name;
        assert!(
            def.example.starts_with('{') && def.example.ends_with('}'),
            "`{op}`: its registry example is an inline table"
        );
        // An operator that tags its products is sampled with a part (which
        // `assign` needs); one that does not must refuse one.
        let tagged = |part: &str| {
            format!(
                "[start]\ncube = {{}}\n[[step]]\n{part}{op} = {}\n{EXAMPLE_CONTEXT}",
                def.example
            )
        };
        if !def.tags {
            let text = tagged("part = \"sample\"\n");
            let file = SourceFile {
                name: "t.toml".into(),
                text,
            };
            let result = compile::parse(&file, SourceFormat::Toml)
                .and_then(|ast| compile::compile(&file, &ast, &[], Path::new(".")));
            match result {
                Err(e) if e.headline().contains("creates no faces") => {}
                other => mismatches.push(format!(
                    "`{op}` says it tags nothing, but a part on it: {:?}",
                    other.err().map(|e| e.headline())
                )),
            }
        }
        let part = if def.tags { "part = \"sample\"\n" } else { "" };
        for variant in variants {
            let text = format!(
                "[start]\ncube = {{}}\n[[step]]\nname = \"first\"\ntriangulate = {{}}\n[[step]]\n{variant}{part}{op} = {}\n{EXAMPLE_CONTEXT}",
                def.example
            );
            let file = SourceFile {
                name: "t.toml".into(),
                text: text.clone(),
            };
            let compiled = compile::parse(&file, SourceFormat::Toml)
                .and_then(|ast| compile::compile(&file, &ast, &[], Path::new(".")));
            let valid = v.is_valid(&toml_json(&text));
            // Every row's example compiles (building its typed arguments:
            // a field the registry and `OpArgs` disagree on panics here)
            // and is valid to the schema.
            if variant.is_empty() && !(compiled.is_ok() && valid) {
                mismatches.push(format!(
                    "`{op}`'s registry example {}: compiler {}, schema {}",
                    def.example,
                    compiled
                        .as_ref()
                        .err()
                        .map_or("accepts".into(), |e| e.headline()),
                    if valid { "accepts" } else { "rejects" },
                ));
            }
            if compiled.is_ok() != valid {
                mismatches.push(format!(
                    "{op} with {variant:?}: compiler {}, schema {} ({})",
                    if compiled.is_ok() {
                        "accepts"
                    } else {
                        "rejects"
                    },
                    if valid { "accepts" } else { "rejects" },
                    compiled.err().map_or(String::new(), |e| e.headline()),
                ));
            }
        }
    }
    assert!(mismatches.is_empty(), "{mismatches:#?}");
}

// ---- lint ------------------------------------------------------------------

#[test]
fn every_example_lints_clean() {
    let mut args = vec!["lint".to_owned()];
    args.extend(examples().iter().map(|p| p.display().to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = graftal(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("warning["), "{}", stderr(&o));
}

#[test]
fn lint_finds_each_kind_of_mistake_at_its_location() {
    let o = graftal(&["lint", "fixtures/lint/warnings.toml"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    let f = "fixtures/lint/warnings.toml";
    for expected in [
        format!("{f}:6:1: warning[unused-param]: parameter `unused` is never used"),
        format!("{f}:13:8: warning[unused-rule]: rule `orphan` is never included"),
        format!("{f}:16:11: warning[unused-compound]: compound `lonely` is never called"),
        format!("{f}:22:11: warning[never-true]: `select` condition `pos.z > 1 && pos.z < 0` can never be true"),
        format!("{f}:27:11: warning[never-true]: `select` condition `area < 0 || sides < 3` can never be true"),
        format!("{f}:32:11: warning[never-true]: `select` condition `random >= 1` can never be true"),
        format!("{f}:37:11: warning[always-true]: `select` condition `faces >= 0` is always true"),
        format!("{f}:38:30: warning[probability-range]: `probability` can be outside [0, 1]: it ranges over [0.5, 1.5]"),
        format!("{f}:41:11: warning[never-true]: `select` condition `(center.x > 1 || center.x < -1) && abs(center.x) < 0.5` can never be true"),
        format!("{f}:42:39: warning[never-true]: `nodes` condition `degree < 0` can never be true"),
        format!("{f}:36:1: warning[unnamed-random-step]: this step draws random values but has no `name`"),
        "fixtures/lint/warnings.toml: 11 warnings".to_owned(),
    ] {
        assert!(err.contains(&expected), "missing {expected:?} in\n{err}");
    }
    assert_eq!(err.matches("warning[").count(), 11, "{err}");
    // The parameters used in conditions (`scoped == 0`) are not flagged.
    assert!(!err.contains("scoped"), "{err}");

    // --allow silences a code; the rest still counts.
    let o = graftal(&[
        "lint",
        "fixtures/lint/warnings.toml",
        "--allow",
        "never-true",
        "--allow",
        "always-true",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains(": 5 warnings"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("never-true"));
    let o = graftal(&[
        "lint",
        "fixtures/lint/warnings.toml",
        "--allow",
        "no-such-code",
    ]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn lint_reports_every_undefined_name_and_exits_2() {
    let o = graftal(&["lint", "fixtures/lint/undefined.toml", "rules/tree.toml"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    let f = "fixtures/lint/undefined.toml";
    for expected in [
        format!("{f}:3:10: error[undefined-name]: `widht` is no parameter"),
        "did you mean `width`?".to_owned(),
        format!("{f}:7:22: error[undefined-name]: `wdth` is no parameter or element property"),
        format!("{f}:7:30: error[undefined-name]: `lenght` is no parameter or element property"),
        format!("{f}:8:30: error[undefined-name]: `area` is no parameter"),
        "rules/tree.toml: ok".to_owned(),
        "error: 1 of 2 rule files does not compile".to_owned(),
    ] {
        assert!(err.contains(&expected), "missing {expected:?} in\n{err}");
    }
}

#[test]
fn lint_of_a_broken_or_missing_file_exits_2_with_a_location() {
    for (file, expected) in [
        ("fixtures/bad/syntax.toml", "fixtures/bad/syntax.toml:"),
        ("fixtures/bad/unknown-key.toml", "unknown field `colour`"),
        ("fixtures/bad/param-cycle.toml", "cycle"),
        ("no/such/file.toml", "cannot read rule file"),
        ("Cargo.lock", "must end in .toml or .ron"),
    ] {
        let o = graftal(&["lint", file]);
        assert_eq!(o.status.code(), Some(2), "{file}: {}", stderr(&o));
        assert!(stderr(&o).contains(expected), "{file}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"), "{file}");
    }
    let o = graftal(&["lint"]);
    assert_eq!(o.status.code(), Some(2));
}

// ---- explain ---------------------------------------------------------------

#[test]
fn explain_json_agrees_with_run_stats_for_every_example() {
    let dir = tempfile::tempdir().unwrap();
    for path in examples() {
        let p = path.display().to_string();
        let out = dir.path().join("m.obj").display().to_string();
        let o = graftal(&["run", &p, "-o", &out, "--stats", "-"]);
        assert!(o.status.success(), "{p}: {}", stderr(&o));
        let stats: Value = serde_json::from_slice(&o.stdout).unwrap();
        let o = graftal(&["explain", &p, "--json"]);
        assert!(o.status.success(), "{p}: {}", stderr(&o));
        let explain: Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(explain["rule_hash"], stats["rule_hash"], "{p}");
        assert_eq!(explain["vertices"], stats["mesh"]["vertices"], "{p}");
        // Every step that ran, with the same counts, in the same order.
        let mut ran: Vec<&Value> = explain["steps"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|s| s["ran"] == true)
            .collect();
        let stat_steps = stats["steps"].as_array().unwrap();
        assert_eq!(ran.len(), stat_steps.len(), "{p}");
        // Explain lists compound contents after their call; stats by generation.
        ran.sort_by_key(|s| s["generation"].as_u64().unwrap());
        for (e, s) in ran.iter().zip(stat_steps) {
            for key in [
                "name",
                "op",
                "runs",
                "candidates",
                "matched",
                "applied",
                "skipped_by_probability",
                "shared",
                "merged",
                "rejected_by_intersection",
                "cancelled",
                "created_vertices",
                "created_edges",
                "created_faces",
            ] {
                assert_eq!(e[key], s[key], "{p}: step {} {key}", s["name"]);
            }
            let (c, m) = (e["candidates"].as_u64(), e["matched"].as_u64());
            assert_eq!(
                e["condition_false"].as_u64(),
                Some(c.unwrap() - m.unwrap()),
                "{p}"
            );
            assert!(
                e["location"].as_str().unwrap().starts_with(&p),
                "{p}: {}",
                e["location"]
            );
        }
    }
}

#[test]
fn explain_text_breaks_down_what_was_not_applied() {
    let o = graftal(&["explain", "rules/flags.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.starts_with("rules/flags.toml (seed "), "{text}");
    assert!(
        text.contains("flags (create_face) at rules/flags.toml:"),
        "{text}"
    );
    assert!(text.contains("rejected by intersection"), "{text}");
    assert!(text.contains("(condition false)"), "{text}");
    // Deterministic.
    assert_eq!(stdout(&graftal(&["explain", "rules/flags.toml"])), text);

    let o = graftal(&["explain", "rules/tree.toml", "--seed", "7"]);
    assert!(
        stdout(&o).contains("skipped by probability"),
        "{}",
        stdout(&o)
    );

    // Compound contents are listed under the call, with their runs summed.
    let o = graftal(&["explain", "rules/grid-scope.toml"]);
    let text = stdout(&o);
    assert!(
        text.contains("\n  nine/peak (split_face) at rules/grid-scope.toml:35:"),
        "{text}"
    );
    assert!(
        text.contains("shared (applied from another scope already"),
        "{text}"
    );

    // --set changes the run: the top-level split now matches.
    let o = graftal(&[
        "explain",
        "rules/grid-scope.toml",
        "--set",
        "scoped=0",
        "--json",
    ]);
    let json: Value = serde_json::from_slice(&o.stdout).unwrap();
    let top = json["steps"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == "peak_top_level")
        .unwrap();
    assert_eq!(top["matched"], 4);
}

#[test]
fn explain_bad_input_exits_with_the_run_codes() {
    let o = graftal(&["explain", "fixtures/bad/unknown-name.toml"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("fixtures/bad/unknown-name.toml:"));
    let o = graftal(&["explain", "rules/tree.toml", "--set", "nope=1"]);
    assert_eq!(o.status.code(), Some(2));
    let o = graftal(&["explain", "fixtures/bad/runtime-negative-size.toml"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let o = graftal(&["explain", "rules/sofa.toml", "--max-primitives", "100"]);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
}

// ---- completions and man page ----------------------------------------------

#[test]
fn completions_cover_every_command() {
    for (shell, marker) in [
        ("bash", "complete -F"),
        ("zsh", "#compdef graftal"),
        ("fish", "complete -c graftal"),
    ] {
        let o = graftal(&["completions", shell]);
        assert!(o.status.success(), "{shell}: {}", stderr(&o));
        let script = stdout(&o);
        assert!(script.contains(marker), "{shell}");
        for command in COMMANDS {
            assert!(
                script.contains(command),
                "{shell} completion lacks {command}"
            );
        }
    }
    let o = graftal(&["completions", "tcsh"]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn man_page_is_roff_listing_every_command() {
    let o = graftal(&["man"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let page = stdout(&o);
    assert!(
        page.starts_with(".ie \\n(.g .ds Aq") || page.contains(".TH graftal 1"),
        "{page}"
    );
    assert!(page.contains(".TH graftal 1"), "{page}");
    for command in COMMANDS {
        assert!(
            page.contains(&format!("graftal\\-{command}")),
            "man page lacks {command}"
        );
    }

    let dir = tempfile::tempdir().unwrap();
    let o = graftal(&["man", "--dir", dir.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    for page in [
        "graftal.1",
        "graftal-run.1",
        "graftal-lint.1",
        "graftal-explain.1",
    ] {
        let text = std::fs::read_to_string(dir.path().join(page)).unwrap();
        assert!(text.contains(".TH graftal"), "{page}");
    }
    let run = std::fs::read_to_string(dir.path().join("graftal-run.1")).unwrap();
    assert!(run.contains("max\\-primitives"), "{run}");
    let o = graftal(&["man", "--dir", "no/such/dir"]);
    assert_eq!(o.status.code(), Some(2));
}

/// Every registered operator has a row in the rule reference.
#[test]
fn every_operator_is_documented() {
    let docs = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/rules.md"),
    )
    .unwrap();
    for op in graftal::rules::operators::names() {
        assert!(
            docs.contains(&format!("\n| `{op}` |")),
            "docs/rules.md has no row for `{op}`"
        );
    }
}

/// Every element property has a row in the rule reference.
#[test]
fn every_property_is_documented() {
    let docs = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/rules.md"),
    )
    .unwrap();
    for row in graftal::rules::property::ROWS {
        let shown = match row.name.rsplit_once('.') {
            Some((base, "x" | "y" | "z")) => format!("| `{base}.x/y/z` |"),
            _ => format!("| `{}` |", row.name),
        };
        assert!(
            docs.contains(&shown),
            "docs/rules.md has no row for `{}`",
            row.name
        );
    }
}

/// The fuzzer's dictionary knows every operator, parameter and property
/// (the file is kept by hand; this test keeps it complete).
#[test]
fn the_fuzz_dictionary_is_current() {
    let dict = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/rules.dict"),
    )
    .unwrap();
    let mut missing = Vec::new();
    let words = graftal::rules::operators::OPERATORS
        .iter()
        .flat_map(|d| std::iter::once(d.name).chain(d.params.iter().map(|p| p.key)))
        .chain(graftal::rules::property::ROWS.iter().map(|r| r.name));
    for word in words {
        if !dict.contains(&format!("\"{word}\"")) {
            missing.push(word);
        }
    }
    missing.sort();
    missing.dedup();
    assert!(
        missing.is_empty(),
        "fuzz/rules.dict lacks {missing:?}: add each as \"word\", \"word = \" and \"word: \""
    );
}
