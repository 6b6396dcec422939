//! PNG encoding with fixed settings, so equal images give equal bytes.

use super::{check_image, Image, PreviewError};

/// Encodes `image` as an 8-bit RGBA PNG.
///
/// Compression level and row filter are fixed and no optional chunks (time,
/// text, gamma) are written, so the bytes depend only on the pixels and the
/// `png` crate version. Errors: [`PreviewError::BadImage`] when the buffer
/// does not match the stated size.
pub fn encode_png(image: &Image) -> Result<Vec<u8>, PreviewError> {
    check_image(image)?;
    let png_err = |e: png::EncodingError| PreviewError::Png(e.to_string());
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, image.width, image.height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Balanced);
    // After set_compression, which would otherwise pick the filter itself.
    encoder.set_filter(png::Filter::Adaptive);
    let mut writer = encoder.write_header().map_err(png_err)?;
    writer.write_image_data(&image.rgba).map_err(png_err)?;
    writer.finish().map_err(png_err)?;
    Ok(out)
}
