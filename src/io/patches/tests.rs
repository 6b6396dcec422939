use std::path::Path;

use super::*;

const TEAPOT_BPT: &[u8] = include_bytes!("../../../rules/teapot.bpt");
const TEAPOT_OBJ: &[u8] = include_bytes!("../../../tests/fixtures/teapot.obj");

fn obj(text: &str) -> Result<PatchFile, IoError> {
    decode_obj_surfaces(text.as_bytes(), Path::new("s.obj"))
}

fn bpt(text: &str) -> Result<PatchFile, IoError> {
    decode_bpt(text.as_bytes(), Path::new("p.bpt"))
}

/// (line, column, message) of a located error.
fn located(r: Result<PatchFile, IoError>) -> (usize, usize, String) {
    match r {
        Err(IoError::Located {
            line,
            column,
            message,
            ..
        }) => (line, column, message),
        other => panic!("expected a located error, got {other:?}"),
    }
}

fn assert_error(r: Result<PatchFile, IoError>, line: usize, column: usize, words: &str) {
    let (l, c, m) = located(r);
    assert_eq!((l, c), (line, column), "{m}");
    assert!(m.contains(words), "{m:?} lacks {words:?}");
}

fn net(s: &NurbsSurface) -> Vec<[u64; 4]> {
    let [n_u, n_v] = s.size();
    let mut out = Vec::new();
    for i in 0..n_u {
        for j in 0..n_v {
            let h = s.homogeneous_point(i, j);
            out.push([h.x, h.y, h.z, h.w].map(f64::to_bits));
        }
    }
    out
}

#[test]
fn teapot_bpt_reads_32_bicubic_patches() {
    let f = decode_patches(TEAPOT_BPT, Path::new("rules/teapot.bpt")).unwrap();
    assert_eq!(f.surfaces.len(), 32);
    assert_eq!(f.lines.len(), 32);
    assert_eq!(f.lines[0], 2);
    assert_eq!(f.lines[1], 2 + 17);
    for s in &f.surfaces {
        assert_eq!(s.degree(), [3, 3]);
        assert_eq!(s.size(), [4, 4]);
        assert_eq!(s.domain(), [[0.0, 1.0], [0.0, 1.0]]);
        assert!(!s.is_rational());
    }
    // Patch 0 (rim): its first point is Newell's vertex 0, its last vertex 15; the first row
    // (i = 0) is the data's first four points.
    let p = &f.surfaces[0];
    assert_eq!(p.control_point(0, 0).to_array(), [1.4, 0.0, 2.4]);
    assert_eq!(p.control_point(0, 1).to_array(), [1.4, -0.784, 2.4]);
    assert_eq!(p.control_point(0, 3).to_array(), [0.0, -1.4, 2.4]);
    assert_eq!(p.control_point(1, 0).to_array(), [1.3375, 0.0, 2.53125]);
    assert_eq!(p.control_point(3, 3).to_array(), [0.0, -1.5, 2.4]);
    // A Bézier patch interpolates its corners.
    assert_eq!(p.point(0.0, 0.0).unwrap().to_array(), [1.4, 0.0, 2.4]);
    // z up: the lid's knob is the top, at z = 3.15.
    let top = f
        .surfaces
        .iter()
        .flat_map(|s| (0..16).map(move |k| s.control_point(k / 4, k % 4).z))
        .fold(f64::MIN, f64::max);
    assert_eq!(top, 3.15);
}

#[test]
fn teapot_obj_has_the_same_nets_as_the_bpt() {
    let b = decode_patches(TEAPOT_BPT, Path::new("t.bpt")).unwrap();
    let o = decode_patches(TEAPOT_OBJ, Path::new("t.OBJ")).unwrap();
    assert_eq!(o.surfaces.len(), 32);
    for (k, (sb, so)) in b.surfaces.iter().zip(&o.surfaces).enumerate() {
        assert_eq!(so.degree(), [3, 3]);
        assert_eq!(net(sb), net(so), "patch {k}");
        assert_eq!(sb.knots_u(), so.knots_u());
        assert_eq!(sb.knots_v(), so.knots_v());
    }
    // Each surf starts 5 lines (surf + continuation, parm × 2, end) after the previous one.
    assert!(
        o.lines.windows(2).all(|w| w[1] == w[0] + 5),
        "{:?}",
        o.lines
    );
}

#[test]
fn unknown_extension_names_both_formats() {
    let e = decode_patches(b"", Path::new("a.stl"))
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "a.stl: unknown patch format (expected a .bpt or .obj extension)"
    );
}

#[test]
fn located_errors_display_path_line_column() {
    let text = "1\n3 x\n".to_string() + &"0 0 0\n".repeat(4);
    let e = bpt(&text).unwrap_err().to_string();
    assert_eq!(
        e,
        "p.bpt:2:3: patch 1: degree in v must be an integer from 1 to 64, found \"x\""
    );
}

const BSPLINE: &str = "\
# degree 2 × 1, 4 × 3 net, u fastest
v 0 0 0
v 1 0.2 1
v 2 0.8 2
v 3 1.8 0.5
v 0.1 1 1 7
v 1.1 1.2 3
v 2.1 1.8 0
v 3.1 2.8 1
v 0.2 2 2
v 1.2 2.2 0
v 2.2 2.8 1
v 3.2 3.8 4
cstype bspline
deg 2 1
surf 0 1 0 1 1 2/1 3/1/1 4//1 5 6 7 8 9 10 11 12
parm u 0 0 0 0.5 1 1 1
parm v 0 0 0.3 1 1
end
";

#[test]
fn bspline_surface_matches_geomdl() {
    let f = obj(BSPLINE).unwrap();
    assert_eq!(f.lines, vec![16]);
    let s = &f.surfaces[0];
    assert_eq!(s.degree(), [2, 1]);
    assert_eq!(s.size(), [4, 3]);
    assert_eq!(s.knots_u(), &[0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0]);
    assert_eq!(s.knots_v(), &[0.0, 0.0, 0.3, 1.0, 1.0]);
    // The weight 7 of vertex 5 is ignored: the surface is not rational.
    assert!(!s.is_rational());
    assert_eq!(s.control_point(3, 0).to_array(), [3.0, 1.8, 0.5]);
    assert_eq!(s.control_point(0, 1).to_array(), [0.1, 1.0, 1.0]);
    assert_eq!(s.control_point(3, 2).to_array(), [3.2, 3.8, 4.0]);
    // geomdl 5.4.0 (BSpline.Surface, same net and knots) gives these.
    for ((u, v), expected) in [
        (
            (0.25, 0.6),
            [1.0178571428571428, 1.6535714285714285, 1.4821428571428574],
        ),
        (
            (0.7, 0.2),
            [2.0466666666666664, 1.5186666666666666, 0.9933333333333333],
        ),
    ] {
        let p = s.point(u, v).unwrap();
        for (a, b) in p.to_array().iter().zip(expected) {
            assert!(
                (a - b).abs() < 1e-13,
                "S({u}, {v}) = {p}, geomdl {expected:?}"
            );
        }
    }
}

const RATIONAL: &str = "\
v 1 0 0
v 1 1 0 0.7071067811865476
v 0 1 0
v 1 0 2
v 1 1 2 0.7071067811865476
v 0 1 2
cstype rat bspline
deg 2 1
surf 2 3 0 1 -6 -5 -4 -3 -2 -1
parm u 2 2 2 3 3 3
parm v 0 0 1 1
end
";

#[test]
fn rational_bspline_is_a_quarter_cylinder() {
    let s = &obj(RATIONAL).unwrap().surfaces[0];
    assert!(s.is_rational());
    assert_eq!(s.size(), [3, 2]);
    assert_eq!(s.domain(), [[2.0, 3.0], [0.0, 1.0]]);
    assert_eq!(s.homogeneous_point(1, 0).w, std::f64::consts::FRAC_1_SQRT_2);
    assert_eq!(s.homogeneous_point(1, 1).w, std::f64::consts::FRAC_1_SQRT_2);
    assert_eq!(s.homogeneous_point(0, 1).w, 1.0);
    assert_eq!(s.control_point(2, 1).to_array(), [0.0, 1.0, 2.0]);
    // Every point lies on the unit cylinder; u = 2.5 is the 45° point (analytic), and
    // u = 2.3 matches geomdl 5.4.0's NURBS.Surface.
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let p = s.point(2.5, 0.5).unwrap();
    assert!((p - glam::DVec3::new(h, h, 1.0)).length() < 1e-15, "{p}");
    let p = s.point(2.3, 0.25).unwrap();
    let g = glam::DVec3::new(0.8973756499953727, 0.4412674277525846, 0.5);
    assert!((p - g).length() < 1e-14, "{p}");
    for k in 0..=10 {
        let p = s.point(2.0 + f64::from(k) / 10.0, 0.3).unwrap();
        assert!((p.x.hypot(p.y) - 1.0).abs() < 1e-14, "{p}");
    }
}

#[test]
fn bezier_parm_breaks_make_knots() {
    // Two quadratic segments in u (breaks 0, 1, 3): 5 points; one linear segment in v.
    let mut text = String::new();
    for j in 0..2 {
        for i in 0..5 {
            text += &format!("v {i} {j} {}\n", i * i);
        }
    }
    text += "cstype bezier\ndeg 2 1\nsurf 0 3 5 6 1 2 3 4 5 6 7 8 9 10\n";
    text += "parm u 0 1 3\nparm v 5 6\nend\n";
    let s = &obj(&text).unwrap().surfaces[0];
    assert_eq!(s.size(), [5, 2]);
    assert_eq!(s.knots_u(), &[0.0, 0.0, 0.0, 1.0, 1.0, 3.0, 3.0, 3.0]);
    assert_eq!(s.knots_v(), &[5.0, 5.0, 6.0, 6.0]);
    // The break at u = 1 interpolates the middle control point.
    assert_eq!(s.point(1.0, 5.0).unwrap().to_array(), [2.0, 0.0, 4.0]);
}

#[test]
fn continuation_lines_and_negative_indices() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1\r\n\
                cstype bezier\ndeg 1 1\n\
                surf 0 1 \\\n  0 1 \\\r\n -4 -3 \\\n  -2 -1 # comment \\\nparm u 0 1\nparm v 0 1\nend\n";
    let f = obj(text).unwrap();
    assert_eq!(f.lines, vec![7]);
    let s = &f.surfaces[0];
    assert_eq!(s.control_point(1, 0).to_array(), [1.0, 0.0, 0.0]);
    assert_eq!(s.control_point(0, 1).to_array(), [0.0, 1.0, 0.0]);
    assert_eq!(s.point(0.5, 0.5).unwrap().to_array(), [0.5, 0.5, 0.25]);
    // A bad reference on a continuation line is located on its physical line and column.
    let bad = text.replace("-2 -1", "-2 -9");
    assert_error(obj(&bad), 10, 6, "vertex reference -9 is out of range");
}

#[test]
fn ignored_statements() {
    let text = "mtllib a.mtl\no thing\ng part\ns 1\nusemtl red\nvt 0 0\nvn 0 0 1\n\
                vp 0.5 0.5\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nl 1 2\np 1\n\
                ctech cparm 1\nstech cparm 1 1\ncstype bezier\ndeg 1 1\nsurf 0 1 0 1 1 2 3 4\n\
                parm u 0 1\nparm v 0 1\nend\n";
    assert_eq!(obj(text).unwrap().surfaces.len(), 1);
}

const HEAD: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\ncstype bezier\ndeg 1 1\n";

#[test]
fn obj_errors_are_located() {
    let cases: &[(&str, usize, usize, &str)] = &[
        (
            "v 0 0 0\ncstype cardinal\n",
            2,
            8,
            "cstype cardinal is not supported",
        ),
        (
            "cstype rat taylor\n",
            1,
            12,
            "cstype taylor is not supported",
        ),
        ("cstype bmatrix\n", 1, 8, "not supported"),
        ("cstype nurbs\n", 1, 8, "unknown cstype"),
        (
            "v 0 0 0\ndeg 1 1\nsurf 0 1 0 1 1\n",
            3,
            1,
            "needs a preceding `cstype`",
        ),
        (
            "v 0 0 0\ncstype bezier\nsurf 0 1 0 1 1\n",
            3,
            1,
            "needs a preceding `deg`",
        ),
        ("v 0 0 0\n  deg 3\n", 2, 3, "only surfaces"),
        (
            "deg 0 1\n",
            1,
            5,
            "degree in u must be an integer from 1 to 64",
        ),
        ("deg 1 65\n", 1, 7, "degree in v must be"),
        ("v 0 nan 0\n", 1, 5, "not finite"),
        ("v 0 0\n", 1, 1, "`v` needs 3 coordinates"),
        ("v 0 0 0 1 2\n", 1, 1, "`v` needs 3 coordinates"),
        ("v 0 x 0\n", 1, 5, "expected a number"),
        ("parm u 0 1\n", 1, 1, "outside a `surf`"),
        ("end\n", 1, 1, "`end` without a `surf`"),
        ("curv 0 1 1 2\n", 1, 1, "free-form curves are not supported"),
        ("curv2 1 2\n", 1, 1, "free-form curves are not supported"),
    ];
    for &(text, line, column, words) in cases {
        assert_error(obj(text), line, column, words);
    }
    let block: &[(&str, usize, usize, &str)] = &[
        (
            "surf 0 1 0 1 1 2 3 0\n",
            7,
            20,
            "vertex reference 0 is invalid",
        ),
        ("surf 0 1 0 1 1 2 3 5\n", 7, 20, "out of range: 4 vertices"),
        ("surf 0 1 0 1 1 2 3 -5\n", 7, 20, "out of range"),
        (
            "surf 0 1 0 1 1 2 3 -9223372036854775808\n",
            7,
            20,
            "out of range",
        ),
        (
            "surf 0 1 0 1 1 2 3 x/1\n",
            7,
            20,
            "expected a vertex reference",
        ),
        (
            "surf 0 1 0 1 1 2 3 /1\n",
            7,
            20,
            "expected a vertex reference",
        ),
        ("surf 0 1 0 inf 1 2 3 4\n", 7, 12, "not finite"),
        ("surf 0 1 0 1\n", 7, 1, "needs its parameter range"),
        (
            "surf 0 1 0 1 1 2 3 4\nparm u 0 1\nparm v 0 1\n",
            7,
            1,
            "not closed by `end` (the file ends)",
        ),
        (
            "surf 0 1 0 1 1 2 3 4\nparm u 0 1\nv 0 0 0\nend\n",
            7,
            1,
            "line 9 starts a `v`",
        ),
        (
            "surf 0 1 0 1 1 2 3 4\nparm u 0 1\nsurf 0 1 0 1 1 2 3 4\n",
            7,
            1,
            "not closed",
        ),
        (
            "surf 0 1 0 1 1 2 3 4\nparm u 0 1\ntrim 0 1 1\n",
            9,
            1,
            "trimming curves",
        ),
        (
            "surf 0 1 0 1 1 2 3 4\nhole 0 1 1\n",
            8,
            1,
            "`hole`: trimming",
        ),
        ("surf 0 1 0 1 1 2 3 4\nscrv 0 1 1\n", 8, 1, "not supported"),
        ("surf 0 1 0 1 1 2 3 4\nsp 1\n", 8, 1, "not supported"),
        ("surf 0 1 0 1 1 2 3 4\nparm w 0 1\n", 8, 6, "must be u or v"),
        ("surf 0 1 0 1 1 2 3 4\nparm\n", 8, 1, "needs a direction"),
        (
            "surf 0 1 0 1 1 2 3 4\nparm u 0 1\nparm u 0 1\n",
            9,
            1,
            "second `parm u`",
        ),
        (
            "surf 0 1 0 1 1 2 3 4\nparm u 0 1\nend\n",
            7,
            1,
            "no `parm v`",
        ),
        (
            "surf 0 1 0 1 1 2 3 4\nparm u 0\nparm v 0 1\nend\n",
            8,
            1,
            "at least 2 breaks",
        ),
        (
            "surf 0 1 0 1 1 2 3 4\nparm u 0 0.5 1\nparm v 0 1\nend\n",
            7,
            1,
            "lists 4 control points, but its `parm u` and `parm v` describe a 3 × 2 net",
        ),
        (
            "surf 0 1 0 1 1 2 3 4\nparm u 0 1\nparm v 1 0\nend\n",
            7,
            1,
            "surface: knots_v",
        ),
        (
            "surf 0 1 0 0.5 1 2 3 4\nparm u 0 1\nparm v 0 1\nend\n",
            7,
            1,
            "a parameter range inside the knot domain is not supported",
        ),
        (
            "surf 0 1 0 1 1 2 3 4\nparm u 0 1\nparm v 0 1 x\nend\n",
            9,
            12,
            "expected a number",
        ),
    ];
    for &(tail, line, column, words) in block {
        assert_error(obj(&format!("{HEAD}{tail}")), line, column, words);
    }
    // Within 1e-12 relative of the domain is accepted.
    let near = format!("{HEAD}surf 0 1.0000000000001 0 1 1 2 3 4\nparm u 0 1\nparm v 0 1\nend\n");
    assert!(obj(&near).is_ok());
    // A B-spline knot vector too short for its degree is reported on its `parm`.
    let short = "v 0 0 0\ncstype bspline\ndeg 2 1\nsurf 0 1 0 1 1 1 1 1 1 1\nparm u 0 0 0 1 1\nparm v 0 0 1 1\nend\n";
    assert_error(obj(short), 5, 1, "a degree-2 B-spline needs at least 6");
    // Rational weights are validated by the surface.
    let zero_w = "v 0 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\ncstype rat bezier\ndeg 1 1\nsurf 0 1 0 1 1 2 3 4\nparm u 0 1\nparm v 0 1\nend\n";
    assert_error(obj(zero_w), 7, 1, "surface: ");
    // No surfaces at all.
    for text in ["", "v 0 0 0\nf 1 1 1\n", "\u{feff}# nothing\n"] {
        let e = obj(text).unwrap_err().to_string();
        assert_eq!(e, "s.obj: no free-form surfaces (`surf`) in file");
    }
}

#[test]
fn bpt_errors_are_located() {
    let patch = "3 3\n".to_string() + &"1 2 3\n".repeat(16);
    let cases: Vec<(String, usize, usize, &str)> = vec![
        ("".into(), 1, 1, "empty file"),
        ("  x\n".into(), 1, 3, "expected the number of patches"),
        ("-1\n".into(), 1, 1, "expected the number of patches"),
        ("0\n".into(), 1, 1, "declares no patches"),
        ("100001\n".into(), 1, 1, "exceed the limit of 100000"),
        (
            "99999999999999999999999\n".into(),
            1,
            1,
            "expected the number of patches",
        ),
        (format!("5\n{patch}"), 1, 1, "5 patches cannot fit"),
        (
            format!("2\n{patch}{}", " ".repeat(30)),
            18,
            6,
            "file ends early: expected the degrees of patch 2",
        ),
        (
            format!("1\n{patch}1\n"),
            19,
            1,
            "unexpected \"1\" after the last of 1 patches",
        ),
        (
            "1\n0 3\n".to_string() + &"0 0 0\n".repeat(4),
            2,
            1,
            "patch 1: degree in u must be",
        ),
        (
            "1\n3 65\n".to_string() + &"0 0 0\n".repeat(4),
            2,
            3,
            "degree in v must be",
        ),
        (
            "1\n3 3.0\n".to_string() + &"0 0 0\n".repeat(4),
            2,
            3,
            "degree in v must be",
        ),
        (
            "1\n64 64\n".to_string() + &"0 0 0\n".repeat(4),
            2,
            6,
            "4225 points of degree 64×64 cannot fit",
        ),
        (
            format!("1\n3 3\n1 2 nan\n{}", "1 2 3\n".repeat(15)),
            3,
            5,
            "coordinate z of point 1 of patch 1 is not finite",
        ),
        (
            format!("1\n3 3\n1 2 3\n1 2 -inf\n{}", "1 2 3\n".repeat(14)),
            4,
            5,
            "coordinate z of point 2",
        ),
        (
            format!("1\n3 3\n1e200 2 3\n{}", "1 2 3\n".repeat(15)),
            2,
            1,
            "patch 1: ",
        ),
        (
            format!("1\n{}", &patch[..patch.len() - 3]),
            2,
            4,
            "16 points of degree 3×3 cannot fit in the 94 bytes",
        ),
        (
            format!("1\n3 3\n{}10 20", "10 20 30\n".repeat(15)),
            18,
            6,
            "file ends early: expected coordinate z of point 16 of patch 1",
        ),
    ];
    for (text, line, column, words) in cases {
        assert_error(bpt(&text), line, column, words);
    }
}

#[test]
fn bpt_accepts_blank_lines_crlf_and_other_degrees() {
    let text = "\r\n 2 \r\n\r\n1 2\r\n".to_string()
        + &"0 0 0\t\n".repeat(6)
        + "\n2 1   \n"
        + &"1 1 1\n".repeat(6)
        + "\n\n";
    let f = bpt(&text).unwrap();
    assert_eq!(f.lines, vec![4, 12]);
    assert_eq!(f.surfaces[0].size(), [2, 3]);
    assert_eq!(f.surfaces[1].degree(), [2, 1]);
}

/// Surfaces exercising the writer: the teapot, the hand-written ones, and a rational surface
/// with awkward weights and knots.
fn sample_surfaces() -> Vec<NurbsSurface> {
    let mut all = decode_bpt(TEAPOT_BPT, Path::new("t.bpt")).unwrap().surfaces;
    all.extend(obj(BSPLINE).unwrap().surfaces);
    all.extend(obj(RATIONAL).unwrap().surfaces);
    let mut points = Vec::new();
    let mut weights = Vec::new();
    for i in 0..5 {
        for j in 0..4 {
            let (x, y) = (f64::from(i), f64::from(j));
            points.push([x / 3.0, y * 1e-7, (x * y).sin() * 1e17]);
            weights.push(0.3 + 0.1 * x + 0.01 * y);
        }
    }
    let knots_u = vec![
        -1.0 / 3.0,
        -1.0 / 3.0,
        -1.0 / 3.0,
        0.1,
        0.2,
        2.0 / 3.0,
        2.0 / 3.0,
        2.0 / 3.0,
    ];
    let knots_v = vec![0.0, 0.0, 0.0, 0.0, 1e-3, 1e-3, 1e-3, 1e-3];
    all.push(NurbsSurface::new([2, 3], [5, 4], &points, Some(&weights), knots_u, knots_v).unwrap());
    all
}

#[test]
fn encode_then_decode_is_bit_exact() {
    let surfaces = sample_surfaces();
    let bytes = encode_obj_surfaces(&surfaces);
    let text = String::from_utf8(bytes.clone()).unwrap();
    assert!(text.contains("cstype rat bspline\ndeg 2 3\n"));
    assert!(text.contains("cstype bspline\ndeg 3 3\nsurf 0 1 0 1 \\\n 1 2 3 4 5 6 7 8 \\\n 9 "));
    let back = decode_obj_surfaces(&bytes, Path::new("back.obj")).unwrap();
    assert_eq!(back.surfaces.len(), surfaces.len());
    for (k, (a, b)) in surfaces.iter().zip(&back.surfaces).enumerate() {
        assert_eq!(a.degree(), b.degree(), "surface {k}");
        assert_eq!(a.size(), b.size(), "surface {k}");
        assert_eq!(a.knots_u(), b.knots_u(), "surface {k}");
        assert_eq!(a.knots_v(), b.knots_v(), "surface {k}");
        assert_eq!(a.is_rational(), b.is_rational(), "surface {k}");
        let [n_u, n_v] = a.size();
        for i in 0..n_u {
            for j in 0..n_v {
                let (pa, pb) = (a.control_point(i, j), b.control_point(i, j));
                assert_eq!(
                    pa.to_array().map(f64::to_bits),
                    pb.to_array().map(f64::to_bits),
                    "surface {k} ({i}, {j})"
                );
                let (wa, wb) = (a.homogeneous_point(i, j).w, b.homogeneous_point(i, j).w);
                assert_eq!(wa.to_bits(), wb.to_bits(), "surface {k} ({i}, {j})");
            }
        }
    }
    // Writing what was read gives the same bytes.
    assert_eq!(encode_obj_surfaces(&back.surfaces), bytes);
}

/// xorshift64*: a fixed-seed byte source for the mutation test.
fn rng(seed: u64) -> impl FnMut() -> u64 {
    let mut s = seed;
    move || {
        s ^= s >> 12;
        s ^= s << 25;
        s ^= s >> 27;
        s.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
}

#[test]
fn truncated_and_mutated_files_do_not_panic() {
    let encoded = encode_obj_surfaces(&sample_surfaces());
    let inputs: [(&[u8], &str); 3] = [
        (TEAPOT_BPT, "t.bpt"),
        (TEAPOT_OBJ, "t.obj"),
        (&encoded, "e.obj"),
    ];
    for (bytes, name) in inputs {
        let path = Path::new(name);
        for n in 0..bytes.len().min(2048) {
            let _ = decode_patches(&bytes[..n], path);
        }
        let mut next = rng(0x9e37_79b9_7f4a_7c15);
        let specials: &[u8] = b" \n\r\t\\/#-+.0123456789eEnaif\xff\x00";
        for _ in 0..300 {
            let mut m = bytes.to_vec();
            for _ in 0..1 + next() % 4 {
                let at = (next() % m.len() as u64) as usize;
                m[at] = if next() % 2 == 0 {
                    specials[(next() % specials.len() as u64) as usize]
                } else {
                    next() as u8
                };
            }
            let _ = decode_patches(&m, path);
            let _ = decode_bpt(&m, path);
            let _ = decode_obj_surfaces(&m, path);
        }
    }
}

#[test]
fn huge_counts_are_refused_before_allocating() {
    // A count that would need terabytes if trusted.
    assert_error(bpt("100000 3 3 1 2 3"), 1, 1, "cannot fit");
    // A long surf line is bounded by the per-surface limit, not by memory.
    let mut text = String::from("v 0 0 0\ncstype bspline\ndeg 1 1\nsurf 0 1 0 1");
    text += &" 1".repeat(MAX_SURFACE_POINTS + 1);
    let (line, column, message) = located(obj(&text));
    assert_eq!(
        (line, column),
        (4, 14 + 2 * MAX_SURFACE_POINTS),
        "{message}"
    );
    assert!(
        message.contains("more than 1048576 control points"),
        "{message}"
    );
    // Non-UTF-8 bytes are errors, not panics.
    assert_error(
        decode_obj_surfaces(b"v 0 \xff 0\n", Path::new("s.obj")),
        1,
        5,
        "expected a number",
    );
    assert_error(
        decode_bpt(b"\xff", Path::new("p.bpt")),
        1,
        1,
        "expected the number",
    );
}
