//! Camera placement: view basis, framing and projection to pixels.
//!
//! The camera works in *normalised* scene space: the renderer first maps the
//! used vertices' bounding box to a box centred on the origin whose largest
//! half-extent is 1 (see `raster::Normaliser`). That keeps every product
//! below finite no matter how large or small the input coordinates are.

use glam::DVec3;

use super::{Projection, View};

/// Fraction of the image left free on each side by orthographic framing.
const MARGIN: f64 = 0.06;
/// Smallest half-extent per axis (normalised units), so flat or point-like
/// scenes still give a finite scale.
const MIN_EXTENT: f64 = 1e-3;
/// Vertical field of view of the perspective camera.
const FOV_Y_DEGREES: f64 = 35.0;
/// Line depth bias as a fraction of the scene's depth range.
const BIAS_FRACTION: f64 = 5e-3;

/// A framed camera for one image size.
///
/// Projection yields `[x, y, q]`: pixel coordinates (y down, pixel centres
/// at +0.5) and a depth key `q` that grows towards the camera and is affine
/// in screen space (so it interpolates linearly across a triangle).
pub(super) struct Camera {
    right: DVec3,
    up: DVec3,
    /// Unit vector from the target towards the camera.
    back: DVec3,
    centre_x: f64,
    centre_y: f64,
    lens: Lens,
    bias: f64,
}

enum Lens {
    /// `q` is the signed distance towards the camera.
    Orthographic { scale: f64 },
    /// `q` is 1 / (distance from the eye along the view axis).
    Perspective { distance: f64, focal: f64 },
}

/// Right, up and towards-camera unit vectors for a view.
pub(super) fn basis(view: View) -> (DVec3, DVec3, DVec3) {
    let (back, up_hint) = match view {
        View::Iso => (DVec3::new(1.0, -1.0, 0.8), DVec3::Z),
        View::Front => (DVec3::NEG_Y, DVec3::Z),
        View::Back => (DVec3::Y, DVec3::Z),
        View::Left => (DVec3::NEG_X, DVec3::Z),
        View::Right => (DVec3::X, DVec3::Z),
        View::Top => (DVec3::Z, DVec3::Y),
        View::Bottom => (DVec3::NEG_Z, DVec3::NEG_Y),
    };
    // The hints are never parallel to `back`, so these are unit vectors.
    let back = back.normalize();
    let right = up_hint.cross(back).normalize();
    let up = back.cross(right);
    (right, up, back)
}

impl Camera {
    /// Frames a box centred on the origin with half-extents `half` for a
    /// `width` × `height` image (both at least 1).
    pub(super) fn frame(
        view: View,
        projection: Projection,
        half: DVec3,
        width: u32,
        height: u32,
    ) -> Camera {
        let (right, up, back) = basis(view);
        let half = half.max(DVec3::splat(MIN_EXTENT));
        let (w, h) = (f64::from(width), f64::from(height));
        let (lens, bias) = match projection {
            Projection::Orthographic => {
                // Half-size of the projected box: each axis contributes
                // |component| times its half-extent.
                let half_w = right.abs().dot(half);
                let half_h = up.abs().dot(half);
                let usable = 1.0 - 2.0 * MARGIN;
                let scale = (w * usable / (2.0 * half_w)).min(h * usable / (2.0 * half_h));
                let depth_range = 2.0 * back.abs().dot(half);
                // Plus one pixel's worth of depth, so lines on faces steeper
                // than the depth range suggests still win the test.
                let bias = BIAS_FRACTION * depth_range + 1.0 / scale;
                (Lens::Orthographic { scale }, bias)
            }
            Projection::Perspective => {
                let radius = half.length();
                let tan_y = libm::tan(FOV_Y_DEGREES.to_radians() / 2.0);
                let tan_x = tan_y * w / h;
                let half_angle = libm::atan(tan_y.min(tan_x));
                // Far enough that the bounding sphere fits the narrower
                // field of view, with a little margin.
                let distance = radius / libm::sin(half_angle) / (1.0 - MARGIN);
                let focal = h / 2.0 / tan_y;
                let near = distance - radius;
                let q_range = 1.0 / near - 1.0 / (distance + radius);
                let bias = BIAS_FRACTION * q_range + 1.0 / (focal * near);
                (Lens::Perspective { distance, focal }, bias)
            }
        };
        Camera {
            right,
            up,
            back,
            centre_x: w / 2.0,
            centre_y: h / 2.0,
            lens,
            bias,
        }
    }

    /// `[x, y, q]` for a point in normalised space.
    pub(super) fn project(&self, p: DVec3) -> [f64; 3] {
        let (x, y, z) = (p.dot(self.right), p.dot(self.up), p.dot(self.back));
        match self.lens {
            Lens::Orthographic { scale } => {
                [self.centre_x + scale * x, self.centre_y - scale * y, z]
            }
            Lens::Perspective { distance, focal } => {
                // Every framed point is at least `distance - radius` > 0
                // in front of the eye, so this never divides by zero.
                let depth = distance - z;
                [
                    self.centre_x + focal * x / depth,
                    self.centre_y - focal * y / depth,
                    1.0 / depth,
                ]
            }
        }
    }

    /// Positive when normal `n` at point `p` faces the camera.
    pub(super) fn facing(&self, p: DVec3, n: DVec3) -> f64 {
        match self.lens {
            Lens::Orthographic { .. } => n.dot(self.back),
            Lens::Perspective { distance, .. } => n.dot(self.back * distance - p),
        }
    }

    /// Amount added to a line's depth key before testing it against the
    /// triangles.
    pub(super) fn line_bias(&self) -> f64 {
        self.bias
    }
}
