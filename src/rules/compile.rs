//! Rule file → program: parse (TOML or RON by extension), resolve names to
//! slots, compile expressions, check every semantic rule, and locate each
//! error in the file.

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use rustc_hash::FxHashMap;

use crate::kernel::ops::delete::DeleteMode;
use crate::kernel::ops::select::Adjacency;
use crate::kernel::Domain;

use super::ast::{self, DomainName, Operation, ParamSpec, RuleFile, Scalar as AstScalar};
use super::diagnostic::{content_span, RuleError, SourceFile};
use super::expr::{Expr, ExprError, BUILTIN_CONSTANT_NAMES};
use super::program::{
    Command, CommandKind, Compound, Condition, FrameParams, Offset, OnIntersection, Op, Param,
    ParamKind, Policy, Program, Property, Resource, Scalar, Step, StepBody, Vector,
};
use super::random::stream_key;
use super::spanned::{SourceFormat, Spanned};

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

/// Reads a rule file's text.
pub fn load_text(path: &Path) -> Result<SourceFile, RuleError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|err| {
        RuleError::at(
            &SourceFile {
                name: name.clone(),
                text: String::new(),
            },
            None,
            format!("cannot read rule file: {err}"),
        )
    })?;
    source_from_bytes(name, bytes)
}

/// A rule file's text from its bytes; bytes that are not UTF-8 are an
/// error located at the first bad byte.
pub fn source_from_bytes(name: String, bytes: Vec<u8>) -> Result<SourceFile, RuleError> {
    match String::from_utf8(bytes) {
        Ok(text) => Ok(SourceFile { name, text }),
        Err(err) => {
            let offset = err.utf8_error().valid_up_to();
            let bad = err.as_bytes()[offset];
            // Show the text up to the bad byte, so the snippet is exact.
            let text = String::from_utf8_lossy(&err.as_bytes()[..offset]).into_owned();
            let file = SourceFile { name, text };
            Err(RuleError::at(
                &file,
                Some(offset..offset),
                format!(
                    "the rule file is not UTF-8 text: byte 0x{bad:02x} at byte offset {offset}"
                ),
            )
            .with_label("the bad byte is here")
            .with_help("save the file as UTF-8"))
        }
    }
}

/// Reads and parses a rule file (format chosen by extension).
pub fn load(path: &Path) -> Result<(SourceFile, RuleFile), RuleError> {
    let file = load_text(path)?;
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
    match format {
        SourceFormat::Toml => toml::from_str::<RuleFile>(&file.text)
            .map_err(|err| RuleError::at(file, err.span(), err.message().trim().to_owned())),
        SourceFormat::Ron => super::ron::parse(&file.text)
            .and_then(|value| super::ron::from_value::<RuleFile>(&value))
            .map_err(|err| RuleError::at(file, err.span, err.message)),
    }
}

/// Single-name element properties; dotted ones (`pos.x`) are listed in
/// [`property_for`]. Parameters may not take these names.
pub(crate) const PROPERTY_NAMES: &[&str] = &[
    "id",
    "random",
    "length",
    "area",
    "sides",
    "degree",
    "edges",
    "faces",
    "neighbors",
    "vert_neighbors",
    "age",
    "generation",
    "radius",
    "out_edges",
    "in_edges",
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
pub(crate) fn property_for(domain: Domain, name: &str) -> Option<Property> {
    use Domain::{Edge as E, Face as F, Vert as V};
    use Property::*;
    let simple = match (domain, name) {
        (_, "id") => Some(Id),
        (_, "random") => Some(Random),
        (_, "age") => Some(Age),
        (_, "generation") => Some(Generation),
        (_, "radius") => Some(Radius),
        (E, "length") => Some(Length),
        (F, "area") => Some(Area),
        (F, "sides" | "edges") => Some(Sides),
        (V, "degree" | "edges") => Some(Degree),
        (V | E, "faces") => Some(FaceCount),
        (V | E, "out_edges") => Some(OutEdges),
        (V | E, "in_edges") => Some(InEdges),
        (E, "neighbors") => Some(EdgeNeighborEdges),
        (F, "neighbors") => Some(EdgeNeighbors),
        (F, "vert_neighbors") => Some(VertNeighbors),
        (V | E, "pre.length") => Some(PreLength),
        (E, "rel.length") => Some(RelativeLength),
        (F, "rel.area") => Some(RelativeArea),
        _ => None,
    };
    if simple.is_some() {
        return simple;
    }
    let (base, component) = name.split_once('.')?;
    let i = axis(component)?;
    match (domain, base) {
        (V, "pos") => Some(Position(i)),
        (V | F, "normal") => Some(Normal(i)),
        (E | F, "center") => Some(Center(i)),
        (E, "dir") => Some(Direction(i)),
        (E | F, "min") => Some(Min(i)),
        (E | F, "max") => Some(Max(i)),
        (E, "pre") => Some(PrePosition(i)),
        (E, "post") => Some(PostPosition(i)),
        (_, "rel") => Some(Relative(i)),
        _ => None,
    }
}

struct Compiler<'a> {
    file: &'a SourceFile,
    param_names: Vec<String>,
    /// Files the program needs (see [`Program::resources`]).
    resources: std::cell::RefCell<Vec<Resource>>,
}

impl<'a> Compiler<'a> {
    /// The index of `resource` in the program's list (added on first use).
    fn resource(&self, resource: Resource) -> usize {
        let mut list = self.resources.borrow_mut();
        match list.iter().position(|r| r.path == resource.path) {
            Some(i) => i,
            None => {
                list.push(resource);
                list.len() - 1
            }
        }
    }

    fn error(&self, span: Option<Range<usize>>, message: impl Into<String>) -> RuleError {
        RuleError::at(self.file, span, message)
    }

    /// The span of a string value's content, for locating expression errors.
    fn content_span<T>(&self, spanned: &Spanned<T>, content: &str) -> Option<Range<usize>> {
        spanned
            .span
            .as_ref()
            .map(|span| content_span(&self.file.text, span.clone(), content))
    }

    fn expr_error(&self, base: Option<Range<usize>>, err: ExprError) -> RuleError {
        let span =
            base.map(|b| b.start + err.span.start..b.start + err.span.end.max(err.span.start + 1));
        self.error(span, err.message)
    }

    /// The slot of parameter `name` (slots are in name order).
    fn resolve_param(&self, name: &str) -> Option<u32> {
        self.param_names
            .binary_search_by(|p| p.as_str().cmp(name))
            .ok()
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

    /// A per-primitive value: a number, or an expression over parameters
    /// and the properties of `domain`'s primitives.
    fn property_scalar(&self, domain: Domain, value: &ast::Value) -> Result<Condition, RuleError> {
        match &value.value {
            AstScalar::Number(x) => Ok(Condition {
                expr: self.number(*x, value.span.clone())?,
            }),
            AstScalar::Expr(text) => self.condition(
                domain,
                &Spanned {
                    value: text.clone(),
                    span: value.span.clone(),
                },
            ),
        }
    }

    fn property_vector(
        &self,
        domain: Domain,
        v: &ast::Vector,
    ) -> Result<[Condition; 3], RuleError> {
        match &v.value {
            ast::VectorSpec::Components(parts) => Ok([
                self.property_scalar(domain, &parts[0])?,
                self.property_scalar(domain, &parts[1])?,
                self.property_scalar(domain, &parts[2])?,
            ]),
            ast::VectorSpec::Uniform(s) => {
                let one = self.property_scalar(
                    domain,
                    &Spanned {
                        value: s.clone(),
                        span: v.span.clone(),
                    },
                )?;
                Ok([one.clone(), one.clone(), one])
            }
        }
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
        let base = self.param_names.len() as u32;
        let resolver = |name: &str| -> Option<u32> {
            if let Some(slot) = self.resolve_param(name) {
                return Some(slot);
            }
            // Slots past the parameters are properties, in the fixed
            // order of `property_index`.
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
        Ok(Condition { expr })
    }
}

/// Dense numbering of properties so a condition's slot array can be
/// indexed directly: slot = param_count + property_index.
pub fn property_index(p: Property) -> u32 {
    use Property::*;
    let vector = |base: u32, i: usize| base + i as u32;
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
        Age => 9,
        Generation => 10,
        Radius => 11,
        OutEdges => 12,
        InEdges => 13,
        EdgeNeighborEdges => 14,
        PreLength => 15,
        RelativeLength => 16,
        RelativeArea => 17,
        Position(i) => vector(18, i),
        Center(i) => vector(21, i),
        Normal(i) => vector(24, i),
        Min(i) => vector(27, i),
        Max(i) => vector(30, i),
        Direction(i) => vector(33, i),
        PrePosition(i) => vector(36, i),
        PostPosition(i) => vector(39, i),
        Relative(i) => vector(42, i),
    }
}

/// Number of property slots after the parameters.
pub const PROPERTY_SLOTS: usize = 45;

/// Inverse of [`property_index`].
pub fn property_from_index(i: u32) -> Property {
    use Property::*;
    const SCALARS: [Property; 18] = [
        Id,
        Random,
        Length,
        Area,
        Sides,
        Degree,
        FaceCount,
        EdgeNeighbors,
        VertNeighbors,
        Age,
        Generation,
        Radius,
        OutEdges,
        InEdges,
        EdgeNeighborEdges,
        PreLength,
        RelativeLength,
        RelativeArea,
    ];
    if let Some(&p) = SCALARS.get(i as usize) {
        return p;
    }
    let c = ((i - 18) % 3) as usize;
    match (i - 18) / 3 {
        0 => Position(c),
        1 => Center(c),
        2 => Normal(c),
        3 => Min(c),
        4 => Max(c),
        5 => Direction(c),
        6 => PrePosition(c),
        7 => PostPosition(c),
        _ => Relative(c),
    }
}

fn property_help(domain: Domain) -> &'static str {
    match domain {
        Domain::Vert => "id, random, age, generation, radius, pos.x/y/z, rel.x/y/z, normal.x/y/z, degree (= edges), faces, out_edges, in_edges, pre.length",
        Domain::Edge => "id, random, age, generation, radius, length, rel.length, pre.length, center.x/y/z, rel.x/y/z, dir.x/y/z, pre.x/y/z, post.x/y/z, min.x/y/z, max.x/y/z, faces, neighbors, out_edges, in_edges",
        Domain::Face => "id, random, age, generation, radius, area, rel.area, sides (= edges), neighbors, vert_neighbors, center.x/y/z, rel.x/y/z, normal.x/y/z, min.x/y/z, max.x/y/z",
    }
}

/// Which element kinds an operator's selection may be made of; the first
/// is the default.
pub(crate) fn allowed_domains(op: &Operation) -> &'static [Domain] {
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
        Operation::CreateEdge(_) | Operation::EditNode(_) => &[Vert],
        Operation::SplitEdge(_) | Operation::CreateFace(_) | Operation::Skin(_) => &[Edge],
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

fn plural(d: Domain) -> &'static str {
    match d {
        Domain::Vert => "vertices",
        Domain::Edge => "edges",
        Domain::Face => "faces",
    }
}

pub(crate) fn domain_of(name: DomainName) -> Domain {
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
    ast: &RuleFile,
    overrides: &[Override],
    base_dir: &Path,
) -> Result<Program, RuleError> {
    let mut compiler = Compiler {
        file,
        param_names: Vec::new(),
        resources: std::cell::RefCell::new(Vec::new()),
    };

    // Slots are assigned in name order: TOML does not keep table order, and
    // one canonical order keeps both formats (and the stats) identical.
    let mut declared: Vec<&(Spanned<String>, Spanned<ParamSpec>)> = ast.params.0.iter().collect();
    declared.sort_by(|a, b| a.0.value.cmp(&b.0.value));

    // Parameter names first, so expressions can refer to any of them.
    for (name, _) in declared.iter().map(|p| (&p.0, &p.1)) {
        let span = name.span.clone();
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
            || BUILTIN_CONSTANT_NAMES.contains(&name.value.as_str())
        {
            return Err(compiler.error(
                span,
                format!(
                    "`{}` is reserved (an element property or constant)",
                    name.value
                ),
            ));
        }
        // Sorted: a name declared twice is next to its first declaration.
        if compiler.param_names.last() == Some(&name.value) {
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
                    param_names: compiler.param_names.clone(),
                    resources: std::cell::RefCell::new(Vec::new()),
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

    let default_tolerance = match &ast.tolerance {
        Some(t) => check_tolerance(&compiler, t)?,
        None => DEFAULT_TOLERANCE,
    };
    let policy = match ast.policy.as_ref().map(|p| p.value) {
        Some(ast::PolicyName::Merge) => Policy::Merge {
            tolerance: default_tolerance,
        },
        Some(ast::PolicyName::Intersect) => Policy::Intersect,
        Some(ast::PolicyName::None) | None => Policy::None,
    };
    let on_intersection = match &ast.on_intersection {
        None => OnIntersection::Skip,
        Some(o) => match on_intersection(o.value) {
            OnIntersection::CancelCompound | OnIntersection::CancelRule => {
                return Err(compiler
                    .error(
                        o.span.clone(),
                        "the file's `on_intersection` can be \"skip\" or \"error\"; cancelling belongs to steps in a compound or a rule",
                    )
                    .with_help("put `on_intersection = \"cancel_compound\"` on the compound call or its steps, `\"cancel_rule\"` on a rule's steps"));
            }
            other => other,
        },
    };
    let mut expander = Expander {
        c: &compiler,
        ast,
        base_dir,
        next_uid: 0,
        rule_stack: Vec::new(),
        compound_stack: Vec::new(),
        compounds: (0..ast.compound.0.len()).map(|_| None).collect(),
        uses_graph: false,
        edges_possible: false,
        default_tolerance,
        rule_instances: Vec::new(),
        next_rule_instance: 0,
        may_cancel: false,
        bodies: FxHashMap::default(),
    };
    check_unrolled_size(&compiler, ast)?;
    let mut steps: Vec<Step> = Vec::new();
    if let Some(start) = &ast.start {
        if let Some((key, op)) = &start.op {
            if !is_create(&op.value) {
                return Err(compiler.error(key.span.clone(), format!("`[start]` must be a create operator (vertex, circle, grid, cube, uv_sphere, cylinder, cone, import), not `{}`", key.value)));
            }
        }
        if start.rule.is_some() || start.compound.is_some() || start.repeat.is_some() {
            let key = start
                .rule
                .as_ref()
                .and_then(|r| r.span.clone())
                .or_else(|| start.compound.as_ref().and_then(|(k, _)| k.span.clone()))
                .or_else(|| start.repeat.as_ref().and_then(|r| r.span.clone()))
                .or_else(|| start.span.clone());
            return Err(compiler.error(
                key,
                "`[start]` takes one create operator, not `rule`, `compound` or `repeat`",
            ));
        }
        expander.expand(std::slice::from_ref(start), "", &mut steps, Some("start"))?;
    }
    expander.expand(&ast.steps, "", &mut steps, None)?;
    let uses_graph = expander.uses_graph;
    let may_cancel = expander.may_cancel;
    let step_count = expander.next_uid as usize;
    let mut compounds = Vec::with_capacity(expander.compounds.len());
    for (i, compound) in expander.compounds.into_iter().enumerate() {
        match compound {
            Some(c) => compounds.push(c),
            // Never called: still compiled, so its errors are reported.
            None => {
                let mut check = Expander {
                    c: &compiler,
                    ast,
                    base_dir,
                    next_uid: step_count as u32,
                    rule_stack: Vec::new(),
                    compound_stack: Vec::new(),
                    compounds: (0..ast.compound.0.len()).map(|_| None).collect(),
                    uses_graph: false,
                    edges_possible: true,
                    default_tolerance,
                    rule_instances: Vec::new(),
                    next_rule_instance: 0,
                    may_cancel: false,
                    bodies: FxHashMap::default(),
                };
                check.compile_compound(i, None)?;
                compounds.push(Compound {
                    name: ast.compound.0[i].0.value.clone(),
                    domain: Domain::Face,
                    select: None,
                    steps: Vec::new(),
                });
            }
        }
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
        compounds,
        step_count,
        uses_graph,
        policy,
        on_intersection,
        may_cancel,
        resources: compiler.resources.take(),
    })
}

fn on_intersection(name: ast::OnIntersectionName) -> OnIntersection {
    match name {
        ast::OnIntersectionName::Skip => OnIntersection::Skip,
        ast::OnIntersectionName::CancelCompound => OnIntersection::CancelCompound,
        ast::OnIntersectionName::CancelRule => OnIntersection::CancelRule,
        ast::OnIntersectionName::Error => OnIntersection::Error,
    }
}

/// Merge tolerance when the file gives none (model units).
pub const DEFAULT_TOLERANCE: f64 = 1e-6;
/// Largest merge tolerance accepted: beyond it whole features would weld.
pub const MAX_TOLERANCE: f64 = 1.0;

fn check_tolerance(c: &Compiler, t: &Spanned<f64>) -> Result<f64, RuleError> {
    let span = t.span.clone();
    if !(0.0..=MAX_TOLERANCE).contains(&t.value) {
        return Err(c
            .error(
                span,
                format!(
                    "`tolerance` must be between 0 and {MAX_TOLERANCE} (model units), got {}",
                    t.value
                ),
            )
            .with_help(
                "nodes closer than the tolerance are merged; 1e-6 suits models of unit size",
            ));
    }
    Ok(t.value)
}

fn compile_param(
    c: &Compiler,
    name: &Spanned<String>,
    spec: &Spanned<ParamSpec>,
) -> Result<(ParamKind, Option<(Expr, Expr)>), RuleError> {
    let span = spec.span.clone();
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
    // Depth-first, with an explicit stack: a chain of 100,000 parameters
    // must not overflow the call stack. 0 = unvisited, 1 = on the stack,
    // 2 = done.
    let mut state = vec![0u8; n];
    let mut order: Vec<usize> = Vec::with_capacity(n);
    for root in 0..n {
        if state[root] == 2 {
            continue;
        }
        // (parameter, index of its next dependency to visit)
        let mut stack: Vec<(usize, usize)> = vec![(root, 0)];
        state[root] = 1;
        while let Some(&mut (i, ref mut next)) = stack.last_mut() {
            let Some(&d) = deps[i].get(*next) else {
                state[i] = 2;
                order.push(i);
                stack.pop();
                continue;
            };
            *next += 1;
            let d = d as usize;
            match state[d] {
                2 => {}
                1 => {
                    let from = stack.iter().position(|&(s, _)| s == d).unwrap_or(0);
                    let mut cycle: Vec<usize> = stack[from..].iter().map(|&(s, _)| s).collect();
                    cycle.push(d);
                    let names: Vec<&str> = cycle.iter().map(|&k| params[k].name.as_str()).collect();
                    let first = &declared[cycle[0]].0;
                    return Err(c.error(
                        first.span.clone(),
                        format!(
                            "parameters depend on each other in a cycle: {}",
                            names.join(" → ")
                        ),
                    ));
                }
                _ => {
                    state[d] = 1;
                    stack.push((d, 0));
                }
            }
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

/// Refuses a file whose rules unroll to more than [`MAX_STEPS`] steps
/// before anything is unrolled: counting costs one pass over the file,
/// whatever the repeat counts say. The error points at the top-level step
/// that passes the limit.
fn check_unrolled_size(c: &Compiler, ast: &RuleFile) -> Result<(), RuleError> {
    let names = definition_names(&ast.rules);
    let mut memo: Vec<Option<u64>> = vec![None; names.len()];
    let mut visiting = vec![false; names.len()];
    let mut total: u64 = u64::from(ast.start.is_some());
    for (_, def) in &ast.compound.0 {
        total = total.saturating_add(unrolled(
            ast,
            &names,
            &def.steps,
            &mut memo,
            &mut visiting,
            0,
        ));
    }
    for step in &ast.steps {
        total = total.saturating_add(unrolled(
            ast,
            &names,
            std::slice::from_ref(step),
            &mut memo,
            &mut visiting,
            0,
        ));
        if total > u64::from(MAX_STEPS) {
            let span = step
                .repeat
                .as_ref()
                .and_then(|r| r.span.clone())
                .or_else(|| step.rule.as_ref().and_then(|r| r.span.clone()))
                .or_else(|| step.span.clone());
            let count = if total == u64::MAX {
                "an astronomical number of".to_owned()
            } else {
                total.to_string()
            };
            return Err(c
                .error(
                    span,
                    format!(
                        "the rules unroll to more than {MAX_STEPS} steps ({count} up to this one)"
                    ),
                )
                .with_help("every `repeat` multiplies the steps of the rule it includes"));
        }
    }
    Ok(())
}

/// Steps `steps` unroll to, rules included and repeats multiplied
/// (saturating; a rule in a cycle or nested past [`MAX_NESTING`] counts 0
/// here: the expander reports those).
fn unrolled(
    ast: &RuleFile,
    names: &[&str],
    steps: &[ast::Step],
    memo: &mut [Option<u64>],
    visiting: &mut [bool],
    depth: usize,
) -> u64 {
    let mut total: u64 = 0;
    for step in steps {
        let repeat = step.repeat.as_ref().map_or(1, |r| r.value.max(1) as u64);
        let each = match &step.rule {
            None => 1,
            Some(rule) => match names.iter().position(|n| *n == rule.value) {
                None => 0,
                Some(i) if visiting[i] || depth >= MAX_NESTING => 0,
                Some(i) => match memo[i] {
                    Some(n) => n,
                    None => {
                        visiting[i] = true;
                        let n = unrolled(
                            ast,
                            names,
                            &ast.rules.0[i].1.steps,
                            memo,
                            visiting,
                            depth + 1,
                        );
                        visiting[i] = false;
                        memo[i] = Some(n);
                        n
                    }
                },
            },
        };
        total = total.saturating_add(repeat.saturating_mul(each));
    }
    total
}

/// Turns lists of AST steps into program steps: includes rules, unrolls
/// repeats, compiles compounds once, numbers every step (its uid) in
/// program order and names it by its path.
struct Expander<'c, 'a> {
    c: &'c Compiler<'a>,
    ast: &'c RuleFile,
    base_dir: &'c Path,
    next_uid: u32,
    /// Rules being included, for cycle detection.
    rule_stack: Vec<usize>,
    compound_stack: Vec<usize>,
    compounds: Vec<Option<Compound>>,
    uses_graph: bool,
    /// Whether the model may have an edge once the steps expanded so far
    /// have run (an over-approximation: only `false` is a certainty).
    edges_possible: bool,
    /// The file's `tolerance`, for steps that turn merging on.
    default_tolerance: f64,
    /// Rule applications being expanded, outermost first (cleared inside
    /// a compound, whose steps are compiled once for every call).
    rule_instances: Vec<u32>,
    next_rule_instance: u32,
    /// Whether a step may cancel a compound or rule application.
    may_cancel: bool,
    /// Compiled bodies by written step (looked up only, never iterated):
    /// copies of a step share one.
    bodies: FxHashMap<*const ast::Step, Arc<StepBody>>,
}

/// Deepest nesting of rule inclusions and compound commands (a rule that
/// includes a rule that calls a compound counts 3): input-driven recursion
/// must stay far from the stack's end.
pub const MAX_NESTING: usize = 64;

/// Most steps a rule file may unroll to: a guard against `repeat = 1e9`.
const MAX_STEPS: u32 = 1_000_000;

impl Expander<'_, '_> {
    /// Expands `steps` into `out`. `prefix` is prepended to every path;
    /// `forced_name` names a lone step (the start).
    fn expand(
        &mut self,
        steps: &[ast::Step],
        prefix: &str,
        out: &mut Vec<Step>,
        forced_name: Option<&str>,
    ) -> Result<(), RuleError> {
        let c = self.c;
        // Local step names → uids of their copies, for `from`.
        let mut local: Vec<(String, Vec<u32>)> = Vec::new();
        let mut explicit: Vec<&str> = Vec::new();
        for (i, step) in steps.iter().enumerate() {
            check_stray_keys(c, step)?;
            let name = match (&step.name, forced_name, &step.rule) {
                (Some(n), _, _) => {
                    let span = c.content_span(n, &n.value);
                    if n.value.is_empty() || n.value.contains(['/', '#']) {
                        return Err(c.error(
                            span,
                            "step names must be non-empty and contain no `/` or `#`",
                        ));
                    }
                    if explicit.contains(&n.value.as_str()) {
                        return Err(c.error(span, format!("two steps are named `{}`", n.value)));
                    }
                    explicit.push(&n.value);
                    n.value.clone()
                }
                (None, Some(forced), _) => forced.to_owned(),
                (None, None, Some(rule)) => rule.value.clone(),
                (None, None, None) => format!("step{}", i + 1),
            };
            let repeat = match &step.repeat {
                None => 1,
                Some(r) => {
                    if !(1..=i64::from(MAX_STEPS)).contains(&r.value) {
                        return Err(c.error(
                            r.span.clone(),
                            format!("`repeat` must be between 1 and {MAX_STEPS}"),
                        ));
                    }
                    r.value as u32
                }
            };
            let mut copies = Vec::new();
            for k in 0..repeat {
                let path = if repeat > 1 {
                    format!("{prefix}{name}#{}", k + 1)
                } else {
                    format!("{prefix}{name}")
                };
                if let Some(rule) = &step.rule {
                    self.include_rule(step, rule, &format!("{path}/"), out)?;
                } else {
                    if self.next_uid >= MAX_STEPS {
                        return Err(c.error(
                            step.repeat.as_ref().and_then(|r| r.span.clone()),
                            format!("the rules unroll to more than {MAX_STEPS} steps"),
                        ));
                    }
                    let uid = self.next_uid;
                    self.next_uid += 1;
                    let compiled = self.compile_step(step, uid, &path, &local)?;
                    out.push(compiled);
                    copies.push(uid);
                }
            }
            if !copies.is_empty() {
                local.retain(|(n, _)| *n != name);
                local.push((name, copies));
            }
        }
        Ok(())
    }

    fn include_rule(
        &mut self,
        step: &ast::Step,
        rule: &Spanned<String>,
        prefix: &str,
        out: &mut Vec<Step>,
    ) -> Result<(), RuleError> {
        let c = self.c;
        let span = c.content_span(rule, &rule.value);
        if step.op.is_some() || step.compound.is_some() {
            return Err(c.error(
                span,
                "a step includes a rule or runs an operator or a compound, not both",
            ));
        }
        for (present, key) in [
            (step.select.is_some(), "select"),
            (step.from.is_some(), "from"),
            (step.on.is_some(), "on"),
            (step.policy.is_some(), "policy"),
            (step.tolerance.is_some(), "tolerance"),
        ] {
            if present {
                return Err(c.error(
                    span,
                    format!(
                        "a step that includes a rule takes no `{key}` (put it on the rule's steps)"
                    ),
                ));
            }
        }
        let names = definition_names(&self.ast.rules);
        let index = find_definition(
            c,
            span.clone(),
            &rule.value,
            &names,
            (
                "rule",
                "rules",
                "define it as `[rules.NAME]` with a `step` list",
            ),
        )?;
        if let Some(cycle) = cycle_through(&self.rule_stack, index, &names) {
            return Err(c.error(
                span,
                format!("rules include each other in a cycle: {cycle}"),
            ));
        }
        self.check_nesting(span.clone())?;
        self.rule_stack.push(index);
        self.rule_instances.push(self.next_rule_instance);
        self.next_rule_instance += 1;
        let steps = &self.ast.rules.0[index].1.steps;
        let result = self.expand(steps, prefix, out, None);
        self.rule_instances.pop();
        self.rule_stack.pop();
        result
    }

    /// Refuses one more level of rule inclusion or compound nesting past
    /// [`MAX_NESTING`].
    fn check_nesting(&self, span: Option<Range<usize>>) -> Result<(), RuleError> {
        if self.rule_stack.len() + self.compound_stack.len() < MAX_NESTING {
            return Ok(());
        }
        Err(self
            .c
            .error(
                span,
                format!(
                    "rules and compound commands are nested more than {MAX_NESTING} levels deep"
                ),
            )
            .with_help("use `repeat` on a step or a rule instead of a chain of inclusions"))
    }

    /// Compiles compound `index` once; `call_span` locates a cycle error.
    fn compile_compound(
        &mut self,
        index: usize,
        call_span: Option<Range<usize>>,
    ) -> Result<(), RuleError> {
        let c = self.c;
        if self.compounds[index].is_some() {
            return Ok(());
        }
        let names = definition_names(&self.ast.compound);
        if let Some(cycle) = cycle_through(&self.compound_stack, index, &names) {
            return Err(c.error(
                call_span,
                format!("compound commands contain each other in a cycle: {cycle}"),
            ));
        }
        self.check_nesting(call_span.clone())?;
        let (name, def) = &self.ast.compound.0[index];
        if !is_identifier(&name.value) {
            return Err(c.error(
                name.span.clone(),
                format!(
                    "`{}` is not a valid compound name (letters, digits, `_`)",
                    name.value
                ),
            ));
        }
        let domain = domain_of(def.on.value);
        let select = match &def.select {
            Some(s) => Some(c.condition(domain, s)?),
            None => None,
        };
        // Validate the definition's own parameters now (calls merge them).
        compile_frame(c, domain, &def.frame(), &ast::FrameSpec::default())?;
        self.compound_stack.push(index);
        let outer_rules = std::mem::take(&mut self.rule_instances);
        let mut steps = Vec::new();
        let result = self.expand(&def.steps, &format!("{}/", name.value), &mut steps, None);
        self.compound_stack.pop();
        self.rule_instances = outer_rules;
        result?;
        if steps.is_empty() {
            return Err(c.error(
                name.span.clone(),
                format!("compound `{}` has no steps", name.value),
            ));
        }
        if let Some(s) = steps.iter().find(|s| s.op.is_create()) {
            return Err(c.error(
                None,
                format!(
                    "compound `{}`: step `{}` creates a shape from nothing; a compound only grows its initial primitive",
                    name.value, s.name
                ),
            ));
        }
        self.compounds[index] = Some(Compound {
            name: name.value.clone(),
            domain,
            select,
            steps,
        });
        Ok(())
    }

    /// A relative `create_edge` or `edit_node` takes its length unit from
    /// the node's incoming edge. Where the steps so far cannot have made any
    /// edge (a file starting from one vertex) and the length is not zero,
    /// that is certain to fail, so it is reported before anything runs. Inside compounds the
    /// order of calls is not known here; the engine reports those cases.
    fn check_preceding_edge(
        &mut self,
        op: &Op,
        span: Option<Range<usize>>,
        key: &str,
    ) -> Result<(), RuleError> {
        if !self.compound_stack.is_empty() {
            return Ok(());
        }
        let node_command = match op {
            Op::Command(command) => matches!(
                command.kind,
                CommandKind::CreateEdge | CommandKind::EditNode
            )
            .then_some(command),
            _ => None,
        };
        if let Some(command) = node_command {
            // A zero relative length is fine without an edge (the node's own
            // frame is used); only a length certain to be non-zero fails.
            let length = match &command.length {
                None => Some(if command.kind == CommandKind::CreateEdge {
                    1.0
                } else {
                    0.0
                }),
                Some(l) => l.expr.constant(),
            };
            let moves = length.is_some_and(|l| l != 0.0)
                || command
                    .vary_length
                    .as_ref()
                    .is_some_and(|v| v.expr.constant() != Some(0.0));
            if command.relative && moves && !self.edges_possible {
                return Err(self
                    .c
                    .error(
                        span,
                        format!("relative `{key}` needs a preceding edge (the node's incoming edge), but no edge can exist yet at this step"),
                    )
                    .with_help("make the first edge absolute (leave out `relative` or set it to false), as the trunk of rules/tree.toml does"));
            }
        }
        let keeps_edgeless = matches!(op, Op::Vertex { .. })
            || node_command.is_some_and(|c| c.kind == CommandKind::EditNode);
        if !keeps_edgeless {
            self.edges_possible = true;
        }
        Ok(())
    }

    /// One copy of a written step: its place and what it reads, with the
    /// body compiled on the step's first copy and shared by the others.
    fn compile_step(
        &mut self,
        step: &ast::Step,
        uid: u32,
        path: &str,
        earlier: &[(String, Vec<u32>)],
    ) -> Result<Step, RuleError> {
        let c = self.c;
        let body = match self.bodies.get(&std::ptr::from_ref(step)) {
            Some(body) => Arc::clone(body),
            None => {
                let body = Arc::new(self.compile_body(step, path)?);
                self.bodies
                    .insert(std::ptr::from_ref(step), Arc::clone(&body));
                body
            }
        };
        let from = match &step.from {
            None => None,
            Some(f) => {
                let span = c.content_span(f, &f.value);
                match earlier.iter().find(|(n, _)| *n == f.value) {
                    Some((_, uids)) => Some(uids.clone()),
                    None => {
                        let names: Vec<&str> = earlier.iter().map(|(n, _)| n.as_str()).collect();
                        return Err(c
                            .error(span, format!("no earlier step is named `{}`", f.value))
                            .with_help(if names.is_empty() {
                                "`from` names an earlier step of the same list; this is the first"
                                    .to_owned()
                            } else {
                                format!("earlier steps: {}", names.join(", "))
                            }));
                    }
                }
            }
        };
        let on_intersection = self.step_on_intersection(step, &body.op)?;
        Ok(Step {
            uid,
            key: stream_key(&format!("step/{path}")),
            name: path.to_owned(),
            from,
            on_intersection,
            rule_instances: self.rule_instances.clone(),
            body,
        })
    }

    /// What a written step does: its operator, condition, kind and policy
    /// (the same for every copy; `path` names the first in errors).
    fn compile_body(&mut self, step: &ast::Step, path: &str) -> Result<StepBody, RuleError> {
        let c = self.c;
        let (op_key, op, compound_index) = match (&step.op, &step.compound) {
            (Some(_), Some((key, _))) => {
                return Err(c.error(
                    key.span.clone(),
                    "a step runs one operator or one compound, not both",
                ))
            }
            (Some((key, op)), None) => (key, Some(op), None),
            (None, Some((key, call))) => {
                let span = call.value.name.span.clone().or_else(|| call.span.clone());
                let index = find_definition(
                    c,
                    span.clone(),
                    &call.value.name.value,
                    &definition_names(&self.ast.compound),
                    (
                        "compound command",
                        "compound commands",
                        "define it as `[compound.NAME]` with `on` and a `step` list",
                    ),
                )?;
                self.compile_compound(index, span)?;
                (key, None, Some(index))
            }
            (None, None) => {
                return Err(c
                    .error(step.span.clone(), format!("step `{path}` has no operator"))
                    .with_help(
                        "add one operator key, such as `cube = {}` or `extrude_faces = { distance = 1 }`, or `rule = \"NAME\"`, or `compound = \"NAME\"`",
                    ));
            }
        };
        let op_span = op_key.span.clone();
        let creates = op.is_some_and(|op| is_create(&op.value));
        let whole_mesh = op.is_some_and(|op| matches!(op.value, Operation::Skin(_)));
        if creates || whole_mesh {
            for (present, key) in [
                (step.select.is_some(), "select"),
                (step.from.is_some(), "from"),
                (step.on.is_some(), "on"),
            ] {
                if present {
                    let what = if creates {
                        "creates geometry"
                    } else {
                        "works on the whole mesh"
                    };
                    return Err(c.error(
                        op_span.clone(),
                        format!("`{}` {what} and takes no `{key}`", op_key.value),
                    ));
                }
            }
        }
        let compound_domain = compound_index.map(|i| {
            self.compounds[i]
                .as_ref()
                .map_or(Domain::Face, |compound| compound.domain)
        });
        let allowed: &[Domain] = match (op, compound_domain) {
            (Some(op), _) => allowed_domains(&op.value),
            (None, Some(Domain::Vert)) => &[Domain::Vert],
            (None, Some(Domain::Edge)) => &[Domain::Edge],
            (None, _) => &[Domain::Face],
        };
        let domain = match &step.on {
            None => allowed[0],
            Some(on) => {
                let d = domain_of(on.value);
                if !allowed.contains(&d) {
                    let names: Vec<&str> = allowed.iter().map(|&d| plural(d)).collect();
                    return Err(c.error(
                        on.span.clone(),
                        format!(
                            "`{}` works on {}, not {}",
                            op_key.value,
                            names.join(" or "),
                            plural(d)
                        ),
                    ));
                }
                d
            }
        };
        let select = match &step.select {
            Some(s) => Some(c.condition(domain, s)?),
            None => None,
        };
        let op = match (op, compound_index) {
            (Some(op), _) => {
                let compiled = compile_op(c, op, op_span.clone(), domain, self.base_dir)?;
                if matches!(compiled, Op::Command(_)) {
                    self.uses_graph = true;
                }
                compiled
            }
            (None, Some(index)) => {
                self.uses_graph = true;
                let (_, call) = step.compound.as_ref().expect("compound step");
                let def = &self.ast.compound.0[index].1;
                Op::Compound {
                    index,
                    frame: Box::new(compile_frame(c, domain, &def.frame(), &call.value.frame)?),
                }
            }
            (None, None) => unreachable!("checked above"),
        };
        self.check_preceding_edge(&op, op_span.clone(), &op_key.value)?;
        let location = match op_span {
            Some(span) => {
                let (line, column) = super::diagnostic::line_column(&c.file.text, span.start);
                format!("{}:{line}:{column}", c.file.name)
            }
            None => c.file.name.clone(),
        };
        let policy = self.step_policy(step, &op, &op_key.value)?;
        Ok(StepBody {
            location,
            domain,
            select,
            op,
            policy,
        })
    }

    /// A step's own `on_intersection`: G³ commands and compound calls only;
    /// cancelling needs something to cancel.
    fn step_on_intersection(
        &mut self,
        step: &ast::Step,
        op: &Op,
    ) -> Result<Option<OnIntersection>, RuleError> {
        let Some(name) = &step.on_intersection else {
            return Ok(None);
        };
        let c = self.c;
        let span = name.span.clone();
        let is_compound = matches!(op, Op::Compound { .. });
        if !matches!(op, Op::Command(_)) && !is_compound {
            return Err(c.error(
                span,
                "`on_intersection` belongs to G³ commands and compound calls",
            ));
        }
        let value = on_intersection(name.value);
        let in_compound = !self.compound_stack.is_empty();
        match value {
            OnIntersection::CancelCompound if !in_compound && !is_compound => {
                return Err(c
                    .error(span, "`cancel_compound` outside a compound command")
                    .with_help(
                        "use it on a compound call or on the steps of a `[compound.NAME]`",
                    ));
            }
            OnIntersection::CancelRule if self.rule_instances.is_empty() && !in_compound => {
                return Err(c.error(span, "`cancel_rule` outside a rule").with_help(
                    "use it on the steps of a `[rules.NAME]` included with `rule = \"NAME\"`",
                ));
            }
            OnIntersection::CancelCompound | OnIntersection::CancelRule => self.may_cancel = true,
            OnIntersection::Skip | OnIntersection::Error => {}
        }
        Ok(Some(value))
    }

    /// A step's own `policy` and `tolerance`; they belong to G³ commands
    /// and compound calls only.
    fn step_policy(
        &self,
        step: &ast::Step,
        op: &Op,
        op_name: &str,
    ) -> Result<Option<Policy>, RuleError> {
        let c = self.c;
        if step.policy.is_none() && step.tolerance.is_none() {
            return Ok(None);
        }
        if !matches!(op, Op::Command(_) | Op::Compound { .. }) {
            let (span, key) = match &step.policy {
                Some(p) => (p.span.clone(), "policy"),
                None => (
                    step.tolerance.as_ref().and_then(|t| t.span.clone()),
                    "tolerance",
                ),
            };
            return Err(c.error(
                span,
                format!("`{key}` belongs to G³ commands and compound calls, not `{op_name}`"),
            ));
        }
        let tolerance = match &step.tolerance {
            Some(t) => Some(check_tolerance(c, t)?),
            None => None,
        };
        match (step.policy.as_ref().map(|p| p.value), tolerance) {
            (Some(ast::PolicyName::Merge), t) => Ok(Some(Policy::Merge {
                tolerance: t.unwrap_or(self.default_tolerance),
            })),
            (Some(ast::PolicyName::None), None) => Ok(Some(Policy::None)),
            (Some(ast::PolicyName::Intersect), None) => Ok(Some(Policy::Intersect)),
            (_, Some(_)) => Err(c
                .error(
                    step.tolerance.as_ref().and_then(|t| t.span.clone()),
                    "`tolerance` is the distance of `policy = \"merge\"`",
                )
                .with_help("add `policy = \"merge\"` to this step, or remove `tolerance`")),
            (None, None) => unreachable!("returned above"),
        }
    }
}

fn definition_names<T>(defs: &ast::Named<T>) -> Vec<&str> {
    defs.0.iter().map(|(name, _)| name.value.as_str()).collect()
}

/// Index of definition `name` among `names`, or an "unknown" error with a
/// did-you-mean hint. `what` is (singular, plural, how to define one).
fn find_definition(
    c: &Compiler,
    span: Option<Range<usize>>,
    name: &str,
    names: &[&str],
    what: (&str, &str, &str),
) -> Result<usize, RuleError> {
    let (singular, plural, define) = what;
    if let Some(i) = names.iter().position(|n| *n == name) {
        return Ok(i);
    }
    let e = c.error(span, format!("no {singular} is named `{name}`"));
    Err(match closest_in(name, names) {
        Some(i) => e.with_help(format!("did you mean `{}`?", names[i])),
        None if names.is_empty() => e.with_help(define.to_owned()),
        None => e.with_help(format!("{plural}: {}", names.join(", "))),
    })
}

/// `a → b → a` when `index` is already on `stack` (definitions being expanded).
fn cycle_through(stack: &[usize], index: usize, names: &[&str]) -> Option<String> {
    let at = stack.iter().position(|&r| r == index)?;
    let mut cycle: Vec<&str> = stack[at..].iter().map(|&r| names[r]).collect();
    cycle.push(names[index]);
    Some(cycle.join(" → "))
}

/// Reports a step's unknown keys and extra operators.
fn check_stray_keys(c: &Compiler, step: &ast::Step) -> Result<(), RuleError> {
    let Some(stray) = step.stray_keys.first() else {
        return Ok(());
    };
    let span = stray.span.clone();
    Err(match &step.op {
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
                    "a step takes `name`, `select`, `from`, `on`, `repeat` and one operator ({}), `rule = \"NAME\"` or `compound = \"NAME\"`",
                    ast::OPERATOR_NAMES.join(", ")
                )),
            }
        }
    })
}

/// A compound's frame: the call's values override the definition's.
fn compile_frame(
    c: &Compiler,
    domain: Domain,
    definition: &ast::FrameSpec,
    call: &ast::FrameSpec,
) -> Result<FrameParams, RuleError> {
    let scalar = |v: Option<&ast::Value>| -> Result<Option<Condition>, RuleError> {
        v.map(|v| c.property_scalar(domain, v)).transpose()
    };
    let vector = |v: Option<&ast::Vector>| -> Result<Option<Box<[Condition; 3]>>, RuleError> {
        v.map(|v| c.property_vector(domain, v).map(Box::new))
            .transpose()
    };
    Ok(FrameParams {
        relative: call
            .relative
            .as_ref()
            .or(definition.relative.as_ref())
            .is_some_and(|r| r.value),
        length: scalar(call.length.as_ref().or(definition.length.as_ref()))?,
        radius: scalar(call.radius.as_ref().or(definition.radius.as_ref()))?,
        heading: vector(call.heading.as_ref().or(definition.heading.as_ref()))?,
        up: vector(call.up.as_ref().or(definition.up.as_ref()))?,
    })
}

/// Compiles a G³ command's parameters against the matched primitive.
fn compile_command(
    c: &Compiler,
    kind: CommandKind,
    o: &ast::CommandOp,
    domain: Domain,
    span: Option<Range<usize>>,
) -> Result<Command, RuleError> {
    let scalar = |v: &Option<ast::Value>| -> Result<Option<Condition>, RuleError> {
        v.as_ref().map(|v| c.property_scalar(domain, v)).transpose()
    };
    let vector = |v: &Option<ast::Vector>| -> Result<Option<Box<[Condition; 3]>>, RuleError> {
        v.as_ref()
            .map(|v| c.property_vector(domain, v).map(Box::new))
            .transpose()
    };
    if let Some(p) = &o.probability {
        if let AstScalar::Number(x) = p.value {
            if !(0.0..=1.0).contains(&x) {
                return Err(c.error(
                    p.span.clone(),
                    format!("a probability must be in [0, 1], got {x}"),
                ));
            }
        }
    }
    for (value, key) in [
        (&o.vary_length, "vary_length"),
        (&o.vary_radius, "vary_radius"),
        (&o.vary_turn, "vary_turn"),
        (&o.vary_pitch, "vary_pitch"),
        (&o.vary_roll, "vary_roll"),
    ] {
        if let Some(Spanned {
            value: AstScalar::Number(x),
            span: s,
        }) = value
        {
            if *x < 0.0 {
                return Err(c.error(
                    s.clone(),
                    format!("`{key}` is a spread σ (values are drawn from U(−σ, σ)) and cannot be negative, got {x}"),
                ));
            }
        }
    }
    let nodes = match (&o.nodes, kind) {
        (None, _) => None,
        (Some(n), CommandKind::SplitFace) => Some(c.condition(Domain::Vert, n)?),
        (Some(n), _) => {
            return Err(c.error(
                c.content_span(n, &n.value).or(span),
                "`nodes` (a secondary condition) belongs to `split_face` only",
            ))
        }
    };
    Ok(Command {
        kind,
        relative: o.relative.unwrap_or(!matches!(
            kind,
            CommandKind::CreateEdge | CommandKind::EditNode
        )),
        length: scalar(&o.length)?,
        radius: scalar(&o.radius)?,
        heading: vector(&o.heading)?,
        up: vector(&o.up)?,
        turn: scalar(&o.turn)?,
        pitch: scalar(&o.pitch)?,
        roll: scalar(&o.roll)?,
        vary_length: scalar(&o.vary_length)?,
        vary_radius: scalar(&o.vary_radius)?,
        vary_turn: scalar(&o.vary_turn)?,
        vary_pitch: scalar(&o.vary_pitch)?,
        vary_roll: scalar(&o.vary_roll)?,
        probability: scalar(&o.probability)?,
        nodes,
    })
}

fn compile_op(
    c: &Compiler,
    op: &Spanned<Operation>,
    span: Option<Range<usize>>,
    domain: Domain,
    base_dir: &Path,
) -> Result<Op, RuleError> {
    let s = |v: &ast::Value| c.scalar(v);
    let command = |kind: CommandKind, o: &ast::CommandOp| -> Result<Op, RuleError> {
        Ok(Op::Command(Box::new(compile_command(
            c,
            kind,
            o,
            domain,
            span.clone(),
        )?)))
    };
    Ok(match &op.value {
        Operation::Vertex(o) => Op::Vertex {
            at: c.opt_vector(&o.at, [0.0; 3])?,
            radius: o.radius.as_ref().map(s).transpose()?,
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
            let path = if path.is_absolute() {
                path
            } else {
                base_dir.join(path)
            };
            let location = match &o.path.span {
                Some(span) => {
                    let (line, column) = super::diagnostic::line_column(&c.file.text, span.start);
                    format!("{}:{line}:{column}", c.file.name)
                }
                None => c.file.name.clone(),
            };
            let weld = match &o.weld {
                Some(w) if !(w.value.is_finite() && w.value >= 0.0) => {
                    return Err(c.error(
                        w.span.clone(),
                        format!("`weld` is a distance ≥ 0, got {}", w.value),
                    ))
                }
                w => w.as_ref().map(|w| w.value),
            };
            let y_up = match o.up {
                None | Some(ast::AxisName::Z) => false,
                Some(ast::AxisName::Y) => true,
                Some(ast::AxisName::X) => {
                    return Err(c.error(span.clone(), "`up` of an import is \"y\" or \"z\""))
                }
            };
            Op::Import {
                resource: c.resource(Resource {
                    path,
                    written: o.path.value.clone(),
                    location,
                }),
                weld,
                y_up,
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
        Operation::CreateEdge(o) => command(CommandKind::CreateEdge, o)?,
        Operation::SplitEdge(o) => command(CommandKind::SplitEdge, o)?,
        Operation::CreateFace(o) => command(CommandKind::CreateFace, o)?,
        Operation::SplitFace(o) => command(CommandKind::SplitFace, o)?,
        Operation::EditNode(o) => command(CommandKind::EditNode, o)?,
        Operation::Skin(o) => Op::Skin {
            sides: c.opt_scalar(&o.sides, 8.0)?,
            radius: c.opt_scalar(&o.radius, 0.1)?,
            joints: o.joints.unwrap_or(true),
            keep_wires: o.keep_wires.unwrap_or(false),
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
    let keys: Vec<&'static str> = ast::STEP_KEYS
        .iter()
        .chain(ast::OPERATOR_NAMES)
        .copied()
        .collect();
    closest_in(word, &keys).map(|i| keys[i])
}

/// Index of the candidate nearest to `word`, if close enough to be a typo
/// ([`crate::geom::names::closest`]).
pub(crate) fn closest_in<S: AsRef<str>>(word: &str, candidates: &[S]) -> Option<usize> {
    crate::geom::names::closest(word, candidates)
}

/// A "did you mean" hint for an unknown name in an expression.
fn unknown_name_hint(message: &str, names: &[String]) -> Option<String> {
    let name = message.strip_prefix("unknown name `")?.split('`').next()?;
    closest_in(name, names).map(|i| format!("did you mean `{}`?", names[i]))
}

/// Loads and compiles a rule file in one go.
pub fn compile_file(path: &Path, overrides: &[Override]) -> Result<Program, RuleError> {
    let (file, ast) = load(path)?;
    let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    compile(&file, &ast, overrides, &base_dir)
}
