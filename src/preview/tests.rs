use std::collections::BTreeMap;

use super::*;

/// Positions, triangles and lines of a test mesh.
type Mesh = (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<[u32; 2]>);

/// Unit cube [0,1]^3: 8 corners, 12 triangles, 12 edges.
fn cube() -> Mesh {
    let positions = (0..8u32)
        .map(|i| {
            [
                f64::from(i & 1),
                f64::from((i >> 1) & 1),
                f64::from((i >> 2) & 1),
            ]
        })
        .collect();
    // -z, +z, -y, +y, -x, +x
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    let mut lines = Vec::new();
    for a in 0..8u32 {
        for bit in [1, 2, 4] {
            if a & bit == 0 {
                lines.push([a, a | bit]);
            }
        }
    }
    (positions, triangles, lines)
}

/// The square [-1,1]^2 in the plane spanned by axes `u` and `v`.
fn square(u: usize, v: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let corners = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    let positions = corners
        .iter()
        .map(|c| {
            let mut p = [0.0; 3];
            p[u] = c[0];
            p[v] = c[1];
            p
        })
        .collect();
    (positions, vec![[0, 1, 2], [0, 2, 3]])
}

fn opts(width: u32, height: u32, view: View) -> Options {
    Options {
        width,
        height,
        view,
        ..Options::default()
    }
}

fn is_bg(image: &Image, options: &Options, x: u32, y: u32) -> bool {
    let p = image.pixel(x, y).expect("pixel in range");
    p[..3] == options.background
}

fn at(image: &Image, fx: f64, fy: f64) -> [u8; 4] {
    let x = (fx * f64::from(image.width)) as u32;
    let y = (fy * f64::from(image.height)) as u32;
    image.pixel(x, y).expect("pixel in range")
}

fn brightness(p: [u8; 4]) -> u32 {
    u32::from(p[0]) + u32::from(p[1]) + u32::from(p[2])
}

/// Inclusive bounding box of the non-background pixels.
fn ink_box(image: &Image, options: &Options) -> Option<(u32, u32, u32, u32)> {
    let mut b: Option<(u32, u32, u32, u32)> = None;
    for y in 0..image.height {
        for x in 0..image.width {
            if !is_bg(image, options, x, y) {
                b = Some(match b {
                    None => (x, y, x, y),
                    Some((x0, y0, x1, y1)) => (x0.min(x), y0.min(y), x1.max(x), y1.max(y)),
                });
            }
        }
    }
    b
}

#[test]
fn cube_iso_is_framed_and_shows_three_shades_with_top_up() {
    let (positions, triangles, _) = cube();
    let scene = Scene {
        positions: &positions,
        triangles: &triangles,
        ..Scene::default()
    };
    let o = Options::default();
    let img = render(&scene, &o).unwrap();
    assert_eq!(
        (img.width, img.height, img.rgba.len()),
        (512, 512, 512 * 512 * 4)
    );
    assert!(!is_bg(&img, &o, 256, 256));
    for (x, y) in [(0, 0), (511, 0), (0, 511), (511, 511)] {
        assert!(is_bg(&img, &o, x, y), "corner {x},{y}");
    }
    assert!(
        img.rgba.chunks(4).any(|p| p != &img.rgba[..4]),
        "one colour"
    );

    // Three most common non-background colours: the three visible faces.
    let mut hist = BTreeMap::new();
    for p in img.rgba.chunks_exact(4) {
        if p[..3] != o.background {
            *hist.entry([p[0], p[1], p[2]]).or_insert(0usize) += 1;
        }
    }
    let mut common: Vec<_> = hist.into_iter().collect();
    common.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    assert!(common.len() >= 3);
    for (c, n) in &common[..3] {
        assert!(*n > 512 * 512 / 30, "face colour {c:?} covers only {n} px");
    }
    for i in 0..3 {
        for j in i + 1..3 {
            let d: i32 = (0..3)
                .map(|k| (i32::from(common[i].0[k]) - i32::from(common[j].0[k])).abs())
                .sum();
            assert!(d >= 15, "faces {i} and {j} too similar: {common:?}");
        }
    }

    // Z-up with the front (-Y) face on the left and +X face on the right:
    // the top face (lit from above) is brightest, the -Y face (towards the
    // key light) next, the +X face (away from it) darkest.
    let top = at(&img, 0.5, 0.26);
    let front = at(&img, 0.3, 0.6);
    let right = at(&img, 0.7, 0.6);
    for p in [top, front, right] {
        assert_ne!(p[..3], o.background);
    }
    assert!(brightness(top) > brightness(front), "{top:?} {front:?}");
    assert!(brightness(front) > brightness(right), "{front:?} {right:?}");
    // Below the cube is background: the cube is not upside down.
    assert!(is_bg(&img, &o, 256, 500));
}

#[test]
fn output_is_deterministic() {
    let (positions, triangles, lines) = cube();
    let scene = Scene {
        positions: &positions,
        triangles: &triangles,
        lines: &lines,
        ..Scene::default()
    };
    let o = Options {
        edges: true,
        projection: Projection::Perspective,
        ..Options::default()
    };
    let a = render(&scene, &o).unwrap();
    let b = render(&scene, &o).unwrap();
    assert_eq!(a.rgba, b.rgba);
    assert_eq!(encode_png(&a).unwrap(), encode_png(&b).unwrap());
}

/// A square facing the camera fills a centred square region, ~88% of the
/// shorter side, keeping its aspect on a non-square image.
fn assert_centred_square(img: &Image, o: &Options) {
    let (x0, y0, x1, y1) = ink_box(img, o).expect("something drawn");
    let (w, h) = (img.width as i64, img.height as i64);
    let (x0, y0, x1, y1) = (x0 as i64, y0 as i64, x1 as i64, y1 as i64);
    assert!((x0 + x1 + 1 - w).abs() <= 1, "x {x0}..{x1} in {w}");
    assert!((y0 + y1 + 1 - h).abs() <= 1, "y {y0}..{y1} in {h}");
    assert!(((x1 - x0) - (y1 - y0)).abs() <= 1, "not square");
    let side = (y1 - y0 + 1) as f64;
    assert!((side - 0.88 * h.min(w) as f64).abs() <= 2.0, "side {side}");
    // Filled inside, no cracks along the diagonal.
    for y in y0 + 1..y1 {
        for x in x0 + 1..x1 {
            assert!(!is_bg(img, o, x as u32, y as u32), "hole at {x},{y}");
        }
    }
}

#[test]
fn front_view_of_xz_square_and_top_view_of_xy_square_are_centred() {
    for (u, v, view) in [(0, 2, View::Front), (0, 1, View::Top)] {
        let (positions, triangles) = square(u, v);
        let scene = Scene {
            positions: &positions,
            triangles: &triangles,
            ..Scene::default()
        };
        let o = opts(200, 100, view);
        assert_centred_square(&render(&scene, &o).unwrap(), &o);
        let o = opts(64, 150, view);
        assert_centred_square(&render(&scene, &o).unwrap(), &o);
    }
}

#[test]
fn front_and_top_views_are_oriented() {
    // One triangle in the (+first, +second) quadrant; a line (not drawn)
    // widens the framing to [-1,1]^2.
    for (u, v, view) in [(0, 2, View::Front), (0, 1, View::Top)] {
        let mut positions = vec![[0.0; 3]; 5];
        for (p, c) in
            positions
                .iter_mut()
                .zip([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [-1.0, -1.0], [1.0, 1.0]])
        {
            p[u] = c[0];
            p[v] = c[1];
        }
        let triangles = [[0, 1, 2]];
        let lines = [[3, 4]];
        let scene = Scene {
            positions: &positions,
            triangles: &triangles,
            lines: &lines,
            ..Scene::default()
        };
        let o = opts(100, 100, view);
        let img = render(&scene, &o).unwrap();
        // (0.8, 0.3) is inside the triangle: right of and above the centre.
        assert!(!is_bg(&img, &o, 85, 37), "{view:?}");
        for (x, y) in [(15, 37), (85, 63), (15, 63)] {
            assert!(is_bg(&img, &o, x, y), "{view:?} {x},{y}");
        }
    }
}

#[test]
fn every_view_and_projection_shows_the_cube() {
    let (positions, triangles, lines) = cube();
    let scene = Scene {
        positions: &positions,
        triangles: &triangles,
        lines: &lines,
        ..Scene::default()
    };
    for view in View::ALL {
        for projection in [Projection::Orthographic, Projection::Perspective] {
            let o = Options {
                width: 96,
                height: 64,
                view,
                projection,
                edges: true,
                ..Options::default()
            };
            let img = render(&scene, &o).unwrap();
            assert!(!is_bg(&img, &o, 48, 32), "{view:?} {projection:?}");
            assert!(is_bg(&img, &o, 0, 0), "{view:?} {projection:?}");
            assert!(is_bg(&img, &o, 95, 63), "{view:?} {projection:?}");
        }
    }
}

#[test]
fn lines_alone_draw_dark_pixels_only_when_edges_is_set() {
    let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 1.0], [1.0, 0.0, 0.0]];
    let lines = [[0, 1], [1, 2]];
    let scene = Scene {
        positions: &positions,
        lines: &lines,
        ..Scene::default()
    };
    let mut o = opts(64, 64, View::Front);
    o.edges = true;
    let img = render(&scene, &o).unwrap();
    let dark = img.rgba.chunks_exact(4).filter(|p| p[0] < 60).count();
    assert!(dark > 60, "only {dark} dark pixels");
    o.edges = false;
    let img = render(&scene, &o).unwrap();
    assert!(img.rgba.chunks_exact(4).all(|p| p[..3] == o.background));
}

#[test]
fn lines_on_and_in_front_of_a_face_show_and_lines_behind_it_do_not() {
    let (mut positions, triangles) = square(0, 2);
    // Rows z = 0.5 (on the face), z = 0 (in front, -Y), z = -0.5 (behind).
    for (y, z) in [(0.0, 0.5), (-0.3, 0.0), (0.3, -0.5)] {
        positions.push([-0.9, y, z]);
        positions.push([0.9, y, z]);
    }
    let lines = [[4, 5], [6, 7], [8, 9]];
    let scene = Scene {
        positions: &positions,
        triangles: &triangles,
        lines: &lines,
        ..Scene::default()
    };
    let o = Options {
        edges: true,
        ..opts(100, 100, View::Front)
    };
    let img = render(&scene, &o).unwrap();
    let row_is_dark = |z: f64| {
        // Scale 44 px per unit, centred: search a few rows around it.
        let y = (50.0 - 44.0 * z) as i64;
        (y - 2..=y + 2).any(|y| img.pixel(50, y as u32).unwrap()[0] < 60)
    };
    assert!(row_is_dark(0.5), "line on the face hidden");
    assert!(row_is_dark(0.0), "line in front hidden");
    assert!(!row_is_dark(-0.5), "line behind the face shows");
}

#[test]
fn empty_scene_is_background_only() {
    let o = opts(32, 16, View::Iso);
    let positions = [[1.0, 2.0, 3.0], [f64::NAN, 0.0, 0.0]];
    for scene in [
        Scene::default(),
        Scene {
            positions: &positions,
            ..Scene::default()
        },
    ] {
        let img = render(&scene, &o).unwrap();
        assert_eq!(img.rgba.len(), 32 * 16 * 4);
        assert!(img.rgba.chunks_exact(4).all(|p| p == [222, 228, 236, 255]));
    }
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let o = opts(16, 16, View::Iso);
    let positions = [
        [0.0, 0.0, 0.0],
        [f64::NAN, 0.0, 0.0],
        [0.0, 1.0, f64::INFINITY],
    ];
    let tri = |t: &'static [[u32; 3]]| Scene {
        positions: &positions,
        triangles: t,
        ..Scene::default()
    };
    assert_eq!(
        render(&tri(&[[0, 1, 0]]), &o).unwrap_err(),
        PreviewError::NonFinite { vertex: 1 }
    );
    assert_eq!(
        render(&tri(&[[0, 0, 2]]), &o).unwrap_err(),
        PreviewError::NonFinite { vertex: 2 }
    );
    assert_eq!(
        render(&tri(&[[0, 0, 0], [0, 7, 0]]), &o).unwrap_err(),
        PreviewError::BadIndex {
            primitive: "triangle",
            element: 1,
            index: 7,
            vertex_count: 3
        }
    );
    let line = Scene {
        positions: &positions,
        lines: &[[0, u32::MAX]],
        ..Scene::default()
    };
    assert!(matches!(
        render(&line, &o),
        Err(PreviewError::BadIndex {
            primitive: "line",
            index: u32::MAX,
            ..
        })
    ));
    let colours = Scene {
        positions: &positions,
        triangles: &[[0, 0, 0]],
        triangle_colors: &[[1.0, 0.0, 0.0]; 2],
        ..Scene::default()
    };
    assert!(matches!(
        render(&colours, &o),
        Err(PreviewError::LengthMismatch {
            field: "triangle_colors",
            expected: 1,
            actual: 2
        })
    ));
    for (w, h) in [
        (0, 16),
        (16, 0),
        (10_000, 16),
        (16, 8193),
        (u32::MAX, u32::MAX),
    ] {
        let err = render(&Scene::default(), &opts(w, h, View::Iso)).unwrap_err();
        assert_eq!(
            err,
            PreviewError::TooLarge {
                width: u64::from(w),
                height: u64::from(h)
            }
        );
        assert!(err.to_string().contains("out of range"));
    }
    assert!(render(&Scene::default(), &opts(8192, 1, View::Iso)).is_ok());
}

#[test]
fn degenerate_and_extreme_boxes_render() {
    // A single point (zero-length line) is framed and drawn at the centre.
    let positions = [[3.0, -2.0, 1e6]];
    let scene = Scene {
        positions: &positions,
        lines: &[[0, 0]],
        ..Scene::default()
    };
    let o = Options {
        edges: true,
        ..opts(33, 33, View::Iso)
    };
    let img = render(&scene, &o).unwrap();
    let dark: Vec<usize> = img
        .rgba
        .chunks_exact(4)
        .enumerate()
        .filter(|(_, p)| p[0] < 60)
        .map(|(i, _)| i)
        .collect();
    assert_eq!(dark, vec![16 * 33 + 16]);

    // A flat square seen edge-on draws nothing, without failing.
    let (positions, triangles) = square(0, 1);
    let scene = Scene {
        positions: &positions,
        triangles: &triangles,
        ..Scene::default()
    };
    let o = opts(40, 40, View::Front);
    assert!(ink_box(&render(&scene, &o).unwrap(), &o).is_none());

    // Scaling and shifting by powers of two changes nothing; huge and tiny
    // coordinates neither overflow nor underflow.
    let (positions, triangles, _) = cube();
    let reference = {
        let scene = Scene {
            positions: &positions,
            triangles: &triangles,
            ..Scene::default()
        };
        render(&scene, &opts(64, 64, View::Iso)).unwrap()
    };
    for (scale, shift) in [(2f64.powi(900), 3.0), (2f64.powi(-1000), -1.0)] {
        let moved: Vec<[f64; 3]> = positions
            .iter()
            .map(|p| p.map(|c| (c + shift) * scale))
            .collect();
        let scene = Scene {
            positions: &moved,
            triangles: &triangles,
            ..Scene::default()
        };
        assert_eq!(render(&scene, &opts(64, 64, View::Iso)).unwrap(), reference);
    }
    let extreme: Vec<[f64; 3]> = positions
        .iter()
        .map(|p| p.map(|c| if c > 0.5 { f64::MAX } else { -f64::MAX }))
        .collect();
    let scene = Scene {
        positions: &extreme,
        triangles: &triangles,
        ..Scene::default()
    };
    let o = opts(64, 64, View::Iso);
    assert!(!is_bg(&render(&scene, &o).unwrap(), &o, 32, 32));
}

#[test]
fn colours_and_smooth_normals_are_used() {
    let (positions, triangles, _) = cube();
    let colours = vec![[0.9f32, 0.1, 0.1]; triangles.len()];
    // Normals pointing out from the cube centre: smooth shading gives a
    // gradient on each face instead of a flat colour. Corner 0 of the first
    // triangle is NaN to exercise the fall-back.
    let mut normals: Vec<[[f64; 3]; 3]> = triangles
        .iter()
        .map(|t| t.map(|i| positions[i as usize].map(|c| c - 0.5)))
        .collect();
    normals[0][0] = [f64::NAN; 3];
    let scene = Scene {
        positions: &positions,
        triangles: &triangles,
        triangle_colors: &colours,
        corner_normals: &normals,
        lines: &[],
    };
    let o = Options::default();
    let img = render(&scene, &o).unwrap();
    let mut distinct = std::collections::BTreeSet::new();
    // Interior pixels only: edge pixels are blended with the background.
    for y in 1..511 {
        for x in 1..511 {
            let covered = [(1, 1), (0, 1), (2, 1), (1, 0), (1, 2)]
                .iter()
                .all(|&(dx, dy)| !is_bg(&img, &o, x + dx - 1, y + dy - 1));
            if covered {
                let p = img.pixel(x, y).unwrap();
                assert!(p[0] > p[1] && p[0] > p[2], "not red: {p:?}");
                distinct.insert([p[0], p[1], p[2]]);
            }
        }
    }
    assert!(distinct.len() > 50, "only {} shades", distinct.len());
}

#[test]
fn png_round_trips() {
    let (positions, triangles, lines) = cube();
    let scene = Scene {
        positions: &positions,
        triangles: &triangles,
        lines: &lines,
        ..Scene::default()
    };
    let img = render(
        &scene,
        &Options {
            edges: true,
            ..opts(70, 50, View::Iso)
        },
    )
    .unwrap();
    let bytes = encode_png(&img).unwrap();
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (70, 50));
    assert_eq!(info.color_type, png::ColorType::Rgba);
    assert_eq!(&buf[..info.buffer_size()], &img.rgba[..]);

    let bad = Image {
        width: 2,
        height: 2,
        rgba: vec![0; 15],
    };
    assert!(matches!(
        encode_png(&bad),
        Err(PreviewError::BadImage { .. })
    ));
}

#[test]
fn contact_sheet_layout_and_labels() {
    let (positions, triangles, _) = cube();
    let scene = Scene {
        positions: &positions,
        triangles: &triangles,
        ..Scene::default()
    };
    let (w, h) = (40u32, 30u32);
    let tiles: Vec<(Image, String)> = [View::Iso, View::Front, View::Top]
        .iter()
        .map(|&v| {
            (
                render(&scene, &opts(w, h, v)).unwrap(),
                format!("{} é", v.name()),
            )
        })
        .collect();
    let sheet = contact_sheet(&tiles, 2).unwrap();
    let (p, l) = (SHEET_PADDING, LABEL_HEIGHT);
    assert_eq!(sheet.width, 2 * (w + p) + p);
    assert_eq!(sheet.height, 2 * (h + l + p) + p);
    assert_eq!(sheet.rgba.len(), (sheet.width * sheet.height * 4) as usize);
    // Tile 1 is copied verbatim at its cell.
    assert_eq!(sheet.pixel(p + w + p + 3, p + 5), tiles[1].0.pixel(3, 5));
    // Its label band has dark text; the empty fourth cell stays white.
    let band_is_dark = |x0: u32, y0: u32| {
        (y0..y0 + l).any(|y| (x0..x0 + w).any(|x| sheet.pixel(x, y).unwrap()[0] < 60))
    };
    assert!(band_is_dark(p, p + h));
    assert!(band_is_dark(p + w + p, p + h));
    assert!(!band_is_dark(p + w + p, 2 * p + h + l + h));
    assert!((0..w + p).all(|x| (0..h).all(|y| sheet
        .pixel(sheet.width - 1 - x, sheet.height - 1 - y)
        .unwrap()
        == [255; 4])));

    // More columns than tiles: one row.
    let wide = contact_sheet(&tiles, 9).unwrap();
    assert_eq!((wide.width, wide.height), (3 * (w + p) + p, h + l + 2 * p));

    assert_eq!(
        contact_sheet(&tiles, 0).unwrap_err(),
        PreviewError::EmptySheet
    );
    assert_eq!(contact_sheet(&[], 2).unwrap_err(), PreviewError::EmptySheet);
    let mut mixed = tiles.clone();
    mixed[2].0 = render(&scene, &opts(w + 1, h, View::Iso)).unwrap();
    assert_eq!(
        contact_sheet(&mixed, 2).unwrap_err(),
        PreviewError::TileMismatch {
            tile: 2,
            expected: (w, h),
            actual: (w + 1, h)
        }
    );
    // 320 cells of 8008 x 27 is just over 8192^2 pixels.
    let strip = Image {
        width: 8000,
        height: 1,
        rgba: vec![0; 8000 * 4],
    };
    let many = vec![(strip, String::new()); 320];
    assert!(matches!(
        contact_sheet(&many, 1),
        Err(PreviewError::TooLarge { .. })
    ));
}

#[test]
fn srgb_conversion_round_trips_every_byte() {
    for c in 0..=255u8 {
        let l = raster::srgb_to_linear(c);
        assert_eq!(raster::linear_to_srgb(f64::from(l)), c);
    }
    assert_eq!(raster::linear_to_srgb(0.5), 188);
    assert_eq!(raster::linear_to_srgb(f64::NAN), 0);
    assert_eq!(raster::linear_to_srgb(7.0), 255);
}
