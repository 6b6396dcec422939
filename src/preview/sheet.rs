//! Contact sheets: equally sized images in a grid, each labelled below.

use super::font::{self, Canvas};
use super::{check_image, Image, PreviewError, MAX_SHEET_PIXELS};

/// Height of the label band under each tile, in pixels.
pub const LABEL_HEIGHT: u32 = 22;
/// White space around and between cells, in pixels.
pub const SHEET_PADDING: u32 = 4;
/// Label colour (sRGB).
const TEXT_SRGB: [u8; 3] = [20, 20, 20];

/// Tiles images in a grid of `columns` columns (fewer if there are fewer
/// tiles), each with its label centred under it, on a white background.
///
/// Each cell is the tile plus a [`LABEL_HEIGHT`] band; cells are separated
/// and surrounded by [`SHEET_PADDING`] pixels, so the sheet is
/// `c * (w + P) + P` by `r * (h + L + P) + P` for `c` used columns and `r`
/// rows. Labels are ASCII (anything else prints as '?') and are cut to the
/// tile width.
///
/// Errors: [`PreviewError::EmptySheet`] for no tiles or zero columns,
/// [`PreviewError::BadImage`] / [`PreviewError::TileMismatch`] for a tile
/// whose buffer is inconsistent or whose size differs from the first, and
/// [`PreviewError::TooLarge`] past [`MAX_SHEET_PIXELS`].
pub fn contact_sheet(tiles: &[(Image, String)], columns: u32) -> Result<Image, PreviewError> {
    let Some((first, _)) = tiles.first() else {
        return Err(PreviewError::EmptySheet);
    };
    if columns == 0 {
        return Err(PreviewError::EmptySheet);
    }
    let (w, h) = (first.width, first.height);
    for (t, (tile, _)) in tiles.iter().enumerate() {
        check_image(tile)?;
        if (tile.width, tile.height) != (w, h) {
            return Err(PreviewError::TileMismatch {
                tile: t,
                expected: (w, h),
                actual: (tile.width, tile.height),
            });
        }
    }

    // u64 throughout: the inputs are unbounded until checked.
    let count = tiles.len() as u64;
    let cols = u64::from(columns).min(count);
    let rows = count.div_ceil(cols);
    let pad = u64::from(SHEET_PADDING);
    let cell_w = u64::from(w) + pad;
    let cell_h = u64::from(h) + u64::from(LABEL_HEIGHT) + pad;
    let sheet_w = cols * cell_w + pad;
    let sheet_h = rows.saturating_mul(cell_h).saturating_add(pad);
    if sheet_w.saturating_mul(sheet_h) > MAX_SHEET_PIXELS {
        return Err(PreviewError::TooLarge {
            width: sheet_w,
            height: sheet_h,
        });
    }
    // Both fit in u32 now: their product is at most 2^26.
    let (sw, sh) = (sheet_w as usize, sheet_h as usize);
    let mut rgba = vec![255u8; sw * sh * 4];

    let (w, h) = (w as usize, h as usize);
    let (pad, cell_w, cell_h) = (pad as usize, cell_w as usize, cell_h as usize);
    for (t, (tile, label)) in tiles.iter().enumerate() {
        let (col, row) = (t % cols as usize, t / cols as usize);
        let (x0, y0) = (pad + col * cell_w, pad + row * cell_h);
        for y in 0..h {
            let src = &tile.rgba[y * w * 4..(y + 1) * w * 4];
            let o = ((y0 + y) * sw + x0) * 4;
            rgba[o..o + w * 4].copy_from_slice(src);
        }
        let max_chars = (w + font::SCALE) / font::ADVANCE;
        let text: String = label.chars().take(max_chars).collect();
        let text_w = font::text_width(text.chars().count());
        let tx = x0 + (w - text_w.min(w)) / 2;
        let ty = y0 + h + (LABEL_HEIGHT as usize - font::TEXT_HEIGHT) / 2;
        let mut canvas = Canvas {
            rgba: &mut rgba,
            width: sw,
            height: sh,
        };
        font::draw_text(&mut canvas, tx, ty, &text, TEXT_SRGB);
    }
    Ok(Image {
        width: sheet_w as u32,
        height: sheet_h as u32,
        rgba,
    })
}
