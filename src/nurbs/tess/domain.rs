//! Parameter-domain bookkeeping shared by the tessellators: closed directions (periodic
//! unwrapping across the seam), poles (a collapsed border has one vertex whose free parameter
//! is taken from its neighbours), edge midpoints and the deviation measure of the stats.
//!
//! Every vertex stores its canonical (u, v): a seam vertex the lower end of the closed
//! direction, a pole vertex the border value in the fixed parameter. A triangle's corners are
//! unwrapped before any interpolation, and every derived parameter is wrapped back, so an edge's
//! midpoint is a function of the edge alone (both neighbours get the same vertex).

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use super::super::hash::edge_key;
use super::super::mesh::TriMesh;
use super::super::surface::NurbsSurface;

/// Closed directions and poles of a surface's domain.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ParamDomain {
    pub lo: DVec2,
    pub hi: DVec2,
    pub closed: [bool; 2],
    /// [u = u_min, u = u_max, v = v_min, v = v_max]
    pub poles: [bool; 4],
}

impl ParamDomain {
    pub fn new(surface: &NurbsSurface) -> Self {
        let [[a, b], [c, d]] = surface.domain();
        let t = surface.topology();
        ParamDomain {
            lo: DVec2::new(a, c),
            hi: DVec2::new(b, d),
            closed: [t.closed_u, t.closed_v],
            poles: t.poles,
        }
    }

    /// Which coordinate of `uv` is free (0 = u, 1 = v) if `uv` is a pole vertex.
    #[inline]
    pub fn free(&self, uv: DVec2) -> Option<usize> {
        if (self.poles[0] && uv.x == self.lo.x) || (self.poles[1] && uv.x == self.hi.x) {
            Some(1)
        } else if (self.poles[2] && uv.y == self.lo.y) || (self.poles[3] && uv.y == self.hi.y) {
            Some(0)
        } else {
            None
        }
    }

    /// Unwraps up to four corners in place: across a seam to the side of the largest coordinate, and the
    /// free coordinate of a pole to the mean of the others.
    pub fn unwrap(&self, pts: &mut [DVec2]) {
        let mut free = [None; 4];
        for (f, p) in free.iter_mut().zip(pts.iter()) {
            *f = self.free(*p);
        }
        for d in 0..2 {
            let fixed = |k: usize| free[k] != Some(d);
            if self.closed[d] {
                let period = self.hi[d] - self.lo[d];
                let mut top = f64::NEG_INFINITY;
                for (k, p) in pts.iter().enumerate() {
                    if fixed(k) {
                        top = top.max(p[d]);
                    }
                }
                for (k, p) in pts.iter_mut().enumerate() {
                    if fixed(k) && p[d] < top - 0.5 * period {
                        p[d] += period;
                    }
                }
            }
            let (mut sum, mut count) = (0.0, 0usize);
            for (k, p) in pts.iter().enumerate() {
                if fixed(k) {
                    sum += p[d];
                    count += 1;
                }
            }
            if count > 0 && count < pts.len() {
                let mean = sum / count as f64;
                for (k, p) in pts.iter_mut().enumerate() {
                    if !fixed(k) {
                        p[d] = mean;
                    }
                }
            }
        }
    }

    /// Maps an unwrapped parameter back into the canonical range.
    #[inline]
    pub fn wrap(&self, mut uv: DVec2) -> DVec2 {
        for d in 0..2 {
            if self.closed[d] && uv[d] >= self.hi[d] {
                uv[d] -= self.hi[d] - self.lo[d];
            }
            uv[d] = uv[d].clamp(self.lo[d], self.hi[d]);
        }
        uv
    }

    /// Canonical parameter of the midpoint of edge (a, b); symmetric in a and b.
    #[inline]
    pub fn edge_mid(&self, a: DVec2, b: DVec2) -> DVec2 {
        let mut pts = [a, b];
        self.unwrap(&mut pts);
        self.wrap((pts[0] + pts[1]) * 0.5)
    }

    /// Whether edge (a, b) lies on a side of the domain that has a forced parameter strictly
    /// between its ends (sides in [`crate::nurbs::patchset::Side`] order).
    pub fn forced_between(&self, forced: &[Vec<f64>; 4], a: DVec2, b: DVec2) -> bool {
        for (side, list) in forced.iter().enumerate() {
            if list.is_empty() {
                continue;
            }
            let (fixed, along) = if side < 2 { (0, 1) } else { (1, 0) };
            let bound = if side % 2 == 0 {
                self.lo[fixed]
            } else {
                self.hi[fixed]
            };
            // A pole vertex lies on both sides that end at the pole.
            let on = |p: DVec2| p[fixed] == bound || self.free(p) == Some(fixed);
            if !on(a) || !on(b) {
                continue;
            }
            let (t0, t1) = (a[along].min(b[along]), a[along].max(b[along]));
            let tol = PARAM_TOLERANCE * (self.hi[along] - self.lo[along]);
            let i = list.partition_point(|&f| f <= t0 + tol);
            if i < list.len() && list[i] < t1 - tol {
                return true;
            }
        }
        false
    }

    /// Canonical parameter of a triangle's centroid.
    #[inline]
    pub fn centroid(&self, a: DVec2, b: DVec2, c: DVec2) -> DVec2 {
        let mut pts = [a, b, c];
        self.unwrap(&mut pts);
        self.wrap((pts[0] + pts[1] + pts[2]) / 3.0)
    }
}

/// Parameters closer than this (relative to the domain) are the same border sample.
pub(crate) const PARAM_TOLERANCE: f64 = 1e-9;

/// A surface sample: position and unit normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Sample {
    pub p: DVec3,
    pub n: DVec3,
}

/// Position and normal at a canonical parameter.
pub(crate) fn sample(surface: &NurbsSurface, uv: DVec2) -> Sample {
    let d = surface.eval_derivs(uv.x, uv.y, 1);
    let n = match super::super::surface::unit_normal(d.su, d.sv) {
        Some(n) => n,
        None => surface.fallback_normal(uv.x, uv.y),
    };
    Sample { p: d.s, n }
}

#[inline]
fn v3(p: [f64; 3]) -> DVec3 {
    DVec3::from_array(p)
}

#[inline]
fn v2(p: [f64; 2]) -> DVec2 {
    DVec2::from_array(p)
}

/// Max distance between the surface and the mesh at corresponding parameters, sampled at
/// triangle centroids and edge midpoints (spec §2.5 item 4).
pub(crate) fn max_deviation(surface: &NurbsSurface, dom: &ParamDomain, mesh: &TriMesh) -> f64 {
    let tri_max = mesh
        .triangles
        .par_iter()
        .map(|t| {
            let uv = dom.centroid(
                v2(mesh.uvs[t[0] as usize]),
                v2(mesh.uvs[t[1] as usize]),
                v2(mesh.uvs[t[2] as usize]),
            );
            let flat = (v3(mesh.positions[t[0] as usize])
                + v3(mesh.positions[t[1] as usize])
                + v3(mesh.positions[t[2] as usize]))
                / 3.0;
            (surface.eval_point(uv.x, uv.y) - flat).length()
        })
        .reduce(|| 0.0, f64::max);
    let mut keys: Vec<u64> = mesh
        .triangles
        .iter()
        .flat_map(|t| {
            [
                edge_key(t[0], t[1]),
                edge_key(t[1], t[2]),
                edge_key(t[2], t[0]),
            ]
        })
        .collect();
    keys.par_sort_unstable();
    keys.dedup();
    let edge_max = keys
        .par_iter()
        .map(|&k| {
            let (a, b) = ((k >> 32) as usize, (k & 0xffff_ffff) as usize);
            let uv = dom.edge_mid(v2(mesh.uvs[a]), v2(mesh.uvs[b]));
            let chord = (v3(mesh.positions[a]) + v3(mesh.positions[b])) * 0.5;
            (surface.eval_point(uv.x, uv.y) - chord).length()
        })
        .reduce(|| 0.0, f64::max);
    tri_max.max(edge_max)
}
