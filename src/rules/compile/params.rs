//! Parameters: distributions and expressions compiled, then ordered so
//! that each comes after the parameters it reads (cycles refused).

use super::*;

pub(super) fn compile_param(
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
pub(super) fn order_params(
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

pub(super) fn param_exprs(p: &Param) -> impl Iterator<Item = &Expr> {
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
