//! The renderer: validation, triangle rasterisation with a z-buffer and
//! 2×2 supersampling, lighting, and depth-tested wire lines.
//!
//! The image is drawn in horizontal strips so that the supersampled colour
//! and depth buffers stay small (a strip, not the whole frame) however big
//! the output is. Every triangle is visited once per strip; a y-range check
//! skips the ones that miss it.

use glam::DVec3;

use super::camera::Camera;
use super::{check_dimensions, Image, Options, PreviewError, Scene};

/// Supersampling factor per axis.
const SS: usize = 2;
/// Output rows per strip.
const STRIP_ROWS: usize = 32;
/// Base colour of triangles without one.
const DEFAULT_COLOR: [f32; 3] = [0.8, 0.8, 0.8];
/// Wire line colour, sRGB (≈ 0.1 of full scale).
const LINE_SRGB: [u8; 3] = [26, 26, 26];

/// Unit vector towards the key light: upper front left.
const KEY_DIR: [f64; 3] = [-0.5, -0.8, 1.0];
const KEY_COLOR: [f64; 3] = [0.78, 0.75, 0.70];
const SKY_COLOR: [f64; 3] = [0.36, 0.40, 0.48];
const GROUND_COLOR: [f64; 3] = [0.16, 0.14, 0.12];
const AMBIENT: f64 = 0.04;

/// Renders `scene` as seen from `options.view`.
///
/// Errors: [`PreviewError::TooLarge`] for a size outside
/// 1..=[`MAX_DIMENSION`](super::MAX_DIMENSION) (checked before allocating),
/// [`PreviewError::LengthMismatch`] for per-triangle arrays of the wrong
/// length, [`PreviewError::BadIndex`] for an out-of-range vertex index and
/// [`PreviewError::NonFinite`] for a used vertex with a NaN or infinite
/// coordinate. A scene with nothing in it gives a background-only image.
pub fn render(scene: &Scene, options: &Options) -> Result<Image, PreviewError> {
    check_dimensions(options.width, options.height)?;
    check_lengths(scene)?;
    let bounds = used_bounds(scene)?;

    let (width, height) = (options.width as usize, options.height as usize);
    let bg = options.background;
    let mut rgba = Vec::with_capacity(width * height * 4);
    for _ in 0..width * height {
        rgba.extend_from_slice(&[bg[0], bg[1], bg[2], 255]);
    }
    let mut image = Image {
        width: options.width,
        height: options.height,
        rgba,
    };
    let Some(mut bounds) = bounds else {
        return Ok(image);
    };
    if let Some([lo, hi]) = options.frame {
        let (lo, hi) = (DVec3::from_array(lo), DVec3::from_array(hi));
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(PreviewError::BadFrame);
        }
        bounds = (lo.min(hi), lo.max(hi));
    }

    let norm = Normaliser::new(bounds);
    let camera = Camera::frame(
        options.view,
        options.projection,
        norm.half,
        options.width,
        options.height,
    );
    // Unused vertices are projected too (it is cheaper than tracking them);
    // their values, possibly NaN, are never read.
    let projected: Vec<[f64; 3]> = scene
        .positions
        .iter()
        .map(|&p| camera.project(norm.apply(p)))
        .collect();
    let triangles = setup_triangles(scene, &norm, &camera, &projected);

    let background = bg.map(srgb_to_linear);
    let sw = width * SS;
    let mut colour = vec![[0f32; 3]; sw * STRIP_ROWS * SS];
    let mut depth = vec![f64::NEG_INFINITY; sw * STRIP_ROWS * SS];
    let mut nearest = vec![f64::NEG_INFINITY; width * STRIP_ROWS];
    let bias = camera.line_bias();

    let mut row0 = 0;
    while row0 < height {
        let rows = STRIP_ROWS.min(height - row0);
        let strip = Strip {
            sample_row0: row0 * SS,
            sample_rows: rows * SS,
            sample_width: sw,
        };
        let n = sw * strip.sample_rows;
        colour[..n].fill(background);
        depth[..n].fill(f64::NEG_INFINITY);
        for tri in &triangles {
            raster_triangle(tri, &strip, &mut colour[..n], &mut depth[..n]);
        }
        resolve_strip(
            &mut image.rgba,
            row0,
            rows,
            width,
            &colour,
            &depth,
            &mut nearest,
        );
        if options.edges {
            let mut target = LineTarget {
                rgba: &mut image.rgba,
                width,
                row0,
                rows,
                nearest: &nearest,
                bias,
            };
            for line in scene.lines {
                target.draw(projected[line[0] as usize], projected[line[1] as usize]);
            }
        }
        row0 += rows;
    }
    Ok(image)
}

fn check_lengths(scene: &Scene) -> Result<(), PreviewError> {
    let n = scene.triangles.len();
    for (field, len) in [
        ("triangle_colors", scene.triangle_colors.len()),
        ("corner_normals", scene.corner_normals.len()),
    ] {
        if len != 0 && len != n {
            return Err(PreviewError::LengthMismatch {
                field,
                expected: n,
                actual: len,
            });
        }
    }
    Ok(())
}

/// Checks every index and every used vertex, returning the used vertices'
/// bounding box (`None` when nothing is used).
fn used_bounds(scene: &Scene) -> Result<Option<(DVec3, DVec3)>, PreviewError> {
    let count = scene.positions.len();
    let mut bounds: Option<(DVec3, DVec3)> = None;
    let mut visit = |primitive: &'static str, element: usize, index: u32| {
        let Some(&p) = scene.positions.get(index as usize) else {
            return Err(PreviewError::BadIndex {
                primitive,
                element,
                index,
                vertex_count: count,
            });
        };
        let p = DVec3::from_array(p);
        if !p.is_finite() {
            return Err(PreviewError::NonFinite {
                vertex: index as usize,
            });
        }
        bounds = Some(match bounds {
            None => (p, p),
            Some((lo, hi)) => (lo.min(p), hi.max(p)),
        });
        Ok(())
    };
    for (t, tri) in scene.triangles.iter().enumerate() {
        for &i in tri {
            visit("triangle", t, i)?;
        }
    }
    for (l, line) in scene.lines.iter().enumerate() {
        for &i in line {
            visit("line", l, i)?;
        }
    }
    Ok(bounds)
}

/// Maps the used bounding box onto a box centred on the origin with largest
/// half-extent 1, so later arithmetic cannot overflow or underflow.
struct Normaliser {
    centre: DVec3,
    scale: f64,
    /// Half-extents after normalisation (each in 0..=1).
    half: DVec3,
}

impl Normaliser {
    fn new((lo, hi): (DVec3, DVec3)) -> Normaliser {
        // Halving first keeps `hi - lo` finite even for ±f64::MAX.
        let centre = lo * 0.5 + hi * 0.5;
        let half = hi * 0.5 - lo * 0.5;
        let largest = half.max_element();
        let scale = 1.0 / largest;
        // A point-like box (or one so small that 1/extent overflows)
        // collapses to the origin; the camera's minimum extent frames it.
        let scale = if largest > 0.0 && scale.is_finite() {
            scale
        } else {
            0.0
        };
        Normaliser {
            centre,
            scale,
            half: (half * scale).min(DVec3::ONE),
        }
    }

    fn apply(&self, p: [f64; 3]) -> DVec3 {
        (DVec3::from_array(p) - self.centre) * self.scale
    }
}

/// How a triangle is coloured.
enum Shade {
    /// One lit linear colour for the whole triangle.
    Flat([f32; 3]),
    /// Per-pixel lighting from interpolated corner normals (already facing
    /// the camera), with the face normal as fallback.
    Smooth {
        normals: [DVec3; 3],
        face: DVec3,
        base: [f32; 3],
    },
}

/// A triangle ready to rasterise, in sample coordinates, with positive
/// orientation under [`edge`].
struct Tri {
    v: [[f64; 2]; 3],
    q: [f64; 3],
    y_min: f64,
    y_max: f64,
    shade: Shade,
}

fn setup_triangles(
    scene: &Scene,
    norm: &Normaliser,
    camera: &Camera,
    projected: &[[f64; 3]],
) -> Vec<Tri> {
    let ss = SS as f64;
    let mut out = Vec::with_capacity(scene.triangles.len());
    for (t, idx) in scene.triangles.iter().enumerate() {
        let [i0, i1, i2] = idx.map(|i| i as usize);
        let p = [i0, i1, i2].map(|i| norm.apply(scene.positions[i]));
        let face = (p[1] - p[0]).cross(p[2] - p[0]);
        let len = face.length();
        if !(len > 0.0 && len.is_finite()) {
            continue; // Degenerate: covers no pixels.
        }
        let mut face = face / len;
        let flip = camera.facing(p[0], face) < 0.0;
        if flip {
            face = -face;
        }
        let mut v = [i0, i1, i2].map(|i| [projected[i][0] * ss, projected[i][1] * ss]);
        let mut q = [i0, i1, i2].map(|i| projected[i][2]);
        let area = edge(v[0], v[1], v[2]);
        if area == 0.0 || !area.is_finite() {
            continue; // Seen edge-on.
        }
        let base = scene
            .triangle_colors
            .get(t)
            .map_or(DEFAULT_COLOR, |&c| sanitize_color(c));
        let mut shade = match scene.corner_normals.get(t) {
            None => Shade::Flat(lit(base, face)),
            Some(corners) => Shade::Smooth {
                normals: corners.map(|n| {
                    let n = DVec3::from_array(n);
                    let len = n.length();
                    if len > 1e-300 && len.is_finite() {
                        let n = n / len;
                        if flip {
                            -n
                        } else {
                            n
                        }
                    } else {
                        face
                    }
                }),
                face,
                base,
            },
        };
        if area < 0.0 {
            // Make the orientation positive so "inside" is w > 0 for all
            // three edges.
            v.swap(1, 2);
            q.swap(1, 2);
            if let Shade::Smooth { normals, .. } = &mut shade {
                normals.swap(1, 2);
            }
        }
        let y_min = v[0][1].min(v[1][1]).min(v[2][1]);
        let y_max = v[0][1].max(v[1][1]).max(v[2][1]);
        out.push(Tri {
            v,
            q,
            y_min,
            y_max,
            shade,
        });
    }
    out
}

fn sanitize_color(c: [f32; 3]) -> [f32; 3] {
    if c.iter().all(|x| x.is_finite()) {
        c.map(|x| x.clamp(0.0, 1.0))
    } else {
        DEFAULT_COLOR
    }
}

/// Which supersampled rows are being drawn, and how wide they are.
struct Strip {
    sample_row0: usize,
    sample_rows: usize,
    sample_width: usize,
}

/// Twice the signed area of (a, b, p); positive when p is to the right of
/// a→b in y-down screen space.
///
/// It is always evaluated with the edge's end points in one canonical order
/// and negated otherwise, so two triangles sharing an edge get exactly
/// opposite values and the fill rule never leaves cracks or double pixels.
fn edge(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    let orient =
        |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
    if a[0] < b[0] || (a[0] == b[0] && a[1] <= b[1]) {
        orient(a, b)
    } else {
        -orient(b, a)
    }
}

/// Top-left fill rule for the directed edge a→b of a positively oriented
/// triangle (y down): top edges run +x horizontally, left edges run -y.
fn is_top_left(a: [f64; 2], b: [f64; 2]) -> bool {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    (dy == 0.0 && dx > 0.0) || dy < 0.0
}

/// Point-in-triangle test with the top-left fill rule, for a positively
/// oriented triangle.
struct Coverage {
    /// Edge k is the one opposite vertex k.
    edges: [([f64; 2], [f64; 2]); 3],
    top_left: [bool; 3],
}

impl Coverage {
    fn new([a, b, c]: [[f64; 2]; 3]) -> Coverage {
        let edges = [(b, c), (c, a), (a, b)];
        Coverage {
            edges,
            top_left: edges.map(|(p, q)| is_top_left(p, q)),
        }
    }

    /// Unnormalised barycentric weights and their (positive) sum when `p`
    /// is covered.
    fn weights(&self, p: [f64; 2]) -> Option<([f64; 3], f64)> {
        let w = self.edges.map(|(e0, e1)| edge(e0, e1, p));
        let inside = (0..3).all(|k| w[k] > 0.0 || (w[k] == 0.0 && self.top_left[k]));
        let sum = w[0] + w[1] + w[2];
        // A positive sum can only fail for slivers lost to rounding.
        (inside && sum > 0.0).then_some((w, sum))
    }
}

fn raster_triangle(tri: &Tri, strip: &Strip, colour: &mut [[f32; 3]], depth: &mut [f64]) {
    let top = strip.sample_row0 as f64;
    let bottom = (strip.sample_row0 + strip.sample_rows) as f64;
    if tri.y_max < top || tri.y_min >= bottom {
        return;
    }
    // Sample centres at +0.5: rows j with y_min <= j + 0.5 <= y_max.
    let clamp_to = |x: f64, lo: f64, hi: f64| x.max(lo).min(hi);
    let j0 = clamp_to((tri.y_min - 0.5).ceil(), top, bottom) as usize;
    let j1 = clamp_to((tri.y_max - 0.5).floor() + 1.0, top, bottom) as usize;
    let width = strip.sample_width as f64;
    let x_min = tri.v[0][0].min(tri.v[1][0]).min(tri.v[2][0]);
    let x_max = tri.v[0][0].max(tri.v[1][0]).max(tri.v[2][0]);
    let i0 = clamp_to((x_min - 0.5).ceil(), 0.0, width) as usize;
    let i1 = clamp_to((x_max - 0.5).floor() + 1.0, 0.0, width) as usize;

    let cover = Coverage::new(tri.v);
    for j in j0..j1 {
        let y = j as f64 + 0.5;
        let row = (j - strip.sample_row0) * strip.sample_width;
        for i in i0..i1 {
            let Some((w, sum)) = cover.weights([i as f64 + 0.5, y]) else {
                continue;
            };
            let bary = w.map(|x| x / sum);
            let q = bary[0] * tri.q[0] + bary[1] * tri.q[1] + bary[2] * tri.q[2];
            let idx = row + i;
            if q > depth[idx] {
                depth[idx] = q;
                colour[idx] = match &tri.shade {
                    Shade::Flat(c) => *c,
                    Shade::Smooth {
                        normals,
                        face,
                        base,
                    } => {
                        let n = normals[0] * bary[0] + normals[1] * bary[1] + normals[2] * bary[2];
                        lit(*base, n.try_normalize().unwrap_or(*face))
                    }
                };
            }
        }
    }
}

/// Lambert key light + hemispherical sky/ground + ambient, in linear RGB.
fn lit(base: [f32; 3], n: DVec3) -> [f32; 3] {
    let key = DVec3::from_array(KEY_DIR).normalize();
    let lambert = n.dot(key).max(0.0);
    let t = (0.5 * (n.z + 1.0)).clamp(0.0, 1.0);
    let mut out = [0f32; 3];
    for k in 0..3 {
        let hemi = GROUND_COLOR[k] + (SKY_COLOR[k] - GROUND_COLOR[k]) * t;
        let light = KEY_COLOR[k] * lambert + hemi + AMBIENT;
        out[k] = (f64::from(base[k]) * light) as f32;
    }
    out
}

/// Box-filters one strip into the output and records, per output pixel,
/// the nearest depth among its samples (for the line test).
fn resolve_strip(
    rgba: &mut [u8],
    row0: usize,
    rows: usize,
    width: usize,
    colour: &[[f32; 3]],
    depth: &[f64],
    nearest: &mut [f64],
) {
    let sw = width * SS;
    for y in 0..rows {
        for x in 0..width {
            let mut sum = [0f64; 3];
            let mut near = f64::NEG_INFINITY;
            for sy in 0..SS {
                for sx in 0..SS {
                    let s = (y * SS + sy) * sw + x * SS + sx;
                    for (acc, c) in sum.iter_mut().zip(colour[s]) {
                        *acc += f64::from(c);
                    }
                    near = near.max(depth[s]);
                }
            }
            nearest[y * width + x] = near;
            // Untouched pixels keep the exact background bytes.
            if near == f64::NEG_INFINITY {
                continue;
            }
            let o = ((row0 + y) * width + x) * 4;
            let n = (SS * SS) as f64;
            for k in 0..3 {
                rgba[o + k] = linear_to_srgb(sum[k] / n);
            }
        }
    }
}

/// Where wire lines go for one strip: the finished output rows and the
/// nearest triangle depth per pixel.
struct LineTarget<'a> {
    rgba: &'a mut [u8],
    width: usize,
    row0: usize,
    rows: usize,
    nearest: &'a [f64],
    bias: f64,
}

impl LineTarget<'_> {
    /// DDA line from `a` to `b` (`[x, y, q]` in output pixels), plotting
    /// only the rows of this strip, where it is not behind a triangle.
    fn draw(&mut self, a: [f64; 3], b: [f64; 3]) {
        let (top, bottom) = (self.row0 as f64, (self.row0 + self.rows) as f64);
        if a[1].max(b[1]) < top || a[1].min(b[1]) >= bottom {
            return;
        }
        let (dx, dy, dq) = (b[0] - a[0], b[1] - a[1], b[2] - a[2]);
        // Framed points lie inside the image, so this is at most a few
        // thousand; the cap only guards against the unexpected.
        let steps = dx.abs().max(dy.abs()).ceil().clamp(1.0, 65536.0);
        // Only the steps whose y can fall in this strip (one step of slack).
        let (lo, hi) = if dy != 0.0 {
            let t0 = (top - 1.0 - a[1]) / dy;
            let t1 = (bottom + 1.0 - a[1]) / dy;
            let (t0, t1) = (t0.min(t1), t0.max(t1));
            (
                (t0 * steps).floor().max(0.0),
                (t1 * steps).ceil().min(steps),
            )
        } else {
            (0.0, steps)
        };
        if lo > hi {
            return;
        }
        for i in lo as usize..=hi as usize {
            let t = i as f64 / steps;
            let (x, y) = ((a[0] + dx * t).floor(), (a[1] + dy * t).floor());
            if x < 0.0 || x >= self.width as f64 || y < top || y >= bottom {
                continue;
            }
            let (x, y) = (x as usize, y as usize);
            let q = a[2] + dq * t;
            if q + self.bias >= self.nearest[(y - self.row0) * self.width + x] {
                let o = (y * self.width + x) * 4;
                self.rgba[o..o + 3].copy_from_slice(&LINE_SRGB);
            }
        }
    }
}

/// Exact sRGB decoding of an 8-bit channel.
pub(super) fn srgb_to_linear(c: u8) -> f32 {
    let c = f64::from(c) / 255.0;
    let l = if c <= 0.04045 {
        c / 12.92
    } else {
        libm::pow((c + 0.055) / 1.055, 2.4)
    };
    l as f32
}

/// Exact piecewise sRGB encoding, clamped and rounded to 8 bits.
pub(super) fn linear_to_srgb(l: f64) -> u8 {
    let l = if l.is_nan() { 0.0 } else { l.clamp(0.0, 1.0) };
    let s = if l <= 0.003_130_8 {
        12.92 * l
    } else {
        1.055 * libm::pow(l, 1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5).clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Orients a triangle positively, as `setup_triangles` does.
    fn positive(mut v: [[f64; 2]; 3]) -> Coverage {
        if edge(v[0], v[1], v[2]) < 0.0 {
            v.swap(1, 2);
        }
        Coverage::new(v)
    }

    #[test]
    fn fill_rule_covers_each_sample_of_a_fan_exactly_once() {
        // A fan of 13 triangles around a sample centre, vertices on sample
        // centres, edges running through many sample centres; wound both
        // ways to exercise the canonical edge order.
        let c = [8.5, 8.5];
        let rim = [
            [8.5, 0.5],
            [12.5, 0.5],
            [16.5, 0.5],
            [16.5, 4.5],
            [16.5, 8.5],
            [16.5, 16.5],
            [12.5, 16.5],
            [8.5, 16.5],
            [0.5, 16.5],
            [0.5, 12.5],
            [0.5, 8.5],
            [0.5, 0.5],
            [4.5, 0.5],
        ];
        let tris: Vec<Coverage> = (0..rim.len())
            .map(|k| {
                let (a, b) = (rim[k], rim[(k + 1) % rim.len()]);
                positive(if k % 2 == 0 { [c, a, b] } else { [b, a, c] })
            })
            .collect();
        for y in 1..16 {
            for x in 1..16 {
                let p = [f64::from(x) + 0.5, f64::from(y) + 0.5];
                let hits = tris.iter().filter(|t| t.weights(p).is_some()).count();
                assert_eq!(hits, 1, "sample {p:?}");
            }
        }
    }

    #[test]
    fn slivers_and_degenerate_triangles_cover_nothing() {
        let flat = positive([[0.5, 0.5], [4.5, 0.5], [8.5, 0.5]]);
        for x in 0..10 {
            assert!(flat.weights([f64::from(x) + 0.5, 0.5]).is_none());
        }
    }
}
