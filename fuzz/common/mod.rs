//! Shared by the fuzz targets (each includes it with `#[path]`): input
//! framing, the compile path of `graftal check`, the mesh checks of the
//! readers, and the bounds every target keeps to.
//!
//! Framing of the rule targets: the first byte chooses the format (even:
//! TOML, odd: RON; the seeds use `0` and `1`), the rest is the file.
//! Framing of `info_report`: the first byte chooses the format (see
//! [`mesh_format`]) and the gate tolerance, the rest is the file.

#![allow(dead_code)]

use std::path::Path;
use std::sync::{Arc, OnceLock};

use graftal::geom::IndexedMesh;
use graftal::io::{self, MeshFormat};
use graftal::rules::compile::{compile, parse, source_from_bytes};
use graftal::rules::diagnostic::SourceFile;
use graftal::rules::spanned::SourceFormat;
use graftal::rules::{Program, RuleError};

/// Largest rule file a target reads: rule files are hand-written, and
/// every cost should show at this size already.
pub const MAX_RULE_BYTES: usize = 64 * 1024;

/// Largest mesh file a target reads.
pub const MAX_MESH_BYTES: usize = 1024 * 1024;

/// `graftal run --max-primitives` and `--max-evaluations` for the
/// `rules_run` target: small, so that one execution stays in milliseconds,
/// and an execution that is slow anyway is slow out of proportion.
pub const MAX_ELEMENTS: usize = 20_000;
/// A tenth of the command line's default: a rule that repeats an empty
/// step 999,999 times is within the default (0.8 s in a release build,
/// over the 10 s timeout in the instrumented fuzz build on a busy
/// machine); here it is refused before it starts, as `--max-evaluations
/// 100000` would.
pub const MAX_EVALUATIONS: u64 = 100_000;

/// The rule format and text of a framed input.
pub fn rule_input(data: &[u8]) -> Option<(SourceFormat, &[u8])> {
    let (&first, body) = data.split_first()?;
    if body.len() > MAX_RULE_BYTES {
        return None;
    }
    let format = if first % 2 == 0 {
        SourceFormat::Toml
    } else {
        SourceFormat::Ron
    };
    Some((format, body))
}

/// Renders an error the way the command line does, both colourless and in
/// colour: it must not panic, and its size must stay in proportion to the
/// error's own strings (the snippet shows at most three lines, each cut to
/// `SNIPPET_WIDTH` characters).
pub fn render(error: &RuleError) {
    let headline = error.headline();
    let plain = error.render(false);
    let color = error.render(true);
    let own = error.message.len()
        + error.label.len()
        + error.help.as_ref().map_or(0, String::len)
        + error.location.len();
    // Each shown line is at most ~100 characters of 4 bytes, plus gutter,
    // carets (one per character of the span on its line, cut or not) and
    // frame: allow generously, but not a copy of the whole text per line.
    let span_width = error
        .span
        .as_ref()
        .map_or(0, |s| s.end.saturating_sub(s.start));
    let bound = 4 * own + 3 * span_width + 8 * 1024;
    assert!(
        plain.len() <= bound,
        "render(false) is {} bytes for an error whose own text is {own} bytes",
        plain.len()
    );
    assert!(color.len() <= bound + 256, "render(true) is {} bytes", color.len());
    // The headline is `location: message`, each control character shown as
    // its picture (U+2400..U+2421: one byte becomes three).
    assert!(headline.len() <= 3 * own + 8);
}

/// Parses and compiles rule text as `graftal check` does (no overrides,
/// relative paths under a directory that does not exist: compiling never
/// reads files). Every error is rendered.
pub fn parse_and_compile(format: SourceFormat, body: &[u8]) -> Option<(SourceFile, Program)> {
    let name = match format {
        SourceFormat::Toml => "fuzz.toml",
        SourceFormat::Ron => "fuzz.ron",
    };
    let result = source_from_bytes(name.to_owned(), body.to_vec()).and_then(|file| {
        let ast = parse(&file, format)?;
        let program = compile(&file, &ast, &[], Path::new("/nonexistent/graftal-fuzz"))?;
        Ok((file, program))
    });
    match result {
        Ok(done) => Some(done),
        Err(error) => {
            render(&error);
            None
        }
    }
}

/// What `import` steps get: a unit cube with a wire edge, for every
/// resource the program names (the command line would read the files).
pub fn inputs_for(program: &Program) -> Arc<[graftal::grammar::Input]> {
    static CUBE: OnceLock<Arc<IndexedMesh>> = OnceLock::new();
    let cube = CUBE.get_or_init(|| {
        let obj = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\nv 2 2 2\n\
f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\nl 7 9\n";
        Arc::new(io::decode(obj, MeshFormat::Obj, Path::new("cube.obj")).expect("cube parses"))
    });
    program
        .resources
        .iter()
        .map(|_| graftal::grammar::Input::new(Arc::clone(cube)))
        .collect()
}

/// The formats `info_report` chooses from by its first byte.
pub const INFO_FORMATS: [MeshFormat; 5] = [
    MeshFormat::Obj,
    MeshFormat::StlBinary,
    MeshFormat::PlyBinary,
    MeshFormat::Gltf,
    MeshFormat::Glb,
];

/// Tolerances of `info --tolerance` that `info_report` chooses from.
pub const INFO_TOLERANCES: [f64; 4] = [1e-6, 0.0, 1e-3, 0.25];

/// The file name a format's errors name.
pub fn file_name(format: MeshFormat) -> &'static Path {
    Path::new(match format {
        MeshFormat::Obj => "fuzz.obj",
        MeshFormat::StlAscii | MeshFormat::StlBinary => "fuzz.stl",
        MeshFormat::PlyAscii | MeshFormat::PlyBinary => "fuzz.ply",
        MeshFormat::Gltf => "fuzz.gltf",
        MeshFormat::Glb => "fuzz.glb",
    })
}

/// The reader targets: decode; an error must render; a mesh the reader
/// accepts must be one the writers either refuse with an error or write
/// in a form the same reader accepts again (`convert` in and out).
pub fn check_reader(data: &[u8], read: MeshFormat, write: &[MeshFormat]) {
    if data.len() > MAX_MESH_BYTES {
        return;
    }
    let path = file_name(read);
    let mesh = match io::decode(data, read, path) {
        Ok(mesh) => mesh,
        Err(error) => {
            let _ = error.to_string();
            return;
        }
    };
    for &format in write {
        if let Ok(bytes) = io::encode(&mesh, format) {
            if let Err(error) = io::decode(&bytes, format, file_name(format)) {
                panic!("{format:?} written from an accepted {read:?} does not read back: {error}");
            }
        }
    }
}
