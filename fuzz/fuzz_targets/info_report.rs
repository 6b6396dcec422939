//! `graftal info`'s report path: the first byte chooses the format
//! (`% 5`: OBJ, STL, PLY, glTF, GLB) and the close-vertex tolerance
//! (`/ 5 % 4`: 1e-6, 0, 1e-3, 0.25); the rest (at most 1 MiB) is the file.
//! Decode, build the kernel mesh, check its invariants, report, and run
//! both gates with the limits `info` uses (`PairLimits::for_items`).
#![no_main]

#[path = "../common/mod.rs"]
mod common;

use glam::DVec3;
use graftal::io;
use graftal::kernel::build::mesh_from_indexed;
use graftal::kernel::intersect::{count_close_points, self_intersection_search, PairLimits};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&first, body)) = data.split_first() else {
        return;
    };
    if body.len() > common::MAX_MESH_BYTES {
        return;
    }
    let format = common::INFO_FORMATS[first as usize % common::INFO_FORMATS.len()];
    let tolerance = common::INFO_TOLERANCES
        [first as usize / common::INFO_FORMATS.len() % common::INFO_TOLERANCES.len()];
    let Ok(indexed) = io::decode(body, format, common::file_name(format)) else {
        return;
    };
    let Ok((mesh, _import)) = mesh_from_indexed(&indexed) else {
        return;
    };
    if let Err(error) = mesh.validate() {
        panic!("mesh_from_indexed made an invalid mesh: {error}");
    }
    let _report = mesh.report();
    // As `cli::stats::gates`.
    let points: Vec<DVec3> = mesh.vert_ids().map(|v| mesh.position(v)).collect();
    let budget = PairLimits::for_items(points.len()).max_tests;
    let _ = self_intersection_search(&mesh, PairLimits::for_items);
    let _ = count_close_points(&points, tolerance, budget);
});
