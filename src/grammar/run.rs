//! Running a program: parameters, then each step in order. A step gathers
//! its candidates (every primitive of its kind, those of the current scope,
//! or what an earlier step created), keeps those whose condition holds on
//! the generation it reads, and runs its operator, G³ command or compound
//! command on them.

use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::DVec3;
use rustc_hash::FxHashMap;

use super::error::{RunError, StepError};
use super::fields::{FieldStats, Input};
use super::intersect::Guard;
use super::merge::Merger;
use super::operators;
use super::surfaces::SurfaceStats;
use crate::kernel::ops::Selection;
use crate::kernel::{Domain, EdgeId, FaceId, Mesh, VertId};
use crate::rules::expr::SlotSource;
use crate::rules::program::{
    Call, Compound, Condition, FrameParams, OnIntersection, Op, ParamKind, Policy, Program, Step,
};
use crate::rules::property;
use crate::rules::random;

use super::graph::{self, Frame};
use super::lineage;
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
    /// (shared by every variant of a batch, with their distance fields).
    pub inputs: Arc<[Input]>,
    /// Stop with [`RunErrorKind::TooLarge`] before meshing a field on a
    /// grid of more cells than this (checked before allocating).
    pub max_cells: u64,
    /// Where meshers count the blocks they mesh (a progress bar reads it).
    pub mesh_progress: crate::sdf::Progress,
}

/// Default `--max-cells`: 2³⁰, a 1024³ grid.
pub const DEFAULT_MAX_CELLS: u64 = 1 << 30;

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
            max_cells: DEFAULT_MAX_CELLS,
            mesh_progress: crate::sdf::Progress(None),
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
    pub name: std::sync::Arc<str>,
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
    /// What meshing fields did (steps that mesh one).
    pub field: Option<Box<FieldStats>>,
    /// What tessellating surfaces or PN smoothing did.
    pub surface: Option<Box<SurfaceStats>>,
}

#[derive(Debug)]
pub struct RunOutput {
    pub mesh: Mesh,
    pub seed: u64,
    /// Parameter values, sorted by name.
    pub params: Vec<(String, f64)>,
    /// One entry per step that ran, in program order.
    pub steps: Vec<Box<StepStats>>,
    /// Warnings about the inputs (each once), in the order they arose.
    pub warnings: Vec<String>,
}

/// `Runner::product_slot` of a step whose products no step reads.
const NO_SLOT: u32 = u32::MAX;

pub(super) struct Runner<'p> {
    pub(super) program: &'p Program,
    /// Part and material of the enclosing compound calls' products.
    pub(super) looks: (Option<u32>, Option<u32>),
    pub(super) inputs: Arc<[Input]>,
    pub(super) max_cells: u64,
    pub(super) mesh_progress: crate::sdf::Progress,
    pub(super) warnings: Vec<String>,
    pub(super) seed: u64,
    pub(super) max_elements: usize,
    pub(super) deadline: Option<Instant>,
    pub(super) max_evaluations: u64,
    /// Condition and parameter evaluations so far.
    pub(super) evaluations: u64,
    pub(super) shuffle: Option<u64>,
    pub(super) validate_each_step: bool,
    /// Parameter values, then property values of the current element.
    pub(super) slots: Vec<f64>,
    /// Products of the latest run of each step some `from` reads, by the
    /// step's slot in `product_slot`.
    pub(super) created: Vec<Selection>,
    /// By uid: the step's slot in `created`, or `NO_SLOT` when no step reads
    /// its products (most steps: the others cost nothing to remember).
    pub(super) product_slot: Vec<u32>,
    /// By uid; boxed, since most of a large program's steps may never run.
    pub(super) stats: Vec<Option<Box<StepStats>>>,
    /// Innermost scope last.
    pub(super) scopes: Vec<Scope>,
    /// Uids of the compound steps being run, innermost last.
    pub(super) calls: Vec<u32>,
    /// (compound step, command step, primitive) → products, for the
    /// shared-primitive rule. Looked up only, never iterated.
    pub(super) applied: FxHashMap<(u32, u32, u32), Selection>,
    /// Policies of the compound calls being run, innermost last, above the
    /// file's default.
    pub(super) policies: Vec<Policy>,
    /// Reactions to intersections of the compound calls being run.
    pub(super) reactions: Vec<OnIntersection>,
    pub(super) merger: Merger,
    pub(super) guard: Guard,
}

/// Runs the program and returns the mesh with per-step statistics.
pub fn run(program: &Program, options: &RunOptions) -> Result<RunOutput, RunError> {
    let mut runner = Runner::new(program, options);
    // Every top-level step costs at least one evaluation: a program that
    // unrolls to more steps than the budget is refused before the work.
    let steps = program.steps.len() as u64;
    if steps > options.max_evaluations {
        let error = StepError::TooManySteps {
            steps,
            limit: options.max_evaluations,
        };
        return Err(RunError {
            kind: error.kind(),
            step: "(all)".into(),
            location: program.file.clone(),
            error,
        });
    }
    runner.evaluate_params()?;
    let mut mesh = Mesh::new();
    if program.uses_graph {
        graph::ensure_layers(&mut mesh);
    }
    if program.tags_looks {
        super::asset::ensure_layers(&mut mesh);
    }
    if program.draws_per_primitive {
        lineage::ensure_layers(&mut mesh);
    }
    runner
        .run_steps(&mut mesh, &program.steps, true)
        .map_err(Stop::into_error)?;
    runner.paint(&mut mesh);
    let params = runner.param_values();
    Ok(RunOutput {
        mesh,
        seed: runner.seed,
        params,
        // The boxes move: a million-step program's records are not copied.
        steps: runner.stats.into_iter().flatten().collect(),
        warnings: runner.warnings,
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
            inputs: Arc::clone(&options.inputs),
            max_cells: options.max_cells,
            mesh_progress: options.mesh_progress,
            warnings: Vec::new(),
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
            looks: (None, None),
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
    pub(super) fn remember(&mut self, uid: u32, made: Selection) {
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
pub(super) enum Stop {
    Fail(RunError),
    Cancel(CancelLevel, RunError),
}

#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum CancelLevel {
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
                if let StepError::Intersects { uncaught, .. } = &mut e.error {
                    *uncaught = match level {
                        CancelLevel::Compound => {
                            "; `cancel_compound`, but no compound application is running"
                        }
                        CancelLevel::Rule => "; `cancel_rule`, but no rule application is running",
                    };
                }
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

pub(super) fn step_error(step: &Step, error: StepError) -> RunError {
    RunError {
        kind: error.kind(),
        step: step.name.to_string(),
        location: step.location.clone(),
        error,
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
pub(super) struct Tally {
    pub(super) candidates: usize,
    pub(super) matched: usize,
    pub(super) applied: usize,
    pub(super) skipped: usize,
    pub(super) shared: usize,
    pub(super) merged: usize,
    pub(super) rejected: usize,
    pub(super) cancelled: usize,
    pub(super) cancelled_compounds: usize,
    pub(super) field: Option<FieldStats>,
    pub(super) surface: Option<SurfaceStats>,
}

impl Runner<'_> {
    fn evaluate_params(&mut self) -> Result<(), RunError> {
        let seed = self.seed;
        for p in &self.program.params {
            let fail = |error: StepError| RunError {
                kind: error.kind(),
                step: format!("params.{}", p.name),
                location: self.program.file.clone(),
                error,
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
                        return Err(fail(StepError::EmptyRange { low: lo, high: hi }));
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
                    return Err(fail(StepError::EmptyClamp { low: lo, high: hi }));
                }
                value = value.clamp(lo, hi);
            }
            if !value.is_finite() {
                return Err(fail(StepError::NotFinite {
                    name: p.name.clone(),
                    value,
                }));
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
        // A step is work even when it selects nothing: a runaway `repeat`
        // meets --max-evaluations, a deterministic bound.
        self.evaluations = self.evaluations.saturating_add(1);
        self.check_size(mesh, step, 0)?;
        // A compound call's part and material are its steps' default; its
        // steps tag their own products.
        let compound = matches!(step.op, Op::Compound { .. });
        let outer = self.looks;
        let looks = (step.part.or(outer.0), step.material.or(outer.1));
        if compound {
            self.looks = looks;
        }
        let products = self.step_products(mesh, step, generation, &mut tally);
        self.looks = outer;
        if !compound && self.program.tags_looks {
            if let Ok(made) = &products {
                super::asset::tag(mesh, made, looks);
            }
        }
        if let (true, Op::Call(_), Ok(made)) =
            (self.program.draws_per_primitive, &step.op, &products)
        {
            lineage::assign_derived(mesh, step.key, made);
        }
        let made = match products {
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
            mesh.validate()
                .map_err(|e| step_error(step, StepError::Invalid(e)))?;
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
                field: None,
                surface: None,
            })
        });
        if let Some(s) = &tally.surface {
            stats
                .surface
                .get_or_insert_with(|| Box::new(SurfaceStats::default()))
                .add(s);
        }
        if let Some(f) = &tally.field {
            stats
                .field
                .get_or_insert_with(|| Box::new(FieldStats::default()))
                .add(f);
        }
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
        if let Op::Call(call) = &step.op {
            if call.def.is_create() {
                return Ok(self.run_call(mesh, step, call, &[], tally)?.made);
            }
        }
        // Candidates stream through the select: the matched list is all
        // that lives through the step (a list of every primitive would be
        // 3 MB at 10⁶ primitives, and a hole in the heap after it).
        let extra = match &step.op {
            Op::Compound { index, .. } => self.program.compounds[*index].select.as_ref(),
            _ => None,
        };
        let mut candidates = 0;
        let matched: Vec<usize> = self
            .candidates(mesh, step)
            .inspect(|_| candidates += 1)
            .filter(|&i| {
                [step.select.as_ref(), extra]
                    .into_iter()
                    .flatten()
                    .all(|c| self.eval(mesh, step, generation, i, step.domain, c) != 0.0)
            })
            .collect();
        tally.candidates = candidates;
        tally.matched = matched.len();
        match &step.op {
            Op::Command(command) => self.run_command(mesh, step, command, &matched, tally),
            Op::Compound { index, frame } => {
                tally.applied = matched.len();
                self.run_compound(mesh, step, *index, frame, &matched, tally)
            }
            Op::Call(call) => {
                let done = self.run_call(mesh, step, call, &matched, tally)?;
                // An operator that applies to fewer than it was given says so.
                tally.applied = done.applied.unwrap_or(matched.len());
                Ok(done.made)
            }
        }
    }

    /// Runs a create, kernel or whole-mesh operator on `selected`, once the
    /// primitive limit and the evaluation budget admit what it would make.
    fn run_call(
        &mut self,
        mesh: &mut Mesh,
        step: &Step,
        call: &Call,
        selected: &[usize],
        tally: &mut Tally,
    ) -> Result<operators::Applied, RunError> {
        // A kernel operator may move, make or remove anything.
        self.merger.invalidate();
        self.guard.invalidate();
        let total = mesh.vert_count() + mesh.edge_count() + mesh.face_count();
        let ctx = operators::Context {
            slots: &self.slots,
            resources: &self.program.resources,
            inputs: &self.inputs,
            sdf: &self.program.sdf,
            nurbs: &self.program.nurbs,
            domain: step.domain,
            max_cells: self.max_cells,
            mesh_progress: self.mesh_progress,
            budget: self.max_elements.saturating_sub(total) as u64,
            uses_graph: self.program.uses_graph,
        };
        let growth = operators::predicted_growth(&ctx, mesh, call, selected);
        // Kernel work counts against the evaluation budget: one unit per
        // element the operator selects or creates.
        self.evaluations = self
            .evaluations
            .saturating_add(selected.len() as u64)
            .saturating_add(growth);
        self.check_size(mesh, step, usize::try_from(growth).unwrap_or(usize::MAX))?;
        let done = operators::apply(&ctx, mesh, call, selected).map_err(|e| step_error(step, e))?;
        if let Some(field) = &done.field {
            // A field evaluation is work like an expression's.
            self.evaluations = self.evaluations.saturating_add(field.field_evaluations);
            tally.field = Some(field.clone());
        }
        if let Some(surface) = &done.surface {
            tally.surface = Some(surface.clone());
        }
        for w in &done.warnings {
            if !self.warnings.contains(w) {
                self.warnings.push(w.clone());
            }
        }
        if done.replaced {
            for made in &mut self.created {
                *made = Selection::new();
            }
        }
        Ok(done)
    }

    /// The run's bounds: the primitive count (with `coming` more on the
    /// way), the evaluation budget and the deadline.
    pub(super) fn check_size(
        &self,
        mesh: &Mesh,
        step: &Step,
        coming: usize,
    ) -> Result<(), RunError> {
        if self.evaluations > self.max_evaluations {
            return Err(step_error(
                step,
                StepError::Evaluations {
                    count: self.evaluations,
                    limit: self.max_evaluations,
                },
            ));
        }
        if self.deadline.is_some_and(|d| Instant::now() > d) {
            return Err(step_error(step, StepError::Timeout));
        }
        let total = mesh.vert_count() + mesh.edge_count() + mesh.face_count();
        if total.saturating_add(coming) > self.max_elements {
            let limit = self.max_elements;
            return Err(step_error(
                step,
                if coming == 0 {
                    StepError::TooLarge { total, limit }
                } else {
                    StepError::WouldBeTooLarge {
                        total,
                        coming,
                        limit,
                    }
                },
            ));
        }
        Ok(())
    }

    /// Value of condition `c` for primitive `index` of `domain`. Element
    /// properties are computed when the condition reads them, so the right
    /// side of a failed `&&` costs nothing.
    pub(super) fn eval(
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
            values: [0.0; property::SLOT_COUNT],
            known: 0,
        };
        self.evaluations += 1;
        c.expr.eval_with(&mut source)
    }

    /// Candidates in ascending id order: a stream over the mesh, or the
    /// list a `from` or the scope names.
    pub(super) fn candidates<'m>(
        &self,
        mesh: &'m Mesh,
        step: &Step,
    ) -> Box<dyn Iterator<Item = usize> + 'm> {
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
            let domain = step.domain;
            return Box::new(ids.into_iter().filter(move |&i| match domain {
                Domain::Vert => mesh.contains_vert(VertId::from_index(i)),
                Domain::Edge => mesh.contains_edge(EdgeId::from_index(i)),
                Domain::Face => mesh.contains_face(FaceId::from_index(i)),
            }));
        }
        if let Some(scope) = self.scopes.last() {
            return Box::new(scope.members(mesh, step.domain).into_iter());
        }
        match step.domain {
            Domain::Vert => Box::new(mesh.vert_ids().map(|v| v.index())),
            Domain::Edge => Box::new(mesh.edge_ids().map(|e| e.index())),
            Domain::Face => Box::new(mesh.face_ids().map(|f| f.index())),
        }
    }

    pub(super) fn reference(&self) -> Reference {
        self.scopes.last().map_or(Reference::WORLD, |s| s.reference)
    }

    /// The reaction to intersections in force: the innermost compound
    /// call's, or the file's.
    pub(super) fn reaction(&self) -> OnIntersection {
        *self
            .reactions
            .last()
            .expect("the file's reaction is never popped")
    }

    /// The policy in force: the innermost compound call's, or the file's.
    pub(super) fn policy(&self) -> Policy {
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
                    StepError::CompoundFrame {
                        compound: compound.name.clone(),
                        domain: step.domain,
                        index: i,
                    },
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
}

/// Slot values for a condition: parameters as given, element properties
/// computed on first read and remembered for the rest of the evaluation.
pub(super) struct LazyProperties<'a> {
    pub(super) params: &'a [f64],
    pub(super) ctx: &'a Context<'a>,
    pub(super) domain: Domain,
    pub(super) index: usize,
    pub(super) values: [f64; property::SLOT_COUNT],
    /// Bit k set: `values[k]` holds property k.
    pub(super) known: u64,
}

const _: () = assert!(property::SLOT_COUNT <= u64::BITS as usize);

impl SlotSource for LazyProperties<'_> {
    fn slot(&mut self, slot: u32) -> f64 {
        let Some(k) = (slot as usize).checked_sub(self.params.len()) else {
            return self.params[slot as usize];
        };
        if self.known & (1 << k) == 0 {
            let property = property::at(k as u32);
            self.values[k] = properties::property(self.ctx, self.domain, self.index, property);
            self.known |= 1 << k;
        }
        self.values[k]
    }
}
