//! Issue 16: files that are assets — parts, materials, shading normals,
//! texture coordinates, their round trips through `convert`, and
//! previews.

mod common;

use std::path::Path;

use common::{assert_located_error, glb_json, graftal_in, read_mesh, stderr};
use serde_json::Value;

/// A cube body with a roof grown from its top, each its own part.
const HOUSE: &str = r##"
[materials.wood]
base_color = "#8b5a2b"
roughness = 0.8

[materials.tiles]
base_color = [0.5, 0.1, 0.1]
metallic = 0.2

[parts.body]
material = "wood"
uv = { projection = "box", size = 0.5 }

[parts.roof]
material = "tiles"
normals = { crease = 60 }

[start]
cube = { size = 2 }
part = "body"

[[step]]
select = "normal.z > 0.5"
extrude_faces = { offset = [0, 0, 1] }
part = "roof"

[[step]]
name = "chimney"
select = "normal.z > 0.5"
inset_faces = { thickness = 0.3 }
"##;

fn run_in(dir: &Path, rules: &str, out: &str) {
    std::fs::write(dir.join("house.toml"), rules).unwrap();
    let o = graftal_in(dir, &["run", "house.toml", "-o", out]);
    assert!(o.status.success(), "{}", stderr(&o));
}

fn names(json: &Value, key: &str) -> Vec<String> {
    json[key]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["name"].as_str().unwrap().to_owned())
        .collect()
}

#[test]
fn parts_become_named_nodes_with_their_materials() {
    let dir = tempfile::tempdir().unwrap();
    run_in(dir.path(), HOUSE, "house.glb");
    let json = glb_json(&dir.path().join("house.glb"));
    // Program order: the default part (unused here), body, roof.
    assert_eq!(names(&json, "nodes"), ["body", "roof"]);
    assert_eq!(names(&json, "meshes"), ["body", "roof"]);
    // Materials in name order (TOML keeps no table order; RON gives the same).
    assert_eq!(names(&json, "materials"), ["tiles", "wood"]);
    let wood = &json["materials"][1];
    let pbr = &wood["pbrMetallicRoughness"];
    // sRGB #8b = 139 → linear 0.2581.
    let r = pbr["baseColorFactor"][0].as_f64().unwrap();
    assert!((r - 0.258_182_9).abs() < 1e-6, "{r}");
    assert_eq!(pbr["roughnessFactor"].as_f64().unwrap() as f32, 0.8);
    // Body and roof together are one closed shell: neither material's
    // faces close on their own, but back faces are never seen, so both are
    // single-sided (docs/rules.md, "Materials").
    assert_eq!(wood["doubleSided"], false);
    assert_eq!(json["materials"][0]["doubleSided"], false);
    let body = &json["meshes"][0]["primitives"][0];
    assert_eq!(body["material"], 1);
    assert!(body["attributes"]["TEXCOORD_0"].is_number(), "box UVs");
    let roof = &json["meshes"][1]["primitives"][0];
    assert_eq!(roof["material"], 0);
    // UVs are all-or-nothing over the file: the roof's are zeros.
    assert!(roof["attributes"]["TEXCOORD_0"].is_number());
}

#[test]
fn a_closed_part_is_single_sided_and_smooth_normals_share_vertices() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = |normals: &str| {
        format!("normals = {normals}\n[start]\nuv_sphere = {{ segments = 16, rings = 8 }}\n")
    };
    let count = |rules: &str| {
        run_in(dir.path(), rules, "s.glb");
        let json = glb_json(&dir.path().join("s.glb"));
        assert_eq!(json["materials"][0]["name"], "graftal_default");
        assert_eq!(
            json["materials"][0]["doubleSided"], false,
            "closed: one side"
        );
        json["accessors"][0]["count"].as_u64().unwrap()
    };
    let smooth = count(&sphere("\"smooth\""));
    let flat = count(&sphere("\"flat\""));
    // 16 × 7 ring vertices and 2 poles: smooth shares every one.
    assert_eq!(smooth, 16 * 7 + 2);
    assert!(flat > 3 * smooth, "flat splits per face: {flat}");
}

#[test]
fn parts_materials_normals_and_uvs_survive_convert() {
    let dir = tempfile::tempdir().unwrap();
    run_in(dir.path(), HOUSE, "house.glb");
    let d = dir.path();
    for (from, to) in [
        ("house.glb", "a.obj"),
        ("a.obj", "b.glb"),
        ("b.glb", "c.ply"),
        ("house.glb", "d.gltf"),
    ] {
        let o = graftal_in(d, &["convert", from, to]);
        assert!(o.status.success(), "{from} → {to}: {}", stderr(&o));
    }
    let original = read_mesh(&d.join("house.glb"));
    assert_eq!(original.parts, ["body", "roof"]);
    // OBJ keeps parts, materials (through the .mtl), normals and UVs.
    let mtl = std::fs::read_to_string(d.join("a.mtl")).unwrap();
    assert!(mtl.contains("newmtl wood\nKd 0.258"), "{mtl}");
    let obj = std::fs::read_to_string(d.join("a.obj")).unwrap();
    assert!(obj.starts_with("# graftal\nmtllib a.mtl\n"), "{obj:.40}");
    let back = read_mesh(&d.join("b.glb"));
    assert_eq!(back.parts, original.parts);
    assert_eq!(back.materials.len(), 2);
    // OBJ numbers materials by first `usemtl`: compare by name.
    let material_of = |m: &graftal::io::IndexedMesh, k: usize| {
        m.materials[m.polygon_materials[k] as usize].name.clone()
    };
    for k in 0..original.polygon_count() {
        assert_eq!(material_of(&original, k), material_of(&back, k));
    }
    for a in &original.materials {
        let b = back.materials.iter().find(|b| b.name == a.name).unwrap();
        for (x, y) in a.base_color.iter().zip(&b.base_color) {
            assert!((x - y).abs() < 1e-6, "{a:?} {b:?}");
        }
        assert!((a.roughness - b.roughness).abs() < 1e-6);
        assert_eq!(a.double_sided, b.double_sided);
    }
    assert_eq!(back.polygon_parts, original.polygon_parts);
    assert_eq!(back.corner_uvs.len(), original.corner_uvs.len());
    for (a, b) in original.corner_uvs.iter().zip(&back.corner_uvs) {
        assert!((a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6);
    }
    for (a, b) in original.corner_normals.iter().zip(&back.corner_normals) {
        let dot: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
        assert!(dot > 1.0 - 1e-6);
    }
    // PLY keeps the parts (names in comments, an index per face).
    let ply = read_mesh(&d.join("c.ply"));
    assert_eq!(ply.parts, original.parts);
    assert_eq!(ply.polygon_parts, original.polygon_parts);
    // .gltf as .glb.
    let gltf = read_mesh(&d.join("d.gltf"));
    assert_eq!(gltf, original);
}

#[test]
fn steps_in_a_compound_inherit_its_part() {
    let dir = tempfile::tempdir().unwrap();
    let rules = r#"
[compound.tower]
on = "faces"
[[compound.tower.step]]
extrude_faces = { offset = [0, 0, 1] }
[[compound.tower.step]]
select = "normal.z > 0.5"
extrude_faces = { offset = [0, 0, 0.5] }
part = "cap"

[start]
grid = { segments = [2, 1], size = [2, 1] }

[[step]]
select = "center.x > 0"
compound = "tower"
part = "tower"
"#;
    run_in(dir.path(), rules, "t.obj");
    let mesh = read_mesh(&dir.path().join("t.obj"));
    // Parts are numbered as the file first names them: the compound's
    // definition comes before its call.
    assert_eq!(mesh.parts, ["house", "cap", "tower"]);
    let faces_of = |p: u32| mesh.polygon_parts.iter().filter(|&&q| q == p).count();
    // The grid's two cells stay in the default part; the first extrusion
    // gives the tower its 4 sides (and the moved top, which the cap step
    // extrudes again: 4 more sides and the new top).
    let counts = [faces_of(0), faces_of(1), faces_of(2)];
    // The untouched cell stays in the default part; the tower's first
    // extrusion makes its 4 sides; the cap extrudes the moved top again:
    // 4 sides and the top itself.
    assert_eq!(counts, [1, 5, 4], "house, cap, tower");
}

#[test]
fn bad_looks_are_located_errors() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "[start]\ncube = {}\nmaterial = \"wod\"\n[materials.wood]\n",
            "rules.toml:3:12",
            "no material named `wod`",
        ),
        (
            "[materials.wood]\nbase_color = \"#12345\"\n[start]\ncube = {}\n",
            "rules.toml:2:14",
            "sRGB hex colour",
        ),
        (
            "[materials.wood]\nroughnes = 0.5\n[start]\ncube = {}\n",
            "rules.toml:2:1",
            "did you mean `roughness`?",
        ),
        (
            "[materials.wood]\nmetallic = 2\n[start]\ncube = {}\n",
            "rules.toml:2:12",
            "outside [0, 1]",
        ),
        (
            "normals = { crease = 200 }\n[start]\ncube = {}\n",
            "rules.toml:1:22",
            "from 0 (flat) to 180",
        ),
        (
            "uv = { projection = \"sphere\" }\n[start]\ncube = {}\n",
            "rules.toml:1:21",
            "unknown projection `sphere`",
        ),
        (
            "[start]\ncube = {}\npart = \"my part\"\n",
            "rules.toml:3:8",
            "not a valid part name",
        ),
        (
            "[start]\ncube = {}\n[[step]]\ntranslate = { offset = [0, 0, 1] }\npart = \"top\"\n",
            "rules.toml:5:8",
            "creates no faces",
        ),
        (
            "[start]\ncube = {}\n[[step]]\nassign = {}\n",
            "rules.toml:4:1",
            "`assign` changes nothing without `part` or `material`",
        ),
        (
            "[materials.glass]\nalpha_cutoff = 0.3\n[start]\ncube = {}\n",
            "rules.toml:2:16",
            "only to alpha_mode = \"mask\"",
        ),
    ];
    for (text, location, words) in cases {
        assert_located_error(dir.path(), text, location, words);
    }
}

#[test]
fn previews_are_deterministic_pngs_of_rule_and_mesh_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("house.toml"), HOUSE).unwrap();
    let mut images = Vec::new();
    for (input, out) in [
        ("house.toml", "a.png"),
        ("house.toml", "b.png"),
        ("house.glb", "c.png"),
    ] {
        if input.ends_with(".glb") {
            let o = graftal_in(d, &["run", "house.toml", "-o", "house.glb"]);
            assert!(o.status.success());
        }
        let o = graftal_in(d, &["preview", input, "-o", out, "--size", "96"]);
        assert!(o.status.success(), "{}", stderr(&o));
        images.push(std::fs::read(d.join(out)).unwrap());
    }
    assert_eq!(images[0], images[1], "same input, same bytes");
    let decode = |bytes: &[u8]| {
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes.to_vec()));
        let mut reader = decoder.read_info().unwrap();
        let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut pixels).unwrap();
        assert_eq!((info.width, info.height), (96, 96));
        pixels
    };
    let pixels = decode(&images[0]);
    // The GLB holds f32 values: the same picture within rounding.
    let from_glb = decode(&images[2]);
    let differ = pixels
        .iter()
        .zip(&from_glb)
        .filter(|(a, b)| a.abs_diff(**b) > 2)
        .count();
    assert!(differ < pixels.len() / 100, "{differ} channels differ");
    // The wood colour shows somewhere: a pixel redder than it is blue.
    assert!(pixels
        .chunks(4)
        .any(|p| i32::from(p[0]) > i32::from(p[2]) + 20));
    // Not a PNG name, and a rule file's seed on a mesh: exit 2, no file.
    for args in [
        &["preview", "house.toml", "-o", "x.jpg"][..],
        &["preview", "house.glb", "-o", "x.png", "--seed", "3"],
    ] {
        let o = graftal_in(d, args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
    }
    assert!(!d.join("x.png").exists() && !d.join("x.jpg").exists());
}

#[test]
fn colour_expressions_paint_faces_and_survive_ply_and_gltf() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Bottom red (hue 0), top cyan-ish (hue 0.5): by the face centre's height.
    let rules = r#"
color = { hsv = ["(center.z > 0) * 0.5", 1, 1] }
[start]
cube = { size = 2 }
"#;
    run_in(d, rules, "c.glb");
    let json = glb_json(&d.join("c.glb"));
    let primitive = &json["meshes"][0]["primitives"][0];
    assert!(primitive["attributes"]["COLOR_0"].is_number());
    // The fallback material turns white so COLOR_0 shows as computed.
    let base = &json["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"];
    assert_eq!(base[0], 1.0);
    let mesh = read_mesh(&d.join("c.glb"));
    let top = (0..mesh.polygon_count())
        .find(|&k| {
            mesh.polygon(k)
                .iter()
                .all(|&v| mesh.positions[v as usize][2] > 0.0)
        })
        .unwrap();
    let c = mesh.corner_colors[mesh.face_starts[top] as usize];
    assert!(
        c[0] < 1e-6 && (c[1] - 1.0).abs() < 1e-6 && (c[2] - 1.0).abs() < 1e-6,
        "{c:?}"
    );
    {
        let (to, back) = ("c.ply", "d.glb");
        assert!(graftal_in(d, &["convert", "c.glb", to]).status.success());
        assert!(graftal_in(d, &["convert", to, back]).status.success());
        let again = read_mesh(&d.join(back));
        // PLY stores sRGB bytes: equal within a byte's step.
        let mut original: Vec<[u32; 3]> = mesh
            .corner_colors
            .iter()
            .map(|c| c.map(|x| (graftal::geom::material::linear_to_srgb(x) * 255.0).round() as u32))
            .collect();
        let mut read: Vec<[u32; 3]> = again
            .corner_colors
            .iter()
            .map(|c| c.map(|x| (graftal::geom::material::linear_to_srgb(x) * 255.0).round() as u32))
            .collect();
        original.sort();
        read.sort();
        assert_eq!(original, read);
    }
    assert_located_error(
        d,
        "color = { hsl = [0, 1, 1] }\n[start]\ncube = {}\n",
        "rules.toml:1:11",
        "unknown field `hsl` of color",
    );
    assert_located_error(
        d,
        "color = { rgb = [0, 1] }\n[start]\ncube = {}\n",
        "rules.toml:1:17",
        "3 channels",
    );
    assert_located_error(
        d,
        "color = { rgb = [\"lenght\", 1, 1] }\n[start]\ncube = {}\n",
        "rules.toml:1:19",
        "lenght",
    );
}

#[test]
fn skeletons_show_as_tubes_or_go() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rules = r#"
[start]
vertex = {}

[[step]]
name = "trunk"
on = "verts"
create_edge = { heading = [0, 0, 1], up = [1, 0, 0], length = 1 }

[[step]]
name = "branch"
from = "trunk"
on = "verts"
create_edge = { heading = [1, 0, 1], up = [0, 0, 1], length = 0.5 }
"#;
    std::fs::write(d.join("s.toml"), rules).unwrap();
    // Lines by default: STL cannot hold them and says so.
    let o = graftal_in(d, &["run", "s.toml", "-o", "lines.stl"]);
    assert!(stderr(&o).contains("--skeleton tubes"), "{}", stderr(&o));
    // Tubes: closed hexagonal prisms, 20 triangles per edge, no warning.
    let o = graftal_in(d, &["run", "s.toml", "-o", "t.stl", "--skeleton", "tubes"]);
    assert!(
        o.status.success() && !stderr(&o).contains("warning"),
        "{}",
        stderr(&o)
    );
    let tubes = read_mesh(&d.join("t.stl"));
    assert_eq!(tubes.polygon_count(), 2 * 20);
    let o = graftal_in(
        d,
        &[
            "run",
            "s.toml",
            "-o",
            "t.glb",
            "--skeleton",
            "tubes",
            "--tube-radius",
            "0.05",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let json = glb_json(&d.join("t.glb"));
    assert_eq!(names(&json, "materials"), ["skeleton"]);
    let max = json["accessors"][0]["max"][0].as_f64().unwrap();
    // The branch ends at x = 0.5·√½ ≈ 0.354, plus at most the radius.
    assert!(max > 0.354 && max < 0.354 + 0.051, "{max}");
    // Omitted: no lines left in the OBJ.
    let o = graftal_in(d, &["run", "s.toml", "-o", "o.obj", "--skeleton", "omit"]);
    assert!(o.status.success());
    let obj = std::fs::read_to_string(d.join("o.obj")).unwrap();
    assert!(!obj.contains("\nl "), "{obj}");
}

#[test]
fn nurbs_parts_carry_their_surface_parameters_as_uvs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = common::graftal(&[
        "run",
        "rules/vase.toml",
        "-o",
        d.join("vase.glb").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json = glb_json(&d.join("vase.glb"));
    let attributes = &json["meshes"][0]["primitives"][0]["attributes"];
    assert!(attributes["TEXCOORD_0"].is_number());
    // The parameters leave as texture coordinates only.
    assert!(attributes.get("_SURFACE_U").is_none(), "{attributes}");
    let vase = read_mesh(&d.join("vase.glb"));
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for k in 0..vase.polygon_count() {
        let first = vase.face_starts[k] as usize;
        let uvs = &vase.corner_uvs[first..vase.face_starts[k + 1] as usize];
        for c in 0..2 {
            let span = uvs.iter().map(|t| t[c]).fold(f64::MIN, f64::max)
                - uvs.iter().map(|t| t[c]).fold(f64::MAX, f64::min);
            // No triangle stretches across the seam.
            assert!(span < 0.5, "triangle {k}: {uvs:?}");
        }
        for t in uvs {
            for c in 0..2 {
                lo[c] = lo[c].min(t[c]);
                hi[c] = hi[c].max(t[c]);
            }
        }
    }
    // Around the lathe once (the seam's far side at 1), bottom to rim.
    assert!(
        lo[0].abs() < 1e-6 && (hi[0] - 1.0).abs() < 1e-6,
        "{lo:?} {hi:?}"
    );
    assert!(
        lo[1].abs() < 1e-6 && (hi[1] - 1.0).abs() < 1e-6,
        "{lo:?} {hi:?}"
    );
}
