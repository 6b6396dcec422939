//! Rule file → program: parse (TOML or RON by extension), resolve names to
//! slots, compile expressions, check every semantic rule, and locate each
//! error in the file.

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use rustc_hash::FxHashMap;

use crate::kernel::Domain;

use super::ast::{self, ArgValue, DomainName, ParamSpec, RuleFile, Scalar as AstScalar};
use super::diagnostic::{content_span, RuleError, SourceFile};
use super::expr::{Expr, ExprError, BUILTIN_CONSTANT_NAMES};
use super::operators::{self, ArgKind, Default, Family, OpId, OperatorDef, ParamDef};
use super::program::{
    Arg, Call, Command, CommandKind, Compound, Condition, FrameParams, Look, OnIntersection, Op,
    Param, ParamKind, Policy, Program, Property, Resource, Scalar, Step, StepBody, Vector,
};
use super::property;
use super::random::stream_key;

mod args;
mod look;
mod nurbs;
mod sdf;
mod step_key;
use super::spanned::{SourceFormat, Spanned};
pub use nurbs::SURFACE_KEYS;

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

/// Parses a rule file's text, in the format its name's extension says.
pub fn load(file: &SourceFile) -> Result<RuleFile, RuleError> {
    let format = format_of(Path::new(&file.name)).map_err(|m| RuleError::at(file, None, m))?;
    parse(file, format)
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

struct Compiler<'a> {
    file: &'a SourceFile,
    param_names: Vec<String>,
    /// Files the program needs (see [`Program::resources`]).
    resources: std::cell::RefCell<Vec<Resource>>,
    /// Directory relative paths resolve against.
    base_dir: &'a Path,
    /// The file's `[sdf.NAME]` tables.
    sdf_defs: &'a ast::Named<Spanned<ast::Args>>,
    /// Trees compiled so far.
    trees: std::cell::RefCell<sdf::TreeState>,
    /// The file's `[nurbs.NAME]` tables.
    nurbs_defs: &'a ast::Named<Spanned<ast::Args>>,
    /// Whether an expression reads `random` (see [`Program::draws_per_primitive`]).
    reads_random: std::cell::Cell<bool>,
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

    /// `file:line:column` of `span`, for errors found at run time.
    fn location(&self, span: Option<&Range<usize>>) -> String {
        match span {
            Some(span) => {
                let (line, column) = super::diagnostic::line_column(&self.file.text, span.start);
                format!("{}:{line}:{column}", self.file.name)
            }
            None => self.file.name.clone(),
        }
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
            if property::plain_names()
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

    fn condition(&self, domain: Domain, text: &Spanned<String>) -> Result<Condition, RuleError> {
        let base = self.param_names.len() as u32;
        let resolver = |name: &str| -> Option<u32> {
            if let Some(slot) = self.resolve_param(name) {
                return Some(slot);
            }
            // Slots past the parameters are properties, in the fixed
            // order of `property::SLOTS`.
            property::lookup(domain, name).map(|p| base + property::index(p))
        };
        let expr = Expr::compile(&text.value, &resolver).map_err(|err| {
            let hint = unknown_name_hint(&err.message, &self.param_names);
            let e = self.expr_error(self.content_span(text, &text.value), err);
            let properties = format!("{} properties: {}", domain, property::help(domain));
            e.with_help(match hint {
                Some(hint) => format!("{hint} ({properties})"),
                None => properties,
            })
        })?;
        if expr
            .used_slots()
            .contains(&(base + property::index(Property::Random)))
        {
            self.reads_random.set(true);
        }
        Ok(Condition { expr })
    }
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
        base_dir,
        sdf_defs: &ast.sdf,
        trees: std::default::Default::default(),
        nurbs_defs: &ast.nurbs,
        reads_random: std::cell::Cell::new(false),
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
        if property::plain_names().contains(&name.value.as_str())
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
                let no_trees = ast::Named::default();
                let c = Compiler {
                    file: &source,
                    param_names: compiler.param_names.clone(),
                    resources: std::cell::RefCell::new(Vec::new()),
                    base_dir,
                    sdf_defs: &no_trees,
                    trees: std::default::Default::default(),
                    nurbs_defs: &no_trees,
                    reads_random: std::cell::Cell::new(false),
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
    compiler.compile_named_trees()?;
    let surfaces = compiler.compile_surfaces()?;

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
        look: compiler.compile_look(ast)?,
        tags_looks: false,
    };
    check_unrolled_size(&compiler, ast)?;
    let mut steps: Vec<Step> = Vec::new();
    if let Some(start) = &ast.start {
        if let Some((key, _)) = &start.op {
            if !operators::find(&key.value).is_some_and(|d| d.is_create()) {
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
        expander.expand(
            std::slice::from_ref(start),
            Paths::ROOT,
            &mut steps,
            Some("start"),
        )?;
    }
    expander.expand(&ast.steps, Paths::ROOT, &mut steps, None)?;
    let uses_graph = expander.uses_graph;
    let may_cancel = expander.may_cancel;
    let tags_looks = expander.tags_looks;
    let mut expander_look = expander.look;
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
                    look: std::mem::take(&mut expander_look),
                    tags_looks: false,
                };
                check.compile_compound(i, None)?;
                expander_look = check.look;
                compounds.push(Compound {
                    name: ast.compound.0[i].0.value.clone(),
                    domain: Domain::Face,
                    select: None,
                    steps: Vec::new(),
                });
            }
        }
    }

    compiler.validate_trees(&params)?;
    compiler.validate_surfaces(&surfaces, &params)?;

    let mut hash_input = file.text.clone();
    for o in overrides {
        hash_input.push_str(&format!("\n--set {}={}", o.name, o.value));
    }
    // Per-primitive draws key on lineage, which the engine keeps only
    // for programs that draw.
    let command_draws = |steps: &[Step]| {
        steps
            .iter()
            .any(|s| matches!(&s.op, Op::Command(c) if c.draws()))
    };
    let draws_per_primitive = compiler.reads_random.get()
        || command_draws(&steps)
        || compounds.iter().any(|c| command_draws(&c.steps));
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
        sdf: compiler.trees.take().forest,
        nurbs: surfaces,
        look: expander_look,
        tags_looks,
        draws_per_primitive,
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

/// A step's two paths: the one it is shown by (`grow#2/step1`) and the one
/// its random stream is named by (`grow#2/~3f…`, see [`step_key`]).
#[derive(Clone, Copy)]
struct Paths<'a> {
    display: &'a str,
    key: &'a str,
}

impl Paths<'_> {
    const ROOT: Paths<'static> = Paths {
        display: "",
        key: "",
    };
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
    /// Parts and materials; steps add the parts they name.
    look: Look,
    /// Whether a step names a part or material.
    tags_looks: bool,
}

/// Deepest nesting of rule inclusions and compound commands (a rule that
/// includes a rule that calls a compound counts 3): input-driven recursion
/// must stay far from the stack's end.
pub const MAX_NESTING: usize = 64;

/// Most steps a rule file may unroll to: a guard against `repeat = 1e9`.
const MAX_STEPS: u32 = 1_000_000;

impl Expander<'_, '_> {
    /// Expands `steps` into `out`. `prefix`'s paths are prepended to
    /// every step's; `forced_name` names a lone step (the start).
    fn expand(
        &mut self,
        steps: &[ast::Step],
        prefix: Paths<'_>,
        out: &mut Vec<Step>,
        forced_name: Option<&str>,
    ) -> Result<(), RuleError> {
        let c = self.c;
        // Local step names → uids of their copies, for `from`.
        let mut local: Vec<(String, Vec<u32>)> = Vec::new();
        let mut explicit: Vec<&str> = Vec::new();
        // Key names given so far in this list, to tell siblings apart.
        let mut key_names: Vec<String> = Vec::new();
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
            // The random stream's name: the step's name, or for an unnamed
            // operator step its content (issue 33: not its position). Two
            // siblings with one key name are told apart by occurrence.
            let key_name = match (&step.name, forced_name, &step.rule) {
                (None, None, None) => step_key::content_name(step),
                _ => name.clone(),
            };
            let earlier = key_names.iter().filter(|k| **k == key_name).count();
            key_names.push(key_name.clone());
            let key_name = match earlier {
                0 => key_name,
                n => format!("{key_name}.{}", n + 1),
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
                let copy = |base: &str| {
                    if repeat > 1 {
                        format!("{base}#{}", k + 1)
                    } else {
                        base.to_owned()
                    }
                };
                let path = format!("{}{}", prefix.display, copy(&name));
                let key_path = format!("{}{}", prefix.key, copy(&key_name));
                if let Some(rule) = &step.rule {
                    let (display, key) = (format!("{path}/"), format!("{key_path}/"));
                    self.include_rule(
                        step,
                        rule,
                        Paths {
                            display: &display,
                            key: &key,
                        },
                        out,
                    )?;
                } else {
                    if self.next_uid >= MAX_STEPS {
                        return Err(c.error(
                            step.repeat.as_ref().and_then(|r| r.span.clone()),
                            format!("the rules unroll to more than {MAX_STEPS} steps"),
                        ));
                    }
                    let uid = self.next_uid;
                    self.next_uid += 1;
                    let compiled = self.compile_step(step, uid, &path, &key_path, &local)?;
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
        prefix: Paths<'_>,
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
        let prefix = format!("{}/", name.value);
        let paths = Paths {
            display: &prefix,
            key: &prefix,
        };
        let result = self.expand(&def.steps, paths, &mut steps, None);
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
        let keeps_edgeless = matches!(op, Op::Call(call) if call.def.id == OpId::Vertex)
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
        key_path: &str,
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
            key: stream_key(&format!("step/{key_path}")),
            name: path.into(),
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
        let def = op
            .map(|_| operators::find(&op_key.value).expect("the parser keeps operator keys only"));
        let creates = def.is_some_and(|d| d.family == Family::Create);
        let whole_mesh = def.is_some_and(|d| d.family == Family::WholeMesh);
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
        let allowed: &[Domain] = match (def, compound_domain) {
            (Some(def), _) => def.domains,
            (None, Some(Domain::Vert)) => &[Domain::Vert],
            (None, Some(Domain::Edge)) => &[Domain::Edge],
            (None, _) => &[Domain::Face],
        };
        let domain = match &step.on {
            None => allowed.first().copied().unwrap_or(Domain::Face),
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
            (Some(args), _) => {
                let def = def.expect("an operator step has a definition");
                let compiled = compile_op(c, def, args, op_span.clone(), domain, self.base_dir)?;
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
        let location = c.location(op_span.as_ref());
        let policy = self.step_policy(step, &op, &op_key.value)?;
        let part = match &step.part {
            Some(name) => {
                c.check_name(name, "part")?;
                Some(self.look.part_index(&name.value))
            }
            None => None,
        };
        let material = match &step.material {
            Some(name) => Some(c.material_reference(&self.look, name)?),
            None => None,
        };
        // Steps that create no faces or edges (they move, merge or delete)
        // would tag nothing: say so rather than do nothing.
        let tags_nothing = def.is_some_and(|d| !d.tags);
        if tags_nothing && (part.is_some() || material.is_some()) {
            let key = step
                .part
                .as_ref()
                .or(step.material.as_ref())
                .and_then(|k| k.span.clone());
            return Err(c
                .error(key, format!("`{}` creates no faces, so `part` and `material` would change nothing", op_key.value))
                .with_help("give existing faces a part or material with a separate step: `assign = {}` with the same `select`"));
        }
        if def.is_some_and(|d| d.id == operators::OpId::Assign)
            && part.is_none()
            && material.is_none()
        {
            return Err(c
                .error(
                    op_span.clone(),
                    "`assign` changes nothing without `part` or `material`",
                )
                .with_help("add `part = \"NAME\"` or `material = \"NAME\"` to the step"));
        }
        self.tags_looks |= part.is_some() || material.is_some();
        Ok(StepBody {
            location,
            domain,
            select,
            op,
            policy,
            part,
            material,
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
        Some((key, _)) if operators::find(&stray.value).is_some() => c
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
                    operators::names().collect::<Vec<_>>().join(", ")
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

/// An operator's arguments checked against its definition: every key
/// known, none twice, the required ones present, exclusive ones apart,
/// every value of its parameter's shape and literal numbers in bounds.
/// Values by parameter index.
struct CheckedArgs<'a> {
    def: &'static OperatorDef,
    values: Vec<Option<&'a Spanned<ArgValue>>>,
}

fn check_args<'a>(
    c: &Compiler,
    def: &'static OperatorDef,
    args: &'a Spanned<ast::Args>,
    span: Option<Range<usize>>,
) -> Result<CheckedArgs<'a>, RuleError> {
    let mut values: Vec<Option<&'a Spanned<ArgValue>>> = vec![None; def.params.len()];
    for (key, value) in &args.value.0 {
        let Some(i) = def.params.iter().position(|p| p.key == key.value) else {
            if key.value == "nodes" && def.family == Family::Command {
                return Err(c.error(
                    key.span.clone(),
                    "`nodes` (a secondary condition) belongs to `split_face` only",
                ));
            }
            let expected = if def.params.is_empty() {
                format!("`{}` takes no parameters", def.name)
            } else {
                let keys: Vec<String> = def.keys().map(|k| format!("`{k}`")).collect();
                format!("expected one of {}", keys.join(", "))
            };
            let keys: Vec<&str> = def.keys().collect();
            let e = c.error(
                key.span.clone(),
                format!("unknown field `{}`, {expected}", key.value),
            );
            return Err(match closest_in(&key.value, &keys) {
                Some(k) => e.with_help(format!("did you mean `{}`?", keys[k])),
                None => e,
            });
        };
        if values[i].is_some() {
            return Err(c.error(key.span.clone(), format!("duplicate field `{}`", key.value)));
        }
        check_value(c, def.name, &def.params[i], value)?;
        values[i] = Some(value);
    }
    for (p, v) in def.params.iter().zip(&values) {
        if p.required && v.is_none() {
            return Err(c.error(
                args.span.clone().or(span.clone()),
                format!("missing field `{}`", p.key),
            ));
        }
    }
    let present = |key: &str| {
        def.params
            .iter()
            .zip(&values)
            .any(|(p, v)| p.key == key && v.is_some())
    };
    for (a, b) in def.exclusive {
        if present(a) && present(b) {
            return Err(c.error(span, format!("give either `{a}` or `{b}`, not both")));
        }
    }
    Ok(CheckedArgs { def, values })
}

/// Checks one value's shape (and a literal number's bounds) for its parameter.
fn check_value(
    c: &Compiler,
    owner: &str,
    p: &ParamDef,
    value: &Spanned<ArgValue>,
) -> Result<(), RuleError> {
    let wrong = |expected: &str| {
        c.error(
            value.span.clone(),
            format!(
                "invalid type: {}, expected {expected}",
                value.value.describe()
            ),
        )
    };
    let scalar = |v: &ArgValue| matches!(v, ArgValue::Number(_) | ArgValue::Text(_));
    let scalars = |items: &[Spanned<ArgValue>]| items.iter().all(|i| scalar(&i.value));
    match (p.kind, &value.value) {
        (ArgKind::Scalar | ArgKind::Element, v) if scalar(v) => {}
        (ArgKind::Scalar | ArgKind::Element, _) => {
            return Err(wrong("a number or an expression string"))
        }
        (ArgKind::Vector | ArgKind::ElementVector, ArgValue::List(items)) => {
            if items.len() != 3 {
                return Err(c.error(
                    value.span.clone(),
                    format!("invalid length {}, expected 3 components", items.len()),
                ));
            }
            if !scalars(items) {
                return Err(wrong("a 3-vector [x, y, z] of numbers or expressions"));
            }
        }
        (ArgKind::Vector | ArgKind::ElementVector, v) if scalar(v) => {}
        (ArgKind::Vector | ArgKind::ElementVector, _) => {
            return Err(wrong(
                "a 3-vector [x, y, z] or a single number or expression",
            ))
        }
        (ArgKind::Pair, ArgValue::List(items)) if items.len() == 2 && scalars(items) => {}
        (ArgKind::Pair, ArgValue::List(items)) if items.len() != 2 => {
            return Err(c.error(
                value.span.clone(),
                format!("invalid length {}, expected 2 values", items.len()),
            ))
        }
        (ArgKind::Pair, _) => return Err(wrong("a list of two numbers or expressions, [a, b]")),
        (ArgKind::ScalarList, ArgValue::List(items)) if scalars(items) => {
            if items.is_empty() {
                return Err(c.error(
                    value.span.clone(),
                    format!("`{}` needs at least one value", p.key),
                ));
            }
        }
        (ArgKind::ScalarList, _) => return Err(wrong("a list of numbers or expressions")),
        (ArgKind::Bool, ArgValue::Bool(_)) => {}
        (ArgKind::Bool, _) => return Err(wrong("a boolean")),
        (ArgKind::Choice(names), ArgValue::Text(n) | ArgValue::Name(n)) => {
            if !names.contains(&n.as_str()) {
                let list: Vec<String> = names.iter().map(|n| format!("`{n}`")).collect();
                return Err(c.error(
                    value.span.clone(),
                    format!("unknown variant `{n}`, expected one of {}", list.join(", ")),
                ));
            }
        }
        (ArgKind::Choice(_), _) => return Err(wrong("a name")),
        (ArgKind::Path, ArgValue::Text(t)) if !t.is_empty() => {}
        (ArgKind::Path, _) => return Err(wrong("a file path string")),
        (ArgKind::NodeCondition, ArgValue::Text(_)) => {}
        (ArgKind::NodeCondition, _) => return Err(wrong("a condition string")),
        (ArgKind::Tree, ArgValue::Text(_) | ArgValue::Name(_) | ArgValue::Table(_)) => {}
        (ArgKind::Surface, ArgValue::Text(_) | ArgValue::Name(_)) => {}
        (ArgKind::Surface, _) => return Err(wrong("the name of a [nurbs.NAME] surface")),
        (ArgKind::Tree, _) => {
            return Err(wrong(
                "the name of an [sdf.NAME] tree, or a tree table such as { kind = \"sphere\", radius = 1 }",
            ))
        }
        (ArgKind::Bounds, ArgValue::List(corners))
            if corners.len() == 2
                && corners.iter().all(
                    |c| matches!(&c.value, ArgValue::List(x) if x.len() == 3 && scalars(x)),
                ) =>
        {
            for corner in corners {
                if let ArgValue::List(items) = &corner.value {
                    for item in items {
                        if let ArgValue::Number(x) = item.value {
                            if !x.is_finite() {
                                return Err(c.error(item.span.clone(), "numbers must be finite"));
                            }
                        }
                    }
                }
            }
        }
        (ArgKind::Bounds, _) => {
            return Err(wrong(
                "a box [[x, y, z], [x, y, z]] (lowest corner, highest corner)",
            ))
        }
    }
    let mut literals: Vec<(f64, Option<Range<usize>>)> = Vec::new();
    match &value.value {
        ArgValue::Number(x) => literals.push((*x, value.span.clone())),
        ArgValue::List(items) => {
            for item in items {
                if let ArgValue::Number(x) = item.value {
                    literals.push((x, item.span.clone()));
                }
            }
        }
        _ => {}
    }
    for (x, span) in literals {
        if !x.is_finite() {
            return Err(c.error(span, "numbers must be finite"));
        }
        if let Some(bound) = p.above.filter(|&b| x <= b) {
            let what = if bound == 0.0 {
                "positive".to_string()
            } else {
                format!("greater than {bound}")
            };
            return Err(c.error(
                span,
                format!("`{}` of `{owner}` must be {what}, got {x}", p.key),
            ));
        }
        let below = p.min.is_some_and(|m| x < m);
        let above = p.max.is_some_and(|m| x > m);
        if below || above {
            let message = match (p.min, p.max) {
                (Some(lo), Some(hi)) => format!("a {} must be in [{lo}, {hi}], got {x}", p.key),
                _ if p.key.starts_with("vary_") => format!(
                    "`{}` is a spread σ (values are drawn from U(−σ, σ)) and cannot be negative, got {x}",
                    p.key
                ),
                (Some(lo), None) => format!("`{}` of `{owner}` must be at least {lo}, got {x}", p.key),
                (None, Some(hi)) => format!("`{}` of `{owner}` must be at most {hi}, got {x}", p.key),
                (None, None) => unreachable!("a bound was passed"),
            };
            return Err(c.error(span, message));
        }
    }
    Ok(())
}

/// Checked values by parameter index, with typed accessors.
struct CheckedValues<'v, 'a> {
    params: &'v [ParamDef],
    values: &'v [Option<&'a Spanned<ArgValue>>],
}

impl<'a> CheckedArgs<'a> {
    fn view(&self) -> CheckedValues<'_, 'a> {
        CheckedValues {
            params: self.def.params,
            values: &self.values,
        }
    }
}

impl CheckedValues<'_, '_> {
    fn value(&self, key: &str) -> Option<&Spanned<ArgValue>> {
        let i = self.params.iter().position(|p| p.key == key)?;
        self.values[i]
    }

    /// The value as the AST's scalar (checked to be one).
    fn scalar(&self, key: &str) -> Option<ast::Value> {
        self.value(key).map(as_scalar)
    }

    /// The value as the AST's vector (checked to be one).
    fn vector(&self, key: &str) -> Option<ast::Vector> {
        self.value(key).map(|v| match &v.value {
            ArgValue::List(items) => Spanned {
                value: ast::VectorSpec::Components(Box::new([
                    as_scalar(&items[0]),
                    as_scalar(&items[1]),
                    as_scalar(&items[2]),
                ])),
                span: v.span.clone(),
            },
            _ => {
                let s = as_scalar(v);
                Spanned {
                    value: ast::VectorSpec::Uniform(s.value),
                    span: s.span,
                }
            }
        })
    }

    fn text(&self, key: &str) -> Option<Spanned<String>> {
        self.value(key).and_then(|v| match &v.value {
            ArgValue::Text(t) | ArgValue::Name(t) => Some(Spanned {
                value: t.clone(),
                span: v.span.clone(),
            }),
            _ => None,
        })
    }

    fn flag(&self, key: &str) -> Option<bool> {
        self.value(key).and_then(|v| match v.value {
            ArgValue::Bool(b) => Some(b),
            _ => None,
        })
    }
}

/// A number or text value as the AST's scalar.
fn as_scalar(v: &Spanned<ArgValue>) -> ast::Value {
    Spanned {
        value: match &v.value {
            ArgValue::Number(x) => AstScalar::Number(*x),
            ArgValue::Text(t) => AstScalar::Expr(t.clone()),
            other => unreachable!("checked to be a scalar: {other:?}"),
        },
        span: v.span.clone(),
    }
}

/// Compiles an operator's arguments. A G³ command becomes a [`Command`];
/// every other operator a [`Call`] with one [`Arg`] per parameter,
/// defaults filled in.
fn compile_op(
    c: &Compiler,
    def: &'static OperatorDef,
    args: &Spanned<ast::Args>,
    span: Option<Range<usize>>,
    domain: Domain,
    base_dir: &Path,
) -> Result<Op, RuleError> {
    let checked = check_args(c, def, args, span.clone())?;
    if def.family == Family::Command {
        return Ok(Op::Command(Box::new(compile_command(c, &checked, domain)?)));
    }
    check_method_params(c, &checked)?;
    let args = compile_params(c, def.name, def.params, &checked.values, base_dir)?;
    Ok(Op::Call(Box::new(Call {
        def,
        args: args::typed(def, args),
    })))
}

/// Parameters that belong to one `method` of an operator: written with
/// the other, they are an error (they would be silently ignored).
fn check_method_params(c: &Compiler, checked: &CheckedArgs) -> Result<(), RuleError> {
    if checked.def.id != OpId::Skin {
        return Ok(());
    }
    let view = checked.view();
    let field = view.text("method").is_some_and(|m| m.value == "field");
    let (method, other_only): (&str, &[&str]) = if field {
        ("field", &["sides", "joints"])
    } else {
        (
            "tubes",
            &["blend", "min_radius", "cell", "mesher", "vertex"],
        )
    };
    for key in other_only {
        if let Some(v) = view.value(key) {
            let other = if field { "tubes" } else { "field" };
            return Err(c
                .error(
                    v.span.clone(),
                    format!("`{key}` belongs to `method = \"{other}\"`, and this skin uses \"{method}\""),
                )
                .with_help(format!("remove `{key}`, or set `method = \"{other}\"`")));
        }
    }
    Ok(())
}

/// Compiles checked values (by parameter index) of `params` into one
/// [`Arg`] each, defaults filled in.
fn compile_params(
    c: &Compiler,
    owner: &str,
    params: &[ParamDef],
    values: &[Option<&Spanned<ArgValue>>],
    base_dir: &Path,
) -> Result<Vec<Arg>, RuleError> {
    let checked = CheckedValues { params, values };
    let mut compiled: Vec<Arg> = Vec::with_capacity(params.len());
    for p in params {
        let arg = match (p.kind, checked.value(p.key)) {
            (ArgKind::Scalar, Some(_)) => {
                Arg::Scalar(c.scalar(&checked.scalar(p.key).expect("present"))?)
            }
            (ArgKind::Vector, Some(_)) => {
                Arg::Vector(c.vector(&checked.vector(p.key).expect("present"))?)
            }
            (ArgKind::Pair, Some(v)) => match &v.value {
                ArgValue::List(items) => Arg::Pair([
                    c.scalar(&as_scalar(&items[0]))?,
                    c.scalar(&as_scalar(&items[1]))?,
                ]),
                _ => unreachable!("checked to be a pair"),
            },
            (ArgKind::ScalarList, Some(v)) => match &v.value {
                ArgValue::List(items) => Arg::List(
                    items
                        .iter()
                        .map(|i| c.scalar(&as_scalar(i)))
                        .collect::<Result<_, _>>()?,
                ),
                _ => unreachable!("checked to be a list"),
            },
            (ArgKind::Bool, Some(_)) => Arg::Bool(checked.flag(p.key).expect("present")),
            (ArgKind::Choice(names), Some(_)) => {
                let name = checked.text(p.key).expect("present").value;
                Arg::Choice(names.iter().position(|n| *n == name).expect("checked"))
            }
            (ArgKind::Path, Some(_)) => {
                let written = checked.text(p.key).expect("present");
                let path = PathBuf::from(&written.value);
                let path = if path.is_absolute() {
                    path
                } else {
                    base_dir.join(path)
                };
                let location = c.location(written.span.as_ref());
                Arg::Resource(c.resource(Resource {
                    path,
                    written: written.value,
                    location,
                }))
            }
            (ArgKind::Tree, Some(v)) => Arg::Tree(c.tree_reference(v, owner)?),
            (ArgKind::Surface, Some(v)) => Arg::Surface(c.surface_reference(v)?),
            (ArgKind::Bounds, Some(v)) => match &v.value {
                ArgValue::List(corners) => {
                    let corner = |k: usize| -> Result<Vector, RuleError> {
                        let ArgValue::List(items) = &corners[k].value else {
                            unreachable!("checked to be a box")
                        };
                        Ok(Vector([
                            c.scalar(&as_scalar(&items[0]))?,
                            c.scalar(&as_scalar(&items[1]))?,
                            c.scalar(&as_scalar(&items[2]))?,
                        ]))
                    };
                    Arg::Bounds(Box::new([corner(0)?, corner(1)?]))
                }
                _ => unreachable!("checked to be a box"),
            },
            (ArgKind::Element | ArgKind::ElementVector | ArgKind::NodeCondition, _) => {
                unreachable!("per-primitive parameters belong to G³ commands")
            }
            (_, None) => match p.default {
                Default::None => Arg::Absent,
                Default::Number(x) => Arg::Scalar(c.number(x, None)?),
                Default::Vector(v) => Arg::Vector(Vector([
                    c.number(v[0], None)?,
                    c.number(v[1], None)?,
                    c.number(v[2], None)?,
                ])),
                Default::Pair(v) => Arg::Pair([c.number(v[0], None)?, c.number(v[1], None)?]),
                Default::Bool(b) => Arg::Bool(b),
                Default::Choice(i) => Arg::Choice(i),
                Default::SameAs(other) => {
                    let i = params
                        .iter()
                        .position(|q| q.key == other)
                        .expect("registered");
                    compiled[i].clone()
                }
            },
        };
        compiled.push(arg);
    }
    Ok(compiled)
}

/// A G³ command's parameters (thesis 003 §2.4.3): conditions evaluated per
/// matched primitive.
fn compile_command(
    c: &Compiler,
    checked: &CheckedArgs,
    domain: Domain,
) -> Result<Command, RuleError> {
    let a = checked.view();
    let kind = match checked.def.id {
        OpId::CreateEdge => CommandKind::CreateEdge,
        OpId::SplitEdge => CommandKind::SplitEdge,
        OpId::CreateFace => CommandKind::CreateFace,
        OpId::SplitFace => CommandKind::SplitFace,
        OpId::EditNode => CommandKind::EditNode,
        other => unreachable!("{other:?} is no command"),
    };
    let scalar = |key: &str| -> Result<Option<Condition>, RuleError> {
        a.scalar(key)
            .map(|v| c.property_scalar(domain, &v))
            .transpose()
    };
    let vector = |key: &str| -> Result<Option<Box<[Condition; 3]>>, RuleError> {
        a.vector(key)
            .map(|v| c.property_vector(domain, &v).map(Box::new))
            .transpose()
    };
    let nodes = match checked.def.param("nodes") {
        Some(_) => a
            .text("nodes")
            .map(|n| c.condition(Domain::Vert, &n))
            .transpose()?,
        None => None,
    };
    Ok(Command {
        kind,
        relative: a.flag("relative").unwrap_or(!matches!(
            kind,
            CommandKind::CreateEdge | CommandKind::EditNode
        )),
        length: scalar("length")?,
        radius: scalar("radius")?,
        heading: vector("heading")?,
        up: vector("up")?,
        turn: scalar("turn")?,
        pitch: scalar("pitch")?,
        roll: scalar("roll")?,
        vary_length: scalar("vary_length")?,
        vary_radius: scalar("vary_radius")?,
        vary_turn: scalar("vary_turn")?,
        vary_pitch: scalar("vary_pitch")?,
        vary_roll: scalar("vary_roll")?,
        probability: scalar("probability")?,
        nodes,
    })
}

/// The step key nearest to `word`, if close enough to be a typo.
fn closest(word: &str) -> Option<&'static str> {
    let keys: Vec<&'static str> = ast::STEP_KEYS
        .iter()
        .copied()
        .chain(operators::names())
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

/// Parses and compiles a rule file's text; `base_dir` resolves the paths
/// it names (the caller reads those files: see [`Program::resources`]).
pub fn compile_source(
    file: &SourceFile,
    overrides: &[Override],
    base_dir: &Path,
) -> Result<Program, RuleError> {
    let ast = load(file)?;
    compile(file, &ast, overrides, base_dir)
}
