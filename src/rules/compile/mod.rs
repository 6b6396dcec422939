//! Rule file → program: parse (TOML or RON by extension), resolve names to
//! slots, compile expressions, check every semantic rule, and locate each
//! error in the file.
//!
//! [`compile`] here runs the stages, one module each: `load` (text and
//! syntax tree), `compiler` (the shared state and values: numbers,
//! vectors, expressions), `params` (distributions, dependency order),
//! `steps` (rules, repeats, compounds, step bodies; `step_key` names their
//! random streams), `arguments` (operator tables checked against the
//! registry; `args` makes their typed arguments), `look` (parts,
//! materials, colours), `sdf` and `nurbs` (the pillars' tables).

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
    Param, ParamKind, Policy, Program, Property, Resource, ResourceKind, Scalar, Step, StepBody,
    Vector,
};
use super::property;
use super::random::stream_key;

mod args;
mod arguments;
mod compiler;
mod load;
mod look;
mod nurbs;
mod params;
mod sdf;
mod step_key;
mod steps;

use super::spanned::{SourceFormat, Spanned};
use arguments::*;
pub(crate) use compiler::domain_of;
use compiler::*;
pub use load::*;
pub use nurbs::SURFACE_KEYS;
use params::*;
use steps::*;

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
