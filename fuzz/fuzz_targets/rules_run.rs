//! Rule-file compile + run (`graftal run --max-primitives 20000
//! --max-evaluations 1000000`), framed as in `rules_compile`. A run must
//! end (result or error) without panicking; the mesh it makes must pass
//! the kernel's invariant checks, report, and either encode or be refused
//! with an error; and a second run of the same program must make the same
//! mesh, bit for bit ("same rule file + seed → the same bytes").
#![no_main]

#[path = "../common/mod.rs"]
mod common;

use graftal::geom::IndexedMesh;
use graftal::grammar::{run, RunOptions};
use graftal::io::{self, MeshFormat};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((format, body)) = common::rule_input(data) else {
        return;
    };
    let Some((_file, program)) = common::parse_and_compile(format, body) else {
        return;
    };
    let options = RunOptions {
        max_elements: common::MAX_ELEMENTS,
        max_evaluations: common::MAX_EVALUATIONS,
        inputs: common::inputs_for(&program),
        ..RunOptions::default()
    };
    let output = match run(&program, &options) {
        Ok(output) => output,
        Err(error) => {
            let _ = error.to_string();
            return;
        }
    };
    let mesh = output.mesh;
    if let Err(error) = mesh.validate() {
        panic!("the run made an invalid mesh: {error}");
    }
    let _ = mesh.report();
    let indexed = mesh.to_indexed();
    match run(&program, &options) {
        Ok(again) => {
            let again = again.mesh.to_indexed();
            if bits(&again) != bits(&indexed) {
                panic!("two runs of one program made different meshes");
            }
        }
        Err(error) => panic!("a second run of one program failed: {error}"),
    }
    for format in [MeshFormat::Obj, MeshFormat::Glb, MeshFormat::StlBinary, MeshFormat::PlyBinary] {
        let _ = io::encode(&indexed, format);
    }
});

/// Everything an indexed mesh holds, floats as bits (NaN equals itself).
fn bits(mesh: &IndexedMesh) -> (Vec<[u64; 3]>, &[u32], &[u32], &[[u32; 2]], Vec<(&str, Vec<u64>)>) {
    (
        mesh.positions.iter().map(|p| p.map(f64::to_bits)).collect(),
        &mesh.face_starts,
        &mesh.face_indices,
        &mesh.lines,
        mesh.vertex_scalars
            .iter()
            .map(|(name, values)| (name.as_str(), values.iter().map(|v| v.to_bits()).collect()))
            .collect(),
    )
}
