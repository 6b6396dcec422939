//! Batch production through the binary: variants, byte identity across
//! `-j` and shards, manifests, NDJSON stats, limits, golden checks and the
//! bad input each must refuse.

mod common;
use common::{examples, graftal, graftal_in, stderr};

use std::path::{Path, PathBuf};
use std::process::Output;

fn rules(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("rules")
        .join(name)
        .display()
        .to_string()
}

/// `graftal manifest merge INPUTS -o OUTPUT` in `dir`.
fn merge(dir: &Path, inputs: &[&str], output: &str) -> Output {
    let mut args = vec!["manifest", "merge"];
    args.extend(inputs);
    args.extend(["-o", output]);
    graftal_in(dir, &args)
}

fn code(o: &Output) -> i32 {
    o.status.code().expect("exited")
}

/// Every file under `dir`, relative path → bytes, sorted.
fn files(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let bytes = std::fs::read(&path).unwrap();
                out.push((path.strip_prefix(dir).unwrap().to_path_buf(), bytes));
            }
        }
    }
    out.sort();
    out
}

/// A rule file whose size follows the parameter `n` (an n × n grid,
/// extruded), with a random height per seed.
const SIZED: &str = r#"
[params]
n = 2
height = { uniform = [0.5, 1.5] }
[start]
grid = { segments = ["n", "n"], size = [1, 1] }
[[step]]
extrude_region = { offset = [0, 0, "height"] }
"#;

fn sized(dir: &Path) -> String {
    let path = dir.join("sized.toml");
    std::fs::write(&path, SIZED).unwrap();
    path.display().to_string()
}

#[test]
fn outputs_and_manifest_are_identical_for_any_job_count_and_repeat() {
    let chair = rules("chair.toml");
    let mut runs = Vec::new();
    for jobs in ["1", "2", "2", "3"] {
        let dir = tempfile::tempdir().unwrap();
        let o = graftal_in(
            dir.path(),
            &[
                "run",
                &chair,
                "--seeds",
                "0..7",
                "--grid",
                "width=1,1.3",
                "-o",
                "out/{name}-{width}-{seed:02}.glb",
                "-j",
                jobs,
                "--quiet",
            ],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        assert!(stderr(&o).is_empty(), "quiet: {}", stderr(&o));
        runs.push(files(dir.path()));
    }
    // 14 meshes and the manifest, in the template's directory.
    assert_eq!(runs[0].len(), 15);
    assert!(runs[0]
        .iter()
        .any(|(p, _)| p == Path::new("out/manifest.json")));
    assert!(runs[0]
        .iter()
        .any(|(p, _)| p == Path::new("out/chair-1.3-06.glb")));
    for other in &runs[1..] {
        assert!(other == &runs[0], "bytes differ between job counts");
    }
    // Seeds give different chairs.
    let meshes: std::collections::BTreeSet<&Vec<u8>> = runs[0]
        .iter()
        .filter(|(p, _)| p.extension().is_some_and(|e| e == "glb"))
        .map(|(_, b)| b)
        .collect();
    assert_eq!(meshes.len(), 14);
}

#[test]
fn four_shards_merge_into_the_unsharded_manifest_and_files() {
    let chair = rules("chair.toml");
    let whole = tempfile::tempdir().unwrap();
    let args = |extra: &[&'static str]| {
        let mut a: Vec<&str> = vec![
            "run",
            "--seeds",
            "0..10",
            "-o",
            "out/{name}-{seed}.obj",
            "-q",
        ];
        a.extend_from_slice(extra);
        a
    };
    let mut a = args(&[]);
    a.insert(1, &chair);
    assert_eq!(code(&graftal_in(whole.path(), &a)), 0);

    let sharded = tempfile::tempdir().unwrap();
    let specs = ["2/4", "0/4", "3/4", "1/4"];
    for spec in specs {
        let mut a = args(&["--shard", spec]);
        a.insert(1, &chair);
        let o = graftal_in(sharded.path(), &a);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
    }
    let shard_files: Vec<String> = (0..4)
        .map(|i| format!("out/manifest.shard-{i}-of-4.json"))
        .collect();
    let reversed: Vec<&str> = shard_files.iter().rev().map(String::as_str).collect();
    let o = merge(sharded.path(), &reversed, "out/manifest.json");
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    for f in &shard_files {
        std::fs::remove_file(sharded.path().join(f)).unwrap();
    }
    assert!(files(sharded.path()) == files(whole.path()));

    // Shards that do not add up are refused, with nothing written.
    let o = merge(sharded.path(), &["out/manifest.json"], "out/m2.json");
    assert_eq!(code(&o), 2);
    assert!(stderr(&o).contains("not a shard"), "{}", stderr(&o));
    assert!(!sharded.path().join("out/m2.json").exists());
}

#[test]
fn manifests_from_different_rule_files_or_versions_do_not_merge() {
    let dir = tempfile::tempdir().unwrap();
    for (file, shard) in [("chair.toml", "0/2"), ("house.toml", "1/2")] {
        let o = graftal_in(
            dir.path(),
            &[
                "run",
                &rules(file),
                "--seeds",
                "0..2",
                "--shard",
                shard,
                "-o",
                "{name}-{seed}.obj",
                "--manifest",
                &format!("{file}.json"),
                "-q",
            ],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
    }
    let o = merge(
        dir.path(),
        &["chair.toml.json", "house.toml.json"],
        "m.json",
    );
    assert_eq!(code(&o), 2);
    // The message names the field that differs.
    assert!(
        stderr(&o).contains("are not shards of one batch: rule_sha256: \""),
        "{}",
        stderr(&o)
    );

    // The same rule file from another graftal version.
    let o = graftal_in(
        dir.path(),
        &[
            "run",
            &rules("chair.toml"),
            "--seeds",
            "0..2",
            "--shard",
            "1/2",
            "-o",
            "{name}-{seed}.obj",
            "--manifest",
            "other.json",
            "-q",
        ],
    );
    assert_eq!(code(&o), 0);
    let text = std::fs::read_to_string(dir.path().join("other.json")).unwrap();
    let version = format!("\"graftal_version\": \"{}\"", env!("CARGO_PKG_VERSION"));
    std::fs::write(
        dir.path().join("other.json"),
        text.replace(&version, "\"graftal_version\": \"0.0.1\""),
    )
    .unwrap();
    let o = merge(dir.path(), &["chair.toml.json", "other.json"], "m.json");
    assert_eq!(code(&o), 2);
    assert!(
        stderr(&o).contains(&format!(
            "graftal_version: \"{}\" vs \"0.0.1\"",
            env!("CARGO_PKG_VERSION")
        )),
        "{}",
        stderr(&o)
    );
    assert!(!dir.path().join("m.json").exists());
}

#[test]
fn stats_stream_one_ndjson_line_per_variant_in_index_order() {
    let dir = tempfile::tempdir().unwrap();
    let o = graftal_in(
        dir.path(),
        &[
            "run",
            &rules("chair.toml"),
            "--seeds",
            "3,1,2",
            "-o",
            "{seed}.ply",
            "--stats",
            "-",
            "-j",
            "3",
            "--json",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let stdout = String::from_utf8(o.stdout.clone()).unwrap();
    let lines: Vec<serde_json::Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    // Three stats lines, then the --json summary.
    assert_eq!(lines.len(), 4);
    for (k, seed) in [3, 1, 2].into_iter().enumerate() {
        assert_eq!(lines[k]["index"], k);
        assert_eq!(lines[k]["seed"], seed);
        assert_eq!(lines[k]["output"], format!("{seed}.ply"));
        assert!(lines[k]["mesh"]["faces"].as_u64().unwrap() > 0);
    }
    assert_eq!(lines[3]["ok"], 3);
    assert_eq!(lines[3]["exit_code"], 0);
    // Not a terminal: no progress bar, only the summary line.
    let err = stderr(&o);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("3 written") && !err.contains('\r'), "{err}");
}

#[test]
fn limits_fail_their_variant_with_their_exit_code_and_the_batch_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let file = sized(dir.path());
    // n = 60 makes about 22,000 primitives, over the limit.
    let o = graftal_in(
        dir.path(),
        &[
            "run",
            &file,
            "--grid",
            "n=2,60,3",
            "-o",
            "out/{n}.obj",
            "--max-primitives",
            "5000",
            "--json",
        ],
    );
    assert_eq!(code(&o), 3, "{}", stderr(&o));
    assert!(dir.path().join("out/2.obj").exists() && dir.path().join("out/3.obj").exists());
    assert!(!dir.path().join("out/60.obj").exists());
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        (summary["ok"].as_u64(), summary["failed"].as_u64()),
        (Some(2), Some(1))
    );
    assert_eq!(summary["failures"][0]["kind"], "too_large");
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("out/manifest.json")).unwrap())
            .unwrap();
    assert_eq!(manifest["variants"][1]["status"], "failed");
    assert_eq!(manifest["variants"][1]["error"]["exit_code"], 3);

    // --fail-fast on one worker: the variant after the failure never starts.
    let o = graftal_in(
        dir.path(),
        &[
            "run",
            &file,
            "--grid",
            "n=2,60,3",
            "-o",
            "ff/{n}.obj",
            "--max-primitives",
            "5000",
            "--fail-fast",
            "-j",
            "1",
            "-q",
        ],
    );
    assert_eq!(code(&o), 3);
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("ff/manifest.json")).unwrap())
            .unwrap();
    assert_eq!(manifest["summary"]["not_run"], 1);
    assert_eq!(manifest["variants"][2]["status"], "not_run");
    assert!(!dir.path().join("ff/3.obj").exists());

    // The expression budget (deterministic) and the wall-clock timeout.
    let tree = rules("tree.toml");
    for (flag, value, exit, kind) in [
        ("--max-evaluations", "100", 5, "expression evaluations"),
        ("--timeout", "0.000001", 4, "time limit"),
    ] {
        let o = graftal_in(dir.path(), &["run", &tree, "-o", "t.obj", flag, value]);
        assert_eq!(code(&o), exit, "{flag}: {}", stderr(&o));
        assert!(stderr(&o).contains(kind), "{}", stderr(&o));
        assert!(!dir.path().join("t.obj").exists());
    }
}

#[test]
fn bad_batch_input_exits_2_and_writes_nothing() {
    let chair = rules("chair.toml");
    let cases: &[(&[&str], &str)] = &[
        (&["--seeds", "5..2"], "is empty"),
        (&["--seeds", "1..x"], "not a seed"),
        (&["--seeds", "1,1"], "listed twice"),
        (
            &["--seeds", "0..3", "-o", "out/{name}-{colour}.obj"],
            "unknown field `{colour}`",
        ),
        (
            &["--seeds", "0..3", "-o", "out/{name}.obj"],
            "would both be written",
        ),
        (&["--seeds", "0..3", "--shard", "5/4"], "0 to 3"),
        (&["--seeds", "0..3", "--shard", "1/0"], "at least 1"),
        (&["--grid", "width"], "name=v1,v2"),
        (&["--grid", "width=1,", "--seeds", "0..2"], "empty value"),
        (&["--seeds", "0..3", "-o", "out/{seed:x}.obj"], ":0N"),
        (&["--timeout", "0"], "positive"),
        (&["--seeds", "0..100000000"], "more than"),
    ];
    for (extra, expected) in cases {
        let dir = tempfile::tempdir().unwrap();
        let mut args = vec!["run", chair.as_str()];
        args.extend_from_slice(extra);
        let o = graftal_in(dir.path(), &args);
        assert_eq!(code(&o), 2, "{extra:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(expected), "{extra:?}: {}", stderr(&o));
        assert!(files(dir.path()).is_empty(), "{extra:?} wrote files");
    }
}

/// `graftal verify` of the chair's seeds 1 and 2 against `golden/`.
fn verify(dir: &Path, extra: &[&str]) -> Output {
    let chair = rules("chair.toml");
    let mut args = vec!["verify", "--golden", "golden", &chair, "--seeds", "1..3"];
    args.extend_from_slice(extra);
    graftal_in(dir, &args)
}

#[test]
fn verify_catches_a_one_ulp_change_unless_tolerated_and_bless_rewrites() {
    let dir = tempfile::tempdir().unwrap();
    let chair = rules("chair.toml");
    let golden = dir.path().join("golden");
    // A missing golden directory is bad input, blessing or not.
    let o = graftal_in(dir.path(), &["verify", "--golden", "golden", &chair]);
    assert_eq!(code(&o), 2);
    assert!(stderr(&o).contains("does not exist"), "{}", stderr(&o));
    std::fs::create_dir(&golden).unwrap();
    let o = verify(dir.path(), &["--bless"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let o = verify(dir.path(), &[]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));

    // One float of the stats golden moved by one ULP.
    let json_path = golden.join("chair-2.json");
    let original = std::fs::read_to_string(&json_path).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&original).unwrap();
    let area = doc["mesh"]["area"].as_f64().unwrap();
    let nudged = f64::from_bits(area.to_bits() + 1);
    doc["mesh"]["area"] = serde_json::json!(nudged);
    std::fs::write(&json_path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    let o = verify(dir.path(), &[]);
    assert_eq!(code(&o), 1);
    let report = stderr(&o);
    assert!(
        report.contains("chair-2.json: mesh.area: expected"),
        "{report}"
    );
    assert!(report.contains(&nudged.to_string()), "{report}");
    let o = verify(dir.path(), &["--rel-tol", "1e-12"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));

    // One vertex coordinate of the mesh golden moved by one ULP.
    std::fs::write(&json_path, &original).unwrap();
    let obj_path = golden.join("chair-1.obj");
    let obj = std::fs::read_to_string(&obj_path).unwrap();
    let (k, line) = obj
        .lines()
        .enumerate()
        .find(|(_, l)| l.starts_with("v "))
        .unwrap();
    let mut coords: Vec<f64> = line[2..].split(' ').map(|c| c.parse().unwrap()).collect();
    coords[1] = f64::from_bits(coords[1].to_bits() + 1);
    let mut lines: Vec<String> = obj.lines().map(String::from).collect();
    lines[k] = format!("v {} {} {}", coords[0], coords[1], coords[2]);
    std::fs::write(&obj_path, lines.join("\n") + "\n").unwrap();
    let o = verify(dir.path(), &[]);
    assert_eq!(code(&o), 1);
    assert!(
        stderr(&o).contains("chair-1.obj: vertex 1 y: expected"),
        "{}",
        stderr(&o)
    );
    let o = verify(dir.path(), &["--abs-tol", "1e-9"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));

    // --bless puts the truth back.
    verify(dir.path(), &["--bless"]);
    let o = verify(dir.path(), &[]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
}

/// The project's own goldens: every example's stats and mesh, exactly.
#[test]
fn examples_match_the_project_goldens() {
    // Relative paths: the goldens are keyed by them.
    let examples: Vec<String> = examples()
        .iter()
        .map(|p| format!("rules/{}", p.file_name().unwrap().to_string_lossy()))
        .collect();
    let mut args = vec!["verify", "--golden", "tests/golden"];
    args.extend(examples.iter().map(String::as_str));
    let o = graftal(&args);
    assert_eq!(
        code(&o),
        0,
        "{}\nIf the change is intended: graftal verify --golden tests/golden rules/*.toml rules/*.ron --bless",
        stderr(&o)
    );
}

/// A variant whose kernel mesh has 2¹⁶ corners or more is freed on another
/// thread while its files are written (issue 38). Its files, in every
/// format and with stats, are the same bytes on one thread and two, with
/// one job and two, and as a single run.
#[test]
fn large_variants_land_the_same_while_their_mesh_is_freed_alongside() {
    let dir = tempfile::tempdir().unwrap();
    // 150² quads extruded: about 92,000 corners.
    let rules = dir.path().join("large.toml");
    std::fs::write(&rules, SIZED.replace("n = 2", "n = 150")).unwrap();
    let rules = rules.display().to_string();
    for ext in ["glb", "gltf", "ply", "stl", "obj"] {
        let mut runs = Vec::new();
        for (threads, jobs) in [("1", "1"), ("2", "1"), ("2", "2")] {
            let out = dir.path().join(format!("{ext}-t{threads}j{jobs}"));
            std::fs::create_dir(&out).unwrap();
            let o = std::process::Command::new(env!("CARGO_BIN_EXE_graftal"))
                .current_dir(&out)
                .env("RAYON_NUM_THREADS", threads)
                .args(["run", &rules, "--seeds", "0..2", "-j", jobs])
                .args(["-o", &format!("{{seed}}.{ext}"), "--stats", "{seed}.json"])
                .output()
                .unwrap();
            assert_eq!(code(&o), 0, "{}", stderr(&o));
            let made: Vec<_> = files(&out)
                .into_iter()
                .filter(|(path, _)| path != Path::new("manifest.json"))
                .collect();
            // Two meshes and two stats files, and an OBJ's material library.
            assert_eq!(made.len(), if ext == "obj" { 6 } else { 4 }, "{ext}");
            runs.push(made);
        }
        assert!(
            runs.windows(2).all(|w| w[0] == w[1]),
            "{ext}: bytes depend on threads or jobs"
        );
        // A single run of seed 1 writes the batch's variant 1 (under the
        // same name: an OBJ names its material library after itself).
        let single = dir.path().join(format!("single-{ext}"));
        std::fs::create_dir(&single).unwrap();
        let single = single.join(format!("1.{ext}"));
        let o = graftal(&[
            "run",
            &rules,
            "--seed",
            "1",
            "-o",
            &single.display().to_string(),
        ]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let batch = &runs[0]
            .iter()
            .find(|(p, _)| p == Path::new(&format!("1.{ext}")))
            .unwrap()
            .1;
        assert!(
            &std::fs::read(&single).unwrap() == batch,
            "{ext}: a single run differs"
        );
    }
}

/// The manifest records each imported file's SHA-256, which the load now
/// computes on a second core while the file is decoded (`load_inputs`):
/// the same hash at one thread and at two, and a malformed file is still
/// refused with its place in the rule file.
#[test]
fn a_manifest_records_the_hash_of_each_imported_file_at_any_thread_count() {
    use sha2::{Digest, Sha256};
    let dir = tempfile::tempdir().unwrap();
    let mesh = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
    std::fs::write(dir.path().join("quad.obj"), mesh).unwrap();
    std::fs::write(
        dir.path().join("r.toml"),
        "[start]\nimport = { path = \"quad.obj\" }\n[[step]]\nextrude_region = { offset = [0, 0, 1] }\n",
    )
    .unwrap();
    let expected: String = Sha256::digest(mesh.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    for threads in ["1", "2"] {
        let out = format!("t{threads}");
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_graftal"))
            .current_dir(dir.path())
            .env("RAYON_NUM_THREADS", threads)
            .args([
                "run",
                "r.toml",
                "--seeds",
                "0..2",
                "-o",
                &format!("{out}/{{seed}}.ply"),
                "-q",
            ])
            .output()
            .unwrap();
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let manifest: serde_json::Value = serde_json::from_slice(
            &std::fs::read(dir.path().join(&out).join("manifest.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(manifest["inputs"][0]["path"], "quad.obj");
        assert_eq!(manifest["inputs"][0]["sha256"], expected.as_str());
    }
    std::fs::write(dir.path().join("quad.obj"), "v 0 0 0\nf 1 2 9\n").unwrap();
    let o = graftal_in(dir.path(), &["run", "r.toml", "-o", "bad.ply", "-q"]);
    assert_ne!(code(&o), 0);
    assert!(stderr(&o).contains("r.toml:2:"), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("cannot import `quad.obj`"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.path().join("bad.ply").exists());
}
