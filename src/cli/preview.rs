//! `graftal preview`: a shaded PNG of a mesh file or of what a rule file
//! makes (issue 16), and the thumbnails of `run --contact-sheet`. The
//! picture comes from [`crate::preview`]'s software rasterizer: the same
//! bytes on every machine.

use std::path::{Path, PathBuf};

use super::{files, Failure, InputArgs};
use crate::grammar::{self, RunOptions};
use crate::preview::{self, Image, Options, Projection, SceneData, View};
use crate::rules::Override;

/// `--view`: one of the renderer's view names.
fn parse_view(text: &str) -> Result<View, String> {
    View::ALL
        .into_iter()
        .find(|v| v.name() == text)
        .ok_or_else(|| {
            let names: Vec<&str> = View::ALL.iter().map(|v| v.name()).collect();
            format!("unknown view `{text}` (one of {})", names.join(", "))
        })
}

/// How previews and thumbnails are drawn.
#[derive(clap::Args, Debug, Clone)]
pub struct LookArgs {
    /// Camera direction: iso (three-quarter from front-right-above),
    /// front (from −Y), back, left, right, top (from +Z), bottom.
    #[arg(long, default_value = "iso", value_parser = parse_view)]
    pub view: View,
    /// Perspective (35° field of view) instead of orthographic.
    #[arg(long)]
    pub perspective: bool,
    /// Image width and height in pixels (1 to 8192).
    #[arg(long, default_value_t = 512, value_name = "PIXELS", value_parser = clap::value_parser!(u32).range(1..=8192))]
    pub size: u32,
}

impl LookArgs {
    pub(crate) fn options(&self, size: u32) -> Options {
        Options {
            width: size,
            height: size,
            view: self.view,
            projection: if self.perspective {
                Projection::Perspective
            } else {
                Projection::Orthographic
            },
            edges: true,
            ..Options::default()
        }
    }
}

#[derive(clap::Args, Debug)]
pub struct PreviewArgs {
    /// Mesh files (OBJ, STL, PLY, glTF, GLB) or rule files (.toml, .ron,
    /// run first). Several inputs make a contact sheet, one labelled
    /// thumbnail each, in the order given.
    #[arg(required = true, value_name = "INPUT")]
    pub inputs: Vec<PathBuf>,
    /// The PNG to write.
    #[arg(short, long, value_name = "OUT.png")]
    pub output: PathBuf,
    #[command(flatten)]
    pub look: LookArgs,
    /// Seed of the rule file's run.
    #[arg(long)]
    pub seed: Option<u64>,
    #[arg(long = "set", value_name = "NAME=VALUE", value_parser = super::parse_override)]
    pub overrides: Vec<Override>,
    #[arg(long, default_value_t = crate::grammar::DEFAULT_MAX_ELEMENTS, value_name = "N")]
    pub max_primitives: usize,
    #[command(flatten)]
    pub input_args: InputArgs,
}

/// Renders `mesh` (Z-up) as a PNG's pixels.
pub(crate) fn render(mesh: &crate::geom::IndexedMesh, options: &Options) -> Result<Image, String> {
    let data = SceneData::new(mesh);
    preview::render(&data.scene(), options).map_err(|e| e.to_string())
}

pub fn run(args: &PreviewArgs) -> Result<(), Failure> {
    if !has_extension(&args.output, "png") {
        return Err(Failure::Input(format!(
            "{}: a preview is a PNG; name the output *.png",
            args.output.display()
        )));
    }
    let options = args.look.options(args.look.size);
    let mut tiles = Vec::with_capacity(args.inputs.len());
    for input in &args.inputs {
        let mesh = load(args, input)?;
        let image = render(&mesh, &options)
            .map_err(|e| Failure::Runtime(format!("{}: {e}", input.display())))?;
        let label = input
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        tiles.push((image, label));
    }
    let image = if tiles.len() == 1 {
        tiles.pop().expect("one tile").0
    } else {
        preview::contact_sheet(&tiles, sheet_columns(tiles.len()))
            .map_err(|e| Failure::Input(format!("contact sheet: {e}")))?
    };
    let png = preview::encode_png(&image).map_err(|e| Failure::Runtime(e.to_string()))?;
    files::write_atomic(&args.output, &png)
        .map_err(|e| Failure::Runtime(format!("cannot write {}: {e}", args.output.display())))
}

/// The mesh `input` holds, or the one its rules make.
fn load(args: &PreviewArgs, input: &Path) -> Result<crate::geom::IndexedMesh, Failure> {
    let is_rules = has_extension(input, "toml") || has_extension(input, "ron");
    if is_rules {
        let program = files::compile_rules(input, &args.overrides)?;
        let inputs = files::load_inputs(&program, args.input_args.policy())?;
        let options = RunOptions {
            seed: args.seed,
            max_elements: args.max_primitives,
            inputs: inputs.meshes,
            ..RunOptions::default()
        };
        let result = grammar::run(&program, &options)
            .map_err(|e| Failure::Limit(super::run_exit_code(e.kind), e.to_string()))?;
        Ok(grammar::export(&program, &result.mesh))
    } else {
        if args.seed.is_some() || !args.overrides.is_empty() {
            return Err(Failure::Input(
                "--seed and --set apply to rule files, not to mesh files".into(),
            ));
        }
        args.input_args.read_mesh(input)
    }
}

/// Columns of a contact sheet of `tiles` thumbnails: near square, at
/// most 8.
pub(crate) fn sheet_columns(tiles: usize) -> u32 {
    ((tiles as f64).sqrt().ceil() as u32).clamp(1, 8)
}

/// Whether `path` ends in `.ext` (any case).
pub(crate) fn has_extension(path: &Path, ext: &str) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case(ext))
}
