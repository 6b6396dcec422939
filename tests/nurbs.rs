//! Parametric surfaces from rule files (thesis 002, issue 15): `[nurbs]`
//! surfaces tessellated by `nurbs` in every mode, `pn_smooth` on any
//! mesh, located errors before the run, limits, determinism.

mod common;

use std::path::Path;

use common::{graftal, graftal_in, stderr, stdout};
use serde_json::Value;

fn temp_dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

/// The JSON stats printed before the "wrote …" line.
fn stats(o: &std::process::Output) -> Value {
    let text = stdout(o);
    let end = text.rfind('}').expect("stats on stdout");
    serde_json::from_str(&text[..=end]).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

fn run_stats(args: &[&str]) -> Value {
    let dir = temp_dir();
    let out = dir.path().join("out.obj");
    let mut all = vec!["run"];
    all.extend_from_slice(args);
    all.extend(["-o", out.to_str().unwrap(), "--stats", "-"]);
    let o = graftal(&all);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    stats(&o)
}

/// Writes `text` as `dir/NAME.toml`, runs it to `dir/NAME.obj` and returns its stats.
fn run_text(dir: &Path, name: &str, text: &str) -> Value {
    std::fs::write(dir.join(format!("{name}.toml")), text).unwrap();
    let (rules, out) = (format!("{name}.toml"), format!("{name}.obj"));
    let o = graftal_in(dir, &["run", &rules, "-o", &out, "--stats", "-"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    stats(&o)
}

fn surface_of<'a>(s: &'a Value, step: &str) -> &'a Value {
    let steps = s["steps"].as_array().unwrap();
    &steps.iter().find(|x| x["name"] == step).unwrap()["surface"]
}

#[test]
fn the_peer_surface_meets_its_tolerance_with_few_triangles() {
    let s = run_stats(&["rules/nurbs-surface.toml"]);
    let t = surface_of(&s, "start");
    let deviation = t["max_deviation"].as_f64().unwrap();
    assert!(deviation <= 1e-3 && deviation > 5e-4, "{deviation}");
    let triangles = t["triangles"].as_u64().unwrap();
    // At most half of curvo's 165,848, fewer than OpenCASCADE's 39,660
    // (../shared/peers.md §3).
    assert!(triangles < 39_660, "{triangles}");
    assert_eq!(t["patches"], 49);
    let mesh = &s["mesh"];
    assert_eq!(mesh["triangles"].as_u64(), Some(triangles));
    assert_eq!(mesh["manifold"], true);
    assert_eq!(mesh["consistently_oriented"], true);
    assert_eq!(mesh["components"], 1);
    assert_eq!(
        mesh["euler_characteristic"], 1,
        "a disk: conforming, no cracks"
    );
    assert_eq!(mesh["close_vertex_pairs"], 0);
    assert_eq!(mesh["self_intersecting_face_pairs"], 0);
    // The net spans [0, 9]²: the border is the domain's border.
    assert_eq!(mesh["bounds"][0][0], 0.0);
    assert!((mesh["bounds"][1][0].as_f64().unwrap() - 9.0).abs() < 1e-12);
    // A finer tolerance, more triangles, still within it.
    let fine = run_stats(&["rules/nurbs-surface.toml", "--set", "tolerance=1e-4"]);
    let f = surface_of(&fine, "start");
    assert!(f["max_deviation"].as_f64().unwrap() <= 1e-4);
    assert!(f["triangles"].as_u64().unwrap() > 3 * triangles);
}

/// A uniform grid without seams or poles is built from its samples in closed form, and its
/// vertices carry their surface parameters in bulk (issue 38): every vertex of a 6 × 4-cell
/// grid has its own (i/6, j/4), and the parameters grow with x and y as the surface does.
#[test]
fn a_plain_uniform_grid_carries_each_vertex_its_own_surface_parameters() {
    let dir = temp_dir();
    let text = "uv = { projection = \"surface\" }\n\n[nurbs.flat]\ndegree = 3\nsize = [5, 4]\npoints = [\"i\", \"j\", \"0.1 * i * j\"]\n\n[start]\nnurbs = { surface = \"flat\", mode = \"uniform\", cells = [6, 4], per_patch = false }\n";
    let s = run_text(dir.path(), "flat", text);
    assert_eq!(surface_of(&s, "start")["triangles"], 48);
    let obj = std::fs::read_to_string(dir.path().join("flat.obj")).unwrap();
    let numbers = |line: &str| -> Vec<f64> {
        line.split_whitespace()
            .skip(1)
            .map(|x| x.parse().unwrap())
            .collect()
    };
    let positions: Vec<Vec<f64>> = obj
        .lines()
        .filter(|l| l.starts_with("v "))
        .map(numbers)
        .collect();
    let uvs: Vec<Vec<f64>> = obj
        .lines()
        .filter(|l| l.starts_with("vt "))
        .map(numbers)
        .collect();
    assert_eq!(positions.len(), 35);
    // Each corner's (position, uv), through the faces.
    let mut corners = Vec::new();
    for face in obj.lines().filter(|l| l.starts_with("f ")) {
        for corner in face.split_whitespace().skip(1) {
            let ids: Vec<usize> = corner.split('/').map(|x| x.parse().unwrap()).collect();
            corners.push((positions[ids[0] - 1].clone(), uvs[ids[1] - 1].clone()));
        }
    }
    let mut seen: Vec<[u64; 2]> = corners
        .iter()
        .map(|(_, uv)| [uv[0].to_bits(), uv[1].to_bits()])
        .collect();
    seen.sort_unstable();
    seen.dedup();
    let mut grid: Vec<[u64; 2]> = (0..=6)
        .flat_map(|i| {
            (0..=4).map(move |j| [(i as f64 / 6.0).to_bits(), (j as f64 / 4.0).to_bits()])
        })
        .collect();
    grid.sort_unstable();
    assert_eq!(seen, grid, "one (u, v) per grid sample");
    for (p, uv) in &corners {
        for (q, wv) in &corners {
            if uv[0] < wv[0] {
                assert!(p[0] < q[0], "x grows with u: {p:?} {uv:?} / {q:?} {wv:?}");
            }
            if uv[1] < wv[1] {
                assert!(p[1] < q[1], "y grows with v: {p:?} {uv:?} / {q:?} {wv:?}");
            }
        }
    }
}

#[test]
fn every_mode_of_the_seed_patch_is_a_disk() {
    let s = run_stats(&["rules/bezier-patch.toml"]);
    assert_eq!(surface_of(&s, "uniform")["triangles"], 2 * 16 * 16);
    for step in ["start", "interpatch"] {
        let d = surface_of(&s, step)["max_deviation"].as_f64().unwrap();
        assert!(d <= 0.01, "{step}: {d}");
    }
    // Three disks side by side, each conforming (χ = 1 each).
    assert_eq!(s["mesh"]["components"], 3);
    assert_eq!(s["mesh"]["euler_characteristic"], 3);
    assert_eq!(s["mesh"]["manifold"], true);
}

#[test]
fn pn_cube_counts_follow_the_gl_pattern_and_stay_closed() {
    for (level, triangles) in [("1", 12), ("5", 444), ("10", 1800)] {
        let s = run_stats(&["rules/pn-cube.toml", "--set", &format!("level={level}")]);
        let mesh = &s["mesh"];
        assert_eq!(mesh["triangles"], triangles, "level {level}");
        assert_eq!(mesh["watertight"], true);
        assert_eq!(mesh["euler_characteristic"], 2);
        assert_eq!(mesh["self_intersecting_face_pairs"], 0);
    }
}

#[test]
fn pn_keeps_flat_faces_flat_below_the_crease_angle() {
    let dir = temp_dir();
    let text = "[start]\ncube = { size = 2 }\n[[step]]\npn_smooth = { level = 4, crease = 30 }\n";
    std::fs::write(dir.path().join("r.toml"), text).unwrap();
    let o = graftal_in(
        dir.path(),
        &["run", "r.toml", "-o", "out.obj", "--stats", "-"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s = stats(&o);
    // Every edge of a cube is a crease: each face stays a flat square.
    assert_eq!(s["mesh"]["triangles"], 12 * 16);
    assert_eq!(s["mesh"]["watertight"], true);
    assert!((s["mesh"]["volume"].as_f64().unwrap() - 8.0).abs() < 1e-12);
}

#[test]
fn identical_bytes_twice_and_at_any_job_count() {
    let files = common::assert_same_bytes_at_any_thread_and_job_count(
        "rules/nurbs-surface.toml",
        "s-{tolerance}.glb",
        &["--grid", "tolerance=0.01,0.003"],
    );
    assert_eq!(files, 2);
}

/// A surface table around `body` (degree 2 on a 3 × 3 net by default).
fn surface(body: &str, step: &str) -> String {
    format!("[nurbs.s]\n{body}\n[start]\nnurbs = {{ surface = \"s\"{step} }}\n")
}

const NET: &str = "points = [\"i\", \"j\", \"0\"]";

#[test]
fn bad_surfaces_are_located_errors_exit_2_with_no_output() {
    let cases: Vec<(String, &str, &str)> = vec![
        (
            surface(&format!("degree = 2\nsize = [3, 3]\n{NET}\nknots_u = [0, 0, 0, 1, 1]"), ""),
            "rules.toml:5:11",
            "knots_u: expected 6 knots",
        ),
        (
            surface(&format!("degree = 2\nsize = [3, 3]\n{NET}\nknots_v = [0, 0, 0, 1, 0.5, 1]"), ""),
            "rules.toml:5:11",
            "smaller than the previous knot",
        ),
        (
            surface("degree = 1\nsize = [2, 2]\npoints = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]\nweights = [1, 1, 0, 1]", ""),
            "rules.toml:5:11",
            "weights[2]: weight 0 must be positive",
        ),
        (
            surface(&format!("degree = 3\nsize = [3, 3]\n{NET}"), ""),
            "rules.toml:2:10",
            "degree 3 needs at least 4 control points",
        ),
        (
            surface("degree = 2\nsize = [3, 3]\npoints = [\"i\", \"j\", \"sqrt(i - 1)\"]", ""),
            "rules.toml:4:10",
            "point [0, 0]",
        ),
        (
            surface("degree = 2\nsize = [3, 3]\npoints = [[0, 0, 0]]", ""),
            "rules.toml:4:10",
            "needs 9 points, the list has 1",
        ),
        (
            surface(&format!("degree = 2\nsize = [3, 3]\n{NET}"), ", tolerance = 0"),
            "rules.toml:6:",
            "tolerance",
        ),
        (
            surface(&format!("degree = 2\nsize = [3, 3]\n{NET}"), ", max_level = 99"),
            "rules.toml:6:",
            "max_level",
        ),
        (
            surface(&format!("degree = 2\nsize = [3, 3]\n{NET}\ncolour = 1"), ""),
            "rules.toml:5:1",
            "unknown field `colour` of a nurbs surface",
        ),
        (
            surface("degree = 2\nsize = [3, 3]", ""),
            "rules.toml:1:1",
            "missing field `points`",
        ),
        (
            surface(&format!("degree = 2\nsize = [3, 3]\n{NET}"), "").replace("surface = \"s\"", "surface = \"t\""),
            "rules.toml:6:",
            "no nurbs surface named `t`",
        ),
        (
            surface("degree = 2\nsize = [3, 3]\npoints = [\"i\", \"k\", \"0\"]", ""),
            "rules.toml:4:17",
            "unknown name `k`",
        ),
    ];
    let dir = temp_dir();
    for (text, location, words) in &cases {
        common::assert_located_error(dir.path(), text, location, words);
    }
}

#[test]
fn a_tessellation_past_the_primitive_limit_is_refused_exit_3() {
    let dir = temp_dir();
    let out = dir.path().join("x.obj");
    let o = graftal(&[
        "run",
        "rules/nurbs-surface.toml",
        "--set",
        "tolerance=1e-6",
        "--max-primitives",
        "100000",
        "-o",
        out.to_str().unwrap(),
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("tessellating `hill`"), "{err}");
    assert!(!out.exists());
}

#[test]
fn generator_parameters_count_as_used_and_i_j_are_known() {
    let dir = temp_dir();
    let text = "[params]\nh = 2\n[nurbs.s]\ndegree = 2\nsize = [3, 3]\npoints = [\"i\", \"j\", \"h * i * j\"]\n[start]\nnurbs = { surface = \"s\" }\n";
    std::fs::write(dir.path().join("r.toml"), text).unwrap();
    let o = graftal_in(dir.path(), &["lint", "r.toml"]);
    let all = format!("{}{}", stdout(&o), stderr(&o));
    assert_eq!(o.status.code(), Some(0), "{all}");
    assert!(!all.contains("unused") && !all.contains("unknown"), "{all}");
}

#[test]
fn every_example_surface_is_documented() {
    let doc = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/rules.md"))
        .unwrap();
    for key in graftal::rules::compile::SURFACE_KEYS {
        assert!(doc.contains(&format!("| `{key}` |")), "no row for {key}");
    }
}

#[test]
fn a_profile_turned_on_a_lathe_is_closed_around_and_open_at_the_rim() {
    let s = run_stats(&["rules/vase.toml"]);
    let mesh = &s["mesh"];
    assert_eq!(mesh["manifold"], true);
    assert_eq!(mesh["consistently_oriented"], true);
    assert_eq!(mesh["components"], 1);
    assert_eq!(
        mesh["euler_characteristic"], 1,
        "a disk: pole at the bottom, one rim"
    );
    assert_eq!(mesh["close_vertex_pairs"], 0);
    assert!(surface_of(&s, "start")["max_deviation"].as_f64().unwrap() <= 0.002);
    // An open tube: two rims, χ = 0; the circle is exact, so every vertex
    // of a degree-1 profile at radius 1 lies on the cylinder.
    let dir = temp_dir();
    let text = "[nurbs.tube]\ndegree = 1\nprofile = [[1, 0], [1, 2]]\n[start]\nnurbs = { surface = \"tube\", tolerance = 1e-4 }\n";
    std::fs::write(dir.path().join("t.toml"), text).unwrap();
    let o = graftal_in(
        dir.path(),
        &["run", "t.toml", "-o", "t.obj", "--stats", "-"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let t = stats(&o);
    assert_eq!(t["mesh"]["euler_characteristic"], 0);
    assert_eq!(t["mesh"]["manifold"], true);
    let m = common::read_mesh(&dir.path().join("t.obj"));
    for p in &m.positions {
        assert!((p[0].hypot(p[1]) - 1.0).abs() < 1e-12, "{p:?}");
    }
}

#[test]
fn bad_profiles_are_located_errors() {
    let dir = temp_dir();
    for (text, location, words) in [
        (
            "[nurbs.v]\ndegree = 1\nprofile = [[-1, 0], [1, 1]]\n[start]\nnurbs = { surface = \"v\" }\n",
            "rules.toml:3:11",
            "r must be finite and ≥ 0",
        ),
        (
            "[nurbs.v]\ndegree = 1\npoints = [[0, 0, 0]]\nprofile = [[1, 0], [1, 1]]\n[start]\nnurbs = { surface = \"v\" }\n",
            "rules.toml:4:11",
            "not both",
        ),
        (
            "[nurbs.v]\ndegree = 1\nprofile = [[1, 0], [1, 1]]\nknots_u = [0, 1]\n[start]\nnurbs = { surface = \"v\" }\n",
            "rules.toml:4:11",
            "give `knots_v` only",
        ),
        (
            "[nurbs.v]\ndegree = 1\nprofile = [\"1\", \"j\"]\n[start]\nnurbs = { surface = \"v\" }\n",
            "rules.toml:1:1",
            "missing field `size`",
        ),
    ] {
        common::assert_located_error(dir.path(), text, location, words);
    }
}

#[test]
fn nurbs_part_places_one_closed_copy_per_selected_face_scaled_by_its_size() {
    let s = run_stats(&["rules/knobs.toml"]);
    let knobs = surface_of(&s, "knobs");
    let one = knobs["triangles"].as_u64().unwrap() / 8;
    assert_eq!(
        knobs["triangles"].as_u64().unwrap(),
        8 * one,
        "eight faces, eight copies"
    );
    assert_eq!(s["mesh"]["components"], 9, "the panel and eight knobs");
    assert_eq!(
        s["mesh"]["watertight"], true,
        "each knob is closed: poles at foot and top"
    );
    assert_eq!(s["mesh"]["self_intersecting_face_pairs"], 0);
    // Unit faces: the knobs are as tall as `height` (0.3) above the panel.
    let top = s["mesh"]["bounds"][1][2].as_f64().unwrap();
    assert!((top - 0.5).abs() < 1e-9, "{top}");
    // Twice the face size, twice the knob.
    let dir = temp_dir();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("rules/knobs.toml"))
        .unwrap()
        .replace("size = [4, 2] }", "size = [8, 4] }");
    std::fs::write(dir.path().join("k.toml"), text).unwrap();
    let o = graftal_in(
        dir.path(),
        &["run", "k.toml", "-o", "k.obj", "--stats", "-"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let big = stats(&o);
    let top = big["mesh"]["bounds"][1][2].as_f64().unwrap();
    assert!((top - (0.2 + 2.0 * 0.3)).abs() < 1e-9, "{top}");
}

#[test]
fn the_thesis_edge_tests_combine_with_the_chordal_test() {
    let dir = temp_dir();
    let run = |extra: &str| {
        let text = format!(
            "[nurbs.hill]\ndegree = 3\nsize = [10, 10]\npoints = [\"i\", \"j\", \"2 * sin(0.7 * i) * cos(0.5 * j)\"]\n[start]\nnurbs = {{ surface = \"hill\", tolerance = 0.01, max_level = 6{extra} }}\n"
        );
        std::fs::write(dir.path().join("e.toml"), text).unwrap();
        let o = graftal_in(
            dir.path(),
            &["run", "e.toml", "-o", "e.obj", "--stats", "-"],
        );
        assert_eq!(o.status.code(), Some(0), "{extra}: {}", stderr(&o));
        let s = stats(&o);
        assert_eq!(s["mesh"]["manifold"], true, "{extra}");
        assert_eq!(s["mesh"]["euler_characteristic"], 1, "{extra}: conforming");
        let t = surface_of(&s, "start");
        (
            t["triangles"].as_u64().unwrap(),
            t["max_deviation"].as_f64().unwrap(),
        )
    };
    let (alone, d) = run("");
    assert!(d <= 0.01);
    let (any, d_any) = run(", test = \"two_triangle\"");
    assert!(any > alone && d_any <= 0.01, "{any} vs {alone}");
    let (all, _) = run(", test = \"two_triangle\", combine = \"all\"");
    assert!(all <= any, "{all} vs {any}");
}

#[test]
fn nurbs_patch_replaces_quads_and_keeps_the_solid_closed() {
    let s = run_stats(&["rules/cushions.toml"]);
    let steps = s["steps"].as_array().unwrap();
    let cushions = steps.iter().find(|x| x["name"] == "cushions").unwrap();
    assert_eq!(cushions["applied"], 3);
    assert_eq!(cushions["created_faces"], 3 * 8 * 8);
    let mesh = &s["mesh"];
    assert_eq!(mesh["watertight"], true);
    assert_eq!(mesh["euler_characteristic"], 2);
    assert_eq!(mesh["self_intersecting_face_pairs"], 0);
    assert_eq!(mesh["close_vertex_pairs"], 0);
    // Without lift the patch is the face itself: the slab keeps its volume.
    let dir = temp_dir();
    let text = "[start]\ngrid = { segments = [2, 2], size = [2, 2] }\n[[step]]\nextrude_region = { keep_original = true, offset = [0, 0, 1] }\n[[step]]\nselect = \"normal.z > 0.5\"\nnurbs_patch = { lift = 0, cells = 5 }\n";
    let flat = run_text(dir.path(), "p", text);
    assert_eq!(flat["mesh"]["watertight"], true);
    assert!((flat["mesh"]["volume"].as_f64().unwrap() - 4.0).abs() < 1e-12);
}

/// The nine-point rational circle of radius `r` as a `[nurbs.NAME]` curve.
fn circle_curve(name: &str, r: f64) -> String {
    format!(
        "[nurbs.{name}]\ndegree = 2\npoints = [[{r}, 0, 0], [{r}, {r}, 0], [0, {r}, 0], [-{r}, {r}, 0], [-{r}, 0, 0], [-{r}, -{r}, 0], [0, -{r}, 0], [{r}, -{r}, 0], [{r}, 0, 0]]\nweights = \"1 - (1 - sqrt(0.5)) * (i % 2)\"\nknots = [0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1]\n"
    )
}

#[test]
fn a_circle_swept_round_a_circle_is_a_closed_torus() {
    let dir = temp_dir();
    let text = format!(
        "{}{}[nurbs.ring]\nprofile = \"tube\"\npath = \"spine\"\npath_tolerance = 1e-4\n[start]\nnurbs = {{ surface = \"ring\", tolerance = 1e-3 }}\n",
        circle_curve("tube", 0.25),
        circle_curve("spine", 2.0)
    );
    std::fs::write(dir.path().join("t.toml"), text).unwrap();
    let o = graftal_in(
        dir.path(),
        &["run", "t.toml", "-o", "t.obj", "--stats", "-"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let mesh = &stats(&o)["mesh"];
    assert_eq!(mesh["watertight"], true, "{mesh}");
    assert_eq!(mesh["euler_characteristic"], 0, "a torus");
    assert_eq!(mesh["consistently_oriented"], true);
    // Outward normals: the volume is the torus's, 2π²Rr², within the tolerances.
    let volume = mesh["volume"].as_f64().unwrap();
    let exact = 2.0 * std::f64::consts::PI.powi(2) * 2.0 * 0.25f64.powi(2);
    assert!((volume - exact).abs() / exact < 5e-3, "{volume} vs {exact}");
    let m = common::read_mesh(&dir.path().join("t.obj"));
    let worst = m
        .positions
        .iter()
        .map(|p| ((p[0].hypot(p[1]) - 2.0).hypot(p[2]) - 0.25).abs())
        .fold(0.0, f64::max);
    assert!(worst < 2e-3, "off the torus by {worst}");
}

#[test]
fn a_lathe_of_a_named_curve_equals_the_lathe_of_its_list() {
    let dir = temp_dir();
    let listed = "[nurbs.v]\ndegree = 2\nprofile = [[0, 0], [1, 0.5], [0.6, 1.5], [0.8, 2]]\n[start]\nnurbs = { surface = \"v\" }\n";
    let named = "[nurbs.p]\ndegree = 2\npoints = [[0, 0, 0], [1, 0, 0.5], [0.6, 0, 1.5], [0.8, 0, 2]]\n[nurbs.v]\nprofile = \"p\"\n[start]\nnurbs = { surface = \"v\" }\n";
    let mut meshes = Vec::new();
    for (name, text) in [("a", listed), ("b", named)] {
        std::fs::write(dir.path().join(format!("{name}.toml")), text).unwrap();
        let out = format!("{name}.obj");
        let o = graftal_in(dir.path(), &["run", &format!("{name}.toml"), "-o", &out]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        meshes.push(common::read_mesh(&dir.path().join(out)));
    }
    assert_eq!(meshes[0].positions, meshes[1].positions, "the same surface");
    assert_eq!(meshes[0].face_indices, meshes[1].face_indices);
}

#[test]
fn the_cup_example_is_one_closed_solid_of_two_parts() {
    let s = run_stats(&["rules/cup.toml"]);
    // The handle, capped, fused into the body by an exact boolean union:
    // one closed solid with one hole through it.
    assert_eq!(s["mesh"]["components"], 1);
    assert_eq!(s["mesh"]["manifold"], true);
    assert_eq!(s["mesh"]["watertight"], true);
    assert_eq!(s["mesh"]["non_manifold_edges"], 0);
    assert_eq!(s["mesh"]["boundary_edges"], 0);
    assert_eq!(s["mesh"]["euler_characteristic"], 0);
    let parts: Vec<&str> = s["parts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    assert_eq!(parts, ["body", "handle"]);
    assert!(surface_of(&s, "handle")["max_deviation"].as_f64().unwrap() <= 0.002);
}

#[test]
fn bad_curves_and_sweeps_are_located_errors() {
    let dir = temp_dir();
    let grip = circle_curve("c", 0.1);
    let line = "[nurbs.l]\ndegree = 1\npoints = [[0, 0, 0], [0, 0, 1]]\n";
    let cases = [
        (
            format!("{grip}[start]\nnurbs = {{ surface = \"c\" }}\n"),
            "rules.toml:7:21",
            "`c` is a curve, not a surface",
        ),
        (
            format!("{grip}{line}[nurbs.s]\nprofile = \"c\"\npath = \"nope\"\n[start]\nnurbs = {{ surface = \"s\" }}\n"),
            "rules.toml:11:8",
            "no nurbs curve named `nope`",
        ),
        (
            format!("{grip}{line}[nurbs.s]\nprofile = \"c\"\npath = \"l\"\ndegree = 3\n[start]\nnurbs = {{ surface = \"s\" }}\n"),
            "rules.toml:12:10",
            "takes their degree",
        ),
        (
            format!("{grip}{line}[nurbs.s]\nprofile = \"c\"\npath = \"l\"\npath_tolerance = 0\n[start]\nnurbs = {{ surface = \"s\" }}\n"),
            "rules.toml:12:18",
            "must be a positive number",
        ),
        (
            format!("{grip}{line}[nurbs.s]\nprofile = \"c\"\npath = \"l\"\norient = \"sideways\"\n[start]\nnurbs = {{ surface = \"s\" }}\n"),
            "rules.toml:12:10",
            "invalid orient `sideways`",
        ),
        (
            // The grip is drawn in XY: not a lathe profile.
            format!("{grip}[nurbs.s]\nprofile = \"c\"\n[start]\nnurbs = {{ surface = \"s\" }}\n"),
            "rules.toml:7:11",
            "a profile lies in the XZ plane",
        ),
        (
            "[nurbs.c]\ndegree = 1\nsize = 2\npoints = [[0, 0, 0], [1, 0, 0]]\nknots_u = [0, 0, 1, 1]\n[start]\nnurbs = { surface = \"c\" }\n".to_owned(),
            "rules.toml:5:11",
            "a curve (one `size`) takes",
        ),
        (
            "[nurbs.c]\ndegree = 3\npoints = [[0, 0, 0], [1, 0, 0]]\n[nurbs.s]\nprofile = \"c\"\n[start]\nnurbs = { surface = \"s\" }\n".to_owned(),
            "rules.toml:2:10",
            "nurbs curve `c`",
        ),
    ];
    for (text, location, words) in &cases {
        common::assert_located_error(dir.path(), text, location, words);
    }
}

// ---------------------------------------------------------------- patch sets (issue 37)

/// Boundary loops of an indexed mesh: components of its boundary edges.
fn boundary_loops(mesh: &graftal::io::IndexedMesh) -> usize {
    let mut count: std::collections::BTreeMap<[u32; 2], u32> = Default::default();
    for k in 0..mesh.face_starts.len() - 1 {
        let f = &mesh.face_indices[mesh.face_starts[k] as usize..mesh.face_starts[k + 1] as usize];
        for i in 0..f.len() {
            let (a, b) = (f[i], f[(i + 1) % f.len()]);
            *count.entry([a.min(b), a.max(b)]).or_default() += 1;
        }
    }
    let mut parent: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            x = p[x as usize];
        }
        x
    }
    let mut on = std::collections::BTreeSet::new();
    for (e, n) in &count {
        if *n == 1 {
            on.insert(e[0]);
            on.insert(e[1]);
            let (a, b) = (find(&mut parent, e[0]), find(&mut parent, e[1]));
            parent[a.max(b) as usize] = a.min(b);
        }
    }
    on.iter().filter(|&&v| find(&mut parent, v) == v).count()
}

/// Pairs of distinct vertices at bit-identical positions, with the position.
fn coincident_vertices(mesh: &graftal::io::IndexedMesh) -> Vec<[f64; 3]> {
    let mut keys: Vec<([u64; 3], [f64; 3])> = mesh
        .positions
        .iter()
        .map(|p| (p.map(|x| (x + 0.0).to_bits()), *p))
        .collect();
    keys.sort_by_key(|k| k.0);
    keys.windows(2)
        .filter(|w| w[0].0 == w[1].0)
        .map(|w| w[0].1)
        .collect()
}

/// The teapot in each mode, from the example's patch file copied beside a rule file.
fn teapot(dir: &Path, file: &str, step: &str) -> (Value, graftal::io::IndexedMesh) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (from, to) in [
        ("rules/teapot.bpt", "teapot.bpt"),
        ("tests/fixtures/teapot.obj", "teapot.obj"),
    ] {
        std::fs::copy(root.join(from), dir.join(to)).unwrap();
    }
    let text = format!("[nurbs.teapot]\npatches = \"{file}\"\n\n[start]\nnurbs = {{ surface = \"teapot\", {step} }}\n");
    let s = run_text(dir, "t", &text);
    (s, common::read_mesh(&dir.join("t.obj")))
}

#[test]
fn the_teapot_is_one_mesh_without_cracks_in_every_mode() {
    let dir = temp_dir();
    for step in [
        "mode = \"uniform\", cells = [8, 8]",
        "mode = \"uniform\", cells = [5, 3]",
        "mode = \"interpatch\", tolerance = 0.001",
        "mode = \"adaptive\", tolerance = 0.001",
    ] {
        let (s, mesh) = teapot(dir.path(), "teapot.bpt", step);
        let m = &s["mesh"];
        // Body with rim and bottom, lid, handle, spout: each a manifold sheet.
        assert_eq!(m["components"], 4, "{step}: {m}");
        assert_eq!(m["manifold"], true, "{step}");
        assert_eq!(m["non_manifold_edges"], 0, "{step}");
        assert_eq!(m["non_manifold_vertices"], 0, "{step}");
        assert_eq!(m["consistently_oriented"], true, "{step}");
        // Open only where Newell's data is: rim, lid edge, both ends of handle and spout
        // (per-patch meshing gave 10 loops and 28 crack vertices at 8 × 8).
        assert_eq!(boundary_loops(&mesh), 6, "{step}");
        // No crack vertex; the one coincident pair is the handle's end touching a corner of
        // the body, where no border is shared (welding it would make a vertex of two fans).
        assert_eq!(coincident_vertices(&mesh), vec![[-2.0, 0.0, 0.9]], "{step}");
        assert_eq!(s["steps"][0]["surface"]["patches"], 32);
    }
    // Uniform 8 × 8: every patch a full grid, the 64 triangles at the 8 pole patches dropped.
    let (s, _) = teapot(
        dir.path(),
        "teapot.bpt",
        "mode = \"uniform\", cells = [8, 8]",
    );
    assert_eq!(s["mesh"]["triangles"], 32 * 128 - 8 * 8);
}

#[test]
fn the_teapot_reads_the_same_from_obj_free_form_and_bpt() {
    let (a, b) = (temp_dir(), temp_dir());
    let step = "mode = \"adaptive\", tolerance = 0.002";
    teapot(a.path(), "teapot.bpt", step);
    teapot(b.path(), "teapot.obj", step);
    assert_eq!(
        std::fs::read(a.path().join("t.obj")).unwrap(),
        std::fs::read(b.path().join("t.obj")).unwrap()
    );
}

#[test]
fn inter_patch_stays_close_to_adaptive_on_the_teapot() {
    let dir = temp_dir();
    let count = |step: &str| {
        let (s, _) = teapot(dir.path(), "teapot.bpt", step);
        let surface = &s["steps"][0]["surface"];
        assert!(surface["max_deviation"].as_f64().unwrap() <= 1e-3 * (1.0 + 1e-9));
        surface["triangles"].as_f64().unwrap()
    };
    let inter = count("mode = \"interpatch\", tolerance = 0.001");
    let adaptive = count("mode = \"adaptive\", tolerance = 0.001");
    assert!(inter / adaptive <= 1.5, "{inter} / {adaptive}");
}

#[test]
fn a_named_patch_set_welds_a_reversed_border() {
    // Two bicubic patches; b's side v0 is a's side u1 run backwards, with heights whose
    // evaluation at t and 1 − t differ in the last bit.
    let bump = [0.0, 0.45, 0.05, 0.3];
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for i in 0..4 {
        for j in 0..4 {
            let z = if i == 3 {
                bump[j]
            } else {
                0.1 * (i * j) as f64
            };
            a.push(format!("[{i}, {j}, {z}]"));
            let z = if j == 0 {
                bump[3 - i]
            } else {
                0.2 * j as f64 * (i as f64 - 1.5)
            };
            b.push(format!("[{}, {}, {z}]", 3 + j, 3 - i as i32));
        }
    }
    let text = format!(
        "[nurbs.a]\ndegree = 3\nsize = [4, 4]\npoints = [{}]\n\n[nurbs.b]\ndegree = 3\nsize = [4, 4]\npoints = [{}]\n\n[nurbs.pair]\npatches = [\"a\", \"b\"]\n\n[start]\nnurbs = {{ surface = \"pair\", mode = \"uniform\", cells = [8, 8] }}\n",
        a.join(", "),
        b.join(", ")
    );
    let dir = temp_dir();
    let s = run_text(dir.path(), "p", &text);
    let mesh = common::read_mesh(&dir.path().join("p.obj"));
    assert_eq!(s["mesh"]["components"], 1);
    assert_eq!(s["mesh"]["manifold"], true);
    // One outline: 6 sides of 8 segments (each patch alone: 4 × 8).
    assert_eq!(s["mesh"]["boundary_edges"], 48);
    assert_eq!(boundary_loops(&mesh), 1);
    assert!(coincident_vertices(&mesh).is_empty());
}

#[test]
fn patch_set_errors_are_located() {
    let dir = temp_dir();
    let two = "[nurbs.a]\ndegree = 1\nsize = [2, 2]\npoints = [[0, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0]]\n\n";
    for (text, location, words) in [
        (
            format!("{two}[nurbs.s]\npatches = [\"a\", \"nope\"]\n\n[start]\nnurbs = {{ surface = \"s\" }}\n"),
            "rules.toml:7:17",
            "no nurbs surface named `nope`",
        ),
        (
            format!("{two}[nurbs.s]\npatches = [\"a\"]\njoins = [[\"a.u9\", \"a.u0\"]]\n\n[start]\nnurbs = {{ surface = \"s\" }}\n"),
            "rules.toml:8:11",
            "unknown side `u9`",
        ),
        (
            format!("{two}[nurbs.s]\npatches = [\"a\"]\ndegree = 3\n\n[start]\nnurbs = {{ surface = \"s\" }}\n"),
            "rules.toml:8:10",
            "a patch set takes `patches` and `joins` only",
        ),
        (
            "[nurbs.s]\npatches = \"missing.bpt\"\n\n[start]\nnurbs = { surface = \"s\" }\n".to_owned(),
            "rules.toml:2:11",
            "cannot import",
        ),
    ] {
        common::assert_located_error(dir.path(), &text, location, words);
    }
    // A malformed patch file: its own file:line:column, exit 2, no output.
    let bad = format!("1\n3 3\n0 0 0\n1 0 x\n{}", "0 0 0\n".repeat(14));
    std::fs::write(dir.path().join("bad.bpt"), bad).unwrap();
    std::fs::write(
        dir.path().join("r.toml"),
        "[nurbs.s]\npatches = \"bad.bpt\"\n\n[start]\nnurbs = { surface = \"s\" }\n",
    )
    .unwrap();
    let o = graftal_in(dir.path(), &["run", "r.toml", "-o", "out.obj"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("bad.bpt:4:5"), "{err}");
    assert!(!dir.path().join("out.obj").exists());
}

#[test]
fn nurbs_part_places_a_patch_set() {
    // A 2 × 1 grid's two faces each get a teapot, tessellated once and placed.
    let dir = temp_dir();
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("rules/teapot.bpt"),
        dir.path().join("teapot.bpt"),
    )
    .unwrap();
    let text = "[nurbs.teapot]\npatches = \"teapot.bpt\"\n\n[start]\ngrid = { segments = [2, 1], size = [2, 1] }\n\n[[step]]\nname = \"pots\"\nnurbs_part = { surface = \"teapot\", mode = \"uniform\", cells = [4, 4] }\n";
    let s = run_text(dir.path(), "p", text);
    let one = 32 * 32 - 8 * 4;
    assert_eq!(surface_of(&s, "pots")["triangles"], 2 * one);
    // The grid and two teapots of 4 sheets each.
    assert_eq!(s["mesh"]["components"], 1 + 2 * 4);
    assert_eq!(s["mesh"]["non_manifold_vertices"], 0);
}
