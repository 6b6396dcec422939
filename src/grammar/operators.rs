//! The engine's implementations of the registry's create, kernel and
//! whole-mesh operators ([`crate::rules::operators`]): for each [`OpId`],
//! what it makes at most (checked against the primitive limit before it
//! allocates anything) and what it does. Dispatch is an exhaustive `match`
//! on the typed arguments ([`OpArgs`]), so a registered operator without
//! an implementation does not compile, and no argument is looked up by
//! name. G³ commands and compounds run in [`super::run`].

use glam::DVec3;

use super::error::StepError;
use super::fields::{self, FieldApplied, FieldContext, FieldStats, Input};
use super::graph;
use super::surfaces;
use crate::kernel::ops::delete::DeleteMode;
use crate::kernel::ops::extrude::ExtrudeOffset;
use crate::kernel::ops::{self, Selection};
use crate::kernel::{AttrValue, Domain, EdgeId, FaceId, Mesh, VertId};
use crate::rules::expr::Expr;
use crate::rules::op_args::{
    Adjacency, Axis, BevelOffset, BooleanOp, DeleteKind, ExtrudeArgs, OpArgs, SkinMethod,
    SubdivisionBoundary, SubdivisionScheme, UpAxis,
};
use crate::rules::operators::Reads;
use crate::rules::program::{Call, Resource, Vector, PART_LAYER};
use crate::rules::sdf_tree::SdfForest;
use rustc_hash::FxHashMap;

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

    fn offset(&self, args: &ExtrudeArgs) -> ExtrudeOffset {
        match (&args.offset, &args.distance) {
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
    let n = |e: &Expr| ctx.predicted(e);
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
    match &call.args {
        OpArgs::Vertex { .. } => 1,
        OpArgs::Circle { segments, .. } => m(n(segments), 2).saturating_add(1),
        OpArgs::Grid { segments, .. } => {
            let (x, y) = (
                n(&segments[0]).saturating_add(1),
                n(&segments[1]).saturating_add(1),
            );
            m(m(x, y), 4)
        }
        OpArgs::Cube { .. } => 26,
        OpArgs::NurbsPatch { cells, .. } => {
            let n = patch_cells(ctx.scalar(cells)) as u64 + 1;
            m(sel.by_domain.faces.len() as u64, m(m(n, n), 4))
        }
        OpArgs::UvSphere {
            segments, rings, ..
        } => m(m(n(segments), n(rings).saturating_add(1)), 3).saturating_add(2),
        OpArgs::Cylinder { segments, .. } | OpArgs::Cone { segments, .. } => {
            m(n(segments), 6).saturating_add(2)
        }
        OpArgs::Import { path, .. } => ctx.inputs.get(*path).map_or(0, |input| {
            let mesh = &input.mesh;
            (mesh.positions.len() + 2 * mesh.face_indices.len() + mesh.lines.len()) as u64
        }),
        OpArgs::ExtrudeVerts(_) => m(vert_count(), 2),
        OpArgs::ExtrudeEdges(_) => m(edge_count(), 6),
        OpArgs::ExtrudeFaces(_)
        | OpArgs::ExtrudeRegion(_)
        | OpArgs::InsetFaces(_)
        | OpArgs::InsetRegion(_) => rings(),
        OpArgs::SplitEdges { cuts, ratios } => match ratios {
            Some(ratios) => m(m(edge_count(), ratios.len() as u64), 2),
            None => m(m(edge_count(), cuts.as_ref().map_or(1, n)), 2),
        },
        OpArgs::Subdivide { scheme, levels, .. } => {
            use ops::subdivide::{predict, Scheme, Subdivision};
            let options = Subdivision {
                scheme: match scheme {
                    SubdivisionScheme::Loop => Scheme::Loop,
                    _ => Scheme::CatmullClark,
                },
                levels: n(levels).min(u64::from(u32::MAX)) as u32,
                boundary: ops::subdivide::Boundary::KeepCorners,
                crease_angle: None,
            };
            let [v, e, f] = predict(mesh, &sel.by_domain.faces, options);
            u64::try_from(v.saturating_add(e).saturating_add(f)).unwrap_or(u64::MAX)
        }
        // A copy of every corner's vertex, edge and face at most, and a rim
        // quad (two edges) per boundary edge.
        // A hull of n points: n vertices, 3n − 6 edges, 2n − 4 faces at most.
        OpArgs::ConvexHull { .. } => m(vert_count(), 6),
        // Pieces of cut faces: a few triangles per crossing; bounded by
        // eight per face of the whole mesh for the estimate.
        OpArgs::Boolean { .. } => m(mesh.face_count() as u64, 8),
        // A copy of each profile vertex per step, a quad (and two edges)
        // per profile edge and step.
        OpArgs::Spin { steps, .. } => m(
            n(steps),
            m(vert_count(), 2).saturating_add(m(edge_count(), 3)),
        ),
        // Per selected edge and segment: a face, two edges and a vertex at
        // most (a shorter loop's vertices pair with the longer one's, never
        // more than all the selected edges' vertices).
        OpArgs::BridgeLoops { segments, .. } => m(n(segments), m(edge_count(), 4)),
        // Per beveled edge (or edge at a beveled vertex): its two
        // profiles' points, a band of `segments` faces and at each end a
        // share of the corner grid, ⌈segments / 2⌉² faces per side; as
        // many edges again (a cube's 12 edges at 1 segment: 98 new
        // elements, 168 allowed).
        OpArgs::Bevel { segments, .. } => {
            let s = n(segments);
            let half = s.saturating_add(1) / 2;
            let per_edge = m(
                m(s.saturating_add(1), 2)
                    .saturating_add(s)
                    .saturating_add(m(m(half, half), 2)),
                2,
            );
            let edges = match ctx.domain {
                Domain::Vert => sel
                    .by_domain
                    .verts
                    .iter()
                    .map(|&v| mesh.vert_degree(v) as u64)
                    .fold(0, u64::saturating_add),
                _ => edge_count(),
            };
            m(edges, per_edge)
        }
        OpArgs::Solidify { .. } => m(
            sel.by_domain
                .faces
                .iter()
                .map(|&f| mesh.face_len(f) as u64)
                .fold(0, u64::saturating_add),
            5,
        ),
        // n - 3 diagonals and n - 2 triangles for the one face removed.
        OpArgs::Triangulate => sel
            .by_domain
            .faces
            .iter()
            .map(|&f| 2 * (mesh.face_len(f) as u64).saturating_sub(3))
            .fold(0, u64::saturating_add),
        OpArgs::Duplicate | OpArgs::Mirror { .. } => size(&sel.full()),
        OpArgs::MakeFace => 1,
        // Meshing a field cannot be predicted; the mesher stops at the budget.
        OpArgs::Sdf { .. }
        | OpArgs::SdfPart { .. }
        | OpArgs::SdfBoolean { .. }
        | OpArgs::Nurbs(_)
        | OpArgs::NurbsPart { .. }
        | OpArgs::PnSmooth { .. } => 0,
        OpArgs::Skin(skin) if skin.method == SkinMethod::Field => 0,
        OpArgs::Skin(skin) => {
            let s = n(&skin.sides);
            let wires = mesh.edge_ids().filter(|&e| mesh.is_wire_edge(e)).count() as u64;
            let tubes = m(wires, m(s, 6).saturating_add(2));
            let spheres = if skin.joints {
                m(
                    mesh.vert_count() as u64,
                    m(m(s, (s / 2).max(2)), 3).saturating_add(2),
                )
            } else {
                0
            };
            tubes.saturating_add(spheres)
        }
        OpArgs::Translate { .. }
        | OpArgs::Rotate { .. }
        | OpArgs::Scale { .. }
        | OpArgs::Assign
        | OpArgs::Reverse
        | OpArgs::RecomputeNormals { .. }
        | OpArgs::Crease { .. }
        | OpArgs::Delete { .. }
        | OpArgs::DissolveEdges
        | OpArgs::Merge { .. }
        | OpArgs::RegionExtend { .. }
        | OpArgs::RegionReduce { .. } => 0,
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
    let surface_ctx = || surfaces::SurfaceContext {
        slots: ctx.slots,
        surfaces: ctx.nurbs,
        inputs: ctx.inputs,
        budget: ctx.budget,
        uses_graph: ctx.uses_graph,
    };
    let surfaced = |(made, stats): (Selection, surfaces::SurfaceStats), replaced: bool| Applied {
        made,
        applied: None,
        field: None,
        surface: Some(stats),
        warnings: Vec::new(),
        replaced,
    };
    match &call.args {
        OpArgs::Sdf { tree, meshing } => {
            return fields::create(&field_ctx(), mesh, *tree, meshing).map(Applied::from)
        }
        OpArgs::SdfPart {
            tree,
            relative,
            meshing,
        } => {
            return fields::place_parts(
                &field_ctx(),
                mesh,
                (*tree, *relative, meshing),
                ctx.domain,
                selected,
            )
            .map(Applied::from)
        }
        OpArgs::SdfBoolean {
            tree,
            operation,
            blend,
            meshing,
        } => {
            return fields::boolean(&field_ctx(), mesh, (*tree, *operation, blend, meshing))
                .map(Applied::from)
        }
        OpArgs::Skin(skin) if skin.method == SkinMethod::Field => {
            return fields::skin(&field_ctx(), mesh, skin).map(Applied::from)
        }
        OpArgs::Nurbs(args) => {
            return Ok(surfaced(
                surfaces::create(&surface_ctx(), mesh, args)?,
                false,
            ))
        }
        OpArgs::NurbsPart {
            tessellate,
            relative,
        } => {
            let placed = surfaces::place_parts(
                &surface_ctx(),
                mesh,
                (tessellate, *relative),
                ctx.domain,
                selected,
            )?;
            return Ok(surfaced(placed, false));
        }
        OpArgs::PnSmooth {
            level,
            pattern,
            crease,
        } => {
            let smoothed = surfaces::pn_smooth(&surface_ctx(), mesh, (level, *pattern, crease))?;
            return Ok(surfaced(smoothed, true));
        }
        _ => {}
    }
    let sel = Selected {
        mesh,
        domain: ctx.domain,
        by_domain: selection_of(ctx.domain, selected),
    };
    // What the implementation reads of the selection (its registry row
    // says), before it borrows the mesh mutably.
    let (verts, edges, full) = match call.def.reads {
        Reads::Verts => (sel.verts(), Vec::new(), Selection::new()),
        Reads::Edges => (Vec::new(), sel.edges(), Selection::new()),
        Reads::Everything => (Vec::new(), Vec::new(), sel.full()),
        Reads::EverythingUnlessFaces if ctx.domain != Domain::Face => {
            (Vec::new(), Vec::new(), sel.full())
        }
        Reads::EverythingUnlessFaces | Reads::Selection | Reads::Nothing => {
            (Vec::new(), Vec::new(), Selection::new())
        }
    };
    let faces_list = sel.by_domain.faces.clone();
    let by_domain = sel.by_domain;
    let moved = |vs: Vec<VertId>| Selection::from_parts(vs, Vec::new(), Vec::new());
    let s = |e: &Expr| ctx.scalar(e);
    let v = |x: &Vector| ctx.vector(x);
    let mut applied = None;
    let made = match &call.args {
        OpArgs::Vertex { at, radius } => {
            let made = create::create_vert(mesh, v(at))?;
            if let Some(r) = radius {
                graph::ensure_layers(mesh);
                for &w in &made.verts {
                    graph::set_radius(mesh, w, ctx.scalar(r));
                }
            }
            made
        }
        OpArgs::Circle {
            segments,
            radius,
            fill,
        } => create::create_circle(mesh, ctx.count(segments, "segments")?, s(radius), *fill)?,
        OpArgs::Grid { segments, size } => create::create_grid(
            mesh,
            ctx.count(&segments[0], "segments")?,
            ctx.count(&segments[1], "segments")?,
            s(&size[0]),
            s(&size[1]),
        )?,
        OpArgs::Cube { size } => create::create_cube(mesh, s(size))?,
        OpArgs::UvSphere {
            segments,
            rings,
            radius,
        } => create::create_uv_sphere(
            mesh,
            ctx.count(segments, "segments")?,
            ctx.count(rings, "rings")?,
            s(radius),
        )?,
        OpArgs::Cylinder {
            segments,
            radius,
            radius_top,
            depth,
            caps,
        } => create::create_cylinder(
            mesh,
            ctx.count(segments, "segments")?,
            s(radius),
            s(radius_top),
            s(depth),
            *caps,
        )?,
        OpArgs::Cone {
            segments,
            radius,
            depth,
            caps,
        } => create::create_cylinder(
            mesh,
            ctx.count(segments, "segments")?,
            s(radius),
            0.0,
            s(depth),
            *caps,
        )?,
        OpArgs::Import { path, weld, up } => {
            let source = &ctx.resources[*path];
            let loaded = &ctx
                .inputs
                .get(*path)
                .ok_or_else(|| StepError::NotLoaded(source.written.clone()))?
                .mesh;
            let built = match (weld, up) {
                // Welded as it is built, on two cores: no welded copy.
                (Some(d), UpAxis::Z) => {
                    crate::kernel::build::append_welded(mesh, loaded, ctx.scalar(d))
                }
                _ => {
                    let mut indexed = match weld {
                        Some(d) => std::borrow::Cow::Owned(loaded.welded(ctx.scalar(d))),
                        None => std::borrow::Cow::Borrowed(&**loaded),
                    };
                    if *up == UpAxis::Y {
                        indexed.to_mut().y_up_to_z_up();
                    }
                    // Built straight into the working mesh: no copy.
                    crate::kernel::build::append_indexed(mesh, &indexed)
                }
            };
            built.map_err(|error| StepError::Import {
                file: source.written.clone(),
                error,
            })?
        }
        OpArgs::Translate { offset } => {
            transform::translate(mesh, &verts, v(offset))?;
            moved(verts)
        }
        OpArgs::Rotate {
            angle,
            axis,
            center,
        } => {
            let angle = s(angle).to_radians();
            transform::rotate(mesh, &verts, v(center), v(axis), angle)?;
            moved(verts)
        }
        OpArgs::Scale { factor, center } => {
            transform::scale(mesh, &verts, v(center), v(factor))?;
            moved(verts)
        }
        OpArgs::ExtrudeVerts(e) => extrude::extrude_verts(mesh, &verts, ctx.offset(e))?,
        OpArgs::ExtrudeEdges(e) => extrude::extrude_edges(mesh, &edges, ctx.offset(e))?,
        OpArgs::ExtrudeFaces(e) => {
            extrude::extrude_faces(mesh, &faces_list, e.keep_original, ctx.offset(e))?
        }
        OpArgs::ExtrudeRegion(e) => {
            extrude::extrude_face_region(mesh, &faces_list, e.keep_original, ctx.offset(e))?
        }
        OpArgs::InsetFaces(i) => {
            inset::inset_faces(mesh, &faces_list, s(&i.thickness), s(&i.depth))?
        }
        OpArgs::InsetRegion(i) => {
            inset::inset_region(mesh, &faces_list, s(&i.thickness), s(&i.depth))?
        }
        OpArgs::NurbsPatch { lift, cells } => {
            let n = patch_cells(s(cells));
            let lift = s(lift);
            let mut place = |corners: [DVec3; 4], normal: DVec3, size: f64| {
                surfaces::quad_patch_grid(corners, normal * (lift * size), n)
            };
            let (made, filled) = ops::grid_fill::grid_fill(mesh, &faces_list, n, &mut place)?;
            applied = Some(filled);
            made
        }
        OpArgs::SplitEdges { cuts, ratios } => match ratios {
            Some(ratios) => {
                let r: Vec<f64> = ratios.iter().map(s).collect();
                split::split_edges_at(mesh, &edges, &r)?
            }
            None => {
                let cuts = match cuts {
                    Some(c) => ctx.count(c, "cuts")?,
                    None => 1,
                };
                split::split_edges(mesh, &edges, cuts)?
            }
        },
        OpArgs::Triangulate => faces::triangulate(mesh, &faces_list)?,
        OpArgs::Subdivide {
            scheme,
            levels,
            boundary,
            crease_angle,
        } => {
            use ops::subdivide::{self, Boundary, Scheme, Subdivision};
            let options = Subdivision {
                scheme: match scheme {
                    SubdivisionScheme::CatmullClark => Scheme::CatmullClark,
                    SubdivisionScheme::Simple => Scheme::Simple,
                    SubdivisionScheme::Loop => Scheme::Loop,
                },
                levels: ctx.count(levels, "levels")?,
                boundary: match boundary {
                    SubdivisionBoundary::KeepCorners => Boundary::KeepCorners,
                    SubdivisionBoundary::Smooth => Boundary::Smooth,
                },
                crease_angle: crease_angle.as_ref().map(s),
            };
            let creases = stored_creases(mesh, &faces_list);
            let done = subdivide::subdivide(mesh, &faces_list, options, &creases)?;
            // What is left of each crease stays on its children (a later
            // `subdivide` reads it); the copies `split_edge` made of the
            // parents' values are replaced.
            if !creases.is_empty() {
                let left: FxHashMap<EdgeId, f64> = done.creases.iter().copied().collect();
                for &f in &done.made.faces {
                    for e in mesh.face_edges(f).collect::<Vec<_>>() {
                        let value = AttrValue::Scalar(left.get(&e).copied().unwrap_or(0.0));
                        let _ = mesh.set_attr(CREASE_LAYER, Domain::Edge, e.index(), value);
                    }
                }
            }
            done.made
        }
        OpArgs::Solidify {
            thickness,
            offset,
            even,
            rim,
        } => {
            let options = ops::solidify::Solidify {
                thickness: s(thickness),
                offset: s(offset),
                even: *even,
                rim: *rim,
            };
            ops::solidify::solidify(mesh, &faces_list, options)?
        }
        OpArgs::Bevel {
            width,
            offset_type,
            segments,
            profile,
            clamp_overlap,
        } => {
            use ops::bevel::{Affect, Bevel, OffsetType};
            let options = Bevel {
                width: s(width),
                offset_type: match offset_type {
                    BevelOffset::Offset => OffsetType::Offset,
                    BevelOffset::Width => OffsetType::Width,
                    BevelOffset::Depth => OffsetType::Depth,
                    BevelOffset::Percent => OffsetType::Percent,
                },
                segments: ctx.count(segments, "segments")?,
                profile: s(profile),
                clamp_overlap: *clamp_overlap,
                affect: if ctx.domain == Domain::Vert {
                    Affect::Vertices
                } else {
                    Affect::Edges
                },
            };
            ops::bevel::bevel(mesh, &by_domain.edges, &by_domain.verts, options)?
        }
        OpArgs::ConvexHull { triangulate } => ops::hull::convex_hull(mesh, &verts, *triangulate)?,
        OpArgs::Boolean { operation, with } => {
            use ops::boolean::BooleanOperation as Operation;
            let part_of = super::asset::int_layer(mesh, PART_LAYER, Domain::Face, 0);
            let others: Vec<FaceId> = mesh
                .face_ids()
                .filter(|f| part_of(f.index()) == *with as i32)
                .collect();
            let own: Vec<FaceId> = faces_list
                .iter()
                .copied()
                .filter(|f| part_of(f.index()) != *with as i32)
                .collect();
            drop(part_of);
            if *with == 0 && own.is_empty() {
                // A part named as the rule file is the default part: everything no step put in
                // a part is in it, the other operand too.
                return Err(ops::OpError::Degenerate(
                    "boolean: the `with` part is the default part (it has the rule file's name and holds every face no step put in a part), so the selection has no faces outside it: give the other operand's part another name".to_owned(),
                )
                .into());
            }
            if others.is_empty() || own.is_empty() {
                return Err(ops::OpError::Degenerate(format!(
                    "boolean: {} has no faces (the selection holds {} faces outside the `with` part)",
                    if others.is_empty() { "the `with` part" } else { "the selection outside the `with` part" },
                    own.len()
                ))
                .into());
            }
            let operation = match operation {
                BooleanOp::Difference => Operation::Difference,
                BooleanOp::Union => Operation::Union,
                BooleanOp::Intersection => Operation::Intersection,
            };
            ops::boolean::boolean(mesh, &own, &others, operation)?
        }
        OpArgs::Spin {
            angle,
            steps,
            axis,
            center,
        } => {
            let options = ops::spin::Spin {
                angle_degrees: s(angle),
                steps: ctx.count(steps, "steps")?,
                axis: v(axis),
                center: v(center),
            };
            ops::spin::spin(mesh, &by_domain.edges, &by_domain.verts, options)?
        }
        OpArgs::BridgeLoops { twist, segments } => {
            let twist = s(twist);
            if !(twist.is_finite() && twist.fract() == 0.0 && twist.abs() <= 1e15) {
                return Err(ops::OpError::parameter(
                    "twist",
                    format!("must be a whole number of places, got {twist}"),
                )
                .into());
            }
            let options = ops::bridge::Bridge {
                twist: twist as i64,
                segments: ctx.count(segments, "segments")?,
            };
            ops::bridge::bridge_loops(mesh, &by_domain.edges, options)?
        }
        OpArgs::Crease { sharpness } => {
            let value = AttrValue::Scalar(s(sharpness));
            let _ = mesh.add_layer(CREASE_LAYER, Domain::Edge, AttrValue::Scalar(0.0));
            for &e in &edges {
                let _ = mesh.set_attr(CREASE_LAYER, Domain::Edge, e.index(), value);
            }
            Selection::from_parts(Vec::new(), edges, Vec::new())
        }
        // The step tags what it returns (`grammar::asset::tag`): the
        // selected faces, or edges.
        OpArgs::Assign => by_domain,
        OpArgs::Reverse => {
            faces::reverse_faces(mesh, &faces_list)?;
            Selection::from_parts(Vec::new(), Vec::new(), faces_list)
        }
        OpArgs::RecomputeNormals { outside } => {
            faces::recompute_normals(mesh, &faces_list, *outside)?;
            Selection::from_parts(Vec::new(), Vec::new(), faces_list)
        }
        OpArgs::Delete { mode } => {
            let mode = match mode {
                DeleteKind::Faces => DeleteMode::Faces,
                DeleteKind::FacesAndEdges => DeleteMode::FacesAndEdges,
                DeleteKind::All => DeleteMode::All,
            };
            let s = if ctx.domain == Domain::Face {
                by_domain
            } else {
                full
            };
            delete::delete(mesh, &s, mode)?
        }
        OpArgs::Duplicate => delete::duplicate(mesh, &full)?,
        OpArgs::DissolveEdges => {
            let report = delete::dissolve_edges_report(mesh, &edges)?;
            applied = Some(report.dissolved);
            Selection::from_parts(Vec::new(), Vec::new(), report.faces)
        }
        OpArgs::MakeFace => faces::make_face_from_edges(mesh, &edges)?,
        OpArgs::Merge { distance } => {
            let r = merge::merge_by_distance(mesh, &verts, s(distance))?;
            moved(r.survivors)
        }
        OpArgs::Mirror {
            axis,
            normal,
            point,
            merge_distance,
        } => {
            let normal = match axis {
                Some(Axis::X) => DVec3::X,
                Some(Axis::Y) => DVec3::Y,
                Some(Axis::Z) => DVec3::Z,
                None => v(normal),
            };
            merge::mirror(mesh, &full, v(point), normal, s(merge_distance))?
        }
        OpArgs::RegionExtend { by } | OpArgs::RegionReduce { by } => {
            let by = match by {
                Adjacency::Vert => select::Adjacency::Vert,
                Adjacency::Edge => select::Adjacency::Edge,
            };
            let faces = if matches!(call.args, OpArgs::RegionExtend { .. }) {
                select::region_extend(mesh, &faces_list, by)
            } else {
                select::region_reduce(mesh, &faces_list, by)
            };
            Selection::from_parts(Vec::new(), Vec::new(), faces)
        }
        OpArgs::Skin(skin) => {
            let options = ops::skin::SkinOptions {
                sides: ctx.count(&skin.sides, "sides")?,
                default_radius: s(&skin.radius),
                joints: skin.joints,
            };
            let tubes = ops::skin::skin_wire_edges(mesh, &options)?;
            if !skin.keep_wires {
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
        OpArgs::Sdf { .. }
        | OpArgs::SdfPart { .. }
        | OpArgs::SdfBoolean { .. }
        | OpArgs::Nurbs(_)
        | OpArgs::NurbsPart { .. }
        | OpArgs::PnSmooth { .. } => unreachable!("applied above"),
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

/// `nurbs_patch`'s cells per side, from the parameter (bounded by the
/// registry; rounded, at least 1).
fn patch_cells(x: f64) -> usize {
    if x.is_finite() {
        libm::round(x).clamp(1.0, 256.0) as usize
    } else {
        1
    }
}

/// The edge layer `crease` steps write and `subdivide` reads: OpenSubdiv
/// sharpness (levels an edge stays sharp).
pub const CREASE_LAYER: &str = "crease";

/// The creased edges of `faces`, from the crease layer (none without it).
fn stored_creases(mesh: &Mesh, faces: &[FaceId]) -> Vec<(EdgeId, f64)> {
    if mesh
        .attributes()
        .layer(CREASE_LAYER, Domain::Edge)
        .is_none()
    {
        return Vec::new();
    }
    let mut out: Vec<(EdgeId, f64)> = faces
        .iter()
        .flat_map(|&f| mesh.face_edges(f))
        .filter_map(|e| match mesh.attr(CREASE_LAYER, Domain::Edge, e.index()) {
            Some(AttrValue::Scalar(s)) if s > 0.0 => Some((e, s)),
            _ => None,
        })
        .collect();
    out.sort_unstable_by_key(|&(e, _)| e);
    out.dedup_by_key(|&mut (e, _)| e);
    out
}
