//! Production batches through the real binary (issue 33): shards from the
//! scheduler's environment, shared folders written from other PID
//! namespaces, `--resume` after deletions, corruption and a kill, the
//! content-addressed `--cache` (hits, misses, corruption, concurrent
//! writers, eviction), strict merges, `manifest check`, and `verify`'s
//! JUnit and picture reports.

mod common;
use common::{graftal_in, stderr, stdout};

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn rules(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("rules")
        .join(name)
        .display()
        .to_string()
}

fn code(o: &Output) -> i32 {
    o.status.code().expect("exited")
}

/// The environment variables `--shard auto` reads: cleared for every run
/// here, so a test run inside a Slurm job still tests what it means to.
const SHARD_VARIABLES: &[&str] = &[
    "SLURM_ARRAY_TASK_ID",
    "SLURM_ARRAY_TASK_MIN",
    "SLURM_ARRAY_TASK_STEP",
    "SLURM_ARRAY_TASK_COUNT",
    "JOB_COMPLETION_INDEX",
    "GRAFTAL_SHARD",
];

/// The binary, in `dir`, with the shard variables cleared, then `env`.
fn command(dir: &Path, args: &[&str], env: &[(&str, String)]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_graftal"));
    c.current_dir(dir).args(args);
    for v in SHARD_VARIABLES {
        c.env_remove(v);
    }
    for (k, v) in env {
        c.env(k, v);
    }
    c
}

fn graftal_env(dir: &Path, args: &[&str], env: &[(&str, String)]) -> Output {
    command(dir, args, env).output().expect("graftal runs")
}

/// Every file under `dir` except manifests and journals, relative path →
/// bytes, sorted.
fn outputs(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if path.is_dir() {
                stack.push(path);
            } else {
                // Manifests, journals and what a killed writer leaves
                // (checked on their own) are not outputs.
                let temp = name.contains(".graftal-") && name.ends_with(".tmp");
                if name.starts_with("manifest") || name.ends_with(".journal") || temp {
                    continue;
                }
                let bytes = std::fs::read(&path).unwrap();
                out.push((path.strip_prefix(dir).unwrap().to_path_buf(), bytes));
            }
        }
    }
    out.sort();
    out
}

fn json(o: &Output) -> serde_json::Value {
    serde_json::from_str(stdout(o).trim()).unwrap_or_else(|e| panic!("{e}: {}", stdout(o)))
}

fn read(path: impl AsRef<Path>) -> Vec<u8> {
    std::fs::read(path.as_ref()).unwrap_or_else(|e| panic!("{}: {e}", path.as_ref().display()))
}

/// Flips one byte in the middle of a file, keeping its size.
fn corrupt(path: &Path) {
    let mut bytes = read(path);
    let k = bytes.len() / 2;
    bytes[k] ^= 0x20;
    std::fs::write(path, bytes).unwrap();
}

/// Whether this machine lets us start processes in a new PID namespace.
fn pid_namespaces() -> bool {
    let ok = Command::new("unshare")
        .args(["--pid", "--fork", "--mount-proc", "true"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        // Root on Linux (CI) can; anywhere else the other writers run in
        // this namespace, which still tests that no writer removes
        // another's temporary files.
        let root = std::fs::read_to_string("/proc/self/status").is_ok_and(|s| {
            s.lines()
                .any(|l| l.starts_with("Uid:") && l.split_whitespace().nth(1) == Some("0"))
        });
        assert!(
            !(cfg!(target_os = "linux") && root),
            "unshare --pid failed as root"
        );
        eprintln!("note: no PID namespaces here; concurrent writers share this one");
    }
    ok
}

/// A graftal run in a new PID namespace when the machine allows it.
fn namespaced(dir: &Path, args: &[&str], namespaces: bool) -> Command {
    let mut c = if namespaces {
        let mut c = Command::new("unshare");
        c.args([
            "--pid",
            "--fork",
            "--mount-proc",
            env!("CARGO_BIN_EXE_graftal"),
        ]);
        c
    } else {
        Command::new(env!("CARGO_BIN_EXE_graftal"))
    };
    c.current_dir(dir).args(args);
    for v in SHARD_VARIABLES {
        c.env_remove(v);
    }
    c
}

// ---- --shard auto ----

#[test]
fn shard_auto_takes_slurm_kubernetes_and_graftal_shard_and_merges_to_the_whole() {
    let chair = rules("chair.toml");
    let batch = [
        "run",
        chair.as_str(),
        "--seeds",
        "0..10",
        "-o",
        "out/{name}-{seed}.glb",
        "-q",
    ];
    let whole = tempfile::tempdir().unwrap();
    assert_eq!(code(&graftal_env(whole.path(), &batch, &[])), 0);
    type Environment = dyn Fn(usize) -> Vec<(&'static str, String)>;
    let schedulers: [(&str, &Environment); 4] = [
        // A Slurm array numbered 10-13.
        ("auto", &|i| {
            vec![
                ("SLURM_ARRAY_TASK_ID", (10 + i).to_string()),
                ("SLURM_ARRAY_TASK_MIN", "10".into()),
                ("SLURM_ARRAY_TASK_COUNT", "4".into()),
            ]
        }),
        // A stepped Slurm array, --array=0-6:2.
        ("auto", &|i| {
            vec![
                ("SLURM_ARRAY_TASK_ID", (2 * i).to_string()),
                ("SLURM_ARRAY_TASK_MIN", "0".into()),
                ("SLURM_ARRAY_TASK_STEP", "2".into()),
                ("SLURM_ARRAY_TASK_COUNT", "4".into()),
            ]
        }),
        ("auto/4", &|i| vec![("JOB_COMPLETION_INDEX", i.to_string())]),
        ("auto", &|i| vec![("GRAFTAL_SHARD", format!("{i}/4"))]),
    ];
    for (flag, env) in schedulers {
        let dir = tempfile::tempdir().unwrap();
        for i in 0..4 {
            let mut args = batch.to_vec();
            args.extend(["--shard", flag]);
            let o = graftal_env(dir.path(), &args, &env(i));
            assert_eq!(code(&o), 0, "{flag} {:?}: {}", env(i), stderr(&o));
            assert!(dir
                .path()
                .join(format!("out/manifest.shard-{i}-of-4.json"))
                .exists());
        }
        let shards: Vec<String> = (0..4)
            .map(|i| format!("out/manifest.shard-{i}-of-4.json"))
            .collect();
        let mut args = vec!["manifest", "merge"];
        args.extend(shards.iter().map(String::as_str));
        args.extend(["-o", "out/manifest.json"]);
        let o = graftal_in(dir.path(), &args);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        assert_eq!(
            read(dir.path().join("out/manifest.json")),
            read(whole.path().join("out/manifest.json"))
        );
        assert!(outputs(dir.path()) == outputs(whole.path()));
    }
}

#[test]
fn shard_auto_refuses_a_missing_or_ambiguous_environment() {
    let dir = tempfile::tempdir().unwrap();
    let chair = rules("chair.toml");
    let run = |flag: &str, env: &[(&str, &str)]| {
        let env: Vec<(&str, String)> = env.iter().map(|(k, v)| (*k, v.to_string())).collect();
        graftal_env(
            dir.path(),
            &[
                "run",
                &chair,
                "--seeds",
                "0..4",
                "-o",
                "o/{seed}.glb",
                "--shard",
                flag,
            ],
            &env,
        )
    };
    let slurm = [
        ("SLURM_ARRAY_TASK_ID", "1"),
        ("SLURM_ARRAY_TASK_MIN", "0"),
        ("SLURM_ARRAY_TASK_COUNT", "4"),
    ];
    type Case<'a> = (&'a str, Vec<(&'a str, &'a str)>, &'a str);
    let cases: Vec<Case> = vec![
        ("auto", vec![], "looked for SLURM_ARRAY_TASK_ID"),
        ("auto", vec![], "JOB_COMPLETION_INDEX"),
        (
            "auto",
            vec![("JOB_COMPLETION_INDEX", "1")],
            "--shard auto/N",
        ),
        ("auto/3", slurm.to_vec(), "counts disagree"),
        (
            "auto",
            [&slurm[..], &[("GRAFTAL_SHARD", "2/4")]].concat(),
            "indices disagree",
        ),
        (
            "auto",
            vec![("GRAFTAL_SHARD", "4/4")],
            "numbered from 0 to 3",
        ),
        (
            "auto",
            vec![("SLURM_ARRAY_TASK_ID", "3")],
            "SLURM_ARRAY_TASK_MIN is not",
        ),
        (
            "auto",
            vec![("JOB_COMPLETION_INDEX", "x")],
            "not a whole number",
        ),
        ("auto/0", vec![], "at least 1"),
    ];
    for (flag, env, expected) in cases {
        let o = run(flag, &env);
        assert_eq!(code(&o), 2, "{flag} {env:?}");
        assert!(
            stderr(&o).contains(expected),
            "{flag} {env:?}: {}",
            stderr(&o)
        );
        assert!(!stderr(&o).contains("panicked"));
    }
    assert!(!dir.path().join("o").exists(), "nothing written");
    // Agreeing sources are fine.
    let o = run(
        "auto/4",
        &[&slurm[..], &[("GRAFTAL_SHARD", "1/4")]].concat(),
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert!(dir.path().join("o/manifest.shard-1-of-4.json").exists());
}

// ---- shared folders ----

#[test]
fn a_shared_folder_loses_no_variant_to_writers_in_other_pid_namespaces() {
    let dir = tempfile::tempdir().unwrap();
    let cup = rules("cup.toml");
    let namespaces = pid_namespaces();
    let main = command(
        dir.path(),
        &[
            "run",
            &cup,
            "--seeds",
            "0..100",
            "-o",
            "out/cup-{seed}.glb",
            "-j1",
            "-q",
            "--json",
        ],
        &[],
    )
    .stdout(Stdio::piped())
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    // Other batches start into the same folder, one after another, for as
    // long as the main one writes (each first write used to sweep the
    // temporary files of every process it could not see).
    let mut others = 0;
    let started = Instant::now();
    let mut failures = Vec::new();
    while std::fs::metadata(dir.path().join("out/manifest.json")).is_err()
        && started.elapsed() < Duration::from_secs(300)
    {
        let manifest = format!("out/other-{others}.json");
        let o = namespaced(
            dir.path(),
            &[
                "run",
                &cup,
                "--seeds",
                "1000..1003",
                "-o",
                "out/o{seed}.glb",
                "--manifest",
                &manifest,
                "-q",
            ],
            namespaces,
        )
        .output()
        .unwrap();
        if code(&o) != 0 {
            failures.push(stderr(&o));
        }
        others += 1;
    }
    let main = main.wait_with_output().unwrap();
    assert!(failures.is_empty(), "{failures:?}");
    assert!(
        others >= 2,
        "the other writers ran during the batch ({others})"
    );
    assert_eq!(code(&main), 0, "{}", stderr(&main));
    let summary = json(&main);
    assert_eq!(
        (summary["ok"].as_u64(), summary["failed"].as_u64()),
        (Some(100), Some(0))
    );
    let o = graftal_in(dir.path(), &["manifest", "check", "out/manifest.json"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    // Nothing half-written is left.
    let leftovers: Vec<String> = std::fs::read_dir(dir.path().join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp") || n.ends_with(".journal"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

// ---- --resume ----

#[test]
fn resume_redoes_only_what_is_missing_or_corrupt_and_writes_the_same_manifest() {
    let chair = rules("chair.toml");
    let args = [
        "run",
        chair.as_str(),
        "--seeds",
        "0..10",
        "-o",
        "out/{name}-{seed}.obj",
        "--stats",
        "stats/{seed}.json",
        "-q",
        "--json",
    ];
    let fresh = tempfile::tempdir().unwrap();
    assert_eq!(code(&graftal_env(fresh.path(), &args, &[])), 0);
    let manifest: serde_json::Value =
        serde_json::from_slice(&read(fresh.path().join("out/manifest.json"))).unwrap();
    // The .mtl and the stats file are listed with their hashes.
    let extra = manifest["variants"][0]["extra_files"].as_array().unwrap();
    let paths: Vec<&str> = extra.iter().map(|f| f["path"].as_str().unwrap()).collect();
    assert_eq!(paths, ["out/chair-0.mtl", "stats/0.json"]);

    let dir = tempfile::tempdir().unwrap();
    assert_eq!(code(&graftal_env(dir.path(), &args, &[])), 0);
    let d = dir.path();
    std::fs::remove_file(d.join("out/chair-1.obj")).unwrap();
    corrupt(&d.join("out/chair-2.obj"));
    std::fs::write(d.join("out/chair-3.mtl"), b"").unwrap();
    std::fs::remove_file(d.join("stats/4.json")).unwrap();
    let mut resume = args.to_vec();
    resume.push("--resume");
    let o = graftal_env(d, &resume, &[]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert_eq!(json(&o)["resumed"], 6);
    assert_eq!(
        read(d.join("out/manifest.json")),
        read(fresh.path().join("out/manifest.json"))
    );
    assert!(outputs(d) == outputs(fresh.path()));
    // Nothing to do: everything is resumed, and the bytes stay.
    let o = graftal_env(d, &resume, &[]);
    assert_eq!(json(&o)["resumed"], 10);
    assert_eq!(
        read(d.join("out/manifest.json")),
        read(fresh.path().join("out/manifest.json"))
    );

    // Another batch's manifest is not trusted: a warning, everything made.
    let mut other = resume.clone();
    other[3] = "0..12";
    let o = graftal_env(d, &other, &[]);
    assert_eq!(code(&o), 0);
    assert_eq!(json(&o)["resumed"], 0);
    assert!(
        stderr(&o).contains("a different batch (batch.seeds: \"0..12\" vs \"0..10\")"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn resume_after_a_kill_finishes_the_batch_from_its_journal() {
    let chair = rules("house.toml");
    let args = [
        "run",
        chair.as_str(),
        "--seeds",
        "0..1000",
        "-o",
        "out/{seed}.glb",
        "-j1",
        "-q",
        "--json",
    ];
    let fresh = tempfile::tempdir().unwrap();
    assert_eq!(code(&graftal_env(fresh.path(), &args, &[])), 0);
    let dir = tempfile::tempdir().unwrap();
    let journal = dir.path().join("out/.manifest.json.journal");
    let mut child = command(dir.path(), &args, &[])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let started = Instant::now();
    loop {
        let lines = std::fs::read_to_string(&journal).map_or(0, |t| t.lines().count());
        if lines > 20 || started.elapsed() > Duration::from_secs(120) {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(
        !dir.path().join("out/manifest.json").exists(),
        "killed before its end"
    );
    let done = std::fs::read_to_string(&journal).unwrap().lines().count() - 1;
    let mut resume = args.to_vec();
    resume.push("--resume");
    let o = graftal_env(dir.path(), &resume, &[]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let resumed = json(&o)["resumed"].as_u64().unwrap() as usize;
    assert!(
        resumed >= done.min(20) && resumed < 1000,
        "{resumed} resumed, {done} journaled"
    );
    assert_eq!(
        read(dir.path().join("out/manifest.json")),
        read(fresh.path().join("out/manifest.json"))
    );
    assert!(outputs(dir.path()) == outputs(fresh.path()));
    // The killed run may have left a temporary file mid-write: `clean`
    // removes it (no run writes there now).
    let o = graftal_in(dir.path(), &["clean", "out"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let left: Vec<String> = std::fs::read_dir(dir.path().join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
    assert!(
        !journal.exists(),
        "the journal goes once the manifest is written"
    );
}

#[test]
fn resume_refuses_what_it_cannot_restore() {
    let dir = tempfile::tempdir().unwrap();
    let chair = rules("chair.toml");
    for (extra, words) in [
        (&["--seeds", "0..2", "--stats", "-"][..], "NDJSON"),
        (
            &["--seeds", "0..2", "--contact-sheet", "s.png"][..],
            "contact sheet",
        ),
        (&[][..], "needs a batch manifest"),
    ] {
        let mut args = vec!["run", chair.as_str(), "-o", "{seed}.glb", "--resume"];
        args.extend_from_slice(extra);
        let o = graftal_env(dir.path(), &args, &[]);
        assert_eq!(code(&o), 2, "{extra:?}");
        assert!(stderr(&o).contains(words), "{}", stderr(&o));
    }
}

// ---- --cache ----

fn cache_size(dir: &Path) -> u64 {
    let mut total = 0;
    let mut stack = vec![dir.join("graftal-cache-1/entries")];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let e = e.unwrap();
            if e.file_type().unwrap().is_dir() {
                stack.push(e.path());
            } else {
                total += e.metadata().unwrap().len();
            }
        }
    }
    total
}

fn cache_files(dir: &Path, role: &str) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for shard in std::fs::read_dir(dir.join("graftal-cache-1/entries")).unwrap() {
        for entry in std::fs::read_dir(shard.unwrap().path()).unwrap() {
            let f = entry.unwrap().path().join(role);
            if f.exists() {
                found.push(f);
            }
        }
    }
    found.sort();
    found
}

#[test]
fn the_cache_restores_the_same_bytes_and_manifest_and_misses_on_any_change() {
    let chair = rules("chair.toml");
    let cache = tempfile::tempdir().unwrap();
    let c = cache.path().display().to_string();
    let batch_to = |output: &str, extra: &[&str]| -> Vec<String> {
        let mut a: Vec<String> = [
            "run",
            chair.as_str(),
            "--seeds",
            "0..8",
            "-o",
            output,
            "--stats",
            "-",
            "-q",
            "--json",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let batch = |extra: &[&str]| batch_to("out/{name}-{seed}.obj", extra);
    let run = |dir: &Path, args: &[String]| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        graftal_env(dir, &args, &[])
    };
    let plain = tempfile::tempdir().unwrap();
    let reference = run(plain.path(), &batch(&[]));
    assert_eq!(code(&reference), 0);
    let ndjson = |o: &Output| {
        stdout(o)
            .lines()
            .filter(|l| l.contains("\"stats\"") || l.contains("\"mesh\""))
            .map(str::to_owned)
            .collect::<Vec<_>>()
    };

    let cold = tempfile::tempdir().unwrap();
    let o = run(cold.path(), &batch(&["--cache", &c]));
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let summary: serde_json::Value =
        serde_json::from_str(stdout(&o).lines().last().unwrap()).unwrap();
    assert_eq!(summary["cache_hits"], 0);
    assert!(outputs(cold.path()) == outputs(plain.path()));
    assert_eq!(
        read(cold.path().join("out/manifest.json")),
        read(plain.path().join("out/manifest.json"))
    );

    let warm = tempfile::tempdir().unwrap();
    let o = run(warm.path(), &batch(&["--cache", &c]));
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let summary: serde_json::Value =
        serde_json::from_str(stdout(&o).lines().last().unwrap()).unwrap();
    assert_eq!(summary["cache_hits"], 8);
    assert!(outputs(warm.path()) == outputs(plain.path()));
    assert_eq!(
        read(warm.path().join("out/manifest.json")),
        read(plain.path().join("out/manifest.json"))
    );
    // The NDJSON stats come back from the cache byte for byte.
    assert_eq!(ndjson(&o), ndjson(&reference));
    let hits = |o: &Output| {
        let summary: serde_json::Value =
            serde_json::from_str(stdout(o).lines().last().unwrap()).unwrap();
        summary["cache_hits"].as_u64().unwrap()
    };

    // A corrupted entry is a miss, never wrong bytes; it is stored again.
    let meshes = cache_files(cache.path(), "mesh");
    assert_eq!(meshes.len(), 8);
    corrupt(&meshes[3]);
    let again = tempfile::tempdir().unwrap();
    let o = run(again.path(), &batch(&["--cache", &c]));
    assert_eq!(hits(&o), 7);
    assert!(outputs(again.path()) == outputs(plain.path()));
    let o = run(
        tempfile::tempdir().unwrap().path(),
        &batch(&["--cache", &c]),
    );
    assert_eq!(hits(&o), 8);

    // A different override, format or limit is a different key.
    for args in [
        batch(&["--cache", &c, "--set", "width=1.1"]),
        batch_to("out/{name}-{seed}.glb", &["--cache", &c]),
        batch(&["--cache", &c, "--max-primitives", "123456"]),
    ] {
        let o = run(tempfile::tempdir().unwrap().path(), &args);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        assert_eq!(hits(&o), 0, "{args:?}");
    }

    // A single run restores from the cache too, and says so.
    let single = tempfile::tempdir().unwrap();
    for round in 0..2 {
        let o = graftal_env(
            single.path(),
            &["run", &chair, "--seed", "100", "-o", "c.glb", "--cache", &c],
            &[],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        assert_eq!(
            stderr(&o).contains("from the cache"),
            round == 1,
            "{}",
            stderr(&o)
        );
    }
    let o = graftal_env(
        plain.path(),
        &["run", &chair, "--seed", "100", "-o", "c.glb"],
        &[],
    );
    assert_eq!(code(&o), 0);
    assert_eq!(
        read(single.path().join("c.glb")),
        read(plain.path().join("c.glb"))
    );

    // A contact sheet's thumbnails come from the cache as well.
    let sheet = |dir: &Path| {
        let o = graftal_env(
            dir,
            &[
                "run",
                &chair,
                "--seeds",
                "0..3",
                "-o",
                "{seed}.glb",
                "--contact-sheet",
                "s.png",
                "--cache",
                &c,
                "-q",
            ],
            &[],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        read(dir.join("s.png"))
    };
    let first = sheet(tempfile::tempdir().unwrap().path());
    assert_eq!(sheet(tempfile::tempdir().unwrap().path()), first);
}

#[test]
fn the_cache_survives_concurrent_writers_and_keeps_within_its_size() {
    let chair = rules("chair.toml");
    let cache = tempfile::tempdir().unwrap();
    let c = cache.path().display().to_string();
    let args = [
        "run",
        chair.as_str(),
        "--seeds",
        "0..60",
        "-o",
        "out/{seed}.glb",
        "-q",
        "--json",
        "-j1",
        "--cache",
        c.as_str(),
    ];
    let reference = tempfile::tempdir().unwrap();
    assert_eq!(code(&graftal_env(reference.path(), &args[..9], &[])), 0);
    // Two batches at once on one cache, one in another PID namespace.
    let namespaces = pid_namespaces();
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let first = namespaced(a.path(), &args, namespaces)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let second = command(b.path(), &args, &[])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    for (o, dir) in [
        (first.wait_with_output().unwrap(), &a),
        (second.wait_with_output().unwrap(), &b),
    ] {
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        assert!(outputs(dir.path()) == outputs(reference.path()));
        assert_eq!(
            read(dir.path().join("out/manifest.json")),
            read(reference.path().join("out/manifest.json"))
        );
    }
    // Whatever interleaving, the store is whole: a third run hits all.
    let third = tempfile::tempdir().unwrap();
    let o = graftal_env(third.path(), &args, &[]);
    assert_eq!(json(&o)["cache_hits"], 60);
    assert!(outputs(third.path()) == outputs(reference.path()));
    assert!(std::fs::read_dir(cache.path().join("graftal-cache-1/tmp"))
        .unwrap()
        .next()
        .is_none());

    // Bounded: the least recently used entries go first.
    let full = cache_size(cache.path());
    let bound = full / 3;
    let mut bounded = args.to_vec();
    let size = format!("{bound}");
    bounded.extend(["--cache-max-size", size.as_str()]);
    bounded[3] = "40..60";
    let o = graftal_env(tempfile::tempdir().unwrap().path(), &bounded, &[]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert!(json(&o)["cache_evicted"].as_u64().unwrap() > 0);
    assert!(cache_size(cache.path()) <= bound);
    // The seeds just used (40..60, about a third) are the ones kept.
    let o = graftal_env(tempfile::tempdir().unwrap().path(), &bounded, &[]);
    let hits = json(&o)["cache_hits"].as_u64().unwrap();
    assert!(hits >= 15, "{hits} of 20 recent entries kept");
}

// ---- merge and check ----

fn shards_with_a_failure(dir: &Path) {
    // n = 40 is over --max-primitives: those variants fail.
    let text = "[params]\nn = 2\n[start]\ngrid = { segments = [\"n\", \"n\"] }\n";
    std::fs::write(dir.join("g.toml"), text).unwrap();
    for i in 0..2 {
        let shard = format!("{i}/2");
        let o = graftal_env(
            dir,
            &[
                "run",
                "g.toml",
                "--seeds",
                "0..2",
                "--grid",
                "n=2,40",
                "-o",
                "out/{index}.obj",
                "--max-primitives",
                "1000",
                "--shard",
                &shard,
                "-q",
            ],
            &[],
        );
        assert_eq!(code(&o), 3, "{}", stderr(&o));
    }
}

#[test]
fn a_merge_with_failed_variants_fails_but_writes_the_manifest() {
    let dir = tempfile::tempdir().unwrap();
    shards_with_a_failure(dir.path());
    let merge = |extra: &[&str]| {
        let mut a = vec![
            "manifest",
            "merge",
            "out/manifest.shard-0-of-2.json",
            "out/manifest.shard-1-of-2.json",
            "-o",
            "out/manifest.json",
        ];
        a.extend_from_slice(extra);
        graftal_in(dir.path(), &a)
    };
    let o = merge(&[]);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    assert!(
        stderr(&o).contains("2 of 4 variants failed and 0 did not run; the first: variant 2"),
        "{}",
        stderr(&o)
    );
    let m: serde_json::Value =
        serde_json::from_slice(&read(dir.path().join("out/manifest.json"))).unwrap();
    assert_eq!(m["summary"]["failed"], 2);
    assert_eq!(code(&merge(&["--allow-failed"])), 0);
    // `manifest check` says the same, and names the failures.
    let o = graftal_in(dir.path(), &["manifest", "check", "out/manifest.json"]);
    assert_eq!(code(&o), 1);
    assert!(
        stderr(&o).contains("out/2.obj: variant 2 (seed 0) failed"),
        "{}",
        stderr(&o)
    );
    let o = graftal_in(
        dir.path(),
        &["manifest", "check", "out/manifest.json", "--allow-failed"],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
}

#[test]
fn merging_shards_of_different_batches_names_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let chair = rules("chair.toml");
    for (i, width) in [(0, "width=1"), (1, "width=1.2")] {
        let shard = format!("{i}/2");
        let o = graftal_env(
            dir.path(),
            &[
                "run",
                &chair,
                "--seeds",
                "0..2",
                "--set",
                width,
                "--shard",
                &shard,
                "-o",
                "{seed}.glb",
                "-q",
            ],
            &[],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
    }
    let o = graftal_in(
        dir.path(),
        &[
            "manifest",
            "merge",
            "manifest.shard-0-of-2.json",
            "manifest.shard-1-of-2.json",
            "-o",
            "m.json",
        ],
    );
    assert_eq!(code(&o), 2);
    assert!(
        stderr(&o).contains("not shards of one batch: batch.set: [\"width=1\"] vs [\"width=1.2\"]"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.path().join("m.json").exists());
}

#[test]
fn manifest_check_names_each_missing_or_changed_file() {
    let dir = tempfile::tempdir().unwrap();
    let chair = rules("chair.toml");
    let o = graftal_env(
        dir.path(),
        &[
            "run",
            &chair,
            "--seeds",
            "0..5",
            "-o",
            "out/{seed}.obj",
            "-q",
        ],
        &[],
    );
    assert_eq!(code(&o), 0);
    let o = graftal_in(dir.path(), &["manifest", "check", "out/manifest.json"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert!(
        stderr(&o).contains("10 files of 5 variants match"),
        "{}",
        stderr(&o)
    );
    std::fs::remove_file(dir.path().join("out/1.obj")).unwrap();
    corrupt(&dir.path().join("out/2.obj"));
    std::fs::write(dir.path().join("out/3.mtl"), b"newmtl x\n").unwrap();
    let o = graftal_in(dir.path(), &["manifest", "check", "out/manifest.json"]);
    assert_eq!(code(&o), 1);
    let err = stderr(&o);
    assert!(err.contains("out/1.obj: missing"), "{err}");
    assert!(err.contains("out/2.obj: SHA-256 "), "{err}");
    assert!(
        err.contains("out/3.mtl: 9 bytes, the manifest records"),
        "{err}"
    );
    assert!(err.contains("3 problem(s) in 5 variants"), "{err}");
    assert_eq!(
        code(&graftal_in(dir.path(), &["manifest", "check", "nope.json"])),
        2
    );
}

// ---- verify reports ----

#[test]
fn verify_writes_a_junit_report_and_pictures_of_what_changed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let chair = rules("chair.toml");
    let cube = rules("cube-from-vertex.ron");
    let verify = |extra: &[&str]| {
        let mut a = vec![
            "verify",
            "--golden",
            "g",
            chair.as_str(),
            cube.as_str(),
            "--seeds",
            "0..2",
        ];
        a.extend_from_slice(extra);
        graftal_in(d, &a)
    };
    std::fs::create_dir(d.join("g")).unwrap();
    assert_eq!(code(&verify(&["--bless"])), 0);
    // All match: a report without failures, no pictures.
    let o = verify(&["--junit", "ok.xml", "--diff-dir", "diffs-ok"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let text = std::fs::read_to_string(d.join("ok.xml")).unwrap();
    let xml = roxmltree::Document::parse(&text).unwrap();
    let root = xml.root_element();
    assert_eq!(
        (root.attribute("tests"), root.attribute("failures")),
        (Some("4"), Some("0"))
    );
    assert!(
        !d.join("diffs-ok").exists()
            || std::fs::read_dir(d.join("diffs-ok"))
                .unwrap()
                .next()
                .is_none()
    );

    // Move one vertex of chair seed 1 and edit cube seed 0's stats.
    let obj = std::fs::read_to_string(d.join("g/chair-1.obj")).unwrap();
    let line = obj.lines().find(|l| l.starts_with("v ")).unwrap();
    std::fs::write(
        d.join("g/chair-1.obj"),
        obj.replacen(line, "v 0.5 0.5 5", 1),
    )
    .unwrap();
    let stats = std::fs::read_to_string(d.join("g/cube-from-vertex-0.json")).unwrap();
    std::fs::write(
        d.join("g/cube-from-vertex-0.json"),
        stats.replacen("\"seed\": 0", "\"seed\": 9", 1),
    )
    .unwrap();
    let o = verify(&["--junit", "report.xml", "--diff-dir", "diffs"]);
    assert_eq!(code(&o), 1);
    let text = std::fs::read_to_string(d.join("report.xml")).unwrap();
    let xml = roxmltree::Document::parse(&text).unwrap();
    let root = xml.root_element();
    assert_eq!(root.tag_name().name(), "testsuites");
    assert_eq!(
        (root.attribute("tests"), root.attribute("failures")),
        (Some("4"), Some("2"))
    );
    let cases: Vec<roxmltree::Node> = xml
        .descendants()
        .filter(|n| n.has_tag_name("testcase"))
        .collect();
    assert_eq!(cases.len(), 4);
    let failure = |classname: &str, name: &str| {
        let case = cases
            .iter()
            .find(|c| {
                c.attribute("classname") == Some(classname) && c.attribute("name") == Some(name)
            })
            .unwrap_or_else(|| panic!("no testcase {classname} {name}"));
        case.children()
            .find(|n| n.has_tag_name("failure"))
            .map(|f| {
                (
                    f.attribute("message").unwrap().to_owned(),
                    f.text().unwrap_or("").to_owned(),
                )
            })
    };
    let (message, body) = failure(&chair, "seed 1").expect("chair seed 1 fails");
    assert!(
        message.contains("difference(s) from the goldens"),
        "{message}"
    );
    assert!(
        body.contains("chair-1.obj: vertex 1 x: expected 0.5"),
        "{body}"
    );
    assert!(failure(&chair, "seed 0").is_none());
    let (_, body) = failure(&cube, "seed 0").expect("cube seed 0 fails");
    assert!(body.contains("seed: expected 9, got 0"), "{body}");

    // A picture per changed variant: golden | new | difference.
    let mut pictures: Vec<String> = std::fs::read_dir(d.join("diffs"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    pictures.sort();
    assert_eq!(pictures, ["chair-1.png", "cube-from-vertex-0.png"]);
    let magenta = |name: &str| {
        let decoder = png::Decoder::new(std::io::BufReader::new(
            std::fs::File::open(d.join("diffs").join(name)).unwrap(),
        ));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert!(
            info.width > 3 * 256 && info.height > 256,
            "{}x{}",
            info.width,
            info.height
        );
        let channels = info.line_size / info.width as usize;
        buf[..info.buffer_size()]
            .chunks(channels)
            .filter(|p| p[..3] == [255, 0, 255])
            .count()
    };
    // The moved vertex shows; a stats-only change draws two same pictures.
    assert!(magenta("chair-1.png") > 20);
    assert_eq!(magenta("cube-from-vertex-0.png"), 0);
}
