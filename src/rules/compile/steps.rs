//! Steps: rules included, repeats unrolled (counted against the limit
//! before anything unrolls), compounds compiled once, every step numbered
//! and keyed, its body (operator, condition, policy, look) compiled.

use super::*;

/// Refuses a file whose rules unroll to more than [`MAX_STEPS`] steps
/// before anything is unrolled: counting costs one pass over the file,
/// whatever the repeat counts say. The error points at the top-level step
/// that passes the limit.
pub(super) fn check_unrolled_size(c: &Compiler, ast: &RuleFile) -> Result<(), RuleError> {
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
pub(super) fn unrolled(
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
pub(super) struct Paths<'a> {
    pub(super) display: &'a str,
    pub(super) key: &'a str,
}

impl Paths<'_> {
    pub(super) const ROOT: Paths<'static> = Paths {
        display: "",
        key: "",
    };
}

/// Turns lists of AST steps into program steps: includes rules, unrolls
/// repeats, compiles compounds once, numbers every step (its uid) in
/// program order and names it by its path.
pub(super) struct Expander<'c, 'a> {
    pub(super) c: &'c Compiler<'a>,
    pub(super) ast: &'c RuleFile,
    pub(super) base_dir: &'c Path,
    pub(super) next_uid: u32,
    /// Rules being included, for cycle detection.
    pub(super) rule_stack: Vec<usize>,
    pub(super) compound_stack: Vec<usize>,
    pub(super) compounds: Vec<Option<Compound>>,
    pub(super) uses_graph: bool,
    /// Whether the model may have an edge once the steps expanded so far
    /// have run (an over-approximation: only `false` is a certainty).
    pub(super) edges_possible: bool,
    /// The file's `tolerance`, for steps that turn merging on.
    pub(super) default_tolerance: f64,
    /// Rule applications being expanded, outermost first (cleared inside
    /// a compound, whose steps are compiled once for every call).
    pub(super) rule_instances: Vec<u32>,
    pub(super) next_rule_instance: u32,
    /// Whether a step may cancel a compound or rule application.
    pub(super) may_cancel: bool,
    /// Compiled bodies by written step (looked up only, never iterated):
    /// copies of a step share one.
    pub(super) bodies: FxHashMap<*const ast::Step, Arc<StepBody>>,
    /// Parts and materials; steps add the parts they name.
    pub(super) look: Look,
    /// Whether a step names a part or material.
    pub(super) tags_looks: bool,
}

/// Deepest nesting of rule inclusions and compound commands (a rule that
/// includes a rule that calls a compound counts 3): input-driven recursion
/// must stay far from the stack's end.
pub const MAX_NESTING: usize = 64;

/// Most steps a rule file may unroll to: a guard against `repeat = 1e9`.
pub(super) const MAX_STEPS: u32 = 1_000_000;

impl Expander<'_, '_> {
    /// Expands `steps` into `out`. `prefix`'s paths are prepended to
    /// every step's; `forced_name` names a lone step (the start).
    pub(super) fn expand(
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

    pub(super) fn include_rule(
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
    pub(super) fn check_nesting(&self, span: Option<Range<usize>>) -> Result<(), RuleError> {
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
    pub(super) fn compile_compound(
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
    pub(super) fn check_preceding_edge(
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
    pub(super) fn compile_step(
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
                            .with_help(if f.value == "start" {
                                // What a user writes first to delete an imported
                                // mesh after taking its convex hull.
                                "the start shape is not a step `from` can name: make it a \
                                 named step (`[[step]]` with `name = \"input\"` and its \
                                 create operator) and write `from = \"input\"`"
                                    .to_owned()
                            } else if names.is_empty() {
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
    pub(super) fn compile_body(
        &mut self,
        step: &ast::Step,
        path: &str,
    ) -> Result<StepBody, RuleError> {
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
                let look = &mut self.look;
                let compiled = compile_op(
                    c,
                    def,
                    args,
                    op_span.clone(),
                    domain,
                    self.base_dir,
                    &mut |name| look.part_index(name),
                )?;
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
    pub(super) fn step_on_intersection(
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
    pub(super) fn step_policy(
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

pub(super) fn definition_names<T>(defs: &ast::Named<T>) -> Vec<&str> {
    defs.0.iter().map(|(name, _)| name.value.as_str()).collect()
}

/// Index of definition `name` among `names`, or an "unknown" error with a
/// did-you-mean hint. `what` is (singular, plural, how to define one).
pub(super) fn find_definition(
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
pub(super) fn cycle_through(stack: &[usize], index: usize, names: &[&str]) -> Option<String> {
    let at = stack.iter().position(|&r| r == index)?;
    let mut cycle: Vec<&str> = stack[at..].iter().map(|&r| names[r]).collect();
    cycle.push(names[index]);
    Some(cycle.join(" → "))
}

/// Reports a step's unknown keys and extra operators.
pub(super) fn check_stray_keys(c: &Compiler, step: &ast::Step) -> Result<(), RuleError> {
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
pub(super) fn compile_frame(
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
