//! Distance functions of the primitives, in their local frame.
//!
//! Negative inside, positive outside (spec §1.2). Axial primitives use the
//! local **+Z** axis (decision D2: graftal's kernel is Z-up; the thesis's
//! torus, §1.2.3, revolves about y and is rotated here). Formulas: sphere,
//! box and torus from thesis §1.2.1–1.2.3; the others from spec §1.3 and
//! Quilez's exact distance functions. Every function here is exact unless
//! its doc says otherwise; the claims are property-tested against sampled
//! surface points in `tests`.
//!
//! Transcendentals go through `libm` so the bits do not depend on the
//! platform's maths library.

use glam::{DVec2, DVec3};

/// `sign` as in GLSL: −1, 0 or +1.
#[inline]
fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Sphere of radius `r` at the origin (thesis §1.2.1: |OP| − R).
#[inline]
pub fn sphere(p: DVec3, r: f64) -> f64 {
    p.length() - r
}

/// Box with half-sizes `h` (thesis §1.2.2:
/// |max(d, 0)| + min(0, max(d.x, d.y, d.z)) with d = |p| − h).
#[inline]
pub fn cuboid(p: DVec3, h: DVec3) -> f64 {
    let d = p.abs() - h;
    d.max(DVec3::ZERO).length() + d.max_element().min(0.0)
}

/// Box with half-sizes `h` whose edges are rounded with radius `r ≤ min h`.
#[inline]
pub fn rounded_box(p: DVec3, h: DVec3, r: f64) -> f64 {
    cuboid(p, h - DVec3::splat(r)) - r
}

/// Torus about +Z: `major` from the centre to the tube centre, tube radius
/// `minor` (thesis §1.2.3 with the axis moved from y to z).
#[inline]
pub fn torus(p: DVec3, major: f64, minor: f64) -> f64 {
    let q = DVec2::new(DVec2::new(p.x, p.y).length() - major, p.z);
    q.length() - minor
}

/// 2D regular `n`-gon of circumradius `r`, a vertex on +X (spec §1.3).
/// Exact: the polygon is symmetric under its sector mirrors, so the closest
/// boundary point lies in the query point's sector.
#[inline]
pub fn ngon2(p: DVec2, n: u32, r: f64) -> f64 {
    let a = std::f64::consts::PI / n as f64;
    let (sa, ca) = (libm::sin(a), libm::cos(a));
    ngon2_with(p, a, ca, sa, r)
}

/// [`ngon2`] with the half-sector angle and its cosine/sine precomputed.
#[inline]
pub fn ngon2_with(p: DVec2, a: f64, ca: f64, sa: f64, r: f64) -> f64 {
    let len = p.length();
    let two_a = 2.0 * a;
    let ang = libm::atan2(p.y, p.x);
    // GLSL mod: x − y·floor(x / y).
    let b = ang - two_a * (ang / two_a).floor() - a;
    let mut q =
        DVec2::new(len * libm::cos(b), (len * libm::sin(b)).abs()) - DVec2::new(r * ca, r * sa);
    q.y += (-q.y).clamp(0.0, r * sa);
    q.length() * sign(q.x)
}

/// Exact extrusion of a 2D distance `d2` to half-height `h` along z.
#[inline]
pub fn extrude(d2: f64, z: f64, h: f64) -> f64 {
    let w = DVec2::new(d2, z.abs() - h);
    w.x.max(w.y).min(0.0) + w.max(DVec2::ZERO).length()
}

/// Capped cylinder about +Z, radius `r`, half-height `h` (spec §1.3).
#[inline]
pub fn cylinder(p: DVec3, r: f64, h: f64) -> f64 {
    extrude(DVec2::new(p.x, p.y).length() - r, p.z, h)
}

/// Capped cone about +Z (Quilez `sdCappedCone`): half-height `h`, radius
/// `r1` at z = −h and `r2` at z = +h (`r2 = 0` is a cone).
#[inline]
pub fn capped_cone(p: DVec3, h: f64, r1: f64, r2: f64) -> f64 {
    let q = DVec2::new(DVec2::new(p.x, p.y).length(), p.z);
    let k1 = DVec2::new(r2, h);
    let k2 = DVec2::new(r2 - r1, 2.0 * h);
    let ca = DVec2::new(
        q.x - q.x.min(if q.y < 0.0 { r1 } else { r2 }),
        q.y.abs() - h,
    );
    let cb = q - k1 + k2 * ((k1 - q).dot(k2) / k2.dot(k2)).clamp(0.0, 1.0);
    let s = if cb.x < 0.0 && ca.y < 0.0 { -1.0 } else { 1.0 };
    s * ca.dot(ca).min(cb.dot(cb)).sqrt()
}

/// Regular prism about +Z: `n`-gon of circumradius `r`, half-height `h`.
#[inline]
pub fn prism(p: DVec3, n: u32, r: f64, h: f64) -> f64 {
    extrude(ngon2(DVec2::new(p.x, p.y), n, r), p.z, h)
}

/// Capsule: segment `a`–`b` of radius `r`.
#[inline]
pub fn capsule(p: DVec3, a: DVec3, b: DVec3, r: f64) -> f64 {
    let pa = p - a;
    let ba = b - a;
    let t = (pa.dot(ba) / ba.dot(ba)).clamp(0.0, 1.0);
    (pa - ba * t).length() - r
}

/// Precomputed shape constants of a round cone (Quilez `sdRoundCone`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoundCone {
    pub a: DVec3,
    pub ba: DVec3,
    pub r1: f64,
    pub r2: f64,
    pub l2: f64,
    pub rr: f64,
    pub a2: f64,
    pub il2: f64,
}

impl RoundCone {
    /// The round cone between spheres (a, r1) and (b, r2). Requires
    /// |r1 − r2| < |b − a| (otherwise one sphere holds the other; callers
    /// use a sphere then).
    pub fn new(a: DVec3, b: DVec3, r1: f64, r2: f64) -> Self {
        let ba = b - a;
        let l2 = ba.dot(ba);
        let rr = r1 - r2;
        RoundCone {
            a,
            ba,
            r1,
            r2,
            l2,
            rr,
            a2: l2 - rr * rr,
            il2: 1.0 / l2,
        }
    }

    /// True when the two end spheres do not contain one another.
    pub fn is_proper(a: DVec3, b: DVec3, r1: f64, r2: f64) -> bool {
        let ba = b - a;
        let l2 = ba.dot(ba);
        let rr = r1 - r2;
        l2 - rr * rr > 0.0 && (r1 - r2).abs() < ba.length()
    }

    /// Exact distance (one square root; Quilez's branch between the caps and
    /// the cone).
    #[inline]
    pub fn eval(&self, p: DVec3) -> f64 {
        let pa = p - self.a;
        let y = pa.dot(self.ba);
        let z = y - self.l2;
        let w = pa * self.l2 - self.ba * y;
        let x2 = w.dot(w);
        let y2 = y * y * self.l2;
        let z2 = z * z * self.l2;
        let k = sign(self.rr) * self.rr * self.rr * x2;
        if sign(z) * self.a2 * z2 > k {
            return (x2 + z2).sqrt() * self.il2 - self.r2;
        }
        if sign(y) * self.a2 * y2 < k {
            return (x2 + y2).sqrt() * self.il2 - self.r1;
        }
        ((x2 * self.a2 * self.il2).sqrt() + y * self.rr) * self.il2 - self.r1
    }
}

/// Closest point on triangle `abc` to `p` (Ericson, *Real-Time Collision
/// Detection* §5.1.5), and which feature it lies on.
#[inline]
pub fn closest_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (DVec3, Feature) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Feature::Vertex(0));
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Feature::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, Feature::Edge(0));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Feature::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, Feature::Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, Feature::Edge(1));
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    (a + ab * v + ac * w, Feature::Face)
}

/// The feature of a triangle that holds a closest point. Edge `k` joins
/// corners `k` and `(k + 1) % 3`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Feature {
    Face,
    Edge(u8),
    Vertex(u8),
}

/// Regular pyramid: `n`-gon base of circumradius `r` in the plane z = 0,
/// apex at z = `height`, optionally cut flat at z = `top` (< height).
///
/// Exact (spec §1.3): fold p into the sector of its base edge; the solid is
/// convex and symmetric under the sector mirrors, so outside the distance is
/// the smallest point–triangle distance to the boundary pieces inside that
/// sector (base fan triangle, lateral face, top fan triangle), and inside it
/// is the largest signed face-plane distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pyramid {
    a: f64,
    /// Base vertices of sector 0 (edge normal on +X), z = 0.
    v0: DVec3,
    v1: DVec3,
    /// Top vertices (truncated) or the apex twice.
    t0: DVec3,
    t1: DVec3,
    top: Option<f64>,
    /// Unit outward normal of lateral face 0 and its plane offset.
    ln: DVec3,
    ld: f64,
}

impl Pyramid {
    /// A pyramid; `top` is the truncation height (validated by the tree).
    pub fn new(n: u32, r: f64, height: f64, top: Option<f64>) -> Self {
        let a = std::f64::consts::PI / n as f64;
        let (sa, ca) = (libm::sin(a), libm::cos(a));
        // Sector 0 spans angles [−a, a] around +X: edge normal on +X.
        let v0 = DVec3::new(r * ca, -r * sa, 0.0);
        let v1 = DVec3::new(r * ca, r * sa, 0.0);
        let apex = DVec3::new(0.0, 0.0, height);
        let (t0, t1) = match top {
            Some(t) => {
                let s = 1.0 - t / height;
                (
                    DVec3::new(v0.x * s, v0.y * s, t),
                    DVec3::new(v1.x * s, v1.y * s, t),
                )
            }
            None => (apex, apex),
        };
        let ln = (v1 - v0).cross(apex - v0).normalize();
        let ld = ln.dot(v0);
        Pyramid {
            a,
            v0,
            v1,
            t0,
            t1,
            top,
            ln,
            ld,
        }
    }

    /// Distance at `p`.
    #[inline]
    pub fn eval(&self, p: DVec3) -> f64 {
        // Rotate p into sector 0 (edge normal on +X), then mirror y ≥ 0 is
        // not needed: all three pieces of the sector are used whole.
        let ang = libm::atan2(p.y, p.x);
        let two_a = 2.0 * self.a;
        let k = ((ang + self.a) / two_a).floor();
        let rot = -k * two_a;
        let (s, c) = (libm::sin(rot), libm::cos(rot));
        let q = DVec3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z);
        let lateral = self.ln.dot(q) - self.ld;
        let mut plane = lateral.max(-q.z);
        if let Some(t) = self.top {
            plane = plane.max(q.z - t);
        }
        if plane <= 0.0 {
            return plane;
        }
        let o = DVec3::ZERO;
        let mut d2 = dist2_tri(q, o, self.v1, self.v0);
        d2 = d2.min(dist2_tri(q, self.v0, self.v1, self.t1));
        if let Some(t) = self.top {
            d2 = d2.min(dist2_tri(q, self.v0, self.t1, self.t0));
            d2 = d2.min(dist2_tri(q, DVec3::new(0.0, 0.0, t), self.t0, self.t1));
        }
        d2.sqrt()
    }
}

#[inline]
fn dist2_tri(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (q, _) = closest_on_triangle(p, a, b, c);
    (p - q).length_squared()
}

/// Polygonal torus about +Z (thesis §1.2.4, formula from spec §1.3): the
/// ring is a regular `m`-gon of apothem `major` (`m = 0`: a circle), the
/// tube a regular `n`-gon of circumradius `minor` (`n = 0`: a circle), a
/// tube vertex pointing away from the axis.
///
/// Exact for a circular ring (an exact 2D profile revolved, with the profile
/// off the axis). For a polygonal ring (`m ≥ 3`) it is a **bound**: inside
/// each ring sector it is the exact distance to the straight tube of that
/// sector, whose closest point can leave the sector near the inner mitre
/// joints (see DESIGN.md, deviations).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolyTorus {
    ring: u32,
    tube: u32,
    major: f64,
    minor: f64,
    ra: f64,
    ta: f64,
    tca: f64,
    tsa: f64,
}

impl PolyTorus {
    /// A polygonal torus (parameters validated by the tree).
    pub fn new(ring: u32, tube: u32, major: f64, minor: f64) -> Self {
        let ra = if ring >= 3 {
            std::f64::consts::PI / ring as f64
        } else {
            0.0
        };
        let ta = if tube >= 3 {
            std::f64::consts::PI / tube as f64
        } else {
            0.0
        };
        PolyTorus {
            ring,
            tube,
            major,
            minor,
            ra,
            ta,
            tca: libm::cos(ta),
            tsa: libm::sin(ta),
        }
    }

    /// Distance at `p`.
    #[inline]
    pub fn eval(&self, p: DVec3) -> f64 {
        let rho = if self.ring >= 3 {
            // Fold the angle into the ring segment whose outward normal is
            // nearest; x' = the component along that normal.
            let ang = libm::atan2(p.y, p.x);
            let two_a = 2.0 * self.ra;
            let b = ang - two_a * ((ang + self.ra) / two_a).floor();
            DVec2::new(p.x, p.y).length() * libm::cos(b)
        } else {
            DVec2::new(p.x, p.y).length()
        };
        let q = DVec2::new(rho - self.major, p.z);
        if self.tube >= 3 {
            ngon2_with(q, self.ta, self.tca, self.tsa, self.minor)
        } else {
            q.length() - self.minor
        }
    }
}
