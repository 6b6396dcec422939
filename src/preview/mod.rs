//! Software preview renderer: turns a triangle mesh (plus optional wire
//! lines) into a small shaded image, tiles images into a labelled contact
//! sheet, and encodes images as PNG.
//!
//! Everything here is single-threaded and uses no clock, no hashing and no
//! platform maths (transcendentals go through `libm`), so the same input
//! gives the same bytes on every machine.
//!
//! Layout: `camera` frames the scene, `raster` draws it, `font` and `sheet`
//! make contact sheets, `png_out` writes PNG, `mesh` turns the writers'
//! [`crate::geom::IndexedMesh`] into a scene. Knows only `geom`.

mod camera;
mod font;
mod mesh;
mod png_out;
mod raster;
mod sheet;
#[cfg(test)]
mod tests;

use std::fmt;

pub use mesh::SceneData;
pub use png_out::encode_png;
pub use raster::render;
pub use sheet::{contact_sheet, LABEL_HEIGHT, SHEET_PADDING};

/// Largest accepted image width or height, in pixels.
pub const MAX_DIMENSION: u32 = 8192;

/// Largest accepted contact sheet, in total pixels.
pub const MAX_SHEET_PIXELS: u64 = MAX_DIMENSION as u64 * MAX_DIMENSION as u64;

/// Geometry to draw, Z-up (the kernel's convention: +Z is height).
///
/// Only vertices referenced by `triangles` or `lines` are looked at: they
/// must be finite, and they alone decide the camera framing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Scene<'a> {
    /// Vertex positions.
    pub positions: &'a [[f64; 3]],
    /// Triangles over `positions`.
    pub triangles: &'a [[u32; 3]],
    /// One linear-RGB base colour per triangle (components 0..1); empty = all
    /// light grey (0.8). Non-finite components fall back to the grey,
    /// others are clamped to 0..1.
    pub triangle_colors: &'a [[f32; 3]],
    /// Optional per-corner shading normals (`normals[t][k]`); empty = flat
    /// (face normal). Triangles are drawn double-sided: a back-facing
    /// triangle is lit with its normals flipped. A zero or non-finite corner
    /// normal falls back to the face normal.
    pub corner_normals: &'a [[[f64; 3]; 3]],
    /// Wire edges drawn (when [`Options::edges`] is set) as 1-pixel dark
    /// lines, depth-tested against the triangles with a small bias so edges
    /// lying on a surface show.
    pub lines: &'a [[u32; 2]],
}

/// Camera direction. Every view keeps +Z up on screen except
/// [`View::Top`] (+Y up) and [`View::Bottom`] (-Y up).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum View {
    /// Three-quarter view from front-right-above: the camera sits towards
    /// (+1, -1, +0.8) from the target, so the model's -Y "front" shows on the
    /// left, its +X side on the right and its top above.
    Iso,
    /// From -Y looking towards +Y; +X to the right.
    Front,
    /// From +Y looking towards -Y; -X to the right.
    Back,
    /// From -X looking towards +X; -Y to the right.
    Left,
    /// From +X looking towards -X; +Y to the right.
    Right,
    /// From +Z looking down; +X right, +Y up on screen.
    Top,
    /// From -Z looking up; +X right, -Y up on screen.
    Bottom,
}

impl View {
    /// All views, in a fixed order (handy for contact sheets).
    pub const ALL: [View; 7] = [
        View::Iso,
        View::Front,
        View::Back,
        View::Left,
        View::Right,
        View::Top,
        View::Bottom,
    ];

    /// Lower-case name, e.g. for labels and file names.
    pub fn name(self) -> &'static str {
        match self {
            View::Iso => "iso",
            View::Front => "front",
            View::Back => "back",
            View::Left => "left",
            View::Right => "right",
            View::Top => "top",
            View::Bottom => "bottom",
        }
    }
}

/// How 3D points map to the image plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Projection {
    /// Parallel projection; the projected bounding box fills the frame.
    Orthographic,
    /// 35° vertical field of view; the bounding sphere fits the frame.
    Perspective,
}

/// Render settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Image width in pixels, 1..=[`MAX_DIMENSION`].
    pub width: u32,
    /// Image height in pixels, 1..=[`MAX_DIMENSION`].
    pub height: u32,
    /// Camera direction.
    pub view: View,
    /// Camera projection.
    pub projection: Projection,
    /// Flat background colour (sRGB).
    pub background: [u8; 3],
    /// Draw [`Scene::lines`]. The lines count for framing either way, so
    /// toggling this never moves the camera.
    pub edges: bool,
    /// The box (min, max corners) the camera frames instead of the
    /// scene's own bounds: pictures of two meshes framed by one box line
    /// up pixel for pixel (`verify --diff-dir`). Must be finite.
    pub frame: Option<[[f64; 3]; 2]>,
}

impl Default for Options {
    /// 512×512, iso, orthographic, light grey-blue background, no edges.
    fn default() -> Self {
        Options {
            width: 512,
            height: 512,
            view: View::Iso,
            projection: Projection::Orthographic,
            background: [222, 228, 236],
            edges: false,
            frame: None,
        }
    }
}

/// An 8-bit sRGB image with straight alpha, rows top to bottom.
#[derive(Clone, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` RGBA quadruples, row-major from the top-left.
    pub rgba: Vec<u8>,
}

impl Image {
    /// The RGBA value at (`x`, `y`), or `None` outside the image (or if
    /// `rgba` is shorter than the size says).
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 4]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y as usize * self.width as usize + x as usize) * 4;
        let px = self.rgba.get(i..i + 4)?;
        Some([px[0], px[1], px[2], px[3]])
    }
}

// By hand so that a failed assertion does not print megabytes of pixels.
impl fmt::Debug for Image {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Image")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("rgba_len", &self.rgba.len())
            .finish()
    }
}

/// Why an image could not be made.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PreviewError {
    /// Requested size is zero, over [`MAX_DIMENSION`] on a side, or (for a
    /// contact sheet) over [`MAX_SHEET_PIXELS`] in total.
    TooLarge {
        /// Requested width.
        width: u64,
        /// Requested height.
        height: u64,
    },
    /// A used vertex has a NaN or infinite coordinate.
    NonFinite {
        /// Index into [`Scene::positions`].
        vertex: usize,
    },
    /// A triangle or line refers to a vertex that does not exist.
    BadIndex {
        /// `"triangle"` or `"line"`.
        primitive: &'static str,
        /// Which triangle or line.
        element: usize,
        /// The offending vertex index.
        index: u32,
        /// How many positions there are.
        vertex_count: usize,
    },
    /// A per-triangle array is neither empty nor one entry per triangle.
    LengthMismatch {
        /// `"triangle_colors"` or `"corner_normals"`.
        field: &'static str,
        /// Number of triangles.
        expected: usize,
        /// Length given.
        actual: usize,
    },
    /// An image's `rgba` length does not match its size, or its size is 0.
    BadImage {
        /// Stated width.
        width: u32,
        /// Stated height.
        height: u32,
        /// Actual `rgba` length in bytes.
        len: usize,
    },
    /// Contact-sheet tiles differ in size.
    TileMismatch {
        /// Index of the first tile that differs from tile 0.
        tile: usize,
        /// Size of tile 0.
        expected: (u32, u32),
        /// Size of the differing tile.
        actual: (u32, u32),
    },
    /// Contact sheet asked for with no tiles or zero columns.
    EmptySheet,
    /// [`Options::frame`] has a NaN or infinite corner.
    BadFrame,
    /// The PNG encoder failed (not expected when writing to memory).
    Png(String),
}

impl fmt::Display for PreviewError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PreviewError::TooLarge { width, height } => write!(
                f,
                "image size {width}x{height} is out of range (each side 1..={MAX_DIMENSION}, \
                 sheets at most {MAX_SHEET_PIXELS} pixels)"
            ),
            PreviewError::NonFinite { vertex } => {
                write!(f, "vertex {vertex} has a non-finite coordinate")
            }
            PreviewError::BadFrame => write!(f, "the frame box has a non-finite corner"),
            PreviewError::BadIndex {
                primitive,
                element,
                index,
                vertex_count,
            } => write!(
                f,
                "{primitive} {element} uses vertex {index}, but there are only {vertex_count} vertices"
            ),
            PreviewError::LengthMismatch {
                field,
                expected,
                actual,
            } => write!(
                f,
                "{field} has {actual} entries; expected 0 or {expected} (one per triangle)"
            ),
            PreviewError::BadImage { width, height, len } => write!(
                f,
                "image claims {width}x{height} pixels but holds {len} bytes of RGBA"
            ),
            PreviewError::TileMismatch {
                tile,
                expected,
                actual,
            } => write!(
                f,
                "contact sheet tile {tile} is {}x{}, but tile 0 is {}x{}",
                actual.0, actual.1, expected.0, expected.1
            ),
            PreviewError::EmptySheet => {
                write!(f, "contact sheet needs at least one tile and one column")
            }
            PreviewError::Png(msg) => write!(f, "PNG encoding failed: {msg}"),
        }
    }
}

impl std::error::Error for PreviewError {}

/// Checks an output size against [`MAX_DIMENSION`] before anything is
/// allocated.
fn check_dimensions(width: u32, height: u32) -> Result<(), PreviewError> {
    let ok = |d: u32| (1..=MAX_DIMENSION).contains(&d);
    if ok(width) && ok(height) {
        Ok(())
    } else {
        Err(PreviewError::TooLarge {
            width: u64::from(width),
            height: u64::from(height),
        })
    }
}

/// Checks that an image's buffer matches its stated, non-zero size.
fn check_image(image: &Image) -> Result<(), PreviewError> {
    let expected = (image.width as usize)
        .checked_mul(image.height as usize)
        .and_then(|n| n.checked_mul(4));
    if image.width == 0 || image.height == 0 || expected != Some(image.rgba.len()) {
        return Err(PreviewError::BadImage {
            width: image.width,
            height: image.height,
            len: image.rgba.len(),
        });
    }
    Ok(())
}
