//! The compiler's state and its values: numbers, vectors and expressions
//! over parameters or element properties, every error located in the
//! file.

use super::*;

pub(super) struct Compiler<'a> {
    pub(super) file: &'a SourceFile,
    pub(super) param_names: Vec<String>,
    /// Files the program needs (see [`Program::resources`]).
    pub(super) resources: std::cell::RefCell<Vec<Resource>>,
    /// Directory relative paths resolve against.
    pub(super) base_dir: &'a Path,
    /// The file's `[sdf.NAME]` tables.
    pub(super) sdf_defs: &'a ast::Named<Spanned<ast::Args>>,
    /// Trees compiled so far.
    pub(super) trees: std::cell::RefCell<sdf::TreeState>,
    /// The file's `[nurbs.NAME]` tables.
    pub(super) nurbs_defs: &'a ast::Named<Spanned<ast::Args>>,
    /// Whether an expression reads `random` (see [`Program::draws_per_primitive`]).
    pub(super) reads_random: std::cell::Cell<bool>,
}

impl<'a> Compiler<'a> {
    /// The index of `resource` in the program's list (added on first use).
    pub(super) fn resource(&self, resource: Resource) -> usize {
        let mut list = self.resources.borrow_mut();
        match list
            .iter()
            .position(|r| r.path == resource.path && r.kind == resource.kind)
        {
            Some(i) => i,
            None => {
                list.push(resource);
                list.len() - 1
            }
        }
    }

    pub(super) fn error(
        &self,
        span: Option<Range<usize>>,
        message: impl Into<String>,
    ) -> RuleError {
        RuleError::at(self.file, span, message)
    }

    /// `file:line:column` of `span`, for errors found at run time.
    pub(super) fn location(&self, span: Option<&Range<usize>>) -> String {
        match span {
            Some(span) => {
                let (line, column) =
                    crate::rules::diagnostic::line_column(&self.file.text, span.start);
                format!("{}:{line}:{column}", self.file.name)
            }
            None => self.file.name.clone(),
        }
    }

    /// The span of a string value's content, for locating expression errors.
    pub(super) fn content_span<T>(
        &self,
        spanned: &Spanned<T>,
        content: &str,
    ) -> Option<Range<usize>> {
        spanned
            .span
            .as_ref()
            .map(|span| content_span(&self.file.text, span.clone(), content))
    }

    pub(super) fn expr_error(&self, base: Option<Range<usize>>, err: ExprError) -> RuleError {
        let span =
            base.map(|b| b.start + err.span.start..b.start + err.span.end.max(err.span.start + 1));
        self.error(span, err.message)
    }

    /// The slot of parameter `name` (slots are in name order).
    pub(super) fn resolve_param(&self, name: &str) -> Option<u32> {
        self.param_names
            .binary_search_by(|p| p.as_str().cmp(name))
            .ok()
            .map(|i| i as u32)
    }

    /// Compiles an expression over parameters only.
    pub(super) fn param_expr(
        &self,
        text: &str,
        span: Option<Range<usize>>,
    ) -> Result<Expr, RuleError> {
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
    pub(super) fn property_scalar(
        &self,
        domain: Domain,
        value: &ast::Value,
    ) -> Result<Condition, RuleError> {
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

    pub(super) fn property_vector(
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

    pub(super) fn scalar(&self, value: &ast::Value) -> Result<Scalar, RuleError> {
        match &value.value {
            AstScalar::Number(x) => self.number(*x, value.span.clone()),
            AstScalar::Expr(text) => self.param_expr(text, self.content_span(value, text)),
        }
    }

    pub(super) fn number(&self, x: f64, span: Option<Range<usize>>) -> Result<Scalar, RuleError> {
        if !x.is_finite() {
            return Err(self.error(span, "numbers must be finite"));
        }
        Ok(Expr::compile(&format!("{x:?}"), &|_: &str| None).expect("a finite literal compiles"))
    }

    pub(super) fn vector(&self, v: &ast::Vector) -> Result<Vector, RuleError> {
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

    pub(super) fn condition(
        &self,
        domain: Domain,
        text: &Spanned<String>,
    ) -> Result<Condition, RuleError> {
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

pub(super) fn plural(d: Domain) -> &'static str {
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

pub(super) fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}
