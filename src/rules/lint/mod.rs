//! `graftal lint`: static checks of a rule file beyond what compiling it
//! requires. Every finding is located (`file:line:column`) with the same span
//! machinery as compile errors.
//!
//! | code | severity | finding |
//! |---|---|---|
//! | `undefined-name` | error | a name in an expression that is no parameter (or, where allowed, element property); all of them, where compiling stops at the first |
//! | `unused-param` | warning | a parameter no expression uses (directly or through other used parameters) |
//! | `unused-rule` | warning | a `[rules.NAME]` no reachable step includes |
//! | `unused-compound` | warning | a `[compound.NAME]` no reachable step calls |
//! | `probability-range` | warning | a `probability` expression that can leave [0, 1] with the file's parameter values (the run would stop with an error) |
//! | `never-true` | warning | a condition (`select`, a compound's `select`, `nodes`) no element can satisfy |
//! | `always-true` | warning | a condition every element satisfies (it selects nothing out) |
//!
//! Conditions are analysed by interval arithmetic over the compiled
//! expression ([`crate::rules::expr::Tree`]): each element property has its
//! range (counts are integers ≥ 0, `sides` ≥ 3, `random` in [0, 1), normal and
//! direction components in [−1, 1], lengths and areas ≥ 0, …); `&&` narrows
//! the ranges of properties compared with something on its left before
//! evaluating its right (`x > 1 && x < 0` is never true), `||` likewise with
//! the left side false. Parameters count as any finite number in conditions,
//! since `--set` can change them (so `scoped == 0` is not flagged); in
//! `probability` they take the ranges their definitions allow.

use std::cell::RefCell;
use std::collections::BTreeSet;
use std::ops::Range as Span;
use std::path::Path;

use crate::geom::interval::{next_down, next_up, Interval};
use crate::kernel::Domain;

use super::ast::{self, ArgValue, ParamSpec, RuleFile, Scalar, VectorSpec};
use super::compile::{self, domain_of, Override};
use super::diagnostic::{content_span, line_column, RuleError, SourceFile};
use super::expr::{Binary, Expr, Ternary, Tree, Unary};
use super::operators::{self, ArgKind, Family};
use super::program::{ParamKind, Program, Property};
use super::property;
use super::sdf_kinds;
use super::spanned::Spanned;

/// How bad a finding is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    Warning,
    Error,
}

/// One lint finding.
#[derive(Debug, Clone, PartialEq)]
pub struct Finding {
    pub severity: Severity,
    /// Stable code (`never-true`, …), usable with `--allow`.
    pub code: &'static str,
    /// `file:line:column`, or the file name.
    pub location: String,
    pub message: String,
    pub help: Option<String>,
    /// Byte offset, for sorting.
    offset: usize,
}

impl Finding {
    /// `file:line:col: warning[code]: message`.
    pub fn headline(&self) -> String {
        let severity = match self.severity {
            Severity::Warning => "warning",
            Severity::Error => "error",
        };
        format!(
            "{}: {severity}[{}]: {}",
            self.location, self.code, self.message
        )
    }
}

/// Every lint code, for `--allow` and the documentation.
pub const CODES: &[&str] = &[
    "undefined-name",
    "unused-param",
    "unused-rule",
    "unused-compound",
    "probability-range",
    "never-true",
    "always-true",
    "unnamed-random-step",
];

/// Lints a rule file. `Err` when it does not parse or compile (a located
/// error); otherwise the findings, errors (`undefined-name`) first. When
/// there are undefined names the file does not compile, and only those are
/// reported.
pub fn lint_source(
    file: &SourceFile,
    overrides: &[Override],
    base_dir: &Path,
) -> Result<Vec<Finding>, RuleError> {
    let ast = compile::load(file)?;
    let linter = Linter::new(file, &ast);
    let sites = linter.sites();
    let undefined = linter.undefined_names(&sites);
    if !undefined.is_empty() {
        return Ok(undefined);
    }
    let program = compile::compile(file, &ast, overrides, base_dir)?;
    let mut findings = Vec::new();
    linter.unused_params(&sites, &mut findings);
    linter.unused_definitions(&mut findings);
    linter.unnamed_random_steps(&mut findings);
    linter.conditions(&sites, &program, &mut findings);
    findings.sort_by(|a, b| {
        (std::cmp::Reverse(a.severity), a.offset, a.code, &a.message).cmp(&(
            std::cmp::Reverse(b.severity),
            b.offset,
            b.code,
            &b.message,
        ))
    });
    Ok(findings)
}

/// What names an expression may use, and what it is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Context {
    /// A parameter's definition (`params.NAME`): parameters only.
    Param(usize),
    /// A kernel operator's value: parameters only.
    Operator,
    /// A G³ command's or compound's value, per primitive of this kind.
    Primitive(Domain),
    /// A condition over primitives of this kind.
    Condition(Domain),
    /// A `[nurbs.NAME]` value: parameters and the net indices `i`, `j`.
    Generator,
}

/// An expression string in the file.
struct Site<'a> {
    text: &'a str,
    /// Where the expression's text starts.
    span: Option<Span<usize>>,
    context: Context,
    /// The key it is the value of (`select`, `probability`, …).
    key: &'static str,
}

struct Linter<'a> {
    file: &'a SourceFile,
    ast: &'a RuleFile,
    /// Parameter names by slot (sorted, as the compiler assigns them).
    params: Vec<String>,
}

impl<'a> Linter<'a> {
    fn new(file: &'a SourceFile, ast: &'a RuleFile) -> Self {
        let mut params: Vec<String> = ast.params.0.iter().map(|(n, _)| n.value.clone()).collect();
        params.sort();
        params.dedup();
        Linter { file, ast, params }
    }

    fn location(&self, span: Option<&Span<usize>>) -> (String, usize) {
        match span {
            Some(s) => {
                let (line, column) = line_column(&self.file.text, s.start);
                (format!("{}:{line}:{column}", self.file.name), s.start)
            }
            None => (self.file.name.clone(), 0),
        }
    }

    fn finding(
        &self,
        severity: Severity,
        code: &'static str,
        span: Option<&Span<usize>>,
        message: String,
        help: Option<String>,
    ) -> Finding {
        let (location, offset) = self.location(span);
        Finding {
            severity,
            code,
            location,
            message,
            help,
            offset,
        }
    }

    /// Where a string value's content is (spans include the quotes).
    fn content_span<T>(&self, spanned: &Spanned<T>, content: &str) -> Option<Span<usize>> {
        spanned
            .span
            .as_ref()
            .map(|span| content_span(&self.file.text, span.clone(), content))
    }

    // ---- collecting expressions ------------------------------------------

    fn sites(&self) -> Vec<Site<'a>> {
        let mut out = Vec::new();
        let mut declared: Vec<&(Spanned<String>, Spanned<ParamSpec>)> =
            self.ast.params.0.iter().collect();
        declared.sort_by(|a, b| a.0.value.cmp(&b.0.value));
        for (name, spec) in declared.iter().map(|p| (&p.0, &p.1)) {
            let Ok(slot) = self.params.binary_search(&name.value) else {
                continue;
            };
            let context = Context::Param(slot);
            match &spec.value {
                ParamSpec::Number(_) => {}
                ParamSpec::Expr(text) => out.push(Site {
                    text,
                    span: self.content_span(spec, text),
                    context,
                    key: "params",
                }),
                ParamSpec::Table(t) => {
                    let pairs = [&t.uniform, &t.normal, &t.int, &t.clamp];
                    for ast::Pair(values) in pairs.into_iter().flatten() {
                        for v in values {
                            self.value(v, context, "params", &mut out);
                        }
                    }
                    for v in t.choice.iter().flatten() {
                        self.value(v, context, "params", &mut out);
                    }
                }
            }
        }
        let compound_domain = |name: &str| {
            self.ast
                .compound
                .0
                .iter()
                .find(|(n, _)| n.value == name)
                .map(|(_, d)| domain_of(d.on.value))
        };
        let mut steps: Vec<&ast::Step> = Vec::new();
        steps.extend(&self.ast.start);
        steps.extend(&self.ast.steps);
        for (_, rule) in &self.ast.rules.0 {
            steps.extend(&rule.steps);
        }
        for (_, def) in &self.ast.compound.0 {
            let domain = domain_of(def.on.value);
            if let Some(s) = &def.select {
                out.push(self.condition(s, domain, "select"));
            }
            self.frame(
                [&def.length, &def.radius],
                [&def.heading, &def.up],
                domain,
                &mut out,
            );
            steps.extend(&def.steps);
        }
        for (_, table) in &self.ast.sdf.0 {
            self.tree_table(&table.value, &mut out);
        }
        for (_, table) in &self.ast.nurbs.0 {
            self.surface_table(&table.value, &mut out);
        }
        for step in steps {
            let domain = match (&step.on, &step.op, &step.compound) {
                (Some(on), _, _) => domain_of(on.value),
                (None, Some((key, _)), _) => operators::find(&key.value)
                    .and_then(|d| d.domains.first().copied())
                    .unwrap_or(Domain::Face),
                (None, None, Some((_, call))) => {
                    compound_domain(&call.value.name.value).unwrap_or(Domain::Face)
                }
                (None, None, None) => Domain::Face,
            };
            if let Some(s) = &step.select {
                out.push(self.condition(s, domain, "select"));
            }
            if let Some((_, call)) = &step.compound {
                let f = &call.value.frame;
                self.frame(
                    [&f.length, &f.radius],
                    [&f.heading, &f.up],
                    domain,
                    &mut out,
                );
            }
            if let Some((key, op)) = &step.op {
                self.operation(&key.value, &op.value, domain, &mut out);
            }
        }
        out
    }

    /// The expression sites of an inline tree (a name is linted where it
    /// is defined).
    fn tree(&self, value: &'a Spanned<ArgValue>, out: &mut Vec<Site<'a>>) {
        if let ArgValue::Table(table) = &value.value {
            self.tree_table(table, out);
        }
    }

    /// The expression sites of a tree node: its numeric values (which see
    /// parameters only) and its inline children.
    fn tree_table(&self, table: &'a ast::Args, out: &mut Vec<Site<'a>>) {
        for (key, value) in &table.0 {
            match key.value.as_str() {
                sdf_kinds::CHILD_KEY => self.tree(value, out),
                sdf_kinds::CHILDREN_KEY => {
                    if let ArgValue::List(items) = &value.value {
                        for item in items {
                            self.tree(item, out);
                        }
                    }
                }
                sdf_kinds::KIND_KEY => {}
                _ => {
                    let items: Vec<&'a Spanned<ArgValue>> = match &value.value {
                        ArgValue::List(items) => items.iter().collect(),
                        _ => vec![value],
                    };
                    // Paths and choice names are strings too: only keys
                    // of numeric kinds hold expressions.
                    let numeric = sdf_kinds::KINDS
                        .iter()
                        .flat_map(|k| k.params)
                        .chain(sdf_kinds::PLACEMENT)
                        .any(|p| {
                            p.key == key.value
                                && matches!(p.kind, ArgKind::Scalar | ArgKind::Vector)
                        });
                    if !numeric {
                        continue;
                    }
                    for item in items {
                        if let ArgValue::Text(text) = &item.value {
                            out.push(Site {
                                text,
                                span: self.content_span(item, text),
                                context: Context::Operator,
                                key: "sdf",
                            });
                        }
                    }
                }
            }
        }
    }

    /// The expression sites of a `[nurbs.NAME]` table: every string in it
    /// but the knot shorthand.
    fn surface_table(&self, table: &'a ast::Args, out: &mut Vec<Site<'a>>) {
        fn strings<'v>(v: &'v Spanned<ArgValue>, out: &mut Vec<(&'v Spanned<ArgValue>, &'v str)>) {
            match &v.value {
                ArgValue::Text(t) => out.push((v, t)),
                ArgValue::List(items) => items.iter().for_each(|i| strings(i, out)),
                _ => {}
            }
        }
        for (key, value) in &table.0 {
            // Names of curves, patches, files and choices, not expressions.
            let named = matches!(key.value.as_str(), "path" | "orient" | "patches" | "joins")
                || (key.value == "profile" && matches!(value.value, ArgValue::Text(_)));
            if named {
                continue;
            }
            let mut found = Vec::new();
            strings(value, &mut found);
            for (v, text) in found {
                if text != "clamped_uniform" {
                    out.push(Site {
                        text,
                        span: self.content_span(v, text),
                        context: Context::Generator,
                        key: "nurbs",
                    });
                }
            }
        }
    }

    fn condition(&self, s: &'a Spanned<String>, domain: Domain, key: &'static str) -> Site<'a> {
        Site {
            text: &s.value,
            span: self.content_span(s, &s.value),
            context: Context::Condition(domain),
            key,
        }
    }

    fn value(
        &self,
        v: &'a ast::Value,
        context: Context,
        key: &'static str,
        out: &mut Vec<Site<'a>>,
    ) {
        if let Scalar::Expr(text) = &v.value {
            out.push(Site {
                text,
                span: self.content_span(v, text),
                context,
                key,
            });
        }
    }

    fn vector(
        &self,
        v: &'a ast::Vector,
        context: Context,
        key: &'static str,
        out: &mut Vec<Site<'a>>,
    ) {
        match &v.value {
            VectorSpec::Components(parts) => {
                for p in parts.iter() {
                    self.value(p, context, key, out);
                }
            }
            VectorSpec::Uniform(Scalar::Expr(text)) => out.push(Site {
                text,
                span: self.content_span(v, text),
                context,
                key,
            }),
            VectorSpec::Uniform(Scalar::Number(_)) => {}
        }
    }

    fn frame(
        &self,
        values: [&'a Option<ast::Value>; 2],
        vectors: [&'a Option<ast::Vector>; 2],
        domain: Domain,
        out: &mut Vec<Site<'a>>,
    ) {
        let context = Context::Primitive(domain);
        for v in values.into_iter().flatten() {
            self.value(v, context, "compound", out);
        }
        for v in vectors.into_iter().flatten() {
            self.vector(v, context, "compound", out);
        }
    }

    /// The expression sites of an operator's arguments, by the kind of
    /// each parameter in the registry: operator values see parameters
    /// only, a G³ command's see the matched primitive too.
    fn operation(&self, name: &str, args: &'a ast::Args, domain: Domain, out: &mut Vec<Site<'a>>) {
        let Some(def) = operators::find(name) else {
            return;
        };
        for (key, value) in &args.0 {
            let Some(p) = def.param(&key.value) else {
                continue;
            };
            let (context, site_key) = match p.kind {
                ArgKind::Element | ArgKind::ElementVector => (Context::Primitive(domain), p.key),
                ArgKind::NodeCondition => {
                    if let ArgValue::Text(text) = &value.value {
                        out.push(Site {
                            text,
                            span: self.content_span(value, text),
                            context: Context::Condition(Domain::Vert),
                            key: p.key,
                        });
                    }
                    continue;
                }
                ArgKind::Scalar | ArgKind::Vector | ArgKind::Pair | ArgKind::ScalarList => {
                    (Context::Operator, "operator")
                }
                ArgKind::Bounds => (Context::Operator, "operator"),
                ArgKind::Tree => {
                    // Inline trees; named ones are linted with `[sdf]`.
                    self.tree(value, out);
                    continue;
                }
                ArgKind::Bool
                | ArgKind::Choice(_)
                | ArgKind::Path
                | ArgKind::Surface
                | ArgKind::Part => continue,
            };
            let items: Vec<&'a Spanned<ArgValue>> = match &value.value {
                ArgValue::List(items) => items
                    .iter()
                    .flat_map(|i| match &i.value {
                        ArgValue::List(inner) => inner.iter().collect(),
                        _ => vec![i],
                    })
                    .collect(),
                _ => vec![value],
            };
            for item in items {
                if let ArgValue::Text(text) = &item.value {
                    out.push(Site {
                        text,
                        span: self.content_span(item, text),
                        context,
                        key: site_key,
                    });
                }
            }
        }
    }

    // ---- names ---------------------------------------------------------------

    /// Compiles a site's expression as the compiler would (parameters are
    /// slots 0.., properties follow); unknown names are collected instead of
    /// failing, and so are the parameters read.
    fn compile_site(&self, site: &Site) -> (Option<Expr>, Vec<String>, BTreeSet<usize>) {
        let unknown: RefCell<Vec<String>> = RefCell::new(Vec::new());
        let used: RefCell<BTreeSet<usize>> = RefCell::new(BTreeSet::new());
        let base = self.params.len() as u32;
        let domain = match site.context {
            Context::Primitive(d) | Context::Condition(d) => Some(d),
            Context::Param(_) | Context::Operator | Context::Generator => None,
        };
        let generator = matches!(site.context, Context::Generator);
        let resolver = |name: &str| -> Option<u32> {
            if let Some(k) = crate::rules::nurbs_def::GENERATOR_NAMES
                .iter()
                .position(|n| generator && *n == name)
            {
                return Some(base + k as u32);
            }
            if let Ok(slot) = self.params.binary_search_by(|p| p.as_str().cmp(name)) {
                used.borrow_mut().insert(slot);
                return Some(slot as u32);
            }
            if let Some(p) = domain.and_then(|d| property::lookup(d, name)) {
                return Some(base + property::index(p));
            }
            unknown.borrow_mut().push(name.to_owned());
            // Keep parsing to find every unknown name.
            Some(u32::MAX)
        };
        let expr = Expr::compile(site.text, &resolver).ok();
        (expr, unknown.into_inner(), used.into_inner())
    }

    fn undefined_names(&self, sites: &[Site]) -> Vec<Finding> {
        let mut out = Vec::new();
        for site in sites {
            let (_, unknown, _) = self.compile_site(site);
            for name in unknown {
                let span = site.span.as_ref().and_then(|s| {
                    name_offset(site.text, &name).map(|i| s.start + i..s.start + i + name.len())
                });
                let what = match site.context {
                    Context::Param(_) | Context::Operator => "no parameter",
                    Context::Generator => "no parameter (nor `i`, `j`)",
                    Context::Primitive(_) | Context::Condition(_) => {
                        "no parameter or element property"
                    }
                };
                let help = match site.context {
                    Context::Primitive(d) | Context::Condition(d)
                        if [Domain::Vert, Domain::Edge, Domain::Face]
                            .iter()
                            .any(|&other| property::lookup(other, &name).is_some()) =>
                    {
                        Some(format!(
                            "`{name}` is a property of other elements, not of {}s",
                            d
                        ))
                    }
                    Context::Param(_) | Context::Operator
                        if [Domain::Vert, Domain::Edge, Domain::Face]
                            .iter()
                            .any(|&d| property::lookup(d, &name).is_some()) =>
                    {
                        Some("element properties are only available in conditions and G³ command values".to_owned())
                    }
                    _ if !self.params.is_empty() => {
                        Some(match compile::closest_in(&name, &self.params) {
                            Some(i) => format!("did you mean `{}`?", self.params[i]),
                            None => format!("parameters: {}", self.params.join(", ")),
                        })
                    }
                    _ => Some("declare it under [params]".to_owned()),
                };
                out.push(self.finding(
                    Severity::Error,
                    "undefined-name",
                    span.as_ref(),
                    format!("`{name}` is {what}"),
                    help,
                ));
            }
        }
        out
    }

    fn unused_params(&self, sites: &[Site], out: &mut Vec<Finding>) {
        let n = self.params.len();
        let mut deps: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n];
        let mut used = vec![false; n];
        let mut stack: Vec<usize> = Vec::new();
        for site in sites {
            let (_, _, reads) = self.compile_site(site);
            match site.context {
                Context::Param(p) => deps[p].extend(reads),
                _ => stack.extend(reads),
            }
        }
        while let Some(p) = stack.pop() {
            if !std::mem::replace(&mut used[p], true) {
                stack.extend(deps[p].iter().copied());
            }
        }
        for (name, _) in &self.ast.params.0 {
            let Ok(slot) = self.params.binary_search(&name.value) else {
                continue;
            };
            if !used[slot] {
                out.push(self.finding(
                    Severity::Warning,
                    "unused-param",
                    name.span.clone().as_ref(),
                    format!("parameter `{}` is never used", name.value),
                    Some("remove it, or use it in an expression".to_owned()),
                ));
            }
        }
    }

    fn unused_definitions(&self, out: &mut Vec<Finding>) {
        let rules = &self.ast.rules.0;
        let compounds = &self.ast.compound.0;
        let mut rule_used = vec![false; rules.len()];
        let mut compound_used = vec![false; compounds.len()];
        let mut stack: Vec<&ast::Step> = Vec::new();
        stack.extend(&self.ast.start);
        stack.extend(&self.ast.steps);
        while let Some(step) = stack.pop() {
            if let Some(rule) = &step.rule {
                if let Some(i) = rules.iter().position(|(n, _)| n.value == rule.value) {
                    if !std::mem::replace(&mut rule_used[i], true) {
                        stack.extend(&rules[i].1.steps);
                    }
                }
            }
            if let Some((_, call)) = &step.compound {
                if let Some(i) = compounds
                    .iter()
                    .position(|(n, _)| n.value == call.value.name.value)
                {
                    if !std::mem::replace(&mut compound_used[i], true) {
                        stack.extend(&compounds[i].1.steps);
                    }
                }
            }
        }
        let rule_names = rules.iter().map(|(name, _)| name).zip(rule_used);
        let compound_names = compounds.iter().map(|(name, _)| name).zip(compound_used);
        let unused = [
            (
                "unused-rule",
                "rule",
                "included",
                "include",
                rule_names.collect::<Vec<_>>(),
            ),
            (
                "unused-compound",
                "compound",
                "called",
                "apply",
                compound_names.collect(),
            ),
        ];
        for (code, kind, verb, how, names) in unused {
            for (name, _) in names.into_iter().filter(|(_, used)| !used) {
                out.push(self.finding(
                    Severity::Warning,
                    code,
                    name.span.clone().as_ref(),
                    format!("{kind} `{}` is never {verb}", name.value),
                    Some(format!(
                        "{how} it with a step `{kind} = \"{}\"`, or remove it",
                        name.value
                    )),
                ));
            }
        }
    }

    /// Steps that draw random values but have no `name`: their stream is
    /// keyed by their content, so any edit to them (a length, a select)
    /// re-rolls every draw they make.
    fn unnamed_random_steps(&self, out: &mut Vec<Finding>) {
        let every_step = self
            .ast
            .start
            .iter()
            .chain(&self.ast.steps)
            .chain(self.ast.rules.0.iter().flat_map(|(_, r)| &r.steps))
            .chain(self.ast.compound.0.iter().flat_map(|(_, c)| &c.steps));
        for step in every_step.filter(|s| s.name.is_none()) {
            let reads_random = step
                .select
                .as_ref()
                .is_some_and(|s| mentions(&s.value, "random"));
            // A G³ command draws when it has a probability or a spread.
            let varies = step.op.as_ref().is_some_and(|(key, args)| {
                operators::find(&key.value).is_some_and(|d| d.family == Family::Command)
                    && args
                        .value
                        .0
                        .iter()
                        .any(|(k, _)| k.value == "probability" || k.value.starts_with("vary_"))
            });
            if reads_random || varies {
                out.push(self.finding(
                    Severity::Warning,
                    "unnamed-random-step",
                    step.span.as_ref(),
                    "this step draws random values but has no `name`: its draws are keyed by its content, so editing any of its arguments re-rolls them".to_owned(),
                    Some("give it a `name = \"...\"` to keep its draws through edits".to_owned()),
                ));
            }
        }
    }

    // ---- conditions and probabilities ----------------------------------------

    fn conditions(&self, sites: &[Site], program: &Program, out: &mut Vec<Finding>) {
        let base = self.params.len();
        // Parameters in conditions: any finite number (`--set` may change them).
        let mut any_params = vec![Interval::finite(); base + property::SLOT_COUNT];
        let mut integer = vec![false; base + property::SLOT_COUNT];
        for k in 0..property::SLOT_COUNT {
            let (range, int) = property_range(property::at(k as u32));
            any_params[base + k] = range;
            integer[base + k] = int;
        }
        // Parameters in probabilities: the ranges their definitions allow.
        let mut defined = any_params.clone();
        let analysis = Analysis { integer: &integer };
        for p in &program.params {
            let slot = p.slot as usize;
            if slot < base {
                defined[slot] = param_range(&analysis, p, &defined);
            }
        }
        for site in sites {
            let (Some(expr), _, _) = self.compile_site(site) else {
                continue;
            };
            let tree = expr.tree();
            match (site.context, site.key) {
                (Context::Primitive(_), "probability") => {
                    let r = analysis.eval(&tree, &defined);
                    let outside = r.nan || r.lo < 0.0 || r.hi > 1.0;
                    if outside {
                        let never_inside = !r.nan && (r.hi < 0.0 || r.lo > 1.0);
                        out.push(self.finding(
                            Severity::Warning,
                            "probability-range",
                            site.span.as_ref(),
                            format!(
                                "`probability` {} outside [0, 1]: it ranges over {} with the file's parameter values",
                                if never_inside { "is always" } else { "can be" },
                                r
                            ),
                            Some("the run stops with an error when a probability leaves [0, 1]; clamp it, e.g. `clamp(…, 0, 1)`".to_owned()),
                        ));
                    }
                }
                (Context::Condition(_), key) => {
                    let r = analysis.eval(&tree, &any_params);
                    let (can_false, can_true) = r.truth();
                    let what = match key {
                        "nodes" => "`nodes` condition",
                        _ => "`select` condition",
                    };
                    let ranges = used_ranges(&expr, base, &any_params, &integer);
                    if !can_true {
                        out.push(self.finding(
                            Severity::Warning,
                            "never-true",
                            site.span.as_ref(),
                            format!(
                                "{what} `{}` can never be true: nothing will match",
                                site.text
                            ),
                            ranges.or(Some("its comparisons contradict each other".to_owned())),
                        ));
                    } else if !can_false {
                        out.push(self.finding(
                            Severity::Warning,
                            "always-true",
                            site.span.as_ref(),
                            format!(
                                "{what} `{}` is always true: it selects nothing out",
                                site.text
                            ),
                            ranges.or(Some("remove it".to_owned())),
                        ));
                    }
                }
                _ => {}
            }
        }
    }
}

/// Byte offset of `name` as a whole name in an expression's text.
/// Whether `text` uses the identifier `name` (not as part of a longer one).
fn mentions(text: &str, name: &str) -> bool {
    text.match_indices(name).any(|(i, _)| {
        let ident = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '.';
        !text[..i].chars().next_back().is_some_and(ident)
            && !text[i + name.len()..].chars().next().is_some_and(ident)
    })
}

fn name_offset(text: &str, name: &str) -> Option<usize> {
    let bytes = text.as_bytes();
    let is_name = |b: u8| b.is_ascii_alphanumeric() || b == b'_' || b == b'.';
    let mut start = 0;
    while let Some(i) = text[start..].find(name) {
        let at = start + i;
        let end = at + name.len();
        let before = at == 0 || !is_name(bytes[at - 1]);
        let after = end >= bytes.len() || !is_name(bytes[end]);
        if before && after {
            return Some(at);
        }
        start = at + 1;
    }
    None
}

/// "ranges assumed: normal.z in [-1, 1], …" for the properties an
/// expression reads.
fn used_ranges(expr: &Expr, base: usize, ranges: &[Interval], integer: &[bool]) -> Option<String> {
    let parts: Vec<String> = expr
        .used_slots()
        .iter()
        .filter(|&&s| (s as usize) >= base && (s as usize) < ranges.len())
        .filter(|&&s| ranges[s as usize] != Interval::finite())
        .map(|&s| {
            let p = property::at(s - base as u32);
            let name = property_name(p);
            let r = ranges[s as usize];
            let kind = if integer[s as usize] {
                "an integer "
            } else {
                ""
            };
            format!("`{name}` is {kind}in {r}")
        })
        .collect();
    (!parts.is_empty()).then(|| parts.join("; "))
}

/// The name a condition uses for a property.
fn property_name(p: Property) -> &'static str {
    property::row(p).name
}

/// The values a property can take, and whether it is an integer.
fn property_range(p: Property) -> (Interval, bool) {
    match property::row(p).range {
        property::Range::Finite => (Interval::finite(), false),
        property::Range::AtLeast { min, integer } => (Interval::new(min, f64::INFINITY), integer),
        property::Range::Between { min, max } => (Interval::new(min, max), false),
        property::Range::Unit => (Interval::new(0.0, next_down(1.0)), false),
    }
}

/// The values a parameter's definition allows (overrides included).
fn param_range(a: &Analysis, p: &super::program::Param, env: &[Interval]) -> Interval {
    let e = |x: &Expr| a.eval(&x.tree(), env);
    let r = match &p.kind {
        ParamKind::Expr(x) => e(x),
        ParamKind::Uniform { low, high } => e(low).hull(e(high)),
        ParamKind::Normal { .. } => Interval::finite(),
        ParamKind::Int { low, high } => {
            let r = e(low).hull(e(high));
            Interval::new(libm::round(r.lo), libm::round(r.hi))
        }
        ParamKind::Choice { values, .. } => values
            .iter()
            .map(e)
            .reduce(Interval::hull)
            .unwrap_or(Interval::finite()),
    };
    let r = match &p.clamp {
        Some((lo, hi)) => binary(Binary::Min, binary(Binary::Max, r, e(lo)), e(hi)),
        None => r,
    };
    // The engine stops on a non-finite parameter, so a running one is finite.
    Interval {
        lo: r.lo.max(f64::MIN),
        hi: r.hi.min(f64::MAX),
        nan: false,
    }
}

mod judge;
#[cfg(test)]
mod tests;

use judge::*;
