//! Criterion benchmarks for the G³ engine: a synthetic grammar grown to
//! 10³…10⁶ primitives (cost per primitive must stay flat), and the house,
//! sofa and tree-in-box examples end to end.

use std::hint::black_box;
use std::path::{Path, PathBuf};

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use graftal::grammar::{run, RunOptions};
use graftal::rules::diagnostic::SourceFile;
use graftal::rules::{compile_source, Override, Program};

/// Compiles a rule file (the benchmarks read it themselves: the library does no I/O).
fn compile_file(path: &Path, overrides: &[Override]) -> Result<Program, graftal::rules::RuleError> {
    let file = SourceFile {
        name: path.display().to_string(),
        text: std::fs::read_to_string(path).expect("rule file"),
    };
    compile_source(&file, overrides, path.parent().unwrap())
}

fn rules(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(name)
}

/// `benches/synthetic.toml` at size `n` (about 28·n² primitives).
fn synthetic(n: u32) -> Program {
    let size = Override::parse(&format!("n={n}")).unwrap();
    compile_file(&rules("benches/synthetic.toml"), &[size]).unwrap()
}

/// Primitives (nodes, edges, faces) of the program's result.
fn primitives(program: &Program) -> u64 {
    let out = run(program, &RunOptions::default()).unwrap();
    (out.mesh.vert_count() + out.mesh.edge_count() + out.mesh.face_count()) as u64
}

/// Bytes per element of the kernel mesh the synthetic grammar grows to
/// ~10⁶ primitives, part by part (issue 38, deliverable 3), printed once:
/// what the records and layers hold, before the allocator's own overhead
/// (the whole process's peak RSS per primitive is `make bench-scaling`).
fn print_memory() {
    let out = run(&synthetic(190), &RunOptions::default()).unwrap();
    let mesh = &out.mesh;
    let primitives = mesh.vert_count() + mesh.edge_count() + mesh.face_count();
    println!(
        "memory at {primitives} primitives ({} vertices, {} edges, {} loops, {} faces):",
        mesh.vert_count(),
        mesh.edge_count(),
        mesh.loop_count(),
        mesh.face_count()
    );
    let mut total = 0;
    for part in mesh.memory() {
        let per = if part.name.starts_with("vertex") || part.name.starts_with("Vert") {
            mesh.vert_count()
        } else if part.name.starts_with("edge") || part.name.starts_with("Edge") {
            mesh.edge_count()
        } else if part.name.starts_with("loop") {
            mesh.loop_count()
        } else {
            mesh.face_count()
        };
        println!(
            "  {:<24} {:>6.2} B per element, {:>5.1} B per primitive",
            part.name,
            part.used as f64 / per.max(1) as f64,
            part.used as f64 / primitives as f64
        );
        total += part.used;
    }
    println!(
        "  total                    {:>5.1} B per primitive",
        total as f64 / primitives as f64
    );
}

fn grammar(c: &mut Criterion) {
    // Only when measuring (`cargo bench`), not when a test runner lists
    // or smoke-runs the benchmarks.
    if std::env::args().any(|a| a == "--bench") {
        print_memory();
    }
    let mut group = c.benchmark_group("grammar");
    group.sample_size(10);
    for n in [8u32, 26, 82, 190] {
        let program = synthetic(n);
        let primitives = primitives(&program);
        group.throughput(Throughput::Elements(primitives));
        group.bench_with_input(
            BenchmarkId::new("synthetic", primitives),
            &program,
            |b, p| b.iter(|| black_box(run(p, &RunOptions::default()).unwrap())),
        );
    }
    for example in ["house", "sofa", "tree-in-box"] {
        let path = rules(&format!("rules/{example}.toml"));
        // tree-in-box without its final field skin: this measures the G³
        // engine (the skin is `cargo bench --bench sdf`).
        let text = std::fs::read_to_string(&path).expect("rule file");
        let file = SourceFile {
            name: path.display().to_string(),
            text: text
                .split("\n# One watertight solid")
                .next()
                .unwrap()
                .to_owned(),
        };
        let program = compile_source(&file, &[], path.parent().unwrap()).unwrap();
        group.throughput(Throughput::Elements(primitives(&program)));
        group.bench_function(example, |b| {
            b.iter(|| black_box(run(&program, &RunOptions::default()).unwrap()))
        });
    }
    group.finish();
}

criterion_group!(benches, grammar);
criterion_main!(benches);
