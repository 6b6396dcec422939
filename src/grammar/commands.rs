//! The five G³ commands (thesis 003 §2.4.5, §3.4) on the kernel.
//!
//! A command runs in two phases so its result does not depend on the order
//! primitives are visited in: every matched primitive is first *planned*
//! on the generation Gₙ the command reads (parameters evaluated, new
//! positions and frames computed, secondary conditions checked), and only
//! then are the plans *applied*, each touching nothing another plan reads.

use glam::DVec3;

use crate::kernel::attrs::AttrValue;
use crate::kernel::ops::Selection;
use crate::kernel::{Domain, EdgeId, FaceId, Mesh, VertId};
use crate::rules::program::{Command, CommandKind, Condition};

use super::error::StepError;
use super::graph::{self, Frame};
use super::lineage;
use super::run::{step_error, CancelLevel, Runner, Stop, Tally};
use super::scope::Reference;
use crate::rules::program::{OnIntersection, Policy, Step};
use crate::rules::random;

/// What one command will do to one primitive.
///
/// A step holds one plan per matched primitive until all are applied (216k
/// at the 10⁶-primitive benchmark, part of its peak memory), so a plan
/// keeps only what every command needs: 88 bytes. `split_face`'s extras
/// are a [`Fan`] beside it.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Where the new node goes (`edit_node`: where the node moves to).
    pub position: DVec3,
    /// Heading H and left L of the new edge (or of the new node for
    /// `split_face`): all of the frame the graph layers store.
    pub heading: DVec3,
    pub left: DVec3,
    /// Radius of the new node, when `has_radius`.
    radius: f64,
    /// The matched primitive's index (in the command's domain).
    target: u32,
    /// `false`: the node keeps (or inherits) the preceding radius.
    has_radius: bool,
    /// `create_face`: wind the triangle against the edge (n1, n0, n2) so it
    /// agrees with the face already on the edge.
    pub against_edge: bool,
}

impl Plan {
    /// The matched primitive's index (in the command's domain).
    pub fn target(&self) -> usize {
        self.target as usize
    }

    /// Radius of the new node; `None` keeps or inherits the preceding one.
    pub fn radius(&self) -> Option<f64> {
        self.has_radius.then_some(self.radius)
    }
}

/// `split_face`'s part of a plan.
#[derive(Debug, Clone, Default)]
pub struct Fan {
    /// Up of the new node's frame: the fan's spokes are framed by it.
    pub up: DVec3,
    /// The face's nodes that passed the secondary condition, in face order.
    pub nodes: Vec<VertId>,
}

/// The preceding primitive(s) of a command's target: what relative
/// parameters multiply and whose frame they use as basis.
struct Preceding {
    frame: Frame,
    /// `None` for a node with no incoming edge.
    length: Option<f64>,
    radius: f64,
    /// Where the new node is measured from.
    origin: DVec3,
}

fn preceding(mesh: &Mesh, kind: CommandKind, index: usize) -> Preceding {
    match kind {
        CommandKind::CreateEdge | CommandKind::EditNode => {
            let v = VertId::from_index(index);
            let incoming = graph::incoming_edges(mesh, v);
            let frames: Vec<Frame> = incoming
                .iter()
                .map(|&e| graph::edge_frame(mesh, e))
                .collect();
            let length = (!incoming.is_empty()).then(|| {
                incoming.iter().map(|&e| mesh.edge_length(e)).sum::<f64>() / incoming.len() as f64
            });
            Preceding {
                frame: Frame::average(&frames).unwrap_or_else(|| graph::node_frame(mesh, v)),
                length,
                radius: graph::radius(mesh, v),
                origin: mesh.position(v),
            }
        }
        CommandKind::SplitEdge | CommandKind::CreateFace => {
            let e = EdgeId::from_index(index);
            let [a, b] = mesh.edge_verts(e);
            Preceding {
                frame: graph::edge_frame(mesh, e),
                length: Some(mesh.edge_length(e)),
                radius: graph::mean_radius(mesh, [a, b].into_iter()),
                origin: mesh.position(if kind == CommandKind::SplitEdge { a } else { b }),
            }
        }
        CommandKind::SplitFace => {
            let f = FaceId::from_index(index);
            Preceding {
                frame: graph::face_frame(mesh, f),
                length: Some(mesh.face_area(f).sqrt()),
                radius: graph::mean_radius(mesh, mesh.face_verts(f)),
                origin: mesh.face_center(f),
            }
        }
    }
}

/// Per-command defaults: whether parameters are relative, the heading (in
/// the basis) and the length. They make the bare commands useful: a unit
/// edge along +x, an edge split at its middle, an equilateral triangle on
/// an edge, a face split at its barycentre, a node left in place.
pub fn default_heading_and_length(kind: CommandKind) -> (DVec3, f64) {
    match kind {
        CommandKind::CreateEdge => (DVec3::X, 1.0),
        CommandKind::SplitEdge => (DVec3::X, 0.5),
        CommandKind::CreateFace => (DVec3::new(-0.5, 0.75f64.sqrt(), 0.0), 1.0),
        CommandKind::SplitFace => (DVec3::Z, 0.0),
        CommandKind::EditNode => (DVec3::X, 0.0),
    }
}

/// Random inputs of one plan: `spread(i)` is uniform in (−1, 1) from draw
/// `i` of the command's stream for this primitive.
pub const DRAW_LENGTH: u64 = 1;
pub const DRAW_RADIUS: u64 = 2;
pub const DRAW_TURN: u64 = 3;
pub const DRAW_PITCH: u64 = 4;
pub const DRAW_ROLL: u64 = 5;

/// Why a command could not be planned or applied on a primitive.
#[derive(Debug, thiserror::Error)]
pub enum CommandError {
    #[error("relative `length` needs a preceding edge, but node {node} has no incoming edge")]
    NoPrecedingEdge { node: usize },
    #[error("{what} evaluates to {value}")]
    NotFinite { what: &'static str, value: f64 },
    #[error("the new node's position is not finite")]
    Position,
    #[error(transparent)]
    Kernel(crate::kernel::KernelError),
}

/// Plans `command` on primitive `index`. `eval` evaluates a parameter on
/// this primitive; `spread` gives its symmetric random draws. Returns the
/// plan and the new frame's up (which only `split_face` keeps).
pub fn plan(
    mesh: &Mesh,
    command: &Command,
    index: usize,
    reference: &Reference,
    eval: &mut dyn FnMut(&Condition) -> f64,
    spread: &dyn Fn(u64) -> f64,
) -> Result<(Plan, DVec3), CommandError> {
    let target = u32::try_from(index).expect("arena slots are u32");
    let pre = preceding(mesh, command.kind, index);
    let (default_heading, default_length) = default_heading_and_length(command.kind);
    let mut vector = |v: &Option<Box<[Condition; 3]>>, default: DVec3| match v {
        Some(v) => DVec3::new(eval(&v[0]), eval(&v[1]), eval(&v[2])),
        None => default,
    };
    let heading = vector(&command.heading, default_heading);
    let up = vector(&command.up, DVec3::Z);
    // A value plus its variation: base + σ · U(−1, 1).
    let mut varied = |c: &Option<Condition>, vary: &Option<Condition>, default: f64, draw: u64| {
        let base = c.as_ref().map_or(default, &mut *eval);
        match vary {
            Some(sigma) => base + eval(sigma) * spread(draw),
            None => base,
        }
    };
    let length = varied(
        &command.length,
        &command.vary_length,
        default_length,
        DRAW_LENGTH,
    );
    let turn = varied(&command.turn, &command.vary_turn, 0.0, DRAW_TURN);
    let pitch = varied(&command.pitch, &command.vary_pitch, 0.0, DRAW_PITCH);
    let roll = varied(&command.roll, &command.vary_roll, 0.0, DRAW_ROLL);
    let radius = command
        .radius
        .as_ref()
        .map(|_| varied(&command.radius, &command.vary_radius, 1.0, DRAW_RADIUS));

    // Table 3.2: relative values scale with the preceding primitive, absolute
    // ones with the reference (the enclosing compound, or the world).
    let (basis, length_unit, radius_unit) = if command.relative {
        let unit = match pre.length {
            Some(l) => l,
            None if length == 0.0 => 0.0,
            None => return Err(CommandError::NoPrecedingEdge { node: index }),
        };
        (pre.frame, unit, pre.radius)
    } else {
        (reference.frame, reference.length, reference.radius)
    };
    let frame = Frame::from_heading_up(basis.to_world(heading), basis.to_world(up)).rotated(
        turn.to_radians(),
        pitch.to_radians(),
        roll.to_radians(),
    );
    let position = pre.origin + frame.h * (length * length_unit);
    // No radius given: a new node inherits the preceding one's, an edited
    // node keeps its own.
    let radius = match radius {
        Some(r) => Some(r * radius_unit),
        None if command.kind == CommandKind::EditNode => None,
        None => Some(pre.radius),
    };
    for (what, x) in [
        ("length", length * length_unit),
        ("radius", radius.unwrap_or(0.0)),
    ] {
        if !x.is_finite() {
            return Err(CommandError::NotFinite { what, value: x });
        }
    }
    if !position.is_finite() {
        return Err(CommandError::Position);
    }
    let plan = Plan {
        position,
        heading: frame.h,
        left: frame.l,
        radius: radius.unwrap_or(0.0),
        target,
        has_radius: radius.is_some(),
        against_edge: command.kind == CommandKind::CreateFace && {
            let e = EdgeId::from_index(index);
            let [a, _] = mesh.edge_verts(e);
            // The lowest-id face on the edge decides; it runs a → b when its
            // loop on the edge starts at a.
            let mut faces: Vec<(FaceId, bool)> = mesh
                .edge_loops(e)
                .map(|l| (mesh.loop_face(l), mesh.loop_vert(l) == a))
                .collect();
            faces.sort_unstable();
            faces.first().is_some_and(|&(_, runs_a_to_b)| runs_a_to_b)
        },
    };
    Ok((plan, frame.u))
}

/// Applies a plan (with its fan, for `split_face`); returns what it created
/// (for `from`, scopes and stats). `generation` becomes the age of
/// everything new.
pub fn apply(
    mesh: &mut Mesh,
    kind: CommandKind,
    plan: &Plan,
    fan: Option<&Fan>,
    generation: u32,
) -> Result<Selection, CommandError> {
    let e = CommandError::Kernel;
    let mut made = Selection::new();
    match kind {
        CommandKind::CreateEdge => {
            let v = VertId::from_index(plan.target());
            let (edge, w) = mesh.make_edge_vert(v, plan.position).map_err(e)?;
            new_node(mesh, w, plan, generation);
            new_edge(mesh, edge, plan.heading, plan.left, generation);
            made.verts.push(w);
            made.edges.push(edge);
        }
        CommandKind::SplitEdge => {
            let edge = EdgeId::from_index(plan.target());
            let [a, b] = mesh.edge_verts(edge);
            let old = graph::edge_frame(mesh, edge);
            let (pa, pb) = (mesh.position(a), mesh.position(b));
            // Attributes blend by the new node's place along the edge.
            let t = (plan.position - pa).dot(pb - pa) / (pb - pa).length_squared().max(1e-300);
            let (w, rest) = mesh.split_edge(edge, t.clamp(0.0, 1.0)).map_err(e)?;
            mesh.move_vert(w, plan.position);
            new_node(mesh, w, plan, generation);
            // (n0, n2) follows the parameters; (n2, n1) keeps the old left.
            new_edge(mesh, edge, plan.heading, plan.left, generation);
            let rest_frame = Frame::from_heading_left(pb - plan.position, old.l);
            new_edge(mesh, rest, rest_frame.h, rest_frame.l, generation);
            made.verts.push(w);
            made.edges.push(rest);
        }
        CommandKind::CreateFace => {
            let edge = EdgeId::from_index(plan.target());
            let [a, b] = mesh.edge_verts(edge);
            let w = mesh.make_vert(plan.position);
            mesh.copy_vert_attrs(b, w);
            new_node(mesh, w, plan, generation);
            // Thesis: e1 = (n1, n2), e2 = (n2, n0).
            let e1 = mesh.make_edge(b, w).map_err(e)?;
            let e2 = mesh.make_edge(w, a).map_err(e)?;
            new_edge(mesh, e1, plan.heading, plan.left, generation);
            let back = Frame::from_heading_left(mesh.position(a) - plan.position, plan.left);
            new_edge(mesh, e2, back.h, back.l, generation);
            let ring = if plan.against_edge {
                [b, a, w]
            } else {
                [a, b, w]
            };
            let f = mesh.make_face(&ring).map_err(e)?;
            graph::set_age(mesh, Domain::Face, f.index(), generation);
            made.verts.push(w);
            made.edges.extend([e1, e2]);
            made.faces.push(f);
        }
        CommandKind::SplitFace => {
            let none = Fan::default();
            debug_assert!(fan.is_some(), "split_face plans come with a fan");
            split_face(mesh, plan, fan.unwrap_or(&none), generation, &mut made)?;
        }
        CommandKind::EditNode => {
            let v = VertId::from_index(plan.target());
            mesh.move_vert(v, plan.position);
            if let Some(r) = plan.radius() {
                graph::set_radius(mesh, v, r);
            }
            made.verts.push(v);
        }
    }
    Ok(made)
}

fn split_face(
    mesh: &mut Mesh,
    plan: &Plan,
    fan: &Fan,
    generation: u32,
    made: &mut Selection,
) -> Result<(), CommandError> {
    let e = CommandError::Kernel;
    let f = FaceId::from_index(plan.target());
    let ring: Vec<VertId> = mesh.face_verts(f).collect();
    let picked = &fan.nodes;
    match picked.len() {
        0 => {}
        1 => {
            // One node: a new node joined to it, the face unchanged.
            let (edge, c) = mesh.make_edge_vert(picked[0], plan.position).map_err(e)?;
            new_node(mesh, c, plan, generation);
            new_edge(mesh, edge, plan.heading, plan.left, generation);
            made.verts.push(c);
            made.edges.push(edge);
        }
        2 if ring_adjacent(&ring, picked[0], picked[1]) => {}
        2 => {
            // Thesis §3.4: two nodes are joined by an edge, no node is made.
            let (g, edge) = mesh.split_face(f, picked[0], picked[1]).map_err(e)?;
            let dir = mesh.position(picked[1]) - mesh.position(picked[0]);
            let frame = Frame::from_heading_up(dir, mesh.face_normal(f));
            new_edge(mesh, edge, frame.h, frame.l, generation);
            for face in [f, g] {
                graph::set_age(mesh, Domain::Face, face.index(), generation);
            }
            made.edges.push(edge);
            made.faces.extend([f, g]);
        }
        _ => {
            // A fan around the new node: one face per run of the boundary
            // between consecutive picked nodes, wound as the original.
            let c = mesh.make_vert(plan.position);
            mesh.copy_vert_attrs(picked[0], c);
            new_node(mesh, c, plan, generation);
            // The fan's faces inherit the face they replace (its part and
            // material, among other layers); the age is set below.
            let inherited: Vec<(String, AttrValue)> = mesh
                .attributes()
                .layers()
                .iter()
                .filter(|l| l.domain == Domain::Face)
                .map(|l| (l.name.clone(), l.get(f.index())))
                .collect();
            mesh.kill_face(f).map_err(e)?;
            // Spokes first, so each runs from its node to the new one
            // (thesis: eᵢ = (nᵢ, n₍ₙ₊₁₎)).
            for &node in picked {
                let spoke = mesh.make_edge(node, c).map_err(e)?;
                let dir = plan.position - mesh.position(node);
                let frame = Frame::from_heading_up(dir, fan.up);
                new_edge(mesh, spoke, frame.h, frame.l, generation);
                made.edges.push(spoke);
            }
            let at = |v: VertId| {
                ring.iter()
                    .position(|&r| r == v)
                    .expect("picked from the ring")
            };
            for k in 0..picked.len() {
                let (from, to) = (at(picked[k]), at(picked[(k + 1) % picked.len()]));
                let mut piece = Vec::with_capacity(ring.len() + 1);
                let mut i = from;
                loop {
                    piece.push(ring[i]);
                    if i == to {
                        break;
                    }
                    i = (i + 1) % ring.len();
                }
                piece.push(c);
                let face = mesh.make_face(&piece).map_err(e)?;
                for (name, value) in &inherited {
                    let _ = mesh.set_attr(name, Domain::Face, face.index(), *value);
                }
                graph::set_age(mesh, Domain::Face, face.index(), generation);
                made.faces.push(face);
            }
            made.verts.push(c);
        }
    }
    Ok(())
}

/// At most how many vertices, edges, loops and faces applying `plans`
/// adds (what `apply` makes per plan, less the face a fan replaces), so
/// the kernel grows once per step rather than doubling as it fills.
fn growth(mesh: &Mesh, kind: CommandKind, plans: &[Plan], fans: &[Fan]) -> [usize; 4] {
    let n = plans.len();
    match kind {
        CommandKind::CreateEdge => [n, n, 0, 0],
        CommandKind::SplitEdge => {
            let loops = plans
                .iter()
                .map(|p| mesh.edge_face_count(EdgeId::from_index(p.target())))
                .sum();
            [n, n, loops, 0]
        }
        CommandKind::CreateFace => [n, 2 * n, 3 * n, n],
        CommandKind::SplitFace => fans.iter().fold([0; 4], |[v, e, l, f], fan| {
            let k = fan.nodes.len();
            [v + 1, e + k.max(1), l + 2 * k, f + k]
        }),
        CommandKind::EditNode => [0; 4],
    }
}

/// Whether `a` and `b` follow each other around `ring`.
fn ring_adjacent(ring: &[VertId], a: VertId, b: VertId) -> bool {
    let n = ring.len();
    (0..n).any(|i| {
        let (x, y) = (ring[i], ring[(i + 1) % n]);
        (x, y) == (a, b) || (x, y) == (b, a)
    })
}

fn new_node(mesh: &mut Mesh, v: VertId, plan: &Plan, generation: u32) {
    graph::set_heading_left(mesh, Domain::Vert, v.index(), plan.heading, plan.left);
    graph::set_age(mesh, Domain::Vert, v.index(), generation);
    if let Some(r) = plan.radius() {
        graph::set_radius(mesh, v, r);
    }
}

fn new_edge(mesh: &mut Mesh, e: EdgeId, heading: DVec3, left: DVec3, generation: u32) {
    graph::set_heading_left(mesh, Domain::Edge, e.index(), heading, left);
    graph::set_age(mesh, Domain::Edge, e.index(), generation);
}

/// Running a G³ command step: plan on Gₙ, apply in canonical order (or
/// the testing hook's shuffle), key the products' lineage, then merge or
/// record what the policy says.
impl Runner<'_> {
    /// Plans a G³ command on every matched primitive of generation Gₙ, then
    /// applies the plans.
    pub(super) fn run_command(
        &mut self,
        mesh: &mut Mesh,
        step: &Step,
        command: &Command,
        matched: &[usize],
        tally: &mut Tally,
    ) -> Result<Selection, Stop> {
        let generation = step.uid + 1;
        let fail = |index: usize, error: CommandError| {
            step_error(
                step,
                StepError::Command {
                    domain: step.domain,
                    index,
                    error,
                },
            )
        };
        let call = self.calls.last().copied();
        let reference = self.reference();
        let mut made = Selection::new();
        let mut plans: Vec<Plan> = Vec::with_capacity(matched.len());
        // `split_face` only: each plan's fan, parallel to `plans`.
        let mut fans: Vec<Fan> = Vec::new();
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
                    return Err(Stop::Fail(step_error(
                        step,
                        StepError::Probability {
                            domain: step.domain,
                            index: i,
                            value: p,
                        },
                    )));
                }
                if random::unit(self.seed, step.key, lineage::key(mesh, step.domain, i), 0) >= p {
                    tally.skipped += 1;
                    continue;
                }
            }
            let (seed, key) = (self.seed, step.key);
            let id = lineage::key(mesh, step.domain, i);
            let spread = |draw: u64| 2.0 * random::unit(seed, key, id, draw) - 1.0;
            let (plan, up) = {
                let mut eval = |c: &Condition| self.eval(mesh, step, generation, i, step.domain, c);
                plan(mesh, command, i, &reference, &mut eval, &spread)
            }
            .map_err(|e| fail(i, e))?;
            if command.kind == CommandKind::SplitFace {
                let ring: Vec<VertId> = mesh.face_verts(FaceId::from_index(i)).collect();
                let nodes = match &command.nodes {
                    None => ring,
                    Some(c) => ring
                        .into_iter()
                        .filter(|v| {
                            self.eval(mesh, step, generation, v.index(), Domain::Vert, c) != 0.0
                        })
                        .collect(),
                };
                fans.push(Fan { up, nodes });
            }
            plans.push(plan);
        }
        tally.applied = plans.len();
        // Each plan adds at most a node, a few edges and faces per side.
        let coming: usize = 4 * plans.len() + fans.iter().map(|f| 2 * f.nodes.len()).sum::<usize>();
        self.check_size(mesh, step, coming)?;
        let [verts, edges, loops, faces] = growth(mesh, command.kind, &plans, &fans);
        mesh.reserve_growth(verts, edges, loops, faces);
        let policy = step.policy.unwrap_or(self.policy());
        let testing = policy == Policy::Intersect;
        // Plans apply in plan order (ascending target). Under `intersect` an
        // application is tested against what the ones before it made, so
        // the order stays canonical; otherwise the testing hook may shuffle
        // it (a seeded Fisher–Yates), and only then is an order list kept.
        let shuffle = self.shuffle.filter(|_| !testing);
        let order: Option<Vec<usize>> = shuffle.map(|shuffle| {
            let mut order: Vec<usize> = (0..plans.len()).collect();
            for k in (1..order.len()).rev() {
                let j = random::int_in(shuffle, 0, k as u64, 0, 0, k as i64) as usize;
                order.swap(k, j);
            }
            order
        });
        // The nodes the plans make, for the merge below in plan order: one
        // flat list (not a vector and a heap block per plan: 6 MB of the
        // peak at 216k plans), tagged with the plan only when shuffled.
        let mut new_nodes: Vec<VertId> = Vec::new();
        let mut new_node_plans: Vec<u32> = Vec::new();
        let count = plans.len();
        for nth in 0..count {
            let k = order.as_ref().map_or(nth, |order| order[nth]);
            let plan = &plans[k];
            let fan = fans.get(k);
            if testing && self.guard.would_intersect(mesh, command.kind, plan, fan) {
                tally.rejected += 1;
                tally.applied -= 1;
                let reaction = step.on_intersection.unwrap_or(self.reaction());
                let error = || {
                    step_error(
                        step,
                        StepError::Intersects {
                            domain: step.domain,
                            index: plan.target(),
                            op: step.op.name(),
                            uncaught: "",
                        },
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
            let parent = lineage::key(mesh, step.domain, plan.target());
            let products = apply(mesh, command.kind, plan, fan, generation)
                .map_err(|e| fail(plan.target(), e))?;
            if self.program.draws_per_primitive {
                lineage::assign_children(mesh, step.key, parent, &products);
            }
            if testing {
                self.guard.accept(mesh, &products);
            }
            if let Some(call) = call {
                self.applied
                    .insert((call, step.uid, plan.target() as u32), products.clone());
            }
            new_nodes.extend_from_slice(&products.verts);
            if order.is_some() {
                new_node_plans.extend(std::iter::repeat_n(k as u32, products.verts.len()));
            }
            made.append(&products);
        }
        // Thesis §3.1.2.1: after the command, the nodes it made (or, for
        // edit_node, moved) are merged with those they coincide with. They
        // are listed in plan order (ascending target), not id order: ids
        // follow the order plans were applied in, and the first listed of
        // several new nodes survives.
        let touched: Vec<VertId> = if command.kind == CommandKind::EditNode {
            plans
                .iter()
                .map(|p| VertId::from_index(p.target()))
                .collect()
        } else if order.is_some() {
            // Stable: a plan's nodes keep their order.
            let mut tagged: Vec<(u32, VertId)> =
                new_node_plans.into_iter().zip(new_nodes).collect();
            tagged.sort_by_key(|&(k, _)| k);
            tagged.into_iter().map(|(_, v)| v).collect()
        } else {
            new_nodes
        };
        // The merge and the bookkeeping below do not read the plans.
        drop((plans, fans, order));
        let reshapes = matches!(
            command.kind,
            CommandKind::SplitEdge | CommandKind::SplitFace | CommandKind::EditNode
        );
        match policy {
            Policy::Merge { tolerance } => {
                tally.merged += self
                    .merger
                    .merge(mesh, &touched, tolerance, &mut made)
                    .map_err(|e| step_error(step, StepError::Merging(e)))?;
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
}

#[cfg(test)]
mod tests {
    /// A step holds a plan per matched primitive until all are applied:
    /// at 10⁶ G³ primitives every byte here is 0.2 MB of peak memory.
    #[test]
    fn a_plan_stays_small() {
        assert!(std::mem::size_of::<super::Plan>() <= 88);
    }
}
