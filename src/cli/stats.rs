//! JSON and text renderings of run statistics and mesh reports. Field order
//! is fixed by the structs, floats print in shortest round-trip form, and
//! times appear only on request, so stats are byte-stable for golden checks.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::geom::sink::SinkError;
use crate::geom::IndexedMesh;
use crate::grammar::{FieldStats, RunOutput, StepStats, SurfaceStats};
use crate::kernel::build::{builds_one_to_one, mesh_from_indexed, ImportReport};
use glam::DVec3;

use crate::kernel::intersect::{
    count_close_points, indexed_self_intersection_search, self_intersection_search, PairLimits,
    PairSearch,
};
use crate::kernel::measure::report_of_indexed;
use crate::kernel::{FaceId, Mesh, MeshReport};
use crate::rules::Program;

/// Tolerance of the close-vertex gate when none is given (model units).
pub const CLOSE_TOLERANCE: f64 = 1e-6;

/// Mesh checks that search the whole mesh (BVH and hash grid; about
/// 0.1 s per 10⁵ triangles), reported beside the [`MeshReport`]. Both
/// searches are bounded (see [`PairLimits::for_items`]): on degenerate
/// input they stop, and say so, instead of running out of memory.
#[derive(Debug, PartialEq)]
pub struct Gates {
    /// Pairs of faces whose triangles intersect other than along shared
    /// vertices and edges (a lower bound unless `complete`), and the
    /// first of them (at most 1,000, sorted).
    pub self_intersections: PairSearch<(FaceId, FaceId)>,
    /// Pairs of distinct vertices at most `close_tolerance` apart.
    pub close_vertices: PairSearch<()>,
    pub close_tolerance: f64,
}

impl Gates {
    /// Whether both searches ran to the end.
    pub fn complete(&self) -> bool {
        self.self_intersections.complete && self.close_vertices.complete
    }
}

/// Both searches, side by side on two threads (each is deterministic on
/// its own, so the answer does not depend on the thread count).
fn gates(mesh: &Mesh, close_tolerance: f64) -> Gates {
    searched(
        || self_intersection_search(mesh, PairLimits::for_items),
        || mesh.vert_ids().map(|v| mesh.position(v)).collect(),
        close_tolerance,
    )
}

/// [`gates`] of the kernel mesh `indexed` builds one to one
/// ([`builds_one_to_one`]), searched in the indexed mesh itself.
fn indexed_gates(indexed: &IndexedMesh, close_tolerance: f64) -> Gates {
    searched(
        || indexed_self_intersection_search(indexed, PairLimits::for_items),
        || {
            (0..indexed.positions.len() as u32)
                .map(|i| indexed.position(i))
                .collect()
        },
        close_tolerance,
    )
}

fn searched(
    self_intersections: impl FnOnce() -> PairSearch<(FaceId, FaceId)> + Send,
    points: impl FnOnce() -> Vec<DVec3> + Send,
    close_tolerance: f64,
) -> Gates {
    let (self_intersections, close_vertices) = rayon::join(self_intersections, || {
        let points = points();
        let budget = PairLimits::for_items(points.len()).max_tests;
        count_close_points(&points, close_tolerance, budget)
    });
    Gates {
        self_intersections,
        close_vertices,
        close_tolerance,
    }
}

/// The mesh report and both gates, computed side by side.
pub fn report_and_gates(mesh: &Mesh, close_tolerance: f64) -> (MeshReport, Gates) {
    rayon::join(|| mesh.report(), || gates(mesh, close_tolerance))
}

/// What `graftal info` reports of an indexed mesh: the kernel mesh it
/// builds, measured, with both gates. When it builds one to one the
/// report and the gates are taken from the indexed mesh itself, side by
/// side, without building the kernel mesh (the same answers, sooner).
pub fn info_of(
    indexed: &IndexedMesh,
    close_tolerance: f64,
) -> Result<(MeshReport, Gates, ImportReport), SinkError> {
    if builds_one_to_one(indexed) {
        let (report, gates) = rayon::join(
            || report_of_indexed(indexed),
            || indexed_gates(indexed, close_tolerance),
        );
        Ok((report, gates, ImportReport::default()))
    } else {
        let (mesh, import) = mesh_from_indexed(indexed)?;
        let (report, gates) = report_and_gates(&mesh, close_tolerance);
        Ok((report, gates, import))
    }
}

#[derive(Serialize)]
pub struct MeshJson {
    vertices: usize,
    edges: usize,
    faces: usize,
    triangles: usize,
    wire_edges: usize,
    boundary_edges: usize,
    non_manifold_edges: usize,
    non_manifold_vertices: usize,
    isolated_vertices: usize,
    bounds: Option<[[f64; 3]; 2]>,
    area: f64,
    volume: Option<f64>,
    manifold: bool,
    watertight: bool,
    consistently_oriented: bool,
    components: usize,
    euler_characteristic: i64,
    self_intersecting_face_pairs: u64,
    close_vertex_pairs: u64,
    close_tolerance: f64,
    /// `false` when a search stopped on degenerate input: the two counts
    /// are then lower bounds.
    #[serde(skip_serializing_if = "is_true")]
    searches_complete: bool,
}

fn is_true(b: &bool) -> bool {
    *b
}

fn mesh_json(r: &MeshReport, g: &Gates) -> MeshJson {
    MeshJson {
        vertices: r.verts,
        edges: r.edges,
        faces: r.faces,
        triangles: r.triangles,
        wire_edges: r.wire_edges,
        boundary_edges: r.boundary_edges,
        non_manifold_edges: r.non_manifold_edges,
        non_manifold_vertices: r.non_manifold_verts,
        isolated_vertices: r.isolated_verts,
        bounds: r.bounds.map(|(lo, hi)| [lo.to_array(), hi.to_array()]),
        area: r.area,
        volume: r.volume,
        manifold: r.manifold,
        watertight: r.watertight,
        consistently_oriented: r.consistently_oriented,
        components: r.components,
        euler_characteristic: r.euler_characteristic,
        self_intersecting_face_pairs: g.self_intersections.count,
        close_vertex_pairs: g.close_vertices.count,
        close_tolerance: g.close_tolerance,
        searches_complete: g.complete(),
    }
}

/// One step's statistics, as the stats document and the batch manifest
/// write them (and `manifest merge` reads them back).
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
pub struct StepJson {
    pub name: std::sync::Arc<str>,
    pub op: String,
    pub runs: usize,
    pub candidates: usize,
    pub matched: usize,
    pub applied: usize,
    pub skipped_by_probability: usize,
    pub shared: usize,
    pub merged: usize,
    pub rejected_by_intersection: usize,
    pub cancelled: usize,
    pub created_vertices: usize,
    pub created_edges: usize,
    pub created_faces: usize,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_ms: Option<f64>,
    /// Steps that mesh a signed distance field: what the meshing did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub field: Option<Box<FieldJson>>,
    /// `nurbs` and `pn_smooth` steps: what the tessellation made.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface: Option<Box<SurfaceJson>>,
}

/// What tessellating a surface (or PN smoothing) did (see
/// [`SurfaceStats`]).
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
pub struct SurfaceJson {
    /// Surfaces tessellated, or meshes smoothed.
    pub runs: usize,
    pub triangles: u64,
    pub vertices: u64,
    /// Largest distance between the surface and its triangles, sampled at
    /// every triangle centroid and edge midpoint.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_deviation: Option<f64>,
    /// Adaptive tessellation: highest edge level and refinement rounds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_level: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rounds: Option<u32>,
    /// Bézier patches (knot spans u × v) of the surfaces.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub patches: Option<usize>,
    /// `pn_smooth`: the level.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pn_level: Option<u32>,
}

fn surface_json(s: &SurfaceStats) -> SurfaceJson {
    let tessellated = s.pn_level.is_none();
    SurfaceJson {
        runs: s.runs,
        triangles: s.triangles,
        vertices: s.vertices,
        max_deviation: tessellated.then_some(s.max_deviation),
        max_level: (s.max_level > 0).then_some(s.max_level),
        rounds: (s.rounds > 0).then_some(s.rounds),
        patches: tessellated.then_some(s.patches),
        pn_level: s.pn_level,
    }
}

/// What meshing a field did (see [`FieldStats`]).
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
pub struct FieldJson {
    /// Fields meshed (runs of the step that meshed one).
    pub meshings: usize,
    /// Meshes appended: an `sdf_part` places one meshing on every primitive.
    pub instances: usize,
    /// Cells per axis of the (last) grid, and its cell edge.
    pub grid: [usize; 3],
    pub cell: f64,
    pub grid_cells: u64,
    /// Cells whose corners were evaluated; the others were culled in
    /// blocks far from the surface.
    pub cells_evaluated: u64,
    pub blocks: u64,
    pub blocks_culled: u64,
    pub field_evaluations: u64,
    pub triangles: u64,
    /// Largest |f| at an output vertex.
    pub max_abs_f: f64,
    pub volume: f64,
    pub area: f64,
    pub watertight: bool,
    pub components: usize,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub genus: Option<i64>,
    /// `skin` with `method = "field"`: connected skeletons, solids, cavities.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skeletons: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solids: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cavities: Option<usize>,
    /// How the inside of each meshed input was decided.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sign: Vec<String>,
    /// With `--timings`: evaluating the field, and making triangles.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub field_ms: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh_ms: Option<f64>,
}

fn field_json(f: &FieldStats, timings: bool) -> FieldJson {
    FieldJson {
        meshings: f.meshings,
        instances: f.instances,
        grid: f.grid,
        cell: f.cell,
        grid_cells: f.grid_cells,
        cells_evaluated: f.cells_evaluated,
        blocks: f.blocks,
        blocks_culled: f.blocks_culled,
        field_evaluations: f.field_evaluations,
        triangles: f.triangles,
        max_abs_f: f.max_abs_f,
        volume: f.volume,
        area: f.area,
        watertight: f.watertight,
        components: f.components,
        genus: f.genus,
        skeletons: f.skin.map(|s| s.skeletons),
        solids: f.skin.map(|s| s.solids),
        cavities: f.skin.map(|s| s.cavities),
        sign: f.sign.clone(),
        field_ms: timings.then_some(f.field_time.as_secs_f64() * 1e3),
        mesh_ms: timings.then_some(f.mesh_time.as_secs_f64() * 1e3),
    }
}

/// The steps of a run in program order; times only if `timings`.
pub fn steps_json(steps: &[Box<StepStats>], timings: bool) -> Vec<StepJson> {
    steps
        .iter()
        .map(|s| StepJson {
            name: s.name.clone(),
            op: s.op.to_string(),
            runs: s.runs,
            candidates: s.candidates,
            matched: s.matched,
            applied: s.applied,
            skipped_by_probability: s.skipped,
            shared: s.shared,
            merged: s.merged,
            rejected_by_intersection: s.rejected,
            cancelled: s.cancelled,
            created_vertices: s.created.verts,
            created_edges: s.created.edges,
            created_faces: s.created.faces,
            time_ms: timings.then_some(s.elapsed.as_secs_f64() * 1e3),
            field: s.field.as_deref().map(|f| Box::new(field_json(f, timings))),
            surface: s.surface.as_deref().map(|s| Box::new(surface_json(s))),
        })
        .collect()
}

/// The `--stats` document of a run.
#[derive(Serialize)]
pub struct RunJson<'a> {
    graftal_version: &'a str,
    rules: &'a str,
    rule_hash: String,
    seed: u64,
    params: Vec<(&'a str, f64)>,
    mesh: MeshJson,
    /// Faces and wire edges per part, in the file's part order.
    parts: Vec<PartJson>,
    /// Wire edges the output format could not hold (STL); absent when none.
    #[serde(skip_serializing_if = "is_zero")]
    dropped_wire_edges: usize,
    steps: Vec<StepJson>,
}

/// One part's element counts.
#[derive(Serialize)]
struct PartJson {
    name: String,
    faces: usize,
    #[serde(skip_serializing_if = "is_zero")]
    wire_edges: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// The `--stats` document of a run, to serialize.
pub fn run_stats_doc<'a>(
    program: &'a Program,
    run: &'a RunOutput,
    report: &MeshReport,
    gates: &Gates,
    dropped_wire_edges: usize,
    timings: bool,
) -> RunJson<'a> {
    RunJson {
        dropped_wire_edges,
        graftal_version: env!("CARGO_PKG_VERSION"),
        rules: &program.file,
        rule_hash: format!("{:016x}", program.rule_hash),
        seed: run.seed,
        params: run.params.iter().map(|(n, v)| (n.as_str(), *v)).collect(),
        mesh: mesh_json(report, gates),
        parts: crate::grammar::part_counts(program, &run.mesh)
            .into_iter()
            .map(|c| PartJson {
                name: c.name,
                faces: c.faces,
                wire_edges: c.wire_edges,
            })
            .collect(),
        steps: steps_json(&run.steps, timings),
    }
}

#[derive(Serialize)]
struct InfoJson<'a> {
    file: &'a str,
    degenerate_faces_dropped: usize,
    #[serde(flatten)]
    mesh: MeshJson,
    /// The first self-intersecting face pairs (by face index), at most 1,000.
    first_self_intersecting_face_pairs: Vec<[usize; 2]>,
}

pub fn info_json(path: &Path, report: &MeshReport, gates: &Gates, import: &ImportReport) -> String {
    let file = path.display().to_string();
    serde_json::to_string_pretty(&InfoJson {
        file: &file,
        degenerate_faces_dropped: import.degenerate_faces,
        mesh: mesh_json(report, gates),
        first_self_intersecting_face_pairs: gates
            .self_intersections
            .pairs
            .iter()
            .map(|(a, b)| [a.index(), b.index()])
            .collect(),
    })
    .expect("info serializes")
}

/// Self-intersecting face pairs `info` lists in its text form.
const INFO_PAIRS_SHOWN: usize = 10;

pub fn info_text(path: &Path, r: &MeshReport, g: &Gates, import: &ImportReport) -> String {
    let mut s = String::new();
    let yes = |b: bool| if b { "yes" } else { "no" };
    s += &format!("file:               {}\n", path.display());
    s += &format!("vertices:           {}\n", r.verts);
    s += &format!(
        "edges:              {} ({} wire, {} boundary, {} non-manifold)\n",
        r.edges, r.wire_edges, r.boundary_edges, r.non_manifold_edges
    );
    s += &format!(
        "faces:              {} ({} triangles)\n",
        r.faces, r.triangles
    );
    if let Some((lo, hi)) = r.bounds {
        s += &format!(
            "bounds:             [{}, {}, {}] .. [{}, {}, {}]\n",
            lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
        );
    }
    s += &format!("area:               {}\n", r.area);
    match r.volume {
        Some(v) => s += &format!("volume:             {v}\n"),
        None => s += "volume:             (not closed)\n",
    }
    s += &format!("manifold:           {}\n", yes(r.manifold));
    s += &format!("watertight:         {}\n", yes(r.watertight));
    s += &format!("oriented:           {}\n", yes(r.consistently_oriented));
    s += &format!("components:         {}\n", r.components);
    s += &format!("euler:              {}\n", r.euler_characteristic);
    let at_least = |complete: bool| if complete { "" } else { "at least " };
    s += &format!(
        "self-intersections: {}{} face pairs\n",
        at_least(g.self_intersections.complete),
        g.self_intersections.count
    );
    if !g.self_intersections.pairs.is_empty() {
        let shown: Vec<String> = g
            .self_intersections
            .pairs
            .iter()
            .take(INFO_PAIRS_SHOWN)
            .map(|(a, b)| format!("{}–{}", a.index(), b.index()))
            .collect();
        let more = if g.self_intersections.count > shown.len() as u64 {
            ", …"
        } else {
            ""
        };
        s += &format!("                    faces {}{more}\n", shown.join(", "));
    }
    s += &format!(
        "close vertices:     {}{} pairs within {}\n",
        at_least(g.close_vertices.complete),
        g.close_vertices.count,
        g.close_tolerance
    );
    if !g.complete() {
        s += "                    (a search stopped early on degenerate input: counts are lower bounds)\n";
    }
    if import.degenerate_faces > 0 {
        s += &format!(
            "degenerate faces:   {} dropped on import\n",
            import.degenerate_faces
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::ops::create;

    /// Two UV spheres crossing each other, with a wire edge and a vertex
    /// off the surface (close to a sphere vertex), as an indexed mesh.
    fn crossing_spheres() -> IndexedMesh {
        let mut mesh = Mesh::new();
        create::create_uv_sphere(&mut mesh, 24, 13, 1.0).unwrap();
        let second = create::create_uv_sphere(&mut mesh, 20, 11, 0.7).unwrap();
        for v in second.verts {
            let p = mesh.position(v);
            mesh.move_vert(v, p + DVec3::new(0.8, 0.1, 0.0));
        }
        let mut indexed = mesh.to_indexed();
        let near = indexed.positions[5].map(|x| x + 1e-7);
        indexed.positions.push(near);
        indexed.lines.push([0, 7]);
        indexed
    }

    #[test]
    fn info_from_the_indexed_mesh_equals_info_from_the_built_mesh() {
        let mut dropped = crossing_spheres();
        dropped.push_polygon(&[0, 1, 0]);
        for indexed in [crossing_spheres(), dropped] {
            let (mesh, import) = mesh_from_indexed(&indexed).unwrap();
            let (report, gates) = report_and_gates(&mesh, CLOSE_TOLERANCE);
            let info = info_of(&indexed, CLOSE_TOLERANCE).unwrap();
            assert_eq!(info, (report, gates, import));
            assert!(info.1.self_intersections.count > 10);
            assert_eq!(info.1.close_vertices.count, 1);
        }
        assert!(builds_one_to_one(&crossing_spheres()));
    }
}
