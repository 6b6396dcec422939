//! Signed distance fields from rule files (thesis 004, issue 14): trees
//! compiled and checked with located errors, meshed into the kernel by
//! `sdf`, `sdf_part`, `sdf_boolean` and `skin` with `method = "field"`,
//! closed and byte-identical at any thread count.

mod common;

use std::path::Path;

use common::{graftal, graftal_in, grow, stderr, stdout, step, toml};
use graftal::grammar::{run, RunOptions};
use serde_json::Value;

fn temp_dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

fn path_str(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Runs `rules` (written as `dir/rules.toml`) to `dir/out.obj` with JSON
/// stats on stdout.
fn run_in(dir: &Path, rules: &str, extra: &[&str]) -> std::process::Output {
    std::fs::write(dir.join("rules.toml"), rules).unwrap();
    let mut args = vec!["run", "rules.toml", "-o", "out.obj", "--stats", "-"];
    args.extend_from_slice(extra);
    graftal_in(dir, &args)
}

/// The JSON stats printed before the "wrote …" line.
fn stats(o: &std::process::Output) -> Value {
    let text = stdout(o);
    let end = text.rfind('}').expect("stats on stdout");
    serde_json::from_str(&text[..=end]).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

fn field_of<'a>(stats: &'a Value, step: &str) -> &'a Value {
    let steps = stats["steps"].as_array().unwrap();
    let s = steps.iter().find(|s| s["name"] == step).unwrap();
    &s["field"]
}

#[test]
fn sphere_minus_box_is_one_watertight_solid_of_the_right_volume() {
    let dir = temp_dir();
    let out = dir.path().join("part.glb");
    let o = graftal(&[
        "run",
        "rules/sphere-minus-box.toml",
        "-o",
        path_str(&out),
        "--stats",
        "-",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s = stats(&o);
    let mesh = &s["mesh"];
    // 128 cells on [-1.2, 1.2]³ (the peers' workload, ../shared/peers.md).
    assert_eq!(mesh["triangles"], 107_036);
    assert_eq!(mesh["watertight"], true);
    assert_eq!(mesh["consistently_oriented"], true);
    assert_eq!(mesh["components"], 1);
    assert_eq!(mesh["euler_characteristic"], 2);
    assert_eq!(mesh["self_intersecting_face_pairs"], 0);
    assert_eq!(mesh["close_vertex_pairs"], 0);
    let exact = 7.0 / 8.0 * 4.0 / 3.0 * std::f64::consts::PI;
    let volume = mesh["volume"].as_f64().unwrap();
    assert!(
        (volume / exact - 1.0).abs() < 2e-3,
        "volume {volume} vs {exact}"
    );
    let field = field_of(&s, "start");
    // h = 2.4 / 128; the lattice (k + ½)·h widens the domain to 129 cells.
    assert_eq!(field["grid"], serde_json::json!([129, 129, 129]));
    assert_eq!(field["genus"], 0);
    let culled = field["cells_evaluated"].as_u64().unwrap();
    assert!(
        culled * 3 < field["grid_cells"].as_u64().unwrap(),
        "cost follows the surface: {culled} cells evaluated"
    );
}

#[test]
fn trees_take_expressions_distributions_and_shared_names() {
    let text = r#"
        seed = 3
        [params]
        r = { uniform = [0.4, 0.6] }
        [sdf.pair]
        kind = "union"
        children = ["ball", { kind = "translate", offset = [2, 0, 0], child = "ball" }]
        [sdf.ball]
        kind = "sphere"
        radius = "r"
        [start]
        sdf = { tree = "pair", cell = 0.05 }
    "#;
    let out = grow(text);
    let f = step(&out, "start").field.as_ref().expect("field stats");
    assert!(f.watertight);
    assert_eq!(f.components, 2);
    assert_eq!(f.genus, Some(0));
    let r = out.params.iter().find(|(n, _)| n == "r").unwrap().1;
    assert!((0.4..=0.6).contains(&r));
    let exact = 2.0 * 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
    assert!(
        (f.volume / exact - 1.0).abs() < 0.02,
        "{} vs {exact}",
        f.volume
    );
    // Another seed draws another radius, so another volume.
    let p = toml(&text.replace("seed = 3", "seed = 4"));
    let other = run(&p, &RunOptions::default()).unwrap();
    let g = step(&other, "start").field.as_ref().unwrap();
    assert_ne!(g.volume, f.volume);
}

/// Each case: a rule file, the place of the error and words of its message.
const BAD_TREES: &[(&str, &str, &str)] = &[
    (
        "[start]\nsdf = { tree = { kind = \"spere\", radius = 1 } }\n",
        "rules.toml:2:25",
        "did you mean `sphere`",
    ),
    (
        "[start]\nsdf = { tree = { kind = \"sphere\", raduis = 1 } }\n",
        "rules.toml:2:35",
        "`raduis`",
    ),
    (
        "[start]\nsdf = { tree = { kind = \"sphere\" } }\n",
        "rules.toml:2:16",
        "missing field `radius` of a `sphere` node",
    ),
    (
        "[start]\nsdf = { tree = { radius = 1 } }\n",
        "rules.toml:2:16",
        "missing field `kind`",
    ),
    (
        "[start]\nsdf = { tree = \"nowhere\" }\n",
        "rules.toml:2:16",
        "nowhere",
    ),
    (
        "[sdf.a]\nkind = \"union\"\nchildren = [\"b\"]\n[sdf.b]\nkind = \"offset\"\ndistance = 1\nchild = \"a\"\n[start]\nsdf = { tree = \"a\" }\n",
        "rules.toml:7:9",
        "contains itself: a → b → a",
    ),
    (
        "[start]\nsdf = { tree = { kind = \"sphere\", radius = 0 } }\n",
        "rules.toml:2:44",
        "`radius` must be positive, got 0",
    ),
    (
        "[start]\nsdf = { tree = { kind = \"smooth_union\", blend = -1, children = [{ kind = \"sphere\", radius = 1 }] } }\n",
        "rules.toml:2:49",
        "`blend` of `smooth_union` must be at least 0",
    ),
    (
        "[sdf.inner]\nkind = \"smooth_union\"\nblend = 0.1\nchildren = [{ kind = \"sphere\", radius = 1 }, { kind = \"sphere\", radius = 1, at = [1, 0, 0] }]\n[start]\nsdf = { tree = { kind = \"smooth_union\", blend = 0.1, children = [\"inner\", { kind = \"sphere\", radius = 1 }] } }\n",
        "rules.toml:6:65",
        "is not exact outside"
    ),
    (
        "[start]\nsdf = { tree = { kind = \"mesh\", path = \"missing.stl\" } }\n",
        "rules.toml:2:40",
        "cannot find ./missing.stl",
    ),
    (
        "[start]\nsdf = { tree = { kind = \"sphere\", radius = 1 }, mesher = \"marching_squares\" }\n",
        "rules.toml:2:58",
        "unknown variant `marching_squares`",
    ),
    (
        "[start]\nvertex = {}\n[[step]]\nskin = { radius = 0.1, blend = 0.2 }\n",
        "rules.toml:4:32",
        "`blend` belongs to `method = \"field\"`",
    ),
];

#[test]
fn bad_trees_are_located_errors_exit_2_with_no_output() {
    let dir = temp_dir();
    for (text, location, words) in BAD_TREES {
        common::assert_located_error(dir.path(), text, location, words);
    }
}

#[test]
fn a_value_drawn_invalid_by_the_seed_fails_the_run_naming_the_node() {
    let dir = temp_dir();
    // The nominal value (1) is valid, so `check` passes; some seeds draw
    // a negative radius.
    let text = "[params]\nr = { uniform = [-1, 3] }\n[sdf.ball]\nkind = \"sphere\"\nradius = \"r\"\n[start]\nsdf = { tree = \"ball\", cell = 0.2 }\n";
    std::fs::write(dir.path().join("rules.toml"), text).unwrap();
    assert_eq!(
        graftal_in(dir.path(), &["check", "rules.toml"])
            .status
            .code(),
        Some(0)
    );
    let (mut good, mut bad) = (0, 0);
    for seed in 0..12 {
        let seed = seed.to_string();
        let o = graftal_in(
            dir.path(),
            &["run", "rules.toml", "-o", "out.obj", "--seed", &seed],
        );
        let err = stderr(&o);
        assert!(!err.contains("panicked"), "{err}");
        if o.status.code() == Some(0) {
            good += 1;
            std::fs::remove_file(dir.path().join("out.obj")).unwrap();
            continue;
        }
        bad += 1;
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains("ball"), "the node is named: {err}");
        assert!(err.contains("radius"), "{err}");
        assert!(!dir.path().join("out.obj").exists(), "no output on error");
    }
    assert!(good > 0 && bad > 0, "{good} good, {bad} bad seeds");
}

#[test]
fn too_many_cells_is_a_limit_exit_3_with_no_output() {
    let dir = temp_dir();
    let text = "[start]\nsdf = { tree = { kind = \"sphere\", radius = 1 }, cells = 4096 }\n";
    let o = run_in(dir.path(), text, &["--max-cells", "1000000"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(
        err.contains("1000000") || err.contains("1,000,000"),
        "{err}"
    );
    assert!(!dir.path().join("out.obj").exists());
    // The same file within the default limit but with a smaller grid runs.
    let o = run_in(dir.path(), &text.replace("4096", "16"), &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

#[test]
fn identical_bytes_at_any_thread_count_and_job_count() {
    let files = common::assert_same_bytes_at_any_thread_and_job_count(
        "rules/brick.toml",
        "brick-{seed}.glb",
        &["--seeds", "0..3"],
    );
    assert_eq!(files, 3);
}

#[test]
fn sdf_part_places_one_closed_copy_per_selected_face() {
    let text = r#"
        [start]
        grid = { segments = [3, 2], size = [3, 2] }
        [[step]]
        name = "balls"
        sdf_part = { tree = { kind = "sphere", radius = 0.3 }, relative = false, cell = 0.05 }
    "#;
    let out = grow(text);
    let f = step(&out, "balls").field.as_ref().unwrap();
    assert_eq!(f.meshings, 1, "meshed once, placed six times");
    assert_eq!(f.instances, 6);
    assert_eq!(f.components, 6);
    assert!(f.watertight);
    let exact = 6.0 * 4.0 / 3.0 * std::f64::consts::PI * 0.027;
    assert!(
        (f.volume / exact - 1.0).abs() < 0.02,
        "{} vs {exact}",
        f.volume
    );
    // The grid's faces are kept; the balls sit on their centres.
    let report = out.mesh.report();
    assert_eq!(report.components, 7);
}

#[test]
fn sdf_boolean_replaces_the_model_by_one_closed_solid() {
    let text = r#"
        [start]
        grid = { segments = [2, 2], size = [2, 2] }
        [[step]]
        name = "slab"
        extrude_region = { keep_original = true, offset = [0, 0, 1] }
        [[step]]
        name = "hole"
        sdf_boolean = { tree = { kind = "cylinder", radius = 0.4, height = 3, at = [0, 0, 0.5] }, operation = "difference", cell = 0.04 }
    "#;
    let out = grow(text);
    let f = step(&out, "hole").field.as_ref().unwrap();
    assert!(f.watertight);
    assert_eq!(f.components, 1);
    assert_eq!(f.genus, Some(1), "a drilled slab is a torus");
    let exact = 4.0 - std::f64::consts::PI * 0.16;
    assert!(
        (f.volume / exact - 1.0).abs() < 0.01,
        "{} vs {exact}",
        f.volume
    );
    let report = out.mesh.report();
    assert!(report.watertight);
    assert_eq!(report.components, 1);
}

#[test]
fn field_skins_are_one_solid_per_connected_skeleton() {
    // A Y: three branches from one node.
    let y = r#"
        [start]
        vertex = { at = [0, 0, 0], radius = 0.1 }
        [[step]]
        name = "trunk"
        create_edge = { heading = [0, 0, 1], up = [1, 0, 0], length = 1, radius = 0.1 }
        [[step]]
        name = "left"
        select = "out_edges == 0"
        create_edge = { relative = true, length = 0.7, radius = 0.8, pitch = 35 }
        [[step]]
        name = "right"
        select = "out_edges == 1 && in_edges == 1"
        create_edge = { relative = true, length = 0.7, radius = 0.8, pitch = -35 }
        [[step]]
        name = "skin"
        skin = { method = "field", cell = 0.02 }
    "#;
    let out = grow(y);
    let f = step(&out, "skin").field.as_ref().unwrap();
    let counts = f.skin.expect("skin counts");
    assert_eq!(counts.skeletons, 1);
    assert_eq!(counts.solids, 1);
    assert_eq!(counts.cavities, 0);
    assert_eq!(f.genus, Some(0));
    assert!(f.watertight);
}

#[test]
fn an_open_mesh_as_a_field_is_a_warning_and_still_meshes_closed() {
    let dir = temp_dir();
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("rules/cupboard-front.obj"),
        dir.path().join("front.obj"),
    )
    .unwrap();
    let text = "[start]\nsdf = { tree = { kind = \"offset\", distance = 0.05, child = { kind = \"mesh\", path = \"front.obj\" } }, cells = 48 }\n";
    let o = run_in(dir.path(), text, &[]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert_eq!(err.matches("warning:").count(), 1, "{err}");
    assert!(err.contains("winding"), "{err}");
    let s = stats(&o);
    assert_eq!(s["mesh"]["watertight"], true);
    let sign = field_of(&s, "start")["sign"].as_array().unwrap();
    assert!(sign[0].as_str().unwrap().contains("winding"), "{sign:?}");
}

#[test]
fn a_mesh_field_reads_the_same_from_obj_and_stl() {
    let dir = temp_dir();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::copy(root.join("rules/tower.obj"), dir.path().join("tower.obj")).unwrap();
    let c = graftal_in(dir.path(), &["convert", "tower.obj", "tower.stl"]);
    assert_eq!(c.status.code(), Some(0), "{}", stderr(&c));
    let mut volumes = Vec::new();
    for file in ["tower.obj", "tower.stl"] {
        let text = format!(
            "[start]\nsdf = {{ tree = {{ kind = \"mesh\", path = \"{file}\" }}, cells = 40 }}\n"
        );
        let o = run_in(dir.path(), &text, &[]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let s = stats(&o);
        assert_eq!(s["mesh"]["watertight"], true);
        let sign = field_of(&s, "start")["sign"][0]
            .as_str()
            .unwrap()
            .to_owned();
        assert!(sign.contains("pseudonormal"), "{sign}");
        volumes.push(s["mesh"]["volume"].as_f64().unwrap());
    }
    // STL stores f32 positions; the fields differ by rounding only.
    assert!((volumes[0] / volumes[1] - 1.0).abs() < 1e-4, "{volumes:?}");
}

#[test]
fn a_parameter_used_only_in_a_tree_is_not_unused() {
    let dir = temp_dir();
    let text = "[params]\nr = 0.5\n[sdf.ball]\nkind = \"sphere\"\nradius = \"r\"\n[start]\nsdf = { tree = \"ball\", cell = 0.1 }\n";
    std::fs::write(dir.path().join("rules.toml"), text).unwrap();
    let o = graftal_in(dir.path(), &["lint", "rules.toml"]);
    let all = format!("{}{}", stdout(&o), stderr(&o));
    assert!(!all.contains("unused"), "{all}");
    assert_eq!(o.status.code(), Some(0), "{all}");
}

#[test]
fn every_node_kind_has_a_row_in_the_rule_reference() {
    let doc = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/rules.md"))
        .unwrap();
    for kind in graftal::rules::sdf_kinds::KINDS {
        assert!(
            doc.contains(&format!("| `{}` |", kind.name)),
            "no row for {}",
            kind.name
        );
    }
}

#[test]
fn the_tree_in_its_box_is_skinned_inside_the_box() {
    let dir = temp_dir();
    let out = dir.path().join("tree.glb");
    let o = graftal(&[
        "run",
        "rules/tree-in-box.toml",
        "-o",
        path_str(&out),
        "--stats",
        "-",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s = stats(&o);
    assert_eq!(
        s["mesh"]["self_intersecting_face_pairs"], 0,
        "the skin never crosses the box"
    );
    assert_eq!(s["mesh"]["close_vertex_pairs"], 0);
    let skin = field_of(&s, "skin");
    assert_eq!(skin["watertight"], true);
    assert_eq!(skin["skeletons"], 1);
    assert_eq!(skin["solids"], 1);
    // The box is [-1, 1]² × [0, 2.2]; the skin is meshed 0.01 inside it.
    let bounds = &s["mesh"]["bounds"];
    assert_eq!(
        bounds,
        &serde_json::json!([[-1.0, -1.0, 0.0], [1.0, 1.0, 2.2]])
    );
}
