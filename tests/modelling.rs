//! The modelling operators of issue 35 from rule files: `bevel`,
//! `subdivide`, `crease`, `solidify`, `spin`, `bridge_loops`, `convex_hull` (against qhull:
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
fn bevel_gives_the_issues_counts_and_keeps_parts_and_materials() {
    let d = tempfile::tempdir().unwrap();
    // A cube's 12 edges with 1 segment: 24, 48, 26, as Blender.
    let chamfer = stats(
        d.path(),
        "[start]\ncube = { size = 2 }\n[[step]]\non = \"edges\"\nbevel = { width = 0.2 }\n",
    );
    assert_eq!(counts(&chamfer), (24, 48, 26));
    assert_eq!(chamfer["mesh"]["watertight"], true);
    assert_eq!(chamfer["mesh"]["consistently_oriented"], true);
    let round = stats(
        d.path(),
        "[start]\ncube = { size = 2 }\n[[step]]\non = \"edges\"\nbevel = { width = 0.25, segments = 2 }\n",
    );
    assert_eq!(counts(&round), (56, 108, 54));
    // Parts and materials: the top face's material stays on its
    // replacement; the step's part names what it made.
    let rules = r##"
[start]
cube = { size = 2 }

[[step]]
select = "normal.z > 0.5"
assign = {}
material = "red"

[[step]]
on = "edges"
select = "center.z > 0.5"
bevel = { width = 0.3, segments = 3 }
part = "rounded"

[materials.red]
base_color = "#ff0000"
"##;
    std::fs::write(d.path().join("m.toml"), rules).unwrap();
    let o = graftal_in(d.path(), &["run", "m.toml", "-o", "m.obj"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let obj = std::fs::read_to_string(d.path().join("m.obj")).unwrap();
    assert!(obj.contains("usemtl red"), "{obj}");
    assert!(
        obj.lines().any(|l| l == "g rounded" || l == "o rounded"),
        "{obj}"
    );
    // 6 faces, 4 bands of 3, no corner faces (two bands share a profile).
    assert_eq!(obj.lines().filter(|l| l.starts_with("f ")).count(), 6 + 12);
    // Vertices cut off: a cube's 8 corners give 24 vertices and 14 faces.
    let cut = stats(
        d.path(),
        "[start]\ncube = { size = 2 }\n[[step]]\non = \"vertices\"\nbevel = { width = 0.4 }\n",
    );
    assert_eq!((counts(&cut).0, counts(&cut).2), (24, 14));
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

/// An OBJ of wire loops: for each `(n, radius, z, closed)`, `n` points on
/// a circle (or the first `n` of 12 on it, open).
fn loops_obj(loops: &[(usize, f64, f64, bool)]) -> String {
    let (mut vs, mut ls, mut base) = (String::new(), String::new(), 0);
    for &(n, r, z, closed) in loops {
        let step = if closed { n } else { 12 };
        for i in 0..n {
            let a = std::f64::consts::TAU * i as f64 / step as f64;
            vs += &format!("v {} {} {z}\n", r * a.cos(), r * a.sin());
        }
        let sides = if closed { n } else { n - 1 };
        for i in 0..sides {
            ls += &format!("l {} {}\n", base + i + 1, base + (i + 1) % n + 1);
        }
        base += n;
    }
    vs + &ls
}

#[test]
fn bridge_loops_join_loops_with_twist_segments_and_unequal_counts() {
    let d = tempfile::tempdir().unwrap();
    let run = |obj: &str, args: &str| {
        std::fs::write(d.path().join("loops.obj"), obj).unwrap();
        stats(
            d.path(),
            &format!(
                "[start]\nimport = {{ path = \"loops.obj\" }}\n\
                 [[step]]\non = \"edges\"\nbridge_loops = {args}\npart = \"band\"\n"
            ),
        )
    };
    // 8 and 12 vertices: 8 quads and 4 triangles, 12 rungs; an open tube.
    let unequal = loops_obj(&[(8, 1.0, 0.0, true), (12, 1.5, 1.0, true)]);
    let s = run(&unequal, "{}");
    assert_eq!(counts(&s), (20, 20 + 12, 12));
    assert_eq!(s["mesh"]["triangles"], 8 * 2 + 4);
    assert_eq!(s["mesh"]["manifold"], true);
    assert_eq!(s["mesh"]["consistently_oriented"], true);
    assert_eq!(s["mesh"]["boundary_edges"], 20);
    // Three faces across: two rings of 12 between, three times the faces.
    let s = run(&unequal, "{ segments = 3 }");
    assert_eq!(counts(&s), (20 + 24, 20 + 24 + 36, 36));
    assert_eq!(s["mesh"]["manifold"], true);
    // Equal hexagons one above the other: untwisted, the band is six unit
    // squares; a twist turns every quad.
    let hexagons = loops_obj(&[(6, 1.0, 0.0, true), (6, 1.0, 1.0, true)]);
    let straight = run(&hexagons, "{}");
    assert!((straight["mesh"]["area"].as_f64().unwrap() - 6.0).abs() < 1e-9);
    for twist in ["1", "-1", "\"1 + 1\""] {
        let s = run(&hexagons, &format!("{{ twist = {twist} }}"));
        assert_eq!(counts(&s), (12, 18, 6));
        let area = s["mesh"]["area"].as_f64().unwrap();
        assert!((area - 6.0).abs() > 0.1, "twist {twist}: {area}");
    }
    // Open chains pair end to end.
    let open = loops_obj(&[(4, 1.0, 0.0, false), (4, 1.0, 1.0, false)]);
    let s = run(&open, "{ segments = 2 }");
    assert_eq!(counts(&s), (12, 17, 6));
    // The documentation's vase: 12, 8 and 12 vertices chained in order.
    let vase = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/operators/bridge-vase.toml"),
    )
    .unwrap();
    let s = stats(d.path(), &vase);
    assert_eq!(counts(&s), (56, 104, 48));
    assert_eq!(s["mesh"]["manifold"], true);
    assert_eq!(s["mesh"]["consistently_oriented"], true);

    // Refusals, located at the step, with no output.
    for (obj, args, words) in [
        (
            loops_obj(&[(8, 1.0, 0.0, true)]),
            "{}",
            "at least two loops of selected edges, found 1",
        ),
        (
            loops_obj(&[(8, 1.0, 0.0, true), (4, 1.0, 1.0, false)]),
            "{}",
            "all closed or all open",
        ),
        (
            loops_obj(&[(8, 1.0, 0.0, true), (8, 1.0, 1.0, true)]) + "v 0 0 -1\nl 1 17\n",
            "{}",
            "simple chains or loops",
        ),
        (hexagons.clone(), "{ twist = 0.5 }", "twist"),
        (hexagons.clone(), "{ segments = \"0\" }", "segments"),
    ] {
        std::fs::write(d.path().join("loops.obj"), &obj).unwrap();
        std::fs::write(
            d.path().join("b.toml"),
            format!(
                "[start]\nimport = {{ path = \"loops.obj\" }}\n\
                 [[step]]\non = \"edges\"\nbridge_loops = {args}\n"
            ),
        )
        .unwrap();
        let o = graftal_in(d.path(), &["run", "b.toml", "-o", "b.obj"]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args}: {err}");
        assert!(err.contains("b.toml:5:1") && err.contains(words), "{err}");
        assert!(!d.path().join("b.obj").exists());
    }
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
fn a_wall_cut_by_windows_and_a_drill_has_the_volume_and_genus_it_should() {
    let d = tempfile::tempdir().unwrap();
    let rules = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/operators/boolean-cut.toml"),
    )
    .unwrap();
    let s = stats(d.path(), &rules);
    let m = &s["mesh"];
    assert_eq!(m["watertight"], true);
    assert_eq!(m["components"], 1);
    // Three holes through one solid: V - E + F = 2 - 2 * 3.
    assert_eq!(m["euler_characteristic"], -4, "{m}");
    // A 4 x 0.3 x 2.5 slab less two 0.8 x 1.1 windows and a 24-gon of
    // radius 0.35, each 0.3 deep.
    let polygon = 12.0 * 0.35f64 * 0.35 * (15f64).to_radians().sin();
    let expected = 3.0 - 0.3 * (2.0 * 0.8 * 1.1 + polygon);
    let volume = m["volume"].as_f64().unwrap();
    assert!((volume - expected).abs() < 1e-12, "{volume} {expected}");
    // Union: the ball keeps its material where it stands out of the box.
    let rules = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/operators/boolean-union.toml"),
    )
    .unwrap();
    std::fs::write(d.path().join("u.toml"), &rules).unwrap();
    let o = graftal_in(d.path(), &["run", "u.toml", "-o", "u.obj"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let obj = std::fs::read_to_string(d.path().join("u.obj")).unwrap();
    assert!(obj.contains("usemtl brass"), "{obj}");
    // Boxes touching on part of a face: computed exactly, fused into one
    // closed solid (the exact path; the general-position one refuses).
    let s = stats(
        d.path(),
        "[start]\ncube = {}\n[[step]]\nname = \"b\"\ncube = {}\npart = \"b\"\n\
         [[step]]\nfrom = \"b\"\non = \"vertices\"\ntranslate = { offset = [2, 1, 1] }\n\
         [[step]]\nboolean = { operation = \"union\", with = \"b\" }\n",
    );
    let m = &s["mesh"];
    assert_eq!(m["watertight"], true, "{m}");
    assert_eq!(m["manifold"], true, "{m}");
    assert_eq!(m["components"], 1, "{m}");
    assert_eq!(m["euler_characteristic"], 2, "{m}");
    // Two cubes of side 2 meeting on a 1 x 1 square of the face x = 1.
    assert!((m["volume"].as_f64().unwrap() - 16.0).abs() < 1e-12, "{m}");
    // An open operand: how many boundary edges.
    std::fs::write(
        d.path().join("o.toml"),
        "[start]\ngrid = {}\n[[step]]\nname = \"b\"\ncube = {}\npart = \"b\"\n\
         [[step]]\nboolean = { with = \"b\" }\n",
    )
    .unwrap();
    let o = graftal_in(d.path(), &["run", "o.toml", "-o", "o.obj"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("o.toml:8:1") && stderr(&o).contains("4 boundary edges"),
        "{}",
        stderr(&o)
    );
    // A cutter's part named as the rule file is the default part: the error says so.
    std::fs::write(
        d.path().join("drill.toml"),
        "[start]\ncube = {}\n[[step]]\ncube = { size = 0.5 }\npart = \"drill\"\n\
         [[step]]\nboolean = { with = \"drill\" }\n",
    )
    .unwrap();
    let o = graftal_in(d.path(), &["run", "drill.toml", "-o", "d.obj"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("is the default part") && stderr(&o).contains("another name"),
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
    for (text, words) in [
        (
            "[start]\ncube = {}\n[[step]]\non = \"edges\"\nbevel = { width = 0.1, segments = 0 }\n",
            "segments",
        ),
        (
            "[start]\ncube = {}\n[[step]]\non = \"edges\"\nbevel = { width = 0.1, profile = 1.5 }\n",
            "profile",
        ),
        (
            "[start]\ncube = {}\n[[step]]\non = \"edges\"\nbevel = { width = 0.1, offset_type = \"miter\" }\n",
            "offset_type",
        ),
        ("[start]\ncube = {}\n[[step]]\non = \"edges\"\nbevel = {}\n", "width"),
    ] {
        common::assert_located_error(d.path(), text, "rules.toml:5:", words);
    }
    // Found at run time: a vertex bevel measured across a band, located
    // at the step, and nothing written.
    std::fs::write(
        d.path().join("v.toml"),
        "[start]\ncube = {}\n[[step]]\non = \"vertices\"\nbevel = { width = 0.1, offset_type = \"width\" }\n",
    )
    .unwrap();
    let o = graftal_in(d.path(), &["run", "v.toml", "-o", "v.obj"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("v.toml:5:1") && stderr(&o).contains("offset_type"),
        "{}",
        stderr(&o)
    );
    assert!(!d.path().join("v.obj").exists());
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
        "bevel-chamfer",
        "bevel-round",
        "bevel-top",
        "subdivide-smooth",
        "subdivide-creased",
        "solidify-shell",
        "spin-vase",
        "boolean-cut",
        "boolean-union",
    ] {
        let d = tempfile::tempdir().unwrap();
        let rules = std::fs::read_to_string(dir.join(format!("{shell}.toml"))).unwrap();
        let s = stats(d.path(), &rules);
        assert_eq!(s["mesh"]["watertight"], true, "{shell}");
    }
}

/// The wall's windows are flush with both of its faces and the cup's
/// handle lies in the lathe's seam plane: touching contacts, on the exact
/// path. Every seed: one closed solid of the right genus whose faces do
/// not cross (rounding the exact points must not fold a triangle over).
#[test]
fn touching_examples_come_out_closed_and_without_crossing_faces() {
    let d = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (example, seeds, euler) in [("wall", 0..10, -4), ("cup", 0..4, 0)] {
        let rules = std::fs::read_to_string(root.join(format!("rules/{example}.toml"))).unwrap();
        std::fs::write(d.path().join("r.toml"), &rules).unwrap();
        for seed in seeds {
            let o = graftal_in(
                d.path(),
                &[
                    "run",
                    "r.toml",
                    "--seed",
                    &seed.to_string(),
                    "-o",
                    "r.ply",
                    "--stats",
                    "-",
                ],
            );
            assert!(o.status.success(), "{}", stderr(&o));
            let s: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
            let m = &s["mesh"];
            assert_eq!(m["watertight"], true, "{example} {seed}: {m}");
            assert_eq!(m["components"], 1, "{example} {seed}: {m}");
            assert_eq!(m["euler_characteristic"], euler, "{example} {seed}: {m}");
            assert_eq!(
                m["self_intersecting_face_pairs"], 0,
                "{example} {seed}: {m}"
            );
        }
    }
}
