//! Tensor-product B-spline and NURBS surfaces (thesis §1.2–1.3, eqs. 1.11 and 1.15) and their
//! normals (eq. 1.18).
//!
//! - [`NurbsSurface`] validates its degrees, knots, control net and weights (spec §2.2.3),
//!   stores the net in homogeneous coordinates and evaluates points and derivatives up to order 2
//!   (A3.6 / A4.4).
//! - [`NurbsSurface::normal`] is eq. (1.18) with the deterministic fallback of spec §2.2.5 where
//!   S_u ∥ S_v (the thesis's Example 1.1.5 patch has this at (0, 0)): it never returns NaN.
//! - [`NurbsSurface::grid`] evaluates a whole grid from two [`BasisTable`]s, contracting over i
//!   first and then over j (decision D9).
//! - [`NurbsSurface::insert_knot`] and [`NurbsSurface::decompose`] are Boehm insertion and the
//!   Bézier decomposition the thesis's §2.1 says every tessellator starts from.
//! - [`Topology`] records closed directions and collapsed borders (poles), found by
//!   [`NurbsSurface::detect_topology`]; the tessellators weld seams and poles exactly.

use glam::{DVec3, DVec4};
use rayon::prelude::*;

use super::bezier::{project, BezierPatch};
use super::curve::{homogeneous_points, insert_knot_h, multiplicity};
use super::error::{Dir, Field, NurbsError};
use super::knots::{
    breakpoints, clamped_uniform, ders_basis_funs, find_span, validate_knots, BasisTable,
};

/// Largest control net (points) that knot insertion or decomposition may build.
pub const MAX_NET_POINTS: usize = 1 << 26;

/// Closed directions and collapsed borders of a surface.
///
/// A closed direction's two borders coincide (u = u_min and u = u_max give the same curve);
/// tessellators then give them the same vertices. A pole is a border curve collapsed to a point
/// (the tip of a revolved profile that touches the axis); tessellators weld it to one vertex and
/// drop the triangles that collapse.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Topology {
    /// u = u_min and u = u_max coincide.
    pub closed_u: bool,
    /// v = v_min and v = v_max coincide.
    pub closed_v: bool,
    /// Collapsed borders: [u = u_min, u = u_max, v = v_min, v = v_max].
    pub poles: [bool; 4],
}

/// S and its partial derivatives up to order 2 at one parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceDerivs {
    /// S(u, v).
    pub s: DVec3,
    /// ∂S/∂u.
    pub su: DVec3,
    /// ∂S/∂v.
    pub sv: DVec3,
    /// ∂²S/∂u².
    pub suu: DVec3,
    /// ∂²S/∂u∂v.
    pub suv: DVec3,
    /// ∂²S/∂v².
    pub svv: DVec3,
}

/// Grids of at least this many points are evaluated a row per task.
const PARALLEL_GRID: usize = 1 << 15;

/// What evaluating the rows of a grid `us × vs` needs: the surface and the basis tables of both
/// axes (derivatives too when normals are wanted), built once.
struct GridRows<'a> {
    surface: &'a NurbsSurface,
    us: &'a [f64],
    vs: &'a [f64],
    tu: BasisTable,
    tv: BasisTable,
}

impl<'a> GridRows<'a> {
    fn new(
        surface: &'a NurbsSurface,
        us: &'a [f64],
        vs: &'a [f64],
        normals: bool,
    ) -> Result<Self, NurbsError> {
        for &x in us.iter().chain(vs) {
            if !x.is_finite() {
                return Err(NurbsError::ParameterNotFinite { value: x });
            }
        }
        let [p, q] = surface.degree;
        let order = usize::from(normals);
        Ok(GridRows {
            surface,
            us,
            vs,
            tu: BasisTable::new(&surface.knots_u, p, surface.size[0] - 1, us, order),
            tv: BasisTable::new(&surface.knots_v, q, surface.size[1] - 1, vs, order),
        })
    }

    /// Row `iu`'s points into `prow` (and unit normals into `nrow`, which needs the tables built
    /// with normals). `scratch` holds the row's column sums C_j (and ∂C_j/∂u after them).
    fn row(
        &self,
        iu: usize,
        scratch: &mut Vec<DVec4>,
        prow: &mut [[f64; 3]],
        nrow: Option<&mut [[f64; 3]]>,
    ) {
        let s = self.surface;
        let (p, q, m) = (s.degree[0], s.degree[1], s.size[1]);
        let (tu, tv) = (&self.tu, &self.tv);
        let span_u = tu.spans[iu];
        let derivs = if nrow.is_some() { 2 } else { 1 };
        scratch.clear();
        scratch.resize(derivs * m, DVec4::ZERO);
        for (k, out) in scratch.chunks_exact_mut(m).enumerate() {
            for (ai, &bu) in tu.row(iu, k).iter().enumerate() {
                let row = &s.net[(span_u - p + ai) * m..(span_u - p + ai + 1) * m];
                for (cj, pw) in out.iter_mut().zip(row) {
                    *cj += *pw * bu;
                }
            }
        }
        let (cols, cols_u) = scratch.split_at(m);
        match nrow {
            None => {
                for (iv, out) in prow.iter_mut().enumerate() {
                    let base = tv.spans[iv] - q;
                    let mut h = DVec4::ZERO;
                    for (bj, &bv) in tv.row(iv, 0).iter().enumerate() {
                        h += cols[base + bj] * bv;
                    }
                    *out = project(h).to_array();
                }
            }
            Some(nrow) => {
                let [[a, b], [c, d]] = s.domain();
                for (iv, (out, nout)) in prow.iter_mut().zip(nrow.iter_mut()).enumerate() {
                    let base = tv.spans[iv] - q;
                    let (b0, b1) = (tv.row(iv, 0), tv.row(iv, 1));
                    let (mut h, mut hu, mut hv) = (DVec4::ZERO, DVec4::ZERO, DVec4::ZERO);
                    for bj in 0..=q {
                        h += cols[base + bj] * b0[bj];
                        hu += cols_u[base + bj] * b0[bj];
                        hv += cols[base + bj] * b1[bj];
                    }
                    let pt = h.truncate() / h.w;
                    let su = (hu.truncate() - pt * hu.w) / h.w;
                    let sv = (hv.truncate() - pt * hv.w) / h.w;
                    *out = pt.to_array();
                    let n = match unit_normal(su, sv) {
                        Some(n) => n,
                        None => s.fallback_normal(self.us[iu].clamp(a, b), self.vs[iv].clamp(c, d)),
                    };
                    *nout = n.to_array();
                }
            }
        }
    }
}

/// Points (and optionally unit normals) of a grid, row-major: index `iu * nv + iv`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GridSamples {
    /// S(u_i, v_j).
    pub points: Vec<[f64; 3]>,
    /// Unit normals, empty unless requested.
    pub normals: Vec<[f64; 3]>,
}

/// A validated NURBS surface.
#[derive(Debug, Clone, PartialEq)]
pub struct NurbsSurface {
    degree: [usize; 2],
    size: [usize; 2],
    knots_u: Vec<f64>,
    knots_v: Vec<f64>,
    /// Homogeneous net, row-major: `net[i * size_v + j]`, i along u.
    net: Vec<DVec4>,
    rational: bool,
    topology: Topology,
}

/// Relative threshold of spec §2.2.5: |S_u × S_v| ≤ this · |S_u|·|S_v| is degenerate.
const DEGENERATE_NORMAL: f64 = 1e-10;

impl NurbsSurface {
    /// A surface of degrees `degree = [p, q]` on a `size = [n_u, n_v]` net given row-major
    /// (`points[i * n_v + j]`, i along u), with explicit knots. `weights = None` gives a
    /// B-spline surface. The topology is detected ([`Self::detect_topology`]).
    pub fn new(
        degree: [usize; 2],
        size: [usize; 2],
        points: &[[f64; 3]],
        weights: Option<&[f64]>,
        knots_u: Vec<f64>,
        knots_v: Vec<f64>,
    ) -> Result<Self, NurbsError> {
        validate_knots(&knots_u, degree[0], size[0], Field::DegreeU, Field::KnotsU)?;
        validate_knots(&knots_v, degree[1], size[1], Field::DegreeV, Field::KnotsV)?;
        let expected = size[0].checked_mul(size[1]).ok_or(NurbsError::TooLarge {
            what: "control net",
            requested: size[0] as u128 * size[1] as u128,
            limit: usize::MAX as u128,
        })?;
        if points.len() != expected {
            return Err(NurbsError::NetShape {
                size_u: size[0],
                size_v: size[1],
                expected,
                found: points.len(),
            });
        }
        let net = homogeneous_points(points, weights)?;
        let rational = net.iter().any(|h| h.w != 1.0);
        let mut surface = NurbsSurface {
            degree,
            size,
            knots_u,
            knots_v,
            net,
            rational,
            topology: Topology::default(),
        };
        surface.topology = surface.detect_topology(1e-10);
        Ok(surface)
    }

    /// A surface with clamped uniform knots on [0, 1]² in both directions.
    pub fn clamped(
        degree: [usize; 2],
        size: [usize; 2],
        points: &[[f64; 3]],
        weights: Option<&[f64]>,
    ) -> Result<Self, NurbsError> {
        let ku = clamped_uniform(degree[0], size[0], Field::DegreeU)?;
        let kv = clamped_uniform(degree[1], size[1], Field::DegreeV)?;
        Self::new(degree, size, points, weights, ku, kv)
    }

    /// Builds from an already homogeneous net (internal: insertion and decomposition).
    fn from_parts(
        degree: [usize; 2],
        size: [usize; 2],
        knots_u: Vec<f64>,
        knots_v: Vec<f64>,
        net: Vec<DVec4>,
        topology: Topology,
    ) -> Self {
        let rational = net.iter().any(|h| h.w != 1.0);
        NurbsSurface {
            degree,
            size,
            knots_u,
            knots_v,
            net,
            rational,
            topology,
        }
    }

    /// Degrees [p, q].
    pub fn degree(&self) -> [usize; 2] {
        self.degree
    }

    /// Net size [n_u, n_v].
    pub fn size(&self) -> [usize; 2] {
        self.size
    }

    /// Knots in u.
    pub fn knots_u(&self) -> &[f64] {
        &self.knots_u
    }

    /// Knots in v.
    pub fn knots_v(&self) -> &[f64] {
        &self.knots_v
    }

    /// Whether any weight differs from 1.
    pub fn is_rational(&self) -> bool {
        self.rational
    }

    /// Homogeneous control point (i, j).
    pub fn homogeneous_point(&self, i: usize, j: usize) -> DVec4 {
        self.net[i * self.size[1] + j]
    }

    /// Euclidean control point (i, j).
    pub fn control_point(&self, i: usize, j: usize) -> DVec3 {
        project(self.homogeneous_point(i, j))
    }

    /// The parameter domain [[u_p, u_{n+1}], [v_q, v_{m+1}]].
    pub fn domain(&self) -> [[f64; 2]; 2] {
        [
            [self.knots_u[self.degree[0]], self.knots_u[self.size[0]]],
            [self.knots_v[self.degree[1]], self.knots_v[self.size[1]]],
        ]
    }

    /// Distinct knot values inside the domain, ends included: the borders of the Bézier patches.
    pub fn breakpoints(&self, dir: Dir) -> Vec<f64> {
        match dir {
            Dir::U => breakpoints(&self.knots_u, self.degree[0], self.size[0]),
            Dir::V => breakpoints(&self.knots_v, self.degree[1], self.size[1]),
        }
    }

    /// The recorded topology (detected at construction).
    pub fn topology(&self) -> Topology {
        self.topology
    }

    /// Replaces the topology. A direction declared closed must meet itself within 1e-6 of the
    /// control net's size; a declared pole must be collapsed within the same tolerance.
    pub fn with_topology(mut self, topology: Topology) -> Result<Self, NurbsError> {
        let tol = 1e-6 * self.net_diagonal().max(f64::MIN_POSITIVE);
        let (gap_u, gap_v, pole_gaps) = self.seam_gaps();
        if topology.closed_u && gap_u > tol {
            return Err(NurbsError::NotClosed {
                dir: Dir::U,
                gap: gap_u,
            });
        }
        if topology.closed_v && gap_v > tol {
            return Err(NurbsError::NotClosed {
                dir: Dir::V,
                gap: gap_v,
            });
        }
        for (k, &pole) in topology.poles.iter().enumerate() {
            if pole && pole_gaps[k] > tol {
                let dir = if k < 2 { Dir::U } else { Dir::V };
                return Err(NurbsError::NotClosed {
                    dir,
                    gap: pole_gaps[k],
                });
            }
        }
        self.topology = topology;
        Ok(self)
    }

    /// Diagonal of the bounding box of the Euclidean control points.
    pub fn net_diagonal(&self) -> f64 {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for h in &self.net {
            let p = project(*h);
            lo = lo.min(p);
            hi = hi.max(p);
        }
        (hi - lo).length()
    }

    /// Samples along the borders: parameters at every span's quarter points.
    fn border_samples(&self, dir: Dir) -> Vec<f64> {
        let b = self.breakpoints(dir);
        let mut out = Vec::with_capacity(4 * b.len());
        for w in b.windows(2) {
            for k in 0..4 {
                out.push(w[0] + (w[1] - w[0]) * k as f64 / 4.0);
            }
        }
        out.push(*b.last().unwrap_or(&0.0));
        out
    }

    /// (gap between the u borders, gap between the v borders, spread of each border curve).
    fn seam_gaps(&self) -> (f64, f64, [f64; 4]) {
        let [[a, b], [c, d]] = self.domain();
        let vs = self.border_samples(Dir::V);
        let us = self.border_samples(Dir::U);
        let mut gap_u: f64 = 0.0;
        let mut gap_v: f64 = 0.0;
        let mut poles = [0.0f64; 4];
        let first = [self.eval_point(a, vs[0]), self.eval_point(b, vs[0])];
        for &v in &vs {
            let (p, q) = (self.eval_point(a, v), self.eval_point(b, v));
            gap_u = gap_u.max((p - q).length());
            poles[0] = poles[0].max((p - first[0]).length());
            poles[1] = poles[1].max((q - first[1]).length());
        }
        let first = [self.eval_point(us[0], c), self.eval_point(us[0], d)];
        for &u in &us {
            let (p, q) = (self.eval_point(u, c), self.eval_point(u, d));
            gap_v = gap_v.max((p - q).length());
            poles[2] = poles[2].max((p - first[0]).length());
            poles[3] = poles[3].max((q - first[1]).length());
        }
        (gap_u, gap_v, poles)
    }

    /// Detects closed directions and poles, with a tolerance relative to the net's size
    /// (`rel · diagonal`), by sampling the borders at every span's quarter points.
    pub fn detect_topology(&self, rel: f64) -> Topology {
        let tol = rel * self.net_diagonal();
        let (gap_u, gap_v, pole_gaps) = self.seam_gaps();
        Topology {
            closed_u: gap_u <= tol,
            closed_v: gap_v <= tol,
            poles: pole_gaps.map(|g| g <= tol),
        }
    }

    fn check(&self, u: f64, v: f64) -> Result<(f64, f64), NurbsError> {
        for x in [u, v] {
            if !x.is_finite() {
                return Err(NurbsError::ParameterNotFinite { value: x });
            }
        }
        let [[a, b], [c, d]] = self.domain();
        Ok((u.clamp(a, b), v.clamp(c, d)))
    }

    /// S(u, v); parameters are clamped to the domain.
    pub fn point(&self, u: f64, v: f64) -> Result<DVec3, NurbsError> {
        let (u, v) = self.check(u, v)?;
        Ok(self.eval_point(u, v))
    }

    /// S(u, v) for parameters already inside the domain.
    pub(crate) fn eval_point(&self, u: f64, v: f64) -> DVec3 {
        project(self.eval_h(u, v))
    }

    fn eval_h(&self, u: f64, v: f64) -> DVec4 {
        let [p, q] = self.degree;
        let su = find_span(&self.knots_u, p, self.size[0] - 1, u);
        let sv = find_span(&self.knots_v, q, self.size[1] - 1, v);
        let mut nu = [0.0; 66];
        let mut nv = [0.0; 66];
        let mut scratch = [0.0; 132];
        super::knots::basis_funs(&self.knots_u, su, u, p, &mut nu, &mut scratch);
        super::knots::basis_funs(&self.knots_v, sv, v, q, &mut nv, &mut scratch);
        let mut h = DVec4::ZERO;
        for (a, &bu) in nu[..=p].iter().enumerate() {
            let row = (su - p + a) * self.size[1] + sv - q;
            let mut c = DVec4::ZERO;
            for (b, &bv) in nv[..=q].iter().enumerate() {
                c += self.net[row + b] * bv;
            }
            h += c * bu;
        }
        h
    }

    /// S and its derivatives up to order 2 (A3.6 on the homogeneous net, then A4.4).
    pub fn derivatives(&self, u: f64, v: f64) -> Result<SurfaceDerivs, NurbsError> {
        let (u, v) = self.check(u, v)?;
        Ok(self.eval_derivs(u, v, 2))
    }

    /// Derivatives up to `order` (1 or 2) for parameters inside the domain; higher entries are
    /// zero when `order` = 1.
    pub(crate) fn eval_derivs(&self, u: f64, v: f64, order: usize) -> SurfaceDerivs {
        let [p, q] = self.degree;
        let su = find_span(&self.knots_u, p, self.size[0] - 1, u);
        let sv = find_span(&self.knots_v, q, self.size[1] - 1, v);
        let (wu, wv) = (p + 1, q + 1);
        let mut du = vec![0.0; (order + 1) * wu];
        let mut dv = vec![0.0; (order + 1) * wv];
        ders_basis_funs(&self.knots_u, su, u, p, order, &mut du);
        ders_basis_funs(&self.knots_v, sv, v, q, order, &mut dv);
        // a[k][l]: homogeneous derivative of order (k, l), k + l ≤ order.
        let mut a = [[DVec4::ZERO; 3]; 3];
        let mut temp = [DVec4::ZERO; 3];
        for b in 0..wv {
            // contract over i first: temp[k] = Σ_a N_a^(k)(u) P_{a, b}
            for t in temp.iter_mut() {
                *t = DVec4::ZERO;
            }
            for ai in 0..wu {
                let pw = self.net[(su - p + ai) * self.size[1] + sv - q + b];
                for (k, t) in temp.iter_mut().enumerate().take(order + 1) {
                    *t += pw * du[k * wu + ai];
                }
            }
            for (k, ak) in a.iter_mut().enumerate().take(order + 1) {
                for (l, akl) in ak.iter_mut().enumerate().take(order + 1 - k) {
                    *akl += temp[k] * dv[l * wv + b];
                }
            }
        }
        let s = rational_surface_derivs(&a, order);
        SurfaceDerivs {
            s: s[0][0],
            su: s[1][0],
            sv: s[0][1],
            suu: s[2][0],
            suv: s[1][1],
            svv: s[0][2],
        }
    }

    /// Unit normal (S_u × S_v)/|S_u × S_v| (thesis eq. 1.18), never NaN.
    ///
    /// Where |S_u × S_v| ≤ 1e-10·|S_u|·|S_v| (S_u ∥ S_v, a collapsed edge, a pole) the normal is
    /// taken at (u + δ_u, v + δ_v), δ = 1e-6 of the domain span, stepping toward the domain's
    /// centre; then 1e-4 and 1e-2. A surface degenerate everywhere there gets +Z.
    pub fn normal(&self, u: f64, v: f64) -> Result<DVec3, NurbsError> {
        let (u, v) = self.check(u, v)?;
        Ok(self.eval_normal(u, v))
    }

    pub(crate) fn eval_normal(&self, u: f64, v: f64) -> DVec3 {
        let d = self.eval_derivs(u, v, 1);
        if let Some(n) = unit_normal(d.su, d.sv) {
            return n;
        }
        self.fallback_normal(u, v)
    }

    /// The stepping fallback of spec §2.2.5, toward the domain centre.
    pub(crate) fn fallback_normal(&self, u: f64, v: f64) -> DVec3 {
        let [[a, b], [c, d]] = self.domain();
        let (cu, cv) = (0.5 * (a + b), 0.5 * (c + d));
        let su = if u <= cu { 1.0 } else { -1.0 };
        let sv = if v <= cv { 1.0 } else { -1.0 };
        for scale in [1e-6, 1e-4, 1e-2] {
            let uu = (u + su * scale * (b - a)).clamp(a, b);
            let vv = (v + sv * scale * (d - c)).clamp(c, d);
            let dd = self.eval_derivs(uu, vv, 1);
            if let Some(n) = unit_normal(dd.su, dd.sv) {
                return n;
            }
        }
        DVec3::Z
    }

    /// Points (and unit normals if `normals`) on the grid `us × vs`, by basis tables built once
    /// per axis and a factorised contraction: per u sample, C_j = Σ_i N_i(u) P^w_ij for every
    /// column j; then per v sample Σ_j N_j(v) C_j (decision D9). Rows run in parallel; every
    /// point is computed the same way at any thread count.
    pub fn grid(&self, us: &[f64], vs: &[f64], normals: bool) -> Result<GridSamples, NurbsError> {
        let rows = GridRows::new(self, us, vs, normals)?;
        let nv = vs.len();
        let total = us.len() * nv;
        let mut points = vec![[0.0; 3]; total];
        let mut norms = if normals {
            vec![[0.0; 3]; total]
        } else {
            Vec::new()
        };
        if nv == 0 {
            return Ok(GridSamples {
                points,
                normals: norms,
            });
        }
        let parallel = total >= PARALLEL_GRID;
        if normals {
            type Rows<'r> = (&'r mut [[f64; 3]], &'r mut [[f64; 3]]);
            let job = |(iu, (pr, nr)): (usize, Rows)| rows.row(iu, &mut Vec::new(), pr, Some(nr));
            if parallel {
                points
                    .par_chunks_mut(nv)
                    .zip(norms.par_chunks_mut(nv))
                    .enumerate()
                    .for_each(job);
            } else {
                points
                    .chunks_mut(nv)
                    .zip(norms.chunks_mut(nv))
                    .enumerate()
                    .for_each(job);
            }
        } else {
            let job = |(iu, pr): (usize, &mut [[f64; 3]])| rows.row(iu, &mut Vec::new(), pr, None);
            if parallel {
                points.par_chunks_mut(nv).enumerate().for_each(job);
            } else {
                points.chunks_mut(nv).enumerate().for_each(job);
            }
        }
        Ok(GridSamples {
            points,
            normals: norms,
        })
    }

    /// The largest `measure(iu, row)` over the rows of the grid `us × vs`, every row's points
    /// computed as [`NurbsSurface::grid`] computes them but into a buffer of the task's own
    /// that the next row reuses: the grid is never stored whole. A uniform tessellation's
    /// deviation (spec §2.5 item 4) takes a maximum over five grids of a million points at 1000²;
    /// storing them cost more in freshly touched memory than evaluating them (issue 38).
    /// `0.0` for an empty grid; NaN measures are passed over, as `f64::max` does, so the result
    /// does not depend on the order rows are taken in.
    pub fn grid_rows_max(
        &self,
        us: &[f64],
        vs: &[f64],
        measure: impl Fn(usize, &[[f64; 3]]) -> f64 + Sync,
    ) -> Result<f64, NurbsError> {
        let rows = GridRows::new(self, us, vs, false)?;
        let nv = vs.len();
        if nv == 0 {
            return Ok(0.0);
        }
        let scratch = || (Vec::new(), vec![[0.0; 3]; nv]);
        let job = |(cols, row): &mut (Vec<DVec4>, Vec<[f64; 3]>), iu: usize| {
            rows.row(iu, cols, row, None);
            measure(iu, row)
        };
        Ok(if us.len() * nv >= PARALLEL_GRID {
            (0..us.len())
                .into_par_iter()
                .map_init(scratch, job)
                .reduce(|| 0.0, f64::max)
        } else {
            let mut buffers = scratch();
            (0..us.len())
                .map(|iu| job(&mut buffers, iu))
                .fold(0.0, f64::max)
        })
    }

    /// Inserts `value` `times` times in direction `dir` (Boehm, A5.3): the surface is unchanged.
    pub fn insert_knot(
        &self,
        dir: Dir,
        value: f64,
        times: usize,
    ) -> Result<NurbsSurface, NurbsError> {
        let [nu, nv] = self.size;
        match dir {
            Dir::U => {
                let field = Field::KnotsU;
                let p = self.degree[0];
                let new_n = nu + times;
                check_net(new_n, nv)?;
                let mut net = vec![DVec4::ZERO; new_n * nv];
                let mut knots = Vec::new();
                for j in 0..nv {
                    let column: Vec<DVec4> = (0..nu).map(|i| self.net[i * nv + j]).collect();
                    let (k, c) = insert_knot_h(&self.knots_u, p, &column, value, times, field)?;
                    for (i, h) in c.into_iter().enumerate() {
                        net[i * nv + j] = h;
                    }
                    knots = k;
                }
                Ok(Self::from_parts(
                    self.degree,
                    [new_n, nv],
                    knots,
                    self.knots_v.clone(),
                    net,
                    self.topology,
                ))
            }
            Dir::V => {
                let field = Field::KnotsV;
                let q = self.degree[1];
                let new_m = nv + times;
                check_net(nu, new_m)?;
                let mut net = Vec::with_capacity(nu * new_m);
                let mut knots = Vec::new();
                for i in 0..nu {
                    let row = &self.net[i * nv..(i + 1) * nv];
                    let (k, r) = insert_knot_h(&self.knots_v, q, row, value, times, field)?;
                    net.extend(r);
                    knots = k;
                }
                Ok(Self::from_parts(
                    self.degree,
                    [nu, new_m],
                    self.knots_u.clone(),
                    knots,
                    net,
                    self.topology,
                ))
            }
        }
    }

    /// Decomposition into rational Bézier patches (A5.7): every distinct knot value in the
    /// domain, ends included, is raised to multiplicity p (q in v). Adjacent patches share their
    /// border row of control points, so their border curves are identical (spec §2.2.4).
    pub fn decompose(&self) -> Result<BezierNet, NurbsError> {
        let [p, q] = self.degree;
        let bu = self.breakpoints(Dir::U);
        let bv = self.breakpoints(Dir::V);
        let pu = bu.len() - 1;
        let pv = bv.len() - 1;
        check_net(pu * p + 1 + 2 * p, pv * q + 1 + 2 * q)?;
        let mut s = self.clone();
        for &x in &bu {
            let m = multiplicity(&s.knots_u, x);
            if m < p {
                s = s.insert_knot(Dir::U, x, p - m)?;
            }
        }
        for &x in &bv {
            let m = multiplicity(&s.knots_v, x);
            if m < q {
                s = s.insert_knot(Dir::V, x, q - m)?;
            }
        }
        // First control index of the first span in each direction; spans then advance by p (q).
        let su0 = find_span(&s.knots_u, p, s.size[0] - 1, 0.5 * (bu[0] + bu[1])) - p;
        let sv0 = find_span(&s.knots_v, q, s.size[1] - 1, 0.5 * (bv[0] + bv[1])) - q;
        let (rows, cols) = (pu * p + 1, pv * q + 1);
        let mut net = Vec::with_capacity(rows * cols);
        for i in 0..rows {
            let base = (su0 + i) * s.size[1] + sv0;
            net.extend_from_slice(&s.net[base..base + cols]);
        }
        Ok(BezierNet {
            degree: [p, q],
            patches: [pu, pv],
            breaks_u: bu,
            breaks_v: bv,
            net,
        })
    }
}

fn check_net(nu: usize, nv: usize) -> Result<(), NurbsError> {
    let requested = nu as u128 * nv as u128;
    if requested > MAX_NET_POINTS as u128 {
        return Err(NurbsError::TooLarge {
            what: "control net after knot insertion",
            requested,
            limit: MAX_NET_POINTS as u128,
        });
    }
    Ok(())
}

/// Unit S_u × S_v, or `None` when degenerate (spec §2.2.5) or not finite.
#[inline]
pub(crate) fn unit_normal(su: DVec3, sv: DVec3) -> Option<DVec3> {
    let n = su.cross(sv);
    let len2 = n.length_squared();
    // |n| > 1e-10·|S_u|·|S_v|, compared squared (one square root instead of three).
    let limit = DEGENERATE_NORMAL * DEGENERATE_NORMAL * su.length_squared() * sv.length_squared();
    if len2 > limit && len2 > 0.0 && len2.is_finite() {
        Some(n / len2.sqrt())
    } else {
        None
    }
}

/// Rational surface derivatives from homogeneous ones (A4.4), orders k + l ≤ `order` ≤ 2.
fn rational_surface_derivs(a: &[[DVec4; 3]; 3], order: usize) -> [[DVec3; 3]; 3] {
    const BIN: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 2.0, 1.0]];
    let mut s = [[DVec3::ZERO; 3]; 3];
    let w00 = a[0][0].w;
    for k in 0..=order {
        for l in 0..=(order - k) {
            let mut v = a[k][l].truncate();
            for j in 1..=l {
                v -= s[k][l - j] * (BIN[l][j] * a[0][j].w);
            }
            for i in 1..=k {
                v -= s[k - i][l] * (BIN[k][i] * a[i][0].w);
                let mut v2 = DVec3::ZERO;
                for j in 1..=l {
                    v2 += s[k - i][l - j] * (BIN[l][j] * a[i][j].w);
                }
                v -= v2 * BIN[k][i];
            }
            s[k][l] = v / w00;
        }
    }
    s
}

/// A surface decomposed into Bézier patches on one shared net.
#[derive(Debug, Clone, PartialEq)]
pub struct BezierNet {
    /// Degrees [p, q].
    pub degree: [usize; 2],
    /// Patch counts [in u, in v].
    pub patches: [usize; 2],
    /// Patch borders in u (patches[0] + 1 values).
    pub breaks_u: Vec<f64>,
    /// Patch borders in v.
    pub breaks_v: Vec<f64>,
    /// Homogeneous net of (patches[0]·p + 1) × (patches[1]·q + 1) points, row-major.
    pub net: Vec<DVec4>,
}

impl BezierNet {
    /// Net columns.
    pub fn cols(&self) -> usize {
        self.patches[1] * self.degree[1] + 1
    }

    /// Homogeneous net point (i, j).
    pub fn at(&self, i: usize, j: usize) -> DVec4 {
        self.net[i * self.cols() + j]
    }

    /// Patch (a, b): rows a·p..=(a+1)·p, columns b·q..=(b+1)·q.
    pub fn patch(&self, a: usize, b: usize) -> BezierPatch {
        let [p, q] = self.degree;
        let mut points = Vec::with_capacity((p + 1) * (q + 1));
        for i in 0..=p {
            for j in 0..=q {
                points.push(self.at(a * p + i, b * q + j));
            }
        }
        BezierPatch {
            degree_u: p,
            degree_v: q,
            points,
            u_range: [self.breaks_u[a], self.breaks_u[a + 1]],
            v_range: [self.breaks_v[b], self.breaks_v[b + 1]],
        }
    }

    /// All patches, u-major.
    pub fn all_patches(&self) -> Vec<BezierPatch> {
        let mut out = Vec::with_capacity(self.patches[0] * self.patches[1]);
        for a in 0..self.patches[0] {
            for b in 0..self.patches[1] {
                out.push(self.patch(a, b));
            }
        }
        out
    }
}
