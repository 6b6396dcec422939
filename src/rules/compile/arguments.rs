//! Operator arguments: every key checked against the registry (known,
//! once, required, exclusive, of its kind, in bounds), then compiled to a
//! call's typed arguments or a G³ command.

use super::*;

/// An operator's arguments checked against its definition: every key
/// known, none twice, the required ones present, exclusive ones apart,
/// every value of its parameter's shape and literal numbers in bounds.
/// Values by parameter index.
pub(super) struct CheckedArgs<'a> {
    pub(super) def: &'static OperatorDef,
    pub(super) values: Vec<Option<&'a Spanned<ArgValue>>>,
}

pub(super) fn check_args<'a>(
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
pub(super) fn check_value(
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
        (ArgKind::Part, ArgValue::Text(_) | ArgValue::Name(_)) => {}
        (ArgKind::Part, _) => return Err(wrong("the name of a part")),
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
pub(super) struct CheckedValues<'v, 'a> {
    pub(super) params: &'v [ParamDef],
    pub(super) values: &'v [Option<&'a Spanned<ArgValue>>],
}

impl<'a> CheckedArgs<'a> {
    pub(super) fn view(&self) -> CheckedValues<'_, 'a> {
        CheckedValues {
            params: self.def.params,
            values: &self.values,
        }
    }
}

impl CheckedValues<'_, '_> {
    pub(super) fn value(&self, key: &str) -> Option<&Spanned<ArgValue>> {
        let i = self.params.iter().position(|p| p.key == key)?;
        self.values[i]
    }

    /// The value as the AST's scalar (checked to be one).
    pub(super) fn scalar(&self, key: &str) -> Option<ast::Value> {
        self.value(key).map(as_scalar)
    }

    /// The value as the AST's vector (checked to be one).
    pub(super) fn vector(&self, key: &str) -> Option<ast::Vector> {
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

    pub(super) fn text(&self, key: &str) -> Option<Spanned<String>> {
        self.value(key).and_then(|v| match &v.value {
            ArgValue::Text(t) | ArgValue::Name(t) => Some(Spanned {
                value: t.clone(),
                span: v.span.clone(),
            }),
            _ => None,
        })
    }

    pub(super) fn flag(&self, key: &str) -> Option<bool> {
        self.value(key).and_then(|v| match v.value {
            ArgValue::Bool(b) => Some(b),
            _ => None,
        })
    }
}

/// A number or text value as the AST's scalar.
pub(super) fn as_scalar(v: &Spanned<ArgValue>) -> ast::Value {
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
pub(super) fn compile_op(
    c: &Compiler,
    def: &'static OperatorDef,
    args: &Spanned<ast::Args>,
    span: Option<Range<usize>>,
    domain: Domain,
    base_dir: &Path,
    parts: &mut dyn FnMut(&str) -> u32,
) -> Result<Op, RuleError> {
    let checked = check_args(c, def, args, span.clone())?;
    if def.family == Family::Command {
        return Ok(Op::Command(Box::new(compile_command(c, &checked, domain)?)));
    }
    check_method_params(c, &checked)?;
    let args = compile_params(c, def.name, def.params, &checked.values, base_dir, parts)?;
    Ok(Op::Call(Box::new(Call {
        def,
        args: args::typed(def, args),
    })))
}

/// Parameters that belong to one `method` of an operator: written with
/// the other, they are an error (they would be silently ignored).
pub(super) fn check_method_params(c: &Compiler, checked: &CheckedArgs) -> Result<(), RuleError> {
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
pub(super) fn compile_params(
    c: &Compiler,
    owner: &str,
    params: &[ParamDef],
    values: &[Option<&Spanned<ArgValue>>],
    base_dir: &Path,
    parts: &mut dyn FnMut(&str) -> u32,
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
                    kind: ResourceKind::Mesh,
                }))
            }
            (ArgKind::Tree, Some(v)) => Arg::Tree(c.tree_reference(v, owner)?),
            (ArgKind::Surface, Some(v)) => Arg::Surface(c.surface_reference(v)?),
            (ArgKind::Part, Some(_)) => {
                let name = checked.text(p.key).expect("present");
                c.check_name(&name, "part")?;
                Arg::Part(parts(&name.value))
            }
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
pub(super) fn compile_command(
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
