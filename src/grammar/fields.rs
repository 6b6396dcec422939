//! The engine's side of the implicit-surface pillar (thesis 004): the
//! `sdf`, `sdf_part` and `sdf_boolean` operators and the field method of
//! `skin`. Trees are built from the program with the step's parameter
//! values ([`crate::rules::sdf_tree`]), compiled to a tape and meshed by
//! [`crate::sdf`]; the triangles enter the kernel through its builder, so
//! what comes out is ordinary kernel faces every later step can select.
//!
//! Imported meshes become distance fields once per batch: [`Input`] keeps
//! each file's decoded mesh and, on first use, its [`MeshField`] for each
//! sign mode, shared by every variant (and thread) of the batch.

use crate::nurbs::surface::NurbsSurface;
use std::sync::{Arc, OnceLock};
use std::time::Duration;

use glam::{DMat3, DVec3};

use super::error::StepError;
use super::graph;
use crate::geom::sink::{MeshSink, Placed};
use crate::geom::IndexedMesh;
use crate::kernel::build::KernelBuilder;
use crate::kernel::ops::delete::{self, DeleteMode};
use crate::kernel::ops::{self, Selection};
use crate::kernel::{Domain, EdgeId, FaceId, Mesh, VertId};
use crate::rules::op_args::{self as args, BooleanOp, MeshingArgs, SkinArgs};
use crate::rules::program::Scalar;
use crate::rules::sdf_tree::tree_limits;
use crate::rules::sdf_tree::{BuiltTree, SdfForest};
use crate::sdf::{
    self, GridKind, MeshCheck, MeshField, MeshLimits, MeshOptions, MeshOutput, Mesher, Node,
    Resolution, SdfError, SignMethod, SignMode, Skeleton, SkinNode, SkinOptions, Tape,
    VertexPlacement,
};

/// A file the program reads, decoded, with its distance fields built on
/// first use.
#[derive(Debug)]
pub struct Input {
    pub mesh: Arc<IndexedMesh>,
    /// A patch file's surfaces (`[nurbs.NAME] patches = "…"`); the mesh is then empty.
    pub patches: Option<Arc<[NurbsSurface]>>,
    /// By sign mode (auto, pseudonormal, winding) × up axis (z, y).
    fields: [OnceLock<Result<Arc<MeshField>, String>>; 6],
}

impl Input {
    pub fn new(mesh: Arc<IndexedMesh>) -> Input {
        Input {
            mesh,
            patches: None,
            fields: Default::default(),
        }
    }

    /// A patch file's surfaces.
    pub fn patches(surfaces: Vec<NurbsSurface>) -> Input {
        Input {
            mesh: Arc::new(IndexedMesh::default()),
            patches: Some(Arc::from(surfaces)),
            fields: Default::default(),
        }
    }

    /// The file's signed distance field (built once, then shared).
    pub fn field(&self, sign: SignMode, y_up: bool) -> Result<Arc<MeshField>, String> {
        let k = match sign {
            SignMode::Auto => 0,
            SignMode::Force(SignMethod::Pseudonormal) => 1,
            SignMode::Force(SignMethod::WindingNumber) => 2,
        };
        self.fields[2 * k + usize::from(y_up)]
            .get_or_init(|| {
                let triangles = self.mesh.triangles();
                let mut positions = self.mesh.positions.clone();
                if y_up {
                    // As `import` reads a Y-up file: (x, y, z) → (x, −z, y).
                    for p in &mut positions {
                        *p = [p[0], -p[2] + 0.0, p[1]];
                    }
                }
                MeshField::new(&positions, &triangles, sign)
                    .map(Arc::new)
                    .map_err(|e| e.to_string())
            })
            .clone()
    }
}

/// What meshing a field did, summed over the runs of a step.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FieldStats {
    /// Fields meshed.
    pub meshings: usize,
    /// Meshes appended (an `sdf_part` places one meshing many times).
    pub instances: usize,
    /// Cells per axis of the last grid.
    pub grid: [usize; 3],
    /// Cell edge of the last grid (model units; `sdf_part`: the part's).
    pub cell: f64,
    pub grid_cells: u64,
    /// Cells whose corners were evaluated (the rest were culled).
    pub cells_evaluated: u64,
    pub blocks: u64,
    pub blocks_culled: u64,
    pub field_evaluations: u64,
    /// Triangles appended (every instance).
    pub triangles: u64,
    /// Largest |f| at an output vertex (how far vertices sit off the surface).
    pub max_abs_f: f64,
    pub volume: f64,
    pub area: f64,
    /// Every mesh closed, 2-manifold and consistently oriented.
    pub watertight: bool,
    pub components: usize,
    /// Total genus, when every mesh is closed.
    pub genus: Option<i64>,
    /// The skin's connected skeletons, solids and enclosed cavities.
    pub skin: Option<SkinCounts>,
    /// How the sign of imported or current meshes was decided.
    pub sign: Vec<String>,
    pub field_time: Duration,
    pub mesh_time: Duration,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SkinCounts {
    pub skeletons: usize,
    pub solids: usize,
    pub cavities: usize,
}

impl FieldStats {
    /// Adds another run's statistics.
    pub fn add(&mut self, o: &FieldStats) {
        let first = self.meshings == 0;
        self.meshings += o.meshings;
        self.instances += o.instances;
        self.grid = o.grid;
        self.cell = o.cell;
        self.grid_cells += o.grid_cells;
        self.cells_evaluated += o.cells_evaluated;
        self.blocks += o.blocks;
        self.blocks_culled += o.blocks_culled;
        self.field_evaluations += o.field_evaluations;
        self.triangles += o.triangles;
        self.max_abs_f = self.max_abs_f.max(o.max_abs_f);
        self.volume += o.volume;
        self.area += o.area;
        self.watertight = (first || self.watertight) && o.watertight;
        self.components += o.components;
        self.genus = match (first, self.genus, o.genus) {
            (true, _, g) => g,
            (false, Some(a), Some(b)) => Some(a + b),
            _ => None,
        };
        self.skin = match (self.skin, o.skin) {
            (Some(a), Some(b)) => Some(SkinCounts {
                skeletons: a.skeletons + b.skeletons,
                solids: a.solids + b.solids,
                cavities: a.cavities + b.cavities,
            }),
            (a, b) => a.or(b),
        };
        for s in &o.sign {
            if !self.sign.contains(s) {
                self.sign.push(s.clone());
            }
        }
        self.field_time += o.field_time;
        self.mesh_time += o.mesh_time;
    }

    /// One meshing placed `scales.len()` times, each scaled by its factor.
    fn of(out: &MeshOutput, check: &MeshCheck, scales: &[f64]) -> FieldStats {
        let s = &out.stats;
        let sum = |p: i32| scales.iter().map(|k| libm::pow(*k, p as f64)).sum::<f64>();
        let n = scales.len();
        let largest = scales.iter().fold(0.0f64, |m, &k| m.max(k));
        FieldStats {
            meshings: 1,
            instances: n,
            grid: s.grid,
            cell: s.cell_size[0],
            grid_cells: s.grid_cells,
            cells_evaluated: s.cells_evaluated,
            blocks: s.blocks,
            blocks_culled: s.blocks_culled,
            field_evaluations: s.field_evaluations,
            triangles: s.triangles * n as u64,
            max_abs_f: s.max_abs_f_at_vertices * largest,
            volume: check.volume * sum(3),
            area: check.area * sum(2),
            watertight: check.is_closed_manifold(),
            components: check.components * n,
            genus: check.genus().map(|g| g * n as i64),
            skin: None,
            sign: Vec::new(),
            field_time: out.timings.map_or(Duration::ZERO, |t| t.field),
            mesh_time: out.timings.map_or(Duration::ZERO, |t| t.mesh),
        }
    }
}

/// What a field operator sees of the run.
pub(super) struct FieldContext<'a> {
    pub slots: &'a [f64],
    pub sdf: &'a SdfForest,
    pub inputs: &'a [Input],
    /// `--max-cells`.
    pub max_cells: u64,
    pub mesh_progress: sdf::Progress,
    /// Primitives the model may still grow by.
    pub budget: u64,
    /// Whether the program keeps G³ layers (a re-meshed model needs them).
    pub uses_graph: bool,
}

/// What a field operator did.
pub(super) struct FieldApplied {
    pub made: Selection,
    pub stats: FieldStats,
    pub warnings: Vec<String>,
    /// The whole model was replaced: element ids an earlier step
    /// remembered mean nothing now.
    pub replaced: bool,
}

/// `sdf`: the tree meshed, appended.
pub(super) fn create(
    ctx: &FieldContext,
    mesh: &mut Mesh,
    tree: usize,
    meshing: &MeshingArgs,
) -> Result<FieldApplied, StepError> {
    let (built, mut warnings) = build(ctx, tree)?;
    let (out, check) = mesh_built(ctx, meshing, &built)?;
    let mut stats = FieldStats::of(&out, &check, &[1.0]);
    stats.sign = signs(&built, &mut warnings);
    let made = append(mesh, &out, DMat3::IDENTITY, DVec3::ZERO)?;
    Ok(FieldApplied {
        made,
        stats,
        warnings,
        replaced: false,
    })
}

/// `sdf_part`: the tree meshed once, placed in the frame of every
/// selected primitive (scaled by its size when `relative`).
pub(super) fn place_parts(
    ctx: &FieldContext,
    mesh: &mut Mesh,
    (tree, relative, meshing): (usize, bool, &MeshingArgs),
    domain: Domain,
    selected: &[usize],
) -> Result<FieldApplied, StepError> {
    let placements: Vec<(DMat3, DVec3, f64)> = selected
        .iter()
        .map(|&i| placement(mesh, domain, i, relative))
        .collect();
    let (built, mut warnings) = build(ctx, tree)?;
    if placements.is_empty() {
        return Ok(FieldApplied {
            made: Selection::new(),
            stats: FieldStats::default(),
            warnings,
            replaced: false,
        });
    }
    let (out, check) = mesh_built(ctx, meshing, &built)?;
    let per_copy = primitives_of(&out);
    let coming = per_copy.saturating_mul(placements.len() as u64);
    if coming > ctx.budget {
        return Err(StepError::FieldTooLarge {
            what: format!(
                "{} copies of a {}-triangle part",
                placements.len(),
                out.triangles.len()
            ),
            coming,
            budget: ctx.budget,
        });
    }
    let scales: Vec<f64> = placements.iter().map(|p| p.2).collect();
    let mut stats = FieldStats::of(&out, &check, &scales);
    stats.sign = signs(&built, &mut warnings);
    let mut made = Selection::new();
    for (linear, origin, _) in placements {
        let part = append(mesh, &out, linear, origin)?;
        made.verts.extend(part.verts);
        made.edges.extend(part.edges);
        made.faces.extend(part.faces);
    }
    Ok(FieldApplied {
        made,
        stats,
        warnings,
        replaced: false,
    })
}

/// `sdf_boolean`: the model's distance field combined with the tree, and
/// the result meshed in place of the model.
pub(super) fn boolean(
    ctx: &FieldContext,
    mesh: &mut Mesh,
    (tree, operation, blend, meshing): (usize, BooleanOp, &Scalar, &MeshingArgs),
) -> Result<FieldApplied, StepError> {
    let (mut built, mut warnings) = build(ctx, tree)?;
    let current = mesh.to_indexed();
    let triangles = current.triangles();
    if triangles.is_empty() {
        return Err(StepError::Field {
            what: "the model".into(),
            error: Box::new(SdfError::MeshEmpty { dropped: 0 }),
        });
    }
    let field =
        MeshField::new(&current.positions, &triangles, SignMode::Auto).map_err(|error| {
            StepError::Field {
                what: "the model's distance field".into(),
                error: Box::new(error),
            }
        })?;
    let report = field.report();
    let mut sign = vec![sign_name(report.sign).to_string()];
    if !field.is_continuous() {
        warnings.push(format!(
            "the model is not a closed oriented manifold ({}): its inside is decided by the generalized winding number, and every cell of the grid is evaluated",
            report.reason
        ));
    }
    let model = built.tree.push(Node::Mesh(Arc::new(field)));
    let blend = blend.eval(ctx.slots);
    let tool = built.root;
    let combined = match (operation, blend > 0.0) {
        (BooleanOp::Union, false) => Node::Union(vec![model, tool]),
        (BooleanOp::Union, true) => Node::SmoothUnion {
            children: vec![model, tool],
            k: blend,
        },
        (BooleanOp::Intersection, false) => Node::Intersection(vec![model, tool]),
        (BooleanOp::Intersection, true) => Node::SmoothIntersection {
            children: vec![model, tool],
            k: blend,
        },
        (BooleanOp::Difference, false) => Node::Difference {
            base: model,
            subtract: vec![tool],
        },
        (BooleanOp::Difference, true) => Node::SmoothDifference {
            base: model,
            subtract: vec![tool],
            k: blend,
        },
    };
    built.root = built.tree.push(combined);
    let (out, check) = mesh_built(ctx, meshing, &built)?;
    let mut stats = FieldStats::of(&out, &check, &[1.0]);
    sign.extend(signs(&built, &mut warnings));
    sign.dedup();
    stats.sign = sign;
    *mesh = Mesh::new();
    if ctx.uses_graph {
        graph::ensure_layers(mesh);
    }
    let made = append(mesh, &out, DMat3::IDENTITY, DVec3::ZERO)?;
    Ok(FieldApplied {
        made,
        stats,
        warnings,
        replaced: true,
    })
}

/// `skin` with `method = "field"`: round cones over the wire edges, with
/// isolated nodes as spheres, smoothly united (order-independent) and
/// meshed into one watertight solid per connected skeleton; the wires and
/// their nodes go unless `keep_wires`.
pub(super) fn skin(
    ctx: &FieldContext,
    mesh: &mut Mesh,
    args: &SkinArgs,
) -> Result<FieldApplied, StepError> {
    let options = ops::skin::SkinOptions {
        sides: 3,
        default_radius: args.radius.eval(ctx.slots),
        joints: false,
    };
    let wires: Vec<EdgeId> = mesh.edge_ids().filter(|&e| mesh.is_wire_edge(e)).collect();
    let mut nodes: Vec<VertId> = wires.iter().flat_map(|&w| mesh.edge_verts(w)).collect();
    nodes.extend(
        mesh.vert_ids()
            .filter(|&v| mesh.vert_edges(v).next().is_none()),
    );
    nodes.sort_unstable();
    nodes.dedup();
    let thinnest = args.min_radius.as_ref().map_or(0.0, |e| e.eval(ctx.slots));
    let mut skeleton = Skeleton::default();
    for &v in &nodes {
        skeleton.nodes.push(SkinNode {
            position: mesh.position(v).to_array(),
            radius: ops::skin::node_radius(mesh, v, &options)?.max(thinnest),
        });
    }
    let index = |v: VertId| nodes.binary_search(&v).expect("listed") as u32;
    skeleton.edges = wires
        .iter()
        .map(|&w| {
            let [a, b] = mesh.edge_verts(w);
            [index(a), index(b)]
        })
        .collect();
    if skeleton.nodes.is_empty() {
        return Ok(FieldApplied {
            made: Selection::new(),
            stats: FieldStats::default(),
            warnings: Vec::new(),
            replaced: false,
        });
    }
    let min_radius = skeleton
        .nodes
        .iter()
        .fold(f64::INFINITY, |m, n| m.min(n.radius));
    let blend = args
        .blend
        .as_ref()
        .map_or(0.5 * min_radius, |e| e.eval(ctx.slots));
    let skin_options = SkinOptions {
        blend,
        cell: args.meshing.cell.as_ref().map(|e| e.eval(ctx.slots)),
        mesh: MeshOptions {
            resolution: Resolution::CellsPerAxis(1),
            ..mesh_options(ctx, &args.meshing)?
        },
    };
    let skinned = sdf::skin(&skeleton, &skin_options).map_err(|e| field_error("the skin", e))?;
    let mut stats = FieldStats::of(&skinned.mesh, &skinned.check, &[1.0]);
    stats.skin = Some(SkinCounts {
        skeletons: skinned.skeleton_components,
        solids: skinned.solids,
        cavities: skinned.cavities,
    });
    if !args.keep_wires {
        let wire_selection = Selection::from_parts(Vec::new(), wires, Vec::new());
        delete::delete(mesh, &wire_selection, DeleteMode::All)?;
        nodes.retain(|&v| mesh.contains_vert(v) && mesh.vert_edges(v).next().is_none());
        let loose = Selection::from_parts(nodes, Vec::new(), Vec::new());
        delete::delete(mesh, &loose, DeleteMode::All)?;
    }
    let made = append(mesh, &skinned.mesh, DMat3::IDENTITY, DVec3::ZERO)?;
    Ok(FieldApplied {
        made,
        stats,
        warnings: Vec::new(),
        replaced: false,
    })
}

/// The step's tree, built with the step's parameter values.
fn build(ctx: &FieldContext, root: usize) -> Result<(BuiltTree, Vec<String>), StepError> {
    let mut fields = |resource: usize, sign: SignMode, y_up: bool| {
        ctx.inputs
            .get(resource)
            .ok_or_else(|| "the file was not loaded before the run".to_string())?
            .field(sign, y_up)
    };
    let built = ctx
        .sdf
        .build(root, ctx.slots, &mut fields)
        .map_err(|e| StepError::Tree(ctx.sdf.describe(&e)))?;
    Ok((built, Vec::new()))
}

/// Compiles and meshes a built tree, then checks the result.
fn mesh_built(
    ctx: &FieldContext,
    meshing: &MeshingArgs,
    built: &BuiltTree,
) -> Result<(MeshOutput, MeshCheck), StepError> {
    let tape = Tape::compile(&built.tree, built.root, &tree_limits()).map_err(|e| {
        let located = ctx.sdf.locate(built, &e);
        StepError::Tree(ctx.sdf.describe(&located))
    })?;
    let out = sdf::mesh(&tape, &mesh_options(ctx, meshing)?).map_err(|e| match e {
        SdfError::EmptyBounds { .. } | SdfError::Unbounded { .. } => {
            let located = ctx.sdf.locate(built, &e);
            StepError::Tree(ctx.sdf.describe(&located))
        }
        other => field_error("the tree", other),
    })?;
    let check = sdf::check(&out.positions, &out.triangles);
    Ok((out, check))
}

/// The pillar's meshing error as a step error (limits keep their kind).
fn field_error(what: &str, error: SdfError) -> StepError {
    match error {
        SdfError::TooManyCells {
            cells,
            nx,
            ny,
            nz,
            limit,
        } => StepError::TooManyCells {
            cells: u64::try_from(cells).unwrap_or(u64::MAX),
            grid: [nx, ny, nz],
            limit,
        },
        SdfError::TooManyTriangles { limit } | SdfError::TooManyVertices { limit } => {
            StepError::FieldTooLarge {
                what: format!("meshing {what}"),
                coming: limit.saturating_add(1),
                budget: limit,
            }
        }
        error => StepError::Field {
            what: what.to_string(),
            error: Box::new(error),
        },
    }
}

/// The meshing parameters of a step.
fn mesh_options(ctx: &FieldContext, meshing: &MeshingArgs) -> Result<MeshOptions, StepError> {
    let value = |e: &Option<crate::rules::program::Scalar>| e.as_ref().map(|e| e.eval(ctx.slots));
    let resolution = match (value(&meshing.cell), value(&meshing.cells)) {
        (Some(h), _) if !(h.is_finite() && h > 0.0) => {
            return Err(StepError::Option {
                key: "cell",
                message: format!("must be positive, got {h}"),
            })
        }
        (Some(h), _) => Resolution::CellSize(h),
        (None, Some(n)) => Resolution::CellsPerAxis(count("cells", n)?.max(1)),
        (None, None) => Resolution::CellsPerAxis(DEFAULT_CELLS),
    };
    let domain = match &meshing.domain {
        Some(corners) => {
            let v = |x: &crate::rules::program::Vector| {
                DVec3::new(
                    x.0[0].eval(ctx.slots),
                    x.0[1].eval(ctx.slots),
                    x.0[2].eval(ctx.slots),
                )
            };
            let (lo, hi) = (v(&corners[0]), v(&corners[1]));
            if !(lo.is_finite() && hi.is_finite() && lo.cmplt(hi).all()) {
                return Err(StepError::Option {
                    key: "domain",
                    message: format!(
                        "needs a lowest corner below the highest on every axis, got {lo} .. {hi}"
                    ),
                });
            }
            Some(sdf::Aabb { lo, hi })
        }
        None => None,
    };
    let padding = match value(&meshing.padding) {
        Some(p) => count("padding", p)?,
        None => 1,
    };
    Ok(MeshOptions {
        mesher: match meshing.mesher {
            args::Mesher::DualContouring => Mesher::DualContouring,
            args::Mesher::MarchingCubes => Mesher::MarchingCubes,
        },
        grid: match meshing.grid {
            args::GridKind::Lattice => GridKind::Lattice,
            args::GridKind::Linspace => GridKind::Linspace,
            args::GridKind::LatticeHalf => GridKind::LatticeHalf,
        },
        resolution,
        domain,
        padding,
        vertex: match meshing.vertex {
            args::VertexPlacement::Midpoint => VertexPlacement::Midpoint,
            args::VertexPlacement::Refine => VertexPlacement::Refine {
                steps: REFINE_STEPS,
            },
            args::VertexPlacement::Linear => VertexPlacement::Linear,
        },
        limits: MeshLimits {
            max_cells: ctx.max_cells,
            // A triangle brings one face, one and a half edges and half a vertex.
            max_triangles: ctx.budget / 3,
            max_vertices: ctx.budget,
        },
        threads: 0,
        timings: true,
        progress: ctx.mesh_progress,
    })
}

/// Cells along the longest side when a step gives neither `cell` nor `cells`.
pub const DEFAULT_CELLS: u32 = 64;
/// Root refinement steps of `vertex = "refine"`.
pub const REFINE_STEPS: u32 = 12;

fn count(key: &'static str, x: f64) -> Result<u32, StepError> {
    let r = libm::round(x);
    if !(r.is_finite() && (0.0..=u32::MAX as f64).contains(&r)) {
        return Err(StepError::NotACount {
            what: key,
            value: r,
        });
    }
    Ok(r as u32)
}

/// The sign methods of the tree's mesh nodes; a winding-number one is
/// also a warning (the file is not a closed oriented manifold).
fn signs(built: &BuiltTree, warnings: &mut Vec<String>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for i in 0..built.tree.len() {
        if let Some(Node::Mesh(field)) = built.tree.node(sdf::NodeId(i as u32)) {
            let report = field.report();
            let name = sign_name(report.sign).to_string();
            if !field.is_continuous() {
                let warning = format!(
                    "an imported mesh is not a closed oriented manifold ({}): its inside is decided by the generalized winding number, and every cell of the grid is evaluated",
                    report.reason
                );
                if !warnings.contains(&warning) {
                    warnings.push(warning);
                }
            }
            if !out.contains(&name) {
                out.push(name);
            }
        }
    }
    out
}

fn sign_name(method: SignMethod) -> &'static str {
    match method {
        SignMethod::Pseudonormal => "pseudonormal",
        SignMethod::WindingNumber => "winding_number",
    }
}

/// Primitives a meshed part adds to the kernel (vertices, edges, faces).
fn primitives_of(out: &MeshOutput) -> u64 {
    let t = out.triangles.len() as u64;
    out.positions.len() as u64 + t + t * 3 / 2
}

/// Appends the meshed triangles, mapped by `origin + linear·p`.
fn append(
    mesh: &mut Mesh,
    out: &MeshOutput,
    linear: DMat3,
    origin: DVec3,
) -> Result<Selection, StepError> {
    let mut builder = KernelBuilder::new(mesh);
    let emitted = if linear == DMat3::IDENTITY && origin == DVec3::ZERO {
        out.emit(&mut builder)
    } else {
        out.emit(&mut Placed::new(
            &mut builder as &mut dyn MeshSink,
            linear,
            origin,
        ))
    };
    emitted.map_err(|error| StepError::Import {
        file: "the meshed field".into(),
        error,
    })?;
    Ok(builder.finish().0)
}

/// Where an `sdf_part` goes on primitive `index`: the frame's axes (H, L,
/// U) as columns scaled by the size, the origin, and the size.
pub(super) fn placement(
    mesh: &Mesh,
    domain: Domain,
    index: usize,
    relative: bool,
) -> (DMat3, DVec3, f64) {
    let safe = |x: f64| if x.is_finite() && x > 1e-300 { x } else { 1.0 };
    let (frame, origin, size) = match domain {
        Domain::Face => {
            let f = FaceId::from_index(index);
            (
                graph::face_frame(mesh, f),
                mesh.face_center(f),
                safe(mesh.face_area(f).sqrt()),
            )
        }
        Domain::Edge => {
            let e = EdgeId::from_index(index);
            let [a, b] = mesh.edge_verts(e);
            (
                graph::edge_frame(mesh, e),
                0.5 * (mesh.position(a) + mesh.position(b)),
                safe(mesh.edge_length(e)),
            )
        }
        Domain::Vert => {
            let v = VertId::from_index(index);
            (
                graph::node_frame(mesh, v),
                mesh.position(v),
                safe(graph::radius(mesh, v).abs()),
            )
        }
    };
    let s = if relative { size } else { 1.0 };
    (
        DMat3::from_cols(frame.h * s, frame.l * s, frame.u * s),
        origin,
        s,
    )
}
