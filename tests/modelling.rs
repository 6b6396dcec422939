//! The modelling operators of issue 35 from rule files: `subdivide`,
//! `crease`, `solidify`, `spin`, `convex_hull` (against qhull:
//! `tests/qhull`). Their geometry is checked against Blender by
//! `tests/blender/` (`make test-blender`) and in the kernel's unit tests;
//! here: the rule-file surface (parameters, parts and materials, located
//! errors, determinism) and the documentation's pictures.

mod common;

use std::path::Path;

use common::{graftal, graftal_in, stderr, stdout};

fn stats(dir: &Path, rules: &str) -> serde_json::Value {
    std::fs::write(dir.join("r.toml"), rules).unwrap();
    let o = graftal_in(dir, &["run", "r.toml", "-o", "r.glb", "--stats", "-"]);
    assert!(o.status.success(), "{}\n{rules}", stderr(&o));
    serde_json::from_str(&stdout(&o)).unwrap()
}

fn counts(s: &serde_json::Value) -> (u64, u64, u64) {
    let m = &s["mesh"];
    (
        m["vertices"].as_u64().unwrap(),
        m["edges"].as_u64().unwrap(),
        m["faces"].as_u64().unwrap(),
    )
}

#[test]
fn subdivide_and_solidify_give_the_issues_counts() {
    let d = tempfile::tempdir().unwrap();
    let cube = stats(
        d.path(),
        "[start]\ncube = {}\n[[step]]\nsubdivide = { levels = 2 }\n",
    );
    assert_eq!(counts(&cube), (98, 192, 96));
    assert_eq!(cube["mesh"]["watertight"], true);
    let grid = stats(
        d.path(),
        "[start]\ngrid = { segments = [4, 4] }\n[[step]]\nsolidify = { thickness = 0.1 }\n",
    );
    assert_eq!(counts(&grid), (50, 96, 48));
    assert_eq!(grid["mesh"]["watertight"], true);
    assert_eq!(grid["mesh"]["manifold"], true);
    // Loop on triangles: every triangle into four.
    let loop_ = stats(
        d.path(),
        "[start]\ncube = {}\n[[step]]\ntriangulate = {}\n[[step]]\nsubdivide = { scheme = \"loop\", levels = 2 }\n",
    );
    assert_eq!(counts(&loop_).2, 12 * 16);
}

#[test]
fn a_vase_profile_spins_into_a_closed_solid() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(
        d.path().join("profile.obj"),
        "v 0 0 0\nv 0.6 0 0\nv 0.4 0 0.5\nv 0.7 0 1.2\nv 0 0 1.2\nl 1 2 3 4 5\n",
    )
    .unwrap();
    let s = stats(
        d.path(),
        "[start]\nimport = { path = \"profile.obj\" }\n\
         [[step]]\non = \"edges\"\nspin = { steps = 24 }\npart = \"vase\"\n",
    );
    assert_eq!(counts(&s), (2 + 3 * 24, 4 * 24 + 3 * 24, 4 * 24));
    assert_eq!(s["mesh"]["watertight"], true);
    assert_eq!(s["mesh"]["consistently_oriented"], true);
    assert!(s["mesh"]["volume"].as_f64().unwrap() > 0.0, "wound outward");
}

#[test]
fn a_hull_wraps_grown_geometry_and_flat_selections_are_errors() {
    let d = tempfile::tempdir().unwrap();
    // The stool of docs/operators/subdivide-cage.toml, wrapped: its seat's
    // top corners and its legs' outer foot corners span a box, and the
    // points on its sides and edges (exactly coplanar, collinear) are not
    // hull vertices: 8 vertices, 6 quads.
    let rules = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/operators/subdivide-cage.toml"),
    )
    .unwrap()
        + "\n[[step]]\nconvex_hull = {}\nname = \"hull\"\n\
           [[step]]\nfrom = \"hull\"\ninset_faces = { thickness = 0.01 }\n";
    let s = stats(d.path(), &rules);
    let hull = s["steps"]
        .as_array()
        .unwrap()
        .iter()
        .find(|st| st["name"] == "hull")
        .unwrap();
    assert_eq!(hull["created_vertices"], 8, "{hull}");
    assert_eq!(hull["created_faces"], 6, "{hull}");
    // A flat selection: a located run-time error naming why.
    std::fs::write(
        d.path().join("flat.toml"),
        "[start]\ngrid = { segments = [3, 3] }\n[[step]]\nconvex_hull = {}\n",
    )
    .unwrap();
    let o = graftal_in(d.path(), &["run", "flat.toml", "-o", "flat.obj"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("flat.toml:4:1") && stderr(&o).contains("lie in one plane"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn the_pieces_keep_their_part_and_material() {
    let d = tempfile::tempdir().unwrap();
    let rules = r##"
[start]
grid = { segments = [2, 2] }

[[step]]
assign = {}
part = "sheet"
material = "red"

[[step]]
solidify = { thickness = 0.1 }

[[step]]
subdivide = { levels = 1 }

[materials.red]
base_color = "#ff0000"
"##;
    std::fs::write(d.path().join("r.toml"), rules).unwrap();
    let o = graftal_in(d.path(), &["run", "r.toml", "-o", "r.obj"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let obj = std::fs::read_to_string(d.path().join("r.obj")).unwrap();
    // One group and one material for every face of the shell.
    let faces = obj.lines().filter(|l| l.starts_with("f ")).count();
    assert_eq!(faces, (4 + 4 + 8) * 4);
    assert_eq!(
        obj.lines().filter(|l| l.starts_with("usemtl ")).count(),
        1,
        "{obj}"
    );
    assert!(obj.contains("usemtl red"));
    assert!(
        obj.lines().any(|l| l == "g sheet" || l == "o sheet"),
        "{obj}"
    );
}

#[test]
fn creases_are_spent_and_kept_between_steps() {
    let d = tempfile::tempdir().unwrap();
    // A fully creased cube stays a cube through both steps: the second
    // reads what the first left of sharpness 10 (always sharp).
    let s = stats(
        d.path(),
        "[start]\ncube = { size = 2 }\n[[step]]\non = \"edges\"\ncrease = {}\n\
         [[step]]\nsubdivide = {}\n[[step]]\nsubdivide = {}\n",
    );
    assert!(
        (s["mesh"]["volume"].as_f64().unwrap() - 8.0).abs() < 1e-12,
        "{s}"
    );
    // Sharpness 1: sharp in the first step only, so the second rounds.
    let s = stats(
        d.path(),
        "[start]\ncube = { size = 2 }\n[[step]]\non = \"edges\"\ncrease = { sharpness = 1 }\n\
         [[step]]\nsubdivide = {}\n[[step]]\nsubdivide = {}\n",
    );
    let v = s["mesh"]["volume"].as_f64().unwrap();
    assert!(v < 8.0 - 1e-3, "{v}");
    // And by angle, without any crease step.
    let s = stats(
        d.path(),
        "[start]\ncube = { size = 2 }\n[[step]]\nsubdivide = { levels = 2, crease_angle = 30 }\n",
    );
    assert!((s["mesh"]["volume"].as_f64().unwrap() - 8.0).abs() < 1e-12);
}

#[test]
fn bad_uses_are_located_errors_with_no_output() {
    let d = tempfile::tempdir().unwrap();
    // Checked before the run: a literal out of bounds.
    for (text, words) in [
        (
            "[start]\ncube = {}\n[[step]]\nsubdivide = { levels = 9 }\n",
            "levels",
        ),
        (
            "[start]\ncube = {}\n[[step]]\nsolidify = { thickness = 0.1, offset = 2 }\n",
            "offset",
        ),
        ("[start]\ncube = {}\n[[step]]\nsolidify = {}\n", "thickness"),
        (
            "[start]\ncube = {}\n[[step]]\nsubdivide = { scheme = \"butterfly\" }\n",
            "scheme",
        ),
    ] {
        common::assert_located_error(d.path(), text, "rules.toml:4:", words);
    }
    // Found at run time: Loop on quads, located at the step.
    std::fs::write(
        d.path().join("q.toml"),
        "[start]\ncube = {}\n[[step]]\nsubdivide = { scheme = \"loop\" }\n",
    )
    .unwrap();
    let o = graftal_in(d.path(), &["run", "q.toml", "-o", "q.obj"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("q.toml:4:1") && stderr(&o).contains("triangles only"));
    assert!(!d.path().join("q.obj").exists());
}

#[test]
fn runs_are_byte_identical_at_any_thread_count() {
    let d = tempfile::tempdir().unwrap();
    let rules = "[start]\nuv_sphere = { segments = 12, rings = 6 }\n\
                 [[step]]\non = \"vertices\"\nselect = \"pos.z < -0.01\"\ndelete = {}\n\
                 [[step]]\nsolidify = { thickness = 0.1, even = true, offset = 0 }\n\
                 [[step]]\nsubdivide = { levels = 2 }\n";
    std::fs::write(d.path().join("r.toml"), rules).unwrap();
    let mut outputs = Vec::new();
    for jobs in ["1", "2", "2"] {
        let out = format!("r{}.glb", outputs.len());
        let o = graftal_in(d.path(), &["run", "r.toml", "-o", &out, "-j", jobs]);
        assert!(o.status.success(), "{}", stderr(&o));
        outputs.push(std::fs::read(d.path().join(out)).unwrap());
    }
    assert!(outputs.windows(2).all(|w| w[0] == w[1]));
}

#[test]
fn the_documentation_pictures_rule_files_run() {
    // docs/rules.md shows what these make (docs/operators/*.png).
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/operators");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".toml"))
        .collect();
    names.sort();
    assert!(names.len() >= 5, "{names:?}");
    for name in names {
        let path = format!("docs/operators/{name}");
        let o = graftal(&["check", &path]);
        assert!(o.status.success(), "{path}: {}", stderr(&o));
        let png = format!("{}.png", name.split('-').next().unwrap());
        assert!(dir.join(&png).exists(), "{path}: no {png}");
    }
    for shell in [
        "subdivide-smooth",
        "subdivide-creased",
        "solidify-shell",
        "spin-vase",
    ] {
        let d = tempfile::tempdir().unwrap();
        let rules = std::fs::read_to_string(dir.join(format!("{shell}.toml"))).unwrap();
        let s = stats(d.path(), &rules);
        assert_eq!(s["mesh"]["watertight"], true, "{shell}");
    }
}
