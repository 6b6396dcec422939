//! Rule file → program: parse (TOML or RON by extension), resolve names to
//! slots, compile expressions, check every semantic rule, and locate each
//! error in the file.

use std::ops::Range;
use std::path::{Path, PathBuf};

use crate::kernel::ops::delete::DeleteMode;
use crate::kernel::ops::select::Adjacency;
use crate::kernel::Domain;

use super::ast::{self, DomainName, Operation, ParamSpec, RuleFile, Scalar as AstScalar};
use super::diagnostic::{find_key, find_literal, offset_of, RuleError, SourceFile};
use super::expr::{Expr, ExprError};
use super::program::{
    Condition, Offset, Op, Param, ParamKind, Program, Property, Scalar, Step, Vector,
};
use super::random::stream_key;
use super::spanned::{with_format, SourceFormat, Spanned};

/// A `--set name=value` override from the command line.
#[derive(Debug, Clone, PartialEq)]
pub struct Override {
    pub name: String,
    pub value: String,
}

impl Override {
    /// Parses `name=value`.
    pub fn parse(text: &str) -> Result<Override, String> {
        let (name, value) = text
            .split_once('=')
            .ok_or_else(|| format!("`{text}` is not of the form name=value"))?;
        let name = name.trim();
        if name.is_empty() || value.trim().is_empty() {
            return Err(format!("`{text}` is not of the form name=value"));
        }
        Ok(Override {
            name: name.to_owned(),
            value: value.trim().to_owned(),
        })
    }
}

/// Reads and parses a rule file (format chosen by extension).
pub fn load(path: &Path) -> Result<(SourceFile, RuleFile), RuleError> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|err| {
        RuleError::at(
            &SourceFile {
                name: name.clone(),
                text: String::new(),
            },
            None,
            format!("cannot read rule file: {err}"),
        )
    })?;
    let file = SourceFile { name, text };
    let ast = parse(
        &file,
        format_of(path).map_err(|m| RuleError::at(&file, None, m))?,
    )?;
    Ok((file, ast))
}

/// The rule format for a path's extension.
pub fn format_of(path: &Path) -> Result<SourceFormat, String> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("toml") => Ok(SourceFormat::Toml),
        Some("ron") => Ok(SourceFormat::Ron),
        _ => Err("rule files must end in .toml or .ron".to_owned()),
    }
}

/// Parses rule text in the given format.
pub fn parse(file: &SourceFile, format: SourceFormat) -> Result<RuleFile, RuleError> {
    with_format(format, || match format {
        SourceFormat::Toml => toml::from_str::<RuleFile>(&file.text)
            .map_err(|err| RuleError::at(file, err.span(), err.message().trim().to_owned())),
        // Implicit `Some` lets optional keys be written plainly: `start: (cube: ())`.
        SourceFormat::Ron => ron::Options::default()
            .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
            .from_str::<RuleFile>(&file.text)
            .map_err(|err| {
                let start = offset_of(&file.text, err.span.start.line, err.span.start.col);
                let end = offset_of(&file.text, err.span.end.line, err.span.end.col).max(start);
                RuleError::at(
                    file,
                    Some(start..end.max(start + 1).min(file.text.len().max(start))),
                    err.code.to_string(),
                )
            }),
    })
}

/// Single-name element properties; dotted ones (`pos.x`) are listed in
/// [`property_for`]. Parameters may not take these names.
const PROPERTY_NAMES: &[&str] = &[
    "id",
    "random",
    "length",
    "area",
    "sides",
    "degree",
    "faces",
    "neighbors",
    "vert_neighbors",
];

fn axis(c: &str) -> Option<usize> {
    match c {
        "x" => Some(0),
        "y" => Some(1),
        "z" => Some(2),
        _ => None,
    }
}

/// The property a name denotes for elements of `domain`, if any.
fn property_for(domain: Domain, name: &str) -> Option<Property> {
    use Property::*;
    let simple = match (domain, name) {
        (_, "id") => Some(Id),
        (_, "random") => Some(Random),
        (Domain::Edge, "length") => Some(Length),
        (Domain::Face, "area") => Some(Area),
        (Domain::Face, "sides") => Some(Sides),
        (Domain::Vert, "degree") => Some(Degree),
        (Domain::Vert | Domain::Edge, "faces") => Some(FaceCount),
        (Domain::Face, "neighbors") => Some(EdgeNeighbors),
        (Domain::Face, "vert_neighbors") => Some(VertNeighbors),
        _ => None,
    };
    if simple.is_some() {
        return simple;
    }
    let (base, component) = name.split_once('.')?;
    let i = axis(component)?;
    match (domain, base) {
        (Domain::Vert, "pos") => Some(Position(i)),
        (Domain::Vert | Domain::Face, "normal") => Some(Normal(i)),
        (Domain::Edge | Domain::Face, "center") => Some(Center(i)),
        (Domain::Edge, "dir") => Some(Direction(i)),
        (Domain::Edge | Domain::Face, "min") => Some(Min(i)),
        (Domain::Edge | Domain::Face, "max") => Some(Max(i)),
        _ => None,
    }
}

struct Compiler<'a> {
    file: &'a SourceFile,
    format: SourceFormat,
    param_names: Vec<String>,
}

impl<'a> Compiler<'a> {
    fn error(&self, span: Option<Range<usize>>, message: impl Into<String>) -> RuleError {
        RuleError::at(self.file, span, message)
    }

    /// The span of a string value's content, for locating expression errors.
    fn content_span<T>(&self, spanned: &Spanned<T>, content: &str) -> Option<Range<usize>> {
        match (&spanned.span, self.format) {
            (Some(span), _) => {
                let raw = &self.file.text[span.clone()];
                let quote = if raw.starts_with("\"\"\"") || raw.starts_with("'''") {
                    3
                } else if raw.starts_with('"') || raw.starts_with('\'') {
                    1
                } else {
                    0
                };
                Some(span.start + quote..span.start + quote + content.len())
            }
            (None, _) => find_literal(&self.file.text, content),
        }
    }

    fn span_of<T>(&self, spanned: &Spanned<T>, fallback_key: &str) -> Option<Range<usize>> {
        spanned
            .span
            .clone()
            .or_else(|| find_key(&self.file.text, fallback_key))
    }

    fn expr_error(&self, base: Option<Range<usize>>, err: ExprError) -> RuleError {
        let span =
            base.map(|b| b.start + err.span.start..b.start + err.span.end.max(err.span.start + 1));
        self.error(span, err.message)
    }

    fn resolve_param(&self, name: &str) -> Option<u32> {
        self.param_names
            .iter()
            .position(|p| p == name)
            .map(|i| i as u32)
    }

    /// Compiles an expression over parameters only.
    fn param_expr(&self, text: &str, span: Option<Range<usize>>) -> Result<Expr, RuleError> {
        Expr::compile(text, &|name: &str| self.resolve_param(name)).map_err(|err| {
            let hint = unknown_name_hint(&err.message, &self.param_names);
            let mut e = self.expr_error(span.clone(), err);
            if let Some(hint) = hint {
                return e.with_help(hint);
            }
            if PROPERTY_NAMES
                .iter()
                .any(|p| e.message.contains(&format!("`{p}`")))
                || e.message.contains('.')
            {
                e = e.with_help("element properties are only available in `select` conditions; operator parameters see parameters only");
            }
            e
        })
    }

    fn scalar(&self, value: &ast::Value) -> Result<Scalar, RuleError> {
        match &value.value {
            AstScalar::Number(x) => self.number(*x, value.span.clone()),
            AstScalar::Expr(text) => self.param_expr(text, self.content_span(value, text)),
        }
    }

    fn number(&self, x: f64, span: Option<Range<usize>>) -> Result<Scalar, RuleError> {
        if !x.is_finite() {
            return Err(self.error(span, "numbers must be finite"));
        }
        Ok(Expr::compile(&format!("{x:?}"), &|_: &str| None).expect("a finite literal compiles"))
    }

    fn opt_scalar(&self, value: &Option<ast::Value>, default: f64) -> Result<Scalar, RuleError> {
        match value {
            Some(v) => self.scalar(v),
            None => self.number(default, None),
        }
    }

    fn vector(&self, v: &ast::Vector) -> Result<Vector, RuleError> {
        match &v.value {
            ast::VectorSpec::Components(parts) => Ok(Vector([
                self.scalar(&parts[0])?,
                self.scalar(&parts[1])?,
                self.scalar(&parts[2])?,
            ])),
            ast::VectorSpec::Uniform(s) => {
                let one = self.scalar(&Spanned {
                    value: s.clone(),
                    span: v.span.clone(),
                })?;
                Ok(Vector([one.clone(), one.clone(), one]))
            }
        }
    }

    fn opt_vector(&self, v: &Option<ast::Vector>, default: [f64; 3]) -> Result<Vector, RuleError> {
        match v {
            Some(v) => self.vector(v),
            None => Ok(Vector([
                self.number(default[0], None)?,
                self.number(default[1], None)?,
                self.number(default[2], None)?,
            ])),
        }
    }

    fn offset(&self, op: &ast::ExtrudeOp, span: Option<Range<usize>>) -> Result<Offset, RuleError> {
        match (&op.offset, &op.distance) {
            (Some(_), Some(_)) => {
                Err(self.error(span, "give either `offset` or `distance`, not both"))
            }
            (Some(v), None) => Ok(Offset::Vector(Box::new(self.vector(v)?))),
            (None, Some(d)) => Ok(Offset::Normal(self.scalar(d)?)),
            (None, None) => Ok(Offset::None),
        }
    }

    fn condition(&self, domain: Domain, text: &Spanned<String>) -> Result<Condition, RuleError> {
        let mut properties: Vec<Property> = Vec::new();
        let base = self.param_names.len() as u32;
        let resolver = |name: &str| -> Option<u32> {
            if let Some(slot) = self.resolve_param(name) {
                return Some(slot);
            }
            // Slots past the parameters are properties, numbered in the
            // fixed order of this list; `properties` is rebuilt below.
            property_for(domain, name).map(|p| base + property_index(p))
        };
        let expr = Expr::compile(&text.value, &resolver).map_err(|err| {
            let hint = unknown_name_hint(&err.message, &self.param_names);
            let e = self.expr_error(self.content_span(text, &text.value), err);
            let properties = format!("{} properties: {}", domain, property_help(domain));
            e.with_help(match hint {
                Some(hint) => format!("{hint} ({properties})"),
                None => properties,
            })
        })?;
        for &slot in expr.used_slots() {
            if slot >= base {
                properties.push(property_from_index(slot - base));
            }
        }
        Ok(Condition { expr, properties })
    }
}

/// Dense numbering of properties so a condition's slot array can be
/// indexed directly: slot = param_count + property_index.
pub fn property_index(p: Property) -> u32 {
    use Property::*;
    match p {
        Id => 0,
        Random => 1,
        Length => 2,
        Area => 3,
        Sides => 4,
        Degree => 5,
        FaceCount => 6,
        EdgeNeighbors => 7,
        VertNeighbors => 8,
        Position(i) => 9 + i as u32,
        Center(i) => 12 + i as u32,
        Normal(i) => 15 + i as u32,
        Min(i) => 18 + i as u32,
        Max(i) => 21 + i as u32,
        Direction(i) => 24 + i as u32,
    }
}

/// Number of property slots after the parameters.
pub const PROPERTY_SLOTS: usize = 27;

fn property_from_index(i: u32) -> Property {
    use Property::*;
    let c = |base: u32| (i - base) as usize;
    match i {
        0 => Id,
        1 => Random,
        2 => Length,
        3 => Area,
        4 => Sides,
        5 => Degree,
        6 => FaceCount,
        7 => EdgeNeighbors,
        8 => VertNeighbors,
        9..=11 => Position(c(9)),
        12..=14 => Center(c(12)),
        15..=17 => Normal(c(15)),
        18..=20 => Min(c(18)),
        21..=23 => Max(c(21)),
        _ => Direction(c(24)),
    }
}

fn property_help(domain: Domain) -> &'static str {
    match domain {
        Domain::Vert => "id, random, pos.x/y/z, normal.x/y/z, degree, faces",
        Domain::Edge => "id, random, length, center.x/y/z, dir.x/y/z, min.x/y/z, max.x/y/z, faces",
        Domain::Face => "id, random, area, sides, neighbors, vert_neighbors, center.x/y/z, normal.x/y/z, min.x/y/z, max.x/y/z",
    }
}

/// Which element kinds an operator's selection may be made of; the first
/// is the default.
fn allowed_domains(op: &Operation) -> &'static [Domain] {
    use Domain::*;
    match op {
        Operation::Translate(_)
        | Operation::Rotate(_)
        | Operation::Scale(_)
        | Operation::Merge(_)
        | Operation::ExtrudeVerts(_) => &[Vert, Edge, Face],
        Operation::ExtrudeEdges(_)
        | Operation::SplitEdges(_)
        | Operation::DissolveEdges(_)
        | Operation::MakeFace(_) => &[Edge, Face],
        Operation::Delete(_) | Operation::Duplicate(_) | Operation::Mirror(_) => {
            &[Face, Edge, Vert]
        }
        _ => &[Face],
    }
}

fn is_create(op: &Operation) -> bool {
    matches!(
        op,
        Operation::Vertex(_)
            | Operation::Circle(_)
            | Operation::Grid(_)
            | Operation::Cube(_)
            | Operation::UvSphere(_)
            | Operation::Cylinder(_)
            | Operation::Cone(_)
            | Operation::Import(_)
    )
}

fn domain_of(name: DomainName) -> Domain {
    match name {
        DomainName::Verts => Domain::Vert,
        DomainName::Edges => Domain::Edge,
        DomainName::Faces => Domain::Face,
    }
}

fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// Compiles a parsed rule file. `base_dir` resolves relative paths.
pub fn compile(
    file: &SourceFile,
    format: SourceFormat,
    ast: &RuleFile,
    overrides: &[Override],
    base_dir: &Path,
) -> Result<Program, RuleError> {
    let mut compiler = Compiler {
        file,
        format,
        param_names: Vec::new(),
    };

    // Slots are assigned in name order: TOML does not keep table order, and
    // one canonical order keeps both formats (and the stats) identical.
    let mut declared: Vec<&(Spanned<String>, Spanned<ParamSpec>)> = ast.params.0.iter().collect();
    declared.sort_by(|a, b| a.0.value.cmp(&b.0.value));

    // Parameter names first, so expressions can refer to any of them.
    for (name, _) in declared.iter().map(|p| (&p.0, &p.1)) {
        let span = compiler.span_of(name, &name.value);
        if !is_identifier(&name.value) {
            return Err(compiler.error(
                span,
                format!(
                    "`{}` is not a valid parameter name (letters, digits, `_`)",
                    name.value
                ),
            ));
        }
        if PROPERTY_NAMES.contains(&name.value.as_str())
            || ["pi", "tau", "e", "true", "false"].contains(&name.value.as_str())
        {
            return Err(compiler.error(
                span,
                format!(
                    "`{}` is reserved (an element property or constant)",
                    name.value
                ),
            ));
        }
        if compiler.param_names.contains(&name.value) {
            return Err(
                compiler.error(span, format!("parameter `{}` is defined twice", name.value))
            );
        }
        compiler.param_names.push(name.value.clone());
    }
    for o in overrides {
        if compiler.resolve_param(&o.name).is_none() {
            let known = if compiler.param_names.is_empty() {
                "the file declares no parameters".to_owned()
            } else {
                format!("known parameters: {}", compiler.param_names.join(", "))
            };
            return Err(RuleError::at(
                file,
                None,
                format!(
                    "--set {}: no parameter named `{}` ({known})",
                    o.name, o.name
                ),
            ));
        }
    }

    let mut params = Vec::with_capacity(ast.params.0.len());
    for (slot, (name, spec)) in declared.iter().map(|p| (&p.0, &p.1)).enumerate() {
        let overridden = overrides.iter().rev().find(|o| o.name == name.value);
        let (kind, clamp) = match overridden {
            Some(o) => {
                let source = SourceFile {
                    name: format!("--set {}", o.name),
                    text: o.value.clone(),
                };
                let c = Compiler {
                    file: &source,
                    format,
                    param_names: compiler.param_names.clone(),
                };
                let expr = c.param_expr(&o.value, Some(0..o.value.len()))?;
                (ParamKind::Expr(expr), None)
            }
            None => compile_param(&compiler, name, spec)?,
        };
        params.push(Param {
            name: name.value.clone(),
            slot: slot as u32,
            key: stream_key(&format!("param/{}", name.value)),
            kind,
            clamp,
        });
    }
    let params = order_params(&compiler, &declared, params)?;

    let mut steps: Vec<Step> = Vec::new();
    if let Some(start) = &ast.start {
        if let Some((key, op)) = &start.op {
            if !is_create(&op.value) {
                return Err(compiler.error(compiler.span_of(key, &key.value), format!("`[start]` must be a create operator (vertex, circle, grid, cube, uv_sphere, cylinder, cone, import), not `{}`", key.value)));
            }
        }
        steps.push(compile_step(&compiler, start, "start", &steps, base_dir)?);
    }
    for (i, step) in ast.steps.iter().enumerate() {
        let default_name = format!("step{}", i + 1);
        steps.push(compile_step(
            &compiler,
            step,
            &default_name,
            &steps,
            base_dir,
        )?);
    }

    let mut hash_input = file.text.clone();
    for o in overrides {
        hash_input.push_str(&format!("\n--set {}={}", o.name, o.value));
    }
    Ok(Program {
        file: file.name.clone(),
        base_dir: base_dir.to_path_buf(),
        default_seed: ast.seed.as_ref().map_or(0, |s| s.value),
        rule_hash: stream_key(&hash_input),
        param_names: compiler.param_names.clone(),
        params,
        steps,
    })
}

fn compile_param(
    c: &Compiler,
    name: &Spanned<String>,
    spec: &Spanned<ParamSpec>,
) -> Result<(ParamKind, Option<(Expr, Expr)>), RuleError> {
    let span = spec
        .span
        .clone()
        .or_else(|| find_key(&c.file.text, &name.value));
    Ok(match &spec.value {
        ParamSpec::Number(x) => (ParamKind::Expr(c.number(*x, span)?), None),
        ParamSpec::Expr(text) => {
            let content = c.content_span(spec, text);
            (ParamKind::Expr(c.param_expr(text, content)?), None)
        }
        ParamSpec::Table(t) => {
            let given = [
                t.uniform.is_some(),
                t.normal.is_some(),
                t.int.is_some(),
                t.choice.is_some(),
            ]
            .iter()
            .filter(|&&b| b)
            .count();
            if given != 1 {
                return Err(c.error(span, format!("parameter `{}` needs exactly one of `uniform`, `normal`, `int`, `choice` (found {given})", name.value)));
            }
            if t.weights.is_some() && t.choice.is_none() {
                return Err(c.error(span, "`weights` goes with `choice`"));
            }
            let kind = if let Some(ast::Pair([a, b])) = &t.uniform {
                ParamKind::Uniform {
                    low: c.scalar(a)?,
                    high: c.scalar(b)?,
                }
            } else if let Some(ast::Pair([a, b])) = &t.normal {
                ParamKind::Normal {
                    mean: c.scalar(a)?,
                    sd: c.scalar(b)?,
                }
            } else if let Some(ast::Pair([a, b])) = &t.int {
                ParamKind::Int {
                    low: c.scalar(a)?,
                    high: c.scalar(b)?,
                }
            } else {
                let values = t.choice.as_ref().expect("checked above");
                if values.is_empty() {
                    return Err(c.error(span, "`choice` needs at least one value"));
                }
                let weights: Vec<f64> = match &t.weights {
                    None => vec![1.0; values.len()],
                    Some(w) => {
                        if w.len() != values.len() {
                            return Err(c.error(
                                span,
                                format!(
                                    "`choice` has {} values but `weights` has {}",
                                    values.len(),
                                    w.len()
                                ),
                            ));
                        }
                        for x in w {
                            if !(x.value.is_finite() && x.value >= 0.0) {
                                return Err(c.error(
                                    x.span.clone().or(span.clone()),
                                    "weights must be finite and not negative",
                                ));
                            }
                        }
                        w.iter().map(|x| x.value).collect()
                    }
                };
                if weights.iter().sum::<f64>() <= 0.0 {
                    return Err(c.error(span, "the weights add up to zero"));
                }
                ParamKind::Choice {
                    values: values
                        .iter()
                        .map(|v| c.scalar(v))
                        .collect::<Result<_, _>>()?,
                    weights,
                }
            };
            let clamp = match &t.clamp {
                Some(ast::Pair([lo, hi])) => Some((c.scalar(lo)?, c.scalar(hi)?)),
                None => None,
            };
            (kind, clamp)
        }
    })
}

/// Orders parameters so each comes after those it uses; rejects cycles.
fn order_params(
    c: &Compiler,
    declared: &[&(Spanned<String>, Spanned<ParamSpec>)],
    params: Vec<Param>,
) -> Result<Vec<Param>, RuleError> {
    let n = params.len();
    let deps: Vec<Vec<u32>> = params
        .iter()
        .map(|p| {
            let mut d: Vec<u32> = param_exprs(p)
                .flat_map(|e| e.used_slots().iter().copied())
                .collect();
            d.sort_unstable();
            d.dedup();
            d
        })
        .collect();
    // 0 = unvisited, 1 = on the stack, 2 = done.
    let mut state = vec![0u8; n];
    let mut order: Vec<usize> = Vec::with_capacity(n);
    fn visit(
        i: usize,
        deps: &[Vec<u32>],
        state: &mut [u8],
        order: &mut Vec<usize>,
        stack: &mut Vec<usize>,
    ) -> Result<(), Vec<usize>> {
        match state[i] {
            2 => return Ok(()),
            1 => {
                let from = stack.iter().position(|&s| s == i).unwrap_or(0);
                let mut cycle = stack[from..].to_vec();
                cycle.push(i);
                return Err(cycle);
            }
            _ => {}
        }
        state[i] = 1;
        stack.push(i);
        for &d in &deps[i] {
            visit(d as usize, deps, state, order, stack)?;
        }
        stack.pop();
        state[i] = 2;
        order.push(i);
        Ok(())
    }
    for i in 0..n {
        let mut stack = Vec::new();
        if let Err(cycle) = visit(i, &deps, &mut state, &mut order, &mut stack) {
            let names: Vec<&str> = cycle.iter().map(|&k| params[k].name.as_str()).collect();
            let first = &declared[cycle[0]].0;
            return Err(c.error(
                c.span_of(first, &first.value),
                format!(
                    "parameters depend on each other in a cycle: {}",
                    names.join(" → ")
                ),
            ));
        }
    }
    let mut slots: Vec<Option<Param>> = params.into_iter().map(Some).collect();
    Ok(order
        .into_iter()
        .map(|i| slots[i].take().expect("each parameter once"))
        .collect())
}

fn param_exprs(p: &Param) -> impl Iterator<Item = &Expr> {
    let mut v: Vec<&Expr> = match &p.kind {
        ParamKind::Expr(e) => vec![e],
        ParamKind::Uniform { low, high } | ParamKind::Int { low, high } => vec![low, high],
        ParamKind::Normal { mean, sd } => vec![mean, sd],
        ParamKind::Choice { values, .. } => values.iter().collect(),
    };
    if let Some((a, b)) = &p.clamp {
        v.push(a);
        v.push(b);
    }
    v.into_iter()
}

fn compile_step(
    c: &Compiler,
    step: &ast::Step,
    default_name: &str,
    earlier: &[Step],
    base_dir: &Path,
) -> Result<Step, RuleError> {
    if let Some(stray) = step.stray_keys.first() {
        let span = c.span_of(stray, &stray.value);
        return Err(match &step.op {
            Some((key, _)) if ast::OPERATOR_NAMES.contains(&stray.value.as_str()) => c
                .error(
                    span,
                    format!(
                        "a step runs one operator, but this one has both `{}` and `{}`",
                        key.value, stray.value
                    ),
                )
                .with_help("split them into two steps"),
            _ => {
                let e = c.error(span, format!("unknown key `{}` in a step", stray.value));
                match closest(&stray.value) {
                    Some(best) => e.with_help(format!("did you mean `{best}`?")),
                    None => e.with_help(format!(
                        "a step takes `name`, `select`, `from`, `on` and one operator: {}",
                        ast::OPERATOR_NAMES.join(", ")
                    )),
                }
            }
        });
    }
    let Some((op_key, op)) = &step.op else {
        return Err(c
            .error(None, format!("step `{default_name}` has no operator"))
            .with_help(
                "add one operator key, such as `cube = {}` or `extrude_faces = { distance = 1 }`",
            ));
    };
    let op_span = c.span_of(op_key, &op_key.value);
    let name = match &step.name {
        Some(n) => {
            let span = c.content_span(n, &n.value);
            if n.value.is_empty() || n.value.contains('/') {
                return Err(c.error(span, "step names must be non-empty and contain no `/`"));
            }
            if earlier.iter().any(|s| s.name == n.value) {
                return Err(c.error(span, format!("two steps are named `{}`", n.value)));
            }
            n.value.clone()
        }
        None => default_name.to_owned(),
    };
    let creates = is_create(&op.value);
    if creates {
        for (present, key) in [
            (step.select.is_some(), "select"),
            (step.from.is_some(), "from"),
            (step.on.is_some(), "on"),
        ] {
            if present {
                return Err(c.error(
                    op_span.clone(),
                    format!("`{}` creates geometry and takes no `{key}`", op_key.value),
                ));
            }
        }
    }
    let allowed = allowed_domains(&op.value);
    let domain = match &step.on {
        None => allowed[0],
        Some(on) => {
            let d = domain_of(on.value);
            if !allowed.contains(&d) {
                let names: Vec<String> = allowed.iter().map(|d| format!("{d}s")).collect();
                return Err(c.error(
                    c.span_of(on, "on"),
                    format!(
                        "`{}` works on {}, not {d}s",
                        op_key.value,
                        names.join(" or ")
                    ),
                ));
            }
            d
        }
    };
    let from = match &step.from {
        None => None,
        Some(f) => {
            let span = c.content_span(f, &f.value);
            match earlier.iter().position(|s| s.name == f.value) {
                Some(i) => Some(i),
                None => {
                    let names: Vec<&str> = earlier.iter().map(|s| s.name.as_str()).collect();
                    return Err(c
                        .error(span, format!("no earlier step is named `{}`", f.value))
                        .with_help(if names.is_empty() {
                            "`from` names an earlier step; this is the first".to_owned()
                        } else {
                            format!("earlier steps: {}", names.join(", "))
                        }));
                }
            }
        }
    };
    let select = match &step.select {
        Some(s) => Some(c.condition(domain, s)?),
        None => None,
    };
    let op = compile_op(c, op, op_span.clone(), base_dir)?;
    let location = match op_span {
        Some(span) => {
            let (line, column) = super::diagnostic::line_column(&c.file.text, span.start);
            format!("{}:{line}:{column}", c.file.name)
        }
        None => c.file.name.clone(),
    };
    Ok(Step {
        key: stream_key(&format!("step/{name}")),
        name,
        location,
        domain,
        select,
        from,
        op,
    })
}

fn compile_op(
    c: &Compiler,
    op: &Spanned<Operation>,
    span: Option<Range<usize>>,
    base_dir: &Path,
) -> Result<Op, RuleError> {
    let s = |v: &ast::Value| c.scalar(v);
    Ok(match &op.value {
        Operation::Vertex(o) => Op::Vertex {
            at: c.opt_vector(&o.at, [0.0; 3])?,
        },
        Operation::Circle(o) => Op::Circle {
            segments: c.opt_scalar(&o.segments, 32.0)?,
            radius: c.opt_scalar(&o.radius, 1.0)?,
            fill: o.fill.unwrap_or(false),
        },
        Operation::Grid(o) => {
            let segments = match &o.segments {
                Some(ast::Pair([a, b])) => [s(a)?, s(b)?],
                None => [c.number(1.0, None)?, c.number(1.0, None)?],
            };
            let size = match &o.size {
                Some(ast::Pair([a, b])) => [s(a)?, s(b)?],
                None => [c.number(2.0, None)?, c.number(2.0, None)?],
            };
            Op::Grid { segments, size }
        }
        Operation::Cube(o) => Op::Cube {
            size: c.opt_scalar(&o.size, 2.0)?,
        },
        Operation::UvSphere(o) => Op::UvSphere {
            segments: c.opt_scalar(&o.segments, 32.0)?,
            rings: c.opt_scalar(&o.rings, 16.0)?,
            radius: c.opt_scalar(&o.radius, 1.0)?,
        },
        Operation::Cylinder(o) => {
            let radius = c.opt_scalar(&o.radius, 1.0)?;
            Op::Cylinder {
                segments: c.opt_scalar(&o.segments, 32.0)?,
                radius_top: match &o.radius_top {
                    Some(v) => s(v)?,
                    None => radius.clone(),
                },
                radius,
                depth: c.opt_scalar(&o.depth, 2.0)?,
                caps: o.caps.unwrap_or(true),
            }
        }
        Operation::Cone(o) => Op::Cylinder {
            segments: c.opt_scalar(&o.segments, 32.0)?,
            radius: c.opt_scalar(&o.radius, 1.0)?,
            radius_top: c.number(0.0, None)?,
            depth: c.opt_scalar(&o.depth, 2.0)?,
            caps: o.caps.unwrap_or(true),
        },
        Operation::Import(o) => {
            let path = PathBuf::from(&o.path.value);
            Op::Import {
                path: if path.is_absolute() {
                    path
                } else {
                    base_dir.join(path)
                },
            }
        }
        Operation::Translate(o) => Op::Translate {
            offset: c.vector(&o.offset)?,
        },
        Operation::Rotate(o) => Op::Rotate {
            angle_degrees: s(&o.angle)?,
            axis: c.opt_vector(&o.axis, [0.0, 0.0, 1.0])?,
            center: c.opt_vector(&o.center, [0.0; 3])?,
        },
        Operation::Scale(o) => Op::Scale {
            factor: c.vector(&o.factor)?,
            center: c.opt_vector(&o.center, [0.0; 3])?,
        },
        Operation::ExtrudeVerts(o) => Op::ExtrudeVerts {
            offset: c.offset(o, span)?,
        },
        Operation::ExtrudeEdges(o) => Op::ExtrudeEdges {
            offset: c.offset(o, span)?,
        },
        Operation::ExtrudeFaces(o) => Op::ExtrudeFaces {
            keep_original: o.keep_original.unwrap_or(false),
            offset: c.offset(o, span)?,
        },
        Operation::ExtrudeRegion(o) => Op::ExtrudeRegion {
            keep_original: o.keep_original.unwrap_or(false),
            offset: c.offset(o, span)?,
        },
        Operation::InsetFaces(o) => Op::InsetFaces {
            thickness: s(&o.thickness)?,
            depth: c.opt_scalar(&o.depth, 0.0)?,
        },
        Operation::InsetRegion(o) => Op::InsetRegion {
            thickness: s(&o.thickness)?,
            depth: c.opt_scalar(&o.depth, 0.0)?,
        },
        Operation::SplitEdges(o) => match (&o.cuts, &o.ratios) {
            (Some(_), Some(_)) => {
                return Err(c.error(span, "give either `cuts` or `ratios`, not both"))
            }
            (Some(n), None) => Op::SplitEdgesCuts { cuts: s(n)? },
            (None, Some(r)) => {
                if r.is_empty() {
                    return Err(c.error(span, "`ratios` needs at least one value"));
                }
                Op::SplitEdgesRatios {
                    ratios: r.iter().map(s).collect::<Result<_, _>>()?,
                }
            }
            (None, None) => Op::SplitEdgesCuts {
                cuts: c.number(1.0, None)?,
            },
        },
        Operation::Triangulate(_) => Op::Triangulate,
        Operation::Reverse(_) => Op::Reverse,
        Operation::RecomputeNormals(o) => Op::RecomputeNormals {
            outside: o.outside.unwrap_or(true),
        },
        Operation::Delete(o) => Op::Delete {
            mode: match o.mode.unwrap_or(ast::DeleteModeName::All) {
                ast::DeleteModeName::All => DeleteMode::All,
                ast::DeleteModeName::Faces => DeleteMode::Faces,
                ast::DeleteModeName::FacesAndEdges => DeleteMode::FacesAndEdges,
            },
        },
        Operation::Duplicate(_) => Op::Duplicate,
        Operation::DissolveEdges(_) => Op::DissolveEdges,
        Operation::MakeFace(_) => Op::MakeFace,
        Operation::Merge(o) => Op::Merge {
            distance: s(&o.distance)?,
        },
        Operation::Mirror(o) => {
            let normal = match (&o.axis, &o.normal) {
                (Some(_), Some(_)) => {
                    return Err(c.error(span, "give either `axis` or `normal`, not both"))
                }
                (Some(a), None) => {
                    let mut n = [0.0; 3];
                    n[*a as usize] = 1.0;
                    c.opt_vector(&None, n)?
                }
                (None, Some(n)) => c.vector(n)?,
                (None, None) => c.opt_vector(&None, [1.0, 0.0, 0.0])?,
            };
            Op::Mirror {
                point: c.opt_vector(&o.point, [0.0; 3])?,
                normal,
                merge_distance: c.opt_scalar(&o.merge_distance, 1e-6)?,
            }
        }
        Operation::RegionExtend(o) => Op::RegionExtend {
            by: adjacency(o.by),
        },
        Operation::RegionReduce(o) => Op::RegionReduce {
            by: adjacency(o.by),
        },
    })
}

fn adjacency(by: Option<ast::AdjacencyName>) -> Adjacency {
    match by.unwrap_or(ast::AdjacencyName::Edge) {
        ast::AdjacencyName::Edge => Adjacency::Edge,
        ast::AdjacencyName::Vert => Adjacency::Vert,
    }
}

/// The step key nearest to `word`, if close enough to be a typo.
fn closest(word: &str) -> Option<&'static str> {
    let keys: Vec<&'static str> = ["name", "select", "from", "on"]
        .iter()
        .chain(ast::OPERATOR_NAMES)
        .copied()
        .collect();
    closest_in(word, &keys).map(|i| keys[i])
}

/// Index of the candidate nearest to `word` by edit distance, if close
/// enough to be a typo (at most 2 edits, more for long words).
fn closest_in<S: AsRef<str>>(word: &str, candidates: &[S]) -> Option<usize> {
    fn distance(a: &str, b: &str) -> usize {
        let b: Vec<char> = b.chars().collect();
        let mut row: Vec<usize> = (0..=b.len()).collect();
        for (i, ca) in a.chars().enumerate() {
            let mut previous = row[0];
            row[0] = i + 1;
            for (j, &cb) in b.iter().enumerate() {
                let substitute = previous + usize::from(ca != cb);
                previous = row[j + 1];
                row[j + 1] = substitute.min(row[j] + 1).min(row[j + 1] + 1);
            }
        }
        row[b.len()]
    }
    candidates
        .iter()
        .enumerate()
        .map(|(i, c)| (distance(word, c.as_ref()), i))
        .filter(|&(d, i)| d > 0 && d <= 2.max(candidates[i].as_ref().len() / 4))
        .min()
        .map(|(_, i)| i)
}

/// A "did you mean" hint for an unknown name in an expression.
fn unknown_name_hint(message: &str, names: &[String]) -> Option<String> {
    let name = message.strip_prefix("unknown name `")?.split('`').next()?;
    closest_in(name, names).map(|i| format!("did you mean `{}`?", names[i]))
}

/// Loads and compiles a rule file in one go.
pub fn compile_file(path: &Path, overrides: &[Override]) -> Result<Program, RuleError> {
    let (file, ast) = load(path)?;
    let format = format_of(path).map_err(|m| RuleError::at(&file, None, m))?;
    let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    compile(&file, format, &ast, overrides, &base_dir)
}
