//! Orthonormal frames (the G³ turtle's heading H, left L, up U) and the
//! deterministic perpendicular every degenerate case falls back to.

use glam::{DQuat, DVec3};

/// The world axis least aligned with `v` (ties go to X, then Y): its
/// cosine with a unit `v` is at most 1/√3, so projections off it never
/// degenerate.
pub fn least_aligned_axis(v: DVec3) -> DVec3 {
    let a = v.abs();
    if a.x <= a.y && a.x <= a.z {
        DVec3::X
    } else if a.y <= a.z {
        DVec3::Y
    } else {
        DVec3::Z
    }
}

/// A unit vector perpendicular to unit `v`: the least aligned world axis,
/// Gram–Schmidt'ed against `v` (deterministic).
pub fn any_perpendicular(v: DVec3) -> DVec3 {
    let axis = least_aligned_axis(v);
    (axis - v * v.dot(axis)).normalize()
}

/// An orthonormal, right-handed turtle frame: H = L × U.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    pub h: DVec3,
    pub l: DVec3,
    pub u: DVec3,
}

impl Frame {
    /// H = +x, L = +y, U = +z: parameters written at top level are world
    /// coordinates.
    pub const WORLD: Frame = Frame {
        h: DVec3::X,
        l: DVec3::Y,
        u: DVec3::Z,
    };

    /// The frame with heading `h` whose up is as close to `up` as possible.
    /// Degenerate input falls back to a deterministic perpendicular.
    pub fn from_heading_up(h: DVec3, up: DVec3) -> Frame {
        let h = h.try_normalize().unwrap_or(DVec3::X);
        let u = (up - h * h.dot(up))
            .try_normalize()
            .unwrap_or_else(|| any_perpendicular(h));
        Frame {
            h,
            l: u.cross(h),
            u,
        }
    }

    /// The frame with heading `h` whose left is as close to `left` as possible.
    pub fn from_heading_left(h: DVec3, left: DVec3) -> Frame {
        let h = h.try_normalize().unwrap_or(DVec3::X);
        let l = (left - h * h.dot(left))
            .try_normalize()
            .unwrap_or_else(|| any_perpendicular(h));
        Frame {
            h,
            l,
            u: h.cross(l),
        }
    }

    /// Coordinates in this frame's basis (H, L, U) → world vector.
    pub fn to_world(&self, v: DVec3) -> DVec3 {
        self.h * v.x + self.l * v.y + self.u * v.z
    }

    /// World vector → coordinates in this frame's basis.
    pub fn to_local(&self, v: DVec3) -> DVec3 {
        DVec3::new(v.dot(self.h), v.dot(self.l), v.dot(self.u))
    }

    /// Turtle rotations in radians: roll about H first (so a branch's
    /// side is chosen around its parent's axis), then turn about the rolled
    /// U, then pitch about the resulting L.
    pub fn rotated(&self, turn: f64, pitch: f64, roll: f64) -> Frame {
        let mut f = *self;
        if roll != 0.0 {
            f = f.rotate(DQuat::from_axis_angle(f.h, roll));
        }
        if turn != 0.0 {
            f = f.rotate(DQuat::from_axis_angle(f.u, turn));
        }
        if pitch != 0.0 {
            f = f.rotate(DQuat::from_axis_angle(f.l, pitch));
        }
        f
    }

    fn rotate(&self, q: DQuat) -> Frame {
        Frame::from_heading_left(q * self.h, q * self.l)
    }

    /// The mean of several frames, re-orthonormalized (thesis: several
    /// preceding primitives are averaged).
    pub fn average(frames: &[Frame]) -> Option<Frame> {
        match frames {
            [] => None,
            [one] => Some(*one),
            _ => {
                let h: DVec3 = frames.iter().map(|f| f.h).sum();
                let l: DVec3 = frames.iter().map(|f| f.l).sum();
                Some(Frame::from_heading_left(h, l))
            }
        }
    }
}
