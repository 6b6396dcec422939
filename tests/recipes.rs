//! The README's scheduler recipes, read from the README and run (issue
//! 33): the `graftal` lines of the Kubernetes Indexed Job and of the
//! GitHub Actions matrix with the variables each scheduler sets, and the
//! GNU parallel recipe as a shell script. Each must merge into exactly the
//! manifest and files an unsharded run writes. (The Slurm recipe runs
//! against a real Slurm in `tests/slurm/run.sh`, `make test-slurm`.)
//!
//! One substitution: `--seeds 0..1000` becomes `0..40`, so the suite stays
//! quick; everything else is the README's text.

mod common;
use common::stderr;

use std::path::{Path, PathBuf};
use std::process::Command;

const SEEDS: (&str, &str) = ("--seeds 0..1000", "--seeds 0..40");

/// The body of the fenced block right after `<!-- recipe: NAME -->`.
fn recipe(name: &str) -> String {
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let marker = format!("<!-- recipe: {name} -->");
    let mut lines = readme.lines().skip_while(|l| l.trim() != marker).skip(1);
    let fence = lines
        .next()
        .unwrap_or_else(|| panic!("README.md has no recipe {name}"));
    assert!(
        fence.trim_start().starts_with("```"),
        "recipe {name}: no fence after the marker"
    );
    let body: Vec<&str> = lines
        .take_while(|l| !l.trim_start().starts_with("```"))
        .collect();
    assert_eq!(
        readme.matches(&marker).count(),
        1,
        "recipe {name} appears twice"
    );
    body.join("\n").replace(SEEDS.0, SEEDS.1)
}

/// The `graftal …` command lines of a YAML recipe (a `run:` step or an
/// `args:` item), in order.
fn graftal_lines(block: &str) -> Vec<String> {
    block
        .lines()
        .map(|l| {
            l.trim()
                .trim_start_matches("- ")
                .trim_start_matches("run: ")
                .trim()
        })
        .filter(|l| l.starts_with("graftal "))
        .map(str::to_owned)
        .collect()
}

/// A working directory holding `rules/`, as every recipe expects.
fn workdir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let rules = Path::new(env!("CARGO_MANIFEST_DIR")).join("rules");
    std::os::unix::fs::symlink(rules, dir.path().join("rules")).unwrap();
    dir
}

/// Runs a shell command in `dir` with this graftal first on the PATH.
fn sh(dir: &Path, script: &str, env: &[(&str, String)]) {
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_graftal"));
    let path = format!(
        "{}:{}",
        bin.parent().unwrap().display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut c = Command::new("sh");
    c.args(["-e", "-c", script])
        .current_dir(dir)
        .env("PATH", path);
    for v in [
        "SLURM_ARRAY_TASK_ID",
        "SLURM_ARRAY_TASK_MIN",
        "SLURM_ARRAY_TASK_COUNT",
        "JOB_COMPLETION_INDEX",
        "GRAFTAL_SHARD",
    ] {
        c.env_remove(v);
    }
    for (k, v) in env {
        c.env(k, v);
    }
    let o = c.output().unwrap();
    assert!(o.status.success(), "{script}\n{}", stderr(&o));
}

/// The outputs and manifest of the recipe's batch run unsharded, to
/// compare with.
fn reference(shard_line: &str) -> tempfile::TempDir {
    let dir = workdir();
    let whole: String = shard_line
        .split(' ')
        .filter(|w| !w.starts_with("auto"))
        .collect::<Vec<_>>()
        .join(" ")
        .replace(" --shard", "");
    assert!(!whole.contains("shard"), "{whole}");
    sh(dir.path(), &whole, &[]);
    dir
}

/// Every file under `dir/out` but shard manifests, sorted.
fn out_files(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files: Vec<(PathBuf, Vec<u8>)> = std::fs::read_dir(dir.join("out"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            !p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("manifest.shard-")
        })
        .map(|p| {
            (
                p.strip_prefix(dir).unwrap().to_path_buf(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect();
    files.sort();
    files
}

fn assert_same_batch(got: &Path, want: &Path) {
    assert!(got.join("out/manifest.json").exists(), "no merged manifest");
    let (a, b) = (out_files(got), out_files(want));
    assert_eq!(a.len(), b.len());
    assert!(a == b, "the merged batch differs from the unsharded one");
}

#[test]
fn the_kubernetes_indexed_job_and_its_merge_job_run_as_written() {
    let lines = graftal_lines(&recipe("kubernetes"));
    assert_eq!(lines.len(), 2, "{lines:?}");
    let completions = recipe("kubernetes")
        .lines()
        .find_map(|l| l.trim().strip_prefix("completions: "))
        .map(|n| n.parse::<usize>().unwrap())
        .unwrap();
    let dir = workdir();
    for index in 0..completions {
        sh(
            dir.path(),
            &lines[0],
            &[("JOB_COMPLETION_INDEX", index.to_string())],
        );
    }
    sh(dir.path(), &lines[1], &[]);
    assert_same_batch(dir.path(), reference(&lines[0]).path());
}

#[test]
fn the_github_actions_matrix_and_its_merge_job_run_as_written() {
    let block = recipe("github-actions");
    assert!(
        block.contains("GRAFTAL_SHARD: '${{ matrix.shard }}/4'"),
        "{block}"
    );
    let lines = graftal_lines(&block);
    assert_eq!(lines.len(), 3, "{lines:?}");
    let dir = workdir();
    for shard in 0..4 {
        sh(
            dir.path(),
            &lines[0],
            &[("GRAFTAL_SHARD", format!("{shard}/4"))],
        );
    }
    sh(dir.path(), &lines[1], &[]);
    sh(dir.path(), &lines[2], &[]);
    assert_same_batch(dir.path(), reference(&lines[0]).path());
}

#[test]
fn the_gnu_parallel_recipe_runs_as_written() {
    let have = Command::new("parallel")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !have {
        // CI installs it (`.ci/run`); a machine without it is told so.
        assert!(
            std::env::var_os("CI").is_none(),
            "GNU parallel is not installed (apt-get install parallel)"
        );
        eprintln!("note: GNU parallel is not installed here; skipping its recipe");
        return;
    }
    let block = recipe("gnu-parallel");
    let dir = workdir();
    sh(dir.path(), &block, &[]);
    let first = block.lines().next().unwrap();
    let line = first
        .replace("parallel --retries 2 GRAFTAL_SHARD={}/4 ", "")
        .replace(" ::: 0 1 2 3", "")
        .replace("\"'out/{name}-{seed}.glb'\"", "'out/{name}-{seed}.glb'");
    assert_same_batch(dir.path(), reference(&line).path());
}
