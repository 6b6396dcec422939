//! Signed distance trees: `[sdf.NAME]` tables and inline trees, checked
//! against the node-kind registry ([`crate::rules::sdf_kinds`]) and compiled
//! into the program's [`SdfForest`]. Children are names (shared: a tree
//! named twice is compiled once) or inline tables; cycles of names and
//! nesting past [`MAX_TREE_DEPTH`] are located errors.
//!
//! After the parameters are compiled, every tree is built once with the
//! parameters at nominal values (literal numbers as written, distributions
//! at their centre) and validated by the SDF pillar, so a negative radius, a
//! rounding larger than its box or a smooth blend over a child that is only
//! a bound (spec D1) is an error before the run, at its key.

use std::ops::Range;
use std::sync::Arc;

use super::{check_value, closest_in, compile_params, Compiler};
use crate::rules::ast::{self, ArgValue};
use crate::rules::diagnostic::RuleError;
use crate::rules::program::{Arg, Param, ParamKind};
use crate::rules::sdf_kinds::{self, Children, CHILDREN_KEY, CHILD_KEY, KIND_KEY, PLACEMENT};
use crate::rules::sdf_tree::{tree_limits, MAX_TREE_DEPTH};
use crate::rules::sdf_tree::{SdfForest, SdfNode, TreeError};
use crate::rules::spanned::Spanned;
use crate::sdf::{MeshField, SignMode};

/// What the compiler keeps while compiling trees.
#[derive(Default)]
pub(super) struct TreeState {
    pub forest: SdfForest,
    /// By `[sdf.NAME]` index: its node, once compiled.
    by_name: Vec<Option<usize>>,
    /// Names being compiled (for cycles), innermost last.
    stack: Vec<usize>,
    /// By node: where its table and keys are written.
    spans: Vec<NodeSpans>,
    /// Nodes that are the root of a tree some operator uses, or of a
    /// named tree: validated after compilation.
    roots: Vec<usize>,
}

#[derive(Default)]
struct NodeSpans {
    table: Option<Range<usize>>,
    keys: Vec<(String, Option<Range<usize>>)>,
}

impl Compiler<'_> {
    /// Compiles every `[sdf.NAME]` table (in file order), so errors in
    /// unused trees are reported too.
    pub(super) fn compile_named_trees(&self) -> Result<(), RuleError> {
        self.trees.borrow_mut().by_name = vec![None; self.sdf_defs.0.len()];
        for i in 0..self.sdf_defs.0.len() {
            let node = self.named_tree(i, self.sdf_defs.0[i].0.span.clone(), 0)?;
            self.trees.borrow_mut().roots.push(node);
        }
        Ok(())
    }

    /// The node an operator's `tree` parameter names or writes inline.
    pub(super) fn tree_reference(
        &self,
        value: &Spanned<ArgValue>,
        owner: &str,
    ) -> Result<usize, RuleError> {
        let node = self.tree_value(value, &format!("{owner}.tree"), 0)?;
        self.trees.borrow_mut().roots.push(node);
        Ok(node)
    }

    /// A child or tree value: a name or a table.
    fn tree_value(
        &self,
        value: &Spanned<ArgValue>,
        path: &str,
        depth: usize,
    ) -> Result<usize, RuleError> {
        match &value.value {
            ArgValue::Text(name) | ArgValue::Name(name) => {
                let names: Vec<&str> = self
                    .sdf_defs
                    .0
                    .iter()
                    .map(|(n, _)| n.value.as_str())
                    .collect();
                let Some(i) = names.iter().position(|n| *n == name) else {
                    let e = self.error(value.span.clone(), format!("no sdf tree named `{name}`"));
                    return Err(match closest_in(name, &names) {
                        Some(k) => e.with_help(format!("did you mean `{}`?", names[k])),
                        None if names.is_empty() => {
                            e.with_help("define it as a table `[sdf.NAME]` with a `kind`")
                        }
                        None => e.with_help(format!("sdf trees: {}", names.join(", "))),
                    });
                };
                self.named_tree(i, value.span.clone(), depth)
            }
            ArgValue::Table(args) => {
                self.tree_table(args, value.span.clone(), path.to_string(), depth)
            }
            other => Err(self.error(
                value.span.clone(),
                format!(
                    "invalid type: {}, expected the name of an sdf tree or a tree table",
                    other.describe()
                ),
            )),
        }
    }

    /// The node of `[sdf.NAME]` number `i`, compiled on first use.
    fn named_tree(
        &self,
        i: usize,
        span: Option<Range<usize>>,
        depth: usize,
    ) -> Result<usize, RuleError> {
        if let Some(node) = self.trees.borrow().by_name[i] {
            return Ok(node);
        }
        let name = self.sdf_defs.0[i].0.value.clone();
        if let Some(at) = self.trees.borrow().stack.iter().position(|&k| k == i) {
            let stack = &self.trees.borrow().stack;
            let cycle: Vec<&str> = stack[at..]
                .iter()
                .map(|&k| self.sdf_defs.0[k].0.value.as_str())
                .chain([name.as_str()])
                .collect();
            return Err(self.error(
                span,
                format!("sdf tree `{name}` contains itself: {}", cycle.join(" → ")),
            ));
        }
        self.trees.borrow_mut().stack.push(i);
        let table = &self.sdf_defs.0[i].1;
        let node = self.tree_table(&table.value, table.span.clone(), name, depth);
        self.trees.borrow_mut().stack.pop();
        let node = node?;
        self.trees.borrow_mut().by_name[i] = Some(node);
        Ok(node)
    }

    /// One node table: its kind, children, parameters and placement.
    fn tree_table(
        &self,
        table: &ast::Args,
        span: Option<Range<usize>>,
        path: String,
        depth: usize,
    ) -> Result<usize, RuleError> {
        if depth >= MAX_TREE_DEPTH {
            return Err(self
                .error(
                    span,
                    format!("sdf trees are nested more than {MAX_TREE_DEPTH} levels deep"),
                )
                .with_help("share a subtree by naming it once instead of nesting copies"));
        }
        let Some((kind_key, kind_value)) = table.get(KIND_KEY) else {
            let kinds: Vec<&str> = sdf_kinds::names().collect();
            return Err(self
                .error(span, "missing field `kind` of an sdf node")
                .with_help(format!("kinds: {}", kinds.join(", "))));
        };
        let kind_name = match &kind_value.value {
            ArgValue::Text(k) | ArgValue::Name(k) => k.as_str(),
            other => {
                return Err(self.error(
                    kind_value.span.clone(),
                    format!(
                        "invalid type: {}, expected a node kind name",
                        other.describe()
                    ),
                ))
            }
        };
        let Some(kind) = sdf_kinds::find(kind_name) else {
            let kinds: Vec<&str> = sdf_kinds::names().collect();
            let e = self.error(
                kind_value.span.clone(),
                format!("unknown sdf node kind `{kind_name}`"),
            );
            return Err(match closest_in(kind_name, &kinds) {
                Some(k) => e.with_help(format!("did you mean `{}`?", kinds[k])),
                None => e.with_help(format!("kinds: {}", kinds.join(", "))),
            });
        };
        let mut values: Vec<Option<&Spanned<ArgValue>>> = vec![None; kind.params.len()];
        let mut placed: Vec<Option<&Spanned<ArgValue>>> = vec![None; PLACEMENT.len()];
        let mut child_values: Option<(&Spanned<String>, &Spanned<ArgValue>)> = None;
        let mut spans = NodeSpans {
            table: span.clone(),
            keys: Vec::new(),
        };
        for (key, value) in &table.0 {
            spans.keys.push((key.value.clone(), value.span.clone()));
            let k = key.value.as_str();
            let slot = if k == KIND_KEY {
                continue;
            } else if let Some(i) = kind.params.iter().position(|p| p.key == k) {
                check_value(self, kind.name, &kind.params[i], value)?;
                &mut values[i]
            } else if let Some(i) = PLACEMENT.iter().position(|p| p.key == k) {
                check_value(self, kind.name, &PLACEMENT[i], value)?;
                &mut placed[i]
            } else if (k == CHILD_KEY && kind.children == Children::One)
                || (k == CHILDREN_KEY && matches!(kind.children, Children::Many { .. }))
            {
                if child_values.is_some() {
                    return Err(self.error(key.span.clone(), format!("duplicate field `{k}`")));
                }
                child_values = Some((key, value));
                continue;
            } else {
                let mut keys: Vec<&str> = kind.params.iter().map(|p| p.key).collect();
                match kind.children {
                    Children::None => {}
                    Children::One => keys.push(CHILD_KEY),
                    Children::Many { .. } => keys.push(CHILDREN_KEY),
                }
                keys.extend(PLACEMENT.iter().map(|p| p.key));
                let listed: Vec<String> = keys.iter().map(|k| format!("`{k}`")).collect();
                let e = self.error(
                    key.span.clone(),
                    format!(
                        "unknown field `{k}` of a `{}` node, expected one of {}",
                        kind.name,
                        listed.join(", ")
                    ),
                );
                return Err(match closest_in(k, &keys) {
                    Some(i) => e.with_help(format!("did you mean `{}`?", keys[i])),
                    None => e,
                });
            };
            if slot.is_some() {
                return Err(self.error(key.span.clone(), format!("duplicate field `{k}`")));
            }
            *slot = Some(value);
        }
        for (p, v) in kind.params.iter().zip(&values) {
            if p.required && v.is_none() {
                return Err(self.error(
                    span.clone(),
                    format!("missing field `{}` of a `{}` node", p.key, kind.name),
                ));
            }
        }
        let children = match (kind.children, child_values) {
            (Children::None, _) => Vec::new(),
            (Children::One, Some((_, value))) => {
                vec![self.tree_value(value, &format!("{path}.child"), depth + 1)?]
            }
            (Children::One, None) => {
                return Err(self.error(
                    span,
                    format!("missing field `child` of a `{}` node", kind.name),
                ))
            }
            (Children::Many { min }, Some((key, value))) => {
                let ArgValue::List(items) = &value.value else {
                    return Err(self.error(
                        value.span.clone(),
                        format!(
                            "invalid type: {}, expected a list of trees (names or tables)",
                            value.value.describe()
                        ),
                    ));
                };
                if items.len() < min {
                    return Err(self.error(
                        value.span.clone().or(key.span.clone()),
                        format!(
                            "a `{}` node needs at least {min} children, got {}",
                            kind.name,
                            items.len()
                        ),
                    ));
                }
                items
                    .iter()
                    .enumerate()
                    .map(|(i, item)| {
                        self.tree_value(item, &format!("{path}.children[{i}]"), depth + 1)
                    })
                    .collect::<Result<_, _>>()?
            }
            (Children::Many { .. }, None) => {
                return Err(self.error(
                    span,
                    format!("missing field `children` of a `{}` node", kind.name),
                ))
            }
        };
        // No tree parameter names a part.
        let no_parts =
            &mut |name: &str| -> u32 { unreachable!("sdf parameter naming part {name}") };
        let args = compile_params(
            self,
            kind.name,
            kind.params,
            &values,
            self.base_dir,
            no_parts,
        )?;
        let placement = PLACEMENT
            .iter()
            .zip(&placed)
            .map(|(p, v)| match v {
                Some(_) => compile_params(
                    self,
                    kind.name,
                    std::slice::from_ref(p),
                    &[*v],
                    self.base_dir,
                    &mut |name: &str| -> u32 { unreachable!("placement naming part {name}") },
                )
                .map(|mut a| a.remove(0)),
                None => Ok(Arg::Absent),
            })
            .collect::<Result<Vec<Arg>, RuleError>>()?;
        let location = self.location(kind_key.span.as_ref().or(span.as_ref()));
        let mut state = self.trees.borrow_mut();
        state.forest.nodes.push(SdfNode {
            kind,
            args,
            placement,
            children,
            name: path,
            location,
        });
        state.spans.push(spans);
        Ok(state.forest.nodes.len() - 1)
    }

    /// Builds every tree with the parameters at nominal values and lets
    /// the pillar validate it; the first problem is an error at its key.
    pub(super) fn validate_trees(&self, params: &[Param]) -> Result<(), RuleError> {
        let state = self.trees.borrow();
        if state.roots.is_empty() {
            return Ok(());
        }
        let Some(slots) = nominal_slots(params, self.param_names.len()) else {
            return Ok(());
        };
        // A mesh file is not read yet: a small closed stand-in has the
        // contract of any closed mesh (an exact distance).
        let stand_in = Arc::new(stand_in_field());
        let mut fields = |_: usize, _: SignMode, _: bool| Ok(Arc::clone(&stand_in));
        let limits = tree_limits();
        for &root in &state.roots {
            let built = state
                .forest
                .build(root, &slots, &mut fields)
                .map_err(|e| self.tree_error(&state, &e))?;
            if let Err(e) = built.tree.analyze(built.root, &limits) {
                let located = state.forest.locate(&built, &e);
                return Err(self.tree_error(&state, &located));
            }
        }
        Ok(())
    }

    fn tree_error(&self, state: &TreeState, e: &TreeError) -> RuleError {
        let spans = &state.spans[e.node];
        let span = e
            .key
            .as_deref()
            .and_then(|key| {
                let base = key.split('[').next().unwrap_or(key);
                spans
                    .keys
                    .iter()
                    .find(|(k, _)| k == base)
                    .map(|(_, s)| s.clone())
            })
            .flatten()
            .or(spans.table.clone());
        let node = &state.forest.nodes[e.node];
        let reads_params = !self.param_names.is_empty();
        let e = self.error(span, format!("sdf node `{}`: {}", node.name, e.message));
        if reads_params {
            e.with_help("checked with every parameter at its nominal value (constants as written, distributions at their centre, the first choice)")
        } else {
            e
        }
    }
}

/// Parameter values for checking trees before the run: expressions as
/// written, uniform and integer ranges at their centre, normals at their
/// mean, the first choice, clamped. `None` if one is not finite.
pub(super) fn nominal_slots(params: &[Param], count: usize) -> Option<Vec<f64>> {
    let mut slots = vec![0.0; count];
    for p in params {
        let e = |x: &crate::rules::expr::Expr| x.eval(&slots);
        let mut v = match &p.kind {
            ParamKind::Expr(x) => e(x),
            ParamKind::Uniform { low, high } => 0.5 * (e(low) + e(high)),
            ParamKind::Normal { mean, .. } => e(mean),
            ParamKind::Int { low, high } => libm::round(0.5 * (e(low) + e(high))),
            ParamKind::Choice { values, .. } => e(&values[0]),
        };
        if let Some((lo, hi)) = &p.clamp {
            let (lo, hi) = (e(lo), e(hi));
            if lo <= hi {
                v = v.clamp(lo, hi);
            }
        }
        if !v.is_finite() {
            return None;
        }
        slots[p.slot as usize] = v;
    }
    Some(slots)
}

/// A unit tetrahedron's distance field.
fn stand_in_field() -> MeshField {
    let p = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let t = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    MeshField::new(&p, &t, SignMode::Auto).expect("a tetrahedron is a valid mesh")
}
