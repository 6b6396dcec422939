//! Tests of the glTF writer and reader.

use super::*;
use crate::io::test_meshes;
use ::gltf::mesh::Mode;

fn p() -> &'static Path {
    Path::new("mesh.glb")
}

fn parse_json(bytes: &[u8]) -> json::Value {
    let json = if bytes.starts_with(b"glTF") {
        split_glb(bytes, p()).unwrap().0
    } else {
        bytes
    };
    serde_json::from_slice(json).unwrap()
}

#[test]
fn base64_round_trip() {
    for len in 0..40usize {
        let data: Vec<u8> = (0..len).map(|i| (i * 37 + 11) as u8).collect();
        let mut s = Vec::new();
        base64_encode(&data, &mut s);
        assert_eq!(s.len(), len.div_ceil(3) * 4);
        assert_eq!(
            base64_decode(std::str::from_utf8(&s).unwrap()).unwrap(),
            data
        );
    }
    let mut s = Vec::new();
    base64_encode(b"graftal", &mut s);
    assert_eq!(s, b"Z3JhZnRhbA==");
    assert!(base64_decode("Z3=JhZ").is_none());
    assert!(base64_decode("Z3J*").is_none());
}

/// Reads a GLB with the gltf crate (no validation: without its `extras` feature gltf-json
/// flags `_RADIUS` as an invalid semantic) and checks accessors.
#[test]
fn glb_reads_back_with_the_gltf_crate() {
    let mesh = test_meshes::cube_with_wire();
    let bytes = encode_glb(&mesh).unwrap();
    assert_eq!(bytes.len() % 4, 0);
    let g = ::gltf::Gltf::from_slice_without_validation(&bytes).unwrap();
    let blob = g.blob.clone().unwrap();
    assert_eq!(blob.len() % 4, 0);
    let doc = &g.document;
    assert_eq!(doc.meshes().count(), 1);
    assert_eq!(doc.nodes().count(), 1);
    assert_eq!(doc.default_scene().unwrap().nodes().count(), 1);
    let prims: Vec<_> = doc.meshes().next().unwrap().primitives().collect();
    assert_eq!(prims.len(), 2);
    assert_eq!(prims[0].mode(), Mode::Triangles);
    assert_eq!(prims[1].mode(), Mode::Lines);

    let reader = prims[0].reader(|_| Some(&blob[..]));
    let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    assert_eq!(positions.len(), 24, "6 quads x 4 duplicated vertices");
    let normals: Vec<[f32; 3]> = reader.read_normals().unwrap().collect();
    for n in &normals {
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-6, "{n:?}");
    }
    // The cube's bottom face, (0, 0, −1) in the Z-up kernel, is −Y in glTF.
    assert_eq!(normals[0], [0.0, -1.0, 0.0]);
    let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
    assert_eq!(indices.len(), 36);
    assert!(indices.iter().all(|&i| i < 24));
    // Triangles face along their normals.
    for t in indices.chunks(3) {
        let [a, b, c] =
            [0, 1, 2].map(|k| DVec3::from_array(positions[t[k] as usize].map(f64::from)));
        let n = DVec3::from_array(normals[t[0] as usize].map(f64::from));
        assert!((b - a).cross(c - a).dot(n) > 0.0);
    }
    let pos_acc = prims[0].get(&::gltf::Semantic::Positions).unwrap();
    // The unit cube [0, 1]³ turned Y-up: y ∈ [0, 1] from z, z ∈ [−1, 0] from −y.
    assert_eq!(pos_acc.min().unwrap(), serde_json::json!([0.0, 0.0, -1.0]));
    assert_eq!(pos_acc.max().unwrap(), serde_json::json!([1.0, 1.0, 0.0]));
    assert_eq!(
        prims[0].indices().unwrap().data_type(),
        ::gltf::accessor::DataType::U16
    );

    let wire = prims[1].reader(|_| Some(&blob[..]));
    let wire_pos: Vec<[f32; 3]> = wire.read_positions().unwrap().collect();
    assert_eq!(
        wire_pos,
        vec![[1.0, 1.0, -1.0], [2.0, 2.0, -2.0]],
        "turned Y-up"
    );
    // Its indices would only count 0, 1: none are written.
    assert!(wire.read_indices().is_none());
    assert!(prims[1].indices().is_none());
    let wire_acc = prims[1].get(&::gltf::Semantic::Positions).unwrap();
    assert_eq!(wire_acc.min().unwrap(), serde_json::json!([1.0, 1.0, -2.0]));
    assert_eq!(wire_acc.max().unwrap(), serde_json::json!([2.0, 2.0, -1.0]));

    // Buffer views: 4-byte aligned, targets set, inside the buffer.
    for view in doc.views() {
        assert_eq!(view.offset() % 4, 0);
        assert!(view.target().is_some());
        assert!(view.offset() + view.length() <= blob.len());
    }

    // The custom attribute is in the JSON on both primitives, as f32 scalars.
    let v = parse_json(&bytes);
    for k in 0..2 {
        let attrs = &v["meshes"][0]["primitives"][k]["attributes"];
        let acc = attrs["_RADIUS"].as_u64().unwrap() as usize;
        assert_eq!(v["accessors"][acc]["type"], "SCALAR");
        assert_eq!(v["accessors"][acc]["componentType"], 5126);
    }
    assert_eq!(v["asset"]["generator"], "graftal");
    assert_eq!(v["asset"]["version"], "2.0");
}

#[test]
fn round_trip_glb_and_gltf() {
    let mesh = test_meshes::cube_with_wire();
    for bytes in [encode_glb(&mesh).unwrap(), encode_gltf(&mesh).unwrap()] {
        assert_eq!(
            bytes,
            if bytes.starts_with(b"glTF") {
                encode_glb(&mesh).unwrap()
            } else {
                encode_gltf(&mesh).unwrap()
            }
        );
        let back = decode(&bytes, p()).unwrap();
        assert_eq!(back.positions.len(), 9, "flat-shaded copies merge back");
        assert_eq!(back.polygon_count(), 12);
        assert_eq!(back.lines.len(), 1);
        let radius = back.vertex_scalar("radius").unwrap();
        for (v, p) in back.positions.iter().enumerate() {
            let original = mesh
                .positions
                .iter()
                .position(|q| (0..3).all(|k| (p[k] - q[k]).abs() < 1e-6))
                .unwrap();
            let expected = mesh.vertex_scalars[0].1[original];
            assert!((radius[v] - expected).abs() < 1e-6);
        }
        let [a, b] = back.lines[0];
        assert_eq!(back.positions[a as usize], [1.0, 1.0, 1.0]);
        assert_eq!(back.positions[b as usize], [2.0, 2.0, 2.0]);
        // Closed surface: every undirected edge twice.
        let mut counts = BTreeMap::new();
        for poly in back.polygons() {
            for k in 0..3 {
                let (a, b) = (poly[k], poly[(k + 1) % 3]);
                *counts.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        assert!(counts.values().all(|&c| c == 2));
    }
}

#[test]
fn gltf_embeds_a_data_uri() {
    let bytes = encode_gltf(&test_meshes::cube_with_wire()).unwrap();
    let v = parse_json(&bytes);
    let uri = v["buffers"][0]["uri"].as_str().unwrap();
    assert!(uri.starts_with(DATA_URI_PREFIX));
    let data = base64_decode(&uri[DATA_URI_PREFIX.len()..]).unwrap();
    assert_eq!(
        data.len() as u64,
        v["buffers"][0]["byteLength"].as_u64().unwrap()
    );
}

#[test]
fn empty_mesh_writes_an_empty_scene() {
    for bytes in [
        encode_glb(&IndexedMesh::new()).unwrap(),
        encode_gltf(&IndexedMesh::default()).unwrap(),
    ] {
        let v = parse_json(&bytes);
        assert_eq!(v["scenes"], serde_json::json!([{}]));
        assert_eq!(v["scene"], 0);
        assert!(v.get("meshes").is_none() && v.get("nodes").is_none());
        assert!(v.get("buffers").is_none());
        assert_eq!(decode(&bytes, p()).unwrap(), IndexedMesh::new());
    }
    // Lines only: one LINES primitive, no surface.
    let mut m = IndexedMesh::new();
    m.positions = vec![[0.0; 3], [1.0, 0.0, 0.0]];
    m.lines.push([1, 0]);
    let bytes = encode_glb(&m).unwrap();
    let v = parse_json(&bytes);
    assert_eq!(v["meshes"][0]["primitives"].as_array().unwrap().len(), 1);
    assert_eq!(v["meshes"][0]["primitives"][0]["mode"], 1);
    let back = decode(&bytes, p()).unwrap();
    assert_eq!(back.lines, vec![[0, 1]]);
    assert_eq!(back.positions, vec![[1.0, 0.0, 0.0], [0.0; 3]]);
}

#[test]
fn awkward_mesh_has_unit_normals_and_no_nan() {
    let mesh = test_meshes::awkward();
    let bytes = encode_glb(&mesh).unwrap();
    let g = ::gltf::Gltf::from_slice_without_validation(&bytes).unwrap();
    let blob = g.blob.clone().unwrap();
    let prim = g
        .document
        .meshes()
        .next()
        .unwrap()
        .primitives()
        .next()
        .unwrap();
    let reader = prim.reader(|_| Some(&blob[..]));
    let normals: Vec<[f32; 3]> = reader.read_normals().unwrap().collect();
    // Corners share a vertex where position and normal agree.
    assert!(!normals.is_empty() && normals.len() <= mesh.face_indices.len());
    for n in &normals {
        assert!(n.iter().all(|c| c.is_finite()));
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-6);
    }
    // The collinear polygon (4th) gets the kernel's up, +Z, which glTF
    // calls +Y.
    assert!(normals.contains(&[0.0, 1.0, 0.0]), "{normals:?}");
    let back = decode(&bytes, p()).unwrap();
    assert_eq!(back.polygon_count() as u64, mesh.triangle_count());
    assert_eq!(back.lines.len(), 2);
    assert_eq!(
        back.vertex_scalars
            .iter()
            .map(|(n, _)| n.as_str())
            .collect::<Vec<_>>(),
        vec!["age", "radius"]
    );
}

#[test]
fn large_meshes_switch_to_u32_indices() {
    let mut m = IndexedMesh::new();
    let n = 70_000u32;
    for i in 0..n {
        m.positions.push([f64::from(i), f64::from(i % 7), 0.0]);
    }
    // A strip: each vertex in three triangles, so the index buffer is not
    // the identity.
    for i in 0..n - 2 {
        m.push_polygon(&[i, i + 1, i + 2]);
    }
    let bytes = encode_glb(&m).unwrap();
    let v = parse_json(&bytes);
    let idx = v["meshes"][0]["primitives"][0]["indices"].as_u64().unwrap() as usize;
    assert_eq!(v["accessors"][idx]["componentType"], 5125);
    let back = decode(&bytes, p()).unwrap();
    assert_eq!(back.polygon_count(), m.polygon_count());
}

#[test]
fn a_soup_is_written_without_an_index_buffer() {
    let mut m = IndexedMesh::new();
    for i in 0..30u32 {
        m.positions
            .push([f64::from(i), f64::from(i % 3), f64::from(i % 5)]);
    }
    for i in 0..10 {
        m.push_polygon(&[3 * i, 3 * i + 1, 3 * i + 2]);
    }
    let bytes = encode_glb(&m).unwrap();
    let v = parse_json(&bytes);
    assert!(v["meshes"][0]["primitives"][0].get("indices").is_none());
    let back = decode(&bytes, p()).unwrap();
    assert_eq!(back.polygon_count(), 10);
    assert_eq!(back.positions.len(), 30);
}

#[test]
fn out_of_range_values_are_rejected() {
    let mut m = test_meshes::cube_with_wire();
    m.positions[0][0] = -1e39;
    assert!(matches!(
        encode_glb(&m),
        Err(IoError::OutOfRange { vertex: 0, .. })
    ));
    let mut m = test_meshes::cube_with_wire();
    m.vertex_scalars[0].1[2] = 1e40;
    let e = encode_gltf(&m).unwrap_err().to_string();
    assert!(e.contains("\"radius\" at vertex 2"), "{e}");
}

/// A tiny hand-written glTF around 4 positions (a unit square in z = 0).
fn square_gltf(mode: u32, extra_root: serde_json::Value) -> Vec<u8> {
    let pos: [f32; 12] = [0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0.];
    let mut uri = DATA_URI_PREFIX.as_bytes().to_vec();
    base64_encode(bytemuck::cast_slice(&pos), &mut uri);
    let uri = String::from_utf8(uri).unwrap();
    let mut v = serde_json::json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": 48, "uri": uri}],
        "bufferViews": [{"buffer": 0, "byteLength": 48}],
        "accessors": [{"bufferView": 0, "count": 4, "componentType": 5126, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": mode}]}],
        "nodes": [{"mesh": 0}],
    });
    for (k, value) in extra_root.as_object().unwrap() {
        v[k] = value.clone();
    }
    serde_json::to_vec(&v).unwrap()
}

#[test]
fn quantized_positions_are_read() {
    // KHR_mesh_quantization as gltfpack writes it: normalized SHORT
    // positions with a stride of 8, scaled back by the node.
    let shorts: [i16; 12] = [0, 0, 0, 0, 32767, 0, 0, 0, 0, 32767, 0, 0];
    let bytes: &[u8] = bytemuck::cast_slice(&shorts);
    let mut uri = DATA_URI_PREFIX.as_bytes().to_vec();
    base64_encode(bytes, &mut uri);
    let doc = |component: u32, normalized: bool, required: &[&str]| {
        serde_json::to_vec(&serde_json::json!({
            "asset": {"version": "2.0"},
            "extensionsUsed": ["KHR_mesh_quantization"],
            "extensionsRequired": required,
            "buffers": [{"byteLength": 24, "uri": String::from_utf8(uri.clone()).unwrap()}],
            "bufferViews": [{"buffer": 0, "byteLength": 24, "byteStride": 8}],
            "accessors": [{"bufferView": 0, "count": 3, "componentType": component,
                           "normalized": normalized, "type": "VEC3"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "nodes": [{"mesh": 0, "scale": [2, 2, 2]}],
        }))
        .unwrap()
    };
    let m = decode(&doc(5122, true, &["KHR_mesh_quantization"]), p()).unwrap();
    // glTF (2, 0, 0) and (0, 2, 0) are the kernel's (2, 0, 0) and (0, 0, 2).
    assert_eq!(
        m.positions,
        [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 2.0]]
    );
    // Not normalized: the integers themselves.
    let m = decode(&doc(5122, false, &[]), p()).unwrap();
    assert_eq!(m.positions[1], [65534.0, 0.0, 0.0]);
    // Normalized UNSIGNED_SHORT: 32767 / 65535.
    let m = decode(&doc(5123, true, &[]), p()).unwrap();
    assert_eq!(m.positions[1][0], 2.0 * f64::from(32767.0f32 / 65535.0));
    // Other required extensions are still refused.
    let e = decode(&doc(5122, true, &["KHR_texture_basisu"]), p()).unwrap_err();
    assert!(e.to_string().contains("KHR_texture_basisu"), "{e}");
}

#[test]
fn strips_fans_and_loops() {
    let read = |mode| decode(&square_gltf(mode, serde_json::json!({})), p()).unwrap();
    let strip = read(5);
    assert_eq!(
        strip.polygons().collect::<Vec<_>>(),
        vec![&[0, 1, 2][..], &[2, 1, 3]]
    );
    let fan = read(6);
    assert_eq!(
        fan.polygons().collect::<Vec<_>>(),
        vec![&[1, 2, 0][..], &[2, 3, 0]]
    );
    assert_eq!(read(4).polygon_count(), 1);
    assert_eq!(read(1).lines, vec![[0, 1], [2, 3]]);
    assert_eq!(read(3).lines, vec![[0, 1], [1, 2], [2, 3]]);
    assert_eq!(read(2).lines, vec![[0, 1], [1, 2], [2, 3], [3, 0]]);
    let points = read(0);
    assert_eq!(
        points.polygon_count() + points.lines.len() + points.positions.len(),
        0
    );
}

#[test]
fn node_transforms_are_applied() {
    // Root node translates by (10, 0, 0) and has a child scaled by 2 holding the mesh;
    // a second root mesh node has a matrix; scene lists both roots.
    let bytes = square_gltf(
        4,
        serde_json::json!({
            "nodes": [
                {"translation": [10, 0, 0], "children": [1]},
                {"scale": [2, 2, 2], "mesh": 0},
                {"matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,5,1], "mesh": 0},
                {"mesh": 0}
            ],
            "scenes": [{"nodes": [0, 2]}],
            "scene": 0
        }),
    );
    let m = decode(&bytes, p()).unwrap();
    assert_eq!(m.polygon_count(), 2, "node 3 is not in the scene");
    // glTF's (x, y, z) is the kernel's (x, −z, y).
    assert_eq!(
        m.positions[..3],
        [[10.0, 0.0, 0.0], [12.0, 0.0, 0.0], [10.0, 0.0, 2.0]]
    );
    assert_eq!(
        m.positions[3..],
        [[0.0, -5.0, 0.0], [1.0, -5.0, 0.0], [0.0, -5.0, 1.0]]
    );
    // 90 degrees about z: (1, 0, 0) -> (0, 1, 0).
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let bytes = square_gltf(
        4,
        serde_json::json!({"nodes": [{"rotation": [0, 0, h, h], "mesh": 0}]}),
    );
    let m = decode(&bytes, p()).unwrap();
    assert!((m.positions[1][0]).abs() < 1e-6 && (m.positions[1][2] - 1.0).abs() < 1e-6);
    // Cycles in the node graph do not loop forever.
    let bytes = square_gltf(
        4,
        serde_json::json!({"nodes": [{"children": [1], "mesh": 0}, {"children": [0]}],
                           "scenes": [{"nodes": [0]}]}),
    );
    assert_eq!(decode(&bytes, p()).unwrap().polygon_count(), 1);
}

#[test]
fn external_buffers_come_through_the_resolver() {
    let mesh = test_meshes::cube_with_wire();
    let glb = encode_glb(&mesh).unwrap();
    let (json_bytes, bin) = split_glb(&glb, p()).unwrap();
    let bin = bin.unwrap().to_vec();
    let mut v: serde_json::Value = serde_json::from_slice(json_bytes).unwrap();
    v["buffers"][0]["uri"] = "my%20data.bin".into();
    let gltf = serde_json::to_vec(&v).unwrap();
    let path = Path::new("model.gltf");
    // The resolver is given the percent-decoded URI and the byteLength.
    let read = |stored: Option<&[u8]>| {
        decode_with(&gltf, path, &mut |uri: &str, max: u64| {
            assert_eq!(uri, "my data.bin");
            let data = stored.ok_or("no such file")?;
            Ok(data[..data.len().min(max as usize)].to_vec())
        })
    };
    let e = read(None).unwrap_err().to_string();
    assert!(
        e.contains("buffer 0: cannot read external file my data.bin: no such file"),
        "{e}"
    );
    // Without a resolver, external files are refused.
    let e = decode(&gltf, path).unwrap_err().to_string();
    assert!(e.contains("not available"), "{e}");
    assert_eq!(read(Some(&bin)).unwrap().polygon_count(), 12);
    // A longer file is cut at byteLength; a shorter one is reported.
    let mut longer = bin.clone();
    longer.extend([0u8; 64]);
    assert_eq!(read(Some(&longer)).unwrap().polygon_count(), 12);
    let e = read(Some(&[0u8; 10])).unwrap_err().to_string();
    assert!(
        e.contains("buffer 0 has 10 bytes but declares byteLength"),
        "{e}"
    );
}

#[test]
fn errors_are_specific() {
    let mesh = test_meshes::cube_with_wire();
    let glb = encode_glb(&mesh).unwrap();
    let e = decode(&glb[..glb.len() - 8], p()).unwrap_err().to_string();
    assert_eq!(
        e,
        format!(
            "mesh.glb: GLB truncated at byte {} (expected {})",
            glb.len() - 8,
            glb.len()
        )
    );
    let e = decode(b"glTF\x01\0\0\0", p()).unwrap_err().to_string();
    assert_eq!(e, "mesh.glb: GLB truncated at byte 8 (expected 12)");
    let e = decode(b"{\"asset\":", p()).unwrap_err().to_string();
    assert!(e.starts_with("mesh.glb: invalid glTF JSON"), "{e}");
    let e = decode(br#"{"asset":{"version":"1.0"}}"#, p())
        .unwrap_err()
        .to_string();
    assert!(e.contains("unsupported glTF version"), "{e}");
    let e = decode(
        br#"{"asset":{"version":"2.0"},"extensionsRequired":["KHR_texture_basisu"]}"#,
        p(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.ends_with("requires unsupported extension KHR_texture_basisu"));
    let bad_uri = br#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":4,"uri":"data:application/octet-stream;base64,@@@@"}]}"#;
    let e = decode(bad_uri, p()).unwrap_err().to_string();
    assert!(e.ends_with("buffer 0: invalid base64 in data URI"), "{e}");
    // POSITION accessor out of range must not panic (gltf-json's validator would).
    let mut v = parse_json(&encode_gltf(&mesh).unwrap());
    v["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 99.into();
    let json = serde_json::to_vec(&v).unwrap();
    let e = decode(&json, p()).unwrap_err().to_string();
    assert!(e.contains("POSITION accessor 99: does not exist"), "{e}");
    // Index out of range.
    let bytes = square_gltf(4, serde_json::json!({}));
    let mut v: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
    let mut uri = DATA_URI_PREFIX.as_bytes().to_vec();
    let mut data: Vec<u8> =
        bytemuck::cast_slice(&[0f32, 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0.]).to_vec();
    data.extend_from_slice(bytemuck::cast_slice(&[0u16, 1, 7, 0]));
    base64_encode(&data, &mut uri);
    let uri = String::from_utf8(uri).unwrap();
    v["buffers"][0] = serde_json::json!({"byteLength": 56, "uri": uri});
    v["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"buffer": 0, "byteOffset": 48, "byteLength": 6}));
    v["accessors"].as_array_mut().unwrap().push(
        serde_json::json!({"bufferView": 1, "count": 3, "componentType": 5123, "type": "SCALAR"}),
    );
    v["meshes"][0]["primitives"][0]["indices"] = 1.into();
    let e = decode(&serde_json::to_vec(&v).unwrap(), p())
        .unwrap_err()
        .to_string();
    assert!(
        e.ends_with("mesh 0 primitive 0: index 2 refers to vertex 7 but only 4 exist"),
        "{e}"
    );
    // Accessor larger than its view.
    v["accessors"][1]["count"] = 4.into();
    let e = decode(&serde_json::to_vec(&v).unwrap(), p())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("indices accessor 1: 4 elements do not fit in bufferView 1"),
        "{e}"
    );
}

#[test]
fn garbage_and_truncation_never_panic() {
    let mesh = test_meshes::awkward();
    let glb = encode_glb(&mesh).unwrap();
    let gltf = encode_gltf(&mesh).unwrap();
    for cut in 0..glb.len() {
        let _ = decode(&glb[..cut], p());
    }
    for cut in (0..gltf.len()).step_by(7) {
        let _ = decode(&gltf[..cut], p());
    }
    let mut state = 3u64;
    for _ in 0..2000 {
        let mut copy = glb.clone();
        for _ in 0..3 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let at = (state >> 33) as usize % copy.len();
            copy[at] = (state >> 13) as u8;
        }
        let _ = decode(&copy, p());
    }
    // Numbers in the JSON replaced with hostile values.
    let v = parse_json(&glb);
    let text = serde_json::to_string(&v).unwrap();
    for hostile in [
        "0",
        "1",
        "4294967295",
        "18446744073709551615",
        "-1",
        "1e300",
        "65535",
    ] {
        for (i, _) in text.match_indices(|c: char| c.is_ascii_digit()).step_by(3) {
            let end = text[i..]
                .find(|c: char| !c.is_ascii_digit() && c != '.')
                .map_or(text.len(), |e| i + e);
            let patched = format!("{}{}{}", &text[..i], hostile, &text[end..]);
            let _ = decode(patched.as_bytes(), Path::new("x.gltf"));
        }
    }
}

/// Writes sample files for the Khronos validator into `$GRAFTAL_GLTF_SAMPLES`:
/// `GRAFTAL_GLTF_SAMPLES=/tmp/s cargo test --lib gltf_validator_samples -- --ignored`,
/// then `NODE_PATH=DIR/node_modules node tests/validate_gltf.mjs --strict /tmp/s/*`.
#[test]
#[ignore]
fn gltf_validator_samples() {
    let dir = std::path::PathBuf::from(
        std::env::var("GRAFTAL_GLTF_SAMPLES").expect("set GRAFTAL_GLTF_SAMPLES"),
    );
    std::fs::create_dir_all(&dir).unwrap();
    let mut lines_only = IndexedMesh::new();
    lines_only.positions = vec![[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]];
    lines_only.lines = vec![[0, 1], [1, 2]];
    let mut big = IndexedMesh::new();
    for i in 0..70_000u32 {
        big.positions.push([
            f64::from(i % 300),
            f64::from(i / 300),
            f64::from(i % 7) * 0.1,
        ]);
    }
    for i in 0..69_000u32 {
        if i % 300 < 299 {
            big.push_polygon(&[i, i + 1, i + 301, i + 300]);
        }
    }
    let samples = [
        ("cube_wire_radius", test_meshes::cube_with_wire()),
        ("empty", IndexedMesh::new()),
        ("awkward", test_meshes::awkward()),
        ("lines_only", lines_only),
        ("big_u32_indices", big),
    ];
    for (name, mesh) in samples {
        std::fs::write(dir.join(format!("{name}.glb")), encode_glb(&mesh).unwrap()).unwrap();
        std::fs::write(
            dir.join(format!("{name}.gltf")),
            encode_gltf(&mesh).unwrap(),
        )
        .unwrap();
    }
}

/// Writes a 1M-triangle GLB (500k quads) and reports the time; run with
/// `cargo test --release --lib glb_million_triangles -- --ignored --nocapture`.
#[test]
#[ignore]
fn glb_million_triangles_timing() {
    let side = 708; // 707 x 707 quads = 499_849 quads ~ 1M triangles
    let mut m = IndexedMesh::new();
    for j in 0..side {
        for i in 0..side {
            let (x, y) = (i as f64 * 0.01, j as f64 * 0.01);
            m.positions
                .push([x, y, (x * 3.0).sin() * (y * 2.0).cos() * 0.1]);
        }
    }
    for j in 0..side - 1 {
        for i in 0..side - 1 {
            let v = (j * side + i) as u32;
            let s = side as u32;
            m.push_polygon(&[v, v + 1, v + s + 1, v + s]);
        }
    }
    m.lines.push([0, 1]);
    let radius = (0..m.positions.len())
        .map(|i| (i % 13) as f64 * 0.01)
        .collect();
    m.vertex_scalars.push(("radius".to_string(), radius));
    let tris = m.triangle_count();
    let mut best = f64::INFINITY;
    let mut size = 0;
    for _ in 0..5 {
        let t = std::time::Instant::now();
        let bytes = encode_glb(&m).unwrap();
        best = best.min(t.elapsed().as_secs_f64());
        size = bytes.len();
    }
    let t = std::time::Instant::now();
    let gltf_len = encode_gltf(&m).unwrap().len();
    let gltf_time = t.elapsed().as_secs_f64();
    println!(
        "GLB: {tris} triangles, {size} bytes, best of 5: {:.1} ms; .gltf (base64): {gltf_len} bytes, {:.1} ms",
        best * 1e3,
        gltf_time * 1e3
    );
}

#[test]
fn a_primitive_naming_a_missing_material_reads_with_the_default() {
    let mut mesh = IndexedMesh::new();
    mesh.positions = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    mesh.push_polygon(&[0, 1, 2]);
    mesh.materials = vec![crate::geom::Material {
        name: "wood".into(),
        double_sided: Some(true),
        ..crate::geom::Material::fallback()
    }];
    mesh.polygon_materials = vec![0];
    let mut bytes = encode_glb(&mesh).unwrap();
    let key = b"\"material\":0";
    let at = bytes.windows(key.len()).position(|w| w == key).unwrap();
    bytes[at + key.len() - 1] = b'7';
    let back = decode(&bytes, p()).unwrap();
    back.validate().unwrap();
    let names: Vec<&str> = back.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["wood", "gltf_default"]);
    assert_eq!(back.polygon_materials, vec![1]);
}

/// `glb` rewritten as `gltfpack -c` stores it: every bufferView compressed
/// by meshoptimizer's codecs (ATTRIBUTES, or TRIANGLES for index views)
/// into buffer 0, the views themselves pointing into a fallback buffer 1
/// that holds no data.
fn meshopt_compressed(glb: &[u8]) -> Vec<u8> {
    let (json_bytes, blob) = split_glb(glb, p()).unwrap();
    let blob = blob.unwrap();
    let mut doc: json::Value = serde_json::from_slice(json_bytes).unwrap();
    // Each view's element size, from an accessor that reads it.
    let mut element = BTreeMap::new();
    for acc in doc["accessors"].as_array().unwrap() {
        let size = match acc["componentType"].as_u64().unwrap() {
            5120 | 5121 => 1,
            5122 | 5123 => 2,
            _ => 4,
        };
        let dims = match acc["type"].as_str().unwrap() {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            _ => 4,
        };
        element.insert(
            acc["bufferView"].as_u64().unwrap(),
            (size * dims, dims == 1),
        );
    }
    let mut packed = Vec::new();
    for (i, view) in doc["bufferViews"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .enumerate()
    {
        let start = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        let length = view["byteLength"].as_u64().unwrap() as usize;
        let data = &blob[start..start + length];
        let (stride, scalar) = element[&(i as u64)];
        let index_view = view["target"] == 34963 && scalar;
        let (encoded, mode) = if index_view {
            let indices: Vec<u32> = if stride == 2 {
                data.chunks_exact(2)
                    .map(|c| u32::from(u16::from_le_bytes([c[0], c[1]])))
                    .collect()
            } else {
                data.chunks_exact(4)
                    .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect()
            };
            let vertices = indices.iter().max().map_or(0, |&m| m as usize + 1);
            // One stream, decoded to 16- or 32-bit indices as the stride says.
            let encoded = ::meshopt::encode_index_buffer(&indices, vertices).unwrap();
            (encoded, "TRIANGLES")
        } else {
            assert_eq!(stride % 4, 0);
            let words: Vec<[u8; 4]> = data
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect();
            let encoded = match stride / 4 {
                1 => ::meshopt::encode_vertex_buffer(&words).unwrap(),
                2 => ::meshopt::encode_vertex_buffer(
                    &words
                        .chunks_exact(2)
                        .map(|c| [c[0], c[1]])
                        .collect::<Vec<_>>(),
                )
                .unwrap(),
                3 => ::meshopt::encode_vertex_buffer(
                    &words
                        .chunks_exact(3)
                        .map(|c| [c[0], c[1], c[2]])
                        .collect::<Vec<_>>(),
                )
                .unwrap(),
                n => panic!("stride of {n} words"),
            };
            (encoded, "ATTRIBUTES")
        };
        view["buffer"] = 1.into();
        view["extensions"] = serde_json::json!({"EXT_meshopt_compression": {
            "buffer": 0, "byteOffset": packed.len(), "byteLength": encoded.len(),
            "byteStride": stride, "count": length / stride, "mode": mode}});
        packed.extend_from_slice(&encoded);
        packed.resize(packed.len().next_multiple_of(4), 0);
    }
    let fallback = blob.len();
    doc["buffers"] = serde_json::json!([
        {"byteLength": packed.len()},
        {"byteLength": fallback, "extensions": {"EXT_meshopt_compression": {"fallback": true}}}
    ]);
    doc["extensionsUsed"] = serde_json::json!(["EXT_meshopt_compression"]);
    doc["extensionsRequired"] = serde_json::json!(["EXT_meshopt_compression"]);
    let mut json_text = serde_json::to_vec(&doc).unwrap();
    json_text.resize(json_text.len().next_multiple_of(4), b' ');
    let mut out = b"glTF".to_vec();
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((28 + json_text.len() + packed.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(json_text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_text);
    out.extend_from_slice(&(packed.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&packed);
    out
}

#[test]
fn meshopt_compressed_views_read_as_the_uncompressed_file() {
    // Positions, normals, texture coordinates, colours, scalars, 16-bit
    // triangle indices and a wire primitive: every kind of view we write.
    let mut mesh = test_meshes::cube_with_wire();
    let corners = mesh.face_indices.len();
    mesh.corner_uvs = (0..corners).map(|c| [c as f64 / 7.0, 0.25]).collect();
    mesh.corner_colors = (0..corners)
        .map(|c| [0.5, (c % 3) as f64 / 2.0, 1.0])
        .collect();
    let plain = encode_glb(&mesh).unwrap();
    let packed = meshopt_compressed(&plain);
    let expected = decode(&plain, p()).unwrap();
    let back = decode(&packed, p()).unwrap();
    assert_eq!(back.positions, expected.positions);
    assert_eq!(back.face_indices, expected.face_indices);
    assert_eq!(back.lines, expected.lines);
    assert_eq!(back.corner_normals, expected.corner_normals);
    assert_eq!(back.corner_uvs, expected.corner_uvs);
    assert_eq!(back.corner_colors, expected.corner_colors);
    assert_eq!(back.vertex_scalars, expected.vertex_scalars);
    // And writing it again gives the uncompressed file's bytes.
    assert_eq!(encode_glb(&back).unwrap(), encode_glb(&expected).unwrap());

    // A count the compressed bytes cannot hold is refused before decoding.
    let (json_bytes, _) = split_glb(&packed, p()).unwrap();
    let text = String::from_utf8(json_bytes.to_vec()).unwrap();
    // The first compressed view's count (not an accessor's).
    let ext = text
        .find("\"EXT_meshopt_compression\":{\"buffer\"")
        .unwrap();
    let at = ext + text[ext..].find("\"count\":").unwrap() + "\"count\":".len();
    let hostile = format!("{}4000000000{}", &text[..at], &text[at..]);
    let mut bytes = packed.clone();
    bytes.splice(20..20 + json_bytes.len(), hostile.bytes());
    let new_len = (bytes.len() as u32).to_le_bytes();
    bytes[8..12].copy_from_slice(&new_len);
    let chunk = (hostile.len() as u32).to_le_bytes();
    bytes[12..16].copy_from_slice(&chunk);
    let message = decode(&bytes, p()).unwrap_err().to_string();
    assert!(message.contains("EXT_meshopt_compression"), "{message}");
    // Garbage where the compressed stream should be is an error, not a panic.
    let mut broken = packed.clone();
    let bin = 20 + json_bytes.len() + 8;
    for b in &mut broken[bin..bin + 16] {
        *b = 0xff;
    }
    assert!(decode(&broken, p()).is_err());
}
