//! Wavefront OBJ free-form surfaces (`surf`): reader and writer.
//!
//! Read: `v x y z [w]`, `cstype [rat] bezier|bspline`, `deg du dv`,
//! `surf s0 s1 t0 t1 v1 v2 …` (references `v`, `v/vt`, `v/vt/vn` or `v//vn`; only `v` is used;
//! a negative reference counts back from the last vertex read so far), `parm u|v …`, `end`.
//! A line ending in `\` continues on the next one; `#` starts a comment. Ignored: `vt`, `vn`,
//! `vp`, `g`, `o`, `s`, `mg`, `usemtl`, `mtllib`, `ctech`, `stech`, `bmat`, `step`, `con`,
//! display attributes, polygonal `f`/`l`/`p` and unknown keywords.
//!
//! Refused with a located error: `cstype cardinal|taylor|bmatrix`, trimming and special
//! curves/points (`trim`, `hole`, `scrv`, `sp`), free-form curves (`curv`, `curv2`), a `surf`
//! without a preceding `cstype` or `deg`, a reference to a vertex not yet read, `parm` counts
//! that do not fit the control points, a `surf` range other than the knot domain, a `surf` not
//! closed by `end`, and a file with no `surf`.
//!
//! Semantics (OBJ 3.0 specification, "Free-form geometry" and "Mathematics for free-form
//! curves/surfaces"):
//! - A surface's control points are listed with **u varying fastest**: reference
//!   `k` is net point (i = k mod n_u, j = k div n_u). It is transposed into the row-major
//!   order of [`NurbsSurface`] (`points[i * n_v + j]`, i along u).
//! - `bspline`: `parm u` is the whole knot vector, so n_u = (values) − du − 1.
//! - `bezier`: `parm u` holds the k + 1 break values of k segments, n_u = du·k + 1; the knots
//!   are the first break du+1 times, each interior break du times and the last du+1 times.
//! - The weight `w` of `v` is used only by `rat` types; a non-rational surface ignores it, as
//!   the specification says.
//! - `surf s0 s1 t0 t1` must be the knot domain (to 1e-12 relative): a range inside it would
//!   mean evaluating part of the surface, which is not supported.

use std::path::Path;

use super::{
    parse_degree, parse_finite, shown, tokens, Locator, PatchFile, Token, MAX_FILE_POINTS,
    MAX_PATCHES, MAX_SURFACE_POINTS,
};
use crate::io::{push_f64, push_u64, IoError};
use crate::nurbs::surface::NurbsSurface;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Basis {
    Bezier,
    Bspline,
}

/// A `surf` waiting for its `end`.
struct Open<'a> {
    keyword: Token<'a>,
    basis: Basis,
    rational: bool,
    degree: [usize; 2],
    range: [f64; 4],
    /// 0-based vertex indices, in file order (u fastest).
    refs: Vec<usize>,
    /// `parm u` and `parm v`: the keyword and the values.
    parm: [Option<(Token<'a>, Vec<f64>)>; 2],
}

/// Logical statements: physical lines joined at a trailing `\`, comments removed. Each token
/// keeps its physical position.
fn statements(bytes: &[u8]) -> impl Iterator<Item = Vec<Token<'_>>> {
    let mut rest = Some((bytes, 0usize, 1usize));
    std::iter::from_fn(move || {
        let mut statement = Vec::new();
        while let Some((text, offset, line)) = rest {
            let (raw, next) = match text.iter().position(|&b| b == b'\n') {
                Some(n) => (&text[..n], Some((&text[n + 1..], offset + n + 1, line + 1))),
                None => (text, None),
            };
            rest = next;
            let mut content = raw;
            if let Some(hash) = content.iter().position(|&b| b == b'#') {
                content = &content[..hash];
            }
            while let [head @ .., last] = content {
                if last.is_ascii_whitespace() {
                    content = head;
                } else {
                    break;
                }
            }
            let continued = content.last() == Some(&b'\\');
            if continued {
                content = &content[..content.len() - 1];
            }
            statement.extend(tokens(content).map(|t| Token {
                line,
                offset: offset + t.offset,
                ..t
            }));
            if !continued && !statement.is_empty() {
                return Some(statement);
            }
        }
        (!statement.is_empty()).then_some(statement)
    })
}

/// Decodes the free-form surfaces of an OBJ file; `path` names it in errors.
pub fn decode_obj_surfaces(bytes: &[u8], path: &Path) -> Result<PatchFile, IoError> {
    let at = Locator { path };
    let mut vertices: Vec<[f64; 4]> = Vec::new();
    let mut cstype: Option<(Basis, bool)> = None;
    let mut degree: Option<[usize; 2]> = None;
    let mut open: Option<Open> = None;
    let mut out = PatchFile {
        surfaces: Vec::new(),
        lines: Vec::new(),
    };
    let mut total_points = 0usize;
    for statement in statements(bytes) {
        let keyword = statement[0];
        let args = &statement[1..];
        let name = keyword.text;
        let closes = matches!(
            name,
            b"v" | b"cstype"
                | b"deg"
                | b"surf"
                | b"curv"
                | b"curv2"
                | b"f"
                | b"l"
                | b"p"
                | b"bmat"
                | b"step"
                | b"con"
        );
        if let (true, Some(o)) = (closes, &open) {
            return Err(unclosed(&at, o, Some(&keyword)));
        }
        match name {
            b"v" => {
                if !(3..=4).contains(&args.len()) {
                    return Err(
                        at.token(&keyword, "`v` needs 3 coordinates and an optional weight")
                    );
                }
                let mut v = [0.0, 0.0, 0.0, 1.0];
                for (slot, t) in v.iter_mut().zip(args) {
                    *slot = parse_finite(t, "vertex coordinate", &at)?;
                }
                vertices.push(v);
            }
            b"cstype" => cstype = Some(parse_cstype(&at, &keyword, args)?),
            b"deg" => {
                if args.len() != 2 {
                    return Err(at.token(
                        &keyword,
                        "`deg` needs two degrees (du dv): only surfaces are supported",
                    ));
                }
                degree = Some([
                    parse_degree(&args[0], "degree in u", &at)?,
                    parse_degree(&args[1], "degree in v", &at)?,
                ]);
            }
            b"surf" => {
                let (basis, rational) = cstype
                    .ok_or_else(|| at.token(&keyword, "`surf` needs a preceding `cstype`"))?;
                let degree =
                    degree.ok_or_else(|| at.token(&keyword, "`surf` needs a preceding `deg`"))?;
                if out.surfaces.len() == MAX_PATCHES {
                    return Err(at.token(
                        &keyword,
                        format!("more than {MAX_PATCHES} surfaces in one file"),
                    ));
                }
                if args.len() < 5 {
                    return Err(at.token(
                        &keyword,
                        "`surf` needs its parameter range s0 s1 t0 t1 and control points",
                    ));
                }
                let mut range = [0.0; 4];
                for (slot, t) in range.iter_mut().zip(args) {
                    *slot = parse_finite(t, "surface parameter range", &at)?;
                }
                let mut refs = Vec::new();
                for t in &args[4..] {
                    if refs.len() == MAX_SURFACE_POINTS {
                        return Err(at.token(
                            t,
                            format!("a surface has more than {MAX_SURFACE_POINTS} control points"),
                        ));
                    }
                    if total_points == MAX_FILE_POINTS {
                        return Err(at.token(
                            t,
                            format!(
                                "the file's control points exceed the limit of {MAX_FILE_POINTS}"
                            ),
                        ));
                    }
                    refs.push(vertex_ref(&at, t, vertices.len())?);
                    total_points += 1;
                }
                open = Some(Open {
                    keyword,
                    basis,
                    rational,
                    degree,
                    range,
                    refs,
                    parm: [None, None],
                });
            }
            b"parm" => {
                let o = open
                    .as_mut()
                    .ok_or_else(|| at.token(&keyword, "`parm` outside a `surf` … `end` block"))?;
                let dir_tok = args
                    .first()
                    .ok_or_else(|| at.token(&keyword, "`parm` needs a direction (u or v)"))?;
                let dir = match dir_tok.text {
                    b"u" => 0,
                    b"v" => 1,
                    other => {
                        return Err(at.token(
                            dir_tok,
                            format!("`parm` direction must be u or v, found {:?}", shown(other)),
                        ))
                    }
                };
                if o.parm[dir].is_some() {
                    return Err(at.token(
                        &keyword,
                        format!(
                            "a second `parm {}` for the same surface",
                            "uv".as_bytes()[dir] as char
                        ),
                    ));
                }
                let values = args[1..]
                    .iter()
                    .map(|t| parse_finite(t, "parameter value", &at))
                    .collect::<Result<Vec<f64>, IoError>>()?;
                o.parm[dir] = Some((keyword, values));
            }
            b"end" => {
                let o = open
                    .take()
                    .ok_or_else(|| at.token(&keyword, "`end` without a `surf`"))?;
                let line = o.keyword.line;
                out.surfaces.push(finish(&at, &vertices, o)?);
                out.lines.push(line);
            }
            b"trim" | b"hole" | b"scrv" | b"sp" => {
                return Err(at.token(
                    &keyword,
                    format!(
                        "`{}`: trimming curves and special curves/points are not supported",
                        shown(name)
                    ),
                ))
            }
            b"curv" | b"curv2" => {
                return Err(at.token(
                    &keyword,
                    format!(
                        "`{}`: free-form curves are not supported, only surfaces",
                        shown(name)
                    ),
                ))
            }
            _ => {}
        }
    }
    if let Some(o) = &open {
        return Err(unclosed(&at, o, None));
    }
    if out.surfaces.is_empty() {
        return Err(IoError::Malformed {
            path: path.to_path_buf(),
            message: "no free-form surfaces (`surf`) in file".into(),
        });
    }
    Ok(out)
}

fn unclosed(at: &Locator, o: &Open, by: Option<&Token>) -> IoError {
    let message = match by {
        Some(t) => format!(
            "`surf` is not closed by `end` (line {} starts a `{}` statement)",
            t.line,
            shown(t.text)
        ),
        None => "`surf` is not closed by `end` (the file ends)".into(),
    };
    at.token(&o.keyword, message)
}

fn parse_cstype(at: &Locator, keyword: &Token, args: &[Token]) -> Result<(Basis, bool), IoError> {
    let (rational, kind) = match args {
        [t] => (false, t),
        [r, t] if r.text == b"rat" => (true, t),
        _ => return Err(at.token(keyword, "`cstype` needs a type, optionally after `rat`")),
    };
    match kind.text {
        b"bezier" => Ok((Basis::Bezier, rational)),
        b"bspline" => Ok((Basis::Bspline, rational)),
        b"cardinal" | b"taylor" | b"bmatrix" => Err(at.token(
            kind,
            format!(
                "cstype {} is not supported (only bezier and bspline)",
                shown(kind.text)
            ),
        )),
        other => Err(at.token(kind, format!("unknown cstype {:?}", shown(other)))),
    }
}

/// Resolves a `v`, `v/vt`, `v/vt/vn` or `v//vn` reference to a 0-based vertex index.
fn vertex_ref(at: &Locator, t: &Token, count: usize) -> Result<usize, IoError> {
    let v = t.text.split(|&b| b == b'/').next().unwrap_or_default();
    let index = std::str::from_utf8(v)
        .ok()
        .and_then(|s| s.parse::<i64>().ok())
        .ok_or_else(|| {
            at.token(
                t,
                format!("expected a vertex reference, found {:?}", shown(t.text)),
            )
        })?;
    let resolved = match index {
        0 => None,
        i if i > 0 => usize::try_from(i - 1).ok().filter(|&k| k < count),
        i => usize::try_from(i.unsigned_abs())
            .ok()
            .and_then(|back| count.checked_sub(back)),
    };
    resolved.ok_or_else(|| {
        let why = if index == 0 {
            "vertex reference 0 is invalid (OBJ counts from 1)".to_string()
        } else {
            format!(
                "vertex reference {index} is out of range: {count} vertices are defined before it"
            )
        };
        at.token(t, why)
    })
}

/// Net size along one direction from its `parm` values, and the knot vector.
fn knots_of(at: &Locator, o: &Open, dir: usize) -> Result<(usize, Vec<f64>), IoError> {
    let name = ["u", "v"][dir];
    let Some((keyword, values)) = &o.parm[dir] else {
        return Err(at.token(
            &o.keyword,
            format!("`surf` has no `parm {name}` before its `end`"),
        ));
    };
    let d = o.degree[dir];
    let l = values.len();
    match o.basis {
        Basis::Bspline => {
            if l < 2 * d + 2 {
                return Err(at.token(
                    keyword,
                    format!(
                        "`parm {name}` has {l} knots: a degree-{d} B-spline needs at least {}",
                        2 * d + 2
                    ),
                ));
            }
            Ok((l - d - 1, values.clone()))
        }
        Basis::Bezier => {
            if l < 2 {
                return Err(at.token(
                    keyword,
                    format!(
                        "`parm {name}` has {l} values: a Bézier surface needs at least 2 breaks"
                    ),
                ));
            }
            // l ≤ tokens in the file, d ≤ 64: no overflow on any real input; checked anyway.
            let n = d.checked_mul(l - 1).and_then(|n| n.checked_add(1));
            let n = n.filter(|&n| n <= MAX_SURFACE_POINTS).ok_or_else(|| {
                at.token(
                    keyword,
                    format!("`parm {name}` makes too many control points"),
                )
            })?;
            let mut knots = Vec::with_capacity(n + d + 1);
            knots.extend(std::iter::repeat_n(values[0], d + 1));
            for &b in &values[1..l - 1] {
                knots.extend(std::iter::repeat_n(b, d));
            }
            knots.extend(std::iter::repeat_n(values[l - 1], d + 1));
            Ok((n, knots))
        }
    }
}

/// Builds the surface of a closed `surf` … `end` block.
fn finish(at: &Locator, vertices: &[[f64; 4]], o: Open) -> Result<NurbsSurface, IoError> {
    let (n_u, knots_u) = knots_of(at, &o, 0)?;
    let (n_v, knots_v) = knots_of(at, &o, 1)?;
    if n_u.checked_mul(n_v) != Some(o.refs.len()) {
        return Err(at.token(
            &o.keyword,
            format!(
                "`surf` lists {} control points, but its `parm u` and `parm v` describe a {n_u} × {n_v} net",
                o.refs.len()
            ),
        ));
    }
    // File order is u fastest: reference k is (i = k % n_u, j = k / n_u).
    let mut points = Vec::with_capacity(o.refs.len());
    let mut weights = Vec::with_capacity(if o.rational { o.refs.len() } else { 0 });
    for i in 0..n_u {
        for j in 0..n_v {
            let v = vertices[o.refs[j * n_u + i]];
            points.push([v[0], v[1], v[2]]);
            if o.rational {
                weights.push(v[3]);
            }
        }
    }
    let weights = o.rational.then_some(&weights[..]);
    let surface = NurbsSurface::new(o.degree, [n_u, n_v], &points, weights, knots_u, knots_v)
        .map_err(|e| at.token(&o.keyword, format!("surface: {e}")))?;
    let [[a, b], [c, d]] = surface.domain();
    let [s0, s1, t0, t1] = o.range;
    let off = |x: f64, y: f64, lo: f64, hi: f64| {
        let tol = 1e-12 * lo.abs().max(hi.abs()).max(hi - lo);
        (x - lo).abs() > tol || (y - hi).abs() > tol
    };
    if off(s0, s1, a, b) || off(t0, t1, c, d) {
        return Err(at.token(
            &o.keyword,
            format!(
                "`surf` range [{s0}, {s1}] × [{t0}, {t1}] is not the knot domain [{a}, {b}] × [{c}, {d}]: a parameter range inside the knot domain is not supported"
            ),
        ));
    }
    Ok(surface)
}

/// Writes `surfaces` as OBJ free-form B-spline surfaces: per surface its control points as
/// `v` lines (with the weight if it is rational), `cstype [rat] bspline`, `deg`, `surf` over
/// the knot domain (references u fastest, continued every 8), `parm u`, `parm v` and `end`.
/// Floats are written in their shortest round-trip form, so [`decode_obj_surfaces`] reads
/// back the same knots, weights and Euclidean control points.
pub fn encode_obj_surfaces(surfaces: &[NurbsSurface]) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(b"# NURBS surfaces written by graftal\n");
    let mut next_vertex = 1u64;
    for s in surfaces {
        let [n_u, n_v] = s.size();
        let rational = s.is_rational();
        for j in 0..n_v {
            for i in 0..n_u {
                let p = s.control_point(i, j);
                out.extend_from_slice(b"v");
                for x in [p.x, p.y, p.z] {
                    out.push(b' ');
                    push_f64(&mut out, x);
                }
                if rational {
                    out.push(b' ');
                    push_f64(&mut out, s.homogeneous_point(i, j).w);
                }
                out.push(b'\n');
            }
        }
        out.extend_from_slice(if rational {
            b"cstype rat bspline\ndeg "
        } else {
            b"cstype bspline\ndeg "
        });
        let [p, q] = s.degree();
        push_u64(&mut out, p as u64);
        out.push(b' ');
        push_u64(&mut out, q as u64);
        out.extend_from_slice(b"\nsurf");
        for x in s.domain().as_flattened() {
            out.push(b' ');
            push_f64(&mut out, *x);
        }
        for k in 0..n_u * n_v {
            out.extend_from_slice(if k % 8 == 0 { b" \\\n " } else { b" " });
            push_u64(&mut out, next_vertex);
            next_vertex += 1;
        }
        for (name, knots) in [("u", s.knots_u()), ("v", s.knots_v())] {
            out.extend_from_slice(b"\nparm ");
            out.extend_from_slice(name.as_bytes());
            for x in knots {
                out.push(b' ');
                push_f64(&mut out, *x);
            }
        }
        out.extend_from_slice(b"\nend\n");
    }
    out
}
