//! Criterion benchmarks for the G³ engine: a synthetic grammar grown to
//! 10³…10⁵ primitives (cost per primitive must stay flat), and the house
//! example end to end.

use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use graftal::grammar::{run, RunOptions};
use graftal::rules::compile::{compile, compile_file, parse};
use graftal::rules::diagnostic::SourceFile;
use graftal::rules::spanned::SourceFormat;
use graftal::rules::Program;

/// A grid of `n`×`n` quads; every face fanned, every spoke split, a
/// skeleton edge grown from every node: five commands over the whole model.
fn synthetic(n: u32) -> Program {
    let text = format!(
        r#"
[start]
grid = {{ segments = [{n}, {n}], size = [{n}, {n}] }}
[[step]]
name = "fan"
split_face = {{ length = 0.2 }}
[[step]]
name = "spokes"
select = "faces == 2"
split_edge = {{}}
[[step]]
name = "hairs"
select = "faces >= 2 && pos.z > 0.1"
create_edge = {{ heading = [0, 0, 1], length = 0.3, radius = 0.05, vary_turn = 10 }}
[[step]]
name = "tips"
select = "in_edges == 1 && faces == 0"
create_edge = {{ relative = true, length = 0.5, pitch = 30 }}
[[step]]
name = "lift"
select = "faces == 0 && out_edges == 0"
edit_node = {{ heading = [0, 0, 1], length = 0.1 }}
"#
    );
    let file = SourceFile {
        name: "synthetic.toml".into(),
        text,
    };
    let ast = parse(&file, SourceFormat::Toml).unwrap();
    compile(&file, SourceFormat::Toml, &ast, &[], Path::new(".")).unwrap()
}

fn grammar(c: &mut Criterion) {
    let mut group = c.benchmark_group("grammar");
    group.sample_size(10);
    for n in [8u32, 26, 82] {
        let program = synthetic(n);
        let primitives = {
            let out = run(&program, &RunOptions::default()).unwrap();
            out.mesh.vert_count() + out.mesh.edge_count() + out.mesh.face_count()
        };
        group.throughput(Throughput::Elements(primitives as u64));
        group.bench_with_input(
            BenchmarkId::new("synthetic", primitives),
            &program,
            |b, p| b.iter(|| black_box(run(p, &RunOptions::default()).unwrap())),
        );
    }
    let house = compile_file(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("rules/house.toml"),
        &[],
    )
    .unwrap();
    group.bench_function("house", |b| {
        b.iter(|| black_box(run(&house, &RunOptions::default()).unwrap()))
    });
    group.finish();
}

criterion_group!(benches, grammar);
criterion_main!(benches);
