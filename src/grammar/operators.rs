//! The engine's implementations of the registry's create, kernel and
//! whole-mesh operators ([`crate::rules::operators`]): for each [`OpId`],
//! what it makes at most (checked against the primitive limit before it
//! allocates anything) and what it does. Dispatch is an exhaustive `match`
//! on the identity, so a registered operator without an implementation
//! does not compile. G³ commands and compounds run in [`super::run`].

use glam::DVec3;

use super::error::StepError;
use super::fields::{self, FieldApplied, FieldContext, FieldStats, Input};
use super::graph;
use super::surfaces;
use crate::kernel::ops::delete::DeleteMode;
use crate::kernel::ops::extrude::ExtrudeOffset;
use crate::kernel::ops::select::Adjacency;
use crate::kernel::ops::{self, Selection};
use crate::kernel::{Domain, EdgeId, FaceId, Mesh, VertId};
use crate::rules::expr::Expr;
use crate::rules::operators::OpId;
use crate::rules::program::{Call, Resource, Vector};
use crate::rules::sdf_tree::SdfForest;

/// What an operator implementation sees besides the mesh.
pub(super) struct Context<'a> {
    /// Parameter values (the slots expressions read).
    pub slots: &'a [f64],
    /// The program's files, read before the run.
    pub resources: &'a [Resource],
    pub inputs: &'a [Input],
    /// The program's signed distance trees.
    pub sdf: &'a SdfForest,
    /// The program's parametric surfaces.
    pub nurbs: &'a [crate::rules::nurbs_def::SurfaceDef],
    /// The element kind the step selected.
    pub domain: Domain,
    /// `--max-cells`.
    pub max_cells: u64,
    pub mesh_progress: crate::sdf::Progress,
    /// Primitives the model may still grow by (for operators that cannot
    /// predict their growth: meshing a field).
    pub budget: u64,
    pub uses_graph: bool,
}

/// What an operator did.
pub(super) struct Applied {
    pub made: Selection,
    /// How many of the selected elements it applied to, when fewer than
    /// all (`dissolve_edges` skips edges it cannot dissolve).
    pub applied: Option<usize>,
    /// What meshing a field did.
    pub field: Option<FieldStats>,
    /// What tessellating a surface or PN smoothing did.
    pub surface: Option<super::surfaces::SurfaceStats>,
    pub warnings: Vec<String>,
    /// The model was replaced as a whole (ids remembered before are void).
    pub replaced: bool,
}

impl From<FieldApplied> for Applied {
    fn from(f: FieldApplied) -> Self {
        Applied {
            made: f.made,
            applied: None,
            field: Some(f.stats),
            surface: None,
            warnings: f.warnings,
            replaced: f.replaced,
        }
    }
}

impl Context<'_> {
    fn scalar(&self, e: &Expr) -> f64 {
        e.eval(self.slots)
    }

    fn vector(&self, v: &Vector) -> DVec3 {
        DVec3::new(
            self.scalar(&v.0[0]),
            self.scalar(&v.0[1]),
            self.scalar(&v.0[2]),
        )
    }

    /// A whole number of at least 0 (rounded).
    fn count(&self, e: &Expr, what: &'static str) -> Result<u32, StepError> {
        let x = libm::round(self.scalar(e));
        if !(x.is_finite() && (0.0..=u32::MAX as f64).contains(&x)) {
            return Err(StepError::NotACount { what, value: x });
        }
        Ok(x as u32)
    }

    /// A count for prediction: saturating, 0 for what `count` refuses.
    fn predicted(&self, e: &Expr) -> u64 {
        let x = libm::round(self.scalar(e));
        if x.is_nan() || x <= 0.0 {
            0
        } else if x >= u64::MAX as f64 {
            u64::MAX
        } else {
            x as u64
        }
    }

    fn offset(&self, call: &Call) -> ExtrudeOffset {
        match (call.vector("offset"), call.scalar("distance")) {
            (Some(v), _) => ExtrudeOffset::Vector(self.vector(v)),
            (None, Some(d)) => ExtrudeOffset::Normal(self.scalar(d)),
            (None, None) => ExtrudeOffset::None,
        }
    }
}

/// The selected elements of the step's kind as a selection.
pub(super) fn selection_of(domain: Domain, indices: &[usize]) -> Selection {
    let mut s = Selection::new();
    match domain {
        Domain::Vert => s.verts = indices.iter().map(|&i| VertId::from_index(i)).collect(),
        Domain::Edge => s.edges = indices.iter().map(|&i| EdgeId::from_index(i)).collect(),
        Domain::Face => s.faces = indices.iter().map(|&i| FaceId::from_index(i)).collect(),
    }
    s
}

/// The selection and what it implies (its vertices, edges, or everything
/// under it), computed on demand.
struct Selected<'a> {
    mesh: &'a Mesh,
    domain: Domain,
    by_domain: Selection,
}

impl Selected<'_> {
    fn verts(&self) -> Vec<VertId> {
        match self.domain {
            Domain::Vert => self.by_domain.verts.clone(),
            Domain::Edge => ops::select::select_from_edges(self.mesh, &self.by_domain.edges).verts,
            Domain::Face => ops::select::select_from_faces(self.mesh, &self.by_domain.faces).verts,
        }
    }

    fn edges(&self) -> Vec<EdgeId> {
        match self.domain {
            Domain::Face => ops::select::select_from_faces(self.mesh, &self.by_domain.faces).edges,
            _ => self.by_domain.edges.clone(),
        }
    }

    fn full(&self) -> Selection {
        match self.domain {
            Domain::Vert => ops::select::select_from_verts(self.mesh, &self.by_domain.verts),
            Domain::Edge => ops::select::select_from_edges(self.mesh, &self.by_domain.edges),
            Domain::Face => ops::select::select_from_faces(self.mesh, &self.by_domain.faces),
        }
    }
}

/// At most how many primitives (vertices + edges + faces) `call` creates
/// on `selected`, from its parameters, so that the primitive limit refuses
/// it before anything is allocated. Saturating: a parameter too large to
/// count predicts `u64::MAX`.
pub(super) fn predicted_growth(ctx: &Context, mesh: &Mesh, call: &Call, selected: &[usize]) -> u64 {
    let sel = Selected {
        mesh,
        domain: ctx.domain,
        by_domain: selection_of(ctx.domain, selected),
    };
    let m = u64::saturating_mul;
    let n = |key: &str| call.scalar(key).map_or(0, |e| ctx.predicted(e));
    let size = |s: &Selection| (s.verts.len() + s.edges.len() + s.faces.len()) as u64;
    let edge_count = || sel.edges().len() as u64;
    let vert_count = || match ctx.domain {
        Domain::Vert => sel.by_domain.verts.len() as u64,
        _ => sel.full().verts.len() as u64,
    };
    // Per face of n sides: n new vertices, 2n edges, n + 1 faces at most
    // (extrude and inset, individually or as a region).
    let rings = || -> u64 {
        sel.by_domain
            .faces
            .iter()
            .map(|&f| 4 * mesh.face_len(f) as u64 + 1)
            .fold(0, u64::saturating_add)
    };
    match call.def.id {
        OpId::Vertex => 1,
        OpId::Circle => m(n("segments"), 2).saturating_add(1),
        OpId::Grid => {
            let p = call.pair("segments").expect("defaulted");
            let (x, y) = (
                ctx.predicted(&p[0]).saturating_add(1),
                ctx.predicted(&p[1]).saturating_add(1),
            );
            m(m(x, y), 4)
        }
        OpId::Cube => 26,
        OpId::NurbsPatch => {
            let n = patch_cells(call.scalar("cells").map_or(8.0, |e| ctx.scalar(e))) as u64 + 1;
            m(sel.by_domain.faces.len() as u64, m(m(n, n), 4))
        }
        OpId::UvSphere => m(m(n("segments"), n("rings").saturating_add(1)), 3).saturating_add(2),
        OpId::Cylinder | OpId::Cone => m(n("segments"), 6).saturating_add(2),
        OpId::Import => call
            .resource("path")
            .and_then(|r| ctx.inputs.get(r))
            .map_or(0, |input| {
                let mesh = &input.mesh;
                (mesh.positions.len() + 2 * mesh.face_indices.len() + mesh.lines.len()) as u64
            }),
        OpId::ExtrudeVerts => m(vert_count(), 2),
        OpId::ExtrudeEdges => m(edge_count(), 6),
        OpId::ExtrudeFaces | OpId::ExtrudeRegion | OpId::InsetFaces | OpId::InsetRegion => rings(),
        OpId::SplitEdges => match call.list("ratios") {
            Some(ratios) => m(m(edge_count(), ratios.len() as u64), 2),
            None => m(
                m(
                    edge_count(),
                    call.scalar("cuts").map_or(1, |e| ctx.predicted(e)),
                ),
                2,
            ),
        },
        // n - 3 diagonals and n - 2 triangles for the one face removed.
        OpId::Triangulate => sel
            .by_domain
            .faces
            .iter()
            .map(|&f| 2 * (mesh.face_len(f) as u64).saturating_sub(3))
            .fold(0, u64::saturating_add),
        OpId::Duplicate | OpId::Mirror => size(&sel.full()),
        OpId::MakeFace => 1,
        // Meshing a field cannot be predicted; the mesher stops at the budget.
        OpId::Sdf
        | OpId::SdfPart
        | OpId::SdfBoolean
        | OpId::Nurbs
        | OpId::NurbsPart
        | OpId::PnSmooth => 0,
        OpId::Skin if is_field_skin(call) => 0,
        OpId::Skin => {
            let s = n("sides");
            let wires = mesh.edge_ids().filter(|&e| mesh.is_wire_edge(e)).count() as u64;
            let tubes = m(wires, m(s, 6).saturating_add(2));
            let spheres = if call.flag("joints") == Some(true) {
                m(
                    mesh.vert_count() as u64,
                    m(m(s, (s / 2).max(2)), 3).saturating_add(2),
                )
            } else {
                0
            };
            tubes.saturating_add(spheres)
        }
        OpId::Translate
        | OpId::Rotate
        | OpId::Scale
        | OpId::Assign
        | OpId::Reverse
        | OpId::RecomputeNormals
        | OpId::Delete
        | OpId::DissolveEdges
        | OpId::Merge
        | OpId::RegionExtend
        | OpId::RegionReduce => 0,
        OpId::CreateEdge
        | OpId::SplitEdge
        | OpId::CreateFace
        | OpId::SplitFace
        | OpId::EditNode => {
            unreachable!("G³ commands are no calls")
        }
    }
}

/// Runs `call` on the `selected` elements of the step's kind.
pub(super) fn apply(
    ctx: &Context,
    mesh: &mut Mesh,
    call: &Call,
    selected: &[usize],
) -> Result<Applied, StepError> {
    use ops::{create, delete, extrude, faces, inset, merge, select, split, transform};
    let field_ctx = || FieldContext {
        slots: ctx.slots,
        sdf: ctx.sdf,
        inputs: ctx.inputs,
        max_cells: ctx.max_cells,
        mesh_progress: ctx.mesh_progress,
        budget: ctx.budget,
        uses_graph: ctx.uses_graph,
    };
    match call.def.id {
        OpId::Sdf => return fields::create(&field_ctx(), mesh, call).map(Applied::from),
        OpId::Nurbs | OpId::NurbsPart | OpId::PnSmooth => {
            let surface_ctx = surfaces::SurfaceContext {
                slots: ctx.slots,
                surfaces: ctx.nurbs,
                budget: ctx.budget,
                uses_graph: ctx.uses_graph,
            };
            let (made, stats) = match call.def.id {
                OpId::Nurbs => surfaces::create(&surface_ctx, mesh, call)?,
                OpId::NurbsPart => {
                    surfaces::place_parts(&surface_ctx, mesh, call, ctx.domain, selected)?
                }
                _ => surfaces::pn_smooth(&surface_ctx, mesh, call)?,
            };
            return Ok(Applied {
                made,
                applied: None,
                field: None,
                surface: Some(stats),
                warnings: Vec::new(),
                replaced: call.def.id == OpId::PnSmooth,
            });
        }
        OpId::SdfPart => {
            return fields::place_parts(&field_ctx(), mesh, call, ctx.domain, selected)
                .map(Applied::from)
        }
        OpId::SdfBoolean => return fields::boolean(&field_ctx(), mesh, call).map(Applied::from),
        OpId::Skin if is_field_skin(call) => {
            return fields::skin(&field_ctx(), mesh, call).map(Applied::from)
        }
        _ => {}
    }
    let sel = Selected {
        mesh,
        domain: ctx.domain,
        by_domain: selection_of(ctx.domain, selected),
    };
    // What the implementation needs of the selection, before it borrows
    // the mesh mutably.
    let (verts, edges, full) = match call.def.id {
        OpId::Translate | OpId::Rotate | OpId::Scale | OpId::ExtrudeVerts | OpId::Merge => {
            (sel.verts(), Vec::new(), Selection::new())
        }
        OpId::ExtrudeEdges | OpId::SplitEdges | OpId::DissolveEdges | OpId::MakeFace => {
            (Vec::new(), sel.edges(), Selection::new())
        }
        OpId::Duplicate | OpId::Mirror => (Vec::new(), Vec::new(), sel.full()),
        OpId::Delete if ctx.domain != Domain::Face => (Vec::new(), Vec::new(), sel.full()),
        _ => (Vec::new(), Vec::new(), Selection::new()),
    };
    let faces_list = sel.by_domain.faces.clone();
    let by_domain = sel.by_domain;
    let moved = |vs: Vec<VertId>| Selection::from_parts(vs, Vec::new(), Vec::new());
    let s = |key: &str| ctx.scalar(call.scalar(key).expect("defaulted"));
    let v = |key: &str| ctx.vector(call.vector(key).expect("defaulted"));
    let count =
        |key: &str, what: &'static str| ctx.count(call.scalar(key).expect("defaulted"), what);
    let mut applied = None;
    let made = match call.def.id {
        OpId::Vertex => {
            let made = create::create_vert(mesh, v("at"))?;
            if let Some(r) = call.scalar("radius") {
                graph::ensure_layers(mesh);
                for &w in &made.verts {
                    graph::set_radius(mesh, w, ctx.scalar(r));
                }
            }
            made
        }
        OpId::Circle => create::create_circle(
            mesh,
            count("segments", "segments")?,
            s("radius"),
            call.flag("fill") == Some(true),
        )?,
        OpId::Grid => {
            let p = call.pair("segments").expect("defaulted");
            let size = call.pair("size").expect("defaulted");
            create::create_grid(
                mesh,
                ctx.count(&p[0], "segments")?,
                ctx.count(&p[1], "segments")?,
                ctx.scalar(&size[0]),
                ctx.scalar(&size[1]),
            )?
        }
        OpId::Cube => create::create_cube(mesh, s("size"))?,
        OpId::UvSphere => create::create_uv_sphere(
            mesh,
            count("segments", "segments")?,
            count("rings", "rings")?,
            s("radius"),
        )?,
        OpId::Cylinder => create::create_cylinder(
            mesh,
            count("segments", "segments")?,
            s("radius"),
            s("radius_top"),
            s("depth"),
            call.flag("caps") == Some(true),
        )?,
        OpId::Cone => create::create_cylinder(
            mesh,
            count("segments", "segments")?,
            s("radius"),
            0.0,
            s("depth"),
            call.flag("caps") == Some(true),
        )?,
        OpId::Import => {
            let resource = call.resource("path").expect("required");
            let source = &ctx.resources[resource];
            let loaded = &ctx
                .inputs
                .get(resource)
                .ok_or_else(|| StepError::NotLoaded(source.written.clone()))?
                .mesh;
            let mut indexed = match call.scalar("weld") {
                Some(d) => std::borrow::Cow::Owned(loaded.welded(ctx.scalar(d))),
                None => std::borrow::Cow::Borrowed(&**loaded),
            };
            if call.choice("up") == Some("y") {
                indexed.to_mut().y_up_to_z_up();
            }
            // Built straight into the working mesh: no copy.
            crate::kernel::build::append_indexed(mesh, &indexed).map_err(|error| {
                StepError::Import {
                    file: source.written.clone(),
                    error,
                }
            })?
        }
        OpId::Translate => {
            transform::translate(mesh, &verts, v("offset"))?;
            moved(verts)
        }
        OpId::Rotate => {
            let angle = s("angle").to_radians();
            transform::rotate(mesh, &verts, v("center"), v("axis"), angle)?;
            moved(verts)
        }
        OpId::Scale => {
            transform::scale(mesh, &verts, v("center"), v("factor"))?;
            moved(verts)
        }
        OpId::ExtrudeVerts => extrude::extrude_verts(mesh, &verts, ctx.offset(call))?,
        OpId::ExtrudeEdges => extrude::extrude_edges(mesh, &edges, ctx.offset(call))?,
        OpId::ExtrudeFaces => extrude::extrude_faces(
            mesh,
            &faces_list,
            call.flag("keep_original") == Some(true),
            ctx.offset(call),
        )?,
        OpId::ExtrudeRegion => extrude::extrude_face_region(
            mesh,
            &faces_list,
            call.flag("keep_original") == Some(true),
            ctx.offset(call),
        )?,
        OpId::InsetFaces => inset::inset_faces(mesh, &faces_list, s("thickness"), s("depth"))?,
        OpId::NurbsPatch => {
            let n = patch_cells(s("cells"));
            let lift = s("lift");
            let mut place = |corners: [DVec3; 4], normal: DVec3, size: f64| {
                surfaces::quad_patch_grid(corners, normal * (lift * size), n)
            };
            let (made, filled) = ops::grid_fill::grid_fill(mesh, &faces_list, n, &mut place)?;
            applied = Some(filled);
            made
        }
        OpId::InsetRegion => inset::inset_region(mesh, &faces_list, s("thickness"), s("depth"))?,
        OpId::SplitEdges => match call.list("ratios") {
            Some(ratios) => {
                let r: Vec<f64> = ratios.iter().map(|x| ctx.scalar(x)).collect();
                split::split_edges_at(mesh, &edges, &r)?
            }
            None => {
                let cuts = match call.scalar("cuts") {
                    Some(c) => ctx.count(c, "cuts")?,
                    None => 1,
                };
                split::split_edges(mesh, &edges, cuts)?
            }
        },
        OpId::Triangulate => faces::triangulate(mesh, &faces_list)?,
        // The step tags what it returns (`grammar::asset::tag`).
        OpId::Assign => Selection::from_parts(Vec::new(), edges.clone(), faces_list.clone()),
        OpId::Reverse => {
            faces::reverse_faces(mesh, &faces_list)?;
            Selection::from_parts(Vec::new(), Vec::new(), faces_list)
        }
        OpId::RecomputeNormals => {
            faces::recompute_normals(mesh, &faces_list, call.flag("outside") == Some(true))?;
            Selection::from_parts(Vec::new(), Vec::new(), faces_list)
        }
        OpId::Delete => {
            let mode = match call.choice("mode") {
                Some("faces") => DeleteMode::Faces,
                Some("faces_and_edges") => DeleteMode::FacesAndEdges,
                _ => DeleteMode::All,
            };
            let s = if ctx.domain == Domain::Face {
                by_domain
            } else {
                full
            };
            delete::delete(mesh, &s, mode)?
        }
        OpId::Duplicate => delete::duplicate(mesh, &full)?,
        OpId::DissolveEdges => {
            let report = delete::dissolve_edges_report(mesh, &edges)?;
            applied = Some(report.dissolved);
            Selection::from_parts(Vec::new(), Vec::new(), report.faces)
        }
        OpId::MakeFace => faces::make_face_from_edges(mesh, &edges)?,
        OpId::Merge => {
            let r = merge::merge_by_distance(mesh, &verts, s("distance"))?;
            moved(r.survivors)
        }
        OpId::Mirror => {
            let normal = match call.choice("axis") {
                Some("x") => DVec3::X,
                Some("y") => DVec3::Y,
                Some("z") => DVec3::Z,
                _ => v("normal"),
            };
            merge::mirror(mesh, &full, v("point"), normal, s("merge_distance"))?
        }
        OpId::RegionExtend | OpId::RegionReduce => {
            let by = match call.choice("by") {
                Some("vert") => Adjacency::Vert,
                _ => Adjacency::Edge,
            };
            let faces = if call.def.id == OpId::RegionExtend {
                select::region_extend(mesh, &faces_list, by)
            } else {
                select::region_reduce(mesh, &faces_list, by)
            };
            Selection::from_parts(Vec::new(), Vec::new(), faces)
        }
        OpId::Skin => {
            let options = ops::skin::SkinOptions {
                sides: count("sides", "sides")?,
                default_radius: s("radius"),
                joints: call.flag("joints") == Some(true),
            };
            let tubes = ops::skin::skin_wire_edges(mesh, &options)?;
            if call.flag("keep_wires") != Some(true) {
                let wires: Vec<EdgeId> =
                    mesh.edge_ids().filter(|&w| mesh.is_wire_edge(w)).collect();
                let mut nodes: Vec<VertId> =
                    wires.iter().flat_map(|&w| mesh.edge_verts(w)).collect();
                let wire_selection = Selection::from_parts(Vec::new(), wires, Vec::new());
                delete::delete(mesh, &wire_selection, DeleteMode::All)?;
                // The skeleton's nodes go with its wires, unless a face still uses them.
                nodes.sort_unstable();
                nodes.dedup();
                nodes.retain(|&v| mesh.vert_edges(v).next().is_none());
                let loose = Selection::from_parts(nodes, Vec::new(), Vec::new());
                delete::delete(mesh, &loose, DeleteMode::All)?;
            }
            let map = mesh.join_mesh(&tubes);
            Selection::from_parts(
                map.verts.into_iter().flatten().collect(),
                map.edges.into_iter().flatten().collect(),
                map.faces.into_iter().flatten().collect(),
            )
        }
        OpId::Sdf
        | OpId::SdfPart
        | OpId::SdfBoolean
        | OpId::Nurbs
        | OpId::NurbsPart
        | OpId::PnSmooth => unreachable!("applied above"),
        OpId::CreateEdge
        | OpId::SplitEdge
        | OpId::CreateFace
        | OpId::SplitFace
        | OpId::EditNode => {
            unreachable!("G³ commands are no calls")
        }
    };
    Ok(Applied {
        made,
        applied,
        field: None,
        surface: None,
        warnings: Vec::new(),
        replaced: false,
    })
}

/// Whether a `skin` step meshes a field (`method = "field"`).
fn is_field_skin(call: &Call) -> bool {
    call.choice("method") == Some("field")
}

/// `nurbs_patch`'s cells per side, from the parameter (bounded by the
/// registry; rounded, at least 1).
fn patch_cells(x: f64) -> usize {
    if x.is_finite() {
        libm::round(x).clamp(1.0, 256.0) as usize
    } else {
        1
    }
}
