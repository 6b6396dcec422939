//! Newell's teapot patch format as Paul Bourke publishes it (`.bpt`).
//!
//! Whitespace-separated numbers: the number of patches; then per patch its degrees `du dv`
//! and (du+1)·(dv+1) points `x y z`. Each patch is a Bézier patch: clamped, one span each
//! way, knots on [0, 1]. Line breaks carry no meaning (blank lines and trailing whitespace
//! are fine); anything after the last patch is an error.
//!
//! Point order: in Bourke's `teapot.bpt` a patch's points are Newell's 4 × 4 net row by row
//! (the first dv+1 points are one row). Point k becomes net point (i, j) with
//! `i = k / (dv+1)` and `j = k % (dv+1)`, i along u: the file order *is* the row-major order
//! of [`NurbsSurface`] (`points[i * n_v + j]`).

use std::path::Path;

use super::{
    parse_degree, parse_finite, shown, tokens, Locator, PatchFile, MAX_FILE_POINTS, MAX_PATCHES,
};
use crate::io::IoError;
use crate::nurbs::surface::NurbsSurface;

/// Fewest bytes `n` more tokens take after a token: a separator and one byte each.
fn min_bytes(n: usize) -> usize {
    n.saturating_mul(2)
}

/// Decodes a `.bpt` file; `path` names it in errors.
pub fn decode_bpt(bytes: &[u8], path: &Path) -> Result<PatchFile, IoError> {
    let at = Locator { path };
    let mut toks = tokens(bytes);
    let first = toks
        .next()
        .ok_or_else(|| at.at(1, 1, "empty file: expected the number of patches"))?;
    let count = std::str::from_utf8(first.text)
        .ok()
        .and_then(|s| s.parse::<usize>().ok())
        .ok_or_else(|| {
            at.token(
                &first,
                format!(
                    "expected the number of patches, found {:?}",
                    shown(first.text)
                ),
            )
        })?;
    if count == 0 {
        return Err(at.token(&first, "the file declares no patches"));
    }
    if count > MAX_PATCHES {
        return Err(at.token(
            &first,
            format!("{count} patches exceed the limit of {MAX_PATCHES}"),
        ));
    }
    // Every patch is at least 2 degrees and 4 points of 3 numbers.
    let remaining = first.bytes_after(bytes);
    if min_bytes(count.saturating_mul(14)) > remaining {
        return Err(at.token(
            &first,
            format!("{count} patches cannot fit in the {remaining} bytes that follow"),
        ));
    }

    let mut surfaces = Vec::with_capacity(count);
    let mut lines = Vec::with_capacity(count);
    let mut total_points = 0usize;
    let mut end_pos = (first.line, first.column + first.text.len());
    let mut next = |what: &dyn Fn() -> String| match toks.next() {
        Some(t) => {
            end_pos = (t.line, t.column + t.text.len());
            Ok(t)
        }
        None => Err(at.at(
            end_pos.0,
            end_pos.1,
            format!("file ends early: expected {}", what()),
        )),
    };
    for patch in 1..=count {
        let du_tok = next(&|| format!("the degrees of patch {patch}"))?;
        let du = parse_degree(&du_tok, &format!("patch {patch}: degree in u"), &at)?;
        let dv_tok = next(&|| format!("the v degree of patch {patch}"))?;
        let dv = parse_degree(&dv_tok, &format!("patch {patch}: degree in v"), &at)?;
        // Degrees are at most 64, so n ≤ 65² and nothing here overflows.
        let n = (du + 1) * (dv + 1);
        total_points += n;
        if total_points > MAX_FILE_POINTS {
            return Err(at.token(
                &du_tok,
                format!("patch {patch}: the file's control points exceed the limit of {MAX_FILE_POINTS}"),
            ));
        }
        let left = dv_tok.bytes_after(bytes);
        if min_bytes(3 * n) > left {
            return Err(at.at(
                dv_tok.line,
                dv_tok.column + dv_tok.text.len(),
                format!(
                    "patch {patch}: {n} points of degree {du}×{dv} cannot fit in the {left} bytes that follow"
                ),
            ));
        }
        let mut points = Vec::with_capacity(n);
        for k in 0..n {
            let mut p = [0.0; 3];
            for (c, slot) in p.iter_mut().enumerate() {
                let what = || {
                    format!(
                        "coordinate {} of point {} of patch {patch}",
                        "xyz".as_bytes()[c] as char,
                        k + 1
                    )
                };
                let t = next(&what)?;
                *slot = parse_finite(&t, &what(), &at)?;
            }
            points.push(p);
        }
        let surface = NurbsSurface::clamped([du, dv], [du + 1, dv + 1], &points, None)
            .map_err(|e| at.token(&du_tok, format!("patch {patch}: {e}")))?;
        surfaces.push(surface);
        lines.push(du_tok.line);
    }
    if let Some(extra) = toks.next() {
        return Err(at.token(
            &extra,
            format!(
                "unexpected {:?} after the last of {count} patches",
                shown(extra.text)
            ),
        ));
    }
    Ok(PatchFile { surfaces, lines })
}
