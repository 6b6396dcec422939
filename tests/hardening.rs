//! Regression tests for the defects found by fuzzing, fault injection and
//! real clients (issue 12): every one ends in a documented exit code, a
//! located message, bounded memory and no partial output.

mod common;
use common::{graftal_in, read_mesh, stderr, stdout};

use std::path::Path;
use std::process::Output;

fn dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

/// Writes `text` to `name` in `dir`.
fn file(dir: &Path, name: &str, text: impl AsRef<[u8]>) {
    std::fs::write(dir.join(name), text).unwrap();
}

/// No panic, no abort: the process ended with one of the documented codes.
fn assert_clean_exit(o: &Output, code: i32) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(code), "{err}");
    assert!(
        !err.contains("panicked") && !err.contains("overflow"),
        "{err}"
    );
}

fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

// ---- 1, 2: long lines and deep nesting ----

#[test]
fn errors_past_column_65535_render_a_window() {
    let d = dir();
    let mut text = "x = [".to_owned();
    text.push_str(&"1,".repeat(33_000));
    text.push('\n');
    file(d.path(), "long.toml", &text);
    let o = graftal_in(d.path(), &["check", "long.toml"]);
    assert_clean_exit(&o, 2);
    let err = stderr(&o);
    assert!(err.contains("long.toml:1:66006"), "{err}");
    assert!(
        err.len() < 2_000,
        "the snippet is a window: {} bytes",
        err.len()
    );

    let text = format!(
        "[params]\nx = \"{}zzz\"\n[start]\ncube = {{}}\n",
        "1+".repeat(33_000)
    );
    file(d.path(), "expr.toml", &text);
    let o = graftal_in(d.path(), &["check", "expr.toml"]);
    assert_clean_exit(&o, 2);
    assert!(stderr(&o).contains("expr.toml:2:66006: unknown name `zzz`"));
}

#[test]
fn input_driven_recursion_is_bounded() {
    let d = dir();
    // 3,000 rules, each including the next.
    let mut text = String::from("[start]\ncube = {}\n[[step]]\nrule = \"r0\"\n");
    for i in 0..3000 {
        text += &format!("[rules.r{i}]\nstep = [{{ rule = \"r{}\" }}]\n", i + 1);
    }
    text += "[rules.r3000]\nstep = [{ translate = { offset = [0, 0, 1] } }]\n";
    file(d.path(), "chain.toml", &text);
    let o = graftal_in(d.path(), &["check", "chain.toml"]);
    assert_clean_exit(&o, 2);
    assert!(
        stderr(&o).contains("nested more than 64 levels deep"),
        "{}",
        stderr(&o)
    );
    // `lint` walks the same file.
    assert_clean_exit(&graftal_in(d.path(), &["lint", "chain.toml"]), 2);

    // 3,000 compounds, each calling the next.
    let mut text = String::from("[start]\ncube = {}\n[[step]]\ncompound = \"c0\"\n");
    for i in 0..3000 {
        text += &format!(
            "[compound.c{i}]\non = \"faces\"\nstep = [{{ compound = \"c{}\" }}]\n",
            i + 1
        );
    }
    text += "[compound.c3000]\non = \"faces\"\nstep = [{ split_face = {} }]\n";
    file(d.path(), "compounds.toml", &text);
    let o = graftal_in(d.path(), &["check", "compounds.toml"]);
    assert_clean_exit(&o, 2);
    assert!(stderr(&o).contains("nested more than 64 levels deep"));

    // 100,000 parameters, each the next plus one: no recursion at all.
    let mut text = String::from("[params]\n");
    for i in 0..100_000 {
        text += &format!("p{i} = \"p{} + 1\"\n", i + 1);
    }
    text += "p100000 = 0\n[start]\ncube = { size = \"1 + p0 * 0\" }\n";
    file(d.path(), "params.toml", &text);
    assert_clean_exit(&graftal_in(d.path(), &["check", "params.toml"]), 0);

    // Deep brackets in RON and TOML, deep parentheses in an expression.
    let deep = format!(
        "(params: (x: {}{}))",
        "[".repeat(100_000),
        "]".repeat(100_000)
    );
    file(d.path(), "deep.ron", deep);
    let o = graftal_in(d.path(), &["check", "deep.ron"]);
    assert_clean_exit(&o, 2);
    assert!(stderr(&o).contains("deep.ron:1:"), "{}", stderr(&o));
    let deep = format!("x = {}{}\n", "[".repeat(100_000), "]".repeat(100_000));
    file(d.path(), "deep.toml", deep);
    assert_clean_exit(&graftal_in(d.path(), &["check", "deep.toml"]), 2);
    let deep = format!(
        "[params]\nx = \"{}1{}\"\n[start]\ncube = {{}}\n",
        "(".repeat(100_000),
        ")".repeat(100_000)
    );
    file(d.path(), "deep-expr.toml", deep);
    let o = graftal_in(d.path(), &["check", "deep-expr.toml"]);
    assert_clean_exit(&o, 2);
    assert!(stderr(&o).contains("too deeply nested"));
}

// ---- 3, 4, 7: limits checked before the work ----

#[test]
fn operators_are_refused_before_they_allocate() {
    let d = dir();
    let cases = [
        ("[start]\ncircle = { segments = 1e8 }\n", "start", "200000001"),
        ("[start]\ngrid = { segments = [20000, 20000] }\n", "start", "1600160004"),
        ("[start]\nuv_sphere = { segments = 20000, rings = 20000 }\n", "start", "1200060002"),
        ("[start]\ncylinder = { segments = 1e8 }\n", "start", "600000002"),
        (
            "[start]\ncube = {}\n[[step]]\nname = \"cut\"\non = \"edges\"\nsplit_edges = { cuts = 1e8 }\n",
            "cut",
            "2400000000",
        ),
    ];
    for (i, (text, step, count)) in cases.iter().enumerate() {
        file(d.path(), &format!("r{i}.toml"), text);
        let o = graftal_in(d.path(), &["run", &format!("r{i}.toml"), "-o", "out.ply"]);
        assert_clean_exit(&o, 3);
        let err = stderr(&o);
        assert!(
            err.contains(&format!("step `{step}`")) && err.contains(count),
            "{text}: {err}"
        );
    }
    // Doubling by `duplicate`: stopped at the step that would pass the limit.
    file(
        d.path(),
        "double.toml",
        "[start]\ngrid = { segments = [10, 10] }\n[[step]]\nname = \"twice\"\nduplicate = {}\nrepeat = 40\n",
    );
    let o = graftal_in(
        d.path(),
        &[
            "run",
            "double.toml",
            "-o",
            "out.ply",
            "--max-primitives",
            "100000",
        ],
    );
    assert_clean_exit(&o, 3);
    assert!(stderr(&o).contains("step `twice#"), "{}", stderr(&o));
    assert!(!d.path().join("out.ply").exists());
}

#[test]
fn repeat_counts_are_checked_before_unrolling() {
    let d = dir();
    // 1,000 × 1,001 steps through a repeated rule: refused at once.
    file(
        d.path(),
        "many.toml",
        "[start]\ncube = {}\n[[step]]\nrule = \"r\"\nrepeat = 1000\n[rules.r]\nstep = [{ translate = { offset = [0, 0, 1] }, repeat = 1001 }]\n",
    );
    let o = graftal_in(d.path(), &["check", "many.toml"]);
    assert_clean_exit(&o, 2);
    let err = stderr(&o);
    assert!(
        err.contains("many.toml:5:10") && err.contains("more than 1000000 steps"),
        "{err}"
    );
    // Just under the limit compiles (copies share one compiled body).
    file(
        d.path(),
        "under.toml",
        "[start]\ncube = {}\n[[step]]\nselect = \"id < 0\"\ntranslate = { offset = [0, 0, 1] }\nrepeat = 999999\n",
    );
    let o = graftal_in(d.path(), &["check", "under.toml"]);
    assert_clean_exit(&o, 0);
    assert!(stdout(&o).contains("1000000 steps"));
}

#[test]
fn kernel_operator_work_counts_against_max_evaluations() {
    let d = dir();
    file(
        d.path(),
        "work.toml",
        "[start]\ngrid = { segments = [100, 100] }\n[[step]]\nname = \"split\"\non = \"edges\"\nsplit_edges = { cuts = 50 }\n",
    );
    let o = graftal_in(
        d.path(),
        &[
            "run",
            "work.toml",
            "-o",
            "out.obj",
            "--max-evaluations",
            "100000",
        ],
    );
    assert_clean_exit(&o, 5);
    assert!(stderr(&o).contains("step `split`"));
    assert!(!d.path().join("out.obj").exists());
    assert_clean_exit(
        &graftal_in(d.path(), &["run", "work.toml", "-o", "out.obj"]),
        0,
    );
}

#[test]
fn large_faces_triangulate_and_fans_grow_linearly() {
    // A 100,000-gon: quadratic before (the fan's hub walked once per spoke).
    let d = dir();
    file(
        d.path(),
        "tri.toml",
        "[start]\ncircle = { segments = 100000, fill = true }\n[[step]]\ntriangulate = {}\n",
    );
    let o = graftal_in(
        d.path(),
        &["run", "tri.toml", "-o", "tri.ply", "--stats", "tri.json"],
    );
    assert_clean_exit(&o, 0);
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.path().join("tri.json")).unwrap()).unwrap();
    assert_eq!(stats["mesh"]["faces"], 99_998);
}

// ---- 5: bounded mesh gates ----

#[test]
fn info_on_thousands_of_coincident_triangles_is_bounded() {
    let d = dir();
    let mut text = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    text += &"f 1 2 3\n".repeat(20_000);
    file(d.path(), "dup.obj", &text);
    let o = graftal_in(d.path(), &["info", "dup.obj", "--json"]);
    assert_clean_exit(&o, 0);
    let info: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(info["searches_complete"], false, "{info}");
    let found = info["self_intersecting_face_pairs"].as_u64().unwrap();
    assert!(found > 1_000_000 && found < 199_990_000, "{found}");
    let listed = info["first_self_intersecting_face_pairs"]
        .as_array()
        .unwrap();
    assert_eq!(listed.len(), 1_000);
    assert_eq!(listed[0], serde_json::json!([0, 1]));
    let o = graftal_in(d.path(), &["info", "dup.obj"]);
    assert!(stdout(&o).contains("at least"), "{}", stdout(&o));

    // A 50,000-index face over four vertices.
    let mut text = String::from("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf");
    for i in 0..50_000 {
        text += &format!(" {}", i % 4 + 1);
    }
    text.push('\n');
    file(d.path(), "big.obj", &text);
    assert_clean_exit(&graftal_in(d.path(), &["info", "big.obj"]), 0);
}

// ---- 6: what input files may reach ----

#[test]
fn gltf_buffers_stay_in_their_directory_and_within_byte_length() {
    let d = dir();
    let sub = d.path().join("models");
    std::fs::create_dir(&sub).unwrap();
    let gltf = |uri: &str, length: u64| {
        format!(
            r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":{length},"uri":"{uri}"}}],
               "bufferViews":[{{"buffer":0,"byteLength":36}}],
               "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],
               "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
               "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#
        )
    };
    let floats: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    file(d.path(), "outside.bin", &floats);
    file(&sub, "inside.bin", &floats);
    for (name, uri) in [
        ("zero.gltf", "/dev/zero"),
        ("up.gltf", "../outside.bin"),
        (
            "abs.gltf",
            &d.path().join("outside.bin").display().to_string(),
        ),
    ] {
        file(&sub, name, gltf(uri, 36));
        let o = graftal_in(&sub, &["info", name]);
        assert_clean_exit(&o, 2);
        assert!(
            stderr(&o).contains("--allow-outside-paths"),
            "{name}: {}",
            stderr(&o)
        );
    }
    // Allowed: `../` is followed; /dev/zero is still no regular file.
    let o = graftal_in(&sub, &["info", "up.gltf", "--allow-outside-paths"]);
    assert_clean_exit(&o, 0);
    let o = graftal_in(&sub, &["info", "zero.gltf", "--allow-outside-paths"]);
    assert_clean_exit(&o, 2);
    assert!(stderr(&o).contains("not a regular file"));
    // Inside: read, and only byteLength bytes of a longer file.
    let mut longer = floats.clone();
    longer.extend(std::iter::repeat_n(0u8, 1 << 20));
    file(&sub, "inside.bin", &longer);
    file(&sub, "ok.gltf", gltf("inside.bin", 36));
    assert_clean_exit(&graftal_in(&sub, &["info", "ok.gltf"]), 0);

    // A mesh path that is a device, a FIFO or a directory.
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink("/dev/zero", d.path().join("zero.stl")).unwrap();
        let o = graftal_in(d.path(), &["info", "zero.stl"]);
        assert_clean_exit(&o, 2);
        assert!(stderr(&o).contains("not a regular file"), "{}", stderr(&o));
        let fifo = d.path().join("pipe.obj");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            let o = graftal_in(d.path(), &["convert", "pipe.obj", "out.ply"]);
            assert_clean_exit(&o, 2);
            assert!(stderr(&o).contains("not a regular file"));
        }
    }
    std::fs::create_dir(d.path().join("dir.obj")).unwrap();
    assert_clean_exit(&graftal_in(d.path(), &["info", "dir.obj"]), 2);
}

#[test]
fn imports_are_read_before_the_run_and_located() {
    let d = dir();
    file(
        d.path(),
        "missing.toml",
        "[start]\nimport = { path = \"nowhere.obj\" }\n",
    );
    for command in ["check", "run"] {
        let o = graftal_in(d.path(), &[command, "missing.toml"]);
        assert_clean_exit(&o, 2);
        let err = stderr(&o);
        assert!(
            err.contains("missing.toml:2:19: cannot import `nowhere.obj`"),
            "{err}"
        );
    }
    file(
        d.path(),
        "outside.toml",
        "[start]\nimport = { path = \"../x.obj\" }\n",
    );
    let o = graftal_in(d.path(), &["check", "outside.toml"]);
    assert_clean_exit(&o, 2);
    assert!(stderr(&o).contains("--allow-outside-paths"));
}

// ---- 8, 9, 20: outputs ----

#[test]
fn a_run_writes_all_its_outputs_or_none() {
    let d = dir();
    file(d.path(), "cube.toml", "[start]\ncube = {}\n");
    file(d.path(), "blocker", "a file, not a directory");
    let o = graftal_in(
        d.path(),
        &[
            "run",
            "cube.toml",
            "-o",
            "cube.obj",
            "--stats",
            "blocker/stats.json",
        ],
    );
    assert_clean_exit(&o, 1);
    assert_eq!(
        entries(d.path()),
        ["blocker", "cube.toml"],
        "no mesh without its stats"
    );
    // A batch whose manifest cannot be written writes no variant.
    let o = graftal_in(
        d.path(),
        &[
            "run",
            "cube.toml",
            "--seeds",
            "0..3",
            "-o",
            "out/{seed}.obj",
            "--manifest",
            "blocker/m.json",
        ],
    );
    assert_clean_exit(&o, 1);
    assert!(!d.path().join("out").join("0.obj").exists());
}

#[test]
fn a_closed_pipe_ends_quietly() {
    let d = dir();
    file(d.path(), "cube.toml", "[start]\ncube = {}\n");
    let bin = env!("CARGO_BIN_EXE_graftal");
    for args in [
        "run cube.toml -o cube.obj --stats -",
        "run cube.toml --seeds 0..200 -o 'out/{seed}.obj' --stats - -j2",
        "schema",
        "man",
    ] {
        let o = std::process::Command::new("sh")
            .current_dir(d.path())
            .arg("-c")
            .arg(format!(
                "'{bin}' {args} | head -c 1 > /dev/null; echo rc=${{PIPESTATUS[0]:-x}}"
            ))
            .output()
            .unwrap();
        let err = stderr(&o);
        assert!(
            !err.contains("panicked") && !err.contains("Broken pipe"),
            "{args}: {err}"
        );
    }
}

#[test]
fn the_largest_seed_is_a_seed() {
    let d = dir();
    file(d.path(), "cube.toml", "[start]\ncube = {}\n");
    for seeds in [
        "18446744073709551615",
        "18446744073709551614..=18446744073709551615",
    ] {
        let o = graftal_in(
            d.path(),
            &[
                "run",
                "cube.toml",
                "--seeds",
                seeds,
                "-o",
                "c-{seed}.obj",
                "-q",
            ],
        );
        assert_clean_exit(&o, 0);
    }
    assert!(d.path().join("c-18446744073709551615.obj").exists());
    let o = graftal_in(
        d.path(),
        &["run", "cube.toml", "--seeds", "5..5", "-o", "c.obj"],
    );
    assert_clean_exit(&o, 2);
}

#[test]
fn stale_temporary_files_are_reported_and_removed_only_when_asked() {
    let d = dir();
    file(d.path(), "cube.toml", "[start]\ncube = {}\n");
    // What a `kill -9` mid-write leaves, backdated three hours.
    let stale = d
        .path()
        .join(".cube.obj.graftal-0badf00d-4194304-0123456789abcdef.tmp");
    std::fs::write(&stale, "partial").unwrap();
    let old = std::time::SystemTime::now() - std::time::Duration::from_secs(3 * 3600);
    std::fs::File::options()
        .write(true)
        .open(&stale)
        .unwrap()
        .set_modified(old)
        .unwrap();
    // A write beside it reports it, and leaves it: its writer may be alive
    // on another host or in another PID namespace.
    let o = graftal_in(d.path(), &["run", "cube.toml", "-o", "cube.obj"]);
    assert_clean_exit(&o, 0);
    let err = stderr(&o);
    assert!(
        err.contains("warning: .: 1 graftal temporary file(s) older than 1 h")
            && err.contains("graftal clean ."),
        "{err}"
    );
    assert!(stale.exists());
    // A run told the age removes it.
    let o = graftal_in(
        d.path(),
        &[
            "run",
            "cube.toml",
            "-o",
            "cube.obj",
            "--remove-stale-temps",
            "2h",
        ],
    );
    assert_clean_exit(&o, 0);
    assert!(
        stderr(&o).contains("removed 1 graftal temporary file(s) older than 2 h"),
        "{}",
        stderr(&o)
    );
    // The OBJ's material library lands beside it; nothing else is left.
    assert_eq!(entries(d.path()), ["cube.mtl", "cube.obj", "cube.toml"]);
    // `graftal clean` removes by age, or all of them.
    std::fs::write(&stale, "partial").unwrap();
    let o = graftal_in(d.path(), &["clean", ".", "--older-than", "1h"]);
    assert_clean_exit(&o, 0);
    assert!(stale.exists(), "a fresh file is younger than an hour");
    let o = graftal_in(d.path(), &["clean", ".", "--dry-run"]);
    assert_clean_exit(&o, 0);
    assert!(stdout(&o).contains("would remove ./.cube.obj.graftal-") && stale.exists());
    let o = graftal_in(d.path(), &["clean", "."]);
    assert_clean_exit(&o, 0);
    assert!(
        stdout(&o).contains("removed ./.cube.obj.graftal-"),
        "{}",
        stdout(&o)
    );
    assert_eq!(entries(d.path()), ["cube.mtl", "cube.obj", "cube.toml"]);
    assert_clean_exit(&graftal_in(d.path(), &["clean", "missing-dir"]), 2);
}

// ---- 10, 11, 12: every error located ----

#[test]
fn every_rule_error_has_a_location() {
    let d = dir();
    let cases: &[(&str, &[u8], &str)] = &[
        (
            "latin1.toml",
            b"seed = 1\n# caf\xe9\n[start]\ncube = {}\n",
            "latin1.toml:2:6: the rule file is not UTF-8",
        ),
        (
            "nan.ron",
            b"(start: (cube: (size: NaN)))",
            "nan.ron:1:23: numbers must be finite",
        ),
        (
            "inf.toml",
            b"[start]\ncube = { size = inf }\n",
            "inf.toml:2:17: numbers must be finite",
        ),
        (
            "noop.toml",
            b"[start]\ncube = {}\n[[step]]\nname = \"x\"\n",
            "noop.toml:3:1: step `x` has no operator",
        ),
        (
            "empty-start.toml",
            b"[start]\n[[step]]\ntriangulate = {}\n",
            "empty-start.toml:1:1: step `start` has no operator",
        ),
        (
            "start-repeat.toml",
            b"[start]\ncube = {}\nrepeat = 3\n",
            "start-repeat.toml:3:10: `[start]` takes one create operator",
        ),
        (
            "start-rule.toml",
            b"[start]\nrule = \"r\"\n[rules.r]\nstep = []\n",
            "start-rule.toml:2:8: `[start]` takes one create operator",
        ),
        (
            "no-op.ron",
            b"(start: (cube: ()), step: [()])",
            "no-op.ron:1:28: step `step1` has no operator",
        ),
    ];
    for (name, text, expected) in cases {
        file(d.path(), name, text);
        let o = graftal_in(d.path(), &["check", name]);
        assert_clean_exit(&o, 2);
        let err = stderr(&o);
        assert!(
            err.contains(expected),
            "{name}: expected {expected:?} in\n{err}"
        );
        assert!(err.contains('╭'), "{name}: a snippet in\n{err}");
    }
}

#[test]
fn cr_only_files_number_lines_once() {
    // TOML refuses a lone CR; RON takes it as a line break, as the
    // headline and the snippet must both do.
    let d = dir();
    file(
        d.path(),
        "mac.ron",
        "(\r  params: (w: 1, h: \"w +\"),\r  start: (cube: ()),\r)\r",
    );
    let o = graftal_in(d.path(), &["check", "mac.ron"]);
    assert_clean_exit(&o, 2);
    let err = stderr(&o);
    assert!(err.starts_with("error: mac.ron:2:25: "), "{err}");
    assert!(err.contains("╭─[mac.ron:2:25]"), "{err}");
    assert!(err.contains("2 │   params: (w: 1, h: \"w +\"),"), "{err}");
    file(d.path(), "mac.toml", "[params]\rw = 1\r");
    let o = graftal_in(d.path(), &["check", "mac.toml"]);
    let err = stderr(&o);
    let location = err.lines().next().unwrap().trim_start_matches("error: ");
    let location = &location[..location.find(": ").unwrap()];
    assert!(err.contains(&format!("╭─[{location}]")), "{err}");
}

#[test]
fn a_quote_before_crlf_is_located_not_a_panic() {
    // Issue 34: the 3-byte rule file `'` CR LF panicked while rendering its
    // snippet (TOML's error is at the LF, between the two bytes of the
    // line break). The file is fixtures/fuzz/, framed in fuzz/regressions/.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let bytes =
        std::fs::read(root.join("fixtures/fuzz/rules_compile-crlf-unterminated-string.toml"))
            .unwrap();
    assert_eq!(bytes, b"'\r\n");
    let d = dir();
    for name in ["q.toml", "q.ron"] {
        file(d.path(), name, &bytes);
        let o = graftal_in(d.path(), &["check", name]);
        assert_clean_exit(&o, 2);
        let err = stderr(&o);
        let location = err.lines().next().unwrap().trim_start_matches("error: ");
        let location = &location[..location.find(": ").unwrap()];
        assert!(location.starts_with(&format!("{name}:1:")), "{err}");
        assert!(err.contains(&format!("╭─[{location}]")), "{err}");
        assert!(err.contains("1 │ '\n"), "{err}");
    }
    let o = graftal_in(d.path(), &["check", "q.toml"]);
    assert!(
        stderr(&o).starts_with("error: q.toml:1:2: key with no value, expected `=`"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn every_rule_file_the_fuzzers_found_checks_cleanly() {
    // fixtures/fuzz/: the inputs that once crashed a rule-file target, as
    // graftal reads them; `check` ends in 0 or 2, never in a panic.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/fuzz");
    let mut checked = 0;
    for entry in std::fs::read_dir(&root).unwrap() {
        let path = entry.unwrap().path();
        let Some(ext) = path.extension().and_then(|e| e.to_str()) else {
            continue;
        };
        if ext != "toml" && ext != "ron" {
            continue;
        }
        let o = graftal_in(
            &root,
            &["check", path.file_name().unwrap().to_str().unwrap()],
        );
        let code = o.status.code();
        assert!(
            code == Some(0) || code == Some(2),
            "{}: {o:?}",
            path.display()
        );
        assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
        checked += 1;
    }
    assert!(checked >= 2, "{checked} files in {}", root.display());
}

#[test]
fn ron_errors_point_at_the_value_not_its_first_copy() {
    // The same text twice: valid for faces, wrong for vertices. Searching
    // for the literal found the first one.
    let d = dir();
    file(
        d.path(),
        "twice.ron",
        r#"(
    start: (cube: ()),
    step: [
        (on: faces, select: "area > 0.5", inset_faces: (thickness: 0.1)),
        (on: vertices, select: "area > 0.5", translate: (offset: [0, 0, 1])),
    ],
)
"#,
    );
    let o = graftal_in(d.path(), &["check", "twice.ron"]);
    assert_clean_exit(&o, 2);
    assert!(
        stderr(&o).contains("twice.ron:5:33: unknown name `area`"),
        "{}",
        stderr(&o)
    );
    // And a RON key is located at the key.
    file(d.path(), "key.ron", "(start: (cube: (size: 1, colour: 2)))");
    let o = graftal_in(d.path(), &["check", "key.ron"]);
    assert!(
        stderr(&o).contains("key.ron:1:26: unknown field `colour`"),
        "{}",
        stderr(&o)
    );
}

// ---- 13, 14, 19: conventions of real clients ----

#[test]
fn gltf_is_y_up_and_round_trips_exactly() {
    let d = dir();
    // A tall box: 1 × 1 × 3 along the kernel's Z.
    file(
        d.path(),
        "tall.toml",
        "[start]\ncube = { size = 1 }\n[[step]]\nscale = { factor = [1, 1, 3] }\n",
    );
    assert_clean_exit(
        &graftal_in(d.path(), &["run", "tall.toml", "-o", "tall.glb"]),
        0,
    );
    assert_clean_exit(
        &graftal_in(d.path(), &["run", "tall.toml", "-o", "tall.obj"]),
        0,
    );
    let glb = std::fs::read(d.path().join("tall.glb")).unwrap();
    let (doc, buffers, _) = gltf::import_slice(&glb).unwrap();
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&buffers[b.index()]));
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in reader.read_positions().unwrap() {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    assert_eq!(hi[1] - lo[1], 3.0, "the height runs along +Y");
    assert_eq!((hi[0] - lo[0], hi[2] - lo[2]), (1.0, 1.0));
    // Back into the Z-up kernel: the same positions as the OBJ.
    assert_clean_exit(
        &graftal_in(d.path(), &["convert", "tall.glb", "back.obj"]),
        0,
    );
    let sorted = |name: &str| {
        let mut p: Vec<[u64; 3]> = read_mesh(&d.path().join(name))
            .positions
            .iter()
            .map(|p| p.map(f64::to_bits))
            .collect();
        p.sort_unstable();
        p
    };
    assert_eq!(sorted("back.obj"), sorted("tall.obj"));
    // `--up y` for OBJ.
    assert_clean_exit(
        &graftal_in(d.path(), &["run", "tall.toml", "-o", "up.obj", "--up", "y"]),
        0,
    );
    let up = read_mesh(&d.path().join("up.obj"));
    let height = up.positions.iter().map(|p| p[1]).fold(f64::MIN, f64::max)
        - up.positions.iter().map(|p| p[1]).fold(f64::MAX, f64::min);
    assert_eq!(height, 3.0);
}

#[test]
fn gltfpack_output_reads() {
    // `gltfpack -i chair.glb -o chair-gltfpack.glb` (npm gltfpack, its
    // defaults): KHR_mesh_quantization, 16-bit positions, a node transform.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let o = graftal_in(
        root,
        &["info", "fixtures/clients/chair-gltfpack.glb", "--json"],
    );
    assert_clean_exit(&o, 0);
    let info: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(info["vertices"], 56);
    assert_eq!(info["watertight"], true);
    // The chair's volume, 0.46209 unquantized, within 16-bit steps.
    assert!(
        (info["volume"].as_f64().unwrap() - 0.462_094).abs() < 1e-3,
        "{info}"
    );
    // Z-up again: the chair stands 2.19 high along z.
    let bounds = &info["bounds"];
    let height = bounds[1][2].as_f64().unwrap() - bounds[0][2].as_f64().unwrap();
    assert!((height - 2.19).abs() < 1e-2, "{bounds}");
}

#[test]
fn stl_says_when_it_drops_wire_edges() {
    let d = dir();
    file(
        d.path(),
        "pole.toml",
        "[start]\nvertex = {}\n[[step]]\nname = \"pole\"\ncreate_edge = { length = 2 }\n",
    );
    let o = graftal_in(
        d.path(),
        &["run", "pole.toml", "-o", "pole.stl", "--stats", "pole.json"],
    );
    assert_clean_exit(&o, 0);
    assert!(
        stderr(&o).contains("STL cannot hold the 1 wire edges"),
        "{}",
        stderr(&o)
    );
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.path().join("pole.json")).unwrap()).unwrap();
    assert_eq!(stats["dropped_wire_edges"], 1);
    let o = graftal_in(
        d.path(),
        &["run", "pole.toml", "-o", "strict.stl", "--strict"],
    );
    assert_clean_exit(&o, 1);
    assert!(!d.path().join("strict.stl").exists());
    // convert too.
    assert_clean_exit(
        &graftal_in(d.path(), &["run", "pole.toml", "-o", "pole.obj"]),
        0,
    );
    let o = graftal_in(d.path(), &["convert", "pole.obj", "c.stl", "--strict"]);
    assert_clean_exit(&o, 1);
}

#[test]
fn weld_joins_meshes_with_one_vertex_per_corner() {
    let d = dir();
    // A cube as Blender writes it after a glTF import: 24 vertices.
    let mut text = String::new();
    let quads = [
        [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]],
        [[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
        [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]],
        [[1, 0, 0], [1, 1, 0], [1, 1, 1], [1, 0, 1]],
        [[1, 1, 0], [0, 1, 0], [0, 1, 1], [1, 1, 1]],
        [[0, 1, 0], [0, 0, 0], [0, 0, 1], [0, 1, 1]],
    ];
    for q in &quads {
        for p in q {
            text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
        }
    }
    for k in 0..6 {
        text += &format!(
            "f {} {} {} {}\n",
            4 * k + 1,
            4 * k + 2,
            4 * k + 3,
            4 * k + 4
        );
    }
    file(d.path(), "split.obj", &text);
    let info = |args: &[&str]| -> serde_json::Value {
        let o = graftal_in(d.path(), args);
        assert_clean_exit(&o, 0);
        serde_json::from_str(&stdout(&o)).unwrap()
    };
    let loose = info(&["info", "split.obj", "--json"]);
    assert_eq!(
        (loose["vertices"].as_u64(), loose["watertight"].as_bool()),
        (Some(24), Some(false))
    );
    let welded = info(&["info", "split.obj", "--json", "--weld"]);
    assert_eq!(
        (welded["vertices"].as_u64(), welded["watertight"].as_bool()),
        (Some(8), Some(true))
    );
    assert!((welded["volume"].as_f64().unwrap() - 1.0).abs() < 1e-12);
    let near = info(&["info", "split.obj", "--json", "--weld", "0.5"]);
    assert_eq!(near["vertices"], 8);
    assert_clean_exit(
        &graftal_in(d.path(), &["convert", "split.obj", "w.ply", "--weld"]),
        0,
    );
    assert_eq!(read_mesh(&d.path().join("w.ply")).positions.len(), 8);
}

// ---- 15, 16, 17: operators and explain ----

#[test]
fn skinned_skeletons_have_no_coincident_vertices_or_loose_nodes() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let d = dir();
    for example in ["house", "cupboard", "tree"] {
        let rules = root.join("rules").join(format!("{example}.toml"));
        let json = d.path().join(format!("{example}.json"));
        let o = graftal_in(
            d.path(),
            &[
                "run",
                rules.to_str().unwrap(),
                "-o",
                "x.glb",
                "--stats",
                json.to_str().unwrap(),
            ],
        );
        assert_clean_exit(&o, 0);
        let stats: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        let mesh = &stats["mesh"];
        assert_eq!(mesh["close_vertex_pairs"], 0, "{example}: {mesh}");
        assert_eq!(mesh["isolated_vertices"], 0, "{example}: {mesh}");
    }
    // The tree's GLB, read back (welded by position), is still closed.
    let o = graftal_in(d.path(), &["info", "x.glb", "--json"]);
    let glb: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(glb["watertight"], true);
}

#[test]
fn dissolve_edges_dissolves_regions_and_counts_what_it_did() {
    let d = dir();
    file(
        d.path(),
        "dissolve.toml",
        "[start]\ngrid = { segments = [2, 2] }\n[[step]]\nname = \"inner\"\non = \"edges\"\nselect = \"faces == 2\"\ndissolve_edges = {}\n",
    );
    let o = graftal_in(
        d.path(),
        &["run", "dissolve.toml", "-o", "d.obj", "--stats", "d.json"],
    );
    assert_clean_exit(&o, 0);
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.path().join("d.json")).unwrap()).unwrap();
    assert_eq!(stats["mesh"]["faces"], 1);
    assert_eq!(stats["mesh"]["vertices"], 8, "the centre vertex goes");
    let step = &stats["steps"][1];
    assert_eq!(
        (step["matched"].as_u64(), step["applied"].as_u64()),
        (Some(4), Some(4))
    );
}

#[test]
fn explain_names_cancel_compound_as_such() {
    // tests/intersect.rs's scene: an arm reaching a wall cancels its compound.
    let d = dir();
    file(
        d.path(),
        "cancel.toml",
        r#"policy = "intersect"
[start]
grid = { segments = [1, 1], size = [2, 2] }
[[step]]
name = "stand"
rotate = { angle = 90, axis = [0, 1, 0] }
[[step]]
name = "place"
translate = { offset = [1, 0, 0] }
[[step]]
name = "thin"
edit_node = { radius = 0.01 }
[[step]]
name = "a"
vertex = { at = [0.8, 0, 0], radius = 0.01 }
[compound.arm]
on = "verts"
step = [
  { name = "stem", create_edge = { heading = [0, 0, 1], length = 0.3 } },
  { name = "reach", from = "stem", on = "verts", on_intersection = "cancel_compound", create_edge = { heading = [1, 0, 0], length = 0.5 } },
]
[[step]]
name = "arms"
select = "degree == 0"
compound = "arm"
"#,
    );
    let o = graftal_in(d.path(), &["explain", "cancel.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert_eq!(out.matches("(cancel_compound)").count(), 2, "{out}");
    assert!(!out.contains("(cancel_rule)"), "{out}");
}

// ---- 21: documentation matches the parser ----

#[test]
fn on_vertices_is_accepted_for_verts() {
    let d = dir();
    file(
        d.path(),
        "v.toml",
        "[start]\ncube = {}\n[[step]]\non = \"vertices\"\nselect = \"pos.z > 0\"\ntranslate = { offset = [0, 0, 1] }\n",
    );
    assert_clean_exit(&graftal_in(d.path(), &["check", "v.toml"]), 0);
}

#[test]
fn lint_warns_about_unnamed_steps_that_draw() {
    let d = dir();
    file(
        d.path(),
        "draws.toml",
        "[start]\ngrid = { segments = [2, 2] }\n[[step]]\non = \"faces\"\nselect = \"random < 0.5\"\ninset_faces = { thickness = 0.1 }\n[[step]]\nname = \"named\"\non = \"faces\"\nselect = \"random < 0.5\"\ninset_faces = { thickness = 0.1 }\n",
    );
    let o = graftal_in(d.path(), &["lint", "draws.toml"]);
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert_eq!(err.matches("unnamed-random-step").count(), 1, "{err}");
    assert!(err.contains("draws.toml:3:1"), "{err}");
}

// ---- issue 34: this round's hostile inputs ----

/// Runs graftal in `dir` with its address space limited to `kib` KiB
/// (`ulimit -v`): an input that needs more memory aborts, which the test
/// sees as a failed exit.
fn graftal_capped(dir: &Path, kib: u64, args: &[&str]) -> Output {
    let mut script = format!("ulimit -v {kib}; exec \"$0\"");
    for (k, _) in args.iter().enumerate() {
        script += &format!(" \"${}\"", k + 1);
    }
    std::process::Command::new("sh")
        .current_dir(dir)
        .arg("-c")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_graftal"))
        .args(args)
        .output()
        .expect("sh runs")
}

#[test]
fn a_million_empty_repeats_are_bounded_and_charged() {
    let d = dir();
    file(
        d.path(),
        "r.toml",
        "[[step]]\ninset_faces = { thickness = 0.1 }\nrepeat = 1000000\n",
    );
    // Nothing is selected: it runs, in bounded memory (it took 1.4 GB).
    let o = graftal_capped(d.path(), 900_000, &["run", "r.toml", "-o", "r.obj", "-q"]);
    assert_clean_exit(&o, 0);
    // Each step run costs one evaluation: over the budget it is refused
    // before it starts, with exit 5 and no output.
    let o = graftal_in(
        d.path(),
        &["run", "r.toml", "-o", "s.obj", "--max-evaluations", "1000"],
    );
    assert_clean_exit(&o, 5);
    assert!(
        stderr(&o).contains("at least 1000000 steps"),
        "{}",
        stderr(&o)
    );
    assert!(!d.path().join("s.obj").exists());
}

#[test]
fn one_face_of_300000_corners_is_bounded() {
    let d = dir();
    let n = 91;
    let mut text = String::new();
    for i in 0..n {
        let a = std::f64::consts::TAU * i as f64 / n as f64;
        text += &format!("v {} {} 0\n", libm::cos(a), libm::sin(a));
    }
    text.push('f');
    for i in 0..300_000 {
        text += &format!(" {}", i % n + 1);
    }
    text.push('\n');
    file(d.path(), "big.obj", &text);
    // It took 1 GB and 11 s; the search now stops at its memory cap and
    // says its counts are lower bounds.
    let o = graftal_capped(d.path(), 600_000, &["info", "big.obj", "--json"]);
    assert_clean_exit(&o, 0);
    let info: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(info["searches_complete"], false, "{info}");
    assert!(info["self_intersecting_face_pairs"].as_u64().unwrap() > 1000);
}

#[test]
fn a_device_is_not_read_as_a_rule_file() {
    if !Path::new("/dev/zero").exists() {
        return;
    }
    let d = dir();
    for args in [
        &["run", "/dev/zero", "-o", "z.obj"][..],
        &["run", "/dev/zero", "--seeds", "0..2", "-o", "{seed}.obj"],
        &["check", "/dev/zero"],
        &["info", "/dev/zero"],
    ] {
        let o = graftal_in(d.path(), args);
        assert_clean_exit(&o, 2);
        assert!(
            stderr(&o).contains("not a regular file"),
            "{args:?}: {}",
            stderr(&o)
        );
    }
    assert!(entries(d.path()).is_empty());
}
