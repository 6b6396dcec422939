//! Parametric surfaces in the engine (thesis 002, issue 15): `nurbs`
//! builds a `[nurbs.NAME]` surface with the variant's parameters,
//! tessellates it (uniform, inter-patch or fully adaptive) and appends the
//! triangles; `pn_smooth` replaces the model by PN triangles (Vlachos et
//! al.) over its crease-split vertex normals. Both check the primitive
//! budget inside the library, before the output is allocated.

use glam::{DMat3, DVec3};

use super::error::StepError;
use crate::geom::normals::corner_normals;
use crate::geom::sink::{Begin, MeshSink, Placed};
use crate::geom::uv::{SURFACE_U, SURFACE_V};
use crate::kernel::build::KernelBuilder;
use crate::kernel::ops::Selection;
use crate::kernel::{AttrValue, Domain, Mesh};
use crate::nurbs::error::Dir;
use crate::nurbs::pn::{pn_triangles, Creases, Pattern, PnError, PnOptions};
use crate::nurbs::surface::NurbsSurface;
use crate::nurbs::tess::{
    tessellate, tessellate_set, uniform_grid, AdaptiveOptions, Diagonal, Mode, TessError,
    Tessellation, UniformGrid,
};
use crate::nurbs::tess::{Combine, EdgeTest};
use crate::rules::nurbs_def::SurfaceDef;
use crate::rules::op_args::{self, EdgeTestName, PnPattern, TessMode, TessellateArgs};
use crate::rules::program::Scalar;

/// What the parametric operators need of the run.
pub(super) struct SurfaceContext<'a> {
    pub slots: &'a [f64],
    pub surfaces: &'a [SurfaceDef],
    /// The files the program read (patch files by resource index).
    pub inputs: &'a [super::fields::Input],
    /// Primitives the model may still grow by.
    pub budget: u64,
    /// The program uses G³ commands (a new model gets the graph layers).
    pub uses_graph: bool,
}

/// What a tessellation or PN smoothing made, for the stats.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceStats {
    /// Surfaces tessellated, or meshes smoothed.
    pub runs: usize,
    pub triangles: u64,
    pub vertices: u64,
    /// Largest distance between the surface and the mesh, sampled at every
    /// triangle centroid and edge midpoint (tessellation).
    pub max_deviation: f64,
    /// Adaptive: highest edge level reached, and refinement rounds.
    pub max_level: u32,
    pub rounds: u32,
    /// Bézier patches of the surface (knot spans u × v).
    pub patches: usize,
    /// PN: the level used.
    pub pn_level: Option<u32>,
}

impl SurfaceStats {
    pub fn add(&mut self, o: &SurfaceStats) {
        self.runs += o.runs;
        self.triangles += o.triangles;
        self.vertices += o.vertices;
        self.max_deviation = self.max_deviation.max(o.max_deviation);
        self.max_level = self.max_level.max(o.max_level);
        self.rounds = self.rounds.max(o.rounds);
        self.patches += o.patches;
        self.pn_level = self.pn_level.max(o.pn_level);
    }
}

/// Most triangles the budget allows (a triangle brings one face, about
/// one and a half edges and half a vertex).
fn triangle_cap(budget: u64) -> usize {
    usize::try_from(budget / 3).unwrap_or(usize::MAX)
}

/// A surface tessellated: a mesh, or a uniform grid kept as its samples.
enum Tessellated {
    Mesh(Tessellation),
    Grid(UniformGrid),
}

/// What the caller takes: a grid where the tessellation is one (it builds the mesh in closed
/// form), or always a mesh.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Shape {
    GridOrMesh,
    Mesh,
}

/// The step's surface tessellated as its parameters say; the stats of one
/// tessellation.
fn tessellate_call(
    ctx: &SurfaceContext,
    args: &TessellateArgs,
    copies: usize,
    shape: Shape,
) -> Result<(Tessellated, SurfaceStats), StepError> {
    let def = &ctx.surfaces[args.surface];
    let file_patches = |resource: usize| {
        ctx.inputs
            .get(resource)
            .and_then(|input| input.patches.as_ref())
            .map(|p| p.to_vec())
    };
    let set = def
        .build_set(ctx.surfaces, ctx.slots, &file_patches)
        .map_err(|e| StepError::Surface {
            surface: def.name.clone(),
            message: format!("{}: {}", e.key, e.message),
        })?;
    let value = |e: &Option<Scalar>| e.as_ref().map(|e| e.eval(ctx.slots));
    let tolerance = value(&args.tolerance).unwrap_or(1e-3);
    let mode = match args.mode {
        TessMode::Uniform => {
            let cells = match &args.cells {
                Some([u, v]) => [u.eval(ctx.slots), v.eval(ctx.slots)],
                None => [8.0, 8.0],
            };
            let count = |x: f64| -> Result<usize, StepError> {
                if !(x.is_finite() && x >= 1.0) {
                    return Err(StepError::Option {
                        key: "cells",
                        message: format!("must be at least 1, got {x}"),
                    });
                }
                Ok(libm::round(x).min(1e9) as usize)
            };
            Mode::Uniform {
                cells: [count(cells[0])?, count(cells[1])?],
                per_patch: args.per_patch,
                diagonal: Diagonal::Fixed,
            }
        }
        TessMode::InterPatch => Mode::InterPatch { tolerance },
        TessMode::Adaptive => {
            let mut options = AdaptiveOptions::sagitta(tolerance);
            let level = args.max_level.eval(ctx.slots);
            options.max_level = libm::round(level).clamp(1.0, 64.0) as u32;
            let threshold = |default: f64| value(&args.threshold).unwrap_or(default);
            let extra = match args.test {
                EdgeTestName::OneEdgeNormal => Some(EdgeTest::OneEdgeNormal {
                    t1: threshold(0.02),
                }),
                EdgeTestName::OneEdgeComplementary => Some(EdgeTest::OneEdgeComplementary {
                    t1: threshold(0.02),
                    t2: 2.0 * threshold(0.02),
                }),
                EdgeTestName::TwoTriangle => Some(EdgeTest::TwoTriangle {
                    t3: threshold(0.02),
                }),
                EdgeTestName::FirstOrderNeighbour => Some(EdgeTest::FirstOrderNeighbour {
                    t3: threshold(0.02),
                }),
                EdgeTestName::VectorDeviation => Some(EdgeTest::VectorDeviation {
                    cos_max: threshold(libm::cos(2f64.to_radians())),
                }),
                EdgeTestName::LocalFlat => Some(EdgeTest::LocalFlat { t: threshold(0.05) }),
                EdgeTestName::UmbrellaFlat => Some(EdgeTest::UmbrellaFlat { t: threshold(0.05) }),
                EdgeTestName::Sagitta => None,
            };
            if let Some(test) = extra {
                options.tests.push(test);
                // The flip rule is for the chordal test alone.
                options.flips = false;
            }
            if args.combine == op_args::Combine::All {
                options.combine = Combine::All;
            }
            Mode::Adaptive(options)
        }
    };
    // Every copy counts against the budget.
    let cap = triangle_cap(ctx.budget / copies.max(1) as u64);
    // One surface keeps its own path (seams and poles within it); a set is welded across.
    let t = match (set.surfaces.as_slice(), &mode, shape) {
        (
            [surface],
            &Mode::Uniform {
                cells,
                per_patch,
                diagonal: Diagonal::Fixed,
            },
            Shape::GridOrMesh,
        ) if !def.is_set() => match uniform_grid(surface, cells, per_patch, cap) {
            Ok(Some(grid)) => Ok(Tessellated::Grid(grid)),
            Ok(None) => tessellate(surface, &mode, cap).map(Tessellated::Mesh),
            Err(e) => Err(e),
        },
        ([surface], ..) if !def.is_set() => tessellate(surface, &mode, cap).map(Tessellated::Mesh),
        _ => tessellate_set(&set, &mode, cap).map(Tessellated::Mesh),
    };
    let t = t.map_err(|e| match e {
        TessError::TriangleLimit { needed, .. } => StepError::FieldTooLarge {
            what: if copies > 1 {
                format!("{copies} copies of `{}`", def.name)
            } else {
                format!("tessellating `{}`", def.name)
            },
            coming: u64::try_from(needed.saturating_mul(3).saturating_mul(copies as u128))
                .unwrap_or(u64::MAX),
            budget: ctx.budget,
        },
        other => StepError::Surface {
            surface: def.name.clone(),
            message: other.to_string(),
        },
    })?;
    let tess = match &t {
        Tessellated::Mesh(t) => &t.stats,
        Tessellated::Grid(g) => &g.stats,
    };
    let stats = SurfaceStats {
        runs: 1,
        triangles: tess.triangles as u64,
        vertices: tess.vertices as u64,
        max_deviation: tess.max_deviation,
        max_level: tess.max_level,
        rounds: tess.rounds,
        patches: set
            .surfaces
            .iter()
            .map(|surface| {
                [Dir::U, Dir::V]
                    .iter()
                    .map(|&d| surface.breakpoints(d).len().saturating_sub(1))
                    .product::<usize>()
            })
            .sum(),
        pn_level: None,
    };
    Ok((t, stats))
}

/// `nurbs`: the surface tessellated, appended.
pub(super) fn create(
    ctx: &SurfaceContext,
    mesh: &mut Mesh,
    args: &TessellateArgs,
) -> Result<(Selection, SurfaceStats), StepError> {
    let (t, stats) = tessellate_call(ctx, args, 1, Shape::GridOrMesh)?;
    let made = match t {
        Tessellated::Grid(g) => {
            let uvs = g.us.iter().flat_map(|&u| g.vs.iter().map(move |&v| [u, v]));
            match append_grid(mesh, [g.us.len(), g.vs.len()], &g.positions, Some(uvs)) {
                Some(made) => made,
                None => append_surface(mesh, &g.positions, &g.uvs(), &g.triangles(), None)?,
            }
        }
        Tessellated::Mesh(t) => {
            let t = &t.mesh;
            let with_uv = !t.uvs.is_empty() && t.uvs.len() == t.positions.len();
            let uvs = with_uv.then_some(t.uvs.iter().copied());
            let made = grid_shape(t.positions.len(), &t.triangles)
                .and_then(|shape| append_grid(mesh, shape, &t.positions, uvs));
            match made {
                Some(made) => made,
                None => append_surface(mesh, &t.positions, &t.uvs, &t.triangles, None)?,
            }
        }
    };
    Ok((made, stats))
}

/// A tessellation that is a grid (uniform, without seams or poles) built
/// in closed form, in parallel ([`Mesh::append_triangle_grid`]): the mesh
/// [`append_surface`] would build, with the vertices' surface parameters
/// `uvs`, in vertex order, when given. `None` when the kernel declines;
/// nothing is changed then.
fn append_grid(
    mesh: &mut Mesh,
    [nu, nv]: [usize; 2],
    positions: &[[f64; 3]],
    uvs: Option<impl Iterator<Item = [f64; 2]> + Clone>,
) -> Option<Selection> {
    let made = mesh.append_triangle_grid(nu, nv, positions)?;
    if let Some(uvs) = uvs {
        for name in [SURFACE_U, SURFACE_V] {
            // A same-named layer of another kind stays; values then do not
            // land (as in the face-by-face build).
            let _ = mesh.add_layer(name, Domain::Vert, AttrValue::Scalar(0.0));
        }
        let end = made.verts.iter().map(|v| v.index() + 1).max().unwrap_or(0);
        for (name, axis) in [(SURFACE_U, 0), (SURFACE_V, 1)] {
            let values = made.verts.iter().zip(uvs.clone());
            let values = values.map(|(v, uv)| (v.index(), uv[axis]));
            let _ = mesh.set_scalar_attrs(name, Domain::Vert, end, values);
        }
    }
    Some(made)
}

/// `[nu, nv]` when `triangles` over `vertices` points are exactly the grid
/// [`Mesh::append_triangle_grid`] makes: vertex (i, j) = i·nv + j, cells
/// in order, each as (a, b, c), (a, c, d).
fn grid_shape(vertices: usize, triangles: &[[u32; 3]]) -> Option<[usize; 2]> {
    let nv = triangles.first()?[1] as usize;
    if nv < 2 || vertices % nv != 0 {
        return None;
    }
    let nu = vertices / nv;
    if nu < 2 || triangles.len() != 2 * (nu - 1) * (nv - 1) {
        return None;
    }
    let cv = nv - 1;
    let grid = triangles.chunks_exact(2).enumerate().all(|(cell, pair)| {
        let a = ((cell / cv) * nv + cell % cv) as u32;
        let (b, d) = (a + nv as u32, a + 1);
        pair[0] == [a, b, b + 1] && pair[1] == [a, b + 1, d]
    });
    grid.then_some([nu, nv])
}

/// `nurbs_part`: the surface tessellated once and placed in the frame of
/// every selected primitive (scaled by its size when `relative`).
pub(super) fn place_parts(
    ctx: &SurfaceContext,
    mesh: &mut Mesh,
    (args, relative): (&TessellateArgs, bool),
    domain: Domain,
    selected: &[usize],
) -> Result<(Selection, SurfaceStats), StepError> {
    let placements: Vec<(DMat3, DVec3, f64)> = selected
        .iter()
        .map(|&i| super::fields::placement(mesh, domain, i, relative))
        .collect();
    if placements.is_empty() {
        return Ok((Selection::new(), SurfaceStats::default()));
    }
    let (t, one) = tessellate_call(ctx, args, placements.len(), Shape::Mesh)?;
    let Tessellated::Mesh(t) = t else {
        unreachable!("`Shape::Mesh` asks for a mesh");
    };
    let n = placements.len() as u64;
    let stats = SurfaceStats {
        triangles: one.triangles * n,
        vertices: one.vertices * n,
        // Deviation scales with the copy.
        max_deviation: placements
            .iter()
            .fold(0.0f64, |m, p| m.max(one.max_deviation * p.2)),
        ..one
    };
    let mut made = Selection::new();
    for (linear, origin, _) in placements {
        let part = append_surface(
            mesh,
            &t.mesh.positions,
            &t.mesh.uvs,
            &t.mesh.triangles,
            Some((linear, origin)),
        )?;
        made.verts.extend(part.verts);
        made.edges.extend(part.edges);
        made.faces.extend(part.faces);
    }
    Ok((made, stats))
}

/// `pn_smooth`: the model's faces (triangulated) replaced by PN triangles.
pub(super) fn pn_smooth(
    ctx: &SurfaceContext,
    mesh: &mut Mesh,
    (level, pattern, crease): (&Scalar, PnPattern, &Scalar),
) -> Result<(Selection, SurfaceStats), StepError> {
    let level = level.eval(ctx.slots);
    if !(level.is_finite() && level >= 1.0) {
        return Err(StepError::Option {
            key: "level",
            message: format!("must be at least 1, got {level}"),
        });
    }
    let level = libm::round(level).min(f64::from(u32::MAX)) as u32;
    let crease = crease.eval(ctx.slots);
    let current = mesh.to_indexed();
    let triangles = current.triangles();
    if triangles.is_empty() {
        return Ok((Selection::new(), SurfaceStats::default()));
    }
    let normals = corner_normals(&current.positions, &triangles, crease);
    let options = PnOptions {
        pattern: match pattern {
            PnPattern::Gl => Pattern::Gl,
            PnPattern::Uniform => Pattern::Uniform,
        },
        // Edges whose corner normals differ stay straight: a crease stays
        // a sharp edge, and the faces beside it stay flat where they were.
        creases: Creases::Keep,
        ..PnOptions::level(level)
    };
    let cap = triangle_cap(ctx.budget);
    let pn = pn_triangles(&current.positions, &triangles, &normals, &options, cap).map_err(
        |e| match e {
            PnError::TriangleLimit { needed, .. } => StepError::FieldTooLarge {
                what: "PN smoothing".into(),
                coming: u64::try_from(needed.saturating_mul(3)).unwrap_or(u64::MAX),
                budget: ctx.budget,
            },
            other => StepError::Surface {
                surface: "the model".into(),
                message: other.to_string(),
            },
        },
    )?;
    // Vertices split only by their shading normal weld into one point, so
    // a closed model stays closed.
    let mut positions = vec![[0.0; 3]; pn.points];
    for (v, &point) in pn.point_of_vertex.iter().enumerate() {
        positions[point as usize] = pn.mesh.positions[v];
    }
    let welded: Vec<[u32; 3]> = pn
        .mesh
        .triangles
        .iter()
        .map(|t| t.map(|v| pn.point_of_vertex[v as usize]))
        .collect();
    let stats = SurfaceStats {
        runs: 1,
        triangles: welded.len() as u64,
        vertices: positions.len() as u64,
        pn_level: Some(level),
        ..SurfaceStats::default()
    };
    *mesh = Mesh::new();
    if ctx.uses_graph {
        super::graph::ensure_layers(mesh);
    }
    let made = append_triangles(mesh, &positions, &welded, None)?;
    Ok((made, stats))
}

/// `nurbs_patch`: the (n + 1)² grid points of the bicubic Bézier patch on
/// a quad's corners — its 4 × 4 net the bilinear interpolation of the
/// corners, the four inner points raised by `lift` — row-major, `i` along
/// corner 0 → 1. The border net is the quad's edges, so the patch's border
/// is each edge itself (Bézier curves reproduce lines).
pub(super) fn quad_patch_grid(corners: [DVec3; 4], lift: DVec3, n: usize) -> Vec<DVec3> {
    let bilinear = |u: f64, v: f64| {
        corners[0] * ((1.0 - u) * (1.0 - v))
            + corners[1] * (u * (1.0 - v))
            + corners[2] * (u * v)
            + corners[3] * ((1.0 - u) * v)
    };
    let mut net = Vec::with_capacity(16);
    for i in 0..4 {
        for j in 0..4 {
            let inner = (1..3).contains(&i) && (1..3).contains(&j);
            let p =
                bilinear(i as f64 / 3.0, j as f64 / 3.0) + if inner { lift } else { DVec3::ZERO };
            net.push(p.to_array());
        }
    }
    let ts: Vec<f64> = (0..=n).map(|k| k as f64 / n as f64).collect();
    match NurbsSurface::clamped([3, 3], [4, 4], &net, None).and_then(|s| s.grid(&ts, &ts, false)) {
        Ok(g) => g.points.into_iter().map(DVec3::from_array).collect(),
        // Only non-finite corners fail; their grid is the bilinear one.
        Err(_) => ts
            .iter()
            .flat_map(|&u| ts.iter().map(move |&v| (u, v)))
            .map(|(u, v)| bilinear(u, v))
            .collect(),
    }
}

/// Appends a triangle mesh to the kernel mesh through its sink, mapped by
/// `placed` = (linear, origin) when given.
fn append_triangles(
    mesh: &mut Mesh,
    positions: &[[f64; 3]],
    triangles: &[[u32; 3]],
    placed: Option<(DMat3, DVec3)>,
) -> Result<Selection, StepError> {
    append_surface(mesh, positions, &[], triangles, placed)
}

/// [`append_triangles`] whose vertices also carry their surface
/// parameters `(u, v)` (when `uvs` has one per vertex) in the vertex
/// layers [`SURFACE_U`] and [`SURFACE_V`], for `uv = { projection =
/// "surface" }` (issue 16).
fn append_surface(
    mesh: &mut Mesh,
    positions: &[[f64; 3]],
    uvs: &[[f64; 2]],
    triangles: &[[u32; 3]],
    placed: Option<(DMat3, DVec3)>,
) -> Result<Selection, StepError> {
    let with_uv = !uvs.is_empty() && uvs.len() == positions.len();
    let names: &[&str] = if with_uv {
        &[SURFACE_U, SURFACE_V]
    } else {
        &[]
    };
    let mut builder = KernelBuilder::new(mesh);
    let emit = |sink: &mut dyn MeshSink| {
        sink.begin(&Begin {
            vertices: positions.len(),
            polygons: triangles.len(),
            scalars: names,
            ..Begin::default()
        })?;
        for (i, p) in positions.iter().enumerate() {
            let scalars = if with_uv { &uvs[i][..] } else { &[][..] };
            sink.vertex(DVec3::from_array(*p), scalars)?;
        }
        for t in triangles {
            sink.polygon(t)?;
        }
        sink.end()
    };
    let emitted = match placed {
        Some((linear, origin)) => emit(&mut Placed::new(&mut builder, linear, origin)),
        None => emit(&mut builder),
    };
    emitted.map_err(|error| {
        builder.abort();
        StepError::Import {
            file: "the tessellation".into(),
            error,
        }
    })?;
    Ok(builder.finish().0)
}
