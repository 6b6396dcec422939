//! Running a program: parameters, then each step in order.

use std::time::{Duration, Instant};

use glam::DVec3;
use thiserror::Error;

use crate::io;
use crate::kernel::ops::extrude::ExtrudeOffset;
use crate::kernel::ops::{self, Selection};
use crate::kernel::{Domain, EdgeId, FaceId, Mesh, VertId};
use crate::rules::compile::{property_index, PROPERTY_SLOTS};
use crate::rules::program::{Offset, Op, ParamKind, Program, Step, Vector};
use crate::rules::random;

use super::properties;

#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Seed; the program's default when `None`.
    pub seed: Option<u64>,
    /// Stop with an error when the mesh holds more elements than this
    /// (vertices + edges + faces): the guard against runaway rules.
    pub max_elements: usize,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            seed: None,
            max_elements: 50_000_000,
        }
    }
}

/// Elements a step created.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CreatedCounts {
    pub verts: usize,
    pub edges: usize,
    pub faces: usize,
}

/// What one step did.
#[derive(Debug, Clone)]
pub struct StepStats {
    pub name: String,
    pub op: &'static str,
    /// Elements considered (all of the kind, or an earlier step's products).
    pub candidates: usize,
    /// Candidates whose condition held.
    pub matched: usize,
    pub created: CreatedCounts,
    pub elapsed: Duration,
}

#[derive(Debug)]
pub struct RunOutput {
    pub mesh: Mesh,
    pub seed: u64,
    /// Parameter values, sorted by name.
    pub params: Vec<(String, f64)>,
    pub steps: Vec<StepStats>,
}

/// A failure while running: which step, where it is written, and why.
#[derive(Debug, Error)]
#[error("{location}: step `{step}`: {message}")]
pub struct RunError {
    pub step: String,
    pub location: String,
    pub message: String,
}

struct Runner<'p> {
    program: &'p Program,
    seed: u64,
    /// Parameter values, then property values of the current element.
    slots: Vec<f64>,
}

/// Runs the program and returns the mesh with per-step statistics.
pub fn run(program: &Program, options: &RunOptions) -> Result<RunOutput, RunError> {
    let seed = options.seed.unwrap_or(program.default_seed);
    let mut runner = Runner {
        program,
        seed,
        slots: vec![0.0; program.param_names.len() + PROPERTY_SLOTS],
    };
    runner.evaluate_params()?;
    let mut mesh = Mesh::new();
    let mut created: Vec<Selection> = Vec::with_capacity(program.steps.len());
    let mut stats = Vec::with_capacity(program.steps.len());
    for step in &program.steps {
        let started = Instant::now();
        let fail = |message: String| RunError {
            step: step.name.clone(),
            location: step.location.clone(),
            message,
        };
        let (candidates, selected) = runner.select(&mesh, step, &created);
        let made = runner.apply(&mut mesh, step, &selected).map_err(fail)?;
        let total = mesh.vert_count() + mesh.edge_count() + mesh.face_count();
        if total > options.max_elements {
            return Err(fail(format!(
                "the mesh has {total} elements, over the limit of {} (raise it with --max-elements)",
                options.max_elements
            )));
        }
        stats.push(StepStats {
            name: step.name.clone(),
            op: step.op.name(),
            candidates,
            matched: selected.len(),
            created: CreatedCounts {
                verts: made.verts.len(),
                edges: made.edges.len(),
                faces: made.faces.len(),
            },
            elapsed: started.elapsed(),
        });
        created.push(made);
    }
    let params = program
        .param_names
        .iter()
        .enumerate()
        .map(|(i, n)| (n.clone(), runner.slots[i]))
        .collect();
    Ok(RunOutput {
        mesh,
        seed,
        params,
        steps: stats,
    })
}

impl Runner<'_> {
    fn evaluate_params(&mut self) -> Result<(), RunError> {
        let seed = self.seed;
        for p in &self.program.params {
            let fail = |message: String| RunError {
                step: format!("params.{}", p.name),
                location: self.program.file.clone(),
                message,
            };
            let slots = &self.slots;
            let mut value = match &p.kind {
                ParamKind::Expr(e) => e.eval(slots),
                ParamKind::Uniform { low, high } => {
                    let (lo, hi) = (low.eval(slots), high.eval(slots));
                    lo + (hi - lo) * random::unit(seed, p.key, 0, 0)
                }
                ParamKind::Normal { mean, sd } => {
                    mean.eval(slots) + sd.eval(slots) * random::standard_normal(seed, p.key, 0, 0)
                }
                ParamKind::Int { low, high } => {
                    let (lo, hi) = (libm::round(low.eval(slots)), libm::round(high.eval(slots)));
                    if !(lo.is_finite() && hi.is_finite()) || lo > hi {
                        return Err(fail(format!("integer range [{lo}, {hi}] is empty")));
                    }
                    random::int_in(seed, p.key, 0, 0, lo as i64, hi as i64) as f64
                }
                ParamKind::Choice { values, weights } => {
                    let total: f64 = weights.iter().sum();
                    let mut target = random::unit(seed, p.key, 0, 0) * total;
                    let mut pick = values.len() - 1;
                    for (i, w) in weights.iter().enumerate() {
                        if target < *w {
                            pick = i;
                            break;
                        }
                        target -= w;
                    }
                    values[pick].eval(slots)
                }
            };
            if let Some((lo, hi)) = &p.clamp {
                let (lo, hi) = (lo.eval(slots), hi.eval(slots));
                if lo > hi {
                    return Err(fail(format!("clamp range [{lo}, {hi}] is empty")));
                }
                value = value.clamp(lo, hi);
            }
            if !value.is_finite() {
                return Err(fail(format!("parameter `{}` evaluates to {value}", p.name)));
            }
            self.slots[p.slot as usize] = value;
        }
        Ok(())
    }

    /// Candidates and the selected element indices (ascending).
    fn select(&mut self, mesh: &Mesh, step: &Step, created: &[Selection]) -> (usize, Vec<usize>) {
        if step.op.is_create() {
            return (0, Vec::new());
        }
        let alive = |i: usize| match step.domain {
            Domain::Vert => mesh.contains_vert(VertId::from_index(i)),
            Domain::Edge => mesh.contains_edge(EdgeId::from_index(i)),
            Domain::Face => mesh.contains_face(FaceId::from_index(i)),
        };
        let candidates: Vec<usize> = match step.from {
            Some(i) => {
                let s = &created[i];
                let ids: Vec<usize> = match step.domain {
                    Domain::Vert => s.verts.iter().map(|v| v.index()).collect(),
                    Domain::Edge => s.edges.iter().map(|e| e.index()).collect(),
                    Domain::Face => s.faces.iter().map(|f| f.index()).collect(),
                };
                ids.into_iter().filter(|&i| alive(i)).collect()
            }
            None => match step.domain {
                Domain::Vert => mesh.vert_ids().map(|v| v.index()).collect(),
                Domain::Edge => mesh.edge_ids().map(|e| e.index()).collect(),
                Domain::Face => mesh.face_ids().map(|f| f.index()).collect(),
            },
        };
        let count = candidates.len();
        let Some(condition) = &step.select else {
            return (count, candidates);
        };
        let base = self.program.param_names.len();
        let selected = candidates
            .into_iter()
            .filter(|&i| {
                for &p in &condition.properties {
                    self.slots[base + property_index(p) as usize] =
                        properties::property(mesh, step.domain, i, p, self.seed, step.key);
                }
                condition.expr.eval(&self.slots) != 0.0
            })
            .collect();
        (count, selected)
    }

    fn scalar(&self, e: &crate::rules::expr::Expr) -> f64 {
        e.eval(&self.slots)
    }

    fn vector(&self, v: &Vector) -> DVec3 {
        DVec3::new(
            self.scalar(&v.0[0]),
            self.scalar(&v.0[1]),
            self.scalar(&v.0[2]),
        )
    }

    fn count(&self, e: &crate::rules::expr::Expr, what: &str) -> Result<u32, String> {
        let x = libm::round(self.scalar(e));
        if !(x.is_finite() && (0.0..=u32::MAX as f64).contains(&x)) {
            return Err(format!("{what} must be a whole number ≥ 0, got {x}"));
        }
        Ok(x as u32)
    }

    fn offset(&self, o: &Offset) -> ExtrudeOffset {
        match o {
            Offset::None => ExtrudeOffset::None,
            Offset::Vector(v) => ExtrudeOffset::Vector(self.vector(v)),
            Offset::Normal(d) => ExtrudeOffset::Normal(self.scalar(d)),
        }
    }

    fn apply(&self, mesh: &mut Mesh, step: &Step, selected: &[usize]) -> Result<Selection, String> {
        use ops::{create, delete, extrude, faces, inset, merge, select, split, transform};
        let by_domain = selection_of(step.domain, selected);
        let verts = || -> Vec<VertId> {
            match step.domain {
                Domain::Vert => by_domain.verts.clone(),
                Domain::Edge => select::select_from_edges(mesh, &by_domain.edges).verts,
                Domain::Face => select::select_from_faces(mesh, &by_domain.faces).verts,
            }
        };
        let edges = || -> Vec<EdgeId> {
            match step.domain {
                Domain::Face => select::select_from_faces(mesh, &by_domain.faces).edges,
                _ => by_domain.edges.clone(),
            }
        };
        let full_selection = || -> Selection {
            match step.domain {
                Domain::Vert => select::select_from_verts(mesh, &by_domain.verts),
                Domain::Edge => select::select_from_edges(mesh, &by_domain.edges),
                Domain::Face => select::select_from_faces(mesh, &by_domain.faces),
            }
        };
        let moved = |vs: Vec<VertId>| Selection::from_parts(vs, Vec::new(), Vec::new());
        let faces_list = &by_domain.faces;
        let e = |err: ops::OpError| err.to_string();
        Ok(match &step.op {
            Op::Vertex { at } => create::create_vert(mesh, self.vector(at)).map_err(e)?,
            Op::Circle {
                segments,
                radius,
                fill,
            } => create::create_circle(
                mesh,
                self.count(segments, "segments")?,
                self.scalar(radius),
                *fill,
            )
            .map_err(e)?,
            Op::Grid { segments, size } => create::create_grid(
                mesh,
                self.count(&segments[0], "segments")?,
                self.count(&segments[1], "segments")?,
                self.scalar(&size[0]),
                self.scalar(&size[1]),
            )
            .map_err(e)?,
            Op::Cube { size } => create::create_cube(mesh, self.scalar(size)).map_err(e)?,
            Op::UvSphere {
                segments,
                rings,
                radius,
            } => create::create_uv_sphere(
                mesh,
                self.count(segments, "segments")?,
                self.count(rings, "rings")?,
                self.scalar(radius),
            )
            .map_err(e)?,
            Op::Cylinder {
                segments,
                radius,
                radius_top,
                depth,
                caps,
            } => create::create_cylinder(
                mesh,
                self.count(segments, "segments")?,
                self.scalar(radius),
                self.scalar(radius_top),
                self.scalar(depth),
                *caps,
            )
            .map_err(e)?,
            Op::Import { path } => {
                let indexed = io::read_mesh(path).map_err(|err| err.to_string())?;
                let other = io::bridge::mesh_from_indexed(&indexed)
                    .map_err(|err| format!("{}: {err}", path.display()))?;
                let map = mesh.join_mesh(&other);
                Selection::from_parts(
                    map.verts.into_iter().flatten().collect(),
                    map.edges.into_iter().flatten().collect(),
                    map.faces.into_iter().flatten().collect(),
                )
            }
            Op::Translate { offset } => {
                let vs = verts();
                transform::translate(mesh, &vs, self.vector(offset)).map_err(e)?;
                moved(vs)
            }
            Op::Rotate {
                angle_degrees,
                axis,
                center,
            } => {
                let vs = verts();
                let angle = self.scalar(angle_degrees).to_radians();
                transform::rotate(mesh, &vs, self.vector(center), self.vector(axis), angle)
                    .map_err(e)?;
                moved(vs)
            }
            Op::Scale { factor, center } => {
                let vs = verts();
                transform::scale(mesh, &vs, self.vector(center), self.vector(factor)).map_err(e)?;
                moved(vs)
            }
            Op::ExtrudeVerts { offset } => {
                let vs = verts();
                extrude::extrude_verts(mesh, &vs, self.offset(offset)).map_err(e)?
            }
            Op::ExtrudeEdges { offset } => {
                let es = edges();
                extrude::extrude_edges(mesh, &es, self.offset(offset)).map_err(e)?
            }
            Op::ExtrudeFaces {
                keep_original,
                offset,
            } => extrude::extrude_faces(mesh, faces_list, *keep_original, self.offset(offset))
                .map_err(e)?,
            Op::ExtrudeRegion {
                keep_original,
                offset,
            } => {
                extrude::extrude_face_region(mesh, faces_list, *keep_original, self.offset(offset))
                    .map_err(e)?
            }
            Op::InsetFaces { thickness, depth } => {
                inset::inset_faces(mesh, faces_list, self.scalar(thickness), self.scalar(depth))
                    .map_err(e)?
            }
            Op::InsetRegion { thickness, depth } => {
                inset::inset_region(mesh, faces_list, self.scalar(thickness), self.scalar(depth))
                    .map_err(e)?
            }
            Op::SplitEdgesCuts { cuts } => {
                let es = edges();
                split::split_edges(mesh, &es, self.count(cuts, "cuts")?).map_err(e)?
            }
            Op::SplitEdgesRatios { ratios } => {
                let es = edges();
                let r: Vec<f64> = ratios.iter().map(|x| self.scalar(x)).collect();
                split::split_edges_at(mesh, &es, &r).map_err(e)?
            }
            Op::Triangulate => faces::triangulate(mesh, faces_list).map_err(e)?,
            Op::Reverse => {
                faces::reverse_faces(mesh, faces_list).map_err(e)?;
                Selection::from_parts(Vec::new(), Vec::new(), faces_list.clone())
            }
            Op::RecomputeNormals { outside } => {
                faces::recompute_normals(mesh, faces_list, *outside).map_err(e)?;
                Selection::from_parts(Vec::new(), Vec::new(), faces_list.clone())
            }
            Op::Delete { mode } => {
                let s = match step.domain {
                    Domain::Face => by_domain.clone(),
                    _ => full_selection(),
                };
                delete::delete(mesh, &s, *mode).map_err(e)?
            }
            Op::Duplicate => {
                let s = full_selection();
                delete::duplicate(mesh, &s).map_err(e)?
            }
            Op::DissolveEdges => {
                let es = edges();
                delete::dissolve_edges(mesh, &es).map_err(e)?
            }
            Op::MakeFace => {
                let es = edges();
                faces::make_face_from_edges(mesh, &es).map_err(e)?
            }
            Op::Merge { distance } => {
                let vs = verts();
                let r = merge::merge_by_distance(mesh, &vs, self.scalar(distance)).map_err(e)?;
                moved(r.survivors)
            }
            Op::Mirror {
                point,
                normal,
                merge_distance,
            } => {
                let s = full_selection();
                merge::mirror(
                    mesh,
                    &s,
                    self.vector(point),
                    self.vector(normal),
                    self.scalar(merge_distance),
                )
                .map_err(e)?
            }
            Op::RegionExtend { by } => Selection::from_parts(
                Vec::new(),
                Vec::new(),
                select::region_extend(mesh, faces_list, *by),
            ),
            Op::RegionReduce { by } => Selection::from_parts(
                Vec::new(),
                Vec::new(),
                select::region_reduce(mesh, faces_list, *by),
            ),
        })
    }
}

fn selection_of(domain: Domain, indices: &[usize]) -> Selection {
    let mut s = Selection::new();
    match domain {
        Domain::Vert => s.verts = indices.iter().map(|&i| VertId::from_index(i)).collect(),
        Domain::Edge => s.edges = indices.iter().map(|&i| EdgeId::from_index(i)).collect(),
        Domain::Face => s.faces = indices.iter().map(|&i| FaceId::from_index(i)).collect(),
    }
    s
}
