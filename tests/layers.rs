//! The layering ARCHITECTURE.md promises, checked on the source: file I/O
//! only in `src/cli/files/`, no `unsafe`, and each module using only the
//! modules below it (`geom` nothing, `kernel` only `geom`, the engine not
//! the compiler's internals). Test code (`tests.rs`, `*_tests.rs`,
//! `tests/` folders, and everything after a `#[cfg(test)]` line) is exempt
//! from the I/O rule.

use std::path::{Path, PathBuf};

fn sources() -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut stack = vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("src")];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

/// `src/…` relative path with `/` separators.
fn relative(path: &Path) -> String {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    path.strip_prefix(&src)
        .unwrap()
        .to_string_lossy()
        .replace('\\', "/")
}

fn is_test_file(rel: &str) -> bool {
    rel.ends_with("tests.rs") || rel.ends_with("_tests.rs") || rel.contains("/tests/")
}

/// The file's code before its `#[cfg(test)]` module, comments dropped.
fn production_code(path: &Path) -> Vec<(usize, String)> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .enumerate()
        .take_while(|(_, l)| l.trim() != "#[cfg(test)]")
        .map(|(i, l)| (i + 1, l.split("//").next().unwrap_or("").to_owned()))
        .collect()
}

#[test]
fn file_io_happens_only_in_cli_files() {
    const IO: &[&str] = &[
        "std::fs",
        "fs::",
        "File::",
        ".exists()",
        ".is_dir()",
        ".is_file()",
        "read_dir",
        "canonicalize",
        "current_exe",
        "OpenOptions",
    ];
    let mut found = Vec::new();
    for path in sources() {
        let rel = relative(&path);
        if rel.starts_with("cli/files/") || is_test_file(&rel) {
            continue;
        }
        for (line, code) in production_code(&path) {
            if let Some(pattern) = IO.iter().find(|p| code.contains(*p)) {
                found.push(format!("src/{rel}:{line}: `{pattern}`: {}", code.trim()));
            }
        }
    }
    assert!(
        found.is_empty(),
        "file I/O outside src/cli/files/:\n{}",
        found.join("\n")
    );
}

#[test]
fn there_is_no_unsafe_code() {
    let lib =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("src/lib.rs")).unwrap();
    assert!(lib.contains("#![forbid(unsafe_code)]"));
}

/// The crate modules a file names (`crate::kernel::…` → `kernel`).
fn crate_uses(code: &str) -> Vec<String> {
    let mut uses = Vec::new();
    let mut rest = code;
    while let Some(at) = rest.find("crate::") {
        let tail = &rest[at + "crate::".len()..];
        let name: String = tail
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect();
        if !name.is_empty() {
            uses.push(name);
        }
        rest = tail;
    }
    uses
}

#[test]
fn modules_use_only_the_layers_below_them() {
    // module → the other crate modules it may use (ARCHITECTURE.md).
    let allowed: &[(&str, &[&str])] = &[
        ("geom", &[]),
        ("nurbs", &["geom"]),
        ("kernel", &["geom"]),
        ("sdf", &["geom"]),
        ("io", &["geom", "nurbs"]),
        ("preview", &["geom"]),
        ("rules", &["geom", "kernel", "sdf", "nurbs"]),
        ("grammar", &["geom", "kernel", "sdf", "nurbs", "rules"]),
    ];
    let mut found = Vec::new();
    for path in sources() {
        let rel = relative(&path);
        let module = rel.split(['/', '.']).next().unwrap();
        let Some((_, may)) = allowed.iter().find(|(m, _)| *m == module) else {
            continue;
        };
        for (line, code) in production_code(&path) {
            for used in crate_uses(&code) {
                if used != module && !may.contains(&used.as_str()) {
                    found.push(format!("src/{rel}:{line}: {module} uses crate::{used}"));
                }
            }
            // The engine runs programs; the compiler's internals are not
            // its business (the property table lives in `rules::property`).
            if module == "grammar" && code.contains("rules::compile") {
                found.push(format!("src/{rel}:{line}: grammar uses rules::compile"));
            }
        }
    }
    assert!(found.is_empty(), "layer violations:\n{}", found.join("\n"));
}
