//! The PLY reader, ASCII or binary (either endianness) by header (at most
//! 1 MiB); an accepted mesh is written back as binary and ASCII PLY and
//! must read again.
#![no_main]

#[path = "../common/mod.rs"]
mod common;

use graftal::io::MeshFormat;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    common::check_reader(
        data,
        MeshFormat::PlyBinary,
        &[MeshFormat::PlyBinary, MeshFormat::PlyAscii],
    );
});
