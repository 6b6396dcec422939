//! Parametric surfaces: `[nurbs.NAME]` tables compiled into the program's
//! [`SurfaceDef`]s (thesis 002 §1.2; spec §4.3). Every number takes an
//! expression over the parameters; `points` and `weights` may instead be
//! generators over the net indices `i` (along u) and `j` (along v). After
//! the parameters are compiled, each surface is built once at nominal
//! parameter values, so knot vectors of the wrong length, decreasing knots,
//! weights ≤ 0 or a degree too high for its points are located errors
//! before the run.

use std::ops::Range;

use super::{as_scalar, closest_in, Compiler};
use crate::nurbs::patchset::Side;
use crate::rules::ast::{self, ArgValue, Scalar as AstScalar};
use crate::rules::diagnostic::RuleError;
use crate::rules::expr::Expr;
use crate::rules::nurbs_def::{
    JoinDef, Kind, Knots, Orient, PatchSource, Points, Profile, SurfaceDef, Weights,
    GENERATOR_NAMES,
};
use crate::rules::program::{Param, Resource, ResourceKind, Scalar};
use crate::rules::spanned::Spanned;

/// The keys a `[nurbs.NAME]` table takes.
pub const SURFACE_KEYS: [&str; 13] = [
    "degree",
    "size",
    "points",
    "weights",
    "knots_u",
    "knots_v",
    "profile",
    "knots",
    "path",
    "orient",
    "path_tolerance",
    "patches",
    "joins",
];

/// `patches` and `joins` (indices into [`SURFACE_KEYS`]).
const PATCHES: usize = 11;
const JOINS: usize = 12;

/// The keys a curve takes (indices into [`SURFACE_KEYS`]).
const CURVE_KEYS: [usize; 5] = [0, 1, 2, 3, 7];

/// The keys a surface made of named curves takes besides `profile`.
const SWEEP_KEYS: [usize; 3] = [8, 9, 10];

/// `orient` of a sweep.
const ORIENTS: [&str; 2] = ["follow", "fixed"];

/// The knot shorthand.
const CLAMPED_UNIFORM: &str = "clamped_uniform";

impl Compiler<'_> {
    /// Compiles every `[nurbs.NAME]` table, in file order.
    pub(super) fn compile_surfaces(&self) -> Result<Vec<SurfaceDef>, RuleError> {
        self.nurbs_defs
            .0
            .iter()
            .map(|(name, table)| self.surface(&name.value, table))
            .collect()
    }

    /// The index of the surface `surface = "NAME"` names.
    pub(super) fn surface_reference(&self, value: &Spanned<ArgValue>) -> Result<usize, RuleError> {
        let names: Vec<&str> = self
            .nurbs_defs
            .0
            .iter()
            .map(|(n, _)| n.value.as_str())
            .collect();
        let (ArgValue::Text(name) | ArgValue::Name(name)) = &value.value else {
            return Err(self.error(
                value.span.clone(),
                format!(
                    "invalid type: {}, expected the name of a [nurbs.NAME] surface",
                    value.value.describe()
                ),
            ));
        };
        if let Some(k) = names.iter().position(|n| n == name) {
            if is_curve_table(&self.nurbs_defs.0[k].1.value) {
                return Err(self
                    .error(value.span.clone(), format!("`{name}` is a curve, not a surface"))
                    .with_help(format!(
                        "make a surface of it: a [nurbs.NAME] table with profile = \"{name}\" (a lathe) or with a path to sweep it along"
                    )));
            }
        }
        names.iter().position(|n| n == name).ok_or_else(|| {
            let e = self.error(
                value.span.clone(),
                format!("no nurbs surface named `{name}`"),
            );
            match closest_in(name, &names) {
                Some(k) => e.with_help(format!("did you mean `{}`?", names[k])),
                None if names.is_empty() => {
                    e.with_help("define it as a table [nurbs.NAME] with degree, size and points")
                }
                None => e.with_help(format!("nurbs surfaces: {}", names.join(", "))),
            }
        })
    }

    fn surface(&self, name: &str, table: &Spanned<ast::Args>) -> Result<SurfaceDef, RuleError> {
        let mut values: [Option<&Spanned<ArgValue>>; SURFACE_KEYS.len()] =
            [None; SURFACE_KEYS.len()];
        for (key, value) in &table.value.0 {
            let Some(i) = SURFACE_KEYS.iter().position(|k| *k == key.value) else {
                let listed: Vec<String> = SURFACE_KEYS.iter().map(|k| format!("`{k}`")).collect();
                let e = self.error(
                    key.span.clone(),
                    format!(
                        "unknown field `{}` of a nurbs surface, expected one of {}",
                        key.value,
                        listed.join(", ")
                    ),
                );
                return Err(match closest_in(&key.value, &SURFACE_KEYS) {
                    Some(k) => e.with_help(format!("did you mean `{}`?", SURFACE_KEYS[k])),
                    None => e,
                });
            };
            if values[i].is_some() {
                return Err(
                    self.error(key.span.clone(), format!("duplicate field `{}`", key.value))
                );
            }
            values[i] = Some(value);
        }
        let required = |i: usize| {
            values[i].ok_or_else(|| {
                self.error(
                    table.span.clone(),
                    format!(
                        "missing field `{}` of nurbs surface `{name}`",
                        SURFACE_KEYS[i]
                    ),
                )
            })
        };
        let refuse = |keys: &[usize], why: &str| -> Result<(), RuleError> {
            match keys.iter().find_map(|&k| values[k]) {
                Some(v) => Err(self.error(v.span.clone(), why.to_owned())),
                None => Ok(()),
            }
        };
        let location = self.location(table.span.as_ref());
        let def = |kind, degree, size, points, weights, knots| SurfaceDef {
            name: name.to_owned(),
            location: location.clone(),
            kind,
            degree,
            size,
            points,
            weights,
            knots,
        };
        if is_curve_table(&table.value) {
            let others: Vec<usize> = (0..SURFACE_KEYS.len())
                .filter(|k| !CURVE_KEYS.contains(k))
                .collect();
            refuse(
                &others,
                "a curve (one `size`) takes degree, size, points, weights and knots",
            )?;
            let degree = self.param_scalar(required(0)?)?;
            let points = self.points(required(2)?)?;
            let size = match (&points, values[1]) {
                (_, Some(s)) => self.param_scalar(s)?,
                (Points::List(list), None) => self.number(list.len() as f64, None)?,
                _ => {
                    return Err(self.error(
                        table.span.clone(),
                        format!("missing field `size` of nurbs curve `{name}`: the number of points a generator makes"),
                    ))
                }
            };
            let weights = values[3].map(|w| self.weights(w)).transpose()?;
            let knots = [self.knots(values[7])?, Knots::ClampedUniform];
            return Ok(def(
                Kind::Curve,
                [degree.clone(), degree],
                [size.clone(), size],
                points,
                weights,
                knots,
            ));
        }
        if let Some(patches) = values[PATCHES] {
            refuse(
                &(0..PATCHES).collect::<Vec<_>>(),
                "a patch set takes `patches` and `joins` only (its surfaces bring the rest)",
            )?;
            let (source, names) = self.patch_source(name, patches)?;
            let joins = match values[JOINS] {
                Some(j) => self.joins(j, &names)?,
                None => Vec::new(),
            };
            let one = self.number(1.0, None)?;
            return Ok(def(
                Kind::Surface,
                [one.clone(), one.clone()],
                [one.clone(), one],
                Points::Set {
                    patches: source,
                    joins,
                },
                None,
                [Knots::ClampedUniform, Knots::ClampedUniform],
            ));
        }
        refuse(&[JOINS], "`joins` belongs to a patch set (give `patches`)")?;
        refuse(
            &[7],
            "a surface has `knots_u` and `knots_v`; `knots` is a curve's",
        )?;
        let named_profile =
            values[6].filter(|p| matches!(p.value, ArgValue::Text(_) | ArgValue::Name(_)));
        if let Some(profile) = named_profile {
            // Everything comes from the named curves.
            refuse(
                &[0, 1, 2, 3, 4, 5],
                "a surface made of named curves takes their degree, points, weights and knots",
            )?;
            let profile = self.curve_reference(profile)?;
            let points = match values[8] {
                Some(path) => Points::Sweep {
                    profile,
                    path: self.curve_reference(path)?,
                    orient: match values[9] {
                        Some(v) => self.orient(v)?,
                        None => Orient::Follow,
                    },
                    tolerance: match values[10] {
                        Some(t) => self.param_scalar(t)?,
                        None => self.number(1e-3, None)?,
                    },
                },
                None => {
                    refuse(
                        &[9, 10],
                        "`orient` and `path_tolerance` belong to a sweep (give a `path`)",
                    )?;
                    Points::Revolve(Profile::Curve(profile))
                }
            };
            let one = self.number(1.0, None)?;
            return Ok(def(
                Kind::Surface,
                [one.clone(), one.clone()],
                [one.clone(), one],
                points,
                None,
                [Knots::ClampedUniform, Knots::ClampedUniform],
            ));
        }
        refuse(
            &SWEEP_KEYS,
            "a sweep's `profile` and `path` are the names of [nurbs.NAME] curves",
        )?;
        let (degree, size, points) = match (values[2], values[6]) {
            (Some(_), Some(profile)) => {
                return Err(self.error(
                    profile.span.clone(),
                    "a surface takes `points` (a control net) or `profile` (a surface of revolution), not both",
                ))
            }
            (None, Some(profile)) => {
                if let Some(k) = values[4] {
                    return Err(self.error(
                        k.span.clone(),
                        "a surface of revolution has the circle's knots along u: give `knots_v` only",
                    ));
                }
                let degree = self.param_scalar(required(0)?)?;
                let profile = self.profile(profile)?;
                let size = match (&profile, values[1]) {
                    (Profile::List(list), None) => self.number(list.len() as f64, None)?,
                    (_, Some(s)) => self.param_scalar(s)?,
                    _ => {
                        return Err(self.error(
                            table.span.clone(),
                            format!("missing field `size` of nurbs surface `{name}`: the number of profile points a generator makes"),
                        ))
                    }
                };
                (
                    [degree.clone(), degree],
                    [size.clone(), size],
                    Points::Revolve(profile),
                )
            }
            _ => (
                self.scalar_pair(required(0)?, true)?,
                self.scalar_pair(required(1)?, false)?,
                self.points(required(2)?)?,
            ),
        };
        let weights = values[3].map(|w| self.weights(w)).transpose()?;
        let knots = [self.knots(values[4])?, self.knots(values[5])?];
        Ok(def(Kind::Surface, degree, size, points, weights, knots))
    }

    /// A patch set's `patches`: a file path, or a list of surface names (returned too, for
    /// `joins`).
    fn patch_source(
        &self,
        name: &str,
        value: &Spanned<ArgValue>,
    ) -> Result<(PatchSource, Vec<String>), RuleError> {
        match &value.value {
            ArgValue::Text(written) => {
                let path = std::path::PathBuf::from(written);
                let path = if path.is_absolute() {
                    path
                } else {
                    self.base_dir.join(path)
                };
                let index = self.resource(Resource {
                    path,
                    written: written.clone(),
                    location: self.location(value.span.as_ref()),
                    kind: ResourceKind::Patches,
                });
                Ok((PatchSource::File(index), Vec::new()))
            }
            ArgValue::List(items) if !items.is_empty() => {
                let tables = &self.nurbs_defs.0;
                let mut indices = Vec::with_capacity(items.len());
                let mut names = Vec::with_capacity(items.len());
                for item in items {
                    let (ArgValue::Text(n) | ArgValue::Name(n)) = &item.value else {
                        return Err(self.error(
                            item.span.clone(),
                            "a patch set lists the names of [nurbs.NAME] surfaces",
                        ));
                    };
                    let k = self.surface_reference(item)?;
                    let table = &tables[k].1.value;
                    if n == name || table.0.iter().any(|(key, _)| key.value == "patches") {
                        return Err(self.error(
                            item.span.clone(),
                            format!("`{n}` is a patch set: a set lists single surfaces"),
                        ));
                    }
                    if names.contains(n) {
                        return Err(self.error(
                            item.span.clone(),
                            format!("`{n}` is listed twice"),
                        ));
                    }
                    indices.push(k);
                    names.push(n.clone());
                }
                Ok((PatchSource::Named(indices), names))
            }
            _ => Err(self.error(
                value.span.clone(),
                "`patches` is a patch file (\".bpt\" or OBJ free-form \".obj\") or a non-empty list of [nurbs.NAME] surface names",
            )),
        }
    }

    /// `joins = [["PATCH.SIDE", "PATCH.SIDE"], …]`: PATCH a listed surface's name, or a patch
    /// file's patch number (from 0); SIDE `u0`, `u1`, `v0` or `v1`.
    fn joins(
        &self,
        value: &Spanned<ArgValue>,
        names: &[String],
    ) -> Result<Vec<JoinDef>, RuleError> {
        let shape = |span: Option<Range<usize>>| {
            self.error(
                span,
                "`joins` is a list of pairs [\"PATCH.SIDE\", \"PATCH.SIDE\"] (PATCH a listed surface or a file's patch number from 0; SIDE u0, u1, v0 or v1)",
            )
        };
        let ArgValue::List(pairs) = &value.value else {
            return Err(shape(value.span.clone()));
        };
        let border = |item: &Spanned<ArgValue>| -> Result<(usize, Side), RuleError> {
            let ArgValue::Text(text) = &item.value else {
                return Err(shape(item.span.clone()));
            };
            let (patch, side) = text
                .rsplit_once('.')
                .ok_or_else(|| shape(item.span.clone()))?;
            let side = Side::parse(side).ok_or_else(|| {
                self.error(
                    item.span.clone(),
                    format!("unknown side `{side}`: a side is u0, u1, v0 or v1"),
                )
            })?;
            let patch = if names.is_empty() {
                patch.parse::<usize>().map_err(|_| {
                    self.error(
                        item.span.clone(),
                        format!("`{patch}` is not a patch number (the file's patches are numbered from 0)"),
                    )
                })?
            } else {
                names.iter().position(|n| n == patch).ok_or_else(|| {
                    self.error(
                        item.span.clone(),
                        format!(
                            "`{patch}` is not one of this set's patches ({})",
                            names.join(", ")
                        ),
                    )
                })?
            };
            Ok((patch, side))
        };
        let mut out = Vec::with_capacity(pairs.len());
        for pair in pairs {
            match &pair.value {
                ArgValue::List(two) if two.len() == 2 => out.push(JoinDef {
                    a: border(&two[0])?,
                    b: border(&two[1])?,
                }),
                _ => return Err(shape(pair.span.clone())),
            }
        }
        Ok(out)
    }

    /// The index of the curve a `profile` or `path` names.
    fn curve_reference(&self, value: &Spanned<ArgValue>) -> Result<usize, RuleError> {
        let (ArgValue::Text(name) | ArgValue::Name(name)) = &value.value else {
            return Err(self.error(
                value.span.clone(),
                format!(
                    "invalid type: {}, expected the name of a [nurbs.NAME] curve",
                    value.value.describe()
                ),
            ));
        };
        let tables = &self.nurbs_defs.0;
        let curves: Vec<&str> = tables
            .iter()
            .filter(|(_, t)| is_curve_table(&t.value))
            .map(|(n, _)| n.value.as_str())
            .collect();
        match tables.iter().position(|(n, _)| n.value == *name) {
            Some(k) if is_curve_table(&tables[k].1.value) => Ok(k),
            Some(_) => Err(self
                .error(value.span.clone(), format!("`{name}` is a surface, not a curve"))
                .with_help("a curve is a [nurbs.NAME] table with one `size` (or a list of points) and one `degree`")),
            None => {
                let e = self.error(value.span.clone(), format!("no nurbs curve named `{name}`"));
                Err(match closest_in(name, &curves) {
                    Some(k) => e.with_help(format!("did you mean `{}`?", curves[k])),
                    None if curves.is_empty() => e.with_help(
                        "define it as a table [nurbs.NAME] with degree, size (one number) and points",
                    ),
                    None => e.with_help(format!("nurbs curves: {}", curves.join(", "))),
                })
            }
        }
    }

    fn orient(&self, value: &Spanned<ArgValue>) -> Result<Orient, RuleError> {
        match &value.value {
            ArgValue::Text(t) | ArgValue::Name(t) if t == ORIENTS[0] => Ok(Orient::Follow),
            ArgValue::Text(t) | ArgValue::Name(t) if t == ORIENTS[1] => Ok(Orient::Fixed),
            other => Err(self
                .error(
                    value.span.clone(),
                    match other {
                        ArgValue::Text(t) | ArgValue::Name(t) => {
                            format!("invalid orient `{t}`, expected \"follow\" or \"fixed\"")
                        }
                        _ => format!(
                            "invalid orient: {}, expected \"follow\" or \"fixed\"",
                            other.describe()
                        ),
                    },
                )
                .with_help(
                    "follow: the profile turns with the path; fixed: it is only translated",
                )),
        }
    }

    /// `[a, b]`, or (when `one_for_both`) one value for both directions.
    fn scalar_pair(
        &self,
        value: &Spanned<ArgValue>,
        one_for_both: bool,
    ) -> Result<[Scalar; 2], RuleError> {
        match &value.value {
            ArgValue::List(items) if items.len() == 2 => {
                Ok([self.param_scalar(&items[0])?, self.param_scalar(&items[1])?])
            }
            ArgValue::Number(_) | ArgValue::Text(_) if one_for_both => {
                let one = self.param_scalar(value)?;
                Ok([one.clone(), one])
            }
            other => Err(self.error(
                value.span.clone(),
                format!(
                    "invalid type: {}, expected {}",
                    other.describe(),
                    if one_for_both {
                        "a number or [u, v]"
                    } else {
                        "[u, v]"
                    }
                ),
            )),
        }
    }

    /// A number or an expression over the parameters.
    fn param_scalar(&self, value: &Spanned<ArgValue>) -> Result<Scalar, RuleError> {
        match &value.value {
            ArgValue::Number(_) | ArgValue::Text(_) => self.scalar(&as_scalar(value)),
            other => Err(self.error(
                value.span.clone(),
                format!(
                    "invalid type: {}, expected a number or an expression",
                    other.describe()
                ),
            )),
        }
    }

    /// A number or an expression over the parameters and `i`, `j`.
    fn generator(&self, value: &Spanned<ArgValue>) -> Result<Scalar, RuleError> {
        let v = as_scalar(value);
        match &v.value {
            AstScalar::Number(_) => self.scalar(&v),
            AstScalar::Expr(text) => {
                let base = self.param_names.len() as u32;
                let resolve = |name: &str| match GENERATOR_NAMES.iter().position(|n| *n == name) {
                    Some(k) => Some(base + k as u32),
                    None => self.resolve_param(name),
                };
                Expr::compile(text, &resolve)
                    .map_err(|err| self.expr_error(self.content_span(&v, text), err))
            }
        }
    }

    fn points(&self, value: &Spanned<ArgValue>) -> Result<Points, RuleError> {
        let ArgValue::List(items) = &value.value else {
            return Err(self.points_shape(value.span.clone()));
        };
        if items.iter().all(|p| matches!(p.value, ArgValue::List(_))) && !items.is_empty() {
            let list = items
                .iter()
                .map(|p| match &p.value {
                    ArgValue::List(xyz) if xyz.len() == 3 => Ok([
                        self.param_scalar(&xyz[0])?,
                        self.param_scalar(&xyz[1])?,
                        self.param_scalar(&xyz[2])?,
                    ]),
                    _ => Err(self.error(p.span.clone(), "a control point is [x, y, z]")),
                })
                .collect::<Result<_, _>>()?;
            return Ok(Points::List(list));
        }
        if items.len() == 3 && items.iter().all(is_scalar) {
            return Ok(Points::Generator(Box::new([
                self.generator(&items[0])?,
                self.generator(&items[1])?,
                self.generator(&items[2])?,
            ])));
        }
        Err(self.points_shape(value.span.clone()))
    }

    /// `profile`: a list of `[r, z]`, or one `[r, z]` of expressions over `j`.
    fn profile(&self, value: &Spanned<ArgValue>) -> Result<Profile, RuleError> {
        let shape = || {
            self.error(
                value.span.clone(),
                "`profile` is a list of [r, z] (radius from the z axis, height), or one [r, z] of expressions over j",
            )
        };
        let ArgValue::List(items) = &value.value else {
            return Err(shape());
        };
        if items.len() == 2 && items.iter().all(is_scalar) {
            return Ok(Profile::Generator(Box::new([
                self.generator(&items[0])?,
                self.generator(&items[1])?,
            ])));
        }
        items
            .iter()
            .map(|p| match &p.value {
                ArgValue::List(rz) if rz.len() == 2 => {
                    Ok([self.param_scalar(&rz[0])?, self.param_scalar(&rz[1])?])
                }
                _ => Err(self.error(p.span.clone(), "a profile point is [r, z]")),
            })
            .collect::<Result<_, _>>()
            .map(Profile::List)
    }

    fn points_shape(&self, span: Option<Range<usize>>) -> RuleError {
        self.error(span, "`points` is a list of [x, y, z] (row-major, i along u), or one [x, y, z] of expressions over i and j").with_help("for example points = [\"i\", \"j\", \"sin(i) * cos(j)\"]")
    }

    fn weights(&self, value: &Spanned<ArgValue>) -> Result<Weights, RuleError> {
        match &value.value {
            ArgValue::List(items) => Ok(Weights::List(
                items
                    .iter()
                    .map(|w| self.param_scalar(w))
                    .collect::<Result<_, _>>()?,
            )),
            _ if is_scalar(value) => Ok(Weights::Generator(self.generator(value)?)),
            other => Err(self.error(
                value.span.clone(),
                format!(
                    "invalid type: {}, expected a list of weights or an expression over i and j",
                    other.describe()
                ),
            )),
        }
    }

    fn knots(&self, value: Option<&Spanned<ArgValue>>) -> Result<Knots, RuleError> {
        let Some(value) = value else {
            return Ok(Knots::ClampedUniform);
        };
        match &value.value {
            ArgValue::Text(t) | ArgValue::Name(t) if t == CLAMPED_UNIFORM => {
                Ok(Knots::ClampedUniform)
            }
            ArgValue::List(items) => Ok(Knots::List(
                items.iter().map(|k| self.param_scalar(k)).collect::<Result<_, _>>()?,
            )),
            other => Err(self
                .error(
                    value.span.clone(),
                    format!(
                        "invalid knots: {}, expected \"{CLAMPED_UNIFORM}\" or a list of numbers",
                        other.describe()
                    ),
                )
                .with_help("clamped_uniform (the default) repeats the end knots degree + 1 times and spaces the others evenly")),
        }
    }

    /// Builds every surface with the parameters at nominal values; the
    /// first that fails is an error at its key.
    pub(super) fn validate_surfaces(
        &self,
        surfaces: &[SurfaceDef],
        params: &[Param],
    ) -> Result<(), RuleError> {
        if surfaces.is_empty() {
            return Ok(());
        }
        let Some(slots) = super::sdf::nominal_slots(params, self.param_names.len()) else {
            return Ok(());
        };
        for (def, (_, table)) in surfaces.iter().zip(&self.nurbs_defs.0) {
            let built = match def.kind {
                Kind::Curve => def.build_curve(&slots).map(drop),
                // A set's listed surfaces are checked as themselves; its file at run time.
                Kind::Surface if def.is_set() => Ok(()),
                Kind::Surface => def.build(surfaces, &slots).map(drop),
            };
            if let Err(e) = built {
                let span = table
                    .value
                    .0
                    .iter()
                    .find(|(k, _)| k.value == e.key)
                    .and_then(|(k, v)| v.span.clone().or(k.span.clone()))
                    .or(table.span.clone());
                let what = match def.kind {
                    Kind::Curve => "curve",
                    Kind::Surface => "surface",
                };
                return Err(self.error(span, format!("nurbs {what} `{}`: {}", def.name, e.message)));
            }
        }
        Ok(())
    }
}

fn is_scalar(v: &Spanned<ArgValue>) -> bool {
    matches!(v.value, ArgValue::Number(_) | ArgValue::Text(_))
}

/// A `[nurbs.NAME]` table is a curve when its `size` is one number, or when
/// it has no `size` and its `points` is a list (a surface needs `[n_u, n_v]`).
pub(crate) fn is_curve_table(table: &ast::Args) -> bool {
    let get = |key: &str| {
        table
            .0
            .iter()
            .find(|(k, _)| k.value == key)
            .map(|(_, v)| &v.value)
    };
    match get("size") {
        Some(size) => !matches!(size, ArgValue::List(_)),
        None => {
            get("profile").is_none()
                && matches!(get("points"), Some(ArgValue::List(items)) if items.iter().all(|p| matches!(p.value, ArgValue::List(_))))
        }
    }
}
