//! Issue 39: lossless interchange. What graftal writes it reads back
//! unchanged: converting a file into its own format is a fixed point, and
//! converting between GLB and glTF gives `run`'s own bytes. Every example,
//! every format pair, through the real `convert` command.

mod common;

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use common::{examples, glb_json, graftal_in, read_mesh, stderr};

const FORMATS: [&str; 5] = ["glb", "gltf", "obj", "ply", "stl"];

/// Runs `check` on every example from two threads (the binary is the work;
/// the examples are independent) and returns every failure it reports.
fn each_example(check: impl Fn(&Path, &str) -> Vec<String> + Sync) -> Vec<String> {
    let examples: Vec<PathBuf> = examples();
    let next = AtomicUsize::new(0);
    let failures = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| {
                while let Some(rules) = examples.get(next.fetch_add(1, Ordering::Relaxed)) {
                    let name = rules.file_stem().unwrap().to_str().unwrap();
                    let found = check(rules, name);
                    failures.lock().unwrap().extend(found);
                }
            });
        }
    });
    let mut failures = failures.into_inner().unwrap();
    failures.sort();
    failures
}

fn graftal_ok(dir: &Path, args: &[&str]) {
    let o = graftal_in(dir, args);
    assert!(o.status.success(), "graftal {args:?}: {}", stderr(&o));
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::read(a), std::fs::read(b)) {
        (Ok(x), Ok(y)) => x == y,
        (Err(_), Err(_)) => true,
        _ => false,
    }
}

/// Runs every example to `source`, converts that to every format, and
/// converts each result into its own format again: the second conversion
/// must change no byte (with its `.mtl`, for OBJ).
fn conversions_settle_from(source: &str) {
    let failures = each_example(|rules, name| {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        for sub in ["once", "twice"] {
            std::fs::create_dir(d.join(sub)).unwrap();
        }
        let original = format!("{name}.{source}");
        graftal_ok(d, &["run", rules.to_str().unwrap(), "-o", &original, "-q"]);
        let mut failures = Vec::new();
        for target in FORMATS {
            let once = format!("once/{name}.{target}");
            let twice = format!("twice/{name}.{target}");
            graftal_ok(d, &["convert", &original, &once]);
            graftal_ok(d, &["convert", &once, &twice]);
            let mut same = same_file(&d.join(&once), &d.join(&twice));
            if target == "obj" {
                same &= same_file(
                    &d.join(format!("once/{name}.mtl")),
                    &d.join(format!("twice/{name}.mtl")),
                );
            }
            if !same {
                failures.push(format!(
                    "{name}: {source} → {target}, then {target} → {target} changed bytes"
                ));
            }
        }
        failures
    });
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn converting_glb_output_again_changes_no_byte() {
    conversions_settle_from("glb");
}

#[test]
fn converting_gltf_output_again_changes_no_byte() {
    conversions_settle_from("gltf");
}

#[test]
fn converting_obj_output_again_changes_no_byte() {
    conversions_settle_from("obj");
}

#[test]
fn converting_ply_output_again_changes_no_byte() {
    conversions_settle_from("ply");
}

#[test]
fn converting_stl_output_again_changes_no_byte() {
    conversions_settle_from("stl");
}

/// `convert` between GLB and glTF (and into the same one) writes exactly
/// what `run` writes for the same model: normals, UVs and colours are
/// quantised once, and vertices numbered as the triangles first use them.
#[test]
fn converting_between_glb_and_gltf_gives_runs_own_bytes() {
    let failures = each_example(|rules, name| {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("converted")).unwrap();
        for format in ["glb", "gltf"] {
            let out = format!("{name}.{format}");
            graftal_ok(d, &["run", rules.to_str().unwrap(), "-o", &out, "-q"]);
        }
        let mut failures = Vec::new();
        for (from, to) in [
            ("glb", "gltf"),
            ("gltf", "glb"),
            ("glb", "glb"),
            ("gltf", "gltf"),
        ] {
            let converted = format!("converted/{name}.{to}");
            graftal_ok(d, &["convert", &format!("{name}.{from}"), &converted]);
            if !same_file(&d.join(&converted), &d.join(format!("{name}.{to}"))) {
                failures.push(format!(
                    "{name}: convert {from} → {to} differs from run's {to}"
                ));
            }
        }
        failures
    });
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Each material's `doubleSided` in a GLB, by name.
fn double_sided_by_name(glb: &Path) -> BTreeMap<String, bool> {
    glb_json(glb)["materials"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|m| {
            let name = m["name"].as_str().unwrap().to_string();
            (name, m["doubleSided"].as_bool().unwrap_or(false))
        })
        .collect()
}

/// The oracle, written independently of the writer's linear pass: shells
/// found by a breadth-first walk over edges in a hash map, and a shell is
/// closed when each of its edges is used as often one way as the other.
/// A material is single-sided when all its faces lie on closed shells.
fn expected_double_sided(mesh: &graftal::io::IndexedMesh) -> BTreeMap<String, bool> {
    let polys: Vec<&[u32]> = mesh.polygons().collect();
    let mut uses: HashMap<(u32, u32), Vec<(usize, bool)>> = HashMap::new();
    let mut degenerate = vec![false; polys.len()];
    for (k, p) in polys.iter().enumerate() {
        for i in 0..p.len() {
            let (a, b) = (p[i], p[(i + 1) % p.len()]);
            if a == b {
                degenerate[k] = true;
            } else {
                uses.entry((a.min(b), a.max(b)))
                    .or_default()
                    .push((k, a < b));
            }
        }
    }
    let mut shell = vec![usize::MAX; polys.len()];
    let mut closed_shell = Vec::new();
    for seed in 0..polys.len() {
        if shell[seed] != usize::MAX {
            continue;
        }
        let id = closed_shell.len();
        let mut closed = true;
        let mut queue = vec![seed];
        shell[seed] = id;
        while let Some(k) = queue.pop() {
            closed &= !degenerate[k];
            let p = polys[k];
            for i in 0..p.len() {
                let (a, b) = (p[i], p[(i + 1) % p.len()]);
                let Some(edge) = uses.get(&(a.min(b), a.max(b))) else {
                    continue;
                };
                let forward = edge.iter().filter(|u| u.1).count();
                closed &= 2 * forward == edge.len();
                for &(other, _) in edge {
                    if shell[other] == usize::MAX {
                        shell[other] = id;
                        queue.push(other);
                    }
                }
            }
        }
        closed_shell.push(closed);
    }
    let mut out: BTreeMap<String, bool> = BTreeMap::new();
    for (k, _) in polys.iter().enumerate() {
        if let Some(m) = mesh.polygon_material(k) {
            let open = !closed_shell[shell[k]];
            *out.entry(mesh.materials[m as usize].name.clone())
                .or_insert(false) |= open;
        }
    }
    out
}

/// docs/rules.md, "Materials": single-sided where the material's faces lie
/// on closed, consistently oriented shells, double-sided otherwise. The
/// OBJ keeps the kernel's vertex numbering, so the oracle sees the shells
/// the writer saw.
#[test]
fn materials_are_single_sided_exactly_where_their_faces_lie_on_closed_shells() {
    let decided = Mutex::new(BTreeMap::new());
    let failures = each_example(|rules, name| {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        for format in ["glb", "obj"] {
            let out = format!("{name}.{format}");
            graftal_ok(d, &["run", rules.to_str().unwrap(), "-o", &out, "-q"]);
        }
        let written = double_sided_by_name(&d.join(format!("{name}.glb")));
        let expected = expected_double_sided(&read_mesh(&d.join(format!("{name}.obj"))));
        decided
            .lock()
            .unwrap()
            .insert(name.to_string(), written.clone());
        // Materials no face uses are not in the oracle's map.
        let used: BTreeMap<String, bool> = written
            .into_iter()
            .filter(|(m, _)| expected.contains_key(m))
            .collect();
        if used != expected {
            vec![format!("{name}: written {used:?}, expected {expected:?}")]
        } else {
            Vec::new()
        }
    });
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // The cases: closed models single-sided, open sheets not.
    let decided = decided.into_inner().unwrap();
    for closed in ["chair", "cottage", "tower"] {
        assert!(
            decided[closed].values().all(|&double| !double),
            "{closed}: {:?}",
            decided[closed]
        );
    }
    assert!(decided["flags"]["cloth"]);
    assert!(decided["vase"]["glaze"]);
}

/// The largest distance from a point of `a` to its nearest in `b`.
fn farthest(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .map(|p| {
            b.iter()
                .map(|q| (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt())
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

/// Files made by real tools from `rules/chair.toml`'s GLB (remake them if
/// the chair changes): `gltfpack -cc` (KHR_mesh_quantization and
/// EXT_meshopt_compression with filters, gltfpack 1.3.0) and
/// `gltf-pipeline -d` (KHR_draco_mesh_compression, gltf-pipeline 4.3.1).
/// Each reads back with the chair's triangles, every vertex within half a
/// quantisation step per axis of the original's (positions: 14 bits for
/// gltfpack, 11 for gltf-pipeline, over the model's extent).
/// `make test-compressed-gltf` does the same with the tools themselves on
/// seven examples.
#[test]
fn files_compressed_by_gltfpack_and_gltf_pipeline_read_within_their_quantisation_step() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let chair = Path::new(env!("CARGO_MANIFEST_DIR")).join("rules/chair.toml");
    graftal_ok(
        d,
        &["run", chair.to_str().unwrap(), "-o", "chair.glb", "-q"],
    );
    let original = read_mesh(&d.join("chair.glb"));
    let extent = (0..3)
        .map(|k| {
            let values = original.positions.iter().map(|p| p[k]);
            values.clone().fold(f64::MIN, f64::max) - values.fold(f64::MAX, f64::min)
        })
        .fold(0.0, f64::max);
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    for (file, bits) in [("chair-meshopt.glb", 14), ("chair-draco.glb", 11)] {
        let path = fixtures.join(file);
        let back = read_mesh(&path);
        assert_eq!(back.polygon_count(), original.polygon_count(), "{file}");
        let bound = 3f64.sqrt() / 2.0 * extent / f64::from((1u32 << bits) - 1) * 1.001;
        let distance = farthest(&back.positions, &original.positions)
            .max(farthest(&original.positions, &back.positions));
        assert!(distance <= bound, "{file}: {distance:e} > {bound:e}");
        // The decoded normals are unit and the file converts like any other.
        assert!(!back.corner_normals.is_empty(), "{file}");
        for n in &back.corner_normals {
            let length = n.iter().map(|c| c * c).sum::<f64>().sqrt();
            assert!((length - 1.0).abs() < 1e-6, "{file}: {n:?}");
        }
        graftal_ok(d, &["convert", path.to_str().unwrap(), "decoded.glb"]);

        // Damage in the compressed stream is a reported error or a mesh,
        // never a panic: every 97th byte of the binary chunk flipped.
        let mut bytes = std::fs::read(&path).unwrap();
        let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        for b in bytes[20 + json_len + 8..].iter_mut().step_by(97) {
            *b ^= 0x5a;
        }
        std::fs::write(d.join("damaged.glb"), &bytes).unwrap();
        let o = graftal_in(d, &["convert", "damaged.glb", "damaged.ply"]);
        assert!(
            o.status.success() || o.status.code() == Some(2) || o.status.code() == Some(1),
            "{file}: {:?} {}",
            o.status,
            stderr(&o)
        );
        assert!(!stderr(&o).contains("panicked"), "{file}: {}", stderr(&o));
    }
}
