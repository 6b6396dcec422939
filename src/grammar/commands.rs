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

use super::graph::{self, Frame};
use super::scope::Reference;

/// What one command will do to one primitive.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The matched primitive's index (in the command's domain).
    pub target: usize,
    /// Frame of the new edge (or of the new node for `split_face`).
    pub frame: Frame,
    /// Where the new node goes (`edit_node`: where the node moves to).
    pub position: DVec3,
    /// Radius of the new node; `None` keeps or inherits the preceding one.
    pub radius: Option<f64>,
    /// `split_face`: the face's nodes that passed the secondary condition,
    /// in face order.
    pub nodes: Vec<VertId>,
    /// `create_face`: wind the triangle against the edge (n1, n0, n2) so it
    /// agrees with the face already on the edge.
    pub against_edge: bool,
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
/// this primitive; `spread` gives its symmetric random draws.
pub fn plan(
    mesh: &Mesh,
    command: &Command,
    index: usize,
    reference: &Reference,
    eval: &mut dyn FnMut(&Condition) -> f64,
    spread: &dyn Fn(u64) -> f64,
) -> Result<Plan, CommandError> {
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
    Ok(Plan {
        target: index,
        frame,
        position,
        radius,
        nodes: Vec::new(),
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
    })
}

/// Applies a plan; returns what it created (for `from`, scopes and stats).
/// `generation` becomes the age of everything new.
pub fn apply(
    mesh: &mut Mesh,
    kind: CommandKind,
    plan: &Plan,
    generation: i64,
) -> Result<Selection, CommandError> {
    let e = CommandError::Kernel;
    let mut made = Selection::new();
    match kind {
        CommandKind::CreateEdge => {
            let v = VertId::from_index(plan.target);
            let (edge, w) = mesh.make_edge_vert(v, plan.position).map_err(e)?;
            new_node(mesh, w, plan, generation);
            new_edge(mesh, edge, &plan.frame, generation);
            made.verts.push(w);
            made.edges.push(edge);
        }
        CommandKind::SplitEdge => {
            let edge = EdgeId::from_index(plan.target);
            let [a, b] = mesh.edge_verts(edge);
            let old = graph::edge_frame(mesh, edge);
            let (pa, pb) = (mesh.position(a), mesh.position(b));
            // Attributes blend by the new node's place along the edge.
            let t = (plan.position - pa).dot(pb - pa) / (pb - pa).length_squared().max(1e-300);
            let (w, rest) = mesh.split_edge(edge, t.clamp(0.0, 1.0)).map_err(e)?;
            mesh.set_position(w, plan.position);
            refresh_around(mesh, w);
            new_node(mesh, w, plan, generation);
            // (n0, n2) follows the parameters; (n2, n1) keeps the old left.
            new_edge(mesh, edge, &plan.frame, generation);
            let rest_frame = Frame::from_heading_left(pb - plan.position, old.l);
            new_edge(mesh, rest, &rest_frame, generation);
            made.verts.push(w);
            made.edges.push(rest);
        }
        CommandKind::CreateFace => {
            let edge = EdgeId::from_index(plan.target);
            let [a, b] = mesh.edge_verts(edge);
            let w = mesh.make_vert(plan.position);
            mesh.copy_vert_attrs(b, w);
            new_node(mesh, w, plan, generation);
            // Thesis: e1 = (n1, n2), e2 = (n2, n0).
            let e1 = mesh.make_edge(b, w).map_err(e)?;
            let e2 = mesh.make_edge(w, a).map_err(e)?;
            new_edge(mesh, e1, &plan.frame, generation);
            let back = Frame::from_heading_left(mesh.position(a) - plan.position, plan.frame.l);
            new_edge(mesh, e2, &back, generation);
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
        CommandKind::SplitFace => split_face(mesh, plan, generation, &mut made)?,
        CommandKind::EditNode => {
            let v = VertId::from_index(plan.target);
            mesh.set_position(v, plan.position);
            refresh_around(mesh, v);
            if let Some(r) = plan.radius {
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
    generation: i64,
    made: &mut Selection,
) -> Result<(), CommandError> {
    let e = CommandError::Kernel;
    let f = FaceId::from_index(plan.target);
    let ring: Vec<VertId> = mesh.face_verts(f).collect();
    let picked = &plan.nodes;
    match picked.len() {
        0 => {}
        1 => {
            // One node: a new node joined to it, the face unchanged.
            let (edge, c) = mesh.make_edge_vert(picked[0], plan.position).map_err(e)?;
            new_node(mesh, c, plan, generation);
            new_edge(mesh, edge, &plan.frame, generation);
            made.verts.push(c);
            made.edges.push(edge);
        }
        2 if ring_adjacent(&ring, picked[0], picked[1]) => {}
        2 => {
            // Thesis §3.4: two nodes are joined by an edge, no node is made.
            let (g, edge) = mesh.split_face(f, picked[0], picked[1]).map_err(e)?;
            let dir = mesh.position(picked[1]) - mesh.position(picked[0]);
            new_edge(
                mesh,
                edge,
                &Frame::from_heading_up(dir, mesh.face_normal(f)),
                generation,
            );
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
                new_edge(
                    mesh,
                    spoke,
                    &Frame::from_heading_up(dir, plan.frame.u),
                    generation,
                );
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

/// Whether `a` and `b` follow each other around `ring`.
fn ring_adjacent(ring: &[VertId], a: VertId, b: VertId) -> bool {
    let n = ring.len();
    (0..n).any(|i| {
        let (x, y) = (ring[i], ring[(i + 1) % n]);
        (x, y) == (a, b) || (x, y) == (b, a)
    })
}

fn new_node(mesh: &mut Mesh, v: VertId, plan: &Plan, generation: i64) {
    graph::set_frame(mesh, Domain::Vert, v.index(), &plan.frame);
    graph::set_age(mesh, Domain::Vert, v.index(), generation);
    if let Some(r) = plan.radius {
        graph::set_radius(mesh, v, r);
    }
}

fn new_edge(mesh: &mut Mesh, e: EdgeId, frame: &Frame, generation: i64) {
    graph::set_frame(mesh, Domain::Edge, e.index(), frame);
    graph::set_age(mesh, Domain::Edge, e.index(), generation);
}

fn refresh_around(mesh: &mut Mesh, v: VertId) {
    let faces: Vec<FaceId> = mesh.vert_faces(v).collect();
    for f in faces {
        mesh.refresh_normal(f);
    }
}
