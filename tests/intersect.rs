//! The `intersect` policy (thesis 003 §3.2) through rule files: the
//! tree-in-box and flags examples, every `on_intersection` reaction, and
//! rejected input. Narrow-phase cases have fixtures in
//! `kernel::intersect`.

mod common;
use common::{assert_rejected, grow, program, step};

use graftal::grammar::graph::RADIUS;
use graftal::grammar::{run, RunOptions, RunOutput};
use graftal::kernel::intersect::{self_intersections, self_intersections_with, WireThickness};

fn total_rejected(out: &RunOutput) -> usize {
    out.steps.iter().map(|s| s.rejected).sum()
}

#[test]
fn tree_in_box_stays_in_the_box_and_never_touches_itself() {
    // The growth, without the final skin (the policy keeps edges apart;
    // the skin is meshed inside the box, see the next test).
    let text = include_str!("../rules/tree-in-box.toml");
    let growth = text.split("\n# One watertight solid").next().unwrap();
    assert!(growth.len() < text.len(), "the skin step moved");
    let out = grow(growth);
    let m = &out.mesh;
    assert!(m.vert_count() > 5000, "{} nodes", m.vert_count());
    assert!(
        total_rejected(&out) > 0,
        "the box and branches must have blocked growth"
    );
    for v in m.vert_ids() {
        let p = m.position(v);
        assert!(p.x.abs() <= 1.0 && p.y.abs() <= 1.0, "{p}");
        assert!((0.0..=2.2).contains(&p.z), "{p}");
    }
    let found = self_intersections_with(m, WireThickness::VertLayer(RADIUS));
    assert!(found.faces.is_empty(), "{:?}", found.faces);
    assert!(
        found.edge_faces.is_empty(),
        "{:?}",
        &found.edge_faces[..found.edge_faces.len().min(5)]
    );
    assert!(
        found.edges.is_empty(),
        "{:?}",
        &found.edges[..found.edges.len().min(5)]
    );
}

#[test]
fn flags_never_cross_and_do_without_the_policy() {
    let text = include_str!("../rules/flags.toml");
    let out = grow(text);
    let flags = step(&out, "flags");
    assert!(flags.rejected > 0 && flags.applied > 0, "{flags:?}");
    assert_eq!(flags.applied + flags.rejected, flags.matched);
    assert!(self_intersections(&out.mesh).is_empty());
    // The same flags without testing cross each other.
    let loose = grow(&text.replace("policy = \"intersect\"", "policy = \"none\""));
    assert_eq!(step(&loose, "flags").applied, flags.matched);
    assert!(!self_intersections(&loose.mesh).is_empty());
}

/// A wall: a vertical quad at x = 1 with thin nodes.
const WALL_ONLY: &str = r#"
[start]
grid = { segments = [1, 1], size = [2, 2] }
[[step]]
name = "stand"
rotate = { angle = 90, axis = [0, 1, 0] }
[[step]]
name = "place"
translate = { offset = [1, 0, 0] }
[[step]]
name = "thin"
edit_node = { radius = 0.01 }
"#;

/// A seed node for growth tests.
fn seed(name: &str, x: f64) -> String {
    format!("[[step]]\nname = \"{name}\"\nvertex = {{ at = [{x}, 0, 0], radius = 0.01 }}\n")
}

/// The wall and a node at the origin; steps grow edges along +x, which
/// reach the wall when longer than 1.
fn wall() -> String {
    format!("{WALL_ONLY}{}", seed("seed", 0.0))
}

#[test]
fn skip_leaves_out_only_the_intersecting_application() {
    let text = format!(
        "{}[[step]]\nname = \"grow\"\nselect = \"degree == 0\"\npolicy = \"intersect\"\ncreate_edge = {{ heading = [1, 0, 0], length = 1.5 }}\n[[step]]\nname = \"short\"\nselect = \"degree == 0\"\npolicy = \"intersect\"\ncreate_edge = {{ heading = [1, 0, 0], length = 0.5 }}\n",
        wall()
    );
    let out = grow(&text);
    assert_eq!(step(&out, "grow").rejected, 1);
    assert_eq!(step(&out, "grow").applied, 0);
    assert_eq!(step(&out, "short").applied, 1);
}

/// Two posts along +y whose tips an `edit_node` leans crosswise: each
/// leaning post alone clears the other post as it stood, but the two lean
/// posts cross.
const CROSSING_LEAN: &str = r#"
[[step]]
name = "a"
vertex = { at = [0, 0, 0], radius = 0.01 }
[[step]]
name = "b"
vertex = { at = [1, 0, 0], radius = 0.01 }
[[step]]
name = "posts"
select = "degree == 0"
create_edge = { heading = [0, 1, 0], length = 1 }
[[step]]
name = "lean"
select = "pos.y > 0.5"
policy = "intersect"
edit_node = { heading = ["1 - 2 * pos.x", 1, 0], length = 1.4142135623730951 }
"#;

#[test]
fn an_application_is_tested_against_what_earlier_ones_reshaped() {
    let wires =
        |out: &RunOutput| self_intersections_with(&out.mesh, WireThickness::VertLayer(RADIUS));
    // The first tip leans; the second would cross the first post's new
    // shape (not its old one), so it stays.
    let out = grow(CROSSING_LEAN);
    assert_eq!(step(&out, "lean").applied, 1);
    assert_eq!(step(&out, "lean").rejected, 1);
    assert!(wires(&out).edges.is_empty(), "{:?}", wires(&out).edges);
    // Without the policy both lean and the posts cross.
    let out = grow(&CROSSING_LEAN.replace("policy = \"intersect\"\n", ""));
    assert_eq!(step(&out, "lean").applied, 2);
    assert_eq!(wires(&out).edges.len(), 1);
}

/// A thick wire path (0,0,0) → (1,0,0) → (1,1,0) and a triangle grown flat
/// on each edge: the first below the path, the second inside the corner,
/// passing 0.2 from the first edge. Once the first edge has a face it is
/// no longer a capsule 0.3 thick, so the second triangle is free to grow.
const FACES_ON_A_THICK_PATH: &str = r#"
[[step]]
name = "a"
vertex = { at = [0, 0, 0], radius = 0.3 }
[[step]]
name = "out"
select = "degree == 0"
create_edge = { heading = [1, 0, 0], length = 1 }
[[step]]
name = "up"
select = "degree == 1 && pos.x > 0.5"
create_edge = { heading = [0, 1, 0], length = 1 }
[[step]]
name = "faces"
policy = "intersect"
create_face = { relative = false, heading = ["-0.5 - 0.4 * center.y", "-0.5 - 0.6 * center.y", 0], length = "0.7071067811865476 + 0.7118 * center.y" }
"#;

#[test]
fn a_wire_edge_that_gains_a_face_stops_being_a_capsule() {
    let out = grow(FACES_ON_A_THICK_PATH);
    assert_eq!(step(&out, "faces").applied, 2);
    assert_eq!(step(&out, "faces").rejected, 0);
    assert!(self_intersections(&out.mesh).is_empty());
}

#[test]
fn error_stops_the_run_with_a_located_message() {
    let text = format!(
        "{}[[step]]\nname = \"grow\"\nselect = \"degree == 0\"\npolicy = \"intersect\"\non_intersection = \"error\"\ncreate_edge = {{ heading = [1, 0, 0], length = 1.5 }}\n",
        wall()
    );
    let p = program(&text).unwrap();
    let err = run(&p, &RunOptions::default()).unwrap_err();
    assert!(
        matches!(err.error, graftal::grammar::StepError::Intersects { .. }),
        "{err}"
    );
    assert!(
        err.to_string()
            .contains("would make a primitive that intersects the model"),
        "{err}"
    );
    assert!(err.location.starts_with("test.toml:"), "{}", err.location);
}

#[test]
fn cancel_rule_rolls_the_whole_rule_application_back() {
    // Each application of `pair` grows a short edge, then a long one that
    // hits the wall: the short edge is rolled back too.
    let text = format!(
        "{}[rules.pair]\nstep = [\n  {{ name = \"short\", select = \"degree == 0\", create_edge = {{ heading = [0, 1, 0], length = 0.2 }} }},\n  {{ name = \"long\", from = \"short\", on = \"verts\", on_intersection = \"cancel_rule\", create_edge = {{ heading = [1, 0, 0], length = 1.5 }} }},\n  {{ name = \"after\", from = \"long\", on = \"verts\", create_edge = {{ heading = [0, 0, 1], length = 0.1 }} }},\n]\n[[step]]\nrule = \"pair\"\n",
        wall()
    );
    let text = format!("policy = \"intersect\"\n{text}");
    let out = grow(&text);
    assert_eq!(step(&out, "pair/long").cancelled, 1);
    // Only the wall and the lone seed node remain.
    assert_eq!(out.mesh.edge_count(), 4);
    assert_eq!(out.mesh.vert_count(), 5);
    // Without the long edge hitting, the rule stands.
    let fine = text.replace("length = 1.5", "length = 0.5");
    let out = grow(&fine);
    assert_eq!(out.mesh.edge_count(), 7);
}

#[test]
fn cancel_compound_rolls_back_one_scope_and_keeps_the_others() {
    // Two seed nodes; the compound grows a stem and then an arm towards the
    // wall. From the node at x = 0.8 the arm reaches the wall: that scope is
    // rolled back whole; the node at x = -1.5 keeps stem and arm.
    let text = format!(
        "policy = \"intersect\"\n{WALL_ONLY}{}{}{}",
        seed("a", 0.8),
        seed("b", -1.5),
        r#"
[compound.arm]
on = "verts"
step = [
  { name = "stem", create_edge = { heading = [0, 0, 1], length = 0.3 } },
  { name = "reach", from = "stem", on = "verts", on_intersection = "cancel_compound", create_edge = { heading = [1, 0, 0], length = 0.5 } },
]
[[step]]
name = "arms"
select = "degree == 0"
compound = "arm"
"#
    );
    let out = grow(&text);
    let arms = step(&out, "arms");
    assert_eq!(arms.cancelled, 1);
    assert_eq!(arms.applied, 1);
    // The wall's 4 edges and the kept scope's stem and arm.
    assert_eq!(out.mesh.edge_count(), 6);
    for v in out.mesh.vert_ids() {
        let p = out.mesh.position(v);
        let cancelled_stem = (p.x - 0.8).abs() < 1e-9 && p.z > 0.1;
        assert!(!cancelled_stem, "the cancelled stem is gone: {p}");
    }
}

#[test]
fn bad_intersection_input_is_rejected_with_a_location() {
    let cases: &[(&str, &str)] = &[
        (
            "on_intersection = \"explode\"\n",
            "unknown variant `explode`",
        ),
        (
            "on_intersection = \"cancel_rule\"\n",
            "the file's `on_intersection` can be \"skip\" or \"error\"",
        ),
        (
            "[[step]]\ncreate_edge = {}\non_intersection = \"cancel_compound\"\n",
            "test.toml:3:19: `cancel_compound` outside a compound command",
        ),
        (
            "[[step]]\ncreate_edge = {}\non_intersection = \"cancel_rule\"\n",
            "`cancel_rule` outside a rule",
        ),
        (
            "[[step]]\ncube = {}\non_intersection = \"skip\"\n",
            "`on_intersection` belongs to G³ commands and compound calls",
        ),
        (
            "[[step]]\ncreate_edge = {}\npolicy = \"intersect\"\ntolerance = 0.1\n",
            "`tolerance` is the distance of `policy = \"merge\"`",
        ),
    ];
    assert_rejected(cases);
}
