//! Running a program: parameters, then each step in order. A step gathers
//! its candidates (every primitive of its kind, those of the current scope,
//! or what an earlier step created), keeps those whose condition holds on
//! the generation it reads, and runs its operator, G³ command or compound
//! command on them.

use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::DVec3;
use rustc_hash::FxHashMap;
use thiserror::Error;

use super::intersect::Guard;
use super::merge::Merger;
use crate::geom::IndexedMesh;
use crate::kernel::ops::extrude::ExtrudeOffset;
use crate::kernel::ops::{self, Selection};
use crate::kernel::{Domain, EdgeId, FaceId, Mesh, VertId};
use crate::rules::compile::{property_from_index, PROPERTY_SLOTS};
use crate::rules::expr::SlotSource;
use crate::rules::program::{
    Command, CommandKind, Compound, Condition, FrameParams, Offset, OnIntersection, Op, ParamKind,
    Policy, Program, Step, Vector,
};
use crate::rules::random;

use super::commands::{self, Plan};
use super::graph::{self, Frame};
use super::properties::{self, Context};
use super::scope::{Measure, Reference, Scope};

#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Seed; the program's default when `None`.
    pub seed: Option<u64>,
    /// Stop with an error when the mesh holds more primitives than this
    /// (vertices + edges + faces): the guard against runaway rules.
    pub max_elements: usize,
    /// Testing hook: apply each command's plans in an order shuffled by
    /// this value instead of ascending id (results must not change).
    #[doc(hidden)]
    pub shuffle_visits: Option<u64>,
    /// Testing hook: check every kernel invariant after every step.
    #[doc(hidden)]
    pub validate_each_step: bool,
    /// Stop with [`RunErrorKind::Timeout`] once this instant has passed
    /// (checked between steps and before each command applies).
    pub deadline: Option<Instant>,
    /// Stop with [`RunErrorKind::EvaluationLimit`] after this many
    /// evaluations of conditions and per-primitive parameters: the bound
    /// on expression work, deterministic unlike a timeout.
    pub max_evaluations: u64,
    /// The program's [`Program::resources`], read by the caller, by index
    /// (shared by every variant of a batch).
    pub inputs: Arc<[Arc<IndexedMesh>]>,
}

/// Default `--max-evaluations`.
pub const DEFAULT_MAX_EVALUATIONS: u64 = 10_000_000_000;

/// Default `--max-primitives`.
pub const DEFAULT_MAX_ELEMENTS: usize = 50_000_000;

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            seed: None,
            max_elements: DEFAULT_MAX_ELEMENTS,
            shuffle_visits: None,
            validate_each_step: false,
            deadline: None,
            max_evaluations: DEFAULT_MAX_EVALUATIONS,
            inputs: Arc::from(Vec::new()),
        }
    }
}

/// Elements a step created.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CreatedCounts {
    pub verts: usize,
    pub edges: usize,
    pub faces: usize,
}

/// What one step did, summed over every time it ran (a compound's steps
/// run once per initial primitive).
#[derive(Debug, Clone)]
pub struct StepStats {
    pub name: String,
    pub op: &'static str,
    /// Times the step ran.
    pub runs: usize,
    /// Primitives considered (all of the kind, the scope's, or an earlier
    /// step's products).
    pub candidates: usize,
    /// Candidates whose condition held.
    pub matched: usize,
    /// Matched primitives the step was applied to.
    pub applied: usize,
    /// Matched primitives skipped by the command's probability.
    pub skipped: usize,
    /// Matched primitives another scope had already applied this command
    /// to (thesis 003 §3.3.3): not applied again, products shared.
    pub shared: usize,
    /// Nodes merged away into coinciding ones (`policy = "merge"`).
    pub merged: usize,
    /// Applications not made because a product would intersect the model
    /// (`policy = "intersect"`).
    pub rejected: usize,
    /// Applications rolled back: for a compound step, its scopes cancelled
    /// by `cancel_compound`; for a step, the rule applications it
    /// cancelled by `cancel_rule` or `cancel_compound`.
    pub cancelled: usize,
    /// Of `cancelled`, for a step that is not a compound call: the
    /// compound applications it cancelled (`cancel_compound`); the rest
    /// were rule applications.
    pub cancelled_compounds: usize,
    pub created: CreatedCounts,
    pub elapsed: Duration,
}

#[derive(Debug)]
pub struct RunOutput {
    pub mesh: Mesh,
    pub seed: u64,
    /// Parameter values, sorted by name.
    pub params: Vec<(String, f64)>,
    /// One entry per step that ran, in program order.
    pub steps: Vec<StepStats>,
}

/// Why a run failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunErrorKind {
    /// An operator or command could not be applied.
    Failed,
    /// The model outgrew `max_elements`.
    TooLarge,
    /// The run passed its deadline.
    Timeout,
    /// The run evaluated more expressions than `max_evaluations`.
    EvaluationLimit,
}

/// A failure while running: which step, where it is written, and why.
#[derive(Debug, Error)]
#[error("{location}: step `{step}`: {message}")]
pub struct RunError {
    pub kind: RunErrorKind,
    pub step: String,
    pub location: String,
    pub message: String,
}

/// `Runner::product_slot` of a step whose products no step reads.
const NO_SLOT: u32 = u32::MAX;

struct Runner<'p> {
    program: &'p Program,
    /// Set by a kernel operator that applied to fewer elements than it was
    /// given (`dissolve_edges` skips edges it cannot dissolve).
    applied_override: std::cell::Cell<Option<usize>>,
    inputs: Arc<[Arc<IndexedMesh>]>,
    seed: u64,
    max_elements: usize,
    deadline: Option<Instant>,
    max_evaluations: u64,
    /// Condition and parameter evaluations so far.
    evaluations: u64,
    shuffle: Option<u64>,
    validate_each_step: bool,
    /// Parameter values, then property values of the current element.
    slots: Vec<f64>,
    /// Products of the latest run of each step some `from` reads, by the
    /// step's slot in `product_slot`.
    created: Vec<Selection>,
    /// By uid: the step's slot in `created`, or `NO_SLOT` when no step reads
    /// its products (most steps: the others cost nothing to remember).
    product_slot: Vec<u32>,
    /// By uid; boxed, since most of a large program's steps may never run.
    stats: Vec<Option<Box<StepStats>>>,
    /// Innermost scope last.
    scopes: Vec<Scope>,
    /// Uids of the compound steps being run, innermost last.
    calls: Vec<u32>,
    /// (compound step, command step, primitive) → products, for the
    /// shared-primitive rule. Looked up only, never iterated.
    applied: FxHashMap<(u32, u32, u32), Selection>,
    /// Policies of the compound calls being run, innermost last, above the
    /// file's default.
    policies: Vec<Policy>,
    /// Reactions to intersections of the compound calls being run.
    reactions: Vec<OnIntersection>,
    merger: Merger,
    guard: Guard,
}

/// Runs the program and returns the mesh with per-step statistics.
pub fn run(program: &Program, options: &RunOptions) -> Result<RunOutput, RunError> {
    let mut runner = Runner::new(program, options);
    runner.evaluate_params()?;
    let mut mesh = Mesh::new();
    if program.uses_graph {
        graph::ensure_layers(&mut mesh);
    }
    runner
        .run_steps(&mut mesh, &program.steps, true)
        .map_err(Stop::into_error)?;
    let params = runner.param_values();
    Ok(RunOutput {
        mesh,
        seed: runner.seed,
        params,
        steps: runner.stats.into_iter().flatten().map(|s| *s).collect(),
    })
}

/// The parameter values a run with `seed` (the program's default when
/// `None`) would use, sorted by name, without running anything.
pub fn parameter_values(
    program: &Program,
    seed: Option<u64>,
) -> Result<Vec<(String, f64)>, RunError> {
    let options = RunOptions {
        seed,
        ..RunOptions::default()
    };
    let mut runner = Runner::new(program, &options);
    runner.evaluate_params()?;
    Ok(runner.param_values())
}

impl<'p> Runner<'p> {
    fn new(program: &'p Program, options: &RunOptions) -> Self {
        let mut runner = Runner {
            program,
            applied_override: std::cell::Cell::new(None),
            inputs: Arc::clone(&options.inputs),
            seed: options.seed.unwrap_or(program.default_seed),
            max_elements: options.max_elements,
            deadline: options.deadline,
            max_evaluations: options.max_evaluations,
            evaluations: 0,
            shuffle: options.shuffle_visits,
            validate_each_step: options.validate_each_step,
            slots: vec![0.0; program.param_names.len()],
            created: Vec::new(),
            product_slot: Vec::new(),
            stats: vec![None; program.step_count],
            scopes: Vec::new(),
            calls: Vec::new(),
            applied: FxHashMap::default(),
            policies: vec![program.policy],
            reactions: vec![program.on_intersection],
            merger: Merger::new(),
            guard: Guard::new(),
        };
        runner.product_slot = vec![NO_SLOT; program.step_count];
        let every_step = program
            .steps
            .iter()
            .chain(program.compounds.iter().flat_map(|c| &c.steps));
        for uid in every_step.filter_map(|s| s.from.as_ref()).flatten() {
            let slot = &mut runner.product_slot[*uid as usize];
            if *slot == NO_SLOT {
                *slot = runner.created.len() as u32;
                runner.created.push(Selection::new());
            }
        }
        runner
    }

    /// Remembers what step `uid` made, if a later step reads it.
    fn remember(&mut self, uid: u32, made: Selection) {
        let slot = self.product_slot[uid as usize];
        if slot != NO_SLOT {
            self.created[slot as usize] = made;
        }
    }

    fn param_values(&self) -> Vec<(String, f64)> {
        self.program
            .param_names
            .iter()
            .zip(&self.slots)
            .map(|(n, &v)| (n.clone(), v))
            .collect()
    }
}

/// Why running stopped early: a failure, or an intersection that cancels
/// the innermost compound or rule application (caught by the one that
/// rolls back; a cancel nobody catches becomes a failure).
enum Stop {
    Fail(RunError),
    Cancel(CancelLevel, RunError),
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum CancelLevel {
    Compound,
    Rule,
}

impl From<RunError> for Stop {
    fn from(e: RunError) -> Self {
        Stop::Fail(e)
    }
}

impl Stop {
    fn into_error(self) -> RunError {
        match self {
            Stop::Fail(e) => e,
            Stop::Cancel(level, mut e) => {
                let what = match level {
                    CancelLevel::Compound => {
                        "`cancel_compound`, but no compound application is running"
                    }
                    CancelLevel::Rule => "`cancel_rule`, but no rule application is running",
                };
                e.message = format!("{}; {what}", e.message);
                e
            }
        }
    }
}

/// The state a cancelled application rolls back to.
struct Snapshot {
    mesh: Mesh,
    applied: FxHashMap<(u32, u32, u32), Selection>,
}

fn step_error(step: &Step, kind: RunErrorKind, message: String) -> RunError {
    RunError {
        kind,
        step: step.name.clone(),
        location: step.location.clone(),
        message,
    }
}

/// Element counts of a selection.
fn counts(s: &Selection) -> CreatedCounts {
    CreatedCounts {
        verts: s.verts.len(),
        edges: s.edges.len(),
        faces: s.faces.len(),
    }
}

/// What a step did in one run, before it is summed into [`StepStats`].
#[derive(Default)]
struct Tally {
    candidates: usize,
    matched: usize,
    applied: usize,
    skipped: usize,
    shared: usize,
    merged: usize,
    rejected: usize,
    cancelled: usize,
    cancelled_compounds: usize,
}

impl Runner<'_> {
    fn evaluate_params(&mut self) -> Result<(), RunError> {
        let seed = self.seed;
        for p in &self.program.params {
            let fail = |message: String| RunError {
                kind: RunErrorKind::Failed,
                step: format!("params.{}", p.name),
                location: self.program.file.clone(),
                message,
            };
            let slots = &self.slots;
            let mut value = match &p.kind {
                ParamKind::Expr(e) => e.eval(slots),
                ParamKind::Uniform { low, high } => {
                    let (lo, hi) = (low.eval(slots), high.eval(slots));
                    lo + (hi - lo) * random::unit(seed, p.key, 0, 0)
                }
                ParamKind::Normal { mean, sd } => {
                    mean.eval(slots) + sd.eval(slots) * random::standard_normal(seed, p.key, 0, 0)
                }
                ParamKind::Int { low, high } => {
                    let (lo, hi) = (libm::round(low.eval(slots)), libm::round(high.eval(slots)));
                    if !(lo.is_finite() && hi.is_finite()) || lo > hi {
                        return Err(fail(format!("integer range [{lo}, {hi}] is empty")));
                    }
                    random::int_in(seed, p.key, 0, 0, lo as i64, hi as i64) as f64
                }
                ParamKind::Choice { values, weights } => {
                    let total: f64 = weights.iter().sum();
                    let mut target = random::unit(seed, p.key, 0, 0) * total;
                    let mut pick = values.len() - 1;
                    for (i, w) in weights.iter().enumerate() {
                        if target < *w {
                            pick = i;
                            break;
                        }
                        target -= w;
                    }
                    values[pick].eval(slots)
                }
            };
            if let Some((lo, hi)) = &p.clamp {
                let (lo, hi) = (lo.eval(slots), hi.eval(slots));
                if lo > hi {
                    return Err(fail(format!("clamp range [{lo}, {hi}] is empty")));
                }
                value = value.clamp(lo, hi);
            }
            if !value.is_finite() {
                return Err(fail(format!("parameter `{}` evaluates to {value}", p.name)));
            }
            self.slots[p.slot as usize] = value;
        }
        Ok(())
    }

    /// Runs a list of steps (the program's, or a compound's). With `top`,
    /// records of the shared-primitive rule are dropped after each step.
    /// When the program may cancel rule applications, the mesh is
    /// snapshotted as each rule application starts; a `cancel_rule` from one
    /// of its steps restores the snapshot and skips the application's other
    /// steps.
    fn run_steps(&mut self, mesh: &mut Mesh, steps: &[Step], top: bool) -> Result<(), Stop> {
        // Rule applications running, outermost first, with their snapshots.
        let mut open: Vec<(u32, Option<Snapshot>)> = Vec::new();
        let mut i = 0;
        while i < steps.len() {
            let step = &steps[i];
            let depth = open
                .iter()
                .zip(&step.rule_instances)
                .take_while(|((a, _), b)| a == *b)
                .count();
            open.truncate(depth);
            for &instance in &step.rule_instances[depth..] {
                let snapshot = self.program.may_cancel.then(|| self.snapshot(mesh));
                open.push((instance, snapshot));
            }
            let result = self.run_step(mesh, step);
            if top {
                self.applied.clear();
            }
            match result {
                Ok(()) => i += 1,
                Err(Stop::Cancel(CancelLevel::Rule, error)) => {
                    let Some((instance, snapshot)) = open.pop() else {
                        return Err(Stop::Cancel(CancelLevel::Rule, error));
                    };
                    let snapshot =
                        snapshot.expect("snapshots are kept when cancelling is possible");
                    self.restore(mesh, snapshot);
                    while i < steps.len() && steps[i].rule_instances.contains(&instance) {
                        self.remember(steps[i].uid, Selection::new());
                        i += 1;
                    }
                }
                Err(other) => return Err(other),
            }
        }
        Ok(())
    }

    fn snapshot(&self, mesh: &Mesh) -> Snapshot {
        Snapshot {
            mesh: mesh.clone(),
            applied: self.applied.clone(),
        }
    }

    /// Rolls back to `snapshot`; the vertex grid and intersection index are
    /// rebuilt when next needed.
    fn restore(&mut self, mesh: &mut Mesh, snapshot: Snapshot) {
        *mesh = snapshot.mesh;
        self.applied = snapshot.applied;
        self.merger.invalidate();
        self.guard.invalidate();
    }

    fn run_step(&mut self, mesh: &mut Mesh, step: &Step) -> Result<(), Stop> {
        let started = Instant::now();
        let generation = step.uid + 1;
        let mut tally = Tally::default();
        let made = match self.step_products(mesh, step, generation, &mut tally) {
            Ok(made) => made,
            Err(stop) => {
                // A cancelled or failed run still counts what it matched
                // and rejected.
                self.tally(step, &tally, &Selection::new(), started);
                return Err(stop);
            }
        };
        for scope in &mut self.scopes {
            scope.add(&made);
        }
        if self.validate_each_step {
            mesh.validate().map_err(|e| {
                step_error(
                    step,
                    RunErrorKind::Failed,
                    format!("invalid mesh after the step: {e}"),
                )
            })?;
        }
        self.check_size(mesh, step, 0)?;
        self.tally(step, &tally, &made, started);
        self.remember(step.uid, made);
        Ok(())
    }

    /// Adds one run of `step` to its statistics.
    fn tally(&mut self, step: &Step, tally: &Tally, made: &Selection, started: Instant) {
        let stats = self.stats[step.uid as usize].get_or_insert_with(|| {
            Box::new(StepStats {
                name: step.name.clone(),
                op: step.op.name(),
                runs: 0,
                candidates: 0,
                matched: 0,
                applied: 0,
                skipped: 0,
                shared: 0,
                merged: 0,
                rejected: 0,
                cancelled: 0,
                cancelled_compounds: 0,
                created: CreatedCounts::default(),
                elapsed: Duration::ZERO,
            })
        });
        stats.runs += 1;
        stats.candidates += tally.candidates;
        stats.matched += tally.matched;
        stats.applied += tally.applied;
        stats.skipped += tally.skipped;
        stats.shared += tally.shared;
        stats.merged += tally.merged;
        stats.rejected += tally.rejected;
        stats.cancelled += tally.cancelled;
        stats.cancelled_compounds += tally.cancelled_compounds;
        let c = counts(made);
        stats.created.verts += c.verts;
        stats.created.edges += c.edges;
        stats.created.faces += c.faces;
        stats.elapsed += started.elapsed();
    }

    /// What the step makes (running it), with its counts in `tally`.
    fn step_products(
        &mut self,
        mesh: &mut Mesh,
        step: &Step,
        generation: u32,
        tally: &mut Tally,
    ) -> Result<Selection, Stop> {
        if step.op.is_create() {
            self.merger.invalidate();
            self.guard.invalidate();
            self.admit_kernel_op(mesh, step, &[])?;
            return Ok(self
                .apply(mesh, step, &[])
                .map_err(|m| step_error(step, RunErrorKind::Failed, m))?);
        }
        let candidates = self.candidates(mesh, step);
        tally.candidates = candidates.len();
        let extra = match &step.op {
            Op::Compound { index, .. } => self.program.compounds[*index].select.as_ref(),
            _ => None,
        };
        let matched: Vec<usize> = candidates
            .into_iter()
            .filter(|&i| {
                [step.select.as_ref(), extra]
                    .into_iter()
                    .flatten()
                    .all(|c| self.eval(mesh, step, generation, i, step.domain, c) != 0.0)
            })
            .collect();
        tally.matched = matched.len();
        match &step.op {
            Op::Command(command) => self.run_command(mesh, step, command, &matched, tally),
            Op::Compound { index, frame } => {
                tally.applied = matched.len();
                self.run_compound(mesh, step, *index, frame, &matched, tally)
            }
            _ => {
                tally.applied = matched.len();
                // A kernel operator may move, make or remove anything.
                self.merger.invalidate();
                self.guard.invalidate();
                self.admit_kernel_op(mesh, step, &matched)?;
                let made = self
                    .apply(mesh, step, &matched)
                    .map_err(|m| step_error(step, RunErrorKind::Failed, m))?;
                // An operator that applies to fewer than it was given says so.
                if let Some(applied) = self.applied_override.take() {
                    tally.applied = applied;
                }
                Ok(made)
            }
        }
    }

    /// The run's bounds: the primitive count (with `coming` more on the
    /// way), the evaluation budget and the deadline.
    fn check_size(&self, mesh: &Mesh, step: &Step, coming: usize) -> Result<(), RunError> {
        if self.evaluations > self.max_evaluations {
            return Err(step_error(
                step,
                RunErrorKind::EvaluationLimit,
                format!(
                    "{} expression evaluations, over the limit of {}; raise it with --max-evaluations if the work is intended",
                    self.evaluations, self.max_evaluations
                ),
            ));
        }
        if self.deadline.is_some_and(|d| Instant::now() > d) {
            return Err(step_error(
                step,
                RunErrorKind::Timeout,
                "the run passed its time limit (--timeout)".to_string(),
            ));
        }
        let total = mesh.vert_count() + mesh.edge_count() + mesh.face_count();
        if total.saturating_add(coming) > self.max_elements {
            let message = if coming == 0 {
                format!(
                    "the model has {total} primitives, over the limit of {}",
                    self.max_elements
                )
            } else {
                format!(
                    "the model would grow past the limit of {} primitives (it has {total}, this step adds about {coming})",
                    self.max_elements
                )
            };
            return Err(step_error(
                step,
                RunErrorKind::TooLarge,
                format!("{message}; raise it with --max-primitives if the growth is intended"),
            ));
        }
        Ok(())
    }

    /// Value of condition `c` for primitive `index` of `domain`. Element
    /// properties are computed when the condition reads them, so the right
    /// side of a failed `&&` costs nothing.
    fn eval(
        &mut self,
        mesh: &Mesh,
        step: &Step,
        generation: u32,
        index: usize,
        domain: Domain,
        c: &Condition,
    ) -> f64 {
        let ctx = Context {
            mesh,
            scope: self.scopes.last(),
            seed: self.seed,
            stream: step.key,
            generation,
        };
        let base = self.program.param_names.len();
        let mut source = LazyProperties {
            params: &self.slots[..base],
            ctx: &ctx,
            domain,
            index,
            values: [0.0; PROPERTY_SLOTS],
            known: 0,
        };
        self.evaluations += 1;
        c.expr.eval_with(&mut source)
    }

    /// Candidates in ascending id order.
    fn candidates(&self, mesh: &Mesh, step: &Step) -> Vec<usize> {
        let alive = |i: usize| match step.domain {
            Domain::Vert => mesh.contains_vert(VertId::from_index(i)),
            Domain::Edge => mesh.contains_edge(EdgeId::from_index(i)),
            Domain::Face => mesh.contains_face(FaceId::from_index(i)),
        };
        if let Some(uids) = &step.from {
            let mut ids: Vec<usize> = Vec::new();
            for &uid in uids {
                let s = &self.created[self.product_slot[uid as usize] as usize];
                match step.domain {
                    Domain::Vert => ids.extend(s.verts.iter().map(|v| v.index())),
                    Domain::Edge => ids.extend(s.edges.iter().map(|e| e.index())),
                    Domain::Face => ids.extend(s.faces.iter().map(|f| f.index())),
                }
            }
            ids.sort_unstable();
            ids.dedup();
            return ids.into_iter().filter(|&i| alive(i)).collect();
        }
        if let Some(scope) = self.scopes.last() {
            return scope.members(mesh, step.domain);
        }
        match step.domain {
            Domain::Vert => mesh.vert_ids().map(|v| v.index()).collect(),
            Domain::Edge => mesh.edge_ids().map(|e| e.index()).collect(),
            Domain::Face => mesh.face_ids().map(|f| f.index()).collect(),
        }
    }

    fn reference(&self) -> Reference {
        self.scopes.last().map_or(Reference::WORLD, |s| s.reference)
    }

    /// Plans a G³ command on every matched primitive of generation Gₙ, then
    /// applies the plans.
    fn run_command(
        &mut self,
        mesh: &mut Mesh,
        step: &Step,
        command: &Command,
        matched: &[usize],
        tally: &mut Tally,
    ) -> Result<Selection, Stop> {
        let generation = step.uid + 1;
        let fail = |m: String| step_error(step, RunErrorKind::Failed, m);
        let call = self.calls.last().copied();
        let reference = self.reference();
        let mut made = Selection::new();
        let mut plans: Vec<Plan> = Vec::with_capacity(matched.len());
        for &i in matched {
            if let Some(call) = call {
                if let Some(products) = self.applied.get(&(call, step.uid, i as u32)) {
                    made.append(products);
                    tally.shared += 1;
                    continue;
                }
            }
            if let Some(p) = &command.probability {
                let p = self.eval(mesh, step, generation, i, step.domain, p);
                if !(0.0..=1.0).contains(&p) {
                    return Err(Stop::Fail(fail(format!(
                        "probability evaluates to {p} for {} {i}; it must be in [0, 1]",
                        step.domain
                    ))));
                }
                if random::unit(self.seed, step.key, i as u64, 0) >= p {
                    tally.skipped += 1;
                    continue;
                }
            }
            let (seed, key) = (self.seed, step.key);
            let spread = |draw: u64| 2.0 * random::unit(seed, key, i as u64, draw) - 1.0;
            let mut plan = {
                let mut eval = |c: &Condition| self.eval(mesh, step, generation, i, step.domain, c);
                commands::plan(mesh, command, i, &reference, &mut eval, &spread)
            }
            .map_err(|m| fail(format!("{} {i}: {m}", step.domain)))?;
            if command.kind == CommandKind::SplitFace {
                let ring: Vec<VertId> = mesh.face_verts(FaceId::from_index(i)).collect();
                plan.nodes = match &command.nodes {
                    None => ring,
                    Some(c) => ring
                        .into_iter()
                        .filter(|v| {
                            self.eval(mesh, step, generation, v.index(), Domain::Vert, c) != 0.0
                        })
                        .collect(),
                };
            }
            plans.push(plan);
        }
        tally.applied = plans.len();
        // Each plan adds at most a node, a few edges and faces per side.
        let coming: usize = plans.iter().map(|p| 4 + 2 * p.nodes.len()).sum();
        self.check_size(mesh, step, coming)?;
        let policy = step.policy.unwrap_or(self.policy());
        let testing = policy == Policy::Intersect;
        let mut order: Vec<usize> = (0..plans.len()).collect();
        // Under `intersect` an application is tested against what the ones
        // before it made, so the order stays canonical (ascending target).
        if let (Some(shuffle), false) = (self.shuffle, testing) {
            // Testing hook: a seeded Fisher–Yates shuffle.
            for k in (1..order.len()).rev() {
                let j = random::int_in(shuffle, 0, k as u64, 0, 0, k as i64) as usize;
                order.swap(k, j);
            }
        }
        // New nodes by plan, so they can be listed in plan order below.
        let mut new_nodes: Vec<Vec<VertId>> = vec![Vec::new(); plans.len()];
        for k in order {
            let plan = &plans[k];
            if testing && self.guard.would_intersect(mesh, command.kind, plan) {
                tally.rejected += 1;
                tally.applied -= 1;
                let reaction = step.on_intersection.unwrap_or(self.reaction());
                let error = || {
                    step_error(
                        step,
                        RunErrorKind::Failed,
                        format!(
                            "applied to {} {}, `{}` would make a primitive that intersects the model",
                            step.domain,
                            plan.target,
                            step.op.name()
                        ),
                    )
                };
                match reaction {
                    OnIntersection::Skip => continue,
                    OnIntersection::Error => return Err(Stop::Fail(error())),
                    OnIntersection::CancelCompound => {
                        tally.cancelled += 1;
                        tally.cancelled_compounds += 1;
                        return Err(Stop::Cancel(CancelLevel::Compound, error()));
                    }
                    OnIntersection::CancelRule => {
                        tally.cancelled += 1;
                        return Err(Stop::Cancel(CancelLevel::Rule, error()));
                    }
                }
            }
            let products = commands::apply(mesh, command.kind, plan, i64::from(generation))
                .map_err(|m| fail(format!("{} {}: {m}", step.domain, plan.target)))?;
            if testing {
                self.guard.accept(mesh, &products);
            }
            if let Some(call) = call {
                self.applied
                    .insert((call, step.uid, plan.target as u32), products.clone());
            }
            new_nodes[k].clone_from(&products.verts);
            made.append(&products);
        }
        // Thesis §3.1.2.1: after the command, the nodes it made (or, for
        // edit_node, moved) are merged with those they coincide with. They
        // are listed in plan order (ascending target), not id order: ids
        // follow the order plans were applied in, and the first listed of
        // several new nodes survives.
        let touched: Vec<VertId> = if command.kind == CommandKind::EditNode {
            plans.iter().map(|p| VertId::from_index(p.target)).collect()
        } else {
            new_nodes.concat()
        };
        let reshapes = matches!(
            command.kind,
            CommandKind::SplitEdge | CommandKind::SplitFace | CommandKind::EditNode
        );
        match policy {
            Policy::Merge { tolerance } => {
                tally.merged += self
                    .merger
                    .merge(mesh, &touched, tolerance, &mut made)
                    .map_err(|e| fail(format!("merging: {e}")))?;
                self.guard.invalidate();
            }
            Policy::None => {
                self.merger.record(mesh, &touched);
                self.guard.record(mesh, &made, reshapes);
            }
            Policy::Intersect => {
                self.merger.record(mesh, &touched);
                self.guard.finish_command(reshapes);
            }
        }
        // Products shared from another scope may since have been merged away.
        made.verts.retain(|&v| mesh.contains_vert(v));
        made.edges.retain(|&e| mesh.contains_edge(e));
        made.faces.retain(|&f| mesh.contains_face(f));
        made.normalize();
        Ok(made)
    }

    /// The reaction to intersections in force: the innermost compound
    /// call's, or the file's.
    fn reaction(&self) -> OnIntersection {
        *self
            .reactions
            .last()
            .expect("the file's reaction is never popped")
    }

    /// The policy in force: the innermost compound call's, or the file's.
    fn policy(&self) -> Policy {
        *self
            .policies
            .last()
            .expect("the file's policy is never popped")
    }

    /// Runs a compound command: one scope per matched initial primitive,
    /// all planned on the generation the command reads, then run in
    /// ascending id order with the scope on top of the stack.
    fn run_compound(
        &mut self,
        mesh: &mut Mesh,
        step: &Step,
        index: usize,
        frame: &FrameParams,
        matched: &[usize],
        tally: &mut Tally,
    ) -> Result<Selection, Stop> {
        let generation = step.uid + 1;
        let compound = &self.program.compounds[index];
        let parent = self.reference();
        let mut scopes = Vec::with_capacity(matched.len());
        for &i in matched {
            let measure = Measure::of(mesh, step.domain, i);
            let mut value = |c: &Option<Condition>, default: f64| match c {
                Some(c) => self.eval(mesh, step, generation, i, step.domain, c),
                None => default,
            };
            let length = value(&frame.length, 1.0);
            let radius = value(&frame.radius, 1.0);
            let mut vector = |v: &Option<Box<[Condition; 3]>>, default: DVec3| match v {
                Some(v) => DVec3::new(
                    self.eval(mesh, step, generation, i, step.domain, &v[0]),
                    self.eval(mesh, step, generation, i, step.domain, &v[1]),
                    self.eval(mesh, step, generation, i, step.domain, &v[2]),
                ),
                None => default,
            };
            let heading = vector(&frame.heading, DVec3::X);
            let up = vector(&frame.up, DVec3::Z);
            // Table 3.2: a relative compound scales with its initial
            // primitive, an absolute one with the enclosing reference.
            let (basis, length_unit, radius_unit) = if frame.relative {
                let initial_radius = match step.domain {
                    Domain::Vert => graph::radius(mesh, VertId::from_index(i)),
                    Domain::Edge => {
                        graph::mean_radius(mesh, mesh.edge_verts(EdgeId::from_index(i)).into_iter())
                    }
                    Domain::Face => {
                        graph::mean_radius(mesh, mesh.face_verts(FaceId::from_index(i)))
                    }
                };
                (measure.frame, measure.size, initial_radius)
            } else {
                (parent.frame, parent.length, parent.radius)
            };
            let reference = Reference {
                frame: Frame::from_heading_up(basis.to_world(heading), basis.to_world(up)),
                length: length * length_unit,
                radius: radius * radius_unit,
            };
            if !(reference.length.is_finite() && reference.radius.is_finite()) {
                return Err(Stop::Fail(step_error(
                    step,
                    RunErrorKind::Failed,
                    format!(
                        "compound `{}` on {} {i}: length or radius is not finite",
                        compound.name, step.domain
                    ),
                )));
            }
            scopes.push(Scope::new(mesh, step.domain, i, reference, measure));
        }
        self.policies.push(step.policy.unwrap_or(self.policy()));
        self.reactions
            .push(step.on_intersection.unwrap_or(self.reaction()));
        let result = self.run_scopes(mesh, step, compound, scopes, tally);
        self.policies.pop();
        self.reactions.pop();
        result
    }

    /// Runs the compound's steps in each scope in turn. A `cancel_compound`
    /// from inside a scope rolls the mesh back to before that scope ran.
    fn run_scopes(
        &mut self,
        mesh: &mut Mesh,
        step: &Step,
        compound: &Compound,
        scopes: Vec<Scope>,
        tally: &mut Tally,
    ) -> Result<Selection, Stop> {
        let mut made = Selection::new();
        for scope in scopes {
            let initial = scope.sizes();
            let snapshot = self.program.may_cancel.then(|| self.snapshot(mesh));
            self.scopes.push(scope);
            self.calls.push(step.uid);
            let result = self.run_steps(mesh, &compound.steps, false);
            self.calls.pop();
            let scope = self.scopes.pop().expect("pushed above");
            match result {
                Ok(()) => made.append(&scope.added_since(initial)),
                Err(Stop::Cancel(CancelLevel::Compound, _)) => {
                    let snapshot =
                        snapshot.expect("snapshots are kept when cancelling is possible");
                    self.restore(mesh, snapshot);
                    tally.applied -= 1;
                    tally.cancelled += 1;
                }
                Err(other) => return Err(other),
            }
        }
        made.normalize();
        Ok(made)
    }

    fn scalar(&self, e: &crate::rules::expr::Expr) -> f64 {
        e.eval(&self.slots)
    }

    fn vector(&self, v: &Vector) -> DVec3 {
        DVec3::new(
            self.scalar(&v.0[0]),
            self.scalar(&v.0[1]),
            self.scalar(&v.0[2]),
        )
    }

    fn count(&self, e: &crate::rules::expr::Expr, what: &str) -> Result<u32, String> {
        let x = libm::round(self.scalar(e));
        if !(x.is_finite() && (0.0..=u32::MAX as f64).contains(&x)) {
            return Err(format!("{what} must be a whole number ≥ 0, got {x}"));
        }
        Ok(x as u32)
    }

    fn offset(&self, o: &Offset) -> ExtrudeOffset {
        match o {
            Offset::None => ExtrudeOffset::None,
            Offset::Vector(v) => ExtrudeOffset::Vector(self.vector(v)),
            Offset::Normal(d) => ExtrudeOffset::Normal(self.scalar(d)),
        }
    }
    /// At most how many primitives (vertices + edges + faces) the step's
    /// kernel operator will create, from its parameters and selection, so
    /// that the primitive limit refuses it before anything is allocated.
    /// Saturating: a parameter too large to count predicts `u64::MAX`.
    fn predicted_growth(&self, mesh: &Mesh, step: &Step, selected: &[usize]) -> u64 {
        use ops::select;
        let n = |e: &crate::rules::expr::Expr| -> u64 {
            let x = libm::round(self.scalar(e));
            if x.is_nan() || x <= 0.0 {
                0
            } else if x >= u64::MAX as f64 {
                u64::MAX
            } else {
                x as u64
            }
        };
        let by_domain = selection_of(step.domain, selected);
        let full = || match step.domain {
            Domain::Vert => select::select_from_verts(mesh, &by_domain.verts),
            Domain::Edge => select::select_from_edges(mesh, &by_domain.edges),
            Domain::Face => select::select_from_faces(mesh, &by_domain.faces),
        };
        let size = |s: &Selection| (s.verts.len() + s.edges.len() + s.faces.len()) as u64;
        let edge_count = || match step.domain {
            Domain::Face => select::select_from_faces(mesh, &by_domain.faces)
                .edges
                .len() as u64,
            _ => by_domain.edges.len() as u64,
        };
        let vert_count = || match step.domain {
            Domain::Vert => by_domain.verts.len() as u64,
            _ => full().verts.len() as u64,
        };
        // Per face of n sides: n new vertices, 2n edges, n + 1 faces at most
        // (extrude and inset, individually or as a region).
        let rings = || -> u64 {
            by_domain
                .faces
                .iter()
                .map(|&f| 4 * mesh.face_len(f) as u64 + 1)
                .fold(0, u64::saturating_add)
        };
        let m = u64::saturating_mul;
        match &step.op {
            Op::Vertex { .. } => 1,
            Op::Circle { segments, .. } => m(n(segments), 2).saturating_add(1),
            Op::Grid { segments, .. } => {
                let (x, y) = (
                    n(&segments[0]).saturating_add(1),
                    n(&segments[1]).saturating_add(1),
                );
                m(m(x, y), 4)
            }
            Op::Cube { .. } => 26,
            Op::UvSphere {
                segments, rings, ..
            } => m(m(n(segments), n(rings).saturating_add(1)), 3).saturating_add(2),
            Op::Cylinder { segments, .. } => m(n(segments), 6).saturating_add(2),
            Op::ExtrudeVerts { .. } => m(vert_count(), 2),
            Op::ExtrudeEdges { .. } => m(edge_count(), 6),
            Op::ExtrudeFaces { .. }
            | Op::ExtrudeRegion { .. }
            | Op::InsetFaces { .. }
            | Op::InsetRegion { .. } => rings(),
            Op::SplitEdgesCuts { cuts } => m(m(edge_count(), n(cuts)), 2),
            Op::SplitEdgesRatios { ratios } => m(m(edge_count(), ratios.len() as u64), 2),
            // n - 3 diagonals and n - 2 triangles for the one face removed.
            Op::Triangulate => by_domain
                .faces
                .iter()
                .map(|&f| 2 * (mesh.face_len(f) as u64).saturating_sub(3))
                .fold(0, u64::saturating_add),
            Op::Duplicate | Op::Mirror { .. } => size(&full()),
            Op::MakeFace => 1,
            Op::Skin { sides, joints, .. } => {
                let s = n(sides);
                let wires = mesh.edge_ids().filter(|&e| mesh.is_wire_edge(e)).count() as u64;
                let tubes = m(wires, m(s, 6).saturating_add(2));
                let spheres = if *joints {
                    m(
                        mesh.vert_count() as u64,
                        m(m(s, (s / 2).max(2)), 3).saturating_add(2),
                    )
                } else {
                    0
                };
                tubes.saturating_add(spheres)
            }
            Op::Import { .. }
            | Op::Translate { .. }
            | Op::Rotate { .. }
            | Op::Scale { .. }
            | Op::Reverse
            | Op::RecomputeNormals { .. }
            | Op::Delete { .. }
            | Op::DissolveEdges
            | Op::Merge { .. }
            | Op::RegionExtend { .. }
            | Op::RegionReduce { .. }
            | Op::Command(_)
            | Op::Compound { .. } => 0,
        }
    }

    /// Refuses a kernel operator that would outgrow the primitive limit or
    /// spend the evaluation budget (one unit per element it selects or
    /// creates), before it allocates anything.
    fn admit_kernel_op(
        &mut self,
        mesh: &Mesh,
        step: &Step,
        selected: &[usize],
    ) -> Result<(), RunError> {
        let growth = self.predicted_growth(mesh, step, selected);
        self.evaluations = self
            .evaluations
            .saturating_add(selected.len() as u64)
            .saturating_add(growth);
        self.check_size(mesh, step, usize::try_from(growth).unwrap_or(usize::MAX))
    }

    fn apply(&self, mesh: &mut Mesh, step: &Step, selected: &[usize]) -> Result<Selection, String> {
        use ops::{create, delete, extrude, faces, inset, merge, select, split, transform};
        let by_domain = selection_of(step.domain, selected);
        let verts = || -> Vec<VertId> {
            match step.domain {
                Domain::Vert => by_domain.verts.clone(),
                Domain::Edge => select::select_from_edges(mesh, &by_domain.edges).verts,
                Domain::Face => select::select_from_faces(mesh, &by_domain.faces).verts,
            }
        };
        let edges = || -> Vec<EdgeId> {
            match step.domain {
                Domain::Face => select::select_from_faces(mesh, &by_domain.faces).edges,
                _ => by_domain.edges.clone(),
            }
        };
        let full_selection = || -> Selection {
            match step.domain {
                Domain::Vert => select::select_from_verts(mesh, &by_domain.verts),
                Domain::Edge => select::select_from_edges(mesh, &by_domain.edges),
                Domain::Face => select::select_from_faces(mesh, &by_domain.faces),
            }
        };
        let moved = |vs: Vec<VertId>| Selection::from_parts(vs, Vec::new(), Vec::new());
        let faces_list = &by_domain.faces;
        let e = |err: ops::OpError| err.to_string();
        Ok(match &step.op {
            Op::Vertex { at, radius } => {
                let made = create::create_vert(mesh, self.vector(at)).map_err(e)?;
                if let Some(r) = radius {
                    graph::ensure_layers(mesh);
                    for &v in &made.verts {
                        graph::set_radius(mesh, v, self.scalar(r));
                    }
                }
                made
            }
            Op::Circle {
                segments,
                radius,
                fill,
            } => create::create_circle(
                mesh,
                self.count(segments, "segments")?,
                self.scalar(radius),
                *fill,
            )
            .map_err(e)?,
            Op::Grid { segments, size } => create::create_grid(
                mesh,
                self.count(&segments[0], "segments")?,
                self.count(&segments[1], "segments")?,
                self.scalar(&size[0]),
                self.scalar(&size[1]),
            )
            .map_err(e)?,
            Op::Cube { size } => create::create_cube(mesh, self.scalar(size)).map_err(e)?,
            Op::UvSphere {
                segments,
                rings,
                radius,
            } => create::create_uv_sphere(
                mesh,
                self.count(segments, "segments")?,
                self.count(rings, "rings")?,
                self.scalar(radius),
            )
            .map_err(e)?,
            Op::Cylinder {
                segments,
                radius,
                radius_top,
                depth,
                caps,
            } => create::create_cylinder(
                mesh,
                self.count(segments, "segments")?,
                self.scalar(radius),
                self.scalar(radius_top),
                self.scalar(depth),
                *caps,
            )
            .map_err(e)?,
            Op::Import {
                resource,
                weld,
                y_up,
            } => {
                let source = &self.program.resources[*resource];
                let loaded = self
                    .inputs
                    .get(*resource)
                    .ok_or_else(|| format!("`{}` was not loaded before the run", source.written))?;
                let mut indexed = match weld {
                    Some(distance) => std::borrow::Cow::Owned(loaded.welded(*distance)),
                    None => std::borrow::Cow::Borrowed(&**loaded),
                };
                if *y_up {
                    indexed.to_mut().y_up_to_z_up();
                }
                // Built straight into the working mesh: no copy.
                crate::kernel::build::append_indexed(mesh, &indexed)
                    .map_err(|err| format!("{}: {err}", source.written))?
            }
            Op::Translate { offset } => {
                let vs = verts();
                transform::translate(mesh, &vs, self.vector(offset)).map_err(e)?;
                moved(vs)
            }
            Op::Rotate {
                angle_degrees,
                axis,
                center,
            } => {
                let vs = verts();
                let angle = self.scalar(angle_degrees).to_radians();
                transform::rotate(mesh, &vs, self.vector(center), self.vector(axis), angle)
                    .map_err(e)?;
                moved(vs)
            }
            Op::Scale { factor, center } => {
                let vs = verts();
                transform::scale(mesh, &vs, self.vector(center), self.vector(factor)).map_err(e)?;
                moved(vs)
            }
            Op::ExtrudeVerts { offset } => {
                let vs = verts();
                extrude::extrude_verts(mesh, &vs, self.offset(offset)).map_err(e)?
            }
            Op::ExtrudeEdges { offset } => {
                let es = edges();
                extrude::extrude_edges(mesh, &es, self.offset(offset)).map_err(e)?
            }
            Op::ExtrudeFaces {
                keep_original,
                offset,
            } => extrude::extrude_faces(mesh, faces_list, *keep_original, self.offset(offset))
                .map_err(e)?,
            Op::ExtrudeRegion {
                keep_original,
                offset,
            } => {
                extrude::extrude_face_region(mesh, faces_list, *keep_original, self.offset(offset))
                    .map_err(e)?
            }
            Op::InsetFaces { thickness, depth } => {
                inset::inset_faces(mesh, faces_list, self.scalar(thickness), self.scalar(depth))
                    .map_err(e)?
            }
            Op::InsetRegion { thickness, depth } => {
                inset::inset_region(mesh, faces_list, self.scalar(thickness), self.scalar(depth))
                    .map_err(e)?
            }
            Op::SplitEdgesCuts { cuts } => {
                let es = edges();
                split::split_edges(mesh, &es, self.count(cuts, "cuts")?).map_err(e)?
            }
            Op::SplitEdgesRatios { ratios } => {
                let es = edges();
                let r: Vec<f64> = ratios.iter().map(|x| self.scalar(x)).collect();
                split::split_edges_at(mesh, &es, &r).map_err(e)?
            }
            Op::Triangulate => faces::triangulate(mesh, faces_list).map_err(e)?,
            Op::Reverse => {
                faces::reverse_faces(mesh, faces_list).map_err(e)?;
                Selection::from_parts(Vec::new(), Vec::new(), faces_list.clone())
            }
            Op::RecomputeNormals { outside } => {
                faces::recompute_normals(mesh, faces_list, *outside).map_err(e)?;
                Selection::from_parts(Vec::new(), Vec::new(), faces_list.clone())
            }
            Op::Delete { mode } => {
                let s = match step.domain {
                    Domain::Face => by_domain.clone(),
                    _ => full_selection(),
                };
                delete::delete(mesh, &s, *mode).map_err(e)?
            }
            Op::Duplicate => {
                let s = full_selection();
                delete::duplicate(mesh, &s).map_err(e)?
            }
            Op::DissolveEdges => {
                let es = edges();
                let report = delete::dissolve_edges_report(mesh, &es).map_err(e)?;
                self.applied_override.set(Some(report.dissolved));
                Selection::from_parts(Vec::new(), Vec::new(), report.faces)
            }
            Op::MakeFace => {
                let es = edges();
                faces::make_face_from_edges(mesh, &es).map_err(e)?
            }
            Op::Merge { distance } => {
                let vs = verts();
                let r = merge::merge_by_distance(mesh, &vs, self.scalar(distance)).map_err(e)?;
                moved(r.survivors)
            }
            Op::Mirror {
                point,
                normal,
                merge_distance,
            } => {
                let s = full_selection();
                merge::mirror(
                    mesh,
                    &s,
                    self.vector(point),
                    self.vector(normal),
                    self.scalar(merge_distance),
                )
                .map_err(e)?
            }
            Op::RegionExtend { by } => Selection::from_parts(
                Vec::new(),
                Vec::new(),
                select::region_extend(mesh, faces_list, *by),
            ),
            Op::RegionReduce { by } => Selection::from_parts(
                Vec::new(),
                Vec::new(),
                select::region_reduce(mesh, faces_list, *by),
            ),
            Op::Skin {
                sides,
                radius,
                joints,
                keep_wires,
            } => {
                let options = ops::skin::SkinOptions {
                    sides: self.count(sides, "sides")?,
                    default_radius: self.scalar(radius),
                    joints: *joints,
                };
                let tubes = ops::skin::skin_wire_edges(mesh, &options).map_err(e)?;
                if !*keep_wires {
                    let wires: Vec<EdgeId> =
                        mesh.edge_ids().filter(|&w| mesh.is_wire_edge(w)).collect();
                    let mut nodes: Vec<VertId> =
                        wires.iter().flat_map(|&w| mesh.edge_verts(w)).collect();
                    let wire_selection = Selection::from_parts(Vec::new(), wires, Vec::new());
                    delete::delete(mesh, &wire_selection, delete::DeleteMode::All).map_err(e)?;
                    // The skeleton's nodes go with its wires, unless a face still uses them.
                    nodes.sort_unstable();
                    nodes.dedup();
                    nodes.retain(|&v| mesh.vert_edges(v).next().is_none());
                    let loose = Selection::from_parts(nodes, Vec::new(), Vec::new());
                    delete::delete(mesh, &loose, delete::DeleteMode::All).map_err(e)?;
                }
                let map = mesh.join_mesh(&tubes);
                Selection::from_parts(
                    map.verts.into_iter().flatten().collect(),
                    map.edges.into_iter().flatten().collect(),
                    map.faces.into_iter().flatten().collect(),
                )
            }
            Op::Command(_) | Op::Compound { .. } => {
                unreachable!("commands and compounds run in run_step")
            }
        })
    }
}

fn selection_of(domain: Domain, indices: &[usize]) -> Selection {
    let mut s = Selection::new();
    match domain {
        Domain::Vert => s.verts = indices.iter().map(|&i| VertId::from_index(i)).collect(),
        Domain::Edge => s.edges = indices.iter().map(|&i| EdgeId::from_index(i)).collect(),
        Domain::Face => s.faces = indices.iter().map(|&i| FaceId::from_index(i)).collect(),
    }
    s
}

/// Slot values for a condition: parameters as given, element properties
/// computed on first read and remembered for the rest of the evaluation.
struct LazyProperties<'a> {
    params: &'a [f64],
    ctx: &'a Context<'a>,
    domain: Domain,
    index: usize,
    values: [f64; PROPERTY_SLOTS],
    /// Bit k set: `values[k]` holds property k.
    known: u64,
}

const _: () = assert!(PROPERTY_SLOTS <= u64::BITS as usize);

impl SlotSource for LazyProperties<'_> {
    fn slot(&mut self, slot: u32) -> f64 {
        let Some(k) = (slot as usize).checked_sub(self.params.len()) else {
            return self.params[slot as usize];
        };
        if self.known & (1 << k) == 0 {
            let property = property_from_index(k as u32);
            self.values[k] = properties::property(self.ctx, self.domain, self.index, property);
            self.known |= 1 << k;
        }
        self.values[k]
    }
}
